/* tests/test_system.c -- docs/method.md properties 1, 3 and 5 on whole meshes,
 * through iso_assemble_dense, iso_distortion and iso_solver_*:
 *   (a) a rigid field has d = 0 for every ω, also far from the origin;
 *   (b) 1->4 subdivision leaves d1 unchanged (param) or divides it by 4
 *       (area), the field interpolated linearly to the edge midpoints;
 *   (c) A is symmetric PSD with exactly the six rigid fields as null space
 *       on a closed generic mesh; A_ff is PD under valid constraints and the
 *       solver's field is the dense solution of A_ff v_f = −A_fc v_c;
 *   (d) ill-posed constraints and options are refused at creation.
 *
 * Tolerance scale: E(v) = Σ_T 4 σ_T |v_T|² bounds Σ_T v_Tᵀ N_T v_T, the
 * un-fitted energy every term of d is a fraction of (d2's extrapolated fits
 * add a factor of a few). Rounding in d is a few eps times that, so 1e-12 E
 * is loose for rounding and tight for any modelling error. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "geom_fixtures.c"
#include "iso_dense.h"
#include "iso_solver.h"
#include "testutil.h"

static const iso_weighting WEIGHTINGS[2] = {ISO_WEIGHT_PARAM, ISO_WEIGHT_AREA};

static iso_solver_opts make_opts(double omega, iso_weighting w)
{
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    o.omega = omega;
    o.weighting = w;
    return o;
}

static double energy_scale(const fx_mesh *fm, const double *v, iso_weighting w)
{
    double e = 0;
    for (int t = 0; t < fm->nt; t++) {
        double x[9], vv = 0;
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++) {
                x[3 * k + c] = fm->x[3 * fm->tri[3 * t + k] + c];
                vv += v[3 * fm->tri[3 * t + k] + c] * v[3 * fm->tri[3 * t + k] + c];
            }
        e += 4 * iso_elem_n_scale(x, w) * vv;
    }
    return e;
}

static double *random_field(fx_rng *rng, int nv)
{
    double *v = malloc(sizeof(double) * 3 * (size_t)nv);
    assert_non_null(v);
    for (int i = 0; i < 3 * nv; i++)
        v[i] = fx_uniform(rng, -1, 1);
    return v;
}

static double *dense_a(const iso_mesh *m, const double *x, const iso_solver_opts *o)
{
    int n = 3 * iso_mesh_vertex_count(m);
    double *A = malloc(sizeof(double) * (size_t)n * (size_t)n);
    assert_non_null(A);
    iso_err err;
    iso_err_clear(&err);
    if (iso_assemble_dense(m, x, o, A, &err) != ISO_OK)
        fail_msg("iso_assemble_dense: %s", err.msg);
    return A;
}

static double quad_form(int n, const double *A, const double *v)
{
    double s = 0;
    for (int i = 0; i < n; i++) {
        double r = 0;
        for (int j = 0; j < n; j++)
            r += A[(size_t)n * i + j] * v[j];
        s += v[i] * r;
    }
    return s;
}

/* ---- consistency of the two evaluations of d ---------------------------------- */

/* d1 and d2 summed here from the element blocks (checked against
 * quadrature in test_element): every triangle once, and every interior
 * edge as both ordered pairs (Ti, Tj) and (Tj, Ti). */
static void reference_d1_d2(const iso_mesh *m, const double *x, const double *v, iso_weighting w,
                            double *d1, double *d2)
{
    const int *tri = iso_mesh_triangles(m), *et = iso_mesh_edge_triangles(m);
    *d1 = *d2 = 0;
    for (int t = 0; t < iso_mesh_triangle_count(m); t++) {
        double xt[9], vt[9], Q[81];
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++) {
                xt[3 * k + c] = x[3 * tri[3 * t + k] + c];
                vt[3 * k + c] = v[3 * tri[3 * t + k] + c];
            }
        assert_int_equal(iso_elem_q1(xt, w, Q), 0);
        *d1 += quad_form(9, Q, vt);
    }
    for (int e = 0; e < iso_mesh_edge_count(m); e++) {
        if (et[2 * e + 1] < 0)
            continue;
        for (int dir = 0; dir < 2; dir++) {
            const int *ti = tri + 3 * et[2 * e + dir], *tj = tri + 3 * et[2 * e + 1 - dir];
            double xi[9], xo[3], v4[12], Q[144];
            int jmap[3], other = -1;
            for (int k = 0; k < 3; k++) {
                jmap[k] = 3;
                for (int l = 0; l < 3; l++)
                    if (tj[k] == ti[l])
                        jmap[k] = l;
                if (jmap[k] == 3)
                    other = tj[k];
            }
            assert_true(other >= 0);
            for (int k = 0; k < 3; k++)
                for (int c = 0; c < 3; c++) {
                    xi[3 * k + c] = x[3 * ti[k] + c];
                    v4[3 * k + c] = v[3 * ti[k] + c];
                }
            for (int c = 0; c < 3; c++) {
                xo[c] = x[3 * other + c];
                v4[9 + c] = v[3 * other + c];
            }
            assert_int_equal(iso_elem_q2(xi, xo, jmap, w, Q), 0);
            *d2 += quad_form(12, Q, v4);
        }
    }
}

/* vᵀAv (assembled) = iso_distortion (element by element) = (1−ω)d1 + ωd2,
 * and d1, d2 equal the sums of the element blocks over all triangles and
 * both ordered pairs of every interior edge; relative 1e-12 of E(v), on a
 * closed and on an open mesh (boundary edges contribute nothing). */
