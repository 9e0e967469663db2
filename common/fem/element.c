/* Element matrices of the linear FEM reference: the isotropic D matrix, the
 * trilinear hexahedron with 2x2x2 Gauss integration and the constant-strain
 * tetrahedron. The formulation is written out in docs/fem.md. */
#include "ftm/fem.h"

#include "fem_internal.h"

#include <math.h>
#include <string.h>

ftm_fem_material ftm_default_fem_material(void)
{
    return (ftm_fem_material){.young = 1.0, .poisson = 0.3};
}

int ftm_fem_check_material(const ftm_fem_material *m, const char *what, ftm_error *err)
{
    if (!m)
        return ftm_fem_fail(err, FTM_EINVAL, "%s: no material", what);
    if (!isfinite(m->young) || !(m->young > 0))
        return ftm_fem_fail(err, FTM_EINVAL, "%s: Young's modulus must be > 0, got %g", what,
                            m->young);
    if (!isfinite(m->poisson) || !(m->poisson > -1.0) || !(m->poisson < 0.5))
        return ftm_fem_fail(err, FTM_EINVAL,
                            "%s: Poisson's ratio must be > -1 and < 0.5, got %g", what,
                            m->poisson);
    return FTM_OK;
}

void ftm_fem_elasticity_matrix(const ftm_fem_material *m, double d[36])
{
    double e = m->young, nu = m->poisson;
    double c = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
    memset(d, 0, 36 * sizeof *d);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            d[6 * i + j] = c * (i == j ? 1.0 - nu : nu);
    for (int i = 3; i < 6; i++)
        d[6 * i + i] = c * (1.0 - 2.0 * nu) / 2.0;
}

/* Strain-displacement rows of one node with shape-function gradient g:
 * column 3a+k of B. Writes b[6][3] for that node. */
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
    double b[8][6][3];  /* B, node by node */
    double db[6][24];   /* D B */
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

/* Determinant and inverse of a 3x3 matrix (row-major). */
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

int ftm_fem_hex_stiffness(const ftm_vec3 x[8], const ftm_fem_material *m, double ke[576],
                          double *min_det)
{
    double d[36];
    ftm_fem_elasticity_matrix(m, d);
    memset(ke, 0, 576 * sizeof *ke);
    const double g = 1.0 / sqrt(3.0);
    double lowest = INFINITY;
    for (int q = 0; q < 8; q++) {
        /* Gauss point q: the corner pattern scaled by 1/sqrt(3); weights 1 */
        double r = g * hex_corner[q][0], s = g * hex_corner[q][1], t = g * hex_corner[q][2];
        double dn[8][3]; /* dN_a / d(r, s, t) */
        for (int a = 0; a < 8; a++) {
            double ra = hex_corner[a][0], sa = hex_corner[a][1], ta = hex_corner[a][2];
            dn[a][0] = 0.125 * ra * (1.0 + s * sa) * (1.0 + t * ta);
            dn[a][1] = 0.125 * sa * (1.0 + r * ra) * (1.0 + t * ta);
            dn[a][2] = 0.125 * ta * (1.0 + r * ra) * (1.0 + s * sa);
        }
        double jac[9] = {0}; /* J[i][j] = d x_i / d xi_j */
        for (int a = 0; a < 8; a++) {
            const double p[3] = {x[a].x, x[a].y, x[a].z};
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    jac[3 * i + j] += p[i] * dn[a][j];
        }
        double det = det3(jac);
        if (det < lowest)
            lowest = det;
        if (!(det > 0.0))
            continue; /* reported below; keep scanning for the smallest */
        double ji[9];
        inv3(jac, det, ji);
        double grad[8][3]; /* dN_a / dx_i = sum_j dN_a/dxi_j (J^-1)_ji */
        for (int a = 0; a < 8; a++)
            for (int i = 0; i < 3; i++)
                grad[a][i] = dn[a][0] * ji[0 * 3 + i] + dn[a][1] * ji[1 * 3 + i] +
                             dn[a][2] * ji[2 * 3 + i];
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

int ftm_fem_tet_stiffness(const ftm_vec3 x[4], const ftm_fem_material *m, double ke[144],
                          double *signed_volume)
{
    /* J = [b - a, c - a, d - a] as columns: x = a + J xi with N = (1 - sum xi, xi1, xi2, xi3) */
    double jac[9];
    const ftm_vec3 e[3] = {{x[1].x - x[0].x, x[1].y - x[0].y, x[1].z - x[0].z},
                           {x[2].x - x[0].x, x[2].y - x[0].y, x[2].z - x[0].z},
                           {x[3].x - x[0].x, x[3].y - x[0].y, x[3].z - x[0].z}};
    for (int j = 0; j < 3; j++) {
        jac[0 * 3 + j] = e[j].x;
        jac[1 * 3 + j] = e[j].y;
        jac[2 * 3 + j] = e[j].z;
    }
    double det = det3(jac); /* 6 V, signed */
    if (signed_volume)
        *signed_volume = det / 6.0;
    double longest = 0.0;
    for (int a = 0; a < 4; a++)
        for (int b = a + 1; b < 4; b++) {
            double dx = x[b].x - x[a].x, dy = x[b].y - x[a].y, dz = x[b].z - x[a].z;
            double l = sqrt(dx * dx + dy * dy + dz * dz);
            if (l > longest)
                longest = l;
        }
    memset(ke, 0, 144 * sizeof *ke);
    if (!(fabs(det) > 1e-12 * longest * longest * longest))
        return FTM_EINVAL;
    double ji[9];
    inv3(jac, det, ji);
    static const double dn[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    double grad[4][3];
    for (int a = 0; a < 4; a++)
        for (int i = 0; i < 3; i++)
            grad[a][i] = dn[a][0] * ji[0 * 3 + i] + dn[a][1] * ji[1 * 3 + i] +
                         dn[a][2] * ji[2 * 3 + i];
    double d[36];
    ftm_fem_elasticity_matrix(m, d);
    add_btdb(4, (const double(*)[3])grad, d, fabs(det) / 6.0, ke);
    return FTM_OK;
}
