/* actuators/actuators.c -- see iso_actuators.h. */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "act_internal.h"
#include "iso_actuators.h"
#include "iso_clock.h"
#include "iso_fb_host.h"

#define ECHO_SLOTS 128u      /* sent frames kept for the ACK check, by frame seq */
#define PERIOD_US 10000u     /* the sender's SETPOINTS period: 100 Hz (PROTOCOL.md) */
#define KEEP_ARMED_US 40000u /* HELLO again this often until the first publish */
/* The e-stop, the loop watchdog and safe_stop are looked at this often, not
 * only once a period: an e-stop edge sends SAFE within 2 ms (+ the probe). */
#define HOLD_POLL_US 2000u
/* The loop watchdog stops setpoints this much before loop_timeout_ms: the
 * MCU brakes 100 ms after the last SETPOINTS *arrives* and checks every
 * 1 ms, and a frame takes ~2 ms on a 115200 baud UART. So the safe state
 * comes within loop_timeout_ms + 100 ms of the loop's last progress. */
#define STOP_GUARD_US 5000u
#define LOOP_TIMEOUT_MIN_MS 250 /* the default's floor: max(250, 5 ticks) */
#define SILENT_US 500000u       /* no frame this long: say so (5 heartbeats) */
#define REOPEN_MS 50            /* after a loss; an emulation restart never blocks */
#define STILL_LOST_US 2000000u  /* repeat the loss notice this often */

/* Lock-free means lock-free: alive() and estop() run inside the loop and
 * from an e-stop handler, which must never wait on the sender. */
_Static_assert(ATOMIC_LLONG_LOCK_FREE == 2, "64-bit atomics are lock-free");
_Static_assert(ATOMIC_INT_LOCK_FREE == 2, "int atomics are lock-free");

typedef struct act_channel {
    iso_act_channel spec;
    int *verts; /* region centroid: its vertices (owned); NULL for a vertex */
    int n_verts;
} act_channel;

/* One SETPOINTS frame as it went out. Keyed by the frame's seq, which the
 * ACK echoes: the tick may repeat (the sender re-sends the latest values
 * when the loop has no new tick), the seq never does within 65536 frames. */
typedef struct echo_slot {
    uint64_t sent_us; /* before the write, so a preempted write still counts */
    uint32_t tick;
    uint16_t seq;
    uint8_t n, used;
    int16_t value[ISO_ACT_MAX_CHANNELS];
} echo_slot;

/* Threads: the loop calls publish; with a link, the sender thread owns the
 * host and the link (host, echo, told_channels are its alone). Everything
 * both touch is under `lock`, held for copies only, never across I/O. */
struct iso_actuators {
    act_channel ch[ISO_ACT_MAX_CHANNELS];
    int n_ch, nv;
    int top; /* highest configured channel + 1 */
    iso_act_notice_fn notice;
    void *notice_ctx;

    iso_link *link; /* owned */
    iso_fb_host host;
    int host_up;
    int told_channels; /* the count notice went out for this MCU description */
    echo_slot echo[ECHO_SLOTS];

    pthread_t sender;
    int sender_started;
    pthread_mutex_t lock;
    pthread_cond_t cond; /* frames handled, safe state seen, link state changed */
    /* ---- under lock ---- */
    int16_t values[ISO_ACT_MAX_CHANNELS]; /* latest published, by channel */
    uint32_t tick;                        /* and its tick */
    int have_tick;                        /* the loop has published at least once */
    int stopped;                          /* safe_stop: send no more SETPOINTS */
    int quit;                             /* destroy: the sender ends */
    int link_state;                       /* the host's ISO_FB_HOST_*, after the last step */
    int mismatch;                         /* the MCU lacks a configured channel */
    iso_fb_hello hello;                   /* MCU's last answer */
    int have_hello;
    int saw_safe; /* safe_stop watches for these */
    uint64_t safe_us, last_sent_us;
    uint64_t frames;           /* frames the sender handled, for poll */
    iso_fb_host_stats host_st; /* the host's counters after the last step */
    iso_err down;              /* why the link last went down */
    uint64_t last_publish_us;  /* when the latest publish began */
    iso_act_stats st;

    /* ---- lock-free, any thread ---- */
    atomic_ullong progress_us; /* the loop's last alive()/publish(); 0: watchdog not armed */
    atomic_ullong alive_calls;
    atomic_int estop_req;   /* iso_actuators_estop() */
    atomic_ullong estop_us; /* when it was pressed */
    atomic_int state;       /* ISO_ACT_STATE_* */
    atomic_uint holds;      /* ISO_ACT_HOLD_* */

    /* ---- the sender thread's alone ---- */
    uint64_t loop_timeout_us; /* 0: no loop watchdog */
    int loop_timeout_ms;
    iso_act_estop_fn estop_probe;
    void *estop_ctx;
    unsigned hold;           /* what holds holds */
    uint64_t fresh_after_us; /* a publish from this time on re-arms after a hold */
    int prev_host_state, ever_streamed;
    int lost; /* lost and not streaming again yet */
    uint64_t lost_us, lost_told_us;
    uint32_t reopens_seen;
    int silent;
    uint64_t silent_from_us;
    int mcu_safe;   /* the MCU's last word: safe or idle (1), armed (0) */
    int await_safe; /* streaming stopped: the next safe report confirms it */
    uint64_t break_us;
    int break_cause;
    const char *break_what;
};

static void say(const iso_actuators *a, const char *line)
{
    if (a->notice)
        a->notice(a->notice_ctx, line);
    else
        fprintf(stderr, "%s\n", line);
}

/* ------------------------------------------------------------------------ */
/* The spec                                                                   */
/* ------------------------------------------------------------------------ */

static const char *region_name(int region, char *buf, size_t cap)
{
    if (region == ISO_ACT_REGION_FIXED)
        snprintf(buf, cap, "the fixed region");
    else
        snprintf(buf, cap, "handle %d", region);
    return buf;
}

