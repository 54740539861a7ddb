/* actuators/iso_actuators.h -- the actuator sink: chosen mesh points, one axis
 * each, streamed as setpoints to the actuator microcontroller over the
 * firmware bridge (iso_fb_host.h), or to an emulated one.
 *
 * Each channel follows a vertex or the centroid of a region (the fixed
 * region, or handle k as labelled by an iso_regions) along x, y or z. Per
 * tick the value in scene units is clamped to the channel's [min, max],
 * multiplied by `scale` (scene units to actuator milli-units), rounded and
 * clamped to int16; every channel that needed either clamp counts one clamp
 * for that tick. Channel c of the spec is entry c of the SETPOINTS frame.
 *
 * The MCU accepts SETPOINTS only with n equal to its own channel count. Its
 * HELLO answer tells that count: when the spec drives fewer channels, the
 * others are sent at the MCU's safe position for them (with a one-line
 * notice); when the spec names a channel the MCU does not have, nothing is
 * sent and iso_actuators_publish() reports it, so the MCU's link watchdog
 * keeps it safe.
 *
 * Stopping: iso_actuators_safe_stop() stops sending SETPOINTS, sends SAFE
 * to an MCU that obeys it (firmware >= 1.1, HELLO flag CAN_SAFE; it brakes
 * at once and answers FAULT(requested)), and listens until the MCU reports
 * its safe state (that FAULT, FAULT(watchdog), or a HEARTBEAT in the safe
 * or idle state). An MCU without SAFE gets there by its link watchdog, 100
 * ms + one frame after the last setpoints (PROTOCOL.md).
 *
 * Emulated firmware (emu_firmware.c): the real firmware ELF in
 * `qemu-system-arm -M mps2-an385` with its UART0 on a loopback TCP
 * connection, or, where QEMU or the ELF is absent, the same iso_fb_mcu.c
 * logic in a thread of this process on a socket pair, clocked from
 * CLOCK_MONOTONIC, with the firmware's channel configuration. Either way the
 * result is an iso_link whose close also ends the emulation (kills and reaps
 * QEMU, or joins the thread).
 *
 * Timing: with a link, a sender thread of the sink owns the host and the
 * link and sends SETPOINTS at 100 Hz on absolute CLOCK_MONOTONIC deadlines,
 * always the latest published values, reading the replies in between
 * (before the first publish it re-sends HELLO every 40 ms instead, which
 * keeps the MCU armed at its current positions). So
 * the MCU's 100 ms link watchdog holds however slow the loop's ticks are (a
 * 40k-vertex tick takes longer than 100 ms), and publish never touches I/O.
 *
 * Safety. The sender streams only while three things hold; when
 * one fails it stops sending SETPOINTS and sends SAFE (PROTOCOL.md step 5):
 * the MCU brakes to its safe state at once, one frame after the sender saw
 * the cause. An MCU without SAFE (firmware 1.0) brakes by its own link
 * watchdog, 100 ms (+ one 1 ms MCU tick) after the last SETPOINTS it got.
 * Either way the sink says so in one notice line. The sender looks at the
 * three every 2 ms, between its 10 ms SETPOINTS periods too:
 *  - the loop makes progress: once the loop has called iso_actuators_alive()
 *    (the loop watchdog is armed by that first call; a loop that never
 *    calls it is not guarded), no SETPOINTS go out later than
 *    loop_timeout_ms - 5 ms after the last alive() or publish(), so the MCU
 *    is safe within loop_timeout_ms + 2 ms + one frame of the loop's last
 *    progress (+ 100 ms without SAFE). A slow tick is live as long as it
 *    calls alive() as it goes;
 *  - no e-stop: iso_actuators_estop(a, 1) or the safety opts' estop_probe,
 *    which the sender itself calls every 2 ms, so a stuck loop does not
 *    delay it. From the edge to the brake: at most 2 ms + the probe + one
 *    frame (~2 ms at 115200 baud) + one 1 ms MCU tick (measured: see
 *    tests/test_actuators.c; the goal is 20 ms). Without SAFE, ~102 ms;
 *  - the link is up (see "Loss" below).
 * The loop watchdog's bound and the e-stop probe are iso_act_safety_opts
 * (iso_actuators_create).
 * A stalled process: the sender also watches its own clock. When two of its
 * 2 ms looks lie further apart than the loop bound (loop_timeout_ms; 250 ms
 * without a loop watchdog), the whole process did not run (SIGSTOP, a
 * suspended machine, a starved thread): the MCU's own watchdog braked it
 * meanwhile, and the loop's progress report may look fresh before the
 * sender looks. That counts as a loop stall (loop_stalls), is said, sends
 * SAFE, and holds until a tick computed after the gap.
 * Re-arming: when a hold ends (e-stop released, loop stall over, gap),
 * setpoints resume with a tick that began after its end, never with values
 * from before it. The sink sees publishes, not tick starts; publishes come
 * from one thread, each tick after the last publish, so it takes the second
 * publish() after the end (the first may be the tick that was in progress
 * when the hold began): the sink sends HELLO (the MCU arms holding where it
 * stands, after a brake its safe positions; PROTOCOL.md step 2) and then
 * streams that tick.
 *
 * Loss. A transport error, or no valid frame for link_timeout_ms, is a lost
 * link: one notice at once, then the sink reopens the link every 50 ms (an
 * emulated link relaunches QEMU, or restarts the native MCU thread, when it
 * died) and shakes hands again; another notice when it is armed again.
 * While a hold stands (e-stop, loop stall, stop) a lost link is not
 * reopened: a reopen ends in HELLO, which would arm the MCU. An
 * MCU silent for 500 ms (no heartbeat) gets a notice before it counts as
 * lost. Every time the MCU reports its safe state after streaming stopped
 * (FAULT, a heartbeat that is not armed, HELLO(BOOT) after a restart), the
 * sink counts a confirmation and says how long it took.
 *
 * Link state for a status line: iso_actuators_state() and
 * iso_actuators_link_state(), lock-free, any thread.
 *
 * actuators/ does not depend on config/: the controller converts a scene's
 * iso_scene_actuators into the structs below. Publish, poll and safe_stop
 * from one thread (the real-time loop); stats, format_stats, mcu_hello,
 * alive, estop, state and link_state from any (the last four lock-free).
 * Names: functions are iso_actuators_* (the emulator's iso_actuators_emu_*),
 * types iso_act_* and constants ISO_ACT_*. */
