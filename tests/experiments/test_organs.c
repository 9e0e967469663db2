/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The generated surface organs of `ftm experiment organs` (paper 4.4,
 * tools/organs.c): the paper's exact node and triangle counts, closed and
 * consistently oriented surfaces of well-shaped triangles, and meshes that
 * simulate stably at h = 1 ms. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "organs.h"

#include <math.h>
#include <stdio.h>

static void count_log(void *user, ftm_log_level level, const char *message)
{
    (void)level;
    (void)message;
    (*(int *)user)++;
}

static void check_organ(ftm_organ_kind kind, int32_t nodes, int32_t tris)
{
    ftm_organ o;
    assert_int_equal(ftm_organ_generate(kind, &o), 0);
    ftm_organ_quality q;
    ftm_organ_measure(&o, &q);
    printf("%s: %d nodes, %d triangles, %d edges, %d rings; angles %.1f..%.1f deg, "
           "%d below 20; edges %.2f..%.2f mm; max degree %d; volume %.3g l\n",
           o.name, q.nodes, q.triangles, q.edges, o.rings, q.min_angle, q.max_angle,
           q.below_20deg, q.min_edge * 1e3, q.max_edge * 1e3, q.max_degree, q.volume * 1e3);
    assert_int_equal(q.nodes, nodes);
    assert_int_equal(q.triangles, tris);
    assert_int_equal(q.edges, 3 * tris / 2); /* closed: every edge in two triangles */
    assert_int_equal(q.euler, 2);
    assert_int_equal(q.open_edges, 0);
    assert_int_equal(q.misoriented_edges, 0);
    assert_int_equal(q.degenerate, 0);
    assert_int_equal(q.inverted, 0);
    assert_true(q.volume > 0); /* normals outward */
    assert_true(q.min_angle >= 20.0);
    assert_true(ftm_organ_quality_ok(&q));
    int32_t fixed = 0;
    for (int32_t i = 0; i < o.node_count; i++)
        fixed += o.fixed[i];
    assert_true(fixed >= 3 && fixed < o.node_count / 10); /* attached, not held */

    /* the mesh: a spring per edge, the attachment fixed; stable at 1 ms */
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_material_def mat = ftm_organ_material();
    ftm_error err;
    assert_int_equal(ftm_organ_build(&o, &mat, mb, &err), 0);
    ftm_mesh *mesh;
    assert_int_equal(ftm_mesh_build(mb, NULL, &mesh, &err), 0);
    ftm_mesh_builder_destroy(mb);
    assert_int_equal(ftm_mesh_node_count(mesh), nodes);
    assert_int_equal(ftm_mesh_triangle_count(mesh), tris);
    assert_int_equal(ftm_mesh_link_count(mesh), q.edges);
    assert_true(ftm_mesh_critical_time_step(mesh) > 1.5 * FTM_ORGAN_TIME_STEP);
    int warnings = 0;
    ftm_sim_def sd = ftm_default_sim_def();
    sd.time_step = FTM_ORGAN_TIME_STEP;
    sd.log = count_log;
    sd.log_user = &warnings;
    ftm_sim *sim;
    assert_int_equal(ftm_sim_create(mesh, &sd, &sim, &err), 0);
    assert_int_equal(warnings, 0);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(mesh);

    /* the pressed triangle is free and its normal outward */
    ftm_vec3 n;
    int32_t t = ftm_organ_press_triangle(&o, &n);
    assert_true(t >= 0 && t < o.tri_count);
    for (int v = 0; v < 3; v++)
        assert_false(o.fixed[o.tris[3 * t + v]]);
    assert_true(fabs(n.x * n.x + n.y * n.y + n.z * n.z - 1) < 1e-12);
    ftm_organ_free(&o);
}

static void test_lung(void **state)
{
    (void)state;
    check_organ(FTM_ORGAN_LUNG, 1769, 3534);
}

static void test_stomach(void **state)
{
    (void)state;
    check_organ(FTM_ORGAN_STOMACH, 512, 1020);
}

/* Deterministic: two generations give the same bits. */
static void test_deterministic(void **state)
{
    (void)state;
    ftm_organ a, b;
    assert_int_equal(ftm_organ_generate(FTM_ORGAN_STOMACH, &a), 0);
    assert_int_equal(ftm_organ_generate(FTM_ORGAN_STOMACH, &b), 0);
    assert_memory_equal(a.pos, b.pos, (size_t)a.node_count * 3 * sizeof *a.pos);
    assert_memory_equal(a.tris, b.tris, (size_t)a.tri_count * 3 * sizeof *a.tris);
    ftm_organ_free(&a);
    ftm_organ_free(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lung),
        cmocka_unit_test(test_stomach),
        cmocka_unit_test(test_deterministic),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
