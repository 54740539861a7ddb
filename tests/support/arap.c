/* tests/support/arap.c -- as-rigid-as-possible deformation (iso_arap.h).
 *
 * Everything runs over the edge list: each edge (i, j) with weight w
 * contributes to both one-rings, with the same rest vector p_ij and deformed
 * vector q_ij (the terms of i and of j differ only in sign, and the
 * energy and covariance are quadratic). So one pass over edges gives the
 * covariances, one the right-hand side, one the energy.
 *
 * Unknowns are the displacements u = x − p of the free vertices; free
 * vertex f is column f of CHOLMOD's n_free x 3 right-hand side. With R = I
 * and no constrained displacement the right-hand side is exactly zero, so
 * a no-motion problem stays at the rest pose bit for bit. */
#include "iso_arap.h"

#include <cholmod.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "iso_clock.h"

typedef struct arap {
    const iso_mesh *m;
    const iso_regions *r;
    int nv, ne, nf;
    const int *edges;     /* 2*ne */
    const double *p;      /* 3*nv rest positions */
    double *w;            /* ne cotangent weights */
    int *free_of;         /* nv: free index or −1 */
    int *vert_of;         /* nf: vertex of each free index */
    double *x;            /* 3*nv current positions */
    double *u;            /* 3*nv current displacements */
    double *R;            /* 9*nv rotations, row-major */
    double *S;            /* 9*nv covariances Σ w q pᵀ */
    unsigned char *moved; /* nv: some one-ring edge differs from rest */
    int n_clamped;
    cholmod_common c;
    int c_started;
    cholmod_sparse *A;
    cholmod_factor *L;
    cholmod_dense *B, *X, *Y, *E;
} arap;

/* ===== 3x3 closest rotation ============================================= */

/* Cyclic Jacobi on a symmetric 3x3 A (row-major, destroyed): eigenvalues
 * into d, eigenvectors into the columns of V. Rotations are computed the
 * Rutishauser way (t from θ = (a_qq − a_pp)/2a_pq), which stays accurate
 * for the tiny and nearly equal eigenvalues a flat one-ring produces. */
static void jacobi3(double A[9], double d[3], double V[9])
{
    static const int P[3] = {0, 0, 1}, Q[3] = {1, 2, 2};
    for (int i = 0; i < 9; i++)
        V[i] = (i % 4 == 0);
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = fabs(A[1]) + fabs(A[2]) + fabs(A[5]);
        double diag = fabs(A[0]) + fabs(A[4]) + fabs(A[8]);
        if (off == 0.0 || off <= 1e-300 || off < 1e-18 * diag)
            break;
        for (int k = 0; k < 3; k++) {
            int p = P[k], q = Q[k];
            double apq = A[3 * p + q];
            if (apq == 0.0)
                continue;
            double theta = (A[3 * q + q] - A[3 * p + p]) / (2.0 * apq);
            double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
            double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
            for (int j = 0; j < 3; j++) { /* A <- Jᵀ A J, columns then rows */
                double ajp = A[3 * j + p], ajq = A[3 * j + q];
                A[3 * j + p] = c * ajp - s * ajq;
                A[3 * j + q] = s * ajp + c * ajq;
            }
            for (int j = 0; j < 3; j++) {
                double apj = A[3 * p + j], aqj = A[3 * q + j];
                A[3 * p + j] = c * apj - s * aqj;
                A[3 * q + j] = s * apj + c * aqj;
            }
            A[3 * p + q] = A[3 * q + p] = 0.0;
            for (int j = 0; j < 3; j++) {
                double vjp = V[3 * j + p], vjq = V[3 * j + q];
                V[3 * j + p] = c * vjp - s * vjq;
                V[3 * j + q] = s * vjp + c * vjq;
            }
        }
    }
    d[0] = A[0], d[1] = A[4], d[2] = A[8];
}

