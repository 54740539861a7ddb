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
 * blocks are all among the edge's), chosen as the OpenCL path chooses. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "element_internal.h"
#include "solver_internal.h"

typedef iso_solver__element element;
#define local_count iso_solver__local_count
#define LANES ISO_ELEM__LANES
#define FIT_STRIDE ISO_ELEM__FIT_STRIDE

/* ===== plans ============================================================== */

/* One interior edge, its two ordered pairs, in the edge layout (a, b, p, q)
 * of iso_solver__edge_layout. */
enum {
    EDGE_CARRY_I = ISO_ELEM__EDGE_CARRY_I, /* adds Ti's Q1 */
    EDGE_CARRY_J = ISO_ELEM__EDGE_CARRY_J, /* adds Tj's Q1 */
    EDGE_RHS = 1 << 8                      /* a free vertex with a handle vertex */
};
typedef struct edge_item {
    int v[4];      /* global vertices a, b, p, q */
    int ti, tj;    /* the triangles */
    int flags;     /* bits 0-5: off-diagonal block 01 02 03 12 13 23 goes to A transposed */
    int stride[4]; /* per vertex: 3 (blocks in its column − 1), or −1 if not free */
    int pos[10];   /* per block (l <= m, row order): its first value in A, or −1 */
} edge_item;

struct iso_solver__cpu_plan {
    int nfit;
    int *fit_tri;     /* the elements' triangles, ascending */
    double *fits;     /* FIT_STRIDE per triangle (element_internal.h), 64-byte aligned */
    double *x4;       /* the positions, 4 doubles a vertex, 32-byte aligned */
    int ne;           /* interior edges */
    edge_item *edges; /* in Z-order (sort_edges_z) */
    int nother;
    int *other; /* elements outside the edges: lone Q1, restoration */
};

void iso_solver__cpu_plan_destroy(iso_solver__cpu_plan *p)
{
    if (!p)
        return;
    free(p->fit_tri);
    free(p->fits);
    free(p->x4);
    free(p->edges);
    free(p->other);
    free(p);
}

/* The element after pair element i if it is i's mirror, else NULL. */
static const element *mirror_of(const iso_solver *s, int i)
{
    return i + 1 < s->nel && iso_solver__is_mirror(&s->el[i], &s->el[i + 1]) ? &s->el[i + 1] : NULL;
}

/* Where block (l, m) of edge e goes: pos and the column strides, and the
 * transpose flag; the slot map says where each column of it starts.
 * −1: an internal inconsistency (the slot map is not what build_pattern
 * makes). */
static int plan_blocks(const iso_solver *s, const element *e, const int map[4], edge_item *it)
{
    const int *sl = s->slots + e->slot, nl = 4;
    int f[4], b = 0, n_off = 0;
    for (int l = 0; l < 4; l++) {
        f[l] = s->free_of[it->v[l]];
        it->stride[l] = -1;
    }
    for (int l = 0; l < 4; l++)
        for (int m = l; m < 4; m++, b++) {
            int off = l != m ? n_off++ : -1;
            it->pos[b] = -1;
            if (f[l] < 0 || f[m] < 0) {
                if (f[l] >= 0 || f[m] >= 0) {
                    int c = f[l] < 0 ? l : m;
                    it->flags |= s->r->kind[it->v[c]] == ISO_HANDLE ? EDGE_RHS : 0;
                }
                continue;
            }
            int tr = f[l] > f[m], lo = tr ? m : l, hi = tr ? l : m;
            const int *col = sl + 3 * (nl * map[lo] + map[hi]);
            int st = col[1] - col[0] - 1;
            if (col[0] < 0 || col[2] != col[0] + 2 * st + 3 ||
                (it->stride[hi] >= 0 && it->stride[hi] != st))
                return -1;
            it->stride[hi] = st;
            it->pos[b] = col[0];
            if (tr)
                it->flags |= 1 << off;
        }
    return 0;
}

/* Which pair element carries each triangle element's Q1: the first whose
 * Ti or Tj it is, as in the OpenCL path. q1_el[t]: the triangle element of
 * t, −1 once carried. */
