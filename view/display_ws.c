/* view/display_ws.c -- the few pieces of RFC 6455 the live view needs: the
 * handshake's accept key (SHA-1 and base64), a server frame header, and a
 * parser for what a browser sends, which only ever discards payloads.
 *
 * The parser never buffers a payload, so a frame header announcing any
 * length costs nothing; lengths above ISO_DISPLAY_MAX_CLIENT_FRAME end the
 * connection before a byte of the payload is read. */
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

/* ---- what the browser sends ---------------------------------------------- */

/* Bytes of header a frame needs, known once its first two are in. */
static unsigned header_need(const unsigned char *h)
{
    unsigned n = h[1] & 0x7f;
    return 2 + (n == 126 ? 2 : n == 127 ? 8 : 0) + ((h[1] & 0x80) ? 4 : 0);
}

/* Judges a complete header; returns 0 and sets rx->skip, or a close status. */
static int header_done(iso_display__ws_rx *rx)
{
    const unsigned char *h = rx->hdr;
    unsigned n = h[1] & 0x7f;
    uint64_t len = n;
    if (n == 126)
        len = (uint64_t)h[2] << 8 | h[3];
    else if (n == 127)
        for (int i = 0; i < 8; i++)
            len = (i ? len << 8 : 0) | h[2 + i];
    int opcode = h[0] & 0x0f;
    rx->hdr_len = 0;
    rx->frames++;
    if ((h[0] & 0x70) || !(h[1] & 0x80)) /* reserved bits; browsers always mask */
        return ISO_DISPLAY_WS_PROTOCOL_ERROR;
    if (opcode >= 8 && (len > 125 || !(h[0] & 0x80))) /* control frames: short, whole */
        return ISO_DISPLAY_WS_PROTOCOL_ERROR;
    if (len > ISO_DISPLAY_MAX_CLIENT_FRAME)
        return ISO_DISPLAY_WS_TOO_BIG;
    if (opcode == 8)
        return ISO_DISPLAY_WS_NORMAL;
    rx->skip = len;
    return 0;
}

int iso_display__ws_rx_feed(iso_display__ws_rx *rx, const unsigned char *p, size_t n)
{
    while (n) {
        if (rx->skip) {
            size_t k = rx->skip < n ? (size_t)rx->skip : n;
            rx->skip -= k;
            p += k;
            n -= k;
            continue;
        }
        rx->hdr[rx->hdr_len++] = *p++;
        n--;
        if (rx->hdr_len >= 2 && rx->hdr_len == header_need(rx->hdr)) {
            int st = header_done(rx);
            if (st)
                return st;
        }
    }
    return 0;
}