static void assembly_matches_distortion(void **state)
{
    (void)state;
    fx_rng rng = {21};
    fx_mesh meshes[2] = {fx_icosphere(1, 1.0, 0.03, &rng), fx_grid(7, 5, 1.2, 0.8)};
    for (int i = 0; i < meshes[1].nv; i++) /* a bump so the grid is not flat */
        meshes[1].x[3 * i + 2] =
            0.3 * sin(2 * meshes[1].x[3 * i]) * cos(3 * meshes[1].x[3 * i + 1]);
    for (int mi = 0; mi < 2; mi++) {
        fx_mesh *fm = &meshes[mi];
        iso_mesh *m = fx_make(fm);
        double *v = random_field(&rng, fm->nv);
        for (int wi = 0; wi < 2; wi++) {
            iso_solver_opts o = make_opts(0.37, WEIGHTINGS[wi]);
            double *A = dense_a(m, fm->x, &o);
            double d1, d2;
            double d = iso_distortion(m, fm->x, v, &o, &d1, &d2);
            double vav = quad_form(3 * fm->nv, A, v);
            double tol = 1e-12 * energy_scale(fm, v, WEIGHTINGS[wi]);
            if (!(fabs(d - vav) <= tol))
                fail_msg("mesh %d w %d: d = %.17g, vᵀAv = %.17g", mi, wi, d, vav);
            assert_true(fabs(d - (0.63 * d1 + 0.37 * d2)) <= tol);
            assert_true(d1 > 0 && d2 > 0);
            double r1, r2;
            reference_d1_d2(m, fm->x, v, WEIGHTINGS[wi], &r1, &r2);
            if (!(fabs(d1 - r1) <= tol && fabs(d2 - r2) <= tol))
                fail_msg("mesh %d w %d: d1 %.17g vs %.17g, d2 %.17g vs %.17g", mi, wi, d1, r1, d2,
                         r2);
            free(A);
        }
        free(v);
        iso_mesh_destroy(m);
        fx_mesh_free(fm);
    }
}

/* ---- (a) rigid fields ------------------------------------------------------------- */

/* d(a + b × x) = 0 for ω ∈ {0.01, 1/3, 1}, both weightings, on a generic
 * closed mesh at the origin (radius 1) and on a small copy (radius 0.05)
 * 1e4 away from it, also through the assembled A: |A v| relative 1e-12. */
static void rigid_fields_have_zero_distortion(void **state)
{
    (void)state;
    fx_rng rng = {22};
    const double omegas[3] = {0.01, 1.0 / 3.0, 1.0};
    for (int far = 0; far < 2; far++) {
        fx_mesh fm = fx_icosphere(2, far ? 0.05 : 1.0, 0.03, &rng);
        const double off[3] = {1e4, -2e4, 5e3};
        if (far)
            fx_translate(&fm, off);
        iso_mesh *m = fx_make(&fm);
        double *v = malloc(sizeof(double) * 3 * (size_t)fm.nv);
        double *Av = malloc(sizeof(double) * 3 * (size_t)fm.nv);
        assert_non_null(v);
        assert_non_null(Av);
        for (int trial = 0; trial < 3; trial++) {
            double a[3], b[3];
            for (int c = 0; c < 3; c++) {
                a[c] = fx_uniform(&rng, -1, 1);
                b[c] = fx_uniform(&rng, -1, 1);
            }
            fx_rigid_field(fm.nv, fm.x, a, b, v);
            /* The rounding of v itself is eps (|a| + |b| |x|), not eps |v|. */
            double vscale = fx_norm(a) + fx_norm(b) * (far ? fx_norm(off) + 1 : 2);
            for (int wi = 0; wi < 2; wi++)
                for (int oi = 0; oi < 3; oi++) {
                    iso_solver_opts o = make_opts(omegas[oi], WEIGHTINGS[wi]);
                    double d1, d2, d = iso_distortion(m, fm.x, v, &o, &d1, &d2);
                    double tol = 1e-12 * energy_scale(&fm, v, WEIGHTINGS[wi]);
                    if (!(fabs(d) <= tol && fabs(d1) <= tol && fabs(d2) <= tol))
                        fail_msg("far %d w %d ω %g: d = %g (d1 %g, d2 %g), bound %g", far, wi,
                                 omegas[oi], d, d1, d2, tol);
                    if (oi != 1)
                        continue;
                    int n = 3 * fm.nv;
                    double *A = dense_a(m, fm.x, &o);
                    double amax = iso_test_max_abs(A, (size_t)n * n), worst = 0;
                    for (int i = 0; i < n; i++) {
                        Av[i] = 0;
                        for (int j = 0; j < n; j++)
                            Av[i] += A[(size_t)n * i + j] * v[j];
                        worst = fmax(worst, fabs(Av[i]));
                    }
                    /* Each row of A has ~40 nonzeros of size ≤ amax. */
                    if (!(worst <= 1e-12 * 40 * amax * vscale))
                        fail_msg("far %d w %d: |Av|_max = %g, bound %g", far, wi, worst,
                                 1e-12 * 40 * amax * vscale);
                    free(A);
                }
        }
        free(v);
        free(Av);
        iso_mesh_destroy(m);
        fx_mesh_free(&fm);
    }
}

/* ---- (b) subdivision ------------------------------------------------------------ */

/* Each child triangle's second moment is 1/16 of its parent's (the corner
 * children are half-size translates, the middle one a half-size point
 * reflection) and the field is the same linear field, so every child has
 * the parent's best rigid fit and its residual integral is 1/16 of the
 * parent's: d1 sums to the same under param (N scale 1/24 per triangle,
 * integral / 2A) and to 1/4 under area. Exact, so 1e-12 relative. Two
 * levels, on a jittered sphere (curved, irregular) and a random field. */
