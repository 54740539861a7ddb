/* controller/cmd_deform.c -- `isoshape deform`: integrate a deformation from
 * the rest pose (t = 0) to the handle's final pose M (t = 1) along the screw
 * motion exp(t log M), then report the paper's distortion measures, the work
 * done and where the time went. */
#include "internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_integrate.h"
#include "iso_json.h"
#include "iso_mesh.h"
#include "iso_metrics.h"
#include "iso_motion.h"
#include "iso_pc2.h"
#include "iso_proxy.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"

/* Restoration defaults: at mu 1, tau 0.05 restoration put metricErr and
 * angleErr below a converged ARAP's on all four benchmark problems; a
 * larger mu wrecked the bar's twist (docs/method.md). */
#define RESTORE_DEFAULT_MU 1.0
#define RESTORE_DEFAULT_TAU 0.05
#define RESTORE_DEFAULT_TEXT "1,0.05"

typedef struct deform_args {
    iso_cli__source src;
    const char *out, *pc2, *write_problem, *against;
    int json, steps, start;
    double tol;
    iso_solver_opts so;
} deform_args;

/* ------------------------------------------------------------------------ */
/* Options                                                                    */
/* ------------------------------------------------------------------------ */

/* One part of --restore MU,TAU, held to the solver's range for `setting`
 * (the one a scene's solver.restore is held to). */
static int restore_part(const char *name, const char *setting, const char *text, double *out,
                        char *why, size_t cap)
{
    static const iso_range any = {0}; /* TAU when MU is 0: a number, unused */
    char said[160];
    if (iso_range_parse(setting ? iso_solver_range(setting) : &any, text, out, said, sizeof said) ==
        0)
        return 0;
    snprintf(why, cap, "%s %s", name, said);
    return -1;
}

/* --restore MU,TAU (MU >= 0, TAU > 0 when MU > 0) or off (MU = 0: the
 * paper's method exactly), into the solver options at dst. */
static int set_restore(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    iso_solver_opts *so = dst;
    char mu[64];
    (void)o;
    if (strcmp(val, "off") == 0) {
        so->restore_mu = so->restore_tau = 0.0;
        return 0;
    }
    const char *comma = strchr(val, ',');
    if (!comma || (size_t)(comma - val) >= sizeof mu || strchr(comma + 1, ',')) {
        snprintf(why, cap, "expected MU,TAU (e.g. " RESTORE_DEFAULT_TEXT ") or off");
        return -1;
    }
    snprintf(mu, sizeof mu, "%.*s", (int)(comma - val), val);
    double m, t = 0.0;
    if (restore_part("MU", "restore_mu", mu, &m, why, cap) != 0 ||
        restore_part("TAU", m > 0.0 ? "restore_tau" : NULL, comma + 1, &t, why, cap) != 0)
        return -1;
    so->restore_mu = m;
    so->restore_tau = m > 0.0 ? t : 0.0;
    return 0;
}

/* --proxy off|auto|N (N >= ISO_PROXY_MIN_BUDGET): the reduced model. */
static int set_proxy(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    iso_solver_opts *so = dst;
    (void)o;
    if (strcmp(val, "off") == 0 || strcmp(val, "auto") == 0) {
        so->proxy = val[0] == 'o' ? 0 : ISO_SOLVER_PROXY_AUTO;
        return 0;
    }
    char *end;
    long n = strtol(val, &end, 10);
    if (*val == '\0' || *end != '\0' || n < ISO_PROXY_MIN_BUDGET || n > 100000000L) {
        snprintf(why, cap, "expected off, auto or a vertex budget of at least %d",
                 ISO_PROXY_MIN_BUDGET);
        return -1;
    }
    so->proxy = (int)n;
    return 0;
}

