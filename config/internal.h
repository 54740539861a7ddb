/* config/internal.h -- what the scene files share: the YAML walking context
 * (file, current key, error) and the build step. Not installed. */
#ifndef ISO_SCENE_INTERNAL_H
#define ISO_SCENE_INTERNAL_H

#include "iso_scene.h"

/* Builds what a parsed scene describes: loads the mesh (resolving the
 * benchmark through opts), builds the regions from the .sel and the
 * selections, loads .def files and makes their twists. Errors name the
 * scene file, the selection's line:col and its key. (scene_build.c) */
int iso_scene__build(iso_scene *s, const iso_scene_opts *opts, iso_err *err);

/* Joins a name from the scene with the scene's folder (absolute names stay). */
int iso_scene__resolve(const iso_scene *s, const char *name, char *out, size_t cap);

/* Levenshtein distance, capped at 255 (nearest-key suggestions). */
int iso_scene__distance(const char *a, const char *b);

#endif
