/* mesh/mesh_io_internal.h -- private cross-file symbols of the mesh module
 * (mesh.c, mesh_io.c and the per-format mesh_io_*.c readers); not installed,
 * not public API. The fuzz targets use iso_mesh__load_buffer(). */
#ifndef ISO_MESH_IO_INTERNAL_H
#define ISO_MESH_IO_INTERNAL_H

#include <stddef.h>

#include "iso_mesh.h"

/* Replaces m's note (copied). Returns ISO_OK or ISO_ENOMEM (note unchanged).
 * Only loaders call this, right after creating m. */
int iso_mesh__set_note(iso_mesh *m, const char *note);

/* Loads a mesh from memory; `name` picks the format by extension exactly as
 * iso_mesh_load does and names the source in messages. data need not be
 * NUL-terminated; it is never read past len. */
ISO_NODISCARD int iso_mesh__load_buffer(const char *name, const unsigned char *data, size_t len,
                                        iso_mesh **out, iso_err *err);

/* ---- the builder every reader fills -------------------------------------
 * Vertices and polygons as read; polygons are range-checked, triangulated
 * (convex fans) and handed to iso_mesh_create_src by _finish. */
typedef struct iso_mesh__builder {
    const char *name;
    int src_is_offset; /* 1: src values are byte offsets, 0: lines */
    int index_base;    /* added to indices in messages (1 for OBJ) */
    double *x;
    size_t nv, cap_v;
    long *idx; /* polygon corners, 0-based, not yet range-checked */
    size_t nidx, cap_idx;
    size_t *start; /* nface + 1 entries into idx */
    long *src;     /* per face: line or byte offset */
    size_t nface, cap_face;
    int open; /* a face is between _face_begin and _face_end */
} iso_mesh__builder;

void iso_mesh__builder_init(iso_mesh__builder *b, const char *name, int src_is_offset,
                            int index_base);
void iso_mesh__builder_deinit(iso_mesh__builder *b);
/* Adds a vertex read at `src`; refuses non-finite coordinates (EPARSE). */
int iso_mesh__add_vertex(iso_mesh__builder *b, const double p[3], long src, iso_err *err);
int iso_mesh__face_begin(iso_mesh__builder *b, long src, iso_err *err);
int iso_mesh__face_index(iso_mesh__builder *b, long i, iso_err *err);
/* Closes the face; refuses one with fewer than 3 corners (EPARSE). */
int iso_mesh__face_end(iso_mesh__builder *b, iso_err *err);
ISO_NODISCARD int iso_mesh__builder_finish(iso_mesh__builder *b, iso_mesh **out, iso_err *err);

/* "name, line 12" or "name, byte offset 300" (src < 0: just the name). */
const char *iso_mesh__where(char *buf, size_t cap, const iso_mesh__builder *b, long src);
/* A token quoted for a message: at most 24 printable characters. */
const char *iso_mesh__quote(char *buf, size_t cap, const char *tok, size_t n);

/* ---- text scanning ------------------------------------------------------ */
typedef struct iso_mesh__text {
    const char *p, *end;
    long line; /* line number of the line last returned, 1-based */
} iso_mesh__text;

void iso_mesh__text_init(iso_mesh__text *t, const char *data, size_t len);
/* Next line that has a token, with '#' comments removed if hash_comments.
 * Returns 1 and its content in [*b, *e), or 0 at the end of the data. */
int iso_mesh__text_line(iso_mesh__text *t, int hash_comments, const char **b, const char **e);
/* Next whitespace-separated token of [*p, e); returns 1, or 0 if none. */
int iso_mesh__token(const char **p, const char *e, const char **tok, size_t *n);
/* Whole-token conversions; return 0 on success, -1 if the token is not a
 * number of that kind (or does not fit a long). */
int iso_mesh__to_double(const char *tok, size_t n, double *v);
int iso_mesh__to_long(const char *tok, size_t n, long *v);

/* ---- per-format readers (data is never read past len) -------------------- */
int iso_mesh__read_off(iso_mesh__builder *b, const char *data, size_t len, iso_err *err);
int iso_mesh__read_obj(iso_mesh__builder *b, const char *data, size_t len, iso_err *err);
int iso_mesh__read_ply(iso_mesh__builder *b, const unsigned char *data, size_t len, iso_err *err);

#endif
