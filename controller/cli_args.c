/* controller/cli_args.c -- option parsing and benchmark lookup for the
 * isoshape command. Every message names the option and the value, so a user
 * sees what to fix without reading the help. */
#include "internal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "iso_element.h"

void iso_cli__fail(const char *cmd, const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "isoshape%s%s: ", cmd ? " " : "", cmd ? cmd : "");
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

int iso_cli__value(const char *cmd, int argc, char **argv, int *i, const char *name,
                   const char **val)
{
    const char *arg = argv[*i];
    size_t n = strlen(name);
    if (strncmp(arg, name, n) != 0)
        return 0;
    if (arg[n] == '=') {
        *val = arg + n + 1;
        return 1;
    }
    if (arg[n] != '\0')
        return 0;
    if (*i + 1 >= argc) {
        iso_cli__fail(cmd, "option %s needs a value (see isoshape %s --help).", name, cmd);
        return -1;
    }
    *val = argv[++*i];
    return 1;
}

int iso_cli__double(const char *cmd, const char *opt, const char *val, double *out)
{
    char *end;
    errno = 0;
    double d = strtod(val, &end);
    if (end == val || *end != '\0' || errno == ERANGE || !isfinite(d)) {
        iso_cli__fail(cmd, "%s '%s' is not a finite number.", opt, val);
        return -1;
    }
    *out = d;
    return 0;
}

int iso_cli__int(const char *cmd, const char *opt, const char *val, int *out)
{
    char *end;
    errno = 0;
    long l = strtol(val, &end, 10);
    if (end == val || *end != '\0' || errno == ERANGE || l < INT_MIN || l > INT_MAX) {
        iso_cli__fail(cmd, "%s '%s' is not an integer.", opt, val);
        return -1;
    }
    *out = (int)l;
    return 0;
}

int iso_cli__unknown(const char *cmd, const char *arg)
{
    if (arg[0] == '-')
        iso_cli__fail(cmd, "unknown option '%s' (see isoshape %s --help).", arg, cmd);
    else
        iso_cli__fail(cmd, "unexpected argument '%s' (see isoshape %s --help).", arg, cmd);
    return 2;
}

int iso_cli__omega(const char *cmd, const char *val, double *omega)
{
    double w;
    if (iso_cli__double(cmd, "--omega", val, &w) != 0)
        return -1;
    if (!(w > 0.0 && w <= 1.0)) {
        iso_cli__fail(cmd,
                      "--omega %s is outside (0, 1]: at 0 a flat region makes the system "
                      "singular, and above 1 the distortion term turns negative.",
                      val);
        return -1;
    }
    *omega = w;
    return 0;
}

int iso_cli__enum(const char *cmd, const char *opt, const char *val, const char *const *names,
                  int *out)
{
    int v = iso_names_find(names, val);
    if (v < 0) {
        char all[256];
        iso_cli__fail(cmd, "%s %s: use %s.", opt, val,
                      iso_names_list(names, " or ", all, sizeof all));
        return -1;
    }
    *out = v;
    return 0;
}

int iso_cli__restore(const char *cmd, const char *val, double *mu, double *tau)
{
    if (strcmp(val, "off") == 0) {
        *mu = 0.0;
        *tau = 0.0;
        return 0;
    }
    const char *comma = strchr(val, ',');
    char num[64];
    if (!comma || (size_t)(comma - val) >= sizeof num) {
        iso_cli__fail(cmd, "--restore '%s' is not MU,TAU (e.g. 1,0.05) or off.", val);
        return -1;
    }
    memcpy(num, val, (size_t)(comma - val));
    num[comma - val] = '\0';
    double m, t;
    if (iso_cli__double(cmd, "--restore MU", num, &m) != 0 ||
        iso_cli__double(cmd, "--restore TAU", comma + 1, &t) != 0)
        return -1;
    if (!(m >= 0.0)) {
        iso_cli__fail(cmd, "--restore %s: the weight MU must be >= 0 (0 = off).", val);
        return -1;
    }
    if (m > 0.0 && !(t > 0.0)) {
        iso_cli__fail(cmd, "--restore %s: the time constant TAU must be positive.", val);
        return -1;
    }
    *mu = m;
    *tau = m > 0.0 ? t : 0.0;
    return 0;
}

/* ------------------------------------------------------------------------ */
/* The benchmark                                                              */
/* ------------------------------------------------------------------------ */

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
