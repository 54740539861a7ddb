/* mesh/iso_mesh.h -- a validated triangle mesh, its topology, and mesh files.
 *
 * An iso_mesh is immutable once created: rest positions, triangles, the edge
 * list and, for every interior edge, its two triangles. Creation validates
 * everything the solver relies on, so a mesh that exists is usable:
 *   - indices in range, no repeated index inside a triangle;
 *   - finite coordinates;
 *   - no degenerate or nearly degenerate triangle (quality below
 *     ISO_MESH_MIN_QUALITY, see below);
 *   - no edge shared by more than two triangles, no duplicated triangle.
 * Unreferenced vertices are allowed; they are reported by
 * iso_mesh_unreferenced_count() and never move.
 *
 * Files: OFF, OBJ and PLY (ASCII and binary little/big endian) are read;
 * OFF, OBJ and PLY (ASCII or binary little endian) are written. Convex
 * polygons are triangulated as fans and the mesh's note says so; a
 * non-convex polygon is an error. Every error names the file and the line
 * (text) or byte offset (binary) and what is wrong. */
#ifndef ISO_MESH_H
#define ISO_MESH_H

#include "iso_err.h"

/* Triangle quality q = 4*sqrt(3)*area / (sum of squared edge lengths):
 * 1 for an equilateral triangle, 0 for a degenerate one. Below this a
 * triangle's rigid fit is ill-conditioned (condition grows like 1/q^2), so
 * the mesh is refused. The benchmark meshes' worst is far above it. */
#define ISO_MESH_MIN_QUALITY 1e-4

typedef struct iso_mesh iso_mesh; /* opaque */

/* Builds a mesh from arrays (copied). `origin` names the source in messages
 * (a file name, or NULL for "mesh"); `tri_src` optionally gives, per
 * triangle, the line (text) or byte offset (binary) it came from, and
 * `src_is_offset` says which.
 * Checks run in this order, the first failure wins: counts (nv >= 3,
 * nt >= 1), index range, repeated index in a triangle, finite coordinates,
 * duplicated triangle, quality, non-manifold edge. Codes: ISO_EINVAL for
 * caller bugs (NULL arrays, negative counts); ISO_EPARSE for malformed data
 * (index out of range, repeated index, non-finite coordinate); ISO_EMESH for
 * a well-formed but unusable mesh (too few vertices, no triangle, duplicated,
 * degenerate or non-manifold triangles). err->offset is the offending
 * triangle's tri_src entry, or -1. On failure *out is NULL. */
ISO_API ISO_NODISCARD int iso_mesh_create(int nv, const double *x, int nt, const int *tri,
                                          const char *origin, iso_mesh **out, iso_err *err);
ISO_API ISO_NODISCARD int iso_mesh_create_src(int nv, const double *x, int nt, const int *tri,
                                              const char *origin, const long *tri_src,
                                              int src_is_offset, iso_mesh **out, iso_err *err);
ISO_API void iso_mesh_destroy(iso_mesh *m); /* NULL is a no-op */

ISO_API int iso_mesh_vertex_count(const iso_mesh *m);
ISO_API int iso_mesh_triangle_count(const iso_mesh *m);
ISO_API const double *iso_mesh_positions(const iso_mesh *m); /* 3*nv, rest pose */
ISO_API const int *iso_mesh_triangles(const iso_mesh *m);    /* 3*nt */
ISO_API const char *iso_mesh_origin(const iso_mesh *m);

/* Undirected edges, each as (i, j) with i < j, sorted. */
ISO_API int iso_mesh_edge_count(const iso_mesh *m);
ISO_API const int *iso_mesh_edges(const iso_mesh *m); /* 2*ne */
/* For edge e: its triangles (t0, t1); t1 = -1 on a boundary edge. */
ISO_API const int *iso_mesh_edge_triangles(const iso_mesh *m); /* 2*ne */
ISO_API int iso_mesh_unreferenced_count(const iso_mesh *m);
/* 1 if vertex i belongs to at least one triangle. */
ISO_API int iso_mesh_vertex_used(const iso_mesh *m, int i);
/* Axis-aligned bounding-box diagonal of the referenced vertices. */
ISO_API double iso_mesh_bbox_diagonal(const iso_mesh *m);

/* A human-readable note about repairs made while loading (polygons
 * triangulated); "" when there were none. */
ISO_API const char *iso_mesh_note(const iso_mesh *m);

typedef enum iso_mesh_format {
    ISO_MESH_FMT_AUTO = 0, /* from the file name's extension */
    ISO_MESH_FMT_OFF,
    ISO_MESH_FMT_OBJ,
    ISO_MESH_FMT_PLY_ASCII,
    ISO_MESH_FMT_PLY_BINARY /* little endian */
} iso_mesh_format;

/* Loads OFF/OBJ/PLY by extension (case-insensitive); content decides ASCII
 * vs binary PLY. An unknown extension is ISO_ENOTSUP, an unreadable file
 * ISO_EIO, malformed content ISO_EPARSE (also for a header count larger than
 * the file can hold, and for content after the announced elements), a
 * non-convex polygon or an unusable mesh ISO_EMESH. */
ISO_API ISO_NODISCARD int iso_mesh_load(const char *path, iso_mesh **out, iso_err *err);

/* Writes m's triangles with positions `x` (3*nv; NULL = rest positions).
 * Coordinates are written with 17 significant digits in text formats, so a
 * save/load round trip is exact. All nv vertices are written, referenced or
 * not, so indices survive. ISO_MESH_FMT_AUTO with ".ply" writes binary
 * little endian. Non-finite positions are refused (ISO_EINVAL) rather than
 * written into a file that could not be read back. */
ISO_API ISO_NODISCARD int iso_mesh_save(const iso_mesh *m, const double *x, const char *path,
                                        iso_mesh_format fmt, iso_err *err);

#endif
