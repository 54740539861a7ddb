/* tests/fuzz/fuzz_dev_common.h -- what the device decoder targets share:
 * split the input into chunks, decode it twice, compare, check invariants. */
#ifndef ISO_FUZZ_DEV_COMMON_H
#define ISO_FUZZ_DEV_COMMON_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "iso_dev_decode.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static uint64_t iso_fuzz_dev_pass(int kind, const uint8_t *d, size_t n)
{
    iso_dev_info info;
    memset(&info, 0, sizeof info);
    info.kind = (uint8_t)kind;
    info.debounce_us = 300;
    iso_dev_decoder dec;
    if (iso_dev_decoder_init(&dec, &info, 1, NULL) != ISO_OK)
        return 0;
    static iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    uint64_t h = 0xcbf29ce484222325ULL;
    int64_t t = 0;
    size_t i = 0;
    while (i < n) {
        uint8_t head = d[i++];
        size_t len = head & 0x7f;
        if (len > n - i)
            len = n - i;
        t += (int64_t)(head & 0x0f) * 100000;
        iso_dev_chunk c;
        memset(&c, 0, sizeof c);
        c.t_ns = t;
        c.type = (head & 0x80) ? ISO_DEV_CHUNK_GONE : ISO_DEV_CHUNK_DATA;
        if (c.type == ISO_DEV_CHUNK_DATA) {
            c.len = (uint16_t)len;
            memcpy(c.data, d + i, len);
            i += len;
        }
        size_t k = iso_dev_decode(&dec, &c, ev, ISO_DEV_EVENTS_PER_CHUNK);
        k += iso_dev_decode_tick(&dec, t, ev + k, ISO_DEV_EVENTS_PER_CHUNK - k);
        if (k > ISO_DEV_EVENTS_PER_CHUNK)
            abort();
        for (size_t e = 0; e < k; e++) {
            if (ev[e].source != 1 || ev[e].t_ns > t || ev[e].kind < ISO_DEV_EV_AXES ||
                ev[e].kind > ISO_DEV_EV_RELEASE)
                abort();
            const unsigned char *b = (const unsigned char *)&ev[e];
            for (size_t j = 0; j < sizeof ev[e]; j++)
                h = (h ^ b[j]) * 0x100000001b3ULL;
        }
    }
    if (dec.n.garbage > 0 && kind == ISO_DEV_KIND_HID)
        abort(); /* a HID report gives at most one event: never over capacity */
    return h;
}

static int iso_fuzz_dev_decoder(int kind, const uint8_t *d, size_t n)
{
    if (iso_fuzz_dev_pass(kind, d, n) != iso_fuzz_dev_pass(kind, d, n))
        abort();
    return 0;
}

#endif
