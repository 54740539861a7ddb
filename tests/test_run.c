/* tests/test_run.c -- `isoshape run`, the real-time loop, as a real process.
 *
 * - Every recording in tests/streams drives the built-in cactus (resolution 1,
 *   570 vertices, C assembly) through the whole loop as fast as possible on
 *   stream time. Two runs give byte-identical final meshes, and the result
 *   matches the golden summary in tests/streams/golden (tick count, distortion,
 *   every 10th vertex). Golden tolerance 1e-7 of the bounding-box diagonal:
 *   the run repeats the same operations, so only the BLAS kernels OpenBLAS
 *   picks for another CPU can move the bits (round-off, ~1e-13 here); any
 *   change of logic moves vertices by 1e-5 or more. Rewrite the goldens
 *   with ISO_UPDATE_GOLDEN=1 after a deliberate change, and say why.
 * - One engine: the same recording through `run` of its scene and through
 *   `isoshape replay --shape` gives the same bytes. A screw driver equals
 *   `isoshape deform --steps N --start adams` to 1e-12 (same integrator, the
 *   loop's low-order start; measured 3e-15).
 *   Keyframes end at their pose.
 * - Time: late ticks cover every deadline already due (ticks + skipped =
 *   the path's periods), latency does not pile up, pacing follows --speed.
 * - SIGTERM mid-run with a live device (a pseudo-terminal) exits 0, leaves
 *   a whole recording, and replaying it reproduces the run's mesh bit for
 *   bit. (tests/test_loop.c drives the engine in-process.)
 * - A headless Chromium opens the live view while a replay runs and receives
 *   frames (screenshot kept as tests/tmp/run_live.png in the build folder).
 * - Bad scenes and options give errors that name what is wrong. */
#define _DEFAULT_SOURCE /* openpty, kill */
#include "cdp.h"
#include "testutil.h"

#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <pty.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "iso_dev_rec.h"
#include "iso_fb.h"
#include "iso_mesh.h"

static char g_bin[PATH_MAX];
static char g_out[1 << 16], g_err[1 << 16];

#define DIAG_TOL_GOLDEN 1e-7
#define DIAG_TOL_DEFORM 1e-12

static const char *const streams[] = {"sm_twist",    "clutch_buttons", "unplug_replug",
                                      "serial_pose", "gpio_estop",     "torn",
                                      "sm_session"};

/* ---- helpers ---------------------------------------------------------------- */

static int iso(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int iso(const char *fmt, ...)
{
    char args[4096], cmd[PATH_MAX + 4200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(args, sizeof args, fmt, ap);
    va_end(ap);
    snprintf(cmd, sizeof cmd, "'%s' %s", g_bin, args);
    return iso_test_sh(cmd, g_out, sizeof g_out, g_err, sizeof g_err);
}

static void json_handle_p(const char *json, double p[3])
{
    const char *q = strstr(json, "\"p\": [");
    assert_non_null(q);
    q += 6;
    for (int j = 0; j < 3; j++) {
        char *end;
        p[j] = strtod(q, &end);
        q = end + 1;
    }
}

static void slurp(const char *path, char *buf, size_t cap)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, cap - 1, f);
    buf[n] = 0;
    fclose(f);
}

static iso_mesh *load(const char *path)
{
    iso_mesh *m = NULL;
    iso_err e;
    iso_err_clear(&e);
    if (iso_mesh_load(path, &m, &e) != ISO_OK)
        fail_msg("%s: %s", path, e.msg);
    return m;
}

static double bbox_diag(const iso_mesh *m)
{
    const double *x = iso_mesh_positions(m);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int v = 0; v < iso_mesh_vertex_count(m); v++)
        for (int j = 0; j < 3; j++) {
            lo[j] = fmin(lo[j], x[3 * v + j]);
            hi[j] = fmax(hi[j], x[3 * v + j]);
        }
    return sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
}

static double max_diff(const char *a, const char *b, double *diag)
{
    iso_mesh *ma = load(a), *mb = load(b);
    int nv = iso_mesh_vertex_count(ma);
    assert_int_equal(nv, iso_mesh_vertex_count(mb));
    double d =
        iso_test_max_abs_diff(iso_mesh_positions(ma), iso_mesh_positions(mb), (size_t)nv * 3);
    *diag = bbox_diag(ma);
    iso_mesh_destroy(ma);
    iso_mesh_destroy(mb);
    return d;
}

static int same_bytes(const char *a, const char *b)
{
    char cmd[2 * PATH_MAX + 16], o[16], e[16];
    snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", a, b);
    return iso_test_sh(cmd, o, sizeof o, e, sizeof e) == 0;
}

/* A scene on the built-in cactus at resolution 1, driven by `driver`. */
static void write_scene(const char *path, const char *devices, const char *driver,
                        const char *extra)
{
    static char text[16384];
    snprintf(text, sizeof text,
             "name: test\n"
             "mesh: {shape: cactus, resolution: 1}\n"
             "%s"
             "regions:\n"
             "  sel: builtin\n"
             "  handles:\n"
             "    - name: top\n"
             "      driver: %s\n"
             "solver: {assembly: cpu, refactor: always}\n"
             "%s",
             devices, driver, extra);
    iso_test_write(path, text, -1);
}

static void replay_scene(const char *path, const char *stream)
{
    char dev[PATH_MAX + 100];
    snprintf(dev, sizeof dev, "devices:\n  - {name: dev, kind: replay, file: %s/%s.isorec}\n",
             ISO_TEST_STREAMS, stream);
    write_scene(path, dev, "{device: dev}", "");
}

/* ---- goldens ------------------------------------------------------------------ */

static void golden_path(char *buf, size_t cap, const char *stream)
{
    snprintf(buf, cap, "%s/golden/%s.txt", ISO_TEST_STREAMS, stream);
}

