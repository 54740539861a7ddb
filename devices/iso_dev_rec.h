/* devices/iso_dev_rec.h -- recordings (devices/RECORDING.md): the writer
 * that keeps the chunks a hub drains, the reader and the replay source
 * that give them back. Chunks and the sources' descriptions are the
 * base's (iso_dev.h); the replay source is a source (iso_dev_source.h). */
#ifndef ISO_DEV_REC_H
#define ISO_DEV_REC_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev.h"
#include "iso_dev_source.h"
#include "iso_err.h"

/* ====================================================================== */
/* Recordings (devices/RECORDING.md)                                       */
/* ====================================================================== */

/* Written: 2 (an END record closes every whole recording; SKIP records).
 * Read: 1 and 2. */
#define ISO_DEV_REC_VERSION 2u
/* A recording keeps at most this many bytes per second of stream time of a
 * source's chunks that decode to nothing; beyond it they become SKIP
 * records (RECORDING.md, "The noise cap"). A 115200-baud line's whole
 * stream (11.5 kB/s) fits under it. */
#define ISO_DEV_REC_NOISE_CAP 16384u

/* The writer. The caller's thread (the loop's tick) only encodes records
 * into a queue of ISO_DEV_REC_QUEUE_BYTES made at open; a thread of the
 * writer's own writes them, a tick at a time: records become the thread's
 * at iso_dev_rec_tick, so the file always ends at a TICK record. The
 * calls below make no system call and take no lock after open: the tick
 * never waits on the disk. The thread writes within a few milliseconds of
 * each tick, so a kill -9 loses the ticks still queued, no more.
 *
 * The recording is never silently incomplete. When the queue cannot take a
 * record (the disk or a FIFO's reader does not keep up) the recording is
 * cut at the last whole tick: the tick in progress is dropped, later
 * writes are taken and ignored (ISO_OK), the thread writes what came
 * before and the END record. When a write fails (a full disk) the thread
 * stops, cuts a regular file back to the last whole tick it wrote and adds
 * the END record if the disk takes it. Either way the recording replays to
 * where it ends, and iso_dev_rec_writer_ended says so, once; the caller
 * goes on.
 *
 * open: a FIFO with no reader is refused at once (opening it would wait for
 * one); one with a reader is written through; anything else is created or
 * truncated. It allocates the queue and starts the thread. close: what came
 * after the last tick is written too (a replay ends at the last TICK
 * record), then the END record; it waits for the thread, at most
 * ISO_DEV_REC_CLOSE_MS for a FIFO's reader that takes nothing (the
 * recording then ends where the reader stopped, and close says so). */
#define ISO_DEV_REC_QUEUE_BYTES (4u << 20) /* seconds of a noisy line's capped 1 MB/s */
#define ISO_DEV_REC_CLOSE_MS 500           /* within SIGINT's second (docs/realtime.md) */

typedef struct iso_dev_rec_writer {
    struct iso_dev__rec_async *a; /* the queue and its thread; NULL when closed */
    long records;                 /* records taken */
    char path[ISO_DEV_NAME_MAX * 2];
} iso_dev_rec_writer;

ISO_API ISO_NODISCARD int iso_dev_rec_writer_open(iso_dev_rec_writer *w, const char *path,
                                                  const iso_dev_info *infos, size_t n,
                                                  int64_t t0_ns, iso_err *err);
ISO_API ISO_NODISCARD int iso_dev_rec_write(iso_dev_rec_writer *w, const iso_dev_chunk *c,
                                            iso_err *err);
/* A TICK record: the tick's records are the thread's to write. */
ISO_API ISO_NODISCARD int iso_dev_rec_tick(iso_dev_rec_writer *w, int64_t t_ns, iso_err *err);
/* 1 once, after the recording was cut, with the sentence that says where
 * it ends (msg, cap bytes); else 0. */
ISO_API int iso_dev_rec_writer_ended(iso_dev_rec_writer *w, char *msg, size_t cap);
ISO_API ISO_NODISCARD int iso_dev_rec_writer_close(iso_dev_rec_writer *w, iso_err *err);

/* Encodes a header or a record into memory (what the writer writes).
 * Return the length, or ISO_EINVAL if it does not fit cap. */
