/* tests/tools/view_publish_bench.c -- what the live view costs the tick at
 * scale. For built-in meshes of 40k, 160k and 1M vertices (bumpplane 201,
 * tentacle 128 and 317) it publishes a frame through the real display
 * (view/iso_display.h) at 60 Hz, to deadlines as the loop does, with 0, 1
 * and 4 WebSocket viewers on loopback that read everything they are sent
 * (tests/ws_client.h), and prints for each case:
 *   - the bytes of one frame (what iso_display.h's wire format makes it);
 *   - iso_display_publish's duration: median, p99 and max over the ticks;
 *   - in the same ticks, one memcpy of a frame's bytes between two buffers
 *     of this tool (median and p99): the unit a copy costs on this machine
 *     now, and publish's median over it (publish reads the positions as
 *     doubles and writes floats: 1.5 times the bytes of the copy);
 *   - the frames and megabytes each viewer received per second;
 *   - the CPU the display's server thread used, as a share of one core
 *     (/proc/self/task/TID/schedstat);
 *   - the ticks that started more than a period late;
 * and for each mesh the bytes a viewer gets before its first frame: the
 * topology (binary), then its control state (JSON).
 * Like the loop (controller/loop_run.c), the publishing thread runs at
 * SCHED_FIFO 20 during the ticks when it may, and the server and the
 * viewers at normal priority; the first line says which it got.
 *
 * Usage: view_publish_bench [SECONDS] [MESHES] [--no-rt]: SECONDS of ticks
 * per case (default 5), MESHES a comma list of 40k, 160k, 1m (default all
 * three); --no-rt keeps the tick thread at normal priority.
 * Prints figures; asserts nothing (speed is measured, never tested). On a
 * shared machine the figures move with its load: it prints the load
 * average before and after. */
#include <dirent.h>
#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_display.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "ws_client.h"

#define TICK_HZ 60
#define RT_PRIORITY 20 /* ISO_LOOP_RT_PRIORITY */
#define MAX_READERS 4

typedef struct mesh_case {
    const char *label, *shape;
    int resolution;
} mesh_case;

static const mesh_case meshes[] = {
    {"40k", "bumpplane", 201}, {"160k", "tentacle", 128}, {"1m", "tentacle", 317}};
static const int viewer_counts[] = {0, 1, 4};

/* ---- figures --------------------------------------------------------------- */

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Sorts v; the nearest-rank quantile q of its n values. */
static double quantile(double *v, int n, double q)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return v[(int)ceil(q * n) - 1 < 0 ? 0 : (int)ceil(q * n) - 1];
}

static void print_load(const char *when)
{
    char buf[128] = "?";
    FILE *f = fopen("/proc/loadavg", "r");
    if (f && fgets(buf, sizeof buf, f))
        buf[strcspn(buf, "\n")] = 0;
    if (f)
        fclose(f);
    printf("load average %s: %s\n", when, buf);
}

static void print_machine(void)
{
    char line[256], model[128] = "?";
    FILE *f = fopen("/proc/cpuinfo", "r");
    while (f && fgets(line, sizeof line, f))
        if (strncmp(line, "model name", 10) == 0 && strchr(line, ':')) {
            snprintf(model, sizeof model, "%s", strchr(line, ':') + 2);
            model[strcspn(model, "\n")] = 0;
            break;
        }
    if (f)
        fclose(f);
    printf("machine: %s, %ld cores online\n", model, sysconf(_SC_NPROCESSORS_ONLN));
}

/* ---- threads' CPU time --------------------------------------------------------- */

/* The ids of this process's threads, at most cap of them; how many. */
static int list_threads(long *tid, int cap)
{
    DIR *dir = opendir("/proc/self/task");
    int n = 0;
    for (struct dirent *e; dir && (e = readdir(dir)) != NULL;)
        if (e->d_name[0] != '.' && n < cap)
            tid[n++] = atol(e->d_name);
    if (dir)
        closedir(dir);
    return n;
}

