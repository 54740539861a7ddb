/* devices/source.c -- the source interface's dispatch: every backend
 * (backend_*.c) fills an iso_dev_source with its ops, and these calls go
 * through them. */
#include "iso_dev_source.h"

#include <stddef.h>
#include <stdlib.h>

#include "internal.h"

/* The backend's struct starts at the first offset after the source that
 * any type may start at. */
#define IMPL_OFFSET                                                                                \
    ((sizeof(iso_dev_source) + _Alignof(max_align_t) - 1) / _Alignof(max_align_t) *                \
     _Alignof(max_align_t))

iso_dev_source *iso_dev__source_new(const iso_dev_source_ops *ops, size_t impl_size)
{
    iso_dev_source *s = calloc(1, IMPL_OFFSET + impl_size);
    if (!s)
        return NULL;
    s->ops = ops;
    s->impl = (char *)s + IMPL_OFFSET;
    return s;
}

void iso_dev__source_free(iso_dev_source *s)
{
    free(s);
}

int iso_dev_source_fd(iso_dev_source *s)
{
    return s && s->ops->fd ? s->ops->fd(s) : -1;
}

int iso_dev_source_read(iso_dev_source *s, int64_t until_ns, iso_dev_chunk *out, iso_err *err)
{
    return s->ops->read(s, until_ns, out, err);
}

void iso_dev_source_close(iso_dev_source *s)
{
    if (!s)
        return;
    s->ops->close(s);
}
