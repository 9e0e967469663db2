/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Scene parser tests: good scenes give the right mesh, simulation definition
 * and loads; every malformed scene gives a negative code and a message that
 * names the file and the offending line; scripted loads ramp as documented. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/ftm.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* cmocka 1.1 has no double comparison. */
#define assert_near(a, b, eps) near_impl((a), (b), (eps), #a, __LINE__)

static void near_impl(double a, double b, double eps, const char *what, int line)
{
    if (!(fabs(a - b) <= eps))
        fail_msg("line %d: %s = %.17g, expected %.17g (+- %g)", line, what, a, b, eps);
}

static ftm_scene *parse_ok(const char *text)
{
    ftm_scene *scene = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_scene_parse(text, strlen(text), "test.scene", &scene, &err);
    if (rc != FTM_OK)
        fail_msg("parse failed (%d): %s", rc, err.message);
    assert_non_null(scene);
    return scene;
}

static int32_t count_fixed(const ftm_mesh *mesh)
{
    int32_t n = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(mesh); i++)
        n += ftm_mesh_fixed(mesh, i);
    return n;
}

/* ------------------------------------------------------------ good scenes */

static const char lattice3d_scene[] =
    "# a small cube\n"
    "[scene]\n"
    "name = little cube\n"
    "description = used by test_scene\n"
    "\n"
    "[mesh]\n"
    "generator = lattice3d   # trailing comment\n"
    "nx = 3\n"
    "ny = 4\n"
    "nz = 5\n"
    "spacing = 0.01 0.02 0.03\n"
    "stencil = 6\n"
    "class_scale = 1 0.5 0.25\n"
    "fixed_faces = zmin\n"
    "[material]\n"
    "mass = 0.002\n"
    "damping = 0.1\n"
    "stiffness = 40\n"
    "axis_scale = 1 2 3\n"
    "[sim]\n"
    "time_step = 2e-4\n"
    "depth = 5\n"
    "order = jacobi\n"
    "steps = 77\n"
    "sleep_tolerance = 1e-5\n"
    "region_sleep_steps = 9\n"
    "guard = off\n"
    "guard_motion = 0.25\n"
    "max_substeps = 8\n"
    "[load]\n"
    "node = 59\n"
    "kind = displacement\n"
    "value = 0 0 -0.001\n"
    "group = 3\n"
    "start = 0.1\n"
    "end = 0.3\n"
    "release = 0.5\n"
    "ramp = linear\n"
    "[load]\n"
    "node = 58\n"
    "value = 1 2 3\n";

static void test_lattice3d_scene(void **state)
{
    (void)state;
    ftm_scene *scene = parse_ok(lattice3d_scene);
    assert_string_equal(ftm_scene_name(scene), "little cube");
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    assert_int_equal(ftm_mesh_node_count(mesh), 3 * 4 * 5);
    /* stencil 6: one link per lattice edge along each axis */
    assert_int_equal(ftm_mesh_link_count(mesh), 2 * 4 * 5 + 3 * 3 * 5 + 3 * 4 * 4);
    assert_int_equal(count_fixed(mesh), 3 * 4);
    for (int32_t i = 0; i < ftm_mesh_node_count(mesh); i++) {
        assert_true(ftm_mesh_mass(mesh, i) == 0.002);
        assert_true(ftm_mesh_damping(mesh, i) == 0.1);
    }
    /* Axis-aligned links get stiffness * class edge scale * axis scale. */
    int32_t a0 = ftm_mesh_node_of_input(mesh, 0), ax = ftm_mesh_node_of_input(mesh, 1);
    const int32_t *nb;
    const double *k, *len;
    int32_t deg = ftm_mesh_neighbors(mesh, a0, &nb, &k, &len);
    bool found = false;
    for (int32_t j = 0; j < deg; j++) {
        if (nb[j] == ax) {
            found = true;
            assert_near(k[j], 40.0, 1e-12);
            assert_near(len[j], 0.01, 1e-15);
        }
    }
    assert_true(found);

    ftm_sim_def def = ftm_scene_sim_def(scene);
    assert_true(def.time_step == 2e-4);
    assert_int_equal(def.depth, 5);
    assert_int_equal(def.order, FTM_ORDER_LAYER_JACOBI);
    assert_true(def.sleep_tolerance == 1e-5);
    assert_int_equal(def.region_sleep_steps, 9);
    assert_false(def.guard);
    assert_true(def.guard_motion == 0.25);
    assert_int_equal(def.max_substeps, 8);
    assert_null(def.log);
    assert_int_equal(ftm_scene_steps(scene), 77);

    assert_int_equal(ftm_scene_load_count(scene), 2);
    const ftm_scene_load *l = ftm_scene_loads(scene);
    assert_int_equal(l[0].contact.node, ftm_mesh_node_of_input(mesh, 59));
    assert_int_equal(l[0].contact.kind, FTM_CONTACT_DISPLACEMENT);
    assert_int_equal(l[0].contact.group, 3);
    assert_true(l[0].contact.value.x == 0 && l[0].contact.value.y == 0 &&
                l[0].contact.value.z == -0.001);
    assert_true(l[0].start == 0.1 && l[0].end == 0.3 && l[0].release == 0.5);
    assert_int_equal(l[0].ramp, FTM_RAMP_LINEAR);
    /* Defaults: force, group 0, start 0, end = start, never released, constant. */
    assert_int_equal(l[1].contact.node, ftm_mesh_node_of_input(mesh, 58));
    assert_int_equal(l[1].contact.kind, FTM_CONTACT_FORCE);
    assert_int_equal(l[1].contact.group, 0);
    assert_true(l[1].contact.value.x == 1 && l[1].contact.value.y == 2 &&
                l[1].contact.value.z == 3);
    assert_true(l[1].start == 0 && l[1].end == 0);
    assert_true(isinf(l[1].release));
    assert_int_equal(l[1].ramp, FTM_RAMP_CONSTANT);
    ftm_scene_destroy(scene);
}

