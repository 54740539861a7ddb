/* tests/test_mcap.c -- `isoshape export` and the MCAP writer, read back by
 * an independent reader: @mcap/core from the npm registry, with fzstd (a
 * zstd decoder in JavaScript, not libzstd) for the compressed chunks, both
 * installed by .ci/setup into the build folder (tests/tools/check_mcap.cjs
 * does the reading). It checks the data section's CRC, the summary's CRC,
 * every chunk's compression, sizes and CRC (of its records decompressed)
 * and its chunk index, the statistics against the messages, seeking
 * through the chunk index, one mesh and one /loop message a recorded tick,
 * every mesh message's triangles, the last commanded handle rotation
 * against the replay of the same recording, and every message of the
 * compressed export against the uncompressed export's, byte for byte; the
 * uncompressed file passes the same checks. Also: the same recording
 * exports the same bytes, compression makes the file smaller, the
 * writer's compression setting is refused after the first message, and a
 * torn recording is said by export as by replay. Without node or the
 * installed packages the reader's part skips with a reason. */
#include "testutil.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "iso_mcap.h"
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
    char rec[512], a[512], b[512], plain[512], rest[512], cmd[4096];
    static char out[65536];
    snprintf(rec, sizeof rec, "%s/sm_session.isorec", ISO_TEST_STREAMS);
    snprintf(a, sizeof a, "%s/export_a.mcap", ISO_TEST_TMP);
    snprintf(b, sizeof b, "%s/export_b.mcap", ISO_TEST_TMP);
    snprintf(plain, sizeof plain, "%s/export_plain.mcap", ISO_TEST_TMP);
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
    /* a and b: the default (zstd); plain: without compression */
    const char *const to[3] = {a, b, plain};
    for (int k = 0; k < 3; k++) {
        snprintf(cmd, sizeof cmd, "%s export %s --shape cactus --resolution 1 --mcap %s%s", g_bin,
                 rec, to[k], k == 2 ? " --mcap-compression none" : "");
        sh_ok(cmd, out, sizeof out);
    }
    assert_true(files_equal(a, b)); /* stream time only, one compression level: the same bytes */
    print_message("export: %s\n", out);
    struct stat sa, sp;
    assert_int_equal(stat(a, &sa), 0);
    assert_int_equal(stat(plain, &sp), 0);
    print_message("zstd: %lld bytes, none: %lld\n", (long long)sa.st_size, (long long)sp.st_size);
    if (!(sa.st_size * 2 < sp.st_size))
        fail_msg("the zstd export (%lld bytes) is not under half the plain one (%lld)",
                 (long long)sa.st_size, (long long)sp.st_size);
    if (system("node --version >/dev/null 2>&1") != 0)
        SKIP_WHY("node is not installed: the MCAP file was not read back by @mcap/core");
    static const char *const packages[] = {"@mcap/core", "fzstd"};
    for (int i = 0; i < 2; i++) {
        char pj[1024], why[1400];
        snprintf(pj, sizeof pj, "%s/%s/package.json", ISO_TEST_NODE_MODULES, packages[i]);
        snprintf(why, sizeof why,
                 "%s is not installed in %s (.ci/setup installs it from the npm registry): the "
                 "MCAP files were not read back",
                 packages[i], ISO_TEST_NODE_MODULES);
        struct stat st;
        if (stat(pj, &st) != 0)
            SKIP_WHY(why);
    }
    /* the compressed file, then the plain one through the same checks */
    const char *const file[2] = {a, plain}, *const comp[2] = {"zstd", ""};
    for (int k = 0; k < 2; k++) {
        int n = snprintf(
            cmd, sizeof cmd, "node %s/tools/check_mcap.cjs %s %s %s '%s' %ld %d %d handle",
            ISO_TEST_SOURCE_TESTS, ISO_TEST_NODE_MODULES, file[k], plain, comp[k], ticks, nv, nt);
        for (int i = 0; i < 9; i++)
            n += snprintf(cmd + n, sizeof cmd - (size_t)n, " %.17g", R[i]);
        static char err[8192];
        int rc = iso_test_sh(cmd, out, sizeof out, err, sizeof err);
        print_message("%s%s", out, err);
        assert_int_equal(rc, 0);
    }
}

/* The writer's own rules for its setting: one compression a file, set
 * before the first message, and only one it knows. */
static void compression_is_set_before_the_first_message(void **state)
{
    (void)state;
    char path[512];
    snprintf(path, sizeof path, "%s/setting.mcap", ISO_TEST_TMP);
    iso_mcap *m = NULL;
    iso_err e;
    iso_err_clear(&e);
    uint16_t schema, ch;
    assert_int_equal(iso_mcap_create(path, "", "test_mcap", &m, &e), ISO_OK);
    assert_int_equal(iso_mcap_set_compression(m, 7, &e), ISO_EINVAL);
    assert_non_null(strstr(e.msg, "no compression 7"));
    iso_err_clear(&e);
    assert_int_equal(iso_mcap_set_compression(m, ISO_MCAP_NONE, &e), ISO_OK);
    assert_int_equal(iso_mcap_add_schema(m, "s", "jsonschema", "{}", &schema, &e), ISO_OK);
    assert_int_equal(iso_mcap_add_channel(m, schema, "/t", "json", &ch, &e), ISO_OK);
    assert_int_equal(iso_mcap_write(m, ch, 1, "{}", 2, &e), ISO_OK);
    assert_int_equal(iso_mcap_set_compression(m, ISO_MCAP_ZSTD, &e), ISO_EINVAL);
    assert_non_null(strstr(e.msg, "after the first message"));
    assert_int_equal(iso_mcap_finish(m, &e), ISO_OK);
    /* the names the command line takes, by value */
    assert_string_equal(iso_mcap_compression_names[ISO_MCAP_ZSTD], "zstd");
    assert_string_equal(iso_mcap_compression_names[ISO_MCAP_NONE], "none");
    assert_null(iso_mcap_compression_names[2]);
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
        cmocka_unit_test(compression_is_set_before_the_first_message),
        cmocka_unit_test(torn_recording_is_said),
    };
    return cmocka_run_group_tests_name("mcap", t, NULL, NULL);
}
