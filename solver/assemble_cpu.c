/* solver/assemble_cpu.c -- the C assembly path: element forms at the
 * current positions, added into A_ff's values and the right-hand side.
 *
 * An evaluation runs in three passes over plans made at the first one
 * (iso_solver__cpu_plan):
 *   fits    every element triangle's rigid fit, ISO_ELEM__LANES triangles at
 *           a time (element_batch.c), into one record per triangle;
 *   edges   per interior edge, both ordered pairs' ω Q2 and the (1 − ω) Q1
 *           of the triangles it carries, as one 12x12 block, ISO_ELEM__LANES
 *           edges at a time; each edge's block is then added into A's values
 *           through the edge's block positions, edge by edge in the plan's
 *           order (so every sum is in a fixed order and the values are
 *           bit-identical from run to run);
 *   others  the triangle elements no edge carries (none, in practice) and
 *           the restoration edges, one element at a time through the slot
 *           map.
 * Every triangle element's Q1 rides on one of its interior edges (its
 * blocks are all among the edge's), chosen as the OpenCL path chooses.
 *
 * On a large mesh (ISO_SOLVER_CPU_SPLIT_EDGES interior edges or more), or
 * at any size under ISO_SOLVER_SPLIT_ALWAYS (the reduced model's proxy), the
 * fits and the edges run in two fixed halves of the plan's order, on the
 * evaluating thread and on a helper (iso_solver__team): the 40k bumpplane
 * assembly is 30 ms on one core. The halves add into A's values directly,
 * except where both add to the same column: there the second half adds
 * into a side buffer of its own, which is added to A after both end, as is
 * its right-hand side. So each value is (first half's sum) + (second
 * half's sum), in an order fixed by the plan, and the bits are the same on
 * one thread or two. Smaller meshes keep one half and the element-list
 * sums of before. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "assemble_cpu_internal.h"

typedef iso_solver__element element;
#define local_count iso_solver__local_count
#define LANES ISO_ELEM__LANES
#define FIT_STRIDE ISO_ELEM__FIT_STRIDE

/* ===== fits =============================================================== */

static int report_degenerate(iso_solver *s, int t, iso_err *err)
{
    return iso_err_set(err, ISO_ENUMERIC, -1,
                       "%s: triangle %d has degenerated during the deformation (its "
                       "rigid fit is singular)",
                       iso_mesh_origin(s->m), t);
}

/* A fit has failed: names the triangle of the first element, in list
 * order, whose fit failed, as the OpenCL path does. */
static int report_first_degenerate(iso_solver *s, iso_err *err)
{
    const double *fits = s->cpu->fits;
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        if ((e->kind == 1 || e->kind == 2) &&
            fits[FIT_STRIDE * (size_t)e->tri + ISO_ELEM__FIT_BAD] != 0)
            return report_degenerate(s, e->tri, err);
    }
    return iso_err_set(err, ISO_ENUMERIC, -1, "%s: a rigid fit is singular", iso_mesh_origin(s->m));
}

/* The fit records of planned triangles [begin, end) at the positions in
 * x4; nonzero if one of them is singular. A short batch repeats its first
 * triangle. */
static int compute_fits(iso_solver *s, int begin, int end)
{
    iso_solver__cpu_plan *p = s->cpu;
    const int *tri = iso_mesh_triangles(s->m);
    iso_elem__fit_batch b = {.x4 = p->x4, .fits = p->fits};
    int bad = 0;
    for (int i0 = begin; i0 < end; i0 += LANES) {
        int n = end - i0 < LANES ? end - i0 : LANES;
        for (int k = 0; k < LANES; k++) {
            int t = p->fit_tri[i0 + (k < n ? k : 0)];
            for (int c = 0; c < 3; c++)
                b.v[c][k] = tri[3 * t + c];
            b.t[k] = t;
        }
        bad |= iso_elem__fits(&b, s->o.weighting);
    }
    return bad;
}

/* ===== edges ============================================================== */

/* Adds lane k's values of one block into A's values. A block's value
 * (i, j) -- row i of its row vertex, column j of its column vertex, which
 * iso_elem__edges has arranged -- goes to column j of the column vertex,
 * which starts at pos + j stride + j (j + 1)/2. */
