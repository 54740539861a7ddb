/* devices/iso_dev.h -- the input side: sources (one backend per file),
 * decoders that only ever see bytes and timestamps, the mapping from decoded
 * events to one command per tick, recordings, and the hub that ties them.
 *
 *   backend ──chunk──▶ hub ──chunk──▶ decoder ──events──▶ map ──▶ iso_dev_tick
 *                        └──▶ recording (the same chunks) ──▶ replay backend
 *
 * A chunk is what one read of a source gave: raw bytes with a monotonic
 * timestamp in nanoseconds. Everything above the chunk is deterministic: the
 * same chunks (a recording) give the same events and the same tick commands,
 * bit for bit, whatever the wall clock does.
 *
 * Ownership: sources and hubs are heap handles (open/close, create/destroy,
 * NULL is a no-op); decoders, maps, readers and writers are caller-owned
 * structs (init/deinit). Nothing here is thread-safe; no global state. */
#ifndef ISO_DEV_H
#define ISO_DEV_H

#include <stddef.h>
#include <stdint.h>

#include "iso_clock.h" /* iso_clock_ns(): the time base of every live chunk */
#include "iso_err.h"
#include "iso_geom.h"

/* ====================================================================== */
/* Chunks and source descriptions                                          */
/* ====================================================================== */

#define ISO_DEV_CHUNK_MAX 255u /* bytes per chunk: one HID report, one serial read */
#define ISO_DEV_DESC_MAX 4096u /* HID report descriptor (HID_MAX_DESCRIPTOR_SIZE) */
#define ISO_DEV_NAME_MAX 128u
#define ISO_DEV_MAX_SOURCES 16u
#define ISO_DEV_MAX_HANDLES 8u

typedef enum iso_dev_kind {
    ISO_DEV_KIND_HID = 1,    /* raw HID input reports, report ID first (3D mice) */
    ISO_DEV_KIND_SPNAV = 2,  /* spacenavd events in this library's encoding (RECORDING.md) */
    ISO_DEV_KIND_SERIAL = 3, /* the firmware bridge's byte stream (COBS frames) */
    ISO_DEV_KIND_GPIO = 4,   /* GPIO edges: (role, level) byte pairs */
    ISO_DEV_KIND_VIEW = 5    /* the browser view's commands (see "The browser view" below) */
} iso_dev_kind;

typedef enum iso_dev_chunk_type {
    ISO_DEV_CHUNK_DATA = 1, /* bytes from the device */
    ISO_DEV_CHUNK_GONE = 2, /* the device went away (unplugged, read error) */
    ISO_DEV_CHUNK_BACK = 3, /* the device was opened again */
    ISO_DEV_CHUNK_TICK = 4, /* a tick boundary of the loop that recorded (no source) */
    /* Format 2 (RECORDING.md). END: the writer closed the recording; the
     * reader consumes it and never hands it out. SKIP: noise the raw-byte
     * cap left out of the recording (ISO_DEV_REC_NOISE_CAP): its payload
     * is what the source's decoder counted and where its frame parser
     * stood after it, so that a replay decodes what follows exactly as
     * the live run did. */
    ISO_DEV_CHUNK_END = 5,
    ISO_DEV_CHUNK_SKIP = 6
} iso_dev_chunk_type;

typedef struct iso_dev_chunk {
    int64_t t_ns;   /* CLOCK_MONOTONIC of the read (or of the kernel event) */
    uint8_t source; /* index in the hub / the recording header */
    uint8_t type;   /* iso_dev_chunk_type */
    uint16_t len;
    uint8_t data[ISO_DEV_CHUNK_MAX];
} iso_dev_chunk;

/* GPIO roles: the first byte of each GPIO pair. */
enum { ISO_DEV_GPIO_CLUTCH = 0, ISO_DEV_GPIO_ESTOP = 1, ISO_DEV_GPIO_ROLES = 2 };

/* What a recording's header says about one source. */
typedef struct iso_dev_info {
    uint8_t kind;                         /* iso_dev_kind */
    uint16_t vid, pid;                    /* USB IDs, 0 if none */
    uint32_t baud;                        /* serial: bits per second, 0 if none */
    uint8_t data_bits, parity, stop_bits; /* serial: 8, 'N'/'E'/'O', 1 */
    uint32_t debounce_us;                 /* GPIO debounce time */
    char name[ISO_DEV_NAME_MAX];          /* path or label, NUL-terminated */
    uint16_t desc_len;                    /* HID report descriptor bytes, 0 if unknown */
    uint8_t desc[ISO_DEV_DESC_MAX];
} iso_dev_info;

/* "hid", "spnav", "serial", "gpio", "view"; never NULL */
ISO_API const char *iso_dev_kind_name(int kind);

/* ====================================================================== */
/* Sources: one interface, one backend per file                            */
/* ====================================================================== */

