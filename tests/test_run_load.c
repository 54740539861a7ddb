/* tests/test_run_load.c -- the README's demo scene under background load:
 * no thread the tick waits for runs below it (controller/iso_loop.h,
 * "Priorities"), so busy processes on every core neither trip the loop
 * watchdog nor take the tick's CPU.
 *
 * `isoshape run config/scenes/replay_cactus.yaml --no-display --speed 0.25
 * --duration 5` (the command the load was first measured with) runs twice:
 * alone, then beside nproc + 1 busy processes this test starts and stops
 * (each ends by itself after 90 s at the latest). Both runs' figures are
 * printed side by side: slowest and p99 tick, deadline misses, the
 * worker's waits, loop stalls, the share of its runnable time the tick's
 * thread spent waiting for a CPU, the share of the machine's time its
 * hypervisor took (steal), and the SCHED_FIFO priorities the run's threads
 * had (read from /proc while it ran).
 *
 * Under load: no loop stall, and the tick's thread waits for a CPU at most
 * 15 points of its runnable time more than alone (/proc/PID/task/TID/
 * schedstat). That is the rule's own claim, measured where the guest's
 * scheduler decides it. Alone it waits about a quarter of it already, for
 * the threads above it (the emulated MCU's QEMU at 22 takes about half a
 * core here); with the tick at SCHED_OTHER beside the busy processes it
 * waited 61 %. Deadlines are not the bound: on a virtual machine the host
 * takes CPU from a guest whose cores are all busy (top showed 12 % steal
 * during one such run; /proc/stat's count does not always see it), which
 * no priority inside the guest can prevent, and a loaded run here lost 93
 * of 300 deadlines with its tick waiting 29 % against 24 % alone. The priorities
 * must be the rule's: tick 20, worker 19, sender 21, emulated MCU 22.
 *
 * Skips (77) without the binary, where SCHED_FIFO is not permitted (the
 * run says so: grant CAP_SYS_NICE, or run as root), or where the scene
 * trips the watchdog even alone (a sanitized build: one piece of a tick
 * outlasts its bound), so that there is nothing to compare. */
#define _DEFAULT_SOURCE /* usleep, getloadavg */
#include "testutil.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_loop.h"

static struct {
    char bin[1024], src[1024];
} g;

typedef struct figures {
    double tick_max, tick_p99, tick_median, wait_ms;
    long ticks, misses, skipped;
    unsigned stalls;
    int rt;       /* the run held SCHED_FIFO */
    int prio[64]; /* SCHED_FIFO priorities seen among its threads (and QEMU's) */
    int n_prio;
    char why[512]; /* the run's real-time line when it was refused */
    /* the tick's thread (SCHED_FIFO ISO_LOOP_RT_PRIORITY) from /proc/PID/task/TID/schedstat:
     * ns on a CPU and ns runnable but waiting for one, at the first and the
     * last sample that saw it */
    int tick_tid;
    double run0, wait0, run1, wait1;
    double steal; /* the hypervisor's share of the machine's time during the run */
} figures;

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

static void note_prio(figures *f, int p)
{
    for (int i = 0; i < f->n_prio; i++)
        if (f->prio[i] == p)
            return;
    if (f->n_prio < 64)
        f->prio[f->n_prio++] = p;
}

/* The schedstat of the tick's thread, tid in the task folder dir. */
static void note_tick_thread(figures *f, const char *dir, int tid)
{
    char path[128], buf[128];
    snprintf(path, sizeof path, "%s/%d/schedstat", dir, tid);
    slurp(path, buf, sizeof buf);
    double run = 0, wait = 0;
    if (sscanf(buf, "%lf %lf", &run, &wait) != 2 || (f->tick_tid && f->tick_tid != tid))
        return;
    if (!f->tick_tid) {
        f->tick_tid = tid;
        f->run0 = run;
        f->wait0 = wait;
    }
    f->run1 = run;
    f->wait1 = wait;
}

/* The share of the time the tick's thread was runnable in which it waited
 * for a CPU, between the first and the last sample (0 without two). */
static double tick_wait_share(const figures *f)
{
    double run = f->run1 - f->run0, wait = f->wait1 - f->wait0;
    return run + wait > 0 ? wait / (run + wait) : 0;
}

/* The machine's total and stolen time so far, in jiffies (/proc/stat's
 * first line: user nice system idle iowait irq softirq steal ...). */
static void cpu_times(double *total, double *steal)
{
    char buf[512];
    slurp("/proc/stat", buf, sizeof buf);
    double v[8] = {0};
    sscanf(buf, "cpu %lf %lf %lf %lf %lf %lf %lf %lf", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5],
           &v[6], &v[7]);
    *total = *steal = v[7];
    for (int i = 0; i < 7; i++)
        *total += v[i];
}

