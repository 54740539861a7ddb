/* controller/loop_run.c -- the run: stream and wall clocks, absolute
 * deadlines, real-time scheduling and locked memory, and the status line
 * (iso_loop.h). */
#include "loop_internal.h"

#include <errno.h>
#include <math.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include "iso_actuators.h"
#include "iso_clock.h"

/* ======================================================================== */
/* The run                                                                  */
/* ======================================================================== */

int64_t iso_loop__grid_ns(const iso_loop *l, int64_t k)
{
    return l->stream0 + (int64_t)llround((double)k * 1e9 / l->sc->tick_hz);
}

/* Sleeps to an absolute deadline; returns early only for a stop request. */
static void sleep_until(const iso_loop *l, int64_t t)
{
    while (iso_clock_sleep_until(t))
        if (l->o.stop && *l->o.stop)
            return;
}

/* The threads the tick waits for, at their places around the tick's
 * priority (iso_loop.h states the rule): the factorization worker just
 * below it, the devices' byte-stream reader below that, the actuators'
 * sender (the tick's watchdog) above it and an emulated MCU above that.
 * Says what was not permitted into why. */
static void threads_realtime(iso_loop *l, char *why, size_t cap)
{
    iso_err e;
    iso_err_clear(&e);
    if (l->solver &&
        iso_solver_set_worker_priority(l->solver, ISO_LOOP_RT_PRIORITY - 1, &e) != ISO_OK)
        snprintf(why + strlen(why), cap - strlen(why), "%s%.150s", why[0] ? "; " : "", e.msg);
    iso_err_clear(&e);
    if (l->hub && iso_dev_hub_set_priority(l->hub, ISO_LOOP_RT_PRIORITY - 2, &e) != ISO_OK)
        snprintf(why + strlen(why), cap - strlen(why), "%s%.150s", why[0] ? "; " : "", e.msg);
    iso_err_clear(&e);
    struct iso_actuators *a = iso_loop_actuators(l);
    if (a && iso_actuators_set_priority(a, ISO_LOOP_RT_PRIORITY + 1, &e) != ISO_OK)
        snprintf(why + strlen(why), cap - strlen(why), "%s%.150s", why[0] ? "; " : "", e.msg);
}

/* SCHED_FIFO and locked memory, when this process may have them. Asked for
 * after the display's and BLAS's threads exist, so only the loop's thread
 * and the threads it waits for run at real-time priority (threads_realtime).
 * Memory: what the process holds now (MCL_CURRENT: the mesh, the solver and
 * its factor, the sinks, the tick statistics reserved for the planned run),
 * not what it allocates later, so a browser's buffers are never locked
 * (lock only the memory the loop needs). */
static void go_realtime(iso_loop *l)
{
    iso_loop_summary *r = &l->rt;
    char why[400] = "";
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = ISO_LOOP_RT_PRIORITY;
    if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
        r->rt_active = 1;
        threads_realtime(l, why, sizeof why);
    } else {
        snprintf(why, sizeof why, "SCHED_FIFO: %s", strerror(errno));
    }
    /* the tick statistics' room was made at create (iso_loop__stats_reserve) */
    if (mlockall(MCL_CURRENT) == 0)
        r->mem_locked = 1;
    else
        snprintf(why + strlen(why), sizeof why - strlen(why), "%smlockall: %s", why[0] ? "; " : "",
                 strerror(errno));
    if (why[0]) {
        snprintf(r->rt_note, sizeof r->rt_note,
                 "not permitted (%.250s): normal priority (grant CAP_SYS_NICE and CAP_IPC_LOCK, "
                 "or rtprio/memlock in limits.conf)",
                 why);
        iso_loop_say(l, "real-time scheduling %s", r->rt_note);
    } else {
        iso_loop_say(l,
                     "real-time: SCHED_FIFO priority %d (factorization worker %d%s), "
                     "memory locked",
                     sp.sched_priority, sp.sched_priority - 1,
                     iso_loop_actuators(l) ? ", actuator sender and its MCU above" : "");
    }
}

/* The stream time of the next tick, or INT64_MAX when the run is over. */
static int64_t next_stream_tick(iso_loop *l)
{
    if (l->replay) {
        int64_t t = iso_dev_hub_next_tick(l->hub, l->period_ns);
        return t != INT64_MAX && t - l->stream0 > l->t_end ? INT64_MAX : t;
    }
    return l->k >= l->k_end ? INT64_MAX : iso_loop__grid_ns(l, l->k + 1);
}

/* The devices' part of the status line: events per second each, the
 * active handle, clutch and e-stop. */
