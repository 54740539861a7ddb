/* controller/cmd_replay.c -- `isoshape replay FILE`: a recording through
 * the tick engine (iso_loop.h), alone or moving a scene, at the recorded
 * speed, scaled, or as fast as possible. The tick commands depend on the
 * recording and the options only: the summary checksum and the handles'
 * final poses are the same at any speed the machine keeps up with.
 * Also the mapping options shared with `isoshape record`. */
#include "internal.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_dev.h"
#include "iso_loop.h"

int iso_cli__replay(int argc, char **argv);
int iso_cli__dev_map_option(const char *cmd, int argc, char **argv, int *i, iso_dev_map_opts *o);

#define ISO_CLI_DEV_MAP_HELP                                                                       \
    "  --handles N        handles the devices drive (1..8; a 'next handle' button cycles)\n"       \
    "  --sensitivity L,A  at full deflection: L m/s and A rad/s (default 0.1,0.5)\n"               \
    "  --dead-zone F      fraction of full scale that maps to 0 (default 0.05)\n"                  \
    "  --curve E          response exponent (1 linear, 2 quadratic; default 1)\n"                  \
    "  --remap A,B,C,D,E,F  output axis i reads input axis (0..5: tx ty tz rx ry rz)\n"            \
    "  --invert AXES      comma list of axes to negate: tx,ty,tz,rx,ry,rz (or x,y,z)\n"            \
    "  --dominant         keep only the largest axis\n"                                            \
    "  --lock L           none, translation (translation only) or rotation (rotation only)\n"      \
    "  --frame F          world (default) or device: axes along the handle's own\n"                \
    "  --deadman          move only while the clutch is held (default: held = hold still)\n"

/* An axis of iso_dev_axis_names ("tx" .. "rz"); "x", "y" and "z" stand
 * for "tx", "ty" and "tz" (what this option took before scenes named them). */
static int axis_index(const char *s, size_t n)
{
    char word[4];
    if (n < 1 || n > 2)
        return -1;
    snprintf(word, sizeof word, "%s%.*s", n == 1 ? "t" : "", (int)n, s);
    return iso_names_find(iso_dev_axis_names, word);
}

/* A mapping number in the range devices/ holds it to (iso_dev_map_check). */
static int map_number(const char *cmd, const char *opt, const char *text, const char *field,
                      double v)
{
    char why[128];
    if (iso_dev_map_check(field, v, why, sizeof why) == 0)
        return 0;
    iso_cli__fail(cmd, "%s %s: %s.", opt, text, why);
    return -1;
}

