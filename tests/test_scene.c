/* tests/test_scene.c -- scene files (config/iso_scene.h): the shipped
 * examples load, every error class names FILE:LINE:COL and the key, unknown
 * keys suggest the nearest one, and the struct holds what the file says.
 *
 * White-box: the second half walks the schema itself (config/internal.h,
 * one table of keys per section) and holds the reader and SCENES.md to it:
 * every key is read and stored where its row says, every section refuses
 * an unknown key with its own nearest one, every range is enforced,
 * documented defaults are the loaded ones, and SCENES.md's key table is
 * the schema's. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "iso_names.h"
#include "iso_scene.h"
#include "scene_schema.h"
#include "testutil.h"

/* `rel` in this source tree (from this file's own path) into buf. */
static const char *source_path(char *buf, size_t cap, const char *rel)
{
    snprintf(buf, cap, "%s", __FILE__);
    char *t = strstr(buf, "tests/test_scene.c");
    if (t)
        snprintf(t, cap - (size_t)(t - buf), "%s", rel);
    else
        snprintf(buf, cap, "../%s", rel);
    return buf;
}

static const char *scenes_dir(void)
{
    static char dir[1024];
    return source_path(dir, sizeof dir, "config/scenes");
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
#define REGIONS_NONE "regions: {handles: [{driver: none}]}\n"
#define HANDLES                                                                                    \
    "  handles:\n"                                                                                 \
    "    - name: top\n"                                                                            \
    "      driver: {screw: {duration: 1}}\n"

static void test_examples_load(void **state)
{
    (void)state;
    static const char *const names[] = {
        "cactus",        "bar",         "cylinder",           "bumpplane",  "mouse_cactus",
        "replay_cactus", "soak_cactus", "replay_fast_cactus", "view_cactus"};
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
    assert_int_equal(s->devices[0].stale_ms, 0); /* not given: its kind's default at run time */
    assert_int_equal(iso_scene_device_stale_ms(&s->devices[0], ISO_DEV_KIND_SERIAL),
                     ISO_SCENE_STALE_MS_DEFAULT);
    assert_int_equal(iso_scene_device_stale_ms(&s->devices[0], ISO_DEV_KIND_VIEW),
                     ISO_SCENE_STALE_MS_VIEW_DEFAULT); /* a replay's recorded view */
    assert_int_equal(iso_scene_device_stale_ms(&s->devices[1], ISO_DEV_KIND_SERIAL),
                     250); /* given */
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
    /* the worker is the adaptive default's: always without worker_lag has none */
    assert_int_equal(s->solver.worker_lag, 0);
    assert_int_equal(s->solver.proxy, ISO_SOLVER_PROXY_AUTO); /* the size decides */
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
    expect_error(
        BASE "regions:\n  sel: builtin\n" HANDLES "tick_hz: fast\n", ISO_EPARSE,
        "bad.yaml:7:10:", "tick_hz: 'fast' is not a number: expected a value in (0, 100000]", NULL);
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
    expect_error(
        BASE "regions:\n  sel: builtin\n" HANDLES "integrator: {cg_share: 2}\n", ISO_EINVAL,
        "bad.yaml:", "integrator.cg_share: '2' is out of range: expected a value in [0, 1]", NULL);
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "integrator: {abm: pex}\n", ISO_EPARSE,
                 "integrator.abm", "did you mean 'pec'", NULL);
    expect_error(BASE "devices: [{name: m, kind: tty, path: /dev/x, address: 'h:1'}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EPARSE, "devices[0].address", "unknown key", NULL);
    /* A twist stream's stale time: its range, and only on stream kinds. */
    expect_error(BASE "devices: [{name: b, kind: tcp, address: 'h:1', stale_ms: 0}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EINVAL, "bad.yaml:2:", "devices[0].stale_ms",
                 "'0' is out of range: expected an integer in [1, 10000]", NULL);
    expect_error(BASE "devices:\n  - {name: b, kind: serialport, port: /dev/ttyS0,\n"
                      "     stale_ms: 20000}\nregions:\n  sel: builtin\n" HANDLES,
                 ISO_EINVAL, "bad.yaml:4:16:", "devices[0].stale_ms: '20000' is out of range",
                 NULL);
    expect_error(BASE "devices: [{name: b, kind: tty, path: /dev/x, stale_ms: soon}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EPARSE, "devices[0].stale_ms",
                 "'soon' is not an integer: expected an integer in [1, 10000]", NULL);
    expect_error(BASE "devices: [{name: m, kind: spnav, stale_ms: 100}]\n"
                      "regions:\n  sel: builtin\n" HANDLES,
                 ISO_EPARSE, "bad.yaml:2:", "devices[0].stale_ms",
                 "only twist and target streams time out (kinds tty, tcp, serialport, replay, "
                 "view); a spnav "
                 "device reports a state",
                 NULL);
    /* Keys that go with another form of their mapping, at the value; a
     * key of another device kind, at the key, with the kind's keys. */
    expect_error("mesh: {shape: bar, fallback_shape: cactus}\n" REGIONS_NONE, ISO_EPARSE,
                 "bad.yaml:1:36:", "mesh.fallback_shape: only goes with benchmark", NULL);
    expect_error(BASE REGIONS_NONE
                 "sinks:\n  actuators:\n    link: {tcp: 'h:1', baud: 9600}\n"
                 "    channels: [{channel: 0, vertex: 0, axis: x, min: 0, max: 1}]\n",
                 ISO_EPARSE,
                 "bad.yaml:5:30:", "sinks.actuators.link.baud: only goes with tty or serial", NULL);
    expect_error(
        BASE "regions:\n  handles:\n    - driver: {screw: {duration: 1}, mapping: {curve: 2}}\n",
        ISO_EPARSE, "bad.yaml:4:48:", "regions.handles[0].driver.mapping: only goes with device",
        NULL);
    expect_error(BASE "devices: [{name: m, kind: tty, path: /dev/x, addres: 'h:1'}]\n" REGIONS_NONE,
                 ISO_EPARSE, "bad.yaml:2:46:", "devices[0].addres: unknown key",
                 "did you mean 'address'", NULL);
    expect_error(BASE
                 "devices: [{name: m, kind: tty, path: /dev/x, address: 'h:1'}]\n" REGIONS_NONE,
                 ISO_EPARSE, "bad.yaml:2:46:", "devices[0].address: unknown key for kind tty",
                 "(expected one of: name, kind, stale_ms, path, baud)", NULL);
    /* A missing enum names its values. */
    expect_error(BASE "devices: [{name: m}]\n" REGIONS_NONE, ISO_EPARSE,
                 "bad.yaml:2:12:", "devices[0].kind: missing required key",
                 "hid, spnav, tty, tcp, serialport, gpio, replay or view", NULL);
    /* Explicit keys, refused before libfyaml 0.7.12 sees them: it crashes
     * on "? e:<tab>-" (found by fuzz_scene). */
    expect_error("? e:\t-\n", ISO_EPARSE, "bad.yaml:1:1:", "explicit keys ('? ')", NULL);
    expect_error(BASE "regions:\n  handles:\n    - ? driver\n      : none\n", ISO_EPARSE,
                 "bad.yaml:4:7:", "explicit keys ('? ') are not supported", NULL);
    /* An empty file. */
    expect_error("", ISO_EPARSE, "bad.yaml:1:1:", "empty", NULL);
}

/* Regions a bar's scene builds: the shape's own fixed and handle. */
#define RGN "regions: {sel: builtin, handles: [{driver: none}]}\n"

/* Loads `text` as a scene (files checked); ISO_OK or fails with the message. */
static void expect_ok(const char *text)
{
    iso_scene *s = NULL;
    iso_err err;
    if (load_text("ok.yaml", text, &s, &err) != ISO_OK)
        fail_msg("refused: %s\n%s", err.msg, text);
    iso_scene_destroy(s);
}

/* YAML's null is no value: an empty value, ~ or null is refused where a
 * key is written, at the key's own line and column (an empty value has no
 * token of its own), with what the key takes; a quoted "~" is text. */
static void test_null_is_no_value(void **state)
{
    (void)state;
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "tick_hz:\n", ISO_EPARSE,
                 "bad.yaml:7:1: tick_hz: expected a value in (0, 100000], found an empty value; "
                 "leave the key out for its default (60)",
                 NULL);
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "recording: ~\n", ISO_EPARSE,
                 "bad.yaml:7:12: recording: expected a file or folder name, found null ('~')",
                 NULL);
    expect_error(BASE "regions:\n  sel: builtin\n" HANDLES "name: null\n", ISO_EPARSE,
                 "bad.yaml:7:7: name: expected a non-empty text, found null;", NULL);
    expect_error(BASE RGN "sinks:\n  ply:\n    dir:\n    every: 2\n", ISO_EPARSE,
                 "bad.yaml:5:5: sinks.ply.dir: expected a file or folder name, found an empty "
                 "value (the key is required)",
                 NULL);
    expect_error(BASE RGN "sinks: {display: {snapshot_dir: Null}}\n", ISO_EPARSE,
                 "bad.yaml:3:33: sinks.display.snapshot_dir:", "found null", NULL);
    expect_error(BASE RGN "sinks:\n  actuators:\n    link: {tty: ~}\n"
                          "    channels: [{channel: 0, vertex: 0, axis: x, min: 0, max: 1}]\n",
                 ISO_EPARSE, "bad.yaml:5:17: sinks.actuators.link.tty:", "found null ('~')", NULL);
    expect_error(BASE RGN "devices:\n  -\n", ISO_EPARSE,
                 "bad.yaml:3:1: devices[0]: expected a device {name, kind, ...}, found an empty "
                 "value",
                 NULL);
    expect_error(BASE RGN "solver: {restore: ~}\n", ISO_EPARSE,
                 "bad.yaml:3:19: solver.restore: expected off or {mu, tau}, found null ('~')",
                 NULL);
    expect_error("mesh:\n" RGN, ISO_EPARSE, "bad.yaml:1:1: mesh:", "found an empty value",
                 "(the key is required)", NULL);
    /* quoted, it is a name like any other */
    expect_ok(BASE "regions:\n  sel: builtin\n" HANDLES "name: '~'\nrecording: 'null'\n");
}

