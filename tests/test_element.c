/* tests/test_element.c -- docs/method.md properties 1-3 on single triangles and
 * adjacent pairs (iso_element.h):
 *   (a) a rigid field is in the null space of Q1 and Q2, also far from the
 *       origin, for both weightings;
 *   (b) Q1, Q2 and R equal an independent computation: the best rigid fit by
 *       weighted least squares over the points of Dunavant's degree-5 rule,
 *       then |v − ρ̂|² integrated with the same rule; and the paper's
 *       Section 3.2 relation d_T = hᵀ S h with the corrected off-diagonals;
 *   (c) Q1 and Q2 are symmetric PSD; Q1 has rank 3 and Q2 rank 6.
 *
 * Scale of every tolerance: all quadratic forms here are bounded by vᵀNv
 * ≤ 4σ|v|² (σ = N's scale, 4 = J's largest eigenvalue), and a backward-
 * stable computation of them carries a rounding error of a few eps times
 * that bound. 1e-12 of it leaves a factor ~1e3 for the conditioning of the
 * 6x6 fit on the moderately shaped triangles used, and still catches any
 * wrong coefficient (which shows up at 1e-3 or more). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geom_fixtures.c"
#include "iso_element.h"
#include "testutil.h"

static const iso_weighting WEIGHTINGS[2] = {ISO_WEIGHT_PARAM, ISO_WEIGHT_AREA};

/* A generic triangle, an obtuse one, and a pair's fourth vertex. */
static const double TRI_A[9] = {0.1, 0.2, 0.3, 1.2, -0.1, 0.5, 0.4, 0.9, -0.2};
static const double TRI_OBTUSE[9] = {0, 0, 0, 2, 0, 0, 1.9, 0.3, 0.1};
static const double APEX_A[3] = {0.95, -0.63, 1.28}; /* across edge (0,1) of TRI_A, not coplanar */

/* ---- helpers ------------------------------------------------------------------- */

static double quad_form(int n, const double *Q, const double *v)
{
    double s = 0;
    for (int i = 0; i < n; i++) {
        double r = 0;
        for (int j = 0; j < n; j++)
            r += Q[n * i + j] * v[j];
        s += v[i] * r;
    }
    return s;
}

static double norm2(int n, const double *v)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += v[i] * v[i];
    return s;
}

static double area_of(const double x[9])
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++) {
        a[k] = x[3 + k] - x[k];
        b[k] = x[6 + k] - x[k];
    }
    fx_cross(a, b, c);
    return 0.5 * fx_norm(c);
}

static double sigma_of(const double x[9], iso_weighting w)
{
    return w == ISO_WEIGHT_AREA ? area_of(x) / 12.0 : 1.0 / 24.0;
}

/* Scales x (9) by k about the origin and adds offset d. */
static void place(const double src[9], double k, const double d[3], double dst[9])
{
    for (int i = 0; i < 9; i++)
        dst[i] = k * src[i] + d[i % 3];
}

/* Q2's corner data for the pair Ti = (x0, x1, x2), Tj = (x1, x0, apex). */
static void pair_q2(const double xi[9], const double apex[3], iso_weighting w, double Q[144])
{
    const int jmap[3] = {1, 0, 3};
    assert_int_equal(iso_elem_q2(xi, apex, jmap, w, Q), 0);
}

/* ---- Dunavant's 7-point rule, degree 5, in closed form --------------------------- */

typedef struct quad_rule {
    double b[7][3]; /* barycentric coordinates */
    double w[7];    /* weights, summing to 1 */
} quad_rule;

