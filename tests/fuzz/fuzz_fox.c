/* tests/fuzz/fuzz_fox.c -- what a Foxglove client says to the view's server
 * (view/foxglove_live_rx.c) under arbitrary bytes. The first byte picks the
 * session's channel count; the rest is a run of text messages split at
 * newlines. Every message is taken (counted); subscriptions stay none or a
 * u32 on an existing channel; and a message said twice leaves the same
 * subscriptions as said once (subscribe and unsubscribe set, never add). */
#include <stdlib.h>
#include <string.h>

#include "display_internal.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
    if (size < 1)
        return 0;
    int n_ch = data[0] >> 2; /* 0..63 */
    data++, size--;
    static iso_display__fox_rx once, twice;
    iso_display__fox_rx_init(&once);
    iso_display__fox_rx_init(&twice);
    long messages = 0;
    for (size_t at = 0; at <= size;) {
        const unsigned char *nl = memchr(data + at, '\n', size - at);
        size_t n = nl ? (size_t)(nl - (data + at)) : size - at;
        iso_display__fox_rx_message(&once, n_ch, data + at, n);
        iso_display__fox_rx_message(&twice, n_ch, data + at, n);
        iso_display__fox_rx_message(&twice, n_ch, data + at, n);
        messages++;
        at += n + 1;
    }
    if (once.messages != messages || twice.messages != 2 * messages)
        abort();
    if (memcmp(once.sub, twice.sub, sizeof once.sub) != 0)
        abort();
    for (int c = 0; c < ISO_DISPLAY_FOX_MAX_CHANNELS; c++)
        if (once.sub[c] < -1 || once.sub[c] > 0xffffffffL || (c >= n_ch && once.sub[c] != -1))
            abort();
    return 0;
}
