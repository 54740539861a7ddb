/* devices/source.c -- the source interface's dispatch: every backend
 * (backend_*.c) fills an iso_dev_source with its ops, and these calls go
 * through them. */
#include "iso_dev_source.h"

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
