/* tests/test_supersolve.c -- the solver's own triangular solves with
 * CHOLMOD's supernodal factor (solver/supersolve_internal.h):
 *   (a) on supernodal factors of sparse SPD matrices with 3x3 blocks, as
 *       the solver's (a 3D grid, and a random pattern), the solution agrees
 *       with cholmod_solve2's to 1e-12 of its largest entry, and its
 *       residual ‖A x − b‖∞ is at most 1e-12 ‖A‖∞ ‖x‖∞ (a backward error
 *       some 5000 unit roundoffs wide: the matrices are diagonally
 *       dominant, so well conditioned, and a stable solve lands far
 *       inside it); the factors are checked to have supernodes wider than a
 *       panel of 8 columns, of widths that are not multiples of 8, and with
 *       row counts below the diagonal that are not multiples of 4, so that
 *       every loop tail runs;
 *   (b) b and x may be one array, with the same bits, and two runs give the
 *       same bits;
 *   (c) a simplicial factor is refused (−1) and x is left as it was;
 *   (d) the two-thread solve (iso_solver__super_solve_split) finds a split
 *       of these trees, agrees with cholmod_solve2 as (a) does, and gives
 *       the same bits with a helper thread, without one, and again.
 * White-box: it calls the solver's internal function, and CHOLMOD. */
#include <cholmod.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../solver/solver_internal.h"
#include "../solver/supersolve_internal.h"
#include "geom_fixtures.c"
#include "testutil.h"

/* An SPD matrix of nb vertices' 3x3 blocks, upper triangle stored: block
 * (i, j) for each neighbour pair from `pairs`, diagonal blocks dominant. */
static cholmod_sparse *block_matrix(int nb, const int *pairs, int np, fx_rng *rng,
                                    cholmod_common *c)
{
    int n = 3 * nb;
    cholmod_triplet *T = cholmod_allocate_triplet((size_t)n, (size_t)n, (size_t)(9 * np + 6 * nb),
                                                  1, CHOLMOD_REAL, c);
    assert_non_null(T);
    int *ti = T->i, *tj = T->j;
    double *tx = T->x;
    double *rowsum = calloc((size_t)n, sizeof *rowsum);
    size_t k = 0;
    for (int p = 0; p < np; p++) {
        int a = pairs[2 * p] < pairs[2 * p + 1] ? pairs[2 * p] : pairs[2 * p + 1];
        int b = pairs[2 * p] ^ pairs[2 * p + 1] ^ a;
        for (int r = 0; r < 3; r++)
            for (int q = 0; q < 3; q++) {
                double v = fx_uniform(rng, -1, 1);
                ti[k] = 3 * a + r, tj[k] = 3 * b + q, tx[k++] = v;
                rowsum[3 * a + r] += fabs(v);
                rowsum[3 * b + q] += fabs(v);
            }
    }
    for (int v = 0; v < nb; v++)
        for (int r = 0; r < 3; r++)
            for (int q = r; q < 3; q++) {
                double off = r == q ? 0 : fx_uniform(rng, -0.1, 0.1);
                ti[k] = 3 * v + r, tj[k] = 3 * v + q;
                tx[k++] = r == q ? rowsum[3 * v + r] + 0.2 + fx_uniform(rng, 0, 1) : off;
            }
    T->nnz = k;
    cholmod_sparse *A = cholmod_triplet_to_sparse(T, 0, c);
    assert_non_null(A);
    cholmod_free_triplet(&T, c);
    free(rowsum);
    return A;
}

/* Neighbour pairs of an nx × ny × nz grid (6-connected, plus one diagonal
 * so that the pattern is less regular). */
