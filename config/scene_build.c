/* config/scene_build.c -- from a parsed scene to what it describes: the mesh
 * (a file, a built-in shape, or a benchmark problem with a built-in standing
 * in), the regions, the scripted motions' twists.
 *
 * Errors from the layers below (mesh reader, .sel and .def readers) come
 * back prefixed with the scene's FILE:LINE:COL and key, so the user sees both
 * where the scene named the file and what is wrong inside it. */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Re-reports a lower layer's error at a place in the scene. */
static int wrap(iso_scene *s, iso_err *err, int line, int col, const char *key, const iso_err *in)
{
    return iso_err_set(err, in->code, line, "%s:%d:%d: %s: %s", s->path, line, col, key, in->msg);
}

static int at(iso_scene *s, iso_err *err, int code, int line, int col, const char *key,
              const char *fmt, ...) ISO_PRINTF(7, 8);
static int at(iso_scene *s, iso_err *err, int code, int line, int col, const char *key,
              const char *fmt, ...)
{
    char what[384];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return iso_err_set(err, code, line, "%s:%d:%d: %s: %s", s->path, line, col, key, what);
}

/* Loads the mesh; fills base (the shape's labels or the benchmark's .sel),
 * with base->nv == 0 when the source has none. */
static int build_mesh(iso_scene *s, const iso_scene_opts *opts, iso_regions *base, iso_err *err)
{
    iso_scene_mesh_src *m = &s->mesh_src;
    iso_err e;
    iso_err_clear(&e);
    int rc;
    const char *shape = m->shape;
    if (m->kind == ISO_SCENE_MESH_FILE) {
        m->used = ISO_SCENE_MESH_FILE;
        if ((rc = iso_mesh_load(m->path, &s->mesh, &e)))
            return wrap(s, err, m->line, m->col, "mesh", &e);
        return ISO_OK;
    }
    if (m->kind == ISO_SCENE_MESH_BENCHMARK) {
        char why[1024] = "no benchmark lookup was given";
        if (opts->bench_find && opts->bench_find(opts->bench_ctx, m->benchmark, m->path, m->sel,
                                                 m->def, why, sizeof why)) {
            m->used = ISO_SCENE_MESH_BENCHMARK;
            if ((rc = iso_mesh_load(m->path, &s->mesh, &e)))
                return wrap(s, err, m->line, m->col, "mesh.benchmark", &e);
            if ((rc = iso_sel_load(m->sel, iso_mesh_vertex_count(s->mesh), base, &e)) ||
                (rc = iso_def_load(m->def, s->shape_M, &e)))
                return wrap(s, err, m->line, m->col, "mesh.benchmark", &e);
            s->have_shape_M = 1;
            return ISO_OK;
        }
        m->sel[0] = m->def[0] = m->path[0] = '\0';
        if (!m->fallback_shape[0])
            return at(s, err, ISO_EIO, m->line, m->col, "mesh.benchmark",
                      "benchmark problem '%s' not found (looked in: %s); add fallback_shape to run "
                      "a built-in shape instead",
                      m->benchmark, why);
        snprintf(m->note, sizeof m->note,
                 "benchmark '%s' not found (looked in: %.900s); using the "
                 "built-in shape '%s'",
                 m->benchmark, why, m->fallback_shape);
        shape = m->fallback_shape;
    }
    m->used = ISO_SCENE_MESH_SHAPE;
    iso_shape sh;
    if ((rc = iso_shape_init(&sh, shape, m->resolution, &e)))
        return wrap(s, err, m->line, m->col, "mesh", &e);
    rc = iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, sh.name, &s->mesh, &e);
    if (rc == ISO_OK)
        rc = iso_shape_regions(&sh, base, &e);
    memcpy(s->shape_M, sh.M, sizeof sh.M);
    s->have_shape_M = 1;
    iso_shape_deinit(&sh);
    if (rc)
        return wrap(s, err, m->line, m->col, "mesh", &e);
    return ISO_OK;
}

static int selected(const iso_scene_sel *q, const double *p)
{
    switch (q->kind) {
    case ISO_SCENE_SEL_BOX:
        for (int k = 0; k < 3; k++)
            if (p[k] < q->a[k] || p[k] > q->b[k])
                return 0;
        return 1;
    case ISO_SCENE_SEL_SPHERE: {
        double d2 = 0;
        for (int k = 0; k < 3; k++)
            d2 += (p[k] - q->a[k]) * (p[k] - q->a[k]);
        return d2 <= q->radius * q->radius;
    }
    case ISO_SCENE_SEL_PLANE: {
        double d = 0;
        for (int k = 0; k < 3; k++)
            d += (p[k] - q->a[k]) * q->b[k];
        return d > 0;
    }
    }
    return 0;
}

