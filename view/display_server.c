/* view/display_server.c -- the live view's server: one thread, one poll()
 * loop, non-blocking sockets, a fixed table of connections, and the policy
 * that keeps page loads going under a flood of connections (iso_display.h).
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
 * response written and lingering for the peer's close, or a WebSocket of
 * some kind (iso_display__proto; the view's own in display_viewer.c). A
 * WebSocket's output is at most one message at a time, with a pong slipped
 * in between two messages; its kind says what comes next. */
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

long long iso_display__now_ms(void)
{
    return (long long)(iso_clock_ns() / 1000000);
}
#define now_ms iso_display__now_ms

/* ---- connections ---------------------------------------------------------- */

static int pending(const iso_display__conn *c)
{
    return c->out_pos < c->head_len + c->body_len;
}

/* Ends a connection. `drop`: the server gives up on the peer (a stall, a
 * timeout, an eviction): the close is a reset, so what it had not yet sent
 * leaves the kernel at once instead of waiting there for a peer that does
 * not read. */
static void conn_close(iso_display *d, iso_display__conn *c, int drop)
{
    if (c->state == C_SOCKET) {
        c->proto->close(d, c);
        atomic_fetch_sub(&d->viewers, 1);
    }
    if (drop) {
        struct linger lg = {1, 0};
        setsockopt(c->fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
    }
    close(c->fd);
    c->fd = -1;
    c->state = C_FREE;
}

/* Writes what it can of c's output, at most *budget bytes (counted down).
 * Returns 1 when all of it is written, 0 when some is left for the next
 * POLLOUT or the next turn, -1 when the peer is gone. */
static int flush_out(iso_display__conn *c, size_t *budget)
{
    size_t total = c->head_len + c->body_len;
    while (c->out_pos < total) {
        size_t want = total - c->out_pos < *budget ? total - c->out_pos : *budget;
        if (want == 0)
            return 0;
        struct iovec iov[2];
        int k = 0;
        if (c->out_pos < c->head_len) {
            size_t h = c->head_len - c->out_pos;
            iov[k].iov_base = c->head + c->out_pos;
            iov[k++].iov_len = h < want ? h : want;
            if (c->body_len && want > h) {
                iov[k].iov_base = (void *)c->body;
                iov[k++].iov_len = want - h;
            }
        } else {
            iov[k].iov_base = (void *)(c->body + (c->out_pos - c->head_len));
            iov[k++].iov_len = want;
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
        *budget -= (size_t)w;
    }
    return 1;
}

void iso_display__set_output(iso_display__conn *c, const void *body, size_t len)
{
    c->body = body;
    c->body_len = len;
    c->out_pos = 0;
}

void iso_display__queue_message(iso_display__conn *c, int opcode, const void *body, size_t len)
{
    unsigned char h[10];
    c->head_len = iso_display__ws_header(h, opcode, len);
    memcpy(c->head, h, c->head_len);
    iso_display__set_output(c, body, len);
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
    iso_display__set_output(c, head_only ? NULL : body, head_only ? 0 : len);
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

/* ---- WebSockets ------------------------------------------------------------ */

static int count_sockets(const iso_display *d)
{
    int n = 0;
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++)
        n += d->conns[i].state == C_SOCKET;
    return n;
}

/* The kind a Sec-WebSocket-Protocol offer asks for: the first offered name
 * that a kind answers to (Foxglove's only once iso_display_foxglove made
 * the session); the view's own when there is no offer. NULL when nothing
 * offered is spoken here. */
static const iso_display__proto *choose_proto(iso_display *d, const iso_display__request *r)
{
    static const iso_display__proto *const kinds[] = {&iso_display__view_proto,
                                                      &iso_display__fox_proto};
    if (!r->protocol)
        return &iso_display__view_proto;
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++)
        if (kinds[k]->name && (kinds[k] != &iso_display__fox_proto || atomic_load(&d->fox)) &&
            iso_display__list_has(r->protocol, r->protocol_len, kinds[k]->name))
            return kinds[k];
    return NULL;
}

/* Foxglove's subprotocol offered before iso_display_foxglove made the
 * session (the first moments of a run): worth a retry, not a refusal. */
static int fox_starting(const iso_display *d, const iso_display__request *r)
{
    return r->protocol && !atomic_load(&d->fox) &&
           iso_display__list_has(r->protocol, r->protocol_len, iso_display__fox_proto.name);
}

static void start_socket(iso_display *d, iso_display__conn *c, const iso_display__request *r,
                         const iso_display__proto *proto)
{
    char accept[29];
    if (iso_display__ws_accept(r->key, r->key_len, accept) != 0) {
        respond_error(c, 400, "Bad Request", NULL, "Sec-WebSocket-Key must have 24 characters", 0);
        return;
    }
    c->proto = proto;
    c->id = ++d->next_id;
    memset(&c->rx, 0, sizeof c->rx);
    memset(&c->v, 0, sizeof c->v);
    c->ctl_len = 0;
    if (proto->open(d, c, r) != 0) {
        respond_error(c, 503, "Service Unavailable", NULL, "out of memory", 0);
        return;
    }
    char sub[96] = "";
    if (proto->name)
        snprintf(sub, sizeof sub, "Sec-WebSocket-Protocol: %s\r\n", proto->name);
    int n = snprintf(c->head, sizeof c->head,
                     "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n"
                     "Connection: Upgrade\r\nSec-WebSocket-Accept: %s\r\n%s\r\n",
                     accept, sub);
    c->head_len = (size_t)n;
    iso_display__set_output(c, NULL, 0);
    c->state = C_SOCKET;
    c->since = now_ms();
    c->deadline = c->since + ISO_DISPLAY_STALL_MS;
    atomic_fetch_add(&d->viewers, 1);
}

static void upgrade(iso_display *d, iso_display__conn *c, const iso_display__request *r, int head)
{
    const iso_display__proto *proto = choose_proto(d, r);
    if (!origin_is_ours(d, c, r))
        respond_error(c, 403, "Forbidden", NULL,
                      "the stream is only for this view's own page (foreign Origin)", head);
    else if (head || !r->upgrade ||
             !iso_display__contains_ci(r->upgrade, r->upgrade_len, "websocket"))
        respond_error(c, 426, "Upgrade Required", "Upgrade: websocket\r\n", "/ws is a WebSocket",
                      head);
    else if (!r->version || !iso_display__token_eq(r->version, r->version_len, "13"))
        respond_error(c, 426, "Upgrade Required", "Sec-WebSocket-Version: 13\r\n",
                      "only WebSocket version 13 is spoken", 0);
    else if (!proto && fox_starting(d, r))
        respond_error(c, 503, "Service Unavailable", "Retry-After: 1\r\n",
                      "the Foxglove session is starting: try again in a moment", 0);
    else if (!proto)
        respond_error(c, 400, "Bad Request", NULL, "no subprotocol offered is spoken here", 0);
    else if (count_sockets(d) >= ISO_DISPLAY_MAX_VIEWERS)
        respond_error(c, 503, "Service Unavailable", "Retry-After: 5\r\n",
                      "the view has as many viewers as it serves", 0);
    else
        start_socket(d, c, r, proto);
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
    if (PATH_IS("/") || PATH_IS("/index.html"))
        respond(c, 200, "OK", "text/html; charset=utf-8", NULL, iso_display__page_html,
                strlen(iso_display__page_html), head);
    else if (PATH_IS("/app.js"))
        respond(c, 200, "OK", js, NULL, iso_display__app_js, strlen(iso_display__app_js), head);
    else if (PATH_IS("/three.min.js"))
        respond(c, 200, "OK", js, NULL, d->three, d->three_len, head);
    else if (PATH_IS("/OrbitControls.js") && d->orbit)
        respond(c, 200, "OK", js, NULL, d->orbit, d->orbit_len, head);
    else if (PATH_IS("/TransformControls.js") && d->gizmo)
        respond(c, 200, "OK", js, NULL, d->gizmo, d->gizmo_len, head);
    else if (PATH_IS("/GLTFExporter.js") && d->gltf)
        respond(c, 200, "OK", js, NULL, d->gltf, d->gltf_len, head);
    else if (PATH_IS("/ws"))
        upgrade(d, c, &r, head);
    else
        respond_error(c, 404, "Not Found", NULL, "no such page", head);
#undef PATH_IS
}

/* ---- a WebSocket's output and input ---------------------------------------- */

/* Writes what c has and queues what comes next (a pong first, then what
 * its kind says), until the socket is full or nothing is left. */
static void socket_pump(iso_display *d, iso_display__conn *c, long long now)
{
    size_t budget = ISO_DISPLAY_TURN_BYTES;
    for (;;) {
        int st = flush_out(c, &budget);
        if (st < 0) {
            conn_close(d, c, 1);
            return;
        }
        if (st == 0) {
            if (c->patient && budget < ISO_DISPLAY_TURN_BYTES)
                c->deadline = now + ISO_DISPLAY_STALL_MS; /* progress: the clock starts again */
            return;
        }
        c->head_len = c->body_len = c->out_pos = 0;
        c->patient = 0;
        if (c->ctl_len) {
            memcpy(c->head, c->ctl_out, c->ctl_len);
            c->head_len = c->ctl_len;
            c->ctl_len = 0;
            iso_display__set_output(c, NULL, 0);
        } else if (!c->proto->next(d, c, now)) {
            return;
        }
        c->since = now;
        c->deadline = now + ISO_DISPLAY_STALL_MS;
    }
}

/* Sends a close frame with `status` if it fits between two messages, then
 * closes; the peer's reply is not waited for (it would hold a slot). */
static void socket_close(iso_display *d, iso_display__conn *c, int status)
{
    if (!pending(c)) { /* a pong owed goes first */
        unsigned char f[sizeof c->ctl_out + 4];
        memcpy(f, c->ctl_out, c->ctl_len);
        unsigned char *cl = f + c->ctl_len;
        cl[0] = 0x88;
        cl[1] = 2;
        cl[2] = (unsigned char)(status >> 8);
        cl[3] = (unsigned char)status;
        ssize_t w = send(c->fd, f, c->ctl_len + 4, MSG_NOSIGNAL | MSG_DONTWAIT);
        (void)w;
        c->ctl_len = 0;
        shutdown(c->fd, SHUT_WR);
    }
    conn_close(d, c, pending(c));
}

/* Feeds the browser's bytes to the parser and acts on what completes.
 * Returns 0 when the connection goes on. */
static int socket_input(iso_display *d, iso_display__conn *c, const unsigned char *p, size_t n)
{
    while (n) {
        iso_display__ws_event ev;
        size_t used = 0;
        int st = iso_display__ws_rx_feed(&c->rx, p, n, &used, &ev);
        p += used;
        n -= used;
        int status = 0;
        if (st == ISO_DISPLAY_WS_MESSAGE)
            status = c->proto->message(d, c, ev.opcode, ev.data, ev.len);
        else if (st == ISO_DISPLAY_WS_PING) {
            c->ctl_out[0] = 0x8a; /* a pong with the ping's payload; a newer ping replaces it */
            c->ctl_out[1] = (unsigned char)ev.len;
            memcpy(c->ctl_out + 2, ev.data, ev.len);
            c->ctl_len = 2 + ev.len;
        } else if (st == ISO_DISPLAY_WS_CLOSE)
            status = ev.code == ISO_DISPLAY_WS_NO_STATUS ? ISO_DISPLAY_WS_NORMAL : ev.code;
        else if (st == ISO_DISPLAY_WS_FAIL)
            status = ev.code;
        if (status) {
            socket_close(d, c, status);
            return -1;
        }
    }
    if (!pending(c)) /* a pong, or what the message asked for (a subscription's tick) */
        socket_pump(d, c, now_ms());
    return 0;
}

static void on_socket_bytes(iso_display *d, iso_display__conn *c)
{
    unsigned char buf[4096];
    ssize_t r = recv(c->fd, buf, sizeof buf, 0);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        conn_close(d, c, pending(c));
        return;
    }
    if (r > 0)
        (void)socket_input(d, c, buf, (size_t)r);
}

