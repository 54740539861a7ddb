/* tests/test_mesh_io.c -- OFF/OBJ/PLY reading and writing: round trips,
 * format features, and every refused input with its code and message. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_mesh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Loads `len` bytes (or the string) written to tmp/<name>. */
static int load_bytes(const char *name, const char *text, long len, iso_mesh **m, iso_err *err)
{
    char path[512];
    iso_test_tmp(path, sizeof path, name);
    iso_test_write(path, text, len);
    iso_err_clear(err);
    return iso_mesh_load(path, m, err);
}

static iso_mesh *load_ok(const char *name, const char *text, long len)
{
    iso_mesh *m = NULL;
    iso_err err;
    int rc = load_bytes(name, text, len, &m, &err);
    if (rc != ISO_OK)
        fail_msg("%s: unexpected error %d: %s", name, rc, err.msg);
    return m;
}

/* Asserts the load fails with `code` and a message holding the file name and
 * both substrings (NULL: not checked). */
static void expect_fail_bytes(const char *name, const char *text, long len, int code,
                              const char *s1, const char *s2)
{
    iso_mesh *m = (iso_mesh *)1;
    iso_err err;
    int rc = load_bytes(name, text, len, &m, &err);
    print_message("%-12s -> %s\n", name, err.msg);
    assert_int_equal(rc, code);
    assert_int_equal(err.code, code);
    assert_null(m);
    assert_non_null(strstr(err.msg, name));
    if (s1 && !strstr(err.msg, s1))
        fail_msg("'%s' not in '%s'", s1, err.msg);
    if (s2 && !strstr(err.msg, s2))
        fail_msg("'%s' not in '%s'", s2, err.msg);
}

static void expect_fail(const char *name, const char *text, int code, const char *s1,
                        const char *s2)
{
    expect_fail_bytes(name, text, -1, code, s1, s2);
}

/* ==== round trips ======================================================== */

static void round_trip_every_format(void **state)
{
    (void)state;
    /* Awkward doubles: no short decimal form, tiny, huge, negative zero. */
    double x[] = {0.1, 1.0 / 3, -0.0,    1 + 1e-15,          2.0 / 7, 1e-300, M_PI, 1e300 * 0 + 2.5,
                  3,   -1e-7,   7.0 / 3, 12.345678901234567, 42,      42,     42};
    const int tri[] = {0, 1, 2, 0, 2, 3};
    iso_mesh *m = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_mesh_create(5, x, 2, tri, "rt", &m, &err), ISO_OK);
    double moved[15];
    for (int i = 0; i < 15; i++)
        moved[i] = x[i] * 1.000000000000001 + 1e-17;
    static const struct {
        const char *name;
        iso_mesh_format fmt;
    } f[] = {{"rt.off", ISO_MESH_FMT_OFF},         {"rt.obj", ISO_MESH_FMT_OBJ},
             {"rt_a.ply", ISO_MESH_FMT_PLY_ASCII}, {"rt_b.ply", ISO_MESH_FMT_PLY_BINARY},
             {"rt_auto.PLY", ISO_MESH_FMT_AUTO},   {"rt_auto.off", ISO_MESH_FMT_AUTO}};
    for (size_t i = 0; i < sizeof f / sizeof f[0]; i++)
        for (int use_moved = 0; use_moved < 2; use_moved++) {
            char path[512];
            iso_test_tmp(path, sizeof path, f[i].name);
            const double *want = use_moved ? moved : x;
            assert_int_equal(iso_mesh_save(m, use_moved ? moved : NULL, path, f[i].fmt, &err),
                             ISO_OK);
            iso_mesh *r = NULL;
            assert_int_equal(iso_mesh_load(path, &r, &err), ISO_OK);
            assert_int_equal(iso_mesh_vertex_count(r), 5);
            assert_int_equal(iso_mesh_triangle_count(r), 2);
            assert_memory_equal(iso_mesh_positions(r), want, sizeof x); /* bit-exact */
            assert_memory_equal(iso_mesh_triangles(r), tri, sizeof tri);
            assert_int_equal(iso_mesh_unreferenced_count(r), 1);
            iso_mesh_destroy(r);
        }
    iso_mesh_destroy(m);
}

