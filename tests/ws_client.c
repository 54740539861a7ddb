/* tests/ws_client.c -- see ws_client.h. */
#include "ws_client.h"
#include "testutil.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

int iso_test_connect(int family, int port, int rcvbuf)
{
    int fd = socket(family, SOCK_STREAM, 0);
    if (fd < 0)
        return -1;
    struct timeval tv = {5, 0};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    if (rcvbuf)
        setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_storage ss;
    memset(&ss, 0, sizeof ss);
    socklen_t sl;
    if (family == AF_INET6) {
        struct sockaddr_in6 *a = (struct sockaddr_in6 *)&ss;
        a->sin6_family = AF_INET6;
        a->sin6_port = htons((unsigned short)port);
        a->sin6_addr = in6addr_loopback;
        sl = sizeof *a;
    } else {
        struct sockaddr_in *a = (struct sockaddr_in *)&ss;
        a->sin_family = AF_INET;
        a->sin_port = htons((unsigned short)port);
        a->sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        sl = sizeof *a;
    }
    if (connect(fd, (struct sockaddr *)&ss, sl) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

void iso_test_send_all(int fd, const char *s)
{
    size_t n = strlen(s);
    while (n) {
        ssize_t w = write(fd, s, n);
        assert_true(w > 0);
        s += w;
        n -= (size_t)w;
    }
}

int iso_test_read_head(int fd, char *buf, size_t cap)
{
    size_t n = 0;
    while (n < cap - 1 && !(n >= 4 && memcmp(buf + n - 4, "\r\n\r\n", 4) == 0)) {
        ssize_t r = read(fd, buf + n, 1);
        if (r <= 0)
            break;
        n++;
    }
    buf[n] = 0;
    return n > 12 ? atoi(buf + 9) : -1;
}

int iso_test_ws_open(int family, int port, const char *host, const char *extra, int rcvbuf,
                     int *status)
{
    int fd = iso_test_connect(family, port, rcvbuf);
    assert_true(fd >= 0);
    char req[1024];
    snprintf(req, sizeof req,
             "GET /ws HTTP/1.1\r\nHost: %s\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n%s\r\n",
             host, extra);
    iso_test_send_all(fd, req);
    char head[2048];
    *status = iso_test_read_head(fd, head, sizeof head);
    return fd;
}

static int read_n(int fd, unsigned char *p, size_t n)
{
    while (n) {
        ssize_t k = read(fd, p, n);
        if (k <= 0)
            return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

static void *reader_main(void *arg)
{
    iso_test_ws_reader *r = arg;
    for (;;) {
        unsigned char h[10];
        if (read_n(r->fd, h, 2) != 0)
            break;
        uint64_t n = h[1] & 0x7f;
        size_t ext = n == 126 ? 2 : n == 127 ? 8 : 0;
        if (ext && read_n(r->fd, h + 2, ext) != 0)
            break;
        if (ext) {
            n = 0;
            for (size_t i = 0; i < ext; i++)
                n = n << 8 | h[2 + i];
        }
        unsigned char buf[65536], first[16];
        uint64_t left = n;
        size_t at = 0;
        while (left) {
            ssize_t k = read(r->fd, buf, left < sizeof buf ? (size_t)left : sizeof buf);
            if (k <= 0)
                return NULL;
            for (ssize_t i = 0; i < k && at < sizeof first; i++)
                first[at++] = buf[i];
            left -= (uint64_t)k;
        }
        if ((h[0] & 0x0f) == 2 && at == sizeof first) {
            double t;
            memcpy(&t, first + 8, 8);
            if (t <= r->last_tick)
                r->failed = 1;
            r->last_tick = t;
            r->frames++;
        }
    }
    return NULL;
}

void iso_test_ws_reader_start(iso_test_ws_reader *r, int fd)
{
    r->fd = fd;
    r->frames = 0;
    r->last_tick = -1;
    r->failed = 0;
    assert_int_equal(pthread_create(&r->th, NULL, reader_main, r), 0);
}

void iso_test_ws_reader_stop(iso_test_ws_reader *r)
{
    shutdown(r->fd, SHUT_RDWR);
    pthread_join(r->th, NULL);
    close(r->fd);
}
