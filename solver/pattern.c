/* solver/pattern.c -- the free–free system's structure, made once per
 * solver from connectivity and regions: the element list, the pattern of
 * A_ff, the slot map, and the fill-reducing ordering with CHOLMOD's
 * symbolic analysis.
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
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "iso_clock.h"
#include "solver_internal.h"
#include "supersolve_internal.h"

typedef iso_solver__element element;
#define local_count iso_solver__local_count

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

/* ===== ordering and analysis ============================================ */

/* Orderings, one at a time. METIS, which CHOLMOD's analysis runs beside
 * AMD, draws from a random-number generator that the whole process shares
 * and that each call seeds afresh, so two analyses at once in two threads
 * interleave their draws and may order differently than either alone: the
 * built-in bar (resolution 6) got nnz(L) 223,443 instead of 223,839 once
 * in 300 creations beside a cactus, and its deformation then differed by
 * 3.7e-13. A solver's ordering must depend on its mesh alone (its bits
 * do), so every analysis in the library takes this lock. It is held only
 * for the analysis, which runs at creation, never in a tick. */
static pthread_mutex_t analysis_lock = PTHREAD_MUTEX_INITIALIZER;

cholmod_factor *iso_solver__analyze(cholmod_sparse *A, int *perm, cholmod_common *c)
{
    pthread_mutex_lock(&analysis_lock);
    cholmod_factor *L = perm ? cholmod_analyze_p(A, perm, NULL, 0, c) : cholmod_analyze(A, c);
    pthread_mutex_unlock(&analysis_lock);
    return L;
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
    cholmod_factor *Lb = iso_solver__analyze(B, NULL, &s->c);
    if (!Lb) {
        s->c.nmethods = 0;
        s->c.status = CHOLMOD_OK;
        Lb = iso_solver__analyze(B, NULL, &s->c);
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
    double t0 = iso_clock_now();
    /* Unit values so the analysis sees the true pattern. */
    double *Ax = s->A->x;
    int *Ap = s->A->p;
    for (int i = 0; i < Ap[n3]; i++)
        Ax[i] = 1.0;
    int *perm = block_ordering(s, bp);
    if (perm) {
        s->c.nmethods = 1;
        s->c.method[0].ordering = CHOLMOD_GIVEN;
        s->L = iso_solver__analyze(s->A, perm, &s->c);
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
    s->st.supernodal = s->L->is_super != 0;
    s->st.t_analysis = iso_clock_now() - t0;
    s->factor_flops = s->c.fl;
    return ISO_OK;
}

int iso_solver__build_system(iso_solver *s, iso_err *err)
{
    int rc = build_elements(s, err);
    buckets bp = {NULL, NULL}; /* the block pattern, until the analysis has ordered it */
    if (rc == ISO_OK)
        rc = build_pattern(s, &bp, err);
    if (rc == ISO_OK)
        rc = analyse(s, &bp, err);
    free(bp.start);
    free(bp.rows);
    return rc;
}
