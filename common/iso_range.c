/* common/iso_range.c -- see iso_range.h. */
#include "iso_range.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *iso_range_text(const iso_range *r, char *buf, size_t cap)
{
    if (r->lo_end && r->hi_end)
        snprintf(buf, cap, "in %c%.15g, %.15g%c", r->lo_end == ISO_RANGE_OPEN ? '(' : '[', r->lo,
                 r->hi, r->hi_end == ISO_RANGE_OPEN ? ')' : ']');
    else if (r->lo_end)
        snprintf(buf, cap, "%s %.15g", r->lo_end == ISO_RANGE_OPEN ? ">" : ">=", r->lo);
    else if (r->hi_end)
        snprintf(buf, cap, "%s %.15g", r->hi_end == ISO_RANGE_OPEN ? "<" : "<=", r->hi);
    else if (cap)
        buf[0] = '\0';
    return buf;
}

const char *iso_range_expected(const iso_range *r, char *buf, size_t cap)
{
    char ends[96];
    if (!r->lo_end && !r->hi_end)
        snprintf(buf, cap, "%s", r->integer ? "an integer" : "a finite number");
    else
        snprintf(buf, cap, "%s %s", r->integer ? "an integer" : "a value",
                 iso_range_text(r, ends, sizeof ends));
    return buf;
}

int iso_range_holds(const iso_range *r, double v)
{
    if (isnan(v) || (r->integer && v != floor(v)))
        return 0;
    if (r->lo_end == ISO_RANGE_OPEN ? !(v > r->lo) : r->lo_end == ISO_RANGE_CLOSED && !(v >= r->lo))
        return 0;
    if (r->hi_end == ISO_RANGE_OPEN ? !(v < r->hi) : r->hi_end == ISO_RANGE_CLOSED && !(v <= r->hi))
        return 0;
    return 1;
}

/* A whole number: decimal, or hex after 0x (so a leading 0 is never octal). */
static int parse_integer(const char *text, double *out)
{
    const char *digits = text + (*text == '-' || *text == '+');
    int base = digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X') ? 16 : 10;
    char *end;
    errno = 0;
    long long v = strtoll(text, &end, base);
    if (end == text || *end != '\0' || errno == ERANGE || !(*digits >= '0' && *digits <= '9'))
        return -1;
    *out = (double)v;
    return 0;
}

static int parse_number(const char *text, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(text, &end);
    if (end == text || *end != '\0' || errno == ERANGE || !isfinite(v))
        return -1;
    *out = v;
    return 0;
}

int iso_range_parse(const iso_range *r, const char *text, double *out, char *why, size_t cap)
{
    char want[128], shown[48];
    size_t n = strlen(text);
    if (n > 40)
        snprintf(shown, sizeof shown, "%.37s...", text);
    else
        snprintf(shown, sizeof shown, "%s", text);
    iso_range_expected(r, want, sizeof want);
    double v;
    if ((r->integer ? parse_integer(text, &v) : parse_number(text, &v)) != 0) {
        snprintf(why, cap, "'%s' is not %s: expected %s", shown,
                 r->integer ? "an integer" : "a number", want);
        return ISO_RANGE_NOT_A_NUMBER;
    }
    if (!iso_range_holds(r, v)) {
        snprintf(why, cap, "'%s' is out of range: expected %s", shown, want);
        return ISO_RANGE_OUTSIDE;
    }
    *out = v;
    return 0;
}
