/* controller/cmd_metrics.c -- `isoshape metrics ORIGINAL DEFORMED [--json]`:
 * the paper's Table 1 measures between two meshes of the same connectivity. */
#include "internal.h"

#include <stdio.h>
#include <string.h>

#include "iso_json.h"
#include "iso_mesh.h"
#include "iso_metrics.h"

typedef struct metrics_args {
    int json;
} metrics_args;

static const iso_cli__opt metrics_options[] = {
    {"json", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(metrics_args, json), NULL,
     .help = "print one JSON object instead of text (keys metric_err, area_err, angle_err, "
             "max_edge_strain, rms_edge_strain)",
     .flag = 1},
    {0}};

int iso_cli__same_connectivity(const iso_mesh *a, const iso_mesh *b, char *why, size_t why_cap)
{
    int nv = iso_mesh_vertex_count(a), nt = iso_mesh_triangle_count(a);
    if (iso_mesh_vertex_count(b) != nv || iso_mesh_triangle_count(b) != nt) {
        snprintf(why, why_cap, "%s has %d vertices and %d triangles but %s has %d and %d",
                 iso_mesh_origin(b), iso_mesh_vertex_count(b), iso_mesh_triangle_count(b),
                 iso_mesh_origin(a), nv, nt);
        return 0;
    }
    const int *ta = iso_mesh_triangles(a), *tb = iso_mesh_triangles(b);
    for (int t = 0; t < nt; t++)
        if (memcmp(ta + 3 * t, tb + 3 * t, 3 * sizeof *ta) != 0) {
            snprintf(why, why_cap, "triangle %d of %s is (%d %d %d) but in %s it is (%d %d %d)", t,
                     iso_mesh_origin(b), tb[3 * t], tb[3 * t + 1], tb[3 * t + 2],
                     iso_mesh_origin(a), ta[3 * t], ta[3 * t + 1], ta[3 * t + 2]);
            return 0;
        }
    return 1;
}

static int metrics_main(int argc, char **argv)
{
    const char *cmd = "metrics", *path[2] = {NULL, NULL};
    metrics_args a = {0};
    int npath = 0;
    int status = iso_cli__parse(&iso_cli__metrics_cmd, argc, argv, &a, path, 2, &npath);
    if (status >= 0)
        return status;
    if (npath != 2) {
        iso_cli__fail(cmd,
                      "needs two meshes, ORIGINAL and DEFORMED (see isoshape metrics --help).");
        return 2;
    }
    iso_mesh *m[2] = {NULL, NULL};
    iso_err err;
    iso_err_clear(&err);
    status = 1;
    char why[1024];
    for (int k = 0; k < 2; k++)
        if (iso_mesh_load(path[k], &m[k], &err) != ISO_OK) {
            iso_cli__fail(cmd, "%s", err.msg);
            goto out;
        }
    if (!iso_cli__same_connectivity(m[0], m[1], why, sizeof why)) {
        iso_cli__fail(cmd, "%s, so they are not an original and its deformation.", why);
        goto out;
    }
    iso_metrics mt;
    iso_metrics_compute(m[0], iso_mesh_positions(m[0]), iso_mesh_positions(m[1]), &mt);
    if (a.json) {
        iso_json j;
        iso_json_begin(&j, stdout);
        size_t n;
        const iso_metrics_measure *k = iso_metrics_measures(&n);
        for (size_t i = 0; i < n; i++)
            iso_json_number(&j, k[i].key, iso_metrics_value(&mt, &k[i]));
        iso_json_end(&j);
    } else
        iso_metrics_print(stdout, "", &mt);
    status = 0;
out:
    iso_mesh_destroy(m[0]);
    iso_mesh_destroy(m[1]);
    return status;
}

const iso_cli__cmd iso_cli__metrics_cmd = {
    .name = "metrics",
    .summary = "distortion between an original mesh and a deformed copy",
    .usage = "usage: isoshape metrics ORIGINAL DEFORMED [--json]\n"
             "\n"
             "Distortion of DEFORMED against ORIGINAL (OFF, OBJ or PLY; same vertices and\n"
             "triangles in the same order): the paper's metricErr, areaErr and angleErr, and\n"
             "the largest and the root-mean-square relative edge length change, each printed\n"
             "with what it measures.\n",
    .opts = metrics_options,
    .main = metrics_main};
