/* controller/cli_solver.c -- the solver options that deform, field and bench
 * share: how the system is assembled and when it is factored afresh.
 *
 * The command's defaults differ from the library's on purpose: the library
 * defaults to the paper's scheme on the C path (what a caller embedding it
 * expects), while the command asks for the fastest path: auto, OpenCL on a
 * GPU where there is one, else the C path (with a one-line notice). */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>

#include "iso_element.h"
#include "iso_loop.h"

void iso_cli__solver_opts_default(iso_solver_opts *so)
{
    iso_solver_opts_default(so);
    so->assembly = ISO_ASSEMBLY_AUTO;
    so->refactor = ISO_REFACTOR_ADAPTIVE;
    so->cg_tol = ISO_CLI_DEFAULT_CG_TOL;
    iso_cli__solver_threads(&so->threads);
}

void iso_cli__loop_opts_default(iso_loop_opts *o, const char *cmd)
{
    iso_loop_opts_default(o);
    iso_cli__solver_threads(&o->threads);
    o->cmd = cmd;
}

int iso_cli__rest_fields(const struct iso_scene *sc, const iso_solver_opts *so, int reps,
                         iso_solver_stats *each, iso_solver_stats *total, double *flops,
                         iso_err *err)
{
    int nv = iso_mesh_vertex_count(sc->mesh);
    const double *x = iso_mesh_positions(sc->mesh);
    double *vc = calloc((size_t)nv * 3, sizeof *vc), *v = malloc((size_t)nv * 3 * sizeof *v);
    iso_solver *s = NULL;
    int rc = vc && v ? iso_solver_create(sc->mesh, &sc->regions, so, &s, err)
                     : iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertices", nv);
    for (int i = 0; rc == ISO_OK && i < nv; i++)
        if (sc->regions.kind[i] == ISO_HANDLE)
            iso_twist_velocity(&sc->handles[0].driver.twist, x + 3 * i, vc + 3 * i);
    if (rc == ISO_OK)
        rc = iso_solver_field(s, x, vc, v, err); /* warm caches and workspace */
    for (int k = 0; rc == ISO_OK && k < reps; k++) {
        iso_solver_stats a, b;
        iso_solver_get_stats(s, &a);
        rc = iso_solver_field(s, x, vc, v, err);
        iso_solver_get_stats(s, &b);
        each[k].t_assembly = b.t_assembly - a.t_assembly;
        each[k].t_factor = b.t_factor - a.t_factor;
        each[k].t_solve = b.t_solve - a.t_solve;
    }
    if (rc == ISO_OK && total)
        iso_solver_get_stats(s, total);
    if (rc == ISO_OK && flops)
        *flops = iso_cli__factor_flops(s);
    iso_solver_destroy(s);
    free(vc);
    free(v);
    return rc;
}

void iso_cli__solver_threads(iso_solver_threads *t)
{
    int omp_user = getenv("OMP_MAX_ACTIVE_LEVELS") || getenv("OMP_THREAD_LIMIT");
    t->omp = omp_user ? ISO_SOLVER_OMP_LEAVE : ISO_SOLVER_OMP_CALLER;
    t->blas = getenv("OPENBLAS_NUM_THREADS") ? ISO_SOLVER_BLAS_LEAVE : ISO_SOLVER_BLAS_SIZED;
}

/* ------------------------------------------------------------------------ */
/* The options, as table fragments the commands include                       */
/* ------------------------------------------------------------------------ */

const iso_cli__opt iso_cli__assembly_options[] = {
    {"assembly", ISO_CLI_OPT_ENUM, ISO_CLI_ENUM_AT(iso_solver_opts, assembly), NULL,
     .help = "who fills the system each evaluation: cpu, the C path; opencl, OpenCL kernels; auto "
             "(default), OpenCL on a GPU when there is one, else the C path (faster on a CPU). "
             "Without a usable device the C path runs, with a notice",
     .names = iso_assembly_names},
    {"cl-device", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(iso_solver_opts, cl_device), "SPEC",
     .help = "OpenCL device: P:D platform/device indices or part of a name (default: the first CPU "
             "device; under auto, the first GPU or accelerator)",
     .nonempty = 1},
    {0}};

static const iso_cli__opt refactor_options[] = {
    {"refactor", ISO_CLI_OPT_ENUM, ISO_CLI_ENUM_AT(iso_solver_opts, refactor), NULL,
     .help =
         "always: factor every evaluation (the paper's scheme); adaptive (default): reuse the last "
         "factor as a CG preconditioner",
     .names = iso_refactor_names},
    {0}};

/* The numbers' ranges are the solver's (iso_solver_range), which scene
 * files are held to as well. */
const iso_cli__opt iso_cli__pcg_options[] = {
    {"cg-tol", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(iso_solver_opts, cg_tol), "T",
     .help = "adaptive: CG's relative residual, %R, default " ISO_CLI_STR(ISO_CLI_DEFAULT_CG_TOL),
     .solver = "cg_tol"},
    {"preconditioner", ISO_CLI_OPT_ENUM, ISO_CLI_ENUM_AT(iso_solver_opts, preconditioner), NULL,
     .help = "adaptive: CG's preconditioner, rotated (default): the last factor turned by each "
             "vertex ring's rotation since, or plain: the factor as it is",
     .names = iso_precond_names},
    {0}};

static const iso_cli__opt worker_options[] = {
    {"worker-lag", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(iso_solver_opts, worker_lag), "N",
     .help = "adaptive: 0 (default) factors on the evaluating thread; N %R factors on a worker "
             "thread, each factor used from N evaluations after its matrix's",
     .solver = "worker_lag"},
    {0}};

const iso_cli__opt iso_cli__solver_options[] = {
    {NULL, ISO_CLI_OPT_TABLE, 0, .table = iso_cli__assembly_options},
    {NULL, ISO_CLI_OPT_TABLE, 0, .table = refactor_options},
    {NULL, ISO_CLI_OPT_TABLE, 0, .table = worker_options},
    {NULL, ISO_CLI_OPT_TABLE, 0, .table = iso_cli__pcg_options},
    {0}};

const iso_cli__opt iso_cli__weight_options[] = {
    {"omega", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(iso_solver_opts, omega), "W",
     .help = "smoothness weight %R, default 1/3", .solver = "omega"},
    {"weighting", ISO_CLI_OPT_ENUM, ISO_CLI_ENUM_AT(iso_solver_opts, weighting), NULL,
     .help = "how triangles are weighted (default param)", .names = iso_weighting_names},
    {0}};

void iso_cli__print_notice(const char *cmd, const char *notice)
{
    if (notice && *notice)
        fprintf(stderr, "isoshape %s: %s\n", cmd, notice);
}
