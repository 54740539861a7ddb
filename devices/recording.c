/* devices/recording.c -- the recording format of RECORDING.md: a header
 * that describes every source, then length-prefixed, checksummed records.
 *
 * The reader works on the recording in memory and trusts nothing in it: a
 * record cut off at the end stops the replay where the last complete one
 * ended, and a damaged record is skipped by resynchronising on the next
 * sync byte that starts a record whose checksum holds. */
#include "internal.h"
#include "iso_crc32.h"
#include "iso_dev_rec.h"
#include "iso_file.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAGIC "ISOSHREC"
#define SYNC 0xA5u

/* Four bits at a time (iso_crc32_small): the bitwise loop made a 16 MB
 * recording's load check and a noisy device's recording cost 8 shifts a
 * byte. */
uint32_t iso_dev_crc32(const uint8_t *p, size_t len)
{
    return iso_crc32_small(0, p, len);
}

/* ---- little-endian cursors --------------------------------------------- */

typedef struct wcur {
    uint8_t *p;
    size_t cap, n;
    int over;
} wcur;

static void put(wcur *c, const void *src, size_t len)
{
    if (c->over || c->cap - c->n < len) {
        c->over = 1;
        return;
    }
    memcpy(c->p + c->n, src, len);
    c->n += len;
}
static void put_u(wcur *c, uint64_t v, int bytes)
{
    uint8_t b[8];
    for (int i = 0; i < bytes; i++)
        b[i] = (uint8_t)(v >> (8 * i));
    put(c, b, (size_t)bytes);
}

typedef struct rcur {
    const uint8_t *p;
    size_t len, n;
    int over;
} rcur;

static uint64_t get_u(rcur *c, int bytes)
{
    if (c->over || c->len - c->n < (size_t)bytes) {
        c->over = 1;
        return 0;
    }
    uint64_t v = 0;
    for (int i = 0; i < bytes; i++)
        v |= (uint64_t)c->p[c->n + (size_t)i] << (8 * i);
    c->n += (size_t)bytes;
    return v;
}
static const uint8_t *get_bytes(rcur *c, size_t len)
{
    if (c->over || c->len - c->n < len) {
        c->over = 1;
        return NULL;
    }
    const uint8_t *p = c->p + c->n;
    c->n += len;
    return p;
}

/* ---- encoding ----------------------------------------------------------- */

int iso_dev_rec_encode_header(uint8_t *dst, size_t cap, const iso_dev_info *infos, size_t n,
                              int64_t t0_ns)
{
    if (n > ISO_DEV_MAX_SOURCES)
        return ISO_EINVAL;
    wcur c = {dst, cap, 0, 0};
    put(&c, MAGIC, 8);
    put_u(&c, ISO_DEV_REC_VERSION, 2);
    put_u(&c, n, 2);
    put_u(&c, 0, 4); /* header length, patched below */
    put_u(&c, (uint64_t)t0_ns, 8);
    for (size_t i = 0; i < n; i++) {
        const iso_dev_info *f = &infos[i];
        size_t nl = strnlen(f->name, ISO_DEV_NAME_MAX - 1);
        size_t dl = f->desc_len <= ISO_DEV_DESC_MAX ? f->desc_len : ISO_DEV_DESC_MAX;
        put_u(&c, f->kind, 1);
        put_u(&c, f->vid, 2);
        put_u(&c, f->pid, 2);
        put_u(&c, f->baud, 4);
        put_u(&c, f->data_bits, 1);
        put_u(&c, f->parity, 1);
        put_u(&c, f->stop_bits, 1);
        put_u(&c, f->debounce_us, 4);
        put_u(&c, nl, 1);
        put(&c, f->name, nl);
        put_u(&c, dl, 2);
        put(&c, f->desc, dl);
    }
    if (c.over || cap - c.n < 4)
        return ISO_EINVAL;
    uint32_t total = (uint32_t)(c.n + 4);
    for (int i = 0; i < 4; i++)
        dst[12 + i] = (uint8_t)(total >> (8 * i));
    put_u(&c, iso_dev_crc32(dst, c.n), 4);
    return (int)c.n;
}

