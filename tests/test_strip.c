/* tests/test_strip.c -- docs/method.md property 4: rolling a flat strip into a
 * half cylinder is nearly isometric.
 *
 * The strip lies along x (length 1, 61 vertices) and is a few vertices wide
 * along y. The first columns are fixed, the last columns are the handle.
 * The handle moves as the end of an arc of constant curvature κ(t) = π t / ℓ
 * bent over the free part [x_a, x_b] (ℓ = x_b − x_a): an exactly isometric
 * rolling exists at every t, and at t = 1 the free part is a half cylinder
 * of radius ℓ/π with the handle turned by π, pointing back along −x.
 *
 * Checked: the relative RMS edge-length change at t = 1 is below 2e-3; it
 * is a small fraction of a bi-Laplacian baseline's; it falls when the mesh
 * is refined and when ω decreases. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geom_fixtures.c"
#include "iso_integrate.h"
#include "iso_metrics.h"
#include "testutil.h"

/* ---- the rolling path -------------------------------------------------------------- */

typedef struct roll_path {
    double xa, xb; /* the bent part of the strip, in rest coordinates */
} roll_path;

/* sin φ / φ, (1 − cos φ) / φ and their φ-derivatives, by series near 0. */
static void arc_functions(double f, double *s, double *c, double *ds, double *dc)
{
    if (f < 1e-3) {
        double f2 = f * f;
        *s = 1 - f2 / 6 + f2 * f2 / 120;
        *c = f / 2 - f * f2 / 24;
        *ds = -f / 3 + f * f2 / 30;
        *dc = 0.5 - f2 / 8;
    } else {
        *s = sin(f) / f;
        *c = (1 - cos(f)) / f;
        *ds = (f * cos(f) - sin(f)) / (f * f);
        *dc = (f * sin(f) - (1 - cos(f))) / (f * f);
    }
}

/* Pose of the handle (rest x ≥ x_b): y = R(φ)(x − x_b e_x) + P(φ) with
 * φ = π t, R turning e_x to (cos φ, 0, sin φ) about y, and P = (x_a + ℓ sin
 * φ/φ, 0, ℓ (1 − cos φ)/φ), the end of the arc. World twist: w = −φ' e_y,
 * v = dp/dt − w × p with p = P − x_b R e_x. */
static int roll_eval(void *ctx, int handle, double t, iso_pose *pose, iso_twist *tw)
{
    const roll_path *rp = ctx;
    (void)handle;
    const double pi = acos(-1.0);
    double f = pi * t, df = pi, l = rp->xb - rp->xa;
    double s, c, ds, dc;
    arc_functions(f, &s, &c, &ds, &dc);
    double cf = cos(f), sf = sin(f);
    const double R[9] = {cf, 0, -sf, 0, 1, 0, sf, 0, cf};
    memcpy(pose->R, R, sizeof R);
    pose->p[0] = rp->xa + l * s - rp->xb * cf;
    pose->p[1] = 0;
    pose->p[2] = l * c - rp->xb * sf;
    double dp[3] = {df * (l * ds + rp->xb * sf), 0, df * (l * dc - rp->xb * cf)};
    tw->w[0] = 0;
    tw->w[1] = -df;
    tw->w[2] = 0;
    double wp[3];
    fx_cross(tw->w, pose->p, wp);
    for (int i = 0; i < 3; i++)
        tw->v[i] = dp[i] - wp[i];
    return 0;
}

/* ---- the problem ---------------------------------------------------------------------- */

typedef struct strip {
    fx_mesh fm;
    iso_mesh *m;
    iso_regions r;
    unsigned char *kind;
    roll_path rp;
} strip;

/* nx x ny strip of length 1 and width w, fixed where x ≤ xa, handle
 * where x ≥ 1 − xa (xa a multiple of the spacing, so a refined strip has
 * the same physical regions). */
static void strip_init(strip *s, int nx, int ny, double w, double xa)
{
    s->fm = fx_grid(nx, ny, 1.0, w);
    s->m = fx_make(&s->fm);
    s->kind = malloc((size_t)s->fm.nv);
    assert_non_null(s->kind);
    double dx = 1.0 / (nx - 1);
    s->rp.xa = xa;
    s->rp.xb = 1 - xa;
    for (int i = 0; i < s->fm.nv; i++) {
        double x = s->fm.x[3 * i];
        s->kind[i] = x <= s->rp.xa + 0.25 * dx   ? ISO_FIXED
                     : x >= s->rp.xb - 0.25 * dx ? ISO_HANDLE
                                                 : ISO_FREE;
    }
    fx_regions(&s->r, s->fm.nv, s->kind);
}

