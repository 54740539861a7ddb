/* tests/test_dev_view.c -- the browser view as a device (devices/iso_dev_view.h,
 * "the browser view's commands"), below the server: the decoder and the
 * mapping on scripted envelopes at exact stream times, and the real view
 * source recorded by a hub and replayed.
 *   - a target within the speed bounds is reached in one tick, to round-off;
 *     one beyond is approached at the bound along the same screw and ends
 *     on it;
 *   - targets only count from the viewer in control, in growing order; the
 *     rest is counted, never applied;
 *   - a quiet controller goes stale after stale_ms (one message, counted)
 *     and its handle holds; release and leaving hold it too;
 *   - the page's stop is an e-stop of its own source: another source's
 *     release does not end it, and nothing commanded before it resumes;
 *   - a session on the real view source, recorded by the hub, replays to
 *     the same commands bit for bit. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "iso_dev_decode.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"
#include "iso_dev_view.h"

#define MS 1000000LL
#define TICK (MS * 50 / 3) /* 60 Hz, to the nanosecond */

typedef struct notes {
    char msg[32][600];
    int n;
} notes;

static void note(void *ctx, const char *msg)
{
    notes *w = ctx;
    if (w->n < 32)
        snprintf(w->msg[w->n], sizeof w->msg[0], "%s", msg);
    w->n++;
}

static int noted(const notes *w, const char *part)
{
    int k = 0;
    for (int i = 0; i < w->n && i < 32; i++)
        k += strstr(w->msg[i], part) != NULL;
    return k;
}

/* An envelope chunk's bytes: what, conn, then a message of `type`. */
static size_t envelope(uint8_t *b, int what, uint32_t conn, int type, uint32_t seq,
                       const double *pose)
{
    b[0] = (uint8_t)what;
    for (int i = 0; i < 4; i++)
        b[1 + i] = (uint8_t)(conn >> (8 * i));
    if (what == ISO_DEV_VIEW_END) {
        b[5] = ISO_DEV_VIEW_END_RELEASED;
        return 6;
    }
    if (what != ISO_DEV_VIEW_MSG)
        return 5;
    iso_dev_view_msg m = {(uint8_t)type, 0, seq, (double)seq, {0}};
    if (pose)
        memcpy(m.pose, pose, sizeof m.pose);
    int n = iso_dev_view_encode(&m, b + 5, ISO_DEV_VIEW_MSG_MAX);
    assert_true(n > 0);
    return 5 + (size_t)n;
}

/* A hub with a scripted view source (and optionally a GPIO one), a
 * mapping for one handle centred at c with the view's bounds. */
typedef struct rig {
    iso_dev_hub *hub;
    iso_dev_source *view, *gpio;
    iso_dev_map map;
    iso_pose pose; /* the handle's commanded pose */
    notes said;
    int64_t t;
} rig;

static void rig_open(rig *r, int with_gpio, double speed, double turn)
{
    memset(r, 0, sizeof *r);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_hub_create(note, &r->said, &r->hub, &err), ISO_OK);
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = ISO_DEV_KIND_VIEW;
    snprintf(in.name, sizeof in.name, "hand");
    assert_int_equal(iso_dev_fake_open(&in, &r->view, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(r->hub, r->view, NULL, NULL, &err), ISO_OK);
    if (with_gpio) {
        in.kind = ISO_DEV_KIND_GPIO;
        snprintf(in.name, sizeof in.name, "gpiochip0");
        assert_int_equal(iso_dev_fake_open(&in, &r->gpio, &err), ISO_OK);
        assert_int_equal(iso_dev_hub_add(r->hub, r->gpio, NULL, NULL, &err), ISO_OK);
    }
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    assert_int_equal(iso_dev_map_init(&r->map, &mo, &err), ISO_OK);
    static const double c[3] = {1, 2, 3};
    iso_dev_map_set_centre(&r->map, 0, c);
    assert_int_equal(iso_dev_map_set_limits(&r->map, 0, speed, turn, &err), ISO_OK);
    iso_pose_identity(&r->pose);
}

static void push(rig *r, int64_t t, int what, uint32_t conn, int type, uint32_t seq,
                 const double *pose)
{
    uint8_t b[ISO_DEV_CHUNK_MAX];
    size_t n = envelope(b, what, conn, type, seq, pose);
    assert_int_equal(iso_dev_fake_push(r->view, t, b, n), ISO_OK);
}