ISO_API int iso_dev_rec_encode_header(uint8_t *dst, size_t cap, const iso_dev_info *infos, size_t n,
                                      int64_t t0_ns);
ISO_API int iso_dev_rec_encode_record(uint8_t *dst, size_t cap, const iso_dev_chunk *c);

typedef struct iso_dev_rec_reader {
    const uint8_t *data; /* the whole recording (owned when loaded from a file) */
    size_t len, pos;
    int owned;
    uint16_t version;
    int64_t t0_ns;
    size_t n_sources;
    iso_dev_info *infos; /* n_sources entries, owned */
    long records;        /* complete records read */
    long damaged;        /* damaged stretches skipped */
    long last_damage_at; /* byte offset of the last one, -1 if none */
    int torn;            /* 1: the recording ends inside a record */
    long end_at;         /* byte offset just past the last complete record */
    char note[320];      /* the last damage or the tear, as a sentence */
    long header_len;     /* where the records start */
    int ended;           /* 1: its END record was read (format 2) */
} iso_dev_rec_reader;

/* Parses the header of a recording in memory (not copied: data must
 * outlive the reader). ISO_EPARSE with the byte offset for a bad header. */
ISO_API ISO_NODISCARD int iso_dev_rec_reader_init(iso_dev_rec_reader *r, const uint8_t *data,
                                                  size_t len, iso_err *err);
ISO_API ISO_NODISCARD int iso_dev_rec_reader_load(iso_dev_rec_reader *r, const char *path,
                                                  iso_err *err);
/* Next complete record: returns 1 and fills *c, or 0 at the end (r->torn
 * and r->note then say where it stopped; r->ended after an END record).
 * Damaged records are counted, described in r->note and skipped;
 * *damaged_now tells the caller (may be NULL). */
ISO_API int iso_dev_rec_next(iso_dev_rec_reader *r, iso_dev_chunk *c, int *damaged_now);

/* Whether the recording was cut off, and the one sentence that says so.
 * Every command that reads a recording (run, replay, inspect, export)
 * prints this sentence, from this function, when it opens the file: a
 * replay that ends at its last TICK record never reads the torn end, so
 * r->torn alone would leave the cut unsaid. Scans the records from the
 * header to the end without moving the reader (r may be mid-replay).
 * A recording is cut off when it ends inside a record, or when it ends
 * without the END record its writer adds on closing (format 2; a writer
 * killed, a disk full, a file cut at a record boundary). Damaged records
 * inside are not a cut (iso_dev_rec_next says where each one is). Returns 1
 * and fills msg (cap bytes, NUL-terminated) with a sentence naming the byte
 * where the file ends, where the complete part ends and how much of it
 * there is, e.g. "the recording is cut off at byte 376, inside a record
 * that starts at byte 371: what came before is used (12 records, 5 ticks,
 * up to byte 371)"; *at (may be NULL) gets the byte offset where the
 * complete part ends. Returns 0, msg "" and *at the file's length when it
 * ends whole. A format-1 recording has no END record: only a cut inside
 * a record shows there. */
ISO_API int iso_dev_rec_reader_cut(const iso_dev_rec_reader *r, char *msg, size_t cap, long *at);
ISO_API void iso_dev_rec_reader_deinit(iso_dev_rec_reader *r);

/* The replay backend: a multiplexed source over a reader (which it does not
 * own and which must outlive it). Hands out records stamped <= until_ns;
 * TICK records are returned too (the player uses them as tick boundaries). */
ISO_API ISO_NODISCARD int iso_dev_replay_open(iso_dev_rec_reader *r, iso_dev_source **out,
                                              iso_err *err);
/* Time of the next record, or INT64_MAX at the end. */
ISO_API int64_t iso_dev_replay_peek(iso_dev_source *s);
/* Time of the next TICK record, or INT64_MAX if none is left. */
ISO_API int64_t iso_dev_replay_next_tick(iso_dev_source *s);
/* The reader under a replay source; NULL for any other source. */
ISO_API const iso_dev_rec_reader *iso_dev_replay_reader(iso_dev_source *s);

/* CRC-32 (IEEE 802.3, reflected 0xEDB88320); check value 0xCBF43926. */
ISO_API uint32_t iso_dev_crc32(const uint8_t *p, size_t len);

#endif
