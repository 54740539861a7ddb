/* tests/tools/stop_latency.c -- how long a page's STOP takes to act while
 * Foxglove clients read every channel of a large mesh as fast as loopback
 * carries it.
 *
 *   stop_latency ISOSHAPE [SUBSCRIBERS [RESOLUTION [STOPS [rt]]]]
 *
 * Runs `isoshape run` on the built-in bumpplane at RESOLUTION (default
 * 201: 40,401 vertices) with a view device driving its handle, the live
 * view and the native emulated MCU (`rt`: at real-time priority, as the
 * command runs when permitted; else --no-rt); connects SUBSCRIBERS (default 4)
 * Foxglove clients that subscribe to every channel and read without pause,
 * a page, and a second page that only watches. The page then presses STOP
 * STOPS times (default 20), 300 ms apart, each released 300 ms later (a
 * stop is held at least ISO_DISPLAY_UNSTOP_MIN_MS) before the next,
 * and prints, for the STOPs:
 *   - send -> the page's control message saying "stop": when the server
 *     had read and handed the STOP on (an upper bound of its part: the
 *     message waits behind the page's frame in flight, if any);
 *   - the actuators' own figure from the run's stderr: the e-stop (its
 *     arrival at the server) -> the MCU reports its safe state;
 *   - the subscribers' throughput and the watching page's frames a second.
 * Medians, p90 and max; the figure to hold against a bound is the sum of
 * the two. A benchmark, not a test: it prints, asserts nothing. */
#define _DEFAULT_SOURCE /* mkstemps */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
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

#define MAX_SUBS 16
#define MAX_STOPS 200

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void nap_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static void quantiles(const char *what, double *v, int n)
{
    if (n == 0) {
        printf("  %-44s none\n", what);
        return;
    }
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    printf("  %-44s median %7.1f ms  p90 %7.1f ms  max %7.1f ms  (%d)\n", what, v[n / 2],
           v[(n * 9) / 10 < n ? (n * 9) / 10 : n - 1], v[n - 1], n);
}

static child_stderr g_err; /* the run's stderr */

/* A Foxglove client that subscribes to every channel it is advertised. */
static int subscriber(int port, const char *host)
{
    int st = 0;
    int fd = iso_test_ws_open(AF_INET, port, host,
                              "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n", 0, &st);
    if (st != 101)
        return -1;
    int n_ch = 0;
    for (int i = 0; i < 2; i++) { /* serverInfo, advertise */
        unsigned char *p;
        size_t n;
        if (iso_test_ws_recv(fd, &p, &n) != 1)
            return -1;
        for (const char *q = (const char *)p; (q = strstr(q, "\"topic\"")) != NULL; q++)
            n_ch++;
        free(p);
    }
    char sub[2048];
    size_t k = (size_t)snprintf(sub, sizeof sub, "{\"op\":\"subscribe\",\"subscriptions\":[");
    for (int c = 0; c < n_ch; c++)
        k += (size_t)snprintf(sub + k, sizeof sub - k, "%s{\"id\":%d,\"channelId\":%d}",
                              c ? "," : "", c, c);
    snprintf(sub + k, sizeof sub - k, "]}");
    iso_test_ws_send(fd, 1, 1, sub, strlen(sub));
    return fd;
}

/* The page reads everything it is sent on a thread of its own (a page
 * that stops reading is dropped by the server), and keeps the newest
 * control message's stop flag and when it came. */
typedef struct page_reader {
    int fd;
    atomic_int stop;     /* -1 before the first control message */
    _Atomic double when; /* now_s() of the newest control message */
    pthread_t th;
} page_reader;

static void *read_page(void *arg)
{
    page_reader *r = arg;
    for (;;) {
        unsigned char *p;
        size_t n;
        int op = iso_test_ws_recv(r->fd, &p, &n);
        if (op < 0)
            return NULL;
        if (op == 1 && strstr((char *)p, "\"type\":\"control\"")) {
            atomic_store(&r->when, now_s());
            atomic_store(&r->stop, strstr((char *)p, "\"stop\":true") != NULL);
        }
        free(p);
    }
}

/* Waits until the page is told stop == want; the seconds since t0, or -1
 * after 10 s. */
static double wait_control(page_reader *r, int want, double t0)
{
    while (now_s() < t0 + 10) {
        if (atomic_load(&r->stop) == want)
            return atomic_load(&r->when) - t0;
        struct timespec ts = {0, 200000};
        nanosleep(&ts, NULL);
    }
    return -1;
}

static void command(int fd, int type, uint32_t seq)
{
    iso_dev_view_msg m = {(uint8_t)type, 0, seq, 1000.0 + seq, {0}};
    uint8_t b[ISO_DEV_VIEW_MSG_MAX];
    int n = iso_dev_view_encode(&m, b, sizeof b);
    iso_test_ws_send(fd, 1, 2, b, (size_t)n);
}

