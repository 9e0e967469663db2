/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Volumes: a scalar image of intensities 0..255 on a regular grid (volume.h).
 * Made by the synthetic head phantom or read from a NIfTI-1 file (.nii, and
 * .nii.gz with zlib). Files are untrusted: every header field is checked
 * before it sizes anything, and voxel data is only read where the file has
 * it, so a hostile header cannot make us allocate more than the file holds. */
#include "ftm/volume.h"

#include "error.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef FTM_HAVE_ZLIB
#include <zlib.h>
#endif

/* 2^28 voxels: 256 MiB of intensities, 2 GiB of float64 in the file. */
#define VOLUME_MAX_VOXELS ((int64_t)1 << 28)
#define PHANTOM_MAX_VOXELS 512
#define NIFTI_HEADER 348
#define NIFTI_MIN_OFFSET 352 /* header plus the 4-byte extension flag */
/* The largest file we read (or inflate to): the largest allowed image of
 * float64 after the largest offset we accept. */
#define NIFTI_MAX_OFFSET ((uint64_t)1 << 24)
#define NIFTI_MAX_BYTES ((uint64_t)VOLUME_MAX_VOXELS * 8 + NIFTI_MAX_OFFSET)
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

/* ------------------------------------------------------------ NIfTI-1 */

ftm_volume_load_def ftm_default_volume_load_def(void)
{
    return (ftm_volume_load_def){
        .low_percentile = 0.0, .high_percentile = 99.5, .origin = {0, 0, 0}, .scale = 1.0};
}

typedef struct nifti {
    bool swap;            /* the file's byte order is not ours */
    int32_t n[3];         /* dim[1..3] */
    int16_t datatype;
    int bytes;            /* per voxel */
    double pixdim[3];     /* pixdim[1..3], in the file's units */
    double unit;          /* metres per file unit */
    double slope, inter;  /* scl_slope, scl_inter as applied */
    uint64_t offset;      /* vox_offset */
    uint64_t needed;      /* offset + voxel bytes: the file's least size */
} nifti;

static uint16_t rd16(const uint8_t *p, bool swap)
{
    uint16_t v;
    memcpy(&v, p, 2);
    return swap ? (uint16_t)(v >> 8 | v << 8) : v;
}

static uint32_t rd32(const uint8_t *p, bool swap)
{
    uint32_t v;
    memcpy(&v, p, 4);
    return swap ? __builtin_bswap32(v) : v;
}

static uint64_t rd64(const uint8_t *p, bool swap)
{
    uint64_t v;
    memcpy(&v, p, 8);
    return swap ? __builtin_bswap64(v) : v;
}

