/* tests/test_fb_proto.c -- the firmware-bridge wire protocol: CRC check
 * value, COBS round trips at every length, frames at every payload length,
 * every parser drop path with its counter, and the message layouts. */
#include <string.h>

#include "iso_fb.h"
#include "testutil.h"

/* A tiny deterministic generator, so failures reproduce. */
static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 24;
}

static void crc16_ccitt_false_check_value(void **state)
{
    (void)state;
    static const uint8_t msg[] = "123456789";
    assert_int_equal(iso_fb_crc16(msg, 9), 0x29B1);
    assert_int_equal(iso_fb_crc16(msg, 0), 0xFFFF);
}

static void cobs_round_trip_every_length(void **state)
{
    (void)state;
    uint32_t seed = 1;
    uint8_t src[256], enc[ISO_FB_COBS_MAX(256)], dec[256];
    for (int pattern = 0; pattern < 4; pattern++) {
        for (size_t len = 0; len <= 254; len++) {
            for (size_t i = 0; i < len; i++) {
                uint8_t b = (uint8_t)lcg(&seed);
                src[i] = pattern == 0   ? b
                         : pattern == 1 ? 0
                         : pattern == 2 ? 0xFF
                                        : (b & 1u ? 0 : b);
            }
            int e = iso_fb_cobs_encode(enc, ISO_FB_COBS_MAX(len), src, len);
            assert_true(e > 0 && (size_t)e <= ISO_FB_COBS_MAX(len));
            assert_null(memchr(enc, 0, (size_t)e));
            int d = iso_fb_cobs_decode(dec, sizeof dec, enc, (size_t)e);
            assert_int_equal(d, (int)len);
            if (len)
                assert_memory_equal(dec, src, len);
            /* in place */
            d = iso_fb_cobs_decode(enc, sizeof enc, enc, (size_t)e);
            assert_int_equal(d, (int)len);
            if (len)
                assert_memory_equal(enc, src, len);
        }
    }
}

static void cobs_errors(void **state)
{
    (void)state;
    uint8_t src[10] = {1, 2, 0, 4}, dst[32];
    /* too little room: refused up front, nothing written past the cap */
    memset(dst, 0xAA, sizeof dst);
    assert_int_equal(iso_fb_cobs_encode(dst, ISO_FB_COBS_MAX(4) - 1, src, 4), ISO_FB_ENOSPACE);
    assert_int_equal(dst[0], 0xAA);
    /* a zero inside the stuffed data */
    const uint8_t zero_inside[] = {3, 1, 0};
    assert_int_equal(iso_fb_cobs_decode(dst, sizeof dst, zero_inside, 3), ISO_FB_ECOBS);
    /* a code byte of zero */
    const uint8_t zero_code[] = {0, 1};
    assert_int_equal(iso_fb_cobs_decode(dst, sizeof dst, zero_code, 2), ISO_FB_ECOBS);
    /* a code that runs past the end */
    const uint8_t overrun[] = {5, 1, 2};
    assert_int_equal(iso_fb_cobs_decode(dst, sizeof dst, overrun, 3), ISO_FB_ECOBS);
    /* output capacity honoured */
    const uint8_t ok[] = {4, 1, 2, 3};
    memset(dst, 0xAA, sizeof dst);
    assert_int_equal(iso_fb_cobs_decode(dst, 2, ok, 4), ISO_FB_ENOSPACE);
    assert_int_equal(dst[2], 0xAA);
    assert_int_equal(iso_fb_cobs_decode(dst, 3, ok, 4), 3);
    assert_int_equal(iso_fb_cobs_encode(NULL, 10, src, 4), ISO_FB_EARG);
}

/* Feeds a byte string; returns the last non-MORE result and the frame. */
static int feed_all(iso_fb_parser *p, const uint8_t *b, size_t n, iso_fb_view *v, int *frames)
{
    int last = ISO_FB_MORE;
    for (size_t i = 0; i < n; i++) {
        int r = iso_fb_parser_feed(p, b[i], v);
        if (r != ISO_FB_MORE)
            last = r;
        if (r == ISO_FB_FRAME && frames)
            (*frames)++;
    }
    return last;
}

