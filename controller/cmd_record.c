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

#include "iso_dev_map.h"
#include "iso_dev_source.h"
#include "iso_loop.h"

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
    iso_loop *l; /* the hooks run on its tick: they say through its log */
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
        iso_loop_say(rc->l, "%.0f s, %ld ticks (%ld late)", t->t_s, t->tick, rc->late);
}

static void on_command(void *ctx, const iso_dev_tick *out, double dt)
{
    const record_ctx *rc = ctx;
    (void)dt;
    if (out->actions & (1u << ISO_DEV_ACT_RESET_POSE))
        iso_loop_say(rc->l, "reset pose of handle %d", out->active);
}

typedef struct record_args {
    const char *out;
    src_spec specs[ISO_DEV_MAX_SOURCES];
    int n, quiet;
    int baud; /* for the next --tty or --serial */
    double tick_ms, duration, debounce_ms;
    iso_dev_gpio_opts gp; /* for every --gpio */
    iso_dev_map_opts mo;
} record_args;

/* A source option adds one source of its kind (the option's name), with
 * the --baud given before it. */
static int add_source(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    record_args *a = dst;
    if (a->n >= (int)ISO_DEV_MAX_SOURCES) {
        snprintf(why, cap, "more than %u sources", ISO_DEV_MAX_SOURCES);
        return -1;
    }
    src_spec *sp = &a->specs[a->n++];
    memset(sp, 0, sizeof *sp);
    snprintf(sp->kind, sizeof sp->kind, "%s", o->name);
    sp->arg = val;
    sp->baud = (uint32_t)a->baud;
    return 0;
}

static const iso_cli__opt record_options[] = {
    {"hid", ISO_CLI_OPT_CALL, 0, "PATH|auto",
     .help = "a 3D mouse through hidapi/hidraw (auto: the first one)", .set = add_source},
    {"mouse", ISO_CLI_OPT_FLAG, 0, NULL,
     .help = "a 3D mouse: through spacenavd when it runs, else hidapi", .set = add_source},
    {"spnav", ISO_CLI_OPT_FLAG, 0, NULL, .help = "3D mouse events from the spacenavd daemon",
     .set = add_source},
    {"tty", ISO_CLI_OPT_CALL, 0, "PATH", .help = "a serial stream on a tty or pseudo-terminal",
     .set = add_source},
    {"serial", ISO_CLI_OPT_CALL, 0, "NAME", .help = "a serial adapter through libserialport",
     .set = add_source},
    {"tcp", ISO_CLI_OPT_CALL, 0, "HOST:PORT", .help = "a serial-over-network bridge",
     .set = add_source},
    {"gpio", ISO_CLI_OPT_CALL, 0, "CHIP",
     .help = "clutch/e-stop inputs on a GPIO chip, on the lines below", .set = add_source},
    {"clutch-line", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(record_args, gp.clutch_line), "N",
     .help = "--gpio: the clutch's line, %R", ISO_CLI_GE(0)},
    {"estop-line", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(record_args, gp.estop_line), "N",
     .help = "--gpio: the e-stop's line, %R", ISO_CLI_GE(0)},
    {"pulse-line", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(record_args, gp.pulse_line), "N",
     .help = "--gpio: a line that pulses each tick, %R", ISO_CLI_GE(0)},
    {"active-low", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(record_args, gp.active_low), NULL,
     .help = "--gpio: the lines are active low", .flag = 1},
    {"debounce-ms", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(record_args, debounce_ms), "X",
     .help = "--gpio: debounce time, %R (default 5)", ISO_CLI_GT(0)},
    {NULL, ISO_CLI_OPT_HEADING, 0, NULL, .help = "Options:"},
    {NULL, ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(record_args, out), "FILE",
     .help = "the recording to write (required)", .short_name = 'o'},
    {"baud", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(record_args, baud), "N",
     .help = "serial rate for the next --tty/--serial, %R (default 115200)", ISO_CLI_GE(0)},
    {"tick-ms", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(record_args, tick_ms), "T",
     .help = "tick length, %R (default 1)", ISO_CLI_GT(0)},
    {"duration", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(record_args, duration), "S",
     .help = "stop after S seconds (default: at Ctrl-C)"},
    {"quiet", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(record_args, quiet), NULL,
     .help = "no per-second status line", .flag = 1},
    {NULL, ISO_CLI_OPT_HEADING, 0, NULL, .help = "Mapping:"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(record_args, mo, iso_dev_map_opts),
     .table = iso_cli__dev_map_options},
    {0}};

