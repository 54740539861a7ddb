/* common/iso_json.c -- see iso_json.h. */
#include "iso_json.h"

#include <math.h>
#include <string.h>

/* Quotes, backslashes and control characters escaped; other bytes (UTF-8
 * included) pass as they are. */
static void escaped(FILE *f, const char *s)
{
    fputc('"', f);
    for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
        if (*c == '"' || *c == '\\')
            fprintf(f, "\\%c", *c);
        else if (*c == '\n')
            fputs("\\n", f);
        else if (*c < 0x20)
            fprintf(f, "\\u%04x", *c);
        else
            fputc(*c, f);
    }
    fputc('"', f);
}

/* The separator before a value and its key, if any. */
static void lead(iso_json *j, const char *key)
{
    if (j->depth > 0 && j->items[j->depth - 1]++ > 0)
        fputs(", ", j->f);
    if (key) {
        escaped(j->f, key);
        fputs(": ", j->f);
    }
}

static void open_as(iso_json *j, const char *key, char open, char close)
{
    if (j->depth >= ISO_JSON_MAX_DEPTH) {
        j->too_deep++; /* a caller bug: nothing opens, and its close pairs with it */
        return;
    }
    lead(j, key);
    fputc(open, j->f);
    j->close[j->depth] = close;
    j->items[j->depth] = 0;
    j->depth++;
}

void iso_json_begin(iso_json *j, FILE *f)
{
    memset(j, 0, sizeof *j);
    j->f = f;
    open_as(j, NULL, '{', '}');
}

int iso_json_end(iso_json *j)
{
    while (j->depth > 0)
        iso_json_close(j);
    fputc('\n', j->f);
    return ferror(j->f) ? -1 : 0;
}

void iso_json_object(iso_json *j, const char *key)
{
    open_as(j, key, '{', '}');
}

void iso_json_array(iso_json *j, const char *key)
{
    open_as(j, key, '[', ']');
}

void iso_json_close(iso_json *j)
{
    if (j->too_deep > 0)
        j->too_deep--;
    else if (j->depth > 0)
        fputc(j->close[--j->depth], j->f);
}

void iso_json_number(iso_json *j, const char *key, double v)
{
    lead(j, key);
    if (isfinite(v))
        fprintf(j->f, "%.17g", v);
    else
        fputs("null", j->f);
}

void iso_json_int(iso_json *j, const char *key, long long v)
{
    lead(j, key);
    fprintf(j->f, "%lld", v);
}

void iso_json_bool(iso_json *j, const char *key, int v)
{
    lead(j, key);
    fputs(v ? "true" : "false", j->f);
}

void iso_json_string(iso_json *j, const char *key, const char *s)
{
    lead(j, key);
    if (s)
        escaped(j->f, s);
    else
        fputs("null", j->f);
}

/* An integer member (int, long, uint32_t, uint64_t or an int read as a bool). */
static long long member_int(const char *at, iso_json_type type)
{
    int v;
    long l;
    uint32_t u;
    uint64_t u64;
    if (type == ISO_JSON_LONG)
        return memcpy(&l, at, sizeof l), l;
    if (type == ISO_JSON_U64)
        return memcpy(&u64, at, sizeof u64), (long long)u64;
    if (type == ISO_JSON_U32)
        return memcpy(&u, at, sizeof u), u;
    return memcpy(&v, at, sizeof v), v;
}

void iso_json_fields(iso_json *j, const void *base, const iso_json_field *f, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        const char *at = (const char *)base + f[i].at;
        double d;
        switch (f[i].type) {
        case ISO_JSON_TEXT: iso_json_string(j, f[i].key, at); break;
        case ISO_JSON_DOUBLE:
            memcpy(&d, at, sizeof d);
            iso_json_number(j, f[i].key, d);
            break;
        case ISO_JSON_BOOL: iso_json_bool(j, f[i].key, member_int(at, f[i].type) != 0); break;
        default: iso_json_int(j, f[i].key, member_int(at, f[i].type)); break;
        }
    }
}
