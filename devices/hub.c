/* devices/hub.c -- sources, their decoders, the recording and reconnects.
 *
 * The hub is what turns "a device went away" into one message, a GONE event
 * (its handles hold still) and a retry every retry interval, and what makes
 * live and replayed runs the same: every chunk it decodes is first written
 * to the recording, and a live chunk is never stamped later than the tick
 * that drains it, so a replay drains the same chunks into the same ticks. */
#include "iso_dev_hub.h"

#include <inttypes.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "iso_dev_decode.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"

#define HUB_EVENTS 2048u

/* The noise cap's state for one source while recording: the second of
 * stream time it counts, the noise bytes recorded in it, and the chunks
 * left out since the last record of the source (RECORDING.md). */
typedef struct hub_cap {
    int64_t window;
    uint32_t used;
    uint32_t skip_bytes, skip_chunks; /* 0 chunks: none pending */
    iso_dev_decoder first;            /* the decoder before the first one left out */
} hub_cap;

typedef struct hub_src {
    iso_dev_source *s; /* NULL while gone */
    iso_dev_info info;
    iso_dev_reopen_fn reopen;
    void *reopen_ctx;
    int64_t next_try;
    iso_dev_decoder dec;
    char detail[ISO_DEV_NAME_MAX]; /* the source's detail when it was last opened */
    uint8_t present;               /* 0 while gone */
    uint8_t stale;                 /* its twist counted zero in the last tick */
    uint8_t targeting;             /* a view: a fresh target drove its handle last tick */
    int64_t quiet_from;            /* stream time of the last twist before it went stale */
    uint32_t events, gone, back, stale_count;
    uint8_t estop_line; /* the source has an e-stop input (estop_level answers) */
    uint8_t noise_told; /* the noise message went out for the present stretch */
    uint8_t threaded;   /* its reads are the reader thread's (hub_reader.c) */
    hub_cap cap;
} hub_src;

struct iso_dev_hub {
    hub_src src[ISO_DEV_MAX_SOURCES];
    size_t n;
    iso_dev_source *mux; /* a replay: every chunk names its source */
    iso_dev_notify_fn notify;
    void *notify_ctx;
    int64_t retry_ns;
    int retry_now;
    int retry_kept; /* retry_now holds for the next drain too */
    int recording;
    iso_dev_rec_writer rec;
    int64_t last_tick;
    int ticked;
    long tick_records;           /* replay: TICK records drained so far */
    iso_dev_decoder before;      /* take(): a decoder before its chunk, for the noise cap */
    iso_dev__reader *reader;     /* reads the byte streams (hub_reader.c); NULL until one */
    iso_dev__reopener *reopener; /* reopens gone sources (hub_reopen.c); NULL until one */
    iso_dev_event ev[HUB_EVENTS];
    size_t nev;
    /* Guards src[].s and n against iso_dev_hub_estop_probe on another
     * thread: held to swap a pointer or to read the lines, never across a
     * device open, a close or a read of input. */
    pthread_mutex_t line_mu;
};

/* Sets source i's pointer under line_mu and returns the old one. */
static iso_dev_source *swap_source(iso_dev_hub *h, size_t i, iso_dev_source *s)
{
    pthread_mutex_lock(&h->line_mu);
    iso_dev_source *old = h->src[i].s;
    h->src[i].s = s;
    pthread_mutex_unlock(&h->line_mu);
    return old;
}

static void say(iso_dev_hub *h, const char *fmt, ...) ISO_PRINTF(2, 3);
static void say(iso_dev_hub *h, const char *fmt, ...)
{
    if (!h->notify)
        return;
    char msg[600];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    h->notify(h->notify_ctx, msg);
}

int iso_dev_hub_create(iso_dev_notify_fn notify, void *notify_ctx, iso_dev_hub **out, iso_err *err)
{
    *out = calloc(1, sizeof **out);
    if (!*out)
        return iso_err_set(err, ISO_ENOMEM, -1, "device hub: out of memory");
    (*out)->notify = notify;
    (*out)->notify_ctx = notify_ctx;
    (*out)->retry_ns = 500000000;
    /* the loop's tick and the actuators' sender both take it: whoever holds
     * it runs at the other's priority until it lets go */
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&(*out)->line_mu, &ma);
    pthread_mutexattr_destroy(&ma);
    return ISO_OK;
}

