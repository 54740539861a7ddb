/* tests/test_late_drag.c -- a fast drag through late ticks ends as it does
 * on time.
 *
 * A page of the live view drags the built-in cactus's top straight up at
 * one bounding-box diagonal a second (half the view's limit) for 0.5 s and
 * holds it: tests/streams/view_drag.isorec with every tick on time, and
 * view_drag_late.isorec, the same messages with ticks 1 to 6 periods apart
 * while it moves, as a loaded machine records them (both written by
 * tests/streams/make_streams.c). Each is replayed at --fast through the
 * loop of a scene like view_cactus.yaml (ABM PEC, restoration μ 1, τ 0.5).
 *
 *   (a) With restoration on, PEC and PECE: the late replay's largest edge
 *       strain is at most 1.5 times the on-time replay's, computed here,
 *       and on time PEC ends within 1.5 times PECE. Before a PEC step whose
 *       predictor missed ended with PECE's evaluation (iso_integrate.h), PEC
 *       ended at 916% late and 231% on time, PECE at 94% and 94%; now PEC
 *       ends at 94% and 94%. The bound is the issue's; the margin is wide.
 *   (b) Without restoration (the paper's method), no blow-up: late within
 *       2 times on time (measured 1.87 under PEC and PECE alike, 171%
 *       against 92%), PEC within 5% of PECE. What is left is the first-
 *       order error of a twist held over a tick: the history carries each
 *       jump of the handle's twist a fraction of a step late; on time the
 *       lag of the drag's start is undone at its stop, and a late tick's
 *       restart at the stop leaves it (docs/realtime.md, "Late ticks").
 *   (c) The late replays give the same bits twice.
 * No replay fails ("not positive definite"). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "iso_loop.h"
#include "replay_fast.h"
#include "testutil.h"

static void replay_hooked(const char *stream, const char *abm, int restore, iso_loop_summary *s,
                          void (*on_tick)(void *, const iso_loop_tick_info *), void *ctx)
{
    char path[1024], name[96], text[2048];
    snprintf(name, sizeof name, "late_drag_%s_%s_%s.yaml", stream, abm, restore ? "on" : "off");
    iso_test_tmp(path, sizeof path, name);
    snprintf(text, sizeof text,
             "name: view_drag\n"
             "mesh: {shape: cactus}\n"
             "devices:\n"
             "  - {name: hand, kind: replay, file: %s/%s.isorec}\n"
             "regions:\n"
             "  sel: builtin\n"
             "  handles:\n"
             "    - name: top\n"
             "      driver: {device: hand}\n"
             "solver: {omega: 0.333, restore: %s, assembly: cpu, refactor: adaptive,\n"
             "         worker_lag: 4}\n"
             "integrator: {abm: %s}\n"
             "tick_hz: 60\n",
             ISO_TEST_STREAMS, stream, restore ? "{mu: 1.0, tau: 0.5}" : "off", abm);
    iso_test_write(path, text, -1);
    char what[160];
    snprintf(what, sizeof what, "%s (%s, restoration %s)", stream, abm, restore ? "on" : "off");
    replay_fast_hooked(path, what, s, on_tick, ctx);
}

static void replay(const char *stream, const char *abm, int restore, iso_loop_summary *s)
{
    replay_hooked(stream, abm, restore, s, NULL, NULL);
}

typedef struct drag {
    iso_loop_summary late, late2, on;
} drag;

static void replay_both(const char *abm, int restore, drag *d)
{
    replay("view_drag_late", abm, restore, &d->late);
    replay("view_drag_late", abm, restore, &d->late2);
    replay("view_drag", abm, restore, &d->on);
    print_message("%-4s restoration %-3s: largest edge strain %6.1f%% late (%ld ticks, %ld "
                  "sub-steps beyond one a tick, %ld PEC steps ended PECE), %6.1f%% on time (%ld "
                  "ticks, %ld ended PECE)\n",
                  abm, restore ? "on" : "off", 100 * d->late.metrics.max_edge_strain, d->late.ticks,
                  d->late.substeps, d->late.integ.pec_misses, 100 * d->on.metrics.max_edge_strain,
                  d->on.ticks, d->on.integ.pec_misses);
    /* the recordings are what they say: the late one has late ticks */
    assert_true(d->late.ticks < d->on.ticks && d->late.substeps > 0);
    assert_true(d->on.substeps == 0);
    assert_true(d->late.checksum == d->late2.checksum);
    assert_true(d->late.integ.max_step_evaluations <= 2 && d->on.integ.max_step_evaluations <= 2);
}

