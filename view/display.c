/* view/display.c -- the live view's API: create, publish, counters and
 * destroy (see iso_display.h). The server itself is display_server.c. */
#include "iso_display.h"

#include "display_internal.h"
#include "iso_fd.h"
#include "iso_file.h"
#include "iso_snapshot.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the display's frame format is written as host floats: little-endian hosts only"
#endif

#define CONTROLS_DIR "/usr/share/javascript/three/examples/js/controls/"
#define ORBIT_JS CONTROLS_DIR "OrbitControls.js"
#define GIZMO_JS CONTROLS_DIR "TransformControls.js"
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

/* The control part of the topology: the handles the page may move, each
 * with its rest centroid (the gizmo's pivot), or null when read-only. */
static void control_json(sbuf *b, const iso_display *d, const iso_display_opts *o)
{
    if (!o->view_device) {
        sb_printf(b, ",\"control\":null");
        return;
    }
    const double *x = iso_mesh_positions(o->mesh);
    sb_printf(b, ",\"control\":{\"handles\":[");
    for (int j = 0; j < o->n_handles; j++) {
        double c[3] = {0, 0, 0}, n = 0;
        for (int v = 0; o->regions && v < o->regions->nv; v++)
            if (o->regions->kind[v] == ISO_HANDLE &&
                o->regions->handle[v] == o->handles[j].handle) {
                for (int k = 0; k < 3; k++)
                    c[k] += x[3 * v + k];
                n += 1;
            }
        for (int k = 0; k < 3 && n > 0; k++)
            c[k] /= n;
        sb_printf(b, "%s{\"name\":\"", j ? "," : "");
        for (const char *p = o->handles[j].name ? o->handles[j].name : "?"; *p; p++) {
            if (*p == '"' || *p == '\\')
                sb_printf(b, "\\%c", *p);
            else
                sb_printf(b, "%c", (unsigned char)*p < 32 ? '?' : *p);
        }
        sb_printf(b, "\",\"handle\":%d,\"centre\":[%.17g,%.17g,%.17g]}", o->handles[j].handle, c[0],
                  c[1], c[2]);
    }
    sb_printf(b, "],\"token\":%s}", d->token[0] ? "true" : "false");
}

/* The topology message (iso_display.h, "Wire format"): a 16-byte header,
 * the JSON of what is small (padded with spaces so that the arrays after
 * it fall on 4-byte bounds, as a page's typed arrays need), then the rest
 * positions as f32, the triangles as u32 and the kinds as u8. As JSON a
 * 1M-vertex mesh's was 84 MB, seconds to print and to parse; binary it is
 * 37 MB and needs neither. */
static int build_topology(iso_display *d, const iso_display_opts *o, iso_err *err)
{
    const iso_regions *r = o->regions;
    sbuf b = {malloc(4096), 0, 4096, 0};
    if (!b.p)
        return iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    int nt = iso_mesh_triangle_count(d->mesh);
    sb_printf(&b, "{\"type\":\"topology\",\"nv\":%d,\"nt\":%d,\"strain_full\":%g,\"nh\":%d", d->nv,
              nt, ISO_SNAPSHOT_STRAIN_FULL, d->nh);
    control_json(&b, d, o);
    sb_printf(&b, "}");
    while (!b.oom && b.len % 4)
        sb_printf(&b, " ");
    size_t json = b.len;
    size_t len =
        ISO_DISPLAY_TOPOLOGY_HEADER + json + 12 * (size_t)d->nv + 12 * (size_t)nt + (size_t)d->nv;
    unsigned char *m = b.oom ? NULL : malloc(len);
    if (!m) {
        free(b.p);
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "display: out of memory for the topology (%zu bytes)", len);
    }
    uint32_t head[4] = {ISO_DISPLAY_TOPOLOGY_MAGIC, (uint32_t)d->nv, (uint32_t)nt, (uint32_t)json};
    memcpy(m, head, sizeof head);
    memcpy(m + ISO_DISPLAY_TOPOLOGY_HEADER, b.p, json);
    free(b.p);
    const double *x = iso_mesh_positions(d->mesh);
    const int *tri = iso_mesh_triangles(d->mesh);
    unsigned char *at = m + ISO_DISPLAY_TOPOLOGY_HEADER + json;
    for (int i = 0; i < 3 * d->nv; i++, at += 4) {
        float f = (float)x[i];
        memcpy(at, &f, 4);
    }
    for (int i = 0; i < 3 * nt; i++, at += 4) {
        uint32_t u = (uint32_t)tri[i];
        memcpy(at, &u, 4);
    }
    for (int i = 0; i < d->nv; i++)
        *at++ = (unsigned char)(r ? r->kind[i] : ISO_FREE);
    d->topology = (char *)m;
    d->topology_len = len;
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
void iso_display__wake(iso_display *d)
{
    if (atomic_exchange(&d->wake_pending, 1))
        return;
    ssize_t w = write(d->wake[1], "w", 1);
    (void)w; /* full pipe: the server is awake anyway */
}

