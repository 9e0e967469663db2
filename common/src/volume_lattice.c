/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The control lattice of a volume (paper section 4.2): a cubic lattice over
 * the image's box whose cells of air are left out and whose points in hard
 * tissue are fixed. Links, stiffness, cells and surface faces follow the
 * cubic lattice generator (lattice.h), restricted to the kept cells. */
#include "ftm/volume.h"

#include "error.h"
#include "lattice.h"
#include "material.h"
#include "volume_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define VOLUME_LATTICE_MAX_POINTS ((int64_t)1 << 24)
#define ALL_FACES                                                                                  \
    (FTM_FACE_XMIN | FTM_FACE_XMAX | FTM_FACE_YMIN | FTM_FACE_YMAX | FTM_FACE_ZMIN | FTM_FACE_ZMAX)

ftm_volume_lattice_def ftm_default_volume_lattice_def(void)
{
    return (ftm_volume_lattice_def){.nodes = {10, 10, 10},
                                    .stencil = FTM_STENCIL_18,
                                    .material = ftm_default_material_def(),
                                    .hard_threshold = 0.9,
                                    .air_threshold = 0.05,
                                    .fixed_faces = 0};
}

ftm_volume_frame ftm_volume_frame_of(const ftm_volume *volume, const int32_t nodes[3])
{
    ftm_volume_info in = ftm_volume_get_info(volume);
    const double o[3] = {in.origin.x, in.origin.y, in.origin.z};
    const double s[3] = {in.spacing.x, in.spacing.y, in.spacing.z};
    const int32_t nv[3] = {in.nx, in.ny, in.nz};
    ftm_volume_frame f;
    for (int a = 0; a < 3; a++) {
        f.n[a] = nodes[a];
        f.origin[a] = o[a];
        f.extent[a] = nv[a] * s[a];
        f.cell[a] = f.extent[a] / (nodes[a] - 1);
    }
    return f;
}

static ftm_vec3 frame_point(const ftm_volume_frame *f, double i, double j, double k)
{
    return (ftm_vec3){ftm_volume_frame_coord(f, 0, i), ftm_volume_frame_coord(f, 1, j),
                      ftm_volume_frame_coord(f, 2, k)};
}

/* Air: every one of 5 x 5 x 5 samples over the cell, faces included, below
 * the threshold. */
static bool cell_is_air(const ftm_volume *v, const ftm_volume_frame *f, const int32_t c[3],
                        double threshold)
{
    for (int z = 0; z <= 4; z++)
        for (int y = 0; y <= 4; y++)
            for (int x = 0; x <= 4; x++) {
                ftm_vec3 p = frame_point(f, c[0] + x / 4.0, c[1] + y / 4.0, c[2] + z / 4.0);
                if (ftm_volume_sample(v, p) >= threshold)
                    return false;
            }
    return true;
}

/* Mean intensity over the cube of half a cell each way around a point, from
 * 4 x 4 x 4 samples at the centres of its sub-cubes. */
static double point_intensity(const ftm_volume *v, const ftm_volume_frame *f, const int32_t p[3])
{
    double sum = 0.0;
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++)
                sum += ftm_volume_sample(v, frame_point(f, p[0] + (x + 0.5) / 4.0 - 0.5,
                                                        p[1] + (y + 0.5) / 4.0 - 0.5,
                                                        p[2] + (z + 0.5) / 4.0 - 0.5));
    return sum / 64.0;
}

static int64_t cell_index(const ftm_volume_frame *f, const int32_t c[3])
{
    return c[0] + (int64_t)(f->n[0] - 1) * (c[1] + (int64_t)(f->n[1] - 1) * c[2]);
}

static bool cell_kept(const ftm_volume_frame *f, const uint8_t *kept, const int32_t c[3])
{
    for (int a = 0; a < 3; a++)
        if (c[a] < 0 || c[a] > f->n[a] - 2)
            return false;
    return kept[cell_index(f, c)];
}

/* Whether points p and p + d (d a stencil offset) share a kept cell: per
 * axis the cells holding both are p - 1 and p where d is 0, else the one
 * between them. */