#ifndef ISO_ACTUATORS_H
#define ISO_ACTUATORS_H

#include <stddef.h>
#include <stdint.h>

#include "iso_err.h"
#include "iso_fb.h"
#include "iso_fb_mcu.h"
#include "iso_link.h"
#include "iso_regions.h"

/* A SETPOINTS frame carries at most this many channels. */
#define ISO_ACT_MAX_CHANNELS ((int)ISO_FB_MAX_CHANNELS)
#define ISO_ACT_PATH_MAX 4096

/* ---- channels ------------------------------------------------------------ */
#define ISO_ACT_REGION_NONE (-2)  /* the channel follows `vertex` */
#define ISO_ACT_REGION_FIXED (-1) /* the centroid of the fixed vertices */

typedef struct iso_act_channel {
    int channel;     /* SETPOINTS index, 0..ISO_ACT_MAX_CHANNELS-1, each once */
    int vertex;      /* a vertex index, or -1 when `region` is set */
    int region;      /* ISO_ACT_REGION_FIXED, a handle index >= 0, or ISO_ACT_REGION_NONE */
    int axis;        /* 0 x, 1 y, 2 z */
    double min, max; /* limits in scene units, min < max */
    double scale;    /* scene units -> actuator milli-units, finite and != 0 */
} iso_act_channel;

/* ---- the link ------------------------------------------------------------ */
typedef enum iso_act_link_kind {
    ISO_ACT_LINK_NONE = 0, /* compute only: publish computes, sends nothing */
    ISO_ACT_LINK_TTY = 1,  /* path, baud */
    ISO_ACT_LINK_TCP = 2,  /* host, port; connects within 5 ms, so a reopen fits a sender period */
    ISO_ACT_LINK_SERIAL = 3,   /* path (libserialport name), baud */
    ISO_ACT_LINK_EMULATED = 4, /* emulation: ISO_ACT_EMU_* */
    ISO_ACT_LINK_USB = 5       /* vid, pid: bulk endpoints through libusb (iso_link_usb_open) */
} iso_act_link_kind;

