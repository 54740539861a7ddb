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
#include "iso_mesh.h"
#include "iso_metrics.h"
#include "iso_motion.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"

static const char *const help =
    "usage: isoshape deform --mesh M --sel S --def D [options]\n"
    "       isoshape deform --shape NAME [--resolution N] [options]\n"
    "       isoshape deform --benchmark NAME [--benchmark-dir DIR] [options]\n"
    "\n"
    "Moves the handle from its rest pose to the pose D along a screw motion and\n"
    "integrates the free vertices along the isometry-preserving field.\n"
    "  --mesh M           OFF, OBJ or PLY mesh\n"
    "  --sel S            one label per vertex: 0 fixed, 1 free, 2 handle\n"
    "  --def D            the handle's final transform: 4x4 row-major, x' = M [x;1]\n"
    "  --shape NAME       a built-in problem instead: bar, cylinder, bumpplane, cactus\n"
    "  --resolution N     the built-in shape's resolution (0: its default)\n"
    "  --benchmark NAME   a Botsch-Sorkine benchmark problem (cactus, bar, cylinder,\n"
    "                     bumpplane) read from --benchmark-dir, $ISOSHAPE_BENCHMARK_DIR\n"
    "                     or ../shared/data/benchmark; the built-in shape if absent\n"
    "  --omega W          smoothness weight in (0, 1], default 1/3\n"
    "  --weighting        param (default) or area: how triangles are weighted\n"
    "  --steps N          N fixed steps, or\n"
    "  --tol T            adaptive steps with local error T x bbox diagonal (default 1e-4)\n"
    "  --out OUT          write the deformed mesh (format from the extension)\n"
    "  --reference REF    also measure REF, another result of the same problem\n"
    "                     (with --benchmark: the Laplacian-editing result)\n"
    "  --json             print one JSON object instead of text\n";

typedef struct deform_args {
    const char *mesh, *sel, *def, *shape, *benchmark, *bench_dir, *out, *reference;
    int resolution, json, steps;
    double tol;
    iso_solver_opts so;
} deform_args;

/* Everything one run owns, released by problem_deinit. */
typedef struct problem {
    char label[ISO_CLI_PATH_MAX + 64];
    char ref_path[ISO_CLI_PATH_MAX];
    iso_shape shape;
    iso_mesh *mesh, *ref;
    iso_regions reg;
    double M[16];
} problem;

static void problem_deinit(problem *p)
{
    iso_mesh_destroy(p->mesh);
    iso_mesh_destroy(p->ref);
    iso_regions_deinit(&p->reg);
    iso_shape_deinit(&p->shape);
}

/* ------------------------------------------------------------------------ */
/* Options                                                                    */
/* ------------------------------------------------------------------------ */

/* Returns -1 to go on, else the exit status (0 after --help). */
static int parse_args(int argc, char **argv, deform_args *a)
{
    const char *cmd = "deform", *val = NULL;
    int r, weighting, have_steps = 0, have_tol = 0;
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    memset(a, 0, sizeof *a);
    iso_solver_opts_default(&a->so);
    a->steps = io.steps;
    a->tol = io.tol;
    weighting = (int)a->so.weighting;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            fputs(help, stdout);
            return 0;
        }
        if (strcmp(argv[i], "--json") == 0) {
            a->json = 1;
            continue;
        }
#define VALUE(name) ((r = iso_cli__value(cmd, argc, argv, &i, name, &val)) != 0)
        if (VALUE("--mesh"))
            a->mesh = val;
        else if (VALUE("--sel"))
            a->sel = val;
        else if (VALUE("--def"))
            a->def = val;
        else if (VALUE("--shape"))
            a->shape = val;
        else if (VALUE("--benchmark"))
            a->benchmark = val;
        else if (VALUE("--benchmark-dir"))
            a->bench_dir = val;
        else if (VALUE("--out"))
            a->out = val;
        else if (VALUE("--reference"))
            a->reference = val;
        else if (VALUE("--resolution")) {
            if (r > 0 && iso_cli__int(cmd, "--resolution", val, &a->resolution) != 0)
                return 2;
        } else if (VALUE("--omega")) {
            if (r > 0 && iso_cli__omega(cmd, val, &a->so.omega) != 0)
                return 2;
        } else if (VALUE("--weighting")) {
            if (r > 0 && iso_cli__weighting(cmd, val, &weighting) != 0)
                return 2;
        } else if (VALUE("--steps")) {
            if (r > 0 && iso_cli__int(cmd, "--steps", val, &a->steps) != 0)
                return 2;
            if (r > 0 && a->steps <= 0) {
                iso_cli__fail(cmd, "--steps %s must be a positive number of steps.", val);
                return 2;
            }
            have_steps = 1;
        } else if (VALUE("--tol")) {
            if (r > 0 && iso_cli__double(cmd, "--tol", val, &a->tol) != 0)
                return 2;
            if (r > 0 && !(a->tol > 0)) {
                iso_cli__fail(cmd, "--tol %s must be positive.", val);
                return 2;
            }
            have_tol = 1;
        } else
            return iso_cli__unknown(cmd, argv[i]);
