/* tests/tools/drag_bench.c -- the real-time loop under a person's hand:
 * one run of `isoshape run` in real time, driven by a drag through the live
 * view's command channel or by a recorded 3D-mouse session, and its figures
 * in one row.
 *
 *   drag_bench ISOSHAPE SOURCE MESH RESTORE [rt]
 *     SOURCE   view-person: a page that takes control and sends a TARGET
 *                every 25 ms, as a browser does: lift the handle by 10% of
 *                the bounding-box diagonal in 0.5 s, slide it 10% in 0.5 s,
 *                turn it 30 degrees about its centre in 1 s and back in
 *                1 s, then hold 1 s;
 *              view-fast: the same drag at the view's speed limits'
 *                scale: 25% up in 0.15 s and across in 0.15 s (1.7
 *                diagonals a second), 90 degrees in 0.3 s and back;
 *              FILE.isorec: a recorded 3D-mouse session, replayed in real
 *                time with replay_cactus.yaml's mapping.
 *     MESH     cactus (the benchmark's when ../shared/data/benchmark is
 *              there, else the built-in) or plane (the benchmark's 40k
 *              bumpplane, on the reduced model solver.proxy auto chooses)
 *     RESTORE  on (mu 1, tau 0.5 s, as the shipped scenes) or off
 *     rt       the run at real-time priority where permitted (else --no-rt)
 *     record=FILE  the run's devices recorded to FILE, so that the same
 *              drag replays at --fast (a preconditioner or a step rule
 *              compared on the very motion a person made)
 *
 * The scene is the shipped view_cactus.yaml's: PEC, worker_lag 4, the live
 * view, and the actuators behind the emulated MCU (the real firmware in
 * QEMU when it is installed). The row: ticks computed of the periods the
 * run spanned, the tick's median / p99 / max, input due to published
 * (median / p90 / p99), factorizations on the tick's thread (besides the
 * one before the clock starts) and by the worker, inexact solves and the
 * worst residual, the largest edge strain, and for a view drag how far the
 * handle ended from the last target (of the diagonal). A benchmark: it
 * prints and asserts nothing (tests/tools/drag_figures.sh runs the table). */
#define _DEFAULT_SOURCE /* mkstemps */
#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "child_stderr.h"
#include "iso_dev_view.h"
#include "ws_client.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void sleep_until(double t)
{
    double d = t - now_s();
    if (d <= 0)
        return;
    struct timespec ts = {(time_t)d, (long)((d - floor(d)) * 1e9)};
    nanosleep(&ts, NULL);
}

static child_stderr g_err; /* the run's stderr */

/* The number after the first "key": at or after the first `object` key
 * (NULL: the start), NaN when there is none. */
static double num_in(const char *json, const char *object, const char *key)
{
    const char *at = object ? strstr(json, object) : json;
    char k[80];
    snprintf(k, sizeof k, "\"%s\": ", key);
    at = at ? strstr(at, k) : NULL;
    return at ? strtod(at + strlen(k), NULL) : NAN;
}

static char *read_all(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t cap = 1 << 16, len = 0;
    char *b = malloc(cap);
    size_t n;
    while (b && (n = fread(b + len, 1, cap - len - 1, f)) > 0)
        if ((len += n) == cap - 1)
            b = realloc(b, cap *= 2);
    fclose(f);
    if (b)
        b[len] = 0;
    return b;
}

/* ---- the drag --------------------------------------------------------------- */

typedef struct profile {
    double lift, slide, turn_deg; /* of the diagonal, of the diagonal, degrees */
    double t_lift, t_slide, t_turn, t_hold;
} profile;

static const profile PERSON = {0.10, 0.10, 30, 0.5, 0.5, 1.0, 1.0};
static const profile FAST = {0.25, 0.25, 90, 0.15, 0.15, 0.3, 1.0};

static double ramp(double t, double t0, double len)
{
    return t <= t0 ? 0 : t >= t0 + len ? 1 : (t - t0) / len;
}

/* The target at t seconds into the drag: offset o (scene units) and the
 * rotation vector r about the handle's centre c, as the pose rest ->
 * target (p = c + o - R c, r). Returns 0 once the drag is over. */
static int target_at(const profile *P, double diag, const double c[3], double t, double pose[6])
{
    double t1 = P->t_lift, t2 = t1 + P->t_slide, t3 = t2 + P->t_turn, t4 = t3 + P->t_turn;
    double up = P->lift * diag * ramp(t, 0, t1), across = P->slide * diag * ramp(t, t1, P->t_slide);
    double ang = P->turn_deg * M_PI / 180 * (ramp(t, t2, P->t_turn) - ramp(t, t3, P->t_turn));
    /* R about the y axis through c: R c = (c cos + c_z sin, c_y, -c_x sin + c_z cos) */
    double co = cos(ang), si = sin(ang);
    double rc[3] = {co * c[0] + si * c[2], c[1], -si * c[0] + co * c[2]};
    double o[3] = {across, 0, up};
    for (int i = 0; i < 3; i++)
        pose[i] = c[i] + o[i] - rc[i];
    pose[3] = 0;
    pose[4] = ang;
    pose[5] = 0;
    return t <= t4 + P->t_hold;
}

