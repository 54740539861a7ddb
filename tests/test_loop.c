/* tests/test_loop.c -- the tick engine (controller/iso_loop.h) in-process.
 *
 * - Exact stream time: a scripted path's last tick is at its end, and the
 *   mesh's handle vertices sit at the `.def` pose to 1e-12 of the diagonal
 *   (they are placed from the exact path pose, never integrated); a duration
 *   D runs round(D × tick_hz) ticks.
 * - The loop converges to the offline integrator at its order: against
 *   iso_integrate with 1920 fixed steps (what `deform --steps 1920` runs),
 *   the error at 60 Hz over the error at 120 Hz is at least 6 (third order
 *   gives 8).
 * - No lost motion: a replay in real time on a loop slowed on purpose (a
 *   tick hook that sleeps) merges late ticks, and still ends with the
 *   handles at the `fast` replay's poses to 1e-9 of the diagonal, with the
 *   mesh's largest edge strain within 1.5× of the `fast` run's.
 *
 * - The reduced model (solver.proxy): handles exact on the whole mesh, fixed
 *   vertices at rest bit for bit, the same bits run to run.
 *
 * - CG's tolerance follows the integrator (iso_integrate.h, cg_share): on
 *   the cactus scene (config/scenes/cactus.yaml: the benchmark cactus when
 *   this test finds it, else the scene's own fallback, the built-in cactus),
 *   the final mesh differs from the same run with 1e-12 solves by less than
 *   a tenth of the integrator's own error, measured against 1e-12 solves at
 *   8x the tick rate.
 *
 * The mesh is the built-in cactus at resolution 1 (570 vertices), C assembly
 * and a factorization every evaluation: the same bits on every machine
 * (the cactus scene's test aside: adaptive refactoring, C assembly). */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_integrate.h"
#include "iso_loop.h"
#include "iso_metrics.h"

static iso_scene *scene_text(const char *text)
{
    iso_scene *sc = NULL;
    iso_err e;
    iso_err_clear(&e);
    if (iso_scene_load_mem(text, strlen(text), "t", NULL, &sc, &e) != ISO_OK)
        fail_msg("scene: %s", e.msg);
    return sc;
}

static iso_scene *scene(const char *driver, const char *devices, double hz)
{
    static char text[8192];
    snprintf(text, sizeof text,
             "name: t\n"
             "mesh: {shape: cactus, resolution: 1}\n"
             "%s"
             "regions:\n  sel: builtin\n  handles:\n    - name: top\n      driver: %s\n"
             "solver: {assembly: cpu, refactor: always}\n"
             "tick_hz: %.17g\n",
             devices, driver, hz);
    return scene_text(text);
}

typedef struct run_out {
    long ticks, misses, skipped, handovers;
    double strain;
    iso_pose handle;
    double *x; /* final positions, owned */
} run_out;

static void run(iso_scene *sc, const iso_loop_opts *o, run_out *r)
{
    iso_err e;
    iso_err_clear(&e);
    iso_loop *l = NULL;
    if (iso_loop_create(sc, o, &l, &e) != ISO_OK || iso_loop_run(l, &e) != ISO_OK)
        fail_msg("loop: %s", e.msg);
    iso_loop_summary s;
    iso_loop_get_summary(l, &s);
    r->ticks = s.ticks;
    r->misses = s.misses;
    r->skipped = s.skipped;
    r->handovers = s.solver.handovers;
    r->strain = s.metrics.max_edge_strain;
    r->handle = *iso_loop_commanded_pose(l, 0);
    size_t n = 3 * (size_t)iso_mesh_vertex_count(sc->mesh);
    r->x = malloc(n * sizeof *r->x);
    assert_non_null(r->x);
    memcpy(r->x, iso_loop_positions(l), n * sizeof *r->x);
    iso_loop_destroy(l);
}

static iso_loop_opts fast_opts(void)
{
    iso_loop_opts o;
    iso_loop_opts_default(&o);
    o.fast = 1;
    o.rt = 0;
    o.display = 0;
    return o;
}

static double max_diff3(const double *a, const double *b, size_t n)
{
    return iso_test_max_abs_diff(a, b, n);
}

