/* controller/bench_realtime.c -- `isoshape bench`'s real-time table: each
 * benchmark scene through the tick engine as fast as possible, beside one
 * bare solve of the same system measured in the same run, so that the
 * tick's cost reads in solves (a tick near the cost of one solve is at
 * its wall; docs/performance.md). Kept apart from cmd_bench.c, which only calls it.
 *
 * The scenes are config/scenes/{cactus,bar,cylinder,bumpplane}.yaml as
 * written there (the benchmark problem or the built-in shape of its name,
 * its screw over 2 s, ABM3 PEC, adaptive refactoring, 60 Hz), built here
 * from the same text without the live view, so that the command needs no
 * source tree. The bench's --assembly, --cl-device, --cg-tol and
 * --worker-lag apply. */
#include "internal.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_loop.h"
#include "iso_scene.h"

static int load_scene(const char *name, const char *bench_dir, int resolution,
                      const iso_solver_opts *so, iso_scene **out, iso_err *err)
{
    char res[32] = "", text[1024];
    if (resolution > 0)
        snprintf(res, sizeof res, ", resolution: %d", resolution);
    snprintf(text, sizeof text,
             "name: %s\n"
             "mesh: {benchmark: %s, fallback_shape: %s%s}\n"
             "regions:\n"
             "  sel: builtin\n"
             "  handles:\n"
             "    - name: top\n"
             "      driver: {screw: {def: builtin, duration: 2.0}}\n"
             "solver: {omega: 0.333, weighting: param, restore: off, assembly: %s,\n"
             "         refactor: adaptive, cg_tol: %.17g, worker_lag: %d, proxy: off}\n"
             "integrator: {steps_per_tick: 1, abm: pec}\n"
             "tick_hz: 60\n",
             name, name, name, res, iso_names_get(iso_assembly_names, so->assembly), so->cg_tol,
             so->worker_lag);
    iso_scene_opts opts = {.bench_find = iso_cli__scene_bench_find, .bench_ctx = (void *)bench_dir};
    return iso_scene_load_mem(text, strlen(text), name, &opts, out, err);
}

/* One bare solve of the scene's system at its rest pose: the median over
 * reps evaluations of the solve alone (each factors afresh first). */
static int bare_solve(const iso_scene *sc, int reps, double *ms, iso_err *err)
{
    iso_solver_opts so = sc->solver;
    so.assembly = ISO_ASSEMBLY_CPU; /* the solve does not depend on who assembled */
    so.refactor = ISO_REFACTOR_ALWAYS;
    so.worker_lag = 0;
    iso_cli__solver_threads(&so.threads); /* as the tick engine's solver had them */
    iso_solver_stats each[99];
    double t[99];
    int rc = iso_cli__rest_fields(sc, &so, reps, each, NULL, NULL, err);
    for (int r = 0; rc == ISO_OK && r < reps; r++)
        t[r] = each[r].t_solve;
    if (rc == ISO_OK) {
        *ms = 1e3 * iso_cli__median(t, reps);
    }
    return rc;
}

int iso_cli__bench_realtime(const char *name, const char *bench_dir, int resolution,
                            const iso_solver_opts *so, int reps, iso_cli__rt_row *row, iso_err *err)
{
    memset(row, 0, sizeof *row);
    snprintf(row->scene, sizeof row->scene, "%s", name);
    iso_scene *sc = NULL;
    iso_loop *l = NULL;
    int rc = load_scene(name, bench_dir, resolution, so, &sc, err);
    /* The engine's notices are the solver's, which bench prints once for
     * all its runs; four copies of it said nothing more. Errors come back
     * in err. */
    FILE *quiet = fopen("/dev/null", "w");
    if (rc == ISO_OK) {
        iso_loop_opts o;
        iso_cli__loop_opts_default(&o, "bench");
        o.log = quiet; /* NULL (no /dev/null): stderr */
        o.fast = 1;
        o.rt = 0;
        o.display = 0;
        o.cl_device = so->cl_device;
        rc = iso_loop_create(sc, &o, &l, err);
    }
    if (rc == ISO_OK)
        rc = iso_loop_run(l, err);
    if (rc == ISO_OK) {
        iso_loop_summary s;
        iso_loop_get_summary(l, &s);
        row->builtin = sc->mesh_src.used != ISO_SCENE_MESH_BENCHMARK;
        row->vertices = iso_mesh_vertex_count(sc->mesh);
        row->ticks = s.ticks;
        row->ticks_per_s = s.wall_s > 0 ? (double)s.ticks / s.wall_s : NAN;
        row->median_ms = s.tick_median;
        row->p99_ms = s.tick_p99;
        row->max_step_evaluations = s.integ.max_step_evaluations;
        row->evaluations = s.solver.evaluations;
        row->cg_iterations = s.solver.cg_iterations;
        row->factor_solves = s.solver.factor_solves;
        row->factorizations = s.solver.factorizations;
        row->handovers = s.solver.handovers;
        iso_loop_destroy(l); /* frees the engine's solver before the bare one */
        l = NULL;
        rc = bare_solve(sc, reps, &row->bare_solve_ms, err);
    }
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    if (quiet)
        fclose(quiet);
    return rc;
}

