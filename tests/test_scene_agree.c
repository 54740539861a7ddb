/* tests/test_scene_agree.c -- `isoshape check` and `isoshape run` validate
 * a scene alike. For every key of the loader's own schema (the tables that
 * SCENES.md's key table is generated from, which test_scene holds SCENES.md
 * to), a value of the wrong type, YAML's null and an empty value are each
 * refused by both commands: exit status 1, and the same one line, which
 * names the key's path and a FILE:LINE:COLUMN inside the key's own text.
 *
 * White-box: it walks the schema (config/internal.h, through
 * scene_schema.c) and runs the built binary ($ISOSHAPE_BIN). */
#include <limits.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "scene_schema.h"
#include "testutil.h"

/* The test program's state (the SQLite manner). */
static struct {
    char bin[PATH_MAX];
    char path[512];                 /* the scene written */
    char doc[8192];                 /* its text */
    char out[16384], err[2][16384]; /* the last commands' output: check's, run's */
} g;

/* The wrong values: a mapping no key takes (every kind refuses it: a
 * scalar or a list is not a mapping, and no section has a key "wrong"),
 * YAML's null, and nothing at all. */
static const struct {
    const char *value, *label;
} wrong[] = {{"{wrong: 1}", "a value of the wrong type"}, {"~", "null"}, {"", "an empty value"}};

/* Runs `isoshape check` (i = 0) or `isoshape run` (i = 1) on the scene,
 * run for one tick with `run_args`; its stderr into g.err[i]. */
static int run_iso(int i, const char *run_args)
{
    char cmd[PATH_MAX + 1024];
    /* a scene wrongly accepted would start the run: bound it */
    snprintf(cmd, sizeof cmd, "timeout 60 '%s' %s '%s' %s </dev/null", g.bin, i ? "run" : "check",
             g.path, i ? run_args : "");
    return iso_test_sh(cmd, g.out, sizeof g.out, g.err[i], sizeof g.err[i]);
}

#define RUN_ONE_TICK "--no-rt --quiet --ticks 1"

/* The line after "isoshape CMD: ", or NULL. */
static const char *said(const char *text, const char *cmd)
{
    char prefix[64];
    snprintf(prefix, sizeof prefix, "isoshape %s: ", cmd);
    return strncmp(text, prefix, strlen(prefix)) == 0 ? text + strlen(prefix) : NULL;
}

/* 1 if column col of line 1 lies inside some "KEY: VALUE" of the document
 * (from the key's first character to the value's last). */
static int inside_key(const char *key, const char *value, int col)
{
    char text[512];
    snprintf(text, sizeof text, "%s: %s", key, value);
    for (const char *p = g.doc; (p = strstr(p, text)) != NULL; p++) {
        int from = (int)(p - g.doc) + 1, to = from + (int)strlen(text);
        if ((p == g.doc || p[-1] == ' ' || p[-1] == '{') && col >= from && col <= to)
            return 1;
    }
    return 0;
}

static void agree(const scene_section *sec, const scene_key *k, const char *value,
                  const char *label)
{
    char what[4096], key[ISO_SCENE_KEY_MAX], file[600];
    content(sec, k, value, what, sizeof what);
    snprintf(g.doc, sizeof g.doc, place_of(sec)->doc, what);
    iso_scene__join(key, sizeof key, place_of(sec)->path, k->key);
    iso_test_write(g.path, g.doc, -1);
    int check = run_iso(0, NULL), run = run_iso(1, RUN_ONE_TICK " --no-display");
    const char *a = said(g.err[0], "check"), *b = said(g.err[1], "run");
    if (check != 1 || run != 1 || !a || !b)
        fail_msg("%s as %s: check exited %d, run %d:\n%s%s\nscene: %s", key, label, check, run,
                 g.err[0], g.err[1], g.doc);
    if (strcmp(a, b) != 0)
        fail_msg("%s as %s: check and run disagree:\n  check: %s  run:   %s", key, label, a, b);
    if (strchr(a, '\n') != a + strlen(a) - 1)
        fail_msg("%s as %s: not one line: %s", key, label, a);
    int line = 0, col = 0, n = 0;
    snprintf(file, sizeof file, "%s:%%d:%%d: %%n", g.path);
    if (sscanf(a, file, &line, &col, &n) != 2 || n == 0 || line != 1 ||
        !inside_key(k->key, value, col))
        fail_msg("%s as %s: the refusal is not at the key (%s: %s):\n  %s  scene: %s", key, label,
                 k->key, value, a, g.doc);
    if (strncmp(a + n, key, strlen(key)) != 0)
        fail_msg("%s as %s: the refusal does not name the key: %s", key, label, a);
}

