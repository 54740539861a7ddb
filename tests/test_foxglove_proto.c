/* tests/test_foxglove_proto.c -- the edges of the view's Foxglove protocol
 * (view/foxglove_live.c), on an in-process display:
 *   - before the session exists (the first moments of a run) an offer of
 *     foxglove.websocket.v1 gets 503 with Retry-After, not a refusal;
 *   - the subprotocol is matched as a token: "xfoxglove.websocket.v1y" is
 *     not it (400), "a, foxglove.websocket.v1" is;
 *   - a subscription to a channel that is not advertised and an op that is
 *     not served are answered with a "status" message (level 1, warning)
 *     that says which, and the connection goes on. */
#include "testutil.h"
#include "ws_client.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "iso_display.h"
#include "iso_foxglove.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"

#define OFFER(p) "Sec-WebSocket-Protocol: " p "\r\n"

static int open_fox(int port, const char *extra, int *status)
{
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    return iso_test_ws_open(AF_INET, port, host, extra, 0, status);
}

/* The next text message holding `with`; fails after a few unrelated ones. */
static void text_with(int fd, const char *with, char *out, size_t cap)
{
    for (int k = 0; k < 20; k++) {
        unsigned char *p;
        size_t n;
        int op = iso_test_ws_recv(fd, &p, &n);
        if (op < 0)
            fail_msg("the connection ended before a message with %s", with);
        int hit = op == 1 && strstr((char *)p, with);
        if (hit)
            snprintf(out, cap, "%s", (char *)p);
        free(p);
        if (hit)
            return;
    }
    fail_msg("no message with %s", with);
}

static void the_protocol_edges(void **state)
{
    (void)state;
    iso_err err;
    iso_err_clear(&err);
    iso_shape shape;
    iso_mesh *mesh = NULL;
    iso_regions regions;
    if (iso_shape_init(&shape, "bar", 4, &err) != ISO_OK ||
        iso_mesh_create(shape.nv, shape.x, shape.nt, shape.tri, "bar", &mesh, &err) != ISO_OK ||
        iso_shape_regions(&shape, &regions, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    iso_display_opts o = {.mesh = mesh, .regions = &regions};
    iso_display *d = NULL;
    if (iso_display_create(&o, &d, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    int port = iso_display_port(d), st = 0;
    /* before the session: come back in a moment */
    int fd = open_fox(port, OFFER("foxglove.websocket.v1"), &st);
    assert_int_equal(st, 503);
    close(fd);
    iso_sink_session s;
    memset(&s, 0, sizeof s);
    s.mesh = mesh;
    s.regions = &regions;
    s.n_handles = 1;
    snprintf(s.handle_name[0], sizeof s.handle_name[0], "top");
    if (iso_display_foxglove(d, &s, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    /* a name that only contains it is not it */
    fd = open_fox(port, OFFER("xfoxglove.websocket.v1y"), &st);
    assert_int_equal(st, 400);
    close(fd);
    fd = open_fox(port, OFFER("other.v2, foxglove.websocket.v1"), &st);
    assert_int_equal(st, 101);
    char m[2048];
    text_with(fd, "\"op\":\"serverInfo\"", m, sizeof m);
    text_with(fd, "\"op\":\"advertise\"", m, sizeof m);
    const char *sub = "{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":1,\"channelId\":999}]}";
    iso_test_ws_send(fd, 1, 1, sub, strlen(sub));
    text_with(fd, "\"op\":\"status\"", m, sizeof m);
    print_message("%s\n", m);
    assert_non_null(strstr(m, "\"level\":1"));
    assert_non_null(strstr(m, "channel 999 is not advertised"));
    const char *adv = "{\"op\":\"advertise\",\"channels\":[]}";
    iso_test_ws_send(fd, 1, 1, adv, strlen(adv));
    text_with(fd, "\"op\":\"status\"", m, sizeof m);
    print_message("%s\n", m);
    assert_non_null(strstr(m, "op 'advertise' is not served here"));
    close(fd);
    iso_display_destroy(d);
    iso_regions_deinit(&regions);
    iso_mesh_destroy(mesh);
    iso_shape_deinit(&shape);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(the_protocol_edges),
    };
    return cmocka_run_group_tests_name("foxglove_proto", t, NULL, NULL);
}
