/* tests/test_assemble_cpu.c -- the C assembly in two halves
 * (solver/assemble_cpu.c), which large meshes use, against the same
 * assembly in one:
 *   (a) the values of A and of the right-hand side agree to 1e-13 of the
 *       largest (only the order of the sums differs), with handles, a
 *       fixed vertex inside and restoration on, so that every kind of
 *       block and both right-hand-side paths take part;
 *   (b) the two halves give the same bits on one thread and on two, and
 *       from one assembly to the next;
 *   (c) a singular fit in either half is reported, as with one half.
 * The split is forced on a small grid by lowering the solver's threshold
 * before its first assembly. White-box: it reads the solver's internals. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../solver/solver_internal.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_solver.h"
#include "testutil.h"

enum { GRID = 31 }; /* vertices a side: 1,740 interior edges */

typedef struct grid {
    iso_mesh *m;
    iso_regions r;
    double *x, *vc; /* a deformed pose, handle velocities */
    int nv;
} grid;

static void grid_init(grid *g)
{
    int nv = g->nv = GRID * GRID, nt = 2 * (GRID - 1) * (GRID - 1);
    double *x = malloc(3 * (size_t)nv * sizeof *x);
    int *tri = malloc(3 * (size_t)nt * sizeof *tri);
    g->x = malloc(3 * (size_t)nv * sizeof *g->x);
    g->vc = calloc(3 * (size_t)nv, sizeof *g->vc);
    assert_true(x && tri && g->x && g->vc);
    for (int j = 0; j < GRID; j++)
        for (int i = 0; i < GRID; i++) {
            double *p = x + 3 * (j * GRID + i), *q = g->x + 3 * (j * GRID + i);
            p[0] = i, p[1] = j, p[2] = 0.4 * sin(0.3 * i) * cos(0.2 * j);
            q[0] = p[0] + 0.05 * sin(0.5 * j), q[1] = p[1], q[2] = p[2] + 0.02 * i;
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
    assert_int_equal(iso_mesh_create(nv, x, nt, tri, "grid", &g->m, &err), ISO_OK);
    assert_int_equal(iso_regions_init(&g->r, nv, &err), ISO_OK);
    for (int j = 0; j < GRID; j++) {
        int h = j * GRID + GRID - 1;
        g->r.kind[j * GRID] = ISO_FIXED;
        g->r.kind[h] = ISO_HANDLE;
        g->r.handle[h] = 0;
        g->vc[3 * h + 2] = 1.0;
        g->vc[3 * h] = 0.1 * j;
    }
    g->r.kind[15 * GRID + 15] = ISO_FIXED;
    g->r.n_handles = 1;
    free(x);
    free(tri);
}

static void grid_deinit(grid *g)
{
    iso_regions_deinit(&g->r);
    iso_mesh_destroy(g->m);
    free(g->x);
    free(g->vc);
}

/* A solver for g with restoration; split: its threshold (INT_MAX: never),
 * helper: whether a helper thread may run the second half. */
static iso_solver *make_solver(const grid *g, int split, int helper)
{
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    o.restore_mu = 0.5;
    o.restore_tau = 0.2;
    iso_solver *s;
    iso_err err;
    assert_int_equal(iso_solver_create(g->m, &g->r, &o, &s, &err), ISO_OK);
    s->cpu_split_edges = split;
    s->cpu_helper = helper;
    return s;
}

/* A and B of solver s assembled at x, copied out. */
static void assemble(iso_solver *s, const double *x, const double *vc, double **A, double **B)
{
    iso_err err;
    if (iso_solver__assemble(s, x, vc, &err) != ISO_OK)
        fail_msg("assembly: %s", err.msg);
    size_t nnz = (size_t)((int *)s->A->p)[3 * s->nf], n3 = 3 * (size_t)s->nf;
    *A = malloc(nnz * sizeof **A);
    *B = malloc(n3 * sizeof **B);
    assert_true(*A && *B);
    memcpy(*A, s->A->x, nnz * sizeof **A);
    memcpy(*B, s->B->x, n3 * sizeof **B);
}

static void halves_agree_with_one(void **state)
{
    (void)state;
    grid g;
    grid_init(&g);
    iso_solver *one = make_solver(&g, 1 << 30, 1), *two = make_solver(&g, 1, 1),
               *serial = make_solver(&g, 1, 0);
    double *A1, *B1, *A2, *B2, *As, *Bs, *A2b, *B2b;
    assemble(one, g.x, g.vc, &A1, &B1);
    assemble(two, g.x, g.vc, &A2, &B2);
    assemble(serial, g.x, g.vc, &As, &Bs);
    assemble(two, g.x, g.vc, &A2b, &B2b);
    size_t nnz = (size_t)((int *)one->A->p)[3 * one->nf], n3 = 3 * (size_t)one->nf;
    double amax = iso_test_max_abs(A1, nnz), bmax = iso_test_max_abs(B1, n3);
    double da = iso_test_max_abs_diff(A1, A2, nnz), db = iso_test_max_abs_diff(B1, B2, n3);
    printf("two halves against one: A %.3g of its largest %.3g, B %.3g of %.3g\n", da, amax, db,
           bmax);
    assert_true(amax > 0 && bmax > 0);
    assert_true(da <= 1e-13 * amax);
    assert_true(db <= 1e-13 * bmax);
    assert_memory_equal(A2, As, nnz * sizeof *A2); /* one thread or two: the same bits */
    assert_memory_equal(B2, Bs, n3 * sizeof *B2);
    assert_memory_equal(A2, A2b, nnz * sizeof *A2); /* and again */
    assert_memory_equal(B2, B2b, n3 * sizeof *B2);
    free(A1), free(B1), free(A2), free(B2), free(As), free(Bs), free(A2b), free(B2b);
    iso_solver_destroy(one);
    iso_solver_destroy(two);
    iso_solver_destroy(serial);
    grid_deinit(&g);
}

/* The public policy sets the threshold: SPLIT_ALWAYS assembles the grid
 * (far below ISO_SOLVER_CPU_SPLIT_EDGES) in two halves, the bits of a
 * forced split; the default keeps one; an unknown policy is refused. */
static void the_split_policy_sets_the_threshold(void **state)
{
    (void)state;
    grid g;
    grid_init(&g);
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    assert_int_equal(o.threads.split, ISO_SOLVER_SPLIT_LARGE);
    o.restore_mu = 0.5;
    o.restore_tau = 0.2;
    o.threads.split = ISO_SOLVER_SPLIT_ALWAYS;
    iso_solver *always, *plain, *forced = make_solver(&g, 1, 1);
    iso_err err;
    assert_int_equal(iso_solver_create(g.m, &g.r, &o, &always, &err), ISO_OK);
    o.threads.split = ISO_SOLVER_SPLIT_LARGE;
    assert_int_equal(iso_solver_create(g.m, &g.r, &o, &plain, &err), ISO_OK);
    assert_int_equal(plain->cpu_split_edges, ISO_SOLVER_CPU_SPLIT_EDGES);
    double *Aa, *Ba, *Af, *Bf;
    assemble(always, g.x, g.vc, &Aa, &Ba);
    assemble(forced, g.x, g.vc, &Af, &Bf);
    size_t nnz = (size_t)((int *)always->A->p)[3 * always->nf], n3 = 3 * (size_t)always->nf;
    assert_memory_equal(Aa, Af, nnz * sizeof *Aa);
    assert_memory_equal(Ba, Bf, n3 * sizeof *Ba);
    o.threads.split = (iso_solver_split)7;
    iso_solver *bad = NULL;
    iso_err_clear(&err);
    assert_int_equal(iso_solver_create(g.m, &g.r, &o, &bad, &err), ISO_EINVAL);
    printf("unknown policy: %s\n", err.msg);
    assert_non_null(strstr(err.msg, "split"));
    free(Aa), free(Ba), free(Af), free(Bf);
    iso_solver_destroy(always);
    iso_solver_destroy(plain);
    iso_solver_destroy(forced);
    grid_deinit(&g);
}

/* A triangle collapsed in the first half's fits, then in the second's. */
static void a_singular_fit_is_reported_in_either_half(void **state)
{
    (void)state;
    grid g;
    grid_init(&g);
    for (int which = 0; which < 2; which++) {
        iso_solver *s = make_solver(&g, 1, 1);
        double *x = malloc(3 * (size_t)g.nv * sizeof *x);
        assert_non_null(x);
        memcpy(x, g.x, 3 * (size_t)g.nv * sizeof *x);
        int a = which == 0 ? 2 * GRID + 2 : (GRID - 3) * GRID + GRID - 3; /* free, far apart */
        memcpy(x + 3 * a, x + 3 * (a + 1), 3 * sizeof *x);                /* onto its neighbour */
        iso_err err;
        iso_err_clear(&err);
        assert_int_equal(iso_solver__assemble(s, x, g.vc, &err), ISO_ENUMERIC);
        assert_non_null(strstr(err.msg, "degenerated"));
        free(x);
        iso_solver_destroy(s);
    }
    grid_deinit(&g);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(halves_agree_with_one),
        cmocka_unit_test(the_split_policy_sets_the_threshold),
        cmocka_unit_test(a_singular_fit_is_reported_in_either_half),
    };
    return cmocka_run_group_tests_name("assemble_cpu", t, NULL, NULL);
}
