/* config/scene_walk.c -- reading a YAML mapping by its section's table.
 *
 * The walk is schema-first: every mapping is checked against the keys its
 * table holds before any value is read, so a typo is reported as an unknown
 * key (with the nearest known one) rather than as a missing one. Then the
 * rows are read in the table's order, which is also SCENES.md's. Every
 * message starts with FILE:LINE:COL and the dotted key path, the way a
 * compiler reports, so an editor can jump to it. */
#include "internal.h"

#include <libfyaml.h>
#include <stdarg.h>
#include <string.h>

#include "iso_names.h"

/* ------------------------------------------------------------------------ */
/* Positions and messages                                                    */
/* ------------------------------------------------------------------------ */

/* Where scalar n's own token starts; 0 when it has none (an empty value). */
static int token_mark(fnode *n, int *line, int *col)
{
    size_t len = 0;
    struct fy_token *t = fy_node_get_scalar_token(n);
    const struct fy_mark *m = t ? fy_token_start_mark(t) : NULL;
    if (!m || (fy_node_get_scalar(n, &len) && len == 0 && fy_node_get_style(n) == FYNS_PLAIN))
        return 0;
    *line = m->line + 1;
    *col = m->column + 1;
    return 1;
}

/* An empty value has no token of its own (libfyaml 0.7 gives it none, or
 * one at the document's start): it is reported at its key, or at the
 * list it is an item of. */
static void empty_mark(fnode *n, int *line, int *col)
{
    for (int depth = 0; n && depth < 64; depth++) {
        fnode *parent = fy_node_get_parent(n);
        void *it = NULL;
        struct fy_node_pair *p;
        if (parent && fy_node_is_mapping(parent))
            while ((p = fy_node_mapping_iterate(parent, &it)) != NULL)
                if (fy_node_pair_value(p) == n) {
                    iso_scene__mark(fy_node_pair_key(p), line, col);
                    return;
                }
        n = parent; /* an item of a list: where the list is */
    }
}

/* Collections have no public start token in libfyaml 0.7, so they report
 * their first scalar (a mapping's first key). */