int iso_cli__dev_map_option(const char *cmd, int argc, char **argv, int *i, iso_dev_map_opts *o)
{
    const char *v;
    int r;
    if (strcmp(argv[*i], "--dominant") == 0) {
        o->dominant = 1;
        return 1;
    }
    if (strcmp(argv[*i], "--deadman") == 0) {
        o->clutch_is_deadman = 1;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--handles", &v)) != 0) {
        if (r < 0 || iso_cli__int(cmd, "--handles", v, &o->n_handles) != 0)
            return -1;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--sensitivity", &v)) != 0) {
        double l, a;
        char tail;
        if (r < 0)
            return -1;
        if (sscanf(v, "%lf,%lf%c", &l, &a, &tail) != 2) {
            iso_cli__fail(cmd, "--sensitivity %s: give L,A (m/s and rad/s at full scale).", v);
            return -1;
        }
        if (map_number(cmd, "--sensitivity", v, "sensitivity", l) != 0 ||
            map_number(cmd, "--sensitivity", v, "sensitivity", a) != 0)
            return -1;
        for (int k = 0; k < 3; k++) {
            o->sensitivity[k] = l;
            o->sensitivity[k + 3] = a;
        }
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--dead-zone", &v)) != 0) {
        double d;
        if (r < 0 || iso_cli__double(cmd, "--dead-zone", v, &d) != 0 ||
            map_number(cmd, "--dead-zone", v, "dead_zone", d) != 0)
            return -1;
        for (int k = 0; k < 6; k++)
            o->dead_zone[k] = d;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--curve", &v)) != 0) {
        double e;
        if (r < 0 || iso_cli__double(cmd, "--curve", v, &e) != 0 ||
            map_number(cmd, "--curve", v, "curve", e) != 0)
            return -1;
        for (int k = 0; k < 6; k++)
            o->curve[k] = e;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--remap", &v)) != 0) {
        int m[6];
        char tail;
        if (r < 0)
            return -1;
        if (sscanf(v, "%d,%d,%d,%d,%d,%d%c", &m[0], &m[1], &m[2], &m[3], &m[4], &m[5], &tail) !=
            6) {
            iso_cli__fail(cmd, "--remap %s: give six input axes, e.g. 0,2,1,3,5,4.", v);
            return -1;
        }
        memcpy(o->remap, m, sizeof m);
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--invert", &v)) != 0) {
        if (r < 0)
            return -1;
        for (const char *p = v; *p;) {
            size_t n = strcspn(p, ",");
            int a = axis_index(p, n);
            if (a < 0) {
                iso_cli__fail(cmd, "--invert %s: '%.*s' is not one of tx,ty,tz,rx,ry,rz.", v,
                              (int)n, p);
                return -1;
            }
            o->invert[a] = 1;
            p += n + (p[n] == ',');
        }
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--lock", &v)) != 0) {
        if (r < 0)
            return -1;
        return iso_cli__enum(cmd, "--lock", v, iso_dev_lock_names, &o->lock) != 0 ? -1 : 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--frame", &v)) != 0) {
        if (r < 0)
            return -1;
        return iso_cli__enum(cmd, "--frame", v, iso_dev_frame_names, &o->frame) != 0 ? -1 : 1;
    }
    return 0;
}

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
    const char *path, *out;
    double speed, tick_ms;
    int fast, print, steps;
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
    if (r && r->torn)
        fprintf(stderr, "isoshape replay: %s: %s\n", a->path, r->note);
    const iso_dev_hub *h = iso_loop_hub(l);
    for (size_t k = 0; h && k < iso_dev_hub_sources(h); k++) {
        const iso_dev_counters *n = &iso_dev_hub_decoder(h, k)->n;
        if (n->short_reports || n->unknown_ids || n->bad_frames || n->garbage)
            fprintf(stderr,
                    "isoshape replay: source %zu: skipped %u short reports, %u unknown IDs, %u "
                    "bad frames, %u garbage bytes\n",
                    k, n->short_reports, n->unknown_ids, n->bad_frames, n->garbage);
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

static void usage(void)
{
    printf("usage: isoshape replay FILE [options]\n"
           "\n"
           "Replays a recording (devices/RECORDING.md) through the tick engine that\n"
           "`isoshape run` uses: the decoders and the mapping, one tick at each of its TICK\n"
           "records, and prints a summary: ticks, a checksum of every tick's handle commands,\n"
           "and each handle's commanded pose. The result is the same bit for bit at any speed\n"
           "unless the machine falls behind in real time (then late ticks merge, as in `run`).\n"
           "\n"
           "  --speed X          X times the recorded speed (default 1)\n"
           "  --fast             as fast as possible\n"
           "  --tick-ms T        tick length for recordings without TICK records (default 1)\n"
           "  --print-ticks      one line per tick: time, active handle, clutch, e-stop,\n"
           "                     buttons, and the active handle's twist (w, v) in %%a\n"
           "A scene moved by the replayed commands, as `isoshape run` moves it, with a\n"
           "checksum of its vertices:\n"
           "  --shape NAME       a built-in shape (bar, cylinder, bumpplane, cactus)\n"
           "  --resolution N     the built-in shape's resolution (0: its default)\n"
           "  --mesh M --sel S   or a mesh and its regions\n"
           "  --steps N          ABM steps per tick (default 1)\n"
           "  --out FILE         save the deformed mesh\n"
           "Mapping:\n" ISO_CLI_DEV_MAP_HELP);
}

/* Returns 0 to go on, 1 after --help, 2 on a usage error. */
static int parse(int argc, char **argv, replay_args *a)
{
    const char *cmd = "replay", *v;
    for (int i = 1; i < argc; i++) {
        int r;
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage();
            return 1;
        }
        if (strcmp(argv[i], "--fast") == 0) {
            a->fast = 1;
            continue;
        }
        if (strcmp(argv[i], "--print-ticks") == 0) {
            a->print = 1;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--speed", &v)) != 0) {
            if (r < 0 || iso_cli__double(cmd, "--speed", v, &a->speed) != 0)
                return 2;
            if (!(a->speed > 0)) {
                iso_cli__fail(cmd, "--speed %s must be > 0 (use --fast for no waiting).", v);
                return 2;
            }
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--tick-ms", &v)) != 0) {
            if (r < 0 || iso_cli__double(cmd, "--tick-ms", v, &a->tick_ms) != 0)
                return 2;
            if (!(a->tick_ms > 0)) {
                iso_cli__fail(cmd, "--tick-ms %s must be > 0.", v);
                return 2;
            }
            continue;
        }
        if ((r = iso_cli__dev_map_option(cmd, argc, argv, &i, &a->mo)) != 0) {
            if (r < 0)
                return 2;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--shape", &a->src.shape)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--mesh", &a->src.mesh)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--sel", &a->src.sel)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--out", &a->out)) != 0) {
            if (r < 0)
                return 2;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--resolution", &v)) != 0) {
            if (r < 0 || iso_cli__int(cmd, "--resolution", v, &a->src.resolution) != 0)
                return 2;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--steps", &v)) != 0) {
            if (r < 0 || iso_cli__int(cmd, "--steps", v, &a->steps) != 0)
                return 2;
            if (a->steps < 1) {
                iso_cli__fail(cmd, "--steps %s must be >= 1.", v);
                return 2;
            }
            continue;
        }
        if (argv[i][0] == '-' || a->path)
            return iso_cli__unknown(cmd, argv[i]);
        a->path = argv[i];
    }
    if (!a->path) {
        iso_cli__fail(cmd, "no recording given (isoshape replay FILE).");
        return 2;
    }
    int scene = a->src.shape || a->src.mesh || a->src.sel;
    if (scene && !a->src.shape && (!a->src.mesh || !a->src.sel)) {
        iso_cli__fail(cmd, "a scene needs --shape NAME, or both --mesh and --sel.");
        return 2;
    }
    if (a->out && !scene) {
        iso_cli__fail(cmd, "--out needs a scene (--shape, or --mesh and --sel).");
        return 2;
    }
    return 0;
}

