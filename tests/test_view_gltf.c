/* tests/test_view_gltf.c -- the live page's "Save .glb" in a real headless
 * Chromium: the page, opened with ?glb=1, exports the mesh as shown with
 * three.js's GLTFExporter (libjs-three's examples, served by the view) once
 * its first frame arrived, and says the file's size in the body's data-glb.
 * The size must hold at least the triangles' positions and colours (the
 * page draws nt unindexed triangles: 2 x 36 bytes each), so the exporter
 * found the geometry and its vertex colours. Skips with a reason without
 * Chromium or the exporter. */
#include "testutil.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "iso_display.h"
#include "iso_shapes.h"

#define SKIP_WHY(why)                                                                              \
    do {                                                                                           \
        print_message("SKIP: %s\n", why);                                                          \
        skip();                                                                                    \
    } while (0)

typedef struct publisher {
    iso_display *d;
    const double *x;
    pthread_mutex_t lock;
    int stop;
} publisher;

static void *publish_main(void *arg)
{
    publisher *p = arg;
    for (long tick = 0;; tick++) {
        pthread_mutex_lock(&p->lock);
        int stop = p->stop;
        pthread_mutex_unlock(&p->lock);
        if (stop)
            return NULL;
        (void)!iso_display_publish(p->d, tick, p->x, NULL, NULL);
        struct timespec ts = {0, 20000000};
        nanosleep(&ts, NULL);
    }
}

static void page_saves_a_glb(void **state)
{
    (void)state;
    if (access("/usr/bin/chromium", X_OK) != 0)
        SKIP_WHY("/usr/bin/chromium is not installed (apt-get install chromium)");
    if (access("/usr/share/javascript/three/examples/js/exporters/GLTFExporter.js", R_OK) != 0)
        SKIP_WHY("libjs-three has no GLTFExporter.js in its examples");
    iso_shape sh;
    iso_err e;
    assert_int_equal(iso_shape_init(&sh, "cylinder", 24, &e), ISO_OK);
    iso_mesh *m = NULL;
    assert_int_equal(iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, "cylinder", &m, &e), ISO_OK);
    iso_regions r;
    assert_int_equal(iso_shape_regions(&sh, &r, &e), ISO_OK);
    iso_display_opts o;
    memset(&o, 0, sizeof o);
    o.mesh = m;
    o.regions = &r;
    iso_display *d = NULL;
    if (iso_display_create(&o, &d, &e) != ISO_OK)
        fail_msg("display: %s", e.msg);
    publisher p = {d, sh.x, PTHREAD_MUTEX_INITIALIZER, 0};
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, publish_main, &p), 0);
    char dom[512], log[512], profile[512], cmd[4096];
    snprintf(dom, sizeof dom, "%s/gltf_dom.html", ISO_TEST_TMP);
    snprintf(log, sizeof log, "%s/gltf_chromium.log", ISO_TEST_TMP);
    snprintf(profile, sizeof profile, "%s/gltf-chromium-profile", ISO_TEST_TMP);
    snprintf(cmd, sizeof cmd,
             "rm -rf '%s' && mkdir -p '%s' && timeout 60 /usr/bin/chromium --headless "
             "--no-sandbox --disable-gpu --disable-quic --no-first-run "
             "--disable-background-networking --disable-component-update --disable-sync "
             "--use-angle=swiftshader --enable-unsafe-swiftshader --mute-audio "
             "--window-size=800,600 --virtual-time-budget=6000 --user-data-dir='%s' --dump-dom "
             "'http://127.0.0.1:%d/?glb=1' >'%s' 2>'%s'",
             profile, profile, profile, iso_display_port(d), dom, log);
    int rc = system(cmd);
    pthread_mutex_lock(&p.lock);
    p.stop = 1;
    pthread_mutex_unlock(&p.lock);
    pthread_join(th, NULL);
    iso_display_destroy(d);
    char rm[600];
    snprintf(rm, sizeof rm, "rm -rf '%s'", profile);
    assert_int_equal(system(rm), 0);
    if (rc != 0)
        fail_msg("chromium failed (%d); see %s", rc, log);
    FILE *f = fopen(dom, "rb");
    assert_non_null(f);
    static char html[1 << 16];
    size_t n = fread(html, 1, sizeof html - 1, f);
    html[n] = 0;
    fclose(f);
    const char *g = strstr(html, "data-glb=\"");
    if (!g)
        fail_msg("the page did not save a .glb (no data-glb in %s)", dom);
    long bytes = atol(g + strlen("data-glb=\""));
    print_message("the page's .glb of %d triangles: %ld bytes\n", sh.nt, bytes);
    assert_true(bytes >= 72L * sh.nt);
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    iso_shape_deinit(&sh);
}

int main(void)
{
    const struct CMUnitTest t[] = {cmocka_unit_test(page_saves_a_glb)};
    return cmocka_run_group_tests_name("view_gltf", t, NULL, NULL);
}
