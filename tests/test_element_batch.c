/* tests/test_element_batch.c -- the C assembly's batches (element_internal.h)
 * keep the promises the assembly relies on:
 *   (a) a batch of fits gives, lane by lane, iso_elem_fit_compute's and
 *       iso_elem_n_scale's values bit for bit, and flags exactly the
 *       triangles iso_elem_fit_compute refuses (so both assembly paths and
 *       the scalar code decide alike which triangle has degenerated), with
 *       a collapsed and a NaN triangle among the lanes;
 *   (b) a batch of edges read by reference gives, lane by lane, the bits of
 *       the same edge computed alone (iso_elem__edge_one with the weights the
 *       assembly uses): no lane depends on the others, the gathers and the
 *       weights are right, and a block flagged for transposition comes out
 *       transposed and otherwise unchanged;
 *   (c) and that edge agrees with the two ordered pairs and the two Q1 of
 *       the scalar forms (iso_elem_q2_from_fit, iso_elem_q1_from_fit) to
 *       1e-13 of the block's largest entry, as test_element's edge test.
 * White-box: it calls the solver's internal batch functions. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../solver/element_internal.h"
#include "geom_fixtures.c"
#include "iso_element.h"
#include "testutil.h"

#define LANES ISO_ELEM__LANES

static const iso_weighting WEIGHTINGS[2] = {ISO_WEIGHT_PARAM, ISO_WEIGHT_AREA};

/* A random triangle's corners in [-1, 1]^3. */
static void random_points(fx_rng *rng, int n, double *x)
{
    for (int i = 0; i < 3 * n; i++)
        x[i] = fx_uniform(rng, -1, 1);
}

/* Positions, 4 doubles a vertex, 64-byte aligned, as the assembly keeps them. */
static double *x4_of(const double *x, int nv)
{
    double *x4 = aligned_alloc(64, (size_t)(nv + 2) / 2 * 2 * 4 * sizeof *x4);
    assert_non_null(x4);
    for (int v = 0; v < nv; v++) {
        memcpy(x4 + 4 * v, x + 3 * v, 3 * sizeof *x);
        x4[4 * v + 3] = 0;
    }
    return x4;
}

/* ---- (a) fits ------------------------------------------------------------------ */

static void fits_are_the_scalar_fits(void **state)
{
    (void)state;
    fx_rng rng = {7};
    enum { NT = 3 * LANES };
    double x[3 * 3 * NT];
    random_points(&rng, 3 * NT, x);
    for (int i = 3 * 3 * LANES; i < 3 * 3 * 2 * LANES; i++) /* batch 2: small and far away */
        x[i] = 1e-2 * x[i] + (i % 3 == 1 ? -1e4 : 1e4);
    memcpy(x + 9 * 5 + 3, x + 9 * 5, 3 * sizeof *x); /* triangle 5 collapsed... */
    memcpy(x + 9 * 5 + 6, x + 9 * 5, 3 * sizeof *x);
    x[9 * 13 + 4] = NAN; /* ...and triangle 13 undefined */
    double *x4 = x4_of(x, 3 * NT);
    double *fits = aligned_alloc(64, NT * ISO_ELEM__FIT_STRIDE * sizeof *fits);
    assert_non_null(fits);
    for (int wi = 0; wi < 2; wi++) {
        int bad = 0;
        for (int b = 0; b < NT / LANES; b++) {
            iso_elem__fit_batch fb = {.x4 = x4, .fits = fits};
            for (int k = 0; k < LANES; k++) {
                int t = LANES * b + k;
                for (int c = 0; c < 3; c++)
                    fb.v[c][k] = 3 * t + c;
                fb.t[k] = t;
            }
            bad |= iso_elem__fits(&fb, WEIGHTINGS[wi]) != 0;
        }
        assert_true(bad);
        for (int t = 0; t < NT; t++) {
            const double *rec = fits + ISO_ELEM__FIT_STRIDE * t;
            iso_elem_fit f;
            int rc = iso_elem_fit_compute(x + 9 * t, &f);
            assert_int_equal(rec[ISO_ELEM__FIT_BAD] != 0, rc != 0);
            assert_int_equal(rc != 0, t == 5 || t == 13);
            if (rc != 0)
                continue;
            double sigma = iso_elem_n_scale(x + 9 * t, WEIGHTINGS[wi]);
            assert_memory_equal(rec + ISO_ELEM__FIT_C, f.c, sizeof f.c);
            assert_memory_equal(rec + ISO_ELEM__FIT_D, f.d, sizeof f.d);
            assert_memory_equal(rec + ISO_ELEM__FIT_W, f.W, sizeof f.W);
            assert_memory_equal(rec + ISO_ELEM__FIT_INVS, &f.inv_s, sizeof f.inv_s);
            assert_memory_equal(rec + ISO_ELEM__FIT_S, &f.s, sizeof f.s);
            assert_memory_equal(rec + ISO_ELEM__FIT_SIGMA, &sigma, sizeof sigma);
        }
    }
    free(x4);
    free(fits);
}