/* What `run` would refuse when it opens its sinks and devices, the loader
 * refuses first, so that `check` says it too, at the key. */
static void test_run_refusals_are_the_loaders(void **state)
{
    (void)state;
    static const char *const remote[] = {"0.0.0.0", "'::'", "192.168.1.20", NULL};
    static const char *const bad[] = {"example.com", "'true'", "987654.5", "'1.2.3.4.5'", NULL};
    static const char *const good[] = {"127.0.0.1", "127.1.2.3", "localhost",
                                       "'::1'",     "'[::1]'",   NULL};
    char text[512];
    for (int i = 0; remote[i]; i++) {
        snprintf(text, sizeof text, BASE RGN "sinks: {display: {host: %s}}\n", remote[i]);
        expect_error(text, ISO_EINVAL, "bad.yaml:3:2",
                     "sinks.display.host:", "can be reached from other machines",
                     "allow_remote: true", NULL);
        snprintf(text, sizeof text, BASE RGN "sinks: {display: {host: %s, allow_remote: true}}\n",
                 remote[i]);
        expect_ok(text);
    }
    for (int i = 0; bad[i]; i++) {
        snprintf(text, sizeof text, BASE RGN "sinks: {display: {host: %s, allow_remote: true}}\n",
                 bad[i]);
        expect_error(text, ISO_EINVAL, "bad.yaml:3:2",
                     "sinks.display.host:", "is not a numeric IPv4 or IPv6 address or localhost",
                     NULL);
    }
    for (int i = 0; good[i]; i++) {
        snprintf(text, sizeof text, BASE RGN "sinks: {display: {host: %s}}\n", good[i]);
        expect_ok(text);
    }
    /* a SETPOINTS frame carries 8 channels; a scale of 0 makes every
     * position one setpoint; a fixed region that is empty */
    expect_error(BASE RGN "sinks:\n  actuators:\n    link: emulated\n"
                          "    channels: [{channel: 8, vertex: 0, axis: x, min: 0, max: 1}]\n",
                 ISO_EINVAL,
                 "bad.yaml:6:26: sinks.actuators.channels[0].channel: '8' is out of "
                 "range: expected an integer in [0, 7]",
                 NULL);
    expect_error(
        BASE RGN "sinks:\n  actuators:\n    link: emulated\n"
                 "    channels: [{channel: 0, vertex: 0, axis: x, min: 0, max: 1, scale: 0}]\n",
        ISO_EINVAL, "bad.yaml:6:72: sinks.actuators.channels[0].scale: '0' is out of range", NULL);
    expect_error(BASE "regions: {handles: [{select: {vertices: [0]}, driver: none}]}\n"
                      "sinks:\n  actuators:\n    link: emulated\n"
                      "    channels: [{channel: 0, region: fixed, axis: x, min: 0, max: 1}]\n",
                 ISO_ECONSTRAINT,
                 "bad.yaml:6:17: sinks.actuators.channels[0].region:", "'fixed' has no vertices",
                 NULL);
    /* a replay stands for the devices it recorded */
    snprintf(text, sizeof text,
             BASE "devices:\n  - {name: r, kind: replay, file: %s/sm_twist.isorec}\n"
                  "  - {name: m, kind: spnav}\n" RGN,
             ISO_TEST_STREAMS);
    expect_error(text, ISO_EINVAL,
                 "bad.yaml:3:21: devices[0].kind: 'replay' stands for every device", NULL);
    /* a recording run could not read is refused at its key */
    char junk[512];
    iso_test_write(iso_test_tmp(junk, sizeof junk, "junk.isorec"), "not a recording at all", -1);
    expect_error(BASE "devices: [{name: r, kind: replay, file: junk.isorec}]\n" RGN, ISO_EPARSE,
                 "bad.yaml:2:41: devices[0].file: ", "not an isoshape recording", NULL);
    /* outputs go in folders that exist, checked before the run */
    expect_error(BASE RGN "sinks: {ply: {dir: no/such/frames}}\n", ISO_EIO,
                 "bad.yaml:3:20: sinks.ply.dir: cannot write", "folder", "does not exist", NULL);
    expect_error(BASE RGN "recording: nowhere/r.isorec\n", ISO_EIO,
                 "bad.yaml:3:12: recording: cannot write", NULL);
    expect_ok(BASE RGN "sinks: {ply: {dir: frames/}}\nrecording: r.isorec\n");
}

