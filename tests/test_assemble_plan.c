/* tests/test_assemble_plan.c -- the OpenCL assembly's plan
 * (solver/assemble_plan_internal.h), checked without a device against what
 * the mesh, the regions and A's pattern say on their own:
 *   (a) every block an element kernel writes lands in a slot of the right
 *       place: a block of A_ff (both vertices free) in that block's run of
 *       slots, transposed exactly when its rows are the higher free index;
 *       a free–handle block in the free vertex's handle slots with the
 *       handle's vertex beside it; anything else in the slots nothing
 *       reads; a restoration edge's linear parts in its free ends' runs;
 *   (b) no two writers share a slot, each A block's run holds exactly as
 *       many slots as items write to it (counted from the items' vertices),
 *       and the runs of the blocks cover A's values once (blk_dst);
 *   (c) every triangle element's Q1 is carried by exactly one real pair
 *       item, the fit items are the items' triangles, and padding carries
 *       nothing and writes only unread slots;
 *   (d) the plan is the same, array for array, when made twice.
 * On a curved grid with fixed, handle and free vertices, restoration on,
 * and work-groups that leave every list padded. White-box: it reads the
 * solver's internals. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../solver/assemble_plan_internal.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_solver.h"
#include "testutil.h"

enum { GRID = 9 }; /* vertices a side */

typedef struct fixture {
    iso_mesh *m;
    iso_regions r;
    iso_solver *s;
} fixture;

/* A bumped GRID x GRID grid: column 0 fixed, column GRID−1 on handle 0,
 * the rest free except one fixed vertex inside. */
static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    assert_non_null(f);
    int nv = GRID * GRID, nt = 2 * (GRID - 1) * (GRID - 1);
    double *x = malloc(3 * (size_t)nv * sizeof *x);
    int *tri = malloc(3 * (size_t)nt * sizeof *tri);
    assert_true(x && tri);
    for (int j = 0; j < GRID; j++)
        for (int i = 0; i < GRID; i++) {
            double *p = x + 3 * (j * GRID + i);
            p[0] = i, p[1] = j, p[2] = 0.3 * sin(0.7 * i) * cos(0.5 * j);
        }
    int t = 0;
    for (int j = 0; j + 1 < GRID; j++)
        for (int i = 0; i + 1 < GRID; i++) {
            int a = j * GRID + i, b = a + 1, c = a + GRID, d = c + 1;
            int q[6] = {a, b, d, a, d, c};
            memcpy(tri + 3 * t, q, sizeof q);
            t += 2;
        }
    iso_err err;
    assert_int_equal(iso_mesh_create(nv, x, nt, tri, "grid", &f->m, &err), ISO_OK);
    assert_int_equal(iso_regions_init(&f->r, nv, &err), ISO_OK);
    for (int j = 0; j < GRID; j++) {
        f->r.kind[j * GRID] = ISO_FIXED;
        f->r.kind[j * GRID + GRID - 1] = ISO_HANDLE;
        f->r.handle[j * GRID + GRID - 1] = 0;
    }
    f->r.kind[4 * GRID + 4] = ISO_FIXED;
    f->r.n_handles = 1;
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    o.restore_mu = 1.0;
    o.restore_tau = 0.5;
    assert_int_equal(iso_solver_create(f->m, &f->r, &o, &f->s, &err), ISO_OK);
    free(x);
    free(tri);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    iso_solver_destroy(f->s);
    iso_regions_deinit(&f->r);
    iso_mesh_destroy(f->m);
    free(f);
    return 0;
}

static const size_t WG[3] = {7, 13, 31}; /* none divides its list's length here */

/* Who writes each slot start: −1 none; marks a range as taken. */
static void take(int *owner, size_t nslot, int at, int size, int who)
{
    assert_true(at >= 0 && (size_t)at + (size_t)size <= nslot);
    for (int k = 0; k < size; k++) {
        assert_int_equal(owner[at + k], -1);
        owner[at + k] = who;
    }
}

