/* devices/internal.h -- what the devices/ files share and nobody else sees:
 * each hardware backend's part of iso_dev_enumerate() and whether it is
 * built. Not installed. */
#ifndef ISO_DEV_INTERNAL_H
#define ISO_DEV_INTERNAL_H

#include "iso_dev_decode.h"
#include "iso_dev_enum.h"
#include "iso_dev_hub.h"
#include "iso_dev_source.h"

#include <string.h>

/* A record's size around its chunk (RECORDING.md): sync, type, source,
 * len (2) and t (8) before the data, its CRC-32 after. */
#define ISO_DEV__REC_HEAD 13u
#define ISO_DEV__REC_MAX (ISO_DEV__REC_HEAD + ISO_DEV_CHUNK_MAX + 4u)

/* A read of n bytes into out->data: n > 0 stamps the chunk with the time
 * base of every live chunk (iso_clock_ns) and returns 1; n <= 0 returns 0,
 * leaving the caller to tell "nothing yet" from an error. */
static inline int iso_dev__chunk_read(iso_dev_chunk *out, long n)
{
    if (n <= 0)
        return 0;
    out->t_ns = iso_clock_ns();
    out->len = (uint16_t)n;
    return 1;
}

/* What a serial line's source reports: kind SERIAL, baud, 8N1. */
static inline void iso_dev__serial_info(iso_dev_info *info, uint32_t baud)
{
    info->kind = ISO_DEV_KIND_SERIAL;
    info->baud = baud;
    info->data_bits = 8;
    info->parity = 'N';
    info->stop_bits = 1;
}

/* The next event slot of a decoder's output, zeroed and stamped with time
 * t, kind and the decoder's source; NULL, counted as garbage, when the
 * caller's cap is reached (the event is then lost, never written past). */
static inline iso_dev_event *iso_dev__emit(iso_dev_decoder *d, int64_t t, int kind,
                                           iso_dev_event *ev, size_t cap, size_t *n)
{
    if (*n >= cap) {
        d->n.garbage++;
        return NULL;
    }
    iso_dev_event *e = &ev[(*n)++];
    memset(e, 0, sizeof *e);
    e->t_ns = t;
    e->kind = (uint8_t)kind;
    e->source = d->source;
    return e;
}

/* The view's decoder (decode_view.c): one envelope of len bytes. */
size_t iso_dev__view_decode(iso_dev_decoder *d, int64_t t, const uint8_t *p, size_t len,
                            iso_dev_event *ev, size_t cap);
/* decode.c: the noise cap's side of the decoders (RECORDING.md, "The noise
 * cap"). 1 when a data chunk that gave `events` events, decoded by a
 * decoder that was `before` and is now `after`, is one a recording may
 * leave out: no event and no good report or frame, so that nothing but the
 * counts and the serial parser's unfinished frame changed (a SKIP carries
 * both). The start of a good frame cut across two reads is such a chunk:
 * left out only beyond the cap, and then exactly. */
int iso_dev__noise_chunk(const iso_dev_decoder *before, const iso_dev_decoder *after,
                         size_t events);
/* A SKIP record's payload for chunks left out: `first` is the decoder
 * before the first of them, `after` after the last. Returns its length, or
 * ISO_EINVAL when cap is too small (ISO_DEV_CHUNK_MAX always suffices). */
int iso_dev__skip_encode(const iso_dev_decoder *after, const iso_dev_decoder *first, uint32_t bytes,
                         uint32_t chunks, uint8_t *dst, size_t cap);
/* Applies a SKIP record's payload (t: its time) to the decoder. */
void iso_dev__skip_apply(iso_dev_decoder *d, int64_t t, const uint8_t *p, size_t len);