static void write_golden(const char *stream, const char *json, const char *off)
{
    char path[PATH_MAX];
    golden_path(path, sizeof path, stream);
    iso_mesh *m = load(off);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f,
            "# isoshape run: built-in cactus (resolution 1) driven by %s.isorec, C assembly.\n"
            "# Written by tests/test_run.c with ISO_UPDATE_GOLDEN=1.\n",
            stream);
    fprintf(f, "ticks %.0f\nmetric_err %.17g\n", iso_test_json_num(json, "ticks"),
            iso_test_json_num(json, "metric_err"));
    const double *x = iso_mesh_positions(m);
    for (int v = 0; v < iso_mesh_vertex_count(m); v += 10)
        fprintf(f, "v %d %.17g %.17g %.17g\n", v, x[3 * v], x[3 * v + 1], x[3 * v + 2]);
    fclose(f);
    iso_mesh_destroy(m);
    printf("wrote %s\n", path);
}

static void check_golden(const char *stream, const char *json, const char *off)
{
    char path[PATH_MAX], line[512];
    golden_path(path, sizeof path, stream);
    FILE *f = fopen(path, "r");
    if (!f)
        fail_msg("%s is missing (ISO_UPDATE_GOLDEN=1 writes it)", path);
    iso_mesh *m = load(off);
    double diag = bbox_diag(m), worst = 0;
    const double *x = iso_mesh_positions(m);
    int checked = 0;
    while (fgets(line, sizeof line, f)) {
        double a, b, c;
        int v;
        if (sscanf(line, "ticks %lf", &a) == 1)
            assert_int_equal((long)a, (long)iso_test_json_num(json, "ticks"));
        if (sscanf(line, "metric_err %lf", &a) == 1)
            assert_true(fabs(iso_test_json_num(json, "metric_err") - a) <= 1e-6 * a + 1e-300);
        if (sscanf(line, "v %d %lf %lf %lf", &v, &a, &b, &c) == 4) {
            worst = fmax(worst, fmax(fabs(x[3 * v] - a),
                                     fmax(fabs(x[3 * v + 1] - b), fabs(x[3 * v + 2] - c))));
            checked++;
        }
    }
    fclose(f);
    iso_mesh_destroy(m);
    printf("%-15s golden: %d vertices, max deviation %.3g of the diagonal\n", stream, checked,
           worst / diag);
    assert_true(checked > 10);
    assert_true(worst <= DIAG_TOL_GOLDEN * diag);
}

static void each_stream_replays_deterministically_to_its_golden(void **state)
{
    (void)state;
    int update = getenv("ISO_UPDATE_GOLDEN") != NULL;
    for (size_t i = 0; i < sizeof streams / sizeof streams[0]; i++) {
        const char *s = streams[i];
        char scene[PATH_MAX], a[PATH_MAX], b[PATH_MAX], ja[PATH_MAX], jb[PATH_MAX], name[64];
        snprintf(name, sizeof name, "run_%s.yaml", s);
        replay_scene(iso_test_tmp(scene, sizeof scene, name), s);
        snprintf(name, sizeof name, "run_%s_a.off", s);
        iso_test_tmp(a, sizeof a, name);
        snprintf(name, sizeof name, "run_%s_b.off", s);
        iso_test_tmp(b, sizeof b, name);
        snprintf(name, sizeof name, "run_%s_a.json", s);
        iso_test_tmp(ja, sizeof ja, name);
        snprintf(name, sizeof name, "run_%s_b.json", s);
        iso_test_tmp(jb, sizeof jb, name);
        int st = iso("run '%s' --fast --quiet --out '%s' --stats-json '%s'", scene, a, ja);
        if (st != 0)
            fail_msg("%s: exit %d: %s", s, st, g_err);
        if (strcmp(s, "torn") == 0) /* the damage is reported, the rest replays */
            assert_non_null(strstr(g_err, "byte"));
        assert_int_equal(iso("run '%s' --fast --quiet --out '%s' --stats-json '%s'", scene, b, jb),
                         0);
        assert_true(same_bytes(a, b));
        static char j1[8192], j2[8192];
        slurp(ja, j1, sizeof j1);
        slurp(jb, j2, sizeof j2);
        assert_non_null(strstr(j1, "\"checksum\""));
        assert_string_equal(strstr(j1, "\"checksum\""), strstr(j2, "\"checksum\""));
        char bad[128];
        if (!iso_test_json_keys_snake_case(j1, bad, sizeof bad))
            fail_msg("--stats-json key '%s' is not snake_case", bad);
        assert_true(iso_test_json_num(j1, "ticks") >= 4);
        if (update)
            write_golden(s, j1, a);
        else
            check_golden(s, j1, a);
    }
}

/* ---- independent checks ---------------------------------------------------------- */

/* One engine: a recording through `run` of its scene and through `replay
 * --shape` is the same computation, so the same bits. */
static void loop_agrees_with_the_replay_command(void **state)
{
    (void)state;
    static const char *const which[] = {"sm_twist", "serial_pose", "sm_session"};
    for (size_t i = 0; i < 3; i++) {
        char scene[PATH_MAX], a[PATH_MAX], b[PATH_MAX], name[64];
        snprintf(name, sizeof name, "cross_%s.yaml", which[i]);
        replay_scene(iso_test_tmp(scene, sizeof scene, name), which[i]);
        snprintf(name, sizeof name, "cross_%s_run.off", which[i]);
        iso_test_tmp(a, sizeof a, name);
        snprintf(name, sizeof name, "cross_%s_replay.off", which[i]);
        iso_test_tmp(b, sizeof b, name);
        assert_int_equal(iso("run '%s' --fast --quiet --out '%s'", scene, a), 0);
        assert_int_equal(
            iso("replay --fast '%s/%s.isorec' --shape cactus --resolution 1 --out '%s'",
                ISO_TEST_STREAMS, which[i], b),
            0);
        double diag, d = max_diff(a, b, &diag);
        printf("%-12s run vs replay command: %.3g of the diagonal, same bytes %d\n", which[i],
               d / diag, same_bytes(a, b));
        assert_true(same_bytes(a, b));
    }
}

