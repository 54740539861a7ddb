/* tests/test_log_blocked.c -- a stderr nobody reads cannot freeze the
 * controller, hold up its actuators' watchdog or keep a stop from ending
 * the run.
 *
 * `isoshape run` on a scene of the built-in cactus with a view device and
 * the native emulated MCU; its stderr is a pipe this test reads only until
 * the live view's address is there, and then fills to the brim and never
 * reads again (a `| less` left at its first page, a terminal after Ctrl-S,
 * a supervisor that stopped draining). A page then presses STOP and
 * releases it as fast as the socket takes the messages, for 3 s (the
 * environment's ISO_TEST_FLAP_S seconds instead, for the 30 s figure), each of
 * them a notice of the tick's (STOP pressed) and of the actuators' sender
 * (its safe state, re-arming); another page watches the frames.
 * Asserted:
 *   - the loop keeps ticking: the watching page gets frames in the last
 *     second of the flapping (at least 20 of the 60 a second it publishes;
 *     before the rule, the tick sat in write(2) on its first notice once
 *     the pipe was full, and frames stopped);
 *   - SIGINT ends the run within 1 s (2 s under a sanitizer, which slows
 *     the safe stop), with its summary on stdout and an exit status of 130;
 *   - the actuators' loop watchdog never braked for a stalled loop
 *     (loop_stalls 0 in --stats-json).
 * Skips (77) without the isoshape binary. */
#define _GNU_SOURCE
#include "testutil.h"
#include "ws_client.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "iso_dev_view.h"

#if defined(__SANITIZE_ADDRESS__)
#define STOP_BOUND_S 2.0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define STOP_BOUND_S 2.0
#endif
#endif
#ifndef STOP_BOUND_S
#define STOP_BOUND_S 1.0
#endif

static const char scene_text[] =
    "name: log_blocked\n"
    "mesh: {shape: cactus}\n"
    "devices:\n"
    "  - {name: hand, kind: view}\n"
    "regions:\n"
    "  sel: builtin\n"
    "  handles:\n"
    "    - name: top\n"
    "      driver: {device: hand}\n"
    "solver: {omega: 0.333, assembly: cpu, refactor: adaptive, worker_lag: 4}\n"
    "integrator: {abm: pec}\n"
    "tick_hz: 60\n"
    "sinks:\n"
    "  display: {host: 127.0.0.1}\n"
    "  actuators:\n"
    "    link: {emulated: native}\n"
    "    channels:\n"
    "      - {channel: 0, region: top, axis: z, min: 0.3, max: 1.0, scale: 1000}\n";

/* Reads the pipe until the view's port is said; -1 after 60 s. */
static int read_port(int fd, char *seen, size_t cap)
{
    size_t len = 0;
    double until = iso_test_now_s() + 60;
    const char *key = "live view on http://127.0.0.1:";
    while (iso_test_now_s() < until) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 100) == 1) {
            ssize_t n = read(fd, seen + len, cap - 1 - len);
            if (n <= 0)
                return -1;
            len += (size_t)n;
            seen[len] = 0;
            const char *at = strstr(seen, key);
            if (at && strchr(at, '\n'))
                return atoi(at + strlen(key));
        }
    }
    return -1;
}

static void stop_and_release(int fd, uint32_t seq)
{
    for (int type = ISO_DEV_VIEW_STOP; type <= ISO_DEV_VIEW_UNSTOP; type++) {
        iso_dev_view_msg m = {(uint8_t)type, 0, seq, 1000.0 + seq, {0}};
        uint8_t b[ISO_DEV_VIEW_MSG_MAX];
        int n = iso_dev_view_encode(&m, b, sizeof b);
        assert_true(n > 0);
        iso_test_ws_send(fd, 1, 2, b, (size_t)n);
    }
}

static long json_long(const char *json, const char *key)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\":", key);
    const char *at = strstr(json, k);
    return at ? strtol(at + strlen(k), NULL, 10) : -1;
}

