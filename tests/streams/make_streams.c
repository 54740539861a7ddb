/* tests/streams/make_streams.c -- writes the small recordings in this
 * folder from the documented report formats (devices/RECORDING.md). They
 * are committed; the build makes this program (build/tests/make_streams)
 * and CTest's streams_reproduce runs it into a scratch folder and holds
 * every file to the committed one byte for byte. When the format changes,
 * rewrite them with
 *
 *   build/tests/make_streams tests/streams
 *
 * test_dev_streams.c replays each one and asserts what it decodes to. */
#include "iso_dev_rec.h"
#include "iso_dev_view.h"
#include "iso_fb.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MS 1000000LL

/* The file being written, the output folder and the noise generator's
 * state (a fixed LCG, so that every rebuild writes the same bytes). */
static struct {
    FILE *f;
    char dir[1024];
    unsigned lcg;
} g = {NULL, ".", 12345u};

static void start_file(const char *name, const iso_dev_info *infos, size_t n)
{
    char path[1200];
    snprintf(path, sizeof path, "%s/%s", g.dir, name);
    g.f = fopen(path, "wb");
    if (!g.f) {
        perror(path);
        exit(1);
    }
    static uint8_t buf[80000];
    int len = iso_dev_rec_encode_header(buf, sizeof buf, infos, n, 0);
    fwrite(buf, 1, (size_t)len, g.f);
}

static void rec(int type, int src, int64_t t, const void *data, size_t len)
{
    iso_dev_chunk c;
    memset(&c, 0, sizeof c);
    c.type = (uint8_t)type;
    c.source = (uint8_t)src;
    c.t_ns = t;
    c.len = (uint16_t)len;
    if (len)
        memcpy(c.data, data, len);
    uint8_t buf[300];
    int n = iso_dev_rec_encode_record(buf, sizeof buf, &c);
    fwrite(buf, 1, (size_t)n, g.f);
}

static void tick(int64_t t)
{
    rec(ISO_DEV_CHUNK_TICK, 0, t, NULL, 0);
}

/* A whole recording ends with the END record its writer adds on closing. */
static void finish(void)
{
    rec(ISO_DEV_CHUNK_END, 0, 0, NULL, 0);
    fclose(g.f);
}

static void hid6(int src, int64_t t, int tx, int ty, int tz, int rx, int ry, int rz)
{
    int v[6] = {tx, ty, tz, rx, ry, rz};
    uint8_t r[13];
    r[0] = 1;
    for (int i = 0; i < 6; i++) {
        r[1 + 2 * i] = (uint8_t)(v[i] & 0xff);
        r[2 + 2 * i] = (uint8_t)((v[i] >> 8) & 0xff);
    }
    rec(ISO_DEV_CHUNK_DATA, src, t, r, 13);
}

static void hid_split(int src, int64_t t, int id, int a, int b, int c)
{
    int v[3] = {a, b, c};
    uint8_t r[7];
    r[0] = (uint8_t)id;
    for (int i = 0; i < 3; i++) {
        r[1 + 2 * i] = (uint8_t)(v[i] & 0xff);
        r[2 + 2 * i] = (uint8_t)((v[i] >> 8) & 0xff);
    }
    rec(ISO_DEV_CHUNK_DATA, src, t, r, 7);
}

static void hid_buttons(int src, int64_t t, unsigned b)
{
    uint8_t r[3] = {3, (uint8_t)(b & 0xff), (uint8_t)(b >> 8)};
    rec(ISO_DEV_CHUNK_DATA, src, t, r, 3);
}

static iso_dev_info hid_info(uint16_t vid, uint16_t pid, const char *name)
{
    iso_dev_info i;
    memset(&i, 0, sizeof i);
    i.kind = ISO_DEV_KIND_HID;
    i.vid = vid;
    i.pid = pid;
    snprintf(i.name, sizeof i.name, "%s", name);
    return i;
}

