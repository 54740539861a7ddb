/* devices/hub_reader.c -- the hub's byte streams (serial sources: a tty, a
 * TCP bridge, libserialport) read on a thread of their own.
 *
 * Why: a read of a tty (a pty, a USB serial adapter, a UART) that finds
 * the line discipline's buffer empty waits for the kernel's buffer work
 * (n_tty_read flushes the port's flip buffer on a kworker, which runs at
 * normal priority). The loop's tick read its devices itself, so a device
 * flooding the line made the real-time tick wait for a kworker that any
 * busy process could hold up: 16 MB of random bytes on a pty took the p99
 * tick from 4 to 31-44 ms, with the tick's own work bounded. Here the
 * thread does the reading (and any waiting) into one ring of chunks per
 * source, and the tick only takes chunks out of the rings: it never
 * enters the kernel for these sources.
 *
 * The ring is single-producer (this thread), single-consumer (the tick),
 * lock-free. A full ring stops the reading of its source until the tick
 * has taken some (the kernel's buffers and the device then hold or drop
 * the rest, as they would for a slow reader). A read that fails ends in a
 * GONE chunk carrying the error; the source is then the tick's again (it
 * closes it and reopens it later). Chunks keep the time of their read,
 * as the source stamped it. Nothing else changes: the tick decodes and
 * records the chunks it takes in the same order as before, so a replay
 * still reproduces the run bit for bit. */
#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "iso_dev_hub.h"
#include "iso_dev_source.h"
#include "iso_thread.h"

#define RING 256u /* chunks per source: 64 KiB, four ticks' worth of ISO_DEV_DRAIN_MAX */
#define LOOK_MS 2 /* the longest the thread waits before it looks at its sources again */
#define RING_MASK (RING - 1u)
_Static_assert((RING & RING_MASK) == 0, "the ring's size is a power of two");
_Static_assert(RING *ISO_DEV_CHUNK_MAX >= 2u * ISO_DEV_DRAIN_MAX,
               "a ring holds more than the tick takes");

typedef struct ring {
    iso_dev_chunk c[RING];
    atomic_uint head; /* the next slot the thread fills */
    atomic_uint tail; /* the next slot the tick empties */
} ring;

typedef struct slot {
    _Atomic(iso_dev_source *) s; /* read by the thread while set; NULL: the tick's */
    ring *r;                     /* allocated at the first attach, kept */
} slot;

struct iso_dev__reader {
    slot slots[ISO_DEV_MAX_SOURCES];
    pthread_t thread;
    atomic_int quit;
    atomic_int priority; /* asked for (iso_dev__reader_priority); applied by the thread */
    atomic_int prio_done, prio_errno;
    atomic_uint asked, served; /* iso_dev__reader_sync: passes asked for, and made */
};

static int ring_full(const ring *r)
{
    return atomic_load_explicit(&r->head, memory_order_relaxed) -
               atomic_load_explicit(&r->tail, memory_order_acquire) >=
           RING;
}

static void ring_push(ring *r, const iso_dev_chunk *c)
{
    unsigned h = atomic_load_explicit(&r->head, memory_order_relaxed);
    r->c[h & RING_MASK] = *c;
    atomic_store_explicit(&r->head, h + 1u, memory_order_release);
}

/* Reads source i until it has nothing, its ring is full, or it fails. */
static void read_source(slot *sl)
{
    iso_dev_source *s = atomic_load(&sl->s);
    while (s && !ring_full(sl->r)) {
        iso_dev_chunk c;
        iso_err e;
        iso_err_clear(&e);
        memset(&c, 0, sizeof c);
        int got = iso_dev_source_read(s, INT64_MAX, &c, &e);
        if (got == 0)
            return;
        if (got < 0) { /* the error travels as the GONE chunk's bytes */
            memset(&c, 0, sizeof c);
            c.type = ISO_DEV_CHUNK_GONE;
            c.t_ns = iso_clock_ns();
            size_t n = strnlen(e.msg, sizeof e.msg);
            c.len = (uint16_t)(n < ISO_DEV_CHUNK_MAX ? n : ISO_DEV_CHUNK_MAX);
            memcpy(c.data, e.msg, c.len);
            atomic_store(&sl->s, NULL); /* the tick's again once it takes the GONE */
            ring_push(sl->r, &c);
            return;
        }
        c.type = ISO_DEV_CHUNK_DATA;
        ring_push(sl->r, &c);
    }
}

static void follow_priority(iso_dev__reader *rd)
{
    int want = atomic_load(&rd->priority);
    if (want == atomic_load(&rd->prio_done))
        return;
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = want;
    atomic_store(&rd->prio_errno,
                 pthread_setschedparam(pthread_self(), want ? SCHED_FIFO : SCHED_OTHER, &sp));
    atomic_store(&rd->prio_done, want);
}

