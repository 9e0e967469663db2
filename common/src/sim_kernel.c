/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The hot loop of the integrator: spring forces (Eq. 6), the central
 * difference update (Eq. 8) and the sweeps over the schedule in each order,
 * plus reactions (Eq. 19). */
#include "sim_elem.h"
#include "sim_internal.h"

#include <math.h>
#include <string.h>

/* One link of row slot s: r = xi - x_j, its length |r| + FTM_LEN_EPS and
 * kd = k (|r| - l); adds kd (|r| - l) to *e. */
static inline __attribute__((always_inline)) double link_eval(const ftm_mesh *restrict m,
                                                              const double *restrict x, int32_t s,
                                                              const double xi[3], double r[3],
                                                              double *kd, double *e)
{
    const double *xj = x + 3 * m->adj_node[s];
    r[0] = xi[0] - xj[0];
    r[1] = xi[1] - xj[1];
    r[2] = xi[2] - xj[2];
    double len = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) + FTM_LEN_EPS;
    double ext = len - m->adj_len[s];
    *kd = m->adj_k[s] * ext;
    *e += *kd * ext;
    return len;
}

/* Sum of the spring forces f_ij (Eq. 6) on node i placed at xi:
 *     f_ij = t r,   t = k (|r| - l) / |r|,   r = xi - x_j,
 * over its neighbours in adjacency order (one fixed order, so every caller
 * and every machine rounds the same way). Written this way t is exactly 0 at
 * the rest length (rest lengths are the rest positions' distances computed
 * the same way), so an unloaded mesh at rest is an exact equilibrium.
 * The division is shared by each pair of consecutive links (row slots 2p,
 * 2p+1): w = 1 / (|r_a| |r_b|), t_a = k_a (|r_a| - l_a) (|r_b| w) and t_b
 * likewise, one division for two links where the vector kernel is bound by
 * the divider. A row of odd length pairs its last link with what a padding
 * slot of the vector kernel's padded rows measures, |r| = FTM_LEN_EPS. The
 * products stay normal: every |r| is >= FTM_LEN_EPS = 1e-150, and one above
 * 1.3e154 has already overflowed |r|^2.
 * pe (if not NULL): sum of k (|r| - l)^2 over the links, for the energy
 * guard; a link is seen from both ends, so a node owns a quarter of it. */
static inline __attribute__((always_inline)) void
spring_force_pe(const ftm_mesh *restrict m, const double *restrict x, int32_t i, const double xi[3],
                double f[3], double *pe)
{
    double fx = 0.0, fy = 0.0, fz = 0.0, e = 0.0;
    const int32_t end = m->adj_start[i + 1];
    int32_t s = m->adj_start[i];
    for (; s + 1 < end; s += 2) {
        double ra[3], rb[3], kda, kdb;
        const double la = link_eval(m, x, s, xi, ra, &kda, &e);
        const double lb = link_eval(m, x, s + 1, xi, rb, &kdb, &e);
        const double w = 1.0 / (la * lb), ta = kda * (lb * w), tb = kdb * (la * w);
        fx += ta * ra[0];
        fy += ta * ra[1];
        fz += ta * ra[2];
        fx += tb * rb[0];
        fy += tb * rb[1];
        fz += tb * rb[2];
    }
    if (s < end) { /* the unpaired last link, with a padding slot's length */
        double ra[3], kda;
        const double la = link_eval(m, x, s, xi, ra, &kda, &e);
        const double w = 1.0 / (la * FTM_LEN_EPS), ta = kda * (FTM_LEN_EPS * w);
        fx += ta * ra[0];
        fy += ta * ra[1];
        fz += ta * ra[2];
    }
    f[0] = fx;
    f[1] = fy;
    f[2] = fz;
    if (pe)
        *pe = e;
}

/* The same without the energy (the compiler drops its arithmetic). */
static inline void spring_force(const ftm_mesh *restrict m, const double *restrict x, int32_t i,
                                const double xi[3], double f[3])
{
    spring_force_pe(m, x, i, xi, f, NULL);
}

/* Eq. 8 for node i: new position from the spring forces f, the external
 * force, the current and the previous position. Returns the squared motion. */
static inline double integrate(const ftm_sim *sim, int32_t i, const double cur[3],
                               const double f[3], double out[3])
{
    const double *c = sim->coef + FTM_COEF * i, *F = sim->force + 3 * i, *p = sim->xp + 3 * i;
    for (int d = 0; d < 3; d++)
        out[d] = c[0] * (F[d] - f[d]) + c[1] * cur[d] - c[2] * p[d];
    double dx = out[0] - cur[0], dy = out[1] - cur[1], dz = out[2] - cur[2];
    return dx * dx + dy * dy + dz * dz;
}