/* Marks the vertices of region r in mark[] (0/1). Each selection must
 * select at least one (used) vertex. */
static int select_region(iso_scene *s, const iso_scene_region *r, const char *key,
                         unsigned char *mark, int *count, iso_err *err)
{
    int nv = iso_mesh_vertex_count(s->mesh);
    const double *x = iso_mesh_positions(s->mesh);
    *count = 0;
    for (int i = 0; i < r->n_sel; i++) {
        const iso_scene_sel *q = &r->sel[i];
        int n = 0;
        if (q->kind == ISO_SCENE_SEL_VERTICES) {
            for (int j = 0; j < q->n_vertices; j++) {
                int v = q->vertices[j];
                if (v >= nv)
                    return at(s, err, ISO_EINVAL, q->line, q->col, key,
                              "vertex %d is out of range (the mesh has %d vertices, 0..%d)", v, nv,
                              nv - 1);
                n += !mark[v];
                mark[v] = 1;
            }
        } else {
            int hit = 0;
            for (int v = 0; v < nv; v++)
                if (iso_mesh_vertex_used(s->mesh, v) && selected(q, x + 3 * v)) {
                    hit++;
                    n += !mark[v];
                    mark[v] = 1;
                }
            if (hit == 0)
                return at(s, err, ISO_ECONSTRAINT, q->line, q->col, key,
                          "this selection selects no vertex (the mesh's bounding-box diagonal is "
                          "%g)",
                          iso_mesh_bbox_diagonal(s->mesh));
        }
        *count += n;
    }
    return ISO_OK;
}

static int build_regions(iso_scene *s, iso_regions *base, iso_err *err)
{
    int nv = iso_mesh_vertex_count(s->mesh);
    iso_regions *r = &s->regions;
    iso_err e;
    iso_err_clear(&e);
    int rc;
    if (strcmp(s->sel, "builtin") == 0) {
        if (base->nv == 0)
            return at(s, err, ISO_EPARSE, s->sel_line, s->sel_col, "regions.sel",
                      "'builtin' needs a mesh with its own regions (a shape or a benchmark), "
                      "not a mesh file");
    } else {
        iso_regions_deinit(base);
        if (s->sel[0] && (rc = iso_sel_load(s->sel, nv, base, &e)))
            return wrap(s, err, s->sel_line, s->sel_col, "regions.sel", &e);
    }
    if ((rc = iso_regions_init(r, nv, err)))
        return rc;
    r->n_handles = s->n_handles;
    int base_handles = 0;
    if (base->nv == nv) {
        for (int v = 0; v < nv; v++) {
            if (base->kind[v] == ISO_FIXED)
                r->kind[v] = ISO_FIXED;
            else if (base->kind[v] == ISO_HANDLE && s->handles[0].from_sel) {
                r->kind[v] = ISO_HANDLE;
                r->handle[v] = 0;
                base_handles++;
            }
        }
    }
    unsigned char *mark = calloc((size_t)nv, 1);
    if (!mark)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    if (s->fixed.n_sel) {
        if ((rc = select_region(s, &s->fixed, "regions.fixed", mark, &s->fixed.count, err)))
            goto out;
        for (int v = 0; v < nv; v++)
            if (mark[v]) {
                if (r->kind[v] == ISO_HANDLE) {
                    rc = at(s, err, ISO_ECONSTRAINT, s->fixed.sel[0].line, s->fixed.sel[0].col,
                            "regions.fixed",
                            "vertex %d is both fixed and on handle '%s' (from "
                            "the .sel)",
                            v, s->handles[0].name);
                    goto out;
                }
                r->kind[v] = ISO_FIXED;
            }
    }
    for (int h = 0; h < s->n_handles; h++) {
        iso_scene_handle *hd = &s->handles[h];
        char key[96];
        snprintf(key, sizeof key, "regions.handles[%d]", h);
        if (hd->from_sel) {
            if (h != 0 || base_handles == 0) {
                rc = at(s, err, ISO_EPARSE, s->sel_line, s->sel_col, key,
                        "handle '%s' has no select, so it must be handle 0 of regions.sel, which "
                        "%s",
                        hd->name, h != 0 ? "only has one handle" : "has no handle vertices");
                goto out;
            }
            hd->region.count = base_handles;
            continue;
        }
        memset(mark, 0, (size_t)nv);
        snprintf(key, sizeof key, "regions.handles[%d].select", h);
        if ((rc = select_region(s, &hd->region, key, mark, &hd->region.count, err)))
            goto out;
        for (int v = 0; v < nv; v++) {
            if (!mark[v])
                continue;
            if (r->kind[v] == ISO_FIXED) {
                rc = at(s, err, ISO_ECONSTRAINT, hd->region.sel[0].line, hd->region.sel[0].col, key,
                        "vertex %d is both fixed and on handle '%s'", v, hd->name);
                goto out;
            }
            if (r->kind[v] == ISO_HANDLE) {
                rc = at(s, err, ISO_ECONSTRAINT, hd->region.sel[0].line, hd->region.sel[0].col, key,
                        "vertex %d is on two handles, '%s' and '%s'", v,
                        s->handles[r->handle[v]].name, hd->name);
                goto out;
            }
            r->kind[v] = ISO_HANDLE;
            r->handle[v] = h;
        }
    }
    int nfixed = 0;
    for (int v = 0; v < nv; v++)
        nfixed += r->kind[v] == ISO_FIXED;
    if (s->fixed.n_sel == 0)
        s->fixed.count = nfixed;
    rc = ISO_OK;
out:
    free(mark);
    return rc;
}

