/* controller/cmd_bench.c -- `isoshape bench`: the four benchmark problems of
 * the paper, timed, and beside them the limits of this machine, so that no
 * figure stands alone:
 *   - per problem and refactoring scheme: steps, evaluations, seconds, where
 *     each evaluation's time goes, CG work, the Laplacian-editing result's
 *     metricErr over ours, and the speed-up over the paper's time;
 *   - whether adaptive factor reuse changes the result by less than the
 *     integrator's own error (the same run at tol and tol/10);
 *   - the machine: dense dgemm's rate (the ceiling for a supernodal
 *     factorization), and one bare CHOLMOD factorization and solve of the
 *     cactus system, with the factorization's achieved rate;
 *   - real time: each benchmark scene through the tick engine, its ticks
 *     per second, median and p99 tick over one bare solve (bench_realtime.c).
 * Timings are medians of --reps runs; nothing here asserts a time. The
 * benchmark uses the paper's method exactly (no isometry restoration). */
#include "internal.h"

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_json.h"
#include "iso_metrics.h"

/* The paper's times (Martinez Esturo, Roessl, Theisel 2010, Table 1), and
 * the shipped scenes' factorization worker (config/scenes, solver.worker_lag)
 * that the real-time table follows by default: four 60 Hz ticks (67 ms)
 * leave the bar's factorization (44 ms on one core) room to spare, where
 * three made ticks wait. */
#define RT_WORKER_LAG 4
static const struct {
    const char *name;
    double paper_seconds;
    int small_resolution; /* built-in stand-in under --quick */
    int rt_worker_lag;    /* the scene's solver.worker_lag */
} problems[] = {
    {"cactus", 4.0, 1, RT_WORKER_LAG},
    {"bar", 11.0, 4, RT_WORKER_LAG},
    {"cylinder", 8.0, 12, RT_WORKER_LAG},
    {"bumpplane", 212.0, 11, RT_WORKER_LAG},
};
enum { N_PROBLEMS = sizeof problems / sizeof problems[0], N_SCHEMES = 2 };

typedef struct bench_args {
    iso_cli__source src; /* its bench_dir: where the problems are */
    int quick, json, reps, tty;
    int only;                 /* --refactor: one iso_refactor, or -1 for both */
    int scheme_on[N_SCHEMES]; /* indexed by iso_refactor */
    iso_solver_opts so;
    int rt_worker_lag; /* the real-time table's solver.worker_lag */
    int scale;         /* --scale: the scale table alone */
    int scale_full_max;
} bench_args;

/* One problem under one scheme: the run with the median time. */
typedef struct bench_row {
    const char *problem;
    iso_refactor scheme;
    int builtin, vertices;
    iso_cli__run run;
    double metric_err, ref_metric_err; /* NAN without a reference */
    double paper_seconds, peak_rss_mb;
} bench_row;

/* Per problem: adaptive's effect on metricErr against the integrator's. */
typedef struct bench_accuracy {
    const char *problem;
    double always, adaptive, fine; /* metricErr; fine: always at tol/10; NAN if not run */
} bench_accuracy;

typedef struct bench_machine {
    int dgemm_n, dgemm_reps;
    double dgemm_gflops;  /* with OpenBLAS's own thread count */
    double dgemm1_gflops; /* on one thread: the ceiling of a factorization the
                             solver runs single-threaded (linsolve.c); NAN
                             when the BLAS has no thread control */
    int dgemm_threads;    /* OpenBLAS's thread count, 0 if unknown */
    int bare_reps, unknowns;
    long nnz_l;
    double flops, bare_factor_s, bare_solve_s;
} bench_machine;

typedef struct bench_result {
    bench_row rows[N_PROBLEMS * N_SCHEMES];
    int n_rows;
    bench_accuracy acc[N_PROBLEMS];
    int n_acc;
    bench_machine mach;
    iso_cli__rt_row rt[N_PROBLEMS];
    int n_rt;
    double tol;
    char notice[256]; /* the solver's first notice, printed once */
} bench_result;

/* ------------------------------------------------------------------------ */
/* Small helpers                                                              */
/* ------------------------------------------------------------------------ */

