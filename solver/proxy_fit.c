/* solver/proxy_fit.c -- the reduced model's second stage: the full mesh
 * fitted to the rotations the prolongation carries (proxy_internal.h).
 *
 * The prolongation puts each full vertex where its proxy triangle takes
 * it, so full triangles that straddle a proxy edge see the kink between
 * two flat pieces, and those inside a proxy triangle take its stretch
 * whole. The fit keeps the prolongation's rotations R_i (the corners' ring
 * rotations blended) and asks the positions for nothing else: over the
 * full mesh's edges,
 *     min_x  Σ_(i,j) | x_i − x_j − ½ (R_i + R_j) (X_i − X_j) |²
 *            + λ Σ_i | x_i − x⁰_i |²
 * with x⁰ the prolongation, λ the anchor below, and handle, fixed and
 * unreferenced vertices held where the prolongation put them (exactly).
 * The edge weights are one, as in metricErr's sum. A rigid motion (every R
 * the same, the held vertices moved by it) is reproduced exactly, and so
 * is the rest pose.
 *
 * The normal equations are the graph Laplacian of the free vertices plus
 * λ I, constant from rest on: L x = b. They are solved by conjugate gradients
 * from the prolongation, preconditioned by a two-level method: Jacobi on
 * the full mesh plus the correction on the proxy (the prolongation's
 * barycentric weights as the interpolation P, the Galerkin product PᵀLP
 * factored once by CHOLMOD), so the iterations needed do not grow with
 * how much finer the mesh is than its proxy. It takes a fixed number of
 * iterations (below); everything is a function of the inputs, summed in a
 * fixed order (two halves, half 0 first), so the bits are the same on one
 * thread or two. */
#include <stdlib.h>
#include <string.h>

#include "proxy_internal.h"
#include "solver_internal.h"

/* The fit's conjugate-gradient iterations, a fixed number (a tick's cost
 * known in advance). From the prolongation, one takes most of the way: on
 * the 40k bumpplane and the 160k tentacle under their screw motions,
 * metricErr 3.665 and 0.8167 after one, 3.616 and 0.8025 after two, 3.611
 * and 0.8021 converged (the prolongation alone: 4.107 and 0.9461); the
 * largest edge strain 6.9% and 42% after one, 6.0% and 27-33% after two or
 * more (alone: 12% and 97%). The second iteration cost 2-5 ms a tick on
 * two cores (a direction, a step and a coarse solve), a third of what the
 * whole 40k tick may take at 60 Hz, for 1.3% in metricErr. */
#define FIT_ITERATIONS 1

/* Each free vertex is also drawn to where the prolongation put it, with a
 * weight of FIT_ANCHOR np / nv against one edge's (np proxy vertices, nv
 * full ones): about one over the number of full vertices between two proxy
 * vertices, squared. So the fit corrects what lies below the proxy's edge
 * length (the kinks, the stretch a proxy triangle passes to all it covers)
 * and keeps the proxy's own motion above it, which is the method's; and the
 * system is definite where nothing is held. Measured on an exact bend of
 * the bumpplane (test_proxy): at 3 the fit lands closer to the bend than
 * the prolongation alone at both proxy sizes tested, at 1 it does not. */
#define FIT_ANCHOR 3.0

struct iso_proxy__fit {
    int nv, nf;        /* full vertices, free ones */
    double anchor;     /* the pull to the prolongation, against one edge */
    int *free_of;      /* nf: the full vertex of each free one */
    int *start, *nb;   /* CSR over free vertices: every neighbour, as a full index */
    int *fstart, *fnb; /* CSR over free vertices: free neighbours, as free indices */
    double *inv_deg;   /* nf: 1 / (degree + FIT_ANCHOR), L's diagonal (all neighbours count) */
    double *umb;       /* 3 nf: deg X_i − Σ_j X_j at rest */
    int *pc;           /* 3 nf: coarse unknowns of each free vertex's corners (−1: none) */
    double *pw;        /* 3 nf: their weights */
    int nc;            /* coarse unknowns: the free proxy vertices that carry weight */
    cholmod_common c;
    int c_started;
    cholmod_factor *Lc;
    cholmod_dense *Bc, *Xc, *Yc, *Ec; /* nc × 3 right-hand side, solution, workspace */
    int *lp_start, *lp_col;           /* nf + 1, and CSR: the rows of L P */
    double *lp_val;
    double *acc;            /* 2 × 3 nc: each half's share of Pᵀ r */
    double *r, *zj, *d, *q; /* 3 nf each: CG's vectors, D⁻¹ r */
    iso_solver__team *team;
    /* per run */
    const double *R; /* 9 nv: every full vertex's rotation */
    double *x;       /* 3 nv: positions, in and out */
    const double *X;
    double alpha[3], beta[3];
    double part[2][6]; /* per half: two sums of three components */
    int phase, first, iterations;
};

