/* sinks/snapshot.c -- a software-rendered PNG of the mesh (see iso_snapshot.h).
 *
 * Small on purpose: an orthographic camera, one z-buffer, flat Lambert
 * shading with a light near the eye, and the same distortion colours as the
 * live page, so a picture from a headless run reads like the browser view. */
#include "iso_snapshot.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifdef ISO_WITH_LIBPNG
#include <png.h>
#endif

/* ---- colours ------------------------------------------------------------ */

void iso_snapshot_strain_color(double s, double rgb[3])
{
    static const double stops[3][3] = {{0.23, 0.49, 0.85}, {0.96, 0.84, 0.26}, {0.86, 0.16, 0.12}};
    double t = s / ISO_SNAPSHOT_STRAIN_FULL;
    if (!(t > 0)) /* also NaN */
        t = 0;
    if (t > 1)
        t = 1;
    int k = t < 0.5 ? 0 : 1;
    double u = t < 0.5 ? t * 2 : (t - 0.5) * 2;
    for (int c = 0; c < 3; c++)
        rgb[c] = stops[k][c] + (stops[k + 1][c] - stops[k][c]) * u;
}

static double edge_len(const double *x, int i, int j)
{
    double dx = x[3 * i] - x[3 * j], dy = x[3 * i + 1] - x[3 * j + 1],
           dz = x[3 * i + 2] - x[3 * j + 2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* The largest relative change of a triangle's three edge lengths: the local
 * metric distortion the page and the picture colour by. */
static double triangle_strain(const double *x0, const double *x, const int *t)
{
    double worst = 0;
    for (int k = 0; k < 3; k++) {
        int i = t[k], j = t[(k + 1) % 3];
        double l0 = edge_len(x0, i, j), l = edge_len(x, i, j);
        double s = l0 > 0 ? fabs(l - l0) / l0 : 0;
        if (s > worst)
            worst = s;
    }
    return worst;
}

static void triangle_color(const iso_mesh *m, const double *x, const iso_regions *r, int t,
                           double rgb[3])
{
    const int *tri = iso_mesh_triangles(m) + 3 * t;
    iso_snapshot_strain_color(triangle_strain(iso_mesh_positions(m), x, tri), rgb);
    if (!r)
        return;
    int handle = 0, fixed = 0;
    for (int k = 0; k < 3; k++) {
        handle |= r->kind[tri[k]] == ISO_HANDLE;
        fixed |= r->kind[tri[k]] == ISO_FIXED;
    }
    iso_snapshot_tint_color(handle, fixed, rgb);
}

void iso_snapshot_tint_color(int touches_handle, int touches_fixed, double rgb[3])
{
    static const double magenta[3] = {0.90, 0.25, 0.90}, grey[3] = {0.45, 0.47, 0.52};
    const double *tint = touches_handle ? magenta : touches_fixed ? grey : NULL;
    double a = touches_handle ? 0.5 : 0.55;
    if (tint)
        for (int c = 0; c < 3; c++)
            rgb[c] = rgb[c] * (1 - a) + tint[c] * a;
}

/* ---- camera and rasterizer ---------------------------------------------- */

typedef struct camera {
    double c[3], right[3], up[3], eye[3], light[3];
    double scale, cx, cy;
} camera;

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void camera_fit(camera *cam, const iso_mesh *m, const double *x, int w, int h,
                       const iso_snapshot_view *view)
{
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    int nv = iso_mesh_vertex_count(m);
    for (int i = 0; i < nv; i++) {
        if (!iso_mesh_vertex_used(m, i))
            continue;
        for (int c = 0; c < 3; c++) {
            double v = x[3 * i + c];
            if (isfinite(v)) {
                lo[c] = v < lo[c] ? v : lo[c];
                hi[c] = v > hi[c] ? v : hi[c];
            }
        }
    }
    double r2 = 0;
    for (int c = 0; c < 3; c++) {
        if (!(lo[c] <= hi[c]))
            lo[c] = hi[c] = 0;
        cam->c[c] = 0.5 * (lo[c] + hi[c]);
        r2 += 0.25 * (hi[c] - lo[c]) * (hi[c] - lo[c]);
    }
    double r = r2 > 0 ? sqrt(r2) : 1;
    double yaw = (view ? view->yaw_deg : 30) * 3.14159265358979323846 / 180;
    double pitch = (view ? view->pitch_deg : 20) * 3.14159265358979323846 / 180;
    double zoom = view && view->zoom > 0 ? view->zoom : 1;
    double e[3] = {cos(pitch) * cos(yaw), cos(pitch) * sin(yaw), sin(pitch)};
    double rt[3] = {-sin(yaw), cos(yaw), 0};
    memcpy(cam->eye, e, sizeof e);
    memcpy(cam->right, rt, sizeof rt);
    cam->up[0] = e[1] * rt[2] - e[2] * rt[1];
    cam->up[1] = e[2] * rt[0] - e[0] * rt[2];
    cam->up[2] = e[0] * rt[1] - e[1] * rt[0];
    double l[3], ll = 0;
    for (int c = 0; c < 3; c++) {
        l[c] = e[c] + 0.5 * cam->up[c] + 0.3 * rt[c];
        ll += l[c] * l[c];
    }
    for (int c = 0; c < 3; c++)
        cam->light[c] = l[c] / sqrt(ll);
    cam->scale = zoom * 0.95 * 0.5 * (w < h ? w : h) / r;
    cam->cx = 0.5 * w;
    cam->cy = 0.5 * h;
}

/* Screen position (pixels) and depth (larger is nearer) of point p. */
static void project(const camera *cam, const double *p, double out[3])
{
    double d[3] = {p[0] - cam->c[0], p[1] - cam->c[1], p[2] - cam->c[2]};
    out[0] = cam->cx + dot3(d, cam->right) * cam->scale;
    out[1] = cam->cy - dot3(d, cam->up) * cam->scale;
    out[2] = dot3(d, cam->eye);
}

static void raster_triangle(unsigned char *img, float *zbuf, int w, int h, const double a[3],
                            const double b[3], const double c[3], const unsigned char rgb[3])
{
    double area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if (!(fabs(area) > 1e-12))
        return;
    double fx0 = fmin(a[0], fmin(b[0], c[0])), fx1 = fmax(a[0], fmax(b[0], c[0]));
    double fy0 = fmin(a[1], fmin(b[1], c[1])), fy1 = fmax(a[1], fmax(b[1], c[1]));
    if (!(fx1 >= 0 && fy1 >= 0 && fx0 < w && fy0 < h))
        return; /* off screen, or NaN */
    int x0 = fx0 < 0 ? 0 : (int)fx0, x1 = fx1 > w - 1 ? w - 1 : (int)fx1;
    int y0 = fy0 < 0 ? 0 : (int)fy0, y1 = fy1 > h - 1 ? h - 1 : (int)fy1;
    for (int y = y0; y <= y1; y++) {
        double py = y + 0.5;
        for (int x = x0; x <= x1; x++) {
            double px = x + 0.5;
            double w0 = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) / area;
            double w1 = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) / area;
            double w2 = 1 - w0 - w1;
            if (w0 < 0 || w1 < 0 || w2 < 0)
                continue;
            float z = (float)(w0 * a[2] + w1 * b[2] + w2 * c[2]);
            size_t k = (size_t)y * (size_t)w + (size_t)x;
            if (z <= zbuf[k])
                continue;
            zbuf[k] = z;
            memcpy(img + 3 * k, rgb, 3);
        }
    }
}

