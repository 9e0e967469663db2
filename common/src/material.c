/* A mesh with another material (tissue parameters changed during a session). */
#include "ftm/generate.h"
#include "error.h"
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int check(const ftm_material_def *m, const char *which, ftm_error *err)
{
    if (!(m->node_mass > 0.0) || !isfinite(m->node_mass))
        return ftm_error_set(err, FTM_EINVAL, "material (%s): node mass must be > 0 (got %g)",
                             which, m->node_mass);
    if (!(m->node_damping >= 0.0) || !isfinite(m->node_damping))
        return ftm_error_set(err, FTM_EINVAL, "material (%s): node damping must be >= 0 (got %g)",
                             which, m->node_damping);
    if (!(m->stiffness > 0.0) || !isfinite(m->stiffness))
        return ftm_error_set(err, FTM_EINVAL, "material (%s): stiffness must be > 0 (got %g)",
                             which, m->stiffness);
    const double *s = &m->axis_scale.x;
    for (int i = 0; i < 3; i++)
        if (!(s[i] > 0.0) || !isfinite(s[i]))
            return ftm_error_set(err, FTM_EINVAL,
                                 "material (%s): axis stiffness scale %c must be > 0 (got %g)",
                                 which, "xyz"[i], s[i]);
    return FTM_OK;
}

/* The per-axis factor of a link along d (generate.h); > 0 for a link of
 * non-zero length since every axis scale is > 0. */
static double axis_factor(const ftm_material_def *m, const double d[3])
{
    double l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    return (m->axis_scale.x * d[0] * d[0] + m->axis_scale.y * d[1] * d[1] +
            m->axis_scale.z * d[2] * d[2]) / l2;
}

int ftm_mesh_with_material(const ftm_mesh *base, const ftm_material_def *from,
                           const ftm_material_def *to, ftm_mesh **out, ftm_error *err)
{
    if (!base || !from || !to || !out)
        return ftm_error_set(err, FTM_EINVAL, "mesh with material: null argument");
    int rc;
    if ((rc = check(from, "the mesh's", err)) || (rc = check(to, "new", err)))
        return rc;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    if (!b)
        return ftm_error_set(err, FTM_ENOMEM, "mesh with material: out of memory");
    const double mass_f = to->node_mass / from->node_mass;
    const double damp_f = from->node_damping > 0.0 ? to->node_damping / from->node_damping : 0.0;
    /* Nodes in mesh order: built without reordering, the copy keeps every
     * index, hence the adjacency order, colouring and padding of the base. */
    for (int32_t i = 0; i < base->node_count && rc == FTM_OK; i++) {
        ftm_node_def nd = {
            .position = {base->rest[3 * i], base->rest[3 * i + 1], base->rest[3 * i + 2]},
            .mass = base->mass[i] * mass_f,
            /* a mesh built undamped gets the new damping outright */
            .damping = from->node_damping > 0.0 ? base->damping[i] * damp_f : to->node_damping,
            .fixed = base->fixed[i] != 0,
        };
        int32_t r = ftm_mesh_builder_add_node(b, &nd);
        if (r < 0)
            rc = ftm_error_set(err, FTM_EINVAL,
                               "mesh with material: node %d gets mass %g, damping %g", (int)i,
                               nd.mass, nd.damping);
    }
    for (int32_t l = 0; l < base->link_count && rc == FTM_OK; l++) {
        int32_t a = base->link_a[l], c = base->link_b[l];
        double d[3] = {base->rest[3 * c] - base->rest[3 * a],
                       base->rest[3 * c + 1] - base->rest[3 * a + 1],
                       base->rest[3 * c + 2] - base->rest[3 * a + 2]};
        /* one factor per link, from the base's stiffness: the result depends
         * on (base, from, to) only, not on a history of changes */
        double f = (to->stiffness * axis_factor(to, d)) / (from->stiffness * axis_factor(from, d));
        ftm_link_def ld = {a, c, base->link_k[l] * f, base->link_len[l]};
        if (ftm_mesh_builder_add_link(b, &ld) != FTM_OK)
            rc = ftm_error_set(err, FTM_EINVAL,
                               "mesh with material: link %d (nodes %d-%d) gets stiffness %g", (int)l,
                               (int)a, (int)c, ld.stiffness);
    }
    for (int32_t t = 0; t < base->tri_count && rc == FTM_OK; t++)
        if (ftm_mesh_builder_add_triangle(b, base->tris[3 * t], base->tris[3 * t + 1],
                                          base->tris[3 * t + 2]) != FTM_OK)
            rc = ftm_error_set(err, FTM_EINVAL, "mesh with material: triangle %d", (int)t);
    for (int32_t t = 0; t < base->tet_count && rc == FTM_OK; t++) {
        const int32_t *v = base->tets + 4 * t;
        if (ftm_mesh_builder_add_tetrahedron(b, v[0], v[1], v[2], v[3]) != FTM_OK)
            rc = ftm_error_set(err, FTM_EINVAL, "mesh with material: tetrahedron %d", (int)t);
    }
    for (int32_t h = 0; h < base->hex_count && rc == FTM_OK; h++)
        if (ftm_mesh_builder_add_hexahedron(b, base->hexes + 8 * h) != FTM_OK)
            rc = ftm_error_set(err, FTM_EINVAL, "mesh with material: hexahedron %d", (int)h);
    ftm_mesh *m = NULL;
    if (rc == FTM_OK) {
        ftm_mesh_build_def bd = ftm_default_mesh_build_def();
        bd.reorder = false;
        bd.surface_from_tetrahedra = false; /* the base's triangles are given */
        rc = ftm_mesh_build(b, &bd, &m, err);
    }
    ftm_mesh_builder_destroy(b);
    if (rc)
        return rc;
    /* the same input numbering as the base (the builder's was the identity) */
    memcpy(m->node_of_input, base->node_of_input, (size_t)base->node_count * sizeof(int32_t));
    memcpy(m->input_of_node, base->input_of_node, (size_t)base->node_count * sizeof(int32_t));
    *out = m;
    ftm_error_clear(err);
    return FTM_OK;
}

bool ftm_mesh_same_shape(const ftm_mesh *a, const ftm_mesh *b)
{
    if (a == b)
        return true;
    if (a->node_count != b->node_count || a->link_count != b->link_count ||
        a->tri_count != b->tri_count || a->max_degree != b->max_degree)
        return false;
    size_t n = (size_t)a->node_count, e = (size_t)a->adj_start[n];
    return memcmp(a->rest, b->rest, n * 3 * sizeof(double)) == 0 &&
           memcmp(a->fixed, b->fixed, n) == 0 &&
           memcmp(a->adj_start, b->adj_start, (n + 1) * sizeof(int32_t)) == 0 &&
           memcmp(a->adj_node, b->adj_node, e * sizeof(int32_t)) == 0 &&
           memcmp(a->adj_len, b->adj_len, e * sizeof(double)) == 0 &&
           memcmp(a->tris, b->tris, (size_t)a->tri_count * 3 * sizeof(int32_t)) == 0;
}
