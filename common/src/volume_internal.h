/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: where the lattice points of a volume's control lattice are, so
 * that the generator (volume_lattice.c) and the embedding (ffd.c) agree to
 * the bit. */
#ifndef FTM_SRC_VOLUME_INTERNAL_H
#define FTM_SRC_VOLUME_INTERNAL_H

#include "ftm/volume.h"

typedef struct ftm_volume_frame {
    int32_t n[3];     /* lattice points per axis, >= 2 */
    double origin[3]; /* the volume's box */
    double extent[3];
    double cell[3];   /* extent / (n - 1) */
} ftm_volume_frame;

/* The frame of a nodes[0] x nodes[1] x nodes[2] lattice over the volume's box. */
ftm_volume_frame ftm_volume_frame_of(const ftm_volume *volume, const int32_t nodes[3]);

/* Coordinate a of lattice point index i: the box's faces exactly at the
 * first and the last index. */
static inline double ftm_volume_frame_coord(const ftm_volume_frame *f, int a, double i)
{
    return f->origin[a] + f->extent[a] * i / (f->n[a] - 1);
}

#endif
