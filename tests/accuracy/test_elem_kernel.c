/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The element block kernels (common/src/elem_kernel.c): every kernel this
 * CPU runs (AVX-512, AVX2, portable) gives
 *   - neo-Hookean: exactly the bits of the scalar reference
 *     (ftm_neo_element_forces), element by element, with the elements'
 *     lanes mixed (a cube root near 1 in one lane and far from it in the
 *     next, partial blocks, inverted elements);
 *   - co-rotational: the same bits as every other kernel, and R K_e (R^T x -
 *     X) of the element matrices and a long double polar decomposition to
 *     round-off (the factorised hexahedron, the tetrahedron's R^T F - I);
 * and whole simulations give the same hash with every kernel. Each again
 * with three materials in one body (per-label young and poisson, the
 * labels alternating element by element, so a block's lanes mix them). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/ftm.h"
#include "hyperelastic.h"
#include "sim_elem.h"
#include "sim_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define YOUNG 0.6e6
#define POISSON 0.45
#define MU (YOUNG / (2.0 * (1.0 + POISSON)))
#define KAPPA (YOUNG / (3.0 * (1.0 - 2.0 * POISSON)))

/* Several materials: element e labelled 1 + e % 3; label 1 takes the def's
 * material, 2 and 3 these (set by the labelled tests). */
static bool labelled;
static const ftm_label_material label_mats[2] = {
    {.label = 2, .young = 2.0 * YOUNG, .poisson = 0.3},
    {.label = 3, .young = 0.5 * YOUNG, .poisson = 0.4}};

static double elem_young(int32_t e)
{
    return labelled && e % 3 ? label_mats[e % 3 - 1].young : YOUNG;
}
static double elem_poisson(int32_t e)
{
    return labelled && e % 3 ? label_mats[e % 3 - 1].poisson : POISSON;
}

static const ftm_elem_kernel kernels[] = {FTM_ELEM_KERNEL_BEST, FTM_ELEM_KERNEL_AVX2,
                                          FTM_ELEM_KERNEL_PORTABLE};
static const char *const kernel_names[] = {"best", "avx2", "portable"};

/* xorshift64*: a fixed sequence in [0, 1) */
static double rnd(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 0x2545f4914f6cdd1dULL) >> 11) * 0x1p-53;
}

/* An nx x ny x nz-node block of 10 mm cells, bottom fixed: hexahedra, or
 * each cell as six tetrahedra around its diagonal. */
static ftm_mesh *block_mesh(int nx, int ny, int nz, bool tets)
{
    const double s = 0.01;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int k = 0; k < nz; k++)
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                ftm_node_def nd = ftm_default_node_def();
                nd.position = (ftm_vec3){i * s, j * s, k * s};
                nd.mass = 0.001;
                nd.damping = 0.5;
                nd.fixed = k == 0;
                assert_true(ftm_mesh_builder_add_node(b, &nd) >= 0);
            }
#define ID(i, j, k) ((i) + nx * ((j) + ny * (k)))
    for (int k = 0; k + 1 < nz; k++)
        for (int j = 0; j + 1 < ny; j++)
            for (int i = 0; i + 1 < nx; i++) {
                const int32_t h[8] = {ID(i, j, k),         ID(i + 1, j, k),
                                      ID(i + 1, j + 1, k), ID(i, j + 1, k),
                                      ID(i, j, k + 1),     ID(i + 1, j, k + 1),
                                      ID(i + 1, j + 1, k + 1), ID(i, j + 1, k + 1)};
                if (!tets) {
                    assert_int_equal(ftm_mesh_builder_add_hexahedron(b, h), FTM_OK);
                    const int32_t e = ftm_mesh_builder_hexahedron_count(b) - 1;
                    if (labelled)
                        assert_int_equal(ftm_mesh_builder_set_hexahedron_label(b, e, 1 + e % 3),
                                         FTM_OK);
                    continue;
                }
                static const int path[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                               {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
                for (int t = 0; t < 6; t++) {
                    int c[3] = {i, j, k}, v[4];
                    v[0] = ID(c[0], c[1], c[2]);
                    for (int st = 0; st < 3; st++) {
                        c[path[t][st]]++;
                        v[st + 1] = ID(c[0], c[1], c[2]);
                    }
                    assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, v[0], v[1], v[2], v[3]),
                                     FTM_OK);
                    const int32_t e = ftm_mesh_builder_tetrahedron_count(b) - 1;
                    if (labelled)
                        assert_int_equal(ftm_mesh_builder_set_tetrahedron_label(b, e, 1 + e % 3),
                                         FTM_OK);
                }
            }
