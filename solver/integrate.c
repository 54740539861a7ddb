/* solver/integrate.c -- ABM3 with an RK4 or a low-order Adams start
 * (iso_integrate.h).
 *
 * State: the positions of all vertices. Only free vertices are integrated;
 * before every field evaluation the handle vertices are placed at their
 * exact pose for that stage's time, so they cannot drift.
 *
 * The Adams coefficients are recomputed for the actual node spacing, so the
 * step may change without restarting: a predictor of order k integrates the
 * polynomial through f at t_n, ..., t_{n-k+1} over [t_n, t_n + h], the
 * corrector the one through t_{n+1}, t_n (and t_{n-1} once k ≥ 2). With
 * equal steps and k = 3 they are the textbook 23/12, −16/12, 5/12 and 5/12,
 * 8/12, −1/12; k = 1 is Euler and the trapezoidal rule (Heun). */
#include "iso_integrate.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "iso_names.h"

void iso_integrate_opts_default(iso_integrate_opts *o)
{
    memset(o, 0, sizeof *o);
    o->t0 = 0.0;
    o->t1 = 1.0;
    o->steps = 0;
    o->tol = ISO_INTEGRATE_DEFAULT_TOL;
    o->restore_kappa = ISO_INTEGRATE_RESTORE_KAPPA;
    o->start = ISO_INTEGRATE_START_RK4;
    o->cg_share = ISO_INTEGRATE_CG_SHARE;
}

typedef struct integ {
    iso_solver *s;
    const iso_mesh *m;
    const iso_regions *r;
    const iso_path *path;
    int nv;
    const double *rest;
    iso_pose *poses; /* per handle, at the current stage */
    iso_twist *twists;
    double *vc;        /* 3nv handle velocities */
    double *f[4];      /* history: f_n, f_{n-1}, f_{n-2}, and f_{n-3} for CG's start (3nv each) */
    double tf[4];      /* their times */
    double *xs, *k[4]; /* stage positions and RK4 slopes */
    double *xp;        /* predictor */
    long evaluations;
    double restore_mu, restore_tau; /* the solver's, as the caller set them */
    double restore_kappa;
    int hist;          /* valid entries of the history f for the Adams steps (0..3) */
    int nstart;        /* valid entries of f for CG's start (0..4) */
    double *guess[2];  /* CG's start extrapolated from 3 and from 4 entries of f (3nv each) */
    int cubic;         /* the start from 4 predicted the last solution better */
    double cg_share;   /* CG's share of a step's local error; 0: cg_tol */
    double est, est_h; /* the last third-order step's Milne estimate and length */
    double start_err;  /* adaptive offline: the local error a step is allowed,
                          CG's measure without an estimate; 0: cg_tol alone */
} integ;

/* Places the handle vertices of x at their poses for time t and fills the
 * handle velocities. */
static int place_handles(integ *g, double t, double *x, iso_err *err)
{
    for (int h = 0; h < g->r->n_handles; h++) {
        int rc = g->path->eval(g->path->ctx, h, t, &g->poses[h], &g->twists[h]);
        if (rc != ISO_OK)
            return iso_err_set(err, rc < 0 ? rc : ISO_EINVAL, -1,
                               "the path of handle %d could not be evaluated at t = %g", h, t);
    }
    for (int i = 0; i < g->nv; i++) {
        if (g->r->kind[i] != ISO_HANDLE)
            continue;
        int h = g->r->handle[i];
        iso_pose_apply(&g->poses[h], g->rest + 3 * i, x + 3 * i);
        iso_twist_velocity(&g->twists[h], x + 3 * i, g->vc + 3 * i);
    }
    return ISO_OK;
}

/* f = v̂(x, t); x's handle vertices are updated to time t. With guess
 * (may be f) an iterative solve starts there. */
