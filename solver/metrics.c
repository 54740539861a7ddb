/* solver/metrics.c -- the paper's Table 1 distortion measures (iso_metrics.h).
 *
 * Plain sums over the mesh's edges and triangles. Corner angles use
 * atan2(|a × b|, a · b) rather than acos of a normalised dot product: acos
 * loses half the digits near 0 and π (its derivative is infinite there),
 * which would put rounding noise of 1e-8 rad into angleErr for thin or
 * nearly flat corners where atan2 stays at 1e-16. */
#include "iso_metrics.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

static double edge_length(const double *x, int i, int j)
{
    double d0 = x[3 * j] - x[3 * i];
    double d1 = x[3 * j + 1] - x[3 * i + 1];
    double d2 = x[3 * j + 2] - x[3 * i + 2];
    return sqrt(d0 * d0 + d1 * d1 + d2 * d2);
}

/* Area and the three corner angles of triangle (a, b, c) at positions x. */
static void triangle_shape(const double *x, const int *t, double *area, double angle[3])
{
    double cr_norm = 0;
    for (int k = 0; k < 3; k++) {
        const double *p = x + 3 * t[k];
        const double *q = x + 3 * t[(k + 1) % 3];
        const double *r = x + 3 * t[(k + 2) % 3];
        double a[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
        double b[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
        double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                       a[0] * b[1] - a[1] * b[0]};
        double cn = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        angle[k] = atan2(cn, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
        if (k == 0)
            cr_norm = cn;
    }
    *area = 0.5 * cr_norm;
}

void iso_metrics_compute(const iso_mesh *m, const double *x0, const double *x1, iso_metrics *out)
{
    memset(out, 0, sizeof *out);
    int ne = iso_mesh_edge_count(m);
    const int *e = iso_mesh_edges(m);
    double strain_sq = 0;
    for (int k = 0; k < ne; k++) {
        double l0 = edge_length(x0, e[2 * k], e[2 * k + 1]);
        double l1 = edge_length(x1, e[2 * k], e[2 * k + 1]);
        double d = l1 - l0;
        out->metric_err += d * d;
        /* A mesh that exists has no zero-length edge (degenerate triangles
         * are refused at creation), so l0 > 0. */
        double s = fabs(d) / l0;
        strain_sq += s * s;
        if (s > out->max_edge_strain)
            out->max_edge_strain = s;
    }
    out->rms_edge_strain = ne > 0 ? sqrt(strain_sq / ne) : 0.0;

    int nt = iso_mesh_triangle_count(m);
    const int *tri = iso_mesh_triangles(m);
    for (int t = 0; t < nt; t++) {
        double a0, a1, th0[3], th1[3];
        triangle_shape(x0, tri + 3 * t, &a0, th0);
        triangle_shape(x1, tri + 3 * t, &a1, th1);
        out->area_err += (a1 - a0) * (a1 - a0);
        for (int k = 0; k < 3; k++)
            out->angle_err += (th1[k] - th0[k]) * (th1[k] - th0[k]);
    }
}

static const iso_metrics_measure measures[] = {
    {"metricErr", "metric_err", "sum over edges of (|e'| - |e|)^2, deformed against rest",
     offsetof(iso_metrics, metric_err), 0},
    {"areaErr", "area_err", "sum over triangles of (A' - A)^2", offsetof(iso_metrics, area_err), 0},
    {"angleErr", "angle_err", "sum over triangle corners of (theta' - theta)^2, radians",
     offsetof(iso_metrics, angle_err), 0},
    {"maxEdgeStrain", "max_edge_strain", "largest | |e'| - |e| | / |e| over the edges",
     offsetof(iso_metrics, max_edge_strain), 1},
    {"rmsEdgeStrain", "rms_edge_strain", "root mean square of (|e'| - |e|) / |e| over the edges",
     offsetof(iso_metrics, rms_edge_strain), 1},
};

const iso_metrics_measure *iso_metrics_measures(size_t *n)
{
    *n = sizeof measures / sizeof measures[0];
    return measures;
}

double iso_metrics_value(const iso_metrics *m, const iso_metrics_measure *which)
{
    double v;
    memcpy(&v, (const char *)m + which->offset, sizeof v);
    return v;
}

void iso_metrics_print(FILE *f, const char *indent, const iso_metrics *m)
{
    for (size_t i = 0; i < sizeof measures / sizeof measures[0]; i++) {
        const iso_metrics_measure *k = &measures[i];
        double v = iso_metrics_value(m, k);
        char pct[32] = "";
        if (k->relative)
            snprintf(pct, sizeof pct, " (%.3f%%)", 100.0 * v);
        fprintf(f, "%s%-14s %.6e%s  %s\n", indent, k->name, v, pct, k->what);
    }
}
