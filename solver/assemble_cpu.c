/* solver/assemble_cpu.c -- the C assembly path: element forms at the
 * current positions, scattered through the slot map (solver_internal.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solver_internal.h"

typedef iso_solver__element element;
#define local_count iso_solver__local_count

/* Element matrix Q (dimension 3·nl) of element e at positions x. */
int iso_solver__element_matrix(const iso_solver_opts *o, const element *e, const double *x,
                               double *Q)
{
    double xi[9];
    for (int k = 0; k < 3; k++)
        memcpy(xi + 3 * k, x + 3 * e->v[k], 3 * sizeof(double));
    if (e->kind == 1)
        return iso_elem_q1(xi, o->weighting, Q);
    return iso_elem_q2(xi, x + 3 * e->v[3], e->jmap, o->weighting, Q);
}

/* Restoration term of edge element e: μ Q, Q = w_e [uuᵀ −uuᵀ; −uuᵀ uuᵀ], and its
 * linear part: the minimiser of vᵀAv + gᵀv solves A v = −g/2, so each free
 * endpoint's right-hand side gets −μ w_e c_e (∓u), c_e = (|e| − L_e)/τ. */
static void edge_matrix(iso_solver *s, const element *e, const double *x, double *Q, double *rhs)
{
    const double *a = x + 3 * e->v[0], *b = x + 3 * e->v[1];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double len = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int k = 0; k < 3; k++)
        u[k] /= len;
    double we = s->edge_w[e->tri], c = (len - s->rest_len[e->tri]) / s->o.restore_tau;
    double mu = s->o.restore_mu;
    for (int i = 0; i < 6; i++) /* μ Q, upper triangle: what scatter_upper reads */
        for (int j = i; j < 6; j++) {
            double sign = (i < 3) == (j < 3) ? 1.0 : -1.0;
            Q[6 * i + j] = mu * (sign * we * u[i % 3] * u[j % 3]);
        }
    for (int end = 0; end < 2; end++) {
        int f = s->free_of[e->v[end]];
        if (f < 0)
            continue;
        double sign = end == 0 ? -1.0 : 1.0;
        for (int k = 0; k < 3; k++)
            rhs[3 * f + k] -= s->o.restore_mu * we * c * sign * u[k];
    }
}

/* The rigid fit of triangle t at positions x, computed once per evaluation:
 * a triangle is the source of Q1 and of up to three pairs. The cache keeps
 * the fit's core (what the edge blocks read); Q1 asks for the whole fit in
 * *full, which is then computed afresh (each triangle has one Q1 element,
 * and triangle elements come first). NULL if the fit is singular. */
static const iso_elem_fit_core *cached_fit(iso_solver *s, int t, const double *x,
                                           iso_elem_fit *full)
{
    if (!full && s->fit_stamp[t] == s->fit_epoch)
        return &s->fits[t];
    const int *tri = iso_mesh_triangles(s->m) + 3 * t;
    double xt[9];
    iso_elem_fit tmp, *f = full ? full : &tmp;
    for (int k = 0; k < 3; k++)
        memcpy(xt + 3 * k, x + 3 * tri[k], 3 * sizeof(double));
    if (iso_elem_fit_compute(xt, f) != 0)
        return NULL;
    iso_elem_fit_core_of(f, &s->fits[t]);
    s->fit_stamp[t] = s->fit_epoch;
    return &s->fits[t];
}

/* Which edge carries each triangle element's Q1 (iso_elem_edge_from_fits
 * adds it with the edge's block, which holds all of the triangle's blocks):
 * the first pair element whose Ti or Tj it is. q1_carry[i]: for a pair
 * element (the first of a mirrored two), bit 0 if it carries Ti's and bit
 * 1 if it carries Tj's; for a triangle element, 1 if an edge carries it. A
 * triangle element with no interior edge keeps its own Q1 (iso_solver_create
 * only lets one through with all three vertices constrained, when it is no
 * element at all, but this costs nothing to allow). */
