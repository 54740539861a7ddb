/* devices/decode.c -- decoders: bytes and timestamps in, events out.
 *
 * Every decoder counts what it cannot use and skips it; none fails on input.
 * The same code serves a live device and a replay, so a recording decodes to
 * the same events bit for bit. */
#include "iso_dev_decode.h"

#include <string.h>

#include "internal.h"
#include "iso_fb.h"
_Static_assert(sizeof(iso_fb_parser) <= sizeof(((iso_dev_decoder *)0)->fb),
               "iso_dev_decoder.fb holds an iso_fb_parser");

const char *iso_dev_kind_name(int kind)
{
    switch (kind) {
    case ISO_DEV_KIND_HID: return "hid";
    case ISO_DEV_KIND_SPNAV: return "spnav";
    case ISO_DEV_KIND_SERIAL: return "serial";
    case ISO_DEV_KIND_GPIO: return "gpio";
    case ISO_DEV_KIND_VIEW: return "view";
    default: return "unknown";
    }
}

static int16_t le16(const uint8_t *p)
{
    return (int16_t)(uint16_t)(p[0] | (uint16_t)p[1] << 8);
}

static void emit_axes(iso_dev_decoder *d, int64_t t, iso_dev_event *ev, size_t cap, size_t *n)
{
    iso_dev_event *e = iso_dev__emit(d, t, ISO_DEV_EV_AXES, ev, cap, n);
    if (e)
        memcpy(e->axes, d->axes, sizeof e->axes);
}

static void emit_buttons(iso_dev_decoder *d, int64_t t, uint32_t b, iso_dev_event *ev, size_t cap,
                         size_t *n)
{
    if (b == d->buttons)
        return;
    d->buttons = b;
    iso_dev_event *e = iso_dev__emit(d, t, ISO_DEV_EV_BUTTONS, ev, cap, n);
    if (e)
        e->buttons = b;
}

int iso_dev_decoder_init(iso_dev_decoder *d, const iso_dev_info *info, uint8_t source, iso_err *err)
{
    memset(d, 0, sizeof *d);
    d->kind = info->kind;
    d->source = source;
    d->noise_since = d->noise_last = INT64_MIN;
    d->debounce_ns = (int64_t)info->debounce_us * 1000;
    switch (info->kind) {
    case ISO_DEV_KIND_HID:
    case ISO_DEV_KIND_SPNAV:
    case ISO_DEV_KIND_GPIO:
    case ISO_DEV_KIND_VIEW: return ISO_OK;
    case ISO_DEV_KIND_SERIAL: iso_fb_parser_init((iso_fb_parser *)(void *)d->fb); return ISO_OK;
    default:
        return iso_err_set(err, ISO_EINVAL, -1, "source %u (%s): unknown device kind %d", source,
                           info->name, info->kind);
    }
}

/* ---- SpaceMouse HID reports --------------------------------------------- */

size_t iso_dev_sm_decode(iso_dev_decoder *d, int64_t t, const uint8_t *r, size_t len,
                         iso_dev_event *ev, size_t cap)
{
    size_t n = 0;
    if (len < 1) {
        d->n.short_reports++;
        return 0;
    }
    switch (r[0]) {
    case 1:
        /* 13 bytes: translation and rotation (newer models, the universal
         * receiver); 7 bytes: translation only, rotation follows in ID 2. */
        if (len >= 13) {
            for (int i = 0; i < 6; i++)
                d->axes[i] = le16(r + 1 + 2 * i);
        } else if (len >= 7) {
            for (int i = 0; i < 3; i++)
                d->axes[i] = le16(r + 1 + 2 * i);
        } else {
            d->n.short_reports++;
            return 0;
        }
        d->n.reports++;
        emit_axes(d, t, ev, cap, &n);
        return n;
    case 2:
        if (len < 7) {
            d->n.short_reports++;
            return 0;
        }
        for (int i = 0; i < 3; i++)
            d->axes[3 + i] = le16(r + 1 + 2 * i);
        d->n.reports++;
        emit_axes(d, t, ev, cap, &n);
        return n;
    case 3: {
        if (len < 2) {
            d->n.short_reports++;
            return 0;
        }
        uint32_t b = 0;
        for (size_t i = 1; i < len && i <= 4; i++)
            b |= (uint32_t)r[i] << (8 * (i - 1));
        d->n.reports++;
        emit_buttons(d, t, b, ev, cap, &n);
        return n;
    }
    default: d->n.unknown_ids++; return 0;
    }
}

