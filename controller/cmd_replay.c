/* controller/cmd_replay.c -- `isoshape replay FILE`: a recording through
 * the replay backend, the decoders and the mapping, tick by tick, at the
 * recorded speed, scaled, or as fast as possible. The tick commands depend on
 * the recording and the options only, never on the wall clock: the summary
 * checksum and the handles' final poses are the same at any speed.
 * Also the mapping options shared with `isoshape record`. */
#include "internal.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iso_dev.h"

int iso_cli__replay(int argc, char **argv);
int iso_cli__dev_map_option(const char *cmd, int argc, char **argv, int *i, iso_dev_map_opts *o);

#define ISO_CLI_DEV_MAP_HELP                                                                       \
    "  --handles N        handles the devices drive (1..8; a 'next handle' button cycles)\n"       \
    "  --sensitivity L,A  at full deflection: L m/s and A rad/s (default 0.1,0.5)\n"               \
    "  --dead-zone F      fraction of full scale that maps to 0 (default 0.05)\n"                  \
    "  --curve E          response exponent (1 linear, 2 quadratic; default 1)\n"                  \
    "  --remap A,B,C,D,E,F  output axis i reads input axis (0..5: x y z rx ry rz)\n"               \
    "  --invert AXES      comma list of axes to negate: x,y,z,rx,ry,rz\n"                          \
    "  --dominant         keep only the largest axis\n"                                            \
    "  --lock L           none, translation (translation only) or rotation (rotation only)\n"      \
    "  --frame F          world (default) or device: axes along the handle's own\n"                \
    "  --deadman          move only while the clutch is held (default: held = hold still)\n"

static int axis_index(const char *s, size_t n)
{
    static const char *names[6] = {"x", "y", "z", "rx", "ry", "rz"};
    for (int i = 0; i < 6; i++)
        if (strlen(names[i]) == n && strncmp(s, names[i], n) == 0)
            return i;
    return -1;
}

int iso_cli__dev_map_option(const char *cmd, int argc, char **argv, int *i, iso_dev_map_opts *o)
{
    const char *v;
    int r;
    if (strcmp(argv[*i], "--dominant") == 0) {
        o->dominant = 1;
        return 1;
    }
    if (strcmp(argv[*i], "--deadman") == 0) {
        o->clutch_is_deadman = 1;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--handles", &v)) != 0) {
        if (r < 0 || iso_cli__int(cmd, "--handles", v, &o->n_handles) != 0)
            return -1;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--sensitivity", &v)) != 0) {
        double l, a;
        char tail;
        if (r < 0)
            return -1;
        if (sscanf(v, "%lf,%lf%c", &l, &a, &tail) != 2) {
            iso_cli__fail(cmd, "--sensitivity %s: give L,A (m/s and rad/s at full scale).", v);
            return -1;
        }
        for (int k = 0; k < 3; k++) {
            o->sensitivity[k] = l;
            o->sensitivity[k + 3] = a;
        }
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--dead-zone", &v)) != 0) {
        double d;
        if (r < 0 || iso_cli__double(cmd, "--dead-zone", v, &d) != 0)
            return -1;
        for (int k = 0; k < 6; k++)
            o->dead_zone[k] = d;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--curve", &v)) != 0) {
        double e;
        if (r < 0 || iso_cli__double(cmd, "--curve", v, &e) != 0)
            return -1;
        for (int k = 0; k < 6; k++)
            o->curve[k] = e;
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--remap", &v)) != 0) {
        int m[6];
        char tail;
        if (r < 0)
            return -1;
        if (sscanf(v, "%d,%d,%d,%d,%d,%d%c", &m[0], &m[1], &m[2], &m[3], &m[4], &m[5], &tail) !=
            6) {
            iso_cli__fail(cmd, "--remap %s: give six input axes, e.g. 0,2,1,3,5,4.", v);
            return -1;
        }
        memcpy(o->remap, m, sizeof m);
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--invert", &v)) != 0) {
        if (r < 0)
            return -1;
        for (const char *p = v; *p;) {
            size_t n = strcspn(p, ",");
            int a = axis_index(p, n);
            if (a < 0) {
                iso_cli__fail(cmd, "--invert %s: '%.*s' is not one of x,y,z,rx,ry,rz.", v, (int)n,
                              p);
                return -1;
            }
            o->invert[a] = 1;
            p += n + (p[n] == ',');
        }
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--lock", &v)) != 0) {
        if (r < 0)
            return -1;
        if (strcmp(v, "none") == 0)
            o->lock = ISO_DEV_LOCK_NONE;
        else if (strcmp(v, "translation") == 0)
            o->lock = ISO_DEV_LOCK_TRANSLATION;
        else if (strcmp(v, "rotation") == 0)
            o->lock = ISO_DEV_LOCK_ROTATION;
        else {
            iso_cli__fail(cmd, "--lock %s: use none, translation or rotation.", v);
            return -1;
        }
        return 1;
    }
    if ((r = iso_cli__value(cmd, argc, argv, i, "--frame", &v)) != 0) {
        if (r < 0)
            return -1;
        if (strcmp(v, "world") == 0)
            o->frame = ISO_DEV_FRAME_WORLD;
        else if (strcmp(v, "device") == 0)
            o->frame = ISO_DEV_FRAME_DEVICE;
        else {
            iso_cli__fail(cmd, "--frame %s: use world or device.", v);
            return -1;
        }
        return 1;
    }
    return 0;
}