static int grid_pairs(int nx, int ny, int nz, int *pairs)
{
    int np = 0;
    for (int z = 0; z < nz; z++)
        for (int y = 0; y < ny; y++)
            for (int x = 0; x < nx; x++) {
                int v = (z * ny + y) * nx + x;
                if (x + 1 < nx)
                    pairs[2 * np] = v, pairs[2 * np++ + 1] = v + 1;
                if (y + 1 < ny)
                    pairs[2 * np] = v, pairs[2 * np++ + 1] = v + nx;
                if (z + 1 < nz)
                    pairs[2 * np] = v, pairs[2 * np++ + 1] = v + nx * ny;
                if (x + 1 < nx && y + 1 < ny)
                    pairs[2 * np] = v, pairs[2 * np++ + 1] = v + nx + 1;
            }
    return np;
}

/* Random pairs, each vertex joined to the next (so the graph is connected). */
static int random_pairs(int nb, int extra, fx_rng *rng, int *pairs)
{
    int np = 0;
    for (int v = 0; v + 1 < nb; v++)
        pairs[2 * np] = v, pairs[2 * np++ + 1] = v + 1;
    while (extra-- > 0) {
        int a = (int)fx_uniform(rng, 0, nb), b = (int)fx_uniform(rng, 0, nb);
        if (a != b && a < nb && b < nb)
            pairs[2 * np] = a, pairs[2 * np++ + 1] = b;
    }
    return np;
}

/* Fails unless L has the supernodes that reach every loop's tail. */
static void assert_covers_tails(const cholmod_factor *L)
{
    const int *super = L->super, *pi = L->pi;
    int wide = 0, odd_width = 0, odd_rows = 0;
    for (size_t s = 0; s < L->nsuper; s++) {
        int nscol = super[s + 1] - super[s], m = pi[s + 1] - pi[s] - nscol;
        wide += nscol > 8;
        odd_width += nscol > 8 && nscol % 8 != 0;
        odd_rows += m > 0 && m % 4 != 0;
    }
    assert_true(wide > 0);
    assert_true(odd_width > 0);
    assert_true(odd_rows > 0);
}

