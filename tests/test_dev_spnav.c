/* tests/test_dev_spnav.c -- the spacenavd backend through the real libspnav,
 * against a small spacenavd stand-in on a unix socket in a temporary folder
 * ($SPNAV_SOCKET points at it): events flow; the stand-in is killed and the
 * hub says GONE once, at once; it is started again and the next retry
 * brings the source BACK, events flowing again. A stand-in that says it
 * serves a SpaceNavigator: the axes come back in the device's frame, and a
 * cap gone quiet is reported at rest. */
#define _DEFAULT_SOURCE /* mkdtemp, usleep */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include "iso_dev_axes.h"
#include "iso_dev_enum.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_source.h"
#include "testutil.h"

#define MS 1000000LL

/* ---- a spacenavd stand-in ------------------------------------------------ */
/* What libspnav (1.0/1.1) expects of the daemon on its unix socket, as its
 * protocol is documented (spacenavd's proto.h) and as libspnav behaves:
 * the client first writes one native 32-bit word, 0x7faa5500 | version
 * (REQ_TAG | REQ_CHANGE_PROTO); the daemon answers with the version it
 * grants, in the same form (v1 here). Events then come as eight native
 * int32: type (0 motion, 1 press, 2 release), then for motion x y z rx ry rz
 * and the period in ms. A client that closes without asking (a probe
 * whether anyone listens) is dropped. */
enum { SPNAV_PROTO_REQ = 0x7faa5500, SPNAV_UEV_MOTION = 0 };

static void standin_serve(int ls, int32_t tx)
{
    signal(SIGPIPE, SIG_IGN);
    for (;;) {
        int c = accept(ls, NULL, NULL);
        if (c < 0)
            continue;
        struct pollfd p = {c, POLLIN, 0};
        int32_t w = 0;
        if (poll(&p, 1, 1000) != 1 || read(c, &w, sizeof w) != (ssize_t)sizeof w ||
            ((uint32_t)w & 0xffffff00u) != SPNAV_PROTO_REQ) {
            close(c);
            continue;
        }
        w = SPNAV_PROTO_REQ | 1;
        if (write(c, &w, sizeof w) != (ssize_t)sizeof w) {
            close(c);
            continue;
        }
        for (;;) { /* a deflected puck: motion events every 5 ms */
            const int32_t ev[8] = {SPNAV_UEV_MOTION, tx, 0, 0, 0, 0, 0, 5};
            if (write(c, ev, sizeof ev) != (ssize_t)sizeof ev)
                break;
            usleep(5000);
        }
        close(c);
    }
}

/* Protocol 1 requests (spacenavd's proto.h): eight native int32, the type
 * REQ_TAG | request, the answer the same with data[0..5] and the status in
 * the last word. This stand-in knows the USB id (a SpaceNavigator) and
 * answers every other request with failure. */
enum { SPNAV_REQ_TAG = 0x7faa0000, SPNAV_REQ_DEV_USBID = 0x2004, SPNAV_REQ_DEV_PATH = 0x2001 };

static int standin_answer(int c)
{
    int32_t rr[8];
    struct pollfd p = {c, POLLIN, 0};
    if (poll(&p, 1, 1000) != 1 || read(c, rr, sizeof rr) != (ssize_t)sizeof rr)
        return -1;
    int req = rr[0] & 0xffff;
    memset(rr + 1, 0, sizeof rr - sizeof rr[0]);
    if (req == SPNAV_REQ_DEV_USBID) {
        rr[1] = 0x046d;
        rr[2] = 0xc626;
    } else {
        rr[7] = -1;
    }
    if (write(c, rr, sizeof rr) != (ssize_t)sizeof rr)
        return -1;
    return req;
}

/* Serves one client a script: the device's id and path asked (the path not
 * known), then a motion three times, 400 ms of silence, the same motion
 * with only x changed (spacenavd's kept values in the rest), silence. */
