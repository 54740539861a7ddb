/* solver/iso_metrics.h -- distortion between a mesh and a deformed copy
 * with the same connectivity (the paper's Table 1 measures). */
#ifndef ISO_METRICS_H
#define ISO_METRICS_H

#include <stddef.h>
#include <stdio.h>

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

/* The measures by name, so that every output labels them alike: the
 * paper's name (what text output shows), the JSON key (snake_case, like
 * every key isoshape writes), and what the figure measures. */
typedef struct iso_metrics_measure {
    const char *name; /* "metricErr" */
    const char *key;  /* "metric_err" */
    const char *what; /* "sum over edges of (|e'| - |e|)^2" */
    size_t offset;    /* of the measure's double in iso_metrics */
    int relative;     /* 1: a ratio, shown as a percentage too */
} iso_metrics_measure;

/* The table, in iso_metrics' order; *n gets its length. Static storage. */
ISO_API const iso_metrics_measure *iso_metrics_measures(size_t *n);
/* The value of `which` (an entry of the table) in m. */
ISO_API double iso_metrics_value(const iso_metrics *m, const iso_metrics_measure *which);
/* Prints one line per measure, each starting with `indent`: name, value,
 * and what it measures (e.g. "metricErr      1.234567e-02  sum over ..."). */
ISO_API void iso_metrics_print(FILE *f, const char *indent, const iso_metrics *m);

#endif
