/* solver/assemble_cl.c -- the OpenCL assembly path (solver_internal.h).
 *
 * Per evaluation, three kernels compute element blocks into a buffer of
 * slots and two sum them:
 *   fit_triangles  per triangle: the rigid fit, into a record (computed once
 *                  per evaluation however many edges use it);
 *   pair_edges     per interior edge: both ordered pairs' ω Q2 and the
 *                  (1 − ω) Q1 of the triangles it carries, as one 12x12 block
 *                  (element_batch.c's form: every triangle element is
 *                  carried by one of its interior edges, whose blocks
 *                  include all of its own);
 *   restore_edges  per edge, with restoration on: μ times its block and its
 *                  linear part;
 *   reduce_blocks  per 3x3 block of A_ff, and reduce_rhs per free vertex:
 *                  the sums.
 * Where each element block goes is planned once (assemble_plan.c, plain C
 * that the tests check without a device): every 3x3 block an element
 * kernel computes has a slot (nine values, or a diagonal block's
 * upper six), and the slots of one block of A_ff are consecutive, in
 * element-list order. So the element kernels write each block straight to
 * its place (in the orientation A needs: the rows of the lower free
 * index), and reduce_blocks sums a contiguous run of slots with no index
 * to look up; blocks of a free and a handle vertex go to slots per free
 * vertex, which reduce_rhs multiplies by the handle's velocity; blocks
 * that reach neither go to slots of their own that nothing reads.
 * The sums write every entry of A's value array and of B, straight into
 * s->A->x and s->B->x (wrapped as CL_MEM_USE_HOST_PTR buffers and left
 * mapped for reading between evaluations): no atomics, no host-side
 * scatter, no allocation per evaluation, and sums in a fixed order,
 * bit-identical from run to run. The element kernels are written so that
 * PoCL runs the work-items of a group as vector lanes
 * (assemble_cl_kernels.h says how). */
#ifdef ISO_WITH_OPENCL

#include <ctype.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <CL/cl.h>

#include "assemble_cl_kernels.h"
#include "assemble_plan_internal.h"

typedef struct iso_cl_assembler iso_cl_assembler;
typedef iso_solver__cl_plan plan;

/* The fit record is element_internal.h's, which the kernels' FIT_STRIDE
 * repeats inside their source text. */
#define FIT_STRIDE ISO_ELEM__FIT_STRIDE

enum { K_FIT, K_PAIR, K_RESTORE, K_BLOCKS, K_RHS, K_COUNT };
static const char *const kernel_names[K_COUNT] = {"fit_triangles", "pair_edges", "restore_edges",
                                                  "reduce_blocks", "reduce_rhs"};

struct iso_cl_assembler {
    cl_context ctx;
    cl_device_id dev;
    cl_command_queue q;
    cl_program prog;
    cl_kernel k[K_COUNT];
    size_t wg[K_COUNT];
    /* static inputs, uploaded once */
    cl_mem fit_work, pair_work, rest_work, rest_lin, rest_par;
    cl_mem blk_dst, blk_ptr, hb_ptr, hb_vtx, lin_ptr;
    /* per evaluation */
    cl_mem x, vc, fit, slot, pivot;
    cl_mem A, B; /* wrap s->A->x and s->B->x */
    double *A_host, *B_host;
    size_t nnz, nx;
    int n_fit, n_pair, n_rest, n_blocks, nf;
    int np;    /* pair items padded to whole work-groups */
    int nfp;   /* fit items padded to whole work-groups */
    int nrp;   /* restoration items padded to whole work-groups */
    int hbase; /* where the handle blocks' slots start in slot */
    int mapped;
    double *pivot_host; /* nfp: each fit's last Cholesky pivot, wrapped by `pivot` */
    int *first_el;      /* per fit item: first element (list order) using it as Ti or Q1 */
    int *tri_of;        /* per fit item: its triangle */
    char device[128];
};

/* ===== errors =========================================================== */

