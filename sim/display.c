/* sim/display.c -- the live view's server: civetweb for HTTP and the
 * WebSocket, one sender thread that streams the newest frame (see
 * iso_display.h). */
#include "iso_display.h"

#include "display_internal.h"
#include "iso_snapshot.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef ISO_WITH_CIVETWEB
#include <civetweb.h>
#include <pthread.h>
#include <stdint.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the display's frame format is written as host floats: little-endian hosts only"
#endif

#define MAX_CLIENTS 16
#define ORBIT_JS "/usr/share/javascript/three/examples/js/controls/OrbitControls.js"

struct iso_display {
    struct mg_context *ctx;
    const iso_mesh *mesh;
    int nv, port;
    char *three, *orbit; /* file contents; orbit may be NULL */
    size_t three_len, orbit_len;
    char *topology; /* the JSON sent on connect */
    size_t topology_len;

    /* The latest frame: written by publish, read by the sender. */
    pthread_mutex_t frame_lock;
    pthread_cond_t frame_cond;
    unsigned char *latest;    /* header + 3nv floats */
    unsigned long latest_seq; /* 0 = nothing published yet */
    int stopping;

    /* Lock order: clients_lock, then frame_lock; the sender never holds both. */
    pthread_t sender;
    int sender_started;
    unsigned char *sending; /* the sender thread's own copy */
    unsigned char *welcome; /* ws_ready's copy, under clients_lock */
    size_t frame_len;
    pthread_mutex_t clients_lock; /* held while writing to any client */
    struct mg_connection *clients[MAX_CLIENTS];
    int n_clients;
    long frames_sent;
};

/* ---- file and JSON helpers ---------------------------------------------- */

static int read_file(const char *path, char **out, size_t *len, iso_err *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return iso_err_set(err, ISO_EIO, -1, "display: cannot read %s: %s", path, strerror(errno));
    char *buf = NULL;
    size_t cap = 0, n = 0;
    for (;;) {
        if (n == cap) {
            size_t ncap = cap ? 2 * cap : 1 << 20;
            char *nb = realloc(buf, ncap);
            if (!nb) {
                free(buf);
                fclose(f);
                return iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory reading %s", path);
            }
            buf = nb;
            cap = ncap;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0)
            break;
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        free(buf);
        return iso_err_set(err, ISO_EIO, -1, "display: error reading %s", path);
    }
    *out = buf;
    *len = n;
    return ISO_OK;
}

typedef struct sbuf {
    char *p;
    size_t len, cap;
    int oom;
} sbuf;

static void sb_printf(sbuf *b, const char *fmt, ...) ISO_PRINTF(2, 3);
static void sb_printf(sbuf *b, const char *fmt, ...)
{
    if (b->oom)
        return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(b->p + b->len, b->cap - b->len, fmt, ap);
        va_end(ap);
        if (n >= 0 && (size_t)n < b->cap - b->len) {
            b->len += (size_t)n;
            return;
        }
        size_t ncap = 2 * b->cap + (size_t)(n > 0 ? n : 0) + 64;
        char *np = realloc(b->p, ncap);
        if (!np) {
            b->oom = 1;
            return;
        }
        b->p = np;
        b->cap = ncap;
    }
}

static int build_topology(iso_display *d, const iso_regions *r, iso_err *err)
{
    sbuf b = {malloc(1 << 16), 0, 1 << 16, 0};
    if (!b.p)
        return iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    const double *x = iso_mesh_positions(d->mesh);
    const int *tri = iso_mesh_triangles(d->mesh);
    int nt = iso_mesh_triangle_count(d->mesh);
    sb_printf(&b, "{\"type\":\"topology\",\"nv\":%d,\"nt\":%d,\"strain_full\":%g,\"rest\":[", d->nv,
              nt, ISO_DISPLAY_STRAIN_FULL);
    for (int i = 0; i < 3 * d->nv; i++)
        sb_printf(&b, "%s%.9g", i ? "," : "", x[i]);
    sb_printf(&b, "],\"tri\":[");
    for (int i = 0; i < 3 * nt; i++)
        sb_printf(&b, "%s%d", i ? "," : "", tri[i]);
    sb_printf(&b, "],\"kind\":[");
    for (int i = 0; i < d->nv; i++)
        sb_printf(&b, "%s%d", i ? "," : "", r ? r->kind[i] : ISO_FREE);
    sb_printf(&b, "]}");
    if (b.oom) {
        free(b.p);
        return iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory for the topology");
    }
    d->topology = b.p;
    d->topology_len = b.len;
    return ISO_OK;
}

