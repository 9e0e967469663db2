/* The force transmittal integrator: contacts, cached layers and update
 * schedule, Gauss-Seidel central differences, relaxation and sleep, the
 * stability guard, reactions and the state hash. */
#include "ftm/sim.h"

#include "error.h"
#include "layers.h"
#include "mesh_internal.h"
#include "sim_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Added to a spring's length before dividing by it: exact for any length
 * above ~1e-134, and keeps coincident nodes (r = 0) from producing 0/0. */
#define FTM_LEN_EPS 1e-150
#define FTM_SUBSTEP_RETRY 1024 /* steps before the guard tries fewer substeps */

/* Scheduled nodes are the free and force-loaded ones (kind < NODE_DISP). */
enum { NODE_FREE = 0, NODE_FORCE = 1, NODE_DISP = 2, NODE_FIXED = 3 };

/* GCC vector extensions, for the colored order's four-lane blocks: the same
 * source compiles to AVX or SSE2 with the same IEEE results. */
typedef double v4d __attribute__((vector_size(32)));
typedef int64_t v4l __attribute__((vector_size(32)));
/* Lanes from four addresses. Built as one initialiser: element-by-element
 * assignment makes GCC assemble the vector on the stack, and the wide
 * reload of narrow stores stalls store forwarding. */
#define GATHER4(p, i0, i1, i2, i3) ((v4d){(p)[i0], (p)[i1], (p)[i2], (p)[i3]})
/* Consecutive doubles at any alignment (vectors alias their elements). */
typedef double v4du __attribute__((vector_size(32), aligned(8)));
typedef double v2du __attribute__((vector_size(16), aligned(8)));
#define LOAD4(p) (*(const v4du *)(p))
#define LOAD2(p) (*(const v2du *)(p))

/* FTM_ORDER_LAYER_COLORED updates up to four nodes of one independent set
 * together: schedule positions first .. first+lanes-1, over `slots` padded
 * neighbour slots (the largest degree among them), once linked stored
 * slot-major from slot index `link` of the schedule's link arrays, so that
 * the kernel loads each slot's four lanes with one vector load. `forced`: a lane has an
 * external force (else all are +0.0 and the block skips reading them). */
typedef struct block {
    int32_t first, lanes, slots, link;
    bool forced;
} block;

/* The update order of the contact region, rebuilt when the region changes:
 * the free and force-loaded nodes of the layers, in update order. */
typedef struct schedule {
    int32_t count;  /* scheduled nodes */
    int32_t *node;  /* mesh index */
    int32_t groups; /* Jacobi: one per layer */
    int32_t *group; /* group g: schedule positions group[g] .. group[g+1]-1 */
    int32_t blocks; /* colored order */
    block *block;
    /* colored order, 4 lanes per slot: 3 * neighbour (spare lanes repeat the
     * block's last node), stiffness and rest length, as in pad_node / pad_kl */
    int32_t *link_j;
    double *link_kl; /* per slot: k of the 4 lanes, then len */
    /* rollback: previous positions overwritten in the last step; 3 per
     * schedule position, or in the colored order x, y and z vectors of 4 per block */
    double *save;
    double *tmp;    /* Jacobi: new positions of a group */
    int32_t uses;   /* colored sweeps since the schedule was built */
    bool linked;    /* link_j / link_kl hold the blocks' links */
    int32_t cap, gcap;
    size_t link_cap;
} schedule;

struct ftm_sim;
typedef bool (*sweep_fn)(struct ftm_sim *sim, double *max_m2);

struct ftm_sim {
    const ftm_mesh *m;
    ftm_sim_def def;
    int32_t n;
    double *x, *xp; /* positions and previous positions, 3 per node */
    double *coef;   /* per-node a, b, c for the current substep length */
    double *force;  /* external force, 3 per node (zero but at force contacts) */
    double *lim2;   /* guard: squared motion limit per node */
    uint8_t *kind;  /* NODE_* per node */

    ftm_contact *contacts; /* current contacts, sorted by node */
    int32_t ncontacts, contact_cap;
    int32_t *sources;      /* contact node ids (sorted) = layer 0 */
    int32_t *disp;         /* displacement-contact nodes, in contact order */
    int32_t ndisp;

    ftm_layering ly;
    bool layers_dirty;     /* node set or depth changed since the last build */
    bool schedule_dirty;   /* only the contacts' kinds changed */
    int32_t built_depth;
    schedule s;

    int32_t *relax; /* displaced nodes outside the region, ascending */
    int32_t nrelax, relax_cap;
    int32_t *relax_tmp;
    double *relax_save; /* rollback for relaxing and displacement nodes: x, xp */

    int32_t substeps;
    int32_t steps_at_substeps;
    double h_sub;

    int32_t quiet_steps; /* consecutive steps with the region below the sleep tolerance */
    bool region_sleeping;
    bool warned_dt;

    double *reaction; /* 3 per group */
    int32_t reaction_groups;

    double tol; /* sleep tolerance in metres */
    sweep_fn sweep_blocks; /* the block kernel for this CPU (see select_kernel) */
    ftm_sim_stats st;
};

ftm_sim_def ftm_default_sim_def(void)
{
    return (ftm_sim_def){.time_step = 1e-3,
                         .depth = 10,
                         .order = FTM_ORDER_LAYER_COLORED,
                         .sleep_tolerance = 1e-6,
                         .region_sleep_steps = 0,
                         .guard = true,
                         .guard_motion = 0.5,
                         .max_substeps = 64,
                         .cache_layers = true,
                         .log = NULL,
                         .log_user = NULL};
}

#define FTM_MAX_DEPTH 1000000

static int check_def(const ftm_sim_def *d, ftm_error *err)
{
    if (!(d->time_step > 0.0) || !isfinite(d->time_step))
        return ftm_error_set(err, FTM_EINVAL, "sim: time_step must be > 0 (got %g)", d->time_step);
    if (d->depth < 0 || d->depth > FTM_MAX_DEPTH)
        return ftm_error_set(err, FTM_EINVAL, "sim: depth must be in 0..%d (got %d)",
                             FTM_MAX_DEPTH, (int)d->depth);
    if (d->order != FTM_ORDER_LAYER_COLORED && d->order != FTM_ORDER_BFS &&
        d->order != FTM_ORDER_LAYER_JACOBI)
        return ftm_error_set(err, FTM_EINVAL, "sim: unknown order %d", (int)d->order);
    if (!(d->sleep_tolerance >= 0.0) || !isfinite(d->sleep_tolerance))
        return ftm_error_set(err, FTM_EINVAL, "sim: sleep_tolerance must be >= 0 (got %g)",
                             d->sleep_tolerance);
    if (d->region_sleep_steps < 0)
        return ftm_error_set(err, FTM_EINVAL, "sim: region_sleep_steps must be >= 0 (got %d)",
                             (int)d->region_sleep_steps);
    if (!(d->guard_motion > 0.0) || !isfinite(d->guard_motion))
        return ftm_error_set(err, FTM_EINVAL, "sim: guard_motion must be > 0 (got %g)",
                             d->guard_motion);
    if (d->max_substeps < 1 || d->max_substeps > 1 << 20)
        return ftm_error_set(err, FTM_EINVAL, "sim: max_substeps must be in 1..%d (got %d)",
                             1 << 20, (int)d->max_substeps);
    return FTM_OK;
}