/* Gauss-Seidel sweep over schedule positions [k0, k1): each node reads the
 * current (already updated where earlier) positions of its neighbours.
 * Returns false if a node moved more than its guard limit or to a non-finite
 * position. The overwritten previous positions are saved for rollback. */
bool ftm_sweep_gs(ftm_sim *sim, int32_t k0, int32_t k1, double *max_m2)
{
    const ftm_mesh *m = sim->m;
    schedule *s = &sim->s;
    double *restrict x = sim->x, *restrict xp = sim->xp;
    bool ok = true;
    double mm = *max_m2, en = 0.0;
    for (int32_t k = k0; k < k1; k++) {
        int32_t i = s->node[k];
        double *xi = x + 3 * i, *pi = xp + 3 * i, *sv = s->save + 3 * k;
        double cur[3] = {xi[0], xi[1], xi[2]}, f[3], nw[3], pe, ground = 0.0;
        spring_force_pe(m, x, i, cur, f, &pe);
        double m2 = m->bc && m->bc[i] ? ftm_bc_update(sim, i, cur, f, nw, &ground)
                                      : integrate(sim, i, cur, f, nw);
        ok &= m2 <= ftm_sim_lim2(sim, i); /* false for NaN too */
        mm = m2 > mm ? m2 : mm;
        en += sim->ke_w[i] * m2 + 0.25 * pe + ground;
        for (int d = 0; d < 3; d++) {
            sv[d] = pi[d];
            pi[d] = cur[d];
            xi[d] = nw[d];
        }
    }
    *max_m2 = mm;
    sim->energy += en;
    return ok;
}

/* The coefficient rows (a, b, c, lim2) of nodes on[0..3] as a, b, c and
 * lim2 vectors: four 32-byte loads and a 4 x 4 transpose, in place of
 * sixteen scalar loads from separate arrays (docs/benchmarks.md). */
static inline __attribute__((always_inline)) void load_coef4(const double *p, const size_t on[4],
                                                             v4d *a, v4d *b, v4d *c, v4d *lim2)
{
    const v4d r0 = LOAD4(p + FTM_COEF * on[0]), r1 = LOAD4(p + FTM_COEF * on[1]),
              r2 = LOAD4(p + FTM_COEF * on[2]), r3 = LOAD4(p + FTM_COEF * on[3]);
    const v4d ac01 = __builtin_shufflevector(r0, r1, 0, 4, 2, 6),
              bl01 = __builtin_shufflevector(r0, r1, 1, 5, 3, 7),
              ac23 = __builtin_shufflevector(r2, r3, 0, 4, 2, 6),
              bl23 = __builtin_shufflevector(r2, r3, 1, 5, 3, 7);
    *a = __builtin_shufflevector(ac01, ac23, 0, 1, 4, 5);
    *b = __builtin_shufflevector(bl01, bl23, 0, 1, 4, 5);
    *c = __builtin_shufflevector(ac01, ac23, 2, 3, 6, 7);
    *lim2 = __builtin_shufflevector(bl01, bl23, 2, 3, 6, 7);
}

/* The group sweep, for the Jacobi and the colored orders: the nodes of a
 * group (a layer in the Jacobi order, an independent set in the colored one)
 * read only the state before the group, so they are independent and are
 * updated JW per vector straight from the schedule, without waiting on each
 * other. In the colored order no two nodes of a group are adjacent, so this
 * is also exactly updating them one after another (the shared-colour set,
 * whose nodes may be adjacent, is one group per node). sim_groups.inc holds
 * the sweep, sim_block.inc one block of it: 4 lanes for AVX and SSE2, 8 for
 * AVX-512 (whose 32 registers hold two blocks' chains of square roots and
 * divisions at once), where a group's last block of four nodes or fewer
 * runs 4 lanes wide at half the cost. Lane l does
 * exactly what spring_force and integrate do for its node (padding slots
 * add -0.0), so the state is bit-identical to updating the group's nodes one
 * by one from a copy of the state before it; the energy is summed in the same
 * order by every variant (an 8-lane block as its two 4-lane halves). */

/* the (k, len) pairs of four padded rows at slot sl, as k and len vectors */
static inline __attribute__((always_inline)) void load_kl4(const double *const kl[4], int32_t sl,
                                                           v4d *k, v4d *len)
{
    v4d p02 = __builtin_shufflevector(LOAD2(kl[0] + 2 * sl), LOAD2(kl[2] + 2 * sl), 0, 1, 2, 3),
        p13 = __builtin_shufflevector(LOAD2(kl[1] + 2 * sl), LOAD2(kl[3] + 2 * sl), 0, 1, 2, 3);
    *k = __builtin_shufflevector(p02, p13, 0, 4, 2, 6);
    *len = __builtin_shufflevector(p02, p13, 1, 5, 3, 7);
}

