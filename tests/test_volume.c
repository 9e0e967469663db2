/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Volumes (paper section 4.2): the phantom, trilinear sampling, the control
 * lattice with air trimming and hard-tissue fixing, the FFD embedding, the
 * `head` built-in under a press, the NIfTI-1 reader on good and malformed
 * files, and [volume] scene sections. */
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

#ifdef FTM_TEST_NIFTI
#include <zlib.h>
#endif

/* Without libnifti, libftm refuses every NIfTI file: the tests that read
 * one are skipped (CI builds with it). */
#ifdef FTM_TEST_NIFTI
#define NEEDS_NIFTI() ((void)0)
#else
#define NEEDS_NIFTI() skip()
#endif

#define assert_near(a, b, eps) near_impl((a), (b), (eps), #a, __LINE__)

static void near_impl(double a, double b, double eps, const char *what, int line)
{
    if (!(fabs(a - b) <= eps))
        fail_msg("line %d: %s = %.17g, expected %.17g (+- %g)", line, what, a, b, eps);
}

#define assert_has(msg, part)                                                                     \
    do {                                                                                          \
        if (!strstr((msg), (part)))                                                               \
            fail_msg("line %d: message '%s' lacks '%s'", __LINE__, (msg), (part));              \
    } while (0)

static ftm_volume *phantom(int32_t voxels)
{
    ftm_volume_phantom_def d = ftm_default_volume_phantom_def();
    d.voxels = voxels;
    ftm_volume *v = NULL;
    ftm_error err;
    if (ftm_volume_phantom(&d, &v, &err) != FTM_OK)
        fail_msg("phantom: %s", err.message);
    return v;
}

/* Builds the control lattice of v; point_input may be NULL. */
static ftm_mesh *lattice(const ftm_volume *v, const ftm_volume_lattice_def *d, int32_t *point_input)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    if (ftm_generate_volume_lattice(b, v, d, point_input, &err) != FTM_OK)
        fail_msg("lattice: %s", err.message);
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    ftm_mesh *m = NULL;
    if (ftm_mesh_build(b, &bd, &m, &err) != FTM_OK)
        fail_msg("build: %s", err.message);
    ftm_mesh_builder_destroy(b);
    return m;
}

static int32_t count_fixed(const ftm_mesh *m)
{
    int32_t n = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++)
        n += ftm_mesh_fixed(m, i);
    return n;
}

/* ------------------------------------------------------------ phantom */

static void test_phantom(void **state)
{
    (void)state;
    ftm_volume *v = phantom(64);
    ftm_volume_info in = ftm_volume_get_info(v);
    assert_int_equal(in.nx, 64);
    assert_int_equal(in.ny, 64);
    assert_int_equal(in.nz, 64);
    assert_true(in.spacing.x == 0.2 / 64 && in.spacing.z == 0.2 / 64);
    assert_true(in.origin.x == 0 && in.origin.y == 0 && in.origin.z == 0);
    const uint8_t *d = ftm_volume_data(v);
#define AT(i, j, k) d[(i) + 64 * ((j) + 64 * (k))]
    assert_int_equal(AT(0, 0, 0), 0);       /* air in the corner */
    assert_int_equal(AT(32, 32, 32), 140);  /* brain at the centre */
    assert_int_equal(AT(32, 32, 55), 255);  /* skull above it */
    assert_int_equal(AT(32, 32, 58), 115);  /* scalp over the skull */
    assert_int_equal(AT(32, 32, 62), 0);    /* air above the head */
    assert_int_equal(AT(35, 32, 35), 51);   /* right ventricle */
    assert_int_equal(AT(28, 32, 35), 51);   /* left ventricle */
#undef AT
    /* a voxel centre samples its own value */
    ftm_vec3 c = {(32 + 0.5) * in.spacing.x, (32 + 0.5) * in.spacing.y, (55 + 0.5) * in.spacing.z};
    assert_near(ftm_volume_sample(v, c), 1.0, 1e-12);
    ftm_volume_destroy(v);

    ftm_volume_phantom_def pd = ftm_default_volume_phantom_def();
    ftm_error err;
    pd.voxels = 4;
    v = NULL;
    assert_int_equal(ftm_volume_phantom(&pd, &v, &err), FTM_EINVAL);
    assert_has(err.message, "voxels");
    assert_null(v);
    pd = ftm_default_volume_phantom_def();
    pd.size = -1;
    assert_int_equal(ftm_volume_phantom(&pd, &v, &err), FTM_EINVAL);
    assert_has(err.message, "size");
}

/* ------------------------------------------------------------ NIfTI writer */

typedef struct nii {
    int16_t dim[8];
    int16_t datatype, bitpix;
    float pixdim[8];
    float vox_offset, slope, inter;
    uint8_t units;
    char magic[4];
    bool big;
    int16_t qform_code, sform_code;
    float quatern[3], qoffset[3];
    float srow[3][4];
} nii;

static nii nii_default(int16_t nx, int16_t ny, int16_t nz, int16_t datatype, int16_t bitpix)
{
    nii h = {.dim = {3, nx, ny, nz, 1, 1, 1, 1},
             .datatype = datatype,
             .bitpix = bitpix,
             .pixdim = {1, 1, 1, 1, 0, 0, 0, 0},
             .vox_offset = 352,
             .units = 2,
             .magic = {'n', '+', '1', '\0'}};
    return h;
}

static void put(uint8_t *p, const void *v, int n, bool big)
{
    const uint8_t *s = v;
    for (int i = 0; i < n; i++)
        p[i] = big ? s[n - 1 - i] : s[i]; /* the host is little-endian (x86-64, arm64) */
}

/* Header + 4 zero bytes + voxel bytes (already in the file's byte order). */
static uint8_t *nii_bytes(const nii *h, const void *voxels, size_t vbytes, size_t *size)
{
    size_t off = (size_t)h->vox_offset;
    *size = off + vbytes;
    uint8_t *b = calloc(*size + 1, 1);
    int32_t sz = 348;
    put(b, &sz, 4, h->big);
    for (int i = 0; i < 8; i++)
        put(b + 40 + 2 * i, &h->dim[i], 2, h->big);
    put(b + 70, &h->datatype, 2, h->big);
    put(b + 72, &h->bitpix, 2, h->big);
    for (int i = 0; i < 8; i++)
        put(b + 76 + 4 * i, &h->pixdim[i], 4, h->big);
    put(b + 108, &h->vox_offset, 4, h->big);
    put(b + 112, &h->slope, 4, h->big);
    put(b + 116, &h->inter, 4, h->big);
    b[123] = h->units;
    put(b + 252, &h->qform_code, 2, h->big);
    put(b + 254, &h->sform_code, 2, h->big);
    for (int i = 0; i < 3; i++) {
        put(b + 256 + 4 * i, &h->quatern[i], 4, h->big);
        put(b + 268 + 4 * i, &h->qoffset[i], 4, h->big);
        for (int c = 0; c < 4; c++)
            put(b + 280 + 16 * i + 4 * c, &h->srow[i][c], 4, h->big);
    }
    memcpy(b + 344, h->magic, 4);
    memcpy(b + off, voxels, vbytes);
    return b;
}

static int parse(const uint8_t *b, size_t size, const ftm_volume_load_def *def, ftm_volume **v,
                 ftm_error *err)
{
    NEEDS_NIFTI();
    memset(err, 0, sizeof *err);
    *v = NULL;
    return ftm_volume_parse_nifti(b, size, "t.nii", def, v, err);
}

/* A 4 x 3 x 2 uint8 image 0..255, 0.25 m voxels: exact arithmetic. */
static ftm_volume *small_volume(void)
{
    uint8_t vox[24];
    for (int i = 0; i < 24; i++)
        vox[i] = (uint8_t)(i * 11 + (i == 23 ? 2 : 0)); /* 0 .. 255 */
    nii h = nii_default(4, 3, 2, 2, 8);
    h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 0.25f;
    h.units = 1; /* metres */
    size_t size;
    uint8_t *b = nii_bytes(&h, vox, sizeof vox, &size);
    ftm_volume_load_def def = ftm_default_volume_load_def();
    def.high_percentile = 100;
    ftm_volume *v;
    ftm_error err;
    if (parse(b, size, &def, &v, &err) != FTM_OK)
        fail_msg("%s", err.message);
    free(b);
    return v;
}