typedef struct iso_dev_source iso_dev_source;
typedef struct iso_dev_source_ops {
    const char *backend; /* "hidapi", "tty", "tcp", ... */
    /* A descriptor to poll for input, or -1 (hidapi has none: read each tick). */
    int (*fd)(iso_dev_source *s);
    /* Reads what is there without blocking: returns 1 and fills *out (data
     * stamped at or before until_ns), 0 when there is nothing now, or a
     * negative ISO_E* code with err filled when the device is gone. */
    int (*read)(iso_dev_source *s, int64_t until_ns, iso_dev_chunk *out, iso_err *err);
    /* Optional: drives an output line (GPIO trigger); NULL if none. */
    int (*write_level)(iso_dev_source *s, int level, iso_err *err);
    void (*close)(iso_dev_source *s);
    /* Optional: the e-stop input's level now, read without blocking and
     * safe to call from another thread than read's (the actuators' sender
     * reads it every 2 ms while a tick computes: iso_dev_hub_estop_probe).
     * 1 pressed, 0 released, ISO_ENOTSUP when the source has no e-stop
     * line, another negative ISO_E* when the read failed. NULL: none. */
    int (*estop_level)(iso_dev_source *s);
} iso_dev_source_ops;

struct iso_dev_source {
    const iso_dev_source_ops *ops;
    iso_dev_info info;
    int multiplexed; /* 1: chunks carry their own source index (replay) */
    void *impl;      /* the backend's private struct */
    /* For people, not recorded: what else says which device this is (a HID
     * product name, the socket spacenavd answered on); "" if nothing. */
    char detail[ISO_DEV_NAME_MAX];
};

ISO_API int iso_dev_source_fd(iso_dev_source *s);
ISO_API ISO_NODISCARD int iso_dev_source_read(iso_dev_source *s, int64_t until_ns,
                                              iso_dev_chunk *out, iso_err *err);
ISO_API void iso_dev_source_close(iso_dev_source *s); /* NULL is a no-op */

/* ---- simulated backends (always built) --------------------------------- */

/* A scripted source for tests: chunks and "gone" marks queued by the test,
 * handed out in order once until_ns reaches their time. */
ISO_API ISO_NODISCARD int iso_dev_fake_open(const iso_dev_info *info, iso_dev_source **out,
                                            iso_err *err);
/* Queues bytes (len <= ISO_DEV_CHUNK_MAX) at time t. */
ISO_API ISO_NODISCARD int iso_dev_fake_push(iso_dev_source *s, int64_t t_ns, const void *data,
                                            size_t len);
/* Queues a device failure at time t: read then returns ISO_EIO. */
ISO_API ISO_NODISCARD int iso_dev_fake_push_gone(iso_dev_source *s, int64_t t_ns);
/* How many times write_level was called, and the last level written. */
ISO_API int iso_dev_fake_writes(iso_dev_source *s, int *last_level);
/* Gives the fake an e-stop line at this level (1 pressed, 0 released, or a
 * negative ISO_E* its estop_level then returns); any thread. Until the first
 * call it has none (ISO_ENOTSUP). */
ISO_API void iso_dev_fake_set_estop(iso_dev_source *s, int level);

/* ---- OS backends without optional libraries (always built) ------------ */

/* A POSIX tty (pseudo-terminal, emulator, /dev/ttyUSB0) in raw 8N1 at baud. */
ISO_API ISO_NODISCARD int iso_dev_tty_open(const char *path, uint32_t baud, iso_dev_source **out,
                                           iso_err *err);
/* A TCP client to a serial-over-network bridge, "host:port". Connects before
 * it returns (timeout_ms), then reads without blocking. */
ISO_API ISO_NODISCARD int iso_dev_tcp_open(const char *host_port, int timeout_ms,
                                           iso_dev_source **out, iso_err *err);

/* ---- hardware backends (compiled when their -dev package is present) -- */
/* Each returns ISO_ENOTSUP with a sentence when its library was not built in. */

/* hidapi (hidraw): path as hidapi enumerates it ("/dev/hidraw3"), or NULL
 * for the first known 3D mouse. */
ISO_API ISO_NODISCARD int iso_dev_hid_open(const char *path, iso_dev_source **out, iso_err *err);
/* The same, held to a vendor and product id (0: any): without a path, the
 * first device with that vid (and pid); with both 0, the first known 3D
 * mouse. With a path, a device there whose ids differ is refused (ISO_EIO,
 * naming both pairs), so a scene never drives a handle from a device it did
 * not name. Not found: ISO_EIO naming the ids. */
ISO_API ISO_NODISCARD int iso_dev_hid_open_id(const char *path, uint16_t vid, uint16_t pid,
                                              iso_dev_source **out, iso_err *err);
