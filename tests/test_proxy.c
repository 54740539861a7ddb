/* tests/test_proxy.c -- the reduced model (solver/iso_proxy.h):
 *   (a) the proxy of a closed shape and of a plate: at most the budget and
 *       near it, a valid mesh of the same topology (Euler characteristic,
 *       boundary kept), its vertices mesh vertices in the same regions,
 *       every region present, and a problem the solver accepts;
 *   (b) the prolongation reproduces the rest pose and any rigid motion of
 *       the proxy (to rounding), and places handle and fixed vertices of
 *       the full mesh exactly (the motion test makes the fixed region a
 *       handle, since a fixed vertex does not move);
 *   (c) it converges: under a smooth bend of the proxy the full mesh's
 *       distance from the same bend of itself shrinks as the budget grows,
 *       and the fit (proxy_fit.c) lands closer to it than the prolongation
 *       alone at every budget;
 *   (d) the fit lowers the full mesh's distortion under the method's own
 *       motion (the tentacle's bend and twist integrated on its proxy):
 *       metricErr, the largest and the rms edge strain all drop;
 *   (d') the proxy's smoothness weight (iso_proxy_omega) has its closed
 *       form, and on a bumpy plate the method on the proxy with it lands
 *       nearer the whole mesh's metricErr than with the mesh's own ω;
 *   (e) the same mesh and budget give the same proxy and the same positions,
 *       bit for bit, on two threads as on one;
 *   (f) bad budgets are refused with a reason. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../solver/proxy_internal.h"
#include "iso_geom.h"
#include "iso_integrate.h"
#include "iso_mesh.h"
#include "iso_metrics.h"
#include "iso_motion.h"
#include "iso_proxy.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"
#include "testutil.h"

typedef struct problem {
    iso_shape s;
    iso_mesh *m;
    iso_regions r;
} problem;

static void problem_init(problem *p, const char *name, int res)
{
    iso_err err;
    assert_int_equal(iso_shape_init(&p->s, name, res, &err), ISO_OK);
    assert_int_equal(iso_mesh_create(p->s.nv, p->s.x, p->s.nt, p->s.tri, name, &p->m, &err),
                     ISO_OK);
    assert_int_equal(iso_shape_regions(&p->s, &p->r, &err), ISO_OK);
}

static void problem_deinit(problem *p)
{
    iso_regions_deinit(&p->r);
    iso_mesh_destroy(p->m);
    iso_shape_deinit(&p->s);
}

static int boundary_edges(const iso_mesh *m)
{
    int n = 0, ne = iso_mesh_edge_count(m);
    const int *et = iso_mesh_edge_triangles(m);
    for (int e = 0; e < ne; e++)
        n += et[2 * e + 1] < 0;
    return n;
}

/* (a) for one problem and budget; returns the proxy. */
static iso_proxy *check_proxy(const problem *p, int budget)
{
    iso_proxy *px;
    iso_err err;
    if (iso_proxy_create(p->m, &p->r, budget, &px, &err) != ISO_OK)
        fail_msg("proxy of %s at %d: %s", p->s.name, budget, err.msg);
    const iso_mesh *pm = iso_proxy_mesh(px);
    const iso_regions *pr = iso_proxy_regions(px);
    int np = iso_mesh_vertex_count(pm), nt = iso_mesh_triangle_count(pm),
        ne = iso_mesh_edge_count(pm);
    printf("%s (%d vertices): proxy of %d vertices, %d triangles for a budget of %d\n", p->s.name,
           p->s.nv, np, nt, budget);
    assert_true(np <= budget && np >= budget * 9 / 10);
    int chi =
        iso_mesh_vertex_count(p->m) - iso_mesh_edge_count(p->m) + iso_mesh_triangle_count(p->m);
    assert_int_equal(np - ne + nt, chi);
    assert_int_equal(boundary_edges(pm) > 0, boundary_edges(p->m) > 0);
    const double *X = iso_mesh_positions(p->m), *Y = iso_mesh_positions(pm);
    int count[3] = {0, 0, 0};
    for (int k = 0; k < np; k++) {
        int i = iso_proxy_full_vertex(px, k);
        assert_true(i >= 0 && i < p->s.nv);
        assert_memory_equal(Y + 3 * k, X + 3 * i, 3 * sizeof *Y);
        assert_int_equal(pr->kind[k], p->r.kind[i]);
        assert_int_equal(pr->handle[k], p->r.handle[i]);
        count[pr->kind[k]]++;
    }
    assert_true(count[ISO_FIXED] > 0 && count[ISO_FREE] > 0 && count[ISO_HANDLE] > 0);
    iso_solver *s;
    if (iso_solver_create(pm, pr, NULL, &s, &err) != ISO_OK)
        fail_msg("the solver refused the proxy: %s", err.msg);
    iso_solver_destroy(s);
    return px;
}

