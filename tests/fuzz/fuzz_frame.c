/* tests/fuzz/fuzz_frame.c -- the firmware-bridge frame parser and message
 * unpackers under arbitrary bytes. Every accepted frame must re-encode to a
 * frame that parses back to the same view. */
#include <stdlib.h>
#include <string.h>

#include "iso_fb.h"

static void unpack_any(const iso_fb_view *v)
{
    union {
        iso_fb_hello h;
        iso_fb_sample s;
        iso_fb_setpoints sp;
        iso_fb_heartbeat hb;
        iso_fb_ack a;
        iso_fb_nak k;
        iso_fb_fault f;
        iso_fb_diag d;
        iso_fb_safe q;
    } m;
    switch (v->type) {
    case ISO_FB_HELLO: (void)iso_fb_hello_unpack(&m.h, v->payload, v->len); break;
    case ISO_FB_HANDLE_SAMPLE: (void)iso_fb_sample_unpack(&m.s, v->payload, v->len); break;
    case ISO_FB_SETPOINTS: (void)iso_fb_setpoints_unpack(&m.sp, v->payload, v->len); break;
    case ISO_FB_HEARTBEAT: (void)iso_fb_heartbeat_unpack(&m.hb, v->payload, v->len); break;
    case ISO_FB_ACK: (void)iso_fb_ack_unpack(&m.a, v->payload, v->len); break;
    case ISO_FB_NAK: (void)iso_fb_nak_unpack(&m.k, v->payload, v->len); break;
    case ISO_FB_FAULT: (void)iso_fb_fault_unpack(&m.f, v->payload, v->len); break;
    case ISO_FB_DIAG: (void)iso_fb_diag_unpack(&m.d, v->payload, v->len); break;
    case ISO_FB_SAFE: (void)iso_fb_safe_unpack(&m.q, v->payload, v->len); break;
    default: abort(); /* the parser must never pass an unknown type */
    }
}

static void check_reencode(const iso_fb_view *v)
{
    uint8_t wire[ISO_FB_FRAME_MAX];
    int n = iso_fb_frame_encode(wire, sizeof wire, v->type, v->seq, v->payload, v->len);
    if (n <= 0)
        abort();
    iso_fb_parser q;
    iso_fb_parser_init(&q);
    iso_fb_view w;
    int got = 0;
    for (int i = 0; i < n; i++)
        if (iso_fb_parser_feed(&q, wire[i], &w) == ISO_FB_FRAME)
            got++;
    if (got != 1 || w.type != v->type || w.seq != v->seq || w.len != v->len ||
        memcmp(w.payload, v->payload, v->len) != 0)
        abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    iso_fb_parser p;
    iso_fb_parser_init(&p);
    uint32_t frames = 0, drops = 0;
    for (size_t i = 0; i < size; i++) {
        iso_fb_view v;
        int r = iso_fb_parser_feed(&p, data[i], &v);
        if (r == ISO_FB_FRAME) {
            frames++;
            if (v.len > ISO_FB_MAX_PAYLOAD)
                abort();
            unpack_any(&v);
            check_reencode(&v);
        } else if (r < 0) {
            drops++;
        }
    }
    if (p.n.frames_ok != frames || p.n.resyncs != drops)
        abort();
    /* Raw COBS decode with a tight output buffer must stay in bounds. */
    uint8_t out[64];
    (void)iso_fb_cobs_decode(out, sizeof out, data, size);
    return 0;
}
