/* view/display_server.c -- the live view's server: one thread, one poll()
 * loop, non-blocking sockets, a fixed table of connections.
 *
 * Why not civetweb, which served this before: Debian 12's civetweb 1.15 is
 * built without IPv6, spends a worker thread per WebSocket (eight browsers
 * took every thread), allocates whatever payload a frame header announces,
 * and gives its threads a 100 KiB stack with no option to change it. What
 * the view needs of HTTP is small: GET and HEAD of five fixed paths and one
 * WebSocket that only sends. Doing that here makes every bound in
 * iso_display.h a line of this file.
 *
 * A connection is a request being read, a response being written, a
 * response written and lingering for the peer's close, or a viewer. A
 * viewer's output is at most one message: the handshake answer, then the
 * topology, then frames; when a message is done and a newer frame was
 * published, that frame is copied out and becomes the next message. */
#include "display_internal.h"
#include "iso_clock.h"
#include "iso_fd.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

#define LINGER_MS 1000 /* how long a finished response waits for the peer's close */

typedef enum conn_state {
    C_FREE,
    C_REQUEST,  /* reading the request line and headers */
    C_RESPONSE, /* writing a response, then C_LINGER */
    C_LINGER,   /* written and shut down for writing; draining until the peer closes */
    C_VIEWER    /* a WebSocket */
} conn_state;

typedef enum viewer_stage { V_HANDSHAKE, V_TOPOLOGY, V_FRAMES } viewer_stage;

struct iso_display__conn {
    int fd;
    conn_state state;
    long long since;      /* ms: accepted, or the current message queued */
    unsigned long serial; /* order of acceptance: the oldest request yields its slot */
    long long deadline;   /* ms: when this connection is given up */
    char local[64];       /* the address it arrived on, as a Host header spells it */

    char req[ISO_DISPLAY_MAX_REQUEST + 1];
    size_t req_len;

    /* Output: head, then body; out_pos counts over both. */
    char head[1024];
    size_t head_len;
    const unsigned char *body;
    size_t body_len, out_pos;

    /* Viewer only. */
    viewer_stage stage;
    unsigned char *frame; /* its own copy of the frame being written */
    unsigned long frame_seq;
    int writing_frame;
    iso_display__ws_rx rx;
    iso_display__fox *fox; /* a Foxglove client (foxglove.c), or NULL: the page */
};

static long long now_ms(void)
{
    return (long long)(iso_clock_ns() / 1000000);
}

/* ---- addresses ------------------------------------------------------------ */

/* Spells a socket address as a Host header would: 1.2.3.4 or [::1]; a
 * v4-mapped IPv6 address as the IPv4 it is. */
static void host_spelling(const struct sockaddr *sa, char *out, size_t cap)
{
    char a[INET6_ADDRSTRLEN] = "?";
    if (sa->sa_family == AF_INET) {
        inet_ntop(AF_INET, &((const struct sockaddr_in *)sa)->sin_addr, a, sizeof a);
        snprintf(out, cap, "%s", a);
        return;
    }
    const struct in6_addr *v6 = &((const struct sockaddr_in6 *)sa)->sin6_addr;
    if (IN6_IS_ADDR_V4MAPPED(v6)) {
        inet_ntop(AF_INET, v6->s6_addr + 12, a, sizeof a);
        snprintf(out, cap, "%s", a);
        return;
    }
    inet_ntop(AF_INET6, v6, a, sizeof a);
    snprintf(out, cap, "[%s]", a);
}

static int is_loopback(const struct sockaddr *sa)
{
    if (sa->sa_family == AF_INET)
        return (ntohl(((const struct sockaddr_in *)sa)->sin_addr.s_addr) >> 24) == 127;
    const struct in6_addr *v6 = &((const struct sockaddr_in6 *)sa)->sin6_addr;
    if (IN6_IS_ADDR_V4MAPPED(v6))
        return v6->s6_addr[12] == 127;
    return IN6_IS_ADDR_LOOPBACK(v6);
}

