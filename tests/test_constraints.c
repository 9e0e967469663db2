/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Partial constraints and springs to ground in the transmittal
 * (docs/scene-format.md, Boundary conditions):
 *   - a block resting on a plane, its bottom nodes sliding on it, pressed
 *     from above: it spreads sideways and its bottom never leaves the plane
 *     (an axis plane exactly, a tilted one to rounding), in every order;
 *   - a node on springs to ground alone, loaded: displacement F / k_total;
 *   - every kernel (native, portable; planar or full sweep) gives the same
 *     bits with constraints, as without;
 *   - the scene keys build what they say; the mesh keeps them. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/ftm.h"
#include "sim_internal.h" /* ftm_sim_select_kernel */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define NB 6      /* nodes per side of the block */
#define NZ 4      /* layers of the block */
#define SP 0.01   /* spacing [m] */

/* A NB x NB x NZ lattice block, nothing fixed, its bottom (z = 0) nodes
 * sliding on the plane normal to `normal`; with `spring`, two top corners
 * on springs to ground. */
static ftm_mesh *bc_block(ftm_vec3 normal, bool spring)
{
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_lattice3d_def d = ftm_default_lattice3d_def();
    d.nx = d.ny = NB;
    d.nz = NZ;
    d.spacing = (ftm_vec3){SP, SP, SP};
    d.stencil = FTM_STENCIL_18;
    d.material = (ftm_material_def){0.001, 0.3, 50.0, {1.0, 1.0, 1.0}};
    d.fixed_faces = 0;
    assert_int_equal(ftm_generate_lattice3d(b, &d, &err), FTM_OK);
    for (int32_t i = 0; i < NB * NB; i++)
        assert_int_equal(ftm_mesh_builder_add_slide(b, i, normal), FTM_OK);
    if (spring) {
        const int32_t top = NB * NB * (NZ - 1);
        assert_int_equal(ftm_mesh_builder_add_ground_spring(b, top, 20.0), FTM_OK);
        assert_int_equal(ftm_mesh_builder_add_ground_spring(b, top + NB * NB - 1, 20.0), FTM_OK);
    }
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    return m;
}

/* The top face's nodes pressed down, each by f. */
static int32_t top_press(const ftm_mesh *m, double f, ftm_contact *c)
{
    int32_t count = 0;
    for (int j = 1; j < NB - 1; j++)
        for (int i = 1; i < NB - 1; i++)
            c[count++] = (ftm_contact){
                .node = ftm_mesh_node_of_input(m, i + NB * (j + NB * (NZ - 1))),
                .group = 0,
                .kind = FTM_CONTACT_FORCE,
                .value = {0, 0, -f}};
    return count;
}

static ftm_sim *pressed(const ftm_mesh *m, ftm_order order, bool portable, int steps)
{
    ftm_error err;
    ftm_sim_def sd = ftm_default_sim_def();
    sd.order = order;
    sd.time_step = 1e-3;
    sd.depth = 20; /* the whole block */
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &sd, &sim, &err), FTM_OK);
    ftm_sim_select_kernel(sim, portable);
    ftm_contact c[NB * NB];
    int32_t nc = top_press(m, 0.02, c);
    assert_int_equal(ftm_sim_set_contacts(sim, c, nc, &err), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, steps), FTM_OK);
    return sim;
}

/* Bottom on z = 0: exactly on it; it spreads outward; the top goes down. */
static void test_block_slides_on_floor(void **state)
{
    (void)state;
    const ftm_order orders[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS, FTM_ORDER_LAYER_JACOBI};
    ftm_mesh *m = bc_block((ftm_vec3){0, 0, 1}, false);
    for (int o = 0; o < 3; o++) {
        ftm_sim *sim = pressed(m, orders[o], false, 1500);
        const double c = 0.5 * (NB - 1) * SP;
        double spread = 0.0, off = 0.0;
        for (int32_t in = 0; in < NB * NB; in++) {
            const int32_t i = ftm_mesh_node_of_input(m, in);
            ftm_vec3 x = ftm_sim_position(sim, i), X = ftm_mesh_rest_position(m, i);
            off = fmax(off, fabs(x.z - X.z));
            /* outward: along the node's direction from the centre */
            spread += (x.x - X.x) * (X.x - c) + (x.y - X.y) * (X.y - c);
            if (in == 0) /* a corner moved out in x and y */
                assert_true(x.x - X.x < -1e-6 && x.y - X.y < -1e-6);
        }
        assert_true(off == 0.0); /* an axis plane: bit for bit */
        assert_true(spread > 0.0);
        const int32_t top = ftm_mesh_node_of_input(m, NB / 2 + NB * (NB / 2 + NB * (NZ - 1)));
        assert_true(ftm_sim_position(sim, top).z - ftm_mesh_rest_position(m, top).z < -1e-4);
        ftm_sim_destroy(sim);
    }
    ftm_mesh_destroy(m);
}

