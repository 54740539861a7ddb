/* controller/bench_scale.c -- `isoshape bench --scale`: meshes of 40k to 1M
 * vertices through the tick engine, the method on the whole mesh beside
 * the reduced model (solver.proxy auto), each row with its ticks per
 * second, median and p99 tick, peak memory, and the median tick over one
 * product with a matrix of the whole mesh's system measured in the same
 * run: the floor a tick of the whole mesh could approach (a product is
 * what one conjugate-gradient iteration cannot do without).
 *
 * Each row runs in a child process of its own, so that its peak memory
 * (the child's maximum resident set, from wait4) is the row's alone. The
 * meshes are built-in shapes, so that the table needs no data: the plane
 * at 40,401 vertices, the tentacle at 163,842 and at 1,004,892. The method
 * on the whole mesh is skipped above --scale-full-max vertices (default
 * 200,000): its factor at 1M vertices would not fit the machine.
 *
 * The product: y = A v with the upper triangle of a symmetric matrix of
 * the system's pattern (3x3 blocks between free vertices that share a
 * triangle, or lie across an edge from each other: what the elements
 * couple), stored as CHOLMOD's sdmult reads it (column-compressed, upper),
 * on one thread; values drawn at random, since the time depends on the
 * pattern only. Building the solver's own matrix would need its symbolic
 * factorization, which at 1M vertices alone outgrows the machine. */
#include "internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "iso_clock.h"
#include "iso_loop.h"
#include "iso_scene.h"

/* ===== one product with the whole system's pattern ====================== */

typedef struct csc {
    int n;      /* scalar columns */
    int *p, *i; /* column starts, row indices (upper triangle, rows ascending) */
    double *x;
} csc;

static void csc_free(csc *a)
{
    free(a->p);
    free(a->i);
    free(a->x);
}

/* Marks the couplings of free vertices (row <= col) per column, in lists. */
typedef struct couplings {
    int *start, *rows, *fill;
} couplings;

