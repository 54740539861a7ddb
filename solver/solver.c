/* solver/solver.c -- the free–free system and its CHOLMOD factorization
 * (iso_solver.h).
 *
 * Layout. Free vertices are numbered 0..nf−1; unknown 3f+α is component α
 * of free vertex f. A_ff is stored as CHOLMOD's upper triangle (stype = 1),
 * column-compressed. Because every coupling is a dense 3x3 vertex block, the
 * rows of block (fa, fb) in scalar column 3fb+k are contiguous: an element
 * needs only, per local vertex pair, the three column offsets where its
 * block starts. Those offsets (the "slot map") are computed once.
 *
 * Elements are the triangles (Q1, 3 vertices) and the ordered pairs of
 * edge-adjacent triangles (Q2, 4 vertices). Elements without a free vertex
 * contribute nothing to A_ff or the right-hand side and are dropped. */
#include "iso_solver.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_clock.h"
#include "iso_names.h"
#include "solver_internal.h"
#include "supersolve_internal.h"

const char *const iso_assembly_names[] = {"cpu", "opencl", "auto", NULL};
const char *const iso_refactor_names[] = {"adaptive", "always", NULL};
const char *const iso_precond_names[] = {"rotated", "plain", NULL};

typedef iso_solver__element element;
#define local_count iso_solver__local_count

void iso_solver_opts_default(iso_solver_opts *o)
{
    o->omega = 1.0 / 3.0;
    o->weighting = ISO_WEIGHT_PARAM;
    o->restore_mu = 0.0;
    o->restore_tau = 0.0;
    o->assembly = ISO_ASSEMBLY_CPU;
    o->cl_device = NULL;
    o->refactor = ISO_REFACTOR_ALWAYS;
    o->cg_tol = 1e-10;
    o->cg_max_iter = 12;
    o->preconditioner = ISO_PRECOND_ROTATED;
    o->worker_lag = 0;
    o->worker_ahead = 1;
    o->threads.omp = ISO_SOLVER_OMP_CALLER;
    o->threads.blas = ISO_SOLVER_BLAS_LEAVE;
}

static int check_opts(const iso_solver_opts *o, iso_err *err)
{
    if (!(o->omega > 0.0 && o->omega <= 1.0))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "omega = %g is outside (0, 1]: with omega = 0 a flat region makes "
                           "the system singular, and above 1 the distortion term turns negative",
                           o->omega);
    if (o->weighting != ISO_WEIGHT_PARAM && o->weighting != ISO_WEIGHT_AREA)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown weighting %d", (int)o->weighting);
    if (!(o->restore_mu >= 0.0 && isfinite(o->restore_mu)))
        return iso_err_set(err, ISO_EINVAL, -1, "restoration weight mu = %g must be >= 0",
                           o->restore_mu);
    if (o->restore_mu > 0.0 && !(o->restore_tau > 0.0 && isfinite(o->restore_tau)))
        return iso_err_set(err, ISO_EINVAL, -1, "restoration time constant tau = %g must be > 0",
                           o->restore_tau);
    if (o->preconditioner != ISO_PRECOND_ROTATED && o->preconditioner != ISO_PRECOND_PLAIN)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown preconditioner %d",
                           (int)o->preconditioner);
    if (o->worker_lag < 0 || o->worker_lag > ISO_SOLVER_WORKER_LAG_MAX)
        return iso_err_set(err, ISO_EINVAL, -1, "worker_lag = %d is outside [0, %d]", o->worker_lag,
                           ISO_SOLVER_WORKER_LAG_MAX);
    if (o->worker_lag > 0 && o->refactor != ISO_REFACTOR_ADAPTIVE)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "worker_lag = %d asks for a factorization worker, which only the "
                           "adaptive scheme uses (refactor is %s)",
                           o->worker_lag, iso_names_get(iso_refactor_names, (int)o->refactor));
    if (o->threads.omp != ISO_SOLVER_OMP_CALLER && o->threads.omp != ISO_SOLVER_OMP_LEAVE)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown OpenMP thread policy %d",
                           (int)o->threads.omp);
    if (o->threads.blas != ISO_SOLVER_BLAS_LEAVE && o->threads.blas != ISO_SOLVER_BLAS_SIZED)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown BLAS thread policy %d",
                           (int)o->threads.blas);
    return ISO_OK;
}