/* ---- HTTP handlers ------------------------------------------------------ */

static int send_body(struct mg_connection *c, const char *type, const char *body, size_t len)
{
    mg_printf(c,
              "HTTP/1.1 200 OK\r\nContent-Type: %s\r\nContent-Length: %zu\r\n"
              "Cache-Control: no-cache\r\nConnection: close\r\n\r\n",
              type, len);
    mg_write(c, body, len);
    return 200;
}

static int page_handler(struct mg_connection *c, void *cb)
{
    (void)cb;
    return send_body(c, "text/html; charset=utf-8", iso_display__page_html,
                     strlen(iso_display__page_html));
}

static int app_handler(struct mg_connection *c, void *cb)
{
    (void)cb;
    return send_body(c, "application/javascript", iso_display__app_js, strlen(iso_display__app_js));
}

static int three_handler(struct mg_connection *c, void *cb)
{
    iso_display *d = cb;
    return send_body(c, "application/javascript", d->three, d->three_len);
}

static int orbit_handler(struct mg_connection *c, void *cb)
{
    iso_display *d = cb;
    if (!d->orbit) {
        mg_send_http_error(c, 404, "%s", "OrbitControls.js is not installed");
        return 404;
    }
    return send_body(c, "application/javascript", d->orbit, d->orbit_len);
}

/* ---- WebSocket ---------------------------------------------------------- */

static int ws_connect(const struct mg_connection *c, void *cb)
{
    iso_display *d = cb;
    (void)c;
    pthread_mutex_lock(&d->clients_lock);
    int full = d->n_clients >= MAX_CLIENTS;
    pthread_mutex_unlock(&d->clients_lock);
    return full; /* non-zero refuses */
}

/* A new browser gets the topology and, if there is one, the latest frame,
 * under the clients lock so no sender write interleaves. */
static void ws_ready(struct mg_connection *c, void *cb)
{
    iso_display *d = cb;
    pthread_mutex_lock(&d->clients_lock);
    if (d->n_clients < MAX_CLIENTS)
        d->clients[d->n_clients++] = c;
    mg_websocket_write(c, MG_WEBSOCKET_OPCODE_TEXT, d->topology, d->topology_len);
    pthread_mutex_lock(&d->frame_lock);
    int have = d->latest_seq > 0;
    if (have)
        memcpy(d->welcome, d->latest, d->frame_len);
    pthread_mutex_unlock(&d->frame_lock);
    if (have)
        mg_websocket_write(c, MG_WEBSOCKET_OPCODE_BINARY, (const char *)d->welcome, d->frame_len);
    pthread_mutex_unlock(&d->clients_lock);
}

static int ws_data(struct mg_connection *c, int bits, char *data, size_t len, void *cb)
{
    (void)c;
    (void)data;
    (void)len;
    (void)cb;
    return (bits & 0x0f) != MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE; /* 0 closes */
}

static void ws_close(const struct mg_connection *c, void *cb)
{
    iso_display *d = cb;
    pthread_mutex_lock(&d->clients_lock);
    for (int i = 0; i < d->n_clients; i++)
        if (d->clients[i] == c) {
            d->clients[i] = d->clients[--d->n_clients];
            break;
        }
    pthread_mutex_unlock(&d->clients_lock);
}

/* ---- the sender thread -------------------------------------------------- */

static void *sender_main(void *arg)
{
    iso_display *d = arg;
    unsigned long seen = 0;
    for (;;) {
        pthread_mutex_lock(&d->frame_lock);
        while (!d->stopping && d->latest_seq == seen)
            pthread_cond_wait(&d->frame_cond, &d->frame_lock);
        if (d->stopping) {
            pthread_mutex_unlock(&d->frame_lock);
            return NULL;
        }
        seen = d->latest_seq;
        memcpy(d->sending, d->latest, d->frame_len);
        pthread_mutex_unlock(&d->frame_lock);
        /* Never hold frame_lock while writing: publish must not wait on the
         * network, and ws_ready takes the locks clients first. */
        pthread_mutex_lock(&d->clients_lock);
        int wrote = 0;
        for (int i = 0; i < d->n_clients; i++)
            wrote |= mg_websocket_write(d->clients[i], MG_WEBSOCKET_OPCODE_BINARY,
                                        (const char *)d->sending, d->frame_len) > 0;
        d->frames_sent += wrote;
        pthread_mutex_unlock(&d->clients_lock);
    }
}

