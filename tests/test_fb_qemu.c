/* tests/test_fb_qemu.c -- end to end: the real firmware ELF runs in
 * qemu-system-arm (mps2-an385); its UART0 is a TCP connection to a proxy in
 * this process, which hands the other end to the host link as a pty (so the
 * POSIX tty backend is what talks to the emulator). The proxy can flip bits,
 * drop, insert garbage and delay bytes in either direction.
 *
 * What it shows: HELLO completes; setpoints at 100 Hz with every echoed value
 * right; at a bit-error rate of 1e-3 no corrupted frame gets through and the
 * link recovers by itself; a silent host puts the MCU in its safe state within
 * the watchdog time plus one frame and motion resumes only after HELLO; a hung
 * firmware is reset by the hardware watchdog.
 *
 * Assertions are on counts and values with generous deadlines, never on
 * tight timings: CI runs this on two loaded cores, also under ASan. QEMU is
 * killed on every path (teardown, atexit, fatal signals, and PDEATHSIG should
 * this process die). Skips (77) only where qemu-system-arm is absent. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <pty.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "fb_test_config.h"
#include "iso_clock.h"
#include "iso_fb_host.h"
#include "iso_fb_host_drill.h"
#include "iso_fb_mcu.h"
#include "testutil.h"

#define N_CH 4 /* the firmware's channel count (firmware/main.c) */

/* ---- the proxy ---------------------------------------------------------- */
enum { TO_MCU = 0, TO_HOST = 1 };

typedef struct dir_cfg {
    double ber;     /* probability each bit is flipped */
    double drop;    /* probability each byte is dropped */
    double garbage; /* probability a burst of 1..8 random bytes is inserted before a byte */
    int delay_ms;   /* every byte held this long */
} dir_cfg;

typedef struct dir_stats {
    uint64_t bytes, flipped_bits, dropped, garbage_bytes;
} dir_stats;

#define QCAP (1u << 16)
typedef struct queue {
    uint8_t b[QCAP];
    uint64_t t[QCAP];
    uint32_t head, tail;
} queue;

typedef struct seen {
    int acks, bad_echo, samples, bad_samples, faults, hellos, boot_hellos, diag_acks;
    iso_fb_fault fault;
    iso_fb_hello hello;
    iso_fb_heartbeat hb;
    int heartbeats;
    uint64_t fault_us, boot_hello_us, diag_ack_us;
} seen;

static struct {
    pid_t qemu;
    int listen_fd, qemu_fd, master, slave_keep;
    char slave_name[128];
    pthread_t thread;
    int thread_started;
    atomic_int stop, qemu_gone;
    pthread_mutex_t mu;
    dir_cfg cfg[2];
    dir_stats st[2];
    uint64_t rng[2];
    queue q[2];
    iso_link *link;
    iso_fb_host host;
    int host_up;
    seen z;
    uint32_t tick;
    uint64_t last_send_us;
    int16_t hold[N_CH]; /* ticks in [hold_from, hold_to) stream these, not the pattern */
    uint32_t hold_from, hold_to;
} g = {.qemu = -1, .listen_fd = -1, .qemu_fd = -1, .master = -1, .slave_keep = -1};

static double rnd(int d)
{
    uint64_t x = g.rng[d];
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    g.rng[d] = x;
    return (double)(x >> 11) * (1.0 / 9007199254740992.0);
}

static void enqueue(int d, uint8_t b, uint64_t t)
{
    queue *q = &g.q[d];
    if (q->head - q->tail >= QCAP)
        return; /* cannot happen at these rates; dropping would be visible as a CRC error */
    q->b[q->head % QCAP] = b;
    q->t[q->head % QCAP] = t;
    q->head++;
}

/* Takes bytes read from one side through the fault injection into the
 * other side's queue. */
