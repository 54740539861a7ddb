/* solver/element_batch.c -- rigid fits and interior-edge blocks in batches
 * of lanes (element_internal.h), the arithmetic of the C assembly path.
 *
 * The work behind each entry point is compiled three times, for AVX-512,
 * AVX2 and the x86-64 baseline, and the loader picks the widest the
 * processor has (GCC's target_clones). Every lane does the same operations
 * in the same order whichever runs, and nothing is contracted into fused
 * multiply-adds (ISO C mode), so the three give the same bits (cactus A
 * and right-hand side compared across all three; test_element_batch holds
 * a batch to the scalar code's bits).
 *
 * Inputs are read by reference: a lane's rows (a fit record, a
 * vertex's coordinates) are loaded whole and turned into the structure of
 * arrays by an 8x8 transpose in registers, not stored lane by lane into
 * memory and read back as vectors, which waits on every store. */
#include "element_internal.h"
#include "simd_internal.h"

#include <math.h>
#include <string.h>

typedef iso_elem__vd vd;
typedef iso_elem__vm vm;
#define LANES ISO_ELEM__LANES

/* Every loop over lanes, rows or fields is unrolled (#pragma GCC unroll),
 * so that the small arrays of vectors become registers rather than stack
 * slots: cactus assembly 1.87 -> 1.25 ms. */

/* Square roots lane by lane: generic vectors have none, and sqrt() is the
 * correctly rounded root whatever the instruction set. */
_Static_assert(LANES == 8, "sqrt_lanes and the batch layouts assume 8 lanes");
ISO_INLINE void sqrt_lanes(vd *v)
{
    /* Built as a vector, not lane by lane in memory: a vector read of
     * values just stored one at a time waits for the stores to retire. */
    vd r = *v;
    *v = (vd){sqrt(r[0]), sqrt(r[1]), sqrt(r[2]), sqrt(r[3]),
              sqrt(r[4]), sqrt(r[5]), sqrt(r[6]), sqrt(r[7])};
}

/* The fit's arithmetic, in lanes: the scalar fit's lines (element.c). The
 * root is a value there; here, a statement expression, since a vector
 * returned by value changes the ABI between the clones (-Wpsabi). */
#define FIT_T vd
#define FIT_MASK vm
#define FIT_SQRT(v)                                                                                \
    __extension__({                                                                                \
        vd fit_root_ = (v);                                                                        \
        sqrt_lanes(&fit_root_);                                                                    \
        fit_root_;                                                                                 \
    })
#include "element_fit.h"

/* ----- lanes from rows ----- */

typedef double v4d __attribute__((vector_size(32)));

/* r[k] (lane k's row of 8) becomes r[j] (field j of every lane). */
ISO_INLINE void transpose8(vd r[8])
{
    vd t[8], u[8];
#pragma GCC unroll 16
    for (int k = 0; k < 8; k += 2) {
        t[k] = __builtin_shufflevector(r[k], r[k + 1], 0, 8, 2, 10, 4, 12, 6, 14);
        t[k + 1] = __builtin_shufflevector(r[k], r[k + 1], 1, 9, 3, 11, 5, 13, 7, 15);
    }
#pragma GCC unroll 16
    for (int k = 0; k < 8; k += 4)
#pragma GCC unroll 16
        for (int h = 0; h < 2; h++) {
            u[k + h] = __builtin_shufflevector(t[k + h], t[k + h + 2], 0, 1, 8, 9, 4, 5, 12, 13);
            u[k + h + 2] =
                __builtin_shufflevector(t[k + h], t[k + h + 2], 2, 3, 10, 11, 6, 7, 14, 15);
        }
#pragma GCC unroll 16
    for (int h = 0; h < 4; h++) {
        r[h] = __builtin_shufflevector(u[h], u[h + 4], 0, 1, 2, 3, 8, 9, 10, 11);
        r[h + 4] = __builtin_shufflevector(u[h], u[h + 4], 4, 5, 6, 7, 12, 13, 14, 15);
    }
}

/* The coordinates of vertices va[k] and vb[k] (rows of x4) as lanes: a[0..2]
 * and, unless b is NULL, b[0..2]. */
