/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Lattice generators: the paper's 2D triangular lattice and 3D cubic lattices. */
#include "ftm/generate.h"

#include "error.h"
#include "lattice.h"
#include "material.h"

#include <float.h>
#include <math.h>

ftm_material_def ftm_default_material_def(void)
{
    return (ftm_material_def){
        .node_mass = 1.0, .node_damping = 1.0, .stiffness = 1.0, .axis_scale = {1, 1, 1}};
}

ftm_lattice2d_def ftm_default_lattice2d_def(void)
{
    return (ftm_lattice2d_def){
        .nx = 50, .ny = 50, .spacing = 1.0, .material = ftm_default_material_def(),
        .fixed_faces = FTM_FACE_XMIN | FTM_FACE_XMAX | FTM_FACE_YMIN | FTM_FACE_YMAX};
}

ftm_lattice3d_def ftm_default_lattice3d_def(void)
{
    return (ftm_lattice3d_def){.nx = 10, .ny = 10, .nz = 10, .spacing = {1, 1, 1},
                               .stencil = FTM_STENCIL_6, .material = ftm_default_material_def(),
                               .class_scale = {1, 1, 1}, .fixed_faces = FTM_FACE_ZMIN};
}

#define FTM_MAX_LATTICE_NODES (64 * 1024 * 1024)

/* Stiffness of a link along direction (dx, dy, dz), scaled per axis. */
double ftm_lattice_axis_stiffness(const ftm_material_def *m, double dx, double dy, double dz)
{
    double l2 = dx * dx + dy * dy + dz * dz;
    return m->stiffness *
           (m->axis_scale.x * dx * dx + m->axis_scale.y * dy * dy + m->axis_scale.z * dz * dz) / l2;
}

const int8_t ftm_lattice_offsets[13][3] = {
    {1, 0, 0}, {0, 1, 0}, {0, 0, 1},                                  /* edges */
    {1, 1, 0}, {1, -1, 0}, {1, 0, 1}, {1, 0, -1}, {0, 1, 1}, {0, 1, -1}, /* face diagonals */
    {1, 1, 1}, {1, 1, -1}, {1, -1, 1}, {1, -1, -1}};                    /* body diagonals */

