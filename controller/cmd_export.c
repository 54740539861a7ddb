/* controller/cmd_export.c -- `isoshape export REC --mcap OUT`: a recording
 * replayed through the tick engine as fast as the machine goes, into an
 * MCAP file that Foxglove Studio opens (sinks/iso_foxglove.h lists the
 * channels). Log times are stream time and the replay is deterministic, so
 * the same recording and options export the same bytes: the wall-clock
 * figures a live run records (/loop's tick_ms, latency_ms) are left out.
 * Nothing is driven: no live view, no actuators (a scene's /actuators
 * channel comes from `run --mcap` only). A recording cut off is said once,
 * by the tick engine as it opens the file (the sentence run and replay
 * print, with the byte where it ends), and the file holds the ticks before
 * the cut; the exit status is 0, as theirs is. */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "iso_loop.h"
#include "iso_mcap.h"

const iso_cli__opt iso_cli__mcap_compression_options[] = {
    {"mcap-compression", ISO_CLI_OPT_ENUM, 0, NULL,
     .help = "how the MCAP file's chunks are written: zstd (the default; Foxglove Studio and the "
             "mcap tools read it) or none, for a reader without zstd",
     .names = iso_mcap_compression_names},
    {0}};

typedef struct export_args {
    const char *path, *mcap, *scene;
    int steps;
    int compression; /* iso_mcap_compression */
    iso_cli__source src;
    iso_dev_map_opts mo;
} export_args;

static const iso_cli__opt export_options[] = {
    {"mcap", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(export_args, mcap), "OUT",
     .help = "the MCAP file to write", .nonempty = 1},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_INT_AT(export_args, compression),
     .table = iso_cli__mcap_compression_options},
    {NULL, ISO_CLI_OPT_HEADING, 0, NULL,
     .help = "The scene the recording moves: a scene file (its one device becomes the\n"
             "recording), or a mesh as `isoshape replay` takes it:"},
    {"scene", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(export_args, scene), "SCENE",
     .help = "a scene file (config/scenes)", .nonempty = 1},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(export_args, src, iso_cli__source),
     .table = iso_cli__shape_or_mesh_options},
    {"steps", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(export_args, steps), "N",
     .help = "ABM steps per tick with --shape or --mesh, %R (default 1)", ISO_CLI_GE(1)},
    {NULL, ISO_CLI_OPT_HEADING, 0, NULL, .help = "Mapping (with --shape or --mesh):"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(export_args, mo, iso_dev_map_opts),
     .table = iso_cli__dev_map_options},
    {0}};

static int parse(int argc, char **argv, export_args *a)
{
    int status = iso_cli__parse(&iso_cli__export_cmd, argc, argv, a, &a->path, 1, NULL);
    if (status >= 0)
        return status;
    const char *why = !a->path   ? "no recording given (isoshape export REC --mcap OUT)."
                      : !a->mcap ? "nothing to export to: --mcap OUT."
                                 : NULL;
    int mesh = a->src.shape || a->src.mesh || a->src.sel;
    if (!why && !a->scene && !mesh)
        why = "the recording needs a scene to move: --scene SCENE, --shape NAME, or --mesh and "
              "--sel.";
    if (!why && a->scene && mesh)
        why = "--scene, or --shape / --mesh: not both.";
    if (!why && mesh && !a->src.shape && (!a->src.mesh || !a->src.sel))
        why = "a mesh needs both --mesh and --sel.";
    if (why) {
        iso_cli__fail("export", "%s", why);
        return 2;
    }
    return -1;
}

/* A scene file, its one device replaced by the recording. */
static int scene_file(const export_args *a, iso_scene **out, iso_err *err)
{
    if (iso_cli__scene_load("export", a->scene, out) != 0)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: the scene could not be loaded", a->scene);
    iso_scene *sc = *out;
    if (sc->n_devices != 1 || !sc->mesh)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s: export needs a scene with a mesh and exactly one device, the one "
                           "the recording stands for (it has %d)",
                           a->scene, sc->n_devices);
    sc->devices[0].backend = ISO_SCENE_DEV_REPLAY;
    snprintf(sc->devices[0].path, sizeof sc->devices[0].path, "%s", a->path);
    sc->actuators.enabled = 0;
    sc->display.enabled = 0;
    sc->display.n_snapshots = 0;
    sc->ply.enabled = 0;
    sc->recording[0] = 0;
    return ISO_OK;
}

static int export_main(int argc, char **argv)
{
    export_args a;
    memset(&a, 0, sizeof a);
    iso_dev_map_opts_default(&a.mo);
    int status = parse(argc, argv, &a);
    if (status >= 0)
        return status;
    iso_err err;
    iso_err_clear(&err);
    iso_scene *sc = NULL;
    int rc = a.scene ? scene_file(&a, &sc, &err)
                     : iso_cli__replay_scene(a.path, &a.src, &a.mo, a.steps, &sc, &err);
    iso_loop_opts lo;
    iso_cli__loop_opts_default(&lo, "export");
    lo.fast = 1;
    lo.rt = 0;
    lo.display = 0;
    lo.mcap = a.mcap;
    lo.mcap_compression = a.compression;
    iso_loop *l = NULL;
    if (rc == ISO_OK)
        rc = iso_loop_create(sc, &lo, &l, &err);
    if (rc == ISO_OK)
        rc = iso_loop_run(l, &err);
    iso_loop_summary s;
    memset(&s, 0, sizeof s);
    if (l) {
        int r2 = iso_loop_shutdown(l, &err); /* writes the summary and renames the file */
        rc = rc == ISO_OK ? r2 : rc;
        iso_loop_get_summary(l, &s);
    }
    if (rc == ISO_OK) {
        struct stat st;
        long long bytes = stat(a.mcap, &st) == 0 ? (long long)st.st_size : -1;
        printf("%s: %ld ticks, %.3f s of stream time -> %s: %ld messages, %lld bytes\n", a.path,
               s.ticks, s.stream_s, a.mcap, s.mcap_messages, bytes);
        if (s.frames_dropped)
            printf("  %ld ticks dropped: the disk was slower than the export\n", s.frames_dropped);
    } else {
        iso_cli__fail("export", "%s", err.msg);
        status = 1;
    }
    iso_loop_destroy(l);
    iso_cli__replay_scene_free(sc);
    return rc == ISO_OK ? 0 : 1;
}

const iso_cli__cmd iso_cli__export_cmd = {
    .name = "export",
    .summary = "replay a recording into an MCAP file for Foxglove",
    .usage = "usage: isoshape export REC --mcap OUT --scene SCENE\n"
             "       isoshape export REC --mcap OUT --shape NAME [options]\n"
             "\n"
             "Replays a device recording through the tick engine as fast as the machine goes,\n"
             "moving a scene, and writes the session into OUT (MCAP, for Foxglove Studio):\n"
             "the mesh coloured by strain (/mesh), each handle's commanded and achieved pose\n"
             "(/handles/NAME/...), the ticks (/loop) and each device's decoded state and\n"
             "counters (/devices/I). Times are stream time: the same recording and options\n"
             "give the same file. OUT is written under a temporary name and renamed at the end.\n"
             "\n",
    .opts = export_options,
    .main = export_main};
