/* Deterministic replay of tick frames; see replay.h and docs/protocol.md. */
#include "replay.h"

#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- SHA-256 (FIPS 180-4) ---------------------------------------------------- */

typedef struct sha256 {
    uint32_t h[8];
    uint8_t buf[64];
    size_t fill;
    uint64_t bytes;
} sha256;

static const uint32_t sha_k[64] = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4,
    0xab1c5ed5, 0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe,
    0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f,
    0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7,
    0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc,
    0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b,
    0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116,
    0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
    0xc67178f2};

static uint32_t ror(uint32_t x, int n) { return (x >> n) | (x << (32 - n)); }

static void sha_block(sha256 *s, const uint8_t *p)
{
    uint32_t w[64];
    for (int i = 0; i < 16; i++)
        w[i] = (uint32_t)p[4 * i] << 24 | (uint32_t)p[4 * i + 1] << 16 |
               (uint32_t)p[4 * i + 2] << 8 | (uint32_t)p[4 * i + 3];
    for (int i = 16; i < 64; i++) {
        uint32_t s0 = ror(w[i - 15], 7) ^ ror(w[i - 15], 18) ^ (w[i - 15] >> 3);
        uint32_t s1 = ror(w[i - 2], 17) ^ ror(w[i - 2], 19) ^ (w[i - 2] >> 10);
        w[i] = w[i - 16] + s0 + w[i - 7] + s1;
    }
    uint32_t a = s->h[0], b = s->h[1], c = s->h[2], d = s->h[3], e = s->h[4], f = s->h[5],
             g = s->h[6], h = s->h[7];
    for (int i = 0; i < 64; i++) {
        uint32_t t1 = h + (ror(e, 6) ^ ror(e, 11) ^ ror(e, 25)) + ((e & f) ^ (~e & g)) +
                      sha_k[i] + w[i];
        uint32_t t2 = (ror(a, 2) ^ ror(a, 13) ^ ror(a, 22)) + ((a & b) ^ (a & c) ^ (b & c));
        h = g;
        g = f;
        f = e;
        e = d + t1;
        d = c;
        c = b;
        b = a;
        a = t1 + t2;
    }
    s->h[0] += a;
    s->h[1] += b;
    s->h[2] += c;
    s->h[3] += d;
    s->h[4] += e;
    s->h[5] += f;
    s->h[6] += g;
    s->h[7] += h;
}

static void sha_init(sha256 *s)
{
    static const uint32_t h0[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                                   0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
    memcpy(s->h, h0, sizeof h0);
    s->fill = 0;
    s->bytes = 0;
}

static void sha_update(sha256 *s, const void *data, size_t n)
{
    const uint8_t *p = data;
    s->bytes += n;
    while (n > 0) {
        size_t take = 64 - s->fill < n ? 64 - s->fill : n;
        memcpy(s->buf + s->fill, p, take);
        s->fill += take;
        p += take;
        n -= take;
        if (s->fill == 64) {
            sha_block(s, s->buf);
            s->fill = 0;
        }
    }
}

static void sha_final(sha256 *s, uint8_t out[32])
{
    uint64_t bits = s->bytes * 8;
    uint8_t pad = 0x80, zero = 0;
    sha_update(s, &pad, 1);
    while (s->fill != 56)
        sha_update(s, &zero, 1);
    uint8_t len[8];
    for (int i = 0; i < 8; i++)
        len[i] = (uint8_t)(bits >> (56 - 8 * i));
    sha_update(s, len, 8);
    for (int i = 0; i < 8; i++)
        for (int j = 0; j < 4; j++)
            out[4 * i + j] = (uint8_t)(s->h[i] >> (24 - 8 * j));
}

void ftm_sha256(const void *data, size_t size, uint8_t out[32])
{
    sha256 s;
    sha_init(&s);
    sha_update(&s, data, size);
    sha_final(&s, out);
}

/* Little-endian, whatever the host. */
static void sha_u64(sha256 *s, uint64_t v)
{
    uint8_t b[8];
    for (int i = 0; i < 8; i++)
        b[i] = (uint8_t)(v >> (8 * i));
    sha_update(s, b, 8);
}

static void sha_f64(sha256 *s, double d)
{
    uint64_t v;
    memcpy(&v, &d, sizeof v);
    sha_u64(s, v);
}

/* ---- scene --------------------------------------------------------------------- */

ftm_sim_def ftm_replay_sim_def(const ftm_scene *scene)
{
    ftm_sim_def d = ftm_scene_sim_def(scene);
    d.log = NULL;
    d.log_user = NULL;
    return d;
}

void ftm_replay_scene_digest(const ftm_scene *scene, uint8_t out[FTM_REPLAY_DIGEST_SIZE])
{
    const ftm_mesh *m = ftm_scene_mesh(scene);
    sha256 s;
    sha_init(&s);
    sha_update(&s, "ftm.v1 scene", 12);
    int32_t n = ftm_mesh_node_count(m);
    sha_u64(&s, (uint64_t)n);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 p = ftm_mesh_rest_position(m, i);
        sha_f64(&s, p.x);
        sha_f64(&s, p.y);
        sha_f64(&s, p.z);
        sha_f64(&s, ftm_mesh_mass(m, i));
        sha_f64(&s, ftm_mesh_damping(m, i));
        sha_u64(&s, ftm_mesh_fixed(m, i));
        const int32_t *nb;
        const double *k, *l;
        int32_t deg = ftm_mesh_neighbors(m, i, &nb, &k, &l);
        sha_u64(&s, (uint64_t)deg);
        for (int32_t j = 0; j < deg; j++) {
            sha_u64(&s, (uint64_t)nb[j]);
            sha_f64(&s, k[j]);
            sha_f64(&s, l[j]);
        }
    }
    int32_t nt = ftm_mesh_triangle_count(m);
    const int32_t *t = ftm_mesh_triangles(m);
    sha_u64(&s, (uint64_t)nt);
    for (int32_t i = 0; i < 3 * nt; i++)
        sha_u64(&s, (uint64_t)t[i]);
    ftm_sim_def d = ftm_replay_sim_def(scene);
    sha_f64(&s, d.time_step);
    sha_u64(&s, (uint64_t)d.depth);
    sha_u64(&s, (uint64_t)d.order);
    sha_f64(&s, d.sleep_tolerance);
    sha_u64(&s, (uint64_t)d.region_sleep_steps);
    sha_u64(&s, d.guard);
    sha_f64(&s, d.guard_motion);
    sha_u64(&s, (uint64_t)d.max_substeps);
    sha_u64(&s, d.cache_layers);
    sha_final(&s, out);
}

