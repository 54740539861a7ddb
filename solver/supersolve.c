/* solver/supersolve.c -- forward and backward substitution with CHOLMOD's
 * supernodal factor (supersolve_internal.h).
 *
 * A supernode holds columns k1 .. k1 + nscol − 1 of L, which share their
 * row pattern: a dense column-major block of nsrow rows (leading dimension
 * nsrow) at L->x + px[s], whose first nscol rows are the columns
 * themselves (the lower triangle of the diagonal block) and whose other m
 * rows are the rows L->s[pi[s] + nscol ..] below it. Each direction reads
 * every entry once, in eight-column panels, so that a row of the panel
 * updates or reads the right-hand side once, not eight times:
 *   forward, for each supernode: the diagonal triangle, panel by panel,
 *     then t = (rows below) y_k, scattered: y[rows] −= t;
 *   backward, for each supernode from the last: t = y[rows] gathered,
 *     y_k −= (rows below)ᵀ t, then the transposed diagonal triangle, panel
 *     by panel from the bottom.
 * The products below the diagonal are the only long loops; they are cloned
 * per instruction set and sum in a fixed order (simd_internal.h). */
#include <stdlib.h>
#include <string.h>

#include "simd_internal.h"
#include "solver_internal.h"
#include "supersolve_internal.h"

#define PANEL 8

typedef double v4 __attribute__((vector_size(4 * sizeof(double))));

/* A v4 from four doubles anywhere (the columns have no alignment). */
#define LOAD4(p)                                                                                   \
    __extension__({                                                                                \
        v4 load4_;                                                                                 \
        memcpy(&load4_, (p), sizeof load4_);                                                       \
        load4_;                                                                                    \
    })

/* t[0..m) += Σ_j X[0..m, j] y[j] over the NC columns of X (leading
 * dimension ld), the panel's sum first, from its first column. NC is a
 * constant where it is inlined, so each panel width gets a loop of its
 * own. */
ISO_INLINE void times_nc(const double *X, int ld, const int NC, const double *y, int m, double *t)
{
    for (int i = 0; i < m; i++) {
        double sum = X[i] * y[0];
#pragma GCC unroll 8
        for (int j = 1; j < NC; j++)
            sum += X[(size_t)j * ld + i] * y[j];
        t[i] += sum;
    }
}

/* out[j] = X[0..m, j] · t for the NC columns of X: each in four partial
 * sums (rows i mod 4), added pairwise, then the m mod 4 last rows. */
ISO_INLINE void dots_nc(const double *X, int ld, const int NC, const double *t, int m, double *out)
{
    v4 acc[PANEL] = {{0}};
    int m4 = m & ~3;
    for (int i = 0; i < m4; i += 4) {
        v4 tv = LOAD4(t + i);
#pragma GCC unroll 8
        for (int j = 0; j < NC; j++)
            acc[j] += LOAD4(X + (size_t)j * ld + i) * tv;
    }
    for (int j = 0; j < NC; j++) {
        double sum = (acc[j][0] + acc[j][1]) + (acc[j][2] + acc[j][3]);
        for (int i = m4; i < m; i++)
            sum += X[(size_t)j * ld + i] * t[i];
        out[j] = sum;
    }
}

/* The two for any panel width ncol in [1, PANEL]. */
#define BY_WIDTH(call, ncol)                                                                       \
    do {                                                                                           \
        switch (ncol) {                                                                            \
        case 1: call(1); break;                                                                    \
        case 2: call(2); break;                                                                    \
        case 3: call(3); break;                                                                    \
        case 4: call(4); break;                                                                    \
        case 5: call(5); break;                                                                    \
        case 6: call(6); break;                                                                    \
        case 7: call(7); break;                                                                    \
        default: call(8); break;                                                                   \
        }                                                                                          \
    } while (0)

ISO_CLONES static void panel_times(const double *X, int ld, int ncol, const double *y, int m,
                                   double *t)
{
#define TIMES(nc) times_nc(X, ld, nc, y, m, t)
    BY_WIDTH(TIMES, ncol);
#undef TIMES
}

ISO_CLONES static void panel_dots(const double *X, int ld, int ncol, const double *t, int m,
                                  double *out)
{
#define DOTS(nc) dots_nc(X, ld, nc, t, m, out)
    BY_WIDTH(DOTS, ncol);
#undef DOTS
}

