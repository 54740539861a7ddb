/* view/foxglove_live.c -- the view's server speaking Foxglove's WebSocket
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
 * client sends is read into a fixed buffer of ISO_DISPLAY_MAX_CLIENT_MESSAGE
 * bytes; a larger frame closes it (1009).
 *
 * Encoding happens once per published tick for all clients, on a thread of
 * its own, never on the loop's and never on the server's: a large mesh's
 * JSON takes 7 ms (median, 40k vertices) to 22 ms, and the server thread,
 * which reads a page's STOP, must not spend that between two reads. The
 * encoder fills one of two buffers while the server copies clients'
 * batches out of the other, and swaps them under a lock held for the swap
 * and for those copies. */
#include "display_internal.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "iso_bytes.h"
#include "iso_foxglove.h"
#include "iso_thread.h"

#define FOX_SUBPROTOCOL "foxglove.websocket.v1"

/* ---- growable output ------------------------------------------------------ */

typedef iso_bytes obuf;

static void puts_(obuf *b, const char *s)
{
    iso_bytes_put(b, s, strlen(s));
}

/* A JSON string's contents, escaped. */
static void put_escaped(obuf *b, const char *s)
{
    for (; *s; s++) {
        char e[8];
        if (*s == '"' || *s == '\\') {
            e[0] = '\\';
            e[1] = *s;
            iso_bytes_put(b, e, 2);
        } else if ((unsigned char)*s < 0x20) {
            snprintf(e, sizeof e, "\\u%04x", (unsigned)(unsigned char)*s);
            iso_bytes_put(b, e, 6);
        } else {
            iso_bytes_put(b, s, 1);
        }
    }
}

static void put_ws_header(obuf *b, int opcode, size_t len)
{
    unsigned char h[10];
    iso_bytes_put(b, h, iso_display__ws_header(h, opcode, len));
}

/* ---- what all clients share ------------------------------------------------ */

struct iso_display__fox_shared {
    iso_display *d;
    iso_fox_encoder *enc;
    iso_fox_channel ch[ISO_FOX_MAX_CHANNELS];
    int n_ch;
    obuf hello; /* serverInfo and advertise, as two text frames */
    /* the encoder's own */
    iso_sink_frame frame; /* the newest tick's, copied from publish */
    double *x;            /* its positions */
    unsigned long encoded_seq;
    pthread_t thread;
    int started;
    /* under mu: the published tick, the encoder's wake-up */
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int want, quit;
    int pub;                               /* which of payload[] is published */
    obuf payload[2][ISO_FOX_MAX_CHANNELS]; /* a tick's messages, by channel */
    unsigned long cached_seq;              /* the published tick (0: none yet) */
    uint64_t cached_t;
};

/* ---- one client -------------------------------------------------------------- */

_Static_assert(ISO_FOX_MAX_CHANNELS <= ISO_DISPLAY_FOX_MAX_CHANNELS,
               "every channel can be subscribed");

struct iso_display__fox {
    iso_display__fox_rx rx; /* what the client says, and its subscriptions */
    int hello_queued;
    long status_sent; /* rx.status_ver when the last status went out */
    unsigned long seq_sent;
    obuf out; /* the batch being written */
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
        return iso_display__list_has(p, n, FOX_SUBPROTOCOL);
    }
    return 0;
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
    iso_bytes_put(&s->hello, j.p, j.n);
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
    iso_bytes_put(&s->hello, j.p, j.n);
    if (j.oom)
        s->hello.oom = 1;
    free(j.p);
}

void iso_display__fox_shared_free(iso_display__fox_shared *s)
{
    if (!s)
        return;
    if (s->started) {
        pthread_mutex_lock(&s->mu);
        s->quit = 1;
        pthread_cond_signal(&s->cv);
        pthread_mutex_unlock(&s->mu);
        pthread_join(s->thread, NULL);
    }
    pthread_cond_destroy(&s->cv);
    pthread_mutex_destroy(&s->mu);
    iso_fox_encoder_destroy(s->enc);
    free(s->hello.p);
    free(s->x);
    for (int b = 0; b < 2; b++)
        for (int c = 0; c < ISO_FOX_MAX_CHANNELS; c++)
            free(s->payload[b][c].p);
    free(s);
}