/* ---- one tick ------------------------------------------------------------------ */

int ftm_replay_step(ftm_sim *sim, int32_t depth, const ftm_contact *contacts, int32_t count,
                    ftm_error *err)
{
    int rc = ftm_sim_set_depth(sim, depth);
    if (rc) {
        if (err) {
            err->code = rc;
            snprintf(err->message, sizeof err->message, "depth %d out of range", (int)depth);
        }
        return rc;
    }
    rc = ftm_sim_set_contacts(sim, contacts, count, err);
    if (rc)
        return rc;
    rc = ftm_sim_step(sim);
    if (rc && err) {
        err->code = rc;
        snprintf(err->message, sizeof err->message, "step failed: %s", ftm_strerror(rc));
    }
    return rc;
}

/* ---- tissue parameters ------------------------------------------------------- */

ftm_wire_tissue ftm_replay_scene_tissue(const ftm_scene *scene)
{
    ftm_material_def m = ftm_scene_material(scene);
    return (ftm_wire_tissue){m.node_mass, m.node_damping, m.stiffness, m.axis_scale};
}

ftm_wire_tissue ftm_replay_tissue_now(const ftm_replay_material *mat)
{
    return mat->changed ? mat->current : ftm_replay_scene_tissue(mat->scene);
}

static bool same_tissue(const ftm_wire_tissue *a, const ftm_wire_tissue *b)
{
    return a->node_mass == b->node_mass && a->node_damping == b->node_damping &&
           a->stiffness == b->stiffness && a->axis_scale.x == b->axis_scale.x &&
           a->axis_scale.y == b->axis_scale.y && a->axis_scale.z == b->axis_scale.z;
}

int ftm_replay_set_tissue(ftm_replay_material *mat, ftm_sim *sim, const ftm_wire_tissue *t,
                          ftm_error *err)
{
    ftm_wire_tissue base = ftm_replay_scene_tissue(mat->scene), now = ftm_replay_tissue_now(mat);
    if (!t)
        t = &base;
    if (same_tissue(t, &now))
        return FTM_OK;
    const ftm_mesh *scene_mesh = ftm_scene_mesh(mat->scene);
    ftm_mesh *m = NULL;
    int rc;
    if (!same_tissue(t, &base)) {
        ftm_material_def from = ftm_scene_material(mat->scene);
        ftm_material_def to = {t->node_mass, t->node_damping, t->stiffness, t->axis_scale};
        if ((rc = ftm_mesh_with_material(scene_mesh, &from, &to, &m, err)))
            return rc;
    }
    if ((rc = ftm_sim_set_mesh(sim, m ? m : scene_mesh, err))) {
        ftm_mesh_destroy(m);
        return rc;
    }
    ftm_mesh_destroy(mat->mesh);
    mat->mesh = m;
    mat->changed = m != NULL;
    mat->current = *t;
    return FTM_OK;
}

void ftm_replay_material_free(ftm_replay_material *mat)
{
    ftm_mesh_destroy(mat->mesh);
    mat->mesh = NULL;
    mat->changed = false;
}

