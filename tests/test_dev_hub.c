/* tests/test_dev_hub.c -- the hub with scripted fake sources: unplug and
 * replug (one message each, handles hold still, picked up again without a
 * restart), the e-stop within one tick, the per-tick trigger pulse, and a
 * live run recorded and replayed to bit-identical tick commands. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "iso_dev_decode.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"
#include "testutil.h"

#define MS 1000000LL
#define TICKS 40

typedef struct world {
    char msgs[8][600];
    int nmsg;
    int reopen_calls;
    int64_t back_at; /* the fake device can be opened again from this time */
    int64_t now;
    iso_dev_source *hid2; /* what reopen hands out */
} world;

static void note(void *ctx, const char *msg)
{
    world *w = ctx;
    if (w->nmsg < 8)
        snprintf(w->msgs[w->nmsg], sizeof w->msgs[0], "%s", msg);
    w->nmsg++;
}

static int reopen(void *ctx, const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    world *w = ctx;
    (void)info;
    w->reopen_calls++;
    if (w->now < w->back_at || !w->hid2)
        return iso_err_set(err, ISO_EIO, -1, "not there");
    *out = w->hid2;
    w->hid2 = NULL;
    return ISO_OK;
}

static void hid_report(iso_dev_source *s, int64_t t, int16_t tx)
{
    uint8_t r[13] = {1, (uint8_t)(tx & 0xff), (uint8_t)((uint16_t)tx >> 8)};
    assert_int_equal(iso_dev_fake_push(s, t, r, sizeof r), ISO_OK);
}

static iso_dev_source *fake(int kind, const char *name, uint32_t debounce_us)
{
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = (uint8_t)kind;
    in.vid = kind == ISO_DEV_KIND_HID ? 0x256f : 0;
    in.pid = kind == ISO_DEV_KIND_HID ? 0xc635 : 0;
    in.debounce_us = debounce_us;
    snprintf(in.name, sizeof in.name, "%s", name);
    iso_dev_source *s;
    assert_int_equal(iso_dev_fake_open(&in, &s, NULL), ISO_OK);
    return s;
}