static void *reader_main(void *arg)
{
    iso_dev__reader *rd = arg;
    while (!atomic_load(&rd->quit)) {
        follow_priority(rd);
        unsigned asked = atomic_load(&rd->asked);
        struct pollfd pf[ISO_DEV_MAX_SOURCES];
        size_t at[ISO_DEV_MAX_SOURCES], n = 0;
        for (size_t i = 0; i < ISO_DEV_MAX_SOURCES; i++) {
            iso_dev_source *s = atomic_load(&rd->slots[i].s);
            if (!s || ring_full(rd->slots[i].r))
                continue;
            pf[n].fd = iso_dev_source_fd(s);
            pf[n].events = POLLIN;
            pf[n].revents = 0;
            at[n++] = i;
        }
        int wait = asked != atomic_load(&rd->served) ? 0 : LOOK_MS;
        if (n == 0 || poll(pf, (nfds_t)n, wait) <= 0) {
            atomic_store(&rd->served, asked); /* nothing there: all of it was read */
            if (n == 0 && wait)
                iso_clock_sleep_until(iso_clock_ns() + LOOK_MS * 1000000LL);
            continue;
        }
        for (size_t k = 0; k < n; k++)
            if (pf[k].revents)
                read_source(&rd->slots[at[k]]);
    }
    return NULL;
}

int iso_dev__reader_sync(iso_dev__reader *rd, int timeout_ms)
{
    unsigned want = atomic_fetch_add(&rd->asked, 1u) + 1u;
    int64_t end = iso_clock_ns() + (int64_t)timeout_ms * 1000000;
    while ((int)(atomic_load(&rd->served) - want) < 0) {
        if (iso_clock_ns() >= end)
            return 0;
        iso_clock_sleep_until(iso_clock_ns() + 200000);
    }
    return 1;
}

int iso_dev__reader_create(iso_dev__reader **out, iso_err *err)
{
    *out = NULL;
    iso_dev__reader *rd = calloc(1, sizeof *rd);
    if (!rd)
        return iso_err_set(err, ISO_ENOMEM, -1, "device hub: out of memory for its reader");
    atomic_init(&rd->quit, 0);
    atomic_init(&rd->priority, 0);
    atomic_init(&rd->prio_done, 0);
    atomic_init(&rd->prio_errno, 0);
    atomic_init(&rd->asked, 0);
    atomic_init(&rd->served, 0);
    for (size_t i = 0; i < ISO_DEV_MAX_SOURCES; i++)
        atomic_init(&rd->slots[i].s, NULL);
    int rc = iso_thread_start(&rd->thread, reader_main, rd); /* signals stay with the program's */
    if (rc != 0) {
        free(rd);
        return iso_err_set(err, ISO_EIO, -1, "device hub: cannot start its reader thread: %s",
                           strerror(rc));
    }
    *out = rd;
    return ISO_OK;
}

void iso_dev__reader_destroy(iso_dev__reader *rd)
{
    if (!rd)
        return;
    atomic_store(&rd->quit, 1);
    pthread_join(rd->thread, NULL);
    for (size_t i = 0; i < ISO_DEV_MAX_SOURCES; i++)
        free(rd->slots[i].r);
    free(rd);
}

int iso_dev__reader_attach(iso_dev__reader *rd, size_t i, iso_dev_source *s, iso_err *err)
{
    slot *sl = &rd->slots[i];
    if (!sl->r) {
        sl->r = calloc(1, sizeof *sl->r);
        if (!sl->r)
            return iso_err_set(err, ISO_ENOMEM, -1, "device hub: out of memory for a ring");
        atomic_init(&sl->r->head, 0);
        atomic_init(&sl->r->tail, 0);
    }
    atomic_store(&sl->s, s);
    return ISO_OK;
}

int iso_dev__reader_pop(iso_dev__reader *rd, size_t i, iso_dev_chunk *c)
{
    ring *r = rd->slots[i].r;
    if (!r)
        return 0;
    unsigned t = atomic_load_explicit(&r->tail, memory_order_relaxed);
    if (t == atomic_load_explicit(&r->head, memory_order_acquire))
        return 0;
    *c = r->c[t & RING_MASK];
    atomic_store_explicit(&r->tail, t + 1u, memory_order_release);
    return 1;
}

int iso_dev__reader_priority(iso_dev__reader *rd, int priority, iso_err *err)
{
    atomic_store(&rd->priority, priority);
    for (int k = 0; k < 100 && atomic_load(&rd->prio_done) != priority; k++)
        iso_clock_sleep_until(iso_clock_ns() + 1000000);
    int rc = atomic_load(&rd->prio_done) == priority ? atomic_load(&rd->prio_errno) : ETIMEDOUT;
    if (rc != 0)
        return iso_err_set(err, ISO_EIO, -1, "device hub: its reader thread at SCHED_FIFO %d: %s",
                           priority, strerror(rc));
    return ISO_OK;
}
