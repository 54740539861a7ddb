/* solver/solver_internal.h -- what the solver's parts share: the element
 * list, the slot map and the solver struct. Not installed; only the
 * solver's own sources and white-box tests include it.
 *
 * Assembly backends (the C path in assemble_cpu.c, the OpenCL path in
 * assemble_cl.c with its plan in assemble_plan.c) fill s->A's values
 * (upper triangle of A_ff) and s->B (the right-hand side −A_fc v_c, plus
 * the restoration term's linear part) from the current positions. They
 * must agree to rounding, and each must be bit-identical from run to run
 * (replays depend on it). */
#ifndef ISO_SOLVER_INTERNAL_H
#define ISO_SOLVER_INTERNAL_H

#include <cholmod.h>
#include <pthread.h>

#include "iso_solver.h"

typedef struct iso_solver__element {
    int kind;    /* 1: triangle (Q1), 2: ordered pair (Q2), 3: edge (restoration) */
    int tri;     /* the triangle (Q1) or Ti (Q2) */
    int v[4];    /* global vertices in local order */
    int jmap[3]; /* Q2: local index of each of Tj's corners */
    int slot;    /* index of this element's first slot in the slot map */
} iso_solver__element;

/* Vertices of an element: 3 (triangle), 4 (pair), 2 (edge). */
static inline int iso_solver__local_count(const iso_solver__element *e)
{
    return e->kind == 1 ? 3 : e->kind == 2 ? 4 : 2;
}

/* Is b the mirror (Tj, Ti) of the pair element a = (Ti, Tj)? build_elements
 * lists the two ordered pairs of an edge one after the other; both
 * assembly paths compute them as one edge block. */
static inline int iso_solver__is_mirror(const iso_solver__element *a, const iso_solver__element *b)
{
    if (b->kind != 2)
        return 0;
    int opp_a = -1; /* Ti's corner that is not in Tj */
    for (int l = 0; l < 3; l++)
        if (a->jmap[0] != l && a->jmap[1] != l && a->jmap[2] != l)
            opp_a = a->v[l];
    if (b->v[3] != opp_a)
        return 0;
    for (int k = 0; k < 3; k++)
        if (b->v[k] != a->v[a->jmap[k]])
            return 0;
    return 1;
}

/* The edge layout (a, b, p, q) of pair element e: the shared edge in Ti's
 * order, Ti's third corner, Tj's third corner. map[x] is e's local index of
 * layout vertex x (iso_elem_edge_from_fits takes points in this order). */
static inline void iso_solver__edge_layout(const iso_solver__element *e, int map[4])
{
    int n = 0;
    for (int l = 0; l < 3; l++)
        if (e->jmap[0] == l || e->jmap[1] == l || e->jmap[2] == l)
            map[n++] = l;
    for (int l = 0; l < 3; l++)
        if (e->jmap[0] != l && e->jmap[1] != l && e->jmap[2] != l)
            map[2] = l;
    map[3] = 3;
}

#define ISO_SOLVER__WORK 5
#define ISO_SOLVER__HIST 8 /* past solutions PCG's start is projected on (warmstart.c) */