ISO_INLINE void gather_points(const double *x4, const int *va, const int *vb, vd a[3], vd b[3])
{
    vd r[8];
#pragma GCC unroll 16
    for (int k = 0; k < 8; k++) {
        v4d pa, pb;
        memcpy(&pa, x4 + 4 * (size_t)va[k], sizeof pa);
        memcpy(&pb, x4 + 4 * (size_t)vb[k], sizeof pb);
        r[k] = __builtin_shufflevector(pa, pb, 0, 1, 2, 3, 4, 5, 6, 7);
    }
    transpose8(r);
#pragma GCC unroll 16
    for (int i = 0; i < 3; i++) {
        a[i] = r[i];
        if (b)
            b[i] = r[4 + i];
    }
}

/* Fields 0..15 of the fit records rec[k] as lanes. */
ISO_INLINE void gather_fits(const double *fits, const int *t, vd f[16])
{
#pragma GCC unroll 16
    for (int k = 0; k < 8; k++) {
        const double *rec = fits + ISO_ELEM__FIT_STRIDE * (size_t)t[k];
        memcpy(&f[k], rec, sizeof f[k]);
        memcpy(&f[8 + k], rec + 8, sizeof f[k]);
    }
    transpose8(f);
    transpose8(f + 8);
}

/* ===== fits ==============================================================
 *
 * iso_elem_fit_compute (element.c) and iso_elem_n_scale, lane by lane: the
 * same lines (element_fit.h) on vectors. */

ISO_INLINE void fit_lanes(const vd x[9], iso_weighting w, vd f[ISO_ELEM__FIT_STRIDE])
{
    vd c[3], s, inv, d[3], r[9];
    vm ok;
    fit_triangle(x, c, &s, &inv, d, r, f + ISO_ELEM__FIT_W, &ok);
#pragma GCC unroll 16
    for (int a = 0; a < 3; a++) {
        f[ISO_ELEM__FIT_C + a] = c[a];
        f[ISO_ELEM__FIT_D + a] = d[a];
    }
    f[ISO_ELEM__FIT_INVS] = inv;
    f[ISO_ELEM__FIT_S] = s;
    if (w == ISO_WEIGHT_AREA) {
        fit_area(x, &f[ISO_ELEM__FIT_SIGMA]);
        f[ISO_ELEM__FIT_SIGMA] /= 12.0;
    } else
        f[ISO_ELEM__FIT_SIGMA] = (vd){0} + 1.0 / 24.0;
    f[ISO_ELEM__FIT_BAD] = (vd)((vm)((vd){0} + 1.0) & ~ok);
}

ISO_CLONES static int fits_batch(const iso_elem__fit_batch *b, iso_weighting w)
{
    vd x[9], f[ISO_ELEM__FIT_STRIDE];
    gather_points(b->x4, b->v[0], b->v[1], x, x + 3);
    gather_points(b->x4, b->v[2], b->v[2], x + 6, NULL);
    fit_lanes(x, w, f);
    int any = 0;
#pragma GCC unroll 16
    for (int k = 0; k < LANES; k++)
        any |= f[ISO_ELEM__FIT_BAD][k] != 0;
    transpose8(f);
    transpose8(f + 8);
#pragma GCC unroll 16
    for (int k = 0; k < LANES; k++) {
        double *rec = b->fits + ISO_ELEM__FIT_STRIDE * (size_t)b->t[k];
        memcpy(rec, &f[k], sizeof f[k]);
        memcpy(rec + LANES, &f[8 + k], sizeof f[k]);
    }
    return any;
}

