/* common/iso_names.h -- names of enum values, for files, options and output.
 *
 * A name table is a NULL-terminated array of names indexed by the enum's
 * value (value i is names[i]). The module that defines an enum owns its
 * table (iso_assembly_names in solver/iso_solver.h, iso_dev_lock_names in
 * devices/iso_dev_map.h, ...); scene files, the command line and the summaries
 * all read that one table, so a name is spelled in one place. */
#ifndef ISO_NAMES_H
#define ISO_NAMES_H

#include <stddef.h>

#include "iso_api.h"

/* The value whose name is `word`, or -1. */
ISO_API int iso_names_find(const char *const *names, const char *word);
/* The name of `value`, or "?" when the table has none. */
ISO_API const char *iso_names_get(const char *const *names, int value);
/* The names joined into buf: sep between them, last before the last one
 * ("a|b|c" with sep = last = "|"). Returns buf. */
ISO_API const char *iso_names_join(const char *const *names, const char *sep, const char *last,
                                   char *buf, size_t cap);
/* The names as a phrase into buf: "a, b or c" with last = " or ", or
 * "a, b, c" with last = ", " (iso_names_join with sep ", "). Returns buf. */
ISO_API const char *iso_names_list(const char *const *names, const char *last, char *buf,
                                   size_t cap);

#endif
