/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Materials and element matrices of the linear FEM reference: the isotropic
 * D matrix, the trilinear hexahedron with 2x2x2 Gauss integration and the
 * constant-strain tetrahedron (computed by the core, element.c). The
 * formulation is written out in docs/fem.md. */
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
        return ftm_error_set(err, FTM_EINVAL, "%s: no material", what);
    if (!isfinite(m->young) || !(m->young > 0))
        return ftm_error_set(err, FTM_EINVAL, "%s: Young's modulus must be > 0, got %g", what,
                            m->young);
    if (!isfinite(m->poisson) || !(m->poisson > -1.0) || !(m->poisson < 0.5))
        return ftm_error_set(err, FTM_EINVAL,
                            "%s: Poisson's ratio must be > -1 and < 0.5, got %g", what,
                            m->poisson);
    return FTM_OK;
}

void ftm_fem_elasticity_matrix(const ftm_fem_material *m, double d[36])
{
    ftm_elasticity_matrix(m->young, m->poisson, d);
}

/* The element matrices live in the core (common/src/element.c), which the
 * integrator's element forces share; these keep the FEM reference's API. */
int ftm_fem_hex_stiffness(const ftm_vec3 x[8], const ftm_fem_material *m, double ke[576],
                          double *min_det)
{
    return ftm_hex8_stiffness(x, m->young, m->poisson, ke, min_det);
}

int ftm_fem_tet_stiffness(const ftm_vec3 x[4], const ftm_fem_material *m, double ke[144],
                          double *signed_volume)
{
    return ftm_tet4_stiffness(x, m->young, m->poisson, ke, signed_volume);
}