/* ---- exact stream time ------------------------------------------------------ */

static void scripted_path_ends_on_its_pose(void **state)
{
    (void)state;
    iso_scene *sc = scene("{screw: {def: builtin, duration: 2.0}}", "", 60);
    iso_loop_opts o = fast_opts();
    run_out r;
    run(sc, &o, &r);
    assert_int_equal(r.ticks, 120);
    /* every handle vertex at M x_rest */
    const double *X = iso_mesh_positions(sc->mesh), *M = sc->shape_M;
    double worst = 0, diag = iso_mesh_bbox_diagonal(sc->mesh);
    for (int v = 0; v < iso_mesh_vertex_count(sc->mesh); v++) {
        if (sc->regions.kind[v] != ISO_HANDLE)
            continue;
        for (int i = 0; i < 3; i++) {
            double y = M[4 * i + 3];
            for (int j = 0; j < 3; j++)
                y += M[4 * i + j] * X[3 * v + j];
            worst = fmax(worst, fabs(y - r.x[3 * v + i]));
        }
    }
    printf("scripted cactus at 60 Hz: 120 ticks, handle at the .def pose to %.3g of the diagonal\n",
           worst / diag);
    assert_true(worst <= 1e-12 * diag);
    free(r.x);
    iso_scene_destroy(sc);
}

static void duration_runs_rounded_ticks(void **state)
{
    (void)state;
    static const struct {
        double hz, d;
        long ticks;
    } cases[] = {{60, 1, 60}, {60, 2, 120}, {30, 0.5, 15}, {120, 1, 120}, {60, 0.999, 60}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        iso_scene *sc = scene("none", "", cases[i].hz);
        iso_loop_opts o = fast_opts();
        o.duration_s = cases[i].d;
        run_out r;
        run(sc, &o, &r);
        printf("--duration %g at %g Hz: %ld ticks\n", cases[i].d, cases[i].hz, r.ticks);
        assert_int_equal(r.ticks, cases[i].ticks);
        free(r.x);
        iso_scene_destroy(sc);
    }
}

/* ---- convergence to the offline integrator ----------------------------------- */

static void loop_converges_at_its_order(void **state)
{
    (void)state;
    /* the reference: the screw over [0, 1] in 1920 fixed PECE steps */
    iso_scene *sc = scene("{screw: {def: builtin, duration: 1.0}}", "", 60);
    int nv = iso_mesh_vertex_count(sc->mesh);
    double *ref = malloc(3 * (size_t)nv * sizeof *ref);
    assert_non_null(ref);
    memcpy(ref, iso_mesh_positions(sc->mesh), 3 * (size_t)nv * sizeof *ref);
    iso_err e;
    iso_err_clear(&e);
    iso_solver *s = NULL;
    assert_int_equal(iso_solver_create(sc->mesh, &sc->regions, &sc->solver, &s, &e), ISO_OK);
    iso_twist xi = sc->handles[0].driver.twist;
    iso_screw_path sp = {&xi, 1};
    iso_path path = iso_screw_path_make(&sp);
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.steps = 1920;
    iso_integrate_stats st;
    assert_int_equal(iso_integrate(s, sc->mesh, &sc->regions, &path, &io, ref, &st, &e), ISO_OK);
    iso_solver_destroy(s);
    double diag = iso_mesh_bbox_diagonal(sc->mesh), err[3];
    static const double hz[3] = {30, 60, 120};
    for (int i = 0; i < 3; i++) {
        iso_scene *si = scene("{screw: {def: builtin, duration: 1.0}}", "", hz[i]);
        iso_loop_opts o = fast_opts();
        run_out r;
        run(si, &o, &r);
        err[i] = max_diff3(r.x, ref, 3 * (size_t)nv) / diag;
        printf("loop at %3.0f Hz: %ld ticks, %.3g of the diagonal from 1920 steps\n", hz[i],
               r.ticks, err[i]);
        free(r.x);
        iso_scene_destroy(si);
    }
    printf("error ratios: 30->60 Hz %.2f, 60->120 Hz %.2f (third order: 8)\n", err[0] / err[1],
           err[1] / err[2]);
    assert_true(err[1] / err[2] >= 6);
    free(ref);
    iso_scene_destroy(sc);
}