static double over_solve(const iso_cli__rt_row *r)
{
    return r->bare_solve_ms > 0 ? r->median_ms / r->bare_solve_ms : NAN;
}

void iso_cli__bench_realtime_print(const iso_cli__rt_row *rows, int n)
{
    printf("\nreal time: each benchmark scene (its screw over 2 s, ABM3 PEC, adaptive "
           "refactoring, 60 Hz) through the tick engine, as fast as possible; a tick is "
           "timed from wake to published; one bare solve of the same system in the same run\n");
    printf("%-10s %8s %5s %8s %9s %9s | %9s %12s | %8s %6s %6s %5s %5s\n", "scene", "vertices",
           "ticks", "ticks/s", "median ms", "p99 ms", "solve ms", "median/solve", "ev/tick",
           "CG/ev", "fs/ev", "facts", "bg");
    for (int i = 0; i < n; i++) {
        const iso_cli__rt_row *r = &rows[i];
        double ev = r->evaluations > 0 ? (double)r->evaluations : NAN;
        printf("%-9s%s %8d %5ld %8.1f %9.2f %9.2f | %9.2f %12.1f | %8d %6.2f %6.2f %5ld %5ld\n",
               r->scene, r->builtin ? "*" : " ", r->vertices, r->ticks, r->ticks_per_s,
               r->median_ms, r->p99_ms, r->bare_solve_ms, over_solve(r), r->max_step_evaluations,
               (double)r->cg_iterations / ev, (double)r->factor_solves / ev, r->factorizations,
               r->handovers);
    }
    printf("ev/tick: the most field evaluations one tick made; CG/ev: PCG iterations per "
           "evaluation; fs/ev: solves with a factor per evaluation (PCG's start, its iterations "
           "that did not end on the residual, direct solves); facts: factorizations on the tick's "
           "thread; bg: factors the worker handed "
           "over (solver.worker_lag); * built-in shape\n");
}

#define RT(key, type, member) key, type, offsetof(iso_cli__rt_row, member)
static const iso_json_field rt_fields[] = {
    {RT("scene", ISO_JSON_TEXT, scene)},
    {RT("builtin", ISO_JSON_BOOL, builtin)},
    {RT("vertices", ISO_JSON_INT, vertices)},
    {RT("ticks", ISO_JSON_LONG, ticks)},
    {RT("ticks_per_s", ISO_JSON_DOUBLE, ticks_per_s)},
    {RT("tick_median_ms", ISO_JSON_DOUBLE, median_ms)},
    {RT("tick_p99_ms", ISO_JSON_DOUBLE, p99_ms)},
    {RT("bare_solve_ms", ISO_JSON_DOUBLE, bare_solve_ms)},
};
static const iso_json_field rt_counts[] = {
    {RT("max_step_evaluations", ISO_JSON_INT, max_step_evaluations)},
    {RT("evaluations", ISO_JSON_LONG, evaluations)},
    {RT("cg_iterations", ISO_JSON_LONG, cg_iterations)},
    {RT("factor_solves", ISO_JSON_LONG, factor_solves)},
    {RT("factorizations", ISO_JSON_LONG, factorizations)},
    {RT("handovers", ISO_JSON_LONG, handovers)},
};

void iso_cli__bench_realtime_json(iso_json *j, const iso_cli__rt_row *rows, int n)
{
    for (int i = 0; i < n; i++) {
        iso_json_object(j, NULL);
        iso_json_fields(j, &rows[i], rt_fields, sizeof rt_fields / sizeof rt_fields[0]);
        iso_json_number(j, "median_tick_over_bare_solve", over_solve(&rows[i]));
        iso_json_fields(j, &rows[i], rt_counts, sizeof rt_counts / sizeof rt_counts[0]);
        iso_json_close(j);
    }
}