static void proxies_are_valid_meshes_of_the_same_shape(void **state)
{
    (void)state;
    problem t, b;
    problem_init(&t, "tentacle", 32); /* 10,242 vertices */
    iso_proxy_destroy(check_proxy(&t, 1000));
    iso_proxy_destroy(check_proxy(&t, 3000));
    problem_deinit(&t);
    problem_init(&b, "bumpplane", 101); /* 10,201 vertices, a disk */
    iso_proxy_destroy(check_proxy(&b, 1500));
    problem_deinit(&b);
}

/* y: the proxy's rest positions under pose g (NULL: rest). */
static double *proxy_under(const iso_proxy *px, const iso_pose *g)
{
    const iso_mesh *pm = iso_proxy_mesh(px);
    int np = iso_mesh_vertex_count(pm);
    const double *Y = iso_mesh_positions(pm);
    double *y = malloc(3 * (size_t)np * sizeof *y);
    assert_non_null(y);
    for (int k = 0; k < np; k++)
        if (g)
            iso_pose_apply(g, Y + 3 * k, y + 3 * k);
        else
            memcpy(y + 3 * k, Y + 3 * k, 3 * sizeof *y);
    return y;
}

/* The regions with every vertex of kind `from` made `to` (handle 0). */
static void relabel(problem *p, int from, int to)
{
    for (int i = 0; i < p->r.nv; i++)
        if (p->r.kind[i] == from) {
            p->r.kind[i] = (unsigned char)to;
            p->r.handle[i] = to == ISO_HANDLE ? 0 : -1;
        }
}

static void rest_and_rigid_motions_are_exact(void **state)
{
    (void)state;
    problem t;
    problem_init(&t, "tentacle", 32);
    iso_proxy *px = check_proxy(&t, 2000);
    problem u; /* the same with the fixed cap a handle: all of it may move */
    problem_init(&u, "tentacle", 32);
    relabel(&u, ISO_FIXED, ISO_HANDLE);
    iso_proxy *pu;
    iso_err err;
    assert_int_equal(iso_proxy_create(u.m, &u.r, 2000, &pu, &err), ISO_OK);
    int nv = t.s.nv;
    const double *X = iso_mesh_positions(t.m);
    double diag = iso_mesh_bbox_diagonal(t.m), *x = malloc(3 * (size_t)nv * sizeof *x);
    assert_non_null(x);
    iso_pose id, g;
    iso_pose_identity(&id);
    double *y = proxy_under(px, NULL);
    iso_proxy_prolong(px, y, &id, x);
    double d = iso_test_vertex_max_diff(x, X, nv);
    printf("rest: %.3g of the diagonal\n", d / diag);
    assert_true(d <= 1e-14 * diag);
    free(y);
    /* a turn of 140° about a skew axis and a move: every vertex, the
     * handle's exactly as its pose puts it */
    iso_twist xi = {{0.6, -1.1, 1.9}, {0.3, 2.0, -0.7}};
    iso_twist_exp(&xi, 1.0, &g);
    y = proxy_under(px, &g); /* constrained vertices: exactly where they belong */
    iso_proxy_prolong(px, y, &g, x);
    for (int i = 0; i < nv; i++) {
        double want[3];
        iso_pose_apply(&g, X + 3 * i, want);
        if (t.r.kind[i] == ISO_HANDLE)
            assert_memory_equal(x + 3 * i, want, sizeof want);
        else if (t.r.kind[i] == ISO_FIXED)
            assert_memory_equal(x + 3 * i, X + 3 * i, 3 * sizeof *x);
    }
    free(y);
    y = proxy_under(pu, &g); /* everything follows the motion */
    iso_proxy_prolong(pu, y, &g, x);
    double worst = 0;
    for (int i = 0; i < nv; i++) {
        double want[3];
        iso_pose_apply(&g, X + 3 * i, want);
        for (int a = 0; a < 3; a++)
            worst = fmax(worst, fabs(x[3 * i + a] - want[a]));
    }
    printf("rigid motion: %.3g of the diagonal off\n", worst / diag);
    assert_true(worst <= 1e-12 * diag);
    free(y);
    free(x);
    iso_proxy_destroy(px);
    iso_proxy_destroy(pu);
    problem_deinit(&t);
    problem_deinit(&u);
}

