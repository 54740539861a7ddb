/* mesh/shapes.c -- the built-in shapes of iso_shapes.h.
 *
 * Every shape is generated from a structured layout (grids, rings, or the
 * boundary of a union of lattice boxes), so manifoldness and orientation
 * hold by construction rather than by repair. */
#include "iso_shapes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_geom.h"
#include "shapes_internal.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ------------------------------------------------------------------------ */
/* A growing vertex and triangle list                                         */
/* ------------------------------------------------------------------------ */

typedef struct builder {
    double *x;
    int nv, cap_v;
    int *tri;
    int nt, cap_t;
    int oom; /* sticky: an allocation failed, the result is unusable */
} builder;

static int add_vertex(builder *b, double x, double y, double z)
{
    if (b->oom)
        return -1;
    if (b->nv == b->cap_v) {
        int cap = b->cap_v ? 2 * b->cap_v : 1024;
        double *p = realloc(b->x, (size_t)cap * 3 * sizeof *p);
        if (!p) {
            b->oom = 1;
            return -1;
        }
        b->x = p;
        b->cap_v = cap;
    }
    b->x[3 * b->nv + 0] = x;
    b->x[3 * b->nv + 1] = y;
    b->x[3 * b->nv + 2] = z;
    return b->nv++;
}

static void add_tri(builder *b, int i, int j, int k)
{
    if (b->oom || i < 0 || j < 0 || k < 0)
        return;
    if (b->nt == b->cap_t) {
        int cap = b->cap_t ? 2 * b->cap_t : 2048;
        int *p = realloc(b->tri, (size_t)cap * 3 * sizeof *p);
        if (!p) {
            b->oom = 1;
            return;
        }
        b->tri = p;
        b->cap_t = cap;
    }
    b->tri[3 * b->nt + 0] = i;
    b->tri[3 * b->nt + 1] = j;
    b->tri[3 * b->nt + 2] = k;
    b->nt++;
}

/* A quad p00 p10 p11 p01, counter-clockwise seen from its outside. The
 * diagonal alternates in a checkerboard (`flip`), so a sheared or twisted
 * grid does not get a preferred direction. */
static void add_quad(builder *b, int p00, int p10, int p11, int p01, int flip)
{
    if (flip) {
        add_tri(b, p00, p10, p01);
        add_tri(b, p10, p11, p01);
    } else {
        add_tri(b, p00, p10, p11);
        add_tri(b, p00, p11, p01);
    }
}

static void builder_free(builder *b)
{
    free(b->x);
    free(b->tri);
    memset(b, 0, sizeof *b);
}

/* ------------------------------------------------------------------------ */
/* Transforms                                                                 */
/* ------------------------------------------------------------------------ */

/* M = rotation by `deg` about the unit axis u through point c. */
void iso_shape__rotation_about(double M[16], const double u[3], double deg, const double c[3])
{
    double a = deg * M_PI / 180.0, cs = cos(a), sn = sin(a), k = 1.0 - cs;
    double R[9] = {
        cs + u[0] * u[0] * k,        u[0] * u[1] * k - u[2] * sn, u[0] * u[2] * k + u[1] * sn,
        u[1] * u[0] * k + u[2] * sn, cs + u[1] * u[1] * k,        u[1] * u[2] * k - u[0] * sn,
        u[2] * u[0] * k - u[1] * sn, u[2] * u[1] * k + u[0] * sn, cs + u[2] * u[2] * k};
    iso_pose g;
    iso_pose_about(R, c, NULL, &g); /* the centre stays put */
    iso_pose_to_matrix(&g, M);
}

static void translation(double M[16], double tx, double ty, double tz)
{
    memset(M, 0, 16 * sizeof *M);
    M[0] = M[5] = M[10] = M[15] = 1.0;
    M[3] = tx;
    M[7] = ty;
    M[11] = tz;
}

