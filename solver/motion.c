/* solver/motion.c -- the screw path (iso_motion.h); the poses and twists
 * it moves along are common/iso_geom.c's. */
#include "iso_motion.h"

static int screw_eval(void *ctx, int handle, double t, iso_pose *pose, iso_twist *twist)
{
    const iso_screw_path *sp = ctx;
    if (handle < 0 || handle >= sp->n)
        return ISO_EINVAL;
    *twist = sp->twists[handle];
    iso_twist_exp(twist, t, pose);
    return ISO_OK;
}

iso_path iso_screw_path_make(iso_screw_path *sp)
{
    iso_path p = {screw_eval, sp};
    return p;
}
