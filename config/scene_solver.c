/* config/scene_solver.c -- the scene's `solver:` and `integrator:`
 * sections. Defaults are the library's (iso_solver_opts_default,
 * iso_integrate_opts_default) except where scene.c's new_scene says; the
 * ranges are the solver's (iso_solver_range), which the command line's
 * options read too. */
#include "internal.h"

#include <string.h>

#include "iso_names.h"
#include "iso_proxy.h"

_Static_assert(sizeof(iso_weighting) == sizeof(int) && sizeof(iso_assembly) == sizeof(int) &&
                   sizeof(iso_refactor) == sizeof(int),
               "SK_ENUM stores an int: the solver's enums must be int-sized");

static const scene_key restore_keys[] = {
    {"mu", SK_NUMBER, FIELD(iso_solver_opts, restore_mu), SK_REQUIRED, SOLVER_RANGE("restore_mu"),
     .help = "the restoration term's weight (0: off)"},
    {"tau", SK_NUMBER, FIELD(iso_solver_opts, restore_tau), SOLVER_RANGE("restore_tau"),
     .help = "its time constant in seconds of stream time", .dflt = "required when mu > 0"},
    {.key = NULL},
};

/* `restore: off` is mu = 0. */
static int restore_off(scene_ctx *c, scene_map *m)
{
    iso_solver_opts *o = m->obj;
    const char *t = iso_scene__scalar(c, m->node);
    if (!t || strcmp(t, "off") != 0)
        return iso_scene__want_map(c, m->node, m->key, "off or {mu, tau}");
    o->restore_mu = 0;
    o->restore_tau = 0;
    return ISO_OK;
}

static int restore_end(scene_ctx *c, scene_map *m)
{
    const iso_solver_opts *o = m->obj;
    if (o->restore_mu > 0 && !iso_scene__get(m->node, "tau"))
        return iso_scene__missing(c, m->node, m->key, "tau", "a time constant > 0 when mu > 0");
    return ISO_OK;
}

static const scene_section restore = {.name = "solver.restore",
                                      .what = "off or {mu, tau}",
                                      .keys = restore_keys,
                                      .scalar = restore_off,
                                      .end = restore_end};

/* `proxy: off | auto | N` (iso_solver_opts.proxy, iso_proxy.h). */
static int store_proxy(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    int *at = (int *)((char *)obj + k->off);
    const char *t = iso_scene__scalar(c, v);
    if (t && (strcmp(t, "off") == 0 || strcmp(t, "auto") == 0)) {
        *at = t[0] == 'o' ? 0 : ISO_SOLVER_PROXY_AUTO;
        return ISO_OK;
    }
    double n; /* an integer of the row's range, refused in its words */
    int rc = iso_scene__number(c, k, v, key, &n);
    if (rc == ISO_OK)
        *at = (int)n;
    return rc;
}

