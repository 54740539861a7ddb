/* actuators/emu_firmware.c -- an actuator MCU without hardware, behind an
 * iso_link: the real firmware ELF in qemu-system-arm, or the same protocol
 * logic (iso_fb_mcu.c) in a thread. See iso_actuators.h. */
#define _GNU_SOURCE /* prctl */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "act_internal.h"
#include "iso_actuators.h"
#include "iso_clock.h"
#include "iso_fd.h"

const char *const iso_act_emu_names[] = {"auto", "qemu", "native", NULL};

#define QEMU_CONNECT_MS 5000 /* QEMU connects its UART at start-up; loaded CI is slow */

/* Threads: the link's owner (the sink's sender) reads, writes and reopens;
 * iso_act__emu_signal may come from any thread, so what it touches (the
 * QEMU pid, the native thread's flags) is atomic. */
typedef struct emu_link {
    iso_link base;
    int mode; /* ISO_ACT_EMU_QEMU or ISO_ACT_EMU_NATIVE */
    char what[64];
    atomic_uint restarts; /* relaunches after the emulation died */
    /* QEMU: its UART0 is a TCP connection it made to us */
    atomic_int qemu; /* pid, -1 when none */
    int sock;
    int sock_dead; /* the stream ended (QEMU died): reopen relaunches */
    int lfd;       /* listening for a relaunched QEMU's UART, else -1 */
    uint64_t launched_us;
    char qemu_path[PATH_MAX], elf[PATH_MAX];
    /* native: the MCU logic on one end of a socket pair (`master`), the host
     * on the other (`sock`, as QEMU's UART is) */
    int master;
    pthread_t thread;
    int thread_started;
    atomic_int stop;
    atomic_int killed;      /* SIGKILL drill: the thread ends and closes the master */
    atomic_int paused;      /* SIGSTOP drill */
    atomic_uint tx_dropped; /* bytes the host did not take in time */
    atomic_int priority;    /* SCHED_FIFO asked for (iso_act__emu_priority); 0: none */
    atomic_int prio_done;   /* native: the priority its thread applied last, and how: */
    atomic_int prio_errno;  /* 0, or pthread_setschedparam's error */
    iso_fb_mcu mcu;         /* touched only by the thread once it runs */
    int64_t t0_ns;          /* iso_clock_ns() at the MCU's start: its uptime counts from here */
} emu_link;

/* ------------------------------------------------------------------------ */
/* Socket I/O for the QEMU stream                                            */
/* ------------------------------------------------------------------------ */

static int sock_read(emu_link *e, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    if (e->sock < 0 || e->sock_dead)
        return iso_err_set(err, ISO_EIO, -1, "%s: no UART stream (QEMU restarting)", e->what);
    struct pollfd p = {e->sock, POLLIN, 0};
    int r = poll(&p, 1, timeout_ms < 0 ? 0 : timeout_ms);
    if (r < 0 && errno != EINTR)
        return iso_err_set(err, ISO_EIO, -1, "%s: poll: %s", e->what, strerror(errno));
    if (r <= 0)
        return 0;
    ssize_t n = read(e->sock, buf, cap);
    if (n > 0)
        return (int)n;
    if (n < 0 && (errno == EAGAIN || errno == EINTR))
        return 0;
    e->sock_dead = 1;
    return iso_err_set(err, ISO_EIO, -1, "%s: %s closed its UART (%s)", e->what,
                       e->mode == ISO_ACT_EMU_QEMU ? "QEMU" : "the MCU thread",
                       n == 0 ? "end of stream" : strerror(errno));
}

/* Sends what the socket takes now of buf[*done, n), advancing *done: 1 when
 * all of it is sent, 0 when the socket is full (poll for POLLOUT and call
 * again), -1 on an error (errno says which). */
static int send_now(int fd, const uint8_t *buf, size_t n, size_t *done)
{
    while (*done < n) {
        ssize_t w = send(fd, buf + *done, n - *done, MSG_NOSIGNAL);
        if (w > 0)
            *done += (size_t)w;
        else if (w < 0 && errno != EAGAIN && errno != EINTR)
            return -1;
        else
            return 0;
    }
    return 1;
}

