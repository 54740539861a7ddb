/* tests/test_dev_stale.c -- a twist stream that goes quiet stops moving its
 * handle: on a real pseudo-terminal with frames encoded by the firmware
 * bridge's library (live, then its recording replayed to the same ticks
 * bit for bit), and on scripted sources at exact stream times (the
 * boundary, per-source stale times, pose streams and 3D mice untouched).
 * Also the hub's per-source counters and descriptions. */
#define _XOPEN_SOURCE 700 /* posix_openpt, grantpt, unlockpt, ptsname */
#define _DEFAULT_SOURCE   /* usleep */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "iso_dev_decode.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"
#include "iso_fb.h"
#include "testutil.h"

#define MS 1000000LL
#define MAXT 400

typedef struct notes {
    char msg[16][600];
    int n;
} notes;

static void note(void *ctx, const char *msg)
{
    notes *w = ctx;
    if (w->n < 16)
        snprintf(w->msg[w->n], sizeof w->msg[0], "%s", msg);
    w->n++;
}

/* One HANDLE_SAMPLE wire frame: a twist of vx m/s along x (or a pose at x). */
static size_t sample_frame(uint8_t *dst, size_t cap, uint16_t seq, int kind, double x)
{
    iso_fb_sample sm;
    memset(&sm, 0, sizeof sm);
    sm.kind = (uint8_t)kind;
    sm.v[0] = (int32_t)lround(x * 1e6);
    uint8_t pl[ISO_FB_MAX_PAYLOAD];
    int n = iso_fb_sample_pack(pl, sizeof pl, &sm);
    assert_true(n > 0);
    int w = iso_fb_frame_encode(dst, cap, ISO_FB_HANDLE_SAMPLE, seq, pl, (size_t)n);
    assert_true(w > 0);
    return (size_t)w;
}

static void identity_poses(iso_pose *P)
{
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
}

/* Skips when this build cannot decode serial streams. */
static void need_serial_decoder(void)
{
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = ISO_DEV_KIND_SERIAL;
    iso_dev_decoder d;
    iso_err err;
    iso_err_clear(&err);
    if (iso_dev_decoder_init(&d, &in, 0, &err) != ISO_OK) {
        print_message("skipped: %s\n", err.msg);
        skip();
    }
}

/* ---- live, on a pseudo-terminal ----------------------------------------- */

typedef struct live_run {
    iso_dev_tick t[MAXT];
    int n;
    notes w;
} live_run;

/* Sends a twist of +x 0.5 m/s every 10 ms for 0.5 s, goes quiet (link still
 * open) for 0.4 s, then sends again for 0.1 s; ticks every 10 ms on the
 * monotonic clock (the live loop's stream time), recording everything. */
