/* config/scene.c -- reading a scene file (YAML, libfyaml) into iso_scene.
 *
 * The walk is schema-first: every mapping is checked against the keys it may
 * hold before any value is read, so a typo is reported as an unknown key
 * (with the nearest known one) rather than as a missing one. Every message
 * starts with FILE:LINE:COL and the dotted key path, the way a compiler
 * reports, so an editor can jump to it. libfyaml's own diagnostics are
 * collected, never printed, and the first one becomes the error. */
#include "internal.h"

#include <errno.h>
#include <libfyaml.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "iso_actuators.h" /* iso_act_emu_names */
#include "iso_file.h"
#include "iso_names.h"

/* Key paths ("regions.handles[0].select[2].box.min") are built into fixed
 * buffers for messages; a path longer than KEY_MAX is cut, by design. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wformat-truncation"
#endif

/* ------------------------------------------------------------------------ */
/* Context and messages                                                      */
/* ------------------------------------------------------------------------ */

typedef struct sctx {
    iso_scene *s;
    const char *file; /* the scene's name in messages */
    iso_err *err;
    int check_files; /* 0 with ISO_SCENE_PARSE_ONLY */
    /* Scalar text, copied: libfyaml 0.7.12's fy_node_get_scalar0() leaks
     * the NUL-terminated copy it makes of a scalar in several chunks
     * (found by fuzz_scene), so we copy from fy_node_get_scalar(). A ring,
     * because a caller may hold a few at once. */
    char text[8][ISO_SCENE_PATH_MAX];
    unsigned next;
} sctx;

typedef struct fy_node fnode;

/* Where a node starts. Collections have no public start token in libfyaml
 * 0.7, so they report their first scalar (a mapping's first key). */
static void mark_of(fnode *n, int *line, int *col)
{
    *line = 1;
    *col = 1;
    for (int depth = 0; n && depth < 64; depth++) {
        if (fy_node_is_scalar(n)) {
            struct fy_token *t = fy_node_get_scalar_token(n);
            const struct fy_mark *m = t ? fy_token_start_mark(t) : NULL;
            if (m) {
                *line = m->line + 1;
                *col = m->column + 1;
            }
            return;
        }
        void *it = NULL;
        if (fy_node_is_mapping(n)) {
            struct fy_node_pair *p = fy_node_mapping_iterate(n, &it);
            n = p ? fy_node_pair_key(p) : NULL;
        } else if (fy_node_is_sequence(n)) {
            n = fy_node_sequence_iterate(n, &it);
        } else {
            return;
        }
    }
}

static int fail(sctx *c, fnode *at, int code, const char *key, const char *fmt, ...)
    ISO_PRINTF(5, 6);
static int fail(sctx *c, fnode *at, int code, const char *key, const char *fmt, ...)
{
    int line, col;
    mark_of(at, &line, &col);
    char what[384];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return iso_err_set(c->err, code, line, "%s:%d:%d: %s: %s", c->file, line, col, key, what);
}

/* "parent.name" or "name" into buf. */
static const char *join(char *buf, size_t cap, const char *parent, const char *name)
{
    if (parent && *parent)
        snprintf(buf, cap, "%s.%s", parent, name);
    else
        snprintf(buf, cap, "%s", name);
    return buf;
}

#define KEY_MAX 256

int iso_scene__distance(const char *a, const char *b)
{
    size_t la = strlen(a), lb = strlen(b);
    if (la > 64 || lb > 64)
        return 255;
    int row[65];
    for (size_t j = 0; j <= lb; j++)
        row[j] = (int)j;
    for (size_t i = 1; i <= la; i++) {
        int prev = row[0];
        row[0] = (int)i;
        for (size_t j = 1; j <= lb; j++) {
            int cur = row[j];
            int sub = prev + (a[i - 1] != b[j - 1]);
            int del = row[j] + 1, ins = row[j - 1] + 1;
            row[j] = sub < del ? (sub < ins ? sub : ins) : (del < ins ? del : ins);
            prev = cur;
        }
    }
    return row[lb];
}

/* The nearest of `known` to `word`, or NULL when none is close (more than
 * half the word's length away: no suggestion beats a silly one). */
static const char *nearest(const char *word, const char *const *known)
{
    const char *best = NULL;
    int bd = 255;
    for (size_t i = 0; known[i]; i++) {
        int d = iso_scene__distance(word, known[i]);
        if (d < bd) {
            bd = d;
            best = known[i];
        }
    }
    int len = (int)strlen(word);
    return best && bd <= (len > 4 ? len / 2 : 2) ? best : NULL;
}

static void list_keys(char *buf, size_t cap, const char *const *known)
{
    iso_names_list(known, ", ", buf, cap);
}

static const char *scalar(sctx *c, fnode *n);

static const char *type_name(fnode *n)
{
    if (!n)
        return "nothing";
    if (fy_node_is_mapping(n))
        return "a mapping";
    if (fy_node_is_sequence(n))
        return "a list";
    if (fy_node_is_alias(n))
        return "an alias";
    return "a scalar";
}

/* ------------------------------------------------------------------------ */
/* Typed access                                                              */
/* ------------------------------------------------------------------------ */

static int want_map(sctx *c, fnode *n, const char *key, const char *what)
{
    if (n && fy_node_is_mapping(n))
        return ISO_OK;
    return fail(c, n, ISO_EPARSE, key, "expected %s, found %s", what, type_name(n));
}

/* Checks that every key of map is a plain scalar among `known`. */
static int check_keys(sctx *c, fnode *map, const char *path, const char *const *known)
{
    void *it = NULL;
    struct fy_node_pair *p;
    while ((p = fy_node_mapping_iterate(map, &it)) != NULL) {
        fnode *k = fy_node_pair_key(p);
        const char *ks = scalar(c, k);
        if (!ks)
            return fail(c, k ? k : map, ISO_EPARSE, path && *path ? path : "(top level)",
                        "expected a plain key, found %s", type_name(k));
        size_t i;
        for (i = 0; known[i]; i++)
            if (strcmp(known[i], ks) == 0)
                break;
        if (known[i])
            continue;
        char key[KEY_MAX], all[512];
        join(key, sizeof key, path, ks);
        list_keys(all, sizeof all, known);
        const char *near = nearest(ks, known);
        if (near)
            return fail(c, k, ISO_EPARSE, key,
                        "unknown key; did you mean '%s'? (expected one of: %s)", near, all);
        return fail(c, k, ISO_EPARSE, key, "unknown key (expected one of: %s)", all);
    }
    return ISO_OK;
}

static fnode *get(fnode *map, const char *name)
{
    return fy_node_mapping_lookup_by_string(map, name, strlen(name));
}

/* The text of a scalar (NULL for collections and aliases). */
static const char *scalar(sctx *c, fnode *n)
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

static int to_double(sctx *c, fnode *n, const char *key, double *out)
{
    const char *t = scalar(c, n);
    if (!t)
        return fail(c, n, ISO_EPARSE, key, "expected a number, found %s", type_name(n));
    char *end;
    errno = 0;
    double v = strtod(t, &end);
    if (end == t || *end != '\0' || errno == ERANGE || !isfinite(v))
        return fail(c, n, ISO_EPARSE, key, "expected a finite number, found '%s'", t);
    *out = v;
    return ISO_OK;
}

static int to_long(sctx *c, fnode *n, const char *key, long lo, long hi, long *out)
{
    const char *t = scalar(c, n);
    if (!t)
        return fail(c, n, ISO_EPARSE, key, "expected an integer, found %s", type_name(n));
    char *end;
    errno = 0;
    long v = strtol(t, &end, 0);
    if (end == t || *end != '\0' || errno == ERANGE)
        return fail(c, n, ISO_EPARSE, key, "expected an integer, found '%s'", t);
    if (v < lo || v > hi)
        return fail(c, n, ISO_EINVAL, key, "expected an integer in [%ld, %ld], found %ld", lo, hi,
                    v);
    *out = v;
    return ISO_OK;
}

static int to_int(sctx *c, fnode *n, const char *key, long lo, long hi, int *out)
{
    long v = 0;
    int rc = to_long(c, n, key, lo, hi, &v);
    if (rc == ISO_OK)
        *out = (int)v;
    return rc;
}

static int to_bool(sctx *c, fnode *n, const char *key, int *out)
{
    static const char *const yes[] = {"true", "yes", "on", NULL};
    static const char *const no[] = {"false", "no", "off", NULL};
    const char *t = scalar(c, n);
    for (size_t i = 0; t && yes[i]; i++)
        if (strcmp(t, yes[i]) == 0)
            return (*out = 1), ISO_OK;
    for (size_t i = 0; t && no[i]; i++)
        if (strcmp(t, no[i]) == 0)
            return (*out = 0), ISO_OK;
    return fail(c, n, ISO_EPARSE, key, "expected true or false, found %s%s%s", t ? "'" : "",
                t ? t : type_name(n), t ? "'" : "");
}