static const iso_cli__opt deform_options[] = {
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(deform_args, src, iso_cli__source),
     .table = iso_cli__mesh_options},
    {"def", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(deform_args, src.def), "D",
     .help = "the handle's final transform: 4x4 row-major, x' = M [x;1]"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(deform_args, src, iso_cli__source),
     .table = iso_cli__shape_options},
    {"benchmark", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(deform_args, src.benchmark), "NAME",
     .help = "a Botsch-Sorkine benchmark problem instead (cactus, bar, cylinder, bumpplane), read "
             "from --benchmark-dir; the built-in shape of its name when absent"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(deform_args, src, iso_cli__source),
     .table = iso_cli__benchmark_dir_options},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(deform_args, so, iso_solver_opts),
     .table = iso_cli__weight_options},
    {"steps", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(deform_args, steps), "N",
     .help = "N fixed steps (%R), or", ISO_CLI_GE(1)},
    {"tol", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(deform_args, tol), "T",
     .help = "adaptive steps with local error T x bbox diagonal, T %R (default 1e-4)",
     ISO_CLI_GT(0)},
    {"start", ISO_CLI_OPT_ENUM, ISO_CLI_INT_AT(deform_args, start), NULL,
     .help =
         "how the Adams history starts: rk4 (default, the paper's) or adams, the real-time loop's "
         "(orders 1, 2, 3)",
     .names = iso_integrate_start_names},
    {"restore", ISO_CLI_OPT_CALL, ISO_CLI_AT(deform_args, so, iso_solver_opts), "MU,TAU",
     .help =
         "isometry restoration (beyond the paper): each edge's length relaxes to its rest length "
         "with time constant TAU seconds (the path takes 1 s, t in [0, 1], so TAU is also its "
         "fraction; a scene's tau is seconds of its stream time: a scene whose motion lasts D s "
         "matches TAU/D here), weight MU; default " RESTORE_DEFAULT_TEXT
         "; off: the paper's method exactly (use for paper reproductions)",
     .set = set_restore},
    {"proxy", ISO_CLI_OPT_CALL, ISO_CLI_AT(deform_args, so, iso_solver_opts), "N|auto|off",
     .help = "the reduced model: integrate a proxy of the mesh of at most N vertices and let the "
             "whole mesh follow it (auto: the size a 60 Hz tick allows, none for a mesh the "
             "method steps in full); default off",
     .set = set_proxy},
    {"proxy-smoothness", ISO_CLI_OPT_ENUM, ISO_CLI_ENUM_AT(deform_args, so.proxy_smoothness), NULL,
     .help = "with --proxy: step it with the mesh's omega (mesh, default) or with the omega that "
             "lets it bend as the mesh would (matched: nearer the whole mesh without "
             "restoration; docs/method.md)",
     .names = iso_proxy_smoothness_names},
    {"against", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(deform_args, against), "MESH",
     .help = "also report each vertex's distance to MESH (the same mesh deformed otherwise, "
             "e.g. without --proxy), as a share of the bounding-box diagonal"},
    {"out", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(deform_args, out), "OUT",
     .help = "write the deformed mesh (format from the extension)"},
    {"pc2", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(deform_args, pc2), "FILE",
     .help = "write a PC2 point cache for Blender: the rest pose, then a frame per step; the "
             "rest mesh beside it as FILE's name with .rest.ply",
     .nonempty = 1},
    {"write-problem", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(deform_args, write_problem), "DIR",
     .help = "with --shape: write the problem as files into DIR (made if absent), NAME.off (the "
             "rest mesh), NAME.sel and NAME.def, which --mesh, --sel and --def read back to the "
             "same bits; then exit without integrating",
     .nonempty = 1},
    {"reference", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(deform_args, src.reference), "REF",
     .help = "also measure REF, another result of the same problem (with --benchmark: the "
             "Laplacian-editing result)"},
    {"json", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(deform_args, json), NULL,
     .help = "print one JSON object instead of text", .flag = 1},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(deform_args, so, iso_solver_opts),
     .table = iso_cli__solver_options},
    {0}};

/* The problem's options exclude each other, and --steps excludes --tol.
 * Returns -1 when all fit, else 2 after saying why. */
static int check_args(const char *cmd, deform_args *a)
{
    const iso_cli__source *s = &a->src;
    if (a->steps > 0 && !isnan(a->tol)) {
        iso_cli__fail(cmd, "--steps and --tol exclude each other: fixed steps or adaptive ones.");
        return 2;
    }
    int sources = (s->shape != NULL) + (s->benchmark != NULL) + (s->mesh || s->sel || s->def);
    if (sources != 1) {
        iso_cli__fail(cmd, "give one problem: --mesh/--sel/--def, --shape NAME or --benchmark "
                           "NAME (see isoshape deform --help).");
        return 2;
    }
    if (!s->shape && !s->benchmark && (!s->mesh || !s->sel || !s->def)) {
        iso_cli__fail(cmd, "--%s is missing: a file problem needs --mesh, --sel and --def.",
                      !s->mesh  ? "mesh"
                      : !s->sel ? "sel"
                                : "def");
        return 2;
    }
    if (s->benchmark && !iso_cli__bench_known(s->benchmark)) {
        iso_cli__fail(cmd, "--benchmark '%s' is unknown: use cactus, bar, cylinder or bumpplane.",
                      s->benchmark);
        return 2;
    }
    if (a->write_problem && !s->shape) {
        iso_cli__fail(cmd, "--write-problem writes a built-in shape's problem: give --shape NAME "
                           "(bar, cylinder, bumpplane or cactus).");
        return 2;
    }
    if (s->bench_dir && !s->benchmark) {
        iso_cli__fail(cmd, "--benchmark-dir %s needs --benchmark NAME.", s->bench_dir);
        return 2;
    }
    return -1;
}

