/* SPDX-License-Identifier: GPL-3.0-or-later */
/* One tick (docs/server.md, The tick loop): the trainees' probes become
 * contacts by point collision with the deformed surface (collide.h), the
 * simulation steps exactly as every replica will (ftm_replay_step), the
 * reactions go into the frame, the report and --reactions. */
#include "rooms.h"
#include "step.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CATCHUP 50 /* ticks run in one timer callback before we call them missed */

static void hist_add(uint32_t *h, double ns)
{
    int64_t b = ns > 0 ? (int64_t)(ns / 10000.0) : 0;
    h[b < TICK_HIST_BINS ? b : TICK_HIST_BINS - 1]++;
}

/* The q-quantile of a histogram of `bins` bins `width` wide (upper edge of
 * its bin, in the unit of width); 0 when it is empty. */
static double quantile_of(const uint32_t *h, int bins, double width, double q)
{
    uint64_t n = 0, acc = 0;
    for (int i = 0; i < bins; i++)
        n += h[i];
    for (int i = 0; i < bins && n; i++)
        if ((acc += h[i]) >= (uint64_t)ceil(q * (double)n))
            return (i + 1) * width;
    return 0.0;
}

/* The q-quantile [ms] of a 10 us histogram (upper edge of its bin). */
double srv_hist_quantile(const uint32_t *h, double q)
{
    return quantile_of(h, TICK_HIST_BINS, 0.01, q);
}

/* The q-quantile [us] of a tick-work histogram (1 us bins). */
double srv_work_quantile(const uint32_t *h, double q)
{
    return quantile_of(h, WORK_HIST_BINS, 1.0, q);
}

uint64_t srv_hist_count(const uint32_t *h, int bins)
{
    uint64_t n = 0;
    for (int i = 0; i < bins; i++)
        n += h[i];
    return n;
}

