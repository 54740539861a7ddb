/* tests/support/iso_arap.h -- as-rigid-as-possible deformation (Sorkine & Alexa 2007),
 * run to convergence: the baseline the isometry solver is compared with.
 * Part of the test-support library (tests/CMakeLists.txt), not of
 * libisoshape: the tests and tests/tools/arap_reference link it.
 *
 * Energy (classic "spokes" ARAP, CGAL's ORIGINAL_ARAP):
 *
 *     E(x, R) = Σ_i Σ_{j ∈ N(i)} w_ij |(x_i − x_j) − R_i (p_i − p_j)|²
 *
 * p = rest positions, x = deformed positions, R_i one rotation per vertex,
 * w_ij = ½ (max(0, cot α_ij) + max(0, cot β_ij)), the angles opposite edge
 * ij in its one or two triangles, taken on the rest mesh. Negative cotangents
 * (angles above 90°) are clamped to zero as CGAL's Surface_mesh_deformation
 * does for ORIGINAL_ARAP: with a negative weight the global step's matrix
 * can be indefinite and the local-global iteration no longer minimises E.
 * On a mesh without obtuse angles the clamp changes nothing.
 *
 * Iteration (the local-global scheme, in CGAL's order): rotations start at
 * the identity (the rest pose's own optimal rotations); each iteration is
 *   global: minimise E over the free vertices with R fixed -- one sparse
 *           Laplacian solve, the matrix factored once with CHOLMOD;
 *   local:  R_i = the rotation closest to Σ_j w_ij (x_i − x_j)(p_i − p_j)ᵀ
 *           (3x3 SVD; a reflection is turned into a rotation by flipping
 *           the singular vector of the smallest singular value).
 * Neither step can raise E, so the energy after each iteration is
 * non-increasing (up to rounding). Because the first step is global with
 * R = I, the free vertices' starting positions do not enter: the starting
 * pose is the rest pose with the constrained vertices at their targets.
 *
 * Fixed and handle vertices are both Dirichlet values: they sit at
 * x_constrained and never move. Unreferenced vertices keep their rest
 * position. The solve is written for the displacement x − p, so a problem
 * whose targets equal the rest positions returns the rest pose bit for bit. */
#ifndef ISO_ARAP_H
#define ISO_ARAP_H

#include "iso_err.h"
#include "iso_mesh.h"
#include "iso_regions.h"

typedef struct iso_arap_stats {
    /* input (optional): a caller-owned buffer for the energy after each
     * iteration; NULL or energy_cap = 0 records nothing. */
    double *energy_history;
    int energy_cap;
    /* output: */
    int iterations;        /* local-global iterations run */
    int converged;         /* 1 if stopped because |ΔE| <= rel_tol·E */
    int history_len;       /* entries written to energy_history */
    int n_free;            /* unknown vertices (free and referenced) */
    int n_clamped;         /* rest-mesh angles whose negative cotangent was clamped */
    double energy_initial; /* E at the starting pose with R = I */
    double energy;         /* E after the last iteration */
    double seconds_factor; /* assembly, analysis and factorization */
    double seconds_iterate;
} iso_arap_stats;

/* Deforms m under the constraints of r by ARAP.
 *
 * // input:
 *   m, r            the mesh and its regions (r->nv == vertex count)
 *   x_constrained   3*nv; read only at fixed and handle vertices: their
 *                   target positions (finite)
 *   max_iterations  >= 1
 *   rel_tol         >= 0: stop after iteration k >= 2 once
 *                   |E_{k−1} − E_k| <= rel_tol · E_k (0 = run max_iterations
 *                   unless E stops changing exactly). This is CGAL's
 *                   criterion; CGAL's default 1e-4 stops well short of
 *                   convergence on the benchmark (the bar: 376 iterations,
 *                   metricErr 13.3, against 12.0 after 1000)
 * // output:
 *   x_out           3*nv; may be the same array as x_constrained
 *   st              may be NULL; see iso_arap_stats (its input fields are read)
 *   err             may be NULL
 *
 * Returns ISO_OK, or: ISO_EINVAL (NULL arguments, region count mismatch,
 * max_iterations < 1, bad rel_tol, non-finite target), ISO_ECONSTRAINT (no
 * fixed or handle vertex, or a group of free vertices linked to none by a
 * positive weight: the global step would be singular), ISO_ENUMERIC (CHOLMOD
 * found the matrix not positive definite), ISO_ENOMEM. On failure x_out is
 * not written. */
ISO_NODISCARD int iso_arap_solve(const iso_mesh *m, const iso_regions *r,
                                 const double *x_constrained, int max_iterations, double rel_tol,
                                 double *x_out, iso_arap_stats *st, iso_err *err);

/* The rotation closest to M (row-major 3x3) in the Frobenius norm,
 * i.e. the R maximising tr(Rᵀ M): R = U diag(1, 1, det(U Vᵀ)) Vᵀ for
 * M = U Σ Vᵀ. M = 0 gives I. Exposed for tests. */
void iso_arap_closest_rotation(const double M[9], double R[9]);

#endif
