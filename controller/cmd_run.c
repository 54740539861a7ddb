/* controller/cmd_run.c -- `isoshape run SCENE`: the real-time loop on a
 * scene file (controller/loop.h). Ctrl-C or SIGTERM stops it after the
 * current tick; the recording is closed whole, the actuators go to their
 * safe state and the final mesh and statistics are written before exit. A
 * second Ctrl-C kills at once. */
#include "internal.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include <unistd.h>

#include "iso_loop.h"
#include "iso_outfile.h"
#include "iso_snapshot.h"

/* The one piece of file-scope state: a signal handler can reach nothing else. */
static volatile sig_atomic_t g_stop;
static void on_signal(int sig)
{
    g_stop = sig;
    signal(sig, SIG_DFL); /* a second one ends the process */
}

typedef struct run_args {
    const char *scene, *out, *json, *png;
    iso_outfile out_f, json_f, png_f; /* where each goes (iso_outfile.h), planned before the run */
    int quiet, ticks, exit_at_end;
    int abm; /* iso_abm_mode, -1: the scene's */
    iso_loop_opts lo;
} run_args;

static const iso_cli__opt run_options[] = {
    {"fast", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(run_args, lo.fast), NULL,
     .help = "no waiting: as fast as possible on stream time (replays and scripted scenes give "
             "the same result at any speed)",
     .flag = 1},
    {"speed", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(run_args, lo.speed), "X",
     .help = "stream seconds per wall second, %R (default 1; --fast runs without waiting)",
     ISO_CLI_GT(0)},
    {"duration", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(run_args, lo.duration_s), "S",
     .help = "stop after S seconds of stream time, S %R", ISO_CLI_GT(0)},
    {"ticks", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(run_args, ticks), "N",
     .help = "stop after N ticks, N %R", ISO_CLI_GE(1)},
    {"no-display", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(run_args, lo.display), NULL,
     .help = "no live view, whatever the scene says", .flag = 0},
    {"display", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(run_args, lo.display), NULL,
     .help = "the live view even if the scene has none", .flag = 1},
    {"port", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(run_args, lo.port), "N",
     .help = "live view port %R (0: any free port; default: the scene's)", ISO_CLI_GE(0),
     ISO_CLI_LE(65535)},
    {"no-rt", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(run_args, lo.rt), NULL,
     .help = "do not ask for real-time scheduling and locked memory", .flag = 0},
    {"abm", ISO_CLI_OPT_ENUM, ISO_CLI_INT_AT(run_args, abm), NULL,
     .help = "the integrator mode: pece (the paper's, two field evaluations a step) or pec "
             "(one); default: the scene's",
     .names = iso_abm_mode_names},
    {"assembly", ISO_CLI_OPT_ENUM, ISO_CLI_INT_AT(run_args, lo.assembly), NULL,
     .help = "who fills the system each evaluation (default: the scene's)",
     .names = iso_assembly_names},
    {"cl-device", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(run_args, lo.cl_device), "SPEC",
     .help = "OpenCL device (see isoshape deform --help)"},
    {"record", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(run_args, lo.record), "FILE",
     .help = "record the devices to FILE (overrides the scene; empty: no recording)"},
    {"out", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(run_args, out), "FILE",
     .help = "write the final mesh (OFF, OBJ or PLY by extension)"},
    {"png", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(run_args, png), "FILE",
     .help = "write a picture of the final mesh, coloured by distortion"},
    {"stats-json", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(run_args, json), "FILE",
     .help = "write the summary as JSON"},
    {"pc2", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(run_args, lo.pc2), "FILE",
     .help = "write every tick into a PC2 point cache for Blender's Mesh Cache modifier, the "
             "rest mesh beside it as FILE's name with .rest.ply",
     .nonempty = 1},
    {"mcap", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(run_args, lo.mcap), "FILE",
     .help = "write the session into an MCAP file for Foxglove: the mesh, the handles' poses, "
             "the devices, the ticks and the actuators",
     .nonempty = 1},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_INT_AT(run_args, lo.mcap_compression),
     .table = iso_cli__mcap_compression_options},
    {"quiet", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(run_args, quiet), NULL,
     .help = "no status line and no summary", .flag = 1},
    {"exit-at-end", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(run_args, exit_at_end), NULL,
     .help = "exit when the run ends; on a terminal the live view otherwise stays up with the "
             "last frame until Ctrl-C",
     .flag = 1},
    {0}};

/* Returns -1 to go on, else the exit status: 0 after --help, 2 on a usage
 * error. */