/* ===== constraint check: every part of the mesh must be pinned ========== */

static int uf_find(int *parent, int i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

typedef struct part_info {
    int n_free, n_constrained, first_free;
    int have_p0, have_p1, pinned;
    double p0[3], p1[3];
} part_info;

/* Streams the constrained points of a part: pinned once three of them span
 * a plane (a rigid field vanishing at three non-collinear points is zero). */
static void part_add_constrained(part_info *pi, const double *p, double eps)
{
    pi->n_constrained++;
    if (pi->pinned)
        return;
    if (!pi->have_p0) {
        memcpy(pi->p0, p, sizeof pi->p0);
        pi->have_p0 = 1;
        return;
    }
    double d[3] = {p[0] - pi->p0[0], p[1] - pi->p0[1], p[2] - pi->p0[2]};
    if (!pi->have_p1) {
        if (sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) > eps) {
            memcpy(pi->p1, p, sizeof pi->p1);
            pi->have_p1 = 1;
        }
        return;
    }
    double u[3] = {pi->p1[0] - pi->p0[0], pi->p1[1] - pi->p0[1], pi->p1[2] - pi->p0[2]};
    double cx = u[1] * d[2] - u[2] * d[1], cy = u[2] * d[0] - u[0] * d[2],
           cz = u[0] * d[1] - u[1] * d[0];
    double lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    if (sqrt(cx * cx + cy * cy + cz * cz) / lu > eps)
        pi->pinned = 1;
}

/* Parts are the classes of triangles joined through shared edges: the d2
 * coupling acts across edges only, so parts that touch at a single vertex
 * can rotate about it independently and must be pinned separately. */
static int check_constraints(const iso_mesh *m, const iso_regions *r, iso_err *err)
{
    int nt = iso_mesh_triangle_count(m), ne = iso_mesh_edge_count(m);
    const int *tri = iso_mesh_triangles(m), *et = iso_mesh_edge_triangles(m);
    const double *x = iso_mesh_positions(m);
    double eps = 1e-9 * iso_mesh_bbox_diagonal(m);
    int *parent = malloc((size_t)(nt > 0 ? nt : 1) * sizeof *parent);
    part_info *pi = calloc((size_t)(nt > 0 ? nt : 1), sizeof *pi);
    int *seen = calloc((size_t)(r->nv > 0 ? r->nv : 1), sizeof *seen);
    int rc = ISO_OK;
    if (!parent || !pi || !seen) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory checking constraints");
        goto out;
    }
    for (int t = 0; t < nt; t++)
        parent[t] = t;
    for (int e = 0; e < ne; e++)
        if (et[2 * e + 1] >= 0) {
            int a = uf_find(parent, et[2 * e]), b = uf_find(parent, et[2 * e + 1]);
            if (a != b)
                parent[a] = b;
        }
    /* seen[v] = 1 + the last part that counted v, so shared vertices count
     * once per part (parts meeting at a vertex each see it). */
    for (int t = 0; t < nt; t++) {
        int p = uf_find(parent, t);
        for (int k = 0; k < 3; k++) {
            int v = tri[3 * t + k];
            if (seen[v] == p + 1)
                continue;
            seen[v] = p + 1;
            if (r->kind[v] == ISO_FREE) {
                if (pi[p].n_free++ == 0)
                    pi[p].first_free = v;
            } else {
                part_add_constrained(&pi[p], x + 3 * v, eps);
            }
        }
    }
    for (int t = 0; t < nt && rc == ISO_OK; t++) {
        if (uf_find(parent, t) != t || pi[t].n_free == 0)
            continue;
        if (pi[t].n_constrained == 0)
            rc = iso_err_set(err, ISO_ECONSTRAINT, -1,
                             "%s: ill-posed: the part of the mesh containing free vertex %d "
                             "(%d free vertices) touches no fixed or handle vertex, so its "
                             "motion is undetermined",
                             iso_mesh_origin(m), pi[t].first_free, pi[t].n_free);
        else if (!pi[t].pinned)
            rc = iso_err_set(err, ISO_ECONSTRAINT, -1,
                             "%s: constraints too few: the %d fixed/handle vertices of the part "
                             "containing free vertex %d lie on one line, so the part could "
                             "rotate about it; fix or move at least three non-collinear vertices",
                             iso_mesh_origin(m), pi[t].n_constrained, pi[t].first_free);
    }
