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
 * factorization, which at 1M vertices alone outgrows the machine.
 *
 * Beside it, the factorization table: what the full-resolution path's
 * costs are at each size, measured without the tick engine. The plane at
 * 40k, 90k and 160k vertices and the 160k tentacle (up to the same
 * --scale-full-max), each in a child: the system's unknowns and stored
 * entries, one numeric factor's memory as CHOLMOD holds it, the ordering
 * and analysis, then the median of three evaluations under the paper's
 * scheme (each one assembly, one factorization and one solve with the
 * factor) on one BLAS thread, as the tick engine's worker factors, and the
 * product on the same pattern: a tick of the whole mesh can go no faster
 * than its solves with the factor and its assemblies on one core, nor than
 * a factorization per worker_lag ticks on the other. */
#include "internal.h"

#include <dlfcn.h>
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

/* The median time of one product, over 21; *nnz: the matrix's entries. */
static double product_ms(const iso_mesh *m, const iso_regions *r, long *nnz)
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
        ms = iso_cli__median(t, 21);
        *nnz = a.p[a.n];
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
        long nnz = 0;
        row->vertices = iso_mesh_vertex_count(sc->mesh);
        row->product_ms = product_ms(sc->mesh, &sc->regions, &nnz);
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
        const iso_solver_stats *st = &s.solver;
        double ticks = s.ticks > 0 ? (double)s.ticks : NAN;
        row->solves_per_tick = (double)st->factor_solves / ticks;
        row->assembly_ms = 1e3 * st->t_assembly / ticks;
        row->solve_ms = 1e3 * st->t_solve / ticks;
        row->wait_ms = 1e3 * st->t_wait / ticks;
        row->tick_factorizations = st->factorizations;
    } else {
        snprintf(row->why, sizeof row->why, "%.200s", err.msg);
    }
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    if (quiet)
        fclose(quiet);
}

/* What a child computes: fills out (size bytes), which a pipe brings back. */
typedef void child_fn(const iso_cli__scale_mesh *mesh, int arg, void *out);

static void child_row(const iso_cli__scale_mesh *mesh, int proxy, void *out)
{
    child_run(mesh, proxy, out);
}

/* Runs fn in a child process; out comes back through a pipe (it starts as
 * the parent's copy), the child's peak memory from wait4. */
static int in_child(child_fn *fn, const iso_cli__scale_mesh *mesh, int arg, void *out, size_t size,
                    double *peak_mb, iso_err *err)
{
    char *back = malloc(size);
    int fd[2];
    if (!back)
        return iso_err_set(err, ISO_ENOMEM, -1, "bench --scale: out of memory for a row");
    if (pipe(fd) != 0) {
        free(back);
        return iso_err_set(err, ISO_EIO, -1, "bench --scale: no pipe for a child");
    }
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        close(fd[0]);
        close(fd[1]);
        free(back);
        return iso_err_set(err, ISO_EIO, -1, "bench --scale: could not start a child");
    }
    if (pid == 0) {
        close(fd[0]);
        memcpy(back, out, size);
        fn(mesh, arg, back);
        ssize_t w = write(fd[1], back, size);
        _exit(w == (ssize_t)size ? 0 : 1);
    }
    close(fd[1]);
    size_t got = 0;
    while (got < size) {
        ssize_t n = read(fd[0], back + got, size - got);
        if (n <= 0)
            break;
        got += (size_t)n;
    }
    close(fd[0]);
    int status = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    while (wait4(pid, &status, 0, &ru) < 0)
        ;
    int rc = ISO_OK;
    if (got != size || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "bench --scale: the run of %s %d died (status %d)",
                         mesh->shape, mesh->resolution, status);
    } else {
        memcpy(out, back, size);
        *peak_mb = (double)ru.ru_maxrss / 1024.0;
    }
    free(back);
    return rc;
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
        int rc = in_child(child_row, m, -1, &unit, sizeof unit, &unit.peak_mb, err);
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
            rc = in_child(child_row, m, proxy, row, sizeof *row, &row->peak_mb, err);
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
    printf("per tick, the run's sums over its ticks: solves with a factor, ms of assembly, of "
           "solving (PCG included) and of waiting for the worker; facts: factorizations on the "
           "ticks' thread\n");
    printf("%-14s %8s %-8s %6s %6s %8s %9s %9s %8s %10s %13s %10s %8s %8s %8s %8s %5s\n", "mesh",
           "vertices", "path", "proxy", "ticks", "ticks/s", "median ms", "p99 ms", "peak MB",
           "product ms", "median/prod", "metricErr", "solves", "asm ms", "solve ms", "wait ms",
           "facts");
    for (int i = 0; i < n; i++) {
        const iso_cli__scale_row *r = &rows[i];
        if (r->why[0]) {
            printf("%-14s %8d %-8s %s\n", r->mesh, r->vertices, r->reduced ? "reduced" : "whole",
                   r->why);
            continue;
        }
        printf("%-14s %8d %-8s %6d %6ld %8.2f %9.2f %9.2f %8.0f %10.2f %13.1f %10.4g %8.2f %8.2f "
               "%8.2f %8.2f %5ld\n",
               r->mesh, r->vertices, r->reduced ? "reduced" : "whole", r->proxy, r->ticks,
               r->ticks_per_s, r->median_ms, r->p99_ms, r->peak_mb, r->product_ms,
               r->median_ms / r->product_ms, r->metric_err, r->solves_per_tick, r->assembly_ms,
               r->solve_ms, r->wait_ms, r->tick_factorizations);
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
            iso_json_number(j, "solves_per_tick", r->solves_per_tick);
            iso_json_number(j, "assembly_ms_per_tick", r->assembly_ms);
            iso_json_number(j, "solve_ms_per_tick", r->solve_ms);
            iso_json_number(j, "wait_ms_per_tick", r->wait_ms);
            iso_json_int(j, "tick_factorizations", r->tick_factorizations);
        }
        iso_json_number(j, "product_ms", r->product_ms);
        iso_json_close(j);
    }
}