/* y[0..nscol) ← D⁻¹ y, D the supernode's diagonal block (lower). */
static void forward_diagonal(const double *X, int ld, int nscol, double *y, double *t)
{
    for (int lo = 0; lo < nscol; lo += PANEL) {
        int hi = lo + PANEL < nscol ? lo + PANEL : nscol;
        for (int j = lo; j < hi; j++) {
            const double *c = X + (size_t)j * ld;
            y[j] /= c[j];
            for (int i = j + 1; i < hi; i++)
                y[i] -= c[i] * y[j];
        }
        if (hi < nscol) {
            memset(t, 0, (size_t)(nscol - hi) * sizeof *t);
            panel_times(X + (size_t)lo * ld + hi, ld, hi - lo, y + lo, nscol - hi, t);
            for (int i = hi; i < nscol; i++)
                y[i] -= t[i - hi];
        }
    }
}

/* y[0..nscol) ← D⁻ᵀ y. */
static void backward_diagonal(const double *X, int ld, int nscol, double *y, double *t)
{
    for (int hi = nscol; hi > 0; hi -= PANEL) {
        int lo = hi > PANEL ? hi - PANEL : 0;
        if (hi < nscol) {
            panel_dots(X + (size_t)lo * ld + hi, ld, hi - lo, y + hi, nscol - hi, t);
            for (int j = lo; j < hi; j++)
                y[j] -= t[j - lo];
        }
        for (int j = hi - 1; j >= lo; j--) {
            const double *c = X + (size_t)j * ld;
            double v = y[j];
            for (int i = j + 1; i < hi; i++)
                v -= c[i] * y[i];
            y[j] = v / c[j];
        }
    }
}

/* The rows below supernode s's diagonal block: y[rows] −= (below) y_k. */
static void forward_below(const double *X, int ld, int nscol, const int *rows, int m, double *y,
                          double *yk, double *t)
{
    if (m == 0)
        return;
    memset(t, 0, (size_t)m * sizeof *t);
    for (int lo = 0; lo < nscol; lo += PANEL) {
        int ncol = nscol - lo < PANEL ? nscol - lo : PANEL;
        panel_times(X + (size_t)lo * ld, ld, ncol, yk + lo, m, t);
    }
    for (int i = 0; i < m; i++)
        y[rows[i]] -= t[i];
}

/* y_k −= (below)ᵀ y[rows]. */
static void backward_below(const double *X, int ld, int nscol, const int *rows, int m,
                           const double *y, double *yk, double *t, double *dots)
{
    if (m == 0)
        return;
    for (int i = 0; i < m; i++)
        t[i] = y[rows[i]];
    for (int lo = 0; lo < nscol; lo += PANEL) {
        int ncol = nscol - lo < PANEL ? nscol - lo : PANEL;
        panel_dots(X + (size_t)lo * ld, ld, ncol, t, m, dots);
        for (int j = 0; j < ncol; j++)
            yk[lo + j] -= dots[j];
    }
}

size_t iso_solver__super_work(const cholmod_factor *L)
{
    return 4 * (size_t)L->n + 2 * PANEL;
}

static int supported(const cholmod_factor *L)
{
    return L->is_super && L->is_ll && L->xtype == CHOLMOD_REAL && L->dtype == CHOLMOD_DOUBLE &&
           L->itype == CHOLMOD_INT && L->x && L->s && L->super && L->pi && L->px;
}

/* Supernode s forward: its diagonal block, then the rows below it, into y
 * (or, for the rows that own[] does not give to `mine`, into side). */
static void forward_node(const cholmod_factor *L, int s, double *y, double *t,
                         const signed char *own, int mine, double *side)
{
    const int *super = L->super, *pi = L->pi, *px = L->px, *ls = L->s;
    int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s], m = nsrow - nscol;
    const double *X = (const double *)L->x + px[s];
    forward_diagonal(X, nsrow, nscol, y + k1, t);
    if (!side) {
        forward_below(X + nscol, nsrow, nscol, ls + pi[s] + nscol, m, y, y + k1, t);
        return;
    }
    if (m == 0)
        return;
    const int *rows = ls + pi[s] + nscol;
    memset(t, 0, (size_t)m * sizeof *t);
    for (int lo = 0; lo < nscol; lo += PANEL) {
        int ncol = nscol - lo < PANEL ? nscol - lo : PANEL;
        panel_times(X + nscol + (size_t)lo * nsrow, nsrow, ncol, y + k1 + lo, m, t);
    }
    for (int i = 0; i < m; i++) {
        if (own[rows[i]] == mine)
            y[rows[i]] -= t[i];
        else
            side[rows[i]] += t[i];
    }
}