static const char *cl_error_name(cl_int rc)
{
    switch (rc) {
    case CL_DEVICE_NOT_FOUND: return "CL_DEVICE_NOT_FOUND";
    case CL_DEVICE_NOT_AVAILABLE: return "CL_DEVICE_NOT_AVAILABLE";
    case CL_COMPILER_NOT_AVAILABLE: return "CL_COMPILER_NOT_AVAILABLE";
    case CL_MEM_OBJECT_ALLOCATION_FAILURE: return "CL_MEM_OBJECT_ALLOCATION_FAILURE";
    case CL_OUT_OF_RESOURCES: return "CL_OUT_OF_RESOURCES";
    case CL_OUT_OF_HOST_MEMORY: return "CL_OUT_OF_HOST_MEMORY";
    case CL_BUILD_PROGRAM_FAILURE: return "CL_BUILD_PROGRAM_FAILURE";
    case CL_MAP_FAILURE: return "CL_MAP_FAILURE";
    case CL_INVALID_VALUE: return "CL_INVALID_VALUE";
    case CL_INVALID_PLATFORM: return "CL_INVALID_PLATFORM";
    case CL_INVALID_DEVICE: return "CL_INVALID_DEVICE";
    case CL_INVALID_CONTEXT: return "CL_INVALID_CONTEXT";
    case CL_INVALID_COMMAND_QUEUE: return "CL_INVALID_COMMAND_QUEUE";
    case CL_INVALID_HOST_PTR: return "CL_INVALID_HOST_PTR";
    case CL_INVALID_MEM_OBJECT: return "CL_INVALID_MEM_OBJECT";
    case CL_INVALID_BUFFER_SIZE: return "CL_INVALID_BUFFER_SIZE";
    case CL_INVALID_PROGRAM: return "CL_INVALID_PROGRAM";
    case CL_INVALID_PROGRAM_EXECUTABLE: return "CL_INVALID_PROGRAM_EXECUTABLE";
    case CL_INVALID_KERNEL_NAME: return "CL_INVALID_KERNEL_NAME";
    case CL_INVALID_KERNEL: return "CL_INVALID_KERNEL";
    case CL_INVALID_ARG_INDEX: return "CL_INVALID_ARG_INDEX";
    case CL_INVALID_ARG_VALUE: return "CL_INVALID_ARG_VALUE";
    case CL_INVALID_ARG_SIZE: return "CL_INVALID_ARG_SIZE";
    case CL_INVALID_KERNEL_ARGS: return "CL_INVALID_KERNEL_ARGS";
    case CL_INVALID_WORK_GROUP_SIZE: return "CL_INVALID_WORK_GROUP_SIZE";
    case CL_INVALID_GLOBAL_WORK_SIZE: return "CL_INVALID_GLOBAL_WORK_SIZE";
    case CL_INVALID_OPERATION: return "CL_INVALID_OPERATION";
    case -1001: return "CL_PLATFORM_NOT_FOUND_KHR";
    default: return "an OpenCL error";
    }
}

/* Turns a failed OpenCL call into ISO_EIO naming the call and the code. */
static int cl_fail(iso_err *err, const char *what, cl_int rc)
{
    return iso_err_set(err, ISO_EIO, -1, "OpenCL: %s failed: %s (%d)", what, cl_error_name(rc),
                       (int)rc);
}

/* ===== device selection ================================================= */

#define MAX_PLATFORMS 16
#define MAX_DEVICES 16

static void device_string(cl_device_id d, cl_device_info what, char *buf, size_t cap)
{
    buf[0] = '\0';
    if (clGetDeviceInfo(d, what, cap, buf, NULL) != CL_SUCCESS)
        snprintf(buf, cap, "?");
    buf[cap - 1] = '\0';
}

static int contains_nocase(const char *hay, const char *needle)
{
    size_t n = strlen(needle);
    for (; *hay; hay++) {
        size_t i = 0;
        while (i < n && hay[i] &&
               tolower((unsigned char)hay[i]) == tolower((unsigned char)needle[i]))
            i++;
        if (i == n)
            return 1;
    }
    return n == 0;
}