static void plan_carry(int ti, int tj, int *q1_el, edge_item *it)
{
    if (q1_el[ti] >= 0) {
        it->flags |= EDGE_CARRY_I;
        q1_el[ti] = -1;
    }
    if (q1_el[tj] >= 0) {
        it->flags |= EDGE_CARRY_J;
        q1_el[tj] = -1;
    }
}

/* The edges in Z-order (order.c): cachegrind's simulated 2 MiB cache
 * misses 2.9x less often in the scatter than in element-list order, and
 * the cactus assembly takes 1.18 ms instead of 1.29 (median of 9
 * alternating runs). The order is fixed at the plan, so the sums are still
 * in one order from run to run. */
static int sort_edges_z(const iso_solver *s, iso_solver__cpu_plan *p)
{
    int *a = malloc(((size_t)p->ne + 1) * sizeof *a), *b = malloc(((size_t)p->ne + 1) * sizeof *b);
    int *order = malloc(((size_t)p->ne + 1) * sizeof *order);
    edge_item *sorted = malloc(((size_t)p->ne + 1) * sizeof *sorted);
    int rc = !a || !b || !order || !sorted ? -1 : 0;
    for (int e = 0; e < p->ne && rc == 0; e++) {
        a[e] = p->edges[e].v[0];
        b[e] = p->edges[e].v[1];
    }
    if (rc == 0)
        rc = iso_solver__z_order(s->m, p->ne, a, b, order);
    if (rc == 0) {
        for (int e = 0; e < p->ne; e++)
            sorted[e] = p->edges[order[e]];
        free(p->edges);
        p->edges = sorted;
        sorted = NULL;
    }
    free(a);
    free(b);
    free(order);
    free(sorted);
    return rc;
}

static int plan_edges(iso_solver *s, iso_solver__cpu_plan *p, int *q1_el, iso_err *err)
{
    p->edges = malloc(((size_t)s->nel + 1) * sizeof *p->edges);
    if (!p->edges)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the C assembly");
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        if (e->kind != 2)
            continue;
        const element *mirror = mirror_of(s, i);
        if (!mirror) /* build_elements makes both or neither: same four vertices */
            return iso_err_set(err, ISO_EINVAL, -1, "internal error: pair element %d has no mirror",
                               i);
        edge_item *it = &p->edges[p->ne++];
        int map[4];
        iso_solver__edge_layout(e, map);
        for (int l = 0; l < 4; l++)
            it->v[l] = e->v[map[l]];
        it->ti = e->tri;
        it->tj = mirror->tri;
        it->flags = 0;
        plan_carry(it->ti, it->tj, q1_el, it);
        if (plan_blocks(s, e, map, it) != 0)
            return iso_err_set(err, ISO_EINVAL, -1,
                               "internal error: the slot map of element %d is not in A's layout",
                               i);
        i++;
    }
    if (sort_edges_z(s, p) != 0)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the C assembly");
    return ISO_OK;
}

/* The triangles whose fits an evaluation needs: every element's. */
static int plan_fits(iso_solver *s, iso_solver__cpu_plan *p, iso_err *err)
{
    int nt = iso_mesh_triangle_count(s->m);
    size_t nv4 = ((size_t)s->nv + 2) / 2 * 2; /* whole 64-byte lines */
    char *used = calloc((size_t)nt + 1, 1);
    p->fit_tri = malloc(((size_t)nt + 1) * sizeof *p->fit_tri);
    p->fits = aligned_alloc(64, ((size_t)nt + 1) * FIT_STRIDE * sizeof *p->fits);
    p->x4 = aligned_alloc(64, nv4 * 4 * sizeof *p->x4);
    if (!used || !p->fit_tri || !p->fits || !p->x4) {
        free(used);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the rigid-fit records");
    }
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 1 || s->el[i].kind == 2)
            used[s->el[i].tri] = 1;
    for (int t = 0; t < nt; t++)
        if (used[t])
            p->fit_tri[p->nfit++] = t;
    free(used);
    memset(p->x4, 0, nv4 * 4 * sizeof *p->x4);
    return ISO_OK;
}