/* ---- no lost motion ------------------------------------------------------------ */

static void sleepy_tick(void *ctx, const iso_loop_tick_info *t)
{
    long *merged = ctx;
    if (t->merged > 1)
        (*merged)++;
    struct timespec ts = {0, 60 * 1000 * 1000}; /* a sink that takes 60 ms */
    nanosleep(&ts, NULL);
}

static void slowed_replay_keeps_the_motion(void **state)
{
    (void)state;
    char dev[4096];
    snprintf(dev, sizeof dev, "devices:\n  - {name: d, kind: replay, file: %s/sm_session.isorec}\n",
             ISO_TEST_STREAMS);
    iso_scene *sc = scene("{device: d}", dev, 60);
    iso_loop_opts o = fast_opts();
    run_out fast, slow;
    run(sc, &o, &fast);
    long merged = 0;
    o.fast = 0;
    o.speed = 4; /* 6.5 s of session in ~1.6 s, ticks every ~4 ms of wall time */
    o.on_tick = sleepy_tick;
    o.hook_ctx = &merged;
    run(sc, &o, &slow);
    double diag = iso_mesh_bbox_diagonal(sc->mesh), dp = 0, dR = 0;
    for (int j = 0; j < 3; j++)
        dp = fmax(dp, fabs(fast.handle.p[j] - slow.handle.p[j]));
    for (int j = 0; j < 9; j++)
        dR = fmax(dR, fabs(fast.handle.R[j] - slow.handle.R[j]));
    /* the mesh's handle vertices too: where the mesh actually is */
    double dh = 0;
    for (int v = 0; v < iso_mesh_vertex_count(sc->mesh); v++)
        if (sc->regions.kind[v] == ISO_HANDLE)
            for (int j = 0; j < 3; j++)
                dh = fmax(dh, fabs(fast.x[3 * v + j] - slow.x[3 * v + j]));
    printf("slowed replay: %ld ticks (%ld merged, %ld recorded ticks skipped) against %ld; "
           "commanded pose %.3g / %.3g, mesh handle %.3g of the diagonal; max edge strain %.4g "
           "against %.4g\n",
           slow.ticks, merged, slow.skipped, fast.ticks, dp / diag, dR, dh / diag, slow.strain,
           fast.strain);
    assert_true(merged > 0); /* the slowing worked: ticks were merged */
    assert_true(slow.ticks < fast.ticks);
    assert_true(dp <= 1e-9 * diag && dR <= 1e-9);
    assert_true(dh <= 1e-9 * diag);
    assert_true(slow.strain <= 1.5 * fast.strain);
    free(fast.x);
    free(slow.x);
    iso_scene_destroy(sc);
}

/* ---- the factorization worker -------------------------------------------------- */

/* With solver.worker_lag the factor each tick uses is fixed by evaluation
 * counts, so real time gives the bits --fast gives: in --fast the ticks
 * come as fast as they can and often wait for the worker; paced at half
 * speed (a tick every ~33 ms of wall time) the worker is always done
 * first. Without misses the step sequence is the same, and so must be
 * every bit of the mesh. */
