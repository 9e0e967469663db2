/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Volumes: a scalar image of intensities 0..255 on a regular grid (volume.h).
 * Made by the synthetic head phantom or read from a NIfTI file (nifti.c:
 * libnifti, with our bounds and messages in front). */
#include "ftm/volume.h"

#include "error.h"
#include "nifti.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PHANTOM_MAX_VOXELS 512
#define HISTOGRAM_BINS 65536

struct ftm_volume {
    ftm_volume_info info;
    uint8_t *data;
};

static bool finite_vec(ftm_vec3 v)
{
    return isfinite(v.x) && isfinite(v.y) && isfinite(v.z);
}

static int volume_new(int32_t nx, int32_t ny, int32_t nz, ftm_vec3 spacing, ftm_vec3 origin,
                      const char *who, ftm_volume **out, ftm_error *err)
{
    ftm_volume *v = calloc(1, sizeof *v);
    size_t n = (size_t)nx * (size_t)ny * (size_t)nz;
    if (v)
        v->data = calloc(n, 1);
    if (!v || !v->data) {
        free(v);
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory for %zu voxels", who, n);
    }
    v->info = (ftm_volume_info){.nx = nx, .ny = ny, .nz = nz, .spacing = spacing, .origin = origin};
    *out = v;
    return FTM_OK;
}

void ftm_volume_destroy(ftm_volume *volume)
{
    if (!volume)
        return;
    free(volume->data);
    free(volume);
}

ftm_volume_info ftm_volume_get_info(const ftm_volume *volume)
{
    return volume->info;
}

const uint8_t *ftm_volume_data(const ftm_volume *volume)
{
    return volume->data;
}

double ftm_volume_sample(const ftm_volume *v, ftm_vec3 point)
{
    const double c[3] = {point.x, point.y, point.z};
    const double o[3] = {v->info.origin.x, v->info.origin.y, v->info.origin.z};
    const double s[3] = {v->info.spacing.x, v->info.spacing.y, v->info.spacing.z};
    const int64_t n[3] = {v->info.nx, v->info.ny, v->info.nz};
    int64_t i0[3], i1[3];
    double f[3];
    for (int a = 0; a < 3; a++) {
        if (!(c[a] >= o[a] && c[a] <= o[a] + (double)n[a] * s[a]))
            return 0.0; /* outside the box (or NaN) */
        /* voxel centres sit at integers; the half voxel at the box's faces
         * takes the edge voxel's value (indices clamped) */
        double u = (c[a] - o[a]) / s[a] - 0.5, fl = floor(u);
        f[a] = u - fl;
        i0[a] = (int64_t)fl;
        i1[a] = i0[a] + 1;
        i0[a] = i0[a] < 0 ? 0 : i0[a] > n[a] - 1 ? n[a] - 1 : i0[a];
        i1[a] = i1[a] < 0 ? 0 : i1[a] > n[a] - 1 ? n[a] - 1 : i1[a];
    }
    const uint8_t *d = v->data;
    double val[2][2]; /* [z][y], interpolated along x */
    for (int z = 0; z < 2; z++)
        for (int y = 0; y < 2; y++) {
            int64_t row = n[0] * ((y ? i1[1] : i0[1]) + n[1] * (z ? i1[2] : i0[2]));
            val[z][y] = (1.0 - f[0]) * d[row + i0[0]] + f[0] * d[row + i1[0]];
        }
    double lo = (1.0 - f[1]) * val[0][0] + f[1] * val[0][1];
    double hi = (1.0 - f[1]) * val[1][0] + f[1] * val[1][1];
    return ((1.0 - f[2]) * lo + f[2] * hi) / 255.0;
}

/* ------------------------------------------------------------ phantom */

ftm_volume_phantom_def ftm_default_volume_phantom_def(void)
{
    return (ftm_volume_phantom_def){.voxels = 64, .size = 0.2, .origin = {0, 0, 0}};
}

/* Intensity 0..255 of the phantom at a point in units of the box's half
 * edge from its centre: an ellipsoidal head whose scalp is the shell
 * 0.92 < r <= 1, skull 0.80 < r <= 0.92, brain inside, r the ellipsoidal
 * radius for semi-axes (0.70, 0.82, 0.86) (x across, y front to back, z up);
 * two ventricles at (+-0.10, 0, 0.10) with semi-axes (0.05, 0.22, 0.10). */
