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
 * Where each element block goes is planned once, here: every 3x3 block an
 * element kernel computes has a slot (nine values, or a diagonal block's
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
#include "element_internal.h"
#include "solver_internal.h"

typedef iso_solver__element element;
typedef struct iso_cl_assembler iso_cl_assembler;
#define local_count iso_solver__local_count

/* The fit record and the pair flags are element_internal.h's, which the
 * kernels' FIT_STRIDE and CARRY_I/J repeat inside their source text. */
#define FIT_STRIDE ISO_ELEM__FIT_STRIDE
#define CARRY_I ISO_ELEM__EDGE_CARRY_I
#define CARRY_J ISO_ELEM__EDGE_CARRY_J
#define PAIR_ROWS 23 /* rows of the pair kernel's work list */
#define REST_ROWS 5  /* rows of the restoration kernel's work list */

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

/* ===== the plan: work lists and slots =================================== */

/* A block (or linear part) an element kernel computes, and the int of a
 * work list that gets the offset of its slot: key is the block of A_ff it
 * adds to (A), or the free vertex (handle blocks, linear parts); hv the
 * handle vertex of a handle block. */
typedef struct contrib {
    int key, hv;
    int *at;
} contrib;

enum { C_A, C_HANDLE, C_LIN, C_DUMP, C_KINDS };

/* Host-side lists built once; freed after upload. */
typedef struct plan {
    int *fit_work;    /* 4 per fit item */
    int *pair_work;   /* PAIR_ROWS rows of np */
    int *rest_work;   /* REST_ROWS rows of nrp: v0, v1, slots of blocks 00, 01, 11 */
    int *rest_lin;    /* 2 rows of nrp: slots of the linear parts at v0, v1 */
    double *rest_par; /* 2 rows of nrp: rest length, w_e */
    int *fit_of_tri;  /* per triangle: fit item or −1 */
    int *blk_of_pos;  /* per value of A: the block starting there, or −1 */
    int *blk_dst;     /* 4 per block */
    contrib *c[C_KINDS];
    size_t n[C_KINDS], cap[C_KINDS];
    int *blk_ptr, *hb_ptr, *hb_vtx, *lin_ptr;
    size_t nslot; /* doubles in the slot buffer */
} plan;

static void plan_free(plan *p)
{
    free(p->fit_work);
    free(p->pair_work);
    free(p->rest_work);
    free(p->rest_lin);
    free(p->rest_par);
    free(p->fit_of_tri);
    free(p->blk_of_pos);
    free(p->blk_dst);
    for (int k = 0; k < C_KINDS; k++)
        free(p->c[k]);
    free(p->blk_ptr);
    free(p->hb_ptr);
    free(p->hb_vtx);
    free(p->lin_ptr);
}

/* Fit item of triangle t (made on first use); `el` the element index that
 * uses it, so a degenerate triangle is reported as the C path reports it. */
static int fit_item(iso_cl_assembler *cl, plan *p, const int *tri, int t, int el)
{
    int f = p->fit_of_tri[t];
    if (f < 0) {
        f = p->fit_of_tri[t] = cl->n_fit++;
        memcpy(p->fit_work + 4 * f, tri + 3 * t, 3 * sizeof(int));
        p->fit_work[4 * f + 3] = 0;
        cl->first_el[f] = el;
        cl->tri_of[f] = t;
    }
    if (el < cl->first_el[f])
        cl->first_el[f] = el;
    return f;
}

static int add_contrib(plan *p, int kind, int key, int hv, int *at)
{
    if (p->n[kind] == p->cap[kind]) {
        size_t cap = p->cap[kind] ? 2 * p->cap[kind] : 1024;
        contrib *c = realloc(p->c[kind], cap * sizeof *c);
        if (!c)
            return -1;
        p->c[kind] = c;
        p->cap[kind] = cap;
    }
    p->c[kind][p->n[kind]++] = (contrib){key, hv, at};
    return 0;
}

/* Plans block (la, lb) of element e (local vertices; the block's rows are
 * la's): its slot offset goes to *at, and, if step is not NULL, the step
 * between its rows in the slot, 3, or 1 where it is to be written
 * transposed (the rows of lb), since a slot holds the rows of the lower
 * free index (A), or of the free vertex (handle block). */
static int plan_block(const iso_solver *s, plan *p, const element *e, int la, int lb, int *at,
                      int *step)
{
    int nl = local_count(e), va = e->v[la], vb = e->v[lb];
    int fa = s->free_of[va], fb = s->free_of[vb];
    const int *sl = s->slots + e->slot;
    if (step)
        *step = 3;
    if (fa >= 0 && fb >= 0) {
        int lo = fa <= fb ? la : lb, hi = lo == la ? lb : la;
        if (step && fa > fb)
            *step = 1;
        return add_contrib(p, C_A, p->blk_of_pos[sl[3 * (lo * nl + hi)]], 0, at);
    }
    if (la != lb && (fa >= 0) != (fb >= 0)) {
        int f = fa >= 0 ? fa : fb, h = fa >= 0 ? vb : va;
        if (s->r->kind[h] == ISO_HANDLE) {
            if (step && fb >= 0)
                *step = 1;
            return add_contrib(p, C_HANDLE, f, h, at);
        }
    }
    return add_contrib(p, C_DUMP, 0, 0, at);
}

/* Numbers the slots of one kind: stable by key, so that each key's slots
 * are consecutive, in the order planned (element-list order). From offset
 * `base` on, `size` doubles a slot, or 6 where `diag` (A's blocks, may be
 * NULL) flags the key as a diagonal block. ptr (nkeys + 1) gets the offset
 * of each key's first slot, hv (may be NULL) each slot's handle vertex. */
static int number_slots(plan *p, int kind, int nkeys, const int *diag, int base, int size,
                        int **ptr, int **hv)
{
    size_t n = p->n[kind];
    const contrib *c = p->c[kind];
    int *count = calloc((size_t)nkeys + 1, sizeof *count);
    int *next = malloc(((size_t)nkeys + 1) * sizeof *next);
    *ptr = malloc(((size_t)nkeys + 1) * sizeof **ptr);
    if (!count || !next || !*ptr || (hv && !(*hv = malloc((n + 1) * sizeof **hv)))) {
        free(count);
        free(next);
        return -1;
    }
    for (size_t i = 0; i < n; i++)
        count[c[i].key]++;
    int at = base, slots = 0;
    for (int k = 0; k < nkeys; k++) {
        int nk = count[k];
        (*ptr)[k] = next[k] = at;
        at += nk * (diag && diag[4 * k + 3] ? 6 : size);
        count[k] = slots; /* now: the number of k's first slot */
        slots += nk;
    }
    (*ptr)[nkeys] = at;
    for (size_t i = 0; i < n; i++) {
        int k = c[i].key;
        *c[i].at = next[k];
        next[k] += diag && diag[4 * k + 3] ? 6 : size;
        if (hv)
            (*hv)[count[k]++] = c[i].hv;
    }
    free(count);
    free(next);
    return 0;
}

/* The 3x3 blocks of A_ff in column order: block j of column block fb starts
 * at Ap[3fb + k] + 3j in column 3fb + k; the diagonal block comes last. */
static int find_blocks(const iso_solver *s, iso_cl_assembler *cl, plan *p)
{
    const int *Ap = s->A->p;
    p->blk_of_pos = malloc((cl->nnz + 1) * sizeof *p->blk_of_pos);
    int nb = 0;
    for (int f = 0; f < s->nf; f++)
        nb += (Ap[3 * f + 1] - Ap[3 * f] - 1) / 3 + 1;
    p->blk_dst = malloc(((size_t)nb + 1) * 4 * sizeof *p->blk_dst);
    if (!p->blk_of_pos || !p->blk_dst)
        return -1;
    for (size_t i = 0; i < cl->nnz; i++)
        p->blk_of_pos[i] = -1;
    int b = 0;
    for (int f = 0; f < s->nf; f++) {
        int n = (Ap[3 * f + 1] - Ap[3 * f] - 1) / 3 + 1;
        for (int j = 0; j < n; j++, b++) {
            for (int k = 0; k < 3; k++)
                p->blk_dst[4 * b + k] = Ap[3 * f + k] + 3 * j;
            p->blk_dst[4 * b + 3] = j == n - 1;
            p->blk_of_pos[Ap[3 * f] + 3 * j] = b;
        }
    }
    cl->n_blocks = nb;
    return 0;
}

/* Pads a work list of `rows` rows from n items to np (whole work-groups):
 * a padding item repeats item 0, but its slots (rows slot0 to slot0 +
 * nslots − 1) are slots of its own that nothing reads. */
static int pad_items(plan *p, int *work, int rows, int n, int np, int slot0, int nslots)
{
    for (int j = n; j < np; j++)
        for (int r = 0; r < rows; r++) {
            work[r * np + j] = work[r * np];
            if (r >= slot0 && r < slot0 + nslots &&
                add_contrib(p, C_DUMP, 0, 0, &work[r * np + j]) != 0)
                return -1;
        }
    return 0;
}

static size_t padded(int n, size_t wg)
{
    return ((size_t)n + wg - 1) / wg * wg;
}

/* The pair elements' indices (the first of each mirrored two) in
 * element-list order, into *out (n of them). */
static int pair_elements(const iso_solver *s, int **out, int *n, iso_err *err)
{
    *n = 0;
    *out = malloc(((size_t)s->nel + 1) * sizeof **out);
    if (!*out)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 2) {
            if (i + 1 >= s->nel || !iso_solver__is_mirror(&s->el[i], &s->el[i + 1]))
                return iso_err_set(err, ISO_EINVAL, -1,
                                   "OpenCL: internal error: pair element %d has no mirror", i);
            (*out)[(*n)++] = i++;
        }
    return ISO_OK;
}

