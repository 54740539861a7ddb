/* mesh/mesh_io.c -- iso_mesh_load/iso_mesh_save, and what the per-format
 * readers share: the polygon builder (with convex-fan triangulation) and the
 * text scanner. Format specifics live in mesh_io_off.c, mesh_io_obj.c and
 * mesh_io_ply.c. */
#include "iso_file.h"
#include "iso_mesh.h"
#include "mesh_io_internal.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ==== messages =========================================================== */

const char *iso_mesh__where(char *buf, size_t cap, const iso_mesh__builder *b, long src)
{
    if (src < 0)
        snprintf(buf, cap, "%s", b->name);
    else
        snprintf(buf, cap, "%s, %s %ld", b->name, b->src_is_offset ? "byte offset" : "line", src);
    return buf;
}

const char *iso_mesh__quote(char *buf, size_t cap, const char *tok, size_t n)
{
    size_t o = 0, max = 24;
    for (size_t i = 0; i < n && i < max && o + 5 < cap; i++) {
        unsigned char c = (unsigned char)tok[i];
        buf[o++] = isprint(c) ? (char)c : '?';
    }
    if (n > max && o + 4 < cap) {
        memcpy(buf + o, "...", 3);
        o += 3;
    }
    buf[o] = '\0';
    return buf;
}

/* ==== builder ============================================================ */

void iso_mesh__builder_init(iso_mesh__builder *b, const char *name, int src_is_offset,
                            int index_base)
{
    memset(b, 0, sizeof *b);
    b->name = name;
    b->src_is_offset = src_is_offset;
    b->index_base = index_base;
}

void iso_mesh__builder_deinit(iso_mesh__builder *b)
{
    free(b->x);
    free(b->idx);
    free(b->start);
    free(b->src);
    memset(b, 0, sizeof *b);
}

/* Grows *p (elements of `size` bytes) to hold at least `need`. Doubling keeps
 * appends amortised O(1); nothing is allocated ahead of the data read, so a
 * bogus header count cannot make us allocate much. */
static int grow(void **p, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return 0;
    size_t n = *cap ? *cap : 64;
    while (n < need) {
        if (n > SIZE_MAX / 2 / size)
            return -1;
        n *= 2;
    }
    void *q = realloc(*p, n * size);
    if (!q)
        return -1;
    *p = q;
    *cap = n;
    return 0;
}

static int no_memory(const iso_mesh__builder *b, iso_err *err)
{
    return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory while reading the mesh", b->name);
}

int iso_mesh__add_vertex(iso_mesh__builder *b, const double p[3], long src, iso_err *err)
{
    char loc[320];
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return iso_err_set(err, ISO_EPARSE, src,
                           "%s: vertex %zu has a non-finite coordinate "
                           "(%g, %g, %g)",
                           iso_mesh__where(loc, sizeof loc, b, src), b->nv, p[0], p[1], p[2]);
    if (b->nv >= (size_t)(INT_MAX / 3))
        return iso_err_set(err, ISO_EPARSE, src, "%s: too many vertices (at most %d)",
                           iso_mesh__where(loc, sizeof loc, b, src), INT_MAX / 3);
    void *x = b->x;
    size_t cap = b->cap_v;
    if (grow(&x, &cap, 3 * (b->nv + 1), sizeof *b->x))
        return no_memory(b, err);
    b->x = x;
    b->cap_v = cap;
    memcpy(b->x + 3 * b->nv, p, 3 * sizeof *p);
    b->nv++;
    return ISO_OK;
}

int iso_mesh__face_begin(iso_mesh__builder *b, long src, iso_err *err)
{
    void *p;
    size_t cap;
    if (b->nface >= (size_t)(INT_MAX / 3)) {
        char loc[320];
        return iso_err_set(err, ISO_EPARSE, src, "%s: too many faces (at most %d)",
                           iso_mesh__where(loc, sizeof loc, b, src), INT_MAX / 3);
    }
    p = b->start, cap = b->cap_face;
    if (grow(&p, &cap, b->nface + 2, sizeof *b->start))
        return no_memory(b, err);
    b->start = p;
    p = b->src;
    if (grow(&p, &b->cap_face, b->nface + 2, sizeof *b->src))
        return no_memory(b, err);
    b->src = p;
    b->start[b->nface] = b->nidx;
    b->src[b->nface] = src;
    b->open = 1;
    return ISO_OK;
}

