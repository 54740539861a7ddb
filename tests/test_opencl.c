/* tests/test_opencl.c -- the OpenCL assembly against the C path.
 *
 * White-box: both paths fill the same cached CHOLMOD matrix (upper
 * triangle of A_ff) and right-hand side, so this compares s->A->x and
 * s->B->x directly:
 *   (a) the paths agree to 1e-12 relative (max |A_cl − A_c| / max |A_c|, and
 *       the same for the right-hand side) on the built-in shapes and on the
 *       benchmark meshes when ../shared/data/benchmark is there, with
 *       restoration on and off and under both weightings;
 *   (b) each path is bit-identical from run to run;
 *   (c) a triangle that degenerates is reported by both paths alike;
 *   (d) a device that does not exist gives the C path and a notice;
 *   (e) whole field evaluations agree;
 *   (f) the auto assembly takes OpenCL on a GPU or accelerator with double
 *       precision where this machine has one (listed here through the
 *       OpenCL API itself), else the C path with a notice, never a CPU
 *       device unless it is named.
 * Speed is not a test's business: tests/tools/assembly_bench prints the
 * median assembly time of each path, measured in the same run.
 *
 * When no OpenCL platform or device is usable, or the build has no OpenCL,
 * it prints why and exits 77 (CTest: skipped). ISO_TEST_CL_DEVICE picks the
 * device (opts.cl_device); unset = the first CPU device. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef ISO_TEST_HAVE_CL /* the OpenCL API, to list the devices (f) */
#include <CL/cl.h>
#endif

#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"
#include "testutil.h"

/* The solver's internals need cholmod.h on the include path. */
#if defined(__has_include)
#if __has_include(<cholmod.h>)
#include "../solver/solver_internal.h"
#define HAVE_INTERNALS 1
#endif
#endif

#ifdef HAVE_INTERNALS

static const iso_weighting WEIGHTINGS[2] = {ISO_WEIGHT_PARAM, ISO_WEIGHT_AREA};

static struct {
    const char *device; /* ISO_TEST_CL_DEVICE or NULL */
} g;

typedef struct problem {
    char name[64];
    iso_mesh *m;
    iso_regions r;
    double *x;  /* positions: rest pose, perturbed */
    double *vc; /* handle velocities (garbage elsewhere: must be ignored) */
} problem;

/* Positions: the rest pose perturbed by 0.1% of the bounding box, so that
 * restoration has lengths to restore. Returns the centroid of the rest pose. */
static void set_positions(problem *p, double c[3])
{
    int nv = iso_mesh_vertex_count(p->m);
    const double *x0 = iso_mesh_positions(p->m);
    double h = 1e-3 * iso_mesh_bbox_diagonal(p->m);
    c[0] = c[1] = c[2] = 0;
    for (int i = 0; i < nv; i++) {
        p->x[3 * i] = x0[3 * i] + h * sin(1.3 * i);
        p->x[3 * i + 1] = x0[3 * i + 1] + h * cos(2.1 * i);
        p->x[3 * i + 2] = x0[3 * i + 2] + h * sin(0.7 * i + 1.0);
        for (int a = 0; a < 3; a++)
            c[a] += x0[3 * i + a] / nv;
    }
}

/* Positions, and a twist for the handle. */
static void problem_fill(problem *p)
{
    int nv = iso_mesh_vertex_count(p->m);
    double c[3];
    p->x = malloc(sizeof(double) * 3 * (size_t)nv);
    p->vc = malloc(sizeof(double) * 3 * (size_t)nv);
    assert_non_null(p->x);
    assert_non_null(p->vc);
    set_positions(p, c);
    const double u[3] = {0.1, 0.2, -0.3}, w[3] = {0.5, -0.2, 0.1};
    for (int i = 0; i < nv; i++) {
        double *v = p->vc + 3 * i;
        if (p->r.kind[i] != ISO_HANDLE) {
            v[0] = v[1] = v[2] = 1e3 * (i % 7 + 1);
            continue;
        }
        double d[3] = {p->x[3 * i] - c[0], p->x[3 * i + 1] - c[1], p->x[3 * i + 2] - c[2]};
        v[0] = u[0] + w[1] * d[2] - w[2] * d[1];
        v[1] = u[1] + w[2] * d[0] - w[0] * d[2];
        v[2] = u[2] + w[0] * d[1] - w[1] * d[0];
    }
}

