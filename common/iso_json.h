/* common/iso_json.h -- the one JSON writer every command uses (deform,
 * bench, metrics, run --stats-json).
 *
 * Key style: every key isoshape writes is snake_case ("metric_err",
 * "cg_iterations", "assembly_ms_per_evaluation"); tests/test_cli.c and
 * tests/test_run.c hold each command's output to it. Numbers are written
 * with 17 significant digits, so a double reads back to the same bits; a
 * number that is not finite is written as null (JSON has no NaN or
 * infinity). Strings are escaped here and nowhere else.
 *
 * A writer streams to a FILE: begin, then values (a key for each one inside
 * an object, NULL inside an array), nested objects and arrays closed in
 * order, then end. Nesting deeper than ISO_JSON_MAX_DEPTH is a caller's
 * bug: such an object or array does not open (its values go to the level
 * above) and its close pairs with it. */
#ifndef ISO_JSON_H
#define ISO_JSON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "iso_api.h"

#define ISO_JSON_MAX_DEPTH 16

typedef struct iso_json { /* caller-owned; iso_json_begin fills it */
    FILE *f;
    int depth;                               /* open objects and arrays */
    char close[ISO_JSON_MAX_DEPTH];          /* '}' or ']' for each */
    unsigned long items[ISO_JSON_MAX_DEPTH]; /* values written in each */
    int too_deep;                            /* opens refused past the limit */
} iso_json;

/* Starts the top-level object on f. */
ISO_API void iso_json_begin(iso_json *j, FILE *f);
/* Closes whatever is open, ends the line; returns 0, or -1 when f reports
 * a write error. */
ISO_API int iso_json_end(iso_json *j);

/* Opens an object or an array as the value of `key` (NULL inside an array). */
ISO_API void iso_json_object(iso_json *j, const char *key);
ISO_API void iso_json_array(iso_json *j, const char *key);
/* Closes the innermost open object or array. */
ISO_API void iso_json_close(iso_json *j);

ISO_API void iso_json_number(iso_json *j, const char *key, double v); /* non-finite: null */
ISO_API void iso_json_int(iso_json *j, const char *key, long long v);
ISO_API void iso_json_bool(iso_json *j, const char *key, int v);
ISO_API void iso_json_string(iso_json *j, const char *key, const char *s); /* NULL: null */

/* A struct's members as values, by a table: each row names the key, the
 * member's type and its offset ({ISO_JSON_FIELD(T, m, type)} for a member
 * written under its own name). Tables keep long records from being runs of look-alike
 * calls, and say in one place what a record holds. */
typedef enum iso_json_type {
    ISO_JSON_DOUBLE, /* double */
    ISO_JSON_INT,    /* int */
    ISO_JSON_LONG,   /* long */
    ISO_JSON_U32,    /* uint32_t */
    ISO_JSON_BOOL,   /* int, written true or false */
    ISO_JSON_TEXT,   /* char array, NUL-terminated */
    ISO_JSON_U64     /* uint64_t (a counter: below 2^63) */
} iso_json_type;
typedef struct iso_json_field {
    const char *key;
    iso_json_type type;
    size_t at; /* offsetof */
} iso_json_field;
#define ISO_JSON_FIELD(type_name, member, json_type) #member, json_type, offsetof(type_name, member)
ISO_API void iso_json_fields(iso_json *j, const void *base, const iso_json_field *f, size_t n);

#endif
