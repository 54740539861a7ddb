/* tests/test_cli_docs.c -- the README's commands run as written. The
 * blocks of its Commands section run line by line in an empty folder (each
 * line may use what the lines above it wrote), those of its Devices section
 * from the source tree's root, with `isoshape` on the PATH as the built
 * binary: a line that needs a file nobody wrote, or hardware, fails here
 * unless it is one the test names as skipped and says why. And the files
 * that make the first block self-contained, `deform --shape NAME
 * --write-problem DIR`, read back through --mesh, --sel and --def to the
 * same deformation, bit for bit; and meshes are written in the formats
 * the README's File formats section says. */
#include "testutil.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* The test program's state (the SQLite manner). */
static struct {
    char bin[PATH_MAX];
    char out[65536], err[16384]; /* the last command's output */
} g;

/* `rel` in this source tree (from this file's own path) into buf. */
static const char *source_path(char *buf, size_t cap, const char *rel)
{
    snprintf(buf, cap, "%s", __FILE__);
    char *t = strstr(buf, "tests/test_cli_docs.c");
    if (t)
        snprintf(t, cap - (size_t)(t - buf), "%s", rel);
    else
        snprintf(buf, cap, "../%s", rel);
    return buf;
}

static int sh(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int sh(const char *fmt, ...)
{
    static char cmd[4 * PATH_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    return iso_test_sh(cmd, g.out, sizeof g.out, g.err, sizeof g.err);
}

static void need_binary(void)
{
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0) {
        print_message("skipped: no isoshape binary at %s (set ISOSHAPE_BIN)\n", g.bin);
        skip();
    }
}

/* ---- --write-problem ------------------------------------------------------ */

static void write_problem_reads_back_to_the_same_deformation(void **state)
{
    (void)state;
    char dir[PATH_MAX], a[PATH_MAX], b[PATH_MAX];
    need_binary();
    iso_test_tmp(dir, sizeof dir, "problem");
    iso_test_tmp(a, sizeof a, "problem_shape.off");
    iso_test_tmp(b, sizeof b, "problem_files.off");
    assert_int_equal(sh("rm -rf '%s'", dir), 0);
    if (sh("'%s' deform --shape cactus --resolution 1 --write-problem '%s'", g.bin, dir) != 0)
        fail_msg("--write-problem failed: %s", g.err);
    printf("%s", g.out);
    static const char *const said[] = {"cactus.off: ",
                                       " vertices, ",
                                       "cactus.sel: ",
                                       " fixed, ",
                                       " handle",
                                       "cactus.def: the handle's final pose",
                                       NULL};
    for (int i = 0; said[i]; i++)
        if (!strstr(g.out, said[i]))
            fail_msg("--write-problem does not say '%s': %s", said[i], g.out);
    if (sh("'%s' deform --shape cactus --resolution 1 --steps 6 --assembly cpu --out '%s'", g.bin,
           a) != 0)
        fail_msg("deform --shape: %s", g.err);
    if (sh("'%s' deform --mesh '%s/cactus.off' --sel '%s/cactus.sel' --def '%s/cactus.def' "
           "--steps 6 --assembly cpu --out '%s'",
           g.bin, dir, dir, dir, b) != 0)
        fail_msg("deform --mesh --sel --def: %s", g.err);
    if (sh("cmp '%s' '%s'", a, b) != 0)
        fail_msg("the written problem deforms differently from the built-in: %s", g.out);
    /* again into the same folder: replaced whole, no temporary left */
    assert_int_equal(sh("'%s' deform --shape cactus --resolution 1 --write-problem '%s' && ls '%s'",
                        g.bin, dir, dir),
                     0);
    assert_null(strstr(g.out, ".part"));
    /* it writes a built-in problem, nothing else */
    assert_int_equal(sh("'%s' deform --mesh '%s/cactus.off' --sel '%s/cactus.sel' --def "
                        "'%s/cactus.def' --write-problem '%s'",
                        g.bin, dir, dir, dir, dir),
                     2);
    assert_non_null(strstr(g.err, "--write-problem writes a built-in shape's problem: give "
                                  "--shape NAME"));
    assert_int_equal(sh("'%s' deform --shape cactus --write-problem ''", g.bin), 2);
    assert_non_null(strstr(g.err, "--write-problem is empty"));
}

/* File formats, as the README says them: OFF and OBJ text with 17
 * significant digits, PLY binary little-endian with double coordinates;
 * each reads back to the same bits (the distortion between them is 0). */
static void written_meshes_are_what_the_readme_says(void **state)
{
    (void)state;
    char base[PATH_MAX];
    need_binary();
    iso_test_tmp(base, sizeof base, "formats");
    static const char *const ext[] = {"off", "obj", "ply"};
    for (int i = 0; i < 3; i++)
        if (sh("'%s' deform --shape bar --resolution 4 --steps 2 --assembly cpu --out '%s.%s'",
               g.bin, base, ext[i]) != 0)
            fail_msg("deform --out .%s: %s", ext[i], g.err);
    assert_int_equal(sh("head -c 200 '%s.ply'", base), 0);
    assert_non_null(strstr(g.out, "format binary_little_endian 1.0\n"));
    assert_non_null(strstr(g.out, "property double x\n"));
    assert_int_equal(sh("sed -n 3p '%s.off'", base), 0); /* the first vertex */
    double x, y, z;
    char tail;
    assert_int_equal(sscanf(g.out, "%lf %lf %lf%c", &x, &y, &z, &tail), 4);
    for (int i = 1; i < 3; i++) {
        if (sh("'%s' metrics '%s.off' '%s.%s' --json", g.bin, base, base, ext[i]) != 0)
            fail_msg("metrics .off against .%s: %s", ext[i], g.err);
        if (!strstr(g.out, "\"metric_err\": 0,") || !strstr(g.out, "\"max_edge_strain\": 0,"))
            fail_msg(".%s does not read back to the .off's bits: %s", ext[i], g.out);
    }
}

/* ---- the README's blocks ---------------------------------------------------- */

/* The text of the first ```sh block after the heading `section` of the
 * README, into buf. */
static void readme_block(const char *section, char *buf, size_t cap)
{
    static char text[1 << 17];
    char path[PATH_MAX];
    FILE *f = fopen(source_path(path, sizeof path, "README.md"), "rb");
    assert_non_null(f);
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    const char *h = strstr(text, section), *from = h ? strstr(h, "```sh\n") : NULL;
    const char *to = from ? strstr(from + 6, "```") : NULL;
    if (!to)
        fail_msg("README.md has no ```sh block after '%s'", section);
    from += 6;
    snprintf(buf, cap, "%.*s", (int)(to - from), from);
}

/* Runs the block's lines in folder `dir`, with `isoshape` on the PATH, each
 * line after the ones above it; a line starting with one of `skips` is
 * left out with the reason beside it. Returns the lines run. */
static int run_block(const char *block, const char *dir, const char *const skips[][2])
{
    char bin_dir[PATH_MAX], line[1024], script[PATH_MAX];
    int ran = 0;
    iso_test_tmp(bin_dir, sizeof bin_dir, "readme_bin");
    assert_int_equal(sh("rm -rf '%s' && mkdir -p '%s' && ln -s '%s' '%s/isoshape'", bin_dir,
                        bin_dir, g.bin, bin_dir),
                     0);
    iso_test_tmp(script, sizeof script, "readme_line.sh");
    for (const char *p = block; *p; p += strcspn(p, "\n") + (p[strcspn(p, "\n")] != '\0')) {
        snprintf(line, sizeof line, "%.*s", (int)strcspn(p, "\n"), p);
        if (!line[0] || line[0] == '#')
            continue;
        const char *why = NULL;
        for (int s = 0; skips[s][0] && !why; s++)
            if (strncmp(line, skips[s][0], strlen(skips[s][0])) == 0)
                why = skips[s][1];
        if (why) {
            printf("skipped: %s  (%s)\n", line, why);
            continue;
        }
        iso_test_write(script, line, -1);
        printf("$ %s\n", line);
        if (sh("cd '%s' && PATH='%s':\"$PATH\" timeout 300 sh -e '%s' </dev/null", dir, bin_dir,
               script) != 0)
            fail_msg("the README's line failed in %s:\n  %s\n%s%s", dir, line, g.out, g.err);
        ran++;
    }
    return ran;
}

static void readme_commands_run_as_written(void **state)
{
    (void)state;
    static char block[8192];
    static const char *const skips[][2] = {
        {"isoshape bench", "minutes; test_cli runs bench --quick --json"}, {NULL, NULL}};
    char dir[PATH_MAX];
    need_binary();
    readme_block("\n## Commands\n", block, sizeof block);
    iso_test_tmp(dir, sizeof dir, "readme_commands");
    assert_int_equal(sh("rm -rf '%s' && mkdir -p '%s'", dir, dir), 0);
    int ran = run_block(block, dir, skips);
    printf("%d lines of the Commands block ran as written in an empty folder\n", ran);
    assert_true(ran >= 8);
}

static void readme_device_lines_run_as_written(void **state)
{
    (void)state;
    static char block[8192];
    static const char *const skips[][2] = {
        {"isoshape record", "needs the devices it names: a 3D mouse and a GPIO chip"},
        {NULL, NULL}};
    char root[PATH_MAX];
    need_binary();
    readme_block("\n## Devices\n", block, sizeof block);
    source_path(root, sizeof root, "");
    int ran = run_block(block, root, skips);
    printf("%d lines of the Devices block ran as written from the clone's root\n", ran);
    assert_true(ran >= 4);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(write_problem_reads_back_to_the_same_deformation),
        cmocka_unit_test(written_meshes_are_what_the_readme_says),
        cmocka_unit_test(readme_commands_run_as_written),
        cmocka_unit_test(readme_device_lines_run_as_written),
    };
    return cmocka_run_group_tests_name("cli_docs", tests, NULL, NULL);
}
