/* view/foxglove.c -- the view's server speaking Foxglove's WebSocket
 * protocol (subprotocol "foxglove.websocket.v1", its specification is
 * public) to a client that offers it: Foxglove Studio connected live.
 *
 * On connect the server sends serverInfo and advertises the session's
 * channels, the same as an MCAP export's (sinks/iso_foxglove.h). The client
 * subscribes (JSON text frames: subscribe, unsubscribe); the server then
 * sends, for the newest published tick, one binary message per subscribed
 * channel: opcode 0x01, u32 subscription id, u64 time (stream time, ns),
 * the JSON payload. The rules are the page's: a client gets the newest tick
 * once it has taken the last batch whole (latest wins, ticks in between are
 * skipped), the tick never waits for it, and a client whose batch is not
 * written ISO_DISPLAY_STALL_MS after it was queued is disconnected. What a
 * client sends is read into a fixed buffer of ISO_DISPLAY_MAX_CLIENT_FRAME
 * bytes; a larger frame closes it (1009).
 *
 * Encoding happens on the server thread, once per published tick for all
 * clients (a cache by tick), never on the loop's. */
#include "display_internal.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "iso_foxglove.h"

#define FOX_SUBPROTOCOL "foxglove.websocket.v1"

/* ---- growable output ------------------------------------------------------ */

typedef struct obuf {
    unsigned char *p;
    size_t n, cap;
    int oom;
} obuf;

static void put(obuf *b, const void *p, size_t n)
{
    if (b->oom)
        return;
    if (b->n + n > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->n + n)
            cap *= 2;
        unsigned char *q = realloc(b->p, cap);
        if (!q) {
            b->oom = 1;
            return;
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->n, p, n);
    b->n += n;
}

static void puts_(obuf *b, const char *s)
{
    put(b, s, strlen(s));
}

/* A JSON string's contents, escaped. */
static void put_escaped(obuf *b, const char *s)
{
    for (; *s; s++) {
        char e[8];
        if (*s == '"' || *s == '\\') {
            e[0] = '\\';
            e[1] = *s;
            put(b, e, 2);
        } else if ((unsigned char)*s < 0x20) {
            snprintf(e, sizeof e, "\\u%04x", (unsigned)(unsigned char)*s);
            put(b, e, 6);
        } else {
            put(b, s, 1);
        }
    }
}

static void put_ws_header(obuf *b, int opcode, size_t len)
{
    unsigned char h[10];
    put(b, h, iso_display__ws_header(h, opcode, len));
}

/* ---- what all clients share ------------------------------------------------ */

struct iso_display__fox_shared {
    iso_fox_encoder *enc;
    iso_fox_channel ch[ISO_FOX_MAX_CHANNELS];
    int n_ch;
    obuf hello;          /* serverInfo and advertise, as two text frames */
    iso_fox_frame frame; /* the newest tick's, copied from publish */
    double *x;           /* its positions */
    unsigned long cached_seq;
    obuf payload[ISO_FOX_MAX_CHANNELS]; /* the cached tick's messages */
    uint64_t cached_t;
};

/* ---- one client -------------------------------------------------------------- */

struct iso_display__fox {
    long sub[ISO_FOX_MAX_CHANNELS]; /* subscription id per channel, -1: none */
    int hello_queued;
    unsigned long seq_sent;
    obuf out; /* the batch being written */
    /* what the client sends, a frame at a time */
    unsigned char hdr[14];
    unsigned hdr_len;
    uint64_t need, got;
    int opcode;
    unsigned char mask[4];
    unsigned char msg[ISO_DISPLAY_MAX_CLIENT_FRAME + 1];
};

int iso_display__fox_offered(const char *req)
{
    /* the header's value lists subprotocols, comma separated */
    for (const char *p = req; (p = strchr(p, '\n')) != NULL;) {
        p++;
        static const char key[] = "sec-websocket-protocol:";
        if (strncasecmp(p, key, sizeof key - 1) != 0)
            continue;
        const char *e = strchr(p, '\r');
        size_t n = e ? (size_t)(e - p) : strlen(p);
        return iso_display__contains_ci(p, n, FOX_SUBPROTOCOL);
    }
    return 0;
}

const char *iso_display__fox_subprotocol(void)
{
    return FOX_SUBPROTOCOL;
}

