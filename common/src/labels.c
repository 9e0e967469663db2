/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Label maps (labels.h): NIfTI voxels as whole-number labels, through the
 * same reader as volumes (nifti.c). */
#include "ftm/labels.h"

#include "nifti.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct ftm_label_map {
    ftm_volume_info info;
    int32_t *labels;
    int axis[3];  /* the file's axis along each of the map's */
    bool flip[3]; /* running the other way */
};

ftm_label_map_def ftm_default_label_map_def(void)
{
    return (ftm_label_map_def){.axes = FTM_VOLUME_AXES_SCANNER,
                               .origin = {0, 0, 0},
                               .scale = 1.0,
                               .threshold = false,
                               .above = 0.0};
}

static int check_def(const ftm_label_map_def *d, const char *name, ftm_error *err)
{
    if (d->axes != FTM_VOLUME_AXES_SCANNER && d->axes != FTM_VOLUME_AXES_STORED)
        return ftm_error_set(err, FTM_EINVAL, "%s: axes must be FTM_VOLUME_AXES_SCANNER or "
                                              "_STORED (got %d)",
                             name, (int)d->axes);
    if (!(d->scale > 0.0) || !isfinite(d->scale))
        return ftm_error_set(err, FTM_EINVAL, "%s: scale must be > 0 and finite (got %g)", name,
                             d->scale);
    if (!isfinite(d->origin.x) || !isfinite(d->origin.y) || !isfinite(d->origin.z))
        return ftm_error_set(err, FTM_EINVAL, "%s: origin must be finite", name);
    if (d->threshold && !isfinite(d->above))
        return ftm_error_set(err, FTM_EINVAL, "%s: the threshold must be finite (got %g)", name,
                             d->above);
    return FTM_OK;
}

int ftm_label_map_parse_nifti(const void *data, size_t size, const char *name,
                              const ftm_label_map_def *def, ftm_label_map **out, ftm_error *err)
{
    if (!name)
        name = "(nifti)";
    if ((!data && size) || !out)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", name);
    *out = NULL;
    ftm_label_map_def dd = def ? *def : ftm_default_label_map_def();
    int rc = check_def(&dd, name, err);
    if (rc != FTM_OK)
        return rc;
    ftm_nifti h;
    if ((rc = ftm_nifti_header(data, size, size, name, &h, err)) != FTM_OK)
        return rc;
    if (h.needed > size)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: truncated voxel data: %lld x %lld x %lld voxels of %d bytes from "
                             "byte %llu need %llu bytes, the file has %zu",
                             name, (long long)h.n[0], (long long)h.n[1], (long long)h.n[2],
                             h.bytes, (unsigned long long)h.offset, (unsigned long long)h.needed,
                             size);
    ftm_nifti_grid g;
    rc = ftm_nifti_grid_of(&h, dd.axes == FTM_VOLUME_AXES_STORED ? FTM_NIFTI_AXES_STORED
                                                                  : FTM_NIFTI_AXES_SCANNER,
                           dd.scale, dd.origin, name, &g, err);
    if (rc != FTM_OK)
        return rc;
    const size_t count = (size_t)h.n[0] * (size_t)h.n[1] * (size_t)h.n[2];
    ftm_label_map *m = calloc(1, sizeof *m);
    if (m)
        m->labels = malloc(count * sizeof *m->labels);
    if (!m || !m->labels) {
        free(m);
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory for %zu labels", name, count);
    }
    const uint8_t *vox = (const uint8_t *)data + h.offset;
    size_t at = 0;
    for (int32_t z = 0; z < g.n[2]; z++)
        for (int32_t y = 0; y < g.n[1]; y++)
            for (int32_t x = 0; x < g.n[0]; x++) {
                size_t i = ftm_nifti_file_index(&h, &g, x, y, z);
                double raw = ftm_nifti_raw(&h, vox, i);
                double v = raw * h.slope + h.inter;
                bool ok = dd.threshold ? !isnan(v)
                                       : v == floor(v) && v >= INT32_MIN && v <= INT32_MAX;
                if (!ok) {
                    size_t nx = (size_t)h.n[0], ny = (size_t)h.n[1];
                    ftm_label_map_destroy(m);
                    return ftm_error_set(
                        err, FTM_EPARSE, "%s: voxel (%zu, %zu, %zu) at byte %llu is %g%s: %s",
                        name, i % nx, i / nx % ny, i / (nx * ny),
                        (unsigned long long)(h.offset + i * (size_t)h.bytes), v,
                        h.slope == 1.0 && h.inter == 0.0 ? "" : " after scl_slope/scl_inter",
                        dd.threshold ? "not a number"
                                     : "not a label (a label map holds whole numbers)");
                }
                m->labels[at++] = dd.threshold ? (v > dd.above ? 1 : 0) : (int32_t)v;
            }
    m->info = (ftm_volume_info){
        .nx = g.n[0], .ny = g.n[1], .nz = g.n[2], .spacing = g.spacing, .origin = g.origin};
    for (int a = 0; a < 3; a++) {
        m->axis[a] = g.axis[a];
        m->flip[a] = g.flip[a];
    }
    *out = m;
    return FTM_OK;
}

int ftm_label_map_load(const char *path, const ftm_label_map_def *def, ftm_label_map **out,
                       ftm_error *err)
{
    if (!path || !out)
        return ftm_error_set(err, FTM_EINVAL, "label map loader: null argument");
    *out = NULL;
    ftm_label_map_def dd = def ? *def : ftm_default_label_map_def();
    int rc = check_def(&dd, path, err);
    if (rc != FTM_OK)
        return rc;
    uint8_t *data = NULL;
    size_t size = 0;
    if ((rc = ftm_nifti_read(path, &data, &size, err)) != FTM_OK)
        return rc;
    rc = ftm_label_map_parse_nifti(data, size, path, &dd, out, err);
    free(data);
    return rc;
}

void ftm_label_map_destroy(ftm_label_map *map)
{
    if (!map)
        return;
    free(map->labels);
    free(map);
}

ftm_volume_info ftm_label_map_get_info(const ftm_label_map *map)
{
    return map->info;
}

const int32_t *ftm_label_map_data(const ftm_label_map *map)
{
    return map->labels;
}

int ftm_label_map_file_voxel(const ftm_label_map *map, int32_t x, int32_t y, int32_t z,
                             int32_t ijk[3])
{
    const int32_t c[3] = {x, y, z}, n[3] = {map->info.nx, map->info.ny, map->info.nz};
    for (int a = 0; a < 3; a++)
        if (c[a] < 0 || c[a] >= n[a])
            return FTM_ERANGE;
    for (int a = 0; a < 3; a++)
        ijk[map->axis[a]] = map->flip[a] ? n[a] - 1 - c[a] : c[a];
    return FTM_OK;
}

int32_t ftm_label_map_at(const ftm_label_map *map, ftm_vec3 point)
{
    const ftm_volume_info *in = &map->info;
    const double c[3] = {point.x, point.y, point.z};
    const double o[3] = {in->origin.x, in->origin.y, in->origin.z};
    const double s[3] = {in->spacing.x, in->spacing.y, in->spacing.z};
    const int64_t n[3] = {in->nx, in->ny, in->nz};
    int64_t idx[3];
    for (int a = 0; a < 3; a++) {
        double u = (c[a] - o[a]) / s[a];
        if (!(u >= 0.0 && u < (double)n[a]))
            return 0; /* outside the box, or NaN */
        idx[a] = (int64_t)u;
    }
    return map->labels[idx[0] + n[0] * (idx[1] + n[1] * idx[2])];
}
