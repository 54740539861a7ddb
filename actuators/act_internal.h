/* actuators/act_internal.h -- private to actuators/: the sink's state,
 * shared by its API (actuators.c), its sender thread (sender.c) and its
 * safety rules (safety.c), and what the sink asks of its emulated link
 * (emu_firmware.c); not installed. */
#ifndef ISO_ACT_INTERNAL_H
#define ISO_ACT_INTERNAL_H

#include "iso_err.h"
#include "iso_link.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

#include "iso_actuators.h"
#include "iso_fb_host.h"

/* ---- the sink's shared state (actuators.c, sender.c, safety.c) ---- */

#define ECHO_SLOTS 128u  /* sent frames kept for the ACK check, by frame seq */
#define PERIOD_US 10000u /* the sender's SETPOINTS period: 100 Hz (PROTOCOL.md) */
#define REOPEN_MS 50     /* after a loss; an emulation restart never blocks */

/* Lock-free means lock-free: alive() and estop() run inside the loop and
 * from an e-stop handler, which must never wait on the sender. */
_Static_assert(ATOMIC_LLONG_LOCK_FREE == 2, "64-bit atomics are lock-free");
_Static_assert(ATOMIC_INT_LOCK_FREE == 2, "int atomics are lock-free");

typedef struct act_channel {
    iso_act_channel spec;
    int *verts; /* region centroid: its vertices (owned); NULL for a vertex */
    int n_verts;
} act_channel;

/* One SETPOINTS frame as it went out. Keyed by the frame's seq, which the
 * ACK echoes: the tick may repeat (the sender re-sends the latest values
 * when the loop has no new tick), the seq never does within 65536 frames. */
typedef struct echo_slot {
    uint64_t sent_us; /* before the write, so a preempted write still counts */
    uint32_t tick;
    uint16_t seq;
    uint8_t n, used;
    int16_t value[ISO_ACT_MAX_CHANNELS];
} echo_slot;

/* Threads: the loop calls publish; with a link, the sender thread owns the
 * host and the link (host, echo, told_channels are its alone). Everything
 * both touch is under `lock`, held for copies only, never across I/O. */
struct iso_actuators {
    act_channel ch[ISO_ACT_MAX_CHANNELS];
    int n_ch, nv;
    int top; /* highest configured channel + 1 */
    iso_act_notice_fn notice;
    void *notice_ctx;
    struct iso_logq *logq; /* without a notice callback: stderr, through a queue */

    iso_link *link; /* owned */
    iso_fb_host host;
    int host_up;
    int told_channels; /* the count notice went out for this MCU description */
    echo_slot echo[ECHO_SLOTS];

    pthread_t sender;
    int sender_started;
    pthread_mutex_t lock;
    pthread_cond_t cond; /* frames handled, safe state seen, link state changed */
    /* ---- under lock ---- */
    int16_t values[ISO_ACT_MAX_CHANNELS]; /* latest published, by channel */
    uint32_t tick;                        /* and its tick */
    int have_tick;                        /* the loop has published at least once */
    int stopped;                          /* safe_stop: send no more SETPOINTS */
    int quit;                             /* destroy: the sender ends */
    int link_state;                       /* the host's ISO_FB_HOST_*, after the last step */
    int mismatch;                         /* the MCU lacks a configured channel */
    iso_fb_hello hello;                   /* MCU's last answer */
    int have_hello;
    int saw_safe; /* safe_stop watches for these */
    uint64_t safe_us, last_sent_us;
    uint64_t frames;           /* frames the sender handled, for poll */
    iso_fb_host_stats host_st; /* the host's counters after the last step */
    iso_err down;              /* why the link last went down */
    uint64_t last_publish_us;  /* when the latest publish began */
    uint64_t prev_publish_us;  /* and the one before it (the re-arm rule, safety.c) */
    iso_act_stats st;

    /* ---- lock-free, any thread ---- */
    atomic_ullong progress_us; /* the loop's last alive()/publish(); 0: watchdog not armed */
    atomic_ullong alive_calls;
    atomic_int estop_req;   /* iso_actuators_estop() */
    atomic_ullong estop_us; /* when it was pressed */
    atomic_int state;       /* ISO_ACT_STATE_* */
    atomic_uint holds;      /* ISO_ACT_HOLD_* */

    /* ---- the sender thread's alone ---- */
    uint64_t loop_timeout_us; /* 0: no loop watchdog */
    int loop_timeout_ms;
    iso_act_estop_fn estop_probe;
    void *estop_ctx;
    unsigned hold;           /* what holds holds */
    uint64_t fresh_after_us; /* a tick begun after this time re-arms after a hold */
    uint64_t awake_us;       /* the sender's last look at the holds: a gap is a stall */
    int gap_now;             /* a gap was found in this look: send SAFE */
    int prev_host_state, ever_streamed;
    int lost; /* lost and not streaming again yet */
    uint64_t lost_us, lost_told_us;
    uint32_t reopens_seen;
    int silent;
    uint64_t silent_from_us;
    int mcu_safe;   /* the MCU's last word: safe or idle (1), armed (0) */
    int await_safe; /* streaming stopped: the next safe report confirms it */
    uint64_t break_us;
    int break_cause;
    const char *break_what;
};

/* A notice line through the sink's notice callback, or to stderr through
 * the sink's log queue: the sender thread never writes to a descriptor. */
void iso_act__say(const iso_actuators *a, const char *line);

/* safety.c: the rules that stop the setpoints. */
/* Reads the safety options into a (defaults for NULL or zero fields). */
int iso_act__take_safety(iso_actuators *a, const iso_act_safety_opts *so, iso_err *err);
/* Streaming stopped at t0 because of `what` (sender thread). */
void iso_act__begin_break(iso_actuators *a, uint64_t t0, int cause, const char *what);
/* The MCU says it is in its safe state (sender thread). */
void iso_act__note_safe(iso_actuators *a, const char *how);
/* The holds now; a hold that begins sends SAFE at once (sender thread). */
unsigned iso_act__holds_now(iso_actuators *a);
/* 1 when the sender's clock has jumped past the loop bound since its last
 * look (the process was stopped): checked again right before a write, so
 * that a stop between the look and the write sends nothing stale. */
int iso_act__gap_since_look(const iso_actuators *a);

/* sender.c: the thread that owns the host and the link. */
void iso_act__host_callbacks(iso_actuators *a, iso_fb_host_callbacks *cb);
void *iso_act__sender_main(void *arg);

/* emu_find.c: the emulation's qemu-system-arm ($ISO_FB_QEMU, else PATH)
 * and firmware ELF ($ISO_FB_FIRMWARE, else next to the program, its
 * ../share/isoshape/, or where it is installed). Each returns 1 with the
 * path in out, or 0 with where it looked in why. */
int iso_act__find_qemu(char *out, size_t cap, char *why, size_t why_cap);
int iso_act__find_firmware(char *out, size_t cap, char *why, size_t why_cap);

/* 1 when l came from iso_actuators_emu_open(). */
int iso_act__emu_is(const iso_link *l);
/* Times the emulation was relaunched after it died; any thread. */
unsigned iso_act__emu_restarts(const iso_link *l);
/* See iso_actuators_emu_signal(); any thread. */
int iso_act__emu_signal(iso_link *l, int sig, iso_err *err);
/* The emulated MCU's SCHED_FIFO priority (0: back to SCHED_OTHER; native:
 * its thread, QEMU: every thread of the process), kept for a restarted or
 * relaunched one; any thread. */
int iso_act__emu_priority(iso_link *l, int priority, iso_err *err);

#endif
