/* firmware-bridge/iso_fb.h -- the wire protocol between isoshape and the
 * actuator/sensor microcontroller: CRC, COBS framing, a byte-at-a-time frame
 * parser with drop counters, and the message layouts. PROTOCOL.md is the
 * prose version of this header.
 *
 * Freestanding C11: no malloc, no stdio, no globals. Every buffer is owned by
 * the caller and passed with its capacity. The same file builds into the
 * Cortex-M firmware and into libisoshape. */
#ifndef ISO_FB_H
#define ISO_FB_H

#include <stddef.h>
#include <stdint.h>

#include "iso_api.h"

/* ---- sizes ------------------------------------------------------------- */
#define ISO_FB_VERSION 1u      /* protocol version, first header byte */
#define ISO_FB_MAX_PAYLOAD 64u /* message payload bytes, compile-time bound */
#define ISO_FB_HEADER 5u       /* version, type, seq (2), payload length */
#define ISO_FB_CRC_BYTES 2u
#define ISO_FB_MAX_CHANNELS 8u /* actuator channels a SETPOINTS frame can carry */
/* Raw (un-stuffed) frame: header + payload + CRC. */
#define ISO_FB_RAW_MAX (ISO_FB_HEADER + ISO_FB_MAX_PAYLOAD + ISO_FB_CRC_BYTES)
/* COBS of m bytes needs at most m + m/254 + 1 bytes (PacketSerial's bound). */
#define ISO_FB_COBS_MAX(m) ((m) + (m) / 254u + 1u)
/* On the wire a frame is 0x00, COBS(raw), 0x00: the leading delimiter ends
 * any garbage before it, so noise costs at most the frame it touches. */
#define ISO_FB_WIRE_MAX(payload)                                                                   \
    (ISO_FB_COBS_MAX(ISO_FB_HEADER + (payload) + ISO_FB_CRC_BYTES) + 2u)
#define ISO_FB_FRAME_MAX ISO_FB_WIRE_MAX(ISO_FB_MAX_PAYLOAD)

_Static_assert(ISO_FB_RAW_MAX <= 254u, "a raw frame fits one COBS block (no 0xFF code needed)");
_Static_assert(ISO_FB_MAX_PAYLOAD <= 255u, "payload length fits the one-byte length field");
_Static_assert(ISO_FB_MAX_CHANNELS * 2u + 5u <= ISO_FB_MAX_PAYLOAD, "SETPOINTS fits a payload");
_Static_assert(ISO_FB_MAX_CHANNELS * 6u + 9u <= ISO_FB_MAX_PAYLOAD, "HELLO fits a payload");

/* ---- results ----------------------------------------------------------- */
enum {
    ISO_FB_MORE = 0,       /* parser: byte taken, no frame yet */
    ISO_FB_FRAME = 1,      /* parser: *out holds a valid frame */
    ISO_FB_ENOSPACE = -20, /* destination capacity too small */
    ISO_FB_EARG = -21,     /* bad argument (NULL, too long, too many channels) */
    ISO_FB_ECOBS = -22,    /* frame dropped: bad COBS stuffing */
    ISO_FB_ESHORT = -23,   /* frame dropped: shorter than header + CRC */
    ISO_FB_ECRC = -24,     /* frame dropped: CRC mismatch */
    ISO_FB_ETOOLONG = -25, /* frame dropped: more bytes than ISO_FB_FRAME_MAX */
    ISO_FB_EVERSION = -26, /* frame dropped: unknown protocol version */
    ISO_FB_ELENGTH = -27,  /* frame dropped: length field disagrees with frame size */
    ISO_FB_ETYPE = -28,    /* frame dropped: unknown message type */
    ISO_FB_EDUP = -29,     /* frame dropped: same sequence number as the last one */
    ISO_FB_EORDER = -30,   /* frame dropped: sequence number older than the last one */
    ISO_FB_EPAYLOAD = -31  /* message payload does not match its type's layout */
};
/* A short constant name for any ISO_FB_* result; never NULL. */
ISO_API const char *iso_fb_strerror(int code);

/* ---- message types ----------------------------------------------------- */
enum {
    ISO_FB_HELLO = 1,         /* both ways: host asks, MCU answers with its description */
    ISO_FB_HANDLE_SAMPLE = 2, /* MCU -> host: timestamped pose or twist plus buttons */
    ISO_FB_SETPOINTS = 3,     /* host -> MCU: one value per actuator channel */
    ISO_FB_HEARTBEAT = 4,     /* MCU -> host: uptime, state, positions */
    ISO_FB_ACK = 5,           /* MCU -> host: a frame was applied (echoes setpoints) */
    ISO_FB_NAK = 6,           /* MCU -> host: a frame was refused, with a reason */
    ISO_FB_FAULT = 7,         /* MCU -> host: safe state entered, with a reason */
    ISO_FB_DIAG = 8,          /* host -> MCU: diagnostics (hang to prove the HW watchdog) */
    ISO_FB_SAFE = 9,          /* host -> MCU: brake to the safe state now (firmware >= 1.1) */
    ISO_FB_TYPE_COUNT = 10
};

