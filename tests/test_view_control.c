/* tests/test_view_control.c -- the live view as a control surface, at its
 * server (view/iso_display.h, "Who may command"), with a view device from
 * devices/ behind it and WebSocket clients standing for pages:
 *   - a stop is released only by the viewer who pressed it or the one in
 *     control (anyone once the one who pressed it has left), never within
 *     ISO_DISPLAY_UNSTOP_MIN_MS of it: a page flapping its stop for 1 s
 *     makes a few changes, not thousands;
 *   - one viewer at a time controls (the first to ask); the others are
 *     refused, counted and told who controls; its leaving ends its control,
 *     and so does its silence for ISO_DISPLAY_LAPSE_MS;
 *   - a stop comes from any viewer that may command and acts on the
 *     device's e-stop level at once; its release is a message of its own;
 *   - malformed, oversized or unpermitted commands never reach the device;
 *   - beyond loopback, commanding needs the token, watching does not; a
 *     foreign Origin cannot even connect; a view without a device refuses;
 *   - the run's end takes control away and shows its note. */
#include "testutil.h"

#include <arpa/inet.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_display.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "ws_client.h"

typedef struct rig {
    iso_shape shape;
    iso_mesh *mesh;
    iso_regions regions;
    iso_dev_source *dev;
    iso_display *d;
    int port;
    char origin[96];
} rig;