/* The one thread in after[] that before[] lacks: the display's server,
 * which iso_display_create starts and nothing else does. -1 if not one. */
static long new_thread(const long *before, int nb, const long *after, int na)
{
    long found = -1;
    for (int i = 0; i < na; i++) {
        int seen = 0;
        for (int j = 0; j < nb; j++)
            seen |= after[i] == before[j];
        if (!seen) {
            if (found >= 0)
                return -1;
            found = after[i];
        }
    }
    return found;
}

/* Nanoseconds thread tid has run (schedstat's first field); -1 when the
 * kernel does not say. */
static double thread_cpu_ns(long tid)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/self/task/%ld/schedstat", tid);
    FILE *f = fopen(path, "r");
    double ns = -1;
    if (f && fscanf(f, "%lf", &ns) != 1)
        ns = -1;
    if (f)
        fclose(f);
    return ns;
}

/* ---- one case ---------------------------------------------------------------- */

typedef struct bench {
    iso_display *d;
    long server_tid;
    int nv, nh, seconds, rt;
    const double *rest;
    double *x;            /* the tick's positions: rest, moved a little each tick */
    unsigned char *a, *b; /* memcpy's source and destination, a frame each */
    size_t frame_len;
    double *pub_ms, *copy_ms;
    long first_text; /* text bytes a viewer had by its first frame */
} bench;

/* The tick thread at the loop's priority for the timed ticks, so that the
 * server and the viewers (normal priority) compete as they do in a run. */
static int set_realtime(int on)
{
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = on ? RT_PRIORITY : 0;
    return sched_setscheduler(0, on ? SCHED_FIFO : SCHED_OTHER, &sp);
}

static void move_positions(bench *b, long tick)
{
    double s = 1.0 + 1e-3 * sin(0.1 * (double)tick);
    for (int i = 0; i < 3 * b->nv; i++)
        b->x[i] = b->rest[i] * s;
}

/* Publishes at TICK_HZ for `ticks` ticks to absolute deadlines; each tick
 * then times one memcpy of a frame. Returns the ticks that started late by
 * more than a period. */
static int run_ticks(bench *b, int ticks, int record)
{
    const int64_t period = 1000000000LL / TICK_HZ, start = iso_clock_ns();
    int late = 0;
    for (int k = 0; k < ticks; k++) {
        int64_t due = start + (int64_t)k * period;
        iso_clock_sleep_until(due);
        late += iso_clock_ns() - due > period;
        move_positions(b, k);
        int64_t t0 = iso_clock_ns();
        iso_display_publish(b->d, k, b->x, NULL, NULL);
        int64_t t1 = iso_clock_ns();
        memcpy(b->b, b->a, b->frame_len);
        int64_t t2 = iso_clock_ns();
        b->a[(size_t)k % b->frame_len] ^= b->b[(size_t)(k + 1) % b->frame_len]; /* copy used */
        if (record) {
            b->pub_ms[k] = (double)(t1 - t0) * 1e-6;
            b->copy_ms[k] = (double)(t2 - t1) * 1e-6;
        }
    }
    return late;
}

/* Opens n viewers and waits until each has had a frame (the topology comes
 * first: tens of megabytes at 1M vertices). Returns how many are up. */
static int open_viewers(bench *b, iso_test_ws_reader *r, int n)
{
    int port = iso_display_port(b->d), up = 0;
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    for (int i = 0; i < n; i++) {
        int st;
        iso_test_ws_reader_start(&r[i], iso_test_ws_open(AF_INET, port, host, "", 0, &st));
        if (st != 101)
            fprintf(stderr, "view_publish_bench: viewer %d answered %d\n", i, st);
    }
    for (int waited = 0; waited < 60 * TICK_HZ; waited += TICK_HZ / 4) {
        up = 0;
        for (int i = 0; i < n; i++)
            up += atomic_load(&r[i].frames) > 0;
        if (up == n)
            break;
        run_ticks(b, TICK_HZ / 4, 0);
    }
    return up;
}