static void inject(int d, const uint8_t *buf, size_t n)
{
    pthread_mutex_lock(&g.mu);
    dir_cfg c = g.cfg[d];
    dir_stats *s = &g.st[d];
    uint64_t release = iso_clock_us() + (uint64_t)c.delay_ms * 1000u;
    for (size_t i = 0; i < n; i++) {
        s->bytes++;
        if (c.garbage > 0 && rnd(d) < c.garbage) {
            int k = 1 + (int)(rnd(d) * 8);
            for (int j = 0; j < k; j++, s->garbage_bytes++)
                enqueue(d, (uint8_t)(rnd(d) * 256), release);
        }
        if (c.drop > 0 && rnd(d) < c.drop) {
            s->dropped++;
            continue;
        }
        uint8_t b = buf[i];
        if (c.ber > 0)
            for (int bit = 0; bit < 8; bit++)
                if (rnd(d) < c.ber) {
                    b ^= (uint8_t)(1u << bit);
                    s->flipped_bits++;
                }
        enqueue(d, b, release);
    }
    pthread_mutex_unlock(&g.mu);
}

/* Writes what is due from queue d to fd; keeps the rest on EAGAIN. */
static void flush_queue(int d, int fd, uint64_t now, uint64_t *next_due)
{
    queue *q = &g.q[d];
    uint8_t out[4096];
    size_t n = 0;
    uint32_t t = q->tail;
    while (t != q->head && n < sizeof out && q->t[t % QCAP] <= now)
        out[n++] = q->b[t++ % QCAP];
    if (t != q->head && q->t[t % QCAP] > now && q->t[t % QCAP] < *next_due)
        *next_due = q->t[t % QCAP];
    if (n == 0 || fd < 0)
        return;
    ssize_t w = write(fd, out, n);
    if (w > 0)
        q->tail += (uint32_t)w;
    if (w < (ssize_t)n && now + 1000 < *next_due)
        *next_due = now + 1000; /* retry soon */
}

static void *proxy_main(void *arg)
{
    (void)arg;
    uint8_t buf[4096];
    while (!atomic_load(&g.stop)) {
        struct pollfd p[3] = {
            {g.listen_fd, POLLIN, 0}, {g.qemu_fd, POLLIN, 0}, {g.master, POLLIN, 0}};
        uint64_t now = iso_clock_us(), next_due = now + 5000;
        pthread_mutex_lock(&g.mu);
        flush_queue(TO_MCU, g.qemu_fd, now, &next_due);
        flush_queue(TO_HOST, g.master, now, &next_due);
        pthread_mutex_unlock(&g.mu);
        int wait = (int)((next_due - now + 999) / 1000);
        if (poll(p, 3, wait < 1 ? 1 : wait) < 0 && errno != EINTR)
            break;
        if (p[0].revents & POLLIN) {
            int fd = accept(g.listen_fd, NULL, NULL);
            if (fd >= 0) {
                fcntl(fd, F_SETFL, O_NONBLOCK);
                g.qemu_fd = fd;
            }
        }
        if (g.qemu_fd >= 0 && (p[1].revents & (POLLIN | POLLHUP | POLLERR))) {
            ssize_t n = read(g.qemu_fd, buf, sizeof buf);
            if (n > 0)
                inject(TO_HOST, buf, (size_t)n);
            else if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
                close(g.qemu_fd);
                g.qemu_fd = -1;
                atomic_store(&g.qemu_gone, 1);
            }
        }
        if (p[2].revents & POLLIN) {
            ssize_t n = read(g.master, buf, sizeof buf);
            if (n > 0)
                inject(TO_MCU, buf, (size_t)n);
        }
    }
    return NULL;
}

static void set_noise(double ber, double drop, double garbage, int delay_ms)
{
    pthread_mutex_lock(&g.mu);
    for (int d = 0; d < 2; d++) {
        g.cfg[d].ber = ber;
        g.cfg[d].drop = drop;
        g.cfg[d].garbage = garbage;
        g.cfg[d].delay_ms = delay_ms;
    }
    pthread_mutex_unlock(&g.mu);
}