static int plan_q1_carriers(iso_solver *s, iso_err *err)
{
    int nt = iso_mesh_triangle_count(s->m);
    int *q1_el = malloc(((size_t)nt + 1) * sizeof *q1_el);
    s->q1_carry = calloc((size_t)s->nel + 1, 1);
    if (!q1_el || !s->q1_carry) {
        free(q1_el);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the rigid-fit cache");
    }
    for (int t = 0; t < nt; t++)
        q1_el[t] = -1;
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 1)
            q1_el[s->el[i].tri] = i;
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        if (e->kind != 2)
            continue;
        int k = i, tj = -1;
        if (i + 1 < s->nel && iso_solver__is_mirror(e, &s->el[i + 1]))
            tj = s->el[++i].tri;
        int qi = q1_el[e->tri], qj = tj >= 0 ? q1_el[tj] : -1;
        if (qi >= 0) {
            s->q1_carry[k] |= 1;
            s->q1_carry[qi] = 1;
            q1_el[e->tri] = -1;
        }
        if (qj >= 0) {
            s->q1_carry[k] |= 2;
            s->q1_carry[qj] = 1;
            q1_el[tj] = -1;
        }
    }
    free(q1_el);
    return ISO_OK;
}

static int ensure_fit_cache(iso_solver *s, iso_err *err)
{
    if (s->fits)
        return ISO_OK;
    size_t nt = (size_t)iso_mesh_triangle_count(s->m) + 1;
    s->fits = malloc(nt * sizeof *s->fits);
    s->fit_stamp = calloc(nt, sizeof *s->fit_stamp);
    if (!s->fits || !s->fit_stamp)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the rigid-fit cache");
    return plan_q1_carriers(s, err);
}

/* w Q1 of a triangle element through the fit cache; −1 if degenerate. */
static int cached_element_matrix(iso_solver *s, const element *e, const double *x, double w,
                                 double *Q)
{
    iso_elem_fit full, *f = &full;
    if (!cached_fit(s, e->tri, x, f))
        return -1;
    double xi[9];
    for (int k = 0; k < 3; k++)
        memcpy(xi + 3 * k, x + 3 * e->v[k], 3 * sizeof(double));
    iso_elem_q1_from_fit(xi, f, s->o.weighting, Q);
    for (int i = 0; i < 9; i++) /* the upper triangle is what is scattered */
        for (int j = i; j < 9; j++)
            Q[9 * i + j] *= w;
    return 0;
}

static int report_degenerate(iso_solver *s, int t, iso_err *err)
{
    return iso_err_set(err, ISO_ENUMERIC, -1,
                       "%s: triangle %d has degenerated during the deformation (its "
                       "rigid fit is singular)",
                       iso_mesh_origin(s->m), t);
}

/* A fit has failed: names the triangle of the first element, in list
 * order, whose fit fails, as the OpenCL path does, whichever element's
 * fit this assembly happened to compute first. */
static int report_first_degenerate(iso_solver *s, const double *x, iso_err *err)
{
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        if ((e->kind == 1 || e->kind == 2) && !cached_fit(s, e->tri, x, NULL))
            return report_degenerate(s, e->tri, err);
    }
    return iso_err_set(err, ISO_ENUMERIC, -1, "%s: a rigid fit is singular", iso_mesh_origin(s->m));
}

/* N scale of triangle t (iso_elem_n_scale) at positions x. */
static double n_scale_of(const iso_solver *s, int t, const double *x)
{
    if (s->o.weighting != ISO_WEIGHT_AREA)
        return 1.0 / 24.0;
    const int *tri = iso_mesh_triangles(s->m) + 3 * t;
    double xt[9];
    for (int k = 0; k < 3; k++)
        memcpy(xt + 3 * k, x + 3 * tri[k], 3 * sizeof(double));
    return iso_elem_n_scale(xt, ISO_WEIGHT_AREA);
}

/* ω (Q2(Ti, Tj) + Q2(Tj, Ti)) of pair element e and, when `mirror` is not
 * NULL, its mirror, as one 12x12 block (upper triangle) in the edge layout
 * (a, b, p, q) of iso_solver__edge_layout: both ordered pairs of an edge
 * share their four vertices, so one block and one scatter serve both. With
 * it (1 − ω) Q1 of Ti (carry bit 0) and of Tj (bit 1), whose blocks are
 * among the edge's (plan_q1_carriers). −1 when a fit is singular. */