/* A smooth bend: the plane z = 0 rolled about the line y = ρ, x free. */
static void bend(const double *p, double *q)
{
    const double rho = 80.0;
    double a = p[1] / rho;
    q[0] = p[0];
    q[1] = (rho - p[2]) * sin(a);
    q[2] = rho - (rho - p[2]) * cos(a);
}

/* The proxy of p for budget under the bend, prolonged with the fit on or
 * off: the full positions (3 nv, the caller frees). */
static double *bent_full(const problem *p, int budget, int fit)
{
    iso_proxy *px;
    iso_err err;
    assert_int_equal(iso_proxy_create(p->m, &p->r, budget, &px, &err), ISO_OK);
    iso_proxy__set_fit(px, fit);
    const iso_mesh *pm = iso_proxy_mesh(px);
    int np = iso_mesh_vertex_count(pm), nv = p->s.nv;
    const double *Y = iso_mesh_positions(pm);
    double *y = malloc(3 * (size_t)np * sizeof *y), *x = malloc(3 * (size_t)nv * sizeof *x);
    assert_true(y && x);
    for (int k = 0; k < np; k++)
        bend(Y + 3 * k, y + 3 * k);
    iso_pose id;
    iso_pose_identity(&id); /* only free vertices are compared */
    iso_proxy_prolong(px, y, &id, x);
    free(y);
    iso_proxy_destroy(px);
    return x;
}

/* The largest distance of the prolonged bend from the bend itself, on the
 * free vertices (over the diagonal). */
static double bend_error(const problem *p, int budget, int fit)
{
    double *x = bent_full(p, budget, fit), worst = 0;
    const double *X = iso_mesh_positions(p->m);
    for (int i = 0; i < p->s.nv; i++) {
        double want[3];
        bend(X + 3 * i, want);
        if (p->r.kind[i] == ISO_FREE)
            for (int a = 0; a < 3; a++)
                worst = fmax(worst, fabs(x[3 * i + a] - want[a]));
    }
    free(x);
    return worst / iso_mesh_bbox_diagonal(p->m);
}

static void the_prolongation_converges(void **state)
{
    (void)state;
    problem b; /* all free, so that the whole proxy may bend */
    problem_init(&b, "bumpplane", 101);
    relabel(&b, ISO_FIXED, ISO_FREE);
    relabel(&b, ISO_HANDLE, ISO_FREE);
    double e1 = bend_error(&b, 600, 1), e2 = bend_error(&b, 2400, 1);
    double d1 = bend_error(&b, 600, 0), d2 = bend_error(&b, 2400, 0);
    printf("bend: %.3g of the diagonal at 600 proxy vertices, %.3g at 2400 (ratio %.2f); "
           "without the fit %.3g and %.3g (ratio %.2f)\n",
           e1, e2, e1 / e2, d1, d2, d1 / d2);
    assert_true(e1 < 1e-2);
    assert_true(e2 < e1 / 2); /* edges half as long: second order would give 4 */
    assert_true(d2 < d1 / 2);
    assert_true(e1 < d1 && e2 < d2);
    problem_deinit(&b);
}

/* (d) the method's own motion: the tentacle's bend and twist integrated on
 * its proxy, the full mesh prolonged with the fit and without. */
/* The method on mesh/reg (p's own or a proxy's) along p's screw to t = 1,
 * from the rest positions into pos, with smoothness omega and step
 * tolerance tol (0: the default); the handle's final pose into g. */
