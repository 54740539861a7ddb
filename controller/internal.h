/* controller/internal.h -- what the isoshape command's files share: the
 * subcommands and their option tables, the parser and --help printer that
 * read them, locating the benchmark, and the run-time library report of
 * --version. Not installed. */
#ifndef ISO_CLI_INTERNAL_H
#define ISO_CLI_INTERNAL_H

#include <stddef.h>
#include <stdio.h>

#include "iso_dev_map.h"
#include "iso_err.h"
#include "iso_integrate.h"
#include "iso_json.h"
#include "iso_mesh.h"
#include "iso_metrics.h"
#include "iso_names.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"

#define ISO_CLI_PATH_MAX 4096

/* Prints "isoshape <cmd>: <message>\n" on stderr. */
void iso_cli__fail(const char *cmd, const char *fmt, ...) ISO_PRINTF(2, 3);
/* The median of n values, sorting them in place; NAN for none (cli_stats.c). */
double iso_cli__median(double *v, int n);
/* The process's peak resident memory so far, MiB (getrusage), as `check`
 * and `run` say it. */
double iso_cli__peak_mb(void);

/* ------------------------------------------------------------------------ */
/* Options as tables (cli_opts.c)                                             */
/* ------------------------------------------------------------------------ */

/* A command's options are data, as getopt_long's table and SQLite's pragma
 * table are: one row says an option's name, kind, range, metavar and help
 * line and where its value goes, and the parser, the range check and the
 * --help printer all read that row. A table ends with a row of kind
 * ISO_CLI_OPT_END (all zero). Options that several commands take are one
 * table of their own, included by a row of kind ISO_CLI_OPT_TABLE. */
typedef enum iso_cli__opt_kind {
    ISO_CLI_OPT_END = 0, /* ends a table */
    ISO_CLI_OPT_FLAG,    /* no value: stores .flag (an int), or calls .set */
    ISO_CLI_OPT_INT,     /* an int in the row's range */
    ISO_CLI_OPT_DOUBLE,  /* a finite double in the row's range */
    ISO_CLI_OPT_STRING,  /* a path or a name: a const char * into argv */
    ISO_CLI_OPT_ENUM,    /* one of .names: its index, as an int */
    ISO_CLI_OPT_CALL,    /* a compound value (MU,TAU, a list): .set parses it */
    ISO_CLI_OPT_TABLE,   /* the rows of .table, their values inside the one at .at */
    ISO_CLI_OPT_HEADING  /* no option: .help is a heading line in --help */
} iso_cli__opt_kind;

/* A range's end: none, open (excluded) or closed (included). */
typedef enum iso_cli__end { ISO_CLI_NONE = 0, ISO_CLI_OPEN, ISO_CLI_CLOSED } iso_cli__end;

/* A row's range, as designated initializers: {..., ISO_CLI_GT(0), ISO_CLI_LE(1)}
 * is (0, 1]. */
#define ISO_CLI_GT(x) .lo = (x), .lo_end = ISO_CLI_OPEN
#define ISO_CLI_GE(x) .lo = (x), .lo_end = ISO_CLI_CLOSED
#define ISO_CLI_LT(x) .hi = (x), .hi_end = ISO_CLI_OPEN
#define ISO_CLI_LE(x) .hi = (x), .hi_end = ISO_CLI_CLOSED

/* Where a row's value goes: the offset of `member` in `type`, which must be
 * of C type `ctype` (a compile error otherwise, so a row cannot write an
 * int into a double). ISO_CLI_ENUM_AT takes an int or an enum the size of
 * one (ENUM, INT and FLAG rows store an int). ISO_CLI_ZERO_IF(c) is 0 when
 * c holds and a negative array size, refused by the compiler, when not. */
#define ISO_CLI_ZERO_IF(c) (0 * sizeof(char[(c) ? 1 : -1]))
#define ISO_CLI_IS(type, member, ctype) _Generic(((type *)0)->member, ctype : 1, default : 0)
#define ISO_CLI_AT(type, member, ctype)                                                            \
    (offsetof(type, member) + ISO_CLI_ZERO_IF(ISO_CLI_IS(type, member, ctype)))