static void schedule_free(schedule *s)
{
    free(s->node);
    free(s->group);
    free(s->block);
    free(s->link_j);
    free(s->link_kl);
    free(s->save);
    free(s->tmp);
    memset(s, 0, sizeof *s);
}

void ftm_sim_destroy(ftm_sim *sim)
{
    if (!sim)
        return;
    free(sim->x);
    free(sim->xp);
    free(sim->coef);
    free(sim->force);
    free(sim->lim2);
    free(sim->kind);
    free(sim->contacts);
    free(sim->sources);
    free(sim->disp);
    ftm_layering_free(&sim->ly);
    schedule_free(&sim->s);
    free(sim->relax);
    free(sim->relax_tmp);
    free(sim->relax_save);
    free(sim->reaction);
    free(sim);
}

/* a = 1/(m/h^2 + d/2h), b = 2m/h^2 * a, c = (m/h^2 - d/2h) * a, so that
 * x_new = a (F - sum f) + b x - c x_prev  (Eq. 8 written for positions). */
static void node_coef(const ftm_mesh *m, int32_t i, double h, double *out)
{
    double mh = m->mass[i] / (h * h), dh = m->damping[i] / (2.0 * h);
    double a = 1.0 / (mh + dh);
    out[0] = a;
    out[1] = 2.0 * mh * a;
    out[2] = (mh - dh) * a;
}

static void set_substep_length(ftm_sim *sim, double h)
{
    sim->h_sub = h;
    for (int32_t i = 0; i < sim->n; i++)
        node_coef(sim->m, i, h, sim->coef + 3 * i);
}

/* The layer-by-layer (Gauss-Seidel) update is not time-reversible like plain
 * central differences: without damping a mode of frequency w grows roughly
 * like exp(0.025 w t) whatever the time step (measured on chains and
 * lattices; see docs/core.md), so nodal damping must outweigh it:
 * d / 2m > 0.025 w_max. Warns once, naming the worst node. */
static void warn_low_damping(const ftm_sim *sim)
{
    const ftm_mesh *m = sim->m;
    int32_t worst = -1;
    double worst_ratio = INFINITY;
    for (int32_t i = 0; i < m->node_count; i++) {
        if (m->fixed[i])
            continue;
        double lambda = 0.0;
        for (int32_t e = m->adj_start[i]; e < m->adj_start[i + 1]; e++)
            lambda += m->adj_k[e] * (1.0 / m->mass[i] + 1.0 / sqrt(m->mass[i] * m->mass[m->adj_node[e]]));
        if (lambda <= 0.0)
            continue;
        double ratio = m->damping[i] / (2.0 * m->mass[i]) / (0.025 * sqrt(lambda));
        if (ratio < worst_ratio) {
            worst_ratio = ratio;
            worst = i;
        }
    }
    if (worst >= 0 && worst_ratio < 1.0)
        ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                 "nodal damping is low for the layer-by-layer update (node %d: d/2m = %g, "
                 "0.025 w_max = %g): the scene may gain energy slowly; raise damping",
                 (int)worst, m->damping[worst] / (2.0 * m->mass[worst]),
                 m->damping[worst] / (2.0 * m->mass[worst]) / worst_ratio);
}

int ftm_sim_create(const ftm_mesh *m, const ftm_sim_def *def, ftm_sim **out, ftm_error *err)
{
    if (!m || !out)
        return ftm_error_set(err, FTM_EINVAL, "sim: null argument");
    ftm_sim_def d = def ? *def : ftm_default_sim_def();
    int rc = check_def(&d, err);
    if (rc)
        return rc;
    ftm_sim *sim = calloc(1, sizeof *sim);
    if (!sim)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
    sim->m = m;
    sim->def = d;
    sim->n = m->node_count;
    size_t n = (size_t)sim->n;
    sim->x = malloc(n * 3 * sizeof(double));
    sim->xp = malloc(n * 3 * sizeof(double));
    sim->coef = malloc(n * 3 * sizeof(double));
    sim->force = calloc(n * 3, sizeof(double));
    sim->lim2 = malloc(n * sizeof(double));
    sim->kind = calloc(n, 1);
    sim->relax_tmp = malloc(n * sizeof(int32_t));
    if (!sim->x || !sim->xp || !sim->coef || !sim->force || !sim->lim2 || !sim->kind || !sim->relax_tmp ||
        ftm_layering_init(&sim->ly, sim->n) != FTM_OK) {
        ftm_sim_destroy(sim);
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for %zu nodes", n);
    }
    memcpy(sim->x, m->rest, n * 3 * sizeof(double));
    memcpy(sim->xp, m->rest, n * 3 * sizeof(double));
    for (size_t i = 0; i < n; i++)
        sim->kind[i] = m->fixed[i] ? NODE_FIXED : NODE_FREE;
    ftm_sim_select_kernel(sim, false);
    for (size_t i = 0; i < n; i++) {
        double lim = d.guard_motion * m->min_link[i];
        sim->lim2[i] = isfinite(lim) ? lim * lim : INFINITY;
    }
    sim->substeps = 1;
    set_substep_length(sim, d.time_step);
    sim->tol = d.sleep_tolerance * m->mean_link_length;
    sim->layers_dirty = true;
    sim->st.depth = d.depth;
    sim->st.substeps = 1;
    warn_low_damping(sim);
    double hc = ftm_mesh_critical_time_step(m);
    if (d.time_step > hc) {
        ftm_logf(d.log, d.log_user, FTM_LOG_WARN,
                 "time step %g s exceeds the critical time step %g s of this mesh: the stability "
                 "guard will substep",
                 d.time_step, hc);
        sim->warned_dt = true;
    }
    *out = sim;
    ftm_error_clear(err);
    return FTM_OK;
}

const ftm_mesh *ftm_sim_mesh(const ftm_sim *sim) { return sim->m; }

/* ---- contacts ---- */

static int cmp_contact(const void *a, const void *b)
{
    int32_t x = ((const ftm_contact *)a)->node, y = ((const ftm_contact *)b)->node;
    return (x > y) - (x < y);
}