/* 128 bits from the kernel's generator, as 32 hex digits. */
static int make_token(iso_display *d, iso_err *err)
{
    unsigned char b[16];
    int fd = open("/dev/urandom", O_RDONLY | O_CLOEXEC);
    ssize_t n = fd >= 0 ? read(fd, b, sizeof b) : -1;
    if (fd >= 0)
        close(fd);
    if (n != (ssize_t)sizeof b)
        return iso_err_set(err, ISO_EIO, -1,
                           "display: cannot read /dev/urandom for the command token: %s",
                           n < 0 ? strerror(errno) : "short read");
    for (int i = 0; i < 16; i++)
        snprintf(d->token + 2 * i, 3, "%02x", b[i]);
    return ISO_OK;
}

static int check_opts(const iso_display_opts *o, int nv, iso_err *err)
{
    if (o->port < 0 || o->port > 65535)
        return iso_err_set(err, ISO_EINVAL, -1, "display: port %d is outside 0..65535", o->port);
    if (o->regions && o->regions->nv != nv)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "display: regions have %d vertices, the mesh has %d", o->regions->nv,
                           nv);
    if (o->view_device && !iso_dev_is_view(o->view_device))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "display: the view device is not one (iso_dev_view_open makes it)");
    if (o->n_handles < 0 || o->n_handles > ISO_DISPLAY_MAX_HANDLES ||
        (o->n_handles > 0 && !o->handles))
        return iso_err_set(err, ISO_EINVAL, -1, "display: %d handles to command (at most %d)",
                           o->n_handles, ISO_DISPLAY_MAX_HANDLES);
    return ISO_OK;
}

static void init_state(iso_display *d, const iso_display_opts *o, int nv)
{
    d->mesh = o->mesh;
    d->nv = nv;
    d->nh = o->regions ? o->regions->n_handles : 0;
    if (d->nh > ISO_DISPLAY_MAX_HANDLES)
        d->nh = ISO_DISPLAY_MAX_HANDLES;
    d->dev = o->view_device;
    d->n_cmd_handles = o->view_device ? o->n_handles : 0;
    d->listen_fd = d->wake[0] = d->wake[1] = -1;
    d->frame_len = ISO_DISPLAY_FRAME_HEADER + (size_t)ISO_DISPLAY_FRAME_POSE * (size_t)d->nh +
                   (size_t)12 * (size_t)nv;
    /* The loop's tick takes it to publish: a server thread holding it runs
     * at the tick's priority until it lets go (no priority inversion). */
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&d->frame_lock, &ma);
    pthread_mutex_init(&d->note_lock, &ma); /* the loop's notes, for the same reason */
    pthread_mutexattr_destroy(&ma);
    atomic_init(&d->published, 0);
    atomic_init(&d->wake_pending, 0);
    atomic_init(&d->stopping, 0);
    atomic_init(&d->viewers, 0);
    atomic_init(&d->frames_sent, 0);
    atomic_init(&d->note_ver, 0);
    atomic_init(&d->ended, 0);
    atomic_init(&d->holder, 0);
    atomic_init(&d->cmd_accepted, 0);
    atomic_init(&d->cmd_refused, 0);
    atomic_init(&d->cmd_malformed, 0);
    atomic_init(&d->cmd_dropped, 0);
    atomic_init(&d->cmd_grants, 0);
    atomic_init(&d->cmd_stops, 0);
}

static int read_scripts(iso_display *d, const iso_display_opts *o, iso_err *err)
{
    const char *three = o->three_js ? o->three_js : ISO_DISPLAY_DEFAULT_THREE;
    if (iso_file_read(three, 0, &d->three, &d->three_len, NULL) < 0)
        return iso_err_set(err, ISO_EIO, -1,
                           "display: three.js not found at %s: %s (install Debian's libjs-three)",
                           three, strerror(errno));
    /* the page has controls of its own for when the examples are absent */
    if (iso_file_read(ORBIT_JS, 0, &d->orbit, &d->orbit_len, NULL) < 0)
        d->orbit = NULL;
    if (iso_file_read(GIZMO_JS, 0, &d->gizmo, &d->gizmo_len, NULL) < 0)
        d->gizmo = NULL;
    if (iso_file_read(GLTF_JS, 0, &d->gltf, &d->gltf_len, NULL) < 0)
        d->gltf = NULL; /* the page's Save .glb button then says what is missing */
    return ISO_OK;
}

