/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Generated surface organ models for the paper's section 4.4 (`ftm
 * experiment organs`): closed triangle surfaces with exactly the node and
 * triangle counts of the paper's lung (1769 nodes, 3534 triangles) and
 * stomach (512 nodes, 1020 triangles). We have no scans: each organ is a
 * smooth parametric shape (the lung a tall half-ellipsoid-like lobe with a
 * concave medial face, the stomach a J-shaped curved sac) meshed ring by ring
 * with near-equilateral triangles, the ring sizes chosen to hit the counts.
 * Deterministic: the same numbers on every run. See docs/experiments.md. */
#ifndef FTM_TOOLS_ORGANS_H
#define FTM_TOOLS_ORGANS_H

#include "ftm/ftm.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

typedef enum ftm_organ_kind { FTM_ORGAN_LUNG = 0, FTM_ORGAN_STOMACH = 1, FTM_ORGAN_COUNT = 2 } ftm_organ_kind;

typedef struct ftm_organ {
    ftm_organ_kind kind;
    const char *name;      /* "lung", "stomach" */
    int32_t node_count;    /* the paper's counts */
    int32_t tri_count;     /* 2 * node_count - 4 */
    double *pos;           /* 3 per node [m] */
    double *axis;          /* 3 per node: the point of the organ's axis its ring is around */
    int32_t *tris;         /* 3 per triangle, counter-clockwise seen from outside */
    bool *fixed;           /* per node: attached to the body (lung hilum, stomach ends) */
    double fixed_box[6];   /* the attachment as a box (xmin ymin zmin xmax ymax zmax) */
    ftm_vec3 press_target; /* where the probe presses: the triangle nearest to it */
    int32_t rings;
} ftm_organ;

/* The material and time step of both organs (stable at h = 1 ms). */
ftm_material_def ftm_organ_material(void);
#define FTM_ORGAN_TIME_STEP 1e-3

/* Generates an organ. 0 or FTM_ENOMEM. */
int ftm_organ_generate(ftm_organ_kind kind, ftm_organ *organ);
void ftm_organ_free(ftm_organ *organ);

typedef struct ftm_organ_quality {
    int32_t nodes, triangles, edges;
    int32_t euler;              /* V - E + F: 2 for a closed surface of genus 0 */
    int32_t open_edges;         /* edges not in exactly two triangles */
    int32_t misoriented_edges;  /* edges both triangles run the same way */
    int32_t degenerate;         /* triangles of area below 1e-3 * mean */
    int32_t inverted;           /* triangles whose normal points into the organ */
    int32_t below_20deg;        /* triangles with an angle below 20 degrees */
    int32_t max_degree;
    double min_angle, max_angle; /* [degrees] */
    double min_edge, max_edge, mean_edge; /* [m] */
    double area, volume;        /* [m^2], [m^3] (> 0: outward orientation) */
    double extent[3];           /* bounding box size [m] */
} ftm_organ_quality;

void ftm_organ_measure(const ftm_organ *organ, ftm_organ_quality *q);
/* Everything a closed, consistently oriented, well-shaped surface needs. */
bool ftm_organ_quality_ok(const ftm_organ_quality *q);

/* Adds the organ to a builder as the OBJ loader does (nodes, triangles, a
 * spring per triangle edge with the material) and fixes its attachment. */
int ftm_organ_build(const ftm_organ *organ, const ftm_material_def *material,
                    ftm_mesh_builder *builder, ftm_error *err);

/* The triangle the probe presses (nearest centroid to press_target) and its
 * outward unit normal. */
int32_t ftm_organ_press_triangle(const ftm_organ *organ, ftm_vec3 *normal);

#endif