static int sock_write(emu_link *e, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    if (e->sock < 0 || e->sock_dead)
        return iso_err_set(err, ISO_EIO, -1, "%s: no UART stream (QEMU restarting)", e->what);
    uint64_t deadline = iso_clock_us() + (uint64_t)(timeout_ms < 0 ? 0 : timeout_ms) * 1000u;
    size_t done = 0;
    for (int r; (r = send_now(e->sock, buf, n, &done)) != 1;) {
        if (r < 0) {
            e->sock_dead = 1;
            return iso_err_set(err, ISO_EIO, -1, "%s: write: %s", e->what, strerror(errno));
        }
        int left = iso_clock_ms_until(deadline);
        struct pollfd p = {e->sock, POLLOUT, 0};
        if (left == 0 || poll(&p, 1, left) == 0)
            return iso_err_set(err, ISO_EIO, -1, "%s: write timed out after %d ms", e->what,
                               timeout_ms);
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* The link                                                                   */
/* ------------------------------------------------------------------------ */

/* Both emulations are a stream socket to the host: QEMU's UART on loopback
 * TCP, the native MCU on a socket pair. Never a tty: a tty read that finds
 * the line empty waits for the kernel's buffer work, at normal priority,
 * which any busy process can hold up (measured: 100-160 ms, and the MCU's
 * watchdog braked it while the sender waited in a read). */
static int emu_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    return sock_read((emu_link *)l, buf, cap, timeout_ms, err);
}

static int emu_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    return sock_write((emu_link *)l, buf, n, timeout_ms, err);
}

static int emu_poll_fd(iso_link *l)
{
    return ((emu_link *)l)->sock;
}

static int qemu_reopen(emu_link *e, iso_err *err);
static int native_reopen(emu_link *e, iso_err *err);

/* While the emulation lives the stream never breaks, so a "loss" (no frame
 * for link_timeout_ms: QEMU descheduled) is answered by handshaking again on
 * the same stream. An emulation that is stopped (QEMU under SIGSTOP, the
 * native thread's drill) cannot answer: taking the link up again then would
 * be said as a reopen while the MCU is still frozen, so the reopen fails,
 * its reason saying why, until the emulation runs again. When it died,
 * reopen restarts it. */
static int emu_reopen(iso_link *l, iso_err *err)
{
    emu_link *e = (emu_link *)l;
    if (atomic_load(&e->stop))
        return iso_err_set(err, ISO_EIO, -1, "%s: stopped", e->what);
    return e->mode == ISO_ACT_EMU_QEMU ? qemu_reopen(e, err) : native_reopen(e, err);
}

/* Kills and reaps QEMU if there is one, and closes its stream. */
static void qemu_reap(emu_link *e)
{
    int pid = atomic_exchange(&e->qemu, -1);
    if (pid > 0) {
        kill(pid, SIGKILL);
        kill(pid, SIGCONT); /* a stopped QEMU dies only once it runs */
        while (waitpid(pid, NULL, 0) < 0 && errno == EINTR) {
        }
    }
    if (e->sock >= 0)
        close(e->sock);
    e->sock = -1;
    e->sock_dead = 0;
    if (e->lfd >= 0)
        close(e->lfd);
    e->lfd = -1;
}

static void native_end(emu_link *e);

static void emu_close(iso_link *l)
{
    emu_link *e = (emu_link *)l;
    qemu_reap(e);
    atomic_store(&e->stop, 1);
    native_end(e);
    free(e);
}

static const iso_link_ops emu_ops = {"emulated",  emu_read,   emu_write,
                                     emu_poll_fd, emu_reopen, emu_close};

static emu_link *emu_new(int mode)
{
    emu_link *e = calloc(1, sizeof *e);
    if (!e)
        return NULL;
    e->base.ops = &emu_ops;
    e->mode = mode;
    atomic_init(&e->qemu, -1);
    atomic_init(&e->priority, 0);
    atomic_init(&e->prio_done, -1);
    atomic_init(&e->prio_errno, 0);
    e->sock = e->lfd = e->master = -1;
    snprintf(e->what, sizeof e->what, "emulated MCU (%s)",
             mode == ISO_ACT_EMU_QEMU ? "QEMU" : "native");
    return e;
}

