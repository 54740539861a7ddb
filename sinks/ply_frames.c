/* sinks/ply_frames.c -- a PLY frame sequence (see iso_snapshot.h). */
#include "iso_snapshot.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

struct iso_ply_frames {
    const iso_mesh *mesh;
    int every_n;
    char dir[4096];
};

int iso_ply_frames_create(const char *dir, const iso_mesh *m, int every_n, iso_ply_frames **out,
                          iso_err *err)
{
    if (out)
        *out = NULL;
    if (!dir || !m || !out)
        return iso_err_set(err, ISO_EINVAL, -1, "PLY frames: NULL folder, mesh or out argument");
    if (every_n < 1)
        return iso_err_set(err, ISO_EINVAL, -1, "PLY frames: every_n must be >= 1, got %d",
                           every_n);
    if (strlen(dir) + 32 > sizeof((iso_ply_frames *)0)->dir)
        return iso_err_set(err, ISO_EINVAL, -1, "PLY frames: folder name too long: %.64s...", dir);
    if (mkdir(dir, 0777) != 0 && errno != EEXIST)
        return iso_err_set(err, ISO_EIO, -1, "PLY frames: cannot make folder %s: %s", dir,
                           strerror(errno));
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return iso_err_set(err, ISO_EIO, -1, "PLY frames: %s is not a folder", dir);
    iso_ply_frames *f = calloc(1, sizeof *f);
    if (!f)
        return iso_err_set(err, ISO_ENOMEM, -1, "PLY frames: out of memory");
    f->mesh = m;
    f->every_n = every_n;
    snprintf(f->dir, sizeof f->dir, "%s", dir);
    *out = f;
    return ISO_OK;
}

const char *iso_ply_frames_path(const iso_ply_frames *f, long tick, char *buf, size_t cap)
{
    snprintf(buf, cap, "%s/frame_%08ld.ply", f->dir, tick);
    return buf;
}

int iso_ply_frames_write(iso_ply_frames *f, long tick, const double *x, iso_err *err)
{
    if (!f || !x)
        return iso_err_set(err, ISO_EINVAL, -1, "PLY frames: NULL writer or positions");
    if (tick < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "PLY frames: negative tick %ld", tick);
    if (tick % f->every_n != 0)
        return 0;
    char path[4200];
    iso_ply_frames_path(f, tick, path, sizeof path);
    int rc = iso_mesh_save(f->mesh, x, path, ISO_MESH_FMT_PLY_BINARY, err);
    return rc < 0 ? rc : 1;
}

void iso_ply_frames_destroy(iso_ply_frames *f)
{
    free(f);
}
