/* tests/test_run_view.c -- `isoshape run` with its live view, end to end:
 * a browser that stops reading must not stall the loop, even
 * with stderr on a terminal (where the status line reads the view's
 * counters every tick).
 *
 * The command runs twice in real time, 4 s of a scripted screw on the
 * cactus at 30 Hz, stderr on a pseudo-terminal that the test reads:
 *   A. one viewer that reads every frame;
 *   B. the same, plus a viewer that never reads (4 KiB receive buffer).
 * Asserted: B's wall time and median tick are within 1.3x of A's (a stall
 * of the size measured before the view sent only the newest frame, 29.9 s, would be far beyond), B
 * skips at most 15 more deadlines than A (half a second; a stalling view skipped 614), and in both
 * runs the reading viewer receives frames at the tick rate (at least 90% of the ticks) in order;
 * the times in one of up to three pairs of runs (the order of frames and the tick counts in every
 * one). The times are one run each on a shared machine: the 1.3x is the bound a non-reading browser
 * may cost, and the median tick (2-3 ms here) is also accepted within 2 ms of A's, since a loaded
 * 2-core machine moves a 2 ms median by more than 30% between two quiet runs (seen: 0.95x and 1.47x
 * with a load average of 11). */
#include "testutil.h"
#include "ws_client.h"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static const char *g_bin;

typedef struct run_result {
    double wall_s, tick_median;
    long ticks, skipped, good_frames;
    int good_failed, bad_status, exit_status;
    char tty[16384]; /* what the terminal showed */
} run_result;

/* Reads what the terminal got so far (non-blocking). */
static void drain_tty(int m, run_result *r, size_t *len)
{
    struct pollfd p = {m, POLLIN, 0};
    while (poll(&p, 1, 0) == 1 && (p.revents & POLLIN)) {
        char buf[4096];
        ssize_t n = read(m, buf, sizeof buf);
        if (n <= 0)
            return;
        size_t room = sizeof r->tty - 1 - *len;
        size_t k = (size_t)n < room ? (size_t)n : room;
        memcpy(r->tty + *len, buf, k);
        *len += k;
        r->tty[*len] = 0;
    }
}

static void run_view(const char *scene, int with_bad, run_result *r)
{
    memset(r, 0, sizeof *r);
    char json[4096];
    iso_test_tmp(json, sizeof json, with_bad ? "view_bad.json" : "view_good.json");
    unlink(json);
    int m, sl;
    assert_int_equal(openpty(&m, &sl, NULL, NULL, NULL), 0);
    double t0 = iso_test_now_s();
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int nul = open("/dev/null", O_RDWR);
        dup2(nul, 0);
        dup2(nul, 1);
        dup2(sl, 2); /* stderr is a terminal: the status line runs */
        close(m);
        execl(g_bin, g_bin, "run", scene, "--no-rt", "--port", "0", "--stats-json", json,
              (char *)NULL);
        _exit(127);
    }
    close(sl);
    size_t len = 0;
    int port = -1;
    while (port < 0 && iso_test_now_s() < t0 + 30) {
        drain_tty(m, r, &len);
        const char *p = strstr(r->tty, "live view on http://127.0.0.1:");
        if (p)
            port = atoi(p + strlen("live view on http://127.0.0.1:"));
        else
            iso_test_nap_ms(5);
    }
    if (port <= 0) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        fail_msg("no live view address on the terminal: %s", r->tty);
    }
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    int st = 0, bad = -1;
    iso_test_ws_reader good;
    iso_test_ws_reader_start(&good, iso_test_ws_open(AF_INET, port, host, "", 0, &st));
    assert_int_equal(st, 101);
    if (with_bad) {
        bad = iso_test_ws_open(AF_INET, port, host, "", 4096, &r->bad_status);
        assert_int_equal(r->bad_status, 101); /* and it never reads again */
    }
    int status = 0;
    while (waitpid(pid, &status, WNOHANG) == 0) {
        if (iso_test_now_s() > t0 + 120) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            fail_msg("the run did not end within 120 s");
        }
        drain_tty(m, r, &len);
        iso_test_nap_ms(10);
    }
    drain_tty(m, r, &len);
    r->wall_s = iso_test_now_s() - t0;
    iso_test_ws_reader_stop(&good);
    if (bad >= 0)
        close(bad);
    close(m);
    r->exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r->good_frames = good.frames;
    r->good_failed = good.failed;
    static char j[1 << 16];
    FILE *f = fopen(json, "rb");
    if (!f)
        fail_msg("no stats JSON; the terminal showed: %s", r->tty);
    size_t n = fread(j, 1, sizeof j - 1, f);
    j[n] = 0;
    fclose(f);
    r->ticks = (long)iso_test_json_num(j, "ticks");
    r->skipped = (long)iso_test_json_num(j, "skipped");
    const char *tk = strstr(j, "\"tick_ms\": {");
    assert_non_null(tk);
    r->tick_median = iso_test_json_num(tk, "median");
}

