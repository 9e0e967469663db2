/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm mesh (tools/mesher): label maps the test writes itself (two nested
 * spheres, placed by an sform) meshed, the .msh read back through libftm's
 * loader and checked here independently: tissues as labels, each element
 * where the map has its tissue, the scan's frame, the dihedral angles;
 * then the inputs it must refuse, each with what and where. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "ftm/labels.h"
#include "ftm/load.h"
#include "ftm/mesh.h"

static char tmpdir[] = "/tmp/ftm-test-mesher-XXXXXX";

/* tmpdir/name; the string lives until the test ends (few are made) */
static const char *tmp(const char *name)
{
    char p[600];
    snprintf(p, sizeof p, "%s/%s", tmpdir, name);
    static char *kept[256];
    static int count;
    for (int i = 0; i < count; i++)
        if (strcmp(kept[i], p) == 0)
            return kept[i];
    assert_true(count < 256);
    kept[count] = strdup(p);
    return kept[count++];
}

/* Runs ftm (FTM_CLI) with "mesh ARGS": its exit status; its standard error
 * in err (and output in out, when not NULL). */
static int run_mesh(const char *args, char *err, size_t errcap, char *out, size_t outcap)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s mesh %s >%s 2>%s", FTM_CLI, args, tmp("out.txt"),
             tmp("err.txt"));
    int st = system(cmd);
    int code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    const char *files[2] = {tmp("err.txt"), tmp("out.txt")};
    char *bufs[2] = {err, out};
    size_t caps[2] = {errcap, outcap};
    for (int i = 0; i < 2; i++) {
        if (!bufs[i])
            continue;
        FILE *f = fopen(files[i], "r");
        size_t n = f ? fread(bufs[i], 1, caps[i] - 1, f) : 0;
        bufs[i][n] = '\0';
        if (f)
            fclose(f);
    }
    return code;
}

/* ------------------------------------------------------------ label maps */

#define N 40

/* A NIfTI-1 uint8 label map, N^3 voxels of 1 mm, placed by the sform
 * x = 70 - i, y = j - 20, z = k + 5 (mm): x runs against i. */
static void write_map(const char *path, const uint8_t *vox)
{
    uint8_t h[352] = {0};
    int32_t sz = 348;
    memcpy(h, &sz, 4);
    int16_t dim[8] = {3, N, N, N, 1, 1, 1, 1};
    memcpy(h + 40, dim, sizeof dim);
    int16_t dt = 2, bp = 8;
    memcpy(h + 70, &dt, 2);
    memcpy(h + 72, &bp, 2);
    float pix[8] = {1, 1, 1, 1, 0, 0, 0, 0};
    memcpy(h + 76, pix, sizeof pix);
    float off = 352;
    memcpy(h + 108, &off, 4);
    h[123] = 2; /* mm */
    int16_t sform = 1;
    memcpy(h + 254, &sform, 2);
    float srow[12] = {-1, 0, 0, 70, 0, 1, 0, -20, 0, 0, 1, 5};
    memcpy(h + 280, srow, sizeof srow);
    memcpy(h + 344, "n+1", 4);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(h, 1, sizeof h, f), sizeof h);
    assert_int_equal(fwrite(vox, 1, N * N * N, f), N * N * N);
    assert_int_equal(fclose(f), 0);
}

/* Two nested spheres around the image's centre: label 2 within 7 mm, label
 * 1 (and a patch of label 3 in it) within 14 mm, 0 outside. */
static uint8_t *spheres(void)
{
    uint8_t *v = calloc(N * N * N, 1);
    for (int k = 0; k < N; k++)
        for (int j = 0; j < N; j++)
            for (int i = 0; i < N; i++) {
                double x = i + 0.5 - N / 2.0, y = j + 0.5 - N / 2.0, z = k + 0.5 - N / 2.0;
                double r = sqrt(x * x + y * y + z * z);
                v[i + N * (j + N * k)] = r < 7 ? 2 : r < 14 ? (x > 10 && y > 5 ? 3 : 1) : 0;
            }
    return v;
}

