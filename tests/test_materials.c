/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Materials per element label (issue 31, item 2): a scene's [fem LABEL]
 * and [material LABEL] sections and the forces that honour them: linear,
 * co-rotational and neo-Hookean elements, lumped masses from each label's
 * density, the elastic far field, and springs whose links take their
 * label's stiffness.
 *
 * The physics check is exact: a bar of two labels, E1 and E2 = 4 E1, with
 * Poisson's ratio 0, clamped at x = 0 and stretched along x. Its linear
 * elastic solution is uniaxial stress sigma in both parts, the strain
 * sigma / E of each part: two springs in series. The hexahedra represent
 * that field exactly, so at those positions every node off the two ends is
 * in equilibrium (internal force 0) and the end's forces add up to sigma A;
 * with one material for the whole bar the interface is not. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/fem.h"
#include "ftm/generate.h"
#include "ftm/mesh.h"
#include "ftm/scene.h"
#include "ftm/sim.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <unistd.h>

static char tmp_dir[256];
static char msh_path[300];
static char long_path[300]; /* LONG_CELLS hexahedra along x, labels 5 then 9 */

#define LONG_CELLS 8

/* Two unit hexahedra along x, in physical groups 5 (x 0..1) and 9 (x 1..2). */
static const char bar_msh[] =
    "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
    "$Entities\n0 0 0 2\n"
    "1 0 0 0 1 1 1 1 5 0\n2 1 0 0 2 1 1 1 9 0\n$EndEntities\n"
    "$Nodes\n1 12 1 12\n3 1 0 12\n1\n2\n3\n4\n5\n6\n7\n8\n9\n10\n11\n12\n"
    "0 0 0\n1 0 0\n2 0 0\n0 1 0\n1 1 0\n2 1 0\n0 0 1\n1 0 1\n2 0 1\n0 1 1\n1 1 1\n2 1 1\n"
    "$EndNodes\n"
    "$Elements\n2 2 1 2\n3 1 5 1\n1 1 2 5 4 7 8 11 10\n3 2 5 1\n2 2 3 6 5 8 9 12 11\n"
    "$EndElements\n";

static int group_setup(void **state)
{
    (void)state;
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/ftm-test-materials-XXXXXX");
    if (!mkdtemp(tmp_dir))
        return -1;
    snprintf(msh_path, sizeof msh_path, "%s/bar.msh", tmp_dir);
    FILE *f = fopen(msh_path, "w");
    if (!f)
        return -1;
    fputs(bar_msh, f);
    fclose(f);
    /* the long bar: unit cells along x, the first half label 5, the rest 9 */
    snprintf(long_path, sizeof long_path, "%s/long.msh", tmp_dir);
    if (!(f = fopen(long_path, "w")))
        return -1;
    const int n = LONG_CELLS, nn = 4 * (n + 1);
    fprintf(f, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 2\n"
               "1 0 0 0 %d 1 1 1 5 0\n2 %d 0 0 %d 1 1 1 9 0\n$EndEntities\n",
            n / 2, n / 2, n);
    fprintf(f, "$Nodes\n1 %d 1 %d\n3 1 0 %d\n", nn, nn, nn);
    for (int i = 1; i <= nn; i++)
        fprintf(f, "%d\n", i);
    for (int k = 0; k < 2; k++)
        for (int j = 0; j < 2; j++)
            for (int i = 0; i <= n; i++)
                fprintf(f, "%d %d %d\n", i, j, k);
    fprintf(f, "$EndNodes\n$Elements\n2 %d 1 %d\n", n, n);
#define NODE(i, j, k) (1 + (i) + (n + 1) * ((j) + 2 * (k)))
    for (int half = 0; half < 2; half++) {
        fprintf(f, "3 %d 5 %d\n", half + 1, n / 2);
        for (int c = half * n / 2; c < (half + 1) * n / 2; c++)
            fprintf(f, "%d %d %d %d %d %d %d %d %d\n", c + 1, NODE(c, 0, 0), NODE(c + 1, 0, 0),
                    NODE(c + 1, 1, 0), NODE(c, 1, 0), NODE(c, 0, 1), NODE(c + 1, 0, 1),
                    NODE(c + 1, 1, 1), NODE(c, 1, 1));
    }
#undef NODE
    fputs("$EndElements\n", f);
    fclose(f);
    /* the far field's cache in the test's directory, not the user's */
    setenv("FTM_CACHE_DIR", tmp_dir, 1);
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    unlink(msh_path);
    unlink(long_path);
    DIR *d = opendir(tmp_dir); /* and the far field's cache files */
    for (struct dirent *e; d && (e = readdir(d));) {
        char path[600];
        if (strncmp(e->d_name, "far-", 4) == 0) {
            snprintf(path, sizeof path, "%s/%s", tmp_dir, e->d_name);
            unlink(path);
        }
    }
    if (d)
        closedir(d);
    return rmdir(tmp_dir) == 0 ? 0 : -1;
}