/* ---- public API --------------------------------------------------------- */

static int log_quiet(const struct mg_connection *c, const char *msg)
{
    (void)c;
    (void)msg;
    return 1; /* civetweb's messages would mix into the loop's status line */
}

int iso_display_create(const iso_display_opts *opts, iso_display **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!opts || !opts->mesh || !out)
        return iso_err_set(err, ISO_EINVAL, -1, "display: NULL options, mesh or out argument");
    if (opts->port < 0 || opts->port > 65535)
        return iso_err_set(err, ISO_EINVAL, -1, "display: port %d is outside 0..65535", opts->port);
    int nv = iso_mesh_vertex_count(opts->mesh);
    if (opts->regions && opts->regions->nv != nv)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "display: regions have %d vertices, the mesh has %d", opts->regions->nv,
                           nv);
    const char *host = opts->host ? opts->host : ISO_DISPLAY_DEFAULT_HOST;
    if (strlen(host) > 200 || strchr(host, ','))
        return iso_err_set(err, ISO_EINVAL, -1, "display: bad host \"%.60s\"", host);
    if (!mg_check_feature(MG_FEATURES_WEBSOCKET))
        return iso_err_set(err, ISO_ENOTSUP, -1,
                           "display: this civetweb was built without WebSocket support");

    iso_display *d = calloc(1, sizeof *d);
    if (!d)
        return iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    d->mesh = opts->mesh;
    d->nv = nv;
    d->frame_len = ISO_DISPLAY_FRAME_HEADER + (size_t)12 * (size_t)nv;
    pthread_mutex_init(&d->frame_lock, NULL);
    pthread_cond_init(&d->frame_cond, NULL);
    pthread_mutex_init(&d->clients_lock, NULL);
    int rc;
    const char *three = opts->three_js ? opts->three_js : ISO_DISPLAY_DEFAULT_THREE;
    if ((rc = read_file(three, &d->three, &d->three_len, NULL)) < 0) {
        rc = iso_err_set(err, ISO_EIO, -1,
                         "display: three.js not found at %s: %s (install Debian's libjs-three)",
                         three, strerror(errno));
        goto fail;
    }
    if (read_file(ORBIT_JS, &d->orbit, &d->orbit_len, NULL) < 0)
        d->orbit = NULL; /* the page has its own orbit control */
    if ((rc = build_topology(d, opts->regions, err)) < 0)
        goto fail;
    d->latest = calloc(1, d->frame_len);
    d->sending = calloc(1, d->frame_len);
    d->welcome = calloc(1, d->frame_len);
    if (!d->latest || !d->sending || !d->welcome) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
        goto fail;
    }

    char ports[256];
    snprintf(ports, sizeof ports, "%s:%d", host, opts->port);
    const char *options[] = {"listening_ports",   ports, "num_threads", "8",
                             "enable_keep_alive", "no",  NULL};
    struct mg_callbacks cbs;
    memset(&cbs, 0, sizeof cbs);
    cbs.log_message = log_quiet;
    mg_init_library(MG_FEATURES_WEBSOCKET);
    struct mg_init_data init = {&cbs, d, options};
    struct mg_error_data ed;
    char emsg[256] = "";
    memset(&ed, 0, sizeof ed);
    ed.text = emsg;
    ed.text_buffer_size = sizeof emsg;
    d->ctx = mg_start2(&init, &ed);
    if (!d->ctx) {
        mg_exit_library();
        rc = iso_err_set(err, ISO_EIO, -1, "display: cannot serve on %s: %s", ports,
                         emsg[0] ? emsg : "civetweb could not start");
        goto fail;
    }
    struct mg_server_port sp[4];
    int np = mg_get_server_ports(d->ctx, 4, sp);
    d->port = np > 0 ? sp[0].port : opts->port;
    mg_set_request_handler(d->ctx, "/$", page_handler, d);
    mg_set_request_handler(d->ctx, "/index.html$", page_handler, d);
    mg_set_request_handler(d->ctx, "/app.js$", app_handler, d);
    mg_set_request_handler(d->ctx, "/three.min.js$", three_handler, d);
    mg_set_request_handler(d->ctx, "/OrbitControls.js$", orbit_handler, d);
    mg_set_websocket_handler(d->ctx, "/ws$", ws_connect, ws_ready, ws_data, ws_close, d);
    if (pthread_create(&d->sender, NULL, sender_main, d) != 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "display: cannot start the sender thread");
        goto fail;
    }
    d->sender_started = 1;
    *out = d;
    return ISO_OK;