static void notice(const iso_display_opts *o, const char *line)
{
    if (o->notice)
        o->notice(o->notice_ctx, line);
    else
        fprintf(stderr, "%s\n", line);
}

int iso_display__listen(iso_display *d, const iso_display_opts *o, iso_err *err)
{
    const char *host = o->host ? o->host : ISO_DISPLAY_DEFAULT_HOST;
    char h[128];
    size_t n = strlen(host);
    if (n >= sizeof h)
        return iso_err_set(err, ISO_EINVAL, -1, "display: host \"%.60s...\" is too long", host);
    if (n >= 2 && host[0] == '[' && host[n - 1] == ']') { /* [::1] as in a URL */
        memcpy(h, host + 1, n - 2);
        h[n - 2] = 0;
    } else {
        memcpy(h, host, n + 1);
    }
    if (strcasecmp(h, "localhost") == 0)
        snprintf(h, sizeof h, "127.0.0.1");
    char port[16];
    snprintf(port, sizeof port, "%d", o->port);
    struct addrinfo hints, *ai = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICHOST | AI_NUMERICSERV | AI_PASSIVE;
    if (getaddrinfo(h, port, &hints, &ai) != 0 || !ai)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "display: host \"%s\" is not a numeric IPv4 or IPv6 address or "
                           "localhost",
                           host);
    char spelled[64];
    host_spelling(ai->ai_addr, spelled, sizeof spelled);
    int rc = ISO_OK;
    if (!is_loopback(ai->ai_addr) && !o->allow_remote) {
        rc = iso_err_set(err, ISO_EINVAL, -1,
                         "display: refusing to listen on %s, which other machines can reach, "
                         "while the view has no password; set allow_remote (scene key "
                         "sinks.display.allow_remote: true) to do it anyway",
                         spelled);
        goto done;
    }
    int fd = socket(ai->ai_family, SOCK_STREAM, 0);
    if (fd < 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "display: cannot open a socket for %s: %s", spelled,
                         strerror(errno));
        goto done;
    }
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, 64) != 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "display: cannot serve on %s port %d: %s", spelled,
                         o->port, strerror(errno));
        close(fd);
        goto done;
    }
    (void)iso_fd_nonblock(fd);
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    getsockname(fd, (struct sockaddr *)&ss, &sl);
    d->port = ntohs(ss.ss_family == AF_INET ? ((struct sockaddr_in *)&ss)->sin_port
                                            : ((struct sockaddr_in6 *)&ss)->sin6_port);
    d->listen_fd = fd;
    snprintf(d->host_name, sizeof d->host_name, "%s", spelled);
    d->conns = calloc(ISO_DISPLAY_MAX_CONNS, sizeof *d->conns);
    if (!d->conns) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
        goto done;
    }
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++)
        d->conns[i].fd = -1;
    if (!is_loopback(ai->ai_addr)) {
        char line[256];
        snprintf(line, sizeof line,
                 "display: warning: the live view on %s port %d can be reached from other "
                 "machines, and anyone who reaches it sees the mesh (allow_remote is set)",
                 spelled, d->port);
        notice(o, line);
    }
done:
    freeaddrinfo(ai);
    return rc;
}

/* ---- connections ---------------------------------------------------------- */

static void conn_close(iso_display *d, iso_display__conn *c)
{
    if (c->state == C_VIEWER)
        atomic_fetch_sub(&d->viewers, 1);
    close(c->fd);
    free(c->frame);
    c->frame = NULL;
    iso_display__fox_free(c->fox);
    c->fox = NULL;
    c->fd = -1;
    c->state = C_FREE;
}

/* Writes what it can of c's output. Returns 1 when all of it is written, 0
 * when some is left for the next POLLOUT, -1 when the peer is gone. */