/* ---- spacenavd events ---------------------------------------------------- */
/* 'M' + six LE int16 (x y z rx ry rz) + LE uint16 period, 15 bytes;
 * 'B' + button index + press, 3 bytes. One chunk may hold several. */
static size_t spnav_decode(iso_dev_decoder *d, int64_t t, const uint8_t *p, size_t len,
                           iso_dev_event *ev, size_t cap)
{
    size_t n = 0, i = 0;
    while (i < len) {
        if (p[i] == 'M') {
            if (len - i < 15) {
                d->n.short_reports++;
                return n;
            }
            for (int a = 0; a < 6; a++)
                d->axes[a] = le16(p + i + 1 + 2 * a);
            d->n.reports++;
            emit_axes(d, t, ev, cap, &n);
            i += 15;
        } else if (p[i] == 'B') {
            if (len - i < 3) {
                d->n.short_reports++;
                return n;
            }
            uint32_t b = d->buttons;
            if (p[i + 1] < 32) {
                uint32_t bit = (uint32_t)1 << p[i + 1];
                b = p[i + 2] ? (b | bit) : (b & ~bit);
                d->n.reports++;
                emit_buttons(d, t, b, ev, cap, &n);
            } else {
                d->n.unknown_ids++;
            }
            i += 3;
        } else {
            d->n.unknown_ids++;
            d->n.garbage++;
            i++;
        }
    }
    return n;
}

/* ---- the firmware bridge's serial stream ------------------------------- */

/* Garbage: every byte since the last frame boundary that no accepted frame
 * ends (the 0x00 that ends a stretch is a delimiter, not garbage). The
 * parser says where stretches end: a drop (a 0x00 that ends a bad frame,
 * or the byte that overflows the buffer, after which it skips to the next
 * 0x00), an accepted frame, or a 0x00 that ends a skipped stretch. */
static void serial_account(iso_dev_decoder *d, uint8_t byte, int rc)
{
    d->fb_pending++;
    if (rc == ISO_FB_FRAME)
        d->fb_pending = 0;
    else if (rc < 0 || byte == 0) {
        d->n.garbage += d->fb_pending - (byte == 0);
        d->fb_pending = 0;
    }
}

static size_t serial_decode(iso_dev_decoder *d, int64_t t, const uint8_t *p, size_t len,
                            iso_dev_event *ev, size_t cap)
{
    iso_fb_parser *fb = (iso_fb_parser *)(void *)d->fb;
    size_t n = 0;
    for (size_t i = 0; i < len; i++) {
        iso_fb_view v;
        int rc = iso_fb_parser_feed(fb, p[i], &v);
        serial_account(d, p[i], rc);
        if (rc < 0) {
            d->n.bad_frames++;
            continue;
        }
        if (rc != ISO_FB_FRAME || v.type != ISO_FB_HANDLE_SAMPLE)
            continue;
        iso_fb_sample s;
        if (iso_fb_sample_unpack(&s, v.payload, v.len) != 0) {
            d->n.bad_frames++;
            d->n.bad_payloads++;
            continue;
        }
        d->n.reports++;
        /* The bridge sends micrometres and microradians (per second for twists). */
        iso_dev_event *e = iso_dev__emit(
            d, t, s.kind == ISO_FB_SAMPLE_POSE ? ISO_DEV_EV_POSE : ISO_DEV_EV_TWIST, ev, cap, &n);
        if (e)
            for (int k = 0; k < 6; k++)
                e->v[k] = (double)s.v[k] * 1e-6;
        emit_buttons(d, t, s.buttons, ev, cap, &n);
    }
    return n;
}

void iso_dev_decoder_drops(const iso_dev_decoder *d, iso_dev_frame_drops *out)
{
    memset(out, 0, sizeof *out);
    if (d->kind != ISO_DEV_KIND_SERIAL)
        return;
    const iso_fb_counters *n = &((const iso_fb_parser *)(const void *)d->fb)->n;
    out->too_long = n->too_long;
    out->bad_cobs = n->bad_cobs;
    out->too_short = n->too_short;
    out->bad_crc = n->bad_crc;
    out->bad_version = n->bad_version;
    out->bad_length = n->bad_length;
    out->unknown_type = n->unknown_type;
    out->duplicate = n->duplicate;
    out->out_of_order = n->out_of_order;
    out->seq_gaps = n->seq_gaps;
}