static quad_rule dunavant7(void)
{
    quad_rule q;
    double s15 = sqrt(15.0);
    double a1 = (6 - s15) / 21, a2 = (6 + s15) / 21;
    double w1 = (155 - s15) / 1200, w2 = (155 + s15) / 1200;
    q.b[0][0] = q.b[0][1] = q.b[0][2] = 1.0 / 3;
    q.w[0] = 9.0 / 40;
    for (int k = 0; k < 3; k++) {
        for (int c = 0; c < 3; c++) {
            q.b[1 + k][c] = c == k ? 1 - 2 * a1 : a1;
            q.b[4 + k][c] = c == k ? 1 - 2 * a2 : a2;
        }
        q.w[1 + k] = w1;
        q.w[4 + k] = w2;
    }
    return q;
}

/* Point (and field value) at barycentric b of a triangle with corners x. */
static void at_bary(const double x[9], const double b[3], double y[3])
{
    for (int c = 0; c < 3; c++)
        y[c] = b[0] * x[c] + b[1] * x[3 + c] + b[2] * x[6 + c];
}

/* The best rigid field ρ(y) = a + β × (y − x0) on triangle x for the linear
 * field v (9), by weighted least squares over the quadrature points (the
 * integrand is quadratic, so a degree-2+ rule gives the exact minimiser).
 * Solved with LAPACK's dposv, not the element code's Cholesky. */
static void fit_by_quadrature(const double x[9], const double v[9], double a[3], double beta[3])
{
    quad_rule q = dunavant7();
    double G[36] = {0}, rhs[6] = {0}, p[6];
    for (int k = 0; k < 7; k++) {
        double y[3], vq[3], Phi[3][6] = {{0}};
        at_bary(x, q.b[k], y);
        at_bary(v, q.b[k], vq);
        for (int c = 0; c < 3; c++)
            y[c] -= x[c];
        /* a + β × y = a − [y]x β */
        for (int c = 0; c < 3; c++)
            Phi[c][c] = 1;
        Phi[0][4] = y[2];
        Phi[0][5] = -y[1];
        Phi[1][3] = -y[2];
        Phi[1][5] = y[0];
        Phi[2][3] = y[1];
        Phi[2][4] = -y[0];
        for (int i = 0; i < 6; i++) {
            for (int j = 0; j < 6; j++)
                for (int c = 0; c < 3; c++)
                    G[6 * i + j] += q.w[k] * Phi[c][i] * Phi[c][j];
            for (int c = 0; c < 3; c++)
                rhs[i] += q.w[k] * Phi[c][i] * vq[c];
        }
    }
    assert_int_equal(fx_spd_solve(6, G, rhs, p), 0);
    memcpy(a, p, 3 * sizeof(double));
    memcpy(beta, p + 3, 3 * sizeof(double));
}

/* ∫ |v − ρ|² over triangle x (param: du dv over the parameter triangle,
 * area: dA), ρ(y) = a + β × (y − o). */
static double residual_integral(const double x[9], const double v[9], const double a[3],
                                const double beta[3], const double o[3], iso_weighting w)
{
    quad_rule q = dunavant7();
    double s = 0;
    for (int k = 0; k < 7; k++) {
        double y[3], vq[3], d[3], r[3];
        at_bary(x, q.b[k], y);
        at_bary(v, q.b[k], vq);
        for (int c = 0; c < 3; c++)
            d[c] = y[c] - o[c];
        fx_cross(beta, d, r);
        double e = 0;
        for (int c = 0; c < 3; c++)
            e += (vq[c] - a[c] - r[c]) * (vq[c] - a[c] - r[c]);
        s += q.w[k] * e;
    }
    /* The parameter triangle has area 1/2. */
    return s * (w == ISO_WEIGHT_AREA ? area_of(x) : 0.5);
}

static void random_vec(fx_rng *rng, int n, double *v)
{
    for (int i = 0; i < n; i++)
        v[i] = fx_uniform(rng, -1, 1);
}

/* A random triangle in [-1,1]³ with quality ≥ 0.3 (so the fit is well
 * conditioned and 1e-12 is a fair tolerance). */