/* The scene: the bar, clamped at x = 0, [fem] for label 5 and `extra`
 * (e.g. a [fem 9] section) after it. */
static int parse_bar(const char *sim_keys, const char *extra, ftm_scene **out, ftm_error *err)
{
    char text[2048];
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_box = -0.1 -0.1 -0.1 0.1 1.1 1.1\n"
             "[material]\nmass = 0.01\nstiffness = 100\ndamping = 0.5\n"
             "[sim]\n%s\n"
             "[fem]\nyoung = 1e4\npoisson = 0\n%s",
             msh_path, sim_keys, extra);
    return ftm_scene_parse(text, strlen(text), "bar.scene", out, err);
}

/* The internal forces at the series solution of a bar of moduli e1 (x < 1)
 * and e2 (x > 1) pulled to sigma = 100 Pa: the largest |f| at a node off
 * the ends, relative to sigma A (A = 1), and the x = 2 end's sum of f_x. */
static void series_forces_at(const ftm_scene *scene, double e1, double e2, double sigma,
                             double *worst, double *end_fx)
{
    const ftm_mesh *m = ftm_scene_mesh(scene);
    ftm_sim_def d = ftm_scene_sim_def(scene);
    ftm_sim *sim = NULL;
    ftm_error err;
    if (ftm_sim_create(m, &d, &sim, &err) != FTM_OK)
        fail_msg("%s", err.message);
    const double eps1 = sigma / e1, eps2 = sigma / e2;
    int32_t n = ftm_mesh_node_count(m);
    double *x = malloc(3 * (size_t)n * sizeof *x), *f = malloc(3 * (size_t)n * sizeof *f);
    assert_non_null(x);
    assert_non_null(f);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 r = ftm_mesh_rest_position(m, i);
        double u = r.x <= 1.0 ? eps1 * r.x : eps1 + eps2 * (r.x - 1.0);
        x[3 * i] = r.x + u;
        x[3 * i + 1] = r.y;
        x[3 * i + 2] = r.z;
    }
    assert_int_equal(ftm_sim_internal_forces(sim, x, f), FTM_OK);
    *worst = 0.0;
    *end_fx = 0.0;
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 r = ftm_mesh_rest_position(m, i);
        if (r.x == 2.0) {
            *end_fx += f[3 * i];
            continue;
        }
        if (r.x == 0.0)
            continue;
        double a = sqrt(f[3 * i] * f[3 * i] + f[3 * i + 1] * f[3 * i + 1] +
                        f[3 * i + 2] * f[3 * i + 2]);
        *worst = fmax(*worst, a / sigma);
    }
    free(x);
    free(f);
    ftm_sim_destroy(sim);
}

static void series_forces(const ftm_scene *scene, double e1, double e2, double *worst,
                          double *end_fx)
{
    series_forces_at(scene, e1, e2, 100.0, worst, end_fx);
}

static void test_two_labels_in_series(void **state)
{
    (void)state;
    ftm_scene *scene = NULL;
    ftm_error err;
    int rc = parse_bar("forces = linear-fem", "[fem 9]\nyoung = 4e4\npoisson = 0\n", &scene, &err);
    if (rc)
        fail_msg("%s", err.message);
    ftm_sim_def d = ftm_scene_sim_def(scene);
    assert_int_equal(d.label_material_count, 1);
    assert_int_equal(d.label_materials[0].label, 9);
    assert_true(d.label_materials[0].young == 4e4);

    double worst, end_fx;
    series_forces(scene, 1e4, 4e4, &worst, &end_fx);
    assert_true(worst < 1e-9);                       /* in equilibrium inside */
    assert_true(fabs(fabs(end_fx) - 100.0) < 1e-9);  /* sigma A at the end */
    /* the series solution of one material is not: the stiffer part is honoured */
    double worst1, end1;
    series_forces(scene, 1e4, 1e4, &worst1, &end1);
    assert_true(worst1 > 0.1);
    ftm_scene_destroy(scene);

    /* without [fem 9] the bar is one material: its own series solution
     * holds, the two-material one does not */
    assert_int_equal(parse_bar("forces = linear-fem", "", &scene, &err), FTM_OK);
    assert_int_equal(ftm_scene_sim_def(scene).label_material_count, 0);
    series_forces(scene, 1e4, 1e4, &worst, &end_fx);
    assert_true(worst < 1e-9);
    series_forces(scene, 1e4, 4e4, &worst, &end_fx);
    assert_true(worst > 0.1);
    ftm_scene_destroy(scene);

    /* the label of the default material may have its own section too */
    rc = parse_bar("forces = linear-fem",
                   "[fem 5]\nyoung = 4e4\npoisson = 0\n[fem 9]\npoisson = 0\nyoung = 1e4\n",
                   &scene, &err);
    if (rc)
        fail_msg("%s", err.message);
    series_forces(scene, 4e4, 1e4, &worst, &end_fx);
    assert_true(worst < 1e-9);
    ftm_scene_destroy(scene);
}