static int cmp_i32(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

static bool finite3(ftm_vec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

static bool at_rest(const ftm_sim *sim, int32_t i)
{
    const double *x = sim->x + 3 * i, *xp = sim->xp + 3 * i, *X = sim->m->rest + 3 * i;
    return x[0] == X[0] && x[1] == X[1] && x[2] == X[2] && xp[0] == X[0] && xp[1] == X[1] &&
           xp[2] == X[2];
}

static int relax_reserve(ftm_sim *sim, int32_t need)
{
    if (need <= sim->relax_cap)
        return FTM_OK;
    int32_t cap = sim->relax_cap ? sim->relax_cap : 256;
    while (cap < need)
        cap *= 2;
    int32_t *r = realloc(sim->relax, (size_t)cap * sizeof *r);
    if (!r)
        return FTM_ENOMEM;
    sim->relax = r;
    double *sv = realloc(sim->relax_save, (size_t)cap * 6 * sizeof *sv);
    if (!sv)
        return FTM_ENOMEM;
    sim->relax_save = sv;
    sim->relax_cap = cap;
    return FTM_OK;
}

int ftm_sim_set_contacts(ftm_sim *sim, const ftm_contact *c, int32_t count, ftm_error *err)
{
    if (!sim || count < 0 || (count > 0 && !c))
        return ftm_error_set(err, FTM_EINVAL, "contacts: null argument or negative count");
    if (count > sim->n)
        return ftm_error_set(err, FTM_ERANGE, "contacts: %d contacts for %d nodes", (int)count,
                             (int)sim->n);
    for (int32_t i = 0; i < count; i++) {
        if (c[i].node < 0 || c[i].node >= sim->n)
            return ftm_error_set(err, FTM_ERANGE, "contact %d: node %d out of range 0..%d",
                                 (int)i, (int)c[i].node, (int)sim->n - 1);
        if (sim->m->fixed[c[i].node])
            return ftm_error_set(err, FTM_EINVAL, "contact %d: node %d is fixed", (int)i,
                                 (int)c[i].node);
        if (c[i].kind != FTM_CONTACT_FORCE && c[i].kind != FTM_CONTACT_DISPLACEMENT)
            return ftm_error_set(err, FTM_EINVAL, "contact %d: unknown kind %d", (int)i,
                                 (int)c[i].kind);
        if (!finite3(c[i].value))
            return ftm_error_set(err, FTM_EINVAL, "contact %d: value is not finite", (int)i);
        if (c[i].group < 0 || c[i].group > 1 << 20)
            return ftm_error_set(err, FTM_EINVAL, "contact %d: group %d out of range 0..%d",
                                 (int)i, (int)c[i].group, 1 << 20);
    }
    /* sorted copy, then duplicates */
    ftm_contact *nc = malloc(((size_t)count + 1) * sizeof *nc);
    int32_t *nsrc = malloc(((size_t)count + 1) * sizeof *nsrc);
    int32_t *ndisp = malloc(((size_t)count + 1) * sizeof *ndisp);
    if (!nc || !nsrc || !ndisp) {
        free(nc);
        free(nsrc);
        free(ndisp);
        return ftm_error_set(err, FTM_ENOMEM, "contacts: out of memory");
    }
    if (count)
        memcpy(nc, c, (size_t)count * sizeof *nc);
    qsort(nc, (size_t)count, sizeof *nc, cmp_contact);
    for (int32_t i = 1; i < count; i++)
        if (nc[i].node == nc[i - 1].node) {
            int twice = (int)nc[i].node;
            free(nc);
            free(nsrc);
            free(ndisp);
            return ftm_error_set(err, FTM_EINVAL, "contacts: node %d listed twice", twice);
        }
    int32_t groups = 0, nd = 0;
    for (int32_t i = 0; i < count; i++) {
        nsrc[i] = nc[i].node;
        if (nc[i].group + 1 > groups)
            groups = nc[i].group + 1;
        if (nc[i].kind == FTM_CONTACT_DISPLACEMENT)
            ndisp[nd++] = nc[i].node;
    }
    if (groups > sim->reaction_groups) {
        double *r = realloc(sim->reaction, (size_t)groups * 3 * sizeof *r);
        if (!r) {
            free(nc);
            free(nsrc);
            free(ndisp);
            return ftm_error_set(err, FTM_ENOMEM, "contacts: out of memory");
        }
        memset(r + 3 * sim->reaction_groups, 0,
               (size_t)(groups - sim->reaction_groups) * 3 * sizeof *r);
        sim->reaction = r;
        sim->reaction_groups = groups;
    }

    bool same_nodes = count == sim->ncontacts, same_kinds = same_nodes;
    bool same_values = same_nodes;
    for (int32_t i = 0; same_nodes && i < count; i++) {
        if (nc[i].node != sim->contacts[i].node) {
            same_nodes = same_kinds = same_values = false;
        } else if (nc[i].kind != sim->contacts[i].kind) {
            same_kinds = same_values = false;
        } else if (memcmp(&nc[i].value, &sim->contacts[i].value, sizeof nc[i].value) != 0 ||
                   nc[i].group != sim->contacts[i].group) {
            same_values = false;
        }
    }
    for (int32_t i = 0; i < sim->ncontacts; i++) {
        int32_t v = sim->contacts[i].node;
        sim->kind[v] = NODE_FREE;
        sim->force[3 * v] = sim->force[3 * v + 1] = sim->force[3 * v + 2] = 0.0;
    }
    for (int32_t i = 0; i < count; i++) {
        int32_t v = nc[i].node;
        sim->kind[v] = nc[i].kind == FTM_CONTACT_FORCE ? NODE_FORCE : NODE_DISP;
        if (nc[i].kind == FTM_CONTACT_FORCE) {
            sim->force[3 * v] = nc[i].value.x;
            sim->force[3 * v + 1] = nc[i].value.y;
            sim->force[3 * v + 2] = nc[i].value.z;
        }
    }
    free(sim->contacts);
    free(sim->sources);
    free(sim->disp);
    sim->contacts = nc;
    sim->sources = nsrc;
    sim->disp = ndisp;
    sim->ncontacts = count;
    sim->ndisp = nd;
    if (!same_nodes)
        sim->layers_dirty = true;
    else if (!same_kinds)
        sim->schedule_dirty = true;
    if (!same_values) {
        sim->region_sleeping = false;
        sim->quiet_steps = 0;
    }
    ftm_error_clear(err);
    return FTM_OK;
}

int ftm_sim_set_depth(ftm_sim *sim, int32_t depth)
{
    if (!sim || depth < 0 || depth > FTM_MAX_DEPTH)
        return FTM_EINVAL;
    if (depth != sim->def.depth) {
        sim->def.depth = depth;
        sim->st.depth = depth;
        sim->layers_dirty = true;
        sim->region_sleeping = false;
        sim->quiet_steps = 0;
    }
    return FTM_OK;
}

/* ---- schedule ---- */

static int schedule_reserve(schedule *s, int32_t count, int32_t groups, int32_t max_degree)
{
#define GROW(p, n, per)                                                                       \
    do {                                                                                      \
        void *q_ = realloc((p), ((size_t)(n) * (per) + 1) * sizeof *(p));                     \
        if (!q_)                                                                              \
            return FTM_ENOMEM;                                                                \
        (p) = q_;                                                                             \
    } while (0)
    if (count > s->cap) {
        int32_t cap = s->cap ? s->cap : 256;
        while (cap < count)
            cap *= 2;
        GROW(s->node, cap, 1);
        GROW(s->block, cap, 1);
        GROW(s->save, cap, 12); /* blocks <= count */
        GROW(s->tmp, cap, 3);
        s->cap = cap;
    }
    size_t links = (size_t)count * (size_t)max_degree * 4; /* slots of all blocks, 4 lanes */
    if (links > s->link_cap) {
        GROW(s->link_j, links, 1);
        GROW(s->link_kl, links, 2);
        s->link_cap = links;
    }
    if (groups + 1 > s->gcap) {
        int32_t cap = s->gcap ? s->gcap : 64;
        while (cap < groups + 1)
            cap *= 2;
        GROW(s->group, cap, 1);
        s->gcap = cap;
    }
#undef GROW
    return FTM_OK;
}

/* Nodes of the old region (and old relaxing set) that the new region does
 * not cover and that are not at rest become (stay) relaxing, ascending.
 * Called after the search; `old` holds the old region's nodes. */
static int update_relaxing(ftm_sim *sim, int32_t *old, int32_t cand)
{
    const ftm_layering *ly = &sim->ly;
    int32_t nr = 0;
    int32_t *merged = sim->relax;
    for (int32_t k = 0; k < cand; k++) {
        int32_t i = old[k];
        if (!ftm_layering_contains(ly, i) && !sim->m->fixed[i] && !at_rest(sim, i))
            old[nr++] = i;
    }
    int32_t nold = 0;
    for (int32_t k = 0; k < sim->nrelax; k++) {
        int32_t i = sim->relax[k];
        if (!ftm_layering_contains(ly, i))
            merged[nold++] = i;
    }
    /* sort the new candidates, then merge with the (sorted) survivors */
    qsort(old, (size_t)nr, sizeof *old, cmp_i32);
    int32_t *out = malloc(((size_t)nold + (size_t)nr + 1) * sizeof *out);
    if (!out)
        return FTM_ENOMEM;
    int32_t a = 0, b = 0, w = 0;
    while (a < nold || b < nr) {
        int32_t v;
        if (b >= nr || (a < nold && merged[a] < old[b]))
            v = merged[a++];
        else if (a >= nold || old[b] < merged[a])
            v = old[b++];
        else {
            v = merged[a++];
            b++;
        }
        out[w++] = v;
    }
    int rc = relax_reserve(sim, w + 1);
    if (rc) {
        free(out);
        return rc;
    }
    memcpy(sim->relax, out, (size_t)w * sizeof *out);
    sim->nrelax = w;
    free(out);
    return FTM_OK;
}

/* Colored order: the scheduled nodes of each independent set, cut into
 * blocks of up to four (one node per block in the shared-colour set, whose
 * nodes may be adjacent). Their link data is copied slot-major only on the
 * schedule's second use (schedule_links): a schedule used once, as with
 * cache_layers = false, is cheaper read from the mesh's padded rows. */
static void schedule_blocks(ftm_sim *sim)
{
    const ftm_layering *ly = &sim->ly;
    schedule *s = &sim->s;
    const int32_t *adj_start = sim->m->adj_start;
    int32_t kk = 0, nb = 0, link = 0;
    for (int32_t set = 0; set < ly->sets; set++) {
        int32_t first = kk;
        for (int32_t k = ly->set_start[set]; k < ly->set_start[set + 1]; k++) {
            int32_t i = ly->order[k];
            s->node[kk] = i;
            kk += sim->kind[i] < NODE_DISP;
        }
        int32_t width = ly->set_color[set] == FTM_SHARED_COLOR ? 1 : 4;
        for (int32_t p = first; p < kk; p += width) {
            int32_t lanes = kk - p < width ? kk - p : width, slots = 0;
            bool forced = false;
            for (int32_t l = 0; l < lanes; l++) {
                int32_t i = s->node[p + l], d = adj_start[i + 1] - adj_start[i];
                slots = d > slots ? d : slots;
                forced |= sim->kind[i] == NODE_FORCE;
            }
            s->block[nb++] = (block){p, lanes, slots, link, forced};
            link += slots;
        }
    }
    s->count = kk;
    s->blocks = nb;
    s->uses = 0;
    s->linked = false;
}

/* The four lanes of a block: its nodes, spare lanes repeating the last. */
static inline __attribute__((always_inline)) void block_lanes(const schedule *s, block bl,
                                                              int32_t n[4])
{
    const int32_t *sn = s->node + bl.first;
    n[0] = sn[0];
    n[1] = sn[bl.lanes > 1 ? 1 : 0];
    n[2] = sn[bl.lanes > 2 ? 2 : bl.lanes - 1];
    n[3] = sn[bl.lanes - 1];
}

/* Copies each block's padded link rows slot-major: per slot the four lanes'
 * 3 * neighbour, k and rest length. */
static void schedule_links(ftm_sim *sim)
{
    schedule *s = &sim->s;
    const int32_t *pad_node = sim->m->pad_node;
    const double *pad_kl = sim->m->pad_kl;
    const size_t deg = (size_t)sim->m->max_degree;
    for (int32_t b = 0; b < s->blocks; b++) {
        int32_t n[4];
        block_lanes(s, s->block[b], n);
        const int32_t *n0 = pad_node + n[0] * deg, *n1 = pad_node + n[1] * deg,
                      *n2 = pad_node + n[2] * deg, *n3 = pad_node + n[3] * deg;
        const double *kl0 = pad_kl + 2 * n[0] * deg, *kl1 = pad_kl + 2 * n[1] * deg,
                     *kl2 = pad_kl + 2 * n[2] * deg, *kl3 = pad_kl + 2 * n[3] * deg;
        int32_t *lj = s->link_j + 4 * (size_t)s->block[b].link;
        double *lkl = s->link_kl + 8 * (size_t)s->block[b].link;
        for (int32_t sl = 0; sl < s->block[b].slots; sl++) {
            lj[4 * sl] = 3 * n0[sl];
            lj[4 * sl + 1] = 3 * n1[sl];
            lj[4 * sl + 2] = 3 * n2[sl];
            lj[4 * sl + 3] = 3 * n3[sl];
            /* the lanes' (k, len) pairs unpacked into k and len */
            v2du p0 = LOAD2(kl0 + 2 * sl), p1 = LOAD2(kl1 + 2 * sl), p2 = LOAD2(kl2 + 2 * sl),
                 p3 = LOAD2(kl3 + 2 * sl);
            *(v2du *)(lkl + 8 * sl) = __builtin_shufflevector(p0, p1, 0, 2);
            *(v2du *)(lkl + 8 * sl + 2) = __builtin_shufflevector(p2, p3, 0, 2);
            *(v2du *)(lkl + 8 * sl + 4) = __builtin_shufflevector(p0, p1, 1, 3);
            *(v2du *)(lkl + 8 * sl + 6) = __builtin_shufflevector(p2, p3, 1, 3);
        }
    }
    s->linked = true;
}

/* Plain orders: the scheduled nodes layer by layer, one group per layer. */
static void schedule_layers(ftm_sim *sim)
{
    const ftm_layering *ly = &sim->ly;
    schedule *s = &sim->s;
    int32_t kk = 0, g = 0;
    for (int32_t l = 0; l < ly->layers; l++) {
        int32_t first = kk;
        for (int32_t k = ly->start[l]; k < ly->start[l + 1]; k++) {
            int32_t i = ly->order[k];
            if (sim->kind[i] < NODE_DISP)
                s->node[kk++] = i;
        }
        if (kk > first)
            s->group[g++] = first;
    }
    s->group[g] = kk;
    s->groups = g;
    s->count = kk;
}

/* The update schedule from the current layers and contact kinds. */
static int rebuild_schedule(ftm_sim *sim)
{
    int rc = schedule_reserve(&sim->s, sim->ly.count, sim->ly.layers, sim->m->max_degree);
    if (rc)
        return rc;
    if (sim->def.order == FTM_ORDER_LAYER_COLORED)
        schedule_blocks(sim);
    else
        schedule_layers(sim);
    sim->schedule_dirty = false;
    return FTM_OK;
}

/* Rebuilds layers and schedule; moves displaced nodes that left the region
 * into the relaxing set. */
static int rebuild_region(ftm_sim *sim)
{
    ftm_layering *ly = &sim->ly;
    /* Same sources and depth as the last search (a search forced by
     * cache_layers = false): the region is the same, so is the relaxing set. */
    bool same_region = ly->gen && !sim->layers_dirty && sim->built_depth == sim->def.depth;
    int32_t cand = 0;
    if (!same_region) { /* nodes of the old region are candidates for relaxing */
        int32_t old_count = ly->gen ? ly->count : 0;
        int rc = relax_reserve(sim, sim->nrelax + old_count + 1);
        if (rc)
            return rc;
        memcpy(sim->relax_tmp, ly->order, (size_t)old_count * sizeof *ly->order);
        cand = old_count;
    }
    bool colored = sim->def.order == FTM_ORDER_LAYER_COLORED;
    int rc = ftm_layering_build(ly, sim->m, sim->sources, sim->ncontacts, sim->def.depth, colored);
    if (rc)
        return rc;
    sim->st.searches++;
    sim->built_depth = sim->def.depth;
    if (!same_region) {
        rc = update_relaxing(sim, sim->relax_tmp, cand);
        if (rc)
            return rc;
    }
    rc = rebuild_schedule(sim);
    if (rc)
        return rc;
    sim->layers_dirty = false;
    if (!same_region) {
        sim->region_sleeping = false;
        sim->quiet_steps = 0;
    }
    return FTM_OK;
}

/* Brings layers and schedule up to date: a new search when the contact node
 * set or the depth changed (or on every step without caching), only a new
 * schedule when just the contacts' kinds changed. */
static int refresh_region(ftm_sim *sim)
{
    if (sim->layers_dirty || sim->built_depth != sim->def.depth || !sim->def.cache_layers)
        return rebuild_region(sim);
    if (sim->schedule_dirty)
        return rebuild_schedule(sim);
    return FTM_OK;
}


/* ---- the hot loop ---- */

/* Sum of the spring forces f_ij (Eq. 6) on node i placed at xi:
 *     f_ij = t r,   t = k (|r| - l) / |r|,   r = xi - x_j,
 * over its neighbours in adjacency order (one fixed order, so every caller
 * and every machine rounds the same way). Written this way t is exactly 0 at
 * the rest length (rest lengths are the rest positions' distances computed
 * the same way), so an unloaded mesh at rest is an exact equilibrium. */
static inline void spring_force(const ftm_mesh *restrict m, const double *restrict x, int32_t i,
                                const double xi[3], double f[3])
{
    const int32_t *restrict nb = m->adj_node;
    const double *restrict kk = m->adj_k, *restrict len = m->adj_len;
    double fx = 0.0, fy = 0.0, fz = 0.0;
    for (int32_t e = m->adj_start[i]; e < m->adj_start[i + 1]; e++) {
        const double *xj = x + 3 * nb[e];
        double rx = xi[0] - xj[0], ry = xi[1] - xj[1], rz = xi[2] - xj[2];
        double r = sqrt(rx * rx + ry * ry + rz * rz) + FTM_LEN_EPS;
        double t = kk[e] * (r - len[e]) / r;
        fx += t * rx;
        fy += t * ry;
        fz += t * rz;
    }
    f[0] = fx;
    f[1] = fy;
    f[2] = fz;
}

/* Eq. 8 for node i: new position from the spring forces f, the external
 * force, the current and the previous position. Returns the squared motion. */
static inline double integrate(const ftm_sim *sim, int32_t i, const double cur[3],
                               const double f[3], double out[3])
{
    const double *c = sim->coef + 3 * i, *F = sim->force + 3 * i, *p = sim->xp + 3 * i;
    for (int d = 0; d < 3; d++)
        out[d] = c[0] * (F[d] - f[d]) + c[1] * cur[d] - c[2] * p[d];
    double dx = out[0] - cur[0], dy = out[1] - cur[1], dz = out[2] - cur[2];
    return dx * dx + dy * dy + dz * dz;
}

/* Gauss-Seidel sweep over schedule positions [k0, k1): each node reads the
 * current (already updated where earlier) positions of its neighbours.
 * Returns false if a node moved more than its guard limit or to a non-finite
 * position. The overwritten previous positions are saved for rollback. */
static bool sweep_gs(ftm_sim *sim, int32_t k0, int32_t k1, double *max_m2)
{
    const ftm_mesh *m = sim->m;
    schedule *s = &sim->s;
    double *restrict x = sim->x, *restrict xp = sim->xp;
    bool ok = true;
    double mm = *max_m2;
    for (int32_t k = k0; k < k1; k++) {
        int32_t i = s->node[k];
        double *xi = x + 3 * i, *pi = xp + 3 * i, *sv = s->save + 3 * k;
        double cur[3] = {xi[0], xi[1], xi[2]}, f[3], nw[3];
        spring_force(m, x, i, cur, f);
        double m2 = integrate(sim, i, cur, f, nw);
        ok &= m2 <= sim->lim2[i]; /* false for NaN too */
        mm = m2 > mm ? m2 : mm;
        for (int d = 0; d < 3; d++) {
            sv[d] = pi[d];
            pi[d] = cur[d];
            xi[d] = nw[d];
        }
    }
    *max_m2 = mm;
    return ok;
}

/* The colored sweep, four nodes of an independent set per vector. Lane l
 * does exactly the operations spring_force and integrate do for its node,
 * in the same order (padding slots add -0.0, see mesh_internal.h), and the
 * nodes of a block are not adjacent, so the result is bit-identical to
 * updating them one by one in schedule order. GCC vector extensions: the
 * same source compiles to AVX or SSE2 with the same IEEE results (no
 * contraction, sqrt and division correctly rounded). */
static inline __attribute__((always_inline)) bool sweep_blocks_body(ftm_sim *sim, double *max_m2,
                                                                  bool linked)
{
    const schedule *s = &sim->s;
    const size_t deg = (size_t)sim->m->max_degree;
    const int32_t *restrict pad_node = sim->m->pad_node;
    const double *restrict pad_kl = sim->m->pad_kl;
    const double *restrict coef = sim->coef, *restrict force = sim->force, *restrict lim2 = sim->lim2;
    double *restrict x = sim->x, *restrict xp = sim->xp;
    v4d mm = {*max_m2, *max_m2, *max_m2, *max_m2};
    v4l bad = {0, 0, 0, 0};
    for (int32_t b = 0; b < s->blocks; b++) {
        const block bl = s->block[b];
        int32_t n[4];
        block_lanes(s, bl, n);
        const size_t i0 = 3 * (size_t)n[0], i1 = 3 * (size_t)n[1], i2 = 3 * (size_t)n[2],
                     i3 = 3 * (size_t)n[3];
        const v4d cx = GATHER4(x, i0, i1, i2, i3), cy = GATHER4(x + 1, i0, i1, i2, i3),
                  cz = GATHER4(x + 2, i0, i1, i2, i3);
        v4d ax = {0, 0, 0, 0}, ay = ax, az = ax;
        const int32_t *restrict lj = s->link_j + 4 * (size_t)bl.link;
        const double *restrict lkl = s->link_kl + 8 * (size_t)bl.link;
        const int32_t *nb0 = pad_node + n[0] * deg, *nb1 = pad_node + n[1] * deg,
                      *nb2 = pad_node + n[2] * deg, *nb3 = pad_node + n[3] * deg;
        const double *kl0 = pad_kl + 2 * n[0] * deg, *kl1 = pad_kl + 2 * n[1] * deg,
                     *kl2 = pad_kl + 2 * n[2] * deg, *kl3 = pad_kl + 2 * n[3] * deg;
        for (int32_t sl = 0; sl < bl.slots; sl++) {
            size_t j0, j1, j2, j3;
            v4d k, rest;
            if (linked) {
                j0 = (size_t)lj[4 * sl];
                j1 = (size_t)lj[4 * sl + 1];
                j2 = (size_t)lj[4 * sl + 2];
                j3 = (size_t)lj[4 * sl + 3];
                k = LOAD4(lkl + 8 * sl);
                rest = LOAD4(lkl + 8 * sl + 4);
            } else { /* the same from the padded rows: (k, len) pairs of lanes 0|2 and 1|3 */
                j0 = 3 * (size_t)nb0[sl];
                j1 = 3 * (size_t)nb1[sl];
                j2 = 3 * (size_t)nb2[sl];
                j3 = 3 * (size_t)nb3[sl];
                v4d p02 = __builtin_shufflevector(LOAD2(kl0 + 2 * sl), LOAD2(kl2 + 2 * sl), 0, 1, 2, 3),
                    p13 = __builtin_shufflevector(LOAD2(kl1 + 2 * sl), LOAD2(kl3 + 2 * sl), 0, 1, 2, 3);
                k = __builtin_shufflevector(p02, p13, 0, 4, 2, 6);
                rest = __builtin_shufflevector(p02, p13, 1, 5, 3, 7);
            }
            const v4d rx = cx - GATHER4(x, j0, j1, j2, j3),
                      ry = cy - GATHER4(x + 1, j0, j1, j2, j3),
                      rz = cz - GATHER4(x + 2, j0, j1, j2, j3);
            v4d q = rx * rx + ry * ry + rz * rz, len;
            for (int l = 0; l < 4; l++)
                len[l] = sqrt(q[l]);
            len += FTM_LEN_EPS;
            v4d t = k * (len - rest) / len;
            ax += t * rx;
            ay += t * ry;
            az += t * rz;
        }
        const v4d ca = GATHER4(coef, i0, i1, i2, i3), cb = GATHER4(coef + 1, i0, i1, i2, i3),
                  cc = GATHER4(coef + 2, i0, i1, i2, i3);
        v4d fx = {0, 0, 0, 0}, fy = fx, fz = fx;
        if (bl.forced) {
            fx = GATHER4(force, i0, i1, i2, i3);
            fy = GATHER4(force + 1, i0, i1, i2, i3);
            fz = GATHER4(force + 2, i0, i1, i2, i3);
        }
        const v4d px = GATHER4(xp, i0, i1, i2, i3), py = GATHER4(xp + 1, i0, i1, i2, i3),
                  pz = GATHER4(xp + 2, i0, i1, i2, i3);
        const v4d lim = GATHER4(lim2, n[0], n[1], n[2], n[3]);
        v4d nx = ca * (fx - ax) + cb * cx - cc * px;
        v4d ny = ca * (fy - ay) + cb * cy - cc * py;
        v4d nz = ca * (fz - az) + cb * cz - cc * pz;
        v4d dx = nx - cx, dy = ny - cy, dz = nz - cz;
        v4d m2 = dx * dx + dy * dy + dz * dz;
        bad |= ~(m2 <= lim); /* NaN fails too */
        v4l up = m2 > mm;
        mm = (v4d)((up & (v4l)m2) | (~up & (v4l)mm));
        double *sv = s->save + 12 * (size_t)b;
        *(v4du *)sv = px;
        *(v4du *)(sv + 4) = py;
        *(v4du *)(sv + 8) = pz;
        /* all four lanes: a spare lane stores what the lane it repeats stores */
        for (int l = 0; l < 4; l++) {
            double *xi = x + 3 * (size_t)n[l], *pi = xp + 3 * (size_t)n[l];
            pi[0] = cx[l];
            pi[1] = cy[l];
            pi[2] = cz[l];
            xi[0] = nx[l];
            xi[1] = ny[l];
            xi[2] = nz[l];
        }
    }
    double out = *max_m2;
    for (int l = 0; l < 4; l++)
        out = mm[l] > out ? mm[l] : out;
    *max_m2 = out;
    return !(bad[0] | bad[1] | bad[2] | bad[3]);
}

#if defined(__x86_64__) || defined(__i386__)
__attribute__((target("avx"))) static bool sweep_blocks_avx(ftm_sim *sim, double *max_m2)
{
    return sim->s.linked ? sweep_blocks_body(sim, max_m2, true)
                         : sweep_blocks_body(sim, max_m2, false);
}
#endif

static bool sweep_blocks_portable(ftm_sim *sim, double *max_m2)
{
    return sim->s.linked ? sweep_blocks_body(sim, max_m2, true)
                         : sweep_blocks_body(sim, max_m2, false);
}

void ftm_sim_select_kernel(ftm_sim *sim, bool portable)
{
    sim->sweep_blocks = sweep_blocks_portable;
#if defined(__x86_64__) || defined(__i386__)
    if (!portable && __builtin_cpu_supports("avx"))
        sim->sweep_blocks = sweep_blocks_avx;
#endif
}

/* Jacobi variant: every node of a block computed from the state before the
 * block, then committed. */
static bool sweep_jacobi(ftm_sim *sim, int32_t k0, int32_t k1, double *max_m2)
{
    const ftm_mesh *m = sim->m;
    schedule *s = &sim->s;
    bool ok = true;
    double mm = *max_m2;
    for (int32_t k = k0; k < k1; k++) {
        int32_t i = s->node[k];
        double f[3];
        spring_force(m, sim->x, i, sim->x + 3 * i, f);
        double m2 = integrate(sim, i, sim->x + 3 * i, f, s->tmp + 3 * k);
        ok &= m2 <= sim->lim2[i];
        mm = m2 > mm ? m2 : mm;
    }
    for (int32_t k = k0; k < k1; k++) {
        int32_t i = s->node[k];
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i, *sv = s->save + 3 * k,
               *t = s->tmp + 3 * k;
        for (int d = 0; d < 3; d++) {
            sv[d] = pi[d];
            pi[d] = xi[d];
            xi[d] = t[d];
        }
    }
    *max_m2 = mm;
    return ok;
}

/* Relaxing nodes, in ascending order. */
static bool sweep_relax(ftm_sim *sim)
{
    bool ok = true;
    for (int32_t r = 0; r < sim->nrelax; r++) {
        int32_t i = sim->relax[r];
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        double cur[3] = {xi[0], xi[1], xi[2]}, f[3], nw[3];
        spring_force(sim->m, sim->x, i, cur, f);
        ok &= integrate(sim, i, cur, f, nw) <= sim->lim2[i];
        for (int d = 0; d < 3; d++) {
            pi[d] = cur[d];
            xi[d] = nw[d];
        }
    }
    return ok;
}

/* ---- step ---- */

static void impose_displacements(ftm_sim *sim)
{
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        if (ct->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        int32_t i = ct->node;
        const double *X = sim->m->rest + 3 * i;
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        double v[3] = {ct->value.x, ct->value.y, ct->value.z};
        for (int d = 0; d < 3; d++) {
            pi[d] = xi[d];
            xi[d] = X[d] + v[d];
        }
    }
}

/* Saves x and xp of the displacement and relaxing nodes (and, when
 * substepping, of the scheduled nodes too) so a step can be undone. */
static int save_state(ftm_sim *sim, double **full)
{
    int32_t aux = sim->ndisp + sim->nrelax;
    int rc = relax_reserve(sim, aux + 1);
    if (rc)
        return rc;
    double *sv = sim->relax_save;
    for (int32_t r = 0; r < sim->ndisp; r++, sv += 6) {
        memcpy(sv, sim->x + 3 * sim->disp[r], 3 * sizeof(double));
        memcpy(sv + 3, sim->xp + 3 * sim->disp[r], 3 * sizeof(double));
    }
    for (int32_t r = 0; r < sim->nrelax; r++, sv += 6) {
        memcpy(sv, sim->x + 3 * sim->relax[r], 3 * sizeof(double));
        memcpy(sv + 3, sim->xp + 3 * sim->relax[r], 3 * sizeof(double));
    }
    *full = NULL;
    if (sim->substeps > 1 && sim->s.count > 0) {
        double *f = malloc((size_t)sim->s.count * 6 * sizeof *f);
        if (!f)
            return FTM_ENOMEM;
        for (int32_t k = 0; k < sim->s.count; k++) {
            memcpy(f + 6 * k, sim->x + 3 * sim->s.node[k], 3 * sizeof(double));
            memcpy(f + 6 * k + 3, sim->xp + 3 * sim->s.node[k], 3 * sizeof(double));
        }
        *full = f;
    }
    return FTM_OK;
}

static void restore_state(ftm_sim *sim, double *full, bool region_ran)
{
    const double *sv = sim->relax_save;
    for (int32_t r = 0; r < sim->ndisp; r++, sv += 6) {
        memcpy(sim->x + 3 * sim->disp[r], sv, 3 * sizeof(double));
        memcpy(sim->xp + 3 * sim->disp[r], sv + 3, 3 * sizeof(double));
    }
    for (int32_t r = 0; r < sim->nrelax; r++, sv += 6) {
        memcpy(sim->x + 3 * sim->relax[r], sv, 3 * sizeof(double));
        memcpy(sim->xp + 3 * sim->relax[r], sv + 3, 3 * sizeof(double));
    }
    if (!region_ran)
        return;
    if (full) {
        for (int32_t k = 0; k < sim->s.count; k++) {
            memcpy(sim->x + 3 * sim->s.node[k], full + 6 * k, 3 * sizeof(double));
            memcpy(sim->xp + 3 * sim->s.node[k], full + 6 * k + 3, 3 * sizeof(double));
        }
    } else { /* one substep: x_prev holds the old x, save the old x_prev */
        const schedule *s = &sim->s;
        for (int32_t k = 0; k < s->count; k++) {
            int32_t i = s->node[k];
            memcpy(sim->x + 3 * i, sim->xp + 3 * i, 3 * sizeof(double));
        }
        if (sim->def.order == FTM_ORDER_LAYER_COLORED) {
            for (int32_t b = 0; b < s->blocks; b++)
                for (int32_t l = 0; l < s->block[b].lanes; l++)
                    for (int d = 0; d < 3; d++)
                        sim->xp[3 * s->node[s->block[b].first + l] + d] =
                            s->save[12 * b + 4 * d + l];
        } else {
            for (int32_t k = 0; k < s->count; k++)
                memcpy(sim->xp + 3 * s->node[k], s->save + 3 * k, 3 * sizeof(double));
        }
    }
}

/* Changes the number of substeps, keeping velocities: x_prev is moved so that
 * (x - x_prev) / h stays the same for the new substep length. */
static void change_substeps(ftm_sim *sim, int32_t substeps)
{
    double h_new = sim->def.time_step / substeps, ratio = h_new / sim->h_sub;
    for (int32_t i = 0; i < sim->n; i++) {
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        if (xi[0] == pi[0] && xi[1] == pi[1] && xi[2] == pi[2])
            continue;
        for (int d = 0; d < 3; d++)
            pi[d] = xi[d] - (xi[d] - pi[d]) * ratio;
    }
    sim->substeps = substeps;
    sim->steps_at_substeps = 0;
    set_substep_length(sim, h_new);
    sim->st.substeps = substeps;
}

/* One attempt at a full step with the current substeps. */
static bool attempt_step(ftm_sim *sim, bool region_active, double *region_m2)
{
    bool ok = true;
    schedule *s = &sim->s;
    *region_m2 = 0.0;
    for (int32_t sub = 0; sub < sim->substeps; sub++) {
        if (region_active) {
            impose_displacements(sim);
            if (sim->def.order == FTM_ORDER_LAYER_JACOBI) {
                for (int32_t g = 0; g < s->groups; g++)
                    ok &= sweep_jacobi(sim, s->group[g], s->group[g + 1], region_m2);
            } else if (sim->def.order == FTM_ORDER_LAYER_COLORED) {
                if (!s->linked && s->uses++ > 0)
                    schedule_links(sim);
                ok &= sim->sweep_blocks(sim, region_m2);
            } else {
                ok &= sweep_gs(sim, 0, s->count, region_m2);
            }
        }
        ok &= sweep_relax(sim);
        if (!sim->def.guard)
            ok = true;
        if (!ok)
            return false;
    }
    return true;
}

static void compute_reactions(ftm_sim *sim)
{
    if (sim->reaction_groups)
        memset(sim->reaction, 0, (size_t)sim->reaction_groups * 3 * sizeof(double));
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        if (ct->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        double f[3];
        spring_force(sim->m, sim->x, ct->node, sim->x + 3 * ct->node, f);
        double *r = sim->reaction + 3 * ct->group;
        r[0] -= f[0];
        r[1] -= f[1];
        r[2] -= f[2];
    }
}

/* Relaxing nodes back at rest are set exactly to rest and dropped. */
static void sleep_relaxed(ftm_sim *sim)
{
    int32_t w = 0;
    const double tol = sim->tol;
    for (int32_t r = 0; r < sim->nrelax; r++) {
        int32_t i = sim->relax[r];
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        const double *X = sim->m->rest + 3 * i;
        bool rest = true;
        for (int d = 0; d < 3; d++)
            rest = rest && fabs(xi[d] - X[d]) <= tol && fabs(xi[d] - pi[d]) <= tol;
        if (rest) {
            memcpy(xi, X, 3 * sizeof(double));
            memcpy(pi, X, 3 * sizeof(double));
        } else {
            sim->relax[w++] = i;
        }
    }
    sim->nrelax = w;
}

int ftm_sim_step(ftm_sim *sim)
{
    int rc0 = refresh_region(sim);
    if (rc0)
        return rc0;
    bool region_active = (sim->s.count > 0 || sim->ndisp > 0) && !sim->region_sleeping;
    if (!region_active && sim->nrelax == 0) {
        sim->st.step++;
        sim->st.updated_nodes = 0;
        return FTM_OK;
    }
    double region_m2 = 0.0;
    for (;;) {
        double *full = NULL;
        int rc = save_state(sim, &full);
        if (rc)
            return rc;
        bool ok = attempt_step(sim, region_active, &region_m2);
        if (ok) {
            free(full);
            break;
        }
        restore_state(sim, full, region_active);
        free(full);
        sim->st.guard_events++;
        if (sim->substeps * 2 > sim->def.max_substeps) {
            sim->st.unstable_steps++;
            ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_ERROR,
                     "step %llu diverged even with %d substeps; state kept as before the step",
                     (unsigned long long)sim->st.step, (int)sim->substeps);
            return FTM_EUNSTABLE;
        }
        change_substeps(sim, sim->substeps * 2);
        ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                 "step %llu unstable (a node moved more than %g of its shortest link): rolled "
                 "back, now %d substeps per step",
                 (unsigned long long)sim->st.step, sim->def.guard_motion, (int)sim->substeps);
    }
    sim->st.updated_nodes = (region_active ? sim->s.count : 0) + sim->nrelax;
    sim->st.updated_nodes *= sim->substeps;
    sleep_relaxed(sim);
    compute_reactions(sim);
    if (sim->def.region_sleep_steps > 0 && region_active) {
        if (region_m2 <= sim->tol * sim->tol && sim->nrelax == 0) {
            if (++sim->quiet_steps >= sim->def.region_sleep_steps) {
                sim->region_sleeping = true; /* zero velocity: x_prev = x */
                for (int32_t k = 0; k < sim->s.count; k++) {
                    int32_t i = sim->s.node[k];
                    memcpy(sim->xp + 3 * i, sim->x + 3 * i, 3 * sizeof(double));
                }
                for (int32_t r = 0; r < sim->ndisp; r++)
                    memcpy(sim->xp + 3 * sim->disp[r], sim->x + 3 * sim->disp[r],
                           3 * sizeof(double));
            }
        } else {
            sim->quiet_steps = 0;
        }
    }
    if (sim->substeps > 1 && ++sim->steps_at_substeps >= FTM_SUBSTEP_RETRY)
        change_substeps(sim, sim->substeps / 2); /* the guard raises it again if needed */
    sim->st.step++;
    return FTM_OK;
}