/* A bridge on USB is named by its ids as lsusb prints them, in hex; what
 * is not two hex ids of at most four digits (or is 0000:0000) is refused
 * at the value, saying the form. */
static void test_usb_link(void **state)
{
    (void)state;
    static const struct {
        const char *text;
        int vid, pid;
    } good[] = {{"'1209:0001'", 0x1209, 0x0001}, {"'CAFE:babe'", 0xcafe, 0xbabe}, {"'0:1'", 0, 1}};
    static const char *const bad[] = {"'1209'",    "'1209:'", "':0001'", "'12345:1'",
                                      "'1209:1x'", "'0:0'",   "'g:1'",   "1209",
                                      "'-1:2'",    "' 1:2'",  NULL};
    char text[512];
    for (size_t i = 0; i < sizeof good / sizeof good[0]; i++) {
        snprintf(text, sizeof text,
                 BASE RGN "sinks:\n  actuators:\n    link: {usb: %s}\n"
                          "    channels: [{channel: 0, vertex: 0, axis: x, min: 0, max: 1}]\n",
                 good[i].text);
        iso_scene *s = NULL;
        iso_err err;
        if (load_text("ok.yaml", text, &s, &err) != ISO_OK)
            fail_msg("refused: %s\n%s", err.msg, text);
        assert_int_equal(s->actuators.link, ISO_SCENE_LINK_USB);
        assert_int_equal(s->actuators.vid, good[i].vid);
        assert_int_equal(s->actuators.pid, good[i].pid);
        assert_string_equal(iso_scene_link_name(s->actuators.link), "usb");
        iso_scene_destroy(s);
    }
    for (int i = 0; bad[i]; i++) {
        snprintf(text, sizeof text,
                 BASE RGN "sinks:\n  actuators:\n    link: {usb: %s}\n"
                          "    channels: [{channel: 0, vertex: 0, axis: x, min: 0, max: 1}]\n",
                 bad[i]);
        expect_error(text, ISO_EPARSE, "bad.yaml:5:", "sinks.actuators.link.usb: expected VID:PID",
                     NULL);
    }
}