static double peak_rss_mb(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0)
        return NAN;
    return (double)ru.ru_maxrss / 1024.0; /* Linux: kilobytes */
}

static double rel_diff(double a, double b)
{
    return b > 0 ? fabs(a - b) / b : NAN;
}

/* ------------------------------------------------------------------------ */
/* Options                                                                    */
/* ------------------------------------------------------------------------ */

static const iso_cli__opt bench_options[] = {
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(bench_args, src, iso_cli__source),
     .table = iso_cli__benchmark_dir_options},
    {"quick", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(bench_args, quick), NULL,
     .help =
         "under a minute: one rep, dgemm at n = 1000, no bumpplane (the small built-in one when "
         "the benchmark is absent)",
     .flag = 1},
    {"reps", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(bench_args, reps), "N",
     .help = "timed runs per figure, median reported, %R (default 3; 1 with --quick)",
     ISO_CLI_GE(1), ISO_CLI_LE(99)},
    {"json", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(bench_args, json), NULL,
     .help = "print one JSON object instead of tables", .flag = 1},
    {"refactor", ISO_CLI_OPT_ENUM, ISO_CLI_INT_AT(bench_args, only), NULL,
     .help =
         "run only this scheme: always (factor every evaluation, the paper's scheme) or adaptive "
         "(reuse the last factor as a CG preconditioner); default: both",
     .names = iso_refactor_names},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(bench_args, so, iso_solver_opts),
     .table = iso_cli__assembly_options},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(bench_args, so, iso_solver_opts),
     .table = iso_cli__pcg_options},
    {"scale", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(bench_args, scale), NULL,
     .help = "only the scale table: built-in meshes of 40k to 1M vertices in real time, the "
             "method on the whole mesh beside the reduced model, then the whole mesh's "
             "factorization at 40k to 160k vertices, its memory and times (minutes; with "
             "--quick, meshes of 49 to 2.6k vertices in seconds)",
     .flag = 1},
    {"scale-full-max", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(bench_args, scale_full_max), "N",
     .help = "the scale table runs the method on the whole mesh, and the factorization table "
             "factors it, up to N vertices, %R (default 200000; 2000 with --quick)",
     ISO_CLI_GE(1)},
    {"worker-lag", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(bench_args, rt_worker_lag), "N",
     .help = "the real-time table's factorization worker (solver.worker_lag), %R; default "
             "each shipped scene's: " ISO_CLI_STR(RT_WORKER_LAG),
     .solver = "worker_lag"},
    {0}};

/* Returns -1 to go on, else the exit status (0 after --help). */
static int parse_args(int argc, char **argv, bench_args *a)
{
    memset(a, 0, sizeof *a);
    iso_cli__solver_opts_default(&a->so);
    a->so.restore_mu = 0.0; /* the paper's method exactly */
    a->only = -1;
    a->rt_worker_lag = -1; /* each scene's own */
    int status = iso_cli__parse(&iso_cli__bench_cmd, argc, argv, a, NULL, 0, NULL);
    if (status >= 0)
        return status;
    for (int k = 0; k < N_SCHEMES; k++)
        a->scheme_on[k] = a->only < 0 || a->only == k;
    if (a->reps == 0) /* not given */
        a->reps = a->quick ? 1 : 3;
    a->tty = isatty(STDERR_FILENO);
    return -1;
}

/* ------------------------------------------------------------------------ */
/* The machine: dgemm, and bare CHOLMOD on the cactus system                  */
/* ------------------------------------------------------------------------ */

/* The Fortran BLAS entry point, as every BLAS exports it. It is looked up in
 * the process rather than linked, so the rate measured is that of the BLAS
 * CHOLMOD actually runs with (Debian picks it through alternatives). */
typedef void dgemm_fn(const char *transa, const char *transb, const int *m, const int *n,
                      const int *k, const double *alpha, const double *a, const int *lda,
                      const double *b, const int *ldb, const double *beta, double *c,
                      const int *ldc);

