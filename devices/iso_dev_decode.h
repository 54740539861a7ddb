/* devices/iso_dev_decode.h -- decoded events, and the decoders that make
 * them: one per source, fed that source's chunks and nothing else (bytes
 * and timestamps), so that a recording's chunks decode to the same events
 * bit for bit; and the counts of what each decoder skipped (bad input is
 * counted, never fatal). The events are what the mapping reads
 * (iso_dev_map.h). The view's command format is iso_dev_view.h, and how a
 * 3D mouse's axes reach the events iso_dev_axes.h. */
#ifndef ISO_DEV_DECODE_H
#define ISO_DEV_DECODE_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev.h"
#include "iso_err.h"

/* ====================================================================== */
/* Decoded events                                                         */
/* ====================================================================== */

typedef enum iso_dev_event_kind {
    ISO_DEV_EV_AXES = 1,    /* axes[6]: tx ty tz rx ry rz in raw counts (full state) */
    ISO_DEV_EV_BUTTONS = 2, /* buttons: full state after the change */
    ISO_DEV_EV_POSE = 3,    /* v[0..2] position (m), v[3..5] rotation vector (rad) */
    ISO_DEV_EV_TWIST = 4,   /* v[0..2] velocity (m/s), v[3..5] angular velocity (rad/s) */
    ISO_DEV_EV_GPIO = 5,    /* line (role), level: debounced, 1 = active */
    ISO_DEV_EV_GONE = 6,
    ISO_DEV_EV_BACK = 7,
    /* A pose target for handle `line` (the mapping's handle index): v[0..2]
     * position, v[3..5] rotation vector of the pose rest -> target, in scene
     * units. A stream of targets goes stale like a twist stream. */
    ISO_DEV_EV_TARGET = 8,
    /* The source stops commanding (its controller let go or left): its
     * target is forgotten and its handle holds where it is. level: the
     * reason, ISO_DEV_VIEW_END_* */
    ISO_DEV_EV_RELEASE = 9
} iso_dev_event_kind;

typedef struct iso_dev_event {
    int64_t t_ns;
    uint8_t kind;
    uint8_t source;
    uint8_t line, level;
    uint32_t buttons;
    int16_t axes[6];
    double v[6];
} iso_dev_event;

/* ====================================================================== */
/* Decoders: bytes and timestamps in, events out                          */
/* ====================================================================== */

typedef struct iso_dev_counters {
    uint32_t chunks;        /* chunks fed */
    uint32_t reports;       /* reports or frames decoded */
    uint32_t short_reports; /* HID: too short for their ID; spnav: truncated */
    uint32_t unknown_ids;   /* HID report IDs or spnav types we do not know */
    uint32_t bad_frames;    /* serial: COBS, CRC, length, version, sequence drops */
    /* Bytes that belong to no valid frame or pair: serial bytes outside
     * every accepted frame (its 0x00 delimiters aside), unknown spnav
     * bytes, a GPIO chunk's odd byte; and events beyond the caller's room
     * (a HID report's only garbage: its bad reports are counted above). */
    uint32_t garbage;
    uint32_t bounces;      /* GPIO edges the debounce did not take at once */
    uint32_t bad_payloads; /* serial: HANDLE_SAMPLE frames whose payload does not unpack
                              (counted in bad_frames too) */
    /* Times the decoder found its reports or frames again after bad
     * input: each stretch of garbage, bad frames or unknown reports that
     * a good one ended counts once. */
    uint32_t resyncs;
    uint32_t unrecorded;   /* raw bytes the recording left out (ISO_DEV_REC_NOISE_CAP) */
    uint32_t refused;      /* view: well-formed commands not applied (not from the viewer
                              in control, or a kind the stream does not carry) */
    uint32_t out_of_order; /* view: targets whose sequence number did not grow (not applied) */
    uint32_t grants;       /* view: times a viewer took control */
    uint32_t releases;     /* view: times control ended (let go, the viewer left) */
} iso_dev_counters;

