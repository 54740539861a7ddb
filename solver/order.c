/* solver/order.c -- orders that keep the assembly's memory accesses near
 * each other (solver_internal.h).
 *
 * A mesh's vertex numbers may be anything (a cactus triangle's corners are
 * 3000 numbers apart at the median), and so are the places in A, in the
 * fit records and in x that consecutive elements of the element list
 * touch. Taken along a Z-order curve through their midpoints at the rest
 * pose, consecutive edges are neighbours, and much of what one touches the
 * next ones touch again. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "solver_internal.h"

/* v's low 21 bits, spread to every third bit. */
static uint64_t spread3(uint64_t v)
{
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
}

typedef struct z_key {
    uint64_t key;
    int at;
} z_key;

static int cmp_z_key(const void *pa, const void *pb)
{
    const z_key *a = pa, *b = pb;
    if (a->key != b->key)
        return a->key < b->key ? -1 : 1;
    return (a->at > b->at) - (a->at < b->at);
}

int iso_solver__z_order(const iso_mesh *m, int n, const int *a, const int *b, int *order)
{
    const double *x = iso_mesh_positions(m);
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (int e = 0; e < n; e++)
        for (int k = 0; k < 3; k++) {
            double mid = 0.5 * (x[3 * a[e] + k] + x[3 * b[e] + k]);
            lo[k] = fmin(lo[k], mid);
            hi[k] = fmax(hi[k], mid);
        }
    z_key *z = malloc(((size_t)n + 1) * sizeof *z);
    if (!z)
        return -1;
    for (int e = 0; e < n; e++) {
        z[e].key = 0;
        z[e].at = e;
        for (int k = 0; k < 3; k++) {
            double mid = 0.5 * (x[3 * a[e] + k] + x[3 * b[e] + k]);
            double u = hi[k] > lo[k] ? (mid - lo[k]) / (hi[k] - lo[k]) : 0.0;
            z[e].key |= spread3((uint64_t)(u * 2097151.0)) << k;
        }
    }
    qsort(z, (size_t)n, sizeof *z, cmp_z_key);
    for (int e = 0; e < n; e++)
        order[e] = z[e].at;
    free(z);
    return 0;
}
