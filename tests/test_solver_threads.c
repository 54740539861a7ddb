/* tests/test_solver_threads.c -- solvers in two threads are independent,
 * and the library leaves the process's thread settings alone unless asked.
 *
 * Two deformations (a cactus and a bar, each with the adaptive scheme so
 * that factorizations and PCG solves interleave) are integrated one at a
 * time, then both at once in two threads, then the cactus twice at once on
 * one shared mesh: every result must be bit-identical to the one-at-a-time
 * run. A solver's own factorization worker (worker_lag) is held to the
 * same: its runs give the same bits alone and beside another. The BLAS runs
 * on one thread, as the solver's header asks of a
 * program that runs solvers in several threads (CTest also sets
 * OPENBLAS_NUM_THREADS=1): OpenBLAS's threaded kernels round differently.
 *
 * The reduced model's prolongation and fit, which run in halves on the
 * proxy's own two-thread team for a large mesh, give the same bits at
 * every call; so do the assembly and the triangular solves in halves on a
 * solver's team (ISO_SOLVER_SPLIT_ALWAYS), alone and beside another.
 *
 * The same program is built with ThreadSanitizer as test_solver_threads_tsan
 * (tests/CMakeLists.txt). */
#include <dirent.h>
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_integrate.h"
#include "iso_proxy.h"
#include "iso_shapes.h"
#include "iso_solver.h"
#include "testutil.h"

/* ---- one deformation ---------------------------------------------------- */

typedef struct problem {
    const char *shape;
    int resolution;
    iso_shape sh;
    iso_mesh *mesh;
    iso_regions reg;
    iso_twist xi;
} problem;

typedef struct run {
    const problem *p;
    iso_refactor refactor;
    int worker_lag;         /* iso_solver_opts.worker_lag */
    int steps;              /* fixed ABM steps; 0: 6 */
    iso_solver_split split; /* the assembly's and the solves' halves */
    double *x;              /* final positions, 3 nv */
    iso_solver_stats st;
    int rc;
    iso_err err;
} run;

static void problem_init(problem *p, const char *shape, int resolution)
{
    iso_err err;
    iso_err_clear(&err);
    memset(p, 0, sizeof *p);
    p->shape = shape;
    p->resolution = resolution;
    if (iso_shape_init(&p->sh, shape, resolution, &err) != ISO_OK ||
        iso_mesh_create(p->sh.nv, p->sh.x, p->sh.nt, p->sh.tri, shape, &p->mesh, &err) != ISO_OK ||
        iso_shape_regions(&p->sh, &p->reg, &err) != ISO_OK ||
        iso_twist_from_matrix(p->sh.M, &p->xi, &err) != ISO_OK)
        fail_msg("%s: %s", shape, err.msg);
}

static void problem_deinit(problem *p)
{
    iso_mesh_destroy(p->mesh);
    iso_regions_deinit(&p->reg);
    iso_shape_deinit(&p->sh);
}

/* Six (or r->steps) fixed ABM steps along the shape's screw path, adaptive refactoring. */
static void *run_main(void *arg)
{
    run *r = arg;
    const problem *p = r->p;
    iso_err_clear(&r->err);
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.refactor = r->refactor;
    so.worker_lag = r->worker_lag;
    so.threads.split = r->split;
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.steps = r->steps > 0 ? r->steps : 6;
    iso_twist tw[1] = {p->xi};
    iso_screw_path sp = {tw, 1};
    iso_path path = iso_screw_path_make(&sp);
    int nv = iso_mesh_vertex_count(p->mesh);
    iso_solver *s = NULL;
    iso_integrate_stats ist;
    r->x = malloc((size_t)nv * 3 * sizeof *r->x);
    if (!r->x) {
        r->rc = ISO_ENOMEM;
        return NULL;
    }
    memcpy(r->x, iso_mesh_positions(p->mesh), (size_t)nv * 3 * sizeof *r->x);
    r->rc = iso_solver_create(p->mesh, &p->reg, &so, &s, &r->err);
    if (r->rc == ISO_OK)
        r->rc = iso_integrate(s, p->mesh, &p->reg, &path, &io, r->x, &ist, &r->err);
    if (s)
        iso_solver_get_stats(s, &r->st);
    iso_solver_destroy(s);
    return NULL;
}

