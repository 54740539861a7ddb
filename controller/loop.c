/* controller/loop.c -- the tick engine: build a scene's parts, then tick on
 * absolute deadlines. iso_loop.h states the clocks, the commanded motion,
 * the late-tick and sub-step rules. This file builds and ends the loop and
 * reports it; loop_devices.c is the input side, loop_tick.c a tick,
 * loop_run.c the pacing. */
#include "loop_internal.h"

#include <errno.h>
#include <math.h>
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include "iso_clock.h"

void iso_loop_opts_default(iso_loop_opts *o)
{
    memset(o, 0, sizeof *o);
    o->speed = 1;
    o->display = -1;
    o->port = -1;
    o->assembly = -1;
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    o->threads = so.threads;
}

/* ======================================================================== */
/* Create / destroy                                                         */
/* ======================================================================== */

static void rest_centroids(iso_loop *l)
{
    const iso_regions *r = &l->sc->regions;
    const double *X = iso_mesh_positions(l->sc->mesh);
    double n[ISO_SCENE_MAX_HANDLES] = {0};
    memset(l->centroid, 0, sizeof l->centroid);
    for (int v = 0; v < l->nv; v++) {
        int h = r->handle[v];
        if (r->kind[v] != ISO_HANDLE || h < 0 || h >= ISO_SCENE_MAX_HANDLES)
            continue;
        for (int j = 0; j < 3; j++)
            l->centroid[h][j] += X[3 * v + j];
        n[h] += 1;
    }
    for (int h = 0; h < ISO_SCENE_MAX_HANDLES; h++)
        for (int j = 0; j < 3 && n[h] > 0; j++)
            l->centroid[h][j] /= n[h];
}

/* The solver's progress inside an evaluation is the loop's progress: the
 * actuators' loop watchdog tells a slow evaluation from a stuck one. */
static void solver_progress(void *ctx)
{
    iso_loop__sinks_alive(ctx);
}

/* The reduced model, when the scene asks for one (or `auto` chooses one
 * for the mesh's size and the tick rate): the method then steps the
 * proxy's positions l->y, and l->x follows them (loop_tick.c). */
static int build_proxy(iso_loop *l, const iso_mesh **mesh, const iso_regions **reg, double **pos,
                       iso_err *err)
{
    const iso_scene *sc = l->sc;
    char why[300];
    int budget = iso_proxy_choose(sc->mesh, sc->solver.proxy, sc->tick_hz, why, sizeof why);
    if (budget <= 0) {
        /* a proxy asked for and not built, or a setting with nothing to act
         * on, is said, not silently dropped */
        if (sc->solver.proxy > 0)
            iso_loop_say(l, "reduced model: none: %s", why);
        if (sc->solver.proxy_smoothness != ISO_PROXY_SMOOTHNESS_MESH)
            iso_loop_say(l, "solver.proxy_smoothness is ignored: the method runs on %s", why);
        return ISO_OK;
    }
    if (l->nv >= 100000) /* seconds of work: say what is happening */
        iso_loop_say(l,
                     "reduced model: simplifying %d vertices to a proxy of at most %d "
                     "(about a second per 100,000 vertices)...",
                     l->nv, budget);
    double t0 = iso_clock_now();
    int rc = iso_proxy_create(sc->mesh, &sc->regions, budget, &l->proxy, err);
    if (rc != ISO_OK)
        return rc;
    l->proxy_s = iso_clock_now() - t0;
    *mesh = iso_proxy_mesh(l->proxy);
    *reg = iso_proxy_regions(l->proxy);
    int np = iso_mesh_vertex_count(*mesh);
    if (!(l->y = malloc((size_t)np * 3 * sizeof *l->y)))
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertices", np);
    memcpy(l->y, iso_mesh_positions(*mesh), (size_t)np * 3 * sizeof *l->y);
    *pos = l->y;
    if (sc->solver.proxy == ISO_SOLVER_PROXY_AUTO)
        iso_loop_say(l,
                     "reduced model: a proxy of %d vertices for %d (built in %.2f s): the "
                     "whole mesh does not fit a %g Hz tick (solver.proxy: off runs it whole)",
                     np, l->nv, l->proxy_s, sc->tick_hz);
    else
        iso_loop_say(l, "reduced model: a proxy of %d vertices for %d (built in %.2f s)", np, l->nv,
                     l->proxy_s);
    if (sc->solver.proxy_smoothness == ISO_PROXY_SMOOTHNESS_MATCHED)
        iso_loop_say(l,
                     "reduced model: the proxy stepped with omega %.4g, matched to "
                     "the mesh's %.4g",
                     iso_proxy_omega(l->proxy, sc->solver.omega), sc->solver.omega);
    return ISO_OK;
}

