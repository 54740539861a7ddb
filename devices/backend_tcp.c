/* devices/backend_tcp.c -- a TCP client to a serial-over-network bridge
 * (ser2net, an ESP32 bridge): the same byte stream as a serial line. */
#include "internal.h"
#include "iso_dev_source.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "iso_fd.h"

typedef struct tcp {
    int fd;
} tcp;

static int tcp_fd(iso_dev_source *s)
{
    return ((tcp *)s->impl)->fd;
}

static int tcp_read(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    tcp *t = s->impl;
    ssize_t n = recv(t->fd, out->data, ISO_DEV_CHUNK_MAX, MSG_DONTWAIT);
    if (iso_dev__chunk_read(out, n))
        return 1;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR))
        return 0;
    return iso_err_set(err, ISO_EIO, -1, "%s: %s", s->info.name,
                       n == 0 ? "the bridge closed the connection" : strerror(errno));
}

static void tcp_close(iso_dev_source *s)
{
    tcp *t = s->impl;
    close(t->fd);
    iso_dev__source_free(s);
}

static const iso_dev_source_ops tcp_ops = {"tcp", tcp_fd, tcp_read, NULL, tcp_close, NULL};

int iso_dev_tcp_open(const char *host_port, int timeout_ms, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    char host[256];
    const char *colon = strrchr(host_port, ':');
    if (!colon || colon == host_port || !colon[1] || (size_t)(colon - host_port) >= sizeof host)
        return iso_err_set(err, ISO_EINVAL, -1, "'%s' is not HOST:PORT", host_port);
    memcpy(host, host_port, (size_t)(colon - host_port));
    host[colon - host_port] = 0;
    int fd = -1;
    int rc = iso_fd_tcp_connect(host, colon + 1, timeout_ms, &fd, err);
    if (rc != ISO_OK)
        return rc;
    iso_dev_source *s = iso_dev__source_new(&tcp_ops, sizeof(tcp));
    if (!s) {
        close(fd);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory", host_port);
    }
    tcp *t = s->impl;
    t->fd = fd;
    s->info.kind = ISO_DEV_KIND_SERIAL;
    snprintf(s->info.name, sizeof s->info.name, "tcp:%s", host_port);
    *out = s;
    return ISO_OK;
}