/* The pair items in Z-order (iso_solver__z_order: what one item touches in
 * x, the fit records and the slots, the next ones touch again; the slots
 * of one block are in this order too). Each triangle element's Q1 goes
 * with the first pair element, in element-list order, whose Ti or Tj it
 * is, as on the C path (q1_el: the element, −1 once carried). */
static int plan_pairs(iso_solver *s, iso_cl_assembler *cl, plan *p, int *q1_el, iso_err *err)
{
    const int *tri = iso_mesh_triangles(s->m);
    int n, *pe = NULL;
    int rc = pair_elements(s, &pe, &n, err);
    int np = cl->np = (int)padded(n, cl->wg[K_PAIR]);
    int *carry = malloc(((size_t)n + 1) * sizeof *carry),
        *ends = malloc(2 * ((size_t)n + 1) * sizeof *ends);
    int *order = malloc(((size_t)n + 1) * sizeof *order);
    p->pair_work = malloc(((size_t)PAIR_ROWS * (size_t)np + 1) * sizeof(int));
    if (rc == ISO_OK && (!carry || !ends || !order || !p->pair_work))
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int k = 0; k < n && rc == ISO_OK; k++) {
        const element *e = &s->el[pe[k]];
        int ti = e->tri, tj = s->el[pe[k] + 1].tri, map[4];
        carry[k] = (q1_el[ti] >= 0 ? CARRY_I : 0) | (q1_el[tj] >= 0 ? CARRY_J : 0);
        if (q1_el[ti] >= 0)
            q1_el[ti] = -1;
        if (q1_el[tj] >= 0)
            q1_el[tj] = -1;
        iso_solver__edge_layout(e, map);
        ends[k] = e->v[map[0]];
        ends[n + k] = e->v[map[1]];
    }
    if (rc == ISO_OK && iso_solver__z_order(s->m, n, ends, ends + n, order) != 0)
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    int *w = p->pair_work;
    for (int j = 0; j < n && rc == ISO_OK; j++) {
        int k = order[j], i = pe[k];
        const element *e = &s->el[i];
        int ti = e->tri, tj = s->el[i + 1].tri, map[4];
        /* the edge layout (a, b, p, q): the shared edge in Ti's order,
         * Ti's third corner, Tj's third corner */
        iso_solver__edge_layout(e, map);
        for (int l = 0; l < 4; l++)
            w[l * np + j] = e->v[map[l]];
        w[4 * np + j] = fit_item(cl, p, tri, ti, i);
        w[5 * np + j] = fit_item(cl, p, tri, tj, i + 1);
        w[6 * np + j] = carry[k];
        for (int l = 0, b = 0, o = 0; l < 4 && rc == ISO_OK; l++)
            for (int m = l; m < 4 && rc == ISO_OK; m++, b++) {
                int *step = l != m ? &w[(17 + o++) * np + j] : NULL;
                if (plan_block(s, p, e, map[l], map[m], &w[(7 + b) * np + j], step) != 0)
                    rc = iso_err_set(err, ISO_ENOMEM, -1,
                                     "out of memory planning the OpenCL assembly");
            }
        cl->n_pair++;
    }
    if (rc == ISO_OK && n > 0 && pad_items(p, w, PAIR_ROWS, n, np, 7, 10) != 0)
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int j = n; j < np && rc == ISO_OK; j++) /* padding carries no Q1 */
        w[6 * np + j] = 0;
    free(pe);
    free(carry);
    free(ends);
    free(order);
    return rc;
}