#undef ID
    /* links: the elements' edges are not needed by element forces, one keeps
     * the builder content */
    ftm_link_def l = ftm_default_link_def();
    l.a = 0;
    l.b = 1;
    l.stiffness = 1.0;
    assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, NULL), FTM_OK);
    ftm_mesh_builder_destroy(b);
    return m;
}

static ftm_sim *make_sim(const ftm_mesh *m, ftm_forces forces)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.forces = forces;
    d.young = YOUNG;
    d.poisson = POISSON;
    d.density = 1040.0;
    d.time_step = 2e-5;
    d.depth = 100;
    if (labelled) {
        d.label_materials = label_mats;
        d.label_material_count = 2;
    }
    ftm_sim *sim = NULL;
    ftm_error err;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    return sim;
}

/* Positions X + u: a smooth field whose volume change varies from about
 * 0.5 to 1.7 over the body (scale 1), so that neighbouring elements take
 * either branch of the cube root, plus noise of relative size noise. */
static void deform(const ftm_mesh *m, double scale, double noise, uint64_t seed, double *x)
{
    uint64_t s = seed;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        ftm_vec3 X = ftm_mesh_rest_position(m, i);
        double u[3] = {scale * (6.0 * X.x * X.x + 2.0 * X.y * X.z),
                       scale * (-3.0 * X.y * X.y + 1.5 * X.x * X.z),
                       scale * (8.0 * X.z * X.x - 2.0 * X.y * X.x)};
        x[3 * i] = X.x + u[0] + noise * 0.01 * (rnd(&s) - 0.5);
        x[3 * i + 1] = X.y + u[1] + noise * 0.01 * (rnd(&s) - 0.5);
        x[3 * i + 2] = X.z + u[2] + noise * 0.01 * (rnd(&s) - 0.5);
    }
}

/* The neo-Hookean internal forces by the scalar reference: each element by
 * ftm_neo_element_forces, each node's sum over its elements in element order
 * (as the integrator sums). false if an element is inverted. */
static bool neo_reference(const ftm_mesh *m, const double *x, double *f)
{
    const int32_t n = ftm_mesh_node_count(m), nh = ftm_mesh_hexahedron_count(m),
                  nt = ftm_mesh_tetrahedron_count(m);
    memset(f, 0, (size_t)n * 3 * sizeof *f);
    bool *seen = calloc((size_t)n, sizeof *seen);
    double *fe = malloc((size_t)(nh + nt) * 24 * sizeof *fe);
    bool ok = true;
    for (int32_t e = 0; e < nh + nt; e++) {
        const bool hex = e < nh;
        const int nn = hex ? 8 : 4;
        const int32_t *v = hex ? ftm_mesh_hexahedra(m) + 8 * e : ftm_mesh_tetrahedra(m) + 4 * (e - nh);
        ftm_vec3 X[8];
        double u[24], gp[200];
        for (int a = 0; a < nn; a++) {
            X[a] = ftm_mesh_rest_position(m, v[a]);
            const double r[3] = {X[a].x, X[a].y, X[a].z};
            for (int c = 0; c < 3; c++)
                u[3 * a + c] = x[3 * v[a] + c] - r[c];
        }
        if (hex) {
            double g[192], det[8];
            assert_int_equal(ftm_hex8_gauss_gradients(X, g, det), FTM_OK);
            for (int q = 0; q < 8; q++) {
                memcpy(gp + 25 * q, g + 24 * q, 24 * sizeof *g);
                gp[25 * q + 24] = det[q];
            }
        } else {
            double ke[144], vol;
            assert_int_equal(ftm_tet4_stiffness(X, YOUNG, POISSON, ke, &vol), FTM_OK);
            assert_int_equal(ftm_tet4_gradients(X, gp), FTM_OK);
            gp[12] = fabs(vol);
        }
        double md;
        /* the element's label counts within its type, as the mesh's labels */
        const int32_t le = hex ? e : e - nh;
        const double young = elem_young(le), nu = elem_poisson(le);
        const double mu = labelled ? young / (2.0 * (1.0 + nu)) : MU,
                     kappa = labelled ? young / (3.0 * (1.0 - 2.0 * nu)) : KAPPA;
        ok &= ftm_neo_element_forces(nn, hex ? 8 : 1, gp, u, mu, kappa, fe + 24 * e, &md);
    }
    /* sums per node over its elements in ascending order */
    for (int32_t e = 0; e < nh + nt; e++) {
        const bool hex = e < nh;
        const int nn = hex ? 8 : 4;
        const int32_t *v = hex ? ftm_mesh_hexahedra(m) + 8 * e : ftm_mesh_tetrahedra(m) + 4 * (e - nh);
        for (int a = 0; a < nn; a++) {
            for (int c = 0; c < 3; c++)
                f[3 * v[a] + c] = seen[v[a]] ? f[3 * v[a] + c] + fe[24 * e + 3 * a + c]
                                             : 0.0 + fe[24 * e + 3 * a + c];
            seen[v[a]] = true;
        }
    }
    free(seen);
    free(fe);
    return ok;
}

