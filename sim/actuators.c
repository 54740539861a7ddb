/* sim/actuators.c -- see iso_actuators.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_actuators.h"
#include "iso_fb_host.h"

#define ECHO_SLOTS 128u /* sent values kept for the ACK check, by tick */

typedef struct act_channel {
    iso_act_channel spec;
    int *verts; /* region centroid: its vertices (owned); NULL for a vertex */
    int n_verts;
} act_channel;

typedef struct echo_slot {
    uint64_t sent_us; /* before the write, so a preempted write still counts */
    uint32_t tick;
    uint8_t n, used;
    int16_t value[ISO_ACT_MAX_CHANNELS];
} echo_slot;

struct iso_actuators {
    act_channel ch[ISO_ACT_MAX_CHANNELS];
    int n_ch, nv;
    int top;                              /* highest configured channel + 1 */
    int16_t values[ISO_ACT_MAX_CHANNELS]; /* last computed */
    iso_act_notice_fn notice;
    void *notice_ctx;

    iso_link *link; /* owned */
    iso_fb_host host;
    int host_up;
    int stopped;
    int mismatch;      /* the MCU lacks a configured channel */
    int told_channels; /* the count notice went out for this MCU description */
    echo_slot echo[ECHO_SLOTS];
    iso_fb_hello hello; /* MCU's last answer */
    int have_hello;
    /* safe_stop watches for these */
    int saw_safe;
    uint64_t safe_us, last_sent_us;
    iso_act_stats st;
};

static uint64_t now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void say(const iso_actuators *a, const char *line)
{
    if (a->notice)
        a->notice(a->notice_ctx, line);
    else
        fprintf(stderr, "%s\n", line);
}

/* ------------------------------------------------------------------------ */
/* The spec                                                                   */
/* ------------------------------------------------------------------------ */

static const char *region_name(int region, char *buf, size_t cap)
{
    if (region == ISO_ACT_REGION_FIXED)
        snprintf(buf, cap, "the fixed region");
    else
        snprintf(buf, cap, "handle %d", region);
    return buf;
}

static int check_channel(const iso_act_channel *c, int i, int nv, const iso_regions *r,
                         iso_err *err)
{
    if (c->channel < 0 || c->channel >= ISO_ACT_MAX_CHANNELS)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel entry %d: channel %d is out of range (0..%d: a "
                           "SETPOINTS frame carries %d)",
                           i, c->channel, ISO_ACT_MAX_CHANNELS - 1, ISO_ACT_MAX_CHANNELS);
    if (c->axis < 0 || c->axis > 2)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: axis %d is not 0 (x), 1 (y) or 2 (z)",
                           c->channel, c->axis);
    if (!isfinite(c->min) || !isfinite(c->max) || !(c->min < c->max))
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: limits [%g, %g] need finite min < max",
                           c->channel, c->min, c->max);
    if (!isfinite(c->scale) || c->scale == 0)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: scale %g must be finite and not 0", c->channel,
                           c->scale);
    if (c->region == ISO_ACT_REGION_NONE) {
        if (c->vertex < 0 || c->vertex >= nv)
            return iso_err_set(err, ISO_EINVAL, i,
                               "actuators: channel %d: vertex %d is out of range (the mesh has %d "
                               "vertices)",
                               c->channel, c->vertex, nv);
        return ISO_OK;
    }
    if (c->vertex >= 0)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: names both vertex %d and a region; give one",
                           c->channel, c->vertex);
    char rn[32];
    if (c->region < ISO_ACT_REGION_FIXED)
        return iso_err_set(err, ISO_EINVAL, i, "actuators: channel %d: region %d is not a region",
                           c->channel, c->region);
    if (!r || r->nv != nv)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d follows %s but no regions for the %d-vertex mesh "
                           "were given",
                           c->channel, region_name(c->region, rn, sizeof rn), nv);
    if (c->region >= r->n_handles)
        return iso_err_set(err, ISO_EINVAL, i,
                           "actuators: channel %d: handle %d does not exist (the regions have %d "
                           "handle%s)",
                           c->channel, c->region, r->n_handles, r->n_handles == 1 ? "" : "s");
    return ISO_OK;
}

static int in_region(const iso_regions *r, int v, int region)
{
    if (region == ISO_ACT_REGION_FIXED)
        return r->kind[v] == ISO_FIXED;
    return r->kind[v] == ISO_HANDLE && r->handle[v] == region;
}