/* A tilted table: the bottom stays on its plane to rounding. */
static void test_block_slides_on_tilted_plane(void **state)
{
    (void)state;
    const ftm_vec3 n = {0.0, 0.6, 0.8};
    ftm_mesh *m = bc_block((ftm_vec3){0.0, 3.0, 4.0}, true); /* any length */
    ftm_vec3 got[2];
    assert_int_equal(ftm_mesh_slide_normals(m, ftm_mesh_node_of_input(m, 0), got), 1);
    assert_true(fabs(got[0].y - 0.6) < 1e-15 && fabs(got[0].z - 0.8) < 1e-15);
    ftm_sim *sim = pressed(m, FTM_ORDER_LAYER_COLORED, false, 1500);
    double off = 0.0, moved = 0.0;
    for (int32_t in = 0; in < NB * NB; in++) {
        const int32_t i = ftm_mesh_node_of_input(m, in);
        ftm_vec3 x = ftm_sim_position(sim, i), X = ftm_mesh_rest_position(m, i);
        ftm_vec3 u = {x.x - X.x, x.y - X.y, x.z - X.z};
        off = fmax(off, fabs(n.x * u.x + n.y * u.y + n.z * u.z));
        moved = fmax(moved, sqrt(u.x * u.x + u.y * u.y + u.z * u.z));
    }
    /* rounding of a 0.01 m coordinate is 1.7e-18 m; the nodes moved 1e-4 m */
    print_message("tilted plane: largest motion %.3g m, off the plane %.3g m\n", moved, off);
    assert_true(moved > 1e-5);
    assert_true(off < 1e-16);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
}

/* One node on two springs to ground (30 + 70 N/m), no links, loaded by F:
 * at rest u = F / 100 N/m. */
static void test_ground_spring_alone(void **state)
{
    (void)state;
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_node_def nd = ftm_default_node_def();
    nd.position = (ftm_vec3){0.1, 0.2, 0.3};
    nd.mass = 0.01;
    nd.damping = 1.0;
    assert_int_equal(ftm_mesh_builder_add_node(b, &nd), 0);
    assert_int_equal(ftm_mesh_builder_add_ground_spring(b, 0, 30.0), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_ground_spring(b, 0, 70.0), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_ground_spring(b, 0, -1.0), FTM_EINVAL);
    assert_int_equal(ftm_mesh_builder_add_ground_spring(b, 1, 1.0), FTM_ERANGE);
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    assert_true(ftm_mesh_ground_stiffness(m, 0) == 100.0);
    /* the critical step counts the spring: 2 sqrt(m / k) */
    assert_true(fabs(ftm_mesh_critical_time_step(m) - 2.0 * sqrt(0.01 / 100.0)) < 1e-15);
    const ftm_order orders[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS, FTM_ORDER_LAYER_JACOBI};
    for (int o = 0; o < 3; o++) {
        ftm_sim_def sd = ftm_default_sim_def();
        sd.order = orders[o];
        sd.time_step = 1e-3;
        ftm_sim *sim = NULL;
        assert_int_equal(ftm_sim_create(m, &sd, &sim, &err), FTM_OK);
        ftm_contact c = {.node = 0, .group = 0, .kind = FTM_CONTACT_FORCE, .value = {0.5, -0.2, 1.0}};
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(sim, 3000), FTM_OK);
        ftm_vec3 x = ftm_sim_position(sim, 0);
        const double u[3] = {x.x - 0.1, x.y - 0.2, x.z - 0.3}, want[3] = {0.005, -0.002, 0.01};
        for (int d = 0; d < 3; d++)
            assert_true(fabs(u[d] - want[d]) < 1e-12);
        /* held at 1 mm instead: the probe feels k u */
        c.kind = FTM_CONTACT_DISPLACEMENT;
        c.value = (ftm_vec3){0.001, 0, 0};
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_int_equal(ftm_sim_step(sim), FTM_OK);
        ftm_vec3 r = ftm_sim_reaction(sim, 0);
        assert_true(fabs(r.x + 0.1) < 1e-12 && r.y == 0.0 && r.z == 0.0); /* -k u */
        double K[9]; /* the haptic model's stiffness: dF/dx = -k I */
        assert_int_equal(ftm_sim_contact_stiffness(sim, 0, K), 1);
        for (int e = 0; e < 9; e++)
            assert_true(K[e] == (e % 4 == 0 ? -100.0 : 0.0));
        ftm_sim_destroy(sim);
    }
    ftm_mesh_destroy(m);
}