static void build_hello(iso_display__fox_shared *s, const iso_display *d)
{
    obuf j = {0};
    char tmp[160];
    snprintf(tmp, sizeof tmp,
             "{\"op\":\"serverInfo\",\"name\":\"isoshape\",\"capabilities\":[],"
             "\"supportedEncodings\":[\"json\"],\"metadata\":{},\"sessionId\":\"%d\"}",
             d->port);
    puts_(&j, tmp);
    put_ws_header(&s->hello, 1, j.n);
    put(&s->hello, j.p, j.n);
    j.n = 0;
    puts_(&j, "{\"op\":\"advertise\",\"channels\":[");
    for (int c = 0; c < s->n_ch; c++) {
        snprintf(tmp, sizeof tmp, "%s{\"id\":%d,\"topic\":\"", c ? "," : "", c);
        puts_(&j, tmp);
        put_escaped(&j, s->ch[c].topic);
        puts_(&j, "\",\"encoding\":\"json\",\"schemaName\":\"");
        put_escaped(&j, s->ch[c].schema_name);
        puts_(&j, "\",\"schemaEncoding\":\"jsonschema\",\"schema\":\"");
        put_escaped(&j, s->ch[c].schema);
        puts_(&j, "\"}");
    }
    puts_(&j, "]}");
    put_ws_header(&s->hello, 1, j.n);
    put(&s->hello, j.p, j.n);
    if (j.oom)
        s->hello.oom = 1;
    free(j.p);
}

void iso_display__fox_shared_free(iso_display__fox_shared *s)
{
    if (!s)
        return;
    iso_fox_encoder_destroy(s->enc);
    free(s->hello.p);
    free(s->x);
    for (int c = 0; c < ISO_FOX_MAX_CHANNELS; c++)
        free(s->payload[c].p);
    free(s);
}

int iso_display_foxglove(iso_display *d, const iso_fox_session *session, iso_err *err)
{
    if (!d || !session || session->mesh != d->mesh)
        return iso_err_set(err, ISO_EINVAL, -1, "display: Foxglove needs the display's own mesh");
    if (atomic_load(&d->fox))
        return iso_err_set(err, ISO_EINVAL, -1, "display: Foxglove is on already");
    iso_display__fox_shared *s = calloc(1, sizeof *s);
    int rc = s ? iso_fox_encoder_create(session, &s->enc, err)
               : iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    iso_fox_frame *latest = rc == ISO_OK ? calloc(1, sizeof *latest) : NULL;
    if (rc == ISO_OK) {
        s->n_ch = iso_fox_channels(session, s->ch, ISO_FOX_MAX_CHANNELS);
        s->x = calloc((size_t)d->nv * 3, sizeof *s->x);
        build_hello(s, d);
        if (!s->x || !latest || s->hello.oom)
            rc = iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    }
    if (rc != ISO_OK) {
        free(latest);
        iso_display__fox_shared_free(s);
        return rc;
    }
    pthread_mutex_lock(&d->frame_lock);
    d->fox_frame = latest;
    pthread_mutex_unlock(&d->frame_lock);
    atomic_store(&d->fox, s);
    return ISO_OK;
}

int iso_display_publish_frame(iso_display *d, const iso_fox_frame *f, iso_err *err)
{
    if (!d || !f)
        return iso_err_set(err, ISO_EINVAL, -1, "display: NULL display or frame");
    pthread_mutex_lock(&d->frame_lock);
    int on = d->fox_frame != NULL;
    if (on) {
        *d->fox_frame = *f;
        d->fox_frame->x = NULL;
        d->fox_frame_seq = d->latest_seq; /* the positions published with it */
    }
    pthread_mutex_unlock(&d->frame_lock);
    return on ? ISO_OK
              : iso_err_set(err, ISO_EINVAL, -1, "display: Foxglove is off (iso_display_foxglove)");
}

iso_display__fox *iso_display__fox_create(void)
{
    iso_display__fox *f = calloc(1, sizeof *f);
    for (int c = 0; f && c < ISO_FOX_MAX_CHANNELS; c++)
        f->sub[c] = -1;
    return f;
}

void iso_display__fox_free(iso_display__fox *f)
{
    if (!f)
        return;
    free(f->out.p);
    free(f);
}

/* Encodes the newest tick into the shared cache, if it is not there. */
static int refresh_cache(iso_display *d, iso_display__fox_shared *s)
{
    pthread_mutex_lock(&d->frame_lock);
    unsigned long seq = d->fox_frame_seq;
    int have = seq != 0 && seq != s->cached_seq;
    if (have) {
        s->frame = *d->fox_frame;
        const float *p = (const float *)(d->latest + ISO_DISPLAY_FRAME_HEADER);
        for (int i = 0; i < 3 * d->nv; i++)
            s->x[i] = p[i]; /* the page's float positions: what every viewer sees */
    }
    pthread_mutex_unlock(&d->frame_lock);
    if (!have)
        return s->cached_seq != 0;
    s->frame.x = s->x;
    s->cached_t = (uint64_t)(s->frame.t_ns > 0 ? s->frame.t_ns : 0);
    for (int c = 0; c < s->n_ch; c++) {
        const char *data;
        size_t len;
        s->payload[c].n = 0;
        if (iso_fox_encode(s->enc, &s->ch[c], &s->frame, &data, &len, NULL) == ISO_OK)
            put(&s->payload[c], data, len);
    }
    s->cached_seq = seq;
    return 1;
}