static void backward_node(const cholmod_factor *L, int s, double *y, double *t, double *dots)
{
    const int *super = L->super, *pi = L->pi, *px = L->px, *ls = L->s;
    int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s];
    const double *X = (const double *)L->x + px[s];
    backward_below(X + nscol, nsrow, nscol, ls + pi[s] + nscol, nsrow - nscol, y, y + k1, t, dots);
    backward_diagonal(X, nsrow, nscol, y + k1, t);
}

int iso_solver__super_solve(const cholmod_factor *L, const double *b, double *x, double *work)
{
    if (!supported(L))
        return -1;
    const int *perm = L->Perm;
    int n = (int)L->n, ns = (int)L->nsuper;
    double *y = work, *t = work + n, *dots = work + 2 * (size_t)n;
    for (int k = 0; k < n; k++)
        y[k] = b[perm ? perm[k] : k];
    for (int s = 0; s < ns; s++)
        forward_node(L, s, y, t, NULL, 0, NULL);
    for (int s = ns - 1; s >= 0; s--)
        backward_node(L, s, y, t, dots);
    for (int k = 0; k < n; k++)
        x[perm ? perm[k] : k] = y[k];
    return 0;
}

/* ===== two subtrees at once =============================================== */

/* Two disjoint unions of whole subtrees of the supernodal elimination tree
 * (A, B) and what is left above them (R). Forward, A and B run at once:
 * each writes only its own rows and R's, A into y and B into a side array
 * that is subtracted from R's rows after both end (so every sum has one
 * order whether the halves ran on one thread or two); then R. Backward, R
 * first, then A and B at once, each reading R's finished rows and writing
 * its own. */
struct iso_solver__super_plan {
    int n, ns;
    int *list[3], len[3]; /* supernodes of A, B, R, ascending */
    signed char *own;     /* n: the part (0 A, 1 B, 2 R) each row's supernode is in */
};

void iso_solver__super_plan_destroy(iso_solver__super_plan *p)
{
    if (!p)
        return;
    for (int h = 0; h < 3; h++)
        free(p->list[h]);
    free(p->own);
    free(p);
}

/* The frontier of subtrees, split into A and B by their work, largest
 * first onto the lighter side (tag 0 or 1); returns the heavier side's. */
static double assign(const int *front, int nf, const double *sub, signed char *tag, int *order)
{
    for (int i = 0; i < nf; i++)
        order[i] = front[i];
    for (int i = 1; i < nf; i++) /* by descending work; frontiers are short */
        for (int j = i; j > 0 && sub[order[j]] > sub[order[j - 1]]; j--) {
            int tmp = order[j];
            order[j] = order[j - 1], order[j - 1] = tmp;
        }
    double side[2] = {0, 0};
    for (int i = 0; i < nf; i++) {
        int h = side[1] < side[0];
        tag[order[i]] = (signed char)h;
        side[h] += sub[order[i]];
    }
    return side[0] > side[1] ? side[0] : side[1];
}

/* Chooses the frontier: from the roots down, the heaviest subtree in it
 * replaced by its children (its own supernode joining R) while that
 * shortens R + the heavier side; tag[] gets the best frontier's sides. */
static void choose(int ns, const int *parent, const double *work, const double *sub,
                   signed char *tag, int *front, int *best, int *order)
{
    int nf = 0, nbest = 0;
    double above = 0, best_t = sub[ns]; /* sub[ns]: everything, the serial time */
    for (int s = 0; s < ns; s++)
        if (parent[s] < 0)
            front[nf++] = s;
    for (int round = 0; round < 64 && nf > 0 && nf < ns; round++) {
        double t = above + assign(front, nf, sub, tag, order);
        if (t < best_t) {
            best_t = t;
            nbest = nf;
            memcpy(best, front, (size_t)nf * sizeof *best);
        }
        int h = 0;
        for (int i = 1; i < nf; i++)
            if (sub[front[i]] > sub[front[h]])
                h = i;
        int top = front[h];
        above += work[top];
        front[h] = front[--nf];
        for (int s = 0; s < top; s++) /* children precede their parent */
            if (parent[s] == top)
                front[nf++] = s;
    }
    for (int s = 0; s < ns; s++)
        tag[s] = 2;
    if (nbest > 0 && best_t < 0.9 * sub[ns])
        assign(best, nbest, sub, tag, order);
}

