/* mesh/mesh.c -- iso_mesh: validation and topology (see iso_mesh.h).
 *
 * Validation runs in a fixed order so that one bad input always gets the same,
 * most basic complaint first: counts, index range, repeated index, finite
 * coordinates, duplicated triangles, quality, non-manifold edges.
 *
 * Error codes: ISO_EINVAL for a caller bug (NULL arrays, negative counts),
 * ISO_EPARSE for data a file format would call malformed (index out of range,
 * repeated index inside a triangle, non-finite coordinate), ISO_EMESH for a
 * mesh that is well formed but unusable (too few vertices or no triangle,
 * duplicated, degenerate or non-manifold triangles). */
#include "iso_mesh.h"
#include "mesh_io_internal.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct iso_mesh {
    int nv, nt, ne;
    double *x;           /* 3*nv */
    int *tri;            /* 3*nt */
    int *edges;          /* 2*ne, (i, j) with i < j, sorted */
    int *edge_tri;       /* 2*ne, (t0, t1), t1 = -1 on the boundary */
    unsigned char *used; /* nv */
    int n_unref;
    double bbox_diag;
    char *origin;
    char *note;
};

/* What the validator needs to say where a triangle came from. */
typedef struct where_ctx {
    const char *origin;
    const long *tri_src;
    int src_is_offset;
} where_ctx;

static char *dup_string(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d)
        memcpy(d, s, n);
    return d;
}

/* "cactus.off, line 12" / "x.ply, byte offset 300" / "mesh" into buf, for
 * triangle t (t < 0: no location). */
static const char *where(char *buf, size_t cap, const where_ctx *w, int t)
{
    if (t >= 0 && w->tri_src)
        snprintf(buf, cap, "%s, %s %ld", w->origin, w->src_is_offset ? "byte offset" : "line",
                 w->tri_src[t]);
    else
        snprintf(buf, cap, "%s", w->origin);
    return buf;
}

static long src_of(const where_ctx *w, int t)
{
    return w->tri_src ? w->tri_src[t] : -1;
}

/* ---- validation steps ------------------------------------------------- */

static int check_counts(int nv, const double *x, int nt, const int *tri, const where_ctx *w,
                        iso_err *err)
{
    if (nv < 0 || nt < 0 || (nv > 0 && !x) || (nt > 0 && !tri))
        return iso_err_set(err, ISO_EINVAL, -1, "%s: bad mesh arguments (nv = %d, nt = %d)",
                           w->origin, nv, nt);
    if (nv > INT_MAX / 3 || nt > INT_MAX / 3)
        return iso_err_set(err, ISO_EMESH, -1,
                           "%s: mesh too large (%d vertices, %d triangles; at most %d each)",
                           w->origin, nv, nt, INT_MAX / 3);
    if (nv < 3)
        return iso_err_set(err, ISO_EMESH, -1,
                           "%s: a mesh needs at least 3 vertices, this one has %d", w->origin, nv);
    if (nt < 1)
        return iso_err_set(err, ISO_EMESH, -1, "%s: the mesh has no triangles", w->origin);
    return ISO_OK;
}

static int check_indices(int nv, int nt, const int *tri, const where_ctx *w, iso_err *err)
{
    char loc[320];
    for (int t = 0; t < nt; t++) {
        const int *v = tri + 3 * t;
        for (int k = 0; k < 3; k++)
            if (v[k] < 0 || v[k] >= nv)
                return iso_err_set(err, ISO_EPARSE, src_of(w, t),
                                   "%s: triangle %d has vertex index %d out of range "
                                   "(the mesh has nv = %d vertices, valid 0..%d)",
                                   where(loc, sizeof loc, w, t), t, v[k], nv, nv - 1);
    }
    for (int t = 0; t < nt; t++) {
        const int *v = tri + 3 * t;
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2])
            return iso_err_set(err, ISO_EPARSE, src_of(w, t),
                               "%s: triangle %d repeats a vertex index (%d, %d, %d)",
                               where(loc, sizeof loc, w, t), t, v[0], v[1], v[2]);
    }
    return ISO_OK;
}

