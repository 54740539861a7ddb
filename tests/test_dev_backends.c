/* tests/test_dev_backends.c -- the OS backends against real kernel objects:
 * the POSIX tty backend on a pseudo-terminal (openpty), the TCP client on
 * 127.0.0.1, and the hardware backends up to where hardware is needed, each
 * with the exact status that follows from whether it is compiled in. */
#define _DEFAULT_SOURCE /* openpty */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <arpa/inet.h>
#include <cmocka.h>
#include <netinet/in.h>
#include <poll.h>
#include <pty.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "iso_dev_enum.h"
#include "iso_dev_source.h"
#include "testutil.h"

/* Reads until `want` bytes came or a second passed. */
static size_t read_all(iso_dev_source *s, uint8_t *out, size_t want)
{
    size_t got = 0;
    for (int spin = 0; spin < 1000 && got < want; spin++) {
        struct pollfd p = {iso_dev_source_fd(s), POLLIN, 0};
        poll(&p, 1, 1);
        iso_dev_chunk c;
        iso_err err;
        iso_err_clear(&err);
        int rc = iso_dev_source_read(s, INT64_MAX, &c, &err);
        assert_true(rc >= 0);
        if (rc == 1) {
            assert_true(c.t_ns > 0);
            memcpy(out + got, c.data, c.len);
            got += c.len;
        }
    }
    return got;
}

static void tty_on_a_pty(void **state)
{
    (void)state;
    int master, slave;
    char name[256];
    assert_int_equal(openpty(&master, &slave, name, NULL, NULL), 0);
    iso_dev_source *s;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tty_open(name, 115200, &s, &err), ISO_OK);
    assert_int_equal(s->info.kind, ISO_DEV_KIND_SERIAL);
    assert_int_equal(s->info.baud, 115200);
    assert_true(iso_dev_source_fd(s) >= 0);
    close(slave);
    /* raw mode: 0x00, 0x0a, 0x0d and 0x03 pass untouched */
    uint8_t msg[300];
    for (int i = 0; i < 300; i++)
        msg[i] = (uint8_t)(i * 31);
    msg[0] = 0x03;
    msg[1] = 0x0a;
    msg[2] = 0x0d;
    assert_int_equal(write(master, msg, sizeof msg), (ssize_t)sizeof msg);
    uint8_t got[300];
    assert_int_equal(read_all(s, got, sizeof got), sizeof got);
    assert_memory_equal(got, msg, sizeof msg);
    /* nothing more: 0, not an error */
    iso_dev_chunk c;
    assert_int_equal(iso_dev_source_read(s, INT64_MAX, &c, &err), 0);
    /* the other side goes away: an error with the path */
    close(master);
    int rc = iso_dev_source_read(s, INT64_MAX, &c, &err);
    assert_int_equal(rc, ISO_EIO);
    assert_non_null(strstr(err.msg, name));
    iso_dev_source_close(s);
    /* errors */
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tty_open("/dev/nonexistent-tty", 115200, &s, &err), ISO_EIO);
    assert_string_equal(err.msg, "/dev/nonexistent-tty: cannot open: No such file or directory");
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tty_open("/dev/null", 12345, &s, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "/dev/null: 12345 baud is not a standard rate (9600 ... 921600)");
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tty_open("/dev/null", 9600, &s, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "/dev/null: not a terminal"));
}

static void tcp_client_on_loopback(void **state)
{
    (void)state;
    int ls = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(bind(ls, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(listen(ls, 1), 0);
    socklen_t al = sizeof a;
    getsockname(ls, (struct sockaddr *)&a, &al);
    char hp[64];
    snprintf(hp, sizeof hp, "127.0.0.1:%u", ntohs(a.sin_port));
    iso_dev_source *s;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tcp_open(hp, 1000, &s, &err), ISO_OK);
    int cs = accept(ls, NULL, NULL);
    assert_true(cs >= 0);
    uint8_t msg[1000];
    for (int i = 0; i < 1000; i++)
        msg[i] = (uint8_t)(i ^ 0x5a);
    assert_int_equal(write(cs, msg, sizeof msg), (ssize_t)sizeof msg);
    uint8_t got[1000];
    assert_int_equal(read_all(s, got, sizeof got), sizeof got);
    assert_memory_equal(got, msg, sizeof msg);
    close(cs);
    iso_dev_chunk c;
    int rc = 0;
    for (int spin = 0; spin < 1000 && rc == 0; spin++) {
        rc = iso_dev_source_read(s, INT64_MAX, &c, &err);
        if (rc == 0)
            usleep(1000);
    }
    assert_int_equal(rc, ISO_EIO);
    char expect[128];
    snprintf(expect, sizeof expect, "tcp:%s: the bridge closed the connection", hp);
    assert_string_equal(err.msg, expect);
    iso_dev_source_close(s);
    /* nobody listening any more */
    close(ls);
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tcp_open(hp, 1000, &s, &err), ISO_EIO);
    snprintf(expect, sizeof expect, "%s: cannot connect: Connection refused", hp);
    assert_string_equal(err.msg, expect);
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tcp_open("no-port", 1000, &s, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "'no-port' is not HOST:PORT");
}

/* CMake's list of the backends it linked (devices/CMakeLists.txt, through
 * tests/CMakeLists.txt); the library's own answer must agree with it. */
#ifndef ISO_TEST_DEV_BACKENDS
#error "tests/CMakeLists.txt defines ISO_TEST_DEV_BACKENDS"
#endif

static const char *const optional_backends[] = {"hidapi", "serialport", "gpiod", "libusb", "spnav"};
#define N_OPTIONAL (sizeof optional_backends / sizeof optional_backends[0])