static void live_unplug_replug_record_replay(void **state)
{
    (void)state;
    static world w;
    memset(&w, 0, sizeof w);
    iso_err err;
    iso_err_clear(&err);
    iso_dev_hub *h;
    assert_int_equal(iso_dev_hub_create(note, &w, &h, &err), ISO_OK);
    iso_dev_hub_set_retry(h, 3 * MS);
    iso_dev_source *hid = fake(ISO_DEV_KIND_HID, "/dev/hidraw7", 0);
    iso_dev_source *gpio = fake(ISO_DEV_KIND_GPIO, "gpiochip0", 1000);
    hid_report(hid, 1 * MS + 5, 350);
    assert_int_equal(iso_dev_fake_push_gone(hid, 10 * MS + 1), ISO_OK);
    w.hid2 = fake(ISO_DEV_KIND_HID, "/dev/hidraw7", 0);
    w.back_at = 20 * MS;
    hid_report(w.hid2, 25 * MS + 3, -175);
    const uint8_t init[4] = {0, 0, 1, 0}, press[2] = {1, 1}, rel[2] = {1, 0};
    assert_int_equal(iso_dev_fake_push(gpio, 0, init, 4), ISO_OK);
    assert_int_equal(iso_dev_fake_push(gpio, 30 * MS + 500, press, 2), ISO_OK);
    assert_int_equal(iso_dev_fake_push(gpio, 33 * MS, rel, 2), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, hid, reopen, &w, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, gpio, NULL, NULL, &err), ISO_OK);
    char path[1024];
    iso_test_tmp(path, sizeof path, "dev_hub_live.isorec");
    assert_int_equal(iso_dev_hub_record_start(h, path, &err), ISO_OK);

    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    iso_dev_map m;
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
    static iso_dev_tick live[TICKS];
    for (int k = 0; k < TICKS; k++) {
        w.now = (k + 1) * MS;
        assert_int_equal(iso_dev_hub_tick(h, &m, w.now, 1e-3, P, &live[k], &err), ISO_OK);
        assert_int_equal(iso_dev_hub_sync(h, 2000), 1); /* a reopen asked for is answered */
    }
    int last_level = -1;
    assert_int_equal(iso_dev_fake_writes(gpio, &last_level), 2 * TICKS); /* one pulse a tick */
    assert_int_equal(last_level, 0);
    assert_int_equal(iso_dev_hub_record_stop(h, &err), ISO_OK);
    iso_dev_hub_destroy(h);

    /* ticks 2..9 move; 10 is the unplug: still from that tick on, one message */
    assert_true(live[0].twist[0].v[0] == 0);
    assert_true(fabs(live[1].twist[0].v[0] - 0.1) < 1e-15);
    assert_true(fabs(live[9].twist[0].v[0] - 0.1) < 1e-15);
    assert_true(live[10].twist[0].v[0] == 0);
    assert_int_equal(live[10].gone, 1);
    assert_int_equal(w.nmsg, 2);
    assert_string_equal(w.msgs[0], "hid /dev/hidraw7 went away (/dev/hidraw7: device unplugged "
                                   "(fake)): its handles hold still until it is back");
    assert_string_equal(w.msgs[1], "hid /dev/hidraw7 is back");
    /* retried every 3 ms from the unplug at tick 11: asked at 14, 17, 20,
     * each answer taken a tick later (the reopen is the hub's thread's, not
     * the tick's): back at 21 */
    assert_int_equal(w.reopen_calls, 3);
    assert_int_equal(live[19].gone, 1);
    assert_int_equal(live[20].gone, 0);
    assert_true(live[20].twist[0].v[0] == 0);
    assert_true(fabs(live[25].twist[0].v[0] + 0.1 * 0.45 / 0.95) < 1e-15);
    /* e-stop pressed at 30.0005 ms: zero in tick 31 itself; released at 33,
     * taken once stable for the 1 ms debounce (tick 34) */
    assert_int_equal(live[29].estop, 0);
    assert_int_equal(live[30].estop, 1);
    assert_true(live[30].twist[0].v[0] == 0);
    assert_int_equal(live[32].estop, 1);
    assert_int_equal(live[33].estop, 0);
    assert_true(live[33].twist[0].v[0] != 0);

    /* The recording replays to the same commands, bit for bit. */
    iso_dev_rec_reader r;
    assert_int_equal(iso_dev_rec_reader_load(&r, path, &err), ISO_OK);
    assert_int_equal(r.n_sources, 2);
    assert_int_equal(r.infos[0].vid, 0x256f);
    iso_dev_source *rs;
    assert_int_equal(iso_dev_replay_open(&r, &rs, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_create(NULL, NULL, &h, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, rs, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    static iso_dev_tick again[TICKS];
    int n = 0;
    for (int64_t t; (t = iso_dev_hub_next_tick(h, MS)) != INT64_MAX && n < TICKS; n++)
        assert_int_equal(iso_dev_hub_tick(h, &m, t, 1e-3, P, &again[n], &err), ISO_OK);
    assert_int_equal(n, TICKS);
    assert_memory_equal(live, again, sizeof live);
    assert_int_equal(iso_dev_hub_replay_done(h), 1);
    iso_dev_hub_destroy(h);
    iso_dev_rec_reader_deinit(&r);
}

static void hub_refuses_mixing_replay_and_live(void **state)
{
    (void)state;
    iso_dev_hub *h;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_hub_create(NULL, NULL, &h, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, fake(ISO_DEV_KIND_HID, "a", 0), NULL, NULL, &err), ISO_OK);
    iso_dev_rec_reader r;
    memset(&r, 0, sizeof r);
    iso_dev_source *rs;
    assert_int_equal(iso_dev_replay_open(&r, &rs, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(h, rs, NULL, NULL, &err), ISO_EINVAL);
    assert_string_equal(err.msg, "device hub: a replay must be the hub's only source");
    /* drain with a small buffer hands the rest out next time, in order */
    iso_dev_hub_destroy(h);
    assert_int_equal(iso_dev_hub_create(NULL, NULL, &h, &err), ISO_OK);
    iso_dev_source *s = fake(ISO_DEV_KIND_HID, "b", 0);
    for (int k = 0; k < 5; k++)
        hid_report(s, k, (int16_t)(k + 1));
    assert_int_equal(iso_dev_hub_add(h, s, NULL, NULL, &err), ISO_OK);
    iso_dev_event ev[2];
    size_t n, seen = 0;
    for (int round = 0; round < 3; round++) {
        assert_int_equal(iso_dev_hub_drain(h, 10, ev, 2, &n, &err), ISO_OK);
        assert_int_equal(n, round < 2 ? 2 : 1);
        for (size_t k = 0; k < n; k++)
            assert_int_equal(ev[k].axes[0], (int)(++seen));
    }
    assert_int_equal(iso_dev_hub_drain(h, 10, ev, 2, &n, &err), ISO_OK);
    assert_int_equal(n, 0);
    iso_dev_hub_destroy(h);
}

/* A device that takes 300 ms to open again (a USB hub enumerating) costs
 * the tick nothing: the reopen runs on the hub's own thread, every tick in
 * the meantime returns at once with the source still gone, and the source
 * is back on the first tick after the open finished. */
typedef struct slow_world {
    pthread_t tick_thread, reopen_thread;
    iso_dev_source *next;
} slow_world;

static int slow_reopen(void *ctx, const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    slow_world *w = ctx;
    (void)info;
    (void)err;
    w->reopen_thread = pthread_self();
    struct timespec ts = {0, 300 * 1000 * 1000};
    nanosleep(&ts, NULL);
    *out = w->next;
    w->next = NULL;
    return ISO_OK;
}

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

static void a_slow_reopen_costs_the_tick_nothing(void **state)
{
    (void)state;
    static slow_world w;
    iso_err err;
    iso_err_clear(&err);
    iso_dev_hub *h;
    assert_int_equal(iso_dev_hub_create(NULL, NULL, &h, &err), ISO_OK);
    iso_dev_hub_set_retry(h, 1 * MS);
    iso_dev_source *hid = fake(ISO_DEV_KIND_HID, "/dev/hidraw7", 0);
    assert_int_equal(iso_dev_fake_push_gone(hid, 1 * MS), ISO_OK);
    w.next = fake(ISO_DEV_KIND_HID, "/dev/hidraw7", 0);
    w.tick_thread = pthread_self();
    assert_int_equal(iso_dev_hub_add(h, hid, slow_reopen, &w, &err), ISO_OK);
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    static iso_dev_map m;
    assert_int_equal(iso_dev_map_init(&m, &o, &err), ISO_OK);
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
    double worst = 0, t0 = now_ms();
    int k = 0, back_at = -1;
    iso_dev_tick t;
    for (; k < 2000 && back_at < 0; k++) { /* ticks every 1 ms of wall time */
        double a = now_ms();
        assert_int_equal(iso_dev_hub_tick(h, &m, (k + 1) * MS, 1e-3, P, &t, &err), ISO_OK);
        double b = now_ms();
        worst = b - a > worst ? b - a : worst;
        if (k > 2 && !t.gone)
            back_at = k;
        struct timespec ts = {0, 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    print_message("a 300 ms reopen: back after %.0f ms of ticks (%d ticks), the slowest tick "
                  "%.3f ms\n",
                  now_ms() - t0, back_at, worst);
    assert_true(back_at > 0);
    assert_true(now_ms() - t0 >= 300); /* it did wait for the open */
    assert_true(worst < 100);          /* no tick waited for it */
    assert_false(pthread_equal(w.reopen_thread, w.tick_thread));
    iso_dev_hub_destroy(h);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(live_unplug_replug_record_replay),
        cmocka_unit_test(a_slow_reopen_costs_the_tick_nothing),
        cmocka_unit_test(hub_refuses_mixing_replay_and_live),
    };
    return cmocka_run_group_tests_name("dev_hub", t, NULL, NULL);
}
