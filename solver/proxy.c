/* solver/proxy.c -- the reduced model (iso_proxy.h): the proxy's mesh and
 * regions, where each full vertex sits on it, and the prolongation.
 *
 * Where a full vertex sits: over the proxy triangle nearest to it among
 * those around the proxy vertex it was collapsed into and that vertex's
 * neighbours (a local search, so that a thin part never takes a triangle
 * of the part across from it), at the closest point's barycentric weights.
 * A proxy vertex sits on one of its own triangles with weight 1.
 *
 * Each proxy vertex's rotation R_k since rest: the least-squares linear
 * map of its ring's edges and its normal (scaled to the ring's size, so
 * that a flat ring still fixes all three axes) from rest to now, F = S P⁻¹
 * (P⁻¹ depends on the rest pose alone and is kept), made orthogonal by
 * Newton–Schulz steps; where they do not converge (a ring crushed or
 * folded), by Horn's quaternion method on S, which is exact for any
 * turn. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_mesh_rings.h"
#include "mat3.h"
#include "proxy_internal.h"
#include "solver_internal.h"

struct iso_proxy {
    const iso_mesh *m;
    const iso_regions *r;
    int nv, np;
    iso_mesh *pm;   /* the proxy's mesh */
    iso_regions pr; /* and regions */
    int *full_of;   /* np */
    int *corner;    /* 3 nv: the proxy triangle's corners a full vertex sits on (−1: none) */
    double *beta;   /* 3 nv: its weights */
    iso_mesh_rings rings; /* each proxy vertex's neighbours and corners (mesh/) */
    double *pinv;         /* 9 np: P_k⁻¹ (zero: R_k = I) */
    double *m_rest;       /* 3 np: the scaled rest normals */
    double *n_now;        /* 3 np: scratch, the current normals */
    double *rot;          /* 9 np: this prolongation's rotations */
    double *quat;         /* 4 np: the same as quaternions */
    iso_solver__team *team;
    iso_proxy__fit *fit; /* the second stage (proxy_fit.c) */
    double *rot_full;    /* 9 nv: every full vertex's rotation, for the fit */
    const double *y_now; /* the prolongation's input, for the team */
    const iso_pose *poses_now;
    double *x_out;
    iso_proxy_stats st;
    int fit_off; /* white-box tests: the prolongation alone */
    char origin[160];
};

/* ===== rotations ========================================================= */

/* The rotation R that best turns the rest vectors onto the current ones
 * for M = Σ current ⊗ rest (maximises tr(Rᵀ M)): Horn's method, the
 * eigenvector of the largest eigenvalue of a symmetric 4×4 matrix, by
 * cyclic Jacobi rotations. Exact for any turn; the fallback. */
