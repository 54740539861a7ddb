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

void iso_scene__doc_table(FILE *out); /* config/internal.h */

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = NULL;
    size_t n = 0, cap = 0, got;
    char chunk[4096];
    while ((got = fread(chunk, 1, sizeof chunk, f)) > 0) {
        if (n + got + 1 > cap) {
            cap = 2 * (n + got + 1);
            char *grown = realloc(buf, cap);
            if (!grown) {
                free(buf);
                fclose(f);
                return NULL;
            }
            buf = grown;
        }
        memcpy(buf + n, chunk, got);
        n += got;
    }
    fclose(f);
    if (buf)
        buf[n] = '\0';
    return buf;
}

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
    char *text = slurp(argv[1]);
    if (!text) {
        perror(argv[1]);
        return 1;
    }
    int rc = rewrite(argv[1], text);
    free(text);
    return rc;
}