static int check_finite(int nv, const double *x, const where_ctx *w, iso_err *err)
{
    for (int i = 0; i < nv; i++) {
        const double *p = x + 3 * i;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return iso_err_set(err, ISO_EPARSE, -1,
                               "%s: vertex %d has a non-finite coordinate (%g, %g, %g)", w->origin,
                               i, p[0], p[1], p[2]);
    }
    return ISO_OK;
}

/* A triangle's vertex set, sorted, plus its index: sorting these brings
 * duplicates together. */
typedef struct tri_key {
    int v[3];
    int t;
} tri_key;

static int cmp_tri_key(const void *pa, const void *pb)
{
    const tri_key *a = pa, *b = pb;
    for (int k = 0; k < 3; k++)
        if (a->v[k] != b->v[k])
            return a->v[k] < b->v[k] ? -1 : 1;
    return (a->t > b->t) - (a->t < b->t);
}

static void sort3(int v[3])
{
    int t;
    if (v[0] > v[1])
        t = v[0], v[0] = v[1], v[1] = t;
    if (v[1] > v[2])
        t = v[1], v[1] = v[2], v[2] = t;
    if (v[0] > v[1])
        t = v[0], v[0] = v[1], v[1] = t;
}

/* Sorting by a leading int key in linear time: the items are placed in
 * buckets of their key (counting sort, stable), and each bucket is sorted
 * on its own (a few items: insertion; a large one, as around a vertex of
 * high valence: qsort). The order is exactly a full sort's by the whole
 * comparison (the keys are unique), and a million-vertex mesh loads in
 * time linear in its size: the global qsorts were half of its load. */
#define SMALL_BUCKET 16

static void sort_bucket(void *base, size_t n, size_t size, int (*cmp)(const void *, const void *))
{
    if (n > SMALL_BUCKET) {
        qsort(base, n, size, cmp);
        return;
    }
    char *b = base, tmp[32]; /* the items here: 16 and 12 bytes */
    for (size_t i = 1; i < n; i++) {
        size_t j = i;
        memcpy(tmp, b + i * size, size);
        for (; j > 0 && cmp(b + (j - 1) * size, tmp) > 0; j--)
            memcpy(b + j * size, b + (j - 1) * size, size);
        memcpy(b + j * size, tmp, size);
    }
}

/* start (nkeys + 1): each key's bucket from the counts in start[1..],
 * turned into offsets; `next` (nkeys) gets a copy to place items with. */
static void bucket_offsets(int *start, int *next, int nkeys)
{
    start[0] = 0;
    for (int k = 0; k < nkeys; k++)
        start[k + 1] += start[k];
    memcpy(next, start, (size_t)nkeys * sizeof *next);
}

/* Reports the duplicate whose later copy comes first in input order, so the
 * message points at the first offending line a reader meets. */