/* A run of p with the adaptive scheme and this worker lag, not started. */
static run make_run(const problem *p, int worker_lag)
{
    run r;
    memset(&r, 0, sizeof r);
    r.p = p;
    r.refactor = ISO_REFACTOR_ADAPTIVE;
    r.worker_lag = worker_lag;
    return r;
}

static void run_now(run *r)
{
    run_main(r);
    if (r->rc != ISO_OK)
        fail_msg("%s: %s", r->p->shape, r->err.msg);
}

/* Runs a and b at the same time, each in a thread of its own. */
static void run_pair(run *a, run *b)
{
    pthread_t ta, tb;
    assert_int_equal(pthread_create(&ta, NULL, run_main, a), 0);
    assert_int_equal(pthread_create(&tb, NULL, run_main, b), 0);
    assert_int_equal(pthread_join(ta, NULL), 0);
    assert_int_equal(pthread_join(tb, NULL), 0);
    if (a->rc != ISO_OK || b->rc != ISO_OK)
        fail_msg("%s: %s / %s: %s", a->p->shape, a->err.msg, b->p->shape, b->err.msg);
}

static void assert_same(const run *alone, const run *beside)
{
    int nv = iso_mesh_vertex_count(alone->p->mesh);
    /* the counts say whether another path was taken (a factorization
     * instead of a PCG solve, another ordering) or the same path rounded
     * otherwise */
    if (memcmp(alone->x, beside->x, (size_t)nv * 3 * sizeof(double)) != 0)
        fail_msg("%s: in a thread beside another solver the result differs by %g (alone / "
                 "beside: %ld / %ld factorizations, %ld / %ld CG iterations, %ld / %ld solves "
                 "with a factor, nnz(L) %ld / %ld)",
                 alone->p->shape, iso_test_max_abs_diff(alone->x, beside->x, (size_t)nv * 3),
                 alone->st.factorizations, beside->st.factorizations, alone->st.cg_iterations,
                 beside->st.cg_iterations, alone->st.factor_solves, beside->st.factor_solves,
                 alone->st.nnz_l, beside->st.nnz_l);
    assert_int_equal(alone->st.evaluations, beside->st.evaluations);
    assert_int_equal(alone->st.factorizations, beside->st.factorizations);
    assert_int_equal(alone->st.cg_iterations, beside->st.cg_iterations);
    assert_int_equal(alone->st.handovers, beside->st.handovers);
}

/* The C assembly and the triangular solves in halves on the solver's team
 * (ISO_SOLVER_SPLIT_ALWAYS, as the tick engine steps a proxy), with a
 * factorization worker beside them: the same bits run to run and in a
 * thread beside another solver, and within rounding of one thread's
 * result. Under TSan (test_solver_threads_tsan) the halves' writes are
 * checked for races. */
static void split_halves_are_deterministic(void **state)
{
    (void)state;
    problem cactus;
    problem_init(&cactus, "cactus", 1);
    run one = make_run(&cactus, 2), a = make_run(&cactus, 2), b = make_run(&cactus, 2),
        c = make_run(&cactus, 2);
    a.split = b.split = c.split = ISO_SOLVER_SPLIT_ALWAYS;
    run_now(&one);
    run_now(&a);
    run_pair(&b, &c);
    assert_same(&a, &b);
    assert_same(&a, &c);
    int nv = iso_mesh_vertex_count(cactus.mesh);
    double d = iso_test_max_abs_diff(a.x, one.x, (size_t)nv * 3),
           m = iso_test_max_abs(one.x, (size_t)nv * 3);
    printf("cactus in halves against one thread: %.3g of %.3g\n", d, m);
    assert_true(d <= 1e-9 * m);
    free(one.x), free(a.x), free(b.x), free(c.x);
    problem_deinit(&cactus);
}

/* ---- the process's thread controls, looked up as the solver does -------- */

typedef struct controls {
    int (*blas_get)(void);
    void (*blas_set)(int);
    int (*omp_get)(void);
} controls;

static void look_up(const char *name, void *fn, size_t size)
{
    void *sym = dlsym(RTLD_DEFAULT, name);
    if (sym)
        memcpy(fn, &sym, size);
}

