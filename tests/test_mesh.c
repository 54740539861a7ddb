/* tests/test_mesh.c -- iso_mesh_create: validation order, messages, topology. */
#include "testutil.h"

#include <math.h>
#include <string.h>

#include "iso_mesh.h"

/* A unit square split into two triangles, plus one unreferenced vertex (4). */
static const double square_x[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 5, 5, 5};
static const int square_t[] = {0, 1, 2, 0, 2, 3};

/* A closed tetrahedron. */
static const double tet_x[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
static const int tet_t[] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};

static void expect_fail(int nv, const double *x, int nt, const int *tri, const long *src,
                        int is_off, int code, const char *s1, const char *s2)
{
    iso_err err;
    iso_err_clear(&err);
    iso_mesh *m = (iso_mesh *)1;
    int rc = iso_mesh_create_src(nv, x, nt, tri, "t.off", src, is_off, &m, &err);
    print_message("message: %s\n", err.msg);
    assert_int_equal(rc, code);
    assert_int_equal(err.code, code);
    assert_null(m);
    assert_non_null(strstr(err.msg, "t.off"));
    if (s1)
        assert_non_null(strstr(err.msg, s1));
    if (s2)
        assert_non_null(strstr(err.msg, s2));
}

static void square_topology(void **state)
{
    (void)state;
    iso_mesh *m = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_mesh_create(5, square_x, 2, square_t, "sq", &m, &err), ISO_OK);
    assert_int_equal(iso_mesh_vertex_count(m), 5);
    assert_int_equal(iso_mesh_triangle_count(m), 2);
    assert_int_equal(iso_mesh_edge_count(m), 5);
    const int *e = iso_mesh_edges(m), *et = iso_mesh_edge_triangles(m);
    static const int want_e[] = {0, 1, 0, 2, 0, 3, 1, 2, 2, 3};
    static const int want_t[] = {0, -1, 0, 1, 1, -1, 0, -1, 1, -1};
    assert_memory_equal(e, want_e, sizeof want_e);
    assert_memory_equal(et, want_t, sizeof want_t);
    assert_int_equal(iso_mesh_unreferenced_count(m), 1);
    assert_true(iso_mesh_vertex_used(m, 0));
    assert_false(iso_mesh_vertex_used(m, 4));
    assert_false(iso_mesh_vertex_used(m, 5));
    assert_false(iso_mesh_vertex_used(m, -1));
    /* the far-away unreferenced vertex must not count in the diagonal */
    assert_true(fabs(iso_mesh_bbox_diagonal(m) - sqrt(2.0)) < 1e-15);
    assert_string_equal(iso_mesh_origin(m), "sq");
    assert_string_equal(iso_mesh_note(m), "");
    assert_memory_equal(iso_mesh_positions(m), square_x, sizeof square_x);
    assert_memory_equal(iso_mesh_triangles(m), square_t, sizeof square_t);
    iso_mesh_destroy(m);
    iso_mesh_destroy(NULL);
}

static void closed_tet_has_no_boundary(void **state)
{
    (void)state;
    iso_mesh *m = NULL;
    assert_int_equal(iso_mesh_create(4, tet_x, 4, tet_t, NULL, &m, NULL), ISO_OK);
    assert_int_equal(iso_mesh_edge_count(m), 6);
    const int *e = iso_mesh_edges(m), *et = iso_mesh_edge_triangles(m);
    for (int k = 0; k < 6; k++) {
        assert_true(e[2 * k] < e[2 * k + 1]);
        if (k)
            assert_true(e[2 * k - 2] < e[2 * k] ||
                        (e[2 * k - 2] == e[2 * k] && e[2 * k - 1] < e[2 * k + 1]));
        assert_true(et[2 * k] >= 0 && et[2 * k + 1] >= 0 && et[2 * k] < et[2 * k + 1]);
    }
    assert_int_equal(iso_mesh_unreferenced_count(m), 0);
    assert_string_equal(iso_mesh_origin(m), "mesh");
    iso_mesh_destroy(m);
}

static void bad_counts(void **state)
{
    (void)state;
    expect_fail(2, square_x, 1, square_t, NULL, 0, ISO_EMESH, "at least 3 vertices", NULL);
    expect_fail(4, square_x, 0, square_t, NULL, 0, ISO_EMESH, "no triangles", NULL);
    expect_fail(-1, square_x, 1, square_t, NULL, 0, ISO_EINVAL, NULL, NULL);
    expect_fail(4, NULL, 1, square_t, NULL, 0, ISO_EINVAL, NULL, NULL);
}