static void strip_deinit(strip *s)
{
    iso_regions_deinit(&s->r);
    free(s->kind);
    iso_mesh_destroy(s->m);
    fx_mesh_free(&s->fm);
}

/* Rolls the strip with `steps` fixed ABM steps at ω; returns the metrics of
 * the result against the rest shape, and the result in xout if not NULL. */
static iso_metrics roll(strip *s, double omega, int steps, double *xout)
{
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.omega = omega;
    iso_solver *solver = NULL;
    iso_err err;
    iso_err_clear(&err);
    if (iso_solver_create(s->m, &s->r, &so, &solver, &err) != ISO_OK)
        fail_msg("iso_solver_create: %s", err.msg);
    iso_path path = {roll_eval, &s->rp};
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.steps = steps;
    double *x = malloc(sizeof(double) * 3 * (size_t)s->fm.nv);
    assert_non_null(x);
    memcpy(x, s->fm.x, sizeof(double) * 3 * (size_t)s->fm.nv);
    iso_integrate_stats st;
    if (iso_integrate(solver, s->m, &s->r, &path, &io, x, &st, &err) != ISO_OK)
        fail_msg("iso_integrate: %s", err.msg);
    iso_metrics q;
    iso_metrics_compute(s->m, s->fm.x, x, &q);
    if (xout)
        memcpy(xout, x, sizeof(double) * 3 * (size_t)s->fm.nv);
    free(x);
    iso_solver_destroy(solver);
    return q;
}

/* ---- the bi-Laplacian baseline ---------------------------------------------------- */

/* Displacements d minimising |L d|² (L: uniform graph Laplacian) with d = 0
 * on fixed and d = final pose − rest on handle vertices: a linear method,
 * which cannot follow a rotation by π. Dense, for small meshes. */
static void bilaplacian(const strip *s, double *xout)
{
    int nv = s->fm.nv;
    double *L = calloc((size_t)nv * (size_t)nv, sizeof(double));
    assert_non_null(L);
    for (int t = 0; t < s->fm.nt; t++)
        for (int k = 0; k < 3; k++) {
            int a = s->fm.tri[3 * t + k], b = s->fm.tri[3 * t + (k + 1) % 3];
            if (L[(size_t)nv * a + b] == 0) {
                L[(size_t)nv * a + b] = L[(size_t)nv * b + a] = 1;
                L[(size_t)nv * a + a] -= 1;
                L[(size_t)nv * b + b] -= 1;
            }
        }
    iso_pose g;
    iso_twist tw;
    roll_path rp = s->rp;
    roll_eval(&rp, 0, 1.0, &g, &tw);
    double *d = calloc(3 * (size_t)nv, sizeof(double));
    assert_non_null(d);
    for (int i = 0; i < nv; i++)
        if (s->kind[i] == ISO_HANDLE) {
            double y[3];
            iso_pose_apply(&g, s->fm.x + 3 * i, y);
            for (int c = 0; c < 3; c++)
                d[3 * i + c] = y[c] - s->fm.x[3 * i + c];
        }
    int *fr = malloc(sizeof(int) * (size_t)nv), nf = 0;
    assert_non_null(fr);
    for (int i = 0; i < nv; i++)
        if (s->kind[i] == ISO_FREE)
            fr[nf++] = i;
    /* K = LᵀL; solve K_ff d_f = −K_fc d_c per coordinate. */
    double *K = malloc(sizeof(double) * (size_t)nv * (size_t)nv);
    assert_non_null(K);
    for (int i = 0; i < nv; i++)
        for (int j = 0; j < nv; j++) {
            double acc = 0;
            for (int k = 0; k < nv; k++)
                acc += L[(size_t)nv * k + i] * L[(size_t)nv * k + j];
            K[(size_t)nv * i + j] = acc;
        }
    double *Kff = malloc(sizeof(double) * (size_t)nf * (size_t)nf);
    double *rhs = malloc(sizeof(double) * (size_t)nf), *sol = malloc(sizeof(double) * (size_t)nf);
    assert_non_null(Kff);
    assert_non_null(rhs);
    assert_non_null(sol);
    for (int i = 0; i < nf; i++)
        for (int j = 0; j < nf; j++)
            Kff[(size_t)nf * i + j] = K[(size_t)nv * fr[i] + fr[j]];
    for (int c = 0; c < 3; c++) {
        for (int i = 0; i < nf; i++) {
            rhs[i] = 0;
            for (int j = 0; j < nv; j++)
                if (s->kind[j] != ISO_FREE)
                    rhs[i] -= K[(size_t)nv * fr[i] + j] * d[3 * j + c];
        }
        assert_int_equal(fx_spd_solve(nf, Kff, rhs, sol), 0);
        for (int i = 0; i < nf; i++)
            d[3 * fr[i] + c] = sol[i];
    }
    for (int i = 0; i < 3 * nv; i++)
        xout[i] = s->fm.x[i] + d[i];
    free(L);
    free(K);
    free(Kff);
    free(rhs);
    free(sol);
    free(fr);
    free(d);
}

