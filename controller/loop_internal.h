/* controller/loop_internal.h -- what the loop's files share: the loop's
 * state and the helpers of loop_drive.c and loop_sinks.c. Not installed. */
#ifndef ISO_LOOP_INTERNAL_H
#define ISO_LOOP_INTERNAL_H

#include "loop.h"

#include "iso_dev.h"
#include "iso_display.h"
#include "iso_integrate.h"
#include "iso_snapshot.h"

struct iso_loop_sinks; /* loop_sinks.c */

struct iso_loop {
    const iso_scene *sc;
    iso_loop_opts o;
    FILE *log;

    /* the method */
    iso_solver *solver;
    iso_stepper *st;
    double *x;              /* current positions, 3*nv */
    int nv;
    double centroid[ISO_SCENE_MAX_HANDLES][3]; /* handles' rest centroids */

    /* devices */
    iso_dev_hub *hub;
    iso_dev_rec_reader reader; /* the replayed recording */
    int replay;             /* 1: the devices are one replayed recording */
    long damaged_seen;
    iso_dev_map map;
    int dev_handle[ISO_SCENE_MAX_HANDLES]; /* map twist j drives scene handle dev_handle[j] */
    int n_dev;
    iso_dev_tick last;      /* the previous tick's command */
    int recording;

    /* time */
    int64_t stream0, stream_now; /* ns */
    int64_t period_ns;
    double script_t;        /* scripted drivers' clock: stream time outside an e-stop */
    double homing_left[ISO_SCENE_MAX_HANDLES]; /* > 0: returning to rest (reset_pose) */
    long ticks, restarts;
    double wall_start, wall_end;

    iso_loop_stats stats;
    iso_loop_summary rt;    /* rt_active, mem_locked, rt_note */
    struct iso_loop_sinks *sinks;
    int shut;
};

/* loop_drive.c: the twist of a scripted driver over [t, t + h] for a handle
 * whose rest centroid is c and whose pose is G now. *crossed is set when the
 * interval crosses a keyframe or the screw's end (a velocity jump). */
ISO_NODISCARD int iso_loop__scripted_twist(const iso_scene_driver *d, const double c[3],
                                           const iso_pose *G, double t, double h, iso_twist *xi,
                                           int *crossed, iso_err *err);
/* The constant twist that takes pose G to pose P in time h > 0. */
ISO_NODISCARD int iso_loop__twist_between(const iso_pose *G, const iso_pose *P, double h,
                                          iso_twist *xi, iso_err *err);
/* When a scripted driver's motion ends (seconds); 0 for other drivers. */
double iso_loop__scripted_end(const iso_scene_driver *d);

/* loop_sinks.c: display, snapshots, PLY frames, actuators. */
ISO_NODISCARD int iso_loop__sinks_open(iso_loop *l, iso_err *err);
/* Publishes tick `tick`'s positions; stats for the display. */
ISO_NODISCARD int iso_loop__sinks_publish(iso_loop *l, long tick, iso_err *err);
/* Stops them: the actuators to their safe state. Idempotent. */
ISO_NODISCARD int iso_loop__sinks_close(iso_loop *l, iso_err *err);
void iso_loop__sinks_summary(const iso_loop *l, iso_loop_summary *s);
/* A one-line note for the status line (display clients), "" if nothing. */
void iso_loop__sinks_status(const iso_loop *l, char *buf, size_t cap);

#endif
