/* controller/cmd_record.c -- `isoshape record -o FILE`: opens the live
 * devices named on the command line, runs the device side of the loop at
 * a fixed tick (drain, map, TICK record, flush) and records every chunk,
 * until --duration or Ctrl-C: the tick engine (iso_loop.h) on a scene of the
 * device side alone. A device unplugged meanwhile is reported once and
 * picked up again when it comes back (libusb hotplug wakes the retry). */
#include "internal.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_dev.h"
#include "iso_loop.h"

int iso_cli__record(int argc, char **argv);
int iso_cli__dev_map_option(const char *cmd, int argc, char **argv, int *i, iso_dev_map_opts *o);

/* The one piece of file-scope state: a signal handler can reach nothing else. */
static volatile sig_atomic_t g_stop;
static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

typedef struct src_spec {
    char kind[8]; /* hid spnav tty serial tcp gpio */
    const char *arg;
    uint32_t baud;
    iso_dev_gpio_opts gpio;
} src_spec;

/* The scene device for one source: the engine opens it, and opens it again
 * when it comes back. --mouse is spacenavd when it runs (it owns the
 * device), else hidapi. */
static int scene_device(const src_spec *sp, int index, iso_scene_device *d)
{
    memset(d, 0, sizeof *d);
    snprintf(d->name, sizeof d->name, "%.7s%d", sp->kind, index);
    d->baud = sp->baud;
    if (sp->arg && strcmp(sp->kind, "tcp") == 0)
        snprintf(d->address, sizeof d->address, "%s", sp->arg);
    else if (sp->arg && strcmp(sp->arg, "auto") != 0)
        snprintf(d->path, sizeof d->path, "%s", sp->arg);
    static const struct {
        const char *kind;
        int backend;
    } kinds[] = {{"hid", ISO_SCENE_DEV_HIDAPI}, {"spnav", ISO_SCENE_DEV_SPNAV},
                 {"tty", ISO_SCENE_DEV_TTY},    {"serial", ISO_SCENE_DEV_SERIALPORT},
                 {"tcp", ISO_SCENE_DEV_TCP},    {"gpio", ISO_SCENE_DEV_GPIOD}};
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++)
        if (strcmp(sp->kind, kinds[k].kind) == 0)
            d->backend = kinds[k].backend;
    if (strcmp(sp->kind, "mouse") == 0) {
        iso_dev_source *s = NULL;
        iso_err quiet;
        iso_err_clear(&quiet);
        d->backend =
            iso_dev_spnav_open(&s, &quiet) == ISO_OK ? ISO_SCENE_DEV_SPNAV : ISO_SCENE_DEV_HIDAPI;
        iso_dev_source_close(s);
    }
    if (d->backend == ISO_SCENE_DEV_GPIOD) {
        d->gpio = sp->gpio;
        snprintf(d->chip, sizeof d->chip, "%s", sp->arg);
        d->gpio.chip = d->chip;
    }
    return d->backend;
}

typedef struct record_ctx {
    int quiet;
    long every, late;
    double tick_ms;
} record_ctx;

static void on_tick(void *ctx, const iso_loop_tick_info *t)
{
    record_ctx *rc = ctx;
    if (t->merged > 1 || t->dt_s > rc->tick_ms * 1.5e-3)
        rc->late++;
    if (!rc->quiet && rc->every > 0 && t->tick % rc->every == 0)
        fprintf(stderr, "isoshape record: %.0f s, %ld ticks (%ld late)\n", t->t_s, t->tick,
                rc->late);
}

static void on_command(void *ctx, const iso_dev_tick *out, double dt)
{
    (void)ctx;
    (void)dt;
    if (out->actions & (1u << ISO_DEV_ACT_RESET_POSE))
        fprintf(stderr, "isoshape record: reset pose of handle %d\n", out->active);
}

static void usage(void)
{
    printf("usage: isoshape record -o FILE SOURCE... [options]\n"
           "\n"
           "Records live input devices (devices/RECORDING.md) while running the device side\n"
           "of the loop, until --duration or Ctrl-C. Sources (any number, up to 16):\n"
           "  --hid PATH|auto    a 3D mouse through hidapi/hidraw (auto: the first one)\n"
           "  --mouse            a 3D mouse: through spacenavd when it runs, else hidapi\n"
           "  --spnav            3D mouse events from the spacenavd daemon\n"
           "  --tty PATH         a serial stream on a tty or pseudo-terminal\n"
           "  --serial NAME      a serial adapter through libserialport\n"
           "  --tcp HOST:PORT    a serial-over-network bridge\n"
           "  --gpio CHIP        clutch/e-stop inputs; with --clutch-line N, --estop-line N,\n"
           "                     --pulse-line N (a pulse each tick), --active-low,\n"
           "                     --debounce-ms X (default 5)\n"
           "Options:\n"
           "  --baud N           serial rate for the next --tty/--serial (default 115200)\n"
           "  --tick-ms T        tick length (default 1)\n"
           "  --duration S       stop after S seconds (default: at Ctrl-C)\n"
           "  --quiet            no per-second status line\n");
}