static void render(unsigned char *img, float *zbuf, int w, int h, const iso_mesh *m,
                   const double *x, const iso_regions *r, const iso_snapshot_view *view)
{
    for (size_t k = 0; k < (size_t)w * (size_t)h; k++) {
        img[3 * k] = ISO_SNAPSHOT_BG_R;
        img[3 * k + 1] = ISO_SNAPSHOT_BG_G;
        img[3 * k + 2] = ISO_SNAPSHOT_BG_B;
        zbuf[k] = -HUGE_VALF;
    }
    camera cam;
    camera_fit(&cam, m, x, w, h, view);
    const int *tri = iso_mesh_triangles(m);
    int nt = iso_mesh_triangle_count(m);
    for (int t = 0; t < nt; t++) {
        const double *p[3] = {x + 3 * tri[3 * t], x + 3 * tri[3 * t + 1], x + 3 * tri[3 * t + 2]};
        double s[3][3];
        for (int k = 0; k < 3; k++)
            project(&cam, p[k], s[k]);
        double u[3], v[3], n[3];
        for (int c = 0; c < 3; c++) {
            u[c] = p[1][c] - p[0][c];
            v[c] = p[2][c] - p[0][c];
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        double nn = sqrt(dot3(n, n));
        double lambert = nn > 0 ? fabs(dot3(n, cam.light)) / nn : 0; /* two-sided */
        double shade = 0.3 + 0.7 * lambert;
        double col[3];
        triangle_color(m, x, r, t, col);
        unsigned char rgb[3];
        for (int c = 0; c < 3; c++) {
            double v8 = 255 * col[c] * shade + 0.5;
            rgb[c] = (unsigned char)(v8 > 255 ? 255 : v8 < 0 ? 0 : v8);
        }
        raster_triangle(img, zbuf, w, h, s[0], s[1], s[2], rgb);
    }
}

/* ---- PNG ---------------------------------------------------------------- */

int iso_snapshot_png(const iso_mesh *m, const double *x, const iso_regions *regions,
                     const char *path, int width, int height, const iso_snapshot_view *view,
                     iso_err *err)
{
    if (!m || !path)
        return iso_err_set(err, ISO_EINVAL, -1, "snapshot: NULL mesh or path");
    if (width < 16 || width > 8192 || height < 16 || height > 8192)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "snapshot %s: size %dx%d is outside 16..8192 pixels", path, width,
                           height);
    if (regions && regions->nv != iso_mesh_vertex_count(m))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "snapshot %s: regions have %d vertices, the mesh has %d", path,
                           regions->nv, iso_mesh_vertex_count(m));
#ifndef ISO_WITH_LIBPNG
    (void)x;
    (void)view;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "snapshot %s: isoshape was built without libpng (install libpng-dev and "
                       "rebuild)",
                       path);
#else
    if (!x)
        x = iso_mesh_positions(m);
    size_t npx = (size_t)width * (size_t)height;
    unsigned char *img = malloc(3 * npx);
    float *zbuf = malloc(npx * sizeof *zbuf);
    int rc = ISO_OK;
    if (!img || !zbuf) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "snapshot %s: out of memory for %dx%d pixels", path,
                         width, height);
        goto out;
    }
    render(img, zbuf, width, height, m, x, regions, view);
    png_image png;
    memset(&png, 0, sizeof png);
    png.version = PNG_IMAGE_VERSION;
    png.width = (png_uint_32)width;
    png.height = (png_uint_32)height;
    png.format = PNG_FORMAT_RGB;
    if (!png_image_write_to_file(&png, path, 0, img, 0, NULL))
        rc = iso_err_set(err, ISO_EIO, -1, "snapshot %s: cannot write the PNG: %s", path,
                         png.message);
    png_image_free(&png);
out:
    free(img);
    free(zbuf);
    return rc;
#endif
}
