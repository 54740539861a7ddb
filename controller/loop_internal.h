/* controller/loop_internal.h -- what the loop's files share: the loop's
 * state and the helpers each of its files gives the others. Not installed. */
#ifndef ISO_LOOP_INTERNAL_H
#define ISO_LOOP_INTERNAL_H

#include "iso_loop.h"

#include "iso_dev_enum.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"
#include "iso_display.h"
#include "iso_integrate.h"
#include "iso_logq.h"
#include "iso_proxy.h"
#include "iso_snapshot.h"

/* ---- statistics (controller/loop_stats.c) --------------------------------- */
/* The tick's statistics live in fixed storage, sized before the first tick:
 * the tick allocates nothing. Samples are kept whole for the first `cap`
 * ticks (the planned run, or 10 minutes of an open-ended one), so the
 * quantiles of a run that fits are exact; every tick also goes into a
 * log-spaced histogram (bins 0.5 % wide), which answers the quantiles of a
 * longer run to within 0.25 %, and the maxima are kept exactly. */
#define ISO_LOOP_HIST_BINS 4800       /* 1e-4 ms to 2.5e6 ms at 0.5 % a bin */
#define ISO_LOOP_RECENT 256           /* the live view's window */
#define ISO_LOOP_SAMPLES_MAX 4000000L /* exact samples at most (64 MB) */
typedef struct iso_loop_stats {
    double *tick_ms, *lat_ms; /* the first min(n, cap) ticks' samples */
    long n, cap;              /* ticks added; samples room */
    long misses, skipped;
    double max_gap_ms; /* the longest wall time from one tick's wake to the next's */
    double last_lat_ms;
    double max_tick_ms, max_lat_ms;
    uint32_t hist_tick[ISO_LOOP_HIST_BINS], hist_lat[ISO_LOOP_HIST_BINS];
    double recent[ISO_LOOP_RECENT];  /* the last ticks' compute times */
    double scratch[ISO_LOOP_RECENT]; /* sorted copy of recent, for its quantiles */
    int n_recent, head;
} iso_loop_stats;

void iso_loop__stats_init(iso_loop_stats *s);
void iso_loop__stats_deinit(iso_loop_stats *s);
/* Room for n ticks' samples (at most ISO_LOOP_SAMPLES_MAX), made before the
 * first tick: before memory is locked, and so that no tick allocates. */
ISO_NODISCARD int iso_loop__stats_reserve(iso_loop_stats *s, long n, iso_err *err);
/* Adds one tick's figures; never allocates (past the reserved room the
 * histogram alone takes them). */
void iso_loop__stats_add(iso_loop_stats *s, double tick_ms, double lat_ms);
/* q-quantile (0..1, nearest rank) of n values; sorts a copy. NAN for n = 0. */
double iso_loop__quantile(const double *v, long n, double q);
/* The q-quantile of the run's tick times (lat = 0) or latencies (lat = 1):
 * exact while every sample is kept, else from the histogram; q = 1 is the
 * exact maximum. Allocates (for the summary, not the tick). */
double iso_loop__stats_quantile(const iso_loop_stats *s, int lat, double q);
/* median, p99, max of the recent window: no allocation, a sort of scratch. */
void iso_loop__stats_recent(iso_loop_stats *s, double *med, double *p99, double *max);

/* A part's notice callback (the device hub's, the actuators'): the line
 * said as the loop's own, iso_loop_say (controller/loop.c). ctx: the loop. */
void iso_loop__note(void *ctx, const char *line);

struct iso_loop_sinks; /* loop_sinks.c */

struct iso_loop {
    const iso_scene *sc;
    iso_loop_opts o;
    FILE *log;
    /* Every line the loop says goes through it, from any thread: a log
     * that takes nothing never holds up the tick, the sender or the view's
     * server (common/iso_logq.h). */
    iso_logq *logq;
    const char *cmd; /* "run", "record", "replay": names notices */

    /* the method (NULL without a mesh) */
    iso_solver *solver;
    iso_stepper *st;
    double *x; /* current positions, 3*nv */
    /* The reduced model (solver.proxy), else NULL: the method steps the
     * proxy's positions y (3 np) and x follows them each tick. */
    iso_proxy *proxy;
    double *y;
    double proxy_s; /* seconds it took to build */
    int nv;
    double diag;                               /* the rest mesh's bounding-box diagonal */
    double centroid[ISO_SCENE_MAX_HANDLES][3]; /* handles' rest centroids */
    int nh; /* handles: the scene's, or the mapping's without a mesh */

    /* devices */
    iso_dev_hub *hub;
    iso_dev_rec_reader reader; /* the replayed recording */
    int replay;                /* 1: the devices are one replayed recording */
    long damaged_seen;
    uint32_t far_said[ISO_DEV_MAX_SOURCES]; /* map.far when it was last said */
    iso_dev_usb_watch *watch;               /* libusb hotplug wakes the hub's retry; NULL without */
    iso_dev_map map;
    int dev_handle[ISO_SCENE_MAX_HANDLES]; /* map twist j drives handle dev_handle[j] */
    int n_dev;
    iso_dev_tick last;                   /* the previous device tick's command */
    iso_dev_source *view_src;            /* the scene's view device (owned by the hub), or NULL */
    int recording;                       /* the hub records (a writer is attached to it) */
    struct iso_loop__recorder *recorder; /* the record button's, live devices with a path */

    /* commanded motion */
    iso_pose cmd_pose[ISO_SCENE_MAX_HANDLES];  /* rest to commanded, per handle */
    double homing_left[ISO_SCENE_MAX_HANDLES]; /* > 0: returning to rest (reset_pose) */