/* One tick at r->t + TICK: the command, and the handle advanced by it. */
static iso_dev_tick step(rig *r)
{
    r->t += TICK;
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
    P[0] = r->pose;
    iso_dev_tick cmd;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_hub_tick(r->hub, &r->map, r->t, TICK * 1e-9, P, &cmd, &err), ISO_OK);
    iso_pose e, n;
    iso_twist_exp(&cmd.twist[0], TICK * 1e-9, &e);
    iso_pose_compose(&e, &r->pose, &n);
    r->pose = n;
    return cmd;
}

static const iso_dev_decoder *dec(const rig *r)
{
    return iso_dev_hub_decoder(r->hub, 0);
}

/* The target's pose as the mapping makes it: exp of the rotation vector,
 * then the position. */
static void target_pose(const double v[6], iso_pose *T)
{
    iso_twist rv = {{v[3], v[4], v[5]}, {0, 0, 0}};
    iso_twist_exp(&rv, 1.0, T);
    memcpy(T->p, v, sizeof T->p);
}

static double pose_gap(const iso_pose *a, const iso_pose *b)
{
    double d = 0;
    for (int i = 0; i < 9; i++)
        d = fmax(d, fabs(a->R[i] - b->R[i]));
    for (int i = 0; i < 3; i++)
        d = fmax(d, fabs(a->p[i] - b->p[i]));
    return d;
}

static void rig_close(rig *r)
{
    iso_dev_hub_destroy(r->hub);
}

static void a_target_is_reached_exactly(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0, 2.0, 6.283185307179586); /* 2 units/s: 33 mm a tick */
    /* near: a turn of 0.037 rad about the centre (1, 2, 3) and a move of 0.027:
     * p = c - R c + t, as the page makes it */
    double near[6] = {0, 0, 0, 0.02, 0.01, -0.03};
    {
        static const double c[3] = {1, 2, 3}, mv[3] = {0.01, -0.02, 0.015};
        iso_pose R;
        target_pose(near, &R);
        double rc[3];
        iso_pose_rotate(&R, c, rc);
        for (int i = 0; i < 3; i++)
            near[i] = c[i] - rc[i] + mv[i];
    }
    push(&r, 0, ISO_DEV_VIEW_GRANT, 7, 0, 0, NULL);
    push(&r, TICK / 2, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TARGET, 1, near);
    iso_dev_tick cmd = step(&r);
    iso_pose T;
    target_pose(near, &T);
    print_message("a near target: after one tick %.3g from it\n", pose_gap(&r.pose, &T));
    assert_true(pose_gap(&r.pose, &T) < 1e-14);
    assert_int_equal(cmd.targeting, 1);
    assert_int_equal(dec(&r)->view.applied_seq, 1);
    assert_int_equal(dec(&r)->view.applied_conn, 7);
    /* a far one: 1 unit away, at most 2 units/s at the centre */
    static const double far[6] = {1.0, 0, 0, 0, 0, 0};
    push(&r, r.t + TICK / 2, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TARGET, 2, far);
    target_pose(far, &T);
    double d0 = 0;
    {
        static const double c[3] = {1, 2, 3};
        double a[3], b[3];
        iso_pose_apply(&r.pose, c, a);
        iso_pose_apply(&T, c, b);
        for (int i = 0; i < 3; i++)
            d0 += (b[i] - a[i]) * (b[i] - a[i]);
        d0 = sqrt(d0);
    }
    int ticks = 0;
    double worst = 0;
    while (pose_gap(&r.pose, &T) > 1e-14 && ticks < 100) {
        double c0[3], c1[3];
        static const double c[3] = {1, 2, 3};
        iso_pose_apply(&r.pose, c, c0);
        /* keep the stream fresh, as a page in control does */
        push(&r, r.t + TICK / 2, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TARGET, (uint32_t)(3 + ticks),
             far);
        step(&r);
        iso_pose_apply(&r.pose, c, c1);
        worst =
            fmax(worst, sqrt((c1[0] - c0[0]) * (c1[0] - c0[0]) + (c1[1] - c0[1]) * (c1[1] - c0[1]) +
                             (c1[2] - c0[2]) * (c1[2] - c0[2])) /
                            (TICK * 1e-9));
        ticks++;
    }
    int least = (int)ceil(d0 / (2.0 * TICK * 1e-9) - 1e-9);
    print_message("a far target (%.4f units, 2 units/s): reached in %d ticks (%d at least), "
                  "fastest %.6f units/s, %.3g from it\n",
                  d0, ticks, least, worst, pose_gap(&r.pose, &T));
    /* at the bound all the way, but for the screw's curve (it turns back
     * the near target's rotation) and the last, shorter tick */
    assert_true(ticks >= least && ticks <= least + 2);
    assert_true(worst <= 2.0 * (1 + 1e-12));
    assert_true(pose_gap(&r.pose, &T) < 1e-14);
    rig_close(&r);
}

