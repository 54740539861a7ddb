/* solver/element.c -- per-element quadratic forms (iso_element.h).
 *
 * Notation follows docs/method.md (sections 2 and 3). N_T = σ (J ⊗ I3)
 * with J = [[2,1,1], [1,2,1],[1,1,2]]; σ = 1/24 (param) or A_T/12 (area).
 * The best rigid fit does not depend on σ, so R is computed with σ = 1 and
 * σ enters Q only. */
#include "element_internal.h"
#include "iso_element.h"

#include <math.h>
#include <string.h>

#define FIT_T double
#define FIT_MASK int
#define FIT_SQRT sqrt
#include "element_fit.h"

const char *const iso_weighting_names[] = {"param", "area", NULL};

/* GCC at -O2 keeps 3-trip loops as loops; unrolled in the assembly's hot
 * paths, their indices and branches fold to constants (at up to three
 * times fewer instructions). */
#if defined(__GNUC__) && !defined(__clang__)
#define UNROLL3 _Pragma("GCC unroll 3")
#else
#define UNROLL3
#endif

static const double J3[3][3] = {{2, 1, 1}, {1, 2, 1}, {1, 1, 2}};

void iso_elem_frame(const double x[9], double c[3], double *s)
{
    fit_centre(x, c, s);
}

double iso_elem_n_scale(const double x[9], iso_weighting w)
{
    if (w != ISO_WEIGHT_AREA)
        return 1.0 / 24.0;
    double area;
    fit_area(x, &area);
    return area / 12.0;
}

void iso_elem_eval_matrix(const double x[9], const double c[3], double s, double E[54])
{
    memset(E, 0, 54 * sizeof(double));
    for (int k = 0; k < 3; k++) {
        double r[3] = {(x[3 * k] - c[0]) / s, (x[3 * k + 1] - c[1]) / s, (x[3 * k + 2] - c[2]) / s};
        double *row = E + 3 * k * 6;
        /* ρ = a + b × r = a − [r]x b: block [I, −[r]x] */
        for (int a = 0; a < 3; a++)
            row[6 * a + a] = 1.0;
        row[0 * 6 + 4] = r[2];
        row[0 * 6 + 5] = -r[1];
        row[1 * 6 + 3] = -r[2];
        row[1 * 6 + 5] = r[0];
        row[2 * 6 + 3] = r[1];
        row[2 * 6 + 4] = -r[0];
    }
}

/* Y = (J ⊗ I3) X for X with 9 rows and `cols` columns. */
static void apply_j(const double *X, int cols, double *Y)
{
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++)
            for (int col = 0; col < cols; col++) {
                double acc = 0;
                for (int l = 0; l < 3; l++)
                    acc += J3[k][l] * X[(3 * l + a) * cols + col];
                Y[(3 * k + a) * cols + col] = acc;
            }
}

/* In-place Cholesky of a 6x6 SPD matrix (lower triangle); -1 if not PD. */
static int cholesky6(double G[36])
{
    for (int j = 0; j < 6; j++) {
        double d = G[6 * j + j];
        for (int k = 0; k < j; k++)
            d -= G[6 * j + k] * G[6 * j + k];
        if (!(d > 0))
            return -1;
        d = sqrt(d);
        G[6 * j + j] = d;
        for (int i = j + 1; i < 6; i++) {
            double v = G[6 * i + j];
            for (int k = 0; k < j; k++)
                v -= G[6 * i + k] * G[6 * j + k];
            G[6 * i + j] = v / d;
        }
    }
    return 0;
}

/* Solves (L Lᵀ) y = b in place for a factor from cholesky6. */
static void cholesky6_solve(const double L[36], double b[6])
{
    for (int i = 0; i < 6; i++) {
        double v = b[i];
        for (int k = 0; k < i; k++)
            v -= L[6 * i + k] * b[k];
        b[i] = v / L[6 * i + i];
    }
    for (int i = 5; i >= 0; i--) {
        double v = b[i];
        for (int k = i + 1; k < 6; k++)
            v -= L[6 * k + i] * b[k];
        b[i] = v / L[6 * i + i];
    }
}

