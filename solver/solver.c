/* solver/solver.c -- the solver's options, its creation and destruction,
 * and one field evaluation (iso_solver.h). The parts live beside it:
 * constraints.c checks that the problem is well posed, pattern.c builds the
 * elements, the pattern and the analysis, assemble_cpu.c and assemble_cl.c
 * fill the values, linsolve.c solves. */
#include "iso_solver.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_clock.h"
#include "iso_names.h"
#include "iso_proxy.h"
#include "solver_internal.h"
#include "supersolve_internal.h"

const char *const iso_assembly_names[] = {"cpu", "opencl", "auto", NULL};
const char *const iso_refactor_names[] = {"adaptive", "always", NULL};
const char *const iso_precond_names[] = {"rotated", "plain", NULL};
const char *const iso_proxy_smoothness_names[] = {"mesh", "matched", NULL};

void iso_solver_opts_default(iso_solver_opts *o)
{
    o->omega = 1.0 / 3.0;
    o->weighting = ISO_WEIGHT_PARAM;
    o->restore_mu = 0.0;
    o->restore_tau = 0.0;
    o->assembly = ISO_ASSEMBLY_CPU;
    o->cl_device = NULL;
    o->refactor = ISO_REFACTOR_ALWAYS;
    o->cg_tol = 1e-10;
    o->cg_max_iter = 12;
    o->preconditioner = ISO_PRECOND_ROTATED;
    o->worker_lag = 0;
    o->worker_ahead = 1;
    o->proxy = 0;
    o->proxy_smoothness = ISO_PROXY_SMOOTHNESS_MESH;
    o->threads.omp = ISO_SOLVER_OMP_CALLER;
    o->threads.blas = ISO_SOLVER_BLAS_LEAVE;
    o->threads.split = ISO_SOLVER_SPLIT_LARGE;
}

static int check_opts(const iso_solver_opts *o, iso_err *err)
{
    if (!(o->omega > 0.0 && o->omega <= 1.0))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "omega = %g is outside (0, 1]: with omega = 0 a flat region makes "
                           "the system singular, and above 1 the distortion term turns negative",
                           o->omega);
    if (o->weighting != ISO_WEIGHT_PARAM && o->weighting != ISO_WEIGHT_AREA)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown weighting %d", (int)o->weighting);
    if (!(o->restore_mu >= 0.0 && isfinite(o->restore_mu)))
        return iso_err_set(err, ISO_EINVAL, -1, "restoration weight mu = %g must be >= 0",
                           o->restore_mu);
    if (o->restore_mu > 0.0 && !(o->restore_tau > 0.0 && isfinite(o->restore_tau)))
        return iso_err_set(err, ISO_EINVAL, -1, "restoration time constant tau = %g must be > 0",
                           o->restore_tau);
    if (o->preconditioner != ISO_PRECOND_ROTATED && o->preconditioner != ISO_PRECOND_PLAIN)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown preconditioner %d",
                           (int)o->preconditioner);
    if (o->worker_lag < 0 || o->worker_lag > ISO_SOLVER_WORKER_LAG_MAX)
        return iso_err_set(err, ISO_EINVAL, -1, "worker_lag = %d is outside [0, %d]", o->worker_lag,
                           ISO_SOLVER_WORKER_LAG_MAX);
    if (o->worker_lag > 0 && o->refactor != ISO_REFACTOR_ADAPTIVE)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "worker_lag = %d asks for a factorization worker, which only the "
                           "adaptive scheme uses (refactor is %s)",
                           o->worker_lag, iso_names_get(iso_refactor_names, (int)o->refactor));
    if (o->proxy != 0 && o->proxy != ISO_SOLVER_PROXY_AUTO && o->proxy < ISO_PROXY_MIN_BUDGET)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "proxy = %d is below the least budget, %d vertices (0: off, -1: auto)",
                           o->proxy, ISO_PROXY_MIN_BUDGET);
    if (o->threads.omp != ISO_SOLVER_OMP_CALLER && o->threads.omp != ISO_SOLVER_OMP_LEAVE)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown OpenMP thread policy %d",
                           (int)o->threads.omp);
    if (o->threads.blas != ISO_SOLVER_BLAS_LEAVE && o->threads.blas != ISO_SOLVER_BLAS_SIZED)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown BLAS thread policy %d",
                           (int)o->threads.blas);
    if (o->threads.split != ISO_SOLVER_SPLIT_LARGE && o->threads.split != ISO_SOLVER_SPLIT_ALWAYS)
        return iso_err_set(err, ISO_EINVAL, -1, "unknown assembly split policy %d",
                           (int)o->threads.split);
    return ISO_OK;
}

