/* SPDX-License-Identifier: GPL-3.0-or-later */
/* NIfTI-1 and NIfTI-2 single files through libnifti (nifti.h). */
#include "nifti.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef FTM_HAVE_NIFTI
/* znzlib's file struct holds the gzFile only when HAVE_ZLIB is defined: the
 * library is built with it (it reads .nii.gz), so its header must say so to
 * give the struct its layout, and we reach the gzFile for gzerror. */
#define HAVE_ZLIB 1
#include <nifti2_io.h>
#include <zlib.h>
#endif

/* The largest vox_offset we accept. */
#define NIFTI_MAX_OFFSET ((uint64_t)1 << 24)
/* An axis more than this (radians, 0.06 degrees) off the nearest world axis
 * makes a transform oblique. */
#define OBLIQUE_TOLERANCE 1e-3

#ifdef FTM_HAVE_NIFTI

/* The fields we use, from either version, in host byte order. */
typedef struct any_header {
    int version;
    size_t size, magic_at;
    const char *magic; /* 4 (NIfTI-1) or 8 (NIfTI-2) bytes */
    int64_t dim[8];
    int datatype, bitpix;
    double pixdim[8];
    double vox_offset;
    double slope, inter;
    int units;
    int qform_code, sform_code;
    double quatern[3], qoffset[3];
    double srow[3][4];
} any_header;

/* 348 or 540 in either byte order; 0 for neither. */
static int header_version(const uint8_t *d, size_t size, bool *swap)
{
    if (size < 4)
        return 0;
    int32_t s;
    memcpy(&s, d, 4);
    *swap = false;
    if (s == 348 || s == 540)
        return s == 348 ? 1 : 2;
    s = (int32_t)__builtin_bswap32((uint32_t)s);
    *swap = true;
    return s == 348 ? 1 : s == 540 ? 2 : 0;
}

static void from_n1(const nifti_1_header *n, any_header *a)
{
    a->version = 1;
    a->size = sizeof *n;
    a->magic_at = offsetof(nifti_1_header, magic);
    for (int i = 0; i < 8; i++) {
        a->dim[i] = n->dim[i];
        a->pixdim[i] = n->pixdim[i];
    }
    a->datatype = n->datatype;
    a->bitpix = n->bitpix;
    a->vox_offset = n->vox_offset;
    a->slope = n->scl_slope;
    a->inter = n->scl_inter;
    a->units = (unsigned char)n->xyzt_units;
    a->qform_code = n->qform_code;
    a->sform_code = n->sform_code;
    a->quatern[0] = n->quatern_b, a->quatern[1] = n->quatern_c, a->quatern[2] = n->quatern_d;
    a->qoffset[0] = n->qoffset_x, a->qoffset[1] = n->qoffset_y, a->qoffset[2] = n->qoffset_z;
    for (int c = 0; c < 4; c++) {
        a->srow[0][c] = n->srow_x[c];
        a->srow[1][c] = n->srow_y[c];
        a->srow[2][c] = n->srow_z[c];
    }
}

static void from_n2(const nifti_2_header *n, any_header *a)
{
    a->version = 2;
    a->size = sizeof *n;
    a->magic_at = offsetof(nifti_2_header, magic);
    for (int i = 0; i < 8; i++) {
        a->dim[i] = n->dim[i];
        a->pixdim[i] = n->pixdim[i];
    }
    a->datatype = n->datatype;
    a->bitpix = n->bitpix;
    a->vox_offset = (double)n->vox_offset;
    a->slope = n->scl_slope;
    a->inter = n->scl_inter;
    a->units = n->xyzt_units;
    a->qform_code = n->qform_code;
    a->sform_code = n->sform_code;
    a->quatern[0] = n->quatern_b, a->quatern[1] = n->quatern_c, a->quatern[2] = n->quatern_d;
    a->qoffset[0] = n->qoffset_x, a->qoffset[1] = n->qoffset_y, a->qoffset[2] = n->qoffset_z;
    for (int c = 0; c < 4; c++) {
        a->srow[0][c] = n->srow_x[c];
        a->srow[1][c] = n->srow_y[c];
        a->srow[2][c] = n->srow_z[c];
    }
}

/* The datatypes we read: integers and reals of one component. */
static bool supported_type(int datatype)
{
    switch (datatype) {
    case NIFTI_TYPE_UINT8:
    case NIFTI_TYPE_INT8:
    case NIFTI_TYPE_INT16:
    case NIFTI_TYPE_UINT16:
    case NIFTI_TYPE_INT32:
    case NIFTI_TYPE_UINT32:
    case NIFTI_TYPE_FLOAT32:
    case NIFTI_TYPE_FLOAT64:
        return true;
    default:
        return false;
    }
}