static int flush_out(iso_display__conn *c)
{
    size_t total = c->head_len + c->body_len;
    while (c->out_pos < total) {
        struct iovec iov[2];
        int k = 0;
        if (c->out_pos < c->head_len) {
            iov[k].iov_base = c->head + c->out_pos;
            iov[k++].iov_len = c->head_len - c->out_pos;
            if (c->body_len) {
                iov[k].iov_base = (void *)c->body;
                iov[k++].iov_len = c->body_len;
            }
        } else {
            iov[k].iov_base = (void *)(c->body + (c->out_pos - c->head_len));
            iov[k++].iov_len = total - c->out_pos;
        }
        struct msghdr m;
        memset(&m, 0, sizeof m);
        m.msg_iov = iov;
        m.msg_iovlen = (size_t)k;
        ssize_t w = sendmsg(c->fd, &m, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0)
            return errno == EAGAIN || errno == EWOULDBLOCK ? 0 : -1;
        c->out_pos += (size_t)w;
    }
    return 1;
}

static void set_output(iso_display__conn *c, const void *body, size_t len)
{
    c->body = body;
    c->body_len = len;
    c->out_pos = 0;
}

/* Queues a whole response and closes after it: Connection: close keeps the
 * table small and each slot's life short. */
static void respond(iso_display__conn *c, int status, const char *reason, const char *type,
                    const char *extra, const void *body, size_t len, int head_only)
{
    int n = snprintf(c->head, sizeof c->head,
                     "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\n"
                     "Cache-Control: no-cache\r\nX-Content-Type-Options: nosniff\r\n"
                     "Connection: close\r\n%s\r\n",
                     status, reason, type, len, extra ? extra : "");
    c->head_len = n > 0 && (size_t)n < sizeof c->head ? (size_t)n : 0;
    set_output(c, head_only ? NULL : body, head_only ? 0 : len);
    c->state = C_RESPONSE;
    c->deadline = now_ms() + ISO_DISPLAY_STALL_MS;
}

/* An error answer whose body is one sentence; the sentence lives in the
 * slot's request buffer, which the request no longer needs. */
static void respond_error(iso_display__conn *c, int status, const char *reason, const char *extra,
                          const char *why, int head_only)
{
    int n = snprintf(c->req, sizeof c->req, "%d %s: %s\n", status, reason, why);
    size_t len = n > 0 ? ((size_t)n < sizeof c->req ? (size_t)n : sizeof c->req - 1) : 0;
    respond(c, status, reason, "text/plain; charset=utf-8", extra, c->req, len, head_only);
}

/* ---- the request ---------------------------------------------------------- */

/* Is `a` (HOST or HOST:PORT) a name of this view? */
static int authority_is_ours(const iso_display *d, const iso_display__conn *c, const char *a,
                             size_t n, int port_optional)
{
    const char *names[] = {"localhost", "127.0.0.1", "[::1]", d->host_name, c->local};
    return iso_display__authority_is(a, n, d->port, port_optional, names,
                                     sizeof names / sizeof names[0]);
}

static int origin_is_ours(const iso_display *d, const iso_display__conn *c,
                          const iso_display__request *r)
{
    if (!r->origin) /* not a web page: browsers send Origin on every upgrade */
        return 1;
    static const char studio[] = "https://app.foxglove.dev"; /* Foxglove's web app */
    if (iso_display__fox_offered(c->req) && r->origin_len == sizeof studio - 1 &&
        strncasecmp(r->origin, studio, sizeof studio - 1) == 0)
        return 1;
    return r->origin_len > 7 && strncasecmp(r->origin, "http://", 7) == 0 &&
           authority_is_ours(d, c, r->origin + 7, r->origin_len - 7, 0);
}

/* ---- answering ------------------------------------------------------------ */