static int parse(int argc, char **argv, run_args *a)
{
    iso_cli__loop_opts_default(&a->lo, "run");
    a->lo.rt = 1; /* the command runs in real time unless --no-rt */
    a->abm = -1;
    int status = iso_cli__parse(&iso_cli__run_cmd, argc, argv, a, &a->scene, 1, NULL);
    if (status >= 0)
        return status;
    if (!a->scene) {
        iso_cli__fail("run",
                      "missing SCENE (usage: isoshape run SCENE; scenes are in config/scenes).");
        return 2;
    }
    if (a->ticks > 0)
        a->lo.max_ticks = a->ticks;
    a->lo.status_line = !a->quiet && isatty(STDERR_FILENO);
    return -1;
}

/* An output's folder must exist and be writable before a long run starts. */
static int check_folder(const char *opt, const char *path)
{
    char dir[ISO_CLI_PATH_MAX];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash == dir)
        dir[1] = 0;
    else if (slash)
        *slash = 0;
    else
        snprintf(dir, sizeof dir, ".");
    if (access(dir, W_OK) != 0) {
        iso_cli__fail("run", "%s %s: cannot write in %s: %s", opt, path, dir, strerror(errno));
        return -1;
    }
    return 0;
}

/* Whether a mesh file's name says its format (iso_mesh_save chooses by it). */
static int mesh_extension_known(const char *path)
{
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash))
        return 0;
    return strcasecmp(dot, ".off") == 0 || strcasecmp(dot, ".obj") == 0 ||
           strcasecmp(dot, ".ply") == 0;
}

/* Plans an output of the run's end (iso_outfile.h): what it replaces and
 * where it is written, or why it cannot be, said before the run starts. */
static int plan_output(const char *opt, const char *path, iso_outfile *o)
{
    iso_err err;
    iso_err_clear(&err);
    if (iso_outfile_plan(o, opt, path, ISO_OUTFILE_SEQUENTIAL, &err) != ISO_OK) {
        iso_cli__fail("run", "%s", err.msg);
        return -1;
    }
    return o->through ? 0 : check_folder(opt, o->final);
}

static int plan_outputs(run_args *a)
{
    if (a->out && !mesh_extension_known(a->out)) {
        iso_cli__fail("run",
                      "--out %s: the name must end in .off, .obj or .ply (the format "
                      "follows it)",
                      a->out);
        return -1;
    }
    return (a->out && plan_output("--out", a->out, &a->out_f)) ||
                   (a->png && plan_output("--png", a->png, &a->png_f)) ||
                   (a->json && plan_output("--stats-json", a->json, &a->json_f)) ||
                   (a->lo.pc2 && check_folder("--pc2", a->lo.pc2)) ||
                   (a->lo.mcap && check_folder("--mcap", a->lo.mcap)) ||
                   (a->lo.record && a->lo.record[0] && check_folder("--record", a->lo.record))
               ? -1
               : 0;
}

static void abort_outputs(run_args *a)
{
    iso_outfile_abort(&a->out_f);
    iso_outfile_abort(&a->png_f);
    iso_outfile_abort(&a->json_f);
}

enum { OUT_MESH, OUT_PNG, OUT_JSON };

/* Writes one output where it was planned, then commits it (a rename onto
 * a regular file; nothing for a FIFO or a device, written through): a
 * failure never leaves a truncated file. Returns 0, or 1 after saying why. */
static int write_output(int what, const char *opt, iso_outfile *o, iso_loop *l, const iso_scene *sc,
                        const iso_loop_summary *s)
{
    iso_err err;
    iso_err_clear(&err);
    const char *w = o->write;
    int rc = what == OUT_MESH  ? iso_mesh_save(iso_loop_mesh(l), iso_loop_positions(l), w,
                                               ISO_MESH_FMT_AUTO, &err)
             : what == OUT_PNG ? iso_snapshot_png(iso_loop_mesh(l), iso_loop_positions(l),
                                                  &sc->regions, w, 960, 720, NULL, &err)
                               : iso_loop_write_json(s, sc, w, &err);
    if (rc != ISO_OK) {
        iso_loop_say(l, "%s %s: %s", opt, o->path, err.msg);
        iso_outfile_abort(o);
        return 1;
    }
    if (iso_outfile_commit(o, opt, &err) != ISO_OK) {
        iso_loop_say(l, "%s", err.msg);
        return 1;
    }
    return 0;
}

/* The summary as text, for the page (NULL when it cannot be made). */
static char *summary_text(const iso_loop_summary *s, const iso_scene *sc)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (!f)
        return NULL;
    iso_loop_print_summary(s, sc, f);
    if (fclose(f) != 0) {
        free(buf);
        return NULL;
    }
    return buf;
}

