/* common/iso_err.h -- the one error type every isoshape module reports through.
 *
 * Every fallible function returns an int status: ISO_OK (0) or a negative
 * ISO_E* code, and fills a caller-owned iso_err with a sentence that says
 * where (file:line, byte offset, triangle, edge, row) and what went wrong.
 * The first error written wins, so the innermost, most specific cause reaches
 * the user. No global state: the message lives in the caller's struct. */
#ifndef ISO_ERR_H
#define ISO_ERR_H

#include <stdarg.h>

#include "iso_api.h"

enum {
    ISO_OK = 0,
    ISO_EINVAL = -1, /* caller bug or bad option value */
    ISO_ENOMEM = -2,
    ISO_EIO = -3,    /* OS or device failure; msg carries strerror text */
    ISO_EPARSE = -4, /* bad input file; msg names file:line or byte offset */
    ISO_ENOTSUP = -5,
    ISO_ENUMERIC = -6,   /* e.g. a system that is not positive definite */
    ISO_EMESH = -7,      /* mesh that parses but cannot be used (degenerate, non-manifold) */
    ISO_ECONSTRAINT = -8 /* ill-posed boundary conditions */
};

typedef struct iso_err {
    int code;
    long offset;   /* line or byte offset in the input, -1 if none */
    char msg[512]; /* first error wins */
} iso_err;

#define ISO_NODISCARD __attribute__((warn_unused_result))
#define ISO_PRINTF(a, b) __attribute__((format(printf, a, b)))

/* Resets *err to "no error". NULL is a no-op. */
ISO_API void iso_err_clear(iso_err *err);

/* Records an error unless one is already recorded (first wins). Returns
 * `code`, so a caller can write `return iso_err_set(err, ISO_EINVAL, ...)`.
 * err may be NULL. */
ISO_API int iso_err_set(iso_err *err, int code, long offset, const char *fmt, ...) ISO_PRINTF(4, 5);
ISO_API int iso_err_setv(iso_err *err, int code, long offset, const char *fmt, va_list ap);

/* A short name for a code; never NULL. */
ISO_API const char *iso_strerror(int code);

#endif