/* ---- reading requests -------------------------------------------------------- */

static void after_response(iso_display *d, iso_display__conn *c, long long now)
{
    size_t budget = ISO_DISPLAY_TURN_BYTES;
    int st = flush_out(c, &budget);
    if (st < 0) {
        conn_close(d, c, 1);
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

static void on_request_bytes(iso_display *d, iso_display__conn *c, long long now)
{
    size_t room = ISO_DISPLAY_MAX_REQUEST - c->req_len;
    ssize_t r = recv(c->fd, c->req + c->req_len, room, 0);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        conn_close(d, c, 0);
        return;
    }
    if (r < 0)
        return;
    size_t from = c->req_len > 3 ? c->req_len - 3 : 0;
    if (memchr(c->req + c->req_len, 0, (size_t)r)) { /* would cut the text short */
        respond_error(c, 400, "Bad Request", NULL, "a NUL byte in the request", 0);
        after_response(d, c, now);
        return;
    }
    c->req_len += (size_t)r;
    c->req[c->req_len] = 0;
    char *end = strstr(c->req + from, "\r\n\r\n");
    if (!end) {
        if (c->req_len == ISO_DISPLAY_MAX_REQUEST) {
            respond_error(c, 431, "Request Header Fields Too Large", NULL,
                          "the request line and headers exceed 8192 bytes", 0);
            after_response(d, c, now);
        }
        return;
    }
    /* Bytes after the headers: a body (discarded while lingering) or, from a
     * new WebSocket, its first frames (fed to the parser). */
    size_t used = (size_t)(end - c->req) + 4;
    unsigned char extra[ISO_DISPLAY_MAX_REQUEST];
    size_t n_extra = c->req_len - used;
    memcpy(extra, c->req + used, n_extra);
    c->req[used] = 0;
    answer(d, c);
    if (c->state == C_RESPONSE) { /* written at once: a flood must not delay it */
        after_response(d, c, now);
        return;
    }
    if (c->state == C_SOCKET && n_extra && socket_input(d, c, extra, n_extra) != 0)
        return;
    if (c->state == C_SOCKET)
        socket_pump(d, c, now);
}

static void on_linger_bytes(iso_display *d, iso_display__conn *c)
{
    unsigned char buf[4096];
    ssize_t r = recv(c->fd, buf, sizeof buf, 0);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR))
        conn_close(d, c, 0);
}