static void worker_gives_the_same_bits_in_real_time(void **state)
{
    (void)state;
    iso_scene *sc = scene_text("name: t\n"
                               "mesh: {shape: cactus, resolution: 1}\n"
                               "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                               "      driver: {screw: {def: builtin, duration: 1.0}}\n"
                               "solver: {assembly: cpu, refactor: adaptive, worker_lag: 2}\n"
                               "integrator: {abm: pec}\n"
                               "tick_hz: 60\n");
    iso_loop_opts o = fast_opts();
    o.duration_s = 0.5;
    run_out fast, paced;
    run(sc, &o, &fast);
    o.fast = 0;
    o.speed = 0.5;
    run(sc, &o, &paced);
    size_t n = 3 * (size_t)iso_mesh_vertex_count(sc->mesh);
    printf("worker lag 2: %ld ticks, %ld factors handed over (--fast), %ld (paced, %ld missed)\n",
           fast.ticks, fast.handovers, paced.handovers, paced.misses);
    assert_true(fast.handovers > 0);
    if (paced.skipped > 0) {
        /* the property holds without misses only: a machine that cannot
         * keep half speed (a sanitized build) has nothing to compare */
        print_message("skipped: the paced run lost %ld deadlines (%ld of %ld ticks computed): "
                      "the comparison needs a build that keeps real time\n",
                      paced.skipped, paced.ticks, fast.ticks);
        free(fast.x);
        free(paced.x);
        iso_scene_destroy(sc);
        skip();
    }
    assert_int_equal(paced.ticks, fast.ticks);
    assert_int_equal(paced.handovers, fast.handovers);
    if (memcmp(fast.x, paced.x, n * sizeof *fast.x) != 0)
        fail_msg("paced run differs from --fast by %g", max_diff3(fast.x, paced.x, n));
    free(fast.x);
    free(paced.x);
    iso_scene_destroy(sc);
}

/* ---- the reduced model in the loop -------------------------------------------- */

/* solver.proxy N: the loop steps a proxy of at most N vertices and the whole
 * mesh follows it; the handles are still placed exactly on the whole mesh
 * (at the .def pose, as without a proxy), fixed vertices stay at rest bit
 * for bit, the free ones move, and a second run gives the same bits (a
 * replay builds the same proxy). */
static void the_reduced_model_follows_exactly_where_it_must(void **state)
{
    (void)state;
    iso_scene *sc = scene_text("name: t\n"
                               "mesh: {shape: cactus, resolution: 1}\n"
                               "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                               "      driver: {screw: {def: builtin, duration: 1.0}}\n"
                               "solver: {assembly: cpu, refactor: adaptive, worker_lag: 2, "
                               "proxy: 250}\n"
                               "integrator: {abm: pec}\n"
                               "tick_hz: 60\n");
    iso_loop_opts o = fast_opts();
    run_out a, b;
    iso_loop *l = NULL;
    iso_err e;
    iso_err_clear(&e);
    if (iso_loop_create(sc, &o, &l, &e) != ISO_OK)
        fail_msg("loop: %s", e.msg);
    iso_loop_summary s;
    iso_loop_get_summary(l, &s);
    iso_loop_destroy(l);
    int nv = iso_mesh_vertex_count(sc->mesh);
    assert_true(s.proxy_vertices >= 200 && s.proxy_vertices <= 250 && s.proxy_vertices < nv);
    run(sc, &o, &a);
    run(sc, &o, &b);
    assert_int_equal(a.ticks, 60);
    const double *X = iso_mesh_positions(sc->mesh), *M = sc->shape_M;
    double handle = 0, fixed = 0, moved = 0, diag = iso_mesh_bbox_diagonal(sc->mesh);
    for (int v = 0; v < nv; v++)
        for (int i = 0; i < 3; i++) {
            double d = fabs(a.x[3 * v + i] - X[3 * v + i]);
            if (sc->regions.kind[v] == ISO_FIXED) {
                fixed = fmax(fixed, d);
            } else if (sc->regions.kind[v] == ISO_HANDLE) {
                double y = M[4 * i + 3];
                for (int j = 0; j < 3; j++)
                    y += M[4 * i + j] * X[3 * v + j];
                handle = fmax(handle, fabs(y - a.x[3 * v + i]));
            } else {
                moved = fmax(moved, d);
            }
        }
    printf("reduced model: a proxy of %d vertices for %d; handles at the .def pose to %.3g of "
           "the diagonal, fixed vertices moved %.3g, free ones up to %.3g\n",
           s.proxy_vertices, nv, handle / diag, fixed, moved / diag);
    assert_true(handle <= 1e-12 * diag);
    assert_true(fixed == 0);
    assert_true(moved > 1e-3 * diag);
    size_t n = 3 * (size_t)nv;
    if (memcmp(a.x, b.x, n * sizeof *a.x) != 0)
        fail_msg("a second run differs by %g", max_diff3(a.x, b.x, n));
    free(a.x);
    free(b.x);
    iso_scene_destroy(sc);
}