static void need_binary(void)
{
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0) {
        print_message("skipped: no isoshape binary at %s (set ISOSHAPE_BIN)\n", g.bin);
        skip();
    }
    iso_test_tmp(g.path, sizeof g.path, "agree.yaml");
}

static void check_and_run_refuse_every_key_alike(void **state)
{
    (void)state;
    need_binary();
    const scene_section *all[64];
    int n = all_sections(all, 64), keys = 0;
    for (int i = 0; i < n; i++)
        for (const scene_key *k = all[i]->keys; k->key; k++, keys++)
            for (size_t w = 0; w < sizeof wrong / sizeof wrong[0]; w++)
                agree(all[i], k, wrong[w].value, wrong[w].label);
    print_message("%d keys, each refused alike by check and run as %zu wrong values\n", keys,
                  sizeof wrong / sizeof wrong[0]);
    assert_true(keys > 90);
}

/* The live view's host: what run would refuse when it binds, check
 * refuses too, in the same words; what check accepts, run serves on. */
static void check_and_run_agree_on_display_hosts(void **state)
{
    (void)state;
    static const char *const refused[] = {"0.0.0.0",  "'::'", "example.com", "null",   "true", "~",
                                          "987654.5", "''",   "[1, 2]",      "{a: 1}", NULL};
    static const char *const served[] = {"127.0.0.1", "localhost", NULL};
    need_binary();
    for (int i = 0; refused[i]; i++) {
        snprintf(g.doc, sizeof g.doc,
                 "mesh: {shape: bar, resolution: 4}\nregions: {sel: builtin, handles: [{driver: "
                 "none}]}\nsinks: {display: {host: %s, port: 8080}}\n",
                 refused[i]);
        iso_test_write(g.path, g.doc, -1);
        int check = run_iso(0, NULL), run = run_iso(1, RUN_ONE_TICK " --port 0");
        const char *a = said(g.err[0], "check"), *b = said(g.err[1], "run");
        if (check != 1 || run != 1 || !a || !b || strcmp(a, b) != 0)
            fail_msg("host %s: check exited %d, run %d:\n%s%s", refused[i], check, run, g.err[0],
                     g.err[1]);
        if (!strstr(a, "agree.yaml:3:") || !strstr(a, "sinks.display.host: "))
            fail_msg("host %s: not at the key: %s", refused[i], a);
        print_message("host %-12s %s", refused[i], strstr(a, "host: ") + 6);
    }
    for (int i = 0; served[i]; i++) {
        snprintf(g.doc, sizeof g.doc,
                 "mesh: {shape: bar, resolution: 4}\nregions: {sel: builtin, handles: [{driver: "
                 "none}]}\nsinks: {display: {host: %s}}\n",
                 served[i]);
        iso_test_write(g.path, g.doc, -1);
        int check = run_iso(0, NULL), run = run_iso(1, RUN_ONE_TICK " --port 0");
        if (check != 0 || run != 0)
            fail_msg("host %s: check exited %d, run %d:\n%s%s", served[i], check, run, g.err[0],
                     g.err[1]);
    }
}

/* A scene of `mesh` with the builtin screw on its top and `solver`, checked
 * (its stdout into check_out) and then run with run_args (into g). */
