/* solver/linsolve.c -- solving A_ff X = B: fresh factorization, or
 * conjugate gradients preconditioned by a cached factor (iso_solver.h,
 * iso_refactor).
 *
 * Why reuse: along a path A(x) changes slowly, and the factor of a recent A
 * is an excellent preconditioner for the current one (docs/performance.md,
 * "Why reuse a factor": 11 iterations to 1e-10 one step after the factor,
 * 80 ten steps after). An iteration costs one triangular solve pair and one
 * matrix-vector product, a few percent of a factorization, so reuse pays
 * while the factor is young.
 * The policy: try PCG from the previous solution; if it has not reached the
 * tolerance within cg_max_iter iterations, or stalls, factor afresh and
 * solve directly. When the previous PCG already needed most of the budget,
 * factor at once rather than spend the iterations first; abandon an attempt
 * early when its rate cannot make the budget; and learn at which age the
 * factor stops paying (see want_reuse). */
#include <dlfcn.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "iso_clock.h"
#include "solver_internal.h"
#include "supersolve_internal.h"

/* ===== threads ========================================================== */

/* Debian's CHOLMOD 3 is built with OpenMP and asks for a fixed team of
 * CHOLMOD_OMP_NUM_THREADS (4) in its supernodal scatter loops, whatever
 * OMP_NUM_THREADS says. Those loops are tiny; on two cores a team of four,
 * beside OpenBLAS's own spinning threads, spends most of the factorization
 * waking and parking threads (futex): the cactus factorization took 90-110
 * ms with the team and 43-55 ms without, and the process used 3x the CPU.
 * Capping max-active-levels at 0 runs every region on the calling thread.
 * That ICV is per thread (libgomp 12): a cap set on one thread does not
 * reach threads started later, and CHOLMOD in a new thread ran 100-330 ms
 * per cactus factorization until that thread set it itself. So the cap is
 * set on whichever thread makes the call, for the call, and put back after:
 * nothing outside the call sees it (ISO_SOLVER_OMP_CALLER).
 *
 * OpenBLAS threads pay only on large supernodes. On the benchmark meshes
 * of a few thousand vertices (0.5 GFLOP factorizations, supernodes of tens
 * of columns) a second thread gained nothing measurable (cactus: 33 ms with
 * one thread or two), and after every call it spins in sched_yield for
 * ~0.1 s, on the core the OpenCL assembly of the next evaluation wants:
 * the PoCL assembly took 28 ms beside it and 17 ms without it. OpenBLAS
 * 0.3.21 has one count for the whole process, so the solver changes it
 * only when asked (ISO_SOLVER_BLAS_SIZED), once for its lifetime; toggling
 * it around each call raced when two solvers ran in two threads.
 *
 * Both libraries are looked up rather than linked, so that a CHOLMOD
 * without OpenMP, or another BLAS, needs nothing. */

/* dlsym returns an object pointer; memcpy turns it into a function pointer
 * without the cast ISO C forbids. */
static void look_up(const char *name, void *fn, size_t fn_size)
{
    void *sym = dlsym(RTLD_DEFAULT, name);
    if (sym)
        memcpy(fn, &sym, fn_size);
}

void iso_solver__threads_begin(iso_solver *s)
{
    if (s->o.threads.omp == ISO_SOLVER_OMP_CALLER) {
        look_up("omp_get_max_active_levels", &s->omp_get_levels, sizeof s->omp_get_levels);
        look_up("omp_set_max_active_levels", &s->omp_set_levels, sizeof s->omp_set_levels);
        if (!s->omp_get_levels || !s->omp_set_levels) {
            s->omp_get_levels = NULL;
            s->omp_set_levels = NULL;
        }
    }
    if (s->o.threads.blas != ISO_SOLVER_BLAS_SIZED || s->nf == 0 ||
        (s->factor_flops >= ISO_SOLVER_BLAS_THREADED_FLOPS && s->o.worker_lag == 0))
        return;
    int (*get_threads)(void) = NULL;
    look_up("openblas_get_num_threads", &get_threads, sizeof get_threads);
    look_up("openblas_set_num_threads", &s->blas_set_threads, sizeof s->blas_set_threads);
    if (!get_threads || !s->blas_set_threads)
        return;
    int before = get_threads();
    if (before > 1) {
        s->blas_set_threads(1);
        s->blas_restore = before;
    }
}