static void integrate_screw(const problem *p, const iso_mesh *mesh, const iso_regions *reg,
                            double omega, double tol, double *pos, iso_pose *g)
{
    iso_err err;
    iso_twist xi, tw;
    assert_int_equal(iso_twist_from_matrix(p->s.M, &xi, &err), ISO_OK);
    iso_screw_path sp = {&xi, 1};
    iso_path path = iso_screw_path_make(&sp);
    iso_solver_opts so;
    iso_solver_opts_default(&so);
    so.omega = omega;
    iso_solver *s = NULL;
    assert_int_equal(iso_solver_create(mesh, reg, &so, &s, &err), ISO_OK);
    iso_integrate_opts io;
    iso_integrate_opts_default(&io);
    if (tol > 0)
        io.tol = tol;
    iso_integrate_stats st;
    memcpy(pos, iso_mesh_positions(mesh), 3 * (size_t)iso_mesh_vertex_count(mesh) * sizeof *pos);
    assert_int_equal(iso_integrate(s, mesh, reg, &path, &io, pos, &st, &err), ISO_OK);
    assert_int_equal(path.eval(path.ctx, 0, 1.0, g, &tw), ISO_OK);
    iso_solver_destroy(s);
}

static void the_fit_lowers_the_distortion(void **state)
{
    (void)state;
    problem t;
    problem_init(&t, "tentacle", 40); /* 16,002 vertices */
    iso_proxy *px = check_proxy(&t, 1500);
    const iso_mesh *pm = iso_proxy_mesh(px);
    int np = iso_mesh_vertex_count(pm), nv = t.s.nv;
    double *y = proxy_under(px, NULL), *x = malloc(3 * (size_t)nv * sizeof *x);
    assert_non_null(x);
    iso_pose g;
    integrate_screw(&t, pm, iso_proxy_regions(px), 1.0 / 3, 0, y, &g);
    const double *X = iso_mesh_positions(t.m);
    iso_metrics m[2], mp;
    iso_metrics_compute(pm, iso_mesh_positions(pm), y, &mp);
    for (int fit = 0; fit < 2; fit++) {
        iso_proxy__set_fit(px, fit);
        iso_proxy_prolong(px, y, &g, x);
        iso_metrics_compute(t.m, X, x, &m[fit]);
    }
    printf("tentacle through %d proxy vertices: metricErr %.4g with the fit, %.4g without (the "
           "proxy's own %.4g); largest edge strain %.3g%% and %.3g%%; rms %.3g%% and %.3g%%\n",
           np, m[1].metric_err, m[0].metric_err, mp.metric_err, 100 * m[1].max_edge_strain,
           100 * m[0].max_edge_strain, 100 * m[1].rms_edge_strain, 100 * m[0].rms_edge_strain);
    assert_true(m[1].metric_err < m[0].metric_err);
    assert_true(m[1].max_edge_strain < m[0].max_edge_strain);
    assert_true(m[1].rms_edge_strain < m[0].rms_edge_strain);
    free(x);
    free(y);
    iso_proxy_destroy(px);
    problem_deinit(&t);
}

/* The method on p's proxy px with smoothness omega, the full mesh
 * following; the full mesh's metricErr. */
static double proxy_metric_err(const problem *p, iso_proxy *px, double omega)
{
    const iso_mesh *pm = iso_proxy_mesh(px);
    double *y = proxy_under(px, NULL), *x = malloc(3 * (size_t)p->s.nv * sizeof *x);
    assert_non_null(x);
    iso_pose g;
    integrate_screw(p, pm, iso_proxy_regions(px), omega, 0, y, &g);
    iso_proxy_prolong(px, y, &g, x);
    iso_metrics m;
    iso_metrics_compute(p->m, iso_mesh_positions(p->m), x, &m);
    free(x);
    free(y);
    return m.metric_err;
}

static void the_proxy_bends_as_the_mesh_does(void **state)
{
    (void)state;
    problem b;
    problem_init(&b, "bumpplane", 61); /* 3,721 vertices */
    iso_proxy *px = check_proxy(&b, 800);
    int np = iso_mesh_vertex_count(iso_proxy_mesh(px)), nv = b.s.nv;
    double w = 1.0 / 3, wp = iso_proxy_omega(px, w);
    /* ω'/(1 − ω') = ω/(1 − ω) · np/nv; no d1 stays no d1 */
    assert_true(fabs(wp / (1 - wp) - 0.5 * np / nv) <= 1e-14);
    assert_true(iso_proxy_omega(px, 1.0) == 1.0);
    /* the whole mesh's integral, at a fine step (tol 1e-6) */
    double *x = malloc(3 * (size_t)nv * sizeof *x);
    assert_non_null(x);
    iso_pose g;
    integrate_screw(&b, b.m, &b.r, w, 1e-6, x, &g);
    iso_metrics whole;
    iso_metrics_compute(b.m, iso_mesh_positions(b.m), x, &whole);
    double same = proxy_metric_err(&b, px, w), matched = proxy_metric_err(&b, px, wp);
    printf("bumpplane 61 through %d proxy vertices: metricErr %.4g with the proxy's omega %.4g, "
           "%.4g with the mesh's %.4g; the whole mesh's %.4g\n",
           np, matched, wp, same, w, whole.metric_err);
    assert_true(fabs(matched - whole.metric_err) < fabs(same - whole.metric_err));
    free(x);
    iso_proxy_destroy(px);
    problem_deinit(&b);
}