static void save_errors(void **state)
{
    (void)state;
    const double x[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const int tri[] = {0, 1, 2};
    iso_mesh *m = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_mesh_create(3, x, 1, tri, NULL, &m, &err), ISO_OK);
    char path[512];
    assert_int_equal(
        iso_mesh_save(m, NULL, iso_test_tmp(path, sizeof path, "a.stl"), ISO_MESH_FMT_AUTO, &err),
        ISO_ENOTSUP);
    assert_non_null(strstr(err.msg, "a.stl"));
    iso_err_clear(&err);
    assert_int_equal(iso_mesh_save(m, NULL, "/nonexistent-dir/x.off", ISO_MESH_FMT_AUTO, &err),
                     ISO_EIO);
    assert_non_null(strstr(err.msg, "/nonexistent-dir/x.off"));
    iso_err_clear(&err);
    double bad[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    assert_int_equal(
        iso_mesh_save(m, bad, iso_test_tmp(path, sizeof path, "nan.off"), ISO_MESH_FMT_OFF, &err),
        ISO_EINVAL);
    assert_non_null(strstr(err.msg, "vertex 2"));
    iso_mesh_destroy(m);
}

/* ==== OFF ================================================================ */

static void off_features(void **state)
{
    (void)state;
    iso_mesh *m = load_ok("feat.off",
                          "# a comment\n"
                          "OFF\n"
                          "\n"
                          "5  2 0   # counts, extra spaces\n"
                          "0 0 0\n"
                          "1 0 0 # trailing comment\r\n"
                          "1 1 0 0.5 0.5 0.5 1\n" /* colour values ignored */
                          "0 1 0\n"
                          "9 9 9\n" /* unreferenced */
                          "3 0 1 2 255 0 0\n"
                          "3  0 2 3\n"
                          "\n",
                          -1);
    assert_int_equal(iso_mesh_vertex_count(m), 5);
    assert_int_equal(iso_mesh_triangle_count(m), 2);
    assert_int_equal(iso_mesh_unreferenced_count(m), 1);
    assert_false(iso_mesh_vertex_used(m, 4));
    assert_true(fabs(iso_mesh_bbox_diagonal(m) - sqrt(2.0)) < 1e-15);
    assert_string_equal(iso_mesh_note(m), "");
    iso_mesh_destroy(m);
    /* counts on the keyword line, COFF, no final newline */
    m = load_ok("same.off", "COFF 3 1 0\n0 0 0 1 1 1\n1 0 0 1 1 1\n0 1 0 1 1 1\n3 0 1 2", -1);
    assert_int_equal(iso_mesh_triangle_count(m), 1);
    iso_mesh_destroy(m);
}

static void off_quad_note(void **state)
{
    (void)state;
    iso_mesh *m = load_ok("quads.off",
                          "OFF\n6 2 0\n0 0 0\n1 0 0\n2 0 0\n0 1 0\n1 1 0\n2 1 0\n"
                          "4 0 1 4 3\n4 1 2 5 4\n",
                          -1);
    assert_int_equal(iso_mesh_triangle_count(m), 4);
    assert_non_null(strstr(iso_mesh_note(m), "quads.off: triangulated 2 convex polygons "
                                             "(quads: 2)"));
    iso_mesh_destroy(m);
}

static void off_errors(void **state)
{
    (void)state;
    expect_fail("empty.off", "", ISO_EPARSE, "empty file", NULL);
    expect_fail("hdr.off", "PLY\n3 1 0\n", ISO_EPARSE, "line 1", "expected the OFF header");
    expect_fail("cnt.off", "OFF\n3 x 0\n", ISO_EPARSE, "line 2", "'x' is not a non-negative");
    expect_fail("cnt1.off", "OFF\n3\n", ISO_EPARSE, "line 2", "found 1 number");
    expect_fail("huge.off", "OFF\n2000000000 2000000000 0\n0 0 0\n", ISO_EPARSE, "line 2",
                "only 6 bytes follow");
    expect_fail("trv.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n# padding padding\n", ISO_EPARSE,
                "after 2 of 3 vertices", NULL);
    expect_fail("trf.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n# padding\n", ISO_EPARSE,
                "after 1 of 2 faces", NULL);
    expect_fail("garb.off", "OFF\n3 1 0\n0 0 0\n1 zz 0\n0 1 0\n3 0 1 2\n", ISO_EPARSE, "line 4",
                "'zz' is not a number");
    expect_fail("short.off", "OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", ISO_EPARSE, "line 4",
                "2 coordinate(s)");
    expect_fail("nan.off", "OFF\n3 1 0\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", ISO_EPARSE, "line 4",
                "vertex 1 has a non-finite");
    expect_fail("two.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", ISO_EPARSE, "line 6",
                "2 vertices; a face needs at least 3");
    expect_fail("few.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", ISO_EPARSE, "line 6",
                "announces 3 vertices but lists 2");
    expect_fail("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", ISO_EPARSE, "line 6",
                "index 3 out of range (the file has nv = 3");
    expect_fail("idx.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n", ISO_EPARSE, "line 6",
                "'2.5' is not an integer");
    expect_fail("tail.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", ISO_EPARSE,
                "line 7", "after the 1 faces");
    expect_fail_bytes("nul.off", "OFF\n3 1 0\n0 0 0\n1\0 0 0\n0 1 0\n3 0 1 2\n", 34, ISO_EPARSE,
                      "line 4", NULL);
}

/* Mesh-level checks report the source line of the face. */
static void off_mesh_errors_name_lines(void **state)
{
    (void)state;
    expect_fail("rep.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 1\n", ISO_EPARSE, "line 6",
                "repeats a vertex index");
    expect_fail("dup.off", "OFF\n4 3 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n3 2 1 0\n",
                ISO_EMESH, "line 9: triangle 2 duplicates triangle 0 (line 7)", NULL);
    expect_fail("deg.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n2 0 0\n3 0 1 2\n3 0 1 3\n", ISO_EMESH,
                "line 8: triangle 1 (vertices 0, 1, 3)", "quality q = 0");
    expect_fail("nm.off",
                "OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 -1 0\n3 0 1 2\n3 0 1 3\n3 1 0 4\n",
                ISO_EMESH, "line 10: non-manifold edge (0, 1)", "(0, 1, 2)");
    expect_fail("notri.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", ISO_EMESH, "no triangles", NULL);
}

static void other_load_errors(void **state)
{
    (void)state;
    expect_fail("mesh.stl", "solid\n", ISO_ENOTSUP, "unknown mesh file extension", NULL);
    iso_mesh *m = (iso_mesh *)1;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_mesh_load("/nonexistent-dir/none.off", &m, &err), ISO_EIO);
    assert_null(m);
    assert_non_null(strstr(err.msg, "/nonexistent-dir/none.off: cannot open"));
}