static double norm3(const double a[3])
{
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

static void cross3(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Some unit vector orthogonal to the unit vector a. */
static void any_orthogonal(const double a[3], double o[3])
{
    double e[3] = {0, 0, 0};
    int k = fabs(a[0]) <= fabs(a[1]) ? (fabs(a[0]) <= fabs(a[2]) ? 0 : 2)
                                     : (fabs(a[1]) <= fabs(a[2]) ? 1 : 2);
    e[k] = 1.0;
    cross3(a, e, o);
    double n = norm3(o);
    for (int i = 0; i < 3; i++)
        o[i] /= n;
}

/* Signed SVD: V from the eigenvectors of MᵀM (sorted by decreasing
 * eigenvalue, made right-handed), u1 and u2 by Gram–Schmidt on M v1 and
 * M v2, u3 = u1 × u2. Then U and V are both rotations and M = U Σ' Vᵀ with
 * the smallest singular value carrying the sign of det M, so R = U Vᵀ is
 * the closest rotation: a reflection has been undone by flipping the
 * column of the smallest singular value, as Sorkine & Alexa prescribe.
 * Rank-deficient M (a flat one-ring: rank 2) is handled by the cross
 * product; rank 1 or 0 picks an arbitrary completion. */
void iso_arap_closest_rotation(const double M[9], double R[9])
{
    double A[9], d[3], V[9];
    double scale = 0;
    for (int i = 0; i < 9; i++)
        scale = fmax(scale, fabs(M[i]));
    if (scale == 0.0 || !isfinite(scale)) {
        for (int i = 0; i < 9; i++)
            R[i] = (i % 4 == 0);
        return;
    }
    double Ms[9];
    for (int i = 0; i < 9; i++)
        Ms[i] = M[i] / scale; /* keep MᵀM clear of overflow and underflow */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            A[3 * i + j] = Ms[i] * Ms[j] + Ms[3 + i] * Ms[3 + j] + Ms[6 + i] * Ms[6 + j];
    jacobi3(A, d, V);
    int o[3] = {0, 1, 2}; /* sort by decreasing eigenvalue */
    for (int a = 0; a < 2; a++)
        for (int b = a + 1; b < 3; b++)
            if (d[o[b]] > d[o[a]]) {
                int t = o[a];
                o[a] = o[b];
                o[b] = t;
            }
    double v[3][3], u[3][3];
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            v[k][i] = V[3 * i + o[k]];
    cross3(v[0], v[1], v[2]); /* right-handed V; also exact unit length up to rounding */
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < 3; i++)
            u[k][i] = Ms[3 * i] * v[k][0] + Ms[3 * i + 1] * v[k][1] + Ms[3 * i + 2] * v[k][2];
    double n0 = norm3(u[0]);
    for (int i = 0; i < 3; i++)
        u[0][i] /= n0; /* n0 > 0: the largest singular value of a nonzero M */
    double dd = u[0][0] * u[1][0] + u[0][1] * u[1][1] + u[0][2] * u[1][2];
    for (int i = 0; i < 3; i++)
        u[1][i] -= dd * u[0][i];
    double n1 = norm3(u[1]);
    if (n1 <= 1e-12)
        any_orthogonal(u[0], u[1]);
    else
        for (int i = 0; i < 3; i++)
            u[1][i] /= n1;
    cross3(u[0], u[1], u[2]);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            R[3 * i + j] = u[0][i] * v[0][j] + u[1][i] * v[1][j] + u[2][i] * v[2][j];
}

/* ===== setup ============================================================ */

/* cot of the angle at c in triangle (a, b, c): cos/sin from dot and cross. */
static double cot_at(const double *a, const double *b, const double *c)
{
    double e[3], f[3], n[3];
    for (int k = 0; k < 3; k++) {
        e[k] = a[k] - c[k];
        f[k] = b[k] - c[k];
    }
    cross3(e, f, n);
    return (e[0] * f[0] + e[1] * f[1] + e[2] * f[2]) / norm3(n);
}

static void compute_weights(arap *s)
{
    const int *tri = iso_mesh_triangles(s->m);
    const int *et = iso_mesh_edge_triangles(s->m);
    for (int e = 0; e < s->ne; e++) {
        int i = s->edges[2 * e], j = s->edges[2 * e + 1];
        double w = 0;
        for (int k = 0; k < 2; k++) {
            int t = et[2 * e + k];
            if (t < 0)
                continue;
            const int *v = tri + 3 * t;
            int c = v[0] != i && v[0] != j ? v[0] : v[1] != i && v[1] != j ? v[1] : v[2];
            double ct = cot_at(s->p + 3 * i, s->p + 3 * j, s->p + 3 * c);
            if (ct < 0) {
                s->n_clamped++;
                ct = 0;
            }
            w += 0.5 * ct;
        }
        s->w[e] = w;
    }
}

static int check_input(const iso_mesh *m, const iso_regions *r, const double *xc,
                       int max_iterations, double rel_tol, const double *x_out, iso_err *err)
{
    if (!m || !r || !xc || !x_out)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "iso_arap_solve: mesh, regions, targets and output must not be NULL");
    const char *o = iso_mesh_origin(m);
    int nv = iso_mesh_vertex_count(m);
    if (r->nv != nv || !r->kind)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s: the regions cover %d vertices but the mesh has %d", o, r->nv, nv);
    if (max_iterations < 1)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s: ARAP needs at least one iteration (max_iterations = %d)", o,
                           max_iterations);
    if (!(rel_tol >= 0.0) || !isfinite(rel_tol))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s: the relative energy tolerance must be finite and >= 0 (got %g)", o,
                           rel_tol);
    int nc = 0;
    for (int i = 0; i < nv; i++) {
        if (r->kind[i] > ISO_HANDLE)
            return iso_err_set(err, ISO_EINVAL, -1, "%s: vertex %d has region kind %d", o, i,
                               (int)r->kind[i]);
        if (r->kind[i] == ISO_FREE || !iso_mesh_vertex_used(m, i))
            continue;
        nc++;
        for (int k = 0; k < 3; k++)
            if (!isfinite(xc[3 * i + k]))
                return iso_err_set(err, ISO_EINVAL, -1,
                                   "%s: the target of %s vertex %d is not finite (coordinate %d)",
                                   o, r->kind[i] == ISO_FIXED ? "fixed" : "handle", i, k);
    }
    if (nc == 0)
        return iso_err_set(err, ISO_ECONSTRAINT, -1,
                           "%s: ARAP needs at least one fixed or handle vertex, but all %d "
                           "vertices are free: the shape would be defined only up to a "
                           "translation and the global step's matrix is singular",
                           o, nv);
    return ISO_OK;
}

