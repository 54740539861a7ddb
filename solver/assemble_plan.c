/* solver/assemble_plan.c -- the OpenCL assembly's plan
 * (assemble_plan_internal.h): the work lists of the element kernels and
 * the numbering of their slots, made once per solver. Plain C: the tests
 * check it without an OpenCL device. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "assemble_plan_internal.h"

typedef iso_solver__element element;
typedef iso_solver__cl_plan plan;
#define local_count iso_solver__local_count
#define CARRY_I ISO_ELEM__EDGE_CARRY_I
#define CARRY_J ISO_ELEM__EDGE_CARRY_J

void iso_solver__cl_plan_free(plan *p)
{
    free(p->fit_work);
    free(p->pair_work);
    free(p->rest_work);
    free(p->rest_lin);
    free(p->rest_par);
    free(p->fit_of_tri);
    free(p->blk_of_pos);
    free(p->blk_dst);
    for (int k = 0; k < ISO_CL_C_KINDS; k++)
        free(p->c[k]);
    free(p->blk_ptr);
    free(p->hb_ptr);
    free(p->hb_vtx);
    free(p->lin_ptr);
    free(p->first_el); /* NULL when the assembler took them */
    free(p->tri_of);
}

/* Fit item of triangle t (made on first use); `el` the element index that
 * uses it, so a degenerate triangle is reported as the C path reports it. */
static int fit_item(plan *p, const int *tri, int t, int el)
{
    int f = p->fit_of_tri[t];
    if (f < 0) {
        f = p->fit_of_tri[t] = p->n_fit++;
        memcpy(p->fit_work + 4 * f, tri + 3 * t, 3 * sizeof(int));
        p->fit_work[4 * f + 3] = 0;
        p->first_el[f] = el;
        p->tri_of[f] = t;
    }
    if (el < p->first_el[f])
        p->first_el[f] = el;
    return f;
}

static int add_contrib(plan *p, int kind, int key, int hv, int *at)
{
    if (p->n[kind] == p->cap[kind]) {
        size_t cap = p->cap[kind] ? 2 * p->cap[kind] : 1024;
        iso_solver__cl_contrib *c = realloc(p->c[kind], cap * sizeof *c);
        if (!c)
            return -1;
        p->c[kind] = c;
        p->cap[kind] = cap;
    }
    p->c[kind][p->n[kind]++] = (iso_solver__cl_contrib){key, hv, at};
    return 0;
}

/* Plans block (la, lb) of element e (local vertices; the block's rows are
 * la's): its slot offset goes to *at, and, if step is not NULL, the step
 * between its rows in the slot, 3, or 1 where it is to be written
 * transposed (the rows of lb), since a slot holds the rows of the lower
 * free index (A), or of the free vertex (handle block). */
static int plan_block(const iso_solver *s, plan *p, const element *e, int la, int lb, int *at,
                      int *step)
{
    int nl = local_count(e), va = e->v[la], vb = e->v[lb];
    int fa = s->free_of[va], fb = s->free_of[vb];
    const int *sl = s->slots + e->slot;
    if (step)
        *step = 3;
    if (fa >= 0 && fb >= 0) {
        int lo = fa <= fb ? la : lb, hi = lo == la ? lb : la;
        if (step && fa > fb)
            *step = 1;
        return add_contrib(p, ISO_CL_C_A, p->blk_of_pos[sl[3 * (lo * nl + hi)]], 0, at);
    }
    if (la != lb && (fa >= 0) != (fb >= 0)) {
        int f = fa >= 0 ? fa : fb, h = fa >= 0 ? vb : va;
        if (s->r->kind[h] == ISO_HANDLE) {
            if (step && fb >= 0)
                *step = 1;
            return add_contrib(p, ISO_CL_C_HANDLE, f, h, at);
        }
    }
    return add_contrib(p, ISO_CL_C_DUMP, 0, 0, at);
}

