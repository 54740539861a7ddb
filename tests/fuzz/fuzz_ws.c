/* tests/fuzz/fuzz_ws.c -- the live view's parser of what a browser sends
 * over its WebSocket (view/display_ws.c) under arbitrary bytes. The parser
 * runs a byte at a time, so how the bytes arrive must not matter: fed whole
 * and fed in pieces (split where the first byte says), it must stop with
 * the same status after the same frames, or go on with the same state. */
#include <stdlib.h>
#include <string.h>

#include "display_internal.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
    if (size < 1)
        return 0;
    size_t piece = (size_t)data[0] % 7 + 1;
    data++, size--;
    iso_display__ws_rx whole, parts;
    memset(&whole, 0, sizeof whole);
    memset(&parts, 0, sizeof parts);
    int a = iso_display__ws_rx_feed(&whole, data, size), b = 0;
    for (size_t i = 0; i < size && !b; i += piece)
        b = iso_display__ws_rx_feed(&parts, data + i, size - i < piece ? size - i : piece);
    if (a != b || whole.frames != parts.frames)
        abort();
    if (!a && (whole.skip != parts.skip || whole.hdr_len != parts.hdr_len))
        abort();
    if (a && a != ISO_DISPLAY_WS_NORMAL && a != ISO_DISPLAY_WS_PROTOCOL_ERROR &&
        a != ISO_DISPLAY_WS_TOO_BIG)
        abort();
    if (whole.hdr_len >= sizeof whole.hdr || whole.skip > ISO_DISPLAY_MAX_CLIENT_FRAME)
        abort();
    return 0;
}