/* Returns -1 to go on, else the exit status (0 after --help). */
static int parse_args(int argc, char **argv, deform_args *a)
{
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    memset(a, 0, sizeof *a);
    iso_cli__solver_opts_default(&a->so);
    a->so.restore_mu = RESTORE_DEFAULT_MU;
    a->so.restore_tau = RESTORE_DEFAULT_TAU;
    a->start = io.start;
    a->tol = NAN; /* not given: the library's default, adaptive unless --steps */
    int status = iso_cli__parse(&iso_cli__deform_cmd, argc, argv, a, NULL, 0, NULL);
    if (status < 0)
        status = check_args("deform", a);
    if (a->steps == 0)
        a->steps = io.steps;
    if (isnan(a->tol))
        a->tol = io.tol;
    else
        a->steps = 0;
    return status;
}

/* ------------------------------------------------------------------------ */
/* Running and reporting                                                      */
/* ------------------------------------------------------------------------ */

typedef struct progress {
    int tty;
    double t0, t1;
    iso_pc2 *pc2;    /* --pc2: a frame per step, or NULL */
    const double *x; /* the positions at each step (iso_integrate_opts.progress) */
    iso_err pc2_err;
    int pc2_failed;
} progress;

/* A one-line bar, redrawn in place; only on a terminal, so logs and pipes
 * stay clean. */
static void show_progress(void *ctx, double t, int steps, long evaluations)
{
    progress *pg = ctx;
    if (pg->pc2 && !pg->pc2_failed && iso_pc2_write(pg->pc2, pg->x, &pg->pc2_err) != ISO_OK)
        pg->pc2_failed = 1;
    if (!pg->tty)
        return;
    enum { WIDTH = 30 };
    double f = (t - pg->t0) / (pg->t1 - pg->t0);
    int fill = (int)lround(fmin(1.0, fmax(0.0, f)) * WIDTH);
    char bar[WIDTH + 1];
    for (int i = 0; i < WIDTH; i++)
        bar[i] = i < fill ? '#' : '-';
    bar[WIDTH] = '\0';
    fprintf(stderr, "\r[%s] t %.4f  steps %d  evaluations %ld ", bar, t, steps, evaluations);
    fflush(stderr);
}

typedef struct report {
    iso_metrics ours, ref;
    int has_ref;
    iso_cli__run run;
    int has_against;
    double against_max, against_rms; /* distance to --against, over the rest diagonal */
} report;

/* Each vertex's distance from x to the --against mesh's, over the rest
 * bounding-box diagonal: largest and root mean square. */
static int measure_against(const char *path, const iso_mesh *m, const double *x, report *r,
                           iso_err *err)
{
    iso_mesh *o = NULL;
    int rc = iso_mesh_load(path, &o, err);
    int nv = iso_mesh_vertex_count(m);
    if (rc == ISO_OK && iso_mesh_vertex_count(o) != nv)
        rc = iso_err_set(err, ISO_EINVAL, -1, "%s has %d vertices, the problem %d.", path,
                         iso_mesh_vertex_count(o), nv);
    if (rc == ISO_OK) {
        const double *y = iso_mesh_positions(o);
        double diag = iso_mesh_bbox_diagonal(m), mx = 0, sum = 0;
        for (int i = 0; i < nv; i++) {
            double d0 = x[3 * i] - y[3 * i], d1 = x[3 * i + 1] - y[3 * i + 1],
                   d2 = x[3 * i + 2] - y[3 * i + 2], d2s = d0 * d0 + d1 * d1 + d2 * d2;
            mx = fmax(mx, sqrt(d2s));
            sum += d2s;
        }
        r->has_against = 1;
        r->against_max = mx / diag;
        r->against_rms = sqrt(sum / nv) / diag;
    }
    iso_mesh_destroy(o);
    return rc;
}

