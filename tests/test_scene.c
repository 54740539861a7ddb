/* tests/test_scene.c -- scene files (config/iso_scene.h): the shipped
 * examples load, every error class names FILE:LINE:COL and the key, unknown
 * keys suggest the nearest one, and the struct holds what the file says. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "iso_scene.h"
#include "testutil.h"

/* config/scenes/ of this source tree (from this file's own path). */
static const char *scenes_dir(void)
{
    static char dir[1024];
    snprintf(dir, sizeof dir, "%s", __FILE__);
    char *t = strstr(dir, "tests/test_scene.c");
    if (t)
        snprintf(t, sizeof dir - (size_t)(t - dir), "config/scenes");
    else
        snprintf(dir, sizeof dir, "../config/scenes");
    return dir;
}
#define SCENES scenes_dir()

static int load_text(const char *name, const char *text, iso_scene **s, iso_err *err)
{
    char path[512];
    iso_test_tmp(path, sizeof path, name);
    iso_test_write(path, text, -1);
    iso_err_clear(err);
    return iso_scene_load(path, s, err);
}

/* Asserts that `text` fails with `code` and a message holding each of the
 * NULL-terminated substrings. */
static void expect_error(const char *text, int code, ...)
{
    iso_scene *s = NULL;
    iso_err err;
    int rc = load_text("bad.yaml", text, &s, &err);
    if (rc != code)
        fail_msg("expected code %d, got %d: %s", code, rc, err.msg);
    assert_null(s);
    va_list ap;
    va_start(ap, code);
    const char *sub;
    while ((sub = va_arg(ap, const char *)) != NULL)
        if (!strstr(err.msg, sub))
            fail_msg("message lacks '%s': %s", sub, err.msg);
    va_end(ap);
    assert_non_null(strstr(err.msg, "bad.yaml:"));
}

#define BASE "mesh: {shape: bar, resolution: 4}\n"
#define HANDLES                                                                                    \
    "  handles:\n"                                                                                 \
    "    - name: top\n"                                                                            \
    "      driver: {screw: {duration: 1}}\n"

static void test_examples_load(void **state)
{
    (void)state;
    static const char *const names[] = {"cactus",    "bar",          "cylinder",
                                        "bumpplane", "mouse_cactus", "replay_cactus"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char path[1100];
        snprintf(path, sizeof path, "%s/%s.yaml", SCENES, names[i]);
        iso_scene *s = NULL;
        iso_err err;
        iso_err_clear(&err);
        /* No benchmark lookup: the fallback shape must stand in. */
        int rc = iso_scene_load(path, &s, &err);
        if (rc)
            fail_msg("%s: %s", path, err.msg);
        assert_int_equal(s->mesh_src.used, ISO_SCENE_MESH_SHAPE);
        assert_true(s->mesh_src.note[0] != '\0');
        assert_int_equal(s->n_handles, 1);
        assert_true(s->handles[0].region.count > 0);
        iso_solver *sol = NULL;
        iso_solver_opts so = s->solver;
        so.assembly = ISO_ASSEMBLY_CPU;
        rc = iso_solver_create(s->mesh, &s->regions, &so, &sol, &err);
        if (rc)
            fail_msg("%s: solver: %s", path, err.msg);
        iso_solver_destroy(sol);
        iso_scene_destroy(s);
    }
}

/* With the benchmark present, `isoshape check` (which resolves it like
 * --benchmark does) must use it. */
static void test_check_benchmark(void **state)
{
    (void)state;
    char probe[512], bin[1024];
    if (!iso_test_benchmark(probe, sizeof probe, "03-cactus-bend/cactus.off")) {
        print_message("skipped: benchmark data absent (%s)\n", probe);
        skip();
    }
    if (iso_test_isoshape_bin(bin, sizeof bin) != 0) {
        print_message("skipped: no isoshape binary at %s (set ISOSHAPE_BIN)\n", bin);
        skip();
    }
    char cmd[3072], out[4096], err[4096];
    snprintf(cmd, sizeof cmd, "ISOSHAPE_BENCHMARK_DIR='%s' '%s' check '%s/cactus.yaml'",
             ISO_BENCHMARK_DIR, bin, SCENES);
    int st = iso_test_sh(cmd, out, sizeof out, err, sizeof err);
    if (st != 0)
        fail_msg("isoshape check exited %d: %s%s", st, out, err);
    assert_non_null(strstr(out, "mesh: benchmark cactus"));
    assert_non_null(strstr(out, "ok"));
}