/* A run that ended by itself on a terminal keeps its view up: the page
 * shows the last frame and the summary until Ctrl-C (scripts, with no
 * terminal, or --exit-at-end, are not held). */
static void hold_view(iso_loop *l, const iso_scene *sc, const iso_loop_summary *s,
                      const run_args *a)
{
    if (a->exit_at_end || g_stop || !isatty(STDIN_FILENO) || !isatty(STDERR_FILENO))
        return;
    char url[512];
    char *text = summary_text(s, sc);
    int up = iso_loop_view_end(l, text, url, sizeof url);
    free(text);
    if (!up)
        return;
    iso_loop_say(l,
                 "the run has ended; the live view keeps showing its last frame and this "
                 "summary at %s: press Ctrl-C to quit (--exit-at-end does not wait)",
                 url);
    while (!g_stop) {
        struct timespec ts = {0, 100 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    g_stop = 0; /* the run ended by itself: leaving the view is no interruption */
}

/* What is left to do once the loop has stopped, for whatever reason. */
static int finish(iso_loop *l, const iso_scene *sc, run_args *a, int status)
{
    iso_err err;
    iso_err_clear(&err);
    if (iso_loop_shutdown(l, &err) != ISO_OK) {
        iso_loop_say(l, "shutdown: %s", err.msg);
        status = 1;
    }
    iso_loop_summary s;
    iso_loop_get_summary(l, &s);
    if (!a->quiet) {
        iso_loop_print_summary(&s, sc, stdout);
        printf("  memory      peak %.0f MB (the process, as the kernel counts it)\n",
               iso_cli__peak_mb());
    }
    if (a->out && write_output(OUT_MESH, "--out", &a->out_f, l, sc, &s))
        status = 1;
    if (a->png) {
        if (write_output(OUT_PNG, "--png", &a->png_f, l, sc, &s))
            status = 1;
        else if (!a->quiet)
            printf("  picture     %s\n", a->png);
    }
    if (a->json && write_output(OUT_JSON, "--stats-json", &a->json_f, l, sc, &s))
        status = 1;
    if (status == 0)
        hold_view(l, sc, &s, a);
    return status;
}

static int run_main(int argc, char **argv)
{
    run_args a;
    memset(&a, 0, sizeof a);
    int r = parse(argc, argv, &a);
    if (r >= 0)
        return r;
    if (plan_outputs(&a) != 0) {
        abort_outputs(&a);
        return 1;
    }
    iso_scene *sc = NULL;
    if (iso_cli__scene_load("run", a.scene, &sc) != 0) {
        abort_outputs(&a);
        return 1;
    }
    if (a.abm >= 0)
        sc->abm_mode = a.abm;
    g_stop = 0;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal; /* no SA_RESTART: clock_nanosleep wakes on it */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    a.lo.stop = &g_stop;
    iso_err err;
    iso_err_clear(&err);
    iso_loop *l = NULL;
    if (iso_loop_create(sc, &a.lo, &l, &err) != ISO_OK) {
        iso_cli__fail("run", "%s", err.msg);
        iso_scene_destroy(sc);
        abort_outputs(&a);
        return 1;
    }
    /* From here on stderr is written through the loop's log, which never
     * blocks: a stderr nobody reads cannot keep a stop from ending the run. */
    int status = 0;
    if (iso_loop_run(l, &err) != ISO_OK) {
        iso_loop_say(l, "%s", err.msg);
        status = 1;
    }
    int sig = g_stop;
    if (sig)
        iso_loop_say(l, "stopped by %s; shutting down cleanly",
                     sig == SIGINT ? "SIGINT" : "SIGTERM");
    status = finish(l, sc, &a, status);
    abort_outputs(&a); /* what was not written (a failed run's) leaves nothing behind */
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    return status == 0 && sig ? 128 + sig : status;
}

const iso_cli__cmd iso_cli__run_cmd = {
    .name = "run",
    .summary = "run a scene: devices or a replay drive the mesh in real time",
    .usage = "usage: isoshape run SCENE [options]\n"
             "  Runs a scene file (config/SCENES.md): each tick reads the devices (or a\n"
             "  replayed recording, or the scripted drivers), advances the mesh by one ABM\n"
             "  step of one tick, and publishes it to the scene's sinks. Prints a live status\n"
             "  line on a terminal and a summary at the end.\n"
             "\n",
    .opts = run_options,
    .after = "\n"
             "  Output files are written whole or not at all (a temporary name, then a\n"
             "  rename), and their folders are checked before the run starts. Exit status:\n"
             "  0 done, 1 failed, 2 bad options; 130 or 143 when SIGINT or SIGTERM stopped\n"
             "  the run (after a clean shutdown: files written, actuators safe).\n",
    .main = run_main};
