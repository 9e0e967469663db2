/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Free-form deformation of a volume by its control lattice (volume.h): the
 * displacement of a rest point is the trilinear blend of the displacements
 * of its cell's corners. Displacements, not positions, are blended, so a
 * lattice at rest maps every point to itself bit for bit, and a corner left
 * out of the mesh (air) simply does not move. */
#include "ftm/volume.h"

#include "error.h"
#include "volume_internal.h"

#include <math.h>
#include <stdlib.h>

struct ftm_ffd {
    ftm_volume_frame f;
    int32_t *node; /* per lattice point: mesh node or -1 */
    double *rest;  /* per lattice point: 3 coordinates; the mesh node's own where it has one */
};

int ftm_ffd_create(const ftm_mesh *mesh, const ftm_volume *volume, const int32_t nodes[3],
                   const int32_t *point_node, ftm_ffd **out, ftm_error *err)
{
    const char *who = "ffd";
    if (!mesh || !volume || !nodes || !point_node || !out)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", who);
    for (int a = 0; a < 3; a++)
        if (nodes[a] < 2)
            return ftm_error_set(err, FTM_EINVAL, "%s: nodes along %c must be >= 2 (got %d)", who,
                                 "xyz"[a], (int)nodes[a]);
    int64_t total = (int64_t)nodes[0] * nodes[1] * nodes[2];
    if (total > ((int64_t)1 << 24))
        return ftm_error_set(err, FTM_EINVAL, "%s: %lld lattice points, more than %lld", who,
                             (long long)total, (long long)1 << 24);
    ftm_ffd *d = calloc(1, sizeof *d);
    uint8_t *seen = calloc((size_t)ftm_mesh_node_count(mesh) + 1, 1);
    if (d) {
        d->f = ftm_volume_frame_of(volume, nodes);
        d->node = malloc((size_t)total * sizeof *d->node);
        d->rest = malloc((size_t)total * 3 * sizeof *d->rest);
    }
    int rc = FTM_OK;
    if (!d || !seen || !d->node || !d->rest) {
        rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", who);
        goto done;
    }
    const int32_t count = ftm_mesh_node_count(mesh);
    for (int32_t k = 0, i = 0; k < nodes[2]; k++)
        for (int32_t j = 0; j < nodes[1]; j++)
            for (int32_t ix = 0; ix < nodes[0]; ix++, i++) {
                double x[3] = {ftm_volume_frame_coord(&d->f, 0, ix),
                               ftm_volume_frame_coord(&d->f, 1, j),
                               ftm_volume_frame_coord(&d->f, 2, k)};
                int32_t nd = point_node[i];
                if (nd < -1 || nd >= count || (nd >= 0 && seen[nd])) {
                    rc = ftm_error_set(err, FTM_EINVAL,
                                       "%s: lattice point (%d, %d, %d): node %d %s", who, (int)ix,
                                       (int)j, (int)k, (int)nd,
                                       nd >= 0 && nd < count ? "is given to another point too"
                                                             : "out of range");
                    goto done;
                }
                if (nd >= 0) {
                    seen[nd] = 1;
                    /* the node's own rest position, so that positions at rest
                     * give a displacement of exactly zero; a surface point
                     * fitted to the image (fit_surface) rests up to 0.85 of a
                     * cell inward, never farther than a cell */
                    ftm_vec3 r = ftm_mesh_rest_position(mesh, nd);
                    double m[3] = {r.x, r.y, r.z};
                    for (int a = 0; a < 3; a++)
                        if (!(fabs(m[a] - x[a]) < d->f.cell[a])) {
                            rc = ftm_error_set(err, FTM_EINVAL,
                                               "%s: lattice point (%d, %d, %d) is at (%g, %g, "
                                               "%g) but its node %d rests at (%g, %g, %g)",
                                               who, (int)ix, (int)j, (int)k, x[0], x[1], x[2],
                                               (int)nd, m[0], m[1], m[2]);
                            goto done;
                        }
                    x[0] = m[0];
                    x[1] = m[1];
                    x[2] = m[2];
                }
                d->node[i] = nd;
                d->rest[3 * (size_t)i] = x[0];
                d->rest[3 * (size_t)i + 1] = x[1];
                d->rest[3 * (size_t)i + 2] = x[2];
            }
    *out = d;
    d = NULL;
done:
    free(seen);
    ftm_ffd_destroy(d);
    return rc;
}