int iso_dev_rec_encode_record(uint8_t *dst, size_t cap, const iso_dev_chunk *ch)
{
    if (ch->len > ISO_DEV_CHUNK_MAX)
        return ISO_EINVAL;
    wcur c = {dst, cap, 0, 0};
    put_u(&c, SYNC, 1);
    put_u(&c, ch->type, 1);
    put_u(&c, ch->source, 1);
    put_u(&c, ch->len, 2);
    put_u(&c, (uint64_t)ch->t_ns, 8);
    put(&c, ch->data, ch->len);
    if (c.over || cap - c.n < 4)
        return ISO_EINVAL;
    put_u(&c, iso_dev_crc32(dst, c.n), 4);
    return (int)c.n;
}

/* ---- reader -------------------------------------------------------------- */

static int header_error(iso_dev_rec_reader *r, iso_err *err, long at, const char *what)
{
    iso_dev_rec_reader_deinit(r);
    return iso_err_set(err, ISO_EPARSE, at, "recording header, byte %ld: %s", at, what);
}

int iso_dev_rec_reader_init(iso_dev_rec_reader *r, const uint8_t *data, size_t len, iso_err *err)
{
    memset(r, 0, sizeof *r);
    r->data = data;
    r->len = len;
    r->last_damage_at = -1;
    rcur c = {data, len, 0, 0};
    const uint8_t *magic = get_bytes(&c, 8);
    if (!magic || memcmp(magic, MAGIC, 8) != 0)
        return header_error(r, err, 0, "not an isoshape recording (no ISOSHREC magic)");
    r->version = (uint16_t)get_u(&c, 2);
    if ((r->version < 1 || r->version > ISO_DEV_REC_VERSION) && !c.over)
        return header_error(r, err, 8, "format version unknown to this build (it reads 1 and 2)");
    size_t n = (size_t)get_u(&c, 2);
    uint32_t hlen = (uint32_t)get_u(&c, 4);
    r->t0_ns = (int64_t)get_u(&c, 8);
    if (c.over)
        return header_error(r, err, (long)len, "the file ends inside the header");
    if (n > ISO_DEV_MAX_SOURCES)
        return header_error(r, err, 10, "more sources than this build can replay (16)");
    if (hlen < 28 || hlen > len)
        return header_error(
            r, err, 12, hlen > len ? "the file ends inside the header" : "header length too small");
    uint32_t crc = (uint32_t)(data[hlen - 4] | (uint32_t)data[hlen - 3] << 8 |
                              (uint32_t)data[hlen - 2] << 16 | (uint32_t)data[hlen - 1] << 24);
    if (iso_dev_crc32(data, hlen - 4) != crc)
        return header_error(r, err, (long)hlen - 4, "header checksum mismatch");
    c.len = hlen - 4;
    r->infos = calloc(n ? n : 1, sizeof *r->infos);
    if (!r->infos) {
        iso_dev_rec_reader_deinit(r);
        return iso_err_set(err, ISO_ENOMEM, -1, "recording header: out of memory");
    }
    r->n_sources = n;
    for (size_t i = 0; i < n; i++) {
        iso_dev_info *f = &r->infos[i];
        f->kind = (uint8_t)get_u(&c, 1);
        f->vid = (uint16_t)get_u(&c, 2);
        f->pid = (uint16_t)get_u(&c, 2);
        f->baud = (uint32_t)get_u(&c, 4);
        f->data_bits = (uint8_t)get_u(&c, 1);
        f->parity = (uint8_t)get_u(&c, 1);
        f->stop_bits = (uint8_t)get_u(&c, 1);
        f->debounce_us = (uint32_t)get_u(&c, 4);
        size_t nl = (size_t)get_u(&c, 1);
        const uint8_t *name = get_bytes(&c, nl);
        if (name && nl < ISO_DEV_NAME_MAX)
            memcpy(f->name, name, nl);
        size_t dl = (size_t)get_u(&c, 2);
        const uint8_t *desc = get_bytes(&c, dl);
        if (c.over || nl >= ISO_DEV_NAME_MAX || dl > ISO_DEV_DESC_MAX)
            return header_error(r, err, (long)c.n, "a source description runs past the header");
        memcpy(f->desc, desc, dl);
        f->desc_len = (uint16_t)dl;
    }
    if (c.n != c.len)
        return header_error(r, err, (long)c.n, "unexpected bytes after the source descriptions");
    r->pos = hlen;
    r->end_at = (long)hlen;
    r->header_len = (long)hlen;
    return ISO_OK;
}