/* Numbers the slots of one kind: stable by key, so that each key's slots
 * are consecutive, in the order planned (element-list order). From offset
 * `base` on, `size` doubles a slot, or 6 where `diag` (A's blocks, may be
 * NULL) flags the key as a diagonal block. ptr (nkeys + 1) gets the offset
 * of each key's first slot, hv (may be NULL) each slot's handle vertex. */
static int number_slots(plan *p, int kind, int nkeys, const int *diag, int base, int size,
                        int **ptr, int **hv)
{
    size_t n = p->n[kind];
    const iso_solver__cl_contrib *c = p->c[kind];
    int *count = calloc((size_t)nkeys + 1, sizeof *count);
    int *next = malloc(((size_t)nkeys + 1) * sizeof *next);
    *ptr = malloc(((size_t)nkeys + 1) * sizeof **ptr);
    if (!count || !next || !*ptr || (hv && !(*hv = malloc((n + 1) * sizeof **hv)))) {
        free(count);
        free(next);
        return -1;
    }
    for (size_t i = 0; i < n; i++)
        count[c[i].key]++;
    int at = base, slots = 0;
    for (int k = 0; k < nkeys; k++) {
        int nk = count[k];
        (*ptr)[k] = next[k] = at;
        at += nk * (diag && diag[4 * k + 3] ? 6 : size);
        count[k] = slots; /* now: the number of k's first slot */
        slots += nk;
    }
    (*ptr)[nkeys] = at;
    for (size_t i = 0; i < n; i++) {
        int k = c[i].key;
        *c[i].at = next[k];
        next[k] += diag && diag[4 * k + 3] ? 6 : size;
        if (hv)
            (*hv)[count[k]++] = c[i].hv;
    }
    free(count);
    free(next);
    return 0;
}

/* The 3x3 blocks of A_ff in column order: block j of column block fb starts
 * at Ap[3fb + k] + 3j in column 3fb + k; the diagonal block comes last. */
static int find_blocks(const iso_solver *s, plan *p)
{
    const int *Ap = s->A->p;
    p->blk_of_pos = malloc((p->nnz + 1) * sizeof *p->blk_of_pos);
    int nb = 0;
    for (int f = 0; f < s->nf; f++)
        nb += (Ap[3 * f + 1] - Ap[3 * f] - 1) / 3 + 1;
    p->blk_dst = malloc(((size_t)nb + 1) * 4 * sizeof *p->blk_dst);
    if (!p->blk_of_pos || !p->blk_dst)
        return -1;
    for (size_t i = 0; i < p->nnz; i++)
        p->blk_of_pos[i] = -1;
    int b = 0;
    for (int f = 0; f < s->nf; f++) {
        int n = (Ap[3 * f + 1] - Ap[3 * f] - 1) / 3 + 1;
        for (int j = 0; j < n; j++, b++) {
            for (int k = 0; k < 3; k++)
                p->blk_dst[4 * b + k] = Ap[3 * f + k] + 3 * j;
            p->blk_dst[4 * b + 3] = j == n - 1;
            p->blk_of_pos[Ap[3 * f] + 3 * j] = b;
        }
    }
    p->n_blocks = nb;
    return 0;
}

/* Pads a work list of `rows` rows from n items to np (whole work-groups):
 * a padding item repeats item 0, but its slots (rows slot0 to slot0 +
 * nslots − 1) are slots of its own that nothing reads. */
static int pad_items(plan *p, int *work, int rows, int n, int np, int slot0, int nslots)
{
    for (int j = n; j < np; j++)
        for (int r = 0; r < rows; r++) {
            work[r * np + j] = work[r * np];
            if (r >= slot0 && r < slot0 + nslots &&
                add_contrib(p, ISO_CL_C_DUMP, 0, 0, &work[r * np + j]) != 0)
                return -1;
        }
    return 0;
}

static size_t padded(int n, size_t wg)
{
    return ((size_t)n + wg - 1) / wg * wg;
}

/* The pair elements' indices (the first of each mirrored two) in
 * element-list order, into *out (n of them). */
