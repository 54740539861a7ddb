/* tests/test_arap.c -- the ARAP baseline (iso_arap.h): the closest
 * rotation, rigid motions reproduced, the energy never rising, the rest
 * pose kept bit for bit, and ill-posed constraints refused. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geom_fixtures.c"
#include "iso_arap.h"
#include "testutil.h"

/* An open tube of radius 1 along z from 0 to h: nr rings of na vertices,
 * odd rings turned by half a step so the triangles are nearly equilateral
 * (no obtuse angle, so no weight is clamped). Ring k is vertices
 * k*na .. k*na+na-1. */
static fx_mesh tube(int na, int nr, double h)
{
    fx_mesh m = {na * nr, 2 * na * (nr - 1), NULL, NULL};
    m.x = malloc(sizeof(double) * 3 * (size_t)m.nv);
    m.tri = malloc(sizeof(int) * 3 * (size_t)m.nt);
    assert_non_null(m.x);
    assert_non_null(m.tri);
    const double pi = acos(-1.0);
    for (int k = 0; k < nr; k++)
        for (int a = 0; a < na; a++) {
            double th = 2 * pi * (a + 0.5 * (k % 2)) / na;
            double *p = m.x + 3 * (k * na + a);
            p[0] = cos(th);
            p[1] = sin(th);
            p[2] = h * k / (nr - 1);
        }
    int t = 0;
    for (int k = 0; k + 1 < nr; k++)
        for (int a = 0; a < na; a++) {
            int b = (a + 1) % na;
            int i0 = k * na + a, i1 = k * na + b, j0 = (k + 1) * na + a, j1 = (k + 1) * na + b;
            /* even rows: the upper ring is shifted forward; odd rows: the lower */
            const int even[6] = {i0, i1, j0, i1, j1, j0}, odd[6] = {i0, j1, j0, i0, i1, j1};
            memcpy(m.tri + 3 * t, k % 2 == 0 ? even : odd, sizeof even);
            t += 2;
        }
    return m;
}

/* Bottom ring fixed, top ring on the handle, the rest free. */
static void tube_regions(iso_regions *r, int na, int nr)
{
    unsigned char *kind = malloc((size_t)(na * nr));
    assert_non_null(kind);
    for (int i = 0; i < na * nr; i++)
        kind[i] = i < na ? ISO_FIXED : i >= na * (nr - 1) ? ISO_HANDLE : ISO_FREE;
    fx_regions(r, na * nr, kind);
    free(kind);
}

static void apply(const double R[9], const double t[3], const double *x, double *y)
{
    for (int a = 0; a < 3; a++)
        y[a] = R[3 * a] * x[0] + R[3 * a + 1] * x[1] + R[3 * a + 2] * x[2] + t[a];
}