static void test_distance(void **state)
{
    (void)state;
    extern int iso_scene__distance(const char *a, const char *b);
    assert_int_equal(iso_scene__distance("omgea", "omega"), 2);
    assert_int_equal(iso_scene__distance("", "abc"), 3);
    assert_int_equal(iso_scene__distance("tick_hz", "tick_hz"), 0);
}

/* ------------------------------------------------------------------------ */
/* The schema (config/internal.h)                                            */
/* ------------------------------------------------------------------------ */

/* Whether the scalar at obj + k->off is the one `value` says. */
static int stored(const scene_key *k, const void *obj, const char *value, const char *variant)
{
    const char *at = (const char *)obj + k->off;
    double d;
    long l = 0;
    int i;
    switch (k->kind) {
    case SK_NUMBER: memcpy(&d, at, sizeof d); return d == strtod(value, NULL);
    case SK_INT:
        if (k->size == sizeof(long))
            memcpy(&l, at, sizeof l);
        else if (k->size == sizeof(int))
            memcpy(&i, at, sizeof i), l = i;
        else
            l = k->size == 2 ? *(const uint16_t *)at : *(const uint8_t *)at;
        return l == strtol(value, NULL, 0);
    case SK_BOOL: memcpy(&i, at, sizeof i); return i == (strcmp(value, "true") == 0);
    case SK_STRING: return strcmp(at, value) == 0;
    case SK_ENUM:
        if (k->flags & SK_AS_TEXT)
            return strcmp(at, value) == 0;
        memcpy(&i, at, sizeof i);
        (void)variant;
        for (int j = 0; names_of(k)[j]; j++)
            if (strcmp(names_of(k)[j], value) == 0)
                return i == k->first + j;
        return 0;
    default: return 1;
    }
}

