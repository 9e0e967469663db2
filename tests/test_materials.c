/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Materials per element label (issue 31, item 2): a scene's [fem LABEL]
 * sections and the element forces that honour them.
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

#include "ftm/mesh.h"
#include "ftm/scene.h"
#include "ftm/sim.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmp_dir[256];
static char msh_path[300];

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
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    unlink(msh_path);
    rmdir(tmp_dir);
    return 0;
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
static void series_forces(const ftm_scene *scene, double e1, double e2, double *worst,
                          double *end_fx)
{
    const ftm_mesh *m = ftm_scene_mesh(scene);
    ftm_sim_def d = ftm_scene_sim_def(scene);
    ftm_sim *sim = NULL;
    ftm_error err;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    const double sigma = 100.0, eps1 = sigma / e1, eps2 = sigma / e2;
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
    expect_refused(lin, "[fem 9]\nlabel = grey\n", "takes young, poisson and name");
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
    expect_refused(lin, "[fem 9]\ndensity = 1000\n", "density is the body's, in [fem]");
    expect_refused(lin, "[fem 9]\nyoung = 1\nyoung = 2\n", ":15: duplicate key 'young'");
    expect_refused("forces = corot-fem", "[fem 9]\nyoung = 1\npoisson = 0\n",
                   "linear-fem only (so far)");
    expect_refused("forces = springs", "[fem 9]\nyoung = 1\npoisson = 0\n",
                   "linear-fem only (so far)");
    expect_refused("forces = linear-fem\nfar_field = elastic", "[fem 9]\nyoung = 1\npoisson = 0\n",
                   "far_field = elastic: not yet");

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
    d.forces = FTM_FORCES_NEO_HOOKEAN;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "linear-fem"));
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
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