int iso_mesh__face_index(iso_mesh__builder *b, long i, iso_err *err)
{
    void *p = b->idx;
    if (grow(&p, &b->cap_idx, b->nidx + 1, sizeof *b->idx))
        return no_memory(b, err);
    b->idx = p;
    b->idx[b->nidx++] = i;
    return ISO_OK;
}

int iso_mesh__face_end(iso_mesh__builder *b, iso_err *err)
{
    size_t k = b->nidx - b->start[b->nface];
    b->open = 0;
    if (k < 3) {
        char loc[320];
        long src = b->src[b->nface];
        return iso_err_set(err, ISO_EPARSE, src,
                           "%s: face %zu has %zu vertices; a face needs at least 3",
                           iso_mesh__where(loc, sizeof loc, b, src), b->nface, k);
    }
    b->nface++;
    b->start[b->nface] = b->nidx;
    return ISO_OK;
}

/* ---- triangulation ------------------------------------------------------- */

/* Is the polygon convex in its best-fit plane? The plane's normal is
 * Newell's (robust for slightly non-planar polygons, and it follows the
 * winding), every turn must be to the left about it, and the turns must sum
 * to one full revolution, which also refuses self-intersecting stars whose
 * turns are all left. Returns 1 if convex; *reflex gets the first corner
 * that is not. */
static int polygon_is_convex(const double *x, const long *v, size_t k, size_t *reflex)
{
    const double *o = x + 3 * v[0];
    double n[3] = {0, 0, 0};
    for (size_t i = 0; i < k; i++) {
        const double *a = x + 3 * v[i], *c = x + 3 * v[(i + 1) % k];
        double ay = a[1] - o[1], az = a[2] - o[2], ax = a[0] - o[0];
        double cy = c[1] - o[1], cz = c[2] - o[2], cx = c[0] - o[0];
        n[0] += (ay - cy) * (az + cz);
        n[1] += (az - cz) * (ax + cx);
        n[2] += (ax - cx) * (ay + cy);
    }
    double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    *reflex = 0;
    if (!(nn > 0) || !isfinite(nn))
        return 0;
    for (int c = 0; c < 3; c++)
        n[c] /= nn;
    /* u: any unit vector perpendicular to n; w = n x u. */
    double u[3];
    if (fabs(n[0]) < 0.9)
        u[0] = 0, u[1] = n[2], u[2] = -n[1];
    else
        u[0] = -n[2], u[1] = 0, u[2] = n[0];
    double un = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int c = 0; c < 3; c++)
        u[c] /= un;
    double w[3] = {n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]};
    double total = 0;
    for (size_t i = 0; i < k; i++) {
        const double *a = x + 3 * v[(i + k - 1) % k], *p = x + 3 * v[i],
                     *c = x + 3 * v[(i + 1) % k];
        double e1[3], e2[3];
        for (int d = 0; d < 3; d++)
            e1[d] = p[d] - a[d], e2[d] = c[d] - p[d];
        double e1u = e1[0] * u[0] + e1[1] * u[1] + e1[2] * u[2];
        double e1w = e1[0] * w[0] + e1[1] * w[1] + e1[2] * w[2];
        double e2u = e2[0] * u[0] + e2[1] * u[1] + e2[2] * u[2];
        double e2w = e2[0] * w[0] + e2[1] * w[1] + e2[2] * w[2];
        double cr = e1u * e2w - e1w * e2u, dt = e1u * e2u + e1w * e2w;
        double scale = sqrt((e1u * e1u + e1w * e1w) * (e2u * e2u + e2w * e2w));
        if (cr < -1e-12 * scale) {
            *reflex = i;
            return 0;
        }
        total += atan2(cr, dt);
    }
    return fabs(total - 6.283185307179586) < 1e-6;
}

static void make_note(char *buf, size_t cap, const char *name, size_t npoly, size_t nquad)
{
    if (npoly == 0)
        buf[0] = '\0';
    else if (npoly == nquad)
        snprintf(buf, cap, "%s: triangulated %zu convex polygons (quads: %zu)", name, npoly, nquad);
    else
        snprintf(buf, cap,
                 "%s: triangulated %zu convex polygons (quads: %zu, 5 or more "
                 "vertices: %zu)",
                 name, npoly, nquad, npoly - nquad);
}

