/* common/iso_bytes.c -- the growable byte buffer (iso_bytes.h). */
#include "iso_bytes.h"

#include <stdlib.h>
#include <string.h>

unsigned char *iso_bytes_grow(iso_bytes *b, size_t more)
{
    if (b->oom)
        return NULL;
    if (b->n + more > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->n + more)
            cap *= 2;
        unsigned char *p = realloc(b->p, cap);
        if (!p) {
            b->oom = 1;
            return NULL;
        }
        b->p = p;
        b->cap = cap;
    }
    unsigned char *d = b->p + b->n;
    b->n += more;
    return d;
}

void iso_bytes_put(iso_bytes *b, const void *p, size_t n)
{
    unsigned char *d = iso_bytes_grow(b, n);
    if (d && n)
        memcpy(d, p, n);
}
