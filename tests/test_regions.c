/* tests/test_regions.c -- iso_regions and the .sel/.def readers. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "iso_regions.h"

static const char *tmp_file(char *path, size_t cap, const char *name, const char *text)
{
    iso_test_tmp(path, cap, name);
    iso_test_write(path, text, -1);
    return path;
}

static void init_deinit(void **state)
{
    (void)state;
    iso_regions r;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_regions_init(&r, 4, &err), ISO_OK);
    assert_int_equal(r.nv, 4);
    assert_int_equal(r.n_handles, 0);
    for (int i = 0; i < 4; i++) {
        assert_int_equal(r.kind[i], ISO_FREE);
        assert_int_equal(r.handle[i], -1);
    }
    iso_regions_deinit(&r);
    assert_null(r.kind);
    iso_regions_deinit(&r); /* twice is fine */
    assert_int_equal(iso_regions_init(&r, -1, &err), ISO_EINVAL);
    iso_regions_deinit(&r);
}

static void sel_reads_kinds(void **state)
{
    (void)state;
    char path[512];
    iso_regions r;
    iso_err err;
    iso_err_clear(&err);
    tmp_file(path, sizeof path, "a.sel",
             "# per vertex status: 0=fixed, 1=deformable-region, 2=handle\n# 5 vertices\n"
             "0\n1\n2\r\n\n2 1 # two on a line\n");
    assert_int_equal(iso_sel_load(path, 5, &r, &err), ISO_OK);
    static const unsigned char kind[] = {ISO_FIXED, ISO_FREE, ISO_HANDLE, ISO_HANDLE, ISO_FREE};
    static const int handle[] = {-1, -1, 0, 0, -1};
    assert_memory_equal(r.kind, kind, sizeof kind);
    assert_memory_equal(r.handle, handle, sizeof handle);
    assert_int_equal(r.n_handles, 1);
    iso_regions_deinit(&r);
}

static void sel_fail(const char *name, const char *text, int nv, const char *s1, const char *s2)
{
    char path[512];
    iso_regions r;
    iso_err err;
    iso_err_clear(&err);
    tmp_file(path, sizeof path, name, text);
    int rc = iso_sel_load(path, nv, &r, &err);
    print_message("%-10s -> %s\n", name, err.msg);
    assert_int_equal(rc, ISO_EPARSE);
    assert_int_equal(err.code, ISO_EPARSE);
    assert_null(r.kind); /* left zeroed */
    assert_non_null(strstr(err.msg, name));
    if (s1 && !strstr(err.msg, s1))
        fail_msg("'%s' not in '%s'", s1, err.msg);
    if (s2 && !strstr(err.msg, s2))
        fail_msg("'%s' not in '%s'", s2, err.msg);
}

static void sel_errors(void **state)
{
    (void)state;
    sel_fail("few.sel", "# c\n0\n1\n", 3, "line 3", "after 2 values, but the mesh has 3");
    sel_fail("many.sel", "# c\n0\n1\n2\n0\n", 3, "line 5", "more values than the mesh's 3");
    sel_fail("val.sel", "# c\n0\n3\n2\n", 3, "line 3", "vertex 1 has status 3");
    sel_fail("neg.sel", "0\n-1\n2\n", 3, "line 2", "status -1");
    sel_fail("tok.sel", "0\n1.0\n2\n", 3, "line 2", "'1.0' is not an integer");
    sel_fail("empty.sel", "", 3, "after 0 values", NULL);
    iso_regions r;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_sel_load("/nonexistent-dir/x.sel", 3, &r, &err), ISO_EIO);
    assert_non_null(strstr(err.msg, "/nonexistent-dir/x.sel"));
}

static int def_load_text(const char *name, const char *text, double M[16], iso_err *err)
{
    char path[512];
    iso_err_clear(err);
    return iso_def_load(tmp_file(path, sizeof path, name, text), M, err);
}

static void def_reads_rigid(void **state)
{
    (void)state;
    double M[16];
    iso_err err;
    assert_int_equal(def_load_text("ok.def",
                                   "# 4x4 handle transformation matrix\n"
                                   "-0.500000 0.000000 -0.866025 5.196152\n"
                                   "0.000000 1.000000 0.000000 0.000000\n"
                                   "0.866025 0.000000 -0.500000 9.000000\n"
                                   "0.000000 0.000000 0.000000 1.000000\n",
                                   M, &err),
                     ISO_OK);
    assert_true(M[0] == -0.5 && M[3] == 5.196152 && M[11] == 9.0 && M[15] == 1.0);
}

