/* config/scene_mesh.c -- the scene's `mesh:` section: a mesh file, a
 * built-in shape, or a benchmark problem with a built-in shape standing in
 * when the benchmark data is absent (scene_build.c loads it). */
#include "internal.h"

#include <string.h>

#include "iso_shapes.h"

/* The benchmark's problems, as --benchmark names them. */
static const char *const problems[] = {"bumpplane", "cylinder", "bar", "cactus", NULL};

static const scene_key mesh_keys[] = {
    {"path", SK_FILE, FIELD(iso_scene_mesh_src, path), SK_ONE_OF,
     .help = "a mesh file (OFF, OBJ or PLY)"},
    {"shape", SK_ENUM, FIELD(iso_scene_mesh_src, shape), SK_ONE_OF | SK_AS_TEXT,
     .names_fn = iso_shape_names, .help = "a built-in shape"},
    {"resolution", SK_INT, FIELD(iso_scene_mesh_src, resolution), IN(0, 4096),
     .with = "shape benchmark",
     .help = "the built-in shape's resolution (a benchmark's fallback's)",
     .dflt = "0 (the shape's own)"},
    {"benchmark", SK_ENUM, FIELD(iso_scene_mesh_src, benchmark), SK_ONE_OF | SK_AS_TEXT,
     .names = problems, .help = "a benchmark problem, found as --benchmark finds it"},
    {"fallback_shape", SK_ENUM, FIELD(iso_scene_mesh_src, fallback_shape), SK_AS_TEXT,
     .names_fn = iso_shape_names, .with = "benchmark",
     .help = "the built-in shape that stands in when the benchmark is absent",
     .dflt = "none: a missing benchmark is an error"},
    {.key = NULL},
};

/* Where `mesh:` was written, for the build step's messages. */
static int mesh_begin(scene_ctx *c, scene_map *m)
{
    iso_scene_mesh_src *src = m->obj;
    (void)c;
    iso_scene__mark(m->node, &src->line, &src->col);
    return ISO_OK;
}

/* `mesh: FILE` is short for {path: FILE}. */
static int mesh_file(scene_ctx *c, scene_map *m)
{
    iso_scene_mesh_src *src = m->obj;
    src->kind = ISO_SCENE_MESH_FILE;
    return iso_scene__to_file(c, m->node, m->key, src->path, sizeof src->path);
}

_Static_assert(ISO_SCENE_MESH_FILE == 1 && ISO_SCENE_MESH_SHAPE == 2 &&
                   ISO_SCENE_MESH_BENCHMARK == 3 && sizeof(iso_scene_mesh_kind) == sizeof(int),
               "mesh_keys' SK_ONE_OF rows are in iso_scene_mesh_kind's order (KIND_AT)");

const scene_section iso_scene__mesh = {
    .name = "mesh",
    .what = "a mesh file name or a mapping with path, shape or benchmark",
    .keys = mesh_keys,
    .begin = mesh_begin,
    .scalar = mesh_file,
    KIND_AT(iso_scene_mesh_src, kind)};