#define GATHER4A(p, i) GATHER4(p, i[0], i[1], i[2], i[3])
#define LOAD_XYZ4(p, o, x, y, z) ftm_load_xyz4(p, o[0], o[1], o[2], o[3], x, y, z)
#define LOAD_XY4(p, o, x, y) ftm_load_xy4(p, o[0], o[1], o[2], o[3], x, y)
#define BW 4
#define BV v4d
#define BL v4l
#define BTARGET
#define BLOAD LOAD_XYZ4
#define BLOADXY LOAD_XY4
#define BGATHER GATHER4A
#define BLOAD_KL load_kl4
#define BLOAD_COEF load_coef4
#define BS 4
#define BNAME block4_in4
#include "sim_block.inc"
#undef BS
#undef BNAME
#define BS 8 /* the tails of the 8-lane layout */
#define BNAME block4_in8
#include "sim_block.inc"
#undef BS
#undef BNAME
#undef BW
#undef BV
#undef BL
#undef BTARGET
#undef BLOAD
#undef BLOADXY
#undef BGATHER
#undef BLOAD_KL
#undef BLOAD_COEF

#define JW 4
#define JV v4d
#define JTARGET
#define JL v4l
#define JNAME sweep_groups_body4
#define JBLOCK block4_in4
#include "sim_groups.inc"
#undef JW
#undef JV
#undef JTARGET
#undef JL
#undef JNAME
#undef JBLOCK
/* one instance of the sweep per (links read, recorded or neither; planar;
 * rows padded or compact; constrained nodes or none): constants in the body.
 * A mesh with constrained nodes (sliding, springs to ground) runs instances
 * of its own, so that the others' loops hold no call to ftm_bc_group (with
 * it, GCC 12 kept their vector accumulators in memory) */
#define SWEEP_PLANAR(body, sim, max_m2, linked, record, compact, bcs)                          \
    (ftm_sim_planar(sim) ? body(sim, max_m2, linked, record, true, compact, bcs)               \
                         : body(sim, max_m2, linked, record, false, compact, bcs))
#define SWEEP_ROWS(body, sim, max_m2, linked, record, bcs)                                     \
    ((sim)->pad_rows ? SWEEP_PLANAR(body, sim, max_m2, linked, record, false, bcs)             \
                     : SWEEP_PLANAR(body, sim, max_m2, linked, record, true, bcs))
#define SWEEP_LINKS(body, sim, max_m2, bcs)                                                    \
    ((sim)->s.linked              ? SWEEP_PLANAR(body, sim, max_m2, true, false, false, bcs)   \
     : ftm_sim_record_links(sim) ? SWEEP_ROWS(body, sim, max_m2, false, true, bcs)            \
                                  : SWEEP_ROWS(body, sim, max_m2, false, false, bcs))
/* the sweep of a kernel (TARGET, body) as two functions, the constrained
 * meshes' instances in one of their own, so the other's code is as it was */
#define SWEEP_FUNCTIONS(name, TARGET, body)                                                    \
    TARGET __attribute__((noinline)) static bool name##_bc(ftm_sim *sim, double *max_m2)       \
    {                                                                                          \
        return SWEEP_LINKS(body, sim, max_m2, true);                                           \
    }                                                                                          \
    TARGET static bool name(ftm_sim *sim, double *max_m2)                                      \
    {                                                                                          \
        if (__builtin_expect((sim)->m->bc != NULL, 0))                                         \
            return name##_bc(sim, max_m2);                                                     \
        return SWEEP_LINKS(body, sim, max_m2, false);                                          \
    }

#if defined(__x86_64__) || defined(__i386__) /* the 8-lane build is for AVX-512 */
#include "simd8.h"

#define BW 8
#define BV v8d
#define BL v8l
#define BTARGET __attribute__((target("avx512f")))
#define BLOAD load_xyz8
#define BLOADXY load_xy8
#define BGATHER GATHER8
#define BLOAD_KL load_kl8
#define BLOAD_COEF load_coef8
#define BS 8
#define BNAME block8_in8
#include "sim_block.inc"

#define JW 8
#define JV v8d
#define JTARGET __attribute__((target("avx512f")))
#define JL v8l
#define JNAME sweep_groups_body8
#define JBLOCK block8_in8
#define JBLOCK4 block4_in8
#include "sim_groups.inc"

