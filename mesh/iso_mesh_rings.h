/* mesh/iso_mesh_rings.h -- each vertex's one-ring: the vertices it shares an
 * edge with and the triangles it is a corner of, as index lists.
 *
 * The solver's ring rotations (solver/rotate.c) and the reduced model's
 * (solver/proxy.c) both walk them; they are made here once, from the
 * mesh's own edge and triangle lists, in one order both rely on:
 * neighbours in the order of the mesh's edges (iso_mesh_edges), corners in
 * the order of the triangles. Internal to the library's parts (not
 * installed): its shape follows their needs. Made once and immutable, so
 * any number of threads may read one. */
#ifndef ISO_MESH_RINGS_H
#define ISO_MESH_RINGS_H

#include "iso_mesh.h"

typedef struct iso_mesh_rings {
    int nv;
    /* nv + 1 entries: vertex v's neighbours are nb[nb_start[v] .. nb_start[v + 1]) */
    int *nb_start, *nb;
    /* nv + 1 entries: vertex v's corners are corner[corner_start[v] ..
     * corner_start[v + 1]), each an index k into iso_mesh_triangles (its
     * triangle k / 3, its position in it k % 3) */
    int *corner_start, *corner;
} iso_mesh_rings;

/* Builds the rings of m into *r (caller-owned; deinit with
 * iso_mesh_rings_deinit). ISO_ENOMEM with err filled when out of memory; r is
 * then zeroed. */
int iso_mesh_rings_init(iso_mesh_rings *r, const iso_mesh *m, iso_err *err);
void iso_mesh_rings_deinit(iso_mesh_rings *r); /* a zeroed or deinited struct is fine */

#endif
