/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Mesh loader tests: OBJ, Gmsh MSH 4.1 ASCII and TetGen .node/.ele.
 *
 * Good files must give the expected node, spring, triangle and tetrahedron
 * counts and positions. Malformed files must fail with the expected code and
 * a message "<path>:<line>: ..." (or "<path>: ..." for whole-file problems),
 * and must leave the builder exactly as it was. Files in tests/data cover the
 * common cases; the many small variants are written to a temporary directory. */
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L /* mkdtemp, strdup */
#endif

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/load.h"
#ifdef FTM_TEST_STL
#include "ftm/stl.h"
#endif

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define DATA(name) FTM_TEST_DATA "/" name

typedef int (*loader_fn)(ftm_mesh_builder *, const char *, const ftm_material_def *, ftm_error *);

/* ---- temporary files ---- */

#define MAX_TMP 256
static char tmp_dir[64];
static char *tmp_paths[MAX_TMP];
static int tmp_count;

static int group_setup(void **state)
{
    (void)state;
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/ftm_test_load_XXXXXX");
    return mkdtemp(tmp_dir) ? 0 : -1;
}

static int group_teardown(void **state)
{
    (void)state;
    for (int i = 0; i < tmp_count; i++) {
        unlink(tmp_paths[i]);
        free(tmp_paths[i]);
    }
    tmp_count = 0;
    return rmdir(tmp_dir);
}

/* Writes `len` bytes to tmp_dir/name; the returned path lives until teardown. */
static const char *tmp_write_n(const char *name, const char *content, size_t len)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", tmp_dir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(content, 1, len, f), len);
    assert_int_equal(fclose(f), 0);
    for (int i = 0; i < tmp_count; i++)
        if (strcmp(tmp_paths[i], path) == 0)
            return tmp_paths[i];
    assert_true(tmp_count < MAX_TMP);
    tmp_paths[tmp_count] = strdup(path);
    assert_non_null(tmp_paths[tmp_count]);
    return tmp_paths[tmp_count++];
}

static const char *tmp_write(const char *name, const char *content)
{
    return tmp_write_n(name, content, strlen(content));
}

/* ---- helpers ---- */

/* |actual - expected| <= tol (this cmocka has no assert_double_equal). */
#define assert_near(actual, expected, tol) check_near((actual), (expected), (tol), __LINE__)
static void check_near(double actual, double expected, double tol, int line)
{
    if (!(fabs(actual - expected) <= tol))
        fail_msg("line %d: %.17g differs from %.17g by more than %g", line, actual, expected, tol);
}

static ftm_material_def test_material(void)
{
    ftm_material_def m = ftm_default_material_def();
    m.node_mass = 0.25;
    m.node_damping = 0.5;
    m.stiffness = 10.0;
    m.axis_scale = (ftm_vec3){1.0, 1.0, 1.0};
    return m;
}

/* Loads into a builder holding `existing` nodes already and builds the mesh. */
static ftm_mesh *load_ok_after(loader_fn fn, const char *path, const ftm_material_def *mat,
                               int32_t existing)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    assert_non_null(b);
    for (int32_t i = 0; i < existing; i++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = (ftm_vec3){100.0 + i, 0.0, 0.0};
        assert_int_equal(ftm_mesh_builder_add_node(b, &nd), i);
    }
    ftm_error err = {0};
    int rc = fn(b, path, mat, &err);
    if (rc != FTM_OK)
        fail_msg("loading %s failed (%d): %s", path, rc, err.message);
    ftm_mesh *m = NULL;
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    rc = ftm_mesh_build(b, &bd, &m, &err);
    if (rc != FTM_OK)
        fail_msg("building %s failed (%d): %s", path, rc, err.message);
    ftm_mesh_builder_destroy(b);
    return m;
}

static ftm_mesh *load_ok(loader_fn fn, const char *path)
{
    ftm_material_def mat = test_material();
    return load_ok_after(fn, path, &mat, 0);
}

static void check_counts(const ftm_mesh *m, int32_t nodes, int32_t links, int32_t tris,
                         int32_t tets)
{
    assert_int_equal(ftm_mesh_node_count(m), nodes);
    assert_int_equal(ftm_mesh_link_count(m), links);
    assert_int_equal(ftm_mesh_triangle_count(m), tris);
    assert_int_equal(ftm_mesh_tetrahedron_count(m), tets);
}

/* Positions of input nodes first .. first+n-1. */
static void check_positions(const ftm_mesh *m, int32_t first, const double (*xyz)[3], int32_t n)
{
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 p = ftm_mesh_rest_position(m, ftm_mesh_node_of_input(m, first + i));
        assert_near(p.x, xyz[i][0], 0.0);
        assert_near(p.y, xyz[i][1], 0.0);
        assert_near(p.z, xyz[i][2], 0.0);
    }
}

/* Every spring must join nodes that are not coincident and have the
 * builder-computed rest length (the distance). */
static void check_links_have_length(const ftm_mesh *m)
{
    for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, l, &a, &b, &k, &len);
        ftm_vec3 pa = ftm_mesh_rest_position(m, a), pb = ftm_mesh_rest_position(m, b);
        double d = sqrt((pa.x - pb.x) * (pa.x - pb.x) + (pa.y - pb.y) * (pa.y - pb.y) +
                        (pa.z - pb.z) * (pa.z - pb.z));
        assert_true(d > 0.0);
        assert_near(len, d, 1e-12);
        assert_true(k > 0.0);
    }
}

/* Expects failure with `code`, a message starting "<msg_path>:<line>: " (or
 * "<msg_path>: " if line is 0) and containing `word`; the builder, which
 * holds one node beforehand, must be unchanged. */
static void expect_fail_in(loader_fn fn, const char *path, int code, const char *msg_path,
                           int line, const char *word)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    assert_non_null(b);
    ftm_node_def nd = ftm_default_node_def();
    assert_int_equal(ftm_mesh_builder_add_node(b, &nd), 0);
    ftm_material_def mat = test_material();
    ftm_error err = {0};
    int rc = fn(b, path, &mat, &err);
    if (rc != code || err.code != code)
        fail_msg("%s: expected code %d, got %d (err.code %d): %s", path, code, rc, err.code,
                 err.message);
    char prefix[512];
    if (line > 0)
        snprintf(prefix, sizeof prefix, "%s:%d: ", msg_path, line);
    else
        snprintf(prefix, sizeof prefix, "%s: ", msg_path);
    if (strncmp(err.message, prefix, strlen(prefix)) != 0)
        fail_msg("message '%s' does not start with '%s'", err.message, prefix);
    if (word && !strstr(err.message, word))
        fail_msg("message '%s' does not mention '%s'", err.message, word);

    /* Atomicity: still exactly the one node, no springs or elements. */
    assert_int_equal(ftm_mesh_builder_node_count(b), 1);
    ftm_mesh *m = NULL;
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    assert_int_equal(ftm_mesh_build(b, &bd, &m, &err), FTM_OK);
    check_counts(m, 1, 0, 0, 0);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void expect_fail(loader_fn fn, const char *path, int code, int line, const char *word)
{
    expect_fail_in(fn, path, code, path, line, word);
}

/* ---- good files ---- */