int iso_mesh__builder_finish(iso_mesh__builder *b, iso_mesh **out, iso_err *err)
{
    char loc[320];
    *out = NULL;
    /* Range first: triangulation needs valid positions. */
    for (size_t f = 0; f < b->nface; f++)
        for (size_t c = b->start[f]; c < b->start[f + 1]; c++)
            if (b->idx[c] < 0 || (size_t)b->idx[c] >= b->nv)
                return iso_err_set(err, ISO_EPARSE, b->src[f],
                                   "%s: face %zu has vertex index %ld out of range (the file "
                                   "has nv = %zu vertices, valid %d..%ld)",
                                   iso_mesh__where(loc, sizeof loc, b, b->src[f]), f,
                                   b->idx[c] + b->index_base, b->nv, b->index_base,
                                   (long)b->nv - 1 + b->index_base);
    size_t nt = 0, npoly = 0, nquad = 0;
    for (size_t f = 0; f < b->nface; f++) {
        size_t k = b->start[f + 1] - b->start[f];
        nt += k - 2;
        if (k > 3) {
            size_t reflex;
            npoly++;
            nquad += k == 4;
            if (!polygon_is_convex(b->x, b->idx + b->start[f], k, &reflex))
                return iso_err_set(err, ISO_EMESH, b->src[f],
                                   "%s: face %zu is a non-convex or degenerate polygon with %zu "
                                   "vertices (first bad corner: %zu, vertex %ld); only convex "
                                   "polygons are triangulated",
                                   iso_mesh__where(loc, sizeof loc, b, b->src[f]), f, k, reflex,
                                   b->idx[b->start[f] + reflex] + b->index_base);
        }
    }
    if (nt > (size_t)(INT_MAX / 3))
        return iso_err_set(err, ISO_EPARSE, -1, "%s: too many triangles (%zu)", b->name, nt);
    int *tri = malloc((nt ? nt : 1) * 3 * sizeof *tri);
    long *src = malloc((nt ? nt : 1) * sizeof *src);
    if (!tri || !src) {
        free(tri);
        free(src);
        return no_memory(b, err);
    }
    size_t t = 0;
    for (size_t f = 0; f < b->nface; f++) {
        const long *v = b->idx + b->start[f];
        size_t k = b->start[f + 1] - b->start[f];
        for (size_t i = 1; i + 1 < k; i++, t++) {
            tri[3 * t] = (int)v[0];
            tri[3 * t + 1] = (int)v[i];
            tri[3 * t + 2] = (int)v[i + 1];
            src[t] = b->src[f];
        }
    }
    int rc = iso_mesh_create_src((int)b->nv, b->x, (int)nt, tri, b->name, src, b->src_is_offset,
                                 out, err);
    free(tri);
    free(src);
    if (rc != ISO_OK)
        return rc;
    char note[512];
    make_note(note, sizeof note, b->name, npoly, nquad);
    if (iso_mesh__set_note(*out, note) != ISO_OK) {
        iso_mesh_destroy(*out);
        *out = NULL;
        return no_memory(b, err);
    }
    return ISO_OK;
}

/* ==== text scanning ====================================================== */

static int is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

void iso_mesh__text_init(iso_mesh__text *t, const char *data, size_t len)
{
    t->p = data;
    t->end = data + len;
    t->line = 0;
}

int iso_mesh__text_line(iso_mesh__text *t, int hash_comments, const char **b, const char **e)
{
    while (t->p < t->end) {
        const char *s = t->p;
        const char *nl = memchr(s, '\n', (size_t)(t->end - s));
        const char *le = nl ? nl : t->end;
        t->p = nl ? nl + 1 : t->end;
        t->line++;
        if (hash_comments) {
            const char *h = memchr(s, '#', (size_t)(le - s));
            if (h)
                le = h;
        }
        const char *q = s;
        while (q < le && is_space(*q))
            q++;
        if (q < le) {
            *b = q;
            *e = le;
            return 1;
        }
    }
    return 0;
}

