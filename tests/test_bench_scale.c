/* tests/test_bench_scale.c -- bench's scale table (controller/bench_scale.c)
 * on its small meshes (--quick): in-process, every row's figures hold
 * together (sizes of the closed forms, tick statistics that agree with the
 * rate, the proxy within its budget, a product and a peak memory measured,
 * a tick's split that is a split), and so do the factorization table's
 * (the factor holds at least A's entries and its values take 8 bytes each,
 * the product is of A's own pattern, every time measured); through the
 * built binary, `bench --scale --quick --json` prints one object a row of
 * each table with snake_case keys. No figure is compared with a time.
 * Links the command's static library (isoshape_cmd), so it reaches
 * controller/internal.h. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "internal.h"
#include "iso_proxy.h"

/* The quick table's largest mesh is above this, so one row is skipped. */
#define FULL_MAX 2000

/* The vertex count of a built-in shape at a resolution: the plane is an
 * R x R grid, the tentacle a geodesic sphere of 10 n^2 + 2 vertices. */
static int vertices_of(const iso_cli__scale_mesh *m)
{
    if (strcmp(m->shape, "tentacle") == 0)
        return 10 * m->resolution * m->resolution + 2;
    return m->resolution * m->resolution;
}

static void check_ran(const iso_cli__scale_row *r, const iso_cli__scale_mesh *m)
{
    if (r->why[0])
        fail_msg("%s (%s) did not run: %s", r->mesh, r->reduced ? "reduced" : "whole", r->why);
    /* the scene's screw lasts 2 s of stream time at 60 Hz */
    assert_int_equal(r->ticks, 120);
    assert_true(r->median_ms > 0 && r->median_ms <= r->p99_ms);
    /* the ticks run one after another within the run's wall time, and at
     * least half of them last the median or longer */
    assert_true(r->ticks_per_s > 0 && r->ticks_per_s <= 2000.0 / r->median_ms);
    assert_true(isfinite(r->peak_mb) && r->peak_mb > 0);
    assert_true(isfinite(r->metric_err) && r->metric_err >= 0);
    /* the split: every tick assembles; solves and waits may be none; the
     * ticks' thread factors at least once, before the clock starts */
    assert_true(isfinite(r->solves_per_tick) && r->solves_per_tick >= 0);
    assert_true(isfinite(r->assembly_ms) && r->assembly_ms > 0);
    assert_true(isfinite(r->solve_ms) && r->solve_ms >= 0);
    assert_true(isfinite(r->wait_ms) && r->wait_ms >= 0);
    assert_true(r->tick_factorizations >= 1);
    if (r->reduced) {
        assert_true(r->proxy >= ISO_PROXY_MIN_BUDGET && r->proxy <= m->budget);
        assert_true(r->proxy < r->vertices && r->build_s > 0);
    } else {
        assert_int_equal(r->proxy, 0);
        assert_true(r->build_s == 0);
    }
}

static void quick_rows_hold_together(void **state)
{
    (void)state;
    iso_cli__scale_row rows[2 * ISO_CLI_SCALE_MESHES];
    int n = -1;
    iso_err err;
    iso_err_clear(&err);
    if (iso_cli__bench_scale(iso_cli__scale_meshes_quick, FULL_MAX, 0, rows, &n, &err) != ISO_OK)
        fail_msg("bench scale: %s", err.msg);
    iso_cli__bench_scale_print(rows, n);
    assert_int_equal(n, 2 * ISO_CLI_SCALE_MESHES);
    int skipped = 0;
    for (int k = 0; k < ISO_CLI_SCALE_MESHES; k++) {
        const iso_cli__scale_mesh *m = &iso_cli__scale_meshes_quick[k];
        const iso_cli__scale_row *whole = &rows[2 * k], *red = &rows[2 * k + 1];
        assert_int_equal(whole->reduced, 0);
        assert_int_equal(red->reduced, 1);
        /* both rows are the same mesh, with one product measured for both */
        assert_int_equal(whole->vertices, vertices_of(m));
        assert_int_equal(red->vertices, vertices_of(m));
        assert_true(isfinite(whole->product_ms) && whole->product_ms > 0);
        assert_true(red->product_ms == whole->product_ms);
        check_ran(red, m);
        if (whole->vertices > FULL_MAX) {
            assert_non_null(strstr(whole->why, "--scale-full-max"));
            skipped++;
        } else {
            check_ran(whole, m);
        }
    }
    assert_int_equal(skipped, 1);
}