static void subdivision_scales_d1_exactly(void **state)
{
    (void)state;
    fx_rng rng = {23};
    fx_mesh coarse = fx_icosphere(1, 1.0, 0.05, &rng);
    double *v0 = random_field(&rng, coarse.nv);
    double *v1 = NULL, *v2 = NULL;
    fx_mesh fine = fx_subdivide(&coarse, v0, &v1);
    fx_mesh finer = fx_subdivide(&fine, v1, &v2);
    iso_mesh *m0 = fx_make(&coarse), *m1 = fx_make(&fine), *m2 = fx_make(&finer);
    for (int wi = 0; wi < 2; wi++) {
        iso_solver_opts o = make_opts(1.0 / 3.0, WEIGHTINGS[wi]);
        double d1_0, d1_1, d1_2, d2_0, d2_1, d2_2;
        (void)iso_distortion(m0, coarse.x, v0, &o, &d1_0, &d2_0);
        (void)iso_distortion(m1, fine.x, v1, &o, &d1_1, &d2_1);
        (void)iso_distortion(m2, finer.x, v2, &o, &d1_2, &d2_2);
        double k = WEIGHTINGS[wi] == ISO_WEIGHT_PARAM ? 1.0 : 0.25;
        if (!(fabs(d1_1 - k * d1_0) <= 1e-12 * d1_0 && fabs(d1_2 - k * k * d1_0) <= 1e-12 * d1_0))
            fail_msg("w %d: d1 = %.17g -> %.17g -> %.17g, expected factor %g per level", wi, d1_0,
                     d1_1, d1_2, k);
        print_message("w %d: d1 ratios %.15f %.15f; d2 ratios %.4f %.4f\n", wi, d1_1 / d1_0,
                      d1_2 / d1_1, d2_1 / d2_0, d2_2 / d2_1);
    }
    iso_mesh_destroy(m0);
    iso_mesh_destroy(m1);
    iso_mesh_destroy(m2);
    free(v0);
    free(v1);
    free(v2);
    fx_mesh_free(&coarse);
    fx_mesh_free(&fine);
    fx_mesh_free(&finer);
}

/* ---- (c) spectrum of A, the constrained solve ------------------------------------- */

/* A (486 x 486 on a jittered level-2 icosphere, 162 vertices) is symmetric,
 * PSD, and has exactly six eigenvalues at rounding level: a generic closed
 * triangulated sphere is infinitesimally rigid (Gluck), so d1 vanishes only
 * on rigid fields, and d2 ≥ 0 adds nothing to the null space. Thresholds:
 * |λ_0..5| ≤ 1e-12 λ_max (rounding: ~1e-15 measured) and λ_6 ≥ 1e-6 λ_max
 * (measured gap printed; it is ~1e-2). */
static void a_is_psd_with_six_dim_null_space(void **state)
{
    (void)state;
    fx_rng rng = {24};
    fx_mesh fm = fx_icosphere(2, 1.0, 0.03, &rng);
    iso_mesh *m = fx_make(&fm);
    int n = 3 * fm.nv;
    double *w = malloc(sizeof(double) * (size_t)n);
    assert_non_null(w);
    for (int wi = 0; wi < 2; wi++) {
        iso_solver_opts o = make_opts(1.0 / 3.0, WEIGHTINGS[wi]);
        double *A = dense_a(m, fm.x, &o);
        double amax = iso_test_max_abs(A, (size_t)n * n);
        for (int i = 0; i < n; i++)
            for (int j = i + 1; j < n; j++)
                assert_true(fabs(A[(size_t)n * i + j] - A[(size_t)n * j + i]) <= 1e-14 * amax);
        fx_eigvalsh(n, A, w);
        double lmax = w[n - 1];
        assert_true(lmax > 0);
        for (int k = 0; k < 6; k++)
            if (!(fabs(w[k]) <= 1e-12 * lmax))
                fail_msg("w %d: eigenvalue %d = %g (λ_max %g)", wi, k, w[k], lmax);
        if (!(w[6] >= 1e-6 * lmax))
            fail_msg("w %d: seventh eigenvalue %g, λ_max %g: null space larger than 6", wi, w[6],
                     lmax);
        print_message("w %d: |λ_0..5| ≤ %.2g λ_max, λ_6 = %.3g λ_max\n", wi,
                      fmax(fabs(w[0]), fabs(w[5])) / lmax, w[6] / lmax);
        free(A);
    }
    free(w);
    iso_mesh_destroy(m);
    fx_mesh_free(&fm);
}

/* Regions on a mesh: fixed below z < zlo, handle above z > zhi, else free. */
static unsigned char *band_kinds(const fx_mesh *fm, int axis, double lo, double hi)
{
    unsigned char *k = malloc((size_t)fm->nv);
    assert_non_null(k);
    for (int i = 0; i < fm->nv; i++) {
        double z = fm->x[3 * i + axis];
        k[i] = z < lo ? ISO_FIXED : z > hi ? ISO_HANDLE : ISO_FREE;
    }
    return k;
}

/* The solver's field against the dense solve A_ff v_f = −A_fc v_c (dposv
 * succeeds: A_ff is PD, and its smallest eigenvalue is checked > 0), to
 * 1e-10 relative: both are backward stable, A_ff's condition number here is
 * ~1e3-1e5, so they agree to ~1e-12. Handle entries are copied from vc,
 * fixed ones are zero. A sphere and an open bumpy grid, both weightings,
 * ω ∈ {0.01, 1/3, 1}. */