/* R = (Eᵀ J E)^{-1} (J E)ᵀ, and JE = (J⊗I) E as a by-product. */
static int rigid_fit_from_e(const double E[54], double R[54], double JE[54])
{
    double G[36];
    apply_j(E, 6, JE);
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 6; j++) {
            double acc = 0;
            for (int r = 0; r < 9; r++)
                acc += E[6 * r + i] * JE[6 * r + j];
            G[6 * i + j] = acc;
        }
    if (cholesky6(G) != 0)
        return -1;
    for (int col = 0; col < 9; col++) {
        double b[6];
        for (int i = 0; i < 6; i++)
            b[i] = JE[6 * col + i];
        cholesky6_solve(G, b);
        for (int i = 0; i < 6; i++)
            R[9 * i + col] = b[i];
    }
    return 0;
}

int iso_elem_rigid_fit(const double x[9], double R[54])
{
    double c[3], s, E[54], JE[54];
    iso_elem_frame(x, c, &s);
    if (!(s > 0))
        return -1;
    iso_elem_eval_matrix(x, c, s, E);
    return rigid_fit_from_e(E, R, JE);
}

/* ===== closed forms for the assembly ===================================
 *
 * With corners r_k = (x_k − c)/s about the centroid, E's normal matrix is
 * Eᵀ(J⊗I)E = diag(12 I, S), S = Σ_k (|r_k|² I − r_k r_kᵀ) (the cross terms
 * vanish because Σ r_k = 0), so the best rigid fit is
 *     R = [I/3 I/3 I/3; B_0 B_1 B_2],  B_l = W [r_l]×,  W = S⁻¹,
 * a 3x3 inverse instead of a 6x6 solve with nine right-hand sides. The
 * OpenCL kernels (assemble_cl_kernels.h) use the same forms. */

/* ([a]× B)_ij = (a × B[:, j])_i for a 3x3 row-major B. */
static inline void cross_mat(const double a[3], const double B[9], double C[9])
{
    UNROLL3 for (int j = 0; j < 3; j++)
    {
        C[j] = a[1] * B[6 + j] - a[2] * B[3 + j];
        C[3 + j] = a[2] * B[j] - a[0] * B[6 + j];
        C[6 + j] = a[0] * B[3 + j] - a[1] * B[j];
    }
}