static void frame_round_trip_every_payload_length(void **state)
{
    (void)state;
    iso_fb_parser p;
    iso_fb_parser_init(&p);
    uint32_t seed = 7;
    for (size_t len = 0; len <= ISO_FB_MAX_PAYLOAD; len++) {
        uint8_t payload[ISO_FB_MAX_PAYLOAD], wire[ISO_FB_FRAME_MAX];
        for (size_t i = 0; i < len; i++)
            payload[i] = (uint8_t)(i % 3 == 0 ? 0 : lcg(&seed));
        int n = iso_fb_frame_encode(wire, sizeof wire, ISO_FB_SETPOINTS, (uint16_t)(len + 1),
                                    payload, len);
        assert_true(n > 0 && n <= (int)ISO_FB_WIRE_MAX(len));
        assert_int_equal(wire[0], 0);
        assert_int_equal(wire[n - 1], 0);
        iso_fb_view v;
        int frames = 0;
        assert_int_equal(feed_all(&p, wire, (size_t)n, &v, &frames), ISO_FB_FRAME);
        assert_int_equal(frames, 1);
        assert_int_equal(v.type, ISO_FB_SETPOINTS);
        assert_int_equal(v.seq, len + 1);
        assert_int_equal(v.len, len);
        if (len)
            assert_memory_equal(v.payload, payload, len);
    }
    assert_int_equal(p.n.frames_ok, ISO_FB_MAX_PAYLOAD + 1);
    assert_int_equal(p.n.resyncs, 0);
    uint8_t wire[ISO_FB_FRAME_MAX], payload[ISO_FB_MAX_PAYLOAD + 1] = {0};
    assert_int_equal(iso_fb_frame_encode(wire, sizeof wire, 1, 0, payload, ISO_FB_MAX_PAYLOAD + 1),
                     ISO_FB_EARG);
    assert_int_equal(iso_fb_frame_encode(wire, ISO_FB_WIRE_MAX(4) - 1, 1, 0, payload, 4),
                     ISO_FB_ENOSPACE);
}

/* Builds a wire frame from a raw (un-stuffed) body: header+payload+CRC as
 * given, so tests can forge any malformation. */
static size_t forge(uint8_t *wire, const uint8_t *raw, size_t n)
{
    wire[0] = 0;
    int e = iso_fb_cobs_encode(wire + 1, ISO_FB_COBS_MAX(256), raw, n);
    assert_true(e > 0);
    wire[1 + e] = 0;
    return (size_t)e + 2;
}

static size_t raw_frame(uint8_t *raw, uint8_t ver, uint8_t type, uint16_t seq, uint8_t len_field,
                        size_t real_len, int good_crc)
{
    raw[0] = ver;
    raw[1] = type;
    raw[2] = (uint8_t)seq;
    raw[3] = (uint8_t)(seq >> 8);
    raw[4] = len_field;
    for (size_t i = 0; i < real_len; i++)
        raw[5 + i] = (uint8_t)(i + 1);
    size_t n = 5 + real_len;
    uint16_t crc = iso_fb_crc16(raw, n);
    if (!good_crc)
        crc ^= 0x0100;
    raw[n++] = (uint8_t)crc;
    raw[n++] = (uint8_t)(crc >> 8);
    return n;
}