/* ---- CRC and COBS ------------------------------------------------------- */
/* CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no xorout.
 * Check value over "123456789" is 0x29B1. */
ISO_API uint16_t iso_fb_crc16(const uint8_t *data, size_t len);

/* COBS-encodes len bytes into dst (no delimiter). Returns the encoded length,
 * or ISO_FB_ENOSPACE if dst_cap < ISO_FB_COBS_MAX(len); never writes past
 * dst_cap. src and dst must not overlap. */
ISO_API int iso_fb_cobs_encode(uint8_t *dst, size_t dst_cap, const uint8_t *src, size_t len);
/* Decodes len COBS bytes (no delimiter) into dst. Returns the decoded length,
 * ISO_FB_ECOBS if the input holds a 0x00 or a code runs past its end, or
 * ISO_FB_ENOSPACE if the result would not fit dst_cap. dst may equal src. */
ISO_API int iso_fb_cobs_decode(uint8_t *dst, size_t dst_cap, const uint8_t *src, size_t len);

/* ---- frames ------------------------------------------------------------ */
typedef struct iso_fb_view {
    uint8_t type;
    uint16_t seq;
    uint8_t len;
    const uint8_t *payload; /* points into the parser's buffer: valid until the next feed */
} iso_fb_view;

/* Writes one wire frame (0x00, COBS(header, payload, CRC), 0x00) into dst.
 * Returns its length, ISO_FB_EARG if len > ISO_FB_MAX_PAYLOAD, or
 * ISO_FB_ENOSPACE if dst_cap < ISO_FB_WIRE_MAX(len). */
ISO_API int iso_fb_frame_encode(uint8_t *dst, size_t dst_cap, uint8_t type, uint16_t seq,
                                const uint8_t *payload, size_t len);

typedef struct iso_fb_counters {
    uint32_t frames_ok;
    uint32_t bad_cobs, too_short, bad_crc, too_long, bad_version, bad_length, unknown_type;
    uint32_t duplicate, out_of_order;
    uint32_t seq_gaps; /* frames missing between accepted ones (accepted anyway) */
    uint32_t resyncs;  /* frames dropped for any reason: the sum of the above drops */
} iso_fb_counters;

typedef struct iso_fb_parser {                    /* caller allocates (stack, static or struct) */
    uint8_t buf[ISO_FB_COBS_MAX(ISO_FB_RAW_MAX)]; /* stuffed bytes of the frame being received */
    uint8_t raw[ISO_FB_RAW_MAX];                  /* the last decoded frame; views point here */
    size_t len;
    uint8_t discarding; /* overflowed: skip to the next 0x00 */
    uint8_t have_seq;   /* last_seq is meaningful */
    uint16_t last_seq;
    iso_fb_counters n;
} iso_fb_parser;

ISO_API void iso_fb_parser_init(iso_fb_parser *p);
/* Forgets the last sequence number, so the next frame is accepted whatever
 * its number (after a reconnect, or when the peer rebooted). HELLO frames do
 * this by themselves. */
ISO_API void iso_fb_parser_reset_seq(iso_fb_parser *p);
/* Feeds one byte. Returns ISO_FB_MORE, ISO_FB_FRAME (*out is valid), or a
 * negative ISO_FB_E* saying why a frame was dropped (also counted). The
 * parser always recovers at the next 0x00 and never writes out of bounds. */
ISO_API int iso_fb_parser_feed(iso_fb_parser *p, uint8_t byte, iso_fb_view *out);

/* ---- messages ---------------------------------------------------------- */
/* Setpoints and positions are signed 16-bit fixed point in milli-units of the
 * channel (mrad for a joint, um for a slide); rates in milli-units per second. */
typedef struct iso_fb_channel_info {
    int16_t min, max;  /* position limits */
    uint16_t max_rate; /* milli-units per second */
    int16_t safe;      /* position a channel takes in the safe state */
} iso_fb_channel_info;

#define ISO_FB_HELLO_BOOT 0x01u /* flags: first HELLO after a (re)boot, sent unasked */
#define ISO_FB_HELLO_CAN_SAFE                                                                      \
    0x02u /* flags, MCU's HELLO: it obeys SAFE (firmware >= 1.1);                                  \
           * a host sends SAFE only to an MCU that says so */

typedef struct iso_fb_hello {
    uint8_t proto_version;
    uint16_t fw_version; /* major << 8 | minor; 0 from the host */
    uint8_t flags;       /* ISO_FB_HELLO_BOOT */
    uint32_t uptime_ms;
    uint8_t n_channels; /* 0 in the host's request */
    iso_fb_channel_info ch[ISO_FB_MAX_CHANNELS];
} iso_fb_hello;