/* GFLOP/s of C = A B at size n, median of reps; NAN if no BLAS is loaded. */
static double dgemm_rate(int n, int reps)
{
    dgemm_fn *dgemm = NULL;
    void *sym = dlsym(RTLD_DEFAULT, "dgemm_");
    if (!sym)
        return NAN;
    memcpy(&dgemm, &sym, sizeof dgemm);
    size_t nn = (size_t)n * (size_t)n;
    double *A = malloc(nn * sizeof *A), *B = malloc(nn * sizeof *B), *C = malloc(nn * sizeof *C);
    double t[99], rate = NAN;
    if (!A || !B || !C)
        goto out;
    for (size_t i = 0; i < nn; i++) {
        A[i] = (double)(i % 7) - 3.0;
        B[i] = (double)(i % 5) * 0.5;
    }
    const double one = 1.0, zero = 0.0;
    int w = n < 200 ? n : 200; /* wakes the thread pool outside the timing */
    dgemm("N", "N", &w, &w, &w, &one, A, &w, B, &w, &zero, C, &w);
    for (int r = 0; r < reps; r++) {
        double t0 = iso_clock_now();
        dgemm("N", "N", &n, &n, &n, &one, A, &n, B, &n, &zero, C, &n);
        t[r] = iso_clock_now() - t0;
    }
    rate = 2.0 * (double)n * (double)n * (double)n / iso_cli__median(t, reps) / 1e9;
out:
    free(A);
    free(B);
    free(C);
    return rate;
}

/* dgemm's rate on one thread, through OpenBLAS's thread control (looked
 * up, like dgemm_); the count in force is restored. NAN without it. */
static double dgemm_rate_one_thread(int n, int reps, int *threads)
{
    void *get = dlsym(RTLD_DEFAULT, "openblas_get_num_threads");
    void *set = dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
    *threads = 0;
    if (!get || !set)
        return NAN;
    int (*get_threads)(void) = NULL;
    void (*set_threads)(int) = NULL;
    memcpy(&get_threads, &get, sizeof get);
    memcpy(&set_threads, &set, sizeof set);
    *threads = get_threads();
    set_threads(1);
    double rate = dgemm_rate(n, reps);
    set_threads(*threads);
    return rate;
}

/* Times single evaluations of the cactus system at its rest pose under the
 * paper's scheme and the C assembly: each one is exactly one
 * cholmod_factorize and one pair of triangular solves with its factor (the
 * solver's own, solver/supersolve.c, as every PCG iteration uses), whose
 * times the solver's stats isolate. */
static int bare_cholmod(const iso_cli__problem *p, int reps, bench_machine *m, iso_err *err)
{
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    iso_cli__solver_threads(&so.threads);
    so.assembly = ISO_ASSEMBLY_CPU;
    so.refactor = ISO_REFACTOR_ALWAYS;
    iso_twist xi;
    int rc = iso_twist_from_matrix(p->M, &xi, err);
    if (rc != ISO_OK)
        return rc;
    int nv = iso_mesh_vertex_count(p->mesh);
    const double *x = iso_mesh_positions(p->mesh);
    double *vc = calloc((size_t)nv * 3, sizeof *vc), *v = malloc((size_t)nv * 3 * sizeof *v);
    double tf[99], ts[99];
    iso_solver *s = NULL;
    if (!vc || !v) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the cactus field.");
        goto out;
    }
    for (int i = 0; i < nv; i++)
        if (p->reg.kind[i] == ISO_HANDLE)
            iso_twist_velocity(&xi, x + 3 * i, vc + 3 * i);
    rc = iso_solver_create(p->mesh, &p->reg, &so, &s, err);
    if (rc == ISO_OK)
        rc = iso_solver_field(s, x, vc, v, err); /* warm caches and workspace */
    for (int r = 0; rc == ISO_OK && r < reps; r++) {
        iso_solver_stats before, after;
        iso_solver_get_stats(s, &before);
        rc = iso_solver_field(s, x, vc, v, err);
        iso_solver_get_stats(s, &after);
        tf[r] = after.t_factor - before.t_factor;
        ts[r] = after.t_solve - before.t_solve;
    }
    if (rc == ISO_OK) {
        iso_solver_stats st;
        iso_solver_get_stats(s, &st);
        m->bare_reps = reps;
        m->unknowns = 3 * st.n_free;
        m->nnz_l = st.nnz_l;
        m->flops = iso_cli__factor_flops(s);
        m->bare_factor_s = iso_cli__median(tf, reps);
        m->bare_solve_s = iso_cli__median(ts, reps);
    }