/* ---- accepting ------------------------------------------------------------ */

/* How readily a connection gives its slot to a newcomer: lower first, -1
 * never. A request with no byte yet is the cheapest to lose (a browser's
 * request is there when it is accepted); then one that lingers after its
 * answer; then a partial request, the slow sender's. */
static int evict_rank(const iso_display__conn *c)
{
    if (c->state == C_REQUEST)
        return c->req_len == 0 ? 0 : 2;
    return c->state == C_LINGER ? 1 : -1;
}

/* A free slot, or the one of the connection that yields first (the oldest
 * of its rank). NULL when every slot is a WebSocket or a response. */
static iso_display__conn *slot_for_newcomer(iso_display *d)
{
    iso_display__conn *best = NULL;
    int best_rank = 99;
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++) {
        iso_display__conn *c = &d->conns[i];
        if (c->state == C_FREE)
            return c;
        int r = evict_rank(c);
        if (r >= 0 && (r < best_rank || (r == best_rank && c->serial < best->serial))) {
            best = c;
            best_rank = r;
        }
    }
    if (best)
        conn_close(d, best, 1);
    return best;
}

static void refuse_busy(int fd)
{
    static const char busy[] = "HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n"
                               "Retry-After: 5\r\nConnection: close\r\n\r\n";
    ssize_t w = send(fd, busy, sizeof busy - 1, MSG_NOSIGNAL | MSG_DONTWAIT);
    (void)w;
    struct linger lg = {1, 0};
    setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
    close(fd);
}