static void random_triangle(fx_rng *rng, double x[9])
{
    for (;;) {
        random_vec(rng, 9, x);
        double l2 = 0;
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++) {
                double d = x[3 * ((k + 1) % 3) + c] - x[3 * k + c];
                l2 += d * d;
            }
        if (4 * sqrt(3.0) * area_of(x) / l2 >= 0.3)
            return;
    }
}

/* ---- (a) rigid fields ---------------------------------------------------------------- */

/* Asserts vᵀQv and |Qv| vanish for the rigid field v (n) = a + b × x_k.
 * vᵀQv: relative 1e-12 to ‖Q‖_max |v|². |Qv| is first order in the
 * rounding of v itself, which is eps (|a| + |b| max|x_k|), not eps |v|, for
 * a triangle far from the origin: the bound is 1e-12 ‖Q‖_max times that. */
static void assert_in_null_space(int n, const double *Q, const double *v, double vscale)
{
    double qmax = iso_test_max_abs(Q, (size_t)n * n);
    double vv = norm2(n, v);
    double Qv[12];
    for (int i = 0; i < n; i++) {
        Qv[i] = 0;
        for (int j = 0; j < n; j++)
            Qv[i] += Q[n * i + j] * v[j];
    }
    double f = quad_form(n, Q, v);
    if (!(fabs(f) <= 1e-12 * qmax * vv))
        fail_msg("rigid field: vᵀQv = %g, bound %g", f, 1e-12 * qmax * vv);
    double bound = 1e-12 * qmax * (sqrt(vv) + vscale);
    if (!(sqrt(norm2(n, Qv)) <= bound))
        fail_msg("rigid field: |Qv| = %g, bound %g", sqrt(norm2(n, Qv)), bound);
}

/* Rigid fields a + b × x on TRI_A and its pair, at the origin and 1e4 away
 * with edges shrunk to ~1e-2: a condition number of (1e4/1e-2)² = 1e12 if
 * the rigid field were parametrised about the origin, which would leave
 * vᵀQv near 1e-8 relative. Two kinds of field far away: rotation about the
 * origin (|v| ~ 1e4 |b|) and rotation about the triangle itself. */
static void rigid_fields_are_null(void **state)
{
    (void)state;
    fx_rng rng = {1};
    const double offsets[3][3] = {{0, 0, 0}, {1e4, -1e4, 1e4}, {-3e4, 2e4, 1e4}};
    const double scales[3] = {1, 1e-2, 1e-2};
    for (int o = 0; o < 3; o++)
        for (int wi = 0; wi < 2; wi++)
            for (int trial = 0; trial < 8; trial++) {
                double xi[9], xo[3], x4[12], Q1[81], Q2[144], v[12];
                place(TRI_A, scales[o], offsets[o], xi);
                for (int c = 0; c < 3; c++)
                    xo[c] = scales[o] * APEX_A[c] + offsets[o][c];
                memcpy(x4, xi, sizeof xi);
                memcpy(x4 + 9, xo, sizeof xo);
                assert_int_equal(iso_elem_q1(xi, WEIGHTINGS[wi], Q1), 0);
                pair_q2(xi, xo, WEIGHTINGS[wi], Q2);
                double a[3], b[3];
                random_vec(&rng, 3, a);
                random_vec(&rng, 3, b);
                if (trial % 2 == 1) { /* rotation about the triangle: a = −b × centroid */
                    double cen[3], bc[3];
                    for (int c = 0; c < 3; c++)
                        cen[c] = (xi[c] + xi[3 + c] + xi[6 + c]) / 3;
                    fx_cross(b, cen, bc);
                    for (int c = 0; c < 3; c++)
                        a[c] = 1e-3 * a[c] - bc[c];
                }
                fx_rigid_field(4, x4, a, b, v);
                double vscale = 3 * (fx_norm(a) + fx_norm(b) * (fx_norm(offsets[o]) + 2));
                assert_in_null_space(9, Q1, v, vscale);
                assert_in_null_space(12, Q2, v, vscale);
            }
}

