/* tests/test_fb_link.c -- the firmware-bridge transports through the
 * iso_link interface: the POSIX tty backend on a pty, the TCP client
 * against a local listener (including loss and reopen), the USB bulk
 * transfer code against a scripted fake of libusb_bulk_transfer (partial
 * transfers, timeouts, stalls, zero-length packets, unplug) and then the
 * whole host endpoint over it, and libserialport's enumeration and errors.
 * Real USB and serial hardware are not needed; where libserialport is not
 * built in, or cannot open a pty, the test concerned skips and says why. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <pty.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include "iso_fb_host.h"
#include "iso_fb_mcu.h"
#include "iso_link.h"
#include "testutil.h"

static int read_exact(iso_link *l, uint8_t *buf, size_t n)
{
    size_t got = 0;
    for (int tries = 0; got < n && tries < 200; tries++) {
        iso_err err;
        iso_err_clear(&err);
        int r = iso_link_read(l, buf + got, n - got, 20, &err);
        if (r < 0)
            return r;
        got += (size_t)r;
    }
    return (int)got;
}

static size_t fd_read_exact(int fd, uint8_t *buf, size_t n)
{
    size_t got = 0;
    for (int tries = 0; got < n && tries < 200; tries++) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 20) > 0) {
            ssize_t r = read(fd, buf + got, n - got);
            if (r > 0)
                got += (size_t)r;
        }
    }
    return got;
}

/* ---- POSIX tty on a pty -------------------------------------------------- */
static void tty_pty_round_trip_and_loss(void **state)
{
    (void)state;
    int master, slave;
    char name[128];
    assert_int_equal(openpty(&master, &slave, name, NULL, NULL), 0);
    iso_link *l = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_link_tty_open(name, 115200, &l, &err), ISO_OK);
    close(slave); /* the link holds its own */
    assert_int_equal(iso_link_poll_fd(l) >= 0, 1);
    /* raw: every byte value passes, no echo, no line discipline */
    uint8_t out[256], in[256];
    for (int i = 0; i < 256; i++)
        out[i] = (uint8_t)i;
    assert_int_equal(write(master, out, sizeof out), 256);
    assert_int_equal(read_exact(l, in, sizeof in), 256);
    assert_memory_equal(in, out, sizeof out);
    assert_int_equal(iso_link_write(l, out, sizeof out, 500, &err), ISO_OK);
    assert_int_equal(fd_read_exact(master, in, sizeof in), 256);
    assert_memory_equal(in, out, sizeof out);
    assert_int_equal(iso_link_read(l, in, sizeof in, 0, &err), 0); /* nothing: no echo back */
    /* the other end goes away */
    close(master);
    int r = 0;
    for (int i = 0; i < 50 && r >= 0; i++)
        r = iso_link_read(l, in, sizeof in, 10, &err);
    assert_int_equal(r, ISO_EIO);
    assert_non_null(strstr(err.msg, name));
    iso_err_clear(&err);
    assert_int_equal(iso_link_reopen(l, &err), ISO_EIO); /* the pty is gone */
    assert_non_null(strstr(err.msg, "open"));
    iso_link_close(l);

    iso_err_clear(&err);
    assert_int_equal(iso_link_tty_open("/nonexistent/ttyFB0", 115200, &l, &err), ISO_EIO);
    assert_null(l);
    assert_non_null(strstr(err.msg, "/nonexistent/ttyFB0"));
    iso_err_clear(&err);
    assert_int_equal(iso_link_tty_open("/dev/null", 12345, &l, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "12345"));
    iso_err_clear(&err);
    assert_int_equal(iso_link_tty_open("/dev/null", 115200, &l, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "not a terminal"));
    iso_link_close(NULL);
}

/* ---- TCP ------------------------------------------------------------------ */
static int listen_local(int *port)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(listen(fd, 2), 0);
    assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &len), 0);
    *port = ntohs(a.sin_port);
    return fd;
}

