/* solver/iso_solver.h -- one field evaluation of the method: given the
 * current positions and the velocities of the constrained vertices, the
 * free vertices' velocities that minimise d(v) = vᵀ A(x) v.
 *
 * One iso_solver owns a CHOLMOD Common, the free-free pattern (built once
 * from connectivity and regions, analysed once), the numeric factor and the
 * solve workspace. Per evaluation it refills values, factorizes and solves.
 * Not thread-safe: one solver per thread. Solvers in different threads are
 * independent and give bit for bit what they give one at a time, as long as
 * none is asked to set the BLAS's process-wide thread count
 * (iso_solver_threads; tests/test_solver_threads.c).
 *
 * Creation refuses ill-posed problems before any solve: ω outside (0, 1], a
 * connected part of the mesh with free vertices but no fixed or handle
 * vertex, or one whose constrained vertices are too few (all on one line)
 * to pin its rigid motions. */
#ifndef ISO_SOLVER_H
#define ISO_SOLVER_H

#include "iso_element.h"
#include "iso_err.h"
#include "iso_mesh.h"
#include "iso_range.h"
#include "iso_regions.h"

typedef struct iso_solver iso_solver; /* opaque */

/* Which code fills the system each evaluation. Both give the same values to
 * rounding (1e-12 relative), and each is bit-identical from run to run. */
typedef enum iso_assembly {
    ISO_ASSEMBLY_CPU = 0, /* the C path (library default) */
    ISO_ASSEMBLY_OPENCL,  /* OpenCL kernels; falls back to CPU with a notice
                             when no platform or device is usable */
    /* OpenCL on the first GPU or accelerator with double precision (or on
     * cl_device when one is named), else the C path with a notice: on a
     * CPU the C path is the faster (cactus: 1.6 ms an evaluation on one
     * core, PoCL 2.7-3.2 ms on two), and PoCL's threads would share the
     * cores with the factorization worker (worker_lag). */
    ISO_ASSEMBLY_AUTO,
} iso_assembly;

/* When to compute a fresh numeric factor. */
typedef enum iso_refactor {
    ISO_REFACTOR_ADAPTIVE = 0, /* reuse the cached factor as a preconditioner for
                                  conjugate gradients from the last solution;
                                  refactor when CG needs more than cg_max_iter
                                  iterations or stalls */
    ISO_REFACTOR_ALWAYS,       /* factor every evaluation: the paper's scheme */
} iso_refactor;

/* What preconditions PCG under the adaptive scheme. The cached factor's
 * matrix was assembled a few evaluations back; along a bending motion the
 * rings have turned since, and A is equivariant under rotation (A(Rx) =
 * Q A(x) Qᵀ, Q = diag(R, ..., R)). So the rotated preconditioner turns the
 * factor by each free vertex's rotation R_i since (fitted to its ring's
 * edges and normal): M⁻¹ = Q L⁻ᵀL⁻¹Qᵀ, Q = diag(R_i). It is exact under a
 * rigid rotation of the whole mesh, symmetric positive definite always,
 * and changes the result only within CG's tolerance. Cactus scene, worker
 * lag 3: 2.8 PCG iterations per evaluation against 4.9, for ~0.6 ms per
 * evaluation of rotations (solver/rotate.c). */
typedef enum iso_precond {
    ISO_PRECOND_ROTATED = 0, /* the factor turned by the rings' rotations (default) */
    ISO_PRECOND_PLAIN,       /* the factor as it is */
} iso_precond;

/* The smoothness weight of the method on a proxy (iso_proxy_omega): the
 * mesh's ω as it is, or matched to the mesh's resolution, so that the proxy
 * bends as freely as the mesh would (nearer the whole mesh's integral
 * without restoration, at the price of more refactoring; docs/method.md). */
typedef enum iso_proxy_smoothness {
    ISO_PROXY_SMOOTHNESS_MESH = 0, /* the mesh's ω (default) */
    ISO_PROXY_SMOOTHNESS_MATCHED,  /* iso_proxy_omega's */
} iso_proxy_smoothness;

/* The enums' names, indexed by value (common/iso_names.h): "cpu",
 * "opencl", "auto"; "adaptive", "always"; "rotated", "plain"; "mesh",
 * "matched". Scenes, options and output use these. */
