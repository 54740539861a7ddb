/* controller/cmd_replay.c -- `isoshape replay FILE`: a recording through
 * the tick engine (iso_loop.h), alone or moving a scene, at the recorded
 * speed, scaled, or as fast as possible. The tick commands depend on the
 * recording and the options only: the summary checksum and the handles'
 * final poses are the same at any speed the machine keeps up with.
 */
#include "internal.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_dev_decode.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_loop.h"

/* A YAML string: quoted, with the two characters that need it escaped. */
static void yaml_str(char *dst, size_t cap, const char *s)
{
    size_t n = 0;
    if (cap < 3)
        return;
    dst[n++] = '"';
    for (; *s && n + 3 < cap; s++) {
        if (*s == '"' || *s == '\\')
            dst[n++] = '\\';
        dst[n++] = *s;
    }
    dst[n++] = '"';
    dst[n] = 0;
}

typedef struct replay_args {
    const char *path, *out, *pc2, *mcap;
    double speed, tick_ms;
    int fast, print, steps;
    int mcap_compression; /* iso_mcap_compression */
    iso_cli__source src;
    iso_dev_map_opts mo;
} replay_args;

/* A scene for the recording: its mesh (a built-in shape, or --mesh and
 * --sel), one handle driven by the replay, C assembly (the same bits on
 * every machine); without a mesh, the device side alone. */
static int build_scene(const replay_args *a, iso_scene **out, iso_err *err)
{
    char rec[2 * ISO_CLI_PATH_MAX + 8];
    char abs[ISO_CLI_PATH_MAX];
    yaml_str(rec, sizeof rec, realpath(a->path, abs) ? abs : a->path);
    double hz = 1000.0 / a->tick_ms;
    if (!a->src.shape && !a->src.mesh) {
        iso_scene *sc = iso_cli__device_scene("replay", hz, &a->mo);
        if (!sc)
            return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for a scene");
        snprintf(sc->path, sizeof sc->path, "%s", a->path);
        sc->n_devices = 1;
        snprintf(sc->devices[0].name, sizeof sc->devices[0].name, "recording");
        sc->devices[0].backend = ISO_SCENE_DEV_REPLAY;
        snprintf(sc->devices[0].path, sizeof sc->devices[0].path, "%s", a->path);
        *out = sc;
        return ISO_OK;
    }
    static char text[8 * ISO_CLI_PATH_MAX + 1024];
    char mesh[2 * ISO_CLI_PATH_MAX + 64], sel[2 * ISO_CLI_PATH_MAX + 8];
    if (a->src.shape) {
        snprintf(mesh, sizeof mesh, "{shape: %s, resolution: %d}", a->src.shape, a->src.resolution);
        snprintf(sel, sizeof sel, "builtin");
    } else {
        yaml_str(mesh, sizeof mesh, realpath(a->src.mesh, abs) ? abs : a->src.mesh);
        yaml_str(sel, sizeof sel, realpath(a->src.sel, abs) ? abs : a->src.sel);
    }
    snprintf(text, sizeof text,
             "name: replay\n"
             "mesh: %s\n"
             "devices:\n  - {name: recording, kind: replay, file: %s}\n"
             "regions:\n  sel: %s\n  handles:\n    - {name: handle, driver: {device: recording}}\n"
             "solver: {assembly: cpu, refactor: always}\n"
             "tick_hz: %.17g\n",
             mesh, rec, sel, hz);
    int rc = iso_scene_load_mem(text, strlen(text), "replay", NULL, out, err);
    if (rc != ISO_OK)
        return rc;
    (*out)->handles[0].driver.map = a->mo;
    (*out)->steps_per_tick = a->steps > 0 ? a->steps : 1;
    return ISO_OK;
}

/* The recorded loop's period, from its first two TICK records: the first
 * tick is then as long as it was there (as in `run` of a scene at that
 * rate). *tick_ms is left alone for recordings without TICK records. A
 * missing or broken file is named here, before a mesh loads. */
static int probe_period(const char *path, double *tick_ms, iso_err *err)
{
    iso_dev_rec_reader probe;
    int rc = iso_dev_rec_reader_load(&probe, path, err);
    if (rc != ISO_OK)
        return rc;
    iso_dev_chunk c;
    int64_t t1 = INT64_MIN;
    while (iso_dev_rec_next(&probe, &c, NULL) == 1) {
        if (c.type != ISO_DEV_CHUNK_TICK)
            continue;
        if (t1 != INT64_MIN && c.t_ns > t1) {
            *tick_ms = (double)(c.t_ns - t1) * 1e-6;
            break;
        }
        t1 = c.t_ns;
    }
    iso_dev_rec_reader_deinit(&probe);
    return ISO_OK;
}

