/* config/scene_drivers.c -- what drives a handle (regions.handles[].driver):
 * nothing, a device through a mapping, a .def screw motion over a duration,
 * or keyframes. A device mapping's defaults and numeric ranges are the
 * devices layer's (iso_dev_map_opts_default, iso_dev_map_check), the same
 * as on the command line. */
#include "internal.h"

#include <libfyaml.h>
#include <string.h>

#include "iso_names.h"

/* ------------------------------------------------------------------------ */
/* Device mappings                                                           */
/* ------------------------------------------------------------------------ */

/* One number of a per-axis value, in the range devices/ holds k->dev to. */
static int axis_value(scene_ctx *c, const scene_key *k, fnode *e, const char *key, double *out)
{
    return iso_scene__number(c, k, e, key, out);
}

/* {tx: .., rz: ..}: some of the six, the rest as they were. */
static int axes_by_name(scene_ctx *c, const scene_key *k, fnode *v, const char *key, double *out)
{
    int rc = iso_scene__check_keys(c, v, key, iso_dev_axis_names);
    for (int i = 0; rc == ISO_OK && i < 6; i++) {
        fnode *e = iso_scene__get(v, iso_dev_axis_names[i]);
        char sub[ISO_SCENE_KEY_MAX];
        if (e)
            rc = axis_value(c, k, e, iso_scene__join(sub, sizeof sub, key, iso_dev_axis_names[i]),
                            &out[i]);
    }
    return rc;
}

/* A per-axis value: one number for all six axes, a list of six, or a
 * mapping of some of tx..rz. */
static int store_axes(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    double *out = (double *)((char *)obj + k->off), x;
    int rc = ISO_OK;
    if (v && fy_node_is_scalar(v)) {
        if ((rc = axis_value(c, k, v, key, &x)) == ISO_OK)
            for (int i = 0; i < 6; i++)
                out[i] = x;
        return rc;
    }
    if (v && fy_node_is_sequence(v) && fy_node_sequence_item_count(v) == 6) {
        void *it = NULL;
        for (int i = 0; rc == ISO_OK && i < 6; i++)
            rc = axis_value(c, k, fy_node_sequence_iterate(v, &it), key, &out[i]);
        return rc;
    }
    if (v && fy_node_is_mapping(v))
        return axes_by_name(c, k, v, key, out);
    return iso_scene__fail(c, v, ISO_EPARSE, key,
                           "expected a number, a list of 6 numbers or a mapping of "
                           "tx, ty, tz, rx, ry, rz; found %s",
                           iso_scene__type_name(v));
}

static int store_remap(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    int *remap = (int *)((char *)obj + k->off), rc;
    if ((rc = iso_scene__want_map(c, v, key,
                                  "a mapping output axis: input axis, e.g. {ty: tz, tz: ty}")) ||
        (rc = iso_scene__check_keys(c, v, key, iso_dev_axis_names)))
        return rc;
    for (int i = 0; i < 6; i++) {
        fnode *e = iso_scene__get(v, iso_dev_axis_names[i]);
        char sub[ISO_SCENE_KEY_MAX];
        if (e && (rc = iso_scene__to_enum(
                      c, e, iso_scene__join(sub, sizeof sub, key, iso_dev_axis_names[i]),
                      iso_dev_axis_names, &remap[i])))
            return rc;
    }
    return ISO_OK;
}

static int store_invert(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    int *invert = (int *)((char *)obj + k->off), n, rc;
    if ((rc = iso_scene__list_count(c, k, v, key, &n)))
        return rc;
    void *it = NULL;
    fnode *e;
    while ((e = fy_node_sequence_iterate(v, &it))) {
        int a;
        if ((rc = iso_scene__to_enum(c, e, key, k->names, &a)))
            return rc;
        invert[a] = 1;
    }
    return ISO_OK;
}

/* An action per button bit, from bit 0; the rest none. */
static int store_buttons(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    uint8_t *action = (uint8_t *)obj + k->off;
    int n, rc;
    if ((rc = iso_scene__list_count(c, k, v, key, &n)))
        return rc;
    memset(action, 0, k->size);
    void *it = NULL;
    fnode *e;
    for (int i = 0; (e = fy_node_sequence_iterate(v, &it)); i++) {
        int a;
        if ((rc = iso_scene__to_enum(c, e, key, k->names, &a)))
            return rc;
        action[i] = (uint8_t)a;
    }
    return ISO_OK;
}

#define AXES_TYPE "number, list of 6 or {tx, ty, tz, rx, ry, rz}"