/* Every free vertex must reach a constrained one through edges of
 * positive weight, or its block of the Laplacian is singular (clamped
 * weights can cut a mesh apart). A breadth-first search from all
 * constrained vertices names the first free vertex left unreached. */
static int check_reachable(const arap *s, iso_err *err)
{
    int nv = s->nv, rc = ISO_OK;
    int *deg = calloc((size_t)nv + 1, sizeof *deg);
    int *adj = malloc(2 * (size_t)s->ne * sizeof *adj + 1);
    int *queue = malloc((size_t)nv * sizeof *queue + 1);
    unsigned char *seen = calloc((size_t)nv, 1);
    if (!deg || !adj || !queue || !seen) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory checking the constraints",
                         iso_mesh_origin(s->m));
        goto out;
    }
    for (int e = 0; e < s->ne; e++)
        if (s->w[e] > 0)
            deg[s->edges[2 * e] + 1]++, deg[s->edges[2 * e + 1] + 1]++;
    for (int i = 0; i < nv; i++)
        deg[i + 1] += deg[i];
    int *fill = queue; /* reuse as insertion cursors before the search */
    memcpy(fill, deg, (size_t)nv * sizeof *fill);
    for (int e = 0; e < s->ne; e++)
        if (s->w[e] > 0) {
            int i = s->edges[2 * e], j = s->edges[2 * e + 1];
            adj[fill[i]++] = j;
            adj[fill[j]++] = i;
        }
    int head = 0, tail = 0;
    for (int i = 0; i < nv; i++)
        if (s->r->kind[i] != ISO_FREE && iso_mesh_vertex_used(s->m, i))
            seen[i] = 1, queue[tail++] = i;
    while (head < tail) {
        int i = queue[head++];
        for (int k = deg[i]; k < deg[i + 1]; k++)
            if (!seen[adj[k]])
                seen[adj[k]] = 1, queue[tail++] = adj[k];
    }
    for (int f = 0; f < s->nf; f++)
        if (!seen[s->vert_of[f]]) {
            rc = iso_err_set(err, ISO_ECONSTRAINT, -1,
                             "%s: free vertex %d is not linked to any fixed or handle vertex "
                             "by edges of positive cotangent weight, so its position is "
                             "undetermined (add a constraint to its part of the mesh)",
                             iso_mesh_origin(s->m), s->vert_of[f]);
            break;
        }