static int check_duplicates(int nv, int nt, const int *tri, const where_ctx *w, iso_err *err)
{
    tri_key *k = malloc((size_t)nt * sizeof *k);
    int *start = calloc((size_t)nv + 1, sizeof *start),
        *next = malloc(((size_t)nv + 1) * sizeof *next);
    if (!k || !start || !next) {
        free(k);
        free(start);
        free(next);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory checking %d triangles",
                           w->origin, nt);
    }
    for (int t = 0; t < nt; t++) {
        int v[3];
        memcpy(v, tri + 3 * t, sizeof v);
        sort3(v);
        start[v[0] + 1]++;
    }
    bucket_offsets(start, next, nv);
    for (int t = 0; t < nt; t++) {
        int v[3];
        memcpy(v, tri + 3 * t, sizeof v);
        sort3(v);
        tri_key *q = &k[next[v[0]]++];
        memcpy(q->v, v, sizeof v);
        q->t = t;
    }
    for (int a = 0; a < nv; a++)
        sort_bucket(k + start[a], (size_t)(start[a + 1] - start[a]), sizeof *k, cmp_tri_key);
    free(start);
    free(next);
    /* g: start of the current run of equal vertex sets; its first member is
     * what every later member duplicates. One pass, O(nt). */
    int first = -1, second = INT_MAX;
    for (int i = 1, g = 0; i < nt; i++) {
        if (memcmp(k[i].v, k[g].v, sizeof k[g].v) != 0) {
            g = i;
            continue;
        }
        if (i == g + 1 && k[i].t < second)
            first = k[g].t, second = k[i].t;
    }
    free(k);
    if (first < 0)
        return ISO_OK;
    char loc[320], loc1[320];
    const int *a = tri + 3 * first;
    if (w->tri_src)
        snprintf(loc1, sizeof loc1, " (%s %ld)", w->src_is_offset ? "byte offset" : "line",
                 w->tri_src[first]);
    else
        loc1[0] = '\0';
    return iso_err_set(err, ISO_EMESH, src_of(w, second),
                       "%s: triangle %d duplicates triangle %d%s: both use vertices {%d, %d, %d}",
                       where(loc, sizeof loc, w, second), second, first, loc1, a[0], a[1], a[2]);
}

/* q = 4*sqrt(3)*area / (sum of squared edge lengths), computed on edges
 * scaled by their largest component so that huge or tiny coordinates neither
 * overflow nor underflow. */
static double triangle_quality(const double *x, const int *v)
{
    double e[3][3];
    double s = 0;
    for (int k = 0; k < 3; k++) {
        const double *p = x + 3 * v[k], *q = x + 3 * v[(k + 1) % 3];
        for (int c = 0; c < 3; c++) {
            e[k][c] = q[c] - p[c];
            s = fmax(s, fabs(e[k][c]));
        }
    }
    if (!(s > 0) || !isfinite(s))
        return 0;
    double sum = 0;
    for (int k = 0; k < 3; k++)
        for (int c = 0; c < 3; c++) {
            e[k][c] /= s;
            sum += e[k][c] * e[k][c];
        }
    double cx = e[0][1] * e[1][2] - e[0][2] * e[1][1];
    double cy = e[0][2] * e[1][0] - e[0][0] * e[1][2];
    double cz = e[0][0] * e[1][1] - e[0][1] * e[1][0];
    double area = 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
    return 4.0 * sqrt(3.0) * area / sum;
}

static int check_quality(const double *x, int nt, const int *tri, const where_ctx *w, iso_err *err)
{
    char loc[320];
    for (int t = 0; t < nt; t++) {
        const int *v = tri + 3 * t;
        double q = triangle_quality(x, v);
        if (!(q >= ISO_MESH_MIN_QUALITY))
            return iso_err_set(err, ISO_EMESH, src_of(w, t),
                               "%s: triangle %d (vertices %d, %d, %d) is degenerate or nearly "
                               "so: quality q = %.3g < %g",
                               where(loc, sizeof loc, w, t), t, v[0], v[1], v[2], q,
                               ISO_MESH_MIN_QUALITY);
    }
    return ISO_OK;
}

/* ---- topology ---------------------------------------------------------- */

typedef struct half_edge {
    int i, j, t; /* i < j */
} half_edge;

static int cmp_half_edge(const void *pa, const void *pb)
{
    const half_edge *a = pa, *b = pb;
    if (a->i != b->i)
        return a->i < b->i ? -1 : 1;
    if (a->j != b->j)
        return a->j < b->j ? -1 : 1;
    return (a->t > b->t) - (a->t < b->t);
}

/* Sorts all 3*nt half edges; equal (i, j) runs are one undirected edge. A run
 * longer than two is a non-manifold edge: the one reported is the one whose
 * third triangle comes first in the input. */
