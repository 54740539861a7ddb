/* controller/cli_version.c -- `isoshape --version`: which CHOLMOD and which
 * BLAS this process actually runs with.
 *
 * Debian picks libblas.so.3 through update-alternatives, so the build cannot
 * know it: the netlib reference BLAS makes CHOLMOD's supernodal factorization
 * several times slower than OpenBLAS. We look at the loaded objects instead
 * (dl_iterate_phdr) and resolve the alternatives symlinks to the real file. */
#include "internal.h"

#include <cholmod.h>
#include <dlfcn.h>
#include <limits.h>
#include <link.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "iso_version.h"

#define MAX_BLAS_OBJECTS 8

typedef struct blas_scan {
    int n;
    char path[MAX_BLAS_OBJECTS][ISO_CLI_PATH_MAX];
} blas_scan;

static int is_blas_name(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    return strncmp(base, "libblas", 7) == 0 || strncmp(base, "libopenblas", 11) == 0 ||
           strncmp(base, "libblis", 7) == 0 || strncmp(base, "libmkl_rt", 9) == 0 ||
           strncmp(base, "libflexiblas", 12) == 0;
}

static int collect_blas(struct dl_phdr_info *info, size_t size, void *ctx)
{
    blas_scan *s = ctx;
    (void)size;
    if (!info->dlpi_name || !*info->dlpi_name || !is_blas_name(info->dlpi_name))
        return 0;
    if (s->n < MAX_BLAS_OBJECTS) {
        char real[PATH_MAX];
        const char *p = realpath(info->dlpi_name, real) ? real : info->dlpi_name;
        snprintf(s->path[s->n++], ISO_CLI_PATH_MAX, "%s", p);
    }
    return 0;
}

/* dlsym returns an object pointer; memcpy turns it into a function pointer
 * without the cast ISO C forbids. */
static void *lookup(const char *symbol, size_t fn_size, void *fn)
{
    void *sym = dlsym(RTLD_DEFAULT, symbol);
    if (sym)
        memcpy(fn, &sym, fn_size);
    return sym;
}

/* OpenBLAS 0.3.21 (Debian 12) does not recognise some current Xeons (they
 * report a generic model) and falls back to its Prescott (SSE3) kernels: on
 * this project's CI machine that doubled the CPU time of a CHOLMOD
 * factorization. The kernel set is chosen when the library loads, so the
 * only cure is the environment: when the fallback is active, the user has
 * not chosen a core type, and the CPU has AVX-512 or AVX2, set
 * OPENBLAS_CORETYPE and execute this program again. */
void iso_cli__tune_blas(char **argv)
{
    if (getenv("OPENBLAS_CORETYPE"))
        return; /* the user's choice, or we already did this */
    char *(*corename)(void) = NULL;
    if (!lookup("openblas_get_corename", sizeof corename, &corename))
        return;
    const char *core = corename();
    if (!core || strcasecmp(core, "Prescott") != 0)
        return;
    __builtin_cpu_init();
    const char *better = __builtin_cpu_supports("avx512f") ? "SkylakeX"
                         : __builtin_cpu_supports("avx2")  ? "Haswell"
                                                           : NULL;
    if (!better || setenv("OPENBLAS_CORETYPE", better, 1) != 0)
        return;
    execv("/proc/self/exe", argv);
    unsetenv("OPENBLAS_CORETYPE"); /* exec failed: carry on as we were */
}

static void print_cholmod(void)
{
    int (*version)(int *) = NULL;
    int v[3] = {0, 0, 0};
    printf("CHOLMOD ");
    if (lookup("cholmod_version", sizeof version, &version) && version) {
        version(v);
        printf("%d.%d.%d (run time), ", v[0], v[1], v[2]);
    } else {
        printf("not loaded yet, ");
    }
    printf("built against %d.%d.%d (%s)\n", CHOLMOD_MAIN_VERSION, CHOLMOD_SUB_VERSION,
           CHOLMOD_SUBSUB_VERSION, CHOLMOD_DATE);
}

static void print_blas(void)
{
    blas_scan s = {0};
    dl_iterate_phdr(collect_blas, &s);
    char *(*config)(void) = NULL;
    lookup("openblas_get_config", sizeof config, &config);
    char *(*corename)(void) = NULL;
    lookup("openblas_get_corename", sizeof corename, &corename);
    int reference = 0, openblas = config != NULL;
    for (int i = 0; i < s.n; i++) {
        if (strstr(s.path[i], "openblas"))
            openblas = 1;
        else if (strstr(s.path[i], "/blas/libblas")) /* netlib, Debian's libblas3 */
            reference = 1;
    }
    if (openblas && !reference) {
        const char *c = config ? config() : NULL;
        if (c && strncmp(c, "OpenBLAS", 8) == 0)
            printf("BLAS: %s\nBLAS kernels in use: %s%s\n", c, corename ? corename() : "?",
                   getenv("OPENBLAS_CORETYPE") ? " (OPENBLAS_CORETYPE)" : "");
        else
            printf("BLAS: OpenBLAS%s%s\n", c ? " " : "", c ? c : "");
    } else if (reference)
        printf("BLAS: reference BLAS (slow; install libopenblas0-pthread)\n");
    else if (s.n > 0)
        printf("BLAS: unrecognised\n");
    else
        printf("BLAS: none loaded\n");
    for (int i = 0; i < s.n; i++)
        printf("BLAS loaded from %s\n", s.path[i]);
}

const char *iso_cli__blas_config(void)
{
    char *(*config)(void) = NULL;
    const char *c = lookup("openblas_get_config", sizeof config, &config) ? config() : NULL;
    return c ? c : "";
}

/* The version lines of --version: isoshape, CHOLMOD (run time and build
 * time) and the BLAS that is loaded, with its resolved path. */
static void print_version(void)
{
    printf("isoshape %s\n", iso_version()); /* the library this runs with */
    print_cholmod();
    print_blas();
}

static const iso_cli__opt version_options[] = {{0}};

static int version_main(int argc, char **argv)
{
    int status = iso_cli__parse(&iso_cli__version_cmd, argc, argv, NULL, NULL, 0, NULL);
    if (status >= 0)
        return status;
    print_version();
    return 0;
}

const iso_cli__cmd iso_cli__version_cmd = {
    .name = "version",
    .usage = "usage: isoshape --version\n"
             "       isoshape version\n"
             "\n"
             "Prints the versions of isoshape and of the CHOLMOD it runs with (and was built\n"
             "against), and the BLAS that is loaded, with the file it was loaded from.\n",
    .opts = version_options,
    .main = version_main};