/* The restoration items, in element-list order. */
static int plan_restoration(iso_solver *s, iso_cl_assembler *cl, plan *p, iso_err *err)
{
    int n = 0;
    for (int i = 0; i < s->nel; i++)
        n += s->el[i].kind == 3;
    int nr = cl->nrp = (int)padded(n, cl->wg[K_RESTORE]);
    p->rest_work = malloc(((size_t)REST_ROWS * (size_t)nr + 1) * sizeof(int));
    p->rest_lin = malloc((2 * (size_t)nr + 1) * sizeof(int));
    p->rest_par = malloc((2 * (size_t)nr + 1) * sizeof(double));
    if (!p->rest_work || !p->rest_lin || !p->rest_par)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    int *w = p->rest_work, *lin = p->rest_lin;
    for (int i = 0; i < s->nel; i++) {
        const element *e = &s->el[i];
        if (e->kind != 3)
            continue;
        int j = cl->n_rest++, rc = 0;
        w[j] = e->v[0];
        w[nr + j] = e->v[1];
        p->rest_par[j] = s->rest_len[e->tri];
        p->rest_par[nr + j] = s->edge_w[e->tri];
        /* blocks 00, 01, 11: symmetric, so never written transposed */
        rc |= plan_block(s, p, e, 0, 0, &w[2 * nr + j], NULL);
        rc |= plan_block(s, p, e, 0, 1, &w[3 * nr + j], NULL);
        rc |= plan_block(s, p, e, 1, 1, &w[4 * nr + j], NULL);
        for (int end = 0; end < 2; end++) {
            int f = s->free_of[e->v[end]];
            rc |= add_contrib(p, f >= 0 ? C_LIN : C_DUMP, f, 0, &lin[end * nr + j]);
        }
        if (rc != 0)
            return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    }
    if (n > 0 &&
        (pad_items(p, w, REST_ROWS, n, nr, 2, 3) != 0 || pad_items(p, lin, 2, n, nr, 0, 2) != 0))
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int j = n; j < nr; j++) {
        p->rest_par[j] = p->rest_par[0];
        p->rest_par[nr + j] = p->rest_par[nr];
    }
    return ISO_OK;
}