static void matmul(const double A[9], const double B[9], double C[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

static double det3(const double A[9])
{
    return A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
           A[2] * (A[3] * A[7] - A[4] * A[6]);
}

/* ===== closest rotation ================================================= */

/* M = R0·S (S symmetric positive semidefinite, or with its smallest
 * eigenvalue negative) has closest rotation R0. */
static void closest_rotation_recovers_the_rotation_factor(void **state)
{
    (void)state;
    double axis[3] = {1 / sqrt(3.0), -1 / sqrt(3.0), 1 / sqrt(3.0)}, R0[9], Q[9], QT[9];
    fx_rotation(axis, 2.1, R0);
    double ax2[3] = {0, 0.6, 0.8};
    fx_rotation(ax2, -0.7, Q);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            QT[3 * i + j] = Q[3 * j + i];
    /* diagonal parts: generic, isotropic pair, rank 2 (flat one-ring),
     * smallest negative (a reflected one-ring), tiny scale */
    const double D[5][3] = {
        {3, 2, 1}, {1, 1, 0.3}, {2, 0.5, 0}, {2, 1, -0.1}, {3e-200, 2e-200, 1e-200}};
    for (int c = 0; c < 5; c++) {
        double S[9] = {0}, T[9], M[9], R[9];
        double Dm[9] = {D[c][0], 0, 0, 0, D[c][1], 0, 0, 0, D[c][2]};
        matmul(Q, Dm, T);
        matmul(T, QT, S);
        matmul(R0, S, M);
        iso_arap_closest_rotation(M, R);
        for (int k = 0; k < 9; k++)
            assert_true(fabs(R[k] - R0[k]) <= 1e-13);
    }
    double Z[9] = {0}, R[9];
    iso_arap_closest_rotation(Z, R);
    for (int k = 0; k < 9; k++)
        assert_true(R[k] == (k % 4 == 0));
}

/* Random matrices (half of them with det < 0): R is a rotation and no
 * nearby rotation does better on tr(Rᵀ M). */
static void closest_rotation_is_a_rotation_and_optimal(void **state)
{
    (void)state;
    fx_rng rng = {42};
    for (int trial = 0; trial < 500; trial++) {
        double M[9], R[9], RtR[9], Rt[9];
        for (int k = 0; k < 9; k++)
            M[k] = fx_uniform(&rng, -1, 1);
        iso_arap_closest_rotation(M, R);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                Rt[3 * i + j] = R[3 * j + i];
        matmul(Rt, R, RtR);
        for (int k = 0; k < 9; k++)
            assert_true(fabs(RtR[k] - (k % 4 == 0)) <= 1e-14);
        assert_true(fabs(det3(R) - 1) <= 1e-14);
        double best = 0;
        for (int k = 0; k < 9; k++)
            best += R[k] * M[k];
        for (int p = 0; p < 6; p++) {
            double a[3] = {p % 3 == 0, p % 3 == 1, p % 3 == 2}, E[9], RE[9], tr = 0;
            fx_rotation(a, p < 3 ? 1e-4 : -1e-4, E);
            matmul(R, E, RE);
            for (int k = 0; k < 9; k++)
                tr += RE[k] * M[k];
            assert_true(tr <= best + 1e-15);
        }
    }
}

/* ===== solves ============================================================ */

typedef struct problem {
    fx_mesh fm;
    iso_mesh *m;
    iso_regions r;
    double *xc, *x;
    int na, nr;
} problem;

static void problem_tube(problem *p, int na, int nr, double h)
{
    memset(p, 0, sizeof *p);
    p->na = na, p->nr = nr;
    p->fm = tube(na, nr, h);
    p->m = fx_make(&p->fm);
    tube_regions(&p->r, na, nr);
    p->xc = malloc(sizeof(double) * 3 * (size_t)p->fm.nv);
    p->x = malloc(sizeof(double) * 3 * (size_t)p->fm.nv);
    assert_non_null(p->xc);
    assert_non_null(p->x);
    memcpy(p->xc, p->fm.x, sizeof(double) * 3 * (size_t)p->fm.nv);
}

static void problem_free(problem *p)
{
    iso_mesh_destroy(p->m);
    iso_regions_deinit(&p->r);
    fx_mesh_free(&p->fm);
    free(p->xc);
    free(p->x);
}

/* Every constrained vertex, fixed ones too, moved by one rotation and
 * translation: the ARAP minimum is that rigid motion (E = 0), and the
 * iteration must reach it for every vertex. */
static void rigid_constraints_give_the_rigid_motion(void **state)
{
    (void)state;
    problem p;
    problem_tube(&p, 16, 9, 2.0);
    double axis[3] = {0.48, 0.6, 0.64}, R0[9], t[3] = {0.3, -1.2, 0.7};
    fx_rotation(axis, 1.1, R0);
    int nv = p.fm.nv;
    double *want = malloc(sizeof(double) * 3 * (size_t)nv);
    assert_non_null(want);
    for (int i = 0; i < nv; i++)
        apply(R0, t, p.fm.x + 3 * i, want + 3 * i);
    for (int i = 0; i < nv; i++)
        if (p.r.kind[i] != ISO_FREE)
            memcpy(p.xc + 3 * i, want + 3 * i, 3 * sizeof(double));
    iso_err err;
    iso_err_clear(&err);
    iso_arap_stats st = {0};
    int rc = iso_arap_solve(p.m, &p.r, p.xc, 1000, 1e-15, p.x, &st, &err);
    assert_int_equal(rc, ISO_OK);
    double bbox = iso_mesh_bbox_diagonal(p.m);
    double e = iso_test_max_abs_diff(p.x, want, 3 * (size_t)nv);
    print_message("rigid: %d iterations, energy %.3g -> %.3g, max error %.3g (bbox %.3g)\n",
                  st.iterations, st.energy_initial, st.energy, e, bbox);
    assert_true(e <= 1e-9 * bbox);
    assert_int_equal(st.n_clamped, 0);
    assert_int_equal(st.n_free, nv - 2 * p.na);
    free(want);
    problem_free(&p);
}

/* A large bend (the handle ring turned 90° about an axis across the top):
 * neither the local nor the global step may raise the energy. */
static void energy_never_rises(void **state)
{
    (void)state;
    problem p;
    problem_tube(&p, 20, 17, 4.0);
    double axis[3] = {0, 1, 0}, R0[9], c[3] = {0, 0, 4.0}, t[3];
    const double pi = acos(-1.0);
    fx_rotation(axis, pi / 2, R0);
    for (int a = 0; a < 3; a++) /* rotate about c: y = R0 (x − c) + c */
        t[a] = c[a] - (R0[3 * a] * c[0] + R0[3 * a + 1] * c[1] + R0[3 * a + 2] * c[2]);
    for (int i = 0; i < p.fm.nv; i++)
        if (p.r.kind[i] == ISO_HANDLE)
            apply(R0, t, p.fm.x + 3 * i, p.xc + 3 * i);
    double hist[300];
    iso_arap_stats st = {.energy_history = hist, .energy_cap = 300};
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_arap_solve(p.m, &p.r, p.xc, 300, 0.0, p.x, &st, &err);
    assert_int_equal(rc, ISO_OK);
    assert_int_equal(st.history_len, st.iterations);
    assert_true(st.iterations >= 50);
    /* Rounding: each energy is a sum of ~3·ne terms of size up to E_0. */
    double tol = 1e-12 * st.energy_initial;
    assert_true(hist[0] <= st.energy_initial + tol);
    for (int k = 1; k < st.history_len; k++)
        if (hist[k] > hist[k - 1] + tol)
            fail_msg("energy rose at iteration %d: %.17g -> %.17g", k + 1, hist[k - 1], hist[k]);
    /* and it did descend: here about 51 -> 5.9 -> 3.06 */
    assert_true(hist[st.history_len - 1] < 0.75 * hist[0]);
    assert_true(st.energy == hist[st.history_len - 1]);
    print_message("bend: E0 %.6g, E1 %.6g, E%d %.6g\n", st.energy_initial, hist[0], st.iterations,
                  st.energy);
    problem_free(&p);
}

/* Targets at the rest positions: the rest pose comes back bit for bit,
 * with zero energy, and the iteration stops at the second step. */
static void no_motion_returns_the_rest_pose_exactly(void **state)
{
    (void)state;
    problem p;
    problem_tube(&p, 12, 7, 1.5);
    iso_arap_stats st = {0};
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_arap_solve(p.m, &p.r, p.xc, 100, 1e-12, p.x, &st, &err);
    assert_int_equal(rc, ISO_OK);
    assert_memory_equal(p.x, p.fm.x, sizeof(double) * 3 * (size_t)p.fm.nv);
    assert_true(st.energy == 0.0);
    assert_true(st.energy_initial == 0.0);
    assert_int_equal(st.iterations, 2);
    assert_int_equal(st.converged, 1);
    problem_free(&p);
}

/* ===== refusals ========================================================== */

static void expect_refusal(const iso_mesh *m, const iso_regions *r, const double *xc, int iters,
                           double tol, int code, const char *needle)
{
    int nv = iso_mesh_vertex_count(m);
    double *x = malloc(sizeof(double) * 3 * (size_t)nv);
    assert_non_null(x);
    for (int k = 0; k < 3 * nv; k++)
        x[k] = -7.0;
    iso_err err;
    iso_err_clear(&err);
    iso_arap_stats st = {0};
    int rc = iso_arap_solve(m, r, xc, iters, tol, x, &st, &err);
    assert_int_equal(rc, code);
    assert_int_equal(err.code, code);
    if (!strstr(err.msg, needle))
        fail_msg("message \"%s\" lacks \"%s\"", err.msg, needle);
    for (int k = 0; k < 3 * nv; k++) /* the output is untouched on failure */
        assert_true(x[k] == -7.0);
    free(x);
}

/* No fixed or handle vertex: translation is free, so the Laplacian is
 * singular. Refused before any factorization, with a sentence saying so. */
static void constraint_free_mesh_is_refused(void **state)
{
    (void)state;
    fx_mesh g = fx_grid(6, 5, 1.0, 0.8);
    iso_mesh *m = fx_make(&g);
    unsigned char kind[30];
    memset(kind, ISO_FREE, sizeof kind);
    iso_regions r;
    fx_regions(&r, g.nv, kind);
    expect_refusal(m, &r, g.x, 10, 1e-9, ISO_ECONSTRAINT,
                   "fixture: ARAP needs at least one fixed or handle vertex, but all 30 "
                   "vertices are free");
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    fx_mesh_free(&g);
}

/* Two separate sheets, constraints only on the first: the second's free
 * vertices are named. */
static void unconstrained_part_is_refused(void **state)
{
    (void)state;
    fx_mesh g = fx_grid(4, 4, 1.0, 1.0), h = fx_grid(3, 3, 1.0, 1.0);
    double d[3] = {5, 0, 0};
    fx_translate(&h, d);
    fx_append(&g, &h);
    iso_mesh *m = fx_make(&g);
    unsigned char kind[25];
    memset(kind, ISO_FREE, sizeof kind);
    kind[0] = ISO_FIXED;
    kind[15] = ISO_HANDLE;
    iso_regions r;
    fx_regions(&r, g.nv, kind);
    expect_refusal(m, &r, g.x, 10, 1e-9, ISO_ECONSTRAINT,
                   "fixture: free vertex 16 is not linked to any fixed or handle vertex");
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    fx_mesh_free(&g);
    fx_mesh_free(&h);
}

static void bad_arguments_are_refused(void **state)
{
    (void)state;
    problem p;
    problem_tube(&p, 8, 4, 1.0);
    expect_refusal(p.m, &p.r, p.xc, 0, 1e-9, ISO_EINVAL, "at least one iteration");
    expect_refusal(p.m, &p.r, p.xc, 10, -1.0, ISO_EINVAL, "tolerance must be finite and >= 0");
    p.xc[3 * 30 + 1] = NAN; /* a handle vertex (top ring is 24..31) */
    expect_refusal(p.m, &p.r, p.xc, 10, 1e-9, ISO_EINVAL,
                   "fixture: the target of handle vertex 30 is not finite (coordinate 1)");
    p.xc[3 * 30 + 1] = 0;
    p.xc[3 * 12] = NAN; /* a free vertex: its target is never read */
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_arap_solve(p.m, &p.r, p.xc, 10, 1e-9, p.x, NULL, &err), ISO_OK);
    assert_int_equal(iso_arap_solve(NULL, &p.r, p.xc, 10, 1e-9, p.x, NULL, &err), ISO_EINVAL);
    problem_free(&p);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(closest_rotation_recovers_the_rotation_factor),
        cmocka_unit_test(closest_rotation_is_a_rotation_and_optimal),
        cmocka_unit_test(rigid_constraints_give_the_rigid_motion),
        cmocka_unit_test(energy_never_rises),
        cmocka_unit_test(no_motion_returns_the_rest_pose_exactly),
        cmocka_unit_test(constraint_free_mesh_is_refused),
        cmocka_unit_test(unconstrained_part_is_refused),
        cmocka_unit_test(bad_arguments_are_refused),
    };
    return cmocka_run_group_tests_name("arap", t, NULL, NULL);
}