/* ---- restoration in the loop -------------------------------------------------- */

/* The built-in bar's twist at 60 Hz under PEC, the shipped scenes' mode:
 * restoration (μ 1, τ 0.05 s, the mode's default κ) ends with lower
 * metricErr and areaErr than the paper's method. (The benchmark's bar, not
 * shipped, is where κ 4 failed this: iso_integrate.h has the figures; this
 * smaller mesh holds at κ 4 too, 3.32 / 6.05, so it guards the property,
 * not that choice.) */
static void restoration_in_the_loop_is_no_worse(void **state)
{
    (void)state;
    static const char *const restore[2] = {"off", "{mu: 1.0, tau: 0.05}"};
    double metric[2], area[2];
    for (int i = 0; i < 2; i++) {
        char text[1024];
        snprintf(text, sizeof text,
                 "name: bar\nmesh: {shape: bar, resolution: 4}\n"
                 "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                 "      driver: {screw: {def: builtin, duration: 2.0}}\n"
                 "solver: {assembly: cpu, refactor: always, restore: %s}\n"
                 "integrator: {abm: pec}\ntick_hz: 60\n",
                 restore[i]);
        iso_scene *sc = scene_text(text);
        iso_loop_opts o = fast_opts();
        iso_err e;
        iso_err_clear(&e);
        iso_loop *l = NULL;
        if (iso_loop_create(sc, &o, &l, &e) != ISO_OK || iso_loop_run(l, &e) != ISO_OK)
            fail_msg("loop: %s", e.msg);
        iso_loop_summary s;
        iso_loop_get_summary(l, &s);
        metric[i] = s.metrics.metric_err;
        area[i] = s.metrics.area_err;
        iso_loop_destroy(l);
        iso_scene_destroy(sc);
    }
    printf("bar at 60 Hz, PEC: restoration off metricErr %.4g areaErr %.4g; on %.4g %.4g\n",
           metric[0], area[0], metric[1], area[1]);
    assert_true(metric[1] <= metric[0]);
    assert_true(area[1] <= area[0]);
}

/* ---- CG's tolerance follows the integrator ------------------------------------ */

/* config/scenes/ of this source tree (from this file's own path). */
static const char *scenes_dir(void)
{
    static char dir[1024];
    snprintf(dir, sizeof dir, "%s", __FILE__);
    char *t = strstr(dir, "tests/test_loop.c");
    if (t)
        snprintf(t, sizeof dir - (size_t)(t - dir), "config/scenes");
    else
        snprintf(dir, sizeof dir, "../config/scenes");
    return dir;
}

/* The scene's benchmark lookup: the cactus under ISO_BENCHMARK_DIR. A
 * sanitizer build runs ~10x slower, so there the scene's built-in cactus
 * (2274 vertices against 5261) stands in and keeps the test short. */
static int find_benchmark(void *ctx, const char *name, char *mesh, char *sel, char *def, char *why,
                          size_t why_cap)
{
    (void)ctx;
#ifdef __SANITIZE_ADDRESS__
    (void)name, (void)mesh, (void)sel, (void)def;
    return snprintf(why, why_cap, "not looked for in a sanitizer build"), 0;
#endif
    if (strcmp(name, "cactus") != 0)
        return snprintf(why, why_cap, "only the cactus is looked for"), 0;
    int ok = iso_test_benchmark(mesh, ISO_SCENE_PATH_MAX, "03-cactus-bend/cactus.off") &&
             iso_test_benchmark(sel, ISO_SCENE_PATH_MAX, "03-cactus-bend/cactus.sel") &&
             iso_test_benchmark(def, ISO_SCENE_PATH_MAX, "03-cactus-bend/cactus.def");
    if (!ok)
        snprintf(why, why_cap, "%s/03-cactus-bend", ISO_BENCHMARK_DIR);
    return ok;
}

/* The cactus scene as written, on the C assembly, at tick_hz × hz_scale,
 * with CG's share of the step error `share` (0: cg_tol 1e-12) and the
 * solver's worker_lag and worker_ahead. */