static void horn(const double *M, double *R)
{
    /* Horn's S is Σ rest ⊗ current = Mᵀ */
    double sxx = M[0], syx = M[1], szx = M[2], sxy = M[3], syy = M[4], szy = M[5], sxz = M[6],
           syz = M[7], szz = M[8];
    double N[4][4] = {{sxx + syy + szz, syz - szy, szx - sxz, sxy - syx},
                      {syz - szy, sxx - syy - szz, sxy + syx, szx + sxz},
                      {szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy},
                      {sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz}};
    double V[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    for (int sweep = 0; sweep < 30; sweep++) {
        double off = 0, diag = 0;
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++)
                *(i == j ? &diag : &off) += N[i][j] * N[i][j];
        if (!(off > 1e-30 * diag))
            break;
        for (int p = 0; p < 3; p++)
            for (int q = p + 1; q < 4; q++) {
                if (N[p][q] == 0)
                    continue;
                double theta = (N[q][q] - N[p][p]) / (2 * N[p][q]);
                double t = (theta >= 0 ? 1 : -1) / (fabs(theta) + sqrt(theta * theta + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 4; k++) { /* columns p, q */
                    double a = N[k][p], b = N[k][q];
                    N[k][p] = c * a - s * b;
                    N[k][q] = s * a + c * b;
                }
                for (int k = 0; k < 4; k++) { /* rows p, q */
                    double a = N[p][k], b = N[q][k];
                    N[p][k] = c * a - s * b;
                    N[q][k] = s * a + c * b;
                }
                for (int k = 0; k < 4; k++) {
                    double a = V[k][p], b = V[k][q];
                    V[k][p] = c * a - s * b;
                    V[k][q] = s * a + c * b;
                }
            }
    }
    int best = 0;
    for (int i = 1; i < 4; i++)
        if (N[i][i] > N[best][best])
            best = i;
    double w = V[0][best], x = V[1][best], y = V[2][best], z = V[3][best];
    double n = sqrt(w * w + x * x + y * y + z * z);
    w /= n, x /= n, y /= n, z /= n;
    double Rq[9] = {w * w + x * x - y * y - z * z, 2 * (x * y - w * z),
                    2 * (x * z + w * y),           2 * (x * y + w * z),
                    w * w - x * x + y * y - z * z, 2 * (y * z - w * x),
                    2 * (x * z - w * y),           2 * (y * z + w * x),
                    w * w - x * x - y * y + z * z};
    memcpy(R, Rq, sizeof Rq);
}

/* F made orthogonal by Newton–Schulz steps F ← F (3I − FᵀF) / 2 (they
 * converge while ‖FᵀF − I‖ < 0.8); 0 if not within 1e-12 in eight. */
static int newton_schulz(double *F)
{
    for (int it = 0; it < 8; it++) {
        double G[9], T[9], d = iso_m3_gram_defect(F, G);
        if (d < 1e-24)
            return 1;
        if (!(d < 0.64))
            return 0;
        iso_m3_mul(F, G, T);
        for (int q = 0; q < 9; q++)
            F[q] = 0.5 * T[q]; /* exact: the halving of the step's G */
    }
    return 0;
}

/* The current normal of each proxy vertex, area weighted, into p->n_now. */
static void normals_now(iso_proxy *p, const double *y)
{
    int nt = iso_mesh_triangle_count(p->pm);
    const int *tri = iso_mesh_triangles(p->pm);
    memset(p->n_now, 0, 3 * (size_t)p->np * sizeof *p->n_now);
    for (int t = 0; t < nt; t++) {
        const int *c = tri + 3 * t;
        double e1[3], e2[3], n[3];
        iso_m3_sub(y + 3 * c[1], y + 3 * c[0], e1);
        iso_m3_sub(y + 3 * c[2], y + 3 * c[0], e2);
        iso_m3_cross(e1, e2, n);
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                p->n_now[3 * c[k] + a] += n[a];
    }
}

/* Scales n to length s (left as is when zero). */
static void scale_to(double *n, double s)
{
    double l = sqrt(iso_m3_dot(n, n));
    if (l > 0)
        for (int a = 0; a < 3; a++)
            n[a] *= s / l;
}

/* S = Σ edges now ⊗ edges at rest + normal now ⊗ normal at rest, for ring k. */
static void ring_moment(const iso_proxy *p, int k, const double *y, const double *Y, double *S)
{
    memset(S, 0, 9 * sizeof *S);
    double len = 0;
    for (int q = p->rings.nb_start[k]; q < p->rings.nb_start[k + 1]; q++) {
        int j = p->rings.nb[q];
        double e[3], f[3];
        iso_m3_sub(y + 3 * j, y + 3 * k, e);
        iso_m3_sub(Y + 3 * j, Y + 3 * k, f);
        iso_m3_add_outer(S, e, f);
        len += sqrt(iso_m3_dot(f, f));
    }
    int deg = p->rings.nb_start[k + 1] - p->rings.nb_start[k];
    double n[3];
    memcpy(n, p->n_now + 3 * k, sizeof n);
    scale_to(n, deg > 0 ? len / deg : 0);
    iso_m3_add_outer(S, n, p->m_rest + 3 * k);
}

/* The unit quaternion (w, x, y, z) of rotation R (Shepperd's method: from
 * the largest of the four squares, so no division is by a small number). */
static void to_quaternion(const double *R, double *q)
{
    double t = R[0] + R[4] + R[8];
    if (t >= R[0] && t >= R[4] && t >= R[8]) {
        double r = sqrt(1 + t), s = 0.5 / r;
        q[0] = 0.5 * r, q[1] = (R[7] - R[5]) * s, q[2] = (R[2] - R[6]) * s,
        q[3] = (R[3] - R[1]) * s;
    } else if (R[0] >= R[4] && R[0] >= R[8]) {
        double r = sqrt(1 + R[0] - R[4] - R[8]), s = 0.5 / r;
        q[0] = (R[7] - R[5]) * s, q[1] = 0.5 * r, q[2] = (R[1] + R[3]) * s,
        q[3] = (R[2] + R[6]) * s;
    } else if (R[4] >= R[8]) {
        double r = sqrt(1 - R[0] + R[4] - R[8]), s = 0.5 / r;
        q[0] = (R[2] - R[6]) * s, q[1] = (R[1] + R[3]) * s, q[2] = 0.5 * r,
        q[3] = (R[5] + R[7]) * s;
    } else {
        double r = sqrt(1 - R[0] - R[4] + R[8]), s = 0.5 / r;
        q[0] = (R[3] - R[1]) * s, q[1] = (R[2] + R[6]) * s, q[2] = (R[5] + R[7]) * s,
        q[3] = 0.5 * r;
    }
}

static const double I3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

/* Proxy vertices [begin, end): each one's ring rotation since rest, and
 * its quaternion. Each vertex's alone, so the halves give one thread's
 * bits. */
static void rotations_range(iso_proxy *p, int begin, int end)
{
    const double *Y = iso_mesh_positions(p->pm), *y = p->y_now;
    for (int k = begin; k < end; k++) {
        double *R = p->rot + 9 * k;
        if (p->pr.kind[k] == ISO_FIXED) {
            memcpy(R, I3, sizeof I3);
        } else if (p->pr.kind[k] == ISO_HANDLE) {
            memcpy(R, p->poses_now[p->pr.handle[k]].R, 9 * sizeof *R);
        } else {
            double S[9];
            ring_moment(p, k, y, Y, S);
            const double *Pi = p->pinv + 9 * k;
            if (Pi[0] == 0 && Pi[4] == 0 && Pi[8] == 0)
                memcpy(R, I3, sizeof I3);
            else {
                iso_m3_mul(S, Pi, R);
                if (!newton_schulz(R))
                    horn(S, R);
            }
        }
        to_quaternion(R, p->quat + 4 * k);
    }
}

static void rotations_half(void *ctx, int half)
{
    iso_proxy *p = ctx;
    int b, e;
    iso_solver__team_half(p->np, half, &b, &e);
    rotations_range(p, b, e);
}

static void rotations(iso_proxy *p, const double *y, const iso_pose *poses)
{
    normals_now(p, y);
    p->y_now = y;
    p->poses_now = poses;
    iso_solver__team_run(p->team, rotations_half, p);
}

/* ===== prolongation ====================================================== */

/* Full vertices [begin, end): where their rest point on the proxy went
 * (barycentric on the deformed triangle), plus their offset from it
 * turned by the corners' rotations blended (quaternions weighted by β,
 * each turned to the hemisphere of the heaviest corner's, so that the
 * blend is continuous across proxy edges; normalised). */
static void prolong_range(iso_proxy *p, int begin, int end)
{
    const double *X = iso_mesh_positions(p->m), *Y = iso_mesh_positions(p->pm), *y = p->y_now;
    double *x = p->x_out;
    for (int i = begin; i < end; i++) {
        const int *c = p->corner + 3 * i;
        const double *b = p->beta + 3 * i, *Xi = X + 3 * i;
        double *xi = x + 3 * i;
        if (c[0] < 0) { /* in no triangle: stays */
            memcpy(xi, Xi, 3 * sizeof *xi);
            memcpy(p->rot_full + 9 * i, I3, sizeof I3);
            continue;
        }
        int ref = b[1] > b[0] ? 1 : 0;
        ref = b[2] > b[ref] ? 2 : ref;
        const double *qr = p->quat + 4 * c[ref];
        double pos[3] = {0, 0, 0}, off[3], q[4] = {0, 0, 0, 0};
        for (int a = 0; a < 3; a++)
            off[a] = Xi[a];
        for (int k = 0; k < 3; k++) {
            const double *Yk = Y + 3 * c[k], *yk = y + 3 * c[k], *qk = p->quat + 4 * c[k];
            double w =
                qk[0] * qr[0] + qk[1] * qr[1] + qk[2] * qr[2] + qk[3] * qr[3] < 0 ? -b[k] : b[k];
            for (int a = 0; a < 3; a++) {
                pos[a] += b[k] * yk[a];
                off[a] -= b[k] * Yk[a];
            }
            for (int a = 0; a < 4; a++)
                q[a] += w * qk[a];
        }
        double n = 1.0 / sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        double qw = q[0] * n, qx = q[1] * n, qy = q[2] * n, qz = q[3] * n;
        double *R = p->rot_full + 9 * i;
        R[0] = 1 - 2 * (qy * qy + qz * qz), R[1] = 2 * (qx * qy - qw * qz);
        R[2] = 2 * (qx * qz + qw * qy), R[3] = 2 * (qx * qy + qw * qz);
        R[4] = 1 - 2 * (qx * qx + qz * qz), R[5] = 2 * (qy * qz - qw * qx);
        R[6] = 2 * (qx * qz - qw * qy), R[7] = 2 * (qy * qz + qw * qx);
        R[8] = 1 - 2 * (qx * qx + qy * qy);
        for (int a = 0; a < 3; a++)
            xi[a] = pos[a] + R[3 * a] * off[0] + R[3 * a + 1] * off[1] + R[3 * a + 2] * off[2];
    }
}

static void prolong_half(void *ctx, int half)
{
    iso_proxy *p = ctx;
    int b, e;
    iso_solver__team_half(p->nv, half, &b, &e);
    prolong_range(p, b, e);
}

void iso_proxy_prolong(iso_proxy *p, const double *y, const iso_pose *poses, double *x)
{
    rotations(p, y, poses);
    p->x_out = x;
    iso_solver__team_run(p->team, prolong_half, p);
    const double *X = iso_mesh_positions(p->m);
    for (int i = 0; i < p->nv; i++) /* the constrained vertices exactly */
        if (p->r->kind[i] == ISO_HANDLE) {
            iso_pose_apply(&poses[p->r->handle[i]], X + 3 * i, x + 3 * i);
            memcpy(p->rot_full + 9 * i, poses[p->r->handle[i]].R, 9 * sizeof(double));
        } else if (p->r->kind[i] == ISO_FIXED) {
            memcpy(x + 3 * i, X + 3 * i, 3 * sizeof *x);
            memcpy(p->rot_full + 9 * i, I3, sizeof I3);
        }
    p->st.prolongations++;
    if (p->fit_off)
        return;
    if (iso_proxy__fit_run(p->fit, X, p->rot_full, x) != 0)
        p->st.fit_failures++;
    long it = iso_proxy__fit_iterations(p->fit);
    p->st.fit_iterations += it;
    if (it > p->st.fit_max_iterations)
        p->st.fit_max_iterations = it;
}

/* ===== set-up ============================================================ */

/* The closest point of triangle (a, b, c) to q as barycentric weights w;
 * returns the squared distance (Ericson, Real-Time Collision Detection,
 * 5.1.5). */
static double closest_on_triangle(const double *q, const double *a, const double *b,
                                  const double *c, double *w)
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    iso_m3_sub(b, a, ab), iso_m3_sub(c, a, ac), iso_m3_sub(q, a, ap);
    double d1 = iso_m3_dot(ab, ap), d2 = iso_m3_dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        w[0] = 1, w[1] = w[2] = 0;
    } else {
        iso_m3_sub(q, b, bp);
        double d3 = iso_m3_dot(ab, bp), d4 = iso_m3_dot(ac, bp);
        iso_m3_sub(q, c, cp);
        double d5 = iso_m3_dot(ab, cp), d6 = iso_m3_dot(ac, cp);
        double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0 && d4 <= d3) {
            w[1] = 1, w[0] = w[2] = 0;
        } else if (d6 >= 0 && d5 <= d6) {
            w[2] = 1, w[0] = w[1] = 0;
        } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
            double v = d1 / (d1 - d3);
            w[0] = 1 - v, w[1] = v, w[2] = 0;
        } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
            double v = d2 / (d2 - d6);
            w[0] = 1 - v, w[2] = v, w[1] = 0;
        } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
            double v = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            w[1] = 1 - v, w[2] = v, w[0] = 0;
        } else {
            double den = 1 / (va + vb + vc), v = vb * den, u = vc * den;
            w[0] = 1 - v - u, w[1] = v, w[2] = u;
        }
    }
    double s = 0;
    for (int k = 0; k < 3; k++) {
        double d = q[k] - (w[0] * a[k] + w[1] * b[k] + w[2] * c[k]);
        s += d * d;
    }
    return s;
}