static void problem_shape(problem *p, const char *name)
{
    iso_shape sh;
    iso_err err;
    iso_err_clear(&err);
    memset(p, 0, sizeof *p);
    snprintf(p->name, sizeof p->name, "%s", name);
    if (iso_shape_init(&sh, name, 0, &err) != ISO_OK ||
        iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, sh.name, &p->m, &err) != ISO_OK ||
        iso_shape_regions(&sh, &p->r, &err) != ISO_OK)
        fail_msg("shape %s: %s", name, err.msg);
    iso_shape_deinit(&sh);
    problem_fill(p);
}

/* Returns 0 when the benchmark is not there. */
static int problem_benchmark(problem *p, const char *dir, const char *stem)
{
    char path[512], rel[128];
    iso_err err;
    iso_err_clear(&err);
    memset(p, 0, sizeof *p);
    snprintf(p->name, sizeof p->name, "benchmark %s", stem);
    snprintf(rel, sizeof rel, "%s/%s.off", dir, stem);
    if (!iso_test_benchmark(path, sizeof path, rel))
        return 0;
    if (iso_mesh_load(path, &p->m, &err) != ISO_OK)
        fail_msg("%s: %s", path, err.msg);
    snprintf(rel, sizeof rel, "%s/%s.sel", dir, stem);
    iso_test_benchmark(path, sizeof path, rel);
    if (iso_sel_load(path, iso_mesh_vertex_count(p->m), &p->r, &err) != ISO_OK)
        fail_msg("%s: %s", path, err.msg);
    problem_fill(p);
    return 1;
}

static void problem_free(problem *p)
{
    iso_mesh_destroy(p->m);
    iso_regions_deinit(&p->r);
    free(p->x);
    free(p->vc);
}

static iso_solver *make_solver(const problem *p, iso_assembly path, iso_weighting w, int restore)
{
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    o.omega = 0.37;
    o.weighting = w;
    o.assembly = path;
    o.cl_device = g.device;
    if (restore) {
        o.restore_mu = 0.5;
        o.restore_tau = 0.1;
    }
    iso_solver *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    if (iso_solver_create(p->m, &p->r, &o, &s, &err) != ISO_OK)
        fail_msg("%s: iso_solver_create: %s", p->name, err.msg);
    if (path == ISO_ASSEMBLY_OPENCL && !s->cl)
        fail_msg("%s: the OpenCL path did not start: %s", p->name, iso_solver_notice(s));
    return s;
}

static int assemble(iso_solver *s, const problem *p, iso_err *err)
{
    iso_err_clear(err);
    if (s->cl)
        return iso_solver__cl_assemble(s->cl, s, p->x, p->vc, err);
    return iso_solver__assemble_cpu(s, p->x, p->vc, err);
}

static size_t nnz_of(const iso_solver *s)
{
    return (size_t)((const int *)s->A->p)[3 * s->nf];
}

/* Assembles twice; asserts both runs are bit-identical; returns copies. */
static void assemble_twice(iso_solver *s, const problem *p, double **A, double **B)
{
    size_t nnz = nnz_of(s), nb = 3 * (size_t)s->nf;
    iso_err err;
    *A = malloc(sizeof(double) * (nnz + 1));
    *B = malloc(sizeof(double) * (nb + 1));
    assert_non_null(*A);
    assert_non_null(*B);
    for (int run = 0; run < 2; run++) {
        memset(s->A->x, run ? 0x5a : 0xa5, nnz * sizeof(double)); /* every entry is written */
        memset(s->B->x, run ? 0x5a : 0xa5, nb * sizeof(double));
        if (assemble(s, p, &err) != ISO_OK)
            fail_msg("%s (%s path): %s", p->name, s->cl ? "OpenCL" : "C", err.msg);
        if (run == 0) {
            memcpy(*A, s->A->x, nnz * sizeof(double));
            memcpy(*B, s->B->x, nb * sizeof(double));
        } else if (memcmp(*A, s->A->x, nnz * sizeof(double)) ||
                   memcmp(*B, s->B->x, nb * sizeof(double))) {
            fail_msg("%s (%s path): two assemblies differ", p->name, s->cl ? "OpenCL" : "C");
        }
    }
}

