/* tests/fuzz/fuzz_dev_view.c -- the browser view's commands (devices/
 * decode_view.c): the message parser alone, and the decoder on arbitrary
 * chunks of envelopes.
 *
 * The parser: a message it takes must be written back byte for byte by
 * iso_dev_view_encode (the format has no slack a second reading could take
 * differently). The decoder: the input is a sequence of [head][bytes] as in
 * fuzz_dev_common.h, decoded twice to the same events; besides, a TARGET
 * event must come from the connection the decoder last saw granted
 * control, with a sequence number above the one before within that
 * control, for a handle below
 * ISO_DEV_MAX_HANDLES, with a finite pose. */
#include <math.h>

#include "fuzz_dev_common.h"
#include "iso_dev_view.h"

static void parser_round_trip(const uint8_t *d, size_t n)
{
    iso_dev_view_msg m;
    char why[128];
    if (iso_dev_view_parse(d, n, &m, why, sizeof why) != ISO_OK)
        return;
    uint8_t back[ISO_DEV_VIEW_MSG_MAX];
    int len = iso_dev_view_encode(&m, back, sizeof back);
    if (len < 0 || (size_t)len != n || memcmp(back, d, n) != 0)
        abort();
}

static void targets_are_permitted(const uint8_t *d, size_t n)
{
    iso_dev_info info;
    memset(&info, 0, sizeof info);
    info.kind = ISO_DEV_KIND_VIEW;
    iso_dev_decoder dec;
    if (iso_dev_decoder_init(&dec, &info, 0, NULL) != ISO_OK)
        abort();
    static iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    uint32_t last_seq = 0, last_grants = 0;
    size_t i = 0;
    while (i < n) {
        size_t len = d[i++] & 0x7f;
        if (len > n - i)
            len = n - i;
        iso_dev_chunk c;
        memset(&c, 0, sizeof c);
        c.type = ISO_DEV_CHUNK_DATA;
        c.len = (uint16_t)len;
        memcpy(c.data, d + i, len);
        i += len;
        uint32_t holder = dec.view.holder;
        size_t k = iso_dev_decode(&dec, &c, ev, ISO_DEV_EVENTS_PER_CHUNK);
        for (size_t e = 0; e < k; e++) {
            if (ev[e].kind != ISO_DEV_EV_TARGET)
                continue;
            if (holder == 0 || dec.view.applied_conn != holder || ev[e].line >= ISO_DEV_MAX_HANDLES)
                abort();
            if (last_grants == dec.n.grants && dec.view.applied_seq <= last_seq)
                abort(); /* within one control, sequence numbers only grow */
            for (int j = 0; j < 6; j++)
                if (!isfinite(ev[e].v[j]))
                    abort();
            last_grants = dec.n.grants;
            last_seq = dec.view.applied_seq;
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    parser_round_trip(data, size);
    targets_are_permitted(data, size);
    return iso_fuzz_dev_decoder(ISO_DEV_KIND_VIEW, data, size);
}