static double tet_min_dihedral(const ftm_mesh *m, const int32_t *t)
{
    ftm_vec3 p[4];
    for (int i = 0; i < 4; i++)
        p[i] = ftm_mesh_rest_position(m, t[i]);
    static const int e[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
    double worst = 180;
    for (int k = 0; k < 6; k++) {
        ftm_vec3 a = p[e[k][0]], b = p[e[k][1]], c = p[e[k][2]], d = p[e[k][3]];
        double u[3] = {b.x - a.x, b.y - a.y, b.z - a.z}, v[3] = {c.x - a.x, c.y - a.y, c.z - a.z},
               w[3] = {d.x - a.x, d.y - a.y, d.z - a.z};
        double n1[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                        u[0] * v[1] - u[1] * v[0]};
        double n2[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                        u[0] * w[1] - u[1] * w[0]};
        double cs = (n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]) /
                    sqrt((n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2]) *
                         (n2[0] * n2[0] + n2[1] * n2[1] + n2[2] * n2[2]));
        double a_deg = acos(fmax(-1, fmin(1, cs))) * 57.295779513082323;
        worst = fmin(worst, a_deg);
    }
    return worst;
}

static ftm_mesh *load_msh(const char *path)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_material_def mat = ftm_default_material_def();
    ftm_error err = {0};
    if (ftm_load_gmsh(b, path, &mat, &err) != FTM_OK)
        fail_msg("%s", err.message);
    ftm_mesh *m = NULL;
    ftm_mesh_build_def d = ftm_default_mesh_build_def();
    if (ftm_mesh_build(b, &d, &m, &err) != FTM_OK)
        fail_msg("%s", err.message);
    ftm_mesh_builder_destroy(b);
    return m;
}