/* Copies the newest published tick, if the encoder has not had it: 1, or
 * 0 when there is nothing new. */
static int take_frame(iso_display__fox_shared *s)
{
    iso_display *d = s->d;
    pthread_mutex_lock(&d->frame_lock);
    unsigned long seq = d->fox_frame_seq;
    int have = seq != 0 && seq != s->encoded_seq;
    if (have) {
        s->frame = *d->fox_frame;
        const float *p = (const float *)(d->latest + ISO_DISPLAY_FRAME_HEADER +
                                         (size_t)ISO_DISPLAY_FRAME_POSE * (size_t)d->nh);
        for (int i = 0; i < 3 * d->nv; i++)
            s->x[i] = p[i]; /* the page's float positions: what every viewer sees */
        s->encoded_seq = seq;
    }
    pthread_mutex_unlock(&d->frame_lock);
    s->frame.x = s->x;
    return have;
}

/* The encoder: woken by the server when a client is due a tick, it
 * encodes the newest one into the buffer not published, swaps, and wakes
 * the server to send it. */
static void *encoder_main(void *arg)
{
    iso_display__fox_shared *s = arg;
    for (;;) {
        pthread_mutex_lock(&s->mu);
        while (!s->want && !s->quit)
            pthread_cond_wait(&s->cv, &s->mu);
        int quit = s->quit, next = 1 - s->pub;
        s->want = 0;
        pthread_mutex_unlock(&s->mu);
        if (quit)
            return NULL;
        if (!take_frame(s))
            continue;
        for (int c = 0; c < s->n_ch; c++) {
            const char *data;
            size_t len;
            s->payload[next][c].n = 0;
            if (iso_fox_encode(s->enc, &s->ch[c], &s->frame, &data, &len, NULL) == ISO_OK)
                iso_bytes_put(&s->payload[next][c], data, len);
        }
        pthread_mutex_lock(&s->mu);
        s->pub = next;
        s->cached_seq = s->encoded_seq;
        s->cached_t = (uint64_t)(s->frame.t_ns > 0 ? s->frame.t_ns : 0);
        pthread_mutex_unlock(&s->mu);
        iso_display__wake(s->d);
    }
}

static int start_encoder(iso_display__fox_shared *s, iso_err *err)
{
    int rc = iso_thread_start(&s->thread, encoder_main, s);
    if (rc != 0)
        return iso_err_set(err, ISO_EIO, -1, "display: cannot start Foxglove's encoder: %s",
                           strerror(rc));
    s->started = 1;
    return ISO_OK;
}

int iso_display_foxglove(iso_display *d, const iso_sink_session *session, iso_err *err)
{
    if (!d || !session || session->mesh != d->mesh)
        return iso_err_set(err, ISO_EINVAL, -1, "display: Foxglove needs the display's own mesh");
    if (atomic_load(&d->fox))
        return iso_err_set(err, ISO_EINVAL, -1, "display: Foxglove is on already");
    iso_display__fox_shared *s = calloc(1, sizeof *s);
    if (s) {
        s->d = d;
        pthread_mutex_init(&s->mu, NULL);
        pthread_cond_init(&s->cv, NULL);
    }
    int rc = s ? iso_fox_encoder_create(session, &s->enc, err)
               : iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    iso_sink_frame *latest = rc == ISO_OK ? calloc(1, sizeof *latest) : NULL;
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
    if ((rc = start_encoder(s, err)) != ISO_OK) {
        pthread_mutex_lock(&d->frame_lock);
        d->fox_frame = NULL;
        pthread_mutex_unlock(&d->frame_lock);
        free(latest);
        iso_display__fox_shared_free(s);
        return rc;
    }
    atomic_store(&d->fox, s);
    return ISO_OK;
}

