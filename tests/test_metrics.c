/* tests/test_metrics.c -- the Table 1 measures (iso_metrics.h) against
 * closed forms: a hand-computed triangle, uniform scaling, rigid motion. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geom_fixtures.c"
#include "iso_metrics.h"
#include "testutil.h"

/* One right triangle stretched by 2 along x; every number by hand. */
static void stretched_triangle_by_hand(void **state)
{
    (void)state;
    double x0[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    double x1[9] = {0, 0, 0, 2, 0, 0, 0, 1, 0};
    int tri[3] = {0, 1, 2};
    fx_mesh fm = {3, 1, x0, tri};
    iso_mesh *m = fx_make(&fm);
    iso_metrics q;
    iso_metrics_compute(m, x0, x1, &q);
    const double pi = acos(-1.0);
    double d12 = sqrt(5.0) - sqrt(2.0); /* hypotenuse sqrt2 -> sqrt5 */
    double e_metric = 1.0 + 0.0 + d12 * d12;
    double e_area = 0.25; /* 1/2 -> 1 */
    double e_angle = pow(atan(0.5) - pi / 4, 2) + pow(atan(2.0) - pi / 4, 2);
    double e_max = 1.0; /* edge 0-1 doubles */
    double e_rms = sqrt((1.0 + pow(d12 / sqrt(2.0), 2)) / 3.0);
    /* Tolerance 1e-14 relative: a handful of roundings on O(1) numbers. */
    assert_true(fabs(q.metric_err - e_metric) <= 1e-14 * e_metric);
    assert_true(fabs(q.area_err - e_area) <= 1e-14 * e_area);
    assert_true(fabs(q.angle_err - e_angle) <= 1e-14 * e_angle);
    assert_true(fabs(q.max_edge_strain - e_max) <= 1e-14);
    assert_true(fabs(q.rms_edge_strain - e_rms) <= 1e-14 * e_rms);
    iso_mesh_destroy(m);
}

static double sum_sq_edges(const iso_mesh *m, const double *x)
{
    double s = 0;
    const int *e = iso_mesh_edges(m);
    for (int k = 0; k < iso_mesh_edge_count(m); k++)
        for (int c = 0; c < 3; c++) {
            double d = x[3 * e[2 * k + 1] + c] - x[3 * e[2 * k] + c];
            s += d * d;
        }
    return s;
}

static double sum_sq_areas(const iso_mesh *m, const double *x)
{
    double s = 0;
    const int *t = iso_mesh_triangles(m);
    for (int k = 0; k < iso_mesh_triangle_count(m); k++) {
        double a[3], b[3], n[3];
        for (int c = 0; c < 3; c++) {
            a[c] = x[3 * t[3 * k + 1] + c] - x[3 * t[3 * k] + c];
            b[c] = x[3 * t[3 * k + 2] + c] - x[3 * t[3 * k] + c];
        }
        fx_cross(a, b, n);
        double A = 0.5 * fx_norm(n);
        s += A * A;
    }
    return s;
}

/* x' = k x: every edge scales by k, every area by k², angles stay. */
static void uniform_scaling_closed_form(void **state)
{
    (void)state;
    fx_rng rng = {7};
    fx_mesh fm = fx_icosphere(2, 1.0, 0.02, &rng);
    iso_mesh *m = fx_make(&fm);
    double *y = malloc(sizeof(double) * 3 * (size_t)fm.nv);
    assert_non_null(y);
    const double ks[] = {0.5, 1.1, 3.0};
    for (int s = 0; s < 3; s++) {
        double k = ks[s];
        for (int i = 0; i < 3 * fm.nv; i++)
            y[i] = k * fm.x[i];
        iso_metrics q;
        iso_metrics_compute(m, fm.x, y, &q);
        double e_metric = (k - 1) * (k - 1) * sum_sq_edges(m, fm.x);
        double e_area = (k * k - 1) * (k * k - 1) * sum_sq_areas(m, fm.x);
        /* 1e-12 relative: lengths carry ~1e-16 relative rounding, and the
         * differences |e'| − |e| = (k−1)|e| lose at most a factor 1/|k−1| = 10. */
        assert_true(fabs(q.metric_err - e_metric) <= 1e-12 * e_metric);
        assert_true(fabs(q.area_err - e_area) <= 1e-12 * e_area);
        /* Angles are unchanged; each carries ~1e-16 rad of rounding, so the
         * sum of 960 squares is ~1e-29: 1e-24 leaves room and still fails
         * for any real angle change. */
        assert_true(q.angle_err <= 1e-24);
        assert_true(fabs(q.max_edge_strain - fabs(k - 1)) <= 1e-13);
        assert_true(fabs(q.rms_edge_strain - fabs(k - 1)) <= 1e-13);
    }
    free(y);
    iso_mesh_destroy(m);
    fx_mesh_free(&fm);
}

/* A rigid motion (rotation + translation) leaves every measure at rounding
 * level: relative 1e-24 to Σ|e|² and ΣA² (squares of 1e-12 relative). */
static void rigid_motion_gives_zero(void **state)
{
    (void)state;
    fx_rng rng = {11};
    fx_mesh fm = fx_icosphere(2, 2.0, 0.02, &rng);
    iso_mesh *m = fx_make(&fm);
    double *y = malloc(sizeof(double) * 3 * (size_t)fm.nv);
    assert_non_null(y);
    double axis[3] = {1, 2, -2}, R[9], p[3] = {0.3, -5, 2};
    for (int c = 0; c < 3; c++)
        axis[c] /= 3.0;
    fx_rotation(axis, 2.1, R);
    for (int i = 0; i < fm.nv; i++)
        for (int r = 0; r < 3; r++)
            y[3 * i + r] = R[3 * r] * fm.x[3 * i] + R[3 * r + 1] * fm.x[3 * i + 1] +
                           R[3 * r + 2] * fm.x[3 * i + 2] + p[r];
    iso_metrics q;
    iso_metrics_compute(m, fm.x, y, &q);
    assert_true(q.metric_err <= 1e-24 * sum_sq_edges(m, fm.x));
    assert_true(q.area_err <= 1e-24 * sum_sq_areas(m, fm.x));
    assert_true(q.angle_err <= 1e-24);
    assert_true(q.max_edge_strain <= 1e-13);
    free(y);
    iso_mesh_destroy(m);
    fx_mesh_free(&fm);
}

/* A sliver whose smallest angle opens from atan(2e-4) to atan(4e-4): the
 * corner angles are known in closed form, and angleErr = 2 (Δθ)² with Δθ ≈
 * 2e-4 (the smallest angle grows by Δθ, the one at vertex 2 shrinks by it).
 * atan2(|a×b|, a·b) keeps each small angle to ~1e-16 absolute, so angleErr
 * is right to ~1e-12 relative; acos of the normalised dot product would be
 * off by ~eps/θ ≈ 1e-12 rad per angle, 7e-10 relative here (measured). The
 * tolerance 1e-10 tells the two apart. */
static void sliver_angles_are_robust(void **state)
{
    (void)state;
    double x0[9] = {0, 0, 0, 1, 0, 0, 1, 2e-4, 0};
    double x1[9] = {0, 0, 0, 1, 0, 0, 1, 4e-4, 0};
    int tri[3] = {0, 1, 2};
    fx_mesh fm = {3, 1, x0, tri};
    iso_mesh *m = fx_make(&fm);
    iso_metrics q;
    iso_metrics_compute(m, x0, x1, &q);
    double d = atan(4e-4) - atan(2e-4);
    double expect = 2 * d * d;
    assert_true(fabs(q.angle_err - expect) <= 1e-10 * expect);
    iso_mesh_destroy(m);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(stretched_triangle_by_hand),
        cmocka_unit_test(uniform_scaling_closed_form),
        cmocka_unit_test(rigid_motion_gives_zero),
        cmocka_unit_test(sliver_angles_are_robust),
    };
    return cmocka_run_group_tests_name("metrics", t, NULL, NULL);
}