/* The A block (plan order) whose run of slots contains `at`, or −1. */
static int block_of_slot(const iso_solver__cl_plan *p, int at)
{
    for (int b = 0; b < p->n_blocks; b++)
        if (at >= p->blk_ptr[b] && at < p->blk_ptr[b + 1])
            return b;
    return -1;
}

/* The free vertices (row, column) of plan block b, from A's pattern. */
static void block_vertices(const iso_solver *s, const iso_solver__cl_plan *p, int b, int *fr,
                           int *fc)
{
    const int *Ap = s->A->p, *Ai = s->A->i;
    int pos = p->blk_dst[4 * b];
    int col = 0;
    while (Ap[col + 1] <= pos)
        col++;
    *fr = Ai[pos] / 3;
    *fc = col / 3;
    assert_int_equal(col % 3, 0);
}

/* Checks one element block (u, w) written at `at` with step `step` (0: a
 * diagonal block, no step): where it lands says which vertices it is of. */
static void check_block(const iso_solver *s, const iso_solver__cl_plan *p, int *owner, int u, int w,
                        int at, int step, int *count, int who)
{
    int fu = s->free_of[u], fw = s->free_of[w];
    if (fu >= 0 && fw >= 0) {
        int b = block_of_slot(p, at);
        assert_true(b >= 0);
        int fr, fc;
        block_vertices(s, p, b, &fr, &fc);
        int lo = fu < fw ? fu : fw, hi = fu < fw ? fw : fu;
        assert_int_equal(fr, lo);
        assert_int_equal(fc, hi);
        if (step)
            assert_int_equal(step, fu > fw ? 1 : 3);
        take(owner, p->nslot, at, p->blk_dst[4 * b + 3] ? 6 : 9, who);
        count[b]++;
        return;
    }
    int f = fu >= 0 ? fu : fw, h = fu >= 0 ? w : u;
    if (u != w && f >= 0 && s->r->kind[h] == ISO_HANDLE) {
        assert_true(at >= p->hb_ptr[f] && at < p->hb_ptr[f + 1]);
        assert_int_equal(p->hb_vtx[(at - p->hbase) / 9], h);
        if (step)
            assert_int_equal(step, fw >= 0 ? 1 : 3);
        take(owner, p->nslot, at, 9, who);
        return;
    }
    assert_true(at >= p->lin_ptr[s->nf]); /* unread */
    take(owner, p->nslot, at, 9, who);
}