static void solver_matches_dense_solve(void **state)
{
    (void)state;
    fx_rng rng = {25};
    fx_mesh meshes[2] = {fx_icosphere(2, 1.0, 0.03, &rng), fx_grid(13, 7, 2.0, 1.0)};
    for (int i = 0; i < meshes[1].nv; i++)
        meshes[1].x[3 * i + 2] = 0.2 * sin(2 * meshes[1].x[3 * i] + meshes[1].x[3 * i + 1]);
    const double omegas[3] = {0.01, 1.0 / 3.0, 1.0};
    for (int mi = 0; mi < 2; mi++) {
        fx_mesh *fm = &meshes[mi];
        iso_mesh *m = fx_make(fm);
        unsigned char *kind = mi == 0 ? band_kinds(fm, 2, -0.6, 0.6) : band_kinds(fm, 0, 0.2, 1.8);
        iso_regions r;
        fx_regions(&r, fm->nv, kind);
        int n = 3 * fm->nv;
        double *vc = calloc((size_t)n, sizeof(double));
        double *v = malloc(sizeof(double) * (size_t)n);
        assert_non_null(vc);
        assert_non_null(v);
        double a[3] = {0.1, -0.3, 0.2}, b[3] = {0.5, 0.2, -0.4};
        for (int i = 0; i < fm->nv; i++)
            if (kind[i] == ISO_HANDLE) {
                double bx[3];
                fx_cross(b, fm->x + 3 * i, bx);
                for (int c = 0; c < 3; c++)
                    vc[3 * i + c] = a[c] + bx[c];
            }
        /* free and constrained index lists */
        int *fr = malloc(sizeof(int) * (size_t)n), *co = malloc(sizeof(int) * (size_t)n);
        assert_non_null(fr);
        assert_non_null(co);
        int nf = 0, nc = 0;
        for (int i = 0; i < fm->nv; i++)
            for (int c = 0; c < 3; c++) {
                if (kind[i] == ISO_FREE)
                    fr[nf++] = 3 * i + c;
                else
                    co[nc++] = 3 * i + c;
            }
        assert_true(nf > 0 && nc > 0);
        double *Aff = malloc(sizeof(double) * (size_t)nf * (size_t)nf);
        double *rhs = malloc(sizeof(double) * (size_t)nf),
               *vf = malloc(sizeof(double) * (size_t)nf);
        double *ev = malloc(sizeof(double) * (size_t)nf);
        assert_non_null(Aff);
        assert_non_null(rhs);
        assert_non_null(vf);
        assert_non_null(ev);
        for (int wi = 0; wi < 2; wi++)
            for (int oi = 0; oi < 3; oi++) {
                iso_solver_opts o = make_opts(omegas[oi], WEIGHTINGS[wi]);
                double *A = dense_a(m, fm->x, &o);
                for (int i = 0; i < nf; i++) {
                    rhs[i] = 0;
                    for (int j = 0; j < nf; j++)
                        Aff[(size_t)nf * i + j] = A[(size_t)n * fr[i] + fr[j]];
                    for (int j = 0; j < nc; j++)
                        rhs[i] -= A[(size_t)n * fr[i] + co[j]] * vc[co[j]];
                }
                fx_eigvalsh(nf, Aff, ev);
                assert_true(ev[0] > 0);
                assert_int_equal(fx_spd_solve(nf, Aff, rhs, vf), 0);
                iso_solver *s = NULL;
                iso_err err;
                iso_err_clear(&err);
                if (iso_solver_create(m, &r, &o, &s, &err) != ISO_OK)
                    fail_msg("iso_solver_create: %s", err.msg);
                if (iso_solver_field(s, fm->x, vc, v, &err) != ISO_OK)
                    fail_msg("iso_solver_field: %s", err.msg);
                double diff = 0, ref = iso_test_max_abs(vf, (size_t)nf);
                for (int i = 0; i < nf; i++)
                    diff = fmax(diff, fabs(v[fr[i]] - vf[i]));
                if (!(diff <= 1e-10 * ref))
                    fail_msg("mesh %d w %d ω %g: solver vs dense %g (|v_f| %g, cond %g)", mi, wi,
                             omegas[oi], diff, ref, ev[nf - 1] / ev[0]);
                for (int i = 0; i < fm->nv; i++)
                    for (int c = 0; c < 3; c++) {
                        if (kind[i] == ISO_HANDLE)
                            assert_true(v[3 * i + c] == vc[3 * i + c]);
                        if (kind[i] == ISO_FIXED)
                            assert_true(v[3 * i + c] == 0.0);
                    }
                iso_solver_stats st;
                iso_solver_get_stats(s, &st);
                assert_int_equal(st.n_free, nf / 3);
                iso_solver_destroy(s);
                free(A);
            }
        free(Aff);
        free(rhs);
        free(vf);
        free(ev);
        free(fr);
        free(co);
        free(vc);
        free(v);
        free(kind);
        iso_regions_deinit(&r);
        iso_mesh_destroy(m);
        fx_mesh_free(fm);
    }
}

/* ---- (d) ill-posed problems ----------------------------------------------------- */

static void expect_refused(const iso_mesh *m, const unsigned char *kind, int nv, double omega,
                           int code, const char *substring)
{
    iso_regions r;
    fx_regions(&r, nv, kind);
    iso_solver_opts o = make_opts(omega, ISO_WEIGHT_PARAM);
    iso_solver *s = (iso_solver *)&r; /* any non-NULL: creation must reset it */
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_solver_create(m, &r, &o, &s, &err);
    if (rc != code)
        fail_msg("expected %d, got %d (%s)", code, rc, err.msg);
    assert_int_equal(err.code, code);
    assert_null(s);
    if (!strstr(err.msg, substring))
        fail_msg("message \"%s\" lacks \"%s\"", err.msg, substring);
    iso_regions_deinit(&r);
}

static void ill_posed_constraints_are_refused(void **state)
{
    (void)state;
    fx_rng rng = {26};
    fx_mesh fm = fx_icosphere(1, 1.0, 0.03, &rng);
    int nv1 = fm.nv;
    iso_mesh *sphere = fx_make(&fm);
    unsigned char *kind = malloc((size_t)nv1 * 2);
    assert_non_null(kind);

    /* A single fixed vertex: rotations about it are free. */
    memset(kind, ISO_FREE, (size_t)nv1);
    kind[0] = ISO_FIXED;
    expect_refused(sphere, kind, nv1, 1.0 / 3.0, ISO_ECONSTRAINT, "one line");
    /* Two constrained vertices: a rotation about the line through them. */
    kind[5] = ISO_HANDLE;
    expect_refused(sphere, kind, nv1, 1.0 / 3.0, ISO_ECONSTRAINT, "one line");
    /* No constraint at all. */
    memset(kind, ISO_FREE, (size_t)nv1);
    expect_refused(sphere, kind, nv1, 1.0 / 3.0, ISO_ECONSTRAINT, "no fixed or handle vertex");

    /* Two spheres; the second has free vertices and no constraint. */
    fx_mesh two = fx_icosphere(1, 1.0, 0.03, &rng);
    const double d[3] = {5, 0, 0};
    fx_translate(&two, d);
    fx_append(&two, &fm);
    iso_mesh *pair = fx_make(&two);
    for (int i = 0; i < two.nv; i++)
        kind[i] = i < nv1 && two.x[3 * i + 2] < -0.5 ? ISO_FIXED : ISO_FREE;
    /* (the first nv1 vertices are the translated sphere's; constrain them) */
    expect_refused(pair, kind, two.nv, 1.0 / 3.0, ISO_ECONSTRAINT, "no fixed or handle vertex");

    /* A flat grid with a whole row fixed: three or more constrained
     * vertices, all collinear, and the grid can swing about that row. */
    fx_mesh grid = fx_grid(6, 5, 1.0, 1.0);
    iso_mesh *g = fx_make(&grid);
    for (int i = 0; i < grid.nv; i++)
        kind[i] = i < 6 ? ISO_FIXED : ISO_FREE;
    expect_refused(g, kind, grid.nv, 1.0 / 3.0, ISO_ECONSTRAINT, "one line");
    /* ... and accepted once one vertex off that line is constrained too. */
    kind[6 * 4 + 3] = ISO_HANDLE;
    {
        iso_regions r;
        fx_regions(&r, grid.nv, kind);
        iso_solver *s = NULL;
        iso_err err;
        iso_err_clear(&err);
        if (iso_solver_create(g, &r, NULL, &s, &err) != ISO_OK)
            fail_msg("valid constraints refused: %s", err.msg);
        iso_solver_destroy(s);
        iso_regions_deinit(&r);
    }

    /* ω outside (0, 1] with otherwise valid constraints. */
    for (int i = 0; i < nv1; i++)
        kind[i] = fm.x[3 * i + 2] < -0.5  ? ISO_FIXED
                  : fm.x[3 * i + 2] > 0.5 ? ISO_HANDLE
                                          : ISO_FREE;
    const double bad[4] = {0.0, 1.0 + 1e-12, 1.5, -0.1};
    for (int k = 0; k < 4; k++)
        expect_refused(sphere, kind, nv1, bad[k], ISO_EINVAL, "outside (0, 1]");
    expect_refused(sphere, kind, nv1, NAN, ISO_EINVAL, "outside (0, 1]");

    free(kind);
    iso_mesh_destroy(sphere);
    iso_mesh_destroy(pair);
    iso_mesh_destroy(g);
    fx_mesh_free(&fm);
    fx_mesh_free(&two);
    fx_mesh_free(&grid);
}

