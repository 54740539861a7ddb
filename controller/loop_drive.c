/* controller/loop_drive.c -- the scripted handle drivers of a scene as
 * exact poses at any stream time: a `.def` screw spread over its duration,
 * and keyframed poses.
 *
 * Keyframes: key k says "at time t_k the handle is translated by T_k and
 * rotated by the rotation vector r_k about its rest centroid c", i.e. the
 * pose y = R_k (x - c) + c + T_k. Between keys T and r are interpolated
 * linearly (before the first key from the rest pose at t = 0; after the last
 * the pose holds). The loop's tick twist is the one constant twist that
 * carries the handle from where it is now to the path's pose at the tick's
 * end: ξ = log(P(t+h) G⁻¹) / h. Aiming at the pose, not differentiating it,
 * means round-off, late ticks and sub-steps never accumulate into drift.
 * The screw's pose is exp((t/T) ξ) with ξ = log M, as `deform` has it. */
#include "loop_internal.h"

#include <string.h>

/* Pose of a keyframed handle at time t; c is its rest centroid. */
static void key_pose(const iso_scene_driver *d, const double c[3], double t, iso_pose *P)
{
    const iso_scene_keyframe *k = d->keys;
    int n = d->n_keys;
    double tr[3] = {0, 0, 0}, rv[3] = {0, 0, 0};
    if (t >= k[n - 1].t) {
        memcpy(tr, k[n - 1].translate, sizeof tr);
        memcpy(rv, k[n - 1].rotate, sizeof rv);
    } else {
        static const double rest[3] = {0, 0, 0}; /* before the first key */
        double t0 = 0, a;
        const double *tr0 = rest, *rv0 = rest;
        int i = 0;
        while (i < n && k[i].t <= t) {
            t0 = k[i].t;
            tr0 = k[i].translate;
            rv0 = k[i].rotate;
            i++;
        }
        a = k[i].t > t0 ? (t - t0) / (k[i].t - t0) : 1.0;
        for (int j = 0; j < 3; j++) {
            tr[j] = tr0[j] + a * (k[i].translate[j] - tr0[j]);
            rv[j] = rv0[j] + a * (k[i].rotate[j] - rv0[j]);
        }
    }
    iso_twist w;
    memset(&w, 0, sizeof w);
    for (int j = 0; j < 3; j++)
        w.w[j] = rv[j] * (3.14159265358979323846 / 180.0);
    iso_pose rot;
    iso_twist_exp(&w, 1.0, &rot); /* v = 0: a pure rotation about the origin */
    iso_pose_about(rot.R, c, tr, P);
}

int iso_loop__twist_between(const iso_pose *G, const iso_pose *P, double h, iso_twist *xi,
                            iso_err *err)
{
    int rc = iso_twist_between(G, P, xi, err);
    if (rc != ISO_OK)
        return rc;
    for (int j = 0; j < 3; j++) {
        xi->w[j] /= h;
        xi->v[j] /= h;
    }
    return ISO_OK;
}

/* A velocity jump at T belongs to the tick over [s0, s1) that contains it
 * or starts on it; one at its end belongs to the next tick (which then
 * starts on it). ε absorbs the round-off of the seconds. */
static int jump_within(double T, double s0, double s1)
{
    double eps = 1e-9 * (s1 - s0);
    return T > s0 - eps && T < s1 - eps;
}

int iso_loop__scripted_jump(const iso_scene_driver *d, double s0, double s1)
{
    if (d->kind == ISO_SCENE_DRIVE_SCREW)
        return jump_within(d->duration, s0, s1);
    if (d->kind == ISO_SCENE_DRIVE_KEYFRAMES)
        for (int i = 0; i < d->n_keys; i++)
            if (jump_within(d->keys[i].t, s0, s1))
                return 1;
    return 0;
}

int iso_loop__scripted_pose(const iso_scene_driver *d, const double c[3], double s, iso_pose *P,
                            iso_err *err)
{
    iso_pose_identity(P);
    if (d->kind == ISO_SCENE_DRIVE_SCREW) {
        /* exp(1·ξ) = M, spread evenly over [0, duration]: exp((s/T) ξ) */
        double f = s < d->duration ? s / d->duration : 1.0;
        iso_twist_exp(&d->twist, f, P);
        return ISO_OK;
    }
    if (d->kind == ISO_SCENE_DRIVE_KEYFRAMES) {
        key_pose(d, c, s, P);
        return ISO_OK;
    }
    (void)err;
    return ISO_OK;
}

double iso_loop__scripted_end(const iso_scene_driver *d)
{
    if (d->kind == ISO_SCENE_DRIVE_SCREW)
        return d->duration;
    if (d->kind == ISO_SCENE_DRIVE_KEYFRAMES)
        return d->keys[d->n_keys - 1].t;
    return 0;
}
