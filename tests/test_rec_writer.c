/* tests/test_rec_writer.c -- a recording written off the tick
 * (iso_dev_rec.h, the writer): the caller never waits on the
 * disk, and a recording the disk could not take is closed whole at a tick.
 *
 * - A FIFO whose reader reads nothing: every write and tick returns
 *   (writing to the FIFO itself would block for ever once its 64 KiB pipe
 *   is full; an alarm turns such a hang into a failure, and the slowest
 *   call is printed: 0.1 ms on a quiet machine, a few ms when preempted),
 *   the queue fills and the
 *   recording is cut and said to end after tick N; when the reader then
 *   reads, it gets a whole recording: N TICK records, the END record, no
 *   torn record.
 * - A full disk (the file size limit, RLIMIT_FSIZE, in a child process):
 *   the recording is said to end, and the file holds whole records only,
 *   ending at a TICK record and the END record (cutting the torn tick off
 *   made room for it).
 * - A FIFO with no reader is refused at open, with a sentence, instead of
 *   waiting in open() for one. */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "iso_dev_rec.h"
#include "testutil.h"

static iso_dev_info one_source(void)
{
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = ISO_DEV_KIND_SERIAL;
    strcpy(in.name, "/dev/ttyACM0");
    return in;
}

/* A tick's worth: one 120-byte DATA chunk and the TICK record. */
static int one_tick(iso_dev_rec_writer *w, long k, iso_err *err)
{
    iso_dev_chunk c = {.t_ns = k * 1000000, .type = ISO_DEV_CHUNK_DATA, .len = 120};
    memset(c.data, (int)(k & 0xff), c.len);
    int rc = iso_dev_rec_write(w, &c, err);
    return rc == ISO_OK ? iso_dev_rec_tick(w, k * 1000000 + 500000, err) : rc;
}

/* Counts the recording's TICK records; *whole: no torn record. */
static long count_ticks(const uint8_t *p, size_t n, int *whole, int *ended)
{
    iso_dev_rec_reader r;
    iso_err err;
    iso_err_clear(&err);
    if (iso_dev_rec_reader_init(&r, p, n, &err) != ISO_OK)
        fail_msg("the recording does not parse: %s", err.msg);
    iso_dev_chunk c;
    long ticks = 0;
    while (iso_dev_rec_next(&r, &c, NULL) == 1)
        ticks += c.type == ISO_DEV_CHUNK_TICK;
    *whole = !r.torn && r.damaged == 0;
    *ended = r.ended;
    iso_dev_rec_reader_deinit(&r);
    return ticks;
}

typedef struct drain {
    int fd;
    uint8_t *buf;
    size_t len, cap;
    pthread_t th;
} drain;

static void *drain_main(void *arg)
{
    drain *d = arg;
    for (;;) {
        if (d->len == d->cap) {
            d->cap *= 2;
            d->buf = realloc(d->buf, d->cap);
        }
        ssize_t n = read(d->fd, d->buf + d->len, d->cap - d->len);
        if (n > 0)
            d->len += (size_t)n;
        else if (n == 0 || (errno != EAGAIN && errno != EINTR))
            return NULL;
        else
            iso_test_nap_ms(1);
    }
}