static void twist_stream_goes_quiet_on_a_pty(void **state)
{
    (void)state;
    need_serial_decoder();
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    assert_true(master >= 0);
    assert_int_equal(grantpt(master), 0);
    assert_int_equal(unlockpt(master), 0);
    char name[128];
    snprintf(name, sizeof name, "%s", ptsname(master));
    iso_dev_source *s;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_tty_open(name, 115200, &s, &err), ISO_OK);
    static live_run a;
    memset(&a, 0, sizeof a);
    iso_dev_hub *h;
    assert_int_equal(iso_dev_hub_create(note, &a.w, &h, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, s, NULL, NULL, &err), ISO_OK);
    char rec[1024];
    iso_test_tmp(rec, sizeof rec, "dev_stale_pty.isorec");
    assert_int_equal(iso_dev_hub_record_start(h, rec, &err), ISO_OK);
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    static iso_dev_map m;
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    iso_pose P[ISO_DEV_MAX_HANDLES];
    identity_poses(P);

    const int64_t t0 = iso_clock_ns();
    uint16_t seq = 0;
    int first_stale = -1, first_resumed = -1;
    int64_t last_sample = 0, before_stale = 0;
    for (a.n = 0; a.n < MAXT; a.n++) {
        int64_t el = iso_clock_ns() - t0;
        if (el >= 1000 * MS)
            break;
        int sending = el < 500 * MS || el >= 900 * MS;
        if (sending) {
            uint8_t wire[ISO_FB_WIRE_MAX(ISO_FB_MAX_PAYLOAD)];
            size_t len = sample_frame(wire, sizeof wire, seq++, ISO_FB_SAMPLE_TWIST, 0.5);
            assert_int_equal(write(master, wire, len), (ssize_t)len);
            usleep(1000);             /* let the pty pass it on, */
            iso_dev_hub_sync(h, 200); /* and the hub's reader thread read it */
        }
        int64_t now = iso_clock_ns();
        int64_t seen = m.src[0].t_twist;
        assert_int_equal(iso_dev_hub_tick(h, &m, now, 10e-3, P, &a.t[a.n], &err), ISO_OK);
        if (first_stale < 0 && (a.t[a.n].stale & 1)) {
            first_stale = a.n;
            last_sample = m.src[0].t_twist;
            before_stale = a.n > 0 ? a.t[a.n - 1].t_ns : 0;
        }
        if (first_stale >= 0 && first_resumed < 0 && m.src[0].t_twist != seen)
            first_resumed = a.n;
        usleep(9000);
    }
    assert_int_equal(iso_dev_hub_record_stop(h, &err), ISO_OK);

    assert_true(first_stale > 0);
    assert_true(first_resumed > first_stale);
    /* every tick while samples came moved the handle at 0.5 m/s; the first
     * tick more than 100 ms of stream time after the last sample is zero,
     * and the one before it was not yet past 100 ms */
    int moving = 0;
    for (int k = 0; k < first_stale; k++)
        moving += a.t[k].twist[0].v[0] == 0.5;
    assert_true(moving >= first_stale - 2); /* the first ticks may precede the first sample */
    assert_true(a.t[first_stale].t_ns - last_sample > 100 * MS);
    assert_true(before_stale - last_sample <= 100 * MS);
    for (int k = first_stale; k < first_resumed; k++) {
        assert_true(a.t[k].twist[0].v[0] == 0 && a.t[k].twist[0].w[2] == 0);
        assert_int_equal(a.t[k].stale, 1);
    }
    assert_true(a.t[first_resumed].twist[0].v[0] == 0.5);
    assert_int_equal(a.t[first_resumed].stale, 0);
    assert_true(a.t[a.n - 1].twist[0].v[0] == 0.5);

    iso_dev_source_stats st;
    assert_int_equal(iso_dev_hub_source_stats(h, 0, &st), ISO_OK);
    assert_int_equal(st.stale, 1);
    assert_int_equal(st.is_stale, 0);
    assert_int_equal(st.present, 1);
    assert_int_equal(st.dec.reports, seq);
    assert_int_equal(st.events, seq); /* a twist event each; buttons never changed */
    assert_int_equal(st.dec.bad_frames, 0);
    assert_int_equal(a.w.n, 2);
    char expect[600];
    snprintf(expect, sizeof expect,
             "serial %s: no twist sample for more than 100 ms: its twist is zero until samples "
             "resume",
             name);
    assert_string_equal(a.w.msg[0], expect);
    snprintf(expect, sizeof expect, "serial %s: twist samples resumed after", name);
    assert_memory_equal(a.w.msg[1], expect, strlen(expect));
    char desc[256];
    assert_int_equal(iso_dev_hub_describe(h, 0, desc, sizeof desc), ISO_OK);
    snprintf(expect, sizeof expect, "serial %s (115200 8N1)", name);
    assert_string_equal(desc, expect);
    printf("pty: %d ticks; stale at tick %d, %.2f ms of stream time after the last sample; "
           "moving again at tick %d\n  said: %s\n  said: %s\n",
           a.n, first_stale, (double)(a.t[first_stale].t_ns - last_sample) / 1e6, first_resumed,
           a.w.msg[0], a.w.msg[1]);
    iso_dev_hub_destroy(h);
    close(master);

    /* The recording replays to the same ticks, messages and counts, bit for bit. */
    static live_run b;
    memset(&b, 0, sizeof b);
    iso_dev_rec_reader r;
    assert_int_equal(iso_dev_rec_reader_load(&r, rec, &err), ISO_OK);
    assert_int_equal(iso_dev_replay_open(&r, &s, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_create(note, &b.w, &h, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, s, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    for (b.n = 0; b.n < MAXT; b.n++) {
        int64_t t = iso_dev_hub_next_tick(h, 10 * MS);
        if (t == INT64_MAX)
            break;
        assert_int_equal(iso_dev_hub_tick(h, &m, t, 10e-3, P, &b.t[b.n], &err), ISO_OK);
    }
    assert_int_equal(b.n, a.n);
    assert_memory_equal(b.t, a.t, sizeof a.t[0] * (size_t)a.n);
    assert_int_equal(b.w.n, a.w.n);
    for (int k = 0; k < a.w.n; k++)
        assert_string_equal(b.w.msg[k], a.w.msg[k]);
    iso_dev_source_stats st2;
    assert_int_equal(iso_dev_hub_source_stats(h, 0, &st2), ISO_OK);
    assert_int_equal(st2.stale, 1);
    assert_int_equal(st2.events, st.events);
    assert_int_equal(iso_dev_hub_describe(h, 0, desc, sizeof desc), ISO_OK);
    snprintf(expect, sizeof expect, "serial %s (115200 8N1, replayed)", name);
    assert_string_equal(desc, expect);
    iso_dev_hub_destroy(h);
    iso_dev_rec_reader_deinit(&r);
}

/* ---- exact stream times, scripted sources -------------------------------- */

static iso_dev_source *fake(int kind, const char *name, uint16_t vid, uint16_t pid)
{
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = (uint8_t)kind;
    in.vid = vid;
    in.pid = pid;
    if (kind == ISO_DEV_KIND_SERIAL) {
        in.baud = 115200;
        in.data_bits = 8;
        in.parity = 'N';
        in.stop_bits = 1;
    }
    snprintf(in.name, sizeof in.name, "%s", name);
    iso_dev_source *s;
    assert_int_equal(iso_dev_fake_open(&in, &s, NULL), ISO_OK);
    return s;
}

static void push_sample(iso_dev_source *s, int64_t t, uint16_t seq, int kind, double x)
{
    uint8_t wire[ISO_FB_WIRE_MAX(ISO_FB_MAX_PAYLOAD)];
    size_t len = sample_frame(wire, sizeof wire, seq, kind, x);
    assert_int_equal(iso_dev_fake_push(s, t, wire, len), ISO_OK);
}

/* Source 0: twists every 10 ms up to 500 ms, default stale time: zero from
 * the tick at 610 ms (600 is exactly 100 ms: still moving). Source 1: the
 * same twists up to 300 ms with a 250 ms stale time: zero from 560 ms.
 * Source 2: a pose stream that stops at 100 ms: holds its pose. Source 3:
 * a 3D mouse deflected once at 5 ms: keeps moving (state, not a stream). */
static void stale_time_is_stream_time(void **state)
{
    (void)state;
    need_serial_decoder();
    static notes w;
    memset(&w, 0, sizeof w);
    iso_err err;
    iso_err_clear(&err);
    iso_dev_hub *h;
    assert_int_equal(iso_dev_hub_create(note, &w, &h, &err), ISO_OK);
    iso_dev_source *s0 = fake(ISO_DEV_KIND_SERIAL, "bridge0", 0, 0);
    iso_dev_source *s1 = fake(ISO_DEV_KIND_SERIAL, "bridge1", 0, 0);
    iso_dev_source *s2 = fake(ISO_DEV_KIND_SERIAL, "poser", 0, 0);
    iso_dev_source *s3 = fake(ISO_DEV_KIND_HID, "/dev/hidraw1", 0x256f, 0xc635);
    for (int k = 0; k <= 50; k++)
        push_sample(s0, k * 10 * MS, (uint16_t)k, ISO_FB_SAMPLE_TWIST, 0.25);
    for (int k = 0; k <= 30; k++)
        push_sample(s1, k * 10 * MS, (uint16_t)k, ISO_FB_SAMPLE_TWIST, 0.125);
    for (int k = 0; k <= 10; k++)
        push_sample(s2, k * 10 * MS, (uint16_t)k, ISO_FB_SAMPLE_POSE, 0);
    const uint8_t rep[13] = {1, 0x5e, 0x01}; /* tx = 350: full deflection */
    assert_int_equal(iso_dev_fake_push(s3, 5 * MS, rep, sizeof rep), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, s0, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, s1, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, s2, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, s3, NULL, NULL, &err), ISO_OK);
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    static iso_dev_map m;
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    assert_int_equal(iso_dev_map_set_stale(&m, 1, 250 * MS, &err), ISO_OK);
    iso_pose P[ISO_DEV_MAX_HANDLES];
    identity_poses(P);
    /* handle at the origin: the pose stream's target (origin) adds nothing */
    static iso_dev_tick t[100];
    for (int k = 0; k < 100; k++)
        assert_int_equal(iso_dev_hub_tick(h, &m, k * 10 * MS, 10e-3, P, &t[k], &err), ISO_OK);
    const double mouse = 0.1;
    assert_true(t[0].twist[0].v[0] == 0.25 + 0.125);
    assert_true(t[1].twist[0].v[0] == 0.25 + 0.125 + mouse);
    assert_true(t[55].twist[0].v[0] == 0.25 + 0.125 + mouse); /* 550: 250 ms after 300 */
    assert_int_equal(t[55].stale, 0);
    assert_true(t[56].twist[0].v[0] == 0.25 + mouse);
    assert_int_equal(t[56].stale, 2);
    assert_true(t[60].twist[0].v[0] == 0.25 + mouse); /* exactly 100 ms after 500 */
    assert_int_equal(t[61].stale, 3);
    for (int k = 61; k < 100; k++)
        assert_true(t[k].twist[0].v[0] == mouse); /* the mouse and the pose hold */
    assert_int_equal(w.n, 2);
    assert_string_equal(w.msg[0], "serial bridge1: no twist sample for more than 250 ms: its "
                                  "twist is zero until samples resume");
    assert_string_equal(w.msg[1], "serial bridge0: no twist sample for more than 100 ms: its "
                                  "twist is zero until samples resume");
    iso_dev_source_stats st;
    for (size_t i = 0; i < 4; i++) {
        assert_int_equal(iso_dev_hub_source_stats(h, i, &st), ISO_OK);
        assert_int_equal(st.stale, i < 2);
        assert_int_equal(st.is_stale, i < 2);
    }
    /* the setter refuses what it cannot mean */
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_set_stale(&m, 16, 100 * MS, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "device mapping: source 16 (must be 0 to 15)");
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_set_stale(&m, 0, 0, &err), ISO_EINVAL);
    assert_string_equal(err.msg,
                        "device mapping: source 0 stale time 0.000 ms (must be 1 to 10000 ms)");
    iso_dev_hub_destroy(h);
}

