/* controller/cmd_record.c -- `isoshape record -o FILE`: opens the live
 * devices named on the command line, runs the device side of the loop at
 * a fixed tick (drain, map, TICK record, flush) and records every chunk,
 * until --duration or Ctrl-C. A device unplugged meanwhile is reported once
 * and picked up again when it comes back (libusb hotplug wakes the retry). */
#include "internal.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_dev.h"

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

static int open_spec(const src_spec *sp, iso_dev_source **out, iso_err *err)
{
    if (strcmp(sp->kind, "hid") == 0)
        return iso_dev_hid_open(strcmp(sp->arg, "auto") == 0 ? NULL : sp->arg, out, err);
    if (strcmp(sp->kind, "spnav") == 0)
        return iso_dev_spnav_open(out, err);
    if (strcmp(sp->kind, "mouse") == 0) {
        /* spacenavd when it runs (it owns the device), else hidraw */
        iso_err quiet;
        iso_err_clear(&quiet);
        if (iso_dev_spnav_open(out, &quiet) == ISO_OK)
            return ISO_OK;
        return iso_dev_hid_open(NULL, out, err);
    }
    if (strcmp(sp->kind, "tty") == 0)
        return iso_dev_tty_open(sp->arg, sp->baud, out, err);
    if (strcmp(sp->kind, "serial") == 0)
        return iso_dev_serialport_open(sp->arg, sp->baud, out, err);
    if (strcmp(sp->kind, "tcp") == 0)
        return iso_dev_tcp_open(sp->arg, 1000, out, err);
    return iso_dev_gpiod_open(&sp->gpio, out, err);
}

static int reopen(void *ctx, const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    (void)info;
    return open_spec(ctx, out, err);
}

static void note(void *ctx, const char *msg)
{
    (void)ctx;
    fprintf(stderr, "isoshape record: %s\n", msg);
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
    iso_dev_map m;
    iso_dev_hub *h = NULL;
    if (iso_dev_map_init(&m, &mo, &err) != ISO_OK || iso_dev_hub_create(note, NULL, &h, &err)) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 2;
    }
    for (int k = 0; k < n; k++) {
        iso_dev_source *s;
        if (open_spec(&specs[k], &s, &err) != ISO_OK ||
            iso_dev_hub_add(h, s, reopen, &specs[k], &err) != ISO_OK) {
            iso_cli__fail(cmd, "%s", err.msg);
            iso_dev_hub_destroy(h);
            return 1;
        }
    }
    if (iso_dev_hub_record_start(h, out_path, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        iso_dev_hub_destroy(h);
        return 1;
    }
    iso_dev_usb_watch *watch = NULL;
    iso_err werr;
    iso_err_clear(&werr);
    if (iso_dev_usb_watch_create(&watch, &werr) != ISO_OK)
        watch = NULL; /* the retry interval still finds replugged devices */
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned k = 0; k < ISO_DEV_MAX_HANDLES; k++)
        iso_pose_identity(&P[k]);
    const int64_t dt = (int64_t)(tick_ms * 1e6), t0 = iso_dev_now_ns();
    const int64_t end = duration >= 0 ? t0 + (int64_t)(duration * 1e9) : INT64_MAX;
    int64_t next = t0 + dt;
    long ticks = 0, late = 0;
    int status = 0;
    while (!g_stop && next <= end) {
        struct timespec ts = {(time_t)(next / 1000000000), (long)(next % 1000000000)};
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR && !g_stop)
            ;
        if (watch && iso_dev_usb_watch_poll(watch) > 0)
            iso_dev_hub_retry_now(h);
        iso_dev_tick out;
        if (iso_dev_hub_tick(h, &m, next, tick_ms * 1e-3, P, &out, &err) != ISO_OK) {
            iso_cli__fail(cmd, "%s", err.msg);
            status = 1;
            break;
        }
        if (out.actions & (1u << ISO_DEV_ACT_RESET_POSE))
            fprintf(stderr, "isoshape record: reset pose of handle %d\n", out.active);
        ticks++;
        int64_t now = iso_dev_now_ns();
        if (now > next + dt)
            late++;
        if (!quiet && ticks % (long)(1000 / tick_ms) == 0)
            fprintf(stderr, "isoshape record: %.0f s, %ld ticks (%ld late)%s%s\n",
                    (double)(next - t0) * 1e-9, ticks, late, out.estop ? ", E-STOP" : "",
                    out.gone ? ", a device is away" : "");
        next += dt;
    }
    iso_dev_usb_watch_destroy(watch);
    if (iso_dev_hub_record_stop(h, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        status = 1;
    }
    iso_dev_hub_destroy(h);
    printf("%s: %ld ticks of %g ms from %d source(s)%s\n", out_path, ticks, tick_ms, n,
           late ? " (some ticks ran late)" : "");
    return status;
}
