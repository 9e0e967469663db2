/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Uniform grid over the deformed surface triangles; see collide.h. */
#include "collide.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_DIM 256
#define MAX_CELLS (1 << 21)

typedef struct cell {
    int32_t n, cap;
    int32_t *tri;
} cell;

struct ftm_collide {
    const ftm_mesh *m;
    int32_t ntri;
    const int32_t *tris;
    double lo[3], h;
    int32_t dim[3];
    cell *cells;
    int16_t (*range)[6]; /* per triangle: i0 j0 k0 i1 j1 k1 */
    /* node -> incident triangles (CSR) */
    int32_t *inc_start, *inc_tri;
    /* surface nodes away from rest at the last update */
    int32_t *off, noff;
    uint32_t *node_stamp, *tri_stamp, stamp;
    int32_t *scratch;
    ftm_collide_stats st;
};

static int cell_index(const ftm_collide *c, int i, int j, int k)
{
    return (k * c->dim[1] + j) * c->dim[0] + i;
}

static int16_t coord(const ftm_collide *c, int axis, double v)
{
    double f = floor((v - c->lo[axis]) / c->h);
    if (!(f >= 0.0)) /* also NaN */
        return 0;
    if (f > c->dim[axis] - 1)
        return (int16_t)(c->dim[axis] - 1);
    return (int16_t)f;
}

static void tri_range(const ftm_collide *c, const double *x, int32_t t, int16_t r[6])
{
    const int32_t *v = c->tris + 3 * t;
    for (int a = 0; a < 3; a++) {
        double mn = x[3 * v[0] + a], mx = mn;
        for (int q = 1; q < 3; q++) {
            double w = x[3 * v[q] + a];
            mn = w < mn ? w : mn;
            mx = w > mx ? w : mx;
        }
        r[a] = coord(c, a, mn);
        r[3 + a] = coord(c, a, mx);
    }
}

static int cell_add(cell *cl, int32_t t)
{
    if (cl->n == cl->cap) {
        int32_t cap = cl->cap ? 2 * cl->cap : 8;
        int32_t *p = realloc(cl->tri, (size_t)cap * sizeof *p);
        if (!p)
            return -1;
        cl->tri = p;
        cl->cap = cap;
    }
    cl->tri[cl->n++] = t;
    return 0;
}

static void cell_remove(cell *cl, int32_t t)
{
    for (int32_t i = 0; i < cl->n; i++)
        if (cl->tri[i] == t) {
            cl->tri[i] = cl->tri[--cl->n];
            return;
        }
}

static int file_tri(ftm_collide *c, int32_t t, const int16_t r[6], bool add)
{
    for (int k = r[2]; k <= r[5]; k++)
        for (int j = r[1]; j <= r[4]; j++)
            for (int i = r[0]; i <= r[3]; i++) {
                cell *cl = &c->cells[cell_index(c, i, j, k)];
                if (add) {
                    if (cell_add(cl, t))
                        return -1;
                } else {
                    cell_remove(cl, t);
                }
            }
    return 0;
}

void ftm_collide_destroy(ftm_collide *c)
{
    if (!c)
        return;
    if (c->cells)
        for (int32_t i = 0; i < c->st.cells; i++)
            free(c->cells[i].tri);
    free(c->cells);
    free(c->range);
    free(c->inc_start);
    free(c->inc_tri);
    free(c->off);
    free(c->node_stamp);
    free(c->tri_stamp);
    free(c->scratch);
    free(c);
}

