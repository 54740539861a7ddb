/* controller/loop_recorder.c -- the record button, off the tick.
 *
 * Starting a recording opens a file, allocates the writer's queue and
 * starts its thread; stopping one waits for that thread (up to
 * ISO_DEV_REC_CLOSE_MS for a FIFO's reader). Neither may happen on the
 * tick (docs/realtime.md, "What a tick does not do"), so a thread of the
 * recorder's own does both. The tick and the thread hand the writer back
 * and forth through one atomic state, and the tick only posts a semaphore:
 *
 *   IDLE ──press──> OPENING ──(thread opened it)──> READY ──(next tick
 *   attaches it to the hub)──> IDLE, recording
 *   recording ──press: the tick detaches it──> CLOSING ──(thread closed
 *   it)──> IDLE
 *
 * So the recording starts a tick or two after the press, never before its
 * file is open, and ends at the tick of the press, whole. A press while
 * the thread is busy is said and ignored (a person presses again).
 *
 * Each recording of a run gets a file of its own: the scene's path for the
 * first, then NAME-2.EXT, NAME-3.EXT, ... (the first name not taken), so a
 * second press never overwrites the first recording. */
#define _DEFAULT_SOURCE /* strnlen */
#include "loop_internal.h"

#include <limits.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_thread.h"

enum { REC_IDLE, REC_OPENING, REC_READY, REC_CLOSING };

struct iso_loop__recorder {
    iso_loop *l;
    iso_thread_waker thread;
    _Atomic int state;
    iso_dev_info infos[ISO_DEV_MAX_SOURCES]; /* the tick's, before OPENING */
    size_t n_infos;
    iso_dev_rec_writer w; /* the thread's while OPENING, READY and CLOSING */
    char base[PATH_MAX];  /* the scene's recording path */
    int made;             /* recordings this run has had (the thread's) */
};

/* The path of the run's k-th recording (k from 1): the base for the first,
 * then the base with "-k" before its extension, skipping names taken. */
static void next_path(const char *base, int k, char *out, size_t cap)
{
    if (k <= 1) {
        snprintf(out, cap, "%s", base);
        return;
    }
    const char *slash = strrchr(base, '/'), *dot = strrchr(base, '.');
    if (!dot || (slash && dot < slash) || dot == (slash ? slash + 1 : base))
        dot = base + strlen(base); /* no extension */
    for (;; k++) {
        snprintf(out, cap, "%.*s-%d%s", (int)(dot - base), base, k, dot);
        if (access(out, F_OK) != 0)
            return;
    }
}

static void open_next(iso_loop__recorder *r)
{
    char path[PATH_MAX + 16];
    next_path(r->base, ++r->made, path, sizeof path);
    iso_err e;
    iso_err_clear(&e);
    if (iso_dev_rec_writer_open(&r->w, path, r->infos, r->n_infos, iso_clock_ns(), &e) == ISO_OK) {
        atomic_store(&r->state, REC_READY);
        return;
    }
    r->made--;
    iso_loop_say(r->l, "not recording: %s", e.msg);
    atomic_store(&r->state, REC_IDLE);
}

static void close_it(iso_loop__recorder *r)
{
    char path[sizeof r->w.path];
    long records = r->w.records;
    snprintf(path, sizeof path, "%s", r->w.path);
    iso_err e;
    iso_err_clear(&e);
    if (iso_dev_rec_writer_close(&r->w, &e) != ISO_OK)
        iso_loop_say(r->l, "recording stopped: %s", e.msg);
    else
        iso_loop_say(r->l, "recording stopped: %s, %ld records", path, records);
    atomic_store(&r->state, REC_IDLE);
}

static void *recorder_main(void *arg)
{
    iso_loop__recorder *r = arg;
    for (;;) {
        iso_thread_waker_wait(&r->thread);
        /* a request posted before quit is carried out first: a recording
         * being closed ends whole */
        int st = atomic_load(&r->state);
        if (st == REC_OPENING)
            open_next(r);
        else if (st == REC_CLOSING)
            close_it(r);
        if (iso_thread_waker_quitting(&r->thread))
            return NULL;
    }
}

int iso_loop__recorder_create(iso_loop *l, const char *base, int recording_now,
                              iso_loop__recorder **out, iso_err *err)
{
    *out = NULL;
    iso_loop__recorder *r = calloc(1, sizeof *r);
    if (!r)
        return iso_err_set(err, ISO_ENOMEM, -1, "the record button: out of memory");
    r->l = l;
    snprintf(r->base, sizeof r->base, "%s", base);
    r->made = recording_now ? 1 : 0;
    int e = iso_thread_waker_start(&r->thread, recorder_main, r);
    if (e != 0) {
        free(r);
        return iso_err_set(err, ISO_EIO, -1, "the record button: cannot start its thread: %s",
                           strerror(e));
    }
    *out = r;
    return ISO_OK;
}

void iso_loop__recorder_destroy(iso_loop__recorder *r)
{
    if (!r)
        return;
    iso_thread_waker_stop(&r->thread);
    if (atomic_load(&r->state) == REC_READY) /* opened, never attached: end it whole */
        close_it(r);
    free(r);
}

void iso_loop__recorder_press(iso_loop__recorder *r, iso_dev_hub *hub, int *recording)
{
    int st = atomic_load(&r->state);
    if (st != REC_IDLE) {
        iso_loop_say(r->l, "the recording is still %s: press again in a moment",
                     st == REC_CLOSING ? "being closed" : "being opened");
        return;
    }
    iso_err e;
    iso_err_clear(&e);
    if (*recording) {
        if (iso_dev_hub_record_detach(hub, &r->w, &e)) {
            *recording = 0;
            atomic_store(&r->state, REC_CLOSING);
            iso_thread_waker_post(&r->thread);
        }
        return;
    }
    r->n_infos = iso_dev_hub_infos(hub, r->infos, ISO_DEV_MAX_SOURCES);
    if (r->n_infos > ISO_DEV_MAX_SOURCES)
        r->n_infos = ISO_DEV_MAX_SOURCES;
    atomic_store(&r->state, REC_OPENING);
    iso_thread_waker_post(&r->thread);
}

void iso_loop__recorder_poll(iso_loop__recorder *r, iso_dev_hub *hub, int *recording)
{
    if (atomic_load(&r->state) != REC_READY)
        return;
    iso_err e;
    iso_err_clear(&e);
    if (iso_dev_hub_record_attach(hub, &r->w, &e) == ISO_OK) {
        *recording = 1;
        iso_loop_say(r->l, "recording to %s", r->w.path);
        atomic_store(&r->state, REC_IDLE);
    } else {
        atomic_store(&r->state, REC_CLOSING); /* cannot happen: the hub was not recording */
        iso_thread_waker_post(&r->thread);
    }
}
