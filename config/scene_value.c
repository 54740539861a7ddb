/* config/scene_value.c -- typed scalars and one value by its row.
 *
 * A value that has the wrong type is an ISO_EPARSE; one of the right type
 * out of its range is an ISO_EINVAL. Numbers are read and held to their
 * range by iso_range_parse, the check the command line uses too; their
 * ranges come from the row, from the solver's table (iso_solver_range) or,
 * for a device mapping's numbers, from the devices layer
 * (iso_dev_map_check), so scenes and the command line hold them to one
 * table. YAML's null (an empty value, ~, null) is never a value: a key
 * written without one is refused, pointing at the key, so that `recording:
 * ~` is not taken for a file named "~". */
#include "internal.h"

#include <errno.h>
#include <libfyaml.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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

int iso_scene__is_null(scene_ctx *c, fnode *n)
{
    static const char *const nulls[] = {"", "~", "null", "Null", "NULL", NULL};
    if (!n)
        return 1;
    if (!fy_node_is_scalar(n) || fy_node_is_alias(n) || fy_node_get_style(n) != FYNS_PLAIN)
        return 0;
    const char *t = iso_scene__scalar(c, n);
    return t && iso_names_find(nulls, t) >= 0;
}

const char *iso_scene__found(scene_ctx *c, fnode *n, char *buf, size_t cap)
{
    const char *t = iso_scene__scalar(c, n);
    if (iso_scene__is_null(c, n))
        snprintf(buf, cap, "%s", !t || !*t ? "an empty value" : "null");
    else if (t)
        snprintf(buf, cap, "'%.*s%s'", 40, t, strlen(t) > 40 ? "..." : "");
    else
        snprintf(buf, cap, "%s", iso_scene__type_name(n));
    if (t && strcmp(t, "~") == 0 && iso_scene__is_null(c, n))
        snprintf(buf + strlen(buf), cap - strlen(buf), " ('~')");
    return buf;
}

/* Refuses a node that is not a plain scalar where a number goes. */
static int not_scalar(scene_ctx *c, fnode *n, const char *key, const char *want)
{
    char found[80];
    return iso_scene__fail(c, n, ISO_EPARSE, key, "expected %s, found %s", want,
                           iso_scene__found(c, n, found, sizeof found));
}

/* n's text held to r, in iso_range_parse's words. */
static int parse_in(scene_ctx *c, const iso_range *r, fnode *n, const char *key, double *out)
{
    char why[192], want[128];
    const char *t = iso_scene__scalar(c, n);
    if (!t || iso_scene__is_null(c, n))
        return not_scalar(c, n, key, iso_range_expected(r, want, sizeof want));
    int rc = iso_range_parse(r, t, out, why, sizeof why);
    if (rc == 0)
        return ISO_OK;
    return iso_scene__fail(c, n, rc == ISO_RANGE_OUTSIDE ? ISO_EINVAL : ISO_EPARSE, key, "%s", why);
}

int iso_scene__to_double(scene_ctx *c, fnode *n, const char *key, double *out)
{
    static const iso_range any = {0};
    return parse_in(c, &any, n, key, out);
}

int iso_scene__number(scene_ctx *c, const scene_key *k, fnode *n, const char *key, double *out)
{
    iso_range r;
    char why[128];
    iso_scene__range(k, &r);
    int rc = parse_in(c, &r, n, key, out);
    if (rc == ISO_OK && k->dev && iso_dev_map_check(k->dev, *out, why, sizeof why) != 0)
        return iso_scene__fail(c, n, ISO_EINVAL, key, "%s", why);
    return rc;
}

static int to_bool(scene_ctx *c, fnode *n, const char *key, int *out)
{
    static const char *const yes[] = {"true", "yes", "on", NULL};
    static const char *const no[] = {"false", "no", "off", NULL};
    const char *t = iso_scene__scalar(c, n);
    char found[80];
    if (t && iso_names_find(yes, t) >= 0)
        return (*out = 1), ISO_OK;
    if (t && iso_names_find(no, t) >= 0)
        return (*out = 0), ISO_OK;
    return iso_scene__fail(c, n, ISO_EPARSE, key, "expected true or false, found %s",
                           iso_scene__found(c, n, found, sizeof found));
}