int ftm_nifti_header(const uint8_t *d, size_t size, uint64_t file_size, const char *name,
                     ftm_nifti *h, ftm_error *err)
{
    memset(h, 0, sizeof *h);
    bool swap = false;
    int version = header_version(d, size, &swap);
    if (size < 4 || (version == 1 && size < sizeof(nifti_1_header)) ||
        (version == 2 && size < sizeof(nifti_2_header)))
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: truncated header: %zu bytes, a NIfTI-%d header has %zu", name,
                             size, version == 2 ? 2 : 1,
                             version == 2 ? sizeof(nifti_2_header) : sizeof(nifti_1_header));
    if (version == 0) {
        int32_t s;
        memcpy(&s, d, 4);
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field sizeof_hdr = %d at byte 0 (expected 348 or 540 "
                             "in either byte order: not a NIfTI-1 or NIfTI-2 file)",
                             name, (int)s);
    }
    any_header a;
    if (version == 1) {
        nifti_1_header n;
        memcpy(&n, d, sizeof n);
        if (swap)
            swap_nifti_header(&n, 1);
        from_n1(&n, &a);
    } else {
        nifti_2_header n;
        memcpy(&n, d, sizeof n);
        if (swap)
            swap_nifti_header(&n, 2);
        from_n2(&n, &a);
    }
    const uint8_t *m = d + a.magic_at;
    /* "n+1\0" / "n+2\0\r\n\032\n": one file; "ni1" / "ni2": a .hdr/.img pair */
    static const uint8_t tail2[4] = {'\r', '\n', 032, '\n'};
    bool single = m[0] == 'n' && m[1] == '+' && m[2] == '0' + version && m[3] == 0 &&
                  (version == 1 || memcmp(m + 4, tail2, 4) == 0);
    if (m[0] == 'n' && m[1] == 'i' && m[2] == '0' + version && m[3] == 0)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field magic at byte %zu is \"ni%d\": the header of a "
                             ".hdr/.img pair; only single-file .nii (magic \"n+%d\") is supported",
                             name, a.magic_at, version, version);
    if (!single)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field magic at byte %zu is not \"n+%d\" (bytes %02x %02x "
                             "%02x %02x)",
                             name, a.magic_at, version, m[0], m[1], m[2], m[3]);
    h->version = version;
    h->swap = swap;
    const int64_t *dim = a.dim;
    if (!(dim[0] == 3 || (dim[0] == 4 && dim[4] == 1)))
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field dim[0] = %lld%s (a 3D image: 3, or 4 with dim[4] = "
                             "1)",
                             name, (long long)dim[0], dim[0] == 4 ? " with dim[4] != 1" : "");
    for (int i = 1; i <= 3; i++)
        if (dim[i] < 1)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field dim[%d] = %lld (each of dim[1..3] must be >= 1)",
                                 name, i, (long long)dim[i]);
    /* each factor below 2^28 before the product, so it cannot overflow */
    if (dim[1] > FTM_NIFTI_MAX_VOXELS || dim[2] > FTM_NIFTI_MAX_VOXELS ||
        dim[3] > FTM_NIFTI_MAX_VOXELS ||
        (double)dim[1] * (double)dim[2] * (double)dim[3] > (double)FTM_NIFTI_MAX_VOXELS)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field dim[1..3] = %lld x %lld x %lld = %.0f voxels, more "
                             "than the limit of %lld",
                             name, (long long)dim[1], (long long)dim[2], (long long)dim[3],
                             (double)dim[1] * (double)dim[2] * (double)dim[3],
                             (long long)FTM_NIFTI_MAX_VOXELS);
    const int64_t count = dim[1] * dim[2] * dim[3];
    if (!supported_type(a.datatype))
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field datatype = %d (%s; supported: 2 uint8, 4 int16, 8 "
                             "int32, 16 float32, 64 float64, 256 int8, 512 uint16, 768 uint32)",
                             name, a.datatype, nifti_datatype_string(a.datatype));
    int bytes = 0, swapsize = 0;
    nifti_datatype_sizes(a.datatype, &bytes, &swapsize);
    if (a.bitpix != 8 * bytes)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field bitpix = %d does not match datatype %d (%s: %d)",
                             name, a.bitpix, a.datatype, nifti_datatype_string(a.datatype),
                             8 * bytes);
    h->datatype = a.datatype;
    h->bytes = bytes;
    for (int i = 1; i <= 3; i++) {
        double p = a.pixdim[i];
        if (!(p > 0.0) || !isfinite(p))
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field pixdim[%d] = %g (a voxel size must be > 0 "
                                 "and finite)",
                                 name, i, p);
        h->pixdim[i - 1] = p;
    }
    const double off = a.vox_offset, min_off = (double)a.size + 4; /* + extension flag */
    if (!(off >= min_off) || !(off <= (double)NIFTI_MAX_OFFSET) || off != floor(off))
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field vox_offset = %g (must be a whole number of bytes, "
                             "%.0f .. %llu, in a single-file .nii)",
                             name, off, min_off, (unsigned long long)NIFTI_MAX_OFFSET);
    h->offset = (uint64_t)off;
    if (file_size != UINT64_MAX && h->offset > file_size)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field vox_offset = %llu is past the end of the file "
                             "(%llu bytes)",
                             name, (unsigned long long)h->offset, (unsigned long long)file_size);
    if (a.slope == 0.0 || !isfinite(a.slope)) { /* the standard: no scaling */
        h->slope = 1.0;
        h->inter = 0.0;
    } else {
        if (!isfinite(a.inter))
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field scl_inter = %g is not finite (scl_slope = %g)",
                                 name, a.inter, a.slope);
        h->slope = a.slope;
        h->inter = a.inter;
    }
    int units = a.units & 7;
    static const double metres[4] = {1e-3, 1.0, 1e-3, 1e-6}; /* unknown = mm */
    if (units > NIFTI_UNITS_MICRON)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: header field xyzt_units = %d: unknown spatial unit %d "
                             "(0 unset, 1 m, 2 mm, 3 micron)",
                             name, a.units, units);
    h->unit = metres[units];
    for (int i = 0; i < 3; i++)
        h->n[i] = dim[i + 1];
    h->needed = h->offset + (uint64_t)count * (uint64_t)h->bytes;
    h->qform_code = a.qform_code;
    h->sform_code = a.sform_code;
    memcpy(h->quatern, a.quatern, sizeof h->quatern);
    memcpy(h->qoffset, a.qoffset, sizeof h->qoffset);
    h->qfac = a.pixdim[0] < 0 ? -1.0 : 1.0; /* the standard: anything but -1 means 1 */
    memcpy(h->srow, a.srow, sizeof h->srow);
    return FTM_OK;
}