/* ---- QEMU --------------------------------------------------------------- */
static void kill_qemu(void)
{
    if (g.qemu > 0) {
        kill(g.qemu, SIGKILL);
        waitpid(g.qemu, NULL, 0);
        g.qemu = -1;
    }
}

static void on_fatal_signal(int sig)
{
    if (g.qemu > 0)
        kill(g.qemu, SIGKILL); /* async-signal-safe; the kernel reaps it with us */
    signal(sig, SIG_DFL);
    raise(sig);
}

static int find_qemu(char *out, size_t cap)
{
    const char *env = getenv("ISO_FB_QEMU"); /* an override; "" means "no emulator here" */
    if (env) {
        snprintf(out, cap, "%s", env);
        return env[0] && access(env, X_OK) == 0;
    }
    if (ISO_FB_QEMU_PATH[0] && access(ISO_FB_QEMU_PATH, X_OK) == 0) {
        snprintf(out, cap, "%s", ISO_FB_QEMU_PATH);
        return 1;
    }
    const char *path = getenv("PATH");
    char dirs[4096];
    snprintf(dirs, sizeof dirs, "%s", path ? path : "/usr/bin:/bin");
    for (char *save = NULL, *d = strtok_r(dirs, ":", &save); d; d = strtok_r(NULL, ":", &save)) {
        snprintf(out, cap, "%s/qemu-system-arm", d);
        if (access(out, X_OK) == 0)
            return 1;
    }
    return 0;
}

static void start_qemu(const char *qemu, int port)
{
    char serial[64];
    snprintf(serial, sizeof serial, "tcp:127.0.0.1:%d", port);
    pid_t pid = fork();
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        int devnull = open("/dev/null", O_RDWR);
        if (devnull >= 0) {
            dup2(devnull, 0);
            dup2(devnull, 1); /* keep stderr: QEMU's own errors reach the CTest log */
        }
        /* -nic user,restrict=on: the board's lan9118 gets a peer that
         * reaches nothing, so QEMU does not warn (actuators/emu_firmware.c) */
        execl(qemu, qemu, "-M", "mps2-an385", "-nodefaults", "-nic", "user,restrict=on", "-display",
              "none", "-monitor", "none", "-serial", serial, "-kernel", ISO_FB_FIRMWARE_ELF,
              (char *)NULL);
        _exit(127);
    }
    assert_true(pid > 0);
    g.qemu = pid;
}

/* ---- the host side ------------------------------------------------------ */
static int16_t pattern(uint32_t tick, unsigned c)
{
    if (tick >= g.hold_from && tick < g.hold_to)
        return g.hold[c];
    return (int16_t)((int32_t)((tick * (c + 1) * 7u) % 1800u) - 900);
}

static void on_ack(void *ctx, const iso_fb_ack *a)
{
    seen *z = ctx;
    if (a->type == ISO_FB_DIAG) {
        z->diag_acks++;
        z->diag_ack_us = iso_clock_us();
        return;
    }
    z->acks++;
    if (a->n != N_CH)
        z->bad_echo++;
    for (unsigned i = 0; i < a->n && i < N_CH; i++) {
        if (a->value[i] != pattern(a->tick, i))
            z->bad_echo++;
    }
}

static void on_sample(void *ctx, const iso_fb_sample *s)
{
    seen *z = ctx;
    iso_fb_sample want;
    iso_fb_mcu_synth_sample(s->t_us, &want);
    z->samples++;
    z->bad_samples += memcmp(want.v, s->v, sizeof want.v) != 0 || want.buttons != s->buttons ||
                      want.kind != s->kind;
}

static void on_fault(void *ctx, const iso_fb_fault *f)
{
    seen *z = ctx;
    z->faults++;
    z->fault = *f;
    z->fault_us = iso_clock_us();
}

