/* firmware-bridge/iso_fb.c -- see iso_fb.h. Freestanding: this file must
 * build with -ffreestanding -nostdlib for the firmware, so it uses no libc
 * beyond <stdint.h>/<stddef.h> and holds no state outside its arguments. */
#include "iso_fb.h"

#include <stddef.h>

const char *iso_fb_strerror(int code)
{
    switch (code) {
    case ISO_FB_MORE: return "more";
    case ISO_FB_FRAME: return "frame";
    case ISO_FB_ENOSPACE: return "destination too small";
    case ISO_FB_EARG: return "bad argument";
    case ISO_FB_ECOBS: return "bad COBS stuffing";
    case ISO_FB_ESHORT: return "frame too short";
    case ISO_FB_ECRC: return "CRC mismatch";
    case ISO_FB_ETOOLONG: return "frame too long";
    case ISO_FB_EVERSION: return "unknown protocol version";
    case ISO_FB_ELENGTH: return "length field mismatch";
    case ISO_FB_ETYPE: return "unknown message type";
    case ISO_FB_EDUP: return "duplicate sequence number";
    case ISO_FB_EORDER: return "out-of-order sequence number";
    case ISO_FB_EPAYLOAD: return "bad payload";
    default: return "unknown result";
    }
}

/* ======================================================================
 * CRC-16/CCITT-FALSE, bitwise: 70 bytes a frame do not justify a 512-byte
 * table in the firmware's flash.
 * ==================================================================== */
uint16_t iso_fb_crc16(const uint8_t *data, size_t len)
{
    uint16_t crc = 0xFFFFu;
    for (size_t i = 0; i < len; i++) {
        crc ^= (uint16_t)((uint16_t)data[i] << 8);
        for (int b = 0; b < 8; b++)
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
    }
    return crc;
}

/* ======================================================================
 * COBS
 * ==================================================================== */
int iso_fb_cobs_encode(uint8_t *dst, size_t dst_cap, const uint8_t *src, size_t len)
{
    if (!dst || (!src && len))
        return ISO_FB_EARG;
    if (dst_cap < ISO_FB_COBS_MAX(len))
        return ISO_FB_ENOSPACE;
    size_t code_at = 0, o = 1;
    uint8_t code = 1;
    for (size_t i = 0; i < len; i++) {
        if (src[i] == 0) {
            dst[code_at] = code;
            code_at = o++;
            code = 1;
            continue;
        }
        dst[o++] = src[i];
        if (++code == 0xFFu) {
            dst[code_at] = code;
            code_at = o++;
            code = 1;
        }
    }
    dst[code_at] = code;
    return (int)o;
}

int iso_fb_cobs_decode(uint8_t *dst, size_t dst_cap, const uint8_t *src, size_t len)
{
    if (!dst || (!src && len))
        return ISO_FB_EARG;
    size_t i = 0, o = 0;
    while (i < len) {
        uint8_t code = src[i++];
        if (code == 0)
            return ISO_FB_ECOBS;
        size_t run = (size_t)code - 1u;
        if (run > len - i)
            return ISO_FB_ECOBS;
        if (run > dst_cap - o)
            return ISO_FB_ENOSPACE;
        /* o < i throughout, so decoding in place (dst == src) is safe. */
        for (size_t k = 0; k < run; k++) {
            uint8_t b = src[i++];
            if (b == 0)
                return ISO_FB_ECOBS;
            dst[o++] = b;
        }
        if (code != 0xFFu && i < len) {
            if (o >= dst_cap)
                return ISO_FB_ENOSPACE;
            dst[o++] = 0;
        }
    }
    return (int)o;
}

/* ======================================================================
 * Frames
 * ==================================================================== */
