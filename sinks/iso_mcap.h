/* sinks/iso_mcap.h -- an MCAP file writer: the container Foxglove Studio
 * and the robotics tools around it open (the format is MCAP version 0,
 * "\x89MCAP0\r\n"; its specification is public).
 *
 * What it writes:
 *   magic, Header (profile, library)
 *   every Schema and Channel, in the data section, before any message
 *   Chunks of Message records, compressed with zstd unless the writer is
 *     told otherwise (iso_mcap_set_compression), each with the CRC32 of
 *     its records as they are uncompressed (the spec's uncompressed_crc),
 *     each followed by one Message Index per channel it holds
 *   Data End, with the CRC32 of every byte before it (magic included)
 *   the summary: the Schemas, the Channels, one Statistics record, one
 *     Chunk Index per chunk; then one Summary Offset per group
 *   Footer, with the CRC32 of the summary through the footer's offsets;
 *   magic.
 * So an indexed reader seeks to any time through the chunk indexes, and a
 * streaming reader gets the schemas and channels before the first message.
 * Messages must come in order of log time (a reader's index assumes it).
 *
 * A mesh message repeats most of the one before it (the same indices, the
 * same digits for whatever moved little), which zstd finds: the demo
 * session's export compresses to about a fifth. Foxglove Studio and the
 * mcap tools read zstd chunks. zstd runs on the writer's one thread at the
 * fixed ISO_MCAP_ZSTD_LEVEL, so the same messages give the same bytes with
 * the same libzstd (its output may differ between its versions; what it
 * decompresses to may not).
 *
 * Like the other outputs, the file goes where iso_outfile_plan says (a
 * temporary name beside a regular file, renamed onto it when
 * iso_mcap_finish succeeds; a FIFO or a device written through); a process stopped before leaves
 * the temporary file holding every chunk closed so far (a streaming reader reads it up to there).
 * Not thread-safe: one thread writes a file. */
#ifndef ISO_MCAP_H
#define ISO_MCAP_H

#include <stddef.h>
#include <stdint.h>

#include "iso_err.h"

#define ISO_MCAP_CHUNK_BYTES (4u << 20) /* a chunk is closed past this size */
#define ISO_MCAP_MAX_CHANNELS 64
/* zstd's own default level: on the demo session's mesh messages in 4 MiB
 * chunks, level 1 leaves the file a sixth larger, level 6 makes it 7 %
 * smaller in three times the time. Level 3 took about 1.6 s of one core of
 * the 2-core test VM for the export's 230 MB, so a live run's 60 Hz mesh
 * (35 MB/s of JSON with the benchmark cactus) costs the writer thread about
 * a quarter of a core. */
#define ISO_MCAP_ZSTD_LEVEL 3

/* How chunks are written. Zero is the default, so a zeroed option struct
 * compresses. */
typedef enum iso_mcap_compression {
    ISO_MCAP_ZSTD = 0, /* "zstd" */
    ISO_MCAP_NONE = 1  /* "": chunks as they are, for a reader without zstd */
} iso_mcap_compression;
/* Their names on the command line, "zstd" and "none", by value
 * (iso_names.h); NULL-terminated. */
ISO_API extern const char *const iso_mcap_compression_names[];

typedef struct iso_mcap iso_mcap; /* opaque */

/* Opens an MCAP file to be committed at `path`, and writes its magic and
 * Header (profile may be "", library names the writer). ISO_EIO naming the
 * file, ISO_ENOMEM. */
ISO_API ISO_NODISCARD int iso_mcap_create(const char *path, const char *profile,
                                          const char *library, iso_mcap **out, iso_err *err);

/* Adds a schema (encoding e.g. "jsonschema") and stores its id (1, 2, ...)
 * in *id. Schemas and channels are added before the first message;
 * ISO_EINVAL after it. */
ISO_API ISO_NODISCARD int iso_mcap_add_schema(iso_mcap *m, const char *name, const char *encoding,
                                              const char *data, uint16_t *id, iso_err *err);
/* Adds a channel on a schema (message_encoding e.g. "json"); its id (0, 1,
 * ...) goes into *id. At most ISO_MCAP_MAX_CHANNELS. */
ISO_API ISO_NODISCARD int iso_mcap_add_channel(iso_mcap *m, uint16_t schema, const char *topic,
                                               const char *message_encoding, uint16_t *id,
                                               iso_err *err);

/* Sets how the chunks are written (iso_mcap_compression; ISO_MCAP_ZSTD
 * until told). Before the first message, so that one file is written one
 * way; ISO_EINVAL after it, or for a value that is not one. */
ISO_API ISO_NODISCARD int iso_mcap_set_compression(iso_mcap *m, int compression, iso_err *err);

/* Appends a message on channel ch at log_time ns (publish time the same;
 * sequence numbers count per channel). ISO_EINVAL for an unknown channel or
 * a time before the last message's; ISO_EIO when a full chunk cannot be
 * written or compressed (the message names zstd's error). */
ISO_API ISO_NODISCARD int iso_mcap_write(iso_mcap *m, uint16_t ch, uint64_t log_time,
                                         const void *data, size_t len, iso_err *err);

/* Messages written so far. */
ISO_API uint64_t iso_mcap_messages(const iso_mcap *m);

/* Closes the last chunk, writes the Data End, the summary and the footer,
 * and renames the file to its final path. The handle is freed whatever
 * happens; on failure the temporary file is removed. */
ISO_API ISO_NODISCARD int iso_mcap_finish(iso_mcap *m, iso_err *err);

/* Closes without finishing: the temporary file stays with every chunk
 * written so far. NULL is a no-op. */
ISO_API void iso_mcap_destroy(iso_mcap *m);

#endif