out:
    iso_solver_destroy(s);
    free(vc);
    free(v);
    return rc;
}

/* ------------------------------------------------------------------------ */
/* The problems                                                               */
/* ------------------------------------------------------------------------ */

/* Runs p reps times under so; keeps the median-time run in *run and the
 * result of the last run in x (the runs are bit-identical). */
static int timed_runs(const iso_cli__problem *p, const iso_solver_opts *so, double tol, int reps,
                      double *x, iso_cli__run *run, iso_err *err)
{
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.tol = tol;
    iso_cli__run runs[99];
    double t[99];
    for (int r = 0; r < reps; r++) {
        int rc = iso_cli__problem_run(p, so, &io, x, &runs[r], err);
        if (rc != ISO_OK)
            return rc;
        t[r] = runs[r].seconds;
    }
    double med = iso_cli__median(t, reps);
    *run = runs[0];
    for (int r = 0; r < reps; r++)
        if (runs[r].seconds == med)
            *run = runs[r];
    if (reps % 2 == 0) /* no run has the mean of the middle two: report it */
        run->seconds = med;
    return ISO_OK;
}

static double metric_err(const iso_cli__problem *p, const double *x)
{
    iso_metrics m;
    iso_metrics_compute(p->mesh, iso_mesh_positions(p->mesh), x, &m);
    return m.metric_err;
}

/* 1 if the problem runs: --quick leaves out the real bumpplane, the largest
 * by a factor of eight, but keeps its small built-in stand-in. */
static int wanted(const bench_args *a, int k, int *builtin)
{
    iso_cli__bench b;
    char why[2048];
    *builtin = !iso_cli__bench_find(problems[k].name, a->src.bench_dir, &b, why, sizeof why);
    return !(a->quick && strcmp(problems[k].name, "bumpplane") == 0 && !*builtin);
}

static int run_problem(const bench_args *a, int k, bench_result *res, iso_err *err)
{
    iso_cli__source src = {0};
    src.benchmark = problems[k].name;
    src.bench_dir = a->src.bench_dir;
    src.resolution = a->quick ? problems[k].small_resolution : 0;
    src.quiet = 0;
    iso_cli__problem p;
    double *x = NULL;
    int rc = iso_cli__problem_load("bench", &src, &p, err);
    if (rc != ISO_OK)
        goto out;
    int nv = iso_mesh_vertex_count(p.mesh);
    if (a->tty)
        fprintf(stderr, "isoshape bench: %s, %d vertices%s ...\n", problems[k].name, nv,
                p.builtin ? " (built-in)" : "");
    x = malloc((size_t)nv * 3 * sizeof *x);
    if (!x) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertex positions.", nv);
        goto out;
    }
    double ref_err = p.ref ? metric_err(&p, iso_mesh_positions(p.ref)) : NAN;
    bench_accuracy *acc = &res->acc[res->n_acc++];
    acc->problem = problems[k].name;
    acc->always = acc->adaptive = acc->fine = NAN;
    static const iso_refactor order[N_SCHEMES] = {ISO_REFACTOR_ALWAYS, ISO_REFACTOR_ADAPTIVE};
    for (int j = 0; j < N_SCHEMES; j++) {
        if (!a->scheme_on[order[j]])
            continue;
        iso_solver_opts so = a->so;
        so.refactor = order[j];
        bench_row *row = &res->rows[res->n_rows++];
        memset(row, 0, sizeof *row);
        row->problem = problems[k].name;
        row->scheme = order[j];
        row->builtin = p.builtin;
        row->vertices = nv;
        row->paper_seconds = problems[k].paper_seconds;
        rc = timed_runs(&p, &so, res->tol, a->reps, x, &row->run, err);
        if (rc != ISO_OK)
            goto out;
        row->metric_err = metric_err(&p, x);
        row->ref_metric_err = ref_err;
        row->peak_rss_mb = peak_rss_mb();
        *(order[j] == ISO_REFACTOR_ALWAYS ? &acc->always : &acc->adaptive) = row->metric_err;
        if (!res->notice[0])
            snprintf(res->notice, sizeof res->notice, "%s", row->run.notice);
    }
    /* The integrator's own error at this tolerance: the same run at tol/10,
     * under the first scheme asked for. */
    iso_solver_opts so = a->so;
    so.refactor = a->scheme_on[ISO_REFACTOR_ALWAYS] ? ISO_REFACTOR_ALWAYS : ISO_REFACTOR_ADAPTIVE;
    iso_cli__run fine;
    rc = timed_runs(&p, &so, res->tol / 10, 1, x, &fine, err);
    if (rc == ISO_OK)
        acc->fine = metric_err(&p, x);
    if (rc == ISO_OK && k == 0)
        rc = bare_cholmod(&p, a->quick ? 1 : 5, &res->mach, err);