static bool share_kept_cell(const ftm_volume_frame *f, const uint8_t *kept, const int32_t p[3],
                            const int8_t d[3])
{
    int32_t lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = d[a] == 0 ? p[a] - 1 : d[a] > 0 ? p[a] : p[a] - 1;
        hi[a] = d[a] == 0 ? p[a] : lo[a];
    }
    int32_t c[3];
    for (c[2] = lo[2]; c[2] <= hi[2]; c[2]++)
        for (c[1] = lo[1]; c[1] <= hi[1]; c[1]++)
            for (c[0] = lo[0]; c[0] <= hi[0]; c[0]++)
                if (cell_kept(f, kept, c))
                    return true;
    return false;
}

static int check_def(const ftm_volume_lattice_def *d, const char *who, ftm_error *err)
{
    for (int a = 0; a < 3; a++)
        if (d->nodes[a] < 2)
            return ftm_error_set(err, FTM_EINVAL, "%s: nodes along %c must be >= 2 (got %d)", who,
                                 "xyz"[a], (int)d->nodes[a]);
    int64_t total = (int64_t)d->nodes[0] * d->nodes[1] * d->nodes[2];
    if (total > VOLUME_LATTICE_MAX_POINTS)
        return ftm_error_set(err, FTM_EINVAL, "%s: %d x %d x %d points, more than %lld", who,
                             (int)d->nodes[0], (int)d->nodes[1], (int)d->nodes[2],
                             (long long)VOLUME_LATTICE_MAX_POINTS);
    if (ftm_lattice_offset_count(d->stencil) == 0)
        return ftm_error_set(err, FTM_EINVAL, "%s: stencil must be 6, 18 or 26 (got %d)", who,
                             (int)d->stencil);
    if (isnan(d->hard_threshold))
        return ftm_error_set(err, FTM_EINVAL, "%s: hard threshold is NaN", who);
    if (!(d->air_threshold >= 0.0) || !isfinite(d->air_threshold))
        return ftm_error_set(err, FTM_EINVAL, "%s: air threshold must be >= 0 (got %g)", who,
                             d->air_threshold);
    if (d->fixed_faces & ~(uint32_t)ALL_FACES)
        return ftm_error_set(err, FTM_EINVAL, "%s: fixed faces 0x%x are not FTM_FACE_* bits", who,
                             (unsigned)d->fixed_faces);
    return ftm_material_check(&d->material, who, err);
}

/* The outward normals of the kept cells' outer faces, summed per point
 * (3 per lattice point; 0 for a point on none). */
static void surface_normals(const ftm_volume_frame *f, const uint8_t *kept, double *nsum)
{
    const int32_t *n = f->n;
    int32_t c[3];
    for (c[2] = 0; c[2] < n[2] - 1; c[2]++)
        for (c[1] = 0; c[1] < n[1] - 1; c[1]++)
            for (c[0] = 0; c[0] < n[0] - 1; c[0]++) {
                if (!kept[cell_index(f, c)])
                    continue;
                for (int face = 0; face < 6; face++) {
                    int ax = face / 2, hi = face & 1, u = (ax + 1) % 3, v = (ax + 2) % 3;
                    int32_t nb[3] = {c[0], c[1], c[2]};
                    nb[ax] += hi ? 1 : -1;
                    if (cell_kept(f, kept, nb))
                        continue;
                    for (int t = 0; t < 4; t++) {
                        int32_t at[3];
                        at[ax] = c[ax] + hi;
                        at[u] = c[u] + (t == 1 || t == 2);
                        at[v] = c[v] + (t >= 2);
                        nsum[3 * (at[0] + (size_t)n[0] * (at[1] + (size_t)n[1] * at[2])) + ax] +=
                            hi ? 1.0 : -1.0;
                    }
                }
            }
}

/* A surface point in air, moved inward along -nrm onto the image's surface:
 * the first of 64 samples up to 0.85 of a cell at or above `air`, else the
 * farthest. Samples in a fixed order: the same point on every machine. */
