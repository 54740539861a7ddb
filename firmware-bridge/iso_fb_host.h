/* firmware-bridge/iso_fb_host.h -- the host's end of the firmware bridge: a
 * link endpoint over any iso_link. It performs the HELLO exchange, streams
 * SETPOINTS every tick, decodes HANDLE_SAMPLE and hands it to a callback
 * (that is how samples reach the device layer), reopens the transport and
 * shakes hands again after a loss, and keeps counters isoshape can print.
 *
 * Non-blocking: the caller drives it with iso_fb_host_step() once per
 * control tick (or iso_fb_host_poll() in between). Not thread-safe. */
#ifndef ISO_FB_HOST_H
#define ISO_FB_HOST_H

#include <stddef.h>
#include <stdint.h>

#include "iso_err.h"
#include "iso_fb.h"
#include "iso_link.h"

/* Called from inside iso_fb_host_poll/step; must not call back into the host. */
typedef struct iso_fb_host_callbacks {
    void (*on_sample)(void *ctx, const iso_fb_sample *s); /* HANDLE_SAMPLE, decoded */
    void (*on_ack)(void *ctx, const iso_fb_ack *a);       /* SETPOINTS echoes */
    void (*on_fault)(void *ctx, const iso_fb_fault *f);   /* MCU went to its safe state */
    void (*on_hello)(void *ctx, const iso_fb_hello *h);   /* any HELLO, asked or not */
    void (*on_heartbeat)(void *ctx, const iso_fb_heartbeat *hb);
    void *ctx;
} iso_fb_host_callbacks;

typedef struct iso_fb_host_opts {
    int hello_retry_ms;   /* resend HELLO while unanswered; default 200 */
    int link_timeout_ms;  /* no valid frame this long -> link lost; default 1000 */
    int reopen_ms;        /* between reopen attempts; default 250 */
    int write_timeout_ms; /* default 100 */
} iso_fb_host_opts;

enum {
    ISO_FB_HOST_DOWN = 0,      /* transport lost; reopening */
    ISO_FB_HOST_HANDSHAKE = 1, /* HELLO sent, waiting for the answer */
    ISO_FB_HOST_STREAMING = 2  /* armed: SETPOINTS flow */
};

typedef struct iso_fb_host_stats {
    uint64_t tx_frames, rx_frames, tx_bytes, rx_bytes;
    /* faults: FAULT reports, each the MCU entering its safe state (a
     * requested SAFE at a run's end counts, so a clean run has one);
     * handshakes: times the link was armed (a HELLO answered), the first
     * and each re-arm after a hold. The summary line words them so. */
    uint32_t acks, naks, faults, samples, hellos, heartbeats;
    uint32_t bad_payloads; /* valid frames whose payload did not unpack */
    uint32_t link_losses, reopens, handshakes;
    uint32_t rtt_count;
    uint64_t rtt_sum_us;
    uint32_t rtt_min_us, rtt_max_us, rtt_last_us;
    iso_fb_counters rx; /* the frame parser's drop counters */
} iso_fb_host_stats;

#define ISO_FB_HOST_RTT_SLOTS 64u
typedef struct iso_fb_host {
    iso_link *link; /* borrowed; the caller closes it after deinit */
    iso_fb_host_opts opts;
    iso_fb_host_callbacks cb;
    iso_fb_parser parser;
    int state;
    uint16_t tx_seq;
    iso_fb_hello device; /* the MCU's last HELLO answer */
    uint64_t last_rx_us, last_hello_us, last_reopen_us;
    uint64_t sent_us[ISO_FB_HOST_RTT_SLOTS]; /* SETPOINTS send time by seq % slots */
    uint16_t sent_seq[ISO_FB_HOST_RTT_SLOTS];
    iso_fb_host_stats stats;
    iso_err last_err; /* why the link last went down */
} iso_fb_host;

/* Sets up h over link (borrowed) and sends the first HELLO. opts and cb may
 * be NULL (defaults, no callbacks). */
ISO_API ISO_NODISCARD int iso_fb_host_init(iso_fb_host *h, iso_link *link,
                                           const iso_fb_host_opts *opts,
                                           const iso_fb_host_callbacks *cb, iso_err *err);
ISO_API void iso_fb_host_deinit(iso_fb_host *h); /* does not close the link */

/* Reads and handles what arrived within timeout_ms. Returns the number of
 * frames handled (>= 0). A lost link is not an error here: the host goes
 * DOWN, remembers why in last_err, and step() brings it back. */
ISO_API int iso_fb_host_poll(iso_fb_host *h, int timeout_ms);

/* One control tick: services reopen/HELLO as needed, sends SETPOINTS(tick,
 * values[n]) when STREAMING, and polls without waiting. Returns 1 if the
 * setpoints went out, 0 if not streaming, or ISO_EINVAL for bad arguments. */
ISO_API int iso_fb_host_step(iso_fb_host *h, uint32_t tick, const int16_t *values, unsigned n);

/* Sends SAFE(cause): an MCU that obeys it (iso_fb_host_can_safe) brakes to
 * its safe state at once and answers FAULT(REQUESTED), which drops the host
 * to HANDSHAKE like any FAULT. ISO_ENOTSUP when the MCU's HELLO did not
 * offer SAFE (firmware 1.0: only its link watchdog brakes it), ISO_EIO when
 * the link is down. */
ISO_API ISO_NODISCARD int iso_fb_host_send_safe(iso_fb_host *h, uint8_t cause, iso_err *err);
/* 1 when the MCU's last HELLO answer offered SAFE (ISO_FB_HELLO_CAN_SAFE). */
ISO_API int iso_fb_host_can_safe(const iso_fb_host *h);

/* Drops to HANDSHAKE so the next step sends HELLO again. */
ISO_API void iso_fb_host_rehello(iso_fb_host *h);

/* One line of counters, e.g. for `isoshape` to print. Returns snprintf's
 * result. The _copy form takes a copy of the counters (a caller whose host
 * lives on another thread). Every part names this pair alike:
 * <module>_format_stats for the object, _copy for a copy of its counters. */
ISO_API int iso_fb_host_format_stats(const iso_fb_host *h, char *buf, size_t cap);
ISO_API int iso_fb_host_format_stats_copy(const iso_fb_host_stats *s, char *buf, size_t cap);

#endif