static inline void add_diag(double *Ax, int pos, int st, const iso_elem__vd *v, int k)
{
    double *c0 = Ax + pos, *c1 = c0 + st + 1, *c2 = c1 + st + 2;
    c0[0] += v[0][k]; /* upper six: 00 01 02 11 12 22 */
    c1[0] += v[1][k];
    c1[1] += v[3][k];
    c2[0] += v[2][k];
    c2[1] += v[4][k];
    c2[2] += v[5][k];
}

static inline void add_off(double *Ax, int pos, int st, const iso_elem__vd *v, int k)
{
    double *c0 = Ax + pos, *c1 = c0 + st + 1, *c2 = c1 + st + 2;
    c0[0] += v[0][k];
    c0[1] += v[3][k];
    c0[2] += v[6][k];
    c1[0] += v[1][k];
    c1[1] += v[4][k];
    c1[2] += v[7][k];
    c2[0] += v[2][k];
    c2[1] += v[5][k];
    c2[2] += v[8][k];
}

/* Adds lane k's blocks of edge `it` into A's values, or the side buffer
 * for the blocks the plan sends there; a block of a constrained vertex has
 * no position. Written out block by block, so that every offset into q is
 * a constant. */
static void add_edge(const edge_item *it, const iso_elem__vd *q, int k, double *Ax, double *side)
{
#define BASE(b) (it->side >> (b)&1 ? side : Ax)
#define DIAG(b, l)                                                                                 \
    if (it->pos[b] >= 0)                                                                           \
    add_diag(BASE(b), it->pos[b], it->stride[l], q + iso_elem__edge_block(l, l), k)
#define OFF(b, o, l, m)                                                                            \
    if (it->pos[b] >= 0)                                                                           \
    add_off(BASE(b), it->pos[b], it->stride[it->flags >> (o)&1 ? (l) : (m)],                       \
            q + iso_elem__edge_block(l, m), k)
    DIAG(0, 0);
    OFF(1, 0, 0, 1);
    OFF(2, 1, 0, 2);
    OFF(3, 2, 0, 3);
    DIAG(4, 1);
    OFF(5, 3, 1, 2);
    OFF(6, 4, 1, 3);
    DIAG(7, 2);
    OFF(8, 5, 2, 3);
    DIAG(9, 3);
#undef BASE
#undef DIAG
#undef OFF
}

/* The right-hand side −Q_fh vc_h of lane k's edge, for each free vertex f
 * and handle vertex h of the edge (blocks of a free and a constrained
 * vertex are never transposed). */
static void add_edge_rhs(const iso_solver *s, const edge_item *it, const iso_elem__vd *q, int k,
                         const double *vc, double *rhs)
{
    int f[4];
    for (int l = 0; l < 4; l++)
        f[l] = s->free_of[it->v[l]];
    for (int l = 0; l < 4; l++)
        for (int m = l + 1; m < 4; m++) {
            if ((f[l] < 0) == (f[m] < 0))
                continue;
            int a = f[l] >= 0 ? l : m, h = a == l ? m : l;
            if (s->r->kind[it->v[h]] != ISO_HANDLE)
                continue;
            const iso_elem__vd *B = q + iso_elem__edge_block(l, m);
            const double *v = vc + 3 * it->v[h];
            double *y = rhs + 3 * f[a];
            for (int al = 0; al < 3; al++)
                if (a == l)
                    y[al] -=
                        B[3 * al][k] * v[0] + B[3 * al + 1][k] * v[1] + B[3 * al + 2][k] * v[2];
                else
                    y[al] -= B[al][k] * v[0] + B[3 + al][k] * v[1] + B[6 + al][k] * v[2];
        }
}