int iso_display__fox_next(iso_display *d, iso_display__fox *f, const unsigned char **body,
                          size_t *len)
{
    iso_display__fox_shared *s = atomic_load(&d->fox);
    f->out.n = 0;
    if (!f->hello_queued) {
        f->hello_queued = 1;
        *body = s->hello.p;
        *len = s->hello.n;
        return 1;
    }
    int any = 0;
    for (int c = 0; c < s->n_ch; c++)
        any |= f->sub[c] >= 0;
    if (!any || !refresh_cache(d, s) || s->cached_seq == f->seq_sent)
        return 0;
    for (int c = 0; c < s->n_ch; c++) {
        if (f->sub[c] < 0)
            continue;
        unsigned char m[13];
        m[0] = 0x01;
        for (int i = 0; i < 4; i++)
            m[1 + i] = (unsigned char)((uint32_t)f->sub[c] >> (8 * i));
        for (int i = 0; i < 8; i++)
            m[5 + i] = (unsigned char)(s->cached_t >> (8 * i));
        put_ws_header(&f->out, 2, sizeof m + s->payload[c].n);
        put(&f->out, m, sizeof m);
        put(&f->out, s->payload[c].p, s->payload[c].n);
    }
    if (f->out.oom)
        return -1;
    f->seq_sent = s->cached_seq;
    *body = f->out.p;
    *len = f->out.n;
    return 1;
}

/* ---- what the client says ---------------------------------------------------- */

/* The integer after `key` (a quoted name and a colon) in [p, e), or -1. */
static long int_after(const char *p, const char *e, const char *key)
{
    size_t k = strlen(key);
    for (; p + k < e; p++)
        if (memcmp(p, key, k) == 0) {
            p += k;
            while (p < e && (isspace((unsigned char)*p) || *p == ':'))
                p++;
            if (p < e && isdigit((unsigned char)*p))
                return strtol(p, NULL, 10);
            return -1;
        }
    return -1;
}

static void on_message(iso_display *d, iso_display__fox *f, char *m, size_t n)
{
    iso_display__fox_shared *s = atomic_load(&d->fox);
    m[n] = 0;
    char *e = m + n;
    if (strstr(m, "\"unsubscribe\"")) {
        char *a = strstr(m, "\"subscriptionIds\"");
        for (char *p = a ? strchr(a, '[') : NULL; p && p < e && *p != ']'; p++) {
            if (!isdigit((unsigned char)*p))
                continue;
            long id = strtol(p, &p, 10);
            for (int c = 0; c < s->n_ch; c++)
                if (f->sub[c] == id)
                    f->sub[c] = -1;
            p--;
        }
    } else if (strstr(m, "\"subscribe\"")) {
        char *a = strstr(m, "\"subscriptions\"");
        for (char *o = a ? strchr(a, '{') : NULL; o; o = strchr(o + 1, '{')) {
            char *close = strchr(o, '}');
            if (!close)
                break;
            long id = int_after(o, close, "\"id\"");
            long ch = int_after(o, close, "\"channelId\"");
            if (id >= 0 && id <= 0xffffffffL && ch >= 0 && ch < s->n_ch)
                f->sub[ch] = id;
            o = close;
        }
    }
    /* other ops (advertise of client channels, parameters...) are not served */
}

/* The frame header's length once its first two bytes are in. */
static unsigned header_len(const unsigned char *h)
{
    unsigned n = 2 + ((h[1] & 0x7f) == 126 ? 2 : (h[1] & 0x7f) == 127 ? 8 : 0);
    return n + ((h[1] & 0x80) ? 4 : 0);
}

int iso_display__fox_rx(iso_display *d, iso_display__fox *f, const unsigned char *p, size_t n)
{
    while (n > 0) {
        if (f->hdr_len < 2 || f->hdr_len < header_len(f->hdr)) {
            f->hdr[f->hdr_len++] = *p++;
            n--;
            if (f->hdr_len < 2 || f->hdr_len < header_len(f->hdr))
                continue;
            const unsigned char *h = f->hdr;
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
            memcpy(f->mask, h + at, 4);
            f->opcode = h[0] & 0x0f;
            if (f->opcode == 8)
                return ISO_DISPLAY_WS_NORMAL;
            if (!(h[0] & 0x80) || f->opcode == 0)
                return ISO_DISPLAY_WS_PROTOCOL_ERROR; /* fragments are not taken */
            f->need = len;
            f->got = 0;
        }
        size_t take = f->need - f->got < n ? (size_t)(f->need - f->got) : n;
        for (size_t i = 0; i < take; i++, f->got++)
            f->msg[f->got] = p[i] ^ f->mask[f->got % 4];
        p += take;
        n -= take;
        if (f->got == f->need) {
            if (f->opcode == 1)
                on_message(d, f, (char *)f->msg, (size_t)f->need);
            f->hdr_len = 0;
        }
    }
    return 0;
}