void iso_dev_hub_destroy(iso_dev_hub *h)
{
    if (!h)
        return;
    iso_dev__reader_destroy(h->reader); /* first: it may be reading a source */
    iso_dev__reopener_destroy(h->reopener);
    for (size_t i = 0; i < h->n; i++)
        iso_dev_source_close(swap_source(h, i, NULL));
    iso_dev_source_close(h->mux);
    if (h->recording && iso_dev_rec_writer_close(&h->rec, NULL) != ISO_OK)
        say(h, "recording %s: could not be closed cleanly", h->rec.path);
    pthread_mutex_destroy(&h->line_mu);
    free(h);
}

/* A byte stream with a descriptor goes to the reader thread (started with
 * the first); other sources (HID reports, spacenavd events, GPIO edges,
 * fakes) are read by the tick itself, which no kernel work delays. */
static int hand_over(iso_dev_hub *h, size_t i, iso_err *err)
{
    hub_src *x = &h->src[i];
    x->threaded = 0;
    if (x->info.kind != ISO_DEV_KIND_SERIAL || iso_dev_source_fd(x->s) < 0)
        return ISO_OK;
    int rc = h->reader ? ISO_OK : iso_dev__reader_create(&h->reader, err);
    if (rc == ISO_OK)
        rc = iso_dev__reader_attach(h->reader, i, x->s, err);
    x->threaded = rc == ISO_OK;
    return rc;
}

int iso_dev_hub_sync(iso_dev_hub *h, int timeout_ms)
{
    int ok = !h || !h->reader || iso_dev__reader_sync(h->reader, timeout_ms);
    return ok && (!h || !h->reopener || iso_dev__reopener_sync(h->reopener, timeout_ms));
}

int iso_dev_hub_set_priority(iso_dev_hub *h, int priority, iso_err *err)
{
    if (!h || priority < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "device hub: priority %d: expected 0 or more",
                           priority);
    return h->reader ? iso_dev__reader_priority(h->reader, priority, err) : ISO_OK;
}

int iso_dev_hub_add(iso_dev_hub *h, iso_dev_source *s, iso_dev_reopen_fn reopen, void *reopen_ctx,
                    iso_err *err)
{
    if (s->multiplexed) {
        const iso_dev_rec_reader *r = iso_dev_replay_reader(s);
        if (h->n || !r) {
            iso_dev_source_close(s);
            return iso_err_set(err, ISO_EINVAL, -1,
                               "device hub: a replay must be the hub's only source");
        }
        for (size_t i = 0; i < r->n_sources; i++) {
            h->src[i].info = r->infos[i];
            h->src[i].present = 1;
            int rc = iso_dev_decoder_init(&h->src[i].dec, &r->infos[i], (uint8_t)i, err);
            if (rc != ISO_OK) {
                iso_dev_source_close(s);
                h->n = 0;
                return rc;
            }
        }
        h->n = r->n_sources;
        h->mux = s;
        return ISO_OK;
    }
    if (h->mux || h->n >= ISO_DEV_MAX_SOURCES) {
        iso_dev_source_close(s);
        return iso_err_set(err, ISO_EINVAL, -1, "device hub: %s",
                           h->mux ? "a replay must be the hub's only source"
                                  : "too many sources (at most 16)");
    }
    hub_src *x = &h->src[h->n];
    memset(x, 0, sizeof *x);
    x->info = s->info;
    int rc = iso_dev_decoder_init(&x->dec, &s->info, (uint8_t)h->n, err);
    if (rc != ISO_OK) {
        iso_dev_source_close(s);
        return rc;
    }
    if (reopen && !h->reopener && (rc = iso_dev__reopener_create(&h->reopener, err)) != ISO_OK) {
        iso_dev_source_close(s);
        return rc;
    }
    x->present = 1;
    memcpy(x->detail, s->detail, sizeof x->detail);
    x->reopen = reopen;
    x->reopen_ctx = reopen_ctx;
    x->estop_line = s->ops->estop_level && s->ops->estop_level(s) != ISO_ENOTSUP;
    pthread_mutex_lock(&h->line_mu);
    x->s = s;
    h->n++;
    pthread_mutex_unlock(&h->line_mu);
    return hand_over(h, h->n - 1, err);
}