static void test_lattice2d_scene_and_defaults(void **state)
{
    (void)state;
    ftm_scene *scene = parse_ok("[mesh]\n"
                                "generator = lattice2d\n"
                                "nx = 4\n"
                                "ny = 5\n"
                                "spacing = 2\n"
                                "fixed_faces = all\n"
                                "[material]\n"
                                "mass = 1\n"
                                "stiffness = 3\n"
                                "[load]\n"
                                "node = 5\n"
                                "value = 0 -1 0\n"
                                "release = never\n");
    /* No [scene] name: the file name without its extension. */
    assert_string_equal(ftm_scene_name(scene), "test");
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    assert_int_equal(ftm_mesh_node_count(mesh), 20);
    /* Triangular lattice: row links plus 2 nx - 1 links between rows. */
    assert_int_equal(ftm_mesh_link_count(mesh), 3 * 5 + 4 * 7);
    assert_int_equal(count_fixed(mesh), 2 * 4 + 2 * 5 - 4);
    assert_true(ftm_mesh_damping(mesh, 0) == 0);
    ftm_sim_def def = ftm_scene_sim_def(scene);
    ftm_sim_def lib = ftm_default_sim_def();
    assert_true(def.time_step == lib.time_step);
    assert_int_equal(def.depth, lib.depth);
    assert_int_equal(def.order, lib.order);
    assert_int_equal(def.guard, lib.guard);
    assert_int_equal(ftm_scene_steps(scene), 1000);
    assert_int_equal(ftm_scene_load_count(scene), 1);
    assert_true(isinf(ftm_scene_loads(scene)[0].release));
    ftm_scene_destroy(scene);
}

static void test_nearest_and_crlf(void **state)
{
    (void)state;
    ftm_scene *scene = parse_ok("[mesh]\r\n"
                                "generator = lattice3d\r\n"
                                "nx = 3\r\nny = 3\r\nnz = 3\r\n"
                                "spacing = 1\r\n"
                                "[material]\r\nmass = 1\r\nstiffness = 1\r\n"
                                "[load]\r\n"
                                "node = nearest 2.1 0.9 1.2\r\n"
                                "value = 0 0 1\r\n");
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    int32_t node = ftm_scene_loads(scene)[0].contact.node;
    ftm_vec3 x = ftm_mesh_rest_position(mesh, node);
    ftm_vec3 origin = ftm_mesh_rest_position(mesh, ftm_mesh_node_of_input(mesh, 0));
    assert_near(x.x - origin.x, 2.0, 1e-12);
    assert_near(x.y - origin.y, 1.0, 1e-12);
    assert_near(x.z - origin.z, 1.0, 1e-12);
    /* stencil defaults to 18 */
    assert_int_equal(ftm_mesh_link_count(mesh), 54 + 72);
    ftm_scene_destroy(scene);
}

/* -------------------------------------------------------- malformed scenes */

typedef struct bad_case {
    const char *text;
    int line;
    const char *needle; /* must appear in the message */
} bad_case;

#define MESH2D "[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 1\n" /* lines 1-5 */
#define MAT "[material]\nmass = 1\nstiffness = 1\n"                          /* lines 6-8 */