int ftm_replay_make_keyframe(const ftm_sim *sim, const ftm_replay_material *mat,
                             ftm_wire_keyframe *out, ftm_error *err)
{
    const ftm_mesh *m = ftm_sim_mesh(sim);
    int32_t n = ftm_mesh_node_count(m);
    const double *x = ftm_sim_positions(sim), *xp = ftm_sim_previous_positions(sim);
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    memset(out, 0, sizeof *out);
    int32_t count = 0;
    for (int pass = 0; pass < 2; pass++) {
        int32_t k = 0;
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 r = ftm_mesh_rest_position(m, i);
            const double *a = x + 3 * i, *b = xp + 3 * i;
            if (a[0] == r.x && a[1] == r.y && a[2] == r.z && b[0] == r.x && b[1] == r.y &&
                b[2] == r.z)
                continue;
            if (pass == 1) {
                out->nodes[k] = i;
                memcpy(out->positions + 3 * k, a, 3 * sizeof(double));
                memcpy(out->previous + 3 * k, b, 3 * sizeof(double));
            }
            k++;
        }
        if (pass == 0) {
            count = k;
            out->nodes = malloc(((size_t)count + 1) * sizeof *out->nodes);
            out->positions = malloc(((size_t)count + 1) * 3 * sizeof(double));
            out->previous = malloc(((size_t)count + 1) * 3 * sizeof(double));
            if (!out->nodes || !out->positions || !out->previous) {
                ftm_replay_keyframe_free(out);
                if (err) {
                    err->code = FTM_ENOMEM;
                    snprintf(err->message, sizeof err->message, "keyframe: out of memory");
                }
                return FTM_ENOMEM;
            }
        }
    }
    out->tick = st.step;
    out->state_hash = ftm_sim_hash(sim);
    out->has_mode = true;
    ftm_sim_get_mode(sim, &out->mode);
    out->has_tissue = mat && mat->changed;
    if (out->has_tissue)
        out->tissue = mat->current;
    out->node_count = n;
    out->depth = st.depth;
    out->count = count;
    const ftm_contact *c;
    int32_t nc = ftm_sim_contacts(sim, &c);
    out->contacts = malloc(((size_t)nc + 1) * sizeof *out->contacts);
    if (!out->contacts) {
        ftm_replay_keyframe_free(out);
        if (err) {
            err->code = FTM_ENOMEM;
            snprintf(err->message, sizeof err->message, "keyframe: out of memory");
        }
        return FTM_ENOMEM;
    }
    if (nc)
        memcpy(out->contacts, c, (size_t)nc * sizeof *c);
    out->contact_count = nc;
    return FTM_OK;
}

void ftm_replay_keyframe_free(ftm_wire_keyframe *k)
{
    free(k->nodes);
    free(k->positions);
    free(k->previous);
    free(k->contacts);
    memset(k, 0, sizeof *k);
}

/* ---- the replica ------------------------------------------------------------------ */

#define RING_CAP 4096            /* frames kept: unapplied ones and recent history */

typedef struct frame {
    uint64_t tick, hash, gap;
    int32_t depth, n, nreact;
    ftm_contact *c;
    ftm_wire_reaction *react;
    bool has_tissue; /* new tissue parameters from this tick on */
    ftm_wire_tissue tissue;
    bool dropped; /* broke the idle rule: not the server's, never applied */
} frame;

struct ftm_replay {
    const ftm_scene *scene;
    ftm_sim *sim;
    ftm_replay_material mat;
    ftm_log_fn log;
    void *log_user;
    uint8_t digest[FTM_REPLAY_DIGEST_SIZE];
    ftm_wire_state state;

    frame *ring;
    int32_t head, count, applied; /* ring[head .. head+applied) are applied */
    bool have_frames;
    uint64_t unbroken_since; /* tick of the first frame of the current gap-free run */
    bool evicted_any;
    uint64_t evicted_max; /* newest tick evicted from the ring */
    uint64_t kf_tick;     /* tick of the last keyframe loaded */
    bool kf_loaded;

    int32_t last_depth; /* depth and contacts of the last applied frame: idle ticks */
    int32_t last_n, last_cap;
    ftm_contact *last_c;

    bool has_pending;
    ftm_wire_keyframe pending;
    bool pending_reported;

    ftm_wire_tick last; /* copy of the last applied frame */
    int32_t last_react_cap, last_contact_cap;

    ftm_replay_stats st;
};

static void rlog(const ftm_replay *r, ftm_log_level level, const char *fmt, ...)
{
    if (!r->log)
        return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    r->log(r->log_user, level, buf);
}

static frame *ring_at(ftm_replay *r, int32_t i) { return &r->ring[(r->head + i) % RING_CAP]; }

static void frame_free(frame *f)
{
    free(f->c);
    free(f->react);
    memset(f, 0, sizeof *f);
}