void iso_solver__threads_end(iso_solver *s)
{
    if (s->blas_restore > 0)
        s->blas_set_threads(s->blas_restore);
    s->blas_restore = 0;
}

/* Enters a CHOLMOD call: returns the calling thread's OpenMP level cap to
 * put back after it, or -1 if there is nothing to put back. */
static int omp_begin(const iso_solver *s)
{
    if (!s->omp_set_levels)
        return -1;
    int before = s->omp_get_levels();
    if (before == 0)
        return -1;
    s->omp_set_levels(0);
    return before;
}

static void omp_end(const iso_solver *s, int before)
{
    if (before >= 0)
        s->omp_set_levels(before);
}

/* ===== factor and solve ================================================= */

/* A factorization's outcome (cholmod_factorize's result, Common->status
 * and L->minor) as a status and a message naming the row that failed. */
static int factor_outcome(const iso_solver *s, int ok, int status, long minor, iso_err *err)
{
    if (!ok || status < CHOLMOD_OK)
        return iso_err_set(err, ISO_ENUMERIC, -1, "CHOLMOD factorization failed (status %d)",
                           status);
    if (status == CHOLMOD_NOT_POSDEF || minor < 3L * s->nf) {
        int row = (int)minor;
        int f = row / 3, v = s->vert_of[f < s->nf ? f : s->nf - 1];
        return iso_err_set(err, ISO_ENUMERIC, row,
                           "%s: the free-free system is not positive definite at row %d "
                           "(vertex %d, %c component): the constraints do not pin the motion "
                           "there, or the mesh has degenerated",
                           iso_mesh_origin(s->m), row, v, "xyz"[row % 3]);
    }
    return ISO_OK;
}

static int factorize(iso_solver *s, iso_err *err)
{
    double t0 = iso_clock_now();
    int levels = omp_begin(s);
    int ok = cholmod_factorize(s->A, s->L, &s->c);
    omp_end(s, levels);
    s->st.t_factor += iso_clock_now() - t0;
    s->have_factor = 0;
    int rc = factor_outcome(s, ok, s->c.status, (long)s->L->minor, err);
    if (rc != ISO_OK)
        return rc;
    s->have_factor = 1;
    s->st.factorizations++;
    iso_solver__progress(s);
    return ISO_OK;
}

/* Z = L⁻ᵀL⁻¹ R with the cached factor: our supernodal solve
 * (supersolve_internal.h says why), else CHOLMOD's, reusing its workspace. */
static int precondition(iso_solver *s, cholmod_dense *R, cholmod_dense **Z, iso_err *err)
{
    s->st.factor_solves++;
    if (s->super_work) {
        if (!*Z && !(*Z = cholmod_zeros(s->L->n, 1, CHOLMOD_REAL, &s->c)))
            return iso_err_set(err, ISO_ENOMEM, -1, "CHOLMOD could not allocate the solution");
        /* where the C assembly runs in two halves, so do the solves (the
         * same choice every run, so the bits do not depend on timing) */
        if (!s->super_plan_made && s->cpu && iso_solver__cpu_halves(s->cpu) == 2) {
            s->super_plan = iso_solver__super_plan_create(s->L);
            s->super_plan_made = 1;
        }
        if (s->super_plan
                ? iso_solver__super_solve_split(s->L, s->super_plan, iso_solver__cpu_team(s->cpu),
                                                R->x, (*Z)->x, s->super_work) == 0
                : iso_solver__super_solve(s->L, R->x, (*Z)->x, s->super_work) == 0)
            return ISO_OK;
    }
    int levels = omp_begin(s);
    int ok = cholmod_solve2(CHOLMOD_A, s->L, R, NULL, Z, NULL, &s->Y, &s->E, &s->c);
    omp_end(s, levels);
    if (!ok || s->c.status < CHOLMOD_OK)
        return iso_err_set(err, ISO_ENUMERIC, -1, "CHOLMOD solve failed (status %d)", s->c.status);
    return ISO_OK;
}