static int eval_field_from(integ *g, double t, double *x, const double *guess, double *f,
                           iso_err *err)
{
    int rc = place_handles(g, t, x, err);
    if (rc == ISO_OK)
        rc = iso_solver_field_from(g->s, x, g->vc, guess, f, err);
    if (rc == ISO_OK)
        g->evaluations++;
    return rc;
}

static int eval_field(integ *g, double t, double *x, double *f, iso_err *err)
{
    return eval_field_from(g, t, x, NULL, f, err);
}

/* y = x + Σ c_j d_j on free vertices; other vertices copied from x. */
static void combine(const integ *g, double *y, const double *x, int n, const double *c,
                    double *const *d)
{
    for (int i = 0; i < g->nv; i++) {
        int fr = g->r->kind[i] == ISO_FREE;
        for (int a = 0; a < 3; a++) {
            int q = 3 * i + a;
            double val = x[q];
            if (fr)
                for (int j = 0; j < n; j++)
                    val += c[j] * d[j][q];
            y[q] = val;
        }
    }
}

/* One RK4 step from (t, x) with f(x, t) already in g->f[0]; x advanced. */
static int rk4_step(integ *g, double t, double h, double *x, iso_err *err)
{
    double half = 0.5 * h;
    int rc;
    memcpy(g->k[0], g->f[0], (size_t)(3 * g->nv) * sizeof(double));
    combine(g, g->xs, x, 1, &half, &g->k[0]);
    if ((rc = eval_field(g, t + half, g->xs, g->k[1], err)) != ISO_OK)
        return rc;
    combine(g, g->xs, x, 1, &half, &g->k[1]);
    if ((rc = eval_field(g, t + half, g->xs, g->k[2], err)) != ISO_OK)
        return rc;
    combine(g, g->xs, x, 1, &h, &g->k[2]);
    if ((rc = eval_field(g, t + h, g->xs, g->k[3], err)) != ISO_OK)
        return rc;
    double c[4] = {h / 6, h / 3, h / 3, h / 6};
    combine(g, x, x, 4, c, g->k);
    return ISO_OK;
}

/* The Lagrange basis polynomials through nodes t[0..n-1] (n ≤ 4), at tau. */
static void lagrange_basis(const double *t, int n, double tau, double *l)
{
    for (int i = 0; i < n; i++) {
        l[i] = 1;
        for (int j = 0; j < n; j++)
            if (j != i)
                l[i] *= (tau - t[j]) / (t[i] - t[j]);
    }
}

/* ∫_a^b of the Lagrange basis polynomials through nodes t[0..n-1], exact by
 * two-point Gauss–Legendre (the basis is at most quadratic). */
static void lagrange_weights(const double *t, int n, double a, double b, double *w)
{
    double mid = 0.5 * (a + b), rad = 0.5 * (b - a), g = rad / sqrt(3.0);
    double pts[2] = {mid - g, mid + g};
    for (int i = 0; i < n; i++)
        w[i] = 0;
    for (int q = 0; q < 2; q++) {
        double l[4];
        lagrange_basis(t, n, pts[q], l);
        for (int i = 0; i < n; i++)
            w[i] += rad * l[i];
    }
}

static void push_history(integ *g, double t)
{
    g->hist = g->hist < 3 ? g->hist + 1 : 3;
    g->nstart = g->nstart < 4 ? g->nstart + 1 : 4;
    double *oldest = g->f[3];
    g->f[3] = g->f[2];
    g->tf[3] = g->tf[2];
    g->f[2] = g->f[1];
    g->f[1] = g->f[0];
    g->f[0] = oldest;
    g->tf[2] = g->tf[1];
    g->tf[1] = g->tf[0];
    g->tf[0] = t;
}

/* Σ |a − b|² over the free vertices' entries. */
static double free_dist2(const integ *g, const double *a, const double *b)
{
    double sum = 0;
    for (int i = 0; i < g->nv; i++)
        if (g->r->kind[i] == ISO_FREE)
            for (int q = 3 * i; q < 3 * i + 3; q++)
                sum += (a[q] - b[q]) * (a[q] - b[q]);
    return sum;
}