int iso_dev_hub_estop_probe(void *hub)
{
    iso_dev_hub *h = hub;
    int pressed = 0;
    pthread_mutex_lock(&h->line_mu);
    for (size_t i = 0; i < h->n && !pressed; i++) {
        const hub_src *x = &h->src[i];
        if (!x->estop_line)
            continue;
        /* gone or unreadable: the e-stop circuit cannot be trusted */
        int v = x->s ? x->s->ops->estop_level(x->s) : ISO_EIO;
        pressed = v != 0 && v != ISO_ENOTSUP;
    }
    pthread_mutex_unlock(&h->line_mu);
    return pressed;
}

int iso_dev_hub_has_estop(const iso_dev_hub *h)
{
    for (size_t i = 0; i < h->n; i++)
        if (h->src[i].estop_line)
            return 1;
    return 0;
}

size_t iso_dev_hub_sources(const iso_dev_hub *h)
{
    return h->n;
}
const iso_dev_decoder *iso_dev_hub_decoder(const iso_dev_hub *h, size_t i)
{
    return i < h->n ? &h->src[i].dec : NULL;
}
int iso_dev_hub_source_stats(const iso_dev_hub *h, size_t i, iso_dev_source_stats *out)
{
    memset(out, 0, sizeof *out);
    if (i >= h->n)
        return ISO_EINVAL;
    const hub_src *x = &h->src[i];
    out->dec = x->dec.n;
    iso_dev_decoder_drops(&x->dec, &out->drops);
    out->events = x->events;
    out->gone = x->gone;
    out->back = x->back;
    out->stale = x->stale_count;
    out->present = x->present;
    out->is_stale = x->stale;
    out->targeting = x->targeting;
    out->holder = x->dec.view.holder != 0;
    return ISO_OK;
}

/* "hid /dev/hidraw3 (256f:c635 SpaceMouse Compact)", "spnav spacenavd
 * (socket /var/run/spnav.sock)", "serial /dev/ttyACM0 (115200 8N1)". */
int iso_dev_hub_describe(const iso_dev_hub *h, size_t i, char *buf, size_t cap)
{
    if (i >= h->n) {
        if (cap)
            buf[0] = '\0';
        return ISO_EINVAL;
    }
    const hub_src *x = &h->src[i];
    const iso_dev_info *f = &x->info;
    char more[3][ISO_DEV_NAME_MAX + 16];
    int n = 0;
    if (f->vid || f->pid)
        snprintf(more[n++], sizeof more[0], "%04x:%04x%s%s", f->vid, f->pid,
                 x->detail[0] && f->kind == ISO_DEV_KIND_HID ? " " : "",
                 f->kind == ISO_DEV_KIND_HID ? x->detail : "");
    else if (x->detail[0] && f->kind == ISO_DEV_KIND_HID)
        snprintf(more[n++], sizeof more[0], "%s", x->detail);
    if (f->kind == ISO_DEV_KIND_SPNAV && x->detail[0])
        snprintf(more[n++], sizeof more[0], "socket %s", x->detail);
    if (f->baud)
        snprintf(more[n++], sizeof more[0], "%u %u%c%u", f->baud, f->data_bits,
                 f->parity ? f->parity : 'N', f->stop_bits);
    else if (f->kind == ISO_DEV_KIND_GPIO)
        snprintf(more[n++], sizeof more[0], "debounce %u us", f->debounce_us);
    if (h->mux && n < 3)
        snprintf(more[n++], sizeof more[0], "replayed");
    int len = snprintf(buf, cap, "%s %s", iso_dev_kind_name(f->kind), f->name);
    for (int k = 0; k < n && len >= 0 && (size_t)len < cap; k++)
        len += snprintf(buf + len, cap - (size_t)len, "%s%s%s", k ? ", " : " (", more[k],
                        k == n - 1 ? ")" : "");
    return ISO_OK;
}

void iso_dev_hub_set_retry(iso_dev_hub *h, int64_t retry_ns)
{
    h->retry_ns = retry_ns;
}
void iso_dev_hub_retry_now(iso_dev_hub *h)
{
    h->retry_now = 1;
}

size_t iso_dev_hub_infos(const iso_dev_hub *h, iso_dev_info *infos, size_t cap)
{
    for (size_t i = 0; i < h->n && i < cap; i++)
        infos[i] = h->src[i].info;
    return h->n;
}

int iso_dev_hub_record_attach(iso_dev_hub *h, const iso_dev_rec_writer *w, iso_err *err)
{
    if (h->recording)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: already recording to %s", w->path,
                           h->rec.path);
    h->rec = *w;
    h->recording = 1;
    for (size_t i = 0; i < h->n; i++)
        memset(&h->src[i].cap, 0, sizeof h->src[i].cap);
    return ISO_OK;
}