static double rdf32(const uint8_t *p, bool swap)
{
    uint32_t u = rd32(p, swap);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* Voxel value as stored (before scl_slope/scl_inter). */
static double voxel_value(const uint8_t *p, int16_t datatype, bool swap)
{
    switch (datatype) {
    case 2: return p[0];
    case 256: return (int8_t)p[0];
    case 4: return (int16_t)rd16(p, swap);
    case 512: return rd16(p, swap);
    case 8: return (int32_t)rd32(p, swap);
    case 16: return rdf32(p, swap);
    default: { /* 64: float64 */
        uint64_t u = rd64(p, swap);
        double d;
        memcpy(&d, &u, 8);
        return d;
    }
    }
}

/* Checks the header of a file of file_size bytes (UINT64_MAX: not known yet,
 * while a .gz is being inflated). */
static int nifti_header(const uint8_t *d, size_t size, uint64_t file_size, const char *name,
                        nifti *h, ftm_error *err)
{
    if (size < NIFTI_HEADER)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: truncated header: %zu bytes, a NIfTI-1 header has %d", name,
                             size, NIFTI_HEADER);
    memset(h, 0, sizeof *h);
    uint32_t sz = rd32(d, false);
    if (sz != NIFTI_HEADER) {
        if (__builtin_bswap32(sz) != NIFTI_HEADER)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field sizeof_hdr = %d at byte 0 (expected 348 in "
                                 "either byte order: not a NIfTI-1 file)",
                                 name, (int)(int32_t)sz);
        h->swap = true;
    }
    const bool sw = h->swap;
    if (memcmp(d + 344, "ni1\0", 4) == 0)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field magic at byte 344 is \"ni1\": the header of a "
                             ".hdr/.img pair; only single-file .nii (magic \"n+1\") is supported",
                             name);
    if (memcmp(d + 344, "n+1\0", 4) != 0)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field magic at byte 344 is not \"n+1\" (bytes %02x %02x "
                             "%02x %02x)",
                             name, d[344], d[345], d[346], d[347]);
    int16_t dim[8];
    for (int i = 0; i < 8; i++)
        dim[i] = (int16_t)rd16(d + 40 + 2 * i, sw);
    if (!(dim[0] == 3 || (dim[0] == 4 && dim[4] == 1)))
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field dim[0] = %d%s (a 3D image: 3, or 4 with dim[4] = "
                             "1)",
                             name, dim[0], dim[0] == 4 ? " with dim[4] != 1" : "");
    for (int i = 1; i <= 3; i++)
        if (dim[i] < 1)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field dim[%d] = %d (each of dim[1..3] must be >= 1)",
                                 name, i, dim[i]);
    int64_t count = (int64_t)dim[1] * dim[2] * dim[3];
    if (count > VOLUME_MAX_VOXELS)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field dim[1..3] = %d x %d x %d = %lld voxels, more than "
                             "the limit of %lld",
                             name, dim[1], dim[2], dim[3], (long long)count,
                             (long long)VOLUME_MAX_VOXELS);
    h->datatype = (int16_t)rd16(d + 70, sw);
    int16_t bitpix = (int16_t)rd16(d + 72, sw);
    int bits;
    const char *type;
    switch (h->datatype) {
    case 2: bits = 8, type = "uint8"; break;
    case 256: bits = 8, type = "int8"; break;
    case 4: bits = 16, type = "int16"; break;
    case 512: bits = 16, type = "uint16"; break;
    case 8: bits = 32, type = "int32"; break;
    case 16: bits = 32, type = "float32"; break;
    case 64: bits = 64, type = "float64"; break;
    default:
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field datatype = %d (supported: 2 uint8, 4 int16, 8 "
                             "int32, 16 float32, 64 float64, 256 int8, 512 uint16)",
                             name, h->datatype);
    }
    if (bitpix != bits)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field bitpix = %d does not match datatype %d (%s: %d)",
                             name, bitpix, h->datatype, type, bits);
    h->bytes = bits / 8;
    for (int i = 1; i <= 3; i++) {
        double p = rdf32(d + 76 + 4 * i, sw);
        if (!(p > 0.0) || !isfinite(p))
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field pixdim[%d] = %g (a voxel size must be > 0 "
                                 "and finite)",
                                 name, i, p);
        h->pixdim[i - 1] = p;
    }
    double off = rdf32(d + 108, sw);
    if (!(off >= NIFTI_MIN_OFFSET) || !(off <= (double)NIFTI_MAX_OFFSET) || off != floor(off))
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field vox_offset = %g (must be a whole number of bytes, "
                             "%d .. %llu, in a single-file .nii)",
                             name, off, NIFTI_MIN_OFFSET, (unsigned long long)NIFTI_MAX_OFFSET);
    h->offset = (uint64_t)off;
    if (file_size != UINT64_MAX && h->offset > file_size)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field vox_offset = %llu is past the end of the file "
                             "(%llu bytes)",
                             name, (unsigned long long)h->offset, (unsigned long long)file_size);
    double slope = rdf32(d + 112, sw), inter = rdf32(d + 116, sw);
    if (slope == 0.0 || !isfinite(slope)) { /* the standard: no scaling */
        h->slope = 1.0;
        h->inter = 0.0;
    } else {
        if (!isfinite(inter))
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field scl_inter = %g is not finite (scl_slope = %g)",
                                 name, inter, slope);
        h->slope = slope;
        h->inter = inter;
    }
    int units = d[123] & 7;
    static const double metres[4] = {1e-3, 1.0, 1e-3, 1e-6}; /* unknown = mm */
    if (units > 3)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field xyzt_units = %d: unknown spatial unit %d "
                             "(0 unset, 1 m, 2 mm, 3 micron)",
                             name, d[123], units);
    h->unit = metres[units];
    for (int i = 0; i < 3; i++)
        h->n[i] = dim[i + 1];
    h->needed = h->offset + (uint64_t)count * (uint64_t)h->bytes;
    return FTM_OK;
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
    return FTM_OK;
}