static void on_hello(void *ctx, const iso_fb_hello *h)
{
    seen *z = ctx;
    z->hellos++;
    z->hello = *h;
    if (h->flags & ISO_FB_HELLO_BOOT) {
        z->boot_hellos++;
        z->boot_hello_us = iso_clock_us();
    }
}

static void on_heartbeat(void *ctx, const iso_fb_heartbeat *hb)
{
    seen *z = ctx;
    z->hb = *hb;
    z->heartbeats++;
}

/* Runs the host for ms: a 100 Hz tick that sends setpoints when `send`,
 * polling in between. Stops early when done(…) says so. Returns setpoints
 * sent. */
static int run_host(int ms, int send, int (*done)(void))
{
    uint64_t end = iso_clock_us() + (uint64_t)ms * 1000u, next = iso_clock_us();
    int sent = 0;
    for (;;) {
        uint64_t now = iso_clock_us();
        if (now >= end || (done && done()))
            break;
        assert_false(atomic_load(&g.qemu_gone));
        if (send && now >= next) {
            int16_t v[N_CH];
            for (unsigned c = 0; c < N_CH; c++)
                v[c] = pattern(g.tick, c);
            int r = iso_fb_host_step(&g.host, g.tick, v, N_CH);
            if (r == 1) {
                sent++;
                g.last_send_us = now;
            }
            g.tick++;
            next += 10000;
            if (next < now) /* a stalled host does not burst to catch up */
                next = now + 10000;
            continue;
        }
        uint64_t until = send && next < end ? next : end;
        int wait = (int)((until - now) / 1000u);
        iso_fb_host_poll(&g.host, wait > 20 ? 20 : wait);
    }
    return sent;
}

static int streaming(void)
{
    return g.host.state == ISO_FB_HOST_STREAMING;
}

/* ---- setup / teardown ----------------------------------------------------- */
static int group_setup(void **state)
{
    (void)state;
    char qemu[4096];
    if (!find_qemu(qemu, sizeof qemu)) {
        printf(
            "SKIP: qemu-system-arm not found (ISO_FB_QEMU '%s', configure-time path '%s', not on "
            "PATH); install Debian's qemu-system-arm to run the firmware end to end\n",
            getenv("ISO_FB_QEMU") ? getenv("ISO_FB_QEMU") : "unset", ISO_FB_QEMU_PATH);
        fflush(stdout);
        exit(ISO_TEST_SKIP);
    }
    struct stat st;
    if (!ISO_FB_FIRMWARE_ELF[0] || stat(ISO_FB_FIRMWARE_ELF, &st) != 0) {
        /* QEMU is here, so a missing firmware is a build problem: fail. */
        fprintf(stderr, "firmware ELF '%s' not built (is gcc-arm-none-eabi installed?)\n",
                ISO_FB_FIRMWARE_ELF);
        return -1;
    }
    atexit(kill_qemu);
    signal(SIGABRT, on_fatal_signal);
    signal(SIGSEGV, on_fatal_signal);
    signal(SIGTERM, on_fatal_signal);
    signal(SIGINT, on_fatal_signal);
    signal(SIGPIPE, SIG_IGN);
    pthread_mutex_init(&g.mu, NULL);
    g.rng[0] = 0x9E3779B97F4A7C15u;
    g.rng[1] = 0xD1B54A32D192ED03u;

    g.listen_fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t alen = sizeof a;
    if (g.listen_fd < 0 || bind(g.listen_fd, (struct sockaddr *)&a, sizeof a) != 0 ||
        listen(g.listen_fd, 1) != 0 ||
        getsockname(g.listen_fd, (struct sockaddr *)&a, &alen) != 0) {
        perror("proxy listen");
        return -1;
    }
    struct termios raw;
    memset(&raw, 0, sizeof raw);
    cfmakeraw(&raw);
    if (openpty(&g.master, &g.slave_keep, g.slave_name, &raw, NULL) != 0) {
        perror("openpty");
        return -1;
    }
    fcntl(g.master, F_SETFL, O_NONBLOCK);
    fcntl(g.master, F_SETFD, FD_CLOEXEC);
    fcntl(g.slave_keep, F_SETFD, FD_CLOEXEC);

    start_qemu(qemu, ntohs(a.sin_port));
    if (pthread_create(&g.thread, NULL, proxy_main, NULL) != 0)
        return -1;
    g.thread_started = 1;

    iso_err err;
    iso_err_clear(&err);
    if (iso_link_tty_open(g.slave_name, 115200, &g.link, &err) != ISO_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return -1;
    }
    iso_fb_host_callbacks cb = {on_sample, on_ack, on_fault, on_hello, on_heartbeat, &g.z};
    iso_fb_host_opts opts = {0};
    opts.link_timeout_ms = 3000; /* generous: QEMU boots on a loaded machine */
    if (iso_fb_host_init(&g.host, g.link, &opts, &cb, &err) != ISO_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return -1;
    }
    g.host_up = 1;
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    if (g.host_up) {
        char line[1024];
        iso_fb_host_format_stats(&g.host, line, sizeof line);
        printf("%s\n", line);
        iso_fb_host_deinit(&g.host);
    }
    kill_qemu();
    atomic_store(&g.stop, 1);
    if (g.thread_started)
        pthread_join(g.thread, NULL);
    iso_link_close(g.link);
    for (int *fd = &g.listen_fd; fd <= &g.slave_keep; fd++)
        if (*fd >= 0)
            close(*fd);
    return 0;
}