static void tcp_round_trip_loss_and_reopen(void **state)
{
    (void)state;
    int port;
    int lfd = listen_local(&port);
    iso_link *l = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_link_tcp_open("127.0.0.1", port, 1000, &l, &err), ISO_OK);
    int s = accept(lfd, NULL, NULL);
    assert_true(s >= 0);
    const uint8_t msg[] = {0, 1, 2, 0xFF, 0};
    uint8_t in[16];
    assert_int_equal(send(s, msg, sizeof msg, 0), (ssize_t)sizeof msg);
    assert_int_equal(read_exact(l, in, sizeof msg), (int)sizeof msg);
    assert_memory_equal(in, msg, sizeof msg);
    assert_int_equal(iso_link_write(l, msg, sizeof msg, 500, &err), ISO_OK);
    assert_int_equal(fd_read_exact(s, in, sizeof msg), sizeof msg);
    close(s); /* the server drops us */
    int r = 0;
    for (int i = 0; i < 50 && r >= 0; i++)
        r = iso_link_read(l, in, sizeof in, 10, &err);
    assert_int_equal(r, ISO_EIO);
    assert_non_null(strstr(err.msg, "peer closed"));
    iso_err_clear(&err);
    assert_int_equal(iso_link_reopen(l, &err), ISO_OK);
    s = accept(lfd, NULL, NULL);
    assert_int_equal(send(s, msg, 3, 0), 3);
    assert_int_equal(read_exact(l, in, 3), 3);
    close(s);
    iso_link_close(l);
    close(lfd); /* now nobody listens on port */
    iso_err_clear(&err);
    assert_int_equal(iso_link_tcp_open("127.0.0.1", port, 1000, &l, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "connect"));
    iso_err_clear(&err);
    assert_int_equal(iso_link_tcp_open("127.0.0.1", 0, 1000, &l, &err), ISO_EINVAL);
}

/* ---- USB bulk through a scripted fake ------------------------------------ */
#define EP_IN 0x81
#define EP_OUT 0x02
typedef struct fake_usb {
    /* IN: scripted results, one per call; then the bytes to deliver */
    int in_rc[16];
    int in_n[16]; /* bytes per call (taken from in_data) */
    int in_calls, in_script;
    uint8_t in_data[256];
    size_t in_pos;
    /* OUT: accepts at most out_chunk per call, answering out_rc */
    int out_chunk, out_rc, out_calls, zlps, stall_once;
    uint8_t out_data[1024];
    size_t out_len;
    int bad_in_length, clear_halts, closed;
    iso_fb_mcu *mcu; /* when set: OUT feeds this MCU, IN drains its output */
    uint8_t mcu_out[1 << 14];
    size_t mcu_len;
} fake_usb;

static int fake_bulk(void *ctx, uint8_t ep, uint8_t *data, int length, int *transferred,
                     unsigned timeout_ms)
{
    fake_usb *f = ctx;
    (void)timeout_ms;
    *transferred = 0;
    if (ep == EP_IN) {
        if (length % 64 != 0)
            f->bad_in_length++; /* must ask for whole packets */
        if (f->mcu) {
            int n = (int)f->mcu_len < length ? (int)f->mcu_len : length;
            memcpy(data, f->mcu_out, (size_t)n);
            memmove(f->mcu_out, f->mcu_out + n, f->mcu_len - (size_t)n);
            f->mcu_len -= (size_t)n;
            *transferred = n;
            return n ? ISO_LINK_USB_OK : ISO_LINK_USB_TIMEOUT;
        }
        if (f->in_calls >= f->in_script)
            return ISO_LINK_USB_TIMEOUT;
        int k = f->in_calls++;
        int n = f->in_n[k] < length ? f->in_n[k] : length;
        memcpy(data, f->in_data + f->in_pos, (size_t)n);
        f->in_pos += (size_t)n;
        *transferred = n;
        return f->in_rc[k];
    }
    assert_int_equal(ep, EP_OUT);
    f->out_calls++;
    if (length == 0) {
        f->zlps++;
        return ISO_LINK_USB_OK;
    }
    if (f->stall_once) {
        f->stall_once = 0;
        return ISO_LINK_USB_PIPE;
    }
    if (f->mcu) {
        iso_fb_mcu_rx(f->mcu, data, (size_t)length);
        *transferred = length;
        return ISO_LINK_USB_OK;
    }
    if (f->out_rc != ISO_LINK_USB_OK && f->out_rc != ISO_LINK_USB_TIMEOUT)
        return f->out_rc;
    int n = length < f->out_chunk ? length : f->out_chunk;
    memcpy(f->out_data + f->out_len, data, (size_t)n);
    f->out_len += (size_t)n;
    *transferred = n;
    return n == length ? ISO_LINK_USB_OK : f->out_rc;
}