/* Co-rotational and neo-Hookean forces honour the labels: at the series
 * solution of a small stress (strain 1e-6 in the soft part) each is in
 * equilibrium off the ends as linear-fem is. Tolerance 1e-4 of sigma A:
 * the co-rotational form is Hooke's for a pure stretch (R = I to
 * round-off), and the neo-Hookean stress differs from Hooke's by terms of
 * second order in the displacement gradient, about the strain (1e-6)
 * relative; the one-material field is off by more than 0.1. */
static void test_corot_neo_per_label(void **state)
{
    (void)state;
    const char *forces[] = {"forces = corot-fem", "forces = neo-hookean", "forces = linear-fem"};
    const double sigma = 0.01; /* Pa: strains 1e-6 and 2.5e-7 */
    for (int k = 0; k < 3; k++) {
        ftm_scene *scene = NULL;
        ftm_error err;
        if (parse_bar(forces[k], "[fem 9]\nyoung = 4e4\npoisson = 0\n", &scene, &err))
            fail_msg("%s", err.message);
        assert_int_equal(ftm_scene_sim_def(scene).label_material_count, 1);
        double worst, end_fx, worst1, end1;
        series_forces_at(scene, 1e4, 4e4, sigma, &worst, &end_fx);
        series_forces_at(scene, 1e4, 1e4, sigma, &worst1, &end1);
        print_message("%s: two materials off by %.2g of sigma A (end %.9g), one material %.2g\n",
                      forces[k], worst, fabs(end_fx) / sigma, worst1);
        assert_true(worst < 1e-4);
        assert_true(fabs(fabs(end_fx) / sigma - 1.0) < 1e-4);
        assert_true(worst1 > 0.1);
        ftm_scene_destroy(scene);
    }
}

/* The lumped masses take each label's density: unit hexahedra, rho / 8 per
 * node from each element holding it. */
static void test_density_per_label(void **state)
{
    (void)state;
    char text[1024];
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_box = -0.1 -0.1 -0.1 0.1 1.1 1.1\n"
             "[material]\nmass = 0.01\nstiffness = 100\ndamping = 0.5\n"
             "[sim]\nforces = corot-fem\n"
             "[fem]\nyoung = 1e4\npoisson = 0.3\ndensity = 1000\n"
             "[fem 9]\nyoung = 4e4\npoisson = 0.3\ndensity = 3000\n",
             msh_path);
    ftm_scene *scene = NULL;
    ftm_error err;
    if (ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err))
        fail_msg("%s", err.message);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    ftm_sim_def d = ftm_scene_sim_def(scene);
    assert_true(d.label_materials[0].density == 3000);
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    const double *mass = ftm_sim_masses(sim);
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        const double x = ftm_mesh_rest_position(m, i).x;
        const double want = x == 0.0 ? 125.0 : x == 1.0 ? 125.0 + 375.0 : 375.0;
        assert_true(fabs(mass[i] - want) < 1e-12 * want);
    }
    ftm_sim_destroy(sim);
    /* equal densities: the bits of one density */
    d.label_materials = &(ftm_label_material){.label = 9, .young = 4e4, .poisson = 0.3,
                                              .density = 1000};
    ftm_sim *one = NULL;
    ftm_sim_def d1 = d;
    d1.label_material_count = 0;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    assert_int_equal(ftm_sim_create(m, &d1, &one, &err), FTM_OK);
    assert_memory_equal(ftm_sim_masses(sim), ftm_sim_masses(one),
                        (size_t)ftm_mesh_node_count(m) * sizeof(double));
    ftm_sim_destroy(sim);
    ftm_sim_destroy(one);
    ftm_scene_destroy(scene);
}

/* [material LABEL]: a link takes the mean of the factors (label stiffness
 * over [material]'s) of the elements holding it. */
