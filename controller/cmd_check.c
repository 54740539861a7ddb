/* controller/cmd_check.c -- isoshape check SCENE: validates a scene file
 * without running it. Loads the mesh and regions (config/iso_scene.h) and
 * checks them as the solver will (iso_solver_check), so ill-posed
 * constraints are caught too, without building the system; prints a short
 * summary and exits 0, or the error and exits 1. */
#include "internal.h"

#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_proxy.h"
#include "iso_scene.h"

/* A recording on a FIFO is written through, and the run refuses one that
 * no one reads (opening it would wait for a reader): said here, so that
 * `check` does not pass over what `run` may refuse. Not opened to see
 * whether a reader is there: a writer that opens and closes would give
 * that reader its end of file. "" for anything else. */
static const char *fifo_note(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISFIFO(st.st_mode))
        return "";
    return " (a FIFO: written through; start its reader before the run, which refuses a FIFO "
           "that no one reads)";
}

/* Measured peak memory of `run --fast` on the reduced model (this
 * machine, no sinks; MiB throughout): 150 at 40k vertices (bumpplane
 * 201), 193 at 164k, 288 at 400k, 542 at 1M (tentacle 128, 200, 317): a
 * fixed part (the libraries, the proxy's solver) and a share per vertex
 * of the mesh, the line through the ends, within 4% between them. */
#define CHECK_PROXY_BASE_MB 133.0
#define CHECK_PROXY_BYTES_PER_VERTEX 426.0

/* A need beyond the machine's memory is said beside it: such a run
 * swaps or is killed, and the reduced model (solver.proxy) is the way out. */
static void beyond_machine(double mb, char *out, size_t cap, int used)
{
    if (used < 0 || (size_t)used >= cap)
        return; /* the sentence before filled the room */
    out += used;
    cap -= (size_t)used;
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    double have = pages > 0 && page > 0 ? (double)pages * (double)page / (1024.0 * 1024.0) : 0.0;
    if (have > 0 && mb > have)
        snprintf(out, cap, ": more than this machine's %.0f MB", have);
}

/* What a run of this scene will hold, said before anyone starts one: the
 * reduced model's from the measured line above; the whole mesh's from its
 * factor's size, which only CHOLMOD's symbolic analysis knows (seconds and
 * gigabytes at a million vertices, so said before it starts). */
static int run_memory(const iso_scene *s, int proxy_budget, char *out, size_t cap)
{
    int nv = iso_mesh_vertex_count(s->mesh);
    if (proxy_budget > 0) {
        double mb = CHECK_PROXY_BASE_MB + CHECK_PROXY_BYTES_PER_VERTEX * nv / (1024.0 * 1024.0);
        int n = snprintf(out, cap,
                         "about %.0f MB on the reduced model (measured: %.0f MB and %.0f bytes a "
                         "vertex, sinks aside)",
                         mb, CHECK_PROXY_BASE_MB, CHECK_PROXY_BYTES_PER_VERTEX);
        beyond_machine(mb, out, cap, n);
        return 0;
    }
    if (nv >= 100000)
        fprintf(stderr,
                "isoshape check: analysing the whole mesh's factor for its size (%d vertices: "
                "seconds)...\n",
                nv);
    iso_solver_opts so = s->solver;
    so.assembly = ISO_ASSEMBLY_CPU; /* the factor's size does not need OpenCL */
    so.worker_lag = 0;              /* nor the worker's thread */
    iso_solver *solver = NULL;
    iso_err err;
    iso_err_clear(&err);
    if (iso_solver_create(s->mesh, &s->regions, &so, &solver, &err) != ISO_OK) {
        fprintf(stderr, "isoshape check: %s: solver: %s\n", s->path, err.msg);
        return 1;
    }
    iso_solver_stats st;
    iso_solver_get_stats(solver, &st);
    iso_solver_destroy(solver);
    int held = s->solver.worker_lag > 0 ? 2 : 1;
    int n = snprintf(out, cap, "the whole mesh's factor %.0f MB%s (the mesh and the rest aside)",
                     (double)st.factor_bytes / (1024.0 * 1024.0),
                     held > 1 ? ", held twice with the worker" : "");
    beyond_machine(held * (double)st.factor_bytes / (1024.0 * 1024.0), out, cap, n);
    return 0;
}