static void test_sample(void **state)
{
    (void)state;
    ftm_volume *v = small_volume();
    const uint8_t *d = ftm_volume_data(v);
    for (int i = 0; i < 24; i++)
        assert_int_equal(d[i], i * 11 + (i == 23 ? 2 : 0));
    /* exact at voxel centres */
    for (int k = 0; k < 2; k++)
        for (int j = 0; j < 3; j++)
            for (int i = 0; i < 4; i++) {
                ftm_vec3 c = {(i + 0.5) * 0.25, (j + 0.5) * 0.25, (k + 0.5) * 0.25};
                assert_true(ftm_volume_sample(v, c) == d[i + 4 * (j + 3 * k)] / 255.0);
            }
    /* trilinear between: halfway along x, then the centre of 8 voxels */
    assert_near(ftm_volume_sample(v, (ftm_vec3){0.25, 0.125, 0.125}), (d[0] + d[1]) / 510.0,
                1e-15);
    double mean = (d[0] + d[1] + d[4] + d[5] + d[12] + d[13] + d[16] + d[17]) / 8.0 / 255.0;
    assert_near(ftm_volume_sample(v, (ftm_vec3){0.25, 0.25, 0.25}), mean, 1e-15);
    /* the half voxel at a face takes the edge voxel; outside is 0 */
    assert_true(ftm_volume_sample(v, (ftm_vec3){0.0, 0.125, 0.125}) == d[0] / 255.0);
    assert_true(ftm_volume_sample(v, (ftm_vec3){1.0, 0.625, 0.375}) == d[23] / 255.0);
    assert_true(ftm_volume_sample(v, (ftm_vec3){1.0001, 0.625, 0.375}) == 0.0);
    assert_true(ftm_volume_sample(v, (ftm_vec3){-1e-9, 0.1, 0.1}) == 0.0);
    assert_true(ftm_volume_sample(v, (ftm_vec3){NAN, 0.1, 0.1}) == 0.0);
    ftm_volume_destroy(v);
}

/* ------------------------------------------------------------ lattice */

static void test_lattice_whole_box(void **state)
{
    (void)state;
    ftm_volume *v = phantom(32);
    ftm_volume_lattice_def d = ftm_default_volume_lattice_def();
    d.air_threshold = 0;  /* keeps every cell */
    d.hard_threshold = 2; /* fixes none */
    int32_t pi[1000];
    ftm_mesh *m = lattice(v, &d, pi);
    assert_int_equal(ftm_mesh_node_count(m), 1000);
    assert_int_equal(ftm_mesh_hexahedron_count(m), 729);
    assert_int_equal(count_fixed(m), 0);
    for (int i = 0; i < 1000; i++)
        assert_int_equal(pi[i], i);
    /* the same links, stiffness and surface as a lattice3d of that size */
    ftm_lattice3d_def l = ftm_default_lattice3d_def();
    l.spacing = (ftm_vec3){0.2 / 9, 0.2 / 9, 0.2 / 9};
    l.stencil = FTM_STENCIL_18;
    l.fixed_faces = 0;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    assert_int_equal(ftm_generate_lattice3d(b, &l, &err), FTM_OK);
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    ftm_mesh *ref = NULL;
    assert_int_equal(ftm_mesh_build(b, &bd, &ref, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    assert_int_equal(ftm_mesh_link_count(m), 7560);
    assert_int_equal(ftm_mesh_link_count(m), ftm_mesh_link_count(ref));
    assert_int_equal(ftm_mesh_triangle_count(m), 6 * 81 * 2);
    assert_int_equal(ftm_mesh_triangle_count(m), ftm_mesh_triangle_count(ref));
    for (int32_t i = 0; i < 1000; i++) {
        ftm_vec3 a = ftm_mesh_rest_position(m, ftm_mesh_node_of_input(m, i));
        ftm_vec3 r = ftm_mesh_rest_position(ref, ftm_mesh_node_of_input(ref, i));
        assert_near(a.x, r.x, 1e-15);
        assert_near(a.y, r.y, 1e-15);
        assert_near(a.z, r.z, 1e-15);
    }
    ftm_mesh_destroy(ref);
    ftm_mesh_destroy(m);

    /* fixed faces as in scenes */
    d.fixed_faces = FTM_FACE_ZMIN;
    m = lattice(v, &d, NULL);
    assert_int_equal(count_fixed(m), 100);
    ftm_mesh_destroy(m);
    ftm_volume_destroy(v);
}

/* Ellipsoidal radius of a point in the phantom (volume.c's geometry). */
static double head_radius(ftm_vec3 p)
{
    double x = (p.x - 0.1) / 0.1 / 0.70, y = (p.y - 0.1) / 0.1 / 0.82, z = (p.z - 0.1) / 0.1 / 0.86;
    return sqrt(x * x + y * y + z * z);
}

static void test_lattice_air_and_skull(void **state)
{
    (void)state;
    ftm_volume *v = phantom(64);
    ftm_volume_lattice_def d = ftm_default_volume_lattice_def();
    d.hard_threshold = 0.62;
    int32_t pi[1000];
    ftm_mesh *m = lattice(v, &d, pi);
    int32_t n = ftm_mesh_node_count(m);
    assert_true(n > 200 && n < 1000);
    assert_true(ftm_mesh_hexahedron_count(m) < 729);
    assert_true(ftm_mesh_triangle_count(m) > 0);
    /* the box's corners are air */
    assert_int_equal(pi[0], -1);
    assert_int_equal(pi[999], -1);
    assert_true(pi[5 + 10 * (5 + 10 * 5)] >= 0);
    /* links only within a cell: no longer than a cell's face diagonal */
    double cell = 0.2 / 9;
    for (int32_t i = 0; i < ftm_mesh_link_count(m); i++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, i, &a, &b, &k, &len);
        assert_true(len <= cell * sqrt(2.0) * (1 + 1e-12));
    }
    /* every triangle vertex a node, every node linked */
    const int32_t *tri = ftm_mesh_triangles(m);
    for (int32_t i = 0; i < 3 * ftm_mesh_triangle_count(m); i++)
        assert_true(tri[i] >= 0 && tri[i] < n);
    for (int32_t i = 0; i < n; i++)
        assert_true(ftm_mesh_neighbors(m, i, NULL, NULL, NULL) > 0);
    /* fixed nodes lie in the skull's band (0.80 < r <= 0.92, give or take
     * the half cell they average over), none in the brain or the scalp's air */
    int32_t fixed = 0;
    for (int32_t i = 0; i < n; i++) {
        double r = head_radius(ftm_mesh_rest_position(m, i));
        if (ftm_mesh_fixed(m, i)) {
            fixed++;
            if (!(r > 0.55 && r < 1.1))
                fail_msg("fixed node %d at radius %g", i, r);
        }
        if (r < 0.5)
            assert_false(ftm_mesh_fixed(m, i));
    }
    assert_true(fixed > 20);
    ftm_mesh_destroy(m);

    /* the default hard threshold: the skull is thinner than a cell */
    d = ftm_default_volume_lattice_def();
    m = lattice(v, &d, NULL);
    assert_int_equal(count_fixed(m), 0);
    ftm_mesh_destroy(m);

    /* errors */
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    d.air_threshold = 2;
    assert_int_equal(ftm_generate_volume_lattice(b, v, &d, NULL, &err), FTM_EINVAL);
    assert_has(err.message, "air");
    d = ftm_default_volume_lattice_def();
    d.nodes[1] = 1;
    assert_int_equal(ftm_generate_volume_lattice(b, v, &d, NULL, &err), FTM_EINVAL);
    assert_has(err.message, "nodes along y");
    d = ftm_default_volume_lattice_def();
    d.stencil = (ftm_stencil)7;
    assert_int_equal(ftm_generate_volume_lattice(b, v, &d, NULL, &err), FTM_EINVAL);
    d = ftm_default_volume_lattice_def();
    d.material.node_mass = -1;
    assert_int_equal(ftm_generate_volume_lattice(b, v, &d, NULL, &err), FTM_EINVAL);
    assert_int_equal(ftm_mesh_builder_node_count(b), 0);
    ftm_mesh_builder_destroy(b);
    ftm_volume_destroy(v);
}

/* ------------------------------------------------------------ FFD */

static uint64_t rng = 88172645463325252ull;

static double uniform(void) /* [0, 1), deterministic */
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

typedef struct embed {
    ftm_volume *v;
    ftm_mesh *m;
    ftm_ffd *ffd;
    double *pos;
} embed;

static embed make_embed(double air)
{
    embed e;
    e.v = phantom(32);
    ftm_volume_lattice_def d = ftm_default_volume_lattice_def();
    d.nodes[0] = 5;
    d.nodes[1] = 6;
    d.nodes[2] = 7;
    d.air_threshold = air;
    int32_t pi[5 * 6 * 7];
    e.m = lattice(e.v, &d, pi);
    for (int i = 0; i < 5 * 6 * 7; i++)
        pi[i] = pi[i] < 0 ? -1 : ftm_mesh_node_of_input(e.m, pi[i]);
    ftm_error err;
    if (ftm_ffd_create(e.m, e.v, d.nodes, pi, &e.ffd, &err) != FTM_OK)
        fail_msg("ffd: %s", err.message);
    int32_t n = ftm_mesh_node_count(e.m);
    e.pos = malloc(3 * (size_t)n * sizeof *e.pos);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 r = ftm_mesh_rest_position(e.m, i);
        e.pos[3 * i] = r.x;
        e.pos[3 * i + 1] = r.y;
        e.pos[3 * i + 2] = r.z;
    }
    return e;
}