fail:
    iso_display_destroy(d);
    return rc;
}

int iso_display_port(const iso_display *d)
{
    return d ? d->port : -1;
}

int iso_display_clients(const iso_display *d)
{
    if (!d)
        return 0;
    iso_display *m = (iso_display *)d; /* the lock is not part of the value */
    pthread_mutex_lock(&m->clients_lock);
    int n = m->n_clients;
    pthread_mutex_unlock(&m->clients_lock);
    return n;
}

long iso_display_frames_sent(const iso_display *d)
{
    if (!d)
        return 0;
    iso_display *m = (iso_display *)d;
    pthread_mutex_lock(&m->clients_lock);
    long n = m->frames_sent;
    pthread_mutex_unlock(&m->clients_lock);
    return n;
}

static float to_f32(double v)
{
    return (float)v;
}

int iso_display_publish(iso_display *d, long tick, const double *x, const iso_display_stats *st,
                        iso_err *err)
{
    if (!d || !x)
        return iso_err_set(err, ISO_EINVAL, -1, "display: NULL display or positions");
    pthread_mutex_lock(&d->frame_lock);
    unsigned char *f = d->latest;
    uint32_t u[2] = {ISO_DISPLAY_FRAME_MAGIC, (uint32_t)d->nv};
    double t = (double)tick;
    float s[4] = {0, 0, 0, 0};
    uint32_t misses[2] = {0, 0};
    if (st) {
        s[0] = to_f32(st->tick_ms_median);
        s[1] = to_f32(st->tick_ms_p99);
        s[2] = to_f32(st->tick_ms_max);
        s[3] = to_f32(st->latency_ms);
        misses[0] = st->misses < 0             ? 0
                    : st->misses > 0xffffffffL ? 0xffffffffu
                                               : (uint32_t)st->misses;
    }
    memcpy(f, u, 8);
    memcpy(f + 8, &t, 8);
    memcpy(f + 16, s, 16);
    memcpy(f + 32, misses, 8);
    float *p = (float *)(f + ISO_DISPLAY_FRAME_HEADER);
    for (int i = 0; i < 3 * d->nv; i++)
        p[i] = (float)x[i];
    d->latest_seq++;
    pthread_cond_signal(&d->frame_cond);
    pthread_mutex_unlock(&d->frame_lock);
    return ISO_OK;
}

void iso_display_destroy(iso_display *d)
{
    if (!d)
        return;
    if (d->sender_started) {
        pthread_mutex_lock(&d->frame_lock);
        d->stopping = 1;
        pthread_cond_signal(&d->frame_cond);
        pthread_mutex_unlock(&d->frame_lock);
        pthread_join(d->sender, NULL);
    }
    if (d->ctx) {
        mg_stop(d->ctx);
        mg_exit_library();
    }
    pthread_mutex_destroy(&d->frame_lock);
    pthread_cond_destroy(&d->frame_cond);
    pthread_mutex_destroy(&d->clients_lock);
    free(d->three);
    free(d->orbit);
    free(d->topology);
    free(d->latest);
    free(d->sending);
    free(d->welcome);
    free(d);
}

#else /* !ISO_WITH_CIVETWEB */

int iso_display_create(const iso_display_opts *opts, iso_display **out, iso_err *err)
{
    (void)opts;
    if (out)
        *out = NULL;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "display: isoshape was built without civetweb, so there is no live view "
                       "(install libcivetweb-dev and rebuild, or use PNG snapshots and PLY "
                       "frames)");
}

int iso_display_port(const iso_display *d)
{
    (void)d;
    return -1;
}

int iso_display_clients(const iso_display *d)
{
    (void)d;
    return 0;
}

long iso_display_frames_sent(const iso_display *d)
{
    (void)d;
    return 0;
}

int iso_display_publish(iso_display *d, long tick, const double *x, const iso_display_stats *st,
                        iso_err *err)
{
    (void)d;
    (void)tick;
    (void)x;
    (void)st;
    return iso_err_set(err, ISO_ENOTSUP, -1, "display: built without civetweb");
}

void iso_display_destroy(iso_display *d)
{
    (void)d;
}

#endif