static int check_channel(const iso_act_channel *c, int i, int nv, const iso_regions *r,
                         iso_err *err)
{
    if (c->channel < 0 || c->channel >= ISO_ACT_MAX_CHANNELS)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel entry %d: channel %d is out of range (0..%d: a "
                           "SETPOINTS frame carries %d)",
                           i, c->channel, ISO_ACT_MAX_CHANNELS - 1, ISO_ACT_MAX_CHANNELS);
    if (c->axis < 0 || c->axis > 2)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: axis %d is not 0 (x), 1 (y) or 2 (z)",
                           c->channel, c->axis);
    if (!isfinite(c->min) || !isfinite(c->max) || !(c->min < c->max))
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: limits [%g, %g] need finite min < max",
                           c->channel, c->min, c->max);
    if (!isfinite(c->scale) || c->scale == 0)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: scale %g must be finite and not 0", c->channel,
                           c->scale);
    if (c->region == ISO_ACT_REGION_NONE) {
        if (c->vertex < 0 || c->vertex >= nv)
            return iso_err_set(err, ISO_EINVAL, i,
                               "actuators: channel %d: vertex %d is out of range (the mesh has %d "
                               "vertices)",
                               c->channel, c->vertex, nv);
        return ISO_OK;
    }
    if (c->vertex >= 0)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: names both vertex %d and a region; give one",
                           c->channel, c->vertex);
    char rn[32];
    if (c->region < ISO_ACT_REGION_FIXED)
        return iso_err_set(err, ISO_EINVAL, i, "actuators: channel %d: region %d is not a region",
                           c->channel, c->region);
    if (!r || r->nv != nv)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d follows %s but no regions for the %d-vertex mesh "
                           "were given",
                           c->channel, region_name(c->region, rn, sizeof rn), nv);
    if (c->region >= r->n_handles)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: handle %d does not exist (the regions have %d "
                           "handle%s)",
                           c->channel, c->region, r->n_handles, r->n_handles == 1 ? "" : "s");
    return ISO_OK;
}

static int in_region(const iso_regions *r, int v, int region)
{
    if (region == ISO_ACT_REGION_FIXED)
        return r->kind[v] == ISO_FIXED;
    return r->kind[v] == ISO_HANDLE && r->handle[v] == region;
}

