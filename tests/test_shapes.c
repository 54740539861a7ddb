/* tests/test_shapes.c -- the built-in shapes are valid problems: oriented
 * 2-manifolds of the right topology, decent triangles, no self-intersection,
 * both regions present, a rigid handle transform, and accepted by
 * iso_mesh_create. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"

/* ---- topology ---------------------------------------------------------- */

typedef struct half {
    int a, b;    /* a < b */
    int forward; /* 1 if the triangle runs a -> b */
} half;

static int half_cmp(const void *p, const void *q)
{
    const half *x = p, *y = q;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    if (x->b != y->b)
        return x->b < y->b ? -1 : 1;
    return x->forward - y->forward;
}

/* Checks that every edge has one or two triangles and that two triangles
 * on an edge run it in opposite directions. Returns the edge count and the
 * boundary edge count. */
static void check_manifold(const iso_shape *s, int *n_edges, int *n_boundary)
{
    half *h = malloc((size_t)s->nt * 3 * sizeof *h);
    assert_non_null(h);
    for (int t = 0; t < s->nt; t++)
        for (int k = 0; k < 3; k++) {
            int i = s->tri[3 * t + k], j = s->tri[3 * t + (k + 1) % 3];
            assert_true(i >= 0 && i < s->nv && j >= 0 && j < s->nv);
            assert_int_not_equal(i, j);
            h[3 * t + k] = (half){i < j ? i : j, i < j ? j : i, i < j};
        }
    qsort(h, (size_t)s->nt * 3, sizeof *h, half_cmp);
    int ne = 0, nb = 0;
    for (int e = 0; e < 3 * s->nt;) {
        int f = e;
        while (f < 3 * s->nt && h[f].a == h[e].a && h[f].b == h[e].b)
            f++;
        if (f - e > 2)
            fail_msg("%s: edge (%d, %d) has %d triangles", s->name, h[e].a, h[e].b, f - e);
        if (f - e == 2 && h[e].forward == h[e + 1].forward)
            fail_msg("%s: the two triangles on edge (%d, %d) disagree on orientation", s->name,
                     h[e].a, h[e].b);
        nb += f - e == 1;
        ne++;
        e = f;
    }
    free(h);
    *n_edges = ne;
    *n_boundary = nb;
}

/* ---- geometry ---------------------------------------------------------- */

static void sub(const double *a, const double *b, double *d)
{
    for (int k = 0; k < 3; k++)
        d[k] = a[k] - b[k];
}