static void run_case(bench *b, const mesh_case *mc, int viewers)
{
    iso_test_ws_reader r[MAX_READERS];
    int up = open_viewers(b, r, viewers);
    if (viewers && up)
        b->first_text = atomic_load(&r[0].text_bytes) + atomic_load(&r[0].topology_bytes);
    run_ticks(b, TICK_HZ / 2, 0); /* warm: pages touched, viewers streaming */
    long frames0[MAX_READERS], bytes0[MAX_READERS];
    for (int i = 0; i < viewers; i++) {
        frames0[i] = atomic_load(&r[i].frames);
        bytes0[i] = atomic_load(&r[i].bytes);
    }
    int ticks = b->seconds * TICK_HZ;
    int rt = b->rt && set_realtime(1) == 0;
    double srv0 = thread_cpu_ns(b->server_tid);
    int64_t t0 = iso_clock_ns();
    int late = run_ticks(b, ticks, 1);
    double wall = (double)(iso_clock_ns() - t0);
    double srv = srv0 >= 0 ? thread_cpu_ns(b->server_tid) - srv0 : -1;
    if (rt)
        set_realtime(0);
    char rates[256] = "";
    for (int i = 0; i < viewers; i++) {
        size_t at = strlen(rates);
        snprintf(rates + at, sizeof rates - at, "%s%.1f/%.0f", i ? " " : "",
                 (double)(atomic_load(&r[i].frames) - frames0[i]) / (wall * 1e-9),
                 (double)(atomic_load(&r[i].bytes) - bytes0[i]) / (wall * 1e-9) * 1e-6);
    }
    for (int i = 0; i < viewers; i++)
        iso_test_ws_reader_stop(&r[i]);
    double copy = quantile(b->copy_ms, ticks, 0.5), copy99 = quantile(b->copy_ms, ticks, 0.99);
    double pub = quantile(b->pub_ms, ticks, 0.5);
    printf("%-9s %8d %2d%s %9zu %7.3f %7.3f %7.3f %7.3f %7.3f %6.2f %4d %5.1f  %s\n", mc->shape,
           b->nv, viewers, up == viewers ? " " : "!", b->frame_len, pub,
           quantile(b->pub_ms, ticks, 0.99), quantile(b->pub_ms, ticks, 1.0), copy, copy99,
           pub / copy, late, srv >= 0 ? 100 * srv / wall : -1, viewers ? rates : "-");
    fflush(stdout);
}

/* ---- one mesh -------------------------------------------------------------- */