static void start_viewer(iso_display *d, iso_display__conn *c, const iso_display__request *r)
{
    char accept[29];
    if (iso_display__ws_accept(r->key, r->key_len, accept) != 0) {
        respond_error(c, 400, "Bad Request", NULL, "Sec-WebSocket-Key must have 24 characters", 0);
        return;
    }
    c->frame = malloc(d->frame_len);
    if (!c->frame) {
        respond_error(c, 503, "Service Unavailable", NULL, "out of memory", 0);
        return;
    }
    int fox = iso_display__fox_offered(c->req) && atomic_load(&d->fox);
    if (fox && !(c->fox = iso_display__fox_create())) {
        respond_error(c, 503, "Service Unavailable", NULL, "out of memory", 0);
        return;
    }
    int n = snprintf(c->head, sizeof c->head,
                     "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n"
                     "Connection: Upgrade\r\nSec-WebSocket-Accept: %s\r\n%s%s%s\r\n",
                     accept, fox ? "Sec-WebSocket-Protocol: " : "",
                     fox ? iso_display__fox_subprotocol() : "", fox ? "\r\n" : "");
    c->head_len = (size_t)n;
    set_output(c, NULL, 0);
    c->state = C_VIEWER;
    c->stage = V_HANDSHAKE;
    c->frame_seq = 0;
    c->writing_frame = 0;
    memset(&c->rx, 0, sizeof c->rx);
    c->since = now_ms();
    c->deadline = c->since + ISO_DISPLAY_STALL_MS;
    atomic_fetch_add(&d->viewers, 1);
}

static int count_viewers(const iso_display *d)
{
    int n = 0;
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++)
        n += d->conns[i].state == C_VIEWER;
    return n;
}

static void answer(iso_display *d, iso_display__conn *c)
{
    iso_display__request r;
    if (iso_display__parse_request(c->req, &r) != 0) {
        respond_error(c, 400, "Bad Request", NULL, "malformed request line", 0);
        return;
    }
    int head = iso_display__token_eq(r.method, r.method_len, "HEAD");
    if (!head && !iso_display__token_eq(r.method, r.method_len, "GET")) {
        respond_error(c, 405, "Method Not Allowed", "Allow: GET, HEAD\r\n",
                      "this view serves only GET and HEAD", 0);
        return;
    }
    if (!r.host || !authority_is_ours(d, c, r.host, r.host_len, 1)) {
        respond_error(c, 403, "Forbidden", NULL,
                      "the Host header does not name this view (use localhost or its address)",
                      head);
        return;
    }
#define PATH_IS(s) (r.path_len == sizeof(s) - 1 && memcmp(r.path, s, sizeof(s) - 1) == 0)
    static const char js[] = "application/javascript";
    if (PATH_IS("/") || PATH_IS("/index.html")) {
        respond(c, 200, "OK", "text/html; charset=utf-8", NULL, iso_display__page_html,
                strlen(iso_display__page_html), head);
    } else if (PATH_IS("/app.js")) {
        respond(c, 200, "OK", js, NULL, iso_display__app_js, strlen(iso_display__app_js), head);
    } else if (PATH_IS("/three.min.js")) {
        respond(c, 200, "OK", js, NULL, d->three, d->three_len, head);
    } else if (PATH_IS("/OrbitControls.js") && d->orbit) {
        respond(c, 200, "OK", js, NULL, d->orbit, d->orbit_len, head);
    } else if (PATH_IS("/GLTFExporter.js") && d->gltf) {
        respond(c, 200, "OK", js, NULL, d->gltf, d->gltf_len, head);
    } else if (PATH_IS("/ws")) {
        if (!origin_is_ours(d, c, &r))
            respond_error(c, 403, "Forbidden", NULL,
                          "the stream is only for this view's own page (foreign Origin)", head);
        else if (head || !r.upgrade ||
                 !iso_display__contains_ci(r.upgrade, r.upgrade_len, "websocket"))
            respond_error(c, 426, "Upgrade Required", "Upgrade: websocket\r\n",
                          "/ws is a WebSocket", head);
        else if (!r.version || !iso_display__token_eq(r.version, r.version_len, "13"))
            respond_error(c, 426, "Upgrade Required", "Sec-WebSocket-Version: 13\r\n",
                          "only WebSocket version 13 is spoken", 0);
        else if (count_viewers(d) >= ISO_DISPLAY_MAX_VIEWERS)
            respond_error(c, 503, "Service Unavailable", "Retry-After: 5\r\n",
                          "the view has as many viewers as it serves", 0);
        else
            start_viewer(d, c, &r);
    } else {
        respond_error(c, 404, "Not Found", NULL, "no such page", head);
    }
#undef PATH_IS
}