static size_t sample_frame(uint8_t *dst, uint16_t seq, int kind, unsigned buttons,
                           const int32_t v[6])
{
    iso_fb_sample s;
    memset(&s, 0, sizeof s);
    s.t_us = seq * 1000u;
    s.kind = (uint8_t)kind;
    s.buttons = (uint16_t)buttons;
    memcpy(s.v, v, sizeof s.v);
    uint8_t pl[64];
    int n = iso_fb_sample_pack(pl, sizeof pl, &s);
    int w = iso_fb_frame_encode(dst, ISO_FB_FRAME_MAX, ISO_FB_HANDLE_SAMPLE, seq, pl, (size_t)n);
    return (size_t)w;
}

/* A 3D-mouse session of 6.5 s for the README's main job: a SpaceMouse
 * Wireless receiver reporting every 8 ms (combined report 1, as the real
 * one does), ticks at 60 Hz. Bends the cactus's top over like the
 * benchmark's handle motion (rx with ty and tz), holds the clutch while
 * deflecting (nothing may move), then brings it a third of the way back
 * with a twist (rz). Deflections rise
 * and fall as sin² bumps with a few counts of sensor noise (a fixed LCG, so
 * the file is the same on every rebuild). */
static int noise(void)
{
    g.lcg = g.lcg * 1103515245u + 12345u;
    return (int)((g.lcg >> 16) % 7u) - 3; /* -3..3 counts, inside the dead zone */
}

static double bump(double t, double t0, double t1)
{
    if (t <= t0 || t >= t1)
        return 0;
    double s = sin(3.14159265358979323846 * (t - t0) / (t1 - t0));
    return s * s;
}

static void session(void)
{
    iso_dev_info one = hid_info(0x256f, 0xc652, "SpaceMouse Wireless (receiver)");
    start_file("sm_session.isorec", &one, 1);
    const int64_t tick_ns = 16666667, report_ns = 8 * MS, end = 6500 * MS;
    int64_t next_tick = tick_ns, next_report = 4 * MS;
    unsigned buttons = 0;
    while (next_tick <= end) {
        if (next_report < next_tick) {
            double t = (double)next_report * 1e-9;
            int rx = (int)lround(-330 * bump(t, 0.3, 3.3) - 300 * bump(t, 3.6, 4.6) +
                                 150 * bump(t, 4.8, 6.3));
            int ty = (int)lround(280 * bump(t, 0.3, 3.3) - 120 * bump(t, 4.8, 6.3));
            int tz = (int)lround(-200 * bump(t, 0.3, 3.3) + 80 * bump(t, 4.8, 6.3));
            int rz = (int)lround(100 * bump(t, 4.8, 6.3));
            unsigned b = (t >= 3.55 && t < 4.65) ? 1u : 0u; /* clutch around the 2nd bump */
            if (b != buttons)
                hid_buttons(0, next_report, b);
            buttons = b;
            hid6(0, next_report, noise(), ty + noise(), tz + noise(), rx + noise(), noise(),
                 rz + noise());
            next_report += report_ns;
        } else {
            tick(next_tick);
            next_tick += tick_ns;
        }
    }
    finish();
}

/* A fast 3D-mouse session of 6 s: the same receiver, a person jabbing the
 * cap to its full deflection (350 counts, where the SpaceMouse's range
 * ends) and letting go, each push reached in 80 ms and released in 80 ms
 * (a trapezoid, as a hand does it): lift (ty), bend over (rx), twist
 * (rz), swing back and sideways at once (rx, tx), a quick push down (tz),
 * then turn back with a tilt (rz, ry). The mapping's sensitivity is the
 * speed at full deflection (devices/iso_dev_map.h, full_scale), so this is the
 * fastest motion a scene lets the mouse command, at its sharpest. */
static double jab(double t, double t0, double t1)
{
    const double ramp = 0.08;
    if (t <= t0 || t >= t1)
        return 0;
    return fmin(1.0, fmin((t - t0) / ramp, (t1 - t) / ramp));
}