/* ------------------------------------------------------------------------ */
/* Native: iso_fb_mcu in a thread                                             */
/* ------------------------------------------------------------------------ */

static uint32_t mcu_ms(const emu_link *e)
{
    return (uint32_t)((iso_clock_ns() - e->t0_ns) / 1000000);
}

/* The firmware queues replies in its UART ring and waits for room; here the
 * socket's buffer is the ring. A host that stops reading until it is full
 * loses bytes after 10 ms (counted), as it would on a UART; the thread
 * itself never stalls for long, so the watchdog keeps its 1 ms resolution. */
static void mcu_write(void *ctx, const uint8_t *bytes, size_t n)
{
    emu_link *e = ctx;
    size_t done = 0;
    for (int waits = 0; send_now(e->master, bytes, n, &done) == 0; waits++) {
        struct pollfd p = {e->master, POLLOUT, 0};
        if (waits >= 10 || poll(&p, 1, 1) < 0)
            break;
    }
    if (done < n)
        atomic_fetch_add(&e->tx_dropped, (unsigned)(n - done));
}

/* Hardware runs on its own; a thread shares the cores. On a loaded machine
 * it can be descheduled for 100+ ms (measured: 151 ms with 5 runnable
 * threads on 2 cores), which trips the link watchdog as a stalled host
 * would. Real-time priority, where the process may take it, keeps the
 * emulated clock honest; without it the emulation still works, with the
 * occasional watchdog FAULT under load that the host recovers from. */
static int try_realtime(int priority)
{
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = priority > 0 ? priority : sched_get_priority_min(SCHED_FIFO);
    return pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
}

/* The thread applies the priority asked for itself (iso_act__emu_priority
 * never touches another thread's handle, which a restart replaces). */
static void follow_priority(emu_link *e)
{
    int want = atomic_load(&e->priority);
    if (want == atomic_load(&e->prio_done))
        return;
    atomic_store(&e->prio_errno, try_realtime(want));
    atomic_store(&e->prio_done, want);
}

static void *mcu_thread(void *arg)
{
    emu_link *e = arg;
    atomic_store(&e->prio_done, -1);
    follow_priority(e);
    uint32_t last = mcu_ms(e);
    uint8_t buf[256];
    while (!atomic_load(&e->stop) && !atomic_load(&e->killed)) {
        follow_priority(e);
        if (atomic_load(&e->paused)) { /* a stopped process: no clock, no I/O */
            iso_clock_sleep_until(iso_clock_ns() + 1000000);
            continue;
        }
        struct pollfd p = {e->master, POLLIN, 0};
        int r = poll(&p, 1, 1);
        if (r > 0 && (p.revents & POLLIN)) {
            ssize_t n = read(e->master, buf, sizeof buf);
            if (n > 0)
                iso_fb_mcu_rx(&e->mcu, buf, (size_t)n);
        } else if (r > 0 && (p.revents & (POLLHUP | POLLERR))) {
            /* no slave open for a moment (a reopen): do not spin */
            iso_clock_sleep_until(iso_clock_ns() + 1000000);
        }
        uint32_t now = mcu_ms(e);
        if (now != last) {
            last = now;
            iso_fb_mcu_tick(&e->mcu, now);
        }
    }
    if (atomic_load(&e->killed)) { /* as a dying process closes its UART */
        close(e->master);
        e->master = -1;
    }
    return NULL;
}

/* Joins the MCU thread and closes both ends of its socket pair. */
static void native_end(emu_link *e)
{
    if (e->thread_started) {
        atomic_store(&e->stop, 1);
        pthread_join(e->thread, NULL);
        e->thread_started = 0;
    }
    if (e->sock >= 0)
        close(e->sock);
    if (e->master >= 0)
        close(e->master);
    e->sock = e->master = -1;
    e->sock_dead = 0;
}