static int build_edges(iso_mesh *m, const where_ctx *w, iso_err *err)
{
    size_t nh = 3 * (size_t)m->nt;
    half_edge *h = malloc(nh * sizeof *h);
    int *start = calloc((size_t)m->nv + 1, sizeof *start),
        *next = malloc(((size_t)m->nv + 1) * sizeof *next);
    if (!h || !start || !next) {
        free(h);
        free(start);
        free(next);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory building edges", w->origin);
    }
    for (size_t k = 0; k < nh; k++) { /* a half edge's bucket: its lower end */
        int a = m->tri[k], b = m->tri[k % 3 == 2 ? k - 2 : k + 1];
        start[(a < b ? a : b) + 1]++;
    }
    bucket_offsets(start, next, m->nv);
    for (int t = 0; t < m->nt; t++)
        for (int k = 0; k < 3; k++) {
            int a = m->tri[3 * t + k], b = m->tri[3 * t + (k + 1) % 3];
            half_edge *e = h + next[a < b ? a : b]++;
            e->i = a < b ? a : b;
            e->j = a < b ? b : a;
            e->t = t;
        }
    for (int v = 0; v < m->nv; v++)
        sort_bucket(h + start[v], (size_t)(start[v + 1] - start[v]), sizeof *h, cmp_half_edge);
    free(start);
    free(next);

    size_t ne = 0, bad = nh;
    for (size_t r = 0; r < nh;) {
        size_t s = r + 1;
        while (s < nh && h[s].i == h[r].i && h[s].j == h[r].j)
            s++;
        if (s - r > 2 && (bad == nh || h[r + 2].t < h[bad + 2].t))
            bad = r;
        ne++;
        r = s;
    }
    if (bad != nh) {
        char loc[320];
        size_t s = bad;
        while (s < nh && h[s].i == h[bad].i && h[s].j == h[bad].j)
            s++;
        char list[160];
        size_t used = 0;
        list[0] = '\0';
        for (size_t q = bad; q < s && used + 16 < sizeof list; q++) {
            if (q - bad == 6) {
                snprintf(list + used, sizeof list - used, ", ...");
                break;
            }
            int n = snprintf(list + used, sizeof list - used, "%s%d", q > bad ? ", " : "", h[q].t);
            used += (size_t)n;
        }
        int rc =
            iso_err_set(err, ISO_EMESH, src_of(w, h[bad + 2].t),
                        "%s: non-manifold edge (%d, %d) is shared by %zu triangles (%s); "
                        "at most two may share an edge",
                        where(loc, sizeof loc, w, h[bad + 2].t), h[bad].i, h[bad].j, s - bad, list);
        free(h);
        return rc;
    }

    m->edges = malloc(2 * ne * sizeof *m->edges);
    m->edge_tri = malloc(2 * ne * sizeof *m->edge_tri);
    if (!m->edges || !m->edge_tri) {
        free(h);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory storing %zu edges", w->origin,
                           ne);
    }
    size_t e = 0;
    for (size_t r = 0; r < nh;) {
        size_t s = r + 1;
        while (s < nh && h[s].i == h[r].i && h[s].j == h[r].j)
            s++;
        m->edges[2 * e] = h[r].i;
        m->edges[2 * e + 1] = h[r].j;
        m->edge_tri[2 * e] = h[r].t;
        m->edge_tri[2 * e + 1] = s - r > 1 ? h[r + 1].t : -1;
        e++;
        r = s;
    }
    m->ne = (int)ne;
    free(h);
    return ISO_OK;
}

