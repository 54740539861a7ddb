/* solver/mat3.h -- small 3-vectors and 3×3 matrices (row-major), shared by
 * the rotated preconditioner (rotate.c) and the reduced model (proxy.c).
 * Internal: static inline, no state. */
#ifndef ISO_MAT3_H
#define ISO_MAT3_H

#include <math.h>

static inline void iso_m3_sub(const double *a, const double *b, double *c)
{
    c[0] = a[0] - b[0], c[1] = a[1] - b[1], c[2] = a[2] - b[2];
}

static inline double iso_m3_dot(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void iso_m3_cross(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* M += u wᵀ */
static inline void iso_m3_add_outer(double *M, const double *u, const double *w)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            M[3 * r + c] += u[r] * w[c];
}

/* y = A v */
static inline void iso_m3_mul_vec(const double *A, const double *v, double *y)
{
    for (int r = 0; r < 3; r++)
        y[r] = A[3 * r] * v[0] + A[3 * r + 1] * v[1] + A[3 * r + 2] * v[2];
}

/* C = A B */
static inline void iso_m3_mul(const double *A, const double *B, double *C)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            C[3 * r + c] = A[3 * r] * B[c] + A[3 * r + 1] * B[3 + c] + A[3 * r + 2] * B[6 + c];
}

/* Y = X⁻¹ by cofactors; 0 where X is singular (|det| below 1e-12 of its
 * diagonal's scale cubed) or not finite. */
static inline int iso_m3_inverse(const double *X, double *Y)
{
    double C[9]; /* rows: the cofactor matrix's, det(X) X⁻ᵀ */
    iso_m3_cross(X + 3, X + 6, C);
    iso_m3_cross(X + 6, X, C + 3);
    iso_m3_cross(X, X + 3, C + 6);
    double det = iso_m3_dot(X, C), scale = fabs(X[0]) + fabs(X[4]) + fabs(X[8]);
    if (!(fabs(det) > 1e-12 * scale * scale * scale) || !isfinite(det))
        return 0;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            Y[3 * r + c] = C[3 * c + r] / det;
    return 1;
}

/* G = 3I − FᵀF (a Newton–Schulz step is F ← F G / 2); returns
 * ‖FᵀF − I‖² (Frobenius). */
static inline double iso_m3_gram_defect(const double *F, double *G)
{
    double d = 0;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double g = F[r] * F[c] + F[3 + r] * F[3 + c] + F[6 + r] * F[6 + c];
            double dev = g - (r == c);
            d += dev * dev;
            G[3 * r + c] = (r == c ? 3.0 : 0.0) - g;
        }
    return d;
}

#endif
