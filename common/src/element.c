/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Linear elastic element matrices: the isotropic D matrix, the trilinear
 * hexahedron with 2x2x2 Gauss integration and the constant-strain
 * tetrahedron, plus lumped masses. They live in the core because the
 * integrator's FEM forces (sim_elem.c) need them; the FEM reference
 * (common/fem) calls the same routines. Formulation: docs/fem.md. */
#include "ftm/mesh.h"

#include "error.h"
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void ftm_elasticity_matrix(double young, double poisson, double d[36])
{
    double e = young, nu = poisson;
    double c = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
    memset(d, 0, 36 * sizeof *d);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            d[6 * i + j] = c * (i == j ? 1.0 - nu : nu);
    for (int i = 3; i < 6; i++)
        d[6 * i + i] = c * (1.0 - 2.0 * nu) / 2.0;
}

/* Strain-displacement rows of one node with shape-function gradient g:
 * columns 3a..3a+2 of B. */
static void node_b(const double g[3], double b[6][3])
{
    memset(b, 0, 18 * sizeof(double));
    b[0][0] = g[0];
    b[1][1] = g[1];
    b[2][2] = g[2];
    b[3][0] = g[1]; /* gamma_xy */
    b[3][1] = g[0];
    b[4][1] = g[2]; /* gamma_yz */
    b[4][2] = g[1];
    b[5][0] = g[2]; /* gamma_zx */
    b[5][2] = g[0];
}

/* ke += w * B^T D B for nn nodes with gradients grad[a][3]; ke is (3nn)^2. */
static void add_btdb(int nn, const double (*grad)[3], const double d[36], double w, double *ke)
{
    int n = 3 * nn;
    double b[8][6][3]; /* B, node by node */
    double db[6][24];  /* D B */
    for (int a = 0; a < nn; a++)
        node_b(grad[a], b[a]);
    for (int i = 0; i < 6; i++)
        for (int a = 0; a < nn; a++)
            for (int k = 0; k < 3; k++) {
                double s = 0.0;
                for (int j = 0; j < 6; j++)
                    s += d[6 * i + j] * b[a][j][k];
                db[i][3 * a + k] = s;
            }
    for (int a = 0; a < nn; a++)
        for (int k = 0; k < 3; k++) {
            int row = 3 * a + k;
            for (int col = 0; col < n; col++) {
                double s = 0.0;
                for (int i = 0; i < 6; i++)
                    s += b[a][i][k] * db[i][col];
                ke[row * n + col] += w * s;
            }
        }
}

static double det3(const double m[9])
{
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
           m[2] * (m[3] * m[7] - m[4] * m[6]);
}

static void inv3(const double m[9], double det, double out[9])
{
    out[0] = (m[4] * m[8] - m[5] * m[7]) / det;
    out[1] = (m[2] * m[7] - m[1] * m[8]) / det;
    out[2] = (m[1] * m[5] - m[2] * m[4]) / det;
    out[3] = (m[5] * m[6] - m[3] * m[8]) / det;
    out[4] = (m[0] * m[8] - m[2] * m[6]) / det;
    out[5] = (m[2] * m[3] - m[0] * m[5]) / det;
    out[6] = (m[3] * m[7] - m[4] * m[6]) / det;
    out[7] = (m[1] * m[6] - m[0] * m[7]) / det;
    out[8] = (m[0] * m[4] - m[1] * m[3]) / det;
}

