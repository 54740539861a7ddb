/* tests/ws_client.c -- see ws_client.h. */
#include "ws_client.h"
#include "testutil.h"

#include "iso_display.h"

#include <arpa/inet.h>
#include <math.h>
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

void iso_test_ws_send(int fd, int fin, int opcode, const void *payload, size_t len)
{
    unsigned char *f = malloc(len + 14);
    assert_non_null(f);
    size_t n = 0;
    f[n++] = (unsigned char)((fin ? 0x80 : 0) | opcode);
    if (len < 126) {
        f[n++] = (unsigned char)(0x80 | len);
    } else if (len < 65536) {
        f[n++] = 0x80 | 126;
        f[n++] = (unsigned char)(len >> 8);
        f[n++] = (unsigned char)len;
    } else {
        f[n++] = 0x80 | 127;
        for (int i = 7; i >= 0; i--)
            f[n++] = (unsigned char)((uint64_t)len >> (8 * i));
    }
    static const unsigned char mask[4] = {0x37, 0xfa, 0x21, 0x3d};
    memcpy(f + n, mask, 4);
    n += 4;
    for (size_t i = 0; i < len; i++)
        f[n++] = ((const unsigned char *)payload)[i] ^ mask[i & 3];
    size_t off = 0;
    while (off < n) {
        ssize_t w = send(fd, f + off, n - off, MSG_NOSIGNAL);
        if (w <= 0)
            break; /* the server may have closed already: the test reads why */
        off += (size_t)w;
    }
    free(f);
}

int iso_test_ws_recv(int fd, unsigned char **payload, size_t *len)
{
    unsigned char h[10];
    *payload = NULL;
    if (read_n(fd, h, 2) != 0)
        return -1;
    uint64_t n = h[1] & 0x7f;
    size_t ext = n == 126 ? 2 : n == 127 ? 8 : 0;
    if (ext && read_n(fd, h + 2, ext) != 0)
        return -1;
    if (ext) {
        n = 0;
        for (size_t i = 0; i < ext; i++)
            n = n << 8 | h[2 + i];
    }
    if (n > (1u << 26))
        return -1;
    *payload = malloc((size_t)n + 1);
    assert_non_null(*payload);
    if (read_n(fd, *payload, (size_t)n) != 0) {
        free(*payload);
        *payload = NULL;
        return -1;
    }
    (*payload)[n] = 0;
    *len = (size_t)n;
    return h[0] & 0x0f;
}

int iso_test_ws_close_status(int fd, int *pongs)
{
    for (;;) {
        unsigned char *p;
        size_t n;
        int op = iso_test_ws_recv(fd, &p, &n);
        if (op < 0)
            return -1;
        if (op == 10 && pongs)
            (*pongs)++;
        int st = op == 8 ? (n >= 2 ? p[0] << 8 | p[1] : 1005) : 0;
        free(p);
        if (op == 8)
            return st;
    }
}

int iso_test_ws_viewer(int port, const char *extra)
{
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    int st;
    int fd = iso_test_ws_open(AF_INET, port, host, extra ? extra : "", 0, &st);
    if (st != 101) {
        close(fd);
        return -1;
    }
    for (int i = 0; i < 2; i++) { /* the topology (binary), then the control state */
        unsigned char *p;
        size_t n;
        if (iso_test_ws_recv(fd, &p, &n) != 2 - i) {
            free(p);
            close(fd);
            return -1;
        }
        free(p);
    }
    return fd;
}

/* The topology's header, when msg is a whole one: its JSON's length and
 * the vertex count; 0 if not. */
static int topology_head(const unsigned char *msg, size_t len, size_t *json, size_t *nv)
{
    uint32_t h[4];
    if (!msg || len < sizeof h)
        return 0;
    memcpy(h, msg, sizeof h);
    *json = h[3];
    *nv = h[1];
    return h[0] == ISO_DISPLAY_TOPOLOGY_MAGIC && len == ISO_DISPLAY_TOPOLOGY_HEADER + (size_t)h[3] +
                                                            13 * (size_t)h[1] + 12 * (size_t)h[2];
}

char *iso_test_topology_json(const unsigned char *msg, size_t len)
{
    size_t json, nv;
    if (!topology_head(msg, len, &json, &nv))
        return NULL;
    return strndup((const char *)msg + ISO_DISPLAY_TOPOLOGY_HEADER, json);
}

double iso_test_topology_diagonal(const unsigned char *msg, size_t len)
{
    size_t json, nv;
    if (!topology_head(msg, len, &json, &nv))
        return NAN;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    const unsigned char *at = msg + ISO_DISPLAY_TOPOLOGY_HEADER + json;
    for (size_t i = 0; i < 3 * nv; i++, at += 4) {
        float f;
        memcpy(&f, at, 4);
        lo[i % 3] = fmin(lo[i % 3], f);
        hi[i % 3] = fmax(hi[i % 3], f);
    }
    return sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
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
        if ((h[0] & 0x0f) == 1)
            atomic_fetch_add(&r->text_bytes, (long)n);
        uint32_t magic = 0;
        if (at >= 4)
            memcpy(&magic, first, 4);
        if ((h[0] & 0x0f) == 2 && magic == ISO_DISPLAY_TOPOLOGY_MAGIC)
            atomic_fetch_add(&r->topology_bytes, (long)n);
        else if ((h[0] & 0x0f) == 2 && at == sizeof first) {
            double t;
            memcpy(&t, first + 8, 8);
            if (t <= r->last_tick)
                r->failed = 1;
            r->last_tick = t;
            atomic_fetch_add(&r->frames, 1);
            atomic_fetch_add(&r->bytes, (long)n);
        }
    }
    return NULL;
}

void iso_test_ws_reader_start(iso_test_ws_reader *r, int fd)
{
    r->fd = fd;
    atomic_init(&r->frames, 0);
    atomic_init(&r->bytes, 0);
    atomic_init(&r->text_bytes, 0);
    atomic_init(&r->topology_bytes, 0);
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