int iso_mesh__token(const char **p, const char *e, const char **tok, size_t *n)
{
    const char *q = *p;
    while (q < e && is_space(*q))
        q++;
    if (q == e) {
        *p = q;
        return 0;
    }
    const char *s = q;
    while (q < e && !is_space(*q))
        q++;
    *tok = s;
    *n = (size_t)(q - s);
    *p = q;
    return 1;
}

/* Copies a token into a NUL-terminated buffer for strtod/strtol; a token too
 * long for any number is refused outright. */
static int token_cstr(const char *tok, size_t n, char buf[80])
{
    if (n == 0 || n >= 80)
        return -1;
    memcpy(buf, tok, n);
    buf[n] = '\0';
    return memchr(buf, '\0', n) ? -1 : 0;
}

int iso_mesh__to_double(const char *tok, size_t n, double *v)
{
    char buf[80], *end;
    if (token_cstr(tok, n, buf))
        return -1;
    errno = 0;
    *v = strtod(buf, &end);
    /* ERANGE on underflow still gives a usable tiny value; overflow gives
     * inf, which the vertex check reports. */
    return end == buf + n ? 0 : -1;
}

int iso_mesh__to_long(const char *tok, size_t n, long *v)
{
    char buf[80], *end;
    if (token_cstr(tok, n, buf))
        return -1;
    size_t i = buf[0] == '-' || buf[0] == '+';
    if (!isdigit((unsigned char)buf[i]))
        return -1;
    errno = 0;
    *v = strtol(buf, &end, 10);
    return end == buf + n && errno == 0 ? 0 : -1;
}

/* ==== load =============================================================== */

static const char *extension(const char *name)
{
    const char *slash = strrchr(name, '/');
    const char *dot = strrchr(name, '.');
    return dot && (!slash || dot > slash) ? dot + 1 : "";
}

int iso_mesh__load_buffer(const char *name, const unsigned char *data, size_t len, iso_mesh **out,
                          iso_err *err)
{
    if (!out)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_mesh_load: out is NULL");
    *out = NULL;
    if (!name || (!data && len))
        return iso_err_set(err, ISO_EINVAL, -1, "iso_mesh_load: NULL name or data");
    const char *ext = extension(name);
    iso_mesh__builder b;
    int rc;
    if (strcasecmp(ext, "off") == 0) {
        iso_mesh__builder_init(&b, name, 0, 0);
        rc = iso_mesh__read_off(&b, (const char *)data, len, err);
    } else if (strcasecmp(ext, "obj") == 0) {
        iso_mesh__builder_init(&b, name, 0, 1);
        rc = iso_mesh__read_obj(&b, (const char *)data, len, err);
    } else if (strcasecmp(ext, "ply") == 0) {
        iso_mesh__builder_init(&b, name, 0, 0);
        rc = iso_mesh__read_ply(&b, data, len, err);
    } else {
        return iso_err_set(err, ISO_ENOTSUP, -1,
                           "%s: unknown mesh file extension '.%s' (expected .off, .obj or .ply)",
                           name, ext);
    }
    if (rc == ISO_OK)
        rc = iso_mesh__builder_finish(&b, out, err);
    iso_mesh__builder_deinit(&b);
    return rc;
}

int iso_mesh_load(const char *path, iso_mesh **out, iso_err *err)
{
    if (!out)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_mesh_load: out is NULL");
    *out = NULL;
    if (!path)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_mesh_load: path is NULL");
    const char *ext = extension(path);
    if (strcasecmp(ext, "off") && strcasecmp(ext, "obj") && strcasecmp(ext, "ply"))
        return iso_err_set(err, ISO_ENOTSUP, -1,
                           "%s: unknown mesh file extension '.%s' (expected .off, .obj or .ply)",
                           path, ext);
    char *data;
    size_t len;
    int rc = iso_file_read(path, 0, &data, &len, err);
    if (rc == ISO_OK)
        rc = iso_mesh__load_buffer(path, (const unsigned char *)data, len, out, err);
    free(data);
    return rc;
}

/* ==== save =============================================================== */

static void put_le32(FILE *f, uint32_t v)
{
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16),
                          (unsigned char)(v >> 24)};
    fwrite(b, 1, 4, f);
}

static void put_le_double(FILE *f, double d)
{
    uint64_t u;
    unsigned char b[8];
    memcpy(&u, &d, sizeof u);
    for (int i = 0; i < 8; i++)
        b[i] = (unsigned char)(u >> (8 * i));
    fwrite(b, 1, 8, f);
}

