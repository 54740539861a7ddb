/* devices/rec_writer.c -- a recording written off the caller's thread
 * (iso_dev_rec.h).
 *
 * The caller (the loop's tick) only encodes records into a byte ring made
 * at open; a thread of the writer's own writes them to the file. The ring
 * has one producer and one consumer: the producer appends at `head` and
 * publishes a tick's records by storing `committed` (release) after its
 * TICK record, the thread writes [done, committed) and stores `done`. So
 * the thread only ever writes whole ticks, and the file ends at a TICK
 * record whatever happens to the disk. The producer makes no system call
 * and takes no lock: a tick never waits on the disk.
 *
 * When the ring cannot take a record (the disk does not keep up: a FIFO
 * nobody reads, a slow mount) the recording is cut at the last whole tick:
 * the tick in progress is dropped, nothing more is taken, and the thread
 * writes what came before and the END record. When a write fails (a full
 * disk) the thread stops there, cuts a regular file back to the last whole
 * tick it wrote, and adds the END record if the disk takes it. Either way
 * iso_dev_rec_writer_ended says so once, naming the tick, and the caller
 * goes on. */
#define _GNU_SOURCE /* O_CLOEXEC with _POSIX_C_SOURCE */
#include "internal.h"
#include "iso_clock.h"
#include "iso_dev_rec.h"
#include "iso_thread.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define IDLE_NS 2000000 /* the thread's nap when there is nothing to write */

enum { CUT_NONE = 0, CUT_FULL = 1, CUT_FAILED = 2 };

struct iso_dev__rec_async {
    int fd, fifo;
    uint8_t *ring;
    size_t cap;
    size_t head;              /* producer: bytes appended (monotonic) */
    _Atomic size_t committed; /* producer → thread: bytes of whole ticks */
    _Atomic size_t done;      /* thread → producer: bytes written */
    long ticks;               /* producer: ticks committed */
    _Atomic int closing, failed_errno;
    int cut;        /* producer: CUT_* */
    int said;       /* iso_dev_rec_writer_ended said it */
    long cut_ticks; /* ticks committed when it was cut */
    pthread_t th;
};

/* ---- the thread -------------------------------------------------------- */

/* Writes n bytes, waiting for a FIFO's reader with poll (so that closing
 * can give up on one that stalls, at deadline once closing). 0, or an
 * errno value. */