static int bench_mesh(const mesh_case *mc, int seconds, int want_rt)
{
    iso_shape sh;
    iso_mesh *m = NULL;
    iso_regions reg;
    iso_err e;
    iso_err_clear(&e);
    memset(&reg, 0, sizeof reg);
    if (iso_shape_init(&sh, mc->shape, mc->resolution, &e) != ISO_OK ||
        iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, mc->shape, &m, &e) != ISO_OK ||
        iso_shape_regions(&sh, &reg, &e) != ISO_OK) {
        fprintf(stderr, "view_publish_bench: %s %d: %s\n", mc->shape, mc->resolution, e.msg);
        return 1;
    }
    bench b;
    memset(&b, 0, sizeof b);
    b.nv = sh.nv;
    b.nh = reg.n_handles < ISO_DISPLAY_MAX_HANDLES ? reg.n_handles : ISO_DISPLAY_MAX_HANDLES;
    b.seconds = seconds;
    b.rt = want_rt;
    b.rest = sh.x;
    b.frame_len = ISO_DISPLAY_FRAME_HEADER + (size_t)ISO_DISPLAY_FRAME_POSE * (size_t)b.nh +
                  (size_t)12 * (size_t)b.nv;
    b.x = malloc(sizeof(double) * 3 * (size_t)b.nv);
    b.a = calloc(1, b.frame_len);
    b.b = calloc(1, b.frame_len);
    b.pub_ms = malloc(sizeof(double) * (size_t)(seconds * TICK_HZ));
    b.copy_ms = malloc(sizeof(double) * (size_t)(seconds * TICK_HZ));
    iso_display_opts o;
    memset(&o, 0, sizeof o);
    o.mesh = m;
    o.regions = &reg;
    long before[256], after[256];
    int nb = list_threads(before, 256);
    int rc = 1;
    if (!b.x || !b.a || !b.b || !b.pub_ms || !b.copy_ms) {
        fprintf(stderr, "view_publish_bench: out of memory\n");
    } else if (iso_display_create(&o, &b.d, &e) != ISO_OK) {
        fprintf(stderr, "view_publish_bench: %s\n", e.msg);
    } else {
        b.server_tid = new_thread(before, nb, after, list_threads(after, 256));
        for (size_t v = 0; v < sizeof viewer_counts / sizeof viewer_counts[0]; v++)
            run_case(&b, mc, viewer_counts[v]);
        printf("%-9s %8d  bytes before the first frame (topology, control): %ld\n", mc->shape, b.nv,
               b.first_text);
        rc = 0;
    }
    iso_display_destroy(b.d);
    free(b.x);
    free(b.a);
    free(b.b);
    free(b.pub_ms);
    free(b.copy_ms);
    iso_regions_deinit(&reg);
    iso_mesh_destroy(m);
    iso_shape_deinit(&sh);
    return rc;
}

int main(int argc, char **argv)
{
    int seconds = 5, want_rt = 1;
    const char *which = "40k,160k,1m";
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--no-rt") == 0)
            want_rt = 0;
        else if (argv[i][0] && strspn(argv[i], "0123456789") == strlen(argv[i]))
            seconds = atoi(argv[i]);
        else
            which = argv[i];
    }
    if (seconds < 1 || seconds > 600) {
        fprintf(stderr, "usage: view_publish_bench [SECONDS (1..600, default 5)] "
                        "[MESHES (a comma list of 40k, 160k, 1m)] [--no-rt]\n");
        return 2;
    }
    print_machine();
    int rt = want_rt && set_realtime(1) == 0;
    if (rt)
        set_realtime(0);
    printf("tick thread: %s during the ticks; %d Hz, %d s a case\n",
           rt        ? "SCHED_FIFO 20"
           : want_rt ? "normal priority (SCHED_FIFO not permitted)"
                     : "normal priority (--no-rt)",
           TICK_HZ, seconds);
    print_load("before");
    printf("publish and memcpy in ms; pub/cpy: publish median over memcpy median; late: ticks "
           "started a period late;\nvw: viewers (! when one never had a frame); srv%%: the server "
           "thread's CPU, %% of one core;\nper viewer: frames/s / MB/s received\n");
    printf("%-9s %8s %3s %9s %7s %7s %7s %7s %7s %6s %4s %5s  %s\n", "mesh", "vertices", "vw",
           "frame B", "pub med", "pub p99", "pub max", "cpy med", "cpy p99", "pub/cp", "late",
           "srv%", "per viewer");
    int rc = 0, ran = 0;
    for (size_t i = 0; i < sizeof meshes / sizeof meshes[0]; i++) {
        const char *at = strstr(which, meshes[i].label);
        size_t n = strlen(meshes[i].label);
        if (at && (at == which || at[-1] == ',') && (at[n] == 0 || at[n] == ',')) {
            rc |= bench_mesh(&meshes[i], seconds, rt);
            ran++;
        }
    }
    print_load("after");
    if (!ran)
        fprintf(stderr, "view_publish_bench: '%s' names none of the meshes 40k, 160k, 1m\n", which);
    return rc || !ran;
}
