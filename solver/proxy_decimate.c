/* solver/proxy_decimate.c -- the reduced model's proxy: the mesh simplified
 * to a vertex budget by half-edge collapses (proxy_internal.h).
 *
 * A collapse u → v removes u and gives its triangles to v, whose position
 * stays: so the proxy's vertices are mesh vertices. Collapses are taken
 * cheapest first, by the quadric error (Garland and Heckbert 1997: the sum
 * of squared distances of v to the planes of u's and v's triangles, area
 * weighted, with planes across boundary edges to keep the boundary) plus
 * |u − v|⁴: on a flat or gently curved region the quadric is near zero and
 * the length term makes the shortest edges go first, so the proxy thins out
 * evenly instead of in the order of the vertex numbers; where curvature is
 * strong for the edge length the quadric keeps detail.
 *
 * A collapse is taken only if
 *   - u and v are in the same region (fixed, free, or the same handle), and
 *     the region keeps REGION_FLOOR vertices: so every proxy vertex carries
 *     its mesh vertex's region, and every region survives;
 *   - it keeps the surface a manifold of the same topology: the link
 *     condition (u and v share exactly the neighbours opposite their
 *     shared edge), and a boundary vertex only moves along a boundary edge;
 *   - no triangle of u's turns over or thins: each keeps its normal within
 *     60° and a quality of MIN_QUALITY (or its own, if lower).
 * Entries of the queue are stamped with their ends' versions; an entry
 * whose end changed since is stale and skipped. Ties in cost are broken by
 * the vertex numbers, so the result is fixed by the mesh alone. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proxy_internal.h"

#define REGION_FLOOR 6   /* vertices a region keeps */
#define MIN_QUALITY 0.25 /* 4√3 area / Σ edge², 1 for an equilateral triangle */
#define MAX_TURN_COS 0.5 /* a triangle's normal turns by at most 60° */

typedef struct entry {
    double cost;
    int u, v;   /* collapse u into v */
    int su, sv; /* their stamps when queued */
} entry;

typedef struct dec {
    int nv, nt;
    const double *X;
    const iso_regions *r;
    int *tri;             /* 3 nt: corners, updated as vertices collapse */
    unsigned char *tdead; /* nt */
    int **vt;             /* nv: each vertex's live triangles */
    int *vn, *vcap;
    double *Q;              /* 10 per vertex: the quadric's upper triangle */
    int *stamp;             /* nv: bumped when a vertex's cost may change */
    int *to;                /* nv: the vertex it was collapsed into, −1 while alive */
    unsigned char *bnd;     /* nv: on the mesh's boundary */
    int *left;              /* per region key: vertices left */
    int *mark, mark_gen;    /* nv: scratch for the link condition */
    unsigned char *blocked; /* nv: an entry at this vertex was refused for its shape */
    int *nb, *todo, nb_cap; /* scratch: a vertex's neighbours, the flagged ones */
    entry *h;               /* the queue: a binary heap */
    size_t hn, hcap;
    int alive; /* referenced vertices alive */
    int oom;
} dec;

/* ===== the queue ========================================================= */

static int before(const entry *a, const entry *b)
{
    if (a->cost != b->cost)
        return a->cost < b->cost;
    if (a->u != b->u)
        return a->u < b->u;
    return a->v < b->v;
}

static void heap_push(dec *d, entry e)
{
    if (d->hn == d->hcap) {
        size_t cap = d->hcap ? 2 * d->hcap : 1024;
        entry *h = realloc(d->h, cap * sizeof *h);
        if (!h) {
            d->oom = 1;
            return;
        }
        d->h = h;
        d->hcap = cap;
    }
    size_t i = d->hn++;
    while (i > 0 && before(&e, &d->h[(i - 1) / 2])) {
        d->h[i] = d->h[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    d->h[i] = e;
}

static entry heap_pop(dec *d)
{
    entry top = d->h[0], last = d->h[--d->hn];
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= d->hn)
            break;
        if (c + 1 < d->hn && before(&d->h[c + 1], &d->h[c]))
            c++;
        if (!before(&d->h[c], &last))
            break;
        d->h[i] = d->h[c];
        i = c;
    }
    if (d->hn > 0)
        d->h[i] = last;
    return top;
}