/* g ← exp(ξ dt) ∘ g: what the loop does to a handle each tick. */
static void advance(iso_pose *g, const iso_twist *xi, double dt)
{
    iso_pose e;
    iso_twist_exp(xi, dt, &e);
    iso_pose n;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++)
                s += e.R[3 * i + k] * g->R[3 * k + j];
            n.R[3 * i + j] = s;
        }
    }
    iso_pose_apply(&e, g->p, n.p);
    *g = n;
}

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 0x100000001b3ULL;
    return h;
}

/* ---- a scene driven by the replayed commands ---------------------------- */
/* Handle h's motion is piecewise screw: in tick k, from its pose G_k at the
 * tick's start, exp((t − t_k) ξ_k) G_k with the tick's constant world twist.
 * The integrator asks for it through an iso_path: the vertex output is a
 * function of the recording alone. */
typedef struct replay_path {
    int n, nh, cap;
    double *t;     /* n + 1 tick boundaries, seconds from the first tick */
    iso_twist *xi; /* n × nh */
    iso_pose *g;   /* n × nh: pose at the start of each tick */
} replay_path;

static int path_push(replay_path *rp, double dt, const iso_dev_tick *out, const iso_pose *P)
{
    if (rp->n == rp->cap) {
        int nc = rp->cap ? 2 * rp->cap : 1024;
        double *t = realloc(rp->t, (size_t)(nc + 1) * sizeof *t);
        if (t)
            rp->t = t;
        iso_twist *xi = realloc(rp->xi, (size_t)nc * (size_t)rp->nh * sizeof *xi);
        if (xi)
            rp->xi = xi;
        iso_pose *g = realloc(rp->g, (size_t)nc * (size_t)rp->nh * sizeof *g);
        if (g)
            rp->g = g;
        if (!t || !xi || !g)
            return ISO_ENOMEM;
        rp->cap = nc;
    }
    if (rp->n == 0)
        rp->t[0] = 0;
    for (int h = 0; h < rp->nh; h++) {
        rp->xi[(size_t)rp->n * (size_t)rp->nh + (size_t)h] = out->twist[h];
        rp->g[(size_t)rp->n * (size_t)rp->nh + (size_t)h] = P[h];
    }
    rp->t[rp->n + 1] = rp->t[rp->n] + dt;
    rp->n++;
    return ISO_OK;
}

static int path_eval(void *ctx, int h, double t, iso_pose *pose, iso_twist *tw)
{
    const replay_path *rp = ctx;
    memset(tw, 0, sizeof *tw);
    iso_pose_identity(pose);
    if (h >= rp->nh || rp->n == 0)
        return 0; /* scene handles beyond the mapped ones hold still */
    int lo = 0, hi = rp->n - 1;
    while (lo < hi) { /* the last tick starting at or before t */
        int mid = (lo + hi + 1) / 2;
        if (rp->t[mid] <= t)
            lo = mid;
        else
            hi = mid - 1;
    }
    size_t k = (size_t)lo * (size_t)rp->nh + (size_t)h;
    *tw = rp->xi[k];
    iso_pose e;
    iso_twist_exp(&rp->xi[k], t - rp->t[lo], &e);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int q = 0; q < 3; q++)
                s += e.R[3 * i + q] * rp->g[k].R[3 * q + j];
            pose->R[3 * i + j] = s;
        }
    iso_pose_apply(&e, rp->g[k].p, pose->p);
    return 0;
}