static void screw_driver_equals_deform(void **state)
{
    (void)state;
    char scene[PATH_MAX], a[PATH_MAX], b[PATH_MAX];
    write_scene(iso_test_tmp(scene, sizeof scene, "screw.yaml"), "",
                "{screw: {def: builtin, duration: 1.0}}", "tick_hz: 20\n");
    iso_test_tmp(a, sizeof a, "screw_run.off");
    iso_test_tmp(b, sizeof b, "screw_deform.off");
    assert_int_equal(iso("run '%s' --fast --quiet --out '%s' --stats-json /dev/null", scene, a), 0);
    assert_int_equal(iso("deform --shape cactus --resolution 1 --steps 20 --start adams "
                         "--restore off --assembly cpu --refactor always --out '%s'",
                         b),
                     0);
    double diag, d = max_diff(a, b, &diag);
    printf("screw: loop vs deform --steps 20 --start adams: %.3g of the diagonal\n", d / diag);
    assert_true(d <= DIAG_TOL_DEFORM * diag);
    assert_int_equal(
        iso("deform --shape cactus --resolution 1 --steps 20 --start rk5 --out '%s'", b), 2);
    assert_non_null(strstr(g_err, "--start 'rk5'"));
}

/* --abm pec: the same screw path at one field evaluation a step instead of
 * two (the start's first step aside), and a result that differs from PECE's by
 * integration error only: both are third order, so PEC lands within a few
 * times PECE's own error (against the offline integrator at 4x the steps)
 * of PECE. */
static void pec_takes_half_the_evaluations(void **state)
{
    (void)state;
    char scene[PATH_MAX], a[PATH_MAX], b[PATH_MAX], ja[PATH_MAX], jb[PATH_MAX];
    static char j[8192];
    write_scene(iso_test_tmp(scene, sizeof scene, "screw_pec.yaml"), "",
                "{screw: {def: builtin, duration: 1.0}}", "tick_hz: 20\n");
    iso_test_tmp(a, sizeof a, "screw_pece.off");
    iso_test_tmp(b, sizeof b, "screw_pec.off");
    iso_test_tmp(ja, sizeof ja, "screw_pece.json");
    iso_test_tmp(jb, sizeof jb, "screw_pec.json");
    assert_int_equal(
        iso("run '%s' --fast --quiet --abm pece --out '%s' --stats-json '%s'", scene, a, ja), 0);
    assert_int_equal(
        iso("run '%s' --fast --quiet --abm pec --out '%s' --stats-json '%s'", scene, b, jb), 0);
    slurp(ja, j, sizeof j);
    long ea = (long)iso_test_json_num(j, "evaluations");
    slurp(jb, j, sizeof j);
    long eb = (long)iso_test_json_num(j, "evaluations");
    assert_non_null(strstr(j, "\"abm\": \"pec\""));
    double diag, d = max_diff(a, b, &diag);
    printf("screw: %ld evaluations under PECE, %ld under PEC; results %.3g of the diagonal apart\n",
           ea, eb, d / diag);
    assert_int_equal(ea, 2 + 19 * 2); /* f(0) and f(x_p), then 19 steps */
    assert_int_equal(eb, 2 + 19 * 1);
    char ref[PATH_MAX];
    iso_test_tmp(ref, sizeof ref, "screw_fine.off");
    assert_int_equal(iso("deform --shape cactus --resolution 1 --steps 80 --restore off "
                         "--assembly cpu --refactor always --out '%s'",
                         ref),
                     0);
    double e_pece = max_diff(a, ref, &diag);
    printf("screw: PECE's own error %.3g of the diagonal\n", e_pece / diag);
    assert_true(d <= 4 * e_pece);
    assert_int_equal(iso("run '%s' --abm pex", scene), 2);
    assert_non_null(strstr(g_err, "--abm 'pex' is unknown: use pece or pec."));
}

static void keyframes_end_at_their_pose(void **state)
{
    (void)state;
    char scene[PATH_MAX], json[PATH_MAX];
    static char j[8192];
    write_scene(iso_test_tmp(scene, sizeof scene, "still.yaml"), "", "none", "tick_hz: 20\n");
    iso_test_tmp(json, sizeof json, "still.json");
    assert_int_equal(iso("run '%s' --fast --quiet --ticks 1 --stats-json '%s'", scene, json), 0);
    slurp(json, j, sizeof j);
    double c[3], p[3];
    json_handle_p(j, c); /* held still: the rest centroid */
    write_scene(scene, "",
                "{keyframes: [{t: 0.5, translate: [0, 0.05, 0], rotate: [20, 0, 0]},"
                " {t: 1.0, translate: [0.02, 0.1, -0.05], rotate: [30, 0, 10]}]}",
                "tick_hz: 40\n");
    iso_test_tmp(json, sizeof json, "keys.json");
    assert_int_equal(iso("run '%s' --fast --quiet --stats-json '%s'", scene, json), 0);
    slurp(json, j, sizeof j);
    json_handle_p(j, p);
    assert_int_equal((long)iso_test_json_num(j, "ticks"), 40);
    const double T[3] = {0.02, 0.1, -0.05};
    for (int k = 0; k < 3; k++) /* rotation about the centroid keeps it: centre = c + T */
        assert_true(fabs(p[k] - (c[k] + T[k])) < 1e-9);
    assert_true(iso_test_json_num(j, "restarts") >= 1); /* the key at 0.5 s is a velocity jump */
}

/* The number the summary line says before (or after) `words`, e.g. "47
 * setpoints sent" or "loop stalls 0". */
static double line_number(const char *line, const char *words, int before)
{
    const char *p = strstr(line, words);
    if (!p)
        fail_msg("the actuators' line lacks '%s': %s", words, line);
    if (!before)
        return strtod(p + strlen(words), NULL);
    while (p > line && p[-1] == ' ')
        p--;
    while (p > line && p[-1] >= '0' && p[-1] <= '9')
        p--;
    return strtod(p, NULL);
}