static void rig_open(rig *r, int with_device, const char *host)
{
    iso_err err;
    iso_err_clear(&err);
    memset(r, 0, sizeof *r);
    if (iso_shape_init(&r->shape, "bar", 4, &err) != ISO_OK ||
        iso_mesh_create(r->shape.nv, r->shape.x, r->shape.nt, r->shape.tri, "bar", &r->mesh,
                        &err) != ISO_OK ||
        iso_shape_regions(&r->shape, &r->regions, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    if (with_device && iso_dev_view_open("hand", &r->dev, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    iso_display_handle h = {"top", 0};
    iso_display_opts o = {.mesh = r->mesh,
                          .regions = &r->regions,
                          .host = host,
                          .allow_remote = host != NULL,
                          .notice = NULL,
                          .view_device = r->dev,
                          .handles = &h,
                          .n_handles = 1};
    if (iso_display_create(&o, &r->d, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    r->port = iso_display_port(r->d);
    snprintf(r->origin, sizeof r->origin, "Origin: http://127.0.0.1:%d\r\n", r->port);
}

static void rig_close(rig *r)
{
    iso_display_destroy(r->d);
    iso_dev_source_close(r->dev);
    iso_regions_deinit(&r->regions);
    iso_mesh_destroy(r->mesh);
    iso_shape_deinit(&r->shape);
}

static void nap_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* A page: /ws with our Origin and an optional query; its first control
 * message goes into ctl. */
static int page(const rig *r, const char *query, char *ctl, size_t cap)
{
    char host[64], req[512];
    snprintf(host, sizeof host, "127.0.0.1:%d", r->port);
    int fd = iso_test_connect(AF_INET, r->port, 0);
    assert_true(fd >= 0);
    snprintf(req, sizeof req,
             "GET /ws%s HTTP/1.1\r\nHost: %s\r\n%sUpgrade: websocket\r\nConnection: Upgrade\r\n"
             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
             query ? query : "", host, r->origin);
    iso_test_send_all(fd, req);
    char head[2048];
    assert_int_equal(iso_test_read_head(fd, head, sizeof head), 101);
    unsigned char *p;
    size_t n;
    assert_int_equal(iso_test_ws_recv(fd, &p, &n), 2); /* the topology */
    char *json = iso_test_topology_json(p, n);
    assert_non_null(json);
    assert_non_null(strstr(json, "\"control\":{\"handles\":[{\"name\":\"top\"") || !r->dev);
    free(json);
    free(p);
    assert_int_equal(iso_test_ws_recv(fd, &p, &n), 1);
    snprintf(ctl, cap, "%s", (char *)p);
    free(p);
    return fd;
}

/* The next text message of the given type ("control" or "note") that
 * holds `with` (NULL: any). */
static void text_with(int fd, const char *type, const char *with, char *out, size_t cap)
{
    char want[64];
    snprintf(want, sizeof want, "\"type\":\"%s\"", type);
    for (;;) {
        unsigned char *p;
        size_t n;
        int op = iso_test_ws_recv(fd, &p, &n);
        if (op < 0)
            fail_msg("the connection ended before a %s message with %s", type, with ? with : "");
        int hit = op == 1 && strstr((char *)p, want) && (!with || strstr((char *)p, with));
        if (hit)
            snprintf(out, cap, "%s", (char *)p);
        free(p);
        if (hit)
            return;
    }
}

static void command(int fd, int type, uint32_t seq, int handle, const double *pose)
{
    iso_dev_view_msg m = {(uint8_t)type, (uint8_t)handle, seq, 1000.0 + seq, {0}};
    if (pose)
        memcpy(m.pose, pose, sizeof m.pose);
    uint8_t b[ISO_DEV_VIEW_MSG_MAX];
    int n = iso_dev_view_encode(&m, b, sizeof b);
    assert_true(n > 0);
    iso_test_ws_send(fd, 1, 2, b, (size_t)n);
}

/* The next chunk the device got within 2 s: its envelope kind and
 * connection, and the message type (0 when none). -1 when none came. */
static int next_chunk_now(const rig *r, uint32_t *conn, int *type);
static int next_chunk(const rig *r, uint32_t *conn, int *type)
{
    for (int w = 0; w < 400; w++) {
        int k = next_chunk_now(r, conn, type);
        if (k)
            return k;
        nap_ms(5);
    }
    return -1;
}

/* The next chunk queued now, without waiting: as next_chunk, 0 when none. */
static int next_chunk_now(const rig *r, uint32_t *conn, int *type)
{
    iso_dev_chunk c;
    if (iso_dev_source_read(r->dev, INT64_MAX, &c, NULL) != 1)
        return 0;
    *conn = (uint32_t)c.data[1] | (uint32_t)c.data[2] << 8 | (uint32_t)c.data[3] << 16 |
            (uint32_t)c.data[4] << 24;
    *type = c.data[0] == ISO_DEV_VIEW_MSG && c.len > 6 ? c.data[6] : 0;
    return c.data[0];
}

static int nothing_queued(const rig *r)
{
    nap_ms(100);
    iso_dev_chunk c;
    return iso_dev_source_read(r->dev, INT64_MAX, &c, NULL) == 0;
}

static uint32_t you(const char *ctl)
{
    const char *p = strstr(ctl, "\"you\":");
    assert_non_null(p);
    return (uint32_t)atol(p + 6);
}

static void one_viewer_controls_at_a_time(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, NULL);
    char ca[512], cb[512];
    int a = page(&r, NULL, ca, sizeof ca), b = page(&r, NULL, cb, sizeof cb);
    uint32_t ida = you(ca), idb = you(cb);
    assert_non_null(strstr(ca, "\"may_command\":true"));
    assert_non_null(strstr(ca, "\"holder\":0"));
    command(a, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    uint32_t conn;
    int type;
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    assert_int_equal(conn, ida);
    char want[64];
    snprintf(want, sizeof want, "\"holder\":%u", (unsigned)ida);
    text_with(b, "control", want, cb, sizeof cb); /* the others see who controls */
    assert_int_equal(iso_display_holder(r.d), ida);
    /* B is refused, told why, and nothing reaches the device */
    static const double pose[6] = {0.5, 0, 0, 0, 0, 0.1};
    command(b, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    text_with(b, "control", "is in control", cb, sizeof cb);
    print_message("refused: %s\n", cb);
    command(b, ISO_DEV_VIEW_TARGET, 2, 0, pose); /* one at a time: each reason is said */
    text_with(b, "control", "take control first", cb, sizeof cb);
    assert_true(nothing_queued(&r));
    /* A's target goes through; one for a handle it may not move does not */
    command(a, ISO_DEV_VIEW_TARGET, 2, 0, pose);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_MSG);
    assert_int_equal(type, ISO_DEV_VIEW_TARGET);
    command(a, ISO_DEV_VIEW_TARGET, 3, 1, pose);
    assert_true(nothing_queued(&r));
    iso_display_command_stats cs;
    iso_display_command_stats_get(r.d, &cs);
    assert_int_equal(cs.grants, 1);
    assert_int_equal(cs.accepted, 1);
    assert_int_equal(cs.refused, 3);
    /* A leaves: its control ends on the device, and B may take it */
    close(a);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_END);
    assert_int_equal(conn, ida);
    text_with(b, "control", "\"holder\":0", cb, sizeof cb);
    command(b, ISO_DEV_VIEW_TAKE, 3, 0, NULL);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    assert_int_equal(conn, idb);
    command(b, ISO_DEV_VIEW_RELEASE, 4, 0, NULL); /* letting go is an end too */
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_END);
    assert_int_equal(iso_display_holder(r.d), 0);
    close(b);
    rig_close(&r);
}

/* A holder that stays connected but sends nothing (a hung or throttled
 * tab) loses control after ISO_DISPLAY_LAPSE_MS, with an END the device
 * records (ISO_DEV_VIEW_END_LAPSED) and a reason on its page; another
 * viewer may then take it. One that keeps sending (a keepalive's target
 * every 25 ms, here every 500 ms for twice the lapse) keeps it. */
static void a_silent_holder_loses_control(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, NULL);
    char ca[512], cb[512];
    int a = page(&r, NULL, ca, sizeof ca), b = page(&r, NULL, cb, sizeof cb);
    uint32_t ida = you(ca), idb = you(cb), conn;
    int type;
    command(a, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    static const double pose[6] = {0.5, 0, 0, 0, 0, 0.1};
    uint32_t seq = 1;
    int64_t t0 = 0;                                            /* its last command */
    for (int k = 0; k < 2 * ISO_DISPLAY_LAPSE_MS / 500; k++) { /* sending: it keeps control */
        command(a, ISO_DEV_VIEW_TARGET, ++seq, 0, pose);
        t0 = iso_clock_ns();
        assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_MSG);
        nap_ms(500);
    }
    assert_int_equal(iso_display_holder(r.d), ida);
    /* silent: the END comes after the lapse, not before */
    iso_dev_chunk c;
    int64_t ended = 0;
    for (int w = 0; w < 2 * ISO_DISPLAY_LAPSE_MS / 10 && !ended; w++) {
        if (iso_dev_source_read(r.dev, INT64_MAX, &c, NULL) == 1) {
            assert_int_equal(c.data[0], ISO_DEV_VIEW_END);
            assert_int_equal(c.data[5], ISO_DEV_VIEW_END_LAPSED);
            ended = iso_clock_ns();
        } else {
            nap_ms(10);
        }
    }
    double after_ms = (double)(ended - t0) * 1e-6;
    print_message("a silent holder lost control %.0f ms after its last command\n", after_ms);
    assert_true(ended > 0);
    assert_true(after_ms >= ISO_DISPLAY_LAPSE_MS - 5 && /* the server counts whole ms */
                after_ms <= ISO_DISPLAY_LAPSE_MS + ISO_DISPLAY_POLL_MS + 500);
    text_with(a, "control", "control lapsed", ca, sizeof ca);
    assert_int_equal(iso_display_holder(r.d), 0);
    command(b, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    assert_int_equal(conn, idb);
    close(a);
    close(b);
    rig_close(&r);
}

static void a_stop_comes_from_anyone_and_acts_at_once(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, NULL);
    char ca[512], cb[512];
    int a = page(&r, NULL, ca, sizeof ca), b = page(&r, NULL, cb, sizeof cb);
    command(a, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    uint32_t conn;
    int type;
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    assert_int_equal(r.dev->ops->estop_level(r.dev), 0);
    command(b, ISO_DEV_VIEW_STOP, 1, 0, NULL); /* B does not control, and may stop */
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_MSG);
    assert_int_equal(type, ISO_DEV_VIEW_STOP);
    assert_int_equal(conn, you(cb));
    assert_int_equal(r.dev->ops->estop_level(r.dev), 1); /* set when it was queued */
    text_with(a, "control", "\"stop\":true", ca, sizeof ca);
    /* a third viewer, neither in control nor the one who pressed it, cannot
     * release it; the one in control cannot at once (a stop stands at least
     * ISO_DISPLAY_UNSTOP_MIN_MS), and can after that */
    char cc[512];
    int c3 = page(&r, NULL, cc, sizeof cc);
    command(c3, ISO_DEV_VIEW_UNSTOP, 1, 0, NULL);
    text_with(c3, "control", "only the viewer who pressed the stop", cc, sizeof cc);
    command(a, ISO_DEV_VIEW_UNSTOP, 2, 0, NULL);
    text_with(a, "control", "too soon after the stop", ca, sizeof ca);
    assert_true(nothing_queued(&r));
    assert_int_equal(r.dev->ops->estop_level(r.dev), 1);
    nap_ms(ISO_DISPLAY_UNSTOP_MIN_MS + 50);
    command(a, ISO_DEV_VIEW_UNSTOP, 3, 0, NULL);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_MSG);
    assert_int_equal(type, ISO_DEV_VIEW_UNSTOP);
    assert_int_equal(r.dev->ops->estop_level(r.dev), 0);
    /* flapping as fast as a socket takes it for 1 s: every STOP acts at
     * once, and the stop changes at most twice a second */
    uint32_t seq = 10;
    double t0 = iso_clock_now();
    while (iso_clock_now() < t0 + 1.0) {
        command(b, ISO_DEV_VIEW_STOP, seq++, 0, NULL);
        command(b, ISO_DEV_VIEW_UNSTOP, seq++, 0, NULL);
        nap_ms(1);
    }
    nap_ms(100);
    int changes = 0;
    while (next_chunk_now(&r, &conn, &type) > 0)
        changes += type == ISO_DEV_VIEW_STOP || type == ISO_DEV_VIEW_UNSTOP;
    print_message("a page flapping its stop for 1 s: %d changes reached the device\n", changes);
    assert_true(changes >= 1 && changes <= 2 * (1000 / ISO_DISPLAY_UNSTOP_MIN_MS + 1));
    iso_display_command_stats cs;
    iso_display_command_stats_get(r.d, &cs);
    assert_true(cs.stops >= 2);
    /* the one who pressed it leaves (a page that reloads): its stop is
     * then anyone's to release, not stuck */
    if (r.dev->ops->estop_level(r.dev) == 0) {
        command(b, ISO_DEV_VIEW_STOP, seq++, 0, NULL);
        assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_MSG);
        assert_int_equal(type, ISO_DEV_VIEW_STOP);
    }
    nap_ms(ISO_DISPLAY_UNSTOP_MIN_MS + 50);
    command(c3, ISO_DEV_VIEW_UNSTOP, 2, 0, NULL);
    assert_true(nothing_queued(&r)); /* b still there: refused */
    close(b);
    nap_ms(100);
    command(c3, ISO_DEV_VIEW_UNSTOP, 3, 0, NULL);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_MSG);
    assert_int_equal(type, ISO_DEV_VIEW_UNSTOP);
    assert_int_equal(r.dev->ops->estop_level(r.dev), 0);
    close(c3);
    close(a);
    rig_close(&r);
}