/* spacenavd through libspnav: fails with ISO_EIO when no daemon runs. The
 * socket is found as libspnav finds it: $SPNAV_SOCKET, then `socket =` in
 * /etc/spnavrc, then /var/run/spnav.sock (the first that accepts; it goes
 * into detail). When the daemon closes the connection (stopped, killed,
 * restarted) read reports the source gone, so the hub emits GONE and
 * retries; libspnav itself would only see "no events". */
ISO_API ISO_NODISCARD int iso_dev_spnav_open(iso_dev_source **out, iso_err *err);
/* libserialport: a real serial adapter by name ("/dev/ttyUSB0"). */
ISO_API ISO_NODISCARD int iso_dev_serialport_open(const char *name, uint32_t baud,
                                                  iso_dev_source **out, iso_err *err);
/* libgpiod v1: chip ("gpiochip0"), clutch and e-stop line offsets (-1 none),
 * active_low, debounce, and an optional output line for a per-tick pulse. */
typedef struct iso_dev_gpio_opts {
    const char *chip;
    int clutch_line, estop_line, pulse_line;
    int active_low;
    uint32_t debounce_us;
} iso_dev_gpio_opts;
ISO_API ISO_NODISCARD int iso_dev_gpiod_open(const iso_dev_gpio_opts *o, iso_dev_source **out,
                                             iso_err *err);

/* ---- discovery ---------------------------------------------------------- */

typedef struct iso_dev_found {
    char backend[16]; /* "hidapi", "spnav", "serialport", "gpiod", "libusb" */
    char path[ISO_DEV_NAME_MAX];
    char what[ISO_DEV_NAME_MAX]; /* product or description */
    uint16_t vid, pid;
    int usable;    /* 1: can be opened now */
    char why[320]; /* when not usable: why, and what fixes it */
} iso_dev_found;

/* Lists what every built-in backend sees. Returns the count written (at most
 * cap); never fails: a backend that cannot look says so in an entry. */
ISO_API size_t iso_dev_enumerate(iso_dev_found *out, size_t cap);
/* 1 if (vid, pid) is a known 3D mouse (3Dconnexion 0x046d / 0x256f). */
ISO_API int iso_dev_is_3dmouse(uint16_t vid, uint16_t pid);
/* The udev rule that grants the logged-in user a device (uaccess). */
ISO_API void iso_dev_udev_rule(uint16_t vid, char *buf, size_t cap);
/* Which backends were compiled in, e.g. "fake replay tty tcp hidapi
 * serialport gpiod libusb spnav", written into buf (the names that fit in
 * cap, whole); returns buf. */
ISO_API const char *iso_dev_backends(char *buf, size_t cap);
/* 1 if the backend `name` ("hidapi", "serialport", "gpiod", "libusb",
 * "spnav", or one always built: "fake", "replay", "tty", "tcp") was compiled
 * in, 0 if it was compiled out (its open function then returns ISO_ENOTSUP),
 * -1 if there is no backend of that name. */
ISO_API int iso_dev_backend_built(const char *name);

/* libusb hotplug: a watcher whose fd set wakes the loop on arrival and
 * removal of known devices. iso_dev_usb_watch_poll returns how many events
 * arrived since the last call (each sets the hub's retry to "now"). */
typedef struct iso_dev_usb_watch iso_dev_usb_watch;
ISO_API ISO_NODISCARD int iso_dev_usb_watch_create(iso_dev_usb_watch **out, iso_err *err);
ISO_API int iso_dev_usb_watch_poll(iso_dev_usb_watch *w);
ISO_API void iso_dev_usb_watch_destroy(iso_dev_usb_watch *w);

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

/* Noise. A device that delivers only bad input (bytes that are no frame,
 * reports of unknown IDs) for ISO_DEV_NOISE_NOTICE_NS of stream time gets
 * one message from the hub, with a hint (a serial line: its baud rate, and
 * whether this is the right device), and one more when good input comes
 * back. Stream time: a replay says it in the same tick. */
#define ISO_DEV_NOISE_NOTICE_NS 2000000000LL
/* A tick drains at most this many bytes from one source; the rest waits
 * for the next tick. It bounds what a flood costs a tick: 16 KiB of noise
 * decoded and recorded, 0.08 ms median and 0.17 ms p99 (tests/tools/
 * noise_bench, SCHED_FIFO on a shared 2-core machine), far above any
 * handle stream (a 115200-baud line brings 192 bytes in a 60 Hz tick; a 3D
 * mouse, ~1 kB/s). The tick never reads a byte stream from the kernel
 * itself (iso_dev_hub_set_priority says why). End to end, so a flood leaves
 * a run's p99 tick within the spread of its quiet runs: a 60 Hz cactus run
 * with its handle on a pty flooded with random bytes at the rate the tick
 * drains, 2.3-3.1 ms against 2.0-3.3 quiet, where a tick that read the tty
 * went to 19-35 ms (noise_bench; docs/performance.md, "Noise on a serial
 * line"). */
