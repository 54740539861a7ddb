/* config/internal.h -- what config/'s files share: the scene schema (one
 * table of keys per section), the walk that reads a YAML mapping by its
 * table, the typed value readers, and the build step. Not installed.
 *
 * One row per key says its name, its kind, its range, whether it is
 * required, a one-line description, the default as SCENES.md shows it, and
 * where the value goes (an offset into the section's struct, or a handler
 * for compound values). The walk (scene_walk.c), the unknown-key
 * suggestions and SCENES.md's key table (scene_doc.c) all read these rows,
 * and test_scene holds SCENES.md to them. */
#ifndef ISO_SCENE_INTERNAL_H
#define ISO_SCENE_INTERNAL_H

#include <stddef.h>
#include <stdio.h>

#include "iso_scene.h"

/* Builds what a parsed scene describes: loads the mesh (resolving the
 * benchmark through opts), builds the regions from the .sel and the
 * selections, loads .def files and makes their twists. Errors name the
 * scene file, the selection's line:col and its key. (scene_build.c) */
int iso_scene__build(iso_scene *s, const iso_scene_opts *opts, iso_err *err);

/* Levenshtein distance, capped at 255 (nearest-key suggestions). */
int iso_scene__distance(const char *a, const char *b);

/* ---- the schema ------------------------------------------------------------ */

typedef struct fy_node fnode; /* libfyaml's node (libfyaml.h) */

/* Key paths ("regions.handles[0].select[2].box.min") are built into fixed
 * buffers for messages; a path longer than this is cut, by design. */
#define ISO_SCENE_KEY_MAX 256
#define ISO_SCENE_SECTION_KEYS 24 /* the most keys a section has, with room */

typedef struct scene_ctx {
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
} scene_ctx;

typedef enum scene_kind {
    SK_NUMBER = 1, /* double; range optional, or the devices layer's (dev) */
    SK_INT,        /* int, long, uint16_t or uint32_t by the field's size; range required */
    SK_BOOL,       /* int 0/1: true/false, yes/no, on/off */
    SK_STRING,     /* char[size], non-empty */
    SK_FILE,       /* char[size]: a file to read, resolved, checked unless parsing only */
    SK_PATH,       /* char[size]: a file or folder to write, resolved, not checked */
    SK_ENUM,       /* a name from a table: int (first + index), or its text (SK_AS_TEXT) */
    SK_VEC3,       /* double[3]: [x, y, z] */
    SK_LIST,       /* a list: of sections (sub), or of scalars read by a handler (store) */
    SK_MAP,        /* a mapping read by a handler (store) */
    SK_SECTION     /* a mapping read by its own table (sub), maybe with a scalar short form */
} scene_kind;

enum {
    SK_REQUIRED = 1 << 0,    /* the mapping must hold it */
    SK_ONE_OF = 1 << 1,      /* exactly one of the section's SK_ONE_OF keys; it is the variant */
    SK_SELECTOR = 1 << 2,    /* an SK_ENUM whose value is the variant (a device's kind) */
    SK_AS_TEXT = 1 << 3,     /* SK_ENUM: store the name, not the index */
    SK_WORD_EMPTY = 1 << 4,  /* SK_FILE: `word` is stored as "" rather than as itself */
    SK_ONE_OR_LIST = 1 << 5, /* SK_LIST: a single mapping is a list of one */
};

struct scene_key;
struct scene_section;

/* A handler for a compound value: reads v (found at `key`) into obj, the
 * section's struct (k->off says where in it). */
typedef int (*scene_store)(scene_ctx *c, const struct scene_key *k, fnode *v, const char *key,
                           void *obj);

typedef struct scene_key {
    const char *key;
    scene_kind kind;
    size_t off, size; /* the value's place in the section's struct: FIELD(type, member) */
    unsigned flags;   /* SK_* */
    /* Value range (SK_NUMBER, SK_INT, and the integers of an SK_LIST);
     * iso_scene__range() says which applies. */
    iso_range range;
    const char *solver; /* the range is the solver's (iso_solver_range, this field) */
    const char *dev;    /* SK_NUMBER: the range is devices/' (iso_dev_map_check, this field) */
    int min_items, max_items;             /* SK_LIST: how many items (max_items 0: no limit) */
    const char *const *names;             /* SK_ENUM (or a list's scalars): the names, by value */
    const char *const *(*names_fn)(void); /* ... or a function that returns them */
    int first;                            /* SK_ENUM: the value of names[0] */
    const char *word;                     /* SK_FILE: a word taken instead of a file ("builtin") */
    const char *with;                /* only with these variants (space-separated); NULL: always */
    const char *need;                /* required with these variants */
    const struct scene_section *sub; /* SK_SECTION, or an SK_LIST's items */
    size_t count_off, stride;        /* SK_LIST of sections: the int count's offset, item size */
    scene_store store;               /* compound values: how they are read */
    const char *type;                /* compound values: the type as SCENES.md shows it */
    const char *noun;                /* SK_LIST: its items, plural, for messages */
    const char *help;                /* one line, a noun phrase: what the value is */
    const char *dflt;                /* the default as SCENES.md shows it; NULL: none */
} scene_key;

