/* tests/test_dev_decode.c -- the decoders fed byte streams built from the
 * documented report formats of each model family, and the mapping's every
 * option on hand-computed numbers. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <math.h>
#include <string.h>

#include "iso_dev_decode.h"
#include "iso_dev_map.h"
#include "testutil.h"

static iso_dev_decoder dec_of(int kind, uint32_t debounce_us)
{
    iso_dev_info info;
    memset(&info, 0, sizeof info);
    info.kind = (uint8_t)kind;
    info.debounce_us = debounce_us;
    iso_dev_decoder d;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_decoder_init(&d, &info, 3, &err), ISO_OK);
    return d;
}

static size_t feed(iso_dev_decoder *d, int64_t t, const void *p, size_t len, iso_dev_event *ev)
{
    iso_dev_chunk c;
    memset(&c, 0, sizeof c);
    c.t_ns = t;
    c.type = ISO_DEV_CHUNK_DATA;
    c.len = (uint16_t)len;
    memcpy(c.data, p, len);
    return iso_dev_decode(d, &c, ev, ISO_DEV_EVENTS_PER_CHUNK);
}

static void spacemouse_report_formats(void **state)
{
    (void)state;
    iso_dev_decoder d = dec_of(ISO_DEV_KIND_HID, 0);
    iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    /* combined 13-byte report 1 (SpaceMouse Wireless, universal receiver) */
    const uint8_t comb[13] = {1,    0x5e, 0x01, 0xa2, 0xfe, 0x00, 0x00,
                              0x01, 0x00, 0xff, 0xff, 0x00, 0x80};
    assert_int_equal(feed(&d, 10, comb, 13, ev), 1);
    assert_int_equal(ev[0].kind, ISO_DEV_EV_AXES);
    assert_int_equal(ev[0].source, 3);
    assert_int_equal(ev[0].t_ns, 10);
    const int16_t want[6] = {350, -350, 0, 1, -1, -32768};
    assert_memory_equal(ev[0].axes, want, sizeof want);
    /* split reports (SpaceNavigator, SpaceMouse Pro): 1 translation, 2 rotation */
    const uint8_t tr[7] = {1, 10, 0, 20, 0, 30, 0}, rot[7] = {2, 0xf6, 0xff, 0, 0, 5, 0};
    assert_int_equal(feed(&d, 11, tr, 7, ev), 1);
    const int16_t w1[6] = {10, 20, 30, 1, -1, -32768};
    assert_memory_equal(ev[0].axes, w1, sizeof w1);
    assert_int_equal(feed(&d, 12, rot, 7, ev), 1);
    const int16_t w2[6] = {10, 20, 30, -10, 0, 5};
    assert_memory_equal(ev[0].axes, w2, sizeof w2);
    /* buttons in report 3: a LE bit mask; unchanged buttons give no event */
    const uint8_t b[3] = {3, 0x05, 0x01};
    assert_int_equal(feed(&d, 13, b, 3, ev), 1);
    assert_int_equal(ev[0].kind, ISO_DEV_EV_BUTTONS);
    assert_int_equal(ev[0].buttons, 0x105);
    assert_int_equal(feed(&d, 14, b, 3, ev), 0);
    assert_int_equal(d.n.reports, 5);
    /* short reports and unknown IDs: counted, skipped, state kept */
    const uint8_t sh1[5] = {1, 1, 2, 3, 4}, sh2[3] = {2, 1, 2}, sh3[1] = {3}, unk[7] = {9};
    assert_int_equal(feed(&d, 15, sh1, 5, ev), 0);
    assert_int_equal(feed(&d, 15, sh2, 3, ev), 0);
    assert_int_equal(feed(&d, 15, sh3, 1, ev), 0);
    assert_int_equal(feed(&d, 15, unk, 7, ev), 0);
    assert_int_equal(feed(&d, 15, unk, 0, ev), 0);
    assert_int_equal(d.n.short_reports, 4);
    assert_int_equal(d.n.unknown_ids, 1);
    assert_memory_equal(d.axes, w2, sizeof w2);
    /* report 1 longer than 13 (padding) still reads as combined */
    uint8_t pad[20] = {1, 7, 0, 0, 0, 0, 0, 0, 0, 0, 0, 9, 0};
    assert_int_equal(feed(&d, 16, pad, 20, ev), 1);
    assert_int_equal(ev[0].axes[0], 7);
    assert_int_equal(ev[0].axes[5], 9);
}

