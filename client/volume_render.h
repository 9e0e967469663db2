/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Drawing of a volume embedded in its control lattice (paper section 4.2):
 * the image is a 3D texture, drawn as slices perpendicular to the lattice
 * axis most aligned with the view, the node planes and 9 slices between
 * each two, back to front with alpha blending. Each slice is a grid (2 x 2
 * quads per lattice cell) whose vertices are the deformed positions of its
 * rest points under the lattice's trilinear free-form deformation
 * (ftm_ffd_map, computed here from the lattice points' displacements) and
 * whose texture coordinates are those rest points in the image's box. Quads
 * over cells that hold only air are left out. Render thread only, with the
 * context current. */
#ifndef FTM_CLIENT_VOLUME_RENDER_H
#define FTM_CLIENT_VOLUME_RENDER_H

#include "ftm/volume.h"

#include <stdbool.h>

typedef struct ftm_volume_render ftm_volume_render;

/* Compiles the shader; draws nothing until a volume is set. */
int ftm_volume_render_create(ftm_volume_render **out, ftm_error *err);
void ftm_volume_render_destroy(ftm_volume_render *vr);

/* The volume and its embedding (both NULL: none); uploads the image once.
 * node_count: the lattice mesh's nodes (positions are checked against it). */
int ftm_volume_render_set(ftm_volume_render *vr, const ftm_volume *volume, const ftm_ffd *ffd,
                          int32_t node_count, ftm_error *err);
bool ftm_volume_render_active(const ftm_volume_render *vr);
/* Slices along the axis drawn last (before a draw: the most along any). */
int32_t ftm_volume_render_slices(const ftm_volume_render *vr);

/* The lattice's current node positions (3 per node; NULL or another count:
 * at rest). */
void ftm_volume_render_update(ftm_volume_render *vr, const double *pos, int32_t node_count);

/* Draws the slices for an eye at `eye` into the w x h window (after the
 * opaque parts, whose depth hides what is behind them: blending and depth
 * writes as they were after; the slices go through a framebuffer of lower
 * resolution, blended over the window). colormap: tint by displacement
 * magnitude, full [m] at the top of the map. cut: the slices on the eye's
 * side of the box's middle plane are left out, so the section through the
 * middle faces the eye (a cut-away: the inside of a head shows). step:
 * every step-th slice is drawn (1, 2, 5 or 10; 10: the node planes only;
 * anything else is taken as 1), opacities corrected for the wider spacing:
 * fewer slices for a renderer without a GPU. */
void ftm_volume_render_draw(ftm_volume_render *vr, const float mvp[16], ftm_vec3 eye,
                            bool colormap, bool cut, int step, double full, int w, int h);

#endif