static int collect_region(act_channel *c, int nv, const iso_regions *r, int i, iso_err *err)
{
    int n = 0;
    for (int v = 0; v < nv; v++)
        n += in_region(r, v, c->spec.region);
    char rn[32];
    if (n == 0)
        return iso_err_set(err, ISO_EINVAL, i, "actuators: channel %d follows %s, which is empty",
                           c->spec.channel, region_name(c->spec.region, rn, sizeof rn));
    c->verts = malloc((size_t)n * sizeof *c->verts);
    if (!c->verts)
        return iso_err_set(err, ISO_ENOMEM, i, "actuators: out of memory");
    c->n_verts = 0;
    for (int v = 0; v < nv; v++)
        if (in_region(r, v, c->spec.region))
            c->verts[c->n_verts++] = v;
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Callbacks from the firmware-bridge host (on the sender thread)             */
/* ------------------------------------------------------------------------ */

/* Reads a->hello without the lock: only the sender thread writes it. */
static void tell_channel_disagreement(iso_actuators *a)
{
    char line[512];
    int mcu = a->hello.n_channels;
    if (a->top > mcu) {
        snprintf(line, sizeof line,
                 "actuators: the MCU has %d channel%s but the spec drives channel %d: sending no "
                 "setpoints (the MCU's watchdog keeps it safe)",
                 mcu, mcu == 1 ? "" : "s", a->top - 1);
        say(a, line);
        return;
    }
    int len = snprintf(line, sizeof line,
                       "actuators: the MCU has %d channels, the spec drives %d:", mcu, a->n_ch);
    for (int c = 0; c < mcu && len < (int)sizeof line; c++) {
        int driven = 0;
        for (int i = 0; i < a->n_ch; i++)
            driven |= a->ch[i].spec.channel == c;
        if (!driven)
            len += snprintf(line + len, sizeof line - (size_t)len,
                            " channel %d held at its safe %d;", c, a->hello.ch[c].safe);
    }
    if (len > 0 && len < (int)sizeof line)
        line[len - 1] = '\0';
    say(a, line);
}

/* Scene limits beyond what the MCU will do are worth one line: the MCU
 * clamps silently, which would look like a tracking error. */
static void tell_limit_disagreement(iso_actuators *a)
{
    for (int i = 0; i < a->n_ch; i++) {
        const iso_act_channel *c = &a->ch[i].spec;
        if (c->channel >= a->hello.n_channels)
            continue;
        double lo = c->min * c->scale, hi = c->max * c->scale;
        if (lo > hi) {
            double t = lo;
            lo = hi;
            hi = t;
        }
        const iso_fb_channel_info *m = &a->hello.ch[c->channel];
        if (lo < m->min || hi > m->max) {
            char line[256];
            snprintf(line, sizeof line,
                     "actuators: channel %d spans [%.0f, %.0f] milli-units, the MCU's limits are "
                     "[%d, %d]; "
                     "it clamps the rest",
                     c->channel, lo, hi, m->min, m->max);
            say(a, line);
        }
    }
}

/* The HELLO as unpacked fills only its n_channels entries; the rest of
 * ch[] is whatever the caller's stack held. Keep a copy with those zeroed
 * and compare only the filled ones, so nothing uninitialised is ever read
 * (valgrind caught the whole-array memcmp). */
static void copy_hello(iso_fb_hello *dst, const iso_fb_hello *h)
{
    memset(dst, 0, sizeof *dst);
    dst->proto_version = h->proto_version;
    dst->fw_version = h->fw_version;
    dst->flags = h->flags;
    dst->uptime_ms = h->uptime_ms;
    dst->n_channels = h->n_channels <= ISO_FB_MAX_CHANNELS ? h->n_channels : ISO_FB_MAX_CHANNELS;
    memcpy(dst->ch, h->ch, dst->n_channels * sizeof h->ch[0]);
}

/* ------------------------------------------------------------------------ */
/* Safety: what stopped the streaming, and the MCU's word that it is safe     */
/* ------------------------------------------------------------------------ */

/* Streaming stopped at t0 because of `what`; the MCU's next safe report
 * confirms it (a later cause replaces an unconfirmed one). Sender thread. */
static void begin_break(iso_actuators *a, uint64_t t0, int cause, const char *what)
{
    a->await_safe = 1;
    a->break_us = t0;
    a->break_cause = cause;
    a->break_what = what;
}

/* The MCU says it is in its safe state (FAULT, a heartbeat that is not
 * armed, HELLO(BOOT)). Counts the transition, and confirms a break. On the
 * sender thread, from the host's callbacks. */
static void note_safe(iso_actuators *a, const char *how)
{
    int fresh = !a->mcu_safe;
    a->mcu_safe = 1;
    int confirm = a->await_safe;
    double ms = 0;
    if (confirm) {
        uint64_t now = iso_clock_us();
        a->await_safe = 0;
        ms = now > a->break_us ? (double)(now - a->break_us) / 1000.0 : 0.0;
    }
    if (!fresh && !confirm)
        return;
    pthread_mutex_lock(&a->lock);
    a->st.safe_confirms += (uint32_t)fresh;
    if (confirm) {
        a->st.last_safe_ms = ms;
        a->st.last_safe_cause = a->break_cause;
    }
    pthread_mutex_unlock(&a->lock);
    char line[256];
    if (confirm)
        snprintf(line, sizeof line,
                 "actuators: the MCU reports its safe state (%s) %.1f ms after %s", how, ms,
                 a->break_what);
    else if (a->hold == 0 && !a->lost && strstr(how, "BOOT"))
        snprintf(line, sizeof line,
                 "actuators: the MCU restarted (%s): it is idle at its safe positions; re-arming",
                 how);
    else if (a->hold == 0 && !a->lost)
        snprintf(
            line, sizeof line,
            "actuators: the MCU went to its safe state by itself (%s): no setpoints reached it "
            "in time; re-arming",
            how);
    else
        return;
    say(a, line);
}

static void on_hello(void *ctx, const iso_fb_hello *h_in)
{
    iso_actuators *a = ctx;
    if (h_in->flags & ISO_FB_HELLO_BOOT) {
        note_safe(a, "HELLO(BOOT)");
        return; /* the unasked one; the answer follows our HELLO */
    }
    a->mcu_safe = 0; /* the answer arms it */
    iso_fb_hello hh;
    copy_hello(&hh, h_in);
    const iso_fb_hello *h = &hh;
    pthread_mutex_lock(&a->lock);
    int changed = !a->have_hello || a->hello.n_channels != h->n_channels ||
                  memcmp(a->hello.ch, h->ch, h->n_channels * sizeof h->ch[0]) != 0;
    a->hello = *h;
    a->have_hello = 1;
    a->st.mcu_channels = h->n_channels;
    a->mismatch = a->top > h->n_channels;
    pthread_mutex_unlock(&a->lock);
    if (changed)
        a->told_channels = 0;
    if (!a->told_channels) { /* outside the lock: the notice may take its time */
        a->told_channels = 1;
        if (a->top > h->n_channels || a->n_ch != h->n_channels)
            tell_channel_disagreement(a);
        tell_limit_disagreement(a);
    }
}

static void on_ack(void *ctx, const iso_fb_ack *k)
{
    iso_actuators *a = ctx;
    if (k->type != ISO_FB_SETPOINTS)
        return;
    const echo_slot *s = &a->echo[k->seq % ECHO_SLOTS];
    int known = s->used && s->seq == k->seq;
    int same = known && s->tick == k->tick && s->n == k->n &&
               memcmp(s->value, k->value, (size_t)k->n * sizeof k->value[0]) == 0;
    double ms = known ? (double)(iso_clock_us() - s->sent_us) / 1000.0 : 0;
    pthread_mutex_lock(&a->lock);
    iso_act_stats *st = &a->st;
    st->acks++;
    if (!known) {
        st->echo_unknown++;
    } else {
        st->echo_mismatches += !same;
        st->rtt_last_ms = ms;
        st->rtt_avg_ms = (st->rtt_avg_ms * st->rtt_count + ms) / (st->rtt_count + 1);
        if (st->rtt_count == 0 || ms < st->rtt_min_ms)
            st->rtt_min_ms = ms;
        if (ms > st->rtt_max_ms)
            st->rtt_max_ms = ms;
        st->rtt_count++;
    }
    pthread_mutex_unlock(&a->lock);
}

static void on_fault(void *ctx, const iso_fb_fault *f)
{
    iso_actuators *a = ctx;
    pthread_mutex_lock(&a->lock);
    a->st.faults++;
    a->st.last_fault_reason = f->reason;
    a->st.last_fault_detail_ms = f->detail;
    if (!a->saw_safe) {
        a->saw_safe = 1;
        a->safe_us = iso_clock_us();
    }
    pthread_mutex_unlock(&a->lock);
    char how[96];
    if (f->reason == ISO_FB_FAULT_WATCHDOG)
        snprintf(how, sizeof how, "FAULT watchdog, %u ms after the last setpoints",
                 (unsigned)f->detail);
    else if (f->reason == ISO_FB_FAULT_REQUESTED)
        snprintf(how, sizeof how, "FAULT requested: it obeyed SAFE");
    else
        snprintf(how, sizeof how, "FAULT reason %u", (unsigned)f->reason);
    note_safe(a, how);
}

static void on_heartbeat(void *ctx, const iso_fb_heartbeat *hb)
{
    iso_actuators *a = ctx;
    pthread_mutex_lock(&a->lock);
    a->st.heartbeats++;
    a->st.mcu_state = hb->state;
    a->st.mcu_uptime_ms = hb->uptime_ms;
    for (unsigned c = 0; c < hb->n && c < ISO_ACT_MAX_CHANNELS; c++)
        a->st.mcu_pos[c] = hb->pos[c];
    if (hb->state != ISO_FB_STATE_ARMED && !a->saw_safe) {
        a->saw_safe = 1;
        a->safe_us = iso_clock_us();
    }
    pthread_mutex_unlock(&a->lock);
    if (hb->state == ISO_FB_STATE_ARMED)
        a->mcu_safe = 0;
    else
        note_safe(a, hb->state == ISO_FB_STATE_IDLE ? "heartbeat: idle" : "heartbeat: safe");
}

/* ------------------------------------------------------------------------ */
/* The sender thread                                                          */
/* ------------------------------------------------------------------------ */

static void remember(iso_actuators *a, uint16_t seq, uint32_t tick, const int16_t *v, unsigned n)
{
    echo_slot *s = &a->echo[seq % ECHO_SLOTS];
    s->seq = seq;
    s->tick = tick;
    s->n = (uint8_t)n;
    s->used = 1;
    s->sent_us = iso_clock_us();
    memcpy(s->value, v, n * sizeof *v);
}

/* Loss, reopen, re-arm and silence, each said once as it happens. */
static void watch_link(iso_actuators *a)
{
    uint64_t now = iso_clock_us();
    int hs = a->host.state, was = a->prev_host_state;
    char line[640];
    if (hs == ISO_FB_HOST_DOWN && was != ISO_FB_HOST_DOWN) {
        a->lost = 1;
        a->lost_us = a->lost_told_us = now;
        a->silent = 0;
        a->mcu_safe = 0; /* unknown until it speaks again */
        if (!a->hold)
            begin_break(a, now, 0, "the link was lost");
        snprintf(line, sizeof line,
                 "actuators: LINK LOST to the MCU: %.300s. No setpoints reach it; its own watchdog "
                 "brakes it to its safe state 100 ms after the last ones. Reopening every %d ms%s",
                 a->host.last_err.msg, REOPEN_MS,
                 a->hold                    ? " once setpoints may flow again"
                 : iso_act__emu_is(a->link) ? " (restarting the emulation if it died)"
                                            : "");
        say(a, line);
    } else if (hs == ISO_FB_HOST_DOWN && now - a->lost_told_us >= STILL_LOST_US) {
        a->lost_told_us = now;
        snprintf(line, sizeof line, "actuators: link still lost after %.1f s: %.300s",
                 (double)(now - a->lost_us) / 1e6, a->host.last_err.msg);
        say(a, line);
    }
    if (a->host.stats.reopens != a->reopens_seen) {
        a->reopens_seen = a->host.stats.reopens;
        unsigned r = iso_act__emu_restarts(a->link);
        snprintf(line, sizeof line,
                 "actuators: link reopened %.0f ms after the loss%s; shaking hands",
                 (double)(now - a->lost_us) / 1000.0, r ? " (the emulation was restarted)" : "");
        say(a, line);
    }
    if (hs == ISO_FB_HOST_STREAMING) {
        a->ever_streamed = 1;
        if (a->lost) {
            a->lost = 0;
            snprintf(line, sizeof line,
                     "actuators: MCU armed again %.0f ms after the link was lost",
                     (double)(now - a->lost_us) / 1000.0);
            say(a, line);
        }
    }
    if (hs != ISO_FB_HOST_DOWN && !a->silent && now > a->host.last_rx_us + SILENT_US) {
        a->silent = 1;
        a->silent_from_us = a->host.last_rx_us;
        pthread_mutex_lock(&a->lock);
        a->st.silences++;
        pthread_mutex_unlock(&a->lock);
        snprintf(line, sizeof line,
                 "actuators: the MCU has been silent for %u ms (no heartbeat, no ack)%s; the link "
                 "counts as lost after %d ms",
                 SILENT_US / 1000u, a->hold ? "" : "; setpoints continue",
                 a->host.opts.link_timeout_ms);
        say(a, line);
    } else if (a->silent && a->host.last_rx_us > a->silent_from_us) {
        a->silent = 0;
        snprintf(line, sizeof line, "actuators: the MCU answers again after %.0f ms of silence",
                 (double)(a->host.last_rx_us - a->silent_from_us) / 1000.0);
        say(a, line);
    }
    a->prev_host_state = hs;
}

static int sink_state(const iso_actuators *a)
{
    int hs = a->host.state;
    if (hs == ISO_FB_HOST_DOWN)
        return ISO_ACT_STATE_LOST;
    if (a->hold)
        return a->mcu_safe ? ISO_ACT_STATE_SAFE : ISO_ACT_STATE_STOPPING;
    if (a->silent)
        return ISO_ACT_STATE_SILENT;
    if (hs == ISO_FB_HOST_STREAMING)
        return ISO_ACT_STATE_ARMED;
    return a->ever_streamed ? ISO_ACT_STATE_RECONNECTING : ISO_ACT_STATE_CONNECTING;
}

/* What the host did, for the other threads: its state, its counters, and
 * why the link went down. Wakes safe_stop and poll. */
static void share_host(iso_actuators *a, int frames)
{
    watch_link(a);
    atomic_store(&a->state, sink_state(a));
    pthread_mutex_lock(&a->lock);
    a->link_state = a->host.state;
    a->host_st = a->host.stats;
    if (a->host.state == ISO_FB_HOST_DOWN)
        a->down = a->host.last_err;
    a->frames += (uint64_t)frames;
    pthread_cond_broadcast(&a->cond);
    pthread_mutex_unlock(&a->lock);
}

/* Before the loop's first publish (the first tick of a 5k-vertex mesh takes
 * longer than the MCU's 100 ms link watchdog) a HELLO every KEEP_ARMED_US:
 * each one re-arms the MCU holding its current positions and restarts its
 * watchdog (PROTOCOL.md), so the wait never ends in FAULT, whose brake to
 * the safe positions would jerk an MCU that was elsewhere. */
static void keep_armed(iso_actuators *a)
{
    if (a->host.state != ISO_FB_HOST_STREAMING ||
        iso_clock_us() - a->host.last_hello_us < KEEP_ARMED_US)
        return;
    iso_fb_host_rehello(&a->host);
    iso_fb_host_step(&a->host, 0, NULL, 0); /* sends the HELLO: no setpoints while handshaking */
}

static void count_event(iso_actuators *a, uint32_t *counter)
{
    pthread_mutex_lock(&a->lock);
    (*counter)++;
    pthread_mutex_unlock(&a->lock);
}

/* How the MCU gets to its safe state after a hold begins (PROTOCOL.md). */
static const char *brake_how(const iso_actuators *a)
{
    return iso_fb_host_can_safe(&a->host)
               ? "SAFE sent: the MCU brakes to its safe state at once"
               : "the MCU (firmware 1.0, no SAFE) brakes by its link watchdog, 100 ms after the "
                 "last setpoints it got";
}

/* The e-stop (the call or the probe), the loop watchdog and safe_stop, as
 * hold bits, each edge said once; returns the bits. A hold that ends leaves
 * ISO_ACT_HOLD_TICK until a publish that began after its end, which re-arms
 * with HELLO: the MCU never chases values computed before the hold. */
static unsigned update_holds(iso_actuators *a, uint64_t now, int stopped, uint64_t last_pub_us)
{
    unsigned h = a->hold;
    char line[320];
    int req = atomic_load(&a->estop_req) != 0;
    int es = req || (a->estop_probe && a->estop_probe(a->estop_ctx) != 0);
    if (es && !(h & ISO_ACT_HOLD_ESTOP)) {
        uint64_t t0 = req ? atomic_load(&a->estop_us) : now;
        if (t0 == 0 || t0 > now)
            t0 = now;
        h |= ISO_ACT_HOLD_ESTOP | ISO_ACT_HOLD_TICK;
        count_event(a, &a->st.estops);
        begin_break(a, t0, ISO_ACT_HOLD_ESTOP, "the e-stop");
        snprintf(line, sizeof line, "actuators: E-STOP%s: setpoints stopped %.1f ms after it; %s",
                 req ? "" : " (probe)", (double)(now - t0) / 1000.0, brake_how(a));
        say(a, line);
    } else if (!es && (h & ISO_ACT_HOLD_ESTOP)) {
        h &= ~(unsigned)ISO_ACT_HOLD_ESTOP;
        a->fresh_after_us = now;
        say(a, "actuators: e-stop released: setpoints resume with the loop's next tick (HELLO "
               "re-arms the MCU where it stands)");
    }
    uint64_t p = atomic_load(&a->progress_us);
    if (a->loop_timeout_us && p) {
        int stalled = now > p && now - p + STOP_GUARD_US > a->loop_timeout_us;
        if (stalled && !(h & ISO_ACT_HOLD_LOOP)) {
            h |= ISO_ACT_HOLD_LOOP | ISO_ACT_HOLD_TICK;
            count_event(a, &a->st.loop_stalls);
            begin_break(a, p, ISO_ACT_HOLD_LOOP, "the loop's last progress");
            snprintf(line, sizeof line,
                     "actuators: LOOP STALLED: no progress for %.0f ms (limit %d ms): setpoints "
                     "stopped; %s",
                     (double)(now - p) / 1000.0, a->loop_timeout_ms, brake_how(a));
            say(a, line);
        } else if (!stalled && (h & ISO_ACT_HOLD_LOOP)) {
            h &= ~(unsigned)ISO_ACT_HOLD_LOOP;
            if (p > a->fresh_after_us)
                a->fresh_after_us = p;
            say(a, "actuators: the loop progresses again: setpoints resume with its next tick");
        }
    }
    if (stopped && !(h & ISO_ACT_HOLD_STOP)) {
        h |= ISO_ACT_HOLD_STOP;
        begin_break(a, now, ISO_ACT_HOLD_STOP, "the stop");
    }
    if ((h & ISO_ACT_HOLD_TICK) &&
        !(h & (ISO_ACT_HOLD_ESTOP | ISO_ACT_HOLD_LOOP | ISO_ACT_HOLD_STOP)) &&
        last_pub_us >= a->fresh_after_us) {
        h &= ~(unsigned)ISO_ACT_HOLD_TICK;
        iso_fb_host_rehello(&a->host);
        say(a, "actuators: re-arming the MCU (HELLO) for the loop's new tick");
    }
    a->hold = h;
    atomic_store(&a->holds, h);
    return h;
}

/* The holds now, from the shared state; a hold that begins sends SAFE at
 * once to an MCU that obeys it (the SETPOINTS stop as well, so a lost SAFE
 * still ends in the MCU's watchdog brake). */
static unsigned holds_now(iso_actuators *a)
{
    pthread_mutex_lock(&a->lock);
    int stopped = a->stopped;
    uint64_t last_pub = a->last_publish_us;
    pthread_mutex_unlock(&a->lock);
    unsigned before = a->hold;
    unsigned h = update_holds(a, iso_clock_us(), stopped, last_pub);
    unsigned fresh = h & ~before;
    uint8_t cause = (fresh & ISO_ACT_HOLD_ESTOP)  ? ISO_FB_SAFE_ESTOP
                    : (fresh & ISO_ACT_HOLD_LOOP) ? ISO_FB_SAFE_LOOP_STALL
                    : (fresh & ISO_ACT_HOLD_STOP) ? ISO_FB_SAFE_STOP
                                                  : 0;
    /* refused without a word when the MCU offers no SAFE or the link is
     * down: brake_how's notice has said how the MCU gets safe then */
    if (cause && iso_fb_host_send_safe(&a->host, cause, NULL) == ISO_OK)
        count_event(a, &a->st.safe_requests);
    return h;
}

/* One period's SETPOINTS: the latest values, undriven channels at the MCU's
 * safe position. Nothing before the first publish, while a hold stands
 * (e-stop, loop stall, safe_stop), or while the MCU lacks a driven channel
 * (only the replies are read then). */
static void send_latest(iso_actuators *a)
{
    int16_t vals[ISO_ACT_MAX_CHANNELS], v[ISO_ACT_MAX_CHANNELS];
    unsigned hold = holds_now(a); /* read right before the write, so the guard holds */
    pthread_mutex_lock(&a->lock);
    int have_tick = a->have_tick, mismatch = a->mismatch;
    uint32_t tick = a->tick;
    memcpy(vals, a->values, sizeof vals);
    unsigned n = a->have_hello ? a->hello.n_channels : (unsigned)a->top;
    for (unsigned c = 0; c < n; c++)
        v[c] = a->have_hello ? a->hello.ch[c].safe : 0;
    pthread_mutex_unlock(&a->lock);
    if (!have_tick || hold || mismatch) {
        if (!have_tick && !hold) {
            /* before the first tick: bring the link up, keep the MCU armed */
            if (a->host.state != ISO_FB_HOST_STREAMING)
                iso_fb_host_step(&a->host, 0, NULL, 0); /* reopen or HELLO; never SETPOINTS */
            keep_armed(a);
        }
        share_host(a, iso_fb_host_poll(&a->host, 0));
        return;
    }
    for (int i = 0; i < a->n_ch; i++)
        v[a->ch[i].spec.channel] = vals[a->ch[i].spec.channel];
    /* Setpoints go out in this step only if the host streams already (its
     * service sends HELLO, never SETPOINTS, on the way up), and then with
     * seq = tx_seq. Remember before sending: the ACK may be read inside
     * this very step. */
    if (a->host.state == ISO_FB_HOST_STREAMING)
        remember(a, a->host.tx_seq, tick, v, n);
    uint64_t t_send = iso_clock_us();
    uint64_t rx0 = a->host.stats.rx_frames;
    int sent = iso_fb_host_step(&a->host, tick, v, n);
    int frames = (int)(a->host.stats.rx_frames - rx0);
    if (sent == 1) {
        pthread_mutex_lock(&a->lock);
        a->st.setpoints_sent++;
        a->last_sent_us = t_send; /* before the write: the watchdog counts from its arrival */
        pthread_mutex_unlock(&a->lock);
    }
    share_host(a, frames);
}

static int quitting(iso_actuators *a)
{
    pthread_mutex_lock(&a->lock);
    int q = a->quit;
    pthread_mutex_unlock(&a->lock);
    return q;
}

static void to_timespec(uint64_t us, struct timespec *ts)
{
    ts->tv_sec = (time_t)(us / 1000000u);
    ts->tv_nsec = (long)(us % 1000000u) * 1000;
}

/* SETPOINTS every PERIOD_US on absolute CLOCK_MONOTONIC deadlines, the
 * replies read in between; a period missed by more than one is skipped, not
 * caught up in a burst. */
static void *sender_main(void *arg)
{
    iso_actuators *a = arg;
    uint64_t next = iso_clock_us();
    while (!quitting(a)) {
        send_latest(a);
        next += PERIOD_US;
        uint64_t now = iso_clock_us();
        if (next + PERIOD_US < now)
            next = now + PERIOD_US;
        while ((now = iso_clock_us()) < next) {
            uint64_t slice = next - now < HOLD_POLL_US ? next - now : HOLD_POLL_US;
            int frames = 0;
            if (slice >= 1000u && a->host.state != ISO_FB_HOST_DOWN)
                frames = iso_fb_host_poll(&a->host, (int)(slice / 1000u));
            else
                iso_clock_sleep_until((int64_t)(now + slice) * 1000);
            unsigned before = a->hold;
            if (holds_now(a) != before || frames > 0 || a->host.state == ISO_FB_HOST_DOWN)
                share_host(a, frames);
        }
    }
    return NULL;
}

/* ------------------------------------------------------------------------ */
/* Create / destroy                                                           */
/* ------------------------------------------------------------------------ */

static int open_link(iso_actuators *a, const iso_act_link_spec *l, iso_err *err)
{
    int baud = l->baud > 0 ? l->baud : 115200;
    switch (l->kind) {
    case ISO_ACT_LINK_TTY: return iso_link_tty_open(l->path, baud, &a->link, err);
    case ISO_ACT_LINK_SERIAL: return iso_link_sp_open(l->path, baud, &a->link, err);
    /* 5 ms: a reopen after a loss runs inside a sender period */
    case ISO_ACT_LINK_TCP: return iso_link_tcp_open(l->host, l->port, 5, &a->link, err);
    case ISO_ACT_LINK_EMULATED: {
        iso_act_emu_info info;
        int rc = iso_act_emu_open(l->emulation, &a->link, &info, err);
        if (rc == ISO_OK && !a->link)
            rc = iso_err_set(err, ISO_EIO, -1, "actuators: the emulated MCU gave no link");
        if (rc == ISO_OK)
            say(a, info.line);
        return rc;
    }
    }
    return iso_err_set(err, ISO_EINVAL, -1, "actuators: unknown link kind %d", l->kind);
}

int iso_actuators_create(const iso_act_channel *ch, int n_ch, int nv, const iso_regions *regions,
                         const iso_act_link_spec *link, const iso_act_opts *opts,
                         iso_actuators **out, iso_err *err)
{
    return iso_actuators_create_v2(ch, n_ch, nv, regions, link, opts, NULL, out, err);
}

/* Reads the safety options into a (defaults for NULL or zero fields). */
static int take_safety(iso_actuators *a, const iso_act_safety_opts *so, iso_err *err)
{
    int tick_ms = so && so->tick_period_ms > 0 ? so->tick_period_ms : 0;
    int t = so ? so->loop_timeout_ms : 0;
    if (t > 0 && t < (int)(PERIOD_US / 1000u))
        return iso_err_set(
            err, ISO_EINVAL, -1,
            "actuators: loop_timeout_ms %d is shorter than the sender's %u ms period "
            "(0 = the default, < 0 = no loop watchdog)",
            t, PERIOD_US / 1000u);
    if (t == 0)
        t = 5 * tick_ms > LOOP_TIMEOUT_MIN_MS ? 5 * tick_ms : LOOP_TIMEOUT_MIN_MS;
    a->loop_timeout_ms = t;
    a->loop_timeout_us = t > 0 ? (uint64_t)t * 1000u : 0;
    if (so) {
        a->estop_probe = so->estop_probe;
        a->estop_ctx = so->estop_ctx;
    }
    return ISO_OK;
}

int iso_actuators_create_v2(const iso_act_channel *ch, int n_ch, int nv, const iso_regions *regions,
                            const iso_act_link_spec *link, const iso_act_opts *opts,
                            const iso_act_safety_opts *safety, iso_actuators **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!out || !ch || n_ch < 1 || n_ch > ISO_ACT_MAX_CHANNELS || nv < 1)
        return iso_err_set(
            err, ISO_EINVAL, -1,
            "actuators: need 1..%d channels over a mesh with vertices (got %d channels, "
            "%d vertices)",
            ISO_ACT_MAX_CHANNELS, n_ch, nv);
    iso_actuators *a = calloc(1, sizeof *a);
    if (!a)
        return iso_err_set(err, ISO_ENOMEM, -1, "actuators: out of memory");
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_mutex_init(&a->lock, NULL);
    pthread_cond_init(&a->cond, &ca);
    pthread_condattr_destroy(&ca);
    a->nv = nv;
    a->st.mcu_state = -1;
    a->st.last_safe_ms = -1;
    a->mcu_safe = 1; /* an MCU boots idle: its first words are no news */
    atomic_init(&a->progress_us, 0);
    atomic_init(&a->alive_calls, 0);
    atomic_init(&a->estop_req, 0);
    atomic_init(&a->estop_us, 0);
    atomic_init(&a->state, ISO_ACT_STATE_OFF);
    atomic_init(&a->holds, 0);
    if (opts) {
        a->notice = opts->notice;
        a->notice_ctx = opts->notice_ctx;
    }
    int rc = take_safety(a, safety, err);
    for (int i = 0; i < n_ch && rc == ISO_OK; i++) {
        if ((rc = check_channel(&ch[i], i, nv, regions, err)) != ISO_OK)
            break;
        for (int j = 0; j < i; j++)
            if (ch[j].channel == ch[i].channel) {
                rc = iso_err_set(err, ISO_EINVAL, i,
                                 "actuators: channel %d is used twice (entries %d and %d)",
                                 ch[i].channel, j, i);
                break;
            }
        if (rc != ISO_OK)
            break;
        a->ch[i].spec = ch[i];
        a->n_ch = i + 1;
        if (ch[i].region != ISO_ACT_REGION_NONE)
            rc = collect_region(&a->ch[i], nv, regions, i, err);
        if (ch[i].channel + 1 > a->top)
            a->top = ch[i].channel + 1;
    }
    if (rc == ISO_OK && link && link->kind != ISO_ACT_LINK_NONE) {
        rc = open_link(a, link, err);
        if (rc == ISO_OK) {
            iso_fb_host_callbacks cb = {NULL, on_ack, on_fault, on_hello, on_heartbeat, a};
            iso_fb_host_opts ho = {0};
            ho.write_timeout_ms = 1; /* never hold a period */
            ho.reopen_ms = REOPEN_MS;
            ho.link_timeout_ms = opts && opts->link_timeout_ms > 0     ? opts->link_timeout_ms
                                 : link->kind == ISO_ACT_LINK_EMULATED ? 3000
                                                                       : 1000;
            rc = iso_fb_host_init(&a->host, a->link, &ho, &cb, err);
            a->host_up = rc == ISO_OK;
            a->link_state = a->prev_host_state = a->host.state;
            atomic_store(&a->state, ISO_ACT_STATE_CONNECTING);
        }
        if (rc == ISO_OK) {
            if (pthread_create(&a->sender, NULL, sender_main, a) == 0)
                a->sender_started = 1;
            else
                rc = iso_err_set(err, ISO_EIO, -1,
                                 "actuators: cannot start the setpoints sender thread");
        }
    }
    if (rc != ISO_OK) {
        iso_actuators_destroy(a);
        return rc;
    }
    *out = a;
    return ISO_OK;
}

