/* actuators/safety.c -- the rules that stop the actuators, in one place.
 *
 * Holds. Setpoints flow only while no hold stands. A hold begins on
 *   - the e-stop: iso_actuators_estop() or the e-stop probe, read every
 *     HOLD_POLL_US by the sender thread whatever the loop is doing;
 *   - the loop watchdog: no progress report (iso_actuators_alive, publish)
 *     for loop_timeout_ms, less STOP_GUARD_US;
 *   - safe_stop: the program's own stop.
 * A hold that begins sends SAFE at once to an MCU that obeys it, and stops
 * the SETPOINTS too, so a lost SAFE still ends in the MCU's own watchdog
 * brake 100 ms after the last setpoints arrived. When the cause ends, the
 * tick hold (ISO_ACT_HOLD_TICK) stays until the loop publishes a tick that
 * began after the end: re-arming (HELLO) never sends values computed before
 * a hold. The MCU's word that it is safe (FAULT, a heartbeat that is not
 * armed, HELLO(BOOT)) confirms a hold, and the sink says how long it took.
 *
 * A tick that began after the end. The sink cannot see when a tick began,
 * only when its publish came; the tick in progress when a hold began
 * publishes after the hold ends, with values computed before it. The loop
 * publishes from one thread, a tick after the publish before it, so the
 * publish that follows another publish made after the end is of a tick
 * that began after the end: the tick hold clears when the publish before
 * the latest came after the end (the second publish after it re-arms).
 *
 * A gap in the sender's own clock. The sender looks every HOLD_POLL_US;
 * when two looks lie further apart than the loop bound, this process did
 * not run (SIGSTOP, a suspended machine, a starved thread), nor did the
 * loop, the setpoints, or their watchdog: the MCU braked by its own
 * watchdog meanwhile, and on waking the loop's progress report may be
 * fresh before the sender looks (the tick thread ran first). So a gap is
 * a loop stall: counted, said, SAFE sent, and the tick hold stands from
 * the moment the sender woke, so that nothing computed before the gap
 * reaches the MCU after it. */
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#include "act_internal.h"
#include "iso_clock.h"

/* The loop watchdog stops setpoints this much before loop_timeout_ms: the
 * MCU brakes 100 ms after the last SETPOINTS *arrives* and checks every
 * 1 ms, and a frame takes ~2 ms on a 115200 baud UART. So the safe state
 * comes within loop_timeout_ms + 100 ms of the loop's last progress. */
#define STOP_GUARD_US 5000u
#define LOOP_TIMEOUT_MIN_MS 250 /* the default's floor: max(250, 5 ticks) */

/* Reads the safety options into a (defaults for NULL or zero fields). */
int iso_act__take_safety(iso_actuators *a, const iso_act_safety_opts *so, iso_err *err)
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

/* ------------------------------------------------------------------------ */
/* Safety: what stopped the streaming, and the MCU's word that it is safe     */
/* ------------------------------------------------------------------------ */

/* Streaming stopped at t0 because of `what`; the MCU's next safe report
 * confirms it (a later cause replaces an unconfirmed one). Sender thread. */
void iso_act__begin_break(iso_actuators *a, uint64_t t0, int cause, const char *what)
{
    a->await_safe = 1;
    a->break_us = t0;
    a->break_cause = cause;
    a->break_what = what;
}

/* The MCU says it is in its safe state (FAULT, a heartbeat that is not
 * armed, HELLO(BOOT)). Counts the transition, and confirms a break. On the
 * sender thread, from the host's callbacks. */
void iso_act__note_safe(iso_actuators *a, const char *how)
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
    /* A report read on waking from a gap (the watchdog brake of an MCU
     * that ran on while this process was stopped) precedes the gap's own
     * look: it re-arms nothing, so it says nothing of re-arming. */
    int woke = iso_act__gap_since_look(a);
    if (confirm)
        snprintf(line, sizeof line,
                 "actuators: the MCU reports its safe state (%s) %.1f ms after %s", how, ms,
                 a->break_what);
    else if (woke)
        return;
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
    iso_act__say(a, line);
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

/* The e-stop (the call or the probe), the loop watchdog, a gap in the
 * sender's clock and safe_stop, as hold bits, each edge said once; returns
 * the bits. A hold that ends leaves ISO_ACT_HOLD_TICK until the publish of
 * a tick begun after its end (prev_pub_us, the publish before the latest,
 * came after it), which re-arms with HELLO: the MCU never chases values
 * computed before the hold. */
/* The longest the sender's looks may lie apart: the loop bound, or the
 * default's floor without a loop watchdog. */
static uint64_t gap_bound_us(const iso_actuators *a)
{
    return a->loop_timeout_us ? a->loop_timeout_us : (uint64_t)LOOP_TIMEOUT_MIN_MS * 1000u;
}

int iso_act__gap_since_look(const iso_actuators *a)
{
    uint64_t now = iso_clock_us();
    return a->awake_us && now > a->awake_us && now - a->awake_us > gap_bound_us(a);
}

/* A gap in the sender's own looks longer than the bound: a stall of the
 * whole process. */
