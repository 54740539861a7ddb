/* solver/assemble_cl.c -- the OpenCL assembly path (solver_internal.h).
 *
 * Per evaluation, three kernels fill an element buffer and two reduce it:
 *   fit_triangles  per triangle: the rigid fit (kept in a fit buffer, so
 *                  it is computed once per evaluation however many pairs
 *                  use it);
 *   pair_edges     per interior edge: ω(Q2_ij + Q2_ji) in the closed form of
 *                  iso_elem_edge_from_fits; both ordered pairs share the
 *                  same four vertices, so one record serves both. It also
 *                  adds (1−ω)Q1 of Ti and Tj where it carries them: every
 *                  triangle element is carried by one of its interior
 *                  edges, whose blocks include all of its own, so Q1 has
 *                  no records (a third of the buffer's bytes, and the
 *                  kernels' time is mostly the buffer's traffic);
 *   restore_edges  per edge, with restoration on: μ times its block and
 *                  its linear part;
 *   reduce_blocks  per 3x3 block of A_ff, reduce_rhs per free vertex: sum
 *                  the records listed for it in a gather map (CSR) built
 *                  once here from the slot map, in a fixed order.
 * Every record holds only what reaches A_ff or the right-hand side, already
 * weighted: upper 3x3 diagonal blocks, off-diagonal blocks with the rows of
 * their first vertex (the gather map lists a block whose other vertex has
 * the lower free index as −offset − 1, and reduce_blocks reads it
 * transposed), and per vertex the triple −Σ_handles Q vc (+ the
 * restoration's linear part).
 * The element kernels are written so that PoCL runs the work-items of a
 * group as vector lanes (check with POCL_VECTORIZER_REMARKS=1): their items
 * are padded to whole work-groups (no bounds check), nothing branches on
 * the data (selects instead, a singular fit is a status, not an early
 * return), every loop is unrolled and every helper inlined, so private
 * arrays are registers, and square roots are Clang's builtin (an
 * instruction; PoCL's sqrt is a call).
 * The reductions write every entry of A's value array and of B, straight
 * into s->A->x and s->B->x (wrapped as CL_MEM_USE_HOST_PTR buffers and left
 * mapped for reading between evaluations), so there are no atomics, no
 * host-side scatter and no allocation per evaluation, and the sums are
 * bit-identical from run to run. */
#ifdef ISO_WITH_OPENCL

#include <ctype.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <CL/cl.h>

#include "assemble_cl_kernels.h"
#include "solver_internal.h"

typedef iso_solver__element element;
typedef struct iso_cl_assembler iso_cl_assembler;
#define local_count iso_solver__local_count

/* Record sizes (doubles) for 2, 3, 4 local vertices: 6 per diagonal block,
 * 9 per pair of vertices, 3 right-hand-side values per vertex. */
#define RECORD_SIZE(nl) (6 * (nl) + 9 * ((nl) * ((nl)-1) / 2) + 3 * (nl))
#define FIT_STRIDE 16 /* must match the kernels' FIT_STRIDE */
#define VF_FIXED (-1)
#define VF_HANDLE (-2)

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
    cl_mem vflag, fit_work, pair_work, rest_work, rest_par;
    cl_mem blk_dst, blk_ptr, blk_src, rhs_ptr, rhs_src;
    /* per evaluation */
    cl_mem x, vc, fit, elem, status;
    cl_mem A, B; /* wrap s->A->x and s->B->x */
    double *A_host, *B_host;
    size_t nnz, nx;
    int n_fit, n_pair, n_rest, n_blocks, nf;
    int np;        /* pair items padded to whole work-groups */
    int nfp;       /* fit items padded to whole work-groups */
    int nrp;       /* restoration items padded to whole work-groups */
    int pair_base; /* the first pair record in the element buffer */
    int mapped;
    int *status_host; /* n_fit, wrapped by `status` */
    int *first_el;    /* per fit item: first element (list order) using it as Ti or Q1 */
    int *tri_of;      /* per fit item: its triangle */
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

/* Picks the device opts.cl_device asks for (iso_solver.h). ISO_ENOTSUP with
 * the reason when there is none. */
