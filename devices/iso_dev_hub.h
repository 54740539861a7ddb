/* devices/iso_dev_hub.h -- the hub: sources, their decoders, the
 * recording and reconnects, one tick at a time. It ties the objects of the
 * other iso_dev_*.h headers together, and includes those its calls take:
 * sources, decoders and their events, the mapping (a recording's writer
 * it names only: iso_dev_rec.h). */
#ifndef ISO_DEV_HUB_H
#define ISO_DEV_HUB_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev.h"
#include "iso_dev_decode.h"
#include "iso_dev_map.h"
#include "iso_dev_source.h"
#include "iso_err.h"
#include "iso_geom.h"

/* ====================================================================== */
/* The hub: sources + decoders + recording + reconnects                    */
/* ====================================================================== */

typedef struct iso_dev_hub iso_dev_hub;
/* Called to open a source again after it went away; returns ISO_OK and a new
 * source, or an error (tried again every retry interval). It is called on
 * a thread of the hub's own, never in a tick (a device open may take as
 * long as a USB enumeration): the drain that asks takes the answer on a
 * later drain, and closes a gone source's handle there too. */
typedef int (*iso_dev_reopen_fn)(void *ctx, const iso_dev_info *info, iso_dev_source **out,
                                 iso_err *err);
/* One sentence per state change (gone, back, damaged record), no newline. */
typedef void (*iso_dev_notify_fn)(void *ctx, const char *msg);

ISO_API ISO_NODISCARD int iso_dev_hub_create(iso_dev_notify_fn notify, void *notify_ctx,
                                             iso_dev_hub **out, iso_err *err);
ISO_API void iso_dev_hub_destroy(iso_dev_hub *h); /* closes its sources; NULL is a no-op */
/* Adds a source (the hub owns it from now, even on failure). A multiplexed
 * source (replay) brings every source of its recording and must be alone. */
ISO_API ISO_NODISCARD int iso_dev_hub_add(iso_dev_hub *h, iso_dev_source *s,
                                          iso_dev_reopen_fn reopen, void *reopen_ctx, iso_err *err);
ISO_API size_t iso_dev_hub_sources(const iso_dev_hub *h);
/* Byte streams (serial sources with a descriptor: a tty, a TCP bridge,
 * libserialport) are read on a thread of the hub's own, into one lock-free
 * ring per source, so that drain and tick never wait in the kernel (a tty
 * read that finds nothing waits for the kernel's buffer work, which any
 * busy process can hold up). Other sources are read by drain itself. This
 * sets that thread's SCHED_FIFO priority (0: SCHED_OTHER), for a real-time
 * loop that wants its input fresh under load; no-op without a byte stream.
 * ISO_EIO with the reason when not permitted. */
ISO_API ISO_NODISCARD int iso_dev_hub_set_priority(iso_dev_hub *h, int priority, iso_err *err);
/* Waits up to timeout_ms until that thread has read what its byte streams
 * had sent by now, so that a drain after it misses nothing (a recording's
 * last drain, a test), and until no gone source is being reopened (the
 * tick asks for a reopen and takes the answer on a later tick, from a
 * thread of the hub's: iso_dev_hub_drain). Returns 1 when it has, 0 on the
 * timeout. Never in a tick: it waits. */
ISO_API int iso_dev_hub_sync(iso_dev_hub *h, int timeout_ms);
/* The e-stop inputs (sources whose estop_level answers, e.g. a GPIO e-stop
 * line), read now: 1 when any is pressed, or is gone or unreadable (an
 * e-stop circuit that cannot be read is not trusted), else 0. Safe to call
 * from any thread while the hub's own thread drains and reconnects; it
 * takes a lock held only for pointer swaps and these reads, never across
 * device I/O. The signature is iso_act_estop_fn's: the actuators' sender
 * calls it every 2 ms, so an e-stop edge acts while a tick computes. The
 * decoded e-stop (debounced, recorded) still goes through the mapping;
 * this probe only ever stops sooner. */
ISO_API int iso_dev_hub_estop_probe(void *hub);
ISO_API int iso_dev_hub_has_estop(const iso_dev_hub *h); /* any source with an e-stop input */
ISO_API const iso_dev_decoder *iso_dev_hub_decoder(const iso_dev_hub *h, size_t i);

/* What the loop's summary and --stats-json report per source: counted
 * since the source was added, across reconnects. */
typedef struct iso_dev_source_stats {
    iso_dev_counters dec;      /* the decoder's: chunks, reports, short, unknown, bad frames ... */
    iso_dev_frame_drops drops; /* serial: bad frames by reason; zero for other kinds */
    uint32_t events;           /* decoded events handed on to the mapping */
    uint32_t gone, back;       /* times it went away, times it was opened again */
    uint32_t stale;            /* times its twist stream went quiet past its stale time */
    uint8_t present;           /* 1: open now (a replay: as recorded at this point) */
    uint8_t is_stale;          /* 1: its twist counted zero in the last tick */
    uint8_t targeting;         /* a view: 1 when a fresh target drove its handle last tick */
    uint8_t holder;            /* a view: 1 while a viewer is in control */
} iso_dev_source_stats;
/* Fills *out for source i. ISO_EINVAL (and *out zeroed) if i is not a
 * source. The stale counts are kept by iso_dev_hub_tick. */