/* ===== creation ========================================================= */

static int number_free_vertices(iso_solver *s, iso_err *err)
{
    s->free_of = malloc((size_t)s->nv * sizeof *s->free_of);
    s->vert_of = malloc((size_t)s->nv * sizeof *s->vert_of);
    if (!s->free_of || !s->vert_of)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    s->nf = 0;
    for (int i = 0; i < s->nv; i++) {
        int f = s->r->kind[i] == ISO_FREE && iso_mesh_vertex_used(s->m, i);
        s->free_of[i] = f ? s->nf : -1;
        if (f)
            s->vert_of[s->nf++] = i;
    }
    return ISO_OK;
}

/* Sets up the OpenCL path, or falls back to C with a notice when OpenCL
 * is not built in or finds no usable device. */
static int start_opencl(iso_solver *s, iso_err *err)
{
#ifdef ISO_WITH_OPENCL
    if (s->nf == 0)
        return ISO_OK;
    iso_err why;
    iso_err_clear(&why);
    int rc = iso_solver__cl_create(s, &s->cl, &why);
    if (rc == ISO_OK) {
        s->o.assembly = ISO_ASSEMBLY_OPENCL;
        return ISO_OK;
    }
    if (rc != ISO_ENOTSUP)
        return iso_err_set(err, rc, why.offset, "%s", why.msg);
    /* The reason is one of assemble_cl.c's short sentences; the precision
     * only keeps the notice (256 bytes) from tripping -Wformat-truncation. */
    snprintf(s->notice, sizeof s->notice, "%s: %.200s; using the C assembly",
             s->o.assembly == ISO_ASSEMBLY_AUTO ? "assembly auto" : "OpenCL", why.msg);
#else
    snprintf(s->notice, sizeof s->notice,
             "OpenCL: this build has no OpenCL support; using the C assembly");
#endif
    (void)err;
    s->o.assembly = ISO_ASSEMBLY_CPU;
    return ISO_OK;
}

/* The rotated preconditioner's frame and scratch (rotate.c), when PCG will
 * run with it. */
static int start_rotations(iso_solver *s, iso_err *err)
{
    if (s->o.refactor != ISO_REFACTOR_ADAPTIVE || s->o.preconditioner != ISO_PRECOND_ROTATED ||
        s->nf == 0)
        return ISO_OK;
    s->rings = iso_solver__rings_create(s->m, s->nf, s->vert_of);
    s->frame = s->rings ? iso_solver__frame_create(s->rings, s->nv) : NULL;
    s->rot = malloc((size_t)s->nf * 9 * sizeof(double));
    if (!s->frame || !s->rot)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the rotated preconditioner");
    return ISO_OK;
}

/* The worker's look-ahead (iso_solver_opts.worker_ahead): the last two
 * evaluations' positions and the job's. */
static int start_ahead(iso_solver *s, iso_err *err)
{
    if (!s->o.worker_ahead)
        return ISO_OK;
    for (int i = 0; i < 3; i++)
        if (!(s->x_seen[i] = malloc((size_t)s->nv * 3 * sizeof(double))))
            return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the worker's look-ahead");
    return ISO_OK;
}

/* The worker's record of which positions its factors are of. */
static int start_worker_positions(iso_solver *s, iso_err *err)
{
    s->x_factor = malloc(((size_t)s->nv * 3 + 1) * sizeof(double));
    s->x_job = malloc(((size_t)s->nv * 3 + 1) * sizeof(double));
    if (!s->x_factor || !s->x_job)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the worker's positions");
    s->same_move = ISO_SOLVER_SAME_MATRIX * iso_mesh_bbox_diagonal(s->m);
    return ISO_OK;
}