static void ring_pop(ftm_replay *r)
{
    frame *f = ring_at(r, 0);
    if (!r->evicted_any || f->tick > r->evicted_max)
        r->evicted_max = f->tick;
    r->evicted_any = true;
    frame_free(f);
    r->head = (r->head + 1) % RING_CAP;
    r->count--;
    if (r->applied > 0)
        r->applied--;
}

int ftm_replay_create(const ftm_scene *scene, ftm_log_fn log, void *log_user, ftm_replay **out,
                      ftm_error *err)
{
    ftm_replay *r = calloc(1, sizeof *r);
    if (!r)
        goto nomem;
    r->ring = calloc(RING_CAP, sizeof *r->ring);
    if (!r->ring)
        goto nomem;
    r->scene = scene;
    r->mat.scene = scene;
    r->log = log;
    r->log_user = log_user;
    ftm_sim_def def = ftm_replay_sim_def(scene);
    def.log = log;
    def.log_user = log_user;
    int rc = ftm_sim_create(ftm_scene_mesh(scene), &def, &r->sim, err);
    if (rc) {
        free(r->ring);
        free(r);
        return rc;
    }
    ftm_replay_scene_digest(scene, r->digest);
    r->state = FTM_WIRE_STATE_JOINING;
    r->last_depth = def.depth;
    *out = r;
    return FTM_OK;
nomem:
    if (r)
        free(r->ring);
    free(r);
    if (err) {
        err->code = FTM_ENOMEM;
        snprintf(err->message, sizeof err->message, "replay: out of memory");
    }
    return FTM_ENOMEM;
}

void ftm_replay_destroy(ftm_replay *r)
{
    if (!r)
        return;
    while (r->count > 0)
        ring_pop(r);
    free(r->ring);
    free(r->last_c);
    free(r->last.contacts);
    free(r->last.reactions);
    if (r->has_pending)
        ftm_replay_keyframe_free(&r->pending);
    ftm_sim_destroy(r->sim);
    ftm_replay_material_free(&r->mat);
    free(r);
}

int ftm_replay_check_announce(const ftm_replay *r, const ftm_wire_announce *a, ftm_error *err)
{
    /* servers from before the field computed with revision 1 */
    const uint32_t theirs = a->arithmetic ? a->arithmetic : 1, ours = ftm_arithmetic_revision();
    if (theirs != ours) {
        if (err) {
            err->code = FTM_EVERSION;
            snprintf(err->message, sizeof err->message,
                     "the server's physics core is of arithmetic revision %" PRIu32
                     ", this build's of revision %" PRIu32
                     ": its replay would not match the server's; use builds of one FTM version",
                     theirs, ours);
        }
        return FTM_EVERSION;
    }
    const char *why = NULL;
    if (a->digest_len != FTM_REPLAY_DIGEST_SIZE || memcmp(a->digest, r->digest, sizeof r->digest))
        why = "content digest differs";
    else if (a->node_count != ftm_mesh_node_count(ftm_scene_mesh(r->scene)))
        why = "node count differs";
    else if (a->time_step != ftm_replay_sim_def(r->scene).time_step)
        why = "time step differs";
    if (!why)
        return FTM_OK;
    if (err) {
        err->code = FTM_EINVAL;
        snprintf(err->message, sizeof err->message,
                 "announced scene '%s' does not match the local scene '%s': %s", a->scene_id,
                 ftm_scene_name(r->scene), why);
    }
    return FTM_EINVAL;
}

static void enter_resync(ftm_replay *r, const char *why)
{
    if (r->state != FTM_WIRE_STATE_SYNCED)
        return;
    r->state = FTM_WIRE_STATE_RESYNCING;
    r->st.resyncs++;
    rlog(r, FTM_LOG_WARN, "replay: resyncing at tick %" PRIu64 ": %s", ftm_replay_tick(r), why);
}

static int remember_last(ftm_replay *r, const frame *f)
{
    if (f->n > r->last_cap) {
        ftm_contact *c = realloc(r->last_c, (size_t)f->n * sizeof *c);
        ftm_contact *c2 = realloc(r->last.contacts, (size_t)f->n * sizeof *c2);
        if (c)
            r->last_c = c;
        if (c2)
            r->last.contacts = c2;
        if (!c || !c2)
            return FTM_ENOMEM;
        r->last_cap = f->n;
    }
    if (f->nreact > r->last_react_cap) {
        ftm_wire_reaction *q = realloc(r->last.reactions, (size_t)f->nreact * sizeof *q);
        if (!q)
            return FTM_ENOMEM;
        r->last.reactions = q;
        r->last_react_cap = f->nreact;
    }
    if (f->n)
        memcpy(r->last_c, f->c, (size_t)f->n * sizeof *f->c);
    if (f->n)
        memcpy(r->last.contacts, f->c, (size_t)f->n * sizeof *f->c);
    if (f->nreact)
        memcpy(r->last.reactions, f->react, (size_t)f->nreact * sizeof *f->react);
    r->last_n = f->n;
    r->last_depth = f->depth;
    r->last.tick = f->tick;
    r->last.depth = f->depth;
    r->last.contact_count = f->n;
    r->last.reaction_count = f->nreact;
    r->last.state_hash = f->hash;
    return FTM_OK;
}

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static int timed_step(ftm_replay *r, int32_t depth, const ftm_contact *c, int32_t n)
{
    double t0 = now_ns();
    ftm_error err = {0, ""};
    int rc = ftm_replay_step(r->sim, depth, c, n, &err);
    double dt = now_ns() - t0;
    r->st.replay_ns_total += dt;
    if (dt > r->st.replay_ns_max)
        r->st.replay_ns_max = dt;
    if (rc)
        rlog(r, FTM_LOG_WARN, "replay: tick %" PRIu64 ": %s", ftm_replay_tick(r) + 1, err.message);
    return rc;
}

