/* tests/tools/write_shape.c -- a built-in shape to a mesh file and its
 * labels to a .sel file, for measuring what large files cost to load:
 *
 *   write_shape NAME RESOLUTION OUT.{off,obj,ply} [OUT.sel]
 *
 * e.g. `write_shape tentacle 317 /tmp/t1m.ply` writes 1,004,892 vertices. */
#include <stdio.h>
#include <stdlib.h>

#include "iso_mesh.h"
#include "iso_shapes.h"

int main(int argc, char **argv)
{
    if (argc < 4 || argc > 5) {
        fprintf(stderr, "usage: write_shape NAME RESOLUTION OUT.{off,obj,ply} [OUT.sel]\n");
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
    if (rc == ISO_OK && argc == 5) {
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
