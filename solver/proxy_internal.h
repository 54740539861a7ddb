/* solver/proxy_internal.h -- what the reduced model's two files share:
 * proxy_decimate.c simplifies the mesh, proxy.c maps the full mesh onto
 * the result and prolongs. Not installed. */
#ifndef ISO_PROXY_INTERNAL_H
#define ISO_PROXY_INTERNAL_H

#include "iso_proxy.h"

/* The outcome of a simplification. */
typedef struct iso_proxy__decimated {
    int np;        /* proxy vertices */
    int *full_of;  /* np: the full vertex each proxy vertex is, ascending */
    int *proxy_of; /* nv: the proxy vertex a full vertex is, else −1 */
    int *rep;      /* nv: the proxy vertex a full vertex was collapsed into
                      (its own if it is one; −1 for an unreferenced vertex) */
    int nt;        /* proxy triangles */
    int *tri;      /* 3 nt, proxy vertex indices, the full mesh's orientation */
} iso_proxy__decimated;

/* Simplifies m to at most `budget` referenced vertices by half-edge
 * collapses (proxy_decimate.c says which), into d. ISO_ENOMEM; d is freed
 * by iso_proxy__decimated_free whatever the outcome. */
int iso_proxy__decimate(const iso_mesh *m, const iso_regions *r, int budget,
                        iso_proxy__decimated *d, iso_err *err);
void iso_proxy__decimated_free(iso_proxy__decimated *d);

#endif
