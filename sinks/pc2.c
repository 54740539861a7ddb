/* sinks/pc2.c -- PC2 point caches (see iso_pc2.h). */
#include "iso_outfile.h"
#include "iso_pc2.h"

#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct iso_pc2 {
    int fd, nv;
    long frames;
    unsigned char *buf; /* one frame, 12 * nv bytes */
    iso_outfile out;    /* where it goes (iso_outfile.h): a temporary name beside its path */
};

static void put_u32(unsigned char *d, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        d[i] = (unsigned char)(v >> (8 * i));
}

static void put_f32(unsigned char *d, double x)
{
    float f = (float)x;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    put_u32(d, u);
}

/* Writes all n bytes at offset off, or fails with errno set. */
static int pwrite_all(int fd, const void *p, size_t n, off_t off)
{
    const unsigned char *c = p;
    while (n > 0) {
        ssize_t w = pwrite(fd, c, n, off);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0) {
            if (w == 0)
                errno = ENOSPC;
            return -1;
        }
        c += w;
        n -= (size_t)w;
        off += w;
    }
    return 0;
}

int iso_pc2_create(const char *path, int nv, iso_pc2 **out, iso_err *err)
{
    *out = NULL;
    if (!path || nv < 1)
        return iso_err_set(err, ISO_EINVAL, -1, "PC2: no path, or %d vertices", nv);
    iso_pc2 *p = calloc(1, sizeof *p);
    unsigned char *buf = malloc((size_t)nv * 12);
    if (!p || !buf) {
        free(p);
        free(buf);
        return iso_err_set(err, ISO_ENOMEM, -1, "PC2: out of memory for %d vertices", nv);
    }
    p->nv = nv;
    p->buf = buf;
    p->fd = -1;
    int rc = iso_outfile_plan(&p->out, "PC2", path, ISO_OUTFILE_SEEKS, err);
    if (rc != ISO_OK) {
        iso_pc2_destroy(p);
        return rc;
    }
    p->fd = open(p->out.write, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    unsigned char h[ISO_PC2_HEADER];
    memset(h, 0, sizeof h);
    memcpy(h, "POINTCACHE2", 12); /* the terminating NUL included */
    put_u32(h + 12, 1);
    put_u32(h + 16, (uint32_t)nv);
    put_f32(h + 20, 0.0);
    put_f32(h + 24, 1.0);
    put_u32(h + 28, 0);
    if (p->fd < 0 || pwrite_all(p->fd, h, sizeof h, 0) != 0) {
        int e = errno;
        iso_pc2_destroy(p);
        return iso_err_set(err, ISO_EIO, -1, "PC2 %s: cannot write it: %s", path, strerror(e));
    }
    *out = p;
    return ISO_OK;
}

int iso_pc2_write(iso_pc2 *p, const double *x, iso_err *err)
{
    if (!p || !x)
        return iso_err_set(err, ISO_EINVAL, -1, "PC2: NULL cache or positions");
    for (int i = 0; i < 3 * p->nv; i++)
        put_f32(p->buf + 4 * i, x[i]);
    size_t fb = (size_t)p->nv * 12;
    unsigned char n[4];
    put_u32(n, (uint32_t)(p->frames + 1));
    /* the frame whole first, then the count that includes it */
    if (pwrite_all(p->fd, p->buf, fb, (off_t)(ISO_PC2_HEADER + (size_t)p->frames * fb)) != 0 ||
        pwrite_all(p->fd, n, 4, 28) != 0)
        return iso_err_set(err, ISO_EIO, -1, "PC2 %s: frame %ld: %s", p->out.write, p->frames,
                           strerror(errno));
    p->frames++;
    return ISO_OK;
}

long iso_pc2_frames(const iso_pc2 *p)
{
    return p ? p->frames : 0;
}

int iso_pc2_commit(iso_pc2 *p, iso_err *err)
{
    if (!p)
        return iso_err_set(err, ISO_EINVAL, -1, "PC2: NULL cache");
    int rc = ISO_OK;
    int fd = p->fd;
    p->fd = -1;
    if (close(fd) != 0)
        rc = iso_err_set(err, ISO_EIO, -1, "PC2 %s: %s", p->out.write, strerror(errno));
    else if (p->frames == 0)
        rc = iso_err_set(err, ISO_EINVAL, -1, "PC2 %s: no frame was written; not saved",
                         p->out.path);
    else
        rc = iso_outfile_commit(&p->out, "PC2", err);
    iso_outfile_abort(&p->out); /* nothing after a commit */
    free(p->buf);
    free(p);
    return rc;
}

void iso_pc2_destroy(iso_pc2 *p)
{
    if (!p)
        return;
    if (p->fd >= 0)
        close(p->fd);
    iso_outfile_abort(&p->out);
    free(p->buf);
    free(p);
}

int iso_pc2_save_rest(const iso_mesh *m, const char *pc2_path, char *rest_path, size_t cap,
                      iso_err *err)
{
    const char *slash = strrchr(pc2_path, '/'), *dot = strrchr(pc2_path, '.');
    if (!dot || (slash && dot < slash))
        dot = pc2_path + strlen(pc2_path);
    snprintf(rest_path, cap, "%.*s.rest.ply", (int)(dot - pc2_path), pc2_path);
    iso_outfile o;
    int rc = iso_outfile_plan(&o, "PC2's rest mesh", rest_path, ISO_OUTFILE_SEQUENTIAL, err);
    if (rc == ISO_OK)
        rc = iso_mesh_save(m, iso_mesh_positions(m), o.write, ISO_MESH_FMT_PLY_BINARY, err);
    if (rc == ISO_OK)
        rc = iso_outfile_commit(&o, "PC2's rest mesh", err);
    iso_outfile_abort(&o);
    return rc;
}
