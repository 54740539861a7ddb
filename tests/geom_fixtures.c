/* tests/geom_fixtures.c -- see geom_fixtures.h. Included by test programs. */
#include "geom_fixtures.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* ---- LAPACK -------------------------------------------------------------- */

FX_FN void fx_eigvalsh(int n, const double *A, double *w)
{
    double *a = malloc(sizeof(double) * (size_t)n * (size_t)n);
    assert_non_null(a);
    memcpy(a, A, sizeof(double) * (size_t)n * (size_t)n);
    int lwork = -1, info = 0;
    double q;
    dsyev_("N", "U", &n, a, &n, w, &q, &lwork, &info);
    assert_int_equal(info, 0);
    lwork = (int)q;
    double *work = malloc(sizeof(double) * (size_t)lwork);
    assert_non_null(work);
    dsyev_("N", "U", &n, a, &n, w, work, &lwork, &info);
    assert_int_equal(info, 0);
    free(work);
    free(a);
}

FX_FN int fx_spd_solve(int n, const double *A, const double *b, double *x)
{
    double *a = malloc(sizeof(double) * (size_t)n * (size_t)n);
    assert_non_null(a);
    memcpy(a, A, sizeof(double) * (size_t)n * (size_t)n);
    memcpy(x, b, sizeof(double) * (size_t)n);
    int one = 1, info = 0;
    dposv_("U", &n, &one, a, &n, x, &n, &info);
    free(a);
    return info;
}

/* ---- random numbers -------------------------------------------------------- */

FX_FN double fx_uniform(fx_rng *r, double lo, double hi)
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return lo + (hi - lo) * ((double)(z >> 11) * 0x1.0p-53);
}

/* ---- small vectors ---------------------------------------------------------- */

FX_FN void fx_cross(const double a[3], const double b[3], double c[3])
{
    double c0 = a[1] * b[2] - a[2] * b[1];
    double c1 = a[2] * b[0] - a[0] * b[2];
    double c2 = a[0] * b[1] - a[1] * b[0];
    c[0] = c0;
    c[1] = c1;
    c[2] = c2;
}

FX_FN double fx_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

FX_FN double fx_norm(const double a[3])
{
    return sqrt(fx_dot(a, a));
}

FX_FN void fx_rotation(const double a[3], double th, double R[9])
{
    double c = cos(th), s = sin(th), C = 1 - c;
    double x = a[0], y = a[1], z = a[2];
    R[0] = c + x * x * C;
    R[1] = x * y * C - z * s;
    R[2] = x * z * C + y * s;
    R[3] = y * x * C + z * s;
    R[4] = c + y * y * C;
    R[5] = y * z * C - x * s;
    R[6] = z * x * C - y * s;
    R[7] = z * y * C + x * s;
    R[8] = c + z * z * C;
}

/* ---- meshes ------------------------------------------------------------------ */

FX_FN void fx_mesh_free(fx_mesh *m)
{
    free(m->x);
    free(m->tri);
    m->x = NULL;
    m->tri = NULL;
    m->nv = m->nt = 0;
}

FX_FN fx_mesh fx_grid(int nx, int ny, double lx, double ly)
{
    fx_mesh m = {nx * ny, 2 * (nx - 1) * (ny - 1), NULL, NULL};
    m.x = malloc(sizeof(double) * 3 * (size_t)m.nv);
    m.tri = malloc(sizeof(int) * 3 * (size_t)m.nt);
    assert_non_null(m.x);
    assert_non_null(m.tri);
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double *p = m.x + 3 * (j * nx + i);
            p[0] = lx * i / (nx - 1);
            p[1] = ly * j / (ny - 1);
            p[2] = 0;
        }
    int t = 0;
    for (int j = 0; j + 1 < ny; j++)
        for (int i = 0; i + 1 < nx; i++) {
            int a = j * nx + i, b = a + 1, c = a + nx, d = c + 1;
            int *q = m.tri + 3 * t;
            if ((i + j) % 2 == 0) { /* diagonal a-d */
                q[0] = a;
                q[1] = b;
                q[2] = d;
                q[3] = a;
                q[4] = d;
                q[5] = c;
            } else { /* diagonal b-c */
                q[0] = a;
                q[1] = b;
                q[2] = c;
                q[3] = b;
                q[4] = d;
                q[5] = c;
            }
            t += 2;
        }
    return m;
}