/* Full vertex i onto the nearest proxy triangle around proxy vertex k (k's
 * own and its neighbours'); a proxy vertex (self) onto its first triangle,
 * with weight 1 at itself. */
static void place(iso_proxy *p, int i, int k, int self)
{
    const double *X = iso_mesh_positions(p->m), *Y = iso_mesh_positions(p->pm);
    const int *tri = iso_mesh_triangles(p->pm);
    if (self) {
        const int *c = tri + 3 * (p->rings.corner[p->rings.corner_start[k]] / 3);
        for (int a = 0; a < 3; a++) {
            p->corner[3 * i + a] = c[a];
            p->beta[3 * i + a] = c[a] == k;
        }
        return;
    }
    double best = HUGE_VAL;
    for (int q = p->rings.nb_start[k] - 1; q < p->rings.nb_start[k + 1]; q++) {
        int v = q < p->rings.nb_start[k] ? k : p->rings.nb[q];
        for (int s = p->rings.corner_start[v]; s < p->rings.corner_start[v + 1]; s++) {
            const int *c = tri + 3 * (p->rings.corner[s] / 3);
            double w[3];
            double d2 = closest_on_triangle(X + 3 * i, Y + 3 * c[0], Y + 3 * c[1], Y + 3 * c[2], w);
            if (d2 < best) {
                best = d2;
                memcpy(p->corner + 3 * i, c, 3 * sizeof *c);
                memcpy(p->beta + 3 * i, w, sizeof w);
            }
        }
    }
}

