/* devices/backend_view.c -- the browser view as a source (iso_dev_view.h):
 * a bounded queue that the view's server fills from its own thread and the
 * hub drains each tick, and an e-stop level set the moment a page's STOP
 * arrives.
 *
 * The queue is a ring of whole chunks under a mutex held only for a copy:
 * the server never waits on the loop, the loop never waits on a socket. Its
 * last ISO_VIEW_RESERVED slots take no TARGET, so a page that floods
 * targets (or a loop stalled long enough to fill the ring) cannot crowd out
 * a STOP, a grant or the end of a control. */
#include "internal.h"
#include "iso_dev_source.h"
#include "iso_dev_view.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ISO_VIEW_QUEUE 256u
#define ISO_VIEW_RESERVED 32u

typedef struct view_src {
    pthread_mutex_t mu;
    iso_dev_chunk q[ISO_VIEW_QUEUE];
    size_t head, n;
    atomic_uint dropped;
    atomic_int estop; /* 1 from a STOP's arrival to an UNSTOP's */
} view_src;

static int view_read(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)err;
    view_src *v = s->impl;
    int got = 0;
    pthread_mutex_lock(&v->mu);
    if (v->n && v->q[v->head].t_ns <= until) {
        *out = v->q[v->head];
        v->head = (v->head + 1) % ISO_VIEW_QUEUE;
        v->n--;
        got = 1;
    }
    pthread_mutex_unlock(&v->mu);
    return got;
}

static int view_estop_level(iso_dev_source *s)
{
    return atomic_load(&((view_src *)s->impl)->estop);
}

static void view_close(iso_dev_source *s)
{
    view_src *v = s->impl;
    pthread_mutex_destroy(&v->mu);
    iso_dev__source_free(s);
}

static const iso_dev_source_ops view_ops = {"view", NULL,       view_read,
                                            NULL,   view_close, view_estop_level};

int iso_dev_is_view(const iso_dev_source *s)
{
    return s && s->ops == &view_ops;
}

int iso_dev_view_open(const char *name, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    iso_dev_source *s = iso_dev__source_new(&view_ops, sizeof(view_src));
    if (!s) {
        return iso_err_set(err, ISO_ENOMEM, -1, "view device: out of memory");
    }
    view_src *v = s->impl;
    /* The view's server thread pushes under it and the tick reads under
     * it: a server thread holding it runs at the tick's priority until it
     * lets go, so a busy machine cannot hold the tick up through it. */
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&v->mu, &ma);
    pthread_mutexattr_destroy(&ma);
    atomic_init(&v->dropped, 0);
    atomic_init(&v->estop, 0);
    s->info.kind = ISO_DEV_KIND_VIEW;
    snprintf(s->info.name, sizeof s->info.name, "%s", name && name[0] ? name : "browser");
    snprintf(s->detail, sizeof s->detail, "the live view's pages");
    *out = s;
    return ISO_OK;
}

int iso_dev_view_push(iso_dev_source *s, int what, uint32_t conn, const void *msg, size_t len)
{
    if (!iso_dev_is_view(s) || (len && !msg) || len > ISO_DEV_VIEW_MSG_MAX ||
        (what != ISO_DEV_VIEW_MSG && what != ISO_DEV_VIEW_GRANT && what != ISO_DEV_VIEW_END))
        return ISO_EINVAL;
    view_src *v = s->impl;
    const uint8_t *m = msg;
    int type = what == ISO_DEV_VIEW_MSG && len >= 2 ? m[1] : 0;
    /* the stop acts now, for the actuators' sender; the chunk follows for the tick */
    if (type == ISO_DEV_VIEW_STOP)
        atomic_store(&v->estop, 1);
    else if (type == ISO_DEV_VIEW_UNSTOP)
        atomic_store(&v->estop, 0);
    iso_dev_chunk c;
    memset(&c, 0, sizeof c);
    c.t_ns = iso_clock_ns();
    c.type = ISO_DEV_CHUNK_DATA;
    c.data[0] = (uint8_t)what;
    for (int i = 0; i < 4; i++)
        c.data[1 + i] = (uint8_t)(conn >> (8 * i));
    if (len)
        memcpy(c.data + ISO_DEV_VIEW_ENVELOPE, msg, len);
    c.len = (uint16_t)(ISO_DEV_VIEW_ENVELOPE + len);
    size_t room = type == ISO_DEV_VIEW_TARGET ? ISO_VIEW_QUEUE - ISO_VIEW_RESERVED : ISO_VIEW_QUEUE;
    int rc = ISO_OK;
    pthread_mutex_lock(&v->mu);
    if (v->n < room) {
        v->q[(v->head + v->n) % ISO_VIEW_QUEUE] = c;
        v->n++;
    } else {
        rc = ISO_ENOMEM;
    }
    pthread_mutex_unlock(&v->mu);
    if (rc != ISO_OK)
        atomic_fetch_add(&v->dropped, 1);
    return rc;
}

uint32_t iso_dev_view_dropped(iso_dev_source *s)
{
    return iso_dev_is_view(s) ? atomic_load(&((view_src *)s->impl)->dropped) : 0;
}