/* ---- the viewer's queue --------------------------------------------------- */

/* Starts c's next message once the last one is written: the topology after
 * the handshake, then the newest frame it has not had, if any. Returns 1
 * when a message was queued. */
static int viewer_next(iso_display *d, iso_display__conn *c, long long now)
{
    unsigned char h[10];
    if (c->writing_frame) { /* the frame before is written whole */
        c->writing_frame = 0;
        if (c->frame_seq > d->counted_seq) {
            d->counted_seq = c->frame_seq;
            atomic_fetch_add(&d->frames_sent, 1);
        }
    }
    if (c->fox) { /* Foxglove's messages instead of the page's */
        const unsigned char *body;
        size_t len;
        if (iso_display__fox_next(d, c->fox, &body, &len) <= 0)
            return 0;
        c->stage = V_FRAMES;
        set_output(c, body, len);
    } else if (c->stage == V_HANDSHAKE) {
        c->stage = V_TOPOLOGY;
        c->head_len = iso_display__ws_header(h, 1, d->topology_len);
        memcpy(c->head, h, c->head_len);
        set_output(c, d->topology, d->topology_len);
    } else {
        c->stage = V_FRAMES;
        if (atomic_load(&d->published) == c->frame_seq)
            return 0;
        pthread_mutex_lock(&d->frame_lock);
        memcpy(c->frame, d->latest, d->frame_len);
        c->frame_seq = d->latest_seq;
        pthread_mutex_unlock(&d->frame_lock);
        c->head_len = iso_display__ws_header(h, 2, d->frame_len);
        memcpy(c->head, h, c->head_len);
        set_output(c, c->frame, d->frame_len);
        c->writing_frame = 1;
    }
    c->since = now;
    c->deadline = now + ISO_DISPLAY_STALL_MS;
    return 1;
}

/* Writes what c has and queues what comes next, until the socket is full
 * or nothing is left. */
static void viewer_pump(iso_display *d, iso_display__conn *c, long long now)
{
    for (;;) {
        int st = flush_out(c);
        if (st < 0) {
            conn_close(d, c);
            return;
        }
        if (st == 0)
            return;
        c->head_len = c->body_len = c->out_pos = 0;
        if (!viewer_next(d, c, now))
            return;
    }
}

static int pending(const iso_display__conn *c)
{
    return c->out_pos < c->head_len + c->body_len;
}

/* Best effort: a close frame, if the socket takes it at once. */
static void viewer_close(iso_display *d, iso_display__conn *c, int status)
{
    if (!pending(c)) { /* else a close frame would land inside a message */
        unsigned char f[4] = {0x88, 2, (unsigned char)(status >> 8), (unsigned char)status};
        ssize_t w = send(c->fd, f, sizeof f, MSG_NOSIGNAL | MSG_DONTWAIT);
        (void)w;
    }
    conn_close(d, c);
}

/* ---- reading -------------------------------------------------------------- */

static void on_request_bytes(iso_display *d, iso_display__conn *c)
{
    size_t room = ISO_DISPLAY_MAX_REQUEST - c->req_len;
    ssize_t r = recv(c->fd, c->req + c->req_len, room, 0);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        conn_close(d, c);
        return;
    }
    if (r < 0)
        return;
    size_t from = c->req_len > 3 ? c->req_len - 3 : 0;
    if (memchr(c->req + c->req_len, 0, (size_t)r)) { /* would cut the text short */
        respond_error(c, 400, "Bad Request", NULL, "a NUL byte in the request", 0);
        return;
    }
    c->req_len += (size_t)r;
    c->req[c->req_len] = 0;
    char *end = strstr(c->req + from, "\r\n\r\n");
    if (!end) {
        if (c->req_len == ISO_DISPLAY_MAX_REQUEST)
            respond_error(c, 431, "Request Header Fields Too Large", NULL,
                          "the request line and headers exceed 8192 bytes", 0);
        return;
    }
    /* Bytes after the headers: a body (discarded while lingering) or, from a
     * new viewer, its first frames (fed to the parser). */
    size_t used = (size_t)(end - c->req) + 4;
    unsigned char extra[ISO_DISPLAY_MAX_REQUEST];
    size_t n_extra = c->req_len - used;
    memcpy(extra, c->req + used, n_extra);
    c->req[used] = 0;
    answer(d, c);
    if (c->state == C_VIEWER && n_extra) {
        int st = c->fox ? iso_display__fox_read(d, c->fox, extra, n_extra)
                        : iso_display__ws_rx_feed(&c->rx, extra, n_extra);
        if (st) {
            viewer_close(d, c, st);
            return;
        }
    }
    if (c->state == C_VIEWER)
        viewer_pump(d, c, now_ms());
}

