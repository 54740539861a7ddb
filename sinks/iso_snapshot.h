/* sinks/iso_snapshot.h -- headless outputs for machines without a browser: a
 * PNG picture of the mesh and a PLY frame sequence.
 *
 * The PNG comes from a small software rasterizer (orthographic camera,
 * z-buffer, flat Lambert shading), coloured like the live view: each
 * triangle by its local metric distortion, the largest relative change of
 * its three edge lengths against the rest pose, on a blue - yellow - red
 * scale that saturates at ISO_SNAPSHOT_STRAIN_FULL; triangles touching a
 * handle vertex are tinted magenta, those touching a fixed vertex grey.
 *
 * The PLY frames are binary little-endian PLY files (iso_mesh_save), named
 * frame_<tick, 8 digits>.ply so that MeshLab, Blender and ParaView list and
 * open them in order. */
#ifndef ISO_SNAPSHOT_H
#define ISO_SNAPSHOT_H

#include <stddef.h>

#include "iso_err.h"
#include "iso_mesh.h"
#include "iso_regions.h"

/* Relative edge-length change at which the colour scale is fully red. */
#define ISO_SNAPSHOT_STRAIN_FULL 0.10

/* Background of the PNG (and the page), 8-bit sRGB. */
#define ISO_SNAPSHOT_BG_R 24
#define ISO_SNAPSHOT_BG_G 26
#define ISO_SNAPSHOT_BG_B 31

/* Camera: the mesh's bounding box is centred and fitted into the picture,
 * seen from direction (yaw about +z, then pitch above the xy plane), with
 * +z up on screen. */
typedef struct iso_snapshot_view {
    double yaw_deg;   /* default 30 */
    double pitch_deg; /* default 20 */
    double zoom;      /* 1 = bounding sphere just fits; default 1 */
} iso_snapshot_view;

/* Colour of a relative strain s >= 0 on the distortion scale, as 0..1 RGB.
 * The page uses the same scale. */
ISO_API void iso_snapshot_strain_color(double s, double rgb[3]);

/* Tints a triangle's colour rgb (in place) as the page and the picture do:
 * magenta when it touches a handle vertex, else grey when it touches a
 * fixed one, else unchanged. */
ISO_API void iso_snapshot_tint_color(int touches_handle, int touches_fixed, double rgb[3]);

/* Renders mesh m at positions x (3*nv; NULL = rest) to an RGB PNG of
 * width x height pixels at `path`. regions may be NULL (no tint), view may
 * be NULL (defaults). Errors: ISO_EINVAL (sizes outside 16..8192, NULL mesh,
 * regions of another size), ISO_ENOMEM, ISO_EIO (naming the path and
 * libpng's reason), ISO_ENOTSUP when built without libpng. */
ISO_API ISO_NODISCARD int iso_snapshot_png(const iso_mesh *m, const double *x,
                                           const iso_regions *regions, const char *path, int width,
                                           int height, const iso_snapshot_view *view, iso_err *err);

typedef struct iso_ply_frames iso_ply_frames; /* opaque */

/* Prepares to write every `every_n`-th tick of mesh m (which must outlive
 * the writer) into folder dir, creating dir (one level) if it is missing.
 * ISO_EINVAL for every_n < 1 or NULL arguments, ISO_EIO if dir cannot be
 * made or is not a folder. */
ISO_API ISO_NODISCARD int iso_ply_frames_create(const char *dir, const iso_mesh *m, int every_n,
                                                iso_ply_frames **out, iso_err *err);

/* Writes dir/frame_<tick>.ply with positions x if tick % every_n == 0 (else
 * does nothing and returns ISO_OK). Returns 1 when a file was written, 0 when
 * skipped, or the negative code from iso_mesh_save. ISO_EINVAL for a
 * negative tick. */
ISO_API int iso_ply_frames_write(iso_ply_frames *f, long tick, const double *x, iso_err *err);

/* The path the frame for `tick` has (or would have), into buf. */
ISO_API const char *iso_ply_frames_path(const iso_ply_frames *f, long tick, char *buf, size_t cap);

ISO_API void iso_ply_frames_destroy(iso_ply_frames *f); /* NULL is a no-op */

#endif