/* The fit R reproduces a rigid field exactly: E R v = v, i.e. p̂ = (a +
 * b × c, s b) in the (c, s) frame of iso_elem_frame. */
static void rigid_fit_recovers_rigid_field(void **state)
{
    (void)state;
    fx_rng rng = {2};
    for (int trial = 0; trial < 10; trial++) {
        double x[9], R[54], v[9], a[3], b[3], c[3], s, p[6];
        random_triangle(&rng, x);
        random_vec(&rng, 3, a);
        random_vec(&rng, 3, b);
        fx_rigid_field(3, x, a, b, v);
        assert_int_equal(iso_elem_rigid_fit(x, R), 0);
        iso_elem_frame(x, c, &s);
        for (int i = 0; i < 6; i++) {
            p[i] = 0;
            for (int j = 0; j < 9; j++)
                p[i] += R[9 * i + j] * v[j];
        }
        double bc[3];
        fx_cross(b, c, bc);
        double scale = sqrt(norm2(9, v));
        for (int k = 0; k < 3; k++) {
            assert_true(fabs(p[k] - (a[k] + bc[k])) <= 1e-13 * scale);
            assert_true(fabs(p[3 + k] - s * b[k]) <= 1e-13 * scale);
        }
    }
}

/* ---- (b) closed form against quadrature -------------------------------------------- */

/* The rule itself: weights sum to 1 and it integrates u², uv exactly
 * (∫u² = 1/12 · 2·area, ∫uv = 1/24 · 2·area over the reference triangle). */
static void quadrature_rule_is_exact(void **state)
{
    (void)state;
    quad_rule q = dunavant7();
    double sw = 0, su2 = 0, suv = 0, su2v2 = 0;
    for (int k = 0; k < 7; k++) {
        sw += q.w[k];
        su2 += q.w[k] * q.b[k][0] * q.b[k][0];
        suv += q.w[k] * q.b[k][0] * q.b[k][1];
        su2v2 += q.w[k] * q.b[k][0] * q.b[k][0] * q.b[k][1] * q.b[k][1];
    }
    /* Means over the triangle: E[u] = 1/3, E[u²] = 1/6, E[uv] = 1/12,
     * E[u²v²] = 2·2!2!/6! = 1/90 (degree 4, within the rule's 5). */
    assert_true(fabs(sw - 1) <= 1e-15);
    assert_true(fabs(su2 - 1.0 / 6) <= 1e-15);
    assert_true(fabs(suv - 1.0 / 12) <= 1e-15);
    assert_true(fabs(su2v2 - 1.0 / 90) <= 1e-15);
}

static void q1_equals_quadrature(void **state)
{
    (void)state;
    fx_rng rng = {3};
    for (int trial = 0; trial < 12; trial++) {
        double x[9];
        if (trial == 0)
            memcpy(x, TRI_A, sizeof x);
        else if (trial == 1)
            memcpy(x, TRI_OBTUSE, sizeof x);
        else
            random_triangle(&rng, x);
        for (int wi = 0; wi < 2; wi++) {
            double Q[81], v[9], a[3], beta[3];
            assert_int_equal(iso_elem_q1(x, WEIGHTINGS[wi], Q), 0);
            random_vec(&rng, 9, v);
            fit_by_quadrature(x, v, a, beta);
            double ref = residual_integral(x, v, a, beta, x, WEIGHTINGS[wi]);
            double got = quad_form(9, Q, v);
            double bound = 1e-12 * 4 * sigma_of(x, WEIGHTINGS[wi]) * norm2(9, v);
            if (!(fabs(got - ref) <= bound))
                fail_msg("trial %d w %d: vᵀQ1v = %.17g, quadrature %.17g", trial, wi, got, ref);
            /* Not a vacuous comparison: a random field is far from rigid. */
            assert_true(ref > 1e-3 * 4 * sigma_of(x, WEIGHTINGS[wi]) * norm2(9, v));
        }
    }
}