static void on_viewer_bytes(iso_display *d, iso_display__conn *c)
{
    unsigned char buf[4096];
    ssize_t r = recv(c->fd, buf, sizeof buf, 0);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        conn_close(d, c);
        return;
    }
    if (r < 0)
        return;
    int st = c->fox ? iso_display__fox_read(d, c->fox, buf, (size_t)r)
                    : iso_display__ws_rx_feed(&c->rx, buf, (size_t)r);
    if (st)
        viewer_close(d, c, st);
    else if (c->fox && c->state == C_VIEWER && !pending(c))
        viewer_pump(d, c, now_ms()); /* a subscription: the newest tick at once */
}

static void on_linger_bytes(iso_display *d, iso_display__conn *c)
{
    unsigned char buf[4096];
    ssize_t r = recv(c->fd, buf, sizeof buf, 0);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR))
        conn_close(d, c);
}

/* ---- accepting ------------------------------------------------------------ */

/* A free slot, or the one of the oldest unfinished request, whose sender
 * loses its place rather than keep a newcomer out. NULL when every slot is
 * a viewer or a response under way. */
static iso_display__conn *slot_for_newcomer(iso_display *d)
{
    iso_display__conn *oldest = NULL;
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++) {
        iso_display__conn *c = &d->conns[i];
        if (c->state == C_FREE)
            return c;
        if ((c->state == C_REQUEST || c->state == C_LINGER) &&
            (!oldest || c->serial < oldest->serial))
            oldest = c;
    }
    if (oldest)
        conn_close(d, oldest);
    return oldest;
}

static void accept_all(iso_display *d, long long now)
{
    for (;;) {
        struct sockaddr_storage ss;
        socklen_t sl = sizeof ss;
        int fd = accept(d->listen_fd, (struct sockaddr *)&ss, &sl);
        if (fd < 0) {
            /* Out of descriptors: the listener stays readable, so rest a
             * while rather than spin; EAGAIN and the rest end this round. */
            if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM)
                d->accept_paused_until = now + 100;
            return;
        }
        (void)iso_fd_nonblock(fd);
        iso_display__conn *c = slot_for_newcomer(d);
        if (!c) {
            static const char busy[] = "HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n"
                                       "Retry-After: 5\r\nConnection: close\r\n\r\n";
            ssize_t w = send(fd, busy, sizeof busy - 1, MSG_NOSIGNAL | MSG_DONTWAIT);
            (void)w;
            close(fd);
            continue;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        memset(c, 0, sizeof *c);
        c->fd = fd;
        c->state = C_REQUEST;
        c->serial = ++d->accepted;
        c->since = now;
        c->deadline = now + ISO_DISPLAY_REQUEST_TIMEOUT_MS;
        sl = sizeof ss;
        if (getsockname(fd, (struct sockaddr *)&ss, &sl) == 0)
            host_spelling((struct sockaddr *)&ss, c->local, sizeof c->local);
    }
}

/* ---- the loop ------------------------------------------------------------- */