int ftm_sim_run(ftm_sim *sim, int32_t count)
{
    for (int32_t i = 0; i < count; i++) {
        int rc = ftm_sim_step(sim);
        if (rc)
            return rc;
    }
    return FTM_OK;
}

/* ---- queries ---- */

const double *ftm_sim_positions(const ftm_sim *sim) { return sim->x; }

ftm_vec3 ftm_sim_position(const ftm_sim *sim, int32_t i)
{
    return (ftm_vec3){sim->x[3 * i], sim->x[3 * i + 1], sim->x[3 * i + 2]};
}

ftm_vec3 ftm_sim_reaction(const ftm_sim *sim, int32_t group)
{
    if (group < 0 || group >= sim->reaction_groups)
        return (ftm_vec3){0, 0, 0};
    const double *r = sim->reaction + 3 * group;
    return (ftm_vec3){r[0], r[1], r[2]};
}

static uint64_t mix64(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return x;
}

static uint64_t node_hash(const ftm_sim *sim, int32_t i)
{
    uint64_t h = mix64((uint64_t)i + 0x9e3779b97f4a7c15ULL);
    for (int d = 0; d < 3; d++) {
        uint64_t b;
        memcpy(&b, sim->x + 3 * i + d, sizeof b);
        h = mix64(h ^ b);
        memcpy(&b, sim->xp + 3 * i + d, sizeof b);
        h = mix64(h ^ b);
    }
    return h;
}