static void standin_script(int ls)
{
    signal(SIGPIPE, SIG_IGN);
    int c;
    int32_t w = 0;
    for (;;) { /* the backend's probe whether anyone listens comes first */
        c = accept(ls, NULL, NULL);
        if (c >= 0 && read(c, &w, sizeof w) == (ssize_t)sizeof w)
            break;
        if (c >= 0)
            close(c);
    }
    w = SPNAV_PROTO_REQ | 1;
    if (write(c, &w, sizeof w) != (ssize_t)sizeof w)
        _exit(1);
    int req;
    do
        req = standin_answer(c);
    while (req >= 0 && req != SPNAV_REQ_DEV_PATH);
    const int32_t a[8] = {SPNAV_UEV_MOTION, 10, 20, 30, 40, 50, 60, 5};
    for (int i = 0; i < 3; i++) {
        if (write(c, a, sizeof a) != (ssize_t)sizeof a)
            _exit(1);
        usleep(5000);
    }
    usleep(400000);
    const int32_t b[8] = {SPNAV_UEV_MOTION, 15, 20, 30, 40, 50, 60, 400};
    if (write(c, b, sizeof b) != (ssize_t)sizeof b)
        _exit(1);
    pause();
}

/* Binds and listens here, then serves in a child: the socket accepts before
 * this returns, so there is no race with the first connect. tx < 0: the
 * script of standin_script. */
static pid_t standin_start(const char *path, int32_t tx)
{
    int ls = socket(AF_UNIX, SOCK_STREAM, 0);
    assert_true(ls >= 0);
    struct sockaddr_un a;
    memset(&a, 0, sizeof a);
    a.sun_family = AF_UNIX;
    assert_true(strlen(path) < sizeof a.sun_path);
    memcpy(a.sun_path, path, strlen(path) + 1);
    unlink(path);
    assert_int_equal(bind(ls, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(listen(ls, 8), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        if (tx < 0)
            standin_script(ls);
        else
            standin_serve(ls, tx);
        _exit(0);
    }
    close(ls);
    return pid;
}

static void standin_kill(pid_t pid)
{
    kill(pid, SIGKILL);
    while (waitpid(pid, NULL, 0) < 0 && errno == EINTR)
        ;
}

/* ---- the hub around it --------------------------------------------------- */

typedef struct notes {
    char msg[8][600];
    int n;
} notes;

static void note(void *ctx, const char *msg)
{
    notes *w = ctx;
    if (w->n < 8)
        snprintf(w->msg[w->n], sizeof w->msg[0], "%s", msg);
    w->n++;
}

static int reopen_spnav(void *ctx, const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    (void)ctx;
    (void)info;
    return iso_dev_spnav_open(out, err);
}

typedef struct rig {
    iso_dev_hub *h;
    iso_dev_map m;
    iso_pose P[ISO_DEV_MAX_HANDLES];
    iso_dev_tick out;
} rig;

/* Ticks every 5 ms of wall time until done(out) or limit_ms passed; returns
 * the milliseconds it took, or -1. */
static double tick_until(rig *r, int (*done)(const iso_dev_tick *), double limit_ms)
{
    int64_t t0 = iso_clock_ns();
    for (;;) {
        iso_err err;
        iso_err_clear(&err);
        int64_t now = iso_clock_ns();
        assert_int_equal(iso_dev_hub_tick(r->h, &r->m, now, 5e-3, r->P, &r->out, &err), ISO_OK);
        if (done(&r->out))
            return (double)(now - t0) / 1e6;
        if (now - t0 > (int64_t)(limit_ms * 1e6))
            return -1;
        usleep(5000);
    }
}

static int moving(const iso_dev_tick *t)
{
    return !(t->gone & 1) && t->twist[0].v[0] > 0;
}
static int gone(const iso_dev_tick *t)
{
    return (t->gone & 1) && t->twist[0].v[0] == 0;
}
static int never(const iso_dev_tick *t)
{
    (void)t;
    return 0;
}

static void daemon_killed_and_restarted(void **state)
{
    (void)state;
    if (iso_dev_backend_built("spnav") != 1) {
        print_message("skipped: libspnav is not built in (libspnav-dev missing)\n");
        skip();
    }
    char dir[] = "/tmp/iso_spnav_XXXXXX", path[64];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/spnav.sock", dir);
    assert_int_equal(setenv("SPNAV_SOCKET", path, 1), 0);

    pid_t pid = standin_start(path, 175);
    iso_dev_source *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_spnav_open(&s, &err), ISO_OK);
    assert_string_equal(s->detail, path); /* SPNAV_SOCKET was honoured */
    static rig r;
    static notes w;
    memset(&w, 0, sizeof w);
    assert_int_equal(iso_dev_hub_create(note, &w, &r.h, &err), ISO_OK);
    const int64_t retry = 100 * MS;
    iso_dev_hub_set_retry(r.h, retry);
    assert_int_equal(iso_dev_hub_add(r.h, s, reopen_spnav, NULL, &err), ISO_OK);
    iso_dev_map_opts o;
    iso_dev_map_opts_default(&o);
    assert_int_equal(iso_dev_map_init(&r.m, &o, &err), ISO_OK);
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&r.P[i]);

    double first = tick_until(&r, moving, 2000);
    assert_true(first >= 0);
    /* half deflection past the 5 % dead zone: 0.1 m/s * 0.45 / 0.95 */
    assert_true(r.out.twist[0].v[0] > 0.04 && r.out.twist[0].v[0] < 0.05);
    assert_int_equal(w.n, 0);

    standin_kill(pid);
    double gone_ms = tick_until(&r, gone, 2000);
    assert_true(gone_ms >= 0);
    assert_true(gone_ms * MS < (double)retry); /* the end of the connection, not a timeout */
    assert_int_equal(w.n, 1);
    assert_non_null(strstr(w.msg[0], "spnav spacenavd went away"));
    assert_non_null(strstr(w.msg[0], path));
    assert_non_null(strstr(w.msg[0], "its handles hold still"));

    /* several retries with nobody listening: still gone, nothing more said */
    tick_until(&r, never, 350);
    assert_true(gone(&r.out));
    assert_int_equal(w.n, 1);

    pid = standin_start(path, 175);
    double back_ms = tick_until(&r, moving, 2000);
    assert_true(back_ms >= 0);
    assert_true(back_ms * MS < (double)retry + 400 * MS); /* the next retry, with slack */
    assert_int_equal(w.n, 2);
    assert_string_equal(w.msg[1], "spnav spacenavd is back");
    printf("spnav: moving %.0f ms after open; GONE %.1f ms after the kill; moving again %.0f "
           "ms after the restart (retry every %lld ms)\n",
           first, gone_ms, back_ms, (long long)(retry / MS));

    iso_dev_hub_destroy(r.h);
    standin_kill(pid);
    unlink(path);
    rmdir(dir);
    unsetenv("SPNAV_SOCKET");
}

