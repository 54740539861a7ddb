/* config/scene_value.c -- typed scalars and one value by its row.
 *
 * A value that has the wrong type is an ISO_EPARSE; one of the right type
 * out of its range is an ISO_EINVAL. Ranges come from the row, or for a
 * device mapping's numbers from the devices layer (iso_dev_map_check), so
 * scenes and the command line hold them to one table. */
#include "internal.h"

#include <errno.h>
#include <libfyaml.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "iso_names.h"

/* ------------------------------------------------------------------------ */
/* Scalars                                                                   */
/* ------------------------------------------------------------------------ */

const char *iso_scene__scalar(scene_ctx *c, fnode *n)
{
    if (!n || !fy_node_is_scalar(n) || fy_node_is_alias(n))
        return NULL;
    size_t len = 0;
    const char *t = fy_node_get_scalar(n, &len);
    if (!t)
        return NULL;
    char *buf = c->text[c->next++ % 8];
    if (len >= ISO_SCENE_PATH_MAX)
        len = ISO_SCENE_PATH_MAX - 1; /* longer than any field: refused by to_string */
    memcpy(buf, t, len);
    buf[len] = '\0';
    return buf;
}

int iso_scene__to_double(scene_ctx *c, fnode *n, const char *key, double *out)
{
    const char *t = iso_scene__scalar(c, n);
    if (!t)
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected a number, found %s",
                               iso_scene__type_name(n));
    char *end;
    errno = 0;
    double v = strtod(t, &end);
    if (end == t || *end != '\0' || errno == ERANGE || !isfinite(v))
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected a finite number, found '%s'", t);
    *out = v;
    return ISO_OK;
}

int iso_scene__to_long(scene_ctx *c, fnode *n, const char *key, long lo, long hi, long *out)
{
    const char *t = iso_scene__scalar(c, n);
    if (!t)
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected an integer, found %s",
                               iso_scene__type_name(n));
    char *end;
    errno = 0;
    long v = strtol(t, &end, 0);
    if (end == t || *end != '\0' || errno == ERANGE)
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected an integer, found '%s'", t);
    if (v < lo || v > hi)
        return iso_scene__fail(c, n, ISO_EINVAL, key,
                               "expected an integer in [%ld, %ld], found %ld", lo, hi, v);
    *out = v;
    return ISO_OK;
}

static int to_bool(scene_ctx *c, fnode *n, const char *key, int *out)
{
    static const char *const yes[] = {"true", "yes", "on", NULL};
    static const char *const no[] = {"false", "no", "off", NULL};
    const char *t = iso_scene__scalar(c, n);
    if (t && iso_names_find(yes, t) >= 0)
        return (*out = 1), ISO_OK;
    if (t && iso_names_find(no, t) >= 0)
        return (*out = 0), ISO_OK;
    return iso_scene__fail(c, n, ISO_EPARSE, key, "expected true or false, found %s%s%s",
                           t ? "'" : "", t ? t : iso_scene__type_name(n), t ? "'" : "");
}

int iso_scene__to_enum(scene_ctx *c, fnode *n, const char *key, const char *const *names, int *out)
{
    const char *t = iso_scene__scalar(c, n);
    if (!t) {
        char all[256];
        iso_names_list(names, ", ", all, sizeof all);
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected one of %s, found %s", all,
                               iso_scene__type_name(n));
    }
    if ((*out = iso_names_find(names, t)) >= 0)
        return ISO_OK;
    char what[300];
    snprintf(what, sizeof what, "unknown value '%.250s'", t);
    return iso_scene__refuse_word(c, n, key, what, t, names, "expected one of");
}

static int to_string(scene_ctx *c, fnode *n, const char *key, char *out, size_t cap)
{
    const char *t = iso_scene__scalar(c, n);
    if (!t || !*t)
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected a non-empty string, found %s",
                               t ? "an empty one" : iso_scene__type_name(n));
    if (strlen(t) >= cap)
        return iso_scene__fail(c, n, ISO_EINVAL, key, "longer than %zu characters", cap - 1);
    memcpy(out, t, strlen(t) + 1);
    return ISO_OK;
}