static const bad_case bad_cases[] = {
    {MESH2D MAT "[sim]\ntime_stepp = 1\n", 10, "unknown key 'time_stepp'"},
    {MESH2D MAT "[sim]\nmass = 1\n", 10, "unknown key 'mass' in [sim] (it belongs in [material])"},
    {MESH2D "[material]\nmass = abc\nstiffness = 1\n", 7, "expected a finite number"},
    {MESH2D "[material]\nmass = nan\nstiffness = 1\n", 7, "expected a finite number"},
    {MESH2D "[material]\nmass = 1\nstiffness = inf\n", 8, "expected a finite number"},
    {MESH2D "[material]\nmass = 1e999\nstiffness = 1\n", 7, "expected a finite number"},
    {MESH2D "[material]\nmass = -1\nstiffness = 1\n", 7, "mass must be > 0"},
    {MESH2D "[material]\nmass = 1\ndamping = -0.5\nstiffness = 1\n", 8, "damping must be >= 0"},
    {MESH2D "[material]\nmass = 1\nstiffness = 0\n", 8, "stiffness must be > 0"},
    {MESH2D "[material]\nmass = 1\nstiffness = 1\naxis_scale = 1 0 1\n", 9, "axis_scale"},
    {MESH2D MAT "[sim]\ndepth = -1\n", 10, "depth must be between 0"},
    {MESH2D MAT "[sim]\ndepth = 1.5\n", 10, "expected an integer"},
    {MESH2D MAT "[sim]\ntime_step = 0\n", 10, "time_step must be > 0"},
    {MESH2D MAT "[sim]\ntime_step = -1e-3\n", 10, "time_step must be > 0"},
    {"[scene]\nname = ab\xff" "cd\n" MESH2D MAT, 2, "name is not valid UTF-8 (byte 3)"},
    {"[scene]\nname = \xed\xa0\x80\n" MESH2D MAT, 2, "name is not valid UTF-8 (byte 1)"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 1e-300\n" MAT, 2,
     "link's length is zero or not finite"},
    /* a spacing whose lattice passes double precision: the field and its limit */
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 3\nspacing = 1e308\n" MAT, 2,
     "lattice2d: spacing 1e+308 m is too large: 4 nodes along an axis would reach beyond double "
     "precision (1.79769e+308); at most 4.49423e+307 m"},
    {"[mesh]\ngenerator = lattice3d\nnx = 2\nny = 4\nnz = 2\nspacing = 1 1e308 1\n" MAT, 2,
     "lattice3d: spacing y 1e+308 m is too large: 4 nodes along y would reach beyond double "
     "precision (1.79769e+308); at most 5.99231e+307 m"},
    {MESH2D MAT "[sim]\ntime_step = 1e-160\n", 10, "time_step must be in 1e-12..1000 s"},
    {MESH2D MAT "[sim]\ntime_step = 2e3\n", 10, "time_step must be in 1e-12..1000 s"},
    {MESH2D MAT "[sim]\norder = random\n", 10, "unknown value 'random'"},
    {MESH2D MAT "[sim]\nguard = maybe\n", 10, "guard"},
    {MESH2D MAT "[sim]\nmax_substeps = 0\n", 10, "max_substeps"},
    {MESH2D MAT "[sim]\nsteps = 10 20\n", 10, "expected 1 value"},
    {MESH2D MAT "[load]\nnode = 16\nvalue = 0 0 1\n", 10, "node 16 out of range"},
    {MESH2D MAT "[load]\nnode = -2\nvalue = 0 0 1\n", 10, "node must be between"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 1\n", 11, "expected 3 values"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 nan 1\n", 11, "expected a finite number"},
    {MESH2D MAT "[load]\nnode = 5\nkind = pressure\nvalue = 0 0 1\n", 11, "pressure"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\nramp = linear\n", 12, "needs end"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\nramp = triangle\nstart = 1\nend = 1\n", 14,
     "end (1) must be after start"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\nstart = 2\nrelease = 1\n", 13,
     "release (1) must be after start"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\nstart = -1\n", 12, "start must be >= 0"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\ngroup = -1\n", 12, "group"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\ngroup = 1048577\n", 12,
     "group must be between 0 and 1048576"},
    {MESH2D MAT "[load]\nvalue = 0 0 1\n", 9, "[load] needs node"},
    {MESH2D MAT "[load]\nnode = 5\n", 9, "[load] needs value"},
    {MESH2D MAT "[load]\nnode = nearest 1 2\nvalue = 0 0 1\n", 10, "nearest"},
    {MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\nrelease = 2\n[load]\nnode = 5\n"
                "value = 1 0 0\nstart = 1\n",
     13, "overlaps in time with the load at line 9"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 1\nfixed_faces = xmin\n"
     "[material]\nmass = 1\nstiffness = 1\n[load]\nnode = 4\nvalue = 0 0 1\n",
     11, "node 4 is fixed"},
    {MAT "[sim]\ndepth = 3\n", 5, "missing [mesh] section"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 1\n", 5,
     "missing [material] section"},
    {MESH2D "[material]\nstiffness = 1\n", 6, "[material] needs mass"},
    {"[mesh]\ngenerator = lattice4d\nnx = 4\n" MAT, 2, "unknown generator 'lattice4d'"},
    {"[mesh]\nnx = 4\n" MAT, 1, "needs 'generator"},
    {"[mesh]\nfile = no-such-mesh-file.obj\n" MAT, 2, "no-such-mesh-file.obj"},
    {"[mesh]\ngenerator = lattice2d\nfile = a.obj\nnx = 4\nny = 4\nspacing = 1\n" MAT, 3,
     "both generator"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nspacing = 1\n" MAT, 2, "lattice2d generator needs ny"},
    {"[mesh]\ngenerator = lattice2d\nnx = 1\nny = 4\nspacing = 1\n" MAT, 3, "nx must be between 2"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nnz = 4\nspacing = 1\n" MAT, 5,
     "nz is not used by lattice2d"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 1 1 1\n" MAT, 5,
     "single spacing"},
    {"[mesh]\ngenerator = lattice3d\nnx = 4\nny = 4\nnz = 4\nspacing = 1 1\n" MAT, 6,
     "spacing: expected 1 value"},
    {"[mesh]\ngenerator = lattice3d\nnx = 4\nny = 4\nnz = 4\nspacing = 0\n" MAT, 6,
     "spacing must be > 0"},
    {"[mesh]\ngenerator = lattice3d\nnx = 4\nny = 4\nnz = 4\nspacing = 1\nstencil = 12\n" MAT,
     7, "stencil must be 6, 18 or 26"},
    {"[mesh]\ngenerator = lattice3d\nnx = 4\nny = 4\nnz = 4\nspacing = 1\nfixed_faces = top\n"
     MAT,
     7, "unknown face 'top'"},
    {"[mesh]\ngenerator = lattice3d\nnx = 4000\nny = 4000\nnz = 4000\nspacing = 1\n" MAT, 2,
     "larger than the limit"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 1\nfixed_faces = zmin\n" MAT, 6,
     "no zmin/zmax"},
    {MESH2D "fixed_nodes = 1 2 99\n" MAT, 6, "fixed_nodes: node 99 out of range"},
    {MESH2D "fixed_nodes = 1 x\n" MAT, 6, "expected an integer"},
    {MESH2D "fixed_box = 0 0 0 1 1\n" MAT, 6, "expected 6 values"},
    {MESH2D "fixed_box = 0 2 0 1 1 1\n" MAT, 6, "min y"},
    {"[mesh]\nfile = m.obj\nfixed_faces = xmin\n" MAT, 3, "use fixed_nodes or fixed_box"},
    /* partial constraints and springs to ground (docs/scene-format.md) */
    {MESH2D "slide_nodes = 0 0 0 : 5\n" MAT, 6, "the normal 0 0 0 has zero length"},
    {MESH2D "slide_nodes = 1 0 : 5\n" MAT, 6, "the normal is x, y, z or three numbers"},
    {MESH2D "slide_nodes = z 5\n" MAT, 6, "expected NORMAL : NODES"},
    {MESH2D "slide_nodes = z :\n" MAT, 6, "expected NORMAL : NODES"},
    {MESH2D "slide_nodes = x : 3 99\n" MAT, 6, "slide_nodes: node 99 out of range"},
    {MESH2D "fixed_nodes = 5\nslide_nodes = x : 5\n" MAT, 7,
     "slide_nodes: node 5 is fixed too"},
    {MESH2D "slide_nodes = x : 5\nslide_nodes = y : 5\nslide_nodes = 1 1 1 : 5\n" MAT, 8,
     "fix it instead"},
    {MESH2D "slide_box = z : 5 5 5 6 6 6\n" MAT, 6, "slide_box: no node lies in the box"},
    {MESH2D "slide_box = z : 0 2 0 1 1 1\n" MAT, 6, "min y"},
    {MESH2D "ground_springs = -3 : 5\n" MAT, 6, "ground_springs must be >= 0, got -3"},
    {MESH2D "ground_springs = 0 : 5\n" MAT, 6, "stiffness must be > 0 N/m"},
    {MESH2D "ground_springs = 10 : 16\n" MAT, 6, "ground_springs: node 16 out of range"},
    {MESH2D "ground_springs = soft : 5\n" MAT, 6, "ground_springs"},
    {"[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 1\nfixed_faces = xmin\n"
     "ground_springs = 10 : 4\n" MAT, 7, "ground_springs: node 4 is fixed too"},
    {MESH2D MAT "[material]\nmass = 2\n", 9, "duplicate section [material] (first at line 6)"},
    {MESH2D "nx = 5\n" MAT, 6, "duplicate key 'nx' (first at line 3)"},
    {MESH2D MAT "[physics]\n", 9, "unknown section [physics]"},
    {MESH2D MAT "[sim\n", 9, "section header"},
    {"mass = 1\n" MESH2D MAT, 1, "outside a section"},
    {MESH2D MAT "[sim]\ndepth 3\n", 10, "expected 'key = value'"},
    {MESH2D MAT "[sim]\ndepth =\n", 10, "depth: missing value"},
    {MESH2D MAT "[sim]\n= 3\n", 10, "missing key"},
    {MESH2D MAT "[scene]\nname = \x01x\n", 10, "control character"},
    {"", 1, "missing [mesh] section"},
};