#define ISO_CLI_INT_AT(type, member) ISO_CLI_AT(type, member, int)
#define ISO_CLI_DOUBLE_AT(type, member) ISO_CLI_AT(type, member, double)
#define ISO_CLI_STRING_AT(type, member) ISO_CLI_AT(type, member, const char *)
#define ISO_CLI_ENUM_AT(type, member)                                                              \
    (offsetof(type, member) + ISO_CLI_ZERO_IF(sizeof(((type *)0)->member) == sizeof(int)))

struct iso_cli__opt;
/* Puts `val` (NULL for a FLAG row) into dst, the row's place in the
 * command's arguments: a CALL row's setter parses the text; any other
 * row's is called instead of storing the value, once the row's own checks
 * passed (its type, its range). Returns 0, or -1 with a phrase in why that
 * follows "--opt 'VALUE': " (e.g. "the weight MU must be >= 0"). */
typedef int (*iso_cli__opt_set)(const struct iso_cli__opt *o, void *dst, const char *val, char *why,
                                size_t why_cap);

typedef struct iso_cli__opt {
    const char *name;            /* without "--"; NULL when the option has a short name only */
    iso_cli__opt_kind kind;      /* what it takes and how it is stored */
    size_t at;                   /* where the value goes (ISO_CLI_*_AT) */
    const char *metavar;         /* "N", "FILE"; NULL for flags and enums (their names show) */
    const char *help;            /* one line, wrapped by the printer; "%R" prints the range */
    char short_name;             /* 'o' for -o, or 0 */
    double lo, hi;               /* INT and DOUBLE: the range, whose ends... */
    iso_cli__end lo_end, hi_end; /* ...are none, open or closed */
    const char *solver;       /* INT and DOUBLE: the range is instead the solver's for this setting
                                 (iso_solver_range), the one scene files are held to */
    int flag;                 /* FLAG: the value stored (1, or 0 for --no-x) */
    int nonempty;             /* STRING: 1 refuses an empty value */
    const char *const *names; /* ENUM: the enum's name table (common/iso_names.h) */
    iso_cli__opt_set set;     /* CALL; others: stores instead of .at's bytes */
    const struct iso_cli__opt *table; /* TABLE: the included rows */
} iso_cli__opt;

/* What iso_cli__opts_parse returns after --help or -h. */
#define ISO_CLI_HELP 1

/* Parses argv[1..argc-1] against opts, into args (each row's .at): both
 * `--opt VALUE` and `--opt=VALUE`, every value checked against its row.
 * An argument that is not an option is a positional: up to max_pos of them
 * go into pos (their count in *n_pos). Stops at --help or -h and returns
 * ISO_CLI_HELP; returns ISO_OK when all is parsed; else ISO_EINVAL with a
 * sentence in err that names the option, the value and what was expected
 * (err->offset: the argument's index). cmd names the command in it. */
int iso_cli__opts_parse(const char *cmd, const iso_cli__opt *opts, int argc, char **argv,
                        void *args, const char **pos, int max_pos, int *n_pos, iso_err *err);

/* Writes the option list of opts, one row an option (headings as they
 * are), help wrapped to 80 columns. */
void iso_cli__opts_print(const iso_cli__opt *opts, FILE *f);

/* A row's range as a phrase: "in (0, 1]", "> 0", ">= 1"; "" without one. */
const char *iso_cli__opt_range(const iso_cli__opt *o, char *buf, size_t cap);
/* A row's range (its own, or the solver's for o->solver); whole numbers
 * for an INT row. */
void iso_cli__opt_range_of(const iso_cli__opt *o, iso_range *r);

/* The option as it is spelled on the command line: "--omega", or "-o". */
const char *iso_cli__opt_spelling(const iso_cli__opt *o, char *buf, size_t cap);

/* One subcommand: its help is usage, then the option list from opts, then
 * after. */
typedef struct iso_cli__cmd {
    const char *name;                   /* "deform" */
    const char *summary;                /* its line in `isoshape --help`; NULL: not listed */
    const char *usage;                  /* the usage lines and the prose before the options */
    const iso_cli__opt *opts;           /* its options */
    const char *after;                  /* prose after the options, or NULL */
    int (*main)(int argc, char **argv); /* argv[0] is the name; returns the exit status */
} iso_cli__cmd;