/* R against the quadrature fit, converted to the (c, s) frame. */
static void rigid_fit_equals_quadrature(void **state)
{
    (void)state;
    fx_rng rng = {4};
    for (int trial = 0; trial < 10; trial++) {
        double x[9], v[9], R[54], a[3], beta[3], c[3], s, p[6];
        random_triangle(&rng, x);
        random_vec(&rng, 9, v);
        fit_by_quadrature(x, v, a, beta);
        assert_int_equal(iso_elem_rigid_fit(x, R), 0);
        iso_elem_frame(x, c, &s);
        for (int i = 0; i < 6; i++) {
            p[i] = 0;
            for (int j = 0; j < 9; j++)
                p[i] += R[9 * i + j] * v[j];
        }
        double d[3], bd[3];
        for (int k = 0; k < 3; k++)
            d[k] = c[k] - x[k];
        fx_cross(beta, d, bd);
        for (int k = 0; k < 3; k++) {
            assert_true(fabs(p[k] - (a[k] + bd[k])) <= 1e-12 * sqrt(norm2(9, v)));
            assert_true(fabs(p[3 + k] - s * beta[k]) <= 1e-12 * sqrt(norm2(9, v)));
        }
    }
}

/* f_{i,j}: Ti's quadrature fit, evaluated and integrated over Tj with Tj's
 * measure, against v4ᵀ Q2 v4; and Q2 does not depend on the order in which
 * Tj's corners are listed in jmap. */
static void q2_equals_quadrature(void **state)
{
    (void)state;
    fx_rng rng = {5};
    for (int trial = 0; trial < 12; trial++) {
        double xi[9], xo[3];
        if (trial == 0) {
            memcpy(xi, TRI_A, sizeof xi);
            memcpy(xo, APEX_A, sizeof xo);
        } else {
            random_triangle(&rng, xi);
            /* apex across edge (0,1): mirror corner 2 through the edge's
             * midpoint, then push it off the plane */
            for (int c = 0; c < 3; c++)
                xo[c] = xi[c] + xi[3 + c] - xi[6 + c] + fx_uniform(&rng, -0.3, 0.3);
        }
        double xj[9] = {xi[3], xi[4], xi[5], xi[0], xi[1], xi[2], xo[0], xo[1], xo[2]};
        for (int wi = 0; wi < 2; wi++) {
            double Q[144], v4[12], a[3], beta[3];
            pair_q2(xi, xo, WEIGHTINGS[wi], Q);
            random_vec(&rng, 12, v4);
            fit_by_quadrature(xi, v4, a, beta); /* Ti's corners are v4[0..8] */
            double vj[9] = {v4[3], v4[4], v4[5], v4[0], v4[1], v4[2], v4[9], v4[10], v4[11]};
            double ref = residual_integral(xj, vj, a, beta, xi, WEIGHTINGS[wi]);
            double got = quad_form(12, Q, v4);
            /* The fit of Ti extrapolated over Tj: bounded by a few times
             * Ti's and Tj's energies; 1e-12 of 4σ_j|v4|² as for Q1. */
            double bound = 1e-12 * 4 * sigma_of(xj, WEIGHTINGS[wi]) * norm2(12, v4);
            if (!(fabs(got - ref) <= bound))
                fail_msg("trial %d w %d: v4ᵀQ2v4 = %.17g, quadrature %.17g", trial, wi, got, ref);
            /* jmap order: Tj's corners listed in other orders, same form. */
            const int orders[4][3] = {{0, 3, 1}, {3, 1, 0}, {0, 1, 3}, {3, 0, 1}};
            for (int o = 0; o < 4; o++) {
                double Qo[144];
                assert_int_equal(iso_elem_q2(xi, xo, orders[o], WEIGHTINGS[wi], Qo), 0);
                assert_true(iso_test_max_abs_diff(Q, Qo, 144) <= 1e-13 * iso_test_max_abs(Q, 144));
            }
        }
    }
}