/* A bumpy 13x7 grid, fixed at one end, its band at the other a handle
 * turning with angular velocity (0, 0.3, 0.1): the system both reuse tests
 * below solve along a path. */
typedef struct bumpy {
    fx_mesh fm;
    iso_mesh *m;
    unsigned char *kind;
    iso_regions r;
    double *vc; /* the handle velocities, 3 nv */
} bumpy;

static void bumpy_init(bumpy *b)
{
    b->fm = fx_grid(13, 7, 2.0, 1.0);
    for (int i = 0; i < b->fm.nv; i++)
        b->fm.x[3 * i + 2] = 0.2 * sin(2 * b->fm.x[3 * i] + b->fm.x[3 * i + 1]);
    b->m = fx_make(&b->fm);
    if (b->fm.nv <= 0 || b->fm.nv > 100000)
        fail_msg("grid of %d vertices", b->fm.nv);
    b->kind = band_kinds(&b->fm, 0, 0.2, 1.8);
    fx_regions(&b->r, b->fm.nv, b->kind);
    b->vc = calloc(3 * (size_t)b->fm.nv, sizeof(double));
    assert_non_null(b->vc);
    double w[3] = {0.0, 0.3, 0.1};
    for (int i = 0; i < b->fm.nv; i++)
        if (b->kind[i] == ISO_HANDLE)
            fx_cross(w, b->fm.x + 3 * i, b->vc + 3 * i);
}

static void bumpy_deinit(bumpy *b)
{
    free(b->vc);
    free(b->kind);
    iso_regions_deinit(&b->r);
    iso_mesh_destroy(b->m);
    fx_mesh_free(&b->fm);
}

/* Two solvers of bp with the options o: one that factors every evaluation
 * (the reference) and one with adaptive refactoring. */
static void create_pair(const bumpy *bp, iso_solver_opts o, iso_solver **always, iso_solver **s)
{
    iso_err err;
    iso_err_clear(&err);
    o.refactor = ISO_REFACTOR_ALWAYS;
    if (iso_solver_create(bp->m, &bp->r, &o, always, &err) != ISO_OK)
        fail_msg("iso_solver_create (always): %s", err.msg);
    o.refactor = ISO_REFACTOR_ADAPTIVE;
    if (iso_solver_create(bp->m, &bp->r, &o, s, &err) != ISO_OK)
        fail_msg("iso_solver_create (adaptive): %s", err.msg);
}

/* Adaptive refactoring (PCG preconditioned by the cached factor) against a
 * fresh factorization every evaluation, along one sequence of positions
 * that moves like an integrator's: pairs of nearby evaluations (predictor,
 * corrector) a step apart, with steps that grow so the factor goes stale
 * (fast enough that PCG's start from the remembered solutions does not
 * save it).
 * Every field agrees with the always-refactor one to 1e-7 of its largest
 * entry (CG stops at 1e-10 relative residual; A_ff's condition number here
 * is ~1e3), the factor was reused, and at least one attempt found it too
 * stale and refactored; a second adaptive run is bit-identical to the first.
 * Those runs precondition with the plain factor (the policy under test);
 * the rotated preconditioner then meets the same tolerance along the same
 * path. */