/* ==== OBJ ================================================================ */

static void obj_features(void **state)
{
    (void)state;
    iso_mesh *m = load_ok("feat.obj",
                          "# comment\n"
                          "mtllib a.mtl\no thing\ng grp\ns off\nusemtl red\n"
                          "v 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0 0.1 0.2 0.3\n"
                          "vt 0 0\nvn 0 0 1\n"
                          "f 1/1/1 2/1/1 3/1/1\n"
                          "f -4//1 -2//1 -1//1\n"
                          "v 5 5 5\n" /* unreferenced */
                          "l 1 2\n",
                          -1);
    assert_int_equal(iso_mesh_vertex_count(m), 5);
    assert_int_equal(iso_mesh_triangle_count(m), 2);
    static const int want[] = {0, 1, 2, 0, 2, 3};
    assert_memory_equal(iso_mesh_triangles(m), want, sizeof want);
    assert_int_equal(iso_mesh_unreferenced_count(m), 1);
    iso_mesh_destroy(m);
    /* i/j corners, a face that names a vertex defined later */
    m = load_ok("fwd.obj", "v 0 0 0\nv 1 0 0\nf 1/1 2/2 3/3\nv 0 1 0\n", -1);
    assert_int_equal(iso_mesh_triangle_count(m), 1);
    iso_mesh_destroy(m);
}