/* Max over free vertices of |a − b| (Euclidean per vertex). */
static double max_free_diff(const integ *g, const double *a, const double *b)
{
    double m = 0;
    for (int i = 0; i < g->nv; i++) {
        if (g->r->kind[i] != ISO_FREE)
            continue;
        double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1],
               dz = a[3 * i + 2] - b[3 * i + 2];
        m = fmax(m, sqrt(dx * dx + dy * dy + dz * dz));
    }
    return m;
}

/* y = the polynomial through the history f at times t[0..n-1] (relative),
 * evaluated at τ: where the field is heading, the start for the solve at
 * the predicted point (the previous solution is one step behind). */
static void extrapolate(const integ *g, const double *t, int n, double tau, double *y)
{
    double l[4];
    lagrange_basis(t, n, tau, l);
    for (int q = 0; q < 3 * g->nv; q++) {
        double val = 0;
        for (int j = 0; j < n; j++)
            val += l[j] * g->f[j][q];
        y[q] = val;
    }
}

/* CG's accuracy for the evaluations of a step of length h: the field error
 * δ of a solve moves the step by h δ (iso_integrate.h), so CG may stop at
 * δ ≤ share × est / h, est the last third-order step's Milne estimate,
 * scaled by (h / its length)⁴ as the local error is. Without an estimate
 * (a start) est is the error such a step is allowed, start_err, or with
 * none the solver's cg_tol holds. */
static void set_cg_target(integ *g, double h)
{
    double target = 0;
    if (g->cg_share > 0 && g->est > 0) {
        double q = h / g->est_h;
        target = g->cg_share * g->est * (q * q) * (q * q) / h;
    } else if (g->cg_share > 0 && g->start_err > 0) {
        target = g->cg_share * g->start_err / h;
    }
    iso_solver_set_cg_target(g->s, target);
}

/* P, E and C of one Adams step of order k (1..3, iso_integrate.h) and
 * length h from t = tf[0]; leaves the corrected positions in xc, f at the
 * predicted point in k[0], and returns Milne's estimate in *est (absolute;
 * it estimates the corrector's error only when k = 3). The history is not
 * touched. */
static int adams_predict_correct(integ *g, int k, double h, const double *x, double *xc,
                                 double *est, iso_err *err)
{
    double t = g->tf[0], wp[3], wc[3];
    double tp[4] = {0, g->tf[1] - t, g->tf[2] - t, g->tf[3] - t};
    lagrange_weights(tp, k, 0, h, wp);
    combine(g, g->xp, x, k, wp, g->f);
    /* CG's start: the history extrapolated to t + h through its last three
     * entries, or its last four, whichever put the last solution closer.
     * On a smooth path the cubic start is an order closer (bumpplane scene:
     * relative residual 5e-7 → 2e-8, solves with the factor per tick 4 →
     * 1.8; cactus scene: CG iterations 245 → 136, bar 317 → 184); under a
     * twist that changes every tick (a recorded 3D-mouse session) it was
     * the worse (37 → 41 factorizations), and the choice keeps the
     * quadratic there (37, and 1,231 iterations against 1,299). Only the
     * start changes, never the tolerance a solve ends at. */
    int both = k == 3 && g->nstart == 4;
    extrapolate(g, tp, k, h, g->guess[0]);
    if (both)
        extrapolate(g, tp, 4, h, g->guess[1]);
    memcpy(g->k[0], g->guess[both && g->cubic], (size_t)(3 * g->nv) * sizeof(double));
    set_cg_target(g, h);
    int rc = eval_field_from(g, t + h, g->xp, g->k[0], g->k[0], err);
    if (rc != ISO_OK)
        return rc;
    if (both)
        g->cubic = free_dist2(g, g->guess[1], g->k[0]) < free_dist2(g, g->guess[0], g->k[0]);
    int kc = k < 2 ? k + 1 : 3; /* the corrector's nodes: t + h and k of the history, at most 2 */
    double tc[3] = {h, 0, g->tf[1] - t};
    lagrange_weights(tc, kc, 0, h, wc);
    double *dc[3] = {g->k[0], g->f[0], g->f[1]};
    combine(g, xc, x, kc, wc, dc);
    *est = max_free_diff(g, xc, g->xp) / 10.0;
    return ISO_OK;
}