/* Section 3.2: d_T = hᵀ S h with h_k = r_kᵀ(v_{π(k+1)} − v_{π(k)}), r_k =
 * x_{π(k+1)} − x_{π(k)}, π(k) = (k+1) mod 3 (r_k is the edge opposite
 * corner k), r_ij = r_iᵀ r_j, α = 4 area², and, writing ρ_0 = r_12, ρ_1 =
 * r_20, ρ_2 = r_01,
 *   S_kk = c (3 ρ_k² + 4α),  S_kl = c (3 ρ_k ρ_l − 2α) (k ≠ l),
 *   c = −1 / (144 α (r_12 + r_20 + r_01)),
 * i.e. the printed constant and diagonal with docs/method.md's corrected
 * off-diagonals. This is the param reading (d_T is then scale-free). */
static void paper_s_matrix_relation(void **state)
{
    (void)state;
    fx_rng rng = {6};
    for (int trial = 0; trial < 12; trial++) {
        double x[9], Q[81], v[9];
        if (trial == 0)
            memcpy(x, TRI_OBTUSE, sizeof x);
        else
            random_triangle(&rng, x);
        assert_int_equal(iso_elem_q1(x, ISO_WEIGHT_PARAM, Q), 0);
        double r[3][3], h[3];
        random_vec(&rng, 9, v);
        for (int k = 0; k < 3; k++) {
            int p0 = (k + 1) % 3, p1 = (k + 2) % 3;
            double dv[3];
            for (int c = 0; c < 3; c++) {
                r[k][c] = x[3 * p1 + c] - x[3 * p0 + c];
                dv[c] = v[3 * p1 + c] - v[3 * p0 + c];
            }
            h[k] = fx_dot(r[k], dv);
        }
        double cr[3];
        fx_cross(r[0], r[1], cr);
        double alpha = fx_dot(cr, cr);
        double rho[3] = {fx_dot(r[1], r[2]), fx_dot(r[2], r[0]), fx_dot(r[0], r[1])};
        double c = -1.0 / (144 * alpha * (rho[0] + rho[1] + rho[2]));
        double hSh = 0;
        for (int k = 0; k < 3; k++)
            for (int l = 0; l < 3; l++)
                hSh += h[k] * h[l] * c *
                       (k == l ? 3 * rho[k] * rho[k] + 4 * alpha : 3 * rho[k] * rho[l] - 2 * alpha);
        double got = quad_form(9, Q, v);
        double bound = 1e-12 * 4 * sigma_of(x, ISO_WEIGHT_PARAM) * norm2(9, v);
        if (!(fabs(got - hSh) <= bound))
            fail_msg("trial %d: vᵀQ1v = %.17g, hᵀSh = %.17g", trial, got, hSh);
    }
}

/* ---- (c) symmetry, PSD and rank ----------------------------------------------------- */

/* Eigenvalues via dsyev. Q1: six at rounding level (|λ| ≤ 1e-13 λ_max: the
 * entries carry ~1e-16 relative rounding) and three equal to σ, N's scale
 * (1e-13 relative); Q2: six null (the rigid fields of the four vertices,
 * see (a): rank 12 − 6) and six ≥ 1e-2 λ_max (measured worst ratio printed,
 * quality ≥ 0.3 triangles). A mis-scaled block or a wrong fit shows as a
 * negative, misplaced or extra (non-)zero eigenvalue. */