const int8_t ftm_lattice_hex_corners[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                              {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

int ftm_lattice_offset_count(ftm_stencil stencil)
{
    return stencil == FTM_STENCIL_6 ? 3 : stencil == FTM_STENCIL_18 ? 9
                                      : stencil == FTM_STENCIL_26 ? 13
                                                                  : 0;
}

bool ftm_lattice_on_faces(uint32_t f, const int32_t i[3], const int32_t dims[3])
{
    for (int a = 0; a < 3; a++)
        if (((f & (FTM_FACE_XMIN << 2 * a)) && i[a] == 0) ||
            ((f & (FTM_FACE_XMAX << 2 * a)) && i[a] == dims[a] - 1))
            return true;
    return false;
}

int ftm_lattice_add_quad(ftm_mesh_builder *b, const int32_t id[4], bool hi)
{
    int rc;
    if (hi) {
        rc = ftm_mesh_builder_add_triangle(b, id[0], id[1], id[2]);
        if (!rc)
            rc = ftm_mesh_builder_add_triangle(b, id[0], id[2], id[3]);
    } else {
        rc = ftm_mesh_builder_add_triangle(b, id[0], id[2], id[1]);
        if (!rc)
            rc = ftm_mesh_builder_add_triangle(b, id[0], id[3], id[2]);
    }
    return rc;
}

int ftm_lattice_node_failed(int32_t r, const char *who, int32_t index, const ftm_node_def *nd,
                            ftm_error *err)
{
    const ftm_vec3 x = nd->position;
    if (r == FTM_EINVAL && !(isfinite(x.x) && isfinite(x.y) && isfinite(x.z)))
        return ftm_error_set(err, r,
                             "%s: cannot add node %d: its position (%g, %g, %g) m is not finite "
                             "in double precision (largest %g): spacing or cell size too large",
                             who, (int)index, x.x, x.y, x.z, DBL_MAX);
    return ftm_error_set(err, r, "%s: cannot add node: %s", who, ftm_strerror(r));
}

/* A link the builder refused: with an extreme spacing (squares that
 * underflow or overflow) its length is zero or not finite, so name that. */
int ftm_lattice_link_failed(int32_t r, const char *who, double smin, double smax, ftm_error *err)
{
    if (r != FTM_EINVAL)
        return ftm_error_set(err, r, "%s: cannot add link: %s", who, ftm_strerror(r));
    return ftm_error_set(err, r,
                         "%s: cannot add link: with spacing %g..%g m a link's length is zero or "
                         "not finite in double precision",
                         who, smin, smax);
}

int ftm_generate_lattice2d(ftm_mesh_builder *b, const ftm_lattice2d_def *def, ftm_error *err)
{
    const char *who = "lattice2d";
    if (!b || !def)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", who);
    if (def->nx < 2 || def->ny < 2 || (int64_t)def->nx * def->ny > FTM_MAX_LATTICE_NODES)
        return ftm_error_set(err, FTM_EINVAL, "%s: size %d x %d out of range (2..; at most %d nodes)",
                             who, (int)def->nx, (int)def->ny, FTM_MAX_LATTICE_NODES);
    if (!(def->spacing > 0.0) || !isfinite(def->spacing))
        return ftm_error_set(err, FTM_EINVAL, "%s: spacing must be > 0 (got %g)", who, def->spacing);
    /* the farthest node is (nx - 0.5, (ny - 1) sqrt(3)/2) spacings away */
    const int32_t span = def->nx > def->ny ? def->nx : def->ny;
    if (!isfinite(def->spacing * span))
        return ftm_error_set(err, FTM_EINVAL,
                             "%s: spacing %g m is too large: %d nodes along an axis would reach "
                             "beyond double precision (%g); at most %g m",
                             who, def->spacing, (int)span, DBL_MAX, DBL_MAX / span);
    int rc = ftm_material_check(&def->material, who, err);
    if (rc)
        return rc;
    const double a = def->spacing, pitch = def->spacing * sqrt(3.0) / 2.0;
    const int32_t base = ftm_mesh_builder_node_count(b);
    for (int32_t iy = 0; iy < def->ny; iy++)
        for (int32_t ix = 0; ix < def->nx; ix++) {
            bool fixed = ((def->fixed_faces & FTM_FACE_XMIN) && ix == 0) ||
                         ((def->fixed_faces & FTM_FACE_XMAX) && ix == def->nx - 1) ||
                         ((def->fixed_faces & FTM_FACE_YMIN) && iy == 0) ||
                         ((def->fixed_faces & FTM_FACE_YMAX) && iy == def->ny - 1);
            ftm_node_def nd = {.position = {(ix + 0.5 * (iy & 1)) * a, iy * pitch, 0.0},
                               .mass = def->material.node_mass,
                               .damping = def->material.node_damping,
                               .fixed = fixed};
            int32_t r = ftm_mesh_builder_add_node(b, &nd);
            if (r < 0)
                return ftm_lattice_node_failed(r, who, ftm_mesh_builder_node_count(b), &nd,
                                               err);
        }
    /* forward half of the 6-neighbour stencil: right, and the two nodes of the
     * next row that touch this one (which depend on the row's parity) */
    for (int32_t iy = 0; iy < def->ny; iy++)
        for (int32_t ix = 0; ix < def->nx; ix++) {
            int32_t nbx[3] = {ix + 1, ix - 1 + (iy & 1), ix + (iy & 1)};
            int32_t nby[3] = {iy, iy + 1, iy + 1};
            for (int k = 0; k < 3; k++) {
                if (nbx[k] < 0 || nbx[k] >= def->nx || nby[k] >= def->ny)
                    continue;
                double dx = (nbx[k] - ix) + 0.5 * ((nby[k] & 1) - (iy & 1));
                double dy = (nby[k] - iy) * sqrt(3.0) / 2.0;
                ftm_link_def ld = {.a = base + ix + def->nx * iy,
                                   .b = base + nbx[k] + def->nx * nby[k],
                                   .stiffness =
                                       ftm_lattice_axis_stiffness(&def->material, dx, dy, 0.0),
                                   .rest_length = -1.0}; /* = the rest positions' distance */
                rc = ftm_mesh_builder_add_link(b, &ld);
                if (rc)
                    return ftm_lattice_link_failed(rc, who, def->spacing, def->spacing, err);
            }
        }
    /* surface triangles, counter-clockwise seen from +z: two per cell between rows */
    for (int32_t iy = 0; iy + 1 < def->ny; iy++)
        for (int32_t ix = 0; ix + 1 < def->nx; ix++) {
            int32_t p0 = base + ix + def->nx * iy, p1 = p0 + 1;
            int32_t q0 = p0 + def->nx, q1 = q0 + 1;
            if (iy & 1) { /* this row is shifted right: q0 sits left of p0 */
                rc = ftm_mesh_builder_add_triangle(b, p0, q1, q0);
                if (!rc)
                    rc = ftm_mesh_builder_add_triangle(b, p0, p1, q1);
            } else {
                rc = ftm_mesh_builder_add_triangle(b, p0, p1, q0);
                if (!rc)
                    rc = ftm_mesh_builder_add_triangle(b, p1, q1, q0);
            }
            if (rc)
                return ftm_error_set(err, rc, "%s: cannot add triangle: %s", who, ftm_strerror(rc));
        }
    return FTM_OK;
}

int ftm_generate_lattice3d(ftm_mesh_builder *b, const ftm_lattice3d_def *def, ftm_error *err)
{
    const char *who = "lattice3d";
    if (!b || !def)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", who);
    if (def->nx < 2 || def->ny < 2 || def->nz < 2 ||
        (int64_t)def->nx * def->ny * def->nz > FTM_MAX_LATTICE_NODES)
        return ftm_error_set(err, FTM_EINVAL,
                             "%s: size %d x %d x %d out of range (2..; at most %d nodes)", who,
                             (int)def->nx, (int)def->ny, (int)def->nz, FTM_MAX_LATTICE_NODES);
    const double sp[3] = {def->spacing.x, def->spacing.y, def->spacing.z};
    for (int i = 0; i < 3; i++)
        if (!(sp[i] > 0.0) || !isfinite(sp[i]))
            return ftm_error_set(err, FTM_EINVAL, "%s: spacing %c must be > 0 (got %g)", who,
                                 "xyz"[i], sp[i]);
    const int32_t count[3] = {def->nx, def->ny, def->nz};
    for (int i = 0; i < 3; i++)
        if (!isfinite(sp[i] * (count[i] - 1)))
            return ftm_error_set(err, FTM_EINVAL,
                                 "%s: spacing %c %g m is too large: %d nodes along %c would reach "
                                 "beyond double precision (%g); at most %g m",
                                 who, "xyz"[i], sp[i], (int)count[i], "xyz"[i], DBL_MAX,
                                 DBL_MAX / (count[i] - 1));
    if (def->stencil != FTM_STENCIL_6 && def->stencil != FTM_STENCIL_18 &&
        def->stencil != FTM_STENCIL_26)
        return ftm_error_set(err, FTM_EINVAL, "%s: stencil must be 6, 18 or 26 (got %d)", who,
                             (int)def->stencil);
    for (int i = 0; i < 3; i++)
        if (!(def->class_scale[i] > 0.0) || !isfinite(def->class_scale[i]))
            return ftm_error_set(err, FTM_EINVAL, "%s: link class scale %d must be > 0 (got %g)",
                                 who, i, def->class_scale[i]);
    int rc = ftm_material_check(&def->material, who, err);
    if (rc)
        return rc;

    const int32_t base = ftm_mesh_builder_node_count(b);
    const int32_t nx = def->nx, ny = def->ny, nz = def->nz;
    for (int32_t iz = 0; iz < nz; iz++)
        for (int32_t iy = 0; iy < ny; iy++)
            for (int32_t ix = 0; ix < nx; ix++) {
                const int32_t at[3] = {ix, iy, iz}, dims[3] = {nx, ny, nz};
                bool fixed = ftm_lattice_on_faces(def->fixed_faces, at, dims);
                ftm_node_def nd = {.position = {ix * sp[0], iy * sp[1], iz * sp[2]},
                                   .mass = def->material.node_mass,
                                   .damping = def->material.node_damping,
                                   .fixed = fixed};
                int32_t r = ftm_mesh_builder_add_node(b, &nd);
                if (r < 0)
                    return ftm_lattice_node_failed(r, who, ftm_mesh_builder_node_count(b), &nd,
                                                   err);
            }
    /* forward half-stencil: each undirected link once */
    const int8_t(*off)[3] = ftm_lattice_offsets;
    int noff = ftm_lattice_offset_count(def->stencil);
    for (int32_t iz = 0; iz < nz; iz++)
        for (int32_t iy = 0; iy < ny; iy++)
            for (int32_t ix = 0; ix < nx; ix++)
                for (int k = 0; k < noff; k++) {
                    int32_t jx = ix + off[k][0], jy = iy + off[k][1], jz = iz + off[k][2];
                    if (jx < 0 || jx >= nx || jy < 0 || jy >= ny || jz < 0 || jz >= nz)
                        continue;
                    double dx = off[k][0] * sp[0], dy = off[k][1] * sp[1], dz = off[k][2] * sp[2];
                    int cls = k < 3 ? FTM_LINK_EDGE : k < 9 ? FTM_LINK_FACE_DIAGONAL
                                                            : FTM_LINK_BODY_DIAGONAL;
                    ftm_link_def ld = {
                        .a = base + ix + nx * (iy + ny * iz),
                        .b = base + jx + nx * (jy + ny * jz),
                        .stiffness = def->class_scale[cls] *
                                     ftm_lattice_axis_stiffness(&def->material, dx, dy, dz),
                        .rest_length = -1.0}; /* = the rest positions' distance */
                    rc = ftm_mesh_builder_add_link(b, &ld);
                    if (rc) {
                        const ftm_vec3 s = def->spacing;
                        return ftm_lattice_link_failed(rc, who, fmin(s.x, fmin(s.y, s.z)),
                                           fmax(s.x, fmax(s.y, s.z)), err);
                    }
                }
    /* hexahedral cells, for the FEM reference: bottom face counter-clockwise
     * seen from +z, then the top face */
    for (int32_t iz = 0; iz + 1 < nz; iz++)
        for (int32_t iy = 0; iy + 1 < ny; iy++)
            for (int32_t ix = 0; ix + 1 < nx; ix++) {
                int32_t c = base + ix + nx * (iy + ny * iz), up = nx * ny;
                int32_t h[8] = {c, c + 1, c + 1 + nx, c + nx, c + up, c + 1 + up, c + 1 + nx + up,
                                c + nx + up};
                rc = ftm_mesh_builder_add_hexahedron(b, h);
                if (rc)
                    return ftm_error_set(err, rc, "%s: cannot add hexahedron: %s", who,
                                         ftm_strerror(rc));
            }
    /* surface triangles: two per boundary quad, outward-facing */
    for (int face = 0; face < 6; face++) {
        int ax = face / 2, hi = face & 1;          /* normal axis, max side? */
        int u = (ax + 1) % 3, v = (ax + 2) % 3;   /* in-plane axes, (u, v, ax) right-handed */
        int32_t dims[3] = {nx, ny, nz};
        for (int32_t j = 0; j + 1 < dims[v]; j++)
            for (int32_t i = 0; i + 1 < dims[u]; i++) {
                int32_t c[4][3];
                int32_t q[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
                int32_t id[4];
                for (int t = 0; t < 4; t++) {
                    c[t][ax] = hi ? dims[ax] - 1 : 0;
                    c[t][u] = q[t][0];
                    c[t][v] = q[t][1];
                    id[t] = base + c[t][0] + nx * (c[t][1] + ny * c[t][2]);
                }
                /* counter-clockwise seen from outside: (u, v) order on the max side */
                rc = ftm_lattice_add_quad(b, id, hi);
                if (rc)
                    return ftm_error_set(err, rc, "%s: cannot add triangle: %s", who,
                                         ftm_strerror(rc));
            }
    }
    return FTM_OK;
}
