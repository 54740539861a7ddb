/* tests/test_stepper.c -- the real-time stepper (iso_integrate.h): one step
 * per tick with a twist held over each tick.
 *
 * Properties: (1) with the same twist every tick it follows the same screw
 * path as iso_integrate with the same start (ISO_INTEGRATE_START_ADAMS) at
 * the same fixed step: the same Adams steps with identical coefficients;
 * they differ only in how the handle pose is formed (composed per tick vs
 * exp(tξ) at once), a rounding-level difference; (2) handle vertices sit
 * exactly at the composed pose; (3) a restart rebuilds the history at
 * orders 1, 2, 3 over three steps, never more than two evaluations a step,
 * and (4) the same input gives bit-identical output; (5) a zero twist leaves
 * the mesh at rest; (6) PEC mode is third order at one evaluation a step;
 * (7) the path stays third order with restarts and twist jumps on it, under
 * PEC and PECE; (8) PEC's smaller stability interval is covered by its
 * restoration clamp; (9) PCG's iterations a step are capped, and past the
 * cap the step falls back to a fresh factorization and a direct solve, with
 * the same answer as a direct solve every evaluation; (10) with bounded
 * solves and a worker, the same capped path never factors on the
 * evaluating thread after its first factor: its inexact solves end below
 * ISO_SOLVER_BOUNDED_RES, each step's iterations stay within the cap, the
 * bits repeat, and the path stays within the integrator's own error of a
 * direct solve every evaluation. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "iso_integrate.h"
#include "iso_metrics.h"
#include "iso_shapes.h"
#include "testutil.h"

typedef struct fixture {
    iso_shape shape;
    iso_mesh *m;
    iso_regions r;
    iso_solver *s;
    iso_twist xi; /* the shape's handle motion, log M */
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_shape_init(&f->shape, "cylinder", 10, &err), ISO_OK);
    assert_int_equal(iso_mesh_create(f->shape.nv, f->shape.x, f->shape.nt, f->shape.tri, "cylinder",
                                     &f->m, &err),
                     ISO_OK);
    assert_int_equal(iso_shape_regions(&f->shape, &f->r, &err), ISO_OK);
    assert_int_equal(iso_solver_create(f->m, &f->r, NULL, &f->s, &err), ISO_OK);
    assert_int_equal(iso_twist_from_matrix(f->shape.M, &f->xi, &err), ISO_OK);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    iso_solver_destroy(f->s);
    iso_regions_deinit(&f->r);
    iso_mesh_destroy(f->m);
    iso_shape_deinit(&f->shape);
    free(f);
    return 0;
}

static double *rest_copy(const fixture *f)
{
    size_t n = 3 * (size_t)iso_mesh_vertex_count(f->m);
    double *x = malloc(n * sizeof *x);
    memcpy(x, iso_mesh_positions(f->m), n * sizeof *x);
    return x;
}

static void run_mode(fixture *f, iso_solver *s, iso_abm_mode mode, double kappa, double *x,
                     int ticks, double h, const iso_twist *tw, int restart_at,
                     iso_integrate_stats *stats)
{
    iso_err err;
    iso_err_clear(&err);
    iso_stepper *st = NULL;
    assert_int_equal(iso_stepper_create(s, f->m, &f->r, x, &st, &err), ISO_OK);
    assert_int_equal(iso_stepper_configure(st, mode, kappa, &err), ISO_OK);
    for (int k = 0; k < ticks; k++)
        if (iso_stepper_step(st, h, tw, k == restart_at, &err) != ISO_OK)
            fail_msg("tick %d: %s", k, err.msg);
    iso_stepper_stats(st, stats);
    assert_true(fabs(iso_stepper_time(st) - ticks * h) <= 1e-12);
    iso_stepper_destroy(st);
}

static void run_ticks(fixture *f, double *x, int ticks, double h, const iso_twist *tw,
                      int restart_at, iso_integrate_stats *stats)
{
    run_mode(f, f->s, ISO_ABM_PECE, -1, x, ticks, h, tw, restart_at, stats);
}