static void test_malformed(void **state)
{
    (void)state;
    size_t n = sizeof bad_cases / sizeof bad_cases[0];
    for (size_t i = 0; i < n; i++) {
        const bad_case *c = &bad_cases[i];
        ftm_scene *scene = NULL;
        ftm_error err;
        memset(&err, 0, sizeof err);
        int rc = ftm_scene_parse(c->text, strlen(c->text), "bad.scene", &scene, &err);
        char prefix[64];
        snprintf(prefix, sizeof prefix, "bad.scene:%d: ", c->line);
        if (rc >= 0 || scene != NULL || err.code != rc || strncmp(err.message, prefix,
                                                                  strlen(prefix)) != 0 ||
            !strstr(err.message, c->needle))
            fail_msg("case %zu: rc %d, message '%s'; wanted '%s...%s'", i, rc, err.message,
                     prefix, c->needle);
        ftm_scene_destroy(scene);
    }
}

static void test_parse_length_is_respected(void **state)
{
    (void)state;
    /* Text past length (a bad line) must not be read. */
    const char text[] = MESH2D MAT "junk";
    ftm_scene *scene = NULL;
    ftm_error err;
    assert_int_equal(ftm_scene_parse(text, strlen(text) - 4, "t", &scene, &err), FTM_OK);
    ftm_scene_destroy(scene);
    assert_true(ftm_scene_parse(text, strlen(text), "t", &scene, &err) < 0);
    assert_non_null(strstr(err.message, "t:9:"));
    /* A NUL byte inside the given length is refused, naming its line. */
    const char nul[] = "[mesh]\nfile = a\0b.obj\n";
    scene = NULL;
    assert_int_equal(ftm_scene_parse(nul, sizeof nul - 1, "n", &scene, &err), FTM_EPARSE);
    assert_null(scene);
    assert_non_null(strstr(err.message, "n:2: NUL"));
}

/* ----------------------------------------------------- file meshes on disk */

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    assert_int_equal(fputs(text, f) >= 0, 1);
    assert_int_equal(fclose(f), 0);
}