static void test_spheres(void **state)
{
    (void)state;
    uint8_t *v = spheres();
    write_map(tmp("spheres.nii"), v);
    char err[8192], out[8192], args[2048];
    snprintf(args, sizeof args,
             "%s --tissue inner=2 --tissue outer=1,3 --size 4mm -o %s --json",
             tmp("spheres.nii"), tmp("spheres.msh"));
    int rc = run_mesh(args, err, sizeof err, out, sizeof out);
    if (rc != 0)
        fail_msg("ftm mesh failed (%d): %s", rc, err);
    /* progress on standard error, the summary on standard output */
    assert_non_null(strstr(err, "refined in"));
    assert_non_null(strstr(out, "\"tissues\": {\"inner\": "));
    ftm_mesh *m = load_msh(tmp("spheres.msh"));
    const int32_t nt = ftm_mesh_tetrahedron_count(m);
    assert_true(nt > 200 && nt < 20000);
    assert_true(ftm_mesh_has_labels(m));
    ftm_label_map *map = NULL;
    ftm_error e = {0};
    if (ftm_label_map_load(tmp("spheres.nii"), NULL, &map, &e) != FTM_OK)
        fail_msg("%s", e.message);
    int count[3] = {0, 0, 0}, agree = 0;
    double worst = 180, volume[3] = {0, 0, 0};
    const int32_t *tets = ftm_mesh_tetrahedra(m);
    for (int32_t t = 0; t < nt; t++) {
        int32_t label = ftm_mesh_tetrahedron_label(m, t);
        assert_true(label == 1 || label == 2); /* inner, outer: as --tissue ordered them */
        count[label]++;
        ftm_vec3 c = {0, 0, 0}, p[4];
        for (int i = 0; i < 4; i++) {
            p[i] = ftm_mesh_rest_position(m, tets[4 * t + i]);
            c.x += p[i].x / 4, c.y += p[i].y / 4, c.z += p[i].z / 4;
        }
        /* in the scan's frame: the label map (read with its sform) has the
         * element's tissue at its centroid */
        int32_t at = ftm_label_map_at(map, c);
        agree += label == 1 ? at == 2 : (at == 1 || at == 3); /* tissue 1 is inner */
        worst = fmin(worst, tet_min_dihedral(m, tets + 4 * t));
        double u[3] = {p[1].x - p[0].x, p[1].y - p[0].y, p[1].z - p[0].z},
               w[3] = {p[2].x - p[0].x, p[2].y - p[0].y, p[2].z - p[0].z},
               z[3] = {p[3].x - p[0].x, p[3].y - p[0].y, p[3].z - p[0].z};
        volume[label] += (u[0] * (w[1] * z[2] - w[2] * z[1]) - u[1] * (w[0] * z[2] - w[2] * z[0]) +
                          u[2] * (w[0] * z[1] - w[1] * z[0])) / 6;
    }
    assert_true(count[1] > 0 && count[2] > 0);
    /* boundary elements may have their centroid in a voxel of the staircase
     * on the other side: in the map as given at least 98 %; in the map as
     * the tool meshed it (islands merged, boundaries smoothed) 99 %, by its
     * own count */
    if (agree < 0.98 * nt)
        fail_msg("%d of %d elements have their tissue at their centroid", agree, nt);
    const char *pct = strstr(out, "\"centroid_in_tissue_pct\": ");
    assert_non_null(pct);
    double meshed = atof(pct + strlen("\"centroid_in_tissue_pct\": "));
    if (meshed < 99)
        fail_msg("%.2f %% of the elements in their tissue in the map as meshed", meshed);
    if (worst < 10)
        fail_msg("smallest dihedral angle %g degrees", worst);
    /* volumes (m^3): 4/3 pi r^3 of the spheres, within a few per cent */
    double inner = 4.0 / 3 * 3.14159265358979323846 * pow(0.007, 3), both = 4.0 / 3 * 3.14159265358979323846 * pow(0.014, 3);
    /* (the inner sphere is 1.75 elements across: its facets, inside the
     * curved surface, and the smoothing make it smaller) */
    if (fabs(volume[1] / inner - 1) > 0.15 || fabs((volume[1] + volume[2]) / both - 1) > 0.05)
        fail_msg("volumes %g and %g m^3, expected %g and %g", volume[1], volume[1] + volume[2],
                 inner, both);
    /* the scan's frame: the spheres' centre, voxel (19.5, 19.5, 19.5), is at
     * x = 70 - 19.5, y = 19.5 - 20, z = 19.5 + 5 mm */
    ftm_vec3 lo = {1e9, 1e9, 1e9}, hi = {-1e9, -1e9, -1e9};
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        ftm_vec3 p = ftm_mesh_rest_position(m, i);
        lo.x = fmin(lo.x, p.x), lo.y = fmin(lo.y, p.y), lo.z = fmin(lo.z, p.z);
        hi.x = fmax(hi.x, p.x), hi.y = fmax(hi.y, p.y), hi.z = fmax(hi.z, p.z);
    }
    double cx = (lo.x + hi.x) / 2, cy = (lo.y + hi.y) / 2, cz = (lo.z + hi.z) / 2;
    if (fabs(cx - 0.0505) > 1e-3 || fabs(cy + 0.0005) > 1e-3 || fabs(cz - 0.0245) > 1e-3)
        fail_msg("the mesh's centre (%g, %g, %g) m is not the spheres' (0.0505, -0.0005, 0.0245)",
                 cx, cy, cz);
    assert_true(fabs(hi.x - lo.x - 0.028) < 1e-3);
    ftm_label_map_destroy(map);
    ftm_mesh_destroy(m);

    /* the same run gives the same file */
    snprintf(args, sizeof args, "%s --tissue inner=2 --tissue outer=1,3 --size 4mm -o %s --quiet",
             tmp("spheres.nii"), tmp("again.msh"));
    assert_int_equal(run_mesh(args, err, sizeof err, NULL, 0), 0);
    assert_string_equal(err, "");
    char cmp[1300];
    snprintf(cmp, sizeof cmp, "cmp -s %s %s", tmp("spheres.msh"), tmp("again.msh"));
    assert_int_equal(system(cmp), 0);
    free(v);
}

