/* tests/fuzz/fuzz_ws.c -- the live view's parser of what a browser sends
 * over its WebSocket (view/display_ws.c) under arbitrary bytes. The parser
 * runs a byte at a time, so how the bytes arrive must not matter: fed whole
 * and fed in pieces (split where the first byte says), it must give the
 * same events (kind, opcode, payload, close status) and stop at the same
 * byte. Every event must be one the server can act on: a message within
 * ISO_DISPLAY_MAX_CLIENT_MESSAGE, a text message that is UTF-8, a control
 * payload of at most 125 bytes, a close status an endpoint may send (or
 * 1005), a failure status of 1002, 1007 or 1009. */
#include <stdlib.h>
#include <string.h>

#include "display_internal.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size);

static int valid_utf8(const unsigned char *p, size_t n)
{
    iso_display__utf8 u = {0, 0, 0};
    for (size_t i = 0; i < n; i++)
        if (iso_display__utf8_step(&u, p[i]) != 0)
            return 0;
    return u.need == 0;
}

/* Feeds data in pieces of `piece` bytes (0: whole); returns an FNV-1a hash
 * of the events and where it stopped. */
static unsigned long long run(const unsigned char *data, size_t size, size_t piece)
{
    static iso_display__ws_rx rx;
    memset(&rx, 0, sizeof rx);
    unsigned long long h = 0xcbf29ce484222325ULL;
#define MIX(v) (h = (h ^ (unsigned long long)(v)) * 0x100000001b3ULL)
    size_t at = 0;
    while (at < size) {
        size_t n = piece && size - at > piece ? piece : size - at;
        iso_display__ws_event ev;
        size_t used = 0;
        int st = iso_display__ws_rx_feed(&rx, data + at, n, &used, &ev);
        if (used > n || (st == ISO_DISPLAY_WS_MORE && used != n))
            abort();
        at += used;
        if (st == ISO_DISPLAY_WS_MORE)
            continue;
        MIX(st);
        MIX(at);
        if (st == ISO_DISPLAY_WS_MESSAGE) {
            if (ev.len > ISO_DISPLAY_MAX_CLIENT_MESSAGE || (ev.opcode != 1 && ev.opcode != 2) ||
                (ev.opcode == 1 && !valid_utf8(ev.data, ev.len)))
                abort();
            MIX(ev.opcode);
        } else if (st == ISO_DISPLAY_WS_PING && ev.len > 125) {
            abort();
        } else if (st == ISO_DISPLAY_WS_CLOSE) {
            if (ev.code != ISO_DISPLAY_WS_NO_STATUS && !iso_display__ws_close_code_ok(ev.code))
                abort();
            MIX(ev.code);
            return h;
        } else if (st == ISO_DISPLAY_WS_FAIL) {
            if (ev.code != ISO_DISPLAY_WS_PROTOCOL_ERROR && ev.code != ISO_DISPLAY_WS_BAD_DATA &&
                ev.code != ISO_DISPLAY_WS_TOO_BIG)
                abort();
            MIX(ev.code);
            return h;
        }
        if (st == ISO_DISPLAY_WS_MESSAGE || st == ISO_DISPLAY_WS_PING)
            for (size_t i = 0; i < ev.len; i++)
                MIX(ev.data[i]);
    }
    if (rx.hdr_len >= sizeof rx.hdr || rx.msg_len > ISO_DISPLAY_MAX_CLIENT_MESSAGE ||
        rx.ctl_len > sizeof rx.ctl)
        abort();
    MIX(rx.hdr_len);
    MIX(rx.left);
    return h;
#undef MIX
}

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
    if (size < 1)
        return 0;
    size_t piece = (size_t)data[0] % 7 + 1;
    if (run(data + 1, size - 1, 0) != run(data + 1, size - 1, piece))
        abort();
    return 0;
}