int iso_fb_frame_encode(uint8_t *dst, size_t dst_cap, uint8_t type, uint16_t seq,
                        const uint8_t *payload, size_t len)
{
    if (!dst || (!payload && len) || len > ISO_FB_MAX_PAYLOAD)
        return ISO_FB_EARG;
    if (dst_cap < ISO_FB_WIRE_MAX(len))
        return ISO_FB_ENOSPACE;
    uint8_t raw[ISO_FB_RAW_MAX];
    raw[0] = (uint8_t)ISO_FB_VERSION;
    raw[1] = type;
    raw[2] = (uint8_t)(seq & 0xFFu);
    raw[3] = (uint8_t)(seq >> 8);
    raw[4] = (uint8_t)len;
    for (size_t i = 0; i < len; i++)
        raw[ISO_FB_HEADER + i] = payload[i];
    size_t n = ISO_FB_HEADER + len;
    uint16_t crc = iso_fb_crc16(raw, n);
    raw[n++] = (uint8_t)(crc & 0xFFu);
    raw[n++] = (uint8_t)(crc >> 8);
    dst[0] = 0;
    int e = iso_fb_cobs_encode(dst + 1, dst_cap - 2, raw, n);
    if (e < 0)
        return e;
    dst[1 + (size_t)e] = 0;
    return e + 2;
}

void iso_fb_parser_init(iso_fb_parser *p)
{
    uint8_t *b = (uint8_t *)p;
    for (size_t i = 0; i < sizeof *p; i++)
        b[i] = 0;
}

void iso_fb_parser_reset_seq(iso_fb_parser *p)
{
    p->have_seq = 0;
}

static int drop(iso_fb_parser *p, uint32_t *counter, int code)
{
    (*counter)++;
    p->n.resyncs++;
    return code;
}

/* Runs the checks on a complete decoded frame in p->raw, cheapest and most
 * telling first, so each dropped frame is counted under one reason. */
static int check_frame(iso_fb_parser *p, size_t n, iso_fb_view *out)
{
    const uint8_t *r = p->raw;
    if (n < ISO_FB_HEADER + ISO_FB_CRC_BYTES)
        return drop(p, &p->n.too_short, ISO_FB_ESHORT);
    size_t body = n - ISO_FB_CRC_BYTES;
    uint16_t crc = (uint16_t)(r[body] | (uint16_t)r[body + 1] << 8);
    if (iso_fb_crc16(r, body) != crc)
        return drop(p, &p->n.bad_crc, ISO_FB_ECRC);
    if (r[0] != ISO_FB_VERSION)
        return drop(p, &p->n.bad_version, ISO_FB_EVERSION);
    if (r[4] > ISO_FB_MAX_PAYLOAD)
        return drop(p, &p->n.too_long, ISO_FB_ETOOLONG);
    if ((size_t)r[4] != body - ISO_FB_HEADER)
        return drop(p, &p->n.bad_length, ISO_FB_ELENGTH);
    if (r[1] == 0 || r[1] >= ISO_FB_TYPE_COUNT)
        return drop(p, &p->n.unknown_type, ISO_FB_ETYPE);
    uint16_t seq = (uint16_t)(r[2] | (uint16_t)r[3] << 8);
    if (r[1] == ISO_FB_HELLO)
        p->have_seq = 0; /* a HELLO opens a new session: its peer may have rebooted */
    if (p->have_seq) {
        uint16_t d = (uint16_t)(seq - p->last_seq);
        if (d == 0)
            return drop(p, &p->n.duplicate, ISO_FB_EDUP);
        if (d >= 0x8000u)
            return drop(p, &p->n.out_of_order, ISO_FB_EORDER);
        p->n.seq_gaps += (uint32_t)(d - 1u);
    }
    p->have_seq = 1;
    p->last_seq = seq;
    p->n.frames_ok++;
    out->type = r[1];
    out->seq = seq;
    out->len = r[4];
    out->payload = r + ISO_FB_HEADER;
    return ISO_FB_FRAME;
}