static int fake_clear_halt(void *ctx, uint8_t ep)
{
    (void)ep;
    ((fake_usb *)ctx)->clear_halts++;
    return 0;
}

static void fake_close(void *ctx)
{
    ((fake_usb *)ctx)->closed++;
}

static iso_link *usb_over(fake_usb *f)
{
    iso_link_usb_io io = {fake_bulk, fake_clear_halt, NULL, fake_close, f};
    iso_link *l = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_link_usb_open_io(&io, EP_IN, EP_OUT, 64, &l, &err), ISO_OK);
    return l;
}

static void usb_bulk_reads(void **state)
{
    (void)state;
    static fake_usb f;
    memset(&f, 0, sizeof f);
    for (int i = 0; i < 256; i++)
        f.in_data[i] = (uint8_t)i;
    /* 10 bytes ok; a timeout that still moved 5; a stall; 100 bytes */
    f.in_rc[0] = ISO_LINK_USB_OK;
    f.in_n[0] = 10;
    f.in_rc[1] = ISO_LINK_USB_TIMEOUT;
    f.in_n[1] = 5;
    f.in_rc[2] = ISO_LINK_USB_PIPE;
    f.in_n[2] = 0;
    f.in_rc[3] = ISO_LINK_USB_OK;
    f.in_n[3] = 100;
    f.in_rc[4] = ISO_LINK_USB_NO_DEVICE;
    f.in_n[4] = 0;
    f.in_script = 5;
    iso_link *l = usb_over(&f);
    assert_int_equal(iso_link_poll_fd(l), -1);
    uint8_t buf[64], all[115];
    size_t got = 0;
    iso_err err;
    iso_err_clear(&err);
    for (int i = 0; i < 20 && got < sizeof all; i++) {
        /* small reads: the rest of a transfer is kept for the next call */
        int r = iso_link_read(l, buf, 7, 5, &err);
        assert_true(r >= 0);
        memcpy(all + got, buf, (size_t)r);
        got += (size_t)r;
    }
    assert_int_equal(got, sizeof all);
    for (size_t i = 0; i < sizeof all; i++)
        assert_int_equal(all[i], i);
    assert_int_equal(f.clear_halts, 1);
    assert_int_equal(f.bad_in_length, 0);
    assert_int_equal(iso_link_read(l, buf, sizeof buf, 5, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "device gone"));
    iso_err_clear(&err);
    assert_int_equal(iso_link_reopen(l, &err), ISO_ENOTSUP);
    iso_link_close(l);
    assert_int_equal(f.closed, 1);
}