static const double cube_xyz[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                      {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

static void test_obj_cube(void **state)
{
    (void)state;
    ftm_mesh *m = load_ok(ftm_load_obj, DATA("cube.obj"));
    /* 6 quads -> 12 triangles; 12 cube edges + one diagonal per face. */
    check_counts(m, 8, 18, 12, 0);
    check_positions(m, 0, cube_xyz, 8);
    check_links_have_length(m);
    for (int32_t i = 0; i < 8; i++) {
        assert_near(ftm_mesh_mass(m, i), 0.25, 0.0);
        assert_near(ftm_mesh_damping(m, i), 0.5, 0.0);
        assert_false(ftm_mesh_fixed(m, i));
    }
    ftm_mesh_destroy(m);
}

static void test_obj_quad_crlf(void **state)
{
    (void)state;
    ftm_mesh *m = load_ok(ftm_load_obj, DATA("quad.obj"));
    check_counts(m, 4, 5, 2, 0);
    static const double xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    check_positions(m, 0, xyz, 4);
    ftm_mesh_destroy(m);
}

/* k = stiffness * (sx nx^2 + sy ny^2 + sz nz^2) for the unit edge direction n. */
static void test_obj_axis_scaled_stiffness(void **state)
{
    (void)state;
    ftm_material_def mat = test_material();
    mat.axis_scale = (ftm_vec3){2.0, 3.0, 1.0};
    ftm_mesh *m = load_ok_after(ftm_load_obj, DATA("quad.obj"), &mat, 0);
    int seen_x = 0, seen_y = 0, seen_diag = 0;
    for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, l, &a, &b, &k, &len);
        ftm_vec3 pa = ftm_mesh_rest_position(m, a), pb = ftm_mesh_rest_position(m, b);
        double dx = fabs(pb.x - pa.x), dy = fabs(pb.y - pa.y);
        if (dx > 0 && dy > 0) {
            assert_near(k, 25.0, 1e-12); /* 10 * (2 * 1/2 + 3 * 1/2) */
            seen_diag++;
        } else if (dx > 0) {
            assert_near(k, 20.0, 1e-12);
            seen_x++;
        } else {
            assert_near(k, 30.0, 1e-12);
            seen_y++;
        }
    }
    assert_int_equal(seen_x, 2);
    assert_int_equal(seen_y, 2);
    assert_int_equal(seen_diag, 1);
    ftm_mesh_destroy(m);
}

/* Loaded nodes follow the nodes already in the builder. */
static void test_obj_appends_to_builder(void **state)
{
    (void)state;
    ftm_material_def mat = test_material();
    ftm_mesh *m = load_ok_after(ftm_load_obj, DATA("cube.obj"), &mat, 2);
    check_counts(m, 10, 18, 12, 0);
    check_positions(m, 2, cube_xyz, 8);
    ftm_vec3 p = ftm_mesh_rest_position(m, ftm_mesh_node_of_input(m, 1));
    assert_near(p.x, 101.0, 0.0);
    ftm_mesh_destroy(m);
}

static void test_gmsh_two_tets(void **state)
{
    (void)state;
    ftm_mesh *m = load_ok(ftm_load_gmsh, DATA("tet2.msh"));
    /* 6 + 6 - 3 shared edges; the 6 boundary triangles come from the file. */
    check_counts(m, 5, 9, 6, 2);
    /* Sparse tags 10, 20, 30, 40, 55 in order of appearance. */
    static const double xyz[5][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, -1}};
    check_positions(m, 0, xyz, 5);
    check_links_have_length(m);
    ftm_mesh_destroy(m);
}

/* Triangles only: their edges become springs. Also has parametric nodes and
 * skipped element types 15, 1 and 3 that must not upset the parser. */
static void test_gmsh_triangles_only(void **state)
{
    (void)state;
    ftm_mesh *m = load_ok(ftm_load_gmsh, DATA("tri.msh"));
    check_counts(m, 4, 5, 2, 0);
    static const double xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    check_positions(m, 0, xyz, 4);
    ftm_mesh_destroy(m);
}

static void test_tetgen_two_tets(void **state)
{
    (void)state;
    ftm_mesh *m = load_ok(ftm_load_tetgen, DATA("tet.node"));
    /* No .face file: the builder takes the 6 boundary faces of the tets. */
    check_counts(m, 5, 9, 6, 2);
    static const double xyz[5][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, -1}};
    check_positions(m, 0, xyz, 5);
    check_links_have_length(m);
    ftm_mesh_destroy(m);
}

/* 0-based indices (tetgen -z) and 10-node tetrahedra: only corners are used. */
static void test_tetgen_zero_based_quadratic(void **state)
{
    (void)state;
    const char *node = tmp_write("quad10.node", "10 3 0 0\n"
                                                "0 0 0 0\n1 2 0 0\n2 0 2 0\n3 0 0 2\n"
                                                "4 1 1 0\n5 0 1 0\n6 1 0 0\n"
                                                "7 0 0 1\n8 1 0 1\n9 0 1 1\n");
    tmp_write("quad10.ele", "1 10 0\n0 0 1 2 3 4 5 6 7 8 9\n");
    ftm_mesh *m = load_ok(ftm_load_tetgen, node);
    check_counts(m, 10, 6, 4, 1);
    static const double xyz[4][3] = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 2}};
    check_positions(m, 0, xyz, 4);
    ftm_mesh_destroy(m);
}

/* The generated Gmsh cases below are variations of this file. */
#define MSH_FORMAT "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n" /* lines 1-3 */
#define MSH_NODES4                                                                                \
    "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n" /* 4-15 */
#define MSH_ELEMS(line19) "$Elements\n1 1 1 1\n3 1 4 1\n" line19 "\n$EndElements\n" /* 16-20 */