/* P_k⁻¹ and the scaled rest normal of each proxy vertex. */
static void rest_frames(iso_proxy *p)
{
    const double *Y = iso_mesh_positions(p->pm);
    normals_now(p, Y);
    for (int k = 0; k < p->np; k++) {
        double P[9] = {0}, len = 0;
        for (int q = p->rings.nb_start[k]; q < p->rings.nb_start[k + 1]; q++) {
            double f[3];
            iso_m3_sub(Y + 3 * p->rings.nb[q], Y + 3 * k, f);
            iso_m3_add_outer(P, f, f);
            len += sqrt(iso_m3_dot(f, f));
        }
        int deg = p->rings.nb_start[k + 1] - p->rings.nb_start[k];
        double *m = p->m_rest + 3 * k;
        memcpy(m, p->n_now + 3 * k, 3 * sizeof *m);
        scale_to(m, deg > 0 ? len / deg : 0);
        iso_m3_add_outer(P, m, m);
        if (!iso_m3_inverse(P, p->pinv + 9 * k))
            memset(p->pinv + 9 * k, 0, 9 * sizeof(double));
    }
}

static int build(iso_proxy *p, const iso_proxy__decimated *d, iso_err *err)
{
    const double *X = iso_mesh_positions(p->m);
    double *Y = malloc((3 * (size_t)d->np + 1) * sizeof *Y);
    if (!Y)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the proxy");
    for (int k = 0; k < d->np; k++)
        memcpy(Y + 3 * k, X + 3 * d->full_of[k], 3 * sizeof *Y);
    snprintf(p->origin, sizeof p->origin, "proxy of %s", iso_mesh_origin(p->m));
    int rc = iso_mesh_create(d->np, Y, d->nt, d->tri, p->origin, &p->pm, err);
    free(Y);
    if (rc == ISO_OK)
        rc = iso_regions_init(&p->pr, d->np, err);
    if (rc != ISO_OK)
        return rc;
    for (int k = 0; k < d->np; k++) {
        int i = d->full_of[k];
        p->pr.kind[k] = p->r->kind[i];
        p->pr.handle[k] = p->r->handle[i];
    }
    p->pr.n_handles = p->r->n_handles;
    size_t nv = (size_t)p->nv + 1, np = (size_t)d->np + 1;
    p->corner = malloc(3 * nv * sizeof *p->corner);
    p->beta = calloc(3 * nv, sizeof *p->beta);
    p->pinv = malloc(9 * np * sizeof *p->pinv);
    p->m_rest = malloc(3 * np * sizeof *p->m_rest);
    p->n_now = malloc(3 * np * sizeof *p->n_now);
    p->rot = malloc(9 * np * sizeof *p->rot);
    p->quat = malloc(4 * np * sizeof *p->quat);
    p->full_of = malloc(np * sizeof *p->full_of);
    if (!p->corner || !p->beta || !p->pinv || !p->m_rest || !p->n_now || !p->rot || !p->quat ||
        !p->full_of || iso_mesh_rings_init(&p->rings, p->pm, NULL) != ISO_OK)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the proxy's map");
    memcpy(p->full_of, d->full_of, (size_t)d->np * sizeof *p->full_of);
    for (int i = 0; i < p->nv; i++) {
        p->corner[3 * i] = p->corner[3 * i + 1] = p->corner[3 * i + 2] = -1;
        if (d->rep[i] >= 0)
            place(p, i, d->rep[i], d->proxy_of[i] >= 0);
    }
    rest_frames(p);
    return ISO_OK;
}