/* "P:D" with decimal indices; -1 if `want` is not of that form. */
static int parse_indices(const char *want, int *p, int *d)
{
    char *end;
    if (*want < '0' || *want > '9')
        return -1;
    long lp = strtol(want, &end, 10);
    if (*end != ':' || end[1] < '0' || end[1] > '9')
        return -1;
    long ld = strtol(end + 1, &end, 10);
    if (*end || lp > INT_MAX || ld > INT_MAX)
        return -1;
    *p = (int)lp;
    *d = (int)ld;
    return 0;
}

static int has_fp64(cl_device_id dev);

/* Picks the device opts.cl_device asks for (iso_solver.h); without one, the
 * first device of type `kind` (CPU; or, for the auto assembly, GPU or
 * accelerator with double precision, so that a later one with it is not
 * passed over). ISO_ENOTSUP with the reason when there is none. */
static int select_device(const char *want, cl_device_type kind, cl_device_id *out, iso_err *err)
{
    cl_platform_id plat[MAX_PLATFORMS];
    cl_uint np = 0;
    cl_int rc = clGetPlatformIDs(MAX_PLATFORMS, plat, &np);
    if (rc == -1001 || (rc == CL_SUCCESS && np == 0))
        return iso_err_set(err, ISO_ENOTSUP, -1, "no platform found");
    if (rc != CL_SUCCESS)
        return iso_err_set(err, ISO_ENOTSUP, -1, "listing platforms failed: %s", cl_error_name(rc));
    if (np > MAX_PLATFORMS)
        np = MAX_PLATFORMS;
    int wp = -1, wd = -1;
    int by_index = want && parse_indices(want, &wp, &wd) == 0;
    if (by_index && wp >= (int)np)
        return iso_err_set(err, ISO_ENOTSUP, -1, "device \"%s\" does not exist: %u platform(s)",
                           want, np);
    for (cl_uint p = 0; p < np; p++) {
        if (by_index && (int)p != wp)
            continue;
        cl_device_id dev[MAX_DEVICES];
        cl_uint nd = 0;
        if (clGetDeviceIDs(plat[p], CL_DEVICE_TYPE_ALL, MAX_DEVICES, dev, &nd) != CL_SUCCESS)
            nd = 0;
        if (nd > MAX_DEVICES)
            nd = MAX_DEVICES;
        if (by_index) {
            if (wd >= (int)nd)
                return iso_err_set(err, ISO_ENOTSUP, -1,
                                   "device \"%s\" does not exist: platform %d has %u device(s)",
                                   want, wp, nd);
            *out = dev[wd];
            return ISO_OK;
        }
        char pname[128];
        if (clGetPlatformInfo(plat[p], CL_PLATFORM_NAME, sizeof pname, pname, NULL) != CL_SUCCESS)
            pname[0] = '\0';
        pname[sizeof pname - 1] = '\0';
        for (cl_uint d = 0; d < nd; d++) {
            if (want) {
                char dname[128];
                device_string(dev[d], CL_DEVICE_NAME, dname, sizeof dname);
                if (!contains_nocase(dname, want) && !contains_nocase(pname, want))
                    continue;
            } else {
                cl_device_type type = 0;
                if (clGetDeviceInfo(dev[d], CL_DEVICE_TYPE, sizeof type, &type, NULL) !=
                        CL_SUCCESS ||
                    !(type & kind) || (kind != CL_DEVICE_TYPE_CPU && !has_fp64(dev[d])))
                    continue;
            }
            *out = dev[d];
            return ISO_OK;
        }
    }
    if (want)
        return iso_err_set(err, ISO_ENOTSUP, -1, "no device or platform name contains \"%s\"",
                           want);
    return iso_err_set(
        err, ISO_ENOTSUP, -1, "no %s found on %u platform(s)",
        kind == CL_DEVICE_TYPE_CPU ? "CPU device" : "GPU or accelerator with double precision", np);
}

/* The kernels need doubles; a device without them cannot run this path. */
static int has_fp64(cl_device_id dev)
{
    cl_device_fp_config fp = 0;
    if (clGetDeviceInfo(dev, CL_DEVICE_DOUBLE_FP_CONFIG, sizeof fp, &fp, NULL) != CL_SUCCESS)
        fp = 0;
    return fp != 0;
}