static void test_gmsh_generated_base(void **state)
{
    (void)state;
    const char *path = tmp_write("base.msh", MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 2 3 4"));
    ftm_mesh *m = load_ok(ftm_load_gmsh, path);
    check_counts(m, 4, 6, 4, 1);
    ftm_mesh_destroy(m);
}

static void test_load_mesh_dispatch(void **state)
{
    (void)state;
    ftm_mesh *m = load_ok(ftm_load_mesh, DATA("cube.obj"));
    check_counts(m, 8, 18, 12, 0);
    ftm_mesh_destroy(m);
    m = load_ok(ftm_load_mesh, DATA("tet2.msh"));
    check_counts(m, 5, 9, 6, 2);
    ftm_mesh_destroy(m);
    m = load_ok(ftm_load_mesh, DATA("tet.node"));
    check_counts(m, 5, 9, 6, 2);
    ftm_mesh_destroy(m);

    /* Extensions are case-insensitive (the .ele keeps the .node's case). */
    m = load_ok(ftm_load_mesh, tmp_write("QUAD.OBJ", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
    check_counts(m, 3, 3, 1, 0);
    ftm_mesh_destroy(m);
    tmp_write("UP.ELE", "1 4 0\n1 1 2 3 4\n");
    m = load_ok(ftm_load_mesh,
                tmp_write("UP.Node", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"));
    check_counts(m, 4, 6, 4, 1);
    ftm_mesh_destroy(m);

    expect_fail(ftm_load_mesh, tmp_write("mesh.ply", "ply\n"), FTM_EINVAL, 0, ".ply");
    /* STL is ftm_stl's, beside the core: the refusal says where */
    expect_fail(ftm_load_mesh, tmp_write("mesh.stl", "solid x\n"), FTM_EINVAL, 0, "ftm_stl");
    expect_fail(ftm_load_mesh, tmp_write("mesh", "v 0 0 0\n"), FTM_EINVAL, 0, "extension");
    expect_fail(ftm_load_mesh, "/nonexistent.dir/mesh", FTM_EINVAL, 0, "extension");
}

/* ---- malformed files ---- */

static void test_missing_files(void **state)
{
    (void)state;
    expect_fail(ftm_load_obj, DATA("no_such_file.obj"), FTM_EIO, 0, "no_such_file.obj");
    expect_fail(ftm_load_gmsh, DATA("no_such_file.msh"), FTM_EIO, 0, "no_such_file.msh");
    expect_fail(ftm_load_tetgen, DATA("no_such_file.node"), FTM_EIO, 0, "no_such_file.node");
    expect_fail(ftm_load_mesh, DATA("no_such_file.obj"), FTM_EIO, 0, NULL);
    /* .node present, .ele missing: the message names the .ele file. */
    char ele[256];
    const char *node = tmp_write("lonely.node", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n");
    snprintf(ele, sizeof ele, "%s/lonely.ele", tmp_dir);
    expect_fail_in(ftm_load_tetgen, node, FTM_EIO, ele, 0, "lonely.ele");
}

static void test_bad_data_files(void **state)
{
    (void)state;
    expect_fail(ftm_load_obj, DATA("bad_index.obj"), FTM_ERANGE, 10, "index 7 out of range");
    expect_fail(ftm_load_obj, DATA("bad_nan.obj"), FTM_EPARSE, 3, "'nan'");
    expect_fail(ftm_load_obj, DATA("bad_degenerate.obj"), FTM_EPARSE, 6, "repeats vertex 4");
    expect_fail(ftm_load_gmsh, DATA("bad_binary.msh"), FTM_EPARSE, 2, "binary");
    expect_fail(ftm_load_gmsh, DATA("bad_tag.msh"), FTM_EPARSE, 9, "node tag 2 repeated");
    expect_fail(ftm_load_tetgen, DATA("bad_count.node"), FTM_EPARSE, 6, "after 4 of 5");
    expect_fail_in(ftm_load_tetgen, DATA("bad_range.node"), FTM_ERANGE, DATA("bad_range.ele"), 3,
                   "node index 4 out of range");
}

typedef struct bad_case {
    const char *name;
    const char *content;
    int code;
    int line; /* 0: a whole-file error */
    const char *word;
} bad_case;

static void run_bad_cases(loader_fn fn, const bad_case *cases, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        const bad_case *c = &cases[i];
        expect_fail(fn, tmp_write(c->name, c->content), c->code, c->line, c->word);
    }
}

static void test_bad_obj(void **state)
{
    (void)state;
#define TRI3 "v 0 0 0\nv 1 0 0\nv 0 1 0\n" /* lines 1-3 */
    static const bad_case cases[] = {
        {"empty.obj", "", FTM_EPARSE, 0, "empty"},
        {"novertex.obj", "# only a comment\n\n", FTM_EPARSE, 0, "no vertices"},
        {"noface.obj", TRI3, FTM_EPARSE, 0, "no faces"},
        {"inf.obj", TRI3 "v 0 inf 0\n", FTM_EPARSE, 4, "'inf'"},
        {"overflow.obj", "v 1e999 0 0\n", FTM_EPARSE, 1, "'1e999'"},
        {"junk.obj", "v 0 0 0\n\n\nv 1 abc 0\n", FTM_EPARSE, 4, "'abc'"},
        {"shortv.obj", "v 1 2\n", FTM_EPARSE, 1, "x y z"},
        {"longv.obj", "v 1 2 3 4 5 6 7 8\n", FTM_EPARSE, 1, "too many"},
        {"zero.obj", TRI3 "f 0 1 2\n", FTM_ERANGE, 4, "index 0"},
        {"range.obj", TRI3 "f 1 2 4\n", FTM_ERANGE, 4, "index 4 out of range"},
        {"negrange.obj", TRI3 "f -1 -2 -4\n", FTM_ERANGE, 4, "index -4"},
        {"forward.obj", "f 1 2 3\n" TRI3, FTM_ERANGE, 1, "index 1 out of range"},
        {"shortf.obj", TRI3 "f 1 2\n", FTM_EPARSE, 4, "at least 3"},
        {"degenerate.obj", TRI3 "f 1 2 -2\n", FTM_EPARSE, 4, "repeats vertex 2"},
        {"coincident.obj", TRI3 "v 1 0 0\nf 1 2 4\n", FTM_EPARSE, 5, "coincident"},
        {"slash1.obj", TRI3 "f 1/ 2 3\n", FTM_EPARSE, 4, "'1/'"},
        {"slash2.obj", TRI3 "f 1/2/3/4 2 3\n", FTM_EPARSE, 4, "'1/2/3/4'"},
        {"slash3.obj", TRI3 "f 1// 2 3\n", FTM_EPARSE, 4, "'1//'"},
        {"slash4.obj", TRI3 "f /1 2 3\n", FTM_EPARSE, 4, "'/1'"},
        {"letters.obj", TRI3 "f a b c\n", FTM_EPARSE, 4, "'a'"},
        {"texjunk.obj", TRI3 "f 1/x 2 3\n", FTM_EPARSE, 4, "'1/x'"},
        {"hugeindex.obj", TRI3 "f 1 2 99999999999999999999\n", FTM_EPARSE, 4, "bad face vertex"},
        {"laterbad.obj", TRI3 "f 1 2 3\n# fine so far\nf 3 2 9\n", FTM_ERANGE, 6, "index 9"},
    };
#undef TRI3
    run_bad_cases(ftm_load_obj, cases, sizeof cases / sizeof cases[0]);
}

static void test_bad_gmsh(void **state)
{
    (void)state;
    static const bad_case cases[] = {
        {"empty.msh", "", FTM_EPARSE, 0, "empty"},
        {"blank.msh", "\n  \n\n", FTM_EPARSE, 0, "empty"},
        {"notmsh.msh", "hello world\n", FTM_EPARSE, 1, "$MeshFormat"},
        {"v22.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", FTM_EPARSE, 2, "'2.2'"},
        {"fmtend.msh", "$MeshFormat\n4.1 0 8\n$Nodes\n", FTM_EPARSE, 3, "$EndMeshFormat"},
        {"fmtshort.msh", "$MeshFormat\n4.1 0\n$EndMeshFormat\n", FTM_EPARSE, 2, "needs 3"},
        {"noelems.msh", MSH_FORMAT MSH_NODES4, FTM_EPARSE, 0, "no $Elements"},
        {"nonodes.msh", MSH_FORMAT "$Elements\n0 0 0 0\n$EndElements\n", FTM_EPARSE, 4,
         "before $Nodes"},
        {"onlyformat.msh", MSH_FORMAT, FTM_EPARSE, 0, "no $Nodes"},
        {"twonodes.msh", MSH_FORMAT MSH_NODES4 MSH_NODES4, FTM_EPARSE, 16, "second $Nodes"},
        {"stray.msh", MSH_FORMAT "junk\n", FTM_EPARSE, 4, "'junk'"},
        {"strayend.msh", MSH_FORMAT "$EndNodes\n", FTM_EPARSE, 4, "unexpected"},
        {"unclosed.msh", MSH_FORMAT "$PhysicalNames\n1\n3 1 \"body\"\n", FTM_EPARSE, 6,
         "file ends inside $PhysicalNames (expected $EndPhysicalNames)"},
        {"unclosed2.msh", MSH_FORMAT "$NodeData\n1\n", FTM_EPARSE, 4, "$EndNodeData"},
        {"pnquote.msh", MSH_FORMAT "$PhysicalNames\n1\n3 1 body\n$EndPhysicalNames\n", FTM_EPARSE,
         6, "physical name not in double quotes"},
        {"pnshort.msh", MSH_FORMAT "$PhysicalNames\n2\n3 1 \"a b\"\n$EndPhysicalNames\n",
         FTM_EPARSE, 7, "expected dimension, tag and \"name\", found '$EndPhysicalNames'"},
        {"pndim.msh", MSH_FORMAT "$PhysicalNames\n1\n4 1 \"a\"\n$EndPhysicalNames\n", FTM_EPARSE,
         6, "physical dimension 4 out of range"},
        {"pntag.msh", MSH_FORMAT "$PhysicalNames\n1\n3 0 \"a\"\n$EndPhysicalNames\n", FTM_EPARSE,
         6, "physical tag 0 out of range"},
        {"pnnoname.msh", MSH_FORMAT "$PhysicalNames\n1\n3 1\n$EndPhysicalNames\n", FTM_EPARSE, 6,
         "needs dimension, tag and \"name\""},
        {"pntwice.msh",
         MSH_FORMAT "$PhysicalNames\n0\n$EndPhysicalNames\n$PhysicalNames\n0\n$EndPhysicalNames\n",
         FTM_EPARSE, 7, "second $PhysicalNames"},
        {"truncnodes.msh", MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n", FTM_EPARSE, 8,
         "ends inside $Nodes"},
        {"nodecount.msh",
         MSH_FORMAT "$Nodes\n1 5 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n",
         FTM_EPARSE, 15, "announces 5"},
        {"coordshort.msh",
         MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n$EndNodes\n",
         FTM_EPARSE, 14, "node coordinates"},
        {"blocktoobig.msh", MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 999999999999\n1\n", FTM_EPARSE, 6,
         "exceed the 4 nodes"},
        {"hugenodes.msh", MSH_FORMAT "$Nodes\n1 999999999999 1 4\n3 1 0 1\n", FTM_ERANGE, 5,
         "999999999999"},
        {"manyblocks.msh", MSH_FORMAT "$Nodes\n999999999999 0 0 0\n$EndNodes\n", FTM_EPARSE, 6,
         "block header"},
        {"tagline.msh", MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1 2\n", FTM_EPARSE, 7,
         "node tag line"},
        {"tagzero.msh", MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n0\n", FTM_EPARSE, 7, "node tag 0"},
        {"reptag3.msh",
         MSH_FORMAT "$Nodes\n1 4 1 7\n3 1 0 4\n5\n7\n5\n5\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n",
         FTM_EPARSE, 9, "node tag 5 repeated (first on line 7)"},
        {"badcoord.msh",
         MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 x 0\n0 0 1\n$EndNodes\n",
         FTM_EPARSE, 13, "'x'"},
        {"nancoord.msh",
         MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\nnan 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                    "$EndNodes\n",
         FTM_EPARSE, 11, "'nan'"},
        {"bigcoord.msh",
         MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1e999 0 0\n0 1 0\n0 0 1\n"
                    "$EndNodes\n",
         FTM_EPARSE, 12, "'1e999'"},
        {"parametric.msh",
         MSH_FORMAT "$Nodes\n1 4 1 4\n2 1 1 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n",
         FTM_EPARSE, 11, "needs 5"},
        {"unknowntag.msh", MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 2 3 9"), FTM_ERANGE, 19,
         "unknown node tag 9"},
        {"elemtag0.msh", MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 2 3 0"), FTM_EPARSE, 19,
         "node tag 0"},
        {"degenerate.msh", MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 2 3 3"), FTM_EPARSE, 19,
         "node tag 3 repeated"},
        {"coincident.msh",
         MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n1 0 0\n$EndNodes\n"
             MSH_ELEMS("1 1 2 3 4"),
         FTM_EPARSE, 19, "coincide"},
        {"elemshort.msh", MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 2 3"), FTM_EPARSE, 19, "needs"},
        /* The same tetrahedron twice, corners in another order. */
        {"reptet.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 2 1 8\n3 1 4 2\n5 1 2 3 4\n8 4 2 1 3\n"
                               "$EndElements\n",
         FTM_EPARSE, 20, "element 8 has the same four nodes as element 5 (line 19)"},
        /* In another block, after triangles; the first repeat is reported. */
        {"reptet3.msh",
         MSH_FORMAT "$Nodes\n1 5 1 5\n3 1 0 5\n1\n2\n3\n4\n5\n"
                    "0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 -1\n$EndNodes\n"
                    "$Elements\n3 6 1 6\n3 1 4 2\n1 1 3 2 5\n2 1 2 3 4\n"
                    "2 1 2 1\n3 1 2 3\n3 2 4 3\n4 2 3 1 4\n5 3 1 5 2\n6 1 2 3 4\n"
                    "$EndElements\n",
         FTM_EPARSE, 26, "element 4 has the same four nodes as element 2 (line 22)"},
        {"elemjunk.msh", MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 2 x 4"), FTM_EPARSE, 19, "'x'"},
        {"type99.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 99 1\n1 1 2 3 4\n$EndElements\n",
         FTM_EPARSE, 18, "element type 99"},
        {"skipjunk.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n2 2 1 2\n1 1 1 1\n1 1 q\n3 1 4 1\n2 1 2 3 4\n"
                               "$EndElements\n",
         FTM_EPARSE, 19, "'q'"},
        {"skipshort.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n2 2 1 2\n2 1 3 1\n1 1 2 3\n3 1 4 1\n2 1 2 3 4\n"
                               "$EndElements\n",
         FTM_EPARSE, 19, "type 3"},
        {"hugeelems.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 999999999999 1 1\n3 1 4 999999999999\n1 1 2 3 4\n"
                               "$EndElements\n",
         FTM_EPARSE, 20, "element line"},
        {"elemblockbig.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 4 5\n1 1 2 3 4\n$EndElements\n",
         FTM_EPARSE, 18, "exceed the 1 elements"},
        {"elemcount.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 2 1 2\n3 1 4 1\n1 1 2 3 4\n$EndElements\n",
         FTM_EPARSE, 20, "announces 2"},
        {"elemblocks.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n2 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n",
         FTM_EPARSE, 20, "block header"},
        {"noendelems.msh", MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n",
         FTM_EPARSE, 19, "ends inside $Elements"},
        {"noshapes.msh", MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n0 1 15 1\n1 1\n$EndElements\n",
         FTM_EPARSE, 0, "no 4-node tetrahedra"},
        {"tet10.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 11 1\n1 1 2 3 4 1 2 3 4 1 2\n"
                               "$EndElements\n",
         FTM_EPARSE, 18, "type 11 (10-node tetrahedron) not supported: a second- or higher-order"},
    };
    run_bad_cases(ftm_load_gmsh, cases, sizeof cases / sizeof cases[0]);

    /* Binary MSH holds NUL bytes; the message must say what the file is. */
    static const char nul[] = "$MeshFormat\n4.1 1 8\n\1\0\0\0\n$EndMeshFormat\n";
    expect_fail(ftm_load_gmsh, tmp_write_n("nul.msh", nul, sizeof nul - 1), FTM_EPARSE, 0,
                "binary");

    /* A line with more tokens than any element type has. */
    char big[4096] = MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 4 1\n1";
    for (int i = 0; i < 200; i++)
        strcat(big, " 1");
    strcat(big, "\n$EndElements\n");
    expect_fail(ftm_load_gmsh, tmp_write("longline.msh", big), FTM_EPARSE, 19, "over 128");
}

typedef struct bad_tetgen {
    const char *stem;
    const char *node;
    const char *ele; /* NULL: the good default */
    int code;
    bool in_ele; /* the message names the .ele file */
    int line;
    const char *word;
} bad_tetgen;

static void test_bad_tetgen(void **state)
{
    (void)state;
#define NODE4 "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n" /* lines 1-5 */
    static const bad_tetgen cases[] = {
        {"empty", "", NULL, FTM_EPARSE, false, 0, "empty"},
        {"comments", "# nothing here\n\n", NULL, FTM_EPARSE, false, 0, "no header"},
        {"hdrjunk", "four 3 0 0\n", NULL, FTM_EPARSE, false, 1, "point count 'four'"},
        {"hdrlong", "4 3 0 0 0\n", NULL, FTM_EPARSE, false, 1, "more than 4"},
        {"zero", "0 3 0 0\n", NULL, FTM_EPARSE, false, 1, "point count 0"},
        {"negative", "-4 3 0 0\n", NULL, FTM_EPARSE, false, 1, "point count -4"},
        {"huge", "99999999999 3 0 0\n", NULL, FTM_ERANGE, false, 1, "99999999999"},
        {"big", "2000000000 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", NULL, FTM_EPARSE,
         false, 5, "after 4 of 2000000000"},
        {"dim2", "4 2 0 0\n", NULL, FTM_EPARSE, false, 1, "dimension 2"},
        {"marker2", "4 3 0 2\n", NULL, FTM_EPARSE, false, 1, "marker flag 2"},
        {"attrneg", "4 3 -1 0\n", NULL, FTM_EPARSE, false, 1, "attribute count -1"},
        {"first2", "4 3 0 0\n2 0 0 0\n", NULL, FTM_EPARSE, false, 2, "first point index 2"},
        {"sequence", "4 3 0 0\n1 0 0 0\n2 1 0 0\n2 0 1 0\n4 0 0 1\n", NULL, FTM_EPARSE, false, 4,
         "index 2 out of sequence"},
        {"extra", "3 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", NULL, FTM_EPARSE, false, 5,
         "data after the 3 points"},
        {"fields", "4 3 0 0\n1 0 0 0\n2 1 0\n", NULL, FTM_EPARSE, false, 3, "needs 4"},
        {"attrmissing", "4 3 1 0\n1 0 0 0\n", NULL, FTM_EPARSE, false, 2, "needs 5"},
        {"attrjunk", "4 3 1 0\n1 0 0 0 q\n", NULL, FTM_EPARSE, false, 2, "'q'"},
        {"markerjunk", "4 3 0 1\n1 0 0 0 0.5\n", NULL, FTM_EPARSE, false, 2, "'0.5'"},
        {"inf", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 -inf 0\n", NULL, FTM_EPARSE, false, 4, "'-inf'"},
        {"nan", "4 3 0 0\n1 NaN 0 0\n", NULL, FTM_EPARSE, false, 2, "'NaN'"},
        {"bigcoord", "4 3 0 0\n1 0 0 0\n2 1e999 0 0\n", NULL, FTM_EPARSE, false, 3, "'1e999'"},
        {"eempty", NODE4, "", FTM_EPARSE, true, 0, "empty"},
        {"ezero", NODE4, "0 4 0\n", FTM_EPARSE, true, 1, "tetrahedron count 0"},
        {"ehuge", NODE4, "99999999999 4 0\n", FTM_ERANGE, true, 1, "99999999999"},
        {"ecorners", NODE4, "1 3 0\n1 1 2 3\n", FTM_EPARSE, true, 1, "3 nodes per tetrahedron"},
        {"ebase", NODE4, "# 0-based by mistake\n1 4 0\n1 0 1 2 3\n", FTM_ERANGE, true, 3,
         "node index 0 out of range"},
        {"edegenerate", NODE4, "1 4 0\n1 1 2 3 3\n", FTM_EPARSE, true, 2, "node 3 repeated"},
        {"erepeat", NODE4, "2 4 0\n1 1 2 3 4\n# again\n2 3 1 2 4\n", FTM_EPARSE, true, 4,
         "tetrahedron 2 has the same four nodes as tetrahedron 1 (line 2)"},
        {"erepeat10", NODE4, "2 10 0\n7 1 2 3 4 1 2 3 4 1 2\n9 2 3 1 4 4 3 2 1 1 1\n",
         FTM_EPARSE, true, 3, "tetrahedron 9 has the same four nodes as tetrahedron 7 (line 2)"},
        {"eregion", NODE4, "1 4 1\n1 1 2 3 4 2.5\n", FTM_EPARSE, true, 2,
         "tetrahedron 1 has region attribute 2.5, not a label"},
        {"eregion0", "5 3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 0 0 -1\n",
         "2 4 1\n1 1 2 3 4 3\n2 1 3 2 5 0\n", FTM_EPARSE, true, 3,
         "tetrahedron 2 has region attribute 0 (no label) while 1 others have one"},
        {"einverted", NODE4, "1 4 0\n1 1 3 2 4\n", FTM_EPARSE, true, 2, "tetrahedron 1 is inverted"},
        {"ecoincide", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 1 0 0\n", "1 4 0\n1 1 2 3 4\n",
         FTM_EPARSE, true, 2, "nodes 2 and 4 coincide"},
        {"etrunc", NODE4, "2 4 0\n1 1 2 3 4\n", FTM_EPARSE, true, 2, "after 1 of 2"},
        {"eextra", NODE4, "1 4 0\n1 1 2 3 4\n2 1 2 3 4\n", FTM_EPARSE, true, 3, "data after"},
        {"efields", NODE4, "1 4 1\n1 1 2 3 4\n", FTM_EPARSE, true, 2, "needs 6"},
        {"eattr", NODE4, "1 4 1\n1 1 2 3 4 zz\n", FTM_EPARSE, true, 2, "'zz'"},
        {"ejunk", NODE4, "1 4 0\n1 1 two 3 4\n", FTM_EPARSE, true, 2, "'two'"},
        {"emid", NODE4, "1 10 0\n1 1 2 3 4 1 2 3 4 1 5\n", FTM_ERANGE, true, 2,
         "node index 5 out of range"},
    };
#undef NODE4
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const bad_tetgen *c = &cases[i];
        char name[64];
        snprintf(name, sizeof name, "%s.node", c->stem);
        const char *node = tmp_write(name, c->node);
        snprintf(name, sizeof name, "%s.ele", c->stem);
        const char *ele = tmp_write(name, c->ele ? c->ele : "1 4 0\n1 1 2 3 4\n");
        expect_fail_in(ftm_load_tetgen, node, c->code, c->in_ele ? ele : node, c->line, c->word);
    }
}

/* ---- hexahedra and element labels ---- */

/* Two unit cubes side by side along x (nodes 1..12: x = 0, 1, 2 at y, z in
 * {0, 1}), in two volumes with physical groups 5 ("grey") and 9 ("white"). */
#define MSH_HEX_ENTITIES                                                                          \
    "$PhysicalNames\n2\n3 5 \"grey\"\n3 9 \"white\"\n$EndPhysicalNames\n"                         \
    "$Entities\n1 0 0 2\n1 0 0 0 0\n"                                                             \
    "1 0 0 0 1 1 1 1 5 0\n2 1 0 0 2 1 1 1 9 0\n$EndEntities\n"
#define MSH_HEX_NODES                                                                             \
    "$Nodes\n1 12 1 12\n3 1 0 12\n1\n2\n3\n4\n5\n6\n7\n8\n9\n10\n11\n12\n"                        \
    "0 0 0\n1 0 0\n2 0 0\n0 1 0\n1 1 0\n2 1 0\n0 0 1\n1 0 1\n2 0 1\n0 1 1\n1 1 1\n2 1 1\n"      \
    "$EndNodes\n"
#define MSH_HEX_ELEMS(first, second)                                                              \
    "$Elements\n2 2 1 2\n3 1 5 1\n" first "\n3 2 5 1\n" second "\n$EndElements\n"

/* Signed volume enclosed by the surface triangles (divergence theorem):
 * positive when they face outward. */
static double enclosed_volume(const ftm_mesh *m)
{
    const int32_t *t = ftm_mesh_triangles(m);
    double v = 0;
    for (int32_t i = 0; i < ftm_mesh_triangle_count(m); i++) {
        ftm_vec3 a = ftm_mesh_rest_position(m, t[3 * i]), b = ftm_mesh_rest_position(m, t[3 * i + 1]),
                 c = ftm_mesh_rest_position(m, t[3 * i + 2]);
        v += (a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x) +
              a.z * (b.x * c.y - b.y * c.x)) / 6;
    }
    return v;
}

static void test_gmsh_hexahedra_labels(void **state)
{
    (void)state;
    const char *path = tmp_write("hex2.msh", MSH_FORMAT MSH_HEX_ENTITIES MSH_HEX_NODES
                                 MSH_HEX_ELEMS("1 1 2 5 4 7 8 11 10", "2 2 3 6 5 8 9 12 11"));
    ftm_mesh *m = load_ok(ftm_load_gmsh, path);
    /* springs: 20 edges and 22 face diagonals (the shared face's counted
     * once); surface: the 10 outer faces, two triangles each */
    check_counts(m, 12, 42, 20, 0);
    assert_int_equal(ftm_mesh_hexahedron_count(m), 2);
    assert_true(ftm_mesh_has_labels(m));
    assert_int_equal(ftm_mesh_hexahedron_label(m, 0), 5);
    assert_int_equal(ftm_mesh_hexahedron_label(m, 1), 9);
    /* the volume groups' $PhysicalNames name the labels (the client's legend) */
    assert_string_equal(ftm_mesh_label_name(m, 5), "grey");
    assert_string_equal(ftm_mesh_label_name(m, 9), "white");
    assert_null(ftm_mesh_label_name(m, 7));
    ftm_material_def mat = ftm_default_material_def(); /* a copy keeps them (a clone) */
    ftm_mesh *c = NULL;
    assert_int_equal(ftm_mesh_with_material(m, &mat, &mat, &c, NULL), FTM_OK);
    assert_string_equal(ftm_mesh_label_name(c, 9), "white");
    ftm_mesh_destroy(c);
    assert_near(enclosed_volume(m), 2.0, 1e-12);
    /* the hexahedra are those of the file, renumbered */
    const int32_t *h = ftm_mesh_hexahedra(m);
    ftm_vec3 p = ftm_mesh_rest_position(m, h[8 + 6]); /* element 2's corner 7: node 12 */
    assert_true(p.x == 2 && p.y == 1 && p.z == 1);
    ftm_mesh_destroy(m);

    /* without $Entities the elements carry no label */
    path = tmp_write("hex2plain.msh", MSH_FORMAT MSH_HEX_NODES
                     MSH_HEX_ELEMS("1 1 2 5 4 7 8 11 10", "2 2 3 6 5 8 9 12 11"));
    m = load_ok(ftm_load_gmsh, path);
    assert_false(ftm_mesh_has_labels(m));
    assert_int_equal(ftm_mesh_hexahedron_label(m, 1), 0);
    ftm_mesh_destroy(m);

    /* tet2.msh puts its tetrahedra in physical group 1 */
    m = load_ok(ftm_load_gmsh, DATA("tet2.msh"));
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 0), 1);
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 1), 1);
    ftm_mesh_destroy(m);
    /* TetGen: the first tetrahedron attribute (the region, tetgen -A) */
    m = load_ok(ftm_load_tetgen, DATA("tet.node"));
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 0), 7);
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 1), 7);
    ftm_mesh_destroy(m);
}