static double ratio(double ref, double ours)
{
    return ours > 0 ? ref / ours : (ref > 0 ? INFINITY : NAN);
}

/* Each distortion measure under its key, prefixed (e.g. "reference_"). */
static void json_measures(iso_json *j, const char *prefix, const iso_metrics *m)
{
    size_t n;
    const iso_metrics_measure *k = iso_metrics_measures(&n);
    for (size_t i = 0; i < n; i++) {
        char key[64];
        snprintf(key, sizeof key, "%s%s", prefix, k[i].key);
        iso_json_number(j, key, iso_metrics_value(m, &k[i]));
    }
}

static void print_json(const deform_args *a, const report *r)
{
    const iso_integrate_stats *ist = &r->run.ist;
    const iso_solver_stats *sst = &r->run.sst;
    iso_json j;
    iso_json_begin(&j, stdout);
    json_measures(&j, "", &r->ours);
    iso_json_int(&j, "steps", ist->steps);
    iso_json_int(&j, "rk4_steps", ist->rk4_steps);
    iso_json_int(&j, "rejected", ist->rejected);
    iso_json_int(&j, "evaluations", ist->evaluations);
    iso_json_string(&j, "assembly", iso_names_get(iso_assembly_names, a->so.assembly));
    iso_json_string(&j, "refactor", iso_names_get(iso_refactor_names, a->so.refactor));
    iso_json_int(&j, "factorizations", sst->factorizations);
    iso_json_int(&j, "cg_iterations", sst->cg_iterations);
    iso_json_int(&j, "factor_solves", sst->factor_solves);
    iso_json_int(&j, "refactors", sst->refactors);
    iso_json_number(&j, "seconds", r->run.seconds);
    iso_json_number(&j, "assembly_seconds", sst->t_assembly);
    iso_json_number(&j, "factor_seconds", sst->t_factor);
    iso_json_number(&j, "solve_seconds", sst->t_solve);
    iso_json_number(&j, "assembly_ms_per_evaluation",
                    iso_cli__per_evaluation_ms(sst->t_assembly, sst->evaluations));
    iso_json_number(&j, "factor_ms_per_evaluation",
                    iso_cli__per_evaluation_ms(sst->t_factor, sst->evaluations));
    iso_json_number(&j, "solve_ms_per_evaluation",
                    iso_cli__per_evaluation_ms(sst->t_solve, sst->evaluations));
    iso_json_number(&j, "other_seconds", r->run.other);
    iso_json_int(&j, "proxy_vertices", r->run.proxy_vertices);
    if (r->run.proxy_vertices > 0)
        iso_json_number(&j, "proxy_omega", r->run.proxy_omega);
    iso_json_number(&j, "proxy_seconds", r->run.proxy_s);
    if (r->run.proxy_vertices > 0)
        json_measures(&j, "proxy_", &r->run.proxy_metrics);
    if (r->has_against) {
        iso_json_number(&j, "against_max_distance", r->against_max);
        iso_json_number(&j, "against_rms_distance", r->against_rms);
    }
    if (r->has_ref) {
        json_measures(&j, "reference_", &r->ref);
        size_t n;
        const iso_metrics_measure *k = iso_metrics_measures(&n);
        for (size_t i = 0; i < n; i++) {
            char key[64];
            snprintf(key, sizeof key, "reference_ratio_%s", k[i].key);
            iso_json_number(
                &j, key,
                ratio(iso_metrics_value(&r->ref, &k[i]), iso_metrics_value(&r->ours, &k[i])));
        }
    }
    iso_json_end(&j);
}

