/* tests/fuzz/fuzz_fox.c -- what a Foxglove client sends the view's server
 * (view/foxglove_rx.c) under arbitrary bytes. The first byte picks the
 * session's channel count and the piece size: fed whole and fed in pieces,
 * the reader must stop with the same status after the same messages, with
 * the same subscriptions, each one none or a u32 on an existing channel. */
#include <stdlib.h>
#include <string.h>

#include "display_internal.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
    if (size < 1)
        return 0;
    size_t piece = (size_t)data[0] % 7 + 1;
    int n_ch = data[0] >> 3; /* 0..31 */
    data++, size--;
    static iso_display__fox_rx whole, parts;
    iso_display__fox_rx_init(&whole);
    iso_display__fox_rx_init(&parts);
    int a = iso_display__fox_rx_feed(&whole, n_ch, data, size), b = 0;
    for (size_t i = 0; i < size && !b; i += piece)
        b = iso_display__fox_rx_feed(&parts, n_ch, data + i, size - i < piece ? size - i : piece);
    if (a != b || whole.messages != parts.messages)
        abort();
    if (memcmp(whole.sub, parts.sub, sizeof whole.sub) != 0)
        abort();
    if (a && a != ISO_DISPLAY_WS_NORMAL && a != ISO_DISPLAY_WS_PROTOCOL_ERROR &&
        a != ISO_DISPLAY_WS_TOO_BIG)
        abort();
    for (int c = 0; c < ISO_DISPLAY_FOX_MAX_CHANNELS; c++)
        if (whole.sub[c] < -1 || whole.sub[c] > 0xffffffffL || (c >= n_ch && whole.sub[c] != -1))
            abort();
    if (whole.got > ISO_DISPLAY_MAX_CLIENT_FRAME || whole.hdr_len >= sizeof whole.hdr)
        abort();
    return 0;
}