/* Returns -1 to go on, else the exit status (0 after --help). */
static int parse_args(int argc, char **argv, record_args *a)
{
    memset(a, 0, sizeof *a);
    a->baud = 115200;
    a->tick_ms = 1;
    a->duration = -1;
    a->debounce_ms = 5;
    a->gp = (iso_dev_gpio_opts){NULL, -1, -1, -1, 0, 0};
    iso_dev_map_opts_default(&a->mo);
    int status = iso_cli__parse(&iso_cli__record_cmd, argc, argv, a, NULL, 0, NULL);
    if (status >= 0)
        return status;
    if (!a->out || a->n == 0) {
        iso_cli__fail("record", "%s (see isoshape record --help).",
                      !a->out ? "no output file: give -o FILE" : "no source given");
        return 2;
    }
    a->gp.debounce_us = (uint32_t)(a->debounce_ms * 1000);
    for (int k = 0; k < a->n; k++)
        if (strcmp(a->specs[k].kind, "gpio") == 0) {
            a->specs[k].gpio = a->gp;
            a->specs[k].gpio.chip = a->specs[k].arg;
        }
    return -1;
}

static int record_main(int argc, char **argv)
{
    const char *cmd = "record";
    record_args a;
    int status = parse_args(argc, argv, &a);
    if (status >= 0)
        return status;
    iso_err err;
    iso_err_clear(&err);
    iso_dev_map m; /* the options' own check */
    if (iso_dev_map_init(&m, &a.mo, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 2;
    }
    /* a scene of the device side alone: the sources, the mapping, the recording */
    iso_scene *sc = iso_cli__device_scene("record", 1000.0 / a.tick_ms, &a.mo);
    if (!sc) {
        iso_cli__fail(cmd, "out of memory");
        return 1;
    }
    sc->n_devices = a.n;
    for (int k = 0; k < a.n; k++)
        scene_device(&a.specs[k], k, &sc->devices[k]);
    snprintf(sc->recording, sizeof sc->recording, "%s", a.out);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    record_ctx ctx = {NULL, a.quiet, (long)llround(1000.0 / a.tick_ms), 0, a.tick_ms};
    iso_loop_opts lo;
    iso_cli__loop_opts_default(&lo, cmd);
    lo.rt = 0;
    lo.display = 0;
    lo.duration_s = a.duration > 0 ? a.duration : a.duration == 0 ? 1e-12 : 0;
    lo.stop = &g_stop;
    lo.on_tick = on_tick;
    lo.on_command = on_command;
    lo.hook_ctx = &ctx;
    iso_loop *l = NULL;
    status = 0;
    if (iso_loop_create(sc, &lo, &l, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        free(sc);
        return 1;
    }
    ctx.l = l;
    if (iso_loop_run(l, &err) != ISO_OK) {
        iso_loop_say(l, "%s", err.msg);
        status = 1;
    }
    iso_err_clear(&err);
    if (iso_loop_shutdown(l, &err) != ISO_OK) {
        iso_loop_say(l, "%s", err.msg);
        status = 1;
    }
    iso_loop_summary sum;
    iso_loop_get_summary(l, &sum);
    iso_loop_destroy(l);
    free(sc);
    printf("%s: %ld ticks of %g ms from %d source(s)%s\n", a.out, sum.device_ticks, a.tick_ms, a.n,
           ctx.late ? " (some ticks ran late)" : "");
    return status;
}

const iso_cli__cmd iso_cli__record_cmd = {
    .name = "record",
    .summary = "record live input devices (3D mouse, serial, GPIO) while running them",
    .usage = "usage: isoshape record -o FILE SOURCE... [options]\n"
             "\n"
             "Records live input devices (devices/RECORDING.md) while running the device side\n"
             "of the loop, until --duration or Ctrl-C. Sources (any number, up to 16):\n",
    .opts = record_options,
    .main = record_main};
