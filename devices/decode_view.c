/* devices/decode_view.c -- the browser view's commands (iso_dev_view.h):
 * the one parser of a page's message, used by the view's server to route it
 * and by the decoder to apply it, and the decoder of the envelopes the
 * server queues.
 *
 * The decoder trusts nothing the server checked: it applies targets only
 * from the connection it last saw granted control, only with a growing
 * sequence number, and counts everything it refuses. A replay therefore
 * applies exactly what the live run applied, and a hand-edited recording
 * cannot do more than a page could. */
#include "internal.h"
#include "iso_dev_decode.h"
#include "iso_dev_view.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* Positions beyond this are no handle pose a page can mean (and their
 * squares would still be finite); rotation vectors beyond 4 pi neither. */
#define VIEW_MAX_POS 1e12
#define VIEW_MAX_ROT (4.0 * 3.14159265358979323846)

static uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static double rdf64(const uint8_t *p)
{
    uint64_t u = 0;
    for (int i = 7; i >= 0; i--)
        u = u << 8 | p[i];
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

static void wr32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void wrf64(uint8_t *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(u >> (8 * i));
}

static int refuse(char *why, size_t cap, const char *fmt, ...) ISO_PRINTF(3, 4);
static int refuse(char *why, size_t cap, const char *fmt, ...)
{
    if (why && cap) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(why, cap, fmt, ap);
        va_end(ap);
    }
    return ISO_EPARSE;
}

static const char *type_name(int t)
{
    static const char *const names[] = {"?", "TAKE", "RELEASE", "TARGET", "STOP", "UNSTOP"};
    return t >= 1 && t <= ISO_DEV_VIEW_UNSTOP ? names[t] : names[0];
}

int iso_dev_view_parse(const uint8_t *p, size_t n, iso_dev_view_msg *out, char *why, size_t cap)
{
    memset(out, 0, sizeof *out);
    if (n < ISO_DEV_VIEW_HEAD)
        return refuse(why, cap, "a message has at least %u bytes, not %zu", ISO_DEV_VIEW_HEAD, n);
    if (p[0] != ISO_DEV_VIEW_VERSION)
        return refuse(why, cap, "version %u (this view speaks %u)", p[0], ISO_DEV_VIEW_VERSION);
    int type = p[1];
    if (type < ISO_DEV_VIEW_TAKE || type > ISO_DEV_VIEW_UNSTOP)
        return refuse(why, cap, "unknown message type %d", type);
    size_t want = type == ISO_DEV_VIEW_TARGET ? ISO_DEV_VIEW_TARGET_LEN : ISO_DEV_VIEW_HEAD;
    if (n != want)
        return refuse(why, cap, "a %s message has %zu bytes, not %zu", type_name(type), want, n);
    if (p[3] != 0)
        return refuse(why, cap, "flags 0x%02x (none are defined)", p[3]);
    if (type == ISO_DEV_VIEW_TARGET ? p[2] >= ISO_DEV_MAX_HANDLES : p[2] != 0)
        return refuse(why, cap, "handle %u on a %s message", p[2], type_name(type));
    out->type = (uint8_t)type;
    out->handle = p[2];
    out->seq = rd32(p + 4);
    out->page_ms = rdf64(p + 8);
    if (out->seq == 0)
        return refuse(why, cap, "sequence number 0 (they start at 1)");
    if (!isfinite(out->page_ms))
        return refuse(why, cap, "the page's clock is not a finite number");
    if (type != ISO_DEV_VIEW_TARGET)
        return ISO_OK;
    double r2 = 0;
    for (int k = 0; k < 6; k++) {
        double v = rdf64(p + 16 + 8 * k);
        if (!isfinite(v) || (k < 3 && fabs(v) > VIEW_MAX_POS))
            return refuse(why, cap, "target %s %c is %g", k < 3 ? "position" : "rotation",
                          "xyzxyz"[k], v);
        out->pose[k] = v;
        if (k >= 3)
            r2 += v * v;
    }
    if (sqrt(r2) > VIEW_MAX_ROT)
        return refuse(why, cap, "a rotation of %g rad (at most 4 pi)", sqrt(r2));
    return ISO_OK;
}

int iso_dev_view_encode(const iso_dev_view_msg *m, uint8_t *dst, size_t cap)
{
    if (m->type < ISO_DEV_VIEW_TAKE || m->type > ISO_DEV_VIEW_UNSTOP)
        return ISO_EINVAL;
    size_t n = m->type == ISO_DEV_VIEW_TARGET ? ISO_DEV_VIEW_TARGET_LEN : ISO_DEV_VIEW_HEAD;
    if (cap < n)
        return ISO_EINVAL;
    memset(dst, 0, n);
    dst[0] = ISO_DEV_VIEW_VERSION;
    dst[1] = m->type;
    dst[2] = m->type == ISO_DEV_VIEW_TARGET ? m->handle : 0;
    wr32(dst + 4, m->seq);
    wrf64(dst + 8, m->page_ms);
    if (m->type == ISO_DEV_VIEW_TARGET)
        for (int k = 0; k < 6; k++)
            wrf64(dst + 16 + 8 * k, m->pose[k]);
    return (int)n;
}