/* Serial: the frames the firmware bridge's parser dropped, by reason
 * (firmware-bridge/PROTOCOL.md, "Receiver"), kept across reconnects. */
typedef struct iso_dev_frame_drops {
    uint32_t too_long, bad_cobs, too_short, bad_crc, bad_version, bad_length, unknown_type;
    uint32_t duplicate, out_of_order;
    uint32_t seq_gaps; /* frames missing between accepted ones (those are accepted) */
} iso_dev_frame_drops;

typedef struct iso_dev_gpio_line {
    uint8_t accepted, raw, have; /* debounced level, last edge's level, seen */
    int64_t t_accept, t_raw;
} iso_dev_gpio_line;

/* What a view decoder knows of its stream. */
typedef struct iso_dev_view_state {
    uint32_t holder;       /* the connection in control, 0 none */
    uint32_t last_seq;     /* the holder's last accepted sequence number */
    uint32_t applied_conn; /* the last target applied: its connection, */
    uint32_t applied_seq;  /* its sequence number */
    double applied_ms;     /* and its page clock */
    uint8_t estop;         /* a page's stop is pressed and not released */
    uint32_t estop_conn;   /* who pressed it */
} iso_dev_view_state;

typedef struct iso_dev_decoder {
    uint8_t kind, source;
    iso_dev_counters n;
    int16_t axes[6];
    uint32_t buttons;
    int64_t debounce_ns;
    iso_dev_gpio_line gpio[ISO_DEV_GPIO_ROLES];
    _Alignas(8) unsigned char fb[512]; /* the firmware bridge's iso_fb_parser */
    uint32_t fb_pending; /* serial: bytes since the last frame boundary (garbage if no frame) */
    /* Stream times of the first and the latest bad input since the last
     * good report or frame; INT64_MIN while there is none. */
    int64_t noise_since, noise_last;
    iso_dev_view_state view; /* kind VIEW */
} iso_dev_decoder;

/* Prepares a decoder for a source of info->kind. ISO_EINVAL for an unknown
 * kind. */
ISO_API ISO_NODISCARD int iso_dev_decoder_init(iso_dev_decoder *d, const iso_dev_info *info,
                                               uint8_t source, iso_err *err);
/* Decodes one chunk into at most cap events appended at ev. Returns the
 * number written. Bad bytes are counted and skipped, never fatal. Events
 * beyond cap are dropped and counted as garbage (size ev for a chunk:
 * ISO_DEV_EVENTS_PER_CHUNK is always enough). A SKIP chunk (a recording's
 * noise left out) adds its counts and leaves the serial parser where the
 * live run's stood after it; it gives no event. */
#define ISO_DEV_EVENTS_PER_CHUNK 130u
ISO_API size_t iso_dev_decode(iso_dev_decoder *d, const iso_dev_chunk *c, iso_dev_event *ev,
                              size_t cap);
/* The serial parser's drops by reason; all zero for other kinds. */
ISO_API void iso_dev_decoder_drops(const iso_dev_decoder *d, iso_dev_frame_drops *out);
/* Time passes without a chunk: confirms GPIO levels that have been stable
 * for the debounce time. Returns the events written. */
ISO_API size_t iso_dev_decode_tick(iso_dev_decoder *d, int64_t now_ns, iso_dev_event *ev,
                                   size_t cap);

/* The SpaceMouse family (3Dconnexion 0x046d and 0x256f): one HID input
 * report, report ID first. Told apart by length: ID 1 with 7 bytes is
 * translation, ID 1 with 13 bytes translation and rotation, ID 2 with 7
 * bytes rotation, ID 3 buttons (little-endian bit mask). Axes are LE int16. */
ISO_API size_t iso_dev_sm_decode(iso_dev_decoder *d, int64_t t_ns, const uint8_t *r, size_t len,
                                 iso_dev_event *ev, size_t cap);

#endif