iso_solver__super_plan *iso_solver__super_plan_create(const cholmod_factor *L)
{
    if (!L->is_super || !L->super || !L->pi || !L->s || L->nsuper < 2)
        return NULL;
    int n = (int)L->n, ns = (int)L->nsuper;
    const int *super = L->super, *pi = L->pi, *ls = L->s;
    iso_solver__super_plan *p = calloc(1, sizeof *p);
    int *parent = malloc((size_t)ns * sizeof *parent), *col = malloc((size_t)n * sizeof *col);
    int *front = malloc(3 * ((size_t)ns + 1) * sizeof *front);
    double *work = malloc(2 * ((size_t)ns + 1) * sizeof *work);
    signed char *tag = malloc((size_t)ns + 1);
    int ok = p && parent && col && front && work && tag;
    if (ok) {
        p->n = n, p->ns = ns;
        p->own = malloc((size_t)n + 1);
        for (int h = 0; h < 3; h++)
            p->list[h] = malloc(((size_t)ns + 1) * sizeof *p->list[h]);
        ok = p->own && p->list[0] && p->list[1] && p->list[2];
    }
    if (ok) {
        double *sub = work + ns + 1;
        for (int s = 0; s < ns; s++)
            for (int k = super[s]; k < super[s + 1]; k++)
                col[k] = s;
        sub[ns] = 0;
        for (int s = 0; s < ns; s++) {
            int nscol = super[s + 1] - super[s], nsrow = pi[s + 1] - pi[s];
            parent[s] = nsrow > nscol ? col[ls[pi[s] + nscol]] : -1;
            ok = ok && (parent[s] < 0 || parent[s] > s);
            work[s] = (double)nsrow * nscol;
            sub[s] = 0;
        }
        for (int s = 0; s < ns && ok; s++) {
            sub[s] += work[s];
            sub[ns] += work[s];
            if (parent[s] >= 0)
                sub[parent[s]] += sub[s];
        }
    }
    if (ok) {
        choose(ns, parent, work, work + ns + 1, tag, front, front + ns + 1, front + 2 * (ns + 1));
        for (int s = ns - 1; s >= 0; s--) /* parents first: a subtree takes its root's side */
            if (tag[s] == 2 && parent[s] >= 0 && tag[parent[s]] != 2)
                tag[s] = tag[parent[s]];
        for (int s = 0; s < ns; s++) {
            for (int k = super[s]; k < super[s + 1]; k++)
                p->own[k] = tag[s];
            p->list[tag[s]][p->len[tag[s]]++] = s;
        }
        ok = p->len[0] > 0 && p->len[1] > 0;
    }
    free(parent), free(col), free(front), free(work), free(tag);
    if (!ok) {
        iso_solver__super_plan_destroy(p);
        return NULL;
    }
    return p;
}

typedef struct split_job {
    const cholmod_factor *L;
    const iso_solver__super_plan *p;
    double *y, *side, *t[2], *dots[2];
    int forward;
} split_job;

static void split_half(void *ctx, int half)
{
    split_job *j = ctx;
    const iso_solver__super_plan *p = j->p;
    const int *list = p->list[half];
    int len = p->len[half];
    if (j->forward)
        for (int i = 0; i < len; i++)
            forward_node(j->L, list[i], j->y, j->t[half], p->own, half, half ? j->side : NULL);
    else
        for (int i = len - 1; i >= 0; i--)
            backward_node(j->L, list[i], j->y, j->t[half], j->dots[half]);
}

int iso_solver__super_solve_split(const cholmod_factor *L, const iso_solver__super_plan *p,
                                  iso_solver__team *team, const double *b, double *x, double *work)
{
    if (!supported(L) || (int)L->n != p->n || (int)L->nsuper != p->ns)
        return -1;
    const int *perm = L->Perm, *super = L->super;
    int n = p->n;
    split_job j = {L,
                   p,
                   work,
                   work + 3 * (size_t)n,
                   {work + n, work + 2 * (size_t)n},
                   {work + 4 * (size_t)n, work + 4 * (size_t)n + PANEL},
                   1};
    for (int k = 0; k < n; k++)
        j.y[k] = b[perm ? perm[k] : k];
    const int *r = p->list[2];
    for (int i = 0; i < p->len[2]; i++)
        for (int k = super[r[i]]; k < super[r[i] + 1]; k++)
            j.side[k] = 0;
    iso_solver__team_run(team, split_half, &j);
    for (int i = 0; i < p->len[2]; i++)
        for (int k = super[r[i]]; k < super[r[i] + 1]; k++)
            j.y[k] -= j.side[k];
    for (int i = 0; i < p->len[2]; i++)
        forward_node(L, r[i], j.y, j.t[0], NULL, 0, NULL);
    for (int i = p->len[2] - 1; i >= 0; i--)
        backward_node(L, r[i], j.y, j.t[0], j.dots[0]);
    j.forward = 0;
    iso_solver__team_run(team, split_half, &j);
    for (int k = 0; k < n; k++)
        x[perm ? perm[k] : k] = j.y[k];
    return 0;
}