static int to_vec3(scene_ctx *c, fnode *n, const char *key, double v[3])
{
    if (!n || !fy_node_is_sequence(n) || fy_node_sequence_item_count(n) != 3)
        return iso_scene__fail(c, n, ISO_EPARSE, key,
                               "expected a list of 3 numbers [x, y, z], found %s",
                               iso_scene__type_name(n));
    void *it = NULL;
    for (int i = 0; i < 3; i++) {
        int rc = iso_scene__to_double(c, fy_node_sequence_iterate(n, &it), key, &v[i]);
        if (rc)
            return rc;
    }
    return ISO_OK;
}

/* Joins a name from the scene with the scene's folder (absolute names stay). */
static int resolve(const iso_scene *s, const char *name, char *out, size_t cap)
{
    int n = name[0] == '/' || !s->dir[0] ? snprintf(out, cap, "%s", name)
                                         : snprintf(out, cap, "%s/%s", s->dir, name);
    return n < 0 || (size_t)n >= cap ? -1 : 0;
}

int iso_scene__to_file(scene_ctx *c, fnode *n, const char *key, char *out, size_t cap)
{
    char name[ISO_SCENE_PATH_MAX];
    int rc = to_string(c, n, key, name, sizeof name);
    if (rc)
        return rc;
    if (resolve(c->s, name, out, cap) != 0)
        return iso_scene__fail(c, n, ISO_EINVAL, key, "path '%s' is too long", name);
    if (!c->check_files)
        return ISO_OK;
    struct stat st;
    if (stat(out, &st) != 0)
        return iso_scene__fail(c, n, ISO_EIO, key,
                               "file '%s' does not exist (%s; relative names start at the "
                               "scene's folder)",
                               out, strerror(errno));
    if (!S_ISREG(st.st_mode))
        return iso_scene__fail(c, n, ISO_EIO, key, "'%s' is not a regular file", out);
    return ISO_OK;
}