out:
    free(parent);
    free(pi);
    free(seen);
    return rc;
}

/* ===== elements ========================================================= */

static int third_vertex(const int *t, int a, int b)
{
    for (int k = 0; k < 3; k++)
        if (t[k] != a && t[k] != b)
            return t[k];
    return -1;
}

static void make_pair(const int *tri, int ti, int tj, int a, int b, element *e)
{
    const int *Ti = tri + 3 * ti, *Tj = tri + 3 * tj;
    e->kind = 2;
    e->tri = ti;
    memcpy(e->v, Ti, 3 * sizeof(int));
    e->v[3] = third_vertex(Tj, a, b);
    for (int k = 0; k < 3; k++) {
        e->jmap[k] = 3;
        for (int l = 0; l < 3; l++)
            if (Tj[k] == Ti[l])
                e->jmap[k] = l;
    }
}

static int has_free(const iso_solver *s, const element *e)
{
    int n = local_count(e);
    for (int k = 0; k < n; k++)
        if (s->free_of[e->v[k]] >= 0)
            return 1;
    return 0;
}

/* Rest lengths and weights w_e of the restoration term (iso_solver.h). */
static int init_restoration(iso_solver *s, iso_err *err)
{
    const iso_mesh *m = s->m;
    int ne = iso_mesh_edge_count(m);
    const int *edges = iso_mesh_edges(m), *et = iso_mesh_edge_triangles(m),
              *tri = iso_mesh_triangles(m);
    const double *x = iso_mesh_positions(m);
    s->rest_len = malloc((size_t)(ne + 1) * sizeof(double));
    s->edge_w = malloc((size_t)(ne + 1) * sizeof(double));
    if (!s->rest_len || !s->edge_w)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the restoration term");
    for (int k = 0; k < ne; k++) {
        const double *a = x + 3 * edges[2 * k], *b = x + 3 * edges[2 * k + 1];
        double d0 = b[0] - a[0], d1 = b[1] - a[1], d2 = b[2] - a[2];
        s->rest_len[k] = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
        double w = 1.0;
        if (s->o.weighting == ISO_WEIGHT_AREA) {
            double area = 0;
            int cnt = 0;
            for (int side = 0; side < 2; side++) {
                int t = et[2 * k + side];
                if (t < 0)
                    continue;
                double xt[9];
                for (int c = 0; c < 3; c++)
                    memcpy(xt + 3 * c, x + 3 * tri[3 * t + c], 3 * sizeof(double));
                area += 12.0 * iso_elem_n_scale(xt, ISO_WEIGHT_AREA);
                cnt++;
            }
            w = 2.0 * area / cnt;
        }
        s->edge_w[k] = w;
    }
    return ISO_OK;
}

/* All triangles, then both ordered pairs of each interior edge, then (with
 * restoration) the edges. */
static int build_elements(iso_solver *s, iso_err *err)
{
    const iso_mesh *m = s->m;
    int nt = iso_mesh_triangle_count(m), ne = iso_mesh_edge_count(m);
    const int *tri = iso_mesh_triangles(m), *edges = iso_mesh_edges(m),
              *et = iso_mesh_edge_triangles(m);
    s->el = malloc((size_t)(nt + 3 * ne + 1) * sizeof *s->el);
    if (!s->el)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d elements", nt + 2 * ne);
    int n = 0;
    for (int t = 0; t < nt; t++) {
        element *e = &s->el[n];
        memset(e, 0, sizeof *e);
        e->kind = 1;
        e->tri = t;
        memcpy(e->v, tri + 3 * t, 3 * sizeof(int));
        e->v[3] = -1;
        n += has_free(s, e);
    }
    for (int k = 0; k < ne; k++) {
        int t0 = et[2 * k], t1 = et[2 * k + 1];
        if (t1 < 0)
            continue;
        make_pair(tri, t0, t1, edges[2 * k], edges[2 * k + 1], &s->el[n]);
        n += has_free(s, &s->el[n]);
        make_pair(tri, t1, t0, edges[2 * k], edges[2 * k + 1], &s->el[n]);
        n += has_free(s, &s->el[n]);
    }
    /* Edge elements only when restoration is on, so that with it off the
     * element list, pattern and summation order are exactly the paper's. */
    for (int k = 0; k < ne && s->o.restore_mu > 0; k++) {
        element *e = &s->el[n];
        memset(e, 0, sizeof *e);
        e->kind = 3;
        e->tri = k; /* for edges: the edge index */
        e->v[0] = edges[2 * k];
        e->v[1] = edges[2 * k + 1];
        e->v[2] = e->v[3] = -1;
        n += has_free(s, e);
    }
    s->nel = n;
    return s->o.restore_mu > 0 ? init_restoration(s, err) : ISO_OK;
}

