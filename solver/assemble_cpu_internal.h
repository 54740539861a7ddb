/* solver/assemble_cpu_internal.h -- the C assembly's plan, shared by
 * assemble_cpu_plan.c, which makes it once per solver, and assemble_cpu.c,
 * which runs it each evaluation. Not installed. */
#ifndef ISO_ASSEMBLE_CPU_INTERNAL_H
#define ISO_ASSEMBLE_CPU_INTERNAL_H

#include "element_internal.h"
#include "solver_internal.h"

/* One interior edge, its two ordered pairs, in the edge layout (a, b, p, q)
 * of iso_solver__edge_layout. */
enum {
    EDGE_CARRY_I = ISO_ELEM__EDGE_CARRY_I, /* adds Ti's Q1 */
    EDGE_CARRY_J = ISO_ELEM__EDGE_CARRY_J, /* adds Tj's Q1 */
    EDGE_RHS = 1 << 8                      /* a free vertex with a handle vertex */
};
typedef struct edge_item {
    int v[4];      /* global vertices a, b, p, q */
    int ti, tj;    /* the triangles */
    int flags;     /* bits 0-5: off-diagonal block 01 02 03 12 13 23 goes to A transposed */
    int side;      /* bit b: block b goes to the side buffer (pos is there), not to A */
    int stride[4]; /* per vertex: 3 (blocks in its column − 1), or −1 if not free */
    int pos[10];   /* per block (l <= m, row order): its first value in A, or −1 */
} edge_item;

struct iso_solver__cpu_plan {
    int halves;                /* 1, or 2 on a large mesh */
    int fit_split, edge_split; /* where the second half's fits and edges begin */
    iso_solver__team *team;    /* runs the two halves; NULL with one */
    double *side;              /* the second half's blocks in the columns both add to */
    size_t nside;              /* its length */
    int nshared, *shared;      /* those columns (free vertices), ascending */
    int *side_off;             /* nf: where column f's values start in side, or −1 */
    double *rhs1;              /* the second half's right-hand side (3 nf) */
    int bad[2];                /* a fit of the half was singular */
    int nfit;
    int *fit_tri;     /* the elements' triangles, ascending */
    double *fits;     /* FIT_STRIDE per triangle (element_internal.h), 64-byte aligned */
    double *x4;       /* the positions, 4 doubles a vertex, 32-byte aligned */
    int ne;           /* interior edges */
    edge_item *edges; /* in Z-order (sort_edges_z) */
    int nother;
    int *other; /* elements outside the edges: lone Q1, restoration */
};

/* Makes s->cpu (ISO_OK), or fails with ISO_ENOMEM or, for an internal
 * inconsistency, ISO_EINVAL. */
int iso_solver__cpu_plan_make(iso_solver *s, iso_err *err);

#endif
