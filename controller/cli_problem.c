/* controller/cli_problem.c -- one deformation problem for the commands that
 * integrate (deform, bench): finding and loading it, with the benchmark's
 * fall-back to the built-in shape of the same name, and one run from the
 * rest pose to the handle's final pose along the screw motion. */
#include "internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_proxy.h"

void iso_cli__problem_deinit(iso_cli__problem *p)
{
    iso_mesh_destroy(p->mesh);
    iso_mesh_destroy(p->ref);
    iso_regions_deinit(&p->reg);
    iso_shape_deinit(&p->shape);
    memset(p, 0, sizeof *p);
}

/* ------------------------------------------------------------------------ */
/* The options, as table fragments the commands include                       */
/* ------------------------------------------------------------------------ */

const iso_cli__opt iso_cli__mesh_options[] = {
    {"mesh", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(iso_cli__source, mesh), "M",
     .help = "an OFF, OBJ or PLY mesh"},
    {"sel", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(iso_cli__source, sel), "S",
     .help = "its labels, one per vertex: 0 fixed, 1 free, 2 handle"},
    {0}};

/* The resolution's range is the shape's own (iso_shape_init names it). */
const iso_cli__opt iso_cli__shape_options[] = {
    {"shape", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(iso_cli__source, shape), "NAME",
     .help = "a built-in shape and its labels: bar, cylinder, bumpplane, cactus, tentacle"},
    {"resolution", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(iso_cli__source, resolution), "N",
     .help = "the built-in shape's resolution (0: its default)"},
    {0}};

const iso_cli__opt iso_cli__shape_or_mesh_options[] = {
    {NULL, ISO_CLI_OPT_TABLE, 0, .table = iso_cli__shape_options},
    {NULL, ISO_CLI_OPT_TABLE, 0, .table = iso_cli__mesh_options},
    {0}};

const iso_cli__opt iso_cli__benchmark_dir_options[] = {
    {"benchmark-dir", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(iso_cli__source, bench_dir), "DIR",
     .help = "where the benchmark problems are (default: $ISOSHAPE_BENCHMARK_DIR, else "
             "../shared/data/benchmark from the current folder or the program's); a problem absent "
             "there runs as the built-in shape of its name"},
    {0}};

/* ------------------------------------------------------------------------ */
/* Loading                                                                    */
/* ------------------------------------------------------------------------ */

static int load_shape(iso_cli__problem *p, const char *name, int resolution, iso_err *err)
{
    int rc = iso_shape_init(&p->shape, name, resolution, err);
    if (rc == ISO_OK)
        rc = iso_mesh_create(p->shape.nv, p->shape.x, p->shape.nt, p->shape.tri, p->shape.name,
                             &p->mesh, err);
    if (rc == ISO_OK)
        rc = iso_shape_regions(&p->shape, &p->reg, err);
    if (rc == ISO_OK) {
        memcpy(p->M, p->shape.M, sizeof p->M);
        p->builtin = 1;
        snprintf(p->label, sizeof p->label, "built-in %s (resolution %d)", p->shape.name,
                 p->shape.resolution);
    }
    return rc;
}

static int load_files(iso_cli__problem *p, const char *mesh, const char *sel, const char *def,
                      iso_err *err)
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

static int load_reference(iso_cli__problem *p, iso_err *err)
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

static int load_benchmark(const char *cmd, const iso_cli__source *src, iso_cli__problem *p,
                          iso_err *err)
{
    iso_cli__bench b;
    char why[2048];
    if (!iso_cli__bench_find(src->benchmark, src->bench_dir, &b, why, sizeof why)) {
        if (!src->quiet)
            fprintf(stderr,
                    "isoshape %s: benchmark '%s' not found (looked in %s); using the "
                    "built-in %s instead.\n",
                    cmd, src->benchmark, why, src->benchmark);
        return load_shape(p, src->benchmark, src->resolution, err);
    }
    int rc = load_files(p, b.mesh, b.sel, b.def, err);
    if (rc == ISO_OK) {
        snprintf(p->label, sizeof p->label, "benchmark %s (%s)", src->benchmark, b.mesh);
        if (!src->reference && access(b.ref, R_OK) == 0)
            snprintf(p->ref_path, sizeof p->ref_path, "%s", b.ref);
    }
    return rc;
}