static int collect_region(act_channel *c, int nv, const iso_regions *r, int i, iso_err *err)
{
    int n = 0;
    for (int v = 0; v < nv; v++)
        n += in_region(r, v, c->spec.region);
    char rn[32];
    if (n == 0)
        return iso_err_set(err, ISO_EINVAL, i, "actuators: channel %d follows %s, which is empty",
                           c->spec.channel, region_name(c->spec.region, rn, sizeof rn));
    c->verts = malloc((size_t)n * sizeof *c->verts);
    if (!c->verts)
        return iso_err_set(err, ISO_ENOMEM, i, "actuators: out of memory");
    c->n_verts = 0;
    for (int v = 0; v < nv; v++)
        if (in_region(r, v, c->spec.region))
            c->verts[c->n_verts++] = v;
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Callbacks from the firmware-bridge host                                    */
/* ------------------------------------------------------------------------ */

static void tell_channel_disagreement(iso_actuators *a)
{
    char line[512];
    int mcu = a->hello.n_channels;
    if (a->top > mcu) {
        snprintf(line, sizeof line,
                 "actuators: the MCU has %d channel%s but the spec drives channel %d: sending no "
                 "setpoints (the MCU's watchdog keeps it safe)",
                 mcu, mcu == 1 ? "" : "s", a->top - 1);
        say(a, line);
        return;
    }
    int len = snprintf(line, sizeof line,
                       "actuators: the MCU has %d channels, the spec drives %d:", mcu, a->n_ch);
    for (int c = 0; c < mcu && len < (int)sizeof line; c++) {
        int driven = 0;
        for (int i = 0; i < a->n_ch; i++)
            driven |= a->ch[i].spec.channel == c;
        if (!driven)
            len += snprintf(line + len, sizeof line - (size_t)len,
                            " channel %d held at its safe %d;", c, a->hello.ch[c].safe);
    }
    if (len > 0 && len < (int)sizeof line)
        line[len - 1] = '\0';
    say(a, line);
}

/* Scene limits beyond what the MCU will do are worth one line: the MCU
 * clamps silently, which would look like a tracking error. */
static void tell_limit_disagreement(iso_actuators *a)
{
    for (int i = 0; i < a->n_ch; i++) {
        const iso_act_channel *c = &a->ch[i].spec;
        if (c->channel >= a->hello.n_channels)
            continue;
        double lo = c->min * c->scale, hi = c->max * c->scale;
        if (lo > hi) {
            double t = lo;
            lo = hi;
            hi = t;
        }
        const iso_fb_channel_info *m = &a->hello.ch[c->channel];
        if (lo < m->min || hi > m->max) {
            char line[256];
            snprintf(line, sizeof line,
                     "actuators: channel %d spans [%.0f, %.0f] milli-units, the MCU's limits are "
                     "[%d, %d]; "
                     "it clamps the rest",
                     c->channel, lo, hi, m->min, m->max);
            say(a, line);
        }
    }
}

static void on_hello(void *ctx, const iso_fb_hello *h)
{
    iso_actuators *a = ctx;
    if (h->flags & ISO_FB_HELLO_BOOT)
        return; /* the unasked one; the answer follows our HELLO */
    int changed = !a->have_hello || a->hello.n_channels != h->n_channels ||
                  memcmp(a->hello.ch, h->ch, sizeof h->ch) != 0;
    a->hello = *h;
    a->have_hello = 1;
    a->st.mcu_channels = h->n_channels;
    a->mismatch = a->top > h->n_channels;
    if (changed)
        a->told_channels = 0;
    if (!a->told_channels) {
        a->told_channels = 1;
        if (a->top > h->n_channels || a->n_ch != h->n_channels)
            tell_channel_disagreement(a);
        tell_limit_disagreement(a);
    }
}

static void on_ack(void *ctx, const iso_fb_ack *k)
{
    iso_actuators *a = ctx;
    if (k->type != ISO_FB_SETPOINTS)
        return;
    a->st.acks++;
    const echo_slot *s = &a->echo[k->tick % ECHO_SLOTS];
    if (!s->used || s->tick != k->tick) {
        a->st.echo_unknown++;
        return;
    }
    if (s->n != k->n || memcmp(s->value, k->value, (size_t)k->n * sizeof k->value[0]) != 0)
        a->st.echo_mismatches++;
    double ms = (double)(now_us() - s->sent_us) / 1000.0;
    iso_act_stats *st = &a->st;
    st->rtt_last_ms = ms;
    st->rtt_avg_ms = (st->rtt_avg_ms * st->rtt_count + ms) / (st->rtt_count + 1);
    if (st->rtt_count == 0 || ms < st->rtt_min_ms)
        st->rtt_min_ms = ms;
    if (ms > st->rtt_max_ms)
        st->rtt_max_ms = ms;
    st->rtt_count++;
}

static void on_fault(void *ctx, const iso_fb_fault *f)
{
    iso_actuators *a = ctx;
    a->st.faults++;
    a->st.last_fault_reason = f->reason;
    a->st.last_fault_detail_ms = f->detail;
    if (!a->saw_safe) {
        a->saw_safe = 1;
        a->safe_us = now_us();
    }
}

static void on_heartbeat(void *ctx, const iso_fb_heartbeat *hb)
{
    iso_actuators *a = ctx;
    a->st.heartbeats++;
    a->st.mcu_state = hb->state;
    a->st.mcu_uptime_ms = hb->uptime_ms;
    for (unsigned c = 0; c < hb->n && c < ISO_ACT_MAX_CHANNELS; c++)
        a->st.mcu_pos[c] = hb->pos[c];
    if (hb->state != ISO_FB_STATE_ARMED && !a->saw_safe) {
        a->saw_safe = 1;
        a->safe_us = now_us();
    }
}

/* ------------------------------------------------------------------------ */
/* Create / destroy                                                           */
/* ------------------------------------------------------------------------ */

static int open_link(iso_actuators *a, const iso_act_link_spec *l, iso_err *err)
{
    int baud = l->baud > 0 ? l->baud : 115200;
    switch (l->kind) {
    case ISO_ACT_LINK_TTY: return iso_link_tty_open(l->path, baud, &a->link, err);
    case ISO_ACT_LINK_SERIAL: return iso_link_sp_open(l->path, baud, &a->link, err);
    /* 5 ms: a reopen after a loss runs inside publish, which must stay short */
    case ISO_ACT_LINK_TCP: return iso_link_tcp_open(l->host, l->port, 5, &a->link, err);
    case ISO_ACT_LINK_EMULATED: {
        iso_act_emu_info info;
        int rc = iso_act_emu_open(l->emulation, &a->link, &info, err);
        if (rc == ISO_OK)
            say(a, info.line);
        return rc;
    }
    }
    return iso_err_set(err, ISO_EINVAL, -1, "actuators: unknown link kind %d", l->kind);
}

int iso_actuators_create(const iso_act_channel *ch, int n_ch, int nv, const iso_regions *regions,
                         const iso_act_link_spec *link, const iso_act_opts *opts,
                         iso_actuators **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!out || !ch || n_ch < 1 || n_ch > ISO_ACT_MAX_CHANNELS || nv < 1)
        return iso_err_set(
            err, ISO_EINVAL, -1,
            "actuators: need 1..%d channels over a mesh with vertices (got %d channels, "
            "%d vertices)",
            ISO_ACT_MAX_CHANNELS, n_ch, nv);
    iso_actuators *a = calloc(1, sizeof *a);
    if (!a)
        return iso_err_set(err, ISO_ENOMEM, -1, "actuators: out of memory");
    a->nv = nv;
    a->st.mcu_state = -1;
    if (opts) {
        a->notice = opts->notice;
        a->notice_ctx = opts->notice_ctx;
    }
    int rc = ISO_OK;
    for (int i = 0; i < n_ch && rc == ISO_OK; i++) {
        if ((rc = check_channel(&ch[i], i, nv, regions, err)) != ISO_OK)
            break;
        for (int j = 0; j < i; j++)
            if (ch[j].channel == ch[i].channel) {
                rc = iso_err_set(err, ISO_EINVAL, i,
                                 "actuators: channel %d is used twice (entries %d and %d)",
                                 ch[i].channel, j, i);
                break;
            }
        if (rc != ISO_OK)
            break;
        a->ch[i].spec = ch[i];
        a->n_ch = i + 1;
        if (ch[i].region != ISO_ACT_REGION_NONE)
            rc = collect_region(&a->ch[i], nv, regions, i, err);
        if (ch[i].channel + 1 > a->top)
            a->top = ch[i].channel + 1;
    }
    if (rc == ISO_OK && link && link->kind != ISO_ACT_LINK_NONE) {
        rc = open_link(a, link, err);
        if (rc == ISO_OK) {
            iso_fb_host_callbacks cb = {NULL, on_ack, on_fault, on_hello, on_heartbeat, a};
            iso_fb_host_opts ho = {0};
            ho.write_timeout_ms = 1; /* never hold the loop */
            ho.link_timeout_ms = opts && opts->link_timeout_ms > 0     ? opts->link_timeout_ms
                                 : link->kind == ISO_ACT_LINK_EMULATED ? 3000
                                                                       : 1000;
            rc = iso_fb_host_init(&a->host, a->link, &ho, &cb, err);
            a->host_up = rc == ISO_OK;
        }
    }
    if (rc != ISO_OK) {
        iso_actuators_destroy(a);
        return rc;
    }
    *out = a;
    return ISO_OK;
}