out:
    free(deg);
    free(adj);
    free(queue);
    free(seen);
    return rc;
}

/* The free–free block of the cotangent Laplacian, upper triangle. */
static int factor_laplacian(arap *s, iso_err *err)
{
    const char *o = iso_mesh_origin(s->m);
    size_t nz = (size_t)s->nf;
    for (int e = 0; e < s->ne; e++)
        if (s->free_of[s->edges[2 * e]] >= 0 && s->free_of[s->edges[2 * e + 1]] >= 0)
            nz++;
    cholmod_triplet *T =
        cholmod_allocate_triplet((size_t)s->nf, (size_t)s->nf, nz, 1, CHOLMOD_REAL, &s->c);
    if (!T)
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "%s: CHOLMOD could not allocate the ARAP Laplacian (status %d)", o,
                           s->c.status);
    int *Ti = T->i, *Tj = T->j;
    double *Tx = T->x;
    size_t k = (size_t)s->nf;
    for (int f = 0; f < s->nf; f++)
        Ti[f] = Tj[f] = f, Tx[f] = 0;
    for (int e = 0; e < s->ne; e++) {
        int fi = s->free_of[s->edges[2 * e]], fj = s->free_of[s->edges[2 * e + 1]];
        double w = s->w[e];
        if (fi >= 0)
            Tx[fi] += w;
        if (fj >= 0)
            Tx[fj] += w;
        if (fi >= 0 && fj >= 0) {
            Ti[k] = fi < fj ? fi : fj;
            Tj[k] = fi < fj ? fj : fi;
            Tx[k++] = -w;
        }
    }
    T->nnz = k;
    s->A = cholmod_triplet_to_sparse(T, k, &s->c);
    cholmod_free_triplet(&T, &s->c);
    if (!s->A)
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "%s: CHOLMOD could not build the ARAP Laplacian (status %d)", o,
                           s->c.status);
    s->L = cholmod_analyze(s->A, &s->c);
    if (!s->L || s->c.status < CHOLMOD_OK)
        return iso_err_set(err, s->c.status == CHOLMOD_OUT_OF_MEMORY ? ISO_ENOMEM : ISO_ENUMERIC,
                           -1, "%s: CHOLMOD analysis of the ARAP Laplacian failed (status %d)", o,
                           s->c.status);
    if (!cholmod_factorize(s->A, s->L, &s->c) || s->c.status < CHOLMOD_OK)
        return iso_err_set(err, s->c.status == CHOLMOD_OUT_OF_MEMORY ? ISO_ENOMEM : ISO_ENUMERIC,
                           -1, "%s: CHOLMOD factorization of the ARAP Laplacian failed (status %d)",
                           o, s->c.status);
    if (s->c.status == CHOLMOD_NOT_POSDEF || s->L->minor < s->L->n) {
        size_t f = s->L->minor;
        return iso_err_set(err, ISO_ENUMERIC, -1,
                           "%s: the ARAP Laplacian is not positive definite (CHOLMOD stopped at "
                           "free vertex %d of %d)",
                           o, f < (size_t)s->nf ? s->vert_of[f] : -1, s->nf);
    }
    s->B = cholmod_zeros((size_t)s->nf, 3, CHOLMOD_REAL, &s->c);
    if (!s->B)
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory for the ARAP right-hand side",
                           o);
    return ISO_OK;
}

/* ===== the two steps ==================================================== */