/* (1) and (2) */
static void constant_twist_matches_offline_integration(void **state)
{
    fixture *f = *state;
    const int N = 12;
    double *xs = rest_copy(f), *xi = rest_copy(f);
    iso_integrate_stats sst, ist;
    run_ticks(f, xs, N, 1.0 / N, &f->xi, -1, &sst);
    assert_int_equal(sst.steps, N);
    assert_int_equal(sst.rk4_steps, 0);
    assert_int_equal(sst.low_order_steps, 2);
    assert_int_equal(sst.evaluations, 2 * N); /* f(0) and f(x_p); then PECE's two */
    assert_int_equal(sst.max_step_evaluations, 2);

    iso_screw_path sp = {&f->xi, 1};
    iso_path path = iso_screw_path_make(&sp);
    iso_integrate_opts o;
    iso_integrate_opts_default(&o);
    o.steps = N;
    o.start = ISO_INTEGRATE_START_ADAMS;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_integrate(f->s, f->m, &f->r, &path, &o, xi, &ist, &err), ISO_OK);
    assert_int_equal(ist.evaluations, sst.evaluations);
    assert_int_equal(ist.low_order_steps, 2);
    int nv = iso_mesh_vertex_count(f->m);
    double diag = iso_mesh_bbox_diagonal(f->m);
    double d = iso_test_max_abs_diff(xs, xi, 3 * (size_t)nv) / diag;
    print_message("stepper vs iso_integrate, %d ticks: max difference %.3g of the diagonal\n", N,
                  d);
    /* Rounding only: the poses are formed differently (12 composed
     * exponentials vs one), which perturbs handle positions by ~1e-15 and
     * the free vertices by a condition-number multiple of that. */
    assert_true(d < 1e-9);
    /* Handle vertices: exactly M applied to the rest pose, up to the
     * composition's rounding. */
    const double *x0 = iso_mesh_positions(f->m);
    const double *M = f->shape.M;
    for (int i = 0; i < nv; i++)
        if (f->r.kind[i] == ISO_HANDLE)
            for (int a = 0; a < 3; a++) {
                double y = M[4 * a] * x0[3 * i] + M[4 * a + 1] * x0[3 * i + 1] +
                           M[4 * a + 2] * x0[3 * i + 2] + M[4 * a + 3];
                assert_true(fabs(y - xs[3 * i + a]) <= 1e-9 * diag);
            }
    free(xs);
    free(xi);
}

/* (3) and (4): orders after the first step and after a restart at tick 5,
 * under both modes; every step at most two evaluations. */
static void restart_rebuilds_the_order_and_replays_bit_identically(void **state)
{
    fixture *f = *state;
    static const int order[8] = {1, 2, 3, 3, 3, 1, 2, 3};
    /* PECE: two a step throughout (the restart's f(x_n) and f(x_p), its
     * step ending PEC); PEC: two on a restart's step, else one */
    static const int evals[2][8] = {{2, 2, 2, 2, 2, 2, 2, 2}, {2, 1, 1, 1, 1, 2, 1, 1}};
    size_t n = 3 * (size_t)iso_mesh_vertex_count(f->m);
    for (int mode = 0; mode < 2; mode++) {
        double *x[2] = {rest_copy(f), rest_copy(f)};
        for (int run = 0; run < 2; run++) {
            iso_err err;
            iso_err_clear(&err);
            iso_stepper *st = NULL;
            assert_int_equal(iso_stepper_create(f->s, f->m, &f->r, x[run], &st, &err), ISO_OK);
            assert_int_equal(iso_stepper_configure(st, (iso_abm_mode)mode, -1, &err), ISO_OK);
            long before = 0;
            for (int k = 0; k < 8; k++) {
                assert_int_equal(iso_stepper_step(st, 0.05, &f->xi, k == 5, &err), ISO_OK);
                iso_integrate_stats s;
                iso_stepper_stats(st, &s);
                if (s.adams_order != order[k] || s.evaluations - before != evals[mode][k])
                    fail_msg("%s tick %d: order %d (want %d), %ld evaluations (want %d)",
                             iso_abm_mode_name((iso_abm_mode)mode), k, s.adams_order, order[k],
                             s.evaluations - before, evals[mode][k]);
                before = s.evaluations;
                if (k == 7) {
                    assert_int_equal(s.low_order_steps, 4); /* ticks 0, 1 and 5, 6 */
                    assert_int_equal(s.rk4_steps, 0);
                    assert_int_equal(s.max_step_evaluations, 2);
                }
            }
            iso_stepper_destroy(st);
        }
        assert_memory_equal(x[0], x[1], n * sizeof(double));
        free(x[0]);
        free(x[1]);
    }
}