static void factor_reuse_matches_refactoring(void **state)
{
    (void)state;
    bumpy bp;
    bumpy_init(&bp);
    int n = 3 * bp.fm.nv, evals = 24;
    double *x = malloc(sizeof(double) * (size_t)n);
    double *v[4];
    for (int k = 0; k < 4; k++) {
        v[k] = malloc(sizeof(double) * (size_t)n * (size_t)evals);
        assert_non_null(v[k]);
    }
    assert_non_null(x);
    iso_solver_stats st[4];
    for (int run = 0; run < 4; run++) {
        iso_solver_opts o = make_opts(1.0 / 3.0, ISO_WEIGHT_PARAM);
        o.refactor = run == 0 ? ISO_REFACTOR_ALWAYS : ISO_REFACTOR_ADAPTIVE;
        o.preconditioner = run == 3 ? ISO_PRECOND_ROTATED : ISO_PRECOND_PLAIN;
        iso_solver *s = NULL;
        iso_err err;
        iso_err_clear(&err);
        if (iso_solver_create(bp.m, &bp.r, &o, &s, &err) != ISO_OK)
            fail_msg("iso_solver_create: %s", err.msg);
        memcpy(x, bp.fm.x, sizeof(double) * (size_t)n);
        for (int e = 0; e < evals; e++) {
            double *ve = v[run] + (size_t)n * (size_t)e;
            if (iso_solver_field(s, x, bp.vc, ve, &err) != ISO_OK)
                fail_msg("run %d evaluation %d: %s", run, e, err.msg);
            /* The next point: the always run's field moves every run alike,
             * a small nudge after even evaluations, a growing step after odd. */
            const double *drive = v[0] + (size_t)n * (size_t)e;
            double h = e % 2 == 0 ? 1e-4 : 0.05 * (1 + e / 2);
            for (int i = 0; i < n; i++)
                x[i] += h * drive[i];
        }
        iso_solver_get_stats(s, &st[run]);
        iso_solver_destroy(s);
    }
    for (int run = 1; run < 4; run += 2)
        for (int e = 0; e < evals; e++) {
            const double *a = v[0] + (size_t)n * (size_t)e, *c = v[run] + (size_t)n * (size_t)e;
            double ref = iso_test_max_abs(a, (size_t)n);
            double diff = iso_test_max_abs_diff(a, c, (size_t)n);
            if (!(diff <= 1e-7 * ref))
                fail_msg("evaluation %d: adaptive (%s) vs always %g (|v| %g)", e,
                         run == 3 ? "rotated" : "plain", diff, ref);
        }
    assert_int_equal(st[0].factorizations, evals);
    assert_int_equal(st[0].factor_solves, evals); /* one direct solve each */
    /* The factor's own counts: L holds A's pattern and its fill, a double
     * for each entry at least, and the analysis took some time. */
    assert_true(st[0].nnz_l >= st[0].nnz_a && st[0].factor_bytes >= 8 * st[0].nnz_l);
    assert_true(st[0].t_analysis > 0 && (st[0].supernodal == 0 || st[0].supernodal == 1));
    /* A PCG solve uses the factor for its start and each iteration at most,
     * a direct one once. */
    assert_true(st[1].factor_solves > st[1].factorizations);
    assert_true(st[1].factor_solves <= evals + st[1].cg_iterations + st[1].factorizations);
    assert_true(st[1].factorizations < evals);
    assert_true(st[1].factorizations > 1);
    assert_true(st[1].cg_iterations > 0);
    assert_true(st[1].refactors > 0);
    assert_memory_equal(v[1], v[2], sizeof(double) * (size_t)n * (size_t)evals);
    for (int run = 1; run < 4; run += 2)
        printf("adaptive, %s: %ld of %d evaluations factorized, %ld CG iterations, %ld refactors\n",
               run == 3 ? "rotated" : "plain", st[run].factorizations, evals, st[run].cg_iterations,
               st[run].refactors);
    for (int k = 0; k < 4; k++)
        free(v[k]);
    free(x);
    bumpy_deinit(&bp);
}

/* The rotated preconditioner (ISO_PRECOND_ROTATED) under a closed form: A
 * is equivariant under rotation, so after the factor was made at x, the
 * system at R x (handle velocities turned alike) is the factor's turned by
 * Q = diag(R): the preconditioner is exact, PCG ends after one iteration,
 * and the field is R times the field at x (to 1e-9 of its largest entry;
 * CG's residual tolerance is 1e-10). With the plain factor PCG gives up on
 * the same turn (or needs more than 3 iterations) and factors afresh. Then the whole mesh shrunk to
 * half (no ring turned rigidly: every vertex falls back to the plain factor) still meets the
 * tolerance against a fresh factorization. */
static void rotated_factor_is_exact_under_a_turn(void **state)
{
    (void)state;
    bumpy bp;
    bumpy_init(&bp);
    int nv = bp.fm.nv, n = 3 * nv;
    double *x = malloc(sizeof(double) * (size_t)n), *vc = malloc(sizeof(double) * (size_t)n);
    double *v0 = malloc(sizeof(double) * (size_t)n), *v1 = malloc(sizeof(double) * (size_t)n);
    assert_true(x && vc && v0 && v1);
    /* R: 0.7 rad about (1, 2, 3)/|.|, by Rodrigues' formula */
    double k[3] = {1, 2, 3}, kn = sqrt(14.0), th = 0.7, R[9];
    for (int a = 0; a < 3; a++)
        k[a] /= kn;
    double c = cos(th), sn = sin(th);
    for (int r = 0; r < 3; r++)
        for (int q = 0; q < 3; q++) {
            double cross_kq = r == q ? 0 : (r + 1) % 3 == q ? -k[3 - r - q] : k[3 - r - q];
            R[3 * r + q] = (r == q ? c : 0) + (1 - c) * k[r] * k[q] + sn * cross_kq;
        }
    long iters[2], facts[2];
    for (int pre = 0; pre < 2; pre++) {
        iso_solver_opts o = make_opts(1.0 / 3.0, ISO_WEIGHT_PARAM);
        o.refactor = ISO_REFACTOR_ADAPTIVE;
        o.preconditioner = pre == 0 ? ISO_PRECOND_ROTATED : ISO_PRECOND_PLAIN;
        iso_solver *s = NULL;
        iso_err err;
        iso_err_clear(&err);
        assert_int_equal(iso_solver_create(bp.m, &bp.r, &o, &s, &err), ISO_OK);
        assert_int_equal(iso_solver_field(s, bp.fm.x, bp.vc, v0, &err), ISO_OK); /* factors */
        for (int i = 0; i < nv; i++)
            for (int r = 0; r < 3; r++) {
                const double *p = bp.fm.x + 3 * i, *u = bp.vc + 3 * i;
                x[3 * i + r] = R[3 * r] * p[0] + R[3 * r + 1] * p[1] + R[3 * r + 2] * p[2] + 0.3;
                vc[3 * i + r] = R[3 * r] * u[0] + R[3 * r + 1] * u[1] + R[3 * r + 2] * u[2];
            }
        iso_solver_stats a, b;
        iso_solver_get_stats(s, &a);
        assert_int_equal(iso_solver_field(s, x, vc, v1, &err), ISO_OK);
        iso_solver_get_stats(s, &b);
        iters[pre] = b.cg_iterations - a.cg_iterations;
        facts[pre] = b.factorizations - a.factorizations;
        if (pre == 0) {
            double top = iso_test_max_abs(v0, (size_t)n), worst = 0;
            for (int i = 0; i < nv; i++)
                for (int r = 0; r < 3; r++) {
                    const double *u = v0 + 3 * i;
                    double want = R[3 * r] * u[0] + R[3 * r + 1] * u[1] + R[3 * r + 2] * u[2];
                    worst = fmax(worst, fabs(v1[3 * i + r] - want));
                }
            printf("turned 0.7 rad: the field is R v to %.2g of |v|\n", worst / top);
            assert_true(worst <= 1e-9 * top);
        }
        iso_solver_destroy(s);
    }
    printf("after the turn: rotated %ld CG iterations and %ld factorizations, plain %ld and %ld\n",
           iters[0], facts[0], iters[1], facts[1]);
    assert_true(iters[0] <= 1);
    assert_int_equal(facts[0], 0); /* the turned factor served */
    assert_true(facts[1] == 1 || iters[1] > 3);

    /* Shrunk to half: F_i = I/2 is no rotation, so Q_i = I. */
    iso_solver_opts o = make_opts(1.0 / 3.0, ISO_WEIGHT_PARAM);
    iso_solver *s = NULL, *always = NULL;
    iso_err err;
    iso_err_clear(&err);
    create_pair(&bp, o, &always, &s);
    assert_int_equal(iso_solver_field(s, bp.fm.x, bp.vc, v0, &err), ISO_OK);
    for (int i = 0; i < n; i++)
        x[i] = 0.5 * bp.fm.x[i];
    assert_int_equal(iso_solver_field(always, x, bp.vc, v0, &err), ISO_OK);
    assert_int_equal(iso_solver_field(s, x, bp.vc, v1, &err), ISO_OK);
    double top = iso_test_max_abs(v0, (size_t)n);
    assert_true(iso_test_max_abs_diff(v0, v1, (size_t)n) <= 1e-7 * top);
    iso_solver_destroy(s);
    iso_solver_destroy(always);
    free(x);
    free(vc);
    free(v0);
    free(v1);
    bumpy_deinit(&bp);
}