typedef enum iso_act_emu_mode {
    ISO_ACT_EMU_AUTO = 0,  /* QEMU when qemu-system-arm and the ELF are found, else native */
    ISO_ACT_EMU_QEMU = 1,  /* QEMU or an error saying what is missing */
    ISO_ACT_EMU_NATIVE = 2 /* iso_fb_mcu.c in a thread on a socket pair */
} iso_act_emu_mode;
/* "auto", "qemu", "native", indexed by iso_act_emu_mode (iso_names.h) */
ISO_API extern const char *const iso_act_emu_names[];

typedef struct iso_act_link_spec {
    int kind;                    /* iso_act_link_kind */
    char path[ISO_ACT_PATH_MAX]; /* TTY device or serial port name */
    char host[256];              /* TCP */
    int port;                    /* TCP */
    int baud;                    /* TTY, SERIAL; 0 = 115200 */
    int emulation;               /* EMULATED: iso_act_emu_mode */
    uint16_t vid, pid;           /* USB */
} iso_act_link_spec;

/* Called with one line (no newline) for things the user should know: which
 * emulation runs and why, a channel-count or limit disagreement with the
 * MCU, and every safety event (loop stall, e-stop, link lost, back, MCU
 * silent, safe state confirmed). Called from the creating thread during
 * create and from the sink's sender thread after that, once per event,
 * never with the sink's lock held: it must be thread-safe and must not
 * block (the sender is the loop's watchdog: no write to a descriptor, no
 * stdio lock; hand the line to a queue). NULL in the options writes the
 * line to stderr from a thread of the sink's own, through a bounded queue
 * that drops (and counts) what a stderr nobody reads cannot take. */
typedef void (*iso_act_notice_fn)(void *ctx, const char *line);

/* Reads an e-stop line: returns nonzero while the e-stop is pressed. Called
 * by the sender thread every 2 ms, between its setpoint periods too, and
 * independently of the loop, so it must be quick and thread-safe (e.g. a
 * GPIO read or an atomic load). */
typedef int (*iso_act_estop_fn)(void *ctx);

typedef struct iso_act_opts {
    int link_timeout_ms;      /* no valid frame this long -> link lost; 0 = 1000 (3000 emulated) */
    iso_act_notice_fn notice; /* NULL = stderr, through a queue */
    void *notice_ctx;
} iso_act_opts;

/* The safety options of iso_actuators_create. A struct of
 * its own, not fields added to iso_act_opts: callers initialise that one
 * positionally, which -Wextra -Werror would turn into a build break. Zero
 * means the default everywhere; NULL is all defaults. */
typedef struct iso_act_safety_opts {
    int tick_period_ms;           /* the loop's nominal tick period; 0 = not given */
    int loop_timeout_ms;          /* no alive()/publish() this long -> stop streaming;
                                   * 0 = max(250, 5 * tick_period_ms); < 0 = no loop watchdog;
                                   * 1..9 is ISO_EINVAL (below the sender's 10 ms period) */
    iso_act_estop_fn estop_probe; /* NULL = only iso_actuators_estop() */
    void *estop_ctx;
} iso_act_safety_opts;

/* ---- state ------------------------------------------------------------ */
typedef enum iso_act_state {
    ISO_ACT_STATE_OFF = 0,         /* no link (ISO_ACT_LINK_NONE) */
    ISO_ACT_STATE_CONNECTING = 1,  /* first handshake pending */
    ISO_ACT_STATE_ARMED = 2,       /* streaming (or keeping the MCU armed before the first tick) */
    ISO_ACT_STATE_SILENT = 3,      /* streaming, but nothing heard from the MCU for 500 ms */
    ISO_ACT_STATE_STOPPING = 4,    /* setpoints withheld (see holds); MCU not yet reported safe */
    ISO_ACT_STATE_SAFE = 5,        /* setpoints withheld and the MCU reported its safe state */
    ISO_ACT_STATE_LOST = 6,        /* link lost; reopening / restarting the emulation */
    ISO_ACT_STATE_RECONNECTING = 7 /* link back, handshaking again (after a loss or a FAULT) */
} iso_act_state;

