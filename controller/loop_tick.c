/* controller/loop_tick.c -- one tick: the device ticks it covers, the
 * commanded poses, and the mesh step that takes the handles there in as
 * many sub-steps as the motion needs (iso_loop.h). */
#include "loop_internal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include "iso_clock.h"

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
    /* A late tick sheds work: with restoration on, at most
     * ISO_LOOP_LATE_SHARE of the periods it covers, so that while a step
     * costs less than 1 / share periods the next tick covers fewer periods
     * than this one and the loop catches up instead of falling further
     * behind. Without it (the paper's method) every period keeps its
     * sub-step: nothing heals the lag a longer step leaves at a twist's
     * jump, and the late drag of tests/streams ended at 358% edge strain
     * with half the sub-steps against 170% with all (92% and 94% with
     * restoration; on time 94% and 92%). */
    double most = ceil(periods - 1e-6);
    if (l->sc->solver.restore_mu > 0)
        most = ceil(ISO_LOOP_LATE_SHARE * periods - 1e-6);
    *coarse = need > most;
    double n = fmin(need, most);
    /* Restoration has a time scale of its own: a long step relaxes the
     * mesh as if τ were κ h, which is stable for the rates the clamp was
     * measured at, not for a step of many τ (a recorded session's mesh
     * tore when one sub-step covered 31 s at τ 0.5 s; steps of 1 s held).
     * Sub-steps stay within ISO_LOOP_RESTORE_SUBSTEP_TAU τ while it is
     * on (and within a period, should τ be shorter), whatever the share. */
    if (l->sc->solver.restore_mu > 0) {
        double hmax = fmax(ISO_LOOP_RESTORE_SUBSTEP_TAU * l->sc->solver.restore_tau,
                           1e-9 * (double)l->period_ns);
        n = fmax(n, fmin(ceil(H / hmax - 1e-9), ceil(periods - 1e-6)));
    }
    if (n < 1)
        n = 1;
    if (n > ISO_LOOP_MAX_SUBSTEPS)
        *coarse = 1;
    return n > ISO_LOOP_MAX_SUBSTEPS ? ISO_LOOP_MAX_SUBSTEPS : (int)n;
}

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

/* Moves the mesh's handles to their commanded poses over H seconds. When
 * the tick was one device tick and needs one step, the handles take the
 * commanded twists themselves (the same arithmetic as the commanded poses,
 * bit for bit); otherwise the constant twist that reaches each pose. */
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
    if (rc == ISO_OK && l->proxy) { /* the full mesh follows the proxy */
        iso_pose poses[ISO_SCENE_MAX_HANDLES];
        for (int k = 0; k < l->nh; k++)
            poses[k] = *iso_stepper_pose(l->st, k);
        iso_proxy_prolong(l->proxy, l->y, poses, l->x);
    }
    return rc;
}

/* One tick: the device ticks it covers (more than one only when late), the
 * scripted poses, the mesh step, the sinks. now is the wall time it woke at
 * (0 with `fast`). */
int iso_loop__tick(iso_loop *l, int64_t now, iso_err *err)
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
            if ((rc = iso_loop__device_tick(l, t, dev_tw, &restart, err)) != ISO_OK)
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
            if ((rc = iso_loop__device_tick(l, t, dev_tw, &restart, err)) != ISO_OK)
                return rc;
        } else {
            l->script_ns += t - t_prev;
        }
        merged = 1; /* one device tick over the whole interval: what the recording says */
        l->k = k1;
        l->t_now = t;
    }
    /* A tick's sub-steps are counted on the periods it spans; a replayed
     * tick spans what its TICK records span, as live, so a late live tick
     * replays with the same sub-steps and to the same bits. */
    int periods = covered;
    if (l->replay) {
        covered = merged;
        long span = l->period_ns > 0 ? lround((double)(t - t_prev) / (double)l->period_ns) : 1;
        periods = span > covered ? (int)(span < INT_MAX ? span : INT_MAX) : covered;
    }
    if (covered > 1) {
        l->stats.misses++;
        l->stats.skipped += covered - 1;
    }
    int steps = 0;
    if (l->st) {
        if ((rc = iso_loop__scripted_poses(l, s0, &restart, err)) != ISO_OK)
            return rc;
        if (restart && l->ticks > 0)
            l->restarts++;
        rc = mesh_step(l, (double)(t - t_prev) * 1e-9, merged, periods, dev_tw, restart, &steps,
                       err);
        if (rc != ISO_OK)
            return rc;
        int per = l->sc->steps_per_tick > 0 ? l->sc->steps_per_tick : 1;
        l->substeps += steps - per;
        l->last_merged = merged;
        l->last_substeps = steps;
        l->last_restart = restart;
        l->last_dt_ns = t - t_prev;
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