/* The SCHED_FIFO priorities of process pid's threads: /proc/PID/task/TID/
 * stat, fields 40 (rt_priority) and 41 (policy, 1 = SCHED_FIFO). */
static void read_priorities(int pid, figures *f)
{
    char dir[64];
    snprintf(dir, sizeof dir, "/proc/%d/task", pid);
    DIR *d = opendir(dir);
    if (!d)
        return;
    for (struct dirent *t; (t = readdir(d)) != NULL;) {
        if (atoi(t->d_name) <= 0)
            continue;
        char path[400], buf[1024];
        snprintf(path, sizeof path, "%s/%s/stat", dir, t->d_name);
        slurp(path, buf, sizeof buf);
        const char *p = strrchr(buf, ')'); /* the command may hold spaces */
        if (!p)
            continue;
        long field[64] = {0};
        int k = 3;
        for (char *save = NULL, *tok = strtok_r((char *)p + 1, " ", &save); tok && k < 64;
             tok = strtok_r(NULL, " ", &save), k++)
            field[k] = strtol(tok, NULL, 10);
        if (field[41] == 1) /* SCHED_FIFO */
            note_prio(f, (int)field[40]);
        if (field[41] == 1 && field[40] == ISO_LOOP_RT_PRIORITY)
            note_tick_thread(f, dir, atoi(t->d_name));
    }
    closedir(d);
}

/* The priorities of pid and of its QEMU child, if any. */
static void read_all_priorities(int pid, figures *f)
{
    read_priorities(pid, f);
    char path[64], buf[512];
    snprintf(path, sizeof path, "/proc/%d/task/%d/children", pid, pid);
    slurp(path, buf, sizeof buf);
    for (char *save = NULL, *t = strtok_r(buf, " \n", &save); t; t = strtok_r(NULL, " \n", &save))
        read_priorities(atoi(t), f);
}

static pid_t busy_process(void)
{
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        alarm(90); /* bounded even if this test dies */
        volatile unsigned long x = 0;
        for (;;)
            x++;
    }
    return pid;
}

static void run_demo(int busy, figures *f, const char *label)
{
    memset(f, 0, sizeof *f);
    char out[1024], json[1024], name[64];
    snprintf(name, sizeof name, "load_%s.out", label);
    iso_test_tmp(out, sizeof out, name);
    snprintf(name, sizeof name, "load_%s.json", label);
    iso_test_tmp(json, sizeof json, name);
    unlink(json);
    pid_t load[16];
    for (int i = 0; i < busy && i < 16; i++)
        load[i] = busy_process();
    double total0, steal0, total1, steal1;
    cpu_times(&total0, &steal0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int fd = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd < 0 || chdir(g.src) != 0)
            _exit(127);
        dup2(fd, 1);
        dup2(fd, 2);
        execl(g.bin, g.bin, "run", "config/scenes/replay_cactus.yaml", "--no-display", "--speed",
              "0.25", "--duration", "5", "--stats-json", json, (char *)NULL);
        _exit(127);
    }
    int status = 0;
    double sampled = 0;
    while (waitpid(pid, &status, WNOHANG) == 0) {
        double now = iso_clock_now();
        if (now - sampled > 0.2) { /* its threads' priorities while it ticks */
            read_all_priorities(pid, f);
            sampled = now;
        }
        usleep(20000);
    }
    cpu_times(&total1, &steal1);
    f->steal = total1 > total0 ? (steal1 - steal0) / (total1 - total0) : 0;
    for (int i = 0; i < busy && i < 16; i++) {
        kill(load[i], SIGKILL);
        waitpid(load[i], NULL, 0);
    }
    static char text[1 << 17], j[1 << 16];
    slurp(out, text, sizeof text);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        fail_msg("%s: isoshape run failed (status %d):\n%s", label, status, text);
    const char *rt = strstr(text, "real-time scheduling not permitted");
    if (rt)
        snprintf(f->why, sizeof f->why, "%.*s", (int)strcspn(rt, "\n"), rt);
    f->rt = strstr(text, "real-time: SCHED_FIFO priority") != NULL;
    slurp(json, j, sizeof j);
    f->ticks = (long)iso_test_json_num(j, "ticks");
    f->misses = (long)iso_test_json_num(j, "misses");
    f->skipped = (long)iso_test_json_num(j, "skipped");
    f->tick_median = iso_test_json_num(j, "median");
    f->tick_p99 = iso_test_json_num(j, "p99");
    f->tick_max = iso_test_json_num(j, "max");
    double ev = iso_test_json_num(j, "evaluations");
    f->wait_ms = ev > 0 ? 1e3 * iso_test_json_num(j, "worker_wait_s") / ev : 0;
    const char *st = strstr(text, "loop stalls ");
    assert_non_null(st);
    f->stalls = (unsigned)strtoul(st + strlen("loop stalls "), NULL, 10);
}