static void print_text(const iso_cli__problem *p, const deform_args *a, const report *r)
{
    const iso_integrate_stats *ist = &r->run.ist;
    const iso_solver_stats *sst = &r->run.sst;
    printf("problem        %s: %d vertices, %d triangles, %d free\n", p->label,
           iso_mesh_vertex_count(p->mesh), iso_mesh_triangle_count(p->mesh), sst->n_free);
    printf("settings       omega %.6g, weighting %s, ", a->so.omega,
           iso_names_get(iso_weighting_names, a->so.weighting));
    if (a->so.restore_mu > 0)
        printf("restore mu %.6g tau %.6g, ", a->so.restore_mu, a->so.restore_tau);
    else
        printf("restore off, ");
    if (a->steps > 0)
        printf("%d fixed steps\n", a->steps);
    else
        printf("adaptive, tol %.3g\n", a->tol);
    printf("solver         assembly %s, refactor %s",
           iso_names_get(iso_assembly_names, a->so.assembly),
           iso_names_get(iso_refactor_names, a->so.refactor));
    if (a->so.refactor == ISO_REFACTOR_ADAPTIVE)
        printf(", CG tolerance %.3g", a->so.cg_tol);
    printf("\n");
    printf("steps          %d (RK4 start %d, rejected %d)\n", ist->steps, ist->rk4_steps,
           ist->rejected);
    printf("evaluations    %ld: %ld factorizations (%ld forced by slow CG), %ld CG iterations, "
           "%ld solves with a factor\n",
           ist->evaluations, sst->factorizations, sst->refactors, sst->cg_iterations,
           sst->factor_solves);
    if (r->run.proxy_vertices > 0)
        printf("reduced model  the method on a proxy of %d vertices (built in %.3f s), the %d of "
               "the mesh following it\n",
               r->run.proxy_vertices, r->run.proxy_s, iso_mesh_vertex_count(p->mesh));
    if (r->run.proxy_vertices > 0 && a->so.proxy_smoothness == ISO_PROXY_SMOOTHNESS_MATCHED)
        printf("               stepped with omega %.4g, matched to the mesh's %.4g\n",
               r->run.proxy_omega, a->so.omega);
    if (r->run.proxy_vertices > 0)
        printf("               the proxy's own: metricErr %.6e, maxEdgeStrain %.4g\n",
               r->run.proxy_metrics.metric_err, r->run.proxy_metrics.max_edge_strain);
    iso_metrics_print(stdout, "", &r->ours);
    if (r->has_against)
        printf("against        %s: vertex distance largest %.4g, rms %.4g of the bounding-box "
               "diagonal\n",
               a->against, r->against_max, r->against_rms);
    printf("time           %.3f s: assembly %.3f, factorization %.3f, solve %.3f, other %.3f\n",
           r->run.seconds, sst->t_assembly, sst->t_factor, sst->t_solve, r->run.other);
    printf("per evaluation %.3f ms: assembly %.3f, factorization %.3f, solve %.3f\n",
           iso_cli__per_evaluation_ms(sst->t_assembly + sst->t_factor + sst->t_solve,
                                      sst->evaluations),
           iso_cli__per_evaluation_ms(sst->t_assembly, sst->evaluations),
           iso_cli__per_evaluation_ms(sst->t_factor, sst->evaluations),
           iso_cli__per_evaluation_ms(sst->t_solve, sst->evaluations));
    if (r->has_ref) {
        printf("reference      %s, the same measures of it\n", p->ref_path);
        size_t n;
        const iso_metrics_measure *k = iso_metrics_measures(&n);
        for (size_t i = 0; i < n; i++) {
            double ref = iso_metrics_value(&r->ref, &k[i]);
            printf("  %-13s %.6e  (reference/ours %.4g)\n", k[i].name, ref,
                   ratio(ref, iso_metrics_value(&r->ours, &k[i])));
        }
    }
}

/* --pc2: the rest mesh beside the cache, and the rest pose as its frame 0;
 * every accepted step adds one. */
static int open_pc2(const deform_args *a, const iso_cli__problem *p, iso_pc2 **out, iso_err *err)
{
    char rest[ISO_CLI_PATH_MAX + 16];
    int rc = iso_pc2_save_rest(p->mesh, a->pc2, rest, sizeof rest, err);
    if (rc == ISO_OK)
        rc = iso_pc2_create(a->pc2, iso_mesh_vertex_count(p->mesh), out, err);
    if (rc == ISO_OK)
        rc = iso_pc2_write(*out, iso_mesh_positions(p->mesh), err);
    if (rc == ISO_OK && !a->json)
        fprintf(stderr,
                "isoshape deform: PC2 point cache into %s, a frame per step; rest mesh %s\n",
                a->pc2, rest);
    return rc;
}