/* Native and portable kernels, planar and full sweeps: the same bits. */
static void test_kernels_agree(void **state)
{
    (void)state;
    ftm_mesh *m = bc_block((ftm_vec3){0.0, 3.0, 4.0}, true);
    const ftm_order orders[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_LAYER_JACOBI};
    for (int o = 0; o < 2; o++) {
        ftm_sim *a = pressed(m, orders[o], false, 400), *b = pressed(m, orders[o], true, 400);
        assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
        ftm_sim_destroy(a);
        ftm_sim_destroy(b);
    }
    ftm_mesh_destroy(m);
    /* a 2D lattice with nodes sliding on in-plane normals: the planar sweep
     * keeps z out and agrees with the full one */
    ftm_error err;
    ftm_mesh_builder *bl = ftm_mesh_builder_create();
    ftm_lattice2d_def d = ftm_default_lattice2d_def();
    d.nx = d.ny = 12;
    d.fixed_faces = FTM_FACE_XMIN;
    assert_int_equal(ftm_generate_lattice2d(bl, &d, &err), FTM_OK);
    for (int32_t j = 0; j < 12; j++) /* the right edge slides along y */
        assert_int_equal(ftm_mesh_builder_add_slide(bl, 11 + 12 * j, (ftm_vec3){1, 0, 0}), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_slide(bl, 5 + 12 * 11, (ftm_vec3){1, 1, 0}), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_ground_spring(bl, 6 + 12 * 6, 0.5), FTM_OK);
    ftm_mesh *p = NULL;
    assert_int_equal(ftm_mesh_build(bl, NULL, &p, &err), FTM_OK);
    ftm_mesh_builder_destroy(bl);
    uint64_t h[4];
    for (int v = 0; v < 4; v++) {
        ftm_sim_def sd = ftm_default_sim_def();
        sd.time_step = 0.1;
        sd.depth = 30;
        sd.planar_kernel = v & 1;
        ftm_sim *s = NULL;
        assert_int_equal(ftm_sim_create(p, &sd, &s, &err), FTM_OK);
        ftm_sim_select_kernel(s, v & 2);
        ftm_contact c = {.node = ftm_mesh_node_of_input(p, 8 + 12 * 5), .group = 0,
                         .kind = FTM_CONTACT_FORCE, .value = {0.3, 0.2, 0}};
        assert_int_equal(ftm_sim_set_contacts(s, &c, 1, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(s, 300), FTM_OK);
        ftm_sim_stats st;
        ftm_sim_get_stats(s, &st);
        assert_true((st.planar_sweeps > 0) == (bool)(v & 1));
        h[v] = ftm_sim_hash(s);
        ftm_sim_destroy(s);
    }
    assert_true(h[0] == h[1] && h[0] == h[2] && h[0] == h[3]);
    ftm_mesh_destroy(p);
}

/* The builder's rules: directions are orthonormalised, a repeated plane is
 * one, a third direction is refused; a fixed node keeps none. */
static void test_builder_rules(void **state)
{
    (void)state;
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int i = 0; i < 3; i++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = (ftm_vec3){i, 0, 0};
        assert_int_equal(ftm_mesh_builder_add_node(b, &nd), i);
    }
    ftm_link_def l = ftm_default_link_def();
    l.a = 0;
    l.b = 1;
    assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_slide(b, 0, (ftm_vec3){0, 0, 0}), FTM_EINVAL);
    assert_int_equal(ftm_mesh_builder_add_slide(b, 0, (ftm_vec3){NAN, 0, 1}), FTM_EINVAL);
    assert_int_equal(ftm_mesh_builder_add_slide(b, 3, (ftm_vec3){0, 0, 1}), FTM_ERANGE);
    assert_int_equal(ftm_mesh_builder_add_slide(b, 0, (ftm_vec3){0, 0, 2}), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_slide(b, 0, (ftm_vec3){0, 0, -1}), FTM_OK); /* same */
    assert_int_equal(ftm_mesh_builder_add_slide(b, 0, (ftm_vec3){1, 0, 1}), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_slide(b, 0, (ftm_vec3){0, 1, 0}), FTM_EINVAL);
    assert_int_equal(ftm_mesh_builder_add_slide(b, 1, (ftm_vec3){1, 0, 0}), FTM_OK);
    assert_int_equal(ftm_mesh_builder_set_fixed(b, 1, true), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_ground_spring(b, 2, 5.0), FTM_OK);
    ftm_mesh *m = NULL;
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    bd.reorder = false;
    assert_int_equal(ftm_mesh_build(b, &bd, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    ftm_vec3 n[2];
    assert_int_equal(ftm_mesh_slide_normals(m, 0, n), 2);
    assert_true(n[0].x == 0 && n[0].y == 0 && n[0].z == 1);
    assert_true(n[1].x == 1 && n[1].y == 0 && n[1].z == 0); /* (1,0,1) less its z part */
    assert_int_equal(ftm_mesh_slide_normals(m, 1, n), 0);   /* fixed */
    assert_int_equal(ftm_mesh_slide_normals(m, 3, n), FTM_ERANGE);
    assert_true(ftm_mesh_ground_stiffness(m, 2) == 5.0 && ftm_mesh_ground_stiffness(m, 0) == 0.0);
    assert_true(ftm_mesh_has_slides(m) && ftm_mesh_has_ground_springs(m));
    ftm_mesh_destroy(m);
}

/* The scene keys, on a lattice: what they build. */
static void test_scene_keys(void **state)
{
    (void)state;
    static const char text[] = "[mesh]\n"
                               "generator = lattice3d\n"
                               "nx = 4\nny = 4\nnz = 3\nspacing = 0.01\n"
                               "fixed_faces = none\n"
                               "slide_box = z : -1 -1 -0.001 1 1 0.001\n"
                               "slide_nodes = x : 47\n"
                               "slide_nodes = 0 1 1 : 44 45\n"
                               "ground_springs = 25 : 40 41\n"
                               "ground_springs = 5 : 41\n"
                               "[material]\nmass = 0.001\nstiffness = 50\ndamping = 0.3\n";
    ftm_scene *scene = NULL;
    ftm_error err;
    int rc = ftm_scene_parse(text, strlen(text), "bc.scene", &scene, &err);
    if (rc)
        fail_msg("%s", err.message);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    int32_t sliding = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++)
        sliding += ftm_mesh_slide_normals(m, i, NULL) > 0;
    assert_int_equal(sliding, 16 + 3);
    ftm_vec3 n[2];
    assert_int_equal(ftm_mesh_slide_normals(m, ftm_mesh_node_of_input(m, 3), n), 1);
    assert_true(n[0].z == 1.0);
    assert_int_equal(ftm_mesh_slide_normals(m, ftm_mesh_node_of_input(m, 47), n), 1);
    assert_true(n[0].x == 1.0);
    assert_int_equal(ftm_mesh_slide_normals(m, ftm_mesh_node_of_input(m, 44), n), 1);
    assert_true(fabs(n[0].y - sqrt(0.5)) < 1e-15 && fabs(n[0].z - sqrt(0.5)) < 1e-15);
    assert_true(ftm_mesh_ground_stiffness(m, ftm_mesh_node_of_input(m, 40)) == 25.0);
    assert_true(ftm_mesh_ground_stiffness(m, ftm_mesh_node_of_input(m, 41)) == 30.0);
    ftm_scene_destroy(scene);
}