static void malformed_commands_never_reach_the_device(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, NULL);
    char c[512];
    int a = page(&r, NULL, c, sizeof c);
    command(a, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    uint32_t conn;
    int type;
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    uint8_t b[ISO_DEV_VIEW_MSG_MAX + 8];
    iso_dev_view_msg m = {ISO_DEV_VIEW_TARGET, 0, 2, 1.0, {0, 0, 0, 0, 0, 0}};
    int n = iso_dev_view_encode(&m, b, sizeof b);
    b[0] = 2; /* another version */
    iso_test_ws_send(a, 1, 2, b, (size_t)n);
    b[0] = 1;
    iso_test_ws_send(a, 1, 2, b, (size_t)n - 1); /* a byte short */
    iso_test_ws_send(a, 1, 2, b, (size_t)n + 1); /* a byte long */
    m.pose[3] = 1.0 / 0.0;
    n = iso_dev_view_encode(&m, b, sizeof b);
    iso_test_ws_send(a, 1, 2, b, (size_t)n);                /* not finite */
    iso_test_ws_send(a, 1, 1, "{\"type\":\"TARGET\"}", 17); /* text carries no command */
    /* the page is told why (the newest reason: refusals that come together
     * are said once) */
    text_with(a, "control", "target rotation x is inf", c, sizeof c);
    print_message("malformed: %s\n", c);
    assert_true(nothing_queued(&r));
    iso_display_command_stats cs;
    iso_display_command_stats_get(r.d, &cs);
    assert_int_equal(cs.malformed, 4);
    assert_int_equal(cs.accepted, 0);
    /* oversized: the connection ends with 1009, and its control with it */
    static unsigned char big[ISO_DISPLAY_MAX_CLIENT_MESSAGE + 1];
    iso_test_ws_send(a, 1, 2, big, sizeof big);
    assert_int_equal(iso_test_ws_close_status(a, NULL), 1009);
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_END);
    close(a);
    rig_close(&r);
}