static ftm_vec3 v_sub(ftm_vec3 a, ftm_vec3 b) { return (ftm_vec3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static double v_dot(ftm_vec3 a, ftm_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

static int reserve_contacts(server *s, int32_t need)
{
    if (need <= s->tk.contact_cap)
        return 0;
    int32_t cap = s->tk.contact_cap ? 2 * s->tk.contact_cap : 64;
    while (cap < need)
        cap *= 2;
    ftm_contact *c = realloc(s->tk.contacts, (size_t)cap * sizeof *c);
    if (!c)
        return -1;
    s->tk.contacts = c;
    ftm_wire_reaction *r = realloc(s->tk.reactions, (size_t)cap * sizeof *r);
    if (!r)
        return -1;
    s->tk.reactions = r;
    s->tk.contact_cap = cap;
    return 0;
}

/* Outward normal of a surface triangle at rest (not normalised): surface
 * triangles are oriented outward (generators, tetrahedra boundaries; OBJ
 * files must be too). */
static ftm_vec3 rest_normal(server *s, int32_t tr)
{
    const int32_t *v = ftm_mesh_triangles(s->mesh) + 3 * tr;
    ftm_vec3 X0 = ftm_mesh_rest_position(s->mesh, v[0]);
    ftm_vec3 e1 = v_sub(ftm_mesh_rest_position(s->mesh, v[1]), X0);
    ftm_vec3 e2 = v_sub(ftm_mesh_rest_position(s->mesh, v[2]), X0);
    return (ftm_vec3){e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z,
                      e1.x * e2.y - e1.y * e2.x};
}

/* Whether a HIP moving by d crosses the triangle from outside to inside. */
static bool entering(server *s, int32_t tr, ftm_vec3 d) { return v_dot(rest_normal(s, tr), d) < 0.0; }

/* A probe's contact begins on triangle tr at its rest-surface point anchor:
 * the anchor and normal the release rule and the push take, a touch in the
 * report, a line in the log. */
static void begin_contact(server *s, const participant *p, int k, probe *pr, int32_t tr,
                          ftm_vec3 anchor)
{
    pr->anchor = anchor;
    pr->normal = rest_normal(s, tr);
    pr->tri = tr;
    pr->contact = true;
    pr->limit_told = false;
    if (p->report >= 0)
        s->rec.report.parts[p->report].probes[k].touches++;
    srv_log(s, "info", "participant %u probe %d: contact on triangle %d", p->id, k, (int)tr);
}

/* A probe's push: HIP - anchor, shortened along itself to the limit. A HIP
 * far inside the tissue (a device glitch, a forged input) would otherwise
 * impose a displacement no step can follow: the guard would give up and the
 * tissue be reset for every participant. The replicas get the shortened
 * push in the frame, so they need not know the limit. */
static ftm_vec3 probe_push(server *s, const participant *p, int k, probe *pr)
{
    ftm_vec3 pen = v_sub(pr->hip, pr->anchor);
    double len = sqrt(v_dot(pen, pen));
    pr->limited = len > s->tk.max_push;
    if (pr->limited) {
        double f = s->tk.max_push / len; /* 0 if len overflowed: no push rather than NaN */
        pen = (ftm_vec3){pen.x * f, pen.y * f, pen.z * f};
        s->tk.push_limited++;
        if (!pr->limit_told)
            srv_log(s, "warn",
                    "participant %u probe %d: HIP %.4g m from its contact point; push limited to "
                    "%.4g m (--max-penetration) while it is further",
                    p->id, k, len, s->tk.max_push);
        pr->limit_told = true;
    }
    pr->push = pen;
    return pen;
}

/* How far p (rest coordinates) lies outside rest triangle tr, in
 * barycentric units; 0 inside. */
static double outside(server *s, int32_t tr, ftm_vec3 p)
{
    const int32_t *v = ftm_mesh_triangles(s->mesh) + 3 * tr;
    ftm_vec3 X0 = ftm_mesh_rest_position(s->mesh, v[0]);
    ftm_vec3 e1 = v_sub(ftm_mesh_rest_position(s->mesh, v[1]), X0);
    ftm_vec3 e2 = v_sub(ftm_mesh_rest_position(s->mesh, v[2]), X0), d = v_sub(p, X0);
    double a = v_dot(e1, e1), b = v_dot(e1, e2), c = v_dot(e2, e2);
    double p1 = v_dot(d, e1), p2 = v_dot(d, e2), det = a * c - b * b;
    if (!(det > 0.0))
        return INFINITY;
    double w1 = (c * p1 - b * p2) / det, w2 = (a * p2 - b * p1) / det, w0 = 1.0 - w1 - w2;
    double o = 0.0;
    o = fmax(o, -w0);
    o = fmax(o, -w1);
    return fmax(o, -w2);
}

/* --resume's first pass: the triangle a contact that began at this tick
 * (recorded reaction re) was on. The collision that chose it needs the
 * deformed surface, which that pass does not have; the frame has what it
 * chose: the contact point (rest coordinates, exact), the triangle's unit
 * normal and the nodes the probe pressed. The triangle is the one with
 * that normal giving those nodes (after the fixed ones and those earlier
 * probes have, contacts[0..n)) closest to the point. -1: none can be told
 * (no node pressed, no plane): the fast resume gives up. */
static int32_t tri_of_reaction(server *s, const ftm_wire_tick *rec, const ftm_wire_reaction *re,
                               int32_t n)
{
    int32_t want[3], nw = 0;
    for (int32_t j = 0; j < rec->contact_count; j++)
        if (rec->contacts[j].group == re->group) {
            if (nw == 3)
                return -1;
            want[nw++] = rec->contacts[j].node;
        }
    if (nw == 0 || !re->has_plane)
        return -1;
    const int32_t *tris = ftm_mesh_triangles(s->mesh);
    const int32_t nt = ftm_mesh_triangle_count(s->mesh);
    int32_t best = -1;
    double best_out = INFINITY;
    for (int32_t tr = 0; tr < nt; tr++) {
        const int32_t *v = tris + 3 * tr;
        int32_t got = 0;
        bool same = true;
        for (int q = 0; q < 3 && same; q++) {
            bool taken = ftm_mesh_fixed(s->mesh, v[q]);
            for (int32_t j = 0; j < n && !taken; j++)
                taken = s->tk.contacts[j].node == v[q];
            if (!taken)
                same = got < nw && want[got++] == v[q];
        }
        if (!same || got != nw)
            continue;
        ftm_vec3 nm = rest_normal(s, tr);
        double nl = sqrt(v_dot(nm, nm));
        if (!(nl > 0.0) || nm.x / nl != re->contact_normal.x || nm.y / nl != re->contact_normal.y ||
            nm.z / nl != re->contact_normal.z)
            continue;
        double o = outside(s, tr, re->contact_point);
        if (best < 0 || o < best_out) {
            best = tr;
            best_out = o;
        }
    }
    return best;
}

static const ftm_wire_reaction *reaction_of(const ftm_wire_tick *rec, int32_t group)
{
    for (int32_t r = 0; rec && r < rec->reaction_count; r++)
        if (rec->reactions[r].group == group)
            return &rec->reactions[r];
    return NULL;
}

/* Probe HIPs -> displacement contacts on the collided triangles' vertices.
 * Returns the contact count; *nreact the probes in contact. emulate
 * (--resume's first pass): no collision; a contact begins where the
 * recorded frame rec (NULL: none was sent) has its reaction; *why says when
 * that cannot be told. */
static int32_t probe_contacts(server *s, int32_t *nreact, bool emulate, const ftm_wire_tick *rec,
                              char *why, size_t why_size)
{
    const double *x = ftm_sim_positions(s->tk.sim);
    const int32_t *tris = ftm_mesh_triangles(s->mesh);
    int32_t n = 0, nr = 0;
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        participant *p = &s->parts.parts[i];
        if (!p->used || p->role != FTM_WIRE_ROLE_TRAINEE)
            continue;
        for (int k = 0; k < MAX_PROBES; k++) {
            probe *pr = &p->probes[k];
            if (!pr->have)
                continue;
            if (pr->contact) {
                ftm_vec3 pen = v_sub(pr->hip, pr->anchor);
                if (v_dot(pen, pr->normal) >= 0.0)
                    pr->contact = false; /* back on the side it came from: released */
            } else if (pr->have_prev && emulate) {
                const ftm_wire_reaction *re = reaction_of(rec, i * MAX_PROBES + k);
                int32_t tr = re ? tri_of_reaction(s, rec, re, n) : -1;
                if (re && tr < 0 && !why[0])
                    snprintf(why, why_size, "tick %" PRIu64 ": participant %u probe %d: the "
                             "triangle its contact began on cannot be told from the frame",
                             s->tk.tick + 1, p->id, k);
                if (tr >= 0)
                    begin_contact(s, p, k, pr, tr, re->contact_point);
            } else if (pr->have_prev) {
                double t, w[3];
                int32_t tr = ftm_collide_segment(s->tk.collide, x, pr->prev, pr->hip, &t, w);
                if (tr >= 0 && !entering(s, tr, v_sub(pr->hip, pr->prev)))
                    tr = -1; /* leaving the tissue through the surface: no contact */
                if (tr >= 0) {
                    const int32_t *v = tris + 3 * tr;
                    ftm_vec3 X[3];
                    for (int q = 0; q < 3; q++)
                        X[q] = ftm_mesh_rest_position(s->mesh, v[q]);
                    begin_contact(s, p, k, pr, tr,
                                  (ftm_vec3){w[0] * X[0].x + w[1] * X[1].x + w[2] * X[2].x,
                                             w[0] * X[0].y + w[1] * X[1].y + w[2] * X[2].y,
                                             w[0] * X[0].z + w[1] * X[1].z + w[2] * X[2].z});
                }
            }
            pr->prev = pr->hip;
            pr->have_prev = true;
            if (!pr->contact)
                continue;
            if (reserve_contacts(s, n + 3))
                return n;
            int32_t group = i * MAX_PROBES + k;
            ftm_vec3 pen = probe_push(s, p, k, pr);
            const int32_t *v = tris + 3 * pr->tri;
            for (int q = 0; q < 3; q++) {
                bool taken = ftm_mesh_fixed(s->mesh, v[q]);
                for (int32_t j = 0; j < n && !taken; j++)
                    taken = s->tk.contacts[j].node == v[q]; /* an earlier probe has it */
                if (!taken)
                    s->tk.contacts[n++] = (ftm_contact){v[q], group, FTM_CONTACT_DISPLACEMENT, pen};
            }
            s->tk.reactions[nr++] = (ftm_wire_reaction){.group = group, .participant = p->id, .probe = k};
        }
    }
    *nreact = nr;
    return n;
}

/* At the end of a run: what kept the tissue in bounds, if anything did. */
void srv_log_limits(server *s)
{
    if (s->tk.push_limited || s->tk.unstable)
        srv_log(s, "info",
                "%" PRIu64 " probe-ticks with the push limited to %.4g m; %" PRIu64
                " unstable ticks (tissue reset)",
                s->tk.push_limited, s->tk.max_push, s->tk.unstable);
}

static void note_step(server *s, double ns, bool contact)
{
    int64_t w = ns > 0 ? (int64_t)(ns / 1000.0) : 0;
    w = w < WORK_HIST_BINS ? w : WORK_HIST_BINS - 1;
    s->tk.work_hist[w]++;
    if (contact)
        s->tk.work_contact_hist[w]++;
    int b = 0;
    while (b < FTM_METRICS_STEP_BUCKETS && ns * 1e-9 > ftm_metrics_step_bounds[b])
        b++;
    s->tk.step_bucket[b]++;
    s->tk.step_count++;
    s->tk.step_sum_ns += ns;
}

/* When the tick started: its period and its lateness against the tick
 * clock (base_ns + k / rate), for the closing statistics. */
static void note_start(server *s, uint64_t begin)
{
    srv_tick *tk = &s->tk;
    if (tk->last_tick_ns)
        hist_add(tk->period_hist, (double)(begin - tk->last_tick_ns));
    tk->last_tick_ns = begin;
    hist_add(tk->late_hist, (double)begin - ((double)tk->base_ns +
                                             (double)(tk->tick + 1 - tk->base_tick) * tk->period_ns));
}

/* The reactions of the probes in contact after the step: the force, the
 * local force model for the client's haptic loop (docs/haptics.md), the
 * contact plane; counted in the report and written to --reactions. */
static void fill_reactions(server *s, int32_t nreact, const ftm_wire_tick *rec)
{
    srv_tick *tk = &s->tk;
    /* a tick the guard substepped: the tissue past its stable step, its
     * forces marked in the report (report.h, unstable); --resume's first
     * pass takes the forces from the frame, and runs only where the
     * keyframes show one substep throughout (offline.c) */
    ftm_sim_mode mode = {.substeps = 1};
    if (!rec)
        ftm_sim_get_mode(tk->sim, &mode);
    const bool unstable = mode.substeps > 1;
    for (int32_t r = 0; r < nreact; r++) {
        ftm_wire_reaction *re = &tk->reactions[r];
        re->force = rec ? rec->reactions[r].force : ftm_sim_reaction(tk->sim, re->group);
        const probe *pb = &s->parts.parts[re->group / MAX_PROBES].probes[re->group % MAX_PROBES];
        re->hip = pb->hip;
        /* a limited push does not follow the HIP: no local model, the client
         * holds the force */
        re->push_limited = pb->limited;
        re->has_model = !rec && !pb->limited &&
                        ftm_sim_contact_stiffness(tk->sim, re->group, re->stiffness) > 0;
        if (re->has_model) {
            ftm_stiffness_make_passive(re->stiffness);
            ftm_stiffness_secant_scale(re->stiffness, re->force, pb->push);
        }
        double nl = sqrt(v_dot(pb->normal, pb->normal));
        re->has_plane = nl > 0.0; /* the release rule of probe_contacts, for the client */
        re->contact_point = pb->anchor;
        if (re->has_plane)
            re->contact_normal = (ftm_vec3){pb->normal.x / nl, pb->normal.y / nl, pb->normal.z / nl};
        const participant *rp = &s->parts.parts[re->group / MAX_PROBES];
        const double push = sqrt(v_dot(pb->push, pb->push));
        if (rp->report >= 0) {
            ftm_report_part *part = &s->rec.report.parts[rp->report];
            ftm_report_contact(&part->probes[re->probe], tk->tick, re->force, push, pb->limited,
                               unstable);
            part->last_tick = tk->tick;
        }
        if (tk->reactions_csv) /* --reactions: what the frame carries, and the push */
            fprintf(tk->reactions_csv, "%" PRIu64 ",%u,%d,%.17g,%.17g,%.17g,%.17g,%.17g,%d\n",
                    tk->tick, re->participant, (int)re->probe, re->force.x, re->force.y,
                    re->force.z, (double)tk->tick / s->o.rate, push, pb->limited ? 1 : 0);
    }
}

void srv_run_tick(server *s)
{
    srv_tick *tk = &s->tk;
    const uint64_t tick_t0 = srv_now(); /* the whole tick, for the depth controller */
    note_start(s, tick_t0);
    int32_t nreact = 0;
    char none[1] = "";
    int32_t n = probe_contacts(s, &nreact, false, NULL, none, sizeof none);
    uint64_t t0 = srv_now();
    ftm_error err = {0, ""};
    int rc = ftm_replay_step(tk->sim, tk->depth, tk->contacts, n, &err);
    double dt = (double)(srv_now() - t0);
    tk->step_ns_total += dt;
    if (dt > tk->step_ns_max)
        tk->step_ns_max = dt;
    tk->tick++;
    if (rc) {
        /* Deterministic, so every replica fails the same way; start over from
         * rest at the next tick number and send the state as a keyframe. */
        tk->unstable++;
        srv_log(s, "error", "tick %" PRIu64 ": %s; tissue reset to rest", tk->tick, err.message);
        srv_reset(s, false);
        n = nreact = 0;
    }
    fill_reactions(s, nreact, NULL);
    if (tk->depth_lo == 0 || tk->depth < tk->depth_lo)
        tk->depth_lo = tk->depth;
    if (tk->depth > tk->depth_hi)
        tk->depth_hi = tk->depth;
    /* keep the collision grid current: the region's nodes may have moved */
    const int32_t *order = NULL, *start = NULL;
    int32_t layers = ftm_sim_layers(tk->sim, &order, &start);
    ftm_collide_update(tk->collide, ftm_sim_positions(tk->sim), order,
                       layers > 0 && order ? start[layers] : 0);
    ftm_sim_stats st;
    ftm_sim_get_stats(tk->sim, &st);
    srv_publish_tick(s, n, nreact, st.updated_nodes > 0);
    note_step(s, (double)(srv_now() - tick_t0), n > 0);
}

/* --resume's first pass (offline.c): tick rec->tick (rec NULL: a tick
 * whose frame was not sent, idle) without collision or the step, the
 * participants' probes, the contacts and the report taken on as
 * srv_run_tick takes them, the new contacts and the forces from the frame.
 * What this makes must be what the frame has (contacts bit-exact, the
 * probes in contact, their push limits). Returns 0, or -1 with *why. */
int srv_emulate_tick(server *s, const ftm_wire_tick *rec, char *why, size_t why_size)
{
    srv_tick *tk = &s->tk;
    int32_t nreact = 0;
    int32_t n = probe_contacts(s, &nreact, true, rec, why, why_size);
    tk->tick++;
    if (why[0])
        return -1;
    bool same = rec ? rec->tick == tk->tick && rec->contact_count == n &&
                          rec->reaction_count == nreact
                    : n == 0 && nreact == 0;
    for (int32_t i = 0; same && rec && i < n; i++) {
        const ftm_contact *a = &tk->contacts[i], *b = &rec->contacts[i];
        same = a->node == b->node && a->group == b->group && a->kind == b->kind &&
               memcmp(&a->value, &b->value, sizeof a->value) == 0;
    }
    for (int32_t r = 0; same && rec && r < nreact; r++) {
        const probe *pb = &s->parts.parts[tk->reactions[r].group / MAX_PROBES]
                               .probes[tk->reactions[r].group % MAX_PROBES];
        same = rec->reactions[r].group == tk->reactions[r].group &&
               rec->reactions[r].push_limited == pb->limited;
    }
    if (!same) {
        snprintf(why, why_size, "tick %" PRIu64 ": the probes give %d contacts of %d probes, "
                 "the frame %s %d of %d", tk->tick, (int)n, (int)nreact,
                 rec ? "has" : "was not sent: idle,", rec ? (int)rec->contact_count : 0,
                 rec ? (int)rec->reaction_count : 0);
        return -1;
    }
    fill_reactions(s, nreact, rec);
    if (tk->depth_lo == 0 || tk->depth < tk->depth_lo)
        tk->depth_lo = tk->depth;
    if (tk->depth > tk->depth_hi)
        tk->depth_hi = tk->depth;
    if (rec) { /* as srv_publish_frame leaves it */
        s->pub.tissue_frame = false;
        s->pub.pub_n = n;
        s->pub.pub_depth = tk->depth;
        s->pub.pub_tick = tk->tick;
        s->pub.published_any = true;
    }
    return 0;
}

/* The ticks that are due by the monotonic clock (tick k at start + k /
 * rate); more than MAX_CATCHUP at once are not run in a burst but counted
 * as missed, and the clock re-based. */
void srv_run_due_ticks(server *s)
{
    srv_tick *tk = &s->tk;
    uint64_t now = srv_now();
    uint64_t due = tk->base_tick + (uint64_t)((double)(now - tk->base_ns) / tk->period_ns);
    int32_t ran = 0;
    while (tk->tick < due && ran < MAX_CATCHUP) {
        srv_run_tick(s);
        ran++;
    }
    if (tk->tick < due) { /* fell behind: skip, do not burst */
        tk->missed_ticks += due - tk->tick;
        tk->base_ns = now;
        tk->base_tick = tk->tick;
    }
}

/* Puts the tissue back at rest, keeping the tick counter. With publish_now
 * (between ticks): first the frame of the current tick if it was not sent
 * (replicas must reach it), then the keyframe of the reset state at that tick,
 * which replicas restore because its hash differs from the frame's. */
void srv_reset(server *s, bool publish_now)
{
    s->tk.resets++;
    if (publish_now)
        srv_publish_tick_frame(s);
    ftm_error err = {0, ""};
    if (ftm_sim_load_state(s->tk.sim, s->tk.tick, s->tk.depth, NULL, NULL, NULL, 0, NULL, 0, NULL, &err))
        srv_log(s, "error", "reset: %s", err.message);
    for (int i = 0; i < MAX_PARTICIPANTS; i++)
        for (int k = 0; k < MAX_PROBES; k++)
            s->parts.parts[i].probes[k].contact = false;
    ftm_collide_update(s->tk.collide, ftm_sim_positions(s->tk.sim), NULL, 0);
    s->pub.pub_n = 0; /* replicas restore the keyframe: no contacts */
    s->pub.keyframe_due = true;
    if (publish_now && srv_publish_keyframe(s)) {
        s->pub.keyframe_due = false;
        s->pub.next_keyframe_ns = srv_now() + (uint64_t)(s->o.keyframe_every * 1e9);
    }
}


/* The simulation of the scene, its collision grid and the push limit. The
 * depth: --depth, else the scene's. Returns 0, or the exit status (2 a
 * depth floor above the depth, 3 a simulation that cannot be made). */
int srv_tick_setup(server *s)
{
    srv_tick *tk = &s->tk;
    ftm_sim_def def = ftm_replay_sim_def(s->scene);
    def.log = srv_log_hook;
    def.log_user = s;
    tk->depth = s->o.depth >= 0 ? s->o.depth : def.depth;
    if (s->o.depth_floor > tk->depth) {
        srv_log(s, "error", "--depth-floor %d is above the depth %d", (int)s->o.depth_floor,
                (int)tk->depth);
        return 2;
    }
    ftm_error err = {0, ""};
    tk->mat.scene = s->scene;
    if (ftm_sim_create(s->mesh, &def, &tk->sim, &err) ||
        ftm_collide_create(s->mesh, &tk->collide, &err)) {
        srv_log(s, "error", "%s", err.message);
        return 3;
    }
    ftm_collide_stats cs;
    ftm_collide_get_stats(tk->collide, &cs);
    /* the default push limit, the scene's size: a probe pushing the surface
     * further than the whole tissue is deep is passing through it */
    tk->max_push = s->o.max_penetration > 0 ? s->o.max_penetration
                   : cs.extent > 0          ? cs.extent
                                            : INFINITY;
    char limit[32] = "none (the recording has none)";
    if (isfinite(tk->max_push))
        snprintf(limit, sizeof limit, "%.4g m", tk->max_push);
    srv_log(s, "info",
            "scene '%s': %d nodes, %d surface triangles; collision grid %dx%dx%d cells of %.4g m; "
            "probe push limit %s",
            ftm_scene_name(s->scene), (int)ftm_mesh_node_count(s->mesh), (int)cs.triangles,
            (int)cs.dims[0], (int)cs.dims[1], (int)cs.dims[2], cs.cell_size, limit);
    char model[256];
    ftm_scene_describe_model(s->scene, model, sizeof model);
    srv_log(s, "info", "scene '%s' runs %s", ftm_scene_name(s->scene), model);
    /* a scene a trainee cannot feel is said now, not found out in the lesson */
    ftm_press_estimate pe;
    if (ftm_scene_press_estimate(s->scene, FTM_PRESS_ESTIMATE_DEPTH, &pe, &err) == FTM_OK) {
        char feel[192];
        ftm_press_describe(&pe, feel, sizeof feel);
        srv_log(s, ftm_press_verdict(&pe) ? "warn" : "info", "scene '%s': %s",
                ftm_scene_name(s->scene), feel);
    } else {
        srv_log(s, "info", "scene '%s': no press estimate: %s", ftm_scene_name(s->scene),
                err.message);
    }
    tk->period_ns = 1e9 / s->o.rate;
    return 0;
}

void srv_tick_free(server *s)
{
    ftm_collide_destroy(s->tk.collide);
    ftm_sim_destroy(s->tk.sim);
    ftm_replay_material_free(&s->tk.mat);
    free(s->tk.contacts);
    free(s->tk.reactions);
}