/* --stats-json gives the actuators' counters one number each, the same
 * numbers the summary line says for people (kept beside them as "line");
 * without actuators, "actuators" is null. */
static void actuator_counters_are_numbers(void **state)
{
    (void)state;
    char scene[PATH_MAX], json[PATH_MAX];
    static char j[16384];
    write_scene(iso_test_tmp(scene, sizeof scene, "act.yaml"), "", "{screw: {duration: 0.5}}",
                "sinks:\n  actuators:\n    link: {emulated: native}\n    channels:\n"
                "      - {channel: 0, region: top, axis: z, min: -1, max: 1, scale: 1000}\n");
    iso_test_tmp(json, sizeof json, "act.json");
    assert_int_equal(iso("run '%s' --no-rt --quiet --stats-json '%s'", scene, json), 0);
    slurp(json, j, sizeof j);
    const char *act = strstr(j, "\"actuators\": {");
    if (!act)
        fail_msg("no actuators object in %s", j);
    char line[4096];
    const char *l = strstr(act, "\"line\": \"");
    assert_non_null(l);
    snprintf(line, sizeof line, "%s", l + strlen("\"line\": \""));
    static const struct {
        const char *key, *words;
        int before;
    } said[] = {{"ticks", " ticks,", 1},
                {"setpoints_sent", " setpoints sent", 1},
                {"acks", " acked", 1},
                {"echo_mismatches", " echo mismatches", 1},
                {"clamps", " clamps,", 1},
                {"link_losses", "losses ", 0},
                {"emu_restarts", "emulation restarts ", 0},
                {"loop_stalls", "loop stalls ", 0},
                {"estops", "e-stops ", 0},
                {"silences", "silences ", 0},
                {"safe_requests", "SAFE requests ", 0},
                {"safe_confirms", "safe states confirmed ", 0}};
    for (size_t i = 0; i < sizeof said / sizeof said[0]; i++) {
        double n = iso_test_json_num(act, said[i].key);
        double m = line_number(line, said[i].words, said[i].before);
        if (n != m)
            fail_msg("actuators.%s is %g, the line says %g: %s", said[i].key, n, m, line);
    }
    double sent = iso_test_json_num(act, "setpoints_sent");
    printf("actuators: %g ticks, %g setpoints sent, %g acked, %g safe states confirmed\n",
           iso_test_json_num(act, "ticks"), sent, iso_test_json_num(act, "acks"),
           iso_test_json_num(act, "safe_confirms"));
    assert_true(sent >= 1 && iso_test_json_num(act, "acks") <= sent);
    assert_true(iso_test_json_num(act, "safe_confirms") >= 1); /* the clean stop */
    assert_non_null(strstr(act, "\"clamps_by_channel\": ["));
    /* no actuators: null, not an empty line */
    write_scene(scene, "", "none", "");
    assert_int_equal(iso("run '%s' --fast --quiet --ticks 1 --stats-json '%s'", scene, json), 0);
    slurp(json, j, sizeof j);
    assert_non_null(strstr(j, "\"actuators\": null"));
}

/* ---- time ------------------------------------------------------------------------ */

/* 1 kHz ticks on a mesh that needs ~10 ms a tick: every tick is late. A
 * late tick covers every deadline already due (no motion lost, no pile-up):
 * the ticks and the deadlines they skipped add up to the 100 of the path,
 * and the handle still ends at the path's end (keyframes_end_at_their_pose
 * checks the pose itself). */
static void overruns_are_counted_and_skipped(void **state)
{
    (void)state;
    char scene[PATH_MAX], json[PATH_MAX];
    static char j[8192];
    write_scene(iso_test_tmp(scene, sizeof scene, "overrun.yaml"), "",
                "{screw: {def: builtin, duration: 0.1}}", "tick_hz: 1000\n");
    iso_test_tmp(json, sizeof json, "overrun.json");
    assert_int_equal(iso("run '%s' --no-rt --quiet --stats-json '%s'", scene, json), 0);
    slurp(json, j, sizeof j);
    double ticks = iso_test_json_num(j, "ticks"), misses = iso_test_json_num(j, "misses");
    double skipped = iso_test_json_num(j, "skipped"), stream = iso_test_json_num(j, "stream_s");
    double wall = iso_test_json_num(j, "wall_s");
    printf("overrun: %.0f ticks, %.0f misses, %.0f skipped, stream %.6f s, wall %.2f s\n", ticks,
           misses, skipped, stream, wall);
    assert_true(ticks < 100);
    assert_true(misses >= 1);
    assert_int_equal((long)(ticks + skipped), 100); /* every period covered, once */
    assert_true(fabs(stream - 0.1) < 1e-12);        /* the path's end, exactly */
    /* no pile-up: a tick starts at once after an overrun, so the wait from one
     * wake to the next publish is at most two tick times */
    const char *lat = strstr(j, "\"latency_ms\"");
    assert_non_null(lat);
    double lat_max = iso_test_json_num(lat, "max");
    const char *tk = strstr(j, "\"tick_ms\"");
    double tick_max = iso_test_json_num(tk, "max");
    assert_true(lat_max <= 2 * tick_max + 5);
}

/* A loop held from outside (the process stopped for a second, as a
 * starved core or a blocked call would hold it) shows in the summary
 * however short every tick was: the deadlines that passed without a tick
 * of their own and the longest wait from one tick to the next, in the
 * JSON and in the printed line. The run still covers every period once. */