static int pair_elements(const iso_solver *s, int **out, int *n, iso_err *err)
{
    *n = 0;
    *out = malloc(((size_t)s->nel + 1) * sizeof **out);
    if (!*out)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 2) {
            if (i + 1 >= s->nel || !iso_solver__is_mirror(&s->el[i], &s->el[i + 1]))
                return iso_err_set(err, ISO_EINVAL, -1,
                                   "OpenCL: internal error: pair element %d has no mirror", i);
            (*out)[(*n)++] = i++;
        }
    return ISO_OK;
}

/* The pair items in Z-order (iso_solver__z_order: what one item touches in
 * x, the fit records and the slots, the next ones touch again; the slots
 * of one block are in this order too). Each triangle element's Q1 goes
 * with the first pair element, in element-list order, whose Ti or Tj it
 * is, as on the C path (q1_el: the element, −1 once carried). */
static int plan_pairs(const iso_solver *s, plan *p, int *q1_el, iso_err *err)
{
    const int *tri = iso_mesh_triangles(s->m);
    int n, *pe = NULL;
    int rc = pair_elements(s, &pe, &n, err);
    int np = p->np = (int)padded(n, p->wg[1]);
    int *carry = malloc(((size_t)n + 1) * sizeof *carry),
        *ends = malloc(2 * ((size_t)n + 1) * sizeof *ends);
    int *order = malloc(((size_t)n + 1) * sizeof *order);
    p->pair_work = malloc(((size_t)ISO_CL_PLAN_PAIR_ROWS * (size_t)np + 1) * sizeof(int));
    if (rc == ISO_OK && (!carry || !ends || !order || !p->pair_work))
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int k = 0; k < n && rc == ISO_OK; k++) {
        const element *e = &s->el[pe[k]];
        int ti = e->tri, tj = s->el[pe[k] + 1].tri, map[4];
        carry[k] = (q1_el[ti] >= 0 ? CARRY_I : 0) | (q1_el[tj] >= 0 ? CARRY_J : 0);
        if (q1_el[ti] >= 0)
            q1_el[ti] = -1;
        if (q1_el[tj] >= 0)
            q1_el[tj] = -1;
        iso_solver__edge_layout(e, map);
        ends[k] = e->v[map[0]];
        ends[n + k] = e->v[map[1]];
    }
    if (rc == ISO_OK && iso_solver__z_order(s->m, n, ends, ends + n, order) != 0)
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    int *w = p->pair_work;
    for (int j = 0; j < n && rc == ISO_OK; j++) {
        int k = order[j], i = pe[k];
        const element *e = &s->el[i];
        int ti = e->tri, tj = s->el[i + 1].tri, map[4];
        /* the edge layout (a, b, p, q): the shared edge in Ti's order,
         * Ti's third corner, Tj's third corner */
        iso_solver__edge_layout(e, map);
        for (int l = 0; l < 4; l++)
            w[l * np + j] = e->v[map[l]];
        w[4 * np + j] = fit_item(p, tri, ti, i);
        w[5 * np + j] = fit_item(p, tri, tj, i + 1);
        w[6 * np + j] = carry[k];
        for (int l = 0, b = 0, o = 0; l < 4 && rc == ISO_OK; l++)
            for (int m = l; m < 4 && rc == ISO_OK; m++, b++) {
                int *step = l != m ? &w[(17 + o++) * np + j] : NULL;
                if (plan_block(s, p, e, map[l], map[m], &w[(7 + b) * np + j], step) != 0)
                    rc = iso_err_set(err, ISO_ENOMEM, -1,
                                     "out of memory planning the OpenCL assembly");
            }
        p->n_pair++;
    }
    if (rc == ISO_OK && n > 0 && pad_items(p, w, ISO_CL_PLAN_PAIR_ROWS, n, np, 7, 10) != 0)
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int j = n; j < np && rc == ISO_OK; j++) /* padding carries no Q1 */
        w[6 * np + j] = 0;
    free(pe);
    free(carry);
    free(ends);
    free(order);
    return rc;
}

