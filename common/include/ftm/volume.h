/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Volumes: a scalar image (an MRI or CT scan) embedded in a mass-spring
 * control lattice and deformed with it (paper section 4.2).
 *
 * The image is a regular grid of voxels; the control lattice is a cubic
 * lattice of nodes[0] x nodes[1] x nodes[2] points spanning the image's box.
 * The lattice is simulated like any other mesh; the image follows it by
 * trilinear free-form deformation (FFD) of the nodes' displacements:
 *
 *     p(X) = X + sum over the 8 corners c of X's cell of  w_c(X) (x_c - X_c)
 *
 * with X a point at rest, w_c the trilinear weights of X in its cell, x_c and
 * X_c corner c's current and rest positions. Cells that hold only air may be
 * left out of the lattice (ftm_volume_lattice_def.air_threshold); a corner
 * that is not a mesh node has zero displacement.
 *
 * Coordinates: voxel (i, j, k) of an image with spacing s and origin o has
 * its centre at o + ((i + 0.5) s.x, (j + 0.5) s.y, (k + 0.5) s.z): the image's
 * box is [o, o + n s]. Voxels are stored x fastest: i + nx (j + ny k).
 *
 * Errors name the file and the byte offset or header field:
 * "head.nii: header field dim[2] = 0 (each of dim[1..3] must be >= 1)". */
#ifndef FTM_VOLUME_H
#define FTM_VOLUME_H

#include "ftm/generate.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_volume ftm_volume; /* immutable once made */

typedef struct ftm_volume_info {
    int32_t nx, ny, nz; /* voxels per axis, >= 1 each */
    ftm_vec3 spacing;   /* voxel size per axis [m], > 0 */
    ftm_vec3 origin;    /* the box's minimum corner [m] */
} ftm_volume_info;

/* Which axes a file's voxels are placed on. */
typedef enum ftm_volume_axes {
    /* The scanner's (world) axes, as the file's sform (or, without one, its
     * qform) places the image: x, y, z are NIfTI's RAS (x to the right, y
     * to the front, z up), and the box lies where the scanner puts it, so a
     * mesh made from the scan lines up with it. The voxel axes
     * are permuted and flipped onto the nearest world axes; an oblique
     * transform (an axis more than 0.06 degrees off) is refused. A file with
     * neither form (both codes 0) is read as STORED. */
    FTM_VOLUME_AXES_SCANNER,
    /* The file's own voxel axes i, j, k, and the box's corner at `origin`. */
    FTM_VOLUME_AXES_STORED,
} ftm_volume_axes;

/* How a file's values become intensities in [0, 1] (stored as 0..255). */
typedef struct ftm_volume_load_def {
    /* Values at or below the low percentile map to 0, at or above the high
     * one to 1, linearly between (a robust window: a few hot voxels do not
     * darken the image). Defaults 0 and 99.5; 0 <= low < high <= 100.
     * Percentiles come from a histogram of 65536 bins (deterministic); a
     * window that comes out empty (most values equal) widens to the full
     * range, and a constant image is 1 where it is above 0. */
    double low_percentile, high_percentile;
    /* STORED: where the box's minimum corner goes [m]; SCANNER: a shift
     * added to where the scanner puts it. Default (0, 0, 0). */
    ftm_vec3 origin;
    /* Factor on every length of the file (voxel size, and with SCANNER the
     * transform's offsets) after its units are converted to metres;
     * default 1. */
    double scale;
    ftm_volume_axes axes; /* default FTM_VOLUME_AXES_SCANNER */
} ftm_volume_load_def;

ftm_volume_load_def ftm_default_volume_load_def(void);

/* NIfTI-1 or NIfTI-2 single file (.nii or .nii.gz), read through libnifti
 * (where libftm was built without it, every file is refused saying so): a
 * 3D image (dim[0] 3, or 4 with dim[4] = 1) of uint8, int8, int16, uint16,
 * int32, uint32, float32 or float64, either byte order; scl_slope/scl_inter
 * applied; voxel size from pixdim[1..3] in the units xyzt_units gives (mm
 * when unset); placed on the axes def->axes says (the sform/qform applied
 * by default). A NaN or infinite value is an error naming the voxel. def
 * may be NULL (defaults). A file starting with the gzip magic is inflated
 * whatever its name; at most 2^28 voxels, and never more bytes read than
 * the header's voxels need. FTM_EIO, FTM_EPARSE, FTM_EINVAL, FTM_ENOMEM. */
int ftm_volume_load(const char *path, const ftm_volume_load_def *def, ftm_volume **out,
                    ftm_error *err);
/* The same from bytes in memory (an uncompressed .nii); name is used in
 * error messages. */
int ftm_volume_parse_nifti(const void *data, size_t size, const char *name,
                           const ftm_volume_load_def *def, ftm_volume **out, ftm_error *err);