static void spnav_encoding(void **state)
{
    (void)state;
    iso_dev_decoder d = dec_of(ISO_DEV_KIND_SPNAV, 0);
    iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    uint8_t m[15 + 3 + 3 + 1 + 2] = {'M',  1,  0, 2,   0, 3, 0,   4,  0, 5,   0,   0xff,
                                     0xff, 16, 0, 'B', 2, 1, 'B', 40, 1, 'x', 'B', 2};
    size_t n = feed(&d, 5, m, sizeof m, ev);
    assert_int_equal(n, 2);
    const int16_t want[6] = {1, 2, 3, 4, 5, -1};
    assert_memory_equal(ev[0].axes, want, sizeof want);
    assert_int_equal(ev[1].buttons, 4);
    assert_int_equal(d.n.unknown_ids, 2); /* button 40 and 'x' */
    assert_int_equal(d.n.short_reports, 1);
}

static void gpio_debounce(void **state)
{
    (void)state;
    iso_dev_decoder d = dec_of(ISO_DEV_KIND_GPIO, 1000); /* 1 ms */
    iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    const uint8_t init[4] = {0, 0, 1, 0};
    assert_int_equal(feed(&d, 0, init, 4, ev), 2); /* initial levels are taken */
    const uint8_t c1[2] = {0, 1}, c0[2] = {0, 0}, e1[2] = {1, 1}, e0[2] = {1, 0};
    /* clutch: first edge after a quiet debounce time is taken at once */
    assert_int_equal(feed(&d, 2000000, c1, 2, ev), 1);
    assert_int_equal(ev[0].line, 0);
    assert_int_equal(ev[0].level, 1);
    /* a bounce inside the window waits; it settles 1 ms after the last edge */
    assert_int_equal(feed(&d, 2100000, c0, 2, ev), 0);
    assert_int_equal(iso_dev_decode_tick(&d, 3000000, ev, 4), 0);
    assert_int_equal(iso_dev_decode_tick(&d, 3100000, ev, 4), 1);
    assert_int_equal(ev[0].t_ns, 3100000);
    assert_int_equal(ev[0].level, 0);
    /* a bounce that comes back before the window ends is never seen */
    assert_int_equal(feed(&d, 3200000, c1, 2, ev), 0);
    assert_int_equal(feed(&d, 3300000, c0, 2, ev), 0);
    assert_int_equal(iso_dev_decode_tick(&d, 9000000, ev, 4), 0);
    /* e-stop: pressing is immediate even inside a window; release waits */
    assert_int_equal(feed(&d, 9000000, e1, 2, ev), 1);
    assert_int_equal(ev[0].line, 1);
    assert_int_equal(feed(&d, 9000100, e0, 2, ev), 0);
    assert_int_equal(feed(&d, 9000200, e1, 2, ev), 0);
    assert_int_equal(feed(&d, 20000000, e0, 2, ev), 0); /* even long after: waits */
    assert_int_equal(iso_dev_decode_tick(&d, 20999999, ev, 4), 0);
    assert_int_equal(iso_dev_decode_tick(&d, 21000000, ev, 4), 1);
    assert_int_equal(ev[0].level, 0);
    /* odd byte and unknown role: counted */
    const uint8_t odd[3] = {7, 1, 0};
    assert_int_equal(feed(&d, 22000000, odd, 3, ev), 0);
    assert_int_equal(d.n.unknown_ids, 1);
    assert_int_equal(d.n.garbage, 1);
    /* after GONE the next reading is an initial level again */
    iso_dev_chunk g = {.t_ns = 23000000, .type = ISO_DEV_CHUNK_GONE};
    assert_int_equal(iso_dev_decode(&d, &g, ev, 4), 1);
    assert_int_equal(ev[0].kind, ISO_DEV_EV_GONE);
    assert_int_equal(feed(&d, 23000001, e1, 2, ev), 1);
}

static void decoder_init_errors(void **state)
{
    (void)state;
    iso_dev_info info;
    memset(&info, 0, sizeof info);
    info.kind = 42;
    strcpy(info.name, "thing");
    iso_dev_decoder d;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_decoder_init(&d, &info, 2, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "source 2 (thing): unknown device kind 42");
    /* events past the caller's capacity are dropped and counted */
    iso_dev_decoder h = dec_of(ISO_DEV_KIND_HID, 0);
    const uint8_t tr[7] = {1, 10, 0, 20, 0, 30, 0};
    iso_dev_chunk c = {.type = ISO_DEV_CHUNK_DATA, .len = 7};
    memcpy(c.data, tr, 7);
    assert_int_equal(iso_dev_decode(&h, &c, NULL, 0), 0);
    assert_int_equal(h.n.garbage, 1);
}

/* ---- mapping ------------------------------------------------------------- */