/* The fit holds what the prolongation places exactly (handles, fixed and
 * unreferenced vertices, and any vertex over no proxy triangle), and
 * interpolates its correction from the proxy's free vertices. */
static int start_fit(iso_proxy *p, iso_err *err)
{
    unsigned char *held = malloc((size_t)p->nv + 1), *pfree = malloc((size_t)p->np + 1);
    p->rot_full = malloc((9 * (size_t)p->nv + 1) * sizeof *p->rot_full);
    if (held && pfree && p->rot_full) {
        for (int i = 0; i < p->nv; i++)
            held[i] = p->r->kind[i] != ISO_FREE || p->corner[3 * i] < 0;
        for (int k = 0; k < p->np; k++)
            pfree[k] = p->pr.kind[k] == ISO_FREE;
        p->fit = iso_proxy__fit_create(p->m, held, p->np, pfree, p->corner, p->beta, p->team);
    }
    free(held);
    free(pfree);
    if (!p->fit)
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "out of memory for the proxy's fit (or its Galerkin matrix is not "
                           "positive definite)");
    return ISO_OK;
}

int iso_proxy_create(const iso_mesh *m, const iso_regions *r, int budget, iso_proxy **out,
                     iso_err *err)
{
    *out = NULL;
    int nv = iso_mesh_vertex_count(m);
    if (budget < ISO_PROXY_MIN_BUDGET)
        return iso_err_set(err, ISO_EINVAL, -1, "a proxy of %d vertices is below the least, %d",
                           budget, ISO_PROXY_MIN_BUDGET);
    if (nv - iso_mesh_unreferenced_count(m) <= budget)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s has %d vertices, no more than the proxy's budget of %d: the "
                           "method runs on it in full",
                           iso_mesh_origin(m), nv, budget);
    if (r->nv != nv)
        return iso_err_set(err, ISO_EINVAL, -1, "the regions cover %d vertices but %s has %d",
                           r->nv, iso_mesh_origin(m), nv);
    iso_proxy *p = calloc(1, sizeof *p);
    if (!p)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the proxy");
    p->m = m;
    p->r = r;
    p->nv = nv;
    iso_proxy__decimated d;
    int rc = iso_proxy__decimate(m, r, budget, &d, err);
    if (rc == ISO_OK) {
        p->np = d.np;
        rc = build(p, &d, err);
    }
    iso_proxy__decimated_free(&d);
    if (rc == ISO_OK && nv >= ISO_SOLVER_CPU_SPLIT_EDGES / 3)
        p->team = iso_solver__team_create(); /* NULL: the prolongation on one thread */
    if (rc == ISO_OK)
        rc = start_fit(p, err);
    if (rc != ISO_OK) {
        iso_proxy_destroy(p);
        return rc;
    }
    *out = p;
    return ISO_OK;
}