int iso_dev_hub_record_start(iso_dev_hub *h, const char *path, iso_err *err)
{
    if (h->recording)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: already recording to %s", path, h->rec.path);
    iso_dev_info infos[ISO_DEV_MAX_SOURCES];
    size_t n = iso_dev_hub_infos(h, infos, ISO_DEV_MAX_SOURCES);
    iso_dev_rec_writer w;
    int rc = iso_dev_rec_writer_open(&w, path, infos, n, iso_clock_ns(), err);
    return rc == ISO_OK ? iso_dev_hub_record_attach(h, &w, err) : rc;
}

/* The chunks of source i left out since its last record, as one SKIP
 * record; `after` is its decoder after the last of them. The record bears
 * the last one's time, which a replay's decoder takes as the latest noise,
 * so that the noise message comes in the same tick. */
static int flush_skip(iso_dev_hub *h, size_t i, const iso_dev_decoder *after, iso_err *err)
{
    hub_cap *k = &h->src[i].cap;
    if (!k->skip_chunks || !h->recording)
        return ISO_OK;
    iso_dev_chunk c;
    memset(&c, 0, sizeof c);
    c.t_ns = after->noise_last;
    c.source = (uint8_t)i;
    c.type = ISO_DEV_CHUNK_SKIP;
    int len = iso_dev__skip_encode(after, &k->first, k->skip_bytes, k->skip_chunks, c.data,
                                   sizeof c.data);
    k->skip_bytes = k->skip_chunks = 0;
    if (len < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: a SKIP record does not fit", h->rec.path);
    c.len = (uint16_t)len;
    return iso_dev_rec_write(&h->rec, &c, err);
}

static int flush_skips(iso_dev_hub *h, iso_err *err)
{
    int rc = ISO_OK;
    for (size_t i = 0; i < h->n && rc == ISO_OK; i++)
        rc = flush_skip(h, i, &h->src[i].dec, err);
    return rc;
}

int iso_dev_hub_record_detach(iso_dev_hub *h, iso_dev_rec_writer *w, iso_err *err)
{
    if (!h->recording)
        return 0;
    /* The SKIP records go into the writer's queue, which cuts the recording
     * itself when they do not fit: no failure is left for the caller. */
    if (flush_skips(h, err) != ISO_OK)
        iso_err_clear(err);
    *w = h->rec;
    h->recording = 0;
    return 1;
}

int iso_dev_hub_record_stop(iso_dev_hub *h, iso_err *err)
{
    iso_dev_rec_writer w;
    if (!iso_dev_hub_record_detach(h, &w, err))
        return ISO_OK;
    return iso_dev_rec_writer_close(&w, err);
}

/* A view's changes of control and its stop, one sentence each (the
 * recording holds them, so a replay says them again in the same ticks). */
static void say_view(iso_dev_hub *h, const hub_src *x, const iso_dev_event *ev, size_t k)
{
    static const char *const why[] = {"", "the page let go", "the viewer left", "the view stopped",
                                      "the page fell silent"};
    for (size_t i = 0; i < k; i++) {
        if (ev[i].kind == ISO_DEV_EV_RELEASE)
            say(h, "view %s: control released (%s): its handle holds where it is", x->info.name,
                ev[i].level <= 4 ? why[ev[i].level] : "?");
        else if (ev[i].kind == ISO_DEV_EV_GPIO && ev[i].line == ISO_DEV_GPIO_ESTOP)
            say(h,
                ev[i].level ? "view %s: STOP pressed in a page: handles hold, actuators to their "
                              "safe state"
                            : "view %s: stop released in a page",
                x->info.name);
    }
}

/* Whether chunk c, just decoded by x->dec (h->before before it), is left
 * out of the recording: noise beyond the cap of its second. */
static int leave_out(iso_dev_hub *h, hub_src *x, const iso_dev_chunk *c, size_t events)
{
    if (c->type != ISO_DEV_CHUNK_DATA || !iso_dev__noise_chunk(&h->before, &x->dec, events))
        return 0;
    hub_cap *k = &x->cap;
    int64_t window = c->t_ns / 1000000000LL;
    if (window != k->window) {
        k->window = window;
        k->used = 0;
    }
    if (k->used + c->len <= ISO_DEV_REC_NOISE_CAP) {
        k->used += c->len;
        return 0;
    }
    if (!k->skip_chunks)
        k->first = h->before;
    k->skip_chunks++;
    k->skip_bytes += c->len;
    x->dec.n.unrecorded += c->len; /* what a replay's decoder counts from the SKIP */
    return 1;
}

/* Decodes one chunk into the hub's event buffer, and records it: a chunk
 * the noise cap leaves out waits in a SKIP, written before the source's
 * next record or the tick's TICK record. */
static int take(iso_dev_hub *h, const iso_dev_chunk *c, iso_err *err)
{
    if (c->type == ISO_DEV_CHUNK_TICK) {
        h->tick_records++;
        return ISO_OK;
    }
    if (c->source >= h->n)
        return ISO_OK;
    hub_src *x = &h->src[c->source];
    if (c->type == ISO_DEV_CHUNK_GONE) {
        x->gone++;
        x->present = 0;
    } else if (c->type == ISO_DEV_CHUNK_BACK) {
        x->back++;
        x->present = 1;
    }
    if (h->recording)
        h->before = x->dec;
    size_t k = iso_dev_decode(&x->dec, c, h->ev + h->nev, HUB_EVENTS - h->nev);
    if (x->info.kind == ISO_DEV_KIND_VIEW)
        say_view(h, x, h->ev + h->nev, k);
    x->events += (uint32_t)k;
    h->nev += k;
    if (!h->recording || leave_out(h, x, c, k))
        return ISO_OK;
    int rc = flush_skip(h, c->source, &h->before, err);
    return rc == ISO_OK ? iso_dev_rec_write(&h->rec, c, err) : rc;
}

static int mark(iso_dev_hub *h, size_t i, int type, int64_t t, iso_err *err)
{
    iso_dev_chunk c;
    memset(&c, 0, sizeof c);
    c.t_ns = t;
    c.source = (uint8_t)i;
    c.type = (uint8_t)type;
    return take(h, &c, err);
}

static int room(const iso_dev_hub *h)
{
    return HUB_EVENTS - h->nev >= ISO_DEV_EVENTS_PER_CHUNK + 2 * ISO_DEV_GPIO_ROLES;
}

static int drain_live(iso_dev_hub *h, size_t i, int64_t now, iso_err *err)
{
    hub_src *x = &h->src[i];
    if (!x->s) {
        /* asked on one tick, taken on a later one (hub_reopen.c) */
        iso_dev_source *back = NULL;
        if (!x->reopen)
            return ISO_OK;
        if (!iso_dev__reopener_take(h->reopener, i, &back) || !back) {
            if (now >= x->next_try || h->retry_now) {
                if (iso_dev__reopener_ask(h->reopener, i, x->reopen, x->reopen_ctx, &x->info))
                    x->next_try = now + h->retry_ns;
                else if (h->retry_now)
                    h->retry_kept = 1; /* a replug seen while a reopen is under way */
            }
            return ISO_OK;
        }
        swap_source(h, i, back);
        memcpy(x->detail, x->s->detail, sizeof x->detail);
        say(h, "%s %s is back", iso_dev_kind_name(x->info.kind), x->info.name);
        int rc = mark(h, i, ISO_DEV_CHUNK_BACK, now, err);
        if (rc == ISO_OK)
            rc = hand_over(h, i, err);
        if (rc != ISO_OK)
            return rc;
    }
    for (size_t taken = 0; room(h) && taken < ISO_DEV_DRAIN_MAX;) {
        iso_dev_chunk c;
        iso_err e;
        iso_err_clear(&e);
        c.type = ISO_DEV_CHUNK_DATA; /* a source's read fills the bytes, never the type */
        int threaded = x->threaded;
        int got = threaded ? iso_dev__reader_pop(h->reader, i, &c)
                           : iso_dev_source_read(x->s, now, &c, &e);
        if (got == 0)
            return ISO_OK;
        if (got > 0 && threaded && c.type == ISO_DEV_CHUNK_GONE) { /* the reader's read failed */
            iso_err_set(&e, ISO_EIO, -1, "%.*s", (int)c.len, (const char *)c.data);
            got = ISO_EIO;
        }
        if (got < 0) {
            say(h, "%s %s went away (%s): its handles hold still until it is back",
                iso_dev_kind_name(x->info.kind), x->info.name, e.msg);
            x->threaded = 0;
            iso_dev_source *old = swap_source(h, i, NULL);
            if (!h->reopener || !iso_dev__reopener_close(h->reopener, i, old))
                iso_dev_source_close(old);
            x->next_try = now + h->retry_ns;
            return mark(h, i, ISO_DEV_CHUNK_GONE, now, err);
        }
        c.source = (uint8_t)i;
        c.type = ISO_DEV_CHUNK_DATA;
        if (c.t_ns > now)
            c.t_ns = now;
        taken += c.len;
        int rc = take(h, &c, err);
        if (rc != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

/* A replay drains up to and including the first TICK record at or before
 * now: the recorded loop's tick boundaries are kept exactly. */
static int drain_mux(iso_dev_hub *h, int64_t now, iso_err *err)
{
    while (room(h)) {
        iso_dev_chunk c;
        int got = iso_dev_source_read(h->mux, now, &c, err);
        if (got <= 0)
            return got < 0 ? got : ISO_OK;
        int rc = take(h, &c, err);
        if (rc != ISO_OK)
            return rc;
        if (c.type == ISO_DEV_CHUNK_TICK)
            return ISO_OK;
    }
    return ISO_OK;
}

static int drain_all(iso_dev_hub *h, int64_t now, iso_err *err)
{
    int rc = ISO_OK;
    if (h->mux)
        rc = drain_mux(h, now, err);
    else
        for (size_t i = 0; i < h->n && rc == ISO_OK; i++)
            rc = drain_live(h, i, now, err);
    h->retry_now = h->retry_kept;
    h->retry_kept = 0;
    for (size_t i = 0; i < h->n; i++)
        h->nev += iso_dev_decode_tick(&h->src[i].dec, now, h->ev + h->nev, HUB_EVENTS - h->nev);
    return rc;
}

int iso_dev_hub_drain(iso_dev_hub *h, int64_t now_ns, iso_dev_event *ev, size_t cap, size_t *n,
                      iso_err *err)
{
    int rc = ISO_OK;
    if (h->nev < cap)
        rc = drain_all(h, now_ns, err);
    size_t k = h->nev < cap ? h->nev : cap;
    memcpy(ev, h->ev, k * sizeof *ev);
    memmove(h->ev, h->ev + k, (h->nev - k) * sizeof *ev);
    h->nev -= k;
    *n = k;
    return rc;
}

/* One message when a source's twist stream goes quiet past its stale time
 * and one when samples resume (not when it went away: GONE said so). The
 * map decides on stream time, so the messages come in the same ticks when
 * the recording is replayed. */
static void watch_stale(iso_dev_hub *h, const iso_dev_map *m, const iso_dev_tick *out)
{
    for (size_t i = 0; i < h->n; i++) {
        hub_src *x = &h->src[i];
        uint32_t bit = (uint32_t)1 << i;
        int stale = (out->stale & bit) != 0;
        const char *kind = iso_dev_kind_name(x->info.kind);
        const int view = x->info.kind == ISO_DEV_KIND_VIEW;
        if (stale && !x->stale) {
            x->stale_count++;
            x->quiet_from = m->src[i].t_twist;
            say(h,
                view ? "%s %s: no command from the page in control for more than %g ms: its "
                       "handle holds until commands resume"
                     : "%s %s: no twist sample for more than %g ms: its twist is zero until "
                       "samples resume",
                kind, x->info.name, (double)m->stale_ns[i] / 1e6);
        } else if (!stale && x->stale && !(out->gone & bit) &&
                   (m->src[i].has_twist || m->src[i].has_target)) {
            say(h,
                view ? "%s %s: commands resumed after %.0f ms without"
                     : "%s %s: twist samples resumed after %.0f ms without",
                kind, x->info.name, (double)(m->src[i].t_twist - x->quiet_from) / 1e6);
        }
        x->stale = (uint8_t)stale;
        x->targeting = (out->targeting & bit) != 0;
    }
}

/* What a source's bad input tells its user, by kind. */
static void noise_hint(const hub_src *x, char *buf, size_t cap)
{
    const iso_dev_info *f = &x->info;
    const iso_dev_counters *n = &x->dec.n;
    switch (f->kind) {
    case ISO_DEV_KIND_SERIAL:
        snprintf(buf, cap,
                 "%u garbage bytes, %u bad frames: check the baud rate (this end reads %u %u%c%u; "
                 "both ends must agree) and that this is the device that sends the handle stream",
                 n->garbage, n->bad_frames, f->baud, f->data_bits ? f->data_bits : 8,
                 f->parity ? f->parity : 'N', f->stop_bits ? f->stop_bits : 1);
        break;
    case ISO_DEV_KIND_HID:
        snprintf(buf, cap,
                 "%u reports of unknown IDs, %u too short: is this a 3D mouse (3Dconnexion)?",
                 n->unknown_ids, n->short_reports);
        break;
    default:
        snprintf(buf, cap, "%u garbage bytes, %u unknown: is this the right device?", n->garbage,
                 n->unknown_ids);
    }
}

/* One message when a source has delivered only bad input for
 * ISO_DEV_NOISE_NOTICE_NS of stream time, one when good input comes back.
 * Stream time: a replay says both in the same ticks. */
static void watch_noise(iso_dev_hub *h)
{
    for (size_t i = 0; i < h->n; i++) {
        hub_src *x = &h->src[i];
        const iso_dev_decoder *d = &x->dec;
        const char *kind = iso_dev_kind_name(x->info.kind);
        if (!x->noise_told && d->noise_since != INT64_MIN &&
            d->noise_last - d->noise_since >= ISO_DEV_NOISE_NOTICE_NS) {
            char hint[300];
            noise_hint(x, hint, sizeof hint);
            x->noise_told = 1;
            say(h, "%s %s: %.1f s of input and not one valid %s (%s)", kind, x->info.name,
                (double)(d->noise_last - d->noise_since) * 1e-9,
                x->info.kind == ISO_DEV_KIND_SERIAL ? "frame" : "report", hint);
        } else if (x->noise_told && d->noise_since == INT64_MIN) {
            x->noise_told = 0;
            say(h, "%s %s: valid input again (%u garbage bytes so far, %u resyncs)", kind,
                x->info.name, d->n.garbage, d->n.resyncs);
        }
    }
}

int iso_dev_hub_tick(iso_dev_hub *h, iso_dev_map *m, int64_t now_ns, double dt_s,
                     const iso_pose *poses, iso_dev_tick *out, iso_err *err)
{
    int rc = drain_all(h, now_ns, err);
    iso_dev_map_tick(m, h->ev, h->nev, now_ns, dt_s, poses, out);
    watch_stale(h, m, out);
    watch_noise(h);
    h->nev = 0;
    h->last_tick = now_ns;
    h->ticked = 1;
    if (rc != ISO_OK)
        return rc;
    for (size_t i = 0; i < h->n && !h->mux; i++) {
        iso_dev_source *s = h->src[i].s;
        if (s && s->ops->write_level) {
            iso_err e;
            iso_err_clear(&e);
            /* The per-tick trigger pulse; a failed pulse must not stop the loop. */
            if (s->ops->write_level(s, 1, &e) == ISO_OK && s->ops->write_level(s, 0, &e) != ISO_OK)
                say(h, "%s: trigger pulse: %s", s->info.name, e.msg);
        }
    }
    if (h->recording && (rc = flush_skips(h, err)) != ISO_OK)
        return rc;
    if (h->recording && (rc = iso_dev_rec_tick(&h->rec, now_ns, err)) == ISO_OK) {
        char msg[ISO_DEV_NAME_MAX * 2 + 200];
        if (iso_dev_rec_writer_ended(&h->rec, msg, sizeof msg)) /* the run goes on */
            say(h, "%s", msg);
    }
    return rc;
}

int64_t iso_dev_hub_next_tick(iso_dev_hub *h, int64_t fallback_dt_ns)
{
    if (!h->mux)
        return INT64_MAX;
    int64_t t = iso_dev_replay_next_tick(h->mux);
    if (t != INT64_MAX)
        return t;
    /* A recording with TICK records ends at its last one: what the recorded
     * loop read after its last tick was kept, but never ticked there. */
    if (h->tick_records > 0)
        return INT64_MAX;
    int64_t next = iso_dev_replay_peek(h->mux);
    if (next == INT64_MAX)
        return INT64_MAX;
    if (!h->ticked)
        return next;
    /* Every tick is played, gaps included: a deflected 3D mouse keeps
     * moving its handle between reports. */
    return h->last_tick + fallback_dt_ns;
}

int iso_dev_hub_replay_done(iso_dev_hub *h)
{
    return !h->mux || (iso_dev_replay_peek(h->mux) == INT64_MAX && h->nev == 0);
}
