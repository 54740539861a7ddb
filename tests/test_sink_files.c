/* tests/test_sink_files.c -- the file outputs and the tick that feeds them.
 *
 * - Nothing allocates on the loop's thread once it ticks: malloc, calloc and
 *   realloc are interposed here and counted on the loop's thread only,
 *   between its 5th tick and its 30th, with the live view, PLY frames, a PC2
 *   cache, an MCAP file and a device recording all on (the recording then
 *   read back whole: its 30 ticks and its END record). Allocations made inside CHOLMOD or the
 *   BLAS (a factorization's workspace, when the solver factors on the
 *   evaluating thread) are the solver's: they are counted apart, by the
 *   caller's library, and printed, not asserted. (Under AddressSanitizer,
 *   whose allocator the interposition would bypass, the test skips with a
 *   reason.)
 * - A PC2 cache read back by a reader written here from the format (32-byte
 *   header, frame-major little-endian float32 xyz) holds the run's PLY
 *   frames bit for bit after rounding to float32, one frame a tick.
 * - A run killed with SIGKILL mid-way leaves its cache (under its temporary
 *   name) well formed: the header's frame count is whole frames that are
 *   all in the file, and they are finite.
 * - `deform --pc2` writes the rest pose and one frame per step. */
#define _GNU_SOURCE /* dladdr */
#include "testutil.h"

#include <dlfcn.h>
#include <execinfo.h>

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "iso_dev_rec.h"
#include "iso_foxglove.h"
#include "iso_loop.h"
#include "iso_mesh.h"
#include "iso_shapes.h"

#if defined(__SANITIZE_ADDRESS__)
#define UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UNDER_ASAN 1
#endif
#endif
#ifndef UNDER_ASAN
#define UNDER_ASAN 0
#endif

/* A skip that says why (cmocka's skip() says nothing). */
#define skip_msg(why)                                                                              \
    do {                                                                                           \
        print_message("SKIP: %s\n", why);                                                          \
        skip();                                                                                    \
    } while (0)

/* ---- the allocation counter ------------------------------------------- */

static _Thread_local int t_counting; /* set on the loop's thread from its 5th tick */
static long g_allocs;                /* allocations while t_counting (one thread) */
static long g_solver_allocs;         /* of those, made inside CHOLMOD or the BLAS */

#if !UNDER_ASAN
/* Counts one allocation: the solver's libraries' apart. backtrace and
 * dladdr do not allocate once backtrace has run once (the test runs it
 * before it counts). */
static void count_one(void)
{
    t_counting = 0;
    void *b[40];
    int n = backtrace(b, 40);
    int solver = 0;
    for (int i = 0; i < n && !solver; i++) {
        Dl_info di;
        if (dladdr(b[i], &di) && di.dli_fname)
            solver = strstr(di.dli_fname, "cholmod") || strstr(di.dli_fname, "blas") ||
                     strstr(di.dli_fname, "lapack");
    }
    if (solver)
        g_solver_allocs++;
    else
        g_allocs++;
    t_counting = 1;
}

extern void *__libc_malloc(size_t n);
extern void *__libc_calloc(size_t n, size_t m);
extern void *__libc_realloc(void *p, size_t n);

void *malloc(size_t n)
{
    if (t_counting)
        count_one();
    return __libc_malloc(n);
}

void *calloc(size_t n, size_t m)
{
    if (t_counting)
        count_one();
    return __libc_calloc(n, m);
}

void *realloc(void *p, size_t n)
{
    if (t_counting)
        count_one();
    return __libc_realloc(p, n);
}
#endif

typedef struct count_ctx {
    long from_tick, last_tick;
    long at_from, at_last, solver_from, solver_last;
} count_ctx;

static void count_ticks(void *ctx, const iso_loop_tick_info *t)
{
    count_ctx *c = ctx;
    if (t->tick == c->from_tick) {
        c->at_from = g_allocs;
        c->solver_from = g_solver_allocs;
        t_counting = 1;
    }
    if (t->tick == c->last_tick) {
        c->at_last = g_allocs;
        c->solver_last = g_solver_allocs;
        t_counting = 0;
    }
}