static const double hex_corner[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                        {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};

/* At natural point (r, s, t): dN_a / d(r, s, t) into dn (and the shape
 * values n[a] unless NULL), and the Jacobian's determinant; its inverse
 * into ji unless det J <= 0. */
static double hex_jacobian(const ftm_vec3 x[8], double r, double s, double t, double *n,
                           double dn[8][3], double ji[9])
{
    for (int a = 0; a < 8; a++) {
        double ra = hex_corner[a][0], sa = hex_corner[a][1], ta = hex_corner[a][2];
        dn[a][0] = 0.125 * ra * (1.0 + s * sa) * (1.0 + t * ta);
        dn[a][1] = 0.125 * sa * (1.0 + r * ra) * (1.0 + t * ta);
        dn[a][2] = 0.125 * ta * (1.0 + r * ra) * (1.0 + s * sa);
        if (n)
            n[a] = 0.125 * (1.0 + r * ra) * (1.0 + s * sa) * (1.0 + t * ta);
    }
    double jac[9] = {0}; /* J[i][j] = d x_i / d xi_j */
    for (int a = 0; a < 8; a++) {
        const double p[3] = {x[a].x, x[a].y, x[a].z};
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                jac[3 * i + j] += p[i] * dn[a][j];
    }
    double det = det3(jac);
    if (det > 0.0)
        inv3(jac, det, ji);
    return det;
}

/* At natural point (r, s, t): shape values n[a] (may be NULL), gradients
 * grad[a] = dN_a/dx and det J. Returns det J; grad is left unset if det J <= 0. */
static double hex_point(const ftm_vec3 x[8], double r, double s, double t, double *n,
                        double grad[8][3])
{
    double dn[8][3], ji[9];
    double det = hex_jacobian(x, r, s, t, n, dn, ji);
    if (!(det > 0.0))
        return det;
    for (int a = 0; a < 8; a++) /* dN_a / dx_i = sum_j dN_a/dxi_j (J^-1)_ji */
        for (int i = 0; i < 3; i++)
            grad[a][i] = dn[a][0] * ji[0 * 3 + i] + dn[a][1] * ji[1 * 3 + i] +
                         dn[a][2] * ji[2 * 3 + i];
    return det;
}

int ftm_hex8_stiffness(const ftm_vec3 x[8], double young, double poisson, double ke[576],
                       double *min_det)
{
    double d[36];
    ftm_elasticity_matrix(young, poisson, d);
    memset(ke, 0, 576 * sizeof *ke);
    const double g = 1.0 / sqrt(3.0);
    double lowest = INFINITY;
    for (int q = 0; q < 8; q++) {
        /* Gauss point q: the corner pattern scaled by 1/sqrt(3); weights 1 */
        double grad[8][3];
        double det = hex_point(x, g * hex_corner[q][0], g * hex_corner[q][1],
                               g * hex_corner[q][2], NULL, grad);
        if (det < lowest)
            lowest = det;
        if (!(det > 0.0))
            continue; /* reported below; keep scanning for the smallest */
        add_btdb(8, (const double(*)[3])grad, d, det, ke);
    }
    if (min_det)
        *min_det = lowest;
    if (!(lowest > 0.0)) {
        memset(ke, 0, 576 * sizeof *ke);
        return FTM_EINVAL;
    }
    return FTM_OK;
}

int ftm_hex8_centre_gradients(const ftm_vec3 x[8], double grad[24])
{
    double g[8][3];
    if (!(hex_point(x, 0.0, 0.0, 0.0, NULL, g) > 0.0))
        return FTM_EINVAL;
    memcpy(grad, g, sizeof g);
    return FTM_OK;
}

int ftm_hex8_gauss_gradients(const ftm_vec3 x[8], double grad[192], double det[8])
{
    const double g = 1.0 / sqrt(3.0); /* the points of ftm_hex8_stiffness, in its order */
    for (int q = 0; q < 8; q++) {
        double gq[8][3];
        det[q] = hex_point(x, g * hex_corner[q][0], g * hex_corner[q][1], g * hex_corner[q][2],
                           NULL, gq);
        if (!(det[q] > 0.0))
            return FTM_EINVAL;
        memcpy(grad + 24 * q, gq, sizeof gq);
    }
    return FTM_OK;
}

int ftm_hex8_inverse_jacobians(const ftm_vec3 x[8], double ji[81], double det[8])
{
    const double g = 1.0 / sqrt(3.0); /* the points of ftm_hex8_stiffness, then the centre */
    double dn[8][3];
    for (int q = 0; q < 9; q++) {
        const double d = q < 8 ? hex_jacobian(x, g * hex_corner[q][0], g * hex_corner[q][1],
                                              g * hex_corner[q][2], NULL, dn, ji + 9 * q)
                               : hex_jacobian(x, 0.0, 0.0, 0.0, NULL, dn, ji + 9 * q);
        if (!(d > 0.0))
            return FTM_EINVAL;
        if (q < 8)
            det[q] = d;
    }
    return FTM_OK;
}

int ftm_hex8_lumped_mass(const ftm_vec3 x[8], double density, double mass[8])
{
    const double g = 1.0 / sqrt(3.0);
    memset(mass, 0, 8 * sizeof *mass);
    for (int q = 0; q < 8; q++) {
        double n[8], grad[8][3];
        double det = hex_point(x, g * hex_corner[q][0], g * hex_corner[q][1],
                               g * hex_corner[q][2], n, grad);
        if (!(det > 0.0))
            return FTM_EINVAL;
        for (int a = 0; a < 8; a++) /* row sum of the consistent mass: int rho N_a dV */
            mass[a] += density * n[a] * det;
    }
    return FTM_OK;
}

/* J = [b - a, c - a, d - a] as columns: x = a + J xi with N = (1 - sum xi, xi1, xi2, xi3).
 * Returns 6 V (signed); grad gets dN_a/dx unless degenerate. */
static double tet_gradients(const ftm_vec3 x[4], double grad[4][3], bool *degenerate)
{
    double jac[9];
    const ftm_vec3 e[3] = {{x[1].x - x[0].x, x[1].y - x[0].y, x[1].z - x[0].z},
                           {x[2].x - x[0].x, x[2].y - x[0].y, x[2].z - x[0].z},
                           {x[3].x - x[0].x, x[3].y - x[0].y, x[3].z - x[0].z}};
    for (int j = 0; j < 3; j++) {
        jac[0 * 3 + j] = e[j].x;
        jac[1 * 3 + j] = e[j].y;
        jac[2 * 3 + j] = e[j].z;
    }
    double det = det3(jac);
    double longest = 0.0;
    for (int a = 0; a < 4; a++)
        for (int b = a + 1; b < 4; b++) {
            double dx = x[b].x - x[a].x, dy = x[b].y - x[a].y, dz = x[b].z - x[a].z;
            double l = sqrt(dx * dx + dy * dy + dz * dz);
            if (l > longest)
                longest = l;
        }
    *degenerate = !(fabs(det) > 1e-12 * longest * longest * longest);
    if (*degenerate)
        return det;
    double ji[9];
    inv3(jac, det, ji);
    static const double dn[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int a = 0; a < 4; a++)
        for (int i = 0; i < 3; i++)
            grad[a][i] = dn[a][0] * ji[0 * 3 + i] + dn[a][1] * ji[1 * 3 + i] +
                         dn[a][2] * ji[2 * 3 + i];
    return det;
}

int ftm_tet4_stiffness(const ftm_vec3 x[4], double young, double poisson, double ke[144],
                       double *signed_volume)
{
    double grad[4][3];
    bool degenerate;
    double det = tet_gradients(x, grad, &degenerate);
    if (signed_volume)
        *signed_volume = det / 6.0;
    memset(ke, 0, 144 * sizeof *ke);
    if (degenerate)
        return FTM_EINVAL;
    double d[36];
    ftm_elasticity_matrix(young, poisson, d);
    add_btdb(4, (const double(*)[3])grad, d, fabs(det) / 6.0, ke);
    return FTM_OK;
}

int ftm_tet4_gradients(const ftm_vec3 x[4], double grad[12])
{
    double g[4][3];
    bool degenerate;
    tet_gradients(x, g, &degenerate);
    if (degenerate)
        return FTM_EINVAL;
    memcpy(grad, g, sizeof g);
    return FTM_OK;
}

static void element_points(const ftm_mesh *m, const int32_t *nodes, int nn, ftm_vec3 *x)
{
    for (int a = 0; a < nn; a++) {
        const double *p = m->rest + 3 * nodes[a];
        x[a] = (ftm_vec3){p[0], p[1], p[2]};
    }
}

/* density, or per element (hexahedra, then tetrahedra) from each[] */
static int lumped_masses(const ftm_mesh *m, double density, const double *each, double *mass,
                         ftm_error *err)
{
    if (!m || !mass)
        return ftm_error_set(err, FTM_EINVAL, "lumped masses: null argument");
    if (!each && (!(density > 0.0) || !isfinite(density)))
        return ftm_error_set(err, FTM_EINVAL, "lumped masses: density must be > 0 (got %g)",
                             density);
    for (int32_t e = 0; each && e < m->hex_count + m->tet_count; e++)
        if (!(each[e] > 0.0) || !isfinite(each[e]))
            return ftm_error_set(err, FTM_EINVAL,
                                 "lumped masses: %s %d: density must be > 0 (got %g)",
                                 e < m->hex_count ? "hexahedron" : "tetrahedron",
                                 (int)(e < m->hex_count ? e : e - m->hex_count), each[e]);
    if (m->hex_count + m->tet_count == 0)
        return ftm_error_set(err, FTM_EINVAL,
                             "lumped masses: mesh has no hexahedra or tetrahedra");
    double *out = calloc((size_t)m->node_count + 1, sizeof *out);
    if (!out)
        return ftm_error_set(err, FTM_ENOMEM, "lumped masses: out of memory");
    for (int32_t e = 0; e < m->hex_count; e++) {
        ftm_vec3 x[8];
        double me[8];
        element_points(m, m->hexes + 8 * e, 8, x);
        if (ftm_hex8_lumped_mass(x, each ? each[e] : density, me) != FTM_OK) {
            free(out);
            return ftm_error_set(err, FTM_EINVAL,
                                 "hexahedron %d is inverted or degenerate (det J <= 0)", (int)e);
        }
        for (int a = 0; a < 8; a++)
            out[m->hexes[8 * e + a]] += me[a];
    }
    for (int32_t e = 0; e < m->tet_count; e++) {
        ftm_vec3 x[4];
        double g[12];
        element_points(m, m->tets + 4 * e, 4, x);
        if (ftm_tet4_gradients(x, g) != FTM_OK) {
            free(out);
            return ftm_error_set(err, FTM_EINVAL, "tetrahedron %d is degenerate", (int)e);
        }
        double ax = x[1].x - x[0].x, ay = x[1].y - x[0].y, az = x[1].z - x[0].z;
        double bx = x[2].x - x[0].x, by = x[2].y - x[0].y, bz = x[2].z - x[0].z;
        double cx = x[3].x - x[0].x, cy = x[3].y - x[0].y, cz = x[3].z - x[0].z;
        double v6 = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx);
        const double rho = each ? each[m->hex_count + e] : density;
        for (int a = 0; a < 4; a++)
            out[m->tets[4 * e + a]] += rho * fabs(v6) / 24.0; /* rho V / 4 */
    }
    memcpy(mass, out, (size_t)m->node_count * sizeof *out);
    free(out);
    return FTM_OK;
}

int ftm_mesh_lumped_masses(const ftm_mesh *m, double density, double *mass, ftm_error *err)
{
    return lumped_masses(m, density, NULL, mass, err);
}

int ftm_mesh_lumped_masses_each(const ftm_mesh *m, const double *density, double *mass,
                                ftm_error *err)
{
    if (!density)
        return ftm_error_set(err, FTM_EINVAL, "lumped masses: null argument");
    return lumped_masses(m, 0.0, density, mass, err);
}
