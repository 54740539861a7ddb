/* devices/backend_fake.c -- the scripted fake source that tests drive:
 * chunks pushed with their times come back from read once the tick's time
 * reaches them, a pushed "gone" reads as an unplug, and the e-stop level
 * and the writes to the device's output line are the test's to set and see. */
#include "internal.h"
#include "iso_dev_source.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

typedef struct fake_item {
    int64_t t;
    int gone;
    uint16_t len;
    uint8_t data[ISO_DEV_CHUNK_MAX];
} fake_item;

typedef struct fake {
    fake_item *q;
    size_t n, cap, next;
    int writes, last_level;
    atomic_int estop; /* iso_dev_fake_set_estop; ISO_ENOTSUP until then */
} fake;

static int fake_read(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    fake *f = s->impl;
    if (f->next >= f->n || f->q[f->next].t > until)
        return 0;
    fake_item *it = &f->q[f->next++];
    if (it->gone)
        return iso_err_set(err, ISO_EIO, -1, "%s: device unplugged (fake)", s->info.name);
    memset(out, 0, sizeof *out);
    out->t_ns = it->t;
    out->type = ISO_DEV_CHUNK_DATA;
    out->len = it->len;
    memcpy(out->data, it->data, it->len);
    return 1;
}

static int fake_write_level(iso_dev_source *s, int level, iso_err *err)
{
    (void)err;
    fake *f = s->impl;
    f->writes++;
    f->last_level = level;
    return ISO_OK;
}

static void fake_close(iso_dev_source *s)
{
    fake *f = s->impl;
    free(f->q);
    iso_dev__source_free(s);
}

static int fake_estop_level(iso_dev_source *s)
{
    return atomic_load(&((fake *)s->impl)->estop);
}

static const iso_dev_source_ops fake_ops = {"fake",           NULL,       fake_read,
                                            fake_write_level, fake_close, fake_estop_level};

void iso_dev_fake_set_estop(iso_dev_source *s, int level)
{
    atomic_store(&((fake *)s->impl)->estop, level);
}

int iso_dev_fake_open(const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    iso_dev_source *s = iso_dev__source_new(&fake_ops, sizeof(fake));
    if (!s) {
        return iso_err_set(err, ISO_ENOMEM, -1, "fake source: out of memory");
    }
    fake *f = s->impl;
    atomic_init(&f->estop, ISO_ENOTSUP);
    s->info = *info;
    *out = s;
    return ISO_OK;
}

static fake_item *fake_add(iso_dev_source *s, int64_t t)
{
    fake *f = s->impl;
    if (f->n == f->cap) {
        size_t nc = f->cap ? 2 * f->cap : 16;
        fake_item *q = realloc(f->q, nc * sizeof *q);
        if (!q)
            return NULL;
        f->q = q;
        f->cap = nc;
    }
    fake_item *it = &f->q[f->n++];
    memset(it, 0, sizeof *it);
    it->t = t;
    return it;
}

int iso_dev_fake_push(iso_dev_source *s, int64_t t_ns, const void *data, size_t len)
{
    if (len > ISO_DEV_CHUNK_MAX)
        return ISO_EINVAL;
    fake_item *it = fake_add(s, t_ns);
    if (!it)
        return ISO_ENOMEM;
    it->len = (uint16_t)len;
    if (len)
        memcpy(it->data, data, len);
    return ISO_OK;
}

int iso_dev_fake_push_gone(iso_dev_source *s, int64_t t_ns)
{
    fake_item *it = fake_add(s, t_ns);
    if (!it)
        return ISO_ENOMEM;
    it->gone = 1;
    return ISO_OK;
}

int iso_dev_fake_writes(iso_dev_source *s, int *last_level)
{
    fake *f = s->impl;
    if (last_level)
        *last_level = f->last_level;
    return f->writes;
}
