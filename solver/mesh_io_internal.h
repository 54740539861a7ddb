/* solver/mesh_io_internal.h -- private cross-file symbols of the mesh module
 * (mesh.c and the mesh_io_*.c loaders); not installed, not public API. */
#ifndef ISO_MESH_IO_INTERNAL_H
#define ISO_MESH_IO_INTERNAL_H

#include <stddef.h>

#include "iso_mesh.h"

/* Replaces m's note (copied). Returns ISO_OK or ISO_ENOMEM (note unchanged).
 * Only loaders call this, right after creating m. */
int iso_mesh__set_note(iso_mesh *m, const char *note);

#endif