static int build_solver(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    iso_solver_opts so = sc->solver;
    if (l->o.assembly >= 0)
        so.assembly = (iso_assembly)l->o.assembly;
    so.cl_device = l->o.cl_device;
    so.threads = l->o.threads;
    l->x = malloc((size_t)l->nv * 3 * sizeof *l->x);
    if (!l->x)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertices", l->nv);
    memcpy(l->x, iso_mesh_positions(sc->mesh), (size_t)l->nv * 3 * sizeof *l->x);
    const iso_mesh *mesh = sc->mesh;
    const iso_regions *reg = &sc->regions;
    double *pos = l->x;
    int rc = build_proxy(l, &mesh, &reg, &pos, err);
    if (rc == ISO_OK && l->proxy)
        iso_proxy_solver_opts(l->proxy, &so);
    if (rc == ISO_OK)
        rc = iso_solver_create(mesh, reg, &so, &l->solver, err);
    if (rc != ISO_OK)
        return rc;
    iso_solver_set_progress(l->solver, solver_progress, l);
    const char *notice = iso_solver_notice(l->solver);
    if (notice && notice[0])
        iso_loop_say(l, "%s", notice);
    rc = iso_stepper_create(l->solver, mesh, reg, pos, &l->st, err);
    if (rc == ISO_OK)
        rc = iso_stepper_configure(l->st, (iso_abm_mode)sc->abm_mode, sc->integrate.restore_kappa,
                                   err);
    if (rc == ISO_OK)
        rc = iso_stepper_set_cg_share(l->st, sc->integrate.cg_share, err);
    /* The first factorization before the clock starts, not in the first
     * tick (in --fast too, so that both runs give the same bits). */
    if (rc == ISO_OK)
        rc = iso_solver_factor_at(l->solver, pos, err);
    /* From here on the tick never factors the whole system: the worker
     * does (docs/realtime.md, "A tick's cost"). */
    iso_solver_set_bounded(l->solver, 1);
    return rc;
}

/* Where the run ends: a scripted path's last tick is the one at its end, a
 * duration D is round(D × tick_hz) ticks; a replay ends with its records. */
static void plan_end(iso_loop *l)
{
    const iso_scene *sc = l->sc;
    double hz = sc->tick_hz;
    l->k_end = INT64_MAX;
    l->t_end = INT64_MAX;
    if (l->o.duration_s > 0) {
        int64_t n = (int64_t)llround(l->o.duration_s * hz);
        l->k_end = n > 0 ? n : 1;
        l->t_end = (int64_t)llround((double)l->k_end * 1e9 / hz);
        return;
    }
    if (l->hub)
        return;
    double end = 0;
    for (int k = 0; k < sc->n_handles; k++) {
        double e = iso_loop__scripted_end(&sc->handles[k].driver);
        if (e > end)
            end = e;
    }
    if (end > 0) {
        l->k_end = (int64_t)ceil(end * hz - 1e-9);
    } else if (l->o.max_ticks == 0) {
        iso_loop_say(l, "nothing drives the handles: running 1 s of ticks");
        l->k_end = (int64_t)llround(hz);
    }
    if (l->k_end < 1)
        l->k_end = 1;
}

static int open_mesh_side(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    l->nv = iso_mesh_vertex_count(sc->mesh);
    l->nh = sc->n_handles;
    l->diag = iso_mesh_bbox_diagonal(sc->mesh);
    rest_centroids(l);
    return build_solver(l, err);
}