static void blocks_land_where_they_belong(void **state)
{
    fixture *f = *state;
    const iso_solver *s = f->s;
    iso_solver__cl_plan p;
    iso_err err;
    assert_int_equal(iso_solver__cl_plan_make(s, WG, &p, &err), ISO_OK);
    assert_true(p.n_pair > 0 && p.n_rest > 0 && p.np > p.n_pair && p.nrp > p.n_rest &&
                p.nfp > p.n_fit);
    int *owner = malloc(p.nslot * sizeof *owner);
    int *count = calloc((size_t)p.n_blocks, sizeof *count);
    assert_true(owner && count);
    for (size_t i = 0; i < p.nslot; i++)
        owner[i] = -1;
    int np = p.np, nr = p.nrp, who = 0;
    for (int j = 0; j < np; j++) {
        const int *v = p.pair_work + j; /* row r at v[r * np] */
        for (int l = 0, b = 0, o = 0; l < 4; l++)
            for (int m = l; m < 4; m++, b++) {
                int at = v[(7 + b) * np], step = l != m ? v[(17 + o++) * np] : 0;
                if (j >= p.n_pair) { /* padding: its own unread slots */
                    assert_true(at >= p.lin_ptr[s->nf]);
                    take(owner, p.nslot, at, 9, who++);
                    continue;
                }
                check_block(s, &p, owner, v[l * np], v[m * np], at, step, count, who++);
            }
    }
    for (int j = 0; j < nr; j++) {
        const int *v = p.rest_work + j;
        int ends[2] = {v[0], v[nr]}, lm[3][2] = {{0, 0}, {0, 1}, {1, 1}};
        for (int b = 0; b < 3; b++) {
            int at = v[(2 + b) * nr];
            if (j >= p.n_rest) {
                assert_true(at >= p.lin_ptr[s->nf]);
                take(owner, p.nslot, at, 9, who++);
                continue;
            }
            check_block(s, &p, owner, ends[lm[b][0]], ends[lm[b][1]], at, 0, count, who++);
        }
        for (int e = 0; e < 2; e++) {
            int at = p.rest_lin[e * nr + j], fe = s->free_of[ends[e]];
            if (j < p.n_rest && fe >= 0) {
                assert_true(at >= p.lin_ptr[fe] && at < p.lin_ptr[fe + 1]);
                take(owner, p.nslot, at, 3, who++);
            } else {
                assert_true(at >= p.lin_ptr[s->nf]);
                take(owner, p.nslot, at, 9, who++);
            }
        }
    }
    /* Each block's run is exactly its writers' slots, counted on their own
     * from the items' vertices: the pairs (l, m) of each real item. */
    for (int b = 0; b < p.n_blocks; b++) {
        int size = p.blk_dst[4 * b + 3] ? 6 : 9;
        assert_int_equal((p.blk_ptr[b + 1] - p.blk_ptr[b]) % size, 0);
        assert_int_equal((p.blk_ptr[b + 1] - p.blk_ptr[b]) / size, count[b]);
        for (int k = p.blk_ptr[b]; k < p.blk_ptr[b + 1]; k++)
            assert_true(owner[k] >= 0);
    }
    free(owner);
    free(count);
    iso_solver__cl_plan_free(&p);
}

/* blk_dst: every 3-row group of A's values belongs to exactly one block,
 * whose diagonal flag says whether it is a diagonal block. */
static void blocks_cover_the_matrix(void **state)
{
    fixture *f = *state;
    const iso_solver *s = f->s;
    iso_solver__cl_plan p;
    iso_err err;
    assert_int_equal(iso_solver__cl_plan_make(s, WG, &p, &err), ISO_OK);
    const int *Ap = s->A->p, *Ai = s->A->i;
    size_t nnz = (size_t)Ap[3 * s->nf];
    char *hit = calloc(nnz, 1);
    assert_non_null(hit);
    for (int b = 0; b < p.n_blocks; b++) {
        int fr, fc;
        block_vertices(s, &p, b, &fr, &fc);
        assert_int_equal(p.blk_dst[4 * b + 3], fr == fc);
        for (int k = 0; k < 3; k++) {
            int pos = p.blk_dst[4 * b + k], rows = fr == fc ? k + 1 : 3;
            assert_true(pos >= Ap[3 * fc + k] && pos + rows <= Ap[3 * fc + k + 1]);
            for (int a = 0; a < rows; a++) {
                assert_int_equal(Ai[pos + a], 3 * fr + a);
                assert_int_equal(hit[pos + a], 0);
                hit[pos + a] = 1;
            }
        }
    }
    for (size_t i = 0; i < nnz; i++)
        assert_int_equal(hit[i], 1);
    free(hit);
    iso_solver__cl_plan_free(&p);
}

/* Whether fit item fi is triangle t's, corners as a set. */
static int fit_is_triangle(const iso_solver__cl_plan *p, const int *tri, int fi, int t)
{
    if (p->tri_of[fi] != t)
        return 0;
    for (int c = 0; c < 3; c++)
        if (p->fit_work[4 * fi + c] != tri[3 * t + c])
            return 0;
    return 1;
}

