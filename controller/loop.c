/* controller/loop.c -- the real-time loop: build a scene's parts, then tick
 * on absolute deadlines. See loop.h for the two clocks and the overrun rule. */
#include "loop_internal.h"

#include <errno.h>
#include <math.h>
#include <sched.h>
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
    o->rt = 1;
    o->display = -1;
    o->port = -1;
    o->assembly = -1;
}

/* ======================================================================== */
/* Devices                                                                  */
/* ======================================================================== */

static int open_device(const iso_scene_device *d, iso_dev_source **out, iso_err *err)
{
    switch (d->backend) {
    case ISO_SCENE_DEV_HIDAPI:
        return iso_dev_hid_open(d->path[0] ? d->path : NULL, out, err);
    case ISO_SCENE_DEV_SPNAV:
        return iso_dev_spnav_open(out, err);
    case ISO_SCENE_DEV_TTY:
        return iso_dev_tty_open(d->path, d->baud, out, err);
    case ISO_SCENE_DEV_TCP:
        return iso_dev_tcp_open(d->address, 1000, out, err);
    case ISO_SCENE_DEV_SERIALPORT:
        return iso_dev_serialport_open(d->path, d->baud, out, err);
    case ISO_SCENE_DEV_GPIOD:
        return iso_dev_gpiod_open(&d->gpio, out, err);
    default:
        return iso_err_set(err, ISO_EINVAL, -1, "device '%s': unknown kind", d->name);
    }
}

static int reopen_device(void *ctx, const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    (void)info;
    return open_device(ctx, out, err);
}

static void hub_note(void *ctx, const char *msg)
{
    iso_loop *l = ctx;
    fprintf(l->log, "%sisoshape run: %s\n", l->o.status_line ? "\r\033[K" : "", msg);
}

/* A replayed recording stands for every device it recorded; live devices
 * are opened one by one. A device that is absent at the start is an error
 * (a scene for a 3D mouse without one is a mistake worth saying); one that
 * goes away while running is retried, its handles holding still. */