static void devices_status(iso_loop *l, double dt, char *buf, size_t cap)
{
    buf[0] = 0;
    if (!l->hub)
        return;
    size_t n = iso_dev_hub_sources(l->hub), used = 0;
    for (size_t i = 0; i < n && i < ISO_DEV_MAX_SOURCES && used + 24 < cap; i++) {
        iso_dev_source_stats st;
        if (iso_dev_hub_source_stats(l->hub, i, &st) != ISO_OK)
            continue;
        double rate = dt > 0 ? (double)(st.events - l->status_events[i]) / dt : 0;
        l->status_events[i] = st.events;
        used += (size_t)snprintf(buf + used, cap - used, "dev%zu %.0f/s%s  ", i, rate,
                                 !st.present   ? " GONE"
                                 : st.is_stale ? " STALE"
                                               : "");
    }
    if (used + 40 < cap)
        snprintf(buf + used, cap - used, "handle %d%s%s  ", l->last.active,
                 l->last.clutch ? " clutch" : "", l->last.estop ? "  E-STOP" : "");
}

static void status_line(iso_loop *l, double t_s, double dt)
{
    double med, p99, max;
    iso_loop__stats_recent(&l->stats, &med, &p99, &max);
    char extra[160] = "", dev[256];
    if (l->sinks)
        iso_loop__sinks_status(l, extra, sizeof extra);
    devices_status(l, dt, dev, sizeof dev);
    char line[ISO_LOGQ_LINE_MAX];
    snprintf(line, sizeof line,
             "tick %ld  t %.2f s  tick %.1f/%.1f/%.1f ms (med/p99/max)  missed %ld  %s%s", l->ticks,
             t_s, med, p99, max, l->stats.skipped, dev, extra);
    iso_logq_status(l->logq, line);
}

/* The first tick's start: a live run's is now; a replay's is the recorded
 * loop's start, so the first tick is as long as it was there. */
static void start_streams(iso_loop *l)
{
    const int live = l->hub && !l->replay;
    l->stream0 = live ? iso_clock_ns() : 0;
    if (l->replay) {
        int64_t first = iso_dev_hub_next_tick(l->hub, l->period_ns);
        l->stream0 = first == INT64_MAX ? 0 : first - l->period_ns;
        if (first != INT64_MAX && l->reader.t0_ns < first && l->reader.t0_ns >= l->stream0)
            l->stream0 = l->reader.t0_ns;
    }
    l->t_now = l->stream0;
    l->k = 0;
}

int iso_loop_run(iso_loop *l, iso_err *err)
{
    const int live = l->hub && !l->replay;
    const int timed = !l->o.fast;
    if (timed && l->o.rt)
        go_realtime(l);
    else if (!timed && live)
        iso_loop_say(l, "--fast with live devices: ticks do not wait for input");
    start_streams(l);
    l->wall0 = iso_clock_ns();
    int64_t prev_wake = l->wall0;
    l->wall_start = iso_clock_now();
    double last_status = 0;
    int rc = ISO_OK;
    for (;;) {
        if (l->o.stop && *l->o.stop)
            break;
        if (l->o.max_ticks > 0 && l->ticks >= l->o.max_ticks)
            break;
        int64_t t = next_stream_tick(l);
        if (t == INT64_MAX)
            break;
        if (timed) {
            sleep_until(l, l->wall0 + (int64_t)((double)(t - l->stream0) / l->o.speed));
            if (l->o.stop && *l->o.stop)
                break;
        }
        int64_t wake = iso_clock_ns();
        iso_loop__sinks_alive(l);
        if ((rc = iso_loop__tick(l, timed ? wake : 0, err)) != ISO_OK)
            break;
        int64_t done = iso_clock_ns();
        iso_loop__stats_add(&l->stats, (double)(done - wake) * 1e-6,
                            (double)(done - prev_wake) * 1e-6);
        if (l->ticks > 1)
            l->stats.max_gap_ms = fmax(l->stats.max_gap_ms, (double)(wake - prev_wake) * 1e-6);
        prev_wake = wake;
        double w = iso_clock_now();
        if (l->o.status_line && w - last_status > 0.25) {
            status_line(l, (double)(l->t_now - l->stream0) * 1e-9,
                        last_status > 0 ? w - last_status : 0);
            last_status = w;
        }
    }
    l->wall_end = iso_clock_now();
    if (l->o.status_line) { /* erased before the summary is printed under it */
        iso_logq_status(l->logq, "");
        (void)iso_logq_flush(l->logq, ISO_LOGQ_CLOSE_MS);
    }
    if (l->rt.rt_active) {
        /* The summary needs no real-time priority, nor does an idle worker;
         * the actuators' sender keeps its priority through the safe stop. */
        struct sched_param sp;
        memset(&sp, 0, sizeof sp);
        if (sched_setscheduler(0, SCHED_OTHER, &sp) != 0)
            iso_loop_say(l, "back to SCHED_OTHER: %s", strerror(errno));
        iso_err e;
        iso_err_clear(&e);
        if (l->solver && iso_solver_set_worker_priority(l->solver, 0, &e) != ISO_OK)
            iso_loop_say(l, "%s", e.msg);
        iso_err_clear(&e);
        if (l->hub && iso_dev_hub_set_priority(l->hub, 0, &e) != ISO_OK)
            iso_loop_say(l, "%s", e.msg);
    }
    return rc;
}
