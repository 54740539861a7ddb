/* config/scene_regions.c -- the scene's `regions:` section: the .sel file,
 * the fixed vertices, and the handles, each with its selection and driver
 * (scene_drivers.c). A selection is a list of vertices, a box, a sphere or
 * a half-space; a region is one selection or a list of them. */
#include "internal.h"

#include <libfyaml.h>
#include <stdlib.h>
#include <string.h>

#include "iso_names.h"

/* ------------------------------------------------------------------------ */
/* Selections                                                                */
/* ------------------------------------------------------------------------ */

static const scene_key box_keys[] = {
    {"min", SK_VEC3, FIELD(iso_scene_sel, a), SK_REQUIRED, .help = "the low corner [x, y, z]"},
    {"max", SK_VEC3, FIELD(iso_scene_sel, b), SK_REQUIRED,
     .help = "the high corner [x, y, z], >= min on every axis"},
    {.key = NULL},
};

/* A selection whose key `field` is read but wrong: the error names it. */
static int sel_fail(scene_ctx *c, scene_map *m, const char *field, const char *why)
{
    char key[ISO_SCENE_KEY_MAX];
    return iso_scene__fail(c, iso_scene__get(m->node, field), ISO_EINVAL,
                           iso_scene__join(key, sizeof key, m->key, field), "%s", why);
}

static int box_end(scene_ctx *c, scene_map *m)
{
    const iso_scene_sel *sel = m->obj;
    for (int i = 0; i < 3; i++)
        if (sel->a[i] > sel->b[i])
            return sel_fail(c, m, "max", "expected max >= min on every axis");
    return ISO_OK;
}

static const scene_section box = {.name = "selection.box",
                                  .what = "{min: [x, y, z], max: [x, y, z]}",
                                  .keys = box_keys,
                                  .end = box_end};

static const scene_key sphere_keys[] = {
    {"center", SK_VEC3, FIELD(iso_scene_sel, a), SK_REQUIRED, .help = "the centre [x, y, z]"},
    {"radius", SK_NUMBER, FIELD(iso_scene_sel, radius), SK_REQUIRED, ABOVE(0),
     .help = "the radius (scene units)"},
    {.key = NULL},
};

static const scene_section sphere = {
    .name = "selection.sphere", .what = "{center: [x, y, z], radius: r}", .keys = sphere_keys};

static const scene_key beyond_keys[] = {
    {"point", SK_VEC3, FIELD(iso_scene_sel, a), SK_REQUIRED,
     .help = "a point on the plane [x, y, z]"},
    {"normal", SK_VEC3, FIELD(iso_scene_sel, b), SK_REQUIRED,
     .help = "the plane's normal [x, y, z], pointing to the side selected"},
    {.key = NULL},
};

static int beyond_end(scene_ctx *c, scene_map *m)
{
    const iso_scene_sel *sel = m->obj;
    if (sel->b[0] == 0 && sel->b[1] == 0 && sel->b[2] == 0)
        return sel_fail(c, m, "normal", "expected a non-zero normal");
    return ISO_OK;
}

static const scene_section beyond = {.name = "selection.beyond",
                                     .what = "{point: [x, y, z], normal: [x, y, z]}",
                                     .keys = beyond_keys,
                                     .end = beyond_end};

/* Owned by the selection: iso_scene_destroy frees it, counted as read. */
static int store_vertices(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    iso_scene_sel *sel = obj;
    int cnt, rc = iso_scene__list_count(c, k, v, key, &cnt);
    if (rc)
        return rc;
    sel->vertices = malloc((size_t)cnt * sizeof *sel->vertices);
    if (!sel->vertices)
        return iso_err_set(c->err, ISO_ENOMEM, -1, "out of memory");
    void *it = NULL;
    for (int i = 0; i < cnt; i++) {
        double d;
        if ((rc = iso_scene__number(c, k, fy_node_sequence_iterate(v, &it), key, &d)))
            return rc;
        sel->vertices[i] = (int)d;
        sel->n_vertices = i + 1;
    }
    return ISO_OK;
}

static const scene_key selection_keys[] = {
    {"vertices", SK_LIST, 0, 0, SK_ONE_OF, IN(0, 1L << 30), .min_items = 1, .store = store_vertices,
     .noun = "vertex indices", .type = "list of integers", .help = "vertices by index"},
    {"box", SK_SECTION, 0, 0, SK_ONE_OF, .sub = &box, .help = "the vertices in a box"},
    {"sphere", SK_SECTION, 0, 0, SK_ONE_OF, .sub = &sphere, .help = "the vertices in a ball"},
    {"beyond", SK_SECTION, 0, 0, SK_ONE_OF, .sub = &beyond,
     .help = "the vertices on the normal's side of a plane"},
    {.key = NULL},
};

