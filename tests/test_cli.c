/* tests/test_cli.c -- the isoshape command from the outside: it runs the
 * built binary and checks its output, exit status and messages, then
 * installs the library into a temporary prefix and builds a program against
 * it with pkg-config.
 *
 * The binary is $ISOSHAPE_BIN, else <build>/isoshape where <build> is the
 * parent of this test's folder (CTest runs us as <build>/tests/test_cli). */
#include "testutil.h"

#include <ctype.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

typedef struct result {
    int status; /* exit status, or -1 if it did not exit normally */
    char out[65536];
    char err[16384];
} result;

/* The test program's state, gathered in one place (the SQLite manner);
 * `res` is large, so it lives here rather than on the stack. */
typedef struct globals {
    char build[PATH_MAX];    /* the CMake build folder */
    char bin[PATH_MAX + 16]; /* the isoshape binary */
    result res;              /* the last command's output */
} globals;

static globals g;

/* ---- running commands --------------------------------------------------- */

static void slurp(const char *path, char *buf, size_t cap)
{
    FILE *f = fopen(path, "rb");
    size_t n = 0;
    if (f) {
        n = fread(buf, 1, cap - 1, f);
        fclose(f);
    }
    buf[n] = '\0';
}

/* Runs `sh -c "<cmd>"` with stdout and stderr captured. */
static void run_sh(const char *cmd, result *r)
{
    r->status = iso_test_sh(cmd, r->out, sizeof r->out, r->err, sizeof r->err);
}

/* Runs the isoshape binary with `args`. */
static void run_iso(const char *args, result *r)
{
    size_t cap = strlen(g.bin) + strlen(args) + 8;
    char *cmd = malloc(cap);
    assert_non_null(cmd);
    snprintf(cmd, cap, "'%s' %s", g.bin, args);
    run_sh(cmd, r);
    free(cmd);
}

static int have_tool(const char *name)
{
    char cmd[256];
    snprintf(cmd, sizeof cmd, "command -v %s >/dev/null 2>&1", name);
    return system(cmd) == 0;
}

/* ---- a small JSON checker ------------------------------------------------ */

/* Recursive descent over RFC 8259 values; returns the position after the
 * value, or NULL if the text is not valid JSON there. */
static const char *json_value(const char *p, int depth);