static void each_triangle_is_carried_once(void **state)
{
    fixture *f = *state;
    const iso_solver *s = f->s;
    iso_solver__cl_plan p;
    iso_err err;
    assert_int_equal(iso_solver__cl_plan_make(s, WG, &p, &err), ISO_OK);
    int nt = iso_mesh_triangle_count(f->m);
    const int *tri = iso_mesh_triangles(f->m);
    int *carried = calloc((size_t)nt, sizeof *carried);
    assert_non_null(carried);
    int np = p.np;
    for (int j = 0; j < np; j++) {
        const int *v = p.pair_work + j;
        int flags = v[6 * np];
        if (j >= p.n_pair) {
            assert_int_equal(flags, 0);
            continue;
        }
        assert_int_equal(flags & ~(ISO_ELEM__EDGE_CARRY_I | ISO_ELEM__EDGE_CARRY_J), 0);
        /* Ti is (a, b, p) in some order and Tj holds a, b and q. */
        int fi = v[4 * np], fj = v[5 * np], ti = p.tri_of[fi], tj = p.tri_of[fj];
        assert_true(fit_is_triangle(&p, tri, fi, ti) && fit_is_triangle(&p, tri, fj, tj));
        for (int l = 0; l < 4; l++) {
            int in_i = 0, in_j = 0;
            for (int c = 0; c < 3; c++) {
                in_i |= tri[3 * ti + c] == v[l * np];
                in_j |= tri[3 * tj + c] == v[l * np];
            }
            assert_int_equal(in_i, l != 3);
            assert_int_equal(in_j, l != 2);
        }
        if (flags & ISO_ELEM__EDGE_CARRY_I)
            carried[ti]++;
        if (flags & ISO_ELEM__EDGE_CARRY_J)
            carried[tj]++;
    }
    int elements = 0;
    for (int i = 0; i < s->nel; i++)
        if (s->el[i].kind == 1) {
            assert_int_equal(carried[s->el[i].tri], 1);
            carried[s->el[i].tri] = 0;
            elements++;
        }
    for (int t = 0; t < nt; t++) /* and no triangle that is not an element */
        assert_int_equal(carried[t], 0);
    assert_true(elements > 0);
    free(carried);
    iso_solver__cl_plan_free(&p);
}

#define SAME(field, n) assert_memory_equal(a.field, b.field, (size_t)(n) * sizeof *a.field)

static void the_plan_is_deterministic(void **state)
{
    fixture *f = *state;
    iso_solver__cl_plan a, b;
    iso_err err;
    assert_int_equal(iso_solver__cl_plan_make(f->s, WG, &a, &err), ISO_OK);
    assert_int_equal(iso_solver__cl_plan_make(f->s, WG, &b, &err), ISO_OK);
    assert_int_equal(a.nslot, b.nslot);
    assert_int_equal(a.n_fit, b.n_fit);
    SAME(fit_work, 4 * a.nfp);
    SAME(pair_work, ISO_CL_PLAN_PAIR_ROWS * a.np);
    SAME(rest_work, ISO_CL_PLAN_REST_ROWS * a.nrp);
    SAME(rest_lin, 2 * a.nrp);
    SAME(rest_par, 2 * a.nrp);
    SAME(blk_dst, 4 * a.n_blocks);
    SAME(blk_ptr, a.n_blocks + 1);
    SAME(hb_ptr, f->s->nf + 1);
    SAME(lin_ptr, f->s->nf + 1);
    SAME(hb_vtx, a.n[ISO_CL_C_HANDLE]);
    SAME(first_el, a.n_fit);
    iso_solver__cl_plan_free(&a);
    iso_solver__cl_plan_free(&b);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test_setup_teardown(blocks_land_where_they_belong, setup, teardown),
        cmocka_unit_test_setup_teardown(blocks_cover_the_matrix, setup, teardown),
        cmocka_unit_test_setup_teardown(each_triangle_is_carried_once, setup, teardown),
        cmocka_unit_test_setup_teardown(the_plan_is_deterministic, setup, teardown),
    };
    return cmocka_run_group_tests_name("assemble_plan", t, NULL, NULL);
}