static int check_fp64(cl_device_id dev, const char *name, iso_err *err)
{
    if (!has_fp64(dev))
        return iso_err_set(err, ISO_ENOTSUP, -1,
                           "device \"%s\" has no double precision (cl_khr_fp64), which the "
                           "assembly needs",
                           name);
    return ISO_OK;
}

/* ===== program ========================================================== */

/* Squeezes runs of whitespace to one space, so more of a build log fits
 * the one-line error message. */
static void squeeze_spaces(char *s)
{
    char *o = s;
    int space = 1;
    for (; *s; s++) {
        int is = *s == ' ' || *s == '\n' || *s == '\t' || *s == '\r';
        if (is && space)
            continue;
        *o++ = is ? ' ' : *s;
        space = is;
    }
    if (o > s && o[-1] == ' ')
        o--;
    *o = '\0';
}

static int build_program(iso_cl_assembler *cl, iso_err *err)
{
    cl_int rc;
    cl->prog =
        clCreateProgramWithSource(cl->ctx, (cl_uint)ISO_CL_SOURCE_LINES, iso_cl_source, NULL, &rc);
    if (!cl->prog)
        return cl_fail(err, "clCreateProgramWithSource", rc);
    rc = clBuildProgram(cl->prog, 1, &cl->dev, "-cl-std=CL1.2", NULL, NULL);
    if (rc != CL_SUCCESS) {
        size_t len = 0;
        char *log = NULL;
        if (clGetProgramBuildInfo(cl->prog, cl->dev, CL_PROGRAM_BUILD_LOG, 0, NULL, &len) ==
                CL_SUCCESS &&
            (log = malloc(len + 1)) != NULL &&
            clGetProgramBuildInfo(cl->prog, cl->dev, CL_PROGRAM_BUILD_LOG, len, log, NULL) ==
                CL_SUCCESS) {
            log[len] = '\0';
            squeeze_spaces(log);
        }
        iso_err_set(err, ISO_EIO, -1,
                    "OpenCL: the assembly kernels failed to build for %s (%s): %s", cl->device,
                    cl_error_name(rc), log && *log ? log : "(no build log)");
        free(log);
        return ISO_EIO;
    }
    for (int i = 0; i < K_COUNT; i++) {
        cl->k[i] = clCreateKernel(cl->prog, kernel_names[i], &rc);
        if (!cl->k[i])
            return cl_fail(err, kernel_names[i], rc);
        size_t wg = 0;
        if (clGetKernelWorkGroupInfo(cl->k[i], cl->dev, CL_KERNEL_WORK_GROUP_SIZE, sizeof wg, &wg,
                                     NULL) != CL_SUCCESS ||
            wg == 0)
            wg = 1;
        /* 64 items a group: enough for PoCL to vectorise across items and
         * few enough groups to keep both cores busy on small meshes. */
        cl->wg[i] = wg < 64 ? wg : 64;
    }
    return ISO_OK;
}

/* ===== the plan ========================================================= */

/* The plan (assemble_plan.c) for this device's work-group sizes; the
 * assembler keeps its counts and the fit items' triangles and first
 * elements, which report a degenerate triangle as the C path does. */
static int make_plan(iso_solver *s, iso_cl_assembler *cl, plan *p, iso_err *err)
{
    const size_t wg[3] = {cl->wg[K_FIT], cl->wg[K_PAIR], cl->wg[K_RESTORE]};
    int rc = iso_solver__cl_plan_make(s, wg, p, err);
    if (rc != ISO_OK)
        return rc;
    cl->n_fit = p->n_fit;
    cl->n_pair = p->n_pair;
    cl->n_rest = p->n_rest;
    cl->n_blocks = p->n_blocks;
    cl->np = p->np;
    cl->nfp = p->nfp;
    cl->nrp = p->nrp;
    cl->hbase = p->hbase;
    cl->first_el = p->first_el;
    cl->tri_of = p->tri_of;
    p->first_el = p->tri_of = NULL;
    return ISO_OK;
}

