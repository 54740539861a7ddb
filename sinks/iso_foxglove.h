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
#include <stdint.h>

#include "iso_actuators.h"
#include "iso_dev.h"
#include "iso_err.h"
#include "iso_geom.h"
#include "iso_mesh.h"
#include "iso_regions.h"

#define ISO_FOX_MAX_HANDLES 8
#define ISO_FOX_MAX_DEVICES 16
#define ISO_FOX_NAME_MAX 64
#define ISO_FOX_STRAIN_LEVELS 32
#define ISO_FOX_MAX_CHANNELS (4 + 2 * ISO_FOX_MAX_HANDLES + ISO_FOX_MAX_DEVICES)

/* What stays the same through a session. */
typedef struct iso_fox_session {
    const iso_mesh *mesh;       /* must outlive the encoder */
    const iso_regions *regions; /* NULL: no tint */
    int n_handles;
    char handle_name[ISO_FOX_MAX_HANDLES][ISO_FOX_NAME_MAX];
    double handle_centre[ISO_FOX_MAX_HANDLES][3]; /* rest centroids */
    int n_devices;
    uint8_t device_kind[ISO_FOX_MAX_DEVICES]; /* iso_dev_kind */
    int n_act;                                /* actuator channels; 0: no /actuators */
    int act_channel[ISO_ACT_MAX_CHANNELS];    /* their SETPOINTS indices */
    int wall_times;                           /* 1: /loop carries the wall-clock figures */
} iso_fox_session;

/* One device's state at a tick. */
typedef struct iso_fox_device {
    uint8_t present, stale, has_pose, has_twist;
    int16_t axes[6];
    uint32_t buttons;
    double v[6]; /* the last pose or twist sample (iso_dev_map_src) */
    iso_dev_source_stats stats;
} iso_fox_device;

/* What one tick gives. */
typedef struct iso_fox_frame {
    long tick;
    int64_t t_ns, dt_ns; /* stream time since the start, and the tick's length */
    const double *x;     /* 3*nv positions */
    iso_pose commanded[ISO_FOX_MAX_HANDLES], achieved[ISO_FOX_MAX_HANDLES];
    int substeps, merged, restart;
    int active;
    uint8_t clutch, estop;
    uint32_t buttons;
    long evaluations, factorizations, cg_iterations; /* the solver's, so far */
    double tick_ms, latency_ms;                      /* wall times (wall_times only) */
    long misses, dropped; /* deadlines that passed without a tick of their own; frames
                             the writer could not take */
    iso_fox_device dev[ISO_FOX_MAX_DEVICES];
    int have_act;
    int16_t setpoints[ISO_ACT_MAX_CHANNELS]; /* by SETPOINTS index */
    iso_act_stats act;
} iso_fox_frame;

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
ISO_API int iso_fox_channels(const iso_fox_session *s, iso_fox_channel *out, int cap);

typedef struct iso_fox_encoder iso_fox_encoder; /* opaque */

ISO_API ISO_NODISCARD int iso_fox_encoder_create(const iso_fox_session *s, iso_fox_encoder **out,
                                                 iso_err *err);
/* Encodes channel c's message for frame f. *data points into the encoder
 * (valid until its next call) and *len is its length. ISO_ENOMEM. */
ISO_API ISO_NODISCARD int iso_fox_encode(iso_fox_encoder *e, const iso_fox_channel *c,
                                         const iso_fox_frame *f, const char **data, size_t *len,
                                         iso_err *err);
ISO_API void iso_fox_encoder_destroy(iso_fox_encoder *e); /* NULL is a no-op */

#endif