/* ===== pattern ========================================================== */

static int find_row(const int *rows, int n, int row)
{
    int lo = 0, hi = n - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        if (rows[mid] == row)
            return mid;
        if (rows[mid] < row)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

/* Calls visit(ctx, col, row) for every coupling of two free vertices that
 * an element makes, row <= col, duplicates included. */
static void each_coupling(const iso_solver *s, void (*visit)(void *, int, int), void *ctx)
{
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        int nl = local_count(e);
        for (int a = 0; a < nl; a++)
            for (int b = a; b < nl; b++) {
                int fa = s->free_of[e->v[a]], fb = s->free_of[e->v[b]];
                if (fa >= 0 && fb >= 0)
                    visit(ctx, fa > fb ? fa : fb, fa > fb ? fb : fa);
            }
    }
}

/* A column-wise pattern: during block_pattern the buckets being filled,
 * after it the block pattern of A_ff's upper triangle, which the scalar
 * pattern and the ordering are both made from. */
typedef struct buckets {
    int *start; /* nf + 1: where each column's rows begin in rows */
    int *rows;
} buckets;

static void count_coupling(void *ctx, int col, int row)
{
    (void)row;
    ((buckets *)ctx)->start[col + 1]++;
}

static void put_coupling(void *ctx, int col, int row)
{
    buckets *b = ctx;
    b->rows[b->start[col]++] = row;
}

/* The block pattern of A_ff's upper triangle into b, column by column
 * (b->start zeroed, nf + 1), each column's rows unique and ascending. A
 * bucket per column, then each column deduplicated with a mark and sorted
 * (a column has a dozen rows); a global sort of the couplings cost 15 ms of
 * the cactus solver's creation. */
static int block_pattern(const iso_solver *s, buckets *b)
{
    int nf = s->nf, *bstart = b->start;
    each_coupling(s, count_coupling, b);
    for (int f = 0; f < nf; f++)
        bstart[f + 1] += bstart[f];
    b->rows = malloc(((size_t)bstart[nf] + 1) * sizeof *b->rows);
    int *mark = malloc(((size_t)nf + 1) * sizeof *mark);
    if (!b->rows || !mark) {
        free(mark);
        return ISO_ENOMEM; /* b->rows, if any, is the caller's to free */
    }
    each_coupling(s, put_coupling, b); /* advances each start to the next column's */
    int *rows = b->rows, u = 0, begin = 0;
    for (int f = 0; f < nf; f++)
        mark[f] = -1;
    for (int f = 0; f < nf; f++) {
        int end = bstart[f], first = u;
        for (int q = begin; q < end; q++) {
            int r = rows[q];
            if (mark[r] == f)
                continue;
            mark[r] = f;
            /* Insert r in order; u <= q, so no unread row is overwritten. */
            int at = u++;
            for (; at > first && rows[at - 1] > r; at--)
                rows[at] = rows[at - 1];
            rows[at] = r;
        }
        begin = end;
        bstart[f] = first;
    }
    bstart[nf] = u;
    free(mark);
    return ISO_OK;
}

/* Builds the block pattern into bp (the caller frees its arrays; analyse
 * orders it), the scalar CSC matrix and the slot map. */