static void fast_session(void)
{
    iso_dev_info one = hid_info(0x256f, 0xc652, "SpaceMouse Wireless (receiver)");
    start_file("sm_fast.isorec", &one, 1);
    const int64_t tick_ns = 16666667, report_ns = 8 * MS, end = 6000 * MS;
    int64_t next_tick = tick_ns, next_report = 4 * MS;
    while (next_tick <= end) {
        if (next_report < next_tick) {
            double t = (double)next_report * 1e-9;
            int tx = (int)lround(250 * jab(t, 2.8, 3.8));
            int ty = (int)lround(350 * jab(t, 0.3, 1.0));
            int tz = (int)lround(-350 * jab(t, 4.0, 4.4));
            int rx = (int)lround(-350 * jab(t, 1.2, 1.9) + 350 * jab(t, 2.8, 3.8));
            int ry = (int)lround(200 * jab(t, 4.6, 5.6));
            int rz = (int)lround(350 * jab(t, 2.0, 2.6) - 350 * jab(t, 4.6, 5.6));
            hid6(0, next_report, tx + noise(), ty + noise(), tz + noise(), rx + noise(),
                 ry + noise(), rz + noise());
            next_report += report_ns;
        } else {
            tick(next_tick);
            next_tick += tick_ns;
        }
    }
    finish();
}

/* A page of the live view dragging the built-in cactus's top straight up
 * at one bounding-box diagonal a second (0.9306 a second, half the view's
 * 2 diag/s limit): a viewer takes control at 90 ms, and from 0.3 s a TARGET
 * every 25 ms, as a browser sends them, rising for 0.5 s and then held,
 * until 2 s. With `late`, the ticks between 0.3 s and 1 s come 1, 3, 1, 1,
 * 2, 1, 4, 1 and 6 periods apart, cycled, as a loaded machine's late ticks
 * record them (each TICK at the grid time the live tick jumped to); without,
 * every tick is on time. tests/test_late_drag.c replays both. */
static void view_env(int64_t t, int what, uint32_t seq, double z)
{
    uint8_t b[ISO_DEV_VIEW_ENVELOPE + ISO_DEV_VIEW_MSG_MAX];
    const uint32_t conn = 1;
    b[0] = (uint8_t)what;
    for (int i = 0; i < 4; i++)
        b[1 + i] = (uint8_t)(conn >> (8 * i));
    size_t n = ISO_DEV_VIEW_ENVELOPE;
    if (what == ISO_DEV_VIEW_MSG) {
        iso_dev_view_msg m = {ISO_DEV_VIEW_TARGET, 0, seq, (double)seq * 25.0, {0, 0, z, 0, 0, 0}};
        n += (size_t)iso_dev_view_encode(&m, b + n, ISO_DEV_VIEW_MSG_MAX);
    }
    rec(ISO_DEV_CHUNK_DATA, 0, t, b, n);
}

static void view_drag(const char *name, int late)
{
    static const int gaps[] = {1, 3, 1, 1, 2, 1, 4, 1, 6};
    const double diag = 0.930558, speed = 1.0, rise_s = 0.5, period = 1.0 / 60;
    const int64_t start = 300 * MS, late_end = 1000 * MS, end = 2000 * MS;
    iso_dev_info info;
    memset(&info, 0, sizeof info);
    info.kind = ISO_DEV_KIND_VIEW;
    snprintf(info.name, sizeof info.name, "hand");
    start_file(name, &info, 1);
    int64_t next_msg = start;
    int k = 0, granted = 0;
    uint32_t seq = 1;
    size_t gi = 0;
    for (;;) {
        int64_t due = llround((k + 1) * period * 1e9);
        k +=
            late && due > start && due < late_end ? gaps[gi++ % (sizeof gaps / sizeof gaps[0])] : 1;
        int64_t t = llround(k * period * 1e9);
        if (t > end)
            break;
        if (!granted && t >= 100 * MS) {
            view_env(90 * MS, ISO_DEV_VIEW_GRANT, 0, 0);
            granted = 1;
        }
        for (; next_msg + 3 * MS <= t; next_msg += 25 * MS) {
            double s = fmin((double)(next_msg - start) * 1e-9 + 0.025, rise_s);
            view_env(next_msg + 3 * MS, ISO_DEV_VIEW_MSG, ++seq, speed * diag * s);
        }
        tick(t);
    }
    finish();
}