/* PCG's preconditioner: Z = Q L⁻ᵀL⁻¹ Qᵀ R with the rotated preconditioner
 * (Q from rotations_now), else as precondition. */
static int precondition_pcg(iso_solver *s, cholmod_dense *R, cholmod_dense **Z, iso_err *err)
{
    if (!s->frame)
        return precondition(s, R, Z, err);
    cholmod_dense *T = s->work[4];
    iso_solver__rotate(s->rot, s->nf, R->x, T->x, 1);
    int rc = precondition(s, T, Z, err);
    if (rc == ISO_OK)
        iso_solver__rotate(s->rot, s->nf, (*Z)->x, (*Z)->x, 0);
    return rc;
}

/* The rotations from L's frame to this evaluation's positions. */
static void rotations_now(iso_solver *s)
{
    if (s->frame)
        iso_solver__rotations(s->frame, s->x_now, s->rot);
}

/* L is of this evaluation's matrix: so is its frame. */
static void frame_now(iso_solver *s)
{
    if (!s->frame)
        return;
    memcpy(iso_solver__frame_positions(s->frame), s->x_now, (size_t)s->nv * 3 * sizeof(double));
    iso_solver__frame_prepare(s->frame);
}

static int check_finite(const iso_solver *s, iso_err *err)
{
    const double *X = s->X->x;
    for (int i = 0; i < 3 * s->nf; i++)
        if (!isfinite(X[i]))
            return iso_err_set(err, ISO_ENUMERIC, i,
                               "the solve produced a non-finite value at row %d (vertex %d)", i,
                               s->vert_of[i / 3]);
    return ISO_OK;
}

static int direct_solve(iso_solver *s, iso_err *err)
{
    int rc = factorize(s, err);
    if (rc != ISO_OK)
        return rc;
    double t0 = iso_clock_now();
    rc = precondition(s, s->B, &s->X, err);
    frame_now(s);
    s->st.t_solve += iso_clock_now() - t0;
    s->last_cg_iters = -1;
    return rc;
}

/* y = A x with A stored as its upper triangle. */
int iso_solver__matvec(iso_solver *s, cholmod_dense *x, cholmod_dense *y, iso_err *err)
{
    double one[2] = {1, 0}, zero[2] = {0, 0};
    if (!cholmod_sdmult(s->A, 0, one, zero, x, y, &s->c))
        return iso_err_set(err, ISO_ENUMERIC, -1, "CHOLMOD sdmult failed (status %d)", s->c.status);
    return ISO_OK;
}

static int ensure_work(iso_solver *s, iso_err *err)
{
    int n = s->frame ? ISO_SOLVER__WORK : ISO_SOLVER__WORK - 1; /* the last: rotated only */
    for (int i = 0; i < n; i++)
        if (!s->work[i] &&
            !(s->work[i] = cholmod_zeros((size_t)(3 * s->nf), 1, CHOLMOD_REAL, &s->c)))
            return iso_err_set(err, ISO_ENOMEM, -1, "CHOLMOD could not allocate PCG vectors");
    size_t hn = (size_t)(3 * s->nf);
    if ((!s->hist && !(s->hist = cholmod_zeros(hn, ISO_SOLVER__HIST, CHOLMOD_REAL, &s->c))) ||
        (!s->ahist && !(s->ahist = cholmod_zeros(hn, ISO_SOLVER__HIST, CHOLMOD_REAL, &s->c))))
        return iso_err_set(err, ISO_ENOMEM, -1, "CHOLMOD could not allocate PCG vectors");
    return ISO_OK;
}

/* Iterations to reach `target` from r0 at the geometric rate shown by the
 * first k iterations (r0 → rk). */
static double predicted_iterations(double r0, double rk, int k, double target)
{
    if (!(rk < r0) || !(rk > 0))
        return rk > 0 ? HUGE_VAL : (double)k;
    double rate = log(rk / r0) / k; /* < 0 */
    return log(target / r0) / rate;
}

/* Whether this solve may not factor (iso_solver_set_bounded). */
static int bounded_now(const iso_solver *s)
{
    return s->bounded && s->w && s->have_factor && s->X;
}

/* The PCG iterations this solve may spend: cg_max_iter, or what is left of
 * an open budget (iso_solver.h). */