static controls find_controls(void)
{
    controls c = {0};
    look_up("openblas_get_num_threads", &c.blas_get, sizeof c.blas_get);
    look_up("openblas_set_num_threads", &c.blas_set, sizeof c.blas_set);
    look_up("omp_get_max_active_levels", &c.omp_get, sizeof c.omp_get);
    if (!c.blas_get || !c.blas_set) {
        c.blas_get = NULL;
        c.blas_set = NULL;
    }
    return c;
}

/* ---- tests -------------------------------------------------------------- */

static void two_solvers_match_one_at_a_time(void **state)
{
    (void)state;
    problem cactus, bar;
    problem_init(&cactus, "cactus", 1);
    problem_init(&bar, "bar", 6);
    run cactus_alone = make_run(&cactus, 0), bar_alone = make_run(&bar, 0);
    run_now(&cactus_alone);
    run_now(&bar_alone);
    assert_true(cactus_alone.st.factorizations > 0);
    assert_true(cactus_alone.st.cg_iterations > 0); /* PCG ran, not only factorizations */

    run cactus_beside = make_run(&cactus, 0), bar_beside = make_run(&bar, 0);
    run_pair(&cactus_beside, &bar_beside);
    assert_same(&cactus_alone, &cactus_beside);
    assert_same(&bar_alone, &bar_beside);
    free(cactus_beside.x);
    free(bar_beside.x);

    /* Both threads on one mesh and one set of regions: the solver only
     * reads them. */
    cactus_beside = make_run(&cactus, 0);
    run again = make_run(&cactus, 0);
    run_pair(&cactus_beside, &again);
    assert_same(&cactus_alone, &cactus_beside);
    assert_same(&cactus_alone, &again);

    free(cactus_beside.x);
    free(again.x);
    free(cactus_alone.x);
    free(bar_alone.x);
    problem_deinit(&cactus);
    problem_deinit(&bar);
}

/* The bounding-box diagonal of p's rest pose. */
static double diagonal(const problem *p)
{
    int nv = iso_mesh_vertex_count(p->mesh);
    const double *x = iso_mesh_positions(p->mesh);
    double lo[3] = {x[0], x[1], x[2]}, hi[3] = {x[0], x[1], x[2]}, d2 = 0;
    for (int i = 1; i < nv; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], x[3 * i + a]);
            hi[a] = fmax(hi[a], x[3 * i + a]);
        }
    for (int a = 0; a < 3; a++)
        d2 += (hi[a] - lo[a]) * (hi[a] - lo[a]);
    return sqrt(d2);
}

/* With the factorization worker (worker_lag), which factor serves which
 * evaluation is fixed by evaluation counts, so a run gives the same bits
 * whether its worker was early or late: alone, and beside a second worker
 * run in another thread that competes for the cores (and, as
 * test_solver_threads_tsan, under ThreadSanitizer, which also slows every
 * thread differently). Its accuracy is the integrator's to set (the CG
 * target, iso_integrate.h): against the same steps solved by a fresh
 * factorization every evaluation (exact to rounding), the result differs
 * by a small part of the integrator's own error, measured against a run at
 * 8 times the steps. The target asks for a tenth of each step's Milne
 * estimate, and over these six large steps the estimate is rough, so this
 * test bounds the part by a half; test_loop holds the tenth on the cactus
 * scene at 60 Hz, with the worker too. */
static void worker_is_deterministic_and_accurate(void **state)
{
    (void)state;
    problem cactus, bar;
    problem_init(&cactus, "cactus", 1);
    problem_init(&bar, "bar", 6);
    size_t n = (size_t)iso_mesh_vertex_count(cactus.mesh) * 3;
    double diag = diagonal(&cactus);
    run paper = make_run(&cactus, 0), fine = make_run(&cactus, 0);
    paper.refactor = fine.refactor = ISO_REFACTOR_ALWAYS;
    fine.steps = 8 * 6;
    run_now(&paper);
    run_now(&fine);
    double own = iso_test_max_abs_diff(paper.x, fine.x, n) / diag;
    for (int lag = 1; lag <= 3; lag += 2) {
        run alone = make_run(&cactus, lag);
        run_now(&alone);
        assert_true(alone.st.handovers > 0);
        assert_true(alone.st.t_worker > 0);

        run beside = make_run(&cactus, lag), other = make_run(&bar, lag);
        run_pair(&beside, &other);
        assert_same(&alone, &beside);

        double dev = iso_test_max_abs_diff(alone.x, paper.x, n) / diag;
        printf("worker lag %d: %ld handovers, %ld factorizations on the evaluating thread, "
               "%ld CG iterations; against a fresh factorization each evaluation %.2e of the "
               "diagonal, %.3f of the integrator's own error (%.2e)\n",
               lag, alone.st.handovers, alone.st.factorizations, alone.st.cg_iterations, dev,
               dev / own, own);
        assert_true(dev < 0.5 * own);
        free(alone.x);
        free(beside.x);
        free(other.x);
    }
    free(paper.x);
    free(fine.x);
    problem_deinit(&cactus);
    problem_deinit(&bar);
}