static void parser_counts_every_drop(void **state)
{
    (void)state;
    iso_fb_parser p;
    iso_fb_parser_init(&p);
    iso_fb_view v;
    uint8_t raw[300], wire[600];
    size_t n;

    /* bad CRC */
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 1, 2, 2, 0));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_ECRC);
    assert_int_equal(p.n.bad_crc, 1);
    /* too short for a header */
    const uint8_t shorty[] = {0, 3, 1, 1, 0};
    assert_int_equal(feed_all(&p, shorty, sizeof shorty, &v, NULL), ISO_FB_ESHORT);
    assert_int_equal(p.n.too_short, 1);
    /* bad COBS: a code byte that runs past the delimiter */
    const uint8_t badcobs[] = {0, 9, 1, 2, 0};
    assert_int_equal(feed_all(&p, badcobs, sizeof badcobs, &v, NULL), ISO_FB_ECOBS);
    assert_int_equal(p.n.bad_cobs, 1);
    /* unknown version */
    n = forge(wire, raw, raw_frame(raw, 2, ISO_FB_HEARTBEAT, 1, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_EVERSION);
    assert_int_equal(p.n.bad_version, 1);
    /* length field disagrees */
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 1, 3, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_ELENGTH);
    assert_int_equal(p.n.bad_length, 1);
    /* length field over the maximum, CRC valid */
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 1, ISO_FB_MAX_PAYLOAD + 1, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_ETOOLONG);
    assert_int_equal(p.n.too_long, 1);
    /* unknown type, and type 0 */
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_TYPE_COUNT, 1, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_ETYPE);
    n = forge(wire, raw, raw_frame(raw, 1, 0, 1, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_ETYPE);
    assert_int_equal(p.n.unknown_type, 2);
    /* oversize stream with no delimiter: dropped once, no overrun, and the
     * next frame after a 0x00 parses */
    uint8_t junk[1000];
    memset(junk, 0x55, sizeof junk);
    assert_int_equal(feed_all(&p, junk, sizeof junk, &v, NULL), ISO_FB_ETOOLONG);
    assert_int_equal(p.n.too_long, 2);
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 10, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_FRAME);
    assert_int_equal(v.seq, 10);
    /* the longest body that still fits the stuffed buffer parses (length
     * checks decide), one byte more overflows */
    n = forge(wire, raw,
              raw_frame(raw, 1, ISO_FB_HEARTBEAT, 11, ISO_FB_MAX_PAYLOAD, ISO_FB_MAX_PAYLOAD, 1));
    assert_int_equal(n - 2, sizeof p.buf);
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_FRAME);
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 12, 0, ISO_FB_MAX_PAYLOAD + 1, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_ETOOLONG);
    assert_int_equal(p.n.too_long, 3);
    iso_fb_parser_reset_seq(&p);
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 10, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_FRAME);
    /* duplicate, out of order, gap */
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 10, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_EDUP);
    assert_int_equal(p.n.duplicate, 1);
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 9, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_EORDER);
    assert_int_equal(p.n.out_of_order, 1);
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 14, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_FRAME);
    assert_int_equal(p.n.seq_gaps, 3);
    /* sequence wraps around 0xFFFF */
    iso_fb_parser_reset_seq(&p);
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 0xFFFF, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_FRAME);
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HEARTBEAT, 0, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_FRAME);
    /* a HELLO restarts the sequence (the peer rebooted) */
    n = forge(wire, raw, raw_frame(raw, 1, ISO_FB_HELLO, 0, 2, 2, 1));
    assert_int_equal(feed_all(&p, wire, n, &v, NULL), ISO_FB_FRAME);
    assert_int_equal(p.n.duplicate, 1);
    /* every drop was counted as a resync, and only those */
    assert_int_equal(p.n.resyncs, p.n.bad_crc + p.n.too_short + p.n.bad_cobs + p.n.bad_version +
                                      p.n.bad_length + p.n.too_long + p.n.unknown_type +
                                      p.n.duplicate + p.n.out_of_order);
    assert_int_equal(p.n.resyncs, 12);
    assert_int_equal(p.n.frames_ok, 7);
    /* idle delimiters are not errors */
    const uint8_t idle[] = {0, 0, 0, 0};
    assert_int_equal(feed_all(&p, idle, sizeof idle, &v, NULL), ISO_FB_MORE);
    assert_int_equal(p.n.resyncs, 12);
    assert_string_equal(iso_fb_strerror(ISO_FB_ECRC), "CRC mismatch");
}

