/* controller/iso_loop.h -- the tick engine: what `isoshape run`, `record`
 * and `replay` run, and what a program or a test drives in-process.
 *
 * One iso_loop owns everything a scene needs while it runs: the solver and
 * the per-tick stepper, the device hub and its mapping (or the replay of a
 * recording), the scripted handle paths, and the sinks (live display, PNG
 * snapshots, PLY frames, actuators over the firmware bridge, a recording).
 * A scene without a mesh (sc->mesh NULL: `record`, or `replay` without a
 * shape) runs the device side alone: the hub, the mapping, the recording
 * and the commanded handle poses.
 *
 * Time. Two clocks:
 *   stream time  where the mesh lives. Tick k of a live or scripted scene
 *                is at exactly stream0 + k / tick_hz (an integer tick
 *                count, rounded to the nanosecond once, never accumulated);
 *                a replay's ticks are its recording's TICK records.
 *   wall time    CLOCK_MONOTONIC: the deadline of stream time t is
 *                wall0 + (t - stream0) / speed, slept to with
 *                clock_nanosleep(TIMER_ABSTIME). `fast` never waits.
 * A scripted path ends on the tick at its end: ceil(T * tick_hz) ticks; a
 * `duration` D runs round(D * tick_hz) ticks.
 *
 * Commanded motion is never lost nor invented. Each handle has a commanded
 * pose: a device-driven handle's is the product of exp(dt ξ) over the
 * device ticks (the twist ξ the mapping gives for each, held over it), a
 * scripted handle's is its path's exact pose at the tick's stream time.
 * Each tick moves the mesh's handles from where they are to their
 * commanded poses. When a tick is late (a long tick, a stalled machine) the
 * next one covers every deadline that has passed: a live scene's tick jumps
 * to the latest grid time already due (one device tick over the whole
 * interval, as the recording then says); a replay in real time takes every
 * TICK record already due as one mesh step, composing their commands one
 * by one, so the handles reach the same poses as a `fast` replay (to
 * round-off). The first tick is never merged.
 *
 * Sub-steps. A mesh step is split into steps_per_tick ABM steps (the
 * scene's integrator.steps_per_tick), times n, where n = 1 for a tick of one
 * period and, for a longer tick, the motion's need: every sub-step turns a
 * handle by at most ISO_LOOP_SUBSTEP_DEG degrees and moves its centroid by
 * at most ISO_LOOP_SUBSTEP_DIAG of the bounding-box diagonal; but never
 * more sub-steps than the periods the tick covers, and with restoration on
 * never more than ISO_LOOP_LATE_SHARE of them: a late tick sheds work, so
 * that while a step costs less than two periods the next tick covers
 * fewer periods and the loop catches up (on the README's demo, sub-steps
 * as many as the periods grew a late tick's 2 sub-steps to 15 in nine
 * ticks). Without restoration every period keeps its sub-step: nothing
 * heals the lag a longer step leaves at a twist's jump. With restoration
 * on, no sub-step is longer than ISO_LOOP_RESTORE_SUBSTEP_TAU of its τ (or
 * a period, should τ be shorter), whatever the share: its relaxation has a
 * time scale, the motion alone has none. n is capped at
 * ISO_LOOP_MAX_SUBSTEPS so a slow mesh cannot spiral; a tick whose motion
 * wanted more sub-steps than it took (the share or the cap) is counted as
 * coarse (its handles still reach their commanded poses). A sub-step far
 * longer than the step before it restarts the stepper's history
 * (ISO_STEPPER_MAX_STEP_RATIO).
 *
 * Stopping. *stop (a signal handler's flag) is read at tick boundaries and
 * during the wait for a deadline: a run always ends on a whole tick, and a
 * live recording's last TICK record is the last tick computed (input that
 * arrives after it is recorded, but a replay ends at that TICK record), so
 * replaying an interrupted session reproduces it bit for bit.
 *
 * Priorities: no thread the tick waits for runs below it. In real time
 * (rt, not fast) the tick's thread runs SCHED_FIFO at ISO_LOOP_RT_PRIORITY,
 * and every thread it can wait for runs at a real-time priority too:
 *   - the factorization worker (solver.worker_lag), which the tick waits
 *     for at each hand-over, just below the tick (ISO_LOOP_RT_PRIORITY - 1);
 *   - the actuators' sender, whose lock the tick's publish takes, above
 *     the tick (+1): it is the tick's watchdog and must run when the tick
 *     does not; its work is a few microseconds every 2 ms;
 *   - an emulated MCU (its native thread, or every thread of QEMU) above
 *     that (+2): the hardware it stands for has a CPU of its own;
 *   - the solver's two-thread teams (the C assembly of a large mesh, the
 *     reduced model's prolongation and fit), which do half of the tick's
 *     work while it waits: at the tick's own priority, since each job
 *     runs at its caller's (solver/team.c); below it, the worker would
 *     keep them off the second core for the rest of a factorization.
 * The tick reads no tty itself: a read that finds the line empty waits for
 * the kernel's buffer work, at normal priority (a flooded pty took the p99
 * tick from 4 to 31-44 ms that way). The device hub's byte streams are
 * read by a thread of the hub's (iso_dev_hub_set_priority) into lock-free
 * rings that the tick only empties; it runs at -2, below the worker, for
 * fresh input under load, though the tick never waits for it. The same
 * kernel step sits in the actuators' sender's reads on a tty link (a real
 * MCU on a UART or USB serial adapter): under heavy load the sender can
 * wait there past the MCU's 100 ms watchdog, which then brakes the MCU
 * (safe, but a stop). The emulated MCUs use stream sockets, not a tty;
 * a loaded machine with real hardware wants a TCP or USB bulk link.
 * The locks the tick shares with threads it does not raise (the live
 * view's frame, the device hub's e-stop lines) inherit priority, so a
 * holder runs at the tick's priority until it lets go. Nothing else is on
 * the tick's path: the display's server, the USB hotplug thread and a
 * one-thread BLAS (the isoshape command's, ISO_SOLVER_BLAS_SIZED) are
 * never waited for. Not covered: a threaded BLAS's pool (set the BLAS to
 * one thread, as iso_solver.h says) and OpenCL assembly on a CPU device
 * (PoCL's threads; `auto` takes the C path on a CPU). With the rule, busy
 * processes on every core cannot delay a tick: it ends when its own work
 * and the worker's factorization are done (the worker keeps its core).
 * Why wait at the hand-over rather than go on with the old factor when the
 * worker is late: the hand-over at a fixed evaluation count is what makes
 * a run bit-identical whatever the timing (a replay, a scripted scene at
 * --fast against real time); a late hand-over would have to be written
 * into every recording and forced in every replay, and a scripted scene
 * would lose it. The waits stay bounded by the worker's own factorization
 * (cactus ~25 ms on a core of its own), which is compute, not inversion.
 * The library changes no thread but its own (the calling thread for the
 * run, its worker, the hub's reader, its sender, its emulation and QEMU
 * child), and only when o->rt asks; the calling thread, the worker and the
 * reader go back to SCHED_OTHER when the run ends, the sender stays up for
 * the safe stop and ends with the loop.
 *
 * Safety. The loop reports progress to the actuators' loop
 * watchdog at every tick, every ABM step, and inside every field
 * evaluation after its assembly, each factorization and each conjugate-
 * gradient iteration (iso_solver_set_progress). The rule: the loop is live
 * while no gap between two progress reports exceeds the scene's
 * sinks.actuators.loop_timeout_ms (default max(250 ms, 5 tick periods));
 * a slow tick made of short pieces is live whatever its length, a tick
 * stuck anywhere (a hook, a hung call, a single piece longer than the
 * bound) is not, and then the sender stops the setpoints and sends SAFE.
 * E-stop inputs (the scene's GPIO e-stop lines, o->estop_probe) are read by
 * the sender thread itself every 2 ms, so they act while a tick is stuck;
 * the mapping's decoded e-stop acts at each device tick as well.
 *
 * Not thread-safe; the display and the actuators have threads of their own
 * behind their APIs. */