double iso_solver_factor_flops(const iso_solver *s)
{
    return s->factor_flops;
}

const char *iso_solver_notice(const iso_solver *s)
{
    return s->notice;
}

int iso_solver_check(const iso_mesh *m, const iso_regions *r, const iso_solver_opts *opts,
                     iso_err *err)
{
    iso_solver_opts o;
    if (opts)
        o = *opts;
    else
        iso_solver_opts_default(&o);
    int rc = check_opts(&o, err);
    if (rc == ISO_OK)
        rc = iso_solver__check_regions(m, r, err);
    if (rc == ISO_OK)
        rc = iso_solver__check_constraints(m, r, err);
    return rc;
}

int iso_solver_create(const iso_mesh *m, const iso_regions *r, const iso_solver_opts *opts,
                      iso_solver **out, iso_err *err)
{
    *out = NULL;
    iso_solver *s = calloc(1, sizeof *s);
    if (!s)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    s->m = m;
    s->r = r;
    s->nv = iso_mesh_vertex_count(m);
    if (opts)
        s->o = *opts;
    else
        iso_solver_opts_default(&s->o);
    cholmod_start(&s->c);
    s->cpu_split_edges =
        s->o.threads.split == ISO_SOLVER_SPLIT_ALWAYS ? 0 : ISO_SOLVER_CPU_SPLIT_EDGES;
    s->cpu_helper = 1;
    int rc = iso_solver_check(m, r, &s->o, err);
    if (rc == ISO_OK)
        rc = number_free_vertices(s, err);
    if (rc == ISO_OK)
        rc = iso_solver__build_system(s, err);
    if (rc == ISO_OK && s->o.assembly != ISO_ASSEMBLY_CPU)
        rc = start_opencl(s, err);
    if (rc == ISO_OK)
        rc = start_rotations(s, err);
    if (rc != ISO_OK) {
        iso_solver_destroy(s);
        return rc;
    }
    iso_solver__threads_begin(s);
    if (s->o.worker_lag > 0 && s->nf > 0 &&
        ((rc = start_ahead(s, err)) != ISO_OK || (rc = start_worker_positions(s, err)) != ISO_OK ||
         (rc = iso_solver__worker_create(s, &s->w, err)) != ISO_OK)) {
        iso_solver_destroy(s);
        return rc;
    }
    s->st.n_free = s->nf;
    *out = s;
    return ISO_OK;
}

void iso_solver_destroy(iso_solver *s)
{
    if (!s)
        return;
    iso_solver__worker_destroy(s->w);
    iso_solver__threads_end(s);
#ifdef ISO_WITH_OPENCL
    iso_solver__cl_destroy(s->cl);
#endif
    cholmod_free_sparse(&s->A, &s->c);
    cholmod_free_factor(&s->L, &s->c);
    cholmod_free_dense(&s->B, &s->c);
    cholmod_free_dense(&s->X, &s->c);
    cholmod_free_dense(&s->Y, &s->c);
    cholmod_free_dense(&s->E, &s->c);
    free(s->super_work);
    iso_solver__super_plan_destroy(s->super_plan);
    for (int i = 0; i < ISO_SOLVER__WORK; i++)
        cholmod_free_dense(&s->work[i], &s->c);
    cholmod_free_dense(&s->hist, &s->c);
    cholmod_free_dense(&s->ahist, &s->c);
    iso_solver__frame_destroy(s->frame);
    iso_solver__rings_destroy(s->rings);
    free(s->rot);
    for (int i = 0; i < 3; i++)
        free(s->x_seen[i]);
    free(s->x_factor);
    free(s->x_job);
    cholmod_finish(&s->c);
    free(s->free_of);
    free(s->vert_of);
    free(s->el);
    free(s->slots);
    iso_solver__cpu_plan_destroy(s->cpu);
    free(s->rest_len);
    free(s->edge_w);
    free(s);
}

void iso_solver_set_progress(iso_solver *s, iso_solver_progress_fn fn, void *ctx)
{
    if (!s)
        return;
    s->progress = fn;
    s->progress_ctx = ctx;
}