static void obj_polygons(void **state)
{
    (void)state;
    /* a quad and a convex, slightly non-planar hexagon */
    iso_mesh *m = load_ok("cactus.obj",
                          "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                          "v 3 0 0\nv 4 0 0.01\nv 4.5 1 0\nv 4 2 -0.01\nv 3 2 0\n"
                          "v 2.5 1 0\n"
                          "f 1 2 3 4\nf 5 6 7 8 9 10\n",
                          -1);
    assert_int_equal(iso_mesh_triangle_count(m), 2 + 4);
    assert_non_null(strstr(iso_mesh_note(m), "cactus.obj: triangulated 2 convex polygons "
                                             "(quads: 1, 5 or more vertices: 1)"));
    iso_mesh_destroy(m);
    /* the same quad wound the other way round is still convex */
    m = load_ok("cw.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 4 3 2 1\n", -1);
    assert_int_equal(iso_mesh_triangle_count(m), 2);
    iso_mesh_destroy(m);
}

static void obj_non_convex_refused(void **state)
{
    (void)state;
    /* an arrowhead: vertex 4 is reflex */
    expect_fail("arrow.obj", "v 0 0 0\nv 2 1 0\nv 0 2 0\nv 1 1 0\n\nf 1 2 3 4\n", ISO_EMESH,
                "line 6: face 0 is a non-convex", "4 vertices");
    /* a pentagram: all turns left, but twice around */
    char text[1024];
    size_t o = 0;
    for (int i = 0; i < 5; i++)
        o += (size_t)snprintf(text + o, sizeof text - o, "v %.17g %.17g 0\n",
                              cos(2 * M_PI * 2 * i / 5), sin(2 * M_PI * 2 * i / 5));
    snprintf(text + o, sizeof text - o, "f 1 2 3 4 5\n");
    expect_fail("star.obj", text, ISO_EMESH, "line 6", "non-convex");
    /* all corners on one line */
    expect_fail("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3 4\n", ISO_EMESH, "line 5",
                "degenerate polygon");
}

static void obj_errors(void **state)
{
    (void)state;
    expect_fail("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", ISO_EPARSE, "line 4",
                "index 0");
    expect_fail("rel.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", ISO_EPARSE, "line 4",
                "before the first vertex");
    expect_fail("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", ISO_EPARSE, "line 4",
                "index 4 out of range (the file has nv = 3 vertices, valid 1..3)");
    expect_fail("kw.obj", "v 0 0 0\nbogus 1 2\n", ISO_EPARSE, "line 2",
                "unknown OBJ statement 'bogus'");
    expect_fail("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n", ISO_EPARSE, "line 3",
                "face 0 has 2 vertices");
    expect_fail("corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3/x\n", ISO_EPARSE, "line 4",
                "corner '3/x'");
    expect_fail("vtx.obj", "v 0 0\n", ISO_EPARSE, "line 1", "2 coordinate(s)");
    expect_fail("inf.obj", "v 0 0 1e999\n", ISO_EPARSE, "line 1", "non-finite");
    expect_fail("none.obj", "# nothing\n", ISO_EMESH, "at least 3 vertices", NULL);
}

/* ==== PLY ================================================================ */