/* Tissue parameters from a frame or keyframe (NULL: the scene's). */
static int set_tissue(ftm_replay *r, uint64_t tick, const ftm_wire_tissue *t)
{
    ftm_wire_tissue before = ftm_replay_tissue_now(&r->mat);
    ftm_error err = {0, ""};
    int rc = ftm_replay_set_tissue(&r->mat, r->sim, t, &err);
    if (rc) {
        rlog(r, FTM_LOG_ERROR, "replay: tick %" PRIu64 ": tissue parameters not applied: %s",
             tick, err.message);
        return rc;
    }
    ftm_wire_tissue now = ftm_replay_tissue_now(&r->mat);
    if (!same_tissue(&before, &now))
        rlog(r, FTM_LOG_INFO,
             "replay: tick %" PRIu64 ": tissue now k %g N/m, d %g N s/m, m %g kg", tick,
             now.stiffness, now.node_damping, now.node_mass);
    return FTM_OK;
}

static int load_keyframe(ftm_replay *r, const ftm_wire_keyframe *k)
{
    ftm_error err = {0, ""};
    int rc = set_tissue(r, k->tick, k->has_tissue ? &k->tissue : NULL);
    if (rc)
        return rc;
    rc = ftm_sim_load_state(r->sim, k->tick, k->depth, k->nodes, k->positions, k->previous,
                            k->count, k->contacts, k->contact_count,
                            k->has_mode ? &k->mode : NULL, &err);
    if (rc) {
        rlog(r, FTM_LOG_ERROR, "replay: keyframe at tick %" PRIu64 " rejected: %s", k->tick,
             err.message);
        return rc;
    }
    uint64_t h = ftm_sim_hash(r->sim);
    if (h != k->state_hash) {
        rlog(r, FTM_LOG_ERROR,
             "replay: keyframe at tick %" PRIu64 " restored with hash %016" PRIx64
             ", keyframe says %016" PRIx64 " (different scene or libftm?)",
             k->tick, h, k->state_hash);
        return FTM_EINVAL;
    }
    /* idle ticks after it step with its contacts, as the server did */
    if (k->contact_count > r->last_cap) {
        ftm_contact *c = realloc(r->last_c, (size_t)k->contact_count * sizeof *c);
        if (c)
            r->last_c = c;
        ftm_contact *c2 = c ? realloc(r->last.contacts, (size_t)k->contact_count * sizeof *c2) : NULL;
        if (c2)
            r->last.contacts = c2;
        if (!c || !c2)
            return FTM_ENOMEM;
        r->last_cap = k->contact_count;
    }
    if (k->contact_count)
        memcpy(r->last_c, k->contacts, (size_t)k->contact_count * sizeof *k->contacts);
    r->last_depth = k->depth;
    r->last_n = k->contact_count;
    r->kf_tick = k->tick;
    r->kf_loaded = true;
    r->st.keyframes_loaded++;
    /* frames after the keyframe are to be applied (again) */
    int32_t i = 0;
    while (i < r->count && ring_at(r, i)->tick <= k->tick)
        i++;
    r->applied = i;
    return FTM_OK;
}

static void drop_pending(ftm_replay *r)
{
    if (r->has_pending)
        ftm_replay_keyframe_free(&r->pending);
    r->has_pending = false;
    r->pending_reported = false;
}

/* A frame that broke the idle rule: never applied, not even after a resync
 * (a keyframe restores the frames after it, which would bring it back). */
static void drop_frame(ftm_replay *r, frame *f, const char *why)
{
    f->dropped = true;
    r->st.rule_breaks++;
    enter_resync(r, why);
}

