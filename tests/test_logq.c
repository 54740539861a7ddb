/* tests/test_logq.c -- the log queue (common/iso_logq.h) that every thread
 * with a deadline says its lines through:
 *   - onto a pipe nobody reads, no call blocks: 19,998 lines from three
 *     threads all return, the queue refuses (and counts) what does not
 *     fit, destroy returns within its close time (300 ms) plus a
 *     scheduling margin, and what reached the pipe is whole lines, each
 *     producer's in its own order;
 *   - once the pipe is read again, the loss is said in a line of its own;
 *   - a line repeated within the window is written once, and its count
 *     follows in one line, also for two lines that alternate;
 *   - a FILE without a descriptor (a memory stream) gets every line, in
 *     order, and iso_logq_flush waits for them;
 *   - a pipe whose reader has gone costs no SIGPIPE: the lines are counted
 *     as dropped. */
#define _GNU_SOURCE /* F_SETPIPE_SZ */
#include "testutil.h"

#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_logq.h"

#define PER_THREAD (20000 / 3)

typedef struct producer {
    iso_logq *q;
    int id;
    long refused;
    double longest_s; /* the longest one call took */
} producer;

static void *produce(void *arg)
{
    producer *p = arg;
    for (int i = 0; i < PER_THREAD; i++) {
        double t0 = iso_clock_now();
        if (iso_logq_sayf(p->q, "thread %d line %d", p->id, i) != 0)
            p->refused++;
        double t = iso_clock_now() - t0;
        if (t > p->longest_s)
            p->longest_s = t;
    }
    return NULL;
}

/* Everything readable from fd now (non-blocking), NUL-terminated. */
static char *slurp(int fd, size_t *len)
{
    size_t cap = 1 << 20, n = 0;
    char *buf = malloc(cap + 1);
    assert_non_null(buf);
    int fl = fcntl(fd, F_GETFL);
    fcntl(fd, F_SETFL, fl | O_NONBLOCK);
    for (;;) {
        ssize_t r = read(fd, buf + n, cap - n);
        if (r <= 0)
            break;
        n += (size_t)r;
    }
    fcntl(fd, F_SETFL, fl);
    buf[n] = 0;
    *len = n;
    return buf;
}

/* Each line is "thread T line I" with I growing per T. */
static void lines_whole_and_in_order(const char *text, long *count)
{
    int last[3] = {-1, -1, -1};
    long n = 0;
    for (const char *p = text; *p;) {
        const char *nl = strchr(p, '\n');
        assert_non_null(nl); /* no torn last line */
        int t, i;
        if (sscanf(p, "thread %d line %d", &t, &i) == 2) {
            assert_true(t >= 0 && t < 3);
            assert_true(i > last[t]);
            last[t] = i;
            n++;
        }
        p = nl + 1;
    }
    *count = n;
}

static void a_pipe_nobody_reads_blocks_nobody(void **state)
{
    (void)state;
    int fds[2];
    assert_int_equal(pipe(fds), 0);
    /* full before the first line: what a stderr nobody reads comes to */
    fcntl(fds[1], F_SETFL, O_NONBLOCK);
    size_t filled = 0;
    while (write(fds[1], "fill\n", 5) == 5)
        filled += 5;
    fcntl(fds[1], F_SETFL, 0);
    FILE *f = fdopen(fds[1], "w");
    assert_non_null(f);
    iso_logq *q = NULL;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_logq_create(f, 0, &q, &e), ISO_OK);
    producer p[3];
    pthread_t th[3];
    for (int k = 0; k < 3; k++) {
        p[k] = (producer){q, k, 0, 0};
        assert_int_equal(pthread_create(&th[k], NULL, produce, &p[k]), 0);
    }
    for (int k = 0; k < 3; k++)
        pthread_join(th[k], NULL);
    double t0 = iso_clock_now();
    iso_logq_destroy(q); /* the pipe is still full: closing gives up in time */
    double close_s = iso_clock_now() - t0;
    size_t len;
    char *text = slurp(fds[0], &len);
    long got;
    lines_whole_and_in_order(text, &got);
    long refused = p[0].refused + p[1].refused + p[2].refused;
    double longest = p[0].longest_s;
    for (int k = 1; k < 3; k++)
        longest = p[k].longest_s > longest ? p[k].longest_s : longest;
    print_message("a full pipe nobody reads: %d lines said, %ld refused by a full queue, %ld "
                  "reached the pipe (%zu bytes); destroy took %.0f ms; the longest say took "
                  "%.3f ms\n",
                  3 * PER_THREAD, refused, got, len, close_s * 1e3, longest * 1e3);
    assert_true(refused > 0); /* the queue filled: lines were dropped, not waited for */
    assert_int_equal(got, 0); /* the pipe never took a byte more */
    assert_int_equal(len, filled);
    assert_true(close_s < 0.3 + 2.0); /* the close time, and a loaded machine's margin */
    free(text);
    fclose(f);
    close(fds[0]);
}

