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

#include "internal.h" /* config/: the scene schema */
#include "iso_names.h"
#include "iso_scene.h"
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
    /* the worker is the adaptive default's: always without worker_lag has none */
    assert_int_equal(s->solver.worker_lag, 0);
    assert_int_equal(s->solver.proxy, ISO_SOLVER_PROXY_AUTO);
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
                 "hid, spnav, tty, tcp, serialport, gpio or replay", NULL);
    /* Explicit keys, refused before libfyaml 0.7.12 sees them: it crashes
     * on "? e:<tab>-" (found by fuzz_scene). */
    expect_error("? e:\t-\n", ISO_EPARSE, "bad.yaml:1:1:", "explicit keys ('? ')", NULL);
    expect_error(BASE "regions:\n  handles:\n    - ? driver\n      : none\n", ISO_EPARSE,
                 "bad.yaml:4:7:", "explicit keys ('? ') are not supported", NULL);
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

/* ------------------------------------------------------------------------ */
/* The schema (config/internal.h)                                            */
/* ------------------------------------------------------------------------ */

#define MESH "mesh: {shape: bar, resolution: 1}"
#define REGIONS "regions: {handles: [{driver: none}]}"
#define TCP_DEVICE "devices: [{name: d, kind: tcp, address: 'h:1'}]"
#define CHANNEL "{channel: 0, vertex: 0, axis: x, min: 0, max: 1}"

/* Where each section is written in a scene: `doc` with %s where the
 * section's mapping content goes, `path` its key path in messages, and
 * off, size: where its struct lies in iso_scene. */
#define AT(member) offsetof(iso_scene, member), sizeof(((iso_scene *)0)->member)
#define WHOLE 0, sizeof(iso_scene)
static const struct place {
    const char *section, *path, *doc;
    size_t off, size;
} places[] = {
    {"", "", "{%s}", WHOLE},
    {"mesh", "mesh", "{mesh: {%s}, " REGIONS "}", AT(mesh_src)},
    {"devices[]", "devices[0]", "{" MESH ", devices: [{%s}], " REGIONS "}", AT(devices[0])},
    {"regions", "regions", "{" MESH ", regions: {%s}}", WHOLE},
    {"regions.handles[]", "regions.handles[0]", "{" MESH ", regions: {handles: [{%s}]}}",
     AT(handles[0])},
    {"selection", "regions.fixed", "{" MESH ", regions: {fixed: {%s}, handles: [{driver: none}]}}",
     AT(fixed.sel[0])},
    {"selection.box", "regions.fixed.box",
     "{" MESH ", regions: {fixed: {box: {%s}}, handles: [{driver: none}]}}", AT(fixed.sel[0])},
    {"selection.sphere", "regions.fixed.sphere",
     "{" MESH ", regions: {fixed: {sphere: {%s}}, handles: [{driver: none}]}}", AT(fixed.sel[0])},
    {"selection.beyond", "regions.fixed.beyond",
     "{" MESH ", regions: {fixed: {beyond: {%s}}, handles: [{driver: none}]}}", AT(fixed.sel[0])},
    {"regions.handles[].driver", "regions.handles[0].driver",
     "{" MESH ", " TCP_DEVICE ", regions: {handles: [{driver: {%s}}]}}", AT(handles[0].driver)},
    {"regions.handles[].driver.mapping", "regions.handles[0].driver.mapping",
     "{" MESH ", " TCP_DEVICE ", regions: {handles: [{driver: {device: d, mapping: {%s}}}]}}",
     AT(handles[0].driver.map)},
    {"regions.handles[].driver.screw", "regions.handles[0].driver.screw",
     "{" MESH ", regions: {handles: [{driver: {screw: {%s}}}]}}", AT(handles[0].driver)},
    {"regions.handles[].driver.keyframes[]", "regions.handles[0].driver.keyframes[0]",
     "{" MESH ", regions: {handles: [{driver: {keyframes: [{%s}]}}]}}",
     AT(handles[0].driver.keys[0])},
    {"solver", "solver", "{" MESH ", " REGIONS ", solver: {%s}}", AT(solver)},
    {"solver.restore", "solver.restore", "{" MESH ", " REGIONS ", solver: {restore: {%s}}}",
     AT(solver)},
    {"integrator", "integrator", "{" MESH ", " REGIONS ", integrator: {%s}}", WHOLE},
    {"sinks", "sinks", "{" MESH ", " REGIONS ", sinks: {%s}}", WHOLE},
    {"sinks.display", "sinks.display", "{" MESH ", " REGIONS ", sinks: {display: {%s}}}",
     AT(display)},
    {"sinks.ply", "sinks.ply", "{" MESH ", " REGIONS ", sinks: {ply: {%s}}}", AT(ply)},
    {"sinks.actuators", "sinks.actuators", "{" MESH ", " REGIONS ", sinks: {actuators: {%s}}}",
     AT(actuators)},
    {"sinks.actuators.link", "sinks.actuators.link",
     "{" MESH ", " REGIONS ", sinks: {actuators: {channels: [" CHANNEL "], link: {%s}}}}",
     AT(actuators)},
    {"sinks.actuators.channels[]", "sinks.actuators.channels[0]",
     "{" MESH ", " REGIONS ", sinks: {actuators: {link: emulated, channels: [{%s}]}}}",
     AT(actuators.ch[0])},
};

