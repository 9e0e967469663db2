/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Generated surface organ models (organs.h).
 *
 * A shape is a map P(q, phi) = c(q) + rho(q) (u(q, phi) n(q) + v(q, phi) b(q)):
 * q in [0, 1] runs along the organ from one pole to the other (the meridian),
 * c(q) is a point of the organ's axis, (n, b) a frame across it, rho the
 * radius and (u, v) the cross-section. Rings of nodes are placed at equal
 * meridian arc length, about sqrt(3)/2 of a spacing apart, each ring with as
 * many nodes as its perimeter holds spacings, at equal arc length along it;
 * two poles close the surface. Neighbouring rings are joined by the shorter
 * diagonal at each step (near-equilateral triangles), the poles by fans.
 * Any closed surface of genus 0 made so has T = 2V - 4 triangles, so the
 * paper's counts follow from the node count: the spacing is chosen (by
 * bisection) so that the rings hold V - 2 nodes, and the rounding remainder
 * goes to the rings whose perimeter has the most room. */
#include "organs.h"

#include "ftm/internal/load.h" /* ftm_load_commit: the OBJ loader's rules for springs */

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

/* The paper's counts (section 4.4). */
static const int32_t paper_nodes[FTM_ORGAN_COUNT] = {1769, 512};
static const char *const organ_names[FTM_ORGAN_COUNT] = {"lung", "stomach"};

ftm_material_def ftm_organ_material(void)
{
    /* About 0.3 g a node (a lung of 0.5 kg, a stomach of 0.15 kg), k / m as
     * in the default scene: h_crit about 2.2 ms for a surface node's 6-8
     * springs; d about twice the core's warning level at h = 1 ms (more
     * would only slow the soft modes' relaxation). */
    ftm_material_def m = ftm_default_material_def();
    m.node_mass = 3e-4;
    m.stiffness = 15.0;
    m.node_damping = 0.05;
    return m;
}

typedef struct vec3 {
    double x, y, z;
} vec3;