static void test_spring_stiffness_per_label(void **state)
{
    (void)state;
    ftm_scene *scene = NULL, *plain = NULL;
    ftm_error err;
    if (parse_bar("forces = springs", "[material 9]\nstiffness = 400\n", &scene, &err))
        fail_msg("%s", err.message);
    assert_int_equal(parse_bar("forces = springs", "", &plain, &err), FTM_OK);
    const ftm_mesh *m = ftm_scene_mesh(scene), *p = ftm_scene_mesh(plain);
    assert_int_equal(ftm_mesh_link_count(m), ftm_mesh_link_count(p));
    int seen[3] = {0, 0, 0};
    for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
        int32_t a, b, pa, pb;
        double k, len, pk, plen;
        ftm_mesh_link(m, l, &a, &b, &k, &len);
        ftm_mesh_link(p, l, &pa, &pb, &pk, &plen);
        assert_int_equal(a, pa);
        assert_int_equal(b, pb);
        const double xa = ftm_mesh_rest_position(m, a).x, xb = ftm_mesh_rest_position(m, b).x;
        /* in label 5 only: 1; on the shared face x = 1: (1 + 4) / 2; else 4 */
        const int where = xa <= 1.0 && xb <= 1.0 ? (xa == 1.0 && xb == 1.0 ? 1 : 0) : 2;
        const double f = where == 0 ? 1.0 : where == 1 ? 2.5 : 4.0;
        assert_true(k == pk * f);
        seen[where]++;
    }
    assert_true(seen[0] > 0 && seen[1] > 0 && seen[2] > 0);
    /* the adjacency (what the integrator reads) agrees with the links */
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        const int32_t *nb;
        const double *kk, *ll;
        const int32_t deg = ftm_mesh_neighbors(m, i, &nb, &kk, &ll);
        for (int32_t q = 0; q < deg; q++)
            for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
                int32_t a, b;
                double k, len;
                ftm_mesh_link(m, l, &a, &b, &k, &len);
                if ((a == i && b == nb[q]) || (b == i && a == nb[q]))
                    assert_true(kk[q] == k);
            }
    }
    /* an instructor's change scales from the scene's mesh: the ratios stay */
    ftm_material_def from = ftm_scene_material(scene), to = from;
    to.stiffness *= 3.0;
    ftm_mesh *changed = NULL;
    assert_int_equal(ftm_mesh_with_material(m, &from, &to, &changed, &err), FTM_OK);
    for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
        int32_t a, b;
        double k, k3, len;
        ftm_mesh_link(m, l, &a, &b, &k, &len);
        ftm_mesh_link(changed, l, &a, &b, &k3, &len);
        assert_true(fabs(k3 / k - 3.0) < 1e-14);
    }
    ftm_mesh_destroy(changed);
    /* a stiffer label holds the pulled end closer: the springs' far field
     * and the transmittal take the links as they are, so a displacement at
     * the end meets a larger reaction */
    double react[2];
    for (int s2 = 0; s2 < 2; s2++) {
        const ftm_scene *sc = s2 ? scene : plain;
        ftm_sim_def d = ftm_scene_sim_def(sc);
        d.depth = 10;
        ftm_sim *sim = NULL;
        assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &d, &sim, &err), FTM_OK);
        const ftm_mesh *mm = ftm_scene_mesh(sc);
        ftm_contact c[4];
        int nc = 0;
        for (int32_t i = 0; i < ftm_mesh_node_count(mm); i++)
            if (ftm_mesh_rest_position(mm, i).x == 2.0)
                c[nc++] = (ftm_contact){.node = i, .group = 0, .kind = FTM_CONTACT_DISPLACEMENT,
                                        .value = {1e-3, 0, 0}};
        assert_int_equal(nc, 4);
        assert_int_equal(ftm_sim_set_contacts(sim, c, nc, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(sim, 4000), FTM_OK);
        react[s2] = -ftm_sim_reaction(sim, 0).x;
        ftm_sim_destroy(sim);
    }
    print_message("springs: the end pulled 1 mm: reaction %.6g N (one material %.6g N)\n",
                  react[1], react[0]);
    assert_true(react[1] > 1.3 * react[0]);
    ftm_scene_destroy(scene);
    ftm_scene_destroy(plain);
}

/* The long bar's scene: clamped at x = 0, [fem] E = 1e4 (label 5) and the
 * extra sections. */
static int parse_long(const char *sim_keys, const char *extra, ftm_scene **out, ftm_error *err)
{
    char text[2048];
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_box = -0.1 -0.1 -0.1 0.1 1.1 1.1\n"
             "[material]\nmass = 0.01\nstiffness = 100\ndamping = %s\n"
             "[sim]\ntime_step = 2e-4\n%s\n"
             "[fem]\nyoung = 1e4\npoisson = 0.3\n%s",
             long_path, "0.1", sim_keys, extra);
    return ftm_scene_parse(text, strlen(text), "long.scene", out, err);
}

/* The FEM reference of the long bar under the scene's materials (its
 * [fem LABEL] as per-element materials), forces on the end x = n. */