static int put_raw(struct iso_dev__rec_async *a, const uint8_t *p, size_t n, int64_t deadline)
{
    while (n > 0) {
        if (a->fifo) {
            struct pollfd q = {a->fd, POLLOUT, 0};
            int ms = 50;
            if (atomic_load(&a->closing) && deadline > 0) {
                int64_t left = (deadline - iso_clock_ns()) / 1000000;
                if (left <= 0)
                    return ETIMEDOUT;
                ms = left < ms ? (int)left : ms;
            }
            if (poll(&q, 1, ms) <= 0)
                continue;
        }
        ssize_t w = write(a->fd, p, n);
        if (w < 0 && (errno == EINTR || errno == EAGAIN))
            continue;
        if (w <= 0)
            return w < 0 ? errno : EIO;
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

/* Writes the ring's bytes [from, from + n), telling the producer the room
 * each piece frees. */
static int put_bytes(struct iso_dev__rec_async *a, size_t from, size_t n, int64_t deadline)
{
    while (n > 0) {
        size_t at = from % a->cap, k = a->cap - at < n ? a->cap - at : n;
        int e = put_raw(a, a->ring + at, k, deadline);
        if (e != 0)
            return e;
        from += k;
        n -= k;
        atomic_store_explicit(&a->done, from, memory_order_release);
    }
    return 0;
}

static void finish(struct iso_dev__rec_async *a, int failed, size_t whole, int64_t deadline)
{
    uint8_t end[32];
    iso_dev_chunk c = {.type = ISO_DEV_CHUNK_END};
    int len = iso_dev_rec_encode_record(end, sizeof end, &c);
    if (failed && !a->fifo) { /* back to the last whole tick: no torn record */
        (void)!ftruncate(a->fd, (off_t)whole);
        (void)lseek(a->fd, (off_t)whole, SEEK_SET);
    }
    if ((!failed || !a->fifo) && len > 0)
        (void)put_raw(a, end, (size_t)len, deadline);
    close(a->fd);
    a->fd = -1;
}

static void *writer_main(void *arg)
{
    struct iso_dev__rec_async *a = arg;
    int64_t deadline = 0;
    size_t whole = 0; /* bytes up to the last committed point written */
    for (;;) {
        int closing = atomic_load(&a->closing);
        if (closing && deadline == 0)
            deadline = iso_clock_ns() + (int64_t)ISO_DEV_REC_CLOSE_MS * 1000000;
        size_t to = atomic_load_explicit(&a->committed, memory_order_acquire);
        size_t from = atomic_load_explicit(&a->done, memory_order_relaxed);
        if (from < to) {
            int e = put_bytes(a, from, to - from, deadline);
            if (e != 0) {
                atomic_store(&a->failed_errno, e);
                finish(a, 1, whole, deadline);
                return NULL;
            }
            whole = to;
            continue;
        }
        if (closing) {
            finish(a, 0, whole, deadline);
            return NULL;
        }
        iso_clock_sleep_until(iso_clock_ns() + IDLE_NS);
    }
}

/* ---- the caller's side ------------------------------------------------- */

/* Opens path for writing: a FIFO without a reader is refused at once
 * (opening it would wait for one), one with a reader is written through
 * with poll; anything else is created or truncated. */
static int open_target(const char *path, int *fifo, iso_err *err)
{
    struct stat st;
    *fifo = stat(path, &st) == 0 && S_ISFIFO(st.st_mode);
    if (*fifo) {
        int fd = open(path, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
        if (fd < 0 && errno == ENXIO)
            return iso_err_set(err, ISO_EIO, -1,
                               "%s: a FIFO that no one reads: start its reader first", path);
        if (fd < 0)
            return iso_err_set(err, ISO_EIO, -1, "%s: cannot open: %s", path, strerror(errno));
        return fd;
    }
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot create: %s", path, strerror(errno));
    return fd;
}

/* Appends len bytes to the ring if they fit beside what the thread has not
 * written yet; 0 if they do not. */
static int append(struct iso_dev__rec_async *a, const uint8_t *p, size_t len)
{
    size_t done = atomic_load_explicit(&a->done, memory_order_acquire);
    if (a->head - done + len > a->cap)
        return 0;
    for (size_t i = 0; i < len;) {
        size_t at = (a->head + i) % a->cap, k = a->cap - at < len - i ? a->cap - at : len - i;
        memcpy(a->ring + at, p + i, k);
        i += k;
    }
    a->head += len;
    return 1;
}

/* The recording ends at the last whole tick: the tick in progress goes. */
static void cut(struct iso_dev__rec_async *a, int why)
{
    if (a->cut)
        return;
    a->cut = why;
    a->head = atomic_load(&a->committed);
    a->cut_ticks = a->ticks;
}

/* A write the thread could not make ends the recording too. */
static void take_failure(struct iso_dev__rec_async *a)
{
    if (!a->cut && atomic_load(&a->failed_errno) != 0)
        cut(a, CUT_FAILED);
}

static void destroy(struct iso_dev__rec_async *a)
{
    if (!a)
        return;
    if (a->fd >= 0)
        close(a->fd);
    free(a->ring);
    free(a);
}

int iso_dev_rec_writer_open(iso_dev_rec_writer *w, const char *path, const iso_dev_info *infos,
                            size_t n, int64_t t0_ns, iso_err *err)
{
    memset(w, 0, sizeof *w);
    snprintf(w->path, sizeof w->path, "%s", path);
    struct iso_dev__rec_async *a = calloc(1, sizeof *a);
    size_t hcap = 32 + n * (32 + ISO_DEV_NAME_MAX + ISO_DEV_DESC_MAX);
    uint8_t *head = malloc(hcap);
    if (a) {
        a->fd = -1;
        a->cap = ISO_DEV_REC_QUEUE_BYTES;
        a->ring = malloc(a->cap);
    }
    if (!a || !head || !a->ring) {
        free(head);
        destroy(a);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory for the recording's queue",
                           path);
    }
    int len = iso_dev_rec_encode_header(head, hcap, infos, n, t0_ns);
    if (len < 0) {
        free(head);
        destroy(a);
        return iso_err_set(err, ISO_EINVAL, -1, "%s: %zu sources (at most %u can be recorded)",
                           path, n, ISO_DEV_MAX_SOURCES);
    }
    (void)append(a, head, (size_t)len);
    free(head);
    atomic_store(&a->committed, a->head);
    a->fd = open_target(path, &a->fifo, err);
    if (a->fd < 0) {
        int rc = a->fd;
        a->fd = -1;
        destroy(a);
        return rc;
    }
    int e = iso_thread_start(&a->th, writer_main, a);
    if (e != 0) {
        destroy(a);
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot start the recording's writer: %s", path,
                           strerror(e));
    }
    w->a = a;
    return ISO_OK;
}

int iso_dev_rec_write(iso_dev_rec_writer *w, const iso_dev_chunk *c, iso_err *err)
{
    struct iso_dev__rec_async *a = w->a;
    uint8_t buf[ISO_DEV__REC_MAX];
    int len = iso_dev_rec_encode_record(buf, sizeof buf, c);
    if (len < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: a chunk of %u bytes cannot be recorded",
                           w->path, c->len);
    if (!a)
        return iso_err_set(err, ISO_EIO, -1, "%s: the recording is not open", w->path);
    take_failure(a);
    if (a->cut)
        return ISO_OK; /* ended: said by iso_dev_rec_writer_ended */
    if (!append(a, buf, (size_t)len)) {
        cut(a, CUT_FULL);
        return ISO_OK;
    }
    w->records++;
    return ISO_OK;
}

int iso_dev_rec_tick(iso_dev_rec_writer *w, int64_t t_ns, iso_err *err)
{
    iso_dev_chunk c = {.t_ns = t_ns, .type = ISO_DEV_CHUNK_TICK};
    int rc = iso_dev_rec_write(w, &c, err);
    struct iso_dev__rec_async *a = w->a;
    if (rc != ISO_OK || a->cut)
        return rc;
    a->ticks++;
    atomic_store_explicit(&a->committed, a->head, memory_order_release);
    return ISO_OK;
}

int iso_dev_rec_writer_ended(iso_dev_rec_writer *w, char *msg, size_t cap)
{
    struct iso_dev__rec_async *a = w->a;
    if (!a)
        return 0;
    take_failure(a);
    if (!a->cut || a->said)
        return 0;
    a->said = 1;
    int e = atomic_load(&a->failed_errno);
    if (a->cut == CUT_FULL)
        snprintf(msg, cap,
                 "recording %s: ended after tick %ld: the disk or its reader did not keep up "
                 "(%u KiB waiting); it is closed whole and replays to that tick",
                 w->path, a->cut_ticks, (unsigned)(ISO_DEV_REC_QUEUE_BYTES / 1024));
    else
        snprintf(msg, cap,
                 "recording %s: a write failed (%s) by tick %ld: it ends at the last whole tick "
                 "the disk took and replays to it",
                 w->path, strerror(e), a->cut_ticks);
    return 1;
}

int iso_dev_rec_writer_close(iso_dev_rec_writer *w, iso_err *err)
{
    struct iso_dev__rec_async *a = w->a;
    if (!a)
        return ISO_OK;
    /* what came after the last tick is kept (a replay ends at its last TICK) */
    if (!a->cut)
        atomic_store_explicit(&a->committed, a->head, memory_order_release);
    atomic_store(&a->closing, 1);
    pthread_join(a->th, NULL);
    int e = atomic_load(&a->failed_errno);
    w->a = NULL;
    destroy(a);
    if (e == ETIMEDOUT)
        return iso_err_set(err, ISO_EIO, -1,
                           "%s: its reader took nothing for %ld ms at the end: the recording "
                           "ends where the reader stopped",
                           w->path, (long)ISO_DEV_REC_CLOSE_MS);
    if (e != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: %s", w->path, strerror(e));
    return ISO_OK;
}
