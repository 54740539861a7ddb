/* solver/iso_integrate.h -- integrating the free vertices along the field.
 *
 * dx/dt = v̂(x, t) for free vertices; handle vertices are placed from their
 * exact pose at every stage (never integrated, so they cannot drift); fixed
 * vertices never move. Third-order Adams–Bashforth–Moulton in PECE form
 * (two field evaluations per step), with variable-step coefficients, started
 * with RK4 (the paper's) or with low-order Adams steps (the real-time
 * stepper's, below). Adaptive mode controls the step with Milne's estimate
 * |x_c − x_p| / 10 (max over free vertices) against tol × bbox diagonal.
 *
 * The solve's accuracy follows the integrator. With the solver's adaptive
 * refactoring, each evaluation is a PCG solve, and an error δ in one
 * evaluation's field moves the path by h δ in all (the Adams weights that
 * multiply one f over the steps that use it sum to h). So CG stops when
 * h δ is cg_share (a tenth) of the step's local error: δ ≤ cg_share × est / h,
 * est the Milne estimate of the last third-order step scaled by (h / its
 * step)⁴, δ measured as the solver's preconditioned residual at its largest
 * vertex (iso_solver_set_cg_target). Steps without such an estimate yet (the
 * start, RK4 or low order) take, in adaptive mode, the error every step is
 * allowed instead: δ ≤ cg_share × tol × diagonal / h (the RK4 start is
 * accepted unchecked, within tol by its choice of h). On the cactus at tol
 * 1e-4 that cut the run's CG iterations from 93 to 57 (and a factorization)
 * and moved the result by 6e-6 of the diagonal from 1e-12 solves, 2% of the
 * integrator's own error of 2.8e-4 against 1000 steps (test_integrator
 * checks the same on a plate). Fixed steps and the real-time stepper
 * promise no tolerance, so their starts use the solver's cg_tol alone: on
 * the cactus scene at 60 Hz, whose integrator error is 3e-7 of the
 * diagonal, a 1e-4 allowance at the start made CG 13% of that error. With
 * an estimate, cg_tol's residual still ends CG if it comes first, a floor
 * for steps whose error is far below anything that matters (a slow handle:
 * on the soak scene a tenth of it asked CG for 1e-13 of the diagonal and
 * failed to the fallback, 57 factorizations in 1800 ticks instead of 9). Offline and in real time
 * alike; with refactor = always every solve is direct and this changes
 * nothing. */
#ifndef ISO_INTEGRATE_H
#define ISO_INTEGRATE_H

#include "iso_motion.h"
#include "iso_solver.h"

typedef struct iso_integrate_opts {
    double t0, t1; /* default 0, 1 */
    int steps;     /* > 0: fixed step (t1 − t0)/steps; 0: adaptive */
    double tol;    /* adaptive: local error per step relative to the bbox
                      diagonal; default ISO_INTEGRATE_DEFAULT_TOL */
    /* Isometry restoration (iso_solver_opts.restore_mu > 0): each step uses
     * τ_eff = max(τ, κ h). The term relaxes edge lengths at a rate up to
     * 1/τ, an eigenvalue −1/τ that the explicit steps must resolve: ABM3
     * PECE is stable on the negative real axis for h/τ < 1.73 (RK4 2.78),
     * so κ ≥ 0.58 keeps every step stable however large μ is. Default
     * ISO_INTEGRATE_RESTORE_KAPPA; 0 = τ as given (may blow up). */
    double restore_kappa;
    /* Called after every accepted step, t in [t0, t1]; may be NULL. During
     * the call the caller's x (iso_integrate's argument) holds the
     * positions at t, so a callback may sample them (test_long_session). */
    void (*progress)(void *ctx, double t, int steps, long evaluations);
    void *progress_ctx;
    int start;       /* ISO_INTEGRATE_START_RK4 (default, the paper's) or _ADAMS */
    double cg_share; /* CG's share of a step's local error, default
                        ISO_INTEGRATE_CG_SHARE; 0 = the solver's cg_tol always */
} iso_integrate_opts;

#define ISO_INTEGRATE_DEFAULT_TOL 1e-4
#define ISO_INTEGRATE_RESTORE_KAPPA 1.0
#define ISO_INTEGRATE_CG_SHARE 0.1

/* How the Adams history is started.
 *   RK4:   two RK4 steps (4 evaluations each, the first after f(t0)), then
 *          ABM3 PECE: the paper's method.
 *   ADAMS: the real-time stepper's start (iso_stepper_step), for comparing
 *          the two: Adams steps of order 1, 2, then 3. */
enum { ISO_INTEGRATE_START_RK4 = 0, ISO_INTEGRATE_START_ADAMS = 1 };
/* Their names, indexed by value (iso_names.h): "rk4", "adams". */
ISO_API extern const char *const iso_integrate_start_names[];

ISO_API void iso_integrate_opts_default(iso_integrate_opts *o);