static int selection_begin(scene_ctx *c, scene_map *m)
{
    iso_scene_sel *sel = m->obj;
    (void)c;
    iso_scene__mark(m->node, &sel->line, &sel->col);
    return ISO_OK;
}

_Static_assert(ISO_SCENE_SEL_VERTICES == 1 && ISO_SCENE_SEL_BOX == 2 && ISO_SCENE_SEL_SPHERE == 3 &&
                   ISO_SCENE_SEL_PLANE == 4 && sizeof(iso_scene_sel_kind) == sizeof(int),
               "selection_keys' SK_ONE_OF rows are in iso_scene_sel_kind's order (KIND_AT)");

/* Used by regions.fixed and each handle's select. */
static const scene_section selection = {.name = "selection",
                                        .what = "a selection: vertices, box, sphere or beyond",
                                        .keys = selection_keys,
                                        .begin = selection_begin,
                                        KIND_AT(iso_scene_sel, kind)};

/* ------------------------------------------------------------------------ */
/* Handles and regions                                                       */
/* ------------------------------------------------------------------------ */

static const scene_key handle_keys[] = {
    {"name", SK_STRING, FIELD(iso_scene_handle, name),
     .help = "the handle's name (channels and summaries use it)", .dflt = "handle0, handle1, ..."},
    {"select", SK_LIST, FIELD(iso_scene_handle, region.sel), SK_ONE_OR_LIST,
     .count_off = offsetof(iso_scene_handle, region.n_sel), .stride = sizeof(iso_scene_sel),
     .min_items = 1, .max_items = ISO_SCENE_MAX_SELECT, .sub = &selection, .noun = "selections",
     .type = "selection or list", .help = "its vertices: a selection or a list of them",
     .dflt = "the .sel's handle of this index"},
    {"driver", SK_SECTION, FIELD(iso_scene_handle, driver), SK_REQUIRED, .sub = &iso_scene__driver,
     .type = "none or mapping", .help = "none, {device, mapping}, {screw} or {keyframes}"},
    {.key = NULL},
};

static int handle_begin(scene_ctx *c, scene_map *m)
{
    iso_scene_handle *h = m->obj;
    (void)c;
    snprintf(h->name, sizeof h->name, "handle%d", m->item);
    return ISO_OK;
}

static int handle_end(scene_ctx *c, scene_map *m)
{
    iso_scene_handle *h = m->obj;
    const iso_scene_handle *all = h - m->item; /* the list's first */
    char key[ISO_SCENE_KEY_MAX];
    for (int j = 0; j < m->item; j++)
        if (strcmp(all[j].name, h->name) == 0)
            return iso_scene__fail(c, iso_scene__get(m->node, "name"), ISO_EPARSE,
                                   iso_scene__join(key, sizeof key, m->key, "name"),
                                   "handle name '%s' is used twice", h->name);
    h->from_sel = !iso_scene__get(m->node, "select"); /* the .sel's handle; checked when built */
    h->driver.map.n_handles = m->count;
    return ISO_OK;
}

static const scene_section handle = {.name = "regions.handles[]",
                                     .what = "a handle {name, select, driver}",
                                     .keys = handle_keys,
                                     .begin = handle_begin,
                                     .end = handle_end};

static const scene_key regions_keys[] = {
    {"sel", SK_FILE, FIELD(iso_scene, sel), .word = "builtin",
     .help = "a .sel file, or builtin: the benchmark's .sel or the shape's own labels "
             "(fixed + handle 0)",
     .dflt = "none: all free"},
    {"fixed", SK_LIST, FIELD(iso_scene, fixed.sel), SK_ONE_OR_LIST,
     .count_off = offsetof(iso_scene, fixed.n_sel), .stride = sizeof(iso_scene_sel), .min_items = 1,
     .max_items = ISO_SCENE_MAX_SELECT, .sub = &selection, .noun = "selections",
     .type = "selection or list",
     .help = "fixed vertices: a selection or a list of them (added to the .sel's)",
     .dflt = "the .sel's"},
    {"handles", SK_LIST, FIELD(iso_scene, handles), SK_REQUIRED,
     .count_off = offsetof(iso_scene, n_handles), .stride = sizeof(iso_scene_handle),
     .min_items = 1, .max_items = ISO_SCENE_MAX_HANDLES, .sub = &handle, .noun = "handles",
     .type = "list of handles", .help = "a list of handles, each with select and driver"},
    {.key = NULL},
};

/* Where `sel:` was written (or regions:), for the build step's messages. */
static int regions_end(scene_ctx *c, scene_map *m)
{
    iso_scene *s = m->obj;
    fnode *sel = iso_scene__get(m->node, "sel");
    (void)c;
    iso_scene__mark(sel ? sel : m->node, &s->sel_line, &s->sel_col);
    return ISO_OK;
}

const scene_section iso_scene__regions = {.name = "regions",
                                          .what = "a mapping with sel, fixed and handles",
                                          .keys = regions_keys,
                                          .end = regions_end};
