/* solver/constraints.c -- whether a problem is well posed, checked before
 * any solve (iso_solver.h): the regions cover the mesh with valid kinds and
 * handles, and every part of the mesh with free vertices is pinned by
 * constrained vertices that do not all lie on one line. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solver_internal.h"

/* ===== constraint check: every part of the mesh must be pinned ========== */

static int uf_find(int *parent, int i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

typedef struct part_info {
    int n_free, n_constrained, first_free;
    int have_p0, have_p1, pinned;
    double p0[3], p1[3];
} part_info;

/* Streams the constrained points of a part: pinned once three of them span
 * a plane (a rigid field vanishing at three non-collinear points is zero). */
static void part_add_constrained(part_info *pi, const double *p, double eps)
{
    pi->n_constrained++;
    if (pi->pinned)
        return;
    if (!pi->have_p0) {
        memcpy(pi->p0, p, sizeof pi->p0);
        pi->have_p0 = 1;
        return;
    }
    double d[3] = {p[0] - pi->p0[0], p[1] - pi->p0[1], p[2] - pi->p0[2]};
    if (!pi->have_p1) {
        if (sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) > eps) {
            memcpy(pi->p1, p, sizeof pi->p1);
            pi->have_p1 = 1;
        }
        return;
    }
    double u[3] = {pi->p1[0] - pi->p0[0], pi->p1[1] - pi->p0[1], pi->p1[2] - pi->p0[2]};
    double cx = u[1] * d[2] - u[2] * d[1], cy = u[2] * d[0] - u[0] * d[2],
           cz = u[0] * d[1] - u[1] * d[0];
    double lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    if (sqrt(cx * cx + cy * cy + cz * cz) / lu > eps)
        pi->pinned = 1;
}

/* Parts are the classes of triangles joined through shared edges: the d2
 * coupling acts across edges only, so parts that touch at a single vertex
 * can rotate about it independently and must be pinned separately. */
int iso_solver__check_constraints(const iso_mesh *m, const iso_regions *r, iso_err *err)
{
    int nt = iso_mesh_triangle_count(m), ne = iso_mesh_edge_count(m);
    const int *tri = iso_mesh_triangles(m), *et = iso_mesh_edge_triangles(m);
    const double *x = iso_mesh_positions(m);
    double eps = 1e-9 * iso_mesh_bbox_diagonal(m);
    int *parent = malloc((size_t)(nt > 0 ? nt : 1) * sizeof *parent);
    part_info *pi = calloc((size_t)(nt > 0 ? nt : 1), sizeof *pi);
    int *seen = calloc((size_t)(r->nv > 0 ? r->nv : 1), sizeof *seen);
    int rc = ISO_OK;
    if (!parent || !pi || !seen) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory checking constraints");
        goto out;
    }
    for (int t = 0; t < nt; t++)
        parent[t] = t;
    for (int e = 0; e < ne; e++)
        if (et[2 * e + 1] >= 0) {
            int a = uf_find(parent, et[2 * e]), b = uf_find(parent, et[2 * e + 1]);
            if (a != b)
                parent[a] = b;
        }
    /* seen[v] = 1 + the last part that counted v, so shared vertices count
     * once per part (parts meeting at a vertex each see it). */
    for (int t = 0; t < nt; t++) {
        int p = uf_find(parent, t);
        for (int k = 0; k < 3; k++) {
            int v = tri[3 * t + k];
            if (seen[v] == p + 1)
                continue;
            seen[v] = p + 1;
            if (r->kind[v] == ISO_FREE) {
                if (pi[p].n_free++ == 0)
                    pi[p].first_free = v;
            } else {
                part_add_constrained(&pi[p], x + 3 * v, eps);
            }
        }
    }
    for (int t = 0; t < nt && rc == ISO_OK; t++) {
        if (uf_find(parent, t) != t || pi[t].n_free == 0)
            continue;
        if (pi[t].n_constrained == 0)
            rc = iso_err_set(err, ISO_ECONSTRAINT, -1,
                             "%s: ill-posed: the part of the mesh containing free vertex %d "
                             "(%d free vertices) touches no fixed or handle vertex, so its "
                             "motion is undetermined",
                             iso_mesh_origin(m), pi[t].first_free, pi[t].n_free);
        else if (!pi[t].pinned)
            rc = iso_err_set(err, ISO_ECONSTRAINT, -1,
                             "%s: constraints too few: the %d fixed/handle vertices of the part "
                             "containing free vertex %d lie on one line, so the part could "
                             "rotate about it; fix or move at least three non-collinear vertices",
                             iso_mesh_origin(m), pi[t].n_constrained, pi[t].first_free);
    }
out:
    free(parent);
    free(pi);
    free(seen);
    return rc;
}

int iso_solver__check_regions(const iso_mesh *m, const iso_regions *r, iso_err *err)
{
    if (r->nv != iso_mesh_vertex_count(m))
        return iso_err_set(err, ISO_EINVAL, -1, "the regions cover %d vertices but %s has %d",
                           r->nv, iso_mesh_origin(m), iso_mesh_vertex_count(m));
    for (int i = 0; i < r->nv; i++) {
        if (r->kind[i] > ISO_HANDLE)
            return iso_err_set(err, ISO_EINVAL, -1, "vertex %d has region kind %d", i,
                               (int)r->kind[i]);
        if (r->kind[i] == ISO_HANDLE && (r->handle[i] < 0 || r->handle[i] >= r->n_handles))
            return iso_err_set(err, ISO_EINVAL, -1,
                               "handle vertex %d is on handle %d, but there are %d handles", i,
                               r->handle[i], r->n_handles);
    }
    return ISO_OK;
}
