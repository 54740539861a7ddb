/* common/iso_fd.c -- raw descriptors and TCP (iso_fd.h). */
#include "iso_fd.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <unistd.h>

#include "iso_clock.h"

int iso_fd_nonblock(int fd)
{
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) != 0)
        return -1;
    return fcntl(fd, F_SETFD, FD_CLOEXEC) != 0 ? -1 : 0;
}

int iso_fd_listen_host(const char *host, char *why, size_t cap)
{
    char h[128];
    size_t n = host ? strlen(host) : 0;
    if (n == 0 || n >= sizeof h) {
        snprintf(why, cap, "'%.60s%s' is not a numeric IPv4 or IPv6 address or localhost",
                 host ? host : "", n > 60 ? "..." : "");
        return -1;
    }
    if (n >= 2 && host[0] == '[' && host[n - 1] == ']') {
        memcpy(h, host + 1, n - 2);
        h[n - 2] = '\0';
    } else {
        memcpy(h, host, n + 1);
    }
    if (strcasecmp(h, "localhost") == 0)
        return 1;
    struct addrinfo hints, *ai = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICHOST | AI_PASSIVE;
    if (getaddrinfo(h, NULL, &hints, &ai) != 0 || !ai) {
        snprintf(why, cap, "'%s' is not a numeric IPv4 or IPv6 address or localhost", host);
        return -1;
    }
    int loopback;
    if (ai->ai_family == AF_INET) {
        loopback = (ntohl(((const struct sockaddr_in *)ai->ai_addr)->sin_addr.s_addr) >> 24) == 127;
    } else {
        const struct in6_addr *v6 = &((const struct sockaddr_in6 *)ai->ai_addr)->sin6_addr;
        loopback = IN6_IS_ADDR_V4MAPPED(v6) ? v6->s6_addr[12] == 127 : IN6_IS_ADDR_LOOPBACK(v6);
    }
    freeaddrinfo(ai);
    return loopback;
}

/* Connects one address within timeout_ms; -1 with errno set on failure. */
static int connect_one(const struct addrinfo *ai, int timeout_ms)
{
    int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, ai->ai_protocol);
    if (fd < 0)
        return -1;
    if (connect(fd, ai->ai_addr, ai->ai_addrlen) != 0) {
        int e = errno;
        if (e == EINPROGRESS) {
            struct pollfd p = {fd, POLLOUT, 0};
            int r = poll(&p, 1, timeout_ms < 0 ? 0 : timeout_ms);
            int soerr = 0;
            socklen_t len = sizeof soerr;
            if (r < 0)
                e = errno;
            else if (r == 0)
                e = ETIMEDOUT;
            else if (getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &len) != 0)
                e = errno;
            else
                e = soerr;
        }
        if (e != 0) {
            close(fd);
            errno = e;
            return -1;
        }
    }
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    return fd;
}

int iso_fd_tcp_connect(const char *host, const char *port, int timeout_ms, int *fd, iso_err *err)
{
    *fd = -1;
    struct addrinfo hints, *res = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    int g = getaddrinfo(host, port, &hints, &res);
    if (g != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s:%s: cannot resolve: %s", host, port,
                           gai_strerror(g));
    int e = 0;
    for (struct addrinfo *ai = res; ai && *fd < 0; ai = ai->ai_next) {
        *fd = connect_one(ai, timeout_ms);
        if (*fd < 0)
            e = errno;
    }
    freeaddrinfo(res);
    if (*fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s:%s: cannot connect: %s", host, port, strerror(e));
    return ISO_OK;
}

int iso_fd_read(int fd, const char *what, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
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

int iso_fd_write_all(int fd, const char *what, const uint8_t *buf, size_t n, int timeout_ms,
                     int is_socket, iso_err *err)
{
    if (fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: link is closed", what);
    uint64_t deadline = iso_clock_us() + (uint64_t)(timeout_ms < 0 ? 0 : timeout_ms) * 1000u;
    size_t done = 0;
    while (done < n) {
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
