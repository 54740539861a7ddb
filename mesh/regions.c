/* mesh/regions.c -- iso_regions and the benchmark's .sel/.def readers (see
 * iso_regions.h). Both files are read whole and scanned with the mesh
 * readers' tokenizer (mesh_io_internal.h), so there is one fuzzed scanner. */
#include "iso_file.h"
#include "iso_regions.h"
#include "mesh_io_internal.h"
#include "regions_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int iso_regions_init(iso_regions *r, int nv, iso_err *err)
{
    if (!r)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_regions_init: r is NULL");
    memset(r, 0, sizeof *r);
    if (nv < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_regions_init: negative vertex count %d", nv);
    size_t n = nv ? (size_t)nv : 1;
    r->kind = malloc(n);
    r->handle = malloc(n * sizeof *r->handle);
    if (!r->kind || !r->handle) {
        iso_regions_deinit(r);
        return iso_err_set(err, ISO_ENOMEM, -1, "iso_regions_init: out of memory for %d vertices",
                           nv);
    }
    r->nv = nv;
    memset(r->kind, ISO_FREE, (size_t)nv);
    for (int i = 0; i < nv; i++)
        r->handle[i] = -1;
    return ISO_OK;
}

void iso_regions_deinit(iso_regions *r)
{
    if (!r)
        return;
    free(r->kind);
    free(r->handle);
    memset(r, 0, sizeof *r);
}

/* ==== .sel =============================================================== */

static int sel_value(const char *name, long line, const char *tok, size_t n, long i, int nv,
                     iso_regions *r, iso_err *err)
{
    char q[40];
    long v;
    if (iso_mesh__to_long(tok, n, &v))
        return iso_err_set(err, ISO_EPARSE, line, "%s, line %ld: '%s' is not an integer", name,
                           line, iso_mesh__quote(q, sizeof q, tok, n));
    if (v < 0 || v > 2)
        return iso_err_set(err, ISO_EPARSE, line,
                           "%s, line %ld: vertex %ld has status %ld; expected 0 (fixed), 1 "
                           "(free) or 2 (handle)",
                           name, line, i, v);
    if (i >= nv)
        return iso_err_set(err, ISO_EPARSE, line,
                           "%s, line %ld: more values than the mesh's %d vertices", name, line, nv);
    r->kind[i] = (unsigned char)(v == 0 ? ISO_FIXED : v == 1 ? ISO_FREE : ISO_HANDLE);
    r->handle[i] = v == 2 ? 0 : -1;
    if (v == 2)
        r->n_handles = 1;
    return ISO_OK;
}

int iso_sel__parse(const char *name, const unsigned char *data, size_t len, int nv, iso_regions *r,
                   iso_err *err)
{
    int rc = iso_regions_init(r, nv, err);
    if (rc != ISO_OK)
        return rc;
    iso_mesh__text t;
    const char *p, *e, *tok;
    size_t n;
    long i = 0;
    iso_mesh__text_init(&t, (const char *)data, len);
    while (iso_mesh__text_line(&t, 1, &p, &e))
        while (iso_mesh__token(&p, e, &tok, &n))
            if ((rc = sel_value(name, t.line, tok, n, i++, nv, r, err)) != ISO_OK)
                goto err;
    if (i != nv) {
        rc = iso_err_set(err, ISO_EPARSE, t.line,
                         "%s, line %ld: file ends after %ld values, but the mesh has %d vertices",
                         name, t.line > 0 ? t.line : 1, i, nv);
        goto err;
    }
    return ISO_OK;
err:
    iso_regions_deinit(r);
    return rc;
}

int iso_sel_load(const char *path, int nv, iso_regions *r, iso_err *err)
{
    if (!path || !r)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_sel_load: NULL path or regions");
    memset(r, 0, sizeof *r);
    char *data;
    size_t len;
    int rc = iso_file_read(path, 0, &data, &len, err);
    if (rc == ISO_OK)
        rc = iso_sel__parse(path, (const unsigned char *)data, len, nv, r, err);
    free(data);
    return rc;
}

/* ==== .def =============================================================== */

/* max |RᵀR − I| over the 3x3 part of the row-major 4x4 M. */
static double orthogonality_error(const double M[16])
{
    double worst = 0;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double s = 0;
            for (int k = 0; k < 3; k++)
                s += M[4 * k + a] * M[4 * k + b];
            worst = fmax(worst, fabs(s - (a == b)));
        }
    return worst;
}

