/* common/iso_range.h -- a number's allowed range, and the one check that
 * reads a number from text and holds it to its range.
 *
 * Scene files (config/), the command line (controller/) and the solver's
 * table of its settings' ranges (iso_solver_range, solver/iso_solver.h)
 * all check numbers here, so a value is refused in the same words wherever
 * it was written: "'2' is out of range: expected a value in (0, 1]", or
 * "'x1' is not a number: expected a value in (0, 1]". The caller says
 * where and which setting before it ("--omega ", "scene.yaml:3:12:
 * solver.omega: "). */
#ifndef ISO_RANGE_H
#define ISO_RANGE_H

#include <stddef.h>

#include "iso_api.h"

/* A range's end: none, open (excluded) or closed (included). */
typedef enum iso_range_end { ISO_RANGE_NONE = 0, ISO_RANGE_OPEN, ISO_RANGE_CLOSED } iso_range_end;

typedef struct iso_range {
    double lo, hi;
    iso_range_end lo_end, hi_end;
    int integer; /* 1: whole numbers only, written in decimal (or hex after 0x) */
} iso_range;

/* Designated initializers for a range's ends: {ISO_RANGE_GT(0), ISO_RANGE_LE(1)} is (0, 1]. */
#define ISO_RANGE_GT(x) .lo = (x), .lo_end = ISO_RANGE_OPEN
#define ISO_RANGE_GE(x) .lo = (x), .lo_end = ISO_RANGE_CLOSED
#define ISO_RANGE_LT(x) .hi = (x), .hi_end = ISO_RANGE_OPEN
#define ISO_RANGE_LE(x) .hi = (x), .hi_end = ISO_RANGE_CLOSED

/* Codes of iso_range_parse besides 0. */
enum { ISO_RANGE_NOT_A_NUMBER = -1, ISO_RANGE_OUTSIDE = -2 };

/* The ends as a phrase into buf: "in (0, 1]", "> 0", ">= 1", "<= 5"; ""
 * without ends. Returns buf. */
ISO_API const char *iso_range_text(const iso_range *r, char *buf, size_t cap);
/* What a value must be, into buf: "a value in (0, 1]", "an integer >= 1",
 * "a finite number", "an integer". Returns buf. */
ISO_API const char *iso_range_expected(const iso_range *r, char *buf, size_t cap);
/* 1 if v lies in r (NaN never does; an integer range also wants a whole v). */
ISO_API int iso_range_holds(const iso_range *r, double v);
/* Reads the whole of `text` as a finite number (an integer range: a whole
 * number in decimal, or in hex after 0x) and holds it to r. Returns 0 with
 * the value in *out; else ISO_RANGE_NOT_A_NUMBER or ISO_RANGE_OUTSIDE with
 * the refusal in why: "'TEXT' is not a number: expected ..." ("is not an
 * integer" for an integer range) or "'TEXT' is out of range: expected ...".
 * A text longer than 40 characters is cut there, with "...". */
ISO_API int iso_range_parse(const iso_range *r, const char *text, double *out, char *why,
                            size_t cap);

#endif