/* Parses c's command line into args (as iso_cli__opts_parse), printing
 * --help on stdout or the error on stderr. Returns -1 to go on, else the
 * exit status: 0 after --help, 2 after a usage error. pos and n_pos may be
 * NULL when the command takes no positionals. */
int iso_cli__parse(const iso_cli__cmd *c, int argc, char **argv, void *args, const char **pos,
                   int max_pos, int *n_pos);

/* The device mapping's options (cli_dev_map.c), shared by record and
 * replay: a table fragment whose rows' values go into an iso_dev_map_opts. */
extern const iso_cli__opt iso_cli__dev_map_options[];

/* --mcap-compression (cmd_export.c), for every command that takes --mcap:
 * a table fragment whose one row's value is an int, an
 * iso_mcap_compression (include it at that int's offset). */
extern const iso_cli__opt iso_cli__mcap_compression_options[];

/* The subcommands (controller/cmd_*.c, cli_version.c), each at the end of
 * its file after its main, which is static: main() reaches it through the
 * table alone. A main's argv[0] is the subcommand's name; it returns the
 * exit status. */
extern const iso_cli__cmd iso_cli__deform_cmd, iso_cli__field_cmd, iso_cli__metrics_cmd,
    iso_cli__bench_cmd, iso_cli__record_cmd, iso_cli__replay_cmd, iso_cli__inspect_cmd,
    iso_cli__devices_cmd, iso_cli__check_cmd, iso_cli__run_cmd, iso_cli__export_cmd,
    iso_cli__version_cmd;

/* All of them, in the order `isoshape --help` lists them; NULL-terminated
 * (cli_commands.c). */
extern const iso_cli__cmd *const iso_cli__commands[];
/* The subcommand called `name`, or NULL. */
const iso_cli__cmd *iso_cli__command(const char *name);

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

/* Re-executes the program with OPENBLAS_CORETYPE set when OpenBLAS fell
 * back to its generic kernels on a CPU with AVX2/AVX-512; returns otherwise. */
void iso_cli__tune_blas(char **argv);

/* OpenBLAS's build and kernel line (openblas_get_config), or "" when the
 * BLAS loaded is not OpenBLAS. Never NULL. */
const char *iso_cli__blas_config(void);

/* ------------------------------------------------------------------------ */
/* Solver options shared by deform, field and bench (cli_solver.c)           */
/* ------------------------------------------------------------------------ */

#define ISO_CLI_DEFAULT_CG_TOL 1e-10

/* A macro's value as a string literal, for help lines. */
#define ISO_CLI_STR_(x) #x
#define ISO_CLI_STR(x) ISO_CLI_STR_(x)

/* The solver options, as table fragments whose rows' values go into an
 * iso_solver_opts (include them at its offset): --assembly and --cl-device;
 * --cg-tol and --preconditioner; those with --refactor and --worker-lag (bench says both its own
 * way); and the field's weights --omega and --weighting. */
extern const iso_cli__opt iso_cli__assembly_options[];
extern const iso_cli__opt iso_cli__pcg_options[];

extern const iso_cli__opt iso_cli__solver_options[];
extern const iso_cli__opt iso_cli__weight_options[];

/* The library's defaults with the command's: auto assembly, adaptive
 * refactoring, CG tolerance ISO_CLI_DEFAULT_CG_TOL, and the command's
 * thread settings (iso_cli__solver_threads). */
void iso_cli__solver_opts_default(iso_solver_opts *so);

/* What the command asks of threads, since it runs one solver at a time:
 * CHOLMOD's OpenMP regions on the calling thread, and OpenBLAS on one
 * thread while a solver of a small system exists (ISO_SOLVER_BLAS_SIZED).
 * A user who sets OMP_MAX_ACTIVE_LEVELS or OMP_THREAD_LIMIT, or
 * OPENBLAS_NUM_THREADS, keeps that choice: the solver then leaves it. */
void iso_cli__solver_threads(iso_solver_threads *t);

/* The scene's system evaluated at its rest pose, the first handle moving
 * by its driver's twist: one evaluation to warm the caches and the
 * workspace, then reps (at most 99) timed ones. each[k] gets evaluation
 * k's t_assembly, t_factor and t_solve (seconds); *total the solver's
 * stats after the last and *flops its factorization's flops (either may be
 * NULL). For the benches' bare-system figures. */