int iso_scene__to_enum(scene_ctx *c, fnode *n, const char *key, const char *const *names, int *out)
{
    const char *t = iso_scene__scalar(c, n);
    if (!t || iso_scene__is_null(c, n)) {
        char all[256], found[80];
        iso_names_list(names, ", ", all, sizeof all);
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected one of %s, found %s", all,
                               iso_scene__found(c, n, found, sizeof found));
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
    char found[80];
    if (!t || !*t || iso_scene__is_null(c, n))
        return iso_scene__fail(c, n, ISO_EPARSE, key, "expected a non-empty text, found %s",
                               iso_scene__found(c, n, found, sizeof found));
    if (strlen(t) >= cap)
        return iso_scene__fail(c, n, ISO_EINVAL, key, "longer than %zu characters", cap - 1);
    memcpy(out, t, strlen(t) + 1);
    return ISO_OK;
}

static int to_vec3(scene_ctx *c, fnode *n, const char *key, double v[3])
{
    char found[80];
    if (!n || !fy_node_is_sequence(n) || fy_node_sequence_item_count(n) != 3)
        return iso_scene__fail(
            c, n, ISO_EPARSE, key, "expected a list of 3 numbers [x, y, z], found %s",
            n && fy_node_is_sequence(n) ? "a list of another length"
                                        : iso_scene__found(c, n, found, sizeof found));
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
    const char *t = iso_scene__is_null(c, n) ? NULL : iso_scene__scalar(c, n);
    const char *colon = t ? strrchr(t, ':') : NULL;
    char *end, found[80];
    long p = colon ? strtol(colon + 1, &end, 10) : 0;
    if (!colon || colon == t || colon[1] == '\0' || *end != '\0' || p < 1 || p > 65535 ||
        (size_t)(colon - t) >= cap)
        return iso_scene__fail(c, n, ISO_EPARSE, key,
                               "expected host:port (port 1..65535), found %s",
                               iso_scene__found(c, n, found, sizeof found));
    memcpy(host, t, (size_t)(colon - t));
    host[colon - t] = '\0';
    *port = (int)p;
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Ranges and names                                                          */
/* ------------------------------------------------------------------------ */

int iso_scene__range(const scene_key *k, iso_range *r)
{
    const iso_range *from = k->solver ? iso_solver_range(k->solver) : &k->range;
    memset(r, 0, sizeof *r);
    if (k->dev || !from)
        return 0;
    *r = *from;
    r->integer = k->kind == SK_INT || k->kind == SK_LIST;
    return r->lo_end || r->hi_end;
}

const char *iso_scene__range_text(const scene_key *k, char *buf, size_t cap)
{
    iso_range r;
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
    } else if (iso_scene__range(k, &r)) {
        char text[96];
        iso_range_text(&r, text, sizeof text);
        snprintf(buf, cap, "%s", strncmp(text, "in ", 3) == 0 ? text + 3 : text);
    }
    return buf;
}