static int apply_frames(ftm_replay *r)
{
    while (r->state == FTM_WIRE_STATE_SYNCED && r->applied < r->count) {
        frame *f = ring_at(r, r->applied);
        uint64_t cur = ftm_replay_tick(r);
        if (f->dropped) {
            r->applied++;
            continue;
        }
        if (f->gap > 0 && !(r->kf_loaded && f->tick <= r->kf_tick + 1)) {
            r->st.gaps++;
            char why[96];
            snprintf(why, sizeof why, "%" PRIu64 " tick frame(s) lost before tick %" PRIu64,
                     f->gap, f->tick);
            enter_resync(r, why);
            return FTM_OK;
        }
        if (f->tick <= cur) {
            r->st.stale_frames++;
            r->applied++;
            continue;
        }
        /* The server leaves a tick out only when it and the frame before it
         * have no contacts and its step moved nothing (docs/protocol.md).
         * A frame that claims otherwise is not the server's: it is dropped
         * and the replica resyncs, rather than step through up to
         * FTM_WIRE_MAX_TICK_GAP loaded ticks for it. */
        if (f->tick - cur > FTM_WIRE_MAX_TICK_GAP) {
            drop_frame(r, f, "frame too far ahead");
            return FTM_OK;
        }
        if (f->tick - cur > 1 && r->last_n > 0) {
            drop_frame(r, f, "frame skips ticks after a tick with contacts");
            return FTM_OK;
        }
        while (ftm_replay_tick(r) + 1 < f->tick) { /* ticks the server left out: idle */
            uint64_t before = ftm_replay_tick(r);
            timed_step(r, r->last_depth, r->last_c, r->last_n);
            r->st.idle_ticks++;
            if (ftm_replay_tick(r) == before)
                break; /* the step failed; the hash check below catches it */
            ftm_sim_stats st;
            ftm_sim_get_stats(r->sim, &st);
            if (st.updated_nodes > 0) {
                char why[128];
                snprintf(why, sizeof why,
                         "idle tick %" PRIu64 " moved nodes, so the server would have sent it",
                         ftm_replay_tick(r));
                drop_frame(r, f, why);
                return FTM_OK;
            }
        }
        if (f->has_tissue && set_tissue(r, f->tick, &f->tissue)) {
            enter_resync(r, "tissue parameters could not be applied");
            return FTM_OK;
        }
        timed_step(r, f->depth, f->c, f->n);
        r->st.frames_applied++;
        r->applied++;
        int rc = remember_last(r, f);
        if (rc)
            return rc;
        uint64_t h = ftm_sim_hash(r->sim);
        if (h != f->hash || ftm_replay_tick(r) != f->tick) {
            r->st.mismatches++;
            char why[128];
            snprintf(why, sizeof why,
                     "hash mismatch at tick %" PRIu64 ": mine %016" PRIx64 ", server %016" PRIx64,
                     f->tick, h, f->hash);
            enter_resync(r, why);
            return FTM_OK;
        }
        if (r->has_pending && r->pending.tick <= f->tick) {
            if (r->pending.tick == f->tick && r->pending.state_hash != h) {
                rlog(r, FTM_LOG_INFO,
                     "replay: server state changed at tick %" PRIu64 " (reset): keyframe restored",
                     f->tick);
                rc = load_keyframe(r, &r->pending);
                if (rc)
                    enter_resync(r, "keyframe could not be restored");
            }
            drop_pending(r);
        }
    }
    return FTM_OK;
}

/* Not synced: restore the pending keyframe if the frames received since can
 * continue it (no frame after it lost). */
static int try_resync(ftm_replay *r)
{
    if (r->state == FTM_WIRE_STATE_SYNCED || !r->has_pending)
        return FTM_OK;
    uint64_t k = r->pending.tick;
    if (!r->have_frames)
        return FTM_OK; /* wait for frames to show continuity */
    if (r->unbroken_since > k + 1 || (r->evicted_any && r->evicted_max > k)) {
        if (!r->pending_reported) {
            r->st.keyframes_unusable++;
            r->pending_reported = true;
        }
        return FTM_OK; /* frames after it were lost: wait for a newer one */
    }
    int rc = load_keyframe(r, &r->pending);
    drop_pending(r);
    if (rc)
        return FTM_OK;
    rlog(r, FTM_LOG_INFO, "replay: synced from keyframe at tick %" PRIu64, k);
    r->state = FTM_WIRE_STATE_SYNCED;
    return apply_frames(r);
}

int ftm_replay_on_tick(ftm_replay *r, const ftm_wire_received *rx)
{
    const ftm_wire_tick *t = &rx->msg.u.tick;
    r->st.frames_received++;
    if (r->count == RING_CAP)
        ring_pop(r);
    frame *f = ring_at(r, r->count);
    memset(f, 0, sizeof *f);
    f->c = malloc(((size_t)t->contact_count + 1) * sizeof *f->c);
    f->react = malloc(((size_t)t->reaction_count + 1) * sizeof *f->react);
    if (!f->c || !f->react) {
        frame_free(f);
        return FTM_ENOMEM;
    }
    f->tick = t->tick;
    f->hash = t->state_hash;
    f->gap = rx->gap;
    f->depth = t->depth;
    f->n = t->contact_count;
    f->nreact = t->reaction_count;
    f->has_tissue = t->has_tissue;
    f->tissue = t->tissue;
    if (f->n)
        memcpy(f->c, t->contacts, (size_t)f->n * sizeof *f->c);
    if (f->nreact)
        memcpy(f->react, t->reactions, (size_t)f->nreact * sizeof *f->react);
    r->count++;
    if (!r->have_frames || rx->gap > 0)
        r->unbroken_since = t->tick;
    r->have_frames = true;
    if (r->state == FTM_WIRE_STATE_SYNCED)
        return apply_frames(r);
    return try_resync(r);
}

