/* actuators/actuators.c -- see iso_actuators.h: the sink's channels, its
 * creation, what each tick publishes, and its counters. The sender thread
 * is sender.c, the rules that stop it safety.c. */
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "act_internal.h"
#include "iso_actuators_drill.h"
#include "iso_clock.h"
#include "iso_logq.h"

void iso_act__say(const iso_actuators *a, const char *line)
{
    if (a->notice)
        a->notice(a->notice_ctx, line);
    else
        iso_logq_say(a->logq, line); /* the sender never writes to stderr itself */
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
/* Create / destroy                                                           */
/* ------------------------------------------------------------------------ */

static int open_link(iso_actuators *a, const iso_act_link_spec *l, iso_err *err)
{
    int baud = l->baud > 0 ? l->baud : (int)ISO_FB_BOARD_BAUD;
    switch (l->kind) {
    case ISO_ACT_LINK_TTY: return iso_link_tty_open(l->path, baud, &a->link, err);
    case ISO_ACT_LINK_SERIAL: return iso_link_sp_open(l->path, baud, &a->link, err);
    /* 5 ms: a reopen after a loss runs inside a sender period */
    case ISO_ACT_LINK_TCP: return iso_link_tcp_open(l->host, l->port, 5, &a->link, err);
    case ISO_ACT_LINK_USB: return iso_link_usb_open(l->vid, l->pid, &a->link, err);
    case ISO_ACT_LINK_EMULATED: {
        iso_act_emu_info info;
        int rc = iso_actuators_emu_open(l->emulation, &a->link, &info, err);
        if (rc == ISO_OK && !a->link)
            rc = iso_err_set(err, ISO_EIO, -1, "actuators: the emulated MCU gave no link");
        if (rc == ISO_OK)
            iso_act__say(a, info.line);
        return rc;
    }
    }
    return iso_err_set(err, ISO_EINVAL, -1, "actuators: unknown link kind %d", l->kind);
}

int iso_actuators_create(const iso_act_channel *ch, int n_ch, int nv, const iso_regions *regions,
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
    /* The loop's publish takes this lock: a holder below the loop's
     * priority runs at it until it lets go (iso_actuators_set_priority). */
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&a->lock, &ma);
    pthread_mutexattr_destroy(&ma);
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
    int rc = a->notice ? ISO_OK : iso_logq_create(stderr, 0, &a->logq, err);
    if (rc == ISO_OK)
        rc = iso_act__take_safety(a, safety, err);
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
            iso_fb_host_callbacks cb;
            iso_act__host_callbacks(a, &cb);
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
            if (pthread_create(&a->sender, NULL, iso_act__sender_main, a) == 0)
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
    iso_logq_destroy(a->logq);
    free(a);
}

int iso_actuators_set_priority(iso_actuators *a, int priority, iso_err *err)
{
    if (!a || priority < 0 || priority + 1 > sched_get_priority_max(SCHED_FIFO))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "actuators: priority %d: expected 0, or 1..%d (the emulation runs one "
                           "above)",
                           priority, sched_get_priority_max(SCHED_FIFO) - 1);
    if (a->sender_started) {
        struct sched_param sp;
        memset(&sp, 0, sizeof sp);
        sp.sched_priority = priority;
        int rc = pthread_setschedparam(a->sender, priority ? SCHED_FIFO : SCHED_OTHER, &sp);
        if (rc != 0)
            return iso_err_set(err, ISO_EIO, -1,
                               "actuators: the sender thread at SCHED_FIFO %d: %s", priority,
                               strerror(rc));
    }
    if (iso_act__emu_is(a->link))
        return iso_act__emu_priority(a->link, priority ? priority + 1 : 0, err);
    return ISO_OK;
}

static void to_timespec(uint64_t us, struct timespec *ts)
{
    ts->tv_sec = (time_t)(us / 1000000u);
    ts->tv_nsec = (long)(us % 1000000u) * 1000;
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
        a->prev_publish_us = a->last_publish_us;
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

int iso_actuators_setpoints(const iso_actuators *a, int16_t values[ISO_ACT_MAX_CHANNELS],
                            uint32_t *tick)
{
    pthread_mutex_lock(lock_of(a));
    int have = a->have_tick;
    memcpy(values, a->values, ISO_ACT_MAX_CHANNELS * sizeof *values);
    if (tick)
        *tick = a->tick;
    pthread_mutex_unlock(lock_of(a));
    if (!have)
        memset(values, 0, ISO_ACT_MAX_CHANNELS * sizeof *values);
    return have;
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
    return n + 2 + iso_fb_host_format_stats_copy(&hs, buf + n + 2, cap - (size_t)n - 2);
}

int iso_actuators_emu_signal(iso_actuators *a, int sig, iso_err *err)
{
    if (!a || !a->link)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: no emulated MCU to signal");
    return iso_act__emu_signal(a->link, sig, err);
}