    /* time */
    int64_t stream0, t_now; /* ns: tick 0's stream time; the last computed tick's */
    int64_t k;              /* grid index of the last tick (live and scripted) */
    int64_t k_end;          /* the last grid index to run; INT64_MAX: open-ended */
    int64_t t_end;          /* replay: the last stream time to run; INT64_MAX: all */
    int64_t period_ns;      /* the nominal period, rounded (fallback replay ticks) */
    int64_t script_ns;      /* scripted drivers' clock: stream time outside an e-stop */
    int64_t wall0;          /* wall time of stream0 */
    long ticks, device_ticks, restarts, substeps, coarse;
    uint64_t cmd_sum;
    uint32_t status_events[ISO_DEV_MAX_SOURCES]; /* events at the last status line */
    double wall_start, wall_end;

    iso_loop_stats stats;
    iso_loop_summary rt; /* rt_active, mem_locked, rt_note */
    struct iso_loop_sinks *sinks;
    int shut;
    /* what the last tick did, for the sinks */
    int last_merged, last_substeps, last_restart;
    int64_t last_dt_ns;
};

/* loop_recorder.c: the record button's recordings, opened and closed on a
 * thread of their own. create: for the scene's path base (recording_now:
 * the run records to it already). press: the button, on the tick (starts
 * or stops; *recording follows the hub). poll: each device tick before
 * the drain, attaches a recording the thread has opened. destroy: after
 * the last tick; a recording being closed ends whole. */
typedef struct iso_loop__recorder iso_loop__recorder;
ISO_NODISCARD int iso_loop__recorder_create(iso_loop *l, const char *base, int recording_now,
                                            iso_loop__recorder **out, iso_err *err);
void iso_loop__recorder_destroy(iso_loop__recorder *r);
void iso_loop__recorder_press(iso_loop__recorder *r, iso_dev_hub *hub, int *recording);
void iso_loop__recorder_poll(iso_loop__recorder *r, iso_dev_hub *hub, int *recording);

/* loop_devices.c: the mapping, the devices or the replay, ready to tick. */
ISO_NODISCARD int iso_loop__devices_open(iso_loop *l, iso_err *err);
/* One device tick over (l->t_now, t]: drain, map, advance the device-driven
 * handles' commanded poses; tw gets their twists, *restart a discontinuity. */
ISO_NODISCARD int iso_loop__device_tick(iso_loop *l, int64_t t, iso_twist *tw, int *restart,
                                        iso_err *err);
/* Scripted handles: their exact path pose at the scripted clock. */
ISO_NODISCARD int iso_loop__scripted_poses(iso_loop *l, double s0, int *restart, iso_err *err);
/* FNV-1a over n bytes, continuing from h. */
uint64_t iso_loop__fnv1a(uint64_t h, const void *p, size_t n);

/* loop_tick.c: one tick at wall time `now`. */
ISO_NODISCARD int iso_loop__tick(iso_loop *l, int64_t now, iso_err *err);

/* loop_run.c: the stream time of grid tick k: stream0 + k / tick_hz, rounded
 * to the nanosecond once (never accumulated). */
int64_t iso_loop__grid_ns(const iso_loop *l, int64_t k);

/* loop_drive.c: a scripted driver's exact pose at path time s (seconds,
 * e-stops excluded) for a handle whose rest centroid is c. */
ISO_NODISCARD int iso_loop__scripted_pose(const iso_scene_driver *d, const double c[3], double s,
                                          iso_pose *P, iso_err *err);
/* 1 when the driver's velocity jumps (a keyframe, the screw's end) in
 * [s0, s1): the tick over it restarts the Adams history. */
int iso_loop__scripted_jump(const iso_scene_driver *d, double s0, double s1);
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
/* Destroys what sinks_close keeps (the live view, serving its last frame). */
void iso_loop__sinks_free(iso_loop *l);
/* The loop's progress, for the actuators' loop watchdog (lock-free; every
 * tick and every ABM step), and the devices' e-stop, passed on at once. */
void iso_loop__sinks_alive(iso_loop *l);
void iso_loop__sinks_estop(iso_loop *l, int on);
/* A one-line note for the status line (display clients), "" if nothing. */
void iso_loop__sinks_status(const iso_loop *l, char *buf, size_t cap);

/* loop_writer.c: the file sinks' writer thread and the bounded queue the
 * tick hands it frames through (the file says the rules). */
typedef struct iso_loop_writer iso_loop_writer;
struct iso_sink_frame;
struct iso_sink_session;
/* The session the Foxglove channels describe (MCAP and the live view). */
void iso_loop__fox_session(iso_loop *l, struct iso_sink_session *s);
/* NULL in *out when the run has no file output. */
ISO_NODISCARD int iso_loop__writer_open(iso_loop *l, iso_loop_writer **out, iso_err *err);
/* The tick's side. The next free slot for tick `tick` (*want: what is
 * written of it), or NULL when nothing is wanted or the queue is full (the
 * frame is then dropped and counted); fill it, then push. No allocation,
 * no lock, no wait. */
struct iso_sink_frame *iso_loop__writer_slot(iso_loop_writer *w, long tick, int *want);
void iso_loop__writer_push(iso_loop_writer *w, const double *x);
/* The writer thread's first error, if any (the run stops with it). */
ISO_NODISCARD int iso_loop__writer_check(iso_loop_writer *w, iso_err *err);
void iso_loop__writer_counts(const iso_loop_writer *w, iso_loop_summary *s);
long iso_loop__writer_dropped(const iso_loop_writer *w);
/* Writes what is queued, stops the thread, commits the PC2 and MCAP files
 * (commit = 1; else they stay under their temporary names), stores the
 * counts in *counts (may be NULL) and frees w. */
ISO_NODISCARD int iso_loop__writer_close(iso_loop_writer *w, int commit, iso_loop_summary *counts,
                                         iso_err *err);

#endif