static double det3(const double M[16])
{
    return M[0] * (M[5] * M[10] - M[6] * M[9]) - M[1] * (M[4] * M[10] - M[6] * M[8]) +
           M[2] * (M[4] * M[9] - M[5] * M[8]);
}

static int check_rigid(const char *name, const double M[16], const long row_line[4], iso_err *err)
{
    static const double last[4] = {0, 0, 0, 1};
    for (int c = 0; c < 4; c++)
        if (fabs(M[12 + c] - last[c]) > 1e-9)
            return iso_err_set(err, ISO_EPARSE, row_line[3],
                               "%s, line %ld: the last row must be 0 0 0 1, found %g %g %g %g",
                               name, row_line[3], M[12], M[13], M[14], M[15]);
    double orth = orthogonality_error(M), det = fabs(det3(M) - 1);
    if (orth > ISO_DEF_RIGID_TOL || det > ISO_DEF_RIGID_TOL)
        return iso_err_set(err, ISO_EPARSE, row_line[0],
                           "%s, lines %ld-%ld: the 3x3 part is not a rotation: max |R^T R - I| "
                           "= %.3g, |det R - 1| = %.3g (tolerance %g); scale, shear and "
                           "mirroring are refused",
                           name, row_line[0], row_line[2], orth, det, ISO_DEF_RIGID_TOL);
    return ISO_OK;
}

int iso_def__parse(const char *name, const unsigned char *data, size_t len, double M[16],
                   iso_err *err)
{
    iso_mesh__text t;
    const char *p, *e, *tok;
    size_t n;
    char q[40];
    double v[16];
    long row_line[4] = {-1, -1, -1, -1};
    int k = 0;
    iso_mesh__text_init(&t, (const char *)data, len);
    while (iso_mesh__text_line(&t, 1, &p, &e))
        while (iso_mesh__token(&p, e, &tok, &n)) {
            if (k == 16)
                return iso_err_set(err, ISO_EPARSE, t.line,
                                   "%s, line %ld: more than 16 numbers (expected a 4x4 matrix)",
                                   name, t.line);
            if (iso_mesh__to_double(tok, n, &v[k]))
                return iso_err_set(err, ISO_EPARSE, t.line, "%s, line %ld: '%s' is not a number",
                                   name, t.line, iso_mesh__quote(q, sizeof q, tok, n));
            if (!isfinite(v[k]))
                return iso_err_set(err, ISO_EPARSE, t.line,
                                   "%s, line %ld: matrix entry %d is not finite", name, t.line,
                                   k + 1);
            if (k % 4 == 0)
                row_line[k / 4] = t.line;
            k++;
        }
    if (k != 16)
        return iso_err_set(err, ISO_EPARSE, t.line,
                           "%s, line %ld: file ends after %d of 16 numbers (expected a 4x4 "
                           "matrix)",
                           name, t.line > 0 ? t.line : 1, k);
    int rc = check_rigid(name, v, row_line, err);
    if (rc == ISO_OK)
        memcpy(M, v, sizeof v);
    return rc;
}

int iso_def_load(const char *path, double M[16], iso_err *err)
{
    if (!path || !M)
        return iso_err_set(err, ISO_EINVAL, -1, "iso_def_load: NULL path or matrix");
    char *data;
    size_t len;
    int rc = iso_file_read(path, 0, &data, &len, err);
    if (rc == ISO_OK)
        rc = iso_def__parse(path, (const unsigned char *)data, len, M, err);
    free(data);
    return rc;
}
