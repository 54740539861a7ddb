/* tests/test_long_session.c -- a long interactive session, scripted: the
 * built-in cylinder bent to 60° and back twenty times, integrated with a
 * constant step, with and without isometry restoration (docs/method.md).
 *
 * The handle path is θ(t) = θmax sin²(π t), t ∈ [0, 20]: one cycle per
 * time unit, back at the rest pose at every integer t. The paper's method
 * minimises the rate of distortion and never looks back at the rest
 * metric, so the error left at the rest pose accumulates from cycle to
 * cycle; restoration pulls every edge back to its rest length with time
 * constant τ, so it stays bounded.
 *
 * Mapping of τ: offline τ is in path time, here a fraction of one cycle;
 * τ = 0.05 is 1/20 of a cycle, i.e. 0.1 s in a real-time session where the
 * user's out-and-back takes 2 s.
 *
 * Measured (resolution 12, 16 steps per cycle, so h = 1/16 and τ_eff =
 * max(τ, h) = 0.0625): at the rest pose the paper's method goes 3.7e-4 ->
 * 0.157 (426x: the drift is mostly the constant step's truncation error,
 * which it never corrects; with 20 steps per cycle it is 3.6e-4 -> 5.0e-3,
 * 13.7x); restored 1.48e-2 -> 1.29e-2 (0.87x). At 60°: 0.981 -> 1.11
 * against 0.158 (first cycle) -> 5.4e-3.
 *
 * Writes long_session.dat (t, metricErr without, metricErr with, θ in
 * degrees) and, when gnuplot is installed, long_session.png into the test's
 * tmp folder (ISO_TEST_TMP). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_integrate.h"
#include "iso_metrics.h"
#include "iso_shapes.h"
#include "testutil.h"

#define ISO_PI 3.14159265358979323846
#define CYCLES 20
#define STEPS_PER_CYCLE 16
#define THETA_MAX_DEG 60.0
#define RESOLUTION 12 /* vertices around the cylinder: 312 vertices */
#define MU 1.0
#define TAU 0.05

typedef struct bend_path {
    iso_twist xi; /* the twist of the unit parameter: exp(1·xi) is θ = 120° */
    double scale; /* θmax / 120° */
} bend_path;

/* Pose exp(s(t) ξ), s = scale sin²(π t); world twist s'(t) ξ. */
static int bend_eval(void *ctx, int handle, double t, iso_pose *pose, iso_twist *tw)
{
    const bend_path *bp = ctx;
    (void)handle;
    double s = bp->scale * sin(ISO_PI * t) * sin(ISO_PI * t);
    double ds = bp->scale * ISO_PI * sin(2 * ISO_PI * t);
    iso_twist_exp(&bp->xi, s, pose);
    for (int a = 0; a < 3; a++) {
        tw->w[a] = ds * bp->xi.w[a];
        tw->v[a] = ds * bp->xi.v[a];
    }
    return 0;
}

typedef struct sampler {
    const iso_mesh *m;
    const double *x; /* the integrator's state array: current during progress */
    double *err;     /* per step */
    int n;
} sampler;

static void sample(void *ctx, double t, int steps, long evaluations)
{
    sampler *sm = ctx;
    (void)t;
    (void)evaluations;
    iso_metrics q;
    iso_metrics_compute(sm->m, iso_mesh_positions(sm->m), sm->x, &q);
    if (steps >= 1 && steps <= sm->n)
        sm->err[steps - 1] = q.metric_err;
}

static void run_session(const iso_mesh *m, const iso_regions *r, const bend_path *bp, double mu,
                        double *err)
{
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.restore_mu = mu;
    so.restore_tau = mu > 0 ? TAU : 0.0;
    iso_solver *s = NULL;
    iso_err e;
    iso_err_clear(&e);
    if (iso_solver_create(m, r, &so, &s, &e) != ISO_OK)
        fail_msg("iso_solver_create: %s", e.msg);
    int nv = iso_mesh_vertex_count(m);
    double *x = malloc(3 * (size_t)nv * sizeof *x);
    assert_non_null(x);
    memcpy(x, iso_mesh_positions(m), 3 * (size_t)nv * sizeof *x);
    sampler sm = {m, x, err, CYCLES * STEPS_PER_CYCLE};
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.t0 = 0;
    io.t1 = CYCLES;
    io.steps = CYCLES * STEPS_PER_CYCLE;
    io.progress = sample;
    io.progress_ctx = &sm;
    iso_path path = {bend_eval, (void *)bp};
    iso_integrate_stats st;
    if (iso_integrate(s, m, r, &path, &io, x, &st, &e) != ISO_OK)
        fail_msg("iso_integrate (mu %g): %s", mu, e.msg);
    assert_int_equal(st.steps, io.steps);
    iso_solver_destroy(s);
    free(x);
}

static int have_gnuplot(void)
{
    return system("command -v gnuplot >/dev/null 2>&1") == 0;
}