/* A scalar key that may be left out changes nothing in its section's
 * struct but its own field. with_text: the content that holds it, and s
 * the scene loaded from it. The key is blanked out rather than cut, so
 * that every other position (which scenes keep for messages) stays. */
static void only_its_field(const scene_section *sec, const scene_key *k, const char *with_text,
                           const iso_scene *with)
{
    const struct place *pl = place_of(sec);
    char without[4096], what[4096];
    iso_scene *s;
    iso_err err;
    if (k->store || k->kind >= SK_LIST || (k->flags & (SK_ONE_OF | SK_SELECTOR)) ||
        required_for(k, k->need))
        return;
    content(sec, k, NULL, without, sizeof without);
    size_t i = 0, cut = strlen(with_text) - strlen(without);
    while (with_text[i] && with_text[i] == without[i])
        i++;
    /* back to where the key's ", key: value" or "key: value, " starts */
    while (i > 0 && with_text[i] != ',' && !(i >= 2 && strncmp(with_text + i - 2, ", ", 2) == 0))
        i--;
    assert_true(strlen(with_text) < sizeof what);
    memcpy(what, with_text, i); /* the same length as with_text */
    memset(what + i, ' ', cut);
    strcpy(what + i + cut, without + i);
    if (load_section(sec, what, &s, &err) != ISO_OK)
        fail_msg("%s.%s: {%s} refused: %s", sec->name, k->key, what, err.msg);
    unsigned char *a = malloc(pl->size), *b = malloc(pl->size);
    assert_true(a && b);
    memcpy(a, (const char *)s + pl->off, pl->size);
    memcpy(b, (const char *)with + pl->off, pl->size);
    if (strcmp(sec->name, "devices[]") == 0) /* points into its own scene */
        for (unsigned char *p = a; p; p = p == a ? b : NULL)
            memset(p + offsetof(iso_scene_device, gpio.chip), 0, sizeof(const char *));
    if (strcmp(sec->name, "regions") == 0 && strcmp(k->key, "sel") == 0) /* where it was */
        for (unsigned char *p = a; p; p = p == a ? b : NULL)
            memset(p + offsetof(iso_scene, sel_line), 0, 2 * sizeof(int));
    for (size_t j = 0; j < pl->size; j++)
        if (a[j] != b[j] && (j < k->off || j >= k->off + k->size))
            fail_msg("%s.%s changes byte %zu of its section, outside its field [%zu, %zu)",
                     sec->name, k->key, j, k->off, k->off + k->size);
    free(a);
    free(b);
    iso_scene_destroy(s);
}

/* Every key of every section is accepted in a smallest scene, and a
 * scalar lands where its row says and nowhere else. */