double ftm_nifti_raw(const ftm_nifti *h, const uint8_t *voxels, size_t i)
{
    uint8_t b[8];
    memcpy(b, voxels + i * (size_t)h->bytes, (size_t)h->bytes);
    if (h->swap && h->bytes > 1)
        nifti_swap_Nbytes(1, h->bytes, b);
    switch (h->datatype) {
    case NIFTI_TYPE_UINT8: return b[0];
    case NIFTI_TYPE_INT8: return (int8_t)b[0];
    case NIFTI_TYPE_INT16: { int16_t v; memcpy(&v, b, 2); return v; }
    case NIFTI_TYPE_UINT16: { uint16_t v; memcpy(&v, b, 2); return v; }
    case NIFTI_TYPE_INT32: { int32_t v; memcpy(&v, b, 4); return v; }
    case NIFTI_TYPE_UINT32: { uint32_t v; memcpy(&v, b, 4); return v; }
    case NIFTI_TYPE_FLOAT32: { float v; memcpy(&v, b, 4); return v; }
    default: { double v; memcpy(&v, b, 8); return v; } /* float64 */
    }
}

/* gzread's error on f, if any (a stream cut short is not one: the header
 * check reports what is missing), without the "PATH: " zlib puts first. */
static const char *gz_error(znzFile f, const char *path)
{
    if (!f->withz || !f->zfptr)
        return NULL;
    int code = Z_OK;
    const char *msg = gzerror(f->zfptr, &code);
    if (code == Z_OK || code == Z_BUF_ERROR)
        return NULL;
    if (!msg || !msg[0])
        return "inflate failed";
    size_t n = strlen(path);
    if (strncmp(msg, path, n) == 0 && msg[n] == ':' && msg[n + 1] == ' ')
        msg += n + 2;
    return msg;
}

/* Reads up to `want` more bytes into buf + *have, growing it; stops early at
 * the end of the file. */