static void fem_reference(const ftm_scene *scene, const double *forces, double *u)
{
    const ftm_mesh *m = ftm_scene_mesh(scene);
    double young = 0, nu = 0;
    assert_true(ftm_scene_fem_material(scene, &young, &nu, NULL));
    int32_t nl = 0;
    const ftm_label_material *lm = ftm_scene_label_materials(scene, &nl);
    const int32_t nh = ftm_mesh_hexahedron_count(m);
    ftm_fem_material *mat = malloc((size_t)nh * sizeof *mat);
    for (int32_t e = 0; e < nh; e++) {
        mat[e] = (ftm_fem_material){young, nu};
        for (int32_t i = 0; i < nl; i++)
            if (lm[i].label == ftm_mesh_hexahedron_label(m, e))
                mat[e] = (ftm_fem_material){lm[i].young, lm[i].poisson};
    }
    ftm_fem_def fd = ftm_default_fem_def();
    fd.material = (ftm_fem_material){young, nu};
    fd.hex_materials = mat;
    fd.factorization = FTM_FEM_FACTOR_SIMPLICIAL;
    ftm_fem *fem = NULL;
    ftm_error err;
    if (ftm_fem_create(m, &fd, &fem, &err))
        fail_msg("%s", err.message);
    assert_int_equal(ftm_fem_solve(fem, forces, NULL, u, &err), FTM_OK);
    ftm_fem_destroy(fem);
    free(mat);
}

/* The end's force loads; returns their nodes' count. */
static int end_loads(const ftm_mesh *m, double fx, double fz, ftm_contact *c, double *forces)
{
    int nc = 0;
    memset(forces, 0, 3 * (size_t)ftm_mesh_node_count(m) * sizeof *forces);
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++)
        if (ftm_mesh_rest_position(m, i).x == LONG_CELLS) {
            c[nc++] = (ftm_contact){.node = i, .group = 0, .kind = FTM_CONTACT_FORCE,
                                    .value = {fx, 0, fz}};
            forces[3 * i] = fx;
            forces[3 * i + 2] = fz;
        }
    return nc;
}

/* Runs the scene's simulation (with def changes by the caller) under the
 * end's loads to rest; the largest |u - u_ref| over the largest |u_ref|. */
static double settle_against(const ftm_scene *scene, const ftm_sim_def *d, const double *uref,
                             double fx, double fz, double stiffness_factor)
{
    const ftm_mesh *m = ftm_scene_mesh(scene);
    const int32_t n = ftm_mesh_node_count(m);
    ftm_sim *sim = NULL;
    ftm_error err;
    if (ftm_sim_create(m, d, &sim, &err))
        fail_msg("%s", err.message);
    ftm_mesh *changed = NULL;
    if (stiffness_factor != 1.0) { /* the instructor's stiffness change */
        ftm_material_def from = ftm_scene_material(scene), to = from;
        to.stiffness *= stiffness_factor;
        assert_int_equal(ftm_mesh_with_material(m, &from, &to, &changed, &err), FTM_OK);
        if (ftm_sim_set_mesh(sim, changed, &err))
            fail_msg("%s", err.message);
    }
    ftm_contact c[4];
    double *forces = malloc(3 * (size_t)n * sizeof *forces);
    assert_int_equal(end_loads(m, fx, fz, c, forces), 4);
    assert_int_equal(ftm_sim_set_contacts(sim, c, 4, &err), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, 20000), FTM_OK);
    double big = 0, off = 0;
    const double *x = ftm_sim_positions(sim);
    /* the contact region's nodes (every node at full depth): those the
     * elastic far field places where the whole body has them */
    const int32_t *order, *start;
    const int32_t layers = ftm_sim_layers(sim, &order, &start);
    assert_true(start[layers] >= 8);
    for (int32_t r0 = 0; r0 < start[layers]; r0++) {
        const int32_t i = order[r0];
        const ftm_vec3 r = ftm_mesh_rest_position(m, i);
        const double u[3] = {x[3 * i] - r.x, x[3 * i + 1] - r.y, x[3 * i + 2] - r.z};
        for (int k = 0; k < 3; k++) {
            big = fmax(big, fabs(uref[3 * i + k]));
            off = fmax(off, fabs(u[k] - uref[3 * i + k]));
        }
    }
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(changed);
    free(forces);
    return off / big;
}

/* Two materials, the FEM reference against the transmittal at full depth
 * with co-rotational forces (small load: strain about 1e-5, where the
 * co-rotational form is linear to about that, relative), and against the
 * elastic far field at depth 2 with linear forces (at rest exactly the
 * whole body's, to the settling's 1e-6); the one-material reference is far
 * from both. The far field's compliance of two materials is not the one
 * of one material (nor taken from the cache for it): run in turn, each
 * body meets its own reference. The instructor's stiffness change (E
 * times 2) halves the displacements. */