static int make_plan(iso_solver *s, iso_err *err)
{
    iso_solver__cpu_plan *p = calloc(1, sizeof *p);
    int nt = iso_mesh_triangle_count(s->m);
    int *q1_el = malloc(((size_t)nt + 1) * sizeof *q1_el);
    if (p)
        p->other = malloc(((size_t)s->nel + 1) * sizeof *p->other);
    if (!p || !q1_el || !p->other) {
        free(q1_el);
        iso_solver__cpu_plan_destroy(p);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the C assembly");
    }
    for (int t = 0; t < nt; t++)
        q1_el[t] = -1;
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 1)
            q1_el[s->el[i].tri] = i;
    int rc = plan_fits(s, p, err);
    if (rc == ISO_OK)
        rc = plan_edges(s, p, q1_el, err);
    if (rc == ISO_OK) {
        /* A triangle element with no interior edge keeps its own Q1
         * (iso_solver_create only lets one through with all three vertices
         * constrained, when it is no element at all, but this costs nothing
         * to allow); restoration edges follow, in list order. */
        for (int i = 0; i < s->nel; i++)
            if ((s->el[i].kind == 1 && q1_el[s->el[i].tri] == i) || s->el[i].kind == 3)
                p->other[p->nother++] = i;
    }
    free(q1_el);
    if (rc != ISO_OK) {
        iso_solver__cpu_plan_destroy(p);
        return rc;
    }
    s->cpu = p;
    return ISO_OK;
}

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

/* Every planned triangle's fit record at positions x (copied into x4
 * first); nonzero if one of them is singular. A short batch repeats its
 * first triangle. */
static int compute_fits(iso_solver *s, const double *x)
{
    iso_solver__cpu_plan *p = s->cpu;
    const int *tri = iso_mesh_triangles(s->m);
    for (int i = 0; i < s->nv; i++)
        memcpy(p->x4 + 4 * (size_t)i, x + 3 * (size_t)i, 3 * sizeof *x);
    iso_elem__fit_batch b = {.x4 = p->x4, .fits = p->fits};
    int bad = 0;
    for (int i0 = 0; i0 < p->nfit; i0 += LANES) {
        int n = p->nfit - i0 < LANES ? p->nfit - i0 : LANES;
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

/* Adds lane k's blocks of edge `it` into A's values; a block of a
 * constrained vertex has no position. Written out block by block, so that
 * every offset into q is a constant. */
static void add_edge(const edge_item *it, const iso_elem__vd *q, int k, double *Ax)
{
#define DIAG(b, l)                                                                                 \
    if (it->pos[b] >= 0)                                                                           \
    add_diag(Ax, it->pos[b], it->stride[l], q + iso_elem__edge_block(l, l), k)
#define OFF(b, o, l, m)                                                                            \
    if (it->pos[b] >= 0)                                                                           \
    add_off(Ax, it->pos[b], it->stride[it->flags >> (o)&1 ? (l) : (m)],                            \
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

static void assemble_edges(iso_solver *s, const double *vc, double *Ax, double *rhs)
{
    const iso_solver__cpu_plan *p = s->cpu;
    iso_elem__edge_batch b = {.x4 = p->x4, .fits = p->fits, .omega = s->o.omega};
    for (int e0 = 0; e0 < p->ne; e0 += LANES) {
        int n = p->ne - e0 < LANES ? p->ne - e0 : LANES;
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
            add_edge(it, b.q, k, Ax);
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

int iso_solver__assemble_cpu(iso_solver *s, const double *x, const double *vc, iso_err *err)
{
    if (!s->cpu) {
        int rc = make_plan(s, err);
        if (rc != ISO_OK)
            return rc;
    }
    if (compute_fits(s, x) != 0)
        return report_first_degenerate(s, err);
    double *Ax = s->A->x, *rhs = s->B->x;
    int n3 = 3 * s->nf;
    memset(Ax, 0, (size_t)((int *)s->A->p)[n3] * sizeof(double));
    memset(rhs, 0, (size_t)n3 * sizeof(double));
    if (assemble_others(s, x, vc, 0, Ax, rhs) != 0) /* triangles precede pairs */
        return report_first_degenerate(s, err);
    assemble_edges(s, vc, Ax, rhs);
    assemble_others(s, x, vc, 1, Ax, rhs); /* restoration edges follow them */
    return ISO_OK;
}