static int iteration_cap(const iso_solver *s)
{
    if (!s->budget_on)
        return s->o.cg_max_iter;
    int left = s->o.cg_max_iter - s->budget_used;
    if (bounded_now(s) && left < ISO_SOLVER_BOUNDED_MIN_ITERS)
        return ISO_SOLVER_BOUNDED_MIN_ITERS;
    return left > 0 ? left : 0;
}

/* The largest Euclidean norm of a free vertex's three entries of z. */
static double vertex_max(const double *z, int nf)
{
    double m = 0;
    for (int f = 0; f < nf; f++) {
        const double *q = z + 3 * f;
        m = fmax(m, sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]));
    }
    return m;
}

/* PCG's stopping test: the residual against cg_tol, before
 * preconditioning, and with a target also z's largest vertex, after it (z
 * is the next iteration's preconditioned residual anyway), whichever comes
 * first; when z ends it, z is added to x. */
typedef struct cg_goal {
    double res_target; /* ‖r‖ at which to stop: cg_tol × ‖b‖ */
    double z_target;   /* > 0: stop when vertex_max(z) reaches it */
    double z0;         /* vertex_max of the first z, for the rate */
    double res_guard;  /* bounded: ‖r‖ above which the iterate is not kept (iso_solver.h) */
} cg_goal;

static int reached_z(iso_solver *s, cg_goal *g, const double *z, int iters)
{
    if (!(g->z_target > 0))
        return 0;
    double zm = vertex_max(z, s->nf);
    if (iters == 0)
        g->z0 = zm;
    if (zm > g->z_target)
        return 0;
    double *x = s->X->x;
    for (int i = 0; i < 3 * s->nf; i++)
        x[i] += z[i];
    return 1;
}

/* Hopeless: at the rate seen so far the cap would not suffice, so stop now
 * rather than spend it (the common case when the factor is older than a few
 * small steps). The rate is read from what the tests measure: hopeless
 * only if neither would end within the cap. A bounded solve keeps its
 * iterate at the cap, so it is hopeless only when even the cap would leave
 * the residual above the guard: then it factors now, not after the cap. */
static int hopeless(const iso_solver *s, const cg_goal *g, double r0, double r, const double *z,
                    int iters, int cap)
{
    if (iters < 3)
        return 0;
    if (bounded_now(s))
        return predicted_iterations(r0, r, iters, g->res_guard) > (double)cap;
    if (predicted_iterations(r0, r, iters, g->res_target) <= (double)cap)
        return 0;
    return !(g->z_target > 0) ||
           predicted_iterations(g->z0, vertex_max(z, s->nf), iters, g->z_target) > (double)cap;
}

/* PCG from the current X. Returns 1 if converged, 0 if it should give up
 * (*capped: because of the iteration cap; else a stall or a loss of
 * positive curvature), or a negative code. */
