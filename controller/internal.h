/* controller/internal.h -- what the isoshape command's files share: option
 * parsing that names the option in every error, locating the benchmark, and
 * the run-time library report of --version. Not installed. */
#ifndef ISO_CLI_INTERNAL_H
#define ISO_CLI_INTERNAL_H

#include <stddef.h>

#include "iso_err.h"

#define ISO_CLI_PATH_MAX 4096

/* Subcommands: argv[0] is the subcommand's name. Return the exit status. */
int iso_cli__deform(int argc, char **argv);
int iso_cli__field(int argc, char **argv);
int iso_cli__metrics(int argc, char **argv);

/* Prints "isoshape <cmd>: <message>\n" on stderr. */
void iso_cli__fail(const char *cmd, const char *fmt, ...) ISO_PRINTF(2, 3);

/* If argv[*i] is `name` or `name=VALUE`, stores the value (VALUE or the
 * next argument, which *i then skips) in *val and returns 1; returns -1
 * after reporting a missing value; returns 0 if argv[*i] is not `name`. */
int iso_cli__value(const char *cmd, int argc, char **argv, int *i, const char *name,
                   const char **val);

/* Strict number parsing: the whole text must be a finite number. Each
 * returns 0, or -1 after reporting "--opt VALUE is not a number". */
int iso_cli__double(const char *cmd, const char *opt, const char *val, double *out);
int iso_cli__int(const char *cmd, const char *opt, const char *val, int *out);

/* Reports an unknown option or a stray argument; always returns 2. */
int iso_cli__unknown(const char *cmd, const char *arg);

/* Parses --omega and --weighting values into solver options (see
 * iso_solver.h); returns 0 or -1 after reporting. */
int iso_cli__omega(const char *cmd, const char *val, double *omega);
int iso_cli__weighting(const char *cmd, const char *val, int *weighting);

/* The files of one benchmark problem. */
typedef struct iso_cli__bench {
    char dir[ISO_CLI_PATH_MAX];
    char mesh[ISO_CLI_PATH_MAX], sel[ISO_CLI_PATH_MAX], def[ISO_CLI_PATH_MAX],
        ref[ISO_CLI_PATH_MAX];
} iso_cli__bench;

/* 1 if `name` is a benchmark problem (cactus, bar, cylinder, bumpplane). */
int iso_cli__bench_known(const char *name);

/* Finds problem `name` under, in order: dir_opt (--benchmark-dir), the
 * environment's ISOSHAPE_BENCHMARK_DIR, ../shared/data/benchmark from the
 * current folder, and ../shared/data/benchmark from each of the
 * executable's first four ancestor folders (a build folder inside the
 * source tree). Returns 1 and fills *b when its mesh, .sel and .def are
 * there; returns 0 and writes where it looked into why. */
int iso_cli__bench_find(const char *name, const char *dir_opt, iso_cli__bench *b, char *why,
                        size_t why_cap);

/* 1 if a and b have the same vertex count and the same triangles in the
 * same order (a deformed copy); else 0 and a sentence in why. */
struct iso_mesh;
int iso_cli__same_connectivity(const struct iso_mesh *a, const struct iso_mesh *b, char *why,
                               size_t why_cap);

/* Prints the version lines of --version: isoshape, CHOLMOD (run time and
 * build time) and the BLAS that is loaded, with its resolved path. */
void iso_cli__print_version(void);

#endif
