/* firmware-bridge/link.c -- the iso_link dispatch and the fd helpers the tty
 * and TCP backends share. */
#include <errno.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

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

int iso_fb__fd_read(int fd, const char *what, uint8_t *buf, size_t cap, int timeout_ms,
                    iso_err *err)
{
    if (fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: link is closed", what);
    struct pollfd p = {fd, POLLIN, 0};
    int r = poll(&p, 1, timeout_ms < 0 ? 0 : timeout_ms);
    if (r < 0) {
        if (errno == EINTR)
            return 0;
        return iso_err_set(err, ISO_EIO, -1, "%s: poll: %s", what, strerror(errno));
    }
    if (r == 0)
        return 0;
    ssize_t n = read(fd, buf, cap);
    if (n > 0)
        return (int)n;
    if (n == 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: peer closed the link", what);
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)
        return 0;
    return iso_err_set(err, ISO_EIO, -1, "%s: read: %s", what, strerror(errno));
}

int iso_fb__fd_write(int fd, const char *what, const uint8_t *buf, size_t n, int timeout_ms,
                     int is_socket, iso_err *err)
{
    if (fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: link is closed", what);
    uint64_t deadline = iso_clock_us() + (uint64_t)(timeout_ms < 0 ? 0 : timeout_ms) * 1000u;
    size_t done = 0;
    while (done < n) {
        /* MSG_NOSIGNAL: a vanished peer must be an error here, not SIGPIPE. */
        ssize_t w = is_socket ? send(fd, buf + done, n - done, MSG_NOSIGNAL)
                              : write(fd, buf + done, n - done);
        if (w > 0) {
            done += (size_t)w;
            continue;
        }
        if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
            return iso_err_set(err, ISO_EIO, -1, "%s: write: %s", what, strerror(errno));
        int left = iso_clock_ms_until(deadline);
        if (left == 0)
            return iso_err_set(err, ISO_EIO, -1,
                               "%s: write timed out after %d ms (%zu of %zu bytes)", what,
                               timeout_ms, done, n);
        struct pollfd p = {fd, POLLOUT, 0};
        if (poll(&p, 1, left) < 0 && errno != EINTR)
            return iso_err_set(err, ISO_EIO, -1, "%s: poll: %s", what, strerror(errno));
    }
    return ISO_OK;
}