/* ===== buffers ========================================================== */

static int make_buffer(iso_cl_assembler *cl, cl_mem *out, cl_mem_flags flags, size_t bytes,
                       void *host, const char *what, iso_err *err)
{
    cl_int rc;
    if (bytes == 0) { /* an empty list (e.g. no restoration): a placeholder */
        flags &= ~(cl_mem_flags)(CL_MEM_COPY_HOST_PTR | CL_MEM_USE_HOST_PTR);
        host = NULL;
        bytes = 16;
    }
    *out = clCreateBuffer(cl->ctx, flags, bytes, host, &rc);
    if (!*out) {
        char call[96];
        snprintf(call, sizeof call, "allocating the %s buffer (%zu bytes)", what, bytes);
        return cl_fail(err, call, rc);
    }
    return ISO_OK;
}

#define RO_COPY (CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR)

/* A read-only buffer from a host list: a table of them keeps upload short. */
typedef struct upload_item {
    cl_mem *mem;
    const void *host;
    size_t bytes;
    const char *what;
} upload_item;

static int upload(iso_solver *s, iso_cl_assembler *cl, plan *p, iso_err *err)
{
    size_t I = sizeof(int), D = sizeof(double), nf = (size_t)s->nf;
    cl->pivot_host = malloc(((size_t)cl->nfp + 1) * D);
    if (!cl->pivot_host)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    cl->A_host = s->A->x;
    cl->B_host = s->B->x;
    const upload_item ro[] = {
        {&cl->fit_work, p->fit_work, 4 * (size_t)cl->nfp * I, "triangle list"},
        {&cl->pair_work, p->pair_work, ISO_CL_PLAN_PAIR_ROWS * (size_t)cl->np * I, "pair list"},
        {&cl->rest_work, p->rest_work, ISO_CL_PLAN_REST_ROWS * (size_t)cl->nrp * I, "edge list"},
        {&cl->rest_lin, p->rest_lin, 2 * (size_t)cl->nrp * I, "edge list"},
        {&cl->rest_par, p->rest_par, 2 * (size_t)cl->nrp * D, "edge parameter"},
        {&cl->blk_dst, p->blk_dst, 4 * (size_t)cl->n_blocks * I, "block"},
        {&cl->blk_ptr, p->blk_ptr, ((size_t)cl->n_blocks + 1) * I, "block slot"},
        {&cl->hb_ptr, p->hb_ptr, (nf + 1) * I, "handle slot"},
        {&cl->hb_vtx, p->hb_vtx, p->n[ISO_CL_C_HANDLE] * I, "handle vertex"},
        {&cl->lin_ptr, p->lin_ptr, (nf + 1) * I, "linear-part slot"},
    };
    int rc = ISO_OK;
    for (size_t i = 0; i < sizeof ro / sizeof ro[0] && rc == ISO_OK; i++)
        rc = make_buffer(cl, ro[i].mem, RO_COPY, ro[i].bytes, (void *)ro[i].host, ro[i].what, err);
    cl_mem_flags use = CL_MEM_READ_WRITE | CL_MEM_USE_HOST_PTR;
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->x, CL_MEM_READ_ONLY, cl->nx * D, NULL, "position", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->vc, CL_MEM_READ_ONLY, cl->nx * D, NULL, "velocity", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->fit, CL_MEM_READ_WRITE, (size_t)cl->nfp * FIT_STRIDE * D, NULL,
                         "rigid fit", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->slot, CL_MEM_READ_WRITE, p->nslot * D, NULL, "slot", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->pivot, use, (size_t)cl->nfp * D, cl->pivot_host, "pivot", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->A, use, cl->nnz * D, cl->A_host, "matrix", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->B, use, 3 * nf * D, cl->B_host, "right-hand side", err);
    return rc;
}

/* ===== kernel arguments ================================================= */

/* restore_edges' τ: set here and again at every evaluation (it may change). */
#define RESTORE_ARG_TAU 5

#define ARG(k, i, v) (rc |= clSetKernelArg((k), (i), sizeof(v), &(v)))