/* Global: L_ff u_f = Σ_j w_ij (½(R_i + R_j) − I) p_ij + Σ_{j constrained} w_ij u_j. */
static int global_step(arap *s, iso_err *err)
{
    double *b = s->B->x;
    size_t ld = s->B->d;
    memset(b, 0, 3 * ld * sizeof *b);
    for (int e = 0; e < s->ne; e++) {
        int i = s->edges[2 * e], j = s->edges[2 * e + 1];
        int fi = s->free_of[i], fj = s->free_of[j];
        if (fi < 0 && fj < 0)
            continue;
        double w = s->w[e], pij[3], g[3];
        for (int k = 0; k < 3; k++)
            pij[k] = s->p[3 * i + k] - s->p[3 * j + k];
        const double *Ri = s->R + 9 * i, *Rj = s->R + 9 * j;
        for (int a = 0; a < 3; a++) {
            double t = 0;
            for (int k = 0; k < 3; k++)
                t += 0.5 * (Ri[3 * a + k] + Rj[3 * a + k]) * pij[k];
            g[a] = w * (t - pij[a]);
        }
        for (int a = 0; a < 3; a++) {
            if (fi >= 0)
                b[fi + (size_t)a * ld] += g[a] + (fj < 0 ? w * s->u[3 * j + a] : 0.0);
            if (fj >= 0)
                b[fj + (size_t)a * ld] += -g[a] + (fi < 0 ? w * s->u[3 * i + a] : 0.0);
        }
    }
    if (!cholmod_solve2(CHOLMOD_A, s->L, s->B, NULL, &s->X, NULL, &s->Y, &s->E, &s->c) ||
        s->c.status < CHOLMOD_OK)
        return iso_err_set(err, ISO_ENUMERIC, -1,
                           "%s: CHOLMOD solve of the ARAP step failed (status %d)",
                           iso_mesh_origin(s->m), s->c.status);
    const double *xs = s->X->x;
    size_t lx = s->X->d;
    for (int f = 0; f < s->nf; f++) {
        int i = s->vert_of[f];
        for (int a = 0; a < 3; a++) {
            s->u[3 * i + a] = xs[f + (size_t)a * lx];
            s->x[3 * i + a] = s->p[3 * i + a] + s->u[3 * i + a];
        }
    }
    return ISO_OK;
}

/* Local: R_i closest to S_i = Σ_j w_ij q_ij p_ijᵀ. A one-ring whose every
 * edge is bitwise unmoved keeps R = I exactly, so regions far from the
 * handle, and the no-motion problem, carry no rounding. */
static void local_step(arap *s)
{
    memset(s->S, 0, 9 * (size_t)s->nv * sizeof *s->S);
    memset(s->moved, 0, (size_t)s->nv);
    for (int e = 0; e < s->ne; e++) {
        int i = s->edges[2 * e], j = s->edges[2 * e + 1];
        double w = s->w[e], pij[3], qij[3];
        int moved = 0;
        for (int k = 0; k < 3; k++) {
            pij[k] = s->p[3 * i + k] - s->p[3 * j + k];
            qij[k] = s->x[3 * i + k] - s->x[3 * j + k];
            moved |= qij[k] != pij[k];
        }
        if (moved)
            s->moved[i] = s->moved[j] = 1;
        if (w == 0)
            continue;
        for (int a = 0; a < 3; a++)
            for (int k = 0; k < 3; k++) {
                double t = w * qij[a] * pij[k];
                s->S[9 * i + 3 * a + k] += t;
                s->S[9 * j + 3 * a + k] += t;
            }
    }
    for (int i = 0; i < s->nv; i++) {
        double *R = s->R + 9 * i;
        if (!s->moved[i]) {
            for (int k = 0; k < 9; k++)
                R[k] = (k % 4 == 0);
            continue;
        }
        iso_arap_closest_rotation(s->S + 9 * i, R);
    }
}

static double energy(const arap *s)
{
    double E = 0;
    for (int e = 0; e < s->ne; e++) {
        int i = s->edges[2 * e], j = s->edges[2 * e + 1];
        double w = s->w[e], pij[3], qij[3];
        if (w == 0)
            continue;
        for (int k = 0; k < 3; k++) {
            pij[k] = s->p[3 * i + k] - s->p[3 * j + k];
            qij[k] = s->x[3 * i + k] - s->x[3 * j + k];
        }
        const double *Ri = s->R + 9 * i, *Rj = s->R + 9 * j;
        for (int a = 0; a < 3; a++) {
            double ri = qij[a], rj = qij[a];
            for (int k = 0; k < 3; k++) {
                ri -= Ri[3 * a + k] * pij[k];
                rj -= Rj[3 * a + k] * pij[k];
            }
            E += w * (ri * ri + rj * rj);
        }
    }
    return E;
}

/* ===== driver =========================================================== */

static void arap_free(arap *s)
{
    free(s->w);
    free(s->free_of);
    free(s->vert_of);
    free(s->x);
    free(s->u);
    free(s->R);
    free(s->S);
    free(s->moved);
    if (s->c_started) {
        cholmod_free_sparse(&s->A, &s->c);
        cholmod_free_factor(&s->L, &s->c);
        cholmod_free_dense(&s->B, &s->c);
        cholmod_free_dense(&s->X, &s->c);
        cholmod_free_dense(&s->Y, &s->c);
        cholmod_free_dense(&s->E, &s->c);
        cholmod_finish(&s->c);
    }
}