static void free_embed(embed *e)
{
    free(e->pos);
    ftm_ffd_destroy(e->ffd);
    ftm_mesh_destroy(e->m);
    ftm_volume_destroy(e->v);
}

static ftm_vec3 random_point(double margin)
{
    return (ftm_vec3){-margin + (0.2 + 2 * margin) * uniform(),
                      -margin + (0.2 + 2 * margin) * uniform(),
                      -margin + (0.2 + 2 * margin) * uniform()};
}

static void test_ffd_identity_and_affine(void **state)
{
    (void)state;
    embed e = make_embed(0.0);
    int32_t nodes[3];
    ftm_ffd_nodes(e.ffd, nodes);
    assert_true(nodes[0] == 5 && nodes[1] == 6 && nodes[2] == 7);
    ftm_vec3 r = ftm_ffd_point_rest(e.ffd, 4, 5, 6);
    assert_near(r.x, 0.2, 1e-15);
    assert_near(r.z, 0.2, 1e-15);
    assert_true(ftm_ffd_point_node(e.ffd, 0, 0, 0) >= 0);
    assert_int_equal(ftm_ffd_point_node(e.ffd, 5, 0, 0), -1);
    /* at rest every point maps to itself, bit for bit, inside and outside */
    for (int i = 0; i < 2000; i++) {
        ftm_vec3 x = random_point(0.05);
        ftm_vec3 p = ftm_ffd_map(e.ffd, e.pos, x);
        assert_true(p.x == x.x && p.y == x.y && p.z == x.z);
    }
    /* an affine displacement of the nodes is reproduced inside the box */
    const double A[3][3] = {{0.01, -0.02, 0.005}, {0.03, 0.0, -0.01}, {-0.015, 0.02, 0.025}};
    const double t[3] = {0.001, -0.002, 0.0005};
    int32_t n = ftm_mesh_node_count(e.m);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 x = ftm_mesh_rest_position(e.m, i);
        double X[3] = {x.x, x.y, x.z};
        for (int a = 0; a < 3; a++)
            e.pos[3 * i + a] = X[a] + A[a][0] * X[0] + A[a][1] * X[1] + A[a][2] * X[2] + t[a];
    }
    for (int i = 0; i < 2000; i++) {
        ftm_vec3 x = random_point(0.0);
        double X[3] = {x.x, x.y, x.z}, want[3];
        for (int a = 0; a < 3; a++)
            want[a] = X[a] + A[a][0] * X[0] + A[a][1] * X[1] + A[a][2] * X[2] + t[a];
        ftm_vec3 p = ftm_ffd_map(e.ffd, e.pos, x);
        assert_near(p.x, want[0], 1e-15);
        assert_near(p.y, want[1], 1e-15);
        assert_near(p.z, want[2], 1e-15);
        /* and undone */
        ftm_vec3 back = ftm_ffd_unmap(e.ffd, e.pos, p, 30);
        assert_near(back.x, x.x, 1e-13);
        assert_near(back.y, x.y, 1e-13);
        assert_near(back.z, x.z, 1e-13);
    }
    free_embed(&e);
}

static void test_ffd_continuity_and_unmap(void **state)
{
    (void)state;
    embed e = make_embed(0.05); /* air trimmed: missing corners stay put */
    int32_t n = ftm_mesh_node_count(e.m);
    for (int32_t i = 0; i < 3 * n; i++)
        e.pos[i] += 0.002 * (uniform() - 0.5);
    /* across the faces x = cell 1|2, y = 2|3, z = 3|4 */
    const double cx = 0.2 / 4 * 2, cy = 0.2 / 5 * 3, cz = 0.2 / 6 * 4;
    for (int i = 0; i < 200; i++) {
        ftm_vec3 x = random_point(0.0);
        ftm_vec3 lo = x, hi = x;
        int axis = i % 3;
        double at = axis == 0 ? cx : axis == 1 ? cy : cz;
        double *pl = axis == 0 ? &lo.x : axis == 1 ? &lo.y : &lo.z;
        double *ph = axis == 0 ? &hi.x : axis == 1 ? &hi.y : &hi.z;
        *pl = at - 1e-12;
        *ph = at + 1e-12;
        ftm_vec3 a = ftm_ffd_map(e.ffd, e.pos, lo), b = ftm_ffd_map(e.ffd, e.pos, hi);
        assert_near(a.x, b.x, 1e-11);
        assert_near(a.y, b.y, 1e-11);
        assert_near(a.z, b.z, 1e-11);
    }
    /* unmap(map(X)) = X for small displacements */
    for (int i = 0; i < 500; i++) {
        ftm_vec3 x = random_point(0.0);
        ftm_vec3 p = ftm_ffd_map(e.ffd, e.pos, x);
        ftm_vec3 back = ftm_ffd_unmap(e.ffd, e.pos, p, 0);
        assert_near(back.x, x.x, 1e-9);
        assert_near(back.y, x.y, 1e-9);
        assert_near(back.z, x.z, 1e-9);
    }
    /* bad embeddings */
    int32_t bad[5 * 6 * 7];
    for (int i = 0; i < 5 * 6 * 7; i++)
        bad[i] = -1;
    bad[3] = n; /* out of range */
    int32_t nodes[3] = {5, 6, 7};
    ftm_ffd *f = NULL;
    ftm_error err;
    assert_int_equal(ftm_ffd_create(e.m, e.v, nodes, bad, &f, &err), FTM_EINVAL);
    assert_has(err.message, "(3, 0, 0)");
    bad[3] = ftm_ffd_point_node(e.ffd, 2, 2, 2); /* a node somewhere else */
    assert_int_equal(ftm_ffd_create(e.m, e.v, nodes, bad, &f, &err), FTM_EINVAL);
    assert_null(f);
    free_embed(&e);
}

/* ------------------------------------------------------------ head */

static void count_warnings(void *user, ftm_log_level level, const char *message)
{
    (void)message;
    if (level >= FTM_LOG_WARN)
        ++*(int *)user;
}

static void test_head_press(void **state)
{
    (void)state;
    ftm_scene *scene = NULL;
    ftm_error err;
    if (ftm_scene_open("head", &scene, &err) != FTM_OK)
        fail_msg("%s", err.message);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    const ftm_ffd *ffd = ftm_scene_ffd(scene);
    assert_non_null(ftm_scene_volume(scene));
    assert_non_null(ffd);
    int32_t n = ftm_mesh_node_count(m);
    assert_true(count_fixed(m) > 20);
    ftm_sim_def sd = ftm_scene_sim_def(scene);
    assert_true(sd.time_step == 1e-3);
    int warnings = 0;
    sd.log = count_warnings;
    sd.log_user = &warnings;
    ftm_sim *sim = NULL;
    if (ftm_sim_create(m, &sd, &sim, &err) != FTM_OK)
        fail_msg("%s", err.message);
    assert_int_equal(warnings, 0); /* stable at h = 1 ms: no warning */
    assert_int_equal(ftm_scene_load_count(scene), 1);
    const ftm_scene_load *load = ftm_scene_loads(scene);
    int32_t probe = load[0].contact.node;
    ftm_vec3 top = ftm_mesh_rest_position(m, probe);
    assert_near(top.x, 0.1, 0.2 / 9);
    assert_near(top.y, 0.1, 0.2 / 9);
    /* the topmost lattice point (z = 0.2, a cell above the scalp) was
     * fitted onto the scalp (fit_surface): the probe meets the head */
    const double scalp_z = 0.1 + 0.96 * 0.086;
    assert_true(top.z < 0.2 - 0.5 * 0.2 / 9);
    assert_near(top.z, scalp_z, 0.004); /* the image is smooth: 0.05 a little above */
    assert_true(ftm_volume_sample(ftm_scene_volume(scene), top) >= 0.05);
    /* a point of scalp below the probe */
    ftm_vec3 scalp = {top.x, top.y, scalp_z};
    double max_moved = 0;
    for (int step = 0; step < 400; step++) {
        ftm_contact c[4];
        int32_t k = ftm_scene_contacts_at(scene, step * sd.time_step, c, 4);
        assert_int_equal(ftm_sim_set_contacts(sim, c, k, &err), FTM_OK);
        assert_int_equal(ftm_sim_step(sim), FTM_OK);
        const double *x = ftm_sim_positions(sim);
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 r = ftm_mesh_rest_position(m, i);
            double d = fabs(x[3 * i] - r.x) + fabs(x[3 * i + 1] - r.y) + fabs(x[3 * i + 2] - r.z);
            if (ftm_mesh_fixed(m, i) && d != 0)
                fail_msg("fixed node %d moved by %g at step %d", i, d, step);
            if (i != probe && d > max_moved)
                max_moved = d;
        }
    }
    const double *x = ftm_sim_positions(sim);
    assert_near(x[3 * probe + 2], top.z - 0.005, 1e-12);
    assert_true(max_moved > 1e-4); /* the probe's neighbours follow */
    /* the image follows the lattice: the scalp under the probe goes down */
    ftm_vec3 p = ftm_ffd_map(ffd, x, scalp);
    assert_true(p.z < scalp.z - 1e-4);
    ftm_sim_destroy(sim);
    ftm_scene_destroy(scene);
}