/* (a) and (b) for one problem, all four option sets. */
static void check_agreement(const problem *p)
{
    for (int restore = 0; restore < 2; restore++)
        for (int wi = 0; wi < 2; wi++) {
            iso_solver *sc = make_solver(p, ISO_ASSEMBLY_CPU, WEIGHTINGS[wi], restore);
            iso_solver *sl = make_solver(p, ISO_ASSEMBLY_OPENCL, WEIGHTINGS[wi], restore);
            if (restore) { /* the integrators change τ per step: both paths must follow */
                iso_err e;
                assert_int_equal(iso_solver_set_restore_tau(sc, 0.037, &e), ISO_OK);
                assert_int_equal(iso_solver_set_restore_tau(sl, 0.037, &e), ISO_OK);
            }
            size_t nnz = nnz_of(sc), nb = 3 * (size_t)sc->nf;
            assert_int_equal(nnz, nnz_of(sl));
            assert_int_equal(sc->nf, sl->nf);
            double *Ac, *Bc, *Al, *Bl;
            assemble_twice(sc, p, &Ac, &Bc);
            assemble_twice(sl, p, &Al, &Bl);
            double ea = iso_test_max_abs_diff(Ac, Al, nnz) / iso_test_max_abs(Ac, nnz);
            double eb = iso_test_max_abs_diff(Bc, Bl, nb) / iso_test_max_abs(Bc, nb);
            print_message("%-22s %-5s restore %-3s: A %.2e  rhs %.2e  (nnz %zu, %d free)\n",
                          p->name, wi ? "area" : "param", restore ? "on" : "off", ea, eb, nnz,
                          sc->nf);
            if (!(ea <= 1e-12 && eb <= 1e-12))
                fail_msg("%s: the paths disagree: A %.3e, rhs %.3e relative", p->name, ea, eb);
            free(Ac);
            free(Bc);
            free(Al);
            free(Bl);
            iso_solver_destroy(sc);
            iso_solver_destroy(sl);
        }
}

static void shapes_agree(void **state)
{
    (void)state;
    const char *const *names = iso_shape_names();
    for (int i = 0; names[i]; i++) {
        problem p;
        problem_shape(&p, names[i]);
        check_agreement(&p);
        problem_free(&p);
    }
}

/* The cactus shape shrunk to 1e-2 and moved 1e4 from the origin: the
 * rounded centroid of each triangle is then off by ~1e-10 of its size,
 * which both paths must absorb alike (element.c's frame_points, the
 * kernels' FIT_D) rather than each in its own rounding. */
static void far_from_origin_agree(void **state)
{
    (void)state;
    problem p;
    problem_shape(&p, "cactus");
    snprintf(p.name, sizeof p.name, "cactus, 1e4 away");
    int nv = iso_mesh_vertex_count(p.m);
    const double off[3] = {1e4, -1e4, 1e4};
    for (int i = 0; i < 3 * nv; i++)
        p.x[i] = 1e-2 * p.x[i] + off[i % 3];
    check_agreement(&p);
    problem_free(&p);
}

static const char *const BENCH[4][2] = {{"00-plane-lift", "knubbel"},
                                        {"01-cylinder-bend", "cylinder"},
                                        {"02-bar-twist", "bar"},
                                        {"03-cactus-bend", "cactus"}};

static void benchmark_meshes_agree(void **state)
{
    (void)state;
    problem p;
    if (!problem_benchmark(&p, BENCH[0][0], BENCH[0][1])) {
        print_message("benchmark not found under %s: skipping\n", ISO_BENCHMARK_DIR);
        skip();
    }
    problem_free(&p);
    for (int i = 0; i < 4; i++) {
        if (!problem_benchmark(&p, BENCH[i][0], BENCH[i][1]))
            fail_msg("benchmark %s is incomplete", BENCH[i][0]);
        check_agreement(&p);
        problem_free(&p);
    }
}

/* (c): a triangle collapsed to a point. Its neighbours become collinear,
 * whose fits are singular only up to rounding, so the triangle named is
 * the C path's, whichever that is; a vertex at NaN makes the fits of its
 * triangles fail exactly, and the first of them (list order: triangles
 * by index) is the one named. */