out:
    free(x);
    iso_cli__problem_deinit(&p);
    return rc;
}

/* ------------------------------------------------------------------------ */
/* Reporting                                                                  */
/* ------------------------------------------------------------------------ */

static double speedup(const bench_row *r)
{
    return r->builtin ? NAN : r->paper_seconds / r->run.seconds;
}

static double ratio_le(const bench_row *r)
{
    return r->metric_err > 0 ? r->ref_metric_err / r->metric_err : NAN;
}

static double row_gflops(const bench_row *r)
{
    const iso_solver_stats *st = &r->run.sst;
    return st->t_factor > 0 ? r->run.factor_flops * (double)st->factorizations / st->t_factor / 1e9
                            : NAN;
}

static double ms(const bench_row *r, double seconds)
{
    return iso_cli__per_evaluation_ms(seconds, r->run.sst.evaluations);
}

/* A fixed-point cell, or a dash for NAN so missing figures read as missing. */
static void print_cell(double v, int width, int prec)
{
    if (isfinite(v))
        printf(" %*.*f", width, prec, v);
    else
        printf(" %*s", width, "-");
}

static void print_text(const bench_args *a, const bench_result *res)
{
    const bench_machine *m = &res->mach;
    printf("isoshape bench%s: the paper's method, adaptive steps at tol %.0e, assembly %s; "
           "times are medians of %d run%s\n\n",
           a->quick ? " --quick" : "", res->tol, iso_names_get(iso_assembly_names, a->so.assembly),
           a->reps, a->reps > 1 ? "s" : "");
    printf("%-10s %-8s %8s %5s %5s %8s | %-25s | %-12s | %-17s | %-16s | %s\n", "", "", "", "", "",
           "", "ms per evaluation", "CG", "", "paper", "factor  peak");
    printf("%-10s %-8s %8s %5s %5s %8s | %8s %8s %7s | %6s %5s | %9s %7s | %7s %8s | %7s %7s\n",
           "problem", "refactor", "vertices", "steps", "evals", "total s", "assembly", "factor",
           "solve", "iters", "refac", "metricErr", "LE/ours", "s", "speed-up", "GF/s", "RSS MB");
    for (int i = 0; i < res->n_rows; i++) {
        const bench_row *r = &res->rows[i];
        const iso_solver_stats *st = &r->run.sst;
        char name[32];
        snprintf(name, sizeof name, "%s%s", r->problem, r->builtin ? "*" : "");
        printf("%-10s %-8s %8d %5d %5ld %8.2f |", name,
               iso_names_get(iso_refactor_names, r->scheme), r->vertices, r->run.ist.steps,
               r->run.ist.evaluations, r->run.seconds);
        print_cell(ms(r, st->t_assembly), 8, 2);
        print_cell(ms(r, st->t_factor), 8, 2);
        print_cell(ms(r, st->t_solve), 7, 2);
        printf(" | %6ld %5ld | %9.3e", st->cg_iterations, st->refactors, r->metric_err);
        print_cell(ratio_le(r), 7, 2);
        printf(" |");
        print_cell(r->builtin ? NAN : r->paper_seconds, 7, 0);
        print_cell(speedup(r), 7, 2);
        printf("%s|", isfinite(speedup(r)) ? "x" : " ");
        print_cell(row_gflops(r), 7, 2);
        print_cell(r->peak_rss_mb, 7, 1);
        printf("\n");
    }
    int any_builtin = 0;
    for (int i = 0; i < res->n_rows; i++)
        any_builtin |= res->rows[i].builtin;
    if (any_builtin)
        printf("* the built-in shape of that name (the benchmark file was not found): no "
               "reference, and the paper's time does not apply\n");

    printf("\nfactor reuse against the integrator's own error (relative change of metricErr)\n");
    printf("%-10s %14s %14s %14s %19s %16s\n", "problem", "always", "adaptive", "always tol/10",
           "|adaptive-always|", "|tol/10 - tol|");
    for (int i = 0; i < res->n_acc; i++) {
        const bench_accuracy *c = &res->acc[i];
        double base = isfinite(c->always) ? c->always : c->adaptive;
        printf("%-10s %14.6e %14.6e %14.6e %19.3e %16.3e\n", c->problem, c->always, c->adaptive,
               c->fine, rel_diff(c->adaptive, c->always), rel_diff(c->fine, base));
    }

    iso_cli__bench_realtime_print(res->rt, res->n_rt);
    printf("\nthis machine\n");
    printf("  dense dgemm, n = %d: %.1f GFLOP/s on %d thread%s, %.1f on one (median of %d): "
           "the ceilings for the factorization's dense kernels (below 4 GFLOP per "
           "factorization, or with a factorization worker, the solver runs them on one "
           "thread)\n",
           m->dgemm_n, m->dgemm_gflops, m->dgemm_threads, m->dgemm_threads == 1 ? "" : "s",
           m->dgemm1_gflops, m->dgemm_reps);
    const char *blas = iso_cli__blas_config();
    printf("  BLAS: %s\n", *blas ? blas : "not OpenBLAS (see isoshape --version)");
    printf("  cactus system: %d unknowns, nnz(L) %ld, ", m->unknowns, m->nnz_l);
    if (isfinite(m->flops))
        printf("%.3g GFLOP per factorization\n", m->flops / 1e9);
    else
        printf("flop count unavailable (the library lacks iso_solver_factor_flops)\n");
    printf("  bare CHOLMOD factorization %.2f ms", 1e3 * m->bare_factor_s);
    if (isfinite(m->flops))
        printf(" = %.2f GFLOP/s (%.0f%% of one-thread dgemm)", m->flops / m->bare_factor_s / 1e9,
               100.0 * m->flops / m->bare_factor_s / 1e9 / m->dgemm1_gflops);
    printf(", bare solve %.2f ms (median of %d)\n", 1e3 * m->bare_solve_s, m->bare_reps);
}