/* ------------------------------------------------------------ NIfTI */

static void test_nifti_good(void **state)
{
    (void)state;
    ftm_volume *v;
    ftm_error err;
    /* uint8, mm */
    uint8_t u8[8] = {0, 10, 20, 30, 40, 50, 60, 200};
    nii h = nii_default(2, 2, 2, 2, 8);
    h.pixdim[1] = 2, h.pixdim[2] = 3, h.pixdim[3] = 4;
    size_t size;
    uint8_t *b = nii_bytes(&h, u8, sizeof u8, &size);
    ftm_volume_load_def def = ftm_default_volume_load_def();
    def.high_percentile = 100;
    def.scale = 2;
    def.origin = (ftm_vec3){1, 2, 3};
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    ftm_volume_info in = ftm_volume_get_info(v);
    assert_true(in.nx == 2 && in.ny == 2 && in.nz == 2);
    assert_near(in.spacing.x, 0.004, 1e-15);
    assert_near(in.spacing.y, 0.006, 1e-15);
    assert_near(in.spacing.z, 0.008, 1e-15);
    assert_true(in.origin.x == 1 && in.origin.z == 3);
    const uint8_t *d = ftm_volume_data(v);
    assert_int_equal(d[0], 0);
    assert_int_equal(d[7], 255);
    assert_int_equal(d[1], (int)floor(10 / 200.0 * 255 + 0.5));
    ftm_volume_destroy(v);
    /* the default window (99.5th percentile) with one hot voxel out of 1000:
     * the rest spans the full range */
    {
        uint8_t many[1000];
        for (int i = 0; i < 1000; i++)
            many[i] = (uint8_t)(i % 100);
        many[500] = 255;
        nii hm = nii_default(10, 10, 10, 2, 8);
        uint8_t *bm = nii_bytes(&hm, many, sizeof many, &size);
        assert_int_equal(parse(bm, size, NULL, &v, &err), FTM_OK);
        assert_int_equal(ftm_volume_data(v)[500], 255);
        assert_true(ftm_volume_data(v)[99] >= 250); /* 99 is near the window's top */
        assert_int_equal(ftm_volume_data(v)[0], 0);
        ftm_volume_destroy(v);
        free(bm);
    }
    free(b);

    /* int16, big-endian, metres */
    int16_t s16[6] = {-100, 0, 100, 200, 300, 400};
    uint8_t be[12];
    for (int i = 0; i < 6; i++)
        put(be + 2 * i, &s16[i], 2, true);
    h = nii_default(3, 2, 1, 4, 16);
    h.big = true;
    h.units = 1;
    h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 0.5f;
    b = nii_bytes(&h, be, sizeof be, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    in = ftm_volume_get_info(v);
    assert_true(in.nx == 3 && in.ny == 2 && in.nz == 1);
    assert_near(in.spacing.x, 1.0, 0); /* 0.5 m times scale 2 */
    d = ftm_volume_data(v);
    assert_int_equal(d[0], 0);
    assert_int_equal(d[1], (int)floor(100 / 500.0 * 255 + 0.5));
    assert_int_equal(d[5], 255);
    ftm_volume_destroy(v);
    free(b);

    /* float32 with scl_slope / scl_inter, microns: the slope flips the order */
    float f32[4] = {1.0f, 2.0f, 3.0f, 5.0f};
    h = nii_default(4, 1, 1, 16, 32);
    h.dim[0] = 4; /* 4D with one time point */
    h.slope = -2.0f;
    h.inter = 10.0f;
    h.units = 3;
    h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 500;
    b = nii_bytes(&h, f32, sizeof f32, &size);
    def = ftm_default_volume_load_def();
    def.high_percentile = 100;
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    in = ftm_volume_get_info(v);
    assert_near(in.spacing.x, 5e-4, 1e-18);
    d = ftm_volume_data(v); /* values 8, 6, 4, 0 */
    assert_int_equal(d[0], 255);
    assert_int_equal(d[1], (int)floor(6 / 8.0 * 255 + 0.5));
    assert_int_equal(d[3], 0);
    ftm_volume_destroy(v);
    free(b);

    /* slope 0 means no scaling; unset units are mm */
    h = nii_default(4, 1, 1, 16, 32);
    h.units = 0;
    b = nii_bytes(&h, f32, sizeof f32, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    assert_near(ftm_volume_get_info(v).spacing.x, 1e-3, 1e-18);
    assert_int_equal(ftm_volume_data(v)[0], 0);
    assert_int_equal(ftm_volume_data(v)[3], 255);
    ftm_volume_destroy(v);
    free(b);
}

/* NIfTI-2: the same image with a 540-byte header (int64 dims, doubles),
 * voxels from byte 544; sform as given (code 0: none). */
static uint8_t *nii2_bytes(const nii *h, const void *voxels, size_t vbytes, size_t *size)
{
    const size_t off = 544;
    *size = off + vbytes;
    uint8_t *b = calloc(*size + 1, 1);
    int32_t sz = 540;
    put(b, &sz, 4, h->big);
    memcpy(b + 4, "n+2\0\r\n\032\n", 8);
    put(b + 12, &h->datatype, 2, h->big);
    put(b + 14, &h->bitpix, 2, h->big);
    for (int i = 0; i < 8; i++) {
        int64_t d = h->dim[i];
        double p = h->pixdim[i];
        put(b + 16 + 8 * i, &d, 8, h->big);
        put(b + 104 + 8 * i, &p, 8, h->big);
    }
    int64_t o = (int64_t)off;
    put(b + 168, &o, 8, h->big);
    int32_t units = h->units, sform = h->sform_code;
    put(b + 348, &sform, 4, h->big);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 4; c++) {
            double v = h->srow[r][c];
            put(b + 400 + 32 * r + 8 * c, &v, 8, h->big);
        }
    put(b + 500, &units, 4, h->big);
    memcpy(b + off, voxels, vbytes);
    return b;
}

/* The image's axes: the sform or qform placed onto the world (RAS) axes, or
 * the stored ones. */
static void test_nifti_orientation(void **state)
{
    (void)state;
    /* 3 x 2 x 2 voxels, value = file index */
    uint8_t u8[12];
    for (int i = 0; i < 12; i++)
        u8[i] = (uint8_t)(20 * i);
    nii h = nii_default(3, 2, 2, 2, 8);
    h.pixdim[1] = 2, h.pixdim[2] = 1, h.pixdim[3] = 3; /* mm */
    /* sform: x = 10 - 2 i, y = 20 + 3 k, z = j - 5 (mm) */
    h.sform_code = 1;
    h.srow[0][0] = -2, h.srow[0][3] = 10;
    h.srow[1][2] = 3, h.srow[1][3] = 20;
    h.srow[2][1] = 1, h.srow[2][3] = -5;
    size_t size;
    uint8_t *b = nii_bytes(&h, u8, sizeof u8, &size);
    ftm_volume_load_def def = ftm_default_volume_load_def();
    def.high_percentile = 100;
    ftm_volume *v;
    ftm_error err;
    if (parse(b, size, &def, &v, &err) != FTM_OK)
        fail_msg("%s", err.message);
    ftm_volume_info in = ftm_volume_get_info(v);
    assert_true(in.nx == 3 && in.ny == 2 && in.nz == 2);
    assert_near(in.spacing.x, 0.002, 1e-15);
    assert_near(in.spacing.y, 0.003, 1e-15);
    assert_near(in.spacing.z, 0.001, 1e-15);
    /* the box: the smallest voxel centre less half a voxel */
    assert_near(in.origin.x, 0.005, 1e-15);   /* 6 - 1 mm */
    assert_near(in.origin.y, 0.0185, 1e-15);  /* 20 - 1.5 mm */
    assert_near(in.origin.z, -0.0055, 1e-15); /* -5 - 0.5 mm */
    /* grid voxel (x, y, z) is file voxel (2 - x, z, y) */
    const uint8_t *d = ftm_volume_data(v);
    for (int z = 0; z < 2; z++)
        for (int y = 0; y < 2; y++)
            for (int x = 0; x < 3; x++) {
                int file = (2 - x) + 3 * (z + 2 * y);
                assert_int_equal(d[x + 3 * (y + 2 * z)], (int)floor(file * 20 / 220.0 * 255 + 0.5));
            }
    /* the voxel at a world point is the one the sform puts there:
     * file voxel (0, 1, 1), index 9, at x = 10, y = 23, z = -4 mm */
    assert_near(ftm_volume_sample(v, (ftm_vec3){0.010, 0.023, -0.004}),
                floor(9 * 20 / 220.0 * 255 + 0.5) / 255, 1e-12);
    ftm_volume_destroy(v);
    /* scale and origin: every length scaled, then shifted */
    def.scale = 2;
    def.origin = (ftm_vec3){1, 0, 0};
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    in = ftm_volume_get_info(v);
    assert_near(in.origin.x, 1.010, 1e-15);
    assert_near(in.spacing.y, 0.006, 1e-15);
    ftm_volume_destroy(v);
    /* stored axes: as before orientation existed */
    def = ftm_default_volume_load_def();
    def.axes = FTM_VOLUME_AXES_STORED;
    def.origin = (ftm_vec3){1, 2, 3};
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    in = ftm_volume_get_info(v);
    assert_true(in.nx == 3 && in.ny == 2 && in.nz == 2);
    assert_near(in.spacing.z, 0.003, 1e-15);
    assert_true(in.origin.x == 1 && in.origin.y == 2 && in.origin.z == 3);
    ftm_volume_destroy(v);
    free(b);

    /* qform: 180 degrees about z (quaternion d = 1), offset (100, 50, 0) */
    h.sform_code = 0;
    h.qform_code = 1;
    h.quatern[2] = 1;
    h.qoffset[0] = 100, h.qoffset[1] = 50;
    b = nii_bytes(&h, u8, sizeof u8, &size);
    def = ftm_default_volume_load_def();
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    in = ftm_volume_get_info(v);
    assert_true(in.nx == 3 && in.ny == 2 && in.nz == 2);
    assert_near(in.origin.x, 0.095, 1e-12);  /* 100 - 2 (3 - 1) - 1 mm */
    assert_near(in.origin.y, 0.0485, 1e-12); /* 50 - 1 - 0.5 */
    assert_near(in.origin.z, -0.0015, 1e-12);
    ftm_volume_destroy(v);
    free(b);
    /* qfac = -1 (pixdim[0]) flips k */
    h.pixdim[0] = -1;
    b = nii_bytes(&h, u8, sizeof u8, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    assert_near(ftm_volume_get_info(v).origin.z, -0.0045, 1e-12); /* -3 (2 - 1) - 1.5 */
    ftm_volume_destroy(v);
    free(b);
    /* the sform wins over the qform */
    h.sform_code = 2;
    b = nii_bytes(&h, u8, sizeof u8, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    assert_near(ftm_volume_get_info(v).origin.x, 0.005, 1e-15);
    ftm_volume_destroy(v);
    free(b);

    /* refused: an oblique sform (10 degrees about z), odd codes, NaN rows */
    h = nii_default(3, 2, 2, 2, 8);
    h.sform_code = 1;
    h.srow[0][0] = (float)cos(0.17453292519943295), h.srow[0][1] = (float)-sin(0.17453292519943295);
    h.srow[1][0] = (float)sin(0.17453292519943295), h.srow[1][1] = (float)cos(0.17453292519943295);
    h.srow[2][2] = 1;
    b = nii_bytes(&h, u8, sizeof u8, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_EPARSE);
    assert_has(err.message, "t.nii: the sform (srow_x/y/z) is oblique: voxel axis 0 is 10.00 degrees");
    def.axes = FTM_VOLUME_AXES_STORED; /* read as stored: fine */
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_OK);
    ftm_volume_destroy(v);
    def.axes = FTM_VOLUME_AXES_SCANNER;
    free(b);
    h.srow[0][1] = 0, h.srow[1][0] = 0, h.srow[0][0] = 1, h.srow[1][1] = 1;
    h.sform_code = 9;
    b = nii_bytes(&h, u8, sizeof u8, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_EPARSE);
    assert_has(err.message, "sform_code = 9");
    free(b);
    h.sform_code = 1;
    h.srow[1][3] = NAN;
    b = nii_bytes(&h, u8, sizeof u8, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_EPARSE);
    assert_has(err.message, "srow_y[3] = nan is not finite");
    free(b);
    h.srow[1][3] = 0;
    h.srow[1][1] = 0, h.srow[0][1] = 1; /* voxel axes i and j both along x */
    b = nii_bytes(&h, u8, sizeof u8, &size);
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_EPARSE);
    assert_has(err.message, "no three distinct directions");
    free(b);
}

/* NIfTI-2, and uint32 voxels */
static void test_nifti2(void **state)
{
    (void)state;
    uint32_t u32[8] = {0, 1, 2, 3, 4, 5, 6, 4000000000u};
    nii h = nii_default(2, 2, 2, 768, 32);
    h.pixdim[1] = 0.5;
    h.sform_code = 1;
    h.srow[0][0] = 0.5, h.srow[1][1] = 1, h.srow[2][2] = -1, h.srow[2][3] = 7;
    for (int big = 0; big < 2; big++) {
        h.big = big;
        uint8_t vox[32];
        for (int i = 0; i < 8; i++)
            put(vox + 4 * i, &u32[i], 4, h.big);
        size_t size;
        uint8_t *b = nii2_bytes(&h, vox, sizeof vox, &size);
        ftm_volume_load_def def = ftm_default_volume_load_def();
        def.high_percentile = 100;
        ftm_volume *v;
        ftm_error err;
        if (parse(b, size, &def, &v, &err) != FTM_OK)
            fail_msg("%s", err.message);
        ftm_volume_info in = ftm_volume_get_info(v);
        assert_true(in.nx == 2 && in.ny == 2 && in.nz == 2);
        assert_near(in.spacing.x, 0.0005, 1e-18);
        assert_near(in.origin.z, 0.0055, 1e-15); /* 7 - 1 - 0.5 mm */
        /* z flipped: grid (1, 1, 0) is file (1, 1, 1) = 4e9, the brightest */
        assert_int_equal(ftm_volume_data(v)[3], 255);
        assert_int_equal(ftm_volume_data(v)[7], 0);
        ftm_volume_destroy(v);
        /* a NIfTI-2 cut inside its header, and a .hdr/.img pair */
        assert_int_equal(parse(b, 300, &def, &v, &err), FTM_EPARSE);
        assert_has(err.message, "t.nii: truncated header: 300 bytes, a NIfTI-2 header has 540");
        memcpy(b + 4, "ni2", 3);
        assert_int_equal(parse(b, size, &def, &v, &err), FTM_EPARSE);
        assert_has(err.message, "magic at byte 4 is \"ni2\"");
        free(b);
    }
}

static char tmpdir[] = "/tmp/ftm-test-volume-XXXXXX";

static const char *write_file(const char *name, const void *data, size_t size)
{
    static char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, size, f), size);
    fclose(f);
    return path;
}

