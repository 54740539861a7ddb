/* sinks/mcap.c -- an MCAP writer (see iso_mcap.h for the layout). */
#include "iso_mcap.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zstd.h>

#include "iso_bytes.h"
#include "iso_crc32.h"
#include "iso_outfile.h"

enum {
    OP_HEADER = 0x01,
    OP_FOOTER = 0x02,
    OP_SCHEMA = 0x03,
    OP_CHANNEL = 0x04,
    OP_MESSAGE = 0x05,
    OP_CHUNK = 0x06,
    OP_MESSAGE_INDEX = 0x07,
    OP_CHUNK_INDEX = 0x08,
    OP_STATISTICS = 0x0B,
    OP_SUMMARY_OFFSET = 0x0E,
    OP_DATA_END = 0x0F
};

static const unsigned char MAGIC[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

const char *const iso_mcap_compression_names[] = {"zstd", "none", NULL};

/* ---- byte buffers (the writer's thread, never the tick) ----------------- */

typedef iso_bytes buf;

static void put_le(buf *b, uint64_t v, int bytes)
{
    unsigned char *d = iso_bytes_grow(b, (size_t)bytes);
    for (int i = 0; d && i < bytes; i++)
        d[i] = (unsigned char)(v >> (8 * i));
}

static void put_str(buf *b, const char *s)
{
    size_t n = strlen(s);
    put_le(b, n, 4);
    iso_bytes_put(b, s, n);
}

/* Starts a record: its opcode and a length patched by rec_end. */
static size_t rec_begin(buf *b, int op)
{
    put_le(b, (uint64_t)op, 1);
    size_t at = b->n;
    put_le(b, 0, 8);
    return at;
}

static void rec_end(buf *b, size_t at)
{
    if (b->oom)
        return;
    uint64_t len = b->n - at - 8;
    for (int i = 0; i < 8; i++)
        b->p[at + i] = (unsigned char)(len >> (8 * i));
}

/* ---- the writer -------------------------------------------------------- */

typedef struct msg_index { /* one channel's (log time, offset) pairs in the open chunk */
    buf pairs;
} msg_index;

struct iso_mcap {
    FILE *f;
    uint64_t off;        /* bytes written */
    iso_crc32_table crc; /* slicing by eight: the writer checksums every byte twice */
    uint32_t data_crc;   /* running, over every byte so far (until Data End) */
    buf chunk;           /* the open chunk's records */
    int compression;     /* iso_mcap_compression */
    ZSTD_CCtx *zstd;     /* made at the first zstd chunk, kept for the next */
    buf packed;          /* a chunk's records compressed */
    uint64_t chunk_t0, chunk_t1;
    int chunk_msgs;
    msg_index idx[ISO_MCAP_MAX_CHANNELS];
    buf schemas, channels, chunk_indexes; /* summary records, serialized */
    int n_schemas, n_channels, n_chunks;
    uint64_t count[ISO_MCAP_MAX_CHANNELS];
    uint32_t seq[ISO_MCAP_MAX_CHANNELS];
    uint64_t messages, t_first, t_last;
    int err_io;
    const char *codec_err; /* zstd's name for why it failed (static), or NULL */
    /* where it goes (iso_outfile.h): a temporary name, or a FIFO written through */
    iso_outfile out;
};

static uint32_t crc_update(const iso_mcap *m, uint32_t c, const unsigned char *p, size_t n)
{
    return iso_crc32_fast(&m->crc, c, p, n);
}

/* Writes n bytes to the file, counting them into the data section's CRC. */
static void emit(iso_mcap *m, const void *p, size_t n)
{
    if (m->err_io || n == 0)
        return;
    if (fwrite(p, 1, n, m->f) != n) {
        m->err_io = errno ? errno : EIO;
        return;
    }
    m->data_crc = crc_update(m, m->data_crc, p, n);
    m->off += n;
}

static void emit_buf(iso_mcap *m, const buf *b)
{
    emit(m, b->p, b->n);
}

static int io_error(iso_mcap *m, iso_err *err)
{
    if (m->codec_err)
        return iso_err_set(err, ISO_EIO, -1, "MCAP %s: zstd could not compress a chunk: %s",
                           m->out.write, m->codec_err);
    return iso_err_set(err, ISO_EIO, -1, "MCAP %s: %s", m->out.write,
                       m->err_io == ENOMEM ? "out of memory" : strerror(m->err_io));
}

int iso_mcap_create(const char *path, const char *profile, const char *library, iso_mcap **out,
                    iso_err *err)
{
    *out = NULL;
    iso_mcap *m = calloc(1, sizeof *m);
    if (!m)
        return iso_err_set(err, ISO_ENOMEM, -1, "MCAP: out of memory");
    iso_crc32_table_init(&m->crc); /* CRC-32 (IEEE), as the MCAP spec names it */
    int prc = iso_outfile_plan(&m->out, "MCAP", path, ISO_OUTFILE_SEQUENTIAL, err);
    if (prc != ISO_OK) {
        free(m);
        return prc;
    }
    m->f = fopen(m->out.write, "wb");
    if (!m->f) {
        int e = errno;
        iso_outfile_abort(&m->out);
        free(m);
        return iso_err_set(err, ISO_EIO, -1, "MCAP %s: cannot write it: %s", path, strerror(e));
    }
    buf h = {0};
    iso_bytes_put(&h, MAGIC, 8);
    size_t at = rec_begin(&h, OP_HEADER);
    put_str(&h, profile ? profile : "");
    put_str(&h, library ? library : "");
    rec_end(&h, at);
    if (h.oom)
        m->err_io = ENOMEM;
    emit_buf(m, &h);
    free(h.p);
    if (m->err_io) {
        int rc = io_error(m, err);
        iso_mcap_destroy(m);
        return rc;
    }
    *out = m;
    return ISO_OK;
}

int iso_mcap_add_schema(iso_mcap *m, const char *name, const char *encoding, const char *data,
                        uint16_t *id, iso_err *err)
{
    if (m->messages > 0 || m->n_schemas >= 65535)
        return iso_err_set(err, ISO_EINVAL, -1, "MCAP: schema %s added after the first message",
                           name);
    *id = (uint16_t)(m->n_schemas + 1);
    size_t start = m->schemas.n;
    size_t at = rec_begin(&m->schemas, OP_SCHEMA);
    put_le(&m->schemas, *id, 2);
    put_str(&m->schemas, name);
    put_str(&m->schemas, encoding);
    put_str(&m->schemas, data); /* bytes with a u32 length: the same layout */
    rec_end(&m->schemas, at);
    if (m->schemas.oom)
        return iso_err_set(err, ISO_ENOMEM, -1, "MCAP: out of memory");
    emit(m, m->schemas.p + start, m->schemas.n - start);
    m->n_schemas++;
    return m->err_io ? io_error(m, err) : ISO_OK;
}

int iso_mcap_add_channel(iso_mcap *m, uint16_t schema, const char *topic,
                         const char *message_encoding, uint16_t *id, iso_err *err)
{
    if (m->messages > 0 || m->n_channels >= ISO_MCAP_MAX_CHANNELS)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "MCAP: channel %s: after the first message, or more than %d", topic,
                           ISO_MCAP_MAX_CHANNELS);
    *id = (uint16_t)m->n_channels;
    size_t start = m->channels.n;
    size_t at = rec_begin(&m->channels, OP_CHANNEL);
    put_le(&m->channels, *id, 2);
    put_le(&m->channels, schema, 2);
    put_str(&m->channels, topic);
    put_str(&m->channels, message_encoding);
    put_le(&m->channels, 0, 4); /* metadata: an empty map */
    rec_end(&m->channels, at);
    if (m->channels.oom)
        return iso_err_set(err, ISO_ENOMEM, -1, "MCAP: out of memory");
    emit(m, m->channels.p + start, m->channels.n - start);
    m->n_channels++;
    return m->err_io ? io_error(m, err) : ISO_OK;
}