/* Why setpoints are withheld (bits of iso_actuators_state()'s *holds). */
enum {
    ISO_ACT_HOLD_ESTOP = 1u, /* e-stop pressed (call or probe) */
    ISO_ACT_HOLD_LOOP = 2u,  /* the loop watchdog tripped */
    ISO_ACT_HOLD_STOP = 4u,  /* iso_actuators_safe_stop() */
    ISO_ACT_HOLD_TICK = 8u   /* a hold ended: waiting for a tick begun after it to re-arm */
};

/* ---- counters ------------------------------------------------------------ */
typedef struct iso_act_stats {
    uint64_t ticks;           /* publish calls that computed values */
    uint64_t setpoints_sent;  /* SETPOINTS frames that went out */
    uint64_t acks;            /* SETPOINTS ACKs received */
    uint64_t echo_mismatches; /* ACKs whose tick or values differ from their frame's */
    uint64_t echo_unknown;    /* ACKs for a frame too old to check (or never sent) */
    uint64_t clamps;          /* channel-ticks that were clamped, all channels */
    uint64_t clamps_ch[ISO_ACT_MAX_CHANNELS]; /* by channel */
    uint32_t link_losses, faults, naks;
    uint32_t handshakes; /* HELLO answers, the keep-armed ones before the first publish too */
    uint32_t last_fault_reason;    /* ISO_FB_FAULT_*, 0 before any */
    uint32_t last_fault_detail_ms; /* WATCHDOG: last setpoints to safe, MCU clock */
    /* SETPOINTS to its ACK: from before the write to the ACK's handling on
     * the sender thread, which reads replies as they arrive. */
    uint32_t rtt_count;
    double rtt_avg_ms, rtt_min_ms, rtt_max_ms, rtt_last_ms;
    double publish_max_ms;                 /* the longest publish call */
    uint64_t publish_over_1ms;             /* publish calls that took longer than 1 ms */
    int mcu_channels;                      /* from the MCU's last HELLO answer; 0 before */
    int mcu_state;                         /* last HEARTBEAT's ISO_FB_STATE_*, -1 before any */
    uint32_t mcu_uptime_ms;                /* last HEARTBEAT's */
    int16_t mcu_pos[ISO_ACT_MAX_CHANNELS]; /* last HEARTBEAT's positions */
    uint32_t heartbeats;
    /* ---- safety: link recovery, holds and the MCU's safe-state reports ---- */
    uint32_t reopens;       /* the link reopened after a loss (the host's count) */
    uint32_t emu_restarts;  /* emulated link: QEMU relaunched / native MCU thread restarted */
    uint32_t loop_stalls;   /* the loop watchdog tripped */
    uint32_t estops;        /* e-stop presses seen by the sender */
    uint32_t silences;      /* the MCU went quiet for 500 ms */
    uint32_t safe_confirms; /* safe-state reports after streaming stopped */
    uint32_t safe_requests; /* SAFE frames sent (e-stop, loop stall, stop; firmware >= 1.1) */
    uint64_t alive_calls;   /* iso_actuators_alive() calls */
    /* From what stopped the streaming (the e-stop call, the loop's last
     * progress, the loss or silence, the stop) to the MCU's report of its
     * safe state, host clock; -1 before any. */
    double last_safe_ms;
    int last_safe_cause; /* ISO_ACT_HOLD_ESTOP/LOOP/STOP, or 0 for a loss or silence */
} iso_act_stats;

typedef struct iso_actuators iso_actuators; /* opaque */

/* Creates the sink for n_ch channels over a mesh of nv vertices whose
 * regions are `regions` (may be NULL when no channel follows a region).
 * The region vertex lists are copied, so regions need not outlive the
 * handle. Then opens the link (for ISO_ACT_LINK_EMULATED: starts the
 * emulation and reports which one through the notice) and sends the first
 * HELLO; it does not wait for the answer.
 * A bad spec is ISO_EINVAL with a sentence naming the channel entry and
 * what is wrong: a channel index used twice or out of range, min >= max, a
 * zero or non-finite scale, an axis outside 0..2, a vertex out of range, a
 * region that does not exist or has no vertex, a safety loop_timeout_ms of
 * 1..9. Link failures are ISO_EIO (ISO_ENOTSUP for a transport this build
 * lacks). safety may be NULL: the loop watchdog at 250 ms once alive() is
 * first called, no e-stop probe.
 * On success stores a new handle in *out (iso_actuators_destroy frees it);
 * on failure leaves *out NULL and fills err. */