static void degenerate_triangle_reported_alike(void **state)
{
    (void)state;
    problem p;
    problem_shape(&p, "cactus");
    const int *tri = iso_mesh_triangles(p.m);
    int t = 0;
    while (p.r.kind[tri[3 * t]] != ISO_FREE || p.r.kind[tri[3 * t + 1]] != ISO_FREE ||
           p.r.kind[tri[3 * t + 2]] != ISO_FREE)
        t++;
    for (int k = 1; k < 3; k++)
        memcpy(p.x + 3 * tri[3 * t + k], p.x + 3 * tri[3 * t], 3 * sizeof(double));
    iso_solver *sc = make_solver(&p, ISO_ASSEMBLY_CPU, ISO_WEIGHT_PARAM, 0);
    iso_solver *sl = make_solver(&p, ISO_ASSEMBLY_OPENCL, ISO_WEIGHT_PARAM, 0);
    iso_err ec, el;
    assert_int_equal(assemble(sc, &p, &ec), ISO_ENUMERIC);
    assert_int_equal(assemble(sl, &p, &el), ISO_ENUMERIC);
    assert_non_null(strstr(ec.msg, "has degenerated during the deformation"));
    assert_string_equal(el.msg, ec.msg);
    /* NaN at vertex v: the lowest-numbered triangle around v is named */
    double c[3];
    set_positions(&p, c);
    int v = tri[3 * t + 2], first = -1;
    for (int i = 0; first < 0; i++)
        if (tri[3 * i] == v || tri[3 * i + 1] == v || tri[3 * i + 2] == v)
            first = i;
    double keep = p.x[3 * v + 1];
    p.x[3 * v + 1] = NAN;
    char want[64];
    snprintf(want, sizeof want, "triangle %d has degenerated", first);
    assert_int_equal(assemble(sc, &p, &ec), ISO_ENUMERIC);
    assert_int_equal(assemble(sl, &p, &el), ISO_ENUMERIC);
    if (!strstr(ec.msg, want))
        fail_msg("C path: \"%s\", expected \"%s\"", ec.msg, want);
    assert_string_equal(el.msg, ec.msg);
    /* and the OpenCL path recovers once the mesh is whole again */
    p.x[3 * v + 1] = keep;
    assert_int_equal(assemble(sl, &p, &el), ISO_OK);
    iso_solver_destroy(sc);
    iso_solver_destroy(sl);
    problem_free(&p);
}

/* (d): a device that does not exist is a notice and the C path. */
static void missing_device_falls_back(void **state)
{
    (void)state;
    problem p;
    problem_shape(&p, "bar");
    static const struct {
        const char *device, *reason;
    } cases[] = {{"99:0", "does not exist"},
                 {"0:99", "does not exist"},
                 {"no-such-device-xyz", "no device or platform name contains"}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        iso_solver_opts o;
        iso_solver_opts_default(&o);
        o.assembly = ISO_ASSEMBLY_OPENCL;
        o.cl_device = cases[i].device;
        iso_solver *s = NULL;
        iso_err err;
        iso_err_clear(&err);
        assert_int_equal(iso_solver_create(p.m, &p.r, &o, &s, &err), ISO_OK);
        assert_null(s->cl);
        const char *n = iso_solver_notice(s);
        if (!strstr(n, cases[i].reason) || !strstr(n, "using the C assembly"))
            fail_msg("device %s: notice \"%s\"", cases[i].device, n);
        iso_solver_destroy(s);
    }
    problem_free(&p);
}

/* (e): whole evaluations (assemble, factor, solve) agree. */
static void fields_agree(void **state)
{
    (void)state;
    problem p;
    problem_shape(&p, "cylinder");
    int nv = iso_mesh_vertex_count(p.m);
    iso_solver *sc = make_solver(&p, ISO_ASSEMBLY_CPU, ISO_WEIGHT_AREA, 1);
    iso_solver *sl = make_solver(&p, ISO_ASSEMBLY_OPENCL, ISO_WEIGHT_AREA, 1);
    double *vcpu = malloc(sizeof(double) * 3 * (size_t)nv);
    double *vcl = malloc(sizeof(double) * 3 * (size_t)nv);
    assert_non_null(vcpu);
    assert_non_null(vcl);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_solver_field(sc, p.x, p.vc, vcpu, &err), ISO_OK);
    assert_int_equal(iso_solver_field(sl, p.x, p.vc, vcl, &err), ISO_OK);
    size_t n = 3 * (size_t)nv;
    double e = iso_test_max_abs_diff(vcpu, vcl, n) / iso_test_max_abs(vcpu, n);
    if (!(e <= 1e-9))
        fail_msg("fields differ by %.3e relative", e);
    free(vcpu);
    free(vcl);
    iso_solver_destroy(sc);
    iso_solver_destroy(sl);
    problem_free(&p);
}

#ifdef ISO_TEST_HAVE_CL
/* The GPU and accelerator devices with double precision, and the "P:D"
 * of the first CPU device ("" if none), as listed by OpenCL. */
