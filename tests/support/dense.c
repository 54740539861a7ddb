/* tests/support/dense.c -- the method's forms over the whole mesh, dense
 * (iso_dense.h).
 *
 * Elements: every triangle (Q1, weight 1 − ω) and both ordered pairs
 * (Ti, Tj) and (Tj, Ti) of every interior edge (Q2, weight ω), straight
 * from the mesh's edge-triangle adjacency. */
#include "iso_dense.h"

#include <math.h>
#include <string.h>

#include "iso_element.h"

/* One element's matrix Q (dimension 3 nl) on global vertices v[0..nl-1]. */
typedef void (*element_fn)(void *ctx, const int *v, int nl, int pair, const double *Q, double w);

static void corners(const double *x, const int *t, double xi[9])
{
    for (int k = 0; k < 3; k++)
        memcpy(xi + 3 * k, x + 3 * t[k], 3 * sizeof(double));
}

/* The ordered pair (Ti, Tj): Ti's corners, then Tj's corner not in Ti. */
static int pair_matrix(const double *x, const int *Ti, const int *Tj, iso_weighting w, int v[4],
                       double Q[144])
{
    int jmap[3];
    memcpy(v, Ti, 3 * sizeof(int));
    for (int k = 0; k < 3; k++) {
        jmap[k] = 3;
        for (int l = 0; l < 3; l++)
            if (Tj[k] == Ti[l])
                jmap[k] = l;
        if (jmap[k] == 3)
            v[3] = Tj[k];
    }
    double xi[9];
    corners(x, Ti, xi);
    return iso_elem_q2(xi, x + 3 * v[3], jmap, w, Q);
}

static int for_each_element(const iso_mesh *m, const double *x, const iso_solver_opts *o,
                            element_fn fn, void *ctx, iso_err *err)
{
    int nt = iso_mesh_triangle_count(m), ne = iso_mesh_edge_count(m);
    const int *tri = iso_mesh_triangles(m), *et = iso_mesh_edge_triangles(m);
    double Q[144], xi[9];
    int v[4];
    for (int t = 0; t < nt; t++) {
        corners(x, tri + 3 * t, xi);
        if (iso_elem_q1(xi, o->weighting, Q) != 0)
            return iso_err_set(err, ISO_ENUMERIC, -1, "triangle %d is degenerate", t);
        fn(ctx, tri + 3 * t, 3, 0, Q, 1.0 - o->omega);
    }
    for (int k = 0; k < ne; k++) {
        if (et[2 * k + 1] < 0)
            continue;
        for (int side = 0; side < 2; side++) {
            int ti = et[2 * k + side], tj = et[2 * k + 1 - side];
            if (pair_matrix(x, tri + 3 * ti, tri + 3 * tj, o->weighting, v, Q) != 0)
                return iso_err_set(err, ISO_ENUMERIC, -1, "triangle %d is degenerate", ti);
            fn(ctx, v, 4, 1, Q, o->omega);
        }
    }
    return ISO_OK;
}

static int read_opts(const iso_solver_opts *opts, iso_solver_opts *o, iso_err *err)
{
    if (opts)
        *o = *opts;
    else
        iso_solver_opts_default(o);
    if (!(o->omega > 0.0 && o->omega <= 1.0))
        return iso_err_set(err, ISO_EINVAL, -1, "omega = %g is outside (0, 1]", o->omega);
    if (o->weighting != ISO_WEIGHT_PARAM && o->weighting != ISO_WEIGHT_AREA)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown weighting %d", (int)o->weighting);
    return ISO_OK;
}

typedef struct dense_ctx {
    double *A;
    size_t n3;
} dense_ctx;

static void add_dense(void *ctx, const int *v, int nl, int pair, const double *Q, double w)
{
    dense_ctx *d = ctx;
    int dim = 3 * nl;
    (void)pair;
    for (int a = 0; a < dim; a++)
        for (int b = 0; b < dim; b++)
            d->A[(size_t)(3 * v[a / 3] + a % 3) * d->n3 + (size_t)(3 * v[b / 3] + b % 3)] +=
                w * Q[a * dim + b];
}

int iso_assemble_dense(const iso_mesh *m, const double *x, const iso_solver_opts *opts, double *A,
                       iso_err *err)
{
    iso_solver_opts o;
    int rc = read_opts(opts, &o, err);
    if (rc != ISO_OK)
        return rc;
    dense_ctx d = {A, 3 * (size_t)iso_mesh_vertex_count(m)};
    memset(A, 0, d.n3 * d.n3 * sizeof(double));
    return for_each_element(m, x, &o, add_dense, &d, err);
}

typedef struct energy_ctx {
    const double *v;
    double d1, d2;
} energy_ctx;

static void add_energy(void *ctx, const int *v, int nl, int pair, const double *Q, double w)
{
    energy_ctx *c = ctx;
    int dim = 3 * nl;
    double acc = 0;
    (void)w;
    for (int a = 0; a < dim; a++) {
        double va = c->v[3 * v[a / 3] + a % 3], row = 0;
        for (int b = 0; b < dim; b++)
            row += Q[a * dim + b] * c->v[3 * v[b / 3] + b % 3];
        acc += va * row;
    }
    if (pair)
        c->d2 += acc;
    else
        c->d1 += acc;
}

double iso_distortion(const iso_mesh *m, const double *x, const double *v,
                      const iso_solver_opts *opts, double *d1, double *d2)
{
    iso_solver_opts o;
    iso_err e;
    iso_err_clear(&e);
    if (read_opts(opts, &o, &e) != ISO_OK)
        return NAN;
    energy_ctx c = {v, 0, 0};
    if (for_each_element(m, x, &o, add_energy, &c, &e) != ISO_OK)
        return NAN;
    if (d1)
        *d1 = c.d1;
    if (d2)
        *d2 = c.d2;
    return (1.0 - o.omega) * c.d1 + o.omega * c.d2;
}
