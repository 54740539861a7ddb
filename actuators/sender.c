/* actuators/sender.c -- the sender thread: SETPOINTS every PERIOD_US over
 * the firmware bridge's host, the MCU's replies, and the link's story
 * (lost, reopened, re-armed, silent), each said once as it happens. The
 * holds that stop it are safety.c's. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#include "act_internal.h"
#include "iso_clock.h"

#define KEEP_ARMED_US 40000u /* HELLO again this often until the first publish */
/* The holds are looked at this often, not only once a period: an e-stop
 * edge sends SAFE within 2 ms (+ the probe). */
#define HOLD_POLL_US 2000u
#define SILENT_US 500000u      /* no frame this long: say so (5 heartbeats) */
#define STILL_LOST_US 2000000u /* repeat the loss notice this often */

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
        iso_act__say(a, line);
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
    iso_act__say(a, line);
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
            iso_act__say(a, line);
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

static void on_hello(void *ctx, const iso_fb_hello *h_in)
{
    iso_actuators *a = ctx;
    if (h_in->flags & ISO_FB_HELLO_BOOT) {
        iso_act__note_safe(a, "HELLO(BOOT)");
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
    iso_act__note_safe(a, how);
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
        iso_act__note_safe(a,
                           hb->state == ISO_FB_STATE_IDLE ? "heartbeat: idle" : "heartbeat: safe");
}

void iso_act__host_callbacks(iso_actuators *a, iso_fb_host_callbacks *cb)
{
    iso_fb_host_callbacks c = {NULL, on_ack, on_fault, on_hello, on_heartbeat, a};
    *cb = c;
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
            iso_act__begin_break(a, now, 0, "the link was lost");
        snprintf(line, sizeof line,
                 "actuators: LINK LOST to the MCU: %.300s. No setpoints reach it; its own watchdog "
                 "brakes it to its safe state 100 ms after the last ones. Reopening every %d ms%s",
                 a->host.last_err.msg, REOPEN_MS,
                 a->hold                    ? " once setpoints may flow again"
                 : iso_act__emu_is(a->link) ? " (restarting the emulation if it died)"
                                            : "");
        iso_act__say(a, line);
    } else if (hs == ISO_FB_HOST_DOWN && now - a->lost_told_us >= STILL_LOST_US) {
        a->lost_told_us = now;
        snprintf(line, sizeof line, "actuators: link still lost after %.1f s: %.300s",
                 (double)(now - a->lost_us) / 1e6, a->host.last_err.msg);
        iso_act__say(a, line);
    }
    if (a->host.stats.reopens != a->reopens_seen) {
        a->reopens_seen = a->host.stats.reopens;
        unsigned r = iso_act__emu_restarts(a->link);
        snprintf(line, sizeof line,
                 "actuators: link reopened %.0f ms after the loss%s; shaking hands",
                 (double)(now - a->lost_us) / 1000.0, r ? " (the emulation was restarted)" : "");
        iso_act__say(a, line);
    }
    if (hs == ISO_FB_HOST_STREAMING) {
        a->ever_streamed = 1;
        if (a->lost) {
            a->lost = 0;
            snprintf(line, sizeof line,
                     "actuators: MCU armed again %.0f ms after the link was lost",
                     (double)(now - a->lost_us) / 1000.0);
            iso_act__say(a, line);
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
                 SILENT_US / 1000u,
                 a->hold                       ? ""
                 : hs == ISO_FB_HOST_STREAMING ? "; setpoints continue"
                                               : "; no setpoints until it answers HELLO",
                 a->host.opts.link_timeout_ms);
        iso_act__say(a, line);
    } else if (a->silent && a->host.last_rx_us > a->silent_from_us) {
        a->silent = 0;
        snprintf(line, sizeof line, "actuators: the MCU answers again after %.0f ms of silence",
                 (double)(a->host.last_rx_us - a->silent_from_us) / 1000.0);
        iso_act__say(a, line);
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

/* One period's SETPOINTS: the latest values, undriven channels at the MCU's
 * safe position. Nothing before the first publish, while a hold stands
 * (e-stop, loop stall, safe_stop), or while the MCU lacks a driven channel
 * (only the replies are read then). */
static void send_latest(iso_actuators *a)
{
    int16_t vals[ISO_ACT_MAX_CHANNELS], v[ISO_ACT_MAX_CHANNELS];
    unsigned hold = iso_act__holds_now(a); /* read right before the write, so the guard holds */
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
    if (iso_act__gap_since_look(a)) { /* stopped since the look: look again first */
        share_host(a, iso_fb_host_poll(&a->host, 0));
        return;
    }
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

/* SETPOINTS every PERIOD_US on absolute CLOCK_MONOTONIC deadlines, the
 * replies read in between; a period missed by more than one is skipped, not
 * caught up in a burst. */
void *iso_act__sender_main(void *arg)
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
            if (iso_act__holds_now(a) != before || frames > 0 || a->host.state == ISO_FB_HOST_DOWN)
                share_host(a, frames);
        }
    }
    return NULL;
}