static void print_json_row(iso_json *j, const bench_row *r)
{
    const iso_solver_stats *st = &r->run.sst;
    iso_json_object(j, NULL);
    iso_json_string(j, "problem", r->problem);
    iso_json_bool(j, "builtin", r->builtin);
    iso_json_string(j, "refactor", iso_names_get(iso_refactor_names, r->scheme));
    iso_json_int(j, "vertices", r->vertices);
    iso_json_int(j, "steps", r->run.ist.steps);
    iso_json_int(j, "evaluations", r->run.ist.evaluations);
    iso_json_int(j, "factorizations", st->factorizations);
    iso_json_int(j, "cg_iterations", st->cg_iterations);
    iso_json_int(j, "refactors", st->refactors);
    iso_json_number(j, "seconds", r->run.seconds);
    iso_json_number(j, "assembly_ms_per_evaluation", ms(r, st->t_assembly));
    iso_json_number(j, "factor_ms_per_evaluation", ms(r, st->t_factor));
    iso_json_number(j, "solve_ms_per_evaluation", ms(r, st->t_solve));
    iso_json_number(j, "factor_gflops", row_gflops(r));
    iso_json_number(j, "metric_err", r->metric_err);
    iso_json_number(j, "reference_metric_err", r->ref_metric_err);
    iso_json_number(j, "reference_ratio_metric_err", ratio_le(r));
    iso_json_number(j, "paper_seconds", r->builtin ? NAN : r->paper_seconds);
    iso_json_number(j, "speedup_over_paper", speedup(r));
    iso_json_number(j, "peak_rss_mb", r->peak_rss_mb);
    iso_json_close(j);
}