static const char *json_ws(const char *p)
{
    while (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')
        p++;
    return p;
}

static const char *json_string(const char *p)
{
    if (*p++ != '"')
        return NULL;
    while (*p && *p != '"') {
        if ((unsigned char)*p < 0x20)
            return NULL;
        if (*p == '\\') {
            p++;
            if (*p == 'u') {
                for (int i = 1; i <= 4; i++)
                    if (!isxdigit((unsigned char)p[i]))
                        return NULL;
                p += 4;
            } else if (!strchr("\"\\/bfnrt", *p) || !*p) {
                return NULL;
            }
        }
        p++;
    }
    return *p == '"' ? p + 1 : NULL;
}

static const char *json_number(const char *p)
{
    const char *s = p;
    if (*p == '-')
        p++;
    if (*p == '0')
        p++;
    else if (isdigit((unsigned char)*p))
        while (isdigit((unsigned char)*p))
            p++;
    else
        return NULL;
    if (*p == '.') {
        if (!isdigit((unsigned char)*++p))
            return NULL;
        while (isdigit((unsigned char)*p))
            p++;
    }
    if (*p == 'e' || *p == 'E') {
        p++;
        if (*p == '+' || *p == '-')
            p++;
        if (!isdigit((unsigned char)*p))
            return NULL;
        while (isdigit((unsigned char)*p))
            p++;
    }
    return p > s ? p : NULL;
}

static const char *json_value(const char *p, int depth)
{
    if (depth > 32)
        return NULL;
    p = json_ws(p);
    if (*p == '{' || *p == '[') {
        char close = *p == '{' ? '}' : ']';
        int object = *p == '{';
        p = json_ws(p + 1);
        if (*p == close)
            return p + 1;
        for (;;) {
            if (object) {
                p = json_string(json_ws(p));
                if (!p)
                    return NULL;
                p = json_ws(p);
                if (*p++ != ':')
                    return NULL;
            }
            p = json_value(p, depth + 1);
            if (!p)
                return NULL;
            p = json_ws(p);
            if (*p == close)
                return p + 1;
            if (*p++ != ',')
                return NULL;
        }
    }
    if (*p == '"')
        return json_string(p);
    if (strncmp(p, "true", 4) == 0 || strncmp(p, "null", 4) == 0)
        return p + 4;
    if (strncmp(p, "false", 5) == 0)
        return p + 5;
    return json_number(p);
}

static int json_valid(const char *text)
{
    const char *end = json_value(text, 0);
    return end && *json_ws(end) == '\0';
}

/* The number after "key": in a flat object, or NAN. */
static double json_get(const char *text, const char *key)
{
    char pat[128];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = strstr(text, pat);
    return p ? strtod(p + strlen(pat), NULL) : NAN;
}

/* Every key of a command's JSON is snake_case (common/iso_json.h). */
static void assert_keys_snake_case(const char *json)
{
    char bad[128];
    if (!iso_test_json_keys_snake_case(json, bad, sizeof bad))
        fail_msg("key '%s' is not snake_case in %s", bad, json);
}

/* ---- fixtures ------------------------------------------------------------ */

/* A 5x5 grid in the plane z = 0: left column fixed, right column handle. */
static void write_grid(char *mesh, char *sel, size_t cap)
{
    char text[4096];
    int n = snprintf(text, sizeof text, "OFF\n25 32 0\n");
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 5; i++)
            n += snprintf(text + n, sizeof text - n, "%d %d 0\n", i, j);
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) {
            int a = 5 * j + i;
            n += snprintf(text + n, sizeof text - n, "3 %d %d %d\n3 %d %d %d\n", a, a + 1, a + 6, a,
                          a + 6, a + 5);
        }
    iso_test_write(iso_test_tmp(mesh, cap, "grid.off"), text, -1);
    n = snprintf(text, sizeof text, "# grid labels\n");
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 5; i++)
            n += snprintf(text + n, sizeof text - n, "%d\n", i == 0 ? 0 : i == 4 ? 2 : 1);
    iso_test_write(iso_test_tmp(sel, cap, "grid.sel"), text, -1);
}

static int count_lines(const char *text)
{
    int n = 0;
    for (; *text; text++)
        n += *text == '\n';
    return n;
}

/* ---- tests ---------------------------------------------------------------- */

static void version_names_cholmod_and_blas(void **state)
{
    (void)state;
    result *r = &g.res;
    run_iso("--version", r);
    assert_int_equal(r->status, 0);
    assert_non_null(strstr(r->out, "isoshape "));
    assert_non_null(strstr(r->out, "CHOLMOD "));
    assert_non_null(strstr(r->out, "BLAS"));
}

static void deform_prints_json_with_every_key(void **state)
{
    (void)state;
    static const char *const keys[] = {"metric_err",
                                       "area_err",
                                       "angle_err",
                                       "max_edge_strain",
                                       "rms_edge_strain",
                                       "steps",
                                       "rk4_steps",
                                       "evaluations",
                                       "seconds",
                                       "assembly_seconds",
                                       "factor_seconds",
                                       "solve_seconds",
                                       "other_seconds",
                                       "factorizations",
                                       "cg_iterations",
                                       "refactors",
                                       "assembly_ms_per_evaluation",
                                       "factor_ms_per_evaluation",
                                       "solve_ms_per_evaluation"};
    result *r = &g.res;
    run_iso("deform --shape cylinder --steps 4 --json", r);
    if (r->status != 0)
        fail_msg("deform failed (%d): %s", r->status, r->err);
    if (!json_valid(r->out))
        fail_msg("not valid JSON: %s", r->out);
    assert_keys_snake_case(r->out);
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++) {
        char pat[64];
        snprintf(pat, sizeof pat, "\"%s\":", keys[i]);
        if (!strstr(r->out, pat))
            fail_msg("key %s missing from %s", keys[i], r->out);
    }
    assert_true(json_get(r->out, "steps") == 4);
    assert_true(json_get(r->out, "evaluations") >= 8);
    assert_true(json_get(r->out, "metric_err") > 0);
    assert_true(json_get(r->out, "seconds") >= json_get(r->out, "factor_seconds"));
    assert_null(strstr(r->out, "reference"));
}