#ifndef ISO_LOOP_H
#define ISO_LOOP_H

#include <signal.h>
#include <stdint.h>
#include <stdio.h>

#include "iso_actuators.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_err.h"
#include "iso_metrics.h"
#include "iso_proxy.h"
#include "iso_scene.h"

typedef struct iso_loop iso_loop; /* opaque */

#define ISO_LOOP_SUBSTEP_DEG 1.0    /* rotation per sub-step of a late tick, at most */
#define ISO_LOOP_SUBSTEP_DIAG 0.005 /* centroid travel per sub-step, of the diagonal */
#define ISO_LOOP_MAX_SUBSTEPS 32
#define ISO_LOOP_LATE_SHARE 0.5 /* a late tick's sub-steps, of the periods it covers, at most */
#define ISO_LOOP_RESTORE_SUBSTEP_TAU                                                               \
    1.0 /* with restoration on: a sub-step's length, in τ, at most */
/* The tick thread's SCHED_FIFO priority in real time (see "Priorities"). */
#define ISO_LOOP_RT_PRIORITY 20

/* What a tick did, for iso_loop_opts.on_tick. */
typedef struct iso_loop_tick_info {
    long tick;    /* computed ticks so far, this one included */
    double t_s;   /* its stream time, seconds from the start */
    double dt_s;  /* the stream time it covered */
    int merged;   /* device ticks (replayed TICK records) it covered: 1 on time */
    int substeps; /* ABM steps it took */
    int restart;  /* 1: the Adams history was restarted */
} iso_loop_tick_info;