static void a_browser_that_stops_reading_does_not_stall_the_loop(void **state)
{
    (void)state;
    char scene[4096];
    iso_test_tmp(scene, sizeof scene, "view_e2e.yaml");
    iso_test_write(scene,
                   "name: view_e2e\n"
                   "mesh: {shape: cactus, resolution: 1}\n"
                   "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                   "      driver: {screw: {def: builtin, duration: 4.0}}\n"
                   "solver: {assembly: cpu, refactor: adaptive}\n"
                   "tick_hz: 30\n"
                   "sinks:\n  display: {host: 127.0.0.1}\n",
                   -1);
    run_result *a = calloc(1, sizeof *a), *b = calloc(1, sizeof *b);
    assert_non_null(a);
    assert_non_null(b);
    /* The comparison is of two runs' times on a shared machine, so a pair
     * whose load differed can miss a bound by chance; up to three pairs
     * are run and one within every bound passes. A stall of the size once
     * measured (29.9 s, 614 skipped deadlines) misses them in every pair.
     * What does not depend on time is asserted in each. */
    int fits = 0;
    for (int attempt = 1; attempt <= 3 && !fits; attempt++) {
        run_view(scene, 0, a);
        if (a->tick_median > 0.5 * 1000.0 / 30) { /* e.g. an ASan build at -O0 */
            print_message("skipped: this build's median tick (%.1f ms) does not fit half the 33 "
                          "ms period, so the run is not in real time and the comparison means "
                          "nothing\n",
                          a->tick_median);
            free(a);
            free(b);
            skip();
        }
        run_view(scene, 1, b);
        print_message("view e2e, pair %d: one reading viewer: wall %.2f s, %ld ticks, median tick "
                      "%.2f ms, %ld skipped, the viewer got %ld frames\n",
                      attempt, a->wall_s, a->ticks, a->tick_median, a->skipped, a->good_frames);
        print_message("view e2e, pair %d: plus one that never reads: wall %.2f s (%.2fx), %ld "
                      "ticks, median tick %.2f ms (%.2fx), %ld skipped, the reading viewer got %ld "
                      "frames\n",
                      attempt, b->wall_s, b->wall_s / a->wall_s, b->ticks, b->tick_median,
                      b->tick_median / a->tick_median, b->skipped, b->good_frames);
        assert_int_equal(a->exit_status, 0);
        assert_int_equal(b->exit_status, 0);
        assert_int_equal(a->ticks + a->skipped, 120); /* 4 s at 30 Hz: computed + covered */
        assert_int_equal(b->ticks + b->skipped, 120);
        assert_false(a->good_failed); /* frames in tick order */
        assert_false(b->good_failed);
        /* the status line ran: it is what reads the view's counters each tick */
        assert_non_null(strstr(b->tty, "browsers 2"));
        fits = b->wall_s <= 1.3 * a->wall_s &&
               (b->tick_median <= 1.3 * a->tick_median || b->tick_median <= a->tick_median + 2.0) &&
               b->skipped <= a->skipped + 15 && /* half a second */
               a->good_frames >= (long)(0.9 * (double)a->ticks) &&
               b->good_frames >= (long)(0.9 * (double)b->ticks);
    }
    assert_true(fits);
    free(a);
    free(b);
}

/* On a terminal a run that ends by itself keeps its view up with the last
 * frame and the summary until Ctrl-C (exit 0); --exit-at-end does not wait. */