/* bit-identical arrays; prints the first difference */
static bool same_bits(const double *a, const double *b, size_t n, const char *what)
{
    for (size_t i = 0; i < n; i++)
        if (memcmp(a + i, b + i, sizeof *a) != 0) {
            print_error("%s: entry %zu: %.17g, reference %.17g\n", what, i, a[i], b[i]);
            return false;
        }
    return true;
}

/* R of F = R S in long double (Newton's iteration to convergence); I if
 * det F <= 0, as the kernels */
static void polar_ld(const double f[9], long double r[9])
{
    long double x[9];
    for (int q = 0; q < 9; q++)
        x[q] = f[q];
    for (int it = 0; it < 100; it++) {
        long double c[9] = {x[4] * x[8] - x[5] * x[7], x[5] * x[6] - x[3] * x[8],
                            x[3] * x[7] - x[4] * x[6], x[2] * x[7] - x[1] * x[8],
                            x[0] * x[8] - x[2] * x[6], x[1] * x[6] - x[0] * x[7],
                            x[1] * x[5] - x[2] * x[4], x[2] * x[3] - x[0] * x[5],
                            x[0] * x[4] - x[1] * x[3]};
        long double det = x[0] * c[0] + x[1] * c[1] + x[2] * c[2], d = 0;
        if (!(det > 0)) {
            for (int q = 0; q < 9; q++)
                r[q] = q % 4 == 0;
            return;
        }
        for (int q = 0; q < 9; q++) {
            long double y = 0.5L * (x[q] + c[q] / det);
            d = fmaxl(d, fabsl(y - x[q]));
            x[q] = y;
        }
        if (d < 1e-18L)
            break;
    }
    memcpy(r, x, sizeof x);
}

/* Co-rotational internal forces from the element matrices: per element
 * R K_e (R^T x_e - X_e), R the rotation of F at the centre; false if some
 * element has det F <= 0 there. */
