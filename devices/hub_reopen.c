/* devices/hub_reopen.c -- opening gone devices again, and closing the ones
 * that went, on a thread of the hub's own.
 *
 * A reopen is a device open: a path lookup, an open(2), ioctls, a USB
 * enumeration, the source's allocations; a close frees them. Neither may
 * happen on the tick (docs/realtime.md, "What a tick does not do"), and a
 * device that is slow to come back (a hub enumerating, a Bluetooth
 * receiver) would stall the loop for as long. So the tick only asks, and
 * takes the answer on a later tick: each source has one slot whose atomic
 * state goes IDLE -> ASKED (the tick) -> ANSWERED (the thread, with the
 * source or NULL) -> IDLE (the tick took it). The source's info and
 * reopen function stay as they are while it is gone (the hub changes them
 * only at add). A gone source's old handle is handed over to be closed the
 * same way. The thread runs at normal priority with every signal blocked
 * (iso_thread.h). */
#include "internal.h"
#include "iso_clock.h"
#include "iso_dev_hub.h"
#include "iso_dev_source.h"
#include "iso_thread.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

enum { SLOT_IDLE, SLOT_ASKED, SLOT_ANSWERED };

typedef struct reopen_slot {
    _Atomic int state;
    iso_dev_reopen_fn fn; /* the tick's, while ASKED */
    void *ctx;
    const iso_dev_info *info;
    iso_dev_source *back;           /* the thread's answer, while ANSWERED */
    _Atomic(iso_dev_source *) dead; /* a gone source's handle, to close */
} reopen_slot;

struct iso_dev__reopener {
    reopen_slot slot[ISO_DEV_MAX_SOURCES];
    iso_thread_waker w;
    _Atomic int closing; /* handles taken from `dead` and not yet closed */
};

static void *reopener_main(void *arg)
{
    iso_dev__reopener *r = arg;
    for (;;) {
        iso_thread_waker_wait(&r->w);
        for (size_t i = 0; i < ISO_DEV_MAX_SOURCES; i++) {
            reopen_slot *q = &r->slot[i];
            /* the state first: an ask seen here came after its source's
             * handle was handed over, so that handle is closed before the
             * device is opened again (an exclusive open, spnav's one
             * connection) */
            int st = atomic_load(&q->state);
            atomic_fetch_add(&r->closing, 1);
            iso_dev_source_close(atomic_exchange(&q->dead, NULL));
            atomic_fetch_sub(&r->closing, 1);
            if (iso_thread_waker_quitting(&r->w) || st != SLOT_ASKED)
                continue;
            iso_err e;
            iso_err_clear(&e);
            iso_dev_source *back = NULL;
            if (q->fn(q->ctx, q->info, &back, &e) != ISO_OK)
                back = NULL;
            q->back = back;
            atomic_store(&q->state, SLOT_ANSWERED);
        }
        if (iso_thread_waker_quitting(&r->w))
            return NULL;
    }
}

int iso_dev__reopener_create(iso_dev__reopener **out, iso_err *err)
{
    iso_dev__reopener *r = calloc(1, sizeof *r);
    if (!r)
        return iso_err_set(err, ISO_ENOMEM, -1, "device hub: out of memory");
    int e = iso_thread_waker_start(&r->w, reopener_main, r);
    if (e != 0) {
        free(r);
        return iso_err_set(err, ISO_EIO, -1,
                           "device hub: cannot start the thread that reopens devices: %s",
                           strerror(e));
    }
    *out = r;
    return ISO_OK;
}

void iso_dev__reopener_destroy(iso_dev__reopener *r)
{
    if (!r)
        return;
    iso_thread_waker_stop(&r->w); /* a reopen under way finishes first */
    for (size_t i = 0; i < ISO_DEV_MAX_SOURCES; i++) {
        reopen_slot *q = &r->slot[i];
        iso_dev_source_close(atomic_exchange(&q->dead, NULL));
        if (atomic_load(&q->state) == SLOT_ANSWERED)
            iso_dev_source_close(q->back);
    }
    free(r);
}

int iso_dev__reopener_ask(iso_dev__reopener *r, size_t i, iso_dev_reopen_fn fn, void *ctx,
                          const iso_dev_info *info)
{
    reopen_slot *q = &r->slot[i];
    if (atomic_load(&q->state) != SLOT_IDLE)
        return 0;
    q->fn = fn;
    q->ctx = ctx;
    q->info = info;
    atomic_store(&q->state, SLOT_ASKED);
    iso_thread_waker_post(&r->w);
    return 1;
}

int iso_dev__reopener_take(iso_dev__reopener *r, size_t i, iso_dev_source **back)
{
    reopen_slot *q = &r->slot[i];
    if (atomic_load(&q->state) != SLOT_ANSWERED)
        return 0;
    *back = q->back;
    q->back = NULL;
    atomic_store(&q->state, SLOT_IDLE);
    return 1;
}

int iso_dev__reopener_close(iso_dev__reopener *r, size_t i, iso_dev_source *s)
{
    iso_dev_source *expected = NULL;
    if (!atomic_compare_exchange_strong(&r->slot[i].dead, &expected, s))
        return 0; /* the last one handed over is not picked up yet: the caller closes this */
    iso_thread_waker_post(&r->w);
    return 1;
}

int iso_dev__reopener_sync(iso_dev__reopener *r, int timeout_ms)
{
    for (int waited = 0;; waited++) {
        int busy = atomic_load(&r->closing) != 0;
        for (size_t i = 0; i < ISO_DEV_MAX_SOURCES; i++)
            busy |= atomic_load(&r->slot[i].state) == SLOT_ASKED ||
                    atomic_load(&r->slot[i].dead) != NULL;
        if (!busy)
            return 1;
        if (waited >= timeout_ms)
            return 0;
        iso_clock_sleep_until(iso_clock_ns() + 1000000);
    }
}