static int run_on_a_terminal(const char *scene, const char *extra, char *tty, size_t cap,
                             double *held_s)
{
    int m, sl;
    assert_int_equal(openpty(&m, &sl, NULL, NULL, NULL), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int nul = open("/dev/null", O_RDWR);
        dup2(sl, 0); /* stdin and stderr a terminal: Ctrl-C can come */
        dup2(nul, 1);
        dup2(sl, 2);
        close(m);
        execl(g_bin, g_bin, "run", scene, "--no-rt", "--port", "0", extra, (char *)NULL);
        _exit(127);
    }
    close(sl);
    run_result *r = calloc(1, sizeof *r);
    assert_non_null(r);
    size_t len = 0;
    double t0 = iso_test_now_s(), ended = -1;
    int status = 0, signalled = 0;
    while (waitpid(pid, &status, WNOHANG) == 0) {
        drain_tty(m, r, &len);
        const char *held = strstr(r->tty, "the run has ended; the live view keeps showing");
        if (held && ended < 0) {
            ended = iso_test_now_s();
            /* the page still loads, and its viewer gets the summary */
            const char *u = strstr(held, "http://127.0.0.1:");
            assert_non_null(u);
            int port = atoi(u + strlen("http://127.0.0.1:"));
            char host[64];
            snprintf(host, sizeof host, "127.0.0.1:%d", port);
            int st, fd = iso_test_ws_open(AF_INET, port, host, "", 0, &st);
            assert_int_equal(st, 101);
            int note = 0;
            for (int i = 0; i < 8 && !note; i++) {
                unsigned char *p;
                size_t n;
                if (iso_test_ws_recv(fd, &p, &n) < 0)
                    break;
                note = strstr((char *)p, "\"type\":\"note\"") && strstr((char *)p, "scene ");
                free(p);
            }
            close(fd);
            assert_true(note);
        }
        if (ended > 0 && !signalled && iso_test_now_s() > ended + 1.0) {
            kill(pid, SIGINT); /* the user's Ctrl-C */
            signalled = 1;
        }
        if (iso_test_now_s() > t0 + 120) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            fail_msg("the run did not end within 120 s: %s", r->tty);
        }
        iso_test_nap_ms(10);
    }
    drain_tty(m, r, &len);
    close(m);
    snprintf(tty, cap, "%s", r->tty);
    *held_s = ended > 0 ? iso_test_now_s() - ended : 0;
    free(r);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static void on_a_terminal_the_view_stays_until_ctrl_c(void **state)
{
    (void)state;
    char scene[4096];
    iso_test_tmp(scene, sizeof scene, "view_hold.yaml");
    iso_test_write(scene,
                   "name: view_hold\n"
                   "mesh: {shape: cactus, resolution: 1}\n"
                   "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                   "      driver: {screw: {def: builtin, duration: 0.5}}\n"
                   "solver: {assembly: cpu, refactor: adaptive}\n"
                   "tick_hz: 30\n"
                   "sinks:\n  display: {host: 127.0.0.1}\n",
                   -1);
    static char tty[16384];
    double held;
    int st = run_on_a_terminal(scene, "--quiet", tty, sizeof tty, &held);
    print_message("on a terminal: held the view %.1f s after the end, until SIGINT; exit %d\n",
                  held, st);
    assert_int_equal(st, 0);
    assert_true(held >= 1.0);
    assert_non_null(strstr(tty, "press Ctrl-C to quit"));
    st = run_on_a_terminal(scene, "--exit-at-end", tty, sizeof tty, &held);
    assert_int_equal(st, 0);
    assert_true(held == 0); /* never said it was holding */
    assert_null(strstr(tty, "keeps showing"));
}

int main(void)
{
    g_bin = getenv("ISOSHAPE_BIN");
    if (!g_bin || access(g_bin, X_OK) != 0) {
        printf("skipped: ISOSHAPE_BIN does not name the isoshape command (CTest sets it)\n");
        return ISO_TEST_SKIP;
    }
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest t[] = {
        cmocka_unit_test(a_browser_that_stops_reading_does_not_stall_the_loop),
        cmocka_unit_test(on_a_terminal_the_view_stays_until_ctrl_c),
    };
    return cmocka_run_group_tests(t, NULL, NULL);
}