/* The restoration items, in element-list order. */
static int plan_restoration(const iso_solver *s, plan *p, iso_err *err)
{
    int n = 0;
    for (int i = 0; i < s->nel; i++)
        n += s->el[i].kind == 3;
    int nr = p->nrp = (int)padded(n, p->wg[2]);
    p->rest_work = malloc(((size_t)ISO_CL_PLAN_REST_ROWS * (size_t)nr + 1) * sizeof(int));
    p->rest_lin = malloc((2 * (size_t)nr + 1) * sizeof(int));
    p->rest_par = malloc((2 * (size_t)nr + 1) * sizeof(double));
    if (!p->rest_work || !p->rest_lin || !p->rest_par)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    int *w = p->rest_work, *lin = p->rest_lin;
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        if (e->kind != 3)
            continue;
        int j = p->n_rest++, rc = 0;
        w[j] = e->v[0];
        w[nr + j] = e->v[1];
        p->rest_par[j] = s->rest_len[e->tri];
        p->rest_par[nr + j] = s->edge_w[e->tri];
        /* blocks 00, 01, 11: symmetric, so never written transposed */
        rc |= plan_block(s, p, e, 0, 0, &w[2 * nr + j], NULL);
        rc |= plan_block(s, p, e, 0, 1, &w[3 * nr + j], NULL);
        rc |= plan_block(s, p, e, 1, 1, &w[4 * nr + j], NULL);
        for (int end = 0; end < 2; end++) {
            int f = s->free_of[e->v[end]];
            rc |= add_contrib(p, f >= 0 ? ISO_CL_C_LIN : ISO_CL_C_DUMP, f, 0, &lin[end * nr + j]);
        }
        if (rc != 0)
            return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    }
    if (n > 0 && (pad_items(p, w, ISO_CL_PLAN_REST_ROWS, n, nr, 2, 3) != 0 ||
                  pad_items(p, lin, 2, n, nr, 0, 2) != 0))
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int j = n; j < nr; j++) {
        p->rest_par[j] = p->rest_par[0];
        p->rest_par[nr + j] = p->rest_par[nr];
    }
    return ISO_OK;
}

/* Numbers A's blocks in the order the element kernels first add to them,
 * so that the slots of the blocks an item adds to lie near those of the
 * items before it (its neighbours, in Z-order), instead of all over the
 * buffer at A's column order: fewer lines fetched for the scattered
 * writes. reduce_blocks runs in this order too; each block's place in A is
 * in its blk_dst. */
static int order_blocks(plan *p)
{
    int nb = p->n_blocks, next = 0;
    int *renum = malloc(((size_t)nb + 1) * sizeof *renum);
    int *dst = malloc(4 * ((size_t)nb + 1) * sizeof *dst);
    if (!renum || !dst) {
        free(renum);
        free(dst);
        return -1;
    }
    for (int b = 0; b < nb; b++)
        renum[b] = -1;
    for (size_t i = 0; i < p->n[ISO_CL_C_A]; i++)
        if (renum[p->c[ISO_CL_C_A][i].key] < 0)
            renum[p->c[ISO_CL_C_A][i].key] = next++;
    for (int b = 0; b < nb; b++) /* one no element adds to: none, in practice */
        if (renum[b] < 0)
            renum[b] = next++;
    for (size_t i = 0; i < p->n[ISO_CL_C_A]; i++)
        p->c[ISO_CL_C_A][i].key = renum[p->c[ISO_CL_C_A][i].key];
    for (int b = 0; b < nb; b++)
        memcpy(dst + 4 * renum[b], p->blk_dst + 4 * b, 4 * sizeof *dst);
    free(p->blk_dst);
    p->blk_dst = dst;
    free(renum);
    return 0;
}

/* The slots: A's blocks, handle blocks, linear parts, then the slots
 * nothing reads, each numbered in element-list order within its key. */
