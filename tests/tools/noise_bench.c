/* tests/tools/noise_bench.c -- what noise on a serial device costs the
 * tick. Two figures:
 *
 *  1. The hub alone: one tick that drains a source flooded with random
 *     bytes (ISO_DEV_DRAIN_MAX of them, the most a tick takes from one
 *     source), recording on and off, against a tick with nothing to
 *     drain: median and p99 of 600 ticks each. This is the bound a flood
 *     can add to a tick, whatever its rate.
 *  2. End to end: `isoshape run` of the built-in cactus at 60 Hz with its
 *     handle on a pseudo-terminal (a tty device, as a serial bridge would
 *     be), 6 s, quiet and then flooded with MB megabytes of random bytes
 *     written as fast as the pty takes them, recorded: the tick's median and
 *     p99 side by side, the noise counted, and the recording's size
 *     against the noise cap.
 *
 * Usage: noise_bench ISOSHAPE_BIN [MB (16)]. Prints figures; asserts
 * nothing (speed is measured, never tested). Timings on a shared machine
 * move with its load: run it twice. */
#define _DEFAULT_SOURCE /* openpty */
#include <fcntl.h>
#include <pty.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"

static unsigned g_lcg = 12345u;
static uint8_t rnd(void)
{
    g_lcg = g_lcg * 1103515245u + 12345u;
    return (uint8_t)(g_lcg >> 16);
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* median and p99 of n values (sorted in place) */
static void spread(double *v, int n, double *med, double *p99)
{
    qsort(v, (size_t)n, sizeof *v, cmp);
    *med = v[n / 2];
    *p99 = v[(int)(0.99 * (n - 1))];
}

/* ---- 1. the hub alone ---------------------------------------------------- */

static void hub_ticks(int flood, const char *record, double *med, double *p99)
{
    enum { TICKS = 600 };
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = ISO_DEV_KIND_SERIAL;
    in.baud = 115200;
    snprintf(in.name, sizeof in.name, "bench");
    iso_dev_hub *h;
    iso_dev_source *s;
    if (iso_dev_hub_create(NULL, NULL, &h, NULL) != ISO_OK ||
        iso_dev_fake_open(&in, &s, NULL) != ISO_OK || iso_dev_hub_add(h, s, NULL, NULL, NULL))
        exit(1);
    if (record && iso_dev_hub_record_start(h, record, NULL) != ISO_OK)
        exit(1);
    iso_dev_map m;
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    if (iso_dev_map_init(&m, &mo, NULL) != ISO_OK)
        exit(1);
    const int64_t tick = 16666667;
    uint8_t chunk[ISO_DEV_CHUNK_MAX];
    for (int k = 0; flood && k < TICKS; k++) /* a tick's worth, and more, waiting */
        for (unsigned i = 0; i < ISO_DEV_DRAIN_MAX / sizeof chunk + 8; i++) {
            for (size_t j = 0; j < sizeof chunk; j++)
                chunk[j] = rnd();
            if (iso_dev_fake_push(s, k * tick + i, chunk, sizeof chunk) != ISO_OK)
                exit(1);
        }
    static double t[TICKS];
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
    for (int k = 1; k <= TICKS; k++) {
        iso_dev_tick out;
        double t0 = iso_clock_now();
        if (iso_dev_hub_tick(h, &m, k * tick, tick * 1e-9, P, &out, NULL) != ISO_OK)
            exit(1);
        t[k - 1] = (iso_clock_now() - t0) * 1e3;
    }
    iso_dev_hub_destroy(h);
    spread(t, TICKS, med, p99);
}

/* ---- 2. end to end -------------------------------------------------------- */

typedef struct run_fig {
    double med, p99, max;
    long rec_bytes;
    char devline[400];
} run_fig;

static double json_num(const char *j, const char *key)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\":", key);
    const char *p = strstr(j, k);
    return p ? strtod(p + strlen(k), NULL) : -1;
}

static void slurp(const char *path, char *buf, size_t cap)
{
    buf[0] = 0;
    FILE *f = fopen(path, "r");
    if (!f)
        return;
    size_t n = fread(buf, 1, cap - 1, f);
    buf[n] = 0;
    fclose(f);
}

