/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Mesh loaders (OBJ, Gmsh MSH 4.1, TetGen .node/.ele): files a user gives.
 * Input: byte 0 picks the loader; for TetGen the rest is the .node text, a
 * NUL byte, then the .ele text. Properties: a rejected file gets a message
 * naming the file and leaves the builder as it was (empty here); an accepted
 * one builds into a mesh whose counts and indices are consistent. */
#include "fuzz.h"

#include "ftm/load.h"
#include "ftm/mesh.h"

#include <math.h>
#include <string.h>

static void check_mesh(const ftm_mesh *mesh)
{
    int32_t n = ftm_mesh_node_count(mesh);
    fuzz_check(n > 0);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 p = ftm_mesh_rest_position(mesh, i);
        fuzz_check(isfinite(p.x) && isfinite(p.y) && isfinite(p.z));
        fuzz_check(ftm_mesh_input_of_node(mesh, i) >= 0);
        const int32_t *nb;
        int32_t deg = ftm_mesh_neighbors(mesh, i, &nb, NULL, NULL);
        for (int32_t k = 0; k < deg; k++)
            fuzz_check(nb[k] >= 0 && nb[k] < n && nb[k] != i);
    }
    int32_t t = ftm_mesh_triangle_count(mesh);
    const int32_t *tri = ftm_mesh_triangles(mesh);
    for (int32_t i = 0; i < 3 * t; i++)
        fuzz_check(tri[i] >= 0 && tri[i] < n);
    int32_t e = ftm_mesh_tetrahedron_count(mesh);
    const int32_t *tet = ftm_mesh_tetrahedra(mesh);
    for (int32_t i = 0; i < 4 * e; i++)
        fuzz_check(tet[i] >= 0 && tet[i] < n);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    int which = data[0] % 3;
    const uint8_t *text = data + 1;
    size_t n = size - 1;
    const char *path;
    if (which == 0) {
        path = fuzz_write_file("m.obj", text, n);
    } else if (which == 1) {
        path = fuzz_write_file("m.msh", text, n);
    } else {
        const uint8_t *nul = memchr(text, 0, n);
        size_t node_len = nul ? (size_t)(nul - text) : n;
        path = fuzz_write_file("m.node", text, node_len);
        fuzz_write_file("m.ele", nul ? nul + 1 : text + n, nul ? n - node_len - 1 : 0);
    }

    ftm_mesh_builder *b = ftm_mesh_builder_create();
    fuzz_check(b != NULL);
    ftm_material_def mat = ftm_default_material_def();
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = which == 0   ? ftm_load_obj(b, path, &mat, &err)
             : which == 1 ? ftm_load_gmsh(b, path, &mat, &err)
                          : ftm_load_tetgen(b, path, &mat, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && err.message[0] != '\0');
        fuzz_check(strstr(err.message, "m.") != NULL); /* names the file */
        fuzz_check(ftm_mesh_builder_node_count(b) == 0);
        ftm_mesh_builder_destroy(b);
        return 0;
    }
    ftm_mesh_build_def def = ftm_default_mesh_build_def();
    ftm_mesh *mesh = NULL;
    rc = ftm_mesh_build(b, &def, &mesh, &err);
    if (rc == FTM_OK) {
        check_mesh(mesh);
        ftm_mesh_destroy(mesh);
    } else {
        fuzz_check(rc < 0 && err.message[0] != '\0');
    }
    ftm_mesh_builder_destroy(b);
    return 0;
}