static void a_held_loop_shows_in_the_summary(void **state)
{
    (void)state;
    char scene[PATH_MAX], json[PATH_MAX], cmd[3 * PATH_MAX + 300];
    static char j[8192];
    write_scene(iso_test_tmp(scene, sizeof scene, "held.yaml"), "",
                "{screw: {def: builtin, duration: 2.0}}", "tick_hz: 60\n");
    iso_test_tmp(json, sizeof json, "held.json");
    snprintf(cmd, sizeof cmd,
             "{ '%s' run '%s' --no-rt --stats-json '%s' & p=$!; sleep 0.5; kill -STOP $p; "
             "sleep 1; kill -CONT $p; wait $p; }",
             g_bin, scene, json);
    assert_int_equal(iso_test_sh(cmd, g_out, sizeof g_out, g_err, sizeof g_err), 0);
    slurp(json, j, sizeof j);
    double ticks = iso_test_json_num(j, "ticks"), skipped = iso_test_json_num(j, "skipped");
    double gap = iso_test_json_num(j, "gap_max_ms");
    printf("held for 1 s: %.0f ticks, %.0f deadlines without a tick, longest wait %.0f ms\n", ticks,
           skipped, gap);
    assert_int_equal((long)(ticks + skipped), 120); /* every period covered, once */
    assert_true(skipped >= 45); /* a second at 60 Hz, less the machine's slack */
    assert_true(gap >= 900);
    char want[96];
    snprintf(want, sizeof want, "deadlines   %.0f of 120 passed without a tick of their own",
             skipped);
    const char *said = strstr(g_out, want) ? g_out : g_err; /* the summary: stdout or stderr */
    if (!strstr(said, want))
        fail_msg("the summary does not say \"%s\":\n%s%s", want, g_out, g_err);
    assert_non_null(strstr(said, "longest wait between ticks"));
}

static void pacing_follows_speed(void **state)
{
    (void)state;
    char scene[PATH_MAX], json[PATH_MAX];
    static char j[8192];
    write_scene(iso_test_tmp(scene, sizeof scene, "paced.yaml"), "", "none", "tick_hz: 20\n");
    iso_test_tmp(json, sizeof json, "paced.json");
    assert_int_equal(
        iso("run '%s' --no-rt --quiet --duration 1 --speed 2 --stats-json '%s'", scene, json), 0);
    slurp(json, j, sizeof j);
    double wall = iso_test_json_num(j, "wall_s"), stream = iso_test_json_num(j, "stream_s");
    double ticks = iso_test_json_num(j, "ticks"), skipped = iso_test_json_num(j, "skipped");
    printf("paced: %.3f s of stream in %.3f s wall at speed 2, %.0f ticks, %.0f skipped\n", stream,
           wall, ticks, skipped);
    /* every period is covered once: by its own tick, or by a late tick that
     * took it along (a slow sanitizer build merges some) */
    assert_int_equal((long)(ticks + skipped), 20);
    assert_true(fabs(stream - 1.0) < 1e-6);
    assert_true(wall >= 0.45); /* it waited for its deadlines (19 periods of 25 ms) */
}

/* ---- signals and recording ----------------------------------------------------------- */

/* The TICK records in the recording at `path` as it is now (0 while it is
 * absent or has no whole record yet); *bytes gets the DATA bytes and
 * *torn_damaged 1 if the file ends in a torn record plus the damaged ones. */
static long recorded_ticks(const char *path, long *bytes, long *torn_damaged)
{
    iso_dev_rec_reader r;
    iso_err e;
    iso_err_clear(&e);
    if (iso_dev_rec_reader_load(&r, path, &e) != ISO_OK)
        return 0;
    iso_dev_chunk c;
    long ticks = 0, n = 0;
    while (iso_dev_rec_next(&r, &c, NULL) == 1) {
        if (c.type == ISO_DEV_CHUNK_TICK)
            ticks++;
        else if (c.type == ISO_DEV_CHUNK_DATA)
            n += c.len;
    }
    if (bytes)
        *bytes = n;
    if (torn_damaged)
        *torn_damaged = (r.torn != 0) + r.damaged;
    iso_dev_rec_reader_deinit(&r);
    return ticks;
}

/* A pseudo-terminal raw from the start (a cooked line discipline would eat
 * XON, 0x11, before isoshape opens the line and makes it raw itself), and
 * the scene `name` in the tests' folder with it as a tty device `link`
 * driving the handle with `driver`; its path into scene. */
static void tty_scene(const char *name, const char *driver, const char *extra, int *master,
                      int *slave, char *scene, size_t cap)
{
    char tty[256], dev[512];
    assert_int_equal(openpty(master, slave, tty, NULL, NULL), 0);
    struct termios raw;
    assert_int_equal(tcgetattr(*slave, &raw), 0);
    cfmakeraw(&raw);
    assert_int_equal(tcsetattr(*slave, TCSANOW, &raw), 0);
    snprintf(dev, sizeof dev, "devices:\n  - {name: link, kind: tty, path: %s, baud: 115200}\n",
             tty);
    write_scene(iso_test_tmp(scene, cap, name), dev, driver, extra);
}

/* Waits up to 20 s for the recording at path to hold a TICK record; returns
 * the TICK records it holds then. */
static long wait_recorded_ticks(const char *path)
{
    long ticks = 0;
    for (int i = 0; i < 400 && ticks == 0; i++) {
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
        ticks = recorded_ticks(path, NULL, NULL);
    }
    return ticks;
}