/* ===== set-up ============================================================ */

/* The free vertices (those not held and on an edge) and both neighbour
 * lists. */
static int build_graph(iso_proxy__fit *f, const iso_mesh *m, const unsigned char *held)
{
    int nv = f->nv, ne = iso_mesh_edge_count(m);
    const int *ed = iso_mesh_edges(m);
    int *deg = calloc((size_t)nv + 1, sizeof *deg), *fidx = malloc(((size_t)nv + 1) * sizeof *fidx);
    if (!deg || !fidx) {
        free(deg);
        free(fidx);
        return -1;
    }
    for (int e = 0; e < ne; e++)
        deg[ed[2 * e]]++, deg[ed[2 * e + 1]]++;
    f->nf = 0;
    for (int i = 0; i < nv; i++)
        fidx[i] = held[i] || deg[i] == 0 ? -1 : f->nf++;
    size_t nf = (size_t)f->nf + 1;
    f->free_of = malloc(nf * sizeof *f->free_of);
    f->start = calloc(nf + 1, sizeof *f->start);
    f->fstart = calloc(nf + 1, sizeof *f->fstart);
    if (!f->free_of || !f->start || !f->fstart) {
        free(deg);
        free(fidx);
        return -1;
    }
    for (int i = 0; i < nv; i++)
        if (fidx[i] >= 0)
            f->free_of[fidx[i]] = i;
    for (int e = 0; e < ne; e++)
        for (int s = 0; s < 2; s++) {
            int a = fidx[ed[2 * e + s]], b = fidx[ed[2 * e + 1 - s]];
            if (a < 0)
                continue;
            f->start[a + 1]++;
            if (b >= 0)
                f->fstart[a + 1]++;
        }
    for (int k = 0; k < f->nf; k++) {
        f->start[k + 1] += f->start[k];
        f->fstart[k + 1] += f->fstart[k];
    }
    f->nb = malloc(((size_t)f->start[f->nf] + 1) * sizeof *f->nb);
    f->fnb = malloc(((size_t)f->fstart[f->nf] + 1) * sizeof *f->fnb);
    int *na = malloc(nf * sizeof *na), *nfree = malloc(nf * sizeof *nfree);
    int ok = f->nb && f->fnb && na && nfree;
    if (ok) {
        memcpy(na, f->start, (size_t)f->nf * sizeof *na);
        memcpy(nfree, f->fstart, (size_t)f->nf * sizeof *nfree);
        for (int e = 0; e < ne; e++) /* edges are sorted: each list ascends */
            for (int s = 0; s < 2; s++) {
                int i = ed[2 * e + s], j = ed[2 * e + 1 - s], a = fidx[i];
                if (a < 0)
                    continue;
                f->nb[na[a]++] = j;
                if (fidx[j] >= 0)
                    f->fnb[nfree[a]++] = fidx[j];
            }
    }
    free(na);
    free(nfree);
    free(deg);
    free(fidx);
    return ok ? 0 : -1;
}

static void rest_terms(iso_proxy__fit *f, const double *X)
{
    for (int k = 0; k < f->nf; k++) {
        int i = f->free_of[k], deg = f->start[k + 1] - f->start[k];
        double *u = f->umb + 3 * k;
        for (int a = 0; a < 3; a++)
            u[a] = deg * X[3 * i + a];
        for (int q = f->start[k]; q < f->start[k + 1]; q++)
            for (int a = 0; a < 3; a++)
                u[a] -= X[3 * f->nb[q] + a];
        f->inv_deg[k] = 1.0 / (deg + f->anchor);
    }
}

/* The interpolation from the proxy: each free vertex's corners that are
 * free proxy vertices, numbered as coarse unknowns in proxy order. */
