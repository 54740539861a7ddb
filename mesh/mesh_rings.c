/* mesh/mesh_rings.c -- each vertex's one-ring (iso_mesh_rings.h). */
#include "iso_mesh_rings.h"

#include <stdlib.h>
#include <string.h>

void iso_mesh_rings_deinit(iso_mesh_rings *r)
{
    if (!r)
        return;
    free(r->nb_start);
    free(r->nb);
    free(r->corner_start);
    free(r->corner);
    memset(r, 0, sizeof *r);
}

/* Counts (in start[1..n]) to starts (start[0] = 0). */
static void counts_to_starts(int *start, int n)
{
    for (int v = 0; v < n; v++)
        start[v + 1] += start[v];
}

int iso_mesh_rings_init(iso_mesh_rings *r, const iso_mesh *m, iso_err *err)
{
    memset(r, 0, sizeof *r);
    int nv = iso_mesh_vertex_count(m), ne = iso_mesh_edge_count(m);
    int nt = iso_mesh_triangle_count(m);
    const int *ed = iso_mesh_edges(m), *tri = iso_mesh_triangles(m);
    r->nv = nv;
    r->nb_start = calloc((size_t)nv + 1, sizeof *r->nb_start);
    r->corner_start = calloc((size_t)nv + 1, sizeof *r->corner_start);
    r->nb = malloc((2 * (size_t)ne + 1) * sizeof *r->nb);
    r->corner = malloc((3 * (size_t)nt + 1) * sizeof *r->corner);
    int *next = malloc(((size_t)nv + 1) * sizeof *next);
    if (!r->nb_start || !r->corner_start || !r->nb || !r->corner || !next) {
        free(next);
        iso_mesh_rings_deinit(r);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the rings of %d vertices", nv);
    }
    for (int k = 0; k < 2 * ne; k++)
        r->nb_start[ed[k] + 1]++;
    for (int k = 0; k < 3 * nt; k++)
        r->corner_start[tri[k] + 1]++;
    counts_to_starts(r->nb_start, nv);
    counts_to_starts(r->corner_start, nv);
    /* in edge order: edge e's two ends each get the other */
    memcpy(next, r->nb_start, (size_t)nv * sizeof *next);
    for (int k = 0; k < 2 * ne; k++)
        r->nb[next[ed[k]]++] = ed[k ^ 1];
    memcpy(next, r->corner_start, (size_t)nv * sizeof *next);
    for (int k = 0; k < 3 * nt; k++)
        r->corner[next[tri[k]]++] = k;
    free(next);
    return ISO_OK;
}
