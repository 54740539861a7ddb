/* common/iso_bytes.h -- a growable byte buffer, for the writers that build
 * a message or a file section before it goes out (the MCAP writer, the
 * Foxglove server's frames). Growth doubles from 4 KiB; a failed growth
 * sets oom, after which every append is a no-op, so that the writer checks
 * once at the end instead of after every append. Not for the tick: it
 * allocates. Internal to the library: not installed, not exported. */
#ifndef ISO_BYTES_H
#define ISO_BYTES_H

#include <stddef.h>

typedef struct iso_bytes {
    unsigned char *p;
    size_t n, cap;
    int oom; /* an allocation failed: the contents are incomplete */
} iso_bytes;

/* Appends `more` bytes to the end and returns where they start, for the
 * caller to fill; NULL once oom is set. */
unsigned char *iso_bytes_grow(iso_bytes *b, size_t more);

/* Appends n bytes from p (nothing once oom is set). */
void iso_bytes_put(iso_bytes *b, const void *p, size_t n);

#endif