/* (5) */
static void zero_twist_stays_at_rest(void **state)
{
    fixture *f = *state;
    double *x = rest_copy(f);
    iso_twist zero;
    memset(&zero, 0, sizeof zero);
    iso_integrate_stats st;
    run_ticks(f, x, 5, 1.0 / 60, &zero, -1, &st);
    size_t n = 3 * (size_t)iso_mesh_vertex_count(f->m);
    assert_true(iso_test_max_abs_diff(x, iso_mesh_positions(f->m), n) == 0.0);
    free(x);
}

/* (6) PEC: one evaluation per ABM step and still third order. The error
 * against a PECE run at 16x the steps (its own error ~4000x smaller) falls
 * by 2^3 per halving; 6..10 allows for the low-order start and the
 * not-yet-asymptotic first level. */
static void pec_is_third_order_at_one_evaluation_a_step(void **state)
{
    fixture *f = *state;
    int nv = iso_mesh_vertex_count(f->m);
    double diag = iso_mesh_bbox_diagonal(f->m);
    double *ref = rest_copy(f);
    iso_integrate_stats st;
    run_mode(f, f->s, ISO_ABM_PECE, -1, ref, 384, 1.0 / 384, &f->xi, -1, &st);
    double e[3];
    for (int k = 0; k < 3; k++) {
        int n = 24 << k;
        double *x = rest_copy(f);
        run_mode(f, f->s, ISO_ABM_PEC, -1, x, n, 1.0 / n, &f->xi, -1, &st);
        assert_int_equal(st.evaluations, 2 + (n - 1) * 1);
        e[k] = iso_test_max_abs_diff(x, ref, 3 * (size_t)nv) / diag;
        free(x);
    }
    print_message("PEC errors at 24, 48, 96 steps: %.3g %.3g %.3g, ratios %.2f %.2f\n", e[0], e[1],
                  e[2], e[0] / e[1], e[1] / e[2]);
    assert_true(e[0] / e[1] > 6 && e[0] / e[1] < 10);
    assert_true(e[1] / e[2] > 6 && e[1] / e[2] < 10);
    free(ref);
}

/* The path of (7): twist ξ over [0, 0.4), then a jump to a twist about
 * another axis over [0.4, 0.7), then −ξ/2, each jump restarting the
 * history, at n ticks over [0, 1] (n a multiple of 10, so the jumps fall on
 * ticks). */
static void run_jumps(fixture *f, iso_abm_mode mode, int n, double *x, iso_integrate_stats *stats)
{
    iso_twist tw[3] = {f->xi, f->xi, f->xi};
    for (int a = 0; a < 3; a++) {
        tw[1].v[a] = 0.5 * f->xi.w[(a + 1) % 3];
        tw[1].w[a] = 0.7 * f->xi.w[(a + 2) % 3] + 0.3 * f->xi.w[a];
        tw[2].v[a] = -0.5 * f->xi.v[a];
        tw[2].w[a] = -0.5 * f->xi.w[a];
    }
    iso_err err;
    iso_err_clear(&err);
    iso_stepper *st = NULL;
    assert_int_equal(iso_stepper_create(f->s, f->m, &f->r, x, &st, &err), ISO_OK);
    assert_int_equal(iso_stepper_configure(st, mode, -1, &err), ISO_OK);
    int prev = 0;
    for (int k = 0; k < n; k++) {
        int seg = 10 * k < 4 * n ? 0 : 10 * k < 7 * n ? 1 : 2;
        if (iso_stepper_step(st, 1.0 / n, &tw[seg], seg != prev, &err) != ISO_OK)
            fail_msg("tick %d of %d: %s", k, n, err.msg);
        prev = seg;
    }
    iso_stepper_stats(st, stats);
    iso_stepper_destroy(st);
}

/* (7) Restarts cost accuracy only at the method's order: each leaves a
 * fixed number of O(h³) local errors (iso_integrate.h), so with a fixed
 * number of them on the path the error still falls 8x per halving. The
 * reference: PECE at 16x the finest ticks, the same jumps. */