static int build_pattern(iso_solver *s, buckets *bp, iso_err *err)
{
    bp->start = calloc((size_t)s->nf + 1, sizeof *bp->start);
    if (!bp->start || block_pattern(s, bp) != ISO_OK)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory building the pattern");
    const int *bstart = bp->start, *brows = bp->rows;

    /* Scalar column 3fb+k: 3 rows per off-diagonal block, k+1 of the diagonal. */
    size_t nnz = 0;
    for (int f = 0; f < s->nf; f++) {
        int nb = bstart[f + 1] - bstart[f]; /* includes the diagonal block */
        nnz += 3 * (size_t)(3 * (nb - 1)) + 6;
    }
    int n3 = 3 * s->nf;
    s->A = cholmod_allocate_sparse((size_t)n3, (size_t)n3, nnz, 1, 1, 1, CHOLMOD_REAL, &s->c);
    if (!s->A)
        return iso_err_set(err, ISO_ENOMEM, -1, "CHOLMOD could not allocate A (%zu entries)", nnz);
    int *Ap = s->A->p, *Ai = s->A->i;
    Ap[0] = 0;
    for (int f = 0; f < s->nf; f++) {
        const int *rows = brows + bstart[f];
        int nb = bstart[f + 1] - bstart[f];
        for (int k = 0; k < 3; k++) {
            int col = 3 * f + k, q = Ap[col];
            for (int j = 0; j < nb; j++) {
                int len = rows[j] == f ? k + 1 : 3;
                for (int a = 0; a < len; a++)
                    Ai[q++] = 3 * rows[j] + a;
            }
            Ap[col + 1] = q;
        }
    }

    /* Slot map: per element, per local (a, b) with fa <= fb, the position of
     * entry (3fa, 3fb+k) for k = 0..2; −1 where the block is not in A_ff. */
    size_t nslots = 0;
    for (int i = 0; i < s->nel; i++) {
        int nl = local_count(&s->el[i]);
        s->el[i].slot = (int)nslots;
        nslots += (size_t)(nl * nl * 3);
    }
    s->slots = malloc((nslots + 1) * sizeof *s->slots);
    if (!s->slots)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the slot map");
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        int nl = local_count(e);
        int *sl = s->slots + e->slot;
        for (int a = 0; a < nl; a++)
            for (int b = 0; b < nl; b++) {
                int fa = s->free_of[e->v[a]], fb = s->free_of[e->v[b]];
                int *dst = sl + 3 * (a * nl + b);
                if (fa < 0 || fb < 0 || fa > fb) {
                    dst[0] = dst[1] = dst[2] = -1;
                    continue;
                }
                int j = find_row(brows + bstart[fb], bstart[fb + 1] - bstart[fb], fa);
                for (int k = 0; k < 3; k++)
                    dst[k] = Ap[3 * fb + k] + 3 * j;
            }
    }
    return ISO_OK;
}

/* ===== creation ========================================================= */

static int number_free_vertices(iso_solver *s, iso_err *err)
{
    s->free_of = malloc((size_t)s->nv * sizeof *s->free_of);
    s->vert_of = malloc((size_t)s->nv * sizeof *s->vert_of);
    if (!s->free_of || !s->vert_of)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    s->nf = 0;
    for (int i = 0; i < s->nv; i++) {
        int f = s->r->kind[i] == ISO_FREE && iso_mesh_vertex_used(s->m, i);
        s->free_of[i] = f ? s->nf : -1;
        if (f)
            s->vert_of[s->nf++] = i;
    }
    return ISO_OK;
}

static int check_regions(const iso_mesh *m, const iso_regions *r, iso_err *err)
{
    if (r->nv != iso_mesh_vertex_count(m))
        return iso_err_set(err, ISO_EINVAL, -1, "the regions cover %d vertices but %s has %d",
                           r->nv, iso_mesh_origin(m), iso_mesh_vertex_count(m));
    for (int i = 0; i < r->nv; i++) {
        if (r->kind[i] > ISO_HANDLE)
            return iso_err_set(err, ISO_EINVAL, -1, "vertex %d has region kind %d", i,
                               (int)r->kind[i]);
        if (r->kind[i] == ISO_HANDLE && (r->handle[i] < 0 || r->handle[i] >= r->n_handles))
            return iso_err_set(err, ISO_EINVAL, -1,
                               "handle vertex %d is on handle %d, but there are %d handles", i,
                               r->handle[i], r->n_handles);
    }
    return ISO_OK;
}