int iso_scene__host_port(scene_ctx *c, fnode *n, const char *key, char *host, size_t cap, int *port)
{
    const char *t = iso_scene__scalar(c, n);
    const char *colon = t ? strrchr(t, ':') : NULL;
    char *end;
    long p = colon ? strtol(colon + 1, &end, 10) : 0;
    if (!colon || colon == t || colon[1] == '\0' || *end != '\0' || p < 1 || p > 65535 ||
        (size_t)(colon - t) >= cap)
        return iso_scene__fail(c, n, ISO_EPARSE, key,
                               "expected host:port (port 1..65535), found %s%s%s", t ? "'" : "",
                               t ? t : iso_scene__type_name(n), t ? "'" : "");
    memcpy(host, t, (size_t)(colon - t));
    host[colon - t] = '\0';
    *port = (int)p;
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Ranges and names                                                          */
/* ------------------------------------------------------------------------ */

const char *iso_scene__range_text(const scene_key *k, char *buf, size_t cap)
{
    buf[0] = '\0';
    if (k->dev) {
        /* devices/ says it in its own message, for a value never in range */
        char why[128];
        iso_dev_map_check(k->dev, NAN, why, sizeof why);
        const char *from = strstr(why, "expected a value "), *to = strstr(why, ", found");
        if (from && to && to > from) {
            from += strlen("expected a value ");
            from += strncmp(from, "in ", 3) == 0 ? 3 : 0;
            snprintf(buf, cap, "%.*s", (int)(to - from), from);
        }
    } else if (k->ranged && isinf(k->hi)) {
        snprintf(buf, cap, "%s %g", k->lo_open ? ">" : ">=", k->lo);
    } else if (k->ranged && k->kind == SK_NUMBER) {
        snprintf(buf, cap, "%c%g, %g%c", k->lo_open ? '(' : '[', k->lo, k->hi,
                 k->hi_open ? ')' : ']');
    } else if (k->ranged) {
        snprintf(buf, cap, "[%ld, %ld]", (long)k->lo, (long)k->hi);
    }
    return buf;
}

int iso_scene__in_range(scene_ctx *c, const scene_key *k, fnode *n, const char *key, double v)
{
    char why[128], range[64];
    if (k->dev) {
        if (iso_dev_map_check(k->dev, v, why, sizeof why) != 0)
            return iso_scene__fail(c, n, ISO_EINVAL, key, "%s", why);
        return ISO_OK;
    }
    if (!k->ranged ||
        ((k->lo_open ? v > k->lo : v >= k->lo) && (k->hi_open ? v < k->hi : v <= k->hi)))
        return ISO_OK;
    iso_scene__range_text(k, range, sizeof range);
    return iso_scene__fail(c, n, ISO_EINVAL, key, "expected a value %s%s, found %g",
                           isinf(k->hi) ? "" : "in ", range, v);
}

const char *const *iso_scene__names(const scene_key *k)
{
    return k->names ? k->names : k->names_fn();
}

int iso_scene__in_words(const char *list, const char *word)
{
    size_t n = strlen(word);
    for (const char *p = list; (p = strstr(p, word)) != NULL; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0'))
            return 1;
    return 0;
}

const char *iso_scene__words_list(const char *words, const char *last, char *buf, size_t cap)
{
    char copy[256], *save = NULL;
    const char *names[16];
    int n = 0;
    snprintf(copy, sizeof copy, "%s", words);
    for (char *w = strtok_r(copy, " ", &save); w && n < 15; w = strtok_r(NULL, " ", &save))
        names[n++] = w;
    names[n] = NULL;
    return iso_names_list(names, last, buf, cap);
}

/* ------------------------------------------------------------------------ */
/* One value by its row                                                      */
/* ------------------------------------------------------------------------ */

static int read_number(scene_ctx *c, const scene_key *k, fnode *v, const char *key, double *out)
{
    int rc = iso_scene__to_double(c, v, key, out);
    return rc ? rc : iso_scene__in_range(c, k, v, key, *out);
}

/* Into an int, long, uint16_t or uint8_t by the field's size; the range
 * keeps the value representable (a uint32_t field takes non-negative ints
 * below 2^31, whose bytes are an int's). */
static int read_int(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *out)
{
    long l;
    int rc = iso_scene__to_long(c, v, key, (long)k->lo, (long)k->hi, &l);
    if (rc)
        return rc;
    int i = (int)l;
    uint16_t u16 = (uint16_t)l;
    uint8_t u8 = (uint8_t)l;
    const void *from = k->size == sizeof l     ? (const void *)&l
                       : k->size == sizeof i   ? (const void *)&i
                       : k->size == sizeof u16 ? (const void *)&u16
                                               : (const void *)&u8;
    memcpy(out, from, k->size);
    return ISO_OK;
}

static int read_enum(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *out)
{
    const char *const *names = iso_scene__names(k);
    int i, rc = iso_scene__to_enum(c, v, key, names, &i);
    if (rc)
        return rc;
    if (k->flags & SK_AS_TEXT)
        return to_string(c, v, key, out, k->size);
    i += k->first;
    memcpy(out, &i, sizeof i);
    return ISO_OK;
}

static int read_file(scene_ctx *c, const scene_key *k, fnode *v, const char *key, char *out)
{
    const char *t = iso_scene__scalar(c, v);
    if (k->word && t && strcmp(t, k->word) == 0) {
        snprintf(out, k->size, "%s", k->flags & SK_WORD_EMPTY ? "" : k->word);
        return ISO_OK;
    }
    return iso_scene__to_file(c, v, key, out, k->size);
}

/* A file or folder to write: resolved only. */
static int read_path(scene_ctx *c, const scene_key *k, fnode *v, const char *key, char *out)
{
    char name[ISO_SCENE_PATH_MAX];
    int rc = to_string(c, v, key, name, sizeof name);
    if (rc == ISO_OK && resolve(c->s, name, out, k->size) != 0)
        rc = iso_scene__fail(c, v, ISO_EINVAL, key, "path too long");
    return rc;
}

int iso_scene__read(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    void *at = (char *)obj + k->off;
    if (k->store)
        return k->store(c, k, v, key, obj);
    switch (k->kind) {
    case SK_NUMBER: return read_number(c, k, v, key, at);
    case SK_INT: return read_int(c, k, v, key, at);
    case SK_BOOL: return to_bool(c, v, key, at);
    case SK_STRING: return to_string(c, v, key, at, k->size);
    case SK_FILE: return read_file(c, k, v, key, at);
    case SK_PATH: return read_path(c, k, v, key, at);
    case SK_ENUM: return read_enum(c, k, v, key, at);
    case SK_VEC3: return to_vec3(c, v, key, at);
    case SK_LIST: return iso_scene__read_list(c, k, v, key, obj);
    case SK_SECTION: return iso_scene__walk(c, k->sub, v, key, at, -1, 0);
    case SK_MAP: break;
    }
    return iso_err_set(c->err, ISO_EINVAL, -1, "%s: no reader for key '%s' (a schema bug)", c->file,
                       key);
}