static int set_args(iso_solver *s, iso_cl_assembler *cl, iso_err *err)
{
    cl_int rc = CL_SUCCESS;
    /* 1: the kernels' stride between a record's fields (assemble_cl_kernels.h) */
    cl_int weighting = s->o.weighting == ISO_WEIGHT_AREA, unit = 1;
    cl_double omega = s->o.omega, mu = s->o.restore_mu, tau = s->o.restore_tau;
    cl_int nb = cl->n_blocks, nf = s->nf, np = cl->np, nr = cl->nrp;
    cl_int hbase = cl->hbase;
    cl_kernel k = cl->k[K_FIT];
    ARG(k, 0, cl->fit_work), ARG(k, 1, weighting), ARG(k, 2, unit), ARG(k, 3, cl->x);
    ARG(k, 4, cl->fit), ARG(k, 5, cl->pivot);
    k = cl->k[K_PAIR];
    ARG(k, 0, cl->pair_work), ARG(k, 1, np), ARG(k, 2, omega), ARG(k, 3, unit);
    ARG(k, 4, cl->x), ARG(k, 5, cl->fit), ARG(k, 6, cl->slot);
    k = cl->k[K_RESTORE];
    ARG(k, 0, cl->rest_work), ARG(k, 1, cl->rest_lin), ARG(k, 2, cl->rest_par), ARG(k, 3, nr);
    ARG(k, 4, mu), ARG(k, RESTORE_ARG_TAU, tau), ARG(k, 6, unit), ARG(k, 7, cl->x);
    ARG(k, 8, cl->slot);
    k = cl->k[K_BLOCKS];
    ARG(k, 0, cl->blk_dst), ARG(k, 1, cl->blk_ptr), ARG(k, 2, nb), ARG(k, 3, cl->slot);
    ARG(k, 4, cl->A);
    k = cl->k[K_RHS];
    ARG(k, 0, cl->hb_ptr), ARG(k, 1, cl->hb_vtx), ARG(k, 2, cl->lin_ptr), ARG(k, 3, nf);
    ARG(k, 4, hbase), ARG(k, 5, cl->slot), ARG(k, 6, cl->vc), ARG(k, 7, cl->B);
    /* OR-ing error codes loses which one; any failure here is a bug. */
    return rc == CL_SUCCESS ? ISO_OK : cl_fail(err, "clSetKernelArg", rc);
}

/* ===== create / destroy ================================================= */

/* One assembly at the rest pose, its outcome dropped. PoCL builds each
 * kernel's work-group function at its first launch (tens of milliseconds,
 * more on a cold kernel cache): done here, that lands in the solver's
 * creation instead of the first evaluation, which in a real-time session
 * is its first tick, and in deform's per-evaluation figures. A failure to
 * run is reported; what the values are is not (the first evaluation
 * overwrites them). */
static int warm_up(iso_solver *s, iso_cl_assembler *cl, iso_err *err)
{
    double *vc = calloc(cl->nx + 1, sizeof *vc);
    if (!vc)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    iso_err e;
    iso_err_clear(&e);
    int rc = iso_solver__cl_assemble(cl, s, iso_mesh_positions(s->m), vc, &e);
    free(vc);
    if (rc == ISO_ENUMERIC) /* a degenerate rest pose is for the evaluation to report */
        return ISO_OK;
    if (rc != ISO_OK)
        return iso_err_set(err, rc, -1, "%s", e.msg);
    return ISO_OK;
}

