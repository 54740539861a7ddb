/* tests/geom_fixtures.h -- meshes, fields, paths and dense linear algebra
 * built inside the tests, so every property test states its own geometry.
 *
 * Not a library: each test program does `#include "geom_fixtures.c"` (the
 * CMake glob only picks tests/test_*.c). Every function is FX_FN: static, so
 * a test links only what it uses, and marked unused, so a test that leaves
 * one unused still compiles under -Werror. */
#ifndef ISO_GEOM_FIXTURES_H
#define ISO_GEOM_FIXTURES_H

#include <stdint.h>

#include "iso_mesh.h"
#include "iso_motion.h"
#include "iso_regions.h"

#define FX_FN static __attribute__((unused))

/* ---- LAPACK (reference BLAS/LAPACK from liblapack, column-major) -------- */
extern void dsyev_(const char *jobz, const char *uplo, const int *n, double *a, const int *lda,
                   double *w, double *work, const int *lwork, int *info);
extern void dposv_(const char *uplo, const int *n, const int *nrhs, double *a, const int *lda,
                   double *b, const int *ldb, int *info);
extern void dgesv_(const int *n, const int *nrhs, double *a, const int *lda, int *ipiv, double *b,
                   const int *ldb, int *info);

/* Eigenvalues (ascending) of the symmetric n x n matrix A (row-major; A is
 * symmetric so row/column major agree). A is not modified. */
FX_FN void fx_eigvalsh(int n, const double *A, double *w);
/* Solves the SPD system A x = b (A row-major n x n, copied); 0 on success. */
FX_FN int fx_spd_solve(int n, const double *A, const double *b, double *x);

/* ---- deterministic random numbers (splitmix64) -------------------------- */
typedef struct fx_rng {
    uint64_t s;
} fx_rng;
FX_FN double fx_uniform(fx_rng *r, double lo, double hi);

/* ---- small vectors ------------------------------------------------------ */
FX_FN void fx_cross(const double a[3], const double b[3], double c[3]);
FX_FN double fx_dot(const double a[3], const double b[3]);
FX_FN double fx_norm(const double a[3]);
/* Row-major rotation by angle th about the unit axis a (Rodrigues). */
FX_FN void fx_rotation(const double a[3], double th, double R[9]);

/* ---- raw meshes (arrays the test owns) ---------------------------------- */
typedef struct fx_mesh {
    int nv, nt;
    double *x; /* 3*nv */
    int *tri;  /* 3*nt */
} fx_mesh;
FX_FN void fx_mesh_free(fx_mesh *m);
/* nx x ny grid in the z = 0 plane, spacing (lx/(nx-1), ly/(ny-1)); vertex
 * (i, j) is j*nx + i. Quads are split along alternating diagonals. */
FX_FN fx_mesh fx_grid(int nx, int ny, double lx, double ly);
/* Icosahedron subdivided `level` times and projected on the sphere of
 * radius r (level 2: 162 vertices, 320 triangles), then every vertex moved
 * by a random offset of size up to `jitter` * r in each coordinate. */
FX_FN fx_mesh fx_icosphere(int level, double r, double jitter, fx_rng *rng);
/* 1->4 split: each edge gets its midpoint; a field v (3 per vertex, may be
 * NULL) is interpolated linearly into *vout (malloc'd, caller frees). */
FX_FN fx_mesh fx_subdivide(const fx_mesh *m, const double *v, double **vout);
/* Adds a second mesh's vertices and triangles to *m (disjoint union). */
FX_FN void fx_append(fx_mesh *m, const fx_mesh *b);
FX_FN void fx_translate(fx_mesh *m, const double d[3]);
/* Creates the iso_mesh, asserting success. */
FX_FN iso_mesh *fx_make(const fx_mesh *m);

/* v_k = a + b × x_k for all nv vertices. */
FX_FN void fx_rigid_field(int nv, const double *x, const double a[3], const double b[3], double *v);

/* ---- handle paths -------------------------------------------------------- */
/* Rotation of every handle about the unit axis `axis` through `c` by the
 * angle th(t) = amp * sin(freq * π t). */
typedef struct fx_rot_path {
    double axis[3], c[3];
    double amp, freq;
} fx_rot_path;
FX_FN iso_path fx_rot_path_make(fx_rot_path *p);

/* Translation p(t) = t d + sin(π t) bulge (no rotation). */
typedef struct fx_trans_path {
    double d[3], bulge[3];
} fx_trans_path;
FX_FN iso_path fx_trans_path_make(fx_trans_path *p);

/* ---- the regions helper -------------------------------------------------- */
/* Allocates regions for nv vertices with kind[i] given (handle 0 for every
 * ISO_HANDLE vertex). */
FX_FN void fx_regions(iso_regions *r, int nv, const unsigned char *kind);

#endif
