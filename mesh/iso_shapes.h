/* mesh/iso_shapes.h -- procedural meshes that stand in for the benchmark.
 *
 * The Botsch–Sorkine benchmark is not openly licensed, so the project ships
 * look-alikes it can always run: each shape comes with the benchmark's kind
 * of problem, as vertex regions (bottom fixed, top handle) and the handle's
 * final rigid transform M.
 *
 *   bar        12x12 box beam along z, open at the bottom like the
 *              benchmark's; 135° twist about z.
 *   cylinder   radius 1, height 12, closed with ring-triangulated caps;
 *              120° bend about (0,-1,0) through the middle.
 *   bumpplane  grid on [0,100]² with smooth bumps (open disk);
 *              translation of the far strip up and inwards.
 *   cactus     a trunk with two L-shaped arms, a closed genus-0 surface
 *              (the boundary of a union of boxes, smoothed); 70° bend about
 *              −x through the middle of the trunk.
 *   tentacle   a tapered capsule with eight spiral ridges, closed (a
 *              geodesic sphere mapped onto it: triangles of nearly equal
 *              area at any size, 2k to 1M vertices); 60° turn of the top
 *              cap about (1, 0, 1) through the middle, a bend and a twist
 *              at once. The shape to test large meshes on.
 *
 * An iso_shape is a caller-owned struct (init/deinit). Its arrays go
 * straight to iso_mesh_create(), and iso_shape_regions() turns its labels
 * into an iso_regions. Every shape is a valid 2-manifold with consistently
 * oriented (outward) triangles and no self-intersections. */
#ifndef ISO_SHAPES_H
#define ISO_SHAPES_H

#include "iso_err.h"
#include "iso_regions.h"

#define ISO_SHAPE_NAME_MAX 32

typedef struct iso_shape {
    char name[ISO_SHAPE_NAME_MAX];
    int resolution; /* the resolution actually used */
    int nv, nt;
    double *x;           /* 3*nv positions, owned */
    int *tri;            /* 3*nt vertex indices, outward orientation, owned */
    unsigned char *kind; /* nv labels: ISO_FIXED, ISO_FREE or ISO_HANDLE, owned */
    double M[16];        /* handle's final transform, row-major, x' = M [x;1] */
} iso_shape;

/* The built-in names, NULL-terminated, in a fixed order. Never NULL. */
ISO_API const char *const *iso_shape_names(void);

/* Builds shape `name` into *out (which need not be initialised).
 * resolution: 0 for the default (a few thousand vertices), else a
 * shape-specific density, larger is finer:
 *   bar        cells across the 12-wide side   (default 12, 4..64)
 *   cylinder   vertices around the circumference (default 40, 8..256)
 *   bumpplane  vertices along each side          (default 61, 5..401)
 *   cactus     cells per design unit              (default 2, 1..8)
 *   tentacle   geodesic frequency n: 10 n² + 2 vertices (default 24, 4..320;
 *              100: 100,002 vertices, 128: 163,842, 317: 1,004,892)
 * On failure returns a negative ISO_E* code (ISO_EINVAL names the unknown
 * shape or the out-of-range resolution), leaves *out empty and fills err.
 * The caller releases *out with iso_shape_deinit(). */
ISO_API ISO_NODISCARD int iso_shape_init(iso_shape *out, const char *name, int resolution,
                                         iso_err *err);

/* Frees the arrays and zeroes the struct; a zeroed or deinited struct is fine. */
ISO_API void iso_shape_deinit(iso_shape *s);

/* Initialises r (which the caller deinits with iso_regions_deinit()) from
 * the shape's labels; all handle vertices are on handle 0. */
ISO_API ISO_NODISCARD int iso_shape_regions(const iso_shape *s, iso_regions *r, iso_err *err);

#endif