/* slide_label and ground_label on a Gmsh file: three unit hexahedra along
 * x in physical groups 3, 3 and 8 (the last a "ligament"). */
static const char rod_msh[] =
    "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
    "$Entities\n0 0 0 2\n"
    "1 0 0 0 2 1 1 1 3 0\n2 2 0 0 3 1 1 1 8 0\n$EndEntities\n"
    "$Nodes\n1 16 1 16\n3 1 0 16\n"
    "1\n2\n3\n4\n5\n6\n7\n8\n9\n10\n11\n12\n13\n14\n15\n16\n"
    "0 0 0\n1 0 0\n2 0 0\n3 0 0\n0 1 0\n1 1 0\n2 1 0\n3 1 0\n"
    "0 0 1\n1 0 1\n2 0 1\n3 0 1\n0 1 1\n1 1 1\n2 1 1\n3 1 1\n"
    "$EndNodes\n"
    "$Elements\n2 3 1 3\n3 1 5 2\n1 1 2 6 5 9 10 14 13\n2 2 3 7 6 10 11 15 14\n"
    "3 2 5 1\n3 3 4 8 7 11 12 16 15\n$EndElements\n";

static void test_scene_label_keys(void **state)
{
    (void)state;
    char dir[] = "/tmp/ftm-test-constraints-XXXXXX", path[64], text[1024];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/rod.msh", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(rod_msh, f);
    fclose(f);
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_nodes = 0\nslide_label = z : 3\nground_label = 40 : 8\n"
             "[material]\nmass = 0.01\nstiffness = 100\n",
             path);
    ftm_scene *scene = NULL;
    ftm_error err;
    /* node 0 is fixed and in label 3: it stays fixed, the others slide */
    if (ftm_scene_parse(text, strlen(text), "rod.scene", &scene, &err))
        fail_msg("%s", err.message);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    const int32_t n0 = ftm_mesh_node_of_input(m, 0), n1 = ftm_mesh_node_of_input(m, 1);
    assert_true(ftm_mesh_fixed(m, n0) && ftm_mesh_slide_normals(m, n0, NULL) == 0);
    assert_int_equal(ftm_mesh_slide_normals(m, n1, NULL), 1);
    ftm_scene_destroy(scene);
    /* but named by index: refused, naming the line */
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_nodes = 0\nslide_nodes = z : 3 0\n"
             "[material]\nmass = 0.01\nstiffness = 100\n",
             path);
    scene = NULL;
    assert_int_equal(ftm_scene_parse(text, strlen(text), "rod.scene", &scene, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "rod.scene:4: slide_nodes: node 0 is fixed too"));
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nslide_label = z : 3\nground_label = 40 : 8\n"
             "[material]\nmass = 0.01\nstiffness = 100\n",
             path);
    if (ftm_scene_parse(text, strlen(text), "rod.scene", &scene, &err))
        fail_msg("%s", err.message);
    m = ftm_scene_mesh(scene);
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        const ftm_vec3 x = ftm_mesh_rest_position(m, i);
        assert_int_equal(ftm_mesh_slide_normals(m, i, NULL), x.x <= 2.0); /* label 3: x 0..2 */
        assert_true(ftm_mesh_ground_stiffness(m, i) == (x.x >= 2.0 ? 40.0 : 0.0)); /* 8: 2..3 */
    }
    ftm_scene_destroy(scene);
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nground_label = 40 : 5\n[material]\nmass = 0.01\nstiffness = "
             "100\n",
             path);
    scene = NULL;
    assert_int_equal(ftm_scene_parse(text, strlen(text), "rod.scene", &scene, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "rod.scene:3: ground_label: no element of the mesh has "
                                        "label 5 (0 tetrahedra, 3 hexahedra)"));
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    setenv("FTM_CACHE_DIR", "", 1);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_block_slides_on_floor),
        cmocka_unit_test(test_block_slides_on_tilted_plane),
        cmocka_unit_test(test_ground_spring_alone),
        cmocka_unit_test(test_kernels_agree),
        cmocka_unit_test(test_builder_rules),
        cmocka_unit_test(test_scene_keys),
        cmocka_unit_test(test_scene_label_keys),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
