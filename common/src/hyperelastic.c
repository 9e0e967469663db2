/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The compressible neo-Hookean solid (CalculiX's *HYPERELASTIC, NEO HOOKE):
 *     W = C10 (J^(-2/3) I1 - 3) + (J - 1)^2 / D1,  C10 = mu/2, D1 = 2/kappa,
 * I1 = tr(F^T F), J = det F, and its first Piola-Kirchhoff stress
 *     P = mu J^(-2/3) (F - I1/(3J) cof F) + kappa (J - 1) cof F,
 * cof F = J F^-T. Linearised at F = I it is Hooke's law with the shear
 * modulus mu and the bulk modulus kappa, so an element's tangent stiffness
 * at rest is the linear K_e of element.c with the same quadrature.
 *
 * Determinism: only + - * / and frexp/ldexp (exact scaling by powers of
 * two). libm's cbrt, pow, exp and log are not used: glibc picks an FMA
 * variant of them at run time, which would change the bits per CPU. */
#include "hyperelastic.h"

#include <math.h>
#include <string.h>

/* The general case: j = v 2^(e-1), v in [1, 2); e - 1 = 3q + r, r in
 * {0, 1, 2}; then j^(-1/3) = (v 2^r)^(-1/3) 2^(-q). */
static double inv_cbrt_scaled(double j)
{
    int e;
    double v = 2.0 * frexp(j, &e);
    int k = e - 1, q = k >= 0 ? k / 3 : -((2 - k) / 3), r = k - 3 * q;
    double t = ldexp(v, r);
    /* start: the chord of v^(-1/3) over [1, 2] (within 2.7 %) times an
     * approximate 2^(-r/3); each Newton step squares the relative error
     * (e <- about 2 e^2): 1.5e-3, 4.5e-6, 4e-11, round-off */
    static const double scale[3] = {1.0, 0.79370052598409974, 0.62996052494743658};
    double y = (1.0 - 0.20629947401590026 * (v - 1.0)) * scale[r];
    for (int it = 0; it < 5; it++)
        y += y * ((1.0 - t * (y * y * y)) * (1.0 / 3.0));
    return ldexp(y, -q);
}

static inline __attribute__((always_inline)) double inv_cbrt(double j)
{
    /* Newton's step for y = j^(-1/3), y <- y (4 - j y^3) / 3, written as a
     * correction so that the inexact 1/3 only rounds the correction */
    const double d = j - 1.0;
    if (d >= -0.125 && d <= 0.125) {
        /* the Taylor series to d^3 is within 35/243 |d|^4 (3.6e-5 here);
         * three steps: 2.6e-9, 1.4e-17: round-off */
        double y = 1.0 + d * (-1.0 / 3.0 + d * (2.0 / 9.0 + d * (-14.0 / 81.0)));
        for (int it = 0; it < 3; it++)
            y += y * ((1.0 - j * (y * y * y)) * (1.0 / 3.0));
        return y;
    }
    return inv_cbrt_scaled(j);
}

double ftm_inv_cbrt(double j) { return inv_cbrt(j); }

/* J - 1 = det(I + h) - 1 = tr h + (the principal 2x2 minors of h) + det h,
 * without the cancellation of det F - 1 */
static inline __attribute__((always_inline)) double det_minus_one(const double h[9])
{
    const double tr = h[0] + h[4] + h[8];
    const double minors = (h[0] * h[4] - h[1] * h[3]) + (h[0] * h[8] - h[2] * h[6]) +
                          (h[4] * h[8] - h[5] * h[7]);
    const double deth = h[0] * (h[4] * h[8] - h[5] * h[7]) - h[1] * (h[3] * h[8] - h[5] * h[6]) +
                        h[2] * (h[3] * h[7] - h[4] * h[6]);
    return tr + minors + deth;
}

/* P at F = I + h from J - 1 (jm1) and y = J^(-1/3) */
static inline __attribute__((always_inline)) void stress(const double h[9], double jm1, double y,
                                                         double mu, double kappa, double p[9])
{
    const double f[9] = {1.0 + h[0], h[1], h[2], h[3], 1.0 + h[4], h[5], h[6], h[7], 1.0 + h[8]};
    const double c[9] = {f[4] * f[8] - f[5] * f[7], f[5] * f[6] - f[3] * f[8],
                         f[3] * f[7] - f[4] * f[6], f[2] * f[7] - f[1] * f[8],
                         f[0] * f[8] - f[2] * f[6], f[1] * f[6] - f[0] * f[7],
                         f[1] * f[5] - f[2] * f[4], f[2] * f[3] - f[0] * f[5],
                         f[0] * f[4] - f[1] * f[3]};
    const double j = 1.0 + jm1, tr = h[0] + h[4] + h[8];
    double hh = 0.0;
    for (int i = 0; i < 9; i++)
        hh += h[i] * h[i];
    const double i1 = 3.0 + (2.0 * tr + hh);
    const double a = mu * (y * y);
    /* I1 / 3J is exactly 1 at F = I, so P is exactly 0 there */
    const double b = a * (i1 / (3.0 * j)) - kappa * jm1;
    for (int i = 0; i < 9; i++)
        p[i] = a * f[i] - b * c[i];
}

static inline bool valid_det(double j) { return j > 0.0 && isfinite(j); }

bool ftm_neo_stress(const double h[9], double mu, double kappa, double p[9], double *jout)
{
    const double jm1 = det_minus_one(h), j = 1.0 + jm1;
    *jout = j;
    if (!valid_det(j))
        return false;
    stress(h, jm1, inv_cbrt(j), mu, kappa, p);
    return true;
}

/* h = sum_b u_b g_b^T over the element's nodes at one point */
static inline __attribute__((always_inline)) void
displacement_gradient(int nn, const double *g, const double *u, double h[9])
{
    for (int i = 0; i < 9; i++)
        h[i] = 0.0;
    for (int b = 0; b < nn; b++) {
        const double *ub = u + 3 * b, *gb = g + 3 * b;
        for (int i = 0; i < 3; i++) {
            h[3 * i] += ub[i] * gb[0];
            h[3 * i + 1] += ub[i] * gb[1];
            h[3 * i + 2] += ub[i] * gb[2];
        }
    }
}

/* In three passes over the points, so that the points' independent chains
 * of dependent operations (the cube root's Newton steps above all) overlap
 * in the processor instead of waiting on each other. */
static inline __attribute__((always_inline)) bool
element_forces(int nn, int nq, const double *gp, const double *u, double mu, double kappa,
               double *fe, double *min_det)
{
    const int stride = 3 * nn + 1;
    double h[8][9], jm1[8], y[8], lowest = INFINITY;
    memset(fe, 0, (size_t)(3 * nn) * sizeof *fe);
    for (int q = 0; q < nq; q++) {
        displacement_gradient(nn, gp + q * stride, u, h[q]);
        jm1[q] = det_minus_one(h[q]);
        const double j = 1.0 + jm1[q];
        lowest = j < lowest || j != j ? j : lowest;
        if (!valid_det(j)) {
            *min_det = lowest;
            return false;
        }
    }
    for (int q = 0; q < nq; q++)
        y[q] = inv_cbrt(1.0 + jm1[q]);
    for (int q = 0; q < nq; q++) {
        const double *g = gp + q * stride, w = g[3 * nn];
        double p[9];
        stress(h[q], jm1[q], y[q], mu, kappa, p);
        for (int i = 0; i < 9; i++)
            p[i] *= w;
        for (int a = 0; a < nn; a++) {
            const double *ga = g + 3 * a;
            double *fa = fe + 3 * a;
            fa[0] += p[0] * ga[0] + p[1] * ga[1] + p[2] * ga[2];
            fa[1] += p[3] * ga[0] + p[4] * ga[1] + p[5] * ga[2];
            fa[2] += p[6] * ga[0] + p[7] * ga[1] + p[8] * ga[2];
        }
    }
    *min_det = lowest;
    return true;
}

/* the two element types, their sizes known to the compiler */
bool ftm_neo_element_forces(int nn, int nq, const double *gp, const double *u, double mu,
                            double kappa, double *fe, double *min_det)
{
    if (nn == 8 && nq == 8)
        return element_forces(8, 8, gp, u, mu, kappa, fe, min_det);
    if (nn == 4 && nq == 1)
        return element_forces(4, 1, gp, u, mu, kappa, fe, min_det);
    memset(fe, 0, (size_t)(3 * nn) * sizeof *fe);
    *min_det = NAN;
    return false;
}
