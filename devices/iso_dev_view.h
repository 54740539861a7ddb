/* devices/iso_dev_view.h -- the browser view as a device (kind VIEW): the
 * commands a page of the live view sends, the envelope in which its server
 * passes each on (the wire format, below), their parser and encoder, and
 * the source the server feeds. One header, because the format is one
 * contract between view/, the view's decoder (devices/decode_view.c) and
 * the recordings, which keep the envelopes as they came. */
#ifndef ISO_DEV_VIEW_H
#define ISO_DEV_VIEW_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev.h"
#include "iso_dev_source.h"
#include "iso_err.h"

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

/* One parsed message. */
typedef struct iso_dev_view_msg {
    uint8_t type, handle;
    uint32_t seq;
    double page_ms;
    double pose[6]; /* TARGET: p, r; else 0 */
} iso_dev_view_msg;

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

#endif