static void deform_writes_the_deformed_mesh(void **state)
{
    (void)state;
    char out[PATH_MAX], args[PATH_MAX * 2];
    result *r = &g.res;
    iso_test_tmp(out, sizeof out, "bar-twisted.off");
    remove(out);
    snprintf(args, sizeof args, "deform --shape bar --resolution 4 --steps 3 --out '%s'", out);
    run_iso(args, r);
    if (r->status != 0)
        fail_msg("deform failed (%d): %s", r->status, r->err);
    assert_non_null(strstr(r->out, "metricErr      ")); /* text: the paper's names */
    assert_non_null(strstr(r->out, "factorization"));
    /* the result against itself through `metrics`, and a reference of it */
    snprintf(args, sizeof args,
             "deform --shape bar --resolution 4 --steps 3 --json --reference '%s'", out);
    run_iso(args, r);
    if (r->status != 0)
        fail_msg("deform --reference failed (%d): %s", r->status, r->err);
    assert_true(json_valid(r->out));
    assert_keys_snake_case(r->out);
    assert_true(fabs(json_get(r->out, "reference_ratio_metric_err") - 1.0) < 1e-6);
}

static void bad_values_are_refused_by_name(void **state)
{
    (void)state;
    static const struct {
        const char *args, *needle;
    } cases[] = {
        {"deform --shape cylinder --omega 0", "--omega"},
        {"deform --shape cylinder --omega 1.5", "--omega"},
        {"deform --shape cylinder --omega abc", "--omega"},
        {"deform --shape cylinder --steps 0", "--steps"},
        {"deform --shape cylinder --steps -3", "--steps"},
        {"deform --shape cylinder --tol 0", "--tol"},
        {"deform --shape cylinder --tol -1e-3", "--tol"},
        {"deform --shape cylinder --weighting cotan", "--weighting"},
        {"deform --shape cylinder --frobnicate", "--frobnicate"},
        {"deform --shape cylinder --steps", "--steps"},
        {"deform --shape teapot", "teapot"},
        {"deform --benchmark teapot", "--benchmark"},
        {"deform --mesh /nonexistent/x.off --sel a --def b", "/nonexistent/x.off"},
        {"field --shape cylinder --velocity v --out f --omega 0", "--omega"},
        {"metrics onlyone.off", "two meshes"},
        {"deform --shape cylinder --assembly gpu", "--assembly"},
        {"deform --shape cylinder --assembly", "--assembly"},
        {"deform --shape cylinder --refactor sometimes", "--refactor"},
        {"deform --shape cylinder --cg-tol 0", "--cg-tol"},
        {"deform --shape cylinder --cg-tol 2", "--cg-tol"},
        {"deform --shape cylinder --cg-tol tight", "--cg-tol"},
        {"deform --shape cylinder --cl-device=", "--cl-device"},
        {"field --shape cylinder --velocity v --out f --assembly gpu", "--assembly"},
        {"field --shape cylinder --velocity v --out f --refactor never", "--refactor"},
        {"bench --refactor never", "--refactor"},
        {"bench --assembly fpga", "--assembly"},
        {"bench --cg-tol -1", "--cg-tol"},
        {"bench --reps 0", "--reps"},
        {"bench --benchmark-dir", "--benchmark-dir"},
        {"bench --frobnicate", "--frobnicate"},
        {"transmogrify", "transmogrify"},
    };
    result *r = &g.res;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run_iso(cases[i].args, r);
        if (r->status == 0 || r->status == -1)
            fail_msg("'%s' exited with %d", cases[i].args, r->status);
        if (!strstr(r->err, cases[i].needle))
            fail_msg("'%s': stderr does not name %s: %s", cases[i].args, cases[i].needle, r->err);
        assert_int_equal(count_lines(r->err), 1);
    }
}