#undef VALUE
        if (r < 0)
            return 2;
    }
    a->so.weighting = (iso_weighting)weighting;
    if (have_steps && have_tol) {
        iso_cli__fail(cmd, "--steps and --tol exclude each other: fixed steps or adaptive ones.");
        return 2;
    }
    if (have_tol)
        a->steps = 0;
    int sources = (a->shape != NULL) + (a->benchmark != NULL) + (a->mesh || a->sel || a->def);
    if (sources != 1) {
        iso_cli__fail(cmd, "give one problem: --mesh/--sel/--def, --shape NAME or --benchmark "
                           "NAME (see isoshape deform --help).");
        return 2;
    }
    if (!a->shape && !a->benchmark && (!a->mesh || !a->sel || !a->def)) {
        iso_cli__fail(cmd, "--%s is missing: a file problem needs --mesh, --sel and --def.",
                      !a->mesh  ? "mesh"
                      : !a->sel ? "sel"
                                : "def");
        return 2;
    }
    if (a->benchmark && !iso_cli__bench_known(a->benchmark)) {
        iso_cli__fail(cmd, "--benchmark '%s' is unknown: use cactus, bar, cylinder or bumpplane.",
                      a->benchmark);
        return 2;
    }
    if (a->bench_dir && !a->benchmark) {
        iso_cli__fail(cmd, "--benchmark-dir %s needs --benchmark NAME.", a->bench_dir);
        return 2;
    }
    return -1;
}

/* ------------------------------------------------------------------------ */
/* Loading the problem                                                        */
/* ------------------------------------------------------------------------ */

static int load_shape(problem *p, const char *name, int resolution, iso_err *err)
{
    int rc = iso_shape_init(&p->shape, name, resolution, err);
    if (rc == ISO_OK)
        rc = iso_mesh_create(p->shape.nv, p->shape.x, p->shape.nt, p->shape.tri, p->shape.name,
                             &p->mesh, err);
    if (rc == ISO_OK)
        rc = iso_shape_regions(&p->shape, &p->reg, err);
    if (rc == ISO_OK) {
        memcpy(p->M, p->shape.M, sizeof p->M);
        snprintf(p->label, sizeof p->label, "built-in %s (resolution %d)", p->shape.name,
                 p->shape.resolution);
    }
    return rc;
}

static int load_files(problem *p, const char *mesh, const char *sel, const char *def, iso_err *err)
{
    int rc = iso_mesh_load(mesh, &p->mesh, err);
    if (rc == ISO_OK)
        rc = iso_sel_load(sel, iso_mesh_vertex_count(p->mesh), &p->reg, err);
    if (rc == ISO_OK)
        rc = iso_def_load(def, p->M, err);
    if (rc == ISO_OK)
        snprintf(p->label, sizeof p->label, "%s", mesh);
    return rc;
}

static int load_problem(const deform_args *a, problem *p, iso_err *err)
{
    if (a->reference)
        snprintf(p->ref_path, sizeof p->ref_path, "%s", a->reference);
    if (a->shape)
        return load_shape(p, a->shape, a->resolution, err);
    if (!a->benchmark)
        return load_files(p, a->mesh, a->sel, a->def, err);
    iso_cli__bench b;
    char why[2048];
    if (!iso_cli__bench_find(a->benchmark, a->bench_dir, &b, why, sizeof why)) {
        fprintf(stderr,
                "isoshape deform: benchmark '%s' not found (looked in %s); using the "
                "built-in %s instead.\n",
                a->benchmark, why, a->benchmark);
        return load_shape(p, a->benchmark, a->resolution, err);
    }
    int rc = load_files(p, b.mesh, b.sel, b.def, err);
    if (rc == ISO_OK) {
        snprintf(p->label, sizeof p->label, "benchmark %s (%s)", a->benchmark, b.mesh);
        if (!a->reference && access(b.ref, R_OK) == 0)
            snprintf(p->ref_path, sizeof p->ref_path, "%s", b.ref);
    }
    return rc;
}

