/* devices/backend_tty.c -- a POSIX tty in raw mode: pseudo-terminals,
 * emulators, and any serial adapter the kernel exposes as a tty. Debian 12's
 * libserialport (0.1.1) cannot open a pty, so this is the path tests take. */
#include "internal.h"
#include "iso_dev_source.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include "iso_tty.h"

typedef struct tty {
    int fd;
} tty;

static int tty_fd(iso_dev_source *s)
{
    return ((tty *)s->impl)->fd;
}

static int tty_read(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    tty *t = s->impl;
    ssize_t n = read(t->fd, out->data, ISO_DEV_CHUNK_MAX);
    if (iso_dev__chunk_read(out, n))
        return 1;
    if (n < 0 && (errno == EAGAIN || errno == EINTR))
        return 0;
    if (n == 0) {
        /* Raw mode with VMIN = VTIME = 0 reads 0 bytes when there are none;
         * only a hang-up on the descriptor says the device is gone. */
        struct pollfd p = {t->fd, POLLIN, 0};
        if (poll(&p, 1, 0) == 1 && (p.revents & (POLLHUP | POLLERR | POLLNVAL)))
            return iso_err_set(err, ISO_EIO, -1, "%s: the other end hung up", s->info.name);
        return 0;
    }
    /* EIO: a pty whose master closed, an unplugged adapter. */
    return iso_err_set(err, ISO_EIO, -1, "%s: %s", s->info.name, strerror(errno));
}

static void tty_close(iso_dev_source *s)
{
    tty *t = s->impl;
    close(t->fd);
    iso_dev__source_free(s);
}

static const iso_dev_source_ops tty_ops = {"tty", tty_fd, tty_read, NULL, tty_close, NULL};

int iso_dev_tty_open(const char *path, uint32_t baud, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    int fd;
    int rc = iso_tty_open_raw(path, baud, &fd, err);
    if (rc != ISO_OK)
        return rc;
    iso_dev_source *s = iso_dev__source_new(&tty_ops, sizeof(tty));
    if (!s) {
        close(fd);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory", path);
    }
    tty *t = s->impl;
    t->fd = fd;
    iso_dev__serial_info(&s->info, baud);
    snprintf(s->info.name, sizeof s->info.name, "%s", path);
    *out = s;
    return ISO_OK;
}