static void ply_ascii_features(void **state)
{
    (void)state;
    iso_mesh *m = load_ok("feat.ply",
                          "ply\r\n"
                          "format ascii 1.0\r\n"
                          "comment made by hand\n"
                          "obj_info nothing\n"
                          "element vertex 5\n"
                          "property float x\nproperty float y\n"
                          "property uchar red\n" /* between x/y and z */
                          "property double z\n"
                          "property list uchar float extra\n"
                          "element face 2\n"
                          "property int flags\n"
                          "property list uint8 uint32 vertex_index\n"
                          "element edge 1\n"
                          "property int a\nproperty int b\n"
                          "end_header\n"
                          "0 0 255 0 0\n1 0 255 0 2 0.5 0.5\n1 1 1 0 1 7\n0 1 0 0 0\n"
                          "9 9 9 9 0\n"
                          "7 3 0 1 2\n7 3 0 2 3\n"
                          "0 1\n",
                          -1);
    assert_int_equal(iso_mesh_vertex_count(m), 5);
    assert_int_equal(iso_mesh_triangle_count(m), 2);
    assert_int_equal(iso_mesh_unreferenced_count(m), 1);
    assert_true(iso_mesh_positions(m)[13] == 9.0);
    iso_mesh_destroy(m);
}

/* A byte buffer for hand-built binary PLY bodies. */
typedef struct bytes {
    unsigned char b[1024];
    size_t n;
    int be;
} bytes;

static void put(bytes *o, const void *v, size_t size)
{
    unsigned char tmp[8];
    memcpy(tmp, v, size);
    for (size_t i = 0; i < size; i++) /* the test host is little endian */
        o->b[o->n++] = tmp[o->be ? size - 1 - i : i];
}
static void put_f32(bytes *o, float f)
{
    put(o, &f, 4);
}
static void put_u8(bytes *o, unsigned v)
{
    unsigned char c = (unsigned char)v;
    put(o, &c, 1);
}
static void put_i16(bytes *o, int v)
{
    short s = (short)v;
    put(o, &s, 2);
}
static void put_text(bytes *o, const char *s)
{
    size_t n = strlen(s);
    memcpy(o->b + o->n, s, n);
    o->n += n;
}

/* Square with one unreferenced vertex: x,y,z float plus a ushort; faces
 * with a uchar flag before a short-typed list; a skipped element with a
 * list. */
static void build_binary(bytes *o, int be)
{
    memset(o, 0, sizeof *o);
    o->be = be;
    put_text(o, "ply\n");
    put_text(o, be ? "format binary_big_endian 1.0\n" : "format binary_little_endian 1.0\n");
    put_text(o, "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                "property ushort q\n"
                "element face 2\nproperty uchar flag\nproperty list uchar short vertex_indices\n"
                "element junk 1\nproperty list int double v\n"
                "end_header\n");
    static const float v[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 5, 5, 5};
    for (int i = 0; i < 5; i++) {
        for (int k = 0; k < 3; k++)
            put_f32(o, v[3 * i + k]);
        put_i16(o, 65535);
    }
    static const int f[] = {0, 1, 2, 0, 2, 3};
    for (int i = 0; i < 2; i++) {
        put_u8(o, 9);
        put_u8(o, 3);
        for (int k = 0; k < 3; k++)
            put_i16(o, f[3 * i + k]);
    }
    int cnt = 1;
    put(o, &cnt, 4);
    double d = 1.5;
    put(o, &d, 8);
}

static void ply_binary_both_endians(void **state)
{
    (void)state;
    for (int be = 0; be < 2; be++) {
        bytes o;
        build_binary(&o, be);
        iso_mesh *m = load_ok(be ? "be.ply" : "le.ply", (const char *)o.b, (long)o.n);
        assert_int_equal(iso_mesh_vertex_count(m), 5);
        assert_int_equal(iso_mesh_triangle_count(m), 2);
        static const int want[] = {0, 1, 2, 0, 2, 3};
        assert_memory_equal(iso_mesh_triangles(m), want, sizeof want);
        assert_true(iso_mesh_positions(m)[6] == 1.0 && iso_mesh_positions(m)[7] == 1.0);
        assert_int_equal(iso_mesh_unreferenced_count(m), 1);
        iso_mesh_destroy(m);
    }
}