static int coarse_map(iso_proxy__fit *f, int np, const unsigned char *proxy_free, const int *corner,
                      const double *beta)
{
    int *cidx = malloc(((size_t)np + 1) * sizeof *cidx);
    if (!cidx)
        return -1;
    for (int k = 0; k < np; k++)
        cidx[k] = -1;
    for (int k = 0; k < f->nf; k++)
        for (int a = 0; a < 3; a++) {
            int c = corner[3 * f->free_of[k] + a];
            if (c >= 0 && proxy_free[c] && beta[3 * f->free_of[k] + a] != 0)
                cidx[c] = 0;
        }
    f->nc = 0;
    for (int k = 0; k < np; k++)
        if (cidx[k] == 0)
            cidx[k] = f->nc++;
    for (int k = 0; k < f->nf; k++)
        for (int a = 0; a < 3; a++) {
            int i = f->free_of[k], c = corner[3 * i + a];
            int u = c >= 0 && proxy_free[c] && beta[3 * i + a] != 0 ? cidx[c] : -1;
            f->pc[3 * k + a] = u;
            f->pw[3 * k + a] = u >= 0 ? beta[3 * i + a] : 0;
        }
    free(cidx);
    return 0;
}

/* The rows of L P, so that L z = L D⁻¹ r + (L P) e needs no pass of its
 * own: row k is deg_k P_k − Σ_free j P_j, its coarse unknowns merged (a
 * row has at most 3 (1 + degree) of them, usually four to six). */
static int lp_rows(iso_proxy__fit *f)
{
    size_t cap = 0;
    for (int k = 0; k < f->nf; k++)
        cap += 3 * (size_t)(1 + f->fstart[k + 1] - f->fstart[k]);
    f->lp_start = malloc(((size_t)f->nf + 1) * sizeof *f->lp_start);
    f->lp_col = malloc((cap + 1) * sizeof *f->lp_col);
    f->lp_val = malloc((cap + 1) * sizeof *f->lp_val);
    if (!f->lp_start || !f->lp_col || !f->lp_val)
        return -1;
    int n = 0;
    for (int k = 0; k < f->nf; k++) {
        f->lp_start[k] = n;
        double deg = 1.0 / f->inv_deg[k];
        for (int q = f->fstart[k] - 1; q < f->fstart[k + 1]; q++) {
            int j = q < f->fstart[k] ? k : f->fnb[q];
            double w = q < f->fstart[k] ? deg : -1.0;
            for (int b = 0; b < 3; b++) {
                int v = f->pc[3 * j + b], at = f->lp_start[k];
                if (v < 0)
                    continue;
                while (at < n && f->lp_col[at] != v)
                    at++;
                if (at == n)
                    f->lp_col[n] = v, f->lp_val[n++] = 0;
                f->lp_val[at] += w * f->pw[3 * j + b];
            }
        }
    }
    f->lp_start[f->nf] = n;
    return 0;
}

/* The Galerkin product PᵀLP = Σ_k P_kᵀ (LP)_k from the rows of LP, its
 * upper triangle as a triplet list that CHOLMOD sums (about nine entries
 * per free vertex), then factored (simplicial: a small matrix, no BLAS and
 * no OpenMP). */
static int coarse_factor(iso_proxy__fit *f)
{
    size_t cap = 0;
    for (int k = 0; k < f->nf; k++)
        cap += 3 * (size_t)(f->lp_start[k + 1] - f->lp_start[k]);
    cholmod_triplet *T =
        cholmod_allocate_triplet((size_t)f->nc, (size_t)f->nc, cap, 1, CHOLMOD_REAL, &f->c);
    if (!T)
        return -1;
    int *ti = T->i, *tj = T->j;
    double *tx = T->x;
    size_t n = 0;
    for (int k = 0; k < f->nf; k++)
        for (int a = 0; a < 3; a++) {
            int u = f->pc[3 * k + a];
            if (u < 0)
                continue;
            for (int q = f->lp_start[k]; q < f->lp_start[k + 1]; q++) {
                int v = f->lp_col[q];
                if (v < u) /* the upper triangle (stype 1): the lower one mirrors it */
                    continue;
                ti[n] = u, tj[n] = v, tx[n] = f->pw[3 * k + a] * f->lp_val[q];
                n++;
            }
        }
    T->nnz = n;
    cholmod_sparse *A = cholmod_triplet_to_sparse(T, n, &f->c);
    cholmod_free_triplet(&T, &f->c);
    if (!A)
        return -1;
    f->c.supernodal = CHOLMOD_SIMPLICIAL;
    f->Lc = iso_solver__analyze(A, NULL, &f->c);
    int ok = f->Lc && cholmod_factorize(A, f->Lc, &f->c) && f->c.status == CHOLMOD_OK;
    cholmod_free_sparse(&A, &f->c);
    return ok ? 0 : -1;
}