static int native_open(emu_link *e, iso_err *err)
{
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0, sv) != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: socketpair: %s", e->what, strerror(errno));
    e->master = sv[0];
    e->sock = sv[1];
    e->sock_dead = 0;
    iso_fb_mcu_config cfg; /* the firmware's own (test_actuators compares the HELLOs) */
    iso_fb_mcu_config_board(&cfg);
    e->t0_ns = iso_clock_ns();
    if (iso_fb_mcu_init(&e->mcu, &cfg, mcu_write, e, mcu_ms(e)) != 0)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: the firmware configuration is invalid",
                           e->what);
    int pe = pthread_create(&e->thread, NULL, mcu_thread, e);
    if (pe != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot start its thread: %s", e->what,
                           strerror(pe));
    e->thread_started = 1;
    return ISO_OK;
}

/* A killed MCU thread is restarted as a rebooted MCU: fresh socket pair, fresh
 * state (IDLE at the safe positions, HELLO(BOOT)). */
static int native_reopen(emu_link *e, iso_err *err)
{
    if (!atomic_load(&e->killed) && atomic_load(&e->paused))
        return iso_err_set(err, ISO_EIO, -1,
                           "%s: the MCU thread is stopped (SIGSTOP drill): the MCU is frozen, and "
                           "the link is taken up again once it runs",
                           e->what);
    if (!atomic_load(&e->killed))
        return ISO_OK;
    native_end(e);
    atomic_store(&e->stop, 0);
    atomic_store(&e->killed, 0);
    atomic_store(&e->paused, 0);
    int rc = native_open(e, err);
    if (rc == ISO_OK)
        atomic_fetch_add(&e->restarts, 1);
    else
        atomic_store(&e->killed, 1); /* try again at the next reopen */
    return rc;
}

/* ------------------------------------------------------------------------ */
/* QEMU                                                                       */
/* ------------------------------------------------------------------------ */

/* Listens on a loopback port and starts QEMU with its UART0 connecting
 * there; qemu_accept() takes the connection. */
static int qemu_launch(emu_link *e, iso_err *err)
{
    const char *qemu = e->qemu_path, *elf = e->elf;
    int lfd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t alen = sizeof a;
    if (lfd < 0 || bind(lfd, (struct sockaddr *)&a, sizeof a) != 0 || listen(lfd, 1) != 0 ||
        getsockname(lfd, (struct sockaddr *)&a, &alen) != 0) {
        int rc = iso_err_set(err, ISO_EIO, -1, "%s: loopback listen: %s", e->what, strerror(errno));
        if (lfd >= 0)
            close(lfd);
        return rc;
    }
    char serial[64];
    snprintf(serial, sizeof serial, "tcp:127.0.0.1:%d,nodelay=on", ntohs(a.sin_port));
    /* Everything the child needs is built before fork: after it, only
     * async-signal-safe calls (this process may have threads). The board's
     * on-chip Ethernet (lan9118) is created whatever -nodefaults or -nic
     * none say, and QEMU 7.2 warns that it "has no peer": a user-mode
     * network with restrict=on gives it one that reaches neither the host
     * nor the outside (the firmware never drives it). */
    char *const argv[] = {(char *)qemu,       "-M",       "mps2-an385", "-nodefaults", "-nic",
                          "user,restrict=on", "-display", "none",       "-monitor",    "none",
                          "-serial",          serial,     "-kernel",    (char *)elf,   NULL};
    pid_t parent = getpid();
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = atomic_load(&e->priority);
    pid_t pid = fork();
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL); /* never outlive us, even on a crash */
        if (getppid() != parent)
            _exit(127);
        if (sp.sched_priority > 0) /* every thread QEMU starts inherits it */
            (void)sched_setscheduler(0, SCHED_FIFO, &sp);
        int devnull = open("/dev/null", O_RDWR);
        if (devnull >= 0) {
            dup2(devnull, 0);
            dup2(devnull, 1); /* stderr stays: QEMU's own errors reach the user */
        }
        execv(qemu, argv);
        _exit(127);
    }
    if (pid < 0) {
        close(lfd);
        return iso_err_set(err, ISO_EIO, -1, "%s: fork: %s", e->what, strerror(errno));
    }
    atomic_store(&e->qemu, pid);
    e->lfd = lfd;
    e->launched_us = iso_clock_us();
    return ISO_OK;
}

