/* tests/test_common.c -- the helpers every part shares (common/): the
 * clock and its absolute-deadline sleep, the whole-file reader, the JSON
 * writer and enum name tables. */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_crc32.h"
#include "iso_fd.h"
#include "iso_file.h"
#include "iso_json.h"
#include "iso_names.h"
#include "testutil.h"

static void clock_sleeps_to_its_deadline(void **state)
{
    (void)state;
    int64_t t0 = iso_clock_ns();
    assert_true(t0 > 0);
    for (int i = 0; i < 5; i++) {
        int64_t deadline = iso_clock_ns() + 2000000; /* 2 ms */
        assert_int_equal(iso_clock_sleep_until(deadline), 0);
        assert_true(iso_clock_ns() >= deadline); /* never early */
    }
    assert_int_equal(iso_clock_sleep_until(t0), 0); /* already past: at once */
    /* the derived forms read the same clock */
    int64_t ns = iso_clock_ns();
    uint64_t us = iso_clock_us();
    double s = iso_clock_now();
    /* us is read later but truncated to the microsecond: at most 999 ns below */
    assert_true((int64_t)us * 1000 + 999 >= ns && fabs(s - 1e-9 * (double)ns) < 0.5);
    /* ms until a deadline rounds up, and 0 once it has passed */
    uint64_t now = iso_clock_us();
    int ms = iso_clock_ms_until(now + 1500);
    assert_true(ms == 2 || ms == 1); /* 1 only if 500+ us passed in between */
    assert_int_equal(iso_clock_ms_until(now > 10 ? now - 10 : 0), 0);
}

static void file_reads_whole_and_terminated(void **state)
{
    (void)state;
    char path[512], *data = NULL;
    size_t len = 0;
    iso_test_tmp(path, sizeof path, "common_file.bin");
    iso_test_write(path, "ab\0cd", 5);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_file_read(path, 0, &data, &len, &err), ISO_OK);
    assert_int_equal(len, 5);
    assert_memory_equal(data, "ab\0cd", 5);
    assert_int_equal(data[5], '\0');
    free(data);
    /* larger than 200 000 bytes: grows past the first buffer */
    char *big = malloc(200001);
    assert_non_null(big);
    memset(big, 'x', 200000);
    big[200000] = '\0';
    iso_test_write(path, big, 200000);
    assert_int_equal(iso_file_read(path, 0, &data, &len, &err), ISO_OK);
    assert_int_equal(len, 200000);
    assert_string_equal(data, big);
    free(data);
    free(big);
    /* a limit, and a file that is not there: errors that name the path */
    iso_err_clear(&err);
    assert_int_equal(iso_file_read(path, 1000, &data, &len, &err), ISO_EINVAL);
    assert_null(data);
    assert_non_null(strstr(err.msg, "larger than 1000 bytes"));
    assert_non_null(strstr(err.msg, path));
    iso_err_clear(&err);
    assert_int_equal(iso_file_read("/nonexistent/f", 0, &data, &len, &err), ISO_EIO);
    assert_string_equal(err.msg, "/nonexistent/f: cannot open: No such file or directory");
}

/* The test program's state (the SQLite manner): the last JSON written. */
static struct {
    char *text;
    size_t len;
} g;

/* Writes with iso_json into g.text and returns it (valid until the next
 * call; main frees the last). */
static const char *json_of(void (*write)(iso_json *))
{
    free(g.text);
    g.text = NULL;
    FILE *f = open_memstream(&g.text, &g.len);
    assert_non_null(f);
    iso_json j;
    iso_json_begin(&j, f);
    write(&j);
    assert_int_equal(iso_json_end(&j), 0);
    assert_int_equal(fclose(f), 0);
    return g.text;
}

static void write_sample(iso_json *j)
{
    iso_json_number(j, "pi", 3.141592653589793);
    iso_json_number(j, "nan", NAN);
    iso_json_number(j, "inf", -INFINITY);
    iso_json_int(j, "n", -42);
    iso_json_bool(j, "ok", 1);
    iso_json_string(j, "s", "quote \" back \\ tab\t nl\n é");
    iso_json_string(j, "none", NULL);
    iso_json_array(j, "list");
    iso_json_number(j, NULL, 1);
    iso_json_object(j, NULL);
    iso_json_int(j, "k", 2);
    iso_json_close(j);
    iso_json_array(j, NULL);
    iso_json_close(j);
    iso_json_close(j);
    iso_json_object(j, "open"); /* left open: end closes it */
    iso_json_int(j, "last", 3);
}

static void write_too_deep(iso_json *j)
{
    for (int i = 0; i < ISO_JSON_MAX_DEPTH + 3; i++)
        iso_json_array(j, i ? NULL : "deep");
    iso_json_int(j, NULL, 1);
    for (int i = 0; i < ISO_JSON_MAX_DEPTH + 3; i++)
        iso_json_close(j);
    iso_json_int(j, "after", 2);
}

