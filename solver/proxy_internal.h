/* solver/proxy_internal.h -- what the reduced model's two files share:
 * proxy_decimate.c simplifies the mesh, proxy.c maps the full mesh onto
 * the result and prolongs. Not installed. */
#ifndef ISO_PROXY_INTERNAL_H
#define ISO_PROXY_INTERNAL_H

#include "iso_proxy.h"
#include "solver_internal.h"

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

/* The fit (proxy_fit.c): the full mesh's free vertices placed to best
 * carry the prolongation's rotations. create: held[i] != 0 for every
 * vertex the fit keeps where it is given (nv entries); the interpolation
 * from the proxy's np vertices (its free ones, proxy_free[k] != 0) by the
 * prolongation's corners and weights (3 nv each); team: the two halves'
 * helper, or NULL. NULL when out of memory or when the proxy's Galerkin
 * matrix cannot be factored. run: x (3 nv) holds the prolongation on entry
 * and the fit on return; X the rest positions, R (9 nv) every vertex's
 * rotation. 0, or −1 should CHOLMOD fail (x is then the prolongation). */
typedef struct iso_proxy__fit iso_proxy__fit;
iso_proxy__fit *iso_proxy__fit_create(const iso_mesh *m, const unsigned char *held, int np,
                                      const unsigned char *proxy_free, const int *corner,
                                      const double *beta, iso_solver__team *team);
void iso_proxy__fit_destroy(iso_proxy__fit *f); /* NULL is a no-op */
int iso_proxy__fit_run(iso_proxy__fit *f, const double *X, const double *R, double *x);
int iso_proxy__fit_iterations(const iso_proxy__fit *f); /* the last run's CG iterations */
void iso_proxy__fit_set_team(iso_proxy__fit *f, iso_solver__team *team);

/* For white-box tests: the prolongation with the fit (on, the default) or
 * without it; and the proxy's work on the calling thread alone (its helper
 * stopped), to hold the two-thread result to the one-thread one. */
void iso_proxy__set_fit(iso_proxy *p, int on);
void iso_proxy__one_thread(iso_proxy *p);

#endif
