/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Drawing of a volume embedded in its control lattice (paper section 4.2):
 * the image is a 3D texture sampled on planes perpendicular to the lattice
 * axis most aligned with the view, the node planes and 9 planes between
 * each two, back to front with alpha blending. A plane is a grid (2 x 2
 * quads per lattice cell) whose vertices are the deformed positions of its
 * rest points under the lattice's trilinear free-form deformation
 * (ftm_ffd_map, computed here from the lattice points' displacements) and
 * whose texture coordinates are those rest points in the image's box.
 * Every step-th plane is drawn as a slice that samples the step planes
 * behind it along the ray through each pixel (in the image's rest space,
 * through the deformation's Jacobian) and blends them as one: the picture
 * of all the planes, with a step-th of the triangles and fragments; quads
 * whose slab holds only air are left out. Render thread only, with the
 * context current. */
#ifndef FTM_CLIENT_VOLUME_RENDER_H
#define FTM_CLIENT_VOLUME_RENDER_H

#include "ftm/labels.h"
#include "ftm/volume.h"

#include <stdbool.h>

/* The planes a slice stands for unless told (ftm-client --volume-step). */
#define FTM_VOLUME_STEP_DEFAULT 1
/* The slices' framebuffer pixels per voxel of the image unless told
 * (ftm-client --volume-scale), and the most asked for. */
#define FTM_VOLUME_SCALE_DEFAULT 1.5
#define FTM_VOLUME_SCALE_MAX 16.0

typedef struct ftm_volume_render ftm_volume_render;

/* Compiles the shader; draws nothing until a volume is set. */
int ftm_volume_render_create(ftm_volume_render **out, ftm_error *err);
void ftm_volume_render_destroy(ftm_volume_render *vr);

/* The volume and its embedding (both NULL: none); uploads the image once.
 * labels (NULL: none): a label map on the image's voxels; a labelled voxel
 * (label > 0) is drawn in its tissue's colour (ftm_tissue_color, as the
 * surface), with the intensity's opacity and shading; label 0 keeps the
 * intensity's colours. node_count: the lattice mesh's nodes (positions are
 * checked against it). */
int ftm_volume_render_set(ftm_volume_render *vr, const ftm_volume *volume, const ftm_ffd *ffd,
                          const ftm_label_map *labels, int32_t node_count, ftm_error *err);
bool ftm_volume_render_active(const ftm_volume_render *vr);
/* Slices drawn last (before a draw: the most planes along an axis). */
int32_t ftm_volume_render_slices(const ftm_volume_render *vr);

/* The lattice's current node positions (3 per node; NULL or another count:
 * at rest). */
void ftm_volume_render_update(ftm_volume_render *vr, const double *pos, int32_t node_count);

/* Draws the slices for an eye at `eye` into the w x h window (after the
 * opaque parts, which hide what is behind them: blending and depth writes
 * as they were after; the slices go through a framebuffer of lower
 * resolution over the part of the window they cover, blended over the
 * window: scale of its pixels per voxel of the image, along the diagonal,
 * at most the window's; 0 or less: FTM_VOLUME_SCALE_DEFAULT). colormap:
 * tint by displacement magnitude, full [m] at the top of the map. cut:
 * the planes on the eye's side of the box's middle plane are left out, and
 * the middle plane is drawn opaque, so the section through the middle
 * faces the eye (a cut-away: the inside of a head shows). step:
 * each slice samples step planes, 1..10 (anything else is taken as 1): a
 * slice per plane (the paper's drawing) at 1, a tenth of the slices at 10,
 * nearly the same picture (a slice per plane is the cheapest per plane
 * sampled under llvmpipe: one sample per fragment, no loop). */
void ftm_volume_render_draw(ftm_volume_render *vr, const float mvp[16], ftm_vec3 eye,
                            bool colormap, bool cut, int step, double scale, double full, int w,
                            int h);

#endif