/* A unit square split in two triangles, plus a raised fifth vertex. */
static const char square_obj[] = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\n"
                                 "f 1 2 3\nf 1 3 4\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n";

static void test_file_mesh(void **state)
{
    (void)state;
    char dir[] = "/tmp/ftm_test_scene_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char mesh_path[256], scene_path[256], other[256];
    snprintf(mesh_path, sizeof mesh_path, "%s/mesh.obj", dir);
    snprintf(scene_path, sizeof scene_path, "%s/pyramid.scene", dir);
    snprintf(other, sizeof other, "%s/bad.scene", dir);
    write_file(mesh_path, square_obj);
    /* The mesh path is relative to the scene file, not to the working directory. */
    write_file(scene_path, "[mesh]\n"
                           "file = mesh.obj\n"
                           "fixed_nodes = 0\n"
                           "fixed_nodes = 1\n"
                           "fixed_box = -0.1 0.9 -0.1 0.1 1.1 0.1\n"
                           "[material]\n"
                           "mass = 0.5\n"
                           "damping = 0.25\n"
                           "stiffness = 10\n"
                           "[load]\n"
                           "node = 4\n"
                           "kind = displacement\n"
                           "value = 0 0 -0.1\n");
    ftm_scene *scene = NULL;
    ftm_error err;
    int rc = ftm_scene_load_file(scene_path, &scene, &err);
    if (rc != FTM_OK)
        fail_msg("%s", err.message);
    assert_string_equal(ftm_scene_name(scene), "pyramid");
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    assert_int_equal(ftm_mesh_node_count(mesh), 5);
    assert_int_equal(ftm_mesh_link_count(mesh), 9);
    assert_int_equal(ftm_mesh_triangle_count(mesh), 6);
    /* inputs 0 and 1 by index, 3 = (0, 1, 0) by the box; 2 and 4 free */
    assert_true(ftm_mesh_fixed(mesh, ftm_mesh_node_of_input(mesh, 0)));
    assert_true(ftm_mesh_fixed(mesh, ftm_mesh_node_of_input(mesh, 1)));
    assert_false(ftm_mesh_fixed(mesh, ftm_mesh_node_of_input(mesh, 2)));
    assert_true(ftm_mesh_fixed(mesh, ftm_mesh_node_of_input(mesh, 3)));
    assert_false(ftm_mesh_fixed(mesh, ftm_mesh_node_of_input(mesh, 4)));
    for (int32_t i = 0; i < 5; i++) {
        ftm_vec3 x = ftm_mesh_rest_position(mesh, ftm_mesh_node_of_input(mesh, i));
        assert_true(x.z == (i == 4 ? 1.0 : 0.0));
        assert_true(ftm_mesh_mass(mesh, i) == 0.5 && ftm_mesh_damping(mesh, i) == 0.25);
    }
    assert_int_equal(ftm_scene_loads(scene)[0].contact.node, ftm_mesh_node_of_input(mesh, 4));
    ftm_scene_destroy(scene);

    /* Errors in a file name the file and line. */
    write_file(other, "[mesh]\nfile = mesh.obj\nfixed_nodes = 7\n[material]\nmass = 1\n"
                      "stiffness = 1\n");
    scene = NULL;
    assert_int_equal(ftm_scene_load_file(other, &scene, &err), FTM_ERANGE);
    assert_null(scene);
    char want[300];
    snprintf(want, sizeof want, "%s:3: fixed_nodes: node 7 out of range", other);
    assert_non_null(strstr(err.message, want));

    /* A directory given as the scene: said as such, not "read error". */
    assert_int_equal(ftm_scene_load_file(dir, &scene, &err), FTM_EIO);
    assert_null(scene);
    snprintf(want, sizeof want, "%s: is a directory, not a file", dir);
    if (!strstr(err.message, want))
        fail_msg("directory: %s", err.message);

    /* In-memory text: relative to the current directory. */
    char cwd[512];
    assert_non_null(getcwd(cwd, sizeof cwd));
    assert_int_equal(chdir(dir), 0);
    const char text[] = "[mesh]\nfile = mesh.obj\n[material]\nmass = 1\nstiffness = 1\n";
    rc = ftm_scene_parse(text, strlen(text), "mem", &scene, &err);
    assert_int_equal(chdir(cwd), 0);
    if (rc != FTM_OK)
        fail_msg("%s", err.message);
    assert_int_equal(ftm_mesh_node_count(ftm_scene_mesh(scene)), 5);
    ftm_scene_destroy(scene);

    /* A scene file that does not exist. */
    char missing[300];
    snprintf(missing, sizeof missing, "%s/missing.scene", dir);
    assert_int_equal(ftm_scene_load_file(missing, &scene, &err), FTM_EIO);
    assert_non_null(strstr(err.message, "missing.scene"));

    unlink(mesh_path);
    unlink(scene_path);
    unlink(other);
    rmdir(dir);
}

static void test_data_scenes(void **state)
{
    (void)state;
    static const char *const files[] = {"cube_press.scene", "membrane_poke.scene",
                                        "two_probes.scene"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        char path[512];
        snprintf(path, sizeof path, "%s/scenes/%s", FTM_TEST_DATA, files[i]);
        ftm_scene *scene = NULL;
        ftm_error err;
        if (ftm_scene_open(path, &scene, &err) != FTM_OK)
            fail_msg("%s", err.message);
        assert_true(ftm_scene_load_count(scene) >= 1);
        ftm_sim_def def = ftm_scene_sim_def(scene);
        assert_true(def.time_step < ftm_mesh_critical_time_step(ftm_scene_mesh(scene)));
        ftm_scene_destroy(scene);
    }
}