static double *cactus_scene_run(double hz_scale, double share, int worker_lag, int ahead, long *cg,
                                int *nv, double *diag, int *benchmark)
{
    char path[1200];
    snprintf(path, sizeof path, "%s/cactus.yaml", scenes_dir());
    iso_scene_opts so = {find_benchmark, NULL, 0};
    iso_scene *sc = NULL;
    iso_err e;
    iso_err_clear(&e);
    if (iso_scene_load_opts(path, &so, &sc, &e) != ISO_OK)
        fail_msg("%s: %s", path, e.msg);
    assert_int_equal(sc->solver.refactor, ISO_REFACTOR_ADAPTIVE);
    sc->solver.assembly = ISO_ASSEMBLY_CPU; /* bit-identical everywhere, no kernel build */
    sc->tick_hz *= hz_scale;
    sc->integrate.cg_share = share;
    sc->solver.worker_lag = worker_lag;
    sc->solver.worker_ahead = ahead;
    if (share == 0)
        sc->solver.cg_tol = 1e-12;
    iso_loop_opts o = fast_opts();
    iso_loop *l = NULL;
    if (iso_loop_create(sc, &o, &l, &e) != ISO_OK || iso_loop_run(l, &e) != ISO_OK)
        fail_msg("loop: %s", e.msg);
    iso_loop_summary s;
    iso_loop_get_summary(l, &s);
    *cg = s.solver.cg_iterations;
    *nv = iso_mesh_vertex_count(sc->mesh);
    *diag = iso_mesh_bbox_diagonal(sc->mesh);
    *benchmark = sc->mesh_src.used == ISO_SCENE_MESH_BENCHMARK;
    double *x = malloc(3 * (size_t)*nv * sizeof *x);
    assert_non_null(x);
    memcpy(x, iso_loop_positions(l), 3 * (size_t)*nv * sizeof *x);
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    return x;
}

/* The same with the factorization worker (solver.worker_lag 4), its
 * factors assembled ahead (worker_ahead, the default) or at the giving
 * evaluation: older factors change how PCG gets there, not where the
 * target lets it stop; assembled ahead, they are nearer the matrices they
 * serve, so PCG needs fewer iterations. */
static void cg_tolerance_follows_the_integrator(void **state)
{
    (void)state;
    long cg[5];
    int nv, bench;
    double diag;
    double *x = cactus_scene_run(1, ISO_INTEGRATE_CG_SHARE, 0, 1, &cg[0], &nv, &diag, &bench);
    double *xw = cactus_scene_run(1, ISO_INTEGRATE_CG_SHARE, 4, 1, &cg[3], &nv, &diag, &bench);
    double *xb = cactus_scene_run(1, ISO_INTEGRATE_CG_SHARE, 4, 0, &cg[4], &nv, &diag, &bench);
    double *exact = cactus_scene_run(1, 0, 0, 1, &cg[1], &nv, &diag, &bench);
    double *fine = cactus_scene_run(8, 0, 0, 1, &cg[2], &nv, &diag, &bench);
    double d_cg = iso_test_vertex_max_diff(x, exact, nv) / diag;
    double d_worker = iso_test_vertex_max_diff(xw, exact, nv) / diag;
    double d_behind = iso_test_vertex_max_diff(xb, exact, nv) / diag;
    double d_int = iso_test_vertex_max_diff(exact, fine, nv) / diag;
    printf("cactus scene (%s, %d vertices), 60 Hz PEC, adaptive refactoring:\n",
           bench ? "benchmark" : "the scene's fallback, the built-in shape", nv);
    printf("  CG at share %.2g against 1e-12 solves: %.3g of the diagonal (%ld against %ld "
           "CG iterations)\n",
           ISO_INTEGRATE_CG_SHARE, d_cg, cg[0], cg[1]);
    printf("  the same with the factorization worker (worker_lag 4): %.3g (%ld CG iterations); "
           "its factors not assembled ahead: %.3g (%ld)\n",
           d_worker, cg[3], d_behind, cg[4]);
    printf("  integrator's own error (1e-12 solves, against 480 Hz): %.3g of the diagonal\n",
           d_int);
    printf("  CG's part of it: %.3g, with the worker %.3g and %.3g (required below 0.1)\n",
           d_cg / d_int, d_worker / d_int, d_behind / d_int);
    assert_true(d_int > 0);
    assert_true(d_cg < 0.1 * d_int);
    assert_true(d_worker < 0.1 * d_int);
    assert_true(d_behind < 0.1 * d_int);
    assert_true(cg[0] < cg[1]);
    assert_true(cg[3] < cg[4]);
    free(x);
    free(xw);
    free(xb);
    free(exact);
    free(fine);
}