/* Ends a step at time t1 with x at its end: the history takes f at x (an
 * evaluation: RK4, PECE) or, with `pec`, the predictor's f in k[0] (the
 * handles are still placed at t1). */
static int end_step(integ *g, double t1, double *x, int pec, iso_err *err)
{
    push_history(g, t1);
    if (!pec) {
        set_cg_target(g, t1 - g->tf[1]);
        return eval_field(g, t1, x, g->f[0], err);
    }
    double *fp = g->k[0]; /* f(x_p, t1) becomes f_{n+1}; k[0] is scratch */
    g->k[0] = g->f[0];
    g->f[0] = fp;
    return place_handles(g, t1, x, err);
}

/* A third-order step's estimate, for the CG target of the steps after. */
static void keep_estimate(integ *g, double est, double h)
{
    g->est = est;
    g->est_h = h;
}

static int integ_init(integ *g, iso_solver *s, const iso_mesh *m, const iso_regions *r,
                      const iso_path *path, iso_err *err)
{
    memset(g, 0, sizeof *g);
    g->s = s;
    g->m = m;
    g->r = r;
    g->path = path;
    g->nv = iso_mesh_vertex_count(m);
    g->rest = iso_mesh_positions(m);
    size_t n = (size_t)(3 * g->nv) * sizeof(double);
    int nh = r->n_handles > 0 ? r->n_handles : 1;
    g->poses = calloc((size_t)nh, sizeof *g->poses);
    g->twists = calloc((size_t)nh, sizeof *g->twists);
    g->vc = calloc(1, n);
    g->xs = calloc(1, n);
    g->xp = calloc(1, n);
    int ok = g->poses && g->twists && g->vc && g->xs && g->xp;
    for (int i = 0; i < 4; i++)
        ok = ok && (g->f[i] = calloc(1, n));
    for (int i = 0; i < 2; i++)
        ok = ok && (g->guess[i] = calloc(1, n));
    for (int i = 0; i < 4; i++)
        ok = ok && (g->k[i] = calloc(1, n));
    return ok ? ISO_OK : iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the integrator");
}

static void integ_deinit(integ *g)
{
    free(g->poses);
    free(g->twists);
    free(g->vc);
    free(g->xs);
    free(g->xp);
    for (int i = 0; i < 4; i++)
        free(g->f[i]);
    for (int i = 0; i < 2; i++)
        free(g->guess[i]);
    for (int i = 0; i < 4; i++)
        free(g->k[i]);
}

/* Step length that lands exactly on t1 without leaving a sliver. The
 * stretch allowance (5%) must stay below what a rejection shrinks a step by
 * (at least 10%), or a rejected last step would be stretched back to the
 * same length forever. */
static double fit_to_end(double t, double t1, double h)
{
    double rem = t1 - t;
    if (rem <= 1.05 * h)
        return rem;
    if (rem < 2 * h)
        return 0.5 * rem;
    return h;
}

/* Restoration's time constant for a step of length h: τ_eff = max(τ, κ h)
 * (iso_integrate.h). Nothing is touched when the term is off, so that run
 * stays the paper's method bit for bit. */
static int set_step_tau(integ *g, double h, iso_err *err)
{
    if (!(g->restore_mu > 0) || !(g->restore_kappa > 0))
        return ISO_OK;
    return iso_solver_set_restore_tau(g->s, fmax(g->restore_tau, g->restore_kappa * h), err);
}