/* Each refused with a message naming what and where, exit status 2, and
 * no file written. */
static void expect_refusal(const char *args, const char *part)
{
    char err[8192], full[2048];
    unlink(tmp("bad.msh"));
    snprintf(full, sizeof full, "%s -o %s --quiet", args, tmp("bad.msh"));
    int rc = run_mesh(full, err, sizeof err, NULL, 0);
    if (rc != 2 || !strstr(err, part))
        fail_msg("ftm mesh %s: exit %d, message '%s' (wanted 2 and '%s')", args, rc, err, part);
    assert_int_equal(access(tmp("bad.msh"), F_OK), -1);
}

static void test_refusals(void **state)
{
    (void)state;
    uint8_t *v = spheres();
    const char *map = tmp("refuse.nii");
    write_map(map, v);
    char a[1024];
#define REFUSE(part, ...)                                                                          \
    do {                                                                                           \
        snprintf(a, sizeof a, __VA_ARGS__);                                                        \
        expect_refusal(a, part);                                                                   \
    } while (0)
    REFUSE("label 7 of tissue x is missing: no voxel has it (the map has 0 .. 3)",
           "%s --tissue x=7", map);
    REFUSE("tissue x is empty: no voxel has a label in 50-60", "%s --tissue x=50-60", map);
    REFUSE("label 2 is in two tissues, a and b", "%s --tissue a=1-2 --tissue b=2", map);
    REFUSE("more than --max-elements 50", "%s --tissue a=1-3 --size 2mm --max-elements 50", map);
    REFUSE("--size: '3' is not a length > 0 with its unit", "%s --tissue a=1 --size 3", map);
    REFUSE("--tissue a=1-x: '1-x' is not a label", "%s --tissue a=1-x", map);
    REFUSE("no tissue", "%s", map);
    REFUSE("cannot open", "%s --tissue a=1", tmp("none.nii"));
    /* a tissue on the border */
    v[0 + N * (5 + N * 6)] = 1;
    write_map(map, v);
    REFUSE("tissue a touches the image's border at voxel (0, 5, 6) (label 1, at 70 -15 11 mm)",
           "%s --tissue a=1", map);
    v[0 + N * (5 + N * 6)] = 0;
    /* a mask on another grid */
    const char *small = tmp("small.nii");
    FILE *f = fopen(small, "wb");
    uint8_t h[352] = {0};
    int32_t sz = 348;
    memcpy(h, &sz, 4);
    int16_t dim[8] = {3, 2, 2, 2, 1, 1, 1, 1};
    memcpy(h + 40, dim, sizeof dim);
    int16_t dt = 2, bp = 8;
    memcpy(h + 70, &dt, 2);
    memcpy(h + 72, &bp, 2);
    float pix[8] = {1, 1, 1, 1};
    memcpy(h + 76, pix, sizeof pix);
    float off = 352;
    memcpy(h + 108, &off, 4);
    memcpy(h + 344, "n+1", 4);
    fwrite(h, 1, sizeof h, f);
    fwrite(v, 1, 8, f);
    fclose(f);
    REFUSE("is on another grid than", "%s --tissue a=1 --mask %s --above 0", map, small);
    /* an open surface cannot be meshed into a volume */
    f = fopen(tmp("open.stl"), "w");
    fprintf(f, "solid o\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 10 0 0\n"
               "vertex 0 10 0\nendloop\nendfacet\nendsolid o\n");
    fclose(f);
    REFUSE("open.stl:2: facet 1: the surface is not closed", "%s", tmp("open.stl"));
    free(v);
}

/* A closed STL surface (a 20 mm cube) meshed into one tissue; a mask keeps
 * only part of a label map. */