static void print_json_accuracy(iso_json *j, const bench_accuracy *c)
{
    double base = isfinite(c->always) ? c->always : c->adaptive;
    iso_json_object(j, NULL);
    iso_json_string(j, "problem", c->problem);
    iso_json_number(j, "metric_err_always", c->always);
    iso_json_number(j, "metric_err_adaptive", c->adaptive);
    iso_json_number(j, "metric_err_tol_over_10", c->fine);
    iso_json_number(j, "adaptive_vs_always", rel_diff(c->adaptive, c->always));
    iso_json_number(j, "tol_vs_tol_over_10", rel_diff(c->fine, base));
    iso_json_close(j);
}

static void print_json_machine(iso_json *j, const bench_machine *m)
{
    iso_json_object(j, "machine");
    iso_json_int(j, "dgemm_n", m->dgemm_n);
    iso_json_int(j, "dgemm_reps", m->dgemm_reps);
    iso_json_number(j, "dgemm_gflops", m->dgemm_gflops);
    iso_json_int(j, "dgemm_threads", m->dgemm_threads);
    iso_json_number(j, "dgemm_one_thread_gflops", m->dgemm1_gflops);
    iso_json_string(j, "blas", iso_cli__blas_config());
    iso_json_int(j, "cactus_unknowns", m->unknowns);
    iso_json_int(j, "cactus_nnz_l", m->nnz_l);
    iso_json_int(j, "bare_reps", m->bare_reps);
    iso_json_number(j, "cactus_factor_flops", m->flops);
    iso_json_number(j, "bare_factor_ms", 1e3 * m->bare_factor_s);
    iso_json_number(j, "bare_solve_ms", 1e3 * m->bare_solve_s);
    iso_json_number(j, "bare_factor_gflops", m->flops / m->bare_factor_s / 1e9);
    iso_json_close(j);
}

static void print_json(const bench_args *a, const bench_result *res)
{
    iso_json j;
    iso_json_begin(&j, stdout);
    iso_json_bool(&j, "quick", a->quick);
    iso_json_int(&j, "reps", a->reps);
    iso_json_string(&j, "assembly", iso_names_get(iso_assembly_names, a->so.assembly));
    iso_json_number(&j, "tol", res->tol);
    iso_json_array(&j, "rows");
    for (int i = 0; i < res->n_rows; i++)
        print_json_row(&j, &res->rows[i]);
    iso_json_close(&j);
    iso_json_array(&j, "accuracy");
    for (int i = 0; i < res->n_acc; i++)
        print_json_accuracy(&j, &res->acc[i]);
    iso_json_close(&j);
    iso_json_array(&j, "realtime");
    iso_cli__bench_realtime_json(&j, res->rt, res->n_rt);
    iso_json_close(&j);
    print_json_machine(&j, &res->mach);
    iso_json_end(&j);
}

/* ------------------------------------------------------------------------ */
/* The command                                                                */
/* ------------------------------------------------------------------------ */

/* bench --scale: the scale table and the factorization table beside it,
 * both under one --scale-full-max. */
