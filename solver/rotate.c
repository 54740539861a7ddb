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

#include "iso_mesh_rings.h"
#include "mat3.h"
#include "solver_internal.h"

struct iso_solver__rings {
    int nf;
    const int *vert_of; /* the solver's */
    const int *tri;     /* the mesh's */
    iso_mesh_rings r;   /* each vertex's neighbours and corners (mesh/) */
};

struct iso_solver__frame {
    const iso_solver__rings *g;
    int nv;
    double *x;    /* 3 nv: the positions the factor's matrix was assembled at */
    double *f;    /* 3 per ring entry: x_j − x_i there */
    double *m;    /* 3 nf: the scaled vertex normals there */
    double *pinv; /* 9 nf: P_i⁻¹, or all zero where P_i is singular (R_i = I) */
};

/* ===== small 3×3 helpers (row-major) ==================================== */

static const double identity3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

static double norm3(const double *a)
{
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
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
        double G[9], H[9], d = iso_m3_gram_defect(F, G);
        if (d < 1e-6)
            return;
        if (it == 4 || !(d < 0.64))
            break;
        iso_m3_mul(F, G, H);
        for (int q = 0; q < 9; q++)
            F[q] = 0.5 * H[q];
    }
    memcpy(F, identity3, sizeof identity3);
}

/* ===== the rings (topology, made once) =================================== */

void iso_solver__rings_destroy(iso_solver__rings *g)
{
    if (!g)
        return;
    iso_mesh_rings_deinit(&g->r);
    free(g);
}

iso_solver__rings *iso_solver__rings_create(const iso_mesh *m, int nf, const int *vert_of)
{
    iso_solver__rings *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    g->nf = nf;
    g->vert_of = vert_of;
    g->tri = iso_mesh_triangles(m);
    if (iso_mesh_rings_init(&g->r, m, NULL) != ISO_OK) {
        free(g);
        return NULL;
    }
    return g;
}

/* The area-weighted normal of free vertex i's ring at x (unnormalised),
 * scaled to length want (0 where it vanishes). */
static void ring_normal(const iso_solver__rings *g, int i, const double *x, double want, double *n)
{
    int v = g->vert_of[i];
    const double *p = x + 3 * v;
    n[0] = n[1] = n[2] = 0;
    for (int q = g->r.corner_start[v]; q < g->r.corner_start[v + 1]; q++) {
        /* the corner's triangle's other two corners, in its winding order */
        int k = g->r.corner[q], t3 = k - k % 3;
        const double *a = x + 3 * g->tri[t3 + (k + 1) % 3], *b = x + 3 * g->tri[t3 + (k + 2) % 3];
        double u[3] = {a[0] - p[0], a[1] - p[1], a[2] - p[2]};
        double w[3] = {b[0] - p[0], b[1] - p[1], b[2] - p[2]}, c[3];
        iso_m3_cross(u, w, c);
        for (int q = 0; q < 3; q++)
            n[q] += c[q];
    }
    double len = norm3(n), k = len > 0 ? want / len : 0;
    for (int q = 0; q < 3; q++)
        n[q] *= k;
}

/* ===== the factor's frame ================================================ */

iso_solver__frame *iso_solver__frame_create(const iso_solver__rings *g, int nv)
{
    iso_solver__frame *fr = calloc(1, sizeof *fr);
    if (!fr)
        return NULL;
    fr->g = g;
    fr->nv = nv;
    size_t nf = (size_t)g->nf, n_nb = (size_t)g->r.nb_start[g->r.nv];
    fr->x = malloc(3 * (size_t)nv * sizeof(double));
    fr->f = malloc((3 * n_nb + 1) * sizeof(double));
    fr->m = malloc((3 * nf + 1) * sizeof(double));
    fr->pinv = malloc((9 * nf + 1) * sizeof(double));
    if (!fr->x || !fr->f || !fr->m || !fr->pinv) {
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
    free(fr);
}

double *iso_solver__frame_positions(iso_solver__frame *fr)
{
    return fr->x;
}

void iso_solver__frame_prepare(iso_solver__frame *fr)
{
    const iso_solver__rings *g = fr->g;
    const double *y = fr->x;
    for (int i = 0; i < g->nf; i++) {
        int v = g->vert_of[i];
        const double *p = y + 3 * v;
        double P[9] = {0}, *m = fr->m + 3 * i, *Y = fr->pinv + 9 * i;
        for (int k = g->r.nb_start[v]; k < g->r.nb_start[v + 1]; k++) {
            const double *q = y + 3 * g->r.nb[k];
            double *f = fr->f + 3 * k;
            for (int a = 0; a < 3; a++)
                f[a] = q[a] - p[a];
            iso_m3_add_outer(P, f, f);
        }
        /* |m|² = half the ring's trace: the normal weighs like one in-plane axis */
        ring_normal(g, i, y, sqrt(0.5 * (P[0] + P[4] + P[8])), m);
        iso_m3_add_outer(P, m, m);
        if (!iso_m3_inverse(P, Y))
            memset(Y, 0, 9 * sizeof(double));
    }
}

/* ===== per evaluation ==================================================== */

void iso_solver__rotations(const iso_solver__frame *fr, const double *x, double *R)
{
    const iso_solver__rings *g = fr->g;
    for (int i = 0; i < g->nf; i++) {
        const double *Y = fr->pinv + 9 * i, *m = fr->m + 3 * i;
        double *Ri = R + 9 * i;
        if (Y[0] == 0) { /* P_i was singular (an SPD inverse has a positive diagonal) */
            memcpy(Ri, identity3, sizeof identity3);
            continue;
        }
        int v = g->vert_of[i];
        const double *p = x + 3 * v;
        double S[9] = {0}, n[3];
        for (int k = g->r.nb_start[v]; k < g->r.nb_start[v + 1]; k++) {
            const double *q = x + 3 * g->r.nb[k];
            double e[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            iso_m3_add_outer(S, e, fr->f + 3 * k);
        }
        ring_normal(g, i, x, norm3(m), n);
        iso_m3_add_outer(S, n, m);
        iso_m3_mul(S, Y, Ri);
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