/* iso_solver_factor_at: the factor made before the first evaluation
 * serves it (no factorization of its own, at most one CG iteration at the
 * same positions) and its field is the fresh factorization's to 1e-7 of
 * its largest entry; under the paper's scheme the call does nothing. */
static void factor_at_serves_the_first_evaluation(void **state)
{
    (void)state;
    bumpy bp;
    bumpy_init(&bp);
    int n = 3 * bp.fm.nv;
    double *ref = malloc(sizeof(double) * (size_t)n), *v = malloc(sizeof(double) * (size_t)n);
    assert_true(ref && v);
    iso_solver_opts o = make_opts(1.0 / 3.0, ISO_WEIGHT_PARAM);
    iso_solver *always = NULL, *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    create_pair(&bp, o, &always, &s);
    assert_int_equal(iso_solver_factor_at(always, bp.fm.x, &err), ISO_OK);
    iso_solver_stats st;
    iso_solver_get_stats(always, &st);
    assert_int_equal(st.factorizations, 0);
    assert_int_equal(iso_solver_field(always, bp.fm.x, bp.vc, ref, &err), ISO_OK);
    assert_int_equal(iso_solver_factor_at(s, bp.fm.x, &err), ISO_OK);
    assert_int_equal(iso_solver_field(s, bp.fm.x, bp.vc, v, &err), ISO_OK);
    iso_solver_get_stats(s, &st);
    printf("after iso_solver_factor_at: %ld factorizations, %ld CG iterations\n", st.factorizations,
           st.cg_iterations);
    assert_int_equal(st.factorizations, 1);
    assert_true(st.cg_iterations <= 1);
    assert_true(iso_test_max_abs_diff(v, ref, (size_t)n) <=
                1e-7 * iso_test_max_abs(ref, (size_t)n));
    iso_solver_destroy(always);
    iso_solver_destroy(s);
    free(ref);
    free(v);
    bumpy_deinit(&bp);
}

/* An adaptive solver that has factored at the bumpy mesh's rest and
 * computed its field v there (no PCG yet, so it remembers no solution:
 * warmstart.c), and x moved along v by `move`: the next solve's point. */
static iso_solver *one_step_solver(const bumpy *bp, iso_solver_opts o, double move, double *x,
                                   double *v)
{
    iso_solver *always = NULL, *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    create_pair(bp, o, &always, &s);
    iso_solver_destroy(always);
    int n = 3 * bp->fm.nv;
    memcpy(x, bp->fm.x, sizeof(double) * (size_t)n);
    assert_int_equal(iso_solver_field(s, x, bp->vc, v, &err), ISO_OK); /* factors */
    for (int i = 0; i < n; i++)
        x[i] += move * v[i];
    return s;
}

/* The field at x by a fresh factorization (the reference). */
static void reference_field(const bumpy *bp, iso_solver_opts o, const double *x, double *ref)
{
    iso_solver *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    o.refactor = ISO_REFACTOR_ALWAYS;
    if (iso_solver_create(bp->m, &bp->r, &o, &s, &err) != ISO_OK)
        fail_msg("iso_solver_create (always): %s", err.msg);
    assert_int_equal(iso_solver_field(s, x, bp->vc, ref, &err), ISO_OK);
    iso_solver_destroy(s);
}

/* PCG's iterations for one solve from guess, and that the cached factor
 * served it within 1e-7 of the reference's largest entry. */
static long solve_counting(iso_solver *s, const bumpy *bp, const double *x, const double *guess,
                           double *v, const double *ref, double top)
{
    iso_solver_stats a, c;
    iso_err err;
    iso_err_clear(&err);
    int n = 3 * bp->fm.nv;
    iso_solver_get_stats(s, &a);
    assert_int_equal(iso_solver_field_from(s, x, bp->vc, guess, v, &err), ISO_OK);
    iso_solver_get_stats(s, &c);
    assert_int_equal(c.factorizations, a.factorizations); /* the cached factor served */
    assert_true(iso_test_max_abs_diff(v, ref, (size_t)n) <= 1e-7 * top);
    return c.cg_iterations - a.cg_iterations;
}

