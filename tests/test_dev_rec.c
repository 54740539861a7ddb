/* tests/test_dev_rec.c -- the recording format: round trip, the CRC's check
 * value, a recording cut at every byte, damage anywhere, header errors. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_dev_rec.h"
#include "testutil.h"

static uint8_t g_buf[20000];
static size_t g_end; /* where build()'s END record starts */

/* A recording of two sources and 40 records closed by its END record, in
 * g_buf; returns its length and the start of every record but END in
 * starts (ns of them). */
static size_t build(size_t *starts, size_t *ns)
{
    iso_dev_info in[2];
    memset(in, 0, sizeof in);
    in[0].kind = ISO_DEV_KIND_HID;
    in[0].vid = 0x256f;
    in[0].pid = 0xc652;
    strcpy(in[0].name, "/dev/hidraw0");
    in[0].desc_len = 3;
    in[0].desc[0] = 0x05;
    in[0].desc[1] = 0x01;
    in[0].desc[2] = 0x09;
    in[1].kind = ISO_DEV_KIND_SERIAL;
    in[1].baud = 115200;
    in[1].parity = 'N';
    strcpy(in[1].name, "/dev/ttyACM0");
    int h = iso_dev_rec_encode_header(g_buf, sizeof g_buf, in, 2, 77);
    assert_true(h > 0);
    size_t len = (size_t)h;
    *ns = 0;
    for (int k = 0; k < 40; k++) {
        iso_dev_chunk c;
        memset(&c, 0, sizeof c);
        c.t_ns = 1000 * k;
        c.type = k % 5 == 4 ? ISO_DEV_CHUNK_TICK : ISO_DEV_CHUNK_DATA;
        c.source = c.type == ISO_DEV_CHUNK_TICK ? 0 : (uint8_t)(k % 2);
        c.len = c.type == ISO_DEV_CHUNK_TICK ? 0 : (uint16_t)(k % 13 + 1);
        for (int i = 0; i < c.len; i++)
            c.data[i] = (uint8_t)(k * 7 + i); /* includes 0xA5 now and then */
        starts[(*ns)++] = len;
        int n = iso_dev_rec_encode_record(g_buf + len, sizeof g_buf - len, &c);
        assert_true(n > 0);
        len += (size_t)n;
    }
    iso_dev_chunk end = {.type = ISO_DEV_CHUNK_END};
    g_end = len;
    int n = iso_dev_rec_encode_record(g_buf + len, sizeof g_buf - len, &end);
    assert_int_equal(n, 17);
    return len + (size_t)n;
}

static void crc32_check_value(void **state)
{
    (void)state;
    assert_int_equal(iso_dev_crc32((const uint8_t *)"123456789", 9), 0xCBF43926u);
}

static void round_trip_through_a_file(void **state)
{
    (void)state;
    char path[1024];
    iso_test_tmp(path, sizeof path, "dev_rec_roundtrip.isorec");
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = ISO_DEV_KIND_GPIO;
    in.debounce_us = 1500;
    strcpy(in.name, "gpiochip0");
    iso_dev_rec_writer w;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_writer_open(&w, path, &in, 1, 5, &err), ISO_OK);
    iso_dev_chunk c = {.t_ns = -3, .type = ISO_DEV_CHUNK_DATA, .len = 2, .data = {1, 1}};
    assert_int_equal(iso_dev_rec_write(&w, &c, &err), ISO_OK);
    assert_int_equal(iso_dev_rec_tick(&w, 10, &err), ISO_OK);
    assert_int_equal(iso_dev_rec_writer_close(&w, &err), ISO_OK);
    iso_dev_rec_reader r;
    assert_int_equal(iso_dev_rec_reader_load(&r, path, &err), ISO_OK);
    assert_int_equal(r.n_sources, 1);
    assert_int_equal(r.t0_ns, 5);
    assert_int_equal(r.infos[0].debounce_us, 1500);
    assert_string_equal(r.infos[0].name, "gpiochip0");
    iso_dev_chunk o;
    assert_int_equal(iso_dev_rec_next(&r, &o, NULL), 1);
    assert_int_equal(o.t_ns, -3);
    assert_int_equal(o.len, 2);
    assert_int_equal(iso_dev_rec_next(&r, &o, NULL), 1);
    assert_int_equal(o.type, ISO_DEV_CHUNK_TICK);
    assert_int_equal(iso_dev_rec_next(&r, &o, NULL), 0);
    assert_int_equal(r.torn, 0);
    iso_dev_rec_reader_deinit(&r);
    /* errors name the file and what */
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_reader_load(&r, "/nonexistent/x.isorec", &err), ISO_EIO);
    assert_string_equal(err.msg, "/nonexistent/x.isorec: cannot open: No such file or directory");
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_writer_open(&w, "/nonexistent/x.isorec", &in, 1, 0, &err),
                     ISO_EIO);
    assert_string_equal(err.msg, "/nonexistent/x.isorec: cannot create: No such file or directory");
}

