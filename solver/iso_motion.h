/* solver/iso_motion.h -- rigid poses, twists, the screw path exp(t log M),
 * and the handle-path interface the integrator asks for handle motion.
 *
 * Convention: a pose maps rest positions to current ones, y = R x + p. A
 * twist (w, v) is world-frame: the velocity of a point at y is v + w × y.
 * For the screw path g(t) = exp(t ξ) with constant ξ, dg/dt = ξ g, so the
 * world twist is the same constant ξ at every t. */
#ifndef ISO_MOTION_H
#define ISO_MOTION_H

#include "iso_err.h"

typedef struct iso_pose {
    double R[9]; /* row-major rotation */
    double p[3];
} iso_pose;

typedef struct iso_twist {
    double w[3]; /* angular velocity */
    double v[3]; /* velocity of the point at the world origin */
} iso_twist;

ISO_API void iso_pose_identity(iso_pose *g);
/* y = R x + p */
ISO_API void iso_pose_apply(const iso_pose *g, const double x[3], double y[3]);
/* g = a ∘ b: first b, then a (g may alias neither). */
ISO_API void iso_pose_compose(const iso_pose *a, const iso_pose *b, iso_pose *g);
/* Velocity at point y: v + w × y. */
ISO_API void iso_twist_velocity(const iso_twist *xi, const double y[3], double vel[3]);

/* Projects M's 3x3 part to the nearest rotation (via its quaternion) and
 * takes the matrix logarithm: the constant twist whose exp(1·ξ) is M. Fails
 * for a rotation of exactly π (the axis sign is ambiguous there: say so). */
ISO_API ISO_NODISCARD int iso_twist_from_matrix(const double M[16], iso_twist *xi, iso_err *err);
/* g = exp(t ξ), evaluated in closed form (Rodrigues and the screw's V matrix). */
ISO_API void iso_twist_exp(const iso_twist *xi, double t, iso_pose *g);

/* What drives the handles: for handle h at time t, its pose (relative to the
 * rest pose) and its world twist. Returning non-zero aborts integration with
 * that status. */
typedef struct iso_path {
    int (*eval)(void *ctx, int handle, double t, iso_pose *pose, iso_twist *twist);
    void *ctx;
} iso_path;

/* A path for every handle: the screw exp(t ξ) of one twist per handle.
 * `twists` must outlive the path. */
typedef struct iso_screw_path {
    const iso_twist *twists;
    int n;
} iso_screw_path;
ISO_API iso_path iso_screw_path_make(iso_screw_path *sp);

#endif