static int copy_keyframe(ftm_wire_keyframe *dst, const ftm_wire_keyframe *k)
{
    *dst = *k;
    size_t n = (size_t)k->count;
    dst->nodes = malloc((n + 1) * sizeof *dst->nodes);
    dst->positions = malloc((n + 1) * 3 * sizeof(double));
    dst->previous = malloc((n + 1) * 3 * sizeof(double));
    dst->contacts = malloc(((size_t)k->contact_count + 1) * sizeof *dst->contacts);
    if (!dst->nodes || !dst->positions || !dst->previous || !dst->contacts) {
        ftm_replay_keyframe_free(dst);
        return FTM_ENOMEM;
    }
    if (k->contact_count)
        memcpy(dst->contacts, k->contacts, (size_t)k->contact_count * sizeof *k->contacts);
    if (n) {
        memcpy(dst->nodes, k->nodes, n * sizeof *dst->nodes);
        memcpy(dst->positions, k->positions, n * 3 * sizeof(double));
        memcpy(dst->previous, k->previous, n * 3 * sizeof(double));
    }
    return FTM_OK;
}

int ftm_replay_on_keyframe(ftm_replay *r, const ftm_wire_keyframe *k)
{
    if (r->state == FTM_WIRE_STATE_SYNCED) {
        uint64_t cur = ftm_replay_tick(r);
        if (k->tick > cur) { /* frames up to it still to come: check it then */
            if (r->has_pending && r->pending.tick > k->tick)
                return FTM_OK;
            drop_pending(r);
            int rc = copy_keyframe(&r->pending, k);
            r->has_pending = rc == FTM_OK;
            return rc;
        }
        if (k->tick == cur) {
            if (k->state_hash != ftm_sim_hash(r->sim)) {
                rlog(r, FTM_LOG_INFO,
                     "replay: server state changed at tick %" PRIu64 " (reset): keyframe restored",
                     k->tick);
                if (load_keyframe(r, k))
                    enter_resync(r, "keyframe could not be restored");
            }
            return FTM_OK;
        }
        /* behind us: compare with the frame we applied at its tick */
        for (int32_t i = r->applied - 1; i >= 0; i--) {
            frame *f = ring_at(r, i);
            if (f->dropped)
                continue;
            if (f->tick < k->tick)
                break;
            if (f->tick == k->tick) {
                if (f->hash != k->state_hash) {
                    rlog(r, FTM_LOG_INFO,
                         "replay: server state changed at tick %" PRIu64
                         " (reset): keyframe restored, later frames applied again",
                         k->tick);
                    if (load_keyframe(r, k))
                        enter_resync(r, "keyframe could not be restored");
                    else
                        return apply_frames(r);
                }
                break;
            }
        }
        return FTM_OK;
    }
    if (r->has_pending && r->pending.tick >= k->tick)
        return try_resync(r);
    drop_pending(r);
    int rc = copy_keyframe(&r->pending, k);
    if (rc)
        return rc;
    r->has_pending = true;
    return try_resync(r);
}

ftm_wire_state ftm_replay_state(const ftm_replay *r) { return r->state; }

uint64_t ftm_replay_tick(const ftm_replay *r)
{
    ftm_sim_stats st;
    ftm_sim_get_stats(r->sim, &st);
    return st.step;
}

uint64_t ftm_replay_hash(const ftm_replay *r) { return ftm_sim_hash(r->sim); }

const ftm_wire_tick *ftm_replay_last_frame(const ftm_replay *r) { return &r->last; }

void ftm_replay_get_stats(const ftm_replay *r, ftm_replay_stats *stats) { *stats = r->st; }

double ftm_replay_take_max(ftm_replay *r)
{
    double m = r->st.replay_ns_max;
    r->st.replay_ns_max = 0.0;
    return m;
}

ftm_sim *ftm_replay_sim(ftm_replay *r) { return r->sim; }

ftm_wire_tissue ftm_replay_tissue(const ftm_replay *r) { return ftm_replay_tissue_now(&r->mat); }

