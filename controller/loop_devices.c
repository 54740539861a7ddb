/* controller/loop_devices.c -- the loop's input side: the scene's devices
 * or the replayed recording, the mapping, and the commanded motion each
 * device tick and each scripted path gives the handles (iso_loop.h). */
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
    case ISO_SCENE_DEV_VIEW: return iso_dev_view_open(d->name, out, err);
    default: return iso_err_set(err, ISO_EINVAL, -1, "device '%s': unknown kind", d->name);
    }
}

static int reopen_device(void *ctx, const iso_dev_info *info, iso_dev_source **out, iso_err *err)
{
    (void)info;
    return open_device(ctx, out, err);
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
    int rc = iso_dev_hub_create(iso_loop__note, l, &l->hub, err);
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
            char cut[400];
            if (iso_dev_rec_reader_cut(&l->reader, cut, sizeof cut, NULL))
                iso_loop_say(l, "%s: %s", d->path, cut);
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
        if (d->backend == ISO_SCENE_DEV_VIEW)
            l->view_src = s; /* the hub owns it; the display queues the page's commands on it */
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
            iso_loop_say(l,
                         "handle '%s' maps its device like handle '%s' (one mapping "
                         "serves every device-driven handle)",
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

/* Targets and poses refused beyond the workspace: the first of a source
 * said, then at each tenfold (a page that keeps sending one is said a few
 * times, not every tick). */
static void say_far(iso_loop *l)
{
    for (size_t i = 0; i < ISO_DEV_MAX_SOURCES; i++) {
        uint32_t n = l->map.far[i];
        if (n == l->far_said[i])
            continue;
        uint32_t next = l->far_said[i] ? l->far_said[i] * 10 : 1;
        if (n >= next) {
            iso_loop_say(l,
                         "device %zu: %u target%s beyond the workspace refused (a handle's centre "
                         "stays within %g bounding-box diagonals of where it rests)",
                         i, n, n == 1 ? "" : "s", ISO_DEV_WORKSPACE_DIAGS);
            l->far_said[i] = n;
        }
    }
}

/* Each twist stream's staleness bound (a replay's applies to every source
 * it recorded), then one line per device: what it is and where. */
static int devices_ready(iso_loop *l, iso_err *err)
{
    const iso_scene *sc = l->sc;
    iso_dev_info infos[ISO_DEV_MAX_SOURCES];
    size_t n = iso_dev_hub_infos(l->hub, infos, ISO_DEV_MAX_SOURCES);
    for (size_t i = 0; i < n && i < ISO_DEV_MAX_SOURCES; i++) {
        const iso_scene_device *d = &sc->devices[l->replay ? 0 : i];
        /* a source's kind gives the default, the recorded kind in a
         * replay, so a replay times out as the live run did */
        int ms = iso_scene_device_stale_ms(d, infos[i].kind);
        int rc = iso_dev_map_set_stale(&l->map, (int)i, (int64_t)ms * 1000000, err);
        if (rc != ISO_OK)
            return rc;
        /* Targets and poses keep the handles within a workspace the mesh
         * gives, the same live and replayed (without a mesh, no bound). */
        int wrc = l->diag > 0 ? iso_dev_map_set_workspace(&l->map, (int)i,
                                                          ISO_DEV_WORKSPACE_DIAGS * l->diag, err)
                              : ISO_OK;
        if (wrc != ISO_OK)
            return wrc;
        /* A page's targets are followed at a bounded speed, the same live and
         * replayed (the bound comes from the mesh, not from the scene). */
        const iso_dev_decoder *dec = iso_dev_hub_decoder(l->hub, i);
        if (dec && dec->kind == ISO_DEV_KIND_VIEW) {
            double speed = ISO_DEV_VIEW_MAX_DIAG_PER_S * (l->diag > 0 ? l->diag : 1);
            int rc =
                iso_dev_map_set_limits(&l->map, (int)i, speed, ISO_DEV_VIEW_MAX_TURN_PER_S, err);
            if (rc != ISO_OK)
                return rc;
        }
        char desc[192];
        iso_dev_hub_describe(l->hub, i, desc, sizeof desc);
        iso_loop_say(l, "device %zu: %s", i, desc);
    }
    return ISO_OK;
}

int iso_loop__devices_open(iso_loop *l, iso_err *err)
{
    int rc = init_mapping(l, err);
    if (rc == ISO_OK)
        rc = open_devices(l, err);
    if (rc == ISO_OK && l->hub)
        rc = devices_ready(l, err);
    return rc;
}

/* ======================================================================== */
/* Commanded motion: device ticks and scripted paths                        */
/* ======================================================================== */

uint64_t iso_loop__fnv1a(uint64_t h, const void *p, size_t n)
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

/* The record button: its recordings open and close on the recorder's
 * thread (loop_recorder.c), never on the tick. Without a recording path
 * it says so. A recording that cannot start or end cleanly (a FIFO with no
 * reader, a full disk) is said, and the run goes on. */
static void press_record(iso_loop *l)
{
    if (l->recorder)
        iso_loop__recorder_press(l->recorder, l->hub, &l->recording);
    else
        iso_loop_say(l, "the record button: no recording path (the scene's `recording:` or "
                        "--record FILE)");
}

/* One device tick over (l->t_now, t]: drain, map with the commanded poses,
 * advance them, and move l->t_now to t. tw[] receives the twist each device-driven handle was
 * commanded with (zero under an e-stop); *restart is raised on a
 * discontinuity. */
int iso_loop__device_tick(iso_loop *l, int64_t t, iso_twist *tw, int *restart, iso_err *err)
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
    if (l->recorder)
        iso_loop__recorder_poll(l->recorder, l->hub, &l->recording);
    iso_dev_tick cmd;
    int rc = iso_dev_hub_tick(l->hub, &l->map, t, dt, P, &cmd, err);
    if (rc != ISO_OK)
        return rc;
    l->cmd_sum = iso_loop__fnv1a(l->cmd_sum, &cmd, sizeof cmd);
    if (l->o.on_command)
        l->o.on_command(l->o.hook_ctx, &cmd, dt);
    if (l->replay && l->reader.damaged > l->damaged_seen) {
        iso_loop_say(l, "%s", l->reader.note);
        l->damaged_seen = l->reader.damaged;
    }
    say_far(l);
    if ((cmd.actions & (1u << ISO_DEV_ACT_RECORD)) && !l->replay)
        press_record(l);
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
int iso_loop__scripted_poses(iso_loop *l, double s0, int *restart, iso_err *err)
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