static void def_fail(const char *name, const char *text, const char *s1, const char *s2)
{
    double M[16] = {0};
    iso_err err;
    int rc = def_load_text(name, text, M, &err);
    print_message("%-10s -> %s\n", name, err.msg);
    assert_int_equal(rc, ISO_EPARSE);
    assert_int_equal(err.code, ISO_EPARSE);
    assert_true(M[0] == 0); /* untouched */
    assert_non_null(strstr(err.msg, name));
    if (s1 && !strstr(err.msg, s1))
        fail_msg("'%s' not in '%s'", s1, err.msg);
    if (s2 && !strstr(err.msg, s2))
        fail_msg("'%s' not in '%s'", s2, err.msg);
}

static void def_errors(void **state)
{
    (void)state;
    def_fail("scale.def", "# m\n1.01 0 0 0\n0 1.01 0 0\n0 0 1.01 0\n0 0 0 1\n", "lines 2-4",
             "not a rotation");
    def_fail("shear.def", "# m\n1 0.01 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", "not a rotation", NULL);
    def_fail("mirror.def", "# m\n-1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", "|det R - 1| = 2", NULL);
    def_fail("last.def", "# m\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n", "line 5",
             "last row must be 0 0 0 1");
    def_fail("few.def", "# m\n1 0 0 0\n0 1 0 0\n0 0 1 0\n", "after 12 of 16", NULL);
    def_fail("many.def", "# m\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n7\n", "line 6", "more than 16");
    def_fail("tok.def", "# m\n1 0 0 0\n0 1 zero 0\n", "line 3", "'zero' is not a number");
    def_fail("nan.def", "# m\n1 0 0 nan\n", "line 2", "entry 4 is not finite");
}

/* The benchmark's four .def files are rigid; a 1% scale of one is not. */
static void benchmark_defs_and_sels(void **state)
{
    (void)state;
    static const struct {
        const char *def, *sel;
        int nv;
    } b[] = {{"00-plane-lift/knubbel.def", "00-plane-lift/knubbel.sel", 40401},
             {"01-cylinder-bend/cylinder.def", "01-cylinder-bend/cylinder.sel", 4802},
             {"02-bar-twist/bar.def", "02-bar-twist/bar.sel", 6084},
             {"03-cactus-bend/cactus.def", "03-cactus-bend/cactus.sel", 5261}};
    char path[1024];
    if (!iso_test_benchmark(path, sizeof path, b[0].def)) {
        print_message("benchmark not found at %s: skipping\n", path);
        skip();
    }
    for (size_t i = 0; i < sizeof b / sizeof b[0]; i++) {
        double M[16];
        iso_err err;
        iso_err_clear(&err);
        iso_test_benchmark(path, sizeof path, b[i].def);
        if (iso_def_load(path, M, &err) != ISO_OK)
            fail_msg("%s", err.msg);
        /* scaled by 1%, written back and reloaded: refused */
        char text[512];
        size_t o = snprintf(text, sizeof text, "# scaled\n");
        for (int r = 0; r < 4; r++)
            o += (size_t)snprintf(text + o, sizeof text - o, "%.17g %.17g %.17g %.17g\n",
                                  M[4 * r] * (r < 3 ? 1.01 : 1), M[4 * r + 1] * (r < 3 ? 1.01 : 1),
                                  M[4 * r + 2] * (r < 3 ? 1.01 : 1), M[4 * r + 3]);
        double S[16];
        assert_int_equal(def_load_text("scaled.def", text, S, &err), ISO_EPARSE);
        assert_non_null(strstr(err.msg, "not a rotation"));

        iso_regions r;
        iso_err_clear(&err);
        iso_test_benchmark(path, sizeof path, b[i].sel);
        if (iso_sel_load(path, b[i].nv, &r, &err) != ISO_OK)
            fail_msg("%s", err.msg);
        assert_int_equal(r.n_handles, 1);
        iso_regions_deinit(&r);
        /* one vertex fewer than the file holds */
        iso_err_clear(&err);
        assert_int_equal(iso_sel_load(path, b[i].nv - 1, &r, &err), ISO_EPARSE);
    }
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(init_deinit), cmocka_unit_test(sel_reads_kinds),
        cmocka_unit_test(sel_errors),  cmocka_unit_test(def_reads_rigid),
        cmocka_unit_test(def_errors),  cmocka_unit_test(benchmark_defs_and_sels),
    };
    return cmocka_run_group_tests_name("regions", t, NULL, NULL);
}