/* Edges [begin, end) of the plan into Ax (and side) and rhs. */
static void assemble_edges(iso_solver *s, int begin, int end, const double *vc, double *Ax,
                           double *side, double *rhs)
{
    const iso_solver__cpu_plan *p = s->cpu;
    iso_elem__edge_batch b = {.x4 = p->x4, .fits = p->fits, .omega = s->o.omega};
    for (int e0 = begin; e0 < end; e0 += LANES) {
        int n = end - e0 < LANES ? end - e0 : LANES;
        for (int k = 0; k < LANES; k++) { /* a short batch repeats its first */
            const edge_item *it = &p->edges[e0 + (k < n ? k : 0)];
            for (int l = 0; l < 4; l++)
                b.v[l][k] = it->v[l];
            b.ti[k] = it->ti;
            b.tj[k] = it->tj;
            b.flags[k] = it->flags;
        }
        iso_elem__edges(&b);
        for (int k = 0; k < n; k++) {
            const edge_item *it = &p->edges[e0 + k];
            add_edge(it, b.q, k, Ax, side);
            if (it->flags & EDGE_RHS)
                add_edge_rhs(s, it, b.q, k, vc, rhs);
        }
    }
}

/* ===== the other elements ================================================= */

/* GCC at -O2 keeps 3-trip loops as loops; unrolled, the block loops below
 * lose their index arithmetic and the ≤ k bound's branches. */
#if defined(__GNUC__) && !defined(__clang__)
#define UNROLL3 _Pragma("GCC unroll 3")
#else
#define UNROLL3
#endif

/* Restoration term of edge element e = (i, j): μ Q, Q = w_e [uuᵀ −uuᵀ;
 * −uuᵀ uuᵀ], and its linear part: the minimiser of vᵀAv + gᵀv solves
 * A v = −g/2, so each free endpoint's right-hand side gets −μ w_e c_e (∓u),
 * c_e = (|e| − L_e)/τ. Added straight into the three blocks (ii, ij, jj)
 * through the slot map, with a handle endpoint's share moved to the
 * right-hand side; the generic 6×6 element path (scatter_upper) cost
 * 42 ns an edge, half as much again as the rest of a cactus assembly. The
 * products and sums are those of that path, in its order, so the result
 * is the same to the bit. */
static void restore_edge(iso_solver *s, const element *e, const double *x, const double *vc,
                         double *Ax, double *rhs)
{
    const double *a = x + 3 * e->v[0], *b = x + 3 * e->v[1];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double len = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int k = 0; k < 3; k++)
        u[k] /= len;
    double we = s->edge_w[e->tri], c = (len - s->rest_len[e->tri]) / s->o.restore_tau;
    double mu = s->o.restore_mu, P[3][3]; /* μ w_e u uᵀ, each entry as (w_e u_r) u_c */
    UNROLL3 for (int r = 0; r < 3; r++) UNROLL3 for (int q = 0; q < 3; q++) P[r][q] =
        mu * (we * u[r] * u[q]);
    int f[2] = {s->free_of[e->v[0]], s->free_of[e->v[1]]};
    for (int end = 0; end < 2; end++) {
        if (f[end] < 0)
            continue;
        double sign = end == 0 ? -1.0 : 1.0;
        for (int k = 0; k < 3; k++)
            rhs[3 * f[end] + k] -= mu * we * c * sign * u[k];
    }
    const int *sl = s->slots + e->slot; /* blocks (0,0), (0,1), (1,0), (1,1) */
    if (f[0] >= 0 && sl[0] >= 0)
        UNROLL3 for (int k = 0; k < 3; k++) UNROLL3 for (int r = 0; r <= k; r++) Ax[sl[k] + r] +=
            P[r][k];
    /* Edges are (i, j) with i < j (iso_mesh.h) and free indices follow the
     * vertices', so when both are free A's upper triangle holds this block (−P)
     * as rows of i, columns of j: never transposed. */
    if (sl[3] >= 0) {
        UNROLL3 for (int k = 0; k < 3; k++) UNROLL3 for (int r = 0; r < 3; r++) Ax[sl[3 + k] + r] -=
            P[r][k];
    } else if (f[0] >= 0 && s->r->kind[e->v[1]] == ISO_HANDLE) { /* j moves i */
        const double *v = vc + 3 * e->v[1];
        UNROLL3 for (int r = 0; r < 3; r++) rhs[3 * f[0] + r] +=
            P[r][0] * v[0] + P[r][1] * v[1] + P[r][2] * v[2];
    } else if (f[1] >= 0 && s->r->kind[e->v[0]] == ISO_HANDLE) { /* i moves j */
        const double *v = vc + 3 * e->v[0];
        UNROLL3 for (int r = 0; r < 3; r++) rhs[3 * f[1] + r] +=
            P[0][r] * v[0] + P[1][r] * v[1] + P[2][r] * v[2];
    }
    if (f[1] >= 0 && sl[9] >= 0)
        UNROLL3 for (int k = 0; k < 3; k++) UNROLL3 for (int r = 0; r <= k; r++)
            Ax[sl[9 + k] + r] += P[r][k];
}