/* Every node not at rest is in the region, a displacement contact or the
 * relaxing set; XOR makes the result independent of visiting order. */
uint64_t ftm_sim_hash(const ftm_sim *sim)
{
    uint64_t acc = 0;
    const ftm_layering *ly = &sim->ly;
    int32_t region = ly->gen ? ly->count : 0;
    for (int32_t k = 0; k < region; k++)
        if (!at_rest(sim, ly->order[k]))
            acc ^= node_hash(sim, ly->order[k]);
    for (int32_t r = 0; r < sim->nrelax; r++)
        if (!at_rest(sim, sim->relax[r]))
            acc ^= node_hash(sim, sim->relax[r]);
    return mix64(acc ^ mix64(sim->st.step ^ 0x5851f42d4c957f2dULL));
}

void ftm_sim_get_stats(const ftm_sim *sim, ftm_sim_stats *st)
{
    *st = sim->st;
    st->layers = sim->ly.gen ? sim->ly.layers : 0;
    st->region_nodes = sim->ly.gen ? sim->ly.count : 0;
    st->relaxing_nodes = sim->nrelax;
    st->region_sleeping = sim->region_sleeping;
}

int32_t ftm_sim_layers(ftm_sim *sim, const int32_t **order, const int32_t **start)
{
    int rc = FTM_OK;
    if (sim->layers_dirty || sim->built_depth != sim->def.depth)
        rc = rebuild_region(sim);
    else if (sim->schedule_dirty)
        rc = rebuild_schedule(sim);
    if (rc)
        return rc;
    if (order)
        *order = sim->ly.order;
    if (start)
        *start = sim->ly.start;
    return sim->ly.layers;
}