static uint8_t phantom_value(double x, double y, double z)
{
    double r2 = (x / 0.70) * (x / 0.70) + (y / 0.82) * (y / 0.82) + (z / 0.86) * (z / 0.86);
    if (r2 > 1.0)
        return 0; /* air */
    if (r2 > 0.92 * 0.92)
        return 115; /* scalp, 0.45 */
    if (r2 > 0.80 * 0.80)
        return 255; /* skull, 1.0 */
    for (int side = -1; side <= 1; side += 2) {
        double dx = (x - side * 0.10) / 0.05, dy = y / 0.22, dz = (z - 0.10) / 0.10;
        if (dx * dx + dy * dy + dz * dz <= 1.0)
            return 51; /* ventricle, 0.2 */
    }
    return 140; /* brain, 0.55 */
}

int ftm_volume_phantom(const ftm_volume_phantom_def *def, ftm_volume **out, ftm_error *err)
{
    const char *who = "phantom";
    if (!def || !out)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", who);
    if (def->voxels < 8 || def->voxels > PHANTOM_MAX_VOXELS)
        return ftm_error_set(err, FTM_EINVAL, "%s: voxels must be 8..%d (got %d)", who,
                             PHANTOM_MAX_VOXELS, (int)def->voxels);
    if (!(def->size > 0.0) || !isfinite(def->size) || !(def->size / def->voxels > 0.0))
        return ftm_error_set(err, FTM_EINVAL, "%s: size must be > 0 and finite (got %g)", who,
                             def->size);
    if (!finite_vec(def->origin) || !isfinite(def->origin.x + def->size) ||
        !isfinite(def->origin.y + def->size) || !isfinite(def->origin.z + def->size))
        return ftm_error_set(err, FTM_EINVAL, "%s: origin must be finite", who);
    const int32_t n = def->voxels;
    const double s = def->size / n;
    ftm_volume *v = NULL;
    int rc = volume_new(n, n, n, (ftm_vec3){s, s, s}, def->origin, who, &v, err);
    if (rc)
        return rc;
    /* voxel centres in units of the half edge, from the box's centre */
    for (int32_t k = 0; k < n; k++)
        for (int32_t j = 0; j < n; j++)
            for (int32_t i = 0; i < n; i++)
                v->data[i + (size_t)n * (j + (size_t)n * k)] =
                    phantom_value((2.0 * i + 1.0) / n - 1.0, (2.0 * j + 1.0) / n - 1.0,
                                  (2.0 * k + 1.0) / n - 1.0);
    *out = v;
    return FTM_OK;
}

/* ------------------------------------------------------------ NIfTI */

ftm_volume_load_def ftm_default_volume_load_def(void)
{
    return (ftm_volume_load_def){.low_percentile = 0.0,
                                 .high_percentile = 99.5,
                                 .origin = {0, 0, 0},
                                 .scale = 1.0,
                                 .axes = FTM_VOLUME_AXES_SCANNER};
}

/* Value at fraction q (0..1) of the sorted values, from a histogram of
 * HISTOGRAM_BINS bins over [lo, hi], linear inside a bin. */
static double histogram_percentile(const uint64_t *bins, uint64_t count, double lo, double hi,
                                   double q)
{
    if (q <= 0.0)
        return lo;
    if (q >= 1.0)
        return hi;
    double target = q * (double)count, width = (hi - lo) / HISTOGRAM_BINS;
    uint64_t before = 0;
    for (int b = 0; b < HISTOGRAM_BINS; b++) {
        if (bins[b] && (double)(before + bins[b]) >= target) {
            double v = lo + width * (b + (target - (double)before) / (double)bins[b]);
            return v < lo ? lo : v > hi ? hi : v;
        }
        before += bins[b];
    }
    return hi;
}

static int check_load_def(const ftm_volume_load_def *d, const char *name, ftm_error *err)
{
    if (!(d->low_percentile >= 0.0) || !(d->low_percentile < d->high_percentile) ||
        !(d->high_percentile <= 100.0))
        return ftm_error_set(err, FTM_EINVAL,
                             "%s: percentile window %g .. %g (need 0 <= low < high <= 100)", name,
                             d->low_percentile, d->high_percentile);
    if (!(d->scale > 0.0) || !isfinite(d->scale))
        return ftm_error_set(err, FTM_EINVAL, "%s: scale must be > 0 and finite (got %g)", name,
                             d->scale);
    if (!finite_vec(d->origin))
        return ftm_error_set(err, FTM_EINVAL, "%s: origin must be finite", name);
    if (d->axes != FTM_VOLUME_AXES_SCANNER && d->axes != FTM_VOLUME_AXES_STORED)
        return ftm_error_set(err, FTM_EINVAL, "%s: axes must be FTM_VOLUME_AXES_SCANNER or "
                                              "_STORED (got %d)",
                             name, (int)d->axes);
    return FTM_OK;
}