/* The block pattern bp as a CHOLMOD matrix (nf × nf, upper, pattern). */
static cholmod_sparse *block_matrix(iso_solver *s, const buckets *bp)
{
    size_t nnz = (size_t)bp->start[s->nf];
    cholmod_sparse *B = cholmod_allocate_sparse((size_t)s->nf, (size_t)s->nf, nnz + 1, 1, 1, 1,
                                                CHOLMOD_PATTERN, &s->c);
    if (!B)
        return NULL;
    memcpy(B->p, bp->start, ((size_t)s->nf + 1) * sizeof(int));
    memcpy(B->i, bp->rows, nnz * sizeof(int));
    return B;
}

/* A fill-reducing ordering of the vertices, each vertex's three unknowns
 * kept together: AMD and METIS both on the block graph (9x fewer entries
 * than A_ff's), keeping the one with fewer flops. CHOLMOD's default tries
 * METIS only where AMD's ordering looks poor, which missed the benchmark
 * bar (METIS: nnz(L) 2.99M against 3.49M, 0.99 against 1.41 GFLOP); on
 * the scalar matrix the two orderings took 37 of the cactus solver's 85 ms
 * of creation. A CHOLMOD built without METIS gets its default. Returns the
 * scalar permutation (3 nf), or NULL with the cause in the Common. */
static int *block_ordering(iso_solver *s, const buckets *bp)
{
    cholmod_sparse *B = block_matrix(s, bp);
    if (!B)
        return NULL;
    s->c.nmethods = 3; /* the given ordering (none here), AMD, METIS */
    cholmod_factor *Lb = cholmod_analyze(B, &s->c);
    if (!Lb) {
        s->c.nmethods = 0;
        s->c.status = CHOLMOD_OK;
        Lb = cholmod_analyze(B, &s->c);
    }
    int *perm = Lb ? malloc(3 * (size_t)s->nf * sizeof *perm) : NULL;
    if (perm) {
        const int *vperm = Lb->Perm; /* the vertices' */
        for (int k = 0; k < s->nf; k++)
            for (int a = 0; a < 3; a++)
                perm[3 * k + a] = 3 * vperm[k] + a;
    }
    cholmod_free_factor(&Lb, &s->c);
    cholmod_free_sparse(&B, &s->c);
    return perm;
}

static int analyse(iso_solver *s, const buckets *bp, iso_err *err)
{
    int n3 = 3 * s->nf;
    if (n3 == 0)
        return ISO_OK;
    /* Unit values so the analysis sees the true pattern. */
    double *Ax = s->A->x;
    int *Ap = s->A->p;
    for (int i = 0; i < Ap[n3]; i++)
        Ax[i] = 1.0;
    int *perm = block_ordering(s, bp);
    if (perm) {
        s->c.nmethods = 1;
        s->c.method[0].ordering = CHOLMOD_GIVEN;
        s->L = cholmod_analyze_p(s->A, perm, NULL, 0, &s->c);
        free(perm);
    }
    if (!s->L || s->c.status < CHOLMOD_OK)
        return iso_err_set(err, ISO_ENUMERIC, -1, "CHOLMOD analysis failed (status %d)",
                           s->c.status);
    s->B = cholmod_zeros((size_t)n3, 1, CHOLMOD_REAL, &s->c);
    if (!s->B)
        return iso_err_set(err, ISO_ENOMEM, -1, "CHOLMOD could not allocate the right-hand side");
    if (s->L->is_super && !(s->super_work = malloc(iso_solver__super_work(s->L) * sizeof(double))))
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the triangular solves");
    s->st.nnz_a = Ap[n3];
    s->st.nnz_l = (long)s->c.lnz;
    s->factor_flops = s->c.fl;
    return ISO_OK;
}

/* Sets up the OpenCL path, or falls back to C with a notice when OpenCL
 * is not built in or finds no usable device. */