static void restarts_keep_third_order(void **state)
{
    fixture *f = *state;
    int nv = iso_mesh_vertex_count(f->m);
    double diag = iso_mesh_bbox_diagonal(f->m);
    iso_integrate_stats st;
    double *ref = rest_copy(f);
    run_jumps(f, ISO_ABM_PECE, 640, ref, &st);
    for (int mode = 0; mode < 2; mode++) {
        double e[3];
        for (int k = 0; k < 3; k++) {
            int n = 40 << k;
            double *x = rest_copy(f);
            run_jumps(f, (iso_abm_mode)mode, n, x, &st);
            assert_int_equal(st.low_order_steps, 6); /* two after each of the three (re)starts */
            assert_int_equal(st.max_step_evaluations, 2);
            assert_int_equal(st.rk4_steps, 0);
            e[k] = iso_test_max_abs_diff(x, ref, 3 * (size_t)nv) / diag;
            free(x);
        }
        print_message("%s with two twist jumps, errors at 40, 80, 160 ticks: %.3g %.3g %.3g, "
                      "ratios %.2f %.2f (order %.2f %.2f)\n",
                      iso_abm_mode_name((iso_abm_mode)mode), e[0], e[1], e[2], e[0] / e[1],
                      e[1] / e[2], log2(e[0] / e[1]), log2(e[1] / e[2]));
        assert_true(e[1] / e[2] > 6 && e[1] / e[2] < 10);
        assert_true(e[0] / e[1] > 5 && e[0] / e[1] < 11);
    }
    free(ref);
}

/* (8) PEC's stability interval (h/τ < 0.287 against PECE's 1.73) is what
 * its κ default of 6 is for: a stiff restoration term (μ 10, τ far below a
 * step) stays bounded with it, as PECE does at the same τ_eff, and pure PEC
 * (no predictor-miss rule, pec_tol 0) blows up at PECE's κ = 1. With the
 * rule (the default), the steps whose predictor misses end as PECE's do, and
 * PEC at κ 1 stays bounded as well. (The clamp's price: at a given step PEC
 * restores 6x slower.) */
static void pec_needs_its_own_restoration_clamp(void **state)
{
    fixture *f = *state;
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.restore_mu = 10;
    so.restore_tau = 1e-4;
    iso_solver *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_solver_create(f->m, &f->r, &so, &s, &err), ISO_OK);
    double strain[4];
    long misses[4];
    double kappa[4] = {-1, 1.0, ISO_INTEGRATE_RESTORE_KAPPA_PEC, 1.0};
    iso_abm_mode mode[4] = {ISO_ABM_PEC, ISO_ABM_PEC, ISO_ABM_PECE, ISO_ABM_PEC};
    double pec_tol[4] = {0, 0, 0, ISO_STEPPER_PEC_TOL};
    for (int k = 0; k < 4; k++) {
        double *x = rest_copy(f);
        iso_stepper *st = NULL;
        assert_int_equal(iso_stepper_create(s, f->m, &f->r, x, &st, &err), ISO_OK);
        assert_int_equal(iso_stepper_configure(st, mode[k], kappa[k], &err), ISO_OK);
        assert_int_equal(iso_stepper_set_pec_tol(st, -1, &err), ISO_EINVAL);
        assert_int_equal(iso_stepper_set_pec_tol(st, pec_tol[k], &err), ISO_OK);
        int rc = ISO_OK;
        for (int t = 0; t < 40 && rc == ISO_OK; t++)
            rc = iso_stepper_step(st, 1.0 / 40, &f->xi, 0, &err);
        iso_metrics mt;
        iso_metrics_compute(f->m, iso_mesh_positions(f->m), x, &mt);
        /* a blow-up may end in a degenerate triangle: infinite strain */
        strain[k] = rc == ISO_OK ? mt.max_edge_strain : INFINITY;
        iso_integrate_stats is;
        iso_stepper_stats(st, &is);
        misses[k] = is.pec_misses;
        iso_stepper_destroy(st);
        free(x);
    }
    print_message("restoration: max edge strain %.3g pure PEC at its default kappa %g, %.3g pure "
                  "PEC at kappa 1, %.3g PECE at kappa %g, %.3g PEC at kappa 1 with the miss rule "
                  "(%ld of 40 steps ended PECE)\n",
                  strain[0], ISO_INTEGRATE_RESTORE_KAPPA_PEC, strain[1], strain[2],
                  ISO_INTEGRATE_RESTORE_KAPPA_PEC, strain[3], misses[3]);
    assert_true(strain[0] < 1.5 * strain[2]);
    assert_true(!(strain[1] < 1.0)); /* unbounded growth */
    assert_true(strain[3] < 1.5 * strain[2]);
    assert_true(misses[0] == 0 && misses[1] == 0 && misses[3] > 0);
    iso_solver_destroy(s);
}

/* (9) A cap of 3 iterations a step with a tolerance CG cannot always meet in 3
 * (1e-12, no share of the step's error): steps fall back to a fresh
 * factorization and a direct solve. Each step spends at most the cap before
 * its first factorization and at most the cap again after each (the fresh
 * factor refills the budget), and the path is a direct-solve path's to the
 * solves' rounding. */