/* Numbers A's blocks in the order the element kernels first add to them,
 * so that the slots of the blocks an item adds to lie near those of the
 * items before it (its neighbours, in Z-order), instead of all over the
 * buffer at A's column order: fewer lines fetched for the scattered
 * writes. reduce_blocks runs in this order too; each block's place in A is
 * in its blk_dst. */
static int order_blocks(iso_cl_assembler *cl, plan *p)
{
    int nb = cl->n_blocks, next = 0;
    int *renum = malloc(((size_t)nb + 1) * sizeof *renum);
    int *dst = malloc(4 * ((size_t)nb + 1) * sizeof *dst);
    if (!renum || !dst) {
        free(renum);
        free(dst);
        return -1;
    }
    for (int b = 0; b < nb; b++)
        renum[b] = -1;
    for (size_t i = 0; i < p->n[C_A]; i++)
        if (renum[p->c[C_A][i].key] < 0)
            renum[p->c[C_A][i].key] = next++;
    for (int b = 0; b < nb; b++) /* one no element adds to: none, in practice */
        if (renum[b] < 0)
            renum[b] = next++;
    for (size_t i = 0; i < p->n[C_A]; i++)
        p->c[C_A][i].key = renum[p->c[C_A][i].key];
    for (int b = 0; b < nb; b++)
        memcpy(dst + 4 * renum[b], p->blk_dst + 4 * b, 4 * sizeof *dst);
    free(p->blk_dst);
    p->blk_dst = dst;
    free(renum);
    return 0;
}

/* The slots: A's blocks, handle blocks, linear parts, then the slots
 * nothing reads, each numbered in element-list order within its key. */
