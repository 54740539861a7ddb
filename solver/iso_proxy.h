/* solver/iso_proxy.h -- the reduced model: the method on a proxy of the
 * mesh, the full mesh following it.
 *
 * A mesh of 40k vertices and more is too large for the method to step at
 * an interactive rate on two cores (a factor of the 40k plane is 246 MB and
 * one solve with it ~40 ms). The reduced model runs the method, unchanged,
 * on a proxy: a simplification of the mesh to a vertex budget, whose
 * vertices are a subset of the mesh's (half-edge collapses ordered by a
 * quadric error plus a length term, so that flat regions thin out evenly;
 * collapses keep every vertex in its region, every region's boundary, the
 * mesh's boundary, the surface's topology and a floor on triangle quality).
 * A subset rather than resampled points, so that each proxy vertex is a
 * mesh vertex at rest and the proxy carries the mesh's regions exactly.
 *
 * The full mesh follows by a detail-preserving reconstruction: each full
 * vertex i lies, at rest, over a point P_i = Σ_k β_k Y_k of a proxy
 * triangle (a, b, c) (barycentric weights β), at an offset X_i − P_i, and
 *     x_i = Σ_k β_k y_k + R̄_i (X_i − P_i),   k = a, b, c,
 * with X, Y the rest positions of the mesh and the proxy and y the proxy's
 * current ones: the point goes where the deformed triangle takes it, and
 * the offset (the mesh's detail over the proxy) turns with R̄_i, the
 * rotations R_k of the corners' rings since rest blended (quaternions
 * weighted by β in one hemisphere, normalised; a handle vertex's R is its
 * handle's, a fixed vertex's the identity). So the rest pose and every
 * rigid motion are reproduced exactly, and the result is continuous across
 * proxy edges. Handle and fixed vertices of the full mesh are then placed
 * exactly: at their handle's pose, and at rest. Last, the free vertices
 * are fitted to the rotations R̄ edge by edge (solver/proxy_fit.c), which
 * takes out the kinks of a piecewise-affine map along the proxy's edges
 * and keeps the proxy's own motion; exact at rest and under rigid motions
 * too.
 *
 * Everything here is deterministic (no clock, no race): the same mesh,
 * regions and budget give the same proxy and the same positions, bit for
 * bit, whether the prolongation runs on one thread or two. */
#ifndef ISO_PROXY_H
#define ISO_PROXY_H

#include "iso_err.h"
#include "iso_geom.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_solver.h"

typedef struct iso_proxy iso_proxy; /* opaque */

/* The smallest budget accepted: fewer proxy vertices cannot hold a
 * mesh's regions and curvature in any useful way. */
#define ISO_PROXY_MIN_BUDGET 200

/* Builds the reduced model of mesh m with regions r (both must outlive the
 * proxy): a proxy of at most `budget` vertices (≥ ISO_PROXY_MIN_BUDGET), or
 * as few as the collapses allowed (every region keeps a few vertices, and a
 * collapse that would fold or flatten a triangle is skipped). A mesh with
 * no more vertices than the budget is refused (ISO_EINVAL): the reduced
 * model is for what the method cannot step in full. ISO_ENOMEM, or
 * ISO_EMESH should the proxy fail the mesh checks. */
ISO_API ISO_NODISCARD int iso_proxy_create(const iso_mesh *m, const iso_regions *r, int budget,
                                           iso_proxy **out, iso_err *err);
ISO_API void iso_proxy_destroy(iso_proxy *p); /* NULL is a no-op */

/* The proxy's mesh and regions (owned by the proxy; the same handles as
 * the full mesh's), and the full mesh's vertex each proxy vertex is. */
ISO_API const iso_mesh *iso_proxy_mesh(const iso_proxy *p);
ISO_API const iso_regions *iso_proxy_regions(const iso_proxy *p);
ISO_API int iso_proxy_full_vertex(const iso_proxy *p, int k);

/* The full mesh's positions x (3 nv) from the proxy's y (3 np) and each
 * handle's pose (r->n_handles of them; the poses y's handle vertices were
 * placed at). Runs on the caller's thread and one helper of the proxy's
 * own for large meshes; the same bits either way. */
ISO_API void iso_proxy_prolong(iso_proxy *p, const double *y, const iso_pose *poses, double *x);

/* The smoothness weight that lets the proxy bend as the full mesh does
 * under `omega` (what `proxy_smoothness: matched` steps it with). The
 * smoothness term d2 holds a strain part, which does not depend on the
 * mesh's resolution, and a bending part, which grows with the square of
 * the edge length: on a proxy whose edges are H long against the mesh's h,
 * the same ω resists bending (H/h)² times more, and the method finds a
 * stiffer field than on the mesh itself. So the proxy takes the ω' with
 * ω'/(1 − ω') = ω/(1 − ω) · (h/H)², (h/H)² = np / nv (a proxy vertex
 * stands for nv / np of the mesh's area): its field bends as freely as the
 * mesh's would. Measured against the whole mesh's integral in
 * docs/method.md (the reduced model), with why it is not the default.
 * ω = 1 (no d1) stays 1. A function of the two meshes alone, so a replay
 * takes the same ω'. */
ISO_API double iso_proxy_omega(const iso_proxy *p, double omega);

/* Turns the mesh's solver options into the proxy's: ω matched when
 * so->proxy_smoothness asks for it, and the assembly and solves in halves
 * at any size (ISO_SOLVER_SPLIT_ALWAYS: the proxy's assembly is a third of
 * a tick, and the full mesh's reconstruction already uses both threads). */
ISO_API void iso_proxy_solver_opts(const iso_proxy *p, iso_solver_opts *so);

/* What the prolongations so far cost their fit (solver/proxy_fit.c): the
 * calls, the conjugate-gradient iterations in all and the most in one,
 * and the fits that failed (CHOLMOD could not solve the proxy's small
 * system; the prolongation then stood as it was). */
typedef struct iso_proxy_stats {
    long prolongations;
    long fit_iterations, fit_max_iterations;
    long fit_failures;
} iso_proxy_stats;
ISO_API void iso_proxy_get_stats(const iso_proxy *p, iso_proxy_stats *out);

/* The budget `auto` chooses for a mesh of nv vertices stepped at tick_hz:
 * 0 (no proxy) where the full method fits the tick on two cores (8,000
 * vertices at 60 Hz), else the proxy size that does (4,000 at 60 Hz); both
 * grow in proportion to the period below 60 Hz and stay at the 60 Hz
 * figures above it. A function of nv and tick_hz alone, so that a replay
 * chooses as the run did. */
ISO_API int iso_proxy_auto_budget(int nv, double tick_hz);

/* What solver.proxy (0 off, N, or ISO_SOLVER_PROXY_AUTO) makes of mesh m at
 * tick_hz: the proxy budget to build, 0 for the whole mesh (also when N is
 * not below the mesh's size), and a phrase for people that says which and
 * why ("a proxy of at most 4000 vertices that the whole mesh of 40401
 * follows (solver.proxy: auto; ...)"). The one rule the loop builds by and
 * `check` announces. */
ISO_API int iso_proxy_choose(const iso_mesh *m, int proxy, double tick_hz, char *why, size_t cap);

#endif