#define ISO_DEV_DRAIN_MAX 16384u
/* A recording keeps at most this many bytes per second of stream time of a
 * source's chunks that decode to nothing; beyond it they become SKIP
 * records (RECORDING.md, "The noise cap"). A 115200-baud line's whole
 * stream (11.5 kB/s) fits under it. */
#define ISO_DEV_REC_NOISE_CAP 16384u

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

/* ---- the browser view's commands (ISO_DEV_KIND_VIEW) ------------------- */
/* What a page of the live view (view/iso_display.h) sends on its WebSocket,
 * one binary message each, little-endian, and the envelope in which the
 * view's server hands each to its device (and so to the recording).
 *
 * Why a pose target, not a twist: a drag must end where the user let go.
 * A twist stream is integrated by the loop, so every lost, late or merged
 * sample moves the end, and the page cannot tell; a target names the end
 * itself, and the loop reaches it exactly (to round-off) however the
 * samples were spaced. The mapping bounds the speed at which a handle
 * follows (ISO_DEV_VIEW_MAX_*), so a target far away is approached over
 * several ticks instead of jumped to.
 *
 * Message, from the page:
 *   offset 0  u8   version, ISO_DEV_VIEW_VERSION
 *          1  u8   type, ISO_DEV_VIEW_TAKE ... ISO_DEV_VIEW_UNSTOP
 *          2  u8   handle: the mapping's handle index (TARGET), else 0
 *          3  u8   flags, 0
 *          4  u32  seq: the page's own, from 1, growing on each message
 *          8  f64  the page's clock when sent, ms (echoed in the view's frames)
 *         16  6 f64  TARGET only: the pose rest -> target, position (scene
 *                  units) then rotation vector (rad); |r| <= 4 pi
 * A message is exactly 16 bytes, or 64 for TARGET; anything else is refused.
 *
 * Envelope (one chunk, recorded as is):
 *   offset 0  u8   what: ISO_DEV_VIEW_MSG (a page's message follows),
 *                  ISO_DEV_VIEW_GRANT (the connection took control) or
 *                  ISO_DEV_VIEW_END (its control ended; one reason byte,
 *                  ISO_DEV_VIEW_END_*, follows)
 *          1  u32  the connection: the server's number for the WebSocket
 *          5  ...  the message, or the reason
 * The server decides who is in control (one viewer at a time, the first to
 * ask) and forwards TARGETs from that viewer only, STOP and UNSTOP from any
 * viewer that may command; the decoder checks it all again, so a recording
 * edited by hand cannot do what a page could not. */
#define ISO_DEV_VIEW_VERSION 1u
#define ISO_DEV_VIEW_HEAD 16u       /* bytes of every message */
#define ISO_DEV_VIEW_TARGET_LEN 64u /* a TARGET message */
#define ISO_DEV_VIEW_MSG_MAX 64u
#define ISO_DEV_VIEW_ENVELOPE 5u /* bytes before the message */
_Static_assert(ISO_DEV_VIEW_ENVELOPE + ISO_DEV_VIEW_MSG_MAX <= ISO_DEV_CHUNK_MAX,
               "an enveloped message fits one chunk");
enum {
    ISO_DEV_VIEW_TAKE = 1,    /* ask for control */
    ISO_DEV_VIEW_RELEASE = 2, /* give control up */
    ISO_DEV_VIEW_TARGET = 3,  /* move a handle to a pose */
    ISO_DEV_VIEW_STOP = 4,    /* the page's stop button: a software e-stop */
    ISO_DEV_VIEW_UNSTOP = 5   /* its deliberate release */
};
enum { ISO_DEV_VIEW_MSG = 1, ISO_DEV_VIEW_GRANT = 2, ISO_DEV_VIEW_END = 3 };
enum {
    ISO_DEV_VIEW_END_RELEASED = 1, /* the page let go */
    ISO_DEV_VIEW_END_LEFT = 2,     /* the viewer disconnected */
    ISO_DEV_VIEW_END_STOPPED = 3,  /* the server stopped (the run ended) */
    ISO_DEV_VIEW_END_LAPSED = 4    /* the page in control fell silent (ISO_DISPLAY_LAPSE_MS) */
};
/* How fast a view target is followed, at most: the handle's centre moves
 * ISO_DEV_VIEW_MAX_DIAG_PER_S bounding-box diagonals a second and turns
 * ISO_DEV_VIEW_MAX_TURN_PER_S radians a second (the loop sets them per
 * source from the mesh, iso_dev_map_set_limits, live and on replay alike). */