static void the_loss_is_said_when_the_pipe_drains(void **state)
{
    (void)state;
    int fds[2];
    assert_int_equal(pipe(fds), 0);
    fcntl(fds[1], F_SETPIPE_SZ, 4096);
    FILE *f = fdopen(fds[1], "w");
    iso_logq *q = NULL;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_logq_create(f, 0, &q, &e), ISO_OK);
    long refused = 0;
    for (int i = 0; i < 2000; i++)
        refused += iso_logq_sayf(q, "line %d, long enough to fill a pipe of four KiB soon", i) != 0;
    assert_true(refused > 0);
    /* read until the writer has said what was lost */
    char all[1 << 16];
    size_t n = 0;
    double until = iso_clock_now() + 10;
    while (!strstr(all, "lines lost") && iso_clock_now() < until && n < sizeof all - 4096) {
        ssize_t r = read(fds[0], all + n, 4096);
        if (r > 0)
            n += (size_t)r;
        all[n] = 0;
    }
    iso_logq_stats s;
    iso_logq_get_stats(q, &s);
    print_message("%ld refused, %ld written so far: %.80s\n", refused, s.written,
                  strstr(all, "[") ? strstr(all, "[") : "(no loss line)");
    assert_non_null(strstr(all, "lines lost: the output took none while they came]"));
    iso_logq_destroy(q);
    fclose(f);
    close(fds[0]);
}

static void repeats_are_counted_not_written(void **state)
{
    (void)state;
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    assert_non_null(f);
    iso_logq *q = NULL;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_logq_create(f, 0, &q, &e), ISO_OK);
    for (int i = 0; i < 50; i++) {
        assert_int_equal(iso_logq_say(q, "stale"), 0);
        assert_int_equal(iso_logq_say(q, "resumed"), 0);
        if (i % 10 == 9)
            assert_int_equal(iso_logq_flush(q, 5000), 0); /* the queue holds 128 */
    }
    assert_int_equal(iso_logq_say(q, "other"), 0);
    assert_int_equal(iso_logq_flush(q, 5000), 0);
    iso_logq_stats s;
    iso_logq_get_stats(q, &s);
    iso_logq_destroy(q);
    fclose(f);
    print_message("%s", buf);
    assert_string_equal(buf, "stale\nresumed\nother\nstale [49 more times in 2 s]\n"
                             "resumed [49 more times in 2 s]\n");
    assert_int_equal(s.collapsed, 98);
    free(buf);
}

static void a_memory_stream_gets_every_line_in_order(void **state)
{
    (void)state;
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    iso_logq *q = NULL;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_logq_create(f, 0, &q, &e), ISO_OK);
    for (int i = 0; i < 1000; i++) {
        while (iso_logq_sayf(q, "thread 0 line %d", i) != 0)
            assert_int_equal(iso_logq_flush(q, 5000), 0); /* full: wait, then say it again */
    }
    assert_int_equal(iso_logq_flush(q, 5000), 0);
    iso_logq_stats s;
    iso_logq_get_stats(q, &s);
    assert_true(s.written >= 1000); /* and the lines that said what a full queue refused */
    iso_logq_destroy(q);
    fclose(f);
    long got;
    lines_whole_and_in_order(buf, &got);
    assert_int_equal(got, 1000);
    free(buf);
}

static void a_reader_gone_is_no_sigpipe(void **state)
{
    (void)state;
    int fds[2];
    assert_int_equal(pipe(fds), 0);
    close(fds[0]);
    FILE *f = fdopen(fds[1], "w");
    iso_logq *q = NULL;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_logq_create(f, 0, &q, &e), ISO_OK);
    for (int i = 0; i < 10; i++)
        assert_int_equal(iso_logq_sayf(q, "line %d", i), 0);
    assert_int_equal(iso_logq_flush(q, 5000), 0); /* SIGPIPE would have ended the test here */
    iso_logq_stats s;
    iso_logq_get_stats(q, &s);
    assert_int_equal(s.written, 0);
    assert_int_equal(s.dropped, 10);
    iso_logq_destroy(q);
    fclose(f);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(a_pipe_nobody_reads_blocks_nobody),
        cmocka_unit_test(the_loss_is_said_when_the_pipe_drains),
        cmocka_unit_test(repeats_are_counted_not_written),
        cmocka_unit_test(a_memory_stream_gets_every_line_in_order),
        cmocka_unit_test(a_reader_gone_is_no_sigpipe),
    };
    return cmocka_run_group_tests_name("logq", t, NULL, NULL);
}