/* Fails when `help` lists one option line ("  --name ARG") twice; the
 * same option with another argument ("--restore off") is another form. */
static void assert_options_listed_once(const char *cmd, const char *help)
{
    char seen[64][64];
    int n = 0;
    for (const char *l = help; l && *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL) {
        const char *o = l + strspn(l, " ");
        if (o == l || strncmp(o, "--", 2) != 0)
            continue;
        char opt[64];
        size_t len = strcspn(o, " \n");
        len += o[len] == ' ' ? strcspn(o + len + 1, " \n") + 1 : 0;
        snprintf(opt, sizeof opt, "%.*s", (int)len, o);
        for (int k = 0; k < n; k++)
            if (strcmp(seen[k], opt) == 0)
                fail_msg("isoshape %s --help lists '%s' twice", cmd, opt);
        if (n < 64)
            snprintf(seen[n++], sizeof seen[0], "%s", opt);
    }
}

static void help_works_for_every_subcommand(void **state)
{
    (void)state;
    static const char *const cmds[] = {"",      "deform", "field",  "metrics", "bench",  "run",
                                       "check", "replay", "record", "devices", "inspect"};
    result *r = &g.res;
    for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++) {
        char args[64];
        snprintf(args, sizeof args, "%s --help", cmds[i]);
        run_iso(args, r);
        assert_int_equal(r->status, 0);
        assert_non_null(strstr(r->out, "usage: isoshape"));
        assert_options_listed_once(cmds[i], r->out);
    }
}

static void field_writes_one_line_per_vertex(void **state)
{
    (void)state;
    char mesh[PATH_MAX], sel[PATH_MAX], vel[PATH_MAX], out[PATH_MAX], args[PATH_MAX * 5];
    result *r = &g.res;
    write_grid(mesh, sel, sizeof mesh);
    iso_test_write(iso_test_tmp(vel, sizeof vel, "grid.vel"),
                   "# handle moves up\n0 0 1\n0 0 1\n0 0 1\n\n0 0 1\n0 0 1\n", -1);
    iso_test_tmp(out, sizeof out, "grid.field");
    snprintf(args, sizeof args, "field --mesh '%s' --sel '%s' --velocity '%s' --out '%s'", mesh,
             sel, vel, out);
    run_iso(args, r);
    if (r->status != 0)
        fail_msg("field failed (%d): %s", r->status, r->err);
    slurp(out, r->out, sizeof r->out);
    assert_int_equal(count_lines(r->out), 25);
    /* fixed column still, handle column as given, all with 17 digits */
    double v[75];
    const char *p = r->out;
    for (int i = 0; i < 75; i++) {
        char *end;
        v[i] = strtod(p, &end);
        assert_true(end != p);
        p = end;
    }
    for (int j = 0; j < 5; j++) {
        assert_true(v[3 * (5 * j)] == 0 && v[3 * (5 * j) + 2] == 0);
        assert_true(fabs(v[3 * (5 * j + 4) + 2] - 1.0) < 1e-12);
        assert_true(v[3 * (5 * j + 2) + 2] > 0.1 && v[3 * (5 * j + 2) + 2] < 0.9);
    }

    /* a bad line is named by file and line */
    iso_test_write(vel, "0 0 1\n0 0 1\n0 zero 1\n0 0 1\n0 0 1\n", -1);
    run_iso(args, r);
    assert_int_not_equal(r->status, 0);
    assert_non_null(strstr(r->err, "grid.vel:3:"));
    /* and so is a short file */
    iso_test_write(vel, "0 0 1\n0 0 1\n", -1);
    run_iso(args, r);
    assert_int_not_equal(r->status, 0);
    assert_non_null(strstr(r->err, "grid.vel:2:"));
    assert_non_null(strstr(r->err, "5 handle vertices"));
}