int iso_solver__cl_create(iso_solver *s, iso_cl_assembler **out, iso_err *err)
{
    *out = NULL;
    iso_cl_assembler *cl = calloc(1, sizeof *cl);
    if (!cl)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    plan p;
    memset(&p, 0, sizeof p);
    cl->nf = s->nf;
    cl->nnz = (size_t)((int *)s->A->p)[3 * s->nf];
    cl->nx = 3 * (size_t)s->nv;
    cl_device_type kind = s->o.assembly == ISO_ASSEMBLY_AUTO
                              ? CL_DEVICE_TYPE_GPU | CL_DEVICE_TYPE_ACCELERATOR
                              : CL_DEVICE_TYPE_CPU;
    int rc = select_device(s->o.cl_device, kind, &cl->dev, err);
    if (rc == ISO_OK) {
        device_string(cl->dev, CL_DEVICE_NAME, cl->device, sizeof cl->device);
        rc = check_fp64(cl->dev, cl->device, err);
    }
    cl_int crc = CL_SUCCESS;
    if (rc == ISO_OK && !(cl->ctx = clCreateContext(NULL, 1, &cl->dev, NULL, NULL, &crc)))
        rc = cl_fail(err, "clCreateContext", crc);
    if (rc == ISO_OK && !(cl->q = clCreateCommandQueue(cl->ctx, cl->dev, 0, &crc)))
        rc = cl_fail(err, "clCreateCommandQueue", crc);
    if (rc == ISO_OK)
        rc = build_program(cl, err);
    if (rc == ISO_OK)
        rc = make_plan(s, cl, &p, err);
    if (rc == ISO_OK)
        rc = upload(s, cl, &p, err);
    if (rc == ISO_OK)
        rc = set_args(s, cl, err);
    iso_solver__cl_plan_free(&p);
    if (rc == ISO_OK)
        rc = warm_up(s, cl, err);
    if (rc != ISO_OK) {
        iso_solver__cl_destroy(cl);
        return rc;
    }
    *out = cl;
    return ISO_OK;
}

static void release_mem(cl_mem *m)
{
    if (*m)
        clReleaseMemObject(*m);
    *m = NULL;
}

/* Unmaps the value arrays so the kernels may write them again. */
static cl_int unmap_outputs(iso_cl_assembler *cl)
{
    if (!cl->mapped)
        return CL_SUCCESS;
    cl->mapped = 0;
    cl_int rc = clEnqueueUnmapMemObject(cl->q, cl->A, cl->A_host, 0, NULL, NULL);
    rc |= clEnqueueUnmapMemObject(cl->q, cl->B, cl->B_host, 0, NULL, NULL);
    rc |= clEnqueueUnmapMemObject(cl->q, cl->pivot, cl->pivot_host, 0, NULL, NULL);
    return rc;
}

void iso_solver__cl_destroy(iso_cl_assembler *cl)
{
    if (!cl)
        return;
    if (cl->q) {
        unmap_outputs(cl);
        clFinish(cl->q);
    }
    cl_mem *mems[] = {&cl->fit_work, &cl->pair_work, &cl->rest_work, &cl->rest_lin, &cl->rest_par,
                      &cl->blk_dst,  &cl->blk_ptr,   &cl->hb_ptr,    &cl->hb_vtx,   &cl->lin_ptr,
                      &cl->x,        &cl->vc,        &cl->fit,       &cl->slot,     &cl->pivot,
                      &cl->A,        &cl->B};
    for (size_t i = 0; i < sizeof mems / sizeof mems[0]; i++)
        release_mem(mems[i]);
    for (int i = 0; i < K_COUNT; i++)
        if (cl->k[i])
            clReleaseKernel(cl->k[i]);
    if (cl->prog)
        clReleaseProgram(cl->prog);
    if (cl->q)
        clReleaseCommandQueue(cl->q);
    if (cl->ctx)
        clReleaseContext(cl->ctx);
    free(cl->pivot_host);
    free(cl->first_el);
    free(cl->tri_of);
    free(cl);
}

/* ===== evaluation ======================================================= */

static cl_int run_kernel(iso_cl_assembler *cl, int which, int n)
{
    if (n == 0)
        return CL_SUCCESS;
    size_t local = cl->wg[which];
    size_t global = ((size_t)n + local - 1) / local * local;
    return clEnqueueNDRangeKernel(cl->q, cl->k[which], 1, NULL, &global, &local, 0, NULL, NULL);
}

/* The solver's A and B must be the arrays wrapped at creation. */
static int check_outputs(iso_solver *s, iso_cl_assembler *cl, iso_err *err)
{
    if (s->A->x == cl->A_host && s->B->x == cl->B_host)
        return ISO_OK;
    return iso_err_set(err, ISO_EINVAL, -1,
                       "OpenCL: internal error: the solver's matrix or right-hand side moved "
                       "since the OpenCL assembly was set up");
}

