/* solver/iso_motion.h -- the handle-path interface the integrator asks for
 * handle motion, and the screw path exp(t log M). Poses and twists, and
 * their conventions, are common/iso_geom.h's. */
#ifndef ISO_MOTION_H
#define ISO_MOTION_H

#include "iso_geom.h"

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