int iso_fb_parser_feed(iso_fb_parser *p, uint8_t byte, iso_fb_view *out)
{
    if (byte != 0) {
        if (p->discarding)
            return ISO_FB_MORE;
        if (p->len >= sizeof p->buf) {
            p->discarding = 1;
            p->len = 0;
            return drop(p, &p->n.too_long, ISO_FB_ETOOLONG);
        }
        p->buf[p->len++] = byte;
        return ISO_FB_MORE;
    }
    size_t len = p->len;
    p->len = 0;
    if (p->discarding) {
        p->discarding = 0; /* counted when it overflowed */
        return ISO_FB_MORE;
    }
    if (len == 0)
        return ISO_FB_MORE; /* back-to-back delimiters are idle fill, not errors */
    int n = iso_fb_cobs_decode(p->raw, sizeof p->raw, p->buf, len);
    if (n == ISO_FB_ENOSPACE)
        return drop(p, &p->n.too_long, ISO_FB_ETOOLONG);
    if (n < 0)
        return drop(p, &p->n.bad_cobs, ISO_FB_ECOBS);
    return check_frame(p, (size_t)n, out);
}

/* ======================================================================
 * Messages: little-endian fields through a bounded cursor, so a pack can
 * never write past cap and an unpack never reads past len.
 * ==================================================================== */
typedef struct cursor {
    uint8_t *w;
    const uint8_t *r;
    size_t cap, pos;
    int bad;
} cursor;

static void put8(cursor *c, uint32_t v)
{
    if (c->pos >= c->cap) {
        c->bad = 1;
        return;
    }
    c->w[c->pos++] = (uint8_t)v;
}
static void put16(cursor *c, uint32_t v)
{
    put8(c, v & 0xFFu);
    put8(c, (v >> 8) & 0xFFu);
}
static void put32(cursor *c, uint32_t v)
{
    put16(c, v & 0xFFFFu);
    put16(c, v >> 16);
}

static uint32_t get8(cursor *c)
{
    if (c->pos >= c->cap) {
        c->bad = 1;
        return 0;
    }
    return c->r[c->pos++];
}
static uint32_t get16(cursor *c)
{
    uint32_t lo = get8(c);
    return lo | get8(c) << 8;
}
static uint32_t get32(cursor *c)
{
    uint32_t lo = get16(c);
    return lo | get16(c) << 16;
}
/* Two's complement without implementation-defined conversions. */
static int16_t s16(uint32_t v)
{
    return (int16_t)(v >= 0x8000u ? (int32_t)v - 0x10000 : (int32_t)v);
}
static int32_t s32(uint32_t v)
{
    return v >= 0x80000000u ? -(int32_t)(~v) - 1 : (int32_t)v;
}
static uint32_t u16(int16_t v)
{
    return (uint16_t)v;
}

static cursor writer(uint8_t *dst, size_t cap)
{
    cursor c = {dst, NULL, dst ? cap : 0, 0, 0};
    return c;
}
static cursor reader(const uint8_t *src, size_t len)
{
    cursor c = {NULL, src, src ? len : 0, 0, 0};
    return c;
}
static int wdone(const cursor *c)
{
    return c->bad ? ISO_FB_ENOSPACE : (int)c->pos;
}
/* An unpack succeeds only if it consumed exactly the payload. */
static int rdone(const cursor *c)
{
    return c->bad || c->pos != c->cap ? ISO_FB_EPAYLOAD : 0;
}

/* Each message is a layout: its fixed fields in wire order, then, for the
 * ones with channels, a count (a u8 field among the fixed ones, at most
 * ISO_FB_MAX_CHANNELS) and that many items of fields each. One pack and one
 * unpack walk every layout, so the byte order, the bounds and the count
 * rule are written once. */
enum { F_U8, F_U16, F_U32, F_I16, F_I32 };

typedef struct fb_field {
    uint16_t off;  /* offsetof in the message (or in one item) */
    uint8_t kind;  /* F_* */
    uint8_t limit; /* F_U8: the largest valid value, unpack refuses more; 0: any */
} fb_field;

typedef struct fb_layout {
    const fb_field *head, *item;
    uint8_t n_head, n_item; /* n_item 0: no items */
    uint16_t count_off;     /* the u8 count of items, in the message */
    uint16_t items_off;     /* the first item, in the message */
    uint16_t stride;        /* sizeof one item */
} fb_layout;