/* (a) and (b) on the SPD matrix of nb vertices joined by the np pairs. */
static void check_solve(int nb, const int *pairs, int np, fx_rng *rng)
{
    cholmod_common cc, *c = &cc;
    cholmod_start(c);
    cholmod_sparse *A = block_matrix(nb, pairs, np, rng, c);
    c->supernodal = CHOLMOD_SUPERNODAL;
    cholmod_factor *L = cholmod_analyze(A, c);
    assert_non_null(L);
    assert_true(cholmod_factorize(A, L, c));
    assert_int_equal(c->status, CHOLMOD_OK);
    assert_true(L->is_super);
    assert_covers_tails(L);
    size_t n = A->nrow;
    cholmod_dense *B = cholmod_zeros(n, 1, CHOLMOD_REAL, c);
    double *b = B->x;
    for (size_t i = 0; i < n; i++)
        b[i] = fx_uniform(rng, -1, 1);
    cholmod_dense *Xc = cholmod_solve(CHOLMOD_A, L, B, c);
    assert_non_null(Xc);
    double *x = malloc(n * sizeof *x), *x2 = malloc(n * sizeof *x2);
    double *work = malloc(iso_solver__super_work(L) * sizeof *work);
    assert_int_equal(iso_solver__super_solve(L, b, x, work), 0);

    /* (a) against CHOLMOD, and the residual */
    double scale = iso_test_max_abs(Xc->x, n);
    assert_true(iso_test_max_abs_diff(x, Xc->x, n) <= 1e-12 * scale);
    cholmod_dense *Xd = cholmod_zeros(n, 1, CHOLMOD_REAL, c), *R = cholmod_copy_dense(B, c);
    memcpy(Xd->x, x, n * sizeof *x);
    double minus_one[2] = {-1, 0}, one[2] = {1, 0};
    assert_true(cholmod_sdmult(A, 0, minus_one, one, Xd, R, c));
    double anorm = cholmod_norm_sparse(A, 0, c);
    assert_true(iso_test_max_abs(R->x, n) <= 1e-12 * anorm * iso_test_max_abs(x, n));

    /* (b) in place, and again */
    assert_int_equal(iso_solver__super_solve(L, b, x2, work), 0);
    assert_memory_equal(x, x2, n * sizeof *x);
    memcpy(x2, b, n * sizeof *x2);
    assert_int_equal(iso_solver__super_solve(L, x2, x2, work), 0);
    assert_memory_equal(x, x2, n * sizeof *x);

    /* (d) on two threads, on one, and again */
    iso_solver__super_plan *plan = iso_solver__super_plan_create(L);
    assert_non_null(plan);
    iso_solver__team *team = iso_solver__team_create();
    double *x3 = malloc(n * sizeof *x3);
    assert_int_equal(iso_solver__super_solve_split(L, plan, team, b, x2, work), 0);
    printf("%zu unknowns, %zu supernodes: the two-thread solve %.3g from CHOLMOD's (of %.3g)\n", n,
           L->nsuper, iso_test_max_abs_diff(x2, Xc->x, n), scale);
    assert_true(iso_test_max_abs_diff(x2, Xc->x, n) <= 1e-12 * scale);
    assert_int_equal(iso_solver__super_solve_split(L, plan, NULL, b, x3, work), 0);
    assert_memory_equal(x2, x3, n * sizeof *x2);
    assert_int_equal(iso_solver__super_solve_split(L, plan, team, b, x3, work), 0);
    assert_memory_equal(x2, x3, n * sizeof *x2);
    free(x3);
    iso_solver__team_destroy(team);
    iso_solver__super_plan_destroy(plan);

    free(x);
    free(x2);
    free(work);
    cholmod_free_dense(&Xd, c);
    cholmod_free_dense(&R, c);
    cholmod_free_dense(&Xc, c);
    cholmod_free_dense(&B, c);
    cholmod_free_factor(&L, c);
    cholmod_free_sparse(&A, c);
    cholmod_finish(c);
}

static void test_grid(void **state)
{
    (void)state;
    fx_rng rng = {12};
    int nx = 14, ny = 13, nz = 11, nb = nx * ny * nz;
    int *pairs = malloc((size_t)8 * nb * sizeof *pairs);
    check_solve(nb, pairs, grid_pairs(nx, ny, nz, pairs), &rng);
    free(pairs);
}

static void test_random_pattern(void **state)
{
    (void)state;
    fx_rng rng = {34};
    int nb = 700, extra = 900;
    int *pairs = malloc((size_t)2 * (nb + extra) * sizeof *pairs);
    int np = random_pairs(nb, extra, &rng, pairs);
    check_solve(nb, pairs, np, &rng);
    free(pairs);
}

static void test_simplicial_refused(void **state)
{
    (void)state;
    cholmod_common c;
    cholmod_start(&c);
    fx_rng rng = {56};
    int pairs[2 * 40];
    int np = random_pairs(30, 10, &rng, pairs);
    cholmod_sparse *A = block_matrix(30, pairs, np, &rng, &c);
    c.supernodal = CHOLMOD_SIMPLICIAL;
    cholmod_factor *L = cholmod_analyze(A, &c);
    assert_non_null(L);
    assert_true(cholmod_factorize(A, L, &c));
    assert_false(L->is_super);
    double b[90], x[90], work[2 * 90 + 8];
    for (int i = 0; i < 90; i++)
        b[i] = 1.0, x[i] = -7.0;
    assert_int_equal(iso_solver__super_solve(L, b, x, work), -1);
    for (int i = 0; i < 90; i++)
        assert_true(x[i] == -7.0);
    cholmod_free_factor(&L, &c);
    cholmod_free_sparse(&A, &c);
    cholmod_finish(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_grid),
        cmocka_unit_test(test_random_pattern),
        cmocka_unit_test(test_simplicial_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