static void test_schema_every_key(void **state)
{
    (void)state;
    const scene_section *all[64];
    int n = all_sections(all, 64), keys = 0;
    for (int i = 0; i < n; i++)
        for (const scene_key *k = all[i]->keys; k->key; k++) {
            char vbuf[64], sbuf[64], what[4096];
            const char *variant = variant_for(all[i], k, vbuf, sizeof vbuf);
            const char *value = sample(all[i], k, variant, sbuf, sizeof sbuf);
            iso_scene *s;
            iso_err err;
            content(all[i], k, value, what, sizeof what);
            if (load_section(all[i], what, &s, &err) != ISO_OK)
                fail_msg("%s.%s: {%s} refused: %s", all[i]->name, k->key, what, err.msg);
            const void *obj = (const char *)s + place_of(all[i])->off;
            if (!k->store && !stored(k, obj, value, variant))
                fail_msg("%s.%s: %s is not where its row says", all[i]->name, k->key, value);
            only_its_field(all[i], k, what, s);
            iso_scene_destroy(s);
            keys++;
        }
    print_message("%d keys in %d sections accepted\n", keys, n);
    assert_true(keys > 90);
}

/* In every section an unknown key is refused with the section's nearest. */
static void test_schema_unknown_key(void **state)
{
    (void)state;
    const scene_section *all[64];
    int n = all_sections(all, 64);
    for (int i = 0; i < n; i++) {
        const char *first = all[i]->keys[0].key, *path = place_of(all[i])->path;
        char what[256], want[512];
        snprintf(what, sizeof what, "%sq: 1", first);
        iso_scene *s;
        iso_err err;
        assert_int_equal(load_section(all[i], what, &s, &err), ISO_EPARSE);
        snprintf(want, sizeof want, "%s%s%sq: unknown key; did you mean '%s'?", path,
                 *path ? "." : "", first, first);
        if (!strstr(err.msg, want))
            fail_msg("%s: message lacks \"%s\": %s", all[i]->name, want, err.msg);
    }
}

/* Asserts that row k of sec with `value` is refused as out of range,
 * naming its key. */
static void expect_out_of_range(const scene_section *sec, const scene_key *k, const char *value)
{
    char what[4096], key[ISO_SCENE_KEY_MAX];
    iso_scene *s;
    iso_err err;
    content(sec, k, value, what, sizeof what);
    int rc = load_section(sec, what, &s, &err);
    iso_scene__join(key, sizeof key, place_of(sec)->path, k->key);
    if (rc != ISO_EINVAL || !strstr(err.msg, key))
        fail_msg("%s: %s: expected ISO_EINVAL naming %s, got %d: %s", key, value, key, rc, err.msg);
}

/* A value out of range at each end that has one (devices/' ranges: the
 * first it refuses). */
static void out_of_range_values(const scene_key *k, char lo[64], char hi[64])
{
    static const double tries[] = {-1, 0, 0.995, 11, 2e6};
    char why[128];
    iso_range r;
    lo[0] = hi[0] = '\0';
    if (k->dev) {
        for (size_t i = 0; i < sizeof tries / sizeof tries[0] && !lo[0]; i++)
            if (iso_dev_map_check(k->dev, tries[i], why, sizeof why) != 0)
                snprintf(lo, 64, "%g", tries[i]);
        return;
    }
    iso_scene__range(k, &r);
    const char *form = k->kind == SK_LIST ? "[%.17g]" : "%.17g";
    /* an open end is itself out, a closed one 1 past it */
    if (r.lo_end)
        snprintf(lo, 64, form, r.lo_end == ISO_RANGE_OPEN ? r.lo : r.lo - 1);
    if (r.hi_end)
        snprintf(hi, 64, form, r.hi_end == ISO_RANGE_OPEN ? r.hi : r.hi + 1);
}

/* Every ranged key refuses a value beyond each end, and every list with a
 * length limit refuses one item more, naming the key. */
static void test_schema_ranges(void **state)
{
    (void)state;
    const scene_section *all[64];
    int n = all_sections(all, 64), ranged = 0;
    for (int i = 0; i < n; i++)
        for (const scene_key *k = all[i]->keys; k->key; k++) {
            char lo[64], hi[64], many[512] = "[";
            iso_range r;
            if (iso_scene__range(k, &r) || k->dev) {
                out_of_range_values(k, lo, hi);
                if (lo[0])
                    expect_out_of_range(all[i], k, lo);
                if (hi[0])
                    expect_out_of_range(all[i], k, hi);
                ranged++;
            }
            if (k->kind == SK_LIST && k->max_items > 0) {
                for (int j = 0; j <= k->max_items; j++)
                    strcat(many, j ? ", 0" : "0");
                strcat(many, "]");
                expect_out_of_range(all[i], k, many);
                ranged++;
            }
        }
    print_message("%d ranges and lengths refused\n", ranged);
    assert_true(ranged > 30);
}

