/* solver/warmstart.c -- where PCG starts: the best combination, in A's
 * energy norm, of the caller's guess and the last ISO_SOLVER__HIST (8)
 * solutions.
 *
 * Why: under a person's drag the handles' velocity jumps from tick to tick
 * (a page's targets every 25 ms, a mouse's jabs), and the integrator's
 * polynomial extrapolation of the field amplifies each jump: on a recorded
 * drag of the paper's cactus the extrapolated start left residuals of 1 to
 * 100 times ‖b‖, far worse than starting from zero, and PCG with a stale
 * factor then failed and the evaluation factored on its own thread
 * (docs/performance.md, "Under a person's hand"). The Galerkin projection
 * of the solution onto W = [guess, x₋₁, …, x₋₈],
 *     x₀ = W c,   (Wᵀ A W) c = Wᵀ b,
 * is the start in that span whose error is smallest in the A-norm, the norm
 * PCG minimises; zero is in the span, so it is never worse than starting
 * from zero or from the guess. It costs one product of A with the eight
 * solutions as one block (CHOLMOD reads A once for four columns; A·guess is
 * PCG's first product anyway), 54 dot products and a 9×9 solve, and depends on nothing
 * but the evaluation's own numbers, so replays keep their bits. Eight:
 * on the recorded drags and the README's demo 2, 3, 4, 6, 8 and 12
 * solutions left 17, 15, 16, 15, 12 and 9 factorizations on the tick of
 * a page drag, and the demo's median tick was lowest at 8
 * (docs/performance.md).
 *
 * Before any solution is remembered the span is the guess alone: its scale
 * is still projected (a start twice too large costs nothing).
 *
 * History: the free part of every solution (direct or PCG) is kept once
 * PCG has run once (its vectors are allocated with PCG's). */
#include <math.h>
#include <string.h>

#include "solver_internal.h"

/* Directions whose pivot falls below this share of their own energy are
 * dependent on those before them (the guess is mostly a combination of the
 * history on a smooth path) and are left out of the start, which bounds
 * the coefficients' cancellation, and so the rounding of the start and of
 * its product with A, to about 1e4 ε. */
#define WARM_PIVOT_REL 1e-8
#define WARM_K (1 + ISO_SOLVER__HIST) /* the guess and the history */

/* Solves the k×k SPD system G c = g (row-major, leading dimension WARM_K) by
 * Cholesky, giving c = 0 to every direction whose pivot is dependent. */
static void small_solve(const double *G, const double *g, int k, double *c)
{
    double L[WARM_K * WARM_K] = {0}, y[WARM_K] = {0};
    int use[WARM_K] = {0};
    for (int a = 0; a < k; a++) {
        double d = G[(WARM_K + 1) * a];
        for (int q = 0; q < a; q++)
            d -= use[q] ? L[WARM_K * a + q] * L[WARM_K * a + q] : 0;
        if (!(G[(WARM_K + 1) * a] > 0) || !(d > WARM_PIVOT_REL * G[(WARM_K + 1) * a]))
            continue;
        use[a] = 1;
        L[(WARM_K + 1) * a] = sqrt(d);
        for (int t = a + 1; t < k; t++) {
            double v = G[WARM_K * t + a];
            for (int q = 0; q < a; q++)
                v -= use[q] ? L[WARM_K * t + q] * L[WARM_K * a + q] : 0;
            L[WARM_K * t + a] = v / L[(WARM_K + 1) * a];
        }
    }
    for (int a = 0; a < k; a++) {
        double v = g[a];
        for (int q = 0; q < a; q++)
            v -= use[q] ? L[WARM_K * a + q] * y[q] : 0;
        y[a] = use[a] ? v / L[(WARM_K + 1) * a] : 0;
    }
    for (int a = k - 1; a >= 0; a--) {
        double v = y[a];
        for (int t = a + 1; t < k; t++)
            v -= use[t] ? L[WARM_K * t + a] * c[t] : 0;
        c[a] = use[a] ? v / L[(WARM_K + 1) * a] : 0;
    }
}

/* The history's j-th newest solution (j from 0), and A times it. */
static size_t newest(const iso_solver *s, int j)
{
    int col = (s->hist_head - 1 - j + 2 * ISO_SOLVER__HIST) % ISO_SOLVER__HIST;
    return (size_t)col * (size_t)(3 * s->nf);
}

int iso_solver__warm_start(iso_solver *s, cholmod_dense *X, cholmod_dense *AX, iso_err *err)
{
    int n = 3 * s->nf, k = 1 + (s->hist ? s->n_hist : 0);
    const double *b = s->B->x;
    double *W[WARM_K] = {X->x}, *AW[WARM_K] = {AX->x};
    if (k > 1) {
        /* one product for the filled columns (0 .. n_hist − 1: filled in
         * order until they wrap), A read once for all of them */
        cholmod_dense h = *s->hist, ah = *s->ahist;
        h.ncol = ah.ncol = (size_t)s->n_hist;
        h.nzmax = ah.nzmax = h.ncol * h.nrow;
        int rc = iso_solver__matvec(s, &h, &ah, err);
        if (rc != ISO_OK)
            return rc;
        for (int j = 1; j < k; j++) {
            W[j] = (double *)s->hist->x + newest(s, j - 1);
            AW[j] = (double *)s->ahist->x + newest(s, j - 1);
        }
    }
    double G[WARM_K * WARM_K] = {0}, g[WARM_K] = {0}, c[WARM_K] = {0};
    for (int a = 0; a < k; a++) {
        g[a] = iso_solver__dot(W[a], b, n);
        for (int q = 0; q <= a; q++)
            G[WARM_K * a + q] = G[WARM_K * q + a] = iso_solver__dot(W[a], AW[q], n);
    }
    small_solve(G, g, k, c);
    for (int i = 0; i < n; i++) {
        double xv = c[0] * W[0][i], av = c[0] * AW[0][i];
        for (int a = 1; a < k; a++) {
            xv += c[a] * W[a][i];
            av += c[a] * AW[a][i];
        }
        W[0][i] = xv;
        AW[0][i] = av;
    }
    return ISO_OK;
}

void iso_solver__warm_remember(iso_solver *s)
{
    if (!s->hist || !s->X)
        return;
    double *col = (double *)s->hist->x + (size_t)s->hist_head * (size_t)(3 * s->nf);
    memcpy(col, s->X->x, (size_t)(3 * s->nf) * sizeof(double));
    s->hist_head = (s->hist_head + 1) % ISO_SOLVER__HIST;
    s->n_hist += s->n_hist < ISO_SOLVER__HIST;
}
