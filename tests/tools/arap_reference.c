/* tests/tools/arap_reference.c -- a converged ARAP solve of one benchmark
 * problem (iso_arap.h), the baseline the isometry solver is compared with.
 *
 *   arap_reference PREFIX [ITERATIONS [OUT.off]]
 *
 * PREFIX names the problem without extension, e.g.
 * ../shared/data/benchmark/03-cactus-bend/cactus: it reads PREFIX.off,
 * PREFIX.sel and PREFIX.def, places the handle vertices at M [x;1] and the
 * fixed ones at rest, and runs ARAP for ITERATIONS (default 1000) or until
 * the relative energy change falls below 1e-12. It prints the iterations,
 * the time, the energy and the Table 1 measures of the result against the
 * rest mesh, and writes the result to OUT.off if given. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_arap.h"
#include "iso_clock.h"
#include "iso_metrics.h"

#define REL_TOL 1e-12

static int usage(void)
{
    fprintf(stderr, "usage: arap_reference PREFIX [ITERATIONS [OUT.off]]\n"
                    "  PREFIX: a benchmark problem without extension, e.g. "
                    "BENCHDIR/03-cactus-bend/cactus\n");
    return 2;
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc > 4)
        return usage();
    const char *prefix = argv[1];
    int iterations = 1000;
    if (argc >= 3) {
        char *end;
        errno = 0;
        long n = strtol(argv[2], &end, 10);
        if (errno || *end || n < 1 || n > 100000000) {
            fprintf(stderr,
                    "arap_reference: ITERATIONS must be an integer from 1 to 1e8, got \"%s\"\n",
                    argv[2]);
            return 2;
        }
        iterations = (int)n;
    }
    const char *out_path = argc == 4 ? argv[3] : NULL;

    char path[4096];
    iso_err err;
    iso_err_clear(&err);
    iso_mesh *m = NULL;
    iso_regions r;
    memset(&r, 0, sizeof r);
    double M[16], *xc = NULL, *x = NULL;
    int rc, status = 1;

    snprintf(path, sizeof path, "%s.off", prefix);
    if ((rc = iso_mesh_load(path, &m, &err)) != ISO_OK)
        goto fail;
    int nv = iso_mesh_vertex_count(m);
    snprintf(path, sizeof path, "%s.sel", prefix);
    if ((rc = iso_sel_load(path, nv, &r, &err)) != ISO_OK)
        goto fail;
    snprintf(path, sizeof path, "%s.def", prefix);
    if ((rc = iso_def_load(path, M, &err)) != ISO_OK)
        goto fail;

    xc = malloc(3 * (size_t)nv * sizeof *xc);
    x = malloc(3 * (size_t)nv * sizeof *x);
    if (!xc || !x) {
        fprintf(stderr, "arap_reference: out of memory for %d vertices\n", nv);
        goto out;
    }
    const double *p = iso_mesh_positions(m);
    int n_fixed = 0, n_handle = 0;
    for (int i = 0; i < nv; i++) {
        const double *pi = p + 3 * i;
        if (r.kind[i] == ISO_HANDLE) {
            for (int a = 0; a < 3; a++)
                xc[3 * i + a] =
                    M[4 * a] * pi[0] + M[4 * a + 1] * pi[1] + M[4 * a + 2] * pi[2] + M[4 * a + 3];
            n_handle++;
        } else {
            memcpy(xc + 3 * i, pi, 3 * sizeof *xc);
            n_fixed += r.kind[i] == ISO_FIXED;
        }
    }

    iso_arap_stats st;
    memset(&st, 0, sizeof st);
    double t0 = iso_clock_now();
    rc = iso_arap_solve(m, &r, xc, iterations, REL_TOL, x, &st, &err);
    double secs = iso_clock_now() - t0;
    if (rc != ISO_OK)
        goto fail;

    iso_metrics q;
    iso_metrics_compute(m, p, x, &q);
    printf("problem     %s\n", prefix);
    printf("vertices    %d (%d fixed, %d handle, %d free), triangles %d\n", nv, n_fixed, n_handle,
           st.n_free, iso_mesh_triangle_count(m));
    printf("weights     cotangent, %d negative cotangents clamped to 0\n", st.n_clamped);
    printf("iterations  %d (%s, max %d, rel. energy tol %.0e)\n", st.iterations,
           st.converged ? "converged" : "not converged", iterations, REL_TOL);
    printf("seconds     %.3f (factor %.3f, iterate %.3f)\n", secs, st.seconds_factor,
           st.seconds_iterate);
    printf("energy      %.9g (start %.9g)\n", st.energy, st.energy_initial);
    printf("metricErr   %.6g\n", q.metric_err);
    printf("areaErr     %.6g\n", q.area_err);
    printf("angleErr    %.6g\n", q.angle_err);
    printf("edgeStrain  max %.4g, rms %.4g\n", q.max_edge_strain, q.rms_edge_strain);
    if (out_path) {
        if ((rc = iso_mesh_save(m, x, out_path, ISO_MESH_FMT_OFF, &err)) != ISO_OK)
            goto fail;
        printf("wrote       %s\n", out_path);
    }
    status = 0;
    goto out;
fail:
    fprintf(stderr, "arap_reference: %s (%s)\n", err.msg, iso_strerror(rc));
out:
    free(xc);
    free(x);
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    return status;
}