static void a_fast_drag_through_late_ticks_ends_as_on_time(void **state)
{
    (void)state;
    drag pec, pece;
    replay_both("pec", 1, &pec);
    replay_both("pece", 1, &pece);
    assert_true(pec.late.metrics.max_edge_strain <= 1.5 * pec.on.metrics.max_edge_strain);
    assert_true(pece.late.metrics.max_edge_strain <= 1.5 * pece.on.metrics.max_edge_strain);
    assert_true(pec.on.metrics.max_edge_strain <= 1.5 * pece.on.metrics.max_edge_strain);
    assert_true(pec.late.integ.pec_misses > 0); /* the rule is what holds it */
    assert_true(pece.late.integ.pec_misses == 0);
}

static void without_restoration_a_late_drag_does_not_blow_up(void **state)
{
    (void)state;
    drag pec, pece;
    replay_both("pec", 0, &pec);
    replay_both("pece", 0, &pece);
    assert_true(pec.late.metrics.max_edge_strain <= 2.0 * pec.on.metrics.max_edge_strain);
    assert_true(pece.late.metrics.max_edge_strain <= 2.0 * pece.on.metrics.max_edge_strain);
    assert_true(pec.late.metrics.max_edge_strain <= 1.05 * pece.late.metrics.max_edge_strain);
}

/* (d) A late tick sheds work (iso_loop.h, "Sub-steps"): with restoration
 * on no tick takes more sub-steps than half the periods it covers (and
 * some late tick took fewer than its periods), without it no more than
 * its periods. And the tick's thread factors only where a bounded solve's
 * residual stayed above the guard (iso_solver_set_bounded): every other
 * factor came from the worker. */
typedef struct shed {
    double share;
    long over, shed, late;
} shed;

static void count_shed(void *ctx, const iso_loop_tick_info *t)
{
    shed *c = ctx;
    long periods = lround(t->dt_s * 60);
    if (periods <= 1)
        return;
    c->late++;
    c->over += t->substeps > (long)ceil(c->share * (double)periods - 1e-6);
    c->shed += t->substeps < periods;
}

static void a_late_tick_sheds_work(void **state)
{
    (void)state;
    for (int restore = 0; restore <= 1; restore++) {
        shed c = {restore ? ISO_LOOP_LATE_SHARE : 1.0, 0, 0, 0};
        iso_loop_summary s;
        replay_hooked("view_drag_late", "pec", restore, &s, count_shed, &c);
        print_message("restoration %-3s: %ld late ticks, %ld took fewer sub-steps than periods, "
                      "%ld over the share; %ld factorizations on the tick's thread (1 before "
                      "the clock, %ld for a residual above the guard), %ld from the worker, "
                      "%ld inexact solves (worst residual %.2g)\n",
                      restore ? "on" : "off", c.late, c.shed, c.over, s.solver.factorizations,
                      s.solver.refactors, s.solver.handovers, s.solver.inexact,
                      s.solver.inexact_res_max);
        assert_true(c.late > 0);
        assert_int_equal(c.over, 0);
        if (restore)
            assert_true(c.shed > 0);
        assert_int_equal(s.solver.factorizations, 1 + s.solver.refactors);
        assert_true(s.solver.handovers > 0);
        assert_true(s.solver.inexact_res_max <= ISO_SOLVER_BOUNDED_RES);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_fast_drag_through_late_ticks_ends_as_on_time),
        cmocka_unit_test(without_restoration_a_late_drag_does_not_blow_up),
        cmocka_unit_test(a_late_tick_sheds_work),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