static void test_bad_elements(void **state)
{
    (void)state;
    static const bad_case cases[] = {
        /* line 19 is the element; 18 its block header */
        {"prism.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 6 1\n1 1 2 3 4 1 2\n$EndElements\n",
         FTM_EPARSE, 18, "type 6 (6-node prism) not supported"},
        {"pyramid.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 7 1\n1 1 2 3 4 1\n$EndElements\n",
         FTM_EPARSE, 18, "type 7 (5-node pyramid) not supported"},
        {"hex20.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n3 1 17 1\n1 1 2 3 4 1 2 3 4 1 2 3 4 1 2 3 4 "
                               "1 2 3 4\n$EndElements\n",
         FTM_EPARSE, 18, "type 17 (20-node hexahedron) not supported: a second- or higher-order"},
        {"inverted.msh", MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 3 2 4"), FTM_EPARSE, 19,
         "element 1 (4-node tetrahedron) is inverted"},
        {"flat.msh",
         MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n1 1 1e-14\n"
                    "$EndNodes\n" MSH_ELEMS("1 1 2 3 4"),
         FTM_EPARSE, 19, "element 1 (4-node tetrahedron) is degenerate: flat"},
        {"tetdim2.msh",
         MSH_FORMAT MSH_NODES4 "$Elements\n1 1 1 1\n2 1 4 1\n1 1 2 3 4\n$EndElements\n",
         FTM_EPARSE, 18, "in an entity of dimension 2"},
        {"hexinv.msh", MSH_FORMAT MSH_HEX_NODES MSH_HEX_ELEMS("1 1 4 5 2 7 10 11 8", "2 2 3 6 5 8 9 12 11"),
         FTM_EPARSE, 35, "element 1 (8-node hexahedron) is inverted"},
        {"hextwist.msh", MSH_FORMAT MSH_HEX_NODES MSH_HEX_ELEMS("1 1 2 5 4 7 8 10 11", "2 2 3 6 5 8 9 12 11"),
         FTM_EPARSE, 35, "element 1 (8-node hexahedron) is degenerate: flat or twisted"},
        {"hexrep.msh", MSH_FORMAT MSH_HEX_NODES MSH_HEX_ELEMS("1 1 2 5 4 7 8 11 10", "2 2 5 4 1 8 11 10 7"),
         FTM_EPARSE, 37, "element 2 has the same eight nodes as element 1 (line 35)"},
        {"mixed.msh",
         MSH_FORMAT MSH_HEX_NODES "$Elements\n2 2 1 2\n3 1 5 1\n1 1 2 5 4 7 8 11 10\n"
                                  "3 2 4 1\n2 2 3 6 9\n$EndElements\n",
         FTM_EPARSE, 35, "one kind of volume element per mesh"},
        {"unlabelled.msh",
         MSH_FORMAT "$Entities\n0 0 0 2\n1 0 0 0 1 1 1 1 5 0\n2 0 0 0 1 1 1 0 0\n$EndEntities\n"
             MSH_HEX_NODES MSH_HEX_ELEMS("1 1 2 5 4 7 8 11 10", "2 2 3 6 5 8 9 12 11"),
         FTM_EPARSE, 42, "element 2 belongs to no physical group while 1 others have one"},
        {"twogroups.msh",
         MSH_FORMAT "$Entities\n0 0 0 1\n1 0 0 0 1 1 1 2 5 6 0\n$EndEntities\n" MSH_NODES4
             MSH_ELEMS("1 1 2 3 4"),
         FTM_EPARSE, 22, "volume entity 1 is in 2 physical groups (5, 6; line 6)"},
        {"group0.msh",
         MSH_FORMAT "$Entities\n0 0 0 1\n1 0 0 0 1 1 1 1 0 0\n$EndEntities\n" MSH_NODES4
             MSH_ELEMS("1 1 2 3 4"),
         FTM_EPARSE, 22, "physical tag 0 (line 6): a label must be >= 1"},
        {"noentity.msh",
         MSH_FORMAT "$Entities\n0 0 0 1\n7 0 0 0 1 1 1 1 3 0\n$EndEntities\n" MSH_NODES4
             MSH_ELEMS("1 1 2 3 4"),
         FTM_EPARSE, 22, "volume entity 1, which $Entities does not list"},
        {"entcount.msh",
         MSH_FORMAT "$Entities\n0 0 0 1\n1 0 0 0 1 1 1 3 5 0\n$EndEntities\n" MSH_NODES4
             MSH_ELEMS("1 1 2 3 4"),
         FTM_EPARSE, 6, "announces 3 physical tags"},
        {"entafter.msh",
         MSH_FORMAT MSH_NODES4 MSH_ELEMS("1 1 2 3 4") "$Entities\n0 0 0 0\n$EndEntities\n",
         FTM_EPARSE, 21, "$Entities after $Elements"},
    };
    run_bad_cases(ftm_load_gmsh, cases, sizeof cases / sizeof cases[0]);
}