int iso_dev_rec_reader_load(iso_dev_rec_reader *r, const char *path, iso_err *err)
{
    memset(r, 0, sizeof *r);
    char *text;
    size_t len;
    int frc = iso_file_read(path, 0, &text, &len, err);
    if (frc != ISO_OK)
        return frc;
    uint8_t *buf = (uint8_t *)text;
    iso_err e2;
    iso_err_clear(&e2);
    int rc = iso_dev_rec_reader_init(r, buf, len, &e2);
    if (rc != ISO_OK) {
        free(buf);
        return iso_err_set(err, rc, e2.offset, "%s: %s", path, e2.msg);
    }
    r->owned = 1;
    return ISO_OK;
}

void iso_dev_rec_reader_deinit(iso_dev_rec_reader *r)
{
    if (r->owned)
        free((void *)r->data);
    free(r->infos);
    r->infos = NULL;
    r->data = NULL;
    r->owned = 0;
    r->n_sources = 0;
}

/* The sentence for a recording whose complete part ends at byte `good` of
 * `len`: inside a record that starts there (inside = 1), in bytes that
 * hold no record (inside = 0, good < len), or at its very end without an
 * END record (good == len). ticks < 0: not counted (said without). */
static void cut_sentence(char *msg, size_t cap, size_t len, size_t good, int inside, long records,
                         long ticks)
{
    char what[96];
    if (ticks >= 0)
        snprintf(what, sizeof what, "%ld records, %ld ticks, up to byte %zu", records, ticks, good);
    else
        snprintf(what, sizeof what, "%ld records, up to byte %zu", records, good);
    if (inside)
        snprintf(msg, cap,
                 "the recording is cut off at byte %zu, inside a record that starts at byte %zu: "
                 "what came before is used (%s)",
                 len, good, what);
    else if (good < len)
        snprintf(msg, cap,
                 "the recording is cut off at byte %zu: its last %zu bytes (from byte %zu) hold "
                 "no complete record: what came before is used (%s)",
                 len, len - good, good, what);
    else
        snprintf(msg, cap,
                 "the recording is cut off at byte %zu: it has no end record (its writer did not "
                 "close it: killed, crashed or out of space, or the file was cut there): what "
                 "came before is used (%s)",
                 len, what);
}

/* 1: a complete, valid record at off (length in *rl); 0: invalid; -1: it
 * would run past the end of the data. */
static int record_at(const iso_dev_rec_reader *r, size_t off, size_t *rl)
{
    const uint8_t *p = r->data + off;
    size_t left = r->len - off;
    if (left < 1 || p[0] != SYNC)
        return 0;
    if (left < ISO_DEV__REC_HEAD)
        return -1;
    size_t len = (size_t)(p[3] | (unsigned)p[4] << 8);
    int last_type = r->version >= 2 ? ISO_DEV_CHUNK_SKIP : ISO_DEV_CHUNK_TICK;
    if (len > ISO_DEV_CHUNK_MAX || p[1] < ISO_DEV_CHUNK_DATA || p[1] > last_type)
        return 0;
    int sourceless = p[1] == ISO_DEV_CHUNK_TICK || p[1] == ISO_DEV_CHUNK_END;
    if (!sourceless && p[2] >= r->n_sources)
        return 0;
    if (left < ISO_DEV__REC_HEAD + len + 4)
        return -1;
    size_t body = ISO_DEV__REC_HEAD + len;
    uint32_t crc = (uint32_t)(p[body] | (uint32_t)p[body + 1] << 8 | (uint32_t)p[body + 2] << 16 |
                              (uint32_t)p[body + 3] << 24);
    if (iso_dev_crc32(p, body) != crc)
        return 0;
    *rl = body + 4;
    return 1;
}

