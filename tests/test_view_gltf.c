/* tests/test_view_gltf.c -- the live page's "Save .glb" in a real headless
 * Chromium: the page, opened with ?glb=1, exports the mesh as shown with
 * three.js's GLTFExporter (libjs-three's examples, served by the view) once
 * its first frame arrived, and says the file's size in the body's data-glb.
 * The size must hold at least the triangles' positions and colours (the
 * page draws nt unindexed triangles: 2 x 36 bytes each), so the exporter
 * found the geometry and its vertex colours. Skips with a reason without
 * Chromium or the exporter. */
#include "cdp.h"
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
    if (access("/usr/share/javascript/three/examples/js/exporters/GLTFExporter.js", R_OK) != 0)
        SKIP_WHY("libjs-three has no GLTFExporter.js in its examples");
    char profile[512], log[512], url[160];
    snprintf(log, sizeof log, "%s/gltf_chromium.log", ISO_TEST_TMP);
    snprintf(profile, sizeof profile, "%s/gltf-chromium-profile", ISO_TEST_TMP);
    iso_cdp cdp;
    int crc = iso_cdp_start(&cdp, profile, log);
    if (crc == 77)
        SKIP_WHY(cdp.why);
    if (crc != 0)
        fail_msg("chromium: %s", cdp.why);
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
    /* The page saves once after its first frame drawn and says the file's
     * size in data-glb: waited for on the page's own state, with a
     * wall-clock bound (a loaded or sanitized machine is slow, never hung). */
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?glb=1", iso_display_port(d));
    int ok = iso_cdp_open(&cdp, url, 60000) == 0 &&
             iso_cdp_wait(&cdp, "document.body.hasAttribute('data-glb')", 90000);
    char *got = ok ? iso_cdp_eval(&cdp, "document.body.getAttribute('data-glb')", 10000) : NULL;
    char why[sizeof cdp.why];
    snprintf(why, sizeof why, "%s", cdp.why);
    iso_cdp_stop(&cdp);
    pthread_mutex_lock(&p.lock);
    p.stop = 1;
    pthread_mutex_unlock(&p.lock);
    pthread_join(th, NULL);
    iso_display_destroy(d);
    long bytes = got ? atol(got) : -1; /* the attribute's text: the file's size */
    free(got);
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    int nt = sh.nt;
    iso_shape_deinit(&sh);
    if (!ok)
        fail_msg("the page did not save a .glb: %s; see %s", why, log);
    print_message("the page's .glb of %d triangles: %ld bytes\n", nt, bytes);
    assert_true(bytes >= 72L * nt);
}

int main(void)
{
    const struct CMUnitTest t[] = {cmocka_unit_test(page_saves_a_glb)};
    return cmocka_run_group_tests_name("view_gltf", t, NULL, NULL);
}