int iso_cli__problem_load(const char *cmd, const iso_cli__source *src, iso_cli__problem *p,
                          iso_err *err)
{
    memset(p, 0, sizeof *p);
    if (src->reference)
        snprintf(p->ref_path, sizeof p->ref_path, "%s", src->reference);
    int rc;
    if (src->shape)
        rc = load_shape(p, src->shape, src->resolution, err);
    else if (src->benchmark)
        rc = load_benchmark(cmd, src, p, err);
    else
        rc = load_files(p, src->mesh, src->sel, src->def, err);
    if (rc == ISO_OK)
        rc = load_reference(p, err);
    return rc;
}

/* ------------------------------------------------------------------------ */
/* Writing a problem as files                                                 */
/* ------------------------------------------------------------------------ */

/* The .sel: what iso_sel_load reads, with the labels' meaning on top. */
static void write_sel(FILE *f, const iso_cli__problem *p)
{
    int nv = iso_mesh_vertex_count(p->mesh);
    fprintf(f, "# %s: one label per vertex, in vertex order: 0 fixed, 1 free, 2 handle\n",
            p->label);
    for (int v = 0; v < nv; v++)
        fprintf(f, "%d\n", p->reg.kind[v]);
}

/* The .def: the handle's final pose, row-major, x' = M [x;1]. */
static void write_def(FILE *f, const iso_cli__problem *p)
{
    fprintf(f, "# %s: the handle's final pose, a 4x4 row-major matrix M, x' = M [x;1]\n", p->label);
    for (int r = 0; r < 4; r++)
        fprintf(f, "%.17g %.17g %.17g %.17g\n", p->M[4 * r], p->M[4 * r + 1], p->M[4 * r + 2],
                p->M[4 * r + 3]);
}

/* Writes one file through a temporary name beside it, then renames it. */
static int write_whole(const iso_cli__problem *p, const char *path, int what, iso_err *err)
{
    char tmp[ISO_CLI_PATH_MAX + 32];
    snprintf(tmp, sizeof tmp, "%s.part-%ld", path, (long)getpid());
    int rc = ISO_OK;
    if (what == 0) {
        rc = iso_mesh_save(p->mesh, NULL, tmp, ISO_MESH_FMT_OFF, err);
    } else {
        FILE *f = fopen(tmp, "w");
        if (!f)
            return iso_err_set(err, ISO_EIO, -1, "%s: %s", tmp, strerror(errno));
        if (what == 1)
            write_sel(f, p);
        else
            write_def(f, p);
        if ((ferror(f) | fclose(f)) != 0)
            rc = iso_err_set(err, ISO_EIO, -1, "%s: write failed", tmp);
    }
    if (rc == ISO_OK && rename(tmp, path) != 0)
        rc = iso_err_set(err, ISO_EIO, -1, "%s: %s", path, strerror(errno));
    if (rc != ISO_OK)
        unlink(tmp);
    return rc;
}