/* A default SCENES.md shows as a value ("1/3", "0 (any)", "hold") is what
 * a scene without the key loads. */
static int parse_default(const scene_key *k, char *value, size_t cap)
{
    const char *d = k->dflt;
    char *end;
    if (!d || k->store ||
        !(k->kind == SK_NUMBER || k->kind == SK_INT || k->kind == SK_BOOL ||
          (k->kind == SK_ENUM && !(k->flags & SK_AS_TEXT))))
        return 0;
    size_t len = strcspn(d, " ");
    if (strcmp(d + len, "") != 0 && strncmp(d + len, " (", 2) != 0)
        return 0;
    snprintf(value, cap, "%.*s", (int)len, d);
    double a = strtod(value, &end), b;
    if (*end == '/' && (b = strtod(end + 1, &end)) != 0 && *end == '\0')
        snprintf(value, cap, "%.17g", a / b);
    return 1;
}

static void test_schema_defaults(void **state)
{
    (void)state;
    const scene_section *all[64];
    int n = all_sections(all, 64), checked = 0;
    for (int i = 0; i < n; i++)
        for (const scene_key *k = all[i]->keys; k->key; k++) {
            char value[64], what[4096], vbuf[64];
            if (!parse_default(k, value, sizeof value))
                continue;
            const char *variant = variant_for(all[i], k, vbuf, sizeof vbuf);
            iso_scene *s;
            iso_err err;
            content(all[i], k, NULL, what, sizeof what);
            if (load_section(all[i], what, &s, &err) != ISO_OK)
                fail_msg("%s.%s: {%s} refused: %s", all[i]->name, k->key, what, err.msg);
            const void *obj = (const char *)s + place_of(all[i])->off;
            if (!stored(k, obj, value, variant))
                fail_msg("%s.%s: SCENES.md's default '%s' is not what loads", all[i]->name, k->key,
                         k->dflt);
            iso_scene_destroy(s);
            checked++;
        }
    print_message("%d documented defaults are the loaded ones\n", checked);
    assert_true(checked > 30);
}

/* Sections are named by where they hang; the variants a row names exist. */
static void test_schema_shape(void **state)
{
    (void)state;
    const scene_section *all[64];
    int n = all_sections(all, 64);
    for (int i = 0; i < n; i++) {
        int rows = 0;
        for (const scene_key *k = all[i]->keys; k->key; k++, rows++) {
            char want[ISO_SCENE_KEY_MAX];
            iso_scene__join(want, sizeof want, all[i]->name, k->key);
            if (k->kind == SK_LIST)
                strcat(want, "[]");
            if (k->sub && !(k->flags & SK_ONE_OR_LIST) && strcmp(k->sub->name, want) != 0)
                fail_msg("section '%s' hangs at %s", k->sub->name, want);
            assert_true(iso_scene__row(all[i], k->key) == k); /* each key once */
            const char *words[] = {k->with, k->need};
            for (int w = 0; w < 2; w++) {
                char list[128], *save = NULL;
                snprintf(list, sizeof list, "%s", words[w] ? words[w] : "");
                for (char *v = strtok_r(list, " ", &save); v; v = strtok_r(NULL, " ", &save)) {
                    int found = 0;
                    for (const scene_key *o = all[i]->keys; o->key; o++)
                        found |= ((o->flags & SK_ONE_OF) && strcmp(o->key, v) == 0) ||
                                 ((o->flags & SK_SELECTOR) && iso_names_find(names_of(o), v) >= 0);
                    if (!found)
                        fail_msg("%s.%s: no variant '%s'", all[i]->name, k->key, v);
                }
            }
            assert_non_null(k->help);
            char range[64];
            if (k->dev && !iso_scene__range_text(k, range, sizeof range)[0])
                fail_msg("%s.%s: no range read from the devices layer's message for '%s'",
                         all[i]->name, k->key, k->dev);
        }
        assert_true(rows > 0 && rows <= ISO_SCENE_SECTION_KEYS);
    }
}

/* ---- SCENES.md's key table ------------------------------------------------ */