static int build_drivers(iso_scene *s, iso_err *err)
{
    iso_err e;
    iso_err_clear(&e);
    for (int h = 0; h < s->n_handles; h++) {
        iso_scene_driver *d = &s->handles[h].driver;
        char key[96];
        snprintf(key, sizeof key, "regions.handles[%d].driver.screw", h);
        if (d->kind != ISO_SCENE_DRIVE_SCREW)
            continue;
        if (d->def[0]) {
            if (iso_def_load(d->def, d->M, &e))
                return wrap(s, err, s->sel_line, s->sel_col, key, &e);
        } else if (s->have_shape_M) {
            memcpy(d->M, s->shape_M, sizeof d->M);
        } else {
            return at(s, err, ISO_EPARSE, s->sel_line, s->sel_col, key,
                      "def is missing and a mesh file has no motion of its own (give a .def file)");
        }
        if (iso_twist_from_matrix(d->M, &d->twist, &e))
            return wrap(s, err, s->sel_line, s->sel_col, key, &e);
    }
    return ISO_OK;
}

/* What the actuator sink would refuse when the run opens it, said here
 * with the channel's place in the scene. */
static int build_channels(iso_scene *s, iso_err *err)
{
    int nv = iso_mesh_vertex_count(s->mesh), nfixed = 0;
    for (int v = 0; v < nv; v++)
        nfixed += s->regions.kind[v] == ISO_FIXED;
    for (int i = 0; i < s->actuators.n_ch; i++) {
        const iso_scene_channel *c = &s->actuators.ch[i];
        char key[96];
        if (c->vertex >= nv) {
            snprintf(key, sizeof key, "sinks.actuators.channels[%d].vertex", i);
            return at(s, err, ISO_EINVAL, c->line, c->col, key,
                      "vertex %d is out of range (the mesh has %d vertices)", c->vertex, nv);
        }
        if (c->region == ISO_SCENE_REGION_FIXED && nfixed == 0) {
            snprintf(key, sizeof key, "sinks.actuators.channels[%d].region", i);
            return at(s, err, ISO_ECONSTRAINT, c->line, c->col, key,
                      "'fixed' has no vertices in this scene, so the channel has nothing to "
                      "follow");
        }
    }
    return ISO_OK;
}

int iso_scene__build(iso_scene *s, const iso_scene_opts *opts, iso_err *err)
{
    iso_regions base;
    memset(&base, 0, sizeof base);
    int rc = build_mesh(s, opts, &base, err);
    if (rc == ISO_OK)
        rc = build_regions(s, &base, err);
    if (rc == ISO_OK)
        rc = build_drivers(s, err);
    if (rc == ISO_OK)
        rc = build_channels(s, err);
    iso_regions_deinit(&base);
    return rc;
}
