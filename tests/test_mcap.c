/* tests/test_mcap.c -- `isoshape export` and the MCAP writer, read back by
 * an independent reader: @mcap/core from the npm registry, installed by
 * .ci/setup into the build folder (tests/tools/check_mcap.cjs does the
 * reading). It checks the data section's CRC, the summary's CRC, every
 * chunk's CRC, the statistics against the messages, seeking through the
 * chunk index, one mesh and one /loop message a recorded tick, every mesh
 * message's triangles, and the last commanded handle rotation against the
 * replay of the same recording. Also: the same recording exports the same
 * bytes, and a torn recording is said by export as by replay. Without node
 * or the installed reader the reader's part skips with a reason. */
#include "testutil.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "iso_mesh.h"

#define SKIP_WHY(why)                                                                              \
    do {                                                                                           \
        print_message("SKIP: %s\n", why);                                                          \
        skip();                                                                                    \
    } while (0)

static char g_bin[1024];

static void sh_ok(const char *cmd, char *out, size_t cap)
{
    static char err[8192];
    int st = iso_test_sh(cmd, out, cap, err, sizeof err);
    if (st != 0)
        fail_msg("%s: status %d: %s", cmd, st, err);
}

static int files_equal(const char *a, const char *b)
{
    FILE *f = fopen(a, "rb"), *g = fopen(b, "rb");
    int same = f && g;
    while (same) {
        int x = fgetc(f), y = fgetc(g);
        same = x == y;
        if (x == EOF || y == EOF)
            break;
    }
    if (f)
        fclose(f);
    if (g)
        fclose(g);
    return same;
}

static void export_reads_back(void **state)
{
    (void)state;
    if (iso_test_isoshape_bin(g_bin, sizeof g_bin) != 0)
        SKIP_WHY("the isoshape binary is not built");
    char rec[512], a[512], b[512], rest[512], cmd[4096];
    static char out[65536];
    snprintf(rec, sizeof rec, "%s/sm_session.isorec", ISO_TEST_STREAMS);
    snprintf(a, sizeof a, "%s/export_a.mcap", ISO_TEST_TMP);
    snprintf(b, sizeof b, "%s/export_b.mcap", ISO_TEST_TMP);
    snprintf(rest, sizeof rest, "%s/export_final.ply", ISO_TEST_TMP);
    /* the replay of the same recording: its ticks and the handle's pose */
    snprintf(cmd, sizeof cmd, "%s replay %s --shape cactus --resolution 1 --fast --out %s", g_bin,
             rec, rest);
    sh_ok(cmd, out, sizeof out);
    long ticks = 0;
    const char *p = strstr(out, ": ");
    assert_non_null(p);
    assert_int_equal(sscanf(p, ": %ld ticks", &ticks), 1);
    const char *h = strstr(out, "handle 0: p ");
    assert_non_null(h);
    double P[3], R[9];
    assert_int_equal(sscanf(h, "handle 0: p %lf %lf %lf  R %lf %lf %lf %lf %lf %lf %lf %lf %lf",
                            &P[0], &P[1], &P[2], &R[0], &R[1], &R[2], &R[3], &R[4], &R[5], &R[6],
                            &R[7], &R[8]),
                     12);
    iso_mesh *m = NULL;
    iso_err e;
    assert_int_equal(iso_mesh_load(rest, &m, &e), ISO_OK);
    int nv = iso_mesh_vertex_count(m), nt = iso_mesh_triangle_count(m);
    iso_mesh_destroy(m);
    for (int k = 0; k < 2; k++) {
        snprintf(cmd, sizeof cmd, "%s export %s --shape cactus --resolution 1 --mcap %s", g_bin,
                 rec, k ? b : a);
        sh_ok(cmd, out, sizeof out);
    }
    assert_true(files_equal(a, b)); /* stream time only: the same bytes */
    print_message("export: %s\n", out);
    if (system("node --version >/dev/null 2>&1") != 0)
        SKIP_WHY("node is not installed: the MCAP file was not read back by @mcap/core");
    struct stat st;
    if (stat(ISO_TEST_NODE_MODULES "/@mcap/core/package.json", &st) != 0)
        SKIP_WHY("@mcap/core is not installed in " ISO_TEST_NODE_MODULES " (.ci/setup installs "
                 "it from the npm registry)");
    int n = snprintf(cmd, sizeof cmd, "node %s/tools/check_mcap.cjs %s %s %ld %d %d handle",
                     ISO_TEST_SOURCE_TESTS, ISO_TEST_NODE_MODULES, a, ticks, nv, nt);
    for (int i = 0; i < 9; i++)
        n += snprintf(cmd + n, sizeof cmd - (size_t)n, " %.17g", R[i]);
    static char err[8192];
    int rc = iso_test_sh(cmd, out, sizeof out, err, sizeof err);
    print_message("%s%s", out, err);
    assert_int_equal(rc, 0);
}

static void torn_recording_is_said(void **state)
{
    (void)state;
    if (iso_test_isoshape_bin(g_bin, sizeof g_bin) != 0)
        SKIP_WHY("the isoshape binary is not built");
    char rec[512], mc[512], cmd[4096];
    static char out[8192], err_replay[8192], err_export[8192];
    snprintf(rec, sizeof rec, "%s/torn.isorec", ISO_TEST_STREAMS);
    snprintf(mc, sizeof mc, "%s/torn.mcap", ISO_TEST_TMP);
    snprintf(cmd, sizeof cmd, "%s replay %s --fast", g_bin, rec);
    assert_int_equal(iso_test_sh(cmd, out, sizeof out, err_replay, sizeof err_replay), 0);
    snprintf(cmd, sizeof cmd, "%s export %s --shape cactus --resolution 1 --mcap %s", g_bin, rec,
             mc);
    assert_int_equal(iso_test_sh(cmd, out, sizeof out, err_export, sizeof err_export), 0);
    const char *tear = strstr(err_replay, rec);
    assert_non_null(tear); /* replay names the file and where it is torn */
    char line[1024];
    snprintf(line, sizeof line, "%.*s", (int)strcspn(tear, "\n"), tear);
    if (!strstr(err_export, line))
        fail_msg("replay says '%s'; export does not:\n%s", line, err_export);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(export_reads_back),
        cmocka_unit_test(torn_recording_is_said),
    };
    return cmocka_run_group_tests_name("mcap", t, NULL, NULL);
}