static iso_scene *scene_text(const char *text)
{
    iso_scene *sc = NULL;
    iso_err e;
    iso_err_clear(&e);
    if (iso_scene_load_mem(text, strlen(text), "t", NULL, &sc, &e) != ISO_OK)
        fail_msg("scene: %s", e.msg);
    return sc;
}

/* The built-in cactus (570 vertices), its top bent by a scripted screw,
 * PLY frames of every tick into dir. */
/* With rec, a view device beside the screw (live: it makes the loop's
 * hub) and its recording to rec. */
static iso_scene *bending_scene_rec(const char *dir, int display, const char *rec)
{
    static char text[4096], dev[1200];
    snprintf(dev, sizeof dev, "devices:\n  - {name: hand, kind: view}\nrecording: %s\n",
             rec ? rec : "");
    snprintf(text, sizeof text,
             "name: t\n"
             "mesh: {shape: cactus, resolution: 1}\n%s"
             "regions:\n  sel: builtin\n  handles:\n    - name: top\n      driver: {screw: "
             "{def: builtin, duration: 0.5}}\n"
             "solver: {assembly: cpu, refactor: adaptive, worker_lag: 4}\n"
             "tick_hz: 60\n"
             "sinks:\n%s  ply: {dir: %s, every: 1}\n",
             rec ? dev : "", display ? "  display: {port: 8080}\n" : "", dir);
    return scene_text(text);
}

static iso_scene *bending_scene(const char *dir, int display)
{
    return bending_scene_rec(dir, display, NULL);
}

static void tick_allocates_nothing(void **state)
{
    (void)state;
    if (UNDER_ASAN)
        skip_msg("AddressSanitizer's allocator is not the one this test counts; the plain "
                 "build runs it");
    char dir[512], pc2[512], mcap[512], rec[512];
    snprintf(dir, sizeof dir, "%s/alloc_frames", ISO_TEST_TMP);
    snprintf(pc2, sizeof pc2, "%s/alloc.pc2", ISO_TEST_TMP);
    snprintf(mcap, sizeof mcap, "%s/alloc.mcap", ISO_TEST_TMP);
    snprintf(rec, sizeof rec, "%s/alloc.isorec", ISO_TEST_TMP);
    iso_scene *sc = bending_scene_rec(dir, 1, rec);
    iso_loop_opts o;
    iso_loop_opts_default(&o);
    o.fast = 1;
    o.pc2 = pc2;
    o.mcap = mcap;
    o.port = 0;
    o.max_ticks = 30; /* the view device makes the run open-ended */
    FILE *log = tmpfile();
    o.log = log;
    count_ctx c = {5, 30, -1, -1, 0, 0};
    void *warm[4];
    (void)!backtrace(warm, 4); /* its first call loads libgcc and allocates */
    o.on_tick = count_ticks;
    o.hook_ctx = &c;
    iso_loop *l = NULL;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_loop_create(sc, &o, &l, &e), ISO_OK);
    assert_int_equal(iso_loop_run(l, &e), ISO_OK);
    assert_int_equal(iso_loop_shutdown(l, &e), ISO_OK);
    iso_loop_summary s;
    iso_loop_get_summary(l, &s);
    assert_true(s.ticks == 30);
    assert_true(c.at_from >= 0 && c.at_last >= 0);
    print_message("allocations on the loop's thread between tick 5 and tick 30: %ld by the loop "
                  "and its sinks, %ld inside CHOLMOD or the BLAS (PLY frames %ld, PC2 frames %ld, "
                  "MCAP messages %ld)\n",
                  c.at_last - c.at_from, c.solver_last - c.solver_from, s.ply_frames, s.pc2_frames,
                  s.mcap_messages);
    assert_int_equal(c.at_last - c.at_from, 0);
    assert_int_equal(s.ply_frames, 30);
    assert_int_equal(s.pc2_frames, 30);
    iso_dev_rec_reader r; /* the recording is whole: its 30 ticks and its END */
    assert_int_equal(iso_dev_rec_reader_load(&r, rec, &e), ISO_OK);
    iso_dev_chunk ch;
    long rec_ticks = 0;
    while (iso_dev_rec_next(&r, &ch, NULL) == 1)
        rec_ticks += ch.type == ISO_DEV_CHUNK_TICK;
    assert_int_equal(rec_ticks, 30);
    assert_true(r.ended && !r.torn);
    iso_dev_rec_reader_deinit(&r);
    assert_true(s.mcap_messages >= 30 * 4);
    assert_int_equal(s.frames_dropped, 0); /* --fast waits for the writer instead */
    /* the tick's side of the outputs was timed on every tick that wrote */
    assert_true(s.handoff_ms_mean > 0 && s.handoff_ms_max >= s.handoff_ms_mean);
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    fclose(log);
}

