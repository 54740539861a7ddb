/* common/iso_file.c -- see iso_file.h. */
#include "iso_file.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int iso_file_read(const char *path, size_t max, char **out, size_t *len, iso_err *err)
{
    *out = NULL;
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot open: %s", path, strerror(errno));
    char *buf = NULL;
    size_t n = 0, cap = 0;
    int rc = ISO_OK;
    for (;;) {
        if (n + 1 >= cap) { /* room for one more byte and the NUL */
            size_t nc = cap ? 2 * cap : 65536;
            char *p = nc > cap ? realloc(buf, nc) : NULL;
            if (!p) {
                rc = iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory reading %zu bytes", path,
                                 n);
                break;
            }
            buf = p;
            cap = nc;
        }
        size_t got = fread(buf + n, 1, cap - 1 - n, f);
        n += got;
        if (max && n > max) {
            rc = iso_err_set(err, ISO_EINVAL, -1, "%s: larger than %zu bytes", path, max);
            break;
        }
        if (got == 0) {
            if (ferror(f))
                rc = iso_err_set(err, ISO_EIO, (long)n, "%s: read error at byte offset %zu: %s",
                                 path, n, strerror(errno));
            break;
        }
    }
    fclose(f);
    if (rc != ISO_OK) {
        free(buf);
        return rc;
    }
    buf[n] = '\0';
    *out = buf;
    *len = n;
    return ISO_OK;
}