static void sigterm_closes_the_recording_whole(void **state)
{
    (void)state;
    int master, slave;
    char scene[PATH_MAX], rec[PATH_MAX], out[PATH_MAX];
    tty_scene("live.yaml", "{device: link}", "tick_hz: 50\n", &master, &slave, scene, sizeof scene);
    iso_test_tmp(rec, sizeof rec, "live.isorec");
    iso_test_tmp(out, sizeof out, "live.off");
    unlink(rec);
    unlink(out);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int null = open("/dev/null", O_WRONLY);
        dup2(null, 1);
        dup2(null, 2);
        execl(g_bin, g_bin, "run", scene, "--no-rt", "--record", rec, "--out", out, (char *)NULL);
        _exit(127);
    }
    /* Wait for the loop's first TICK record: start-up (mesh, solver, and
     * under the sanitizers a slow process start) must not eat the second
     * of line traffic below. */
    long ticks0 = wait_recorded_ticks(rec);
    assert_true(ticks0 > 0); /* within 20 s */
    /* bytes on the line for a second: not frames, so they are counted as
     * garbage, but every one is recorded */
    const uint8_t junk[8] = {0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88};
    for (int i = 0; i < 20; i++) {
        assert_int_equal(write(master, junk, sizeof junk), (ssize_t)sizeof junk);
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    assert_int_equal(kill(pid, SIGTERM), 0);
    int status = 0;
    for (int i = 0; i < 200 && waitpid(pid, &status, WNOHANG) == 0; i++) {
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    if (waitpid(pid, &status, WNOHANG) == 0) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        fail_msg("isoshape run did not stop within 10 s of SIGTERM");
    }
    close(master);
    close(slave);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 128 + SIGTERM); /* stopped by a signal, cleanly */
    assert_int_equal(access(out, R_OK), 0);               /* the final mesh was written */
    long bytes = 0, torn_damaged = -1;
    long ticks = recorded_ticks(rec, &bytes, &torn_damaged);
    printf("recording after SIGTERM: %ld ticks (%ld when the bytes began), %ld bytes, torn or "
           "damaged %ld\n",
           ticks, ticks0, bytes, torn_damaged);
    assert_int_equal(torn_damaged, 0);
    /* The loop went on ticking while the bytes came: 1 s at 50 Hz is ~50
     * ticks in a normal build, ~10 under ASan at -O0 (a tick of this
     * 570-vertex mesh takes ~90 ms there, so most are skipped). */
    assert_true(ticks - ticks0 >= 3);
    assert_int_equal(bytes, 20 * 8);
    /* The run stopped on a whole tick and its recording ends with that tick:
     * replaying it computes the same ticks and the same mesh, bit for bit. */
    char again[PATH_MAX], rscene[PATH_MAX], rdev[PATH_MAX + 100];
    snprintf(rdev, sizeof rdev, "devices:\n  - {name: link, kind: replay, file: %s}\n", rec);
    write_scene(iso_test_tmp(rscene, sizeof rscene, "live_replay.yaml"), rdev, "{device: link}",
                "tick_hz: 50\n");
    iso_test_tmp(again, sizeof again, "live_again.off");
    assert_int_equal(iso("run '%s' --fast --quiet --out '%s'", rscene, again), 0);
    printf("replay of the interrupted session: same bytes %d\n", same_bytes(out, again));
    assert_true(same_bytes(out, again));
}

/* Whether the recording at path ends whole (its END record, no tear). */
static int ends_whole(const char *path)
{
    iso_dev_rec_reader r;
    iso_err e;
    iso_err_clear(&e);
    if (iso_dev_rec_reader_load(&r, path, &e) != ISO_OK)
        return 0;
    char msg[320];
    int cut = iso_dev_rec_reader_cut(&r, msg, sizeof msg, NULL);
    iso_dev_rec_reader_deinit(&r);
    return !cut;
}

/* One pose sample at rest on the line, with the buttons given. */
static void send_sample(int fd, uint16_t seq, unsigned buttons)
{
    iso_fb_sample smp;
    memset(&smp, 0, sizeof smp);
    smp.t_us = seq * 1000u;
    smp.kind = ISO_FB_SAMPLE_POSE;
    smp.buttons = (uint16_t)buttons;
    uint8_t pl[64], fr[ISO_FB_FRAME_MAX];
    int n = iso_fb_sample_pack(pl, sizeof pl, &smp);
    assert_true(n > 0);
    int w = iso_fb_frame_encode(fr, sizeof fr, ISO_FB_HANDLE_SAMPLE, seq, pl, (size_t)n);
    assert_true(w > 0);
    assert_int_equal(write(fd, fr, (size_t)w), (ssize_t)w);
}

/* Presses and releases the line's button 0, 100 ms apart. */
static void press(int fd, uint16_t *seq)
{
    send_sample(fd, ++*seq, 1);
    struct timespec ts = {0, 100 * 1000 * 1000};
    nanosleep(&ts, NULL);
    send_sample(fd, ++*seq, 0);
}

/* Waits up to 20 s for `what` in the file at log. */
static int wait_for_line(const char *log, const char *what)
{
    for (int i = 0; i < 400; i++) {
        static char buf[1 << 16];
        slurp(log, buf, sizeof buf);
        if (strstr(buf, what))
            return 1;
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    return 0;
}

/* The record button (a serial line's button 0 mapped to `record`) in a live
 * run that records from its start: a press ends that recording whole, the
 * next starts another in a file of its own (NAME-2.EXT), which leaves the
 * first as it was, and SIGTERM ends the second whole. The files are opened
 * and closed on the recorder's thread (loop_recorder.c), so the presses
 * cost the tick nothing; what this test holds is what a person sees: two
 * whole recordings, nothing overwritten. */
static void the_record_button_makes_a_file_each_time(void **state)
{
    (void)state;
    int master, slave;
    char scene[PATH_MAX], rec[PATH_MAX], rec2[PATH_MAX], log[PATH_MAX];
    tty_scene("button.yaml", "{device: link, mapping: {buttons: [record]}}", "tick_hz: 50\n",
              &master, &slave, scene, sizeof scene);
    iso_test_tmp(rec, sizeof rec, "button.isorec");
    iso_test_tmp(rec2, sizeof rec2, "button-2.isorec");
    iso_test_tmp(log, sizeof log, "button.log");
    unlink(rec);
    unlink(rec2);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 1);
        dup2(fd, 2);
        execl(g_bin, g_bin, "run", scene, "--no-rt", "--record", rec, (char *)NULL);
        _exit(127);
    }
    assert_true(wait_recorded_ticks(rec) > 0);
    uint16_t seq = 0;
    press(master, &seq);
    int stopped = wait_for_line(log, "recording stopped: ");
    long first = recorded_ticks(rec, NULL, NULL);
    int whole1 = ends_whole(rec);
    press(master, &seq);
    char want[PATH_MAX + 32];
    snprintf(want, sizeof want, "recording to %s", rec2);
    int started = wait_for_line(log, want);
    long second0 = started ? wait_recorded_ticks(rec2) : 0;
    long first_after = recorded_ticks(rec, NULL, NULL);
    kill(pid, SIGTERM);
    int status = 0;
    waitpid(pid, &status, 0);
    close(master);
    close(slave);
    static char said[1 << 16];
    slurp(log, said, sizeof said);
    long second = recorded_ticks(rec2, NULL, NULL);
    printf("record button: first recording %ld ticks (whole %d), second %ld ticks (whole %d)\n",
           first, whole1, second, ends_whole(rec2));
    if (!stopped || !started)
        fail_msg("the button was not said as pressed:\n%s", said);
    assert_true(whole1 && first > 0);
    assert_int_equal(first_after, first); /* the second press left the first file alone */
    assert_true(second0 > 0 && second >= second0);
    assert_true(ends_whole(rec2));
    assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 128 + SIGTERM);
}