/* ---- STL (ftm_stl, through Assimp) ---- */

#ifdef FTM_TEST_STL

/* A binary STL of `n` facets, 9 coordinates each. */
static const char *write_binary_stl(const char *name, const float *xyz, uint32_t n)
{
    size_t size = 84 + 50 * (size_t)n;
    char *b = calloc(size, 1);
    assert_non_null(b);
    memcpy(b, "solid but binary: the size decides", 34); /* some exporters write this */
    memcpy(b + 80, &n, 4);
    for (uint32_t f = 0; f < n; f++)
        memcpy(b + 84 + 50 * (size_t)f + 12, xyz + 9 * (size_t)f, 36);
    const char *path = tmp_write_n(name, b, size);
    free(b);
    return path;
}

/* The unit tetrahedron's 4 facets, outward. */
static const float tet_facets[36] = {0, 0, 0, 0, 1, 0, 1, 0, 0,  0, 0, 0, 1, 0, 0, 0, 0, 1,
                                     0, 0, 0, 0, 0, 1, 0, 1, 0,  1, 0, 0, 0, 1, 0, 0, 0, 1};

/* An ASCII STL from facets of 9 coordinates (7 lines a facet, from line 2). */
static const char *write_ascii_stl(const char *name, const float *xyz, int n)
{
    char *t = malloc(200 + 300 * (size_t)n);
    assert_non_null(t);
    size_t len = (size_t)sprintf(t, "solid test\n");
    for (int f = 0; f < n; f++) {
        const float *p = xyz + 9 * f;
        len += (size_t)sprintf(t + len,
                               "  facet normal 0 0 0\n    outer loop\n      vertex %g %g %g\n"
                               "      vertex %g %g %g\n      vertex %g %g %g\n    endloop\n"
                               "  endfacet\n",
                               p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]);
    }
    len += (size_t)sprintf(t + len, "endsolid test\n");
    const char *path = tmp_write_n(name, t, len);
    free(t);
    return path;
}