/* Every "reports its safe state (...) X ms after the e-stop" in stderr. */
static int safe_figures(double *v, int cap)
{
    int n = 0;
    const char *key = "reports its safe state";
    pthread_mutex_lock(&g_err.mu);
    for (const char *p = g_err.text; n < cap && (p = strstr(p, key)) != NULL; p++) {
        const char *e = strchr(p, '\n');
        const char *ms = strstr(p, ") ");
        if (ms && (!e || ms < e) && strstr(ms, "after the e-stop") &&
            strstr(ms, "after the e-stop") < (e ? e : ms + 200))
            v[n++] = strtod(ms + 2, NULL);
    }
    pthread_mutex_unlock(&g_err.mu);
    return n;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: stop_latency ISOSHAPE [SUBSCRIBERS [RESOLUTION [STOPS [rt]]]]\n");
        return 2;
    }
    int n_sub = argc > 2 ? atoi(argv[2]) : 4, res = argc > 3 ? atoi(argv[3]) : 201;
    int stops = argc > 4 ? atoi(argv[4]) : 20;
    int rt = argc > 5 && strcmp(argv[5], "rt") == 0;
    if (n_sub < 0 || n_sub > MAX_SUBS || res < 2 || stops < 1 || stops > MAX_STOPS) {
        fprintf(stderr, "stop_latency: SUBSCRIBERS 0..%d, RESOLUTION >= 2, STOPS 1..%d\n", MAX_SUBS,
                MAX_STOPS);
        return 2;
    }
    signal(SIGPIPE, SIG_IGN);
    char scene[] = "/tmp/stop_latency_XXXXXX.yaml";
    int sfd = mkstemps(scene, 5);
    FILE *f = sfd >= 0 ? fdopen(sfd, "w") : NULL;
    if (!f) {
        perror("stop_latency: scene");
        return 1;
    }
    fprintf(f,
            "name: stop_latency\nmesh: {shape: bumpplane, resolution: %d}\n"
            "devices:\n  - {name: hand, kind: view}\n"
            "regions:\n  sel: builtin\n  handles:\n    - name: top\n      driver: {device: hand}\n"
            "solver: {omega: 0.333, weighting: param, restore: off, assembly: cpu, refactor: "
            "adaptive, worker_lag: 4}\n"
            "integrator: {abm: pec}\ntick_hz: 60\n"
            "sinks:\n  display: {host: 127.0.0.1}\n"
            "  actuators:\n    link: {emulated: native}\n    channels:\n"
            "      - {channel: 0, region: top, axis: z, min: -10, max: 10, scale: 100}\n",
            res);
    fclose(f);
    char *args[] = {
        argv[1], "run", scene, "--port", "0", "--duration", "600", rt ? NULL : "--no-rt", NULL};
    pid_t pid = child_stderr_run(args, &g_err);
    if (pid < 0) {
        perror("stop_latency: the run");
        return 1;
    }
    int port = -1;
    for (double t = now_s(); port < 0 && now_s() < t + 120; nap_ms(20))
        port = child_stderr_port(&g_err);
    if (port < 0) {
        fprintf(stderr, "stop_latency: no live view address:\n%s\n", g_err.text);
        kill(pid, SIGKILL);
        return 1;
    }
    char host[64], origin[96];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    snprintf(origin, sizeof origin, "Origin: http://127.0.0.1:%d\r\n", port);
    iso_test_ws_reader subs[MAX_SUBS], watcher;
    for (int i = 0; i < n_sub; i++) {
        int fd = subscriber(port, host);
        if (fd < 0) {
            fprintf(stderr, "stop_latency: subscriber %d refused\n", i);
            kill(pid, SIGKILL);
            return 1;
        }
        iso_test_ws_reader_start(&subs[i], fd);
    }
    iso_test_ws_reader_start(&watcher, iso_test_ws_viewer(port, origin));
    page_reader page = {iso_test_ws_viewer(port, origin), -1, 0, 0};
    pthread_create(&page.th, NULL, read_page, &page);
    nap_ms(2000); /* the subscribers at full speed */
    long bytes0 = 0, frames0 = watcher.frames;
    for (int i = 0; i < n_sub; i++)
        bytes0 += subs[i].bytes;
    double t_start = now_s();
    double ack[MAX_STOPS];
    int n_ack = 0;
    for (int k = 0; k < stops; k++) {
        nap_ms(300);
        double t0 = now_s();
        command(page.fd, ISO_DEV_VIEW_STOP, (uint32_t)(2 * k + 1));
        double a = wait_control(&page, 1, t0);
        if (a >= 0)
            ack[n_ack++] = a * 1e3;
        nap_ms(300); /* a stop is not released within ISO_DISPLAY_UNSTOP_MIN_MS */
        command(page.fd, ISO_DEV_VIEW_UNSTOP, (uint32_t)(2 * k + 2));
        (void)wait_control(&page, 0, now_s());
    }
    double span = now_s() - t_start;
    long bytes1 = 0;
    for (int i = 0; i < n_sub; i++)
        bytes1 += subs[i].bytes;
    long frames1 = watcher.frames;
    kill(pid, SIGINT);
    int status;
    waitpid(pid, &status, 0);
    for (int i = 0; i < n_sub; i++)
        iso_test_ws_reader_stop(&subs[i]);
    iso_test_ws_reader_stop(&watcher);
    shutdown(page.fd, SHUT_RDWR);
    pthread_join(page.th, NULL);
    close(page.fd);
    child_stderr_join(&g_err);
    unlink(scene);
    double safe[MAX_STOPS];
    int n_safe = safe_figures(safe, MAX_STOPS);
    printf("stop_latency: bumpplane %d, %d Foxglove subscribers reading every channel, %d STOPs "
           "over %.1f s%s\n",
           res, n_sub, stops, span, rt ? ", real-time priority" : "");
    if (getenv("STOP_LATENCY_LOG"))
        fputs(g_err.text, stdout);
    printf("  subscribers: %.1f MB/s together; the watching page: %.1f frames/s\n",
           (double)(bytes1 - bytes0) / span / 1e6, (double)(frames1 - frames0) / span);
    quantiles("STOP sent -> the page told it is stopped", ack, n_ack);
    quantiles("e-stop -> the MCU reports its safe state", safe, n_safe);
    return 0;
}