static int load_reference(problem *p, iso_err *err)
{
    if (!p->ref_path[0])
        return ISO_OK;
    int rc = iso_mesh_load(p->ref_path, &p->ref, err);
    if (rc != ISO_OK)
        return rc;
    char why[1024];
    if (!iso_cli__same_connectivity(p->mesh, p->ref, why, sizeof why))
        return iso_err_set(err, ISO_EINVAL, -1, "reference %s does not fit the problem: %s.",
                           p->ref_path, why);
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Running and reporting                                                      */
/* ------------------------------------------------------------------------ */

typedef struct progress {
    int tty;
    double t0, t1;
} progress;

/* A one-line bar, redrawn in place; only on a terminal, so logs and pipes
 * stay clean. */
static void show_progress(void *ctx, double t, int steps, long evaluations)
{
    const progress *pg = ctx;
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
    iso_integrate_stats ist;
    iso_solver_stats sst;
    double seconds, other;
} report;

static void json_number(const char *key, double v, int last)
{
    if (isfinite(v))
        printf("\"%s\": %.17g%s", key, v, last ? "" : ", ");
    else
        printf("\"%s\": null%s", key, last ? "" : ", ");
}

static double ratio(double ref, double ours)
{
    return ours > 0 ? ref / ours : (ref > 0 ? INFINITY : NAN);
}

static void print_json(const report *r)
{
    printf("{");
    json_number("metricErr", r->ours.metric_err, 0);
    json_number("areaErr", r->ours.area_err, 0);
    json_number("angleErr", r->ours.angle_err, 0);
    json_number("maxEdgeStrain", r->ours.max_edge_strain, 0);
    printf("\"steps\": %d, \"rk4Steps\": %d, \"rejected\": %d, \"evaluations\": %ld, ",
           r->ist.steps, r->ist.rk4_steps, r->ist.rejected, r->ist.evaluations);
    json_number("seconds", r->seconds, 0);
    json_number("assemblySeconds", r->sst.t_assembly, 0);
    json_number("factorSeconds", r->sst.t_factor, 0);
    json_number("solveSeconds", r->sst.t_solve, 0);
    json_number("otherSeconds", r->other, !r->has_ref);
    if (r->has_ref) {
        json_number("referenceMetricErr", r->ref.metric_err, 0);
        json_number("referenceAreaErr", r->ref.area_err, 0);
        json_number("referenceAngleErr", r->ref.angle_err, 0);
        json_number("referenceMaxEdgeStrain", r->ref.max_edge_strain, 0);
        json_number("referenceRatioMetricErr", ratio(r->ref.metric_err, r->ours.metric_err), 0);
        json_number("referenceRatioAreaErr", ratio(r->ref.area_err, r->ours.area_err), 0);
        json_number("referenceRatioAngleErr", ratio(r->ref.angle_err, r->ours.angle_err), 1);
    }
    printf("}\n");
}

static void print_text(const problem *p, const deform_args *a, const report *r)
{
    printf("problem        %s: %d vertices, %d triangles, %d free\n", p->label,
           iso_mesh_vertex_count(p->mesh), iso_mesh_triangle_count(p->mesh), r->sst.n_free);
    printf("settings       omega %.6g, weighting %s, ", a->so.omega,
           a->so.weighting == ISO_WEIGHT_AREA ? "area" : "param");
    if (a->steps > 0)
        printf("%d fixed steps\n", a->steps);
    else
        printf("adaptive, tol %.3g\n", a->tol);
    printf("steps          %d (RK4 start %d, rejected %d)\n", r->ist.steps, r->ist.rk4_steps,
           r->ist.rejected);
    printf("evaluations    %ld\n", r->ist.evaluations);
    printf("metricErr      %.6e\n", r->ours.metric_err);
    printf("areaErr        %.6e\n", r->ours.area_err);
    printf("angleErr       %.6e\n", r->ours.angle_err);
    printf("maxEdgeStrain  %.6e (%.3f%%)\n", r->ours.max_edge_strain,
           100.0 * r->ours.max_edge_strain);
    printf("time           %.3f s: assembly %.3f, factorization %.3f, solve %.3f, other %.3f\n",
           r->seconds, r->sst.t_assembly, r->sst.t_factor, r->sst.t_solve, r->other);
    if (r->has_ref) {
        printf("reference      %s\n", p->ref_path);
        printf("  metricErr    %.6e  (reference/ours %.4g)\n", r->ref.metric_err,
               ratio(r->ref.metric_err, r->ours.metric_err));
        printf("  areaErr      %.6e  (reference/ours %.4g)\n", r->ref.area_err,
               ratio(r->ref.area_err, r->ours.area_err));
        printf("  angleErr     %.6e  (reference/ours %.4g)\n", r->ref.angle_err,
               ratio(r->ref.angle_err, r->ours.angle_err));
        printf("  maxEdgeStrain %.6e (%.3f%%)\n", r->ref.max_edge_strain,
               100.0 * r->ref.max_edge_strain);
    }
}

/* Integrates p from t = 0 to 1 into x and fills the run's figures. */
static int run(const deform_args *a, problem *p, double *x, report *rep, iso_err *err)
{
    iso_twist xi;
    int rc = iso_twist_from_matrix(p->M, &xi, err);
    if (rc != ISO_OK)
        return rc;
    if (p->reg.n_handles < 1)
        return iso_err_set(err, ISO_ECONSTRAINT, -1,
                           "%s has no handle vertices (label 2), so nothing moves.", p->label);
    iso_twist *tw = malloc((size_t)p->reg.n_handles * sizeof *tw);
    if (!tw)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d handle twists.",
                           p->reg.n_handles);
    for (int h = 0; h < p->reg.n_handles; h++)
        tw[h] = xi;
    iso_screw_path sp = {tw, p->reg.n_handles};
    iso_path path = iso_screw_path_make(&sp);
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.steps = a->steps;
    io.tol = a->tol;
    progress pg = {isatty(STDERR_FILENO) && !a->json, io.t0, io.t1};
    io.progress = show_progress;
    io.progress_ctx = &pg;

    iso_solver *s = NULL;
    double start = iso_clock_now();
    rc = iso_solver_create(p->mesh, &p->reg, &a->so, &s, err);
    if (rc == ISO_OK)
        rc = iso_integrate(s, p->mesh, &p->reg, &path, &io, x, &rep->ist, err);
    rep->seconds = iso_clock_now() - start;
    if (pg.tty)
        fputc('\n', stderr);
    if (s)
        iso_solver_get_stats(s, &rep->sst);
    rep->other =
        fmax(0.0, rep->seconds - rep->sst.t_assembly - rep->sst.t_factor - rep->sst.t_solve);
    iso_solver_destroy(s);
    free(tw);
    return rc;
}