int iso_display_create(const iso_display_opts *opts, iso_display **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!opts || !opts->mesh || !out)
        return iso_err_set(err, ISO_EINVAL, -1, "display: NULL options, mesh or out argument");
    int nv = iso_mesh_vertex_count(opts->mesh);
    int rc = check_opts(opts, nv, err);
    if (rc != ISO_OK)
        return rc;
    iso_display *d = calloc(1, sizeof *d);
    if (!d)
        return iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
    init_state(d, opts, nv);
    if ((rc = read_scripts(d, opts, err)) < 0 || (rc = open_wake_pipe(d, err)) < 0 ||
        (rc = iso_display__listen(d, opts, err)) < 0)
        goto fail;
    if (d->dev && d->remote && (rc = make_token(d, err)) < 0)
        goto fail;
    if ((rc = build_topology(d, opts, err)) < 0)
        goto fail;
    d->latest = calloc(1, d->frame_len);
    if (!d->latest) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
        goto fail;
    }
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

const char *iso_display_token(const iso_display *d)
{
    return d ? d->token : "";
}

int iso_display_url(const iso_display *d, char *buf, size_t cap)
{
    if (!d)
        return snprintf(buf, cap, "%s", "");
    return snprintf(buf, cap, "http://%s:%d/%s%s", d->host_name, d->port,
                    d->token[0] ? "?token=" : "", d->token);
}

int iso_display_clients(const iso_display *d)
{
    return d ? atomic_load(&((iso_display *)d)->viewers) : 0;
}

long iso_display_frames_sent(const iso_display *d)
{
    return d ? atomic_load(&((iso_display *)d)->frames_sent) : 0;
}

void iso_display_command_stats_get(const iso_display *cd, iso_display_command_stats *out)
{
    memset(out, 0, sizeof *out);
    iso_display *d = (iso_display *)cd; /* atomic loads take non-const pointers */
    if (!d)
        return;
    out->accepted = atomic_load(&d->cmd_accepted);
    out->refused = atomic_load(&d->cmd_refused);
    out->malformed = atomic_load(&d->cmd_malformed);
    out->dropped = atomic_load(&d->cmd_dropped);
    out->grants = atomic_load(&d->cmd_grants);
    out->stops = atomic_load(&d->cmd_stops);
}

uint32_t iso_display_holder(const iso_display *d)
{
    return d ? atomic_load(&((iso_display *)d)->holder) : 0;
}

static float to_f32(double v)
{
    return (float)v;
}

static uint32_t saturate_u32(long v)
{
    return v < 0 ? 0 : v > 0xffffffffL ? 0xffffffffu : (uint32_t)v;
}

/* R (row-major rotation) as a unit quaternion x y z w, by the largest of
 * its four candidate components (no loss of precision near a half-turn). */
static void quaternion_of(const double R[9], double q[4])
{
    double tr = R[0] + R[4] + R[8];
    if (tr > 0) {
        double s = 2 * sqrt(tr + 1);
        q[3] = 0.25 * s;
        q[0] = (R[7] - R[5]) / s;
        q[1] = (R[2] - R[6]) / s;
        q[2] = (R[3] - R[1]) / s;
    } else if (R[0] > R[4] && R[0] > R[8]) {
        double s = 2 * sqrt(1 + R[0] - R[4] - R[8]);
        q[3] = (R[7] - R[5]) / s;
        q[0] = 0.25 * s;
        q[1] = (R[1] + R[3]) / s;
        q[2] = (R[2] + R[6]) / s;
    } else if (R[4] > R[8]) {
        double s = 2 * sqrt(1 + R[4] - R[0] - R[8]);
        q[3] = (R[2] - R[6]) / s;
        q[0] = (R[1] + R[3]) / s;
        q[1] = 0.25 * s;
        q[2] = (R[5] + R[7]) / s;
    } else {
        double s = 2 * sqrt(1 + R[8] - R[0] - R[4]);
        q[3] = (R[3] - R[1]) / s;
        q[0] = (R[2] + R[6]) / s;
        q[1] = (R[5] + R[7]) / s;
        q[2] = 0.25 * s;
    }
}