static void beyond_loopback_commanding_needs_the_token(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, "0.0.0.0");
    const char *tok = iso_display_token(r.d);
    assert_int_equal(strlen(tok), 32);
    char url[256], q[128], c[512];
    iso_display_url(r.d, url, sizeof url);
    assert_non_null(strstr(url, tok));
    /* without the token, or with another: it watches, and is refused */
    int w = page(&r, NULL, c, sizeof c);
    assert_non_null(strstr(c, "\"may_command\":false"));
    command(w, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    command(w, ISO_DEV_VIEW_STOP, 2, 0, NULL);
    text_with(w, "control", "token", c, sizeof c);
    int x = page(&r, "?token=00000000000000000000000000000000", c, sizeof c);
    assert_non_null(strstr(c, "\"may_command\":false"));
    command(x, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    assert_true(nothing_queued(&r));
    assert_int_equal(r.dev->ops->estop_level(r.dev), 0);
    /* watching needs no token: frames reach it */
    assert_int_equal(iso_display_publish(r.d, 1, r.shape.x, NULL, NULL), ISO_OK);
    unsigned char *p;
    size_t n;
    int op;
    while ((op = iso_test_ws_recv(w, &p, &n)) == 1)
        free(p);
    assert_int_equal(op, 2);
    free(p);
    /* with it: control */
    snprintf(q, sizeof q, "?token=%s", tok);
    int y = page(&r, q, c, sizeof c);
    assert_non_null(strstr(c, "\"may_command\":true"));
    command(y, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    uint32_t conn;
    int type;
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    assert_int_equal(conn, you(c));
    close(w);
    close(x);
    close(y);
    rig_close(&r);
}

static void a_foreign_page_and_a_view_without_device_cannot_command(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, NULL);
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", r.port);
    int st;
    int fd = iso_test_ws_open(AF_INET, r.port, host, "Origin: http://evil.example\r\n", 0, &st);
    assert_int_equal(st, 403);
    close(fd);
    assert_true(nothing_queued(&r));
    rig_close(&r);
    rig_open(&r, 0, NULL); /* no view device: it only watches */
    char c[512];
    int a = page(&r, NULL, c, sizeof c);
    assert_non_null(strstr(c, "\"may_command\":false"));
    command(a, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    text_with(a, "control", "only watches", c, sizeof c);
    assert_int_equal(iso_display_holder(r.d), 0);
    close(a);
    rig_close(&r);
}

static void the_end_of_the_run_ends_control(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1, NULL);
    char c[512];
    int a = page(&r, NULL, c, sizeof c);
    command(a, ISO_DEV_VIEW_TAKE, 1, 0, NULL);
    uint32_t conn;
    int type;
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_GRANT);
    iso_display_end(r.d, NULL);
    iso_display_end(r.d, "scene x: 10 ticks\n  \"done\"");
    assert_int_equal(next_chunk(&r, &conn, &type), ISO_DEV_VIEW_END);
    text_with(a, "note", "scene x: 10 ticks\\n  \\\"done\\\"", c, sizeof c);
    command(a, ISO_DEV_VIEW_TAKE, 2, 0, NULL);
    text_with(a, "control", "the run has ended", c, sizeof c);
    assert_non_null(strstr(c, "\"ended\":true"));
    assert_true(nothing_queued(&r));
    close(a);
    rig_close(&r);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(one_viewer_controls_at_a_time),
        cmocka_unit_test(a_silent_holder_loses_control),
        cmocka_unit_test(a_stop_comes_from_anyone_and_acts_at_once),
        cmocka_unit_test(malformed_commands_never_reach_the_device),
        cmocka_unit_test(beyond_loopback_commanding_needs_the_token),
        cmocka_unit_test(a_foreign_page_and_a_view_without_device_cannot_command),
        cmocka_unit_test(the_end_of_the_run_ends_control),
    };
    return cmocka_run_group_tests_name("view_control", t, NULL, NULL);
}