void iso_actuators_destroy(iso_actuators *a)
{
    if (!a)
        return;
    if (a->sender_started) {
        pthread_mutex_lock(&a->lock);
        a->quit = 1;
        pthread_mutex_unlock(&a->lock);
        pthread_join(a->sender, NULL); /* within a period: it checks once per period */
    }
    if (a->host_up)
        iso_fb_host_deinit(&a->host);
    iso_link_close(a->link);
    for (int i = 0; i < a->n_ch; i++)
        free(a->ch[i].verts);
    pthread_cond_destroy(&a->cond);
    pthread_mutex_destroy(&a->lock);
    free(a);
}

/* ------------------------------------------------------------------------ */
/* Per tick                                                                   */
/* ------------------------------------------------------------------------ */

static double coordinate(const act_channel *c, const double *x)
{
    int ax = c->spec.axis;
    if (!c->verts)
        return x[3 * c->spec.vertex + ax];
    double sum = 0;
    for (int k = 0; k < c->n_verts; k++)
        sum += x[3 * c->verts[k] + ax];
    return sum / c->n_verts;
}

/* The values into values[channel], the clamps into clamped[channel] (0/1);
 * touches nothing shared. */
static int compute_values(const iso_actuators *a, const double *x,
                          int16_t values[ISO_ACT_MAX_CHANNELS],
                          uint8_t clamped[ISO_ACT_MAX_CHANNELS], iso_err *err)
{
    double u[ISO_ACT_MAX_CHANNELS];
    for (int i = 0; i < a->n_ch; i++) {
        u[i] = coordinate(&a->ch[i], x);
        if (!isfinite(u[i]))
            return iso_err_set(
                err, ISO_ENUMERIC, -1,
                "actuators: channel %d: its position is not finite (%g); nothing sent",
                a->ch[i].spec.channel, u[i]);
    }
    for (int i = 0; i < a->n_ch; i++) {
        const iso_act_channel *c = &a->ch[i].spec;
        int cl = 0;
        double v = u[i];
        if (v < c->min || v > c->max) {
            v = v < c->min ? c->min : c->max;
            cl = 1;
        }
        double m = nearbyint(v * c->scale);
        if (m < INT16_MIN || m > INT16_MAX) {
            m = m < INT16_MIN ? INT16_MIN : INT16_MAX;
            cl = 1;
        }
        values[c->channel] = (int16_t)m;
        clamped[c->channel] = (uint8_t)cl;
    }
    return ISO_OK;
}