/* One offline step of length h from (t, x): RK4 while the paper's start
 * lasts, else an Adams step of the history's order k. Returns 1 with xc
 * holding the step's end and *pec saying how the history is to be ended
 * (end_step), 0 when an adaptive step was rejected (*h shrunk), or a
 * negative code. *h_next: the next step's length. */
static int offline_step(integ *g, const iso_integrate_opts *o, double t, double *h, double *h_next,
                        double *x, double *xc, int *pec, iso_integrate_stats *st, iso_err *err)
{
    int adaptive = o->steps <= 0, rc;
    double span = o->t1 - o->t0, scale = iso_mesh_bbox_diagonal(g->m);
    double tol = (o->tol > 0 ? o->tol : ISO_INTEGRATE_DEFAULT_TOL) * scale;
    *pec = 0;
    *h_next = *h;
    if (o->start == ISO_INTEGRATE_START_RK4 && st->steps < 2) {
        if ((rc = rk4_step(g, t, *h, x, err)) != ISO_OK)
            return rc;
        st->rk4_steps++;
        memcpy(xc, x, (size_t)(3 * g->nv) * sizeof(double));
        return 1;
    }
    int k = g->hist;
    double est;
    if ((rc = adams_predict_correct(g, k, *h, x, xc, &est, err)) != ISO_OK)
        return rc;
    st->adams_order = k;
    if (k < 3) { /* the low-order start: accepted as RK4's steps are, the first one PEC */
        st->low_order_steps++;
        *pec = k == 1;
        return 1;
    }
    double ratio = est / tol;
    if (adaptive && ratio > 1.0 && *h > 1e-6 * span) {
        st->rejected++;
        *h *= fmax(0.2, 0.9 * cbrt(1.0 / ratio));
        return 0;
    }
    st->max_err_estimate = fmax(st->max_err_estimate, est / scale);
    keep_estimate(g, est, *h);
    if (adaptive)
        *h_next = fmin(*h * fmin(2.0, 0.9 * cbrt(1.0 / fmax(ratio, 1e-12))), span);
    return 1;
}

static int run(integ *g, const iso_integrate_opts *o, double *x, iso_integrate_stats *st,
               iso_err *err)
{
    double span = o->t1 - o->t0, t = o->t0;
    int adaptive = o->steps <= 0;
    double h = adaptive ? span * fmin(0.1, cbrt(o->tol > 0 ? o->tol : ISO_INTEGRATE_DEFAULT_TOL))
                        : span / o->steps;
    int total = adaptive ? 0 : o->steps, rc;
    double *xc = g->xs;

    if ((rc = set_step_tau(g, h, err)) != ISO_OK)
        return rc;
    set_cg_target(g, h);
    if ((rc = eval_field(g, t, x, g->f[0], err)) != ISO_OK)
        return rc;
    g->tf[0] = t;
    g->hist = 1;
    g->nstart = 1;
    while (t < o->t1 && (adaptive || st->steps < total)) {
        if (adaptive)
            h = fit_to_end(t, o->t1, h);
        else if (st->steps == total - 1)
            h = o->t1 - t; /* no drift from summing h */
        double tn = t + h, h_next;
        int pec;
        if ((rc = set_step_tau(g, h, err)) != ISO_OK)
            return rc;
        if ((rc = offline_step(g, o, t, &h, &h_next, x, xc, &pec, st, err)) < 0)
            return rc;
        if (rc == 0)
            continue;
        memcpy(x, xc, (size_t)(3 * g->nv) * sizeof(double));
        if (tn > o->t1 || (!adaptive && st->steps == total - 1))
            tn = o->t1;
        h = h_next;
        if ((rc = end_step(g, tn, x, pec, err)) != ISO_OK)
            return rc;
        t = tn;
        st->steps++;
        if (o->progress)
            o->progress(o->progress_ctx, t, st->steps, g->evaluations);
    }
    return ISO_OK;
}