/* Waits up to wait_ms for the launched QEMU's UART. Returns ISO_OK when it
 * connected, 1 while it may still, or ISO_EIO when QEMU exited or took
 * longer than QEMU_CONNECT_MS (it is then reaped: the next launch starts
 * clean). */
static int qemu_accept(emu_link *e, int wait_ms, iso_err *err)
{
    int pid = atomic_load(&e->qemu), status = 0;
    if (pid <= 0 || waitpid(pid, &status, WNOHANG) == pid) {
        if (pid > 0)
            atomic_store(&e->qemu, -1);
        qemu_reap(e);
        if (pid <= 0)
            return iso_err_set(err, ISO_EIO, -1, "%s: QEMU is gone", e->what);
        return iso_err_set(err, ISO_EIO, -1, "%s: %s exited (%s %d) before connecting its UART",
                           e->what, e->qemu_path, WIFEXITED(status) ? "status" : "signal",
                           WIFEXITED(status) ? WEXITSTATUS(status) : WTERMSIG(status));
    }
    struct pollfd p = {e->lfd, POLLIN, 0};
    if (poll(&p, 1, wait_ms) > 0) {
        e->sock = accept4(e->lfd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (e->sock >= 0) {
            close(e->lfd);
            e->lfd = -1;
            e->sock_dead = 0;
            int one = 1;
            setsockopt(e->sock, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
            return ISO_OK;
        }
    }
    if (iso_clock_us() - e->launched_us > QEMU_CONNECT_MS * 1000u) {
        qemu_reap(e);
        return iso_err_set(err, ISO_EIO, -1, "%s: %s did not connect its UART within %d ms",
                           e->what, e->qemu_path, QEMU_CONNECT_MS);
    }
    return 1;
}

static int qemu_open(emu_link *e, const char *qemu, const char *elf, iso_err *err)
{
    snprintf(e->qemu_path, sizeof e->qemu_path, "%s", qemu);
    snprintf(e->elf, sizeof e->elf, "%s", elf);
    int rc = qemu_launch(e, err);
    if (rc != ISO_OK)
        return rc;
    /* qemu_accept ends with ISO_OK, or an error once QEMU exits or
     * QEMU_CONNECT_MS pass; 1 means poll again. (Tested as `rc == ISO_OK &&
     * (rc = ...) == 1`, the loop ended after one 50 ms poll with rc = 1.) */
    while ((rc = qemu_accept(e, 50, err)) == 1) {
    }
    return rc;
}

/* Whether process pid is stopped (SIGSTOP, or held by a debugger): the
 * state in /proc/PID/stat, after the command's closing parenthesis, is T or
 * t. Read without stdio, as the sender asks every reopen_ms while the link
 * is down. */
static int process_stopped(int pid)
{
    char path[64], buf[512];
    snprintf(path, sizeof path, "/proc/%d/stat", pid);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return 0;
    ssize_t n = read(fd, buf, sizeof buf - 1);
    close(fd);
    if (n <= 0)
        return 0;
    buf[n] = 0;
    const char *p = strrchr(buf, ')');
    return p && p[1] == ' ' && (p[2] == 'T' || p[2] == 't');
}

/* A QEMU that died (its stream ended, or it exited) is relaunched without
 * waiting: this reopen starts it, the next ones (every reopen_ms) take its
 * UART once it connects. A QEMU that lives keeps its stream; a stopped one
 * is not reopened until it runs (emu_reopen says why). */
static int qemu_reopen(emu_link *e, iso_err *err)
{
    int pid = atomic_load(&e->qemu);
    int alive = pid > 0 && waitpid(pid, NULL, WNOHANG) == 0;
    if (pid > 0 && !alive)
        atomic_store(&e->qemu, -1); /* reaped: never signal that pid again */
    if (e->lfd < 0 && e->sock >= 0 && !e->sock_dead && alive) {
        if (process_stopped(pid))
            return iso_err_set(err, ISO_EIO, -1,
                               "%s: pid %d is stopped (SIGSTOP): the MCU is frozen, and the link "
                               "is taken up again once it runs",
                               e->what, pid);
        return ISO_OK;
    }
    if (e->lfd < 0) {
        qemu_reap(e);
        int rc = qemu_launch(e, err);
        if (rc != ISO_OK)
            return rc;
        atomic_fetch_add(&e->restarts, 1);
    }
    int rc = qemu_accept(e, 0, err);
    if (rc == 1)
        return iso_err_set(err, ISO_EIO, -1, "%s: relaunched (pid %d), waiting for its UART",
                           e->what, atomic_load(&e->qemu));
    return rc;
}

/* ------------------------------------------------------------------------ */
/* For the sink                                                               */
/* ------------------------------------------------------------------------ */

int iso_act__emu_is(const iso_link *l)
{
    return l && l->ops == &emu_ops;
}

unsigned iso_act__emu_restarts(const iso_link *l)
{
    return iso_act__emu_is(l) ? atomic_load(&((emu_link *)l)->restarts) : 0;
}

int iso_act__emu_signal(iso_link *l, int sig, iso_err *err)
{
    if (!iso_act__emu_is(l))
        return iso_err_set(err, ISO_EINVAL, -1, "emulated MCU: the link is not an emulation");
    emu_link *e = (emu_link *)l;
    if (e->mode == ISO_ACT_EMU_QEMU) {
        int pid = atomic_load(&e->qemu);
        if (pid <= 0 || kill(pid, sig) != 0)
            return iso_err_set(err, ISO_EIO, -1, "%s: cannot signal QEMU (pid %d): %s", e->what,
                               pid, pid <= 0 ? "not running" : strerror(errno));
        return ISO_OK;
    }
    switch (sig) {
    case SIGKILL: atomic_store(&e->killed, 1); return ISO_OK;
    case SIGSTOP: atomic_store(&e->paused, 1); return ISO_OK;
    case SIGCONT: atomic_store(&e->paused, 0); return ISO_OK;
    }
    return iso_err_set(err, ISO_EINVAL, -1,
                       "%s: signal %d is not emulated (SIGKILL, SIGSTOP, SIGCONT are)", e->what,
                       sig);
}

/* Every thread of process pid under the policy: QEMU's vCPU and I/O
 * threads both stand between the host and the firmware. */
static int set_process_sched(int pid, int priority, const char *what, iso_err *err)
{
    char dir[64];
    snprintf(dir, sizeof dir, "/proc/%d/task", pid);
    DIR *d = opendir(dir);
    if (!d)
        return iso_err_set(err, ISO_EIO, -1, "%s: %s: %s", what, dir, strerror(errno));
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = priority;
    int rc = ISO_OK;
    for (struct dirent *t; (t = readdir(d)) != NULL;) {
        int tid = atoi(t->d_name);
        if (tid > 0 && sched_setscheduler(tid, priority ? SCHED_FIFO : SCHED_OTHER, &sp) != 0 &&
            errno != ESRCH && rc == ISO_OK)
            rc = iso_err_set(err, ISO_EIO, -1, "%s: thread %d at SCHED_FIFO %d: %s", what, tid,
                             priority, strerror(errno));
    }
    closedir(d);
    return rc;
}

int iso_act__emu_priority(iso_link *l, int priority, iso_err *err)
{
    if (!iso_act__emu_is(l))
        return iso_err_set(err, ISO_EINVAL, -1, "emulated MCU: the link is not an emulation");
    emu_link *e = (emu_link *)l;
    atomic_store(&e->priority, priority);
    if (e->mode == ISO_ACT_EMU_QEMU) {
        int pid = atomic_load(&e->qemu);
        return pid > 0 ? set_process_sched(pid, priority, e->what, err) : ISO_OK;
    }
    /* the native thread takes it within its 1 ms loop; a killed one, at
     * its restart */
    for (int i = 0; i < 100 && atomic_load(&e->prio_done) != priority; i++) {
        if (atomic_load(&e->killed))
            return ISO_OK;
        iso_clock_sleep_until(iso_clock_ns() + 1000000);
    }
    int rc = atomic_load(&e->prio_done) == priority ? atomic_load(&e->prio_errno) : ETIMEDOUT;
    if (rc != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: its thread at SCHED_FIFO %d: %s", e->what,
                           priority, strerror(rc));
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Choosing                                                                   */
/* ------------------------------------------------------------------------ */

int iso_actuators_emu_open(int mode, iso_link **out, iso_act_emu_info *info, iso_err *err)
{
    iso_act_emu_info local;
    if (!info)
        info = &local;
    memset(info, 0, sizeof *info);
    if (out)
        *out = NULL;
    if (!out || mode < ISO_ACT_EMU_AUTO || mode > ISO_ACT_EMU_NATIVE)
        return iso_err_set(err, ISO_EINVAL, -1, "emulated MCU: NULL out or unknown mode %d", mode);

    char qemu[PATH_MAX], elf[PATH_MAX], why[PATH_MAX + 128] = "";
    int have = 0;
    if (mode != ISO_ACT_EMU_NATIVE)
        have = iso_act__find_qemu(qemu, sizeof qemu, why, sizeof why) &&
               iso_act__find_firmware(elf, sizeof elf, why, sizeof why);
    if (mode == ISO_ACT_EMU_QEMU && !have)
        return iso_err_set(err, ISO_ENOTSUP, -1, "emulated MCU: QEMU asked for, but %s", why);
    if (have) {
        emu_link *e = emu_new(ISO_ACT_EMU_QEMU);
        if (!e)
            return iso_err_set(err, ISO_ENOMEM, -1, "emulated MCU: out of memory");
        iso_err qerr;
        iso_err_clear(&qerr);
        int qrc = qemu_open(e, qemu, elf, &qerr);
        if (qrc == ISO_OK) {
            info->used = ISO_ACT_EMU_QEMU;
            snprintf(info->line, sizeof info->line,
                     "actuators: emulated MCU: the firmware ELF %.300s in %.300s -M mps2-an385 "
                     "(UART0 on loopback TCP) because %s",
                     elf, qemu,
                     mode == ISO_ACT_EMU_QEMU ? "qemu was asked for"
                                              : "both were found (auto prefers the real firmware)");
            *out = &e->base;
            return ISO_OK;
        }
        /* Never a failure without a reason. Every path of qemu_open names
         * its error now (b2ebb62 fixed the one that did not: a slow QEMU
         * ended its accept loop with status 1); should another appear, the
         * message carries the state it left. */
        if (qerr.code == ISO_OK)
            iso_err_set(&qerr, ISO_EIO, -1,
                        "%s: QEMU did not start, and said nothing why (status %d, pid %d, "
                        "listening %d, socket %d, %.0f ms after launch)",
                        e->what, qrc, atomic_load(&e->qemu), e->lfd >= 0, e->sock >= 0,
                        (double)(iso_clock_us() - e->launched_us) / 1e3);
        emu_close(&e->base);
        if (mode == ISO_ACT_EMU_QEMU)
            return iso_err_set(err, qerr.code, -1, "%s", qerr.msg);
        snprintf(why, sizeof why, "QEMU did not start: %s", qerr.msg);
    }
    emu_link *e = emu_new(ISO_ACT_EMU_NATIVE);
    if (!e)
        return iso_err_set(err, ISO_ENOMEM, -1, "emulated MCU: out of memory");
    int rc = native_open(e, err);
    if (rc != ISO_OK) {
        emu_close(&e->base);
        return rc;
    }
    info->used = ISO_ACT_EMU_NATIVE;
    snprintf(info->line, sizeof info->line,
             "actuators: emulated MCU: native (iso_fb_mcu.c in a thread on a socket pair, the "
             "firmware's "
             "4-channel configuration) because %.500s",
             mode == ISO_ACT_EMU_NATIVE ? "native was asked for" : why);
    *out = &e->base;
    return ISO_OK;
}