/* Loads the scene, integrates it along the replayed path, prints a checksum
 * of the vertices and saves them when out_path is given. */
static int run_scene(iso_cli__problem *pp, replay_path *rp, int steps, const char *out_path)
{
    const char *cmd = "replay";
    iso_err err;
    iso_err_clear(&err);
    iso_cli__problem p = *pp;
    double *x = NULL;
    iso_solver *s = NULL;
    int rc = ISO_OK;
    if (rp->n == 0)
        rc = iso_err_set(&err, ISO_EINVAL, -1, "the recording has no ticks to integrate");
    int nv = iso_mesh_vertex_count(p.mesh);
    if (rc == ISO_OK && !(x = malloc((size_t)nv * 3 * sizeof *x)))
        rc = iso_err_set(&err, ISO_ENOMEM, -1, "out of memory for %d vertices", nv);
    iso_solver_opts so;
    iso_solver_opts_default(&so); /* the C assembly: the same bits on every machine */
    if (rc == ISO_OK) {
        memcpy(x, iso_mesh_positions(p.mesh), (size_t)nv * 3 * sizeof *x);
        rc = iso_solver_create(p.mesh, &p.reg, &so, &s, &err);
    }
    iso_integrate_stats st;
    memset(&st, 0, sizeof st);
    if (rc == ISO_OK) {
        iso_integrate_opts io;
        iso_integrate_opts_default(&io);
        io.t0 = 0;
        io.t1 = rp->t[rp->n];
        io.steps = steps > 0 ? steps : rp->n;
        iso_path path = {path_eval, rp};
        rc = iso_integrate(s, p.mesh, &p.reg, &path, &io, x, &st, &err);
    }
    if (rc == ISO_OK) {
        uint64_t sum = fnv(0xcbf29ce484222325ULL, x, (size_t)nv * 3 * sizeof *x);
        printf("scene %s: %d vertices, %d steps, vertices checksum %016" PRIx64 "\n", p.label, nv,
               st.steps, sum);
        if (out_path)
            rc = iso_mesh_save(p.mesh, x, out_path, ISO_MESH_FMT_AUTO, &err);
    }
    if (rc != ISO_OK)
        iso_cli__fail(cmd, "%s", err.msg);
    iso_solver_destroy(s);
    free(x);
    return rc == ISO_OK ? 0 : 1;
}

/* Handle h's rest centroid: device rotations turn about it, as in the
 * real-time loop (controller/loop.c), so both give the same motion. */
static void set_centres(iso_dev_map *m, const iso_cli__problem *p)
{
    const double *X = iso_mesh_positions(p->mesh);
    int nv = iso_mesh_vertex_count(p->mesh);
    for (int h = 0; h < m->o.n_handles; h++) {
        double c[3] = {0, 0, 0}, n = 0;
        for (int v = 0; v < nv; v++) {
            if (p->reg.kind[v] != ISO_HANDLE || p->reg.handle[v] != h)
                continue;
            for (int j = 0; j < 3; j++)
                c[j] += X[3 * v + j];
            n += 1;
        }
        for (int j = 0; j < 3 && n > 0; j++)
            c[j] /= n;
        iso_dev_map_set_centre(m, h, c);
    }
}