static void write_plot(const char *dat, const char *png)
{
    char gp[512], cmd[1200];
    iso_test_tmp(gp, sizeof gp, "long_session.gp");
    FILE *f = fopen(gp, "w");
    assert_non_null(f);
    fprintf(f,
            "set terminal pngcairo size 1000,560 font 'Sans,11'\n"
            "set output '%s'\n"
            "set title 'Long session: cylinder bent to %.0f deg and back %d times "
            "(%d steps per cycle, ABM3, omega = 1/3)'\n"
            "set xlabel 'time t (cycles; back at the rest pose at every integer t)'\n"
            "set ylabel 'metricErr = sum over edges (|e| - L_e)^2'\n"
            "set logscale y\n"
            "set format y '10^{%%L}'\n"
            "set grid\n"
            "set key bottom right box opaque\n"
            "set xrange [0:%d]\n"
            "plot '%s' using 1:2 with lines lw 2 lc rgb '#c0392b' title "
            "'paper''s method (--restore off)', \\\n"
            "     '%s' using 1:3 with lines lw 2 lc rgb '#2471a3' title "
            "'restored (mu = %g, tau = %g cycle)'\n",
            png, THETA_MAX_DEG, CYCLES, STEPS_PER_CYCLE, CYCLES, dat, dat, MU, TAU);
    fclose(f);
    snprintf(cmd, sizeof cmd, "gnuplot '%s'", gp);
    assert_int_equal(system(cmd), 0);
}

static void restoration_keeps_a_long_session_bounded(void **state)
{
    (void)state;
    iso_shape sh;
    iso_err e;
    iso_err_clear(&e);
    if (iso_shape_init(&sh, "cylinder", RESOLUTION, &e) != ISO_OK)
        fail_msg("%s", e.msg);
    iso_mesh *m = NULL;
    iso_regions r;
    assert_int_equal(iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, sh.name, &m, &e), ISO_OK);
    assert_int_equal(iso_shape_regions(&sh, &r, &e), ISO_OK);
    bend_path bp;
    assert_int_equal(iso_twist_from_matrix(sh.M, &bp.xi, &e), ISO_OK);
    bp.scale = THETA_MAX_DEG / 120.0;

    int n = CYCLES * STEPS_PER_CYCLE;
    double *off = calloc((size_t)n, sizeof *off), *on = calloc((size_t)n, sizeof *on);
    assert_true(off && on);
    run_session(m, &r, &bp, 0.0, off);
    run_session(m, &r, &bp, MU, on);

    char dat[512], png[512];
    iso_test_tmp(dat, sizeof dat, "long_session.dat");
    iso_test_tmp(png, sizeof png, "long_session.png");
    FILE *f = fopen(dat, "w");
    assert_non_null(f);
    fprintf(f, "# t metricErr_off metricErr_restored(mu=%g,tau=%g) theta_deg\n", MU, TAU);
    for (int k = 0; k < n; k++) {
        double t = (double)(k + 1) / STEPS_PER_CYCLE;
        fprintf(f, "%.4f %.6e %.6e %.3f\n", t, off[k], on[k],
                THETA_MAX_DEG * sin(ISO_PI * t) * sin(ISO_PI * t));
    }
    fclose(f);

    /* At the rest pose (end of each cycle) and the peak of each cycle. */
    double rest_off[CYCLES], rest_on[CYCLES], peak_off[CYCLES], peak_on[CYCLES];
    for (int c = 0; c < CYCLES; c++) {
        rest_off[c] = off[(c + 1) * STEPS_PER_CYCLE - 1];
        rest_on[c] = on[(c + 1) * STEPS_PER_CYCLE - 1];
        peak_off[c] = off[c * STEPS_PER_CYCLE + STEPS_PER_CYCLE / 2 - 1];
        peak_on[c] = on[c * STEPS_PER_CYCLE + STEPS_PER_CYCLE / 2 - 1];
    }
    for (int c = 0; c < CYCLES - 1; c += (c < 4 ? 1 : 5))
        print_message("cycle %2d: at rest off %.3e on %.3e; at 60 deg off %.3e on %.3e\n", c + 1,
                      rest_off[c], rest_on[c], peak_off[c], peak_on[c]);
    int last = CYCLES - 1;
    print_message("cycle %2d: at rest off %.3e on %.3e; at 60 deg off %.3e on %.3e\n", last + 1,
                  rest_off[last], rest_on[last], peak_off[last], peak_on[last]);
    print_message("at rest, last / first cycle: off %.2f, restored %.2f\n",
                  rest_off[last] / rest_off[0], rest_on[last] / rest_on[0]);
    if (have_gnuplot()) {
        write_plot(dat, png);
        print_message("plot: %s\n", png);
    } else {
        print_message("gnuplot not found: plot skipped (data in %s)\n", dat);
    }

    assert_true(rest_off[last] >= 3.0 * rest_off[0]);
    assert_true(rest_on[last] <= 1.5 * rest_on[0]);
    assert_true(peak_on[last] <= 1.5 * peak_on[0]);
    /* Along the path restoration keeps the bend nearly isometric. At the
     * rest pose it starts above the paper's method: the
     * first bend ovalises the tube (the Brazier effect; the cross-section
     * flattens, which changes no length to first order), and edge lengths
     * cannot see that shape to pull it back, so ~1% strains stay locked in
     * (measured 1.3e-2; the paper's method starts lower, 3.7e-4, and
     * passes it in the ninth cycle). */
    assert_true(peak_on[last] < 0.05 * peak_off[last]);

    free(off);
    free(on);
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    iso_shape_deinit(&sh);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(restoration_keeps_a_long_session_bounded),
    };
    return cmocka_run_group_tests_name("long_session", t, NULL, NULL);
}