static void test_two_materials_fem_transmittal_far_field(void **state)
{
    (void)state;
    const double fx = 0.002, fz = -0.0005; /* N per end node */
    ftm_scene *two = NULL, *one = NULL;
    ftm_error err;
    if (parse_long("forces = corot-fem\ndepth = 100", "[fem 9]\nyoung = 2.5e3\npoisson = 0.45\n",
                   &two, &err))
        fail_msg("%s", err.message);
    if (parse_long("forces = corot-fem\ndepth = 100", "", &one, &err))
        fail_msg("%s", err.message);
    const ftm_mesh *m = ftm_scene_mesh(two);
    const int32_t n = ftm_mesh_node_count(m);
    double *f = malloc(3 * (size_t)n * sizeof *f), *u2 = malloc(3 * (size_t)n * sizeof *u2),
           *u1 = malloc(3 * (size_t)n * sizeof *u1), *uh = malloc(3 * (size_t)n * sizeof *uh);
    ftm_contact c[4];
    end_loads(m, fx, fz, c, f);
    fem_reference(two, f, u2);
    fem_reference(one, f, u1);
    for (size_t k = 0; k < 3 * (size_t)n; k++)
        uh[k] = 0.5 * u2[k];
    double big = 0, gap = 0;
    for (size_t k = 0; k < 3 * (size_t)n; k++) {
        big = fmax(big, fabs(u2[k]));
        gap = fmax(gap, fabs(u1[k] - u2[k]));
    }
    print_message("FEM: two materials' largest displacement %.4g m, one material's off by %.2g "
                  "of it\n", big, gap / big);
    assert_true(gap > 0.2 * big);

    ftm_sim_def d = ftm_scene_sim_def(two);
    const double corot = settle_against(two, &d, u2, fx, fz, 1.0);
    print_message("transmittal, full depth, co-rotational per label: off the FEM by %.2g\n",
                  corot);
    assert_true(corot < 1e-3);
    ftm_sim_def d1 = ftm_scene_sim_def(one);
    assert_true(settle_against(one, &d1, u2, fx, fz, 1.0) > 0.1);

    /* the elastic far field, depth 2, linear forces: one body, then the
     * other, then the first again (the registry and the cache hold both) */
    for (int round = 0; round < 2; round++) {
        ftm_sim_def a = ftm_scene_sim_def(one), b = ftm_scene_sim_def(two);
        a.forces = b.forces = FTM_FORCES_COROT_FEM;
        a.far_field = b.far_field = FTM_FAR_FIELD_ELASTIC;
        a.depth = b.depth = 2;
        const double ea = settle_against(one, &a, u1, fx, fz, 1.0),
                     eb = settle_against(two, &b, u2, fx, fz, 1.0);
        print_message("elastic far field at depth 2 (round %d): one material off its FEM by %.2g, "
                      "two materials by %.2g\n", round, ea, eb);
        assert_true(ea < 2e-4);
        assert_true(eb < 2e-4);
        /* E times 2 by the instructor: half the displacement */
        const double eh = settle_against(two, &b, uh, fx, fz, 2.0);
        print_message("... stiffness times 2: off half the FEM's by %.2g\n", eh);
        assert_true(eh < 2e-4);
    }
    free(f);
    free(u1);
    free(u2);
    free(uh);
    ftm_scene_destroy(two);
    ftm_scene_destroy(one);
}

/* The press estimate (scene_feel.c) runs the scene's own simulation: a
 * stiffer label gives a larger force, for element forces ([fem LABEL]) and
 * for springs ([material LABEL]). */
static void test_press_estimate_per_label(void **state)
{
    (void)state;
    const char *sims[] = {"forces = corot-fem\ntime_step = 2e-4", "forces = springs\ntime_step = 2e-4"};
    const char *labels[] = {"[fem 5]\nyoung = 4e4\npoisson = 0\n", "[material 5]\nstiffness = 400\n"};
    for (int k = 0; k < 2; k++) {
        double force[2];
        for (int with = 0; with < 2; with++) {
            ftm_scene *scene = NULL;
            ftm_error err;
            if (parse_bar(sims[k], with ? labels[k] : "", &scene, &err))
                fail_msg("%s", err.message);
            ftm_press_estimate e;
            if (ftm_scene_press_estimate(scene, 0.01, &e, &err))
                fail_msg("%s", err.message);
            force[with] = e.force;
            ftm_scene_destroy(scene);
        }
        print_message("press estimate, %s: %.4g N with the stiffer label, %.4g N without\n",
                      k ? "springs" : "co-rotational", force[1], force[0]);
        assert_true(force[1] > 1.2 * force[0]);
    }
}

static void expect_refused(const char *sim_keys, const char *extra, const char *part)
{
    ftm_scene *scene = NULL;
    ftm_error err = {0};
    int rc = parse_bar(sim_keys, extra, &scene, &err);
    if (rc == FTM_OK)
        fail_msg("accepted: [sim] %s / %s", sim_keys, extra);
    assert_null(scene);
    if (!strstr(err.message, "bar.scene:") || !strstr(err.message, part))
        fail_msg("message '%s' lacks the file or '%s'", err.message, part);
}