static void metrics_of_a_mesh_against_itself_are_zero(void **state)
{
    (void)state;
    char mesh[PATH_MAX], sel[PATH_MAX], args[PATH_MAX * 3];
    result *r = &g.res;
    write_grid(mesh, sel, sizeof mesh);
    snprintf(args, sizeof args, "metrics '%s' '%s' --json", mesh, mesh);
    run_iso(args, r);
    if (r->status != 0)
        fail_msg("metrics failed (%d): %s", r->status, r->err);
    assert_true(json_valid(r->out));
    assert_keys_snake_case(r->out);
    assert_true(json_get(r->out, "metric_err") == 0);
    assert_true(json_get(r->out, "area_err") == 0);
    assert_true(json_get(r->out, "angle_err") == 0);
    assert_true(json_get(r->out, "max_edge_strain") == 0);
    assert_true(json_get(r->out, "rms_edge_strain") == 0);
}

/* The number after the n-th (0-based) "key": in text, or NAN. */
static double json_get_nth(const char *text, const char *key, int n)
{
    char pat[128];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = text;
    for (int i = 0; p && i <= n; i++) {
        p = strstr(p, pat);
        if (p && i < n)
            p += strlen(pat);
    }
    return p ? strtod(p + strlen(pat), NULL) : NAN;
}

static int count_of(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = strstr(text, needle); p; p = strstr(p + 1, needle))
        n++;
    return n;
}

/* An empty --benchmark-dir makes every problem its small built-in stand-in,
 * so the whole bench runs in seconds; no figure is compared with a time. */
static void bench_quick_prints_json_with_finite_figures(void **state)
{
    (void)state;
    static const char *const row_keys[] = {"seconds",
                                           "evaluations",
                                           "factorizations",
                                           "steps",
                                           "vertices",
                                           "assembly_ms_per_evaluation",
                                           "factor_ms_per_evaluation",
                                           "solve_ms_per_evaluation",
                                           "metric_err",
                                           "peak_rss_mb"};
    static const char *const positive[] = {"dgemm_gflops",  "bare_factor_ms",
                                           "bare_solve_ms", "cactus_unknowns",
                                           "cactus_nnz_l",  "tol_vs_tol_over_10"};
    static const char *const present[] = {"\"rows\":",
                                          "\"accuracy\":",
                                          "\"machine\":",
                                          "\"cg_iterations\":",
                                          "\"refactors\":",
                                          "\"speedup_over_paper\":",
                                          "\"reference_ratio_metric_err\":",
                                          "\"adaptive_vs_always\":",
                                          "\"factor_gflops\":"};
    char dir[PATH_MAX], args[PATH_MAX * 2];
    result *r = &g.res;
    iso_test_tmp(dir, sizeof dir, "empty-benchmark");
    mkdir(dir, 0755);
    snprintf(args, sizeof args, "bench --quick --json --assembly cpu --benchmark-dir '%s'", dir);
    run_iso(args, r);
    if (r->status != 0)
        fail_msg("bench failed (%d): %s", r->status, r->err);
    if (!json_valid(r->out))
        fail_msg("not valid JSON: %s", r->out);
    assert_keys_snake_case(r->out);
    for (size_t i = 0; i < sizeof present / sizeof present[0]; i++)
        if (!strstr(r->out, present[i]))
            fail_msg("%s missing from %s", present[i], r->out);
    /* four built-in problems, each under both schemes */
    int rows = count_of(r->out, "\"refactor\":");
    assert_int_equal(rows, 8);
    assert_int_equal(count_of(r->out, "\"refactor\": \"always\""), 4);
    /* and each one's scene in real time (bench_realtime.c) */
    assert_int_equal(count_of(r->out, "\"builtin\": true"), 8 + 4);
    static const char *const rt_keys[] = {"ticks_per_s", "tick_median_ms", "tick_p99_ms",
                                          "bare_solve_ms", "median_tick_over_bare_solve"};
    assert_int_equal(count_of(r->out, "\"ticks_per_s\":"), 4);
    for (int k = 0; k < 4; k++)
        for (size_t i = 0; i < sizeof rt_keys / sizeof rt_keys[0]; i++) {
            double v = json_get_nth(r->out, rt_keys[i], k);
            if (!(isfinite(v) && v > 0))
                fail_msg("real-time row %d: %s = %g, not a finite positive number", k, rt_keys[i],
                         v);
        }
    assert_true(json_get_nth(r->out, "max_step_evaluations", 0) <= 2);
    for (int k = 0; k < rows; k++)
        for (size_t i = 0; i < sizeof row_keys / sizeof row_keys[0]; i++) {
            double v = json_get_nth(r->out, row_keys[i], k);
            if (!(isfinite(v) && v > 0))
                fail_msg("row %d: %s = %g, not a finite positive number", k, row_keys[i], v);
        }
    for (size_t i = 0; i < sizeof positive / sizeof positive[0]; i++) {
        double v = json_get(r->out, positive[i]);
        if (!(isfinite(v) && v > 0))
            fail_msg("%s = %g, not a finite positive number", positive[i], v);
    }
    /* adaptive reuse moves metricErr far less than the integrator's own error */
    double reuse = json_get(r->out, "adaptive_vs_always"),
           integ = json_get(r->out, "tol_vs_tol_over_10");
    assert_true(isfinite(reuse) && reuse >= 0 && reuse < integ);
    /* the stand-ins are announced, one line each */
    assert_non_null(strstr(r->err, "using the built-in cactus"));
}

