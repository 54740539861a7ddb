/* view/display_ws.c -- the pieces of RFC 6455 the live view needs: the
 * handshake's accept key (SHA-1 and base64), a server frame header, UTF-8
 * checking, and the parser of what a browser sends.
 *
 * The parser keeps at most ISO_DISPLAY_MAX_CLIENT_MESSAGE bytes of a
 * message: a frame header announcing more than what is left of that ends
 * the connection (1009) before a byte of its payload is read, so a header
 * announcing any length costs nothing. Every rule of section 5 that a
 * server must enforce on a client's frames is a return below. */
#include "display_internal.h"

#include <string.h>

/* ---- SHA-1 (FIPS 180-4), only for the handshake --------------------------- */

static uint32_t rol32(uint32_t v, int n)
{
    return (v << n) | (v >> (32 - n));
}

static void sha1_block(uint32_t h[5], const unsigned char *p)
{
    uint32_t w[80];
    for (int i = 0; i < 16; i++)
        w[i] = (uint32_t)p[4 * i] << 24 | (uint32_t)p[4 * i + 1] << 16 |
               (uint32_t)p[4 * i + 2] << 8 | (uint32_t)p[4 * i + 3];
    for (int i = 16; i < 80; i++)
        w[i] = rol32(w[i - 3] ^ w[i - 8] ^ w[i - 14] ^ w[i - 16], 1);
    uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4];
    for (int i = 0; i < 80; i++) {
        uint32_t f, k;
        if (i < 20) {
            f = (b & c) | (~b & d);
            k = 0x5a827999u;
        } else if (i < 40) {
            f = b ^ c ^ d;
            k = 0x6ed9eba1u;
        } else if (i < 60) {
            f = (b & c) | (b & d) | (c & d);
            k = 0x8f1bbcdcu;
        } else {
            f = b ^ c ^ d;
            k = 0xca62c1d6u;
        }
        uint32_t t = rol32(a, 5) + f + e + k + w[i];
        e = d;
        d = c;
        c = rol32(b, 30);
        b = a;
        a = t;
    }
    h[0] += a;
    h[1] += b;
    h[2] += c;
    h[3] += d;
    h[4] += e;
}

/* Hashes n < 120 bytes (a key and the GUID are 60): two blocks at most. */
static void sha1_short(const unsigned char *msg, size_t n, unsigned char out[20])
{
    uint32_t h[5] = {0x67452301u, 0xefcdab89u, 0x98badcfeu, 0x10325476u, 0xc3d2e1f0u};
    unsigned char buf[128];
    memset(buf, 0, sizeof buf);
    memcpy(buf, msg, n);
    buf[n] = 0x80;
    size_t total = n + 9 <= 64 ? 64 : 128;
    uint64_t bits = (uint64_t)n * 8;
    for (int i = 0; i < 8; i++)
        buf[total - 1 - (size_t)i] = (unsigned char)(bits >> (8 * i));
    for (size_t off = 0; off < total; off += 64)
        sha1_block(h, buf + off);
    for (int i = 0; i < 5; i++) {
        out[4 * i] = (unsigned char)(h[i] >> 24);
        out[4 * i + 1] = (unsigned char)(h[i] >> 16);
        out[4 * i + 2] = (unsigned char)(h[i] >> 8);
        out[4 * i + 3] = (unsigned char)h[i];
    }
}

int iso_display__ws_accept(const char *key, size_t key_len, char out[29])
{
    static const char guid[] = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";
    static const char b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    if (key_len != 24) /* 16 random bytes, base64: RFC 6455 section 4.1 */
        return -1;
    unsigned char msg[24 + sizeof guid - 1], dig[20];
    memcpy(msg, key, 24);
    memcpy(msg + 24, guid, sizeof guid - 1);
    sha1_short(msg, sizeof msg, dig);
    char *o = out;
    for (int i = 0; i < 21; i += 3) { /* 20 bytes: six full groups and one of two */
        uint32_t v = (uint32_t)dig[i] << 16 | (uint32_t)(i + 1 < 20 ? dig[i + 1] : 0) << 8 |
                     (uint32_t)(i + 2 < 20 ? dig[i + 2] : 0);
        *o++ = b64[v >> 18 & 63];
        *o++ = b64[v >> 12 & 63];
        *o++ = i + 1 < 20 ? b64[v >> 6 & 63] : '=';
        *o++ = i + 2 < 20 ? b64[v & 63] : '=';
    }
    *o = 0;
    return 0;
}