void ftm_ffd_destroy(ftm_ffd *ffd)
{
    if (!ffd)
        return;
    free(ffd->node);
    free(ffd->rest);
    free(ffd);
}

void ftm_ffd_nodes(const ftm_ffd *ffd, int32_t nodes[3])
{
    for (int a = 0; a < 3; a++)
        nodes[a] = ffd->f.n[a];
}

static int64_t point_index(const ftm_ffd *ffd, int32_t ix, int32_t iy, int32_t iz)
{
    const int32_t *n = ffd->f.n;
    if (ix < 0 || iy < 0 || iz < 0 || ix >= n[0] || iy >= n[1] || iz >= n[2])
        return -1;
    return ix + (int64_t)n[0] * (iy + (int64_t)n[1] * iz);
}

ftm_vec3 ftm_ffd_point_rest(const ftm_ffd *ffd, int32_t ix, int32_t iy, int32_t iz)
{
    int64_t i = point_index(ffd, ix, iy, iz);
    if (i < 0)
        return (ftm_vec3){NAN, NAN, NAN};
    const double *r = ffd->rest + 3 * i;
    return (ftm_vec3){r[0], r[1], r[2]};
}

int32_t ftm_ffd_point_node(const ftm_ffd *ffd, int32_t ix, int32_t iy, int32_t iz)
{
    int64_t i = point_index(ffd, ix, iy, iz);
    return i < 0 ? -1 : ffd->node[i];
}

/* u(X): the blend of the corner displacements, weights from X clamped to
 * the box. Corners in a fixed order, so the sum is the same everywhere. */
static void displacement(const ftm_ffd *ffd, const double *positions, const double x[3],
                         double u[3])
{
    const ftm_volume_frame *f = &ffd->f;
    int32_t c[3];
    double w[3];
    for (int a = 0; a < 3; a++) {
        double t = (x[a] - f->origin[a]) / f->cell[a];
        double top = f->n[a] - 1;
        t = t > 0.0 ? (t < top ? t : top) : 0.0; /* NaN goes to 0 */
        double fl = floor(t);
        if (fl > top - 1)
            fl = top - 1; /* the last face belongs to the last cell */
        c[a] = (int32_t)fl;
        w[a] = t - fl;
    }
    u[0] = u[1] = u[2] = 0.0;
    for (int k = 0; k < 8; k++) {
        int dx = k & 1, dy = (k >> 1) & 1, dz = k >> 2;
        int64_t i = point_index(ffd, c[0] + dx, c[1] + dy, c[2] + dz);
        int32_t nd = ffd->node[i];
        if (nd < 0)
            continue;
        double wk = (dx ? w[0] : 1.0 - w[0]) * (dy ? w[1] : 1.0 - w[1]) *
                    (dz ? w[2] : 1.0 - w[2]);
        const double *p = positions + 3 * (size_t)nd, *r = ffd->rest + 3 * i;
        for (int a = 0; a < 3; a++)
            u[a] += wk * (p[a] - r[a]);
    }
}

ftm_vec3 ftm_ffd_map(const ftm_ffd *ffd, const double *positions, ftm_vec3 rest)
{
    const double x[3] = {rest.x, rest.y, rest.z};
    double u[3];
    displacement(ffd, positions, x, u);
    return (ftm_vec3){x[0] + u[0], x[1] + u[1], x[2] + u[2]};
}

ftm_vec3 ftm_ffd_unmap(const ftm_ffd *ffd, const double *positions, ftm_vec3 p, int iterations)
{
    if (iterations <= 0)
        iterations = 8;
    const double q[3] = {p.x, p.y, p.z};
    double x[3] = {p.x, p.y, p.z}, u[3];
    for (int it = 0; it < iterations; it++) {
        displacement(ffd, positions, x, u);
        for (int a = 0; a < 3; a++)
            x[a] = q[a] - u[a];
    }
    return (ftm_vec3){x[0], x[1], x[2]};
}