/* ===== interior edges ====================================================
 *
 * iso_elem_edge_from_fits's block, derived (element.c, iso_elem_q2_from_fit)
 * for one ordered pair in its layout (0, 1, s, t) -- the shared corners,
 * the source's third, the target's third -- as
 *     block(l, m) = cjc_lm I + Z_lm + Z_mlᵀ,  Z_lm = P_l [r_m]×,
 *     P_l = [w_l]× W − ½ [r_l]× G,  G = W T W,
 * r in the source's frame, no r for the target's own corner, w0 = r0 − Σq/3,
 * w1 = r1 − Σq/3, w2 = −4 Σq/3, w3 = rt + Σq. Three things halve the work:
 *
 * 1. Weights go into P. The pair's weight wv and the source's Q1 (weight q)
 *    are both of the form P'[r]× + its transpose: Q1/σ's block (k, l) is
 *    (J_kl − 4/3) I + [r_k]× W [r_l]×, and [r_k]× W [r_l]× = Y_kl + Y_lkᵀ
 *    with Y_kl = ½ [r_k]× W [r_l]×, in the pair's own frame. So one set of
 *        P'_l = wv P_l + (q/2) [r_l]× W
 *    per lane carries both, and with D = (wv/2) G − (q/2) W, H = wv W − D,
 *    K = [(wv/3) Σq]× W:
 *        P'_0 = [r0]× H − K,  P'_1 = [r1]× H − K,
 *        P'_s = [r0 + r1]× D − 4K,  P'_t = [wv (rt + Σq)]× W.
 * 2. The translations: a constant field is rigid, so every block row of
 *    the edge's block sums to zero, Q_l3 = −(Q_l0 + Q_l1 + Q_l2) for the
 *    edge layout's last vertex q. Only the blocks among a, b, p are
 *    computed; q's four follow from them. Of Ti's pair (its layout is the
 *    edge's) that needs P'_0, P'_1, P'_s and all three r; of Tj's (a, b,
 *    q, p) P'_0, P'_1, P'_t and r0, r1: no P, no r and no Z of q at all.
 * 3. Both pairs go into one X = Σ_pairs P' R: X's block (l, m) over a, b, p
 *    is the sum of the pairs' P'_l [r_m]×, and block (l, m) of the edge is
 *    c_lm I + X_lm + X_mlᵀ, with c_lm the sum of the pairs' and the Q1s'
 *    weighted constants. */

/* C = [a]× M: column j is a × M[:, j]. */
ISO_INLINE void cross_left(const vd a[3], const vd M[9], vd C[9])
{
    C[0] = a[1] * M[6] - a[2] * M[3];
    C[1] = a[1] * M[7] - a[2] * M[4];
    C[2] = a[1] * M[8] - a[2] * M[5];
    C[3] = a[2] * M[0] - a[0] * M[6];
    C[4] = a[2] * M[1] - a[0] * M[7];
    C[5] = a[2] * M[2] - a[0] * M[8];
    C[6] = a[0] * M[3] - a[1] * M[0];
    C[7] = a[0] * M[4] - a[1] * M[1];
    C[8] = a[0] * M[5] - a[1] * M[2];
}

/* C = M [r]×: row i is M[i, :] × r. */
ISO_INLINE void cross_right(const vd M[9], const vd r[3], vd C[9])
{
#pragma GCC unroll 16
    for (int i = 0; i < 3; i++) {
        const vd *m = M + 3 * i;
        C[3 * i] = m[1] * r[2] - m[2] * r[1];
        C[3 * i + 1] = m[2] * r[0] - m[0] * r[2];
        C[3 * i + 2] = m[0] * r[1] - m[1] * r[0];
    }
}

/* C += M [r]×. */
ISO_INLINE void add_cross_right(const vd M[9], const vd r[3], vd C[9])
{
#pragma GCC unroll 16
    for (int i = 0; i < 3; i++) {
        const vd *m = M + 3 * i;
        C[3 * i] += m[1] * r[2] - m[2] * r[1];
        C[3 * i + 1] += m[2] * r[0] - m[0] * r[2];
        C[3 * i + 2] += m[0] * r[1] - m[1] * r[0];
    }
}

/* A symmetric 3x3 from its upper six (00 01 02 11 12 22). */
ISO_INLINE void full_sym(const vd u[6], vd M[9])
{
    M[0] = u[0], M[1] = M[3] = u[1], M[2] = M[6] = u[2];
    M[4] = u[3], M[5] = M[7] = u[4], M[8] = u[5];
}

/* One ordered pair: the points in the source's frame (f: c, 1/s, d, W),
 * r[0..2] the shared corners a, b and the source's third (−a − b, which
 * the frame's centring makes it to rounding, and which keeps the
 * translations exactly in the null space), and its three rows P'_0, P'_1,
 * and P'_s (third_is_source) or P'_t. xt: the target's third corner. */