int iso_integrate(iso_solver *s, const iso_mesh *m, const iso_regions *r, const iso_path *path,
                  const iso_integrate_opts *opts, double *x, iso_integrate_stats *st, iso_err *err)
{
    iso_integrate_opts o;
    if (opts)
        o = *opts;
    else
        iso_integrate_opts_default(&o);
    memset(st, 0, sizeof *st);
    if (!(o.t1 > o.t0))
        return iso_err_set(err, ISO_EINVAL, -1, "the time span [%g, %g] is empty", o.t0, o.t1);
    if (o.steps <= 0 && !(o.tol > 0))
        return iso_err_set(err, ISO_EINVAL, -1, "tolerance %g must be positive", o.tol);
    if (o.start != ISO_INTEGRATE_START_RK4 && o.start != ISO_INTEGRATE_START_ADAMS)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown start %d (RK4 0 or Adams 1)", o.start);
    if (!(o.cg_share >= 0 && isfinite(o.cg_share)))
        return iso_err_set(err, ISO_EINVAL, -1, "cg_share %g must be >= 0 and finite", o.cg_share);
    integ g;
    int rc = integ_init(&g, s, m, r, path, err);
    iso_solver_get_restore(s, &g.restore_mu, &g.restore_tau);
    g.restore_kappa = o.restore_kappa;
    g.cg_share = o.cg_share;
    if (o.steps <= 0) /* adaptive: every step is allowed tol; fixed steps promise nothing */
        g.start_err = o.tol * iso_mesh_bbox_diagonal(m);
    if (rc == ISO_OK)
        rc = run(&g, &o, x, st, err);
    iso_solver_set_cg_target(s, 0); /* the solver as the caller gave it */
    if (g.restore_mu > 0 && g.restore_kappa > 0) {
        iso_err ignored; /* τ was accepted at creation: setting it back cannot fail */
        if (iso_solver_set_restore_tau(s, g.restore_tau, &ignored) != ISO_OK)
            rc = rc == ISO_OK ? iso_err_set(err, ignored.code, -1, "%s", ignored.msg) : rc;
    }
    st->evaluations = g.evaluations;
    integ_deinit(&g);
    return rc;
}

/* ===== real time: one step per tick ===================================== */

struct iso_stepper {
    integ g;
    iso_path path;
    double *x;
    double t; /* start of the current tick */
    int nh;
    iso_pose *base; /* per handle: pose at t */
    iso_twist *tw;  /* per handle: twist held over the current tick */
    iso_abm_mode mode;
    double pec_tol; /* PEC: a step whose predictor missed by more ends PECE (iso_integrate.h) */
    double diag;    /* the mesh's bounding-box diagonal */
    iso_integrate_stats st;
};

/* The tick's path: exp((t − t_n) ξ) ∘ pose(t_n), constant world twist ξ. */
static int tick_path_eval(void *ctx, int handle, double t, iso_pose *pose, iso_twist *twist)
{
    iso_stepper *st = ctx;
    if (handle < 0 || handle >= st->nh)
        return ISO_EINVAL;
    iso_pose e;
    iso_twist_exp(&st->tw[handle], t - st->t, &e);
    iso_pose_compose(&e, &st->base[handle], pose);
    *twist = st->tw[handle];
    return ISO_OK;
}

