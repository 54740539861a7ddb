/* sinks/iso_sink_frame.h -- what a run gives its sinks: the session (what
 * stays the same through it) and one frame a tick (the positions, the
 * handles' commanded and achieved poses, the mapping's command, the
 * solver's and the devices' counters, the actuators' state). The file
 * sinks (PC2, PLY, the MCAP file through the Foxglove encoding) and the
 * live Foxglove connection read the same record, so each says what the
 * others say. A frame's positions are the caller's and must outlive the
 * call it is given to; everything else is by value. */
#ifndef ISO_SINK_FRAME_H
#define ISO_SINK_FRAME_H

#include <stdint.h>

#include "iso_actuators.h"
#include "iso_dev_hub.h"
#include "iso_geom.h"
#include "iso_mesh.h"
#include "iso_regions.h"

#define ISO_SINK_MAX_HANDLES 8
#define ISO_SINK_MAX_DEVICES 16
#define ISO_SINK_NAME_MAX 64

/* What stays the same through a session. */
typedef struct iso_sink_session {
    const iso_mesh *mesh;       /* must outlive the sinks */
    const iso_regions *regions; /* NULL: no tint */
    int n_handles;
    char handle_name[ISO_SINK_MAX_HANDLES][ISO_SINK_NAME_MAX];
    double handle_centre[ISO_SINK_MAX_HANDLES][3]; /* rest centroids */
    int n_devices;
    uint8_t device_kind[ISO_SINK_MAX_DEVICES]; /* iso_dev_kind */
    int n_act;                                 /* actuator channels; 0: no /actuators */
    int act_channel[ISO_ACT_MAX_CHANNELS];     /* their SETPOINTS indices */
    int wall_times;                            /* 1: /loop carries the wall-clock figures */
} iso_sink_session;

/* One device's state at a tick. */
typedef struct iso_sink_device {
    uint8_t present, stale, has_pose, has_twist;
    int16_t axes[6];
    uint32_t buttons;
    double v[6]; /* the last pose or twist sample (iso_dev_map_src) */
    iso_dev_source_stats stats;
} iso_sink_device;

/* What one tick gives. */
typedef struct iso_sink_frame {
    long tick;
    int64_t t_ns, dt_ns; /* stream time since the start, and the tick's length */
    const double *x;     /* 3*nv positions */
    iso_pose commanded[ISO_SINK_MAX_HANDLES], achieved[ISO_SINK_MAX_HANDLES];
    int substeps, merged, restart;
    int active;
    uint8_t clutch, estop;
    uint32_t buttons;
    long evaluations, factorizations, cg_iterations; /* the solver's, so far */
    double tick_ms, latency_ms;                      /* wall times (wall_times only) */
    long misses, dropped; /* deadlines that passed without a tick of their own; frames
                             the writer could not take */
    iso_sink_device dev[ISO_SINK_MAX_DEVICES];
    int have_act;
    int16_t setpoints[ISO_ACT_MAX_CHANNELS]; /* by SETPOINTS index */
    iso_act_stats act;
} iso_sink_frame;

#endif