int iso_cli__problem_write(const iso_cli__problem *p, const char *dir, const char *name,
                           char paths[3][ISO_CLI_PATH_MAX], iso_err *err)
{
    static const char *const ext[] = {"off", "sel", "def"};
    struct stat st;
    if (stat(dir, &st) != 0 && mkdir(dir, 0777) != 0)
        return iso_err_set(err, ISO_EIO, -1, "--write-problem %s: cannot make the folder: %s", dir,
                           strerror(errno));
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return iso_err_set(err, ISO_EIO, -1, "--write-problem %s: not a folder", dir);
    for (int i = 0; i < 3; i++) {
        int n = snprintf(paths[i], ISO_CLI_PATH_MAX, "%s/%s.%s", dir, name, ext[i]);
        if (n < 0 || n >= ISO_CLI_PATH_MAX)
            return iso_err_set(err, ISO_EINVAL, -1, "--write-problem %s: path too long", dir);
        int rc = write_whole(p, paths[i], i, err);
        if (rc != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Running                                                                    */
/* ------------------------------------------------------------------------ */

/* The reduced model's proxy and its positions, when so->proxy asks for
 * one and the mesh is larger than the budget. */
static int with_proxy(const iso_cli__problem *p, const iso_solver_opts *so, iso_proxy **px,
                      double **y, iso_cli__run *out, iso_err *err)
{
    int nv = iso_mesh_vertex_count(p->mesh);
    int budget = so->proxy == ISO_SOLVER_PROXY_AUTO ? iso_proxy_auto_budget(nv, 60.0) : so->proxy;
    if (budget <= 0 || nv - iso_mesh_unreferenced_count(p->mesh) <= budget)
        return ISO_OK;
    double t0 = iso_clock_now();
    int rc = iso_proxy_create(p->mesh, &p->reg, budget, px, err);
    if (rc != ISO_OK)
        return rc;
    out->proxy_s = iso_clock_now() - t0;
    const iso_mesh *pm = iso_proxy_mesh(*px);
    out->proxy_vertices = iso_mesh_vertex_count(pm);
    if (!(*y = malloc((size_t)out->proxy_vertices * 3 * sizeof **y)))
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the proxy's positions.");
    memcpy(*y, iso_mesh_positions(pm), (size_t)out->proxy_vertices * 3 * sizeof **y);
    return ISO_OK;
}

/* The full mesh x from the proxy's y at the path's end t1. */
static int follow_proxy(const iso_cli__problem *p, iso_proxy *px, const iso_path *path, double t1,
                        const double *y, double *x, iso_err *err)
{
    iso_pose *poses = malloc((size_t)p->reg.n_handles * sizeof *poses);
    if (!poses)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d handle poses.",
                           p->reg.n_handles);
    int rc = ISO_OK;
    for (int h = 0; h < p->reg.n_handles && rc == ISO_OK; h++) {
        iso_twist tw;
        if (path->eval(path->ctx, h, t1, &poses[h], &tw) != ISO_OK)
            rc = iso_err_set(err, ISO_EINVAL, -1, "the path of handle %d has no pose at t = %g.", h,
                             t1);
    }
    if (rc == ISO_OK)
        iso_proxy_prolong(px, y, poses, x);
    free(poses);
    return rc;
}

int iso_cli__problem_run(const iso_cli__problem *p, const iso_solver_opts *so,
                         const iso_integrate_opts *io, double *x, iso_cli__run *out, iso_err *err)
{
    memset(out, 0, sizeof *out);
    out->factor_flops = NAN;
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

    int nv = iso_mesh_vertex_count(p->mesh);
    memcpy(x, iso_mesh_positions(p->mesh), (size_t)nv * 3 * sizeof *x);
    iso_solver *s = NULL;
    double start = iso_clock_now();
    iso_proxy *px = NULL;
    double *y = NULL;
    rc = with_proxy(p, so, &px, &y, out, err);
    const iso_mesh *mesh = px ? iso_proxy_mesh(px) : p->mesh;
    const iso_regions *reg = px ? iso_proxy_regions(px) : &p->reg;
    iso_solver_opts pso = *so;
    if (px)
        iso_proxy_solver_opts(px, &pso);
    out->proxy_omega = pso.omega;
    if (rc == ISO_OK)
        rc = iso_solver_create(mesh, reg, &pso, &s, err);
    if (rc == ISO_OK) {
        snprintf(out->notice, sizeof out->notice, "%s", iso_solver_notice(s));
        out->factor_flops = iso_cli__factor_flops(s);
        rc = iso_integrate(s, mesh, reg, &path, io, px ? y : x, &out->ist, err);
    }
    if (rc == ISO_OK && px) {
        iso_metrics_compute(mesh, iso_mesh_positions(mesh), y, &out->proxy_metrics);
        rc = follow_proxy(p, px, &path, io->t1, y, x, err);
    }
    out->seconds = iso_clock_now() - start;
    if (s)
        iso_solver_get_stats(s, &out->sst);
    out->other =
        fmax(0.0, out->seconds - out->sst.t_assembly - out->sst.t_factor - out->sst.t_solve);
    iso_solver_destroy(s);
    iso_proxy_destroy(px);
    free(y);
    free(tw);
    return rc;
}

double iso_cli__per_evaluation_ms(double seconds, long evaluations)
{
    return evaluations > 0 ? 1e3 * seconds / (double)evaluations : NAN;
}

/* Flops of one numeric factorization (CHOLMOD's count), NaN if unknown. */
double iso_cli__factor_flops(const iso_solver *s)
{
    double f = iso_solver_factor_flops(s);
    return f > 0 ? f : NAN;
}
