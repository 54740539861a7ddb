/* solver/assemble_cpu_plan.c -- the C assembly's plan, made at its first
 * evaluation (assemble_cpu_internal.h; assemble_cpu.c says how it is
 * run): the triangles whose fits are needed, the interior edges in
 * Z-order with where each block of theirs goes in A, the elements outside
 * the edges, and on a large mesh its two halves. */
#include <stdlib.h>
#include <string.h>

#include "assemble_cpu_internal.h"

typedef iso_solver__element element;
#define LANES ISO_ELEM__LANES
#define FIT_STRIDE ISO_ELEM__FIT_STRIDE

int iso_solver__cpu_halves(const iso_solver__cpu_plan *p)
{
    return p->halves;
}

iso_solver__team *iso_solver__cpu_team(const iso_solver__cpu_plan *p)
{
    return p->team;
}

void iso_solver__cpu_plan_destroy(iso_solver__cpu_plan *p)
{
    if (!p)
        return;
    free(p->fit_tri);
    free(p->fits);
    free(p->x4);
    free(p->edges);
    free(p->other);
    iso_solver__team_destroy(p->team);
    free(p->side);
    free(p->shared);
    free(p->side_off);
    free(p->rhs1);
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
        it->side = 0;
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

/* The column (free vertex) block b of edge `it` adds to: the higher free
 * index of its two vertices. */
static int block_column(const iso_solver *s, const edge_item *it, int b)
{
    static const int row[10] = {0, 0, 0, 0, 1, 1, 1, 2, 2, 3},
                     col[10] = {0, 1, 2, 3, 1, 2, 3, 2, 3, 3};
    int fa = s->free_of[it->v[row[b]]], fb = s->free_of[it->v[col[b]]];
    return fa > fb ? fa : fb;
}

/* Two halves: each takes half the fits and half the edges, in whole
 * batches; the second half's blocks in a column that the first half adds
 * to as well go to the side buffer, which holds each such column's values
 * whole (its three scalar columns, laid out as in A), so that the blocks'
 * positions and strides stay A's, shifted. */
static int plan_halves(iso_solver *s, iso_solver__cpu_plan *p, iso_err *err)
{
    const int *Ap = s->A->p;
    p->halves = 2;
    p->fit_split = (p->nfit / 2 + LANES - 1) / LANES * LANES;
    p->edge_split = (p->ne / 2 + LANES - 1) / LANES * LANES;
    unsigned char *mask = calloc((size_t)s->nf + 1, 1);
    p->side_off = malloc(((size_t)s->nf + 1) * sizeof *p->side_off);
    p->shared = malloc(((size_t)s->nf + 1) * sizeof *p->shared);
    p->rhs1 = malloc((3 * (size_t)s->nf + 1) * sizeof *p->rhs1);
    if (!mask || !p->side_off || !p->shared || !p->rhs1) {
        free(mask);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the C assembly");
    }
    for (int e = 0; e < p->ne; e++)
        for (int b = 0; b < 10; b++)
            if (p->edges[e].pos[b] >= 0)
                mask[block_column(s, &p->edges[e], b)] |= e < p->edge_split ? 1 : 2;
    for (int f = 0; f < s->nf; f++) {
        p->side_off[f] = -1;
        if (mask[f] != 3)
            continue;
        p->shared[p->nshared++] = f;
        p->side_off[f] = (int)p->nside;
        p->nside += (size_t)(Ap[3 * f + 3] - Ap[3 * f]);
    }
    free(mask);
    for (int e = p->edge_split; e < p->ne; e++) {
        edge_item *it = &p->edges[e];
        for (int b = 0; b < 10; b++) {
            int f = it->pos[b] >= 0 ? block_column(s, it, b) : -1;
            if (f < 0 || p->side_off[f] < 0)
                continue;
            it->pos[b] = p->side_off[f] + (it->pos[b] - Ap[3 * f]);
            it->side |= 1 << b;
        }
    }
    p->side = malloc((p->nside + 1) * sizeof *p->side);
    if (!p->side)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the C assembly");
    if (s->cpu_helper)
        p->team = iso_solver__team_create(); /* NULL: both halves on this thread */
    return ISO_OK;
}

int iso_solver__cpu_plan_make(iso_solver *s, iso_err *err)
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
    p->halves = 1;
    for (int t = 0; t < nt; t++)
        q1_el[t] = -1;
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 1)
            q1_el[s->el[i].tri] = i;
    int rc = plan_fits(s, p, err);
    if (rc == ISO_OK)
        rc = plan_edges(s, p, q1_el, err);
    if (rc == ISO_OK && p->ne >= s->cpu_split_edges)
        rc = plan_halves(s, p, err);
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