typedef struct iso_integrate_stats {
    int steps; /* accepted steps, RK4 start included */
    int rk4_steps;
    int rejected;                /* adaptive steps redone with a smaller step */
    long evaluations;            /* field evaluations */
    double max_err_estimate;     /* largest accepted Milne estimate (third-order steps), relative */
    int low_order_steps;         /* Adams steps of order 1 or 2 (an Adams start or restart) */
    int adams_order;             /* the last step's predictor order k (0 after RK4) */
    int max_step_evaluations;    /* real time: the most field evaluations one step made */
    long max_step_cg_iterations; /* real time: the most PCG iterations one step made */
    long pec_misses;             /* real time, PEC: steps whose predictor missed by more than
                                    the stepper's pec_tol, ended with PECE's evaluation */
} iso_integrate_stats;

/* Integrates from t0 to t1. x (3*nv) holds the rest positions on entry (the
 * mesh's, or any pose consistent with the path at t0) and the result on exit.
 * Handle h's vertices are placed at pose(t) applied to the mesh's rest
 * positions. */
ISO_API ISO_NODISCARD int iso_integrate(iso_solver *s, const iso_mesh *m, const iso_regions *r,
                                        const iso_path *path, const iso_integrate_opts *opts,
                                        double *x, iso_integrate_stats *st, iso_err *err);

/* ===== real time: one step per tick =====================================
 *
 * The controller advances the mesh by one step per tick, with each handle
 * moving at a constant world twist over the tick (the latest device input).
 * The stepper keeps the Adams history between ticks; the caller asks for a
 * restart after a discontinuity such as the clutch (the field jumps with
 * the twist, so the history before it is of another field). The poses
 * accumulate: pose(t_n + τ) = exp(τ ξ) ∘ pose(t_n). Deterministic: the same
 * twists and step lengths give bit-identical positions.
 *
 * No step costs more than two field evaluations, a restart included. A
 * restart does not take RK4 steps (four evaluations each, five in the
 * restart's tick): it evaluates f at the step's start with the new twists
 * and rebuilds the Adams history at low order over the next steps. The
 * predictor's order k and the corrector's, step by step after a restart:
 *   step 1: k = 1, Euler predictor, trapezoidal corrector (Heun, local
 *           error O(h³)); f(x_n), then f(x_p): two evaluations. It ends PEC
 *           in either mode (f(x_p) joins the history), which keeps it at
 *           two; that f is off by O(h²) and costs a further O(h³) in the two
 *           steps that use it.
 *   step 2: k = 2, AB2 predictor, AM3 corrector (local error O(h⁴) from
 *           the corrector, O(h³) from step 1's f); one evaluation (PEC) or
 *           two (PECE).
 *   step 3 on: k = 3, ABM3 as configured: one (PEC) or two (PECE).
 * A restart thus leaves a fixed number of O(h³) local errors, and the path
 * stays third order at a fixed number of restarts (test_stepper measures
 * it). Milne's estimate speaks for the corrector only when both are of the
 * same order, so only k = 3 steps report one (max_err_estimate) and set
 * CG's target; the low-order steps keep the last one (or cg_tol at first).
 *
 * PCG is capped per step (per tick, at one step a tick): each step opens
 * one solver budget of cg_max_iter iterations for its evaluations together
 * (iso_solver_budget_begin). The fallback when it is spent, or when the rate
 * shows it will be: a fresh factorization and a direct solve, whose factor
 * then serves the step's other evaluation with a fresh budget. */
typedef struct iso_stepper iso_stepper; /* opaque */

/* x (3*nv, caller-owned, must outlive the stepper) holds the current
 * positions and is advanced in place; handles start at the identity pose
 * (x's handle vertices are placed from the mesh's rest positions).
 * s, m and r must outlive the stepper. */
ISO_API ISO_NODISCARD int iso_stepper_create(iso_solver *s, const iso_mesh *m, const iso_regions *r,
                                             double *x, iso_stepper **out, iso_err *err);
ISO_API void iso_stepper_destroy(iso_stepper *st); /* NULL is a no-op */