int iso_stepper_create(iso_solver *s, const iso_mesh *m, const iso_regions *r, double *x,
                       iso_stepper **out, iso_err *err)
{
    *out = NULL;
    iso_stepper *st = calloc(1, sizeof *st);
    if (!st)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the stepper");
    st->nh = r->n_handles > 0 ? r->n_handles : 1;
    st->base = calloc((size_t)st->nh, sizeof *st->base);
    st->tw = calloc((size_t)st->nh, sizeof *st->tw);
    st->path.eval = tick_path_eval;
    st->path.ctx = st;
    st->x = x;
    int rc = st->base && st->tw ? integ_init(&st->g, s, m, r, &st->path, err)
                                : iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    if (rc != ISO_OK) {
        iso_stepper_destroy(st);
        return rc;
    }
    for (int h = 0; h < st->nh; h++)
        iso_pose_identity(&st->base[h]);
    iso_solver_get_restore(s, &st->g.restore_mu, &st->g.restore_tau);
    st->g.restore_kappa = ISO_INTEGRATE_RESTORE_KAPPA;
    st->g.cg_share = ISO_INTEGRATE_CG_SHARE;
    st->pec_tol = ISO_STEPPER_PEC_TOL;
    st->diag = iso_mesh_bbox_diagonal(m);
    *out = st;
    return ISO_OK;
}

void iso_stepper_destroy(iso_stepper *st)
{
    if (!st)
        return;
    if (st->g.s && st->g.restore_mu > 0) {
        iso_err ignored; /* put back the τ the caller configured; it was valid */
        if (iso_solver_set_restore_tau(st->g.s, st->g.restore_tau, &ignored) != ISO_OK)
            ignored.code = ISO_OK;
    }
    if (st->g.s)
        iso_solver_set_cg_target(st->g.s, 0);
    integ_deinit(&st->g);
    free(st->base);
    free(st->tw);
    free(st);
}

const char *const iso_abm_mode_names[] = {"pece", "pec", NULL};
const char *const iso_integrate_start_names[] = {"rk4", "adams", NULL};

const char *iso_abm_mode_name(iso_abm_mode mode)
{
    return iso_names_get(iso_abm_mode_names, (int)mode);
}

int iso_stepper_configure(iso_stepper *st, iso_abm_mode mode, double restore_kappa, iso_err *err)
{
    if (mode != ISO_ABM_PECE && mode != ISO_ABM_PEC)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown ABM mode %d (PECE 0 or PEC 1)", (int)mode);
    if (isnan(restore_kappa))
        return iso_err_set(err, ISO_EINVAL, -1, "restore_kappa is not a number");
    st->mode = mode;
    st->g.restore_kappa = restore_kappa >= 0    ? restore_kappa
                          : mode == ISO_ABM_PEC ? ISO_INTEGRATE_RESTORE_KAPPA_PEC
                                                : ISO_INTEGRATE_RESTORE_KAPPA;
    return ISO_OK;
}

int iso_stepper_set_pec_tol(iso_stepper *st, double tol, iso_err *err)
{
    if (!(tol >= 0 && isfinite(tol)))
        return iso_err_set(err, ISO_EINVAL, -1, "pec_tol %g must be >= 0 and finite", tol);
    st->pec_tol = tol;
    return ISO_OK;
}

int iso_stepper_set_cg_share(iso_stepper *st, double share, iso_err *err)
{
    if (!(share >= 0 && isfinite(share)))
        return iso_err_set(err, ISO_EINVAL, -1, "cg_share %g must be >= 0 and finite", share);
    st->g.cg_share = share;
    return ISO_OK;
}

/* The step's evaluations: f at its start after a restart (with this tick's
 * twists), then an Adams step of the history's order (iso_integrate.h). The
 * restart's own step ends PEC in either mode, so that it too makes two. */