int iso_cli__replay_scene(const char *path, const iso_cli__source *src, const iso_dev_map_opts *mo,
                          int steps, iso_scene **out, iso_err *err)
{
    replay_args a;
    memset(&a, 0, sizeof a);
    a.path = path;
    a.src = *src;
    a.mo = *mo;
    a.steps = steps;
    a.tick_ms = 1;
    int rc = probe_period(path, &a.tick_ms, err);
    return rc == ISO_OK ? build_scene(&a, out, err) : rc;
}

void iso_cli__replay_scene_free(iso_scene *sc)
{
    if (sc && sc->mesh)
        iso_scene_destroy(sc);
    else
        free(sc);
}

typedef struct print_ctx {
    int64_t first;
} print_ctx;

static void print_command(void *ctx, const iso_dev_tick *out, double dt)
{
    print_ctx *pc = ctx;
    (void)dt;
    if (pc->first == INT64_MIN)
        pc->first = out->t_ns;
    const iso_twist *x = &out->twist[out->active];
    printf("%.6f h%d%s%s b%08" PRIx32 " w %a %a %a v %a %a %a\n",
           (double)(out->t_ns - pc->first) * 1e-9, out->active, out->clutch ? " clutch" : "",
           out->estop ? " ESTOP" : "", out->buttons, x->w[0], x->w[1], x->w[2], x->v[0], x->v[1],
           x->v[2]);
}

/* What the recording gave: ticks, records, damage, the commands' checksum,
 * the handles' commanded poses; with a mesh, the vertices' checksum. */
static void report(const replay_args *a, iso_loop *l, const iso_scene *sc, const char *label)
{
    iso_loop_summary s;
    iso_loop_get_summary(l, &s);
    const iso_dev_rec_reader *r = iso_loop_replay_reader(l);
    printf("%s: %ld ticks, %ld records, %ld damaged, commands checksum %016" PRIx64 "\n", a->path,
           s.device_ticks, r ? r->records : 0, r ? r->damaged : 0, s.commands_checksum);
    for (int k = 0; k < s.n_handles; k++) {
        const iso_pose *P = iso_loop_commanded_pose(l, k);
        printf("handle %d: p %.17g %.17g %.17g  R %.17g %.17g %.17g %.17g %.17g %.17g %.17g "
               "%.17g %.17g\n",
               k, P->p[0], P->p[1], P->p[2], P->R[0], P->R[1], P->R[2], P->R[3], P->R[4], P->R[5],
               P->R[6], P->R[7], P->R[8]);
    }
    const iso_dev_hub *h = iso_loop_hub(l);
    for (size_t k = 0; h && k < iso_dev_hub_sources(h); k++) {
        const iso_dev_counters *n = &iso_dev_hub_decoder(h, k)->n;
        if (n->short_reports || n->unknown_ids || n->bad_frames || n->garbage)
            fprintf(stderr,
                    "isoshape replay: source %zu: skipped %u short reports, %u unknown IDs, %u "
                    "bad frames, %u garbage bytes (%u resyncs, %u bytes not recorded)\n",
                    k, n->short_reports, n->unknown_ids, n->bad_frames, n->garbage, n->resyncs,
                    n->unrecorded);
    }
    if (sc->mesh)
        printf("scene %s: %d vertices, %d steps, vertices checksum %016" PRIx64 "\n", label,
               iso_mesh_vertex_count(sc->mesh), s.integ.steps, s.checksum);
    if (s.misses > 0)
        fprintf(stderr,
                "isoshape replay: the machine fell behind the recording: %ld late ticks took "
                "%ld recorded ticks more; the handles' poses are the same as at --fast, the "
                "mesh's steps are not\n",
                s.misses, s.skipped);
}

static const iso_cli__opt replay_options[] = {
    {"speed", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(replay_args, speed), "X",
     .help = "X times the recorded speed, %R (default 1; --fast for no waiting)", ISO_CLI_GT(0)},
    {"fast", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(replay_args, fast), NULL,
     .help = "as fast as possible", .flag = 1},
    {"tick-ms", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(replay_args, tick_ms), "T",
     .help = "tick length for recordings without TICK records, %R (default 1)", ISO_CLI_GT(0)},
    {"print-ticks", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(replay_args, print), NULL,
     .help = "one line per tick: time, active handle, clutch, e-stop, buttons, and the active "
             "handle's twist (w, v) in %a",
     .flag = 1},
    {NULL, ISO_CLI_OPT_HEADING, 0, NULL,
     .help = "A scene moved by the replayed commands, as `isoshape run` moves it, with a\n"
             "checksum of its vertices:"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(replay_args, src, iso_cli__source),
     .table = iso_cli__shape_or_mesh_options},
    {"steps", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(replay_args, steps), "N",
     .help = "ABM steps per tick, %R (default 1)", .solver = "steps_per_tick"},
    {"out", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(replay_args, out), "FILE",
     .help = "save the deformed mesh"},
    {"pc2", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(replay_args, pc2), "FILE",
     .help = "write every tick into a PC2 point cache, the rest mesh beside it (FILE's name "
             "with .rest.ply)",
     .nonempty = 1},
    {"mcap", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(replay_args, mcap), "FILE",
     .help = "write the session into an MCAP file (see isoshape export)", .nonempty = 1},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_INT_AT(replay_args, mcap_compression),
     .table = iso_cli__mcap_compression_options},
    {NULL, ISO_CLI_OPT_HEADING, 0, NULL, .help = "Mapping:"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(replay_args, mo, iso_dev_map_opts),
     .table = iso_cli__dev_map_options},
    {0}};