typedef struct iso_loop_opts {
    int fast;          /* 1: no waiting, as fast as possible on stream time */
    double speed;      /* wall pacing: stream seconds per wall second (1) */
    double duration_s; /* stop after this much stream time; 0: when the stream ends */
    long max_ticks;    /* stop after this many ticks; 0: no limit */
    /* 1: ask for SCHED_FIFO and locked memory (real-time mode only): the
     * calling thread's policy and the loop's own threads' ("Priorities"
     * above), and mlockall of all the process holds. mlockall is
     * process-wide, so the default is 0 and a program asks for them (the
     * isoshape command's run does). */
    int rt;
    int display;           /* -1: as the scene says, 0: off, 1: on */
    int port;              /* display port override; -1: the scene's; 0: any free port */
    int status_line;       /* 1: a live status line on `log` (a terminal) */
    int assembly;          /* -1: the scene's, else iso_assembly */
    const char *cl_device; /* OpenCL device spec or NULL */
    /* The solver's thread settings: the program's, not the scene's (a scene
     * file has no say over process-wide settings). Default: the library's
     * (iso_solver_opts_default), which change nothing process-wide. */
    iso_solver_threads threads;
    const char *record;          /* record the devices here (overrides the scene), or NULL */
    volatile sig_atomic_t *stop; /* set by a signal handler: stop after this tick */
    FILE *log;                   /* notices and the status line; NULL = stderr */
    const char *cmd;             /* the command's name in notices ("run") */
    /* Optional hooks, called on the loop's thread (NULL: none). on_tick
     * after each tick is published; on_command for every device tick
     * (every TICK record of a replay), with the mapping's command. */
    void (*on_tick)(void *ctx, const iso_loop_tick_info *t);
    void (*on_command)(void *ctx, const iso_dev_tick *cmd, double dt_s);
    void *hook_ctx;
    /* An e-stop input of the embedding program (a hardware line, a button
     * of its own), read by the actuators' sender thread every 2 ms whatever
     * the tick is doing: nonzero = pressed. NULL: none. It must be quick and
     * thread-safe. The scene's own e-stop inputs (a GPIO e-stop line) are
     * read the same way without it (iso_dev_hub_estop_probe), and the
     * mapping's decoded e-stop acts at each device tick as well. */
    int (*estop_probe)(void *ctx);
    void *estop_ctx;
    /* File outputs of the command line, beside the scene's (NULL: none),
     * written by the sinks' writer thread, never on the tick (loop_writer.c
     * says how a disk slower than the loop is met: frames dropped and
     * counted). pc2: a PC2 point cache of every tick (sinks/iso_pc2.h), with
     * the rest mesh beside it as <name>.rest.ply; mcap: an MCAP file of the
     * session's Foxglove channels (sinks/iso_foxglove.h). Both are written
     * under a temporary name and renamed when the loop shuts down. */
    const char *pc2;
    const char *mcap;
    int mcap_compression; /* iso_mcap_compression (sinks/iso_mcap.h): 0, the default, is zstd */
} iso_loop_opts;