int main(int argc, char **argv)
{
    if (argc > 1)
        snprintf(g.dir, sizeof g.dir, "%s", argv[1]);

    session();
    fast_session();
    view_drag("view_drag.isorec", 0);
    view_drag("view_drag_late.isorec", 1);

    /* 1. A 3D-mouse twist: the universal receiver (combined 13-byte report 1)
     * and a SpaceNavigator (split reports 1 and 2), ticks every 1 ms. */
    iso_dev_info two[2] = {hid_info(0x256f, 0xc652, "SpaceMouse Wireless (receiver)"),
                           hid_info(0x046d, 0xc626, "SpaceNavigator")};
    start_file("sm_twist.isorec", two, 2);
    for (int k = 1; k <= 10; k++) {
        int64_t t = k * MS;
        if (k == 2)
            hid6(0, t - MS / 2, 175, 0, 0, 0, 0, -350);
        if (k == 3) {
            hid_split(1, t - MS / 2, 1, 0, 350, 0);
            hid_split(1, t - MS / 4, 2, 0, 0, 0);
        }
        if (k == 8)
            hid6(0, t - MS / 2, 0, 0, 0, 0, 0, 0);
        tick(t);
    }
    finish();

    /* 2. A button-driven clutch sequence: deflected throughout; button 0
     * (clutch) held over ticks 3..5, button 1 (next handle) at tick 8. */
    iso_dev_info one = hid_info(0x256f, 0xc635, "SpaceMouse Compact");
    start_file("clutch_buttons.isorec", &one, 1);
    hid6(0, MS / 2, 350, 0, 0, 0, 0, 0);
    for (int k = 1; k <= 10; k++) {
        int64_t t = k * MS;
        if (k == 3)
            hid_buttons(0, t - 10, 0x1);
        if (k == 6)
            hid_buttons(0, t - 10, 0x0);
        if (k == 8)
            hid_buttons(0, t - 10, 0x2);
        if (k == 9)
            hid_buttons(0, t - 10, 0x0);
        tick(t);
    }
    finish();

    /* 3. An unplug and replug: deflected, gone at tick 4, back at tick 7,
     * deflected again (a fresh device starts from rest). */
    start_file("unplug_replug.isorec", &one, 1);
    hid6(0, MS / 2, 0, 0, 350, 0, 0, 0);
    for (int k = 1; k <= 10; k++) {
        int64_t t = k * MS;
        if (k == 4)
            rec(ISO_DEV_CHUNK_GONE, 0, t, NULL, 0);
        if (k == 7)
            rec(ISO_DEV_CHUNK_BACK, 0, t, NULL, 0);
        if (k == 8)
            hid6(0, t - 10, 0, 0, -350, 0, 0, 0);
        tick(t);
    }
    finish();

    /* 4. A serial pose stream with garbage and a bad checksum: four pose
     * samples (x = 1, 2, 3, 4 mm); noise before the first, the second split
     * over two reads, the third with one payload byte flipped (CRC fails). */
    iso_dev_info ser;
    memset(&ser, 0, sizeof ser);
    ser.kind = ISO_DEV_KIND_SERIAL;
    ser.baud = 115200;
    ser.data_bits = 8;
    ser.parity = 'N';
    ser.stop_bits = 1;
    snprintf(ser.name, sizeof ser.name, "/dev/ttyACM0");
    start_file("serial_pose.isorec", &ser, 1);
    uint8_t buf[200], fr[ISO_FB_FRAME_MAX];
    size_t n = 0;
    const uint8_t noise[] = {0x13, 0x37, 0xff, 0x42, 0x00, 0x99, 0x01};
    memcpy(buf, noise, sizeof noise);
    n = sizeof noise;
    for (int k = 1; k <= 4; k++) {
        int32_t v[6] = {k * 1000, 0, 0, 0, 0, 0};
        size_t w = sample_frame(fr, (uint16_t)k, ISO_FB_SAMPLE_POSE, k == 4 ? 1 : 0, v);
        if (k == 3)
            fr[10] ^= 0x40;
        int64_t t = k * MS;
        if (k == 2) {
            rec(ISO_DEV_CHUNK_DATA, 0, t - MS / 2, fr, 9);
            rec(ISO_DEV_CHUNK_DATA, 0, t - MS / 4, fr + 9, w - 9);
        } else {
            memcpy(buf + n, fr, w);
            rec(ISO_DEV_CHUNK_DATA, 0, t - MS / 2, buf, n + w);
        }
        n = 0;
        tick(t);
    }
    finish();

    /* 5. GPIO: the clutch bounces (three edges within 1 ms), the e-stop is
     * pressed at 5.2 ms and released with a bounce at 8 ms; 2 ms debounce. */
    iso_dev_info gp;
    memset(&gp, 0, sizeof gp);
    gp.kind = ISO_DEV_KIND_GPIO;
    gp.debounce_us = 2000;
    snprintf(gp.name, sizeof gp.name, "gpiochip0");
    start_file("gpio_estop.isorec", &gp, 1);
    uint8_t init[4] = {ISO_DEV_GPIO_CLUTCH, 0, ISO_DEV_GPIO_ESTOP, 0};
    rec(ISO_DEV_CHUNK_DATA, 0, 0, init, 4);
    const struct {
        int64_t t;
        uint8_t role, level;
    } edges[] = {{3 * MS, 0, 1},          {3 * MS + 200000, 0, 0}, {3 * MS + 400000, 0, 1},
                 {5 * MS + 200000, 1, 1}, {8 * MS, 1, 0},          {8 * MS + 100000, 1, 1},
                 {8 * MS + 300000, 1, 0}};
    size_t e = 0;
    for (int k = 1; k <= 14; k++) {
        int64_t t = k * MS;
        for (; e < sizeof edges / sizeof edges[0] && edges[e].t <= t; e++) {
            uint8_t p[2] = {edges[e].role, edges[e].level};
            rec(ISO_DEV_CHUNK_DATA, 0, edges[e].t, p, 2);
        }
        tick(t);
    }
    finish();

    /* 6. Torn: the twist stream with record 6 damaged (one byte flipped)
     * and the file cut off 5 bytes into its last TICK record (so its END
     * record is gone too). */
    char src[1200], dst[1200];
    snprintf(src, sizeof src, "%s/sm_twist.isorec", g.dir);
    snprintf(dst, sizeof dst, "%s/torn.isorec", g.dir);
    FILE *in = fopen(src, "rb");
    if (!in) {
        perror(src);
        return 1;
    }
    static uint8_t all[100000];
    size_t len = fread(all, 1, sizeof all, in);
    fclose(in);
    iso_dev_rec_reader r;
    if (iso_dev_rec_reader_init(&r, all, len, NULL) != ISO_OK)
        return 1;
    size_t starts[64], ns = 0;
    iso_dev_chunk c;
    starts[ns++] = r.pos;
    while (iso_dev_rec_next(&r, &c, NULL) == 1 && ns < 64)
        starts[ns++] = r.pos;
    iso_dev_rec_reader_deinit(&r);
    all[starts[5] + 8] ^= 0x01;      /* inside record 6's timestamp */
    size_t cut = starts[ns - 2] + 5; /* 5 bytes into the last record before END */
    FILE *o = fopen(dst, "wb");
    if (!o || fwrite(all, 1, cut, o) != cut || fclose(o) != 0) {
        perror(dst);
        return 1;
    }
    printf("torn.isorec: damaged record at byte %zu, cut at byte %zu of %zu\n", starts[5], cut,
           len);
    return 0;
}