static void test_stl(void **state)
{
    (void)state;
    /* binary, whose header starts with "solid": a surface like an OBJ */
    ftm_mesh *m = load_ok(ftm_load_stl, write_binary_stl("tet.stl", tet_facets, 4));
    check_counts(m, 4, 6, 4, 0);
    static const double xyz[4][3] = {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}};
    check_positions(m, 0, xyz, 4); /* in order of first appearance */
    ftm_mesh_destroy(m);
    /* ASCII */
    m = load_ok(ftm_load_stl, write_ascii_stl("TET.STL", tet_facets, 4));
    check_counts(m, 4, 6, 4, 0);
    ftm_mesh_destroy(m);

    /* as a closed surface (for a volume) */
    ftm_surface *s = NULL;
    ftm_error err;
    char path[300];
    snprintf(path, sizeof path, "%s/tet.stl", tmp_dir);
    assert_int_equal(ftm_surface_load(path, true, &s, &err), FTM_OK);
    assert_int_equal(s->vertex_count, 4);
    assert_int_equal(s->triangle_count, 4);
    ftm_surface_destroy(s);
    /* all facets inward: turned outward */
    float inward[36];
    for (int f = 0; f < 4; f++)
        for (int c = 0; c < 3; c++) /* corners 2 and 3 swapped */
            memcpy(inward + 9 * f + 3 * c, tet_facets + 9 * f + 3 * (c == 0 ? 0 : 3 - c),
                   3 * sizeof(float));
    const char *in = write_binary_stl("inward.stl", inward, 4);
    assert_int_equal(ftm_surface_load(in, true, &s, &err), FTM_OK);
    const int32_t *t = s->triangles;
    assert_true(t[0] == 0 && t[1] == 2 && t[2] == 1); /* facet 1 as tet_facets has it */
    ftm_surface_destroy(s);
}