/* A mesh at rest gives the worker nothing to do: every evaluation at the
 * same positions (handles still) finds its matrix the factor's own
 * (ISO_SOLVER_SAME_MATRIX), so no job is given and none handed over;
 * positions that move give it a job again. */
static void a_mesh_at_rest_leaves_the_worker_idle(void **state)
{
    (void)state;
    problem cactus;
    problem_init(&cactus, "cactus", 1);
    int nv = iso_mesh_vertex_count(cactus.mesh);
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    o.refactor = ISO_REFACTOR_ADAPTIVE;
    o.worker_lag = 2;
    iso_solver *s = NULL;
    iso_err err;
    assert_int_equal(iso_solver_create(cactus.mesh, &cactus.reg, &o, &s, &err), ISO_OK);
    double *x = malloc(3 * (size_t)nv * sizeof *x), *vc = calloc(3 * (size_t)nv, sizeof *vc),
           *v = malloc(3 * (size_t)nv * sizeof *v);
    assert_true(x && vc && v);
    memcpy(x, iso_mesh_positions(cactus.mesh), 3 * (size_t)nv * sizeof *x);
    for (int k = 0; k < 12; k++)
        assert_int_equal(iso_solver_field(s, x, vc, v, &err), ISO_OK);
    iso_solver_stats at_rest;
    iso_solver_get_stats(s, &at_rest);
    double step = 1e-3 * diagonal(&cactus); /* a bend's worth: the free vertices lean */
    for (int k = 0; k < 12; k++) {
        for (int i = 0; i < nv; i++)
            if (cactus.reg.kind[i] == ISO_FREE)
                x[3 * i] += step * x[3 * i + 2];
        assert_int_equal(iso_solver_field(s, x, vc, v, &err), ISO_OK);
    }
    iso_solver_stats moving;
    iso_solver_get_stats(s, &moving);
    printf("at rest: %ld jobs left undone, %ld handed over, %ld factorizations; moving: %ld "
           "more handed over\n",
           at_rest.worker_idle, at_rest.handovers, at_rest.factorizations,
           moving.handovers - at_rest.handovers);
    assert_int_equal(at_rest.handovers, 0);
    assert_int_equal(at_rest.factorizations, 1); /* the first evaluation's */
    assert_true(at_rest.worker_idle >= 10);
    assert_true(moving.handovers > at_rest.handovers);
    free(x);
    free(vc);
    free(v);
    iso_solver_destroy(s);
    problem_deinit(&cactus);
}

/* The defaults change nothing the caller could see: OpenBLAS's count and
 * the calling thread's OpenMP level cap are what they were. */
static void defaults_leave_settings_alone(void **state)
{
    (void)state;
    controls c = find_controls();
    if (!c.blas_get && !c.omp_get)
        skip(); /* neither OpenBLAS nor OpenMP in this process: nothing to watch */
    problem bar;
    problem_init(&bar, "bar", 4);
    int blas_before = c.blas_get ? c.blas_get() : 0;
    if (c.blas_set)
        c.blas_set(2);
    int omp_before = c.omp_get ? c.omp_get() : 0;
    run r = make_run(&bar, 0);
    run_now(&r);
    if (c.blas_get)
        assert_int_equal(c.blas_get(), 2);
    if (c.omp_get)
        assert_int_equal(c.omp_get(), omp_before);
    if (c.blas_set)
        c.blas_set(blas_before);
    free(r.x);
    problem_deinit(&bar);
}

/* ISO_SOLVER_BLAS_SIZED: one thread while a small system's solver exists,
 * the count it found once it is gone. A large system (the built-in
 * bumpplane) keeps the count, unless the solver has a factorization
 * worker: then one thread too. */