static vec3 v_add(vec3 a, vec3 b) { return (vec3){a.x + b.x, a.y + b.y, a.z + b.z}; }
static vec3 v_sub(vec3 a, vec3 b) { return (vec3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static vec3 v_scale(vec3 a, double s) { return (vec3){a.x * s, a.y * s, a.z * s}; }
static double v_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static double v_len(vec3 a) { return sqrt(v_dot(a, a)); }
static vec3 v_cross(vec3 a, vec3 b)
{
    return (vec3){a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
static vec3 v_at(const double *p, int32_t i) { return (vec3){p[3 * i], p[3 * i + 1], p[3 * i + 2]}; }

/* ---- the shapes ------------------------------------------------------------ */

typedef struct frame {
    vec3 c, n, b;
    double rho;
} frame;

/* Lung: z up, 0.25 m tall; x lateral (-) to medial (+), y front (-) to back
 * (+). The lower half is a flat half-ellipsoid (the base on the diaphragm),
 * the upper half a taller one narrowing to the apex. */
static const double lung_height = 0.25, lung_base = 0.05;
static const double lung_ax = 0.055, lung_ay = 0.085; /* cross-section semi-axes at the base */
static const double lung_taper = 0.35;               /* narrower toward the apex */
static const double lung_indent = 0.5;               /* the medial face's concavity */

static frame lung_frame(double q)
{
    double th = PI * q, ct = cos(th);
    double z = th <= PI / 2 ? lung_base * (1 - ct) : lung_base + (lung_height - lung_base) * -ct;
    double taper = 1 - lung_taper * fmax(0.0, -ct);
    return (frame){{0, 0, z}, {1, 0, 0}, {0, 1, 0}, sin(th) * taper};
}

/* An ellipse whose medial side (cos phi > 0) is pushed in: kidney-shaped,
 * the medial face concave (the heart's impression and the hilum). */
static void lung_section(double phi, double *u, double *v)
{
    double c = cos(phi), cp = fmax(c, 0.0);
    *u = lung_ax * (c - lung_indent * cp * cp * cp * cp);
    *v = lung_ay * sin(phi);
}

/* Stomach: a J. The axis runs down from the fundus (straight, 7 cm), then
 * around an arc of 7.5 cm radius through 200 degrees, up to the pylorus; the
 * radius narrows from the fundus (4.6 cm) to the pylorus (1.6 cm); rounded
 * caps at both ends; cross-sections flattened front to back. */
static const double st_top = 0.13, st_straight = 0.07, st_arc_r = 0.075;
static const double st_arc_deg = 200.0, st_flat = 0.8;
static const double st_knot_l[] = {0.0, 0.09, 0.19, 0.27, 1.0};
static const double st_knot_r[] = {0.046, 0.042, 0.034, 0.022, 0.016};

static double st_length(void) { return st_straight + st_arc_r * st_arc_deg * PI / 180.0; }

static double st_radius(double l)
{
    double L = st_length();
    int n = (int)(sizeof st_knot_l / sizeof st_knot_l[0]);
    for (int i = 0; i + 1 < n; i++) {
        double a = st_knot_l[i], b = i + 2 == n ? L : st_knot_l[i + 1];
        if (l <= b || i + 2 == n) {
            double t = fmin(1.0, fmax(0.0, (l - a) / (b - a)));
            t = 0.5 - 0.5 * cos(PI * t); /* smooth between the knots */
            return st_knot_r[i] + (st_knot_r[i + 1] - st_knot_r[i]) * t;
        }
    }
    return st_knot_r[n - 1];
}

/* Axis point, tangent and outward in-plane normal at arc length l. */
static void st_axis(double l, vec3 *c, vec3 *t, vec3 *n)
{
    if (l <= st_straight) {
        *c = (vec3){0, 0, st_top - l};
        *t = (vec3){0, 0, -1};
        *n = (vec3){-1, 0, 0};
        return;
    }
    double a = PI + (l - st_straight) / st_arc_r, ca = cos(a), sa = sin(a);
    vec3 centre = {st_arc_r, 0, st_top - st_straight};
    *c = v_add(centre, (vec3){st_arc_r * ca, 0, st_arc_r * sa});
    *t = (vec3){-sa, 0, ca};
    *n = (vec3){ca, 0, sa};
}

static frame stomach_frame(double q)
{
    double L = st_length(), r0 = st_radius(0), r1 = st_radius(L);
    double cap0 = PI * r0 / 2, cap1 = PI * r1 / 2, total = cap0 + L + cap1;
    double q0 = cap0 / total, q1 = (cap0 + L) / total;
    vec3 c, t, n;
    frame f;
    f.b = (vec3){0, 1, 0};
    if (q < q0) { /* the fundus's cap, beyond the axis's start */
        double beta = q / q0 * PI / 2;
        st_axis(0, &c, &t, &n);
        f.c = v_sub(c, v_scale(t, r0 * cos(beta)));
        f.rho = r0 * sin(beta);
    } else if (q <= q1) {
        double l = (q - q0) / (q1 - q0) * L;
        st_axis(l, &c, &t, &n);
        f.c = c;
        f.rho = st_radius(l);
    } else { /* the pylorus's cap */
        double beta = (q - q1) / (1 - q1) * PI / 2;
        st_axis(L, &c, &t, &n);
        f.c = v_add(c, v_scale(t, r1 * sin(beta)));
        f.rho = r1 * cos(beta);
    }
    f.n = n;
    return f;
}

static frame organ_frame(ftm_organ_kind kind, double q)
{
    return kind == FTM_ORGAN_LUNG ? lung_frame(q) : stomach_frame(q);
}

static vec3 organ_point(ftm_organ_kind kind, const frame *f, double phi)
{
    double u, v;
    if (kind == FTM_ORGAN_LUNG) {
        lung_section(phi, &u, &v);
    } else {
        u = cos(phi);
        v = st_flat * sin(phi);
    }
    return v_add(f->c, v_scale(v_add(v_scale(f->n, u), v_scale(f->b, v)), f->rho));
}

/* ---- meshing ------------------------------------------------------------------ */

enum { MERIDIAN_SAMPLES = 4000, MERIDIAN_PHIS = 16, SECTION_SAMPLES = 512 };

/* Cumulative perimeter of the cross-section at q (SECTION_SAMPLES + 1). */
static void section_lengths(ftm_organ_kind kind, double q, double *cum)
{
    frame f = organ_frame(kind, q);
    vec3 prev = organ_point(kind, &f, 0.0);
    cum[0] = 0.0;
    for (int k = 1; k <= SECTION_SAMPLES; k++) {
        vec3 p = organ_point(kind, &f, 2 * PI * k / SECTION_SAMPLES);
        cum[k] = cum[k - 1] + v_len(v_sub(p, prev));
        prev = p;
    }
}

/* The angle at which a fraction s of the perimeter (cum) is reached. */
static double section_angle(const double *cum, double s)
{
    double target = s * cum[SECTION_SAMPLES];
    int lo = 0, hi = SECTION_SAMPLES;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (cum[mid] <= target)
            lo = mid;
        else
            hi = mid;
    }
    double span = cum[hi] - cum[lo];
    double t = span > 0 ? (target - cum[lo]) / span : 0.0;
    return 2 * PI * (lo + t) / SECTION_SAMPLES;
}

typedef struct meridian {
    double cum[MERIDIAN_SAMPLES + 1]; /* mean arc length from q = 0 */
} meridian;

static void meridian_lengths(ftm_organ_kind kind, meridian *m)
{
    m->cum[0] = 0.0;
    frame f0 = organ_frame(kind, 0.0);
    vec3 prev[MERIDIAN_PHIS];
    for (int j = 0; j < MERIDIAN_PHIS; j++)
        prev[j] = organ_point(kind, &f0, 2 * PI * j / MERIDIAN_PHIS);
    for (int k = 1; k <= MERIDIAN_SAMPLES; k++) {
        frame f = organ_frame(kind, (double)k / MERIDIAN_SAMPLES);
        double sum = 0.0;
        for (int j = 0; j < MERIDIAN_PHIS; j++) {
            vec3 p = organ_point(kind, &f, 2 * PI * j / MERIDIAN_PHIS);
            sum += v_len(v_sub(p, prev[j]));
            prev[j] = p;
        }
        m->cum[k] = m->cum[k - 1] + sum / MERIDIAN_PHIS;
    }
}

/* q at a fraction s of the meridian's length. */
static double meridian_q(const meridian *m, double s)
{
    double target = s * m->cum[MERIDIAN_SAMPLES];
    int lo = 0, hi = MERIDIAN_SAMPLES;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (m->cum[mid] <= target)
            lo = mid;
        else
            hi = mid;
    }
    double span = m->cum[hi] - m->cum[lo];
    return (lo + (span > 0 ? (target - m->cum[lo]) / span : 0.0)) / MERIDIAN_SAMPLES;
}

/* Rings for a spacing: their count, q and perimeter. */
static int32_t ring_layout(ftm_organ_kind kind, const meridian *m, double spacing, double *q,
                           double *perim, int32_t max_rings)
{
    double total = m->cum[MERIDIAN_SAMPLES];
    long rings = lround(total / (spacing * sqrt(3.0) / 2)) - 1;
    if (rings < 1)
        rings = 1;
    if (rings > max_rings)
        rings = max_rings;
    double cum[SECTION_SAMPLES + 1];
    for (int32_t i = 0; i < rings; i++) {
        q[i] = meridian_q(m, (double)(i + 1) / (double)(rings + 1));
        section_lengths(kind, q[i], cum);
        perim[i] = cum[SECTION_SAMPLES];
    }
    return (int32_t)rings;
}

static int32_t ring_nodes(double perim, double spacing)
{
    long n = lround(perim / spacing);
    return n < 3 ? 3 : (int32_t)n;
}

static void add_tri(ftm_organ *o, int32_t *t, int32_t a, int32_t b, int32_t c)
{
    o->tris[3 * *t] = a;
    o->tris[3 * *t + 1] = b;
    o->tris[3 * *t + 2] = c;
    (*t)++;
}

static double dist2(const ftm_organ *o, int32_t a, int32_t b)
{
    vec3 d = v_sub(v_at(o->pos, a), v_at(o->pos, b));
    return v_dot(d, d);
}

/* Joins ring A (na nodes from a0) to ring B (nb from b0), both in the same
 * angular direction, by the shorter diagonal at each step. */
static void join_rings(ftm_organ *o, int32_t *t, int32_t a0, int32_t na, int32_t b0, int32_t nb)
{
    /* B's start: its node nearest A's first */
    int32_t jb = 0;
    for (int32_t j = 1; j < nb; j++)
        if (dist2(o, a0, b0 + j) < dist2(o, a0, b0 + jb))
            jb = j;
    int32_t ia = 0, ib = 0;
    while (ia < na || ib < nb) {
        int32_t a = a0 + ia % na, a1 = a0 + (ia + 1) % na;
        int32_t b = b0 + (jb + ib) % nb, b1 = b0 + (jb + ib + 1) % nb;
        bool advance_a = ib == nb || (ia < na && dist2(o, a1, b) <= dist2(o, a, b1));
        if (advance_a) {
            add_tri(o, t, a, a1, b);
            ia++;
        } else {
            add_tri(o, t, a, b1, b);
            ib++;
        }
    }
}

static void attachment(ftm_organ *o)
{
    static const double boxes[FTM_ORGAN_COUNT][6] = {
        /* lung: the hilum, in the middle of the medial face */
        {0.005, -0.022, 0.09, 0.1, 0.022, 0.15},
        /* stomach: the pylorus's end (the duodenum holds it) */
        {0.12, -0.03, 0.075, 0.2, 0.03, 0.13},
    };
    memcpy(o->fixed_box, boxes[o->kind], sizeof o->fixed_box);
    const double *b = o->fixed_box;
    for (int32_t i = 0; i < o->node_count; i++) {
        const double *p = o->pos + 3 * i;
        o->fixed[i] = p[0] >= b[0] && p[1] >= b[1] && p[2] >= b[2] && p[0] <= b[3] &&
                      p[1] <= b[4] && p[2] <= b[5];
    }
    static const ftm_vec3 targets[FTM_ORGAN_COUNT] = {
        {-0.05, 0.0, 0.09},  /* lung: the costal (lateral) face, low */
        {0.02, -0.04, 0.03}, /* stomach: the front wall of the body */
    };
    o->press_target = targets[o->kind];
}

void ftm_organ_free(ftm_organ *o)
{
    free(o->pos);
    free(o->axis);
    free(o->tris);
    free(o->fixed);
    memset(o, 0, sizeof *o);
}

int ftm_organ_generate(ftm_organ_kind kind, ftm_organ *o)
{
    memset(o, 0, sizeof *o);
    o->kind = kind;
    o->name = organ_names[kind];
    o->node_count = paper_nodes[kind];
    o->tri_count = 2 * o->node_count - 4;
    const int32_t want = o->node_count - 2, max_rings = o->node_count / 3;
    meridian *m = malloc(sizeof *m);
    double *q = malloc((size_t)max_rings * sizeof *q);
    double *perim = malloc((size_t)max_rings * sizeof *perim);
    int32_t *count = malloc((size_t)max_rings * sizeof *count);
    o->pos = malloc((size_t)o->node_count * 3 * sizeof *o->pos);
    o->axis = malloc((size_t)o->node_count * 3 * sizeof *o->axis);
    o->tris = malloc((size_t)o->tri_count * 3 * sizeof *o->tris);
    o->fixed = malloc((size_t)o->node_count * sizeof *o->fixed);
    if (!m || !q || !perim || !count || !o->pos || !o->axis || !o->tris || !o->fixed) {
        free(m);
        free(q);
        free(perim);
        free(count);
        ftm_organ_free(o);
        return FTM_ENOMEM;
    }
    meridian_lengths(kind, m);
    /* the spacing whose rings hold closest to V - 2 nodes (the count falls
     * as the spacing grows) */
    double lo = m->cum[MERIDIAN_SAMPLES] / 2000, hi = m->cum[MERIDIAN_SAMPLES] / 4;
    double best = hi;
    long best_err = -1;
    for (int it = 0; it < 80; it++) {
        double mid = 0.5 * (lo + hi);
        int32_t rings = ring_layout(kind, m, mid, q, perim, max_rings);
        long sum = 0;
        for (int32_t i = 0; i < rings; i++)
            sum += ring_nodes(perim[i], mid);
        if (best_err < 0 || labs(sum - want) < best_err) {
            best_err = labs(sum - want);
            best = mid;
        }
        if (sum > want)
            lo = mid;
        else
            hi = mid;
    }
    int32_t rings = ring_layout(kind, m, best, q, perim, max_rings);
    long sum = 0;
    for (int32_t i = 0; i < rings; i++)
        sum += count[i] = ring_nodes(perim[i], best);
    /* the remainder to the rings with the most room (or the least) */
    while (sum != want) {
        int32_t pick = -1;
        for (int32_t i = 0; i < rings; i++) {
            double room = perim[i] / best - count[i];
            if (sum > want && count[i] <= 3)
                continue;
            if (pick < 0 || (sum < want ? room > perim[pick] / best - count[pick]
                                        : room < perim[pick] / best - count[pick]))
                pick = i;
        }
        count[pick] += sum < want ? 1 : -1;
        sum += sum < want ? 1 : -1;
    }
    o->rings = rings;
    /* nodes: pole at q = 0, the rings, pole at q = 1 */
    double cum[SECTION_SAMPLES + 1];
    int32_t node = 0;
    for (int32_t i = -1; i <= rings; i++) {
        double qi = i < 0 ? 0.0 : i == rings ? 1.0 : q[i];
        frame f = organ_frame(kind, qi);
        int32_t n = i < 0 || i == rings ? 1 : count[i];
        if (n > 1)
            section_lengths(kind, qi, cum);
        for (int32_t j = 0; j < n; j++) {
            double phi = n > 1 ? section_angle(cum, (j + 0.5 * (i & 1)) / n) : 0.0;
            vec3 p = n > 1 ? organ_point(kind, &f, phi) : f.c;
            memcpy(o->pos + 3 * node, &p, sizeof p);
            memcpy(o->axis + 3 * node, &f.c, sizeof f.c);
            node++;
        }
    }
    /* triangles: the fans at the poles and the strips between rings */
    int32_t t = 0, start = 1;
    for (int32_t j = 0; j < count[0]; j++)
        add_tri(o, &t, 0, 1 + (j + 1) % count[0], 1 + j);
    for (int32_t i = 0; i + 1 < rings; i++) {
        join_rings(o, &t, start, count[i], start + count[i], count[i + 1]);
        start += count[i];
    }
    int32_t top = o->node_count - 1, last = count[rings - 1];
    for (int32_t j = 0; j < last; j++)
        add_tri(o, &t, top, start + j, start + (j + 1) % last);
    /* outward: counter-clockwise seen from outside (positive volume) */
    double vol = 0.0;
    for (int32_t k = 0; k < t; k++) {
        const int32_t *tr = o->tris + 3 * k;
        vol += v_dot(v_at(o->pos, tr[0]), v_cross(v_at(o->pos, tr[1]), v_at(o->pos, tr[2])));
    }
    if (vol < 0)
        for (int32_t k = 0; k < t; k++) {
            int32_t s = o->tris[3 * k + 1];
            o->tris[3 * k + 1] = o->tris[3 * k + 2];
            o->tris[3 * k + 2] = s;
        }
    attachment(o);
    free(m);
    free(q);
    free(perim);
    free(count);
    return FTM_OK;
}

/* ---- quality ------------------------------------------------------------------ */

static int cmp_u64(const void *pa, const void *pb)
{
    uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
    return (a > b) - (a < b);
}

void ftm_organ_measure(const ftm_organ *o, ftm_organ_quality *q)
{
    memset(q, 0, sizeof *q);
    q->nodes = o->node_count;
    q->triangles = o->tri_count;
    q->min_angle = 180.0;
    q->min_edge = INFINITY;
    /* directed edges (a, b) as a << 32 | b */
    uint64_t *dir = malloc((size_t)o->tri_count * 3 * sizeof *dir);
    int32_t *degree = calloc((size_t)o->node_count, sizeof *degree);
    if (!dir || !degree) {
        free(dir);
        free(degree);
        q->open_edges = -1;
        return;
    }
    double mean_area = 0.0;
    for (int32_t k = 0; k < o->tri_count; k++) {
        const int32_t *t = o->tris + 3 * k;
        mean_area += 0.5 * v_len(v_cross(v_sub(v_at(o->pos, t[1]), v_at(o->pos, t[0])),
                                         v_sub(v_at(o->pos, t[2]), v_at(o->pos, t[0]))));
    }
    mean_area /= o->tri_count;
    double edge_sum = 0.0;
    for (int32_t k = 0; k < o->tri_count; k++) {
        const int32_t *t = o->tris + 3 * k;
        vec3 p[3] = {v_at(o->pos, t[0]), v_at(o->pos, t[1]), v_at(o->pos, t[2])};
        vec3 cr = v_cross(v_sub(p[1], p[0]), v_sub(p[2], p[0]));
        double area = 0.5 * v_len(cr);
        q->area += area;
        q->volume += v_dot(p[0], v_cross(p[1], p[2])) / 6.0;
        if (!(area > 1e-3 * mean_area))
            q->degenerate++;
        vec3 centre = v_scale(v_add(v_add(p[0], p[1]), p[2]), 1.0 / 3);
        vec3 ax = v_scale(v_add(v_add(v_at(o->axis, t[0]), v_at(o->axis, t[1])),
                                v_at(o->axis, t[2])),
                          1.0 / 3);
        if (!(v_dot(cr, v_sub(centre, ax)) > 0))
            q->inverted++;
        double tri_min = 180.0;
        for (int e = 0; e < 3; e++) {
            vec3 a = v_sub(p[(e + 1) % 3], p[e]), b = v_sub(p[(e + 2) % 3], p[e]);
            double ang = acos(fmax(-1.0, fmin(1.0, v_dot(a, b) / (v_len(a) * v_len(b))))) *
                         180.0 / PI;
            tri_min = fmin(tri_min, ang);
            q->max_angle = fmax(q->max_angle, ang);
            double len = v_len(a);
            q->min_edge = fmin(q->min_edge, len);
            q->max_edge = fmax(q->max_edge, len);
            edge_sum += len;
            dir[3 * k + e] = (uint64_t)(uint32_t)t[e] << 32 | (uint32_t)t[(e + 1) % 3];
        }
        q->min_angle = fmin(q->min_angle, tri_min);
        q->below_20deg += tri_min < 20.0;
    }
    q->mean_edge = edge_sum / (3.0 * o->tri_count);
    /* closed and consistently oriented: every directed edge once, and its
     * reverse once */
    size_t n = (size_t)o->tri_count * 3;
    qsort(dir, n, sizeof *dir, cmp_u64);
    for (size_t i = 0; i < n; i++) {
        uint32_t a = (uint32_t)(dir[i] >> 32), b = (uint32_t)dir[i];
        if (i + 1 < n && dir[i + 1] == dir[i])
            q->misoriented_edges++;
        uint64_t rev = (uint64_t)b << 32 | a;
        if (!bsearch(&rev, dir, n, sizeof *dir, cmp_u64))
            q->open_edges++;
        if (a < b || !bsearch(&rev, dir, n, sizeof *dir, cmp_u64)) {
            q->edges++;
            degree[a]++;
            degree[b]++;
        }
    }
    for (int32_t i = 0; i < o->node_count; i++)
        q->max_degree = degree[i] > q->max_degree ? degree[i] : q->max_degree;
    q->euler = q->nodes - q->edges + q->triangles;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t i = 0; i < o->node_count; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], o->pos[3 * i + a]);
            hi[a] = fmax(hi[a], o->pos[3 * i + a]);
        }
    for (int a = 0; a < 3; a++)
        q->extent[a] = hi[a] - lo[a];
    free(dir);
    free(degree);
}

