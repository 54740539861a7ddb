/* view/foxglove_rx.c -- what a Foxglove client sends the view's server
 * (foxglove.c): WebSocket frames, masked, read into a fixed buffer a byte
 * run at a time, and the two messages the server takes, subscribe and
 * unsubscribe. Everything else is read and ignored. Apart from the rest of
 * the protocol so that a fuzz target takes it alone (tests/fuzz). */
#include "display_internal.h"

#include <ctype.h>
#include <stdlib.h>
#include <string.h>

void iso_display__fox_rx_init(iso_display__fox_rx *rx)
{
    memset(rx, 0, sizeof *rx);
    for (int c = 0; c < ISO_DISPLAY_FOX_MAX_CHANNELS; c++)
        rx->sub[c] = -1;
}

/* The integer after `key` (a quoted name, then a colon) in [p, e), or -1
 * when there is none or it is out of a u32's range. */
static long int_after(const char *p, const char *e, const char *key)
{
    size_t k = strlen(key);
    for (; p + k < e; p++) {
        if (memcmp(p, key, k) != 0)
            continue;
        p += k;
        while (p < e && (isspace((unsigned char)*p) || *p == ':'))
            p++;
        long v = 0;
        int digits = 0;
        for (; p < e && isdigit((unsigned char)*p) && digits < 11; p++, digits++)
            v = v * 10 + (*p - '0');
        return digits > 0 && digits < 11 && v <= 0xffffffffL ? v : -1;
    }
    return -1;
}

static void unsubscribe(iso_display__fox_rx *rx, int n_ch, const char *m, const char *e)
{
    const char *a = strstr(m, "\"subscriptionIds\"");
    const char *p = a ? strchr(a, '[') : NULL;
    while (p && p < e && *p != ']') {
        if (!isdigit((unsigned char)*p)) {
            p++;
            continue;
        }
        long id = 0;
        int digits = 0;
        for (; p < e && isdigit((unsigned char)*p); p++, digits++)
            if (digits < 11)
                id = id * 10 + (*p - '0');
        for (int c = 0; c < n_ch && digits < 11; c++)
            if (rx->sub[c] == id)
                rx->sub[c] = -1;
    }
}

static void subscribe(iso_display__fox_rx *rx, int n_ch, const char *m)
{
    const char *a = strstr(m, "\"subscriptions\"");
    for (const char *o = a ? strchr(a, '{') : NULL; o; o = strchr(o + 1, '{')) {
        const char *close = strchr(o, '}');
        if (!close)
            break;
        long id = int_after(o, close, "\"id\"");
        long ch = int_after(o, close, "\"channelId\"");
        if (id >= 0 && ch >= 0 && ch < n_ch)
            rx->sub[ch] = id;
        o = close;
    }
}

/* One text message, NUL-terminated in its buffer. */
static void on_message(iso_display__fox_rx *rx, int n_ch, char *m, size_t n)
{
    m[n] = 0;
    rx->messages++;
    const char *op = strstr(m, "\"op\"");
    if (!op)
        return;
    if (strstr(op, "\"unsubscribe\""))
        unsubscribe(rx, n_ch, m, m + strlen(m));
    else if (strstr(op, "\"subscribe\""))
        subscribe(rx, n_ch, m);
    /* other ops (client channels, parameters, services) are not served */
}

/* The frame header's length once its first two bytes are in. */
static unsigned header_len(const unsigned char *h)
{
    unsigned n = 2 + ((h[1] & 0x7f) == 126 ? 2 : (h[1] & 0x7f) == 127 ? 8 : 0);
    return n + ((h[1] & 0x80) ? 4 : 0);
}

/* The header is whole: check it and start its payload. 0 to go on, else
 * the status to close with. */
static int header_done(iso_display__fox_rx *rx)
{
    const unsigned char *h = rx->hdr;
    if (!(h[1] & 0x80) || (h[0] & 0x70))
        return ISO_DISPLAY_WS_PROTOCOL_ERROR; /* unmasked, or reserved bits */
    uint64_t len = h[1] & 0x7f;
    unsigned at = 2;
    if (len == 126) {
        len = (uint64_t)h[2] << 8 | h[3];
        at = 4;
    } else if (len == 127) {
        len = 0;
        for (int i = 0; i < 8; i++)
            len = len << 8 | h[2 + i];
        at = 10;
    }
    if (len > ISO_DISPLAY_MAX_CLIENT_FRAME)
        return ISO_DISPLAY_WS_TOO_BIG;
    memcpy(rx->mask, h + at, 4);
    rx->opcode = h[0] & 0x0f;
    if (rx->opcode == 8)
        return ISO_DISPLAY_WS_NORMAL;
    if (!(h[0] & 0x80) || rx->opcode == 0)
        return ISO_DISPLAY_WS_PROTOCOL_ERROR; /* fragments are not taken */
    rx->need = len;
    rx->got = 0;
    rx->in_payload = 1;
    return 0;
}

int iso_display__fox_rx_feed(iso_display__fox_rx *rx, int n_ch, const unsigned char *p, size_t n)
{
    if (n_ch > ISO_DISPLAY_FOX_MAX_CHANNELS)
        n_ch = ISO_DISPLAY_FOX_MAX_CHANNELS;
    while (n > 0 || rx->in_payload) {
        if (!rx->in_payload) {
            rx->hdr[rx->hdr_len++] = *p++;
            n--;
            if (rx->hdr_len < 2 || rx->hdr_len < header_len(rx->hdr))
                continue;
            int st = header_done(rx);
            rx->hdr_len = 0;
            if (st)
                return st;
        }
        size_t take = rx->need - rx->got < n ? (size_t)(rx->need - rx->got) : n;
        for (size_t i = 0; i < take; i++, rx->got++)
            rx->msg[rx->got] = p[i] ^ rx->mask[rx->got % 4];
        p += take;
        n -= take;
        if (rx->got < rx->need)
            return 0; /* the rest of the payload comes later */
        if (rx->opcode == 1)
            on_message(rx, n_ch, (char *)rx->msg, (size_t)rx->need);
        rx->in_payload = 0;
    }
    return 0;
}
