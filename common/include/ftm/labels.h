/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Label maps: segmented scans (from 3D Slicer, ITK-SNAP, an atlas) whose
 * voxels hold which tissue they are in, as whole numbers. Read from NIfTI
 * like volumes (volume.h: the same files, bounds, axes and messages); the
 * scan-to-mesh tool (issue 31, docs/meshes.md) meshes them.
 *
 * Coordinates as for volumes: voxel (i, j, k) of a map with spacing s and
 * origin o has its centre at o + ((i + 0.5) s.x, (j + 0.5) s.y, (k + 0.5)
 * s.z); labels are stored x fastest: i + nx (j + ny k). */
#ifndef FTM_LABELS_H
#define FTM_LABELS_H

#include "ftm/volume.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_label_map ftm_label_map; /* immutable once made */

typedef struct ftm_label_map_def {
    ftm_volume_axes axes; /* default FTM_VOLUME_AXES_SCANNER, as for volumes */
    ftm_vec3 origin;      /* as ftm_volume_load_def.origin; default (0, 0, 0) */
    double scale;         /* as ftm_volume_load_def.scale; default 1 */
    /* false (default): the voxels are labels, whole numbers in int32_t's
     * range (after scl_slope / scl_inter), or the file is refused naming the
     * first voxel that is not. true: a mask made from an intensity image:
     * label 1 where the value is above `above`, 0 elsewhere. */
    bool threshold;
    double above;
} ftm_label_map_def;

ftm_label_map_def ftm_default_label_map_def(void);

/* A NIfTI-1 or -2 file (.nii, .nii.gz), as ftm_volume_load reads it. def
 * may be NULL (defaults). FTM_EIO, FTM_EPARSE (the file; a value that is not
 * a label), FTM_EINVAL (def), FTM_ENOMEM. */
int ftm_label_map_load(const char *path, const ftm_label_map_def *def, ftm_label_map **out,
                       ftm_error *err);
/* The same from bytes in memory (an uncompressed .nii); name is used in
 * error messages. */
int ftm_label_map_parse_nifti(const void *data, size_t size, const char *name,
                              const ftm_label_map_def *def, ftm_label_map **out, ftm_error *err);
void ftm_label_map_destroy(ftm_label_map *map);

ftm_volume_info ftm_label_map_get_info(const ftm_label_map *map);
/* nx * ny * nz labels, x fastest */
const int32_t *ftm_label_map_data(const ftm_label_map *map);
/* The file's voxel (i, j, k) that is voxel (x, y, z) of the map (the map's
 * axes may be the file's permuted and flipped): for messages a user can
 * look up in a viewer. FTM_ERANGE outside the map. */
int ftm_label_map_file_voxel(const ftm_label_map *map, int32_t x, int32_t y, int32_t z,
                             int32_t ijk[3]);
/* The label of the voxel holding a point [m]; 0 outside the box (or NaN). */
int32_t ftm_label_map_at(const ftm_label_map *map, ftm_vec3 point);

#ifdef __cplusplus
}
#endif
#endif
