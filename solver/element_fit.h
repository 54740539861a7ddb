/* solver/element_fit.h -- a triangle's frame, rigid fit and area, written
 * once for one triangle in doubles and for a batch of them in lanes.
 *
 * Not a header of declarations: the arithmetic itself, which a source file
 * includes after defining
 *     FIT_T        the number: double, or iso_elem__vd (a lane per triangle)
 *     FIT_MASK     what `&` of two comparisons of FIT_Ts gives: int, or
 *                  iso_elem__vm (all ones in a true lane)
 *     FIT_SQRT(v)  the correctly rounded square root of v
 * element.c includes it with doubles (iso_elem_frame, iso_elem_n_scale,
 * iso_elem_fit_compute), element_batch.c with lanes. A fit decides whether
 * a triangle has degenerated, and near that edge the scalar code and the
 * batches must decide alike: both are these lines, the same operations in
 * the same order, so they give the same bits (test_element_batch holds them
 * to it). The OpenCL kernel fit_triangles (assemble_cl_kernels.h) repeats
 * them in OpenCL C.
 *
 * The functions are inlined wherever they are used (element_batch.c's
 * cloned functions need their vectors in registers, not passed in memory),
 * and they return through pointers: GCC warns (-Wpsabi) that a vector
 * returned by value changes the ABI between instruction sets. */
#if !defined(FIT_T) || !defined(FIT_MASK) || !defined(FIT_SQRT)
#error "define FIT_T, FIT_MASK and FIT_SQRT before including element_fit.h"
#endif

#define FIT_INLINE static inline __attribute__((always_inline))

/* Centroid c and size s (the RMS distance of the corners from c). */
FIT_INLINE void fit_centre(const FIT_T x[9], FIT_T c[3], FIT_T *s)
{
    FIT_T ss = {0};
#pragma GCC unroll 16
    for (int a = 0; a < 3; a++)
        c[a] = (x[a] + x[3 + a] + x[6 + a]) / 3.0;
#pragma GCC unroll 16
    for (int k = 0; k < 3; k++)
#pragma GCC unroll 16
        for (int a = 0; a < 3; a++) {
            FIT_T t = x[3 * k + a] - c[a];
            ss += t * t;
        }
    *s = FIT_SQRT(ss / 3.0);
}

/* The triangle's area. */
FIT_INLINE void fit_area(const FIT_T x[9], FIT_T *area)
{
    FIT_T e1[3], e2[3];
#pragma GCC unroll 16
    for (int a = 0; a < 3; a++) {
        e1[a] = x[3 + a] - x[a];
        e2[a] = x[6 + a] - x[a];
    }
    FIT_T n0 = e1[1] * e2[2] - e1[2] * e2[1];
    FIT_T n1 = e1[2] * e2[0] - e1[0] * e2[2];
    FIT_T n2 = e1[0] * e2[1] - e1[1] * e2[0];
    *area = 0.5 * FIT_SQRT(n0 * n0 + n1 * n1 + n2 * n2);
}

/* The fit's frame and W = S⁻¹ (element.c derives the closed form): c and s
 * (fit_centre), inv = 1/s, the rounding shift d (the mean of the scaled
 * corners, which the rounded centroid leaves at ~eps |c|/s instead of zero)
 * and the corners in the frame, r = (x − c) inv − d; W's upper six (00 01
 * 02 11 12 22). *ok: true where the fit is regular; a pivot of S's
 * Cholesky factor that is not positive (or s = 0, which makes everything
 * NaN) means the triangle has degenerated, and !(v > 0) is v <= 0 or NaN. */
FIT_INLINE void fit_triangle(const FIT_T x[9], FIT_T c[3], FIT_T *s, FIT_T *inv, FIT_T d[3],
                             FIT_T r[9], FIT_T W[6], FIT_MASK *ok)
{
    fit_centre(x, c, s);
    *inv = 1.0 / *s; /* one division, not one per point */
#pragma GCC unroll 16
    for (int i = 0; i < 9; i++)
        r[i] = (x[i] - c[i % 3]) * *inv;
#pragma GCC unroll 16
    for (int a = 0; a < 3; a++)
        d[a] = (r[a] + r[3 + a] + r[6 + a]) / 3.0;
#pragma GCC unroll 16
    for (int i = 0; i < 9; i++)
        r[i] = (x[i] - c[i % 3]) * *inv - d[i % 3];
    FIT_T S00 = {0}, S11 = {0}, S22 = {0}, S01 = {0}, S02 = {0}, S12 = {0};
#pragma GCC unroll 16
    for (int k = 0; k < 3; k++) {
        FIT_T a0 = r[3 * k], a1 = r[3 * k + 1], a2 = r[3 * k + 2];
        S00 += a1 * a1 + a2 * a2;
        S11 += a0 * a0 + a2 * a2;
        S22 += a0 * a0 + a1 * a1;
        S01 -= a0 * a1;
        S02 -= a0 * a2;
        S12 -= a1 * a2;
    }
    FIT_T L00 = FIT_SQRT(S00), L10 = S01 / L00, L20 = S02 / L00;
    FIT_T d1 = S11 - L10 * L10, L11 = FIT_SQRT(d1), L21 = (S12 - L20 * L10) / L11;
    FIT_T d2 = S22 - L20 * L20 - L21 * L21, L22 = FIT_SQRT(d2);
    FIT_T I00 = 1.0 / L00, I11 = 1.0 / L11, I22 = 1.0 / L22;
    FIT_T I10 = -L10 * I00 * I11, I21 = -L21 * I11 * I22;
    FIT_T I20 = -(L20 * I00 + L21 * I10) * I22;
    W[0] = I00 * I00 + I10 * I10 + I20 * I20;
    W[1] = I10 * I11 + I20 * I21;
    W[2] = I20 * I22;
    W[3] = I11 * I11 + I21 * I21;
    W[4] = I21 * I22;
    W[5] = I22 * I22;
    *ok = (*s > 0) & (S00 > 0) & (d1 > 0) & (d2 > 0);
}

#undef FIT_INLINE
