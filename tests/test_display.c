/* tests/test_display.c -- the display sink: software PNG snapshots, PLY
 * frame sequences, the HTTP + WebSocket server spoken to by hand, and the
 * page in a real headless Chromium. */
#include "testutil.h"

#include <arpa/inet.h>
#include <math.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#ifdef ISO_WITH_LIBPNG
#include <png.h>
#endif

#include "iso_display.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_snapshot.h"

/* ---- fixtures ----------------------------------------------------------- */

typedef struct scene {
    iso_shape shape;
    iso_mesh *mesh;
    iso_regions regions;
} scene;

static void scene_init(scene *s, const char *name, int res)
{
    iso_err err;
    iso_err_clear(&err);
    memset(s, 0, sizeof *s);
    if (iso_shape_init(&s->shape, name, res, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    if (iso_mesh_create(s->shape.nv, s->shape.x, s->shape.nt, s->shape.tri, name, &s->mesh, &err) !=
        ISO_OK)
        fail_msg("%s", err.msg);
    if (iso_shape_regions(&s->shape, &s->regions, &err) != ISO_OK)
        fail_msg("%s", err.msg);
}

static void scene_deinit(scene *s)
{
    iso_regions_deinit(&s->regions);
    iso_mesh_destroy(s->mesh);
    iso_shape_deinit(&s->shape);
}

static void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* ---- (a) PNG snapshots -------------------------------------------------- */

#ifdef ISO_WITH_LIBPNG
typedef struct picture {
    int w, h;
    unsigned char *rgb;
} picture;

static void picture_load(picture *p, const char *path)
{
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path))
        fail_msg("%s: %s", path, img.message);
    img.format = PNG_FORMAT_RGB;
    p->w = (int)img.width;
    p->h = (int)img.height;
    p->rgb = malloc(PNG_IMAGE_SIZE(img));
    assert_non_null(p->rgb);
    if (!png_image_finish_read(&img, NULL, p->rgb, 0, NULL))
        fail_msg("%s: %s", path, img.message);
}

static const unsigned char *pixel(const picture *p, int x, int y)
{
    return p->rgb + 3 * ((size_t)y * (size_t)p->w + (size_t)x);
}

static int is_background(const unsigned char *c)
{
    return c[0] == ISO_SNAPSHOT_BG_R && c[1] == ISO_SNAPSHOT_BG_G && c[2] == ISO_SNAPSHOT_BG_B;
}
#endif