/* Label maps: the same files, whole numbers kept as they are */
static void test_label_map(void **state)
{
    (void)state;
    NEEDS_NIFTI();
    /* int16 labels on 3 x 2 x 2 voxels, the sform of test_nifti_orientation */
    int16_t lab[12] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, -7};
    nii h = nii_default(3, 2, 2, 4, 16);
    h.pixdim[1] = 2, h.pixdim[2] = 1, h.pixdim[3] = 3;
    h.sform_code = 1;
    h.srow[0][0] = -2, h.srow[0][3] = 10;
    h.srow[1][2] = 3, h.srow[1][3] = 20;
    h.srow[2][1] = 1, h.srow[2][3] = -5;
    size_t size;
    uint8_t *b = nii_bytes(&h, lab, sizeof lab, &size);
    ftm_label_map *m = NULL;
    ftm_error err;
    if (ftm_label_map_parse_nifti(b, size, "l.nii", NULL, &m, &err) != FTM_OK)
        fail_msg("%s", err.message);
    ftm_volume_info in = ftm_label_map_get_info(m);
    assert_true(in.nx == 3 && in.ny == 2 && in.nz == 2);
    assert_near(in.origin.y, 0.0185, 1e-15);
    const int32_t *d = ftm_label_map_data(m);
    for (int z = 0; z < 2; z++)
        for (int y = 0; y < 2; y++)
            for (int x = 0; x < 3; x++)
                assert_int_equal(d[x + 3 * (y + 2 * z)], lab[(2 - x) + 3 * (z + 2 * y)]);
    /* world points: file voxel (0, 1, 1) = label 9 at (10, 23, -4) mm */
    assert_int_equal(ftm_label_map_at(m, (ftm_vec3){0.010, 0.023, -0.004}), 9);
    assert_int_equal(ftm_label_map_at(m, (ftm_vec3){0.0091, 0.0216, -0.0036}), 9);
    assert_int_equal(ftm_label_map_at(m, (ftm_vec3){0.0061, 0.0244, -0.0041}), -7);
    assert_int_equal(ftm_label_map_at(m, (ftm_vec3){0.0049, 0.023, -0.004}), 0); /* outside */
    assert_int_equal(ftm_label_map_at(m, (ftm_vec3){NAN, 0.023, -0.004}), 0);
    /* the file's voxel of a map's voxel: (2 - x, z, y) */
    int32_t ijk[3];
    assert_int_equal(ftm_label_map_file_voxel(m, 0, 1, 0, ijk), FTM_OK);
    assert_true(ijk[0] == 2 && ijk[1] == 0 && ijk[2] == 1);
    assert_int_equal(ftm_label_map_file_voxel(m, 3, 0, 0, ijk), FTM_ERANGE);
    ftm_label_map_destroy(m);
    free(b);

    /* from a file, gzip-compressed or not: the same reader as volumes */
    b = nii_bytes(&h, lab, sizeof lab, &size);
    const char *path = write_file("labels.nii", b, size);
    assert_int_equal(ftm_label_map_load(path, NULL, &m, &err), FTM_OK);
    assert_int_equal(ftm_label_map_data(m)[0], 2);
    ftm_label_map_destroy(m);
    free(b);

    /* a mask from an intensity image: 1 above the threshold */
    float f32[8] = {0, 10, 20, 30, 40, 50, 60, 70};
    h = nii_default(2, 2, 2, 16, 32);
    b = nii_bytes(&h, f32, sizeof f32, &size);
    ftm_label_map_def def = ftm_default_label_map_def();
    def.threshold = true;
    def.above = 35;
    assert_int_equal(ftm_label_map_parse_nifti(b, size, "l.nii", &def, &m, &err), FTM_OK);
    for (int i = 0; i < 8; i++)
        assert_int_equal(ftm_label_map_data(m)[i], i >= 4);
    ftm_label_map_destroy(m);
    /* as labels, 10.5 is not one */
    f32[5] = 10.5f;
    free(b);
    b = nii_bytes(&h, f32, sizeof f32, &size);
    assert_int_equal(ftm_label_map_parse_nifti(b, size, "l.nii", NULL, &m, &err), FTM_EPARSE);
    assert_null(m);
    assert_has(err.message, "l.nii: voxel (1, 0, 1) at byte 372 is 10.5: not a label");
    free(b);
    /* scl_slope makes labels of reals, or reals of labels */
    f32[5] = 50;
    h.slope = 0.5f;
    b = nii_bytes(&h, f32, sizeof f32, &size);
    assert_int_equal(ftm_label_map_parse_nifti(b, size, "l.nii", NULL, &m, &err), FTM_OK);
    assert_int_equal(ftm_label_map_data(m)[7], 35);
    ftm_label_map_destroy(m);
    free(b);
    f32[1] = 3;
    b = nii_bytes(&h, f32, sizeof f32, &size);
    assert_int_equal(ftm_label_map_parse_nifti(b, size, "l.nii", NULL, &m, &err), FTM_EPARSE);
    assert_has(err.message, "is 1.5 after scl_slope/scl_inter: not a label");
    free(b);
    /* the header's errors are the volumes' */
    assert_int_equal(ftm_label_map_parse_nifti(lab, 10, "l.nii", NULL, &m, &err), FTM_EPARSE);
    assert_has(err.message, "l.nii: header field sizeof_hdr");
    def = ftm_default_label_map_def();
    def.scale = -1;
    assert_int_equal(ftm_label_map_parse_nifti(lab, 10, "l.nii", &def, &m, &err), FTM_EINVAL);
    assert_has(err.message, "scale");
}