ftm_id_claim ftm_replay_id_verdict(ftm_id_told *told, const ftm_wire_status *server_status,
                                   uint32_t own_id, uint64_t own_origin)
{
    const ftm_wire_status *st = server_status;
    if (st->role != FTM_WIRE_ROLE_SERVER)
        return FTM_ID_NOTHING;
    bool us = false, other = false;
    for (int32_t i = 0; i < st->ignored_count; i++) {
        if (st->ignored_participant[i] != own_id)
            continue;
        if (st->ignored_origin[i] == own_origin)
            us = true;
        else
            other = true;
    }
    if (us && !told->taken) {
        told->taken = true;
        return FTM_ID_TAKEN;
    }
    if (!us && told->taken) {
        told->taken = false;
        told->newcomer = false;
        return FTM_ID_OURS_AGAIN;
    }
    if (other && !us && !told->taken && !told->newcomer) {
        told->newcomer = true;
        return FTM_ID_NEWCOMER;
    }
    return FTM_ID_NOTHING;
}

/* ---- commands and replies (replay.h) ---------------------------------------------------- */

static void pending_drop(ftm_pending *p, int32_t i)
{
    memmove(&p->cmd[i], &p->cmd[i + 1], (size_t)(p->n - i - 1) * sizeof p->cmd[0]);
    p->n--;
}

static void unanswered_text(const ftm_pending_cmd *c, int64_t waited_ns, char *text, size_t cap)
{
    snprintf(text, cap, "%s: no reply from the server in %.0f s (not heard: lost, or no server)",
             c->what, (double)waited_ns * 1e-9);
}

bool ftm_pending_add(ftm_pending *p, uint64_t id, const char *what, int64_t now_ns, char *text,
                     size_t cap)
{
    bool gave_up = false;
    if (cap)
        text[0] = '\0';
    if (p->n == FTM_PENDING_MAX) {
        unanswered_text(&p->cmd[0], now_ns - p->cmd[0].sent_ns, text, cap);
        pending_drop(p, 0);
        gave_up = true;
    }
    ftm_pending_cmd *c = &p->cmd[p->n++];
    c->id = id;
    c->sent_ns = now_ns;
    snprintf(c->what, sizeof c->what, "%s", what);
    return gave_up;
}

void ftm_pending_forget(ftm_pending *p, uint64_t id)
{
    for (int32_t i = 0; i < p->n; i++)
        if (p->cmd[i].id == id) {
            pending_drop(p, i);
            return;
        }
}

bool ftm_pending_reply(ftm_pending *p, const ftm_wire_control_reply *r, char *text, size_t cap)
{
    char what[FTM_PENDING_WHAT + 32];
    int32_t i = 0;
    while (i < p->n && p->cmd[i].id != r->command_id)
        i++;
    bool known = i < p->n;
    if (known)
        snprintf(what, sizeof what, "%s", p->cmd[i].what);
    else
        snprintf(what, sizeof what, "command %" PRIu64, r->command_id);
    const char *sep = r->reason[0] ? ": " : "";
    switch (r->outcome) {
    case FTM_WIRE_OUTCOME_REFUSED: snprintf(text, cap, "%s: refused: %s", what, r->reason); break;
    case FTM_WIRE_OUTCOME_CHANGED:
    case FTM_WIRE_OUTCOME_APPLIED:
    default:
        snprintf(text, cap, "%s: %s after tick %" PRIu64 "%s%s", what,
                 ftm_wire_outcome_name(r->outcome), r->tick, sep, r->reason);
        break;
    }
    if (known)
        pending_drop(p, i);
    return known;
}

bool ftm_pending_expired(ftm_pending *p, int64_t now_ns, int64_t timeout_ns, char *text,
                         size_t cap)
{
    if (p->n == 0 || now_ns - p->cmd[0].sent_ns <= timeout_ns)
        return false; /* oldest first: none later is due either */
    unanswered_text(&p->cmd[0], now_ns - p->cmd[0].sent_ns, text, cap);
    pending_drop(p, 0);
    return true;
}

bool ftm_replay_id_held(const ftm_wire_status *server_status, uint32_t own_id,
                        uint64_t own_origin)
{
    const ftm_wire_status *st = server_status;
    if (st->role != FTM_WIRE_ROLE_SERVER)
        return false;
    for (int32_t i = 0; i < st->holder_count; i++)
        if (st->holder_participant[i] == own_id)
            return st->holder_origin[i] == own_origin; /* (each id at most once: the codec) */
    return false;
}

bool ftm_replay_from_server(uint32_t *id, uint64_t *origin, const ftm_wire_received *rx,
                            bool server_left)
{
    if (*id == 0 && rx->msg.kind == FTM_WIRE_ANNOUNCE) {
        *id = rx->sender;
        *origin = rx->origin;
    }
    if (*id == 0 || rx->sender != *id || !rx->origin)
        return false;
    if (rx->origin == *origin)
        return true;
    if (rx->msg.kind == FTM_WIRE_ANNOUNCE && server_left) {
        *origin = rx->origin; /* its successor */
        return true;
    }
    return false;
}