static iso_twist map1(const iso_dev_map_opts *o, int16_t a0, int16_t a1, int16_t a2, int16_t a3,
                      int16_t a4, int16_t a5)
{
    const int16_t ax[6] = {a0, a1, a2, a3, a4, a5};
    iso_pose g;
    iso_pose_identity(&g);
    iso_twist t;
    iso_dev_map_axes(o, ax, &g, &t);
    return t;
}

static void map_axis_shaping(void **state)
{
    (void)state;
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    iso_twist t = map1(&o, 350, -175, 10, 0, 0, 700);
    assert_true(fabs(t.v[0] - 0.1) < 1e-15);
    assert_true(fabs(t.v[1] + 0.1 * 0.45 / 0.95) < 1e-15);
    assert_true(t.v[2] == 0);                /* 10/350 < 5 % dead zone */
    assert_true(fabs(t.w[2] - 0.5) < 1e-15); /* clamped at full scale */
    o.curve[0] = 2;
    o.dead_zone[0] = 0;
    o.sensitivity[0] = 2;
    t = map1(&o, 175, 0, 0, 0, 0, 0);
    assert_true(fabs(t.v[0] - 2 * 0.25) < 1e-15);
    t = map1(&o, -175, 0, 0, 0, 0, 0);
    assert_true(fabs(t.v[0] + 2 * 0.25) < 1e-15);
    /* remap and invert: output tz reads input ty, inverted */
    iso_dev_map_opts_default(&o);
    o.remap[2] = 1;
    o.invert[2] = 1;
    t = map1(&o, 0, 350, 0, 0, 0, 0);
    assert_true(fabs(t.v[2] + 0.1) < 1e-15);
    assert_true(fabs(t.v[1] - 0.1) < 1e-15);
    /* dominant axis: compares deflections, keeps one */
    iso_dev_map_opts_default(&o);
    o.dominant = 1;
    t = map1(&o, 300, 0, 0, 0, -320, 0);
    assert_true(t.v[0] == 0 && t.w[1] < 0);
    /* locks */
    iso_dev_map_opts_default(&o);
    o.lock = ISO_DEV_LOCK_TRANSLATION;
    t = map1(&o, 350, 0, 0, 350, 0, 0);
    assert_true(t.v[0] > 0 && t.w[0] == 0);
    o.lock = ISO_DEV_LOCK_ROTATION;
    t = map1(&o, 350, 0, 0, 350, 0, 0);
    assert_true(t.v[0] == 0 && t.w[0] > 0);
}

