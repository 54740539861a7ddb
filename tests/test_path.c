/* tests/test_path.c -- docs/method.md property 6: path dependence.
 *
 * (1) There and back: a handle turned by θ(t) = θmax sin(π t) returns to
 *     its rest pose at t = 1. The field is linear in the handle's velocity,
 *     v̂ = θ'(t) F(x, θ), so in terms of θ the flow dx/dθ = F(x, θ) retraces
 *     itself exactly: the free vertices come back to the start up to the
 *     integration error, which the test measures (halving the step must cut
 *     the deviation by ~8, third order).
 * (2) Two mirrored paths to the same end pose: a flat plate compressed by
 *     translating its handle by d along the plate, once bulging up (+n),
 *     once down (−n). The measure commutes with reflections, so the two
 *     results are mirror images of each other (to the integration error),
 *     and they differ: each is buckled the way its path went, by far more
 *     than the integration error. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geom_fixtures.c"
#include "iso_integrate.h"
#include "testutil.h"

typedef struct plate {
    fx_mesh fm;
    iso_mesh *m;
    iso_regions r;
    unsigned char *kind;
    iso_solver *s;
} plate;

/* 16 x 6 plate of 2 x 0.6, z = bump(x, y); fixed x < 0.2, handle x > 1.8. */
static void plate_init(plate *p, double bump)
{
    p->fm = fx_grid(16, 6, 2.0, 0.6);
    for (int i = 0; i < p->fm.nv; i++) {
        double *x = p->fm.x + 3 * i;
        x[2] = bump * sin(2.5 * x[0]) * cos(3 * x[1]);
    }
    p->m = fx_make(&p->fm);
    p->kind = malloc((size_t)p->fm.nv);
    assert_non_null(p->kind);
    for (int i = 0; i < p->fm.nv; i++) {
        double x = p->fm.x[3 * i];
        p->kind[i] = x < 0.2 ? ISO_FIXED : x > 1.8 ? ISO_HANDLE : ISO_FREE;
    }
    fx_regions(&p->r, p->fm.nv, p->kind);
    iso_err err;
    iso_err_clear(&err);
    p->s = NULL;
    if (iso_solver_create(p->m, &p->r, NULL, &p->s, &err) != ISO_OK)
        fail_msg("iso_solver_create: %s", err.msg);
}

static void plate_deinit(plate *p)
{
    iso_solver_destroy(p->s);
    iso_regions_deinit(&p->r);
    free(p->kind);
    iso_mesh_destroy(p->m);
    fx_mesh_free(&p->fm);
}

static void integrate(plate *p, const iso_path *path, int steps, double *x)
{
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    io.steps = steps;
    memcpy(x, p->fm.x, sizeof(double) * 3 * (size_t)p->fm.nv);
    iso_integrate_stats st;
    iso_err err;
    iso_err_clear(&err);
    if (iso_integrate(p->s, p->m, &p->r, path, &io, x, &st, &err) != ISO_OK)
        fail_msg("iso_integrate: %s", err.msg);
}

/* Largest distance between free vertices of a and b; b2 (if not NULL)
 * mirrored in z first. */
static double free_distance(const plate *p, const double *a, const double *b, int mirror)
{
    double e = 0;
    for (int i = 0; i < p->fm.nv; i++)
        if (p->kind[i] == ISO_FREE) {
            double d[3] = {a[3 * i] - b[3 * i], a[3 * i + 1] - b[3 * i + 1],
                           a[3 * i + 2] - (mirror ? -b[3 * i + 2] : b[3 * i + 2])};
            e = fmax(e, fx_norm(d));
        }
    return e;
}

#define N_BACK 40

/* θmax = 1 rad about the y axis through (1.8, 0, 0). With 40 and 80 steps:
 * the deviation from the start falls by 6-10x per halving (so it is the
 * integrator's error, going to zero, not a path effect) and is below 1e-3
 * of the largest excursion along the way (measured at t = 1/2). */