/* Accepts up to ISO_DISPLAY_ACCEPT_BATCH connections and reads each one's
 * request at once. */
static void accept_some(iso_display *d, long long now)
{
    for (int k = 0; k < ISO_DISPLAY_ACCEPT_BATCH; k++) {
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
            refuse_busy(fd);
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
            iso_display__host_spelling((struct sockaddr *)&ss, c->local, sizeof c->local);
        on_request_bytes(d, c, now);
    }
}

/* ---- the loop ------------------------------------------------------------- */

static void drain_wake(iso_display *d)
{
    atomic_store(&d->wake_pending, 0);
    char buf[64];
    while (read(d->wake[0], buf, sizeof buf) > 0) {
    }
}

/* What the peers sent: requests, closes, and a page's commands, which are
 * handed on here, before any connection's output is written this turn. */
static void service_input(iso_display *d, iso_display__conn *c, short re, long long now)
{
    if (!(re & (POLLIN | POLLHUP | POLLERR)))
        return;
    if (c->state == C_REQUEST)
        on_request_bytes(d, c, now);
    else if (c->state == C_LINGER)
        on_linger_bytes(d, c);
    else if (c->state == C_SOCKET)
        on_socket_bytes(d, c);
}

/* What goes to the peers, at most ISO_DISPLAY_TURN_BYTES a connection a
 * turn, so that one fast reader cannot keep the others, or the next
 * turn's reads, waiting. */