#define AT(type, member) (uint16_t) offsetof(type, member)
#define N(a) (uint8_t)(sizeof(a) / sizeof((a)[0]))

static void put_fields(cursor *c, const fb_field *f, unsigned n, const uint8_t *m)
{
    for (unsigned i = 0; i < n; i++) {
        const uint8_t *p = m + f[i].off;
        switch (f[i].kind) {
        case F_U8: put8(c, *p); break;
        case F_U16: put16(c, *(const uint16_t *)p); break;
        case F_U32: put32(c, *(const uint32_t *)p); break;
        case F_I16: put16(c, u16(*(const int16_t *)p)); break;
        default: put32(c, (uint32_t) * (const int32_t *)p); break;
        }
    }
}

/* Reads the fields; 0, or ISO_FB_EPAYLOAD for a u8 above its limit. */
static int get_fields(cursor *c, const fb_field *f, unsigned n, uint8_t *m)
{
    int rc = 0;
    for (unsigned i = 0; i < n; i++) {
        uint8_t *p = m + f[i].off;
        switch (f[i].kind) {
        case F_U8:
            *p = (uint8_t)get8(c);
            if (f[i].limit && *p > f[i].limit)
                rc = ISO_FB_EPAYLOAD;
            break;
        case F_U16: *(uint16_t *)p = (uint16_t)get16(c); break;
        case F_U32: *(uint32_t *)p = get32(c); break;
        case F_I16: *(int16_t *)p = s16(get16(c)); break;
        default: *(int32_t *)p = s32(get32(c)); break;
        }
    }
    return rc;
}

static int pack(const fb_layout *l, uint8_t *dst, size_t cap, const void *msg)
{
    const uint8_t *m = msg;
    unsigned n = l->n_item && m ? m[l->count_off] : 0;
    if (!m || n > ISO_FB_MAX_CHANNELS)
        return ISO_FB_EARG;
    cursor c = writer(dst, cap);
    put_fields(&c, l->head, l->n_head, m);
    for (unsigned i = 0; i < n; i++)
        put_fields(&c, l->item, l->n_item, m + l->items_off + i * l->stride);
    return wdone(&c);
}

/* An unpack succeeds only if every field is valid and it consumed exactly
 * the payload. */
static int unpack(const fb_layout *l, void *msg, const uint8_t *src, size_t len)
{
    uint8_t *m = msg;
    cursor c = reader(src, len);
    if (get_fields(&c, l->head, l->n_head, m) != 0)
        return ISO_FB_EPAYLOAD;
    unsigned n = l->n_item ? m[l->count_off] : 0;
    for (unsigned i = 0; i < n; i++)
        (void)get_fields(&c, l->item, l->n_item, m + l->items_off + i * l->stride);
    return rdone(&c);
}

#define CHANNELS ISO_FB_MAX_CHANNELS
static const fb_field hello_head[] = {{AT(iso_fb_hello, proto_version), F_U8, 0},
                                      {AT(iso_fb_hello, fw_version), F_U16, 0},
                                      {AT(iso_fb_hello, flags), F_U8, 0},
                                      {AT(iso_fb_hello, uptime_ms), F_U32, 0},
                                      {AT(iso_fb_hello, n_channels), F_U8, CHANNELS}};
static const fb_field hello_item[] = {{AT(iso_fb_channel_info, min), F_I16, 0},
                                      {AT(iso_fb_channel_info, max), F_I16, 0},
                                      {AT(iso_fb_channel_info, max_rate), F_U16, 0},
                                      {AT(iso_fb_channel_info, safe), F_I16, 0}};