static void test_surface_and_mask(void **state)
{
    (void)state;
    static const int q[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
    static const double c[8][3] = {{0, 0, 0}, {20, 0, 0}, {20, 20, 0}, {0, 20, 0},
                                   {0, 0, 20}, {20, 0, 20}, {20, 20, 20}, {0, 20, 20}};
    FILE *f = fopen(tmp("cube.stl"), "w");
    fprintf(f, "solid cube\n");
    for (int k = 0; k < 6; k++)
        for (int t = 0; t < 2; t++) {
            int v[3] = {q[k][0], q[k][1 + t], q[k][2 + t]};
            fprintf(f, "facet normal 0 0 0\nouter loop\n");
            for (int i = 0; i < 3; i++)
                fprintf(f, "vertex %g %g %g\n", c[v[i]][0], c[v[i]][1], c[v[i]][2]);
            fprintf(f, "endloop\nendfacet\n");
        }
    fprintf(f, "endsolid cube\n");
    fclose(f);
    char err[8192], args[2048];
    snprintf(args, sizeof args, "%s --tissue block --size 6mm -o %s --quiet", tmp("cube.stl"),
             tmp("cube.msh"));
    if (run_mesh(args, err, sizeof err, NULL, 0) != 0)
        fail_msg("%s", err);
    ftm_mesh *m = load_msh(tmp("cube.msh"));
    double vol = 0;
    const int32_t *t = ftm_mesh_tetrahedra(m);
    for (int32_t e = 0; e < ftm_mesh_tetrahedron_count(m); e++) {
        assert_int_equal(ftm_mesh_tetrahedron_label(m, e), 1);
        ftm_vec3 p[4];
        for (int i = 0; i < 4; i++)
            p[i] = ftm_mesh_rest_position(m, t[4 * e + i]);
        double u[3] = {p[1].x - p[0].x, p[1].y - p[0].y, p[1].z - p[0].z},
               w[3] = {p[2].x - p[0].x, p[2].y - p[0].y, p[2].z - p[0].z},
               z[3] = {p[3].x - p[0].x, p[3].y - p[0].y, p[3].z - p[0].z};
        vol += (u[0] * (w[1] * z[2] - w[2] * z[1]) - u[1] * (w[0] * z[2] - w[2] * z[0]) +
                u[2] * (w[0] * z[1] - w[1] * z[0])) / 6;
    }
    /* 20 mm = 0.02 m (the STL in mm): 8e-6 m^3, less the rounded corners */
    if (!(vol > 0.93 * 8e-6 && vol <= 8e-6 * 1.0001))
        fail_msg("the cube's mesh holds %g m^3, not about 8e-6", vol);
    ftm_mesh_destroy(m);

    /* with a mask: only the voxels where the image is above 0.5 (here the
     * half x < 20 mm of the image, i > 19 by the sform) */
    uint8_t *v = spheres(), *mask = calloc(N * N * N, 1);
    for (int i = 0; i < N * N * N; i++)
        mask[i] = i % N >= N / 2;
    write_map(tmp("m_labels.nii"), v);
    write_map(tmp("m_mask.nii"), mask);
    snprintf(args, sizeof args, "%s --tissue a=1-3 --mask %s --above 0.5 --size 4mm -o %s --quiet",
             tmp("m_labels.nii"), tmp("m_mask.nii"), tmp("half.msh"));
    if (run_mesh(args, err, sizeof err, NULL, 0) != 0)
        fail_msg("%s", err);
    m = load_msh(tmp("half.msh"));
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++)
        assert_true(ftm_mesh_rest_position(m, i).x <= 0.0505 + 1e-3); /* the half of i >= 20 */
    ftm_mesh_destroy(m);
    free(v);
    free(mask);
}

static void test_help_through_ftm(void **state)
{
    (void)state;
    char err[8192], out[8192];
    assert_int_equal(run_mesh("--help", err, sizeof err, out, sizeof out), 0);
    assert_non_null(strstr(out, "usage: ftm mesh LABELS.nii"));
}

int main(void)
{
    if (!mkdtemp(tmpdir))
        return 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help_through_ftm),
        cmocka_unit_test(test_spheres),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_surface_and_mask),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    char cmd[256];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    if (system(cmd) != 0)
        rc = 1;
    return rc;
}
