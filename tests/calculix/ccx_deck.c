/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Writes CalculiX input decks from FTM scenes, so that the independent
 * reference solves exactly FTM's mesh (docs/calculix.md):
 *
 *   ccx_deck SCENE OUT.inp [--model linear|neo-hookean] [--increments N]
 *       the scene's nodes (CalculiX node k+1 = input index k, at its rest
 *       position), its hexahedra (C3D8) and tetrahedra (C3D4, written with
 *       a positive volume), its fixed nodes clamped, its displacement loads
 *       prescribed and its force loads as point loads, at their full value.
 *       The material is [fem]: *ELASTIC with E and nu (linear, *STATIC), or
 *       *HYPERELASTIC, NEO HOOKE with C10 = mu/2 and D1 = 2/kappa (NLGEOM,
 *       *STATIC in N equal increments, tight Newton tolerances). Output:
 *       U of every node, RF of the displacement-loaded nodes (set PRESS)
 *       with totals, in the .dat file.
 *
 *   ccx_deck --tetgen NX NY NZ SX SY SZ OUTBASE [--label-box X0 Y0 Z0 X1 Y1 Z1]
 *       writes OUTBASE.node / OUTBASE.ele: a box of NX x NY x NZ nodes
 *       (spacing SX SY SZ, node (i, j, k) = input index i + NX (j + NY k),
 *       the lattice3d numbering), each cell split into 6 tetrahedra around
 *       its (0,0,0)-(1,1,1) diagonal (a conforming mesh), all of positive
 *       volume. With --label-box, every tetrahedron carries a region
 *       attribute: 2 when its centroid is inside the box, 1 otherwise.
 *
 *   ccx_deck --gmsh-hex NX NY NZ SX SY SZ OUT.msh [--label-box X0 Y0 Z0 X1 Y1 Z1]
 *       the same box as Gmsh MSH 4.1 hexahedra, one per cell (nodes in the
 *       same order); with --label-box, in two volumes of physical groups 2
 *       (centroid inside the box) and 1 (the rest).
 *
 * With [fem LABEL] sections in the scene, each label of the mesh gets its
 * own ELSET (L<label>), *MATERIAL (M<label>) and *SOLID SECTION, with the
 * label's section or else [fem]; a scene without them gives the same deck
 * as before labels existed (one material TISSUE on EALL).
 */
#include "ftm/ftm.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int usage(void)
{
    fprintf(stderr, "usage: ccx_deck SCENE OUT.inp [--model linear|neo-hookean] [--increments N]\n"
                    "       ccx_deck --tetgen NX NY NZ SX SY SZ OUTBASE [--label-box X0 Y0 Z0 X1 Y1 Z1]\n"
                    "       ccx_deck --gmsh-hex NX NY NZ SX SY SZ OUT.msh [--label-box X0 Y0 Z0 X1 Y1 Z1]\n");
    return 2;
}

/* A box of nodes for the generated meshes, and the optional label box. */
typedef struct box {
    long n[3];
    double s[3];
    bool labelled;
    double lo[3], hi[3]; /* elements whose centroid is inside: label 2 */
    const char *out;
} box;

/* argv: NX NY NZ SX SY SZ OUT [--label-box X0 Y0 Z0 X1 Y1 Z1] */
static int parse_box(int argc, char **argv, box *b)
{
    memset(b, 0, sizeof *b);
    if (argc != 7 && argc != 14)
        return usage();
    for (int d = 0; d < 3; d++) {
        char *end;
        b->n[d] = strtol(argv[d], &end, 10);
        if (*end || b->n[d] < 2 || b->n[d] > 1000)
            return usage();
        b->s[d] = strtod(argv[3 + d], &end);
        if (*end || !(b->s[d] > 0))
            return usage();
    }
    b->out = argv[6];
    if (argc == 14) {
        if (strcmp(argv[7], "--label-box") != 0)
            return usage();
        for (int d = 0; d < 6; d++) {
            char *end;
            double v = strtod(argv[8 + d], &end);
            if (*end || !isfinite(v))
                return usage();
            (d < 3 ? b->lo : b->hi)[d % 3] = v;
        }
        b->labelled = true;
    }
    return 0;
}

