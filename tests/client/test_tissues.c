/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The tissues the client draws (client/tissues.c, no GL): the label of the
 * element each surface triangle bounds, faces between two elements left
 * out, the palette, and the legend's rows named from the scene. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "ftm/mesh.h"
#include "ftm/scene.h"
#include "tissues.h"

/* Two tetrahedra sharing the face (1, 2, 3): labels 4 and 7; `shared`: the
 * shared face given as a triangle too (a file's interface triangle). */
static ftm_mesh *two_tets(bool shared, bool labelled)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    assert_non_null(b);
    const double p[5][3] = {{0, 0, -1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 1}};
    for (int i = 0; i < 5; i++) {
        ftm_node_def n = ftm_default_node_def();
        n.position = (ftm_vec3){p[i][0], p[i][1], p[i][2]};
        assert_true(ftm_mesh_builder_add_node(b, &n) == i);
    }
    assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, 0, 1, 3, 2), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, 4, 1, 2, 3), FTM_OK);
    if (labelled) {
        assert_int_equal(ftm_mesh_builder_set_tetrahedron_label(b, 0, 4), FTM_OK);
        assert_int_equal(ftm_mesh_builder_set_tetrahedron_label(b, 1, 7), FTM_OK);
    }
    const int e[9][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}, {4, 1}, {4, 2}, {4, 3}};
    for (int i = 0; i < 9; i++) {
        ftm_link_def l = ftm_default_link_def();
        l.a = e[i][0], l.b = e[i][1];
        assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
    }
    if (shared) { /* every face, the shared one among them */
        const int f[7][3] = {{0, 1, 3}, {0, 2, 1}, {0, 3, 2}, {1, 2, 3},
                             {4, 1, 2}, {4, 2, 3}, {4, 3, 1}};
        for (int i = 0; i < 7; i++)
            assert_int_equal(ftm_mesh_builder_add_triangle(b, f[i][0], f[i][1], f[i][2]), FTM_OK);
    }
    ftm_mesh_build_def d = ftm_default_mesh_build_def();
    d.reorder = false;
    ftm_mesh *m = NULL;
    ftm_error err;
    if (ftm_mesh_build(b, &d, &m, &err) != FTM_OK)
        fail_msg("%s", err.message);
    ftm_mesh_builder_destroy(b);
    return m;
}

/* Whether triangle t of m has node v (a mesh index of input v). */
static bool tri_has(const ftm_mesh *m, int32_t t, int32_t input)
{
    const int32_t *tri = ftm_mesh_triangles(m) + 3 * t, v = ftm_mesh_node_of_input(m, input);
    return tri[0] == v || tri[1] == v || tri[2] == v;
}

static void test_surface_labels(void **state)
{
    (void)state;
    int32_t labels[8];
    /* the boundary faces the mesh extracts: three of each tetrahedron */
    ftm_mesh *m = two_tets(false, true);
    assert_int_equal(ftm_mesh_triangle_count(m), 6);
    assert_int_equal(ftm_tissue_surface_labels(m, labels), FTM_OK);
    for (int32_t t = 0; t < 6; t++)
        assert_int_equal(labels[t], tri_has(m, t, 4) ? 7 : 4);
    ftm_mesh_destroy(m);
    /* the file's triangles, the interface among them: inside, not drawn */
    m = two_tets(true, true);
    assert_int_equal(ftm_mesh_triangle_count(m), 7);
    assert_int_equal(ftm_tissue_surface_labels(m, labels), FTM_OK);
    int inside = 0;
    for (int32_t t = 0; t < 7; t++) {
        bool interface = !tri_has(m, t, 0) && !tri_has(m, t, 4);
        assert_int_equal(labels[t], interface ? FTM_TISSUE_INTERIOR : tri_has(m, t, 4) ? 7 : 4);
        inside += interface;
    }
    assert_int_equal(inside, 1);
    ftm_tissue list[4];
    assert_int_equal(ftm_tissue_list(labels, 7, m, NULL, list, 4), 2); /* the interface left out */
    assert_int_equal(list[0].label, 4);
    assert_int_equal(list[0].triangles, 3);
    assert_string_equal(list[0].name, "label 4");
    assert_true(list[0].young == 0);
    assert_int_equal(list[1].label, 7);
    assert_int_equal(ftm_tissue_list(labels, 7, m, NULL, list, 1), 1); /* at most cap */
    ftm_mesh_destroy(m);
    /* no labels: every triangle label 0, one tissue, the default colour */
    m = two_tets(false, false);
    assert_int_equal(ftm_tissue_surface_labels(m, labels), FTM_OK);
    for (int32_t t = 0; t < 6; t++)
        assert_int_equal(labels[t], 0);
    assert_int_equal(ftm_tissue_list(labels, 6, m, NULL, list, 4), 1);
    assert_string_equal(list[0].name, "unlabelled");
    ftm_mesh_destroy(m);
}

