/* mesh/shapes_tentacle.c -- the tentacle (iso_shapes.h): a closed,
 * curved shape at any size from 2k to 1M vertices, for bending and
 * twisting at scale.
 *
 * The surface is a geodesic sphere (an icosahedron, each face split into
 * n² triangles, projected to the sphere: 10 n² + 2 vertices, 20 n²
 * triangles, every vertex of valence 5 or 6) mapped onto a capsule: the
 * sphere's area is uniform in z (Archimedes), and so is a cylinder's, so
 * the band of the sphere between two heights goes to the body and the two
 * polar caps to hemispheres, each in proportion to its area. Triangles
 * keep nearly equal areas; their aspect stays below about 2.5 where body
 * and caps meet. The body then tapers (radius 1 at the bottom to 0.7 at
 * the top, with a bulge), and carries eight shallow ridges that spiral
 * once around it, faded out towards the caps so that the surface stays
 * smooth where it meets them. Orientation is outward by construction: the
 * icosahedron's faces are, and the maps keep each point's direction from
 * the axis. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapes_internal.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define HALF_LENGTH 3.0 /* the body: z in [−3, 3] */

/* The icosahedron's corners: (±1, ±φ, 0), (0, ±1, ±φ), (±φ, 0, ±1). */
#define PHI 1.6180339887498949
static const double ico_v[12][3] = {
    {-1, PHI, 0},  {1, PHI, 0},  {-1, -PHI, 0}, {1, -PHI, 0}, {0, -1, PHI},  {0, 1, PHI},
    {0, -1, -PHI}, {0, 1, -PHI}, {PHI, 0, -1},  {PHI, 0, 1},  {-PHI, 0, -1}, {-PHI, 0, 1},
};