static const scene_key solver_keys[] = {
    {"omega", SK_NUMBER, FIELD(iso_solver_opts, omega), SOLVER_RANGE("omega"),
     .help = "the distortion term's weight against the isometry term", .dflt = "1/3"},
    {"weighting", SK_ENUM, FIELD(iso_solver_opts, weighting), .names = iso_weighting_names,
     .help = "the element integral: over the parameter triangle or the surface", .dflt = "param"},
    {"restore", SK_SECTION, 0, 0, .sub = &restore, .type = "off or mapping",
     .help = "isometry restoration: edge lengths pulled back with time constant tau",
     .dflt = "off"},
    {"assembly", SK_ENUM, FIELD(iso_solver_opts, assembly), .names = iso_assembly_names,
     .help = "who assembles the system: cpu, opencl, or auto (OpenCL on a GPU, else cpu); "
             "without a usable device cpu runs, with a notice",
     .dflt = "auto"},
    {"refactor", SK_ENUM, FIELD(iso_solver_opts, refactor), .names = iso_refactor_names,
     .help = "always factor, or reuse the factor as PCG's preconditioner", .dflt = "adaptive"},
    {"cg_tol", SK_NUMBER, FIELD(iso_solver_opts, cg_tol), SOLVER_RANGE("cg_tol"),
     .help = "PCG's relative residual (a floor beside integrator.cg_share's target)",
     .dflt = "1e-10"},
    {"cg_max_iter", SK_INT, FIELD(iso_solver_opts, cg_max_iter), SOLVER_RANGE("cg_max_iter"),
     .help = "PCG iterations a tick may spend before it refactors and solves directly",
     .dflt = "12"},
    {"preconditioner", SK_ENUM, FIELD(iso_solver_opts, preconditioner), .names = iso_precond_names,
     .help = "adaptive: PCG's preconditioner, the factor turned by each ring's rotation since "
             "its matrix (rotated) or as it is (plain)",
     .dflt = "rotated"},
    {"worker_lag", SK_INT, FIELD(iso_solver_opts, worker_lag), SOLVER_RANGE("worker_lag"),
     .help = "adaptive: 0 factors on the tick's thread; N factors on a worker thread, each factor "
             "used from N evaluations after its matrix's",
     .dflt = "4"},
    {"proxy", SK_INT, FIELD(iso_solver_opts, proxy), IN(ISO_PROXY_MIN_BUDGET, 100000000),
     .store = store_proxy, .type = "off, auto or integer",
     .help = "the reduced model: the method on a proxy of at most this many vertices, the mesh "
             "following it; auto: none where the method fits the tick, else the proxy that does",
     .dflt = "auto"},
    {"proxy_smoothness", SK_ENUM, FIELD(iso_solver_opts, proxy_smoothness),
     .names = iso_proxy_smoothness_names,
     .help = "with a proxy: the mesh's omega, or matched: the omega that lets the proxy bend as "
             "the mesh would (nearer the whole mesh's result without restoration, more "
             "refactoring)",
     .dflt = "mesh"},
    {"worker_ahead", SK_BOOL, FIELD(iso_solver_opts, worker_ahead),
     .help = "with the worker: factor the matrix at the positions extrapolated to the middle of "
             "the factor's use, instead of the giving evaluation's",
     .dflt = "true"},
    {.key = NULL},
};

/* The factorization worker is a default of the adaptive scheme only: a
 * scene that asks for `refactor: always` without naming worker_lag gets
 * none, rather than a refusal of a default it did not write. */
static int solver_end(scene_ctx *c, scene_map *m)
{
    (void)c;
    iso_solver_opts *o = m->obj;
    if (o->refactor != ISO_REFACTOR_ADAPTIVE && !iso_scene__get(m->node, "worker_lag"))
        o->worker_lag = 0;
    return ISO_OK;
}

const scene_section iso_scene__solver = {.name = "solver",
                                         .what = "a mapping of solver settings",
                                         .keys = solver_keys,
                                         .end = solver_end};

static const scene_key integrator_keys[] = {
    {"steps_per_tick", SK_INT, FIELD(iso_scene, steps_per_tick), SOLVER_RANGE("steps_per_tick"),
     .help = "ABM steps per tick", .dflt = "1"},
    {"restore_kappa", SK_NUMBER, FIELD(iso_scene, integrate.restore_kappa),
     SOLVER_RANGE("restore_kappa"), .help = "restoration's clamp: tau_eff = max(tau, kappa h)",
     .dflt = "1.0 under pece, 6.0 under pec"},
    {"abm", SK_ENUM, FIELD(iso_scene, abm_mode), .names = iso_abm_mode_names,
     .help = "the ABM3 form: two field evaluations a step (pece) or one (pec)", .dflt = "pece"},
    {"cg_share", SK_NUMBER, FIELD(iso_scene, integrate.cg_share), SOLVER_RANGE("cg_share"),
     .help = "PCG's share of a step's local error estimate (0: solver.cg_tol always)",
     .dflt = "0.1"},
    {.key = NULL},
};

const scene_section iso_scene__integrator = {
    .name = "integrator", .what = "a mapping of integrator settings", .keys = integrator_keys};
