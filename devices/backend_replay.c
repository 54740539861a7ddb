/* devices/backend_replay.c -- a recording as a source: its chunks come back
 * at their recorded times through the same decoders as live bytes, and the
 * loop may ask for the next recorded tick to pace itself by the recording. */
#include "internal.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"

#include <stdio.h>
#include <stdlib.h>

typedef struct replay {
    iso_dev_rec_reader *r;
    iso_dev_chunk next;
    int have; /* next holds the record after the last one handed out */
} replay;

static void replay_fill(iso_dev_source *s)
{
    replay *p = s->impl;
    if (!p->have)
        p->have = iso_dev_rec_next(p->r, &p->next, NULL) == 1;
}

int64_t iso_dev_replay_peek(iso_dev_source *s)
{
    replay_fill(s);
    replay *p = s->impl;
    return p->have ? p->next.t_ns : INT64_MAX;
}

static int replay_read(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)err;
    replay *p = s->impl;
    replay_fill(s);
    if (!p->have || p->next.t_ns > until)
        return 0;
    *out = p->next;
    p->have = 0;
    return 1;
}

static void replay_close(iso_dev_source *s)
{
    iso_dev__source_free(s);
}

static const iso_dev_source_ops replay_ops = {"replay", NULL,         replay_read,
                                              NULL,     replay_close, NULL};

int iso_dev_replay_open(iso_dev_rec_reader *r, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    iso_dev_source *s = iso_dev__source_new(&replay_ops, sizeof(replay));
    if (!s) {
        return iso_err_set(err, ISO_ENOMEM, -1, "replay: out of memory");
    }
    replay *p = s->impl;
    p->r = r;
    s->multiplexed = 1;
    snprintf(s->info.name, sizeof s->info.name, "replay");
    *out = s;
    return ISO_OK;
}

const iso_dev_rec_reader *iso_dev_replay_reader(iso_dev_source *s)
{
    return s->ops == &replay_ops ? ((replay *)s->impl)->r : NULL;
}

int64_t iso_dev_replay_next_tick(iso_dev_source *s)
{
    if (s->ops != &replay_ops)
        return INT64_MAX;
    replay *p = s->impl;
    replay_fill(s);
    if (!p->have)
        return INT64_MAX;
    if (p->next.type == ISO_DEV_CHUNK_TICK)
        return p->next.t_ns;
    /* Look ahead on a copy: the reader is a cursor over memory. */
    iso_dev_rec_reader look = *p->r;
    iso_dev_chunk c;
    while (iso_dev_rec_next(&look, &c, NULL) == 1)
        if (c.type == ISO_DEV_CHUNK_TICK)
            return c.t_ns;
    return INT64_MAX;
}
