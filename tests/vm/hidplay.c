/* tests/vm/hidplay.c -- a scripted SpaceMouse for the VM tests: the guest
 * side of the kernel's HID stack, through /dev/uhid (a HID device made by a
 * program, bound by hid-generic) or through a USB gadget's /dev/hidgN (a
 * real USB device on dummy_hcd, bound by usbhid and hid-logitech as on
 * hardware).
 *
 *   hidplay desc rel|fixup|abs           the report descriptor, to stdout
 *   hidplay now                          CLOCK_MONOTONIC in ns, to stdout
 *   hidplay stamp LOG STAMPED            stdin to LOG, and to STAMPED each
 *                                        line behind the time it arrived
 *                                        (CLOCK_MONOTONIC ns)
 *   hidplay uhid VID PID rel|fixup|abs LOG
 *   hidplay hidg /dev/hidgN LOG
 *
 * The descriptors are a SpaceNavigator's: report 1 X/Y/Z and report 2
 * Rx/Ry/Rz as 16-bit values in [-350, 350], report 3 two buttons, report 4
 * an LED, vendor feature reports. `rel` has the unit items and relative
 * Input items (the later SpaceNavigators: hid-logitech's rel->abs fixup
 * misses them, evdev axes stay relative); `fixup` lacks the unit items, so
 * its Input items sit at bytes 32 and 49, where hid-logitech turns them
 * absolute for 046d:c626; `abs` declares absolute axes itself (newer
 * devices). The raw reports are the same bytes in all three.
 *
 * Commands come one a line on stdin; each is answered "ok" (or "error:
 * why") on stdout once done, so a shell can drive it through two fifos:
 *   play FILE      the steps of FILE (sequence format below)
 *   axes TX TY TZ RX RY RZ MS / buttons MASK MS    one step
 *   destroy / create                               uhid: unplug, plug in
 *   mark TEXT      logs TEXT with the time (for bounds measured on the host)
 *   repeat MS      a deflection is sent again every MS ms (40 unless set)
 *   quit
 * A sequence file has one step a line: `axes tx ty tz rx ry rz hold_ms` or
 * `buttons mask hold_ms`; # starts a comment. A step with a deflection is
 * sent again every 40 ms (`repeat`) while it is held, as a device does (a
 * real one every 8 ms or so; slower here, so that hidraw's 63 reports
 * outlast an emulated tick); a rest or a
 * button change once. Every report sent is logged to LOG with its
 * CLOCK_MONOTONIC time. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <linux/uhid.h>
#include <poll.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* Logical [-350, 350], physical [-1400, 1400], then the unit items
 * (exponent -4, centimetres) that only some devices have. */
static const uint8_t axes_range[] = {0x16, 0xa2, 0xfe, 0x26, 0x5e, 0x01,
                                     0x36, 0x88, 0xfa, 0x46, 0x78, 0x05};
static const uint8_t axes_units[] = {0x55, 0x0c, 0x65, 0x11};

static struct {
    int fd;      /* /dev/uhid or /dev/hidgN */
    int uhid;    /* 1: fd is /dev/uhid */
    int created; /* uhid: the device exists */
    uint16_t vid, pid;
    uint8_t desc[512];
    size_t desc_len;
    FILE *log;
    long sent, dropped;
    int16_t axes[6];
    uint16_t buttons;
    int repeat_ms; /* a deflection is sent again this often (40) */
} g;

static int64_t now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static void put(const void *p, size_t n)
{
    memcpy(g.desc + g.desc_len, p, n);
    g.desc_len += n;
}

/* One Physical collection of three 16-bit axes (usages u0..u0+2) under
 * report id; the first one sets the ranges (global items: they hold for
 * the second too). */
static void axes_collection(uint8_t id, uint8_t u0, int first, int units, int absolute)
{
    const uint8_t head[] = {0xa1, 0x00, 0x85, id};
    put(head, sizeof head);
    if (first)
        put(axes_range, sizeof axes_range);
    if (first && units)
        put(axes_units, sizeof axes_units);
    const uint8_t tail[] = {
        0x09, u0,   0x09, (uint8_t)(u0 + 1),      0x09, (uint8_t)(u0 + 2), 0x75, 0x10,
        0x95, 0x03, 0x81, absolute ? 0x02 : 0x06, 0xc0};
    put(tail, sizeof tail);
}