/* ---- counters and descriptions ------------------------------------------- */

static int reopen_none(void *ctx, const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    iso_dev_source **next = ctx;
    (void)info;
    if (!*next)
        return iso_err_set(err, ISO_EIO, -1, "not there");
    *out = *next;
    *next = NULL;
    return ISO_OK;
}

/* A serial stream with a bad CRC, a duplicate and garbage, unplugged and
 * back with another bad CRC: the counts by reason go on across the gap. */
static void counters_and_descriptions(void **state)
{
    (void)state;
    need_serial_decoder();
    iso_err err;
    iso_err_clear(&err);
    iso_dev_hub *h;
    assert_int_equal(iso_dev_hub_create(NULL, NULL, &h, &err), ISO_OK);
    iso_dev_hub_set_retry(h, 5 * MS);
    iso_dev_source *ser = fake(ISO_DEV_KIND_SERIAL, "/dev/ttyACM0", 0x2e8a, 0x000a);
    iso_dev_source *ser2 = fake(ISO_DEV_KIND_SERIAL, "/dev/ttyACM0", 0x2e8a, 0x000a);
    iso_dev_source *hid = fake(ISO_DEV_KIND_HID, "/dev/hidraw3", 0x256f, 0xc635);
    snprintf(hid->detail, sizeof hid->detail, "SpaceMouse Compact");
    iso_dev_source *gpio = fake(ISO_DEV_KIND_GPIO, "gpiochip0", 0, 0);
    uint8_t wire[ISO_FB_WIRE_MAX(ISO_FB_MAX_PAYLOAD)];
    push_sample(ser, 1 * MS, 0, ISO_FB_SAMPLE_TWIST, 0.1);
    size_t len = sample_frame(wire, sizeof wire, 1, ISO_FB_SAMPLE_TWIST, 0.1);
    wire[3] ^= 0x40; /* one flipped bit: a CRC error */
    assert_int_equal(iso_dev_fake_push(ser, 2 * MS, wire, len), ISO_OK);
    push_sample(ser, 3 * MS, 0, ISO_FB_SAMPLE_TWIST, 0.1); /* the same number again */
    assert_int_equal(iso_dev_fake_push_gone(ser, 4 * MS), ISO_OK);
    len = sample_frame(wire, sizeof wire, 7, ISO_FB_SAMPLE_TWIST, 0.1);
    wire[4] ^= 0x01; /* the sequence number: a CRC error again */
    assert_int_equal(iso_dev_fake_push(ser2, 10 * MS, wire, len), ISO_OK);
    push_sample(ser2, 11 * MS, 8, ISO_FB_SAMPLE_TWIST, 0.1);
    assert_int_equal(iso_dev_hub_add(h, ser, reopen_none, &ser2, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, hid, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, gpio, NULL, NULL, &err), ISO_OK);
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    static iso_dev_map m;
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    iso_pose P[ISO_DEV_MAX_HANDLES];
    identity_poses(P);
    iso_dev_tick t;
    for (int k = 1; k <= 12; k++) {
        assert_int_equal(iso_dev_hub_tick(h, &m, k * MS, 1e-3, P, &t, &err), ISO_OK);
        assert_int_equal(iso_dev_hub_sync(h, 2000), 1); /* a reopen asked for is answered */
    }
    iso_dev_source_stats st;
    assert_int_equal(iso_dev_hub_source_stats(h, 0, &st), ISO_OK);
    assert_int_equal(st.gone, 1);
    assert_int_equal(st.back, 1);
    assert_int_equal(st.present, 1);
    assert_int_equal(st.dec.reports, 2);
    assert_int_equal(st.drops.bad_crc, 2);
    assert_int_equal(st.drops.duplicate, 1);
    assert_int_equal(st.dec.bad_frames, 3);
    assert_int_equal(st.dec.bad_payloads, 0);
    assert_int_equal(st.events, 2 + 2); /* two twists, GONE, BACK */
    assert_int_equal(st.stale, 0);
    char d[256];
    assert_int_equal(iso_dev_hub_describe(h, 0, d, sizeof d), ISO_OK);
    assert_string_equal(d, "serial /dev/ttyACM0 (2e8a:000a, 115200 8N1)");
    assert_int_equal(iso_dev_hub_describe(h, 1, d, sizeof d), ISO_OK);
    assert_string_equal(d, "hid /dev/hidraw3 (256f:c635 SpaceMouse Compact)");
    assert_int_equal(iso_dev_hub_describe(h, 2, d, sizeof d), ISO_OK);
    assert_string_equal(d, "gpio gpiochip0 (debounce 0 us)");
    assert_int_equal(iso_dev_hub_describe(h, 1, d, 9), ISO_OK);
    assert_string_equal(d, "hid /dev");
    assert_int_equal(iso_dev_hub_source_stats(h, 1, &st), ISO_OK);
    assert_int_equal(st.drops.bad_crc, 0);
    assert_int_equal(iso_dev_hub_source_stats(h, 3, &st), ISO_EINVAL);
    assert_int_equal(st.events, 0);
    assert_int_equal(iso_dev_hub_describe(h, 3, d, sizeof d), ISO_EINVAL);
    assert_string_equal(d, "");
    iso_dev_hub_destroy(h);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(twist_stream_goes_quiet_on_a_pty),
        cmocka_unit_test(stale_time_is_stream_time),
        cmocka_unit_test(counters_and_descriptions),
    };
    return cmocka_run_group_tests_name("dev_stale", t, NULL, NULL);
}