/* One numeric factor's bytes as CHOLMOD holds it (iso_solver_stats), read
 * from L itself: a supernodal factor's sizes are fixed by the analysis, a
 * simplicial one's nzmax is what the factorization allocated (nnz_l on the
 * solver's path, which factors from scratch and never updates). */
static long factor_bytes(const cholmod_factor *L, long nnz_l)
{
    if (!L)
        return 0;
    size_t idx = L->itype == CHOLMOD_LONG ? sizeof(SuiteSparse_long) : sizeof(int);
    size_t ptr = L->itype == CHOLMOD_INT ? sizeof(int) : sizeof(SuiteSparse_long);
    size_t n = L->n, bytes = 2 * n * idx; /* Perm, ColCount */
    if (L->is_super) {
        bytes += L->xsize * sizeof(double) + L->ssize * idx;
        bytes += (L->nsuper + 1) * (idx + 2 * ptr); /* super; pi, px */
    } else {
        size_t nz = L->xtype == CHOLMOD_PATTERN ? (size_t)nnz_l : L->nzmax;
        bytes += nz * (sizeof(double) + idx);
        bytes += (n + 1) * ptr + n * idx + 2 * (n + 2) * idx; /* p; nz; next, prev */
    }
    return (long)bytes;
}

void iso_solver_get_stats(const iso_solver *s, iso_solver_stats *st)
{
    *st = s->st;
    st->factor_bytes = factor_bytes(s->L, s->st.nnz_l);
}

/* ===== evaluation ======================================================= */

int iso_solver__assemble(iso_solver *s, const double *x, const double *vc, iso_err *err)
{
#ifdef ISO_WITH_OPENCL
    if (s->cl)
        return iso_solver__cl_assemble(s->cl, s, x, vc, err);
#endif
    return iso_solver__assemble_cpu(s, x, vc, err);
}

/* The free entries of guess into X, where PCG starts. */
static void start_from(iso_solver *s, const double *guess)
{
    if (!guess || !s->X || s->nf <= 0)
        return;
    double *X = s->X->x;
    for (int i = 0; i < s->nv; i++) {
        int f = s->free_of[i];
        if (f >= 0)
            memcpy(X + 3 * f, guess + 3 * i, 3 * sizeof(double));
    }
}

int iso_solver_factor_at(iso_solver *s, const double *x, iso_err *err)
{
    if (s->o.refactor != ISO_REFACTOR_ADAPTIVE || s->nf == 0)
        return ISO_OK;
    double *vc = calloc((size_t)s->nv * 3, sizeof *vc); /* B is not wanted */
    if (!vc)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d vertices", s->nv);
    double t0 = iso_clock_now();
    int rc = iso_solver__assemble(s, x, vc, err);
    s->st.t_assembly += iso_clock_now() - t0;
    s->x_now = x;
    if (rc == ISO_OK)
        rc = iso_solver__factor_now(s, err);
    s->x_now = NULL;
    free(vc);
    return rc;
}

int iso_solver_field(iso_solver *s, const double *x, const double *vc, double *v, iso_err *err)
{
    return iso_solver_field_from(s, x, vc, NULL, v, err);
}

int iso_solver_field_from(iso_solver *s, const double *x, const double *vc, const double *guess,
                          double *v, iso_err *err)
{
    start_from(s, guess);
    double t0 = iso_clock_now();
    int rc = ISO_OK;
    if (s->nf > 0)
        rc = iso_solver__assemble(s, x, vc, err);
    s->st.t_assembly += iso_clock_now() - t0;
    iso_solver__progress(s);
    s->x_now = x;
    s->vc_now = vc;
    if (rc == ISO_OK && s->nf > 0)
        rc = iso_solver__linsolve(s, err); /* times its own phases */
    if (rc != ISO_OK)
        return rc;
    s->st.evaluations++;
    const double *X = s->nf > 0 ? s->X->x : NULL;
    for (int i = 0; i < s->nv; i++) {
        int f = s->free_of[i];
        for (int a = 0; a < 3; a++) {
            double val = 0;
            if (f >= 0)
                val = X[3 * f + a];
            else if (s->r->kind[i] == ISO_HANDLE && iso_mesh_vertex_used(s->m, i))
                val = vc[3 * i + a];
            v[3 * i + a] = val;
        }
    }
    return ISO_OK;
}