size_t iso_display__ws_header(unsigned char h[10], int opcode, size_t len)
{
    h[0] = (unsigned char)(0x80 | opcode); /* FIN: every message is one frame */
    if (len < 126) {
        h[1] = (unsigned char)len;
        return 2;
    }
    if (len <= 0xffff) {
        h[1] = 126;
        h[2] = (unsigned char)(len >> 8);
        h[3] = (unsigned char)len;
        return 4;
    }
    h[1] = 127;
    for (int i = 0; i < 8; i++)
        h[2 + i] = (unsigned char)((uint64_t)len >> (56 - 8 * i));
    return 10;
}

/* ---- UTF-8 ------------------------------------------------------------------ */

/* The ranges of RFC 3629's table: after E0 the next byte is A0..BF (no
 * overlong three-byte form), after ED 80..9F (no surrogates), after F0
 * 90..BF, after F4 80..8F (nothing above U+10FFFF); C0, C1 and F5..FF never
 * start a character. */
int iso_display__utf8_step(iso_display__utf8 *u, unsigned char b)
{
    if (u->need) {
        if (b < u->lo || b > u->hi)
            return -1;
        u->need--;
        u->lo = 0x80;
        u->hi = 0xbf;
        return 0;
    }
    if (b < 0x80)
        return 0;
    u->lo = 0x80;
    u->hi = 0xbf;
    if (b >= 0xc2 && b <= 0xdf)
        u->need = 1;
    else if (b >= 0xe0 && b <= 0xef)
        u->need = 2, u->lo = b == 0xe0 ? 0xa0 : 0x80, u->hi = b == 0xed ? 0x9f : 0xbf;
    else if (b >= 0xf0 && b <= 0xf4)
        u->need = 3, u->lo = b == 0xf0 ? 0x90 : 0x80, u->hi = b == 0xf4 ? 0x8f : 0xbf;
    else
        return -1;
    return 0;
}

int iso_display__ws_close_code_ok(int code)
{
    return (code >= 1000 && code <= 1003) || (code >= 1007 && code <= 1014) ||
           (code >= 3000 && code <= 4999);
}

/* ---- what the browser sends ---------------------------------------------- */

/* Bytes of header a frame needs, known once its first two are in. */
static unsigned header_need(const unsigned char *h)
{
    unsigned n = h[1] & 0x7f;
    return 2 + (n == 126 ? 2 : n == 127 ? 8 : 0) + ((h[1] & 0x80) ? 4 : 0);
}

static int fail(iso_display__ws_event *ev, int code)
{
    ev->code = code;
    return ISO_DISPLAY_WS_FAIL;
}

/* Judges a complete header; returns MORE to read its payload, or FAIL. */
static int header_done(iso_display__ws_rx *rx, iso_display__ws_event *ev)
{
    const unsigned char *h = rx->hdr;
    unsigned n = h[1] & 0x7f, k = n == 126 ? 2 : n == 127 ? 8 : 0;
    uint64_t len = n;
    if (k) {
        len = 0;
        for (unsigned i = 0; i < k; i++)
            len = len << 8 | h[2 + i];
    }
    rx->hdr_len = 0;
    rx->frames++;
    rx->opcode = h[0] & 0x0f;
    rx->fin = (h[0] & 0x80) != 0;
    if ((h[0] & 0x70) || !(h[1] & 0x80)) /* reserved bits; clients always mask */
        return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR);
    if (k == 8 && (len >> 63)) /* the most significant bit must be 0 */
        return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR);
    memcpy(rx->mask, h + 2 + k, 4);
    rx->mask_at = 0;
    rx->left = len;
    if (rx->opcode >= 8) {
        if (rx->opcode > 10 || len > 125 || !rx->fin) /* reserved, or long or fragmented */
            return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR);
        rx->ctl_len = 0;
    } else if (rx->opcode == 0) {
        if (!rx->msg_opcode) /* a continuation of nothing */
            return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR);
    } else if (rx->opcode <= 2) {
        if (rx->msg_opcode) /* a new message inside a fragmented one */
            return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR);
        rx->msg_opcode = rx->opcode;
        rx->msg_len = 0;
        memset(&rx->utf8, 0, sizeof rx->utf8);
    } else {
        return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR); /* 3..7 are reserved */
    }
    if (rx->opcode < 8 && len > ISO_DISPLAY_MAX_CLIENT_MESSAGE - rx->msg_len)
        return fail(ev, ISO_DISPLAY_WS_TOO_BIG);
    rx->in_payload = 1;
    return ISO_DISPLAY_WS_MORE;
}