static void usb_bulk_writes(void **state)
{
    (void)state;
    static fake_usb f;
    memset(&f, 0, sizeof f);
    f.out_chunk = 10; /* the device takes 10 bytes per transfer, then times out */
    f.out_rc = ISO_LINK_USB_TIMEOUT;
    iso_link *l = usb_over(&f);
    uint8_t msg[128];
    for (int i = 0; i < 128; i++)
        msg[i] = (uint8_t)(i * 3);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_link_write(l, msg, 100, 1000, &err), ISO_OK);
    assert_int_equal(f.out_len, 100);
    assert_memory_equal(f.out_data, msg, 100);
    assert_int_equal(f.zlps, 0);
    /* a multiple of the packet size ends with a zero-length packet */
    f.out_chunk = 1000;
    f.out_rc = ISO_LINK_USB_OK;
    assert_int_equal(iso_link_write(l, msg, 128, 1000, &err), ISO_OK);
    assert_int_equal(f.zlps, 1);
    /* a stall is cleared once and the transfer retried */
    f.stall_once = 1;
    assert_int_equal(iso_link_write(l, msg, 5, 1000, &err), ISO_OK);
    assert_int_equal(f.clear_halts, 1);
    assert_int_equal(f.out_len, 100 + 128 + 5);
    /* a device that takes nothing: a timeout error naming the byte count */
    f.out_chunk = 0;
    f.out_rc = ISO_LINK_USB_TIMEOUT;
    assert_int_equal(iso_link_write(l, msg, 5, 30, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "timed out"));
    assert_non_null(strstr(err.msg, "0 of 5"));
    iso_err_clear(&err);
    f.out_rc = ISO_LINK_USB_NO_DEVICE;
    assert_int_equal(iso_link_write(l, msg, 5, 30, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "device gone"));
    iso_link_close(l);
    assert_int_equal(f.closed, 1);

    /* bad arguments: refused, and the io is closed (the link owned it) */
    iso_link_usb_io io = {fake_bulk, NULL, NULL, fake_close, &f};
    iso_err_clear(&err);
    assert_int_equal(iso_link_usb_open_io(&io, 0x01, EP_OUT, 64, &l, &err), ISO_EINVAL);
    assert_null(l);
    assert_int_equal(f.closed, 2);
}

static void mcu_out(void *ctx, const uint8_t *b, size_t n)
{
    fake_usb *f = ctx;
    assert_true(f->mcu_len + n <= sizeof f->mcu_out);
    memcpy(f->mcu_out + f->mcu_len, b, n);
    f->mcu_len += n;
}

static void host_endpoint_over_usb_transport(void **state)
{
    (void)state;
    static fake_usb f;
    static iso_fb_mcu mcu;
    memset(&f, 0, sizeof f);
    iso_fb_mcu_config cfg;
    iso_fb_mcu_config_default(&cfg, 2);
    assert_int_equal(iso_fb_mcu_init(&mcu, &cfg, mcu_out, &f, 0), 0);
    f.mcu = &mcu;
    iso_link *l = usb_over(&f);
    iso_fb_host h;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_fb_host_init(&h, l, NULL, NULL, &err), ISO_OK);
    uint32_t t = 0;
    for (uint32_t tick = 0; tick < 50; tick++) {
        const int16_t v[2] = {(int16_t)tick, (int16_t)-tick};
        iso_fb_host_step(&h, tick, v, 2);
        for (int k = 0; k < 10; k++)
            iso_fb_mcu_tick(&mcu, ++t);
    }
    iso_fb_host_poll(&h, 0);
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    assert_true(h.stats.acks >= 45);
    assert_int_equal(h.stats.rx.resyncs, 0);
    assert_int_equal(f.bad_in_length, 0);
    iso_fb_host_deinit(&h);
    iso_link_close(l);
}

/* CMake says whether it linked libusb and libserialport into the library
 * (tests/CMakeLists.txt); each test below asserts the status that follows
 * from that, so a transport compiled in and failing cannot pass as one
 * compiled out. */
#ifndef ISO_HAVE_LIBUSB
#error "tests/CMakeLists.txt defines ISO_HAVE_LIBUSB (0 or 1)"
#endif
#ifndef ISO_HAVE_SERIALPORT
#error "tests/CMakeLists.txt defines ISO_HAVE_SERIALPORT (0 or 1)"
#endif

static void usb_open_without_device(void **state)
{
    (void)state;
    iso_link *l = (iso_link *)1;
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_link_usb_open(0xdead, 0xbeef, &l, &err);
    printf("usb open without hardware: %s\n", err.msg);
    assert_int_equal(rc, ISO_HAVE_LIBUSB ? ISO_EIO : ISO_ENOTSUP);
    assert_null(l);
    assert_non_null(strstr(err.msg, "dead:beef"));
}

