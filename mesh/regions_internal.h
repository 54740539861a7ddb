/* mesh/regions_internal.h -- in-memory entry points of the .sel and .def
 * readers, for the fuzz targets; not installed, not public API. */
#ifndef ISO_REGIONS_INTERNAL_H
#define ISO_REGIONS_INTERNAL_H

#include <stddef.h>

#include "iso_regions.h"

/* As iso_sel_load / iso_def_load, reading `len` bytes of `data` (not
 * NUL-terminated, never read past len); `name` names the source in messages. */
ISO_NODISCARD int iso_sel__parse(const char *name, const unsigned char *data, size_t len, int nv,
                                 iso_regions *r, iso_err *err);
ISO_NODISCARD int iso_def__parse(const char *name, const unsigned char *data, size_t len,
                                 double M[16], iso_err *err);

#endif