/* fixed_label: every node of the label's elements held (issue 31, item 4) */
static void test_fixed_label(void **state)
{
    (void)state;
    char text[1024];
    ftm_scene *scene = NULL;
    ftm_error err;
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_label = 9\n"
             "[material]\nmass = 0.01\nstiffness = 100\n",
             msh_path);
    assert_int_equal(ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err), FTM_OK);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    int32_t fixed = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        const ftm_vec3 x = ftm_mesh_rest_position(m, i);
        /* label 9 is the hexahedron x 1..2: its 8 nodes, the shared face too */
        assert_int_equal(ftm_mesh_fixed(m, i), x.x >= 1.0);
        fixed += ftm_mesh_fixed(m, i);
    }
    assert_int_equal(fixed, 8);
    ftm_scene_destroy(scene);
    /* both labels, on one line: every node */
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_label = 5 9\n"
             "[material]\nmass = 0.01\nstiffness = 100\n",
             msh_path);
    assert_int_equal(ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err), FTM_OK);
    m = ftm_scene_mesh(scene);
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++)
        assert_true(ftm_mesh_fixed(m, i));
    ftm_scene_destroy(scene);
    /* a label no element carries: refused, naming the line */
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_label = 7\n"
             "[material]\nmass = 0.01\nstiffness = 100\n",
             msh_path);
    assert_int_equal(ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "bar.scene:3: fixed_label: no element of the mesh has "
                                        "label 7 (0 tetrahedra, 2 hexahedra)"));
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_label = 0\n"
             "[material]\nmass = 0.01\nstiffness = 100\n",
             msh_path);
    assert_int_not_equal(ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err), FTM_OK);
    assert_non_null(strstr(err.message, "bar.scene:3: fixed_label"));
    printf("fixed_label = 0: %s\n", err.message);
}

/* `name` in [fem LABEL]: what the client's legend calls the label
 * (client/tissues.c); optional, printable ASCII, unique */
static void test_label_names(void **state)
{
    (void)state;
    ftm_scene *scene = NULL;
    ftm_error err = {0};
    int rc = parse_bar("forces = linear-fem",
                       "[fem 9]\nname =  white matter   # inner\nyoung = 4e4\npoisson = 0\n"
                       "[fem 5]\nyoung = 1e4\npoisson = 0\n",
                       &scene, &err);
    if (rc != FTM_OK)
        fail_msg("%s", err.message);
    assert_string_equal(ftm_scene_label_name(scene, 9), "white matter");
    assert_null(ftm_scene_label_name(scene, 5)); /* a section without a name */
    assert_null(ftm_scene_label_name(scene, 7)); /* no section */
    int32_t n = 0;
    const ftm_label_material *m = ftm_scene_label_materials(scene, &n);
    assert_int_equal(n, 2);
    assert_true(m[0].label == 9 && m[0].young == 4e4); /* the name leaves the material be */
    ftm_scene_destroy(scene);

    const char *lin = "forces = linear-fem";
    expect_refused(lin, "[fem 9]\nname =\nyoung = 1\npoisson = 0\n", ":14: name: missing value");
    expect_refused(lin, "[fem 9]\nname = a\nname = b\n", ":15: duplicate key 'name' (first at line 14)");
    expect_refused(lin, "[fem 9]\nname = 0123456789012345678901234567890123456789x\n",
                   ":14: name: at most 40 characters, got 41");
    expect_refused(lin, "[fem 9]\nname = gr\xc3\xa9y\n",
                   ":14: name: character 3 is not printable ASCII (byte 0xc3)");
    expect_refused(lin, "[fem 9]\nname = a\tb\n", "character 2 is not printable ASCII (byte 0x09)");
    expect_refused(lin,
                   "[fem 5]\nname = grey\nyoung = 1\npoisson = 0\n"
                   "[fem 9]\nname = grey\nyoung = 1\npoisson = 0\n",
                   ":18: name 'grey' already names label 5 (line 14)");
    expect_refused(lin, "[fem 9]\nlabel = grey\n", "takes young, poisson, density and name");
}