static long box_node(const box *b, const long c[3])
{
    return c[0] + b->n[0] * (c[1] + b->n[1] * c[2]);
}

/* 2 inside the label box (by the centroid of the element's nodes), else 1. */
static int box_label(const box *b, const long *v, int count)
{
    double c[3] = {0, 0, 0};
    for (int a = 0; a < count; a++) {
        long id = v[a];
        c[0] += (double)(id % b->n[0]) * b->s[0];
        c[1] += (double)((id / b->n[0]) % b->n[1]) * b->s[1];
        c[2] += (double)(id / (b->n[0] * b->n[1])) * b->s[2];
    }
    for (int d = 0; d < 3; d++) {
        c[d] /= count;
        if (c[d] < b->lo[d] || c[d] > b->hi[d])
            return 1;
    }
    return 2;
}

static FILE *open_out(const char *path)
{
    FILE *f = fopen(path, "w");
    if (!f)
        fprintf(stderr, "ccx_deck: %s: %s\n", path, strerror(errno));
    return f;
}

static int write_tetgen(int argc, char **argv)
{
    box b;
    int rc = parse_box(argc, argv, &b);
    if (rc)
        return rc;
    const long *n = b.n;
    char path[4096];
    snprintf(path, sizeof path, "%s.node", b.out);
    FILE *f = open_out(path);
    if (!f)
        return 1;
    long nodes = n[0] * n[1] * n[2];
    fprintf(f, "# %ld x %ld x %ld box, spacing %.17g %.17g %.17g (tests/calculix/ccx_deck)\n",
            n[0], n[1], n[2], b.s[0], b.s[1], b.s[2]);
    fprintf(f, "%ld 3 0 0\n", nodes);
    for (long k = 0, id = 1; k < n[2]; k++)
        for (long j = 0; j < n[1]; j++)
            for (long i = 0; i < n[0]; i++, id++)
                fprintf(f, "%ld %.17g %.17g %.17g\n", id, (double)i * b.s[0], (double)j * b.s[1],
                        (double)k * b.s[2]);
    if (fclose(f) != 0)
        return 1;
    snprintf(path, sizeof path, "%s.ele", b.out);
    if (!(f = open_out(path)))
        return 1;
    long cells = (n[0] - 1) * (n[1] - 1) * (n[2] - 1);
    fprintf(f, "# 6 tetrahedra per cell around its (0,0,0)-(1,1,1) diagonal\n");
    if (b.labelled)
        fprintf(f, "# region attribute: 2 with the centroid in [%.17g, %.17g] x [%.17g, %.17g] "
                   "x [%.17g, %.17g], else 1\n",
                b.lo[0], b.hi[0], b.lo[1], b.hi[1], b.lo[2], b.hi[2]);
    fprintf(f, b.labelled ? "%ld 4 1\n" : "%ld 4 0\n", 6 * cells);
    /* each tetrahedron walks from corner (0,0,0) to (1,1,1) one axis at a
     * time, in one of the 6 axis orders */
    static const int path6[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                    {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    long id = 1;
    for (long k = 0; k + 1 < n[2]; k++)
        for (long j = 0; j + 1 < n[1]; j++)
            for (long i = 0; i + 1 < n[0]; i++)
                for (int t = 0; t < 6; t++) {
                    long c[3] = {i, j, k}, v[4];
                    v[0] = box_node(&b, c);
                    for (int st = 0; st < 3; st++) {
                        c[path6[t][st]]++;
                        v[st + 1] = box_node(&b, c);
                    }
                    /* the edges from v0 step along the axes path6[t][0], [1], [2] in
                     * turn: an odd permutation of x, y, z is a negative volume, so
                     * swap two vertices to keep every tetrahedron positive (FTM's
                     * FEM refuses a mesh of mixed orientations) */
                    const int *pp = path6[t];
                    if ((pp[0] + 1) % 3 != pp[1]) {
                        long sw = v[2];
                        v[2] = v[3];
                        v[3] = sw;
                    }
                    fprintf(f, "%ld %ld %ld %ld %ld", id++, v[0] + 1, v[1] + 1, v[2] + 1,
                            v[3] + 1);
                    if (b.labelled)
                        fprintf(f, " %d", box_label(&b, v, 4));
                    fprintf(f, "\n");
                }
    return fclose(f) != 0;
}

/* Gmsh MSH 4.1 ASCII: the nodes in one block (tag = input index + 1), the
 * hexahedra (type 5, Gmsh's corner order: the bottom face counter-clockwise
 * seen from above, then the top) in one block per volume entity. */
static int write_gmsh_hex(int argc, char **argv)
{
    box b;
    int rc = parse_box(argc, argv, &b);
    if (rc)
        return rc;
    const long *n = b.n;
    FILE *f = open_out(b.out);
    if (!f)
        return 1;
    const long nodes = n[0] * n[1] * n[2], cells = (n[0] - 1) * (n[1] - 1) * (n[2] - 1);
    const int volumes = b.labelled ? 2 : 1;
    double ext[3];
    for (int d = 0; d < 3; d++)
        ext[d] = (double)(n[d] - 1) * b.s[d];
    fprintf(f, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
    if (b.labelled) {
        /* volume v+1 in physical group v+1 (the label); the bounding boxes
         * are the whole box's (the reader checks only that they are numbers) */
        fprintf(f, "$Entities\n0 0 0 2\n");
        for (int v = 1; v <= 2; v++)
            fprintf(f, "%d 0 0 0 %.17g %.17g %.17g 1 %d 0\n", v, ext[0], ext[1], ext[2], v);
        fprintf(f, "$EndEntities\n");
    }
    fprintf(f, "$Nodes\n1 %ld 1 %ld\n3 1 0 %ld\n", nodes, nodes, nodes);
    for (long id = 1; id <= nodes; id++)
        fprintf(f, "%ld\n", id);
    for (long k = 0; k < n[2]; k++)
        for (long j = 0; j < n[1]; j++)
            for (long i = 0; i < n[0]; i++)
                fprintf(f, "%.17g %.17g %.17g\n", (double)i * b.s[0], (double)j * b.s[1],
                        (double)k * b.s[2]);
    fprintf(f, "$EndNodes\n");
    /* the cells of each label, counted first for the block headers */
    long count[3] = {0, 0, 0};
    static const long corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                      {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    for (int pass = 0; pass < 2; pass++) {
        long id = 1;
        if (pass == 1)
            fprintf(f, "$Elements\n%d %ld 1 %ld\n", volumes - (b.labelled && !count[1]) -
                                                         (b.labelled && !count[2]),
                    cells, cells);
        for (int label = 1; label <= volumes; label++) {
            if (pass == 1 && b.labelled && !count[label])
                continue;
            if (pass == 1)
                fprintf(f, "3 %d 5 %ld\n", label, b.labelled ? count[label] : cells);
            for (long k = 0; k + 1 < n[2]; k++)
                for (long j = 0; j + 1 < n[1]; j++)
                    for (long i = 0; i + 1 < n[0]; i++) {
                        long v[8];
                        for (int a = 0; a < 8; a++) {
                            long c[3] = {i + corner[a][0], j + corner[a][1], k + corner[a][2]};
                            v[a] = box_node(&b, c);
                        }
                        if (b.labelled && box_label(&b, v, 8) != label)
                            continue;
                        if (pass == 0) {
                            count[label]++;
                            continue;
                        }
                        fprintf(f, "%ld", id++);
                        for (int a = 0; a < 8; a++)
                            fprintf(f, " %ld", v[a] + 1);
                        fprintf(f, "\n");
                    }
        }
    }
    fprintf(f, "$EndElements\n");
    return fclose(f) != 0;
}

static void write_material(FILE *f, const char *name, double young, double poisson, bool neo)
{
    fprintf(f, "*MATERIAL, NAME=%s\n", name);
    if (neo) {
        double mu = young / (2.0 * (1.0 + poisson)), kappa = young / (3.0 * (1.0 - 2.0 * poisson));
        fprintf(f, "** C10 = mu/2, D1 = 2/kappa: mu = %.14g Pa, kappa = %.14g Pa\n", mu, kappa);
        fprintf(f, "*HYPERELASTIC, NEO HOOKE\n%.14g, %.14g\n", mu / 2.0, 2.0 / kappa);
    } else {
        fprintf(f, "*ELASTIC\n%.14g, %.14g\n", young, poisson);
    }
}

/* CalculiX element id e + 1 of the deck's element e (hexahedra, then
 * tetrahedra): its mesh label. */
static int32_t deck_label(const ftm_mesh *m, int32_t e)
{
    const int32_t nh = ftm_mesh_hexahedron_count(m);
    return e < nh ? ftm_mesh_hexahedron_label(m, e) : ftm_mesh_tetrahedron_label(m, e - nh);
}

/* With [fem LABEL] sections: per label of the mesh (ascending), its element
 * set L<label>, material M<label> (the label's section, or [fem]) and solid
 * section. Returns how many labels were written (0: the scene has no
 * [fem LABEL] section, nothing written). */
static int32_t write_materials(FILE *f, const ftm_scene *sc, bool neo)
{
    int32_t nsec = 0;
    const ftm_label_material *sec = ftm_scene_label_materials(sc, &nsec);
    if (nsec == 0)
        return 0;
    const ftm_mesh *m = ftm_scene_mesh(sc);
    const int32_t ne = ftm_mesh_hexahedron_count(m) + ftm_mesh_tetrahedron_count(m);
    double young = 0, poisson = 0;
    ftm_scene_fem_material(sc, &young, &poisson, NULL);
    int32_t written = 0;
    for (int32_t prev = -1;;) { /* the next label above prev, until none */
        int32_t label = INT32_MAX;
        bool any = false;
        for (int32_t e = 0; e < ne; e++) {
            int32_t l = deck_label(m, e);
            if (l > prev && l <= label) {
                label = l;
                any = true;
            }
        }
        if (!any)
            break;
        fprintf(f, "*ELSET, ELSET=L%d\n", (int)label);
        int col = 0;
        for (int32_t e = 0; e < ne; e++)
            if (deck_label(m, e) == label)
                fprintf(f, "%d%s", (int)e + 1, ++col % 10 ? ", " : "\n");
        if (col % 10)
            fprintf(f, "\n");
        double E = young, nu = poisson;
        const char *from = "[fem]";
        for (int32_t i = 0; i < nsec; i++)
            if (label > 0 && sec[i].label == label) {
                E = sec[i].young;
                nu = sec[i].poisson;
                from = "its [fem LABEL]";
            }
        char name[32];
        snprintf(name, sizeof name, "M%d", (int)label);
        fprintf(f, "** label %d: %d elements, material from %s\n", (int)label, col, from);
        write_material(f, name, E, nu, neo);
        fprintf(f, "*SOLID SECTION, ELSET=L%d, MATERIAL=%s\n", (int)label, name);
        written++;
        prev = label;
    }
    return written;
}

/* ccx reads at most 16 entries per data line (the element lines have 9) and
 * at most 20 characters per number: %.14g, with sign and exponent */
static void write_deck(FILE *f, const ftm_scene *sc, const char *scene_path, bool neo,
                       int increments)
{
    const ftm_mesh *m = ftm_scene_mesh(sc);
    const int32_t n = ftm_mesh_node_count(m);
    double young = 0, poisson = 0;
    ftm_scene_fem_material(sc, &young, &poisson, NULL);
    fprintf(f, "** CalculiX deck of the FTM scene %s (%s), written by tests/calculix/ccx_deck.\n",
            ftm_scene_name(sc), scene_path);
    fprintf(f, "** Node k+1 is FTM input index k; element order as in the FTM mesh.\n");
    fprintf(f, "*HEADING\n%s, %s\n", ftm_scene_name(sc),
            neo ? "neo-Hookean, NLGEOM" : "linear elastic");
    fprintf(f, "*NODE, NSET=NALL\n");
    for (int32_t in = 0; in < n; in++) {
        ftm_vec3 x = ftm_mesh_rest_position(m, ftm_mesh_node_of_input(m, in));
        fprintf(f, "%d, %.14g, %.14g, %.14g\n", (int)in + 1, x.x, x.y, x.z);
    }
#define ID(v) ((int)ftm_mesh_input_of_node(m, (v)) + 1)
    const int32_t nh = ftm_mesh_hexahedron_count(m), nt = ftm_mesh_tetrahedron_count(m);
    int eid = 1;
    if (nh) {
        const int32_t *h = ftm_mesh_hexahedra(m);
        fprintf(f, "*ELEMENT, TYPE=C3D8, ELSET=EALL\n");
        for (int32_t e = 0; e < nh; e++, eid++) {
            fprintf(f, "%d", eid);
            for (int a = 0; a < 8; a++)
                fprintf(f, ", %d", ID(h[8 * e + a]));
            fprintf(f, "\n");
        }
    }
    if (nt) {
        const int32_t *t = ftm_mesh_tetrahedra(m);
        fprintf(f, "*ELEMENT, TYPE=C3D4, ELSET=EALL\n");
        for (int32_t e = 0; e < nt; e++, eid++) {
            int32_t v[4] = {t[4 * e], t[4 * e + 1], t[4 * e + 2], t[4 * e + 3]};
            ftm_vec3 p[4];
            for (int a = 0; a < 4; a++)
                p[a] = ftm_mesh_rest_position(m, v[a]);
            double ax = p[1].x - p[0].x, ay = p[1].y - p[0].y, az = p[1].z - p[0].z;
            double bx = p[2].x - p[0].x, by = p[2].y - p[0].y, bz = p[2].z - p[0].z;
            double cx = p[3].x - p[0].x, cy = p[3].y - p[0].y, cz = p[3].z - p[0].z;
            double v6 = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) +
                        az * (bx * cy - by * cx);
            if (v6 < 0) { /* CalculiX wants (2-1) x (3-1) . (4-1) > 0 */
                int32_t sw = v[2];
                v[2] = v[3];
                v[3] = sw;
            }
            fprintf(f, "%d, %d, %d, %d, %d\n", eid, ID(v[0]), ID(v[1]), ID(v[2]), ID(v[3]));
        }
    }
    /* sets: the clamped nodes, the displacement- and force-loaded ones */
    const ftm_scene_load *loads = ftm_scene_loads(sc);
    const int32_t nl = ftm_scene_load_count(sc);
    int col = 0;
    fprintf(f, "*NSET, NSET=FIXED\n");
    for (int32_t in = 0; in < n; in++)
        if (ftm_mesh_fixed(m, ftm_mesh_node_of_input(m, in)))
            fprintf(f, "%d%s", (int)in + 1, ++col % 10 ? ", " : "\n");
    if (col % 10)
        fprintf(f, "\n");
    bool any_disp = false;
    fprintf(f, "*NSET, NSET=PRESS\n");
    for (int32_t l = 0; l < nl; l++)
        if (loads[l].contact.kind == FTM_CONTACT_DISPLACEMENT) {
            fprintf(f, "%d\n", ID(loads[l].contact.node));
            any_disp = true;
        }
    const int32_t nlab = write_materials(f, sc, neo);
    if (nlab == 0) {
        write_material(f, "TISSUE", young, poisson, neo);
        fprintf(f, "*SOLID SECTION, ELSET=EALL, MATERIAL=TISSUE\n");
    }
    if (neo) {
        double inc = 1.0 / increments;
        fprintf(f, "*STEP, NLGEOM, INC=%d\n*STATIC\n%.14g, 1.0, %.14g, %.14g\n", 100 * increments,
                inc, inc / 1024.0, inc);
        /* Newton until the residual is 1e-9 of the mean force and the
         * correction 1e-9 of the increment (the defaults are 0.5 % and 1 %):
         * converged to the 7 digits ccx prints */
        fprintf(f, "*CONTROLS, PARAMETERS=FIELD\n1e-9, 1e-9\n");
    } else {
        fprintf(f, "*STEP\n*STATIC\n");
    }
    fprintf(f, "*BOUNDARY\nFIXED, 1, 3\n");
    for (int32_t l = 0; l < nl; l++) {
        const ftm_contact *c = &loads[l].contact;
        if (c->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        double v[3] = {c->value.x, c->value.y, c->value.z};
        for (int d = 0; d < 3; d++)
            fprintf(f, "%d, %d, %d, %.14g\n", ID(c->node), d + 1, d + 1, v[d]);
    }
    bool header = false;
    for (int32_t l = 0; l < nl; l++) {
        const ftm_contact *c = &loads[l].contact;
        if (c->kind != FTM_CONTACT_FORCE)
            continue;
        if (!header)
            fprintf(f, "*CLOAD\n");
        header = true;
        double v[3] = {c->value.x, c->value.y, c->value.z};
        for (int d = 0; d < 3; d++)
            if (v[d] != 0.0)
                fprintf(f, "%d, %d, %.14g\n", ID(c->node), d + 1, v[d]);
    }
#undef ID
    /* the end of the step only (ccx always prints a step's last increment) */
    fprintf(f, "*NODE PRINT, NSET=NALL, FREQUENCY=1000000\nU\n");
    if (any_disp)
        fprintf(f, "*NODE PRINT, NSET=PRESS, TOTALS=YES, FREQUENCY=1000000\nRF\n");
    fprintf(f, "*END STEP\n");
}

int main(int argc, char **argv)
{
    if (argc >= 2 && strcmp(argv[1], "--tetgen") == 0)
        return write_tetgen(argc - 2, argv + 2);
    if (argc >= 2 && strcmp(argv[1], "--gmsh-hex") == 0)
        return write_gmsh_hex(argc - 2, argv + 2);
    if (argc < 3)
        return usage();
    bool neo = false;
    int increments = 10;
    for (int i = 3; i < argc; i++) {
        if (strcmp(argv[i], "--model") == 0 && i + 1 < argc) {
            i++;
            if (strcmp(argv[i], "neo-hookean") == 0)
                neo = true;
            else if (strcmp(argv[i], "linear") != 0)
                return usage();
        } else if (strcmp(argv[i], "--increments") == 0 && i + 1 < argc) {
            char *end;
            long v = strtol(argv[++i], &end, 10);
            if (*end || v < 1 || v > 100000)
                return usage();
            increments = (int)v;
        } else {
            return usage();
        }
    }
    ftm_error err;
    ftm_scene *sc = NULL;
    if (ftm_scene_load_file(argv[1], &sc, &err) != FTM_OK) {
        fprintf(stderr, "ccx_deck: %s\n", err.message);
        return 2;
    }
    if (!ftm_scene_fem_material(sc, NULL, NULL, NULL)) {
        fprintf(stderr, "ccx_deck: %s: no [fem] section\n", argv[1]);
        ftm_scene_destroy(sc);
        return 2;
    }
    FILE *f = fopen(argv[2], "w");
    if (!f) {
        fprintf(stderr, "ccx_deck: %s: %s\n", argv[2], strerror(errno));
        ftm_scene_destroy(sc);
        return 1;
    }
    write_deck(f, sc, argv[1], neo, increments);
    int rc = fclose(f) != 0;
    ftm_scene_destroy(sc);
    return rc;
}