static void ply_binary_errors(void **state)
{
    (void)state;
    bytes o;
    build_binary(&o, 0);
    size_t body = (size_t)(strstr((const char *)o.b, "end_header\n") - (const char *)o.b) + 11;
    /* truncated inside the face list: named by byte offset */
    expect_fail_bytes("trunc.ply", (const char *)o.b, (long)(body + 5 * 14 + 6), ISO_EPARSE,
                      "byte offset", "face 0 lists 3 values but the file ends first");
    /* truncated inside the vertices: count check before reading */
    char want[64];
    snprintf(want, sizeof want, "byte offset %zu", body);
    expect_fail_bytes("trv.ply", (const char *)o.b, (long)(body + 20), ISO_EPARSE, want,
                      "announces 5 vertex entries");
    /* trailing junk */
    o.b[o.n++] = 0;
    expect_fail_bytes("tail.ply", (const char *)o.b, (long)o.n, ISO_EPARSE,
                      "1 unexpected bytes after the last element", NULL);
    /* a face index out of range names the face's byte offset */
    build_binary(&o, 0);
    o.b[body + 5 * 14 + 2] = 7;
    snprintf(want, sizeof want, "byte offset %zu: face 0 has vertex index 7", body + 5 * 14);
    expect_fail_bytes("idx.ply", (const char *)o.b, (long)o.n, ISO_EPARSE, want, "nv = 5");
    /* a NaN coordinate names the vertex's byte offset */
    build_binary(&o, 0);
    float nan = NAN;
    memcpy(o.b + body + 14 + 4, &nan, 4);
    snprintf(want, sizeof want, "byte offset %zu: vertex 1", body + 14);
    expect_fail_bytes("nanb.ply", (const char *)o.b, (long)o.n, ISO_EPARSE, want, "non-finite");
    /* a huge count in the header */
    expect_fail("huge.ply",
                "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\n"
                "property double x\nproperty double y\nproperty double z\nend_header\n\1\2\3",
                ISO_EPARSE, "announces 2000000000 vertex entries", "only 3 bytes are left");
}

static void ply_header_errors(void **state)
{
    (void)state;
    expect_fail("magic.ply", "plx\n", ISO_EPARSE, "line 1", "does not start with the line 'ply'");
    expect_fail("fmt.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", ISO_EPARSE,
                "line 2", "unknown format 'binary_middle_endian'");
    expect_fail("noend.ply", "ply\nformat ascii 1.0\nelement vertex 3\n", ISO_EPARSE,
                "no end_header", NULL);
    expect_fail("nofmt.ply", "ply\nend_header\n", ISO_EPARSE, "no format line", NULL);
    expect_fail("type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\n",
                ISO_EPARSE, "line 4", "unknown property type 'quad'");
    expect_fail("noxyz.ply",
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nend_header\n0 0\n",
                ISO_EPARSE, "line 3", "lacks a scalar x, y or z");
    expect_fail("nolist.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty int a\nend_header\n",
                ISO_EPARSE, "line 7", "no list property vertex_indices");
    expect_fail("kw.ply", "ply\nformat ascii 1.0\nbanana\n", ISO_EPARSE, "line 3",
                "unknown keyword 'banana'");
    expect_fail("cnt.ply", "ply\nformat ascii 1.0\nelement vertex -3\n", ISO_EPARSE, "line 3",
                "bad element count '-3'");
}