int iso_mcap_set_compression(iso_mcap *m, int compression, iso_err *err)
{
    if (compression != ISO_MCAP_ZSTD && compression != ISO_MCAP_NONE)
        return iso_err_set(err, ISO_EINVAL, -1, "MCAP: no compression %d", compression);
    if (m->messages > 0)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "MCAP: the compression set after the first message");
    m->compression = compression;
    return ISO_OK;
}

/* The open chunk's records as the file holds them: compressed into
 * m->packed, or m->chunk itself. The MCAP name of the compression goes into
 * *name. On a failure err_io (and codec_err) are set, and from then on
 * nothing more is written: the call that closed the chunk says why. */
static const buf *chunk_records(iso_mcap *m, const char **name)
{
    *name = "";
    if (m->compression != ISO_MCAP_ZSTD)
        return &m->chunk;
    if (!m->zstd && !(m->zstd = ZSTD_createCCtx())) {
        m->err_io = m->err_io ? m->err_io : ENOMEM;
        return &m->chunk;
    }
    size_t bound = ZSTD_compressBound(m->chunk.n);
    m->packed.n = 0;
    if (!iso_bytes_grow(&m->packed, bound)) {
        m->err_io = m->err_io ? m->err_io : ENOMEM;
        return &m->chunk;
    }
    /* one call, one thread, a fixed level: the same records give the same
     * frame (ZSTD_compressCCtx resets the context's parameters to the
     * level's each time, whatever the chunk before set) */
    size_t z =
        ZSTD_compressCCtx(m->zstd, m->packed.p, bound, m->chunk.p, m->chunk.n, ISO_MCAP_ZSTD_LEVEL);
    if (ZSTD_isError(z)) {
        m->codec_err = m->codec_err ? m->codec_err : ZSTD_getErrorName(z);
        m->err_io = m->err_io ? m->err_io : EIO;
        return &m->chunk;
    }
    m->packed.n = z;
    *name = "zstd";
    return &m->packed;
}

