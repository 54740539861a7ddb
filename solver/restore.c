/* solver/restore.c -- run-time access to the isometry restoration term's
 * time constant (iso_solver.h). The term itself is assembled with the
 * others (assemble_cpu.c edge_matrix, and the OpenCL kernels); only τ may
 * change between evaluations, because it enters the right-hand side alone
 * and leaves the pattern and the element list as they were built. */
#include <math.h>

#include "solver_internal.h"

void iso_solver_get_restore(const iso_solver *s, double *mu, double *tau)
{
    if (mu)
        *mu = s->o.restore_mu;
    if (tau)
        *tau = s->o.restore_tau;
}

int iso_solver_set_restore_tau(iso_solver *s, double tau, iso_err *err)
{
    if (!(tau > 0.0 && isfinite(tau)))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "restoration time constant tau = %g must be > 0 and finite", tau);
    s->o.restore_tau = tau;
    return ISO_OK;
}