static void the_same_input_gives_the_same_bits(void **state)
{
    (void)state;
    problem t;
    problem_init(&t, "tentacle", 60); /* 36,002 vertices: the prolongation runs in halves */
    iso_proxy *a = check_proxy(&t, 3000), *b = check_proxy(&t, 3000);
    const iso_mesh *ma = iso_proxy_mesh(a), *mb = iso_proxy_mesh(b);
    int np = iso_mesh_vertex_count(ma), nt = iso_mesh_triangle_count(ma), nv = t.s.nv;
    assert_int_equal(np, iso_mesh_vertex_count(mb));
    assert_int_equal(nt, iso_mesh_triangle_count(mb));
    assert_memory_equal(iso_mesh_triangles(ma), iso_mesh_triangles(mb),
                        3 * (size_t)nt * sizeof(int));
    iso_twist xi = {{0.2, 0.1, 0.4}, {0.0, 0.3, 0.0}};
    iso_pose g;
    iso_twist_exp(&xi, 1.0, &g);
    double *y = proxy_under(a, NULL);
    const double *Y = iso_mesh_positions(ma);
    for (int k = 0; k < np; k++) /* a non-rigid change: a twist growing with height */
        bend(Y + 3 * k, y + 3 * k);
    double *xa = malloc(3 * (size_t)nv * sizeof *xa), *xb = malloc(3 * (size_t)nv * sizeof *xb);
    assert_true(xa && xb);
    iso_proxy_prolong(a, y, &g, xa);
    iso_proxy_prolong(b, y, &g, xb);
    assert_memory_equal(xa, xb, 3 * (size_t)nv * sizeof *xa);
    iso_proxy_prolong(a, y, &g, xb); /* again */
    assert_memory_equal(xa, xb, 3 * (size_t)nv * sizeof *xa);
    iso_proxy__one_thread(b); /* the same on the calling thread alone */
    memset(xb, 0, 3 * (size_t)nv * sizeof *xb);
    iso_proxy_prolong(b, y, &g, xb);
    assert_memory_equal(xa, xb, 3 * (size_t)nv * sizeof *xa);
    free(xa);
    free(xb);
    free(y);
    iso_proxy_destroy(a);
    iso_proxy_destroy(b);
    problem_deinit(&t);
}

static void bad_budgets_are_refused(void **state)
{
    (void)state;
    problem t;
    problem_init(&t, "tentacle", 10); /* 1,002 vertices */
    iso_proxy *px = NULL;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_proxy_create(t.m, &t.r, 50, &px, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "50"));
    assert_null(px);
    iso_err_clear(&err);
    assert_int_equal(iso_proxy_create(t.m, &t.r, 1002, &px, &err), ISO_EINVAL);
    assert_non_null(strstr(err.msg, "in full"));
    assert_null(px);
    iso_proxy_destroy(NULL);
    assert_int_equal(iso_proxy_auto_budget(5261, 60), 0); /* the shipped 5k scenes: in full */
    assert_true(iso_proxy_auto_budget(160801, 60) >= ISO_PROXY_MIN_BUDGET);
    problem_deinit(&t);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(proxies_are_valid_meshes_of_the_same_shape),
        cmocka_unit_test(rest_and_rigid_motions_are_exact),
        cmocka_unit_test(the_prolongation_converges),
        cmocka_unit_test(the_fit_lowers_the_distortion),
        cmocka_unit_test(the_proxy_bends_as_the_mesh_does),
        cmocka_unit_test(the_same_input_gives_the_same_bits),
        cmocka_unit_test(bad_budgets_are_refused),
    };
    return cmocka_run_group_tests_name("proxy", t, NULL, NULL);
}