struct iso_solver {
    const iso_mesh *m;
    const iso_regions *r;
    iso_solver_opts o;
    int nv, nf;
    int *free_of; /* nv: free index or −1 */
    int *vert_of; /* nf: vertex of each free index */
    iso_solver__element *el;
    int nel;
    int *slots;       /* per element, per local (a, b): 3 column offsets or −1 */
    double *rest_len; /* per edge, when restoration is on */
    double *edge_w;   /* per edge weight w_e, when restoration is on */
    char notice[256];
    struct iso_cl_assembler *cl; /* OpenCL path when in use, else NULL */
    cholmod_common c;
    cholmod_sparse *A;
    cholmod_factor *L;
    cholmod_dense *B, *X, *Y, *E;
    double *super_work; /* iso_solver__super_solve's, when L is supernodal; else NULL */
    struct iso_solver__super_plan *super_plan; /* the solves' two halves, or NULL */
    int super_plan_made;
    cholmod_dense *work[ISO_SOLVER__WORK]; /* PCG: residual, preconditioned residual,
                                              direction, A·direction, rotated residual */
    cholmod_dense *hist;              /* 3 nf × ISO_SOLVER__HIST: the last solutions' free parts */
    cholmod_dense *ahist;             /* A times each, this evaluation's A */
    int n_hist;                       /* of hist's columns, those that hold a solution */
    int hist_head;                    /* the column the next solution goes to */
    int have_factor;                  /* L holds a numeric factor of some earlier A */
    double factor_flops;              /* CHOLMOD's Common->fl after analysis */
    struct iso_solver__cpu_plan *cpu; /* C path's plans (assemble_cpu.c), made at first use */
    int cpu_split_edges;              /* interior edges from which the C path runs in two halves */
    int cpu_helper;    /* the two halves may run on a helper thread (else both here) */
    int last_cg_iters; /* iterations of the previous PCG solve, −1 after a direct one */
    int cg_failures;   /* consecutive PCG attempts at factor age 1 that failed */
    int cg_skip;       /* evaluations left before PCG is tried again */
    int factor_age;    /* evaluations since L was computed (this one included) */
    int reuse_horizon; /* oldest factor age PCG is tried at; 0: not learned yet */
    int horizon_probe; /* factorizations left until the horizon is probed */
    double cg_target;  /* > 0: PCG stops on z's largest vertex (iso_solver.h) */
    int budget_on;     /* a shared iteration budget is open */
    int budget_used;   /* its iterations spent since it opened or since a factorization */
    int bounded;       /* iso_solver_set_bounded: no factorization here once a factor exists */
    double last_res;   /* the last PCG solve's relative residual ‖b − A x‖ / ‖b‖ */
    struct iso_solver__worker *w; /* factorization worker (worker_lag > 0), else NULL */
    /* The rotated preconditioner (rotate.c), adaptive with
     * ISO_PRECOND_ROTATED only, else NULL: the rings, L's frame, this
     * evaluation's positions and its rotations (9 nf). */
    struct iso_solver__rings *rings;
    struct iso_solver__frame *frame;
    const double *x_now, *vc_now; /* this evaluation's positions and handle velocities */
    double *rot;
    /* The worker's look-ahead (worker_ahead), else NULL: the positions of
     * the last two evaluations (x_seen[0] the latest) and of the next job;
     * n_seen of the first two hold evaluations. */
    double *x_seen[3];
    int n_seen;
    /* With a worker: the positions of the factor in use (have_x_factor)
     * and of the worker's job, so that a mesh at rest gives it no job
     * (ISO_SOLVER_SAME_MATRIX); same_move is that bound in scene units. */
    double *x_factor, *x_job;
    int have_x_factor;
    double same_move;
    int w_left; /* evaluations until the worker's job is taken; 0: no job */
    /* Thread controls (linsolve.c), looked up once at creation; NULL where
     * the option leaves them alone or the process has no such library. */
    int (*omp_get_levels)(void);
    void (*omp_set_levels)(int);
    void (*blas_set_threads)(int);
    int blas_restore; /* OpenBLAS count to restore at destroy; 0: none */
    iso_solver_stats st;
    iso_solver_progress_fn progress; /* iso_solver_set_progress; NULL: none */
    void *progress_ctx;
};

/* Reports progress (iso_solver_set_progress), if anyone listens. */
static inline void iso_solver__progress(const struct iso_solver *s)
{
    if (s->progress)
        s->progress(s->progress_ctx);
}

/* Creation's checks (constraints.c): the regions fit the mesh, and every
 * part of the mesh with free vertices is pinned (iso_solver.h). ISO_OK, or
 * ISO_EINVAL / ISO_ECONSTRAINT with a message naming the vertex. */
int iso_solver__check_regions(const iso_mesh *m, const iso_regions *r, iso_err *err);
int iso_solver__check_constraints(const iso_mesh *m, const iso_regions *r, iso_err *err);