/* One of `names` (NULL-terminated); *out is its index. */
static int to_enum(sctx *c, fnode *n, const char *key, const char *const *names, int *out)
{
    const char *t = scalar(c, n);
    char all[256];
    list_keys(all, sizeof all, names);
    if (!t)
        return fail(c, n, ISO_EPARSE, key, "expected one of %s, found %s", all, type_name(n));
    for (int i = 0; names[i]; i++)
        if (strcmp(t, names[i]) == 0)
            return (*out = i), ISO_OK;
    const char *near = nearest(t, names);
    if (near)
        return fail(c, n, ISO_EPARSE, key,
                    "unknown value '%s'; did you mean '%s'? (expected one of %s)", t, near, all);
    return fail(c, n, ISO_EPARSE, key, "unknown value '%s' (expected one of %s)", t, all);
}

static int to_string(sctx *c, fnode *n, const char *key, char *out, size_t cap)
{
    const char *t = scalar(c, n);
    if (!t || !*t)
        return fail(c, n, ISO_EPARSE, key, "expected a non-empty string, found %s",
                    t ? "an empty one" : type_name(n));
    if (strlen(t) >= cap)
        return fail(c, n, ISO_EINVAL, key, "longer than %zu characters", cap - 1);
    memcpy(out, t, strlen(t) + 1);
    return ISO_OK;
}

static int to_vec3(sctx *c, fnode *n, const char *key, double v[3])
{
    if (!n || !fy_node_is_sequence(n) || fy_node_sequence_item_count(n) != 3)
        return fail(c, n, ISO_EPARSE, key, "expected a list of 3 numbers [x, y, z], found %s",
                    type_name(n));
    void *it = NULL;
    for (int i = 0; i < 3; i++) {
        int rc = to_double(c, fy_node_sequence_iterate(n, &it), key, &v[i]);
        if (rc)
            return rc;
    }
    return ISO_OK;
}

/* SCENES.md forbids anchors and aliases: a scene says each value where it
 * applies. Walks the whole document first, so an anchor that nothing uses
 * is refused too, and an alias is named as one rather than as the value it
 * stands for. Deeper than any scene goes, the schema walk refuses it. */
static int no_anchors(sctx *c, fnode *n, const char *path, int depth)
{
    const char *at = path && *path ? path : "(top level)";
    size_t len = 0;
    struct fy_anchor *a = n ? fy_node_get_anchor(n) : NULL;
    if (a) {
        const char *t = fy_anchor_get_text(a, &len);
        return fail(c, n, ISO_EPARSE, at,
                    "anchors ('&%.*s') are not accepted in scene files; write the value out",
                    (int)(t ? len : 0), t ? t : "");
    }
    if (n && fy_node_is_alias(n)) {
        const char *t = fy_node_get_scalar(n, &len);
        return fail(c, n, ISO_EPARSE, at,
                    "aliases ('*%.*s') are not accepted in scene files; write the value out",
                    (int)(t ? len : 0), t ? t : "");
    }
    if (!n || depth > 64)
        return ISO_OK;
    void *it = NULL;
    char key[KEY_MAX];
    int rc = ISO_OK;
    if (fy_node_is_mapping(n)) {
        struct fy_node_pair *p;
        while (rc == ISO_OK && (p = fy_node_mapping_iterate(n, &it)) != NULL) {
            const char *ks = scalar(c, fy_node_pair_key(p));
            join(key, sizeof key, path, ks ? ks : "?");
            rc = no_anchors(c, fy_node_pair_key(p), key, depth + 1);
            if (rc == ISO_OK)
                rc = no_anchors(c, fy_node_pair_value(p), key, depth + 1);
        }
    } else if (fy_node_is_sequence(n)) {
        fnode *item;
        for (int i = 0; rc == ISO_OK && (item = fy_node_sequence_iterate(n, &it)) != NULL; i++) {
            snprintf(key, sizeof key, "%s[%d]", path, i);
            rc = no_anchors(c, item, key, depth + 1);
        }
    }
    return rc;
}

static int missing(sctx *c, fnode *map, const char *path, const char *name, const char *what)
{
    char key[KEY_MAX];
    return fail(c, map, ISO_EPARSE, join(key, sizeof key, path, name),
                "missing required key (expected %s)", what);
}

/* Resolves a file name from the scene and, unless parsing only, checks
 * that it is a readable regular file. */
static int file_at(sctx *c, fnode *n, const char *key, char *out, size_t cap)
{
    char name[ISO_SCENE_PATH_MAX];
    int rc = to_string(c, n, key, name, sizeof name);
    if (rc)
        return rc;
    if (iso_scene__resolve(c->s, name, out, cap) != 0)
        return fail(c, n, ISO_EINVAL, key, "path '%s' is too long", name);
    if (!c->check_files)
        return ISO_OK;
    struct stat st;
    if (stat(out, &st) != 0)
        return fail(c, n, ISO_EIO, key,
                    "file '%s' does not exist (%s; relative names start at the "
                    "scene's folder)",
                    out, strerror(errno));
    if (!S_ISREG(st.st_mode))
        return fail(c, n, ISO_EIO, key, "'%s' is not a regular file", out);
    return ISO_OK;
}

int iso_scene__resolve(const iso_scene *s, const char *name, char *out, size_t cap)
{
    int n = name[0] == '/' || !s->dir[0] ? snprintf(out, cap, "%s", name)
                                         : snprintf(out, cap, "%s/%s", s->dir, name);
    return n < 0 || (size_t)n >= cap ? -1 : 0;
}

/* ------------------------------------------------------------------------ */
/* mesh                                                                      */
/* ------------------------------------------------------------------------ */