static void json_writer_is_valid_and_null_for_non_finite(void **state)
{
    (void)state;
    const char *t = json_of(write_sample);
    assert_string_equal(t, "{\"pi\": 3.1415926535897931, \"nan\": null, \"inf\": null, \"n\": -42, "
                           "\"ok\": true, \"s\": \"quote \\\" back \\\\ tab\\u0009 nl\\n é\", "
                           "\"none\": null, \"list\": [1, {\"k\": 2}, []], "
                           "\"open\": {\"last\": 3}}\n");
    assert_true(strtod(strstr(t, "\"pi\": ") + 6, NULL) == 3.141592653589793); /* 17 digits */
    char bad[64];
    assert_int_equal(iso_test_json_keys_snake_case(t, bad, sizeof bad), 1);
    /* past the depth limit nothing opens, and every close still pairs */
    t = json_of(write_too_deep);
    size_t opens = 0, closes = 0;
    for (const char *c = t; *c; c++) {
        opens += *c == '[' || *c == '{';
        closes += *c == ']' || *c == '}';
    }
    assert_int_equal(opens, closes);
    assert_int_equal(opens, ISO_JSON_MAX_DEPTH);
    assert_non_null(strstr(t, ", \"after\": 2}"));
}

typedef struct record {
    char name[8];
    int on, n;
    long big;
    uint32_t u;
    double x;
} record;

static void write_record(iso_json *j)
{
    static const iso_json_field fields[] = {{ISO_JSON_FIELD(record, name, ISO_JSON_TEXT)},
                                            {ISO_JSON_FIELD(record, on, ISO_JSON_BOOL)},
                                            {ISO_JSON_FIELD(record, n, ISO_JSON_INT)},
                                            {"long", ISO_JSON_LONG, offsetof(record, big)},
                                            {ISO_JSON_FIELD(record, u, ISO_JSON_U32)},
                                            {ISO_JSON_FIELD(record, x, ISO_JSON_DOUBLE)}};
    record r = {"a\"b", 1, -3, 1L << 40, 4000000000u, 0.1};
    iso_json_fields(j, &r, fields, sizeof fields / sizeof fields[0]);
    r.x = NAN;
    iso_json_fields(j, &r, fields + 5, 1);
}

/* A record through a table of its members: each type as its own call
 * would write it. */
static void json_fields_write_members_by_table(void **state)
{
    (void)state;
    assert_string_equal(json_of(write_record), "{\"name\": \"a\\\"b\", \"on\": true, \"n\": -3, "
                                               "\"long\": 1099511627776, \"u\": 4000000000, "
                                               "\"x\": 0.10000000000000001, \"x\": null}\n");
}

static void names_find_get_and_list(void **state)
{
    (void)state;
    static const char *const names[] = {"cpu", "opencl", "gpu", NULL};
    char buf[64];
    assert_int_equal(iso_names_find(names, "opencl"), 1);
    assert_int_equal(iso_names_find(names, "OpenCL"), -1);
    assert_int_equal(iso_names_find(names, NULL), -1);
    assert_string_equal(iso_names_get(names, 2), "gpu");
    assert_string_equal(iso_names_get(names, 3), "?");
    assert_string_equal(iso_names_get(names, -1), "?");
    assert_string_equal(iso_names_list(names, " or ", buf, sizeof buf), "cpu, opencl or gpu");
    assert_string_equal(iso_names_list(names, ", ", buf, sizeof buf), "cpu, opencl, gpu");
    assert_string_equal(iso_names_list(names, " or ", buf, 8), "cpu, op"); /* cut, terminated */
}

/* A listening socket on 127.0.0.1 at a port the kernel picks. */
static int listen_local(int *port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    assert_true(fd >= 0);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(listen(fd, 4), 0);
    socklen_t len = sizeof a;
    assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &len), 0);
    *port = ntohs(a.sin_port);
    return fd;
}