struct iso_scene;
int iso_cli__rest_fields(const struct iso_scene *sc, const iso_solver_opts *so, int reps,
                         iso_solver_stats *each, iso_solver_stats *total, double *flops,
                         iso_err *err);

/* The tick engine's defaults with the command's thread settings and name
 * (cmd: "run", "replay", ...), for every command that runs the engine. */
struct iso_loop_opts;
void iso_cli__loop_opts_default(struct iso_loop_opts *o, const char *cmd);

/* Prints iso_solver_notice() as "isoshape <cmd>: <notice>" on stderr, one
 * line; nothing when the notice is empty. */
void iso_cli__print_notice(const char *cmd, const char *notice);

/* ------------------------------------------------------------------------ */
/* One deformation problem (cli_problem.c)                                    */
/* ------------------------------------------------------------------------ */

/* Where a problem comes from: files, a built-in shape, or a benchmark
 * problem (looked up with iso_cli__bench_find, the built-in of the same
 * name when absent). */
typedef struct iso_cli__source {
    const char *mesh, *sel, *def; /* files */
    const char *shape;            /* or a built-in shape */
    const char *benchmark;        /* or a benchmark problem... */
    const char *bench_dir;        /* ...under this folder (NULL: the usual places) */
    const char *reference;        /* another result to measure, or NULL */
    int resolution;               /* built-in shapes: 0 = default */
    int quiet;                    /* 1: no stderr line when the built-in stands in */
} iso_cli__source;

/* Where a problem comes from, as table fragments whose rows' values go
 * into an iso_cli__source (include them at its offset): --mesh and --sel;
 * --shape and --resolution; both, the shape's first (for the commands that
 * take a mesh but no benchmark problem); --benchmark-dir. */
extern const iso_cli__opt iso_cli__mesh_options[];
extern const iso_cli__opt iso_cli__shape_options[];
extern const iso_cli__opt iso_cli__shape_or_mesh_options[];
extern const iso_cli__opt iso_cli__benchmark_dir_options[];

typedef struct iso_cli__problem {
    char label[ISO_CLI_PATH_MAX + 64];
    char ref_path[ISO_CLI_PATH_MAX]; /* "" if none */
    int builtin;                     /* 1 if it is a built-in shape */
    iso_shape shape;
    iso_mesh *mesh, *ref;
    iso_regions reg;
    double M[16]; /* the handle's final pose */
} iso_cli__problem;

/* Loads the problem (and its reference) into *p. On failure returns a
 * negative ISO_E* code with err filled; *p can be deinitialised either way.
 * cmd names the command in the fall-back line. */
int iso_cli__problem_load(const char *cmd, const iso_cli__source *src, iso_cli__problem *p,
                          iso_err *err);
void iso_cli__problem_deinit(iso_cli__problem *p);

/* Writes p as the files `deform --mesh --sel --def` reads, into folder dir
 * (made when absent, one level): NAME.off (the rest mesh, 17 significant
 * digits, so it reads back to the same bits), NAME.sel (0 fixed, 1 free, 2
 * handle, one per vertex) and NAME.def (the handle's final pose). Each file
 * is written whole or not at all (a temporary name, then a rename). Their
 * paths go into paths[3] (ISO_CLI_PATH_MAX each). */
int iso_cli__problem_write(const iso_cli__problem *p, const char *dir, const char *name,
                           char paths[3][ISO_CLI_PATH_MAX], iso_err *err);

/* The figures of one run. */
typedef struct iso_cli__run {
    iso_integrate_stats ist;
    iso_solver_stats sst;
    double seconds;            /* solver creation and integration, wall clock */
    double other;              /* seconds outside assembly, factorization and solve */
    double factor_flops;       /* of one numeric factorization; NAN if unknown */
    char notice[256];          /* iso_solver_notice(), "" if none */
    int proxy_vertices;        /* so->proxy's proxy, 0 if none */
    double proxy_omega;        /* the ω it was stepped with */
    iso_metrics proxy_metrics; /* the proxy's own result against its rest pose */
    double proxy_s;            /* seconds it took to build (in seconds too) */
} iso_cli__run;

/* Integrates p from its rest pose (copied into x, 3*nv) to its final pose
 * with a fresh solver; x holds the result. With so->proxy the method runs
 * on the proxy (auto: the budget of a 60 Hz tick) and x follows it. Fills
 * *out even on failure. */