ISO_API int iso_dev_hub_source_stats(const iso_dev_hub *h, size_t i, iso_dev_source_stats *out);
/* One line for people (the loop's start-up line), no newline: kind, name,
 * then in parentheses what else identifies it, e.g.
 *   hid /dev/hidraw3 (256f:c635 SpaceMouse Compact)
 *   spnav spacenavd (socket /var/run/spnav.sock)
 *   serial /dev/ttyACM0 (115200 8N1)         serial tcp:127.0.0.1:5760
 *   gpio gpiochip0 (debounce 2000 us)        ... (replayed) for a replay.
 * Truncated to cap (NUL-terminated when cap > 0). ISO_EINVAL and "" if i
 * is not a source. */
ISO_API int iso_dev_hub_describe(const iso_dev_hub *h, size_t i, char *buf, size_t cap);
ISO_API void iso_dev_hub_set_retry(iso_dev_hub *h, int64_t retry_ns); /* default 500 ms */
ISO_API void iso_dev_hub_retry_now(iso_dev_hub *h);                   /* hotplug arrival */
/* Records every chunk from now on (header: the current sources). */
ISO_API ISO_NODISCARD int iso_dev_hub_record_start(iso_dev_hub *h, const char *path, iso_err *err);
ISO_API ISO_NODISCARD int iso_dev_hub_record_stop(iso_dev_hub *h, iso_err *err);
typedef struct iso_dev_rec_writer iso_dev_rec_writer; /* iso_dev_rec.h */
/* The same in halves, so that a real-time caller opens and closes the file
 * on another thread: infos gets the current sources (cap entries; returns
 * how many there are), for iso_dev_rec_writer_open there; attach hands the
 * hub a writer opened so (ISO_EINVAL when it records already), and detach
 * takes it back into *w after the SKIP records of noise left out (returns 1,
 * or 0 when it was not recording), for iso_dev_rec_writer_close there.
 * Neither makes a system call or allocates. */
ISO_API size_t iso_dev_hub_infos(const iso_dev_hub *h, iso_dev_info *infos, size_t cap);
ISO_API ISO_NODISCARD int iso_dev_hub_record_attach(iso_dev_hub *h, const iso_dev_rec_writer *w,
                                                    iso_err *err);
ISO_API int iso_dev_hub_record_detach(iso_dev_hub *h, iso_dev_rec_writer *w, iso_err *err);

/* Noise. A device that delivers only bad input (bytes that are no frame,
 * reports of unknown IDs) for ISO_DEV_NOISE_NOTICE_NS of stream time gets
 * one message from the hub, with a hint (a serial line: its baud rate, and
 * whether this is the right device), and one more when good input comes
 * back. Stream time: a replay says it in the same tick. */
#define ISO_DEV_NOISE_NOTICE_NS 2000000000LL
/* A tick drains at most this many bytes from one source; the rest waits
 * for the next tick. It bounds what a flood costs a tick: 16 KiB of noise
 * decoded and recorded, 0.08 ms median and 0.17 ms p99 (tests/tools/
 * noise_bench, SCHED_FIFO on a shared 2-core machine), far above any
 * handle stream (a 115200-baud line brings 192 bytes in a 60 Hz tick; a 3D
 * mouse, ~1 kB/s). The tick never reads a byte stream from the kernel
 * itself (iso_dev_hub_set_priority says why). End to end, so a flood leaves
 * a run's p99 tick within the spread of its quiet runs: a 60 Hz cactus run
 * with its handle on a pty flooded with random bytes at the rate the tick
 * drains, 2.3-3.1 ms against 2.0-3.3 quiet, where a tick that read the tty
 * went to 19-35 ms (noise_bench; docs/performance.md, "Noise on a serial
 * line"). */
#define ISO_DEV_DRAIN_MAX 16384u
/* Once per tick: drains every source up to now_ns, records and decodes what
 * came, handles unplug and replug, and returns the events (at most cap; the
 * rest wait for the next call). Only a recording write error fails. */
ISO_API ISO_NODISCARD int iso_dev_hub_drain(iso_dev_hub *h, int64_t now_ns, iso_dev_event *ev,
                                            size_t cap, size_t *n, iso_err *err);
/* drain + iso_dev_map_tick + a TICK record: what the real-time loop calls.
 * Also says (notify) when a source's twist stream goes stale and when it
 * resumes, and counts it (iso_dev_hub_source_stats): use one map with it. */
ISO_API ISO_NODISCARD int iso_dev_hub_tick(iso_dev_hub *h, iso_dev_map *m, int64_t now_ns,
                                           double dt_s, const iso_pose *poses, iso_dev_tick *out,
                                           iso_err *err);
/* Replay: when the next tick is. The recording's next TICK record if it
 * has one; INT64_MAX after the last TICK record of a recording that has
 * them (records after it are input the recorded loop never ticked); for a
 * recording without TICK records, last + fallback_dt_ns (the first
 * record's time for the first tick), INT64_MAX when every record has been
 * drained. */
ISO_API int64_t iso_dev_hub_next_tick(iso_dev_hub *h, int64_t fallback_dt_ns);
/* Replay: 1 once every record has been drained. */
ISO_API int iso_dev_hub_replay_done(iso_dev_hub *h);

#endif