int iso_solver__cl_assemble(iso_cl_assembler *cl, iso_solver *s, const double *x, const double *vc,
                            iso_err *err)
{
    int rc = check_outputs(s, cl, err);
    if (rc != ISO_OK)
        return rc;
    cl_int crc = unmap_outputs(cl);
    if (crc != CL_SUCCESS)
        return cl_fail(err, "unmapping the matrix", crc);
    size_t bytes = cl->nx * sizeof(double);
    /* Non-blocking writes: the blocking map below waits for the whole
     * in-order queue, and x and vc outlive this call. */
    if ((crc = clEnqueueWriteBuffer(cl->q, cl->x, CL_FALSE, 0, bytes, x, 0, NULL, NULL)) ||
        (crc = clEnqueueWriteBuffer(cl->q, cl->vc, CL_FALSE, 0, bytes, vc, 0, NULL, NULL)))
        return cl_fail(err, "uploading positions", crc);
    /* τ may change between evaluations (iso_solver_set_restore_tau: the
     * integrators clamp it to κ h per step); the kernel reads it from here. */
    cl_double tau = s->o.restore_tau;
    if ((crc = clSetKernelArg(cl->k[K_RESTORE], RESTORE_ARG_TAU, sizeof tau, &tau)) != CL_SUCCESS)
        return cl_fail(err, "setting the restoration time constant", crc);
    if ((crc = run_kernel(cl, K_FIT, cl->n_fit ? cl->nfp : 0)) ||
        (crc = run_kernel(cl, K_PAIR, cl->n_pair ? cl->np : 0)) ||
        (crc = run_kernel(cl, K_RESTORE, cl->n_rest ? cl->nrp : 0)) ||
        (crc = run_kernel(cl, K_BLOCKS, cl->n_blocks)) || (crc = run_kernel(cl, K_RHS, cl->nf)))
        return cl_fail(err, "running the assembly kernels", crc);
    void *pa = clEnqueueMapBuffer(cl->q, cl->A, CL_FALSE, CL_MAP_READ, 0, cl->nnz * sizeof(double),
                                  0, NULL, NULL, &crc);
    void *pb = pa ? clEnqueueMapBuffer(cl->q, cl->B, CL_FALSE, CL_MAP_READ, 0,
                                       3 * (size_t)cl->nf * sizeof(double), 0, NULL, NULL, &crc)
                  : NULL;
    void *ps = pb ? clEnqueueMapBuffer(cl->q, cl->pivot, CL_TRUE, CL_MAP_READ, 0,
                                       (size_t)cl->n_fit * sizeof(double), 0, NULL, NULL, &crc)
                  : NULL;
    if (!pa || !pb || !ps)
        return cl_fail(err, "reading back the matrix", crc);
    cl->mapped = 1;
    /* A USE_HOST_PTR buffer maps at its host pointer (OpenCL 1.2, 5.4.2). */
    if (pa != (void *)cl->A_host || pb != (void *)cl->B_host || ps != (void *)cl->pivot_host)
        return iso_err_set(err, ISO_EIO, -1, "OpenCL: %s mapped a host-pointer buffer elsewhere",
                           cl->device);
    /* a fit is singular where its last pivot is not positive (fit_triangles) */
    int bad = -1;
    for (int f = 0; f < cl->n_fit; f++)
        if (!(cl->pivot_host[f] > 0) && (bad < 0 || cl->first_el[f] < cl->first_el[bad]))
            bad = f;
    if (bad >= 0)
        return iso_err_set(err, ISO_ENUMERIC, -1,
                           "%s: triangle %d has degenerated during the deformation (its "
                           "rigid fit is singular)",
                           iso_mesh_origin(s->m), cl->tri_of[bad]);
    return ISO_OK;
}

#else /* !ISO_WITH_OPENCL */

typedef int iso_assemble_cl_unused; /* ISO C forbids an empty translation unit */

#endif