/* Labels by height: z <= zlo fixed, z >= zhi handle, the rest free. */
static void label_by_z(const builder *b, double zlo, double zhi, unsigned char *kind)
{
    for (int i = 0; i < b->nv; i++) {
        double z = b->x[3 * i + 2];
        kind[i] = z <= zlo ? ISO_FIXED : z >= zhi ? ISO_HANDLE : ISO_FREE;
    }
}

/* ------------------------------------------------------------------------ */
/* Boundary of a union of lattice cells                                       */
/* ------------------------------------------------------------------------ */

/* The boundary of a set of unit cells is a closed 2-manifold as long as no
 * two cells meet only along an edge or at a corner; the shapes below are
 * unions of boxes laid out so that never happens. */
typedef struct voxels {
    int n[3];
    unsigned char *occ;
} voxels;

static int vox_get(const voxels *v, int i, int j, int k)
{
    if (i < 0 || j < 0 || k < 0 || i >= v->n[0] || j >= v->n[1] || k >= v->n[2])
        return 0;
    return v->occ[((size_t)k * v->n[1] + j) * v->n[0] + i];
}

/* Fills cells [lo, hi) on each axis. */
static void vox_box(voxels *v, int x0, int x1, int y0, int y1, int z0, int z1)
{
    for (int k = z0; k < z1; k++)
        for (int j = y0; j < y1; j++)
            for (int i = x0; i < x1; i++)
                v->occ[((size_t)k * v->n[1] + j) * v->n[0] + i] = 1;
}

/* Emits every cell face between an occupied and an empty cell, outward.
 * With open_bottom the faces on the plane z = 0 are left out, leaving a
 * boundary loop there. Vertices sit at lattice points (cell units). */