static void blocks_symmetric_psd_with_rank(void **state)
{
    (void)state;
    fx_rng rng = {8};
    double worst_gap2 = INFINITY, worst_null = 0;
    for (int trial = 0; trial < 12; trial++) {
        double xi[9], xo[3];
        random_triangle(&rng, xi);
        for (int c = 0; c < 3; c++)
            xo[c] = xi[c] + xi[3 + c] - xi[6 + c] + fx_uniform(&rng, -0.3, 0.3);
        for (int wi = 0; wi < 2; wi++) {
            double Q1[81], Q2[144], w1[9], w2[12];
            assert_int_equal(iso_elem_q1(xi, WEIGHTINGS[wi], Q1), 0);
            pair_q2(xi, xo, WEIGHTINGS[wi], Q2);
            for (int i = 0; i < 9; i++)
                for (int j = 0; j < 9; j++)
                    assert_true(fabs(Q1[9 * i + j] - Q1[9 * j + i]) <=
                                1e-15 * iso_test_max_abs(Q1, 81));
            for (int i = 0; i < 12; i++)
                for (int j = 0; j < 12; j++)
                    assert_true(fabs(Q2[12 * i + j] - Q2[12 * j + i]) <=
                                1e-15 * iso_test_max_abs(Q2, 144));
            fx_eigvalsh(9, Q1, w1);
            fx_eigvalsh(12, Q2, w2);
            for (int k = 0; k < 6; k++) {
                assert_true(fabs(w1[k]) <= 1e-13 * w1[8]);
                assert_true(fabs(w2[k]) <= 1e-13 * w2[11]);
                worst_null = fmax(worst_null, fmax(fabs(w1[k]) / w1[8], fabs(w2[k]) / w2[11]));
            }
            /* Q1 = σ (I − P_rigid): the rigid fields about the centroid
             * split into translations (N's eigenvalue 4σ) and centred
             * rotations (eigenvalue σ), an N-invariant subspace, so N is σ
             * times the identity on its orthogonal complement. */
            double sg = sigma_of(xi, WEIGHTINGS[wi]);
            for (int k = 6; k < 9; k++)
                assert_true(fabs(w1[k] - sg) <= 1e-13 * sg);
            assert_true(w2[6] >= 1e-2 * w2[11]);
            worst_gap2 = fmin(worst_gap2, w2[6] / w2[11]);
        }
    }
    print_message("Q2 smallest nonzero/largest eigenvalue %.3g; largest |null|/largest %.3g\n",
                  worst_gap2, worst_null);
}

/* ---- (h) one interior edge: both ordered pairs in one block ------------------------- */

/* iso_elem_edge_from_fits against the sum of the two iso_elem_q2_from_fit
 * blocks and the two triangles' iso_elem_q1_from_fit, on random edges and
 * far from the origin: its upper triangle
 * agrees to 1e-13 of the largest entry, and it leaves the lower triangle
 * alone. Ti = (a, b, p) in that order, Tj = (b, a, q); local (a, b, p, q). */