static int select_device(const char *want, cl_device_id *out, iso_err *err)
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
                    !(type & CL_DEVICE_TYPE_CPU))
                    continue;
            }
            *out = dev[d];
            return ISO_OK;
        }
    }
    if (want)
        return iso_err_set(err, ISO_ENOTSUP, -1, "no device or platform name contains \"%s\"",
                           want);
    return iso_err_set(err, ISO_ENOTSUP, -1, "no CPU device found on %u platform(s)", np);
}

/* The kernels need doubles; a device without them cannot run this path. */
static int check_fp64(cl_device_id dev, const char *name, iso_err *err)
{
    cl_device_fp_config fp = 0;
    if (clGetDeviceInfo(dev, CL_DEVICE_DOUBLE_FP_CONFIG, sizeof fp, &fp, NULL) != CL_SUCCESS)
        fp = 0;
    if (fp == 0)
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

/* ===== work lists and gather maps ======================================= */

/* Host-side lists built once; freed after upload. */
typedef struct plan {
    int *fit_work;  /* 4 per fit item */
    int *pair_work; /* 6 rows of np: the pair items, value-major */
    int *rest_work; /* 4 per restoration item */
    double *rest_par;
    int *fit_of_tri; /* per triangle: fit item or −1 */
    int *blk_of_pos; /* per value of A: the block starting there, or −1 */
    int *blk_dst;    /* 4 per block */
    int *gb, *go;    /* (block, record offset) contributions, in work order */
    int *gr, *gro;   /* (free vertex, record offset) contributions */
    size_t ngb, ngr, nrec;
    int *blk_ptr, *blk_src, *rhs_ptr, *rhs_src;
} plan;

static void plan_free(plan *p)
{
    free(p->fit_work);
    free(p->pair_work);
    free(p->rest_work);
    free(p->rest_par);
    free(p->fit_of_tri);
    free(p->blk_of_pos);
    free(p->blk_dst);
    free(p->gb);
    free(p->go);
    free(p->gr);
    free(p->gro);
    free(p->blk_ptr);
    free(p->blk_src);
    free(p->rhs_ptr);
    free(p->rhs_src);
}

/* Fit item of triangle t (made on first use); `el` the element index that
 * uses it, so a degenerate triangle is reported as the C path reports it. */
static int fit_item(iso_cl_assembler *cl, plan *p, const int *tri, int t, int el)
{
    int f = p->fit_of_tri[t];
    if (f < 0) {
        f = p->fit_of_tri[t] = cl->n_fit++;
        memcpy(p->fit_work + 4 * f, tri + 3 * t, 3 * sizeof(int));
        p->fit_work[4 * f + 3] = -1;
        cl->first_el[f] = el;
        cl->tri_of[f] = t;
    }
    if (el < cl->first_el[f])
        cl->first_el[f] = el;
    return f;
}

/* Records where a record's blocks and right-hand-side triples go. The
 * record's local vertex x is element e's local vertex map[x] (nl of them);
 * the record sits at offset `rec`. */
static void gather_record(const iso_solver *s, plan *p, const element *e, const int *map, int nl,
                          int rec, int force_rhs)
{
    int enl = local_count(e), pair = 0, handle = force_rhs;
    const int *sl = s->slots + e->slot;
    int fv[4];
    for (int a = 0; a < nl; a++) {
        int v = e->v[map[a]];
        fv[a] = s->free_of[v];
        handle |= fv[a] < 0 && s->r->kind[v] == ISO_HANDLE;
    }
    for (int a = 0; a < nl; a++)
        if (fv[a] >= 0) {
            p->gb[p->ngb] = p->blk_of_pos[sl[3 * (map[a] * enl + map[a])]];
            p->go[p->ngb++] = rec + 6 * a;
        }
    for (int a = 0; a < nl; a++)
        for (int b = a + 1; b < nl; b++, pair++) {
            if (fv[a] < 0 || fv[b] < 0)
                continue;
            int lo = fv[a] < fv[b] ? map[a] : map[b], hi = fv[a] < fv[b] ? map[b] : map[a];
            int off = rec + 6 * nl + 9 * pair; /* rows of a, columns of b */
            p->gb[p->ngb] = p->blk_of_pos[sl[3 * (lo * enl + hi)]];
            p->go[p->ngb++] = fv[a] < fv[b] ? off : -off - 1; /* rows of b: transposed */
        }
    if (!handle)
        return;
    for (int a = 0; a < nl; a++)
        if (fv[a] >= 0) {
            p->gr[p->ngr] = fv[a];
            p->gro[p->ngr++] = rec + 6 * nl + 9 * pair + 3 * a;
        }
}

/* Stable counting sort of (key, value) into CSR: order within a key is the
 * order of contribution, which is what makes the sums reproducible. */
static int make_csr(const int *key, const int *val, size_t n, int nkeys, int **ptr, int **src)
{
    *ptr = calloc((size_t)nkeys + 1, sizeof **ptr);
    *src = malloc((n + 1) * sizeof **src);
    int *cur = malloc(((size_t)nkeys + 1) * sizeof *cur);
    if (!*ptr || !*src || !cur) {
        free(cur);
        return -1;
    }
    for (size_t i = 0; i < n; i++)
        (*ptr)[key[i] + 1]++;
    for (int k = 0; k < nkeys; k++)
        (*ptr)[k + 1] += (*ptr)[k];
    memcpy(cur, *ptr, (size_t)nkeys * sizeof *cur);
    for (size_t i = 0; i < n; i++)
        (*src)[cur[key[i]]++] = val[i];
    free(cur);
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

/* Builds the work lists for the three element kernels and the gather maps
 * of the two reductions, in element-list order. */
static int make_plan(iso_solver *s, iso_cl_assembler *cl, plan *p, iso_err *err)
{
    const iso_mesh *m = s->m;
    int nt = iso_mesh_triangle_count(m), nel = s->nel;
    const int *tri = iso_mesh_triangles(m);
    size_t cap = (size_t)nel + 1;
    p->fit_work = malloc(4 * ((size_t)nt + 1 + cl->wg[K_FIT]) * sizeof(int));
    p->fit_of_tri = malloc(((size_t)nt + 1) * sizeof(int));
    cl->first_el = malloc(((size_t)nt + 1) * sizeof(int));
    cl->tri_of = malloc(((size_t)nt + 1) * sizeof(int));
    p->rest_work = malloc(4 * (cap + cl->wg[K_RESTORE]) * sizeof(int));
    p->rest_par = malloc(2 * (cap + cl->wg[K_RESTORE]) * sizeof(double));
    p->gb = malloc(10 * cap * sizeof(int));
    p->go = malloc(10 * cap * sizeof(int));
    p->gr = malloc(4 * cap * sizeof(int));
    p->gro = malloc(4 * cap * sizeof(int));
    if (!p->fit_work || !p->fit_of_tri || !cl->first_el || !cl->tri_of || !p->rest_work ||
        !p->rest_par || !p->gb || !p->go || !p->gr || !p->gro || find_blocks(s, cl, p) != 0)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int t = 0; t < nt; t++)
        p->fit_of_tri[t] = -1;

    /* The fit items first, padded to whole work-groups. */
    for (int i = 0; i < nel; i++) {
        const element *e = &s->el[i];
        if (e->kind == 1 || e->kind == 2)
            fit_item(cl, p, tri, e->tri, i);
        if (e->kind == 2 && i + 1 < nel && iso_solver__is_mirror(e, &s->el[i + 1])) {
            fit_item(cl, p, tri, s->el[i + 1].tri, i + 1);
            i++;
        }
    }
    size_t wgf = cl->wg[K_FIT];
    cl->nfp = (int)(((size_t)cl->n_fit + wgf - 1) / wgf * wgf);
    for (int f = 0; f < cl->nfp; f++) {
        if (f >= cl->n_fit) /* padding: item 0 again */
            memcpy(p->fit_work + 4 * f, p->fit_work, 3 * sizeof(int));
        p->fit_work[4 * f + 3] = 0;
    }
    /* Which pair item carries each triangle element's Q1: the first whose
     * Ti or Tj it is (q1_el: the element, −1 once carried). */
    int *q1_el = malloc(((size_t)nt + 1) * sizeof *q1_el);
    if (!q1_el)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    for (int t = 0; t < nt; t++)
        q1_el[t] = -1;
    for (int i = 0; i < nel; i++)
        if (s->el[i].kind == 1)
            q1_el[s->el[i].tri] = i;
    size_t rec = 0;
    /* Pair items are padded to np, whole work-groups, so that the kernel
     * needs no bounds check; their work list is value-major over np. */
    int n_items = 0;
    for (int i = 0; i < nel; i++)
        if (s->el[i].kind == 2) {
            n_items++;
            i += i + 1 < nel && iso_solver__is_mirror(&s->el[i], &s->el[i + 1]);
        }
    size_t wg = cl->wg[K_PAIR];
    cl->np = (int)(((size_t)n_items + wg - 1) / wg * wg);
    int np = cl->np;
    p->pair_work = malloc(8 * ((size_t)np + 1) * sizeof(int));
    if (!p->pair_work) {
        free(q1_el);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
    }
    /* Each triangle element's Q1 goes with the first pair item whose Ti or
     * Tj it is. There always is one: a triangle with no interior edge is a
     * part of the mesh of its own, which iso_solver_create refuses unless
     * its three vertices are constrained, and then it is no element. */
    for (int i = 0, j = 0; i < nel; i++) {
        const element *e = &s->el[i];
        if (e->kind != 2)
            continue;
        int ti = e->tri, tj = -1;
        if (i + 1 < nel && iso_solver__is_mirror(e, &s->el[i + 1]))
            tj = s->el[++i].tri;
        p->pair_work[6 * np + j] = q1_el[ti] >= 0;
        if (q1_el[ti] >= 0)
            q1_el[ti] = -1;
        p->pair_work[7 * np + j] = tj >= 0 && q1_el[tj] >= 0;
        if (tj >= 0 && q1_el[tj] >= 0)
            q1_el[tj] = -1;
        j++;
    }
    for (int t = 0; t < nt; t++)
        if (q1_el[t] >= 0) {
            free(q1_el);
            return iso_err_set(err, ISO_EINVAL, -1,
                               "OpenCL: internal error: triangle %d is an element, but no "
                               "interior edge carries it",
                               t);
        }
    free(q1_el);
    int pair_base = (int)rec;
    for (int i = 0; i < nel; i++) {
        const element *e = &s->el[i];
        if (e->kind != 2)
            continue;
        /* Record order (a, b, p, q): the shared edge in Ti's order, Ti's
         * third corner, Tj's third corner; so the kernel's indices are
         * constants. map: record local -> e's local. */
        int map[4], j = cl->n_pair;
        iso_solver__edge_layout(e, map);
        for (int l = 0; l < 4; l++)
            p->pair_work[l * np + j] = e->v[map[l]];
        p->pair_work[4 * np + j] = fit_item(cl, p, tri, e->tri, i);
        p->pair_work[5 * np + j] = -1;
        if (i + 1 < nel && iso_solver__is_mirror(e, &s->el[i + 1])) {
            p->pair_work[5 * np + j] = fit_item(cl, p, tri, s->el[i + 1].tri, i + 1);
            i++;
        }
        gather_record(s, p, e, map, 4, (int)rec + RECORD_SIZE(4) * j, 0);
        cl->n_pair++;
    }
    for (int j = cl->n_pair; j < np; j++) /* padding: item 0 again, without mirror or Q1 */
        for (int r = 0; r < 8; r++)
            p->pair_work[r * np + j] = r >= 5 ? (r == 5 ? -1 : 0) : p->pair_work[r * np];
    rec += (size_t)RECORD_SIZE(4) * (size_t)np;
    cl->pair_base = pair_base;
    for (int i = 0; i < nel; i++) {
        const element *e = &s->el[i];
        if (e->kind != 3)
            continue;
        int *w = p->rest_work + 4 * cl->n_rest;
        w[0] = e->v[0];
        w[1] = e->v[1];
        w[2] = (int)rec;
        w[3] = 0;
        p->rest_par[2 * cl->n_rest] = s->rest_len[e->tri];
        p->rest_par[2 * cl->n_rest + 1] = s->edge_w[e->tri];
        static const int id[2] = {0, 1};
        gather_record(s, p, e, id, 2, (int)rec, 1);
        rec += RECORD_SIZE(2);
        cl->n_rest++;
    }
    /* padding to whole work-groups: item 0 again, into records of its own */
    size_t wgr = cl->wg[K_RESTORE];
    cl->nrp = (int)(((size_t)cl->n_rest + wgr - 1) / wgr * wgr);
    for (int j = cl->n_rest; j < cl->nrp; j++) {
        memcpy(p->rest_work + 4 * j, p->rest_work, 4 * sizeof(int));
        memcpy(p->rest_par + 2 * j, p->rest_par, 2 * sizeof(double));
        p->rest_work[4 * j + 2] = (int)rec;
        rec += RECORD_SIZE(2);
    }
    if (rec > INT_MAX)
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "OpenCL: the element buffer (%zu values) is too large for int offsets",
                           rec);
    p->nrec = rec;
    for (size_t i = 0; i < p->ngb; i++)
        if (p->gb[i] < 0)
            return iso_err_set(err, ISO_EINVAL, -1,
                               "OpenCL: internal error: an element block is not in the pattern");
    if (make_csr(p->gb, p->go, p->ngb, cl->n_blocks, &p->blk_ptr, &p->blk_src) != 0 ||
        make_csr(p->gr, p->gro, p->ngr, s->nf, &p->rhs_ptr, &p->rhs_src) != 0)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory planning the OpenCL assembly");
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

static int upload(iso_solver *s, iso_cl_assembler *cl, plan *p, iso_err *err)
{
    int *vflag = malloc(((size_t)s->nv + 1) * sizeof *vflag);
    if (!vflag)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    for (int i = 0; i < s->nv; i++)
        vflag[i] = s->free_of[i] >= 0            ? s->free_of[i]
                   : s->r->kind[i] == ISO_HANDLE ? VF_HANDLE
                                                 : VF_FIXED;
    size_t I = sizeof(int), D = sizeof(double);
    int rc = make_buffer(cl, &cl->vflag, RO_COPY, (size_t)s->nv * I, vflag, "vertex flag", err);
    free(vflag);
    cl->status_host = malloc(((size_t)cl->nfp + 1) * I);
    if (!cl->status_host)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    cl->A_host = s->A->x;
    cl->B_host = s->B->x;
    cl_mem_flags use = CL_MEM_READ_WRITE | CL_MEM_USE_HOST_PTR;
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->fit_work, RO_COPY, 4 * (size_t)cl->nfp * I, p->fit_work,
                         "triangle list", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->pair_work, RO_COPY, 8 * (size_t)cl->np * I, p->pair_work,
                         "pair list", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->rest_work, RO_COPY, 4 * (size_t)cl->nrp * I, p->rest_work,
                         "edge list", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->rest_par, RO_COPY, 2 * (size_t)cl->nrp * D, p->rest_par,
                         "edge parameter", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->blk_dst, RO_COPY, 4 * (size_t)cl->n_blocks * I, p->blk_dst,
                         "block", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->blk_ptr, RO_COPY, ((size_t)cl->n_blocks + 1) * I, p->blk_ptr,
                         "block gather", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->blk_src, RO_COPY, p->ngb * I, p->blk_src, "block gather", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->rhs_ptr, RO_COPY, ((size_t)s->nf + 1) * I, p->rhs_ptr,
                         "rhs gather", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->rhs_src, RO_COPY, p->ngr * I, p->rhs_src, "rhs gather", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->x, CL_MEM_READ_ONLY, cl->nx * D, NULL, "position", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->vc, CL_MEM_READ_ONLY, cl->nx * D, NULL, "velocity", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->fit, CL_MEM_READ_WRITE, (size_t)cl->nfp * FIT_STRIDE * D, NULL,
                         "rigid fit", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->elem, CL_MEM_READ_WRITE, p->nrec * D, NULL, "element", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->status, use, (size_t)cl->nfp * I, cl->status_host, "status", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->A, use, cl->nnz * D, cl->A_host, "matrix", err);
    if (rc == ISO_OK)
        rc = make_buffer(cl, &cl->B, use, (size_t)(3 * s->nf) * D, cl->B_host, "right-hand side",
                         err);
    return rc;
}