int ftm_collide_create(const ftm_mesh *m, ftm_collide **out, ftm_error *err)
{
    int32_t n = ftm_mesh_node_count(m), nt = ftm_mesh_triangle_count(m);
    ftm_collide *c = calloc(1, sizeof *c);
    if (!c)
        goto nomem;
    c->m = m;
    c->ntri = nt;
    c->tris = ftm_mesh_triangles(m);
    c->inc_start = calloc((size_t)n + 1, sizeof *c->inc_start);
    c->inc_tri = malloc(((size_t)nt * 3 + 1) * sizeof *c->inc_tri);
    c->off = malloc(((size_t)n + 1) * sizeof *c->off);
    c->node_stamp = calloc((size_t)n + 1, sizeof *c->node_stamp);
    c->tri_stamp = calloc((size_t)nt + 1, sizeof *c->tri_stamp);
    c->scratch = malloc(((size_t)n + 1) * sizeof *c->scratch);
    c->range = malloc(((size_t)nt + 1) * sizeof *c->range);
    if (!c->inc_start || !c->inc_tri || !c->off || !c->node_stamp || !c->tri_stamp ||
        !c->scratch || !c->range)
        goto nomem;
    for (int32_t i = 0; i < 3 * nt; i++)
        c->inc_start[c->tris[i] + 1]++;
    for (int32_t i = 0; i < n; i++)
        c->inc_start[i + 1] += c->inc_start[i];
    int32_t *fill = c->scratch;
    memcpy(fill, c->inc_start, (size_t)n * sizeof *fill);
    for (int32_t t = 0; t < nt; t++)
        for (int q = 0; q < 3; q++)
            c->inc_tri[fill[c->tris[3 * t + q]]++] = t;

    /* bounds and cell size from the rest surface */
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double edge = 0.0;
    for (int32_t t = 0; t < nt; t++)
        for (int q = 0; q < 3; q++) {
            ftm_vec3 p = ftm_mesh_rest_position(m, c->tris[3 * t + q]);
            ftm_vec3 p2 = ftm_mesh_rest_position(m, c->tris[3 * t + (q + 1) % 3]);
            double v[3] = {p.x, p.y, p.z};
            for (int a = 0; a < 3; a++) {
                lo[a] = v[a] < lo[a] ? v[a] : lo[a];
                hi[a] = v[a] > hi[a] ? v[a] : hi[a];
            }
            edge += sqrt((p.x - p2.x) * (p.x - p2.x) + (p.y - p2.y) * (p.y - p2.y) +
                         (p.z - p2.z) * (p.z - p2.z));
        }
    if (nt == 0) {
        for (int a = 0; a < 3; a++)
            lo[a] = hi[a] = 0.0;
        edge = 1.0;
    } else {
        edge /= 3.0 * nt;
    }
    double ext = 0.0;
    for (int a = 0; a < 3; a++)
        ext = hi[a] - lo[a] > ext ? hi[a] - lo[a] : ext;
    double margin = 0.25 * ext + 2.0 * edge;
    c->h = 2.0 * edge > 0.0 ? 2.0 * edge : 1.0;
    for (;;) {
        int64_t cells = 1;
        for (int a = 0; a < 3; a++) {
            c->lo[a] = lo[a] - margin;
            double span = hi[a] - lo[a] + 2.0 * margin;
            int64_t d = (int64_t)ceil(span / c->h);
            d = d < 1 ? 1 : d;
            c->dim[a] = (int32_t)(d > MAX_DIM ? MAX_DIM + 1 : d);
            cells *= c->dim[a];
        }
        if (cells <= MAX_CELLS && c->dim[0] <= MAX_DIM && c->dim[1] <= MAX_DIM &&
            c->dim[2] <= MAX_DIM)
            break;
        c->h *= 1.5;
    }
    c->st.cells = c->dim[0] * c->dim[1] * c->dim[2];
    memcpy(c->st.dims, c->dim, sizeof c->dim);
    c->st.cell_size = c->h;
    c->st.extent = ext;
    c->st.triangles = nt;
    c->cells = calloc((size_t)c->st.cells, sizeof *c->cells);
    if (!c->cells)
        goto nomem;
    /* file every triangle at rest */
    int32_t rest_n = n;
    double *rest = malloc(((size_t)rest_n * 3 + 1) * sizeof *rest);
    if (!rest)
        goto nomem;
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 p = ftm_mesh_rest_position(m, i);
        rest[3 * i] = p.x;
        rest[3 * i + 1] = p.y;
        rest[3 * i + 2] = p.z;
    }
    for (int32_t t = 0; t < nt; t++) {
        tri_range(c, rest, t, c->range[t]);
        if (file_tri(c, t, c->range[t], true)) {
            free(rest);
            goto nomem;
        }
    }
    free(rest);
    *out = c;
    return FTM_OK;
nomem:
    ftm_collide_destroy(c);
    if (err) {
        err->code = FTM_ENOMEM;
        snprintf(err->message, sizeof err->message, "collision grid: out of memory");
    }
    return FTM_ENOMEM;
}

static bool at_rest(const ftm_mesh *m, const double *x, int32_t i)
{
    ftm_vec3 r = ftm_mesh_rest_position(m, i);
    return x[3 * i] == r.x && x[3 * i + 1] == r.y && x[3 * i + 2] == r.z;
}