/* ---- an independent PC2 reader ---------------------------------------- */

typedef struct pc2_file {
    int32_t version, nv, frames;
    float start, sampling;
    long size;
    float *xyz; /* frames * nv * 3 */
} pc2_file;

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static float lef(const unsigned char *p)
{
    uint32_t u = le32(p);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* Reads path as the format says; fails the test on anything malformed. */
static void pc2_read(const char *path, pc2_file *f)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        fail_msg("%s: %s", path, strerror(errno));
    unsigned char h[32];
    assert_int_equal(fread(h, 1, 32, fp), 32);
    assert_memory_equal(h, "POINTCACHE2\0", 12);
    f->version = (int32_t)le32(h + 12);
    f->nv = (int32_t)le32(h + 16);
    f->start = lef(h + 20);
    f->sampling = lef(h + 24);
    f->frames = (int32_t)le32(h + 28);
    assert_int_equal(f->version, 1);
    assert_true(f->nv > 0 && f->frames > 0); /* Blender refuses 0 frames */
    fseek(fp, 0, SEEK_END);
    f->size = ftell(fp);
    long need = 32 + (long)f->frames * f->nv * 12;
    if (f->size < need)
        fail_msg("%s: %d frames of %d vertices need %ld bytes, the file has %ld", path, f->frames,
                 f->nv, need, f->size);
    fseek(fp, 32, SEEK_SET);
    size_t n = (size_t)f->frames * (size_t)f->nv * 3;
    unsigned char *raw = malloc(n * 4);
    f->xyz = malloc(n * sizeof *f->xyz);
    assert_non_null(raw);
    assert_non_null(f->xyz);
    assert_int_equal(fread(raw, 4, n, fp), n);
    for (size_t i = 0; i < n; i++)
        f->xyz[i] = lef(raw + 4 * i);
    free(raw);
    fclose(fp);
}

static void pc2_matches_the_ply_frames(void **state)
{
    (void)state;
    char dir[512], pc2[512], rest[512];
    snprintf(dir, sizeof dir, "%s/pc2_frames", ISO_TEST_TMP);
    snprintf(pc2, sizeof pc2, "%s/bend.pc2", ISO_TEST_TMP);
    snprintf(rest, sizeof rest, "%s/bend.rest.ply", ISO_TEST_TMP);
    unlink(pc2);
    iso_scene *sc = bending_scene(dir, 0);
    iso_loop_opts o;
    iso_loop_opts_default(&o);
    o.fast = 1;
    o.pc2 = pc2;
    FILE *log = tmpfile();
    o.log = log;
    iso_loop *l = NULL;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_loop_create(sc, &o, &l, &e), ISO_OK);
    assert_int_equal(iso_loop_run(l, &e), ISO_OK);
    iso_loop_destroy(l);
    pc2_file f;
    pc2_read(pc2, &f);
    int nv = iso_mesh_vertex_count(sc->mesh);
    assert_int_equal(f.nv, nv);
    assert_int_equal(f.frames, 30); /* 0.5 s at 60 Hz */
    assert_true(f.size == 32 + (long)f.frames * nv * 12);
    assert_true(f.start == 0.0f && f.sampling == 1.0f);
    for (int k = 0; k < f.frames; k++) {
        char path[600];
        snprintf(path, sizeof path, "%s/frame_%08d.ply", dir, k);
        iso_mesh *m = NULL;
        if (iso_mesh_load(path, &m, &e) != ISO_OK)
            fail_msg("%s: %s", path, e.msg);
        const double *x = iso_mesh_positions(m);
        for (int i = 0; i < 3 * nv; i++) {
            float want = (float)x[i], got = f.xyz[(size_t)k * 3 * nv + (size_t)i];
            if (memcmp(&want, &got, sizeof want) != 0)
                fail_msg("frame %d coordinate %d: PC2 %.9g, PLY %.17g", k, i, got, x[i]);
        }
        iso_mesh_destroy(m);
    }
    /* the rest mesh beside it: the scene's own, same vertex order */
    iso_mesh *r = NULL;
    assert_int_equal(iso_mesh_load(rest, &r, &e), ISO_OK);
    assert_int_equal(iso_mesh_vertex_count(r), nv);
    assert_memory_equal(iso_mesh_positions(r), iso_mesh_positions(sc->mesh),
                        (size_t)nv * 3 * sizeof(double));
    iso_mesh_destroy(r);
    free(f.xyz);
    iso_scene_destroy(sc);
    fclose(log);
}