static void after_response(iso_display *d, iso_display__conn *c, long long now)
{
    int st = flush_out(c);
    if (st < 0) {
        conn_close(d, c);
    } else if (st > 0) {
        /* Close our side, then wait for the peer's: closing with its bytes
         * unread (a POST body) would reset the connection and could lose the
         * answer before the browser reads it. */
        shutdown(c->fd, SHUT_WR);
        c->state = C_LINGER;
        c->deadline = now + LINGER_MS;
    } else if (c->out_pos) {
        c->deadline = now + ISO_DISPLAY_STALL_MS; /* progress: the clock starts again */
    }
}

static void drain_wake(iso_display *d)
{
    atomic_store(&d->wake_pending, 0);
    char buf[64];
    while (read(d->wake[0], buf, sizeof buf) > 0) {
    }
}

static void service(iso_display *d, iso_display__conn *c, short re, long long now)
{
    if (c->state == C_REQUEST && (re & (POLLIN | POLLHUP | POLLERR)))
        on_request_bytes(d, c);
    else if (c->state == C_RESPONSE && (re & (POLLOUT | POLLHUP | POLLERR)))
        after_response(d, c, now);
    else if (c->state == C_LINGER && (re & (POLLIN | POLLHUP | POLLERR)))
        on_linger_bytes(d, c);
    else if (c->state == C_VIEWER) {
        if (re & (POLLIN | POLLHUP | POLLERR))
            on_viewer_bytes(d, c);
        if (c->state == C_VIEWER && (re & POLLOUT))
            viewer_pump(d, c, now);
    }
}

static void expire(iso_display *d, iso_display__conn *c, long long now)
{
    if (c->state == C_FREE || now < c->deadline)
        return;
    if (c->state == C_VIEWER && !pending(c))
        return; /* idle viewers wait for frames as long as they like */
    conn_close(d, c);
}

void *iso_display__serve(void *arg)
{
    iso_display *d = arg;
    struct pollfd pf[2 + ISO_DISPLAY_MAX_CONNS];
    int slot_of[2 + ISO_DISPLAY_MAX_CONNS];
    while (!atomic_load(&d->stopping)) {
        long long now = now_ms();
        int n = 0, timeout = now < d->accept_paused_until ? 100 : ISO_DISPLAY_POLL_MS;
        pf[n].fd = d->wake[0];
        pf[n++].events = POLLIN;
        pf[n].fd = now < d->accept_paused_until ? -1 : d->listen_fd; /* -1: poll skips it */
        pf[n++].events = POLLIN;
        for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++) {
            iso_display__conn *c = &d->conns[i];
            if (c->state == C_FREE)
                continue;
            short ev = c->state == C_RESPONSE ? POLLOUT : POLLIN;
            if (c->state == C_VIEWER && pending(c))
                ev |= POLLOUT;
            if (c->state != C_VIEWER || pending(c)) {
                long long left = c->deadline - now;
                timeout = left < timeout ? (left > 0 ? (int)left : 0) : timeout;
            }
            slot_of[n] = i;
            pf[n].fd = c->fd;
            pf[n++].events = ev;
        }
        if (poll(pf, (nfds_t)n, timeout) < 0 && errno != EINTR)
            break;
        now = now_ms();
        if (pf[0].revents)
            drain_wake(d);
        for (int k = 2; k < n; k++) /* before accepting, which may reuse a slot and fd */
            if (pf[k].revents && d->conns[slot_of[k]].fd == pf[k].fd)
                service(d, &d->conns[slot_of[k]], pf[k].revents, now);
        if (pf[1].revents & POLLIN)
            accept_all(d, now);
        for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++) {
            iso_display__conn *c = &d->conns[i];
            if (c->state == C_VIEWER && !pending(c) && c->stage == V_FRAMES)
                viewer_pump(d, c, now); /* a frame published since it was idle */
            expire(d, c, now);
        }
    }
    return NULL;
}

void iso_display__server_free(iso_display *d)
{
    if (d->conns)
        for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++)
            if (d->conns[i].state != C_FREE)
                conn_close(d, &d->conns[i]);
    free(d->conns);
    d->conns = NULL;
    if (d->listen_fd >= 0)
        close(d->listen_fd);
    d->listen_fd = -1;
}