/* ---- GPIO edges and their debounce ------------------------------------- */
/* libgpiod v1 has no debounce of its own. An edge that comes at least the
 * debounce time after the last accepted change is taken at once (no added
 * latency); one inside that window waits until the line has been stable for
 * the debounce time. The e-stop is asymmetric on purpose: pressing it is
 * never delayed, releasing it always waits for a stable line. */
static void gpio_accept(iso_dev_decoder *d, int role, int64_t t, iso_dev_event *ev, size_t cap,
                        size_t *n)
{
    iso_dev_gpio_line *l = &d->gpio[role];
    l->accepted = l->raw;
    l->t_accept = t;
    iso_dev_event *e = iso_dev__emit(d, t, ISO_DEV_EV_GPIO, ev, cap, n);
    if (e) {
        e->line = (uint8_t)role;
        e->level = l->accepted;
    }
}

static size_t gpio_decode(iso_dev_decoder *d, int64_t t, const uint8_t *p, size_t len,
                          iso_dev_event *ev, size_t cap)
{
    size_t n = 0;
    if (len % 2)
        d->n.garbage++;
    for (size_t i = 0; i + 1 < len; i += 2) {
        uint8_t role = p[i], level = p[i + 1] ? 1 : 0;
        if (role >= ISO_DEV_GPIO_ROLES) {
            d->n.unknown_ids++;
            continue;
        }
        d->n.reports++;
        iso_dev_gpio_line *l = &d->gpio[role];
        if (!l->have) { /* the first reading is the initial level: take it */
            l->have = 1;
            l->raw = level;
            gpio_accept(d, role, t, ev, cap, &n);
            continue;
        }
        l->raw = level;
        l->t_raw = t;
        if (level == l->accepted)
            continue; /* a bounce came back before it was accepted */
        int immediate = role == ISO_DEV_GPIO_ESTOP ? level == 1 : t - l->t_accept >= d->debounce_ns;
        if (immediate)
            gpio_accept(d, role, t, ev, cap, &n);
        else
            d->n.bounces++;
    }
    return n;
}

size_t iso_dev_decode_tick(iso_dev_decoder *d, int64_t now, iso_dev_event *ev, size_t cap)
{
    size_t n = 0;
    if (d->kind != ISO_DEV_KIND_GPIO)
        return 0;
    for (int role = 0; role < ISO_DEV_GPIO_ROLES; role++) {
        iso_dev_gpio_line *l = &d->gpio[role];
        if (l->have && l->raw != l->accepted && now - l->t_raw >= d->debounce_ns)
            gpio_accept(d, role, l->t_raw + d->debounce_ns, ev, cap, &n);
    }
    return n;
}

/* ---- dispatch ------------------------------------------------------------ */

/* Good input (a report, an accepted frame of any type) and bad input so
 * far, for the noise bookkeeping. */
static uint32_t good_count(const iso_dev_decoder *d)
{
    uint32_t g = d->n.reports;
    if (d->kind == ISO_DEV_KIND_SERIAL)
        g += ((const iso_fb_parser *)(const void *)d->fb)->n.frames_ok;
    return g;
}
/* Bytes a serial parser skips to the next 0x00 after an overflow are
 * garbage as they come, though counted as such only at that 0x00. */
static uint32_t bad_count(const iso_dev_decoder *d)
{
    uint32_t skipping = 0;
    if (d->kind == ISO_DEV_KIND_SERIAL && ((const iso_fb_parser *)(const void *)d->fb)->discarding)
        skipping = d->fb_pending;
    return d->n.short_reports + d->n.unknown_ids + d->n.bad_frames + d->n.garbage + skipping;
}

/* After a data chunk: good input ends a stretch of noise (one resync),
 * bad input alone begins or extends it. */