/* Open-addressing map from an undirected edge to its midpoint's index. */
typedef struct edge_map {
    long *key;
    int *val;
    size_t cap;
} edge_map;

static int edge_map_get(edge_map *em, int i, int j, int fresh)
{
    if (i > j) {
        int t = i;
        i = j;
        j = t;
    }
    long k = (long)i * 0x100000L + j;
    size_t h = ((size_t)k * 0x9E3779B97F4A7C15ull) & (em->cap - 1);
    while (em->key[h] >= 0 && em->key[h] != k)
        h = (h + 1) & (em->cap - 1);
    if (em->key[h] < 0) {
        em->key[h] = k;
        em->val[h] = fresh;
    }
    return em->val[h];
}

FX_FN fx_mesh fx_subdivide(const fx_mesh *m, const double *v, double **vout)
{
    size_t cap = 16;
    while (cap < 4 * (size_t)m->nt * 3)
        cap *= 2;
    edge_map em = {malloc(sizeof(long) * cap), malloc(sizeof(int) * cap), cap};
    assert_non_null(em.key);
    assert_non_null(em.val);
    for (size_t k = 0; k < cap; k++)
        em.key[k] = -1;
    /* At most 3 new vertices per triangle. */
    int maxv = m->nv + 3 * m->nt;
    fx_mesh o = {m->nv, 4 * m->nt, malloc(sizeof(double) * 3 * (size_t)maxv),
                 malloc(sizeof(int) * 12 * (size_t)m->nt)};
    assert_non_null(o.x);
    assert_non_null(o.tri);
    double *vo = NULL;
    if (v) {
        vo = malloc(sizeof(double) * 3 * (size_t)maxv);
        assert_non_null(vo);
        memcpy(vo, v, sizeof(double) * 3 * (size_t)m->nv);
    }
    memcpy(o.x, m->x, sizeof(double) * 3 * (size_t)m->nv);
    for (int t = 0; t < m->nt; t++) {
        const int *q = m->tri + 3 * t;
        int mid[3];
        for (int k = 0; k < 3; k++) {
            int a = q[k], b = q[(k + 1) % 3];
            int id = edge_map_get(&em, a, b, o.nv);
            if (id == o.nv) {
                for (int c = 0; c < 3; c++) {
                    o.x[3 * id + c] = 0.5 * (m->x[3 * a + c] + m->x[3 * b + c]);
                    if (vo)
                        vo[3 * id + c] = 0.5 * (v[3 * a + c] + v[3 * b + c]);
                }
                o.nv++;
            }
            mid[k] = id; /* midpoint of edge (q[k], q[k+1]) */
        }
        int *r = o.tri + 12 * t;
        int sub[12] = {q[0],   mid[0], mid[2], mid[0], q[1],   mid[1],
                       mid[2], mid[1], q[2],   mid[0], mid[1], mid[2]};
        memcpy(r, sub, sizeof sub);
    }
    free(em.key);
    free(em.val);
    if (vout)
        *vout = vo;
    else
        free(vo);
    return o;
}

FX_FN fx_mesh fx_icosphere(int level, double r, double jitter, fx_rng *rng)
{
    const double g = (1 + sqrt(5.0)) / 2;
    static const int T[60] = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                              4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                              6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
    const double X[36] = {-1, g,  0,  1, g, 0,  -1, -g, 0,  1, -g, 0, 0,  -1, g,  0,  1, g,
                          0,  -1, -g, 0, 1, -g, g,  0,  -1, g, 0,  1, -g, 0,  -1, -g, 0, 1};
    fx_mesh m = {12, 20, malloc(sizeof X), malloc(sizeof T)};
    assert_non_null(m.x);
    assert_non_null(m.tri);
    memcpy(m.x, X, sizeof X);
    memcpy(m.tri, T, sizeof T);
    for (int l = 0; l < level; l++) {
        fx_mesh s = fx_subdivide(&m, NULL, NULL);
        fx_mesh_free(&m);
        m = s;
    }
    for (int i = 0; i < m.nv; i++) {
        double *p = m.x + 3 * i;
        double n = fx_norm(p);
        for (int c = 0; c < 3; c++)
            p[c] = r * p[c] / n + r * fx_uniform(rng, -jitter, jitter);
    }
    return m;
}

