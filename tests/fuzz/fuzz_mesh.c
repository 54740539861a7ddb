/* tests/fuzz/fuzz_mesh.c -- libFuzzer target for the OFF/OBJ/PLY readers.
 *
 * The first byte picks the format (by the name the loader sees), the rest is
 * the file. Every mesh that loads is also checked for the invariants the
 * solver relies on, so a reader bug that yields a bad mesh is a crash. */
#include <stdint.h>
#include <stdlib.h>

#include "mesh_io_internal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_mesh(const iso_mesh *m)
{
    int nv = iso_mesh_vertex_count(m), nt = iso_mesh_triangle_count(m);
    int ne = iso_mesh_edge_count(m);
    const int *t = iso_mesh_triangles(m), *e = iso_mesh_edges(m), *et = iso_mesh_edge_triangles(m);
    for (int i = 0; i < 3 * nt; i++)
        if (t[i] < 0 || t[i] >= nv)
            abort();
    for (int i = 0; i < ne; i++)
        if (e[2 * i] >= e[2 * i + 1] || et[2 * i] < 0 || et[2 * i] >= nt || et[2 * i + 1] >= nt)
            abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const names[] = {"fuzz.off", "fuzz.obj", "fuzz.ply"};
    if (size == 0)
        return 0;
    iso_mesh *m = NULL;
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_mesh__load_buffer(names[data[0] % 3], data + 1, size - 1, &m, &err);
    if (rc == ISO_OK)
        check_mesh(m);
    else if (m != NULL || err.code != rc || err.msg[0] == '\0')
        abort(); /* every failure must explain itself */
    iso_mesh_destroy(m);
    return 0;
}