/* Values for keys whose kind says too little to make one up. */
static const struct {
    const char *key, *value;
} examples[] = {
    {"mesh", "{shape: bar, resolution: 1}"},
    {"devices", "[{name: d, kind: spnav}]"},
    {"regions", "{handles: [{driver: none}]}"},
    {"solver", "{omega: 0.5}"},
    {"integrator", "{abm: pec}"},
    {"sinks", "{ply: {dir: out}}"},
    {"regions.fixed", "{vertices: [0]}"},
    {"regions.handles", "[{driver: none}]"},
    {"selection.vertices", "[0, 1]"},
    {"selection.box", "{min: [0, 0, 0], max: [1, 1, 1]}"},
    {"selection.sphere", "{center: [0, 0, 0], radius: 1}"},
    {"selection.beyond", "{point: [0, 0, 0], normal: [0, 0, 1]}"},
    {"regions.handles[].select", "[{vertices: [1]}]"},
    {"regions.handles[].driver", "none"},
    {"regions.handles[].driver.device", "d"},
    {"regions.handles[].driver.mapping", "{curve: 2}"},
    {"regions.handles[].driver.screw", "{duration: 1}"},
    {"regions.handles[].driver.keyframes", "[{t: 0}]"},
    {"regions.handles[].driver.mapping.remap", "{ty: tz}"},
    {"regions.handles[].driver.mapping.invert", "[tx]"},
    {"regions.handles[].driver.mapping.buttons", "[clutch]"},
    {"solver.restore", "off"},
    {"solver.restore.mu", "0"},
    {"devices[].address", "'h:1'"},
    {"sinks.display", "{port: 8081}"},
    {"sinks.display.snapshot_ticks", "[1]"},
    {"sinks.ply", "{dir: out}"},
    {"sinks.actuators", "{link: emulated, channels: [" CHANNEL "]}"},
    {"sinks.actuators.link", "emulated"},
    {"sinks.actuators.link.tcp", "'h:1'"},
    {"sinks.actuators.channels", "[" CHANNEL "]"},
    {"sinks.actuators.channels[].region", "fixed"},
    {"sinks.actuators.channels[].min", "0"},
    {"sinks.actuators.channels[].max", "1"},
};

static const struct place *place_of(const scene_section *sec)
{
    for (size_t i = 0; i < sizeof places / sizeof places[0]; i++)
        if (strcmp(places[i].section, sec->name) == 0)
            return &places[i];
    fail_msg("test_scene: no place for section '%s' in places[]", sec->name);
    return NULL;
}

/* Every section once, from the top: n of them into all. */
static int all_sections(const scene_section **all, int cap)
{
    int n = 0;
    all[n++] = &iso_scene__schema;
    for (int i = 0; i < n; i++)
        for (const scene_key *k = all[i]->keys; k->key; k++) {
            int seen = !k->sub;
            for (int j = 0; j < n && !seen; j++)
                seen = all[j] == k->sub;
            if (!seen && n < cap)
                all[n++] = k->sub;
        }
    return n;
}

static const char *const *names_of(const scene_key *k)
{
    return k->names ? k->names : k->names_fn ? k->names_fn() : NULL;
}

/* A value of k's range (or of the devices layer's, for dev). */
static double number_in_range(const scene_key *k)
{
    static const double tries[] = {1, 0.5, 0.1, 2, 10, 350};
    char why[128];
    if (k->dev) {
        for (size_t i = 0; i < sizeof tries / sizeof tries[0]; i++)
            if (iso_dev_map_check(k->dev, tries[i], why, sizeof why) == 0)
                return tries[i];
        fail_msg("%s: no value in the devices layer's range", k->key);
    }
    if (!k->ranged)
        return 1;
    return isinf(k->hi) ? k->lo + 1 : (k->lo + k->hi) / 2;
}

