/* common/iso_geom.h -- rigid poses and twists: the geometry that the solver
 * (handle paths), the devices (what a 3D mouse commands) and the loop share.
 *
 * Convention: a pose maps rest positions to current ones, y = R x + p. A
 * twist (w, v) is world-frame: the velocity of a point at y is v + w × y.
 * For the screw path g(t) = exp(t ξ) with constant ξ, dg/dt = ξ g, so the
 * world twist is the same constant ξ at every t. Pose products are written
 * here once; every part composes, inverts and takes logarithms through
 * these. */
#ifndef ISO_GEOM_H
#define ISO_GEOM_H

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
/* y = R x: the rotation alone, for directions */
ISO_API void iso_pose_rotate(const iso_pose *g, const double x[3], double y[3]);
/* g = a ∘ b: first b, then a (g may alias neither). */
ISO_API void iso_pose_compose(const iso_pose *a, const iso_pose *b, iso_pose *g);
/* The pose that turns by R about the point c, then moves by t:
 * y = R (x − c) + c + t. t may be NULL (no move). */
ISO_API void iso_pose_about(const double R[9], const double c[3], const double t[3], iso_pose *g);
/* The 4x4 row-major matrix [R p; 0 0 0 1]. */
ISO_API void iso_pose_to_matrix(const iso_pose *g, double M[16]);
/* Velocity at point y: v + w × y. */
ISO_API void iso_twist_velocity(const iso_twist *xi, const double y[3], double vel[3]);

/* Projects M's 3x3 part to the nearest rotation (via its quaternion) and
 * takes the matrix logarithm: the constant twist whose exp(1·ξ) is M. Fails
 * for a rotation of exactly π (the axis sign is ambiguous there: say so). */
ISO_API ISO_NODISCARD int iso_twist_from_matrix(const double M[16], iso_twist *xi, iso_err *err);
/* The constant world twist that carries pose a to pose b in unit time:
 * exp(ξ) ∘ a = b, ξ = log(b ∘ a⁻¹). Fails as iso_twist_from_matrix does,
 * for a half-turn between them. */
ISO_API ISO_NODISCARD int iso_twist_between(const iso_pose *a, const iso_pose *b, iso_twist *xi,
                                            iso_err *err);
/* The unit quaternion (w, x, y, z), w >= 0, of a row-major near-rotation,
 * by Shepperd's choice of the largest diagonal combination; normalising it
 * projects to the nearest rotation. */
ISO_API void iso_rotation_quaternion(const double R[9], double q[4]);
/* g = exp(t ξ), evaluated in closed form (Rodrigues and the screw's V matrix). */
ISO_API void iso_twist_exp(const iso_twist *xi, double t, iso_pose *g);

#endif