static ftm_vec3 fit_point(const ftm_volume *v, const ftm_volume_frame *f, ftm_vec3 x,
                          const double nrm[3], double air)
{
    if (ftm_volume_sample(v, x) >= air)
        return x;
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    if (!(len > 0.0))
        return x;
    /* the reach along the direction: 0.7 of the cell it crosses */
    double reach = 0.0;
    for (int a = 0; a < 3; a++)
        reach += fabs(nrm[a] / len) * f->cell[a];
    reach *= 0.85;
    ftm_vec3 y = x;
    for (int s = 1; s <= 64; s++) {
        const double d = reach * s / 64.0;
        y = (ftm_vec3){x.x - nrm[0] / len * d, x.y - nrm[1] / len * d, x.z - nrm[2] / len * d};
        if (ftm_volume_sample(v, y) >= air)
            break;
    }
    return y;
}

int ftm_generate_volume_lattice(ftm_mesh_builder *b, const ftm_volume *volume,
                                const ftm_volume_lattice_def *def, int32_t *point_input,
                                ftm_error *err)
{
    const char *who = "volume lattice";
    if (!b || !volume || !def)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", who);
    int rc = check_def(def, who, err);
    if (rc)
        return rc;
    const ftm_volume_frame f = ftm_volume_frame_of(volume, def->nodes);
    for (int a = 0; a < 3; a++)
        if (!(f.cell[a] > 0.0) || !isfinite(f.cell[a]))
            return ftm_error_set(err, FTM_EINVAL, "%s: cell size %g along %c is not > 0", who,
                                 f.cell[a], "xyz"[a]);
    const int32_t *n = f.n;
    const size_t points = (size_t)n[0] * n[1] * n[2];
    const size_t cells = (size_t)(n[0] - 1) * (n[1] - 1) * (n[2] - 1);
    uint8_t *kept = malloc(cells);
    int32_t *input = malloc(points * sizeof *input);
    if (!kept || !input) {
        free(kept);
        free(input);
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", who);
    }
    size_t kept_cells = 0;
    double *nsum = NULL; /* fit_surface: outward normals per point */
    int32_t c[3], p[3];
    for (c[2] = 0; c[2] < n[2] - 1; c[2]++)
        for (c[1] = 0; c[1] < n[1] - 1; c[1]++)
            for (c[0] = 0; c[0] < n[0] - 1; c[0]++) {
                /* intensities are >= 0: a threshold of 0 keeps every cell */
                bool k = def->air_threshold <= 0.0 ||
                         !cell_is_air(volume, &f, c, def->air_threshold);
                kept[cell_index(&f, c)] = k;
                kept_cells += k;
            }
    if (kept_cells == 0) {
        rc = ftm_error_set(err, FTM_EINVAL,
                           "%s: every cell is air (no sample reaches the air threshold %g)", who,
                           def->air_threshold);
        goto done;
    }
    if (def->fit_surface) {
        nsum = calloc(points * 3, sizeof *nsum);
        if (!nsum) {
            rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", who);
            goto done;
        }
        surface_normals(&f, kept, nsum);
    }
    /* points of a kept cell, x fastest, fixed in hard tissue or on a fixed face */
    for (p[2] = 0; p[2] < n[2]; p[2]++)
        for (p[1] = 0; p[1] < n[1]; p[1]++)
            for (p[0] = 0; p[0] < n[0]; p[0]++) {
                size_t i = p[0] + (size_t)n[0] * (p[1] + (size_t)n[1] * p[2]);
                bool used = false;
                for (int k = 0; k < 8 && !used; k++) {
                    const int8_t *o = ftm_lattice_hex_corners[k];
                    int32_t cc[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
                    used = cell_kept(&f, kept, cc);
                }
                input[i] = -1;
                if (!used)
                    continue;
                bool fixed = ftm_lattice_on_faces(def->fixed_faces, p, n) ||
                             (def->hard_threshold <= 1.0 &&
                              point_intensity(volume, &f, p) >= def->hard_threshold);
                ftm_vec3 at = frame_point(&f, p[0], p[1], p[2]);
                if (nsum && !fixed)
                    at = fit_point(volume, &f, at, nsum + 3 * i, def->air_threshold);
                ftm_node_def nd = {.position = at,
                                   .mass = def->material.node_mass,
                                   .damping = def->material.node_damping,
                                   .fixed = fixed};
                int32_t r = ftm_mesh_builder_add_node(b, &nd);
                if (r < 0) {
                    rc = ftm_lattice_node_failed(r, who, ftm_mesh_builder_node_count(b), &nd,
                                                 err);
                    goto done;
                }
                input[i] = r;
            }
    /* links of the stencil between kept points of a kept cell, each once
     * (forward half-stencil, as lattice3d) */
    const int noff = ftm_lattice_offset_count(def->stencil);
    for (p[2] = 0; p[2] < n[2]; p[2]++)
        for (p[1] = 0; p[1] < n[1]; p[1]++)
            for (p[0] = 0; p[0] < n[0]; p[0]++) {
                int32_t ia = input[p[0] + (size_t)n[0] * (p[1] + (size_t)n[1] * p[2])];
                if (ia < 0)
                    continue;
                for (int k = 0; k < noff; k++) {
                    const int8_t *d = ftm_lattice_offsets[k];
                    int32_t q[3] = {p[0] + d[0], p[1] + d[1], p[2] + d[2]};
                    if (q[0] < 0 || q[0] >= n[0] || q[1] < 0 || q[1] >= n[1] || q[2] < 0 ||
                        q[2] >= n[2])
                        continue;
                    int32_t ib = input[q[0] + (size_t)n[0] * (q[1] + (size_t)n[1] * q[2])];
                    if (ib < 0 || !share_kept_cell(&f, kept, p, d))
                        continue;
                    ftm_link_def ld = {.a = ia,
                                       .b = ib,
                                       .stiffness = ftm_lattice_axis_stiffness(
                                           &def->material, d[0] * f.cell[0], d[1] * f.cell[1],
                                           d[2] * f.cell[2]),
                                       .rest_length = -1.0};
                    if ((rc = ftm_mesh_builder_add_link(b, &ld)) != FTM_OK) {
                        rc = ftm_lattice_link_failed(
                            rc, who, fmin(f.cell[0], fmin(f.cell[1], f.cell[2])),
                            fmax(f.cell[0], fmax(f.cell[1], f.cell[2])), err);
                        goto done;
                    }
                }
            }
    /* kept cells: a hexahedron each, and their faces toward air or the box's
     * faces as the surface */
    for (c[2] = 0; c[2] < n[2] - 1; c[2]++)
        for (c[1] = 0; c[1] < n[1] - 1; c[1]++)
            for (c[0] = 0; c[0] < n[0] - 1; c[0]++) {
                if (!kept[cell_index(&f, c)])
                    continue;
                int32_t h[8];
                for (int k = 0; k < 8; k++) {
                    const int8_t *o = ftm_lattice_hex_corners[k];
                    h[k] = input[(c[0] + o[0]) +
                                 (size_t)n[0] * ((c[1] + o[1]) + (size_t)n[1] * (c[2] + o[2]))];
                }
                if ((rc = ftm_mesh_builder_add_hexahedron(b, h)) != FTM_OK) {
                    rc = ftm_error_set(err, rc, "%s: cannot add hexahedron: %s", who,
                                       ftm_strerror(rc));
                    goto done;
                }
                for (int face = 0; face < 6; face++) {
                    int ax = face / 2, hi = face & 1, u = (ax + 1) % 3, v = (ax + 2) % 3;
                    int32_t nb[3] = {c[0], c[1], c[2]};
                    nb[ax] += hi ? 1 : -1;
                    if (cell_kept(&f, kept, nb))
                        continue;
                    static const int8_t q[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
                    int32_t id[4];
                    for (int t = 0; t < 4; t++) {
                        int32_t at[3];
                        at[ax] = c[ax] + hi;
                        at[u] = c[u] + q[t][0];
                        at[v] = c[v] + q[t][1];
                        id[t] = input[at[0] + (size_t)n[0] * (at[1] + (size_t)n[1] * at[2])];
                    }
                    if ((rc = ftm_lattice_add_quad(b, id, hi)) != FTM_OK) {
                        rc = ftm_error_set(err, rc, "%s: cannot add triangle: %s", who,
                                           ftm_strerror(rc));
                        goto done;
                    }
                }
            }
    if (point_input)
        memcpy(point_input, input, points * sizeof *input);
done:
    free(nsum);
    free(kept);
    free(input);
    return rc;
}