/* A scene named by another machine: found by base name along a search list. */
static void test_open_search(void **state)
{
    (void)state;
    char dir[512], path[1024];
    snprintf(dir, sizeof dir, "%s/scenes", FTM_TEST_DATA);
    ftm_scene *scene = NULL;
    ftm_error err;
    /* a path that exists elsewhere on the server: the base name along the list */
    char search[1200];
    snprintf(search, sizeof search, "/nonexistent-ftm::%s", dir);
    if (ftm_scene_open_search("/srv/ftm/scenes/two_probes.scene", search, &scene, path,
                              sizeof path, &err) != FTM_OK)
        fail_msg("%s", err.message);
    char want[1100];
    snprintf(want, sizeof want, "%s/two_probes.scene", dir);
    assert_string_equal(path, want);
    ftm_scene *direct = NULL;
    assert_int_equal(ftm_scene_open(want, &direct, &err), FTM_OK);
    assert_int_equal(ftm_mesh_node_count(ftm_scene_mesh(scene)),
                     ftm_mesh_node_count(ftm_scene_mesh(direct)));
    ftm_scene_destroy(direct);
    ftm_scene_destroy(scene);
    /* built-ins and files as given come first; the path says which */
    assert_int_equal(ftm_scene_open_search("membrane", search, &scene, path, sizeof path, &err),
                     FTM_OK);
    assert_string_equal(path, "membrane");
    ftm_scene_destroy(scene);
    assert_int_equal(ftm_scene_open_search(want, NULL, &scene, NULL, 0, &err), FTM_OK);
    ftm_scene_destroy(scene);
    /* nowhere: FTM_ENOENT naming every place tried */
    assert_int_equal(ftm_scene_open_search("a/b/none.scene", search, &scene, path, sizeof path,
                                           &err),
                     FTM_ENOENT);
    assert_null(scene);
    assert_string_equal(path, "");
    char tried[1200];
    snprintf(tried, sizeof tried, "tried a/b/none.scene, /nonexistent-ftm/none.scene, %s/none.scene",
             dir);
    if (!strstr(err.message, "scene 'a/b/none.scene' not found") || !strstr(err.message, tried))
        fail_msg("message: %s", err.message);
    /* without a list: ftm_scene_open's own message */
    assert_int_equal(ftm_scene_open_search("nosuch", "", &scene, NULL, 0, &err), FTM_ENOENT);
    assert_non_null(strstr(err.message, "unknown scene 'nosuch'"));
    /* a file found along the list that is malformed: its own error, file and line */
    snprintf(search, sizeof search, "%s", FTM_TEST_DATA);
    assert_int_equal(ftm_scene_open_search("x/bad_index.obj", search, &scene, NULL, 0, &err),
                     FTM_EPARSE);
    assert_non_null(strstr(err.message, "bad_index.obj:"));
}

/* --------------------------------------------------------------- built-ins */

static void test_builtins(void **state)
{
    (void)state;
    const char *const *names = ftm_scene_builtin_names();
    int count = 0;
    for (; names[count]; count++) {
        ftm_scene *scene = NULL;
        ftm_error err;
        if (ftm_scene_builtin(names[count], &scene, &err) != FTM_OK)
            fail_msg("%s: %s", names[count], err.message);
        assert_string_equal(ftm_scene_name(scene), names[count]);
        const ftm_mesh *mesh = ftm_scene_mesh(scene);
        /* Every built-in runs with margin below the stability limit. */
        double h = ftm_scene_sim_def(scene).time_step;
        double crit = ftm_mesh_critical_time_step(mesh);
        if (!(h < 0.8 * crit))
            fail_msg("%s: h %g vs critical %g", names[count], h, crit);
        assert_true(ftm_scene_load_count(scene) >= 1);
        ftm_scene_destroy(scene);
    }
    assert_true(count >= 3);

    ftm_scene *scene = NULL;
    ftm_error err;
    assert_int_equal(ftm_scene_open("default", &scene, &err), FTM_OK);
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    assert_int_equal(ftm_mesh_node_count(mesh), 12 * 12 * 12);
    assert_int_equal(count_fixed(mesh), 12 * 12);
    assert_int_equal(ftm_scene_steps(scene), 2000);
    assert_int_equal(ftm_scene_sim_def(scene).depth, 8);
    const ftm_scene_load *l = ftm_scene_loads(scene);
    assert_int_equal(l[0].contact.kind, FTM_CONTACT_DISPLACEMENT);
    assert_true(l[0].contact.value.z == -0.004 && l[0].release == 0.5);
    ftm_vec3 top = ftm_mesh_rest_position(mesh, l[0].contact.node);
    ftm_vec3 origin = ftm_mesh_rest_position(mesh, ftm_mesh_node_of_input(mesh, 0));
    assert_near(top.z - origin.z, 0.11, 1e-12);
    ftm_scene_destroy(scene);

    assert_int_equal(ftm_scene_open("table3", &scene, &err), FTM_OK);
    mesh = ftm_scene_mesh(scene);
    assert_int_equal(ftm_mesh_node_count(mesh), 2500);
    assert_int_equal(count_fixed(mesh), 4 * 50 - 4);
    assert_int_equal(ftm_scene_sim_def(scene).depth, 20);
    assert_int_equal(ftm_scene_loads(scene)[0].contact.node, ftm_mesh_node_of_input(mesh, 1275));
    ftm_scene_destroy(scene);

    assert_int_equal(ftm_scene_open("membrane", &scene, &err), FTM_OK);
    assert_int_equal(ftm_mesh_node_count(ftm_scene_mesh(scene)), 900);
    ftm_scene_destroy(scene);

    scene = NULL;
    assert_int_equal(ftm_scene_builtin("nope", &scene, &err), FTM_ENOENT);
    assert_null(scene);
    assert_int_equal(ftm_scene_open("nope", &scene, &err), FTM_ENOENT);
    assert_non_null(strstr(err.message, "nope"));
    assert_null(scene);
}