/* The header and the handle poses of iso_display.h's frame. */
static void frame_head(const iso_display *d, unsigned char *f, long tick,
                       const iso_display_stats *st)
{
    static const iso_display_stats none;
    if (!st)
        st = &none;
    uint32_t u[2] = {ISO_DISPLAY_FRAME_MAGIC, (uint32_t)d->nv};
    double t = (double)tick;
    float s[4] = {to_f32(st->tick_ms_median), to_f32(st->tick_ms_p99), to_f32(st->tick_ms_max),
                  to_f32(st->latency_ms)};
    uint32_t w[4] = {saturate_u32(st->misses), (uint32_t)d->nh, st->cmd_conn, st->cmd_seq};
    uint32_t fl[2] = {st->flags, 0};
    memcpy(f, u, 8);
    memcpy(f + 8, &t, 8);
    memcpy(f + 16, s, 16);
    memcpy(f + 32, w, 16);
    memcpy(f + 48, &st->cmd_page_ms, 8);
    memcpy(f + 56, fl, 8);
    for (int h = 0; h < d->nh; h++) {
        double pq[7] = {0, 0, 0, 0, 0, 0, 1};
        if (h < st->n_handles) {
            memcpy(pq, st->handle[h].p, 3 * sizeof(double));
            quaternion_of(st->handle[h].R, pq + 3);
        }
        memcpy(f + ISO_DISPLAY_FRAME_HEADER + (size_t)ISO_DISPLAY_FRAME_POSE * (size_t)h, pq,
               sizeof pq);
    }
}

int iso_display_publish(iso_display *d, long tick, const double *x, const iso_display_stats *st,
                        iso_err *err)
{
    if (!d || !x)
        return iso_err_set(err, ISO_EINVAL, -1, "display: NULL display or positions");
    pthread_mutex_lock(&d->frame_lock);
    unsigned char *f = d->latest;
    frame_head(d, f, tick, st);
    float *p =
        (float *)(f + ISO_DISPLAY_FRAME_HEADER + (size_t)ISO_DISPLAY_FRAME_POSE * (size_t)d->nh);
    for (int i = 0; i < 3 * d->nv; i++)
        p[i] = (float)x[i];
    d->latest_seq++;
    atomic_store(&d->published, d->latest_seq);
    pthread_mutex_unlock(&d->frame_lock);
    iso_display__wake(d);
    return ISO_OK;
}

/* The note message, JSON-escaped once and never changed after: the server
 * reads it once it sees note_ver move. A later call with text sets it when
 * the first had none (the loop ends the view, then the command its note). */
static char *note_json(const char *text)
{
    sbuf b = {malloc(256), 0, 256, 0};
    if (!b.p)
        return NULL;
    sb_printf(&b, "{\"type\":\"note\",\"text\":\"");
    for (const char *p = text; *p && b.len < 4096 + 64; p++) {
        unsigned char ch = (unsigned char)*p;
        if (ch == '"' || ch == '\\')
            sb_printf(&b, "\\%c", ch);
        else if (ch == '\n')
            sb_printf(&b, "\\n");
        else
            sb_printf(&b, "%c", ch < 32 ? ' ' : ch);
    }
    sb_printf(&b, "\"}");
    if (b.oom) {
        free(b.p);
        return NULL;
    }
    return b.p;
}

void iso_display_end(iso_display *d, const char *text)
{
    if (!d)
        return;
    pthread_mutex_lock(&d->note_lock);
    if (text && !d->note && (d->note = note_json(text)) != NULL)
        atomic_fetch_add(&d->note_ver, 1);
    atomic_store(&d->ended, 1);
    pthread_mutex_unlock(&d->note_lock);
    iso_display__wake(d);
}

void iso_display_destroy(iso_display *d)
{
    if (!d)
        return;
    if (d->server_started) {
        atomic_store(&d->stopping, 1);
        atomic_store(&d->wake_pending, 0); /* make sure this wake is written */
        iso_display__wake(d);
        pthread_join(d->server, NULL);
    }
    iso_display__server_free(d);
    for (int i = 0; i < 2; i++)
        if (d->wake[i] >= 0)
            close(d->wake[i]);
    pthread_mutex_destroy(&d->frame_lock);
    pthread_mutex_destroy(&d->note_lock);
    iso_display__fox_shared_free(atomic_load(&d->fox));
    free(d->fox_frame);
    free(d->three);
    free(d->orbit);
    free(d->gizmo);
    free(d->gltf);
    free(d->topology);
    free(d->latest);
    free(d->note);
    free(d);
}