ISO_INLINE void pair_rows(const vd f[ISO_ELEM__FIT_EDGE], const vd xa[3], const vd xb[3],
                          const vd xt[3], const vd *wvp, const vd *qp, int third_is_source, vd r[9],
                          vd P[27])
{
    vd wv = *wvp, q = *qp;
    const vd *c = f + ISO_ELEM__FIT_C, *d = f + ISO_ELEM__FIT_D, inv = f[ISO_ELEM__FIT_INVS];
    vd rt[3], sq[3], W[9], T[9], M[9], Gu[6], Du[6], Hu[6], D[9], H[9], K[9];
#pragma GCC unroll 16
    for (int a = 0; a < 3; a++) {
        r[a] = (xa[a] - c[a]) * inv - d[a];
        r[3 + a] = (xb[a] - c[a]) * inv - d[a];
        rt[a] = (xt[a] - c[a]) * inv - d[a];
        r[6 + a] = -(r[a] + r[3 + a]);
        sq[a] = r[a] + r[3 + a] + rt[a];
    }
    full_sym(f + ISO_ELEM__FIT_W, W);
    /* T = Σ_g (|g|² I − g gᵀ) over g = the target's corners and Σq */
#define OUTER4(i, j) (r[i] * r[j] + r[3 + i] * r[3 + j] + rt[i] * rt[j] + sq[i] * sq[j])
    vd o00 = OUTER4(0, 0), o11 = OUTER4(1, 1), o22 = OUTER4(2, 2), tr = o00 + o11 + o22;
    T[0] = tr - o00, T[4] = tr - o11, T[8] = tr - o22;
    T[1] = T[3] = -OUTER4(0, 1);
    T[2] = T[6] = -OUTER4(0, 2);
    T[5] = T[7] = -OUTER4(1, 2);
#undef OUTER4
#pragma GCC unroll 16
    for (int i = 0; i < 3; i++) /* M = T W */
#pragma GCC unroll 16
        for (int j = 0; j < 3; j++)
            M[3 * i + j] = T[3 * i] * W[j] + T[3 * i + 1] * W[3 + j] + T[3 * i + 2] * W[6 + j];
    static const int ui[6] = {0, 0, 0, 1, 1, 2}, uj[6] = {0, 1, 2, 1, 2, 2};
    vd hw = 0.5 * wv, hq = 0.5 * q;
#pragma GCC unroll 16
    for (int u = 0; u < 6; u++) { /* G = W M, symmetric: its upper six */
        int i = ui[u], j = uj[u];
        Gu[u] = W[3 * i] * M[j] + W[3 * i + 1] * M[3 + j] + W[3 * i + 2] * M[6 + j];
        Du[u] = hw * Gu[u] - hq * f[ISO_ELEM__FIT_W + u];
        Hu[u] = wv * f[ISO_ELEM__FIT_W + u] - Du[u];
    }
    full_sym(Du, D);
    full_sym(Hu, H);
    vd sk[3], third[3];
#pragma GCC unroll 16
    for (int a = 0; a < 3; a++)
        sk[a] = wv * (1.0 / 3.0) * sq[a];
    cross_left(sk, W, K);
    cross_left(r, H, P);
    cross_left(r + 3, H, P + 9);
    if (third_is_source) {
#pragma GCC unroll 16
        for (int a = 0; a < 3; a++)
            third[a] = r[a] + r[3 + a];
        cross_left(third, D, P + 18);
#pragma GCC unroll 16
        for (int i = 0; i < 9; i++)
            P[18 + i] -= 4.0 * K[i];
    } else {
#pragma GCC unroll 16
        for (int a = 0; a < 3; a++)
            third[a] = wv * (rt[a] + sq[a]);
        cross_left(third, W, P + 18);
    }
#pragma GCC unroll 16
    for (int i = 0; i < 9; i++) {
        P[i] -= K[i];
        P[9 + i] -= K[i];
    }
}

/* The edge block's upper blocks among a, b, p (Qf: all nine 3x3 blocks,
 * full, Qf[3 l + m]), from both pairs' rows and the constants. */