static void send_msg(int fd, int type, uint32_t seq, const double pose[6])
{
    iso_dev_view_msg m = {(uint8_t)type, 0, seq, now_s() * 1e3, {0}};
    if (pose)
        memcpy(m.pose, pose, sizeof m.pose);
    uint8_t b[ISO_DEV_VIEW_MSG_MAX];
    int n = iso_dev_view_encode(&m, b, sizeof b);
    iso_test_ws_send(fd, 1, 2, b, (size_t)n);
}

/* Opens a page, reads the handle's centre c and the mesh's diagonal from
 * the topology, takes control and drags; the last target's pose into last
 * (the drag ends unturned, so the centre's goal is c + last's position).
 * -1 if the page failed. */
static int drag(int port, const profile *P, double *diag_out, double c[3], double last[6])
{
    double diag = NAN;
    char host[64], origin[96];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    snprintf(origin, sizeof origin, "Origin: http://127.0.0.1:%d\r\n", port);
    int st = 0, fd = iso_test_ws_open(AF_INET, port, host, origin, 0, &st);
    if (st != 101)
        return -1;
    for (int i = 0; i < 2; i++) { /* the topology (binary), then the control state */
        unsigned char *p = NULL;
        size_t n;
        if (iso_test_ws_recv(fd, &p, &n) != 2 - i) {
            free(p);
            return -1;
        }
        if (i == 0) {
            char *json = iso_test_topology_json(p, n);
            const char *at = json ? strstr(json, "\"centre\":[") : NULL;
            if (at)
                sscanf(at + 10, "%lf,%lf,%lf", &c[0], &c[1], &c[2]);
            free(json);
            diag = iso_test_topology_diagonal(p, n);
        }
        free(p);
    }
    if (!(diag > 0))
        return -1;
    *diag_out = diag;
    iso_test_ws_reader reader; /* the frames, read as a page reads them */
    iso_test_ws_reader_start(&reader, fd);
    uint32_t seq = 1;
    send_msg(fd, ISO_DEV_VIEW_TAKE, seq++, NULL);
    double t0 = now_s() + 0.3;
    sleep_until(t0);
    for (int k = 0;; k++) {
        if (!target_at(P, diag, c, 0.025 * k, last))
            break;
        send_msg(fd, ISO_DEV_VIEW_TARGET, seq++, last);
        sleep_until(t0 + 0.025 * (k + 1));
    }
    sleep_until(now_s() + 0.5); /* the handle arrives */
    iso_test_ws_reader_stop(&reader);
    return 0;
}

/* ---- the run ---------------------------------------------------------------- */

