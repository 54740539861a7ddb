/* solver/opts_range.c -- the ranges of the solver's and the integrator's
 * numeric settings (iso_solver_range in iso_solver.h), in one table that
 * scene files and the command line read. */
#include "iso_solver.h"

#include <string.h>

static const struct {
    const char *name;
    iso_range range;
} ranges[] = {
    /* At omega 0 a flat region makes the system singular, and above 1 the
     * distortion term turns negative. */
    {"omega", {ISO_RANGE_GT(0), ISO_RANGE_LE(1)}},
    /* Below ~1e-16 relative the residual cannot fall further in double
     * precision, so CG would only stall and force a refactor each time; at
     * 1 it is no tolerance at all. */
    {"cg_tol", {ISO_RANGE_GT(0), ISO_RANGE_LT(1)}},
    {"cg_max_iter", {ISO_RANGE_GE(1), ISO_RANGE_LE(100000), .integer = 1}},
    {"worker_lag", {ISO_RANGE_GE(0), ISO_RANGE_LE(ISO_SOLVER_WORKER_LAG_MAX), .integer = 1}},
    {"restore_mu", {ISO_RANGE_GE(0)}},
    {"restore_tau", {ISO_RANGE_GT(0)}},
    {"restore_kappa", {ISO_RANGE_GE(0)}},
    /* A share of the step's local error: beyond 1 CG's error would pass the
     * integrator's own. */
    {"cg_share", {ISO_RANGE_GE(0), ISO_RANGE_LE(1)}},
    {"steps_per_tick", {ISO_RANGE_GE(1), ISO_RANGE_LE(1000), .integer = 1}},
};

const iso_range *iso_solver_range(const char *name)
{
    for (size_t i = 0; name && i < sizeof ranges / sizeof ranges[0]; i++)
        if (strcmp(ranges[i].name, name) == 0)
            return &ranges[i].range;
    return NULL;
}