/* A value for row k of sec, as YAML, into buf. */
static const char *sample(const scene_section *sec, const scene_key *k, const char *variant,
                          char *buf, size_t cap)
{
    char key[ISO_SCENE_KEY_MAX];
    iso_scene__join(key, sizeof key, sec->name, k->key);
    for (size_t i = 0; i < sizeof examples / sizeof examples[0]; i++)
        if (strcmp(examples[i].key, key) == 0)
            return examples[i].value;
    switch (k->kind) {
    case SK_NUMBER: snprintf(buf, cap, "%.17g", number_in_range(k)); return buf;
    case SK_INT: snprintf(buf, cap, "%ld", (long)k->lo); return buf;
    case SK_BOOL: return "true";
    case SK_STRING: return "x";
    case SK_FILE: return "f.txt";
    case SK_PATH: return "out";
    case SK_ENUM: return (k->flags & SK_SELECTOR) && variant ? variant : names_of(k)[0];
    case SK_VEC3: return "[0, 0, 1]";
    default: fail_msg("test_scene: no example for %s in examples[]", key);
    }
    return NULL;
}

static int required_for(const scene_key *k, const char *variant)
{
    return (k->flags & SK_REQUIRED) ||
           (k->need && variant && iso_scene__in_words(k->need, variant));
}

/* The variant that row k needs: its first `with`, itself if SK_ONE_OF, or
 * the section's first (SK_ONE_OF key or selector's name). */
static const char *variant_for(const scene_section *sec, const scene_key *k, char *buf, size_t cap)
{
    if (k && k->with) {
        snprintf(buf, cap, "%s", k->with);
        buf[strcspn(buf, " ")] = '\0';
        return buf;
    }
    if (k && (k->flags & SK_ONE_OF))
        return k->key;
    for (const scene_key *o = sec->keys; o->key; o++)
        if (o->flags & SK_ONE_OF)
            return o->key;
        else if (o->flags & SK_SELECTOR)
            return names_of(o)[0];
    return NULL;
}

/* The smallest content of sec that holds row k with `value`, into buf.
 * value NULL: k only chooses the variant and is left out. */
static const char *content(const scene_section *sec, const scene_key *k, const char *value,
                           char *buf, size_t cap)
{
    char vbuf[64], sbuf[64];
    const char *variant = variant_for(sec, k, vbuf, sizeof vbuf);
    size_t n = 0;
    buf[0] = '\0';
    for (const scene_key *r = sec->keys; r->key; r++) {
        int one_of = (r->flags & SK_ONE_OF) && variant && strcmp(r->key, variant) == 0;
        if (r == k && !value)
            continue;
        if (r != k && !required_for(r, variant) && !one_of && !(r->flags & SK_SELECTOR))
            continue;
        const char *v = r == k ? value : sample(sec, r, variant, sbuf, sizeof sbuf);
        n += (size_t)snprintf(buf + n, cap - n, "%s%s: %s", n ? ", " : "", r->key, v);
        assert_true(n < cap);
    }
    return buf;
}

static int load_section(const scene_section *sec, const char *what, iso_scene **s, iso_err *err)
{
    static char doc[8192];
    iso_scene_opts o = {.flags = ISO_SCENE_PARSE_ONLY};
    snprintf(doc, sizeof doc, place_of(sec)->doc, what);
    iso_err_clear(err);
    *s = NULL;
    return iso_scene_load_mem(doc, strlen(doc), "schema.yaml", &o, s, err);
}

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
    lo[0] = hi[0] = '\0';
    if (k->dev) {
        for (size_t i = 0; i < sizeof tries / sizeof tries[0] && !lo[0]; i++)
            if (iso_dev_map_check(k->dev, tries[i], why, sizeof why) != 0)
                snprintf(lo, 64, "%g", tries[i]);
    } else if (k->kind == SK_NUMBER) {
        snprintf(lo, 64, "%.17g", k->lo_open ? k->lo : k->lo - 1);
        if (!isinf(k->hi))
            snprintf(hi, 64, "%.17g", k->hi_open ? k->hi : k->hi + 1);
    } else {
        snprintf(lo, 64, k->kind == SK_LIST ? "[%ld]" : "%ld", (long)k->lo - 1);
        snprintf(hi, 64, k->kind == SK_LIST ? "[%ld]" : "%ld", (long)k->hi + 1);
    }
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
            if (k->ranged || k->dev) {
                out_of_range_values(k, lo, hi);
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
        cmocka_unit_test(test_examples_load),    cmocka_unit_test(test_check_benchmark),
        cmocka_unit_test(test_round_trip),       cmocka_unit_test(test_errors),
        cmocka_unit_test(test_distance),         cmocka_unit_test(test_schema_shape),
        cmocka_unit_test(test_schema_every_key), cmocka_unit_test(test_schema_unknown_key),
        cmocka_unit_test(test_schema_ranges),    cmocka_unit_test(test_schema_defaults),
        cmocka_unit_test(test_schema_scenes_md),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