static void only_the_controller_in_order_moves_the_handle(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0, 0, 0);
    static const double a[6] = {0.1, 0, 0, 0, 0, 0}, b[6] = {0.2, 0, 0, 0, 0, 0};
    push(&r, TICK / 2, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TARGET, 1, a); /* before any grant */
    step(&r);
    assert_true(r.pose.p[0] == 0);
    push(&r, r.t + 1, ISO_DEV_VIEW_GRANT, 7, 0, 0, NULL);
    push(&r, r.t + 2, ISO_DEV_VIEW_MSG, 8, ISO_DEV_VIEW_TARGET, 1, b); /* another viewer */
    push(&r, r.t + 3, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TARGET, 5, a);
    push(&r, r.t + 4, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TARGET, 5, b);  /* not newer */
    push(&r, r.t + 5, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TARGET, 4, b);  /* older */
    push(&r, r.t + 6, ISO_DEV_VIEW_MSG, 7, ISO_DEV_VIEW_TAKE, 6, NULL); /* the server's to say */
    step(&r);
    const iso_dev_counters *n = &dec(&r)->n;
    print_message("refused %u, out of order %u, applied %u\n", n->refused, n->out_of_order,
                  n->reports);
    assert_true(fabs(r.pose.p[0] - 0.1) < 1e-15);
    assert_int_equal(n->refused, 3);
    assert_int_equal(n->out_of_order, 2);
    assert_int_equal(n->reports, 1);
    assert_int_equal(n->grants, 1);
    rig_close(&r);
}

static void quiet_released_or_gone_it_holds(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0, 0, 0);
    assert_int_equal(iso_dev_map_set_stale(&r.map, 0, 100 * MS, NULL), ISO_OK);
    static const double a[6] = {0.1, 0, 0, 0, 0, 0};
    push(&r, 0, ISO_DEV_VIEW_GRANT, 3, 0, 0, NULL);
    push(&r, TICK / 2, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, 1, a);
    step(&r);
    int64_t last = TICK / 2;
    int stale_at = -1;
    for (int k = 0; k < 12; k++) { /* nothing new: stale strictly past 100 ms */
        iso_dev_tick cmd = step(&r);
        if (cmd.stale && stale_at < 0)
            stale_at = k;
        if (cmd.stale)
            assert_true(r.t - last > 100 * MS);
        else
            assert_true(r.t - last <= 100 * MS);
    }
    iso_dev_source_stats st;
    assert_int_equal(iso_dev_hub_source_stats(r.hub, 0, &st), ISO_OK);
    print_message("stale after %d quiet ticks; said: %s\n", stale_at + 1, r.said.msg[0]);
    assert_int_equal(st.stale, 1);
    assert_int_equal(noted(&r.said, "no command from the page in control"), 1);
    /* it resumes with a fresh sample, then lets go: the handle holds */
    static const double b[6] = {0.2, 0, 0, 0, 0, 0};
    push(&r, r.t + 1, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, 2, b);
    step(&r);
    assert_true(fabs(r.pose.p[0] - 0.2) < 1e-15);
    assert_int_equal(noted(&r.said, "commands resumed"), 1);
    push(&r, r.t + 1, ISO_DEV_VIEW_END, 3, 0, 0, NULL);
    push(&r, r.t + 2, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, 3, a); /* after letting go */
    iso_dev_tick cmd = step(&r);
    assert_true(fabs(r.pose.p[0] - 0.2) < 1e-15);
    assert_int_equal(cmd.targeting, 0);
    assert_int_equal(dec(&r)->n.releases, 1);
    assert_int_equal(noted(&r.said, "control released (the page let go)"), 1);
    rig_close(&r);
}