static const fb_field sample_head[] = {
    {AT(iso_fb_sample, t_us), F_U32, 0},    {AT(iso_fb_sample, kind), F_U8, ISO_FB_SAMPLE_TWIST},
    {AT(iso_fb_sample, buttons), F_U16, 0}, {AT(iso_fb_sample, v[0]), F_I32, 0},
    {AT(iso_fb_sample, v[1]), F_I32, 0},    {AT(iso_fb_sample, v[2]), F_I32, 0},
    {AT(iso_fb_sample, v[3]), F_I32, 0},    {AT(iso_fb_sample, v[4]), F_I32, 0},
    {AT(iso_fb_sample, v[5]), F_I32, 0}};
static const fb_field setpoints_head[] = {{AT(iso_fb_setpoints, tick), F_U32, 0},
                                          {AT(iso_fb_setpoints, n), F_U8, CHANNELS}};
static const fb_field heartbeat_head[] = {{AT(iso_fb_heartbeat, uptime_ms), F_U32, 0},
                                          {AT(iso_fb_heartbeat, state), F_U8, ISO_FB_STATE_SAFE},
                                          {AT(iso_fb_heartbeat, n), F_U8, CHANNELS}};
static const fb_field ack_head[] = {{AT(iso_fb_ack, type), F_U8, 0},
                                    {AT(iso_fb_ack, seq), F_U16, 0},
                                    {AT(iso_fb_ack, tick), F_U32, 0},
                                    {AT(iso_fb_ack, n), F_U8, CHANNELS}};
static const fb_field nak_head[] = {{AT(iso_fb_nak, type), F_U8, 0},
                                    {AT(iso_fb_nak, seq), F_U16, 0},
                                    {AT(iso_fb_nak, reason), F_U8, 0}};
static const fb_field fault_head[] = {{AT(iso_fb_fault, reason), F_U8, 0},
                                      {AT(iso_fb_fault, detail), F_U32, 0},
                                      {AT(iso_fb_fault, uptime_ms), F_U32, 0}};
static const fb_field diag_head[] = {{AT(iso_fb_diag, magic), F_U32, 0}};
static const fb_field safe_head[] = {{AT(iso_fb_safe, cause), F_U8, 0}};
/* One signed 16-bit value per channel. */
static const fb_field i16_item[] = {{0, F_I16, 0}};

#define FIXED(name)                                                                                \
    {                                                                                              \
        name##_head, NULL, N(name##_head), 0, 0, 0, 0                                              \
    }
#define WITH_ITEMS(type, name, item, count, items)                                                 \
    {                                                                                              \
        name##_head, item, N(name##_head), N(item), (uint16_t)offsetof(type, count),               \
            (uint16_t)offsetof(type, items), (uint16_t)sizeof(((type *)0)->items[0])               \
    }

static const fb_layout hello_layout = WITH_ITEMS(iso_fb_hello, hello, hello_item, n_channels, ch);
static const fb_layout sample_layout = FIXED(sample);
static const fb_layout setpoints_layout =
    WITH_ITEMS(iso_fb_setpoints, setpoints, i16_item, n, value);
static const fb_layout heartbeat_layout = WITH_ITEMS(iso_fb_heartbeat, heartbeat, i16_item, n, pos);
static const fb_layout ack_layout = WITH_ITEMS(iso_fb_ack, ack, i16_item, n, value);
static const fb_layout nak_layout = FIXED(nak);
static const fb_layout fault_layout = FIXED(fault);
static const fb_layout diag_layout = FIXED(diag);
static const fb_layout safe_layout = FIXED(safe);

/* The public pack and unpack of each message (iso_fb.h), over its layout. */
#define CODEC(name)                                                                                \
    int iso_fb_##name##_pack(uint8_t *dst, size_t cap, const iso_fb_##name *m)                     \
    {                                                                                              \
        return pack(&name##_layout, dst, cap, m);                                                  \
    }                                                                                              \
    int iso_fb_##name##_unpack(iso_fb_##name *m, const uint8_t *src, size_t len)                   \
    {                                                                                              \
        return unpack(&name##_layout, m, src, len);                                                \
    }
CODEC(hello)
CODEC(sample)
CODEC(setpoints)
CODEC(heartbeat)
CODEC(ack)
CODEC(nak)
CODEC(fault)
CODEC(diag)
CODEC(safe)