static void pcg_cap_falls_back_to_a_direct_solve(void **state)
{
    fixture *f = *state;
    enum { CAP = 3, TICKS = 16 };
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.refactor = ISO_REFACTOR_ADAPTIVE;
    so.cg_tol = 1e-12;
    so.cg_max_iter = CAP;
    iso_err err;
    iso_err_clear(&err);
    iso_solver *s = NULL;
    assert_int_equal(iso_solver_create(f->m, &f->r, &so, &s, &err), ISO_OK);
    double *x = rest_copy(f), *ref = rest_copy(f);
    iso_integrate_stats direct;
    run_mode(f, f->s, ISO_ABM_PECE, -1, ref, TICKS, 1.0 / TICKS, &f->xi, -1, &direct);
    iso_stepper *st = NULL;
    assert_int_equal(iso_stepper_create(s, f->m, &f->r, x, &st, &err), ISO_OK);
    assert_int_equal(iso_stepper_set_cg_share(st, 0, &err), ISO_OK);
    long reused = 0;
    for (int k = 0; k < TICKS; k++) {
        iso_solver_stats a, b;
        iso_solver_get_stats(s, &a);
        assert_int_equal(iso_stepper_step(st, 1.0 / TICKS, &f->xi, 0, &err), ISO_OK);
        iso_solver_get_stats(s, &b);
        long iters = b.cg_iterations - a.cg_iterations;
        long facts = b.factorizations - a.factorizations;
        reused += (b.evaluations - a.evaluations) - facts;
        if (iters > CAP * (1 + facts))
            fail_msg("tick %d: %ld PCG iterations with %ld factorizations, cap %d", k, iters, facts,
                     CAP);
    }
    iso_solver_stats ss;
    iso_solver_get_stats(s, &ss);
    iso_integrate_stats sst;
    iso_stepper_stats(st, &sst);
    int nv = iso_mesh_vertex_count(f->m);
    double d = iso_test_max_abs_diff(x, ref, 3 * (size_t)nv) / iso_mesh_bbox_diagonal(f->m);
    print_message("cap %d: %ld evaluations, %ld factorizations (%ld forced by the cap), %ld "
                  "served by PCG, %ld iterations; against a direct solve each time %.3g of the "
                  "diagonal\n",
                  CAP, ss.evaluations, ss.factorizations, ss.cg_capped, reused, ss.cg_iterations,
                  d);
    assert_true(ss.cg_capped > 0);
    assert_true(ss.refactors >= ss.cg_capped);
    assert_true(reused > 0); /* PCG did serve some solves within the cap */
    assert_true(d < 1e-9);
    iso_stepper_destroy(st);
    iso_solver_destroy(s);
    free(x);
    free(ref);
}

/* (10) The loop's rule (iso_solver_set_bounded). The cap and tolerance of
 * (9), over 60 ticks (the shape's whole bend in a second at 60 Hz), force
 * a factorization on the evaluating thread nearly every tick without the
 * rule, worker or not (lag 4 here). Bounded, only the first evaluation (no
 * factor yet) factors there; the error the inexact solves add is compared
 * with the integrator's own, the same ticks against a direct-solve path at
 * 8x the ticks (measured: 5e-8 of the diagonal against 8e-6). The same
 * bend in 4 ticks, far faster than a hand moves, leaves a stale factor
 * residuals above ISO_SOLVER_BOUNDED_RES, and those solves factor (in 16
 * or 8 ticks PCG's start from the remembered solutions keeps every
 * residual below it). */
typedef struct bounded_run {
    double *x;
    iso_solver_stats ss;
    iso_integrate_stats is;
} bounded_run;

static bounded_run run_bounded(fixture *f, int bounded, int ticks)
{
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.refactor = ISO_REFACTOR_ADAPTIVE;
    so.cg_tol = 1e-12;
    so.cg_max_iter = 3;
    so.worker_lag = 4;
    iso_err err;
    iso_err_clear(&err);
    iso_solver *s = NULL;
    assert_int_equal(iso_solver_create(f->m, &f->r, &so, &s, &err), ISO_OK);
    iso_solver_set_bounded(s, bounded);
    bounded_run r = {rest_copy(f), {0}, {0}};
    iso_stepper *st = NULL;
    assert_int_equal(iso_stepper_create(s, f->m, &f->r, r.x, &st, &err), ISO_OK);
    assert_int_equal(iso_stepper_set_cg_share(st, 0, &err), ISO_OK);
    for (int k = 0; k < ticks; k++)
        assert_int_equal(iso_stepper_step(st, 1.0 / ticks, &f->xi, 0, &err), ISO_OK);
    iso_solver_get_stats(s, &r.ss);
    iso_stepper_stats(st, &r.is);
    iso_stepper_destroy(st);
    iso_solver_destroy(s);
    return r;
}