/* ---- the decoder ---------------------------------------------------------- */

static void release(iso_dev_decoder *d, int64_t t, int reason, iso_dev_event *ev, size_t cap,
                    size_t *n)
{
    d->view.holder = 0;
    d->view.last_seq = 0;
    d->n.releases++;
    iso_dev_event *e = iso_dev__emit(d, t, ISO_DEV_EV_RELEASE, ev, cap, n);
    if (e)
        e->level = (uint8_t)reason;
}

static void set_estop(iso_dev_decoder *d, int64_t t, int on, uint32_t conn, iso_dev_event *ev,
                      size_t cap, size_t *n)
{
    if (d->view.estop == on)
        return;
    d->view.estop = (uint8_t)on;
    d->view.estop_conn = on ? conn : 0;
    iso_dev_event *e = iso_dev__emit(d, t, ISO_DEV_EV_GPIO, ev, cap, n);
    if (e) {
        e->line = ISO_DEV_GPIO_ESTOP;
        e->level = (uint8_t)on;
    }
}

/* A page's message inside an ISO_DEV_VIEW_MSG envelope. */
static void apply(iso_dev_decoder *d, int64_t t, uint32_t conn, const uint8_t *p, size_t len,
                  iso_dev_event *ev, size_t cap, size_t *n)
{
    iso_dev_view_msg m;
    if (iso_dev_view_parse(p, len, &m, NULL, 0) != ISO_OK) {
        d->n.bad_frames++;
        return;
    }
    switch (m.type) {
    case ISO_DEV_VIEW_STOP:
        d->n.reports++;
        set_estop(d, t, 1, conn, ev, cap, n);
        return;
    case ISO_DEV_VIEW_UNSTOP: /* who may release is the server's to decide: it pushes only those */
        d->n.reports++;
        set_estop(d, t, 0, conn, ev, cap, n);
        return;
    case ISO_DEV_VIEW_TARGET:
        if (conn == 0 || conn != d->view.holder) {
            d->n.refused++;
            return;
        }
        if (m.seq <= d->view.last_seq) {
            d->n.out_of_order++;
            return;
        }
        break;
    default: /* TAKE and RELEASE are the server's to decide: they come as envelopes */
        d->n.refused++;
        return;
    }
    d->view.last_seq = m.seq;
    d->view.applied_conn = conn;
    d->view.applied_seq = m.seq;
    d->view.applied_ms = m.page_ms;
    d->n.reports++;
    iso_dev_event *e = iso_dev__emit(d, t, ISO_DEV_EV_TARGET, ev, cap, n);
    if (e) {
        e->line = m.handle;
        memcpy(e->v, m.pose, sizeof e->v);
    }
}

size_t iso_dev__view_decode(iso_dev_decoder *d, int64_t t, const uint8_t *p, size_t len,
                            iso_dev_event *ev, size_t cap)
{
    size_t n = 0;
    if (len < ISO_DEV_VIEW_ENVELOPE) {
        d->n.short_reports++;
        return 0;
    }
    uint32_t conn = rd32(p + 1);
    const uint8_t *body = p + ISO_DEV_VIEW_ENVELOPE;
    size_t blen = len - ISO_DEV_VIEW_ENVELOPE;
    switch (p[0]) {
    case ISO_DEV_VIEW_MSG: apply(d, t, conn, body, blen, ev, cap, &n); break;
    case ISO_DEV_VIEW_GRANT:
        if (conn == 0 || blen != 0) {
            d->n.bad_frames++;
            break;
        }
        if (d->view.holder) /* a grant ends the last control, whatever the server said */
            release(d, t, ISO_DEV_VIEW_END_LEFT, ev, cap, &n);
        d->view.holder = conn;
        d->view.last_seq = 0;
        d->n.grants++;
        break;
    case ISO_DEV_VIEW_END:
        if (blen != 1 || body[0] < ISO_DEV_VIEW_END_RELEASED || body[0] > ISO_DEV_VIEW_END_LAPSED) {
            d->n.bad_frames++;
            break;
        }
        if (conn == d->view.holder && conn != 0)
            release(d, t, body[0], ev, cap, &n);
        else
            d->n.refused++;
        break;
    default: d->n.unknown_ids++; break;
    }
    return n;
}