static void garbage_costs_at_most_the_frame_it_touches(void **state)
{
    (void)state;
    iso_fb_parser p;
    iso_fb_parser_init(&p);
    uint8_t stream[4096];
    size_t len = 0;
    uint32_t seed = 3;
    for (uint16_t s = 0; s < 40; s++) {
        /* garbage, with and without zeros, between frames */
        size_t g = lcg(&seed) % 20;
        for (size_t i = 0; i < g; i++)
            stream[len++] = (uint8_t)lcg(&seed);
        uint8_t pl[8] = {1, 2, 3, 4, 5, 6, 7, (uint8_t)s};
        int n = iso_fb_frame_encode(stream + len, sizeof stream - len, ISO_FB_HEARTBEAT, s, pl,
                                    sizeof pl);
        assert_true(n > 0);
        len += (size_t)n;
    }
    iso_fb_view v;
    int frames = 0;
    uint16_t last = 0;
    for (size_t i = 0; i < len; i++)
        if (iso_fb_parser_feed(&p, stream[i], &v) == ISO_FB_FRAME) {
            frames++;
            assert_int_equal(v.payload[7], v.seq);
            last = v.seq;
        }
    /* the leading delimiter ends the garbage: every frame survives */
    assert_int_equal(frames, 40);
    assert_int_equal(last, 39);
}