ISO_API ISO_NODISCARD int iso_actuators_create(const iso_act_channel *ch, int n_ch, int nv,
                                               const iso_regions *regions,    /* may be NULL */
                                               const iso_act_link_spec *link, /* NULL = NONE */
                                               const iso_act_opts *opts,      /* NULL = defaults */
                                               const iso_act_safety_opts *safety,
                                               iso_actuators **out, iso_err *err);
/* Closes the link (and ends an emulation) without waiting for the MCU: call
 * iso_actuators_safe_stop() first for a clean stop. NULL is a no-op. */
ISO_API void iso_actuators_destroy(iso_actuators *a);

/* Computes the channel values for positions x (3*nv, xyz interleaved) into
 * values[ch] for every configured channel (others are left alone), counting
 * clamps. ISO_ENUMERIC, naming the channel, when a coordinate is not finite.
 * Sends nothing. */
ISO_API ISO_NODISCARD int iso_actuators_compute(iso_actuators *a, const double *x,
                                                int16_t values[ISO_ACT_MAX_CHANNELS], iso_err *err);

/* One control tick: computes the values and hands them to the sender
 * thread, which streams them from its next period on (until a later publish
 * replaces them); never waits for the link. Once iso_actuators_alive() was
 * called, a publish also counts as the loop's progress. Returns 1 if the
 * link is streaming, 0 if not (the link is down, the handshake is pending,
 * or a hold stands: e-stop, loop stall, or a hold just ended, which the
 * second publish after its end clears; the sender recovers by itself), or a negative code:
 * ISO_ENUMERIC for non-finite positions (nothing is handed over), ISO_EINVAL when the MCU
 * lacks a channel the spec drives or after safe_stop. With
 * ISO_ACT_LINK_NONE it only computes (returns 0). */
ISO_API ISO_NODISCARD int iso_actuators_publish(iso_actuators *a, uint32_t tick, const double *x,
                                                iso_err *err);

/* Waits up to timeout_ms for the sender thread to handle incoming frames
 * (ACKs, HEARTBEATs, ...); for tests and tools that watch the link. Returns
 * the frames handled meanwhile, at once (0) while the link is down. */
ISO_API int iso_actuators_poll(iso_actuators *a, int timeout_ms);

/* Stops streaming for good and waits up to timeout_ms for the MCU to report
 * its safe state: FAULT(watchdog), or a HEARTBEAT whose state is safe or
 * idle. Returns ISO_OK when it was seen (*safe_ms, if not NULL, gets the time
 * from the last setpoints sent to its arrival, host clock), or ISO_EIO
 * saying it was not or that the link is down (ISO_EINVAL without a link).
 * Allow at least 150 ms:
 * the watchdog needs 100 ms plus a frame. Later publish calls fail. */
ISO_API ISO_NODISCARD int iso_actuators_safe_stop(iso_actuators *a, int timeout_ms, double *safe_ms,
                                                  iso_err *err);

/* A snapshot of the counters. */
ISO_API void iso_actuators_stats(const iso_actuators *a, iso_act_stats *out);

/* The setpoints of the last publish (by SETPOINTS index; others 0) and
 * its tick, for a recorder of the run; any thread. Returns 1, or 0 before
 * the first publish (values then all 0). */
ISO_API int iso_actuators_setpoints(const iso_actuators *a, int16_t values[ISO_ACT_MAX_CHANNELS],
                                    uint32_t *tick);

/* The MCU's last HELLO answer (channel limits, rates, safe positions).
 * Returns 1 when there is one, else 0. */
ISO_API int iso_actuators_mcu_hello(const iso_actuators *a, iso_fb_hello *out);

/* One line of counters: this sink's (with the safety counts: link losses,
 * reopens, emulation restarts, loop stalls, e-stops, safe states confirmed),
 * then the link's (iso_fb_host_format_stats). Returns snprintf's result. */
ISO_API int iso_actuators_format_stats(const iso_actuators *a, char *buf, size_t cap);