static void build_vertex_info(iso_mesh *m)
{
    for (size_t k = 0; k < 3 * (size_t)m->nt; k++)
        m->used[m->tri[k]] = 1;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    m->n_unref = 0;
    for (int i = 0; i < m->nv; i++) {
        if (!m->used[i]) {
            m->n_unref++;
            continue;
        }
        for (int c = 0; c < 3; c++) {
            lo[c] = fmin(lo[c], m->x[3 * i + c]);
            hi[c] = fmax(hi[c], m->x[3 * i + c]);
        }
    }
    double d[3];
    for (int c = 0; c < 3; c++)
        d[c] = hi[c] - lo[c];
    m->bbox_diag = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

/* ---- public ------------------------------------------------------------ */

int iso_mesh_create_src(int nv, const double *x, int nt, const int *tri, const char *origin,
                        const long *tri_src, int src_is_offset, iso_mesh **out, iso_err *err)
{
    if (!out)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_mesh_create: out is NULL");
    *out = NULL;
    where_ctx w = {origin ? origin : "mesh", tri_src, src_is_offset};
    int rc;
    if ((rc = check_counts(nv, x, nt, tri, &w, err)) != ISO_OK ||
        (rc = check_indices(nv, nt, tri, &w, err)) != ISO_OK ||
        (rc = check_finite(nv, x, &w, err)) != ISO_OK ||
        (rc = check_duplicates(nv, nt, tri, &w, err)) != ISO_OK ||
        (rc = check_quality(x, nt, tri, &w, err)) != ISO_OK)
        return rc;

    iso_mesh *m = calloc(1, sizeof *m);
    if (!m)
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory", w.origin);
    m->nv = nv;
    m->nt = nt;
    m->x = malloc(3 * (size_t)nv * sizeof *m->x);
    m->tri = malloc(3 * (size_t)nt * sizeof *m->tri);
    m->used = calloc((size_t)nv, 1);
    m->origin = dup_string(w.origin);
    m->note = dup_string("");
    if (!m->x || !m->tri || !m->used || !m->origin || !m->note) {
        rc = iso_err_set(err, ISO_ENOMEM, -1,
                         "%s: out of memory copying %d vertices, %d "
                         "triangles",
                         w.origin, nv, nt);
        goto err;
    }
    memcpy(m->x, x, 3 * (size_t)nv * sizeof *m->x);
    memcpy(m->tri, tri, 3 * (size_t)nt * sizeof *m->tri);
    if ((rc = build_edges(m, &w, err)) != ISO_OK)
        goto err;
    build_vertex_info(m);
    *out = m;
    return ISO_OK;
err:
    iso_mesh_destroy(m);
    return rc;
}

int iso_mesh_create(int nv, const double *x, int nt, const int *tri, const char *origin,
                    iso_mesh **out, iso_err *err)
{
    return iso_mesh_create_src(nv, x, nt, tri, origin, NULL, 0, out, err);
}

void iso_mesh_destroy(iso_mesh *m)
{
    if (!m)
        return;
    free(m->x);
    free(m->tri);
    free(m->edges);
    free(m->edge_tri);
    free(m->used);
    free(m->origin);
    free(m->note);
    free(m);
}

int iso_mesh__set_note(iso_mesh *m, const char *note)
{
    char *n = dup_string(note ? note : "");
    if (!n)
        return ISO_ENOMEM;
    free(m->note);
    m->note = n;
    return ISO_OK;
}

int iso_mesh_vertex_count(const iso_mesh *m)
{
    return m->nv;
}
int iso_mesh_triangle_count(const iso_mesh *m)
{
    return m->nt;
}
const double *iso_mesh_positions(const iso_mesh *m)
{
    return m->x;
}
const int *iso_mesh_triangles(const iso_mesh *m)
{
    return m->tri;
}
const char *iso_mesh_origin(const iso_mesh *m)
{
    return m->origin;
}
int iso_mesh_edge_count(const iso_mesh *m)
{
    return m->ne;
}
const int *iso_mesh_edges(const iso_mesh *m)
{
    return m->edges;
}
const int *iso_mesh_edge_triangles(const iso_mesh *m)
{
    return m->edge_tri;
}
int iso_mesh_unreferenced_count(const iso_mesh *m)
{
    return m->n_unref;
}
double iso_mesh_bbox_diagonal(const iso_mesh *m)
{
    return m->bbox_diag;
}
const char *iso_mesh_note(const iso_mesh *m)
{
    return m->note;
}

int iso_mesh_vertex_used(const iso_mesh *m, int i)
{
    return i >= 0 && i < m->nv && m->used[i];
}