static void cross(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double quality(const double *a, const double *b, const double *c)
{
    double u[3], v[3], w[3], n[3];
    sub(b, a, u);
    sub(c, a, v);
    sub(c, b, w);
    cross(u, v, n);
    return 2.0 * sqrt(3.0) * sqrt(dot(n, n)) / (dot(u, u) + dot(v, v) + dot(w, w));
}

/* Segment p-q against triangle abc (Möller–Trumbore), closed on both. */
static int segment_hits(const double *p, const double *q, const double *a, const double *b,
                        const double *c)
{
    double e1[3], e2[3], d[3], pv[3], tv[3], qv[3];
    sub(b, a, e1);
    sub(c, a, e2);
    sub(q, p, d);
    cross(d, e2, pv);
    double det = dot(e1, pv);
    /* Parallel or coplanar (a cylinder's neighbouring chords share a
     * vertical line): rounding would decide, so leave it out. */
    if (fabs(det) <= 1e-10 * sqrt(dot(e1, e1) * dot(e2, e2) * dot(d, d)))
        return 0;
    sub(p, a, tv);
    double u = dot(tv, pv) / det;
    if (u < 0 || u > 1)
        return 0;
    cross(tv, e1, qv);
    double v = dot(d, qv) / det, t = dot(e2, qv) / det;
    return v >= 0 && u + v <= 1 && t >= 0 && t <= 1;
}

typedef struct box {
    double lo[3], hi[3];
    int t;
} box;

static int box_cmp(const void *p, const void *q)
{
    const box *x = p, *y = q;
    return x->lo[0] < y->lo[0] ? -1 : x->lo[0] > y->lo[0];
}

/* Triangles that share no vertex must not cross: a sweep over x sorted
 * boxes, then the edges of each against the other. */
static void check_no_self_intersection(const iso_shape *s)
{
    box *bx = malloc((size_t)s->nt * sizeof *bx);
    assert_non_null(bx);
    for (int t = 0; t < s->nt; t++) {
        bx[t].t = t;
        for (int k = 0; k < 3; k++) {
            bx[t].lo[k] = HUGE_VAL;
            bx[t].hi[k] = -HUGE_VAL;
        }
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) {
                double x = s->x[3 * s->tri[3 * t + c] + k];
                bx[t].lo[k] = fmin(bx[t].lo[k], x);
                bx[t].hi[k] = fmax(bx[t].hi[k], x);
            }
    }
    qsort(bx, (size_t)s->nt, sizeof *bx, box_cmp);
    for (int i = 0; i < s->nt; i++)
        for (int j = i + 1; j < s->nt && bx[j].lo[0] <= bx[i].hi[0]; j++) {
            if (bx[j].lo[1] > bx[i].hi[1] || bx[i].lo[1] > bx[j].hi[1] ||
                bx[j].lo[2] > bx[i].hi[2] || bx[i].lo[2] > bx[j].hi[2])
                continue;
            const int *A = s->tri + 3 * bx[i].t, *B = s->tri + 3 * bx[j].t;
            int shared = 0;
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++)
                    shared |= A[a] == B[b];
            if (shared)
                continue;
            for (int pass = 0; pass < 2; pass++) {
                const int *P = pass ? B : A, *Q = pass ? A : B;
                for (int e = 0; e < 3; e++)
                    if (segment_hits(s->x + 3 * P[e], s->x + 3 * P[(e + 1) % 3], s->x + 3 * Q[0],
                                     s->x + 3 * Q[1], s->x + 3 * Q[2]))
                        fail_msg("%s: triangles %d and %d intersect", s->name, bx[i].t, bx[j].t);
            }
        }
    free(bx);
}

static double signed_volume(const iso_shape *s)
{
    double v = 0, c[3];
    for (int t = 0; t < s->nt; t++) {
        const double *a = s->x + 3 * s->tri[3 * t], *b = s->x + 3 * s->tri[3 * t + 1],
                     *d = s->x + 3 * s->tri[3 * t + 2];
        cross(b, d, c);
        v += dot(a, c) / 6.0;
    }
    return v;
}

/* ---- one shape, all checks ---------------------------------------------- */

static void check_shape(const char *name, int res, int closed, int euler)
{
    iso_shape s;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_shape_init(&s, name, res, &err), ISO_OK);
    assert_string_equal(s.name, name);
    assert_true(s.nv > 100 && s.nt > 100);

    int ne, nb;
    check_manifold(&s, &ne, &nb);
    assert_int_equal(s.nv - ne + s.nt, euler);
    if (closed) {
        assert_int_equal(nb, 0);
        assert_true(signed_volume(&s) > 0); /* outward */
    } else {
        assert_true(nb > 0);
    }

    double qmin = 1;
    for (int t = 0; t < s.nt; t++)
        qmin = fmin(qmin, quality(s.x + 3 * s.tri[3 * t], s.x + 3 * s.tri[3 * t + 1],
                                  s.x + 3 * s.tri[3 * t + 2]));
    if (qmin < 0.3)
        fail_msg("%s: worst triangle quality %.3f is below 0.3", name, qmin);
    check_no_self_intersection(&s);

    int count[3] = {0, 0, 0};
    for (int i = 0; i < s.nv; i++) {
        assert_true(s.kind[i] <= ISO_HANDLE);
        count[s.kind[i]]++;
    }
    assert_true(count[ISO_FIXED] > 0 && count[ISO_FREE] > 0 && count[ISO_HANDLE] > 0);

    /* M is rigid: orthonormal rotation, last row 0 0 0 1 */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = 0;
            for (int k = 0; k < 3; k++)
                d += s.M[4 * k + i] * s.M[4 * k + j];
            assert_true(fabs(d - (i == j)) < 1e-12);
        }
    assert_true(s.M[12] == 0 && s.M[13] == 0 && s.M[14] == 0 && s.M[15] == 1);

    iso_regions r = {0};
    assert_int_equal(iso_shape_regions(&s, &r, &err), ISO_OK);
    assert_int_equal(r.nv, s.nv);
    assert_int_equal(r.n_handles, 1);
    for (int i = 0; i < s.nv; i++)
        assert_int_equal(r.handle[i], s.kind[i] == ISO_HANDLE ? 0 : -1);
    iso_regions_deinit(&r);

    iso_mesh *m = NULL;
    if (iso_mesh_create(s.nv, s.x, s.nt, s.tri, s.name, &m, &err) != ISO_OK)
        fail_msg("%s: iso_mesh_create refused it: %s", name, err.msg);
    assert_int_equal(iso_mesh_unreferenced_count(m), 0);
    iso_mesh_destroy(m);
    iso_shape_deinit(&s);
    assert_null(s.x);
}