int iso_cli__problem_run(const iso_cli__problem *p, const iso_solver_opts *so,
                         const iso_integrate_opts *io, double *x, iso_cli__run *out, iso_err *err);

/* Floating-point operations of one numeric factorization of s's system
 * (CHOLMOD's count after analysis), through iso_solver_factor_flops() when
 * the library has it; NAN when it does not. */
double iso_cli__factor_flops(const iso_solver *s);

/* 1e3 * seconds / evaluations, NAN when there were none. */
double iso_cli__per_evaluation_ms(double seconds, long evaluations);

/* ------------------------------------------------------------------------ */
/* bench's real-time table (bench_realtime.c)                                 */
/* ------------------------------------------------------------------------ */

typedef struct iso_cli__rt_row {
    char scene[32];
    int builtin, vertices, max_step_evaluations;
    long ticks, evaluations, cg_iterations, factor_solves, factorizations, handovers;
    double ticks_per_s, median_ms, p99_ms; /* ticks timed wake to published */
    double bare_solve_ms;                  /* one solve of the same system, median */
} iso_cli__rt_row;

/* Runs the benchmark scene `name` (config/scenes/<name>.yaml as written, the
 * built-in shape at `resolution` standing in when the problem is absent)
 * through the tick engine as fast as possible, then times reps bare solves
 * of its system. so gives the assembly, OpenCL device, CG tolerance and
 * the factorization worker's lag. */
int iso_cli__bench_realtime(const char *name, const char *bench_dir, int resolution,
                            const iso_solver_opts *so, int reps, iso_cli__rt_row *row,
                            iso_err *err);
/* The table for people, and the rows as JSON objects into the array j has
 * open. */
void iso_cli__bench_realtime_print(const iso_cli__rt_row *rows, int n);
void iso_cli__bench_realtime_json(iso_json *j, const iso_cli__rt_row *rows, int n);

/* ------------------------------------------------------------------------ */
/* bench's scale table (bench_scale.c)                                        */
/* ------------------------------------------------------------------------ */

#define ISO_CLI_SCALE_MESHES 3
typedef struct iso_cli__scale_mesh {
    const char *shape;
    int resolution;
    int budget; /* the reduced rows' solver.proxy: 0 auto, else at most this many vertices */
} iso_cli__scale_mesh;
/* The issue-sized meshes (40k plane, 160k and 1M tentacle), and small ones
 * for --quick whose reduced rows name a budget (auto keeps them whole). */
extern const iso_cli__scale_mesh iso_cli__scale_meshes[ISO_CLI_SCALE_MESHES];
extern const iso_cli__scale_mesh iso_cli__scale_meshes_quick[ISO_CLI_SCALE_MESHES];

typedef struct iso_cli__scale_row {
    char mesh[48];
    int vertices, reduced, proxy; /* proxy: the reduced model's vertices, 0 on the whole mesh */
    long ticks;
    double ticks_per_s, median_ms, p99_ms; /* ticks timed wake to published */
    double peak_mb;                        /* the run's process, at its largest */
    double product_ms;                     /* one product with the whole system's pattern */
    double build_s;                        /* the proxy's construction */
    double metric_err;                     /* the whole mesh at the end */
    /* Where a tick's time went, the run's sums over its ticks (the
     * solver's stats; the proxy's system on the reduced rows): solves with
     * a factor, ms of assembly, of solving (PCG included) and of waiting
     * for the worker's factor; and the factorizations the ticks' own
     * thread made (the one before the clock starts, and PCG's fallbacks). */
    double solves_per_tick, assembly_ms, solve_ms, wait_ms;
    long tick_factorizations;
    char why[256]; /* "" or why the row did not run */
} iso_cli__scale_row;

/* Each of the ISO_CLI_SCALE_MESHES meshes on the whole mesh (up to
 * full_max vertices) and reduced, each in a child process; two rows a mesh
 * into rows. */
int iso_cli__bench_scale(const iso_cli__scale_mesh *meshes, int full_max, int tty,
                         iso_cli__scale_row *rows, int *n, iso_err *err);
void iso_cli__bench_scale_print(const iso_cli__scale_row *rows, int n);
void iso_cli__bench_scale_json(iso_json *j, const iso_cli__scale_row *rows, int n);