void iso_proxy_destroy(iso_proxy *p)
{
    if (!p)
        return;
    iso_proxy__fit_destroy(p->fit);
    free(p->rot_full);
    iso_solver__team_destroy(p->team);
    iso_mesh_destroy(p->pm);
    iso_regions_deinit(&p->pr);
    free(p->full_of);
    free(p->corner);
    free(p->beta);
    iso_mesh_rings_deinit(&p->rings);
    free(p->pinv);
    free(p->m_rest);
    free(p->n_now);
    free(p->rot);
    free(p->quat);
    free(p);
}

void iso_proxy__set_fit(iso_proxy *p, int on)
{
    p->fit_off = !on;
}

void iso_proxy__one_thread(iso_proxy *p)
{
    iso_proxy__fit_set_team(p->fit, NULL);
    iso_solver__team_destroy(p->team);
    p->team = NULL;
}

void iso_proxy_get_stats(const iso_proxy *p, iso_proxy_stats *out)
{
    *out = p->st;
}

const iso_mesh *iso_proxy_mesh(const iso_proxy *p)
{
    return p->pm;
}

const iso_regions *iso_proxy_regions(const iso_proxy *p)
{
    return &p->pr;
}

int iso_proxy_full_vertex(const iso_proxy *p, int k)
{
    return k >= 0 && k < p->np ? p->full_of[k] : -1;
}