static int start_opencl(iso_solver *s, iso_err *err)
{
#ifdef ISO_WITH_OPENCL
    if (s->nf == 0)
        return ISO_OK;
    iso_err why;
    iso_err_clear(&why);
    int rc = iso_solver__cl_create(s, &s->cl, &why);
    if (rc == ISO_OK) {
        s->o.assembly = ISO_ASSEMBLY_OPENCL;
        return ISO_OK;
    }
    if (rc != ISO_ENOTSUP)
        return iso_err_set(err, rc, why.offset, "%s", why.msg);
    /* The reason is one of assemble_cl.c's short sentences; the precision
     * only keeps the notice (256 bytes) from tripping -Wformat-truncation. */
    snprintf(s->notice, sizeof s->notice, "%s: %.200s; using the C assembly",
             s->o.assembly == ISO_ASSEMBLY_AUTO ? "assembly auto" : "OpenCL", why.msg);
#else
    snprintf(s->notice, sizeof s->notice,
             "OpenCL: this build has no OpenCL support; using the C assembly");
#endif
    (void)err;
    s->o.assembly = ISO_ASSEMBLY_CPU;
    return ISO_OK;
}

/* The rotated preconditioner's frame and scratch (rotate.c), when PCG will
 * run with it. */
static int start_rotations(iso_solver *s, iso_err *err)
{
    if (s->o.refactor != ISO_REFACTOR_ADAPTIVE || s->o.preconditioner != ISO_PRECOND_ROTATED ||
        s->nf == 0)
        return ISO_OK;
    s->rings = iso_solver__rings_create(s->m, s->nf, s->vert_of, s->free_of);
    s->frame = s->rings ? iso_solver__frame_create(s->rings, s->nv) : NULL;
    s->rot = malloc((size_t)s->nf * 9 * sizeof(double));
    if (!s->frame || !s->rot)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the rotated preconditioner");
    return ISO_OK;
}

/* The worker's look-ahead (iso_solver_opts.worker_ahead): the last two
 * evaluations' positions and the job's. */
static int start_ahead(iso_solver *s, iso_err *err)
{
    if (!s->o.worker_ahead)
        return ISO_OK;
    for (int i = 0; i < 3; i++)
        if (!(s->x_seen[i] = malloc((size_t)s->nv * 3 * sizeof(double))))
            return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the worker's look-ahead");
    return ISO_OK;
}

double iso_solver_factor_flops(const iso_solver *s)
{
    return s->factor_flops;
}

const char *iso_solver_notice(const iso_solver *s)
{
    return s->notice;
}

int iso_solver_create(const iso_mesh *m, const iso_regions *r, const iso_solver_opts *opts,
                      iso_solver **out, iso_err *err)
{
    *out = NULL;
    iso_solver *s = calloc(1, sizeof *s);
    if (!s)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    s->m = m;
    s->r = r;
    s->nv = iso_mesh_vertex_count(m);
    if (opts)
        s->o = *opts;
    else
        iso_solver_opts_default(&s->o);
    cholmod_start(&s->c);
    int rc = check_opts(&s->o, err);
    if (rc == ISO_OK)
        rc = check_regions(m, r, err);
    if (rc == ISO_OK)
        rc = check_constraints(m, r, err);
    if (rc == ISO_OK)
        rc = number_free_vertices(s, err);
    if (rc == ISO_OK)
        rc = build_elements(s, err);
    buckets bp = {NULL, NULL}; /* the block pattern, until the analysis has ordered it */
    if (rc == ISO_OK)
        rc = build_pattern(s, &bp, err);
    if (rc == ISO_OK)
        rc = analyse(s, &bp, err);
    free(bp.start);
    free(bp.rows);
    if (rc == ISO_OK && s->o.assembly != ISO_ASSEMBLY_CPU)
        rc = start_opencl(s, err);
    if (rc == ISO_OK)
        rc = start_rotations(s, err);
    if (rc != ISO_OK) {
        iso_solver_destroy(s);
        return rc;
    }
    iso_solver__threads_begin(s);
    if (s->o.worker_lag > 0 && s->nf > 0 &&
        ((rc = start_ahead(s, err)) != ISO_OK ||
         (rc = iso_solver__worker_create(s, &s->w, err)) != ISO_OK)) {
        iso_solver_destroy(s);
        return rc;
    }
    s->st.n_free = s->nf;
    *out = s;
    return ISO_OK;
}