/* Under the lock: one tick's clamps and the tick itself. */
static void count_tick(iso_actuators *a, const uint8_t clamped[ISO_ACT_MAX_CHANNELS])
{
    for (int i = 0; i < a->n_ch; i++) {
        int c = a->ch[i].spec.channel;
        a->st.clamps += clamped[c];
        a->st.clamps_ch[c] += clamped[c];
    }
    a->st.ticks++;
}

int iso_actuators_compute(iso_actuators *a, const double *x, int16_t values[ISO_ACT_MAX_CHANNELS],
                          iso_err *err)
{
    if (!a || !x || !values)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: NULL handle, positions or values");
    uint8_t clamped[ISO_ACT_MAX_CHANNELS];
    int rc = compute_values(a, x, values, clamped, err);
    if (rc != ISO_OK)
        return rc;
    pthread_mutex_lock(&a->lock);
    count_tick(a, clamped);
    pthread_mutex_unlock(&a->lock);
    return ISO_OK;
}

int iso_actuators_publish(iso_actuators *a, uint32_t tick, const double *x, iso_err *err)
{
    if (!a || !x)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: NULL handle or positions");
    uint64_t t0 = iso_clock_us();
    int16_t v[ISO_ACT_MAX_CHANNELS];
    uint8_t clamped[ISO_ACT_MAX_CHANNELS];
    memset(v, 0, sizeof v);
    int rc = compute_values(a, x, v, clamped, err);
    pthread_mutex_lock(&a->lock);
    int stopped = a->stopped, mismatch = a->mismatch, state = a->link_state;
    int mcu_n = a->hello.n_channels;
    if (!stopped && rc == ISO_OK) {
        count_tick(a, clamped);
        memcpy(a->values, v, sizeof v);
        a->tick = tick;
        a->have_tick = 1;
        a->last_publish_us = t0;
        if (atomic_load_explicit(&a->progress_us, memory_order_relaxed))
            atomic_store_explicit(&a->progress_us, t0, memory_order_relaxed);
        double ms = (double)(iso_clock_us() - t0) / 1000.0;
        if (ms > a->st.publish_max_ms)
            a->st.publish_max_ms = ms;
        a->st.publish_over_1ms += ms > 1.0;
    }
    pthread_mutex_unlock(&a->lock);
    if (stopped)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "actuators: stopped by safe_stop; create a new sink");
    if (rc != ISO_OK || !a->host_up)
        return rc == ISO_OK ? 0 : rc;
    if (mismatch)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "actuators: the MCU has %d channels but the spec drives channel %d; "
                           "nothing sent",
                           mcu_n, a->top - 1);
    int st = atomic_load(&a->state);
    return state == ISO_FB_HOST_STREAMING && atomic_load(&a->holds) == 0 &&
           (st == ISO_ACT_STATE_ARMED || st == ISO_ACT_STATE_SILENT);
}

