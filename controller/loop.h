/* controller/loop.h -- the real-time loop behind `isoshape run SCENE`.
 *
 * One iso_loop owns everything a scene needs while it runs: the solver and
 * the per-tick stepper, the device hub and its mapping (or the replay of a
 * recording), the scripted handle paths, and the sinks (live display, PNG
 * snapshots, PLY frames, actuators over the firmware bridge, a recording).
 *
 * Time. The loop keeps two clocks apart:
 *   stream time  the time the mesh lives in: tick k is at the k-th tick of
 *                the recording being replayed, else at k / tick_hz. Every
 *                step of the integrator is one tick of stream time, always,
 *                so a replay gives the same bits at any speed and under any
 *                load.
 *   wall time    CLOCK_MONOTONIC: deadline k is wall0 + stream(k) / speed,
 *                slept to with clock_nanosleep(TIMER_ABSTIME).
 * When a tick finishes after the next deadline (an overrun) the missed
 * deadlines are counted and skipped: the wall anchor moves forward by whole
 * periods so the next tick starts on the first deadline still ahead. Input
 * is drained at the start of every tick, so the input-to-publish latency
 * stays one tick however many were skipped; what a long overrun costs is
 * that the mesh's stream time falls behind the wall clock, never that
 * queued input piles up. With `fast` there is no waiting at all.
 *
 * Per tick (iso_loop_tick): drain the devices into one command, turn it and
 * the scripted drivers into one world twist per handle held over the tick,
 * advance the mesh by one ABM step (RK4 again after a discontinuity: clutch,
 * e-stop, handle switch, device gone or back), publish the vertices.
 *
 * Not thread-safe; the display and the native firmware emulation have
 * threads of their own behind their APIs. */
#ifndef ISO_LOOP_H
#define ISO_LOOP_H

#include <signal.h>
#include <stdint.h>
#include <stdio.h>

#include "iso_err.h"
#include "iso_metrics.h"
#include "iso_scene.h"

typedef struct iso_loop iso_loop; /* opaque */

typedef struct iso_loop_opts {
    int fast;               /* 1: no waiting, as fast as possible on stream time */
    double speed;           /* wall pacing: stream seconds per wall second (1) */
    double duration_s;      /* stop after this much stream time; 0: when the stream ends */
    long max_ticks;         /* stop after this many ticks; 0: no limit */
    int rt;                 /* 1: ask for SCHED_FIFO and locked memory (real-time mode only) */
    int display;            /* -1: as the scene says, 0: off, 1: on */
    int port;               /* display port override; -1: the scene's; 0: any free port */
    int status_line;        /* 1: a live status line on `log` (a terminal) */
    int assembly;           /* -1: the scene's, else iso_assembly */
    const char *cl_device;  /* OpenCL device spec or NULL */
    const char *record;     /* record the devices here (overrides the scene), or NULL */
    volatile sig_atomic_t *stop; /* set by a signal handler: stop after this tick */
    FILE *log;              /* notices and the status line; NULL = stderr */
} iso_loop_opts;

void iso_loop_opts_default(iso_loop_opts *o);

/* Tick figures, all in milliseconds except counts. */
typedef struct iso_loop_summary {
    long ticks;
    double stream_s, wall_s;       /* stream time covered; wall time of the run */
    double period_ms;              /* the nominal tick period */
    double tick_median, tick_p99, tick_max;       /* compute: wake to published */
    double latency_median, latency_p99, latency_max; /* deadline (input due) to published */
    long misses;                   /* ticks that finished after the next deadline */
    long skipped;                  /* deadlines skipped to catch up */
    long restarts;                 /* RK4 restarts */
    iso_integrate_stats integ;
    iso_solver_stats solver;
    iso_metrics metrics;           /* final positions against the rest pose */
    uint64_t checksum;             /* FNV-1a of the final positions' bytes */
    double handle_p[ISO_SCENE_MAX_HANDLES][3]; /* final handle poses */
    double handle_R[ISO_SCENE_MAX_HANDLES][9];
    int n_handles;
    long frames_sent;              /* display frames written to a browser */
    long ply_frames, snapshots;
    int rt_active;                 /* 1: SCHED_FIFO held */
    int mem_locked;
    char rt_note[400];             /* why not, "" when it is */
    char act_line[1200];           /* the actuator link's counters, "" without one */
} iso_loop_summary;

/* Builds the loop for scene sc (which must outlive it): solver, stepper,
 * devices, sinks. Errors name the part that failed. */
ISO_NODISCARD int iso_loop_create(const iso_scene *sc, const iso_loop_opts *o, iso_loop **out,
                                  iso_err *err);
void iso_loop_destroy(iso_loop *l); /* closes the recording whole; NULL is a no-op */

/* Runs until the stream or duration ends, max_ticks, or *stop. Returns
 * ISO_OK, or the error that stopped it (the mesh stays at its last good
 * tick). */
ISO_NODISCARD int iso_loop_run(iso_loop *l, iso_err *err);

/* Brings the sinks to rest: closes the recording, sends the actuators to
 * their safe state. Safe to call twice; destroy calls it. */
ISO_NODISCARD int iso_loop_shutdown(iso_loop *l, iso_err *err);

/* The figures so far; the metrics and checksum are of the current mesh. */
void iso_loop_get_summary(iso_loop *l, iso_loop_summary *s);
/* The current positions (3*nv) and the mesh. */
const double *iso_loop_positions(const iso_loop *l);
const iso_mesh *iso_loop_mesh(const iso_loop *l);

/* Writes the summary as JSON to path; ISO_EIO naming the path on failure. */
ISO_NODISCARD int iso_loop_write_json(const iso_loop_summary *s, const iso_scene *sc,
                                      const char *path, iso_err *err);
/* Prints the summary for people. */
void iso_loop_print_summary(const iso_loop_summary *s, const iso_scene *sc, FILE *f);

/* ---- statistics (controller/loop_stats.c) --------------------------------- */
/* Per-tick samples kept whole (a 10-minute run at 60 Hz is 36 000 of each). */
typedef struct iso_loop_stats {
    double *tick_ms, *lat_ms;
    long n, cap;
    long misses, skipped;
    double recent[256];            /* the last 256 tick times, for the live view */
    int n_recent, head;
} iso_loop_stats;

void iso_loop__stats_init(iso_loop_stats *s);
void iso_loop__stats_deinit(iso_loop_stats *s);
ISO_NODISCARD int iso_loop__stats_add(iso_loop_stats *s, double tick_ms, double lat_ms,
                                      iso_err *err);
/* q-quantile (0..1, nearest rank) of n values; sorts a copy. NAN for n = 0. */
double iso_loop__quantile(const double *v, long n, double q);
/* median, p99, max of the recent window. */
void iso_loop__stats_recent(const iso_loop_stats *s, double *med, double *p99, double *max);

#endif