/* ---- the summary for people ------------------------------------------------ */

/* The summary stays within 100 columns whatever the sinks report (the
 * actuators' counters are some 600 characters), says "actuators" once, and
 * labels every distortion figure with what it measures. */
static void summary_is_readable(void **state)
{
    (void)state;
    iso_scene *sc = scene("{screw: {def: builtin, duration: 0.1}}", "", 60);
    iso_loop_summary *s = calloc(1, sizeof *s);
    assert_non_null(s);
    s->ticks = 6;
    s->metrics.metric_err = 1.5e-3;
    s->metrics.max_edge_strain = 0.0125;
    s->n_devices = 1;
    snprintf(s->device_desc[0], sizeof s->device_desc[0],
             "hid SpaceMouse Wireless (receiver) (256f:c652, replayed)");
    snprintf(s->act_line, sizeof s->act_line,
             "actuators: 1200 ticks, 1200 setpoints sent, 1198 acked, 0 echo mismatches (0 "
             "unchecked), 3 clamps, rtt avg 0.079 ms (max 0.085), publish max 0.01 ms (0 over 1 "
             "ms); link up, losses 0, reopens 0, emulation restarts 0, loop stalls 0, e-stops 0, "
             "silences 0, safe states confirmed 1; fb link: sent 1206 frames (25130 B), received "
             "1217 (45628 B); dropped 0 (crc 0, cobs 0, too long 0, short 0, seq dup 0, seq order "
             "0), 0 lost in gaps; acks 1198, naks 0, faults 1, samples 1208; link losses 0, "
             "reopens 0, handshakes 2; rtt avg 0.08 ms (min 0.05, max 0.31); safe state reported "
             "101 ms after the last setpoints");
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    assert_non_null(f);
    iso_loop_print_summary(s, sc, f);
    assert_int_equal(fclose(f), 0);
    printf("%s", text);
    for (const char *l = text; *l; l += strcspn(l, "\n") + (l[strcspn(l, "\n")] != '\0'))
        if (strcspn(l, "\n") > 100)
            fail_msg("a summary line of %zu characters: %.*s", strcspn(l, "\n"),
                     (int)strcspn(l, "\n"), l);
    assert_null(strstr(text, "actuators: "));
    assert_non_null(strstr(text, "  actuators   1200 ticks"));
    assert_non_null(strstr(text, "safe state reported 101 ms")); /* nothing cut */
    size_t n;
    const iso_metrics_measure *k = iso_metrics_measures(&n);
    for (size_t i = 0; i < n; i++) {
        char line[256];
        snprintf(line, sizeof line, "%-14s %.6e", k[i].name, iso_metrics_value(&s->metrics, &k[i]));
        const char *at = strstr(text, line);
        assert_non_null(at);
        assert_non_null(strstr(at, k[i].what));
    }
    free(text);
    free(s);
    iso_scene_destroy(sc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(summary_is_readable),
        cmocka_unit_test(scripted_path_ends_on_its_pose),
        cmocka_unit_test(duration_runs_rounded_ticks),
        cmocka_unit_test(loop_converges_at_its_order),
        cmocka_unit_test(slowed_replay_keeps_the_motion),
        cmocka_unit_test(restoration_in_the_loop_is_no_worse),
        cmocka_unit_test(cg_tolerance_follows_the_integrator),
        cmocka_unit_test(worker_gives_the_same_bits_in_real_time),
        cmocka_unit_test(the_reduced_model_follows_exactly_where_it_must),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