static void test_refusals(void **state)
{
    (void)state;
    const char *lin = "forces = linear-fem";
    expect_refused(lin, "[fem 7]\nyoung = 1\npoisson = 0\n",
                   ":13: [fem 7]: no element of the mesh has label 7");
    expect_refused(lin, "[fem 0]\n", ":13: [fem 0]: a label is a whole number 1 ..");
    expect_refused(lin, "[fem 2.5]\n", "a label is a whole number");
    expect_refused(lin, "[fem grey]\n", "a label is a whole number");
    expect_refused(lin, "[fem 9]\nyoung = 1\npoisson = 0\n[fem 9]\n",
                   ":16: duplicate section [fem 9] (first at line 13)");
    expect_refused(lin, "[fem 9]\nyoung = 1\n", ":13: [fem 9] needs poisson");
    expect_refused(lin, "[fem 9]\npoisson = 0.3\n", ":13: [fem 9] needs young");
    expect_refused(lin, "[fem 9]\nyoung = 1\npoisson = 0.5\n", "poisson must be > -1 and < 0.5");
    expect_refused(lin, "[fem 9]\nyoung = -1\npoisson = 0\n", "young");
    expect_refused(lin, "[fem 9]\nyoung = 1\nyoung = 2\n", ":15: duplicate key 'young'");
    expect_refused(lin, "[fem 9]\nyoung = 1\npoisson = 0\nstiffness = 3\n",
                   ":16: unknown key 'stiffness' in [fem 9] (a label's section takes young, "
                   "poisson, density and name)");
    /* a density per label beside a [fem] without one */
    expect_refused(lin, "[fem 9]\nyoung = 1\npoisson = 0\ndensity = 1000\n",
                   ":16: [fem 9]: a density per label needs [fem] density too");
    expect_refused(lin, "[fem 9]\nyoung = 1\npoisson = 0\ndensity = 0\n",
                   ":16: density must be > 0");
    /* [material LABEL] */
    expect_refused(lin, "[material 7]\nstiffness = 5\n",
                   ":13: [material 7]: no element of the mesh has label 7");
    expect_refused(lin, "[material 9]\n", ":13: [material 9] needs stiffness");
    expect_refused(lin, "[material 9]\nmass = 1\n",
                   ":14: unknown key 'mass' in [material 9] (a label's section takes stiffness; "
                   "mass and damping are per node");
    expect_refused(lin, "[material 9]\nstiffness = 0\n", ":14: stiffness must be > 0");
    expect_refused(lin, "[material 9]\nstiffness = 1\nstiffness = 2\n",
                   ":15: duplicate key 'stiffness' (first at line 14)");
    expect_refused(lin, "[material 9]\nstiffness = 1\n[material 9]\nstiffness = 1\n",
                   ":15: duplicate section [material 9] (first at line 13)");
    expect_refused(lin, "[material x]\n", ":13: [material x]: a label is a whole number");
    /* every element model and the elastic far field take them: accepted */
    const char *ok[] = {"forces = corot-fem", "forces = neo-hookean", "forces = springs",
                        "forces = linear-fem\nfar_field = elastic",
                        "forces = corot-fem\nfar_field = elastic"};
    for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++) {
        ftm_scene *sc = NULL;
        ftm_error e2;
        if (parse_bar(ok[i], "[fem 9]\nyoung = 1\npoisson = 0\n", &sc, &e2) != FTM_OK)
            fail_msg("[sim] %s refused: %s", ok[i], e2.message);
        ftm_scene_destroy(sc);
    }

    /* a [fem LABEL] without [fem] */
    char text[1024];
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_box = -0.1 -0.1 -0.1 0.1 1.1 1.1\n"
             "[material]\nmass = 0.01\nstiffness = 100\n"
             "[fem 9]\nyoung = 1\npoisson = 0\n",
             msh_path);
    ftm_scene *scene = NULL;
    ftm_error err;
    assert_int_equal(ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "bar.scene:7: [fem 9] needs a [fem] section too"));

    /* the simulation checks a definition made by hand the same way */
    assert_int_equal(parse_bar(lin, "", &scene, &err), FTM_OK);
    ftm_sim_def d = ftm_scene_sim_def(scene);
    ftm_label_material lm[2] = {{.label = 9, .young = 4e4, .poisson = 0},
                                {.label = 3, .young = 4e4, .poisson = 0}};
    d.label_materials = lm;
    d.label_material_count = 2;
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "label 3 has a material, but no element"));
    lm[1].label = 9;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "label 9 has two materials"));
    d.label_material_count = 1;
    d.forces = FTM_FORCES_SPRINGS; /* springs' stiffness is the links' */
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "per-label materials are for element forces"));
    d.forces = FTM_FORCES_NEO_HOOKEAN;
    lm[0].density = 500; /* a label's density, the body none */
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "label 9 has a density (500 kg/m^3), the body none"));
    lm[0].density = -1;
    d.density = 1000;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "label 9: density must be >= 0"));
    lm[0].density = 0;
    d.density = 0;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_OK);
    ftm_sim_destroy(sim);
    /* the simulation keeps its own copy of the array */
    d.forces = FTM_FORCES_LINEAR_FEM;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_OK);
    lm[0].young = -1;
    assert_int_equal(ftm_sim_step(sim), FTM_OK);
    ftm_sim_destroy(sim);
    ftm_scene_destroy(scene);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_two_labels_in_series),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_label_names),
        cmocka_unit_test(test_fixed_label),
        cmocka_unit_test(test_corot_neo_per_label),
        cmocka_unit_test(test_density_per_label),
        cmocka_unit_test(test_spring_stiffness_per_label),
        cmocka_unit_test(test_two_materials_fem_transmittal_far_field),
        cmocka_unit_test(test_press_estimate_per_label),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
