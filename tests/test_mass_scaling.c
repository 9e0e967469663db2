/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Selective mass scaling ([fem] mass_scaling, ftm_sim_def.mass_scaling):
 * the nodes whose rows bound the critical step below the time step get the
 * mass that brings it to the time step; the others keep theirs.
 *
 * The body: two unit hexahedra along x, clamped at x = 0, the second (label
 * 9) a hundred times as stiff as the first. The time step lies between the
 * two parts' critical steps, so only the stiff part's nodes need mass. */
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

/* Two unit hexahedra along x, physical groups 5 (x 0..1) and 9 (x 1..2). */
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
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/ftm-test-mass-scaling-XXXXXX");
    if (!mkdtemp(tmp_dir))
        return -1;
    snprintf(msh_path, sizeof msh_path, "%s/bar.msh", tmp_dir);
    FILE *f = fopen(msh_path, "w");
    if (!f)
        return -1;
    fputs(bar_msh, f);
    return fclose(f) ? -1 : 0;
}

static int group_teardown(void **state)
{
    (void)state;
    unlink(msh_path);
    rmdir(tmp_dir);
    return 0;
}

static ftm_sim *bar_sim(double time_step, const char *scaling, ftm_scene **scene_out)
{
    char text[2048];
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_box = -0.1 -0.1 -0.1 0.1 1.1 1.1\n"
             "[material]\nmass = 0.01\nstiffness = 100\ndamping = 20000\n"
             "[sim]\nforces = linear-fem\ntime_step = %.17g\n"
             "[fem]\nyoung = 1e4\npoisson = 0.3\ndensity = 1000\n%s\n"
             "[fem 9]\nyoung = 1e6\npoisson = 0.3\n",
             msh_path, time_step, scaling);
    ftm_scene *scene = NULL;
    ftm_error err;
    if (ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err))
        fail_msg("%s", err.message);
    ftm_sim_def d = ftm_scene_sim_def(scene);
    ftm_sim *sim = NULL;
    if (ftm_sim_create(ftm_scene_mesh(scene), &d, &sim, &err))
        fail_msg("%s", err.message);
    *scene_out = scene;
    return sim;
}

static void test_only_the_stiff_part_gets_mass(void **state)
{
    (void)state;
    ftm_scene *s0 = NULL, *s1 = NULL;
    ftm_sim *plain = bar_sim(1e-3, "", &s0);
    const double h_plain = ftm_sim_critical_time_step(plain);
    /* the stiff part's nodes bound it: a step three times as long (the soft
     * part's own critical step is ten times as long) */
    const double h = 3.0 * h_plain;
    ftm_sim_destroy(plain);
    ftm_scene_destroy(s0);
    plain = bar_sim(h, "", &s0);
    ftm_sim *scaled = bar_sim(h, "mass_scaling = on", &s1);
    assert_true(ftm_sim_critical_time_step(plain) < h);
    assert_true(ftm_sim_critical_time_step(scaled) >= h * (1.0 - 1e-9));
    const ftm_mesh *m = ftm_scene_mesh(s1);
    const double *m0 = ftm_sim_masses(plain), *m1 = ftm_sim_masses(scaled);
    int heavier = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        const ftm_vec3 r = ftm_mesh_rest_position(m, i);
        if (ftm_mesh_fixed(m, i))
            continue;
        assert_true(m1[i] >= m0[i]);
        if (r.x == 2.0) /* only in the stiff hexahedron */
            assert_true(m1[i] > m0[i]);
        if (m1[i] > m0[i])
            heavier++;
    }
    assert_true(heavier >= 4);
    ftm_sim_destroy(plain);
    ftm_sim_destroy(scaled);
    ftm_scene_destroy(s0);
    ftm_scene_destroy(s1);
}

/* Under a step three times its critical step the plain bar needs the guard's
 * substeps; the scaled one runs in single steps, stays bounded and gives the
 * same hash twice (heavily damped: the layer-by-layer update with element
 * forces needs d/2m >= 0.055 lambda h, docs/stability.md). */
static void test_scaled_bar_runs_in_single_steps(void **state)
{
    (void)state;
    ftm_scene *s0 = NULL;
    ftm_sim *probe = bar_sim(1e-3, "", &s0);
    const double h = 3.0 * ftm_sim_critical_time_step(probe);
    ftm_sim_destroy(probe);
    ftm_scene_destroy(s0);
    uint64_t hash[2], events[3];
    for (int run = 0; run < 3; run++) { /* scaled twice, then plain */
        ftm_scene *s = NULL;
        ftm_sim *sim = bar_sim(h, run < 2 ? "mass_scaling = on" : "", &s);
        const ftm_mesh *m = ftm_scene_mesh(s);
        int32_t end = -1;
        for (int32_t i = 0; i < ftm_mesh_node_count(m); i++)
            if (ftm_mesh_rest_position(m, i).x == 2.0)
                end = i;
        ftm_contact c = {.node = end, .kind = FTM_CONTACT_FORCE, .value = {10.0, 0.0, 0.0}};
        ftm_error err;
        if (ftm_sim_set_contacts(sim, &c, 1, &err))
            fail_msg("%s", err.message);
        assert_int_equal(ftm_sim_run(sim, 400), FTM_OK);
        ftm_sim_stats st;
        ftm_sim_get_stats(sim, &st);
        events[run] = st.guard_events;
        const double *x = ftm_sim_positions(sim);
        for (int32_t i = 0; i < 3 * ftm_mesh_node_count(m); i++)
            assert_true(isfinite(x[i]) && fabs(x[i]) < 10.0);
        if (run < 2)
            hash[run] = ftm_sim_hash(sim);
        ftm_sim_destroy(sim);
        ftm_scene_destroy(s);
    }
    assert_int_equal(events[0], 0);
    assert_true(events[2] > 0); /* the plain one substeps */
    assert_true(hash[0] == hash[1]);
}

static void test_refused_value(void **state)
{
    (void)state;
    char text[512];
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\n[material]\nmass = 0.01\nstiffness = 100\n"
             "[sim]\nforces = linear-fem\n[fem]\nyoung = 1e4\npoisson = 0.3\nmass_scaling = "
             "maybe\n",
             msh_path);
    ftm_scene *scene = NULL;
    ftm_error err;
    assert_int_not_equal(ftm_scene_parse(text, strlen(text), "bar.scene", &scene, &err), FTM_OK);
    assert_non_null(strstr(err.message, "mass_scaling"));
    assert_non_null(strstr(err.message, "bar.scene:11:"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_only_the_stiff_part_gets_mass),
        cmocka_unit_test(test_scaled_bar_runs_in_single_steps),
        cmocka_unit_test(test_refused_value),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
