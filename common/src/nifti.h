/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: NIfTI-1 and NIfTI-2 single files (.nii, .nii.gz) through the
 * format's reference library (libnifti: the header layouts, byte swapping,
 * the qform quaternion, znzlib's reading of gzip), with our own checks in
 * front of it. Shared by volumes (volume.c) and label maps (labels.c).
 *
 * The file is untrusted: every header field is checked before it sizes
 * anything, files are read only as far as the header's voxels reach, and
 * messages name the file and the header field. libnifti's own checks print
 * to stderr (at its default debug level) and repair fields silently (a NaN
 * pixdim becomes 1); we call none of them, only its layouts and arithmetic. */
#ifndef FTM_SRC_NIFTI_H
#define FTM_SRC_NIFTI_H

#include "ftm/base.h"

/* 2^28 voxels: 256 MiB of intensities, 2 GiB of float64 in the file. */
#define FTM_NIFTI_MAX_VOXELS ((int64_t)1 << 28)

typedef struct ftm_nifti {
    int version;         /* 1 or 2 */
    bool swap;           /* the file's byte order is not ours */
    int64_t n[3];        /* dim[1..3] */
    int datatype;
    int bytes;           /* per voxel */
    double pixdim[3];    /* pixdim[1..3], in the file's units */
    double unit;         /* metres per file unit */
    double slope, inter; /* scl_slope, scl_inter as applied */
    uint64_t offset;     /* vox_offset */
    uint64_t needed;     /* offset + voxel bytes: the file's least size */
    /* orientation, as the header gives it (checked by ftm_nifti_grid) */
    int qform_code, sform_code;
    double quatern[3], qoffset[3], qfac;
    double srow[3][4];
} ftm_nifti;

/* Checks a header at the start of d (size bytes of a file of file_size
 * bytes; UINT64_MAX when not known yet). FTM_EPARSE with "NAME: header field
 * ..." messages. */
int ftm_nifti_header(const uint8_t *d, size_t size, uint64_t file_size, const char *name,
                     ftm_nifti *h, ftm_error *err);

/* Voxel i (file order) as stored, before scl_slope / scl_inter. */
double ftm_nifti_raw(const ftm_nifti *h, const uint8_t *voxels, size_t i);

/* Reads a .nii or .nii.gz (the gzip magic decides) as far as its header's
 * voxels reach: never more bytes than the header declares, so a small .gz
 * cannot inflate to more. *data is malloc'd. FTM_EIO, FTM_EPARSE (the
 * header, corrupt gzip data), FTM_ENOMEM; a file cut short is returned as
 * read (the header check names what is missing). */
int ftm_nifti_read(const char *path, uint8_t **data, size_t *size, ftm_error *err);

/* Which axes an image is placed on. */
enum {
    FTM_NIFTI_AXES_SCANNER, /* the sform (or qform): world axes, RAS */
    FTM_NIFTI_AXES_STORED,  /* i, j, k as stored; the box's corner at `origin` */
};

/* Where the voxels of an image go: grid voxel (x, y, z) of n[0] x n[1] x
 * n[2], centre origin + ((x + 0.5) spacing.x, ...), holds file voxel
 * file_index(x, y, z). */
typedef struct ftm_nifti_grid {
    int32_t n[3];
    ftm_vec3 spacing, origin;   /* [m] */
    int axis[3];                /* file axis (0 i, 1 j, 2 k) along grid axis a */
    bool flip[3];               /* it runs the other way */
    int xform;                  /* 0 none, 1 qform, 2 sform: what placed it */
} ftm_nifti_grid;

/* The grid of a checked header. SCANNER: the sform when sform_code > 0,
 * else the qform when qform_code > 0, else as STORED (no orientation in the
 * file); its axes permuted and flipped onto the nearest world axes, the box
 * where the transform puts it, shifted by `origin`; an oblique transform
 * (more than 0.06 degrees off the axes) is refused, naming the angle.
 * STORED: the file's axes, spacing from pixdim, the box's corner at
 * `origin`. Both scale every length by `scale` (after units to metres).
 * FTM_EPARSE (a transform field), FTM_EINVAL (a size zero or not finite once
 * scaled). */
int ftm_nifti_grid_of(const ftm_nifti *h, int axes, double scale, ftm_vec3 origin,
                      const char *name, ftm_nifti_grid *g, ftm_error *err);

/* Index into the file's voxels of grid voxel (x, y, z). */
static inline size_t ftm_nifti_file_index(const ftm_nifti *h, const ftm_nifti_grid *g,
                                          int32_t x, int32_t y, int32_t z)
{
    int64_t c[3] = {0, 0, 0};
    const int32_t xyz[3] = {x, y, z};
    for (int a = 0; a < 3; a++)
        c[g->axis[a]] = g->flip[a] ? g->n[a] - 1 - xyz[a] : xyz[a];
    return (size_t)(c[0] + h->n[0] * (c[1] + h->n[1] * c[2]));
}

#endif