static void check_then_run(const char *mesh, const char *solver, const char *run_args,
                           char *check_out, size_t cap)
{
    snprintf(g.doc, sizeof g.doc,
             "name: agree\nmesh: %s\nregions:\n  sel: builtin\n  handles:\n"
             "    - name: top\n      driver: {screw: {def: builtin, duration: 1.0}}\n"
             "solver: %s\ntick_hz: 60\n",
             mesh, solver);
    iso_test_write(g.path, g.doc, -1);
    assert_int_equal(run_iso(0, NULL), 0);
    snprintf(check_out, cap, "%s", g.out);
    assert_int_equal(run_iso(1, run_args), 0);
}

/* What the solver's model will be is said alike by both, and a setting
 * with nothing to act on is said, not dropped: a proxy budget not below
 * the mesh's size runs the whole mesh; proxy_smoothness without a proxy is
 * ignored. */
static void check_and_run_say_the_model_alike(void **state)
{
    (void)state;
    need_binary();
    static const char *const solver[] = {"{proxy: 100000}",
                                         "{proxy: off, proxy_smoothness: matched}"};
    for (int i = 0; i < 2; i++) {
        char check_out[sizeof g.out];
        check_then_run("{shape: cactus}", solver[i], RUN_ONE_TICK, check_out, sizeof check_out);
        print_message("solver %s: check says\n%s run says\n%s", solver[i],
                      strstr(check_out, "  model:"), g.err[1]);
        if (i == 0) {
            const char *m = strstr(check_out, "model: the whole mesh of ");
            assert_non_null(m);
            assert_non_null(strstr(m, "(solver.proxy: 100000 is not below the mesh's size)"));
            char line[400];
            snprintf(line, sizeof line, "%.*s", (int)strcspn(m, "\n") - 7, m + 7);
            assert_non_null(strstr(g.err[1], line)); /* run says the same */
        } else {
            assert_non_null(strstr(check_out, "note: solver.proxy_smoothness is ignored"));
            assert_non_null(strstr(g.err[1], "solver.proxy_smoothness is ignored"));
        }
    }
}

/* The first number after `key` in text, or -1. */
static double number_after(const char *text, const char *key)
{
    const char *p = strstr(text, key);
    return p ? strtod(p + strlen(key), NULL) : -1.0;
}

/* What `check` says a run will hold is what a run holds: the reduced
 * model's estimate within 25% of the run's peak (the estimate is a line
 * measured through 40k..1M vertices, within 4% there; sanitizers' shadow
 * memory makes any figure of their build meaningless, so that part skips
 * under them), the whole mesh's factors no more than the run's peak; and
 * the check itself, which builds no system for the reduced model, holds
 * less than the run. */
static void check_says_the_memory_a_run_holds(void **state)
{
    (void)state;
    need_binary();
    static const char *const mesh[] = {"{shape: bumpplane, resolution: 201}", "{shape: cactus}"};
    for (int i = 0; i < 2; i++) {
        char check_out[sizeof g.out];
        check_then_run(mesh[i], "{}", "--no-rt --ticks 5", check_out, sizeof check_out);
        double said = i == 0 ? number_after(check_out, "memory: about ")
                             : number_after(check_out, "memory: the whole mesh's factor ");
        double check_peak = number_after(check_out, "peak memory ");
        double run_peak = number_after(g.out, "memory      peak ");
        print_message("%s: check says %.0f MB, holds %.0f MB; the run's peak %.0f MB\n", mesh[i],
                      said, check_peak, run_peak);
        assert_true(said > 0 && check_peak > 0 && run_peak > 0);
        if (i == 1) {
            int held = strstr(check_out, "held twice") ? 2 : 1;
            assert_true(held * said <= run_peak);
            continue;
        }
        assert_true(check_peak < run_peak);
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_UNDEFINED__)
        print_message("skipped: the estimate against the run's peak (a sanitizer's build)\n");
#else
        assert_true(fabs(said - run_peak) <= 0.25 * run_peak);
#endif
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(check_and_run_agree_on_display_hosts),
        cmocka_unit_test(check_and_run_say_the_model_alike),
        cmocka_unit_test(check_says_the_memory_a_run_holds),
        cmocka_unit_test(check_and_run_refuse_every_key_alike),
    };
    return cmocka_run_group_tests_name("scene_agree", tests, NULL, NULL);
}