ISO_API extern const char *const iso_assembly_names[];
ISO_API extern const char *const iso_refactor_names[];
ISO_API extern const char *const iso_precond_names[];
ISO_API extern const char *const iso_proxy_smoothness_names[];

/* Threads. Debian's CHOLMOD asks OpenMP for a team of 4 in its supernodal
 * loops and calls OpenBLAS, which keeps a pool of its own. On systems the
 * size of the benchmark's (under ISO_SOLVER_BLAS_THREADED_FLOPS a
 * factorization) neither pays: on two cores the cactus factorization takes
 * twice as long with them, and the spinning pool steals the core the
 * OpenCL assembly wants (solver/linsolve.c has the figures). The library
 * never changes a process-wide setting unless asked to here, and reads no
 * environment variable for it: a program that wants OMP_MAX_ACTIVE_LEVELS
 * or OPENBLAS_NUM_THREADS to win passes the LEAVE policies (the isoshape
 * command does when they are set). Solvers may be created in several
 * threads at once: the library runs one CHOLMOD analysis at a time, since
 * METIS's random numbers belong to the whole process, so each solver gets
 * the ordering, and the bits, it would get alone. */
typedef enum iso_solver_omp {
    /* Each CHOLMOD call runs its OpenMP regions on the calling thread: the
     * solver sets the calling thread's max-active-levels to 0 for the call
     * and restores it after. That setting belongs to the calling thread
     * alone (an OpenMP 5 data-environment ICV; libgomp 12 keeps it per
     * thread), so no other thread, and none of the caller's own OpenMP
     * code, ever sees it. The library default. */
    ISO_SOLVER_OMP_CALLER = 0,
    ISO_SOLVER_OMP_LEAVE, /* leave OpenMP as the process has it */
} iso_solver_omp;

typedef enum iso_solver_blas {
    ISO_SOLVER_BLAS_LEAVE = 0, /* never touch the BLAS's thread count (library default) */
    /* Process-wide, for the solver's lifetime: when one factorization costs
     * less than ISO_SOLVER_BLAS_THREADED_FLOPS, or the solver has a
     * factorization worker (worker_lag; it takes the other core, and a
     * threaded BLAS in it competes with the evaluating thread: the
     * bumpplane ran 1.6 ticks/s so, 4.2 on one thread), iso_solver_create
     * sets OpenBLAS to one thread and iso_solver_destroy restores the count
     * it found; otherwise it leaves the count alone. OpenBLAS has one count
     * for the whole process, so this is for a program that runs one solver
     * at a time (the isoshape command), never for solvers in several
     * threads or with overlapping lifetimes: those leave the BLAS alone and
     * the program sets the count once (OPENBLAS_NUM_THREADS). A fixed count
     * also keeps results bit-identical across machines: OpenBLAS's threaded
     * and single-threaded kernels round differently. */
    ISO_SOLVER_BLAS_SIZED,
} iso_solver_blas;

/* Below this many flops per factorization a second BLAS thread gained
 * nothing measurable (cactus: 0.47 GFLOP, 33 ms on one thread or two). */
#define ISO_SOLVER_BLAS_THREADED_FLOPS 4e9

/* The C assembly's two halves (solver/assemble_cpu.c): on the evaluating
 * thread and a helper of the solver's own, with one thread's bits either
 * way, but each split changes a mesh's bits against the unsplit sum. */
typedef enum iso_solver_split {
    /* From ISO_SOLVER_CPU_SPLIT_EDGES interior edges on (about 20k
     * vertices); smaller meshes keep one thread, where a helper would
     * contend with the factorization worker for the second core. The
     * library default. */
    ISO_SOLVER_SPLIT_LARGE = 0,
    /* At any size: for a small mesh stepped inside a larger tick (the
     * reduced model's proxy, whose full mesh's reconstruction already runs
     * on two threads), where the assembly is a third of the tick. */
    ISO_SOLVER_SPLIT_ALWAYS,
} iso_solver_split;

#define ISO_SOLVER_CPU_SPLIT_EDGES 60000

typedef struct iso_solver_threads {
    iso_solver_omp omp;     /* default ISO_SOLVER_OMP_CALLER */
    iso_solver_blas blas;   /* default ISO_SOLVER_BLAS_LEAVE */
    iso_solver_split split; /* default ISO_SOLVER_SPLIT_LARGE */
} iso_solver_threads;

