/* view/display_viewer.c -- the view's own WebSocket protocol (iso_display.h,
 * "Wire format"): what a viewer is sent (the topology, its control state,
 * the run's note, frames) and what it may command (iso_display.h, "Who may
 * command").
 *
 * Who is in control is decided here, on the server's thread, at the moment
 * a message arrives: the first viewer to ask gets it, and it alone may move
 * handles until it lets go or leaves. Every accepted command is queued on
 * the view device at once, so a stop reaches the actuators' sender within
 * its 2 ms probe whatever the loop is doing; every refusal is counted and
 * told to the page that sent it. */
#include "display_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

/* Compares the whole token whatever differs first: no timing tells how
 * much of a guess was right. */
static int token_ok(const iso_display *d, const iso_display__request *r)
{
    if (!d->token[0])
        return 1;
    size_t n = 0;
    const char *t = r->query ? iso_display__query_get(r->query, r->query_len, "token", &n) : NULL;
    size_t want = strlen(d->token);
    unsigned diff = t && n == want ? 0u : 1u;
    for (size_t i = 0; i < want; i++)
        diff |= (unsigned)(unsigned char)(t && i < n ? t[i] : 0) ^ (unsigned char)d->token[i];
    return diff == 0;
}

static int viewer_open(iso_display *d, iso_display__conn *c, const iso_display__request *r)
{
    iso_display__viewer *v = &c->v;
    v->frame = malloc(d->frame_len);
    if (!v->frame)
        return 503;
    /* The kernel keeps at most about two frames for a viewer (it doubles
     * this): a browser that stops reading costs that much, not the
     * megabytes autotuning would give it before the stall drops it. */
    size_t sb = 2 * d->frame_len > 65536 ? 2 * d->frame_len : 65536;
    int sbi = sb < (size_t)(1 << 30) ? (int)sb : 1 << 30;
    setsockopt(c->fd, SOL_SOCKET, SO_SNDBUF, &sbi, sizeof sbi);
    v->stage = V_HANDSHAKE;
    v->may_command = d->dev && token_ok(d, r);
    v->control_ver = d->control_ver - 1; /* its first control message is due */
    v->note_ver = 0;
    v->paced = 0;
    v->sent_tick = v->took_tick = -1;
    return 0;
}

/* ---- what a viewer is sent ----------------------------------------------- */

static void control_message(iso_display *d, iso_display__conn *c)
{
    iso_display__viewer *v = &c->v;
    int n = snprintf(v->text, sizeof v->text,
                     "{\"type\":\"control\",\"you\":%u,\"may_command\":%s,\"holder\":%u,"
                     "\"stop\":%s,\"ended\":%s,\"refused\":%u,\"why\":\"%s\"}",
                     (unsigned)c->id, v->may_command ? "true" : "false",
                     (unsigned)atomic_load(&d->holder), d->stop ? "true" : "false",
                     atomic_load(&d->ended) ? "true" : "false",
                     (unsigned)atomic_load(&d->cmd_refused), v->why);
    size_t len = n > 0 ? ((size_t)n < sizeof v->text ? (size_t)n : sizeof v->text - 1) : 0;
    iso_display__queue_message(c, 1, v->text, len);
    v->control_ver = d->control_ver;
}

/* The newest frame the viewer has not had, copied out under the lock. A
 * paced viewer gets it only once it took the last one sent (TCP keeps the
 * order, so then nothing else is on the way): the sockets' buffers would
 * otherwise fill with frames a busy page has not read, each older than the
 * next, and what it shows would lag by all of them. */
static int frame_message(iso_display *d, iso_display__conn *c)
{
    iso_display__viewer *v = &c->v;
    if (atomic_load(&d->published) == v->frame_seq || (v->paced && v->took_tick < v->sent_tick))
        return 0;
    pthread_mutex_lock(&d->frame_lock);
    memcpy(v->frame, d->latest, d->frame_len);
    v->frame_seq = d->latest_seq;
    pthread_mutex_unlock(&d->frame_lock);
    memcpy(&v->sent_tick, v->frame + 8, sizeof v->sent_tick); /* the frame's tick number */
    iso_display__queue_message(c, 2, v->frame, d->frame_len);
    v->writing_frame = 1;
    return 1;
}

