/* solver/supersolve_internal.h -- the triangular solves with CHOLMOD's
 * supernodal factor, as PCG's preconditioner and the direct solve use them.
 *
 * Why our own: cholmod_solve2 does one BLAS call (dtrsv, then dgemv) per
 * supernode and direction. The cactus factor has 857 supernodes of 15
 * columns on average, and at that size the calls' overheads (OpenBLAS takes
 * a lock for its buffers on each) cost about a fifth of the solve: 1.76-1.79
 * ms against 1.44-1.48 ms here (the cactus scene, 300 solves side by side),
 * one streaming pass over L each way (L: 2.5M entries, 20 MB; reading 40 MB
 * at this machine's 30 GB/s takes 1.3 ms). On the 40k bumpplane (258 MB,
 * memory-bound) the two take the same time (38.9 against 39.3 ms). The
 * solve is most of a PCG iteration, and PCG most of a real-time tick. */
#ifndef ISO_SOLVER_SUPERSOLVE_INTERNAL_H
#define ISO_SOLVER_SUPERSOLVE_INTERNAL_H

#include <cholmod.h>
#include <stddef.h>

/* Doubles of workspace either solve below needs with L: 4 n + 16 (the
 * permuted right-hand side; per half the rows below a supernode and a
 * panel's dots; the side array of the second half's sums). */
size_t iso_solver__super_work(const cholmod_factor *L);

/* x = A⁻¹ b, where L is CHOLMOD's supernodal LLᵀ factor of A (permuted:
 * P A Pᵀ = L Lᵀ, P from L->Perm), computed by cholmod_factorize: forward
 * substitution with L, then backward with Lᵀ. b and x may be the same
 * array; work holds iso_solver__super_work(L) doubles. The result agrees
 * with cholmod_solve2's to rounding (the order of the sums differs), and
 * is the same bits on every run and every instruction set (simd_internal.h).
 * Returns 0, or −1 without touching x when L is not a real supernodal LLᵀ
 * factor with int indices: the caller then uses cholmod_solve2. */
int iso_solver__super_solve(const cholmod_factor *L, const double *b, double *x, double *work);

/* The same solve on two threads: two disjoint groups of whole subtrees of
 * L's supernodal elimination tree, chosen once from L's pattern so that
 * what stays serial (the supernodes above them) plus the heavier group is
 * least, run at once (supersolve.c says how). The sums into the supernodes
 * above both groups take a fixed order, so the bits are the same on one
 * thread or two and from run to run, though not the serial solve's.
 * plan_create returns NULL when L is not supernodal, is out of memory, or
 * no split would save a tenth of the serial time; a plan serves every
 * factor with L's pattern. solve_split returns −1 as super_solve does, or
 * when L's size is not the plan's. */
typedef struct iso_solver__super_plan iso_solver__super_plan;
struct iso_solver__team;
iso_solver__super_plan *iso_solver__super_plan_create(const cholmod_factor *L);
void iso_solver__super_plan_destroy(iso_solver__super_plan *p); /* NULL is a no-op */
int iso_solver__super_solve_split(const cholmod_factor *L, const iso_solver__super_plan *p,
                                  struct iso_solver__team *team, const double *b, double *x,
                                  double *work);

#endif