void iso_actuators_destroy(iso_actuators *a)
{
    if (!a)
        return;
    if (a->host_up)
        iso_fb_host_deinit(&a->host);
    iso_link_close(a->link);
    for (int i = 0; i < a->n_ch; i++)
        free(a->ch[i].verts);
    free(a);
}

/* ------------------------------------------------------------------------ */
/* Per tick                                                                   */
/* ------------------------------------------------------------------------ */

static double coordinate(const act_channel *c, const double *x)
{
    int ax = c->spec.axis;
    if (!c->verts)
        return x[3 * c->spec.vertex + ax];
    double sum = 0;
    for (int k = 0; k < c->n_verts; k++)
        sum += x[3 * c->verts[k] + ax];
    return sum / c->n_verts;
}

int iso_actuators_compute(iso_actuators *a, const double *x, int16_t values[ISO_ACT_MAX_CHANNELS],
                          iso_err *err)
{
    if (!a || !x || !values)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: NULL handle, positions or values");
    double u[ISO_ACT_MAX_CHANNELS];
    for (int i = 0; i < a->n_ch; i++) {
        u[i] = coordinate(&a->ch[i], x);
        if (!isfinite(u[i]))
            return iso_err_set(
                err, ISO_ENUMERIC, -1,
                "actuators: channel %d: its position is not finite (%g); nothing sent",
                a->ch[i].spec.channel, u[i]);
    }
    for (int i = 0; i < a->n_ch; i++) {
        const iso_act_channel *c = &a->ch[i].spec;
        int clamped = 0;
        double v = u[i];
        if (v < c->min || v > c->max) {
            v = v < c->min ? c->min : c->max;
            clamped = 1;
        }
        double m = nearbyint(v * c->scale);
        if (m < INT16_MIN || m > INT16_MAX) {
            m = m < INT16_MIN ? INT16_MIN : INT16_MAX;
            clamped = 1;
        }
        values[c->channel] = (int16_t)m;
        a->st.clamps += (uint64_t)clamped;
        a->st.clamps_ch[c->channel] += (uint64_t)clamped;
    }
    a->st.ticks++;
    return ISO_OK;
}