/* iso_solver_field_from: PCG starts from the guess, or from a better
 * combination of it with the solutions the solver remembers
 * (warmstart.c). With no solution remembered: from the exact solution no
 * iteration, from zero more than from the previous solution. Once it has
 * solved this very system, the projection finds that solution again from
 * any guess, zero or a thousand times the field turned around: no
 * iteration; nor from the exact solution scaled by −100, whose scale the
 * projection takes away. With the plain factor: the rotated one preconditions this
 * small turn so well that zero and the previous solution both take 4. */
static void guess_is_where_cg_starts(void **state)
{
    (void)state;
    bumpy bp;
    bumpy_init(&bp);
    int n = 3 * bp.fm.nv;
    double *x = malloc(sizeof(double) * (size_t)n), *far = malloc(sizeof(double) * (size_t)n);
    double *ref = malloc(sizeof(double) * (size_t)n), *v = malloc(sizeof(double) * (size_t)n);
    double *zero = calloc((size_t)n, sizeof(double));
    assert_true(x && far && ref && v && zero);
    iso_solver_opts o = make_opts(1.0 / 3.0, ISO_WEIGHT_PARAM);
    o.preconditioner = ISO_PRECOND_PLAIN;
    /* the previous solution first: it is the one at the point before; the
     * last, the exact solution scaled by −100 (the start's own scale is
     * projected away) */
    const double *starts[4] = {NULL, zero, ref, far};
    long iters[4];
    for (int k = 0; k < 4; k++) {
        iso_solver *s = one_step_solver(&bp, o, 0.02, x, v);
        if (k == 0)
            reference_field(&bp, o, x, ref);
        double top = iso_test_max_abs(ref, (size_t)n);
        if (k == 3)
            for (int i = 0; i < n; i++)
                far[i] = -100 * ref[i];
        iters[k] = solve_counting(s, &bp, x, starts[k], v, ref, top);
        if (k == 0) { /* the same system again: the remembered solution is found */
            for (int i = 0; i < n; i++)
                far[i] = -1e3 * ref[i] + (double)(i % 7) * top;
            assert_int_equal(solve_counting(s, &bp, x, zero, v, ref, top), 0);
            assert_int_equal(solve_counting(s, &bp, x, far, v, ref, top), 0);
        }
        iso_solver_destroy(s);
    }
    printf("CG iterations from the previous solution %ld, zero %ld, the exact solution %ld, "
           "-100 times it %ld\n",
           iters[0], iters[1], iters[2], iters[3]);
    assert_true(iters[0] > 0);
    assert_true(iters[1] > iters[0]);
    assert_int_equal(iters[2], 0);
    assert_int_equal(iters[3], 0);
    free(x);
    free(far);
    free(ref);
    free(v);
    free(zero);
    bumpy_deinit(&bp);
}

/* iso_solver_set_cg_target: PCG stops when z = (LLᵀ)⁻¹ r is within the
 * target at every free vertex and adds z, so the error left against a
 * direct solve is within the target too; a tighter target costs more
 * iterations, and target 0 goes back to cg_tol. Each solve starts from the
 * same guess (the field at the point before), with the factor of that
 * point, on a solver that remembers no other solution. */
static void cg_target_bounds_the_error(void **state)
{
    (void)state;
    bumpy bp;
    bumpy_init(&bp);
    int nv = bp.fm.nv, n = 3 * nv;
    double *x = malloc(sizeof(double) * (size_t)n), *v0 = malloc(sizeof(double) * (size_t)n);
    double *ref = malloc(sizeof(double) * (size_t)n), *v = malloc(sizeof(double) * (size_t)n);
    assert_true(x && v0 && ref && v);
    iso_solver_opts o = make_opts(1.0 / 3.0, ISO_WEIGHT_PARAM);
    iso_err err;
    iso_err_clear(&err);
    o.cg_max_iter = 100; /* the reference factors: no PCG to cap */
    static const double share[4] = {1e-2, 1e-4, 1e-7, 0};
    long iters[4];
    for (int k = 0; k < 4; k++) {
        iso_solver *s = one_step_solver(&bp, o, 0.05, x, v0);
        if (k == 0)
            reference_field(&bp, o, x, ref);
        double top = iso_test_max_abs(ref, (size_t)n),
               start = iso_test_vertex_max_diff(v0, ref, nv);
        iso_solver_stats a, c;
        iso_solver_get_stats(s, &a);
        iso_solver_set_cg_target(s, share[k] * top);
        assert_int_equal(iso_solver_field_from(s, x, bp.vc, v0, v, &err), ISO_OK);
        iso_solver_get_stats(s, &c);
        assert_int_equal(c.factorizations, a.factorizations); /* PCG served each */
        iters[k] = c.cg_iterations - a.cg_iterations;
        double e = iso_test_vertex_max_diff(v, ref, nv);
        printf("CG target %.0e of the field: %ld iterations, error %.3g of the field (start "
               "%.3g)\n",
               share[k], iters[k], e / top, start / top);
        if (share[k] > 0)
            assert_true(e <= share[k] * top);
        else
            assert_true(e <= 1e-7 * top); /* cg_tol 1e-10, as the tests above */
        iso_solver_destroy(s);
    }
    assert_true(iters[0] <= iters[1] && iters[1] < iters[2]);
    free(x);
    free(v0);
    free(ref);
    free(v);
    bumpy_deinit(&bp);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(assembly_matches_distortion),
        cmocka_unit_test(rigid_fields_have_zero_distortion),
        cmocka_unit_test(subdivision_scales_d1_exactly),
        cmocka_unit_test(a_is_psd_with_six_dim_null_space),
        cmocka_unit_test(solver_matches_dense_solve),
        cmocka_unit_test(ill_posed_constraints_are_refused),
        cmocka_unit_test(factor_reuse_matches_refactoring),
        cmocka_unit_test(rotated_factor_is_exact_under_a_turn),
        cmocka_unit_test(factor_at_serves_the_first_evaluation),
        cmocka_unit_test(guess_is_where_cg_starts),
        cmocka_unit_test(cg_target_bounds_the_error),
    };
    return cmocka_run_group_tests_name("system", t, NULL, NULL);
}
