/* firmware-bridge/link_tcp.c -- TCP client backend (QEMU -serial tcp,
 * ser2net, the test proxy). Nagle is off: frames are small and late. */
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "internal.h"

typedef struct tcp_link {
    iso_link base;
    int fd;
    int port, timeout_ms;
    char host[256];
    char what[300];
} tcp_link;

/* Connects one address with a timeout: a non-blocking connect, then poll. */
static int connect_one(const struct addrinfo *ai, int timeout_ms)
{
    int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, ai->ai_protocol);
    if (fd < 0)
        return -1;
    if (connect(fd, ai->ai_addr, ai->ai_addrlen) != 0) {
        if (errno != EINPROGRESS) {
            int e = errno;
            close(fd);
            errno = e;
            return -1;
        }
        struct pollfd p = {fd, POLLOUT, 0};
        int r = poll(&p, 1, timeout_ms);
        int soerr = 0;
        socklen_t len = sizeof soerr;
        if (r <= 0 || getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &len) != 0 || soerr != 0) {
            close(fd);
            errno = r == 0 ? ETIMEDOUT : soerr ? soerr : errno;
            return -1;
        }
    }
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    return fd;
}

static int tcp_connect(tcp_link *t, iso_err *err)
{
    struct addrinfo hints, *res = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    char port[16];
    snprintf(port, sizeof port, "%d", t->port);
    int g = getaddrinfo(t->host, port, &hints, &res);
    if (g != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot resolve: %s", t->what, gai_strerror(g));
    int e = 0;
    t->fd = -1;
    for (struct addrinfo *ai = res; ai && t->fd < 0; ai = ai->ai_next) {
        t->fd = connect_one(ai, t->timeout_ms);
        if (t->fd < 0)
            e = errno;
    }
    freeaddrinfo(res);
    if (t->fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: connect: %s", t->what, strerror(e));
    return ISO_OK;
}

static int tcp_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    tcp_link *t = (tcp_link *)l;
    return iso_fb__fd_read(t->fd, t->what, buf, cap, timeout_ms, err);
}

static int tcp_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    tcp_link *t = (tcp_link *)l;
    return iso_fb__fd_write(t->fd, t->what, buf, n, timeout_ms, 1, err);
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