/* 1 if `word` is one of the space-separated words of `list`. */
static int has_word(const char *list, const char *word)
{
    size_t n = strlen(word);
    for (const char *p = strstr(list, word); p; p = strstr(p + 1, word))
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0'))
            return 1;
    return 0;
}

static void backend_list_matches_the_build(void **state)
{
    (void)state;
    char built[256];
    iso_dev_backends(built, sizeof built);
    printf("backends: library '%s', CMake '%s'\n", built, ISO_TEST_DEV_BACKENDS);
    assert_string_equal(built, ISO_TEST_DEV_BACKENDS);
    for (size_t i = 0; i < N_OPTIONAL; i++)
        assert_int_equal(iso_dev_backend_built(optional_backends[i]),
                         has_word(ISO_TEST_DEV_BACKENDS, optional_backends[i]));
    assert_int_equal(iso_dev_backend_built("tty"), 1);
    assert_int_equal(iso_dev_backend_built("bluetooth"), -1);
    char tiny[6];
    assert_string_equal(iso_dev_backends(tiny, sizeof tiny), "fake"); /* truncated, terminated */
}

/* The status an open must give without the hardware: built in, the OS's
 * refusal (ISO_EIO); built out, ISO_ENOTSUP and a sentence that says so. */
static void expect_no_hardware(const char *backend, int rc, const iso_err *err, const char *names)
{
    printf("%s: %s\n", backend, err->msg);
    if (iso_dev_backend_built(backend) == 1) {
        assert_int_equal(rc, ISO_EIO);
        assert_null(strstr(err->msg, "this build has no"));
    } else {
        assert_int_equal(rc, ISO_ENOTSUP);
        assert_non_null(strstr(err->msg, "this build has no"));
    }
    assert_non_null(strstr(err->msg, names));
}

static void hardware_backends_without_hardware(void **state)
{
    (void)state;
    iso_dev_source *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_dev_hid_open("/dev/hidraw-none", &s, &err);
    expect_no_hardware("hidapi", rc, &err, "/dev/hidraw-none");
    assert_null(s);
    /* A scene's vid and pid hold: no device with those ids is no device,
     * never the first 3D mouse instead. */
    iso_err_clear(&err);
    rc = iso_dev_hid_open_id(NULL, 0x1234, 0x5678, &s, &err);
    expect_no_hardware("hidapi", rc, &err,
                       iso_dev_backend_built("hidapi") == 1 ? "no HID device 1234:5678 found"
                                                            : "3D mouse");
    assert_null(s);
    iso_err_clear(&err);
    rc = iso_dev_serialport_open("/dev/ttyNONE9", 115200, &s, &err);
    expect_no_hardware("serialport", rc, &err, "/dev/ttyNONE9");
    assert_null(s);
    iso_dev_gpio_opts g = {"gpiochip-none", 3, 4, -1, 1, 2000};
    iso_err_clear(&err);
    rc = iso_dev_gpiod_open(&g, &s, &err);
    expect_no_hardware("gpiod", rc, &err, "gpiochip-none");
    assert_null(s);
    g.clutch_line = g.estop_line = -1;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_gpiod_open(&g, &s, &err), ISO_EINVAL);
    /* spacenavd: where one runs here, opening it succeeds */
    iso_err_clear(&err);
    rc = iso_dev_spnav_open(&s, &err);
    if (rc == ISO_OK && iso_dev_backend_built("spnav") == 1)
        iso_dev_source_close(s);
    else
        expect_no_hardware("spnav", rc, &err, "spacenavd");
    /* libusb's hotplug watch: built in, it works, cannot reach the bus
     * (EIO), or this libusb has no hotplug (ENOTSUP, saying so) */
    iso_dev_usb_watch *w = NULL;
    iso_err_clear(&err);
    rc = iso_dev_usb_watch_create(&w, &err);
    printf("libusb watch: %d %s\n", rc, err.msg);
    if (iso_dev_backend_built("libusb") == 1) {
        assert_true(rc == ISO_OK || rc == ISO_EIO || rc == ISO_ENOTSUP);
        assert_null(strstr(err.msg, "this build has no"));
        if (rc == ISO_ENOTSUP)
            assert_non_null(strstr(err.msg, "no hotplug support"));
    } else {
        assert_int_equal(rc, ISO_ENOTSUP);
        assert_non_null(strstr(err.msg, "this build has no libusb backend"));
    }
    if (rc == ISO_OK) {
        assert_int_equal(iso_dev_usb_watch_poll(w), 0);
        iso_dev_usb_watch_destroy(w);
    }
    /* discovery never fails, and says why for what it cannot use */
    iso_dev_found f[32];
    size_t n = iso_dev_enumerate(f, 32);
    for (size_t i = 0; i < n; i++)
        assert_true(f[i].usable || f[i].why[0]);
    assert_true(iso_dev_is_3dmouse(0x256f, 0xc652));
    assert_true(iso_dev_is_3dmouse(0x046d, 0xc626));
    assert_false(iso_dev_is_3dmouse(0x046d, 0xc077)); /* a Logitech mouse */
    char rule[256];
    iso_dev_udev_rule(0x256f, rule, sizeof rule);
    assert_string_equal(rule, "KERNEL==\"hidraw*\", ATTRS{idVendor}==\"256f\", MODE=\"0660\", "
                              "TAG+=\"uaccess\"");
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(tty_on_a_pty),
        cmocka_unit_test(tcp_client_on_loopback),
        cmocka_unit_test(backend_list_matches_the_build),
        cmocka_unit_test(hardware_backends_without_hardware),
    };
    return cmocka_run_group_tests_name("dev_backends", t, NULL, NULL);
}