int iso_display_publish_frame(iso_display *d, const iso_sink_frame *f, iso_err *err)
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

/* ---- the connection kind (display_internal.h, iso_display__proto) --------- */

static int fox_open(iso_display *d, iso_display__conn *c, const iso_display__request *r)
{
    (void)d;
    (void)r;
    c->fox = calloc(1, sizeof *c->fox);
    if (!c->fox)
        return 503;
    iso_display__fox_rx_init(&c->fox->rx);
    return 0;
}

static void fox_close(iso_display *d, iso_display__conn *c)
{
    (void)d;
    if (c->fox)
        free(c->fox->out.p);
    free(c->fox);
    c->fox = NULL;
}

static int fox_message(iso_display *d, iso_display__conn *c, int opcode, const unsigned char *p,
                       size_t n)
{
    if (opcode == 1) /* binary messages (client channels) are not served */
        iso_display__fox_rx_message(&c->fox->rx, atomic_load(&d->fox)->n_ch, p, n);
    return 0;
}

/* serverInfo and advertise first; then, once something is subscribed, the
 * newest tick it has not had, one binary message per subscribed channel,
 * written as one batch. */
static int fox_next(iso_display *d, iso_display__conn *c, long long now)
{
    (void)now;
    iso_display__fox_shared *s = atomic_load(&d->fox);
    iso_display__fox *f = c->fox;
    f->out.n = 0;
    if (!f->hello_queued) {
        f->hello_queued = 1;
        iso_display__set_output(c, s->hello.p, s->hello.n);
        return 1;
    }
    if (f->status_sent != f->rx.status_ver) { /* what it asked that is not served */
        f->status_sent = f->rx.status_ver;
        puts_(&f->out, "{\"op\":\"status\",\"level\":1,\"message\":\"");
        put_escaped(&f->out, f->rx.status);
        puts_(&f->out, "\"}");
        if (f->out.oom)
            return 0;
        iso_display__queue_message(c, 1, f->out.p, f->out.n);
        return 1;
    }
    int any = 0;
    for (int ch = 0; ch < s->n_ch; ch++)
        any |= f->rx.sub[ch] >= 0;
    if (!any)
        return 0;
    pthread_mutex_lock(&s->mu);
    if (atomic_load(&d->published) != s->cached_seq) { /* a newer tick to encode */
        s->want = 1;
        pthread_cond_signal(&s->cv);
    }
    if (s->cached_seq == 0 || s->cached_seq == f->seq_sent) {
        pthread_mutex_unlock(&s->mu);
        return 0;
    }
    for (int ch = 0; ch < s->n_ch; ch++) {
        if (f->rx.sub[ch] < 0)
            continue;
        unsigned char m[13];
        m[0] = 0x01;
        for (int i = 0; i < 4; i++)
            m[1 + i] = (unsigned char)((uint32_t)f->rx.sub[ch] >> (8 * i));
        for (int i = 0; i < 8; i++)
            m[5 + i] = (unsigned char)(s->cached_t >> (8 * i));
        const obuf *pl = &s->payload[s->pub][ch];
        put_ws_header(&f->out, 2, sizeof m + pl->n);
        iso_bytes_put(&f->out, m, sizeof m);
        iso_bytes_put(&f->out, pl->p, pl->n);
    }
    unsigned long seq = s->cached_seq;
    pthread_mutex_unlock(&s->mu);
    if (f->out.oom)
        return 0; /* out of memory: this tick is skipped, the next may fit */
    f->seq_sent = seq;
    iso_display__set_output(c, f->out.p, f->out.n);
    return 1;
}

const iso_display__proto iso_display__fox_proto = {FOX_SUBPROTOCOL, fox_open, fox_message, fox_next,
                                                   fox_close};