bool ftm_organ_quality_ok(const ftm_organ_quality *q)
{
    return q->triangles == 2 * q->nodes - 4 && q->euler == 2 && q->open_edges == 0 &&
           q->misoriented_edges == 0 && q->degenerate == 0 && q->inverted == 0 &&
           q->min_angle >= 20.0 && q->volume > 0;
}

/* ---- mesh, files ------------------------------------------------------------------ */

int ftm_organ_build(const ftm_organ *o, const ftm_material_def *material,
                    ftm_mesh_builder *builder, ftm_error *err)
{
    int32_t first = ftm_mesh_builder_node_count(builder);
    int rc = ftm_load_commit(builder, o->name, material,
                             &(ftm_load_data){.pos = o->pos,
                                              .node_count = (size_t)o->node_count,
                                              .tris = o->tris,
                                              .tri_count = (size_t)o->tri_count,
                                              .tri_edges = true},
                             err);
    for (int32_t i = 0; rc == FTM_OK && i < o->node_count; i++)
        if (o->fixed[i])
            rc = ftm_mesh_builder_set_fixed(builder, first + i, true);
    return rc;
}

int32_t ftm_organ_press_triangle(const ftm_organ *o, ftm_vec3 *normal)
{
    vec3 target = {o->press_target.x, o->press_target.y, o->press_target.z};
    int32_t best = 0;
    double best_d = INFINITY;
    for (int32_t k = 0; k < o->tri_count; k++) {
        const int32_t *t = o->tris + 3 * k;
        if (o->fixed[t[0]] || o->fixed[t[1]] || o->fixed[t[2]])
            continue;
        vec3 c = v_scale(v_add(v_add(v_at(o->pos, t[0]), v_at(o->pos, t[1])), v_at(o->pos, t[2])),
                         1.0 / 3);
        double d = v_len(v_sub(c, target));
        if (d < best_d) {
            best_d = d;
            best = k;
        }
    }
    const int32_t *t = o->tris + 3 * best;
    vec3 cr = v_cross(v_sub(v_at(o->pos, t[1]), v_at(o->pos, t[0])),
                      v_sub(v_at(o->pos, t[2]), v_at(o->pos, t[0])));
    cr = v_scale(cr, 1.0 / v_len(cr));
    *normal = (ftm_vec3){cr.x, cr.y, cr.z};
    return best;
}