iso_proxy__fit *iso_proxy__fit_create(const iso_mesh *m, const unsigned char *held, int np,
                                      const unsigned char *proxy_free, const int *corner,
                                      const double *beta, iso_solver__team *team)
{
    iso_proxy__fit *f = calloc(1, sizeof *f);
    if (!f)
        return NULL;
    f->nv = iso_mesh_vertex_count(m);
    f->anchor = FIT_ANCHOR * np / f->nv;
    f->team = team;
    cholmod_start(&f->c);
    f->c_started = 1;
    f->c.print = 0;
    f->c.error_handler = NULL;
    if (build_graph(f, m, held) != 0)
        goto fail;
    size_t nf3 = 3 * (size_t)f->nf + 1;
    f->inv_deg = malloc(nf3 / 3 * sizeof(double) + sizeof(double));
    f->umb = malloc(nf3 * sizeof *f->umb);
    f->pc = malloc(nf3 * sizeof *f->pc);
    f->pw = malloc(nf3 * sizeof *f->pw);
    double **vec[] = {&f->r, &f->zj, &f->d, &f->q};
    for (size_t v = 0; v < sizeof vec / sizeof vec[0]; v++)
        if (!(*vec[v] = malloc(nf3 * sizeof(double))))
            goto fail;
    if (!f->inv_deg || !f->umb || !f->pc || !f->pw)
        goto fail;
    rest_terms(f, iso_mesh_positions(m));
    if (coarse_map(f, np, proxy_free, corner, beta) != 0)
        goto fail;
    if (f->nc > 0) {
        if (lp_rows(f) != 0 || coarse_factor(f) != 0)
            goto fail;
        f->Bc = cholmod_zeros((size_t)f->nc, 3, CHOLMOD_REAL, &f->c);
        f->acc = malloc(6 * (size_t)f->nc * sizeof *f->acc);
        if (!f->Bc || !f->acc)
            goto fail;
    }
    return f;
fail:
    iso_proxy__fit_destroy(f);
    return NULL;
}

void iso_proxy__fit_destroy(iso_proxy__fit *f)
{
    if (!f)
        return;
    if (f->c_started) {
        cholmod_free_factor(&f->Lc, &f->c);
        cholmod_free_dense(&f->Bc, &f->c);
        cholmod_free_dense(&f->Xc, &f->c);
        cholmod_free_dense(&f->Yc, &f->c);
        cholmod_free_dense(&f->Ec, &f->c);
        cholmod_finish(&f->c);
    }
    free(f->free_of);
    free(f->start);
    free(f->nb);
    free(f->fstart);
    free(f->fnb);
    free(f->inv_deg);
    free(f->umb);
    free(f->pc);
    free(f->pw);
    free(f->acc);
    free(f->lp_start);
    free(f->lp_col);
    free(f->lp_val);
    free(f->r);
    free(f->zj);
    free(f->d);
    free(f->q);
    free(f);
}

/* ===== one fit =========================================================== */

/* The start's residual at free vertex k, b − (L + λ I) x⁰ with x⁰ the
 * prolongation: ½ R_k u_k + Σ_j (½ R_j (X_k − X_j) − (x⁰_k − x⁰_j)) over
 * every neighbour j (a held neighbour's entry of L is b's, moved over, and
 * the anchor's pull is zero at x⁰). */
static void residual_at(const iso_proxy__fit *f, int k, double *r)
{
    /* Sums in scalars, not through a 3-vector written by a helper: the
     * compiler kept such a vector on the stack and read it back in one
     * wider load than its three stores, which stalls store forwarding on
     * every neighbour (26% of the fit's samples on the 40k plane). The
     * arithmetic and its order are iso_m3_mul_vec's, so the bits are too. */
    int i = f->free_of[k];
    const double *Xi = f->X + 3 * i, *xi = f->x + 3 * i, *Ri = f->R + 9 * i, *u = f->umb + 3 * k;
    double s0 = Ri[0] * u[0] + Ri[1] * u[1] + Ri[2] * u[2];
    double s1 = Ri[3] * u[0] + Ri[4] * u[1] + Ri[5] * u[2];
    double s2 = Ri[6] * u[0] + Ri[7] * u[1] + Ri[8] * u[2];
    double d0 = 0, d1 = 0, d2 = 0;
    for (int q = f->start[k]; q < f->start[k + 1]; q++) {
        int j = f->nb[q];
        const double *Xj = f->X + 3 * j, *xj = f->x + 3 * j, *Rj = f->R + 9 * j;
        double e0 = Xi[0] - Xj[0], e1 = Xi[1] - Xj[1], e2 = Xi[2] - Xj[2];
        s0 += Rj[0] * e0 + Rj[1] * e1 + Rj[2] * e2;
        s1 += Rj[3] * e0 + Rj[4] * e1 + Rj[5] * e2;
        s2 += Rj[6] * e0 + Rj[7] * e1 + Rj[8] * e2;
        d0 += xi[0] - xj[0], d1 += xi[1] - xj[1], d2 += xi[2] - xj[2];
    }
    r[0] = 0.5 * s0 - d0;
    r[1] = 0.5 * s1 - d1;
    r[2] = 0.5 * s2 - d2;
}