/* ---- the tests ---------------------------------------------------------- */
static void hello_completes(void **state)
{
    (void)state;
    run_host(20000, 1, streaming);
    assert_int_equal(g.host.state, ISO_FB_HOST_STREAMING);
    assert_int_equal(g.host.device.proto_version, ISO_FB_VERSION);
    assert_int_equal(g.host.device.fw_version, ISO_FB_MCU_FW_VERSION);
    assert_int_equal(g.host.device.n_channels, N_CH);
    assert_int_equal(g.host.device.ch[1].max, 1500);
    assert_int_equal(g.host.device.ch[3].min, 0);
}

static void setpoints_at_100hz_every_value_correct(void **state)
{
    (void)state;
    run_host(5000, 1, streaming);
    seen before = g.z;
    iso_fb_counters rx0 = g.host.stats.rx;
    int sent = run_host(3000, 1, NULL);
    /* collect the acks still in flight, sending on: a silent host trips the watchdog */
    sent += run_host(300, 1, NULL);
    int acks = g.z.acks - before.acks;
    printf(
        "clean 3 s: sent %d setpoints, %d acks, %d samples, %d watchdog faults, rtt avg %.2f ms\n",
        sent, acks, g.z.samples - before.samples, g.z.faults - before.faults,
        g.host.stats.rtt_count ? (double)g.host.stats.rtt_sum_us / g.host.stats.rtt_count / 1000.0
                               : 0.0);
    assert_true(sent >= 150); /* 300 at an unloaded 100 Hz */
    assert_true(acks >= sent * 8 / 10);
    assert_int_equal(g.z.bad_echo, 0);
    assert_true(g.z.samples - before.samples >= 30);
    assert_int_equal(g.z.bad_samples, 0);
    assert_int_equal(g.host.stats.bad_payloads, 0);
    assert_int_equal(g.host.stats.rx.resyncs, rx0.resyncs); /* a clean line drops nothing */
}

