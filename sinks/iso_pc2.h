/* sinks/iso_pc2.h -- PC2 point caches: every frame of a run's vertex
 * positions in one file that Blender's Mesh Cache modifier plays on the rest
 * mesh (same vertex count and order).
 *
 * The format (little endian throughout):
 *   offset  0  char[12] "POINTCACHE2\0"
 *          12  int32    version, 1
 *          16  int32    vertex count
 *          20  float32  start frame (0)
 *          24  float32  sampling, frames per cache frame (1)
 *          28  int32    frame count
 *          32  float32  frames: x y z per vertex, frame after frame
 * Positions are the run's doubles rounded to float32 (round to nearest).
 *
 * Crash safety: each frame is written whole, then the header's frame count
 * is rewritten to include it (both with pwrite, so they are in the kernel
 * when the call returns). A process killed at any moment leaves a file
 * whose header counts exactly the whole frames in it; the bytes of a frame
 * cut off by the kill lie past them and are ignored by a reader. Blender
 * refuses a frame count of 0, so the file is useful from its first frame.
 *
 * The file is written under a temporary name beside the final one
 * (iso_outfile.h) and renamed to it by iso_pc2_commit, so a finished run
 * replaces an older cache atomically and an unfinished one never
 * overwrites it; a FIFO or a device is refused, since the header is
 * rewritten. Not thread-safe: one thread writes a cache. */
#ifndef ISO_PC2_H
#define ISO_PC2_H

#include <stddef.h>

#include "iso_err.h"
#include "iso_mesh.h"

#define ISO_PC2_HEADER 32

typedef struct iso_pc2 iso_pc2; /* opaque */

/* Opens a cache of nv vertices (nv >= 1) to be committed at `path`: writes
 * the header with 0 frames under the temporary name. ISO_EINVAL for nv < 1
 * or a NULL path, ISO_EIO naming the file and the reason, ISO_ENOMEM. */
ISO_API ISO_NODISCARD int iso_pc2_create(const char *path, int nv, iso_pc2 **out, iso_err *err);

/* Appends one frame, x = 3*nv doubles, and counts it in the header. ISO_EIO
 * naming the file when the disk refuses it (the frames before stay whole
 * and counted). */
ISO_API ISO_NODISCARD int iso_pc2_write(iso_pc2 *p, const double *x, iso_err *err);

/* Frames written so far. */
ISO_API long iso_pc2_frames(const iso_pc2 *p);

/* Closes the cache and renames it to its final path; the handle is freed
 * whatever happens. A cache without frames is not committed (Blender could
 * not open it): the temporary file is removed and ISO_EINVAL says so. */
ISO_API ISO_NODISCARD int iso_pc2_commit(iso_pc2 *p, iso_err *err);

/* Saves the mesh a cache at `pc2_path` plays on: m's rest positions as a
 * binary PLY, vertex order unchanged, at "<pc2_path without its
 * extension>.rest.ply" (that path into rest_path, cap bytes), written under
 * a temporary name and renamed. Blender imports a PLY with its axes as they
 * are, as the Mesh Cache modifier reads the cache. ISO_EIO naming the file. */
ISO_API ISO_NODISCARD int iso_pc2_save_rest(const iso_mesh *m, const char *pc2_path,
                                            char *rest_path, size_t cap, iso_err *err);

/* Closes without committing: the temporary file stays, well formed, with
 * every frame written (what a stopped-by-error run leaves). NULL is a no-op. */
ISO_API void iso_pc2_destroy(iso_pc2 *p);

#endif