static void print_summary(const iso_scene *s, int budget, const char *why, const char *memory)
{
    const iso_scene_mesh_src *m = &s->mesh_src;
    int nv = iso_mesh_vertex_count(s->mesh);
    int counts[3] = {0, 0, 0};
    for (int v = 0; v < nv; v++)
        counts[s->regions.kind[v] <= ISO_HANDLE ? s->regions.kind[v] : 1]++;
    printf("scene %s: %s\n", s->name, s->path);
    if (m->used == ISO_SCENE_MESH_BENCHMARK)
        printf("  mesh: benchmark %s (%s)\n", m->benchmark, m->path);
    else if (m->used == ISO_SCENE_MESH_SHAPE)
        printf("  mesh: built-in shape %s%s\n",
               m->fallback_shape[0] && m->kind == ISO_SCENE_MESH_BENCHMARK ? m->fallback_shape
                                                                           : m->shape,
               m->note[0] ? " (benchmark absent)" : "");
    else
        printf("  mesh: %s\n", m->path);
    printf("  vertices %d, triangles %d: free %d, fixed %d, handle %d\n", nv,
           iso_mesh_triangle_count(s->mesh), counts[ISO_FREE], counts[ISO_FIXED],
           counts[ISO_HANDLE]);
    for (int h = 0; h < s->n_handles; h++) {
        const iso_scene_handle *hd = &s->handles[h];
        const iso_scene_driver *d = &hd->driver;
        printf("  handle %d '%s': %d vertices, driven by %s", h, hd->name, hd->region.count,
               iso_scene_driver_name(d->kind));
        if (d->kind == ISO_SCENE_DRIVE_DEVICE)
            printf(" '%s' (%s)", s->devices[d->device].name,
                   iso_scene_backend_name(s->devices[d->device].backend));
        else if (d->kind == ISO_SCENE_DRIVE_SCREW)
            printf(" over %g s", d->duration);
        else if (d->kind == ISO_SCENE_DRIVE_KEYFRAMES)
            printf(" (%d keyframes, %g s)", d->n_keys, d->keys[d->n_keys - 1].t);
        printf("\n");
    }
    printf("  solver: omega %g, %s weighting, restore %s; tick %g Hz, ABM3 %s\n", s->solver.omega,
           iso_names_get(iso_weighting_names, s->solver.weighting),
           s->solver.restore_mu > 0 ? "on" : "off", s->tick_hz,
           iso_abm_mode_name((iso_abm_mode)s->abm_mode));
    printf("  model: %s\n", why);
    printf("  memory: %s\n", memory);
    if (budget <= 0 && s->solver.proxy_smoothness != ISO_PROXY_SMOOTHNESS_MESH)
        printf("  note: solver.proxy_smoothness is ignored: there is no proxy\n");
    printf("  sinks:");
    if (s->display.enabled)
        printf(" display %s:%d", s->display.host, s->display.port);
    if (s->ply.enabled)
        printf(" ply %s (every %d)", s->ply.dir, s->ply.every);
    if (s->actuators.enabled)
        printf(" actuators %d channels over %s", s->actuators.n_ch,
               iso_scene_link_name(s->actuators.link));
    if (!s->display.enabled && !s->ply.enabled && !s->actuators.enabled)
        printf(" none");
    printf("\n");
    if (s->recording[0])
        printf("  recording: %s%s\n", s->recording, fifo_note(s->recording));
}

static const iso_cli__opt check_options[] = {{0}};

static int check_main(int argc, char **argv)
{
    const char *path = NULL;
    int status = iso_cli__parse(&iso_cli__check_cmd, argc, argv, NULL, &path, 1, NULL);
    if (status >= 0)
        return status;
    if (!path) {
        iso_cli__fail("check", "missing SCENE (usage: isoshape check SCENE)");
        return 2;
    }
    iso_err err;
    iso_err_clear(&err);
    iso_scene *s = NULL;
    double t0 = iso_clock_now();
    if (iso_cli__scene_load("check", path, &s) != 0)
        return 1;
    if (iso_solver_check(s->mesh, &s->regions, &s->solver, &err) != ISO_OK) {
        fprintf(stderr, "isoshape check: %s: regions: %s\n", s->path, err.msg);
        iso_scene_destroy(s);
        return 1;
    }
    char why[300], memory[300];
    int budget = iso_proxy_choose(s->mesh, s->solver.proxy, s->tick_hz, why, sizeof why);
    if (run_memory(s, budget, memory, sizeof memory) != 0) {
        iso_scene_destroy(s);
        return 1;
    }
    print_summary(s, budget, why, memory);
    printf("  check: %.2f s, peak memory %.0f MB\n", iso_clock_now() - t0, iso_cli__peak_mb());
    printf("ok\n");
    iso_scene_destroy(s);
    return 0;
}

const iso_cli__cmd iso_cli__check_cmd = {
    .name = "check",
    .summary = "validate a scene file without running it",
    .usage = "usage: isoshape check SCENE\n"
             "  Validates a scene file (config/SCENES.md) without running it: loads the\n"
             "  mesh and regions, builds the solver, prints a summary. Exit 0 if valid.\n",
    .opts = check_options,
    .main = check_main};
