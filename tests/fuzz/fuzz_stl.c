/* SPDX-License-Identifier: GPL-3.0-or-later */
/* STL surfaces (ftm_surface_parse_stl, ftm_load_stl; Assimp behind our
 * checks): files a user gives, to press as surfaces or to mesh into
 * volumes. Input: byte 0 picks the way in (bit 0: a closed surface asked
 * for; bit 1: the loader into a builder, from a file); the rest is the
 * file. Properties: a rejected file gets a message naming it and nothing
 * else (no surface, an empty builder); an accepted surface has finite
 * vertices, facets of three distinct vertices in range, and when closed
 * every edge in two facets crossing it in opposite directions; an accepted
 * file builds into a mesh of that many nodes and triangles. */
#include "fuzz.h"

#include "ftm/mesh.h"
#include "ftm/stl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

static void check_surface(const ftm_surface *s, bool closed)
{
    fuzz_check(s->vertex_count >= 3 && s->triangle_count >= 1);
    for (int32_t i = 0; i < 3 * s->vertex_count; i++)
        fuzz_check(isfinite(s->positions[i]));
    for (int32_t t = 0; t < s->triangle_count; t++) {
        const int32_t *v = s->triangles + 3 * t;
        for (int k = 0; k < 3; k++)
            fuzz_check(v[k] >= 0 && v[k] < s->vertex_count && v[k] != v[(k + 1) % 3]);
    }
    if (!closed)
        return;
    /* directed edges: each (a, b) once, and (b, a) there too */
    size_t n = 3 * (size_t)s->triangle_count;
    uint64_t *e = malloc(n * sizeof *e);
    fuzz_check(e != NULL);
    for (size_t i = 0; i < n; i++) {
        uint32_t a = (uint32_t)s->triangles[i], b = (uint32_t)s->triangles[i - i % 3 + (i + 1) % 3];
        e[i] = (uint64_t)a << 32 | b;
    }
    qsort(e, n, sizeof *e, compare_u64);
    for (size_t i = 0; i < n; i++) {
        fuzz_check(i == 0 || e[i] != e[i - 1]);
        uint64_t back = e[i] << 32 | e[i] >> 32;
        fuzz_check(bsearch(&back, e, n, sizeof *e, compare_u64) != NULL);
    }
    free(e);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    bool closed = data[0] & 1, loader = data[0] & 2;
    const uint8_t *file = data + 1;
    size_t n = size - 1;
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (!loader) {
        ftm_surface *s = NULL;
        int rc = ftm_surface_parse_stl(file, n, "m.stl", closed, &s, &err);
        if (rc != FTM_OK) {
            fuzz_check(rc < 0 && err.message[0] != '\0');
            fuzz_check(strstr(err.message, "m.stl") != NULL);
            fuzz_check(s == NULL);
            return 0;
        }
        check_surface(s, closed);
        ftm_surface_destroy(s);
        return 0;
    }
    const char *path = fuzz_write_file("m.stl", file, n);
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    fuzz_check(b != NULL);
    ftm_material_def mat = ftm_default_material_def();
    int rc = ftm_load_stl(b, path, &mat, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && err.message[0] != '\0');
        fuzz_check(strstr(err.message, "m.stl") != NULL);
        fuzz_check(ftm_mesh_builder_node_count(b) == 0);
        ftm_mesh_builder_destroy(b);
        return 0;
    }
    ftm_mesh_build_def def = ftm_default_mesh_build_def();
    ftm_mesh *mesh = NULL;
    rc = ftm_mesh_build(b, &def, &mesh, &err);
    if (rc == FTM_OK) {
        fuzz_check(ftm_mesh_node_count(mesh) == ftm_mesh_builder_node_count(b));
        fuzz_check(ftm_mesh_triangle_count(mesh) >= 1);
        ftm_mesh_destroy(mesh);
    } else {
        fuzz_check(rc < 0 && err.message[0] != '\0');
    }
    ftm_mesh_builder_destroy(b);
    return 0;
}