static void bit_errors_never_accepted_and_link_recovers(void **state)
{
    (void)state;
    run_host(5000, 1, streaming);
    seen before = g.z;
    iso_fb_host_stats s0 = g.host.stats;
    dir_stats st0[2];
    pthread_mutex_lock(&g.mu);
    memcpy(st0, g.st, sizeof st0);
    pthread_mutex_unlock(&g.mu);

    set_noise(1e-3, 5e-4, 2e-3, 2);
    int sent = run_host(4000, 1, NULL);
    set_noise(0, 0, 0, 0);
    int noisy_acks = g.z.acks - before.acks;
    dir_stats st[2];
    pthread_mutex_lock(&g.mu);
    memcpy(st, g.st, sizeof st);
    pthread_mutex_unlock(&g.mu);

    /* recovery, by itself */
    run_host(5000, 1, streaming);
    seen mid = g.z;
    int clean_sent = run_host(1500, 1, NULL);
    run_host(300, 1, NULL);
    const iso_fb_counters *rx = &g.host.stats.rx;
    printf("BER 1e-3 for 4 s: %d setpoints sent, %d acked; bits flipped to MCU %llu, to host %llu; "
           "bytes dropped %llu, garbage %llu; host dropped %u frames (crc %u, cobs %u, short %u, "
           "order %u), %u lost in gaps; faults %d, handshakes %u; after: %d sent, %d acked\n",
           sent, noisy_acks, (unsigned long long)(st[0].flipped_bits - st0[0].flipped_bits),
           (unsigned long long)(st[1].flipped_bits - st0[1].flipped_bits),
           (unsigned long long)(st[0].dropped + st[1].dropped - st0[0].dropped - st0[1].dropped),
           (unsigned long long)(st[0].garbage_bytes + st[1].garbage_bytes - st0[0].garbage_bytes -
                                st0[1].garbage_bytes),
           rx->resyncs - s0.rx.resyncs, rx->bad_crc - s0.rx.bad_crc, rx->bad_cobs - s0.rx.bad_cobs,
           rx->too_short - s0.rx.too_short, rx->out_of_order - s0.rx.out_of_order,
           rx->seq_gaps - s0.rx.seq_gaps, g.z.faults - before.faults,
           g.host.stats.handshakes - s0.handshakes, clean_sent, g.z.acks - mid.acks);
    /* the noise was real, in both directions, and the receiver saw it */
    assert_true(st[0].flipped_bits - st0[0].flipped_bits > 10);
    assert_true(st[1].flipped_bits - st0[1].flipped_bits > 10);
    assert_true(rx->resyncs - s0.rx.resyncs > 5);
    /* nothing corrupted got through, either way: every ACK echoes exactly
     * what the host sent for that tick, every sample is the sensor's value */
    assert_int_equal(g.z.bad_echo, before.bad_echo);
    assert_int_equal(g.z.bad_samples, before.bad_samples);
    assert_int_equal(g.host.stats.bad_payloads, s0.bad_payloads);
    assert_true(noisy_acks > sent / 4);
    /* and it recovered without help */
    assert_int_equal(g.host.state, ISO_FB_HOST_STREAMING);
    assert_true(clean_sent >= 50);
    assert_true(g.z.acks - mid.acks >= clean_sent * 8 / 10);
}

static int got_fault(void)
{
    return g.z.faults > 0;
}
static int got_safe_heartbeat(void)
{
    return g.z.hb.state == ISO_FB_STATE_SAFE;
}
static int got_armed_heartbeat_moved(void)
{
    return g.z.hb.state == ISO_FB_STATE_ARMED && g.z.hb.pos[0] == g.hold[0] &&
           g.z.hb.pos[1] == g.hold[1];
}