typedef struct iso_solver_opts {
    double omega;               /* in (0, 1]; default 1/3 */
    iso_weighting weighting;    /* default ISO_WEIGHT_PARAM */
    iso_assembly assembly;      /* default ISO_ASSEMBLY_CPU */
    const char *cl_device;      /* OpenCL device: NULL = the first CPU device
                                   (PoCL; under auto, the first GPU or
                                   accelerator), else "P:D" platform/device
                                   indices or a substring of the device or
                                   platform name */
    iso_refactor refactor;      /* default ISO_REFACTOR_ALWAYS in the library */
    double cg_tol;              /* adaptive: relative residual, default 1e-10; with a target
                                   (iso_solver_set_cg_target) whichever is met first ends CG */
    int cg_max_iter;            /* adaptive: PCG iterations a solve may spend, or a tick
                                   (iso_solver_budget_begin); beyond them it refactors and
                                   solves directly; default 12 */
    iso_precond preconditioner; /* adaptive: default ISO_PRECOND_ROTATED */
    /* Isometry restoration (beyond the paper; 0 = off, the paper's method
     * exactly). Adds, per edge e = (i, j) with rest length L_e, current
     * length |e| and unit direction u_e, the term
     *     μ w_e (u_e · (v_j − v_i) + (|e| − L_e) / τ)²
     * which asks each edge's length rate to pull its length back to L_e with
     * time constant τ. w_e = 1 under param weighting; under area weighting
     * w_e = twice the mean rest area of e's triangles, the same factor that
     * turns param into area weighting for triangles, so μ means the same
     * under both. Since d_T and the edge term both scale with (strain rate ×
     * edge length)², μ is independent of the mesh's size and resolution. */
    double restore_mu;          /* ≥ 0 */
    double restore_tau;         /* > 0 when restore_mu > 0; in the path's time units */
    iso_solver_threads threads; /* what the solver may do to thread settings */
    /* Adaptive only: 0 (default), each factorization runs on the evaluating
     * thread when PCG asks for one; N in [1, ISO_SOLVER_WORKER_LAG_MAX], a
     * worker thread of the solver's own factors the matrices in the
     * background and each factor is handed over N evaluations after the
     * evaluation whose matrix it is (that evaluation waits if the worker is
     * late). Which factor serves which evaluation depends on evaluation
     * counts only, so results are bit-identical from run to run whatever
     * the timing. The worker takes one core while it factors; it runs
     * under the default scheduling policy (iso_solver_set_worker_priority
     * changes it) and with all signals blocked (solver/worker.c says why). Give the BLAS one thread
     * (ISO_SOLVER_BLAS_SIZED, or OPENBLAS_NUM_THREADS=1): a threaded BLAS
     * spreads the worker's factorization over the evaluating thread's
     * core too (the cactus's median tick went from 16 to 28 ms). */
    int worker_lag;
    /* With the worker: 1 (default), the matrix it factors is assembled
     * ahead, at the positions extrapolated (quadratically, through the
     * last three evaluations' positions) to 1.5 worker_lag − 0.5
     * evaluations after the one that gives the job: the middle of the
     * evaluations the factor will serve (ages worker_lag to
     * 2 worker_lag − 1). So the factor is of nearly the matrix it
     * preconditions instead of one worker_lag to 2 worker_lag − 1
     * evaluations old, for one more assembly per job. It assumes
     * evaluations evenly spaced along the path, as the real-time loop's
     * are; elsewhere (or after a jump) the factor is merely a poorer
     * preconditioner. Cactus scene at lag 4: 8.4 ms median tick against
     * 10.7, bar 11.4 against 21.2 (solver/linsolve.c). 0: the matrix of the
     * evaluation that gives the job. */
    int worker_ahead;
    /* The reduced model (iso_proxy.h), for the program that builds the
     * solver: 0 (default) the method on the whole mesh; N ≥
     * ISO_PROXY_MIN_BUDGET (200) the method on a proxy of at most N
     * vertices that the whole mesh follows; ISO_SOLVER_PROXY_AUTO the
     * budget iso_proxy_auto_budget chooses for the mesh's size and the
     * tick rate (none where the method fits the tick). The solver steps the
     * mesh it is given and reads no further than the range check. */
    int proxy;
    /* With a proxy: the ω it is stepped with (iso_proxy_smoothness). */
    iso_proxy_smoothness proxy_smoothness;
} iso_solver_opts;

