/* common/iso_logq.c -- see iso_logq.h. The queue is a bounded
 * multi-producer ring with a sequence number per slot (a producer claims a
 * position with one compare-and-swap, fills the slot, then publishes it);
 * one consumer, the writer thread. */
#include "iso_logq.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_thread.h"

#define REPEATS 16       /* distinct recent lines remembered for collapsing */
#define IDLE_NS 10000000 /* the writer looks at the queue every 10 ms */
#define WAIT_SLICE_MS 50 /* a wait for a full stream looks at `closing` this often */
#define CLEAR "\r\033[K" /* erases a terminal's status line */

enum { KIND_LINE, KIND_STATUS };

typedef struct slot {
    _Atomic size_t seq;
    unsigned char kind;
    char text[ISO_LOGQ_LINE_MAX];
} slot;

typedef struct recent {
    char text[ISO_LOGQ_LINE_MAX];
    double written_at; /* < 0: free */
    long repeats;      /* counted since written_at */
} recent;

struct iso_logq {
    slot slots[ISO_LOGQ_SLOTS];
    _Atomic size_t head;  /* the next position a producer claims */
    _Atomic size_t taken; /* positions the writer has finished with */
    _Atomic long dropped, written, collapsed;
    _Atomic int closing;
    _Atomic int64_t close_by_ns; /* closing's deadline for a stream that takes nothing */
    FILE *f;
    int fd; /* -1: fputs on f */
    int status_clear;
    int dead; /* the stream's reader is gone: nothing more is written */
    long dropped_said;
    int status_shown; /* a status line stands on the stream */
    pthread_t thread;
    /* the writer's own */
    recent recent[REPEATS];
    char status[ISO_LOGQ_LINE_MAX];
    char out[2 * ISO_LOGQ_LINE_MAX + 64];
};

_Static_assert((ISO_LOGQ_SLOTS & (ISO_LOGQ_SLOTS - 1)) == 0, "ISO_LOGQ_SLOTS is a power of two");

/* ------------------------------------------------------------------------ */
/* Producers                                                                  */
/* ------------------------------------------------------------------------ */

/* Claims a slot, or NULL (and a count) when the queue is full. */
static slot *claim(iso_logq *q, size_t *pos_out)
{
    size_t pos = atomic_load_explicit(&q->head, memory_order_relaxed);
    for (;;) {
        slot *s = &q->slots[pos & (ISO_LOGQ_SLOTS - 1)];
        size_t seq = atomic_load_explicit(&s->seq, memory_order_acquire);
        long dif = (long)(seq - pos);
        if (dif == 0) {
            if (atomic_compare_exchange_weak_explicit(&q->head, &pos, pos + 1, memory_order_relaxed,
                                                      memory_order_relaxed)) {
                *pos_out = pos;
                return s;
            }
        } else if (dif < 0) {
            atomic_fetch_add_explicit(&q->dropped, 1, memory_order_relaxed);
            return NULL;
        } else {
            pos = atomic_load_explicit(&q->head, memory_order_relaxed);
        }
    }
}

static int put(iso_logq *q, int kind, const char *fmt, va_list ap)
{
    if (!q)
        return -1;
    size_t pos;
    slot *s = claim(q, &pos);
    if (!s)
        return -1;
    s->kind = (unsigned char)kind;
    vsnprintf(s->text, sizeof s->text, fmt, ap);
    atomic_store_explicit(&s->seq, pos + 1, memory_order_release);
    return 0;
}

static int putf(iso_logq *q, int kind, const char *fmt, ...) ISO_PRINTF(3, 4);
static int putf(iso_logq *q, int kind, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int rc = put(q, kind, fmt, ap);
    va_end(ap);
    return rc;
}

int iso_logq_sayf(iso_logq *q, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int rc = put(q, KIND_LINE, fmt, ap);
    va_end(ap);
    return rc;
}

int iso_logq_say(iso_logq *q, const char *line)
{
    return putf(q, KIND_LINE, "%s", line);
}

int iso_logq_status(iso_logq *q, const char *line)
{
    return putf(q, KIND_STATUS, "%s", line);
}

/* ------------------------------------------------------------------------ */
/* The writer                                                                 */
/* ------------------------------------------------------------------------ */

/* Waits until fd takes bytes; 0, or -1 when closing's deadline passed or
 * the reader is gone (then nothing more is written: no SIGPIPE). */
