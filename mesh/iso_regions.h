/* mesh/iso_regions.h -- which vertices are fixed, free or on a handle, and
 * the benchmark's region (.sel) and handle-transform (.def) files.
 *
 * iso_regions is a caller-owned struct (init/deinit): one kind per vertex and,
 * for handle vertices, the handle it belongs to. A .sel file puts all its
 * handle vertices on handle 0. */
#ifndef ISO_REGIONS_H
#define ISO_REGIONS_H

#include "iso_err.h"

enum { ISO_FIXED = 0, ISO_FREE = 1, ISO_HANDLE = 2 };

typedef struct iso_regions {
    int nv;
    unsigned char *kind; /* nv entries: ISO_FIXED, ISO_FREE or ISO_HANDLE */
    int *handle;         /* nv entries: handle index for ISO_HANDLE, else -1 */
    int n_handles;
} iso_regions;

/* Allocates for nv vertices, all ISO_FREE. */
ISO_API ISO_NODISCARD int iso_regions_init(iso_regions *r, int nv, iso_err *err);
ISO_API void iso_regions_deinit(iso_regions *r); /* zeroed or deinited struct is fine */

/* Reads a .sel file: '#' comments, then exactly nv integers in {0,1,2}
 * (whitespace separated). Errors name the file, line, and what is wrong: a
 * count different from nv, a value outside {0,1,2}, a non-integer token.
 * Initialises r itself (do not pass an initialised struct: it would leak);
 * on success the caller deinits it, on failure it is left zeroed. Bad
 * content is ISO_EPARSE, an unreadable file ISO_EIO. */
ISO_API ISO_NODISCARD int iso_sel_load(const char *path, int nv, iso_regions *r, iso_err *err);

/* Largest deviation |RᵀR − I| (max abs entry) and |det R − 1| accepted for a
 * .def rotation. The benchmark files print 6 decimals, so their rotations are
 * orthonormal to about 1e-6; 1e-4 accepts them and refuses any real shear
 * or scale (1e-4 is a 0.01% stretch). */
#define ISO_DEF_RIGID_TOL 1e-4

/* Reads a .def file: '#' comments, then 16 numbers, a row-major 4x4 matrix M
 * with x' = M [x;1]. Refuses: a wrong count, non-finite values, a last row
 * other than (0 0 0 1), and a matrix whose 3x3 part is not a rotation within
 * ISO_DEF_RIGID_TOL (it names the deviation). All content errors are
 * ISO_EPARSE; M is written only on success. */
ISO_API ISO_NODISCARD int iso_def_load(const char *path, double M[16], iso_err *err);

#endif