int iso_cli__record(int argc, char **argv)
{
    const char *cmd = "record", *out_path = NULL, *v;
    src_spec specs[ISO_DEV_MAX_SOURCES];
    int n = 0, quiet = 0;
    uint32_t baud = 115200;
    double tick_ms = 1, duration = -1, debounce_ms = 5;
    iso_dev_gpio_opts gp = {NULL, -1, -1, -1, 0, 0};
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    for (int i = 1; i < argc; i++) {
        int r;
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage();
            return 0;
        }
        if (strcmp(argv[i], "--active-low") == 0) {
            gp.active_low = 1;
            continue;
        }
        if (strcmp(argv[i], "--quiet") == 0) {
            quiet = 1;
            continue;
        }
        if (strcmp(argv[i], "--spnav") == 0 || strcmp(argv[i], "--mouse") == 0) {
            if (n >= (int)ISO_DEV_MAX_SOURCES) {
                iso_cli__fail(cmd, "more than 16 sources.");
                return 2;
            }
            memset(&specs[n], 0, sizeof specs[n]);
            snprintf(specs[n].kind, sizeof specs[n].kind, "%s", argv[i] + 2);
            n++;
            continue;
        }
        static const char *const kinds[] = {"--hid", "--tty", "--serial", "--tcp", "--gpio"};
        int matched = 0;
        for (int k = 0; k < 5 && !matched; k++) {
            if ((r = iso_cli__value(cmd, argc, argv, &i, kinds[k], &v)) == 0)
                continue;
            if (r < 0)
                return 2;
            if (n >= (int)ISO_DEV_MAX_SOURCES) {
                iso_cli__fail(cmd, "more than 16 sources.");
                return 2;
            }
            memset(&specs[n], 0, sizeof specs[n]);
            snprintf(specs[n].kind, sizeof specs[n].kind, "%s", kinds[k] + 2);
            specs[n].arg = v;
            specs[n].baud = baud;
            n++;
            matched = 1;
        }
        if (matched)
            continue;
        static const char *const nums[] = {
            "--clutch-line", "--estop-line", "--pulse-line",  "--baud",
            "--tick-ms",     "--duration",   "--debounce-ms", "-o"};
        for (int k = 0; k < 8 && !matched; k++) {
            if ((r = iso_cli__value(cmd, argc, argv, &i, nums[k], &v)) == 0)
                continue;
            if (r < 0)
                return 2;
            matched = 1;
            double d = 0;
            if (k == 7) {
                out_path = v;
                continue;
            }
            if (iso_cli__double(cmd, nums[k], v, &d) != 0)
                return 2;
            if (k < 4 && (d < 0 || d != (double)(long)d)) {
                iso_cli__fail(cmd, "%s %s must be a whole number >= 0.", nums[k], v);
                return 2;
            }
            if (k >= 4 && k != 5 && !(d > 0)) {
                iso_cli__fail(cmd, "%s %s must be > 0.", nums[k], v);
                return 2;
            }
            switch (k) {
            case 0: gp.clutch_line = (int)d; break;
            case 1: gp.estop_line = (int)d; break;
            case 2: gp.pulse_line = (int)d; break;
            case 3: baud = (uint32_t)d; break;
            case 4: tick_ms = d; break;
            case 5: duration = d; break;
            default: debounce_ms = d; break;
            }
        }
        if (matched)
            continue;
        if ((r = iso_cli__dev_map_option(cmd, argc, argv, &i, &mo)) != 0) {
            if (r < 0)
                return 2;
            continue;
        }
        return iso_cli__unknown(cmd, argv[i]);
    }
    if (!out_path || n == 0) {
        iso_cli__fail(cmd, "%s (see isoshape record --help).",
                      !out_path ? "no output file: give -o FILE" : "no source given");
        return 2;
    }
    gp.debounce_us = (uint32_t)(debounce_ms * 1000);
    for (int k = 0; k < n; k++)
        if (strcmp(specs[k].kind, "gpio") == 0) {
            specs[k].gpio = gp;
            specs[k].gpio.chip = specs[k].arg;
        }
    iso_err err;
    iso_err_clear(&err);
    iso_dev_map m; /* the options' own check */
    if (iso_dev_map_init(&m, &mo, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 2;
    }
    /* a scene of the device side alone: the sources, the mapping, the recording */
    iso_scene *sc = iso_cli__device_scene("record", 1000.0 / tick_ms, &mo);
    if (!sc) {
        iso_cli__fail(cmd, "out of memory");
        return 1;
    }
    sc->n_devices = n;
    for (int k = 0; k < n; k++)
        scene_device(&specs[k], k, &sc->devices[k]);
    snprintf(sc->recording, sizeof sc->recording, "%s", out_path);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    record_ctx ctx = {quiet, (long)llround(1000.0 / tick_ms), 0, tick_ms};
    iso_loop_opts lo;
    iso_loop_opts_default(&lo);
    iso_cli__solver_threads(&lo.threads);
    lo.cmd = cmd;
    lo.rt = 0;
    lo.display = 0;
    lo.duration_s = duration > 0 ? duration : duration == 0 ? 1e-12 : 0;
    lo.stop = &g_stop;
    lo.on_tick = on_tick;
    lo.on_command = on_command;
    lo.hook_ctx = &ctx;
    iso_loop *l = NULL;
    int status = 0;
    if (iso_loop_create(sc, &lo, &l, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        free(sc);
        return 1;
    }
    if (iso_loop_run(l, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        status = 1;
    }
    iso_err_clear(&err);
    if (iso_loop_shutdown(l, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        status = 1;
    }
    iso_loop_summary sum;
    iso_loop_get_summary(l, &sum);
    iso_loop_destroy(l);
    free(sc);
    printf("%s: %ld ticks of %g ms from %d source(s)%s\n", out_path, sum.device_ticks, tick_ms, n,
           ctx.late ? " (some ticks ran late)" : "");
    return status;
}