/* A close frame's payload: nothing, or a status an endpoint may send and a
 * UTF-8 reason. */
static int close_frame(const iso_display__ws_rx *rx, iso_display__ws_event *ev)
{
    if (rx->ctl_len == 0) {
        ev->code = ISO_DISPLAY_WS_NO_STATUS;
        return ISO_DISPLAY_WS_CLOSE;
    }
    if (rx->ctl_len == 1)
        return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR);
    int code = rx->ctl[0] << 8 | rx->ctl[1];
    if (!iso_display__ws_close_code_ok(code))
        return fail(ev, ISO_DISPLAY_WS_PROTOCOL_ERROR);
    iso_display__utf8 u = {0, 0, 0};
    for (size_t i = 2; i < rx->ctl_len; i++)
        if (iso_display__utf8_step(&u, rx->ctl[i]) != 0)
            return fail(ev, ISO_DISPLAY_WS_BAD_DATA);
    if (u.need)
        return fail(ev, ISO_DISPLAY_WS_BAD_DATA);
    ev->code = code;
    ev->data = rx->ctl + 2;
    ev->len = rx->ctl_len - 2;
    return ISO_DISPLAY_WS_CLOSE;
}

/* The current frame's payload is all in: what it completes. */
static int frame_done(iso_display__ws_rx *rx, iso_display__ws_event *ev)
{
    rx->in_payload = 0;
    switch (rx->opcode) {
    case 8: return close_frame(rx, ev);
    case 9:
        ev->data = rx->ctl;
        ev->len = rx->ctl_len;
        return ISO_DISPLAY_WS_PING;
    case 10: return ISO_DISPLAY_WS_PONG;
    default: break;
    }
    if (!rx->fin)
        return ISO_DISPLAY_WS_MORE;
    if (rx->msg_opcode == 1 && rx->utf8.need) /* text that ends inside a character */
        return fail(ev, ISO_DISPLAY_WS_BAD_DATA);
    ev->opcode = rx->msg_opcode;
    ev->data = rx->msg;
    ev->len = rx->msg_len;
    rx->msg_opcode = 0;
    return ISO_DISPLAY_WS_MESSAGE;
}

/* Unmasks up to k payload bytes into the control or the message buffer;
 * *took says how many it used (up to the bad one, when it fails). */
static int take_payload(iso_display__ws_rx *rx, const unsigned char *p, size_t k, size_t *took,
                        iso_display__ws_event *ev)
{
    int control = rx->opcode >= 8, text = rx->msg_opcode == 1;
    for (size_t i = 0; i < k; i++) {
        unsigned char b = p[i] ^ rx->mask[rx->mask_at++ & 3];
        if (control) {
            rx->ctl[rx->ctl_len++] = b;
            continue;
        }
        if (text && iso_display__utf8_step(&rx->utf8, b) != 0) {
            *took = i + 1;
            return fail(ev, ISO_DISPLAY_WS_BAD_DATA); /* said at the first bad byte */
        }
        rx->msg[rx->msg_len++] = b;
    }
    *took = k;
    return ISO_DISPLAY_WS_MORE;
}

int iso_display__ws_rx_feed(iso_display__ws_rx *rx, const unsigned char *p, size_t n, size_t *used,
                            iso_display__ws_event *ev)
{
    memset(ev, 0, sizeof *ev);
    size_t i = 0;
    int st = ISO_DISPLAY_WS_MORE;
    while (i < n && st == ISO_DISPLAY_WS_MORE) {
        if (!rx->in_payload) {
            rx->hdr[rx->hdr_len++] = p[i++];
            if (rx->hdr_len >= 2 && rx->hdr_len == header_need(rx->hdr)) {
                st = header_done(rx, ev);
                if (st == ISO_DISPLAY_WS_MORE && rx->left == 0)
                    st = frame_done(rx, ev);
            }
            continue;
        }
        size_t k = rx->left < n - i ? (size_t)rx->left : n - i, took = 0;
        st = take_payload(rx, p + i, k, &took, ev);
        i += took;
        rx->left -= took;
        if (st == ISO_DISPLAY_WS_MORE && rx->left == 0)
            st = frame_done(rx, ev);
    }
    *used = i;
    return st;
}