static bool corot_reference(const ftm_mesh *m, const double *x, double *f)
{
    const int32_t n = ftm_mesh_node_count(m), nh = ftm_mesh_hexahedron_count(m),
                  nt = ftm_mesh_tetrahedron_count(m);
    long double *acc = calloc((size_t)n * 3, sizeof *acc);
    bool upright = true;
    for (int32_t e = 0; e < nh + nt; e++) {
        const bool hex = e < nh;
        const int nn = hex ? 8 : 4;
        const int32_t *v = hex ? ftm_mesh_hexahedra(m) + 8 * e : ftm_mesh_tetrahedra(m) + 4 * (e - nh);
        ftm_vec3 X[8];
        double g[24], ke[576], vol;
        for (int a = 0; a < nn; a++)
            X[a] = ftm_mesh_rest_position(m, v[a]);
        const int32_t le = hex ? e : e - nh;
        if (hex) {
            assert_int_equal(ftm_hex8_stiffness(X, elem_young(le), elem_poisson(le), ke, NULL),
                             FTM_OK);
            assert_int_equal(ftm_hex8_centre_gradients(X, g), FTM_OK);
        } else {
            assert_int_equal(ftm_tet4_stiffness(X, elem_young(le), elem_poisson(le), ke, &vol),
                             FTM_OK);
            assert_int_equal(ftm_tet4_gradients(X, g), FTM_OK);
        }
        double fc[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
        for (int a = 0; a < nn; a++)
            for (int i = 0; i < 3; i++) {
                const double r0[3] = {X[a].x, X[a].y, X[a].z};
                const double u = x[3 * v[a] + i] - r0[i];
                for (int j = 0; j < 3; j++)
                    fc[3 * i + j] += u * g[3 * a + j];
            }
        long double r[9], y[24], gk[24];
        polar_ld(fc, r);
        const long double det = fc[0] * (fc[4] * fc[8] - fc[5] * fc[7]) -
                                fc[1] * (fc[3] * fc[8] - fc[5] * fc[6]) +
                                fc[2] * (fc[3] * fc[7] - fc[4] * fc[6]);
        upright &= det > 0;
        for (int a = 0; a < nn; a++) {
            const double r0[3] = {X[a].x, X[a].y, X[a].z};
            for (int i = 0; i < 3; i++) {
                long double s = -(long double)r0[i];
                for (int k = 0; k < 3; k++)
                    s += r[3 * k + i] * x[3 * v[a] + k];
                y[3 * a + i] = s;
            }
        }
        const int w = 3 * nn;
        for (int row = 0; row < w; row++) {
            long double s = 0;
            for (int col = 0; col < w; col++)
                s += ke[row * w + col] * y[col];
            gk[row] = s;
        }
        for (int a = 0; a < nn; a++)
            for (int i = 0; i < 3; i++)
                for (int k = 0; k < 3; k++)
                    acc[3 * v[a] + i] += r[3 * i + k] * gk[3 * a + k];
    }
    for (int32_t k = 0; k < 3 * n; k++)
        f[k] = (double)acc[k];
    free(acc);
    return upright;
}

static void check_corot(bool tets)
{
    ftm_mesh *m = tets ? block_mesh(4, 4, 3, true) : block_mesh(5, 4, 4, false);
    const int32_t n = ftm_mesh_node_count(m);
    double *x = malloc((size_t)n * 3 * sizeof *x), *ref = malloc((size_t)n * 3 * sizeof *ref),
           *f = malloc((size_t)n * 3 * sizeof *f), *f0 = malloc((size_t)n * 3 * sizeof *f0);
    ftm_sim *sim = make_sim(m, FTM_FORCES_COROT_FEM);
    /* small, large (with rotation), and through the body (some inverted) */
    const double scale[] = {0.05, 1.0, 1.0, 0.0}, noise[] = {0.001, 0.0, 0.05, 2.5};
    int inverted = 0;
    for (int fi = 0; fi < 4; fi++) {
        deform(m, scale[fi], noise[fi], 11 + (uint64_t)fi, x);
        const bool upright = corot_reference(m, x, ref);
        inverted += !upright;
        double big = 0, err = 0;
        for (int32_t k = 0; k < 3 * n; k++)
            big = fmax(big, fabs(ref[k]));
        for (size_t k = 0; k < sizeof kernels / sizeof kernels[0]; k++) {
            ftm_elem_select_kernel(sim->elem, kernels[k]);
            assert_int_equal(ftm_sim_internal_forces(sim, x, f), FTM_OK);
            if (k == 0)
                memcpy(f0, f, (size_t)n * 3 * sizeof *f);
            char what[64];
            snprintf(what, sizeof what, "corot %s %s field %d", tets ? "tets" : "hexes",
                     kernel_names[k], fi);
            assert_true(same_bits(f, f0, (size_t)n * 3, what));
        }
        for (int32_t k = 0; k < 3 * n; k++)
            err = fmax(err, fabs(f[k] - ref[k]));
        print_message("corot %s field %d: largest force %.3g N, off the matrices by %.2g of it%s\n",
                      tets ? "tetrahedra" : "hexahedra", fi, big, err / big,
                      upright ? "" : " (inverted elements: R = I)");
        /* the kernel's polar decomposition stops with R within 5e-11
         * (elem_block.inc, revision 6), which moves each element's strain
         * by as much: relative to the force of a strain e about 5e-11 / e,
         * and a lane only stops early at small strains, where its error is
         * about e^4 / 8 (e^3 / 8 of its force, below 2e-9 where it stops
         * early). 1e-11 before revision 6. */
        assert_true(err <= 2e-9 * big);
    }
    assert_true(inverted > 0);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
    free(x);
    free(ref);
    free(f);
    free(f0);
}

static void test_corot_hexahedra(void **state)
{
    (void)state;
    check_corot(false);
}

static void test_corot_tetrahedra(void **state)
{
    (void)state;
    check_corot(true);
}

static void check_forces(ftm_forces forces, bool tets)
{
    /* partial last blocks: 4 x 3 x 3 = 36 hexahedra (4 blocks and 4 lanes),
     * 3 x 3 x 2 cells = 108 tetrahedra (13 blocks and 4 lanes) */
    ftm_mesh *m = tets ? block_mesh(4, 4, 3, true) : block_mesh(5, 4, 4, false);
    const int32_t n = ftm_mesh_node_count(m);
    double *x = malloc((size_t)n * 3 * sizeof *x), *ref = malloc((size_t)n * 3 * sizeof *ref),
           *f = malloc((size_t)n * 3 * sizeof *f);
    ftm_sim *sim = make_sim(m, forces);
    const struct {
        double scale, noise;
        bool inverted;
    } fields[] = {{0.05, 0.001, false}, {1.0, 0.0, false}, {1.0, 0.05, false},
                  {0.0, 1.2, true}};
    int cases = 0;
    for (size_t fi = 0; fi < sizeof fields / sizeof fields[0]; fi++) {
        deform(m, fields[fi].scale, fields[fi].noise, 7 + fi, x);
        const bool ok = neo_reference(m, x, ref);
        if (fields[fi].inverted && ok)
            continue; /* (the noise did not invert one: nothing to compare) */
        assert_true(ok == !fields[fi].inverted);
        for (size_t k = 0; k < sizeof kernels / sizeof kernels[0]; k++) {
            ftm_elem_select_kernel(sim->elem, kernels[k]);
            char what[64];
            snprintf(what, sizeof what, "%s %s field %zu", tets ? "tets" : "hexes",
                     kernel_names[k], fi);
            memset(f, 0, (size_t)n * 3 * sizeof *f);
            int rc = ftm_sim_internal_forces(sim, x, f);
            if (!ok) {
                assert_int_equal(rc, FTM_EINVAL);
                continue;
            }
            assert_int_equal(rc, FTM_OK);
            assert_true(same_bits(f, ref, (size_t)n * 3, what));
            cases++;
        }
    }
    assert_true(cases >= 9);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
    free(x);
    free(ref);
    free(f);
}

static void test_neo_hexahedra(void **state)
{
    (void)state;
    check_forces(FTM_FORCES_NEO_HOOKEAN, false);
}

static void test_neo_tetrahedra(void **state)
{
    (void)state;
    check_forces(FTM_FORCES_NEO_HOOKEAN, true);
}

/* A press, a release and a deep press that inverts elements (substeps, then
 * refused): the same hash after every step with every kernel. */
static void quiet(void *user, ftm_log_level level, const char *msg)
{
    (void)user;
    (void)level;
    (void)msg;
}

static uint64_t run(const ftm_mesh *m, int nx, int nz, ftm_forces forces, ftm_elem_kernel k,
                    ftm_order order)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.forces = forces;
    d.young = YOUNG;
    d.poisson = POISSON;
    d.density = 1040.0;
    d.time_step = 4e-5;
    d.depth = 2;
    d.order = order;
    d.max_substeps = 4;
    d.log = quiet;
    if (labelled) {
        d.label_materials = label_mats;
        d.label_material_count = 2;
    }
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &sim, NULL), FTM_OK);
    ftm_elem_select_kernel(sim->elem, k);
    const int32_t top = ftm_mesh_node_of_input(m, nx / 2 + nx * (nx / 2 + nx * (nz - 1)));
    ftm_contact c[2] = {{.node = top, .group = 0, .kind = FTM_CONTACT_DISPLACEMENT,
                         .value = {0.001, 0.0005, -0.003}},
                        {.node = ftm_mesh_node_of_input(m, nx * nx * nz - 1), .group = 1, .kind = FTM_CONTACT_FORCE,
                         .value = {0.0, 0.3, -1.0}}};
    uint64_t h = 0;
    int refused = 0;
    for (int s = 0; s < 300; s++) {
        if (s == 0 || s == 150)
            assert_int_equal(ftm_sim_set_contacts(sim, c, s == 0 ? 2 : 1, NULL), FTM_OK);
        if (s == 220) { /* a press through the body at once: inverted, refused */
            c[0].value.z = -0.03;
            assert_int_equal(ftm_sim_set_contacts(sim, c, 1, NULL), FTM_OK);
        }
        int rc = ftm_sim_step(sim);
        assert_true(rc == FTM_OK || (s >= 220 && rc == FTM_EUNSTABLE));
        assert_true(forces == FTM_FORCES_NEO_HOOKEAN || rc == FTM_OK);
        refused += rc == FTM_EUNSTABLE;
        h = h * 0x100000001b3ULL ^ ftm_sim_hash(sim);
    }
    if (forces == FTM_FORCES_NEO_HOOKEAN)
        assert_true(refused > 0); /* the deep press was met */
    ftm_sim_destroy(sim);
    return h;
}