static void messages_round_trip(void **state)
{
    (void)state;
    uint8_t b[ISO_FB_MAX_PAYLOAD];
    iso_fb_hello h = {1,      0x0102, ISO_FB_HELLO_BOOT,
                      123456, 3,      {{-5, 7, 100, 0}, {-1000, 1000, 2000, 3}, {0, 1, 1, 1}}};
    int n = iso_fb_hello_pack(b, sizeof b, &h);
    assert_int_equal(n, 9 + 3 * 8);
    iso_fb_hello h2;
    assert_int_equal(iso_fb_hello_unpack(&h2, b, (size_t)n), 0);
    assert_int_equal(h2.fw_version, 0x0102);
    assert_int_equal(h2.uptime_ms, 123456);
    assert_int_equal(h2.ch[0].min, -5);
    assert_int_equal(h2.ch[1].safe, 3);
    assert_int_equal(iso_fb_hello_unpack(&h2, b, (size_t)n - 1), ISO_FB_EPAYLOAD);
    assert_int_equal(iso_fb_hello_pack(b, 10, &h), ISO_FB_ENOSPACE);
    h.n_channels = ISO_FB_MAX_CHANNELS + 1;
    assert_int_equal(iso_fb_hello_pack(b, sizeof b, &h), ISO_FB_EARG);

    iso_fb_sample s = {4000000000u,
                       ISO_FB_SAMPLE_TWIST,
                       0xBEEF,
                       {-1, 2, -2147483647 - 1, 2147483647, 0, -7}},
                  s2;
    n = iso_fb_sample_pack(b, sizeof b, &s);
    assert_int_equal(iso_fb_sample_unpack(&s2, b, (size_t)n), 0);
    assert_memory_equal(s.v, s2.v, sizeof s.v);
    assert_int_equal(s2.t_us, 4000000000u);
    assert_int_equal(s2.buttons, 0xBEEF);
    b[4] = 9; /* unknown kind */
    assert_int_equal(iso_fb_sample_unpack(&s2, b, (size_t)n), ISO_FB_EPAYLOAD);

    iso_fb_setpoints sp = {77, 4, {-32768, 32767, 0, -1}}, sp2;
    n = iso_fb_setpoints_pack(b, sizeof b, &sp);
    assert_int_equal(n, 5 + 8);
    assert_int_equal(iso_fb_setpoints_unpack(&sp2, b, (size_t)n), 0);
    assert_memory_equal(sp.value, sp2.value, 8);
    assert_int_equal(iso_fb_setpoints_unpack(&sp2, b, (size_t)n + 1), ISO_FB_EPAYLOAD);
    b[4] = 200; /* channel count over the maximum */
    assert_int_equal(iso_fb_setpoints_unpack(&sp2, b, (size_t)n), ISO_FB_EPAYLOAD);

    iso_fb_heartbeat hb = {99, ISO_FB_STATE_SAFE, 2, {5, -5}}, hb2;
    n = iso_fb_heartbeat_pack(b, sizeof b, &hb);
    assert_int_equal(iso_fb_heartbeat_unpack(&hb2, b, (size_t)n), 0);
    assert_int_equal(hb2.pos[1], -5);
    /* The wire bytes, by PROTOCOL.md: u32 uptime, u8 state, u8 n, n × i16,
     * little-endian. A state past SAFE does not parse. */
    iso_fb_heartbeat hb3 = {0x04030201u, ISO_FB_STATE_SAFE, 1, {-2}};
    static const uint8_t hb_wire[] = {1, 2, 3, 4, ISO_FB_STATE_SAFE, 1, 0xFE, 0xFF};
    assert_int_equal(iso_fb_heartbeat_pack(b, sizeof b, &hb3), (int)sizeof hb_wire);
    assert_memory_equal(b, hb_wire, sizeof hb_wire);
    b[4] = ISO_FB_STATE_SAFE + 1;
    assert_int_equal(iso_fb_heartbeat_unpack(&hb2, b, sizeof hb_wire), ISO_FB_EPAYLOAD);

    iso_fb_ack a = {ISO_FB_SETPOINTS, 513, 1u << 31, 2, {1, -2}}, a2;
    n = iso_fb_ack_pack(b, sizeof b, &a);
    assert_int_equal(iso_fb_ack_unpack(&a2, b, (size_t)n), 0);
    assert_int_equal(a2.seq, 513);
    assert_int_equal(a2.tick, 1u << 31);
    assert_int_equal(a2.value[1], -2);
    /* u8 type, u16 seq, u32 tick, u8 n, n × i16. */
    iso_fb_ack a3 = {ISO_FB_SETPOINTS, 0x0201u, 0x06050403u, 1, {0x0807}};
    static const uint8_t ack_wire[] = {ISO_FB_SETPOINTS, 1, 2, 3, 4, 5, 6, 1, 7, 8};
    assert_int_equal(iso_fb_ack_pack(b, sizeof b, &a3), (int)sizeof ack_wire);
    assert_memory_equal(b, ack_wire, sizeof ack_wire);

    iso_fb_nak k = {ISO_FB_SETPOINTS, 9, ISO_FB_NAK_CHANNELS}, k2;
    n = iso_fb_nak_pack(b, sizeof b, &k);
    assert_int_equal(iso_fb_nak_unpack(&k2, b, (size_t)n), 0);
    assert_int_equal(k2.reason, ISO_FB_NAK_CHANNELS);

    iso_fb_fault f = {ISO_FB_FAULT_WATCHDOG, 101, 5000}, f2;
    n = iso_fb_fault_pack(b, sizeof b, &f);
    assert_int_equal(iso_fb_fault_unpack(&f2, b, (size_t)n), 0);
    assert_int_equal(f2.detail, 101);
    assert_int_equal(iso_fb_fault_unpack(&f2, b, 0), ISO_FB_EPAYLOAD);

    iso_fb_diag d = {ISO_FB_DIAG_HANG_MAGIC}, d2;
    n = iso_fb_diag_pack(b, sizeof b, &d);
    assert_int_equal(iso_fb_diag_unpack(&d2, b, (size_t)n), 0);
    assert_int_equal(d2.magic, ISO_FB_DIAG_HANG_MAGIC);

    iso_fb_safe q = {ISO_FB_SAFE_LOOP_STALL}, q2;
    n = iso_fb_safe_pack(b, sizeof b, &q);
    assert_int_equal(n, 1); /* cause:u8 (PROTOCOL.md) */
    assert_int_equal(iso_fb_safe_unpack(&q2, b, (size_t)n), 0);
    assert_int_equal(q2.cause, ISO_FB_SAFE_LOOP_STALL);
    assert_int_equal(iso_fb_safe_unpack(&q2, b, 0), ISO_FB_EPAYLOAD);
    assert_int_equal(iso_fb_safe_unpack(&q2, b, 2), ISO_FB_EPAYLOAD);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(crc16_ccitt_false_check_value),
        cmocka_unit_test(cobs_round_trip_every_length),
        cmocka_unit_test(cobs_errors),
        cmocka_unit_test(frame_round_trip_every_payload_length),
        cmocka_unit_test(parser_counts_every_drop),
        cmocka_unit_test(garbage_costs_at_most_the_frame_it_touches),
        cmocka_unit_test(messages_round_trip),
    };
    return cmocka_run_group_tests_name("fb_proto", t, NULL, NULL);
}