static int plan_slots(iso_solver *s, iso_cl_assembler *cl, plan *p, iso_err *err)
{
    size_t most = 9 * (p->n[C_A] + p->n[C_HANDLE] + p->n[C_DUMP]) + 3 * p->n[C_LIN];
    if (most > INT_MAX)
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "OpenCL: the slot buffer (%zu values) is too large for int offsets",
                           most);
    for (size_t i = 0; i < p->n[C_A]; i++)
        if (p->c[C_A][i].key < 0)
            return iso_err_set(err, ISO_EINVAL, -1,
                               "OpenCL: internal error: an element block is not in the pattern");
    if (order_blocks(cl, p) != 0)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    if (number_slots(p, C_A, cl->n_blocks, p->blk_dst, 0, 9, &p->blk_ptr, NULL) != 0 ||
        number_slots(p, C_HANDLE, s->nf, NULL, cl->hbase = p->blk_ptr[cl->n_blocks], 9, &p->hb_ptr,
                     &p->hb_vtx) != 0 ||
        number_slots(p, C_LIN, s->nf, NULL, p->hb_ptr[s->nf], 3, &p->lin_ptr, NULL) != 0)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    size_t dbase = (size_t)p->lin_ptr[s->nf];
    for (size_t i = 0; i < p->n[C_DUMP]; i++)
        *p->c[C_DUMP][i].at = (int)(dbase + 9 * i);
    p->nslot = dbase + 9 * p->n[C_DUMP];
    return ISO_OK;
}

/* Builds the work lists of the three element kernels and the slots. */
static int make_plan(iso_solver *s, iso_cl_assembler *cl, plan *p, iso_err *err)
{
    int nt = iso_mesh_triangle_count(s->m);
    p->fit_work = malloc(4 * ((size_t)nt + 1 + cl->wg[K_FIT]) * sizeof(int));
    p->fit_of_tri = malloc(((size_t)nt + 1) * sizeof(int));
    cl->first_el = malloc(((size_t)nt + 1) * sizeof(int));
    cl->tri_of = malloc(((size_t)nt + 1) * sizeof(int));
    int *q1_el = malloc(((size_t)nt + 1) * sizeof *q1_el);
    if (!p->fit_work || !p->fit_of_tri || !cl->first_el || !cl->tri_of || !q1_el ||
        find_blocks(s, cl, p) != 0) {
        free(q1_el);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    }
    for (int t = 0; t < nt; t++)
        p->fit_of_tri[t] = q1_el[t] = -1;
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 1)
            q1_el[s->el[i].tri] = i;
    /* The fit items: made in the pair items' order (plan_pairs), so that
     * neighbours' records are near each other; then every element's
     * triangle, so that each knows the first element that uses it. */
    int rc = plan_pairs(s, cl, p, q1_el, err);
    const int *tri = iso_mesh_triangles(s->m);
    for (int i = 0; i < s->nel && rc == ISO_OK; i++)
        if (s->el[i].kind == 1 || s->el[i].kind == 2)
            fit_item(cl, p, tri, s->el[i].tri, i);
    /* Every triangle element's Q1 goes with one of its interior edges. There
     * always is one: a triangle with no interior edge is a part of the mesh
     * of its own, which iso_solver_create refuses unless its three vertices
     * are constrained, and then it is no element. */
    for (int t = 0; t < nt && rc == ISO_OK; t++)
        if (q1_el[t] >= 0)
            rc = iso_err_set(err, ISO_EINVAL, -1,
                             "OpenCL: internal error: triangle %d is an element, but no "
                             "interior edge carries it",
                             t);
    free(q1_el);
    if (rc == ISO_OK)
        rc = plan_restoration(s, cl, p, err);
    if (rc == ISO_OK)
        rc = plan_slots(s, cl, p, err);
    if (rc != ISO_OK)
        return rc;
    cl->nfp = (int)padded(cl->n_fit, cl->wg[K_FIT]);
    for (int f = cl->n_fit; f < cl->nfp; f++) /* padding: item 0 again, into its own record */
        memcpy(p->fit_work + 4 * f, p->fit_work, 4 * sizeof(int));
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
        {&cl->pair_work, p->pair_work, PAIR_ROWS * (size_t)cl->np * I, "pair list"},
        {&cl->rest_work, p->rest_work, REST_ROWS * (size_t)cl->nrp * I, "edge list"},
        {&cl->rest_lin, p->rest_lin, 2 * (size_t)cl->nrp * I, "edge list"},
        {&cl->rest_par, p->rest_par, 2 * (size_t)cl->nrp * D, "edge parameter"},
        {&cl->blk_dst, p->blk_dst, 4 * (size_t)cl->n_blocks * I, "block"},
        {&cl->blk_ptr, p->blk_ptr, ((size_t)cl->n_blocks + 1) * I, "block slot"},
        {&cl->hb_ptr, p->hb_ptr, (nf + 1) * I, "handle slot"},
        {&cl->hb_vtx, p->hb_vtx, p->n[C_HANDLE] * I, "handle vertex"},
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
    plan_free(&p);
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