int iso_actuators_poll(iso_actuators *a, int timeout_ms)
{
    if (!a || !a->host_up)
        return 0;
    pthread_mutex_lock(&a->lock);
    uint64_t f0 = a->frames;
    if (a->link_state != ISO_FB_HOST_DOWN && timeout_ms > 0) {
        struct timespec ts;
        to_timespec(iso_clock_us() + (uint64_t)timeout_ms * 1000u, &ts);
        while (a->frames == f0 && a->link_state != ISO_FB_HOST_DOWN)
            if (pthread_cond_timedwait(&a->cond, &a->lock, &ts) != 0)
                break;
    }
    int n = (int)(a->frames - f0);
    pthread_mutex_unlock(&a->lock);
    return n;
}

int iso_actuators_safe_stop(iso_actuators *a, int timeout_ms, double *safe_ms, iso_err *err)
{
    if (safe_ms)
        *safe_ms = -1;
    if (!a || !a->host_up)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: safe_stop needs a link");
    uint64_t start = iso_clock_us(),
             deadline = start + (uint64_t)(timeout_ms > 0 ? timeout_ms : 0) * 1000u;
    struct timespec ts;
    to_timespec(deadline, &ts);
    pthread_mutex_lock(&a->lock);
    a->stopped = 1; /* the sender sends no more SETPOINTS from its next period */
    /* Only what arrives from now on counts: an earlier FAULT was answered
     * by a new HELLO and streaming since. */
    a->saw_safe = 0;
    while (!a->saw_safe && a->link_state != ISO_FB_HOST_DOWN)
        if (pthread_cond_timedwait(&a->cond, &a->lock, &ts) != 0)
            break;
    int saw = a->saw_safe, down = a->link_state == ISO_FB_HOST_DOWN;
    uint64_t safe_us = a->safe_us, last = a->last_sent_us;
    iso_err why = a->down;
    pthread_mutex_unlock(&a->lock);
    if (!saw && down)
        return iso_err_set(err, ISO_EIO, -1,
                           "actuators: the link is down, so the MCU's safe state cannot be "
                           "confirmed (its watchdog takes it there 100 ms after the last "
                           "setpoints it got): %s",
                           why.msg);
    if (!saw)
        return iso_err_set(err, ISO_EIO, -1,
                           "actuators: the MCU did not report its safe state within %d ms of the "
                           "stop (link up)",
                           timeout_ms);
    if (safe_ms)
        *safe_ms = (double)(safe_us - (last ? last : start)) / 1000.0;
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Counters                                                                   */
/* ------------------------------------------------------------------------ */

/* The lock is not part of the handle's value: readers take it too. */
static pthread_mutex_t *lock_of(const iso_actuators *a)
{
    return (pthread_mutex_t *)&a->lock;
}

void iso_actuators_stats(const iso_actuators *a, iso_act_stats *out)
{
    pthread_mutex_lock(lock_of(a));
    *out = a->st;
    if (a->host_up) {
        out->link_losses = a->host_st.link_losses;
        out->handshakes = a->host_st.handshakes;
        out->naks = a->host_st.naks;
        out->reopens = a->host_st.reopens;
    }
    pthread_mutex_unlock(lock_of(a));
    out->emu_restarts = iso_act__emu_restarts(a->link);
    out->alive_calls = atomic_load(&((iso_actuators *)a)->alive_calls);
}

int iso_actuators_mcu_hello(const iso_actuators *a, iso_fb_hello *out)
{
    pthread_mutex_lock(lock_of(a));
    int have = a->have_hello;
    if (have)
        *out = a->hello;
    pthread_mutex_unlock(lock_of(a));
    return have;
}

int iso_actuators_format_stats(const iso_actuators *a, char *buf, size_t cap)
{
    iso_act_stats s;
    iso_actuators_stats(a, &s);
    /* the safety counts come before the link's line, which a short buffer
     * cuts first */
    int n = snprintf(
        buf, cap,
        "actuators: %llu ticks, %llu setpoints sent, %llu acked, %llu echo mismatches (%llu "
        "unchecked), %llu clamps, rtt avg %.3f ms (max %.3f), publish max %.2f ms (%llu over 1 "
        "ms); link %s, losses %u, reopens %u, emulation restarts %u, loop stalls %u, e-stops %u, "
        "silences %u, SAFE requests %u, safe states confirmed %u",
        (unsigned long long)s.ticks, (unsigned long long)s.setpoints_sent,
        (unsigned long long)s.acks, (unsigned long long)s.echo_mismatches,
        (unsigned long long)s.echo_unknown, (unsigned long long)s.clamps, s.rtt_avg_ms,
        s.rtt_max_ms, s.publish_max_ms, (unsigned long long)s.publish_over_1ms,
        iso_actuators_link_state(a), (unsigned)s.link_losses, (unsigned)s.reopens, s.emu_restarts,
        (unsigned)s.loop_stalls, (unsigned)s.estops, (unsigned)s.silences,
        (unsigned)s.safe_requests, (unsigned)s.safe_confirms);
    if (!a->host_up || n < 0 || (size_t)n + 2 >= cap)
        return n;
    /* the host's line from its counters as the sender last shared them */
    pthread_mutex_lock(lock_of(a));
    iso_fb_host_stats hs = a->host_st;
    pthread_mutex_unlock(lock_of(a));
    buf[n] = ';';
    buf[n + 1] = ' ';
    return n + 2 + iso_fb_host_stats_format(&hs, buf + n + 2, cap - (size_t)n - 2);
}

/* ------------------------------------------------------------------------ */
/* Safety calls from any thread                                               */
/* ------------------------------------------------------------------------ */

void iso_actuators_alive(iso_actuators *a)
{
    if (!a)
        return;
    atomic_store_explicit(&a->progress_us, iso_clock_us(), memory_order_relaxed);
    atomic_fetch_add_explicit(&a->alive_calls, 1, memory_order_relaxed);
}

void iso_actuators_estop(iso_actuators *a, int on)
{
    if (!a)
        return;
    if (!on) {
        atomic_store(&a->estop_req, 0);
        return;
    }
    if (atomic_load(&a->estop_req))
        return;                                 /* the edge counts, not the level */
    atomic_store(&a->estop_us, iso_clock_us()); /* before the flag: the sender reads both */
    atomic_store(&a->estop_req, 1);
}

int iso_actuators_state(const iso_actuators *a, unsigned *holds)
{
    iso_actuators *m = (iso_actuators *)a; /* atomic loads take non-const pointers */
    if (holds)
        *holds = m ? atomic_load(&m->holds) : 0;
    return m ? atomic_load(&m->state) : ISO_ACT_STATE_OFF;
}

const char *iso_actuators_link_state(const iso_actuators *a)
{
    unsigned h;
    int s = iso_actuators_state(a, &h);
    switch (s) {
    case ISO_ACT_STATE_CONNECTING: return "connecting";
    case ISO_ACT_STATE_ARMED: return "armed";
    case ISO_ACT_STATE_SILENT: return "silent";
    case ISO_ACT_STATE_STOPPING:
        return h & ISO_ACT_HOLD_ESTOP  ? "stopping (e-stop)"
               : h & ISO_ACT_HOLD_LOOP ? "stopping (loop stalled)"
               : h & ISO_ACT_HOLD_STOP ? "stopping (stopped)"
                                       : "stopping";
    case ISO_ACT_STATE_SAFE:
        return h & ISO_ACT_HOLD_ESTOP  ? "safe (e-stop)"
               : h & ISO_ACT_HOLD_LOOP ? "safe (loop stalled)"
               : h & ISO_ACT_HOLD_STOP ? "safe (stopped)"
                                       : "safe (waiting for a tick)";
    case ISO_ACT_STATE_LOST: return "lost";
    case ISO_ACT_STATE_RECONNECTING: return "reconnecting";
    }
    return "off";
}

int iso_actuators_emu_signal(iso_actuators *a, int sig, iso_err *err)
{
    if (!a || !a->link)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: no emulated MCU to signal");
    return iso_act__emu_signal(a->link, sig, err);
}
