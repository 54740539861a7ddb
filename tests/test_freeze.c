/* tests/test_freeze.c -- a whole `isoshape run` process frozen (SIGSTOP for
 * 1 s, then SIGCONT) while it drives an actuator MCU: the sink counts the
 * stall, sends SAFE, and re-arms only with a tick computed after the
 * freeze; no setpoint from before the stop reaches the MCU after it.
 *
 * - This program plays the MCU on a pseudo-terminal (the same iso_fb_mcu.c
 *   logic as the firmware, clocked by this process, which the SIGSTOP does
 *   not stop) and logs every frame the host sends, so the ticks of the
 *   SETPOINTS it gets after the SIGCONT are seen from outside. The run's
 *   ticks are 50 ms apart (20 Hz) and the stop comes within a few ms of the
 *   first frame of a new tick k, so no later tick had begun: every SETPOINTS
 *   after the SIGCONT must carry a tick of at least k + 2 (k + 1 is the first
 *   tick published after the stop, which the sink takes to be one that may
 *   have begun before it).
 * - The same with the firmware in QEMU, which keeps running while isoshape
 *   is stopped (its watchdog brakes it), and with the native MCU thread,
 *   which stops with it: the run says STALLED, counts the stall in its
 *   summary, and re-arms afterwards.
 * - QEMU itself stopped under a run, for 1 s: the MCU's silence is said and
 *   its return; then for 4 s, past the emulated link's 3 s timeout: the loss
 *   is said, and nothing says the link is back (reopened, answering, armed)
 *   while QEMU is still stopped; it re-arms once QEMU runs. The loop, which
 *   never stopped, counts no stall.
 * Skips (77) without the isoshape binary, and the QEMU part without QEMU or
 * the firmware ELF. */
#define _DEFAULT_SOURCE /* openpty */
#include "testutil.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <pty.h>
#include <sched.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include "iso_actuators.h"
#include "iso_clock.h"
#include "iso_fb.h"
#include "iso_fb_mcu.h"

#define MAX_LOG 20000

/* One frame the host sent, as the MCU got it. */
typedef struct heard {
    double t;
    uint8_t type;
    uint32_t tick; /* SETPOINTS */
    uint8_t state; /* the MCU's state after it */
} heard;

static struct {
    char bin[1024];
    int master;
    iso_fb_mcu mcu;
    iso_fb_parser log_parser;
    pthread_mutex_t lock;
    heard log[MAX_LOG];
    int n;
    atomic_int quit;
} g = {.lock = PTHREAD_MUTEX_INITIALIZER};

static void mcu_write(void *ctx, const uint8_t *b, size_t n)
{
    (void)ctx;
    while (n > 0) {
        ssize_t w = write(g.master, b, n);
        if (w > 0) {
            b += w;
            n -= (size_t)w;
        } else if (w < 0 && errno != EAGAIN && errno != EINTR) {
            return; /* the host is gone */
        } else {
            struct pollfd p = {g.master, POLLOUT, 0};
            if (poll(&p, 1, 5) <= 0)
                return; /* a stopped host reads nothing: drop, as a UART would */
        }
    }
}

static void log_bytes(const uint8_t *b, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        iso_fb_view v;
        if (iso_fb_parser_feed(&g.log_parser, b[i], &v) != ISO_FB_FRAME)
            continue;
        heard h = {iso_clock_now(), v.type, 0, g.mcu.state};
        iso_fb_setpoints s;
        if (v.type == ISO_FB_SETPOINTS && iso_fb_setpoints_unpack(&s, v.payload, v.len) == 0)
            h.tick = s.tick;
        pthread_mutex_lock(&g.lock);
        if (g.n < MAX_LOG)
            g.log[g.n++] = h;
        pthread_mutex_unlock(&g.lock);
    }
}

/* The MCU: bytes from the host to both the logger and the MCU logic, its
 * clock every millisecond. */
static void *mcu_main(void *arg)
{
    (void)arg;
    struct sched_param sp = {.sched_priority = 30}; /* hardware: above the run's threads */
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    int64_t t0 = iso_clock_ns();
    uint8_t buf[512];
    while (!atomic_load(&g.quit)) {
        struct pollfd p = {g.master, POLLIN, 0};
        int ready = poll(&p, 1, 1) > 0 && (p.revents & POLLIN);
        /* the clock first: bytes that waited for this thread count as
         * arriving now, not as late (its own delays fake no watchdog) */
        iso_fb_mcu_tick(&g.mcu, (uint32_t)((iso_clock_ns() - t0) / 1000000));
        ssize_t n = ready ? read(g.master, buf, sizeof buf) : 0;
        if (n > 0) {
            log_bytes(buf, (size_t)n);
            iso_fb_mcu_rx(&g.mcu, buf, (size_t)n);
        }
    }
    return NULL;
}