static int write_scene(char *path, const char *source, const char *mesh, int restore, int view)
{
    int sfd = mkstemps(path, 5);
    FILE *f = sfd >= 0 ? fdopen(sfd, "w") : NULL;
    if (!f)
        return -1;
    const char *bench = strcmp(mesh, "plane") == 0 ? "bumpplane" : "cactus";
    fprintf(f, "name: drag_bench\nmesh: {benchmark: %s, fallback_shape: %s}\ndevices:\n", bench,
            bench);
    if (view)
        fprintf(f, "  - {name: hand, kind: view}\n");
    else
        fprintf(f, "  - {name: hand, kind: replay, file: %s}\n", source);
    fprintf(f, "regions:\n  sel: builtin\n  handles:\n    - name: top\n      driver:\n"
               "        device: hand\n");
    if (!view)
        fprintf(f, "        mapping: {sensitivity: {tx: 0.25, ty: 0.25, tz: 0.25, rx: 0.8, ry: "
                   "0.8, rz: 0.8}, dead_zone: 0.05}\n");
    fprintf(f,
            "solver: {omega: 0.333, restore: %s, assembly: auto, refactor: adaptive, "
            "worker_lag: 4}\n"
            "integrator: {abm: pec}\ntick_hz: 60\n"
            "sinks:\n  display: {host: 127.0.0.1}\n"
            "  actuators:\n    link: {emulated: auto}\n    channels:\n"
            "      - {channel: 0, region: top, axis: x, min: -10, max: 10, scale: 100}\n"
            "      - {channel: 1, region: top, axis: z, min: -10, max: 10, scale: 100}\n",
            restore ? "{mu: 1.0, tau: 0.5}" : "off");
    fclose(f);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 5) {
        fprintf(stderr, "usage: drag_bench ISOSHAPE view-person|view-fast|FILE.isorec "
                        "cactus|plane on|off [rt] [record=FILE]\n");
        return 2;
    }
    const char *bin = argv[1], *source = argv[2], *mesh = argv[3];
    int restore = strcmp(argv[4], "on") == 0, rt = 0;
    const char *record = NULL;
    for (int i = 5; i < argc; i++) {
        if (strcmp(argv[i], "rt") == 0)
            rt = 1;
        else if (strncmp(argv[i], "record=", 7) == 0)
            record = argv[i] + 7;
    }
    int view = strncmp(source, "view-", 5) == 0;
    const profile *P = strcmp(source, "view-fast") == 0 ? &FAST : &PERSON;
    signal(SIGPIPE, SIG_IGN);
    char scene[] = "/tmp/drag_bench_XXXXXX.yaml", stats[] = "/tmp/drag_bench_XXXXXX.json";
    int jfd = mkstemps(stats, 5);
    if (jfd < 0 || write_scene(scene, source, mesh, restore, view) != 0) {
        perror("drag_bench: temporary files");
        return 1;
    }
    close(jfd);
    char *args[16];
    int a = 0;
    args[a++] = (char *)bin;
    args[a++] = "run";
    args[a++] = scene;
    args[a++] = "--port";
    args[a++] = "0";
    args[a++] = "--stats-json";
    args[a++] = stats;
    args[a++] = view ? "--duration" : "--exit-at-end";
    if (view)
        args[a++] = "60";
    if (!rt)
        args[a++] = "--no-rt";
    if (record) {
        args[a++] = "--record";
        args[a++] = (char *)record;
    }
    args[a] = NULL;
    pid_t pid = child_stderr_run(args, &g_err);
    if (pid < 0) {
        perror("drag_bench: the run");
        return 1;
    }
    double last[6] = {0}, diag = NAN, c[3] = {0, 0, 0};
    int dragged = 0;
    if (view) {
        int port = -1;
        for (double t = now_s(); port < 0 && now_s() < t + 120; sleep_until(now_s() + 0.02))
            port = child_stderr_port(&g_err);
        if (port < 0 || drag(port, P, &diag, c, last) != 0) {
            fprintf(stderr, "drag_bench: no live view, or it refused the page:\n%s\n", g_err.text);
            kill(pid, SIGKILL);
            waitpid(pid, NULL, 0);
            return 1;
        }
        dragged = 1;
        kill(pid, SIGINT);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    child_stderr_join(&g_err);
    char *j = read_all(stats);
    unlink(scene);
    unlink(stats);
    if (!j || !strstr(j, "\"ticks\"")) {
        fprintf(stderr, "drag_bench: the run left no statistics (status %d):\n%s\n", status,
                g_err.text);
        free(j);
        return 1;
    }
    double ticks = num_in(j, NULL, "ticks"), skipped = num_in(j, NULL, "skipped");
    double facts = num_in(j, "\"solver\"", "factorizations");
    double end_off = NAN;
    if (dragged) {
        const char *h = strstr(j, "\"handles\"");
        const char *p = h ? strstr(h, "\"p\": [") : NULL;
        double q[3];
        if (p && sscanf(p + 6, "%lf, %lf, %lf", &q[0], &q[1], &q[2]) == 3) {
            double d2 = 0; /* the summary's p is the handle's centre */
            for (int i = 0; i < 3; i++)
                d2 += (q[i] - c[i] - last[i]) * (q[i] - c[i] - last[i]);
            end_off = sqrt(d2) / diag;
        }
    }
    const char *name = strrchr(source, '/') ? strrchr(source, '/') + 1 : source;
    printf("%-16s %-6s %-3s | %5.0f/%-5.0f %5.1f%% | %6.2f %7.2f %7.2f | %6.1f %6.1f %7.1f | "
           "%4.0f %5.0f | %5.0f %8.1e %4.0f | %8.1f%% | %s\n",
           name, mesh, restore ? "on" : "off", ticks, ticks + skipped,
           100 * ticks / (ticks + skipped), num_in(j, "\"tick_ms\"", "median"),
           num_in(j, "\"tick_ms\"", "p99"), num_in(j, "\"tick_ms\"", "max"),
           num_in(j, "\"latency_ms\"", "median"), num_in(j, "\"latency_ms\"", "p90"),
           num_in(j, "\"latency_ms\"", "p99"), facts - 1,
           num_in(j, "\"solver\"", "worker_handovers"), num_in(j, "\"solver\"", "inexact"),
           num_in(j, "\"solver\"", "inexact_res_max"), num_in(j, "\"solver\"", "refactors"),
           100 * num_in(j, "\"metrics\"", "max_edge_strain"),
           dragged ? (isfinite(end_off) ? "" : "no handle pose") : "");
    if (getenv("DRAG_BENCH_LOG")) /* the run's own notices */
        fputs(g_err.text, stdout);
    if (dragged && isfinite(end_off))
        printf("  (the handle ended %.1e of the diagonal from the last target)\n", end_off);
    free(j);
    return 0;
}