/* A synthetic head for tests and demonstrations when no scan is at hand:
 * an ellipsoid of scalp (0.45) around a skull shell (1.0, bright as on CT),
 * brain (0.55) with two ventricles (0.2), in air (0). In units of half the
 * box's edge from its centre, with r the ellipsoidal radius for semi-axes
 * (0.70, 0.82, 0.86) (x across, y front to back, z up): scalp 0.92 < r <= 1,
 * skull 0.80 < r <= 0.92 (about 1 cm: thinner than a 10-point lattice's
 * cell), ventricles at (+-0.10, 0, 0.10) with semi-axes (0.05, 0.22, 0.10).
 * Each voxel takes the value at its centre. voxels at most 512. */
typedef struct ftm_volume_phantom_def {
    int32_t voxels;    /* per axis, >= 8; default 64 */
    double size;       /* edge of the cubic box [m]; default 0.2 */
    ftm_vec3 origin;   /* default (0, 0, 0) */
} ftm_volume_phantom_def;

ftm_volume_phantom_def ftm_default_volume_phantom_def(void);
int ftm_volume_phantom(const ftm_volume_phantom_def *def, ftm_volume **out, ftm_error *err);

void ftm_volume_destroy(ftm_volume *volume);

ftm_volume_info ftm_volume_get_info(const ftm_volume *volume);
/* nx * ny * nz intensities, 0..255, x fastest */
const uint8_t *ftm_volume_data(const ftm_volume *volume);
/* Trilinear intensity in [0, 1] at a point [m]; 0 outside the box. */
double ftm_volume_sample(const ftm_volume *volume, ftm_vec3 point);

/* The control lattice of a volume. */
typedef struct ftm_volume_lattice_def {
    int32_t nodes[3];           /* lattice points per axis, >= 2 each; default 10, 10, 10 */
    ftm_stencil stencil;        /* default FTM_STENCIL_18 */
    ftm_material_def material;  /* as for the cubic lattice */
    /* A point whose intensity (the mean of the image over the cube of half
     * a cell around it) is at least this is in hard tissue and fixed. Values
     * above 1 fix none. Default 0.9. */
    double hard_threshold;
    /* A cell whose intensities (sampled on a 5 x 5 x 5 grid over it) are all
     * below this holds only air and is left out, with the points that belong
     * to no other cell. 0 keeps the whole box. Default 0.05. */
    double air_threshold;
    uint32_t fixed_faces;       /* FTM_FACE_* of the box, fixed as well; default 0 */
    /* Moves each free point of the lattice's surface that lies in air
     * inward, along the mean inward normal of its outer faces, onto the
     * image's surface (the first sample at or above air_threshold), at most
     * 0.85 of a cell: the contact surface is then the tissue's (the scalp),
     * not the kept cells' hull up to a cell above it. Default false. */
    bool fit_surface;
} ftm_volume_lattice_def;

ftm_volume_lattice_def ftm_default_volume_lattice_def(void);

/* Fills a builder (created by the caller, empty) with the control lattice of
 * the volume: a node per kept lattice point, links of the stencil between
 * kept points of a kept cell, each kept cell a hexahedron (so the mesh's
 * surface is the kept cells' outer faces). point_input, when not NULL, has
 * room for nodes[0] * nodes[1] * nodes[2] entries and receives, for lattice
 * point (ix, iy, iz) at index ix + nodes[0] (iy + nodes[1] iz), its input
 * index in the builder, or -1 where the point was left out. FTM_EINVAL (a
 * parameter out of range, every cell air), FTM_ENOMEM. */
int ftm_generate_volume_lattice(ftm_mesh_builder *builder, const ftm_volume *volume,
                                const ftm_volume_lattice_def *def, int32_t *point_input,
                                ftm_error *err);

/* The embedding of a volume in its control lattice. */
typedef struct ftm_ffd ftm_ffd;

/* point_node: for each lattice point (indexed as above) its mesh node
 * (ftm_mesh_node_of_input of its input index), or -1. The lattice spans the
 * volume's box. Copies what it needs. FTM_EINVAL, FTM_ENOMEM. */
int ftm_ffd_create(const ftm_mesh *mesh, const ftm_volume *volume, const int32_t nodes[3],
                   const int32_t *point_node, ftm_ffd **out, ftm_error *err);
void ftm_ffd_destroy(ftm_ffd *ffd);

void ftm_ffd_nodes(const ftm_ffd *ffd, int32_t nodes[3]);
/* Rest position of lattice point (ix, iy, iz) [m]. */
ftm_vec3 ftm_ffd_point_rest(const ftm_ffd *ffd, int32_t ix, int32_t iy, int32_t iz);
/* Mesh node of a lattice point, or -1. */
int32_t ftm_ffd_point_node(const ftm_ffd *ffd, int32_t ix, int32_t iy, int32_t iz);
/* Deformed position of the rest point X, given the mesh's current node
 * positions (3 per node, as ftm_sim_positions). Points outside the box are
 * clamped to it for their weights. */
ftm_vec3 ftm_ffd_map(const ftm_ffd *ffd, const double *positions, ftm_vec3 rest);
/* Rest point whose deformed position is p, by fixed-point iteration
 * X <- p - u(X) from X = p (converges while the displacement's gradient
 * stays below 1); iterations <= 0 means 8. */
ftm_vec3 ftm_ffd_unmap(const ftm_ffd *ffd, const double *positions, ftm_vec3 p, int iterations);

#ifdef __cplusplus
}
#endif
#endif