/* How an ABM3 step of the stepper ends.
 *   PECE (the default, the paper's): predict, evaluate, correct, evaluate
 *        the field again at the corrected positions for the history. Two
 *        field evaluations a step.
 *   PEC: the history keeps the field at the predicted positions; one
 *        evaluation a step, so a tick costs half. Still third order (the
 *        predictor is of the corrector's order), but its stability interval
 *        on the negative real axis is h|λ| < 0.287 against PECE's 1.73 (the
 *        recurrences on y' = λy, iterated for growth in steps of 0.001), so
 *        restoration's τ_eff = max(τ, κ h) needs κ ≥ 3.5 if the term's
 *        fastest rate were 1/τ. It is faster on a real mesh: the bar scene
 *        at 60 Hz (μ 1, τ 0.05) ends at metricErr 9.70 / areaErr 2.99 at
 *        κ 4, worse than without restoration (18.8 / 1.35 in area), and at
 *        2.48 / 0.63 at κ 6, 2.54 / 0.64 at κ 8 (PECE at κ 1: 2.35 /
 *        0.61). So ISO_INTEGRATE_RESTORE_KAPPA_PEC is 6. test_stepper shows
 *        a stiff term bounded at it and blowing up at κ 1 under pure PEC.
 *        A PEC step whose predictor missed ends as PECE does (below).
 *
 * PEC's predictor miss. f(x_p) stands in the history for f(x_c); it is off
 * by the field's change over |x_c − x_p|, and every later step builds on
 * it, which is what shrinks PEC's stability interval. Along a smooth
 * motion the miss is tiny (a recorded 3D-mouse session at 60 Hz: Milne's
 * estimate |x_c − x_p| / 10 at most 3.1e-5 of the diagonal), but where the
 * field jumps it is not: a page dragging a handle at 0.5-2 diagonals a
 * second sends targets every 25 ms, so the handle's twist jumps between
 * ticks, and the estimate was 3e-3 to 1.7e-2 of the diagonal at every step.
 * Under restoration the fed-back f then grew (the field's largest speed 4.6
 * diagonals a second against PECE's 1.5 on the same drag, on time), and a
 * late tick's long steps took that mesh to 916% edge strain where PECE
 * ends at 94%. So a PEC step whose estimate exceeds ISO_STEPPER_PEC_TOL of
 * the diagonal (the offline tolerance of a step, ISO_INTEGRATE_DEFAULT_TOL)
 * evaluates the field again at x_c for the history, as PECE does: at most
 * two evaluations, and the paper's PECE path wherever PEC cannot hold it
 * (the pec_misses count). Only a restart's own step, which has made its
 * two, ends PEC whatever its miss. A smooth session never reaches the
 * tolerance, so its steps and bits are PEC's. */
typedef enum iso_abm_mode { ISO_ABM_PECE = 0, ISO_ABM_PEC = 1 } iso_abm_mode;

#define ISO_INTEGRATE_RESTORE_KAPPA_PEC 6.0
#define ISO_STEPPER_PEC_TOL ISO_INTEGRATE_DEFAULT_TOL

/* "pece" or "pec", as scenes, the command line and the JSON summary write
 * it; "?" for anything else. The table: iso_abm_mode_names (iso_names.h). */
ISO_API extern const char *const iso_abm_mode_names[];
ISO_API const char *iso_abm_mode_name(iso_abm_mode mode);

/* Sets the mode and restoration's κ for the steps that follow; κ < 0 takes
 * the mode's default (ISO_INTEGRATE_RESTORE_KAPPA, _PEC), 0 uses τ as given.
 * The history stays valid across a change. ISO_EINVAL for an unknown mode. */
ISO_API ISO_NODISCARD int iso_stepper_configure(iso_stepper *st, iso_abm_mode mode,
                                                double restore_kappa, iso_err *err);

/* CG's share of a step's local error (iso_integrate.h), default
 * ISO_INTEGRATE_CG_SHARE; 0 = the solver's cg_tol always. ISO_EINVAL for a
 * negative or non-finite share. */
ISO_API ISO_NODISCARD int iso_stepper_set_cg_share(iso_stepper *st, double share, iso_err *err);

/* PEC's predictor miss above which a step ends with PECE's evaluation
 * (above), relative to the mesh's bounding-box diagonal; default
 * ISO_STEPPER_PEC_TOL, 0 = never (pure PEC, for comparison). ISO_EINVAL for
 * a negative or non-finite value. */
ISO_API ISO_NODISCARD int iso_stepper_set_pec_tol(iso_stepper *st, double tol, iso_err *err);

/* The longest step, over the history's last interval, that keeps the
 * history: a longer one restarts it (as restart != 0 does), since the
 * Adams interpolant would be extrapolated far past its nodes. */
#define ISO_STEPPER_MAX_STEP_RATIO 4.0

/* Advances by h > 0 with twists[k] (one per handle) held over the step.
 * restart != 0 drops the multistep history first; so does a step longer
 * than ISO_STEPPER_MAX_STEP_RATIO times the last one. The step's order and
 * evaluations follow the sequence above: at most two evaluations a step.
 * On error x is left at the last completed step, and the next step restarts
 * the history. */
ISO_API ISO_NODISCARD int iso_stepper_step(iso_stepper *st, double h, const iso_twist *twists,
                                           int restart, iso_err *err);

/* Current time (sum of steps), handle k's pose, and counters. */
ISO_API double iso_stepper_time(const iso_stepper *st);
ISO_API const iso_pose *iso_stepper_pose(const iso_stepper *st, int handle);
ISO_API void iso_stepper_stats(const iso_stepper *st, iso_integrate_stats *out);

#endif
