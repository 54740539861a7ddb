/* tests/test_view_server.c -- the live view's server under abuse, as a
 * command channel needs it (view/iso_display.h):
 *   (a) a connect flood from another process (about 20 000 connects a
 *       second here, bounded at 60 000 and 4 s) does not starve page loads:
 *       every one of 30 page loads made during the flood succeeds (5 s
 *       bound each), at most one needs a SYN sent again (over 1 s), and
 *       the figures are printed beside the same loads without a flood;
 *   (b) a viewer the server drops (one that never reads) is closed at once
 *       with a reset: its socket on our side sees the reset, and no socket
 *       of the server's port keeps unsent data in the kernel;
 *   (c) RFC 6455: each violation closes with its status (1007 for text
 *       that is not UTF-8, 1002 for reserved opcodes, stray continuations,
 *       reserved bits, unmasked frames and bad close statuses such as 999),
 *       a valid close is answered with its own status, a ping with a pong. */
#define _DEFAULT_SOURCE 1 /* struct tcp_info and the TCP states of <netinet/tcp.h> */
#include "testutil.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "iso_display.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "ws_client.h"

typedef struct view {
    iso_shape shape;
    iso_mesh *mesh;
    iso_regions regions;
    iso_display *d;
    int port;
} view;

static void view_open(view *v, const char *shape, int res)
{
    iso_err err;
    iso_err_clear(&err);
    memset(v, 0, sizeof *v);
    if (iso_shape_init(&v->shape, shape, res, &err) != ISO_OK ||
        iso_mesh_create(v->shape.nv, v->shape.x, v->shape.nt, v->shape.tri, shape, &v->mesh,
                        &err) != ISO_OK ||
        iso_shape_regions(&v->shape, &v->regions, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    iso_display_opts o = {.mesh = v->mesh, .regions = &v->regions};
    if (iso_display_create(&o, &v->d, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    v->port = iso_display_port(v->d);
}

static void view_close(view *v)
{
    iso_display_destroy(v->d);
    iso_regions_deinit(&v->regions);
    iso_mesh_destroy(v->mesh);
    iso_shape_deinit(&v->shape);
}

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec / 1e6;
}

static void nap_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double quantile(double *v, int n, double q)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    int k = (int)ceil(q * n) - 1;
    return v[k < 0 ? 0 : k >= n ? n - 1 : k];
}

/* ---- (a) a connect flood ----------------------------------------------------- */

enum { FLOOD_MAX_CONNECTS = 60000, FLOOD_HOLD = 256, PAGE_LOADS = 30 };
#define FLOOD_MAX_S 4.0

/* The flooding process: non-blocking connects to the view as fast as it
 * can, never sending a byte. `hold` > 0 keeps that many open (the oldest
 * reset when a new one comes), 0 resets each at once. Bounded by count and
 * time; writes "connects seconds" to out. */
static void flood(int port, int hold, int out)
{
    static int held[FLOOD_HOLD];
    int n_held = 0, next = 0;
    long connects = 0;
    double t0 = now_ms();
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((unsigned short)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    struct linger reset = {1, 0};
    while (connects < FLOOD_MAX_CONNECTS && now_ms() - t0 < FLOOD_MAX_S * 1e3) {
        int fd = socket(AF_INET, SOCK_STREAM, 0);
        if (fd < 0)
            break;
        fcntl(fd, F_SETFL, O_NONBLOCK);
        setsockopt(fd, SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
        if (connect(fd, (struct sockaddr *)&a, sizeof a) == 0 || errno == EINPROGRESS)
            connects++;
        if (!hold) {
            close(fd);
            continue;
        }
        if (n_held == hold) {
            close(held[next]);
            n_held--;
        }
        held[next] = fd;
        next = (next + 1) % hold;
        n_held++;
    }
    double s = (now_ms() - t0) / 1e3;
    for (int i = 0; i < n_held; i++)
        close(held[(next + FLOOD_HOLD - n_held + i) % hold]);
    char line[64];
    int len = snprintf(line, sizeof line, "%ld %.3f\n", connects, s);
    if (write(out, line, (size_t)len) != len)
        _exit(1);
}

/* One page load: GET / whole, with a 5 s bound on every step. Returns its
 * time in ms, or -1 when it failed (reset, timeout, short body). */
static double page_load(int port)
{
    double t0 = now_ms();
    int fd = iso_test_connect(AF_INET, port, 0);
    if (fd < 0)
        return -1;
    struct timeval tv = {5, 0};
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    static const char req[] = "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
    if (send(fd, req, sizeof req - 1, MSG_NOSIGNAL) != (ssize_t)(sizeof req - 1)) {
        close(fd);
        return -1;
    }
    static char buf[1 << 16];
    size_t n = 0;
    for (;;) {
        ssize_t r = read(fd, buf + n, sizeof buf - 1 - n);
        if (r <= 0) {
            if (r < 0)
                n = 0; /* a reset or a timeout: no page */
            break;
        }
        n += (size_t)r;
    }
    close(fd);
    buf[n] = 0;
    const char *cl = strstr(buf, "Content-Length: "), *body = strstr(buf, "\r\n\r\n");
    if (n < 12 || strncmp(buf, "HTTP/1.1 200", 12) != 0 || !cl || !body ||
        (size_t)(body + 4 - buf) + strtoul(cl + 16, NULL, 10) != n)
        return -1;
    return now_ms() - t0;
}

/* Loads the page PAGE_LOADS times; returns how many succeeded, their times
 * in ms in t[]. */
static int page_loads(int port, double *t, int gap_ms)
{
    int ok = 0;
    for (int i = 0; i < PAGE_LOADS; i++) {
        double ms = page_load(port);
        if (ms >= 0)
            t[ok++] = ms;
        nap_ms(gap_ms);
    }
    return ok;
}

static void flood_run(const view *v, int hold, const char *what)
{
    int out[2];
    assert_int_equal(pipe(out), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        close(out[0]);
        flood(v->port, hold, out[1]);
        _exit(0);
    }
    close(out[1]);
    nap_ms(200); /* the flood is on */
    double t[PAGE_LOADS];
    int ok = page_loads(v->port, t, 60), slow = 0;
    for (int i = 0; i < ok; i++)
        slow += t[i] > 1000;
    int st = 0;
    waitpid(pid, &st, 0);
    char line[64] = "";
    ssize_t r = read(out[0], line, sizeof line - 1);
    close(out[0]);
    line[r > 0 ? r : 0] = 0;
    long connects = 0;
    double secs = 0;
    assert_int_equal(sscanf(line, "%ld %lf", &connects, &secs), 2);
    print_message("flood (%s): %ld connects in %.2f s (%.0f/s); %d of %d page loads during it "
                  "succeeded, %d took over 1 s: median %.1f ms, p95 %.1f ms, max %.1f ms\n",
                  what, connects, secs, (double)connects / secs, ok, PAGE_LOADS, slow,
                  ok ? quantile(t, ok, 0.5) : NAN, ok ? quantile(t, ok, 0.95) : NAN,
                  ok ? quantile(t, ok, 1.0) : NAN);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    assert_int_equal(ok, PAGE_LOADS);
    /* Over 1 s is a SYN the kernel dropped and the client sent again: the
     * server did not keep up. One is allowed to an unlucky moment of a
     * loaded machine. The server before this policy, in three runs of this
     * test on the same machine: 1 or 2 of the 30 loads reset and 1 or 2
     * over 1 s (up to 3.1 s) under every held flood. */
    assert_true(slow <= 1);
}

static void page_loads_survive_a_connect_flood(void **state)
{
    (void)state;
    view v;
    view_open(&v, "bar", 4);
    double t[PAGE_LOADS];
    int ok = page_loads(v.port, t, 10);
    print_message("no flood: %d of %d page loads: median %.1f ms, max %.1f ms\n", ok, PAGE_LOADS,
                  quantile(t, ok, 0.5), quantile(t, ok, 1.0));
    assert_int_equal(ok, PAGE_LOADS);
    flood_run(&v, FLOOD_HOLD, "each held open, silent");
    flood_run(&v, 0, "each reset at once");
    /* the view is whole after it: a viewer connects and gets its topology */
    int fd = iso_test_ws_viewer(v.port, NULL);
    assert_true(fd >= 0);
    close(fd);
    view_close(&v);
}

/* ---- (b) a viewer the server drops is reset ----------------------------------- */

/* Sockets of `port` on this machine (/proc/net/tcp and tcp6) other than
 * the listener that still hold unsent bytes, and all of them. */
static int unsent_on_port(int port, int *total)
{
    int n = 0;
    *total = 0;
    const char *files[] = {"/proc/net/tcp", "/proc/net/tcp6"};
    for (int k = 0; k < 2; k++) {
        FILE *f = fopen(files[k], "r");
        if (!f)
            continue;
        char line[512];
        if (!fgets(line, sizeof line, f)) { /* the header */
            fclose(f);
            continue;
        }
        while (fgets(line, sizeof line, f)) {
            char local[128];
            unsigned st = 0;
            unsigned long tx = 0, rx = 0;
            if (sscanf(line, "%*d: %127s %*s %x %lx:%lx", local, &st, &tx, &rx) != 4)
                continue;
            const char *colon = strrchr(local, ':');
            if (!colon || (int)strtol(colon + 1, NULL, 16) != port || st == 0x0a) /* LISTEN */
                continue;
            (*total)++;
            n += tx > 0;
        }
        fclose(f);
    }
    return n;
}

static void a_dropped_viewer_is_reset_at_once(void **state)
{
    (void)state;
    view v;
    view_open(&v, "cylinder", 64); /* ~100 KB frames: a socket that is not read fills fast */
    enum { BAD = 6 };
    int bad[BAD], st;
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", v.port);
    for (int i = 0; i < BAD; i++) {
        bad[i] = iso_test_ws_open(AF_INET, v.port, host, "", 4096, &st);
        assert_int_equal(st, 101); /* and never read again */
    }
    double t0 = now_ms(), dropped = -1;
    for (long tick = 0; now_ms() - t0 < 10000; tick++) {
        assert_int_equal(iso_display_publish(v.d, tick, v.shape.x, NULL, NULL), ISO_OK);
        if (iso_display_clients(v.d) == 0 && dropped < 0)
            dropped = now_ms() - t0;
        if (dropped >= 0 && now_ms() - t0 > dropped + 300)
            break;
        nap_ms(20);
    }
    int total = 0, unsent = unsent_on_port(v.port, &total), reset = 0;
    for (int i = 0; i < BAD; i++) {
        struct tcp_info ti;
        socklen_t tl = sizeof ti;
        memset(&ti, 0, sizeof ti);
        getsockopt(bad[i], IPPROTO_TCP, TCP_INFO, &ti, &tl);
        reset += ti.tcpi_state == TCP_CLOSE; /* a FIN would leave it in CLOSE_WAIT */
        close(bad[i]);
    }
    print_message("%d viewers that never read: dropped %.0f ms after they connected (stall limit "
                  "%d ms); %d of them saw a reset; %d sockets of the port left, %d with unsent "
                  "bytes\n",
                  BAD, dropped, ISO_DISPLAY_STALL_MS, reset, total, unsent);
    assert_true(dropped >= ISO_DISPLAY_STALL_MS - 50);
    assert_int_equal(reset, BAD);
    assert_int_equal(unsent, 0);
    view_close(&v);
}

/* ---- (c) RFC 6455 -------------------------------------------------------------- */

/* Opens a viewer, sends what `send_fn` sends, returns the close status the
 * server answers with (or -1: closed without one); *pongs counts pongs. */
static int answer_to(const view *v, const unsigned char *frames, size_t n, int *pongs)
{
    int fd = iso_test_ws_viewer(v->port, NULL);
    assert_true(fd >= 0);
    size_t off = 0;
    while (off < n) {
        ssize_t w = send(fd, frames + off, n - off, MSG_NOSIGNAL);
        if (w <= 0)
            break;
        off += (size_t)w;
    }
    int st = iso_test_ws_close_status(fd, pongs);
    close(fd);
    return st;
}

/* A masked frame, written out (mask 0: the payload as it is). */
static size_t frame(unsigned char *f, int first, const void *payload, size_t len, int masked)
{
    size_t n = 0;
    f[n++] = (unsigned char)first;
    f[n++] = (unsigned char)((masked ? 0x80 : 0) | len); /* len < 126 here */
    if (masked) {
        memset(f + n, 0, 4);
        n += 4;
    }
    memcpy(f + n, payload, len);
    return n + len;
}

static int status_of(const view *v, int first, const void *payload, size_t len)
{
    unsigned char f[256];
    return answer_to(v, f, frame(f, first, payload, len, 1), NULL);
}

static void rfc6455_violations_close_with_their_status(void **state)
{
    (void)state;
    view v;
    view_open(&v, "bar", 4);
    static const unsigned char bad_text[] = "ok \xc3\x28";
    static const unsigned char surrogate[] = "\xed\xa0\x80";
    static const unsigned char close999[] = {0x03, 0xe7}, close1001[] = {0x03, 0xe9, 'b', 'y'};
    static const unsigned char close1004[] = {0x03, 0xec}, close_bad_reason[] = {0x03, 0xe8, 0xff};
    static const unsigned char one_byte[] = {0x03};
    struct {
        const char *what;
        int first;
        const void *p;
        size_t n;
        int want;
    } cases[] = {
        {"text that is not UTF-8", 0x81, bad_text, sizeof bad_text - 1, 1007},
        {"a UTF-16 surrogate in text", 0x81, surrogate, sizeof surrogate - 1, 1007},
        {"reserved opcode 3", 0x83, "", 0, 1002},
        {"reserved opcode 0xB", 0x8b, "", 0, 1002},
        {"a continuation of nothing", 0x80, "abc", 3, 1002},
        {"a reserved bit", 0xc2, "abc", 3, 1002},
        {"a fragmented ping", 0x09, "p", 1, 1002},
        {"close status 999", 0x88, close999, 2, 1002},
        {"close status 1004", 0x88, close1004, 2, 1002},
        {"a one-byte close", 0x88, one_byte, 1, 1002},
        {"a close reason that is not UTF-8", 0x88, close_bad_reason, 3, 1007},
        {"close 1001 (going away)", 0x88, close1001, 4, 1001},
        {"close without a status", 0x88, "", 0, 1000},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int st = status_of(&v, cases[i].first, cases[i].p, cases[i].n);
        print_message("%-34s -> %d\n", cases[i].what, st);
        if (st != cases[i].want)
            fail_msg("%s: closed with %d, not %d", cases[i].what, st, cases[i].want);
    }
    /* unmasked */
    unsigned char f[256];
    assert_int_equal(answer_to(&v, f, frame(f, 0x82, "abc", 3, 0), NULL), 1002);
    /* text split inside a character is fine; a new message inside a
     * fragmented one is not; a ping inside one is answered */
    size_t n = frame(f, 0x01, "caf\xc3", 4, 1);
    n += frame(f + n, 0x80, "\xa9", 1, 1);
    n += frame(f + n, 0x89, "ping", 4, 1);
    n += frame(f + n, 0x02, "ab", 2, 1);
    n += frame(f + n, 0x82, "cd", 2, 1);
    int pongs = 0;
    assert_int_equal(answer_to(&v, f, n, &pongs), 1002);
    assert_int_equal(pongs, 1);
    /* the parser's bound: a message beyond ISO_DISPLAY_MAX_CLIENT_MESSAGE is 1009 */
    int fd = iso_test_ws_viewer(v.port, NULL);
    static unsigned char big[ISO_DISPLAY_MAX_CLIENT_MESSAGE];
    iso_test_ws_send(fd, 0, 2, big, sizeof big / 2);
    iso_test_ws_send(fd, 1, 0, big, sizeof big / 2 + 1);
    assert_int_equal(iso_test_ws_close_status(fd, NULL), 1009);
    close(fd);
    assert_int_equal(iso_display_clients(v.d) >= 0, 1);
    view_close(&v);
}

static void a_ping_is_answered_and_the_viewer_stays(void **state)
{
    (void)state;
    view v;
    view_open(&v, "bar", 4);
    int fd = iso_test_ws_viewer(v.port, NULL);
    assert_true(fd >= 0);
    iso_test_ws_send(fd, 1, 9, "are you there", 13);
    unsigned char *p;
    size_t n;
    assert_int_equal(iso_test_ws_recv(fd, &p, &n), 10);
    assert_int_equal(n, 13);
    assert_memory_equal(p, "are you there", 13);
    free(p);
    /* and frames still come after it */
    assert_int_equal(iso_display_publish(v.d, 5, v.shape.x, NULL, NULL), ISO_OK);
    assert_int_equal(iso_test_ws_recv(fd, &p, &n), 2);
    free(p);
    assert_int_equal(iso_display_clients(v.d), 1);
    close(fd);
    view_close(&v);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest t[] = {
        cmocka_unit_test(page_loads_survive_a_connect_flood),
        cmocka_unit_test(a_dropped_viewer_is_reset_at_once),
        cmocka_unit_test(rfc6455_violations_close_with_their_status),
        cmocka_unit_test(a_ping_is_answered_and_the_viewer_stays),
    };
    return cmocka_run_group_tests_name("view_server", t, NULL, NULL);
}
