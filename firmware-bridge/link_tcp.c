/* firmware-bridge/link_tcp.c -- TCP client backend (QEMU -serial tcp,
 * ser2net, the test proxy). Nagle is off: frames are small and late. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "internal.h"
#include "iso_fd.h"

typedef struct tcp_link {
    iso_link base;
    int fd;
    int port, timeout_ms;
    char host[256];
    char what[300];
} tcp_link;

static int tcp_connect(tcp_link *t, iso_err *err)
{
    char port[16];
    snprintf(port, sizeof port, "%d", t->port);
    return iso_fd_tcp_connect(t->host, port, t->timeout_ms, &t->fd, err);
}

static int tcp_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    tcp_link *t = (tcp_link *)l;
    return iso_fd_read(t->fd, t->what, buf, cap, timeout_ms, err);
}

static int tcp_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    tcp_link *t = (tcp_link *)l;
    return iso_fd_write_all(t->fd, t->what, buf, n, timeout_ms, 1, err);
}

static int tcp_poll_fd(iso_link *l)
{
    return ((tcp_link *)l)->fd;
}

static int tcp_reopen(iso_link *l, iso_err *err)
{
    tcp_link *t = (tcp_link *)l;
    if (t->fd >= 0)
        close(t->fd);
    t->fd = -1;
    return tcp_connect(t, err);
}

static void tcp_close(iso_link *l)
{
    tcp_link *t = (tcp_link *)l;
    if (t->fd >= 0)
        close(t->fd);
    free(t);
}

static const iso_link_ops tcp_ops = {"tcp",       tcp_read,   tcp_write,
                                     tcp_poll_fd, tcp_reopen, tcp_close};

int iso_link_tcp_open(const char *host, int port, int timeout_ms, iso_link **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!host || !out || port <= 0 || port > 65535 || timeout_ms < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "tcp link: bad host, port %d or timeout %d", port,
                           timeout_ms);
    if (strlen(host) >= sizeof((tcp_link *)0)->host)
        return iso_err_set(err, ISO_EINVAL, -1, "tcp link: host name too long");
    tcp_link *t = calloc(1, sizeof *t);
    if (!t)
        return iso_err_set(err, ISO_ENOMEM, -1, "tcp %s:%d: out of memory", host, port);
    t->base.ops = &tcp_ops;
    t->port = port;
    t->timeout_ms = timeout_ms;
    snprintf(t->host, sizeof t->host, "%s", host);
    snprintf(t->what, sizeof t->what, "tcp %s:%d", host, port);
    int rc = tcp_connect(t, err);
    if (rc != ISO_OK) {
        free(t);
        return rc;
    }
    *out = &t->base;
    return ISO_OK;
}
