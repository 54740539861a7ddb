/* devices/iso_dev.h -- the input side's common base: the chunk, the
 * description of a source (iso_dev_info, as a recording's header keeps
 * it), the kinds of source and the limits every part of the input side
 * sizes its arrays by. The objects built on it have one header each, as
 * libgpiod v2 does, so that a reader finds an object's API by its file
 * name; each includes what it uses (this one among them), so any may be
 * included alone:
 *
 *   iso_dev_source.h  sources: one interface, one backend per file
 *   iso_dev_enum.h    discovery: what is connected, what was built in
 *   iso_dev_decode.h  decoded events, and the decoders that make them
 *   iso_dev_view.h    the browser view's commands, and its source
 *   iso_dev_axes.h    a 3D mouse's axes, from the device to here
 *   iso_dev_map.h     the mapping from events to one command per tick
 *   iso_dev_rec.h     recordings, and the replay source
 *   iso_dev_hub.h     the hub that ties them, one tick at a time
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

#include <stdint.h>

#include "iso_api.h"
#include "iso_clock.h" /* iso_clock_ns(): the time base of every live chunk */

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
    ISO_DEV_KIND_VIEW = 5    /* the browser view's commands (iso_dev_view.h) */
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

#endif