/* The largest SETPOINTS tick logged so far, and how many frames. */
static uint32_t max_tick(int *n)
{
    uint32_t k = 0;
    pthread_mutex_lock(&g.lock);
    for (int i = 0; i < g.n; i++)
        if (g.log[i].type == ISO_FB_SETPOINTS && g.log[i].tick > k)
            k = g.log[i].tick;
    if (n)
        *n = g.n;
    pthread_mutex_unlock(&g.lock);
    return k;
}

static void write_scene(const char *path, const char *link)
{
    char text[2048];
    snprintf(text, sizeof text,
             "name: freeze\n"
             "mesh: {shape: cactus, resolution: 1}\n"
             "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
             "      driver: {screw: {def: builtin, duration: 30.0}}\n"
             "solver: {assembly: cpu, refactor: adaptive}\n"
             "tick_hz: 20\n"
             "sinks:\n  actuators:\n    link: %s\n"
             "    channels:\n"
             "      - {channel: 0, region: top, axis: z, min: -100, max: 100, scale: 10}\n"
             "      - {channel: 1, region: top, axis: x, min: -100, max: 100, scale: 10}\n",
             link);
    iso_test_write(path, text, -1);
}

/* Starts `isoshape run SCENE --no-display` with its output into out_path. */
static pid_t start_run(const char *scene, const char *out_path)
{
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int fd = open(out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd < 0)
            _exit(127);
        dup2(fd, 1);
        dup2(fd, 2);
        execl(g.bin, g.bin, "run", scene, "--no-display", "--duration", "25", (char *)NULL);
        _exit(127);
    }
    return pid;
}

/* Stops the run cleanly (SIGINT) and returns its output. */
static char *end_run(pid_t pid, const char *out_path)
{
    kill(pid, SIGINT);
    int status = 0;
    double end = iso_clock_now() + 20;
    while (waitpid(pid, &status, WNOHANG) == 0 && iso_clock_now() < end)
        usleep(10000);
    if (iso_clock_now() >= end) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        fail_msg("isoshape run did not stop within 20 s of SIGINT");
    }
    static char out[1 << 17];
    FILE *f = fopen(out_path, "r");
    assert_non_null(f);
    size_t n = fread(out, 1, sizeof out - 1, f);
    out[n] = 0;
    fclose(f);
    printf("---- isoshape run (exit %d) ----\n%s----\n",
           WIFEXITED(status) ? WEXITSTATUS(status) : -1, out);
    assert_true(WIFEXITED(status));
    assert_true(WEXITSTATUS(status) == 0 || WEXITSTATUS(status) == 130);
    return out;
}

static unsigned loop_stalls(const char *out)
{
    const char *p = strstr(out, "loop stalls ");
    assert_non_null(p);
    return (unsigned)strtoul(p + strlen("loop stalls "), NULL, 10);
}

