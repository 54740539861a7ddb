/* solver/assemble_plan_internal.h -- the OpenCL assembly's plan
 * (assemble_plan.c): where every block an element kernel computes goes.
 * Plain C, made once per solver on the host; assemble_cl.c uploads it.
 * Not installed; the solver's own sources and white-box tests include it.
 *
 * The element kernels (assemble_cl.c's header lists them) write each 3x3
 * block they compute to a slot of its own: nine values, or a diagonal
 * block's upper six, or three for a linear part. The slots of one block of
 * A_ff are consecutive, in element-list order, so that reduce_blocks sums
 * a contiguous run with no index to look up; blocks of a free and a handle
 * vertex go to slots per free vertex, which reduce_rhs multiplies by the
 * handle's velocity; blocks that reach neither (and padding items) go to
 * slots of their own that nothing reads. */
#ifndef ISO_ASSEMBLE_PLAN_INTERNAL_H
#define ISO_ASSEMBLE_PLAN_INTERNAL_H

#include <stddef.h>

#include "element_internal.h"
#include "solver_internal.h"

/* The pair flags are element_internal.h's, which the kernels' CARRY_I/J
 * repeat inside their source text. */
#define ISO_CL_PLAN_PAIR_ROWS 23 /* rows of the pair kernel's work list */
#define ISO_CL_PLAN_REST_ROWS 5  /* rows of the restoration kernel's work list */

/* A block (or linear part) an element kernel computes, and the int of a
 * work list that gets the offset of its slot: key is the block of A_ff it
 * adds to (A), or the free vertex (handle blocks, linear parts); hv the
 * handle vertex of a handle block. */
typedef struct iso_solver__cl_contrib {
    int key, hv;
    int *at;
} iso_solver__cl_contrib;

enum { ISO_CL_C_A, ISO_CL_C_HANDLE, ISO_CL_C_LIN, ISO_CL_C_DUMP, ISO_CL_C_KINDS };

/* Work lists are stored row-major: row r of a list of n items is
 * [r n, (r + 1) n). Items are padded to whole work-groups (np, nfp, nrp);
 * a padding item repeats item 0 into slots nothing reads.
 *   fit_work   4 per fit item: the triangle's corners and 0;
 *   pair_work  PAIR_ROWS rows of np: the edge layout (a, b, p, q), Ti's
 *              and Tj's fit items, the carry flags (which of the two
 *              triangles' Q1 the item adds), the slots of the 10 blocks
 *              (l, m), l <= m, of the 4x4 layout, and the step (3, or 1:
 *              written transposed) of the 6 off-diagonal ones;
 *   rest_work  REST_ROWS rows of nrp: v0, v1, the slots of blocks 00, 01, 11;
 *   rest_lin   2 rows of nrp: the slots of the linear parts at v0, v1;
 *   rest_par   2 rows of nrp: the rest length and w_e.
 * The sums: A's blocks in the order the element kernels first add to them,
 * each with blk_dst (4 per block: the offsets in A's values of its three
 * columns, and 1 for a diagonal block) and its slots [blk_ptr[b],
 * blk_ptr[b + 1]); free vertex f's handle blocks at [hb_ptr[f], hb_ptr[f +
 * 1]), slot k's handle vertex hb_vtx[(k − hbase) / 9]; its linear parts at
 * [lin_ptr[f], lin_ptr[f + 1]). */
typedef struct iso_solver__cl_plan {
    size_t wg[3]; /* in: work-group sizes of the fit, pair and restoration kernels */
    int *fit_work, *pair_work, *rest_work, *rest_lin;
    double *rest_par;
    int *blk_dst, *blk_ptr, *hb_ptr, *hb_vtx, *lin_ptr;
    size_t nslot; /* doubles in the slot buffer */
    int n_fit, n_pair, n_rest, n_blocks;
    int np, nfp, nrp; /* items padded to whole work-groups */
    int hbase;        /* where the handle blocks' slots start */
    int *first_el;    /* per fit item: first element (list order) using it as Ti or Q1 */
    int *tri_of;      /* per fit item: its triangle */
    /* the planning's own */
    size_t nnz;
    int *fit_of_tri; /* per triangle: fit item or −1 */
    int *blk_of_pos; /* per value of A: the block starting there, or −1 */
    iso_solver__cl_contrib *c[ISO_CL_C_KINDS];
    size_t n[ISO_CL_C_KINDS], cap[ISO_CL_C_KINDS];
} iso_solver__cl_plan;

/* Plans the assembly of solver s (after its pattern and slot map exist)
 * for work-groups of wg[0..2] items. p is overwritten; free it with
 * iso_solver__cl_plan_free whatever the outcome. ISO_ENOMEM, or ISO_EINVAL
 * for an internal inconsistency, with a message. */
int iso_solver__cl_plan_make(const iso_solver *s, const size_t wg[3], iso_solver__cl_plan *p,
                             iso_err *err);
void iso_solver__cl_plan_free(iso_solver__cl_plan *p);

#endif