/* Without a usable OpenCL platform (no ICDs registered for the loader, or
 * a build without OpenCL) the command says so in one line and runs the C
 * path. */
static void opencl_without_a_platform_falls_back_with_a_notice(void **state)
{
    (void)state;
    char vendors[PATH_MAX], cmd[PATH_MAX * 3];
    result *r = &g.res;
    iso_test_tmp(vendors, sizeof vendors, "no-opencl-vendors");
    mkdir(vendors, 0755);
    snprintf(cmd, sizeof cmd,
             "OCL_ICD_VENDORS='%s' OCL_ICD_FILENAMES= '%s' deform --shape cylinder --resolution 8 "
             "--steps 2 --assembly opencl --json",
             vendors, g.bin);
    run_sh(cmd, r);
    if (r->status != 0)
        fail_msg("deform --assembly opencl failed (%d): %s", r->status, r->err);
    assert_true(json_valid(r->out));
    assert_non_null(strstr(r->err, "OpenCL"));
    assert_non_null(strstr(r->err, "C assembly"));
    assert_int_equal(count_lines(r->err), 1);
}

static void installed_library_builds_with_pkg_config(void **state)
{
    (void)state;
    if (!have_tool("pkg-config") || !have_tool("cc") || !have_tool("cmake")) {
        printf("skipped: pkg-config, cc or cmake is not installed\n");
        skip();
    }
    char prefix[PATH_MAX], src[PATH_MAX], exe[PATH_MAX], cmd[PATH_MAX * 6];
    result *r = &g.res;
    iso_test_tmp(prefix, sizeof prefix, "prefix");
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && cmake --install '%s' --prefix '%s'", prefix, g.build,
             prefix);
    run_sh(cmd, r);
    if (r->status != 0)
        fail_msg("cmake --install failed (%d): %s", r->status, r->err);

    iso_test_write(iso_test_tmp(src, sizeof src, "use_isoshape.c"),
                   "#include <iso_shapes.h>\n#include <iso_mesh.h>\n#include <stdio.h>\n"
                   "int main(void) {\n"
                   "    iso_shape s; iso_mesh *m = NULL; iso_err e; iso_err_clear(&e);\n"
                   "    if (iso_shape_init(&s, \"cylinder\", 0, &e) != ISO_OK ||\n"
                   "        iso_mesh_create(s.nv, s.x, s.nt, s.tri, s.name, &m, &e) != ISO_OK) {\n"
                   "        fprintf(stderr, \"%s\\n\", e.msg); return 1; }\n"
                   "    printf(\"%d vertices\\n\", iso_mesh_vertex_count(m));\n"
                   "    iso_mesh_destroy(m); iso_shape_deinit(&s); return 0;\n"
                   "}\n",
                   -1);
    iso_test_tmp(exe, sizeof exe, "use_isoshape");