/* ===== the factorization table ========================================== */

/* The plane at the three sizes the scale section of docs/performance.md
 * has figures for, and the 160k tentacle that the scale table runs. */
const iso_cli__scale_mesh iso_cli__scale_factor_meshes[ISO_CLI_SCALE_FACTOR_MESHES] = {
    {"bumpplane", 201, 0},
    {"bumpplane", 301, 0},
    {"bumpplane", 401, 0},
    {"tentacle", 128, 0},
};

/* 49, 961 and 1,002 vertices, and 2,601 above the quick --scale-full-max;
 * the smallest so small that CHOLMOD chooses a simplicial factor, whose
 * memory is counted otherwise. */
const iso_cli__scale_mesh iso_cli__scale_factor_meshes_quick[ISO_CLI_SCALE_FACTOR_MESHES] = {
    {"bumpplane", 7, 0},
    {"bumpplane", 31, 0},
    {"bumpplane", 51, 0},
    {"tentacle", 10, 0},
};

/* OpenBLAS on one thread in this (child) process, as the tick engine's
 * solver puts it when it has a worker (ISO_SOLVER_BLAS_SIZED), so that the
 * factorization is timed as the worker runs it; unless the user set
 * OPENBLAS_NUM_THREADS, which the engine leaves alone too. */
static void blas_as_the_engine(void)
{
    void *set =
        getenv("OPENBLAS_NUM_THREADS") ? NULL : dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
    void (*set_threads)(int) = NULL;
    if (!set)
        return;
    memcpy(&set_threads, &set, sizeof set);
    set_threads(1);
}

/* The whole mesh's system at its rest pose, the scene's handle moving:
 * evaluations under the paper's scheme (refactor always, no worker, the C
 * assembly), each exactly one assembly, one numeric factorization and one
 * solve with the factor, whose times the solver's stats isolate. The first
 * is not timed: it allocates the factor's values and warms the caches,
 * which a tick engine pays once. Then the product, the unit, on the same
 * pattern in the same process. */
static int factor_figures(const iso_scene *sc, iso_cli__scale_factor_row *row, iso_err *err)
{
    iso_solver_opts so = sc->solver;
    so.assembly = ISO_ASSEMBLY_CPU;
    so.refactor = ISO_REFACTOR_ALWAYS;
    so.worker_lag = 0;
    so.proxy = 0;
    iso_cli__solver_threads(&so.threads);
    blas_as_the_engine();
    iso_solver_stats each[ISO_CLI_SCALE_FACTOR_REPS], st;
    double tf[ISO_CLI_SCALE_FACTOR_REPS], ts[ISO_CLI_SCALE_FACTOR_REPS],
        ta[ISO_CLI_SCALE_FACTOR_REPS], flops = NAN;
    int rc = iso_cli__rest_fields(sc, &so, ISO_CLI_SCALE_FACTOR_REPS, each, &st, &flops, err);
    for (int k = 0; rc == ISO_OK && k < ISO_CLI_SCALE_FACTOR_REPS; k++) {
        tf[k] = 1e3 * each[k].t_factor;
        ts[k] = 1e3 * each[k].t_solve;
        ta[k] = 1e3 * each[k].t_assembly;
    }
    if (rc == ISO_OK) {
        row->unknowns = 3 * st.n_free;
        row->supernodal = st.supernodal;
        row->nnz_a = st.nnz_a;
        row->nnz_l = st.nnz_l;
        row->factor_mb = (double)st.factor_bytes / (1024.0 * 1024.0);
        row->gflop = flops / 1e9;
        row->analysis_s = st.t_analysis;
        row->factor_ms = iso_cli__median(tf, ISO_CLI_SCALE_FACTOR_REPS);
        row->solve_ms = iso_cli__median(ts, ISO_CLI_SCALE_FACTOR_REPS);
        row->assembly_ms = iso_cli__median(ta, ISO_CLI_SCALE_FACTOR_REPS);
    }
    if (rc == ISO_OK)
        row->product_ms = product_ms(sc->mesh, &sc->regions, &row->product_nnz);
    return rc;
}

