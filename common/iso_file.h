/* common/iso_file.h -- reading a whole file into memory, the one way every
 * part does it (meshes, selections, scenes, recordings, the live view's
 * scripts). Internal to the library: not installed, not exported
 * (CMakeLists.txt, iso_add_part INTERNAL). */
#ifndef ISO_FILE_H
#define ISO_FILE_H

#include <stddef.h>

#include "iso_err.h"

/* Reads the file at `path` into a new buffer of *len bytes followed by a
 * NUL that *len does not count, so a text parser may treat it as a string
 * and a binary one ignores it. The caller frees *out (NULL on failure).
 * A file of more than `max` bytes (0: no limit) is refused. Errors name the
 * path: ISO_EIO "PATH: cannot open: <why>" or "PATH: read error at byte
 * offset N: <why>" (offset N), ISO_ENOMEM, ISO_EINVAL "PATH: larger than
 * N bytes". */
ISO_NODISCARD int iso_file_read(const char *path, size_t max, char **out, size_t *len,
                                iso_err *err);

#endif