/* ===== kernel arguments ================================================= */

/* restore_edges' τ: set here and again at every evaluation (it may change). */
#define RESTORE_ARG_TAU 3

#define ARG(k, i, v) (rc |= clSetKernelArg((k), (i), sizeof(v), &(v)))

static int set_args(iso_solver *s, iso_cl_assembler *cl, iso_err *err)
{
    cl_int rc = CL_SUCCESS;
    cl_int weighting = s->o.weighting == ISO_WEIGHT_AREA;
    cl_double w1 = 1.0 - s->o.omega, w2 = s->o.omega, mu = s->o.restore_mu, tau = s->o.restore_tau;
    cl_int nb = cl->n_blocks, nf = s->nf;
    cl_kernel k = cl->k[K_FIT];
    ARG(k, 0, cl->fit_work), ARG(k, 1, weighting), ARG(k, 2, cl->x), ARG(k, 3, cl->fit);
    ARG(k, 4, cl->status);
    cl_int np = cl->np, base = cl->pair_base;
    k = cl->k[K_PAIR];
    ARG(k, 0, cl->pair_work), ARG(k, 1, np), ARG(k, 2, weighting), ARG(k, 3, w1);
    ARG(k, 4, w2), ARG(k, 5, cl->x), ARG(k, 6, cl->vc), ARG(k, 7, cl->vflag);
    ARG(k, 8, cl->fit), ARG(k, 9, cl->elem), ARG(k, 10, base);
    k = cl->k[K_RESTORE];
    ARG(k, 0, cl->rest_work), ARG(k, 1, cl->rest_par), ARG(k, 2, mu), ARG(k, RESTORE_ARG_TAU, tau);
    ARG(k, 4, cl->x), ARG(k, 5, cl->vc), ARG(k, 6, cl->vflag), ARG(k, 7, cl->elem);
    k = cl->k[K_BLOCKS];
    ARG(k, 0, cl->blk_dst), ARG(k, 1, cl->blk_ptr), ARG(k, 2, cl->blk_src), ARG(k, 3, nb);
    ARG(k, 4, cl->elem), ARG(k, 5, cl->A);
    k = cl->k[K_RHS];
    ARG(k, 0, cl->rhs_ptr), ARG(k, 1, cl->rhs_src), ARG(k, 2, nf), ARG(k, 3, cl->elem);
    ARG(k, 4, cl->B);
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
    int rc = select_device(s->o.cl_device, &cl->dev, err);
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
    rc |= clEnqueueUnmapMemObject(cl->q, cl->status, cl->status_host, 0, NULL, NULL);
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
    cl_mem *mems[] = {&cl->vflag,   &cl->fit_work, &cl->pair_work, &cl->rest_work, &cl->rest_par,
                      &cl->blk_dst, &cl->blk_ptr,  &cl->blk_src,   &cl->rhs_ptr,   &cl->rhs_src,
                      &cl->x,       &cl->vc,       &cl->fit,       &cl->elem,      &cl->status,
                      &cl->A,       &cl->B};
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
    free(cl->status_host);
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
    void *ps = pb ? clEnqueueMapBuffer(cl->q, cl->status, CL_TRUE, CL_MAP_READ, 0,
                                       (size_t)cl->n_fit * sizeof(int), 0, NULL, NULL, &crc)
                  : NULL;
    if (!pa || !pb || !ps)
        return cl_fail(err, "reading back the matrix", crc);
    cl->mapped = 1;
    /* A USE_HOST_PTR buffer maps at its host pointer (OpenCL 1.2, 5.4.2). */
    if (pa != (void *)cl->A_host || pb != (void *)cl->B_host || ps != (void *)cl->status_host)
        return iso_err_set(err, ISO_EIO, -1, "OpenCL: %s mapped a host-pointer buffer elsewhere",
                           cl->device);
    int bad = -1;
    for (int f = 0; f < cl->n_fit; f++)
        if (cl->status_host[f] && (bad < 0 || cl->first_el[f] < cl->first_el[bad]))
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
