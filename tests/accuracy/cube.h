/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Test helpers of tests/accuracy (include after cmocka.h, ftm/fem.h and
 * ftm/ftm.h): the elastin cube of the paper as a lattice or Kuhn
 * tetrahedra, loads on its top face, the FEM reference, settling. */
#ifndef FTM_TESTS_ACCURACY_CUBE_H
#define FTM_TESTS_ACCURACY_CUBE_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define YOUNG 0.6e6
#define POISSON 0.45
#define DENSITY 1040.0
#define SIDE 0.1

static inline void assert_contains(const char *text, const char *part)
{
    if (!strstr(text, part))
        fail_msg("message '%s' does not contain '%s'", text, part);
}

/* A SIDE-metre cube of n^3 nodes, 18-neighbour springs; hexahedra, or (tets)
 * 6 Kuhn tetrahedra per cell with springs on their edges. fixed: bottom face. */
static inline ftm_mesh *cube(int n, bool tets, bool fixed, double damping)
{
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    double s = SIDE / (n - 1);
    if (!tets) {
        ftm_lattice3d_def ld = ftm_default_lattice3d_def();
        ld.nx = ld.ny = ld.nz = n;
        ld.spacing = (ftm_vec3){s, s, s};
        ld.stencil = FTM_STENCIL_18;
        ld.material.node_mass = 1e-3;
        ld.material.node_damping = damping;
        ld.material.stiffness = 1000;
        ld.fixed_faces = fixed ? FTM_FACE_ZMIN : 0;
        assert_int_equal(ftm_generate_lattice3d(b, &ld, &err), FTM_OK);
    } else {
        for (int k = 0; k < n; k++)
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++) {
                    ftm_node_def nd = ftm_default_node_def();
                    nd.position = (ftm_vec3){i * s, j * s, k * s};
                    nd.mass = 1e-3;
                    nd.damping = damping;
                    nd.fixed = fixed && k == 0;
                    assert_true(ftm_mesh_builder_add_node(b, &nd) >= 0);
                }
        /* Kuhn split of each cell along its (0,0,0)-(1,1,1) diagonal */
        static const int path[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                       {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (int k = 0; k + 1 < n; k++)
            for (int j = 0; j + 1 < n; j++)
                for (int i = 0; i + 1 < n; i++)
                    for (int t = 0; t < 6; t++) {
                        int c[3] = {i, j, k}, v[4];
                        v[0] = c[0] + n * (c[1] + n * c[2]);
                        for (int st = 0; st < 3; st++) {
                            c[path[t][st]]++;
                            v[st + 1] = c[0] + n * (c[1] + n * c[2]);
                        }
                        if (path[t][0] == (path[t][1] + 1) % 3) { /* odd: keep all positive */
                            int sw = v[2];
                            v[2] = v[3];
                            v[3] = sw;
                        }
                        assert_int_equal(
                            ftm_mesh_builder_add_tetrahedron(b, v[0], v[1], v[2], v[3]), FTM_OK);
                        for (int p = 0; p < 4; p++)
                            for (int q = p + 1; q < 4; q++) {
                                ftm_link_def l = ftm_default_link_def();
                                l.a = v[p];
                                l.b = v[q];
                                l.stiffness = 1000;
                                assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
                            }
                    }
    }
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    return m;
}

/* Total force `total` (downward) on the top face's central nodes: the four
 * around the centre for even n, the centre node for odd n. */
static inline int top_load(const ftm_mesh *m, int n, double total, ftm_contact *c, double *forces)
{
    int lo = (n - 1) / 2, hi = n / 2, count = 0;
    int per = (hi - lo + 1) * (hi - lo + 1);
    memset(forces, 0, sizeof(double) * 3 * (size_t)ftm_mesh_node_count(m));
    for (int j = lo; j <= hi; j++)
        for (int i = lo; i <= hi; i++) {
            int32_t node = ftm_mesh_node_of_input(m, i + n * (j + n * (n - 1)));
            c[count] = (ftm_contact){.node = node, .group = 0, .kind = FTM_CONTACT_FORCE,
                                     .value = {0, 0, -total / per}};
            forces[3 * node + 2] = -total / per;
            count++;
        }
    return count;
}

static inline double *fem_solution(const ftm_mesh *m, const double *forces)
{
    ftm_error err;
    ftm_fem_def fd = ftm_default_fem_def();
    fd.material = (ftm_fem_material){.young = YOUNG, .poisson = POISSON};
    ftm_fem *fem = NULL;
    assert_int_equal(ftm_fem_create(m, &fd, &fem, &err), FTM_OK);
    double *u = malloc(sizeof(double) * 3 * (size_t)ftm_mesh_node_count(m));
    assert_int_equal(ftm_fem_solve(fem, forces, NULL, u, &err), FTM_OK);
    ftm_fem_destroy(fem);
    return u;
}

static inline ftm_sim_def elem_def(ftm_forces forces, ftm_order order)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.forces = forces;
    d.young = YOUNG;
    d.poisson = POISSON;
    d.density = DENSITY;
    d.order = order;
    d.depth = 1000;
    return d;
}