#define ISO_SOLVER_PROXY_AUTO (-1)

#define ISO_SOLVER_WORKER_LAG_MAX 100

ISO_API void iso_solver_opts_default(iso_solver_opts *o);

/* The range of each numeric solver and integrator setting, in one table
 * that scene files and the command line both check against
 * (iso_range_parse), so that a value one refuses the other refuses too, in
 * the same words. Named by the setting's field: "omega" (0, 1], "cg_tol"
 * (0, 1), "cg_max_iter" [1, 100000], "worker_lag" [0,
 * ISO_SOLVER_WORKER_LAG_MAX], "restore_mu" >= 0, "restore_tau" > 0 (of
 * iso_solver_opts); "restore_kappa" >= 0, "cg_share" [0, 1] (of
 * iso_integrate_opts); "steps_per_tick" [1, 1000] (ABM steps a tick of the
 * real-time loop). NULL for a name the table lacks. */
ISO_API const iso_range *iso_solver_range(const char *name);

/* The solver keeps pointers to mesh and regions: both must outlive it. */
ISO_API ISO_NODISCARD int iso_solver_create(const iso_mesh *m, const iso_regions *r,
                                            const iso_solver_opts *opts, /* NULL = defaults */
                                            iso_solver **out, iso_err *err);
ISO_API void iso_solver_destroy(iso_solver *s); /* NULL is a no-op */

/* What iso_solver_create refuses before it builds anything: the options,
 * the regions against the mesh, and the constraints (every free part
 * reaches a fixed or handle vertex). The same messages, without the
 * system's symbolic factorization, which at a million vertices is seconds
 * and gigabytes that a scene's check (`isoshape check`) does not need. */
ISO_API ISO_NODISCARD int iso_solver_check(const iso_mesh *m, const iso_regions *r,
                                           const iso_solver_opts *opts, /* NULL = defaults */
                                           iso_err *err);

/* One field evaluation.
 * input:  x  (3*nv) current positions of all vertices;
 *         vc (3*nv) velocities; only the entries of handle vertices are read
 *            (fixed vertices are zero, free ones are unknown).
 * output: v  (3*nv) the minimising field: free entries solved, handle
 *            entries copied from vc, fixed and unreferenced set to zero.
 * A system that is not positive definite is ISO_ENUMERIC naming the row and
 * its vertex, never a silent wrong answer. */
ISO_API ISO_NODISCARD int iso_solver_field(iso_solver *s, const double *x, const double *vc,
                                           double *v, iso_err *err);

/* As iso_solver_field, but conjugate gradients (the adaptive scheme's
 * reuse of a cached factor) start from the free entries of guess (3*nv;
 * may be v itself) instead of the previous solution: the integrator
 * extrapolates its history to the new time, which starts closer. The
 * result meets the same tolerance either way; a direct solve ignores it. */
ISO_API ISO_NODISCARD int iso_solver_field_from(iso_solver *s, const double *x, const double *vc,
                                                const double *guess, double *v, iso_err *err);

/* Adaptive only (a no-op otherwise): factors the system at positions x
 * (3*nv) now, so that the evaluations after precondition with it instead
 * of the first one factoring on its own time. A real-time loop calls it
 * before its clock starts: the first tick then costs a few CG iterations
 * instead of a factorization (cactus: ~25 ms, a 60 Hz period's 1.5). Counts
 * as a factorization in the stats. Failures as iso_solver_field's. */
ISO_API ISO_NODISCARD int iso_solver_factor_at(iso_solver *s, const double *x, iso_err *err);

/* The factorization worker's scheduling (worker_lag > 0; without a worker
 * a no-op): priority > 0 puts its thread under SCHED_FIFO at that
 * priority, 0 back under SCHED_OTHER. For a real-time loop, whose tick
 * waits for the worker at each hand-over: below the tick's priority and
 * above everything else, no busy process can hold the tick up through it
 * (controller/iso_loop.h). Only the worker's own thread changes; a
 * threaded BLAS's pool would be on the hand-over path too, which is one
 * more reason to give the BLAS one thread (worker_lag above). ISO_EIO
 * with the reason when it is not permitted (CAP_SYS_NICE, rtprio). */
ISO_API ISO_NODISCARD int iso_solver_set_worker_priority(iso_solver *s, int priority, iso_err *err);