#if defined(__SANITIZE_ADDRESS__)
    const char *san = "-fsanitize=address,undefined"; /* libisoshape needs the runtime */
#else
    const char *san = "";
#endif
    /* The .pc file may sit in lib/ or lib/<multiarch>/; search both. It must
     * point into the prefix it was installed to, not the configured one. */
    snprintf(cmd, sizeof cmd,
             "export PKG_CONFIG_PATH=\"$(find '%s' -name isoshape.pc -printf '%%h:')\" && "
             "pkg-config --variable=includedir isoshape",
             prefix);
    run_sh(cmd, r);
    r->out[strcspn(r->out, "\n")] = '\0';
    if (r->status != 0 || strncmp(r->out, prefix, strlen(prefix)) != 0)
        fail_msg("the installed isoshape.pc gives includedir %s, outside the install prefix %s: "
                 "its prefix must follow the install (prefix=${pcfiledir}/../..)",
                 r->out, prefix);
    snprintf(cmd, sizeof cmd,
             "export PKG_CONFIG_PATH=\"$(find '%s' -name isoshape.pc -printf '%%h:')\" && "
             "cc -std=c11 %s -o '%s' '%s' $(pkg-config --cflags --libs isoshape) && "
             "LD_LIBRARY_PATH=\"$(pkg-config --variable=libdir isoshape)\" '%s'",
             prefix, san, exe, src, exe);
    run_sh(cmd, r);
    if (r->status != 0)
        fail_msg("building against the installed library failed (%d): %s", r->status, r->err);
    assert_non_null(strstr(r->out, " vertices"));
}

/* ---- setup ------------------------------------------------------------------ */

static int locate_binary(void)
{
    const char *env = getenv("ISOSHAPE_BIN");
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return -1;
    self[n] = '\0';
    for (int up = 0; up < 2; up++) { /* <build>/tests/test_cli -> <build> */
        char *slash = strrchr(self, '/');
        if (!slash)
            return -1;
        *slash = '\0';
    }
    snprintf(g.build, sizeof g.build, "%s", self);
    if (env && *env)
        snprintf(g.bin, sizeof g.bin, "%s", env);
    else
        snprintf(g.bin, sizeof g.bin, "%s/isoshape", g.build);
    return access(g.bin, X_OK);
}

int main(void)
{
    if (locate_binary() != 0) {
        printf("skipped: no isoshape binary at %s (set ISOSHAPE_BIN)\n", g.bin);
        return ISO_TEST_SKIP;
    }
    const struct CMUnitTest t[] = {
        cmocka_unit_test(version_names_cholmod_and_blas),
        cmocka_unit_test(deform_prints_json_with_every_key),
        cmocka_unit_test(deform_writes_the_deformed_mesh),
        cmocka_unit_test(bad_values_are_refused_by_name),
        cmocka_unit_test(help_works_for_every_subcommand),
        cmocka_unit_test(field_writes_one_line_per_vertex),
        cmocka_unit_test(metrics_of_a_mesh_against_itself_are_zero),
        cmocka_unit_test(bench_quick_prints_json_with_finite_figures),
        cmocka_unit_test(opencl_without_a_platform_falls_back_with_a_notice),
        cmocka_unit_test(installed_library_builds_with_pkg_config),
    };
    return cmocka_run_group_tests_name("cli", t, NULL, NULL);
}
