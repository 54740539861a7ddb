/* config/scene_doc.c -- SCENES.md's key table, from the sections' tables.
 *
 * One row per key, `section.key` (a list's items are `list[]`), in the
 * order the walk reads them, each section after the one it hangs from.
 * test_scene holds SCENES.md to this; tests/tools/scene_keys writes it. */
#include "internal.h"

#include <string.h>

#include "iso_names.h"

/* A cell's text, with the table's separator escaped. */
static void cell(FILE *out, const char *text)
{
    fputs(*text ? " " : "", out);
    for (const char *p = text; *p; p++) {
        if (*p == '|')
            fputc('\\', out);
        fputc(*p, out);
    }
    fputs(" |", out);
}

static const char *type_text(const scene_key *k, char *buf, size_t cap)
{
    static const char *const kinds[] = {"",        "number",  "integer", "true or false", "text",
                                        "file",    "path",    "",        "[x, y, z]",     "list",
                                        "mapping", "mapping", NULL};
    if (k->type)
        return k->type;
    if (k->kind == SK_ENUM)
        return iso_names_list(iso_scene__names(k), " or ", buf, cap);
    if (k->kind == SK_FILE && k->word)
        snprintf(buf, cap, "file or %s", k->word);
    else
        snprintf(buf, cap, "%s", iso_names_get(kinds, (int)k->kind));
    return buf;
}

/* The value's range, and a list's length. */
static const char *range_text(const scene_key *k, char *buf, size_t cap)
{
    char items[64] = "";
    iso_scene__range_text(k, buf, cap);
    if (k->kind == SK_LIST && k->min_items > 0 && k->max_items > 0)
        snprintf(items, sizeof items, "%d to %d items", k->min_items, k->max_items);
    else if (k->kind == SK_LIST && k->max_items > 0)
        snprintf(items, sizeof items, "at most %d items", k->max_items);
    else if (k->kind == SK_LIST && k->min_items > 0)
        snprintf(items, sizeof items, "at least %d item", k->min_items);
    if (items[0]) {
        size_t n = strlen(buf);
        snprintf(buf + n, cap - n, "%s%s", n ? "; " : "", items);
    }
    return buf;
}

/* "required", "required for tty; DEFAULT", "one of ...", or the default. */
static const char *default_text(const scene_section *sec, const scene_key *k, char *buf, size_t cap)
{
    if (k->flags & SK_REQUIRED)
        return "required";
    if (k->flags & SK_ONE_OF) {
        const char *names[ISO_SCENE_SECTION_KEYS + 1];
        int n = 0;
        for (const scene_key *o = sec->keys; o->key && n < ISO_SCENE_SECTION_KEYS; o++)
            if (o->flags & SK_ONE_OF)
                names[n++] = o->key;
        names[n] = NULL;
        char list[128];
        snprintf(buf, cap, "exactly one of %s", iso_names_list(names, " or ", list, sizeof list));
        return buf;
    }
    if (k->need) {
        char need[128];
        iso_scene__words_list(k->need, " or ", need, sizeof need);
        snprintf(buf, cap, "required for %s%s%s", need, k->dflt ? "; " : "",
                 k->dflt ? k->dflt : "");
        return buf;
    }
    return k->dflt ? k->dflt : "";
}

static void row(FILE *out, const scene_section *sec, const scene_key *k)
{
    char key[ISO_SCENE_KEY_MAX], buf[256];
    fputs("|", out);
    fprintf(out, " `%s` |", iso_scene__join(key, sizeof key, sec->name, k->key));
    cell(out, type_text(k, buf, sizeof buf));
    cell(out, range_text(k, buf, sizeof buf));
    cell(out, default_text(sec, k, buf, sizeof buf));
    cell(out, k->with ? iso_scene__words_list(k->with, ", ", buf, sizeof buf) : "");
    cell(out, k->help);
    fputs("\n", out);
}

/* sec's rows, then each section under it once (a selection is under two). */
static void section(FILE *out, const scene_section *sec, const scene_section **done, int *n_done)
{
    for (int i = 0; i < *n_done; i++)
        if (done[i] == sec)
            return;
    if (*n_done < 64)
        done[(*n_done)++] = sec;
    for (const scene_key *k = sec->keys; k->key; k++)
        row(out, sec, k);
    for (const scene_key *k = sec->keys; k->key; k++)
        if (k->sub)
            section(out, k->sub, done, n_done);
}

void iso_scene__doc_table(FILE *out)
{
    const scene_section *done[64];
    int n_done = 0;
    fputs("| key | type | range | default | with | what |\n", out);
    fputs("|---|---|---|---|---|---|\n", out);
    section(out, &iso_scene__schema, done, &n_done);
}