static const scene_key mapping_keys[] = {
    {"full_scale", SK_NUMBER, FIELD(iso_dev_map_opts, full_scale), .dev = "full_scale",
     .help = "raw counts at full deflection", .dflt = "350"},
    {"sensitivity", SK_NUMBER, FIELD(iso_dev_map_opts, sensitivity), .dev = "sensitivity",
     .store = store_axes, .type = AXES_TYPE,
     .help = "output at full scale per axis: m/s (tx, ty, tz), rad/s (rx, ry, rz)",
     .dflt = "0.1 (tx, ty, tz), 0.5 (rx, ry, rz)"},
    {"dead_zone", SK_NUMBER, FIELD(iso_dev_map_opts, dead_zone), .dev = "dead_zone",
     .store = store_axes, .type = AXES_TYPE,
     .help = "the fraction of full scale that maps to 0, per axis", .dflt = "0.05"},
    {"curve", SK_NUMBER, FIELD(iso_dev_map_opts, curve), .dev = "curve", .store = store_axes,
     .type = AXES_TYPE, .help = "the response exponent per axis (1 linear, 2 quadratic)",
     .dflt = "1"},
    {"remap", SK_MAP, FIELD(iso_dev_map_opts, remap), .store = store_remap,
     .type = "{OUT: IN, ...}",
     .help = "the input axis each output axis reads, e.g. {ty: tz, tz: ty}",
     .dflt = "each its own"},
    {"invert", SK_LIST, FIELD(iso_dev_map_opts, invert), .names = iso_dev_axis_names,
     .store = store_invert, .noun = "axes", .type = "list of axes",
     .help = "the output axes to negate", .dflt = "none"},
    {"dominant", SK_BOOL, FIELD(iso_dev_map_opts, dominant), .help = "keep only the largest axis",
     .dflt = "false"},
    {"lock", SK_ENUM, FIELD(iso_dev_map_opts, lock), .names = iso_dev_lock_names,
     .help = "the axes held still", .dflt = "none"},
    {"frame", SK_ENUM, FIELD(iso_dev_map_opts, frame), .names = iso_dev_frame_names,
     .help = "whose axes the device moves along: the world's or the handle's", .dflt = "world"},
    {"clutch", SK_ENUM, FIELD(iso_dev_map_opts, clutch_is_deadman), .names = iso_dev_clutch_names,
     .help = "hold: the clutch held holds still; deadman: moves only while held", .dflt = "hold"},
    {"buttons", SK_LIST, FIELD(iso_dev_map_opts, button_action), .max_items = 32,
     .names = iso_dev_action_names, .store = store_buttons, .noun = "actions",
     .type = "list of actions", .help = "an action per button, by button bit (the rest none)",
     .dflt = "clutch, next_handle"},
    {"pose_gain", SK_NUMBER, FIELD(iso_dev_map_opts, pose_gain), .dev = "pose_gain",
     .help = "pose streams: the fraction of the error closed per tick", .dflt = "1"},
    {"pose_scale", SK_NUMBER, FIELD(iso_dev_map_opts, pose_scale), .dev = "pose_scale",
     .help = "pose streams: their units to scene units", .dflt = "1"},
    {.key = NULL},
};

static const scene_section mapping = {
    .name = "regions.handles[].driver.mapping", .what = "a device mapping", .keys = mapping_keys};

/* ------------------------------------------------------------------------ */
/* Screws and keyframes                                                      */
/* ------------------------------------------------------------------------ */

static const scene_key screw_keys[] = {
    {"def", SK_FILE, FIELD(iso_scene_driver, def), SK_WORD_EMPTY, .word = "builtin",
     .help = "a .def file, or builtin: the benchmark's or the shape's own motion",
     .dflt = "builtin"},
    {"duration", SK_NUMBER, FIELD(iso_scene_driver, duration), SK_REQUIRED, ABOVE(0),
     .help = "the motion's length in seconds"},
    {.key = NULL},
};

static const scene_section screw = {.name = "regions.handles[].driver.screw",
                                    .what = "{def: FILE or builtin, duration: seconds}",
                                    .keys = screw_keys};

static const scene_key keyframe_keys[] = {
    {"t", SK_NUMBER, FIELD(iso_scene_keyframe, t), SK_REQUIRED, AT_LEAST(0),
     .help = "the keyframe's time in seconds, strictly increasing"},
    {"translate", SK_VEC3, FIELD(iso_scene_keyframe, translate),
     .help = "the handle's translation [x, y, z] (scene units)", .dflt = "[0, 0, 0]"},
    {"rotate", SK_VEC3, FIELD(iso_scene_keyframe, rotate),
     .help = "its rotation vector [rx, ry, rz] in degrees (axis times angle)", .dflt = "[0, 0, 0]"},
    {.key = NULL},
};

