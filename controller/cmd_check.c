/* controller/cmd_check.c -- isoshape check SCENE: validates a scene file
 * without running it. Loads the mesh and regions (config/iso_scene.h) and
 * builds the solver, so ill-posed constraints are caught too; prints a short
 * summary and exits 0, or the error and exits 1. */
#include "internal.h"

#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

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

static void print_summary(const iso_scene *s)
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
    char why[300];
    int budget = iso_proxy_choose(s->mesh, s->solver.proxy, s->tick_hz, why, sizeof why);
    printf("  model: %s\n", why);
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
    if (iso_cli__scene_load("check", path, &s) != 0)
        return 1;
    iso_solver *solver = NULL;
    iso_solver_opts so = s->solver;
    so.assembly = ISO_ASSEMBLY_CPU; /* the constraints' check does not need OpenCL */
    if (iso_solver_create(s->mesh, &s->regions, &so, &solver, &err) != ISO_OK) {
        fprintf(stderr, "isoshape check: %s: regions: %s\n", s->path, err.msg);
        iso_scene_destroy(s);
        return 1;
    }
    print_summary(s);
    printf("ok\n");
    iso_solver_destroy(solver);
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