static void remember(iso_actuators *a, uint32_t tick, const int16_t *v, unsigned n)
{
    echo_slot *s = &a->echo[tick % ECHO_SLOTS];
    s->tick = tick;
    s->n = (uint8_t)n;
    s->used = 1;
    s->sent_us = now_us();
    memcpy(s->value, v, n * sizeof *v);
}

int iso_actuators_publish(iso_actuators *a, uint32_t tick, const double *x, iso_err *err)
{
    if (!a || !x)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: NULL handle or positions");
    if (a->stopped)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "actuators: stopped by safe_stop; create a new sink");
    uint64_t t0 = now_us();
    int rc = iso_actuators_compute(a, x, a->values, err);
    if (rc != ISO_OK || !a->host_up)
        return rc == ISO_OK ? 0 : rc;
    if (a->mismatch) {
        iso_fb_host_poll(&a->host, 0); /* keep the counters and the MCU state current */
        return iso_err_set(err, ISO_EINVAL, -1,
                           "actuators: the MCU has %d channels but the spec drives channel %d; "
                           "nothing sent",
                           a->hello.n_channels, a->top - 1);
    }
    /* Undriven channels go out at the MCU's safe position. */
    int16_t v[ISO_ACT_MAX_CHANNELS];
    unsigned n = a->have_hello ? a->hello.n_channels : (unsigned)a->top;
    for (unsigned c = 0; c < n; c++)
        v[c] = a->have_hello ? a->hello.ch[c].safe : 0;
    for (int i = 0; i < a->n_ch; i++)
        v[a->ch[i].spec.channel] = a->values[a->ch[i].spec.channel];
    /* Remember before sending: the ACK may be read inside this very step. */
    remember(a, tick, v, n);
    uint64_t t_send = now_us();
    int sent = iso_fb_host_step(&a->host, tick, v, n);
    if (sent == 1) {
        a->st.setpoints_sent++;
        a->last_sent_us = t_send; /* before the write: the watchdog counts from its arrival */
    }
    double ms = (double)(now_us() - t0) / 1000.0;
    if (ms > a->st.publish_max_ms)
        a->st.publish_max_ms = ms;
    a->st.publish_over_1ms += ms > 1.0;
    return sent < 0 ? iso_err_set(err, sent, -1, "actuators: bad setpoints for the link") : sent;
}