static int build_desc(const char *layout)
{
    int units = strcmp(layout, "fixup") != 0, absolute = strcmp(layout, "abs") == 0;
    if (strcmp(layout, "rel") && strcmp(layout, "fixup") && strcmp(layout, "abs"))
        return -1;
    g.desc_len = 0;
    const uint8_t app[] = {0x05, 0x01, 0x09, 0x08, 0xa1, 0x01};
    put(app, sizeof app);
    axes_collection(1, 0x30, 1, units, absolute);
    axes_collection(2, 0x33, 0, units, absolute);
    const uint8_t rest[] = {
        /* report 3: two buttons and 14 bits of padding */
        0xa1, 0x02, 0x85, 0x03, 0x05, 0x09, 0x19, 0x01, 0x29, 0x02, 0x15, 0x00, 0x25, 0x01, 0x75,
        0x01, 0x95, 0x02, 0x81, 0x02, 0x95, 0x0e, 0x81, 0x03, 0xc0,
        /* report 4: the LED, an output */
        0xa1, 0x02, 0x85, 0x04, 0x05, 0x08, 0x09, 0x4b, 0x15, 0x00, 0x25, 0x01, 0x95, 0x01, 0x75,
        0x01, 0x91, 0x02, 0x95, 0x01, 0x75, 0x07, 0x91, 0x03, 0xc0,
        /* vendor feature reports 5 and 6 */
        0x06, 0x00, 0xff, 0x09, 0x01, 0xa1, 0x02, 0x15, 0x80, 0x25, 0x7f, 0x75, 0x08, 0x09, 0x3a,
        0xa1, 0x02, 0x85, 0x05, 0x09, 0x20, 0x95, 0x01, 0xb1, 0x02, 0xc0, 0xa1, 0x02, 0x85, 0x06,
        0x09, 0x21, 0x95, 0x01, 0xb1, 0x02, 0xc0, 0xc0,
        /* end of the application collection */
        0xc0};
    put(rest, sizeof rest);
    return 0;
}

/* ---- uhid ---------------------------------------------------------------- */

static int uhid_write(const struct uhid_event *ev)
{
    ssize_t n = write(g.fd, ev, sizeof *ev);
    return n == (ssize_t)sizeof *ev ? 0 : -1;
}

static int uhid_create(void)
{
    struct uhid_event ev;
    memset(&ev, 0, sizeof ev);
    ev.type = UHID_CREATE2;
    snprintf((char *)ev.u.create2.name, sizeof ev.u.create2.name, "3Dconnexion SpaceMouse (uhid)");
    snprintf((char *)ev.u.create2.phys, sizeof ev.u.create2.phys, "isoshape-vm/uhid");
    memcpy(ev.u.create2.rd_data, g.desc, g.desc_len);
    ev.u.create2.rd_size = (uint16_t)g.desc_len;
    ev.u.create2.bus = 0x03; /* BUS_USB */
    ev.u.create2.vendor = g.vid;
    ev.u.create2.product = g.pid;
    ev.u.create2.version = 0x0110;
    if (uhid_write(&ev) != 0)
        return -1;
    g.created = 1;
    fprintf(g.log, "%lld create %04x:%04x\n", (long long)now_ns(), g.vid, g.pid);
    return 0;
}

static int uhid_destroy(void)
{
    struct uhid_event ev;
    memset(&ev, 0, sizeof ev);
    ev.type = UHID_DESTROY;
    g.created = 0;
    fprintf(g.log, "%lld destroy\n", (long long)now_ns());
    return uhid_write(&ev);
}

/* Answers what the kernel asks of the device: feature reads get an error
 * (nothing here needs them), the rest needs no answer. */
static void uhid_service(void)
{
    struct uhid_event ev;
    while (read(g.fd, &ev, sizeof ev) > 0) {
        if (ev.type == UHID_GET_REPORT) {
            struct uhid_event r;
            memset(&r, 0, sizeof r);
            r.type = UHID_GET_REPORT_REPLY;
            r.u.get_report_reply.id = ev.u.get_report.id;
            r.u.get_report_reply.err = EIO;
            uhid_write(&r);
        } else if (ev.type == UHID_SET_REPORT) {
            struct uhid_event r;
            memset(&r, 0, sizeof r);
            r.type = UHID_SET_REPORT_REPLY;
            r.u.set_report_reply.id = ev.u.set_report.id;
            uhid_write(&r);
        } else if (ev.type == UHID_OPEN || ev.type == UHID_CLOSE || ev.type == UHID_START) {
            fprintf(g.log, "%lld event %s\n", (long long)now_ns(),
                    ev.type == UHID_OPEN    ? "open"
                    : ev.type == UHID_CLOSE ? "close"
                                            : "start");
        }
    }
}