static void fd_tcp_connects_reads_writes_and_says_why(void **state)
{
    (void)state;
    int port, lfd = listen_local(&port);
    char ps[16];
    snprintf(ps, sizeof ps, "%d", port);
    iso_err err;
    iso_err_clear(&err);
    int fd = -1;
    assert_int_equal(iso_fd_tcp_connect("127.0.0.1", ps, 1000, &fd, &err), ISO_OK);
    int peer = accept(lfd, NULL, NULL);
    assert_true(peer >= 0);
    /* What the header promises of the descriptor. */
    assert_true(fcntl(fd, F_GETFL) & O_NONBLOCK);
    assert_true(fcntl(fd, F_GETFD) & FD_CLOEXEC);
    int nodelay = 0;
    socklen_t len = sizeof nodelay;
    assert_int_equal(getsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &nodelay, &len), 0);
    assert_true(nodelay);

    /* Nothing in time: 0, after about the timeout. */
    uint8_t buf[64];
    int64_t t0 = iso_clock_ns();
    assert_int_equal(iso_fd_read(fd, "t", buf, sizeof buf, 30, &err), 0);
    assert_true(iso_clock_ns() - t0 >= 29 * 1000000LL);
    /* A round trip. */
    const uint8_t msg[] = "frame";
    assert_int_equal(iso_fd_write_all(fd, "t", msg, sizeof msg, 100, 1, &err), ISO_OK);
    assert_int_equal(read(peer, buf, sizeof buf), (int)sizeof msg);
    assert_memory_equal(buf, msg, sizeof msg);
    assert_int_equal(write(peer, "ab", 2), 2);
    assert_int_equal(iso_fd_read(fd, "t", buf, sizeof buf, 1000, &err), 2);

    /* The peer goes: end of file is an error that says so. */
    close(peer);
    iso_err_clear(&err);
    int r;
    while ((r = iso_fd_read(fd, "t", buf, sizeof buf, 1000, &err)) > 0)
        ;
    assert_int_equal(r, ISO_EIO);
    assert_non_null(strstr(err.msg, "t: peer closed the link"));
    close(fd);

    iso_err_clear(&err);
    assert_int_equal(iso_fd_tcp_connect("127.0.0.1", ps, 1000, &fd, &err), ISO_OK);
    peer = accept(lfd, NULL, NULL);
    assert_true(peer >= 0);
    /* A peer that never reads: the write gives up at its timeout, saying how
     * far it got, instead of blocking the caller. */
    static uint8_t big[8 << 20];
    iso_err_clear(&err);
    t0 = iso_clock_ns();
    assert_int_equal(iso_fd_write_all(fd, "t", big, sizeof big, 50, 1, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "t: write timed out after 50 ms"));
    assert_true(iso_clock_ns() - t0 < 2000 * 1000000LL);
    close(fd);
    close(peer);

    /* A closed port, and a name that does not resolve, named in the error. */
    close(lfd);
    iso_err_clear(&err);
    assert_int_equal(iso_fd_tcp_connect("127.0.0.1", ps, 1000, &fd, &err), ISO_EIO);
    assert_int_equal(fd, -1);
    char want[64];
    snprintf(want, sizeof want, "127.0.0.1:%s: cannot connect: %s", ps, strerror(ECONNREFUSED));
    assert_string_equal(err.msg, want);
    iso_err_clear(&err);
    assert_int_equal(iso_fd_tcp_connect("no-such-host.invalid", ps, 100, &fd, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "no-such-host.invalid:"));
    assert_non_null(strstr(err.msg, ": cannot resolve: "));
}

/* The bitwise CRC-32, straight from its definition: the reference both
 * table forms must agree with. */
static uint32_t crc32_bitwise(uint32_t crc, const unsigned char *p, size_t n)
{
    uint32_t c = ~crc;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++)
            c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
    }
    return ~c;
}

/* Both forms give the check value, agree with the bitwise CRC on every
 * length up to 300 (every tail of the eight-byte steps, at every
 * alignment), and continue a running CRC across any split. */
static void crc32_forms_agree_with_the_definition(void **state)
{
    (void)state;
    static iso_crc32_table tab;
    iso_crc32_table_init(&tab);
    assert_int_equal(iso_crc32_small(0, "123456789", 9), 0xCBF43926u);
    assert_int_equal(iso_crc32_fast(&tab, 0, "123456789", 9), 0xCBF43926u);
    unsigned char buf[320];
    uint32_t x = 12345u;
    for (size_t i = 0; i < sizeof buf; i++) {
        x = x * 1103515245u + 12345u;
        buf[i] = (unsigned char)(x >> 16);
    }
    for (size_t off = 0; off < 8; off++)
        for (size_t n = 0; n <= 300; n++) {
            uint32_t want = crc32_bitwise(0, buf + off, n);
            assert_int_equal(iso_crc32_small(0, buf + off, n), want);
            assert_int_equal(iso_crc32_fast(&tab, 0, buf + off, n), want);
            size_t cut = (n * 7) / 13;
            assert_int_equal(
                iso_crc32_fast(&tab, iso_crc32_small(0, buf + off, cut), buf + off + cut, n - cut),
                want);
        }
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(clock_sleeps_to_its_deadline),
        cmocka_unit_test(crc32_forms_agree_with_the_definition),
        cmocka_unit_test(file_reads_whole_and_terminated),
        cmocka_unit_test(json_writer_is_valid_and_null_for_non_finite),
        cmocka_unit_test(json_fields_write_members_by_table),
        cmocka_unit_test(names_find_get_and_list),
        cmocka_unit_test(fd_tcp_connects_reads_writes_and_says_why),
    };
    int failed = cmocka_run_group_tests_name("common", t, NULL, NULL);
    free(g.text);
    return failed;
}