static int cmp_int(const void *a, const void *b)
{
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

/* The block pattern: for each free column vertex, the free row vertices
 * (<= it) an element couples it with, once each. */
static int block_pattern(const iso_mesh *m, const iso_regions *r, const int *free_of, int nf,
                         couplings *c)
{
    int nt = iso_mesh_triangle_count(m), ne = iso_mesh_edge_count(m);
    const int *tri = iso_mesh_triangles(m), *ed = iso_mesh_edges(m),
              *et = iso_mesh_edge_triangles(m);
    (void)r;
    c->start = calloc((size_t)nf + 1, sizeof *c->start);
    c->fill = calloc((size_t)nf + 1, sizeof *c->fill);
    if (!c->start || !c->fill)
        return -1;
    /* groups of vertices coupled all with all: triangles, and each interior
     * edge's four vertices */
    for (int pass = 0; pass < 2; pass++) {
        for (int g = 0; g < nt + ne; g++) {
            int v[4], n = 0;
            if (g < nt) {
                for (int k = 0; k < 3; k++)
                    v[n++] = tri[3 * g + k];
            } else {
                int e = g - nt;
                if (et[2 * e + 1] < 0)
                    continue;
                v[n++] = ed[2 * e];
                v[n++] = ed[2 * e + 1];
                for (int s = 0; s < 2; s++)
                    for (int k = 0; k < 3; k++) {
                        int w = tri[3 * et[2 * e + s] + k];
                        if (w != ed[2 * e] && w != ed[2 * e + 1])
                            v[n++] = w;
                    }
            }
            for (int a = 0; a < n; a++)
                for (int b = 0; b < n; b++) {
                    int fa = free_of[v[a]], fb = free_of[v[b]];
                    if (fa < 0 || fb < 0 || fa > fb)
                        continue;
                    if (pass == 0)
                        c->start[fb + 1]++;
                    else
                        c->rows[c->start[fb] + c->fill[fb]++] = fa;
                }
        }
        if (pass == 0) {
            for (int f = 0; f < nf; f++)
                c->start[f + 1] += c->start[f];
            if (!(c->rows = malloc(((size_t)c->start[nf] + 1) * sizeof *c->rows)))
                return -1;
        }
    }
    return 0;
}

/* The scalar upper-triangle matrix of the block pattern, random values. */
static int system_matrix(const iso_mesh *m, const iso_regions *r, csc *a)
{
    int nv = iso_mesh_vertex_count(m), nf = 0;
    int *free_of = malloc(((size_t)nv + 1) * sizeof *free_of);
    couplings c = {0};
    int rc = free_of ? 0 : -1;
    for (int i = 0; rc == 0 && i < nv; i++)
        free_of[i] = r->kind[i] == ISO_FREE && iso_mesh_vertex_used(m, i) ? nf++ : -1;
    if (rc == 0)
        rc = block_pattern(m, r, free_of, nf, &c);
    /* each column's rows sorted and unique */
    size_t nnz = 0;
    int *nb = rc == 0 ? calloc((size_t)nf + 1, sizeof *nb) : NULL;
    if (!nb)
        rc = -1;
    for (int f = 0; rc == 0 && f < nf; f++) {
        int *rows = c.rows + c.start[f], n = c.start[f + 1] - c.start[f], u = 0;
        qsort(rows, (size_t)n, sizeof *rows, cmp_int);
        for (int k = 0; k < n; k++)
            if (u == 0 || rows[u - 1] != rows[k])
                rows[u++] = rows[k];
        nb[f] = u;
        nnz += 3 * (size_t)(3 * (u - 1)) + 6;
    }
    a->n = 3 * nf;
    if (rc == 0) {
        a->p = malloc(((size_t)a->n + 1) * sizeof *a->p);
        a->i = malloc((nnz + 1) * sizeof *a->i);
        a->x = malloc((nnz + 1) * sizeof *a->x);
        if (!a->p || !a->i || !a->x)
            rc = -1;
    }
    unsigned long long seed = 88172645463325252ULL;
    for (int f = 0, q = 0; rc == 0 && f < nf; f++)
        for (int k = 0; k < 3; k++) {
            a->p[3 * f + k] = q;
            const int *rows = c.rows + c.start[f];
            for (int j = 0; j < nb[f]; j++)
                for (int al = 0; al < (rows[j] == f ? k + 1 : 3); al++) {
                    a->i[q] = 3 * rows[j] + al;
                    seed ^= seed << 13, seed ^= seed >> 7, seed ^= seed << 17;
                    a->x[q++] = (double)(seed >> 11) * 0x1.0p-53 - 0.5;
                }
            a->p[3 * f + k + 1] = q;
        }
    free(nb);
    free(free_of);
    free(c.start);
    free(c.rows);
    free(c.fill);
    return rc;
}

/* y = A v for the symmetric A whose upper triangle a holds. */
static void sym_product(const csc *a, const double *v, double *y)
{
    memset(y, 0, (size_t)a->n * sizeof *y);
    for (int j = 0; j < a->n; j++) {
        double vj = v[j], yj = 0;
        for (int q = a->p[j]; q < a->p[j + 1]; q++) {
            int i = a->i[q];
            double aij = a->x[q];
            yj += aij * v[i];
            if (i != j)
                y[i] += aij * vj;
        }
        y[j] += yj;
    }
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median time of one product, over 21. */
static double product_ms(const iso_mesh *m, const iso_regions *r)
{
    csc a = {0};
    double t[21], ms = NAN;
    double *v = NULL, *y = NULL;
    if (system_matrix(m, r, &a) == 0 && (v = malloc((size_t)a.n * sizeof *v)) &&
        (y = malloc((size_t)a.n * sizeof *y))) {
        for (int i = 0; i < a.n; i++)
            v[i] = 1.0 / (1 + i % 7);
        sym_product(&a, v, y); /* warm */
        for (int k = 0; k < 21; k++) {
            double t0 = iso_clock_now();
            sym_product(&a, v, y);
            t[k] = 1e3 * (iso_clock_now() - t0);
        }
        qsort(t, 21, sizeof t[0], cmp_double);
        ms = t[10];
    }
    free(v);
    free(y);
    csc_free(&a);
    return ms;
}

/* ===== one row in a child =============================================== */

static int load_scene(const iso_cli__scale_mesh *mesh, int reduced, iso_scene **out, iso_err *err)
{
    char text[1024], proxy[32] = "off";
    if (reduced && mesh->budget > 0)
        snprintf(proxy, sizeof proxy, "%d", mesh->budget);
    else if (reduced)
        snprintf(proxy, sizeof proxy, "auto");
    snprintf(text, sizeof text,
             "name: %s\n"
             "mesh: {shape: %s, resolution: %d}\n"
             "regions:\n"
             "  sel: builtin\n"
             "  handles:\n"
             "    - name: top\n"
             "      driver: {screw: {def: builtin, duration: 2.0}}\n"
             "solver: {assembly: auto, refactor: adaptive, worker_lag: 4, proxy: %s}\n"
             "integrator: {abm: pec}\n"
             "tick_hz: 60\n",
             mesh->shape, mesh->shape, mesh->resolution, proxy);
    iso_scene_opts opts = {0};
    return iso_scene_load_mem(text, strlen(text), mesh->shape, &opts, out, err);
}

/* The child's part: the run, or the product (proxy < 0), into row. */
static void child_run(const iso_cli__scale_mesh *mesh, int proxy, iso_cli__scale_row *row)
{
    iso_scene *sc = NULL;
    iso_loop *l = NULL;
    iso_err err;
    iso_err_clear(&err);
    int rc = load_scene(mesh, proxy > 0, &sc, &err);
    if (rc == ISO_OK && proxy < 0) {
        row->vertices = iso_mesh_vertex_count(sc->mesh);
        row->product_ms = product_ms(sc->mesh, &sc->regions);
        iso_scene_destroy(sc);
        return;
    }
    FILE *quiet = fopen("/dev/null", "w");
    if (rc == ISO_OK) {
        iso_loop_opts o;
        iso_cli__loop_opts_default(&o, "bench");
        o.log = quiet;
        o.fast = 1;
        o.rt = 0;
        o.display = 0;
        rc = iso_loop_create(sc, &o, &l, &err);
    }
    if (rc == ISO_OK)
        rc = iso_loop_run(l, &err);
    if (rc == ISO_OK) {
        iso_loop_summary s;
        iso_loop_get_summary(l, &s);
        row->vertices = iso_mesh_vertex_count(sc->mesh);
        row->proxy = s.proxy_vertices;
        row->build_s = s.proxy_build_s;
        row->ticks = s.ticks;
        row->ticks_per_s = s.wall_s > 0 ? (double)s.ticks / s.wall_s : NAN;
        row->median_ms = s.tick_median;
        row->p99_ms = s.tick_p99;
        row->metric_err = s.metrics.metric_err;
    } else {
        snprintf(row->why, sizeof row->why, "%.200s", err.msg);
    }
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    if (quiet)
        fclose(quiet);
}

/* Runs child_run in a child process; the row comes back through a pipe,
 * the peak memory from wait4. */
static int in_child(const iso_cli__scale_mesh *mesh, int proxy, iso_cli__scale_row *row,
                    iso_err *err)
{
    int fd[2];
    if (pipe(fd) != 0)
        return iso_err_set(err, ISO_EIO, -1, "bench --scale: no pipe for a child");
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        close(fd[0]);
        close(fd[1]);
        return iso_err_set(err, ISO_EIO, -1, "bench --scale: could not start a child");
    }
    if (pid == 0) {
        close(fd[0]);
        iso_cli__scale_row r = *row;
        child_run(mesh, proxy, &r);
        ssize_t w = write(fd[1], &r, sizeof r);
        _exit(w == (ssize_t)sizeof r ? 0 : 1);
    }
    close(fd[1]);
    iso_cli__scale_row r;
    ssize_t got = 0;
    while (got < (ssize_t)sizeof r) {
        ssize_t n = read(fd[0], (char *)&r + got, sizeof r - (size_t)got);
        if (n <= 0)
            break;
        got += n;
    }
    close(fd[0]);
    int status = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    while (wait4(pid, &status, 0, &ru) < 0)
        ;
    if (got != (ssize_t)sizeof r || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
        return iso_err_set(err, ISO_EIO, -1, "bench --scale: the run of %s %d died (status %d)",
                           mesh->shape, mesh->resolution, status);
    *row = r;
    row->peak_mb = (double)ru.ru_maxrss / 1024.0;
    return ISO_OK;
}

const iso_cli__scale_mesh iso_cli__scale_meshes[ISO_CLI_SCALE_MESHES] = {
    {"bumpplane", 201, 0},
    {"tentacle", 128, 0},
    {"tentacle", 317, 0},
};

/* 961, 1,002 and 2,562 vertices, in seconds; the largest above the quick
 * --scale-full-max so that the skipped row is exercised too. */
const iso_cli__scale_mesh iso_cli__scale_meshes_quick[ISO_CLI_SCALE_MESHES] = {
    {"bumpplane", 31, 300},
    {"tentacle", 10, 300},
    {"tentacle", 16, 600},
};

int iso_cli__bench_scale(const iso_cli__scale_mesh *meshes, int full_max, int tty,
                         iso_cli__scale_row *rows, int *n, iso_err *err)
{
    *n = 0;
    for (int k = 0; k < ISO_CLI_SCALE_MESHES; k++) {
        const iso_cli__scale_mesh *m = &meshes[k];
        iso_cli__scale_row unit = {0};
        if (tty)
            fprintf(stderr, "isoshape bench: %s %d, one product ...\n", m->shape, m->resolution);
        int rc = in_child(m, -1, &unit, err);
        for (int proxy = 0; rc == ISO_OK && proxy < 2; proxy++) {
            iso_cli__scale_row *row = &rows[(*n)++];
            memset(row, 0, sizeof *row);
            snprintf(row->mesh, sizeof row->mesh, "%s %d", m->shape, m->resolution);
            row->vertices = unit.vertices;
            row->product_ms = unit.product_ms;
            row->reduced = proxy;
            if (!proxy && unit.vertices > full_max) {
                snprintf(row->why, sizeof row->why, "skipped: above --scale-full-max %d vertices",
                         full_max);
                continue;
            }
            if (tty)
                fprintf(stderr, "isoshape bench: %s %d, %s ...\n", m->shape, m->resolution,
                        proxy ? "reduced" : "whole mesh");
            rc = in_child(m, proxy, row, err);
        }
        if (rc != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

void iso_cli__bench_scale_print(const iso_cli__scale_row *rows, int n)
{
    printf("\nscale: built-in meshes through the tick engine (a screw over 2 s, ABM3 PEC, 60 Hz, "
           "adaptive refactoring, worker lag 4, assembly auto), as fast as possible: the method "
           "on the whole mesh and the reduced model (solver.proxy auto, or the budget --quick "
           "names); product: one y = A v "
           "with a matrix of the whole mesh's system pattern, on one thread, in the same run\n");
    printf("%-14s %8s %-8s %6s %6s %8s %9s %9s %8s %10s %13s %10s\n", "mesh", "vertices", "path",
           "proxy", "ticks", "ticks/s", "median ms", "p99 ms", "peak MB", "product ms",
           "median/prod", "metricErr");
    for (int i = 0; i < n; i++) {
        const iso_cli__scale_row *r = &rows[i];
        if (r->why[0]) {
            printf("%-14s %8d %-8s %s\n", r->mesh, r->vertices, r->reduced ? "reduced" : "whole",
                   r->why);
            continue;
        }
        printf("%-14s %8d %-8s %6d %6ld %8.1f %9.2f %9.2f %8.0f %10.2f %13.1f %10.4g\n", r->mesh,
               r->vertices, r->reduced ? "reduced" : "whole", r->proxy, r->ticks, r->ticks_per_s,
               r->median_ms, r->p99_ms, r->peak_mb, r->product_ms, r->median_ms / r->product_ms,
               r->metric_err);
    }
}

void iso_cli__bench_scale_json(iso_json *j, const iso_cli__scale_row *rows, int n)
{
    for (int i = 0; i < n; i++) {
        const iso_cli__scale_row *r = &rows[i];
        iso_json_object(j, NULL);
        iso_json_string(j, "mesh", r->mesh);
        iso_json_int(j, "vertices", r->vertices);
        iso_json_string(j, "path", r->reduced ? "reduced" : "whole");
        if (r->why[0]) {
            iso_json_string(j, "skipped", r->why);
        } else {
            iso_json_int(j, "proxy_vertices", r->proxy);
            iso_json_number(j, "proxy_build_s", r->build_s);
            iso_json_int(j, "ticks", r->ticks);
            iso_json_number(j, "ticks_per_s", r->ticks_per_s);
            iso_json_number(j, "tick_median_ms", r->median_ms);
            iso_json_number(j, "tick_p99_ms", r->p99_ms);
            iso_json_number(j, "peak_mb", r->peak_mb);
            iso_json_number(j, "metric_err", r->metric_err);
        }
        iso_json_number(j, "product_ms", r->product_ms);
        iso_json_close(j);
    }
}