/* (1 − ω) Q1 of a triangle element no edge carries; −1 if degenerate. */
static int lone_q1(iso_solver *s, const element *e, const double *x, double *Q)
{
    double xi[9];
    iso_elem_fit f;
    for (int k = 0; k < 3; k++)
        memcpy(xi + 3 * k, x + 3 * e->v[k], 3 * sizeof(double));
    if (iso_elem_fit_compute(xi, &f) != 0)
        return -1;
    iso_elem_q1_from_fit(xi, &f, s->o.weighting, Q);
    double w = 1.0 - s->o.omega;
    for (int i = 0; i < 9; i++) /* the upper triangle is what is scattered */
        for (int j = i; j < 9; j++)
            Q[9 * i + j] *= w;
    return 0;
}

/* Adds the upper triangle of element e's block Q (dimension 3 n, its
 * weight already in) through the slot map. */
static void scatter_upper(iso_solver *s, const element *e, int n, const double *Q, const double *vc,
                          double *Ax, double *rhs)
{
    const int *sl = s->slots + e->slot;
    int nl = local_count(e), ld = 3 * n, g[4], f[4];
    for (int l = 0; l < n; l++) {
        g[l] = e->v[l];
        f[l] = s->free_of[g[l]];
    }
    for (int l = 0; l < n; l++)
        for (int m = l; m < n; m++) {
            if (f[l] < 0 && f[m] < 0)
                continue;
            const double *B = Q + ld * 3 * l + 3 * m; /* B[ld i + j]: row i, column j */
            const int *pos = sl + 3 * (nl * l + m);
            if (pos[0] >= 0) { /* rows of l, columns of m */
                if (f[l] == f[m]) {
                    UNROLL3 for (int k = 0; k < 3; k++) UNROLL3 for (int al = 0; al <= k; al++)
                        Ax[pos[k] + al] += B[ld * al + k];
                } else {
                    UNROLL3 for (int k = 0; k < 3; k++) UNROLL3 for (int al = 0; al < 3; al++)
                        Ax[pos[k] + al] += B[ld * al + k];
                }
                continue;
            }
            pos = sl + 3 * (nl * m + l);
            if (pos[0] >= 0) { /* rows of m, columns of l: the transpose */
                UNROLL3 for (int k = 0; k < 3; k++) UNROLL3 for (int al = 0; al < 3; al++)
                    Ax[pos[k] + al] += B[ld * k + al];
                continue;
            }
            /* one end free, the other constrained: a handle moves it */
            int a = f[l] >= 0 ? l : m, b = a == l ? m : l;
            if (l == m || s->r->kind[g[b]] != ISO_HANDLE)
                continue;
            const double *v = vc + 3 * g[b];
            double *y = rhs + 3 * f[a];
            if (a == l)
                UNROLL3 for (int al = 0; al < 3; al++) y[al] -=
                    B[ld * al] * v[0] + B[ld * al + 1] * v[1] + B[ld * al + 2] * v[2];
            else
                UNROLL3 for (int al = 0; al < 3; al++) y[al] -=
                    B[al] * v[0] + B[ld + al] * v[1] + B[2 * ld + al] * v[2];
        }
}

/* The elements outside the edges, in list order; those before the first
 * pair element (lone Q1s) or after the last (restoration edges). */