#define ISO_DEV_VIEW_MAX_DIAG_PER_S 2.0
#define ISO_DEV_VIEW_MAX_TURN_PER_S 6.283185307179586
/* How far a target or a pose stream may put a handle: its centre at most
 * ISO_DEV_WORKSPACE_DIAGS bounding-box diagonals from where it rests (the
 * loop sets it per source, iso_dev_map_set_workspace). A target beyond is
 * refused and counted, never followed part of the way. */
#define ISO_DEV_WORKSPACE_DIAGS 3.0

/* One parsed message. */
typedef struct iso_dev_view_msg {
    uint8_t type, handle;
    uint32_t seq;
    double page_ms;
    double pose[6]; /* TARGET: p, r; else 0 */
} iso_dev_view_msg;

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

/* ---- the browser view --------------------------------------------------- */

/* Parses one page message (the format above). Returns ISO_OK and fills
 * *out, or ISO_EPARSE with a phrase in why (e.g. "a TARGET message has 64
 * bytes, not 63"): a wrong version, type, length or flag, a handle on a
 * message that has none, a sequence number of 0, a clock or pose that is
 * not finite, a position beyond 1e12 or a rotation beyond 4 pi. why may be
 * NULL. */
ISO_API ISO_NODISCARD int iso_dev_view_parse(const uint8_t *p, size_t n, iso_dev_view_msg *out,
                                             char *why, size_t cap);
/* Writes a message (what a page sends; for tests and tools). Returns its
 * length, or ISO_EINVAL for an unknown type or a cap below it. */
ISO_API int iso_dev_view_encode(const iso_dev_view_msg *m, uint8_t *dst, size_t cap);

/* The source the view's server feeds: a queue of enveloped chunks, filled
 * from the server's thread (iso_dev_view_push) and read by the hub on the
 * loop's. Its estop_level answers at once from what was pushed, so a
 * page's stop reaches the actuators' sender (which reads it every 2 ms)
 * without waiting for a tick; the same STOP is also decoded in its tick. */
ISO_API ISO_NODISCARD int iso_dev_view_open(const char *name, iso_dev_source **out, iso_err *err);
/* Queues one envelope (what, conn, and for ISO_DEV_VIEW_MSG the message,
 * len <= ISO_DEV_VIEW_MSG_MAX; for ISO_DEV_VIEW_END one reason byte),
 * stamped now. Thread-safe; takes a lock held for a copy. A STOP or UNSTOP
 * sets the e-stop level before it returns. The queue holds 256 chunks;
 * TARGETs may fill all but the last 32, which are kept for the rest, so a
 * flood of targets never crowds out a stop. Returns ISO_OK, ISO_EINVAL
 * (not a view source, a bad envelope) or ISO_ENOMEM when full (counted;
 * what was dropped is said by iso_dev_view_dropped). */
ISO_API ISO_NODISCARD int iso_dev_view_push(iso_dev_source *s, int what, uint32_t conn,
                                            const void *msg, size_t len);
/* Chunks refused because the queue was full; any thread. */
ISO_API uint32_t iso_dev_view_dropped(iso_dev_source *s);
/* Is this a view source? */
ISO_API int iso_dev_is_view(const iso_dev_source *s);

/* The SpaceMouse family (3Dconnexion 0x046d and 0x256f): one HID input
 * report, report ID first. Told apart by length: ID 1 with 7 bytes is
 * translation, ID 1 with 13 bytes translation and rotation, ID 2 with 7
 * bytes rotation, ID 3 buttons (little-endian bit mask). Axes are LE int16. */
ISO_API size_t iso_dev_sm_decode(iso_dev_decoder *d, int64_t t_ns, const uint8_t *r, size_t len,
                                 iso_dev_event *ev, size_t cap);

