/* view/display.c -- the live view's API: create, publish, counters and
 * destroy (see iso_display.h). The server itself is display_server.c. */
#include "iso_display.h"

#include "display_internal.h"
#include "iso_fd.h"
#include "iso_file.h"
#include "iso_snapshot.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the display's frame format is written as host floats: little-endian hosts only"
#endif

#define ORBIT_JS "/usr/share/javascript/three/examples/js/controls/OrbitControls.js"
#define GLTF_JS "/usr/share/javascript/three/examples/js/exporters/GLTFExporter.js"

/* ---- JSON helpers --------------------------------------------------------- */

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

/* ---- public API --------------------------------------------------------- */

static int open_wake_pipe(iso_display *d, iso_err *err)
{
    if (pipe(d->wake) != 0) {
        d->wake[0] = d->wake[1] = -1;
        return iso_err_set(err, ISO_EIO, -1, "display: cannot create the wake pipe: %s",
                           strerror(errno));
    }
    if (iso_fd_nonblock(d->wake[0]) != 0 || iso_fd_nonblock(d->wake[1]) != 0)
        return iso_err_set(err, ISO_EIO, -1, "display: cannot set up the wake pipe: %s",
                           strerror(errno));
    return ISO_OK;
}

/* Wakes the server thread unless a wake is already on its way; never blocks
 * (the pipe is non-blocking and holds at most one byte from here). */
static void wake_server(iso_display *d)
{
    if (atomic_exchange(&d->wake_pending, 1))
        return;
    ssize_t w = write(d->wake[1], "w", 1);
    (void)w; /* full pipe: the server is awake anyway */
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

    iso_display *d = calloc(1, sizeof *d);
    if (!d)
        return iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    d->mesh = opts->mesh;
    d->nv = nv;
    d->listen_fd = d->wake[0] = d->wake[1] = -1;
    d->frame_len = ISO_DISPLAY_FRAME_HEADER + (size_t)12 * (size_t)nv;
    /* The loop's tick takes it to publish: a server thread holding it runs
     * at the tick's priority until it lets go (no priority inversion). */
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&d->frame_lock, &ma);
    pthread_mutexattr_destroy(&ma);
    atomic_init(&d->published, 0);
    atomic_init(&d->wake_pending, 0);
    atomic_init(&d->stopping, 0);
    atomic_init(&d->viewers, 0);
    atomic_init(&d->frames_sent, 0);
    int rc;
    const char *three = opts->three_js ? opts->three_js : ISO_DISPLAY_DEFAULT_THREE;
    if ((rc = iso_file_read(three, 0, &d->three, &d->three_len, NULL)) < 0) {
        rc = iso_err_set(err, ISO_EIO, -1,
                         "display: three.js not found at %s: %s (install Debian's libjs-three)",
                         three, strerror(errno));
        goto fail;
    }
    if (iso_file_read(ORBIT_JS, 0, &d->orbit, &d->orbit_len, NULL) < 0)
        d->orbit = NULL; /* the page has its own orbit control */
    if (iso_file_read(GLTF_JS, 0, &d->gltf, &d->gltf_len, NULL) < 0)
        d->gltf = NULL; /* the page's Save .glb button then says what is missing */
    if ((rc = build_topology(d, opts->regions, err)) < 0)
        goto fail;
    d->latest = calloc(1, d->frame_len);
    if (!d->latest) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
        goto fail;
    }
    if ((rc = open_wake_pipe(d, err)) < 0 || (rc = iso_display__listen(d, opts, err)) < 0)
        goto fail;
    if (pthread_create(&d->server, NULL, iso_display__serve, d) != 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "display: cannot start the server thread");
        goto fail;
    }
    d->server_started = 1;
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
    return d ? atomic_load(&((iso_display *)d)->viewers) : 0;
}

long iso_display_frames_sent(const iso_display *d)
{
    return d ? atomic_load(&((iso_display *)d)->frames_sent) : 0;
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
    atomic_store(&d->published, d->latest_seq);
    pthread_mutex_unlock(&d->frame_lock);
    wake_server(d);
    return ISO_OK;
}

void iso_display_destroy(iso_display *d)
{
    if (!d)
        return;
    if (d->server_started) {
        atomic_store(&d->stopping, 1);
        atomic_store(&d->wake_pending, 0); /* make sure this wake is written */
        wake_server(d);
        pthread_join(d->server, NULL);
    }
    iso_display__server_free(d);
    for (int i = 0; i < 2; i++)
        if (d->wake[i] >= 0)
            close(d->wake[i]);
    pthread_mutex_destroy(&d->frame_lock);
    iso_display__fox_shared_free(atomic_load(&d->fox));
    free(d->fox_frame);
    free(d->three);
    free(d->orbit);
    free(d->gltf);
    free(d->topology);
    free(d->latest);
    free(d);
}
