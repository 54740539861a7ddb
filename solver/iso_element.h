/* solver/iso_element.h -- the per-element quadratic forms of the method
 * (docs/method.md, sections 2 and 3): best rigid fit R_T, the distortion
 * block Q1_T (9x9), and the smoothness block Q2 of an ordered pair of
 * adjacent triangles (12x12).
 *
 * These are pure functions of the corner positions, shared by the CPU
 * assembly, the tests, and as the reference the OpenCL kernels are checked
 * against. All matrices are dense row-major doubles.
 *
 * The rigid field is parametrised about the triangle's centroid c with the
 * rotation scaled by the triangle's size s (RMS corner distance from c):
 *     ρ(x) = a + b × (x − c) / s,   p = (a, b) ∈ R⁶,
 * which spans the same fields as the paper's c = 0 form but stays well
 * conditioned far from the origin and at any mesh scale. */
#ifndef ISO_ELEMENT_H
#define ISO_ELEMENT_H

#include "iso_api.h"

typedef enum iso_weighting {
    ISO_WEIGHT_PARAM = 0, /* N_T = (1/24) J⊗I: integral over the parameter triangle */
    ISO_WEIGHT_AREA = 1   /* N_T = (A_T/12) J⊗I: integral over the surface */
} iso_weighting;
/* "param", "area": iso_weighting's names (common/iso_names.h) */
ISO_API extern const char *const iso_weighting_names[];

/* Centroid c and size s of a triangle (x: 3 corners, 9 doubles). */
ISO_API void iso_elem_frame(const double x[9], double c[3], double *s);

/* N_T's scale: 1/24 (param) or area/12 (area); N_T = scale * (J ⊗ I3). */
ISO_API double iso_elem_n_scale(const double x[9], iso_weighting w);

/* E (9x6): evaluates the rigid field p, parametrised about (c, s), at the
 * three points x (9 doubles). */
ISO_API void iso_elem_eval_matrix(const double x[9], const double c[3], double s, double E[54]);

/* Best rigid fit R (6x9) of triangle x: p̂ = R v_T, in the (c, s) frame of
 * iso_elem_frame. Independent of the weighting. Returns 0, or -1 if the 6x6
 * normal matrix is not positive definite (degenerate triangle). */
ISO_API int iso_elem_rigid_fit(const double x[9], double R[54]);

/* A triangle's best rigid fit with its frame, computed once per evaluation
 * and shared by its Q1 and the Q2 of every pair it is the source of. */
typedef struct iso_elem_fit {
    /* what the edge blocks read, first: two cache lines of the 68 doubles */
    double c[3], s; /* iso_elem_frame */
    double d[3];    /* rounding shift of the frame: the scaled corners
                       (x − c)/s sum to 3d, not exactly zero */
    double inv_s;   /* 1/s: points go to the frame as (x − c) inv_s − d */
    double W[6];    /* S⁻¹ of the closed form (element.c), upper: 00 01 02 11 12 22 */
    double R[54];   /* iso_elem_rigid_fit, in the frame (c + s d, s) */
} iso_elem_fit;

/* Fills f for triangle x. Returns 0, or -1 for a degenerate triangle. */
ISO_API int iso_elem_fit_compute(const double x[9], iso_elem_fit *f);

/* What an edge block reads of a fit: its frame and W, 14 doubles against
 * iso_elem_fit's 68 (the assembly keeps one per triangle, and the memory it
 * streams through is most of its time once a solve has emptied the caches). */
typedef struct iso_elem_fit_core {
    double c[3], s, d[3], inv_s;
    double W[6];
} iso_elem_fit_core;

/* Copies f's frame and W into k. */
ISO_API void iso_elem_fit_core_of(const iso_elem_fit *f, iso_elem_fit_core *k);
/* Q1 and Q2 from a precomputed fit of triangle x (Q1) or Ti (Q2): the same
 * values as iso_elem_q1 / iso_elem_q2, with the fit not recomputed. */
ISO_API void iso_elem_q1_from_fit(const double x[9], const iso_elem_fit *f, iso_weighting w,
                                  double Q[81]);
ISO_API void iso_elem_q2_from_fit(const iso_elem_fit *fi, const double xi[9], const double xo[3],
                                  const int jmap[3], iso_weighting w, double Q[144]);

/* The smoothness block of one interior edge, both ordered pairs summed,
 * and optionally the distortion blocks of its two triangles:
 *     Q += wi Q2(Ti, Tj) + wj Q2(Tj, Ti) + qi Q1(Ti)/σ_i + qj Q1(Tj)/σ_j
 * on the local vertices (a, b, p, q): the shared edge in Ti's order, Ti's
 * third corner, Tj's third corner (xl: their 12 coordinates). fi, fj: the
 * fits of Ti and Tj (their cores). wi carries ω and Tj's N scale, wj ω and
 * Ti's; qi carries (1 − ω) and Ti's own N scale, qj Tj's (a triangle's Q1
 * blocks are all among those of any of its interior edges, so one of them
 * can carry it). fj NULL: no Tj, and wj and qj must be 0. Only Q's upper
 * triangle (12x12, row-major) is added to. Equal to the sum of
 * iso_elem_q2_from_fit's two blocks (and iso_elem_q1_from_fit's) up to
 * rounding, at about half their arithmetic. */
ISO_API void iso_elem_edge_from_fits(const iso_elem_fit_core *fi, const iso_elem_fit_core *fj,
                                     const double xl[12], double wi, double wj, double qi,
                                     double qj, double Q[144]);

/* Q1 (9x9) with d_T(v) = v_Tᵀ Q1 v_T. */
ISO_API int iso_elem_q1(const double x[9], iso_weighting w, double Q[81]);

/* Q2 (12x12) of the ordered pair (Ti, Tj): f_{i,j}(v) = v4ᵀ Q2 v4, where the
 * four local vertices are Ti's corners in Ti's order followed by Tj's corner
 * that is not in Ti. xi: Ti's 3 corners; xo: that fourth vertex; jmap: for
 * each corner of Tj (in any order) its local index 0..3. N is Tj's. */
ISO_API int iso_elem_q2(const double xi[9], const double xo[3], const int jmap[3], iso_weighting w,
                        double Q[144]);

#endif