static int list_devices(char *cpu, size_t cap)
{
    cl_platform_id plat[16];
    cl_uint np = 0;
    int gpus = 0;
    cpu[0] = '\0';
    if (clGetPlatformIDs(16, plat, &np) != CL_SUCCESS)
        return 0;
    for (cl_uint p = 0; p < np && p < 16; p++) {
        cl_device_id dev[16];
        cl_uint nd = 0;
        if (clGetDeviceIDs(plat[p], CL_DEVICE_TYPE_ALL, 16, dev, &nd) != CL_SUCCESS)
            continue;
        for (cl_uint d = 0; d < nd && d < 16; d++) {
            cl_device_type type = 0;
            cl_device_fp_config fp = 0;
            clGetDeviceInfo(dev[d], CL_DEVICE_TYPE, sizeof type, &type, NULL);
            clGetDeviceInfo(dev[d], CL_DEVICE_DOUBLE_FP_CONFIG, sizeof fp, &fp, NULL);
            if ((type & (CL_DEVICE_TYPE_GPU | CL_DEVICE_TYPE_ACCELERATOR)) && fp)
                gpus++;
            if ((type & CL_DEVICE_TYPE_CPU) && !cpu[0])
                snprintf(cpu, cap, "%u:%u", p, d);
        }
    }
    return gpus;
}

static void auto_takes_a_gpu_or_the_c_path(void **state)
{
    (void)state;
    problem p;
    problem_shape(&p, "bar");
    char cpu[32];
    int gpus = list_devices(cpu, sizeof cpu);
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    o.assembly = ISO_ASSEMBLY_AUTO;
    iso_solver *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_solver_create(p.m, &p.r, &o, &s, &err), ISO_OK);
    const char *n = iso_solver_notice(s);
    printf("auto: %d GPU or accelerator device(s) with doubles listed; %s\n", gpus,
           s->cl ? "OpenCL runs" : n);
    if (gpus > 0) {
        assert_non_null(s->cl);
        assert_int_equal(s->o.assembly, ISO_ASSEMBLY_OPENCL);
        assert_string_equal(n, "");
    } else {
        assert_null(s->cl);
        assert_int_equal(s->o.assembly, ISO_ASSEMBLY_CPU);
        if (!strstr(n, "assembly auto: no GPU or accelerator") ||
            !strstr(n, "using the C assembly"))
            fail_msg("notice \"%s\"", n);
    }
    iso_solver_destroy(s);
    if (cpu[0]) { /* a named device wins, a CPU one included */
        o.cl_device = cpu;
        assert_int_equal(iso_solver_create(p.m, &p.r, &o, &s, &err), ISO_OK);
        assert_non_null(s->cl);
        assert_int_equal(s->o.assembly, ISO_ASSEMBLY_OPENCL);
        iso_solver_destroy(s);
    }
    problem_free(&p);
}
#endif

/* Exits 77 with the reason when the OpenCL path cannot start here. */
static void skip_without_opencl(void)
{
    problem p;
    problem_shape(&p, "bar");
    iso_solver_opts o;
    iso_solver_opts_default(&o);
    o.assembly = ISO_ASSEMBLY_OPENCL;
    o.cl_device = g.device;
    iso_solver *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    if (iso_solver_create(p.m, &p.r, &o, &s, &err) != ISO_OK) {
        fprintf(stderr, "test_opencl: creating an OpenCL solver failed: %s\n", err.msg);
        exit(1);
    }
    int have = s->cl != NULL;
    if (!have)
        printf("test_opencl: skipped: %s\n", iso_solver_notice(s));
    iso_solver_destroy(s);
    problem_free(&p);
    if (!have)
        exit(ISO_TEST_SKIP);
}

int main(void)
{
    g.device = getenv("ISO_TEST_CL_DEVICE");
    skip_without_opencl();
    const struct CMUnitTest t[] = {
        cmocka_unit_test(shapes_agree),
        cmocka_unit_test(far_from_origin_agree),
        cmocka_unit_test(benchmark_meshes_agree),
        cmocka_unit_test(degenerate_triangle_reported_alike),
        cmocka_unit_test(missing_device_falls_back),
        cmocka_unit_test(fields_agree),
#ifdef ISO_TEST_HAVE_CL
        cmocka_unit_test(auto_takes_a_gpu_or_the_c_path),
#endif
    };
    return cmocka_run_group_tests_name("opencl", t, NULL, NULL);
}

#else /* !HAVE_INTERNALS */

int main(void)
{
    printf("test_opencl: skipped: cholmod.h is not on this test's include path, so the "
           "solver's internals cannot be compared (tests/CMakeLists.txt: add "
           "CHOLMOD_INCLUDE_DIR)\n");
    return ISO_TEST_SKIP;
}

#endif
