/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Point-based collision of a haptic interface point (HIP) with the deformed
 * surface (paper section 3.3), through a uniform grid over the surface
 * triangles that is kept current as the surface deforms.
 *
 * Structure: a dense uniform grid over the rest surface's bounding box
 * (enlarged by a margin; points outside clamp to the border cells), cell size
 * about twice the mean surface edge. Every triangle is listed in each cell its
 * current bounding box overlaps and remembers that cell range. After a step,
 * ftm_collide_update looks only at the surface nodes that can have moved —
 * the contact region's nodes plus the surface nodes that were away from rest
 * at the previous update (relaxing nodes were in a region before) — and
 * re-files a triangle only when its cell range changed. Cost per tick:
 * proportional to the region, not to the surface. A query walks the cells
 * overlapped by the segment's bounding box and tests each triangle once. */
#ifndef FTM_SERVER_COLLIDE_H
#define FTM_SERVER_COLLIDE_H

#include "ftm/mesh.h"

typedef struct ftm_collide ftm_collide;

typedef struct ftm_collide_stats {
    int32_t triangles, cells;   /* surface triangles, grid cells */
    int32_t dims[3];
    double cell_size;
    double extent;              /* longest side of the rest surface's bounding box; 0: none */
    uint64_t updates, refiled;  /* update calls; triangles re-filed */
    uint64_t queries, tested;   /* segment queries; triangle tests */
} ftm_collide_stats;

int ftm_collide_create(const ftm_mesh *mesh, ftm_collide **out, ftm_error *err);
void ftm_collide_destroy(ftm_collide *c);

/* Positions x (3 per node) after a step; maybe_moved lists nodes that may
 * have moved since the previous update (a superset is fine). */
void ftm_collide_update(ftm_collide *c, const double *x, const int32_t *maybe_moved, int32_t count);

/* The first surface triangle (smallest t) the segment a -> b crosses, with
 * the crossing's parameter t in [0, 1] and barycentric weights of the
 * crossing point; -1 if none. Either side of a triangle counts. */
int32_t ftm_collide_segment(ftm_collide *c, const double *x, ftm_vec3 a, ftm_vec3 b, double *t,
                            double bary[3]);

void ftm_collide_get_stats(const ftm_collide *c, ftm_collide_stats *st);

#endif