static void ply_ascii_errors(void **state)
{
    (void)state;
    static const char hdr[] = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                              "property float y\nproperty float z\nelement face 1\n"
                              "property list uchar int vertex_indices\nend_header\n";
    char text[1024];
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1\n3 0 1 2\n", hdr);
    expect_fail("few.ply", text, ISO_EPARSE, "line 12", "vertex 2 has too few values");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0 4\n3 0 1 2\n", hdr);
    expect_fail("many.ply", text, ISO_EPARSE, "line 12", "more values than the header");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n", hdr);
    expect_fail("trunc.ply", text, ISO_EPARSE, "file ends before face 0 of 1", NULL);
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n3 0 1 x\n", hdr);
    expect_fail("garb.ply", text, ISO_EPARSE, "line 13", "'x' is not a number");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n3 0 1 1.5\n", hdr);
    expect_fail("frac.ply", text, ISO_EPARSE, "line 13", "not an integer");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n2 0 1\n", hdr);
    expect_fail("two.ply", text, ISO_EPARSE, "line 13", "face 0 has 2 vertices");
    snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", hdr);
    expect_fail("tail.ply", text, ISO_EPARSE, "line 14", "after the last element");
    expect_fail("hugea.ply",
                "ply\nformat ascii 1.0\nelement vertex 1000000\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n0 0 0\n",
                ISO_EPARSE, "announces 1000000 vertex entries", NULL);
}

/* ==== benchmark ========================================================== */

static void benchmark_meshes_load(void **state)
{
    (void)state;
    static const struct {
        const char *rel;
        int nv, nt;
    } b[] = {{"00-plane-lift/knubbel.off", 40401, 80000},
             {"01-cylinder-bend/cylinder.off", 4802, 9600},
             {"02-bar-twist/bar.off", 6084, 12106},
             {"03-cactus-bend/cactus.off", 5261, 10518}};
    char path[1024];
    if (!iso_test_benchmark(path, sizeof path, b[0].rel)) {
        print_message("benchmark not found at %s: skipping\n", path);
        skip();
    }
    for (size_t i = 0; i < sizeof b / sizeof b[0]; i++) {
        iso_mesh *m = NULL;
        iso_err err;
        iso_err_clear(&err);
        iso_test_benchmark(path, sizeof path, b[i].rel);
        int rc = iso_mesh_load(path, &m, &err);
        if (rc != ISO_OK)
            fail_msg("%s: %s", path, err.msg);
        assert_int_equal(iso_mesh_vertex_count(m), b[i].nv);
        assert_int_equal(iso_mesh_triangle_count(m), b[i].nt);
        assert_int_equal(iso_mesh_unreferenced_count(m), 0);
        assert_true(iso_mesh_bbox_diagonal(m) > 0);
        /* and it survives a binary round trip bit-exactly */
        char out[512];
        iso_test_tmp(out, sizeof out, "bench.ply");
        assert_int_equal(iso_mesh_save(m, NULL, out, ISO_MESH_FMT_PLY_BINARY, &err), ISO_OK);
        iso_mesh *r = NULL;
        assert_int_equal(iso_mesh_load(out, &r, &err), ISO_OK);
        assert_memory_equal(iso_mesh_positions(r), iso_mesh_positions(m),
                            3 * (size_t)b[i].nv * sizeof(double));
        iso_mesh_destroy(r);
        iso_mesh_destroy(m);
    }
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(round_trip_every_format),
        cmocka_unit_test(save_errors),
        cmocka_unit_test(off_features),
        cmocka_unit_test(off_quad_note),
        cmocka_unit_test(off_errors),
        cmocka_unit_test(off_mesh_errors_name_lines),
        cmocka_unit_test(other_load_errors),
        cmocka_unit_test(obj_features),
        cmocka_unit_test(obj_polygons),
        cmocka_unit_test(obj_non_convex_refused),
        cmocka_unit_test(obj_errors),
        cmocka_unit_test(ply_ascii_features),
        cmocka_unit_test(ply_binary_both_endians),
        cmocka_unit_test(ply_binary_errors),
        cmocka_unit_test(ply_header_errors),
        cmocka_unit_test(ply_ascii_errors),
        cmocka_unit_test(benchmark_meshes_load),
    };
    return cmocka_run_group_tests_name("mesh_io", t, NULL, NULL);
}