static int assemble_others(iso_solver *s, const double *x, const double *vc, int restoration,
                           double *Ax, double *rhs)
{
    const iso_solver__cpu_plan *p = s->cpu;
    double Q[81];
    for (int i = 0; i < p->nother; i++) {
        const element *e = &s->el[p->other[i]];
        if ((e->kind == 3) != restoration)
            continue;
        if (e->kind == 3)
            restore_edge(s, e, x, vc, Ax, rhs);
        else if (lone_q1(s, e, x, Q) == 0) {
            scatter_upper(s, e, 3, Q, vc, Ax, rhs);
        } else {
            return -1;
        }
    }
    return 0;
}

/* ===== two halves ========================================================= */

typedef struct halves_job {
    iso_solver *s;
    const double *vc;
    int phase; /* 0: fits, 1: edges */
} halves_job;

/* One half of a phase (iso_solver__team_run): the first half into A and
 * the right-hand side, the second into them, its side buffer and its own
 * right-hand side. */
static void run_half(void *ctx, int half)
{
    const halves_job *j = ctx;
    iso_solver *s = j->s;
    iso_solver__cpu_plan *p = s->cpu;
    if (j->phase == 0) {
        p->bad[half] =
            half == 0 ? compute_fits(s, 0, p->fit_split) : compute_fits(s, p->fit_split, p->nfit);
        return;
    }
    if (half == 0) {
        assemble_edges(s, 0, p->edge_split, j->vc, s->A->x, NULL, s->B->x);
        return;
    }
    memset(p->side, 0, p->nside * sizeof *p->side);
    memset(p->rhs1, 0, 3 * (size_t)s->nf * sizeof *p->rhs1);
    assemble_edges(s, p->edge_split, p->ne, j->vc, s->A->x, p->side, p->rhs1);
}

/* The second half's sums into A's shared columns and the right-hand side. */
static void merge_halves(iso_solver *s, double *Ax, double *rhs)
{
    const iso_solver__cpu_plan *p = s->cpu;
    const int *Ap = s->A->p;
    for (int k = 0; k < p->nshared; k++) {
        int f = p->shared[k], len = Ap[3 * f + 3] - Ap[3 * f];
        double *a = Ax + Ap[3 * f];
        const double *b = p->side + p->side_off[f];
        for (int i = 0; i < len; i++)
            a[i] += b[i];
    }
    for (int i = 0; i < 3 * s->nf; i++)
        rhs[i] += p->rhs1[i];
}

int iso_solver__assemble_cpu(iso_solver *s, const double *x, const double *vc, iso_err *err)
{
    if (!s->cpu) {
        int rc = iso_solver__cpu_plan_make(s, err);
        if (rc != ISO_OK)
            return rc;
    }
    iso_solver__cpu_plan *p = s->cpu;
    for (int i = 0; i < s->nv; i++)
        memcpy(p->x4 + 4 * (size_t)i, x + 3 * (size_t)i, 3 * sizeof *x);
    double *Ax = s->A->x, *rhs = s->B->x;
    int n3 = 3 * s->nf;
    if (p->halves == 1) {
        if (compute_fits(s, 0, p->nfit) != 0)
            return report_first_degenerate(s, err);
    } else {
        halves_job job = {s, vc, 0};
        iso_solver__team_run(p->team, run_half, &job);
        if (p->bad[0] || p->bad[1])
            return report_first_degenerate(s, err);
    }
    memset(Ax, 0, (size_t)((int *)s->A->p)[n3] * sizeof(double));
    memset(rhs, 0, (size_t)n3 * sizeof(double));
    if (assemble_others(s, x, vc, 0, Ax, rhs) != 0) /* triangles precede pairs */
        return report_first_degenerate(s, err);
    if (p->halves == 1) {
        assemble_edges(s, 0, p->ne, vc, Ax, NULL, rhs);
    } else {
        halves_job job = {s, vc, 1};
        iso_solver__team_run(p->team, run_half, &job);
        merge_halves(s, Ax, rhs);
    }
    assemble_others(s, x, vc, 1, Ax, rhs); /* restoration edges follow them */
    return ISO_OK;
}