/* Integrates p from t = 0 to 1 into x, with the progress bar on a terminal. */
static int run(const deform_args *a, const iso_cli__problem *p, double *x, report *rep,
               iso_err *err)
{
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.steps = a->steps;
    io.tol = a->tol;
    io.start = a->start;
    progress pg = {isatty(STDERR_FILENO) && !a->json, io.t0, io.t1, NULL, x, {0}, 0};
    io.progress = show_progress;
    io.progress_ctx = &pg;
    int rc = a->pc2 ? open_pc2(a, p, &pg.pc2, err) : ISO_OK;
    if (rc == ISO_OK)
        rc = iso_cli__problem_run(p, &a->so, &io, x, &rep->run, err);
    if (pg.tty)
        fputc('\n', stderr);
    if (rc == ISO_OK && pg.pc2_failed)
        rc = iso_err_set(err, pg.pc2_err.code, -1, "--pc2: %s", pg.pc2_err.msg);
    if (rc == ISO_OK && pg.pc2) {
        rc = iso_pc2_commit(pg.pc2, err);
        pg.pc2 = NULL;
    }
    iso_pc2_destroy(pg.pc2);
    iso_cli__print_notice("deform", rep->run.notice);
    return rc;
}

/* --write-problem: the built-in shape's files, and one line saying what
 * they hold. */
static int write_problem(const deform_args *a, const iso_cli__problem *p, iso_err *err)
{
    static char paths[3][ISO_CLI_PATH_MAX];
    int rc = iso_cli__problem_write(p, a->write_problem, p->shape.name, paths, err);
    if (rc != ISO_OK)
        return rc;
    int nv = iso_mesh_vertex_count(p->mesh), count[3] = {0, 0, 0};
    for (int v = 0; v < nv; v++)
        count[p->reg.kind[v] <= ISO_HANDLE ? p->reg.kind[v] : ISO_FREE]++;
    printf("%s: %d vertices, %d triangles\n", paths[0], nv, iso_mesh_triangle_count(p->mesh));
    printf("%s: %d fixed, %d free, %d handle\n", paths[1], count[ISO_FIXED], count[ISO_FREE],
           count[ISO_HANDLE]);
    printf("%s: the handle's final pose\n", paths[2]);
    return ISO_OK;
}

static int deform_main(int argc, char **argv)
{
    deform_args a;
    int status = parse_args(argc, argv, &a);
    if (status >= 0)
        return status;
    status = 1;
    iso_cli__problem p;
    memset(&p, 0, sizeof p);
    report rep;
    memset(&rep, 0, sizeof rep);
    iso_err err;
    iso_err_clear(&err);
    double *x = NULL;
    if (iso_cli__problem_load("deform", &a.src, &p, &err) != ISO_OK)
        goto fail;
    if (a.write_problem) {
        if (write_problem(&a, &p, &err) != ISO_OK)
            goto fail;
        status = 0;
        goto out;
    }
    int nv = iso_mesh_vertex_count(p.mesh);
    x = malloc((size_t)nv * 3 * sizeof *x);
    if (!x) {
        iso_err_set(&err, ISO_ENOMEM, -1, "out of memory for %d vertex positions.", nv);
        goto fail;
    }
    if (run(&a, &p, x, &rep, &err) != ISO_OK)
        goto fail;
    if (a.out && iso_mesh_save(p.mesh, x, a.out, ISO_MESH_FMT_AUTO, &err) != ISO_OK)
        goto fail;
    iso_metrics_compute(p.mesh, iso_mesh_positions(p.mesh), x, &rep.ours);
    if (a.against && measure_against(a.against, p.mesh, x, &rep, &err) != ISO_OK)
        goto fail;
    if (p.ref) {
        rep.has_ref = 1;
        iso_metrics_compute(p.mesh, iso_mesh_positions(p.mesh), iso_mesh_positions(p.ref),
                            &rep.ref);
    }
    if (a.json)
        print_json(&a, &rep);
    else
        print_text(&p, &a, &rep);
    status = 0;
    goto out;
fail:
    iso_cli__fail("deform", "%s", err.msg);
out:
    free(x);
    iso_cli__problem_deinit(&p);
    return status;
}

const iso_cli__cmd iso_cli__deform_cmd = {
    .name = "deform",
    .summary = "integrate the deformation of a mesh as its handle moves to its final pose",
    .usage = "usage: isoshape deform --mesh M --sel S --def D [options]\n"
             "       isoshape deform --shape NAME [--resolution N] [options]\n"
             "       isoshape deform --shape NAME [--resolution N] --write-problem DIR\n"
             "       isoshape deform --benchmark NAME [--benchmark-dir DIR] [options]\n"
             "\n"
             "Moves the handle from its rest pose to the pose D along a screw motion and\n"
             "integrates the free vertices along the isometry-preserving field.\n",
    .opts = deform_options,
    .main = deform_main};