static int scale_table(const bench_args *a, iso_err *err)
{
    iso_cli__scale_row rows[2 * ISO_CLI_SCALE_MESHES];
    iso_cli__scale_factor_row frows[ISO_CLI_SCALE_FACTOR_MESHES];
    int n = 0, nf = 0;
    const iso_cli__scale_mesh *meshes =
        a->quick ? iso_cli__scale_meshes_quick : iso_cli__scale_meshes;
    const iso_cli__scale_mesh *fmeshes =
        a->quick ? iso_cli__scale_factor_meshes_quick : iso_cli__scale_factor_meshes;
    int full_max = a->scale_full_max > 0 ? a->scale_full_max : a->quick ? 2000 : 200000;
    if (iso_cli__bench_scale(meshes, full_max, a->tty, rows, &n, err) != ISO_OK) {
        iso_cli__fail("bench", "%s", err->msg);
        return 1;
    }
    iso_cli__bench_scale_factor(fmeshes, full_max, a->tty, frows, &nf);
    if (a->json) {
        iso_json j;
        iso_json_begin(&j, stdout);
        iso_json_array(&j, "scale");
        iso_cli__bench_scale_json(&j, rows, n);
        iso_json_close(&j);
        iso_json_array(&j, "factorization");
        iso_cli__bench_scale_factor_json(&j, frows, nf);
        iso_json_close(&j);
        iso_json_end(&j);
    } else {
        iso_cli__bench_scale_print(rows, n);
        iso_cli__bench_scale_factor_print(frows, nf);
    }
    return 0;
}

static int bench_main(int argc, char **argv)
{
    bench_args a;
    int status = parse_args(argc, argv, &a);
    if (status >= 0)
        return status;
    bench_result *res = calloc(1, sizeof *res);
    if (!res) {
        iso_cli__fail("bench", "out of memory for the results.");
        return 1;
    }
    res->tol = ISO_INTEGRATE_DEFAULT_TOL;
    iso_err err;
    iso_err_clear(&err);
    status = 1;
    if (a.scale) {
        status = scale_table(&a, &err);
        free(res);
        return status;
    }
    /* The problems come first, so that each peak RSS is the problem's and
     * not dgemm's 3 n^2 doubles. */
    for (int k = 0; k < N_PROBLEMS; k++) {
        int builtin;
        if (!wanted(&a, k, &builtin))
            continue;
        if (run_problem(&a, k, res, &err) != ISO_OK) {
            iso_cli__fail("bench", "%s: %s", problems[k].name, err.msg);
            goto out;
        }
    }
    for (int k = 0; k < N_PROBLEMS; k++) {
        int builtin, res_k = a.quick ? problems[k].small_resolution : 0;
        if (!wanted(&a, k, &builtin))
            continue;
        if (a.tty)
            fprintf(stderr, "isoshape bench: %s in real time ...\n", problems[k].name);
        iso_solver_opts rt_so = a.so;
        rt_so.worker_lag = a.rt_worker_lag >= 0 ? a.rt_worker_lag : problems[k].rt_worker_lag;
        if (iso_cli__bench_realtime(problems[k].name, a.src.bench_dir, res_k, &rt_so,
                                    a.quick ? 3 : 5, &res->rt[res->n_rt++], &err) != ISO_OK) {
            iso_cli__fail("bench", "%s in real time: %s", problems[k].name, err.msg);
            goto out;
        }
    }
    iso_cli__print_notice("bench", res->notice);
    res->mach.dgemm_n = a.quick ? 1000 : 2000;
    res->mach.dgemm_reps = a.quick ? 1 : 3;
    if (a.tty)
        fprintf(stderr, "isoshape bench: dgemm, n = %d ...\n", res->mach.dgemm_n);
    res->mach.dgemm_gflops = dgemm_rate(res->mach.dgemm_n, res->mach.dgemm_reps);
    res->mach.dgemm1_gflops =
        dgemm_rate_one_thread(res->mach.dgemm_n, res->mach.dgemm_reps, &res->mach.dgemm_threads);
    if (a.json)
        print_json(&a, res);
    else
        print_text(&a, res);
    status = 0;
out:
    free(res);
    return status;
}

const iso_cli__cmd iso_cli__bench_cmd = {
    .name = "bench",
    .summary = "time the four benchmark problems against the paper and this machine",
    .usage =
        "usage: isoshape bench [--quick] [--json] [--benchmark-dir DIR] [--reps N] [options]\n"
        "\n"
        "Runs the four benchmark problems (cactus, bar, cylinder, bumpplane) with the paper's\n"
        "method, once per refactoring scheme, and measures this machine's limits beside them:\n"
        "dense dgemm's rate and one bare CHOLMOD factorization and solve of the cactus system.\n"
        "Then runs each problem's scene in real time (as fast as possible) beside one bare "
        "solve.\n",
    .opts = bench_options,
    .main = bench_main};