static int parse_mesh(sctx *c, fnode *n)
{
    static const char *const keys[] = {"path",      "shape",          "resolution",
                                       "benchmark", "fallback_shape", NULL};
    iso_scene_mesh_src *m = &c->s->mesh_src;
    int rc;
    mark_of(n, &m->line, &m->col);
    if (n && fy_node_is_scalar(n)) {
        m->kind = ISO_SCENE_MESH_FILE;
        return file_at(c, n, "mesh", m->path, sizeof m->path);
    }
    if ((rc = want_map(c, n, "mesh",
                       "a mesh file name or a mapping with path, shape or benchmark")) ||
        (rc = check_keys(c, n, "mesh", keys)))
        return rc;
    fnode *path = get(n, "path"), *shape = get(n, "shape"), *bench = get(n, "benchmark");
    int count = (path != NULL) + (shape != NULL) + (bench != NULL);
    if (count != 1)
        return fail(c, n, ISO_EPARSE, "mesh",
                    "expected exactly one of path, shape or benchmark, found %d", count);
    if (path) {
        m->kind = ISO_SCENE_MESH_FILE;
        if ((rc = file_at(c, path, "mesh.path", m->path, sizeof m->path)))
            return rc;
    } else if (shape) {
        m->kind = ISO_SCENE_MESH_SHAPE;
        if ((rc = to_enum(c, shape, "mesh.shape", iso_shape_names(), &(int){0})) ||
            (rc = to_string(c, shape, "mesh.shape", m->shape, sizeof m->shape)))
            return rc;
    } else {
        static const char *const problems[] = {"bumpplane", "cylinder", "bar", "cactus", NULL};
        m->kind = ISO_SCENE_MESH_BENCHMARK;
        if ((rc = to_enum(c, bench, "mesh.benchmark", problems, &(int){0})) ||
            (rc = to_string(c, bench, "mesh.benchmark", m->benchmark, sizeof m->benchmark)))
            return rc;
    }
    fnode *fb = get(n, "fallback_shape"), *res = get(n, "resolution");
    if (fb && !bench)
        return fail(c, fb, ISO_EPARSE, "mesh.fallback_shape", "only goes with mesh.benchmark");
    if (fb && ((rc = to_enum(c, fb, "mesh.fallback_shape", iso_shape_names(), &(int){0})) ||
               (rc = to_string(c, fb, "mesh.fallback_shape", m->fallback_shape,
                               sizeof m->fallback_shape))))
        return rc;
    if (res && path)
        return fail(c, res, ISO_EPARSE, "mesh.resolution",
                    "only goes with a shape or a fallback_shape");
    if (res && (rc = to_int(c, res, "mesh.resolution", 0, 4096, &m->resolution)))
        return rc;
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* regions                                                                   */
/* ------------------------------------------------------------------------ */

static int parse_sel_item(sctx *c, fnode *n, const char *key, iso_scene_sel *sel)
{
    static const char *const keys[] = {"vertices", "box", "sphere", "beyond", NULL};
    int rc;
    if ((rc = want_map(c, n, key, "a selection: vertices, box, sphere or beyond")) ||
        (rc = check_keys(c, n, key, keys)))
        return rc;
    if (fy_node_mapping_item_count(n) != 1)
        return fail(c, n, ISO_EPARSE, key,
                    "expected exactly one of vertices, box, sphere or beyond per list item");
    mark_of(n, &sel->line, &sel->col);
    char sub[KEY_MAX], sub2[KEY_MAX];
    fnode *v;
    if ((v = get(n, "vertices")) != NULL) {
        join(sub, sizeof sub, key, "vertices");
        sel->kind = ISO_SCENE_SEL_VERTICES;
        if (!fy_node_is_sequence(v) || fy_node_sequence_item_count(v) < 1)
            return fail(c, v, ISO_EPARSE, sub, "expected a non-empty list of vertex indices");
        int cnt = fy_node_sequence_item_count(v);
        sel->vertices = malloc((size_t)cnt * sizeof *sel->vertices);
        if (!sel->vertices)
            return iso_err_set(c->err, ISO_ENOMEM, -1, "out of memory");
        void *it = NULL;
        for (int i = 0; i < cnt; i++) {
            if ((rc = to_int(c, fy_node_sequence_iterate(v, &it), sub, 0, 1L << 30,
                             &sel->vertices[i])))
                return rc;
            sel->n_vertices = i + 1;
        }
        return ISO_OK;
    }
    if ((v = get(n, "box")) != NULL) {
        static const char *const bk[] = {"min", "max", NULL};
        join(sub, sizeof sub, key, "box");
        sel->kind = ISO_SCENE_SEL_BOX;
        if ((rc = want_map(c, v, sub, "{min: [x, y, z], max: [x, y, z]}")) ||
            (rc = check_keys(c, v, sub, bk)))
            return rc;
        if (!get(v, "min"))
            return missing(c, v, sub, "min", "[x, y, z]");
        if (!get(v, "max"))
            return missing(c, v, sub, "max", "[x, y, z]");
        if ((rc = to_vec3(c, get(v, "min"), join(sub2, sizeof sub2, sub, "min"), sel->a)) ||
            (rc = to_vec3(c, get(v, "max"), join(sub2, sizeof sub2, sub, "max"), sel->b)))
            return rc;
        for (int i = 0; i < 3; i++)
            if (sel->a[i] > sel->b[i])
                return fail(c, get(v, "max"), ISO_EINVAL, sub2,
                            "expected max >= min on every axis");
        return ISO_OK;
    }
    if ((v = get(n, "sphere")) != NULL) {
        static const char *const sk[] = {"center", "radius", NULL};
        join(sub, sizeof sub, key, "sphere");
        sel->kind = ISO_SCENE_SEL_SPHERE;
        if ((rc = want_map(c, v, sub, "{center: [x, y, z], radius: r}")) ||
            (rc = check_keys(c, v, sub, sk)))
            return rc;
        if (!get(v, "center"))
            return missing(c, v, sub, "center", "[x, y, z]");
        if (!get(v, "radius"))
            return missing(c, v, sub, "radius", "a positive number");
        if ((rc = to_vec3(c, get(v, "center"), join(sub2, sizeof sub2, sub, "center"), sel->a)) ||
            (rc = to_double(c, get(v, "radius"), join(sub2, sizeof sub2, sub, "radius"),
                            &sel->radius)))
            return rc;
        if (!(sel->radius > 0))
            return fail(c, get(v, "radius"), ISO_EINVAL, sub2, "expected a radius > 0, found %g",
                        sel->radius);
        return ISO_OK;
    }
    v = get(n, "beyond");
    static const char *const pk[] = {"point", "normal", NULL};
    join(sub, sizeof sub, key, "beyond");
    sel->kind = ISO_SCENE_SEL_PLANE;
    if ((rc = want_map(c, v, sub, "{point: [x, y, z], normal: [x, y, z]}")) ||
        (rc = check_keys(c, v, sub, pk)))
        return rc;
    if (!get(v, "point"))
        return missing(c, v, sub, "point", "[x, y, z]");
    if (!get(v, "normal"))
        return missing(c, v, sub, "normal", "[x, y, z]");
    if ((rc = to_vec3(c, get(v, "point"), join(sub2, sizeof sub2, sub, "point"), sel->a)) ||
        (rc = to_vec3(c, get(v, "normal"), join(sub2, sizeof sub2, sub, "normal"), sel->b)))
        return rc;
    if (sel->b[0] == 0 && sel->b[1] == 0 && sel->b[2] == 0)
        return fail(c, get(v, "normal"), ISO_EINVAL, sub2, "expected a non-zero normal");
    return ISO_OK;
}

/* A selection list, or a single selection mapping. */
static int parse_region(sctx *c, fnode *n, const char *key, iso_scene_region *r)
{
    if (n && fy_node_is_mapping(n)) {
        r->n_sel = 1;
        return parse_sel_item(c, n, key, &r->sel[0]);
    }
    if (!n || !fy_node_is_sequence(n) || fy_node_sequence_item_count(n) < 1)
        return fail(c, n, ISO_EPARSE, key,
                    "expected a selection or a non-empty list of them, "
                    "found %s",
                    type_name(n));
    int cnt = fy_node_sequence_item_count(n);
    if (cnt > ISO_SCENE_MAX_SELECT)
        return fail(c, n, ISO_EINVAL, key, "at most %d selections, found %d", ISO_SCENE_MAX_SELECT,
                    cnt);
    void *it = NULL;
    for (int i = 0; i < cnt; i++) {
        char sub[KEY_MAX];
        snprintf(sub, sizeof sub, "%s[%d]", key, i);
        r->n_sel = i + 1;
        int rc = parse_sel_item(c, fy_node_sequence_iterate(n, &it), sub, &r->sel[i]);
        if (rc)
            return rc;
    }
    return ISO_OK;
}

/* ---- drivers -------------------------------------------------------------- */

/* A mapping option's value in the range devices/ holds it to
 * (iso_dev_map_check), reported at the value. */
static int map_value(sctx *c, fnode *n, const char *key, const char *field, double *out)
{
    char why[128];
    int rc = to_double(c, n, key, out);
    if (rc == ISO_OK && iso_dev_map_check(field, *out, why, sizeof why) != 0)
        rc = fail(c, n, ISO_EINVAL, key, "%s", why);
    return rc;
}

/* A per-axis value: one number for all six axes, a list of six, or a
 * mapping of some of tx..rz. */
static int parse_axes(sctx *c, fnode *n, const char *key, const char *field, double out[6])
{
    int rc;
    double v;
    if (n && fy_node_is_scalar(n)) {
        if ((rc = map_value(c, n, key, field, &v)))
            return rc;
        for (int i = 0; i < 6; i++)
            out[i] = v;
        return ISO_OK;
    }
    if (n && fy_node_is_sequence(n) && fy_node_sequence_item_count(n) == 6) {
        void *it = NULL;
        for (int i = 0; i < 6; i++)
            if ((rc = map_value(c, fy_node_sequence_iterate(n, &it), key, field, &out[i])))
                return rc;
        return ISO_OK;
    }
    if (n && fy_node_is_mapping(n)) {
        if ((rc = check_keys(c, n, key, iso_dev_axis_names)))
            return rc;
        for (int i = 0; i < 6; i++) {
            fnode *e = get(n, iso_dev_axis_names[i]);
            char sub[KEY_MAX];
            if (e && (rc = map_value(c, e, join(sub, sizeof sub, key, iso_dev_axis_names[i]), field,
                                     &out[i])))
                return rc;
        }
        return ISO_OK;
    }
    return fail(c, n, ISO_EPARSE, key,
                "expected a number, a list of 6 numbers or a mapping of "
                "tx, ty, tz, rx, ry, rz; found %s",
                type_name(n));
}

static int parse_mapping(sctx *c, fnode *n, const char *key, iso_dev_map_opts *o)
{
    static const char *const keys[] = {"full_scale", "sensitivity", "dead_zone",  "curve", "remap",
                                       "invert",     "dominant",    "lock",       "frame", "clutch",
                                       "buttons",    "pose_gain",   "pose_scale", NULL};
    int rc;
    if ((rc = want_map(c, n, key, "a device mapping")) || (rc = check_keys(c, n, key, keys)))
        return rc;
    char sub[KEY_MAX];
    fnode *v;
    if ((v = get(n, "full_scale")) &&
        (rc = map_value(c, v, join(sub, sizeof sub, key, "full_scale"), "full_scale",
                        &o->full_scale)))
        return rc;
    static const char *const axis_fields[] = {"sensitivity", "dead_zone", "curve"};
    double *const per_axis[] = {o->sensitivity, o->dead_zone, o->curve};
    for (size_t i = 0; i < 3; i++)
        if ((v = get(n, axis_fields[i])) &&
            (rc = parse_axes(c, v, join(sub, sizeof sub, key, axis_fields[i]), axis_fields[i],
                             per_axis[i])))
            return rc;
    if ((v = get(n, "remap"))) {
        join(sub, sizeof sub, key, "remap");
        if ((rc =
                 want_map(c, v, sub, "a mapping output axis: input axis, e.g. {ty: tz, tz: ty}")) ||
            (rc = check_keys(c, v, sub, iso_dev_axis_names)))
            return rc;
        for (int i = 0; i < 6; i++) {
            fnode *e = get(v, iso_dev_axis_names[i]);
            char sub2[KEY_MAX];
            if (e && (rc = to_enum(c, e, join(sub2, sizeof sub2, sub, iso_dev_axis_names[i]),
                                   iso_dev_axis_names, &o->remap[i])))
                return rc;
        }
    }
    if ((v = get(n, "invert"))) {
        join(sub, sizeof sub, key, "invert");
        if (!fy_node_is_sequence(v))
            return fail(c, v, ISO_EPARSE, sub, "expected a list of axes (tx, ty, tz, rx, ry, rz)");
        void *it = NULL;
        fnode *e;
        while ((e = fy_node_sequence_iterate(v, &it))) {
            int a;
            if ((rc = to_enum(c, e, sub, iso_dev_axis_names, &a)))
                return rc;
            o->invert[a] = 1;
        }
    }
    if ((v = get(n, "dominant")) &&
        (rc = to_bool(c, v, join(sub, sizeof sub, key, "dominant"), &o->dominant)))
        return rc;
    if ((v = get(n, "lock")) &&
        (rc = to_enum(c, v, join(sub, sizeof sub, key, "lock"), iso_dev_lock_names, &o->lock)))
        return rc;
    if ((v = get(n, "frame")) &&
        (rc = to_enum(c, v, join(sub, sizeof sub, key, "frame"), iso_dev_frame_names, &o->frame)))
        return rc;
    if ((v = get(n, "clutch")) && (rc = to_enum(c, v, join(sub, sizeof sub, key, "clutch"),
                                                iso_dev_clutch_names, &o->clutch_is_deadman)))
        return rc;
    if ((v = get(n, "buttons"))) {
        join(sub, sizeof sub, key, "buttons");
        if (!fy_node_is_sequence(v) || fy_node_sequence_item_count(v) > 32)
            return fail(c, v, ISO_EPARSE, sub,
                        "expected a list of at most 32 actions, by button "
                        "(none, clutch, next_handle, reset_pose, record)");
        void *it = NULL;
        fnode *e;
        memset(o->button_action, 0, sizeof o->button_action);
        for (int i = 0; (e = fy_node_sequence_iterate(v, &it)); i++) {
            int a;
            if ((rc = to_enum(c, e, sub, iso_dev_action_names, &a)))
                return rc;
            o->button_action[i] = (uint8_t)a;
        }
    }
    if ((v = get(n, "pose_gain")) &&
        (rc = map_value(c, v, join(sub, sizeof sub, key, "pose_gain"), "pose_gain", &o->pose_gain)))
        return rc;
    if ((v = get(n, "pose_scale")) &&
        (rc = map_value(c, v, join(sub, sizeof sub, key, "pose_scale"), "pose_scale",
                        &o->pose_scale)))
        return rc;
    return ISO_OK;
}

static int parse_keyframes(sctx *c, fnode *n, const char *key, iso_scene_driver *d)
{
    static const char *const keys[] = {"t", "translate", "rotate", NULL};
    if (!n || !fy_node_is_sequence(n) || fy_node_sequence_item_count(n) < 1)
        return fail(c, n, ISO_EPARSE, key, "expected a non-empty list of {t, translate, rotate}");
    int cnt = fy_node_sequence_item_count(n);
    if (cnt > ISO_SCENE_MAX_KEYFRAMES)
        return fail(c, n, ISO_EINVAL, key, "at most %d keyframes, found %d",
                    ISO_SCENE_MAX_KEYFRAMES, cnt);
    void *it = NULL;
    for (int i = 0; i < cnt; i++) {
        fnode *e = fy_node_sequence_iterate(n, &it);
        iso_scene_keyframe *k = &d->keys[i];
        char sub[KEY_MAX], sub2[KEY_MAX];
        snprintf(sub, sizeof sub, "%s[%d]", key, i);
        int rc;
        if ((rc = want_map(c, e, sub, "a keyframe {t, translate, rotate}")) ||
            (rc = check_keys(c, e, sub, keys)))
            return rc;
        if (!get(e, "t"))
            return missing(c, e, sub, "t", "the keyframe's time in seconds");
        if ((rc = to_double(c, get(e, "t"), join(sub2, sizeof sub2, sub, "t"), &k->t)))
            return rc;
        if (k->t < 0 || (i > 0 && !(k->t > d->keys[i - 1].t)))
            return fail(c, get(e, "t"), ISO_EINVAL, sub2,
                        "expected times >= 0 and strictly increasing, found %g", k->t);
        if (get(e, "translate") &&
            (rc = to_vec3(c, get(e, "translate"), join(sub2, sizeof sub2, sub, "translate"),
                          k->translate)))
            return rc;
        if (get(e, "rotate") &&
            (rc = to_vec3(c, get(e, "rotate"), join(sub2, sizeof sub2, sub, "rotate"), k->rotate)))
            return rc;
        d->n_keys = i + 1;
    }
    return ISO_OK;
}

static int find_device(sctx *c, fnode *n, const char *key, int *out)
{
    const char *t = scalar(c, n);
    if (!t)
        return fail(c, n, ISO_EPARSE, key, "expected a device name, found %s", type_name(n));
    const char *names[ISO_SCENE_MAX_DEVICES + 1];
    for (int i = 0; i < c->s->n_devices; i++) {
        names[i] = c->s->devices[i].name;
        if (strcmp(t, names[i]) == 0)
            return (*out = i), ISO_OK;
    }
    names[c->s->n_devices] = NULL;
    const char *near = nearest(t, names);
    if (c->s->n_devices == 0)
        return fail(c, n, ISO_EPARSE, key, "no device '%s': the scene's devices list is empty", t);
    char all[512];
    list_keys(all, sizeof all, names);
    if (near)
        return fail(c, n, ISO_EPARSE, key, "no device '%s'; did you mean '%s'? (devices: %s)", t,
                    near, all);
    return fail(c, n, ISO_EPARSE, key, "no device '%s' (devices: %s)", t, all);
}

static int parse_driver(sctx *c, fnode *n, const char *key, iso_scene_driver *d)
{
    static const char *const keys[] = {"device", "mapping", "screw", "keyframes", NULL};
    int rc;
    iso_dev_map_opts_default(&d->map);
    d->device = -1;
    if (n && scalar(c, n) && strcmp(scalar(c, n), "none") == 0)
        return (d->kind = ISO_SCENE_DRIVE_NONE), ISO_OK;
    if ((rc = want_map(c, n, key, "none, {device, mapping}, {screw} or {keyframes}")) ||
        (rc = check_keys(c, n, key, keys)))
        return rc;
    fnode *dev = get(n, "device"), *screw = get(n, "screw"), *keyf = get(n, "keyframes");
    int count = (dev != NULL) + (screw != NULL) + (keyf != NULL);
    if (count != 1)
        return fail(c, n, ISO_EPARSE, key,
                    "expected exactly one of device, screw or keyframes, "
                    "found %d",
                    count);
    char sub[KEY_MAX];
    if (get(n, "mapping") && !dev)
        return fail(c, get(n, "mapping"), ISO_EPARSE, join(sub, sizeof sub, key, "mapping"),
                    "only goes with device");
    if (dev) {
        d->kind = ISO_SCENE_DRIVE_DEVICE;
        if ((rc = find_device(c, dev, join(sub, sizeof sub, key, "device"), &d->device)))
            return rc;
        if (get(n, "mapping") &&
            (rc = parse_mapping(c, get(n, "mapping"), join(sub, sizeof sub, key, "mapping"),
                                &d->map)))
            return rc;
        return ISO_OK;
    }
    if (keyf) {
        d->kind = ISO_SCENE_DRIVE_KEYFRAMES;
        return parse_keyframes(c, keyf, join(sub, sizeof sub, key, "keyframes"), d);
    }
    static const char *const sk[] = {"def", "duration", NULL};
    d->kind = ISO_SCENE_DRIVE_SCREW;
    join(sub, sizeof sub, key, "screw");
    if ((rc = want_map(c, screw, sub, "{def: FILE or builtin, duration: seconds}")) ||
        (rc = check_keys(c, screw, sub, sk)))
        return rc;
    char sub2[KEY_MAX];
    if (!get(screw, "duration"))
        return missing(c, screw, sub, "duration", "the motion's length in seconds");
    if ((rc = to_double(c, get(screw, "duration"), join(sub2, sizeof sub2, sub, "duration"),
                        &d->duration)))
        return rc;
    if (!(d->duration > 0))
        return fail(c, get(screw, "duration"), ISO_EINVAL, sub2, "expected > 0 seconds, found %g",
                    d->duration);
    fnode *def = get(screw, "def");
    join(sub2, sizeof sub2, sub, "def");
    if (!def || (scalar(c, def) && strcmp(scalar(c, def), "builtin") == 0))
        d->def[0] = '\0';
    else if ((rc = file_at(c, def, sub2, d->def, sizeof d->def)))
        return rc;
    return ISO_OK;
}

static int parse_regions(sctx *c, fnode *n)
{
    static const char *const keys[] = {"sel", "fixed", "handles", NULL};
    static const char *const hkeys[] = {"name", "select", "driver", NULL};
    iso_scene *s = c->s;
    int rc;
    if ((rc = want_map(c, n, "regions", "a mapping with sel, fixed and handles")) ||
        (rc = check_keys(c, n, "regions", keys)))
        return rc;
    fnode *sel = get(n, "sel"), *fixed = get(n, "fixed"), *handles = get(n, "handles");
    mark_of(sel ? sel : n, &s->sel_line, &s->sel_col);
    if (sel) {
        if (scalar(c, sel) && strcmp(scalar(c, sel), "builtin") == 0)
            snprintf(s->sel, sizeof s->sel, "builtin");
        else if ((rc = file_at(c, sel, "regions.sel", s->sel, sizeof s->sel)))
            return rc;
    }
    if (fixed && (rc = parse_region(c, fixed, "regions.fixed", &s->fixed)))
        return rc;
    if (!handles)
        return missing(c, n, "regions", "handles",
                       "a list of handles, each with select and driver");
    if (!fy_node_is_sequence(handles) || fy_node_sequence_item_count(handles) < 1)
        return fail(c, handles, ISO_EPARSE, "regions.handles",
                    "expected a non-empty list, found %s", type_name(handles));
    int cnt = fy_node_sequence_item_count(handles);
    if (cnt > ISO_SCENE_MAX_HANDLES)
        return fail(c, handles, ISO_EINVAL, "regions.handles", "at most %d handles, found %d",
                    ISO_SCENE_MAX_HANDLES, cnt);
    void *it = NULL;
    for (int i = 0; i < cnt; i++) {
        fnode *h = fy_node_sequence_iterate(handles, &it);
        iso_scene_handle *hd = &s->handles[i];
        char key[KEY_MAX], sub[KEY_MAX];
        snprintf(key, sizeof key, "regions.handles[%d]", i);
        s->n_handles = i + 1;
        if ((rc = want_map(c, h, key, "a handle {name, select, driver}")) ||
            (rc = check_keys(c, h, key, hkeys)))
            return rc;
        snprintf(hd->name, sizeof hd->name, "handle%d", i);
        if (get(h, "name") && (rc = to_string(c, get(h, "name"), join(sub, sizeof sub, key, "name"),
                                              hd->name, sizeof hd->name)))
            return rc;
        for (int j = 0; j < i; j++)
            if (strcmp(s->handles[j].name, hd->name) == 0)
                return fail(c, get(h, "name"), ISO_EPARSE, sub, "handle name '%s' is used twice",
                            hd->name);
        if (get(h, "select")) {
            if ((rc = parse_region(c, get(h, "select"), join(sub, sizeof sub, key, "select"),
                                   &hd->region)))
                return rc;
        } else {
            hd->from_sel = 1; /* the .sel's handle i; checked when built */
        }
        if (!get(h, "driver"))
            return missing(c, h, key, "driver", "none, {device, mapping}, {screw} or {keyframes}");
        if ((rc = parse_driver(c, get(h, "driver"), join(sub, sizeof sub, key, "driver"),
                               &hd->driver)))
            return rc;
        hd->driver.map.n_handles = cnt;
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* solver, integrator                                                        */
/* ------------------------------------------------------------------------ */

static int parse_solver(sctx *c, fnode *n)
{
    static const char *const keys[] = {"omega",    "weighting", "restore",     "assembly",
                                       "refactor", "cg_tol",    "cg_max_iter", NULL};
    iso_solver_opts *o = &c->s->solver;
    int rc;
    fnode *v;
    if ((rc = want_map(c, n, "solver", "a mapping of solver settings")) ||
        (rc = check_keys(c, n, "solver", keys)))
        return rc;
    if ((v = get(n, "omega"))) {
        if ((rc = to_double(c, v, "solver.omega", &o->omega)))
            return rc;
        if (!(o->omega > 0 && o->omega <= 1))
            return fail(c, v, ISO_EINVAL, "solver.omega", "expected a value in (0, 1], found %g",
                        o->omega);
    }
    int w = (int)o->weighting;
    if ((v = get(n, "weighting")) &&
        (rc = to_enum(c, v, "solver.weighting", iso_weighting_names, &w)))
        return rc;
    o->weighting = w ? ISO_WEIGHT_AREA : ISO_WEIGHT_PARAM;
    int a = (int)o->assembly;
    if ((v = get(n, "assembly")) && (rc = to_enum(c, v, "solver.assembly", iso_assembly_names, &a)))
        return rc;
    o->assembly = a ? ISO_ASSEMBLY_OPENCL : ISO_ASSEMBLY_CPU;
    int r = (int)o->refactor;
    if ((v = get(n, "refactor")) && (rc = to_enum(c, v, "solver.refactor", iso_refactor_names, &r)))
        return rc;
    o->refactor = r ? ISO_REFACTOR_ALWAYS : ISO_REFACTOR_ADAPTIVE;
    if ((v = get(n, "cg_tol"))) {
        if ((rc = to_double(c, v, "solver.cg_tol", &o->cg_tol)))
            return rc;
        if (!(o->cg_tol > 0 && o->cg_tol < 1))
            return fail(c, v, ISO_EINVAL, "solver.cg_tol", "expected a value in (0, 1), found %g",
                        o->cg_tol);
    }
    if ((v = get(n, "cg_max_iter")) &&
        (rc = to_int(c, v, "solver.cg_max_iter", 1, 100000, &o->cg_max_iter)))
        return rc;
    if ((v = get(n, "restore"))) {
        if (scalar(c, v) && strcmp(scalar(c, v), "off") == 0) {
            o->restore_mu = 0;
            o->restore_tau = 0;
            return ISO_OK;
        }
        static const char *const rk[] = {"mu", "tau", NULL};
        if ((rc = want_map(c, v, "solver.restore", "off or {mu, tau}")) ||
            (rc = check_keys(c, v, "solver.restore", rk)))
            return rc;
        if (!get(v, "mu"))
            return missing(c, v, "solver.restore", "mu", "a number >= 0");
        if ((rc = to_double(c, get(v, "mu"), "solver.restore.mu", &o->restore_mu)))
            return rc;
        if (!(o->restore_mu >= 0))
            return fail(c, get(v, "mu"), ISO_EINVAL, "solver.restore.mu", "expected >= 0, found %g",
                        o->restore_mu);
        if (o->restore_mu > 0 && !get(v, "tau"))
            return missing(c, v, "solver.restore", "tau", "a time constant > 0 when mu > 0");
        if (get(v, "tau")) {
            if ((rc = to_double(c, get(v, "tau"), "solver.restore.tau", &o->restore_tau)))
                return rc;
            if (!(o->restore_tau > 0))
                return fail(c, get(v, "tau"), ISO_EINVAL, "solver.restore.tau",
                            "expected > 0, found %g", o->restore_tau);
        }
    }
    return ISO_OK;
}

static int parse_integrator(sctx *c, fnode *n)
{
    static const char *const keys[] = {"steps_per_tick", "restore_kappa", "abm", "cg_share", NULL};
    int rc;
    fnode *v;
    if ((rc = want_map(c, n, "integrator", "a mapping of integrator settings")) ||
        (rc = check_keys(c, n, "integrator", keys)))
        return rc;
    if ((v = get(n, "steps_per_tick")) &&
        (rc = to_int(c, v, "integrator.steps_per_tick", 1, 1000, &c->s->steps_per_tick)))
        return rc;
    if ((v = get(n, "abm")) &&
        (rc = to_enum(c, v, "integrator.abm", iso_abm_mode_names, &c->s->abm_mode)))
        return rc;
    if ((v = get(n, "restore_kappa"))) {
        double *k = &c->s->integrate.restore_kappa;
        if ((rc = to_double(c, v, "integrator.restore_kappa", k)))
            return rc;
        if (!(*k >= 0))
            return fail(c, v, ISO_EINVAL, "integrator.restore_kappa", "expected >= 0, found %g",
                        *k);
    }
    if ((v = get(n, "cg_share"))) {
        double *q = &c->s->integrate.cg_share;
        if ((rc = to_double(c, v, "integrator.cg_share", q)))
            return rc;
        if (!(*q >= 0 && *q <= 1))
            return fail(c, v, ISO_EINVAL, "integrator.cg_share",
                        "expected a value in [0, 1], found %g", *q);
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* devices                                                                   */
/* ------------------------------------------------------------------------ */

static const char *const backend_names[] = {"",           "hid",  "spnav",  "tty", "tcp",
                                            "serialport", "gpio", "replay", NULL};

const char *iso_scene_backend_name(int b)
{
    return b >= 1 ? iso_names_get(backend_names, b) : "?";
}

/* "host:port" with a port in 1..65535. */
static int host_port(sctx *c, fnode *n, const char *key, char *host, size_t cap, int *port)
{
    const char *t = scalar(c, n);
    const char *colon = t ? strrchr(t, ':') : NULL;
    char *end;
    long p = colon ? strtol(colon + 1, &end, 10) : 0;
    if (!colon || colon == t || colon[1] == '\0' || *end != '\0' || p < 1 || p > 65535 ||
        (size_t)(colon - t) >= cap)
        return fail(c, n, ISO_EPARSE, key, "expected host:port (port 1..65535), found %s%s%s",
                    t ? "'" : "", t ? t : type_name(n), t ? "'" : "");
    memcpy(host, t, (size_t)(colon - t));
    host[colon - t] = '\0';
    *port = (int)p;
    return ISO_OK;
}

static int parse_device(sctx *c, fnode *n, const char *key, iso_scene_device *d)
{
    static const char *const all[] = {
        "name",       "kind",        "path", "address",     "port",       "baud",
        "vid",        "pid",         "chip", "clutch_line", "estop_line", "pulse_line",
        "active_low", "debounce_us", "file", "stale_ms",    NULL};
    static const char *const per[][12] = {
        {NULL},
        {"name", "kind", "path", "vid", "pid", NULL},
        {"name", "kind", NULL},
        {"name", "kind", "path", "baud", "stale_ms", NULL},
        {"name", "kind", "address", "stale_ms", NULL},
        {"name", "kind", "port", "baud", "stale_ms", NULL},
        {"name", "kind", "chip", "clutch_line", "estop_line", "pulse_line", "active_low",
         "debounce_us", NULL},
        {"name", "kind", "file", "stale_ms", NULL},
    };
    int rc;
    char sub[KEY_MAX];
    if ((rc = want_map(c, n, key, "a device {name, kind, ...}")) ||
        (rc = check_keys(c, n, key, all)))
        return rc;
    if (!get(n, "name"))
        return missing(c, n, key, "name", "the name handles refer to");
    if ((rc = to_string(c, get(n, "name"), join(sub, sizeof sub, key, "name"), d->name,
                        sizeof d->name)))
        return rc;
    if (!get(n, "kind"))
        return missing(c, n, key, "kind", "hid, spnav, tty, tcp, serialport, gpio or replay");
    if ((rc = to_enum(c, get(n, "kind"), join(sub, sizeof sub, key, "kind"), backend_names + 1,
                      &d->backend)))
        return rc;
    d->backend += 1;
    fnode *v;
    /* Only a stream of twist samples can go stale; a 3D mouse reports the
     * state of its cap, and one held still may send nothing new. */
    if ((v = get(n, "stale_ms")) &&
        (d->backend == ISO_SCENE_DEV_HIDAPI || d->backend == ISO_SCENE_DEV_SPNAV ||
         d->backend == ISO_SCENE_DEV_GPIOD))
        return fail(c, v, ISO_EPARSE, join(sub, sizeof sub, key, "stale_ms"),
                    "only twist streams time out (kinds tty, tcp, serialport, replay); a %s device "
                    "reports a state and is not timed out",
                    backend_names[d->backend]);
    /* Keys that belong to another kind are errors too: a tty's "address"
     * would otherwise be silently ignored. */
    if ((rc = check_keys(c, n, key, per[d->backend])))
        return rc;
    d->stale_ms = ISO_SCENE_STALE_MS_DEFAULT;
    if (v && (rc = to_int(c, v, join(sub, sizeof sub, key, "stale_ms"), ISO_SCENE_STALE_MS_MIN,
                          ISO_SCENE_STALE_MS_MAX, &d->stale_ms)))
        return rc;
    long l;
    switch (d->backend) {
    case ISO_SCENE_DEV_HIDAPI:
        if ((v = get(n, "path")) &&
            (rc = to_string(c, v, join(sub, sizeof sub, key, "path"), d->path, sizeof d->path)))
            return rc;
        if ((v = get(n, "vid"))) {
            if ((rc = to_long(c, v, join(sub, sizeof sub, key, "vid"), 0, 0xffff, &l)))
                return rc;
            d->vid = (uint16_t)l;
        }
        if ((v = get(n, "pid"))) {
            if ((rc = to_long(c, v, join(sub, sizeof sub, key, "pid"), 0, 0xffff, &l)))
                return rc;
            d->pid = (uint16_t)l;
        }
        break;
    case ISO_SCENE_DEV_SPNAV: break;
    case ISO_SCENE_DEV_TTY:
    case ISO_SCENE_DEV_SERIALPORT: {
        const char *pk = d->backend == ISO_SCENE_DEV_TTY ? "path" : "port";
        if (!get(n, pk))
            return missing(c, n, key, pk, "the device's name, e.g. /dev/ttyUSB0");
        if ((rc =
                 to_string(c, get(n, pk), join(sub, sizeof sub, key, pk), d->path, sizeof d->path)))
            return rc;
        d->baud = 115200;
        if ((v = get(n, "baud"))) {
            if ((rc = to_long(c, v, join(sub, sizeof sub, key, "baud"), 50, 12000000, &l)))
                return rc;
            d->baud = (uint32_t)l;
        }
        break;
    }
    case ISO_SCENE_DEV_TCP: {
        if (!get(n, "address"))
            return missing(c, n, key, "address", "host:port");
        char host[ISO_SCENE_NAME_MAX];
        int port;
        if ((rc = host_port(c, get(n, "address"), join(sub, sizeof sub, key, "address"), host,
                            sizeof host, &port)))
            return rc;
        snprintf(d->address, sizeof d->address, "%s:%d", host, port);
        break;
    }
    case ISO_SCENE_DEV_GPIOD:
        if (!get(n, "chip"))
            return missing(c, n, key, "chip", "a GPIO chip such as gpiochip0");
        if ((rc = to_string(c, get(n, "chip"), join(sub, sizeof sub, key, "chip"), d->chip,
                            sizeof d->chip)))
            return rc;
        d->gpio.chip = d->chip;
        d->gpio.clutch_line = d->gpio.estop_line = d->gpio.pulse_line = -1;
        if ((v = get(n, "clutch_line")) &&
            (rc = to_int(c, v, join(sub, sizeof sub, key, "clutch_line"), -1, 1023,
                         &d->gpio.clutch_line)))
            return rc;
        if ((v = get(n, "estop_line")) &&
            (rc = to_int(c, v, join(sub, sizeof sub, key, "estop_line"), -1, 1023,
                         &d->gpio.estop_line)))
            return rc;
        if ((v = get(n, "pulse_line")) &&
            (rc = to_int(c, v, join(sub, sizeof sub, key, "pulse_line"), -1, 1023,
                         &d->gpio.pulse_line)))
            return rc;
        if ((v = get(n, "active_low")) &&
            (rc = to_bool(c, v, join(sub, sizeof sub, key, "active_low"), &d->gpio.active_low)))
            return rc;
        if ((v = get(n, "debounce_us"))) {
            if ((rc = to_long(c, v, join(sub, sizeof sub, key, "debounce_us"), 0, 1000000, &l)))
                return rc;
            d->gpio.debounce_us = (uint32_t)l;
        }
        break;
    case ISO_SCENE_DEV_REPLAY:
        if (!get(n, "file"))
            return missing(c, n, key, "file", "a recording (.isorec)");
        if ((rc = file_at(c, get(n, "file"), join(sub, sizeof sub, key, "file"), d->path,
                          sizeof d->path)))
            return rc;
        break;
    }
    return ISO_OK;
}

static int parse_devices(sctx *c, fnode *n)
{
    if (!n || !fy_node_is_sequence(n))
        return fail(c, n, ISO_EPARSE, "devices", "expected a list of devices, found %s",
                    type_name(n));
    int cnt = fy_node_sequence_item_count(n);
    if (cnt > ISO_SCENE_MAX_DEVICES)
        return fail(c, n, ISO_EINVAL, "devices", "at most %d devices, found %d",
                    ISO_SCENE_MAX_DEVICES, cnt);
    void *it = NULL;
    for (int i = 0; i < cnt; i++) {
        fnode *d = fy_node_sequence_iterate(n, &it);
        char key[KEY_MAX];
        snprintf(key, sizeof key, "devices[%d]", i);
        c->s->n_devices = i + 1;
        int rc = parse_device(c, d, key, &c->s->devices[i]);
        if (rc)
            return rc;
        for (int j = 0; j < i; j++)
            if (strcmp(c->s->devices[j].name, c->s->devices[i].name) == 0)
                return fail(c, get(d, "name"), ISO_EPARSE, key, "device name '%s' is used twice",
                            c->s->devices[i].name);
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* sinks, recording                                                          */
/* ------------------------------------------------------------------------ */

static int parse_display(sctx *c, fnode *n)
{
    static const char *const keys[] = {"host",           "port",         "allow_remote",
                                       "snapshot_ticks", "snapshot_dir", NULL};
    iso_scene_display *d = &c->s->display;
    int rc;
    fnode *v;
    if ((rc = want_map(c, n, "sinks.display",
                       "a mapping (host, port, allow_remote, snapshot_ticks, snapshot_dir)")) ||
        (rc = check_keys(c, n, "sinks.display", keys)))
        return rc;
    d->enabled = 1;
    if ((v = get(n, "host")) &&
        (rc = to_string(c, v, "sinks.display.host", d->host, sizeof d->host)))
        return rc;
    if ((v = get(n, "port")) && (rc = to_int(c, v, "sinks.display.port", 1, 65535, &d->port)))
        return rc;
    if ((v = get(n, "allow_remote")) &&
        (rc = to_bool(c, v, "sinks.display.allow_remote", &d->allow_remote)))
        return rc;
    if ((v = get(n, "snapshot_dir"))) {
        char name[ISO_SCENE_PATH_MAX];
        if ((rc = to_string(c, v, "sinks.display.snapshot_dir", name, sizeof name)))
            return rc;
        if (iso_scene__resolve(c->s, name, d->snapshot_dir, sizeof d->snapshot_dir))
            return fail(c, v, ISO_EINVAL, "sinks.display.snapshot_dir", "path too long");
    }
    if ((v = get(n, "snapshot_ticks"))) {
        if (!fy_node_is_sequence(v) || fy_node_sequence_item_count(v) > ISO_SCENE_MAX_SNAPSHOTS)
            return fail(c, v, ISO_EPARSE, "sinks.display.snapshot_ticks",
                        "expected a list of at most %d tick numbers", ISO_SCENE_MAX_SNAPSHOTS);
        void *it = NULL;
        fnode *e;
        while ((e = fy_node_sequence_iterate(v, &it))) {
            if ((rc = to_long(c, e, "sinks.display.snapshot_ticks", 0, 1L << 40,
                              &d->snapshot_ticks[d->n_snapshots])))
                return rc;
            d->n_snapshots++;
        }
    }
    return ISO_OK;
}

#define LINK_FORMS "{tty: PATH}, {tcp: host:port}, {serial: PORT} or {emulated: auto|qemu|native}"

/* `link: emulated` is short for {emulated: auto}. */
static int parse_emulated(sctx *c, fnode *n, iso_scene_actuators *a)
{
    a->link = ISO_SCENE_LINK_EMULATED;
    a->emulation = ISO_SCENE_EMU_AUTO;
    return n ? to_enum(c, n, "sinks.actuators.link.emulated", iso_act_emu_names, &a->emulation)
             : ISO_OK;
}

static int parse_link(sctx *c, fnode *n, iso_scene_actuators *a)
{
    static const char *const keys[] = {"tty", "tcp", "serial", "emulated", "baud", NULL};
    const char *key = "sinks.actuators.link";
    int rc;
    a->baud = 115200;
    const char *word = scalar(c, n);
    if (word && *word) {
        static const char *const words[] = {"emulated", NULL};
        if (strcmp(word, "emulated") == 0)
            return parse_emulated(c, NULL, a);
        if (nearest(word, words))
            return fail(c, n, ISO_EPARSE, key,
                        "unknown link '%s'; did you mean 'emulated'? (expected " LINK_FORMS
                        ", or emulated alone)",
                        word);
        return fail(c, n, ISO_EPARSE, key, "expected " LINK_FORMS ", or emulated alone; found '%s'",
                    word);
    }
    if ((rc = want_map(c, n, key, LINK_FORMS ", with baud for tty and serial")) ||
        (rc = check_keys(c, n, key, keys)))
        return rc;
    fnode *tty = get(n, "tty"), *tcp = get(n, "tcp"), *ser = get(n, "serial"),
          *emu = get(n, "emulated");
    int count = (tty != NULL) + (tcp != NULL) + (ser != NULL) + (emu != NULL);
    if (count != 1)
        return fail(c, n, ISO_EPARSE, key,
                    "expected exactly one of tty, tcp, serial or emulated, found %d", count);
    if ((tcp || emu) && get(n, "baud"))
        return fail(c, get(n, "baud"), ISO_EPARSE, "sinks.actuators.link.baud",
                    "only goes with tty or serial");
    if (emu)
        return parse_emulated(c, emu, a);
    if (tcp) {
        a->link = ISO_SCENE_LINK_TCP;
        return host_port(c, tcp, "sinks.actuators.link.tcp", a->host, sizeof a->host, &a->port);
    }
    a->link = tty ? ISO_SCENE_LINK_TTY : ISO_SCENE_LINK_SERIAL;
    if ((rc = to_string(c, tty ? tty : ser,
                        tty ? "sinks.actuators.link.tty" : "sinks.actuators.link.serial", a->path,
                        sizeof a->path)))
        return rc;
    if (get(n, "baud") &&
        (rc = to_int(c, get(n, "baud"), "sinks.actuators.link.baud", 50, 12000000, &a->baud)))
        return rc;
    return ISO_OK;
}

static int parse_channel(sctx *c, fnode *n, const char *key, iso_scene_channel *ch)
{
    static const char *const keys[] = {"channel", "vertex", "region", "axis",
                                       "min",     "max",    "scale",  NULL};
    int rc;
    char sub[KEY_MAX];
    if ((rc = want_map(c, n, key, "a channel {channel, vertex or region, axis, min, max}")) ||
        (rc = check_keys(c, n, key, keys)))
        return rc;
    mark_of(n, &ch->line, &ch->col);
    static const char *const req[] = {"channel", "axis", "min", "max", NULL};
    for (int i = 0; req[i]; i++)
        if (!get(n, req[i]))
            return missing(c, n, key, req[i], "see SCENES.md, sinks.actuators.channels");
    if ((rc = to_int(c, get(n, "channel"), join(sub, sizeof sub, key, "channel"), 0,
                     ISO_SCENE_MAX_CHANNELS - 1, &ch->channel)))
        return rc;
    static const char *const axes[] = {"x", "y", "z", NULL};
    if ((rc = to_enum(c, get(n, "axis"), join(sub, sizeof sub, key, "axis"), axes, &ch->axis)) ||
        (rc = to_double(c, get(n, "min"), join(sub, sizeof sub, key, "min"), &ch->min)) ||
        (rc = to_double(c, get(n, "max"), join(sub, sizeof sub, key, "max"), &ch->max)))
        return rc;
    if (!(ch->min < ch->max))
        return fail(c, get(n, "max"), ISO_EINVAL, sub, "expected max > min, found min %g, max %g",
                    ch->min, ch->max);
    ch->scale = 1;
    if (get(n, "scale") &&
        (rc = to_double(c, get(n, "scale"), join(sub, sizeof sub, key, "scale"), &ch->scale)))
        return rc;
    fnode *vx = get(n, "vertex"), *rg = get(n, "region");
    if ((vx != NULL) == (rg != NULL))
        return fail(c, n, ISO_EPARSE, key, "expected exactly one of vertex or region");
    ch->vertex = -1;
    ch->region = ISO_SCENE_REGION_NONE;
    if (vx)
        return to_int(c, vx, join(sub, sizeof sub, key, "vertex"), 0, 1L << 30, &ch->vertex);
    const char *names[ISO_SCENE_MAX_HANDLES + 2];
    names[0] = "fixed";
    for (int i = 0; i < c->s->n_handles; i++)
        names[i + 1] = c->s->handles[i].name;
    names[c->s->n_handles + 1] = NULL;
    int idx;
    if ((rc = to_enum(c, rg, join(sub, sizeof sub, key, "region"), names, &idx)))
        return rc;
    ch->region = idx == 0 ? ISO_SCENE_REGION_FIXED : idx - 1;
    return ISO_OK;
}

static int parse_sinks(sctx *c, fnode *n)
{
    static const char *const keys[] = {"display", "ply", "actuators", NULL};
    iso_scene *s = c->s;
    int rc;
    fnode *v;
    if ((rc = want_map(c, n, "sinks", "a mapping with display, ply or actuators")) ||
        (rc = check_keys(c, n, "sinks", keys)))
        return rc;
    if ((v = get(n, "display")) && (rc = parse_display(c, v)))
        return rc;
    if ((v = get(n, "ply"))) {
        static const char *const pk[] = {"dir", "every", NULL};
        if ((rc = want_map(c, v, "sinks.ply", "{dir: FOLDER, every: N}")) ||
            (rc = check_keys(c, v, "sinks.ply", pk)))
            return rc;
        if (!get(v, "dir"))
            return missing(c, v, "sinks.ply", "dir", "a folder for the frames");
        char name[ISO_SCENE_PATH_MAX];
        if ((rc = to_string(c, get(v, "dir"), "sinks.ply.dir", name, sizeof name)))
            return rc;
        if (iso_scene__resolve(s, name, s->ply.dir, sizeof s->ply.dir))
            return fail(c, get(v, "dir"), ISO_EINVAL, "sinks.ply.dir", "path too long");
        s->ply.every = 1;
        if (get(v, "every") &&
            (rc = to_int(c, get(v, "every"), "sinks.ply.every", 1, 1000000, &s->ply.every)))
            return rc;
        s->ply.enabled = 1;
    }
    if ((v = get(n, "actuators"))) {
        static const char *const ak[] = {"link", "channels", "loop_timeout_ms", NULL};
        iso_scene_actuators *a = &s->actuators;
        if ((rc = want_map(c, v, "sinks.actuators", "{link, channels}")) ||
            (rc = check_keys(c, v, "sinks.actuators", ak)))
            return rc;
        if (!get(v, "link"))
            return missing(c, v, "sinks.actuators", "link", LINK_FORMS);
        if ((rc = parse_link(c, get(v, "link"), a)))
            return rc;
        fnode *chs = get(v, "channels");
        if (!chs)
            return missing(c, v, "sinks.actuators", "channels", "a list of channels");
        if (!fy_node_is_sequence(chs) || fy_node_sequence_item_count(chs) < 1 ||
            fy_node_sequence_item_count(chs) > ISO_SCENE_MAX_CHANNELS)
            return fail(c, chs, ISO_EPARSE, "sinks.actuators.channels",
                        "expected a list of 1 to %d channels", ISO_SCENE_MAX_CHANNELS);
        void *it = NULL;
        fnode *e;
        for (int i = 0; (e = fy_node_sequence_iterate(chs, &it)); i++) {
            char key[KEY_MAX];
            snprintf(key, sizeof key, "sinks.actuators.channels[%d]", i);
            a->n_ch = i + 1;
            if ((rc = parse_channel(c, e, key, &a->ch[i])))
                return rc;
            for (int j = 0; j < i; j++)
                if (a->ch[j].channel == a->ch[i].channel)
                    return fail(c, get(e, "channel"), ISO_EPARSE, key, "channel %d is used twice",
                                a->ch[i].channel);
        }
        /* the loop watchdog may be widened or narrowed, never switched off */
        fnode *lt = get(v, "loop_timeout_ms");
        if (lt &&
            (rc = to_int(c, lt, "sinks.actuators.loop_timeout_ms", 20, 60000, &a->loop_timeout_ms)))
            return rc;
        a->enabled = 1;
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* The document                                                              */
/* ------------------------------------------------------------------------ */

static int parse_root(sctx *c, fnode *root)
{
    static const char *const keys[] = {"name",    "mesh",    "regions", "solver",    "integrator",
                                       "tick_hz", "devices", "sinks",   "recording", NULL};
    iso_scene *s = c->s;
    int rc;
    fnode *v;
    if (!root)
        return iso_err_set(c->err, ISO_EPARSE, 1,
                           "%s:1:1: (top level): the file is empty "
                           "(expected a mapping with mesh and regions)",
                           c->file);
    if ((rc = want_map(c, root, "(top level)", "a mapping with mesh and regions")) ||
        (rc = check_keys(c, root, "", keys)))
        return rc;
    if ((v = get(root, "name")) && (rc = to_string(c, v, "name", s->name, sizeof s->name)))
        return rc;
    if (!get(root, "mesh"))
        return missing(c, root, "", "mesh", "a mesh file, {shape: NAME} or {benchmark: NAME}");
    if ((rc = parse_mesh(c, get(root, "mesh"))))
        return rc;
    /* Devices before regions: drivers name them. */
    if ((v = get(root, "devices")) && (rc = parse_devices(c, v)))
        return rc;
    if (!get(root, "regions"))
        return missing(c, root, "", "regions", "a mapping with sel, fixed and handles");
    if ((rc = parse_regions(c, get(root, "regions"))))
        return rc;
    if ((v = get(root, "solver")) && (rc = parse_solver(c, v)))
        return rc;
    if ((v = get(root, "integrator")) && (rc = parse_integrator(c, v)))
        return rc;
    if ((v = get(root, "tick_hz"))) {
        if ((rc = to_double(c, v, "tick_hz", &s->tick_hz)))
            return rc;
        if (!(s->tick_hz > 0 && s->tick_hz <= 100000))
            return fail(c, v, ISO_EINVAL, "tick_hz", "expected a rate in (0, 100000] Hz, found %g",
                        s->tick_hz);
    }
    if ((v = get(root, "sinks")) && (rc = parse_sinks(c, v)))
        return rc;
    if ((v = get(root, "recording"))) {
        char name[ISO_SCENE_PATH_MAX];
        if ((rc = to_string(c, v, "recording", name, sizeof name)))
            return rc;
        if (iso_scene__resolve(s, name, s->recording, sizeof s->recording))
            return fail(c, v, ISO_EINVAL, "recording", "path too long");
    }
    return ISO_OK;
}

/* libfyaml's diagnostics go here instead of stderr; the collected errors
 * are read back after a failed parse. */
static void diag_sink(struct fy_diag *diag, void *user, const char *buf, size_t len)
{
    (void)diag;
    (void)user;
    (void)buf;
    (void)len;
}

static void defaults(iso_scene *s)
{
    iso_solver_opts_default(&s->solver);
    iso_integrate_opts_default(&s->integrate);
    s->integrate.restore_kappa = -1; /* the ABM mode's own */
    s->steps_per_tick = 1;
    s->abm_mode = ISO_ABM_PECE;
    s->tick_hz = 60;
    snprintf(s->display.host, sizeof s->display.host, "127.0.0.1");
    s->display.port = 8080;
}

static int load(const char *text, size_t len, const char *path, const iso_scene_opts *opts,
                iso_scene **out, iso_err *err)
{
    *out = NULL;
    iso_scene_opts o0 = {0};
    if (!opts)
        opts = &o0;
    iso_scene *s = calloc(1, sizeof *s);
    if (!s)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    snprintf(s->path, sizeof s->path, "%s", path);
    const char *slash = strrchr(path, '/');
    if (slash)
        snprintf(s->dir, sizeof s->dir, "%.*s", (int)(slash - path == 0 ? 1 : slash - path), path);
    const char *base = slash ? slash + 1 : path;
    snprintf(s->name, sizeof s->name, "%.*s", (int)strcspn(base, "."), base);
    defaults(s);

    struct fy_diag_cfg dcfg;
    fy_diag_cfg_default(&dcfg);
    dcfg.fp = NULL;
    dcfg.output_fn = diag_sink;
    dcfg.colorize = false;
    struct fy_diag *diag = fy_diag_create(&dcfg);
    if (!diag) {
        free(s);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: cannot create the YAML diagnostics", path);
    }
    fy_diag_set_collect_errors(diag, true);
    struct fy_parse_cfg cfg = {.flags = FYPCF_QUIET | FYPCF_COLLECT_DIAG, .diag = diag};
    struct fy_document *doc = NULL;
    int rc = ISO_OK;
    char *owned = NULL;
    if (!text) {
        iso_err fe;
        iso_err_clear(&fe);
        rc = iso_file_read(path, 16u << 20, &owned, &len, &fe);
        if (rc != ISO_OK) {
            rc = iso_err_set(err, rc, fe.offset, "%s%s", fe.msg,
                             rc == ISO_EINVAL ? " (16 MiB): not a scene" : "");
            goto out;
        }
        text = owned;
    }
    /* libfyaml 0.7.12 can loop forever scanning a malformed directive
     * (found by fuzz_scene), and scenes have no use for directives: refuse
     * any line that starts with '%' (after LF or CR), and control bytes,
     * before the parser sees them. */
    for (size_t i = 0, line = 1; i < len; i++) {
        unsigned char ch = (unsigned char)text[i];
        if (ch < 0x20 && ch != '\t' && ch != '\n' && ch != '\r') {
            rc = iso_err_set(err, ISO_EPARSE, (long)line,
                             "%s:%zu: control byte 0x%02x: a scene is "
                             "a text file",
                             path, line, ch);
            goto out;
        }
        if ((i == 0 || text[i - 1] == '\n' || text[i - 1] == '\r') && ch == '%') {
            rc = iso_err_set(err, ISO_EPARSE, (long)line,
                             "%s:%zu:1: YAML directives ('%%...') are "
                             "not supported in scene files",
                             path, line);
            goto out;
        }
        line += text[i] == '\n';
    }
    doc = fy_document_build_from_string(&cfg, text, len);
    if (!doc) {
        void *it = NULL;
        struct fy_diag_error *e = fy_diag_errors_iterate(diag, &it);
        /* libfyaml's collected line and column count from 1 already. */
        if (e)
            rc = iso_err_set(err, ISO_EPARSE, e->line, "%s:%d:%d: YAML syntax error: %s", path,
                             e->line > 0 ? e->line : 1, e->column > 0 ? e->column : 1,
                             e->msg ? e->msg : "?");
        else
            rc = iso_err_set(err, ISO_EPARSE, 1,
                             "%s:1:1: (top level): the file is empty or holds "
                             "no YAML document (expected a mapping with mesh and regions)",
                             path);
        goto out;
    }
    sctx *c0 = calloc(1, sizeof *c0);
    if (!c0) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
        goto out;
    }
    c0->s = s;
    c0->file = path;
    c0->err = err;
    c0->check_files = !(opts->flags & ISO_SCENE_PARSE_ONLY);
    rc = no_anchors(c0, fy_document_root(doc), "", 0);
    if (rc == ISO_OK)
        rc = parse_root(c0, fy_document_root(doc));
    fy_document_destroy(doc);
    doc = NULL;
    int check_files = c0->check_files;
    free(c0);
    if (rc == ISO_OK && check_files)
        rc = iso_scene__build(s, opts, err);
out:
    free(owned);
    fy_diag_destroy(diag);
    if (rc != ISO_OK) {
        iso_scene_destroy(s);
        return rc;
    }
    *out = s;
    return ISO_OK;
}

int iso_scene_load_opts(const char *path, const iso_scene_opts *opts, iso_scene **out, iso_err *err)
{
    return load(NULL, 0, path, opts, out, err);
}

int iso_scene_load(const char *path, iso_scene **out, iso_err *err)
{
    return load(NULL, 0, path, NULL, out, err);
}

int iso_scene_load_mem(const char *text, size_t len, const char *name, const iso_scene_opts *opts,
                       iso_scene **out, iso_err *err)
{
    return load(text ? text : "", text ? len : 0, name, opts, out, err);
}

void iso_scene_destroy(iso_scene *s)
{
    if (!s)
        return;
    for (int i = 0; i < s->fixed.n_sel; i++)
        free(s->fixed.sel[i].vertices);
    for (int h = 0; h < ISO_SCENE_MAX_HANDLES; h++)
        for (int i = 0; i < s->handles[h].region.n_sel; i++)
            free(s->handles[h].region.sel[i].vertices);
    iso_mesh_destroy(s->mesh);
    iso_regions_deinit(&s->regions);
    free(s);
}

const char *iso_scene_driver_name(int kind)
{
    static const char *const names[] = {"none", "device", "screw", "keyframes", NULL};
    return iso_names_get(names, kind);
}

const char *iso_scene_link_name(int link)
{
    static const char *const names[] = {"?", "tty", "tcp", "serial", "emulated", NULL};
    return iso_names_get(names, link);
}