static void test_round_trip(void **state)
{
    (void)state;
    iso_scene *s = NULL;
    iso_err err;
    int rc = load_text(
        "rt.yaml",
        "name: rt\n" BASE "devices:\n"
        "  - {name: m, kind: tcp, address: 'localhost:4000'}\n"
        "  - {name: t, kind: tty, path: /dev/ttyUSB0, baud: 9600, stale_ms: 250}\n"
        "regions:\n"
        "  fixed: {beyond: {point: [0, 0, 1], normal: [0, 0, -1]}}\n"
        "  handles:\n"
        "    - name: top\n"
        "      select: [{beyond: {point: [0, 0, 11], normal: [0, 0, 1]}}]\n"
        "      driver:\n"
        "        device: m\n"
        "        mapping: {sensitivity: {tx: 0.5}, dead_zone: 0.1, invert: [ry],\n"
        "                  remap: {ty: tz}, lock: rotation, dominant: true}\n"
        "    - name: side\n"
        "      select: {box: {min: [-100, -100, 5.5], max: [100, 100, 6.5]}}\n"
        "      driver:\n"
        "        keyframes: [{t: 0}, {t: 1.5, translate: [1, 0, 0], rotate: [0, 0, 90]}]\n"
        "solver: {omega: 0.5, weighting: area, restore: {mu: 2, tau: 0.25},\n"
        "         refactor: always}\n"
        "integrator: {steps_per_tick: 2, restore_kappa: 0.7, abm: pec,\n"
        "             cg_share: 0.25}\n"
        "tick_hz: 120\n"
        "sinks:\n"
        "  display: {port: 9000, snapshot_ticks: [10, 20]}\n"
        "  ply: {dir: out, every: 5}\n"
        "  actuators:\n"
        "    link: {tcp: '127.0.0.1:5555'}\n"
        "    channels:\n"
        "      - {channel: 0, region: top, axis: z, min: -1, max: 1}\n"
        "      - {channel: 1, vertex: 3, axis: x, min: 0, max: 2, scale: 100}\n"
        "recording: rec.isorec\n",
        &s, &err);
    if (rc)
        fail_msg("%s", err.msg);
    assert_string_equal(s->name, "rt");
    assert_int_equal(s->n_devices, 2);
    assert_string_equal(s->devices[0].address, "localhost:4000");
    assert_int_equal(s->devices[1].baud, 9600);
    assert_int_equal(s->devices[0].stale_ms, ISO_SCENE_STALE_MS_DEFAULT);
    assert_int_equal(s->devices[1].stale_ms, 250);
    assert_int_equal(s->n_handles, 2);
    const iso_scene_driver *d = &s->handles[0].driver;
    assert_int_equal(d->kind, ISO_SCENE_DRIVE_DEVICE);
    assert_int_equal(d->device, 0);
    assert_true(d->map.sensitivity[0] == 0.5);
    assert_true(d->map.dead_zone[3] == 0.1);
    assert_int_equal(d->map.invert[4], 1);
    assert_int_equal(d->map.remap[1], 2);
    assert_int_equal(d->map.lock, ISO_DEV_LOCK_ROTATION);
    assert_int_equal(d->map.dominant, 1);
    assert_int_equal(d->map.n_handles, 2);
    assert_int_equal(s->handles[1].driver.n_keys, 2);
    assert_true(s->handles[1].driver.keys[1].rotate[2] == 90);
    assert_true(s->handles[1].region.count > 0);
    assert_true(s->solver.omega == 0.5);
    assert_int_equal(s->solver.weighting, ISO_WEIGHT_AREA);
    assert_true(s->solver.restore_mu == 2 && s->solver.restore_tau == 0.25);
    assert_int_equal(s->solver.refactor, ISO_REFACTOR_ALWAYS);
    assert_int_equal(s->steps_per_tick, 2);
    assert_true(s->integrate.restore_kappa == 0.7);
    assert_true(s->integrate.cg_share == 0.25);
    assert_int_equal(s->abm_mode, ISO_ABM_PEC);
    assert_true(s->tick_hz == 120);
    assert_string_equal(s->display.host, "127.0.0.1");
    assert_int_equal(s->display.port, 9000);
    assert_int_equal(s->display.n_snapshots, 2);
    assert_int_equal(s->ply.every, 5);
    assert_non_null(strstr(s->ply.dir, "/out"));
    assert_int_equal(s->actuators.link, ISO_SCENE_LINK_TCP);
    assert_int_equal(s->actuators.port, 5555);
    assert_int_equal(s->actuators.ch[0].region, 0);
    assert_int_equal(s->actuators.ch[1].vertex, 3);
    assert_non_null(strstr(s->recording, "rec.isorec"));
    int fixed = 0, handle0 = 0;
    for (int v = 0; v < iso_mesh_vertex_count(s->mesh); v++) {
        fixed += s->regions.kind[v] == ISO_FIXED;
        handle0 += s->regions.kind[v] == ISO_HANDLE && s->regions.handle[v] == 0;
    }
    assert_true(fixed > 0 && handle0 > 0);
    assert_int_equal(fixed, s->fixed.count);
    iso_scene_destroy(s);
}