/* The child's part: the row, or only the vertex count above full_max. */
static void child_factor(const iso_cli__scale_mesh *mesh, int full_max, void *out)
{
    iso_cli__scale_factor_row *row = out;
    iso_scene *sc = NULL;
    iso_err err;
    iso_err_clear(&err);
    int rc = load_scene(mesh, 0, &sc, &err);
    if (rc == ISO_OK) {
        row->vertices = iso_mesh_vertex_count(sc->mesh);
        if (row->vertices > full_max)
            snprintf(row->why, sizeof row->why, "skipped: above --scale-full-max %d vertices",
                     full_max);
        else
            rc = factor_figures(sc, row, &err);
    }
    if (rc != ISO_OK)
        snprintf(row->why, sizeof row->why, "%.200s", err.msg);
    iso_scene_destroy(sc);
}

void iso_cli__bench_scale_factor(const iso_cli__scale_mesh *meshes, int full_max, int tty,
                                 iso_cli__scale_factor_row *rows, int *n)
{
    *n = 0;
    for (int k = 0; k < ISO_CLI_SCALE_FACTOR_MESHES; k++) {
        const iso_cli__scale_mesh *m = &meshes[k];
        iso_cli__scale_factor_row *row = &rows[(*n)++];
        memset(row, 0, sizeof *row);
        snprintf(row->mesh, sizeof row->mesh, "%s %d", m->shape, m->resolution);
        if (tty)
            fprintf(stderr, "isoshape bench: %s %d, factorization ...\n", m->shape, m->resolution);
        /* A child that fails or dies (the kernel's OOM killer, on a mesh
         * too large for the machine) says so in its row: the other rows,
         * and the scale table before them, still stand. */
        iso_err err;
        iso_err_clear(&err);
        if (in_child(child_factor, m, full_max, row, sizeof *row, &row->peak_mb, &err) != ISO_OK)
            snprintf(row->why, sizeof row->why, "%.200s", err.msg);
    }
}

void iso_cli__bench_scale_factor_print(const iso_cli__scale_factor_row *rows, int n)
{
    printf("\nfactorization: the whole mesh's system on its own (CHOLMOD, the solver's ordering), "
           "at the rest pose: unknowns, stored entries of A (upper) and of L, L supernodal or "
           "simplicial and one numeric factor's MiB (values and indices), the ordering and "
           "analysis (once), the median of %d numeric factorizations and of the solves with "
           "each factor, on one BLAS thread as the worker factors, the same evaluations' "
           "assembly, and the product, the unit, in the same process\n",
           ISO_CLI_SCALE_FACTOR_REPS);
    printf("%-14s %8s %8s %10s %11s %-5s %9s %7s %10s %10s %9s %8s %10s %11s %8s\n", "mesh",
           "vertices", "unknowns", "nnz(A)", "nnz(L)", "L", "factor MB", "GFLOP", "analysis s",
           "factor ms", "solve ms", "asm ms", "product ms", "solve/prod", "peak MB");
    for (int i = 0; i < n; i++) {
        const iso_cli__scale_factor_row *r = &rows[i];
        if (r->why[0]) {
            printf("%-14s %8d %s\n", r->mesh, r->vertices, r->why);
            continue;
        }
        printf("%-14s %8d %8d %10ld %11ld %-5s %9.1f %7.3g %10.3g %10.1f %9.2f %8.2f %10.2f %11.1f "
               "%8.0f\n",
               r->mesh, r->vertices, r->unknowns, r->nnz_a, r->nnz_l,
               r->supernodal ? "super" : "simpl", r->factor_mb, r->gflop, r->analysis_s,
               r->factor_ms, r->solve_ms, r->assembly_ms, r->product_ms,
               r->solve_ms / r->product_ms, r->peak_mb);
    }
}

void iso_cli__bench_scale_factor_json(iso_json *j, const iso_cli__scale_factor_row *rows, int n)
{
    for (int i = 0; i < n; i++) {
        const iso_cli__scale_factor_row *r = &rows[i];
        iso_json_object(j, NULL);
        iso_json_string(j, "mesh", r->mesh);
        iso_json_int(j, "vertices", r->vertices);
        if (r->why[0]) {
            iso_json_string(j, "skipped", r->why);
        } else {
            iso_json_int(j, "unknowns", r->unknowns);
            iso_json_int(j, "nnz_a", r->nnz_a);
            iso_json_int(j, "nnz_l", r->nnz_l);
            iso_json_string(j, "factor_kind", r->supernodal ? "supernodal" : "simplicial");
            iso_json_number(j, "factor_mb", r->factor_mb);
            iso_json_number(j, "factor_gflop", r->gflop);
            iso_json_number(j, "analysis_s", r->analysis_s);
            iso_json_number(j, "factor_ms", r->factor_ms);
            iso_json_number(j, "solve_ms", r->solve_ms);
            iso_json_number(j, "assembly_ms", r->assembly_ms);
            iso_json_number(j, "product_ms", r->product_ms);
            iso_json_number(j, "solve_over_product", r->solve_ms / r->product_ms);
            iso_json_number(j, "peak_mb", r->peak_mb);
        }
        iso_json_close(j);
    }
}