static void cut_at_every_byte(void **state)
{
    (void)state;
    size_t starts[64], ns;
    size_t len = build(starts, &ns);
    size_t hlen = starts[0];
    for (size_t cut = 0; cut <= len; cut++) {
        uint8_t *copy = malloc(cut ? cut : 1); /* exact size: ASan sees overreads */
        memcpy(copy, g_buf, cut);
        iso_dev_rec_reader r;
        iso_err err;
        iso_err_clear(&err);
        int rc = iso_dev_rec_reader_init(&r, copy, cut, &err);
        if (cut < hlen) {
            assert_int_equal(rc, ISO_EPARSE);
            assert_non_null(strstr(err.msg, "recording header, byte "));
            free(copy);
            continue;
        }
        assert_int_equal(rc, ISO_OK);
        iso_dev_chunk c;
        long n = 0;
        while (iso_dev_rec_next(&r, &c, NULL) == 1)
            n++;
        /* every record that ends at or before the cut, and nothing else */
        long want = 0;
        size_t last_end = hlen;
        for (size_t i = 0; i < ns; i++) {
            size_t end = i + 1 < ns ? starts[i + 1] : g_end;
            if (end <= cut) {
                want++;
                last_end = end;
            }
        }
        if (cut == len)
            last_end = len; /* the END record */
        assert_int_equal(n, want);
        assert_int_equal(r.damaged, 0);
        assert_int_equal(r.torn, cut != last_end);
        assert_int_equal(r.ended, cut == len);
        assert_int_equal(r.end_at, (long)last_end);
        char expect[64], msg[400];
        snprintf(expect, sizeof expect, "cut off at byte %zu", cut);
        if (r.torn)
            assert_non_null(strstr(r.note, expect));
        /* the one sentence every command prints: a cut anywhere, records
         * boundaries and the END record's own bytes included, says where */
        long at = -1;
        assert_int_equal(iso_dev_rec_reader_cut(&r, msg, sizeof msg, &at), cut != len);
        if (cut != len) {
            assert_non_null(strstr(msg, expect));
            assert_int_equal(at, (long)(last_end < g_end ? last_end : g_end));
            char used[128];
            snprintf(used, sizeof used, "(%ld records, %ld ticks, up to byte %ld)", want, want / 5,
                     at);
            assert_non_null(strstr(msg, used));
        } else {
            assert_string_equal(msg, "");
            assert_int_equal(at, (long)len);
        }
        iso_dev_rec_reader_deinit(&r);
        free(copy);
    }
}

static void damage_anywhere_is_skipped(void **state)
{
    (void)state;
    size_t starts[64], ns;
    size_t len = build(starts, &ns);
    for (size_t i = 0; i + 1 < ns; i++) {
        for (size_t at = starts[i]; at < starts[i + 1]; at += 3) {
            uint8_t *copy = malloc(len);
            memcpy(copy, g_buf, len);
            copy[at] ^= 0x5a;
            iso_dev_rec_reader r;
            assert_int_equal(iso_dev_rec_reader_init(&r, copy, len, NULL), ISO_OK);
            iso_dev_chunk c;
            long n = 0;
            int dmg, seen = 0;
            while (iso_dev_rec_next(&r, &c, &dmg) == 1) {
                seen |= dmg;
                n++;
            }
            /* exactly the damaged record is lost */
            assert_int_equal(n, (long)ns - 1);
            assert_int_equal(r.damaged, 1);
            assert_int_equal(seen, 1);
            assert_int_equal(r.last_damage_at, (long)starts[i]);
            assert_int_equal(r.torn, 0);
            char msg[400];
            assert_int_equal(iso_dev_rec_reader_cut(&r, msg, sizeof msg, NULL), 0); /* whole */
            char expect[64];
            snprintf(expect, sizeof expect, "damaged record at byte %zu", starts[i]);
            assert_non_null(strstr(r.note, expect));
            iso_dev_rec_reader_deinit(&r);
            free(copy);
        }
    }
}

static void header_errors(void **state)
{
    (void)state;
    size_t starts[64], ns;
    size_t len = build(starts, &ns);
    iso_dev_rec_reader r;
    iso_err err;
    uint8_t *copy = malloc(len);
    memcpy(copy, g_buf, len);
    copy[0] = 'X';
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_reader_init(&r, copy, len, &err), ISO_EPARSE);
    assert_string_equal(err.msg,
                        "recording header, byte 0: not an isoshape recording (no ISOSHREC magic)");
    memcpy(copy, g_buf, len);
    copy[8] = 3;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_reader_init(&r, copy, len, &err), ISO_EPARSE);
    assert_string_equal(err.msg, "recording header, byte 8: format version unknown to this "
                                 "build (it reads 1 and 2)");
    memcpy(copy, g_buf, len);
    copy[30] ^= 1;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_reader_init(&r, copy, len, &err), ISO_EPARSE);
    assert_non_null(strstr(err.msg, "header checksum mismatch"));
    assert_int_equal(err.offset, (long)starts[0] - 4);
    free(copy);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(crc32_check_value), cmocka_unit_test(round_trip_through_a_file),
        cmocka_unit_test(cut_at_every_byte), cmocka_unit_test(damage_anywhere_is_skipped),
        cmocka_unit_test(header_errors),
    };
    return cmocka_run_group_tests_name("dev_rec", t, NULL, NULL);
}
