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
#include <string.h>

#include "simd_internal.h"
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
    return 2 * (size_t)L->n + PANEL;
}

static int supported(const cholmod_factor *L)
{
    return L->is_super && L->is_ll && L->xtype == CHOLMOD_REAL && L->dtype == CHOLMOD_DOUBLE &&
           L->itype == CHOLMOD_INT && L->x && L->s && L->super && L->pi && L->px;
}

int iso_solver__super_solve(const cholmod_factor *L, const double *b, double *x, double *work)
{
    if (!supported(L))
        return -1;
    const int *perm = L->Perm, *super = L->super, *pi = L->pi, *px = L->px, *ls = L->s;
    const double *lx = L->x;
    int n = (int)L->n, ns = (int)L->nsuper;
    double *y = work, *t = work + n, *dots = work + 2 * (size_t)n;
    for (int k = 0; k < n; k++)
        y[k] = b[perm ? perm[k] : k];
    for (int s = 0; s < ns; s++) {
        int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s];
        const double *X = lx + px[s];
        forward_diagonal(X, nsrow, nscol, y + k1, t);
        forward_below(X + nscol, nsrow, nscol, ls + pi[s] + nscol, nsrow - nscol, y, y + k1, t);
    }
    for (int s = ns - 1; s >= 0; s--) {
        int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s];
        const double *X = lx + px[s];
        backward_below(X + nscol, nsrow, nscol, ls + pi[s] + nscol, nsrow - nscol, y, y + k1, t,
                       dots);
        backward_diagonal(X, nsrow, nscol, y + k1, t);
    }
    for (int k = 0; k < n; k++)
        x[perm ? perm[k] : k] = y[k];
    return 0;
}