/* Sleeps until the deadline, serving the device meanwhile. */
static void wait_until(int64_t deadline)
{
    for (;;) {
        int64_t left = deadline - now_ns();
        if (left <= 0)
            return;
        struct pollfd p = {g.fd, POLLIN, 0};
        if (g.uhid && poll(&p, 1, (int)((left + 999999) / 1000000)) > 0)
            uhid_service();
        else if (!g.uhid) {
            struct timespec ts = {left / 1000000000, left % 1000000000};
            nanosleep(&ts, NULL);
        }
    }
}

/* ---- reports --------------------------------------------------------------- */

static void send_report(const uint8_t *r, size_t n)
{
    int ok;
    if (g.uhid) {
        struct uhid_event ev;
        memset(&ev, 0, sizeof ev);
        ev.type = UHID_INPUT2;
        ev.u.input2.size = (uint16_t)n;
        memcpy(ev.u.input2.data, r, n);
        ok = g.created && uhid_write(&ev) == 0;
    } else {
        /* The host takes a report when it polls (a device's queue waits
         * for it, however slow the host: TCG can take tenths of a second);
         * an unplugged gadget does not, and the report is dropped, as a
         * device's would be. */
        struct pollfd p = {g.fd, POLLOUT, 0};
        ok = poll(&p, 1, 1000) == 1 && write(g.fd, r, n) == (ssize_t)n;
    }
    if (ok)
        g.sent++;
    else
        g.dropped++;
    fprintf(g.log, "%lld report %u%s\n", (long long)now_ns(), r[0], ok ? "" : " dropped");
}

static void put16(uint8_t *p, int16_t v)
{
    p[0] = (uint8_t)((uint16_t)v & 0xff);
    p[1] = (uint8_t)((uint16_t)v >> 8);
}

static void send_state(int axes, int buttons)
{
    uint8_t r[7];
    if (axes) {
        for (int k = 0; k < 2; k++) {
            r[0] = (uint8_t)(1 + k);
            for (int i = 0; i < 3; i++)
                put16(r + 1 + 2 * i, g.axes[3 * k + i]);
            send_report(r, 7);
        }
    }
    if (buttons) {
        r[0] = 3;
        put16(r + 1, (int16_t)g.buttons);
        send_report(r, 3);
    }
}

/* One step: `axes tx ty tz rx ry rz ms` or `buttons mask ms`. */
static int step(const char *line)
{
    int v[6];
    unsigned mask;
    int ms;
    int deflected = 0;
    if (sscanf(line, "axes %d %d %d %d %d %d %d", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &ms) ==
        7) {
        for (int i = 0; i < 6; i++) {
            g.axes[i] = (int16_t)v[i];
            deflected |= v[i] != 0;
        }
        fprintf(g.log, "%lld step axes %d %d %d %d %d %d\n", (long long)now_ns(), v[0], v[1], v[2],
                v[3], v[4], v[5]);
        int64_t end = now_ns() + (int64_t)ms * 1000000;
        do {
            send_state(1, 0);
            int64_t next = now_ns() + g.repeat_ms * 1000000LL;
            wait_until(deflected && next < end ? next : end);
        } while (deflected && now_ns() < end);
        return 0;
    }
    if (sscanf(line, "buttons %x %d", &mask, &ms) == 2) {
        g.buttons = (uint16_t)mask;
        fprintf(g.log, "%lld step buttons %x\n", (long long)now_ns(), mask);
        send_state(0, 1);
        wait_until(now_ns() + (int64_t)ms * 1000000);
        return 0;
    }
    return -1;
}

static int play(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    char line[256];
    int rc = 0;
    while (rc == 0 && fgets(line, sizeof line, f)) {
        char *s = line + strspn(line, " \t");
        if (*s == '#' || *s == '\n' || *s == '\0')
            continue;
        rc = step(s);
    }
    fclose(f);
    return rc;
}

static int command(char *line)
{
    line[strcspn(line, "\n")] = '\0';
    if (strncmp(line, "play ", 5) == 0)
        return play(line + 5);
    if (strncmp(line, "axes ", 5) == 0 || strncmp(line, "buttons ", 8) == 0)
        return step(line);
    if (strncmp(line, "repeat ", 7) == 0) {
        g.repeat_ms = atoi(line + 7);
        return g.repeat_ms > 0 ? 0 : -1;
    }
    if (strncmp(line, "mark ", 5) == 0) {
        fprintf(g.log, "%lld mark %s\n", (long long)now_ns(), line + 5);
        return 0;
    }
    if (strcmp(line, "destroy") == 0)
        return g.uhid ? uhid_destroy() : -1;
    if (strcmp(line, "create") == 0)
        return g.uhid ? uhid_create() : -1;
    return -1;
}