int iso_cli__deform(int argc, char **argv)
{
    deform_args a;
    int status = parse_args(argc, argv, &a);
    if (status >= 0)
        return status;
    status = 1;
    problem p;
    memset(&p, 0, sizeof p);
    report rep;
    memset(&rep, 0, sizeof rep);
    iso_err err;
    iso_err_clear(&err);
    double *x = NULL;
    if (load_problem(&a, &p, &err) != ISO_OK || load_reference(&p, &err) != ISO_OK)
        goto fail;
    int nv = iso_mesh_vertex_count(p.mesh);
    x = malloc((size_t)nv * 3 * sizeof *x);
    if (!x) {
        iso_err_set(&err, ISO_ENOMEM, -1, "out of memory for %d vertex positions.", nv);
        goto fail;
    }
    memcpy(x, iso_mesh_positions(p.mesh), (size_t)nv * 3 * sizeof *x);
    if (run(&a, &p, x, &rep, &err) != ISO_OK)
        goto fail;
    if (a.out && iso_mesh_save(p.mesh, x, a.out, ISO_MESH_FMT_AUTO, &err) != ISO_OK)
        goto fail;
    iso_metrics_compute(p.mesh, iso_mesh_positions(p.mesh), x, &rep.ours);
    if (p.ref) {
        rep.has_ref = 1;
        iso_metrics_compute(p.mesh, iso_mesh_positions(p.mesh), iso_mesh_positions(p.ref),
                            &rep.ref);
    }
    if (a.json)
        print_json(&rep);
    else
        print_text(&p, &a, &rep);
    status = 0;
    goto out;
fail:
    iso_cli__fail("deform", "%s", err.msg);
out:
    free(x);
    problem_deinit(&p);
    return status;
}