static void track_noise(iso_dev_decoder *d, int64_t t, uint32_t good0, uint32_t bad0)
{
    if (good_count(d) != good0) {
        if (d->noise_since != INT64_MIN)
            d->n.resyncs++;
        d->noise_since = d->noise_last = INT64_MIN;
    } else if (bad_count(d) != bad0) {
        if (d->noise_since == INT64_MIN)
            d->noise_since = t;
        d->noise_last = t;
    }
}

static size_t decode_data(iso_dev_decoder *d, const iso_dev_chunk *c, size_t len, iso_dev_event *ev,
                          size_t cap)
{
    switch (d->kind) {
    case ISO_DEV_KIND_HID: return iso_dev_sm_decode(d, c->t_ns, c->data, len, ev, cap);
    case ISO_DEV_KIND_SPNAV: return spnav_decode(d, c->t_ns, c->data, len, ev, cap);
    case ISO_DEV_KIND_SERIAL: return serial_decode(d, c->t_ns, c->data, len, ev, cap);
    case ISO_DEV_KIND_GPIO: return gpio_decode(d, c->t_ns, c->data, len, ev, cap);
    case ISO_DEV_KIND_VIEW: return iso_dev__view_decode(d, c->t_ns, c->data, len, ev, cap);
    default: d->n.garbage += (uint32_t)len; return 0;
    }
}

size_t iso_dev_decode(iso_dev_decoder *d, const iso_dev_chunk *c, iso_dev_event *ev, size_t cap)
{
    size_t n = 0;
    size_t len = c->len <= ISO_DEV_CHUNK_MAX ? c->len : ISO_DEV_CHUNK_MAX;
    if (c->type == ISO_DEV_CHUNK_SKIP) {
        iso_dev__skip_apply(d, c->t_ns, c->data, len);
        return 0;
    }
    d->n.chunks++;
    switch (c->type) {
    case ISO_DEV_CHUNK_GONE:
        /* What the device held is forgotten: it starts from rest when back. */
        memset(d->axes, 0, sizeof d->axes);
        d->buttons = 0;
        for (int r = 0; r < ISO_DEV_GPIO_ROLES; r++)
            d->gpio[r].have = 0;
        d->view.holder = d->view.last_seq = 0; /* a view's control ends; its stop stands */
        if (d->kind == ISO_DEV_KIND_SERIAL) {
            /* A new link: no half frame, no sequence; the counts go on. */
            iso_fb_parser *fb = (iso_fb_parser *)(void *)d->fb;
            iso_fb_counters keep = fb->n;
            iso_fb_parser_init(fb);
            fb->n = keep;
            d->n.garbage += d->fb_pending; /* a frame the device never finished */
            d->fb_pending = 0;
        }
        iso_dev__emit(d, c->t_ns, ISO_DEV_EV_GONE, ev, cap, &n);
        return n;
    case ISO_DEV_CHUNK_BACK: iso_dev__emit(d, c->t_ns, ISO_DEV_EV_BACK, ev, cap, &n); return n;
    case ISO_DEV_CHUNK_DATA: break;
    default: return 0;
    }
    uint32_t good0 = good_count(d), bad0 = bad_count(d);
    n = decode_data(d, c, len, ev, cap);
    track_noise(d, c->t_ns, good0, bad0);
    return n;
}

int iso_dev__noise_chunk(const iso_dev_decoder *before, const iso_dev_decoder *after, size_t events)
{
    /* a view's refusals and changes of control are state, never noise */
    return events == 0 && after->kind != ISO_DEV_KIND_GPIO && after->kind != ISO_DEV_KIND_VIEW &&
           good_count(after) == good_count(before);
}

/* ---- SKIP records (RECORDING.md): noise the recording left out ---------- */

static void put_le(uint8_t **w, uint64_t v, int bytes)
{
    for (int i = 0; i < bytes; i++)
        *(*w)++ = (uint8_t)(v >> (8 * i));
}

static uint64_t get_le(const uint8_t **r, const uint8_t *end, int bytes, int *bad)
{
    uint64_t v = 0;
    if (end - *r < bytes) {
        *bad = 1;
        return 0;
    }
    for (int i = 0; i < bytes; i++)
        v |= (uint64_t)(*r)[i] << (8 * i);
    *r += bytes;
    return v;
}

/* The decoder's counts a SKIP carries, in payload order, and the parser's. */
#define SKIP_DEC(n)                                                                                \
    &(n).short_reports, &(n).unknown_ids, &(n).bad_frames, &(n).garbage, &(n).bad_payloads