typedef struct md_row {
    char key[ISO_SCENE_KEY_MAX];
    char cells[6][512]; /* key, type, range, default, with, what */
} md_row;

/* Splits a table line into cells at unescaped '|'; returns the count. */
static int split_row(const char *line, md_row *r)
{
    int n = -1;
    size_t len = 0;
    for (const char *p = line; *p && *p != '\n'; p++) {
        if (*p == '|' && (p == line || p[-1] != '\\')) {
            if (n >= 0 && n < 6) {
                char *c = r->cells[n];
                c[len] = '\0';
                while (*c == ' ')
                    memmove(c, c + 1, strlen(c));
                for (size_t e = strlen(c); e && c[e - 1] == ' ';)
                    c[--e] = '\0';
            }
            n++;
            len = 0;
        } else if (n >= 0 && n < 6 && len + 1 < sizeof r->cells[0]) {
            r->cells[n][len++] = *p;
        }
    }
    snprintf(r->key, sizeof r->key, "%.*s", (int)strcspn(r->cells[0] + 1, "`"), r->cells[0] + 1);
    return n;
}

/* The key rows ("| `...") of text, into rows; returns how many. */
static int table_rows(const char *text, md_row *rows, int cap)
{
    int n = 0;
    for (const char *p = text; p && *p; p = strchr(p, '\n'), p = p ? p + 1 : NULL)
        if (strncmp(p, "| `", 3) == 0 && n < cap && split_row(p, &rows[n]) == 6)
            n++;
    return n;
}

static const md_row *find_row(const md_row *rows, int n, const char *key)
{
    for (int i = 0; i < n; i++)
        if (strcmp(rows[i].key, key) == 0)
            return &rows[i];
    return NULL;
}

/* SCENES.md's table is the schema's: no key missing, none extra, and each
 * row's type, range, default, variants and description the same.
 * build/tests/tools/scene_keys config/SCENES.md rewrites it. */
static void test_schema_scenes_md(void **state)
{
    (void)state;
    static const char *const columns[] = {"key", "type", "range", "default", "with", "what"};
    static md_row doc[256], gen[256];
    char path[1024], *text = NULL, *table = NULL;
    size_t len = 0;
    FILE *f = fopen(source_path(path, sizeof path, "config/SCENES.md"), "rb");
    assert_non_null(f);
    text = calloc(1, 1 << 20);
    assert_non_null(text);
    len = fread(text, 1, (1 << 20) - 1, f);
    fclose(f);
    assert_true(len > 0);
    FILE *m = open_memstream(&table, &len);
    iso_scene__doc_table(m);
    fclose(m);
    int nd = table_rows(text, doc, 256), ng = table_rows(table, gen, 256), bad = 0;
    for (int i = 0; i < ng; i++) {
        const md_row *d = find_row(doc, nd, gen[i].key);
        if (!d && ++bad)
            print_error("SCENES.md lacks key %s (schema: %s)\n", gen[i].key, gen[i].cells[5]);
        for (int c = 1; d && c < 6; c++)
            if (strcmp(d->cells[c], gen[i].cells[c]) != 0 && ++bad)
                print_error("SCENES.md: %s: %s is '%s', the schema says '%s'\n", gen[i].key,
                            columns[c], d->cells[c], gen[i].cells[c]);
    }
    for (int i = 0; i < nd; i++)
        if (!find_row(gen, ng, doc[i].key) && ++bad)
            print_error("SCENES.md names key %s, which the schema lacks\n", doc[i].key);
    if (bad)
        fail_msg("SCENES.md's key table: %d differences from the schema "
                 "(build/tests/tools/scene_keys config/SCENES.md rewrites it)",
                 bad);
    assert_true(ng > 90);
    free(table);
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_examples_load),
        cmocka_unit_test(test_check_benchmark),
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_usb_link),
        cmocka_unit_test(test_distance),
        cmocka_unit_test(test_schema_shape),
        cmocka_unit_test(test_null_is_no_value),
        cmocka_unit_test(test_run_refusals_are_the_loaders),
        cmocka_unit_test(test_schema_every_key),
        cmocka_unit_test(test_schema_unknown_key),
        cmocka_unit_test(test_schema_ranges),
        cmocka_unit_test(test_schema_defaults),
        cmocka_unit_test(test_schema_scenes_md),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