static void run_scene(const char *bin, const char *dir, long flood_bytes, run_fig *f)
{
    struct termios raw;
    memset(&raw, 0, sizeof raw);
    cfmakeraw(&raw);
    int master, slave;
    char name[128];
    if (openpty(&master, &slave, name, &raw, NULL) != 0) {
        perror("openpty");
        exit(1);
    }
    char scene[1200], json[1200], out[1200], rec[1200];
    snprintf(scene, sizeof scene, "%s/noise_bench.yaml", dir);
    snprintf(json, sizeof json, "%s/noise_bench.json", dir);
    snprintf(out, sizeof out, "%s/noise_bench.out", dir);
    snprintf(rec, sizeof rec, "%s/noise_bench.isorec", dir);
    FILE *sf = fopen(scene, "w");
    if (!sf) {
        perror(scene);
        exit(1);
    }
    fprintf(sf,
            "name: noise_bench\n"
            "mesh: {shape: cactus}\n"
            "devices:\n  - {name: bridge, kind: tty, path: \"%s\"}\n"
            "regions:\n  sel: builtin\n  handles:\n    - {name: top, driver: {device: bridge}}\n"
            "solver: {assembly: cpu, refactor: adaptive, worker_lag: 4}\n"
            "integrator: {abm: pec}\n"
            "tick_hz: 60\n",
            name);
    fclose(sf);
    unlink(json);
    pid_t writer = -1;
    if (flood_bytes > 0) {
        writer = fork();
        if (writer == 0) {
            uint8_t buf[4096];
            for (long sent = 0; sent < flood_bytes;) {
                for (size_t j = 0; j < sizeof buf; j++)
                    buf[j] = rnd();
                ssize_t w = write(master, buf, sizeof buf);
                if (w <= 0)
                    _exit(0);
                sent += w;
            }
            _exit(0);
        }
    }
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 1);
        dup2(fd, 2);
        execl(bin, bin, "run", scene, "--no-display", "--duration", "6", "--stats-json", json,
              "--record", rec, (char *)NULL);
        _exit(127);
    }
    int st = 0;
    waitpid(pid, &st, 0);
    if (writer > 0) {
        kill(writer, SIGKILL);
        waitpid(writer, NULL, 0);
    }
    close(master);
    close(slave);
    static char j[1 << 16], o[1 << 16];
    slurp(json, j, sizeof j);
    slurp(out, o, sizeof o);
    if (!WIFEXITED(st) || WEXITSTATUS(st) != 0 || !j[0]) {
        fprintf(stderr, "noise_bench: isoshape run failed:\n%s", o);
        exit(1);
    }
    f->med = json_num(j, "median");
    f->p99 = json_num(j, "p99");
    f->max = json_num(j, "max");
    struct stat sb;
    f->rec_bytes = stat(rec, &sb) == 0 ? (long)sb.st_size : -1;
    const char *d = strstr(o, "  device 0");
    d = d ? strchr(d, '\n') : NULL;
    snprintf(f->devline, sizeof f->devline, "%.*s", d ? (int)strcspn(d + 1, "\n") : 0,
             d ? d + 1 : "");
    const char *said = strstr(o, "not one valid frame");
    if (said)
        printf("  the run said: ...%.*s\n", (int)strcspn(said, "\n"), said);
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: noise_bench ISOSHAPE_BIN [MB]\n");
        return 2;
    }
    long mb = argc > 2 ? atol(argv[2]) : 16;
    char dir[] = "/tmp/noise_bench_XXXXXX";
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    /* the hub's figures at real-time priority where permitted, so that the
     * machine's other load does not preempt what is measured */
    struct sched_param sp = {.sched_priority = 10};
    int rt = sched_setscheduler(0, SCHED_FIFO, &sp) == 0;
    double lo[4], hi[4];
    char rec[1200];
    snprintf(rec, sizeof rec, "%s/hub.isorec", dir);
    hub_ticks(0, NULL, &lo[0], &hi[0]);
    hub_ticks(1, NULL, &lo[1], &hi[1]);
    hub_ticks(1, rec, &lo[2], &hi[2]);
    sp.sched_priority = 0;
    if (rt)
        sched_setscheduler(0, SCHED_OTHER, &sp);
    printf("hub tick, one serial source, %s (600 ticks; ms, median / p99):\n"
           "  nothing to drain                  %7.3f / %7.3f\n"
           "  %5u bytes of noise drained       %7.3f / %7.3f\n"
           "  the same, recorded (noise cap)    %7.3f / %7.3f\n",
           rt ? "SCHED_FIFO" : "normal priority (SCHED_FIFO not permitted)", lo[0], hi[0],
           ISO_DEV_DRAIN_MAX, lo[1], hi[1], lo[2], hi[2]);
    run_fig q, n;
    run_scene(argv[1], dir, 0, &q);
    run_scene(argv[1], dir, mb << 20, &n);
    printf("isoshape run, cactus at 60 Hz, handle on a pty, 6 s, recorded (tick ms):\n"
           "                     quiet      %ld MB of random bytes\n"
           "  median          %8.2f     %8.2f\n"
           "  p99             %8.2f     %8.2f\n"
           "  max             %8.2f     %8.2f\n"
           "  recording       %8ld B   %8ld B (noise cap %u B/s)\n"
           "  device quiet:   %s\n"
           "  device flooded: %s\n",
           mb, q.med, n.med, q.p99, n.p99, q.max, n.max, q.rec_bytes, n.rec_bytes,
           ISO_DEV_REC_NOISE_CAP, q.devline, n.devline);
    char cmd[1300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : 1;
}
