/* controller/cli_scene.c -- loading a scene file for the command: the scene
 * layer resolves `benchmark:` through the command's own lookup, so a scene
 * finds the benchmark exactly where --benchmark does. */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>

#include "iso_scene.h"

int iso_cli__scene_bench_find(void *ctx, const char *name, char *mesh, char *sel, char *def,
                              char *why, size_t why_cap)
{
    iso_cli__bench b;
    if (!iso_cli__bench_find(name, ctx, &b, why, why_cap))
        return 0;
    snprintf(mesh, ISO_SCENE_PATH_MAX, "%s", b.mesh);
    snprintf(sel, ISO_SCENE_PATH_MAX, "%s", b.sel);
    snprintf(def, ISO_SCENE_PATH_MAX, "%s", b.def);
    return 1;
}

int iso_cli__scene_load(const char *cmd, const char *path, iso_scene **out)
{
    iso_err err;
    iso_err_clear(&err);
    iso_scene_opts opts = {.bench_find = iso_cli__scene_bench_find};
    if (iso_scene_load_opts(path, &opts, out, &err) != ISO_OK) {
        fprintf(stderr, "isoshape %s: %s\n", cmd, err.msg);
        return 1;
    }
    if ((*out)->mesh_src.note[0])
        fprintf(stderr, "isoshape %s: %s\n", cmd, (*out)->mesh_src.note);
    return 0;
}

iso_scene *iso_cli__device_scene(const char *name, double hz, const iso_dev_map_opts *m)
{
    iso_scene *sc = calloc(1, sizeof *sc);
    if (!sc)
        return NULL;
    snprintf(sc->name, sizeof sc->name, "%s", name);
    sc->tick_hz = hz;
    sc->n_handles = m->n_handles;
    for (int h = 0; h < sc->n_handles; h++) {
        snprintf(sc->handles[h].name, sizeof sc->handles[h].name, "handle %d", h);
        sc->handles[h].driver.kind = ISO_SCENE_DRIVE_DEVICE;
        sc->handles[h].driver.map = *m;
    }
    return sc;
}