/* ---- libserialport ------------------------------------------------------ */
/* Compiled out, both entry points say so; then the test skips, since
 * nothing of libserialport's was exercised. */
static void serialport_compiled_out(void)
{
    iso_link_sp_port ports[1];
    iso_link *l = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_link_sp_list(ports, 1, &err), ISO_ENOTSUP);
    assert_non_null(strstr(err.msg, "built without libserialport"));
    iso_err_clear(&err);
    assert_int_equal(iso_link_sp_open("/dev/ttyFBnonexistent", 115200, &l, &err), ISO_ENOTSUP);
    assert_null(l);
    assert_non_null(strstr(err.msg, "/dev/ttyFBnonexistent"));
    print_message("skipped: libserialport is not built in (%s)\n", err.msg);
    skip();
}

static void serialport_list_and_errors(void **state)
{
    (void)state;
    if (!ISO_HAVE_SERIALPORT)
        serialport_compiled_out();
    iso_link_sp_port ports[16];
    iso_err err;
    iso_err_clear(&err);
    int n = iso_link_sp_list(ports, 16, &err);
    if (n < 0)
        fail_msg("libserialport is built in, yet listing failed (%d): %s", n, err.msg);
    printf("libserialport sees %d port(s)\n", n);
    for (int i = 0; i < n && i < 16; i++)
        printf("  %s  %s  vid %04x pid %04x\n", ports[i].name, ports[i].description,
               ports[i].usb_vid < 0 ? 0 : ports[i].usb_vid,
               ports[i].usb_pid < 0 ? 0 : ports[i].usb_pid);
    iso_link *l = NULL;
    iso_err_clear(&err);
    assert_int_equal(iso_link_sp_open("/dev/ttyFBnonexistent", 115200, &l, &err), ISO_EIO);
    assert_null(l);
    assert_non_null(strstr(err.msg, "/dev/ttyFBnonexistent"));
}

/* A pty through libserialport, where it accepts one (it may not: it looks
 * ports up in sysfs, where a pty has no entry, and asks for modem lines a
 * pty does not have); otherwise it skips and says why. */
static void serialport_on_a_pty(void **state)
{
    (void)state;
    if (!ISO_HAVE_SERIALPORT) {
        print_message("skipped: libserialport is not built in\n");
        skip();
    }
    int master, slave;
    char name[128];
    assert_int_equal(openpty(&master, &slave, name, NULL, NULL), 0);
    iso_link *l = NULL;
    iso_err err;
    iso_err_clear(&err);
    if (iso_link_sp_open(name, 115200, &l, &err) != ISO_OK) {
        close(master);
        close(slave);
        print_message("skipped: libserialport cannot drive a pty here (%s); real adapters only\n",
                      err.msg);
        skip();
    }
    uint8_t in[4];
    assert_true(iso_link_poll_fd(l) >= 0);
    assert_int_equal(write(master, "abcd", 4), 4);
    assert_int_equal(read_exact(l, in, 4), 4);
    assert_memory_equal(in, "abcd", 4);
    assert_int_equal(iso_link_write(l, (const uint8_t *)"wxyz", 4, 500, &err), ISO_OK);
    assert_int_equal(fd_read_exact(master, in, 4), 4);
    assert_memory_equal(in, "wxyz", 4);
    iso_link_close(l);
    close(master);
    close(slave);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(tty_pty_round_trip_and_loss),
        cmocka_unit_test(tcp_round_trip_loss_and_reopen),
        cmocka_unit_test(usb_bulk_reads),
        cmocka_unit_test(usb_bulk_writes),
        cmocka_unit_test(host_endpoint_over_usb_transport),
        cmocka_unit_test(usb_open_without_device),
        cmocka_unit_test(serialport_list_and_errors),
        cmocka_unit_test(serialport_on_a_pty),
    };
    return cmocka_run_group_tests_name("fb_link", t, NULL, NULL);
}