static void service_output(iso_display *d, iso_display__conn *c, short re, long long now)
{
    if (c->state == C_RESPONSE && (re & (POLLOUT | POLLHUP | POLLERR)))
        after_response(d, c, now);
    else if (c->state == C_SOCKET && (re & POLLOUT))
        socket_pump(d, c, now);
}

/* Past its deadline: a request that never completed, a response or message
 * that stalled, a lingering close: dropped. */
static void expire(iso_display *d, iso_display__conn *c, long long now)
{
    if (c->state == C_FREE || now < c->deadline)
        return;
    if (c->state == C_SOCKET && !pending(c))
        return; /* idle WebSockets wait for their next message as long as they like */
    conn_close(d, c, 1);
}

/* One poll() set: the wake pipe, the listener, every connection. */
static int poll_set(iso_display *d, struct pollfd *pf, int *slot_of, long long now, int *timeout)
{
    int n = 0;
    *timeout = now < d->accept_paused_until ? 100 : ISO_DISPLAY_POLL_MS;
    pf[n].fd = d->wake[0];
    pf[n++].events = POLLIN;
    pf[n].fd = now < d->accept_paused_until ? -1 : d->listen_fd; /* -1: poll skips it */
    pf[n++].events = POLLIN;
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++) {
        iso_display__conn *c = &d->conns[i];
        if (c->state == C_FREE)
            continue;
        short ev = c->state == C_RESPONSE ? POLLOUT : POLLIN;
        if (c->state == C_SOCKET && pending(c))
            ev |= POLLOUT;
        if (c->state != C_SOCKET || pending(c)) {
            long long left = c->deadline - now;
            *timeout = left < *timeout ? (left > 0 ? (int)left : 0) : *timeout;
        }
        slot_of[n] = i;
        pf[n].fd = c->fd;
        pf[n++].events = ev;
    }
    return n;
}

void *iso_display__serve(void *arg)
{
    iso_display *d = arg;
    struct pollfd pf[2 + ISO_DISPLAY_MAX_CONNS];
    int slot_of[2 + ISO_DISPLAY_MAX_CONNS];
    int ended = 0;
    while (!atomic_load(&d->stopping)) {
        int timeout, n = poll_set(d, pf, slot_of, now_ms(), &timeout);
        if (poll(pf, (nfds_t)n, timeout) < 0 && errno != EINTR)
            break;
        long long now = now_ms();
        if (pf[0].revents)
            drain_wake(d);
        if (!ended && atomic_load(&d->ended)) {
            ended = 1;
            iso_display__viewer_end(d);
        }
        iso_display__viewer_lapse(d, now);
        /* inputs first, then outputs, both before accepting, which may
         * reuse a slot and fd */
        for (int k = 2; k < n; k++)
            if (pf[k].revents && d->conns[slot_of[k]].fd == pf[k].fd)
                service_input(d, &d->conns[slot_of[k]], pf[k].revents, now);
        for (int k = 2; k < n; k++)
            if (pf[k].revents && d->conns[slot_of[k]].fd == pf[k].fd)
                service_output(d, &d->conns[slot_of[k]], pf[k].revents, now);
        if (pf[1].revents & POLLIN)
            accept_some(d, now);
        for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++) {
            iso_display__conn *c = &d->conns[i];
            if (c->state == C_SOCKET && !pending(c))
                socket_pump(d, c, now); /* a frame or a change since it was idle */
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
                conn_close(d, &d->conns[i], 1);
    free(d->conns);
    d->conns = NULL;
    if (d->listen_fd >= 0)
        close(d->listen_fd);
    d->listen_fd = -1;
}