/* A mapping being walked, as its hooks see it. */
typedef struct scene_map {
    fnode *node;               /* the mapping (or the scalar, for a short form) */
    const char *key;           /* its path, for messages */
    void *obj;                 /* the struct its values go to */
    const char *variant;       /* the SK_ONE_OF key present or the SK_SELECTOR's value */
    const scene_key *selector; /* the row that chose it, NULL for SK_ONE_OF */
    int item, count;           /* its index in its list and the list's length; -1, 0 if none */
} scene_map;

typedef int (*scene_hook)(scene_ctx *c, scene_map *m);

typedef struct scene_section {
    const char *name;      /* its place in the document: "solver", "devices[]" */
    const char *what;      /* the form expected, for a value of another type */
    const scene_key *keys; /* ends with a row whose key is NULL */
    scene_hook begin;      /* before anything: defaults that depend on the item */
    scene_hook scalar;     /* the short form, when the value is a scalar; NULL: none */
    scene_hook chosen;     /* after the SK_SELECTOR row is read */
    scene_hook end;        /* after every key: rules across keys */
    /* With SK_ONE_OF rows: the variant's kind, 1 + its place among those
     * rows (so they are listed in the kind enum's order), is stored as an
     * int at kind_off in the item. */
    int stores_kind;
    size_t kind_off;
} scene_section;

/* .stores_kind and .kind_off for an int-sized kind member of type. */
#define KIND_AT(type, member) .stores_kind = 1, .kind_off = offsetof(type, member)

#define FIELD(type, member) offsetof(type, member), sizeof(((type *)0)->member)
/* Ranges: [a, b], (a, b], >= a, > a; or the solver's for its setting
 * `name` (iso_solver_range), so that a scene and the command line refuse
 * the same values in the same words. */
#define IN(a, b) .range = {ISO_RANGE_GE(a), ISO_RANGE_LE(b)}
#define IN_OC(a, b) .range = {ISO_RANGE_GT(a), ISO_RANGE_LE(b)}
#define AT_LEAST(a) .range = {ISO_RANGE_GE(a)}
#define ABOVE(a) .range = {ISO_RANGE_GT(a)}
#define SOLVER_RANGE(name) .solver = (name)

/* The top level; every other section hangs from it (SK_SECTION and SK_LIST
 * rows' sub). The sections, each in its own file: */
extern const scene_section iso_scene__schema;     /* scene.c */
extern const scene_section iso_scene__mesh;       /* scene_mesh.c */
extern const scene_section iso_scene__regions;    /* scene_regions.c */
extern const scene_section iso_scene__driver;     /* scene_drivers.c */
extern const scene_section iso_scene__solver;     /* scene_solver.c */
extern const scene_section iso_scene__integrator; /* scene_solver.c */
extern const scene_section iso_scene__device;     /* scene_devices.c */
extern const scene_section iso_scene__sinks;      /* scene_sinks.c */

/* ---- the walk (scene_walk.c) ------------------------------------------------ */

/* Reads mapping n, found at `key`, into obj by sec's table: unknown keys
 * are refused with the nearest of the table's keys, then each row is read
 * in the table's order. item and count: n's place in its list (-1, 0). */
int iso_scene__walk(scene_ctx *c, const scene_section *sec, fnode *n, const char *key, void *obj,
                    int item, int count);
/* Reads one value by its row (any kind). */
int iso_scene__read(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj);
/* The number of items in list v, held to k's bounds (a single mapping is
 * one with SK_ONE_OR_LIST). */
int iso_scene__list_count(scene_ctx *c, const scene_key *k, fnode *v, const char *key, int *count);
/* Reads an SK_LIST of sections (k->sub) into obj at k->off, its count at
 * k->count_off. */
int iso_scene__read_list(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj);