ISO_INLINE void blocks_abp(const vd ri[9], const vd Pi[27], const vd rj[9], const vd Pj[27],
                           const vd w[4], vd Qf[9][9])
{
    vd X[9][9];
#pragma GCC unroll 16
    for (int l = 0; l < 3; l++) { /* Ti's pair: columns a, b, p (r_p = −r_a − r_b) */
        cross_right(Pi + 9 * l, ri, X[3 * l]);
        cross_right(Pi + 9 * l, ri + 3, X[3 * l + 1]);
#pragma GCC unroll 16
        for (int i = 0; i < 9; i++)
            X[3 * l + 2][i] = -(X[3 * l][i] + X[3 * l + 1][i]);
    }
#pragma GCC unroll 16
    for (int l = 0; l < 3; l++) { /* Tj's pair: columns a, b (p is its target) */
        add_cross_right(Pj + 9 * l, rj, X[3 * l]);
        add_cross_right(Pj + 9 * l, rj + 3, X[3 * l + 1]);
    }
    /* the constants: pair (Ti, Tj) has cjc 2/3, −1/3, 0 / 2/3, 0 / 4/3 on
     * (a, b, p); pair (Tj, Ti) 2/3, −1/3, −1/3 / 2/3, −1/3 / 2; Q1 of Ti
     * 2/3 on the diagonal and −1/3 off it, Q1 of Tj 2/3, −1/3 on (a, b) */
    vd all = w[0] + w[1] + w[2] + w[3], side = w[1] + w[2];
    vd cst[9];
    cst[0] = cst[4] = 2.0 / 3.0 * all;
    cst[1] = cst[3] = -1.0 / 3.0 * all;
    cst[2] = cst[6] = cst[5] = cst[7] = -1.0 / 3.0 * side;
    cst[8] = 4.0 / 3.0 * w[0] + 2.0 * w[1] + 2.0 / 3.0 * w[2];
#pragma GCC unroll 16
    for (int l = 0; l < 3; l++)
#pragma GCC unroll 16
        for (int m = l; m < 3; m++)
#pragma GCC unroll 16
            for (int i = 0; i < 3; i++)
#pragma GCC unroll 16
                for (int j = 0; j < 3; j++) {
                    vd v = X[3 * l + m][3 * i + j] + X[3 * m + l][3 * j + i];
                    if (i == j)
                        v += cst[3 * l + m];
                    Qf[3 * l + m][3 * i + j] = Qf[3 * m + l][3 * j + i] = v;
                }
}

/* A 3x3 block into q: a diagonal block's upper six (put_diag), or nine
 * values row by row, column by column in the lanes whose tr is all ones
 * (put_off). */
ISO_INLINE void put_diag(const vd B[9], vd *q)
{
    q[0] = B[0], q[1] = B[1], q[2] = B[2], q[3] = B[4], q[4] = B[5], q[5] = B[8];
}

ISO_INLINE void put_off(const vd B[9], const vm *tr, vd *q)
{
    vm mask = *tr;
#pragma GCC unroll 16
    for (int i = 0; i < 3; i++)
#pragma GCC unroll 16
        for (int j = 0; j < 3; j++)
            q[3 * i + j] = (vd)(((vm)B[3 * j + i] & mask) | ((vm)B[3 * i + j] & ~mask));
}

ISO_INLINE void edge_lanes(const vd x[12], const vd fi[ISO_ELEM__FIT_EDGE],
                           const vd fj[ISO_ELEM__FIT_EDGE], const vd w[4], const vm tr[6],
                           vd q[ISO_ELEM__EDGE_VALUES])
{
    vd ri[9], rj[9], Pi[27], Pj[27], Qf[9][9];
    /* (Ti, Tj): target's third q; (Tj, Ti): shared corners a, b, target p */
    pair_rows(fi, x, x + 3, x + 9, &w[0], &w[2], 1, ri, Pi);
    pair_rows(fj, x, x + 3, x + 6, &w[1], &w[3], 0, rj, Pj);
    blocks_abp(ri, Pi, rj, Pj, w, Qf);
    /* q's blocks: Q_l3 = −(Q_l0 + Q_l1 + Q_l2), Q_33 = −Σ_l Q_l3ᵀ */
    vd Q3[3][9], Q33[9];
#pragma GCC unroll 16
    for (int l = 0; l < 3; l++)
#pragma GCC unroll 16
        for (int i = 0; i < 9; i++)
            Q3[l][i] = -(Qf[3 * l][i] + Qf[3 * l + 1][i] + Qf[3 * l + 2][i]);
#pragma GCC unroll 16
    for (int i = 0; i < 3; i++)
#pragma GCC unroll 16
        for (int j = 0; j < 3; j++)
            Q33[3 * i + j] = -(Q3[0][3 * j + i] + Q3[1][3 * j + i] + Q3[2][3 * j + i]);
    put_diag(Qf[0], q + iso_elem__edge_block(0, 0));
    put_off(Qf[1], &tr[0], q + iso_elem__edge_block(0, 1));
    put_off(Qf[2], &tr[1], q + iso_elem__edge_block(0, 2));
    put_off(Q3[0], &tr[2], q + iso_elem__edge_block(0, 3));
    put_diag(Qf[4], q + iso_elem__edge_block(1, 1));
    put_off(Qf[5], &tr[3], q + iso_elem__edge_block(1, 2));
    put_off(Q3[1], &tr[4], q + iso_elem__edge_block(1, 3));
    put_diag(Qf[8], q + iso_elem__edge_block(2, 2));
    put_off(Q3[2], &tr[5], q + iso_elem__edge_block(2, 3));
    put_diag(Q33, q + iso_elem__edge_block(3, 3));
}