static int arap_setup(arap *s, const iso_mesh *m, const iso_regions *r, const double *xc,
                      iso_err *err)
{
    s->m = m;
    s->r = r;
    s->nv = iso_mesh_vertex_count(m);
    s->ne = iso_mesh_edge_count(m);
    s->edges = iso_mesh_edges(m);
    s->p = iso_mesh_positions(m);
    size_t nv = (size_t)s->nv;
    s->w = malloc((size_t)s->ne * sizeof *s->w + 1);
    s->free_of = malloc(nv * sizeof *s->free_of);
    s->vert_of = malloc(nv * sizeof *s->vert_of);
    s->x = malloc(3 * nv * sizeof *s->x);
    s->u = malloc(3 * nv * sizeof *s->u);
    s->R = malloc(9 * nv * sizeof *s->R);
    s->S = malloc(9 * nv * sizeof *s->S);
    s->moved = malloc(nv);
    if (!s->w || !s->free_of || !s->vert_of || !s->x || !s->u || !s->R || !s->S || !s->moved)
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory for ARAP (%d vertices)",
                           iso_mesh_origin(m), s->nv);
    for (int i = 0; i < s->nv; i++) {
        int used = iso_mesh_vertex_used(m, i);
        int f = used && r->kind[i] == ISO_FREE;
        s->free_of[i] = f ? s->nf : -1;
        if (f)
            s->vert_of[s->nf++] = i;
        for (int k = 0; k < 3; k++) {
            /* constrained: target; free and unreferenced: rest */
            double xi = used && r->kind[i] != ISO_FREE ? xc[3 * i + k] : s->p[3 * i + k];
            s->x[3 * i + k] = xi;
            s->u[3 * i + k] = xi - s->p[3 * i + k];
        }
        for (int k = 0; k < 9; k++)
            s->R[9 * i + k] = (k % 4 == 0);
    }
    compute_weights(s);
    int rc = check_reachable(s, err);
    if (rc)
        return rc;
    if (s->nf == 0)
        return ISO_OK; /* nothing to solve: every vertex is placed */
    cholmod_start(&s->c);
    s->c_started = 1;
    s->c.print = 0; /* errors reach the caller through iso_err, not stderr */
    return factor_laplacian(s, err);
}

int iso_arap_solve(const iso_mesh *m, const iso_regions *r, const double *x_constrained,
                   int max_iterations, double rel_tol, double *x_out, iso_arap_stats *st,
                   iso_err *err)
{
    int rc = check_input(m, r, x_constrained, max_iterations, rel_tol, x_out, err);
    if (rc)
        return rc;
    arap s;
    memset(&s, 0, sizeof s);
    iso_arap_stats out;
    memset(&out, 0, sizeof out);
    if (st) {
        out.energy_history = st->energy_history;
        out.energy_cap = st->energy_history ? st->energy_cap : 0;
    }
    double t0 = iso_clock_now();
    rc = arap_setup(&s, m, r, x_constrained, err);
    if (rc)
        goto done;
    double t1 = iso_clock_now();
    out.seconds_factor = t1 - t0;
    out.n_free = s.nf;
    out.n_clamped = s.n_clamped;
    out.energy_initial = energy(&s);
    double e_prev = out.energy_initial;
    for (int it = 1; it <= max_iterations && s.nf > 0; it++) {
        rc = global_step(&s, err);
        if (rc)
            goto done;
        local_step(&s);
        double e = energy(&s);
        out.iterations = it;
        out.energy = e;
        if (out.history_len < out.energy_cap)
            out.energy_history[out.history_len++] = e;
        if (it >= 2 && fabs(e_prev - e) <= rel_tol * e) {
            out.converged = 1;
            break;
        }
        e_prev = e;
    }
    if (s.nf == 0) {
        local_step(&s);
        out.energy = energy(&s);
        out.converged = 1;
    }
    out.seconds_iterate = iso_clock_now() - t1;
    memcpy(x_out, s.x, 3 * (size_t)s.nv * sizeof *x_out);
done:
    arap_free(&s);
    if (st)
        *st = out;
    return rc;
}