static void bar_is_a_tube_open_at_the_bottom(void **state)
{
    (void)state;
    check_shape("bar", 0, 0, 1);
    check_shape("bar", 6, 0, 1);
}

static void cylinder_is_closed(void **state)
{
    (void)state;
    check_shape("cylinder", 0, 1, 2);
    check_shape("cylinder", 13, 1, 2);
}

static void bumpplane_is_a_disk(void **state)
{
    (void)state;
    check_shape("bumpplane", 0, 0, 1);
}

static void cactus_is_a_sphere_at_every_resolution(void **state)
{
    (void)state;
    for (int res = 1; res <= 3; res++)
        check_shape("cactus", res, 1, 2);
}

/* The tentacle: a sphere (closed, genus 0) at every frequency, with 10 n²
 * + 2 vertices; at 100k vertices and more its counts, closedness and
 * triangle quality still hold (the pairwise intersection sweep is left to
 * the smaller sizes: along a tall shape it is quadratic). */
static void tentacle_is_a_sphere_at_every_size(void **state)
{
    (void)state;
    check_shape("tentacle", 0, 1, 2);
    check_shape("tentacle", 7, 1, 2);
    check_shape("tentacle", 32, 1, 2);
    iso_shape s;
    iso_err err;
    assert_int_equal(iso_shape_init(&s, "tentacle", 100, &err), ISO_OK);
    assert_int_equal(s.nv, 10 * 100 * 100 + 2);
    assert_int_equal(s.nt, 20 * 100 * 100);
    int ne, nb;
    check_manifold(&s, &ne, &nb);
    assert_int_equal(nb, 0);
    assert_int_equal(s.nv - ne + s.nt, 2);
    assert_true(signed_volume(&s) > 0);
    double qmin = 1;
    for (int t = 0; t < s.nt; t++)
        qmin = fmin(qmin, quality(s.x + 3 * s.tri[3 * t], s.x + 3 * s.tri[3 * t + 1],
                                  s.x + 3 * s.tri[3 * t + 2]));
    printf("tentacle at %d vertices: worst triangle quality %.3f\n", s.nv, qmin);
    assert_true(qmin >= 0.3);
    iso_shape_deinit(&s);
}

static void names_are_listed_and_buildable(void **state)
{
    (void)state;
    const char *const *names = iso_shape_names();
    int n = 0;
    for (; names[n]; n++) {
        iso_shape s;
        assert_int_equal(iso_shape_init(&s, names[n], 0, NULL), ISO_OK);
        iso_shape_deinit(&s);
    }
    assert_int_equal(n, 5);
}

static void unknown_name_and_bad_resolution_are_refused(void **state)
{
    (void)state;
    iso_shape s;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_shape_init(&s, "teapot", 0, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "'teapot'"));
    assert_null(s.x);
    iso_err_clear(&err);
    assert_int_equal(iso_shape_init(&s, "cactus", 99, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "99"));
    assert_non_null(strstr(err.msg, "cactus"));
    iso_shape_deinit(&s);
    iso_shape_deinit(NULL);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(bar_is_a_tube_open_at_the_bottom),
        cmocka_unit_test(cylinder_is_closed),
        cmocka_unit_test(bumpplane_is_a_disk),
        cmocka_unit_test(cactus_is_a_sphere_at_every_resolution),
        cmocka_unit_test(tentacle_is_a_sphere_at_every_size),
        cmocka_unit_test(names_are_listed_and_buildable),
        cmocka_unit_test(unknown_name_and_bad_resolution_are_refused),
    };
    return cmocka_run_group_tests_name("shapes", t, NULL, NULL);
}