static int read_more(znzFile f, const char *path, uint8_t **buf, size_t *cap, size_t *have,
                     uint64_t want, ftm_error *err)
{
    while (want > 0) {
        if (*have == *cap) {
            size_t ncap = *cap * 2;
            if ((uint64_t)ncap - *have > want)
                ncap = *have + (size_t)want;
            uint8_t *nb = realloc(*buf, ncap);
            if (!nb)
                return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory reading the file", path);
            *buf = nb;
            *cap = ncap;
        }
        size_t chunk = *cap - *have;
        if ((uint64_t)chunk > want)
            chunk = (size_t)want;
        errno = 0;
        size_t got = znzread(*buf + *have, 1, chunk, f);
        if (got > chunk) /* znzread's -1: a read or inflate error */
            got = 0;
        *have += got;
        want -= got;
        const char *why = gz_error(f, path);
        if (why)
            return ftm_error_set(err, FTM_EPARSE, "%s: gzip data corrupt after %zu bytes: %s",
                                 path, *have, why);
        if (got < chunk) {
            if (!f->withz && f->nzfptr && ferror(f->nzfptr))
                return ftm_error_set(err, FTM_EIO, "%s: read error at byte %zu: %s", path, *have,
                                     strerror(errno ? errno : EIO));
            break; /* end of file */
        }
    }
    return FTM_OK;
}

int ftm_nifti_read(const char *path, uint8_t **data, size_t *size, ftm_error *err)
{
    errno = 0;
    znzFile f = znzopen(path, "rb", 1); /* gzip or not, as the bytes say */
    if (znz_isnull(f))
        return ftm_error_set(err, FTM_EIO, "%s: cannot open: %s", path,
                             strerror(errno ? errno : ENOENT));
    size_t cap = sizeof(nifti_2_header), have = 0;
    uint8_t *buf = malloc(cap);
    int rc = buf ? FTM_OK : ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    /* the header first: it says how much more there is to read */
    if (rc == FTM_OK)
        rc = read_more(f, path, &buf, &cap, &have, 4, err);
    bool swap;
    int version = rc == FTM_OK ? header_version(buf, have, &swap) : 0;
    size_t header = version == 2 ? sizeof(nifti_2_header) : sizeof(nifti_1_header);
    if (rc == FTM_OK && version != 0)
        rc = read_more(f, path, &buf, &cap, &have, header - have, err);
    if (rc == FTM_OK && version != 0 && have == header) {
        ftm_nifti h;
        ftm_error ignored;
        /* a bad header is reported by the caller's check, with the size read */
        if (ftm_nifti_header(buf, have, UINT64_MAX, path, &h, &ignored) == FTM_OK)
            rc = read_more(f, path, &buf, &cap, &have, h.needed - have, err);
    }
    znzclose(f);
    if (rc != FTM_OK) {
        free(buf);
        return rc;
    }
    *data = buf;
    *size = have;
    return FTM_OK;
}

/* The transform of the chosen form, voxel indices to file units. */
static int chosen_transform(const ftm_nifti *h, const char *name, double t[3][4], int *xform,
                            ftm_error *err)
{
    *xform = 0;
    if (h->sform_code > 0) {
        if (h->sform_code > NIFTI_XFORM_TEMPLATE_OTHER)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field sform_code = %d (known codes: 0 .. 5)", name,
                                 h->sform_code);
        static const char *const rows[3] = {"srow_x", "srow_y", "srow_z"};
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++) {
                if (!isfinite(h->srow[r][c]))
                    return ftm_error_set(err, FTM_EPARSE,
                                         "%s: header field %s[%d] = %g is not finite (sform_code "
                                         "= %d)",
                                         name, rows[r], c, h->srow[r][c], h->sform_code);
                t[r][c] = h->srow[r][c];
            }
        *xform = 2;
        return FTM_OK;
    }
    if (h->qform_code > 0) {
        if (h->qform_code > NIFTI_XFORM_TEMPLATE_OTHER)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s: header field qform_code = %d (known codes: 0 .. 5)", name,
                                 h->qform_code);
        static const char *const q[6] = {"quatern_b", "quatern_c", "quatern_d",
                                         "qoffset_x", "qoffset_y", "qoffset_z"};
        for (int i = 0; i < 6; i++) {
            double v = i < 3 ? h->quatern[i] : h->qoffset[i - 3];
            if (!isfinite(v))
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s: header field %s = %g is not finite (qform_code = %d)",
                                     name, q[i], v, h->qform_code);
        }
        /* libnifti's quaternion to matrix: the rotation, pixdim, qfac */
        nifti_dmat44 m = nifti_quatern_to_dmat44(
            h->quatern[0], h->quatern[1], h->quatern[2], h->qoffset[0], h->qoffset[1],
            h->qoffset[2], h->pixdim[0], h->pixdim[1], h->pixdim[2], h->qfac);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++)
                t[r][c] = m.m[r][c];
        *xform = 1;
        return FTM_OK;
    }
    return FTM_OK;
}