/* The topology after the handshake; then, in this order, what changed: its
 * control state, the run's note, the newest frame. */
static int viewer_next(iso_display *d, iso_display__conn *c, long long now)
{
    (void)now;
    iso_display__viewer *v = &c->v;
    if (v->writing_frame) { /* the frame before is written whole */
        v->writing_frame = 0;
        if (v->frame_seq > d->counted_seq) {
            d->counted_seq = v->frame_seq;
            atomic_fetch_add(&d->frames_sent, 1);
        }
    }
    if (v->stage == V_HANDSHAKE) {
        v->stage = V_TOPOLOGY;
        iso_display__queue_message(c, 2, d->topology, d->topology_len);
        /* tens of megabytes at a million vertices: a slow link is given the
         * time it needs while bytes move, and dropped when they stop */
        c->patient = 1;
        return 1;
    }
    v->stage = V_FRAMES;
    if (v->control_ver != d->control_ver) {
        control_message(d, c);
        return 1;
    }
    unsigned nv = atomic_load(&d->note_ver);
    if (v->note_ver != nv && d->note) { /* set once, before note_ver: no lock needed */
        v->note_ver = nv;
        iso_display__queue_message(c, 1, d->note, strlen(d->note));
        return 1;
    }
    return frame_message(d, c);
}

/* ---- what a viewer may command ---------------------------------------------- */

/* Says why to this viewer alone (a control message, once per new reason). */
static int refuse(iso_display *d, iso_display__conn *c, const char *why)
{
    atomic_fetch_add(&d->cmd_refused, 1);
    if (strcmp(c->v.why, why) != 0) {
        snprintf(c->v.why, sizeof c->v.why, "%s", why);
        c->v.control_ver = d->control_ver - 1;
    }
    return 0;
}

static int push(iso_display *d, int what, uint32_t conn, const void *msg, size_t len)
{
    if (iso_dev_view_push(d->dev, what, conn, msg, len) == ISO_OK)
        return 1;
    atomic_fetch_add(&d->cmd_dropped, 1);
    return 0;
}

static void end_control(iso_display *d, uint32_t holder, int reason)
{
    unsigned char r = (unsigned char)reason;
    (void)push(d, ISO_DEV_VIEW_END, holder, &r, 1); /* the device checks the holder again */
    atomic_store(&d->holder, 0);
    d->control_ver++;
}

static int take(iso_display *d, iso_display__conn *c)
{
    uint32_t holder = atomic_load(&d->holder);
    if (holder == c->id)
        return 0;
    if (holder) {
        char why[96];
        snprintf(why, sizeof why, "viewer %u is in control", (unsigned)holder);
        return refuse(d, c, why);
    }
    if (!push(d, ISO_DEV_VIEW_GRANT, c->id, NULL, 0))
        return refuse(d, c, "the device is busy: try again");
    atomic_store(&d->holder, c->id);
    d->holder_ms = iso_display__now_ms();
    atomic_fetch_add(&d->cmd_grants, 1);
    c->v.why[0] = 0;
    d->control_ver++;
    return 0;
}

static int command(iso_display *d, iso_display__conn *c, const iso_dev_view_msg *m,
                   const unsigned char *p, size_t n)
{
    if (!d->dev)
        return refuse(d, c, "this view only watches: the scene has no view device");
    if (atomic_load(&d->ended))
        return refuse(d, c, "the run has ended");
    if (!c->v.may_command)
        return refuse(d, c, "commanding needs the token of the URL isoshape printed (?token=...)");
    uint32_t holder = atomic_load(&d->holder);
    if (holder == c->id)
        d->holder_ms = iso_display__now_ms(); /* any command keeps control alive */
    switch (m->type) {
    case ISO_DEV_VIEW_TAKE: return take(d, c);
    case ISO_DEV_VIEW_RELEASE:
        if (holder != c->id)
            return refuse(d, c, "only the viewer in control can let go");
        end_control(d, holder, ISO_DEV_VIEW_END_RELEASED);
        return 0;
    case ISO_DEV_VIEW_TARGET:
        if (holder != c->id)
            return refuse(d, c, "take control first");
        if (m->handle >= d->n_cmd_handles)
            return refuse(d, c, "no such handle");
        break;
    case ISO_DEV_VIEW_STOP: /* anyone who may command, at once, always */
        if (d->stop)
            return 0; /* pressed already: no change reaches the device */
        d->stop = 1;
        d->stop_conn = c->id;
        d->stop_ms = iso_display__now_ms();
        atomic_fetch_add(&d->cmd_stops, 1);
        d->control_ver++;
        break;
    default: /* UNSTOP */
        if (!d->stop)
            return 0; /* nothing to release: nothing reaches the device */
        if (d->stop_conn && c->id != d->stop_conn && c->id != holder)
            return refuse(d, c,
                          "only the viewer who pressed the stop, or the one in control, "
                          "can release it");
        if (iso_display__now_ms() - d->stop_ms < ISO_DISPLAY_UNSTOP_MIN_MS)
            return refuse(d, c, "too soon after the stop: release it again in a moment");
        d->stop = 0;
        d->control_ver++;
        break;
    }
    if (push(d, ISO_DEV_VIEW_MSG, c->id, p, n))
        atomic_fetch_add(&d->cmd_accepted, 1);
    return 0;
}

