/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal layout of ftm_mesh, shared by the core's source files.
 * Adjacency is CSR: the neighbours of node i are adj_node[adj_start[i] ..
 * adj_start[i+1]-1], with the link's stiffness and rest length alongside. */
#ifndef FTM_SRC_MESH_INTERNAL_H
#define FTM_SRC_MESH_INTERNAL_H

#include "ftm/mesh.h"

/* A label's name for display (ftm_mesh_builder_set_label_name). */
typedef struct ftm_label_name {
    int32_t label;
    char name[FTM_MESH_LABEL_NAME_MAX + 1];
} ftm_label_name;

struct ftm_mesh {
    int32_t node_count;
    int32_t link_count;
    int32_t tri_count;
    int32_t tet_count;
    int32_t hex_count;
    int32_t max_degree;

    double *rest;      /* 3 per node */
    double *mass;
    double *damping;
    uint8_t *fixed;
    double *min_link;  /* shortest rest length of a link at each node (INFINITY if none) */
    int32_t *fixed_hops; /* links from each node to the nearest fixed one (INT32_MAX: none) */

    int32_t *adj_start; /* node_count + 1 */
    int32_t *adj_node;
    double *adj_k;
    double *adj_len;
    /* The same adjacency padded to max_degree slots per node: node i's slot s
     * is pad_node[i * max_degree + s] with (k, len) in pad_kl[2 * that];
     * padding slots link i to itself with k = -0.0 and len = 0, adding exactly -0.0.
     * NULL both where the padding would cost too much (ftm_mesh_pad_rows_fit):
     * the vector sweep then reads the adjacency itself. */
    int32_t *pad_node;
    double *pad_kl;
    /* Greedy colouring of the whole graph, 0..63: adjacent nodes differ in
     * colour unless both are 63 (only where a node has >= 63 lower neighbours). */
    uint8_t *color;

    int32_t *link_a, *link_b; /* link_count each, link_a < link_b */
    double *link_k, *link_len;

    int32_t *tris; /* 3 per triangle */
    int32_t *tets; /* 4 per tetrahedron */
    int32_t *hexes; /* 8 per hexahedron */
    /* Element labels (tissues), one per tetrahedron (hexahedron) in the
     * builder's order, 0 = none; NULL when the builder set none. */
    int32_t *tet_labels, *hex_labels;
    ftm_label_name *label_names; /* label_name_count, for display; NULL: none */
    int32_t label_name_count;

    int32_t *node_of_input; /* input index -> mesh index */
    int32_t *input_of_node; /* mesh index -> input index */

    /* Partial constraints and springs to ground (docs/scene-format.md), all
     * three NULL when no node has one. bc[i]: FTM_BC_SLIDES normals node i
     * may not move along (0..2, bc_n[6 i ..] orthonormal) and FTM_BC_SPRING
     * when ground_k[i] > 0; 0 for a node without either. A fixed node has
     * neither. */
    uint8_t *bc;
    double *bc_n;
    double *ground_k;

    double mean_link_length;
    /* Every rest position has z = +0.0 (exactly those bits): a mesh in the
     * plane z = 0, such as the 2D lattice. The group sweep then leaves z out
     * while the loads keep to the plane (ftm_sim_def.planar_kernel). */
    bool planar;
};

/* z is +0.0, exactly those bits (not -0.0): what a planar mesh and a
 * planar state hold (ftm_mesh.planar, ftm_sim_planar). */
static inline bool ftm_is_plus_zero(double z)
{
    return z == 0.0 && !__builtin_signbit(z);
}

/* The padded rows give every node the same trip count, cheaper to run than
 * each node's own degree, but their padding slots cost a link each: worth
 * it unless they add more than a quarter to the links (the search, layers.c,
 * and a fresh schedule's sweep, sim_block.inc, take them then). */
static inline bool ftm_mesh_pad_cheap(const ftm_mesh *m)
{
    size_t slots = (size_t)m->node_count * (size_t)m->max_degree;
    size_t links = (size_t)m->adj_start[m->node_count];
    return slots <= links + links / 4;
}

/* Whether padded rows are kept: while they cost at most four times the
 * adjacency. One node of high degree (an OBJ polygon fanned from a corner,
 * a hub) would otherwise make them node_count x its degree: gigabytes for a
 * mesh of a few thousand nodes. Padding that is cheap (ftm_mesh_pad_cheap)
 * always fits. */
static inline bool ftm_mesh_pad_rows_fit(size_t nodes, int32_t max_degree, size_t adjacency)
{
    return nodes * (size_t)max_degree <= 4 * adjacency + 64;
}

enum { FTM_BC_SLIDES = 3, FTM_BC_SPRING = 4 };

/* Takes out of x (node i's new position) what moves along the node's
 * normals: x -= (n . (x - X)) n for each, in order (they are orthonormal).
 * An axis normal sets that coordinate to X's exactly, so a node sliding on
 * z = c stays on it bit for bit. A normal with a zero component leaves that
 * coordinate's bits (x - (+-0) = x for x = +0.0 too), which keeps a planar
 * state planar. */
static inline void ftm_bc_project(const ftm_mesh *m, int32_t i, double x[3])
{
    const double *X = m->rest + 3 * (size_t)i;
    for (int q = 0; q < (m->bc[i] & FTM_BC_SLIDES); q++) {
        const double *n = m->bc_n + 6 * (size_t)i + 3 * q;
        if (n[1] == 0.0 && n[2] == 0.0) {
            x[0] = X[0];
        } else if (n[0] == 0.0 && n[2] == 0.0) {
            x[1] = X[1];
        } else if (n[0] == 0.0 && n[1] == 0.0) {
            x[2] = X[2];
        } else {
            const double s = n[0] * (x[0] - X[0]) + n[1] * (x[1] - X[1]) + n[2] * (x[2] - X[2]);
            for (int d = 0; d < 3; d++)
                x[d] -= s * n[d];
        }
    }
}

/* Adds node i's springs to ground to f, the sum of its internal forces as
 * Eq. 8 subtracts it: f += k_g (x - X). */
static inline void ftm_bc_ground_force(const ftm_mesh *m, int32_t i, const double x[3],
                                       double f[3])
{
    if (m->bc[i] & FTM_BC_SPRING) {
        const double k = m->ground_k[i], *X = m->rest + 3 * (size_t)i;
        for (int d = 0; d < 3; d++)
            f[d] += k * (x[d] - X[d]);
    }
}

/* A deep copy of m (NULL: out of memory), e.g. to change its material. */
ftm_mesh *ftm_mesh_clone(const ftm_mesh *m);

#endif