double ftm_sim_kinetic_energy(const ftm_sim *sim)
{
    double e = 0.0, h = sim->h_sub;
    for (int32_t i = 0; i < sim->n; i++) {
        const double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        double v2 = 0.0;
        for (int d = 0; d < 3; d++)
            v2 += (xi[d] - pi[d]) * (xi[d] - pi[d]);
        e += 0.5 * sim->m->mass[i] * v2 / (h * h);
    }
    return e;
}

double ftm_sim_potential_energy(const ftm_sim *sim)
{
    const ftm_mesh *m = sim->m;
    double e = 0.0;
    for (int32_t l = 0; l < m->link_count; l++) {
        const double *a = sim->x + 3 * m->link_a[l], *b = sim->x + 3 * m->link_b[l];
        double rx = a[0] - b[0], ry = a[1] - b[1], rz = a[2] - b[2];
        double ext = sqrt(rx * rx + ry * ry + rz * rz) - m->link_len[l];
        e += 0.5 * m->link_k[l] * ext * ext;
    }
    return e;
}

void ftm_sim_reset(ftm_sim *sim)
{
    memcpy(sim->x, sim->m->rest, (size_t)sim->n * 3 * sizeof(double));
    memcpy(sim->xp, sim->m->rest, (size_t)sim->n * 3 * sizeof(double));
    ftm_sim_set_contacts(sim, NULL, 0, NULL);
    sim->nrelax = 0;
    sim->layers_dirty = true;
    sim->region_sleeping = false;
    sim->quiet_steps = 0;
    if (sim->substeps != 1)
        change_substeps(sim, 1);
    uint64_t searches = sim->st.searches;
    memset(&sim->st, 0, sizeof sim->st);
    sim->st.searches = searches;
    sim->st.depth = sim->def.depth;
    sim->st.substeps = 1;
}
