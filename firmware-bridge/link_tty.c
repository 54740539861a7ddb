/* firmware-bridge/link_tty.c -- POSIX tty backend: real UARTs, ptys and
 * QEMU's -serial pty. Raw 8N1 without flow control, non-blocking fd. */
#define _DEFAULT_SOURCE /* cfsetspeed rates beyond POSIX's table */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include "internal.h"

typedef struct tty_link {
    iso_link base;
    int fd;
    int baud;
    char path[256];
    char what[280]; /* "tty /dev/ttyUSB0" for messages */
} tty_link;

static speed_t baud_constant(int baud)
{
    switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    default: return 0;
    }
}

static int tty_configure(int fd, int baud, const char *what, iso_err *err)
{
    struct termios t;
    if (tcgetattr(fd, &t) != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: not a terminal: %s", what, strerror(errno));
    cfmakeraw(&t);
    t.c_cflag |= CLOCAL | CREAD;
    t.c_cflag &= ~(tcflag_t)(CSTOPB | PARENB | CRTSCTS);
    t.c_iflag &= ~(tcflag_t)(IXON | IXOFF | IXANY);
    t.c_cc[VMIN] = 0;
    t.c_cc[VTIME] = 0;
    speed_t s = baud_constant(baud);
    if (s && (cfsetispeed(&t, s) != 0 || cfsetospeed(&t, s) != 0))
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot set %d baud: %s", what, baud, strerror(errno));
    if (tcsetattr(fd, TCSANOW, &t) != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: tcsetattr: %s", what, strerror(errno));
    return ISO_OK;
}

static int tty_connect(tty_link *t, iso_err *err)
{
    t->fd = open(t->path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (t->fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: open: %s", t->what, strerror(errno));
    int rc = tty_configure(t->fd, t->baud, t->what, err);
    if (rc != ISO_OK) {
        close(t->fd);
        t->fd = -1;
    }
    return rc;
}

static int tty_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    tty_link *t = (tty_link *)l;
    return iso_fb__fd_read(t->fd, t->what, buf, cap, timeout_ms, err);
}

static int tty_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    tty_link *t = (tty_link *)l;
    return iso_fb__fd_write(t->fd, t->what, buf, n, timeout_ms, 0, err);
}

static int tty_poll_fd(iso_link *l) { return ((tty_link *)l)->fd; }

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

static const iso_link_ops tty_ops = {"tty", tty_read, tty_write, tty_poll_fd, tty_reopen, tty_close};

int iso_link_tty_open(const char *path, int baud, iso_link **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!path || !out)
        return iso_err_set(err, ISO_EINVAL, -1, "tty link: NULL path or out");
    if (strlen(path) >= sizeof ((tty_link *)0)->path)
        return iso_err_set(err, ISO_EINVAL, -1, "tty link: path too long: %.64s...", path);
    if (baud_constant(baud) == 0)
        return iso_err_set(err, ISO_EINVAL, -1, "tty %s: unsupported baud rate %d", path, baud);
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