static void expect_surface_fail(const char *path, bool closed, int code, const char *part)
{
    ftm_surface *s = (ftm_surface *)&s;
    ftm_error err = {0};
    int rc = ftm_surface_load(path, closed, &s, &err);
    if (rc != code)
        fail_msg("%s: rc %d, expected %d (%s)", path, rc, code, err.message);
    assert_null(s);
    if (!strstr(err.message, path) || !strstr(err.message, part))
        fail_msg("message '%s' lacks the path or '%s'", err.message, part);
}

static void test_bad_stl(void **state)
{
    (void)state;
    /* open: three facets of the tetrahedron; a volume needs it closed */
    const char *open = write_ascii_stl("open.stl", tet_facets, 3);
    expect_surface_fail(open, true, FTM_EPARSE, ":2: facet 1: the surface is not closed: its "
                                                "edge (0 1 0)-(1 0 0) is in 1 facet, not 2");
    ftm_surface *s = NULL;
    ftm_error err;
    assert_int_equal(ftm_surface_load(open, false, &s, &err), FTM_OK); /* a surface is fine */
    ftm_surface_destroy(s);
    /* one facet turned against the others */
    float flipped[36];
    memcpy(flipped, tet_facets, sizeof flipped);
    memcpy(flipped + 27 + 3, tet_facets + 27 + 6, 3 * sizeof(float));
    memcpy(flipped + 27 + 6, tet_facets + 27 + 3, 3 * sizeof(float));
    expect_surface_fail(write_binary_stl("flip.stl", flipped, 4), true, FTM_EPARSE,
                        "is oriented against it");
    /* a facet with a repeated corner, a facet on a line: named with its line */
    float bad[18] = {0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 2, 0, 0};
    expect_surface_fail(write_ascii_stl("rep.stl", bad, 1), false, FTM_EPARSE,
                        ":2: facet 1 is degenerate: corners 2 and 3 are the same point");
    float line[27];
    memcpy(line, tet_facets, 9 * sizeof(float));
    memcpy(line + 9, bad + 9, 9 * sizeof(float));
    memcpy(line + 18, tet_facets + 9, 9 * sizeof(float));
    expect_surface_fail(write_ascii_stl("line.stl", line, 3), false, FTM_EPARSE,
                        ":9: facet 2 is degenerate: its corners are on one line");
    /* not STL at all, an empty solid, a number too large for a float */
    expect_surface_fail(tmp_write("junk.stl", "ply\nformat ascii 1.0\n"), false, FTM_EPARSE,
                        "not an STL file");
    expect_surface_fail(tmp_write("empty.stl", "solid x\nendsolid x\n"), false, FTM_EPARSE,
                        "no facets");
    expect_surface_fail(tmp_write("big.stl", "solid x\nfacet normal 0 0 0\nouter loop\n"
                                             "vertex 1e999 0 0\nvertex 0 1 0\nvertex 0 0 1\n"
                                             "endloop\nendfacet\nendsolid x\n"),
                        false, FTM_EPARSE, "not finite");
    char missing[300];
    snprintf(missing, sizeof missing, "%s/none.stl", tmp_dir);
    expect_surface_fail(missing, false, FTM_EIO, "cannot open");
    /* the loader leaves the builder as it was, and names the line */
    char rep[300];
    snprintf(rep, sizeof rep, "%s/rep.stl", tmp_dir);
    expect_fail(ftm_load_stl, rep, FTM_EPARSE, 2, "facet 1 is degenerate");
}
#endif

/* ---- text forms: byte order mark, long polygons, numbers, repeated tetrahedra ---- */

/* A UTF-8 byte order mark (as Windows editors write) starts the file: it is
 * skipped, not taken for part of the first keyword, which lost the first
 * vertex and shifted every face. */
#define BOM "\xEF\xBB\xBF"

static void test_bom_at_start(void **state)
{
    (void)state;
    ftm_mesh *m = load_ok(ftm_load_obj, tmp_write("bom.obj", BOM "v 0 0 0\nv 1 0 0\nv 1 1 0\n"
                                                             "v 0 1 0\nf 1 2 3\nf 1 3 4\n"));
    check_counts(m, 4, 5, 2, 0);
    static const double xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    check_positions(m, 0, xyz, 4);
    /* The faces are 1 2 3 and 1 3 4 (input 0 1 2 and 0 2 3), not shifted. */
    const int32_t *tri = ftm_mesh_triangles(m);
    int sums = 0;
    for (int t = 0; t < 2; t++) {
        int sum = 0;
        for (int c = 0; c < 3; c++)
            sum += ftm_mesh_input_of_node(m, tri[3 * t + c]);
        sums |= 1 << sum;
    }
    assert_int_equal(sums, 1 << 3 | 1 << 5);
    ftm_mesh_destroy(m);

    m = load_ok(ftm_load_gmsh, tmp_write("bom.msh", BOM MSH_FORMAT MSH_NODES4
                                                        MSH_ELEMS("1 1 2 3 4")));
    check_counts(m, 4, 6, 4, 1);
    ftm_mesh_destroy(m);

    tmp_write("bom.ele", BOM "1 4 0\n1 1 2 3 4\n");
    m = load_ok(ftm_load_tetgen,
                tmp_write("bom.node", BOM "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"));
    check_counts(m, 4, 6, 4, 1);
    ftm_mesh_destroy(m);
}

/* Anywhere but the very start the mark is an error, never skipped text. */
static void test_bom_elsewhere(void **state)
{
    (void)state;
    expect_fail(ftm_load_obj,
                tmp_write("bom2.obj", "v 0 0 0\nv 1 0 0\n" BOM "v 0 1 0\nf 1 2 3\n"),
                FTM_EPARSE, 3, "byte order mark");
    expect_fail(ftm_load_obj, tmp_write("bom3.obj", " " BOM "v 0 0 0\n"), FTM_EPARSE, 1,
                "byte order mark");
    expect_fail(ftm_load_obj, tmp_write("bom4.obj", BOM BOM "v 0 0 0\n"), FTM_EPARSE, 1,
                "byte order mark");
    expect_fail(ftm_load_gmsh, tmp_write("bom2.msh", MSH_FORMAT BOM MSH_NODES4), FTM_EPARSE, 4,
                NULL);
    expect_fail(ftm_load_tetgen, tmp_write("bom2.node", "4 3 0 0\n" BOM "1 0 0 0\n"),
                FTM_EPARSE, 2, "point index");
}