static int vox_surface(const voxels *v, int open_bottom, builder *b)
{
    size_t np = (size_t)(v->n[0] + 1) * (v->n[1] + 1) * (v->n[2] + 1);
    int *id = malloc(np * sizeof *id);
    if (!id)
        return ISO_ENOMEM;
    for (size_t i = 0; i < np; i++)
        id[i] = -1;
    int c[3];
    for (c[2] = 0; c[2] < v->n[2]; c[2]++)
        for (c[1] = 0; c[1] < v->n[1]; c[1]++)
            for (c[0] = 0; c[0] < v->n[0]; c[0]++) {
                if (!vox_get(v, c[0], c[1], c[2]))
                    continue;
                for (int a = 0; a < 3; a++)
                    for (int s = -1; s <= 1; s += 2) {
                        int nb[3] = {c[0], c[1], c[2]};
                        nb[a] += s;
                        if (vox_get(v, nb[0], nb[1], nb[2]))
                            continue;
                        if (open_bottom && a == 2 && s < 0 && c[2] == 0)
                            continue;
                        int ax = (a + 1) % 3, ay = (a + 2) % 3, p[4];
                        for (int q = 0; q < 4; q++) {
                            int u = q == 1 || q == 2, w = q >= 2; /* 00 10 11 01 */
                            int L[3];
                            L[a] = c[a] + (s > 0);
                            L[ax] = c[ax] + u;
                            L[ay] = c[ay] + w;
                            size_t key =
                                ((size_t)L[2] * (v->n[1] + 1) + L[1]) * (v->n[0] + 1) + L[0];
                            if (id[key] < 0)
                                id[key] = add_vertex(b, L[0], L[1], L[2]);
                            p[q] = id[key];
                        }
                        int flip = (c[0] + c[1] + c[2]) & 1;
                        if (s > 0)
                            add_quad(b, p[0], p[1], p[2], p[3], flip);
                        else
                            add_quad(b, p[0], p[3], p[2], p[1], flip);
                    }
            }
    free(id);
    return b->oom ? ISO_ENOMEM : ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* Smoothing (cactus)                                                         */
/* ------------------------------------------------------------------------ */

/* Vertex one-rings in CSR form, from the triangles' edges. */
typedef struct rings {
    int *start; /* nv + 1 */
    int *nbr;
} rings;

static int rings_build(const builder *b, rings *r)
{
    r->start = calloc((size_t)b->nv + 1, sizeof *r->start);
    r->nbr = malloc((size_t)b->nt * 6 * sizeof *r->nbr);
    int *fill = calloc((size_t)b->nv, sizeof *fill);
    if (!r->start || !r->nbr || !fill) {
        free(fill);
        return ISO_ENOMEM;
    }
    /* Each directed half-edge i->j once (closed surface: each undirected
     * edge twice, once per direction), so a vertex's list has no repeats. */
    for (int t = 0; t < b->nt; t++)
        for (int k = 0; k < 3; k++)
            r->start[b->tri[3 * t + k] + 1]++;
    for (int i = 0; i < b->nv; i++)
        r->start[i + 1] += r->start[i];
    for (int t = 0; t < b->nt; t++)
        for (int k = 0; k < 3; k++) {
            int i = b->tri[3 * t + k], j = b->tri[3 * t + (k + 1) % 3];
            r->nbr[r->start[i] + fill[i]++] = j;
        }
    free(fill);
    return ISO_OK;
}

static void rings_free(rings *r)
{
    free(r->start);
    free(r->nbr);
}

/* The cactus as an implicit surface F = 0: the smooth union of capsules
 * (segment a-b, radius r, in design units). The voxel surface only fixes
 * the topology and a starting tessellation; its vertices are then moved
 * onto F = 0 and relaxed along it. */
typedef struct capsule {
    double a[3], b[3], r;
} capsule;

static const capsule cactus_bones[5] = {
    {{2, 2, 2}, {2, 2, 22}, 2.0},   /* trunk */
    {{2, 2, 9}, {2, 7, 9}, 1.0},    /* arm A, out along +y */
    {{2, 7, 9}, {2, 7, 15}, 1.0},   /* arm A, up */
    {{2, 2, 13}, {2, -3, 13}, 1.0}, /* arm B, out along -y */
    {{2, -3, 13}, {2, -3, 18}, 1.0} /* arm B, up */
};

/* Blend width of the smooth union: wide enough for a fillet where an arm
 * meets the trunk, far narrower than the two-unit gap between an arm's
 * upright part and the trunk, so that gap stays open. */
#define CACTUS_BLEND 0.5

static double capsule_distance(const capsule *c, const double p[3])
{
    double ab[3], ap[3], t = 0, l2 = 0, d2 = 0;
    for (int k = 0; k < 3; k++) {
        ab[k] = c->b[k] - c->a[k];
        ap[k] = p[k] - c->a[k];
        t += ab[k] * ap[k];
        l2 += ab[k] * ab[k];
    }
    t = l2 > 0 ? fmin(1.0, fmax(0.0, t / l2)) : 0.0;
    for (int k = 0; k < 3; k++) {
        double d = ap[k] - t * ab[k];
        d2 += d * d;
    }
    return sqrt(d2) - c->r;
}

/* Polynomial smooth minimum (C1). */
static double smooth_min(double a, double b, double k)
{
    double h = fmax(k - fabs(a - b), 0.0) / k;
    return fmin(a, b) - h * h * k * 0.25;
}

static double cactus_field(const double p[3])
{
    double f = capsule_distance(&cactus_bones[0], p);
    for (int i = 1; i < 5; i++)
        f = smooth_min(f, capsule_distance(&cactus_bones[i], p), CACTUS_BLEND);
    return f;
}

static void cactus_gradient(const double p[3], double g[3])
{
    const double eps = 1e-6;
    for (int k = 0; k < 3; k++) {
        double q[3] = {p[0], p[1], p[2]}, fp, fm;
        q[k] = p[k] + eps;
        fp = cactus_field(q);
        q[k] = p[k] - eps;
        fm = cactus_field(q);
        g[k] = (fp - fm) / (2 * eps);
    }
}

/* Newton steps along the gradient onto F = 0 (F is close to a distance, so
 * a few steps suffice). */
static void cactus_project(double p[3])
{
    for (int it = 0; it < 30; it++) {
        double f = cactus_field(p), g[3], g2;
        if (fabs(f) < 1e-12)
            break;
        cactus_gradient(p, g);
        g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if (g2 < 1e-20)
            break;
        for (int k = 0; k < 3; k++)
            p[k] -= f * g[k] / g2;
    }
}

/* Projects every vertex (coordinates in design units) onto the cactus and
 * evens out the triangles with tangential umbrella steps, re-projecting
 * after each, so the vertices slide along the surface and never leave it. */
static int cactus_relax(builder *b, int iterations)
{
    rings r = {0};
    double *d = malloc((size_t)b->nv * 3 * sizeof *d);
    if (!d || rings_build(b, &r) != ISO_OK) {
        free(d);
        rings_free(&r);
        return ISO_ENOMEM;
    }
    for (int i = 0; i < b->nv; i++)
        cactus_project(b->x + 3 * i);
    for (int it = 0; it < iterations; it++) {
        for (int i = 0; i < b->nv; i++) {
            double s[3] = {0, 0, 0}, g[3], gn = 0, dn = 0;
            int n = r.start[i + 1] - r.start[i];
            for (int e = r.start[i]; e < r.start[i + 1]; e++)
                for (int k = 0; k < 3; k++)
                    s[k] += b->x[3 * r.nbr[e] + k];
            cactus_gradient(b->x + 3 * i, g);
            for (int k = 0; k < 3; k++) {
                d[3 * i + k] = n ? s[k] / n - b->x[3 * i + k] : 0.0;
                gn += g[k] * g[k];
            }
            gn = sqrt(gn);
            for (int k = 0; k < 3; k++)
                dn += d[3 * i + k] * (gn > 0 ? g[k] / gn : 0.0);
            for (int k = 0; k < 3; k++)
                d[3 * i + k] -= dn * (gn > 0 ? g[k] / gn : 0.0);
        }
        for (int i = 0; i < b->nv; i++) {
            for (int k = 0; k < 3; k++)
                b->x[3 * i + k] += 0.5 * d[3 * i + k];
            cactus_project(b->x + 3 * i);
        }
    }
    free(d);
    rings_free(&r);
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* The shapes                                                                 */
/* ------------------------------------------------------------------------ */

/* Box beam, cross-section 12x12 centred on the z axis, z in [0, 75], open
 * at the bottom like the benchmark's. */
static int build_bar(int res, builder *b, iso_shape *out)
{
    const double width = 12.0, length = 75.0, h = width / res;
    voxels v = {{res, res, (int)lround(length / h)}, NULL};
    v.occ = calloc((size_t)v.n[0] * v.n[1] * v.n[2], 1);
    if (!v.occ)
        return ISO_ENOMEM;
    vox_box(&v, 0, v.n[0], 0, v.n[1], 0, v.n[2]);
    int rc = vox_surface(&v, 1, b);
    double dz = length / v.n[2];
    free(v.occ);
    if (rc != ISO_OK)
        return rc;
    for (int i = 0; i < b->nv; i++) {
        b->x[3 * i + 0] = (b->x[3 * i + 0] - 0.5 * res) * h;
        b->x[3 * i + 1] = (b->x[3 * i + 1] - 0.5 * res) * h;
        b->x[3 * i + 2] *= dz;
    }
    out->kind = malloc(b->nv > 0 ? (size_t)b->nv : 1u);
    if (!out->kind)
        return ISO_ENOMEM;
    label_by_z(b, 0.06 * length + 1e-9, 0.945 * length - 1e-9, out->kind);
    const double axis[3] = {0, 0, 1}, centre[3] = {0, 0, 0};
    iso_shape__rotation_about(out->M, axis, 135.0, centre);
    return ISO_OK;
}

/* Zips the closed ring a (na vertices) to the closed ring b (nb) around
 * the z axis, both starting at angle 0 and running counter-clockwise seen
 * from +z, advancing whichever ring's next vertex has the smaller angle.
 * up: the triangles face +z (else −z). */
static void zip_rings(builder *bl, const int *a, int na, const int *b, int nb, int up)
{
    int i = 0, j = 0;
    while (i < na || j < nb) {
        /* compare (i+1)/na with (j+1)/nb exactly */
        int step_a = j >= nb || (i < na && (long)(i + 1) * nb < (long)(j + 1) * na);
        int p = a[i % na], q = b[j % nb];
        int r = step_a ? a[(i + 1) % na] : b[(j + 1) % nb];
        if (up)
            add_tri(bl, p, q, r);
        else
            add_tri(bl, p, r, q);
        if (step_a)
            i++;
        else
            j++;
    }
}

/* One cap: a centre vertex and concentric rings whose vertex counts grow
 * with the radius, so the triangles stay near equilateral instead of the
 * thin fan a single centre vertex would give. `outer` is the side's end
 * ring (na vertices) at height z. */
static int build_cap(builder *b, const int *outer, int na, double z, int up)
{
    int nc = (int)lround(na / (2.0 * M_PI));
    if (nc < 1)
        nc = 1;
    int *prev = malloc((size_t)na * sizeof *prev), *cur = malloc((size_t)na * sizeof *cur);
    if (!prev || !cur) {
        free(prev);
        free(cur);
        return ISO_ENOMEM;
    }
    int centre = add_vertex(b, 0, 0, z), nprev = 0;
    for (int m = 1; m <= nc; m++) {
        int cm = m == nc ? na : (int)lround((double)na * m / nc);
        if (cm < 3)
            cm = 3;
        double rad = (double)m / nc;
        for (int i = 0; i < cm; i++) {
            double t = 2.0 * M_PI * i / cm;
            cur[i] = m == nc ? outer[i] : add_vertex(b, rad * cos(t), rad * sin(t), z);
        }
        if (m == 1) {
            for (int i = 0; i < cm; i++) {
                if (up)
                    add_tri(b, centre, cur[i], cur[(i + 1) % cm]);
                else
                    add_tri(b, centre, cur[(i + 1) % cm], cur[i]);
            }
        } else {
            zip_rings(b, prev, nprev, cur, cm, up);
        }
        int *tmp = prev;
        prev = cur;
        cur = tmp;
        nprev = cm;
    }
    free(prev);
    free(cur);
    return b->oom ? ISO_ENOMEM : ISO_OK;
}

/* Radius 1, z in [0, 12], closed with caps. */
static int build_cylinder(int res, builder *b, iso_shape *out)
{
    const double height = 12.0;
    int na = res, nseg = (int)lround(height / (2.0 * M_PI / na));
    if (nseg < 1)
        nseg = 1;
    int *ring = malloc((size_t)(nseg + 1) * na * sizeof *ring);
    if (!ring)
        return ISO_ENOMEM;
    for (int k = 0; k <= nseg; k++)
        for (int i = 0; i < na; i++) {
            double t = 2.0 * M_PI * i / na;
            ring[k * na + i] = add_vertex(b, cos(t), sin(t), height * k / nseg);
        }
    for (int k = 0; k < nseg; k++)
        for (int i = 0; i < na; i++) {
            int i1 = (i + 1) % na;
            add_quad(b, ring[k * na + i], ring[k * na + i1], ring[(k + 1) * na + i1],
                     ring[(k + 1) * na + i], (i + k) & 1);
        }
    int rc = build_cap(b, ring, na, 0.0, 0);
    if (rc == ISO_OK)
        rc = build_cap(b, ring + (size_t)nseg * na, na, height, 1);
    free(ring);
    if (rc != ISO_OK)
        return rc;
    out->kind = malloc(b->nv > 0 ? (size_t)b->nv : 1u);
    if (!out->kind)
        return ISO_ENOMEM;
    label_by_z(b, 0.042 * height, (1.0 - 0.042) * height, out->kind);
    const double axis[3] = {0, -1, 0}, centre[3] = {0, 0, 0.5 * height};
    iso_shape__rotation_about(out->M, axis, 120.0, centre);
    return ISO_OK;
}

/* Height of the bump field: a 3x3 array of Gaussian bumps, 6 and 10 high,
 * that fade out before the fixed and handle strips. */
static double bump_height(double x, double y)
{
    double z = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double cx = 25.0 + 25.0 * i, cy = 25.0 + 25.0 * j;
            double amp = (i + j) & 1 ? 6.0 : 10.0, sg = 7.0;
            double r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
            z += amp * exp(-r2 / (2 * sg * sg));
        }
    return z;
}

/* n x n grid on [0,100]², fixed strip x <= 4, handle strip x >= 96.5,
 * the handle translated like the benchmark's. */
static int build_bumpplane(int res, builder *b, iso_shape *out)
{
    int n = res;
    double h = 100.0 / (n - 1);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++)
            add_vertex(b, i * h, j * h, bump_height(i * h, j * h));
    for (int j = 0; j + 1 < n; j++)
        for (int i = 0; i + 1 < n; i++)
            add_quad(b, j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i,
                     (i + j) & 1);
    if (b->oom)
        return ISO_ENOMEM;
    out->kind = malloc(b->nv > 0 ? (size_t)b->nv : 1u);
    if (!out->kind)
        return ISO_ENOMEM;
    for (int i = 0; i < b->nv; i++) {
        double x = b->x[3 * i];
        out->kind[i] = x <= 4.0 ? ISO_FIXED : x >= 96.5 ? ISO_HANDLE : ISO_FREE;
    }
    translation(out->M, -32.299956, 0.0, 56.703263);
    return ISO_OK;
}