static int pcg(iso_solver *s, int *iters, int *capped, iso_err *err)
{
    int n = 3 * s->nf, rc, cap = iteration_cap(s);
    cholmod_dense *R = s->work[0], *P = s->work[2], *AP = s->work[3];
    double *x = s->X->x, *r = R->x, *p = P->x, *ap = AP->x;
    const double *b = s->B->x;
    *iters = 0;
    *capped = 0;
    if ((rc = iso_solver__matvec(s, s->X, AP, err)) != ISO_OK ||
        (rc = iso_solver__warm_start(s, s->X, AP, err)) != ISO_OK)
        return rc;
    for (int i = 0; i < n; i++)
        r[i] = b[i] - ap[i];
    double bnorm = sqrt(iso_solver__dot(b, b, n)), scale = bnorm > 0 ? bnorm : 1.0;
    cg_goal g = {s->o.cg_tol * scale, s->cg_target, 0, ISO_SOLVER_BOUNDED_RES * scale};
    double rnorm = sqrt(iso_solver__dot(r, r, n)), prev = rnorm, r0norm = rnorm;
    s->last_res = rnorm / scale;
    if (rnorm <= g.res_target)
        return 1;
    rotations_now(s);
    if ((rc = precondition_pcg(s, R, &s->work[1], err)) != ISO_OK)
        return rc;
    double *z = s->work[1]->x;
    if (reached_z(s, &g, z, 0))
        return 1;
    memcpy(p, z, (size_t)n * sizeof(double));
    double rz = iso_solver__dot(r, z, n);
    int slow = 0;
    while (*iters < cap) {
        if ((rc = iso_solver__matvec(s, P, AP, err)) != ISO_OK)
            return rc;
        double pap = iso_solver__dot(p, ap, n);
        if (!(pap > 0) || !(rz > 0))
            return 0;
        double alpha = rz / pap;
        for (int i = 0; i < n; i++) {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        ++*iters;
        iso_solver__progress(s);
        rnorm = sqrt(iso_solver__dot(r, r, n));
        s->last_res = rnorm / scale;
        if (rnorm <= g.res_target)
            return 1;
        /* Stalled: three iterations in a row that gained less than 10%. */
        slow = rnorm > 0.9 * prev ? slow + 1 : 0;
        if (slow >= 3)
            return 0;
        prev = rnorm;
        if (!(g.z_target > 0) && hopeless(s, &g, r0norm, rnorm, NULL, *iters, cap))
            return *capped = 1, 0;
        if ((rc = precondition_pcg(s, R, &s->work[1], err)) != ISO_OK)
            return rc;
        z = s->work[1]->x;
        if (reached_z(s, &g, z, *iters))
            return 1;
        if (g.z_target > 0 && hopeless(s, &g, r0norm, rnorm, z, *iters, cap))
            return *capped = 1, 0;
        double rz_new = iso_solver__dot(r, z, n);
        double beta = rz_new / rz;
        rz = rz_new;
        for (int i = 0; i < n; i++)
            p[i] = z[i] + beta * p[i];
    }
    *capped = 1;
    return 0;
}

/* Whether to try PCG with the cached factor this evaluation.
 *
 * The factor's age (evaluations since it was computed) is what decides
 * whether it still preconditions well, and along one path the age at which
 * it stops doing so is steady, so the solver learns it: after an attempt
 * fails at age a, only ages below a are tried (never less than 1), and
 * every eighth factorization one age more is probed. Under the offline
 * integrator's PECE steps this settles on the pattern that pays: factor at
 * the predicted point, and reuse that factor at the corrected point, which
 * differs from it by the local error only (cactus: 8 iterations or fewer),
 * instead of spending iterations on a factor a whole step old. The older
 * rule, a back-off of 1, 2, 4, ... evaluations after each failure, skipped
 * exactly those cheap corrector solves. Only when even age 1 keeps failing
 * (steps so large that the corrector moves far from the predictor) does it
 * still back off, so that hopeless attempts stay rare. */
static int want_reuse(iso_solver *s)
{
    if (s->o.refactor != ISO_REFACTOR_ADAPTIVE || !s->have_factor || !s->X)
        return 0;
    if (bounded_now(s))
        return 1;
    if (iteration_cap(s) == 0) { /* the tick's budget is spent: the stated fallback */
        s->st.refactors++;
        s->st.cg_capped++;
        return 0;
    }
    if (s->last_cg_iters >= (3 * s->o.cg_max_iter) / 4)
        return 0; /* the previous solve nearly spent the budget: refactor now */
    if (s->w)
        return 1; /* the worker keeps the factor young; no horizon to learn */
    if (s->reuse_horizon > 0 && s->factor_age > s->reuse_horizon)
        return 0;
    if (s->cg_skip > 0) {
        s->cg_skip--;
        return 0;
    }
    return 1;
}

static void learn_from_attempt(iso_solver *s, int converged)
{
    int age = s->factor_age;
    if (converged) {
        s->cg_failures = 0;
        return;
    }
    s->reuse_horizon = age > 2 ? age - 1 : 1;
    s->horizon_probe = 8;
    if (age > 1)
        return;
    s->cg_failures++;
    if (s->cg_failures >= 3)
        s->cg_skip = s->cg_failures >= 7 ? 16 : 1 << (s->cg_failures - 3);
}

/* A learned horizon is probed one evaluation further every eighth
 * factorization, so that it can grow again when the steps shrink. */
static void after_factorization(iso_solver *s)
{
    if (s->x_factor && s->x_now) {
        memcpy(s->x_factor, s->x_now, (size_t)s->nv * 3 * sizeof(double));
        s->have_x_factor = 1;
    }
    s->factor_age = 0;
    s->budget_used = 0; /* the fresh factor starts the count again (iso_solver.h) */
    if (s->reuse_horizon > 0 && s->horizon_probe > 0 && --s->horizon_probe == 0) {
        s->reuse_horizon++;
        s->horizon_probe = 8;
    }
}

/* ===== the factorization worker (worker.c) ============================== */

/* The policy, in evaluation counts only, so that the bits never depend on
 * how fast the worker was: an evaluation whose factor is not of its own
 * matrix (age ≥ 1) and finds the worker idle gives it, after its solve, a
 * matrix to factor: its own, or with worker_ahead the one assembled at the
 * positions extrapolated to the middle of the factor's service (ahead);
 * worker_lag evaluations later that factor is handed over (the evaluation
 * waits for it if need be) with age worker_lag. So on a smooth path the
 * factor in use is worker_lag to 2 worker_lag − 1 evaluations old, and no
 * evaluation factors on its own thread unless PCG fails (the stated
 * fallback, want_reuse). A factor the evaluating thread made after the
 * job was given is younger than the worker's, which is then not taken. */
static int worker_take(iso_solver *s, iso_err *err)
{
    if (s->w_left == 0 || --s->w_left > 0)
        return ISO_OK;
    int lag = s->o.worker_lag, take = !s->have_factor || s->factor_age > lag;
    double t0 = iso_clock_now(), busy = 0;
    int status = 0;
    long minor = 0;
    int ok =
        iso_solver__worker_finish(s->w, take ? &s->L : NULL, &s->frame, &status, &minor, &busy);
    s->st.t_wait += iso_clock_now() - t0;
    s->st.t_worker += busy;
    if (!take)
        return ISO_OK;
    s->have_factor = 0;
    int rc = factor_outcome(s, ok, status, minor, err);
    if (rc != ISO_OK)
        return rc;
    s->have_factor = 1;
    s->factor_age = lag;
    s->st.handovers++;
    double *t = s->x_factor; /* the job's positions are the factor's now */
    s->x_factor = s->x_job;
    s->x_job = t;
    s->have_x_factor = 1;
    return ISO_OK;
}

/* The positions k evaluations after this one, by the polynomial through
 * this one's and (as many as there are) the last two's, into x_seen[2]:
 *     x + k d1 + k (k + 1) / 2 (d1 − d0),  d1 = x − x₋₁, d0 = x₋₁ − x₋₂.
 * Quadratic, because a turning ring's points move on circles, which a
 * straight line leaves at once (at lag 4 on the cactus: 236 against 259
 * CG iterations). */
static const double *ahead(iso_solver *s, double k)
{
    const double *x = s->x_now, *p = s->x_seen[0], *q = s->x_seen[1];
    double *y = s->x_seen[2];
    for (int i = 0; i < 3 * s->nv; i++) {
        double d1 = s->n_seen > 0 ? x[i] - p[i] : 0;
        double d0 = s->n_seen > 1 ? p[i] - q[i] : d1;
        y[i] = x[i] + k * d1 + 0.5 * k * (k + 1) * (d1 - d0);
    }
    return y;
}

/* Would a matrix at x be the factor's own (ISO_SOLVER_SAME_MATRIX)? */
static int near_factor(const iso_solver *s, const double *x)
{
    if (!s->have_x_factor)
        return 0;
    for (int i = 0; i < 3 * s->nv; i++)
        if (!(fabs(x[i] - s->x_factor[i]) <= s->same_move))
            return 0;
    return 1;
}

/* After this evaluation's solve: a new job if the worker is idle and the
 * factor is not of this matrix; with worker_ahead, its matrix assembled at
 * the extrapolated positions (this evaluation's A and B are spent). */
static int worker_give(iso_solver *s, iso_err *err)
{
    if (s->w_left != 0 || !s->have_factor || s->factor_age < 1)
        return ISO_OK;
    const double *x = s->x_now;
    if (s->o.worker_ahead)
        x = ahead(s, 1.5 * s->o.worker_lag - 0.5);
    if (near_factor(s, x)) {
        s->st.worker_idle++;
        return ISO_OK;
    }
    if (s->o.worker_ahead) {
        double t0 = iso_clock_now();
        int rc = iso_solver__assemble(s, x, s->vc_now, err);
        s->st.t_assembly += iso_clock_now() - t0;
        if (rc != ISO_OK)
            return rc;
    }
    iso_solver__worker_start(s->w, s->A, x);
    memcpy(s->x_job, x, (size_t)s->nv * 3 * sizeof(double));
    s->w_left = s->o.worker_lag;
    return ISO_OK;
}

/* This evaluation's positions join the look-ahead's history. */
static void remember_positions(iso_solver *s)
{
    if (!s->x_seen[0])
        return;
    double *t = s->x_seen[1];
    s->x_seen[1] = s->x_seen[0];
    s->x_seen[0] = t;
    memcpy(t, s->x_now, (size_t)s->nv * 3 * sizeof(double));
    s->n_seen += s->n_seen < 2;
}

/* PCG with the cached factor: 1 when it converged or (bounded) kept an
 * iterate below the guard, 0 when the caller should factor, or a negative
 * code. */
static int reuse(iso_solver *s, iso_err *err)
{
    int rc = ensure_work(s, err);
    if (rc != ISO_OK)
        return rc;
    int iters = 0, capped = 0;
    double t0 = iso_clock_now();
    rc = pcg(s, &iters, &capped, err);
    s->st.t_solve += iso_clock_now() - t0;
    s->st.cg_iterations += iters;
    s->budget_used += iters;
    if (rc < 0)
        return rc;
    learn_from_attempt(s, rc == 1);
    if (rc == 1 || (bounded_now(s) && s->last_res <= ISO_SOLVER_BOUNDED_RES)) {
        if (rc != 1) { /* the best iterate: the bounded solve's answer */
            s->st.inexact++;
            s->st.inexact_res_max = fmax(s->st.inexact_res_max, s->last_res);
        }
        s->last_cg_iters = iters;
        return 1;
    }
    s->st.cg_capped += capped;
    return 0;
}

/* A fresh factor or PCG with the cached one (want_reuse). */
static int solve(iso_solver *s, iso_err *err)
{
    if (want_reuse(s)) {
        int rc = reuse(s, err);
        if (rc < 0)
            return rc;
        if (rc == 1)
            return check_finite(s, err);
        s->st.refactors++;
    }
    int rc = direct_solve(s, err);
    if (rc != ISO_OK)
        return rc;
    after_factorization(s);
    return check_finite(s, err);
}

int iso_solver__factor_now(iso_solver *s, iso_err *err)
{
    if (!s->X && !(s->X = cholmod_zeros((size_t)(3 * s->nf), 1, CHOLMOD_REAL, &s->c)))
        return iso_err_set(err, ISO_ENOMEM, -1, "CHOLMOD could not allocate the solution");
    int rc = factorize(s, err);
    if (rc != ISO_OK)
        return rc;
    frame_now(s);
    after_factorization(s);
    s->last_cg_iters = -1;
    return ISO_OK;
}

int iso_solver__linsolve(iso_solver *s, iso_err *err)
{
    int rc = ISO_OK;
    if (s->have_factor)
        s->factor_age++;
    if (s->w)
        rc = worker_take(s, err);
    if (rc == ISO_OK)
        rc = solve(s, err);
    if (rc == ISO_OK && s->w)
        rc = worker_give(s, err);
    if (rc == ISO_OK)
        iso_solver__warm_remember(s);
    remember_positions(s);
    return rc;
}

/* ===== the integrator's settings (iso_solver.h) ========================= */

void iso_solver_set_cg_target(iso_solver *s, double target)
{
    s->cg_target = target > 0 && isfinite(target) ? target : 0.0;
}

void iso_solver_set_bounded(iso_solver *s, int on)
{
    s->bounded = on != 0;
}

void iso_solver_budget_begin(iso_solver *s)
{
    s->budget_on = 1;
    s->budget_used = 0;
}

void iso_solver_budget_end(iso_solver *s)
{
    s->budget_on = 0;
    s->budget_used = 0;
}
