/* tests/test_dev_cut.c -- a recording cut off anywhere says so in every
 * command that reads it. The twist stream (tests/streams/sm_twist.isorec)
 * is cut at every byte of its last three records and of its END record;
 * `run` (a scene that replays it), `replay`, `export` and `inspect` must
 * each print the reader's sentence (iso_dev_rec_reader_cut) naming the
 * byte where the file ends (the three that tick: once), exit 0, and the
 * three that tick must still tick what came before the cut: one tick per
 * TICK record wholly before it, which for export means a finished MCAP
 * file whose /loop channel holds one message a tick (read back here from
 * the file's own statistics). The whole file says nothing of the kind. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "iso_dev_rec.h"
#include "testutil.h"

static struct {
    char bin[1024], rec[1024], scene[1024], mcap[1024];
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

/* How often `needle` occurs in `text`. */
static int occurrences(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = text; (p = strstr(p, needle)) != NULL; p += strlen(needle))
        n++;
    return n;
}

static uint64_t le(const uint8_t *p, int n)
{
    uint64_t v = 0;
    for (int i = n - 1; i >= 0; i--)
        v = v << 8 | p[i];
    return v;
}

/* The number of messages on `topic` in a finished MCAP file, as its
 * summary's Statistics record counts them (MCAP version 0: magic at both
 * ends, the Footer just before the closing magic points at the summary;
 * a Channel record starts with its id, its schema and its topic). Fails the
 * test, saying why, when the file is not a finished MCAP file or has no
 * such channel. */
static long mcap_topic_messages(const char *path, const char *topic)
{
    static const uint8_t magic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
    static uint8_t b[1 << 22];
    FILE *f = fopen(path, "rb");
    if (!f)
        fail_msg("%s: no MCAP file was written", path);
    size_t n = fread(b, 1, sizeof b, f);
    fclose(f);
    const size_t foot = 1 + 8 + 20; /* opcode, length, summary start, offsets start, CRC */
    if (n < 16 + foot || n == sizeof b || memcmp(b, magic, 8) || memcmp(b + n - 8, magic, 8) ||
        b[n - 8 - foot] != 0x02)
        fail_msg("%s: %zu bytes, not a finished MCAP file (magic, footer)", path, n);
    size_t pos = (size_t)le(b + n - 8 - foot + 9, 8), end = n - 8 - foot;
    long id = -1, count = -1;
    while (pos + 9 <= end) {
        const uint8_t op = b[pos];
        const size_t len = (size_t)le(b + pos + 1, 8), at = pos + 9;
        if (len > end - at)
            fail_msg("%s: summary record at byte %zu runs past the footer", path, pos);
        if (op == 0x04 && len >= 8) { /* Channel */
            const size_t tl = (size_t)le(b + at + 4, 4);
            if (8 + tl <= len && tl == strlen(topic) && !memcmp(b + at + 8, topic, tl))
                id = (long)le(b + at, 2);
        }
        if (op == 0x0B && len >= 46 && id >= 0) { /* Statistics: the per-channel map last */
            const size_t ml = (size_t)le(b + at + 42, 4);
            for (size_t k = at + 46; k + 10 <= at + 46 + ml && k + 10 <= at + len; k += 10)
                if ((long)le(b + k, 2) == id)
                    count = (long)le(b + k + 2, 8);
        }
        pos = at + len;
    }
    if (id < 0 || count < 0)
        fail_msg("%s: no %s channel, or no count of its messages, in the summary", path, topic);
    return count;
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
    iso_test_tmp(g.mcap, sizeof g.mcap, "dev_cut.mcap");
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
            assert_int_equal(occurrences(g.all, said), 1);
        assert_int_equal(ticks_after(g.out, ".isorec: "), ticks);

        remove(g.mcap);
        assert_int_equal(
            sh("%s export '%s' --scene '%s' --mcap '%s' ", g.bin, g.rec, g.scene, g.mcap), 0);
        if (whole)
            assert_null(strstr(g.all, "cut off"));
        else if (occurrences(g.all, said) != 1)
            fail_msg("cut at byte %zu: export should say '%s' once:\n%s", cut, said, g.all);
        assert_int_equal(ticks_after(g.out, ".isorec: "), ticks);
        struct stat st;
        assert_int_equal(stat(g.mcap, &st), 0);
        assert_true(st.st_size > 0);
        assert_int_equal(mcap_topic_messages(g.mcap, "/loop"), ticks);

        assert_int_equal(sh("%s run '%s' --fast --no-display ", g.bin, g.scene), 0);
        if (whole)
            assert_null(strstr(g.all, "cut off"));
        else
            assert_int_equal(occurrences(g.all, said), 1);
        assert_int_equal(ticks_after(g.all, "scene cut: "), ticks);
        checked++;
    }
    print_message("%d cuts (bytes %zu..%zu of %zu) said in run, replay, export and inspect\n",
                  checked - 1, starts[ns - 3], len - 1, len);
}

int main(void)
{
    const struct CMUnitTest t[] = {cmocka_unit_test(every_command_says_where_it_was_cut)};
    return cmocka_run_group_tests_name("dev_cut", t, NULL, NULL);
}