/* hub_reopen.c: the thread that opens gone sources again and closes the
 * handles of those that went, so that neither happens on the tick. ask:
 * source i is to be reopened by fn(ctx, info, ...) (info and ctx stay valid
 * until the answer is taken); 0 when an answer for i is pending already.
 * take: 1 with the answer (*back: the source, or NULL when it is not back),
 * 0 while there is none. close: hands s over to be closed; 0 when the last
 * one handed over for i is still open (the caller closes s itself). */
typedef struct iso_dev__reopener iso_dev__reopener;
ISO_NODISCARD int iso_dev__reopener_create(iso_dev__reopener **out, iso_err *err);
void iso_dev__reopener_destroy(iso_dev__reopener *r); /* closes what it holds; NULL: no-op */
int iso_dev__reopener_ask(iso_dev__reopener *r, size_t i, iso_dev_reopen_fn fn, void *ctx,
                          const iso_dev_info *info);
int iso_dev__reopener_take(iso_dev__reopener *r, size_t i, iso_dev_source **back);
int iso_dev__reopener_close(iso_dev__reopener *r, size_t i, iso_dev_source *s);
/* Waits up to timeout_ms until nothing is being reopened or closed: 1, or 0. */
int iso_dev__reopener_sync(iso_dev__reopener *r, int timeout_ms);

/* hub_reader.c: the thread that reads the hub's byte streams, so that the
 * tick never waits in the kernel's tty layer (the file says why). */
typedef struct iso_dev__reader iso_dev__reader;
ISO_NODISCARD int iso_dev__reader_create(iso_dev__reader **out, iso_err *err);
void iso_dev__reader_destroy(iso_dev__reader *rd); /* stops and joins it; NULL is a no-op */
/* From now on the thread alone reads s, as source i, into i's ring; the
 * caller takes s back when it pops the GONE chunk that ends it. */
ISO_NODISCARD int iso_dev__reader_attach(iso_dev__reader *rd, size_t i, iso_dev_source *s,
                                         iso_err *err);
/* The next chunk read from source i: 1 and *c (DATA, or GONE with the
 * error's text as its bytes, after which s is the caller's), 0 when there
 * is none now. Lock-free; one caller thread. */
int iso_dev__reader_pop(iso_dev__reader *rd, size_t i, iso_dev_chunk *c);
/* Waits up to timeout_ms for the thread to find its sources with nothing
 * more to read (or its rings full); 1 when it did, 0 on the timeout. */
int iso_dev__reader_sync(iso_dev__reader *rd, int timeout_ms);
/* The thread's SCHED_FIFO priority (0: SCHED_OTHER), applied by itself. */
ISO_NODISCARD int iso_dev__reader_priority(iso_dev__reader *rd, int priority, iso_err *err);

/* Each appends at most cap entries and returns how many. */
/* A source and its backend's struct in one zeroed allocation: s->ops set
 * and s->impl pointing at impl_size bytes after the source, aligned for
 * any type. NULL when out of memory (then nothing was allocated, and the
 * backend closes only what it opened itself). Every backend makes its
 * source so, and its close ends with iso_dev__source_free, which frees
 * both at once. */
iso_dev_source *iso_dev__source_new(const iso_dev_source_ops *ops, size_t impl_size);
void iso_dev__source_free(iso_dev_source *s); /* NULL is a no-op */

size_t iso_dev__hid_enumerate(iso_dev_found *out, size_t cap);
size_t iso_dev__serialport_enumerate(iso_dev_found *out, size_t cap);
size_t iso_dev__gpiod_enumerate(iso_dev_found *out, size_t cap);
size_t iso_dev__usb_enumerate(iso_dev_found *out, size_t cap);
/* 1 running, 0 not, -1 not built. */
int iso_dev__spnav_running(void);

/* Whether each optional backend is compiled in (1) or out (0): set in the
 * backend's own file by the #ifdef that selects its code. */
extern const int iso_dev__hidapi_built;
extern const int iso_dev__serialport_built;
extern const int iso_dev__gpiod_built;
extern const int iso_dev__libusb_built;
extern const int iso_dev__spnav_built;

#endif