/* A recording aimed at a FIFO: `check` says what the run will need (its
 * reader first), and the run, with no reader, refuses it at once and
 * names why, before anything starts; the FIFO is left a FIFO. */
static void a_fifo_recording_without_a_reader_is_said_and_refused(void **state)
{
    (void)state;
    int master, slave;
    char scene[PATH_MAX], fifo[PATH_MAX], extra[PATH_MAX + 32];
    iso_test_tmp(fifo, sizeof fifo, "rec.fifo");
    unlink(fifo);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    snprintf(extra, sizeof extra, "recording: %s\n", fifo);
    tty_scene("fifo_rec.yaml", "{device: link}", extra, &master, &slave, scene, sizeof scene);
    assert_int_equal(iso("check '%s'", scene), 0);
    if (!strstr(g_out, "start its reader before the run"))
        fail_msg("check does not say the FIFO needs its reader:\n%s%s", g_out, g_err);
    double t0 = iso_test_now_s();
    int rc = iso("run '%s' --no-rt --quiet --duration 0.2", scene);
    double took = iso_test_now_s() - t0;
    printf("a FIFO with no reader: run rc %d in %.2f s: %s", rc, took, g_err);
    assert_true(rc != 0);
    assert_non_null(strstr(g_err, "a FIFO that no one reads"));
    assert_true(took < 10);
    struct stat st;
    assert_int_equal(stat(fifo, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
    unlink(fifo);
    close(master);
    close(slave);
}

/* ---- the live view in a real browser ------------------------------------------------ */

/* Waits up to 20 s for "live view on http://127.0.0.1:PORT/" in the log. */
static int wait_for_port(const char *log)
{
    for (int i = 0; i < 400; i++) {
        static char buf[8192];
        FILE *f = fopen(log, "rb");
        if (f) {
            size_t n = fread(buf, 1, sizeof buf - 1, f);
            buf[n] = 0;
            fclose(f);
            const char *p = strstr(buf, "live view on http://127.0.0.1:");
            if (p)
                return atoi(p + strlen("live view on http://127.0.0.1:"));
        }
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    return -1;
}

/* The live view of a replay run in headless Chromium, driven through
 * DevTools: it waits for the page's own state (frames received) rather
 * than virtual time, which a page drawing a live stream does not let run
 * (tests/cdp.h). */
static void chromium_watches_a_replay_run(void **state)
{
    (void)state;
    char profile[PATH_MAX], shot[PATH_MAX], clog[PATH_MAX];
    iso_test_tmp(profile, sizeof profile, "run-chromium-profile");
    iso_test_tmp(shot, sizeof shot, "run_live.png");
    iso_test_tmp(clog, sizeof clog, "run_chromium.log");
    iso_cdp cdp;
    int rc = iso_cdp_start(&cdp, profile, clog); /* before the run: nothing else to fork */
    if (rc == 77) {
        print_message("skipped: %s\n", cdp.why);
        skip();
    }
    if (rc != 0)
        fail_msg("chromium: %s", cdp.why);
    char scene[PATH_MAX], log[PATH_MAX], json[PATH_MAX], dev[PATH_MAX + 100];
    snprintf(dev, sizeof dev,
             "devices:\n  - {name: dev, kind: replay, file: %s/sm_session.isorec}\n",
             ISO_TEST_STREAMS);
    write_scene(iso_test_tmp(scene, sizeof scene, "live_view.yaml"), dev, "{device: dev}",
                "sinks:\n  display: {host: 127.0.0.1}\n");
    iso_test_tmp(log, sizeof log, "live_view.log");
    iso_test_tmp(json, sizeof json, "live_view.json");
    unlink(log);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) { /* 6.5 s of stream at half speed: 13 s or more of updates */
        int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 1);
        dup2(fd, 2);
        execl(g_bin, g_bin, "run", scene, "--no-rt", "--port", "0", "--speed", "0.5",
              "--stats-json", json, (char *)NULL);
        _exit(127);
    }
    int port = wait_for_port(log);
    char url[64], *st = NULL;
    int ok = 0, shot_rc = -1;
    if (port > 0) {
        snprintf(url, sizeof url, "http://127.0.0.1:%d/", port);
        remove(shot);
        ok = iso_cdp_open(&cdp, url, 60000) == 0 &&
             iso_cdp_wait(&cdp,
                          "+document.body.getAttribute('data-frames') >= 2 && "
                          "+document.body.getAttribute('data-tick') > 0",
                          60000);
        st = ok ? iso_cdp_eval(&cdp, "JSON.stringify(window.isoView.state())", 10000) : NULL;
        shot_rc = ok ? iso_cdp_screenshot(&cdp, shot) : -1;
    }
    char why[sizeof cdp.why];
    snprintf(why, sizeof why, "%s", cdp.why);
    iso_cdp_stop(&cdp);
    kill(pid, SIGTERM); /* if it is still running: it stops cleanly */
    int status = 0;
    waitpid(pid, &status, 0);
    if (port <= 0)
        fail_msg("isoshape run printed no live view address; see %s", log);
    /* 0 when the replay had ended, 143 when the SIGTERM stopped it cleanly */
    assert_true(WIFEXITED(status) &&
                (WEXITSTATUS(status) == 0 || WEXITSTATUS(status) == 128 + SIGTERM));
    if (!ok || !st || shot_rc != 0)
        fail_msg("chromium: %s; see %s", why, clog);
    static char j[8192];
    slurp(json, j, sizeof j);
    double sent = iso_test_json_num(j, "frames_sent");
    int frames = (int)iso_cdp_num(st, "frames");
    print_message("chromium: %d frames received; the loop sent %.0f; screenshot %s\n", frames, sent,
                  shot);
    free(st);
    assert_true(frames >= 2); /* updates arrived while the replay ran */
    assert_true(sent >= 2);
    assert_int_equal(access(shot, R_OK), 0);
}

/* ---- bad input ---------------------------------------------------------------------- */

static void bad_input_is_named(void **state)
{
    (void)state;
    char scene[PATH_MAX];
    write_scene(iso_test_tmp(scene, sizeof scene, "missing.yaml"),
                "devices:\n  - {name: dev, kind: replay, file: /nonexistent/x.isorec}\n",
                "{device: dev}", "");
    assert_int_equal(iso("run '%s' --fast --quiet", scene), 1);
    assert_non_null(strstr(g_err, "/nonexistent/x.isorec"));
    assert_int_equal(iso("run '%s' --speed 0", scene), 2);
    assert_non_null(strstr(g_err, "--speed"));
    assert_int_equal(iso("run '%s' --bogus", scene), 2);
    assert_non_null(strstr(g_err, "--bogus"));
    assert_int_equal(iso("run"), 2);
    assert_non_null(strstr(g_err, "SCENE"));
    char dev[PATH_MAX + 200];
    snprintf(dev, sizeof dev,
             "devices:\n  - {name: a, kind: replay, file: %s/sm_twist.isorec}\n"
             "  - {name: b, kind: tcp, address: '127.0.0.1:1'}\n",
             ISO_TEST_STREAMS);
    write_scene(scene, dev, "{device: a}", "");
    assert_int_equal(iso("run '%s' --fast --quiet", scene), 1);
    assert_non_null(strstr(g_err, "replay"));
}

/* Exits and files like a Unix tool: an output folder that cannot be written
 * is refused before the run; a closed stdout is one error and status 1;
 * no output file is ever left half-written. */
static void exits_and_files(void **state)
{
    (void)state;
    char scene[PATH_MAX], cmd[4 * PATH_MAX], o[4096], e[4096], st[PATH_MAX];
    write_scene(iso_test_tmp(scene, sizeof scene, "exits.yaml"), "",
                "{screw: {def: builtin, duration: 0.2}}", "");
    assert_int_equal(iso("run '%s' --fast --quiet --out /nonexistent/dir/x.off", scene), 1);
    assert_non_null(
        strstr(g_err, "--out /nonexistent/dir/x.off: cannot write in /nonexistent/dir"));
    assert_null(strstr(g_err, "tick")); /* refused before the run, not after it */
    assert_int_equal(iso("run '%s' --fast --quiet --record /nonexistent/dir/r.isorec", scene), 1);
    assert_non_null(
        strstr(g_err, "--record /nonexistent/dir/r.isorec: cannot write in /nonexistent/dir"));
    /* stdout closed early: the summary's write fails once, status 1 */
    iso_test_tmp(st, sizeof st, "exits.status");
    snprintf(cmd, sizeof cmd, "{ ( '%s' run '%s' --fast --no-display; echo $? > '%s' ) | true; }",
             g_bin, scene, st);
    iso_test_sh(cmd, o, sizeof o, e, sizeof e);
    char status[32] = "";
    slurp(st, status, sizeof status);
    printf("closed stdout: status %s, stderr: %s", status, e);
    assert_int_equal(atoi(status), 1);
    const char *first = strstr(e, "standard output: Broken pipe");
    assert_non_null(first);
    assert_null(strstr(first + 1, "standard output")); /* said once */
    /* the outputs are whole, with no temporary file left beside them */
    char json[PATH_MAX], dir[PATH_MAX];
    iso_test_tmp(json, sizeof json, "exits.json");
    unlink(json);
    assert_int_equal(iso("run '%s' --fast --quiet --stats-json '%s'", scene, json), 0);
    assert_int_equal(access(json, R_OK), 0);
    snprintf(dir, sizeof dir, "ls '%s' | grep -c 'exits.part-' || true", ISO_TEST_TMP);
    iso_test_sh(dir, o, sizeof o, e, sizeof e);
    assert_int_equal(atoi(o), 0);
}

int main(void)
{
    if (iso_test_isoshape_bin(g_bin, sizeof g_bin) != 0) {
        printf("skipped: no isoshape binary at %s (set ISOSHAPE_BIN)\n", g_bin);
        return ISO_TEST_SKIP;
    }
    const struct CMUnitTest t[] = {
        cmocka_unit_test(each_stream_replays_deterministically_to_its_golden),
        cmocka_unit_test(loop_agrees_with_the_replay_command),
        cmocka_unit_test(screw_driver_equals_deform),
        cmocka_unit_test(pec_takes_half_the_evaluations),
        cmocka_unit_test(keyframes_end_at_their_pose),
        cmocka_unit_test(actuator_counters_are_numbers),
        cmocka_unit_test(overruns_are_counted_and_skipped),
        cmocka_unit_test(a_held_loop_shows_in_the_summary),
        cmocka_unit_test(pacing_follows_speed),
        cmocka_unit_test(sigterm_closes_the_recording_whole),
        cmocka_unit_test(the_record_button_makes_a_file_each_time),
        cmocka_unit_test(a_fifo_recording_without_a_reader_is_said_and_refused),
        cmocka_unit_test(chromium_watches_a_replay_run),
        cmocka_unit_test(bad_input_is_named),
        cmocka_unit_test(exits_and_files),
    };
    return cmocka_run_group_tests(t, NULL, NULL);
}