static void check_factor(const iso_cli__scale_factor_row *r)
{
    if (r->why[0])
        fail_msg("factorization of %s did not run: %s", r->mesh, r->why);
    /* three unknowns a free vertex */
    assert_true(r->unknowns > 0 && r->unknowns % 3 == 0 && r->unknowns <= 3 * r->vertices);
    /* A's upper triangle holds its diagonal; L holds A's pattern, permuted,
     * and its fill; the product is with A's own pattern */
    assert_true(r->nnz_a >= r->unknowns);
    assert_true(r->nnz_l >= r->nnz_a);
    assert_true(r->product_nnz == r->nnz_a);
    assert_true(r->supernodal == 0 || r->supernodal == 1);
    /* a value of 8 bytes for each of L's entries at least, and the factor
     * lives in the row's process */
    assert_true(r->factor_mb * 1024.0 * 1024.0 >= 8.0 * (double)r->nnz_l);
    assert_true(isfinite(r->peak_mb) && r->peak_mb >= r->factor_mb);
    assert_true(isfinite(r->gflop) && r->gflop > 0);
    assert_true(isfinite(r->analysis_s) && r->analysis_s > 0);
    assert_true(isfinite(r->factor_ms) && r->factor_ms > 0);
    assert_true(isfinite(r->solve_ms) && r->solve_ms > 0);
    assert_true(isfinite(r->assembly_ms) && r->assembly_ms > 0);
    assert_true(isfinite(r->product_ms) && r->product_ms > 0);
}

static void quick_factor_rows_hold_together(void **state)
{
    (void)state;
    iso_cli__scale_factor_row rows[ISO_CLI_SCALE_FACTOR_MESHES];
    int n = -1, skipped = 0;
    iso_cli__bench_scale_factor(iso_cli__scale_factor_meshes_quick, FULL_MAX, 0, rows, &n);
    iso_cli__bench_scale_factor_print(rows, n);
    assert_int_equal(n, ISO_CLI_SCALE_FACTOR_MESHES);
    for (int k = 0; k < n; k++) {
        const iso_cli__scale_mesh *m = &iso_cli__scale_factor_meshes_quick[k];
        assert_int_equal(rows[k].vertices, vertices_of(m));
        if (rows[k].vertices > FULL_MAX) {
            assert_non_null(strstr(rows[k].why, "--scale-full-max"));
            skipped++;
        } else {
            check_factor(&rows[k]);
        }
    }
    assert_int_equal(skipped, 1);
}

static int count_of(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = strstr(text, needle); p; p = strstr(p + 1, needle))
        n++;
    return n;
}

static void quick_json_has_a_row_each(void **state)
{
    (void)state;
    static char out[1 << 16], errs[1 << 14];
    char bin[4096], cmd[4200];
    if (iso_test_isoshape_bin(bin, sizeof bin) != 0) {
        printf("skipped: no isoshape binary at %s (set ISOSHAPE_BIN)\n", bin);
        skip();
    }
    snprintf(cmd, sizeof cmd, "'%s' bench --scale --quick --json", bin);
    int status = iso_test_sh(cmd, out, sizeof out, errs, sizeof errs);
    if (status != 0)
        fail_msg("bench --scale failed (%d): %s", status, errs);
    char bad[128];
    if (!iso_test_json_keys_snake_case(out, bad, sizeof bad))
        fail_msg("key '%s' is not snake_case in %s", bad, out);
    assert_non_null(strstr(out, "{\"scale\": ["));
    char *factor = strstr(out, "\"factorization\": [");
    assert_non_null(factor);
    assert_int_equal(count_of(factor, "\"path\":"), 0); /* the scale table's rows come first */
    assert_true(iso_test_json_num(out, "vertices") == 961);
    /* the factorization table: a row a mesh, one of them skipped */
    int ran = ISO_CLI_SCALE_FACTOR_MESHES - 1;
    assert_int_equal(count_of(factor, "\"mesh\":"), ISO_CLI_SCALE_FACTOR_MESHES);
    assert_int_equal(count_of(factor, "\"skipped\":"), 1);
    assert_int_equal(count_of(factor, "\"nnz_l\":"), ran);
    assert_int_equal(count_of(factor, "\"factor_mb\":"), ran);
    assert_int_equal(count_of(factor, "\"solve_over_product\":"), ran);
    assert_true(iso_test_json_num(factor, "vertices") == 49);
    *factor = '\0';
    assert_int_equal(count_of(out, "\"path\": \"whole\""), ISO_CLI_SCALE_MESHES);
    assert_int_equal(count_of(out, "\"path\": \"reduced\""), ISO_CLI_SCALE_MESHES);
    assert_int_equal(count_of(out, "\"skipped\":"), 1);
    assert_int_equal(count_of(out, "\"product_ms\":"), 2 * ISO_CLI_SCALE_MESHES);
    assert_int_equal(count_of(out, "\"peak_mb\":"), 2 * ISO_CLI_SCALE_MESHES - 1);
    assert_int_equal(count_of(out, "\"solves_per_tick\":"), 2 * ISO_CLI_SCALE_MESHES - 1);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(quick_rows_hold_together),
        cmocka_unit_test(quick_factor_rows_hold_together),
        cmocka_unit_test(quick_json_has_a_row_each),
    };
    return cmocka_run_group_tests_name("bench_scale", t, NULL, NULL);
}