/* Neighbouring labels in clearly different colours, none the background's
 * grey; label 0 the client's tissue colour; the palette repeats. */
static void test_palette(void **state)
{
    (void)state;
    float c[FTM_TISSUE_PALETTE + 1][3]; /* c[0]: label 0 */
    ftm_tissue_color(0, c[0]);
    assert_true(c[0][0] == 0.86f && c[0][1] == 0.56f && c[0][2] == 0.52f);
    for (int i = 1; i <= FTM_TISSUE_PALETTE; i++)
        ftm_tissue_color(i, c[i]);
    for (int i = 0; i <= FTM_TISSUE_PALETTE; i++)
        for (int j = 0; j < i; j++) {
            double d = 0;
            for (int k = 0; k < 3; k++)
                d += (double)(c[i][k] - c[j][k]) * (c[i][k] - c[j][k]);
            if (d < 0.02) /* about 0.08 per channel */
                fail_msg("labels %d and %d look alike", i, j);
        }
    float r[3];
    ftm_tissue_color(FTM_TISSUE_PALETTE + 2, r);
    assert_memory_equal(r, c[2], sizeof r);
}

/* The legend of tests/data/scenes/two_tissue.scene: its names and E. */
static void test_scene_names(void **state)
{
    (void)state;
    ftm_scene *scene = NULL;
    ftm_error err;
    if (ftm_scene_open(FTM_TEST_DATA "/scenes/two_tissue.scene", &scene, &err) != FTM_OK)
        fail_msg("%s", err.message);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    int32_t n = ftm_mesh_triangle_count(m);
    assert_int_equal(n, 272); /* 8 x 4 x 3 hexahedra: 136 quads */
    int32_t labels[272];
    assert_int_equal(ftm_tissue_surface_labels(m, labels), FTM_OK);
    ftm_tissue t[4];
    assert_int_equal(ftm_tissue_list(labels, n, m, scene, t, 4), 2);
    char row[96];
    assert_int_equal(t[0].label, 1);
    assert_int_equal(t[0].triangles, 136);
    ftm_tissue_legend_text(&t[0], row, sizeof row);
    assert_string_equal(row, "grey matter  E 2 kPa");
    ftm_tissue_legend_text(&t[1], row, sizeof row);
    assert_string_equal(row, "white matter  E 6 kPa");
    /* without the scene: the mesh's names (the .msh's $PhysicalNames), E
     * unknown; without either, the label */
    assert_int_equal(ftm_tissue_list(labels, n, m, NULL, t, 4), 2);
    ftm_tissue_legend_text(&t[1], row, sizeof row);
    assert_string_equal(row, "right tissue");
    assert_int_equal(ftm_tissue_list(labels, n, NULL, NULL, t, 4), 2);
    ftm_tissue_legend_text(&t[1], row, sizeof row);
    assert_string_equal(row, "label 2");
    t[1].young = 1.5e6;
    ftm_tissue_legend_text(&t[1], row, sizeof row);
    assert_string_equal(row, "label 2  E 1.5 MPa");
    ftm_scene_destroy(scene);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_surface_labels),
        cmocka_unit_test(test_palette),
        cmocka_unit_test(test_scene_names),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