static void map_frames(void **state)
{
    (void)state;
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    for (int i = 0; i < 6; i++)
        o.dead_zone[i] = 0;
    /* a handle at p = (1, 0, 0) turned 90° about z */
    iso_pose g;
    iso_pose_identity(&g);
    const double R[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
    memcpy(g.R, R, sizeof R);
    g.p[0] = 1;
    const int16_t ax[6] = {350, 0, 0, 0, 0, 350};
    iso_twist t;
    iso_dev_map_axes(&o, ax, &g, &t);
    /* world frame: v at the handle is along world x; rotation about the handle */
    double at[3];
    iso_twist_velocity(&t, g.p, at);
    assert_true(fabs(at[0] - 0.1) < 1e-15 && fabs(at[1]) < 1e-15);
    assert_true(fabs(t.w[2] - 0.5) < 1e-15);
    /* device frame: the device's x is the handle's x, which points along world y */
    o.frame = ISO_DEV_FRAME_DEVICE;
    iso_dev_map_axes(&o, ax, &g, &t);
    iso_twist_velocity(&t, g.p, at);
    assert_true(fabs(at[0]) < 1e-15 && fabs(at[1] - 0.1) < 1e-15);
    assert_true(fabs(t.w[2] - 0.5) < 1e-15);
}

static iso_dev_event ev_of(int kind, int src)
{
    iso_dev_event e;
    memset(&e, 0, sizeof e);
    e.kind = (uint8_t)kind;
    e.source = (uint8_t)src;
    return e;
}

static void map_tick_buttons_estop_pose(void **state)
{
    (void)state;
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    o.n_handles = 3;
    o.button_action[2] = ISO_DEV_ACT_RESET_POSE;
    iso_dev_map m;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    iso_pose P[3];
    for (int i = 0; i < 3; i++)
        iso_pose_identity(&P[i]);
    iso_dev_tick t;
    iso_dev_event e[4];
    e[0] = ev_of(ISO_DEV_EV_AXES, 0);
    e[0].axes[0] = 350;
    e[1] = ev_of(ISO_DEV_EV_BUTTONS, 0);
    e[1].buttons = 0x6; /* next handle + reset pose */
    iso_dev_map_tick(&m, e, 2, 1, 1e-3, P, &t);
    assert_int_equal(t.active, 1);
    assert_int_equal(t.actions, (1u << ISO_DEV_ACT_NEXT_HANDLE) | (1u << ISO_DEV_ACT_RESET_POSE));
    assert_true(fabs(t.twist[1].v[0] - 0.1) < 1e-15);
    iso_dev_map_tick(&m, NULL, 0, 2, 1e-3, P, &t); /* held: no new press */
    assert_int_equal(t.actions, 0);
    assert_int_equal(t.active, 1);
    /* e-stop from a GPIO source: zero within this very tick, whatever else */
    e[0] = ev_of(ISO_DEV_EV_GPIO, 1);
    e[0].line = ISO_DEV_GPIO_ESTOP;
    e[0].level = 1;
    iso_dev_map_tick(&m, e, 1, 3, 1e-3, P, &t);
    assert_int_equal(t.estop, 1);
    for (int h = 0; h < 3; h++)
        assert_true(t.twist[h].v[0] == 0 && t.twist[h].w[0] == 0);
    e[0].level = 0;
    iso_dev_map_tick(&m, e, 1, 4, 1e-3, P, &t);
    assert_true(fabs(t.twist[1].v[0] - 0.1) < 1e-15);
    /* deadman clutch: moves only while the clutch is held */
    m.o.clutch_is_deadman = 1;
    iso_dev_map_tick(&m, NULL, 0, 5, 1e-3, P, &t);
    assert_true(t.twist[1].v[0] == 0);
    e[0] = ev_of(ISO_DEV_EV_GPIO, 1);
    e[0].line = ISO_DEV_GPIO_CLUTCH;
    e[0].level = 1;
    iso_dev_map_tick(&m, e, 1, 6, 1e-3, P, &t);
    assert_true(fabs(t.twist[1].v[0] - 0.1) < 1e-15);
    /* a pose stream: the twist that reaches the target in one tick */
    m.o.clutch_is_deadman = 0;
    e[0].level = 0;
    e[1] = ev_of(ISO_DEV_EV_GONE, 0);
    e[2] = ev_of(ISO_DEV_EV_POSE, 2);
    e[2].v[0] = 0.01;
    e[2].v[5] = 0.3; /* 0.3 rad about z */
    P[1].p[1] = 0.02;
    iso_dev_map_tick(&m, e, 3, 7, 0.002, P, &t);
    assert_int_equal(t.gone, 1);
    iso_pose step; /* the handle after one tick: step ∘ P[1] */
    iso_twist_exp(&t.twist[1], 0.002, &step);
    double o0[3] = {0, 0, 0}, y[3], z[3];
    iso_pose_apply(&P[1], o0, y);
    iso_pose_apply(&step, y, z);
    assert_true(fabs(z[0] - 0.01) < 1e-12 && fabs(z[1]) < 1e-12 && fabs(z[2]) < 1e-12);
    assert_true(fabs(t.twist[1].w[2] - 0.3 / 0.002) < 1e-9);
}

/* An e-stop line that goes away (its GPIO chip unplugged, a read error)
 * counts as pressed: its source's GONE stops everything, BACK alone does
 * not release it, the line's next level does. A source that never had an
 * e-stop line stops nothing by going away; two lines: either one pressed. */
static void map_estop_gone_is_pressed(void **state)
{
    (void)state;
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    iso_dev_map m;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    iso_pose P[1];
    iso_pose_identity(&P[0]);
    iso_dev_tick t;
    iso_dev_event e[3];
    e[0] = ev_of(ISO_DEV_EV_AXES, 0); /* a mouse deflected on source 0 */
    e[0].axes[0] = 350;
    e[1] = ev_of(ISO_DEV_EV_GPIO, 1); /* e-stop line on source 1, released */
    e[1].line = ISO_DEV_GPIO_ESTOP;
    e[1].level = 0;
    e[2] = ev_of(ISO_DEV_EV_GPIO, 2); /* a clutch-only GPIO source */
    e[2].line = ISO_DEV_GPIO_CLUTCH;
    e[2].level = 0;
    iso_dev_map_tick(&m, e, 3, 1, 1e-3, P, &t);
    assert_int_equal(t.estop, 0);
    assert_true(t.twist[0].v[0] > 0);
    e[0] = ev_of(ISO_DEV_EV_GONE, 2);
    iso_dev_map_tick(&m, e, 1, 2, 1e-3, P, &t);
    assert_int_equal(t.estop, 0); /* no e-stop line went away */
    e[0] = ev_of(ISO_DEV_EV_GONE, 1);
    iso_dev_map_tick(&m, e, 1, 3, 1e-3, P, &t);
    assert_int_equal(t.estop, 1);
    assert_true(t.twist[0].v[0] == 0);
    e[0] = ev_of(ISO_DEV_EV_BACK, 1);
    iso_dev_map_tick(&m, e, 1, 4, 1e-3, P, &t);
    assert_int_equal(t.estop, 1); /* back, but the line not read yet */
    e[0] = ev_of(ISO_DEV_EV_GPIO, 1);
    e[0].line = ISO_DEV_GPIO_ESTOP;
    e[0].level = 0;
    iso_dev_map_tick(&m, e, 1, 5, 1e-3, P, &t);
    assert_int_equal(t.estop, 0);
    assert_true(t.twist[0].v[0] > 0);
    /* a second e-stop line pressed, the first released: still stopped */
    e[0] = ev_of(ISO_DEV_EV_GPIO, 3);
    e[0].line = ISO_DEV_GPIO_ESTOP;
    e[0].level = 1;
    e[1] = ev_of(ISO_DEV_EV_GPIO, 1);
    e[1].line = ISO_DEV_GPIO_ESTOP;
    e[1].level = 0;
    iso_dev_map_tick(&m, e, 2, 6, 1e-3, P, &t);
    assert_int_equal(t.estop, 1);
}

static void map_init_errors(void **state)
{
    (void)state;
    iso_dev_map_opts o;
    iso_dev_map m;
    iso_err err;
    iso_dev_map_opts_default(&o);
    o.n_handles = 0;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "device mapping: 0 handles (must be 1 to 8)");
    iso_dev_map_opts_default(&o);
    o.remap[3] = 6;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "device mapping: axis 3 remapped to 6 (must be 0 to 5)");
    iso_dev_map_opts_default(&o);
    o.dead_zone[1] = 1;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_EINVAL);
    assert_string_equal(err.msg,
                        "device mapping: dead_zone.ty: expected a value in [0, 0.99], found 1");
    iso_dev_map_opts_default(&o);
    o.curve[5] = 0;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_EINVAL);
    assert_string_equal(err.msg,
                        "device mapping: curve.rz: expected a value in [0.1, 10], found 0");
    iso_dev_map_opts_default(&o);
    o.pose_gain = 0;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "device mapping: pose_gain: expected a value in (0, 1], found 0");
}