static void frozen_run_rearms_only_with_fresh_ticks(void **state)
{
    (void)state;
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0) {
        print_message("skipped: the isoshape binary is not built\n");
        skip();
    }
    struct termios raw;
    memset(&raw, 0, sizeof raw);
    cfmakeraw(&raw);
    int slave = -1;
    char name[128];
    assert_int_equal(openpty(&g.master, &slave, name, &raw, NULL), 0);
    assert_int_equal(fcntl(g.master, F_SETFL, fcntl(g.master, F_GETFL) | O_NONBLOCK), 0);
    iso_fb_mcu_config cfg;
    iso_fb_mcu_config_board(&cfg);
    iso_fb_parser_init(&g.log_parser);
    assert_int_equal(iso_fb_mcu_init(&g.mcu, &cfg, mcu_write, NULL, 0), 0);
    pthread_t th;
    atomic_store(&g.quit, 0);
    assert_int_equal(pthread_create(&th, NULL, mcu_main, NULL), 0);

    char scene[1024], out_path[1024], link[256];
    iso_test_tmp(scene, sizeof scene, "freeze_pty.yaml");
    iso_test_tmp(out_path, sizeof out_path, "freeze_pty.out");
    snprintf(link, sizeof link, "{tty: \"%s\"}", name);
    write_scene(scene, link);
    pid_t pid = start_run(scene, out_path);

    /* streaming: 20 ticks, within a minute on a loaded machine */
    double give_up = iso_clock_now() + 60;
    while (max_tick(NULL) < 20 && iso_clock_now() < give_up)
        usleep(2000);
    if (max_tick(NULL) < 20) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        fail_msg("no setpoints streamed within 60 s");
    }
    /* the stop, right after the first frame of a new tick */
    uint32_t k0 = max_tick(NULL), k;
    while ((k = max_tick(NULL)) == k0)
        usleep(200);
    double t_seen = iso_clock_now();
    assert_int_equal(kill(pid, SIGSTOP), 0);
    double t_stop = iso_clock_now();
    int n_stop = 0;
    max_tick(&n_stop);
    usleep(1000000);
    int n_cont = 0;
    max_tick(&n_cont);
    assert_int_equal(kill(pid, SIGCONT), 0);
    double t_cont = iso_clock_now();
    usleep(3000000);
    char *out = end_run(pid, out_path);
    atomic_store(&g.quit, 1);
    pthread_join(th, NULL);

    /* frames logged during the stop: those written before it, read late */
    int stale = 0, after = 0, hello_before_first = 0, first_after = -1;
    uint32_t first_tick = 0;
    double t_first = 0;
    pthread_mutex_lock(&g.lock);
    for (int i = n_cont; i < g.n; i++) {
        const heard *h = &g.log[i];
        if (h->type == ISO_FB_HELLO && first_after < 0)
            hello_before_first = 1;
        if (h->type != ISO_FB_SETPOINTS)
            continue;
        after++;
        stale += h->tick < k + 2;
        if (first_after < 0) {
            first_after = i;
            first_tick = h->tick;
            t_first = h->t;
        }
    }
    int during = n_cont - n_stop;
    pthread_mutex_unlock(&g.lock);
    printf("stopped at tick %u (%.1f ms after its first frame came); %d frames heard while "
           "stopped; after the SIGCONT: first SETPOINTS tick %u, %.0f ms after it, %d SETPOINTS, "
           "%d of them from before the stop; HELLO before them: %s\n",
           k, (t_stop - t_seen) * 1000, during, first_tick, (t_first - t_cont) * 1000, after, stale,
           hello_before_first ? "yes" : "no");
    assert_int_equal(stale, 0);
    assert_true(after > 10);         /* it streams again */
    assert_true(hello_before_first); /* re-armed by HELLO, as after any hold */
    assert_true(during <= 3);        /* frames in the pty when it stopped, at most */
    assert_non_null(strstr(out, "STALLED: this process did not run for"));
    assert_true(loop_stalls(out) >= 1); /* 0 before the sink watched its own clock */
    close(slave);
    close(g.master);
}