/* A "took" message (iso_display.h): the tick it names, or NAN when the
 * text is not one. */
static double took_tick(const unsigned char *p, size_t n)
{
    static const char pre[] = ISO_DISPLAY_TOOK_PREFIX;
    char num[32];
    size_t k = sizeof pre - 1;
    if (n <= k + 1 || n - k - 1 >= sizeof num || memcmp(p, pre, k) != 0 || p[n - 1] != '}')
        return NAN;
    memcpy(num, p + k, n - k - 1);
    num[n - k - 1] = 0;
    char *end;
    double t = strtod(num, &end);
    return end != num && *end == 0 && isfinite(t) ? t : NAN;
}

/* A binary message is a command; a text message is a "took" or nothing,
 * and is ignored (it was checked as UTF-8 already). A took paces the
 * viewer's own frames only, so it needs no token; the next frame goes out
 * at once (socket_input pumps after each message). Refusals keep the
 * connection: a page with a stale idea of who controls is not an attack. */
static int viewer_message(iso_display *d, iso_display__conn *c, int opcode, const unsigned char *p,
                          size_t n)
{
    if (opcode == 1) {
        double t = took_tick(p, n);
        if (!isnan(t)) {
            c->v.paced = 1;
            c->v.took_tick = t;
        }
        return 0;
    }
    if (opcode != 2)
        return 0;
    iso_dev_view_msg m;
    char why[96];
    if (iso_dev_view_parse(p, n, &m, why, sizeof why) != ISO_OK) {
        atomic_fetch_add(&d->cmd_malformed, 1);
        if (strcmp(c->v.why, why) != 0) {
            snprintf(c->v.why, sizeof c->v.why, "%s", why);
            c->v.control_ver = d->control_ver - 1;
        }
        return 0;
    }
    return command(d, c, &m, p, n);
}

static void viewer_close(iso_display *d, iso_display__conn *c)
{
    if (d->dev && atomic_load(&d->holder) == c->id)
        end_control(d, c->id, ISO_DEV_VIEW_END_LEFT);
    if (d->stop && d->stop_conn == c->id)
        d->stop_conn = 0; /* its page reconnects, or another releases it: not stuck */
    free(c->v.frame);
    c->v.frame = NULL;
}

void iso_display__viewer_lapse(iso_display *d, long long now)
{
    uint32_t holder = atomic_load(&d->holder);
    if (!d->dev || !holder || now - d->holder_ms <= ISO_DISPLAY_LAPSE_MS)
        return;
    end_control(d, holder, ISO_DEV_VIEW_END_LAPSED);
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++) {
        iso_display__conn *c = &d->conns[i];
        if (c->id == holder && c->state != C_FREE)
            snprintf(c->v.why, sizeof c->v.why, "control lapsed: no command for %d s",
                     ISO_DISPLAY_LAPSE_MS / 1000);
    }
}

void iso_display__viewer_end(iso_display *d)
{
    uint32_t holder = atomic_load(&d->holder);
    if (d->dev && holder)
        end_control(d, holder, ISO_DEV_VIEW_END_STOPPED);
    d->control_ver++;
}

const iso_display__proto iso_display__view_proto = {NULL, viewer_open, viewer_message, viewer_next,
                                                    viewer_close};