static void test_errors(void **state)
{
    (void)state;
    /* Unknown key with the nearest known one. */
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "solver: {omgea: 0.5}\n", ISO_EPARSE,
                 "bad.yaml:7:", "solver.omgea", "did you mean 'omega'", NULL);
    expect_error(BASE "regoins: {}\n", ISO_EPARSE, "bad.yaml:2:1:", "regoins",
                 "did you mean 'regions'", NULL);
    /* YAML syntax: one line with the line:col of the offending token
     * (libfyaml counts from 1 already: no line or column too far). */
    expect_error("mesh: [1, 2\nregions: {\n", ISO_EPARSE, "bad.yaml:", "YAML syntax error", NULL);
    expect_error("a: 1\nb: [1, 2\n}\n", ISO_EPARSE, "bad.yaml:3:1:", "YAML syntax error", NULL);
    /* A duplicate key points at the second one (line 8, column 1). */
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "tick_hz: 60\ntick_hz: 30\n", ISO_EPARSE,
                 "bad.yaml:8:1:", "duplicate key", NULL);
    expect_error("mesh: {shape: bar, resolution: 4, shape: cactus}\n", ISO_EPARSE,
                 "bad.yaml:1:35:", "duplicate key", NULL);
    /* Anchors and aliases (SCENES.md: not accepted), even one nothing uses. */
    expect_error("mesh: &m {shape: bar, resolution: 4}\nregions:\n  sel: builtin\n" HANDLES,
                 ISO_EPARSE, "bad.yaml:1:11:", "mesh: anchors ('&m') are not accepted", NULL);
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "tick_hz: *rate\n", ISO_EPARSE,
                 "bad.yaml:7:11:", "tick_hz: aliases ('*rate') are not accepted", NULL);
    expect_error(BASE "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                      "      driver: {screw: {duration: &d 1}}\n",
                 ISO_EPARSE, "regions.handles[0].driver.screw.duration: anchors ('&d')", NULL);
    /* Types. */
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "tick_hz: fast\n", ISO_EPARSE,
                 "bad.yaml:7:10:", "tick_hz", "expected a finite number", NULL);
    expect_error(BASE "regions:\n  sel: builtin\n  handles: {a: 1}\n", ISO_EPARSE,
                 "regions.handles", "expected a non-empty list", NULL);
    /* Ranges. */
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "solver: {omega: 1.5}\n", ISO_EINVAL,
                 "bad.yaml:7:17:", "solver.omega", "(0, 1]", NULL);
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "tick_hz: -5\n", ISO_EINVAL,
                 "bad.yaml:7:10:", "tick_hz", NULL);
    /* A device mapping's ranges are devices/'s (iso_dev_map_check), as on the
     * command line. */
    expect_error(BASE "devices:\n  - {name: m, kind: tcp, address: 'localhost:4000'}\n"
                      "regions:\n  sel: builtin\n  handles:\n    - name: top\n"
                      "      driver: {device: m, mapping: {dead_zone: {ry: 0.995}}}\n",
                 ISO_EINVAL, "bad.yaml:8:53:", "regions.handles[0].driver.mapping.dead_zone.ry",
                 "expected a value in [0, 0.99], found 0.995", NULL);
    /* Names come from the enum's own module: a near miss is suggested. */
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "solver: {assembly: openlc}\n",
                 ISO_EPARSE, "solver.assembly", "did you mean 'opencl'", "cpu, opencl", NULL);
    /* Missing keys. */
    expect_error("regions: {}\n", ISO_EPARSE, "bad.yaml:1:1:", "mesh", "missing required key",
                 NULL);
    expect_error(BASE "regions:\n  sel: builtin\n  handles:\n    - name: top\n", ISO_EPARSE,
                 "regions.handles[0].driver", "missing required key", NULL);
    /* Files relative to the scene that do not exist. */
    expect_error("mesh: nothere.off\nregions: {handles: []}\n", ISO_EIO, "bad.yaml:1:7:", "mesh",
                 "nothere.off", "does not exist", NULL);
    expect_error(BASE "regions:\n  sel: no.sel\n" HANDLES, ISO_EIO, "bad.yaml:3:8:", "regions.sel",
                 NULL);
    /* Selections that select nothing; a vertex fixed and on a handle. */
    expect_error(BASE "regions:\n  fixed: {sphere: {center: [500, 0, 0], radius: 1}}\n" HANDLES,
                 ISO_ECONSTRAINT, "bad.yaml:3:11:", "regions.fixed", "selects no vertex", NULL);
    expect_error(BASE "regions:\n  fixed: {vertices: [1, 2]}\n"
                      "  handles:\n    - name: top\n      select: {vertices: [2]}\n"
                      "      driver: none\n",
                 ISO_ECONSTRAINT, "bad.yaml:6:16:", "regions.handles[0].select",
                 "vertex 2 is both fixed and on handle 'top'", NULL);
    /* A driver's device that is not in the list, with a suggestion. */
    expect_error(BASE "devices: [{name: mouse, kind: spnav}]\nregions:\n  sel: builtin\n"
                      "  handles:\n    - name: top\n      driver: {device: mose}\n",
                 ISO_EPARSE, "bad.yaml:7:", "driver.device", "did you mean 'mouse'", NULL);
    /* An enum value with a suggestion; a key of another device kind. */
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "solver: {weighting: aera}\n",
                 ISO_EPARSE, "solver.weighting", "did you mean 'area'", NULL);
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "integrator: {cg_share: 2}\n",
                 ISO_EINVAL, "bad.yaml:", "integrator.cg_share", "[0, 1]", "found 2", NULL);
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "integrator: {abm: pex}\n", ISO_EPARSE,
                 "integrator.abm", "did you mean 'pec'", NULL);
    expect_error(BASE "devices: [{name: m, kind: tty, path: /dev/x, address: 'h:1'}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EPARSE, "devices[0].address", "unknown key", NULL);
    /* A twist stream's stale time: its range, and only on stream kinds. */
    expect_error(BASE "devices: [{name: b, kind: tcp, address: 'h:1', stale_ms: 0}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EINVAL, "bad.yaml:2:", "devices[0].stale_ms",
                 "expected an integer in [1, 10000], found 0", NULL);
    expect_error(BASE "devices:\n  - {name: b, kind: serialport, port: /dev/ttyS0,\n"
                      "     stale_ms: 20000}\nregions:\n  sel: builtin\n" HANDLES,
                 ISO_EINVAL, "bad.yaml:4:16:", "devices[0].stale_ms", "found 20000", NULL);
    expect_error(BASE "devices: [{name: b, kind: tty, path: /dev/x, stale_ms: soon}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EPARSE, "devices[0].stale_ms", "expected an integer, found 'soon'", NULL);
    expect_error(BASE "devices: [{name: m, kind: spnav, stale_ms: 100}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EPARSE, "bad.yaml:2:", "devices[0].stale_ms",
                 "only twist streams time out (kinds tty, tcp, serialport, replay); a spnav "
                 "device reports a state",
                 NULL);
    /* An empty file. */
    expect_error("", ISO_EPARSE, "bad.yaml:1:1:", "empty", NULL);
}

static void test_distance(void **state)
{
    (void)state;
    extern int iso_scene__distance(const char *a, const char *b);
    assert_int_equal(iso_scene__distance("omgea", "omega"), 2);
    assert_int_equal(iso_scene__distance("", "abc"), 3);
    assert_int_equal(iso_scene__distance("tick_hz", "tick_hz"), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_examples_load), cmocka_unit_test(test_check_benchmark),
        cmocka_unit_test(test_round_trip),    cmocka_unit_test(test_errors),
        cmocka_unit_test(test_distance),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
