/* solver/rotate.c -- the rotated preconditioner (iso_solver_opts.
 * preconditioner, ISO_PRECOND_ROTATED): the cached factor, turned by each
 * free vertex's rotation since the positions its matrix was assembled at.
 *
 * Why it works: A(x) is built from rigid-field fits (d1, d2) and edge
 * directions (restoration), so it is equivariant under rotation: for a
 * rotation R of the whole mesh, A(R x) = Q A(x) Qᵀ with Q = blockdiag(R).
 * Along a near-isometric motion each one-ring turns nearly rigidly, so with
 * R_i the turn of vertex i's ring from the factor's positions y to the
 * current x, A(x) ≈ Q A(y) Qᵀ with Q = blockdiag(R_i), and
 *     M⁻¹ = Q L⁻ᵀ L⁻¹ Qᵀ        (L L' = A(y), the cached factor)
 * preconditions A(x) far better than L alone, whose matrix is a rotation
 * behind. M⁻¹ is symmetric positive definite for every invertible Q, so a
 * poor R_i costs iterations, never correctness.
 *
 * R_i: the least-squares linear map F_i of the ring's edges and its normal
 * from y to x (F_i = S_i P_i⁻¹, S_i = Σ e fᵀ + n mᵀ and P_i = Σ f fᵀ + m mᵀ
 * over the edges at i, f at y and e at x, m and n the vertex normals at y
 * and x scaled to the ring's size, so that a flat ring still fixes all
 * three axes), made orthogonal by Newton-Schulz steps. What depends on y
 * alone (f, m, P_i⁻¹) is prepared once per factor, by the thread that made
 * the factor: the worker prepares its own (worker.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solver_internal.h"

struct iso_solver__frame {
    const iso_solver *s; /* topology only: mesh, vert_of (outlive the frame) */
    int ne;
    double *x;    /* 3 nv: the positions the factor's matrix was assembled at */
    double *f;    /* 3 ne: the edges at x (b − a) */
    double *m;    /* 3 nv: the scaled vertex normals at x */
    double *pinv; /* 9 nf: P_i⁻¹, or all zero where P_i is singular (R_i = I) */
    double *p;    /* 9 nv: scratch for P */
};

/* ===== small 3×3 helpers (row-major) ==================================== */

static const double identity3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

static void cross(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double norm3(const double *a)
{
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

/* M += u wᵀ */
static void add_outer(double *M, const double *u, const double *w)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            M[3 * r + c] += u[r] * w[c];
}

static void mul3(const double *A, const double *B, double *C)
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            C[3 * r + c] = A[3 * r] * B[c] + A[3 * r + 1] * B[3 + c] + A[3 * r + 2] * B[6 + c];
}

/* Y = X⁻¹ by cofactors; 0 where X is singular or not finite. */
static int inverse3(const double *X, double *Y)
{
    double C[9]; /* rows: the cofactor matrix's, det(X) X⁻ᵀ */
    cross(X + 3, X + 6, C);
    cross(X + 6, X, C + 3);
    cross(X, X + 3, C + 6);
    double det = X[0] * C[0] + X[1] * C[1] + X[2] * C[2];
    double scale = fabs(X[0]) + fabs(X[4]) + fabs(X[8]);
    if (!(fabs(det) > 1e-12 * scale * scale * scale) || !isfinite(det))
        return 0;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            Y[3 * r + c] = C[3 * c + r] / det;
    return 1;
}

/* G = 3I − FᵀF; returns ‖FᵀF − I‖² (Frobenius). */
static double gram_defect(const double *F, double *G)
{
    double d = 0;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double g = F[r] * F[c] + F[3 + r] * F[3 + c] + F[6 + r] * F[6 + c];
            double dev = g - (r == c);
            d += dev * dev;
            G[3 * r + c] = (r == c ? 3.0 : 0.0) - g;
        }
    return d;
}

/* F made orthogonal in place by Newton-Schulz steps F ← F (3I − FᵀF) / 2,
 * which converge quadratically while ‖FᵀF − I‖ < 0.8; done below 1e-3 (on
 * the cactus an exact polar factor gave the same iteration counts). Outside
 * that basin, or not there in four steps (a ring that did not turn
 * rigidly: crushed or folded), F becomes I: that vertex is preconditioned
 * as by the plain factor. */
static void orthogonalize(double *F)
{
    for (int it = 0;; it++) {
        double G[9], H[9], d = gram_defect(F, G);
        if (d < 1e-6)
            return;
        if (it == 4 || !(d < 0.64))
            break;
        mul3(F, G, H);
        for (int q = 0; q < 9; q++)
            F[q] = 0.5 * H[q];
    }
    memcpy(F, identity3, sizeof identity3);
}

/* ===== the factor's frame ================================================ */