/* ---- a 3D mouse's axes, from the device to here ------------------------
 * The axes this library hands on (ISO_DEV_EV_AXES, and so every mapping)
 * are the device's own: its HID report's X Y Z Rx Ry Rz, in its counts
 * (about ±350 on the 3Dconnexion family), from either backend:
 *  - hidraw (hidapi) gives the report's bytes, whatever the kernel makes
 *    of the device for evdev (the same bytes in every layout below). It
 *    keeps 63 reports per reader and drops the newest when full: a tick
 *    slower than that lasts (about 0.25 s at a mouse's 125 reports a
 *    second) can lose the cap's return to rest. A deflected device keeps
 *    reporting, a released one falls silent: so a drain that found the
 *    buffer full, followed by one that finds nothing, ends with a report of
 *    rest (13 bytes, ID 1, zeros);
 *  - spacenavd reads evdev and changes the axes; the spnav backend undoes
 *    it (iso_dev_spnav_to_device), so a scene maps a device the same
 *    through either. What spacenavd (1.1) does, and what the kernel
 *    (6.1) does before it:
 *    Y/Z: for the 3Dconnexion devices it knows (every 256f one, and
 *    046d:c623 c625 c626 c627 c628 c629 c62b) it swaps Y and Z and negates
 *    both, rotations as translations: its (x, y, z) is the device's
 *    (x, -z, -y).
 *    Absolute axes (evdev ABS_X..ABS_RZ: a descriptor whose axes are
 *    absolute, and the SpaceNavigator whose relative descriptor
 *    hid-logitech fixes up, the one without unit items) are rescaled from
 *    the logical range to [-500, 500]: 1.43 times the counts for ±350.
 *    Relative ones (REL_*) pass as they are.
 *    Relative axes never return to 0: the kernel passes no zero relative
 *    value, so spacenavd keeps each axis's last non-zero one and sends it
 *    again with the next event of any axis. A deflected device reports
 *    every poll, so silence means the cap is at rest: after
 *    ISO_DEV_SPNAV_REST_NS without motion (reads that find none for that
 *    long, or spacenavd's period on the next motion, whichever tells
 *    first) the backend reports rest itself (a recorded 'M' record of
 *    zeros, before that next motion), and from then on takes an axis
 *    that still shows the value spacenavd kept as 0, until it changes.
 *    Values spacenavd kept from before the connection cannot be told.
 *    spacenavd's dead zone (|v| < 2 is 0), its sensitivity and any
 *    remapping in /etc/spnavrc stay in effect.
 * Which device and layout spacenavd serves comes from the daemon
 * (protocol 1: its USB id and evdev node) or, when it does not say, from
 * the one 3D mouse among the input devices, and from sysfs (the node's
 * axis capabilities, the HID descriptor's range); without them the
 * backend assumes a swapping device with relative axes, which fails safe
 * (a rest inferred too early stops motion; one never inferred would not).
 * hidapi (0.13) lists a device once per collection that has a usage: a
 * SpaceNavigator's hidraw node three times. It is one device: isoshape
 * devices lists it once. */

/* The six axes' Input items in a HID report descriptor. */
typedef struct iso_dev_hid_axes_info {
    uint8_t found;    /* bit per axis X..Rz (0..5) an Input item carries */
    uint8_t relative; /* bit per axis whose Input item says relative */
    int32_t lo, hi;   /* the axes' logical range (the last axis item's) */
} iso_dev_hid_axes_info;
/* Walks a report descriptor. ISO_OK when all six axes were found,
 * ISO_ENOTSUP when not (out says which were), ISO_EPARSE for an item that
 * runs past len. */
ISO_API int iso_dev_hid_axes(const uint8_t *desc, size_t len, iso_dev_hid_axes_info *out);

#define ISO_DEV_SPNAV_REST_NS 200000000LL /* silence that means rest (relative axes) */

/* How spacenavd changed a device's axes (see above). */
typedef struct iso_dev_spnav_layout {
    int swap_yz;    /* 1: Y and Z swapped and negated */
    int absolute;   /* 1: rescaled from [lo, hi] to [-500, 500]; 0: as they were */
    int32_t lo, hi; /* the device's logical range (absolute only; hi > lo) */
} iso_dev_spnav_layout;
/* 1 if spacenavd 1.1 swaps and negates Y/Z for this USB id; vid 0 (the
 * daemon did not say) counts as swapping, as nearly every device does. */
ISO_API int iso_dev_spnav_swaps_yz(uint16_t vid, uint16_t pid);
/* One spacenavd motion event (x y z rx ry rz) back to the device's axes and
 * counts: the exact inverse of spacenavd's integer rescale, then of the
 * swap; clamped to int16. */
ISO_API void iso_dev_spnav_to_device(const iso_dev_spnav_layout *l, const int v[6], int16_t out[6]);

/* ====================================================================== */
/* Mapping: events to one command per tick                                */
/* ====================================================================== */

enum { ISO_DEV_LOCK_NONE = 0, ISO_DEV_LOCK_TRANSLATION = 1, ISO_DEV_LOCK_ROTATION = 2 };
enum { ISO_DEV_FRAME_WORLD = 0, ISO_DEV_FRAME_DEVICE = 1 };
enum {
    ISO_DEV_ACT_NONE = 0,
    ISO_DEV_ACT_CLUTCH = 1,      /* held: handles decoupled from the device */
    ISO_DEV_ACT_NEXT_HANDLE = 2, /* press: the device drives the next handle */
    ISO_DEV_ACT_RESET_POSE = 3,  /* press: the loop resets the active handle */
    ISO_DEV_ACT_RECORD = 4       /* press: the loop starts or stops recording */
};
/* The names scenes and options use, indexed by value (common/iso_names.h):
 * locks "none", "translation", "rotation"; frames "world", "device";
 * clutch "hold", "deadman" (clutch_is_deadman 0, 1); button actions "none",
 * "clutch", "next_handle", "reset_pose", "record"; axes "tx", "ty", "tz",
 * "rx", "ry", "rz" (index 0..5, as in remap, invert and the per-axis
 * arrays). */