static void snapshot_shows_mesh_and_distortion(void **state)
{
    (void)state;
#ifndef ISO_WITH_LIBPNG
    skip();
#else
    scene s;
    scene_init(&s, "cylinder", 24);
    char rest_png[512], stretched_png[512];
    iso_test_tmp(rest_png, sizeof rest_png, "display_rest.png");
    iso_test_tmp(stretched_png, sizeof stretched_png, "display_stretched.png");
    iso_err err;
    iso_err_clear(&err);
    iso_snapshot_view side = {0, 10, 1};
    if (iso_snapshot_png(s.mesh, NULL, &s.regions, rest_png, 160, 120, &side, &err) != ISO_OK)
        fail_msg("%s", err.msg);

    picture p;
    picture_load(&p, rest_png);
    assert_int_equal(p.w, 160);
    assert_int_equal(p.h, 120);
    const int corners[4][2] = {{0, 0}, {159, 0}, {0, 119}, {159, 119}};
    for (int k = 0; k < 4; k++)
        assert_true(is_background(pixel(&p, corners[k][0], corners[k][1])));
    const unsigned char *c = pixel(&p, 80, 60); /* the middle: free, unstrained */
    assert_false(is_background(c));
    assert_true(c[2] > c[0] + 20); /* blue end of the scale */
    free(p.rgb);

    /* Widen the cylinder by 30%: its rings stretch, so the middle turns red. */
    int nv = s.shape.nv;
    double *x = malloc(3 * (size_t)nv * sizeof *x);
    assert_non_null(x);
    for (int i = 0; i < nv; i++) {
        x[3 * i] = 1.3 * s.shape.x[3 * i];
        x[3 * i + 1] = 1.3 * s.shape.x[3 * i + 1];
        x[3 * i + 2] = s.shape.x[3 * i + 2];
    }
    if (iso_snapshot_png(s.mesh, x, &s.regions, stretched_png, 160, 120, &side, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    picture_load(&p, stretched_png);
    c = pixel(&p, 80, 60);
    assert_false(is_background(c));
    assert_true(c[0] > c[2] + 40); /* red end of the scale */
    free(p.rgb);

    /* Errors are sentences that name the problem. */
    iso_err_clear(&err);
    assert_int_equal(iso_snapshot_png(s.mesh, x, NULL, rest_png, 4, 4, NULL, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "4x4"));
    iso_err_clear(&err);
    assert_int_equal(
        iso_snapshot_png(s.mesh, x, NULL, "/nonexistent-dir/a.png", 32, 32, NULL, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "/nonexistent-dir/a.png"));
    free(x);
    scene_deinit(&s);
#endif
}

/* ---- (b) PLY frames ----------------------------------------------------- */

static void ply_frames_round_trip_exactly(void **state)
{
    (void)state;
    scene s;
    scene_init(&s, "bar", 4);
    char dir[512];
    iso_test_tmp(dir, sizeof dir, "display_frames");
    iso_err err;
    iso_err_clear(&err);
    iso_ply_frames *f = NULL;
    if (iso_ply_frames_create(dir, s.mesh, 2, &f, &err) != ISO_OK)
        fail_msg("%s", err.msg);
    int nv = s.shape.nv;
    double *x = malloc(3 * (size_t)nv * sizeof *x);
    assert_non_null(x);
    for (long tick = 0; tick <= 4; tick++) {
        for (int i = 0; i < 3 * nv; i++)
            x[i] = s.shape.x[i] * (1 + 0.1 * (double)tick) + 1.0 / 3.0 * (double)tick;
        assert_int_equal(iso_ply_frames_write(f, tick, x, &err), tick % 2 == 0 ? 1 : 0);
    }
    for (long tick = 0; tick <= 4; tick++) {
        char path[600];
        iso_ply_frames_path(f, tick, path, sizeof path);
        if (tick % 2) {
            struct stat st;
            assert_int_not_equal(stat(path, &st), 0);
            continue;
        }
        assert_non_null(strstr(path, tick == 4 ? "frame_00000004.ply" : "frame_0000000"));
        iso_mesh *m = NULL;
        if (iso_mesh_load(path, &m, &err) != ISO_OK)
            fail_msg("%s", err.msg);
        assert_int_equal(iso_mesh_vertex_count(m), nv);
        assert_int_equal(iso_mesh_triangle_count(m), s.shape.nt);
        const double *y = iso_mesh_positions(m);
        for (int i = 0; i < 3 * nv; i++) {
            double want = s.shape.x[i] * (1 + 0.1 * (double)tick) + 1.0 / 3.0 * (double)tick;
            assert_memory_equal(&y[i], &want, sizeof want);
        }
        assert_memory_equal(iso_mesh_triangles(m), s.shape.tri,
                            3 * (size_t)s.shape.nt * sizeof(int));
        iso_mesh_destroy(m);
    }
    iso_ply_frames_destroy(f);
    iso_err_clear(&err);
    assert_int_equal(iso_ply_frames_create(dir, s.mesh, 0, &f, &err), ISO_EINVAL);
    assert_null(f);
    free(x);
    scene_deinit(&s);
}

/* ---- (c) the server, by hand -------------------------------------------- */

static int connect_local(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    assert_true(fd >= 0);
    struct timeval tv = {5, 0};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((unsigned short)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(connect(fd, (struct sockaddr *)&a, sizeof a), 0);
    return fd;
}

static void send_all(int fd, const char *s)
{
    size_t n = strlen(s);
    while (n) {
        ssize_t w = write(fd, s, n);
        assert_true(w > 0);
        s += w;
        n -= (size_t)w;
    }
}

/* Reads until the peer closes; returns a NUL-terminated malloc'd buffer. */
static char *read_to_end(int fd, size_t *len)
{
    size_t cap = 1 << 16, n = 0;
    char *b = malloc(cap + 1);
    assert_non_null(b);
    for (;;) {
        if (n == cap) {
            cap *= 2;
            b = realloc(b, cap + 1);
            assert_non_null(b);
        }
        ssize_t r = read(fd, b + n, cap - n);
        assert_true(r >= 0);
        if (r == 0)
            break;
        n += (size_t)r;
    }
    b[n] = 0;
    *len = n;
    return b;
}

static char *http_get(int port, const char *path, size_t *len)
{
    int fd = connect_local(port);
    char req[256];
    snprintf(req, sizeof req, "GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n",
             path);
    send_all(fd, req);
    char *b = read_to_end(fd, len);
    close(fd);
    return b;
}

static void read_exact(int fd, void *buf, size_t n)
{
    unsigned char *p = buf;
    while (n) {
        ssize_t r = read(fd, p, n);
        if (r <= 0)
            fail_msg("WebSocket: connection ended or timed out with %zu bytes to read", n);
        p += r;
        n -= (size_t)r;
    }
}

/* Reads one unmasked server frame; returns its opcode and a malloc'd payload. */
static int ws_read_frame(int fd, unsigned char **payload, size_t *len)
{
    unsigned char h[2];
    read_exact(fd, h, 2);
    assert_true(h[0] & 0x80); /* the server sends whole messages */
    assert_false(h[1] & 0x80);
    uint64_t n = h[1] & 0x7f;
    if (n == 126) {
        unsigned char e[2];
        read_exact(fd, e, 2);
        n = (uint64_t)e[0] << 8 | e[1];
    } else if (n == 127) {
        unsigned char e[8];
        read_exact(fd, e, 8);
        n = 0;
        for (int i = 0; i < 8; i++)
            n = n << 8 | e[i];
    }
    assert_true(n < (1u << 26));
    *payload = malloc((size_t)n + 1);
    assert_non_null(*payload);
    read_exact(fd, *payload, (size_t)n);
    (*payload)[n] = 0;
    *len = (size_t)n;
    return h[0] & 0x0f;
}

static void start_display(const scene *s, iso_display **d)
{
    iso_err err;
    iso_err_clear(&err);
    iso_display_opts o = {.mesh = s->mesh, .regions = &s->regions};
    int rc = iso_display_create(&o, d, &err);
    if (rc == ISO_ENOTSUP) {
        print_message("skipped: %s\n", err.msg);
        skip();
    }
    if (rc != ISO_OK)
        fail_msg("%s", err.msg);
    assert_true(iso_display_port(*d) > 0);
}

static void server_serves_page_and_streams_frames(void **state)
{
    (void)state;
    scene s;
    scene_init(&s, "bar", 4);
    iso_display *d = NULL;
    start_display(&s, &d);
    int port = iso_display_port(d);

    size_t len;
    char *page = http_get(port, "/", &len);
    assert_non_null(strstr(page, "HTTP/1.1 200"));
    assert_non_null(strstr(page, "<script src=\"/three.min.js\">"));
    free(page);
    char *three = http_get(port, "/three.min.js", &len);
    assert_non_null(strstr(three, "HTTP/1.1 200"));
    assert_true(len > 100000);
    assert_non_null(strstr(three, "WebGLRenderer"));
    free(three);
    char *app = http_get(port, "/app.js", &len);
    assert_non_null(strstr(app, "HTTP/1.1 200"));
    assert_non_null(strstr(app, "data-frames"));
    free(app);
    char *missing = http_get(port, "/etc/passwd", &len);
    assert_null(strstr(missing, "HTTP/1.1 200"));
    free(missing);

    /* WebSocket handshake, written out (RFC 6455's sample key and answer). */
    int fd = connect_local(port);
    send_all(fd, "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
                 "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                 "Sec-WebSocket-Version: 13\r\n\r\n");
    char resp[1024];
    size_t n = 0;
    while (n < sizeof resp - 1 && !(n >= 4 && memcmp(resp + n - 4, "\r\n\r\n", 4) == 0)) {
        read_exact(fd, resp + n, 1);
        n++;
    }
    resp[n] = 0;
    assert_non_null(strstr(resp, "101"));
    assert_non_null(strstr(resp, "s3pPLMBiTxaQ9kYGzzhZRbK+xOo="));

    unsigned char *msg;
    assert_int_equal(ws_read_frame(fd, &msg, &len), 1); /* text: topology */
    assert_non_null(strstr((char *)msg, "\"type\":\"topology\""));
    char nv_field[64];
    snprintf(nv_field, sizeof nv_field, "\"nv\":%d,", s.shape.nv);
    assert_non_null(strstr((char *)msg, nv_field));
    free(msg);
    for (int w = 0; w < 500 && iso_display_clients(d) < 1; w++)
        sleep_ms(10);
    assert_int_equal(iso_display_clients(d), 1);

    int nv = s.shape.nv;
    iso_err err;
    iso_err_clear(&err);
    double last_tick = -1;
    for (long tick = 10; tick < 13; tick++) {
        long before = iso_display_frames_sent(d);
        iso_display_stats st = {1.5, 2.5, 3.5, 0.25, tick - 10};
        assert_int_equal(iso_display_publish(d, tick, s.shape.x, &st, &err), ISO_OK);
        for (int w = 0; w < 500 && iso_display_frames_sent(d) == before; w++)
            sleep_ms(2);
        assert_int_equal(ws_read_frame(fd, &msg, &len), 2); /* binary */
        assert_int_equal(len, ISO_DISPLAY_FRAME_HEADER + 12 * (size_t)nv);
        uint32_t u[2];
        double t;
        float f[4], p0[3];
        memcpy(u, msg, 8);
        memcpy(&t, msg + 8, 8);
        memcpy(f, msg + 16, 16);
        memcpy(p0, msg + ISO_DISPLAY_FRAME_HEADER, 12);
        assert_int_equal(u[0], ISO_DISPLAY_FRAME_MAGIC);
        assert_int_equal(u[1], (uint32_t)nv);
        assert_true(t > last_tick);
        assert_true(t == (double)tick);
        last_tick = t;
        assert_true(f[1] == 2.5f);
        assert_true(p0[0] == (float)s.shape.x[0] && p0[2] == (float)s.shape.x[2]);
        free(msg);
    }
    close(fd);
    iso_display_destroy(d);

    /* A missing three.js is a sentence naming the file and the package. */
    iso_display_opts bad = {.mesh = s.mesh, .three_js = "/nonexistent/three.min.js"};
    iso_err_clear(&err);
    assert_int_equal(iso_display_create(&bad, &d, &err), ISO_EIO);
    assert_null(d);
    assert_non_null(strstr(err.msg, "/nonexistent/three.min.js"));
    assert_non_null(strstr(err.msg, "libjs-three"));
    scene_deinit(&s);
}

/* A browser that stops reading must not stall publish, nor destroy. */
static void stalled_browser_never_blocks_publish(void **state)
{
    (void)state;
    scene s;
    scene_init(&s, "cylinder", 64);
    iso_display *d = NULL;
    start_display(&s, &d);
    int fd = connect_local(iso_display_port(d));
    send_all(fd, "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
                 "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                 "Sec-WebSocket-Version: 13\r\n\r\n");
    for (int w = 0; w < 500 && iso_display_clients(d) < 1; w++)
        sleep_ms(10);
    assert_int_equal(iso_display_clients(d), 1);
    struct timespec t0, t1;
    double worst = 0;
    for (long tick = 0; tick < 400; tick++) { /* ~400 x 100 KB: far beyond socket buffers */
        clock_gettime(CLOCK_MONOTONIC, &t0);
        assert_int_equal(iso_display_publish(d, tick, s.shape.x, NULL, NULL), ISO_OK);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        double ms = (double)(t1.tv_sec - t0.tv_sec) * 1e3 + (double)(t1.tv_nsec - t0.tv_nsec) / 1e6;
        worst = ms > worst ? ms : worst;
        if (tick % 50 == 0)
            sleep_ms(5);
    }
    print_message("stalled browser: slowest publish %.3f ms\n", worst);
    assert_true(worst < 50);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    iso_display_destroy(d);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double ms = (double)(t1.tv_sec - t0.tv_sec) * 1e3 + (double)(t1.tv_nsec - t0.tv_nsec) / 1e6;
    print_message("stalled browser: destroy took %.0f ms\n", ms);
    close(fd);
    scene_deinit(&s);
}

/* ---- (d) a real browser ------------------------------------------------- */

typedef struct publisher {
    iso_display *d;
    const scene *s;
    volatile int stop; /* written once by the test thread, joined after */
    pthread_mutex_t lock;
} publisher;

/* Bends the shape a little more each tick, like a replay would. */
static void *publish_main(void *arg)
{
    publisher *p = arg;
    int nv = p->s->shape.nv;
    double *x = malloc(3 * (size_t)nv * sizeof *x);
    if (!x)
        return NULL;
    for (long tick = 0;; tick++) {
        pthread_mutex_lock(&p->lock);
        int stop = p->stop;
        pthread_mutex_unlock(&p->lock);
        if (stop)
            break;
        double a = 0.004 * (double)(tick % 60);
        for (int i = 0; i < nv; i++) {
            const double *r = p->s->shape.x + 3 * i;
            double z = r[2] / 12.0; /* stretch the top more than the bottom */
            x[3 * i] = r[0] * (1 + a * z);
            x[3 * i + 1] = r[1] * (1 + a * z);
            x[3 * i + 2] = r[2];
        }
        iso_display_stats st = {2.0, 4.0, 6.0, 1.0, 0};
        iso_display_publish(p->d, tick, x, &st, NULL);
        sleep_ms(20);
    }
    free(x);
    return NULL;
}

static const char *const chromium_flags =
    "--headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
    "--disable-background-networking --disable-component-update --disable-sync "
    "--use-angle=swiftshader --enable-unsafe-swiftshader --mute-audio "
    "--window-size=800,600 --virtual-time-budget=4000";

static int run_chromium(const char *profile, const char *action, int port, const char *log)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd,
             "rm -rf '%s' && mkdir -p '%s' && timeout 40 /usr/bin/chromium %s "
             "--user-data-dir='%s' %s http://127.0.0.1:%d/ 2>'%s'",
             profile, profile, chromium_flags, profile, action, port, log);
    return system(cmd);
}

static void chromium_renders_live_page(void **state)
{
    (void)state;
    if (access("/usr/bin/chromium", X_OK) != 0) {
        print_message("skipped: /usr/bin/chromium is not installed (apt-get install "
                      "chromium)\n");
        skip();
    }
    scene s;
    scene_init(&s, "cylinder", 24);
    iso_display *d = NULL;
    start_display(&s, &d);
    publisher p = {d, &s, 0, PTHREAD_MUTEX_INITIALIZER};
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, publish_main, &p), 0);

    char profile[512], dom[512], shot[512], log[512];
    iso_test_tmp(profile, sizeof profile, "chromium-profile");
    iso_test_tmp(dom, sizeof dom, "display_dom.html");
    iso_test_tmp(shot, sizeof shot, "display.png");
    iso_test_tmp(log, sizeof log, "chromium.log");
    char action[1200];
    snprintf(action, sizeof action, "--dump-dom > '%s'", dom);
    int rc_dom = run_chromium(profile, action, iso_display_port(d), log);
    snprintf(action, sizeof action, "--screenshot='%s'", shot);
    remove(shot);
    int rc_shot = run_chromium(profile, action, iso_display_port(d), log);

    pthread_mutex_lock(&p.lock);
    p.stop = 1;
    pthread_mutex_unlock(&p.lock);
    pthread_join(th, NULL);
    iso_display_destroy(d);
    char rm[600];
    snprintf(rm, sizeof rm, "rm -rf '%s'", profile);
    assert_int_equal(system(rm), 0);
    if (rc_dom != 0 || rc_shot != 0)
        fail_msg("chromium failed (dump-dom %d, screenshot %d); see %s", rc_dom, rc_shot, log);

    FILE *f = fopen(dom, "rb");
    assert_non_null(f);
    char html[1 << 15];
    size_t n = fread(html, 1, sizeof html - 1, f);
    fclose(f);
    html[n] = 0;
    char *mark = strstr(html, "data-frames=\"");
    if (!mark)
        fail_msg("%s has no data-frames attribute: the page did not run", dom);
    int frames = atoi(mark + strlen("data-frames=\""));
    print_message("chromium: page received %d frames; screenshot %s\n", frames, shot);
    assert_true(frames >= 1);
    assert_non_null(strstr(html, "data-tick=\""));

#ifdef ISO_WITH_LIBPNG
    picture pic;
    picture_load(&pic, shot);
    assert_int_equal(pic.w, 800);
    assert_int_equal(pic.h, 600);
    /* The mesh fills the middle: count pixels far from the background. */
    long lit = 0;
    for (int y = 0; y < pic.h; y++)
        for (int x = 0; x < pic.w; x++) {
            const unsigned char *c = pixel(&pic, x, y);
            lit += abs(c[0] - ISO_SNAPSHOT_BG_R) + abs(c[1] - ISO_SNAPSHOT_BG_G) +
                       abs(c[2] - ISO_SNAPSHOT_BG_B) >
                   60;
        }
    print_message("chromium: %ld of %d pixels differ from the background\n", lit, pic.w * pic.h);
    assert_true(lit > pic.w * pic.h / 50);
    const unsigned char *mid = pixel(&pic, 400, 330);
    assert_false(abs(mid[0] - ISO_SNAPSHOT_BG_R) + abs(mid[1] - ISO_SNAPSHOT_BG_G) +
                     abs(mid[2] - ISO_SNAPSHOT_BG_B) <
                 30);
    free(pic.rgb);
#endif
    scene_deinit(&s);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(snapshot_shows_mesh_and_distortion),
        cmocka_unit_test(ply_frames_round_trip_exactly),
        cmocka_unit_test(server_serves_page_and_streams_frames),
        cmocka_unit_test(stalled_browser_never_blocks_publish),
        cmocka_unit_test(chromium_renders_live_page),
    };
    return cmocka_run_group_tests_name("display", t, NULL, NULL);
}