/* Progress inside a field evaluation, for a watchdog that must tell a slow
 * evaluation from a stuck one (the actuators' loop watchdog, iso_actuators.h).
 * fn(ctx) is called on the evaluating thread after the assembly, after each
 * factorization and after each conjugate-gradient iteration, so the longest
 * silence is one of those pieces (cactus: ~25 ms factorization; the 40k
 * bumpplane: 0.1-0.3 s assembly or factorization). It must be quick and
 * must not call back into the solver. NULL fn stops the calls. */
typedef void (*iso_solver_progress_fn)(void *ctx);
ISO_API void iso_solver_set_progress(iso_solver *s, iso_solver_progress_fn fn, void *ctx);

/* The restoration term's settings (iso_solver_opts): μ and the τ now in use.
 * Defined in restore.c. */
ISO_API void iso_solver_get_restore(const iso_solver *s, double *mu, double *tau); /* out */

/* Sets the τ of the next evaluations (> 0, finite), e.g. the integrator's
 * per-step τ_eff = max(τ, κ h), which keeps the explicit step inside its
 * stability region (iso_integrate.h). Only τ changes: the pattern, the
 * elements and μ stay. With μ = 0 it is accepted and changes nothing. */
ISO_API ISO_NODISCARD int iso_solver_set_restore_tau(iso_solver *s, double tau, iso_err *err);

/* ===== what an integrator asks of conjugate gradients (adaptive refactor)
 *
 * Accuracy. Without a target PCG stops at the relative residual cg_tol,
 * a figure set by habit. An integrator knows what it needs: the error of a
 * solve moves its step by h times that error, which should be a fraction of
 * the step's own local error (iso_integrate.h). iso_solver_set_cg_target(s,
 * target) with target > 0 makes the solves that follow stop instead when
 * z = (LLᵀ)⁻¹ r, the preconditioned residual, is at most target at every
 * free vertex (the Euclidean norm of its three components, in the field's
 * units). z is what the cached factor says the remaining error is: with a
 * young factor, M = LLᵀ close to A, the error e = A⁻¹ r = z + (M⁻¹(M − A)) e.
 * On stopping, z is added to the solution (one preconditioned Richardson
 * step; z was computed for the test, so it is free), which leaves an error
 * smaller than z by the factor's quality. The relative residual cg_tol
 * still ends it if it comes first: it is the floor below which no accuracy
 * is asked, for the steps whose error is far below anything that matters
 * (a slow or still handle: there a tenth of the step's error would ask CG
 * for 1e-13 of the diagonal, and fail to the fallback). target ≤ 0 (or NaN)
 * leaves cg_tol alone. Direct solves are exact anyway.
 *
 * Budget. Between iso_solver_budget_begin() and iso_solver_budget_end() the
 * solves share one budget of cg_max_iter PCG iterations (the real-time
 * stepper opens one a tick, so a tick's iterations are capped, not each
 * solve's). A solve that has spent what is left, or whose rate shows that
 * it would, stops and falls back to a fresh factorization and a direct
 * solve; that factorization refills the budget, as the fresh factor starts
 * the count again. So a tick costs at most cg_max_iter iterations before
 * its first factorization. Outside a budget each solve has cg_max_iter. */
ISO_API void iso_solver_set_cg_target(iso_solver *s, double target);
ISO_API void iso_solver_budget_begin(iso_solver *s);
ISO_API void iso_solver_budget_end(iso_solver *s);

/* Bounded solves: the real-time loop's rule that its thread does not
 * factor the whole system during a run (docs/realtime.md, "A tick's
 * cost"). With on = 1, a worker (worker_lag > 0) and a factor in hand, a
 * solve is PCG with the cached factor: it ends at the tolerance, or at the
 * budget (above; a solve that finds it spent still takes
 * ISO_SOLVER_BOUNDED_MIN_ITERS iterations), or when it stalls, and then
 * keeps its best iterate if its relative residual ‖b − A x‖ / ‖b‖ is at
 * most ISO_SOLVER_BOUNDED_RES: an inexact solve, counted in the stats
 * with the largest such residual. Only a solve that ends above that
 * residual falls back to a factorization here (counted in refactors): on
 * the fast drags of tests/streams the stale factor's iterates reached
 * residuals of 0.1 to 40 while the mesh tore ("not positive definite"),
 * whereas every inexact solve of the recorded 3D-mouse session ended below
 * 0.014 and moved its final mesh by less than the integrator's own error
 * (docs/performance.md). The worker is given the matrix of every
 * evaluation whose factor is not its own, on its usual schedule, so which
 * solve is inexact depends on evaluation counts only: results stay
 * bit-identical from run to run. A factorization here (25 ms on the
 * cactus alone, 60 beside QEMU) made a late tick whose catch-up cost more
 * solves: the cascade this rule breaks. A solve with no factor yet still
 * factors. 0 (the default) is the fallback iso_solver_budget_begin
 * describes. */