static void sleep_until(int64_t t_ns)
{
    struct timespec ts = {(time_t)(t_ns / 1000000000), (long)(t_ns % 1000000000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
        ;
}

static void note(void *ctx, const char *msg)
{
    (void)ctx;
    fprintf(stderr, "isoshape replay: %s\n", msg);
}

static void usage(void)
{
    printf("usage: isoshape replay FILE [options]\n"
           "\n"
           "Replays a recording (devices/RECORDING.md) through the decoders and the mapping,\n"
           "one tick at each of its TICK records, and prints a summary: ticks, a checksum of\n"
           "every tick's handle commands, and each handle's pose after integrating them. The\n"
           "result is the same bit for bit at any speed.\n"
           "\n"
           "  --speed X          X times the recorded speed (default 1)\n"
           "  --fast             as fast as possible\n"
           "  --tick-ms T        tick length for recordings without TICK records (default 1)\n"
           "  --print-ticks      one line per tick: time, active handle, clutch, e-stop,\n"
           "                     buttons, and the active handle's twist (w, v) in %%a\n"
           "A scene moved by the replayed commands (the mapping's handle h drives the\n"
           "scene's handle h), integrated, with a checksum of its vertices:\n"
           "  --shape NAME       a built-in shape (bar, cylinder, bumpplane, cactus)\n"
           "  --resolution N     the built-in shape's resolution (0: its default)\n"
           "  --mesh M --sel S   or a mesh and its regions\n"
           "  --steps N          integration steps (default: one per tick)\n"
           "  --out FILE         save the deformed mesh\n"
           "Mapping:\n" ISO_CLI_DEV_MAP_HELP);
}

int iso_cli__replay(int argc, char **argv)
{
    const char *cmd = "replay", *path = NULL, *v, *out_path = NULL;
    double speed = 1, tick_ms = 1;
    int fast = 0, print = 0, steps = 0;
    iso_cli__source src;
    memset(&src, 0, sizeof src);
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    for (int i = 1; i < argc; i++) {
        int r;
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage();
            return 0;
        }
        if (strcmp(argv[i], "--fast") == 0) {
            fast = 1;
            continue;
        }
        if (strcmp(argv[i], "--print-ticks") == 0) {
            print = 1;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--speed", &v)) != 0) {
            if (r < 0 || iso_cli__double(cmd, "--speed", v, &speed) != 0)
                return 2;
            if (!(speed > 0)) {
                iso_cli__fail(cmd, "--speed %s must be > 0 (use --fast for no waiting).", v);
                return 2;
            }
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--tick-ms", &v)) != 0) {
            if (r < 0 || iso_cli__double(cmd, "--tick-ms", v, &tick_ms) != 0)
                return 2;
            if (!(tick_ms > 0)) {
                iso_cli__fail(cmd, "--tick-ms %s must be > 0.", v);
                return 2;
            }
            continue;
        }
        if ((r = iso_cli__dev_map_option(cmd, argc, argv, &i, &mo)) != 0) {
            if (r < 0)
                return 2;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--shape", &src.shape)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--mesh", &src.mesh)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--sel", &src.sel)) != 0 ||
            (r = iso_cli__value(cmd, argc, argv, &i, "--out", &out_path)) != 0) {
            if (r < 0)
                return 2;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--resolution", &v)) != 0) {
            if (r < 0 || iso_cli__int(cmd, "--resolution", v, &src.resolution) != 0)
                return 2;
            continue;
        }
        if ((r = iso_cli__value(cmd, argc, argv, &i, "--steps", &v)) != 0) {
            if (r < 0 || iso_cli__int(cmd, "--steps", v, &steps) != 0)
                return 2;
            if (steps < 1) {
                iso_cli__fail(cmd, "--steps %s must be >= 1.", v);
                return 2;
            }
            continue;
        }
        if (argv[i][0] == '-' || path)
            return iso_cli__unknown(cmd, argv[i]);
        path = argv[i];
    }
    if (!path) {
        iso_cli__fail(cmd, "no recording given (isoshape replay FILE).");
        return 2;
    }
    int scene = src.shape || src.mesh || src.sel;
    if (scene && !src.shape && (!src.mesh || !src.sel)) {
        iso_cli__fail(cmd, "a scene needs --shape NAME, or both --mesh and --sel.");
        return 2;
    }
    if (out_path && !scene) {
        iso_cli__fail(cmd, "--out needs a scene (--shape, or --mesh and --sel).");
        return 2;
    }
    replay_path rp = {0, mo.n_handles, 0, NULL, NULL, NULL};
    iso_err err;
    iso_err_clear(&err);
    iso_dev_map m;
    if (iso_dev_map_init(&m, &mo, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        return 2;
    }
    iso_cli__problem prob;
    memset(&prob, 0, sizeof prob);
    if (scene) {
        if (iso_cli__problem_load(cmd, &src, &prob, &err) != ISO_OK) {
            iso_cli__fail(cmd, "%s", err.msg);
            iso_cli__problem_deinit(&prob);
            return 1;
        }
        set_centres(&m, &prob);
    }
    iso_dev_rec_reader r;
    if (iso_dev_rec_reader_load(&r, path, &err) != ISO_OK) {
        iso_cli__fail(cmd, "%s", err.msg);
        iso_cli__problem_deinit(&prob);
        return 1;
    }
    iso_dev_source *s = NULL;
    iso_dev_hub *h = NULL;
    int rc = iso_dev_replay_open(&r, &s, &err);
    if (rc == ISO_OK)
        rc = iso_dev_hub_create(note, NULL, &h, &err);
    if (rc == ISO_OK) {
        rc = iso_dev_hub_add(h, s, NULL, NULL, &err);
        s = NULL;
    }
    if (rc != ISO_OK) {
        iso_cli__fail(cmd, "%s: %s", path, err.msg);
        iso_dev_source_close(s);
        iso_dev_hub_destroy(h);
        iso_dev_rec_reader_deinit(&r);
        iso_cli__problem_deinit(&prob);
        return 1;
    }
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned k = 0; k < ISO_DEV_MAX_HANDLES; k++)
        iso_pose_identity(&P[k]);
    const int64_t dt_ns = (int64_t)(tick_ms * 1e6);
    int64_t last = INT64_MIN, first = INT64_MIN, wall0 = iso_dev_now_ns();
    long ticks = 0, damaged_seen = 0;
    uint64_t sum = 0xcbf29ce484222325ULL;
    for (int64_t t; (t = iso_dev_hub_next_tick(h, dt_ns)) != INT64_MAX;) {
        if (first == INT64_MIN)
            first = t;
        if (!fast)
            sleep_until(wall0 + (int64_t)((double)(t - first) / speed));
        double dt = last == INT64_MIN ? tick_ms * 1e-3 : (double)(t - last) * 1e-9;
        iso_dev_tick out;
        if (iso_dev_hub_tick(h, &m, t, dt, P, &out, &err) != ISO_OK) {
            iso_cli__fail(cmd, "%s", err.msg);
            break;
        }
        if (r.damaged > damaged_seen) {
            fprintf(stderr, "isoshape replay: %s: %s\n", path, r.note);
            damaged_seen = r.damaged;
        }
        sum = fnv(sum, &out, sizeof out);
        if (scene && path_push(&rp, dt, &out, P) != ISO_OK) {
            iso_cli__fail(cmd, "out of memory for %d ticks of handle motion.", rp.n);
            break;
        }
        for (int k = 0; k < out.n_handles; k++)
            advance(&P[k], &out.twist[k], dt);
        if (print) {
            const iso_twist *x = &out.twist[out.active];
            printf("%.6f h%d%s%s b%08" PRIx32 " w %a %a %a v %a %a %a\n",
                   (double)(t - first) * 1e-9, out.active, out.clutch ? " clutch" : "",
                   out.estop ? " ESTOP" : "", out.buttons, x->w[0], x->w[1], x->w[2], x->v[0],
                   x->v[1], x->v[2]);
        }
        last = t;
        ticks++;
    }
    printf("%s: %ld ticks, %ld records, %ld damaged, commands checksum %016" PRIx64 "\n", path,
           ticks, r.records, r.damaged, sum);
    for (int k = 0; k < mo.n_handles; k++)
        printf("handle %d: p %.17g %.17g %.17g  R %.17g %.17g %.17g %.17g %.17g %.17g %.17g "
               "%.17g %.17g\n",
               k, P[k].p[0], P[k].p[1], P[k].p[2], P[k].R[0], P[k].R[1], P[k].R[2], P[k].R[3],
               P[k].R[4], P[k].R[5], P[k].R[6], P[k].R[7], P[k].R[8]);
    if (r.torn)
        fprintf(stderr, "isoshape replay: %s: %s\n", path, r.note);
    for (size_t k = 0; k < iso_dev_hub_sources(h); k++) {
        const iso_dev_counters *n = &iso_dev_hub_decoder(h, k)->n;
        if (n->short_reports || n->unknown_ids || n->bad_frames || n->garbage)
            fprintf(stderr,
                    "isoshape replay: source %zu: skipped %u short reports, %u unknown IDs, %u "
                    "bad frames, %u garbage bytes\n",
                    k, n->short_reports, n->unknown_ids, n->bad_frames, n->garbage);
    }
    iso_dev_hub_destroy(h);
    iso_dev_rec_reader_deinit(&r);
    int status = scene ? run_scene(&prob, &rp, steps, out_path) : 0;
    iso_cli__problem_deinit(&prob);
    free(rp.t);
    free(rp.xi);
    free(rp.g);
    return status;
}
