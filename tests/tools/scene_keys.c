/* tests/tools/scene_keys.c -- SCENES.md's key table, from the scene schema
 * (config/internal.h: one table of keys per section).
 *
 *   scene_keys              prints the table
 *   scene_keys SCENES.md    rewrites the table in that file, between its
 *                           "<!-- keys: begin" and "<!-- keys: end" lines
 *
 * test_scene fails while the file and the schema disagree; this writes the
 * file the schema's way. White-box: it links isoshape_internal. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_file.h"

void iso_scene__doc_table(FILE *out); /* config/internal.h */

/* Writes text with the lines between the markers replaced by the table. */
static int rewrite(const char *path, const char *text)
{
    const char *begin = strstr(text, "<!-- keys: begin");
    const char *end = begin ? strstr(begin, "<!-- keys: end") : NULL;
    const char *after_begin = begin ? strchr(begin, '\n') : NULL;
    if (!begin || !end || !after_begin || after_begin > end) {
        fprintf(stderr, "scene_keys: %s has no '<!-- keys: begin' ... '<!-- keys: end' lines\n",
                path);
        return 1;
    }
    FILE *f = fopen(path, "wb");
    if (!f) {
        perror(path);
        return 1;
    }
    fwrite(text, 1, (size_t)(after_begin + 1 - text), f);
    iso_scene__doc_table(f);
    fputs(end, f);
    return fclose(f) == 0 ? 0 : 1;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        iso_scene__doc_table(stdout);
        return 0;
    }
    char *text = NULL;
    size_t len = 0;
    iso_err err;
    iso_err_clear(&err);
    if (iso_file_read(argv[1], 0, &text, &len, &err) != ISO_OK) {
        fprintf(stderr, "scene_keys: %s\n", err.msg);
        return 1;
    }
    int rc = rewrite(argv[1], text);
    free(text);
    return rc;
}
