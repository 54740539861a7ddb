/* controller/cmd_run.c -- `isoshape run SCENE`: the real-time loop on a
 * scene file (controller/loop.h). Ctrl-C or SIGTERM stops it after the
 * current tick; the recording is closed whole, the actuators go to their
 * safe state and the final mesh and statistics are written before exit. A
 * second Ctrl-C kills at once. */
#include "internal.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "iso_loop.h"
#include "iso_snapshot.h"

int iso_cli__run_scene(int argc, char **argv);

/* The one piece of file-scope state: a signal handler can reach nothing else. */
static volatile sig_atomic_t g_stop;
static void on_signal(int sig)
{
    g_stop = sig;
    signal(sig, SIG_DFL); /* a second one ends the process */
}

static void usage(void)
{
    printf("usage: isoshape run SCENE [options]\n"
           "  Runs a scene file (config/SCENES.md): each tick reads the devices (or a\n"
           "  replayed recording, or the scripted drivers), advances the mesh by one ABM\n"
           "  step of one tick, and publishes it to the scene's sinks. Prints a live status\n"
           "  line on a terminal and a summary at the end.\n"
           "\n"
           "  --fast             no waiting: as fast as possible on stream time (replays and\n"
           "                     scripted scenes give the same result at any speed)\n"
           "  --speed X          stream seconds per wall second (default 1)\n"
           "  --duration S       stop after S seconds of stream time\n"
           "  --ticks N          stop after N ticks\n"
           "  --no-display       no live view, whatever the scene says\n"
           "  --display          the live view even if the scene has none\n"
           "  --port N           live view port (0: any free port; default: the scene's)\n"
           "  --no-rt            do not ask for real-time scheduling and locked memory\n"
           "  --abm M            pece (the paper's, two field evaluations a step) or pec\n"
           "                     (one): the integrator mode (default: the scene's)\n"
           "  --assembly A       cpu or opencl (default: the scene's)\n"
           "  --cl-device SPEC   OpenCL device (see isoshape deform --help)\n"
           "  --record FILE      record the devices to FILE (overrides the scene)\n"
           "  --out FILE         write the final mesh (OFF, OBJ or PLY by extension)\n"
           "  --png FILE         write a picture of the final mesh, coloured by distortion\n"
           "  --stats-json FILE  write the summary as JSON\n"
           "  --quiet            no status line and no summary\n"
           "\n"
           "  Output files are written whole or not at all (a temporary name, then a\n"
           "  rename), and their folders are checked before the run starts. Exit status:\n"
           "  0 done, 1 failed, 2 bad options; 130 or 143 when SIGINT or SIGTERM stopped\n"
           "  the run (after a clean shutdown: files written, actuators safe).\n");
}

typedef struct run_args {
    const char *scene, *out, *json, *png;
    int quiet;
    int abm; /* iso_abm_mode, -1: the scene's */
    iso_loop_opts lo;
} run_args;

static int parse_flag(run_args *a, const char *arg)
{
    if (strcmp(arg, "--fast") == 0)
        a->lo.fast = 1;
    else if (strcmp(arg, "--no-display") == 0)
        a->lo.display = 0;
    else if (strcmp(arg, "--display") == 0)
        a->lo.display = 1;
    else if (strcmp(arg, "--no-rt") == 0)
        a->lo.rt = 0;
    else if (strcmp(arg, "--quiet") == 0)
        a->quiet = 1;
    else
        return 0;
    return 1;
}

/* Returns 0 to go on, 1 when --help was printed, 2 on a usage error. */
static int parse(int argc, char **argv, run_args *a)
{
    const char *cmd = "run", *v;
    iso_loop_opts_default(&a->lo);
    a->lo.rt = 1; /* the command runs in real time unless --no-rt */
    iso_cli__solver_threads(&a->lo.threads);
    a->abm = -1;
    for (int i = 1; i < argc; i++) {
        int r;
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage();
            return 1;
        }
        if (parse_flag(a, argv[i]))
            continue;
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--speed", &v)) != 0) {
            if (r < 0 || iso_cli__double(cmd, "--speed", v, &a->lo.speed) != 0)
                return 2;
            if (!(a->lo.speed > 0)) {
                iso_cli__fail(cmd, "--speed %s must be > 0 (--fast runs without waiting).", v);
                return 2;
            }
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--duration", &v)) != 0) {
            if (r < 0 || iso_cli__double(cmd, "--duration", v, &a->lo.duration_s) != 0)
                return 2;
            if (!(a->lo.duration_s > 0)) {
                iso_cli__fail(cmd, "--duration %s must be > 0 seconds.", v);
                return 2;
            }
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--ticks", &v)) != 0) {
            int n;
            if (r < 0 || iso_cli__int(cmd, "--ticks", v, &n) != 0)
                return 2;
            if (n < 1) {
                iso_cli__fail(cmd, "--ticks %s must be >= 1.", v);
                return 2;
            }
            a->lo.max_ticks = n;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--port", &v)) != 0) {
            if (r < 0 || iso_cli__int(cmd, "--port", v, &a->lo.port) != 0)
                return 2;
            if (a->lo.port < 0 || a->lo.port > 65535) {
                iso_cli__fail(cmd, "--port %s must be 0..65535 (0: any free port).", v);
                return 2;
            }
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--abm", &v)) != 0) {
            if (r < 0)
                return 2;
            if (iso_cli__enum(cmd, "--abm", v, iso_abm_mode_names, &a->abm) != 0)
                return 2;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--assembly", &v)) != 0) {
            if (r < 0)
                return 2;
            int as;
            if (iso_cli__enum(cmd, "--assembly", v, iso_assembly_names, &as) != 0)
                return 2;
            a->lo.assembly = as;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--cl-device", &a->lo.cl_device)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--record", &a->lo.record)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--out", &a->out)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--png", &a->png)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--stats-json", &a->json)) != 0) {
            if (r < 0)
                return 2;
            continue;
        }
        if (argv[i][0] == '-' || a->scene)
            return iso_cli__unknown(cmd, argv[i]);
        a->scene = argv[i];
    }
    if (!a->scene) {
        iso_cli__fail(cmd,
                      "missing SCENE (usage: isoshape run SCENE; scenes are in config/scenes).");
        return 2;
    }
    a->lo.status_line = !a->quiet && isatty(STDERR_FILENO);
    return 0;
}