void ftm_collide_update(ftm_collide *c, const double *x, const int32_t *maybe_moved, int32_t count)
{
    c->st.updates++;
    if (++c->stamp == 0) { /* wrapped: clear the stamps */
        memset(c->node_stamp, 0, (size_t)ftm_mesh_node_count(c->m) * sizeof *c->node_stamp);
        memset(c->tri_stamp, 0, (size_t)c->ntri * sizeof *c->tri_stamp);
        c->stamp = 1;
    }
    /* candidates: surface nodes among maybe_moved, and last update's off-rest nodes */
    int32_t nc = 0;
    int32_t *cand = c->scratch;
    for (int32_t k = 0; k < c->noff; k++) {
        int32_t i = c->off[k];
        if (c->node_stamp[i] != c->stamp) {
            c->node_stamp[i] = c->stamp;
            cand[nc++] = i;
        }
    }
    for (int32_t k = 0; k < count; k++) {
        int32_t i = maybe_moved[k];
        if (c->inc_start[i + 1] > c->inc_start[i] && c->node_stamp[i] != c->stamp) {
            c->node_stamp[i] = c->stamp;
            cand[nc++] = i;
        }
    }
    c->noff = 0;
    for (int32_t k = 0; k < nc; k++) {
        int32_t i = cand[k];
        if (!at_rest(c->m, x, i))
            c->off[c->noff++] = i;
        for (int32_t e = c->inc_start[i]; e < c->inc_start[i + 1]; e++) {
            int32_t t = c->inc_tri[e];
            if (c->tri_stamp[t] == c->stamp)
                continue;
            c->tri_stamp[t] = c->stamp;
            int16_t r[6];
            tri_range(c, x, t, r);
            if (memcmp(r, c->range[t], sizeof r) == 0)
                continue;
            file_tri(c, t, c->range[t], false);
            if (file_tri(c, t, r, true) == 0)
                memcpy(c->range[t], r, sizeof r);
            else /* out of memory: keep it filed where it was */
                file_tri(c, t, c->range[t], true);
            c->st.refiled++;
        }
    }
}

/* Moller-Trumbore, two-sided. */
static bool seg_tri(const double *p0, const double *p1, const double *p2, ftm_vec3 a, ftm_vec3 b,
                    double *t, double *u, double *v)
{
    double d[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
    double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
    double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                    d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (fabs(det) < 1e-300)
        return false;
    double inv = 1.0 / det;
    double s[3] = {a.x - p0[0], a.y - p0[1], a.z - p0[2]};
    double uu = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) * inv;
    if (uu < 0.0 || uu > 1.0)
        return false;
    double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                   s[0] * e1[1] - s[1] * e1[0]};
    double vv = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
    if (vv < 0.0 || uu + vv > 1.0)
        return false;
    double tt = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
    if (tt < 0.0 || tt > 1.0)
        return false;
    *t = tt;
    *u = uu;
    *v = vv;
    return true;
}

int32_t ftm_collide_segment(ftm_collide *c, const double *x, ftm_vec3 a, ftm_vec3 b, double *t,
                            double bary[3])
{
    c->st.queries++;
    if (++c->stamp == 0) {
        memset(c->node_stamp, 0, (size_t)ftm_mesh_node_count(c->m) * sizeof *c->node_stamp);
        memset(c->tri_stamp, 0, (size_t)c->ntri * sizeof *c->tri_stamp);
        c->stamp = 1;
    }
    int16_t r[6];
    double pa[3] = {a.x, a.y, a.z}, pb[3] = {b.x, b.y, b.z};
    for (int ax = 0; ax < 3; ax++) {
        r[ax] = coord(c, ax, pa[ax] < pb[ax] ? pa[ax] : pb[ax]);
        r[3 + ax] = coord(c, ax, pa[ax] > pb[ax] ? pa[ax] : pb[ax]);
    }
    int32_t best = -1;
    double best_t = INFINITY;
    for (int k = r[2]; k <= r[5]; k++)
        for (int j = r[1]; j <= r[4]; j++)
            for (int i = r[0]; i <= r[3]; i++) {
                const cell *cl = &c->cells[cell_index(c, i, j, k)];
                for (int32_t e = 0; e < cl->n; e++) {
                    int32_t tr = cl->tri[e];
                    if (c->tri_stamp[tr] == c->stamp)
                        continue;
                    c->tri_stamp[tr] = c->stamp;
                    c->st.tested++;
                    const int32_t *v = c->tris + 3 * tr;
                    double tt, u, w;
                    if (seg_tri(x + 3 * v[0], x + 3 * v[1], x + 3 * v[2], a, b, &tt, &u, &w) &&
                        (tt < best_t || (tt == best_t && tr < best))) {
                        best = tr;
                        best_t = tt;
                        bary[0] = 1.0 - u - w;
                        bary[1] = u;
                        bary[2] = w;
                    }
                }
            }
    if (best >= 0)
        *t = best_t;
    return best;
}

void ftm_collide_get_stats(const ftm_collide *c, ftm_collide_stats *st) { *st = c->st; }