/* Returns -1 to go on, else the exit status: 0 after --help, 2 on a usage
 * error. */
static int parse(int argc, char **argv, replay_args *a)
{
    const char *cmd = "replay";
    int status = iso_cli__parse(&iso_cli__replay_cmd, argc, argv, a, &a->path, 1, NULL);
    if (status >= 0)
        return status;
    if (!a->path) {
        iso_cli__fail(cmd, "no recording given (isoshape replay FILE).");
        return 2;
    }
    int scene = a->src.shape || a->src.mesh || a->src.sel;
    if (scene && !a->src.shape && (!a->src.mesh || !a->src.sel)) {
        iso_cli__fail(cmd, "a scene needs --shape NAME, or both --mesh and --sel.");
        return 2;
    }
    if ((a->out || a->pc2 || a->mcap) && !scene) {
        iso_cli__fail(cmd, "--%s needs a scene (--shape, or --mesh and --sel).",
                      a->out   ? "out"
                      : a->pc2 ? "pc2"
                               : "mcap");
        return 2;
    }
    return -1;
}

static int replay_main(int argc, char **argv)
{
    const char *cmd = "replay";
    replay_args a;
    memset(&a, 0, sizeof a);
    a.speed = 1;
    a.tick_ms = 1;
    iso_dev_map_opts_default(&a.mo);
    int r = parse(argc, argv, &a);
    if (r >= 0)
        return r;
    iso_err err;
    iso_err_clear(&err);
    iso_dev_map m; /* the options' own check, before anything is loaded */
    if (iso_dev_map_init(&m, &a.mo, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 2;
    }
    if (probe_period(a.path, &a.tick_ms, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 1;
    }
    iso_scene *sc = NULL;
    if (build_scene(&a, &sc, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 1;
    }
    char label[ISO_CLI_PATH_MAX + 64];
    if (a.src.shape)
        snprintf(label, sizeof label, "built-in %s (resolution %d)", a.src.shape, a.src.resolution);
    else
        snprintf(label, sizeof label, "%s", a.src.mesh ? a.src.mesh : "");
    iso_loop_opts lo;
    iso_cli__loop_opts_default(&lo, cmd);
    lo.fast = a.fast;
    lo.speed = a.speed;
    lo.rt = 0;
    lo.display = 0;
    lo.pc2 = a.pc2;
    lo.mcap = a.mcap;
    lo.mcap_compression = a.mcap_compression;
    print_ctx pc = {INT64_MIN};
    if (a.print) {
        lo.on_command = print_command;
        lo.hook_ctx = &pc;
    }
    iso_loop *l = NULL;
    int status = 0;
    if (iso_loop_create(sc, &lo, &l, &err) != ISO_OK || iso_loop_run(l, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        status = 1;
    }
    if (l && status == 0) {
        report(&a, l, sc, label);
        if (a.out && iso_mesh_save(sc->mesh, iso_loop_positions(l), a.out, ISO_MESH_FMT_AUTO,
                                   &err) != ISO_OK) {
            iso_cli__fail(cmd, "--out: %s", err.msg);
            status = 1;
        }
    }
    iso_loop_destroy(l);
    iso_cli__replay_scene_free(sc);
    return status;
}

const iso_cli__cmd iso_cli__replay_cmd = {
    .name = "replay",
    .summary = "replay a device recording, deterministically, at any speed",
    .usage = "usage: isoshape replay FILE [options]\n"
             "\n"
             "Replays a recording (devices/RECORDING.md) through the tick engine that\n"
             "`isoshape run` uses: the decoders and the mapping, one tick at each of its TICK\n"
             "records, and prints a summary: ticks, a checksum of every tick's handle commands,\n"
             "and each handle's commanded pose. The result is the same bit for bit at any speed\n"
             "unless the machine falls behind in real time (then late ticks merge, as in `run`).\n"
             "\n",
    .opts = replay_options,
    .main = replay_main};