int iso_loop_create(const iso_scene *sc, const iso_loop_opts *o, iso_loop **out, iso_err *err)
{
    *out = NULL;
    if (!sc || !(sc->tick_hz > 0))
        return iso_err_set(err, ISO_EINVAL, -1, "iso_loop_create: no scene, or no tick rate");
    iso_loop *l = calloc(1, sizeof *l);
    if (!l)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the loop");
    l->sc = sc;
    if (o)
        l->o = *o;
    else
        iso_loop_opts_default(&l->o);
    l->log = l->o.log ? l->o.log : stderr;
    l->cmd = l->o.cmd ? l->o.cmd : "run";
    int rc = iso_logq_create(l->log, l->o.status_line, &l->logq, err);
    if (rc != ISO_OK) {
        free(l);
        return rc;
    }
    if (!(l->o.speed > 0))
        l->o.speed = 1;
    l->period_ns = (int64_t)llround(1e9 / sc->tick_hz);
    for (int h = 0; h < ISO_SCENE_MAX_HANDLES; h++)
        iso_pose_identity(&l->cmd_pose[h]);
    iso_loop__stats_init(&l->stats);
    l->nh = sc->n_handles;
    rc = sc->mesh ? open_mesh_side(l, err) : ISO_OK;
    if (rc == ISO_OK)
        rc = iso_loop__devices_open(l, err);
    /* The recording before the sinks: a path it cannot write (a FIFO with
     * no reader) is refused before the view and an emulated MCU start. */
    const char *rec = l->o.record ? l->o.record : sc->recording;
    if (rc == ISO_OK && rec[0] && l->hub && !l->replay) {
        rc = iso_dev_hub_record_start(l->hub, rec, err);
        l->recording = rc == ISO_OK;
    } else if (rc == ISO_OK && rec[0] && l->replay) {
        iso_loop_say(l, "not recording to %s: the devices are a replay already", rec);
    } else if (rc == ISO_OK && rec[0] && !l->hub) {
        iso_loop_say(l, "not recording to %s: the scene has no devices to record", rec);
    }
    if (rc == ISO_OK && rec[0] && l->hub && !l->replay)
        rc = iso_loop__recorder_create(l, rec, l->recording, &l->recorder, err);
    if (rc == ISO_OK && sc->mesh)
        rc = iso_loop__sinks_open(l, err);
    if (rc == ISO_OK && l->hub && !l->replay) {
        iso_err quiet; /* without libusb the retry interval still finds replugged devices */
        iso_err_clear(&quiet);
        if (iso_dev_usb_watch_create(&l->watch, &quiet) != ISO_OK)
            l->watch = NULL;
    }
    if (rc == ISO_OK) {
        plan_end(l);
        /* the statistics' room before the first tick: the planned ticks,
         * or 10 minutes of an open-ended run (longer runs go on in the
         * histogram) */
        long plan = l->k_end < INT64_MAX ? (long)l->k_end + 1 : (long)(600 * sc->tick_hz);
        if (l->o.max_ticks > 0 && l->o.max_ticks < plan)
            plan = l->o.max_ticks;
        rc = iso_loop__stats_reserve(&l->stats, plan, err);
    }
    if (rc != ISO_OK) {
        iso_loop_destroy(l);
        return rc;
    }
    *out = l;
    return ISO_OK;
}

int iso_loop_shutdown(iso_loop *l, iso_err *err)
{
    if (!l || l->shut)
        return ISO_OK;
    l->shut = 1;
    int rc = l->sinks ? iso_loop__sinks_close(l, err) : ISO_OK;
    if (l->hub && l->recording && !l->replay) {
        /* What arrived after the last tick goes into the recording too, as
         * data without a TICK record: it is kept, and a replay, which ends
         * at the last TICK record, computes exactly the ticks this run did. */
        iso_dev_event ev[64];
        size_t n = 0;
        (void)iso_dev_hub_sync(l->hub, 200); /* the byte streams' reader caught up */
        int r1 = iso_dev_hub_drain(l->hub, iso_clock_ns(), ev, 64, &n, err);
        if (rc == ISO_OK)
            rc = r1;
    }
    if (l->hub && l->recording) {
        int r2 = iso_dev_hub_record_stop(l->hub, err);
        l->recording = 0;
        if (rc == ISO_OK)
            rc = r2;
    }
    return rc;
}

void iso_loop_destroy(iso_loop *l)
{
    if (!l)
        return;
    iso_err e;
    iso_err_clear(&e);
    if (iso_loop_shutdown(l, &e) != ISO_OK)
        iso_loop_say(l, "shutdown: %s", e.msg);
    iso_loop__sinks_free(l); /* the view before the hub: it queues on the hub's view device */
    iso_loop__recorder_destroy(l->recorder);
    iso_dev_usb_watch_destroy(l->watch);
    iso_dev_hub_destroy(l->hub);
    if (l->replay)
        iso_dev_rec_reader_deinit(&l->reader);
    iso_stepper_destroy(l->st);
    iso_solver_destroy(l->solver);
    iso_loop__stats_deinit(&l->stats);
    free(l->sinks);
    free(l->x);
    free(l->y);
    iso_proxy_destroy(l->proxy);
    iso_logq_destroy(l->logq); /* last: everything above may still say something */
    free(l);
}