/* A trunk and two L-shaped arms. The voxel boxes enclose the capsules of
 * cactus_bones (touching them), so moving the voxel surface onto the
 * implicit surface keeps it a sphere. Scaled to the benchmark cactus's box
 * (height 0.82, trunk axis at x = y = 0.5). The arms stay below the handle
 * (the trunk's top) and keep two units of air between their upright parts
 * and the trunk. */
static int build_cactus(int res, builder *b, iso_shape *out)
{
    /* design units: x in [0,4], y in [-4,8] (stored shifted by +4), z in [0,24] */
    static const int box[5][6] = {
        {0, 4, 0, 4, 0, 24},   /* trunk */
        {1, 3, 4, 8, 8, 10},   /* arm A, out along +y */
        {1, 3, 6, 8, 8, 16},   /* arm A, up */
        {1, 3, -4, 0, 12, 14}, /* arm B, out along -y */
        {1, 3, -4, -2, 12, 19} /* arm B, up */
    };
    const int yshift = 4;
    voxels v = {{4 * res, 12 * res, 24 * res}, NULL};
    v.occ = calloc((size_t)v.n[0] * v.n[1] * v.n[2], 1);
    if (!v.occ)
        return ISO_ENOMEM;
    for (int q = 0; q < 5; q++)
        vox_box(&v, box[q][0] * res, box[q][1] * res, (box[q][2] + yshift) * res,
                (box[q][3] + yshift) * res, box[q][4] * res, box[q][5] * res);
    int rc = vox_surface(&v, 0, b);
    free(v.occ);
    if (rc != ISO_OK)
        return rc;
    for (int i = 0; i < b->nv; i++) {
        b->x[3 * i + 0] /= res;
        b->x[3 * i + 1] = b->x[3 * i + 1] / res - yshift;
        b->x[3 * i + 2] /= res;
    }
    rc = cactus_relax(b, 20 * res);
    if (rc != ISO_OK)
        return rc;
    /* design height 24 -> 0.82; trunk axis (2, 2) -> (0.5, 0.5) */
    const double s = 0.82 / 24.0, z0 = 0.07;
    for (int i = 0; i < b->nv; i++) {
        double *p = b->x + 3 * i;
        p[0] = 0.5 + (p[0] - 2.0) * s;
        p[1] = 0.5 + (p[1] - 2.0) * s;
        p[2] = z0 + p[2] * s;
    }
    out->kind = malloc(b->nv > 0 ? (size_t)b->nv : 1u);
    if (!out->kind)
        return ISO_ENOMEM;
    label_by_z(b, z0 + 0.10 * 0.82, z0 + 0.88 * 0.82, out->kind);
    const double axis[3] = {-1, 0, 0}, centre[3] = {0.5, 0.5, z0 + 0.5 * 0.82};
    iso_shape__rotation_about(out->M, axis, 70.0, centre);
    return ISO_OK;
}