int ftm_volume_parse_nifti(const void *data, size_t size, const char *name,
                           const ftm_volume_load_def *def, ftm_volume **out, ftm_error *err)
{
    if (!name)
        name = "(nifti)";
    if ((!data && size) || !out)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", name);
    ftm_volume_load_def dd = def ? *def : ftm_default_volume_load_def();
    int rc = check_load_def(&dd, name, err);
    if (rc)
        return rc;
    const uint8_t *d = data;
    nifti h;
    if ((rc = nifti_header(d, size, size, name, &h, err)) != FTM_OK)
        return rc;
    if (h.needed > size)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: truncated voxel data: %d x %d x %d voxels of %d bytes from "
                             "byte %llu need %llu bytes, the file has %zu",
                             name, (int)h.n[0], (int)h.n[1], (int)h.n[2], h.bytes,
                             (unsigned long long)h.offset, (unsigned long long)h.needed, size);
    ftm_vec3 sp = {h.pixdim[0] * h.unit * dd.scale, h.pixdim[1] * h.unit * dd.scale,
                   h.pixdim[2] * h.unit * dd.scale};
    if (!(sp.x > 0 && sp.y > 0 && sp.z > 0) || !finite_vec(sp) ||
        !isfinite(dd.origin.x + h.n[0] * sp.x) || !isfinite(dd.origin.y + h.n[1] * sp.y) ||
        !isfinite(dd.origin.z + h.n[2] * sp.z))
        return ftm_error_set(err, FTM_EINVAL,
                             "%s: voxel size %g x %g x %g m (pixdim[1..3] times scale %g) is "
                             "zero or not finite in double precision",
                             name, sp.x, sp.y, sp.z, dd.scale);
    const size_t count = (size_t)h.n[0] * (size_t)h.n[1] * (size_t)h.n[2];
    const uint8_t *vox = d + h.offset;
    /* pass 1: every value finite, and their range */
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < count; i++) {
        double raw = voxel_value(vox + i * h.bytes, h.datatype, h.swap);
        double v = raw * h.slope + h.inter;
        if (!isfinite(v)) {
            size_t nx = (size_t)h.n[0], ny = (size_t)h.n[1];
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: voxel (%zu, %zu, %zu) at byte %llu is %s%s", name, i % nx,
                                 i / nx % ny, i / (nx * ny),
                                 (unsigned long long)(h.offset + i * h.bytes),
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
            double v = voxel_value(vox + i * h.bytes, h.datatype, h.swap) * h.slope + h.inter;
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
    if ((rc = volume_new(h.n[0], h.n[1], h.n[2], sp, dd.origin, name, &v, err)) != FTM_OK)
        return rc;
    /* pass 3: intensities; a constant image is 1 where it is above 0 */
    for (size_t i = 0; i < count; i++) {
        double x = voxel_value(vox + i * h.bytes, h.datatype, h.swap) * h.slope + h.inter;
        double t = whi > wlo ? (x - wlo) / (whi - wlo) : x > 0.0 ? 1.0 : 0.0;
        t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
        v->data[i] = (uint8_t)floor(t * 255.0 + 0.5);
    }
    *out = v;
    return FTM_OK;
}

/* Reads a whole file of at most NIFTI_MAX_BYTES. */
static int read_file(const char *path, uint8_t **data, size_t *size, ftm_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return ftm_error_set(err, FTM_EIO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = 1 << 16, n = 0;
    uint8_t *buf = malloc(cap);
    int rc = buf ? FTM_OK : FTM_ENOMEM;
    while (rc == FTM_OK) {
        if (n == cap) {
            if ((uint64_t)cap > NIFTI_MAX_BYTES) {
                rc = ftm_error_set(err, FTM_EPARSE, "%s: file larger than %llu bytes", path,
                                   (unsigned long long)NIFTI_MAX_BYTES);
                break;
            }
            /* one byte past the limit tells a file over it */
            size_t ncap =
                (uint64_t)cap * 2 > NIFTI_MAX_BYTES ? (size_t)NIFTI_MAX_BYTES + 1 : cap * 2;
            uint8_t *nb = realloc(buf, ncap);
            if (!nb) {
                rc = FTM_ENOMEM;
                break;
            }
            buf = nb;
            cap = ncap;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f))
                rc = ftm_error_set(err, FTM_EIO, "%s: read error at byte %zu", path, n);
            break;
        }
    }
    fclose(f);
    if (rc == FTM_ENOMEM)
        rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory reading the file", path);
    if (rc) {
        free(buf);
        return rc;
    }
    *data = buf;
    *size = n;
    return FTM_OK;
}

