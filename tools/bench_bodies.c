/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The bodies of the benchmarks; see bench_bodies.h. */
#include "bench_bodies.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int ftm_bench_cube_geometry(ftm_mesh_builder *b, int n, int32_t *loads, ftm_vec3 *load_force,
                            int *nloads, double *spacing, ftm_error *err)
{
    if (n < 4 || n > 64 || n % 2) {
        snprintf(err->message, sizeof err->message,
                 "cube: %d nodes per edge (an even number in 4..64)", n);
        return FTM_EINVAL;
    }
    ftm_lattice3d_def ld = ftm_default_lattice3d_def();
    ld.nx = ld.ny = ld.nz = n;
    double s = 0.1 / (n - 1);
    ld.spacing = (ftm_vec3){s, s, s};
    ld.stencil = FTM_STENCIL_18;
    ld.material.node_mass = 1e-3;
    ld.material.stiffness = 1.0;
    ld.fixed_faces = FTM_FACE_ZMIN;
    int rc = ftm_generate_lattice3d(b, &ld, err);
    if (rc)
        return rc;
    /* the top face's four central nodes (n = 10: 944, 945, 954, 955) */
    const int32_t c = n / 2 - 1, top = n * n * (n - 1);
    for (int i = 0; i < 4; i++) {
        loads[i] = top + (c + i % 2) + n * (c + i / 2);
        load_force[i] = (ftm_vec3){0, 0, -2.5};
    }
    *nloads = 4;
    *spacing = s;
    return FTM_OK;
}

/* Kidney-shaped organ: the cells of a cubic lattice (spacing s) inside an
 * ellipsoid of semi-axes 55 x 30 x 25 mm with a notch on its +y side (the
 * hilum: a sphere of radius 16.5 mm centred 33 mm from the middle). Nodes
 * within 1.5 s of the notch's sphere are clamped (the vessels hold the
 * organ); a probe presses the middle of the convex -y side with 1 N, spread
 * over the five surface nodes nearest to it. Springs on the hexahedra's
 * edges and face diagonals (the 18-neighbour stencil). */
#define KID_A 0.055
#define KID_B 0.030
#define KID_C 0.025
#define KID_S 0.0025

static bool kidney_inside(double x, double y, double z)
{
    double e = (x / KID_A) * (x / KID_A) + (y / KID_B) * (y / KID_B) + (z / KID_C) * (z / KID_C);
    double hy = y - 1.1 * KID_B, r = 0.55 * KID_B;
    return e <= 1.0 && x * x + hy * hy + z * z > r * r;
}

int ftm_bench_organ_geometry(ftm_mesh_builder *b, int32_t *loads, ftm_vec3 *load_force,
                             int *nloads, double *spacing, ftm_error *err)
{
    const double s = KID_S;
    const int nx = (int)(2 * KID_A / s) + 3, ny = (int)(2 * KID_B / s) + 3,
              nz = (int)(2 * KID_C / s) + 3;
    const double x0 = -0.5 * (nx - 1) * s, y0 = -0.5 * (ny - 1) * s, z0 = -0.5 * (nz - 1) * s;
    size_t np = (size_t)nx * ny * nz;
    int32_t *id = malloc(np * sizeof *id);
    uint8_t *in = calloc(np, 1), *used = calloc(np, 1);
    if (!id || !in || !used) {
        free(id);
        free(in);
        free(used);
        snprintf(err->message, sizeof err->message, "organ: out of memory");
        return FTM_ENOMEM;
    }
#define IDX(i, j, k) ((size_t)(i) + (size_t)nx * ((size_t)(j) + (size_t)ny * (size_t)(k)))
    for (int k = 0; k < nz; k++)
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++)
                in[IDX(i, j, k)] = kidney_inside(x0 + i * s, y0 + j * s, z0 + k * s);
    static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                     {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    for (int k = 0; k + 1 < nz; k++) /* a cell is kept when all its corners are inside */
        for (int j = 0; j + 1 < ny; j++)
            for (int i = 0; i + 1 < nx; i++) {
                bool all = true;
                for (int c = 0; c < 8 && all; c++)
                    all = in[IDX(i + corner[c][0], j + corner[c][1], k + corner[c][2])];
                if (all)
                    for (int c = 0; c < 8; c++)
                        used[IDX(i + corner[c][0], j + corner[c][1], k + corner[c][2])] = 1;
            }
    int rc = FTM_OK;
    const double hy = 1.1 * KID_B, hr = 0.55 * KID_B + 1.5 * s;
    for (size_t p = 0; p < np && rc >= 0; p++) {
        id[p] = -1;
        if (!used[p])
            continue;
        int i = (int)(p % (size_t)nx), j = (int)(p / (size_t)nx % (size_t)ny),
            k = (int)(p / ((size_t)nx * (size_t)ny));
        ftm_node_def nd = ftm_default_node_def();
        nd.position = (ftm_vec3){x0 + i * s, y0 + j * s, z0 + k * s};
        nd.mass = 1e-3;
        double dy = nd.position.y - hy;
        nd.fixed = nd.position.x * nd.position.x + dy * dy + nd.position.z * nd.position.z <= hr * hr;
        rc = id[p] = ftm_mesh_builder_add_node(b, &nd);
    }
    /* hexahedra, their 12 edges and 12 face diagonals */
    static const int pairs[24][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6}, {6, 7}, {7, 4},
                                     {0, 4}, {1, 5}, {2, 6}, {3, 7}, {0, 2}, {1, 3}, {4, 6}, {5, 7},
                                     {0, 5}, {1, 4}, {1, 6}, {2, 5}, {2, 7}, {3, 6}, {3, 4}, {0, 7}};
    for (int k = 0; rc >= 0 && k + 1 < nz; k++)
        for (int j = 0; rc >= 0 && j + 1 < ny; j++)
            for (int i = 0; rc >= 0 && i + 1 < nx; i++) {
                int32_t v[8];
                bool all = true;
                for (int c = 0; c < 8 && all; c++) {
                    size_t p = IDX(i + corner[c][0], j + corner[c][1], k + corner[c][2]);
                    all = in[p];
                    v[c] = id[p];
                }
                if (!all)
                    continue;
                rc = ftm_mesh_builder_add_hexahedron(b, v);
                for (int e = 0; rc >= 0 && e < 24; e++) {
                    ftm_link_def l = ftm_default_link_def();
                    l.a = v[pairs[e][0]];
                    l.b = v[pairs[e][1]];
                    l.stiffness = 1.0;
                    rc = ftm_mesh_builder_add_link(b, &l);
                }
            }
    /* the probe: the five nodes nearest to the middle of the -y side */
    double best[5] = {INFINITY, INFINITY, INFINITY, INFINITY, INFINITY};
    int32_t who[5] = {-1, -1, -1, -1, -1};
    for (size_t p = 0; p < np; p++) {
        if (id[p] < 0)
            continue;
        int i = (int)(p % (size_t)nx), j = (int)(p / (size_t)nx % (size_t)ny),
            k = (int)(p / ((size_t)nx * (size_t)ny));
        double dx = x0 + i * s, dy = y0 + j * s + KID_B, dz = z0 + k * s;
        double d2 = dx * dx + dy * dy + dz * dz;
        for (int q = 0; q < 5; q++)
            if (d2 < best[q]) { /* insertion: ties keep the lower index */
                for (int t = 4; t > q; t--) {
                    best[t] = best[t - 1];
                    who[t] = who[t - 1];
                }
                best[q] = d2;
                who[q] = id[p];
                break;
            }
    }