/* One range per mapping option (iso_dev_map_check), whoever reads it: the
 * bounds themselves, just outside them, NaN, and a name that is none. */
static void map_ranges_are_one_table(void **state)
{
    (void)state;
    static const struct {
        const char *field;
        double in, out;
    } cases[] = {
        {"full_scale", 1e-9, 0},    {"sensitivity", 1e6, -1e-9}, {"sensitivity", 0, 1.000001e6},
        {"dead_zone", 0.99, 0.991}, {"dead_zone", 0, -0.001},    {"curve", 0.1, 0.099},
        {"curve", 10, 10.001},      {"pose_gain", 1, 1.001},     {"pose_gain", 1e-9, 0},
        {"pose_scale", 1e-9, 0},
    };
    char why[128];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        assert_int_equal(iso_dev_map_check(cases[i].field, cases[i].in, why, sizeof why), 0);
        assert_int_equal(iso_dev_map_check(cases[i].field, cases[i].out, why, sizeof why), -1);
        assert_non_null(strstr(why, "expected a value"));
        assert_int_equal(iso_dev_map_check(cases[i].field, NAN, why, sizeof why), -1);
    }
    assert_int_equal(iso_dev_map_check("curve", 11, why, sizeof why), -1);
    assert_string_equal(why, "expected a value in [0.1, 10], found 11");
    assert_int_equal(iso_dev_map_check("full_scale", -2, why, sizeof why), -1);
    assert_string_equal(why, "expected a value > 0, found -2");
    assert_int_equal(iso_dev_map_check("gain", 1, why, sizeof why), -1);
    assert_string_equal(why, "'gain' is not a numeric mapping option");
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(spacemouse_report_formats),
        cmocka_unit_test(spnav_encoding),
        cmocka_unit_test(gpio_debounce),
        cmocka_unit_test(decoder_init_errors),
        cmocka_unit_test(map_axis_shaping),
        cmocka_unit_test(map_frames),
        cmocka_unit_test(map_tick_buttons_estop_pose),
        cmocka_unit_test(map_estop_gone_is_pressed),
        cmocka_unit_test(map_init_errors),
        cmocka_unit_test(map_ranges_are_one_table),
    };
    return cmocka_run_group_tests_name("dev_decode", t, NULL, NULL);
}