static int keyframe_end(scene_ctx *c, scene_map *m)
{
    const iso_scene_keyframe *k = m->obj;
    char key[ISO_SCENE_KEY_MAX];
    if (m->item > 0 && !(k->t > k[-1].t))
        return iso_scene__fail(c, iso_scene__get(m->node, "t"), ISO_EINVAL,
                               iso_scene__join(key, sizeof key, m->key, "t"),
                               "expected times strictly increasing, found %g after %g", k->t,
                               k[-1].t);
    return ISO_OK;
}

static const scene_section keyframe = {.name = "regions.handles[].driver.keyframes[]",
                                       .what = "a keyframe {t, translate, rotate}",
                                       .keys = keyframe_keys,
                                       .end = keyframe_end};

/* ------------------------------------------------------------------------ */
/* The driver                                                                */
/* ------------------------------------------------------------------------ */

/* A device of the scene's list, by name; its index goes to d->device. */
static int store_device(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    iso_scene_driver *d = obj;
    const iso_scene *s = c->s;
    const char *t = iso_scene__scalar(c, v);
    (void)k;
    if (!t)
        return iso_scene__fail(c, v, ISO_EPARSE, key, "expected a device name, found %s",
                               iso_scene__type_name(v));
    const char *names[ISO_SCENE_MAX_DEVICES + 1];
    for (int i = 0; i < s->n_devices; i++)
        names[i] = s->devices[i].name;
    names[s->n_devices] = NULL;
    if ((d->device = iso_names_find(names, t)) >= 0)
        return ISO_OK;
    if (s->n_devices == 0)
        return iso_scene__fail(c, v, ISO_EPARSE, key,
                               "no device '%s': the scene's devices list is empty", t);
    char what[300];
    snprintf(what, sizeof what, "no device '%s'", t);
    return iso_scene__refuse_word(c, v, key, what, t, names, "devices:");
}

static const scene_key driver_keys[] = {
    {"device", SK_STRING, 0, 0, SK_ONE_OF, .store = store_device, .type = "device name",
     .help = "a device of the scene's devices list, by name"},
    {"mapping", SK_SECTION, FIELD(iso_scene_driver, map), .with = "device", .sub = &mapping,
     .help = "how the device's axes and buttons move the handle", .dflt = "the devices layer's"},
    {"screw", SK_SECTION, 0, 0, SK_ONE_OF, .sub = &screw,
     .help = "the .def rigid motion as a screw over a duration"},
    {"keyframes", SK_LIST, FIELD(iso_scene_driver, keys), SK_ONE_OF,
     .count_off = offsetof(iso_scene_driver, n_keys), .stride = sizeof(iso_scene_keyframe),
     .min_items = 1, .max_items = ISO_SCENE_MAX_KEYFRAMES, .sub = &keyframe, .noun = "keyframes",
     .type = "list of keyframes", .help = "poses at times, interpolated"},
    {.key = NULL},
};

static int driver_begin(scene_ctx *c, scene_map *m)
{
    iso_scene_driver *d = m->obj;
    (void)c;
    iso_dev_map_opts_default(&d->map);
    d->device = -1;
    return ISO_OK;
}

/* `driver: none`: held still. */
static int driver_none(scene_ctx *c, scene_map *m)
{
    iso_scene_driver *d = m->obj;
    const char *t = iso_scene__scalar(c, m->node);
    if (t && strcmp(t, "none") == 0)
        return (d->kind = ISO_SCENE_DRIVE_NONE), ISO_OK;
    return iso_scene__want_map(c, m->node, m->key, iso_scene__driver.what);
}

_Static_assert(ISO_SCENE_DRIVE_DEVICE == 1 && ISO_SCENE_DRIVE_SCREW == 2 &&
                   ISO_SCENE_DRIVE_KEYFRAMES == 3 && sizeof(iso_scene_driver_kind) == sizeof(int),
               "driver_keys' SK_ONE_OF rows are in iso_scene_driver_kind's order (KIND_AT)");

const scene_section iso_scene__driver = {.name = "regions.handles[].driver",
                                         .what = "none, {device, mapping}, {screw} or {keyframes}",
                                         .keys = driver_keys,
                                         .begin = driver_begin,
                                         .scalar = driver_none,
                                         KIND_AT(iso_scene_driver, kind)};