/* ---- safety; all lock-free, any thread, NULL a is a no-op ---- */

/* The loop reports progress: at every tick and from inside long ticks as
 * the solver advances (every iteration, or at least every loop_timeout/2).
 * One clock read and two relaxed atomic stores. The first call arms the
 * loop watchdog; publish() also counts as progress after that. */
ISO_API void iso_actuators_alive(iso_actuators *a);

/* Presses (on != 0) or releases the e-stop. The sender stops streaming at
 * its next cycle; see "Safety" above for the time to the safe state. After
 * a release, streaming resumes with the next publish(). */
ISO_API void iso_actuators_estop(iso_actuators *a, int on);

/* The sink's state (ISO_ACT_STATE_*) and, if holds is not NULL, why
 * setpoints are withheld (ISO_ACT_HOLD_* bits). Updated by the sender every
 * cycle. */
ISO_API int iso_actuators_state(const iso_actuators *a, unsigned *holds);

/* The same as one constant word or two for a status line: "armed",
 * "connecting", "silent", "stopping (e-stop)", "safe (e-stop)",
 * "safe (loop stalled)", "safe (stopped)", "safe (waiting for a tick)",
 * "lost", "reconnecting", "off". Never NULL. */
ISO_API const char *iso_actuators_link_state(const iso_actuators *a);

/* Real-time priorities for the sink's own threads, for a real-time loop
 * (controller/iso_loop.h states the rule): priority > 0 puts the sender
 * thread under SCHED_FIFO at `priority` (give it one above the loop's: it
 * is the loop's watchdog, and must run when the loop's tick does not) and
 * an emulated MCU at priority + 1 (the native MCU thread, or every thread
 * of QEMU, and a restarted or relaunched one: the hardware it stands for
 * has a CPU of its own). 0 puts them back as they were: the sender under
 * SCHED_OTHER, QEMU too, the native MCU thread at the lowest SCHED_FIFO
 * priority it asks for by itself. Only the
 * sink's threads and its QEMU change; the lock the loop's publish shares
 * with the sender inherits priority whatever is set here. ISO_EINVAL for
 * a priority outside 0..max-1, ISO_EIO naming what was not permitted
 * (CAP_SYS_NICE, rtprio). Any thread. */
ISO_API ISO_NODISCARD int iso_actuators_set_priority(iso_actuators *a, int priority, iso_err *err);

/* ---- emulated firmware (emu_firmware.c) ---------------------------------- */
typedef struct iso_act_emu_info {
    int used;       /* ISO_ACT_EMU_QEMU or ISO_ACT_EMU_NATIVE */
    char line[768]; /* which emulation runs and why, one line */
} iso_act_emu_info;

/* Starts an emulated MCU and opens a link to it. AUTO tries QEMU (found as
 * $ISO_FB_QEMU, "" meaning none, then on PATH; the ELF as $ISO_FB_FIRMWARE,
 * then next to the running program (where a build puts it, beside the
 * isoshape command), in its ../share/isoshape/, then where `cmake --install`
 * put it) and falls back to native, saying why in info->line. The returned
 * link owns the emulation: iso_link_close() kills and reaps QEMU or stops
 * and joins the thread.
 * Its reopen is a no-op while the emulation lives (the host's loss recovery
 * then shakes hands again on the same stream); when the emulation died it
 * restarts it: QEMU is relaunched without blocking (each reopen checks
 * whether the new one has connected its UART; 5 s to do so), the native
 * MCU thread is restarted on a fresh socket pair. info may be NULL. The native
 * MCU thread asks for SCHED_FIFO (lowest priority, or the one
 * iso_actuators_set_priority gives it) and goes on without it where that
 * is not permitted. Errors: ISO_ENOTSUP when QEMU is asked for
 * and it or the ELF is missing, ISO_EIO when QEMU or the socket pair fails.
 * Both emulations reach the host over a stream socket, never a tty: a tty
 * read that finds the line empty waits for the kernel's buffer work at
 * normal priority, which busy processes hold up (a real MCU on a UART or
 * a USB serial adapter has that wait; see controller/iso_loop.h). */
ISO_API ISO_NODISCARD int iso_actuators_emu_open(int mode, iso_link **out, iso_act_emu_info *info,
                                                 iso_err *err);

#endif