/* ------------------------------------------------------------ contacts_at */

static const char ramps_scene[] = MESH2D MAT
    "[load]\nnode = 5\nvalue = 2 0 0\nstart = 1\nrelease = 3\n"                      /* constant */
    "[load]\nnode = 6\nvalue = 0 4 0\nramp = linear\nstart = 1\nend = 2\nrelease = 4\n"
    "[load]\nnode = 9\nkind = displacement\nvalue = 0 0 -8\ngroup = 2\nramp = triangle\n"
    "start = 0\nend = 2\n";

static int32_t at(const ftm_scene *scene, double t, ftm_contact *c)
{
    return ftm_scene_contacts_at(scene, t, c, 8);
}

static void test_contacts_at(void **state)
{
    (void)state;
    ftm_scene *scene = parse_ok(ramps_scene);
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    int32_t n5 = ftm_mesh_node_of_input(mesh, 5), n6 = ftm_mesh_node_of_input(mesh, 6),
            n9 = ftm_mesh_node_of_input(mesh, 9);
    ftm_contact c[8];

    /* t = 0: only the triangle, at 0 */
    assert_int_equal(at(scene, 0.0, c), 1);
    assert_int_equal(c[0].node, n9);
    assert_int_equal(c[0].group, 2);
    assert_int_equal(c[0].kind, FTM_CONTACT_DISPLACEMENT);
    assert_true(c[0].value.z == 0.0);
    /* t = 0.5: triangle a quarter through: half value */
    assert_int_equal(at(scene, 0.5, c), 1);
    assert_near(c[0].value.z, -4.0, 1e-12);
    /* t = 1: constant at full value, linear at 0, triangle at its peak; load order kept */
    assert_int_equal(at(scene, 1.0, c), 3);
    assert_int_equal(c[0].node, n5);
    assert_true(c[0].value.x == 2 && c[0].value.y == 0 && c[0].value.z == 0);
    assert_int_equal(c[1].node, n6);
    assert_true(c[1].value.y == 0);
    assert_int_equal(c[2].node, n9);
    assert_true(c[2].value.z == -8);
    /* t = 1.5: linear half way, triangle on the way down */
    assert_int_equal(at(scene, 1.5, c), 3);
    assert_near(c[1].value.y, 2.0, 1e-12);
    assert_near(c[2].value.z, -4.0, 1e-12);
    /* t = 2.5: linear held at full value; triangle over but still in contact at 0 */
    assert_int_equal(at(scene, 2.5, c), 3);
    assert_true(c[1].value.y == 4);
    assert_true(c[2].value.z == 0);
    /* t = 3: constant released (release is exclusive) */
    assert_int_equal(at(scene, 3.0, c), 2);
    assert_int_equal(c[0].node, n6);
    /* t = 4: linear released; the triangle is never released */
    assert_int_equal(at(scene, 4.0, c), 1);
    assert_int_equal(c[0].node, n9);
    assert_int_equal(at(scene, 1e9, c), 1);

    /* Capacity: the count of active contacts is returned, only capacity written. */
    ftm_contact one[2];
    one[1].node = -12345;
    assert_int_equal(ftm_scene_contacts_at(scene, 1.0, one, 1), 3);
    assert_int_equal(one[0].node, n5);
    assert_int_equal(one[1].node, -12345);
    assert_int_equal(ftm_scene_contacts_at(scene, 1.0, NULL, 0), 3);
    ftm_scene_destroy(scene);
}

static void test_sequential_loads_same_node(void **state)
{
    (void)state;
    /* Two loads on one node are fine when one ends before the other starts. */
    ftm_scene *scene = parse_ok(MESH2D MAT "[load]\nnode = 5\nvalue = 0 0 1\nrelease = 1\n"
                                           "[load]\nnode = 5\nvalue = 0 0 2\nstart = 1\n");
    ftm_contact c[2];
    assert_int_equal(ftm_scene_contacts_at(scene, 0.999, c, 2), 1);
    assert_true(c[0].value.z == 1);
    assert_int_equal(ftm_scene_contacts_at(scene, 1.0, c, 2), 1);
    assert_true(c[0].value.z == 2);
    ftm_scene_destroy(scene);
}

/* The optional [fem] section: Young's modulus, Poisson's ratio, density. */
static void expect_bad(const char *text, int line, const char *needle)
{
    ftm_scene *scene = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_scene_parse(text, strlen(text), "fem.scene", &scene, &err);
    char prefix[64];
    snprintf(prefix, sizeof prefix, "fem.scene:%d: ", line);
    if (rc >= 0 || scene != NULL || err.code != rc ||
        strncmp(err.message, prefix, strlen(prefix)) != 0 || !strstr(err.message, needle))
        fail_msg("rc %d, message '%s'; wanted '%s...%s'", rc, err.message, prefix, needle);
}