/* C = Aᵀ B for 3x3 row-major A, B. */
static void mul_tn3(const double A[9], const double B[9], double C[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[i] * B[j] + A[3 + i] * B[3 + j] + A[6 + i] * B[6 + j];
}

/* C = A B for 3x3 row-major A, B. */
static void mul_nn3(const double A[9], const double B[9], double C[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* Block l of R's lower half, B_l = W [r_l]×, as it sits in R (6x9). */
static inline void fit_block(const double R[54], int l, double B[9])
{
    UNROLL3 for (int i = 0; i < 3; i++) UNROLL3 for (int j = 0; j < 3; j++) B[3 * i + j] =
        R[9 * (3 + i) + 3 * l + j];
}

/* Points x (n of them) in the fit's frame: (x − c)/s − δ, where δ is the
 * mean of the triangle's own scaled corners. The closed forms rely on the
 * corners summing to zero; the rounded centroid c leaves them summing to
 * ~eps |c| / s, 1e-10 for a 1e-2 triangle 1e4 from the origin, enough to
 * break the null space of translations at that level. Subtracting δ from
 * every point, the triangle's and its neighbours' alike, moves the frame's
 * centre to the exact centroid of the scaled corners. The scaling is by
 * 1/s, one division per fit instead of one per coordinate (the assembly's
 * divisions were a tenth of its time). */
static inline void frame_points(const iso_elem_fit *f, const double *x, int n, double *r)
{
    for (int k = 0; k < n; k++)
        UNROLL3 for (int a = 0; a < 3; a++) r[3 * k + a] =
            (x[3 * k + a] - f->c[a]) * f->inv_s - f->d[a];
}

int iso_elem_fit_compute(const double x[9], iso_elem_fit *f)
{
    double r[9];
    int ok;
    fit_triangle(x, f->c, &f->s, &f->inv_s, f->d, r, f->W, &ok);
    if (!ok)
        return -1;
    const double *u = f->W;
    double W[9] = {u[0], u[1], u[2], u[1], u[3], u[4], u[2], u[4], u[5]};
    double *R = f->R;
    memset(R, 0, 27 * sizeof(double));
    for (int l = 0; l < 3; l++) {
        for (int a = 0; a < 3; a++)
            R[9 * a + 3 * l + a] = 1.0 / 3.0;
        const double *q = r + 3 * l;
        /* B_l = W [r_l]×: row i is W's row i crossed with r_l. */
        for (int i = 0; i < 3; i++) {
            const double *wi = W + 3 * i;
            double *row = R + 9 * (3 + i) + 3 * l;
            row[0] = wi[1] * q[2] - wi[2] * q[1];
            row[1] = wi[2] * q[0] - wi[0] * q[2];
            row[2] = wi[0] * q[1] - wi[1] * q[0];
        }
    }
    return 0;
}

/* Q1 block (k, l) = σ ((J_kl − 4/3) I + [r_k]× B_l): N − N E R with the fit
 * above written out; only the upper blocks are computed, then mirrored. */
void iso_elem_q1_from_fit(const double x[9], const iso_elem_fit *f, iso_weighting w, double Q[81])
{
    double sigma = iso_elem_n_scale(x, w), r[9], B[27];
    frame_points(f, x, 3, r);
    UNROLL3 for (int l = 0; l < 3; l++) fit_block(f->R, l, B + 9 * l);
    UNROLL3 for (int k = 0; k < 3; k++) UNROLL3 for (int l = k; l < 3; l++)
    {
        double C[9];
        cross_mat(r + 3 * k, B + 9 * l, C);
        double jk = k == l ? 2.0 / 3.0 : -1.0 / 3.0;
        UNROLL3 for (int i = 0; i < 3; i++) UNROLL3 for (int j = (k == l ? i : 0); j < 3; j++)
        {
            double v = sigma * ((i == j ? jk : 0.0) + C[3 * i + j]);
            Q[9 * (3 * k + i) + 3 * l + j] = Q[9 * (3 * l + j) + 3 * k + i] = v;
        }
    }
}

/* Q2 in closed form. With M = P − E_j R (9x12) split into 3x3 blocks
 * M_kl = c_kl I + D_kl, c_kl = [jmap_k = l] − [l < 3]/3 and D_kl = [q_k]× B_l
 * (q_k: Tj's corner k in Ti's frame; B_3 = 0, the fourth vertex has no
 * part in Ti's fit), and J = I + 11ᵀ, the block (l, m) of Mᵀ(J⊗I)M is
 *     (c_lᵀ J c_m) I + [w_l]× B_m + ([w_m]× B_l)ᵀ + B_lᵀ T B_m,
 * w_l = Σ_k c_kl u_k, u_k = Σ_k' J_kk' q_k', and
 * T = Σ_kk' J_kk' [q_k]×ᵀ[q_k']× = Σ_k (|q_k|² I − q_k q_kᵀ) + |Σq|² I − Σq Σqᵀ:
 * about a third of the work of forming M and Mᵀ(J⊗I)M. */
void iso_elem_q2_from_fit(const iso_elem_fit *fi, const double xi[9], const double xo[3],
                          const int jmap[3], iso_weighting w, double Q[144])
{
    double xj[9], q[9], B[36], c[12], wv[12], TB[27], T[9];
    for (int k = 0; k < 3; k++) {
        const double *src = jmap[k] < 3 ? xi + 3 * jmap[k] : xo;
        memcpy(xj + 3 * k, src, 3 * sizeof(double));
    }
    double sigma = iso_elem_n_scale(xj, w);
    frame_points(fi, xj, 3, q);
    for (int l = 0; l < 3; l++)
        fit_block(fi->R, l, B + 9 * l);
    memset(B + 27, 0, 9 * sizeof(double));
    double sq[3] = {q[0] + q[3] + q[6], q[1] + q[4] + q[7], q[2] + q[5] + q[8]};
    double sq2 = sq[0] * sq[0] + sq[1] * sq[1] + sq[2] * sq[2];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            T[3 * i + j] = (i == j ? sq2 : 0.0) - sq[i] * sq[j];
    for (int k = 0; k < 3; k++) {
        const double *a = q + 3 * k;
        double a2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                T[3 * i + j] += (i == j ? a2 : 0.0) - a[i] * a[j];
    }
    for (int l = 0; l < 4; l++) {
        for (int k = 0; k < 3; k++)
            c[3 * l + k] = (jmap[k] == l ? 1.0 : 0.0) - (l < 3 ? 1.0 / 3.0 : 0.0);
        for (int a = 0; a < 3; a++) {
            double acc = 0;
            for (int k = 0; k < 3; k++)
                acc += c[3 * l + k] * (q[3 * k + a] + sq[a]);
            wv[3 * l + a] = acc;
        }
    }
    for (int m = 0; m < 3; m++)
        mul_nn3(T, B + 9 * m, TB + 9 * m);
    for (int l = 0; l < 4; l++) {
        const double *cl = c + 3 * l;
        double suml = cl[0] + cl[1] + cl[2];
        for (int m = l; m < 4; m++) {
            const double *cm = c + 3 * m;
            double cjc =
                cl[0] * cm[0] + cl[1] * cm[1] + cl[2] * cm[2] + suml * (cm[0] + cm[1] + cm[2]);
            double blk[9] = {cjc, 0, 0, 0, cjc, 0, 0, 0, cjc}, C[9];
            if (m < 3) {
                cross_mat(wv + 3 * l, B + 9 * m, C);
                for (int i = 0; i < 9; i++)
                    blk[i] += C[i];
            }
            if (l < 3) {
                cross_mat(wv + 3 * m, B + 9 * l, C);
                for (int i = 0; i < 3; i++)
                    for (int j = 0; j < 3; j++)
                        blk[3 * i + j] += C[3 * j + i];
            }
            if (l < 3 && m < 3) {
                mul_tn3(B + 9 * l, TB + 9 * m, C);
                for (int i = 0; i < 9; i++)
                    blk[i] += C[i];
            }
            for (int i = 0; i < 3; i++)
                for (int j = (l == m ? i : 0); j < 3; j++)
                    Q[12 * (3 * l + i) + 3 * m + j] = Q[12 * (3 * m + j) + 3 * l + i] =
                        sigma * blk[3 * i + j];
        }
    }
}

/* ===== one interior edge, both ordered pairs ===========================
 *
 * The C path computes edges in batches (element_batch.c, which derives the
 * closed form); one edge is a batch whose every lane holds it. */

void iso_elem_fit_core_of(const iso_elem_fit *f, iso_elem_fit_core *k)
{
    memcpy(k->c, f->c, sizeof k->c);
    k->s = f->s;
    memcpy(k->d, f->d, sizeof k->d);
    k->inv_s = f->inv_s;
    memcpy(k->W, f->W, sizeof k->W);
}

/* A fit core as the first ISO_ELEM__FIT_EDGE fields of a batch record. */
static void core_to_record(const iso_elem_fit_core *f, double rec[ISO_ELEM__FIT_EDGE])
{
    memset(rec, 0, ISO_ELEM__FIT_EDGE * sizeof *rec);
    memcpy(rec + ISO_ELEM__FIT_C, f->c, sizeof f->c);
    rec[ISO_ELEM__FIT_INVS] = f->inv_s;
    memcpy(rec + ISO_ELEM__FIT_D, f->d, sizeof f->d);
    memcpy(rec + ISO_ELEM__FIT_W, f->W, sizeof f->W);
}

void iso_elem_edge_from_fits(const iso_elem_fit_core *fi, const iso_elem_fit_core *fj,
                             const double xl[12], double wi, double wj, double qi, double qj,
                             double Q[144])
{
    double ri[ISO_ELEM__FIT_EDGE], rj[ISO_ELEM__FIT_EDGE];
    const double w[4] = {wi, wj, qi, qj};
    iso_elem__vd q[ISO_ELEM__EDGE_VALUES];
    core_to_record(fi, ri);
    core_to_record(fj ? fj : fi, rj);
    iso_elem__edge_one(xl, ri, rj, w, q);
    for (int l = 0; l < 4; l++)
        for (int m = l; m < 4; m++) {
            const iso_elem__vd *v = q + iso_elem__edge_block(l, m);
            for (int i = 0, n = 0; i < 3; i++)
                for (int j = l == m ? i : 0; j < 3; j++)
                    Q[12 * (3 * l + i) + 3 * m + j] += v[n++][0];
        }
}

int iso_elem_q1(const double x[9], iso_weighting w, double Q[81])
{
    iso_elem_fit f;
    if (iso_elem_fit_compute(x, &f) != 0)
        return -1;
    iso_elem_q1_from_fit(x, &f, w, Q);
    return 0;
}

int iso_elem_q2(const double xi[9], const double xo[3], const int jmap[3], iso_weighting w,
                double Q[144])
{
    iso_elem_fit f;
    if (iso_elem_fit_compute(xi, &f) != 0)
        return -1;
    iso_elem_q2_from_fit(&f, xi, xo, jmap, w, Q);
    return 0;
}