static int open_devices(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    if (sc->n_devices == 0)
        return ISO_OK;
    int rc = iso_dev_hub_create(hub_note, l, &l->hub, err);
    if (rc != ISO_OK)
        return rc;
    for (int i = 0; i < sc->n_devices; i++) {
        const iso_scene_device *d = &sc->devices[i];
        iso_dev_source *s = NULL;
        if (d->backend == ISO_SCENE_DEV_REPLAY) {
            if (sc->n_devices > 1)
                return iso_err_set(err, ISO_EINVAL, -1,
                                   "%s: devices: a replay stands for every device it recorded; "
                                   "it cannot be combined with other devices",
                                   sc->path);
            if ((rc = iso_dev_rec_reader_load(&l->reader, d->path, err)) != ISO_OK)
                return rc;
            l->replay = 1;
            if ((rc = iso_dev_replay_open(&l->reader, &s, err)) != ISO_OK)
                return rc;
            return iso_dev_hub_add(l->hub, s, NULL, NULL, err);
        }
        if ((rc = open_device(d, &s, err)) != ISO_OK) {
            iso_err e = *err;
            iso_err_clear(err);
            return iso_err_set(err, rc, -1, "%s: device '%s' (%s): %s", sc->path, d->name,
                               iso_scene_backend_name(d->backend), e.msg);
        }
        if ((rc = iso_dev_hub_add(l->hub, s, reopen_device, (void *)d, err)) != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

/* One mapping for the device-driven handles, in scene order: twist j of
 * the devices' command drives the j-th of them ("next handle" cycles). */
static int init_mapping(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    int first = -1;
    for (int h = 0; h < sc->n_handles; h++) {
        const iso_scene_driver *d = &sc->handles[h].driver;
        if (d->kind != ISO_SCENE_DRIVE_DEVICE)
            continue;
        if (first < 0) {
            first = h;
            mo = d->map;
        } else if (memcmp(&d->map, &mo, sizeof mo) != 0) {
            fprintf(l->log,
                    "isoshape run: handle '%s' maps its device like handle '%s' (one mapping "
                    "serves every device-driven handle)\n",
                    sc->handles[h].name, sc->handles[first].name);
        }
        l->dev_handle[l->n_dev++] = h;
    }
    mo.n_handles = l->n_dev > 0 ? l->n_dev : 1;
    int rc = iso_dev_map_init(&l->map, &mo, err);
    /* a twist of the 3D mouse turns the handle about its own centre */
    for (int j = 0; j < l->n_dev && rc == ISO_OK; j++)
        iso_dev_map_set_centre(&l->map, j, l->centroid[l->dev_handle[j]]);
    return rc;
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

static int build_solver(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    iso_solver_opts so = sc->solver;
    if (l->o.assembly >= 0)
        so.assembly = (iso_assembly)l->o.assembly;
    so.cl_device = l->o.cl_device;
    int rc = iso_solver_create(sc->mesh, &sc->regions, &so, &l->solver, err);
    if (rc != ISO_OK)
        return rc;
    const char *notice = iso_solver_notice(l->solver);
    if (notice && notice[0])
        fprintf(l->log, "isoshape run: %s\n", notice);
    l->x = malloc((size_t)l->nv * 3 * sizeof *l->x);
    if (!l->x)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertices", l->nv);
    memcpy(l->x, iso_mesh_positions(sc->mesh), (size_t)l->nv * 3 * sizeof *l->x);
    rc = iso_stepper_create(l->solver, sc->mesh, &sc->regions, l->x, &l->st, err);
    if (rc == ISO_OK)
        rc = iso_stepper_configure(l->st, (iso_abm_mode)sc->abm_mode, sc->integrate.restore_kappa,
                                   err);
    return rc;
}

int iso_loop_create(const iso_scene *sc, const iso_loop_opts *o, iso_loop **out, iso_err *err)
{
    *out = NULL;
    if (!sc || !sc->mesh)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_loop_create: no scene (or a parse-only one)");
    iso_loop *l = calloc(1, sizeof *l);
    if (!l)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the loop");
    l->sc = sc;
    if (o)
        l->o = *o;
    else
        iso_loop_opts_default(&l->o);
    l->log = l->o.log ? l->o.log : stderr;
    if (!(l->o.speed > 0))
        l->o.speed = 1;
    l->nv = iso_mesh_vertex_count(sc->mesh);
    l->period_ns = (int64_t)llround(1e9 / sc->tick_hz);
    iso_loop__stats_init(&l->stats);
    rest_centroids(l);
    int rc = build_solver(l, err);
    if (rc == ISO_OK)
        rc = init_mapping(l, err);
    if (rc == ISO_OK)
        rc = open_devices(l, err);
    if (rc == ISO_OK)
        rc = iso_loop__sinks_open(l, err);
    const char *rec = l->o.record ? l->o.record : sc->recording;
    if (rc == ISO_OK && rec[0] && l->hub && !l->replay) {
        rc = iso_dev_hub_record_start(l->hub, rec, err);
        l->recording = rc == ISO_OK;
    } else if (rc == ISO_OK && rec[0] && l->replay) {
        fprintf(l->log, "isoshape run: not recording to %s: the devices are a replay already\n",
                rec);
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
    int rc = iso_loop__sinks_close(l, err);
    if (l->hub && l->recording && !l->replay) {
        /* what arrived after the last tick goes into the recording too */
        iso_dev_event ev[64];
        size_t n = 0;
        int r1 = iso_dev_hub_drain(l->hub, l->stream_now + l->period_ns, ev, 64, &n, err);
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
        fprintf(l->log, "isoshape run: shutdown: %s\n", e.msg);
    iso_dev_hub_destroy(l->hub);
    if (l->replay)
        iso_dev_rec_reader_deinit(&l->reader);
    iso_stepper_destroy(l->st);
    iso_solver_destroy(l->solver);
    iso_loop__stats_deinit(&l->stats);
    free(l->sinks);
    free(l->x);
    free(l);
}

/* ======================================================================== */
/* One tick                                                                 */
/* ======================================================================== */

/* The device-driven handles' poses, in the mapping's order. */
static void map_poses(const iso_loop *l, iso_pose *P)
{
    for (int j = 0; j < (int)ISO_DEV_MAX_HANDLES; j++)
        iso_pose_identity(&P[j]);
    for (int j = 0; j < l->n_dev; j++)
        P[j] = *iso_stepper_pose(l->st, l->dev_handle[j]);
}

static int discontinuity(const iso_dev_tick *a, const iso_dev_tick *b)
{
    return a->clutch != b->clutch || a->estop != b->estop || a->active != b->active ||
           a->gone != b->gone;
}

/* The reset_pose action: the active handle glides back to rest over a
 * second (a jump in one tick would tear the mesh). */
#define ISO_LOOP_HOMING_S 1.0

static int handle_twists(iso_loop *l, const iso_dev_tick *cmd, double h, iso_twist *tw,
                         int *restart, iso_err *err)
{
    const iso_scene *sc = l->sc;
    memset(tw, 0, sizeof(iso_twist) * ISO_SCENE_MAX_HANDLES);
    if (cmd->actions & (1u << ISO_DEV_ACT_RESET_POSE) && l->n_dev > 0) {
        l->homing_left[l->dev_handle[cmd->active]] = ISO_LOOP_HOMING_S;
        *restart = 1;
    }
    for (int j = 0; j < l->n_dev && j < cmd->n_handles; j++)
        tw[l->dev_handle[j]] = cmd->twist[j];
    for (int k = 0; k < sc->n_handles; k++) {
        const iso_scene_driver *d = &sc->handles[k].driver;
        const iso_pose *G = iso_stepper_pose(l->st, k);
        int crossed = 0, rc = ISO_OK;
        if (cmd->estop) {
            memset(&tw[k], 0, sizeof tw[k]);
        } else if (l->homing_left[k] > 0) {
            iso_pose rest;
            iso_pose_identity(&rest);
            /* the constant twist that reaches rest when the glide ends */
            double left = l->homing_left[k] > h ? l->homing_left[k] : h;
            rc = iso_loop__twist_between(G, &rest, left, &tw[k], err);
            l->homing_left[k] -= h;
            if (l->homing_left[k] <= 0)
                *restart = 1;
        } else if (d->kind == ISO_SCENE_DRIVE_SCREW || d->kind == ISO_SCENE_DRIVE_KEYFRAMES) {
            rc = iso_loop__scripted_twist(d, l->centroid[k], G, l->script_t, h, &tw[k], &crossed,
                                          err);
        }
        if (rc != ISO_OK)
            return rc;
        if (crossed)
            *restart = 1;
    }
    if (!cmd->estop)
        l->script_t += h;
    return ISO_OK;
}

/* Drains the devices up to stream time t_ns, advances the mesh by dt_s and
 * publishes it. */
static int tick(iso_loop *l, int64_t t_ns, double dt_s, iso_err *err)
{
    iso_dev_tick cmd;
    memset(&cmd, 0, sizeof cmd);
    cmd.n_handles = l->n_dev;
    int rc = ISO_OK;
    if (l->hub) {
        iso_pose P[ISO_DEV_MAX_HANDLES];
        map_poses(l, P);
        rc = iso_dev_hub_tick(l->hub, &l->map, t_ns, dt_s, P, &cmd, err);
        if (rc != ISO_OK)
            return rc;
        if (l->replay && l->reader.damaged > l->damaged_seen) {
            fprintf(l->log, "isoshape run: %s\n", l->reader.note);
            l->damaged_seen = l->reader.damaged;
        }
        if ((cmd.actions & (1u << ISO_DEV_ACT_RECORD)) && !l->replay) {
            const char *rec = l->o.record ? l->o.record : l->sc->recording;
            if (l->recording) {
                rc = iso_dev_hub_record_stop(l->hub, err);
                l->recording = 0;
                fprintf(l->log, "isoshape run: recording stopped\n");
            } else if (rec[0]) {
                rc = iso_dev_hub_record_start(l->hub, rec, err);
                l->recording = rc == ISO_OK;
                fprintf(l->log, "isoshape run: recording to %s\n", rec);
            }
            if (rc != ISO_OK)
                return rc;
        }
    }
    int restart = l->ticks == 0 || (l->ticks > 0 && discontinuity(&cmd, &l->last));
    iso_twist tw[ISO_SCENE_MAX_HANDLES];
    if ((rc = handle_twists(l, &cmd, dt_s, tw, &restart, err)) != ISO_OK)
        return rc;
    if (restart && l->ticks > 0)
        l->restarts++;
    int sub = l->sc->steps_per_tick > 0 ? l->sc->steps_per_tick : 1;
    for (int i = 0; i < sub && rc == ISO_OK; i++)
        rc = iso_stepper_step(l->st, dt_s / sub, tw, i == 0 && restart, err);
    if (rc != ISO_OK)
        return rc;
    l->last = cmd;
    l->stream_now = t_ns;
    return iso_loop__sinks_publish(l, l->ticks, err);
}

/* ======================================================================== */
/* The run                                                                  */
/* ======================================================================== */

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* Sleeps to an absolute deadline; returns early only for a stop request. */
static void sleep_until(const iso_loop *l, int64_t t)
{
    struct timespec ts = {(time_t)(t / 1000000000), (long)(t % 1000000000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
        if (l->o.stop && *l->o.stop)
            return;
}

/* SCHED_FIFO and locked memory, when this process may have them. Asked for
 * after the display's and BLAS's threads exist, so only the loop's thread
 * (and threads it starts later) run at real-time priority. */
static void go_realtime(iso_loop *l)
{
    iso_loop_summary *r = &l->rt;
    char why[200] = "";
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = 20;
    if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0)
        r->rt_active = 1;
    else
        snprintf(why, sizeof why, "SCHED_FIFO: %s", strerror(errno));
    if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0)
        r->mem_locked = 1;
    else
        snprintf(why + strlen(why), sizeof why - strlen(why), "%smlockall: %s", why[0] ? "; " : "",
                 strerror(errno));
    if (why[0]) {
        snprintf(r->rt_note, sizeof r->rt_note,
                 "not permitted (%s): normal priority (grant CAP_SYS_NICE and CAP_IPC_LOCK, or "
                 "rtprio/memlock in limits.conf)",
                 why);
        fprintf(l->log, "isoshape run: real-time scheduling %s\n", r->rt_note);
    } else {
        fprintf(l->log, "isoshape run: real-time: SCHED_FIFO priority %d, memory locked\n",
                sp.sched_priority);
    }
}

/* The stream time of the next tick, or INT64_MAX when the stream is over. */
static int64_t next_stream_tick(iso_loop *l)
{
    if (l->replay)
        return iso_dev_hub_next_tick(l->hub, l->period_ns);
    return l->stream0 + (l->ticks + 1) * l->period_ns;
}

/* With no device and no scripted motion left, there is nothing to wait for. */
static double scripted_end(const iso_loop *l)
{
    double end = 0;
    for (int k = 0; k < l->sc->n_handles; k++) {
        double e = iso_loop__scripted_end(&l->sc->handles[k].driver);
        if (e > end)
            end = e;
    }
    return end;
}

static void status_line(iso_loop *l, double t_s)
{
    double med, p99, max;
    iso_loop__stats_recent(&l->stats, &med, &p99, &max);
    char extra[128];
    iso_loop__sinks_status(l, extra, sizeof extra);
    fprintf(l->log,
            "\r\033[Ktick %ld  t %.2f s  tick %.1f/%.1f/%.1f ms (med/p99/max)  misses %ld  %s",
            l->ticks, t_s, med, p99, max, l->stats.misses, extra);
    fflush(l->log);
}

int iso_loop_run(iso_loop *l, iso_err *err)
{
    const int live = l->hub && !l->replay;
    const int timed = !l->o.fast;
    if (timed && l->o.rt)
        go_realtime(l);
    else if (!timed && live)
        fprintf(l->log, "isoshape run: --fast with live devices: ticks do not wait for input\n");
    double end_s = l->o.duration_s > 0 ? l->o.duration_s : 0;
    if (end_s == 0 && !l->hub) {
        end_s = scripted_end(l);
        if (end_s == 0 && l->o.max_ticks == 0) {
            fprintf(l->log, "isoshape run: nothing drives the handles: running 1 s of ticks\n");
            end_s = 1;
        }
    }
    l->stream0 = live ? iso_dev_now_ns() : 0;
    if (l->replay) {
        /* the recording's start, so the first tick is as long as it was */
        int64_t first = iso_dev_hub_next_tick(l->hub, l->period_ns);
        l->stream0 = first == INT64_MAX ? 0 : first - l->period_ns;
        if (first != INT64_MAX && l->reader.t0_ns < first && l->reader.t0_ns >= l->stream0)
            l->stream0 = l->reader.t0_ns;
    }
    int64_t t_prev = l->stream0;
    int64_t anchor = now_ns(), prev_wake = anchor;
    l->wall_start = iso_clock_now();
    double last_status = 0;
    int rc = ISO_OK;
    for (;;) {
        if (l->o.stop && *l->o.stop)
            break;
        if (l->o.max_ticks > 0 && l->ticks >= l->o.max_ticks)
            break;
        int64_t t = next_stream_tick(l);
        if (t == INT64_MAX)
            break;
        if (end_s > 0 && (double)(t - l->stream0) * 1e-9 > end_s + 1e-9)
            break;
        int64_t deadline = anchor + (int64_t)((double)(t - l->stream0) / l->o.speed);
        if (timed) {
            int64_t now = now_ns();
            if (now > deadline && l->ticks > 0) {
                /* the previous tick overran this deadline: skip the ones
                 * already past, start this tick at once */
                l->stats.misses++;
                int64_t per = (int64_t)((double)l->period_ns / l->o.speed);
                int64_t n = per > 0 ? (now - deadline) / per : 0;
                l->stats.skipped += n;
                anchor += n * per;
                deadline += n * per;
            }
            sleep_until(l, deadline);
            if (l->o.stop && *l->o.stop)
                break;
        }
        int64_t wake = now_ns();
        double dt = (double)(t - t_prev) * 1e-9;
        if (!(dt > 0))
            dt = (double)l->period_ns * 1e-9;
        if ((rc = tick(l, t, dt, err)) != ISO_OK)
            break;
        int64_t done = now_ns();
        l->ticks++;
        t_prev = t;
        if ((rc = iso_loop__stats_add(&l->stats, (double)(done - wake) * 1e-6,
                                      (double)(done - prev_wake) * 1e-6, err)) != ISO_OK)
            break;
        prev_wake = wake;
        double w = iso_clock_now();
        if (l->o.status_line && w - last_status > 0.25) {
            status_line(l, (double)(t - l->stream0) * 1e-9);
            last_status = w;
        }
    }
    l->wall_end = iso_clock_now();
    if (l->o.status_line)
        fprintf(l->log, "\r\033[K");
    if (l->rt.rt_active) { /* the summary and shutdown need no real-time priority */
        struct sched_param sp;
        memset(&sp, 0, sizeof sp);
        if (sched_setscheduler(0, SCHED_OTHER, &sp) != 0)
            fprintf(l->log, "isoshape run: back to SCHED_OTHER: %s\n", strerror(errno));
    }
    return rc;
}

/* ======================================================================== */
/* Results                                                                  */
/* ======================================================================== */

static uint64_t fnv1a(const void *p, size_t n)
{
    const unsigned char *b = p;
    uint64_t h = 0xcbf29ce484222325ULL;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 0x100000001b3ULL;
    return h;
}

void iso_loop_get_summary(iso_loop *l, iso_loop_summary *s)
{
    memset(s, 0, sizeof *s);
    s->ticks = l->ticks;
    s->stream_s = (double)(l->stream_now - l->stream0) * 1e-9;
    if (l->ticks == 0)
        s->stream_s = 0;
    double end = l->wall_end > 0 ? l->wall_end : iso_clock_now();
    s->wall_s = l->wall_start > 0 ? end - l->wall_start : 0;
    s->period_ms = (double)l->period_ns * 1e-6;
    const iso_loop_stats *st = &l->stats;
    s->tick_median = iso_loop__quantile(st->tick_ms, st->n, 0.5);
    s->tick_p99 = iso_loop__quantile(st->tick_ms, st->n, 0.99);
    s->tick_max = iso_loop__quantile(st->tick_ms, st->n, 1.0);
    s->latency_median = iso_loop__quantile(st->lat_ms, st->n, 0.5);
    s->latency_p99 = iso_loop__quantile(st->lat_ms, st->n, 0.99);
    s->latency_max = iso_loop__quantile(st->lat_ms, st->n, 1.0);
    s->misses = st->misses;
    s->skipped = st->skipped;
    s->restarts = l->restarts;
    iso_stepper_stats(l->st, &s->integ);
    iso_solver_get_stats(l->solver, &s->solver);
    iso_metrics_compute(l->sc->mesh, iso_mesh_positions(l->sc->mesh), l->x, &s->metrics);
    s->checksum = fnv1a(l->x, (size_t)l->nv * 3 * sizeof *l->x);
    s->n_handles = l->sc->n_handles;
    for (int h = 0; h < s->n_handles; h++) {
        const iso_pose *G = iso_stepper_pose(l->st, h);
        iso_pose_apply(G, l->centroid[h], s->handle_p[h]);
        memcpy(s->handle_R[h], G->R, sizeof G->R);
    }
    s->rt_active = l->rt.rt_active;
    s->mem_locked = l->rt.mem_locked;
    memcpy(s->rt_note, l->rt.rt_note, sizeof s->rt_note);
    iso_loop__sinks_summary(l, s);
}

const double *iso_loop_positions(const iso_loop *l)
{
    return l->x;
}

const iso_mesh *iso_loop_mesh(const iso_loop *l)
{
    return l->sc->mesh;
}