/* Its faces, counter-clockwise seen from outside. */
static const int ico_f[20][3] = {
    {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
    {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
    {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1},
};

/* The icosahedron's 30 edges (a < b) and, per face side, its edge. */
typedef struct ico_edges {
    int a[30], b[30];
    int of[20][3]; /* side k of face f joins corners k and (k + 1) % 3 */
} ico_edges;

static void find_edges(ico_edges *e)
{
    int n = 0;
    for (int f = 0; f < 20; f++)
        for (int k = 0; k < 3; k++) {
            int u = ico_f[f][k], v = ico_f[f][(k + 1) % 3], a = u < v ? u : v, b = u < v ? v : u;
            int found = -1;
            for (int q = 0; q < n; q++)
                if (e->a[q] == a && e->b[q] == b)
                    found = q;
            if (found < 0) {
                e->a[n] = a;
                e->b[n] = b;
                found = n++;
            }
            e->of[f][k] = found;
        }
}

/* Vertex of face f at grid point (i, j), i + j <= n: the point
 * A + i/n (B − A) + j/n (C − A) of face (A, B, C). Corners, edge points
 * and interior points are numbered once each: corners 0..11, then n − 1
 * per edge from its lower corner, then (n − 1)(n − 2)/2 per face. */
static int grid_vertex(const ico_edges *e, int f, int n, int i, int j)
{
    int k = n - i - j; /* weight of A */
    if (i == 0 && j == 0)
        return ico_f[f][0];
    if (i == n)
        return ico_f[f][1];
    if (j == n)
        return ico_f[f][2];
    int side = -1, step = 0; /* along side: from its first corner */
    if (j == 0)
        side = 0, step = i; /* A → B */
    else if (k == 0)
        side = 1, step = j; /* B → C */
    else if (i == 0)
        side = 2, step = n - j; /* C → A */
    if (side >= 0) {
        int q = e->of[f][side], from = ico_f[f][side];
        int s = from == e->a[q] ? step : n - step;
        return 12 + q * (n - 1) + (s - 1);
    }
    /* interior: rows j = 1..n − 2, in row j the points i = 1..n − 1 − j */
    int before = 0;
    for (int r = 1; r < j; r++)
        before += n - 1 - r;
    return 12 + 30 * (n - 1) + f * ((n - 1) * (n - 2) / 2) + before + (i - 1);
}

/* The body's radius at t in [0, 1] (bottom to top): a taper from 1 to 0.7
 * with a bulge, flat at both ends so that the caps meet it smoothly. */
static double body_radius(double t)
{
    double s = t * t * (3 - 2 * t), b = sin(2 * M_PI * t);
    return 1.0 - 0.3 * s + 0.06 * b * b;
}

/* The unit-sphere point p onto the tentacle, into q. */
static void to_tentacle(const double p[3], double q[3])
{
    const double H = HALF_LENGTH, c = 1.0 / (2.0 * (1.0 + H)); /* each cap's share of the area */
    double s = 0.5 * (p[2] + 1.0), rho = hypot(p[0], p[1]);
    double dx = rho > 0 ? p[0] / rho : 1.0, dy = rho > 0 ? p[1] / rho : 0.0;
    double r, z, ridge = 0;
    if (s < c || s > 1 - c) { /* a cap: a hemisphere of the body's end radius */
        int top = s > 1 - c;
        double zh = top ? 1.0 - (1.0 - s) / c : -1.0 + s / c; /* in [−1, 0] or [0, 1] */
        double R = body_radius(top ? 1.0 : 0.0);
        r = R * sqrt(fmax(0.0, 1.0 - zh * zh));
        z = (top ? H : -H) + R * zh;
    } else {
        double t = (s - c) / (1 - 2 * c), theta = atan2(dy, dx), w = sin(M_PI * t);
        ridge = 0.05 * w * w * cos(8.0 * theta + 2.0 * M_PI * t);
        r = body_radius(t) * (1.0 + ridge);
        z = -H + 2.0 * H * t;
    }
    q[0] = r * dx;
    q[1] = r * dy;
    q[2] = z;
}

int iso_shape__tentacle(int n, iso_shape *out)
{
    int nv = 10 * n * n + 2, nt = 20 * n * n;
    out->x = malloc((size_t)nv * 3 * sizeof *out->x);
    out->tri = malloc((size_t)nt * 3 * sizeof *out->tri);
    out->kind = malloc((size_t)nv);
    if (!out->x || !out->tri || !out->kind)
        return ISO_ENOMEM;
    ico_edges e;
    find_edges(&e);
    int t = 0;
    for (int f = 0; f < 20; f++) {
        const double *A = ico_v[ico_f[f][0]], *B = ico_v[ico_f[f][1]], *C = ico_v[ico_f[f][2]];
        for (int j = 0; j <= n; j++)
            for (int i = 0; i + j <= n; i++) {
                double p[3], len = 0;
                for (int k = 0; k < 3; k++) {
                    p[k] = A[k] + (B[k] - A[k]) * i / n + (C[k] - A[k]) * j / n;
                    len += p[k] * p[k];
                }
                len = sqrt(len);
                for (int k = 0; k < 3; k++)
                    p[k] /= len;
                /* a point on a face's side is made by both faces; the last wins */
                to_tentacle(p, out->x + 3 * grid_vertex(&e, f, n, i, j));
                if (i + j < n) { /* the grid's upward triangle, and the downward one beside it */
                    int *q = out->tri + 3 * t++;
                    q[0] = grid_vertex(&e, f, n, i, j);
                    q[1] = grid_vertex(&e, f, n, i + 1, j);
                    q[2] = grid_vertex(&e, f, n, i, j + 1);
                    if (i + j + 1 < n) {
                        q = out->tri + 3 * t++;
                        q[0] = grid_vertex(&e, f, n, i + 1, j);
                        q[1] = grid_vertex(&e, f, n, i + 1, j + 1);
                        q[2] = grid_vertex(&e, f, n, i, j + 1);
                    }
                }
            }
    }
    out->nv = nv;
    out->nt = t;
    /* The bottom cap is fixed, the top cap is the handle. */
    for (int i = 0; i < nv; i++) {
        double z = out->x[3 * i + 2];
        out->kind[i] = z <= -HALF_LENGTH ? ISO_FIXED : z >= HALF_LENGTH ? ISO_HANDLE : ISO_FREE;
    }
    /* The handle turns 60° about an axis halfway between x and z through
     * the body's middle: a bend of the tentacle sideways and a twist of
     * its tip together. */
    const double h = sqrt(0.5), u[3] = {h, 0, h}, centre[3] = {0, 0, 0};
    iso_shape__rotation_about(out->M, u, 60.0, centre);
    return ISO_OK;
}
