/* tests/tools/write_shape.c -- a built-in shape to a mesh file and its
 * labels to a .sel file, for measuring what large files cost to load:
 *
 *   write_shape NAME RESOLUTION OUT.{off,obj,ply} [OUT.sel [OUT.def]]
 *   write_shape --load FILE
 *
 * e.g. `write_shape tentacle 317 /tmp/t1m.ply` writes 1,004,892 vertices
 * (with .sel and .def, the problem as the benchmark's files hold one, for
 * tests/tools/arap_reference);
 * --load reads a mesh file back (iso_mesh_load: parse, checks, edges) and
 * prints the wall and CPU seconds it took and the process's peak memory. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "iso_clock.h"
#include "iso_mesh.h"
#include "iso_shapes.h"

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int load(const char *path)
{
    iso_err err;
    iso_err_clear(&err);
    iso_mesh *m = NULL;
    double t0 = iso_clock_now(), c0 = cpu_now();
    int rc = iso_mesh_load(path, &m, &err);
    double wall = iso_clock_now() - t0, cpu = cpu_now() - c0;
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    if (rc != ISO_OK) {
        fprintf(stderr, "write_shape: %s\n", err.msg);
        return 1;
    }
    printf("%s: %d vertices, %d triangles loaded in %.3f s (cpu %.3f s), peak memory %.1f MB\n",
           path, iso_mesh_vertex_count(m), iso_mesh_triangle_count(m), wall, cpu,
           (double)ru.ru_maxrss / 1024.0);
    iso_mesh_destroy(m);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--load") == 0)
        return load(argv[2]);
    if (argc < 4 || argc > 6) {
        fprintf(stderr, "usage: write_shape NAME RESOLUTION OUT.{off,obj,ply} [OUT.sel [OUT.def]]\n"
                        "       write_shape --load FILE\n");
        return 2;
    }
    iso_err err;
    iso_err_clear(&err);
    iso_shape s;
    iso_mesh *m = NULL;
    int rc = iso_shape_init(&s, argv[1], atoi(argv[2]), &err);
    if (rc == ISO_OK)
        rc = iso_mesh_create(s.nv, s.x, s.nt, s.tri, argv[1], &m, &err);
    if (rc == ISO_OK)
        rc = iso_mesh_save(m, NULL, argv[3], ISO_MESH_FMT_AUTO, &err);
    if (rc == ISO_OK && argc == 6) {
        FILE *f = fopen(argv[5], "w");
        for (int i = 0; f && i < 16; i++)
            fprintf(f, "%.17g%c", s.M[i], i % 4 == 3 ? '\n' : ' ');
        if (!f || fclose(f) != 0) {
            fprintf(stderr, "write_shape: could not write %s\n", argv[5]);
            rc = ISO_EIO;
        }
    }
    if (rc == ISO_OK && argc >= 5) {
        FILE *f = fopen(argv[4], "w");
        for (int i = 0; f && i < s.nv; i++)
            fprintf(f, "%d\n", s.kind[i] == ISO_FIXED ? 0 : s.kind[i] == ISO_HANDLE ? 2 : 1);
        if (!f || fclose(f) != 0) {
            fprintf(stderr, "write_shape: could not write %s\n", argv[4]);
            rc = ISO_EIO;
        }
    }
    if (rc == ISO_OK)
        printf("%s: %d vertices, %d triangles\n", argv[3], s.nv, s.nt);
    else if (err.msg[0])
        fprintf(stderr, "write_shape: %s\n", err.msg);
    iso_mesh_destroy(m);
    iso_shape_deinit(&s);
    return rc == ISO_OK ? 0 : 1;
}