void iso_scene__mark(fnode *n, int *line, int *col)
{
    *line = 1;
    *col = 1;
    for (int depth = 0; n && depth < 64; depth++) {
        if (fy_node_is_scalar(n)) {
            if (!token_mark(n, line, col) && depth == 0)
                empty_mark(n, line, col);
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

int iso_scene__fail(scene_ctx *c, fnode *at, int code, const char *key, const char *fmt, ...)
{
    int line, col;
    iso_scene__mark(at, &line, &col);
    char what[384];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return iso_err_set(c->err, code, line, "%s:%d:%d: %s: %s", c->file, line, col, key, what);
}

const char *iso_scene__join(char *buf, size_t cap, const char *parent, const char *name)
{
    if (parent && *parent)
        snprintf(buf, cap, "%s.%s", parent, name);
    else
        snprintf(buf, cap, "%s", name);
    return buf;
}

int iso_scene__missing(scene_ctx *c, fnode *map, const char *path, const char *name,
                       const char *what)
{
    char key[ISO_SCENE_KEY_MAX];
    return iso_scene__fail(c, map, ISO_EPARSE, iso_scene__join(key, sizeof key, path, name),
                           "missing required key (expected %s)", what);
}

const char *iso_scene__type_name(fnode *n)
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

fnode *iso_scene__get(fnode *map, const char *name)
{
    return fy_node_mapping_lookup_by_string(map, name, strlen(name));
}

int iso_scene__want_map(scene_ctx *c, fnode *n, const char *key, const char *what)
{
    char found[80];
    if (n && fy_node_is_mapping(n))
        return ISO_OK;
    return iso_scene__fail(c, n, ISO_EPARSE, key, "expected %s, found %s", what,
                           iso_scene__found(c, n, found, sizeof found));
}

/* ------------------------------------------------------------------------ */
/* Unknown keys                                                              */
/* ------------------------------------------------------------------------ */

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

/* No suggestion beats a silly one: none more than half the word away. */
const char *iso_scene__nearest(const char *word, const char *const *known)
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

int iso_scene__refuse_word(scene_ctx *c, fnode *n, const char *key, const char *what,
                           const char *word, const char *const *known, const char *label)
{
    char all[512];
    iso_names_list(known, ", ", all, sizeof all);
    const char *near = iso_scene__nearest(word, known);
    if (near)
        return iso_scene__fail(c, n, ISO_EPARSE, key, "%s; did you mean '%s'? (%s %s)", what, near,
                               label, all);
    return iso_scene__fail(c, n, ISO_EPARSE, key, "%s (%s %s)", what, label, all);
}

/* Refuses key `ks` (node k) of the mapping at `path`: `why` says for what
 * ("unknown key" or "unknown key for kind tty"), with the nearest of known. */
static int refuse_key(scene_ctx *c, fnode *k, const char *path, const char *ks, const char *why,
                      const char *const *known)
{
    char key[ISO_SCENE_KEY_MAX];
    iso_scene__join(key, sizeof key, path, ks);
    return iso_scene__refuse_word(c, k, key, why, ks, known, "expected one of:");
}

/* The text of map's key in pair p; refuses a key that is not a plain scalar. */
static int key_text(scene_ctx *c, fnode *map, struct fy_node_pair *p, const char *path,
                    const char **out)
{
    fnode *k = fy_node_pair_key(p);
    *out = iso_scene__scalar(c, k);
    if (*out)
        return ISO_OK;
    return iso_scene__fail(c, k ? k : map, ISO_EPARSE, path && *path ? path : "(top level)",
                           "expected a plain key, found %s", iso_scene__type_name(k));
}

int iso_scene__check_keys(scene_ctx *c, fnode *map, const char *path, const char *const *known)
{
    void *it = NULL;
    struct fy_node_pair *p;
    while ((p = fy_node_mapping_iterate(map, &it)) != NULL) {
        const char *ks;
        int rc = key_text(c, map, p, path, &ks);
        if (rc)
            return rc;
        if (iso_names_find(known, ks) < 0)
            return refuse_key(c, fy_node_pair_key(p), path, ks, "unknown key", known);
    }
    return ISO_OK;
}

const scene_key *iso_scene__row(const scene_section *sec, const char *name)
{
    for (const scene_key *k = sec->keys; k->key; k++)
        if (strcmp(k->key, name) == 0)
            return k;
    return NULL;
}

/* Row k applies to the variant chosen (every row does before one is). */
static int applies(const scene_key *k, const char *variant)
{
    return !k->with || !variant || iso_scene__in_words(k->with, variant);
}

/* The keys of sec that apply to variant, NULL-terminated, into names. */
static void section_keys(const scene_section *sec, const char *variant,
                         const char *names[ISO_SCENE_SECTION_KEYS + 1])
{
    int n = 0;
    for (const scene_key *k = sec->keys; k->key && n < ISO_SCENE_SECTION_KEYS; k++)
        if (applies(k, variant))
            names[n++] = k->key;
    names[n] = NULL;
}

/* A key of the section that does not go with the variant chosen: for an
 * SK_ONE_OF choice, the keys it goes with (at the value, which is what is
 * misplaced); for a selector (a device's kind), the keys that kind takes
 * (at the key, as for any unknown key). */
static int refuse_variant(scene_ctx *c, const scene_section *sec, scene_map *m,
                          struct fy_node_pair *p, const scene_key *k)
{
    char key[ISO_SCENE_KEY_MAX], why[160];
    if (!m->selector) {
        char with[128];
        iso_scene__words_list(k->with, " or ", with, sizeof with);
        return iso_scene__fail(c, fy_node_pair_value(p), ISO_EPARSE,
                               iso_scene__join(key, sizeof key, m->key, k->key),
                               "only goes with %s", with);
    }
    const char *names[ISO_SCENE_SECTION_KEYS + 1];
    section_keys(sec, m->variant, names);
    snprintf(why, sizeof why, "unknown key for %s %s", m->selector->key, m->variant);
    return refuse_key(c, fy_node_pair_key(p), m->key, k->key, why, names);
}

/* Refuses, in the mapping's order, the first key that does not go with
 * the variant chosen. */
static int check_variant(scene_ctx *c, const scene_section *sec, scene_map *m)
{
    void *it = NULL;
    struct fy_node_pair *p;
    while ((p = fy_node_mapping_iterate(m->node, &it)) != NULL) {
        const char *ks = iso_scene__scalar(c, fy_node_pair_key(p));
        const scene_key *k = ks ? iso_scene__row(sec, ks) : NULL;
        if (k && !applies(k, m->variant))
            return refuse_variant(c, sec, m, p, k);
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* The walk                                                                  */
/* ------------------------------------------------------------------------ */

/* Sections with SK_ONE_OF keys: exactly one is there, and it is the variant. */
static int choose_one_of(scene_ctx *c, const scene_section *sec, scene_map *m)
{
    const char *names[ISO_SCENE_SECTION_KEYS + 1];
    int n = 0, found = 0, kind = 0;
    for (const scene_key *k = sec->keys; k->key && n < ISO_SCENE_SECTION_KEYS; k++) {
        if (!(k->flags & SK_ONE_OF))
            continue;
        names[n++] = k->key;
        if (iso_scene__get(m->node, k->key)) {
            found++;
            m->variant = k->key;
            kind = n;
        }
    }
    names[n] = NULL;
    if (n == 0)
        return ISO_OK;
    if (found != 1) {
        char list[256];
        iso_names_list(names, " or ", list, sizeof list);
        return iso_scene__fail(c, m->node, ISO_EPARSE, m->key,
                               "expected exactly one of %s, found %d", list, found);
    }
    if (sec->stores_kind)
        memcpy((char *)m->obj + sec->kind_off, &kind, sizeof kind);
    return check_variant(c, sec, m);
}

static int required(const scene_key *k, const char *variant)
{
    return (k->flags & SK_REQUIRED) ||
           (k->need && variant && iso_scene__in_words(k->need, variant));
}

/* "missing required key (expected HELP)", with an enum's names. */
static int missing(scene_ctx *c, scene_map *m, const scene_key *k)
{
    char what[384], names[256];
    if (k->kind == SK_ENUM)
        snprintf(what, sizeof what, "%s: %s", k->help,
                 iso_names_list(iso_scene__names(k), " or ", names, sizeof names));
    else
        snprintf(what, sizeof what, "%s", k->help);
    return iso_scene__missing(c, m->node, m->key, k->key, what);
}

static int walk_key(scene_ctx *c, const scene_section *sec, scene_map *m, const scene_key *k)
{
    fnode *v = iso_scene__get(m->node, k->key);
    if (!v)
        return required(k, m->variant) ? missing(c, m, k) : ISO_OK;
    char key[ISO_SCENE_KEY_MAX];
    int rc = iso_scene__read(c, k, v, iso_scene__join(key, sizeof key, m->key, k->key), m->obj);
    if (rc != ISO_OK || !(k->flags & SK_SELECTOR))
        return rc;
    int value;
    memcpy(&value, (char *)m->obj + k->off, sizeof value);
    m->variant = iso_scene__names(k)[value - k->first];
    m->selector = k;
    if (sec->chosen && (rc = sec->chosen(c, m)))
        return rc;
    return check_variant(c, sec, m);
}

int iso_scene__walk(scene_ctx *c, const scene_section *sec, fnode *n, const char *key, void *obj,
                    int item, int count)
{
    scene_map m = {.node = n, .key = key, .obj = obj, .item = item, .count = count};
    const char *names[ISO_SCENE_SECTION_KEYS + 1];
    int rc;
    if (sec->begin && (rc = sec->begin(c, &m)))
        return rc;
    if (sec->scalar && n && fy_node_is_scalar(n))
        return sec->scalar(c, &m);
    section_keys(sec, NULL, names);
    if ((rc = iso_scene__want_map(c, n, key, sec->what)) ||
        (rc = iso_scene__check_keys(c, n, key, names)) || (rc = choose_one_of(c, sec, &m)))
        return rc;
    for (const scene_key *k = sec->keys; k->key; k++)
        if ((rc = walk_key(c, sec, &m, k)))
            return rc;
    return sec->end ? sec->end(c, &m) : ISO_OK;
}

int iso_scene__list_count(scene_ctx *c, const scene_key *k, fnode *v, const char *key, int *count)
{
    int one = (k->flags & SK_ONE_OR_LIST) && v && fy_node_is_mapping(v);
    char found[80];
    if (!one && (!v || !fy_node_is_sequence(v) ||
                 (k->min_items > 0 && fy_node_sequence_item_count(v) < 1))) {
        if (k->flags & SK_ONE_OR_LIST)
            return iso_scene__fail(c, v, ISO_EPARSE, key,
                                   "expected a mapping or a non-empty list of %s, found %s",
                                   k->noun, iso_scene__found(c, v, found, sizeof found));
        return iso_scene__fail(c, v, ISO_EPARSE, key, "expected a %slist of %s, found %s",
                               k->min_items > 0 ? "non-empty " : "", k->noun,
                               v && fy_node_is_sequence(v)
                                   ? "an empty one"
                                   : iso_scene__found(c, v, found, sizeof found));
    }
    *count = one ? 1 : fy_node_sequence_item_count(v);
    if (k->max_items > 0 && *count > k->max_items)
        return iso_scene__fail(c, v, ISO_EINVAL, key, "at most %d %s, found %d", k->max_items,
                               k->noun, *count);
    return ISO_OK;
}

int iso_scene__read_list(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    int count, rc = iso_scene__list_count(c, k, v, key, &count);
    if (rc)
        return rc;
    char *items = (char *)obj + k->off;
    int *n = (int *)((char *)obj + k->count_off);
    if (fy_node_is_mapping(v)) {
        *n = 1;
        return iso_scene__walk(c, k->sub, v, key, items, 0, 1);
    }
    void *it = NULL;
    for (int i = 0; i < count; i++) {
        char sub[ISO_SCENE_KEY_MAX];
        snprintf(sub, sizeof sub, "%s[%d]", key, i);
        *n = i + 1; /* before the walk: what it allocates is freed on failure */
        if ((rc = iso_scene__walk(c, k->sub, fy_node_sequence_iterate(v, &it), sub,
                                  items + (size_t)i * k->stride, i, count)))
            return rc;
    }
    return ISO_OK;
}
