/* tests/test_dev_cut.c -- a recording cut off anywhere says so in every
 * command that reads it. The twist stream (tests/streams/sm_twist.isorec)
 * is cut at every byte of its last three records and of its END record;
 * `run` (a scene that replays it), `replay` and `inspect` must each print
 * the reader's sentence (iso_dev_rec_reader_cut) naming the byte where the
 * file ends, and the two that tick must still tick what came before the
 * cut: one tick per TICK record wholly before it. The whole file says
 * nothing of the kind. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_dev.h"
#include "testutil.h"

static struct {
    char bin[1024], rec[1024], scene[1024];
    char out[1 << 16], err[1 << 16], all[1 << 17];
} g;

/* Runs one command line; g.all gets its stderr, then its stdout. */
static int sh(const char *fmt, ...)
{
    char cmd[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int st = iso_test_sh(cmd, g.out, sizeof g.out, g.err, sizeof g.err);
    snprintf(g.all, sizeof g.all, "%s%s", g.err, g.out);
    return st;
}

/* "N ticks" as the command printed it after `key` (the text just before). */
static long ticks_after(const char *text, const char *key)
{
    const char *p = strstr(text, key);
    assert_non_null(p);
    return strtol(p + strlen(key), NULL, 10);
}

static void every_command_says_where_it_was_cut(void **state)
{
    (void)state;
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0) {
        print_message("skipped: the isoshape binary is not built\n");
        skip();
    }
    char src[1024];
    snprintf(src, sizeof src, "%s/sm_twist.isorec", ISO_TEST_STREAMS);
    static char data[1 << 16];
    FILE *f = fopen(src, "rb");
    assert_non_null(f);
    size_t len = fread(data, 1, sizeof data, f);
    fclose(f);
    assert_true(len > 0 && len < sizeof data);
    /* where each record starts, and how many TICK records end by each byte */
    iso_dev_rec_reader r;
    assert_int_equal(iso_dev_rec_reader_init(&r, (const uint8_t *)data, len, NULL), ISO_OK);
    size_t starts[64], ns = 0;
    int is_tick[64];
    iso_dev_chunk c;
    starts[ns] = r.pos;
    while (iso_dev_rec_next(&r, &c, NULL) == 1 && ns < 63) {
        is_tick[ns] = c.type == ISO_DEV_CHUNK_TICK;
        starts[++ns] = r.pos; /* the last is END's start */
    }
    assert_int_equal(r.ended, 1);
    assert_true(ns >= 4);
    iso_dev_rec_reader_deinit(&r);

    iso_test_tmp(g.rec, sizeof g.rec, "dev_cut.isorec");
    iso_test_tmp(g.scene, sizeof g.scene, "dev_cut.yaml");
    char yaml[2048];
    snprintf(yaml, sizeof yaml,
             "name: cut\n"
             "mesh: {shape: cylinder, resolution: 8}\n"
             "devices:\n  - {name: rec, kind: replay, file: \"%s\"}\n"
             "regions:\n  sel: builtin\n  handles:\n    - {name: handle, driver: {device: rec}}\n"
             "solver: {assembly: cpu, refactor: always}\n"
             "tick_hz: 1000\n",
             g.rec);
    iso_test_write(g.scene, yaml, -1);

    int checked = 0;
    for (size_t cut = starts[ns - 3]; cut <= len; cut++) {
        iso_test_write(g.rec, data, (long)cut);
        long ticks = 0; /* TICK records wholly before the cut */
        for (size_t i = 0; i < ns; i++)
            ticks += is_tick[i] && starts[i + 1] <= cut;
        char said[64];
        snprintf(said, sizeof said, "is cut off at byte %zu", cut);
        const int whole = cut == len;

        assert_int_equal(sh("%s inspect '%s' --no-bytes ", g.bin, g.rec), 0);
        if (whole)
            assert_null(strstr(g.all, "cut off"));
        else
            assert_non_null(strstr(g.all, said));
        assert_int_equal(ticks_after(g.all, " records, "), ticks);

        assert_int_equal(sh("%s replay '%s' --fast ", g.bin, g.rec), 0);
        if (whole)
            assert_null(strstr(g.all, "cut off"));
        else
            assert_non_null(strstr(g.all, said));
        assert_int_equal(ticks_after(g.out, ".isorec: "), ticks);

        assert_int_equal(sh("%s run '%s' --fast --no-display ", g.bin, g.scene), 0);
        if (whole)
            assert_null(strstr(g.all, "cut off"));
        else
            assert_non_null(strstr(g.all, said));
        assert_int_equal(ticks_after(g.all, "scene cut: "), ticks);
        checked++;
    }
    print_message("%d cuts (bytes %zu..%zu of %zu) said in run, replay and inspect\n", checked - 1,
                  starts[ns - 3], len - 1, len);
}

int main(void)
{
    const struct CMUnitTest t[] = {cmocka_unit_test(every_command_says_where_it_was_cut)};
    return cmocka_run_group_tests_name("dev_cut", t, NULL, NULL);
}
