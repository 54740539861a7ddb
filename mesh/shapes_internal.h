/* mesh/shapes_internal.h -- what the built-in shapes' files share
 * (shapes.c holds the table of shapes and the shapes built from grids and
 * rings; each larger shape has a file of its own). Not installed. */
#ifndef ISO_SHAPES_INTERNAL_H
#define ISO_SHAPES_INTERNAL_H

#include "iso_shapes.h"

/* M = the rigid motion turning by `deg` degrees about the unit axis u
 * through point c (row-major 4x4, x' = M [x;1]). */
void iso_shape__rotation_about(double M[16], const double u[3], double deg, const double c[3]);

/* The tentacle at geodesic frequency n (shapes_tentacle.c): allocates and
 * fills out's x, tri, kind, nv, nt and M. ISO_ENOMEM leaves what it could
 * allocate in out for the caller to free. */
int iso_shape__tentacle(int n, iso_shape *out);

#endif