static void a_page_stop_is_a_stop_of_its_own(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, 0, 0);
    static const double a[6] = {0.1, 0, 0, 0, 0, 0}, b[6] = {0.3, 0, 0, 0, 0, 0};
    uint8_t pair[2] = {ISO_DEV_GPIO_ESTOP, 0};
    assert_int_equal(iso_dev_fake_push(r.gpio, 0, pair, 2), ISO_OK); /* released at start */
    push(&r, 0, ISO_DEV_VIEW_GRANT, 3, 0, 0, NULL);
    push(&r, 1, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, 1, a);
    step(&r);
    assert_true(fabs(r.pose.p[0] - 0.1) < 1e-15);
    push(&r, r.t + 1, ISO_DEV_VIEW_MSG, 9, ISO_DEV_VIEW_STOP, 1, NULL); /* a watcher stops */
    push(&r, r.t + 2, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, 2, b);
    iso_dev_tick cmd = step(&r);
    assert_int_equal(cmd.estop, 1);
    assert_true(fabs(r.pose.p[0] - 0.1) < 1e-15); /* held */
    pair[1] = 1; /* the GPIO e-stop pressed and released meanwhile */
    assert_int_equal(iso_dev_fake_push(r.gpio, r.t + 1, pair, 2), ISO_OK);
    pair[1] = 0;
    assert_int_equal(iso_dev_fake_push(r.gpio, r.t + 2, pair, 2), ISO_OK);
    cmd = step(&r);
    assert_int_equal(cmd.estop, 1); /* the page's stop still stands */
    push(&r, r.t + 1, ISO_DEV_VIEW_MSG, 9, ISO_DEV_VIEW_UNSTOP, 2, NULL);
    cmd = step(&r);
    assert_int_equal(cmd.estop, 0);
    assert_true(fabs(r.pose.p[0] - 0.1) < 1e-15); /* the target from before stays dropped */
    push(&r, r.t + 1, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, 3, b);
    step(&r);
    assert_true(fabs(r.pose.p[0] - 0.3) < 1e-15); /* a fresh one moves it */
    assert_int_equal(noted(&r.said, "STOP pressed in a page"), 1);
    assert_int_equal(noted(&r.said, "stop released in a page"), 1);
    push(&r, r.t + 1, ISO_DEV_VIEW_MSG, 9, ISO_DEV_VIEW_STOP, 3, NULL);
    push(&r, r.t + 2, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_UNSTOP, 4, NULL); /* the one in control */
    cmd = step(&r);
    assert_int_equal(cmd.estop, 0);
    rig_close(&r);
}

/* A target beyond the workspace is refused and counted, never followed
 * part of the way: the handle keeps following the last one within, also
 * for a turn that carries the centre far (one that is not a number never
 * reaches the mapping: the decoder refuses it). */
static void a_target_beyond_the_workspace_is_refused(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0, 0, 0);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_map_set_workspace(&r.map, 0, 2.0, &err), ISO_OK);
    assert_int_equal(iso_dev_map_set_workspace(&r.map, 0, -1, &err), ISO_EINVAL);
    static const double near[6] = {1.5, 0, 0, 0, 0, 0}, far[6] = {1e12, 0, 0, 0, 0, 0};
    /* a half turn about x through the origin carries the centre (1, 2, 3)
     * to (1, -2, -3): 7.2 away */
    static const double turned[6] = {0, 0, 0, 3.141592653589793, 0, 0};
    const double nan_pose[6] = {NAN, 0, 0, 0, 0, 0};
    push(&r, 0, ISO_DEV_VIEW_GRANT, 3, 0, 0, NULL);
    push(&r, 1, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, 1, near);
    step(&r);
    assert_true(fabs(r.pose.p[0] - 1.5) < 1e-12);
    uint32_t seq = 2, bad = dec(&r)->n.bad_frames;
    for (int k = 0; k < 3; k++) {
        const double *v = k == 0 ? far : k == 1 ? turned : nan_pose;
        push(&r, r.t + 1, ISO_DEV_VIEW_MSG, 3, ISO_DEV_VIEW_TARGET, seq++, v);
        step(&r);
        step(&r);
        assert_true(fabs(r.pose.p[0] - 1.5) < 1e-12); /* still on the last target within */
    }
    assert_int_equal(r.map.far[0], 2);
    assert_int_equal(dec(&r)->n.bad_frames, bad + 1); /* NaN: refused before, by the decoder */
    rig_close(&r);
}

/* The real source on its own clock, pushed from another thread's point of
 * view as the server would, recorded by the hub, then replayed. */
static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 0x100000001b3ULL;
    return h;
}