#else /* no libnifti */

int ftm_nifti_header(const uint8_t *d, size_t size, uint64_t file_size, const char *name,
                     ftm_nifti *h, ftm_error *err)
{
    (void)d, (void)size, (void)file_size, (void)h;
    return ftm_error_set(err, FTM_EPARSE,
                         "%s: this libftm was built without libnifti (libnifti2-dev): it reads "
                         "no NIfTI files",
                         name);
}

double ftm_nifti_raw(const ftm_nifti *h, const uint8_t *voxels, size_t i)
{
    (void)h, (void)voxels, (void)i;
    return 0;
}

int ftm_nifti_read(const char *path, uint8_t **data, size_t *size, ftm_error *err)
{
    (void)data, (void)size;
    return ftm_nifti_header(NULL, 0, 0, path, NULL, err);
}

static int chosen_transform(const ftm_nifti *h, const char *name, double t[3][4], int *xform,
                            ftm_error *err)
{
    (void)h, (void)name, (void)t, (void)err;
    *xform = 0;
    return FTM_OK;
}

#endif

int ftm_nifti_grid_of(const ftm_nifti *h, int axes, double scale, ftm_vec3 origin,
                      const char *name, ftm_nifti_grid *g, ftm_error *err)
{
    memset(g, 0, sizeof *g);
    double t[3][4] = {{0}};
    int xform = 0;
    if (axes == FTM_NIFTI_AXES_SCANNER) {
        int rc = chosen_transform(h, name, t, &xform, err);
        if (rc != FTM_OK)
            return rc;
    }
    const double unit = h->unit * scale;
    const double o[3] = {origin.x, origin.y, origin.z};
    double sp[3], org[3];
    if (xform == 0) { /* the stored axes */
        for (int a = 0; a < 3; a++) {
            g->axis[a] = a;
            g->n[a] = (int32_t)h->n[a];
            sp[a] = h->pixdim[a] * unit;
            org[a] = o[a];
        }
    } else {
        bool used[3] = {false, false, false};
        for (int j = 0; j < 3; j++) { /* file axis j's column */
            double len = sqrt(t[0][j] * t[0][j] + t[1][j] * t[1][j] + t[2][j] * t[2][j]);
            int best = 0;
            for (int i = 1; i < 3; i++)
                if (fabs(t[i][j]) > fabs(t[best][j]))
                    best = i;
            if (!(len > 0) || !isfinite(len) || used[best])
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s: the %s maps the voxel axes onto no three distinct "
                                     "directions (axis %d: %g %g %g)",
                                     name, xform == 2 ? "sform (srow_x/y/z)" : "qform", j,
                                     t[0][j], t[1][j], t[2][j]);
            double angle = acos(fmin(1.0, fabs(t[best][j]) / len));
            if (angle > OBLIQUE_TOLERANCE)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s: the %s is oblique: voxel axis %d is %.2f degrees off "
                                     "the scanner's %c axis; resample the image onto the scanner "
                                     "axes, or read it with its stored axes (axes = stored)",
                                     name, xform == 2 ? "sform (srow_x/y/z)" : "qform", j,
                                     angle * 57.295779513082323, "xyz"[best]);
            used[best] = true;
            g->axis[best] = j;
            g->flip[best] = t[best][j] < 0;
            g->n[best] = (int32_t)h->n[j];
            sp[best] = len * unit;
        }
        /* the box's corner: the smallest voxel centre on each axis, less half
         * a voxel, where the transform puts it */
        for (int a = 0; a < 3; a++) {
            double c = t[a][3];
            for (int j = 0; j < 3; j++)
                if (t[a][j] < 0)
                    c += t[a][j] * (double)(h->n[j] - 1);
            org[a] = c * unit - 0.5 * sp[a] + o[a];
        }
    }
    for (int a = 0; a < 3; a++)
        if (!(sp[a] > 0) || !isfinite(sp[a]) || !isfinite(org[a]) ||
            !isfinite(org[a] + (double)g->n[a] * sp[a]))
            return ftm_error_set(err, FTM_EINVAL,
                                 "%s: voxel size %g x %g x %g m (times scale %g) is zero or not "
                                 "finite in double precision, or the box is not",
                                 name, sp[0], sp[1], sp[2], scale);
    g->spacing = (ftm_vec3){sp[0], sp[1], sp[2]};
    g->origin = (ftm_vec3){org[0], org[1], org[2]};
    g->xform = xform;
    return FTM_OK;
}