#define SKIP_FB(n)                                                                                 \
    &(n).too_long, &(n).bad_cobs, &(n).too_short, &(n).bad_crc, &(n).bad_version, &(n).bad_length, \
        &(n).unknown_type, &(n).duplicate, &(n).out_of_order
#define SKIP_N_FB 9

int iso_dev__skip_encode(const iso_dev_decoder *after, const iso_dev_decoder *first, uint32_t bytes,
                         uint32_t chunks, uint8_t *dst, size_t cap)
{
    const iso_fb_parser *fb = (const iso_fb_parser *)(const void *)after->fb;
    const iso_fb_parser *fb0 = (const iso_fb_parser *)(const void *)first->fb;
    int serial = after->kind == ISO_DEV_KIND_SERIAL;
    size_t tail = serial && !fb->discarding ? fb->len : 0;
    if (cap < 4 + 4 + 8 + 5 * 4 + SKIP_N_FB * 4 + 4 + 2 + tail)
        return ISO_EINVAL;
    uint8_t *w = dst;
    put_le(&w, bytes, 4);
    put_le(&w, chunks, 4);
    put_le(&w, (uint64_t)after->noise_since, 8);
    iso_dev_counters a = after->n, b = first->n;
    const uint32_t *na[] = {SKIP_DEC(a)}, *nb[] = {SKIP_DEC(b)};
    for (int i = 0; i < 5; i++)
        put_le(&w, *na[i] - *nb[i], 4);
    iso_fb_counters fa = fb->n, fz = fb0->n;
    const uint32_t *fa_[] = {SKIP_FB(fa)}, *fz_[] = {SKIP_FB(fz)};
    for (int i = 0; i < SKIP_N_FB; i++)
        put_le(&w, serial ? *fa_[i] - *fz_[i] : 0, 4);
    put_le(&w, serial ? after->fb_pending : 0, 4);
    put_le(&w, serial && fb->discarding, 1);
    put_le(&w, tail, 1);
    memcpy(w, fb->buf, tail);
    return (int)(w - dst) + (int)tail;
}

void iso_dev__skip_apply(iso_dev_decoder *d, int64_t t, const uint8_t *p, size_t len)
{
    const uint8_t *r = p, *end = p + len;
    int bad = 0;
    uint32_t bytes = (uint32_t)get_le(&r, end, 4, &bad);
    uint32_t chunks = (uint32_t)get_le(&r, end, 4, &bad);
    int64_t since = (int64_t)get_le(&r, end, 8, &bad);
    uint32_t dn[5], fn[SKIP_N_FB];
    for (int i = 0; i < 5; i++)
        dn[i] = (uint32_t)get_le(&r, end, 4, &bad);
    for (int i = 0; i < SKIP_N_FB; i++)
        fn[i] = (uint32_t)get_le(&r, end, 4, &bad);
    uint32_t pending = (uint32_t)get_le(&r, end, 4, &bad);
    int discarding = (int)get_le(&r, end, 1, &bad);
    size_t tail = (size_t)get_le(&r, end, 1, &bad);
    iso_fb_parser *fb = (iso_fb_parser *)(void *)d->fb;
    if (bad || (size_t)(end - r) != tail || tail > sizeof fb->buf) {
        d->n.garbage += (uint32_t)len; /* a SKIP that does not parse: said as what it is */
        d->n.bad_frames++;
        return;
    }
    d->n.chunks += chunks;
    d->n.unrecorded += bytes;
    uint32_t *nd[] = {SKIP_DEC(d->n)};
    for (int i = 0; i < 5; i++)
        *nd[i] += dn[i];
    if (d->kind == ISO_DEV_KIND_SERIAL) {
        uint32_t *nf[] = {SKIP_FB(fb->n)}, sum = 0;
        for (int i = 0; i < SKIP_N_FB; i++) {
            *nf[i] += fn[i];
            sum += fn[i];
        }
        fb->n.resyncs += sum;
        fb->discarding = (uint8_t)(discarding != 0);
        fb->len = tail;
        memcpy(fb->buf, r, tail);
        d->fb_pending = pending;
    }
    d->noise_since = since;
    d->noise_last = t;
}