ISO_API extern const char *const iso_dev_lock_names[];
ISO_API extern const char *const iso_dev_frame_names[];
ISO_API extern const char *const iso_dev_clutch_names[];
ISO_API extern const char *const iso_dev_action_names[];
ISO_API extern const char *const iso_dev_axis_names[];

typedef struct iso_dev_map_opts {
    double full_scale;         /* raw counts at full deflection (350) */
    double sensitivity[6];     /* per output axis at full scale: m/s (tx..tz), rad/s (rx..rz) */
    double dead_zone[6];       /* fraction of full scale that maps to 0 */
    double curve[6];           /* response exponent: 1 linear, 2 quadratic ... */
    int remap[6];              /* output axis i reads input axis remap[i] */
    int invert[6];             /* 1: negate output axis i */
    int dominant;              /* 1: keep only the largest axis */
    int lock;                  /* ISO_DEV_LOCK_* */
    int frame;                 /* ISO_DEV_FRAME_*: axes along the world's or the handle's */
    int clutch_is_deadman;     /* 0: clutch held = hold still; 1: move only while held */
    uint8_t button_action[32]; /* ISO_DEV_ACT_* per button bit (3D mouse and serial) */
    int n_handles;             /* 1..ISO_DEV_MAX_HANDLES */
    double pose_gain;          /* absolute pose streams: fraction of the error closed per tick */
    double pose_scale;         /* pose stream units to scene units (1) */
} iso_dev_map_opts;

/* Defaults: 350 counts, 0.1 m/s and 0.5 rad/s, 5 % dead zone, linear,
 * identity remap, no lock, world frame, button 0 clutch, button 1 next
 * handle, one handle, pose gain 1. */
ISO_API void iso_dev_map_opts_default(iso_dev_map_opts *o);

typedef struct iso_dev_tick {
    int64_t t_ns;
    int n_handles;
    iso_twist twist[ISO_DEV_MAX_HANDLES]; /* world twists, rotation about the handle */
    int active;                           /* the handle the devices drive */
    uint8_t clutch;                       /* 1: clutch held */
    uint8_t estop;                        /* 1: emergency stop: every twist is zero. Any
                                           * e-stop line pressed, or gone with its
                                           * source: an e-stop that cannot be read is
                                           * not trusted, until its source is back
                                           * and reports the line released */
    uint32_t buttons;                     /* OR of every source's buttons */
    uint32_t actions;                     /* bit ISO_DEV_ACT_*: pressed during this tick */
    uint32_t gone;                        /* bit per source that is unplugged */
    uint32_t stale;                       /* bit per source whose twist stream went quiet */
    uint32_t targeting;                   /* bit per source with a fresh target (a view) */
} iso_dev_tick;

typedef struct iso_dev_map_src { /* what one source last said */
    int16_t axes[6];
    uint32_t buttons;
    uint8_t has_pose, has_twist;
    uint8_t has_target; /* a view's target for handle `handle` (ISO_DEV_EV_TARGET) */
    uint8_t handle;
    uint8_t stale;   /* 1: its twist or target is older than the stale time: ignored */
    int64_t t_twist; /* stream time of its last twist or target sample */
    double v[6];
    uint8_t estop_line; /* 1: it has reported an e-stop line (kept while gone) */
    uint8_t estop;      /* its e-stop: the line's last level; 1 while the source is gone */
} iso_dev_map_src;

/* Twist streams (ISO_DEV_EV_TWIST: the serial/TCP bridge's HANDLE_SAMPLE
 * twists) are velocity commands: a sender that goes quiet with the link
 * still open must not leave its last twist driving the handle. Past the
 * stale time since a source's last twist sample (measured on the ticks'
 * now_ns, the stream time, never the wall clock, so a replay reproduces
 * it) that source's twist counts as zero until the next sample. 100 ms is
 * the firmware's own link watchdog and a usual robot-base command timeout.
 * A view's targets (ISO_DEV_EV_TARGET) go stale the same way: a page
 * that stops sending stops commanding, and its handle holds where it is.
 * Pose streams hold their last pose (a pose is a target, not a rate). 3D
 * mice (HID axes, spacenavd) are not timed out: their report is the state
 * of the cap, and one held still at a deflection may send nothing new
 * (spacenavd has a repeat option for exactly that); they return to rest
 * with a report of zeros, and a lost mouse or daemon is GONE instead. */
#define ISO_DEV_STALE_DEFAULT_NS 100000000LL
#define ISO_DEV_STALE_MIN_NS 1000000LL     /* 1 ms */
#define ISO_DEV_STALE_MAX_NS 10000000000LL /* 10 s */