/* ---- tests ------------------------------------------------------------------------------ */

/* 61 x 4 strip (width 0.05, regions x ≤ 1/60 and x ≥ 59/60), 40 fixed
 * steps: the metrics change by under 1% from 40 to 80 steps (measured),
 * so what is measured is the method's distortion, not integration error.
 *  - ω = 1/3: relative RMS edge-length change below 2e-3 (property 4's
 *    bound; measured 5.3e-4);
 *  - metricErr under 1% of the bi-Laplacian baseline's (measured 5e-5);
 *  - the strip is rolled: the centre of the free part is at the top of the
 *    arc, height ℓ/π, within 5% of ℓ;
 *  - smaller ω is more isometric: metricErr(0.1) < metricErr(1/3)
 *    (measured 4.5e-8 and 5.1e-8, and 5.5e-8 at ω = 1, not run to save
 *    time: 10% steps, ten times the integration error left at 40 steps). */
static void strip_rolls_nearly_isometrically(void **state)
{
    (void)state;
    strip s;
    strip_init(&s, 61, 4, 0.05, 1.0 / 60);
    double *x = malloc(sizeof(double) * 3 * (size_t)s.fm.nv);
    double *xb = malloc(sizeof(double) * 3 * (size_t)s.fm.nv);
    assert_non_null(x);
    assert_non_null(xb);
    iso_metrics q = roll(&s, 1.0 / 3.0, 40, x);
    bilaplacian(&s, xb);
    iso_metrics qb;
    iso_metrics_compute(s.m, s.fm.x, xb, &qb);
    print_message("61x4, ω 1/3: rms strain %.3g, max %.3g, metricErr %.3g; bi-Laplacian "
                  "metricErr %.3g (ratio %.3g), rms strain %.3g\n",
                  q.rms_edge_strain, q.max_edge_strain, q.metric_err, qb.metric_err,
                  q.metric_err / qb.metric_err, qb.rms_edge_strain);
    assert_true(q.rms_edge_strain < 2e-3);
    assert_true(q.metric_err < 1e-2 * qb.metric_err);
    double l = s.rp.xb - s.rp.xa, zmid = 0;
    for (int i = 0; i < s.fm.nv; i++)
        if (fabs(s.fm.x[3 * i] - 0.5) < 1e-9)
            zmid = fmax(zmid, x[3 * i + 2]);
    if (!(fabs(zmid - l / acos(-1.0)) < 0.05 * l))
        fail_msg("mid height %g, arc %g", zmid, l / acos(-1.0));

    iso_metrics q10 = roll(&s, 0.1, 40, NULL);
    print_message("metricErr ω=1/3: %.3g, ω=0.1: %.3g\n", q.metric_err, q10.metric_err);
    assert_true(q10.metric_err < q.metric_err);
    free(x);
    free(xb);
    strip_deinit(&s);
}

/* Refinement: a 21 x 3 strip and the 41 x 5 strip with the same length,
 * width (0.1) and regions (x ≤ 1/20, x ≥ 19/20), edges halved. The
 * relative RMS edge-length change and metricErr both fall (measured 2.67e-3
 * -> 1.96e-3 and 2.9e-6 -> 1.4e-6; 81 x 9 continues to 1.53e-3, 8.5e-7;
 * all within 1% of their 20-step values, so not integration error). */
static void refinement_is_more_isometric(void **state)
{
    (void)state;
    strip coarse, fine;
    strip_init(&coarse, 21, 3, 0.1, 1.0 / 20);
    strip_init(&fine, 41, 5, 0.1, 1.0 / 20);
    iso_metrics qc = roll(&coarse, 1.0 / 3.0, 40, NULL);
    iso_metrics qf = roll(&fine, 1.0 / 3.0, 40, NULL);
    print_message("rms strain 21x3: %.3g, 41x5: %.3g; metricErr %.3g, %.3g\n", qc.rms_edge_strain,
                  qf.rms_edge_strain, qc.metric_err, qf.metric_err);
    assert_true(qf.rms_edge_strain < qc.rms_edge_strain);
    assert_true(qf.metric_err < qc.metric_err);
    strip_deinit(&coarse);
    strip_deinit(&fine);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(strip_rolls_nearly_isometrically),
        cmocka_unit_test(refinement_is_more_isometric),
    };
    return cmocka_run_group_tests_name("strip", t, NULL, NULL);
}