static void write_ply_header(FILE *f, int binary, int nv, int nt)
{
    fprintf(f, "ply\nformat %s 1.0\ncomment written by isoshape\n",
            binary ? "binary_little_endian" : "ascii");
    fprintf(f, "element vertex %d\nproperty double x\nproperty double y\nproperty double z\n", nv);
    fprintf(f, "element face %d\nproperty list uchar int vertex_indices\nend_header\n", nt);
}

static void write_mesh(FILE *f, iso_mesh_format fmt, int nv, const double *x, int nt, const int *t)
{
    switch (fmt) {
    case ISO_MESH_FMT_OFF:
        fprintf(f, "OFF\n%d %d 0\n", nv, nt);
        for (int i = 0; i < nv; i++)
            fprintf(f, "%.17g %.17g %.17g\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        for (int i = 0; i < nt; i++)
            fprintf(f, "3 %d %d %d\n", t[3 * i], t[3 * i + 1], t[3 * i + 2]);
        break;
    case ISO_MESH_FMT_OBJ:
        for (int i = 0; i < nv; i++)
            fprintf(f, "v %.17g %.17g %.17g\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        for (int i = 0; i < nt; i++)
            fprintf(f, "f %d %d %d\n", t[3 * i] + 1, t[3 * i + 1] + 1, t[3 * i + 2] + 1);
        break;
    case ISO_MESH_FMT_PLY_ASCII:
        write_ply_header(f, 0, nv, nt);
        for (int i = 0; i < nv; i++)
            fprintf(f, "%.17g %.17g %.17g\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        for (int i = 0; i < nt; i++)
            fprintf(f, "3 %d %d %d\n", t[3 * i], t[3 * i + 1], t[3 * i + 2]);
        break;
    default:
        write_ply_header(f, 1, nv, nt);
        for (int i = 0; i < 3 * nv; i++)
            put_le_double(f, x[i]);
        for (int i = 0; i < nt; i++) {
            fputc(3, f);
            for (int k = 0; k < 3; k++)
                put_le32(f, (uint32_t)t[3 * i + k]);
        }
        break;
    }
}

int iso_mesh_save(const iso_mesh *m, const double *x, const char *path, iso_mesh_format fmt,
                  iso_err *err)
{
    if (!m || !path)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_mesh_save: NULL mesh or path");
    if (fmt == ISO_MESH_FMT_AUTO) {
        const char *ext = extension(path);
        if (strcasecmp(ext, "off") == 0)
            fmt = ISO_MESH_FMT_OFF;
        else if (strcasecmp(ext, "obj") == 0)
            fmt = ISO_MESH_FMT_OBJ;
        else if (strcasecmp(ext, "ply") == 0)
            fmt = ISO_MESH_FMT_PLY_BINARY;
        else
            return iso_err_set(err, ISO_ENOTSUP, -1,
                               "%s: unknown mesh file extension '.%s' (expected .off, .obj or "
                               ".ply)",
                               path, ext);
    } else if (fmt < ISO_MESH_FMT_OFF || fmt > ISO_MESH_FMT_PLY_BINARY) {
        return iso_err_set(err, ISO_EINVAL, -1, "%s: unknown mesh format %d", path, (int)fmt);
    }
    int nv = iso_mesh_vertex_count(m), nt = iso_mesh_triangle_count(m);
    if (!x)
        x = iso_mesh_positions(m);
    /* A file we could not load back is worse than no file. */
    for (int i = 0; i < 3 * nv; i++)
        if (!isfinite(x[i]))
            return iso_err_set(err, ISO_EINVAL, -1,
                               "%s: not written: vertex %d has a non-finite coordinate", path,
                               i / 3);
    FILE *f = fopen(path, "wb");
    if (!f)
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot open for writing: %s", path,
                           strerror(errno));
    write_mesh(f, fmt, nv, x, nt, iso_mesh_triangles(m));
    int bad = ferror(f);
    int saved = errno;
    if (fclose(f) != 0 && !bad) {
        bad = 1;
        saved = errno;
    }
    if (bad)
        return iso_err_set(err, ISO_EIO, -1, "%s: write failed: %s", path, strerror(saved));
    return ISO_OK;
}