FX_FN void fx_append(fx_mesh *m, const fx_mesh *b)
{
    m->x = realloc(m->x, sizeof(double) * 3 * (size_t)(m->nv + b->nv));
    m->tri = realloc(m->tri, sizeof(int) * 3 * (size_t)(m->nt + b->nt));
    assert_non_null(m->x);
    assert_non_null(m->tri);
    memcpy(m->x + 3 * m->nv, b->x, sizeof(double) * 3 * (size_t)b->nv);
    for (int k = 0; k < 3 * b->nt; k++)
        m->tri[3 * m->nt + k] = b->tri[k] + m->nv;
    m->nv += b->nv;
    m->nt += b->nt;
}

FX_FN void fx_translate(fx_mesh *m, const double d[3])
{
    for (int i = 0; i < m->nv; i++)
        for (int c = 0; c < 3; c++)
            m->x[3 * i + c] += d[c];
}

FX_FN iso_mesh *fx_make(const fx_mesh *m)
{
    iso_mesh *out = NULL;
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_mesh_create(m->nv, m->x, m->nt, m->tri, "fixture", &out, &err);
    if (rc != ISO_OK)
        fail_msg("fixture mesh refused: %s", err.msg);
    return out;
}

FX_FN void fx_rigid_field(int nv, const double *x, const double a[3], const double b[3], double *v)
{
    for (int i = 0; i < nv; i++) {
        double w[3];
        fx_cross(b, x + 3 * i, w);
        for (int c = 0; c < 3; c++)
            v[3 * i + c] = a[c] + w[c];
    }
}

/* ---- paths ------------------------------------------------------------------- */

/* pose: y = R (x - c) + c; twist: velocity w × (y − c) = −w × c + w × y. */
static int rot_path_eval(void *ctx, int handle, double t, iso_pose *pose, iso_twist *tw)
{
    const fx_rot_path *p = ctx;
    (void)handle;
    const double pi = acos(-1.0);
    double th = p->amp * sin(p->freq * pi * t);
    double dth = p->amp * p->freq * pi * cos(p->freq * pi * t);
    fx_rotation(p->axis, th, pose->R);
    for (int i = 0; i < 3; i++)
        pose->p[i] = p->c[i] - (pose->R[3 * i] * p->c[0] + pose->R[3 * i + 1] * p->c[1] +
                                pose->R[3 * i + 2] * p->c[2]);
    for (int i = 0; i < 3; i++)
        tw->w[i] = dth * p->axis[i];
    fx_cross(p->c, tw->w, tw->v); /* −w × c = c × w */
    return 0;
}

FX_FN iso_path fx_rot_path_make(fx_rot_path *p)
{
    iso_path path = {rot_path_eval, p};
    return path;
}

static int trans_path_eval(void *ctx, int handle, double t, iso_pose *pose, iso_twist *tw)
{
    const fx_trans_path *p = ctx;
    (void)handle;
    const double pi = acos(-1.0);
    memset(pose, 0, sizeof *pose);
    pose->R[0] = pose->R[4] = pose->R[8] = 1;
    for (int i = 0; i < 3; i++) {
        pose->p[i] = t * p->d[i] + sin(pi * t) * p->bulge[i];
        tw->w[i] = 0;
        tw->v[i] = p->d[i] + pi * cos(pi * t) * p->bulge[i];
    }
    return 0;
}

FX_FN iso_path fx_trans_path_make(fx_trans_path *p)
{
    iso_path path = {trans_path_eval, p};
    return path;
}

/* ---- regions ----------------------------------------------------------------- */

FX_FN void fx_regions(iso_regions *r, int nv, const unsigned char *kind)
{
    iso_err err;
    iso_err_clear(&err);
    memset(r, 0, sizeof *r);
    if (iso_regions_init(r, nv, &err) != ISO_OK)
        fail_msg("iso_regions_init: %s", err.msg);
    int any_handle = 0;
    for (int i = 0; i < nv; i++) {
        r->kind[i] = kind[i];
        r->handle[i] = kind[i] == ISO_HANDLE ? 0 : -1;
        any_handle |= kind[i] == ISO_HANDLE;
    }
    r->n_handles = any_handle ? 1 : 0;
}
