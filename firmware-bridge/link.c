/* firmware-bridge/link.c -- the iso_link dispatch. The tty and TCP
 * backends read and write through common/iso_fd.h. */
#include "internal.h"

int iso_link_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    if (!l || !buf)
        return iso_err_set(err, ISO_EINVAL, -1, "link read: NULL argument");
    return l->ops->read(l, buf, cap, timeout_ms, err);
}

int iso_link_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    if (!l || (!buf && n))
        return iso_err_set(err, ISO_EINVAL, -1, "link write: NULL argument");
    return l->ops->write(l, buf, n, timeout_ms, err);
}

int iso_link_poll_fd(iso_link *l)
{
    return l && l->ops->poll_fd ? l->ops->poll_fd(l) : -1;
}

int iso_link_reopen(iso_link *l, iso_err *err)
{
    if (!l)
        return iso_err_set(err, ISO_EINVAL, -1, "link reopen: NULL link");
    if (!l->ops->reopen)
        return iso_err_set(err, ISO_ENOTSUP, -1, "%s link: cannot reopen", l->ops->name);
    return l->ops->reopen(l, err);
}

void iso_link_close(iso_link *l)
{
    if (l)
        l->ops->close(l);
}