static void test_nifti_files(void **state)
{
    (void)state;
    NEEDS_NIFTI();
    uint8_t u8[8] = {0, 10, 20, 30, 40, 50, 60, 200};
    nii h = nii_default(2, 2, 2, 2, 8);
    size_t size;
    uint8_t *b = nii_bytes(&h, u8, sizeof u8, &size);
    const char *path = write_file("good.nii", b, size);
    ftm_volume *v = NULL;
    ftm_error err;
    assert_int_equal(ftm_volume_load(path, NULL, &v, &err), FTM_OK);
    assert_int_equal(ftm_volume_get_info(v).nx, 2);
    ftm_volume_destroy(v);

    char missing[600];
    snprintf(missing, sizeof missing, "%s/none.nii", tmpdir);
    assert_int_equal(ftm_volume_load(missing, NULL, &v, &err), FTM_EIO);
    assert_has(err.message, "none.nii");

    /* gzip: a .nii.gz (zlib.h comes with libnifti's tests: without them the
     * test has skipped above, and this part need not compile) */
#ifdef FTM_TEST_NIFTI
    static const uint8_t gz_member[] = {0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3};
    {
        uLongf cap = compressBound((uLong)size) + 64;
        uint8_t *z = malloc(cap);
        z_stream zs;
        memset(&zs, 0, sizeof zs);
        assert_int_equal(deflateInit2(&zs, 9, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY),
                         Z_OK);
        zs.next_in = b;
        zs.avail_in = (uInt)size;
        zs.next_out = z;
        zs.avail_out = (uInt)cap;
        assert_int_equal(deflate(&zs, Z_FINISH), Z_STREAM_END);
        size_t zn = zs.total_out;
        deflateEnd(&zs);
        path = write_file("good.nii.gz", z, zn);
        assert_int_equal(ftm_volume_load(path, NULL, &v, &err), FTM_OK);
        assert_int_equal(ftm_volume_get_info(v).nz, 2);
        assert_int_equal(ftm_volume_data(v)[7], 255);
        ftm_volume_destroy(v);
        /* cut short: the parser names the truncation */
        path = write_file("short.nii.gz", z, zn / 2);
        assert_true(ftm_volume_load(path, NULL, &v, &err) < 0);
        assert_has(err.message, "short.nii.gz");
        free(z);
    }
    /* not deflate data after a gzip header */
    uint8_t junk[64];
    memcpy(junk, gz_member, sizeof gz_member);
    memset(junk + sizeof gz_member, 0xff, sizeof junk - sizeof gz_member);
    path = write_file("junk.nii.gz", junk, sizeof junk);
    assert_int_equal(ftm_volume_load(path, NULL, &v, &err), FTM_EPARSE);
    assert_has(err.message, "junk.nii.gz");
    /* named once: zlib's own message starts with the path too */
    const char *first = strstr(err.message, "junk.nii.gz");
    if (strstr(first + 1, "junk.nii.gz"))
        fail_msg("the path twice: %s", err.message);
#endif
    free(b);
}

static void expect_bad(const uint8_t *b, size_t size, const char *part, int line)
{
    ftm_volume *v;
    ftm_error err;
    int rc = parse(b, size, NULL, &v, &err);
    if (rc != FTM_EPARSE && rc != FTM_EINVAL)
        fail_msg("line %d: rc %d (%s)", line, rc, err.message);
    assert_null(v);
    if (!strstr(err.message, "t.nii") || !strstr(err.message, part))
        fail_msg("line %d: message '%s' lacks t.nii or '%s'", line, err.message, part);
}

#define BAD(b, size, part) expect_bad((b), (size), (part), __LINE__)

/* A 2 x 2 x 2 file with header h and voxels vox (vbytes), cut to its first
 * `keep` bytes (0: whole), must be refused with a message naming it and part. */
static void expect_bad_file(const nii *h, const void *vox, size_t vbytes, size_t keep,
                            const char *part, int line)
{
    size_t size;
    uint8_t *b = nii_bytes(h, vox, vbytes, &size);
    expect_bad(b, keep ? keep : size, part, line);
    free(b);
}

static const uint8_t bad_u8[8] = {1, 2, 3, 4, 5, 6, 7, 8};

#define BAD_HEADER(h, part) expect_bad_file(&(h), bad_u8, sizeof bad_u8, 0, (part), __LINE__)

