/* solver/element_internal.h -- the element forms of iso_element.h in batches
 * of lanes, for the C assembly path (element_batch.c). Not installed; the
 * solver's own sources and white-box tests include it.
 *
 * A batch holds ISO_ELEM__LANES independent problems side by side, one per
 * lane of a vector: structure of arrays, so that every operation of the
 * arithmetic is one vector operation across the lanes. Each lane's rounding
 * is that of scalar code (no fused multiply-adds: the project compiles in
 * ISO C mode, where GCC contracts nothing), so a result does not depend on
 * the lane it was computed in, on the lanes beside it, or on which of the
 * instruction sets the batch functions were compiled for ran it. */
#ifndef ISO_ELEMENT_INTERNAL_H
#define ISO_ELEMENT_INTERNAL_H

#include "iso_element.h"

#define ISO_ELEM__LANES 8

typedef double iso_elem__vd __attribute__((vector_size(8 * ISO_ELEM__LANES)));
typedef long long iso_elem__vm __attribute__((vector_size(8 * ISO_ELEM__LANES)));

/* A triangle's fit as the batches keep it: one record of 16 doubles, 64-byte
 * aligned (two cache lines). The first 14 are what an edge reads. */
enum {
    ISO_ELEM__FIT_C = 0,     /* centroid c (3) */
    ISO_ELEM__FIT_INVS = 3,  /* 1/s */
    ISO_ELEM__FIT_D = 4,     /* rounding shift d (3), iso_elem_fit */
    ISO_ELEM__FIT_SIGMA = 7, /* N scale σ of the triangle (iso_elem_n_scale) */
    ISO_ELEM__FIT_W = 8,     /* S⁻¹, upper: 00 01 02 11 12 22 */
    ISO_ELEM__FIT_EDGE = 14, /* fields an edge reads */
    ISO_ELEM__FIT_BAD = 14,  /* 1: the fit is singular (degenerate triangle), else 0 */
    ISO_ELEM__FIT_S = 15,    /* size s */
    ISO_ELEM__FIT_STRIDE = 16
};

/* Rigid fits of ISO_ELEM__LANES triangles into their records: lane k's
 * triangle has corners v[0..2][k] (rows of x4, which holds a vertex's
 * coordinates in 4 doubles, the fourth unused, 32-byte aligned) and its
 * record at fits + ISO_ELEM__FIT_STRIDE t[k]. The values are those of
 * iso_elem_fit_compute and iso_elem_n_scale, bit for bit, and so are the
 * OpenCL kernel's. Returns nonzero if a lane's fit is singular. */
typedef struct iso_elem__fit_batch {
    const double *x4;
    double *fits;
    int v[3][ISO_ELEM__LANES];
    int t[ISO_ELEM__LANES];
} iso_elem__fit_batch;

int iso_elem__fits(const iso_elem__fit_batch *b, iso_weighting w);

/* Interior edges, one per lane: iso_elem_edge_from_fits's block, at half its
 * arithmetic, in the edge layout (a, b, p, q) of iso_elem_edge_from_fits.
 * Out: the upper triangle of the 12x12 block in q, block by block (l, m)
 * for l <= m in row order (iso_elem__edge_block): a diagonal block as its
 * upper six (00 01 02 11 12 22), an off-diagonal one as nine values row by
 * row, or column by column where the lane's flag of the block (the six
 * off-diagonal ones in order, 01 02 03 12 13 23, bits 0-5) is set. */
#define ISO_ELEM__EDGE_VALUES 78
enum {
    ISO_ELEM__EDGE_CARRY_I = 1 << 6, /* adds Ti's (1 − ω) Q1 */
    ISO_ELEM__EDGE_CARRY_J = 1 << 7  /* adds Tj's (1 − ω) Q1 */
};

/* By reference: lane k's edge has vertices v[0..3][k] (rows of x4), Ti's
 * fit record ti[k] and Tj's tj[k] (in fits, iso_elem__fit_batch), and is
 * weighted as in the assembly: ω σ_j and ω σ_i for the ordered pairs,
 * (1 − ω) σ for the Q1 it carries (flags). */
typedef struct iso_elem__edge_batch {
    const double *x4;
    const double *fits;
    double omega;
    int v[4][ISO_ELEM__LANES];
    int ti[ISO_ELEM__LANES], tj[ISO_ELEM__LANES];
    int flags[ISO_ELEM__LANES];
    iso_elem__vd q[ISO_ELEM__EDGE_VALUES]; /* out */
} iso_elem__edge_batch;

void iso_elem__edges(iso_elem__edge_batch *b);

/* By value, every lane the same edge (iso_elem_edge_from_fits): x the four
 * points (x[3 l + a]), fi and fj the first ISO_ELEM__FIT_EDGE fields of
 * Ti's and Tj's records, w = (wi, wj, qi, qj) as iso_elem_edge_from_fits
 * takes them; q as above, no block transposed. */
void iso_elem__edge_one(const double x[12], const double fi[ISO_ELEM__FIT_EDGE],
                        const double fj[ISO_ELEM__FIT_EDGE], const double w[4],
                        iso_elem__vd q[ISO_ELEM__EDGE_VALUES]);

/* Where block (l, m), l <= m, of the edge layout starts in q. */
static inline int iso_elem__edge_block(int l, int m)
{
    static const int at[4][4] = {
        {0, 6, 15, 24}, {-1, 33, 39, 48}, {-1, -1, 57, 63}, {-1, -1, -1, 72}};
    return at[l][m];
}

#endif