static void test_runs_match(void **state)
{
    (void)state;
    for (int tets = 0; tets < 2; tets++) {
        const int nx = tets ? 4 : 5;
        ftm_mesh *m = block_mesh(nx, nx, nx, tets);
        for (int f = 0; f < 2; f++) {
            const ftm_forces forces = f ? FTM_FORCES_COROT_FEM : FTM_FORCES_NEO_HOOKEAN;
            const ftm_order order = tets ? FTM_ORDER_BFS : FTM_ORDER_LAYER_COLORED;
            const uint64_t h0 = run(m, nx, nx, forces, kernels[0], order);
            for (size_t k = 1; k < sizeof kernels / sizeof kernels[0]; k++)
                if (run(m, nx, nx, forces, kernels[k], order) != h0)
                    fail_msg("%s, %s: kernel %s differs from the best", tets ? "tets" : "hexes",
                             f ? "corot-fem" : "neo-hookean", kernel_names[k]);
        }
        ftm_mesh_destroy(m);
    }
}

static int set_labelled(void **state)
{
    (void)state;
    labelled = true;
    return 0;
}

static int set_one_material(void **state)
{
    (void)state;
    labelled = false;
    return 0;
}

/* The labelled bodies' forces differ from one material's: the labels are
 * honoured (the tests above would pass with them ignored only if the
 * reference ignored them too). */
