/* tests/tools/restore_run.c -- one deformation of a benchmark problem with
 * or without isometry restoration, printed as one line of figures: the
 * measurement behind restoration's tables (restore_figures.sh runs it).
 *
 *   restore_run PREFIX MU TAU STEPS [KAPPA]
 *
 * PREFIX names the problem without extension (PREFIX.off, .sel, .def, as
 * arap_reference reads it). MU = 0 is the paper's method. STEPS > 0: fixed
 * steps over t in [0, 1]; 0: adaptive with the default tolerance. KAPPA:
 * the integrator's τ_eff = max(τ, κ h) factor (default
 * ISO_INTEGRATE_RESTORE_KAPPA; 0 = τ as given). Prints
 *   metricErr areaErr angleErr steps evaluations seconds
 * or the error and exit status 1 (e.g. when the step is unstable). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_clock.h"
#include "iso_integrate.h"
#include "iso_metrics.h"
#include "iso_motion.h"
#include "iso_regions.h"
#include "iso_solver.h"

int main(int argc, char **argv)
{
    if (argc < 5 || argc > 6) {
        fprintf(stderr, "usage: restore_run PREFIX MU TAU STEPS [KAPPA]\n");
        return 2;
    }
    char path[4096];
    iso_err err;
    iso_err_clear(&err);
    iso_mesh *m = NULL;
    iso_regions r;
    memset(&r, 0, sizeof r);
    iso_solver *s = NULL;
    double M[16], *x = NULL;
    int status = 1;
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.threads.blas = ISO_SOLVER_BLAS_SIZED; /* one solver at a time, as the command */
    so.restore_mu = atof(argv[2]);
    so.restore_tau = atof(argv[3]);
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.steps = atoi(argv[4]);
    if (argc == 6)
        io.restore_kappa = atof(argv[5]);

    snprintf(path, sizeof path, "%s.off", argv[1]);
    if (iso_mesh_load(path, &m, &err) != ISO_OK)
        goto fail;
    int nv = iso_mesh_vertex_count(m);
    snprintf(path, sizeof path, "%s.sel", argv[1]);
    if (iso_sel_load(path, nv, &r, &err) != ISO_OK)
        goto fail;
    snprintf(path, sizeof path, "%s.def", argv[1]);
    if (iso_def_load(path, M, &err) != ISO_OK)
        goto fail;
    iso_twist xi;
    if (iso_twist_from_matrix(M, &xi, &err) != ISO_OK)
        goto fail;
    iso_twist tw[8];
    int nh = r.n_handles < 8 ? r.n_handles : 8;
    for (int h = 0; h < nh; h++)
        tw[h] = xi;
    iso_screw_path sp = {tw, nh};
    iso_path p = iso_screw_path_make(&sp);
    x = malloc(3 * (size_t)nv * sizeof *x);
    if (!x)
        goto out;
    memcpy(x, iso_mesh_positions(m), 3 * (size_t)nv * sizeof *x);
    double t0 = iso_clock_now();
    iso_integrate_stats st;
    if (iso_solver_create(m, &r, &so, &s, &err) != ISO_OK ||
        iso_integrate(s, m, &r, &p, &io, x, &st, &err) != ISO_OK)
        goto fail;
    double secs = iso_clock_now() - t0;
    iso_metrics q;
    iso_metrics_compute(m, iso_mesh_positions(m), x, &q);
    printf("%.4g %.4g %.4g %d %ld %.1f\n", q.metric_err, q.area_err, q.angle_err, st.steps,
           st.evaluations, secs);
    status = 0;
    goto out;
fail:
    printf("failed: %s\n", err.msg);
out:
    iso_solver_destroy(s);
    free(x);
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    return status;
}