/* The system's structure (pattern.c), once free_of and vert_of exist: the
 * element list (s->el, s->nel; with restoration the rest lengths and edge
 * weights), A's pattern (s->A, values undefined), the slot map, the
 * ordering and CHOLMOD's analysis (s->L, s->B, the triangular solves'
 * workspace, nnz and flops in the stats). */
int iso_solver__build_system(iso_solver *s, iso_err *err);

/* CHOLMOD's symbolic analysis of A (perm: the ordering to use, or NULL for
 * the Common's methods), one at a time in the process (pattern.c says why). */
cholmod_factor *iso_solver__analyze(cholmod_sparse *A, int *perm, cholmod_common *c);

/* Applies opts.threads at creation (after the analysis, which knows the
 * factorization's flops) and undoes its process-wide part at destroy. */
void iso_solver__threads_begin(iso_solver *s);
void iso_solver__threads_end(iso_solver *s);

/* Solves A_ff X = B with the current values: a fresh factorization, or
 * (adaptive refactor) PCG preconditioned by the cached factor. Accumulates
 * t_factor / t_solve and the factor statistics. */
int iso_solver__linsolve(iso_solver *s, iso_err *err);

/* aᵀb over n entries, summed in order (the bits of a replay depend on it). */
static inline double iso_solver__dot(const double *a, const double *b, int n)
{
    double acc = 0;
    for (int i = 0; i < n; i++)
        acc += a[i] * b[i];
    return acc;
}

/* y = A x with A's current values (its upper triangle, as stored). */
int iso_solver__matvec(iso_solver *s, cholmod_dense *x, cholmod_dense *y, iso_err *err);

/* PCG's start (warmstart.c): X (the caller's guess) and AX = A X are
 * replaced by the combination of the guess and the remembered solutions
 * that is closest to the solution in A's norm, and A times it. remember:
 * the solution in s->X joins the history (a no-op until PCG's vectors
 * exist). */
int iso_solver__warm_start(iso_solver *s, cholmod_dense *X, cholmod_dense *AX, iso_err *err);
void iso_solver__warm_remember(iso_solver *s);

/* Factors s->A as it is, with its frame at s->x_now (iso_solver_factor_at). */
int iso_solver__factor_now(iso_solver *s, iso_err *err);

/* Fills s->A's values and s->B at positions x with handle velocities vc,
 * by whichever assembly path the solver uses (solver.c). */
int iso_solver__assemble(iso_solver *s, const double *x, const double *vc, iso_err *err);

/* The rotated preconditioner (rotate.c). The rings: each free vertex's
 * neighbours and triangles, made once (NULL when out of memory); they read
 * vert_of, which outlives them. A frame holds the positions a factor's
 * matrix was assembled at and what the rotations need of them alone.
 * create: NULL when out of memory. positions: the 3 nv positions to fill,
 * after which prepare (on any one thread) makes the rest. rotations: each
 * free vertex's rotation R (9 nf, row-major) from the frame's positions to
 * x. rotate: out_i = R_i in_i, or R_iᵀ in_i with transpose (in may be
 * out). */
typedef struct iso_solver__rings iso_solver__rings;
typedef struct iso_solver__frame iso_solver__frame;
iso_solver__rings *iso_solver__rings_create(const iso_mesh *m, int nf, const int *vert_of);
void iso_solver__rings_destroy(iso_solver__rings *g);
iso_solver__frame *iso_solver__frame_create(const iso_solver__rings *g, int nv);
void iso_solver__frame_destroy(iso_solver__frame *fr);
double *iso_solver__frame_positions(iso_solver__frame *fr);
void iso_solver__frame_prepare(iso_solver__frame *fr);
void iso_solver__rotations(const iso_solver__frame *fr, const double *x, double *R);
void iso_solver__rotate(const double *R, int nf, const double *in, double *out, int transpose);

/* The factorization worker (worker.c). create: after the analysis (it
 * copies A's pattern and the symbolic factor) and threads_begin (it takes
 * the OpenMP control); with the solver's frame it keeps one of its own.
 * start: copies A's values (and x, the positions they were assembled at,
 * when there are frames) and wakes the worker, which must be idle (no job,
 * or its result taken); the worker factors and prepares its frame.
 * finish: waits for the job to end; with L, swaps the worker's factor into
 * *L and its frame into *frame (the old ones become the worker's); returns
 * cholmod_factorize's result and gives Common->status and L->minor for
 * factor_outcome, and the seconds the job took. */