static void edge_block_equals_both_pairs(void **state)
{
    (void)state;
    fx_rng rng = {21};
    double worst = 0;
    for (int trial = 0; trial < 24; trial++) {
        double xl[12];
        random_triangle(&rng, xl);
        for (int c = 0; c < 3; c++)
            xl[9 + c] = xl[c] + xl[3 + c] - xl[6 + c] + fx_uniform(&rng, -0.3, 0.3);
        if (trial % 3 == 2) /* small and far away */
            for (int i = 0; i < 12; i++)
                xl[i] = 1e-2 * xl[i] + (i % 3 == 1 ? -1e4 : 1e4);
        double xi[9], xj[9];
        memcpy(xi, xl, 9 * sizeof(double));
        memcpy(xj, xl + 3, 3 * sizeof(double));     /* b */
        memcpy(xj + 3, xl, 3 * sizeof(double));     /* a */
        memcpy(xj + 6, xl + 9, 3 * sizeof(double)); /* q */
        for (int wi = 0; wi < 2; wi++) {
            iso_elem_fit fi, fj;
            assert_int_equal(iso_elem_fit_compute(xi, &fi), 0);
            assert_int_equal(iso_elem_fit_compute(xj, &fj), 0);
            /* pair (Ti, Tj): Tj's corners b, a, q are Ti's local 1, 0, 3 */
            static const int jm_ij[3] = {1, 0, 3};
            /* pair (Tj, Ti) in Tj's local order (b, a, q, p): Ti's corners
             * a, b, p are Tj's local 1, 0, 3 */
            static const int jm_ji[3] = {1, 0, 3};
            double Qij[144], Qji[144], want[144], got[144];
            iso_elem_q2_from_fit(&fi, xi, xl + 9, jm_ij, WEIGHTINGS[wi], Qij);
            iso_elem_q2_from_fit(&fj, xj, xl + 6, jm_ji, WEIGHTINGS[wi], Qji);
            /* Tj's local order (b, a, q, p) -> (a, b, p, q) */
            static const int to_l[4] = {1, 0, 3, 2};
            for (int i = 0; i < 144; i++)
                want[i] = 0.3 * Qij[i];
            for (int i = 0; i < 12; i++)
                for (int j = 0; j < 12; j++) {
                    int li = 3 * to_l[i / 3] + i % 3, lj = 3 * to_l[j / 3] + j % 3;
                    want[12 * li + lj] += 0.7 * Qji[12 * i + j];
                }
            /* and the triangles' own Q1: Ti on (a, b, p), Tj on (b, a, q) */
            double Q1i[81], Q1j[81];
            iso_elem_q1_from_fit(xi, &fi, WEIGHTINGS[wi], Q1i);
            iso_elem_q1_from_fit(xj, &fj, WEIGHTINGS[wi], Q1j);
            for (int i = 0; i < 9; i++)
                for (int j = 0; j < 9; j++) {
                    int li = 3 * to_l[i / 3] + i % 3, lj = 3 * to_l[j / 3] + j % 3;
                    want[12 * i + j] += 0.2 * Q1i[9 * i + j];
                    want[12 * li + lj] += 0.4 * Q1j[9 * i + j];
                }
            for (int i = 0; i < 144; i++)
                got[i] = -7.0; /* the lower triangle must stay as it was */
            for (int i = 0; i < 12; i++)
                for (int j = i; j < 12; j++)
                    got[12 * i + j] = 0;
            /* q2_from_fit folds its target's σ in; the edge form takes it
             * in its weights */
            double si = sigma_of(xi, WEIGHTINGS[wi]), sj = sigma_of(xj, WEIGHTINGS[wi]);
            iso_elem_fit_core ki, kj;
            iso_elem_fit_core_of(&fi, &ki);
            iso_elem_fit_core_of(&fj, &kj);
            iso_elem_edge_from_fits(&ki, &kj, xl, 0.3 * sj, 0.7 * si, 0.2 * si, 0.4 * sj, got);
            double scale = iso_test_max_abs(want, 144), err = 0;
            for (int i = 0; i < 12; i++)
                for (int j = 0; j < 12; j++) {
                    if (j < i) {
                        assert_true(got[12 * i + j] == -7.0);
                        continue;
                    }
                    err = fmax(err, fabs(got[12 * i + j] - want[12 * i + j]) / scale);
                }
            if (!(err <= 1e-13))
                fail_msg("trial %d (%s): edge block off by %.3e relative", trial,
                         wi ? "area" : "param", err);
            worst = fmax(worst, err);
        }
    }
    print_message("edge block against both pairs: largest difference %.3g relative\n", worst);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(rigid_fields_are_null),
        cmocka_unit_test(rigid_fit_recovers_rigid_field),
        cmocka_unit_test(quadrature_rule_is_exact),
        cmocka_unit_test(q1_equals_quadrature),
        cmocka_unit_test(rigid_fit_equals_quadrature),
        cmocka_unit_test(q2_equals_quadrature),
        cmocka_unit_test(paper_s_matrix_relation),
        cmocka_unit_test(blocks_symmetric_psd_with_rank),
        cmocka_unit_test(edge_block_equals_both_pairs),
    };
    return cmocka_run_group_tests_name("element", t, NULL, NULL);
}
