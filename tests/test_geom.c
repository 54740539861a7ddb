/* tests/test_geom.c -- rigid poses and twists (common/iso_geom.h), the one
 * place pose products are written: composition agrees with applying one
 * pose after the other, the inverse-free logarithm iso_twist_between carries
 * one pose onto another, a rotation about a point keeps that point, and the
 * matrix form applies like the pose. Poses are exp(ξ) of twists drawn by a
 * fixed LCG, rotations short of a half-turn. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "iso_geom.h"
#include "testutil.h"

static unsigned lcg = 12345u;
static double uniform(void) /* in [-1, 1) */
{
    lcg = lcg * 1103515245u + 12345u;
    return (double)(lcg >> 8) / (double)(1u << 23) - 1.0;
}

static void random_pose(iso_pose *g)
{
    iso_twist xi;
    for (int i = 0; i < 3; i++) {
        xi.w[i] = 1.6 * uniform(); /* |w| < 2.8 < π */
        xi.v[i] = 5.0 * uniform();
    }
    iso_twist_exp(&xi, 1.0, g);
}

static double pose_diff(const iso_pose *a, const iso_pose *b)
{
    return fmax(iso_test_max_abs_diff(a->R, b->R, 9), iso_test_max_abs_diff(a->p, b->p, 3));
}

static void compose_is_apply_after_apply(void **state)
{
    (void)state;
    for (int k = 0; k < 100; k++) {
        iso_pose a, b, ab;
        random_pose(&a);
        random_pose(&b);
        iso_pose_compose(&a, &b, &ab);
        double x[3] = {uniform(), uniform(), uniform()}, bx[3], abx[3], y[3], r[3];
        iso_pose_apply(&b, x, bx);
        iso_pose_apply(&a, bx, abx);
        iso_pose_apply(&ab, x, y);
        assert_true(iso_test_max_abs_diff(abx, y, 3) < 1e-12);
        /* the rotation alone is the pose without its translation */
        iso_pose_rotate(&ab, x, r);
        for (int i = 0; i < 3; i++)
            assert_true(fabs(r[i] + ab.p[i] - y[i]) < 1e-12);
    }
}

static void twist_between_carries_a_onto_b(void **state)
{
    (void)state;
    double worst = 0;
    for (int k = 0; k < 100; k++) {
        iso_pose a, b, e, got;
        random_pose(&a);
        random_pose(&b);
        iso_twist xi;
        iso_err err;
        iso_err_clear(&err);
        if (iso_twist_between(&a, &b, &xi, &err) != ISO_OK)
            continue; /* b a⁻¹ may be a half-turn: tested below */
        iso_twist_exp(&xi, 1.0, &e);
        iso_pose_compose(&e, &a, &got);
        worst = fmax(worst, pose_diff(&got, &b));
    }
    printf("exp(twist_between(a, b)) a against b: %.3g at worst\n", worst);
    assert_true(worst < 1e-11);
    /* a half-turn has no unique screw: refused, with a sentence */
    iso_pose a, b;
    iso_pose_identity(&a);
    iso_pose_identity(&b);
    b.R[0] = b.R[4] = -1; /* π about z */
    iso_twist xi;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_twist_between(&a, &b, &xi, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "180 degrees"));
}

static void rotation_about_a_point_keeps_it(void **state)
{
    (void)state;
    for (int k = 0; k < 50; k++) {
        iso_pose r, g;
        random_pose(&r);
        double c[3] = {3 * uniform(), 3 * uniform(), 3 * uniform()};
        double t[3] = {uniform(), uniform(), uniform()}, y[3], x[3], rx[3], gx[3];
        iso_pose_about(r.R, c, NULL, &g);
        iso_pose_apply(&g, c, y);
        assert_true(iso_test_max_abs_diff(y, c, 3) < 1e-12);
        iso_pose_about(r.R, c, t, &g);
        iso_pose_apply(&g, c, y);
        for (int i = 0; i < 3; i++)
            assert_true(fabs(y[i] - c[i] - t[i]) < 1e-12);
        /* y = R (x − c) + c + t for any x */
        for (int i = 0; i < 3; i++)
            x[i] = uniform() - c[i];
        iso_pose_rotate(&r, x, rx);
        for (int i = 0; i < 3; i++)
            x[i] += c[i];
        iso_pose_apply(&g, x, gx);
        for (int i = 0; i < 3; i++)
            assert_true(fabs(gx[i] - (rx[i] + c[i] + t[i])) < 1e-12);
    }
}

static void matrix_form_applies_like_the_pose(void **state)
{
    (void)state;
    iso_pose g;
    random_pose(&g);
    double M[16], x[3] = {0.3, -1.2, 2.5}, y[3];
    iso_pose_to_matrix(&g, M);
    iso_pose_apply(&g, x, y);
    for (int i = 0; i < 3; i++)
        assert_true(fabs(M[4 * i] * x[0] + M[4 * i + 1] * x[1] + M[4 * i + 2] * x[2] +
                         M[4 * i + 3] - y[i]) < 1e-12);
    assert_true(M[12] == 0 && M[13] == 0 && M[14] == 0 && M[15] == 1);
    /* and the logarithm of that matrix is the twist it came from */
    iso_twist xi;
    iso_pose back;
    assert_int_equal(iso_twist_from_matrix(M, &xi, NULL), ISO_OK);
    iso_twist_exp(&xi, 1.0, &back);
    assert_true(pose_diff(&back, &g) < 1e-12);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(compose_is_apply_after_apply),
        cmocka_unit_test(twist_between_carries_a_onto_b),
        cmocka_unit_test(rotation_about_a_point_keeps_it),
        cmocka_unit_test(matrix_form_applies_like_the_pose),
    };
    return cmocka_run_group_tests_name("geom", t, NULL, NULL);
}