static int edge_matrix_q2(iso_solver *s, const element *e, const element *mirror, const int map[4],
                          int carry, const double *x, double *Q)
{
    const iso_elem_fit_core *fi = cached_fit(s, e->tri, x, NULL), *fj = NULL;
    if (!fi || (mirror && !(fj = cached_fit(s, mirror->tri, x, NULL))))
        return -1;
    double xl[12];
    for (int l = 0; l < 4; l++)
        memcpy(xl + 3 * l, x + 3 * e->v[map[l]], 3 * sizeof(double));
    memset(Q, 0, 144 * sizeof(double));
    /* each ordered pair's N is its target's; each Q1's N its own */
    double w1 = 1.0 - s->o.omega, w2 = s->o.omega, sj, si = n_scale_of(s, e->tri, x);
    if (mirror) {
        sj = n_scale_of(s, mirror->tri, x);
    } else {
        double xj[9];
        memcpy(xj, xl, 6 * sizeof(double));
        memcpy(xj + 6, xl + 9, 3 * sizeof(double));
        sj = iso_elem_n_scale(xj, s->o.weighting);
    }
    iso_elem_edge_from_fits(fi, fj, xl, w2 * sj, mirror ? w2 * si : 0.0, carry & 1 ? w1 * si : 0.0,
                            mirror && (carry & 2) ? w1 * sj : 0.0, Q);
    return 0;
}

/* GCC at -O2 keeps 3-trip loops as loops; unrolled, the block loops below
 * lose their index arithmetic and the ≤ k bound's branches. */
#if defined(__GNUC__) && !defined(__clang__)
#define UNROLL3 _Pragma("GCC unroll 3")
#else
#define UNROLL3
#endif

/* scatter() for a block whose upper triangle alone is filled: Q (leading
 * dimension ld) in a layout of n vertices that map takes to e's local
 * vertices (and so to e's slots). Its weight is already in Q. */
static void scatter_upper(iso_solver *s, const element *e, int n, const int *map, const double *Q,
                          int ld, const double *vc, double *Ax, double *rhs)
{
    const int *sl = s->slots + e->slot;
    int nl = local_count(e), g[4], f[4];
    for (int l = 0; l < n; l++) {
        g[l] = e->v[map[l]];
        f[l] = s->free_of[g[l]];
    }
    for (int l = 0; l < n; l++)
        for (int m = l; m < n; m++) {
            if (f[l] < 0 && f[m] < 0)
                continue;
            const double *B = Q + ld * 3 * l + 3 * m; /* B[ld i + j]: row i, column j */
            const int *pos = sl + 3 * (nl * map[l] + map[m]);
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
            pos = sl + 3 * (nl * map[m] + map[l]);
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

int iso_solver__assemble_cpu(iso_solver *s, const double *x, const double *vc, iso_err *err)
{
    int rc = ensure_fit_cache(s, err);
    if (rc != ISO_OK)
        return rc;
    if (++s->fit_epoch == 0) { /* wrapped: forget every stamp */
        memset(s->fit_stamp, 0, ((size_t)iso_mesh_triangle_count(s->m) + 1) * sizeof(unsigned));
        s->fit_epoch = 1;
    }
    double *Ax = s->A->x, *rhs = s->B->x;
    int n3 = 3 * s->nf;
    memset(Ax, 0, (size_t)((int *)s->A->p)[n3] * sizeof(double));
    memset(rhs, 0, (size_t)n3 * sizeof(double));
    double Q[144];
    double w1 = 1.0 - s->o.omega;
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        if (e->kind == 3) {
            static const int id2[2] = {0, 1};
            edge_matrix(s, e, x, Q, rhs);
            scatter_upper(s, e, 2, id2, Q, 6, vc, Ax, rhs);
            continue;
        }
        if (e->kind == 2) {
            const element *mirror = NULL;
            if (i + 1 < s->nel && iso_solver__is_mirror(e, &s->el[i + 1]))
                mirror = &s->el[++i];
            int map[4], carry = s->q1_carry[i - (mirror != NULL)];
            iso_solver__edge_layout(e, map);
            if (edge_matrix_q2(s, e, mirror, map, carry, x, Q) != 0)
                return report_first_degenerate(s, x, err);
            scatter_upper(s, e, 4, map, Q, 12, vc, Ax, rhs);
            continue;
        }
        if (s->q1_carry[i]) /* its edge adds it */
            continue;
        if (cached_element_matrix(s, e, x, w1, Q) != 0)
            return report_first_degenerate(s, x, err);
        static const int id[3] = {0, 1, 2};
        scatter_upper(s, e, 3, id, Q, 9, vc, Ax, rhs);
    }
    return ISO_OK;
}
