/* controller/cmd_field.c -- `isoshape field`: one solve of the deformation
 * field at the rest pose, for handle velocities read from a file. */
#include "internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"

typedef struct field_args {
    iso_cli__source src;
    const char *velocity, *out;
    iso_solver_opts so;
} field_args;

static const iso_cli__opt field_options[] = {
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(field_args, src, iso_cli__source),
     .table = iso_cli__mesh_options},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(field_args, src, iso_cli__source),
     .table = iso_cli__shape_options},
    {"velocity", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(field_args, velocity), "V",
     .help =
         "one line 'vx vy vz' per handle vertex, in vertex order ('#' comments and blank lines are "
         "skipped)"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(field_args, so, iso_solver_opts),
     .table = iso_cli__weight_options},
    {"out", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(field_args, out), "F",
     .help = "one line 'vx vy vz' per vertex, 17 significant digits"},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(field_args, so, iso_solver_opts),
     .table = iso_cli__solver_options},
    {0}};

/* Reads one velocity per handle vertex into vc (3*nv). Returns 0, or -1
 * after naming V's line. */
static int read_velocities(const char *path, const iso_regions *r, double *vc)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        iso_cli__fail("field", "cannot open velocity file %s: %s.", path, strerror(errno));
        return -1;
    }
    int n_handle = 0, next = 0, status = -1;
    for (int i = 0; i < r->nv; i++)
        n_handle += r->kind[i] == ISO_HANDLE;
    char line[1024];
    long lineno = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        if (!strchr(line, '\n') && !feof(f)) {
            iso_cli__fail("field", "%s:%ld: the line is longer than %zu characters.", path, lineno,
                          sizeof line - 2);
            goto out;
        }
        char *p = line;
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
            p++;
        if (*p == '\0' || *p == '#')
            continue;
        while (next < r->nv && r->kind[next] != ISO_HANDLE)
            next++;
        if (next >= r->nv) {
            iso_cli__fail("field", "%s:%ld: more velocity lines than the %d handle vertices.", path,
                          lineno, n_handle);
            goto out;
        }
        double v[3];
        for (int k = 0; k < 3; k++) {
            char *end;
            errno = 0;
            v[k] = strtod(p, &end);
            if (end == p || errno == ERANGE || !isfinite(v[k])) {
                iso_cli__fail("field",
                              "%s:%ld: component %d of the velocity is not a finite number "
                              "(expected 'vx vy vz').",
                              path, lineno, k + 1);
                goto out;
            }
            p = end;
        }
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
            p++;
        if (*p != '\0' && *p != '#') {
            iso_cli__fail("field", "%s:%ld: unexpected text '%.20s' after the three components.",
                          path, lineno, p);
            goto out;
        }
        memcpy(vc + 3 * next, v, sizeof v);
        next++;
    }
    if (ferror(f)) {
        iso_cli__fail("field", "cannot read velocity file %s: %s.", path, strerror(errno));
        goto out;
    }
    int got = 0;
    for (int i = 0; i < next; i++)
        got += r->kind[i] == ISO_HANDLE;
    if (got != n_handle) {
        iso_cli__fail("field",
                      "%s:%ld: the file ends after %d velocities but the mesh has %d "
                      "handle vertices.",
                      path, lineno, got, n_handle);
        goto out;
    }
    status = 0;
out:
    fclose(f);
    return status;
}

static int write_field(const char *path, const double *v, int nv)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        iso_cli__fail("field", "cannot create %s: %s.", path, strerror(errno));
        return -1;
    }
    for (int i = 0; i < nv; i++)
        fprintf(f, "%.17g %.17g %.17g\n", v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    if (fclose(f) != 0) {
        iso_cli__fail("field", "cannot write %s: %s.", path, strerror(errno));
        return -1;
    }
    return 0;
}

/* Returns -1 to go on, else the exit status (0 after --help). */
static int parse_args(int argc, char **argv, field_args *a)
{
    const char *cmd = "field";
    memset(a, 0, sizeof *a);
    iso_cli__solver_opts_default(&a->so);
    int status = iso_cli__parse(&iso_cli__field_cmd, argc, argv, a, NULL, 0, NULL);
    if (status >= 0)
        return status;
    const iso_cli__source *s = &a->src;
    if (s->shape ? (s->mesh || s->sel) : (!s->mesh || !s->sel)) {
        iso_cli__fail(cmd, "give either --mesh and --sel, or --shape (see isoshape field --help).");
        return 2;
    }
    if (!a->velocity || !a->out) {
        iso_cli__fail(cmd, "--%s is required (see isoshape field --help).",
                      a->velocity ? "out" : "velocity");
        return 2;
    }
    return -1;
}

static int field_main(int argc, char **argv)
{
    const char *cmd = "field";
    field_args a;
    int status = parse_args(argc, argv, &a);
    if (status >= 0)
        return status;
    iso_err err;
    iso_err_clear(&err);
    iso_shape sh = {0};
    iso_mesh *m = NULL;
    iso_regions reg = {0};
    iso_solver *s = NULL;
    double *vc = NULL, *v = NULL;
    status = 1;
    if (a.src.shape) {
        if (iso_shape_init(&sh, a.src.shape, a.src.resolution, &err) != ISO_OK ||
            iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, sh.name, &m, &err) != ISO_OK ||
            iso_shape_regions(&sh, &reg, &err) != ISO_OK)
            goto fail;
    } else if (iso_mesh_load(a.src.mesh, &m, &err) != ISO_OK ||
               iso_sel_load(a.src.sel, iso_mesh_vertex_count(m), &reg, &err) != ISO_OK) {
        goto fail;
    }
    int nv = iso_mesh_vertex_count(m);
    vc = calloc((size_t)nv * 3, sizeof *vc);
    v = calloc((size_t)nv * 3, sizeof *v);
    if (!vc || !v) {
        iso_cli__fail(cmd, "out of memory for the field of %d vertices.", nv);
        goto out;
    }
    if (read_velocities(a.velocity, &reg, vc) != 0)
        goto out;
    if (iso_solver_create(m, &reg, &a.so, &s, &err) != ISO_OK)
        goto fail;
    iso_cli__print_notice(cmd, iso_solver_notice(s));
    if (iso_solver_field(s, iso_mesh_positions(m), vc, v, &err) != ISO_OK)
        goto fail;
    if (write_field(a.out, v, nv) != 0)
        goto out;
    status = 0;
    goto out;
fail:
    iso_cli__fail(cmd, "%s", err.msg);
out:
    iso_solver_destroy(s);
    free(vc);
    free(v);
    iso_regions_deinit(&reg);
    iso_mesh_destroy(m);
    iso_shape_deinit(&sh);
    return status;
}

const iso_cli__cmd iso_cli__field_cmd = {
    .name = "field",
    .summary = "solve the deformation field once, at the rest pose",
    .usage =
        "usage: isoshape field --mesh M --sel S --velocity V [--omega W] [--weighting param|area] "
        "--out F\n"
        "       isoshape field --shape NAME [--resolution N] --velocity V ... --out F\n"
        "\n"
        "Solves the field once at the rest pose: fixed vertices (label 0) stand still,\n"
        "handle vertices (label 2) move with the velocities in V, and free vertices\n"
        "(label 1) get the velocities that preserve lengths best.\n",
    .opts = field_options,
    .main = field_main};