static int wait_writable(iso_logq *q)
{
    for (;;) {
        int ms = WAIT_SLICE_MS;
        if (atomic_load_explicit(&q->closing, memory_order_acquire)) {
            int64_t left = atomic_load(&q->close_by_ns) - iso_clock_ns();
            if (left <= 0)
                return -1;
            if (left / 1000000 < ms)
                ms = (int)(left / 1000000) + 1;
        }
        struct pollfd p = {q->fd, POLLOUT, 0};
        int n = poll(&p, 1, ms);
        if (n < 0 && errno != EINTR)
            return q->dead = 1, -1;
        if (n > 0 && (p.revents & (POLLERR | POLLHUP | POLLNVAL)))
            return q->dead = 1, -1;
        if (n > 0 && (p.revents & POLLOUT))
            return 0;
    }
}

/* Writes len bytes, in pieces no larger than a pipe writes at once, each
 * after poll() said there is room: 0, or -1 with the line counted lost. */
static int emit(iso_logq *q, const char *buf, size_t len)
{
    if (q->dead)
        return -1;
    if (q->fd < 0) {
        fputs(buf, q->f);
        fflush(q->f);
        return 0;
    }
    size_t done = 0;
    while (done < len) {
        if (wait_writable(q) != 0)
            return -1;
        size_t n = len - done < PIPE_BUF ? len - done : PIPE_BUF;
        ssize_t w = write(q->fd, buf + done, n);
        if (w > 0)
            done += (size_t)w;
        else if (w < 0 && errno != EINTR && errno != EAGAIN)
            return q->dead = 1, -1;
    }
    return 0;
}

static void emit_line(iso_logq *q, const char *text)
{
    const char *clear = q->status_clear && q->status_shown ? CLEAR : "";
    int n = snprintf(q->out, sizeof q->out, "%s%s\n", clear, text);
    if (emit(q, q->out, (size_t)n) == 0) {
        q->status_shown = 0;
        atomic_fetch_add_explicit(&q->written, 1, memory_order_relaxed);
    } else {
        atomic_fetch_add_explicit(&q->dropped, 1, memory_order_relaxed);
    }
}

/* Says how many lines were lost since it last said so. */
static void say_dropped(iso_logq *q)
{
    long d = atomic_load_explicit(&q->dropped, memory_order_relaxed);
    if (d == q->dropped_said || q->dead)
        return;
    char line[160];
    snprintf(line, sizeof line, "[%ld lines lost: the output took none while they came]",
             d - q->dropped_said);
    emit_line(q, line); /* its own loss, if it is lost, is said next time */
    q->dropped_said = atomic_load_explicit(&q->dropped, memory_order_relaxed);
}

/* A remembered line's count, owed when its window ends or it is forgotten:
 * "<line> [N more times in S s]". */
static void say_repeats(iso_logq *q, const recent *r, double seconds)
{
    char line[ISO_LOGQ_LINE_MAX + 64];
    snprintf(line, sizeof line, "%s [%ld more times in %.0f s]", r->text, r->repeats, seconds);
    emit_line(q, line);
}

/* A line written less than ISO_LOGQ_REPEAT_S ago is counted instead. */
static void take_line(iso_logq *q, const char *text, double now)
{
    recent *oldest = &q->recent[0];
    for (int i = 0; i < REPEATS; i++) {
        recent *r = &q->recent[i];
        if (r->written_at >= 0 && now - r->written_at < ISO_LOGQ_REPEAT_S &&
            strcmp(r->text, text) == 0) {
            r->repeats++;
            atomic_fetch_add_explicit(&q->collapsed, 1, memory_order_relaxed);
            return;
        }
        if (r->written_at < oldest->written_at)
            oldest = r;
    }
    if (oldest->repeats > 0) /* its count is owed before it is forgotten */
        say_repeats(q, oldest, now - oldest->written_at);
    snprintf(oldest->text, sizeof oldest->text, "%s", text);
    oldest->written_at = now;
    oldest->repeats = 0;
    emit_line(q, text);
}

/* The counts of windows that have ended; all of them when `all`. */
static void owe_repeats(iso_logq *q, double now, int all)
{
    for (int i = 0; i < REPEATS; i++) {
        recent *r = &q->recent[i];
        if (r->written_at < 0 || (!all && now - r->written_at < ISO_LOGQ_REPEAT_S))
            continue;
        if (r->repeats > 0) {
            say_repeats(q, r, fmax(ISO_LOGQ_REPEAT_S, now - r->written_at));
            r->repeats = 0;
            r->written_at = now; /* a new window: the next repeats are counted again */
        } else if (!all) {
            r->written_at = -1;
        }
    }
}