/* [tool]: the instrument the client draws; each size optional */
static void test_tool_section(void **state)
{
    (void)state;
    ftm_scene *scene = parse_ok(MESH2D MAT "[tool]\ntip_radius = 0.004\nshaft_length = 0.12\n");
    ftm_scene_tool t = ftm_scene_get_tool(scene);
    assert_near(t.tip_radius, 0.004, 0);
    assert_near(t.shaft_length, 0.12, 0);
    assert_near(t.shaft_radius, 0, 0); /* not given: the client's own */
    ftm_scene_destroy(scene);
    scene = parse_ok(MESH2D MAT);
    t = ftm_scene_get_tool(scene);
    assert_true(t.tip_radius == 0 && t.shaft_radius == 0 && t.shaft_length == 0);
    ftm_scene_destroy(scene);
    expect_bad(MESH2D MAT "[tool]\ntip_radius = 0\n", 10, "tip_radius must be > 0, got 0");
    expect_bad(MESH2D MAT "[tool]\nshaft_length = 2\n", 10,
               "shaft_length must be at most 1 m, got 2");
    expect_bad(MESH2D MAT "[tool]\nshaft_radius = -1e-3\n", 10, "shaft_radius must be > 0");
    expect_bad(MESH2D MAT "[tool]\nlength = 0.1\n", 10, "length");
}

static void test_fem_section(void **state)
{
    (void)state;
    double e = -1, nu = -1, rho = -1;
    ftm_scene *scene = parse_ok(MESH2D MAT "[fem]\nyoung = 6e5\npoisson = 0.45\n"
                                           "density = 1060  # soft tissue\n");
    assert_true(ftm_scene_fem_material(scene, &e, &nu, &rho));
    assert_near(e, 6e5, 0);
    assert_near(nu, 0.45, 0);
    assert_near(rho, 1060, 0);
    assert_true(ftm_scene_fem_material(scene, NULL, NULL, NULL));
    ftm_scene_destroy(scene);
    /* density is optional (0 = not given); negative Poisson ratios are valid */
    scene = parse_ok("[fem]\npoisson = -0.2\nyoung = 1e3\n" MESH2D MAT);
    assert_true(ftm_scene_fem_material(scene, &e, &nu, &rho));
    assert_near(nu, -0.2, 0);
    assert_near(rho, 0, 0);
    ftm_scene_destroy(scene);
    /* no [fem]: false, outputs untouched */
    scene = parse_ok(MESH2D MAT);
    e = 7;
    assert_false(ftm_scene_fem_material(scene, &e, &nu, &rho));
    assert_near(e, 7, 0);
    ftm_scene_destroy(scene);

    expect_bad(MESH2D MAT "[fem]\nyoung = 6e5\npoisson = 0.5\n", 11,
               "poisson must be > -1 and < 0.5, got 0.5");
    expect_bad(MESH2D MAT "[fem]\nyoung = 6e5\npoisson = -1\n", 11,
               "poisson must be > -1 and < 0.5, got -1");
    expect_bad(MESH2D MAT "[fem]\nyoung = 0\npoisson = 0.3\n", 10, "young must be > 0, got 0");
    expect_bad(MESH2D MAT "[fem]\nyoung = -5\n", 10, "young must be > 0, got -5");
    expect_bad(MESH2D MAT "[fem]\nyoung = 1e5\npoisson = 0.3\ndensity = 0\n", 12,
               "density must be > 0");
    expect_bad(MESH2D MAT "[fem]\nyoung = 1e5\n", 9, "[fem] needs poisson");
    expect_bad(MESH2D MAT "[fem]\npoisson = 0.3\n", 9, "[fem] needs young");
    expect_bad(MESH2D MAT "[fem]\nyoung = 1e5\npoisson = 0.3 0.4\n", 11,
               "poisson: expected 1 value, got more");
    expect_bad(MESH2D MAT "[fem]\nyoung = 1e5\npoisson = nan\n", 11,
               "poisson: expected a finite number");
    expect_bad(MESH2D MAT "[fem]\nyoung = 1e5\nyoung = 2e5\n", 11, "duplicate key 'young'");
    expect_bad(MESH2D "[material]\nmass = 1\nstiffness = 1\npoisson = 0.3\n", 9,
               "unknown key 'poisson' in [material] (it belongs in [fem])");
    expect_bad(MESH2D MAT "[fem]\nyoung = 1e5\npoisson = 0.3\n[fem]\n", 12,
               "duplicate section [fem]");
    expect_bad(MESH2D MAT "[fem]\nstiffness = 3\n", 10,
               "unknown key 'stiffness' in [fem] (it belongs in [material])");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lattice3d_scene),
        cmocka_unit_test(test_lattice2d_scene_and_defaults),
        cmocka_unit_test(test_nearest_and_crlf),
        cmocka_unit_test(test_malformed),
        cmocka_unit_test(test_parse_length_is_respected),
        cmocka_unit_test(test_file_mesh),
        cmocka_unit_test(test_data_scenes),
        cmocka_unit_test(test_open_search),
        cmocka_unit_test(test_builtins),
        cmocka_unit_test(test_contacts_at),
        cmocka_unit_test(test_sequential_loads_same_node),
        cmocka_unit_test(test_fem_section),
        cmocka_unit_test(test_tool_section),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