/* The next 'M' record from the source within limit_ms: its six axes and
 * when it came; -1 if none. */
static int next_motion(iso_dev_source *s, int16_t ax[6], int64_t *t, double limit_ms)
{
    int64_t t0 = iso_clock_ns();
    while (iso_clock_ns() - t0 < (int64_t)(limit_ms * 1e6)) {
        iso_dev_chunk c;
        iso_err err;
        iso_err_clear(&err);
        int got = iso_dev_source_read(s, iso_clock_ns(), &c, &err);
        assert_true(got >= 0);
        if (got == 1 && c.len >= 15 && c.data[0] == 'M') {
            for (int i = 0; i < 6; i++)
                ax[i] = (int16_t)(uint16_t)(c.data[1 + 2 * i] | c.data[2 + 2 * i] << 8);
            *t = c.t_ns;
            return 0;
        }
        usleep(5000);
    }
    return -1;
}

/* spacenavd says it serves a SpaceNavigator (whose Y/Z it swaps and
 * negates); its evdev node is not known, so the axes count as relative.
 * The motion comes back in the device's frame; when it stops, rest is
 * reported once, 200 ms on; the values spacenavd keeps from before count
 * as 0 in its next event, and only the axis that changed moves. Both ways
 * of seeing the silence: reads that find nothing for 200 ms, and the
 * period of the motion after it. */