/* Σ_free j v_j over k's free neighbours. */
static inline void neighbour_sum(const iso_proxy__fit *f, const double *v, int k, double *s)
{
    double s0 = 0, s1 = 0, s2 = 0;
    for (int q = f->fstart[k]; q < f->fstart[k + 1]; q++) {
        const double *vj = v + 3 * f->fnb[q];
        s0 += vj[0], s1 += vj[1], s2 += vj[2];
    }
    s[0] = s0, s[1] = s1, s[2] = s2;
}

/* After r changed at k: D⁻¹ r into zj, this half's Pᵀ r into acc, and the
 * sums r·r and r·D⁻¹r. */
static inline void after_residual(iso_proxy__fit *f, int k, double *acc, double *sum)
{
    const double *r = f->r + 3 * k;
    double *zj = f->zj + 3 * k, w = f->inv_deg[k];
    for (int c = 0; c < 3; c++) {
        zj[c] = w * r[c];
        sum[c] += r[c] * r[c];
        sum[3 + c] += r[c] * zj[c];
    }
    if (!acc)
        return;
    for (int a = 0; a < 3; a++) {
        int u = f->pc[3 * k + a];
        if (u < 0)
            continue;
        double pw = f->pw[3 * k + a];
        acc[3 * u] += pw * r[0];
        acc[3 * u + 1] += pw * r[1];
        acc[3 * u + 2] += pw * r[2];
    }
}

enum { PH_RESIDUAL, PH_DIRECTION, PH_STEP, PH_LAST_STEP };

/* The new direction at k: z = D⁻¹ r + P e, d = z + β d and q = L d =
 * L D⁻¹ r + (L P) e + β q. Returns d·q's three terms in dq. */
static inline void direction_at(iso_proxy__fit *f, int k, const double *e, double *dq)
{
    double s[3], z[3], lz[3];
    const double *zj = f->zj + 3 * k;
    double deg = 1.0 / f->inv_deg[k];
    neighbour_sum(f, f->zj, k, s);
    for (int c = 0; c < 3; c++) {
        z[c] = zj[c];
        lz[c] = deg * zj[c] - s[c];
    }
    if (e) {
        size_t nc = (size_t)f->nc;
        for (int a = 0; a < 3; a++) {
            int u = f->pc[3 * k + a];
            if (u < 0)
                continue;
            double w = f->pw[3 * k + a];
            z[0] += w * e[u], z[1] += w * e[u + nc], z[2] += w * e[u + 2 * nc];
        }
        for (int q = f->lp_start[k]; q < f->lp_start[k + 1]; q++) {
            int u = f->lp_col[q];
            double w = f->lp_val[q];
            lz[0] += w * e[u], lz[1] += w * e[u + nc], lz[2] += w * e[u + 2 * nc];
        }
    }
    double *d = f->d + 3 * k, *qv = f->q + 3 * k;
    for (int c = 0; c < 3; c++) {
        d[c] = f->first ? z[c] : z[c] + f->beta[c] * d[c];
        qv[c] = f->first ? lz[c] : lz[c] + f->beta[c] * qv[c];
        dq[c] += d[c] * qv[c];
    }
}

/* One phase over one half of the free vertices; part gets the half's sums.
 * The iterate is x itself: a half writes only its own vertices, and no
 * phase that writes x reads a neighbour's. */