/* ---- (b), (c) edges ------------------------------------------------------------- */

/* Edge e of the test: its four points (a, b, p, q) are vertices 4e..4e+3;
 * Ti = (a, b, p) is triangle 2e, Tj = (b, a, q) triangle 2e + 1. */
static void edge_points(fx_rng *rng, int e, double *x)
{
    double *a = x + 12 * e;
    for (;;) {
        random_points(rng, 3, a);
        for (int c = 0; c < 3; c++)
            a[9 + c] = a[c] + a[3 + c] - a[6 + c] + fx_uniform(rng, -0.3, 0.3);
        /* well-shaped: each triangle's area at least a tenth of its edges' squares */
        double e1[3], e2[3], e3[3], n[3], m[3];
        for (int c = 0; c < 3; c++) {
            e1[c] = a[3 + c] - a[c];
            e2[c] = a[6 + c] - a[c];
            e3[c] = a[9 + c] - a[c];
        }
        fx_cross(e1, e2, n);
        fx_cross(e1, e3, m);
        double l = fx_dot(e1, e1) + fx_dot(e2, e2) + fx_dot(e3, e3);
        if (fx_norm(n) > 0.1 * l && fx_norm(m) > 0.1 * l)
            break;
    }
    if (e % 3 == 2) /* small and far away */
        for (int i = 0; i < 12; i++)
            a[i] = 1e-2 * a[i] + (i % 3 == 1 ? -1e4 : 1e4);
}

/* The scalar forms' block of edge (xl, fits fi, fj of Ti, Tj), weights w
 * (wi, wj, qi, qj), upper triangle of want: test_element's reference. */
static void reference_block(const double xl[12], const double w[4], iso_weighting wt,
                            double want[144])
{
    double xi[9], xj[9], Qij[144], Qji[144], Q1i[81], Q1j[81];
    memcpy(xi, xl, 9 * sizeof *xi);
    memcpy(xj, xl + 3, 3 * sizeof *xj);
    memcpy(xj + 3, xl, 3 * sizeof *xj);
    memcpy(xj + 6, xl + 9, 3 * sizeof *xj);
    iso_elem_fit fi, fj;
    assert_int_equal(iso_elem_fit_compute(xi, &fi), 0);
    assert_int_equal(iso_elem_fit_compute(xj, &fj), 0);
    static const int jm[3] = {1, 0, 3}, to_l[4] = {1, 0, 3, 2};
    iso_elem_q2_from_fit(&fi, xi, xl + 9, jm, wt, Qij);
    iso_elem_q2_from_fit(&fj, xj, xl + 6, jm, wt, Qji);
    iso_elem_q1_from_fit(xi, &fi, wt, Q1i);
    iso_elem_q1_from_fit(xj, &fj, wt, Q1j);
    /* q2_from_fit and q1_from_fit fold σ in; the edge takes it in w */
    double si = iso_elem_n_scale(xi, wt), sj = iso_elem_n_scale(xj, wt);
    for (int i = 0; i < 144; i++)
        want[i] = w[0] / sj * Qij[i];
    for (int i = 0; i < 12; i++)
        for (int j = 0; j < 12; j++)
            want[12 * (3 * to_l[i / 3] + i % 3) + 3 * to_l[j / 3] + j % 3] +=
                w[1] / si * Qji[12 * i + j];
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < 9; j++) {
            want[12 * i + j] += w[2] / si * Q1i[9 * i + j];
            want[12 * (3 * to_l[i / 3] + i % 3) + 3 * to_l[j / 3] + j % 3] +=
                w[3] / sj * Q1j[9 * i + j];
        }
}