/* The repeated-vertex check must not be quadratic in the polygon's size:
 * this face took 5.8 s so. */
static void test_obj_long_polygon(void **state)
{
    (void)state;
    enum { K = 200000 };
    size_t cap = (size_t)K * (64 + 8) + 64, len = 0; /* a "v" line and an index each */
    char *text = malloc(cap);
    assert_non_null(text);
    for (int i = 0; i < K; i++) { /* distinct points on a circle */
        double a = 6.283185307179586 * i / K;
        len += (size_t)snprintf(text + len, cap - len, "v %.17g %.17g 0\n", cos(a), sin(a));
    }
    len += (size_t)snprintf(text + len, cap - len, "f");
    for (int i = 1; i <= K; i++)
        len += (size_t)snprintf(text + len, cap - len, " %d", i);
    assert_true(len + 2 < cap);
    text[len++] = '\n';
    const char *path = tmp_write_n("polygon.obj", text, len);

    ftm_mesh_builder *b = ftm_mesh_builder_create();
    assert_non_null(b);
    ftm_material_def mat = test_material();
    ftm_error err = {0};
    clock_t t0 = clock();
    int rc = ftm_load_obj(b, path, &mat, &err);
    double seconds = (double)(clock() - t0) / CLOCKS_PER_SEC;
    if (rc != FTM_OK)
        fail_msg("%s: %s", path, err.message);
    assert_int_equal(ftm_mesh_builder_node_count(b), K);
    if (seconds > 2.0)
        fail_msg("a %d-vertex polygon took %.2f s to load", K, seconds);
    ftm_mesh_builder_destroy(b);

    /* A repeat at the far end is still found, with the same message. */
    len--;
    len += (size_t)snprintf(text + len, cap - len, " 7\n");
    expect_fail(ftm_load_obj, tmp_write_n("polygon2.obj", text, len), FTM_EPARSE, K + 1,
                "face repeats vertex 7");
    free(text);
}

/* Numbers of any length parse; hexadecimal, nan and inf are refused by name. */
static void test_number_forms(void **state)
{
    (void)state;
    char one[128] = "", line[512];
    for (int i = 0; i < 100; i++)
        strcat(one, "0");
    strcat(one, "1"); /* 101 characters */
    char half[160] = "0.5";
    for (int i = 0; i < 120; i++)
        strcat(half, "0");
    snprintf(line, sizeof line, "v 0 0 0\nv %s 0 0\nv 0 %s 0\nf %s 2 3\n", one, half, one);
    ftm_mesh *m = load_ok(ftm_load_obj, tmp_write("long.obj", line));
    static const double xyz[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 0.5, 0}};
    check_positions(m, 0, xyz, 3);
    ftm_mesh_destroy(m);

    /* TetGen indices and counts too. */
    snprintf(line, sizeof line, "4 3 0 0\n%s 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", one);
    tmp_write("long.ele", "1 4 0\n1 4 3 2 1\n");
    m = load_ok(ftm_load_tetgen, tmp_write("long.node", line));
    check_counts(m, 4, 6, 4, 1);
    ftm_mesh_destroy(m);

    static const bad_case cases[] = {
        {"hex.obj", "v 0x1p-10 0 0\n", FTM_EPARSE, 1, "hexadecimal"},
        {"hexneg.obj", "v 0 -0X1.8p1 0\n", FTM_EPARSE, 1, "hexadecimal"},
        {"hexint.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0x1 2 3\n", FTM_EPARSE, 4,
         "hexadecimal"},
        {"infinity.obj", "v 0 0 Infinity\n", FTM_EPARSE, 1, "not a finite number"},
        {"nanpayload.obj", "v 0 0 nan(1)\n", FTM_EPARSE, 1, "not a finite number"},
        {"overflow2.obj", "v 1e400 0 0\n", FTM_EPARSE, 1, "out of range"},
        {"noexp.obj", "v 1e 0 0\n", FTM_EPARSE, 1, "'1e': not a number"},
        {"dot.obj", "v . 0 0\n", FTM_EPARSE, 1, "'.': not a number"},
    };
    run_bad_cases(ftm_load_obj, cases, sizeof cases / sizeof cases[0]);
    expect_fail(ftm_load_gmsh,
                tmp_write("hex.msh", MSH_FORMAT "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n"
                                                "0 0 0\n0x1p0 0 0\n0 1 0\n0 0 1\n$EndNodes\n"),
                FTM_EPARSE, 12, "hexadecimal");
    expect_fail(ftm_load_tetgen, tmp_write("hex.node", "4 3 0 0\n1 0 0 0\n2 0x1 0 0\n"),
                FTM_EPARSE, 3, "hexadecimal");
}

static void test_bad_material(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    assert_non_null(b);
    ftm_error err = {0};
    ftm_material_def mat = test_material();
    mat.node_mass = 0.0;
    assert_int_equal(ftm_load_obj(b, DATA("quad.obj"), &mat, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "quad.obj: material: node mass must be > 0"));
    mat = test_material();
    mat.axis_scale.y = NAN;
    assert_int_equal(ftm_load_gmsh(b, DATA("tet2.msh"), &mat, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "tet2.msh: material: axis stiffness scale y must be > 0"));
    /* Zero scale along y: the quad's y edges would get no stiffness. Refused
     * with the material, as the generators refuse it (one check for both). */
    mat = test_material();
    mat.axis_scale = (ftm_vec3){1.0, 0.0, 1.0};
    assert_int_equal(ftm_load_obj(b, DATA("quad.obj"), &mat, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "quad.obj: material: axis stiffness scale y must be > 0"));
    assert_int_equal(ftm_mesh_builder_node_count(b), 0);
    /* NULL arguments are refused, and err may be NULL. */
    mat = test_material();
    assert_int_equal(ftm_load_obj(NULL, DATA("quad.obj"), &mat, &err), FTM_EINVAL);
    assert_int_equal(ftm_load_obj(b, NULL, &mat, &err), FTM_EINVAL);
    assert_int_equal(ftm_load_tetgen(b, DATA("tet.node"), NULL, NULL), FTM_EINVAL);
    assert_int_equal(ftm_load_mesh(b, DATA("bad_tag.msh"), &mat, NULL), FTM_EPARSE);
    assert_int_equal(ftm_mesh_builder_node_count(b), 0);
    ftm_mesh_builder_destroy(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_obj_cube),
        cmocka_unit_test(test_obj_quad_crlf),
        cmocka_unit_test(test_obj_axis_scaled_stiffness),
        cmocka_unit_test(test_obj_appends_to_builder),
        cmocka_unit_test(test_gmsh_two_tets),
        cmocka_unit_test(test_gmsh_triangles_only),
        cmocka_unit_test(test_gmsh_generated_base),
        cmocka_unit_test(test_tetgen_two_tets),
        cmocka_unit_test(test_tetgen_zero_based_quadratic),
        cmocka_unit_test(test_load_mesh_dispatch),
        cmocka_unit_test(test_missing_files),
        cmocka_unit_test(test_bad_data_files),
        cmocka_unit_test(test_bad_obj),
        cmocka_unit_test(test_bad_gmsh),
        cmocka_unit_test(test_bad_tetgen),
        cmocka_unit_test(test_gmsh_hexahedra_labels),
        cmocka_unit_test(test_bad_elements),
#ifdef FTM_TEST_STL
        cmocka_unit_test(test_stl),
        cmocka_unit_test(test_bad_stl),
#endif
        cmocka_unit_test(test_bom_at_start),
        cmocka_unit_test(test_bom_elsewhere),
        cmocka_unit_test(test_obj_long_polygon),
        cmocka_unit_test(test_number_forms),
        cmocka_unit_test(test_bad_material),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