static void index_out_of_range(void **state)
{
    (void)state;
    static const int t[] = {0, 1, 2, 0, 2, 7};
    static const long src[] = {10, 11};
    expect_fail(4, square_x, 2, t, src, 0, ISO_EPARSE, "line 11: triangle 1",
                "index 7 out of range (the mesh has nv = 4");
    expect_fail(4, square_x, 2, t, src, 1, ISO_EPARSE, "byte offset 11", "nv = 4");
    static const int neg[] = {0, -1, 2};
    expect_fail(4, square_x, 1, neg, NULL, 0, ISO_EPARSE, "t.off: triangle 0", "index -1");
}

static void repeated_index(void **state)
{
    (void)state;
    static const int t[] = {0, 1, 2, 3, 2, 3};
    static const long src[] = {4, 5};
    expect_fail(4, square_x, 2, t, src, 0, ISO_EPARSE, "line 5: triangle 1 repeats", "(3, 2, 3)");
}

static void non_finite(void **state)
{
    (void)state;
    double x[12];
    memcpy(x, square_x, sizeof x);
    x[7] = NAN;
    expect_fail(4, x, 2, square_t, NULL, 0, ISO_EPARSE, "vertex 2", "non-finite");
    x[7] = INFINITY;
    expect_fail(4, x, 2, square_t, NULL, 0, ISO_EPARSE, "vertex 2", "inf");
}

static void duplicated_triangle(void **state)
{
    (void)state;
    static const int t[] = {0, 1, 2, 0, 2, 3, 2, 0, 1};
    static const long src[] = {3, 4, 5};
    expect_fail(4, square_x, 3, t, src, 0, ISO_EMESH,
                "line 5: triangle 2 duplicates triangle 0 (line 3)", "{0, 1, 2}");
    /* two duplicated pairs: the one whose copy comes first is reported */
    static const int t2[] = {0, 1, 2, 0, 2, 3, 3, 2, 0, 1, 2, 0, 0, 1, 2};
    expect_fail(4, square_x, 5, t2, NULL, 0, ISO_EMESH, "triangle 2 duplicates triangle 1",
                "{0, 2, 3}");
}

static void degenerate_triangle(void **state)
{
    (void)state;
    /* vertex 3 on the segment 0-1: a needle of zero area */
    static const double x[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.5, 1e-9, 0};
    static const int t[] = {0, 1, 2, 0, 3, 1};
    static const long src[] = {20, 21};
    expect_fail(4, x, 2, t, src, 0, ISO_EMESH, "line 21: triangle 1 (vertices 0, 3, 1)",
                "quality q = ");
    /* coincident points */
    static const double y[] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    static const int t1[] = {0, 1, 2};
    expect_fail(3, y, 1, t1, NULL, 0, ISO_EMESH, "triangle 0", "q = 0 <");
}

static void huge_and_tiny_coordinates_are_fine(void **state)
{
    (void)state;
    for (double s = 1e-150; s < 1e151; s *= 1e50) {
        double x[12];
        for (int i = 0; i < 12; i++)
            x[i] = square_x[i] * s;
        iso_mesh *m = NULL;
        iso_err err;
        iso_err_clear(&err);
        assert_int_equal(iso_mesh_create(4, x, 2, square_t, NULL, &m, &err), ISO_OK);
        iso_mesh_destroy(m);
    }
}

static void non_manifold_edge(void **state)
{
    (void)state;
    /* three fins on edge (0, 1) */
    static const double x[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0};
    static const int t[] = {0, 1, 2, 0, 1, 3, 1, 0, 4};
    static const long src[] = {7, 8, 9};
    expect_fail(5, x, 3, t, src, 0, ISO_EMESH, "line 9: non-manifold edge (0, 1)",
                "shared by 3 triangles (0, 1, 2)");
}

/* Order: an index error wins over a duplicate that comes earlier. */
static void validation_order(void **state)
{
    (void)state;
    double x[12];
    memcpy(x, square_x, sizeof x);
    x[0] = NAN;
    static const int t[] = {0, 1, 2, 0, 1, 2, 0, 1, 9};
    expect_fail(4, x, 3, t, NULL, 0, ISO_EPARSE, "index 9", NULL);
    expect_fail(4, x, 2, t, NULL, 0, ISO_EPARSE, "non-finite", NULL);
    expect_fail(4, square_x, 2, t, NULL, 0, ISO_EMESH, "duplicates", NULL);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(square_topology),
        cmocka_unit_test(closed_tet_has_no_boundary),
        cmocka_unit_test(bad_counts),
        cmocka_unit_test(index_out_of_range),
        cmocka_unit_test(repeated_index),
        cmocka_unit_test(non_finite),
        cmocka_unit_test(duplicated_triangle),
        cmocka_unit_test(degenerate_triangle),
        cmocka_unit_test(huge_and_tiny_coordinates_are_fine),
        cmocka_unit_test(non_manifold_edge),
        cmocka_unit_test(validation_order),
    };
    return cmocka_run_group_tests_name("mesh", t, NULL, NULL);
}