static void a_stderr_nobody_reads_freezes_nothing(void **state)
{
    (void)state;
    const char *bin = getenv("ISOSHAPE_BIN");
    if (!bin || access(bin, X_OK) != 0)
        skip();
    char scene[4096], json[4096], out[4096];
    iso_test_tmp(scene, sizeof scene, "log_blocked.yaml");
    iso_test_tmp(json, sizeof json, "log_blocked.json");
    iso_test_tmp(out, sizeof out, "log_blocked.out");
    FILE *f = fopen(scene, "w");
    assert_non_null(f);
    fputs(scene_text, f);
    fclose(f);
    unlink(json);
    int err[2];
    assert_int_equal(pipe(err), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int nul = open("/dev/null", O_RDONLY);
        int o = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(nul, 0);
        dup2(o, 1);
        dup2(err[1], 2);
        close(err[0]);
        execl(bin, bin, "run", scene, "--no-rt", "--port", "0", "--stats-json", json, "--duration",
              "60", (char *)NULL);
        _exit(127);
    }
    static char seen[1 << 16];
    int port = read_port(err[0], seen, sizeof seen);
    if (port <= 0) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        fail_msg("no live view address on stderr: %s", seen);
    }
    /* From here on nobody reads stderr, and it is full. The filling goes
     * through an open file description of its own: O_NONBLOCK on the one
     * the run shares would make the run's stderr non-blocking too. */
    char self[64];
    snprintf(self, sizeof self, "/proc/self/fd/%d", err[1]);
    int fill = open(self, O_WRONLY | O_NONBLOCK);
    assert_true(fill >= 0);
    long filled = 0;
    while (write(fill, "x", 1) == 1)
        filled++;
    close(fill);
    char host[64], origin[96];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    snprintf(origin, sizeof origin, "Origin: http://127.0.0.1:%d\r\n", port);
    int st = 0;
    iso_test_ws_reader watcher;
    iso_test_ws_reader_start(&watcher, iso_test_ws_open(AF_INET, port, host, origin, 0, &st));
    assert_int_equal(st, 101);
    int page = iso_test_ws_open(AF_INET, port, host, origin, 0, &st);
    assert_int_equal(st, 101);
    iso_test_ws_reader pager; /* reads what the page is sent, so its socket never fills */
    iso_test_ws_reader_start(&pager, page);
    const char *flap_env = getenv("ISO_TEST_FLAP_S");
    double flap_s = flap_env && atof(flap_env) >= 2 ? atof(flap_env) : 3;
    double t0 = iso_test_now_s();
    long flaps = 0, frames_2s = -1;
    uint32_t seq = 1;
    while (iso_test_now_s() < t0 + flap_s) {
        stop_and_release(page, seq);
        seq += 2;
        flaps++;
        if (frames_2s < 0 && iso_test_now_s() > t0 + flap_s - 1)
            frames_2s = watcher.frames;
        if (flaps % 50 == 0)
            iso_test_nap_ms(1); /* the server thread and the loop share two cores with us */
    }
    long frames_3s = watcher.frames;
    double t_int = iso_test_now_s();
    kill(pid, SIGINT);
    int status = 0;
    while (waitpid(pid, &status, WNOHANG) == 0 && iso_test_now_s() < t_int + 20)
        iso_test_nap_ms(5);
    double stop_s = iso_test_now_s() - t_int;
    if (stop_s >= 20) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
    }
    iso_test_ws_reader_stop(&watcher);
    iso_test_ws_reader_stop(&pager);
    close(err[0]);
    close(err[1]);
    static char summary[1 << 16], stats[1 << 16];
    f = fopen(out, "rb");
    size_t n = f ? fread(summary, 1, sizeof summary - 1, f) : 0;
    summary[n] = 0;
    if (f)
        fclose(f);
    f = fopen(json, "rb");
    n = f ? fread(stats, 1, sizeof stats - 1, f) : 0;
    stats[n] = 0;
    if (f)
        fclose(f);
    long stalls = json_long(stats, "loop_stalls"), ticks = json_long(stats, "ticks");
    print_message(
        "stderr filled with %ld more bytes and never read; %ld STOP/UNSTOP pairs in %g s; "
        "frames to the watching page in the last second: %ld; SIGINT to exit: %.0f ms "
        "(exit status %d); ticks %ld, loop stalls %ld\n",
        filled, flaps, flap_s, frames_3s - frames_2s, stop_s * 1e3,
        WIFEXITED(status) ? WEXITSTATUS(status) : -1, ticks, stalls);
    assert_true(frames_3s - frames_2s >= 20);
    assert_true(stop_s < STOP_BOUND_S);
    assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 130);
    assert_non_null(strstr(summary, "ticks"));
    assert_true(ticks > 0);
    assert_int_equal(stalls, 0);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest t[] = {
        cmocka_unit_test(a_stderr_nobody_reads_freezes_nothing),
    };
    return cmocka_run_group_tests_name("log_blocked", t, NULL, NULL);
}