static void device_frame_and_inferred_rest(void **state)
{
    (void)state;
    if (iso_dev_backend_built("spnav") != 1) {
        print_message("skipped: libspnav is not built in (libspnav-dev missing)\n");
        skip();
    }
    char dir[] = "/tmp/iso_spnav_XXXXXX", path[64];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/spnav.sock", dir);
    assert_int_equal(setenv("SPNAV_SOCKET", path, 1), 0);
    pid_t pid = standin_start(path, -1);
    iso_dev_source *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_spnav_open(&s, &err), ISO_OK);
    assert_int_equal(s->info.vid, 0x046d);
    assert_int_equal(s->info.pid, 0xc626);

    int16_t ax[6];
    int64_t t_move = 0, t_rest = 0, t;
    assert_int_equal(next_motion(s, ax, &t_move, 2000), 0);
    const int16_t device[6] = {10, -30, -20, 40, -60, -50};
    assert_memory_equal(ax, device, sizeof device);
    do /* the same motion twice more, then rest */
        assert_int_equal(next_motion(s, ax, &t_rest, 2000), 0);
    while (ax[0] == 10);
    const int16_t rest[6] = {0};
    assert_memory_equal(ax, rest, sizeof rest);
    double quiet_ms = (double)(t_rest - t_move) / 1e6;
    assert_true(quiet_ms >= ISO_DEV_SPNAV_REST_NS / 1e6);
    assert_int_equal(next_motion(s, ax, &t, 2000), 0);
    const int16_t x_only[6] = {15, 0, 0, 0, 0, 0};
    assert_memory_equal(ax, x_only, sizeof x_only);
    printf("spnav: rest reported %.0f ms after the first motion (inferred after %.0f ms of "
           "silence)\n",
           quiet_ms, ISO_DEV_SPNAV_REST_NS / 1e6);
    iso_dev_source_close(s);
    standin_kill(pid);

    /* Again, reading nothing through the silence (a tick that takes
     * longer than it): spacenavd's period on the next motion says there
     * was one, and rest comes before that motion in the same read. */
    pid = standin_start(path, -1);
    assert_int_equal(iso_dev_spnav_open(&s, &err), ISO_OK);
    assert_int_equal(next_motion(s, ax, &t_move, 2000), 0);
    usleep(800000);
    iso_dev_chunk c;
    assert_int_equal(iso_dev_source_read(s, iso_clock_ns(), &c, &err), 1);
    int16_t seen[8][6];
    int n = 0;
    for (unsigned i = 0; i + 15 <= c.len && n < 8; i += 15) {
        assert_int_equal(c.data[i], 'M');
        for (int k = 0; k < 6; k++)
            seen[n][k] = (int16_t)(uint16_t)(c.data[i + 1 + 2 * k] | c.data[i + 2 + 2 * k] << 8);
        n++;
    }
    /* the motion's repeats the first read left, then rest, then x alone */
    assert_true(n >= 2 && n <= 4);
    for (int k = 0; k < n - 2; k++)
        assert_memory_equal(seen[k], device, sizeof device);
    assert_memory_equal(seen[n - 2], rest, sizeof rest);
    assert_memory_equal(seen[n - 1], x_only, sizeof x_only);
    iso_dev_source_close(s);
    standin_kill(pid);
    unlink(path);
    rmdir(dir);
    unsetenv("SPNAV_SOCKET");
}

/* Nothing listens where SPNAV_SOCKET points (and at the default): an error
 * that names the socket. */
static void no_daemon_names_the_socket(void **state)
{
    (void)state;
    if (iso_dev_backend_built("spnav") != 1) {
        print_message("skipped: libspnav is not built in (libspnav-dev missing)\n");
        skip();
    }
    assert_int_equal(setenv("SPNAV_SOCKET", "/tmp/iso-no-such-dir/spnav.sock", 1), 0);
    iso_dev_source *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_dev_spnav_open(&s, &err);
    if (rc == ISO_OK) { /* a real spacenavd answers on the default socket */
        iso_dev_source_close(s);
    } else {
        assert_int_equal(rc, ISO_EIO);
        assert_null(s);
        assert_non_null(strstr(err.msg, "spacenavd is not running"));
        assert_non_null(strstr(err.msg, "/tmp/iso-no-such-dir/spnav.sock"));
    }
    unsetenv("SPNAV_SOCKET");
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(daemon_killed_and_restarted),
        cmocka_unit_test(device_frame_and_inferred_rest),
        cmocka_unit_test(no_daemon_names_the_socket),
    };
    return cmocka_run_group_tests_name("dev_spnav", t, NULL, NULL);
}
