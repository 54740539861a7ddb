/* controller/cli_solver.c -- the solver options that deform, field and bench
 * share: how the system is assembled and when it is factored afresh.
 *
 * The command's defaults differ from the library's on purpose: the library
 * defaults to the paper's scheme on the C path (what a caller embedding it
 * expects), while the command asks for the fastest path and lets the
 * library fall back, with a one-line notice, where OpenCL is missing. */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void iso_cli__solver_opts_default(iso_solver_opts *so)
{
    iso_solver_opts_default(so);
    so->assembly = ISO_ASSEMBLY_OPENCL;
    so->refactor = ISO_REFACTOR_ADAPTIVE;
    so->cg_tol = ISO_CLI_DEFAULT_CG_TOL;
    iso_cli__solver_threads(&so->threads);
}

void iso_cli__solver_threads(iso_solver_threads *t)
{
    int omp_user = getenv("OMP_MAX_ACTIVE_LEVELS") || getenv("OMP_THREAD_LIMIT");
    t->omp = omp_user ? ISO_SOLVER_OMP_LEAVE : ISO_SOLVER_OMP_CALLER;
    t->blas = getenv("OPENBLAS_NUM_THREADS") ? ISO_SOLVER_BLAS_LEAVE : ISO_SOLVER_BLAS_SIZED;
}

static int parse_cg_tol(const char *cmd, const char *val, double *out)
{
    double t;
    if (iso_cli__double(cmd, "--cg-tol", val, &t) != 0)
        return -1;
    /* Below ~1e-16 relative the residual cannot fall further in double
     * precision, so CG would only stall and force a refactor each time. */
    if (!(t > 0.0 && t < 1.0)) {
        iso_cli__fail(cmd, "--cg-tol %s must lie in (0, 1): it is a relative residual.", val);
        return -1;
    }
    *out = t;
    return 0;
}

int iso_cli__solver_option(const char *cmd, int argc, char **argv, int *i, iso_solver_opts *so)
{
    const char *val = NULL;
    int r;
    int v;
    if ((r = iso_cli__value(cmd, argc, argv, i, "--assembly", &val)) != 0) {
        if (r < 0 || iso_cli__enum(cmd, "--assembly", val, iso_assembly_names, &v) != 0)
            return -1;
        so->assembly = (iso_assembly)v;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--refactor", &val)) != 0) {
        if (r < 0 || iso_cli__enum(cmd, "--refactor", val, iso_refactor_names, &v) != 0)
            return -1;
        so->refactor = (iso_refactor)v;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--cg-tol", &val)) != 0)
        return r < 0 || parse_cg_tol(cmd, val, &so->cg_tol) != 0 ? -1 : 1;
    if ((r = iso_cli__value(cmd, argc, argv, i, "--cl-device", &val)) != 0) {
        if (r < 0)
            return -1;
        if (!*val) {
            iso_cli__fail(cmd, "--cl-device is empty: give P:D indices or part of a device name.");
            return -1;
        }
        so->cl_device = val;
        return 1;
    }
    return 0;
}

void iso_cli__print_notice(const char *cmd, const char *notice)
{
    if (notice && *notice)
        fprintf(stderr, "isoshape %s: %s\n", cmd, notice);
}