ISO_API void iso_loop_opts_default(iso_loop_opts *o);

/* Tick figures, all in milliseconds except counts. */
typedef struct iso_loop_summary {
    long ticks;
    double stream_s, wall_s;                /* stream time covered; wall time of the run */
    double period_ms;                       /* the nominal tick period */
    double tick_median, tick_p99, tick_max; /* compute: wake to published */
    double latency_median, latency_p90, latency_p99, latency_max; /* deadline (input due) to
                                                                     published */
    long misses;                /* ticks that started after a later deadline had passed */
    long skipped;               /* deadlines a late tick covered beyond its own: deadlines
                                   that passed without a tick of their own */
    double gap_max_ms;          /* the longest wall time from one tick's start to the
                                   next's: whatever held the loop (a stopped process, a
                                   starved core, a blocked call) shows here, even when
                                   no tick itself was long */
    long restarts;              /* restarts of the Adams history */
    long device_ticks;          /* mapping ticks (TICK records written or replayed) */
    long substeps;              /* ABM steps beyond one a tick */
    long coarse;                /* late ticks that took fewer sub-steps than their
                                   motion wanted (the late share or the cap) */
    uint64_t commands_checksum; /* FNV-1a of every device tick's command */
    iso_integrate_stats integ;
    iso_solver_stats solver; /* of the proxy's system when there is one */
    int proxy_vertices;      /* the reduced model's proxy (solver.proxy); 0: none */
    double proxy_build_s;    /* seconds it took to build */
    iso_proxy_stats proxy;   /* what following it cost (zero without one) */
    iso_metrics metrics;     /* final positions against the rest pose */
    uint64_t checksum;       /* FNV-1a of the final positions' bytes (0 without a mesh) */
    double handle_p[ISO_SCENE_MAX_HANDLES][3]; /* final handle centroids (without a mesh:
                                                  the commanded poses' translations) */
    double handle_R[ISO_SCENE_MAX_HANDLES][9];
    int n_handles;
    long frames_sent; /* display frames written to a browser */
    /* The page's commands, as the view's server took them (a view device) */
    int view_device; /* 1: the scene has one and the view is up */
    unsigned view_accepted, view_refused, view_malformed, view_dropped, view_grants, view_stops;
    long ply_frames, snapshots;
    long pc2_frames;     /* PC2 cache frames written (dropped ticks' repeats included) */
    long mcap_messages;  /* MCAP messages written */
    long frames_dropped; /* ticks the file writer could not take (the disk behind) */
    /* The tick's own cost of the file outputs: filling the frame (unless
     * the live view filled it already) and copying it into the writer's
     * queue, per tick (0 without file outputs). The encoding, compression
     * and writes are the writer thread's. */
    double handoff_ms_mean, handoff_ms_max;
    int rt_active; /* 1: SCHED_FIFO held */
    int mem_locked;
    char rt_note[400];   /* why not, "" when it is */
    char act_line[1700]; /* the actuator link's counters, "" without one */
    int has_act;         /* 1: the scene has actuators, whose counters are in act */
    iso_act_stats act;   /* (iso_actuators_stats; kept when they close) */
    int n_devices;       /* the hub's sources (a replay: its recorded ones) */
    char device_desc[ISO_DEV_MAX_SOURCES][192];       /* iso_dev_hub_describe */
    iso_dev_source_stats device[ISO_DEV_MAX_SOURCES]; /* events, bad frames by reason, gone,
                                                         back, stale */
} iso_loop_summary;