/* Writes the open chunk, its message indexes, and its chunk index into the
 * summary's buffer. */
static void close_chunk(iso_mcap *m)
{
    if (m->chunk_msgs == 0)
        return;
    uint64_t chunk_start = m->off;
    const char *compression;
    const buf *records = chunk_records(m, &compression);
    buf h = {0};
    size_t at = rec_begin(&h, OP_CHUNK);
    put_le(&h, m->chunk_t0, 8);
    put_le(&h, m->chunk_t1, 8);
    put_le(&h, m->chunk.n, 8); /* uncompressed size */
    /* the spec's uncompressed_crc: of the records before compression, so a
     * reader checks what it decompressed */
    put_le(&h, crc_update(m, 0, m->chunk.p, m->chunk.n), 4);
    put_str(&h, compression);
    put_le(&h, records->n, 8);
    /* the record's length covers the records that follow the header bytes */
    rec_end(&h, at);
    if (!h.oom) {
        uint64_t len = h.n - at - 8 + records->n;
        for (int i = 0; i < 8; i++)
            h.p[at + i] = (unsigned char)(len >> (8 * i));
    }
    emit_buf(m, &h);
    emit_buf(m, records);
    uint64_t chunk_len = m->off - chunk_start;
    buf offsets = {0};
    uint64_t idx_start = m->off;
    for (int c = 0; c < m->n_channels; c++) {
        msg_index *x = &m->idx[c];
        if (x->pairs.n == 0)
            continue;
        put_le(&offsets, (uint64_t)c, 2);
        put_le(&offsets, m->off, 8);
        h.n = 0;
        size_t a2 = rec_begin(&h, OP_MESSAGE_INDEX);
        put_le(&h, (uint64_t)c, 2);
        put_le(&h, x->pairs.n, 4);
        iso_bytes_put(&h, x->pairs.p, x->pairs.n);
        rec_end(&h, a2);
        emit_buf(m, &h);
        x->pairs.n = 0;
    }
    buf *ci = &m->chunk_indexes;
    size_t a3 = rec_begin(ci, OP_CHUNK_INDEX);
    put_le(ci, m->chunk_t0, 8);
    put_le(ci, m->chunk_t1, 8);
    put_le(ci, chunk_start, 8);
    put_le(ci, chunk_len, 8);
    put_le(ci, offsets.n, 4);
    iso_bytes_put(ci, offsets.p, offsets.n);
    put_le(ci, m->off - idx_start, 8);
    put_str(ci, compression);
    put_le(ci, records->n, 8); /* as the file holds them */
    put_le(ci, m->chunk.n, 8);
    rec_end(ci, a3);
    if (h.oom || offsets.oom || ci->oom || m->chunk.oom)
        m->err_io = m->err_io ? m->err_io : ENOMEM;
    free(h.p);
    free(offsets.p);
    m->chunk.n = 0;
    m->chunk_msgs = 0;
    m->n_chunks++;
}

int iso_mcap_write(iso_mcap *m, uint16_t ch, uint64_t log_time, const void *data, size_t len,
                   iso_err *err)
{
    if (!m || ch >= m->n_channels)
        return iso_err_set(err, ISO_EINVAL, -1, "MCAP: no channel %u", (unsigned)ch);
    if (m->messages > 0 && log_time < m->t_last)
        return iso_err_set(err, ISO_EINVAL, -1, "MCAP: a message at %llu ns after one at %llu",
                           (unsigned long long)log_time, (unsigned long long)m->t_last);
    if (m->chunk_msgs > 0 && m->chunk.n + len + 31 > ISO_MCAP_CHUNK_BYTES)
        close_chunk(m);
    if (m->chunk_msgs == 0)
        m->chunk_t0 = log_time;
    put_le(&m->idx[ch].pairs, log_time, 8);
    put_le(&m->idx[ch].pairs, m->chunk.n, 8);
    size_t at = rec_begin(&m->chunk, OP_MESSAGE);
    put_le(&m->chunk, ch, 2);
    put_le(&m->chunk, m->seq[ch]++, 4);
    put_le(&m->chunk, log_time, 8);
    put_le(&m->chunk, log_time, 8);
    iso_bytes_put(&m->chunk, data, len);
    rec_end(&m->chunk, at);
    if (m->chunk.oom || m->idx[ch].pairs.oom)
        m->err_io = ENOMEM;
    m->chunk_t1 = log_time;
    m->chunk_msgs++;
    if (m->messages == 0)
        m->t_first = log_time;
    m->t_last = log_time;
    m->messages++;
    m->count[ch]++;
    return m->err_io ? io_error(m, err) : ISO_OK;
}