static void run_half(void *ctx, int half)
{
    iso_proxy__fit *f = ctx;
    int b, e;
    iso_solver__team_half(f->nf, half, &b, &e);
    double sum[6] = {0, 0, 0, 0, 0, 0};
    double *acc = f->acc ? f->acc + 3 * (size_t)f->nc * half : NULL;
    if (acc && (f->phase == PH_RESIDUAL || f->phase == PH_STEP))
        memset(acc, 0, 3 * (size_t)f->nc * sizeof *acc);
    switch (f->phase) {
    case PH_RESIDUAL:
        for (int k = b; k < e; k++) {
            residual_at(f, k, f->r + 3 * k);
            after_residual(f, k, acc, sum);
        }
        break;
    case PH_DIRECTION:
        for (int k = b; k < e; k++)
            direction_at(f, k, f->Xc ? f->Xc->x : NULL, sum);
        break;
    case PH_STEP:      /* x += α d, r −= α q, and what the next direction needs */
    case PH_LAST_STEP: /* x += α d alone */
        for (int k = b; k < e; k++) {
            double *x = f->x + 3 * f->free_of[k];
            for (int c = 0; c < 3; c++)
                x[c] += f->alpha[c] * f->d[3 * k + c];
            if (f->phase == PH_LAST_STEP)
                continue;
            for (int c = 0; c < 3; c++)
                f->r[3 * k + c] -= f->alpha[c] * f->q[3 * k + c];
            after_residual(f, k, acc, sum);
        }
        break;
    }
    memcpy(f->part[half], sum, sizeof sum);
}

/* Runs a phase on both halves; sums = half 0's + half 1's, in that order. */
static void phase(iso_proxy__fit *f, int ph, double *sums)
{
    f->phase = ph;
    iso_solver__team_run(f->team, run_half, f);
    for (int c = 0; c < 6 && sums; c++)
        sums[c] = f->part[0][c] + f->part[1][c];
}

/* The coarse correction e = (PᵀLP)⁻¹ Pᵀ r into Xc, and r·z =
 * r·D⁻¹r + (Pᵀ r)·e into rz. sums: the step's, r·D⁻¹r at 3..5. */
static int coarse_solve(iso_proxy__fit *f, const double *sums, double *rz)
{
    for (int c = 0; c < 3; c++)
        rz[c] = sums[3 + c];
    if (!f->acc)
        return 0;
    double *bc = f->Bc->x;
    size_t nc = (size_t)f->nc;
    for (size_t u = 0; u < nc; u++)
        for (int c = 0; c < 3; c++)
            bc[u + nc * c] = f->acc[3 * u + c] + f->acc[3 * (nc + u) + c];
    if (!cholmod_solve2(CHOLMOD_A, f->Lc, f->Bc, NULL, &f->Xc, NULL, &f->Yc, &f->Ec, &f->c) ||
        f->c.status != CHOLMOD_OK)
        return -1;
    const double *e = f->Xc->x;
    for (int c = 0; c < 3; c++)
        for (size_t u = 0; u < nc; u++)
            rz[c] += bc[u + nc * c] * e[u + nc * c];
    return 0;
}

int iso_proxy__fit_run(iso_proxy__fit *f, const double *X, const double *R, double *x)
{
    f->X = X, f->R = R, f->x = x;
    f->iterations = 0;
    if (f->nf == 0)
        return 0;
    double s[6], rz[3], rzn[3], dq[6];
    phase(f, PH_RESIDUAL, s);
    if (!(s[0] + s[1] + s[2] > 0)) /* x⁰ is the fit already (the rest pose, a rigid motion) */
        return 0;
    if (coarse_solve(f, s, rz) != 0)
        return -1;
    f->first = 1;
    for (int it = 0; it < FIT_ITERATIONS; it++) {
        phase(f, PH_DIRECTION, dq);
        f->first = 0;
        for (int c = 0; c < 3; c++)
            f->alpha[c] = dq[c] > 0 ? rz[c] / dq[c] : 0;
        int last = it + 1 == FIT_ITERATIONS;
        phase(f, last ? PH_LAST_STEP : PH_STEP, s);
        f->iterations = it + 1;
        if (last)
            break;
        if (coarse_solve(f, s, rzn) != 0)
            return -1;
        for (int c = 0; c < 3; c++) {
            f->beta[c] = rz[c] > 0 ? rzn[c] / rz[c] : 0;
            rz[c] = rzn[c];
        }
    }
    return 0;
}

void iso_proxy__fit_set_team(iso_proxy__fit *f, iso_solver__team *team)
{
    if (f)
        f->team = team;
}

int iso_proxy__fit_iterations(const iso_proxy__fit *f)
{
    return f ? f->iterations : 0;
}