/* Builds the loop for scene sc (which must outlive it): solver, stepper,
 * devices, sinks. Errors name the part that failed. */
ISO_API ISO_NODISCARD int iso_loop_create(const iso_scene *sc, const iso_loop_opts *o,
                                          iso_loop **out, iso_err *err);
ISO_API void iso_loop_destroy(iso_loop *l); /* closes the recording whole; NULL is a no-op */

/* Runs until the stream or duration ends, max_ticks, or *stop. Returns
 * ISO_OK, or the error that stopped it (the mesh stays at its last good
 * tick). */
ISO_API ISO_NODISCARD int iso_loop_run(iso_loop *l, iso_err *err);

/* Brings the sinks to rest: closes the recording, sends the actuators to
 * their safe state. Safe to call twice; destroy calls it. */
ISO_API ISO_NODISCARD int iso_loop_shutdown(iso_loop *l, iso_err *err);

/* The figures so far; the metrics and checksum are of the current mesh. */
ISO_API void iso_loop_get_summary(iso_loop *l, iso_loop_summary *s);
/* The current positions (3*nv) and the mesh. */
ISO_API const double *iso_loop_positions(const iso_loop *l);
ISO_API const iso_mesh *iso_loop_mesh(const iso_loop *l);

/* The run is over: the live view, if there is one, keeps serving its last
 * frame with `text` (the summary, or NULL) until iso_loop_destroy(), and
 * takes no commands. Writes its URL into url (cap bytes; "" without a
 * view). Returns 1 when there is a view, 0 when not. */
ISO_API int iso_loop_view_end(iso_loop *l, const char *text, char *url, size_t cap);

/* The live view's URL (with the command token when one is needed) into
 * url; returns 1, or 0 and "" without a view. */
ISO_API int iso_loop_view_url(const iso_loop *l, char *url, size_t cap);

/* Writes the summary as JSON to path; ISO_EIO naming the path on failure. */
ISO_API ISO_NODISCARD int iso_loop_write_json(const iso_loop_summary *s, const iso_scene *sc,
                                              const char *path, iso_err *err);
/* Says one line on the loop's log (opts.log), "isoshape <cmd>: " before
 * it, the way the loop says its own notices: through a bounded queue and a
 * thread that writes it, so it never blocks whatever the log does (a pipe
 * nobody reads, a terminal stopped with Ctrl-S), from any thread, without
 * allocating. A line repeated within two seconds is counted, not written
 * again; lines that find the queue full are dropped and counted, and the
 * count is said once the log takes lines again. What is queued is written
 * by iso_loop_destroy(), which waits at most 300 ms for a log that takes
 * nothing. */
ISO_API void iso_loop_say(iso_loop *l, const char *fmt, ...) ISO_PRINTF(2, 3);
/* Prints the summary for people. */
ISO_API void iso_loop_print_summary(const iso_loop_summary *s, const iso_scene *sc, FILE *f);

/* Handle h's commanded pose (rest to current): where its device commands
 * or its scripted path have put it; the mesh's handle reaches it at the end
 * of each tick. NULL for h out of range. */
ISO_API const iso_pose *iso_loop_commanded_pose(const iso_loop *l, int h);
/* The device hub (NULL without devices) and, for a replay, its recording's
 * reader (records, damage, tear); NULL otherwise. Read-only. */
ISO_API const iso_dev_hub *iso_loop_hub(const iso_loop *l);
/* The actuator sink (NULL without one), for a status display or a safety
 * monitor on another thread: its stats, state and link state are safe to
 * read from any thread (iso_actuators.h). */
ISO_API struct iso_actuators *iso_loop_actuators(const iso_loop *l);
ISO_API const iso_dev_rec_reader *iso_loop_replay_reader(const iso_loop *l);

#endif