/* The next command from stdin, serving the device while none comes (a
 * uhid device that does not answer a feature read stalls its reader). */
static int next_line(char *line, size_t cap)
{
    static char buf[4096];
    static size_t have;
    for (;;) {
        char *nl = memchr(buf, '\n', have);
        if (nl) {
            size_t n = (size_t)(nl - buf) + 1;
            size_t k = n < cap ? n : cap - 1;
            memcpy(line, buf, k);
            line[k] = '\0';
            memmove(buf, buf + n, have - n);
            have -= n;
            return 1;
        }
        struct pollfd p[2] = {{0, POLLIN, 0}, {g.fd, POLLIN, 0}};
        if (poll(p, g.uhid ? 2 : 1, -1) < 0 && errno != EINTR)
            return 0;
        if (p[1].revents & POLLIN)
            uhid_service();
        if (p[0].revents & (POLLIN | POLLHUP)) {
            ssize_t r = read(0, buf + have, sizeof buf - have);
            if (r <= 0)
                return 0;
            have += (size_t)r;
            if (have == sizeof buf)
                have = 0; /* a line longer than the buffer: dropped */
        }
    }
}

static int usage(void)
{
    fprintf(stderr, "usage: hidplay desc rel|fixup|abs\n"
                    "       hidplay now\n"
                    "       hidplay stamp LOG STAMPED\n"
                    "       hidplay uhid VID PID rel|fixup|abs LOG\n"
                    "       hidplay hidg /dev/hidgN LOG\n");
    return 2;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "now") == 0) {
        printf("%lld\n", (long long)now_ns());
        return 0;
    }
    if (argc == 4 && strcmp(argv[1], "stamp") == 0) {
        FILE *f = fopen(argv[2], "w"), *t = fopen(argv[3], "w");
        if (!f || !t)
            return 1;
        setvbuf(f, NULL, _IOLBF, 0);
        setvbuf(t, NULL, _IOLBF, 0);
        char line[1024];
        while (fgets(line, sizeof line, stdin)) {
            fprintf(t, "%lld %s", (long long)now_ns(), line);
            fputs(line, f);
        }
        return fclose(f) == 0 && fclose(t) == 0 ? 0 : 1;
    }
    if (argc == 3 && strcmp(argv[1], "desc") == 0) {
        if (build_desc(argv[2]) != 0)
            return usage();
        return fwrite(g.desc, 1, g.desc_len, stdout) == g.desc_len ? 0 : 1;
    }
    const char *log;
    g.repeat_ms = 40;
    if (argc == 6 && strcmp(argv[1], "uhid") == 0) {
        g.uhid = 1;
        g.vid = (uint16_t)strtoul(argv[2], NULL, 16);
        g.pid = (uint16_t)strtoul(argv[3], NULL, 16);
        if (build_desc(argv[4]) != 0)
            return usage();
        g.fd = open("/dev/uhid", O_RDWR | O_CLOEXEC | O_NONBLOCK);
        log = argv[5];
    } else if (argc == 4 && strcmp(argv[1], "hidg") == 0) {
        g.fd = open(argv[2], O_RDWR | O_CLOEXEC | O_NONBLOCK);
        log = argv[3];
    } else {
        return usage();
    }
    if (g.fd < 0) {
        fprintf(stderr, "hidplay: cannot open %s: %s\n", g.uhid ? "/dev/uhid" : argv[2],
                strerror(errno));
        return 1;
    }
    g.log = fopen(log, "w");
    if (!g.log)
        return 1;
    setvbuf(g.log, NULL, _IOLBF, 0);
    if (g.uhid && uhid_create() != 0) {
        fprintf(stderr, "hidplay: UHID_CREATE2 failed: %s\n", strerror(errno));
        return 1;
    }
    setvbuf(stdout, NULL, _IOLBF, 0);
    char line[512];
    while (next_line(line, sizeof line)) {
        if (strncmp(line, "quit", 4) == 0)
            break;
        if (command(line) == 0)
            printf("ok\n");
        else
            printf("error: %s\n", line);
    }
    fprintf(g.log, "%lld end: %ld reports sent, %ld dropped\n", (long long)now_ns(), g.sent,
            g.dropped);
    if (g.uhid && g.created)
        uhid_destroy();
    close(g.fd);
    fclose(g.log);
    return 0;
}