/* The temporary cache of process pid for final path `path`. */
static void temp_of(const char *path, long pid, char *buf, size_t cap)
{
    const char *dot = strrchr(path, '.');
    snprintf(buf, cap, "%.*s.part-%ld%s", (int)(dot - path), path, pid, dot);
}

static long file_size(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 ? (long)st.st_size : -1;
}

static void killed_run_leaves_a_good_cache(void **state)
{
    (void)state;
    char bin[1024], pc2[512], rec[512];
    if (iso_test_isoshape_bin(bin, sizeof bin) != 0)
        skip_msg("the isoshape binary is not built");
    snprintf(pc2, sizeof pc2, "%s/killed.pc2", ISO_TEST_TMP);
    snprintf(rec, sizeof rec, "%s/sm_session.isorec", ISO_TEST_STREAMS);
    unlink(pc2);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        freopen("/dev/null", "w", stdout);
        freopen("/dev/null", "w", stderr);
        /* in real time: 6.5 s, killed after a few frames */
        execl(bin, "isoshape", "replay", rec, "--shape", "cactus", "--resolution", "1", "--pc2",
              pc2, (char *)NULL);
        _exit(127);
    }
    char tmp[600];
    temp_of(pc2, (long)pid, tmp, sizeof tmp);
    long frame_bytes = 0;
    for (int i = 0; i < 400; i++) { /* up to 20 s for 20 frames */
        long sz = file_size(tmp);
        if (sz > 32) {
            pc2_file f;
            pc2_read(tmp, &f);
            frame_bytes = (long)f.nv * 12;
            free(f.xyz);
            if (f.frames >= 20)
                break;
        }
        struct timespec ts = {0, 50000000};
        nanosleep(&ts, NULL);
    }
    kill(pid, SIGKILL);
    int status;
    waitpid(pid, &status, 0);
    assert_true(WIFSIGNALED(status));
    assert_true(frame_bytes > 0);
    pc2_file f;
    pc2_read(tmp, &f);
    print_message("killed run: %d whole frames counted, file %ld bytes\n", f.frames, f.size);
    assert_true(f.frames >= 20);
    assert_true(f.frames < 389); /* killed mid-way, not finished */
    for (size_t i = 0; i < (size_t)f.frames * (size_t)f.nv * 3; i++)
        assert_true(isfinite(f.xyz[i]));
    assert_true(file_size(pc2) < 0); /* never committed */
    free(f.xyz);
    unlink(tmp);
}

static void deform_writes_a_frame_per_step(void **state)
{
    (void)state;
    char bin[1024], cmd[2048], out[4096], err[4096], pc2[512];
    if (iso_test_isoshape_bin(bin, sizeof bin) != 0)
        skip_msg("the isoshape binary is not built");
    snprintf(pc2, sizeof pc2, "%s/deform.pc2", ISO_TEST_TMP);
    snprintf(cmd, sizeof cmd, "%s deform --shape bar --resolution 4 --steps 12 --pc2 %s", bin, pc2);
    int st = iso_test_sh(cmd, out, sizeof out, err, sizeof err);
    if (st != 0)
        fail_msg("%s: status %d: %s", cmd, st, err);
    pc2_file f;
    pc2_read(pc2, &f);
    assert_int_equal(f.frames, 13); /* the rest pose, then 12 steps */
    char rest[600];
    snprintf(rest, sizeof rest, "%s/deform.rest.ply", ISO_TEST_TMP);
    iso_mesh *m = NULL;
    iso_err e;
    assert_int_equal(iso_mesh_load(rest, &m, &e), ISO_OK);
    assert_int_equal(iso_mesh_vertex_count(m), f.nv);
    const double *x = iso_mesh_positions(m);
    for (int i = 0; i < 3 * f.nv; i++) { /* frame 0 is the rest mesh */
        float want = (float)x[i];
        assert_memory_equal(&want, &f.xyz[i], sizeof want);
    }
    iso_mesh_destroy(m);
    free(f.xyz);
}