/* Value (i, j) of block (l, m) of lane k, in the block's own orientation. */
static double block_value(const iso_elem__vd *q, int k, int l, int m, int i, int j, int tr)
{
    const iso_elem__vd *v = q + iso_elem__edge_block(l, m);
    if (l == m) {
        static const int at[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
        return v[at[i][j]][k];
    }
    return tr ? v[3 * j + i][k] : v[3 * i + j][k];
}

static void edges_lane_by_lane(void **state)
{
    (void)state;
    fx_rng rng = {11};
    const double omega = 0.37;
    double x[12 * LANES];
    for (int e = 0; e < LANES; e++)
        edge_points(&rng, e, x);
    double *x4 = x4_of(x, 4 * LANES);
    double *fits = aligned_alloc(64, 2 * LANES * ISO_ELEM__FIT_STRIDE * sizeof *fits);
    assert_non_null(fits);
    double worst = 0;
    for (int wi = 0; wi < 2; wi++) {
        /* the fits of the 2 LANES triangles, in two batches */
        for (int b = 0; b < 2; b++) {
            iso_elem__fit_batch fb = {.x4 = x4, .fits = fits};
            for (int k = 0; k < LANES; k++) {
                int t = LANES * b + k, e = t / 2;
                static const int corner[2][3] = {{0, 1, 2}, {1, 0, 3}};
                for (int c = 0; c < 3; c++)
                    fb.v[c][k] = 4 * e + corner[t % 2][c];
                fb.t[k] = t;
            }
            assert_int_equal(iso_elem__fits(&fb, WEIGHTINGS[wi]), 0);
        }
        iso_elem__edge_batch eb = {.x4 = x4, .fits = fits, .omega = omega};
        for (int k = 0; k < LANES; k++) {
            for (int l = 0; l < 4; l++)
                eb.v[l][k] = 4 * k + l;
            eb.ti[k] = 2 * k;
            eb.tj[k] = 2 * k + 1;
            /* every combination of the carries, and transpositions */
            eb.flags[k] = (k & 1 ? ISO_ELEM__EDGE_CARRY_I : 0) |
                          (k & 2 ? ISO_ELEM__EDGE_CARRY_J : 0) | (37 * (k + 1) & 63);
        }
        iso_elem__edges(&eb);
        for (int k = 0; k < LANES; k++) {
            const double *fi = fits + ISO_ELEM__FIT_STRIDE * 2 * k, *fj = fi + ISO_ELEM__FIT_STRIDE;
            double si = fi[ISO_ELEM__FIT_SIGMA], sj = fj[ISO_ELEM__FIT_SIGMA];
            const double w[4] = {omega * sj, omega * si, k & 1 ? (1.0 - omega) * si : 0.0,
                                 k & 2 ? (1.0 - omega) * sj : 0.0};
            iso_elem__vd one[ISO_ELEM__EDGE_VALUES];
            iso_elem__edge_one(x + 12 * k, fi, fj, w, one);
            double want[144], scale = 0, err = 0;
            reference_block(x + 12 * k, w, WEIGHTINGS[wi], want);
            for (int i = 0; i < 144; i++)
                scale = fmax(scale, fabs(want[i]));
            for (int l = 0, o = 0; l < 4; l++)
                for (int m = l; m < 4; m++) {
                    int tr = l != m && (eb.flags[k] >> o++ & 1);
                    for (int i = 0; i < 3; i++)
                        for (int j = l == m ? i : 0; j < 3; j++) {
                            double got = block_value(eb.q, k, l, m, i, j, tr);
                            double alone = block_value(one, 0, l, m, i, j, 0);
                            if (memcmp(&got, &alone, sizeof got) != 0)
                                fail_msg("lane %d block (%d, %d) value (%d, %d): %.17g in the "
                                         "batch, %.17g alone",
                                         k, l, m, i, j, got, alone);
                            err = fmax(err, fabs(got - want[12 * (3 * l + i) + 3 * m + j]));
                        }
                }
            if (!(err <= 1e-13 * scale))
                fail_msg("lane %d (%s): off the scalar forms by %.3e relative", k,
                         wi ? "area" : "param", err / scale);
            worst = fmax(worst, err / scale);
        }
    }
    print_message("batched edges against the scalar forms: largest difference %.3g relative\n",
                  worst);
    free(x4);
    free(fits);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(fits_are_the_scalar_fits),
        cmocka_unit_test(edges_lane_by_lane),
    };
    return cmocka_run_group_tests_name("element_batch", t, NULL, NULL);
}