/* What `auto` chooses: the method on the whole mesh up to AUTO_FULL
 * vertices at 60 Hz, else a proxy of AUTO_BUDGET; at a slower tick both in
 * proportion to the period, at a faster one the 60 Hz figures (a tick that
 * takes longer than its period is caught up by the loop, and a smaller
 * proxy would lose more than it gains). Measured on two cores
 * (iso_proxy.h). */
#define AUTO_FULL 8000.0
#define AUTO_BUDGET 4000.0

double iso_proxy_omega(const iso_proxy *p, double omega)
{
    int nv = iso_mesh_vertex_count(p->m) - iso_mesh_unreferenced_count(p->m);
    int np = iso_mesh_vertex_count(iso_proxy_mesh(p));
    if (!(omega > 0 && omega < 1) || nv <= 0 || np >= nv)
        return omega;
    double r = omega / (1 - omega) * np / nv;
    return r / (1 + r);
}

void iso_proxy_solver_opts(const iso_proxy *p, iso_solver_opts *so)
{
    if (so->proxy_smoothness == ISO_PROXY_SMOOTHNESS_MATCHED)
        so->omega = iso_proxy_omega(p, so->omega);
    so->threads.split = ISO_SOLVER_SPLIT_ALWAYS;
}

int iso_proxy_auto_budget(int nv, double tick_hz)
{
    double scale = tick_hz > 0 && tick_hz < 60.0 ? 60.0 / tick_hz : 1.0;
    if (nv <= AUTO_FULL * scale)
        return 0;
    double b = AUTO_BUDGET * scale;
    return b > 1e8 ? 100000000 : (int)b;
}

int iso_proxy_choose(const iso_mesh *m, int proxy, double tick_hz, char *why, size_t cap)
{
    int nv = iso_mesh_vertex_count(m), used = nv - iso_mesh_unreferenced_count(m);
    int budget = proxy == ISO_SOLVER_PROXY_AUTO ? iso_proxy_auto_budget(nv, tick_hz) : proxy;
    if (proxy == 0) {
        snprintf(why, cap, "the whole mesh of %d vertices (solver.proxy: off)", used);
        return 0;
    }
    if (proxy == ISO_SOLVER_PROXY_AUTO && (budget <= 0 || used <= budget)) {
        snprintf(why, cap,
                 "the whole mesh of %d vertices (solver.proxy: auto; it fits a %g Hz tick)", used,
                 tick_hz);
        return 0;
    }
    if (used <= budget) {
        snprintf(why, cap,
                 "the whole mesh of %d vertices (solver.proxy: %d is not below the mesh's size)",
                 used, proxy);
        return 0;
    }
    if (proxy == ISO_SOLVER_PROXY_AUTO)
        snprintf(why, cap,
                 "a proxy of at most %d vertices that the whole mesh of %d follows (solver.proxy: "
                 "auto; the whole mesh does not fit a %g Hz tick: solver.proxy: off runs it whole)",
                 budget, used, tick_hz);
    else
        snprintf(why, cap, "a proxy of at most %d vertices that the whole mesh of %d follows",
                 budget, used);
    return budget;
}
