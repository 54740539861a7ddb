/* devices/iso_dev_map.h -- the mapping: a tick's decoded events
 * (iso_dev_decode.h) to one command per tick (iso_dev_tick), a world twist
 * per handle with clutch, e-stop, buttons and actions; and the options
 * scenes and the command line set for it, with their names and ranges.
 * Pure arithmetic on the events and the poses it is given, so that the
 * same events give the same commands bit for bit; it reads no source. */
#ifndef ISO_DEV_MAP_H
#define ISO_DEV_MAP_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev.h"
#include "iso_dev_decode.h"
#include "iso_err.h"
#include "iso_geom.h"

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
/* How far a target or a pose stream may put a handle: its centre at most
 * ISO_DEV_WORKSPACE_DIAGS bounding-box diagonals from where it rests (the
 * loop sets it per source, iso_dev_map_set_workspace). A target beyond is
 * refused and counted, never followed part of the way. */
#define ISO_DEV_WORKSPACE_DIAGS 3.0
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

#endif