/* The pid of the QEMU child of process pid, or -1. */
static int qemu_child(pid_t pid)
{
    char path[64], buf[256];
    snprintf(path, sizeof path, "/proc/%d/task/%d/children", (int)pid, (int)pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    for (char *save = NULL, *t = strtok_r(buf, " \n", &save); t; t = strtok_r(NULL, " \n", &save)) {
        char comm[64] = "";
        snprintf(path, sizeof path, "/proc/%s/comm", t);
        FILE *c = fopen(path, "r");
        if (c) {
            if (!fgets(comm, sizeof comm, c))
                comm[0] = 0;
            fclose(c);
        }
        if (strncmp(comm, "qemu-system-arm", 15) == 0)
            return atoi(t);
    }
    return -1;
}

/* The run's output so far (stdout and stderr, unbuffered notices) into buf;
 * returns its length. */
static size_t output_now(const char *out_path, char *buf, size_t cap)
{
    buf[0] = 0;
    FILE *f = fopen(out_path, "r");
    if (!f)
        return 0;
    size_t n = fread(buf, 1, cap - 1, f);
    buf[n] = 0;
    fclose(f);
    return n;
}

/* Waits until the run's output after byte `from` holds `what`; fails,
 * saying so, after `secs` (a bound for a loaded machine, not a timing). */
static void await_output(pid_t pid, const char *out_path, size_t from, const char *what,
                         double secs)
{
    static char buf[1 << 17];
    double end = iso_clock_now() + secs;
    for (;;) {
        size_t n = output_now(out_path, buf, sizeof buf);
        if (n > from && strstr(buf + from, what))
            return;
        if (iso_clock_now() > end)
            break;
        usleep(20000);
    }
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    fail_msg("no '%s' within %.0f s; the run said:\n%s", what, secs, buf);
}

/* QEMU stopped for 4 s, past the link's timeout for an emulation (3 s):
 * the loss is said while it is stopped, and nothing says the link or the
 * MCU is back until it runs; then the link is taken up again and re-arms. */
static void qemu_stopped_past_the_link_timeout(pid_t pid, pid_t qemu, const char *out_path)
{
    static char buf[1 << 17];
    size_t before = output_now(out_path, buf, sizeof buf);
    assert_int_equal(kill(qemu, SIGSTOP), 0);
    usleep(4000000);
    size_t frozen = output_now(out_path, buf, sizeof buf); /* all it said while QEMU was stopped */
    assert_int_equal(kill(qemu, SIGCONT), 0);
    char said[1 << 14];
    snprintf(said, sizeof said, "%.*s", (int)(frozen - before), buf + before);
    printf("---- while QEMU was stopped for 4 s ----\n%s----\n", said);
    assert_non_null(strstr(said, "LINK LOST"));
    assert_null(strstr(said, "link reopened"));
    assert_null(strstr(said, "answers again"));
    assert_null(strstr(said, "armed again"));
    await_output(pid, out_path, frozen, "MCU armed again", 20);
    output_now(out_path, buf, sizeof buf);
    assert_non_null(strstr(buf + frozen, "link reopened"));
    usleep(1000000); /* streaming again: the run's end then finds fresh setpoints */
}

/* An emulated MCU (`link`): isoshape stopped for 1 s (stop_qemu = 0), or
 * QEMU itself (1: for 1 s, then for 4 s). */
static void frozen_with_emulation(const char *link, int stop_qemu, const char *label)
{
    char scene[1024], out_path[1024], name[64];
    snprintf(name, sizeof name, "freeze_%s.yaml", label);
    iso_test_tmp(scene, sizeof scene, name);
    snprintf(name, sizeof name, "freeze_%s.out", label);
    iso_test_tmp(out_path, sizeof out_path, name);
    write_scene(scene, link);
    pid_t pid = start_run(scene, out_path);
    usleep(4000000); /* up and streaming */
    pid_t target = stop_qemu ? qemu_child(pid) : pid;
    if (target <= 0) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        fail_msg("%s: no QEMU child of isoshape run (pid %d)", label, (int)pid);
    }
    assert_int_equal(kill(target, SIGSTOP), 0);
    usleep(1000000);
    assert_int_equal(kill(target, SIGCONT), 0);
    if (stop_qemu) {
        await_output(pid, out_path, 0, "the MCU answers again", 20);
        usleep(1000000); /* re-armed after its clock's jump, so the long stop finds it streaming */
        qemu_stopped_past_the_link_timeout(pid, target, out_path);
    } else {
        usleep(3000000);
    }
    char *out = end_run(pid, out_path);
    if (stop_qemu) {
        /* the MCU froze, this process did not: silence said, then answers
         * again; the loop never stalled; stale setpoints queued meanwhile
         * are the MCU's to refuse (test_actuators: NAK not armed) */
        assert_non_null(strstr(out, "the MCU has been silent for 500 ms"));
        assert_non_null(strstr(out, "the MCU answers again"));
        assert_null(strstr(out, "STALLED"));
        assert_int_equal(loop_stalls(out), 0);
        /* setpoints flowed after the re-arm: the last ones came well after
         * the 4 s stop began */
        const char *last = strstr(out, "safe state reported ");
        assert_non_null(last);
        assert_true(strtod(last + strlen("safe state reported "), NULL) < 3000);
        return;
    }
    const char *stall = strstr(out, "STALLED: this process did not run for");
    assert_non_null(stall);
    assert_true(loop_stalls(out) >= 1);
    assert_non_null(strstr(stall, "re-arming the MCU (HELLO) for the loop's new tick"));
    assert_null(strstr(out, "went to its safe state by itself")); /* the stall, not a mystery */
    assert_non_null(strstr(out, "safe state reported"));          /* the clean stop at the end */
}

static int have_qemu(void)
{
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0 ||
        access("/usr/bin/qemu-system-arm", X_OK) != 0 || !getenv("ISO_FB_FIRMWARE")) {
        print_message("skipped: needs the isoshape binary, qemu-system-arm and $ISO_FB_FIRMWARE\n");
        return 0;
    }
    return 1;
}

/* The firmware in QEMU runs on while isoshape is stopped: its watchdog
 * brakes it; the run says so, counts the stall and re-arms after it. */
static void frozen_run_with_qemu(void **state)
{
    (void)state;
    if (!have_qemu())
        skip();
    frozen_with_emulation("{emulated: qemu}", 0, "qemu");
}

/* The native MCU thread stops with the process: on waking, its clock has
 * jumped and its watchdog brakes it; the same story. */
static void frozen_run_with_native_mcu(void **state)
{
    (void)state;
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0) {
        print_message("skipped: the isoshape binary is not built\n");
        skip();
    }
    frozen_with_emulation("{emulated: native}", 0, "native");
}

/* QEMU stopped for 1 s under a running isoshape. */
static void frozen_qemu_under_a_run(void **state)
{
    (void)state;
    if (!have_qemu())
        skip();
    frozen_with_emulation("{emulated: qemu}", 1, "qemu_stopped");
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(frozen_run_rearms_only_with_fresh_ticks),
        cmocka_unit_test(frozen_run_with_qemu),
        cmocka_unit_test(frozen_run_with_native_mcu),
        cmocka_unit_test(frozen_qemu_under_a_run),
    };
    return cmocka_run_group_tests_name("freeze", t, NULL, NULL);
}