ISO_CLONES static void edges_batch(iso_elem__edge_batch *b)
{
    vd x[12], fi[16], fj[16], w[4];
    vm tr[6];
    gather_points(b->x4, b->v[0], b->v[1], x, x + 3);
    gather_points(b->x4, b->v[2], b->v[3], x + 6, x + 9);
    gather_fits(b->fits, b->ti, fi);
    gather_fits(b->fits, b->tj, fj);
    /* the weights of iso_elem_edge_from_fits: each ordered pair's N is its
     * target's, each Q1's its own triangle's */
    vm fl;
#pragma GCC unroll 16
    for (int k = 0; k < LANES; k++)
        fl[k] = b->flags[k];
    vd si = fi[ISO_ELEM__FIT_SIGMA], sj = fj[ISO_ELEM__FIT_SIGMA];
    vd w1 = (vd){0} + (1.0 - b->omega), w2 = (vd){0} + b->omega;
    vm ci = (fl & ISO_ELEM__EDGE_CARRY_I) != 0, cj = (fl & ISO_ELEM__EDGE_CARRY_J) != 0;
    w[0] = w2 * sj;
    w[1] = w2 * si;
    w[2] = (vd)((vm)(w1 * si) & ci);
    w[3] = (vd)((vm)(w1 * sj) & cj);
#pragma GCC unroll 16
    for (int o = 0; o < 6; o++)
        tr[o] = -(fl >> o & 1);
    edge_lanes(x, fi, fj, w, tr, b->q);
}

ISO_CLONES static void edge_one(const double x[12], const double fi[ISO_ELEM__FIT_EDGE],
                                const double fj[ISO_ELEM__FIT_EDGE], const double w[4],
                                vd q[ISO_ELEM__EDGE_VALUES])
{
    vd xv[12], fiv[ISO_ELEM__FIT_EDGE], fjv[ISO_ELEM__FIT_EDGE], wv[4];
    vm tr[6] = {{0}};
#pragma GCC unroll 16
    for (int i = 0; i < 12; i++)
        xv[i] = (vd){0} + x[i];
#pragma GCC unroll 16
    for (int i = 0; i < ISO_ELEM__FIT_EDGE; i++) {
        fiv[i] = (vd){0} + fi[i];
        fjv[i] = (vd){0} + fj[i];
    }
#pragma GCC unroll 16
    for (int i = 0; i < 4; i++)
        wv[i] = (vd){0} + w[i];
    edge_lanes(xv, fiv, fjv, wv, tr, q);
}

/* The entry points: the clones are static, since GCC 12 exports a cloned
 * function's resolver whatever its visibility says (test_exports). */
int iso_elem__fits(const iso_elem__fit_batch *b, iso_weighting w)
{
    return fits_batch(b, w);
}

void iso_elem__edges(iso_elem__edge_batch *b)
{
    edges_batch(b);
}

void iso_elem__edge_one(const double x[12], const double fi[ISO_ELEM__FIT_EDGE],
                        const double fj[ISO_ELEM__FIT_EDGE], const double w[4],
                        vd q[ISO_ELEM__EDGE_VALUES])
{
    edge_one(x, fi, fj, w, q);
}