static void a_recorded_session_replays_bit_for_bit(void **state)
{
    (void)state;
    char path[512];
    iso_test_tmp(path, sizeof path, "view_session.isorec");
    iso_err err;
    iso_err_clear(&err);
    iso_dev_hub *hub;
    iso_dev_source *src;
    notes said = {{{0}}, 0};
    assert_int_equal(iso_dev_hub_create(note, &said, &hub, &err), ISO_OK);
    assert_int_equal(iso_dev_view_open("hand", &src, &err), ISO_OK);
    iso_dev_source *pusher = src; /* the hub owns it; the "server" keeps pushing */
    assert_int_equal(iso_dev_hub_add(hub, src, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_record_start(hub, path, &err), ISO_OK);
    iso_dev_map map;
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    assert_int_equal(iso_dev_map_init(&map, &mo, &err), ISO_OK);
    assert_int_equal(iso_dev_map_set_limits(&map, 0, 1.0, 3.0, &err), ISO_OK);
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
    uint64_t live = 0xcbf29ce484222325ULL;
    int64_t t = iso_clock_ns();
    uint8_t msg[ISO_DEV_VIEW_MSG_MAX];
    assert_int_equal(iso_dev_view_push(pusher, ISO_DEV_VIEW_GRANT, 4, NULL, 0), ISO_OK);
    for (int k = 0; k < 40; k++) {
        iso_dev_view_msg m = {ISO_DEV_VIEW_TARGET, 0, (uint32_t)(k + 1), k * 16.7, {0}};
        m.pose[0] = 0.01 * k;
        m.pose[5] = 0.02 * k;
        int n = iso_dev_view_encode(&m, msg, sizeof msg);
        assert_int_equal(iso_dev_view_push(pusher, ISO_DEV_VIEW_MSG, 4, msg, (size_t)n), ISO_OK);
        if (k == 20) {
            m.type = ISO_DEV_VIEW_STOP;
            n = iso_dev_view_encode(&m, msg, sizeof msg);
            assert_int_equal(iso_dev_view_push(pusher, ISO_DEV_VIEW_MSG, 9, msg, (size_t)n),
                             ISO_OK);
            assert_int_equal(pusher->ops->estop_level(pusher), 1);
        }
        struct timespec ts = {0, 3 * 1000 * 1000};
        nanosleep(&ts, NULL);
        t += 5 * MS;
        int64_t now = iso_clock_ns();
        if (t < now)
            t = now;
        iso_dev_tick cmd;
        assert_int_equal(iso_dev_hub_tick(hub, &map, t, 0.005, P, &cmd, &err), ISO_OK);
        live = fnv(live, &cmd, sizeof cmd);
        iso_pose e, g;
        iso_twist_exp(&cmd.twist[0], 0.005, &e);
        iso_pose_compose(&e, &P[0], &g);
        P[0] = g;
    }
    assert_int_equal(iso_dev_hub_record_stop(hub, &err), ISO_OK);
    iso_dev_hub_destroy(hub);

    iso_dev_rec_reader rd;
    assert_int_equal(iso_dev_rec_reader_load(&rd, path, &err), ISO_OK);
    assert_int_equal(rd.n_sources, 1);
    assert_int_equal(rd.infos[0].kind, ISO_DEV_KIND_VIEW);
    assert_int_equal(iso_dev_hub_create(NULL, NULL, &hub, &err), ISO_OK);
    assert_int_equal(iso_dev_replay_open(&rd, &src, &err), ISO_OK);
    assert_int_equal(iso_dev_hub_add(hub, src, NULL, NULL, &err), ISO_OK);
    assert_int_equal(iso_dev_map_init(&map, &mo, &err), ISO_OK);
    assert_int_equal(iso_dev_map_set_limits(&map, 0, 1.0, 3.0, &err), ISO_OK);
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
    uint64_t again = 0xcbf29ce484222325ULL;
    int ticks = 0;
    for (int64_t tt; (tt = iso_dev_hub_next_tick(hub, 5 * MS)) != INT64_MAX; ticks++) {
        iso_dev_tick cmd;
        assert_int_equal(iso_dev_hub_tick(hub, &map, tt, 0.005, P, &cmd, &err), ISO_OK);
        again = fnv(again, &cmd, sizeof cmd);
        iso_pose e, g;
        iso_twist_exp(&cmd.twist[0], 0.005, &e);
        iso_pose_compose(&e, &P[0], &g);
        P[0] = g;
    }
    print_message("40 ticks live, %d replayed: commands %016llx and %016llx; said live: %d lines\n",
                  ticks, (unsigned long long)live, (unsigned long long)again, said.n);
    assert_int_equal(ticks, 40);
    assert_true(live == again);
    iso_dev_hub_destroy(hub);
    iso_dev_rec_reader_deinit(&rd);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(a_target_is_reached_exactly),
        cmocka_unit_test(only_the_controller_in_order_moves_the_handle),
        cmocka_unit_test(quiet_released_or_gone_it_holds),
        cmocka_unit_test(a_page_stop_is_a_stop_of_its_own),
        cmocka_unit_test(a_target_beyond_the_workspace_is_refused),
        cmocka_unit_test(a_recorded_session_replays_bit_for_bit),
    };
    return cmocka_run_group_tests_name("dev_view", t, NULL, NULL);
}
