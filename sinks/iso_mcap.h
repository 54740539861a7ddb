/* sinks/iso_mcap.h -- an MCAP file writer: the container Foxglove Studio
 * and the robotics tools around it open (the format is MCAP version 0,
 * "\x89MCAP0\r\n"; its specification is public).
 *
 * What it writes:
 *   magic, Header (profile, library)
 *   every Schema and Channel, in the data section, before any message
 *   Chunks of Message records (uncompressed, each with its CRC32), each
 *     followed by one Message Index per channel it holds
 *   Data End, with the CRC32 of every byte before it (magic included)
 *   the summary: the Schemas, the Channels, one Statistics record, one
 *     Chunk Index per chunk; then one Summary Offset per group
 *   Footer, with the CRC32 of the summary through the footer's offsets;
 *   magic.
 * So an indexed reader seeks to any time through the chunk indexes, and a
 * streaming reader gets the schemas and channels before the first message.
 * Messages must come in order of log time (a reader's index assumes it).
 *
 * Like the other outputs, the file is written under a temporary name
 * beside the final one (iso_pc2_temp_path's rule) and renamed when
 * iso_mcap_finish succeeds; a process stopped before leaves the temporary
 * file holding every chunk closed so far (a streaming reader reads it up to
 * there). Not thread-safe: one thread writes a file. */
#ifndef ISO_MCAP_H
#define ISO_MCAP_H

#include <stddef.h>
#include <stdint.h>

#include "iso_err.h"

#define ISO_MCAP_CHUNK_BYTES (4u << 20) /* a chunk is closed past this size */
#define ISO_MCAP_MAX_CHANNELS 64

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

/* Appends a message on channel ch at log_time ns (publish time the same;
 * sequence numbers count per channel). ISO_EINVAL for an unknown channel or
 * a time before the last message's; ISO_EIO when a full chunk cannot be
 * written. */
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