int iso_cli__replay(int argc, char **argv)
{
    const char *cmd = "replay";
    replay_args a;
    memset(&a, 0, sizeof a);
    a.speed = 1;
    a.tick_ms = 1;
    iso_dev_map_opts_default(&a.mo);
    int r = parse(argc, argv, &a);
    if (r != 0)
        return r == 1 ? 0 : 2;
    iso_err err;
    iso_err_clear(&err);
    iso_dev_map m; /* the options' own check, before anything is loaded */
    if (iso_dev_map_init(&m, &a.mo, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 2;
    }
    iso_dev_rec_reader probe; /* a missing or broken file is named before a mesh loads */
    if (iso_dev_rec_reader_load(&probe, a.path, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 1;
    }
    /* The recorded loop's period, from its first two TICK records: the
     * first tick is then as long as it was there (as in `run` of a scene at
     * that rate). --tick-ms serves recordings without TICK records. */
    iso_dev_chunk c;
    int64_t t1 = INT64_MIN;
    while (iso_dev_rec_next(&probe, &c, NULL) == 1) {
        if (c.type != ISO_DEV_CHUNK_TICK)
            continue;
        if (t1 != INT64_MIN && c.t_ns > t1) {
            a.tick_ms = (double)(c.t_ns - t1) * 1e-6;
            break;
        }
        t1 = c.t_ns;
    }
    iso_dev_rec_reader_deinit(&probe);
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
    iso_loop_opts_default(&lo);
    iso_cli__solver_threads(&lo.threads);
    lo.cmd = cmd;
    lo.fast = a.fast;
    lo.speed = a.speed;
    lo.rt = 0;
    lo.display = 0;
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
    if (sc && sc->mesh)
        iso_scene_destroy(sc);
    else
        free(sc);
    return status;
}