/* n: each vertex's area-weighted normal at x (unnormalised). */
static void vertex_normals(const iso_solver *s, const double *x, double *n)
{
    int nt = iso_mesh_triangle_count(s->m);
    const int *tri = iso_mesh_triangles(s->m);
    memset(n, 0, (size_t)s->nv * 3 * sizeof(double));
    for (int t = 0; t < nt; t++) {
        const int *v = tri + 3 * t;
        double e1[3], e2[3], c[3];
        for (int a = 0; a < 3; a++) {
            e1[a] = x[3 * v[1] + a] - x[3 * v[0] + a];
            e2[a] = x[3 * v[2] + a] - x[3 * v[0] + a];
        }
        cross(e1, e2, c);
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                n[3 * v[k] + a] += c[a];
    }
}

iso_solver__frame *iso_solver__frame_create(const iso_solver *s)
{
    iso_solver__frame *fr = calloc(1, sizeof *fr);
    if (!fr)
        return NULL;
    fr->s = s;
    fr->ne = iso_mesh_edge_count(s->m);
    size_t nv = (size_t)s->nv, nf = (size_t)s->nf, ne = (size_t)fr->ne;
    fr->x = malloc(3 * nv * sizeof(double));
    fr->f = malloc((3 * ne + 1) * sizeof(double));
    fr->m = malloc(3 * nv * sizeof(double));
    fr->pinv = malloc((9 * nf + 1) * sizeof(double));
    fr->p = malloc(9 * nv * sizeof(double));
    if (!fr->x || !fr->f || !fr->m || !fr->pinv || !fr->p) {
        iso_solver__frame_destroy(fr);
        return NULL;
    }
    return fr;
}

void iso_solver__frame_destroy(iso_solver__frame *fr)
{
    if (!fr)
        return;
    free(fr->x);
    free(fr->f);
    free(fr->m);
    free(fr->pinv);
    free(fr->p);
    free(fr);
}

double *iso_solver__frame_positions(iso_solver__frame *fr)
{
    return fr->x;
}

void iso_solver__frame_prepare(iso_solver__frame *fr)
{
    const iso_solver *s = fr->s;
    const int *ed = iso_mesh_edges(s->m);
    double *P = fr->p;
    memset(P, 0, (size_t)s->nv * 9 * sizeof(double));
    for (int k = 0; k < fr->ne; k++) {
        int a = ed[2 * k], b = ed[2 * k + 1];
        double *f = fr->f + 3 * k;
        for (int q = 0; q < 3; q++)
            f[q] = fr->x[3 * b + q] - fr->x[3 * a + q];
        add_outer(P + 9 * a, f, f);
        add_outer(P + 9 * b, f, f);
    }
    vertex_normals(s, fr->x, fr->m);
    for (int i = 0; i < s->nf; i++) {
        int v = s->vert_of[i];
        double *m = fr->m + 3 * v, *Pv = P + 9 * v, *Y = fr->pinv + 9 * i;
        /* |m|² = half the ring's trace: the normal weighs like one in-plane axis */
        double len = norm3(m), want = sqrt(0.5 * (Pv[0] + Pv[4] + Pv[8]));
        double k = len > 0 ? want / len : 0;
        for (int q = 0; q < 3; q++)
            m[q] *= k;
        add_outer(Pv, m, m);
        if (!inverse3(Pv, Y))
            memset(Y, 0, 9 * sizeof(double));
    }
}

/* ===== per evaluation ==================================================== */

void iso_solver__rotations(const iso_solver__frame *fr, const double *x, double *S, double *n,
                           double *R)
{
    const iso_solver *s = fr->s;
    const int *ed = iso_mesh_edges(s->m);
    memset(S, 0, (size_t)s->nv * 9 * sizeof(double));
    for (int k = 0; k < fr->ne; k++) {
        int a = ed[2 * k], b = ed[2 * k + 1];
        const double *f = fr->f + 3 * k;
        double e[3];
        for (int q = 0; q < 3; q++)
            e[q] = x[3 * b + q] - x[3 * a + q];
        add_outer(S + 9 * a, e, f);
        add_outer(S + 9 * b, e, f);
    }
    vertex_normals(s, x, n);
    for (int i = 0; i < s->nf; i++) {
        int v = s->vert_of[i];
        const double *m = fr->m + 3 * v, *Y = fr->pinv + 9 * i;
        double *Si = S + 9 * v, *ni = n + 3 * v, *Ri = R + 9 * i;
        if (Y[0] == 0) { /* P_i was singular (an SPD inverse has a positive diagonal) */
            memcpy(Ri, identity3, sizeof identity3);
            continue;
        }
        double len = norm3(ni), k = len > 0 ? norm3(m) / len : 0;
        for (int q = 0; q < 3; q++)
            ni[q] *= k;
        add_outer(Si, ni, m);
        mul3(Si, Y, Ri);
        orthogonalize(Ri);
    }
}

void iso_solver__rotate(const double *R, int nf, const double *in, double *out, int transpose)
{
    for (int i = 0; i < nf; i++) {
        const double *Ri = R + 9 * i, *u = in + 3 * i;
        double w[3];
        for (int a = 0; a < 3; a++)
            w[a] = transpose ? Ri[a] * u[0] + Ri[3 + a] * u[1] + Ri[6 + a] * u[2]
                             : Ri[3 * a] * u[0] + Ri[3 * a + 1] * u[1] + Ri[3 * a + 2] * u[2];
        memcpy(out + 3 * i, w, sizeof w);
    }
}
