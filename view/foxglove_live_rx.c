/* view/foxglove_live_rx.c -- what a Foxglove client says to the view's server
 * (foxglove_live.c): of its text messages, whole (the server's WebSocket reader
 * framed them), the two the server takes, subscribe and unsubscribe.
 * Everything else is read and ignored. Apart from the rest of the protocol
 * so that a fuzz target takes it alone (tests/fuzz). */
#include "display_internal.h"

#include <ctype.h>
#include <stdarg.h>
#include <stdio.h>
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

static void tell(iso_display__fox_rx *rx, const char *fmt, ...) ISO_PRINTF(2, 3);
static void tell(iso_display__fox_rx *rx, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(rx->status, sizeof rx->status, fmt, ap);
    va_end(ap);
    rx->status_ver++;
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
        else if (ch >= n_ch)
            tell(rx, "channel %ld is not advertised: not subscribed", ch);
        o = close;
    }
}

/* The op's name: the string after "op" and its colon, at most cap - 1
 * characters of it (quotes and escapes not followed: names are plain). */
static void op_name(const char *op, char *out, size_t cap)
{
    const char *q = strchr(op + 4, '"');
    size_t k = 0;
    if (q)
        for (q++; *q && *q != '"' && k + 1 < cap; q++)
            out[k++] = isprint((unsigned char)*q) ? *q : '?';
    out[k] = 0;
}

void iso_display__fox_rx_message(iso_display__fox_rx *rx, int n_ch, const unsigned char *p,
                                 size_t n)
{
    if (n_ch > ISO_DISPLAY_FOX_MAX_CHANNELS)
        n_ch = ISO_DISPLAY_FOX_MAX_CHANNELS;
    if (n > ISO_DISPLAY_MAX_CLIENT_MESSAGE)
        n = ISO_DISPLAY_MAX_CLIENT_MESSAGE;
    char *m = rx->msg;
    memcpy(m, p, n);
    m[n] = 0; /* a NUL inside ends the text early: what follows is not read */
    rx->messages++;
    const char *op = strstr(m, "\"op\"");
    if (!op)
        return;
    char name[48];
    op_name(op, name, sizeof name);
    if (strcmp(name, "unsubscribe") == 0)
        unsubscribe(rx, n_ch, m, m + strlen(m));
    else if (strcmp(name, "subscribe") == 0)
        subscribe(rx, n_ch, m);
    else /* client channels, parameters, services: not served, and said so */
        tell(rx, "op '%s' is not served here", name);
}