static void bounded_solves_never_factor_on_the_tick(void **state)
{
    fixture *f = *state;
    enum { TICKS = 60, FAST = 4 };
    size_t n = 3 * (size_t)iso_mesh_vertex_count(f->m);
    double diag = iso_mesh_bbox_diagonal(f->m);
    double *direct = rest_copy(f), *fine = rest_copy(f);
    iso_integrate_stats ds;
    run_mode(f, f->s, ISO_ABM_PECE, -1, direct, TICKS, 1.0 / TICKS, &f->xi, -1, &ds);
    run_mode(f, f->s, ISO_ABM_PECE, -1, fine, 8 * TICKS, 1.0 / (8 * TICKS), &f->xi, -1, &ds);
    double own = iso_test_max_abs_diff(direct, fine, n) / diag;

    bounded_run off = run_bounded(f, 0, TICKS), on = run_bounded(f, 1, TICKS);
    bounded_run again = run_bounded(f, 1, TICKS), fast = run_bounded(f, 1, FAST);
    double dev = iso_test_max_abs_diff(on.x, direct, n) / diag;
    print_message("%d ticks: unbounded %ld factorizations on the evaluating thread; bounded %ld "
                  "(%ld inexact solves, worst relative residual %.2g, at most %ld iterations a "
                  "step), %.3g of the diagonal from a direct solve each time against the "
                  "integrator's own error %.3g; in %d ticks %ld factorizations, %ld forced by a "
                  "residual above %g\n",
                  TICKS, off.ss.factorizations, on.ss.factorizations, on.ss.inexact,
                  on.ss.inexact_res_max, on.is.max_step_cg_iterations, dev, own, FAST,
                  fast.ss.factorizations, fast.ss.refactors, ISO_SOLVER_BOUNDED_RES);
    assert_true(off.ss.factorizations > TICKS / 2); /* the path does defeat the stale factor */
    assert_int_equal(on.ss.factorizations, 1);
    assert_true(on.ss.inexact > 0 && on.ss.inexact_res_max <= ISO_SOLVER_BOUNDED_RES);
    assert_true(on.is.max_step_cg_iterations <= 3 + ISO_SOLVER_BOUNDED_MIN_ITERS);
    assert_memory_equal(on.x, again.x, n * sizeof *on.x);
    assert_true(dev < 0.1 * own);
    assert_true(fast.ss.refactors > 0 && fast.ss.factorizations == 1 + fast.ss.refactors);
    assert_true(fast.ss.inexact_res_max <= ISO_SOLVER_BOUNDED_RES);
    free(off.x);
    free(on.x);
    free(again.x);
    free(fast.x);
    free(direct);
    free(fine);
}

static void bad_step_is_refused(void **state)
{
    fixture *f = *state;
    double *x = rest_copy(f);
    iso_err err;
    iso_err_clear(&err);
    iso_stepper *st = NULL;
    assert_int_equal(iso_stepper_create(f->s, f->m, &f->r, x, &st, &err), ISO_OK);
    assert_int_equal(iso_stepper_step(st, 0.0, &f->xi, 0, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "positive"));
    iso_err_clear(&err);
    assert_int_equal(iso_stepper_set_cg_share(st, -0.1, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "cg_share"));
    iso_stepper_destroy(st);
    free(x);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(constant_twist_matches_offline_integration),
        cmocka_unit_test(restart_rebuilds_the_order_and_replays_bit_identically),
        cmocka_unit_test(zero_twist_stays_at_rest),
        cmocka_unit_test(pec_is_third_order_at_one_evaluation_a_step),
        cmocka_unit_test(restarts_keep_third_order),
        cmocka_unit_test(pec_needs_its_own_restoration_clamp),
        cmocka_unit_test(pcg_cap_falls_back_to_a_direct_solve),
        cmocka_unit_test(bounded_solves_never_factor_on_the_tick),
        cmocka_unit_test(bad_step_is_refused),
    };
    return cmocka_run_group_tests_name("stepper", t, setup, teardown);
}