static void sized_blas_lasts_the_solver_lifetime(void **state)
{
    (void)state;
    controls c = find_controls();
    if (!c.blas_get) {
        printf("SKIP: this process's BLAS is not OpenBLAS (no openblas_set_num_threads)\n");
        skip();
    }
    problem bar;
    problem_init(&bar, "bar", 4);
    int before = c.blas_get();
    c.blas_set(2);
    iso_err err;
    iso_err_clear(&err);
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.threads.blas = ISO_SOLVER_BLAS_SIZED;
    iso_solver *s = NULL;
    assert_int_equal(iso_solver_create(bar.mesh, &bar.reg, &so, &s, &err), ISO_OK);
    assert_true(iso_solver_factor_flops(s) < ISO_SOLVER_BLAS_THREADED_FLOPS);
    assert_int_equal(c.blas_get(), 1);
    iso_solver_destroy(s);
    assert_int_equal(c.blas_get(), 2);
    problem plane;
    problem_init(&plane, "bumpplane", 150); /* ~6 GFLOP a factorization */
    for (int lag = 0; lag <= 4; lag += 4) {
        so.refactor = ISO_REFACTOR_ADAPTIVE;
        so.worker_lag = lag;
        assert_int_equal(iso_solver_create(plane.mesh, &plane.reg, &so, &s, &err), ISO_OK);
        assert_true(iso_solver_factor_flops(s) >= ISO_SOLVER_BLAS_THREADED_FLOPS);
        assert_int_equal(c.blas_get(), lag > 0 ? 1 : 2);
        iso_solver_destroy(s);
        assert_int_equal(c.blas_get(), 2);
    }
    c.blas_set(before);
    problem_deinit(&plane);
    problem_deinit(&bar);
}

/* The threads this process has now (its /proc/self/task entries), or -1
 * where /proc is not there. */
static int thread_count(void)
{
    DIR *d = opendir("/proc/self/task");
    if (!d)
        return -1;
    int n = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;)
        n += e->d_name[0] != '.';
    closedir(d);
    return n;
}

/* A non-rigid motion of the tentacle (its axis is z, the body z in
 * [-3, 3]): a twist about the axis that grows with height, a swelling that
 * grows with it too, and a sideways shear, so that every ring rotation
 * differs and the fit has work to do. */
static void twist_and_swell(const double *p, double *q)
{
    double a = 0.12 * (p[2] + 4), c = cos(a), s = sin(a), w = 1 + 0.03 * (p[2] + 4);
    q[0] = w * (c * p[0] - s * p[1]) + 0.02 * p[2] * p[2];
    q[1] = w * (s * p[0] + c * p[1]);
    q[2] = p[2];
}

/* The reduced model's prolongation and its fit (solver/proxy.c,
 * proxy_fit.c) run their halves on the proxy's own team, the caller and a
 * helper thread, for a mesh of ISO_SOLVER_CPU_SPLIT_EDGES / 3 (20,000)
 * vertices and more: the tentacle at 48 has 23,042. Every call on the same
 * input is the same bits, whichever half finishes first; and under
 * ThreadSanitizer each of the fit's phases (CG steps that read the
 * neighbours' entries the other half wrote in the phase before) is
 * checked for a race. The handles go where their pose takes them, the
 * fixed region stays, the free proxy vertices move by twist_and_swell. */
