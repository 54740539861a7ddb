/* controller/loop.c -- the tick engine: build a scene's parts, then tick on
 * absolute deadlines. iso_loop.h states the clocks, the commanded motion,
 * the late-tick and sub-step rules. */
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
    o->display = -1;
    o->port = -1;
    o->assembly = -1;
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    o->threads = so.threads;
}

/* ======================================================================== */
/* Devices                                                                  */
/* ======================================================================== */

static int open_device(const iso_scene_device *d, iso_dev_source **out, iso_err *err)
{
    switch (d->backend) {
    case ISO_SCENE_DEV_HIDAPI:
        return iso_dev_hid_open_id(d->path[0] ? d->path : NULL, d->vid, d->pid, out, err);
    case ISO_SCENE_DEV_SPNAV: return iso_dev_spnav_open(out, err);
    case ISO_SCENE_DEV_TTY: return iso_dev_tty_open(d->path, d->baud, out, err);
    case ISO_SCENE_DEV_TCP: return iso_dev_tcp_open(d->address, 1000, out, err);
    case ISO_SCENE_DEV_SERIALPORT: return iso_dev_serialport_open(d->path, d->baud, out, err);
    case ISO_SCENE_DEV_GPIOD: return iso_dev_gpiod_open(&d->gpio, out, err);
    default: return iso_err_set(err, ISO_EINVAL, -1, "device '%s': unknown kind", d->name);
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
    fprintf(l->log, "%sisoshape %s: %s\n", l->o.status_line ? "\r\033[K" : "", l->cmd, msg);
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
            if (!sc->path[0]) /* a command's own scene: the source's error says it all */
                return rc;
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
                    "isoshape %s: handle '%s' maps its device like handle '%s' (one mapping "
                    "serves every device-driven handle)\n",
                    l->cmd, sc->handles[h].name, sc->handles[first].name);
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

/* Each twist stream's staleness bound (a replay's applies to every source
 * it recorded), then one line per device: what it is and where. */
static int devices_ready(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    size_t n = iso_dev_hub_sources(l->hub);
    for (size_t i = 0; i < n; i++) {
        const iso_scene_device *d = &sc->devices[l->replay ? 0 : i];
        if (d->stale_ms > 0) {
            int rc = iso_dev_map_set_stale(&l->map, (int)i, (int64_t)d->stale_ms * 1000000, err);
            if (rc != ISO_OK)
                return rc;
        }
        char desc[192];
        iso_dev_hub_describe(l->hub, i, desc, sizeof desc);
        fprintf(l->log, "isoshape %s: device %zu: %s\n", l->cmd, i, desc);
    }
    return ISO_OK;
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

static int build_solver(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    iso_solver_opts so = sc->solver;
    if (l->o.assembly >= 0)
        so.assembly = (iso_assembly)l->o.assembly;
    so.cl_device = l->o.cl_device;
    so.threads = l->o.threads;
    int rc = iso_solver_create(sc->mesh, &sc->regions, &so, &l->solver, err);
    if (rc != ISO_OK)
        return rc;
    iso_solver_set_progress(l->solver, solver_progress, l);
    const char *notice = iso_solver_notice(l->solver);
    if (notice && notice[0])
        fprintf(l->log, "isoshape %s: %s\n", l->cmd, notice);
    l->x = malloc((size_t)l->nv * 3 * sizeof *l->x);
    if (!l->x)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertices", l->nv);
    memcpy(l->x, iso_mesh_positions(sc->mesh), (size_t)l->nv * 3 * sizeof *l->x);
    rc = iso_stepper_create(l->solver, sc->mesh, &sc->regions, l->x, &l->st, err);
    if (rc == ISO_OK)
        rc = iso_stepper_configure(l->st, (iso_abm_mode)sc->abm_mode, sc->integrate.restore_kappa,
                                   err);
    if (rc == ISO_OK)
        rc = iso_stepper_set_cg_share(l->st, sc->integrate.cg_share, err);
    /* The first factorization before the clock starts, not in the first
     * tick (in --fast too, so that both runs give the same bits). */
    if (rc == ISO_OK)
        rc = iso_solver_factor_at(l->solver, l->x, err);
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
        fprintf(l->log, "isoshape %s: nothing drives the handles: running 1 s of ticks\n", l->cmd);
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
    if (!(l->o.speed > 0))
        l->o.speed = 1;
    l->period_ns = (int64_t)llround(1e9 / sc->tick_hz);
    for (int h = 0; h < ISO_SCENE_MAX_HANDLES; h++)
        iso_pose_identity(&l->cmd_pose[h]);
    iso_loop__stats_init(&l->stats);
    l->nh = sc->n_handles;
    int rc = sc->mesh ? open_mesh_side(l, err) : ISO_OK;
    if (rc == ISO_OK)
        rc = init_mapping(l, err);
    if (rc == ISO_OK)
        rc = open_devices(l, err);
    if (rc == ISO_OK && l->hub)
        rc = devices_ready(l, err);
    if (rc == ISO_OK && sc->mesh)
        rc = iso_loop__sinks_open(l, err);
    const char *rec = l->o.record ? l->o.record : sc->recording;
    if (rc == ISO_OK && rec[0] && l->hub && !l->replay) {
        rc = iso_dev_hub_record_start(l->hub, rec, err);
        l->recording = rc == ISO_OK;
    } else if (rc == ISO_OK && rec[0] && l->replay) {
        fprintf(l->log, "isoshape %s: not recording to %s: the devices are a replay already\n",
                l->cmd, rec);
    }
    if (rc == ISO_OK && l->hub && !l->replay) {
        iso_err quiet; /* without libusb the retry interval still finds replugged devices */
        iso_err_clear(&quiet);
        if (iso_dev_usb_watch_create(&l->watch, &quiet) != ISO_OK)
            l->watch = NULL;
    }
    if (rc == ISO_OK)
        plan_end(l);
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
        fprintf(l->log, "isoshape %s: shutdown: %s\n", l->cmd, e.msg);
    iso_dev_usb_watch_destroy(l->watch);
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
/* Commanded motion: device ticks and scripted paths                        */
/* ======================================================================== */

static uint64_t fnv1a(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 0x100000001b3ULL;
    return h;
}

static int discontinuity(const iso_dev_tick *a, const iso_dev_tick *b)
{
    return a->clutch != b->clutch || a->estop != b->estop || a->active != b->active ||
           a->gone != b->gone;
}

/* The reset_pose action: the active handle glides back to rest over a
 * second (a jump in one tick would tear the mesh). */
#define ISO_LOOP_HOMING_S 1.0

/* g ← exp(dt ξ) ∘ g */
static void advance_pose(iso_pose *g, const iso_twist *xi, double dt)
{
    iso_pose e, n;
    iso_twist_exp(xi, dt, &e);
    iso_pose_compose(&e, g, &n);
    *g = n;
}

static int toggle_recording(iso_loop *l, iso_err *err)
{
    const char *rec = l->o.record ? l->o.record : l->sc->recording;
    int rc = ISO_OK;
    if (l->recording) {
        rc = iso_dev_hub_record_stop(l->hub, err);
        l->recording = 0;
        fprintf(l->log, "isoshape %s: recording stopped\n", l->cmd);
    } else if (rec[0]) {
        rc = iso_dev_hub_record_start(l->hub, rec, err);
        l->recording = rc == ISO_OK;
        fprintf(l->log, "isoshape %s: recording to %s\n", l->cmd, rec);
    }
    return rc;
}

/* One device tick over (l->t_now, t]: drain, map with the commanded poses,
 * advance them, and move l->t_now to t. tw[] receives the twist each device-driven handle was
 * commanded with (zero under an e-stop); *restart is raised on a
 * discontinuity. */
static int device_tick(iso_loop *l, int64_t t, iso_twist *tw, int *restart, iso_err *err)
{
    const int64_t dt_ns = t - l->t_now;
    const double dt = (double)dt_ns * 1e-9;
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (int j = 0; j < (int)ISO_DEV_MAX_HANDLES; j++)
        iso_pose_identity(&P[j]);
    for (int j = 0; j < l->n_dev; j++)
        P[j] = l->cmd_pose[l->dev_handle[j]];
    if (l->watch && iso_dev_usb_watch_poll(l->watch) > 0)
        iso_dev_hub_retry_now(l->hub);
    iso_dev_tick cmd;
    int rc = iso_dev_hub_tick(l->hub, &l->map, t, dt, P, &cmd, err);
    if (rc != ISO_OK)
        return rc;
    l->cmd_sum = fnv1a(l->cmd_sum, &cmd, sizeof cmd);
    if (l->o.on_command)
        l->o.on_command(l->o.hook_ctx, &cmd, dt);
    if (l->replay && l->reader.damaged > l->damaged_seen) {
        fprintf(l->log, "isoshape %s: %s\n", l->cmd, l->reader.note);
        l->damaged_seen = l->reader.damaged;
    }
    if ((cmd.actions & (1u << ISO_DEV_ACT_RECORD)) && !l->replay &&
        (rc = toggle_recording(l, err)) != ISO_OK)
        return rc;
    if (cmd.estop != l->last.estop || l->device_ticks == 0)
        iso_loop__sinks_estop(l, cmd.estop); /* at once, before the mesh step */
    if (l->device_ticks > 0 && discontinuity(&cmd, &l->last))
        *restart = 1;
    l->device_ticks++;
    l->last = cmd;
    if (cmd.actions & (1u << ISO_DEV_ACT_RESET_POSE) && l->n_dev > 0) {
        l->homing_left[l->dev_handle[cmd.active]] = ISO_LOOP_HOMING_S;
        *restart = 1;
    }
    for (int j = 0; j < l->n_dev && j < cmd.n_handles; j++) {
        int k = l->dev_handle[j];
        memset(&tw[k], 0, sizeof tw[k]);
        if (cmd.estop)
            continue;
        if (l->homing_left[k] > 0) {
            iso_pose rest;
            iso_pose_identity(&rest);
            /* the constant twist that reaches rest when the glide ends */
            double left = l->homing_left[k] > dt ? l->homing_left[k] : dt;
            if ((rc = iso_loop__twist_between(&l->cmd_pose[k], &rest, left, &tw[k], err)) != ISO_OK)
                return rc;
            l->homing_left[k] -= dt;
            if (l->homing_left[k] <= 0) {
                *restart = 1;
                l->homing_left[k] = 0;
                l->cmd_pose[k] = rest;
                continue;
            }
        } else {
            tw[k] = cmd.twist[j];
        }
        advance_pose(&l->cmd_pose[k], &tw[k], dt);
    }
    if (!cmd.estop)
        l->script_ns += dt_ns;
    l->t_now = t;
    return ISO_OK;
}

/* Scripted handles: their exact path pose at the scripted clock. */
static int scripted_poses(iso_loop *l, double s0, int *restart, iso_err *err)
{
    const iso_scene *sc = l->sc;
    double s1 = (double)l->script_ns * 1e-9;
    for (int k = 0; k < sc->n_handles; k++) {
        const iso_scene_driver *d = &sc->handles[k].driver;
        if (d->kind != ISO_SCENE_DRIVE_SCREW && d->kind != ISO_SCENE_DRIVE_KEYFRAMES)
            continue;
        if (s1 > s0 && iso_loop__scripted_jump(d, s0, s1))
            *restart = 1;
        int rc = iso_loop__scripted_pose(d, l->centroid[k], s1, &l->cmd_pose[k], err);
        if (rc != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

/* ======================================================================== */
/* The mesh step                                                            */
/* ======================================================================== */

/* How many sub-steps a tick of H seconds covering `periods` periods needs
 * for twists tw (iso_loop.h states the rule). */
static int substeps_for(iso_loop *l, const iso_twist *tw, double H, double periods, int *coarse)
{
    double need = 1;
    for (int k = 0; k < l->nh; k++) {
        const iso_pose *G = iso_stepper_pose(l->st, k);
        double c[3], vel[3];
        iso_pose_apply(G, l->centroid[k], c);
        iso_twist_velocity(&tw[k], c, vel);
        double ang =
            sqrt(tw[k].w[0] * tw[k].w[0] + tw[k].w[1] * tw[k].w[1] + tw[k].w[2] * tw[k].w[2]) * H *
            (180.0 / 3.14159265358979323846);
        double dis = sqrt(vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]) * H;
        need = fmax(need, ceil(ang / ISO_LOOP_SUBSTEP_DEG - 1e-9));
        if (l->diag > 0)
            need = fmax(need, ceil(dis / (ISO_LOOP_SUBSTEP_DIAG * l->diag) - 1e-9));
    }
    double n = fmin(need, ceil(periods - 1e-6));
    if (n < 1)
        n = 1;
    *coarse = n > ISO_LOOP_MAX_SUBSTEPS;
    return n > ISO_LOOP_MAX_SUBSTEPS ? ISO_LOOP_MAX_SUBSTEPS : (int)n;
}

/* Moves the mesh's handles to their commanded poses over H seconds. When
 * the tick was one device tick and needs one step, the handles take the
 * commanded twists themselves (the same arithmetic as the commanded poses,
 * bit for bit); otherwise the constant twist that reaches each pose. */
/* The twists that take each handle from where the stepper has it to its
 * commanded pose in H seconds; with `direct`, device-driven handles take
 * the commanded twists themselves. */
static int aim_twists(iso_loop *l, int direct, const iso_twist *dev_tw, double H, iso_twist *tw,
                      iso_err *err)
{
    for (int k = 0; k < l->nh; k++) {
        if (direct && l->sc->handles[k].driver.kind == ISO_SCENE_DRIVE_DEVICE) {
            tw[k] = dev_tw[k];
            continue;
        }
        int rc =
            iso_loop__twist_between(iso_stepper_pose(l->st, k), &l->cmd_pose[k], H, &tw[k], err);
        if (rc != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

static int mesh_step(iso_loop *l, double H, int merged, int covered, const iso_twist *dev_tw,
                     int restart, int *steps, iso_err *err)
{
    iso_twist tw[ISO_SCENE_MAX_HANDLES];
    memset(tw, 0, sizeof tw);
    int coarse = 0, direct = merged == 1;
    int rc = aim_twists(l, direct, dev_tw, H, tw, err);
    int n = rc == ISO_OK ? substeps_for(l, tw, H, covered, &coarse) : 1;
    if (rc == ISO_OK && n > 1 && direct) /* sub-steps aim at the pose: no round-off drift */
        rc = aim_twists(l, 0, dev_tw, H, tw, err);
    if (rc != ISO_OK)
        return rc;
    l->coarse += coarse;
    *steps = n * (l->sc->steps_per_tick > 0 ? l->sc->steps_per_tick : 1);
    for (int i = 0; i < *steps && rc == ISO_OK; i++) {
        iso_loop__sinks_alive(l); /* progress for the actuators' loop watchdog */
        rc = iso_stepper_step(l->st, H / *steps, tw, i == 0 && restart, err);
    }
    return rc;
}

/* One tick: the device ticks it covers (more than one only when late), the
 * scripted poses, the mesh step, the sinks. now is the wall time it woke at
 * (0 with `fast`). */
static int tick(iso_loop *l, int64_t now, iso_err *err)
{
    int timed = now > 0;
    int64_t t_prev = l->t_now, t = 0;
    int merged = 0, covered = 1, restart = l->ticks == 0, rc = ISO_OK;
    double s0 = (double)l->script_ns * 1e-9;
    iso_twist dev_tw[ISO_SCENE_MAX_HANDLES];
    memset(dev_tw, 0, sizeof dev_tw);
    if (l->replay) {
        /* every TICK record already due is one device tick of this tick */
        for (t = iso_dev_hub_next_tick(l->hub, l->period_ns);;) {
            if ((rc = device_tick(l, t, dev_tw, &restart, err)) != ISO_OK)
                return rc;
            merged++;
            int64_t t2 =
                timed && l->ticks > 0 ? iso_dev_hub_next_tick(l->hub, l->period_ns) : INT64_MAX;
            if (t2 == INT64_MAX || t2 - l->stream0 > l->t_end ||
                l->wall0 + (int64_t)((double)(t2 - l->stream0) / l->o.speed) > now)
                break;
            t = t2;
        }
    } else {
        /* the grid tick after the last, or the latest one already due */
        int64_t k1 = l->k + 1;
        while (timed && l->ticks > 0 && k1 < l->k_end &&
               l->wall0 + (int64_t)((double)(iso_loop__grid_ns(l, k1 + 1) - l->stream0) /
                                    l->o.speed) <=
                   now)
            k1++;
        covered = (int)(k1 - l->k);
        t = iso_loop__grid_ns(l, k1);
        if (l->hub) {
            if ((rc = device_tick(l, t, dev_tw, &restart, err)) != ISO_OK)
                return rc;
        } else {
            l->script_ns += t - t_prev;
        }
        merged = 1; /* one device tick over the whole interval: what the recording says */
        l->k = k1;
        l->t_now = t;
    }
    if (l->replay)
        covered = merged;
    if (covered > 1) {
        l->stats.misses++;
        l->stats.skipped += covered - 1;
    }
    int steps = 0;
    if (l->st) {
        if ((rc = scripted_poses(l, s0, &restart, err)) != ISO_OK)
            return rc;
        if (restart && l->ticks > 0)
            l->restarts++;
        rc = mesh_step(l, (double)(t - t_prev) * 1e-9, merged, covered, dev_tw, restart, &steps,
                       err);
        if (rc != ISO_OK)
            return rc;
        int per = l->sc->steps_per_tick > 0 ? l->sc->steps_per_tick : 1;
        l->substeps += steps - per;
        if ((rc = iso_loop__sinks_publish(l, l->ticks, err)) != ISO_OK)
            return rc;
    } else if (restart && l->ticks > 0) {
        l->restarts++;
    }
    l->ticks++;
    if (l->o.on_tick) {
        iso_loop_tick_info info = {
            l->ticks, (double)(t - l->stream0) * 1e-9, (double)(t - t_prev) * 1e-9, merged, steps,
            restart};
        l->o.on_tick(l->o.hook_ctx, &info);
    }
    return ISO_OK;
}

/* ======================================================================== */
/* The run                                                                  */
/* ======================================================================== */

int64_t iso_loop__grid_ns(const iso_loop *l, int64_t k)
{
    return l->stream0 + (int64_t)llround((double)k * 1e9 / l->sc->tick_hz);
}

/* Sleeps to an absolute deadline; returns early only for a stop request. */
static void sleep_until(const iso_loop *l, int64_t t)
{
    while (iso_clock_sleep_until(t))
        if (l->o.stop && *l->o.stop)
            return;
}

/* SCHED_FIFO and locked memory, when this process may have them. Asked for
 * after the display's and BLAS's threads exist, so only the loop's thread
 * (and threads it starts later) run at real-time priority. Memory: what
 * the process holds now (MCL_CURRENT: the mesh, the solver and its factor,
 * the sinks, the tick statistics reserved for the planned run), not what
 * it allocates later, so a browser's buffers are never locked (issue #14:
 * lock only the memory the loop needs). */
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
    /* the planned ticks, or 10 minutes of a live run, before the lock */
    long plan = l->k_end < INT64_MAX ? (long)l->k_end + 1 : (long)(600 * l->sc->tick_hz);
    iso_err quiet;
    iso_err_clear(&quiet);
    if (iso_loop__stats_reserve(&l->stats, plan, &quiet) != ISO_OK)
        snprintf(why + strlen(why), sizeof why - strlen(why), "%s%.100s", why[0] ? "; " : "",
                 quiet.msg);
    else if (mlockall(MCL_CURRENT) == 0)
        r->mem_locked = 1;
    else
        snprintf(why + strlen(why), sizeof why - strlen(why), "%smlockall: %s", why[0] ? "; " : "",
                 strerror(errno));
    if (why[0]) {
        snprintf(r->rt_note, sizeof r->rt_note,
                 "not permitted (%s): normal priority (grant CAP_SYS_NICE and CAP_IPC_LOCK, or "
                 "rtprio/memlock in limits.conf)",
                 why);
        fprintf(l->log, "isoshape %s: real-time scheduling %s\n", l->cmd, r->rt_note);
    } else {
        fprintf(l->log, "isoshape %s: real-time: SCHED_FIFO priority %d, memory locked\n", l->cmd,
                sp.sched_priority);
    }
}

/* The stream time of the next tick, or INT64_MAX when the run is over. */
static int64_t next_stream_tick(iso_loop *l)
{
    if (l->replay) {
        int64_t t = iso_dev_hub_next_tick(l->hub, l->period_ns);
        return t != INT64_MAX && t - l->stream0 > l->t_end ? INT64_MAX : t;
    }
    return l->k >= l->k_end ? INT64_MAX : iso_loop__grid_ns(l, l->k + 1);
}

/* The devices' part of the status line: events per second each, the
 * active handle, clutch and e-stop. */
static void devices_status(iso_loop *l, double dt, char *buf, size_t cap)
{
    buf[0] = 0;
    if (!l->hub)
        return;
    size_t n = iso_dev_hub_sources(l->hub), used = 0;
    for (size_t i = 0; i < n && i < ISO_DEV_MAX_SOURCES && used + 24 < cap; i++) {
        iso_dev_source_stats st;
        if (iso_dev_hub_source_stats(l->hub, i, &st) != ISO_OK)
            continue;
        double rate = dt > 0 ? (double)(st.events - l->status_events[i]) / dt : 0;
        l->status_events[i] = st.events;
        used += (size_t)snprintf(buf + used, cap - used, "dev%zu %.0f/s%s  ", i, rate,
                                 !st.present   ? " GONE"
                                 : st.is_stale ? " STALE"
                                               : "");
    }
    if (used + 40 < cap)
        snprintf(buf + used, cap - used, "handle %d%s%s  ", l->last.active,
                 l->last.clutch ? " clutch" : "", l->last.estop ? "  E-STOP" : "");
}

static void status_line(iso_loop *l, double t_s, double dt)
{
    double med, p99, max;
    iso_loop__stats_recent(&l->stats, &med, &p99, &max);
    char extra[160] = "", dev[256];
    if (l->sinks)
        iso_loop__sinks_status(l, extra, sizeof extra);
    devices_status(l, dt, dev, sizeof dev);
    fprintf(l->log,
            "\r\033[Ktick %ld  t %.2f s  tick %.1f/%.1f/%.1f ms (med/p99/max)  misses %ld  %s%s",
            l->ticks, t_s, med, p99, max, l->stats.misses, dev, extra);
    fflush(l->log);
}

/* The first tick's start: a live run's is now; a replay's is the recorded
 * loop's start, so the first tick is as long as it was there. */
static void start_streams(iso_loop *l)
{
    const int live = l->hub && !l->replay;
    l->stream0 = live ? iso_clock_ns() : 0;
    if (l->replay) {
        int64_t first = iso_dev_hub_next_tick(l->hub, l->period_ns);
        l->stream0 = first == INT64_MAX ? 0 : first - l->period_ns;
        if (first != INT64_MAX && l->reader.t0_ns < first && l->reader.t0_ns >= l->stream0)
            l->stream0 = l->reader.t0_ns;
    }
    l->t_now = l->stream0;
    l->k = 0;
}

int iso_loop_run(iso_loop *l, iso_err *err)
{
    const int live = l->hub && !l->replay;
    const int timed = !l->o.fast;
    if (timed && l->o.rt)
        go_realtime(l);
    else if (!timed && live)
        fprintf(l->log, "isoshape %s: --fast with live devices: ticks do not wait for input\n",
                l->cmd);
    start_streams(l);
    l->wall0 = iso_clock_ns();
    int64_t prev_wake = l->wall0;
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
        if (timed) {
            sleep_until(l, l->wall0 + (int64_t)((double)(t - l->stream0) / l->o.speed));
            if (l->o.stop && *l->o.stop)
                break;
        }
        int64_t wake = iso_clock_ns();
        iso_loop__sinks_alive(l);
        if ((rc = tick(l, timed ? wake : 0, err)) != ISO_OK)
            break;
        int64_t done = iso_clock_ns();
        if ((rc = iso_loop__stats_add(&l->stats, (double)(done - wake) * 1e-6,
                                      (double)(done - prev_wake) * 1e-6, err)) != ISO_OK)
            break;
        prev_wake = wake;
        double w = iso_clock_now();
        if (l->o.status_line && w - last_status > 0.25) {
            status_line(l, (double)(l->t_now - l->stream0) * 1e-9,
                        last_status > 0 ? w - last_status : 0);
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
            fprintf(l->log, "isoshape %s: back to SCHED_OTHER: %s\n", l->cmd, strerror(errno));
    }
    return rc;
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
    s->tick_median = iso_loop__quantile(st->tick_ms, st->n, 0.5);
    s->tick_p99 = iso_loop__quantile(st->tick_ms, st->n, 0.99);
    s->tick_max = iso_loop__quantile(st->tick_ms, st->n, 1.0);
    s->latency_median = iso_loop__quantile(st->lat_ms, st->n, 0.5);
    s->latency_p99 = iso_loop__quantile(st->lat_ms, st->n, 0.99);
    s->latency_max = iso_loop__quantile(st->lat_ms, st->n, 1.0);
    s->misses = st->misses;
    s->skipped = st->skipped;
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
    iso_metrics_compute(l->sc->mesh, iso_mesh_positions(l->sc->mesh), l->x, &s->metrics);
    s->checksum = fnv1a(0xcbf29ce484222325ULL, l->x, (size_t)l->nv * 3 * sizeof *l->x);
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