int iso_actuators_poll(iso_actuators *a, int timeout_ms)
{
    if (!a || !a->host_up)
        return 0;
    return iso_fb_host_poll(&a->host, timeout_ms);
}

int iso_actuators_safe_stop(iso_actuators *a, int timeout_ms, double *safe_ms, iso_err *err)
{
    if (safe_ms)
        *safe_ms = -1;
    if (!a || !a->host_up)
        return iso_err_set(err, ISO_EINVAL, -1, "actuators: safe_stop needs a link");
    a->stopped = 1;
    /* Only what arrives from now on counts: an earlier FAULT was answered
     * by a new HELLO and streaming since. */
    a->saw_safe = 0;
    uint64_t start = now_us(),
             deadline = start + (uint64_t)(timeout_ms > 0 ? timeout_ms : 0) * 1000u;
    while (!a->saw_safe) {
        uint64_t now = now_us();
        if (now >= deadline)
            break;
        if (a->host.state == ISO_FB_HOST_DOWN)
            return iso_err_set(err, ISO_EIO, -1,
                               "actuators: the link is down, so the MCU's safe state cannot be "
                               "confirmed (its watchdog takes it there 100 ms after the last "
                               "setpoints it got): %s",
                               a->host.last_err.msg);
        uint64_t left = (deadline - now + 999u) / 1000u;
        iso_fb_host_poll(&a->host, left > 10 ? 10 : (int)left);
    }
    if (!a->saw_safe)
        return iso_err_set(err, ISO_EIO, -1,
                           "actuators: the MCU did not report its safe state within %d ms of the "
                           "stop (link %s)",
                           timeout_ms, a->host.state == ISO_FB_HOST_DOWN ? "down" : "up");
    if (safe_ms)
        *safe_ms = (double)(a->safe_us - (a->last_sent_us ? a->last_sent_us : start)) / 1000.0;
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Counters                                                                   */
/* ------------------------------------------------------------------------ */

void iso_actuators_stats(const iso_actuators *a, iso_act_stats *out)
{
    *out = a->st;
    if (!a->host_up)
        return;
    const iso_fb_host_stats *h = &a->host.stats;
    out->link_losses = h->link_losses;
    out->handshakes = h->handshakes;
    out->naks = h->naks;
}

int iso_actuators_mcu_hello(const iso_actuators *a, iso_fb_hello *out)
{
    if (!a->have_hello)
        return 0;
    *out = a->hello;
    return 1;
}

int iso_actuators_format_stats(const iso_actuators *a, char *buf, size_t cap)
{
    iso_act_stats s;
    iso_actuators_stats(a, &s);
    int n =
        snprintf(buf, cap,
                 "actuators: %llu ticks, %llu setpoints sent, %llu acked, %llu echo mismatches "
                 "(%llu unchecked), %llu clamps, rtt avg %.3f ms (max %.3f), publish max %.2f ms "
                 "(%llu over 1 ms)",
                 (unsigned long long)s.ticks, (unsigned long long)s.setpoints_sent,
                 (unsigned long long)s.acks, (unsigned long long)s.echo_mismatches,
                 (unsigned long long)s.echo_unknown, (unsigned long long)s.clamps, s.rtt_avg_ms,
                 s.rtt_max_ms, s.publish_max_ms, (unsigned long long)s.publish_over_1ms);
    if (!a->host_up || n < 0 || (size_t)n + 2 >= cap)
        return n;
    buf[n] = ';';
    buf[n + 1] = ' ';
    return n + 2 + iso_fb_host_format_stats(&a->host, buf + n + 2, cap - (size_t)n - 2);
}