/* Rebuilds the mesh with nodal damping 2 w1 m_i (m_i the lumped masses): the
 * fundamental mode critically damped, for a quick approach to equilibrium;
 * w1^2 from the Rayleigh quotient f.u / u.M u of the static solution. The
 * time step is half the critical one. Returns the damped simulation. */
static inline ftm_sim *damped_sim(const ftm_mesh *m, ftm_sim_def d, const double *u, const double *f,
                           ftm_mesh **damped)
{
    ftm_error err;
    ftm_sim *probe = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &probe, &err), FTM_OK);
    const double *mass = ftm_sim_masses(probe);
    int32_t n = ftm_mesh_node_count(m);
    double fu = 0, umu = 0;
    for (int32_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            fu += f[3 * i + c] * u[3 * i + c];
            umu += mass[i] * u[3 * i + c] * u[3 * i + c];
        }
    double w1 = sqrt(fu / umu), hc = ftm_sim_critical_time_step(probe);
    assert_true(isfinite(hc) && hc > 0);
    /* nodes in m's mesh order, not reordered: the same mesh indices */
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int32_t i = 0; i < n; i++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = ftm_mesh_rest_position(m, i);
        nd.mass = mass[i] > 0 ? mass[i] : 1e-3;
        nd.damping = 2.0 * w1 * nd.mass;
        nd.fixed = ftm_mesh_fixed(m, i);
        assert_true(ftm_mesh_builder_add_node(b, &nd) >= 0);
    }
    for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
        ftm_link_def ld;
        ftm_mesh_link(m, l, &ld.a, &ld.b, &ld.stiffness, &ld.rest_length);
        assert_int_equal(ftm_mesh_builder_add_link(b, &ld), FTM_OK);
    }
    for (int32_t e = 0; e < ftm_mesh_hexahedron_count(m); e++)
        assert_int_equal(ftm_mesh_builder_add_hexahedron(b, ftm_mesh_hexahedra(m) + 8 * e), FTM_OK);
    const int32_t *tt = ftm_mesh_tetrahedra(m);
    for (int32_t e = 0; e < ftm_mesh_tetrahedron_count(m); e++)
        assert_int_equal(
            ftm_mesh_builder_add_tetrahedron(b, tt[4 * e], tt[4 * e + 1], tt[4 * e + 2], tt[4 * e + 3]),
            FTM_OK);
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    bd.reorder = false; /* keep the mesh indices of m */
    assert_int_equal(ftm_mesh_build(b, &bd, damped, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    ftm_sim_destroy(probe);
    d.time_step = 0.5 * hc;
    d.density = 0.0; /* the rebuilt mesh already carries the lumped masses */
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(*damped, &d, &sim, &err), FTM_OK);
    return sim;
}

/* Steps until the largest motion per step is below tol * spacing. Returns steps. */
static inline int settle(ftm_sim *sim, double spacing, double tol, int max_steps)
{
    int32_t n = ftm_mesh_node_count(ftm_sim_mesh(sim));
    for (int s = 1; s <= max_steps; s++) {
        assert_int_equal(ftm_sim_step(sim), FTM_OK);
        const double *x = ftm_sim_positions(sim), *xp = ftm_sim_previous_positions(sim);
        double mm = 0;
        for (int32_t k = 0; k < 3 * n; k++)
            mm = fmax(mm, fabs(x[k] - xp[k]));
        if (mm < tol * spacing)
            return s;
    }
    return max_steps;
}

/* ||x - X - u_ref|| / ||u_ref|| over all nodes. */
static inline double rel_error(const ftm_sim *sim, const double *u_ref)
{
    const ftm_mesh *m = ftm_sim_mesh(sim);
    const double *x = ftm_sim_positions(sim);
    double num = 0, den = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        ftm_vec3 X = ftm_mesh_rest_position(m, i);
        double u[3] = {x[3 * i] - X.x, x[3 * i + 1] - X.y, x[3 * i + 2] - X.z};
        for (int c = 0; c < 3; c++) {
            num += (u[c] - u_ref[3 * i + c]) * (u[c] - u_ref[3 * i + c]);
            den += u_ref[3 * i + c] * u_ref[3 * i + c];
        }
    }
    return sqrt(num / den);
}

#endif