static void test_nifti_bad(void **state)
{
    (void)state;
    const nii good = nii_default(2, 2, 2, 2, 8);
    nii h = good;
    expect_bad_file(&h, bad_u8, 8, 100, "truncated header", __LINE__);
    expect_bad_file(&h, bad_u8, 8, 1, "truncated header", __LINE__);
    expect_bad(bad_u8, 0, "truncated header", __LINE__);
    expect_bad_file(&h, bad_u8, 8, 359, "truncated voxel data", __LINE__);
    expect_bad_file(&h, bad_u8, 8, 359, "need 360 bytes, the file has 359", __LINE__);

    memcpy(h.magic, "abc", 4);
    BAD_HEADER(h, "magic");
    memcpy(h.magic, "ni1", 4);
    BAD_HEADER(h, "only single-file .nii");

    h = good;
    h.dim[2] = 0;
    BAD_HEADER(h, "header field dim[2] = 0");
    h = good;
    h.dim[0] = 5;
    BAD_HEADER(h, "dim[0] = 5");
    h = good;
    h.dim[0] = 4;
    h.dim[4] = 3;
    BAD_HEADER(h, "dim[0] = 4");
    h = good;
    h.dim[1] = h.dim[2] = h.dim[3] = 32767; /* 3.5e13 voxels */
    BAD_HEADER(h, "limit");
    h.dim[1] = h.dim[2] = h.dim[3] = 600; /* under the bound, but not in the file */
    BAD_HEADER(h, "truncated voxel data");

    h = good;
    h.datatype = 32; /* complex64 */
    h.bitpix = 64;
    BAD_HEADER(h, "datatype = 32");
    h = good;
    h.bitpix = 16;
    BAD_HEADER(h, "bitpix = 16");

    h = nii_default(2, 2, 2, 16, 32);
    float f32[8] = {1, 2, 3, NAN, 5, 6, 7, 8}; /* voxel 3 is (1, 1, 0) */
    expect_bad_file(&h, f32, sizeof f32, 0, "voxel (1, 1, 0) at byte 364 is NaN", __LINE__);
    f32[3] = 4;
    f32[6] = INFINITY; /* (0, 1, 1) */
    expect_bad_file(&h, f32, sizeof f32, 0, "voxel (0, 1, 1) at byte 376 is infinite", __LINE__);
    h = nii_default(2, 2, 2, 64, 64);
    h.slope = 1e30f; /* a finite value that scales to infinity */
    double f64[8] = {1, 2, 3, 4, 5, 6, 1e300, 8};
    expect_bad_file(&h, f64, sizeof f64, 0, "after scl_slope", __LINE__);

    h = good;
    h.vox_offset = 4096;
    expect_bad_file(&h, bad_u8, 8, 400, "vox_offset = 4096 is past the end", __LINE__);
    {
        size_t size;
        uint8_t *b = nii_bytes(&good, bad_u8, 8, &size);
        float early = 100; /* inside the header */
        put(b + 108, &early, 4, false);
        expect_bad(b, size, "vox_offset = 100", __LINE__);
        b[0] = 0x12; /* sizeof_hdr in neither byte order */
        expect_bad(b, size, "sizeof_hdr", __LINE__);
        free(b);
    }

    h = good;
    h.pixdim[2] = -1;
    BAD_HEADER(h, "pixdim[2] = -1");
    h = good;
    h.pixdim[3] = NAN;
    BAD_HEADER(h, "pixdim[3]");
    h = good;
    h.units = 5;
    BAD_HEADER(h, "xyzt_units");

    /* bad definitions */
    size_t size;
    uint8_t *b = nii_bytes(&good, bad_u8, 8, &size);
    ftm_volume_load_def def = ftm_default_volume_load_def();
    def.low_percentile = 50;
    def.high_percentile = 50;
    ftm_volume *v;
    ftm_error err;
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_EINVAL);
    assert_has(err.message, "percentile");
    def = ftm_default_volume_load_def();
    def.scale = 0;
    assert_int_equal(parse(b, size, &def, &v, &err), FTM_EINVAL);
    assert_has(err.message, "scale");
    free(b);
}

/* ------------------------------------------------------------ scenes */

static const char *write_text(const char *name, const char *text)
{
    return write_file(name, text, strlen(text));
}

static void expect_scene_error(const char *path, const char *part, int line)
{
    ftm_scene *s = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_scene_load_file(path, &s, &err);
    if (rc == FTM_OK)
        fail_msg("line %d: scene parsed", line);
    assert_null(s);
    if (!strstr(err.message, part))
        fail_msg("line %d: message '%s' lacks '%s'", line, err.message, part);
}

#define SCENE_BAD(path, part) expect_scene_error((path), (part), __LINE__)

static const char mat[] = "[material]\nmass = 0.01\nstiffness = 100\ndamping = 1\n";

static void test_volume_scenes(void **state)
{
    (void)state;
    NEEDS_NIFTI();
    /* a NIfTI file next to the scene, found relative to it */
    uint8_t vox[4 * 4 * 4];
    for (int i = 0; i < 64; i++)
        vox[i] = (uint8_t)(i % 4 == 0 ? 0 : 100 + i);
    nii h = nii_default(4, 4, 4, 2, 8);
    h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 10; /* mm */
    size_t size;
    uint8_t *b = nii_bytes(&h, vox, sizeof vox, &size);
    write_file("block.nii", b, size);
    free(b);
    char text[2048];
    snprintf(text, sizeof text,
             "[mesh]\ngenerator = volume\n%s"
             "[volume]\nfile = block.nii\nnodes = 3 4 5\nstencil = 26\nhard = 2\nair = 0\n"
             "fix = zmin\nwindow = 1 99\nscale = 2\norigin = 1 2 3\n"
             "[load]\nnode = nearest 1.04 2.0533 3.08\nkind = displacement\nvalue = 0 0 -0.001\n",
             mat);
    const char *path = write_text("block.scene", text);
    ftm_scene *s = NULL;
    ftm_error err;
    if (ftm_scene_load_file(path, &s, &err) != FTM_OK)
        fail_msg("%s", err.message);
    const ftm_volume *v = ftm_scene_volume(s);
    assert_non_null(v);
    ftm_volume_info in = ftm_volume_get_info(v);
    assert_near(in.spacing.x, 0.02, 1e-15);
    assert_true(in.origin.x == 1 && in.origin.y == 2 && in.origin.z == 3);
    const ftm_mesh *m = ftm_scene_mesh(s);
    assert_int_equal(ftm_mesh_node_count(m), 3 * 4 * 5);
    assert_int_equal(count_fixed(m), 3 * 4);
    int32_t nodes[3];
    ftm_ffd_nodes(ftm_scene_ffd(s), nodes);
    assert_true(nodes[0] == 3 && nodes[1] == 4 && nodes[2] == 5);
    assert_int_equal(ftm_ffd_point_node(ftm_scene_ffd(s), 2, 3, 4),
                     ftm_mesh_node_of_input(m, 3 * 4 * 5 - 1));
    ftm_scene_destroy(s);

    /* a scene without [volume] has neither */
    assert_int_equal(ftm_scene_open("default", &s, &err), FTM_OK);
    assert_null(ftm_scene_volume(s));
    assert_null(ftm_scene_ffd(s));
    ftm_scene_destroy(s);

    /* a phantom scene */
    snprintf(text, sizeof text,
             "[mesh]\ngenerator = volume\n%s[volume]\nphantom = head\nvoxels = 16\nsize = 0.1\n"
             "nodes = 4\n",
             mat);
    path = write_text("ph.scene", text);
    assert_int_equal(ftm_scene_load_file(path, &s, &err), FTM_OK);
    assert_int_equal(ftm_volume_get_info(ftm_scene_volume(s)).nx, 16);
    ftm_scene_destroy(s);

    /* errors name the file and the line: [volume] at line 7, its keys from 8 */
    static const struct {
        const char *volume; /* the [volume] section's keys */
        const char *part;   /* in the message ("LINE: ..." after "eN.scene:") */
    } bad_volume[] = {
        {"phantom = head\nbogus = 1\n", "9: unknown key 'bogus' in [volume]"},
        {"file = nothere.nii\n", "8: "},
        {"file = nothere.nii\n", "nothere.nii: cannot open"},
        {"phantom = head\nnodes = 1\n", "9: nodes must be between 2 and"},
        {"phantom = head\nnodes = 3 4\n", "9: nodes: expected 1 value"},
        {"phantom = head\nwindow = 1 2\n", "9: window is only used with a file"},
        {"file = x.nii\nvoxels = 9\n", "9: voxels is only used with a phantom"},
        {"phantom = head\nair = 5\n", "7: volume lattice: every cell is air"},
        {"file = x.nii\nphantom = head\n", "9: [volume] has both file (line 8) and phantom"},
        {"phantom = head\naxes = stored\n", "9: axes is only used with a file"},
        {"file = x.nii\naxes = sideways\n", "9: axes: unknown value 'sideways' (expected scanner or stored)"},
        {"nodes = 4\n", "7: [volume] needs 'file = PATH' (NIfTI) or 'phantom = head'"},
    };
    for (size_t i = 0; i < sizeof bad_volume / sizeof bad_volume[0]; i++) {
        char name[32], part[160];
        snprintf(name, sizeof name, "e%zu.scene", i);
        const char *want = bad_volume[i].part; /* "LINE: ..." follows the scene's name */
        bool at_line = want[0] >= '0' && want[0] <= '9';
        snprintf(part, sizeof part, "%s%s%s", at_line ? name : "", at_line ? ":" : "", want);
        snprintf(text, sizeof text, "[mesh]\ngenerator = volume\n%s[volume]\n%s", mat,
                 bad_volume[i].volume);
        expect_scene_error(write_text(name, text), part, (int)i);
    }
    /* [volume] and [mesh] disagree */
    snprintf(text, sizeof text, "[mesh]\ngenerator = volume\n%s", mat);
    SCENE_BAD(write_text("m1.scene", text), "m1.scene:2: the volume generator needs a [volume]");
    snprintf(text, sizeof text,
             "[mesh]\ngenerator = lattice3d\nnx = 2\nny = 2\nnz = 2\nspacing = 1\n"
             "%s[volume]\nphantom = head\n",
             mat);
    SCENE_BAD(write_text("m2.scene", text), "m2.scene:11: [volume] is only used with");
    snprintf(text, sizeof text, "[mesh]\ngenerator = volume\nnx = 3\n%s[volume]\nphantom = head\n",
             mat);
    SCENE_BAD(write_text("m3.scene", text), "m3.scene:3: nx is not used by the volume generator");
    /* a malformed NIfTI: the scene's line, then the file's own message */
    uint8_t bad[400] = {0};
    write_file("bad.nii", bad, sizeof bad);
    snprintf(text, sizeof text, "[mesh]\ngenerator = volume\n%s[volume]\nfile = bad.nii\n", mat);
    path = write_text("e10.scene", text);
    SCENE_BAD(path, "e10.scene:8: ");
    SCENE_BAD(path, "bad.nii: header field sizeof_hdr = 0");
}