static int plan_slots(const iso_solver *s, plan *p, iso_err *err)
{
    size_t most = 9 * (p->n[ISO_CL_C_A] + p->n[ISO_CL_C_HANDLE] + p->n[ISO_CL_C_DUMP]) +
                  3 * p->n[ISO_CL_C_LIN];
    if (most > INT_MAX)
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "OpenCL: the slot buffer (%zu values) is too large for int offsets",
                           most);
    for (size_t i = 0; i < p->n[ISO_CL_C_A]; i++)
        if (p->c[ISO_CL_C_A][i].key < 0)
            return iso_err_set(err, ISO_EINVAL, -1,
                               "OpenCL: internal error: an element block is not in the pattern");
    if (order_blocks(p) != 0)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    if (number_slots(p, ISO_CL_C_A, p->n_blocks, p->blk_dst, 0, 9, &p->blk_ptr, NULL) != 0 ||
        number_slots(p, ISO_CL_C_HANDLE, s->nf, NULL, p->hbase = p->blk_ptr[p->n_blocks], 9,
                     &p->hb_ptr, &p->hb_vtx) != 0 ||
        number_slots(p, ISO_CL_C_LIN, s->nf, NULL, p->hb_ptr[s->nf], 3, &p->lin_ptr, NULL) != 0)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    size_t dbase = (size_t)p->lin_ptr[s->nf];
    for (size_t i = 0; i < p->n[ISO_CL_C_DUMP]; i++)
        *p->c[ISO_CL_C_DUMP][i].at = (int)(dbase + 9 * i);
    p->nslot = dbase + 9 * p->n[ISO_CL_C_DUMP];
    return ISO_OK;
}

/* Builds the work lists of the three element kernels and the slots. */
int iso_solver__cl_plan_make(const iso_solver *s, const size_t wg[3], plan *p, iso_err *err)
{
    memset(p, 0, sizeof *p);
    memcpy(p->wg, wg, sizeof p->wg);
    p->nnz = (size_t)((const int *)s->A->p)[3 * s->nf];
    int nt = iso_mesh_triangle_count(s->m);
    p->fit_work = malloc(4 * ((size_t)nt + 1 + p->wg[0]) * sizeof(int));
    p->fit_of_tri = malloc(((size_t)nt + 1) * sizeof(int));
    p->first_el = malloc(((size_t)nt + 1) * sizeof(int));
    p->tri_of = malloc(((size_t)nt + 1) * sizeof(int));
    int *q1_el = malloc(((size_t)nt + 1) * sizeof *q1_el);
    if (!p->fit_work || !p->fit_of_tri || !p->first_el || !p->tri_of || !q1_el ||
        find_blocks(s, p) != 0) {
        free(q1_el);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    }
    for (int t = 0; t < nt; t++)
        p->fit_of_tri[t] = q1_el[t] = -1;
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 1)
            q1_el[s->el[i].tri] = i;
    /* The fit items: made in the pair items' order (plan_pairs), so that
     * neighbours' records are near each other; then every element's
     * triangle, so that each knows the first element that uses it. */
    int rc = plan_pairs(s, p, q1_el, err);
    const int *tri = iso_mesh_triangles(s->m);
    for (int i = 0; i < s->nel && rc == ISO_OK; i++)
        if (s->el[i].kind == 1 || s->el[i].kind == 2)
            fit_item(p, tri, s->el[i].tri, i);
    /* Every triangle element's Q1 goes with one of its interior edges. There
     * always is one: a triangle with no interior edge is a part of the mesh
     * of its own, which iso_solver_create refuses unless its three vertices
     * are constrained, and then it is no element. */
    for (int t = 0; t < nt && rc == ISO_OK; t++)
        if (q1_el[t] >= 0)
            rc = iso_err_set(err, ISO_EINVAL, -1,
                             "OpenCL: internal error: triangle %d is an element, but no "
                             "interior edge carries it",
                             t);
    free(q1_el);
    if (rc == ISO_OK)
        rc = plan_restoration(s, p, err);
    if (rc == ISO_OK)
        rc = plan_slots(s, p, err);
    if (rc != ISO_OK)
        return rc;
    p->nfp = (int)padded(p->n_fit, p->wg[0]);
    for (int f = p->n_fit; f < p->nfp; f++) /* padding: item 0 again, into its own record */
        memcpy(p->fit_work + 4 * f, p->fit_work, 4 * sizeof(int));
    return ISO_OK;
}
