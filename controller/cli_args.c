/* controller/cli_args.c -- where the benchmark problems are: the folders
 * --benchmark-dir, $ISOSHAPE_BENCHMARK_DIR and the places near the program
 * that deform, bench and scenes look in, and the files of each problem
 * there. (The options it once parsed by hand are tables now, cli_opts.c;
 * config/iso_scene.h names this file for the lookup.) */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct bench_layout {
    const char *name, *folder, *stem;
} bench_layout;

static const bench_layout layouts[] = {
    {"bumpplane", "00-plane-lift", "knubbel"},
    {"cylinder", "01-cylinder-bend", "cylinder"},
    {"bar", "02-bar-twist", "bar"},
    {"cactus", "03-cactus-bend", "cactus"},
};

static const bench_layout *layout_of(const char *name)
{
    for (size_t i = 0; i < sizeof layouts / sizeof layouts[0]; i++)
        if (strcmp(layouts[i].name, name) == 0)
            return &layouts[i];
    return NULL;
}

int iso_cli__bench_known(const char *name)
{
    return layout_of(name) != NULL;
}

static int is_file(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* Fills b from dir; 1 if the three input files exist. */
static int try_dir(const bench_layout *l, const char *dir, iso_cli__bench *b)
{
    int n = snprintf(b->dir, sizeof b->dir, "%s", dir);
    n |= snprintf(b->mesh, sizeof b->mesh, "%s/%s/%s.off", dir, l->folder, l->stem);
    n |= snprintf(b->sel, sizeof b->sel, "%s/%s/%s.sel", dir, l->folder, l->stem);
    n |= snprintf(b->def, sizeof b->def, "%s/%s/%s.def", dir, l->folder, l->stem);
    n |= snprintf(b->ref, sizeof b->ref, "%s/%s/%s-laplacian_editing.off", dir, l->folder, l->stem);
    if (n < 0)
        return 0;
    return is_file(b->mesh) && is_file(b->sel) && is_file(b->def);
}

static void append(char *why, size_t cap, const char *path)
{
    size_t len = strlen(why);
    if (len < cap)
        snprintf(why + len, cap - len, "%s%s", len ? ", " : "", path);
}

int iso_cli__bench_find(const char *name, const char *dir_opt, iso_cli__bench *b, char *why,
                        size_t why_cap)
{
    const bench_layout *l = layout_of(name);
    why[0] = '\0';
    if (!l)
        return 0;
    /* An explicit folder is the only one looked at: falling back past it
     * would hide a typo. */
    const char *env = getenv("ISOSHAPE_BENCHMARK_DIR");
    if (dir_opt || (env && *env)) {
        const char *dir = dir_opt ? dir_opt : env;
        if (try_dir(l, dir, b))
            return 1;
        append(why, why_cap, dir);
        return 0;
    }
    if (try_dir(l, "../shared/data/benchmark", b))
        return 1;
    append(why, why_cap, "../shared/data/benchmark");
    char exe[ISO_CLI_PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0)
        return 0;
    exe[n] = '\0';
    for (int up = 0; up < 4; up++) {
        char *slash = strrchr(exe, '/');
        if (!slash || slash == exe)
            break;
        *slash = '\0';
        char dir[ISO_CLI_PATH_MAX + 32];
        snprintf(dir, sizeof dir, "%s/../shared/data/benchmark", exe);
        if (try_dir(l, dir, b))
            return 1;
        append(why, why_cap, dir);
    }
    return 0;
}
