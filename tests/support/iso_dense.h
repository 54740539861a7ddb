/* tests/support/iso_dense.h -- the method's forms over the whole mesh, dense:
 * the reference the solver's sparse free-free system is checked against.
 *
 * Part of the test-support library (tests/CMakeLists.txt), not of
 * libisoshape: it is written from the public element forms (iso_element.h)
 * and the mesh's adjacency alone, independently of the solver's element
 * list, slot map and assembly paths. For tests and small meshes only. */
#ifndef ISO_DENSE_H
#define ISO_DENSE_H

#include "iso_err.h"
#include "iso_mesh.h"
#include "iso_solver.h"

/* Assembles the whole 3nv x 3nv matrix A(x) (all vertices, no constraints,
 * no restoration term) as dense row-major into `A` (caller-owned, (3nv)^2
 * doubles). opts NULL = iso_solver_opts_default; only omega and weighting
 * are read. ISO_EINVAL for omega outside (0, 1], ISO_ENUMERIC naming a
 * degenerate triangle. */
ISO_NODISCARD int iso_assemble_dense(const iso_mesh *m, const double *x,
                                     const iso_solver_opts *opts, double *A, iso_err *err);

/* d(v) = (1−ω) d1 + ω d2 at positions x, evaluated element by element
 * (no global matrix); d1 and d2 separately if the pointers are non-NULL.
 * NAN when a triangle is degenerate. */
double iso_distortion(const iso_mesh *m, const double *x, const double *v,
                      const iso_solver_opts *opts, double *d1, double *d2);

#endif