uint64_t iso_mcap_messages(const iso_mcap *m)
{
    return m ? m->messages : 0;
}

static void statistics(iso_mcap *m, buf *b)
{
    size_t at = rec_begin(b, OP_STATISTICS);
    put_le(b, m->messages, 8);
    put_le(b, (uint64_t)m->n_schemas, 2);
    put_le(b, (uint64_t)m->n_channels, 4);
    put_le(b, 0, 4); /* attachments */
    put_le(b, 0, 4); /* metadata */
    put_le(b, (uint64_t)m->n_chunks, 4);
    put_le(b, m->messages ? m->t_first : 0, 8);
    put_le(b, m->messages ? m->t_last : 0, 8);
    put_le(b, (uint64_t)m->n_channels * 10, 4);
    for (int c = 0; c < m->n_channels; c++) {
        put_le(b, (uint64_t)c, 2);
        put_le(b, m->count[c], 8);
    }
    rec_end(b, at);
}

/* The summary section: its groups, then one Summary Offset per group. */
static void summary(iso_mcap *m, uint64_t *sum_start, uint64_t *off_start)
{
    buf st = {0}, offs = {0};
    statistics(m, &st);
    const buf *groups[4] = {&m->schemas, &m->channels, &st, &m->chunk_indexes};
    const int ops[4] = {OP_SCHEMA, OP_CHANNEL, OP_STATISTICS, OP_CHUNK_INDEX};
    *sum_start = m->off;
    for (int g = 0; g < 4; g++) {
        if (groups[g]->n == 0)
            continue;
        size_t at = rec_begin(&offs, OP_SUMMARY_OFFSET);
        put_le(&offs, (uint64_t)ops[g], 1);
        put_le(&offs, m->off, 8);
        put_le(&offs, groups[g]->n, 8);
        rec_end(&offs, at);
        emit_buf(m, groups[g]);
    }
    *off_start = m->off;
    emit_buf(m, &offs);
    if (st.oom || offs.oom)
        m->err_io = m->err_io ? m->err_io : ENOMEM;
    free(st.p);
    free(offs.p);
}

static void free_bufs(iso_mcap *m)
{
    free(m->chunk.p);
    free(m->packed.p);
    ZSTD_freeCCtx(m->zstd); /* NULL is a no-op */
    free(m->schemas.p);
    free(m->channels.p);
    free(m->chunk_indexes.p);
    for (int c = 0; c < ISO_MCAP_MAX_CHANNELS; c++)
        free(m->idx[c].pairs.p);
}

int iso_mcap_finish(iso_mcap *m, iso_err *err)
{
    if (!m)
        return iso_err_set(err, ISO_EINVAL, -1, "MCAP: NULL writer");
    close_chunk(m);
    unsigned char de[13] = {OP_DATA_END, 4};
    uint32_t dcrc = m->data_crc;
    for (int i = 0; i < 4; i++)
        de[9 + i] = (unsigned char)(dcrc >> (8 * i));
    emit(m, de, sizeof de);
    uint64_t sum_start, off_start;
    m->data_crc = 0; /* from here: the summary's CRC */
    summary(m, &sum_start, &off_start);
    unsigned char ft[29] = {OP_FOOTER, 20};
    for (int i = 0; i < 8; i++) {
        ft[9 + i] = (unsigned char)(sum_start >> (8 * i));
        ft[17 + i] = (unsigned char)(off_start >> (8 * i));
    }
    uint32_t scrc = crc_update(m, m->data_crc, ft, 25);
    for (int i = 0; i < 4; i++)
        ft[25 + i] = (unsigned char)(scrc >> (8 * i));
    emit(m, ft, sizeof ft);
    emit(m, MAGIC, 8);
    int rc = ISO_OK;
    if (m->err_io)
        rc = io_error(m, err);
    if (fclose(m->f) != 0 && rc == ISO_OK)
        rc = iso_err_set(err, ISO_EIO, -1, "MCAP %s: %s", m->out.write, strerror(errno));
    if (rc == ISO_OK)
        rc = iso_outfile_commit(&m->out, "MCAP", err);
    iso_outfile_abort(&m->out); /* a failed file is removed, not left beside its path */
    free_bufs(m);
    free(m);
    return rc;
}

void iso_mcap_destroy(iso_mcap *m)
{
    if (!m)
        return;
    close_chunk(m);
    fclose(m->f);
    iso_outfile_abort(&m->out); /* an unfinished file is not left behind (a full disk's) */
    free_bufs(m);
    free(m);
}