void iso_loop__note(void *ctx, const char *line)
{
    iso_loop_say(ctx, "%s", line);
}

void iso_loop_say(iso_loop *l, const char *fmt, ...)
{
    char msg[ISO_LOGQ_LINE_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    iso_logq_sayf(l->logq, "isoshape %s: %s", l->cmd, msg);
}

/* ======================================================================== */
/* Results                                                                  */
/* ======================================================================== */

void iso_loop_get_summary(iso_loop *l, iso_loop_summary *s)
{
    memset(s, 0, sizeof *s);
    s->ticks = l->ticks;
    s->stream_s = (double)(l->t_now - l->stream0) * 1e-9;
    if (l->ticks == 0)
        s->stream_s = 0;
    double end = l->wall_end > 0 ? l->wall_end : iso_clock_now();
    s->wall_s = l->wall_start > 0 ? end - l->wall_start : 0;
    s->period_ms = 1e3 / l->sc->tick_hz;
    s->rt_active = l->rt.rt_active;
    s->mem_locked = l->rt.mem_locked;
    memcpy(s->rt_note, l->rt.rt_note, sizeof s->rt_note);
    const iso_loop_stats *st = &l->stats;
    s->tick_median = iso_loop__stats_quantile(st, 0, 0.5);
    s->tick_p99 = iso_loop__stats_quantile(st, 0, 0.99);
    s->tick_max = iso_loop__stats_quantile(st, 0, 1.0);
    s->latency_median = iso_loop__stats_quantile(st, 1, 0.5);
    s->latency_p90 = iso_loop__stats_quantile(st, 1, 0.9);
    s->latency_p99 = iso_loop__stats_quantile(st, 1, 0.99);
    s->latency_max = iso_loop__stats_quantile(st, 1, 1.0);
    s->misses = st->misses;
    s->skipped = st->skipped;
    s->gap_max_ms = st->max_gap_ms;
    s->restarts = l->restarts;
    s->device_ticks = l->device_ticks;
    s->substeps = l->substeps;
    s->coarse = l->coarse;
    s->commands_checksum = l->cmd_sum;
    s->n_handles = l->nh;
    for (int h = 0; h < s->n_handles; h++) {
        const iso_pose *G = l->st ? iso_stepper_pose(l->st, h) : &l->cmd_pose[h];
        iso_pose_apply(G, l->centroid[h], s->handle_p[h]);
        memcpy(s->handle_R[h], G->R, sizeof G->R);
    }
    size_t nd = l->hub ? iso_dev_hub_sources(l->hub) : 0;
    s->n_devices = (int)nd;
    for (size_t i = 0; i < nd; i++) {
        if (iso_dev_hub_source_stats(l->hub, i, &s->device[i]) != ISO_OK)
            memset(&s->device[i], 0, sizeof s->device[i]);
        iso_dev_hub_describe(l->hub, i, s->device_desc[i], sizeof s->device_desc[i]);
    }
    if (!l->st)
        return;
    iso_stepper_stats(l->st, &s->integ);
    iso_solver_get_stats(l->solver, &s->solver);
    if (l->proxy) {
        s->proxy_vertices = iso_mesh_vertex_count(iso_proxy_mesh(l->proxy));
        s->proxy_build_s = l->proxy_s;
        iso_proxy_get_stats(l->proxy, &s->proxy);
    }
    iso_metrics_compute(l->sc->mesh, iso_mesh_positions(l->sc->mesh), l->x, &s->metrics);
    s->checksum = iso_loop__fnv1a(0xcbf29ce484222325ULL, l->x, (size_t)l->nv * 3 * sizeof *l->x);
    iso_loop__sinks_summary(l, s);
}

const double *iso_loop_positions(const iso_loop *l)
{
    return l->x;
}

const iso_pose *iso_loop_commanded_pose(const iso_loop *l, int h)
{
    return h >= 0 && h < l->nh ? &l->cmd_pose[h] : NULL;
}

const iso_dev_hub *iso_loop_hub(const iso_loop *l)
{
    return l->hub;
}

const iso_dev_rec_reader *iso_loop_replay_reader(const iso_loop *l)
{
    return l->replay ? &l->reader : NULL;
}

const iso_mesh *iso_loop_mesh(const iso_loop *l)
{
    return l->sc->mesh;
}