/* Takes one published slot: 1, or 0 when the next is not published yet. */
static int take(iso_logq *q, double now, int *had_status)
{
    size_t pos = atomic_load_explicit(&q->taken, memory_order_relaxed);
    slot *s = &q->slots[pos & (ISO_LOGQ_SLOTS - 1)];
    if (atomic_load_explicit(&s->seq, memory_order_acquire) != pos + 1)
        return 0;
    if (s->kind == KIND_STATUS) {
        memcpy(q->status, s->text, sizeof q->status);
        *had_status = 1;
    } else {
        say_dropped(q);
        take_line(q, s->text, now);
    }
    atomic_store_explicit(&s->seq, pos + ISO_LOGQ_SLOTS, memory_order_release);
    atomic_store_explicit(&q->taken, pos + 1, memory_order_release);
    return 1;
}

static void *writer_main(void *arg)
{
    iso_logq *q = arg;
    for (;;) {
        int had_status = 0, any = 0;
        double now = iso_clock_now();
        while (take(q, now, &had_status))
            any = 1;
        int closing = atomic_load_explicit(&q->closing, memory_order_acquire);
        owe_repeats(q, now, closing);
        say_dropped(q);
        if (had_status && !closing) {
            int n = snprintf(q->out, sizeof q->out, CLEAR "%s", q->status);
            if (emit(q, q->out, (size_t)n) == 0)
                q->status_shown = 1;
        }
        if (closing && atomic_load(&q->taken) == atomic_load(&q->head))
            break;
        if (!any) {
            if (closing && iso_clock_ns() > atomic_load(&q->close_by_ns))
                break; /* a producer that claimed a slot and never filled it */
            iso_clock_sleep_until(iso_clock_ns() + IDLE_NS);
        }
    }
    if (q->status_shown && q->status_clear)
        emit(q, CLEAR, sizeof CLEAR - 1);
    return NULL;
}

/* ------------------------------------------------------------------------ */
/* Life                                                                       */
/* ------------------------------------------------------------------------ */

int iso_logq_create(FILE *f, int status_clear, iso_logq **out, iso_err *err)
{
    *out = NULL;
    iso_logq *q = calloc(1, sizeof *q);
    if (!q)
        return iso_err_set(err, ISO_ENOMEM, -1, "log queue: out of memory");
    for (size_t i = 0; i < ISO_LOGQ_SLOTS; i++)
        atomic_init(&q->slots[i].seq, i);
    for (int i = 0; i < REPEATS; i++)
        q->recent[i].written_at = -1;
    q->f = f;
    fflush(f);
    q->fd = fileno(f);
    q->status_clear = status_clear;
    int rc = iso_thread_start(&q->thread, writer_main, q);
    if (rc != 0) {
        free(q);
        return iso_err_set(err, ISO_EIO, -1, "log queue: cannot start its thread: %s",
                           strerror(rc));
    }
    *out = q;
    return ISO_OK;
}

int iso_logq_flush(iso_logq *q, int timeout_ms)
{
    if (!q)
        return 0;
    size_t want = atomic_load(&q->head);
    int64_t until = iso_clock_ns() + (int64_t)timeout_ms * 1000000;
    while ((long)(atomic_load(&q->taken) - want) < 0) {
        if (iso_clock_ns() > until)
            return -1;
        iso_clock_sleep_until(iso_clock_ns() + 2000000);
    }
    return 0;
}

void iso_logq_destroy(iso_logq *q)
{
    if (!q)
        return;
    atomic_store(&q->close_by_ns, iso_clock_ns() + (int64_t)ISO_LOGQ_CLOSE_MS * 1000000);
    atomic_store_explicit(&q->closing, 1, memory_order_release);
    pthread_join(q->thread, NULL);
    if (q->fd < 0)
        fflush(q->f);
    free(q);
}

void iso_logq_get_stats(const iso_logq *q, iso_logq_stats *out)
{
    memset(out, 0, sizeof *out);
    if (!q)
        return;
    out->written = atomic_load(&q->written);
    out->dropped = atomic_load(&q->dropped);
    out->collapsed = atomic_load(&q->collapsed);
}