/* The factorization table beside it: the whole mesh's system factored and
 * solved on its own, without the tick engine, so that its memory and times
 * say how far the full-resolution path alone can go. The plane at 40k, 90k
 * and 160k vertices and the 160k tentacle, and small ones for --quick (the
 * largest above the quick --scale-full-max, so that a skipped row is
 * exercised too); the budget field is unused. */
#define ISO_CLI_SCALE_FACTOR_MESHES 4
#define ISO_CLI_SCALE_FACTOR_REPS 3 /* timed evaluations, after one that warms */
extern const iso_cli__scale_mesh iso_cli__scale_factor_meshes[ISO_CLI_SCALE_FACTOR_MESHES];
extern const iso_cli__scale_mesh iso_cli__scale_factor_meshes_quick[ISO_CLI_SCALE_FACTOR_MESHES];

typedef struct iso_cli__scale_factor_row {
    char mesh[48];
    int vertices, unknowns;
    int supernodal;             /* CHOLMOD's choice (iso_solver_stats) */
    long nnz_a, nnz_l;          /* A_ff's upper triangle; L as the analysis counts it */
    long product_nnz;           /* the product's matrix: nnz_a when it is A_ff's pattern */
    double factor_mb;           /* one numeric factor (iso_solver_stats.factor_bytes), MiB */
    double gflop;               /* one factorization, CHOLMOD's count */
    double analysis_s;          /* the ordering and symbolic analysis, once */
    double factor_ms, solve_ms; /* medians of ISO_CLI_SCALE_FACTOR_REPS, one BLAS thread */
    double assembly_ms;         /* the same evaluations' C assembly, median */
    double product_ms;          /* one product with the pattern, the unit, same run */
    double peak_mb;             /* the row's process, at its largest */
    char why[256];              /* "" or why the row did not run */
} iso_cli__scale_factor_row;

/* Each of the ISO_CLI_SCALE_FACTOR_MESHES meshes up to full_max vertices,
 * each in a child process; a row a mesh. A row that did not run (above
 * full_max, or its child failed or died) says why. */
void iso_cli__bench_scale_factor(const iso_cli__scale_mesh *meshes, int full_max, int tty,
                                 iso_cli__scale_factor_row *rows, int *n);
void iso_cli__bench_scale_factor_print(const iso_cli__scale_factor_row *rows, int n);
void iso_cli__bench_scale_factor_json(iso_json *j, const iso_cli__scale_factor_row *rows, int n);

/* ------------------------------------------------------------------------ */
/* Scenes (cli_scene.c)                                                       */
/* ------------------------------------------------------------------------ */

struct iso_scene;
/* Loads a scene file, resolving `benchmark:` exactly like --benchmark does;
 * prints the fallback notice, or the error as "isoshape <cmd>: ...".
 * Returns 0 with *out set, or 1. */
int iso_cli__scene_load(const char *cmd, const char *path, struct iso_scene **out);
/* The scene layer's benchmark lookup (iso_scene_opts.bench_find) through
 * iso_cli__bench_find: ctx is the --benchmark-dir (a const char *), NULL
 * for where --benchmark looks. */
int iso_cli__scene_bench_find(void *ctx, const char *name, char *mesh, char *sel, char *def,
                              char *why, size_t why_cap);
/* A scene of the device side alone (no mesh), for `record` and `replay`:
 * mo->n_handles handles driven through the map options mo, ticking at hz.
 * The caller adds the devices and frees it with free(). NULL when out of
 * memory. */
struct iso_scene *iso_cli__device_scene(const char *name, double hz, const iso_dev_map_opts *mo);
/* A scene for replaying the recording at `path` (cmd_replay.c): the mesh of
 * src (a built-in shape, or --mesh and --sel) with one handle the replay
 * drives through mapping mo, steps ABM steps a tick (0: 1), at the
 * recorded loop's period; without a mesh, the device side alone. */
int iso_cli__replay_scene(const char *path, const iso_cli__source *src, const iso_dev_map_opts *mo,
                          int steps, struct iso_scene **out, iso_err *err);
/* Frees a scene from iso_cli__replay_scene (NULL too): with a mesh the
 * whole scene, without one the device side alone. */
void iso_cli__replay_scene_free(struct iso_scene *sc);

#endif