ISO_API void iso_solver_set_bounded(iso_solver *s, int on);
#define ISO_SOLVER_BOUNDED_MIN_ITERS 2
#define ISO_SOLVER_BOUNDED_RES 1e-2

typedef struct iso_solver_stats {
    long evaluations;
    long factorizations;                  /* numeric factorizations */
    long cg_iterations;                   /* adaptive refactor: PCG iterations, summed */
    long refactors;                       /* adaptive: factorizations forced by slow/stalled CG
                                             (bounded: by a residual above
                                             ISO_SOLVER_BOUNDED_RES) */
    long cg_capped;                       /* of those, forced by the iteration cap or budget */
    double t_assembly, t_factor, t_solve; /* seconds, summed */
    int n_free;                           /* free vertices */
    long nnz_a, nnz_l;                    /* stored entries of A_ff (upper) and of L */
    /* The factorization worker (worker_lag > 0): factors it handed over,
     * seconds the evaluations waited for it, seconds it spent on the jobs
     * taken back so far (taken or not; a job still running is not counted).
     * factorizations and t_factor count the evaluating thread's only. */
    long handovers;
    double t_wait, t_worker;
    /* Solves with a factor on the evaluating thread: one per direct solve,
     * and per PCG solve one for its start and one per iteration that did
     * not end on the residual alone. At 40k vertices each streams the
     * whole factor (246 MB), several times what an assembly costs, so it is
     * the unit a tick's cost is counted in. */
    long factor_solves;
    /* The factor as CHOLMOD's analysis chose it, made once at creation:
     * supernodal (1) or simplicial (0, CHOLMOD's choice where the flops per
     * entry of L are few); the seconds the fill-reducing ordering and the
     * symbolic analysis took; and the bytes of one numeric factor as
     * CHOLMOD holds it: supernodal, its xsize values and ssize row indices
     * with three integers a supernode; simplicial, its nzmax values and row
     * indices with four integers a column (nnz_l stands for nzmax before
     * the first factorization allocates it); both, the permutation and the
     * column counts. Each solve with the factor streams its values twice
     * (forward and back), so on a large mesh these bytes set a solve's
     * time. With a worker the solver holds two factors of this size. */
    int supernodal;
    double t_analysis;
    long factor_bytes;
    /* Worker jobs not given because the matrix would have been the
     * factor's own: its positions within ISO_SOLVER_SAME_MATRIX of the
     * factor's (a mesh at rest), so the worker idles instead of factoring
     * the same matrix again. */
    long worker_idle;
    /* Bounded solves (iso_solver_set_bounded): those that ended at the
     * budget or a stall with their best iterate, and the largest relative
     * residual ‖b − A x‖ / ‖b‖ one of them ended at. */
    long inexact;
    double inexact_res_max;
} iso_solver_stats;
ISO_API void iso_solver_get_stats(const iso_solver *s, iso_solver_stats *st);

/* The largest move of any vertex, over the bounding-box diagonal, below
 * which the worker treats a matrix as the cached factor's own. A factor is
 * PCG's preconditioner, so a matrix that far from its own changes nothing a
 * preconditioner notices; a mesh at rest moves by CG's round-off, 1e-12 of
 * the diagonal or less, each evaluation. */
#define ISO_SOLVER_SAME_MATRIX 1e-9

/* Floating-point operations of one numeric factorization, as CHOLMOD's
 * analysis counts them (Common->fl); 0 when there are no free vertices. For
 * reporting a factorization's achieved rate beside the machine's dgemm. */
ISO_API double iso_solver_factor_flops(const iso_solver *s);

/* One line about a choice the solver made that the user should hear of
 * (e.g. "OpenCL: no platform found; using the C assembly"), or "". */
ISO_API const char *iso_solver_notice(const iso_solver *s);

#endif