static void test_labels_change_forces(void **state)
{
    (void)state;
    for (int f = 0; f < 2; f++) {
        const ftm_forces forces = f ? FTM_FORCES_COROT_FEM : FTM_FORCES_NEO_HOOKEAN;
        labelled = true;
        ftm_mesh *m = block_mesh(5, 4, 4, false);
        ftm_sim *a = make_sim(m, forces);
        labelled = false;
        ftm_sim *b = make_sim(m, forces);
        labelled = true;
        const int32_t n = ftm_mesh_node_count(m);
        double *x = malloc((size_t)n * 3 * sizeof *x), *fa = malloc((size_t)n * 3 * sizeof *fa),
               *fb = malloc((size_t)n * 3 * sizeof *fb);
        deform(m, 0.05, 0.001, 5, x);
        assert_int_equal(ftm_sim_internal_forces(a, x, fa), FTM_OK);
        assert_int_equal(ftm_sim_internal_forces(b, x, fb), FTM_OK);
        double big = 0, diff = 0;
        for (int32_t k = 0; k < 3 * n; k++) {
            big = fmax(big, fabs(fb[k]));
            diff = fmax(diff, fabs(fa[k] - fb[k]));
        }
        assert_true(diff > 0.1 * big);
        ftm_sim_destroy(a);
        ftm_sim_destroy(b);
        ftm_mesh_destroy(m);
        free(x);
        free(fa);
        free(fb);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_neo_hexahedra, set_one_material),
        cmocka_unit_test_setup(test_neo_tetrahedra, set_one_material),
        cmocka_unit_test_setup(test_corot_hexahedra, set_one_material),
        cmocka_unit_test_setup(test_corot_tetrahedra, set_one_material),
        cmocka_unit_test_setup(test_runs_match, set_one_material),
        /* three materials in one body */
        cmocka_unit_test_setup(test_neo_hexahedra, set_labelled),
        cmocka_unit_test_setup(test_neo_tetrahedra, set_labelled),
        cmocka_unit_test_setup(test_corot_hexahedra, set_labelled),
        cmocka_unit_test_setup(test_corot_tetrahedra, set_labelled),
        cmocka_unit_test_setup(test_runs_match, set_labelled),
        cmocka_unit_test_setup(test_labels_change_forces, set_labelled),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