/* An output's folder must exist and be writable before a long run starts. */
static int check_output(const char *opt, const char *path)
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

/* The temporary name beside path, extension kept (the format follows it). */
static void temp_name(const char *path, char *tmp, size_t cap)
{
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash))
        dot = path + strlen(path);
    snprintf(tmp, cap, "%.*s.part-%ld%s", (int)(dot - path), path, (long)getpid(), dot);
}

enum { OUT_MESH, OUT_PNG, OUT_JSON };

/* Writes one output to a temporary name beside it, then renames it: a
 * failure never leaves a truncated file. Returns 0, or 1 after saying why. */
static int write_output(int what, const char *opt, const char *path, iso_loop *l,
                        const iso_scene *sc, const iso_loop_summary *s)
{
    char tmp[ISO_CLI_PATH_MAX + 64];
    iso_err err;
    iso_err_clear(&err);
    temp_name(path, tmp, sizeof tmp);
    int rc = what == OUT_MESH  ? iso_mesh_save(iso_loop_mesh(l), iso_loop_positions(l), tmp,
                                               ISO_MESH_FMT_AUTO, &err)
             : what == OUT_PNG ? iso_snapshot_png(iso_loop_mesh(l), iso_loop_positions(l),
                                                  &sc->regions, tmp, 960, 720, NULL, &err)
                               : iso_loop_write_json(s, sc, tmp, &err);
    if (rc != ISO_OK) {
        iso_cli__fail("run", "%s %s: %s", opt, path, err.msg);
        unlink(tmp);
        return 1;
    }
    if (rename(tmp, path) != 0) {
        iso_cli__fail("run", "%s %s: %s", opt, path, strerror(errno));
        unlink(tmp);
        return 1;
    }
    return 0;
}

/* What is left to do once the loop has stopped, for whatever reason. */
static int finish(iso_loop *l, const iso_scene *sc, const run_args *a, int status)
{
    iso_err err;
    iso_err_clear(&err);
    if (iso_loop_shutdown(l, &err) != ISO_OK) {
        iso_cli__fail("run", "shutdown: %s", err.msg);
        status = 1;
    }
    iso_loop_summary s;
    iso_loop_get_summary(l, &s);
    if (!a->quiet)
        iso_loop_print_summary(&s, sc, stdout);
    if (a->out && write_output(OUT_MESH, "--out", a->out, l, sc, &s))
        status = 1;
    if (a->png) {
        if (write_output(OUT_PNG, "--png", a->png, l, sc, &s))
            status = 1;
        else if (!a->quiet)
            printf("  picture     %s\n", a->png);
    }
    if (a->json && write_output(OUT_JSON, "--stats-json", a->json, l, sc, &s))
        status = 1;
    return status;
}

int iso_cli__run_scene(int argc, char **argv)
{
    run_args a;
    memset(&a, 0, sizeof a);
    int r = parse(argc, argv, &a);
    if (r != 0)
        return r == 1 ? 0 : 2;
    if ((a.out && check_output("--out", a.out)) || (a.png && check_output("--png", a.png)) ||
        (a.json && check_output("--stats-json", a.json)))
        return 1;
    iso_scene *sc = NULL;
    if (iso_cli__scene_load("run", a.scene, &sc) != 0)
        return 1;
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
        return 1;
    }
    int status = 0;
    if (iso_loop_run(l, &err) != ISO_OK) {
        iso_cli__fail("run", "%s", err.msg);
        status = 1;
    }
    int sig = g_stop;
    if (sig)
        fprintf(stderr, "isoshape run: stopped by %s; shutting down cleanly\n",
                sig == SIGINT ? "SIGINT" : "SIGTERM");
    status = finish(l, sc, &a, status);
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    return status == 0 && sig ? 128 + sig : status;
}
