/* SPDX-License-Identifier: GPL-3.0-or-later */
/* client-organ: writes an organ-like test scene for the client's frame-rate
 * measurement (docs/client.md): a closed surface of 20480 triangles and
 * 10242 nodes shaped like a liver lobe (a flattened ellipsoid with a bulge
 * and a notch), springs on the triangle edges (the OBJ loader's rule), the
 * base fixed; plus a trainee script that presses into its top.
 *
 *   client-organ DIR   ->  DIR/organ.obj, DIR/organ.scene, DIR/press.bot
 *
 * The sphere is an icosahedron subdivided five times (each triangle into
 * four, midpoints pushed onto the sphere), then mapped point by point. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define LEVELS 5
#define MAXV (10 * (1 << (2 * LEVELS)) + 2)
#define MAXT (20 * (1 << (2 * LEVELS)))

static double vx[MAXV][3];
static int nv;
static int tri[MAXT][3], tri2[MAXT][3];
static int nt;

/* midpoint cache: for each vertex, a short list of (other, mid) */
typedef struct mid {
    int other, mid;
} mid;
static mid cache[MAXV][8];
static int ncache[MAXV];

static int add_vertex(double x, double y, double z)
{
    double l = sqrt(x * x + y * y + z * z);
    vx[nv][0] = x / l;
    vx[nv][1] = y / l;
    vx[nv][2] = z / l;
    return nv++;
}

static int midpoint(int a, int b)
{
    int lo = a < b ? a : b, hi = a < b ? b : a;
    for (int i = 0; i < ncache[lo]; i++)
        if (cache[lo][i].other == hi)
            return cache[lo][i].mid;
    int m = add_vertex(0.5 * (vx[a][0] + vx[b][0]), 0.5 * (vx[a][1] + vx[b][1]),
                       0.5 * (vx[a][2] + vx[b][2]));
    if (ncache[lo] == 8) {
        fprintf(stderr, "client-organ: midpoint cache overflow\n");
        exit(3);
    }
    cache[lo][ncache[lo]++] = (mid){hi, m};
    return m;
}

/* Unit sphere -> organ [m]: ellipsoid 18 x 12 x 8 cm, a bulge on the
 * right lobe, a notch at the back, a flatter underside. */
static void shape(const double u[3], double p[3])
{
    double x = u[0], y = u[1], z = u[2];
    double r = 1.0 + 0.22 * exp(-((x - 0.6) * (x - 0.6) + (y - 0.2) * (y - 0.2)) / 0.2) -
               0.15 * exp(-((x + 0.1) * (x + 0.1) + (y - 0.9) * (y - 0.9)) / 0.05);
    p[0] = 0.09 * r * x;
    p[1] = 0.06 * r * y;
    p[2] = 0.04 * r * (z >= 0 ? z : 0.6 * z);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: client-organ DIR\n");
        return 2;
    }
    const double t = (1.0 + sqrt(5.0)) / 2.0;
    const double ico[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                               {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                               {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    const int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                              {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                              {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                              {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (int i = 0; i < 12; i++)
        add_vertex(ico[i][0], ico[i][1], ico[i][2]);
    for (int i = 0; i < 20; i++)
        memcpy(tri[i], faces[i], sizeof tri[i]);
    nt = 20;
    for (int l = 0; l < LEVELS; l++) {
        memset(ncache, 0, sizeof ncache); /* midpoints of this level's edges only */
        int n2 = 0;
        for (int i = 0; i < nt; i++) {
            int a = tri[i][0], b = tri[i][1], c = tri[i][2];
            int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
            int q[4][3] = {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}};
            memcpy(tri2[n2], q, sizeof q);
            n2 += 4;
        }
        memcpy(tri, tri2, (size_t)n2 * sizeof tri[0]);
        nt = n2;
    }
    char path[4096];
    snprintf(path, sizeof path, "%s/organ.obj", argv[1]);
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "client-organ: cannot write %s: %s\n", path, strerror(errno));
        return 1;
    }
    fprintf(f, "# organ-like test surface for ftm-client (tests/client_gl/organ.c)\n");
    double top[3] = {0, 0, -1};
    for (int i = 0; i < nv; i++) {
        double p[3];
        shape(vx[i], p);
        fprintf(f, "v %.9f %.9f %.9f\n", p[0], p[1], p[2]);
        /* the highest point near (-2 cm, 0): where the trainee presses */
        if (fabs(p[0] + 0.02) < 0.004 && fabs(p[1]) < 0.004 && p[2] > top[2])
            memcpy(top, p, sizeof top);
    }
    for (int i = 0; i < nt; i++)
        fprintf(f, "f %d %d %d\n", tri[i][0] + 1, tri[i][1] + 1, tri[i][2] + 1);
    if (fclose(f)) {
        fprintf(stderr, "client-organ: cannot write %s\n", path);
        return 1;
    }
    snprintf(path, sizeof path, "%s/organ.scene", argv[1]);
    f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "client-organ: cannot write %s: %s\n", path, strerror(errno));
        return 1;
    }
    fprintf(f,
            "# Organ-like surface for the ftm-client frame-rate measurement\n"
            "# (written by tests/client_gl/organ.c): %d nodes, %d triangles.\n"
            "[scene]\nname = organ\n"
            "[mesh]\nfile = organ.obj\n"
            "# the flattened underside rests on the body\n"
            "fixed_box = -1 -1 -1 1 1 -0.018\n"
            "[material]\nmass = 0.0002\nstiffness = 10\ndamping = 0.05\n"
            "[sim]\ntime_step = 1e-3\ndepth = 8\n",
            nv, nt);
    if (fclose(f)) {
        fprintf(stderr, "client-organ: cannot write %s\n", path);
        return 1;
    }
    snprintf(path, sizeof path, "%s/press.bot", argv[1]);
    f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "client-organ: cannot write %s: %s\n", path, strerror(errno));
        return 1;
    }
    fprintf(f,
            "# Trainee on the organ scene: press 8 mm into the top, let go, press again.\n"
            "0.0 %.4f %.4f %.4f\n0.5 %.4f %.4f %.4f\n2.0 %.4f %.4f %.4f\n"
            "4.0 %.4f %.4f %.4f\n5.5 %.4f %.4f %.4f\n7.0 %.4f %.4f %.4f\n600 %.4f %.4f %.4f\n",
            top[0], top[1], top[2] + 0.015, top[0], top[1], top[2] + 0.015, top[0], top[1],
            top[2] - 0.008, top[0], top[1], top[2] - 0.008, top[0], top[1], top[2] + 0.015, top[0],
            top[1], top[2] - 0.008, top[0], top[1], top[2] - 0.008);
    if (fclose(f)) {
        fprintf(stderr, "client-organ: cannot write %s\n", path);
        return 1;
    }
    printf("client-organ: %s/organ.scene: %d nodes, %d triangles; press at (%.4f, %.4f, %.4f)\n",
           argv[1], nv, nt, top[0], top[1], top[2]);
    return 0;
}