#ifdef FTM_HAVE_ZLIB
/* Inflates a gzip file, stopping where the header says the voxel data
 * ends, so a small .gz cannot inflate to more than its header declares. */
static int gunzip(const char *path, const uint8_t *in, size_t in_size, uint8_t **out,
                  size_t *out_size, ftm_error *err)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit2(&z, 16 + MAX_WBITS) != Z_OK)
        return ftm_error_set(err, FTM_ENOMEM, "%s: cannot start zlib", path);
    uint64_t limit = NIFTI_MAX_BYTES;
    size_t cap = 1 << 16, n = 0;
    uint8_t *buf = malloc(cap);
    int rc = buf ? FTM_OK : ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    bool header_seen = false;
    z.next_in = (Bytef *)in;
    size_t left = in_size;
    while (rc == FTM_OK && n < limit) {
        if (n == cap) {
            size_t ncap = (uint64_t)cap * 2 > limit ? (size_t)limit : cap * 2;
            uint8_t *nb = realloc(buf, ncap);
            if (!nb) {
                rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory inflating", path);
                break;
            }
            buf = nb;
            cap = ncap;
        }
        uInt chunk_in = left > (1u << 30) ? (1u << 30) : (uInt)left;
        size_t room = cap - n;
        if ((uint64_t)room > limit - n)
            room = (size_t)(limit - n);
        uInt chunk_out = room > (1u << 30) ? (1u << 30) : (uInt)room;
        z.avail_in = chunk_in;
        z.next_out = buf + n;
        z.avail_out = chunk_out;
        int zr = inflate(&z, Z_NO_FLUSH);
        left -= chunk_in - z.avail_in;
        n += chunk_out - z.avail_out;
        if (!header_seen && n >= NIFTI_HEADER) {
            nifti h;
            header_seen = true;
            if ((rc = nifti_header(buf, n, UINT64_MAX, path, &h, err)) != FTM_OK)
                break;
            limit = h.needed; /* trailing bytes past the voxels are not needed */
        }
        if (zr == Z_STREAM_END) {
            if (left == 0)
                break;
            inflateReset(&z); /* another gzip member follows */
            continue;
        }
        if (zr == Z_BUF_ERROR && left == 0)
            break; /* the stream ends early: the parser reports the truncation */
        if (zr != Z_OK && zr != Z_BUF_ERROR)
            rc = ftm_error_set(err, FTM_EPARSE, "%s: gzip data corrupt at compressed byte %zu: %s",
                               path, in_size - left, z.msg ? z.msg : "inflate failed");
    }
    inflateEnd(&z);
    if (rc) {
        free(buf);
        return rc;
    }
    *out = buf;
    *out_size = n;
    return FTM_OK;
}
#endif

int ftm_volume_load(const char *path, const ftm_volume_load_def *def, ftm_volume **out,
                    ftm_error *err)
{
    if (!path || !out)
        return ftm_error_set(err, FTM_EINVAL, "volume loader: null argument");
    ftm_volume_load_def dd = def ? *def : ftm_default_volume_load_def();
    int rc = check_load_def(&dd, path, err);
    if (rc)
        return rc;
    uint8_t *data = NULL;
    size_t size = 0;
    if ((rc = read_file(path, &data, &size, err)) != FTM_OK)
        return rc;
    if (size >= 2 && data[0] == 0x1f && data[1] == 0x8b) { /* gzip, whatever the name */
#ifdef FTM_HAVE_ZLIB
        uint8_t *raw = NULL;
        size_t raw_size = 0;
        rc = gunzip(path, data, size, &raw, &raw_size, err);
        free(data);
        if (rc)
            return rc;
        data = raw;
        size = raw_size;
#else
        free(data);
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: gzip-compressed (.nii.gz), but this libftm was built without "
                             "zlib: decompress it (gunzip) first",
                             path);
#endif
    }
    rc = ftm_volume_parse_nifti(data, size, path, &dd, out, err);
    free(data);
    return rc;
}