static void watchdog_safe_state_then_resume_after_hello(void **state)
{
    (void)state;
    int bad_echo0 = g.z.bad_echo;
    run_host(5000, 1, streaming);
    /* drive every channel away from its safe position and let it arrive */
    g.hold_from = g.tick;
    g.hold_to = UINT32_MAX;
    g.hold[0] = 400;
    g.hold[1] = -300;
    g.hold[2] = 200;
    g.hold[3] = 800;
    run_host(1500, 1, NULL);
    run_host(5000, 1, got_armed_heartbeat_moved);
    assert_true(got_armed_heartbeat_moved());

    /* the host goes silent (still listening) */
    g.z.faults = 0;
    g.z.hb.state = ISO_FB_STATE_ARMED;
    uint64_t silent_from = g.last_send_us;
    run_host(5000, 0, got_fault);
    assert_int_equal(g.z.faults, 1);
    assert_int_equal(g.z.fault.reason, ISO_FB_FAULT_WATCHDOG);
    /* MCU clock: last valid SETPOINTS to safe state, at most 100 ms + one
     * 10 ms frame */
    assert_true(g.z.fault.detail > 100 && g.z.fault.detail <= 110);
    run_host(3000, 0, got_safe_heartbeat);
    assert_int_equal(g.z.hb.state, ISO_FB_STATE_SAFE);
    for (unsigned c = 0; c < N_CH; c++)
        assert_int_equal(g.z.hb.pos[c], 0); /* every channel's safe position */
    printf(
        "link watchdog: safe state %u ms (MCU clock) after the last setpoints; FAULT reached the "
        "host %.1f ms (host clock) after its last send\n",
        (unsigned)g.z.fault.detail, (double)(g.z.fault_us - silent_from) / 1000.0);
    assert_true(g.z.fault_us - silent_from < 3000000u); /* generous: loaded CI */

    /* the host comes back: HELLO first, then motion */
    uint32_t hs = g.host.stats.handshakes;
    assert_int_equal(g.host.state, ISO_FB_HOST_HANDSHAKE);
    run_host(5000, 1, streaming);
    assert_int_equal(g.host.stats.handshakes, hs + 1);
    run_host(5000, 1, got_armed_heartbeat_moved);
    assert_true(got_armed_heartbeat_moved());
    g.hold_to = g.tick;
    run_host(200, 1, NULL);
    assert_int_equal(g.z.bad_echo, bad_echo0);
}

static int got_boot_hello(void)
{
    return g.z.boot_hellos > 0;
}
static int got_diag_ack(void)
{
    return g.z.diag_acks > 0;
}

static void hardware_watchdog_resets_hung_firmware(void **state)
{
    (void)state;
    run_host(5000, 1, streaming);
    g.z.faults = 0;
    run_host(5000, 0, got_fault); /* unarmed first: the MCU refuses to hang while armed */
    assert_int_equal(g.z.faults, 1);
    g.z.boot_hellos = 0;
    g.z.diag_acks = 0;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_fb_host_send_diag_hang(&g.host, &err), ISO_OK);
    run_host(3000, 0, got_diag_ack);
    assert_int_equal(g.z.diag_acks, 1);
    run_host(10000, 0, got_boot_hello);
    assert_int_equal(g.z.boot_hellos, 1);
    assert_true(g.z.hello.uptime_ms < 1000); /* a fresh boot, not a replay */
    printf("hardware watchdog: hung firmware announced itself rebooted %.1f ms (host clock) after "
           "acknowledging the hang (100 ms to the NMI + 100 ms to the reset)\n",
           (double)(g.z.boot_hello_us - g.z.diag_ack_us) / 1000.0);
    /* and the link comes back up on the rebooted firmware */
    seen before = g.z;
    run_host(5000, 1, streaming);
    assert_int_equal(g.host.state, ISO_FB_HOST_STREAMING);
    run_host(1200, 1, NULL);
    assert_true(g.z.acks - before.acks >= 30);
    assert_int_equal(g.z.bad_echo, before.bad_echo);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(hello_completes),
        cmocka_unit_test(setpoints_at_100hz_every_value_correct),
        cmocka_unit_test(bit_errors_never_accepted_and_link_recovers),
        cmocka_unit_test(watchdog_safe_state_then_resume_after_hello),
        cmocka_unit_test(hardware_watchdog_resets_hung_firmware),
    };
    return cmocka_run_group_tests_name("fb_qemu", t, group_setup, group_teardown);
}