/* "FILE:LINE:COL: KEY: what", at node `at`. Returns code. */
int iso_scene__fail(scene_ctx *c, fnode *at, int code, const char *key, const char *fmt, ...)
    ISO_PRINTF(5, 6);
int iso_scene__missing(scene_ctx *c, fnode *map, const char *path, const char *name,
                       const char *what);
/* Where a node starts (line and column from 1). */
void iso_scene__mark(fnode *n, int *line, int *col);
/* "parent.name" or "name" into buf; returns buf. */
const char *iso_scene__join(char *buf, size_t cap, const char *parent, const char *name);
fnode *iso_scene__get(fnode *map, const char *name);
const char *iso_scene__type_name(fnode *n);
/* The nearest of `known` (NULL-terminated) to `word`, or NULL if none is close. */
const char *iso_scene__nearest(const char *word, const char *const *known);
/* Refuses `word` at node n (scene key `key`), ISO_EPARSE: "WHAT; did you
 * mean 'NEAREST'? (LABEL a, b, c)", or without the suggestion when no
 * known word is close (LABEL: "expected one of", "devices:", ...). known is
 * NULL-terminated. */
int iso_scene__refuse_word(scene_ctx *c, fnode *n, const char *key, const char *what,
                           const char *word, const char *const *known, const char *label);
/* Checks that every key of map is a plain scalar among `known`. */
int iso_scene__check_keys(scene_ctx *c, fnode *map, const char *path, const char *const *known);
int iso_scene__want_map(scene_ctx *c, fnode *n, const char *key, const char *what);
/* The row named `name` in sec, or NULL. */
const scene_key *iso_scene__row(const scene_section *sec, const char *name);

/* ---- values (scene_value.c) ------------------------------------------------- */

/* The text of a scalar (NULL for collections and aliases). */
const char *iso_scene__scalar(scene_ctx *c, fnode *n);
/* 1 if n is YAML's null where a value belongs: no node, an empty value, or
 * a plain (unquoted) ~, null, Null or NULL. A quoted "~" is text. */
int iso_scene__is_null(scene_ctx *c, fnode *n);
/* What n is, for "found ...": "a list", "a mapping", "an empty value",
 * "null ('~')", or the scalar's text in quotes. Into buf; returns buf. */
const char *iso_scene__found(scene_ctx *c, fnode *n, char *buf, size_t cap);
/* Any finite number. */
int iso_scene__to_double(scene_ctx *c, fnode *n, const char *key, double *out);
/* A number of row k's range (iso_scene__range), or of the devices layer's
 * (k->dev): a value of the wrong type is ISO_EPARSE, one out of range
 * ISO_EINVAL, both in iso_range_parse's words. */
int iso_scene__number(scene_ctx *c, const scene_key *k, fnode *n, const char *key, double *out);
/* One of `names` (NULL-terminated); *out is its index. */
int iso_scene__to_enum(scene_ctx *c, fnode *n, const char *key, const char *const *names, int *out);
/* A file to read: resolved against the scene's folder, and unless parsing
 * only, a readable regular file. */
int iso_scene__to_file(scene_ctx *c, fnode *n, const char *key, char *out, size_t cap);
/* "host:port" with a port in 1..65535. */
int iso_scene__host_port(scene_ctx *c, fnode *n, const char *key, char *host, size_t cap,
                         int *port);
/* k's enum names. */
const char *const *iso_scene__names(const scene_key *k);
/* Row k's range into *r: its own, or the solver's for k->solver; whole
 * numbers for SK_INT and for an SK_LIST's items. Returns 0 when it has
 * none (and for k->dev, whose range the devices layer holds). */
int iso_scene__range(const scene_key *k, iso_range *r);
/* k's range as SCENES.md shows it ("(0, 1]", "[1, 65535]", "> 0"), "" if none. */
const char *iso_scene__range_text(const scene_key *k, char *buf, size_t cap);
/* What a value of row k must be, for messages: "a value in (0, 1]", "true
 * or false", "one of a, b or c", the row's type... Into buf; returns buf. */
const char *iso_scene__expected(const scene_key *k, char *buf, size_t cap);
/* Whether `word` is among the space-separated words of `list`. */
int iso_scene__in_words(const char *list, const char *word);
/* The space-separated words as a phrase, "a, b or c" with last = " or ". */
const char *iso_scene__words_list(const char *words, const char *last, char *buf, size_t cap);

/* ---- SCENES.md's key table (scene_doc.c) -------------------------------------- */

/* Writes the key table, one row per key of every section, as markdown. */
void iso_scene__doc_table(FILE *out);

#endif
