/* solver/warmstart.c -- where PCG starts: the best combination, in A's
 * energy norm, of the caller's guess and the last two solutions.
 *
 * Why: under a person's drag the handles' velocity jumps from tick to tick
 * (a page's targets every 25 ms, a mouse's jabs), and the integrator's
 * polynomial extrapolation of the field amplifies each jump: on a recorded
 * drag of the paper's cactus the extrapolated start left residuals of 1 to
 * 100 times ‖b‖, far worse than starting from zero, and PCG with a stale
 * factor then failed and the evaluation factored on its own thread
 * (docs/performance.md, "Under a person's hand"). The Galerkin projection
 * of the solution onto W = [guess, x₋₁, x₋₂],
 *     x₀ = W c,   (Wᵀ A W) c = Wᵀ b,
 * is the start in that span whose error is smallest in the A-norm, the norm
 * PCG minimises; zero is in the span, so it is never worse than starting
 * from zero or from the guess. It costs two products with A (A·guess is
 * PCG's first product anyway) and a 3×3 solve, and depends on nothing
 * but the evaluation's own numbers, so replays keep their bits.
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
 * history on a smooth path) and are left out of the start. */
#define WARM_PIVOT_REL 1e-10

/* Solves the k×k SPD system G c = g (row-major, leading dimension 3) by
 * Cholesky, giving c = 0 to every direction whose pivot is dependent. */
static void small_solve(const double *G, const double *g, int k, double *c)
{
    double L[9] = {0}, y[3] = {0};
    int use[3] = {0, 0, 0};
    for (int a = 0; a < k; a++) {
        double d = G[4 * a];
        for (int q = 0; q < a; q++)
            d -= use[q] ? L[3 * a + q] * L[3 * a + q] : 0;
        if (!(G[4 * a] > 0) || !(d > WARM_PIVOT_REL * G[4 * a]))
            continue;
        use[a] = 1;
        L[4 * a] = sqrt(d);
        for (int t = a + 1; t < k; t++) {
            double v = G[3 * t + a];
            for (int q = 0; q < a; q++)
                v -= use[q] ? L[3 * t + q] * L[3 * a + q] : 0;
            L[3 * t + a] = v / L[4 * a];
        }
    }
    for (int a = 0; a < k; a++) {
        double v = g[a];
        for (int q = 0; q < a; q++)
            v -= use[q] ? L[3 * a + q] * y[q] : 0;
        y[a] = use[a] ? v / L[4 * a] : 0;
    }
    for (int a = k - 1; a >= 0; a--) {
        double v = y[a];
        for (int t = a + 1; t < k; t++)
            v -= use[t] ? L[3 * t + a] * c[t] : 0;
        c[a] = use[a] ? v / L[4 * a] : 0;
    }
}

int iso_solver__warm_start(iso_solver *s, cholmod_dense *X, cholmod_dense *AX, iso_err *err)
{
    int n = 3 * s->nf, k = 1 + (s->hist[0] ? s->n_hist : 0);
    const double *b = s->B->x;
    double *W[3] = {X->x, NULL, NULL}, *AW[3] = {AX->x, NULL, NULL};
    for (int j = 1; j < k; j++) {
        int rc = iso_solver__matvec(s, s->hist[j - 1], s->ahist[j - 1], err);
        if (rc != ISO_OK)
            return rc;
        W[j] = s->hist[j - 1]->x;
        AW[j] = s->ahist[j - 1]->x;
    }
    double G[9] = {0}, g[3] = {0}, c[3] = {0};
    for (int a = 0; a < k; a++) {
        g[a] = iso_solver__dot(W[a], b, n);
        for (int q = 0; q <= a; q++)
            G[3 * a + q] = G[3 * q + a] = iso_solver__dot(W[a], AW[q], n);
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
    if (!s->hist[0] || !s->X)
        return;
    cholmod_dense *t = s->hist[ISO_SOLVER__HIST - 1];
    for (int i = ISO_SOLVER__HIST - 1; i > 0; i--)
        s->hist[i] = s->hist[i - 1];
    s->hist[0] = t;
    memcpy(t->x, s->X->x, (size_t)(3 * s->nf) * sizeof(double));
    s->n_hist += s->n_hist < ISO_SOLVER__HIST;
}
