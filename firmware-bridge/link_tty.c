/* firmware-bridge/link_tty.c -- POSIX tty backend: real UARTs, ptys and
 * QEMU's -serial pty. Raw 8N1 without flow control, non-blocking fd. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "internal.h"
#include "iso_fd.h"
#include "iso_tty.h"

typedef struct tty_link {
    iso_link base;
    int fd;
    int baud;
    char path[256];
    char what[280]; /* "tty /dev/ttyUSB0" for messages */
} tty_link;

/* Opening and raw configuration are common/iso_tty.c's, so a port behaves
 * the same whether it feeds an input source or this link. */
static int tty_connect(tty_link *t, iso_err *err)
{
    if (t->baud <= 0)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: baud rate %d is not positive", t->what,
                           t->baud);
    return iso_tty_open_raw(t->path, (uint32_t)t->baud, &t->fd, err);
}

static int tty_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    tty_link *t = (tty_link *)l;
    return iso_fd_read(t->fd, t->what, buf, cap, timeout_ms, err);
}

static int tty_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    tty_link *t = (tty_link *)l;
    return iso_fd_write_all(t->fd, t->what, buf, n, timeout_ms, 0, err);
}

static int tty_poll_fd(iso_link *l)
{
    return ((tty_link *)l)->fd;
}

static int tty_reopen(iso_link *l, iso_err *err)
{
    tty_link *t = (tty_link *)l;
    if (t->fd >= 0)
        close(t->fd);
    t->fd = -1;
    return tty_connect(t, err);
}

static void tty_close(iso_link *l)
{
    tty_link *t = (tty_link *)l;
    if (t->fd >= 0)
        close(t->fd);
    free(t);
}

static const iso_link_ops tty_ops = {"tty",       tty_read,   tty_write,
                                     tty_poll_fd, tty_reopen, tty_close};

int iso_link_tty_open(const char *path, int baud, iso_link **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!path || !out)
        return iso_err_set(err, ISO_EINVAL, -1, "tty link: NULL path or out");
    if (strlen(path) >= sizeof((tty_link *)0)->path)
        return iso_err_set(err, ISO_EINVAL, -1, "tty link: path too long: %.64s...", path);
    tty_link *t = calloc(1, sizeof *t);
    if (!t)
        return iso_err_set(err, ISO_ENOMEM, -1, "tty %s: out of memory", path);
    t->base.ops = &tty_ops;
    t->baud = baud;
    snprintf(t->path, sizeof t->path, "%s", path);
    snprintf(t->what, sizeof t->what, "tty %s", path);
    int rc = tty_connect(t, err);
    if (rc != ISO_OK) {
        free(t);
        return rc;
    }
    *out = &t->base;
    return ISO_OK;
}