/* The mesh message's points are the positions to 1e-7 of the mesh's size
 * (the encoder writes them without printf), and its triangles are all
 * there. */
static void mesh_message_holds_the_positions(void **state)
{
    (void)state;
    iso_shape sh;
    iso_err e;
    assert_int_equal(iso_shape_init(&sh, "cactus", 1, &e), ISO_OK);
    iso_mesh *m = NULL;
    assert_int_equal(iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, "cactus", &m, &e), ISO_OK);
    double *x = malloc((size_t)sh.nv * 3 * sizeof *x);
    assert_non_null(x);
    for (int i = 0; i < 3 * sh.nv; i++) /* signs, small and large magnitudes */
        x[i] = sh.x[i] * (i % 7 == 0 ? -1e-3 : i % 5 == 0 ? 123.456 : 1.0) - 0.25;
    iso_sink_session s;
    memset(&s, 0, sizeof s);
    s.mesh = m;
    iso_fox_channel ch[ISO_FOX_MAX_CHANNELS];
    assert_true(iso_fox_channels(&s, ch, ISO_FOX_MAX_CHANNELS) >= 1);
    assert_string_equal(ch[0].topic, "/mesh");
    iso_fox_encoder *enc = NULL;
    assert_int_equal(iso_fox_encoder_create(&s, &enc, &e), ISO_OK);
    iso_sink_frame f;
    memset(&f, 0, sizeof f);
    f.x = x;
    const char *data;
    size_t len;
    assert_int_equal(iso_fox_encode(enc, &ch[0], &f, &data, &len, &e), ISO_OK);
    double tol = 1e-7 * iso_mesh_bbox_diagonal(m);
    long points = 0, indices = 0;
    for (const char *p = data; (p = strstr(p, "\"points\":[")) != NULL;) {
        for (p += 10; strncmp(p, "{\"x\":", 5) == 0; points++) {
            double q[3];
            char *end;
            q[0] = strtod(p + 5, &end);
            assert_true(strncmp(end, ",\"y\":", 5) == 0);
            q[1] = strtod(end + 5, &end);
            assert_true(strncmp(end, ",\"z\":", 5) == 0);
            q[2] = strtod(end + 5, &end);
            int found = 0;
            for (int v = 0; v < sh.nv && !found; v++)
                found = fabs(q[0] - x[3 * v]) <= tol && fabs(q[1] - x[3 * v + 1]) <= tol &&
                        fabs(q[2] - x[3 * v + 2]) <= tol;
            if (!found)
                fail_msg("point %.17g %.17g %.17g is no vertex's position to %g", q[0], q[1], q[2],
                         tol);
            p = end + 1 + (end[1] == ','); /* past "}" and "," */
        }
    }
    for (const char *p = data; (p = strstr(p, "\"indices\":[")) != NULL;) {
        p += 11;
        while (*p && *p != ']') {
            strtol(p, (char **)&p, 10);
            indices++;
            if (*p == ',')
                p++;
        }
    }
    assert_true(points >= sh.nv);
    assert_int_equal(indices, 3L * sh.nt);
    iso_fox_encoder_destroy(enc);
    iso_mesh_destroy(m);
    free(x);
    iso_shape_deinit(&sh);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(tick_allocates_nothing),
        cmocka_unit_test(pc2_matches_the_ply_frames),
        cmocka_unit_test(killed_run_leaves_a_good_cache),
        cmocka_unit_test(deform_writes_a_frame_per_step),
        cmocka_unit_test(mesh_message_holds_the_positions),
    };
    return cmocka_run_group_tests_name("sink_files", t, NULL, NULL);
}