void iso_solver_destroy(iso_solver *s)
{
    if (!s)
        return;
    iso_solver__worker_destroy(s->w);
    iso_solver__threads_end(s);
#ifdef ISO_WITH_OPENCL
    iso_solver__cl_destroy(s->cl);
#endif
    cholmod_free_sparse(&s->A, &s->c);
    cholmod_free_factor(&s->L, &s->c);
    cholmod_free_dense(&s->B, &s->c);
    cholmod_free_dense(&s->X, &s->c);
    cholmod_free_dense(&s->Y, &s->c);
    cholmod_free_dense(&s->E, &s->c);
    free(s->super_work);
    for (int i = 0; i < ISO_SOLVER__WORK; i++)
        cholmod_free_dense(&s->work[i], &s->c);
    iso_solver__frame_destroy(s->frame);
    iso_solver__rings_destroy(s->rings);
    free(s->rot);
    for (int i = 0; i < 3; i++)
        free(s->x_seen[i]);
    cholmod_finish(&s->c);
    free(s->free_of);
    free(s->vert_of);
    free(s->el);
    free(s->slots);
    iso_solver__cpu_plan_destroy(s->cpu);
    free(s->rest_len);
    free(s->edge_w);
    free(s);
}

void iso_solver_set_progress(iso_solver *s, iso_solver_progress_fn fn, void *ctx)
{
    if (!s)
        return;
    s->progress = fn;
    s->progress_ctx = ctx;
}

void iso_solver_get_stats(const iso_solver *s, iso_solver_stats *st)
{
    *st = s->st;
}

/* ===== evaluation ======================================================= */

int iso_solver__assemble(iso_solver *s, const double *x, const double *vc, iso_err *err)
{
#ifdef ISO_WITH_OPENCL
    if (s->cl)
        return iso_solver__cl_assemble(s->cl, s, x, vc, err);
#endif
    return iso_solver__assemble_cpu(s, x, vc, err);
}

/* The free entries of guess into X, where PCG starts. */
static void start_from(iso_solver *s, const double *guess)
{
    if (!guess || !s->X || s->nf <= 0)
        return;
    double *X = s->X->x;
    for (int i = 0; i < s->nv; i++) {
        int f = s->free_of[i];
        if (f >= 0)
            memcpy(X + 3 * f, guess + 3 * i, 3 * sizeof(double));
    }
}

int iso_solver_factor_at(iso_solver *s, const double *x, iso_err *err)
{
    if (s->o.refactor != ISO_REFACTOR_ADAPTIVE || s->nf == 0)
        return ISO_OK;
    double *vc = calloc((size_t)s->nv * 3, sizeof *vc); /* B is not wanted */
    if (!vc)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertices", s->nv);
    double t0 = iso_clock_now();
    int rc = iso_solver__assemble(s, x, vc, err);
    s->st.t_assembly += iso_clock_now() - t0;
    s->x_now = x;
    if (rc == ISO_OK)
        rc = iso_solver__factor_now(s, err);
    s->x_now = NULL;
    free(vc);
    return rc;
}

int iso_solver_field(iso_solver *s, const double *x, const double *vc, double *v, iso_err *err)
{
    return iso_solver_field_from(s, x, vc, NULL, v, err);
}

int iso_solver_field_from(iso_solver *s, const double *x, const double *vc, const double *guess,
                          double *v, iso_err *err)
{
    start_from(s, guess);
    double t0 = iso_clock_now();
    int rc = ISO_OK;
    if (s->nf > 0)
        rc = iso_solver__assemble(s, x, vc, err);
    s->st.t_assembly += iso_clock_now() - t0;
    iso_solver__progress(s);
    s->x_now = x;
    s->vc_now = vc;
    if (rc == ISO_OK && s->nf > 0)
        rc = iso_solver__linsolve(s, err); /* times its own phases */
    if (rc != ISO_OK)
        return rc;
    s->st.evaluations++;
    const double *X = s->nf > 0 ? s->X->x : NULL;
    for (int i = 0; i < s->nv; i++) {
        int f = s->free_of[i];
        for (int a = 0; a < 3; a++) {
            double val = 0;
            if (f >= 0)
                val = X[3 * f + a];
            else if (s->r->kind[i] == ISO_HANDLE && iso_mesh_vertex_used(s->m, i))
                val = vc[3 * i + a];
            v[3 * i + a] = val;
        }
    }
    return ISO_OK;
}