#undef IDX
    free(id);
    free(in);
    free(used);
    if (rc < 0) {
        snprintf(err->message, sizeof err->message, "organ: building the mesh: %s",
                 ftm_strerror(rc));
        return rc;
    }
    for (int q = 0; q < 5; q++) {
        loads[q] = who[q];
        load_force[q] = (ftm_vec3){0, 1.0 / 5, 0};
    }
    *nloads = 5;
    *spacing = s;
    return FTM_OK;
}

int ftm_bench_final_mesh(const ftm_mesh *g, const double *mass, double k, double zeta,
                         ftm_mesh **out, ftm_error *err)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    int32_t n = ftm_mesh_node_count(g);
    int rc = b ? FTM_OK : FTM_ENOMEM;
    for (int32_t i = 0; i < n && rc >= 0; i++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = ftm_mesh_rest_position(g, i);
        nd.mass = mass[i];
        nd.damping = 2.0 * zeta * mass[i];
        nd.fixed = ftm_mesh_fixed(g, i);
        rc = ftm_mesh_builder_add_node(b, &nd);
    }
    for (int32_t l = 0; l < ftm_mesh_link_count(g) && rc >= 0; l++) {
        ftm_link_def ld;
        ftm_mesh_link(g, l, &ld.a, &ld.b, &ld.stiffness, &ld.rest_length);
        ld.stiffness = k;
        rc = ftm_mesh_builder_add_link(b, &ld);
    }
    for (int32_t e = 0; e < ftm_mesh_hexahedron_count(g) && rc >= 0; e++)
        rc = ftm_mesh_builder_add_hexahedron(b, ftm_mesh_hexahedra(g) + 8 * e);
    ftm_mesh_build_def bdef = ftm_default_mesh_build_def();
    bdef.reorder = false;
    if (rc >= 0)
        rc = ftm_mesh_build(b, &bdef, out, err);
    ftm_mesh_builder_destroy(b);
    return rc < 0 ? rc : FTM_OK;
}

int ftm_bench_damping_floor(const ftm_mesh *mesh, double *zeta, ftm_error *err)
{
    ftm_sim *probe = NULL;
    ftm_sim_def d = ftm_default_sim_def();
    d.forces = FTM_FORCES_LINEAR_FEM;
    d.young = FTM_BENCH_YOUNG;
    d.poisson = FTM_BENCH_POISSON;
    double hc_s = ftm_mesh_critical_time_step(mesh);
    int rc = ftm_sim_create(mesh, &d, &probe, err);
    if (!rc)
        *zeta = 0.11 / fmin(hc_s, ftm_sim_critical_time_step(probe));
    ftm_sim_destroy(probe);
    return rc;
}

int ftm_bench_body_geometry(const char *name, ftm_mesh **out, int32_t *loads,
                            ftm_vec3 *load_force, int *nloads, double *spacing, ftm_error *err)
{
    *out = NULL;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    if (!b)
        return ftm_error_set(err, FTM_ENOMEM, "out of memory");
    int rc = strcmp(name, "organ") == 0
                 ? ftm_bench_organ_geometry(b, loads, load_force, nloads, spacing, err)
                 : ftm_bench_cube_geometry(b, strcmp(name, "tiny") == 0 ? 4 : 10, loads,
                                           load_force, nloads, spacing, err);
    if (!rc)
        rc = ftm_mesh_build(b, NULL, out, err);
    ftm_mesh_builder_destroy(b);
    return rc;
}