static int has_prio(const figures *f, int p)
{
    for (int i = 0; i < f->n_prio; i++)
        if (f->prio[i] == p)
            return 1;
    return 0;
}

static void demo_scene_holds_under_load(void **state)
{
    (void)state;
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0) {
        print_message("skipped: the isoshape binary is not built\n");
        skip();
    }
    snprintf(g.src, sizeof g.src, "%s", ISO_TEST_STREAMS); /* <src>/tests/streams */
    *strrchr(g.src, '/') = 0;
    *strrchr(g.src, '/') = 0;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    int busy = (int)(cores > 0 && cores < 15 ? cores + 1 : 3);
    double load0[1];
    getloadavg(load0, 1);
    figures a, b;
    run_demo(0, &a, "alone");
    if (!a.rt) {
        print_message("skipped: %s\n", a.why[0] ? a.why : "the run did not get SCHED_FIFO");
        skip();
    }
    /* The comparison needs a build and a machine on which the scene keeps
     * real time alone (a sanitized build does not: its factorizations alone
     * outlast the watchdog's bound); elsewhere there is nothing to compare. */
    if (a.stalls > 0) {
        print_message("skipped: the scene trips the loop watchdog here even alone (%u loop "
                      "stalls, %ld of 300 deadlines lost, slowest tick %.0f ms): the load "
                      "comparison needs a build that keeps real time (a release build)\n",
                      a.stalls, a.skipped, a.tick_max);
        skip();
    }
    run_demo(busy, &b, "busy");
    char pa[128] = "", pb[128] = "";
    for (int i = 0; i < a.n_prio; i++)
        snprintf(pa + strlen(pa), sizeof pa - strlen(pa), "%s%d", i ? "," : "", a.prio[i]);
    for (int i = 0; i < b.n_prio; i++)
        snprintf(pb + strlen(pb), sizeof pb - strlen(pb), "%s%d", i ? "," : "", b.prio[i]);
    print_message("replay_cactus --speed 0.25 --duration 5 (%ld cores, load average %.1f before):\n"
                  "                     alone        beside %d busy processes\n"
                  "  tick median ms   %8.1f     %8.1f\n"
                  "  tick p99 ms      %8.1f     %8.1f\n"
                  "  tick max ms      %8.1f     %8.1f\n"
                  "  misses           %5ld/%ld   %5ld/%ld\n"
                  "  deadlines lost   %8ld     %8ld  (covered by late ticks)\n"
                  "  worker wait      %8.2f     %8.2f  ms per evaluation\n"
                  "  loop stalls      %8u     %8u\n"
                  "  tick thread waited %6.1f     %8.1f  %% of its runnable time\n"
                  "  hypervisor steal %8.1f     %8.1f  %% of the machine's time\n"
                  "  SCHED_FIFO       %s   %s\n",
                  cores, load0[0], busy, a.tick_median, b.tick_median, a.tick_p99, b.tick_p99,
                  a.tick_max, b.tick_max, a.misses, a.ticks, b.misses, b.ticks, a.skipped,
                  b.skipped, a.wait_ms, b.wait_ms, a.stalls, b.stalls, 100 * tick_wait_share(&a),
                  100 * tick_wait_share(&b), 100 * a.steal, 100 * b.steal, pa, pb);
    /* the rule: tick 20, worker 19, sender 21, the emulated MCU 22 */
    for (int p = 19; p <= 22; p++)
        if (!has_prio(&b, p))
            fail_msg("no thread of the run at SCHED_FIFO %d (seen: %s)", p, pb);
    assert_int_equal(b.stalls, 0);
    if (!a.tick_tid || !b.tick_tid || a.run1 <= a.run0 || b.run1 <= b.run0)
        fail_msg("no schedstat of the tick's thread (SCHED_FIFO %d) was read in %s",
                 ISO_LOOP_RT_PRIORITY,
                 !a.tick_tid || a.run1 <= a.run0 ? "the run alone" : "the loaded run");
    assert_true(tick_wait_share(&b) <= tick_wait_share(&a) + 0.15);
}

int main(void)
{
    const struct CMUnitTest t[] = {cmocka_unit_test(demo_scene_holds_under_load)};
    return cmocka_run_group_tests_name("run_load", t, NULL, NULL);
}