int ftm_volume_parse_nifti(const void *data, size_t size, const char *name,
                           const ftm_volume_load_def *def, ftm_volume **out, ftm_error *err)
{
    if (!name)
        name = "(nifti)";
    if ((!data && size) || !out)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", name);
    *out = NULL;
    ftm_volume_load_def dd = def ? *def : ftm_default_volume_load_def();
    int rc = check_load_def(&dd, name, err);
    if (rc)
        return rc;
    const uint8_t *d = data;
    ftm_nifti h;
    if ((rc = ftm_nifti_header(d, size, size, name, &h, err)) != FTM_OK)
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
    const uint8_t *vox = d + h.offset;
    /* pass 1: every value finite, and their range */
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < count; i++) {
        double raw = ftm_nifti_raw(&h, vox, i);
        double v = raw * h.slope + h.inter;
        if (!isfinite(v)) {
            size_t nx = (size_t)h.n[0], ny = (size_t)h.n[1];
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: voxel (%zu, %zu, %zu) at byte %llu is %s%s", name, i % nx,
                                 i / nx % ny, i / (nx * ny),
                                 (unsigned long long)(h.offset + i * (size_t)h.bytes),
                                 isnan(v) ? "NaN" : "infinite",
                                 isfinite(raw) ? " after scl_slope/scl_inter" : "");
        }
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
    }
    /* pass 2: the percentile window, from a histogram (bounded memory) */
    double wlo = lo, whi = hi;
    if (hi > lo) {
        uint64_t *bins = calloc(HISTOGRAM_BINS, sizeof *bins);
        if (!bins)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", name);
        for (size_t i = 0; i < count; i++) {
            double v = ftm_nifti_raw(&h, vox, i) * h.slope + h.inter;
            double t = (v - lo) / (hi - lo) * HISTOGRAM_BINS;
            int b = t >= HISTOGRAM_BINS ? HISTOGRAM_BINS - 1 : (int)t;
            bins[b < 0 ? 0 : b]++;
        }
        wlo = histogram_percentile(bins, count, lo, hi, dd.low_percentile / 100.0);
        whi = histogram_percentile(bins, count, lo, hi, dd.high_percentile / 100.0);
        free(bins);
        if (!(whi > wlo)) { /* most values equal: the window would be empty */
            wlo = lo;
            whi = hi;
        }
    }
    ftm_volume *v = NULL;
    if ((rc = volume_new(g.n[0], g.n[1], g.n[2], g.spacing, g.origin, name, &v, err)) != FTM_OK)
        return rc;
    /* pass 3: intensities, onto the grid's axes; a constant image is 1
     * where it is above 0 */
    size_t out_i = 0;
    for (int32_t z = 0; z < g.n[2]; z++)
        for (int32_t y = 0; y < g.n[1]; y++)
            for (int32_t x = 0; x < g.n[0]; x++) {
                size_t i = ftm_nifti_file_index(&h, &g, x, y, z);
                double val = ftm_nifti_raw(&h, vox, i) * h.slope + h.inter;
                double t = whi > wlo ? (val - wlo) / (whi - wlo) : val > 0.0 ? 1.0 : 0.0;
                t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
                v->data[out_i++] = (uint8_t)floor(t * 255.0 + 0.5);
            }
    *out = v;
    return FTM_OK;
}

int ftm_volume_load(const char *path, const ftm_volume_load_def *def, ftm_volume **out,
                    ftm_error *err)
{
    if (!path || !out)
        return ftm_error_set(err, FTM_EINVAL, "volume loader: null argument");
    *out = NULL;
    ftm_volume_load_def dd = def ? *def : ftm_default_volume_load_def();
    int rc = check_load_def(&dd, path, err);
    if (rc)
        return rc;
    uint8_t *data = NULL;
    size_t size = 0;
    if ((rc = ftm_nifti_read(path, &data, &size, err)) != FTM_OK)
        return rc;
    rc = ftm_volume_parse_nifti(data, size, path, &dd, out, err);
    free(data);
    return rc;
}
