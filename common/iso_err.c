/* common/iso_err.c -- see iso_err.h. */
#include "iso_err.h"

#include <stdio.h>
#include <string.h>

void iso_err_clear(iso_err *err)
{
    if (!err)
        return;
    err->code = ISO_OK;
    err->offset = -1;
    err->msg[0] = '\0';
}

int iso_err_setv(iso_err *err, int code, long offset, const char *fmt, va_list ap)
{
    if (!err || err->code != ISO_OK)
        return code;
    err->code = code;
    err->offset = offset;
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    return code;
}

int iso_err_set(iso_err *err, int code, long offset, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    iso_err_setv(err, code, offset, fmt, ap);
    va_end(ap);
    return code;
}

const char *iso_strerror(int code)
{
    switch (code) {
    case ISO_OK: return "ok";
    case ISO_EINVAL: return "invalid argument";
    case ISO_ENOMEM: return "out of memory";
    case ISO_EIO: return "input/output error";
    case ISO_EPARSE: return "bad input";
    case ISO_ENOTSUP: return "not supported";
    case ISO_ENUMERIC: return "numerical failure";
    case ISO_EMESH: return "unusable mesh";
    case ISO_ECONSTRAINT: return "ill-posed constraints";
    default: return "unknown error";
    }
}
