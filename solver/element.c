/* solver/element.c -- per-element quadratic forms (iso_element.h).
 *
 * Notation follows docs/method.md. N_T = σ (J ⊗ I3) with J = [[2,1,1],
 * [1,2,1],[1,1,2]]; σ = 1/24 (param) or A_T/12 (area). The best rigid fit
 * does not depend on σ, so R is computed with σ = 1 and σ enters Q only. */
#include "iso_element.h"

#include <math.h>
#include <string.h>

static const double J3[3][3] = {{2, 1, 1}, {1, 2, 1}, {1, 1, 2}};

void iso_elem_frame(const double x[9], double c[3], double *s)
{
    double ss = 0;
    for (int a = 0; a < 3; a++)
        c[a] = (x[a] + x[3 + a] + x[6 + a]) / 3.0;
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++) {
            double d = x[3 * k + a] - c[a];
            ss += d * d;
        }
    *s = sqrt(ss / 3.0);
}

static double triangle_area(const double x[9])
{
    double e1[3], e2[3];
    for (int a = 0; a < 3; a++) {
        e1[a] = x[3 + a] - x[a];
        e2[a] = x[6 + a] - x[a];
    }
    double n0 = e1[1] * e2[2] - e1[2] * e2[1];
    double n1 = e1[2] * e2[0] - e1[0] * e2[2];
    double n2 = e1[0] * e2[1] - e1[1] * e2[0];
    return 0.5 * sqrt(n0 * n0 + n1 * n1 + n2 * n2);
}

double iso_elem_n_scale(const double x[9], iso_weighting w)
{
    return w == ISO_WEIGHT_AREA ? triangle_area(x) / 12.0 : 1.0 / 24.0;
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
        row[0 * 6 + 4] = r[2];  row[0 * 6 + 5] = -r[1];
        row[1 * 6 + 3] = -r[2]; row[1 * 6 + 5] = r[0];
        row[2 * 6 + 3] = r[1];  row[2 * 6 + 4] = -r[0];
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

int iso_elem_fit_compute(const double x[9], iso_elem_fit *f)
{
    double E[54], JE[54];
    iso_elem_frame(x, f->c, &f->s);
    if (!(f->s > 0))
        return -1;
    iso_elem_eval_matrix(x, f->c, f->s, E);
    return rigid_fit_from_e(E, f->R, JE);
}

void iso_elem_q1_from_fit(const double x[9], const iso_elem_fit *f, iso_weighting w,
                          double Q[81])
{
    double E[54], JE[54];
    iso_elem_eval_matrix(x, f->c, f->s, E);
    apply_j(E, 6, JE);
    /* Q1 = σ (Jx − JE R): N − N E (Eᵀ N E)^{-1} Eᵀ N with N = σ Jx. */
    double sigma = iso_elem_n_scale(x, w);
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < 9; j++) {
            double acc = (i % 3 == j % 3) ? J3[i / 3][j / 3] : 0.0;
            for (int k = 0; k < 6; k++)
                acc -= JE[6 * i + k] * f->R[9 * k + j];
            Q[9 * i + j] = sigma * acc;
        }
    /* Symmetrise: the two halves differ only by rounding. */
    for (int i = 0; i < 9; i++)
        for (int j = i + 1; j < 9; j++) {
            double m = 0.5 * (Q[9 * i + j] + Q[9 * j + i]);
            Q[9 * i + j] = Q[9 * j + i] = m;
        }
}

void iso_elem_q2_from_fit(const iso_elem_fit *fi, const double xi[9], const double xo[3],
                          const int jmap[3], iso_weighting w, double Q[144])
{
    const double *R = fi->R;
    /* Tj's corners, and Ti's rigid fit evaluated there: G = E_j^{(c_i)} R_i. */
    double xj[9];
    for (int k = 0; k < 3; k++) {
        const double *src = jmap[k] < 3 ? xi + 3 * jmap[k] : xo;
        memcpy(xj + 3 * k, src, 3 * sizeof(double));
    }
    double Ej[54], M[108];
    iso_elem_eval_matrix(xj, fi->c, fi->s, Ej);
    /* M (9x12) = I' − G P: picks v at Tj's corners minus the extrapolated fit. */
    memset(M, 0, sizeof M);
    for (int r = 0; r < 9; r++) {
        for (int col = 0; col < 9; col++) {
            double g = 0;
            for (int k = 0; k < 6; k++)
                g += Ej[6 * r + k] * R[9 * k + col];
            M[12 * r + col] = -g;
        }
        M[12 * r + 3 * jmap[r / 3] + r % 3] += 1.0;
    }
    double JM[108];
    apply_j(M, 12, JM);
    double sigma = iso_elem_n_scale(xj, w);
    for (int i = 0; i < 12; i++)
        for (int j = i; j < 12; j++) {
            double acc = 0;
            for (int r = 0; r < 9; r++)
                acc += M[12 * r + i] * JM[12 * r + j];
            Q[12 * i + j] = Q[12 * j + i] = sigma * acc;
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