/* The tentacle builds its arrays itself (shapes_tentacle.c); the builder
 * takes them, so that a failure frees them as any shape's. */
static int build_tentacle(int res, builder *b, iso_shape *out)
{
    int rc = iso_shape__tentacle(res, out);
    b->x = out->x;
    b->tri = out->tri;
    b->nv = b->cap_v = out->nv;
    b->nt = b->cap_t = out->nt;
    out->x = NULL;
    out->tri = NULL;
    return rc;
}

/* ------------------------------------------------------------------------ */
/* Public API                                                                 */
/* ------------------------------------------------------------------------ */

typedef struct shape_def {
    const char *name;
    int def_res, min_res, max_res;
    const char *res_meaning;
    int (*build)(int res, builder *b, iso_shape *out);
} shape_def;

static const shape_def shapes[] = {
    {"bar", 12, 4, 64, "cells across the 12-wide side", build_bar},
    {"cylinder", 40, 8, 256, "vertices around the circumference", build_cylinder},
    {"bumpplane", 61, 5, 401, "vertices along each side", build_bumpplane},
    {"cactus", 2, 1, 8, "cells per design unit", build_cactus},
    {"tentacle", 24, 4, 320, "geodesic frequency: 10 n^2 + 2 vertices", build_tentacle},
};
#define N_SHAPES ((int)(sizeof shapes / sizeof shapes[0]))