/* The END record at r->pos (rl bytes): the recording ends here. Bytes after
 * it are no part of it: counted as damage and said. */
static int read_end(iso_dev_rec_reader *r, size_t rl)
{
    size_t at = r->pos;
    r->pos += rl;
    r->end_at = (long)r->pos;
    r->ended = 1;
    if (r->pos < r->len) {
        r->damaged++;
        r->last_damage_at = (long)r->pos;
        snprintf(r->note, sizeof r->note,
                 "%zu bytes follow the end record at byte %zu: they are no part of the recording "
                 "and are ignored",
                 r->len - r->pos, at);
    }
    r->pos = r->len;
    return 0;
}

int iso_dev_rec_next(iso_dev_rec_reader *r, iso_dev_chunk *c, int *damaged_now)
{
    if (damaged_now)
        *damaged_now = 0;
    if (!r->data || r->pos >= r->len)
        return 0;
    size_t rl = 0;
    int k = record_at(r, r->pos, &rl);
    if (k != 1) {
        /* Damaged or cut off: find the next record that checks out. If there
         * is none, the recording was torn at the last complete record. */
        size_t start = r->pos, q = r->pos + 1;
        while (q < r->len && record_at(r, q, &rl) != 1)
            q++;
        if (q >= r->len) {
            r->torn = 1;
            r->pos = r->len;
            cut_sentence(r->note, sizeof r->note, r->len, start, k == -1, r->records, -1);
            return 0;
        }
        r->damaged++;
        r->last_damage_at = (long)start;
        snprintf(r->note, sizeof r->note,
                 "damaged record at byte %zu: skipped %zu bytes up to the next good record at "
                 "byte %zu",
                 start, q - start, q);
        if (damaged_now)
            *damaged_now = 1;
        r->pos = q;
    }
    const uint8_t *p = r->data + r->pos;
    if (p[1] == ISO_DEV_CHUNK_END)
        return read_end(r, rl);
    memset(c, 0, sizeof *c);
    c->type = p[1];
    c->source = p[2];
    c->len = (uint16_t)(p[3] | (unsigned)p[4] << 8);
    uint64_t t = 0;
    for (int i = 0; i < 8; i++)
        t |= (uint64_t)p[5 + i] << (8 * i);
    c->t_ns = (int64_t)t;
    memcpy(c->data, p + ISO_DEV__REC_HEAD, c->len);
    r->pos += rl;
    r->end_at = (long)r->pos;
    r->records++;
    return 1;
}

int iso_dev_rec_reader_cut(const iso_dev_rec_reader *r, char *msg, size_t cap, long *at)
{
    if (cap)
        msg[0] = '\0';
    if (at)
        *at = r->data ? (long)r->len : 0;
    if (!r->data || r->header_len <= 0)
        return 0;
    long records = 0, ticks = 0;
    size_t pos = (size_t)r->header_len, rl = 0;
    while (pos < r->len) {
        int k = record_at(r, pos, &rl);
        if (k == 1) {
            const uint8_t type = r->data[pos + 1];
            if (type == ISO_DEV_CHUNK_END)
                return 0; /* whole; what may follow is damage, said by iso_dev_rec_next */
            records++;
            ticks += type == ISO_DEV_CHUNK_TICK;
            pos += rl;
            continue;
        }
        size_t q = pos + 1; /* damage inside, or the cut: is there a good record after? */
        while (q < r->len && record_at(r, q, &rl) != 1)
            q++;
        if (q < r->len) {
            pos = q;
            continue;
        }
        if (cap)
            cut_sentence(msg, cap, r->len, pos, k == -1, records, ticks);
        if (at)
            *at = (long)pos;
        return 1;
    }
    if (r->version < 2)
        return 0; /* format 1 has no END record: a cut between records does not show */
    if (cap)
        cut_sentence(msg, cap, r->len, r->len, 0, records, ticks);
    if (at)
        *at = (long)r->len;
    return 1;
}