SWEEP_FUNCTIONS(sweep_groups_avx512, __attribute__((target("avx512f"))), sweep_groups_body8)
SWEEP_FUNCTIONS(sweep_groups_avx, __attribute__((target("avx"))), sweep_groups_body4)
#endif

SWEEP_FUNCTIONS(sweep_groups_portable, , sweep_groups_body4)

void ftm_sim_select_kernel(ftm_sim *sim, bool portable)
{
    sim->sweep_groups = sweep_groups_portable;
    sim->group_lanes = 4;
#if defined(__x86_64__) || defined(__i386__)
    if (!portable && __builtin_cpu_supports("avx")) {
        sim->sweep_groups = sweep_groups_avx;
    }
    if (!portable && __builtin_cpu_supports("avx512f")) {
        sim->sweep_groups = sweep_groups_avx512;
        sim->group_lanes = 8;
    }
#endif
    if (sim->elem)
        ftm_elem_select_kernel(sim->elem,
                               portable ? FTM_ELEM_KERNEL_PORTABLE : FTM_ELEM_KERNEL_BEST);
    /* the group orders' links are laid out for the kernel's lane count */
    if (sim->def.order != FTM_ORDER_BFS)
        sim->s.linked = false;
}

/* Relaxing nodes, in ascending order. */
bool ftm_sweep_relax(ftm_sim *sim)
{
    bool ok = true;
    double en = 0.0;
    for (int32_t r = 0; r < sim->nrelax; r++) {
        int32_t i = sim->relax[r];
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        double cur[3] = {xi[0], xi[1], xi[2]}, f[3], nw[3], pe, ground = 0.0;
        spring_force_pe(sim->m, sim->x, i, cur, f, &pe);
        double m2 = sim->m->bc && sim->m->bc[i] ? ftm_bc_update(sim, i, cur, f, nw, &ground)
                                                : integrate(sim, i, cur, f, nw);
        ok &= m2 <= ftm_sim_lim2(sim, i);
        en += sim->ke_w[i] * m2 + 0.25 * pe + ground;
        for (int d = 0; d < 3; d++) {
            pi[d] = cur[d];
            xi[d] = nw[d];
        }
    }
    sim->energy += en;
    return ok;
}

bool ftm_bc_group(ftm_sim *sim, int32_t k0, int32_t k1, double *tmp, int w, double *mm,
                  double *en)
{
    const ftm_mesh *m = sim->m;
    bool ok = true;
    for (int32_t k = k0; k < k1; k++) {
        const int32_t i = sim->s.node[k];
        if (!m->bc[i])
            continue;
        const double *xi = sim->x + 3 * (size_t)i;
        double cur[3] = {xi[0], xi[1], xi[2]}, f[3], nw[3], pe, ground;
        spring_force_pe(m, sim->x, i, cur, f, &pe);
        const double m2 = ftm_bc_update(sim, i, cur, f, nw, &ground);
        ok &= m2 <= ftm_sim_lim2(sim, i);
        *mm = m2 > *mm ? m2 : *mm;
        *en += sim->ke_w[i] * m2 + 0.25 * pe + ground;
        double *t = tmp + 3 * (size_t)((k - k0) & ~(w - 1)) + ((k - k0) & (w - 1));
        t[0] = nw[0];
        t[w] = nw[1];
        t[2 * w] = nw[2];
    }
    return ok;
}

void ftm_sim_compute_reactions(ftm_sim *sim)
{
    if (sim->reaction_groups)
        memset(sim->reaction, 0, (size_t)sim->reaction_groups * 3 * sizeof(double));
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        if (ct->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        double f[3];
        spring_force(sim->m, sim->x, ct->node, sim->x + 3 * ct->node, f);
        if (sim->m->bc) /* a held node on a spring to ground pulls on it too */
            ftm_bc_ground_force(sim->m, ct->node, sim->x + 3 * ct->node, f);
        double *r = sim->reaction + 3 * ct->group;
        r[0] -= f[0];
        r[1] -= f[1];
        r[2] -= f[2];
    }
}

/* k (|r| - l)^2 summed over node i's links at the current positions: the
 * energy guard's account of what a held (displaced) node's links store. */
double ftm_sim_link_pe(const ftm_sim *sim, int32_t i)
{
    double f[3], pe;
    spring_force_pe(sim->m, sim->x, i, sim->x + 3 * i, f, &pe);
    return pe;
}

/* Spring force sum on node i at the current positions (for the energy
 * guard's account of the work a displacement contact does). */
void ftm_sim_spring_force(const ftm_sim *sim, int32_t i, double f[3])
{
    spring_force(sim->m, sim->x, i, sim->x + 3 * i, f);
}
