/* solver/iso_metrics.h -- distortion between a mesh and a deformed copy
 * with the same connectivity (the paper's Table 1 measures). */
#ifndef ISO_METRICS_H
#define ISO_METRICS_H

#include "iso_mesh.h"

typedef struct iso_metrics {
    double metric_err;      /* Σ_edges (|e'| − |e|)² */
    double area_err;        /* Σ_triangles (A'_T − A_T)² */
    double angle_err;       /* Σ_triangles Σ_corners (θ' − θ)², radians */
    double max_edge_strain; /* max_e | |e'| − |e| | / |e| */
    double rms_edge_strain; /* sqrt(mean_e ((|e'| − |e|)/|e|)²) */
} iso_metrics;

/* x0, x1: 3*nv positions (rest and deformed) over m's connectivity. */
ISO_API void iso_metrics_compute(const iso_mesh *m, const double *x0, const double *x1,
                                 iso_metrics *out);

#endif
