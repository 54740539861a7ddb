/* tests/tools/assembly_bench.c -- median time of one assembly (A_ff and the
 * right-hand side, no factorization, no solve) on a benchmark problem, the
 * C path and the OpenCL path alternating so that both see the same load on
 * a shared machine: the assembly figures of docs/performance.md.
 *
 *   assembly_bench PREFIX [REPS [cpu|opencl|both|halves [cold]]]
 *
 * PREFIX names the problem without extension (PREFIX.off and PREFIX.sel),
 * e.g. ../shared/data/benchmark/03-cactus-bend/cactus, or a built-in shape
 * as shape:NAME:RESOLUTION. REPS defaults to 31. `halves` times the C path
 * on one thread (never split) against the C path as the solver runs it (in
 * two halves on two threads from ISO_SOLVER_CPU_SPLIT_EDGES edges on).
 * Positions are the rest pose (the assembly's cost does not depend on
 * them), the handle moves with a fixed twist. Prints one line per path:
 * the median and the least wall time of one assembly, and the median CPU
 * time of the process over it (all threads: PoCL's included), which a
 * shared machine's load inflates far less than the wall time.
 * White-box: it calls the assembly entry points of solver_internal.h, so
 * the timing holds nothing but the assembly. Under callgrind, run it with
 * `cpu` and a few reps. With `cold`, 64 MiB are written between
 * assemblies (untimed), as a factorization and solve do in a deformation,
 * so that the assembly starts from caches that hold none of its data. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_clock.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"

#include "../../solver/solver_internal.h"

#define MAX_REPS 1001

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int assemble(iso_solver *s, const double *x, const double *vc, iso_err *err)
{
    if (s->cl)
        return iso_solver__cl_assemble(s->cl, s, x, vc, err);
    return iso_solver__assemble_cpu(s, x, vc, err);
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc > 5) {
        fprintf(stderr, "usage: assembly_bench PREFIX [REPS [cpu|opencl|both|halves [cold]]]\n");
        return 2;
    }
    int reps = argc > 2 ? atoi(argv[2]) : 31;
    const char *which = argc > 3 ? argv[3] : "both";
    if (reps < 1 || reps > MAX_REPS) {
        fprintf(stderr, "assembly_bench: REPS must be in 1..%d\n", MAX_REPS);
        return 2;
    }
    int halves = strcmp(which, "halves") == 0;
    int want[2] = {strcmp(which, "opencl") != 0, strcmp(which, "cpu") != 0};
    int cold = argc > 4 && strcmp(argv[4], "cold") == 0;
    size_t flush_n = cold ? (64u << 20) / sizeof(double) : 0;
    double *flush = NULL;
    char path[4096];
    iso_err err;
    iso_err_clear(&err);
    iso_mesh *m = NULL;
    iso_regions r;
    memset(&r, 0, sizeof r);
    iso_solver *s[2] = {NULL, NULL};
    double *vc = NULL, *t[2] = {NULL, NULL}, *c[2] = {NULL, NULL};
    int status = 1;

    char name[64];
    int res = 0;
    if (sscanf(argv[1], "shape:%63[^:]:%d", name, &res) == 2) {
        iso_shape sh;
        if (iso_shape_init(&sh, name, res, &err) != ISO_OK)
            goto fail;
        int rc = iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, name, &m, &err);
        if (rc == ISO_OK)
            rc = iso_shape_regions(&sh, &r, &err);
        iso_shape_deinit(&sh);
        if (rc != ISO_OK)
            goto fail;
    } else {
        snprintf(path, sizeof path, "%s.off", argv[1]);
        if (iso_mesh_load(path, &m, &err) != ISO_OK)
            goto fail;
        snprintf(path, sizeof path, "%s.sel", argv[1]);
        if (iso_sel_load(path, iso_mesh_vertex_count(m), &r, &err) != ISO_OK)
            goto fail;
    }
    int nv = iso_mesh_vertex_count(m);
    const double *x = iso_mesh_positions(m);
    vc = calloc(3 * (size_t)nv, sizeof *vc);
    t[0] = malloc(MAX_REPS * sizeof(double));
    t[1] = malloc(MAX_REPS * sizeof(double));
    c[0] = malloc(MAX_REPS * sizeof(double));
    c[1] = malloc(MAX_REPS * sizeof(double));
    if (!vc || !t[0] || !t[1] || !c[0] || !c[1]) {
        fprintf(stderr, "assembly_bench: out of memory\n");
        goto done;
    }
    for (int i = 0; i < nv; i++)
        if (r.kind[i] == ISO_HANDLE) {
            const double *p = x + 3 * i;
            vc[3 * i] = 0.1 + 0.3 * p[1] - 0.2 * p[2];
            vc[3 * i + 1] = -0.2 + 0.2 * p[0];
            vc[3 * i + 2] = 0.3 - 0.3 * p[0];
        }
    for (int k = 0; k < 2; k++) {
        if (!want[k])
            continue;
        iso_solver_opts o;
        iso_solver_opts_default(&o);
        o.assembly = k && !halves ? ISO_ASSEMBLY_OPENCL : ISO_ASSEMBLY_CPU;
        if (iso_solver_create(m, &r, &o, &s[k], &err) != ISO_OK)
            goto fail;
        if (halves && k == 0)
            s[k]->cpu_split_edges = 1 << 30; /* never: one thread */
        if (k && !halves && !s[k]->cl) {
            fprintf(stderr, "assembly_bench: %s\n", iso_solver_notice(s[k]));
            goto done;
        }
        if (assemble(s[k], x, vc, &err) != ISO_OK) /* warm up */
            goto fail;
    }
    for (int i = 0; i < reps; i++)
        for (int k = 0; k < 2; k++) {
            if (!want[k])
                continue;
            if (cold && !flush && !(flush = calloc(flush_n, sizeof *flush))) {
                fprintf(stderr, "assembly_bench: out of memory for the cache flush\n");
                goto done;
            }
            for (size_t j = 0; j < flush_n; j++)
                flush[j] += 1.0;
            double t0 = iso_clock_now(), c0 = cpu_now();
            if (assemble(s[k], x, vc, &err) != ISO_OK)
                goto fail;
            t[k][i] = 1e3 * (iso_clock_now() - t0);
            c[k][i] = 1e3 * (cpu_now() - c0);
        }
    for (int k = 0; k < 2; k++) {
        if (!want[k])
            continue;
        qsort(t[k], (size_t)reps, sizeof(double), cmp_double);
        qsort(c[k], (size_t)reps, sizeof(double), cmp_double);
        printf("%-6s median %.3f ms  min %.3f ms  cpu %.3f ms  (%d reps, %d vertices, %d free)\n",
               halves ? (k ? "cpu/2" : "cpu/1")
               : k    ? "opencl"
                      : "cpu",
               t[k][reps / 2], t[k][0], c[k][reps / 2], reps, nv, s[k]->nf);
    }
    status = 0;
    goto done;
fail:
    fprintf(stderr, "assembly_bench: %s\n", err.msg);
done:
    iso_solver_destroy(s[0]);
    iso_solver_destroy(s[1]);
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    free(vc);
    free(t[0]);
    free(t[1]);
    free(c[0]);
    free(c[1]);
    free(flush);
    return status;
}