const char *const *iso_shape_names(void)
{
    static const char *const names[N_SHAPES + 1] = {"bar",    "cylinder", "bumpplane",
                                                    "cactus", "tentacle", NULL};
    return names;
}

int iso_shape_init(iso_shape *out, const char *name, int resolution, iso_err *err)
{
    if (!out)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_shape_init: out is NULL");
    memset(out, 0, sizeof *out);
    const shape_def *d = NULL;
    for (int i = 0; name && i < N_SHAPES; i++)
        if (strcmp(name, shapes[i].name) == 0)
            d = &shapes[i];
    if (!d)
        return iso_err_set(
            err, ISO_EINVAL, -1,
            "Unknown shape '%s': the built-in shapes are bar, cylinder, bumpplane, cactus and "
            "tentacle.",
            name ? name : "(null)");
    int res = resolution ? resolution : d->def_res;
    if (res < d->min_res || res > d->max_res)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "Resolution %d of shape '%s' (%s) is outside %d..%d.", resolution,
                           d->name, d->res_meaning, d->min_res, d->max_res);
    builder b = {0};
    int rc = d->build(res, &b, out);
    if (rc == ISO_OK && b.oom)
        rc = ISO_ENOMEM;
    if (rc != ISO_OK) {
        builder_free(&b);
        free(out->kind);
        memset(out, 0, sizeof *out);
        return iso_err_set(err, rc, -1, "Out of memory while building shape '%s' at resolution %d.",
                           d->name, res);
    }
    snprintf(out->name, sizeof out->name, "%s", d->name);
    out->resolution = res;
    out->nv = b.nv;
    out->nt = b.nt;
    out->x = b.x;
    out->tri = b.tri;
    return ISO_OK;
}

void iso_shape_deinit(iso_shape *s)
{
    if (!s)
        return;
    free(s->x);
    free(s->tri);
    free(s->kind);
    memset(s, 0, sizeof *s);
}

int iso_shape_regions(const iso_shape *s, iso_regions *r, iso_err *err)
{
    int rc = iso_regions_init(r, s->nv, err);
    if (rc != ISO_OK)
        return rc;
    int handles = 0;
    for (int i = 0; i < s->nv; i++) {
        r->kind[i] = s->kind[i];
        r->handle[i] = s->kind[i] == ISO_HANDLE ? 0 : -1;
        handles |= s->kind[i] == ISO_HANDLE;
    }
    r->n_handles = handles;
    return ISO_OK;
}