static void there_and_back_returns(void **state)
{
    (void)state;
    plate p;
    plate_init(&p, 0.15);
    size_t n = 3 * (size_t)p.fm.nv;
    double *x1 = malloc(sizeof(double) * n), *x2 = malloc(sizeof(double) * n);
    double *xh = malloc(sizeof(double) * n);
    assert_non_null(x1);
    assert_non_null(x2);
    assert_non_null(xh);
    fx_rot_path rp = {{0, 1, 0}, {1.8, 0, 0}, 1.0, 1.0};
    iso_path path = fx_rot_path_make(&rp);
    integrate(&p, &path, N_BACK, x1);
    integrate(&p, &path, 2 * N_BACK, x2);
    /* The excursion: the shape at t = 1/2, where θ = θmax. */
    {
        iso_integrate_opts io;
        iso_integrate_opts_default(&io);
        io.steps = 24;
        io.t1 = 0.5;
        memcpy(xh, p.fm.x, sizeof(double) * n);
        iso_integrate_stats st;
        iso_err err;
        iso_err_clear(&err);
        if (iso_integrate(p.s, p.m, &p.r, &path, &io, xh, &st, &err) != ISO_OK)
            fail_msg("iso_integrate: %s", err.msg);
    }
    double excursion = free_distance(&p, xh, p.fm.x, 0);
    double dev1 = free_distance(&p, x1, p.fm.x, 0), dev2 = free_distance(&p, x2, p.fm.x, 0);
    print_message("excursion %.3g; deviation at %d steps %.3g, %d steps %.3g (ratio %.2f)\n",
                  excursion, N_BACK, dev1, 2 * N_BACK, dev2, dev1 / dev2);
    assert_true(excursion > 0.1);
    assert_true(dev1 / dev2 >= 6 && dev1 / dev2 <= 10);
    assert_true(dev2 <= 1e-3 * excursion);
    /* The handle itself is back exactly (placed from its pose, and the
     * pose at t = 1 is the identity up to sin(π) ≈ 1.2e-16). */
    for (int i = 0; i < p.fm.nv; i++)
        if (p.kind[i] == ISO_HANDLE)
            for (int c = 0; c < 3; c++)
                assert_true(fabs(x2[3 * i + c] - p.fm.x[3 * i + c]) <= 1e-14);
    free(x1);
    free(x2);
    free(xh);
    plate_deinit(&p);
}

/* d = (−0.3, 0, 0) (15% compression), bulge ±0.3 n with n = e_z, on the
 * flat plate. Integration error estimated by |x(32) − x(64)| on the +n
 * path. Asserts: the end poses agree (the handle vertices coincide); the
 * two results are mirror images to 10x that error; they differ by more than
 * 0.05 (2.5% of the plate's length) and by more than 1000x that error. */
static void mirrored_paths_end_in_different_shapes(void **state)
{
    (void)state;
    plate p;
    plate_init(&p, 0.0);
    size_t n = 3 * (size_t)p.fm.nv;
    double *up = malloc(sizeof(double) * n), *down = malloc(sizeof(double) * n);
    double *up2 = malloc(sizeof(double) * n);
    assert_non_null(up);
    assert_non_null(down);
    assert_non_null(up2);
    fx_trans_path pu = {{-0.3, 0, 0}, {0, 0, 0.3}}, pd = {{-0.3, 0, 0}, {0, 0, -0.3}};
    iso_path path_up = fx_trans_path_make(&pu), path_down = fx_trans_path_make(&pd);
    integrate(&p, &path_up, 32, up);
    integrate(&p, &path_up, 64, up2);
    integrate(&p, &path_down, 32, down);
    double ierr = free_distance(&p, up, up2, 0);
    double diff = free_distance(&p, up, down, 0);
    double mirror = free_distance(&p, up, down, 1);
    print_message("integration error ~%.3g; +n vs −n differ by %.3g; mirror mismatch %.3g\n", ierr,
                  diff, mirror);
    for (int i = 0; i < p.fm.nv; i++)
        if (p.kind[i] == ISO_HANDLE)
            for (int c = 0; c < 3; c++)
                assert_true(fabs(up[3 * i + c] - down[3 * i + c]) <= 1e-14);
    assert_true(mirror <= 10 * ierr + 1e-12);
    assert_true(diff > 0.05);
    assert_true(diff > 1000 * ierr);
    free(up);
    free(down);
    free(up2);
    plate_deinit(&p);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(there_and_back_returns),
        cmocka_unit_test(mirrored_paths_end_in_different_shapes),
    };
    return cmocka_run_group_tests_name("path", t, NULL, NULL);
}