static void a_stalled_fifo_never_blocks_the_tick(void **state)
{
    (void)state;
    char path[1024];
    iso_test_tmp(path, sizeof path, "rec_writer_stalled.fifo");
    unlink(path);
    assert_int_equal(mkfifo(path, 0600), 0);
    int rfd = open(path, O_RDONLY | O_NONBLOCK); /* a reader that reads nothing yet */
    assert_true(rfd >= 0);
    iso_dev_info in = one_source();
    iso_dev_rec_writer w;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_writer_open(&w, path, &in, 1, 0, &err), ISO_OK);
    alarm(60); /* a write that waits for the reader never returns */
    double slowest = 0;
    long k, said_at = -1;
    char msg[512] = "";
    for (k = 1; k <= 40000; k++) { /* 6 MB: more than the queue and the pipe */
        double t0 = iso_test_now_s();
        assert_int_equal(one_tick(&w, k, &err), ISO_OK);
        double dt = iso_test_now_s() - t0;
        slowest = dt > slowest ? dt : slowest;
        if (said_at < 0 && iso_dev_rec_writer_ended(&w, msg, sizeof msg))
            said_at = k;
    }
    print_message("stalled FIFO: %ld ticks, the slowest write and tick %.3f ms; said at tick "
                  "%ld: %s\n",
                  k - 1, 1e3 * slowest, said_at, msg);
    assert_true(slowest < 1.0); /* returned: not waiting on the reader */
    assert_true(said_at > 0);
    long announced = -1;
    const char *at = strstr(msg, "ended after tick ");
    assert_non_null(at);
    announced = strtol(at + strlen("ended after tick "), NULL, 10);
    assert_int_equal(iso_dev_rec_writer_ended(&w, msg, sizeof msg), 0); /* said once */
    alarm(0);
    drain d = {rfd, malloc(1 << 16), 0, 1 << 16, 0};
    pthread_create(&d.th, NULL, drain_main, &d);
    assert_int_equal(iso_dev_rec_writer_close(&w, &err), ISO_OK);
    pthread_join(d.th, NULL);
    close(rfd);
    int whole = 0, ended = 0;
    long ticks = count_ticks(d.buf, d.len, &whole, &ended);
    print_message("the reader got %zu bytes: %ld ticks, whole %d, END %d\n", d.len, ticks, whole,
                  ended);
    assert_int_equal(ticks, announced);
    assert_true(whole && ended);
    free(d.buf);
    unlink(path);
}

static void a_full_disk_ends_the_recording_whole(void **state)
{
    (void)state;
    char path[1024];
    iso_test_tmp(path, sizeof path, "rec_writer_full.isorec");
    unlink(path);
    enum { LIMIT = 64 * 1024 };
    pid_t pid = fork();
    if (pid == 0) {
        signal(SIGXFSZ, SIG_IGN); /* write() then fails with EFBIG, as on a full disk */
        struct rlimit rl = {LIMIT, LIMIT};
        setrlimit(RLIMIT_FSIZE, &rl);
        iso_dev_info in = one_source();
        iso_dev_rec_writer w;
        iso_err err;
        iso_err_clear(&err);
        if (iso_dev_rec_writer_open(&w, path, &in, 1, 0, &err) != ISO_OK)
            _exit(2);
        char msg[512];
        int said = 0;
        for (long k = 1; k <= 2000 && !said; k++) {
            if (one_tick(&w, k, &err) != ISO_OK)
                _exit(3);
            said = iso_dev_rec_writer_ended(&w, msg, sizeof msg);
            iso_test_nap_ms(k % 50 == 0); /* the thread keeps up, as it does at 60 Hz */
        }
        for (int i = 0; i < 200 && !said; i++, iso_test_nap_ms(5))
            said = one_tick(&w, 9999, &err) == ISO_OK && iso_dev_rec_writer_ended(&w, msg, 512);
        int closed = iso_dev_rec_writer_close(&w, &err); /* EFBIG: said above */
        (void)closed;
        if (said)
            fprintf(stderr, "%s\n", msg);
        _exit(said ? 0 : 4);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    static uint8_t buf[LIMIT + 1];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    int whole = 0, ended = 0;
    long ticks = count_ticks(buf, n, &whole, &ended);
    print_message("full disk at %d bytes: the file is %zu bytes, %ld whole ticks, END %d\n", LIMIT,
                  n, ticks, ended);
    assert_true(n <= LIMIT);
    assert_true(ticks > 100);
    assert_true(whole && ended); /* the cut freed the room its END record needs */
    unlink(path);
}

static void a_fifo_without_reader_is_refused(void **state)
{
    (void)state;
    char path[1024];
    iso_test_tmp(path, sizeof path, "rec_writer_noreader.fifo");
    unlink(path);
    assert_int_equal(mkfifo(path, 0600), 0);
    iso_dev_info in = one_source();
    iso_dev_rec_writer w;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_writer_open(&w, path, &in, 1, 0, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "a FIFO that no one reads"));
    assert_non_null(strstr(err.msg, path));
    unlink(path);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_stalled_fifo_never_blocks_the_tick),
        cmocka_unit_test(a_full_disk_ends_the_recording_whole),
        cmocka_unit_test(a_fifo_without_reader_is_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