static unsigned note_gap(iso_actuators *a, uint64_t now, unsigned h)
{
    uint64_t last = a->awake_us;
    a->awake_us = now;
    uint64_t bound = gap_bound_us(a);
    if (!last || now <= last || now - last <= bound)
        return h;
    a->fresh_after_us = now;
    a->gap_now = 1;
    /* What the MCU said while this process slept is unknown, not silence:
     * its silence and the link's timeout count from now. */
    if (a->host.last_rx_us < now)
        a->host.last_rx_us = now;
    if (!(h & ISO_ACT_HOLD_LOOP)) {
        count_event(a, &a->st.loop_stalls);
        iso_act__begin_break(a, last, ISO_ACT_HOLD_LOOP, "the process stopped");
    }
    char line[320];
    snprintf(line, sizeof line,
             "actuators: STALLED: this process did not run for %.0f ms (stopped, suspended or "
             "starved; limit %.0f ms): setpoints stopped; %s; they resume with a tick computed "
             "after it",
             (double)(now - last) / 1000.0, (double)bound / 1000.0, brake_how(a));
    iso_act__say(a, line);
    return h | ISO_ACT_HOLD_LOOP | ISO_ACT_HOLD_TICK;
}

static unsigned update_holds(iso_actuators *a, uint64_t now, int stopped, uint64_t prev_pub_us)
{
    unsigned h = note_gap(a, now, a->hold);
    char line[320];
    int req = atomic_load(&a->estop_req) != 0;
    int es = req || (a->estop_probe && a->estop_probe(a->estop_ctx) != 0);
    if (es && !(h & ISO_ACT_HOLD_ESTOP)) {
        uint64_t t0 = req ? atomic_load(&a->estop_us) : now;
        if (t0 == 0 || t0 > now)
            t0 = now;
        h |= ISO_ACT_HOLD_ESTOP | ISO_ACT_HOLD_TICK;
        count_event(a, &a->st.estops);
        iso_act__begin_break(a, t0, ISO_ACT_HOLD_ESTOP, "the e-stop");
        snprintf(line, sizeof line, "actuators: E-STOP%s: setpoints stopped %.1f ms after it; %s",
                 req ? "" : " (probe)", (double)(now - t0) / 1000.0, brake_how(a));
        iso_act__say(a, line);
    } else if (!es && (h & ISO_ACT_HOLD_ESTOP)) {
        h &= ~(unsigned)ISO_ACT_HOLD_ESTOP;
        a->fresh_after_us = now;
        iso_act__say(
            a, "actuators: e-stop released: setpoints resume with the loop's next tick (HELLO "
               "re-arms the MCU where it stands)");
    }
    uint64_t p = atomic_load(&a->progress_us);
    if (a->loop_timeout_us && p) {
        int stalled = now > p && now - p + STOP_GUARD_US > a->loop_timeout_us;
        if (stalled && !(h & ISO_ACT_HOLD_LOOP)) {
            h |= ISO_ACT_HOLD_LOOP | ISO_ACT_HOLD_TICK;
            count_event(a, &a->st.loop_stalls);
            iso_act__begin_break(a, p, ISO_ACT_HOLD_LOOP, "the loop's last progress");
            snprintf(line, sizeof line,
                     "actuators: LOOP STALLED: no progress for %.0f ms (limit %d ms): setpoints "
                     "stopped; %s",
                     (double)(now - p) / 1000.0, a->loop_timeout_ms, brake_how(a));
            iso_act__say(a, line);
        } else if (!stalled && (h & ISO_ACT_HOLD_LOOP)) {
            h &= ~(unsigned)ISO_ACT_HOLD_LOOP;
            if (p > a->fresh_after_us)
                a->fresh_after_us = p;
            iso_act__say(a, "actuators: the loop progresses again: setpoints resume with a tick "
                            "it begins from now on");
        }
    } else if (h & ISO_ACT_HOLD_LOOP) {
        h &= ~(unsigned)ISO_ACT_HOLD_LOOP; /* a gap, with no loop watchdog to end it */
    }
    if (stopped && !(h & ISO_ACT_HOLD_STOP)) {
        h |= ISO_ACT_HOLD_STOP;
        iso_act__begin_break(a, now, ISO_ACT_HOLD_STOP, "the stop");
    }
    if ((h & ISO_ACT_HOLD_TICK) &&
        !(h & (ISO_ACT_HOLD_ESTOP | ISO_ACT_HOLD_LOOP | ISO_ACT_HOLD_STOP)) &&
        prev_pub_us >= a->fresh_after_us) {
        h &= ~(unsigned)ISO_ACT_HOLD_TICK;
        iso_fb_host_rehello(&a->host);
        iso_act__say(a, "actuators: re-arming the MCU (HELLO) for the loop's new tick");
    }
    a->hold = h;
    atomic_store(&a->holds, h);
    return h;
}

/* The holds now, from the shared state; a hold that begins sends SAFE at
 * once to an MCU that obeys it (the SETPOINTS stop as well, so a lost SAFE
 * still ends in the MCU's watchdog brake). */
unsigned iso_act__holds_now(iso_actuators *a)
{
    pthread_mutex_lock(&a->lock);
    int stopped = a->stopped;
    uint64_t prev_pub = a->prev_publish_us;
    pthread_mutex_unlock(&a->lock);
    unsigned before = a->hold;
    a->gap_now = 0;
    unsigned h = update_holds(a, iso_clock_us(), stopped, prev_pub);
    unsigned fresh = h & ~before;
    uint8_t cause = (fresh & ISO_ACT_HOLD_ESTOP)                ? ISO_FB_SAFE_ESTOP
                    : (fresh & ISO_ACT_HOLD_LOOP) || a->gap_now ? ISO_FB_SAFE_LOOP_STALL
                    : (fresh & ISO_ACT_HOLD_STOP)               ? ISO_FB_SAFE_STOP
                                                                : 0;
    /* refused without a word when the MCU offers no SAFE or the link is
     * down: brake_how's notice has said how the MCU gets safe then */
    if (cause && iso_fb_host_send_safe(&a->host, cause, NULL) == ISO_OK)
        count_event(a, &a->st.safe_requests);
    return h;
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