typedef struct iso_solver__worker iso_solver__worker;
int iso_solver__worker_create(const iso_solver *s, iso_solver__worker **out, iso_err *err);
void iso_solver__worker_destroy(iso_solver__worker *w);
void iso_solver__worker_start(iso_solver__worker *w, const cholmod_sparse *A, const double *x);
int iso_solver__worker_finish(iso_solver__worker *w, cholmod_factor **L, iso_solver__frame **frame,
                              int *status, long *minor, double *seconds);

/* Sorts n edges (endpoints a[k] and b[k]) along a Z-order curve through
 * their midpoints at the rest pose (order.c): order[k] is the edge at
 * position k, ties broken by edge index, so the order is fixed. 0, or −1
 * when out of memory. */
int iso_solver__z_order(const iso_mesh *m, int n, const int *a, const int *b, int *order);

/* Two halves of a job on two threads (team.c): run calls fn(ctx, 0) on the
 * calling thread and fn(ctx, 1) on the team's helper, and returns when both
 * have returned; without a helper (create could not start one) it calls
 * both on the caller, in that order. create: NULL when out of memory. The
 * helper blocks all signals and runs each job at the caller's scheduling
 * (policy and priority), since the caller waits for it. */
/* Starts a thread running fn(arg) with a full signal mask (signals stay
 * the caller's business) and explicit default scheduling, whatever the
 * creator runs at; the creator's own mask is put back. 0, or -1. */
int iso_solver__start_thread(pthread_t *th, void *(*fn)(void *), void *arg);

typedef struct iso_solver__team iso_solver__team;
iso_solver__team *iso_solver__team_create(void);
void iso_solver__team_destroy(iso_solver__team *t); /* NULL is a no-op */
void iso_solver__team_run(iso_solver__team *t, void (*fn)(void *ctx, int half), void *ctx);
int iso_solver__team_threads(const iso_solver__team *t); /* 2 with a helper, else 1 */
/* The items [begin, end) of n that half 0 or 1 takes: the first n / 2, or the rest. */
void iso_solver__team_half(int n, int half, int *begin, int *end);

/* The C assembly path. Its plans are made at the first call and freed by
 * iso_solver__cpu_plan_destroy (NULL is a no-op). From
 * ISO_SOLVER_CPU_SPLIT_EDGES interior edges on (a mesh of about 20k
 * vertices; any size under ISO_SOLVER_SPLIT_ALWAYS), it runs in two halves
 * on two threads (assemble_cpu.c says how the bits stay one thread's). */
typedef struct iso_solver__cpu_plan iso_solver__cpu_plan;
int iso_solver__assemble_cpu(iso_solver *s, const double *x, const double *vc, iso_err *err);
void iso_solver__cpu_plan_destroy(iso_solver__cpu_plan *p);
int iso_solver__cpu_halves(const iso_solver__cpu_plan *p);             /* 1 or 2 */
iso_solver__team *iso_solver__cpu_team(const iso_solver__cpu_plan *p); /* NULL: one thread */

/* The OpenCL path (assemble_cl.c, compiled when ISO_WITH_OPENCL is defined).
 * create: after the pattern and slot map exist; builds the kernels and the
 * gather maps once. Returns ISO_ENOTSUP when no usable platform/device
 * exists (the caller then falls back to the C path with a notice), other
 * negative codes for real failures (a kernel build failure carries the
 * compiler log in err). assemble: same contract as the C path. */
int iso_solver__cl_create(iso_solver *s, struct iso_cl_assembler **out, iso_err *err);
int iso_solver__cl_assemble(struct iso_cl_assembler *cl, iso_solver *s, const double *x,
                            const double *vc, iso_err *err);
void iso_solver__cl_destroy(struct iso_cl_assembler *cl);

#endif