enum { ISO_FB_SAMPLE_POSE = 0, ISO_FB_SAMPLE_TWIST = 1 };
typedef struct iso_fb_sample {
    uint32_t t_us; /* MCU clock */
    uint8_t kind;  /* ISO_FB_SAMPLE_POSE: um and urad (rotation vector);
                    * ISO_FB_SAMPLE_TWIST: um/s and urad/s */
    uint16_t buttons;
    int32_t v[6];
} iso_fb_sample;

typedef struct iso_fb_setpoints {
    uint32_t tick;
    uint8_t n;
    int16_t value[ISO_FB_MAX_CHANNELS];
} iso_fb_setpoints;

enum { ISO_FB_STATE_IDLE = 0, ISO_FB_STATE_ARMED = 1, ISO_FB_STATE_SAFE = 2 };
typedef struct iso_fb_heartbeat {
    uint32_t uptime_ms;
    uint8_t state; /* ISO_FB_STATE_* */
    uint8_t n;
    int16_t pos[ISO_FB_MAX_CHANNELS];
} iso_fb_heartbeat;

/* ACK of a SETPOINTS frame carries its tick and the values as received, so
 * the host can check every value end to end; other ACKs carry n = 0. */
typedef struct iso_fb_ack {
    uint8_t type;
    uint16_t seq;
    uint32_t tick;
    uint8_t n;
    int16_t value[ISO_FB_MAX_CHANNELS];
} iso_fb_ack;

enum {
    ISO_FB_NAK_NOT_ARMED = 1,   /* SETPOINTS before a HELLO exchange */
    ISO_FB_NAK_CHANNELS = 2,    /* wrong channel count */
    ISO_FB_NAK_BAD_PAYLOAD = 3, /* payload does not parse */
    ISO_FB_NAK_REFUSED = 4      /* request not allowed in this state */
};
typedef struct iso_fb_nak {
    uint8_t type;
    uint16_t seq;
    uint8_t reason;
} iso_fb_nak;

enum {
    ISO_FB_FAULT_WATCHDOG = 1, /* no valid SETPOINTS for the watchdog time */
    ISO_FB_FAULT_REQUESTED = 2 /* the host sent SAFE */
};
typedef struct iso_fb_fault {
    uint8_t reason;
    uint32_t detail; /* WATCHDOG: ms from the last valid SETPOINTS to the safe state;
                      * REQUESTED: the SAFE request's cause */
    uint32_t uptime_ms;
} iso_fb_fault;

#define ISO_FB_DIAG_HANG_MAGIC 0x48414E47u /* "HANG" */
typedef struct iso_fb_diag {
    uint32_t magic;
} iso_fb_diag;

/* SAFE's cause, echoed in FAULT(REQUESTED)'s detail; the MCU brakes the same
 * way for each. */
enum { ISO_FB_SAFE_ESTOP = 1, ISO_FB_SAFE_LOOP_STALL = 2, ISO_FB_SAFE_STOP = 3 };
typedef struct iso_fb_safe {
    uint8_t cause; /* ISO_FB_SAFE_*; any value is obeyed */
} iso_fb_safe;

/* Pack: writes the payload into dst (capacity cap) and returns its length,
 * or ISO_FB_EARG (a count over ISO_FB_MAX_CHANNELS) / ISO_FB_ENOSPACE.
 * Unpack: parses a payload; returns 0, or ISO_FB_EPAYLOAD if its length or
 * a count is wrong (m is then unspecified). All fields little-endian. */
ISO_API int iso_fb_hello_pack(uint8_t *dst, size_t cap, const iso_fb_hello *m);
ISO_API int iso_fb_hello_unpack(iso_fb_hello *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_sample_pack(uint8_t *dst, size_t cap, const iso_fb_sample *m);
ISO_API int iso_fb_sample_unpack(iso_fb_sample *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_setpoints_pack(uint8_t *dst, size_t cap, const iso_fb_setpoints *m);
ISO_API int iso_fb_setpoints_unpack(iso_fb_setpoints *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_heartbeat_pack(uint8_t *dst, size_t cap, const iso_fb_heartbeat *m);
ISO_API int iso_fb_heartbeat_unpack(iso_fb_heartbeat *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_ack_pack(uint8_t *dst, size_t cap, const iso_fb_ack *m);
ISO_API int iso_fb_ack_unpack(iso_fb_ack *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_nak_pack(uint8_t *dst, size_t cap, const iso_fb_nak *m);
ISO_API int iso_fb_nak_unpack(iso_fb_nak *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_fault_pack(uint8_t *dst, size_t cap, const iso_fb_fault *m);
ISO_API int iso_fb_fault_unpack(iso_fb_fault *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_diag_pack(uint8_t *dst, size_t cap, const iso_fb_diag *m);
ISO_API int iso_fb_diag_unpack(iso_fb_diag *m, const uint8_t *src, size_t len);
ISO_API int iso_fb_safe_pack(uint8_t *dst, size_t cap, const iso_fb_safe *m);
ISO_API int iso_fb_safe_unpack(iso_fb_safe *m, const uint8_t *src, size_t len);

#endif
