/* sinks/iso_foxglove.h -- a session's data as Foxglove channels: what the
 * MCAP file (iso_mcap.h) and the live Foxglove connection (the view's
 * server) carry, encoded once, here, so both say the same.
 *
 * Every message is JSON (message encoding "json") under a JSON Schema
 * (schema encoding "jsonschema"); times are stream time, nanoseconds since
 * the run's first tick's start, so a recording gives the same messages
 * whatever the machine. Channels, in this order:
 *
 *   /mesh                       foxglove.SceneUpdate: entity "mesh" in frame
 *                               "world", its triangles coloured by edge
 *                               strain as the live view colours them (the
 *                               largest relative change of the three edge
 *                               lengths, blue 0 - red ISO_SNAPSHOT_STRAIN_FULL,
 *                               magenta tint at handles, grey at fixed
 *                               vertices). A SceneUpdate replaces an entity
 *                               whole, so each message carries the points and
 *                               the triangles: one TriangleListPrimitive per
 *                               colour, the strain quantized to
 *                               ISO_FOX_STRAIN_LEVELS steps over the scale
 *                               (steps of 0.32 % strain: below what the eye
 *                               tells apart on it).
 *   /handles/NAME/commanded     foxglove.FrameTransform, world to frame
 *   /handles/NAME/achieved      "NAME/commanded" or "NAME/achieved": the
 *                               handle's pose (rest to now) applied to its
 *                               rest centre: where it is and how it is turned.
 *   /loop                       isoshape.Tick: the tick, its stream time and
 *                               length, sub-steps, merged device ticks,
 *                               restarts, the mapping's command (active
 *                               handle, clutch, e-stop, buttons), the
 *                               solver's counts; in a live run also the wall
 *                               times (tick compute, latency, misses), which
 *                               an export leaves out to stay reproducible.
 *   /devices/I                  isoshape.DeviceSample, one channel a device:
 *                               its decoded state (axes and buttons, or the
 *                               last pose or twist sample), presence,
 *                               staleness and counters.
 *   /actuators                  isoshape.Actuators, when the run has them:
 *                               the setpoints sent, the MCU's reported state
 *                               and positions, and the link's counters.
 *
 * Not thread-safe: an encoder is used by one thread. */
#ifndef ISO_FOXGLOVE_H
#define ISO_FOXGLOVE_H

#include <stddef.h>

#include "iso_err.h"
#include "iso_sink_frame.h" /* the session and the frames it encodes */

#define ISO_FOX_STRAIN_LEVELS 32
/* the channels: mesh, loop, commanded and achieved per handle, a device's each, actuators */
#define ISO_FOX_MAX_CHANNELS (4 + 2 * ISO_SINK_MAX_HANDLES + ISO_SINK_MAX_DEVICES)

enum {
    ISO_FOX_MESH,
    ISO_FOX_COMMANDED,
    ISO_FOX_ACHIEVED,
    ISO_FOX_LOOP,
    ISO_FOX_DEVICE,
    ISO_FOX_ACT
};

typedef struct iso_fox_channel {
    char topic[128];
    const char *schema_name; /* "foxglove.SceneUpdate", ... */
    const char *schema;      /* its JSON Schema text */
    int what;                /* ISO_FOX_* */
    int index;               /* the handle or device it is of */
} iso_fox_channel;

/* The session's channels, in the order above, into out (cap at least
 * ISO_FOX_MAX_CHANNELS); returns their count. */
ISO_API int iso_fox_channels(const iso_sink_session *s, iso_fox_channel *out, int cap);

typedef struct iso_fox_encoder iso_fox_encoder; /* opaque */

ISO_API ISO_NODISCARD int iso_fox_encoder_create(const iso_sink_session *s, iso_fox_encoder **out,
                                                 iso_err *err);
/* Encodes channel c's message for frame f. *data points into the encoder
 * (valid until its next call) and *len is its length. ISO_ENOMEM. */
ISO_API ISO_NODISCARD int iso_fox_encode(iso_fox_encoder *e, const iso_fox_channel *c,
                                         const iso_sink_frame *f, const char **data, size_t *len,
                                         iso_err *err);
ISO_API void iso_fox_encoder_destroy(iso_fox_encoder *e); /* NULL is a no-op */

#endif
