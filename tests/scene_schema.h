/* tests/scene_schema.h -- the scene schema (config/internal.h) as the
 * white-box tests walk it: where each section is written in a smallest
 * scene, a value for each row, and the smallest content that holds a row
 * with a value. test_scene holds the reader to the schema with it, and
 * test_scene_agree holds `isoshape check` and `isoshape run` to each other. */
#ifndef ISO_TEST_SCENE_SCHEMA_H
#define ISO_TEST_SCENE_SCHEMA_H

#include <stddef.h>

#include "internal.h" /* config/: the scene schema */
#include "iso_scene.h"

/* Where a section is written in a scene: `doc` with %s where the section's
 * mapping content goes, `path` its key path in messages, and off, size:
 * where its struct lies in iso_scene. */
struct place {
    const char *section, *path, *doc;
    size_t off, size;
};

const struct place *place_of(const scene_section *sec);
/* Every section once, from the top: n of them into all. */
int all_sections(const scene_section **all, int cap);
const char *const *names_of(const scene_key *k);
/* A value of k's range (or of the devices layer's, for dev). */
double number_in_range(const scene_key *k);
/* A value for row k of sec, as YAML, into buf. */
const char *sample(const scene_section *sec, const scene_key *k, const char *variant, char *buf,
                   size_t cap);
int required_for(const scene_key *k, const char *variant);
/* The variant that row k needs: its first `with`, itself if SK_ONE_OF, or
 * the section's first (SK_ONE_OF key or selector's name). */
const char *variant_for(const scene_section *sec, const scene_key *k, char *buf, size_t cap);
/* The smallest content of sec that holds row k with `value`, into buf.
 * value NULL: k only chooses the variant and is left out. */
const char *content(const scene_section *sec, const scene_key *k, const char *value, char *buf,
                    size_t cap);
/* Loads sec's place with `what` as its content (parsing only). */
int load_section(const scene_section *sec, const char *what, iso_scene **s, iso_err *err);

#endif