typedef struct iso_dev_map {
    iso_dev_map_opts o;
    int active;
    uint8_t clutch, estop;
    uint32_t gone;
    iso_dev_map_src src[ISO_DEV_MAX_SOURCES];
    int64_t stale_ns[ISO_DEV_MAX_SOURCES]; /* per source; ISO_DEV_STALE_DEFAULT_NS */
    /* Per source, the fastest a target is followed: the handle centre's
     * speed (scene units/s) and turn rate (rad/s); 0 = no bound. */
    double max_speed[ISO_DEV_MAX_SOURCES], max_turn[ISO_DEV_MAX_SOURCES];
    /* Per source, how far from its rest place a target or pose may put a
     * handle's centre (scene units; 0 = no bound), and how many it refused
     * for that. */
    double workspace[ISO_DEV_MAX_SOURCES];
    uint32_t far[ISO_DEV_MAX_SOURCES];
    /* Each handle's centre in rest coordinates (0 unless set): the point
     * device rotations turn about, carried along by the handle's pose. */
    double centre[ISO_DEV_MAX_HANDLES][3];
} iso_dev_map;

/* The range each numeric mapping option must lie in, held in one table and
 * checked here for scene files, the command line and iso_dev_map_init
 * alike. `field` is the option's scene key: "full_scale" (> 0),
 * "sensitivity" [0, 1e6], "dead_zone" [0, 0.99], "curve" [0.1, 10],
 * "pose_gain" (0, 1], "pose_scale" (> 0). Returns 0 when v lies in its
 * field's range; else -1 and a phrase for the caller's message in why,
 * e.g. "expected a value in [0, 0.99], found 1.5" (NaN is never in range;
 * an unknown field says so). */
ISO_API int iso_dev_map_check(const char *field, double v, char *why, size_t cap);

ISO_API ISO_NODISCARD int iso_dev_map_init(iso_dev_map *m, const iso_dev_map_opts *o, iso_err *err);
/* Sets source `source`'s stale time for twist streams (see above), in
 * stream nanoseconds. ISO_EINVAL with a sentence for a source index past
 * ISO_DEV_MAX_SOURCES or a time outside [ISO_DEV_STALE_MIN_NS,
 * ISO_DEV_STALE_MAX_NS]. Set it after iso_dev_map_init (which sets every
 * source to the default). */
ISO_API ISO_NODISCARD int iso_dev_map_set_stale(iso_dev_map *m, int source, int64_t stale_ns,
                                                iso_err *err);
/* Bounds how fast source `source`'s targets are followed (see iso_dev_map):
 * speed in scene units per second at the handle's centre, turn in radians
 * per second; 0 leaves one unbounded. A target within both bounds is
 * reached in one tick; one beyond is approached along the same screw,
 * reached in as many ticks as the bounds need. ISO_EINVAL for a source
 * index out of range or a negative or non-finite bound. */
ISO_API ISO_NODISCARD int iso_dev_map_set_limits(iso_dev_map *m, int source, double speed,
                                                 double turn, iso_err *err);
/* Bounds where source `source`'s targets and poses may put a handle: its
 * centre at most `radius` scene units from its rest place (0: no bound).
 * One beyond is refused (the handle keeps following the last one within)
 * and counted in m->far[source]. ISO_EINVAL for a source index out of
 * range or a negative or non-finite radius. */
ISO_API ISO_NODISCARD int iso_dev_map_set_workspace(iso_dev_map *m, int source, double radius,
                                                    iso_err *err);
/* Sets handle h's centre (rest coordinates): a twist of the device then
 * turns the handle about R c + p, where it is now, instead of about p. */
ISO_API void iso_dev_map_set_centre(iso_dev_map *m, int h, const double c[3]);
/* The mapping of one device reading (6 raw axes) to a twist for a handle
 * at pose g (rotation about its centre g->p). Pure: no state. */
ISO_API void iso_dev_map_axes(const iso_dev_map_opts *o, const int16_t axes[6], const iso_pose *g,
                              iso_twist *out);
/* Applies this tick's events in order and writes the tick's command.
 * poses[h] is handle h's current pose, rest to current (for the device
 * frame, rotation about the handle's centre, and pose streams, whose
 * samples are poses in the same sense); dt_s the tick length.
 * Deterministic. */
ISO_API void iso_dev_map_tick(iso_dev_map *m, const iso_dev_event *ev, size_t n, int64_t now_ns,
                              double dt_s, const iso_pose *poses, iso_dev_tick *out);

/* The recordings and the hub, in headers of their own, part of this one
 * (each includes it first, so any of the three may be included alone). */
#include "iso_dev_hub.h"
#include "iso_dev_rec.h"

#endif