/* Drops the stale entries (an end collapsed or changed since) and rebuilds
 * the heap from the rest, which keeps the queue's memory in proportion to
 * the vertices left. The order of what is taken is unchanged: stale
 * entries are never taken. */
static void compact(dec *d)
{
    size_t n = 0;
    for (size_t i = 0; i < d->hn; i++) {
        const entry *e = &d->h[i];
        if (d->to[e->u] < 0 && d->to[e->v] < 0 && d->stamp[e->u] == e->su &&
            d->stamp[e->v] == e->sv)
            d->h[n++] = *e;
    }
    d->hn = 0;
    for (size_t i = 0; i < n; i++) { /* pushing in place: the slot read is never behind */
        entry e = d->h[i];
        heap_push(d, e);
    }
}

/* ===== geometry ========================================================== */

static void sub3(const double *a, const double *b, double *c)
{
    c[0] = a[0] - b[0], c[1] = a[1] - b[1], c[2] = a[2] - b[2];
}

static void cross3(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* n = (b − a) × (c − a), twice the area along the normal; returns the
 * quality 4√3 area / Σ edge². */
static double tri_normal(const double *a, const double *b, const double *c, double *n)
{
    double e1[3], e2[3], e3[3];
    sub3(b, a, e1);
    sub3(c, a, e2);
    sub3(c, b, e3);
    cross3(e1, e2, n);
    double sum = dot3(e1, e1) + dot3(e2, e2) + dot3(e3, e3);
    return sum > 0 ? 2.0 * sqrt(3.0) * sqrt(dot3(n, n)) / sum : 0.0;
}

/* Q += w p pᵀ for the plane p = (n, −n·x0), n a unit normal. */
static void add_plane(double *Q, const double *n, const double *x0, double w)
{
    double p[4] = {n[0], n[1], n[2], -dot3(n, x0)};
    int k = 0;
    for (int i = 0; i < 4; i++)
        for (int j = i; j < 4; j++)
            Q[k++] += w * p[i] * p[j];
}

/* [x 1] Q [x 1]ᵀ */
static double quadric_at(const double *Q, const double *x)
{
    double p[4] = {x[0], x[1], x[2], 1.0}, s = 0;
    int k = 0;
    for (int i = 0; i < 4; i++)
        for (int j = i; j < 4; j++, k++)
            s += (i == j ? 1.0 : 2.0) * Q[k] * p[i] * p[j];
    return s;
}

/* ===== set-up ============================================================ */

static int region_key(const iso_regions *r, int v)
{
    return r->kind[v] == ISO_FIXED ? 0 : r->kind[v] == ISO_FREE ? 1 : 2 + r->handle[v];
}

static int vt_add(dec *d, int v, int t)
{
    if (d->vn[v] == d->vcap[v]) {
        int cap = d->vcap[v] ? 2 * d->vcap[v] : 8;
        int *p = realloc(d->vt[v], (size_t)cap * sizeof *p);
        if (!p)
            return d->oom = 1, -1;
        d->vt[v] = p;
        d->vcap[v] = cap;
    }
    d->vt[v][d->vn[v]++] = t;
    return 0;
}

static void vt_remove(dec *d, int v, int t)
{
    for (int k = 0; k < d->vn[v]; k++)
        if (d->vt[v][k] == t) {
            memmove(d->vt[v] + k, d->vt[v] + k + 1, (size_t)(d->vn[v] - k - 1) * sizeof(int));
            d->vn[v]--;
            return;
        }
}

/* The quadrics: each triangle's plane, area weighted, at its corners; each
 * boundary edge's plane through it, across its triangle, weighted by its
 * length squared, at its ends. */
static void make_quadrics(dec *d, const iso_mesh *m)
{
    for (int t = 0; t < d->nt; t++) {
        const int *c = d->tri + 3 * t;
        double n[3];
        tri_normal(d->X + 3 * c[0], d->X + 3 * c[1], d->X + 3 * c[2], n);
        double len = sqrt(dot3(n, n));
        if (!(len > 0))
            continue;
        for (int k = 0; k < 3; k++)
            n[k] /= len;
        for (int k = 0; k < 3; k++)
            add_plane(d->Q + 10 * c[k], n, d->X + 3 * c[0], 0.5 * len);
    }
    int ne = iso_mesh_edge_count(m);
    const int *ed = iso_mesh_edges(m), *et = iso_mesh_edge_triangles(m);
    for (int e = 0; e < ne; e++) {
        if (et[2 * e + 1] >= 0)
            continue;
        int a = ed[2 * e], b = ed[2 * e + 1];
        const int *c = d->tri + 3 * et[2 * e];
        double tn[3], dir[3], n[3];
        tri_normal(d->X + 3 * c[0], d->X + 3 * c[1], d->X + 3 * c[2], tn);
        sub3(d->X + 3 * b, d->X + 3 * a, dir);
        cross3(dir, tn, n);
        double len = sqrt(dot3(n, n)), l2 = dot3(dir, dir);
        if (!(len > 0))
            continue;
        for (int k = 0; k < 3; k++)
            n[k] /= len;
        add_plane(d->Q + 10 * a, n, d->X + 3 * a, 10.0 * l2);
        add_plane(d->Q + 10 * b, n, d->X + 3 * a, 10.0 * l2);
        d->bnd[a] = d->bnd[b] = 1;
    }
}

static void push_pair(dec *d, int u, int v)
{
    if (region_key(d->r, u) != region_key(d->r, v))
        return;
    double Q[10], e[3];
    for (int k = 0; k < 10; k++)
        Q[k] = d->Q[10 * u + k] + d->Q[10 * v + k];
    sub3(d->X + 3 * u, d->X + 3 * v, e);
    double l2 = dot3(e, e);
    entry x = {fmax(0.0, quadric_at(Q, d->X + 3 * v)) + l2 * l2, u, v, d->stamp[u], d->stamp[v]};
    heap_push(d, x);
}

/* ===== one collapse ====================================================== */

/* Number of u's triangles that contain v: 0 if not an edge. */
static int shared_triangles(const dec *d, int u, int v)
{
    int n = 0;
    for (int k = 0; k < d->vn[u]; k++) {
        const int *c = d->tri + 3 * d->vt[u][k];
        n += c[0] == v || c[1] == v || c[2] == v;
    }
    return n;
}

/* The link condition: u and v have exactly `shared` common neighbours. */
static int link_ok(dec *d, int u, int v, int shared)
{
    int gen = ++d->mark_gen;
    for (int k = 0; k < d->vn[u]; k++) {
        const int *c = d->tri + 3 * d->vt[u][k];
        for (int j = 0; j < 3; j++)
            d->mark[c[j]] = gen;
    }
    int common = 0, seen = ++d->mark_gen;
    for (int k = 0; k < d->vn[v]; k++) {
        const int *c = d->tri + 3 * d->vt[v][k];
        for (int j = 0; j < 3; j++) {
            int w = c[j];
            if (w == u || w == v || d->mark[w] != gen)
                continue;
            d->mark[w] = seen; /* count each once */
            common++;
        }
    }
    return common == shared;
}

/* u's triangles that v does not share keep their normal and quality. */
static int shape_ok(const dec *d, int u, int v)
{
    for (int k = 0; k < d->vn[u]; k++) {
        const int *c = d->tri + 3 * d->vt[u][k];
        if (c[0] == v || c[1] == v || c[2] == v)
            continue;
        const double *p[3], *q[3];
        for (int j = 0; j < 3; j++) {
            p[j] = d->X + 3 * c[j];
            q[j] = c[j] == u ? d->X + 3 * v : p[j];
        }
        double n0[3], n1[3];
        double q0 = tri_normal(p[0], p[1], p[2], n0), q1 = tri_normal(q[0], q[1], q[2], n1);
        double l0 = sqrt(dot3(n0, n0)), l1 = sqrt(dot3(n1, n1));
        if (!(l1 > 0) || dot3(n0, n1) < MAX_TURN_COS * l0 * l1 || q1 < fmin(MIN_QUALITY, q0))
            return 0;
    }
    return 1;
}

static int stale(const dec *d, const entry *e)
{
    int u = e->u, v = e->v;
    return d->to[u] >= 0 || d->to[v] >= 0 || d->stamp[u] != e->su || d->stamp[v] != e->sv ||
           d->left[region_key(d->r, u)] <= REGION_FLOOR;
}

/* Whether the collapse keeps topology and shape. When its shape does not
 * pass, both ends are flagged: their edges are queued again once their
 * surroundings change (collapse), since a collapse nearby may make it pass. */
static int collapse_ok(dec *d, const entry *e)
{
    int u = e->u, v = e->v;
    int shared = shared_triangles(d, u, v);
    if (shared == 0 || shared > 2 || (d->bnd[u] && shared != 1))
        return 0;
    if (link_ok(d, u, v, shared) && shape_ok(d, u, v))
        return 1;
    d->blocked[u] = d->blocked[v] = 1;
    return 0;
}

/* w's neighbours, each once, into d->nb; their number (−1: out of memory). */
static int neighbours(dec *d, int w)
{
    int n = 0, gen = ++d->mark_gen;
    for (int k = 0; k < d->vn[w]; k++) {
        const int *c = d->tri + 3 * d->vt[w][k];
        for (int j = 0; j < 3; j++) {
            int z = c[j];
            if (z == w || d->mark[z] == gen)
                continue;
            d->mark[z] = gen;
            if (n == d->nb_cap) {
                int cap = d->nb_cap ? 2 * d->nb_cap : 64;
                int *a = realloc(d->nb, (size_t)cap * sizeof *a), *b = NULL;
                if (a)
                    d->nb = a;
                if (a && (b = realloc(d->todo, (size_t)cap * sizeof *b)))
                    d->todo = b;
                if (!a || !b)
                    return d->oom = 1, -1;
                d->nb_cap = cap;
            }
            d->nb[n++] = z;
        }
    }
    return n;
}

/* Queues w's edges again, both ways, and clears its flag. */
static void requeue(dec *d, int w)
{
    int n = neighbours(d, w);
    for (int k = 0; k < n; k++) {
        push_pair(d, w, d->nb[k]);
        push_pair(d, d->nb[k], w);
    }
    d->blocked[w] = 0;
}

static void collapse(dec *d, int u, int v)
{
    for (int k = 0; k < d->vn[u]; k++) {
        int t = d->vt[u][k];
        int *c = d->tri + 3 * t;
        if (c[0] == v || c[1] == v || c[2] == v) {
            d->tdead[t] = 1;
            for (int j = 0; j < 3; j++)
                if (c[j] != u)
                    vt_remove(d, c[j], t);
            continue;
        }
        for (int j = 0; j < 3; j++)
            if (c[j] == u)
                c[j] = v;
        vt_add(d, v, t);
    }
    d->vn[u] = 0;
    d->to[u] = v;
    d->alive--;
    d->left[region_key(d->r, u)]--;
    for (int k = 0; k < 10; k++)
        d->Q[10 * v + k] += d->Q[10 * u + k];
    d->stamp[v]++;
    /* v's edges have new costs; a flagged neighbour may pass now */
    int n = neighbours(d, v), m = 0;
    for (int k = 0; k < n; k++)
        if (d->blocked[d->nb[k]])
            d->todo[m++] = d->nb[k];
    requeue(d, v);
    for (int k = 0; k < m; k++)
        requeue(d, d->todo[k]);
    if (d->hn > 8 * (size_t)d->alive + 4096)
        compact(d);
}

/* ===== the whole ========================================================= */

static int dec_init(dec *d, const iso_mesh *m, const iso_regions *r)
{
    d->nv = iso_mesh_vertex_count(m);
    d->nt = iso_mesh_triangle_count(m);
    d->X = iso_mesh_positions(m);
    d->r = r;
    size_t nv = (size_t)d->nv + 1, nt = (size_t)d->nt + 1;
    d->tri = malloc(3 * nt * sizeof *d->tri);
    d->tdead = calloc(nt, 1);
    d->vt = calloc(nv, sizeof *d->vt);
    d->vn = calloc(nv, sizeof *d->vn);
    d->vcap = calloc(nv, sizeof *d->vcap);
    d->Q = calloc(10 * nv, sizeof *d->Q);
    d->stamp = calloc(nv, sizeof *d->stamp);
    d->to = malloc(nv * sizeof *d->to);
    d->bnd = calloc(nv, 1);
    d->mark = calloc(nv, sizeof *d->mark);
    d->blocked = calloc(nv, 1);
    d->left = calloc((size_t)r->n_handles + 3, sizeof *d->left);
    if (!d->tri || !d->tdead || !d->vt || !d->vn || !d->vcap || !d->Q || !d->stamp || !d->to ||
        !d->bnd || !d->mark || !d->blocked || !d->left)
        return -1;
    memcpy(d->tri, iso_mesh_triangles(m), 3 * (size_t)d->nt * sizeof *d->tri);
    for (int t = 0; t < d->nt; t++)
        for (int k = 0; k < 3; k++)
            if (vt_add(d, d->tri[3 * t + k], t) != 0)
                return -1;
    for (int i = 0; i < d->nv; i++) {
        d->to[i] = -1;
        if (iso_mesh_vertex_used(m, i)) {
            d->alive++;
            d->left[region_key(r, i)]++;
        }
    }
    make_quadrics(d, m);
    int ne = iso_mesh_edge_count(m);
    const int *ed = iso_mesh_edges(m);
    for (int e = 0; e < ne; e++) {
        push_pair(d, ed[2 * e], ed[2 * e + 1]);
        push_pair(d, ed[2 * e + 1], ed[2 * e]);
    }
    return d->oom ? -1 : 0;
}

static void dec_free(dec *d)
{
    for (int i = 0; d->vt && i < d->nv; i++)
        free(d->vt[i]);
    free(d->vt);
    free(d->tri);
    free(d->tdead);
    free(d->vn);
    free(d->vcap);
    free(d->Q);
    free(d->stamp);
    free(d->to);
    free(d->bnd);
    free(d->mark);
    free(d->blocked);
    free(d->nb);
    free(d->todo);
    free(d->left);
    free(d->h);
}

/* The proxy's arrays from what the collapses left. */
static int harvest(const dec *d, const iso_mesh *m, iso_proxy__decimated *o)
{
    o->proxy_of = malloc(((size_t)d->nv + 1) * sizeof *o->proxy_of);
    o->rep = malloc(((size_t)d->nv + 1) * sizeof *o->rep);
    o->full_of = malloc(((size_t)d->alive + 1) * sizeof *o->full_of);
    int nt = 0;
    for (int t = 0; t < d->nt; t++)
        nt += !d->tdead[t];
    o->tri = malloc((3 * (size_t)nt + 1) * sizeof *o->tri);
    if (!o->proxy_of || !o->rep || !o->full_of || !o->tri)
        return -1;
    for (int i = 0; i < d->nv; i++) {
        o->proxy_of[i] = -1;
        if (d->to[i] < 0 && iso_mesh_vertex_used(m, i)) {
            o->proxy_of[i] = o->np;
            o->full_of[o->np++] = i;
        }
    }
    for (int i = 0; i < d->nv; i++) {
        int v = i;
        while (d->to[v] >= 0)
            v = d->to[v];
        o->rep[i] = iso_mesh_vertex_used(m, i) ? o->proxy_of[v] : -1;
    }
    for (int t = 0; t < d->nt; t++)
        if (!d->tdead[t]) {
            for (int k = 0; k < 3; k++)
                o->tri[3 * o->nt + k] = o->proxy_of[d->tri[3 * t + k]];
            o->nt++;
        }
    return 0;
}

int iso_proxy__decimate(const iso_mesh *m, const iso_regions *r, int budget,
                        iso_proxy__decimated *o, iso_err *err)
{
    memset(o, 0, sizeof *o);
    dec d;
    memset(&d, 0, sizeof d);
    int rc = dec_init(&d, m, r);
    while (rc == 0 && d.alive > budget && d.hn > 0 && !d.oom) {
        entry e = heap_pop(&d);
        if (!stale(&d, &e) && collapse_ok(&d, &e))
            collapse(&d, e.u, e.v);
    }
    if (rc == 0 && !d.oom)
        rc = harvest(&d, m, o);
    if (rc != 0 || d.oom) {
        dec_free(&d);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory simplifying %s (%d vertices)",
                           iso_mesh_origin(m), iso_mesh_vertex_count(m));
    }
    dec_free(&d);
    return ISO_OK;
}

void iso_proxy__decimated_free(iso_proxy__decimated *d)
{
    free(d->full_of);
    free(d->proxy_of);
    free(d->rep);
    free(d->tri);
    memset(d, 0, sizeof *d);
}