static int stepper_advance(iso_stepper *st, double h, int restart, iso_err *err)
{
    integ *g = &st->g;
    int rc = set_step_tau(g, h, err);
    if (rc != ISO_OK)
        return rc;
    /* A step much longer than the history's last interval (a late tick
     * of the loop, covering seconds in few sub-steps) would extrapolate
     * the field's interpolant far beyond its nodes: at 128 times the
     * interval a quadratic's curvature grows 16,000-fold, and a recorded
     * session's mesh tore (edge strain 385%) in one such step. It restarts
     * the history instead, at the cost of a restart's two evaluations. */
    if (g->hist > 1 && h > ISO_STEPPER_MAX_STEP_RATIO * (g->tf[0] - g->tf[1]))
        restart = 1;
    if (restart || g->hist == 0) {
        set_cg_target(g, h);
        if ((rc = eval_field(g, st->t, st->x, g->f[0], err)) != ISO_OK)
            return rc;
        g->tf[0] = st->t;
        g->hist = 1;
        g->nstart = 1;
    }
    int k = g->hist;
    double est, *xc = g->xs;
    if ((rc = adams_predict_correct(g, k, h, st->x, xc, &est, err)) != ISO_OK)
        return rc;
    st->st.adams_order = k;
    if (k == 3) {
        st->st.max_err_estimate = fmax(st->st.max_err_estimate, est / st->diag);
        keep_estimate(g, est, h);
    } else {
        st->st.low_order_steps++;
    }
    /* PEC keeps f(x_p) as the history's newest entry, which stands for
     * f(x_c) only while the two points are close: the difference feeds
     * back into every later step, and that is why PEC's stability
     * interval is a sixth of PECE's. A step whose predictor missed by more
     * than pec_tol of the diagonal (est = |x_c − x_p| / 10, the Milne
     * estimate's measure, at any order) ends as PECE does, with f(x_c):
     * a second evaluation, inside the two a step may make. The restart's
     * step has made its two and ends PEC (iso_integrate.h). */
    int pec =
        k == 1 || (st->mode == ISO_ABM_PEC && !(st->pec_tol > 0 && est > st->pec_tol * st->diag));
    if (st->mode == ISO_ABM_PEC && !pec)
        st->st.pec_misses++;
    rc = end_step(g, st->t + h, xc, pec, err);
    if (rc == ISO_OK)
        memcpy(st->x, xc, (size_t)(3 * g->nv) * sizeof(double));
    return rc;
}

int iso_stepper_step(iso_stepper *st, double h, const iso_twist *twists, int restart, iso_err *err)
{
    if (!(h > 0) || !isfinite(h))
        return iso_err_set(err, ISO_EINVAL, -1, "step %g must be positive and finite", h);
    integ *g = &st->g;
    memcpy(st->tw, twists, (size_t)st->nh * sizeof *st->tw);
    long evals0 = g->evaluations;
    iso_solver_stats s0, s1;
    iso_solver_get_stats(g->s, &s0);
    iso_solver_budget_begin(g->s); /* one PCG budget a step (iso_solver.h) */
    int rc = stepper_advance(st, h, restart, err);
    iso_solver_budget_end(g->s);
    if (rc != ISO_OK) {
        g->hist = 0; /* the history is not to be trusted: the next step restarts */
        return rc;
    }
    /* The tick is done: its end becomes the next tick's base. */
    for (int k = 0; k < st->nh; k++) {
        iso_pose end;
        iso_twist tw;
        tick_path_eval(st, k, st->t + h, &end, &tw); /* reads base[k]: no aliasing */
        st->base[k] = end;
    }
    st->t += h;
    st->st.steps++;
    long evals = g->evaluations - evals0;
    iso_solver_get_stats(g->s, &s1);
    st->st.evaluations += evals;
    if (evals > st->st.max_step_evaluations)
        st->st.max_step_evaluations = (int)evals;
    if (s1.cg_iterations - s0.cg_iterations > st->st.max_step_cg_iterations)
        st->st.max_step_cg_iterations = s1.cg_iterations - s0.cg_iterations;
    return ISO_OK;
}

double iso_stepper_time(const iso_stepper *st)
{
    return st->t;
}

const iso_pose *iso_stepper_pose(const iso_stepper *st, int handle)
{
    return handle >= 0 && handle < st->nh ? &st->base[handle] : NULL;
}

void iso_stepper_stats(const iso_stepper *st, iso_integrate_stats *out)
{
    *out = st->st;
}