static void proxy_prolongation_on_its_team_is_deterministic(void **state)
{
    (void)state;
    problem t;
    problem_init(&t, "tentacle", 48);
    int nv = iso_mesh_vertex_count(t.mesh);
    assert_int_equal(nv, 23042);
    iso_err err;
    iso_err_clear(&err);
    int before = thread_count();
    iso_proxy *px = NULL;
    if (iso_proxy_create(t.mesh, &t.reg, 2000, &px, &err) != ISO_OK)
        fail_msg("tentacle 48, budget 2000: %s", err.msg);
    int after = thread_count();
    if (before >= 0) /* the proxy's team started its helper: the halves run in two threads */
        assert_true(after >= before + 1);
    const iso_mesh *pm = iso_proxy_mesh(px);
    const iso_regions *pr = iso_proxy_regions(px);
    int np = iso_mesh_vertex_count(pm);
    assert_true(np <= 2000);
    iso_twist xi = {{0.0, 0.0, 0.3}, {0.1, 0.0, 0.2}};
    iso_pose g;
    iso_twist_exp(&xi, 1.0, &g);
    assert_int_equal(pr->n_handles, 1);
    const double *Y = iso_mesh_positions(pm);
    size_t n = 3 * (size_t)nv;
    double *y = malloc(3 * (size_t)np * sizeof *y), *x0 = malloc(n * sizeof *x0),
           *x = malloc(n * sizeof *x);
    assert_true(y && x0 && x);
    for (int k = 0; k < np; k++)
        if (pr->kind[k] == ISO_HANDLE)
            iso_pose_apply(&g, Y + 3 * k, y + 3 * k);
        else if (pr->kind[k] == ISO_FIXED)
            memcpy(y + 3 * k, Y + 3 * k, 3 * sizeof *y);
        else
            twist_and_swell(Y + 3 * k, y + 3 * k);
    iso_proxy_prolong(px, y, &g, x0);
    const double *X = iso_mesh_positions(t.mesh);
    double moved = iso_test_max_abs_diff(x0, X, n);
    assert_true(moved > 0.1); /* the motion reached the full mesh */
    for (int call = 1; call < 4; call++) {
        memset(x, 0, n * sizeof *x);
        iso_proxy_prolong(px, y, &g, x);
        if (memcmp(x0, x, n * sizeof *x) != 0)
            fail_msg("prolongation %d differs from the first by %g", call + 1,
                     iso_test_max_abs_diff(x0, x, n));
    }
    iso_proxy_stats st;
    iso_proxy_get_stats(px, &st);
    printf("tentacle %d vertices through %d proxy vertices, the halves on the caller and the "
           "proxy's helper: 4 prolongations, the same bits; the fit took %ld iterations (at most "
           "%ld in one), %ld failures\n",
           nv, np, st.fit_iterations, st.fit_max_iterations, st.fit_failures);
    assert_int_equal(st.prolongations, 4);
    assert_int_equal(st.fit_failures, 0);
    assert_true(st.fit_iterations >= 4); /* the fit ran at every call */
    free(y);
    free(x0);
    free(x);
    iso_proxy_destroy(px);
    problem_deinit(&t);
}

static void bad_thread_policy_is_refused(void **state)
{
    (void)state;
    problem bar;
    problem_init(&bar, "bar", 4);
    iso_err err;
    iso_err_clear(&err);
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.threads.blas = (iso_solver_blas)7;
    iso_solver *s = NULL;
    assert_int_equal(iso_solver_create(bar.mesh, &bar.reg, &so, &s, &err), ISO_EINVAL);
    assert_null(s);
    assert_non_null(strstr(err.msg, "BLAS thread policy 7"));
    so.threads.blas = ISO_SOLVER_BLAS_LEAVE;
    so.worker_lag = 2; /* the paper's scheme has no factor to hand over */
    iso_err_clear(&err);
    assert_int_equal(iso_solver_create(bar.mesh, &bar.reg, &so, &s, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "only the adaptive scheme"));
    so.refactor = ISO_REFACTOR_ADAPTIVE;
    so.worker_lag = ISO_SOLVER_WORKER_LAG_MAX + 1;
    iso_err_clear(&err);
    assert_int_equal(iso_solver_create(bar.mesh, &bar.reg, &so, &s, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "worker_lag = 101 is outside [0, 100]"));
    assert_null(s);
    problem_deinit(&bar);
}

int main(void)
{
    /* The program's choice, made once before any thread solves (see the
     * file's comment): one BLAS thread. */
    controls c = find_controls();
    if (c.blas_set)
        c.blas_set(1);
    const struct CMUnitTest t[] = {
        cmocka_unit_test(two_solvers_match_one_at_a_time),
        cmocka_unit_test(split_halves_are_deterministic),
        cmocka_unit_test(worker_is_deterministic_and_accurate),
        cmocka_unit_test(a_mesh_at_rest_leaves_the_worker_idle),
        cmocka_unit_test(defaults_leave_settings_alone),
        cmocka_unit_test(sized_blas_lasts_the_solver_lifetime),
        cmocka_unit_test(bad_thread_policy_is_refused),
        cmocka_unit_test(proxy_prolongation_on_its_team_is_deterministic),
    };
    return cmocka_run_group_tests_name("solver_threads", t, NULL, NULL);
}
