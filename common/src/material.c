/* SPDX-License-Identifier: GPL-3.0-or-later */
/* A mesh with another material (tissue parameters changed during a session). */
#include "ftm/generate.h"
#include "error.h"
#include "material.h"
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int ftm_material_check(const ftm_material_def *m, const char *who, ftm_error *err)
{
    if (!(m->node_mass > 0.0) || !isfinite(m->node_mass))
        return ftm_error_set(err, FTM_EINVAL, "%s: node mass must be > 0 (got %g)", who,
                             m->node_mass);
    if (!(m->node_damping >= 0.0) || !isfinite(m->node_damping))
        return ftm_error_set(err, FTM_EINVAL, "%s: node damping must be >= 0 (got %g)", who,
                             m->node_damping);
    if (!(m->stiffness > 0.0) || !isfinite(m->stiffness))
        return ftm_error_set(err, FTM_EINVAL, "%s: stiffness must be > 0 (got %g)", who,
                             m->stiffness);
    const double s[3] = {m->axis_scale.x, m->axis_scale.y, m->axis_scale.z};
    for (int i = 0; i < 3; i++)
        if (!(s[i] > 0.0) || !isfinite(s[i]))
            return ftm_error_set(err, FTM_EINVAL, "%s: axis stiffness scale %c must be > 0 (got %g)",
                                 who, "xyz"[i], s[i]);
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

/* Stiffness factor of a link along d: (to.k a_to(d)) / (from.k a_from(d)).
 * d and -d give the same bits (only squares enter). */
static double link_factor(const ftm_material_def *from, const ftm_material_def *to,
                          const double d[3])
{
    return (to->stiffness * axis_factor(to, d)) / (from->stiffness * axis_factor(from, d));
}

int ftm_mesh_with_material(const ftm_mesh *base, const ftm_material_def *from,
                           const ftm_material_def *to, ftm_mesh **out, ftm_error *err)
{
    if (!base || !from || !to || !out)
        return ftm_error_set(err, FTM_EINVAL, "mesh with material: null argument");
    int rc;
    if ((rc = ftm_material_check(from, "material (the mesh's)", err)) ||
        (rc = ftm_material_check(to, "material (new)", err)))
        return rc;
    /* A copy scaled in place: the same numbering, adjacency order, colouring
     * and padding; only masses, damping and stiffness change. O(mesh). */
    ftm_mesh *m = ftm_mesh_clone(base);
    if (!m)
        return ftm_error_set(err, FTM_ENOMEM, "mesh with material: out of memory (%d nodes)",
                             (int)base->node_count);
    const double mass_f = to->node_mass / from->node_mass;
    const double damp_f = from->node_damping > 0.0 ? to->node_damping / from->node_damping : 0.0;
    for (int32_t i = 0; i < m->node_count; i++) {
        m->mass[i] = base->mass[i] * mass_f;
        /* a mesh built undamped gets the new damping outright */
        m->damping[i] = from->node_damping > 0.0 ? base->damping[i] * damp_f : to->node_damping;
        if (!(m->mass[i] > 0.0) || !isfinite(m->mass[i]) || !(m->damping[i] >= 0.0) ||
            !isfinite(m->damping[i])) {
            rc = ftm_error_set(err, FTM_EINVAL,
                               "mesh with material: node %d gets mass %g, damping %g", (int)i,
                               m->mass[i], m->damping[i]);
            goto fail;
        }
    }
    const double *X = base->rest;
    for (int32_t l = 0; l < m->link_count; l++) {
        int32_t a = base->link_a[l], c = base->link_b[l];
        double d[3] = {X[3 * c] - X[3 * a], X[3 * c + 1] - X[3 * a + 1], X[3 * c + 2] - X[3 * a + 2]};
        /* one factor per link, from the base's stiffness: the result depends
         * on (base, from, to) only, not on a history of changes */
        m->link_k[l] = base->link_k[l] * link_factor(from, to, d);
        if (!(m->link_k[l] > 0.0) || !isfinite(m->link_k[l])) {
            rc = ftm_error_set(err, FTM_EINVAL,
                               "mesh with material: link %d (nodes %d-%d) gets stiffness %g",
                               (int)l, (int)a, (int)c, m->link_k[l]);
            goto fail;
        }
    }
    /* the adjacency's copies of link stiffness, with the same factor */
    const int32_t deg_max = m->max_degree;
    for (int32_t i = 0; i < m->node_count; i++) {
        int32_t s0 = m->adj_start[i], deg = m->adj_start[i + 1] - s0;
        for (int32_t k = 0; k < deg; k++) {
            int32_t j = m->adj_node[s0 + k];
            double d[3] = {X[3 * j] - X[3 * i], X[3 * j + 1] - X[3 * i + 1],
                           X[3 * j + 2] - X[3 * i + 2]};
            double kk = base->adj_k[s0 + k] * link_factor(from, to, d);
            m->adj_k[s0 + k] = kk;
            if (m->pad_kl)
                m->pad_kl[2 * ((size_t)i * (size_t)deg_max + (size_t)k)] = kk;
        }
    }
    *out = m;
    ftm_error_clear(err);
    return FTM_OK;
fail:
    ftm_mesh_destroy(m);
    return rc;
}

/* The same partial constraints and springs to ground, node for node. */
static bool same_constraints(const ftm_mesh *a, const ftm_mesh *b)
{
    size_t n = (size_t)a->node_count;
    if (!a->bc || !b->bc)
        return !a->bc && !b->bc;
    return memcmp(a->bc, b->bc, n) == 0 && memcmp(a->bc_n, b->bc_n, 6 * n * sizeof(double)) == 0 &&
           memcmp(a->ground_k, b->ground_k, n * sizeof(double)) == 0;
}

/* The elements of each node (hexahedra, then tetrahedra, ascending), CSR. */
static int node_elements(const ftm_mesh *m, int32_t **start_out, int32_t **elem_out)
{
    const size_t n = (size_t)m->node_count, ne = (size_t)m->hex_count + (size_t)m->tet_count;
    const size_t inc = 8 * (size_t)m->hex_count + 4 * (size_t)m->tet_count;
    int32_t *start = calloc(n + 2, sizeof *start), *elem = malloc((inc + 1) * sizeof *elem),
            *fill = malloc((n + 1) * sizeof *fill);
    if (!start || !elem || !fill) {
        free(start);
        free(elem);
        free(fill);
        return FTM_ENOMEM;
    }
    for (size_t e = 0; e < ne; e++) {
        const bool hex = e < (size_t)m->hex_count;
        const int32_t *v = hex ? m->hexes + 8 * e : m->tets + 4 * (e - (size_t)m->hex_count);
        for (int a = 0; a < (hex ? 8 : 4); a++)
            start[v[a] + 1]++;
    }
    for (size_t i = 0; i < n; i++)
        start[i + 1] += start[i];
    memcpy(fill, start, n * sizeof *fill);
    for (size_t e = 0; e < ne; e++) {
        const bool hex = e < (size_t)m->hex_count;
        const int32_t *v = hex ? m->hexes + 8 * e : m->tets + 4 * (e - (size_t)m->hex_count);
        for (int a = 0; a < (hex ? 8 : 4); a++)
            elem[fill[v[a]]++] = (int32_t)e;
    }
    free(fill);
    *start_out = start;
    *elem_out = elem;
    return FTM_OK;
}

/* The factor of the pair a-b: the mean of the factors (fe, per element)
 * of the elements holding both, 1 if none; the same bits for b-a. */
static double pair_factor(const ftm_mesh *m, const int32_t *start, const int32_t *elem,
                          const double *fe, int32_t a, int32_t b)
{
    if (a > b) {
        const int32_t t = a;
        a = b;
        b = t;
    }
    double sum = 0.0;
    int32_t count = 0;
    for (int32_t q = start[a]; q < start[a + 1]; q++) {
        const int32_t e = elem[q];
        const bool hex = e < m->hex_count;
        const int32_t *v = hex ? m->hexes + 8 * (size_t)e : m->tets + 4 * (size_t)(e - m->hex_count);
        bool has = false;
        for (int k = 0; k < (hex ? 8 : 4); k++)
            has |= v[k] == b;
        if (has) {
            sum += fe[e];
            count++;
        }
    }
    return count ? sum / count : 1.0;
}

int ftm_mesh_with_label_stiffness(const ftm_mesh *base, const int32_t *labels,
                                  const double *factor, int32_t count, ftm_mesh **out,
                                  ftm_error *err)
{
    if (!base || !out || count < 0 || (count > 0 && (!labels || !factor)))
        return ftm_error_set(err, FTM_EINVAL, "mesh with label stiffness: null argument");
    for (int32_t i = 0; i < count; i++) {
        if (labels[i] < 1)
            return ftm_error_set(err, FTM_EINVAL,
                                 "mesh with label stiffness: label %d (labels are >= 1)",
                                 (int)labels[i]);
        if (!(factor[i] > 0.0) || !isfinite(factor[i]))
            return ftm_error_set(err, FTM_EINVAL,
                                 "mesh with label stiffness: label %d: factor must be > 0 (got %g)",
                                 (int)labels[i], factor[i]);
        for (int32_t j = 0; j < i; j++)
            if (labels[j] == labels[i])
                return ftm_error_set(err, FTM_EINVAL,
                                     "mesh with label stiffness: label %d listed twice",
                                     (int)labels[i]);
    }
    const int32_t ne = base->hex_count + base->tet_count;
    double *fe = malloc(((size_t)ne + 1) * sizeof *fe);
    int32_t *start = NULL, *elem = NULL;
    ftm_mesh *m = fe ? ftm_mesh_clone(base) : NULL;
    if (!m || node_elements(base, &start, &elem) != FTM_OK) {
        free(fe);
        ftm_mesh_destroy(m);
        return ftm_error_set(err, FTM_ENOMEM, "mesh with label stiffness: out of memory");
    }
    for (int32_t e = 0; e < ne; e++) {
        const int32_t *lab = e < base->hex_count ? base->hex_labels : base->tet_labels;
        const int32_t label = lab ? lab[e < base->hex_count ? e : e - base->hex_count] : 0;
        fe[e] = 1.0;
        for (int32_t i = 0; label > 0 && i < count; i++)
            if (labels[i] == label)
                fe[e] = factor[i];
    }
    for (int32_t l = 0; l < m->link_count; l++)
        m->link_k[l] =
            base->link_k[l] * pair_factor(base, start, elem, fe, base->link_a[l], base->link_b[l]);
    const int32_t deg_max = m->max_degree;
    for (int32_t i = 0; i < m->node_count; i++) {
        const int32_t s0 = m->adj_start[i], deg = m->adj_start[i + 1] - s0;
        for (int32_t k = 0; k < deg; k++) {
            const double kk = base->adj_k[s0 + k] *
                              pair_factor(base, start, elem, fe, i, m->adj_node[s0 + k]);
            m->adj_k[s0 + k] = kk;
            if (m->pad_kl)
                m->pad_kl[2 * ((size_t)i * (size_t)deg_max + (size_t)k)] = kk;
        }
    }
    free(fe);
    free(start);
    free(elem);
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
           memcmp(a->fixed, b->fixed, n) == 0 && same_constraints(a, b) &&
           memcmp(a->adj_start, b->adj_start, (n + 1) * sizeof(int32_t)) == 0 &&
           memcmp(a->adj_node, b->adj_node, e * sizeof(int32_t)) == 0 &&
           memcmp(a->adj_len, b->adj_len, e * sizeof(double)) == 0 &&
           memcmp(a->tris, b->tris, (size_t)a->tri_count * 3 * sizeof(int32_t)) == 0;
}