const char *iso_scene__expected(const scene_key *k, char *buf, size_t cap)
{
    char names[256], range[96];
    iso_range r;
    if (k->kind == SK_SECTION && k->sub)
        snprintf(buf, cap, "%s", k->sub->what);
    else if (k->type)
        snprintf(buf, cap, "%s", k->type);
    else if ((k->kind == SK_NUMBER || k->kind == SK_INT) && k->dev)
        snprintf(buf, cap, "a value in %s", iso_scene__range_text(k, range, sizeof range));
    else if (k->kind == SK_NUMBER || k->kind == SK_INT) {
        iso_scene__range(k, &r);
        r.integer = k->kind == SK_INT;
        iso_range_expected(&r, buf, cap);
    } else if (k->kind == SK_ENUM)
        snprintf(buf, cap, "one of %s",
                 iso_names_list(iso_scene__names(k), ", ", names, sizeof names));
    else if (k->kind == SK_BOOL)
        snprintf(buf, cap, "true or false");
    else if (k->kind == SK_FILE)
        snprintf(buf, cap, "a file name%s%s", k->word ? " or " : "", k->word ? k->word : "");
    else if (k->kind == SK_PATH)
        snprintf(buf, cap, "a file or folder name");
    else if (k->kind == SK_VEC3)
        snprintf(buf, cap, "a list of 3 numbers [x, y, z]");
    else if (k->kind == SK_LIST)
        snprintf(buf, cap, "a list of %s", k->noun ? k->noun : "values");
    else
        snprintf(buf, cap, "a non-empty text");
    return buf;
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

/* Into a double, int, long, uint16_t or uint8_t by the field's size; the
 * range keeps the value representable (a uint32_t field takes
 * non-negative ints below 2^31, whose bytes are an int's). */
static int read_number(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *out)
{
    double d;
    int rc = iso_scene__number(c, k, v, key, &d);
    if (rc || k->kind == SK_NUMBER) {
        if (rc == ISO_OK)
            memcpy(out, &d, sizeof d);
        return rc;
    }
    long l = (long)d;
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

/* A file or folder to write: resolved, and unless parsing only, in a
 * folder that exists and may be written, so that a run fails here, before
 * it starts, rather than when it first writes. */
static int read_path(scene_ctx *c, const scene_key *k, fnode *v, const char *key, char *out)
{
    char name[ISO_SCENE_PATH_MAX], dir[ISO_SCENE_PATH_MAX];
    int rc = to_string(c, v, key, name, sizeof name);
    if (rc == ISO_OK && resolve(c->s, name, out, k->size) != 0)
        rc = iso_scene__fail(c, v, ISO_EINVAL, key, "path too long");
    if (rc != ISO_OK || !c->check_files)
        return rc;
    snprintf(dir, sizeof dir, "%s", out);
    char *slash = strrchr(dir, '/');
    while (slash && slash > dir && slash[1] == '\0') { /* "frames/" names frames */
        *slash = '\0';
        slash = strrchr(dir, '/');
    }
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else
        slash[slash == dir] = '\0'; /* "/x" is in "/" */
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return iso_scene__fail(c, v, ISO_EIO, key,
                               "cannot write '%s': folder '%s' does not exist (relative names "
                               "start at the scene's folder)",
                               out, dir);
    if (access(dir, W_OK | X_OK) != 0)
        return iso_scene__fail(c, v, ISO_EIO, key, "cannot write '%s': folder '%s': %s", out, dir,
                               strerror(errno));
    return ISO_OK;
}

/* A key written without a value: refused at the key, with what it takes
 * and how to get its default. */
static int refuse_null(scene_ctx *c, const scene_key *k, fnode *v, const char *key)
{
    char want[384], found[80], hint[200] = "";
    iso_scene__expected(k, want, sizeof want);
    if (k->flags & SK_REQUIRED)
        snprintf(hint, sizeof hint, " (the key is required)");
    else if (k->dflt && !(k->flags & SK_ONE_OF))
        snprintf(hint, sizeof hint, "; leave the key out for its default (%s)", k->dflt);
    return iso_scene__fail(c, v, ISO_EPARSE, key, "expected %s, found %s%s", want,
                           iso_scene__found(c, v, found, sizeof found), hint);
}

int iso_scene__read(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    void *at = (char *)obj + k->off;
    if (iso_scene__is_null(c, v))
        return refuse_null(c, k, v, key);
    if (k->store)
        return k->store(c, k, v, key, obj);
    switch (k->kind) {
    case SK_NUMBER:
    case SK_INT: return read_number(c, k, v, key, at);
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