/* [volume] labels: a label map on the image's grid, for the client to draw
 * the image by tissue; refused (naming the file and the line) when it is
 * missing or on another grid. */
static void write_labels(const char *name, int16_t nx, int16_t ny, int16_t nz, float mm,
                         float shift)
{
    const size_t n = (size_t)nx * ny * nz;
    int16_t *lab = malloc(n * sizeof *lab);
    assert_non_null(lab);
    for (size_t i = 0; i < n; i++)
        lab[i] = (int16_t)(i % (size_t)nx < (size_t)nx / 2 ? 1 : 15);
    nii h = nii_default(nx, ny, nz, 4, 16); /* int16 */
    h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = mm;
    if (shift != 0) { /* placed by an sform, shifted along each axis [mm] */
        h.sform_code = 1;
        for (int a = 0; a < 3; a++) {
            h.srow[a][a] = mm;
            h.srow[a][3] = shift;
        }
    }
    size_t size;
    uint8_t *b = nii_bytes(&h, lab, n * sizeof *lab, &size);
    write_file(name, b, size);
    free(b);
    free(lab);
}

static void test_volume_label_scenes(void **state)
{
    (void)state;
    NEEDS_NIFTI();
    uint8_t vox[4 * 4 * 4];
    for (int i = 0; i < 64; i++)
        vox[i] = (uint8_t)(100 + i);
    nii h = nii_default(4, 4, 4, 2, 8);
    h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 10; /* mm */
    size_t size;
    uint8_t *b = nii_bytes(&h, vox, sizeof vox, &size);
    write_file("lblock.nii", b, size);
    free(b);
    write_labels("lab.nii", 4, 4, 4, 10, 0);
    write_labels("lab443.nii", 4, 4, 3, 10, 0);
    write_labels("lab9mm.nii", 4, 4, 4, 9, 0);
    write_labels("labshift.nii", 4, 4, 4, 10, 50);
    write_labels("lab16.nii", 16, 16, 16, 6.25f, 0); /* the phantom's 0.1 m / 16 */

    /* read as the image is (scale, origin): on its grid, x fastest */
    char text[1024];
    snprintf(text, sizeof text,
             "[mesh]\ngenerator = volume\n%s"
             "[volume]\nfile = lblock.nii\nlabels = lab.nii\nnodes = 3\nhard = 2\nair = 0\n"
             "scale = 2\norigin = 1 2 3\n",
             mat);
    ftm_scene *s = NULL;
    ftm_error err;
    if (ftm_scene_load_file(write_text("lab.scene", text), &s, &err) != FTM_OK)
        fail_msg("%s", err.message);
    const ftm_label_map *lm = ftm_scene_volume_labels(s);
    assert_non_null(lm);
    ftm_volume_info li = ftm_label_map_get_info(lm), vi = ftm_volume_get_info(ftm_scene_volume(s));
    assert_true(li.nx == 4 && li.ny == 4 && li.nz == 4);
    assert_near(li.spacing.x, vi.spacing.x, 1e-15);
    assert_true(li.origin.x == 1 && li.origin.y == 2 && li.origin.z == 3);
    const int32_t *d = ftm_label_map_data(lm);
    for (int i = 0; i < 64; i++)
        assert_int_equal(d[i], i % 4 < 2 ? 1 : 15);
    ftm_scene_destroy(s);

    /* without the key: none */
    snprintf(text, sizeof text,
             "[mesh]\ngenerator = volume\n%s[volume]\nfile = lblock.nii\nnodes = 3\n", mat);
    assert_int_equal(ftm_scene_load_file(write_text("nolab.scene", text), &s, &err), FTM_OK);
    assert_null(ftm_scene_volume_labels(s));
    ftm_scene_destroy(s);
    assert_int_equal(ftm_scene_open("head", &s, &err), FTM_OK);
    assert_null(ftm_scene_volume_labels(s));
    ftm_scene_destroy(s);

    /* a phantom's grid: its voxels and size, from its origin */
    snprintf(text, sizeof text,
             "[mesh]\ngenerator = volume\n%s[volume]\nphantom = head\nvoxels = 16\n"
             "size = 0.1\nnodes = 4\nlabels = lab16.nii\n",
             mat);
    if (ftm_scene_load_file(write_text("phlab.scene", text), &s, &err) != FTM_OK)
        fail_msg("%s", err.message);
    assert_int_equal(ftm_label_map_get_info(ftm_scene_volume_labels(s)).nz, 16);
    ftm_scene_destroy(s);

    /* [volume] at line 7, its keys from 8 */
    static const struct {
        const char *volume, *part;
    } bad[] = {
        {"file = lblock.nii\nlabels = nothere.nii\n", "9: labels: "},
        {"file = lblock.nii\nlabels = nothere.nii\n", "nothere.nii: cannot open"},
        {"file = lblock.nii\nlabels = lab443.nii\n",
         "9: labels: lab443.nii is 4x4x3 voxels, the image (lblock.nii) 4x4x4: a label map must "
         "be on the image's grid"},
        {"file = lblock.nii\nlabels = lab9mm.nii\n",
         "9: labels: lab9mm.nii has voxels of 9 x 9 x 9 mm, the image (lblock.nii) 10 x 10 x 10"},
        {"file = lblock.nii\nlabels = labshift.nii\n",
         "9: labels: labshift.nii's box starts at (45, 45, 45) mm, the image's (lblock.nii) at "
         "(0, 0, 0) mm"},
        {"phantom = head\nvoxels = 8\nlabels = lab16.nii\n",
         "10: labels: lab16.nii is 16x16x16 voxels, the image (the phantom) 8x8x8"},
        {"file = lblock.nii\nlabels = lab.nii\nlabels = lab.nii\n", "10: "},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char name[32], part[200];
        snprintf(name, sizeof name, "l%zu.scene", i);
        bool at_line = bad[i].part[0] >= '0' && bad[i].part[0] <= '9';
        snprintf(part, sizeof part, "%s%s%s", at_line ? name : "", at_line ? ":" : "",
                 bad[i].part);
        snprintf(text, sizeof text, "[mesh]\ngenerator = volume\n%s[volume]\n%snodes = 3\n", mat,
                 bad[i].volume);
        expect_scene_error(write_text(name, text), part, (int)i);
    }
}

int main(void)
{
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_phantom),
        cmocka_unit_test(test_sample),
        cmocka_unit_test(test_lattice_whole_box),
        cmocka_unit_test(test_lattice_air_and_skull),
        cmocka_unit_test(test_ffd_identity_and_affine),
        cmocka_unit_test(test_ffd_continuity_and_unmap),
        cmocka_unit_test(test_head_press),
        cmocka_unit_test(test_nifti_good),
        cmocka_unit_test(test_nifti_files),
        cmocka_unit_test(test_nifti_bad),
        cmocka_unit_test(test_nifti_orientation),
        cmocka_unit_test(test_nifti2),
        cmocka_unit_test(test_label_map),
        cmocka_unit_test(test_volume_scenes),
        cmocka_unit_test(test_volume_label_scenes),
    };
    int failed = cmocka_run_group_tests(tests, NULL, NULL);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
    return failed;
}
