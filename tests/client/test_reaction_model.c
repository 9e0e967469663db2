/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The server's local force model: the contact stiffness K = dF/dx of the
 * reaction force (ftm_sim_contact_stiffness) against finite differences of
 * the simulation's own reaction (Eq. 19), its passive projection, and the
 * new ProbeReaction fields (stiffness, hip) through the wire codec. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>

#include <cmocka.h>

#include "ftm/scene.h"
#include "ftm/v1/ftm.pb-c.h"
#include "ftm/wire.h"
#include "haptic_wire.h"
#include "replica.h"
#include "step.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A top-face triangle of the built-in default scene (12^3 lattice, 1 cm,
 * top face z = 0.11) near (0.035, 0.035): its three nodes. */
static void top_triangle(const ftm_mesh *m, int32_t v[3])
{
    const int32_t *t = ftm_mesh_triangles(m);
    double best = INFINITY;
    for (int32_t i = 0; i < ftm_mesh_triangle_count(m); i++) {
        ftm_vec3 c = {0, 0, 0};
        bool top = true;
        for (int q = 0; q < 3; q++) {
            ftm_vec3 p = ftm_mesh_rest_position(m, t[3 * i + q]);
            top = top && fabs(p.z - 0.11) < 1e-9;
            c.x += p.x / 3;
            c.y += p.y / 3;
        }
        double d = hypot(c.x - 0.035, c.y - 0.035);
        if (top && d < best) {
            best = d;
            memcpy(v, t + 3 * i, 3 * sizeof *v);
        }
    }
    assert_true(best < 0.01);
}

static void contacts_for(const int32_t v[3], ftm_vec3 pen, ftm_contact c[3])
{
    for (int q = 0; q < 3; q++)
        c[q] = (ftm_contact){v[q], 0, FTM_CONTACT_DISPLACEMENT, pen};
}

/* Reaction of group 0 after one step of depth 0 from rest: only the
 * contacts move, so the rest of the tissue is held, as K assumes. */
static ftm_vec3 held_reaction(ftm_sim *sim, const int32_t v[3], ftm_vec3 pen)
{
    ftm_contact c[3];
    contacts_for(v, pen, c);
    ftm_sim_reset(sim);
    assert_int_equal(ftm_sim_set_depth(sim, 0), FTM_OK);
    assert_int_equal(ftm_sim_set_contacts(sim, c, 3, NULL), FTM_OK);
    assert_int_equal(ftm_sim_step(sim), FTM_OK);
    return ftm_sim_reaction(sim, 0);
}

/* Eq. 19 written out independently: minus the spring forces on the
 * contact nodes, at positions x with the contacts shifted by d. */
static ftm_vec3 eq19(const ftm_mesh *m, const double *x0, const int32_t v[3], ftm_vec3 d)
{
    int32_t n = ftm_mesh_node_count(m);
    double *x = malloc((size_t)n * 3 * sizeof *x);
    memcpy(x, x0, (size_t)n * 3 * sizeof *x);
    for (int q = 0; q < 3; q++) {
        x[3 * v[q]] += d.x;
        x[3 * v[q] + 1] += d.y;
        x[3 * v[q] + 2] += d.z;
    }
    ftm_vec3 F = {0, 0, 0};
    for (int q = 0; q < 3; q++) {
        const int32_t *nb;
        const double *k, *l;
        int32_t deg = ftm_mesh_neighbors(m, v[q], &nb, &k, &l);
        const double *xi = x + 3 * v[q];
        for (int32_t e = 0; e < deg; e++) {
            const double *xj = x + 3 * nb[e];
            double r[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
            double len = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
            double s = k[e] * (len - l[e]) / len;
            F.x -= s * r[0];
            F.y -= s * r[1];
            F.z -= s * r[2];
        }
    }
    free(x);
    return F;
}

static double comp(ftm_vec3 a, int k) { return k == 0 ? a.x : k == 1 ? a.y : a.z; }

static void check_against(const double K[9], ftm_vec3 (*fd)(void *, ftm_vec3), void *u,
                          double h)
{
    double kmax = 0;
    for (int i = 0; i < 9; i++)
        kmax = fmax(kmax, fabs(K[i]));
    assert_true(kmax > 1.0);
    for (int col = 0; col < 3; col++) {
        ftm_vec3 e = {col == 0 ? h : 0, col == 1 ? h : 0, col == 2 ? h : 0};
        ftm_vec3 me = {-e.x, -e.y, -e.z};
        ftm_vec3 fp = fd(u, e), fm = fd(u, me);
        for (int row = 0; row < 3; row++) {
            double d = (comp(fp, row) - comp(fm, row)) / (2 * h);
            /* central differences: O(h^2) truncation, roundoff ~1e-16 |F| / h */
            assert_true(fabs(d - K[3 * row + col]) <= 1e-6 * kmax);
        }
    }
}

typedef struct rest_ctx {
    ftm_sim *sim;
    const int32_t *v;
    ftm_vec3 pen;
} rest_ctx;

static ftm_vec3 rest_fd(void *u, ftm_vec3 d)
{
    rest_ctx *c = u;
    return held_reaction(c->sim, c->v,
                         (ftm_vec3){c->pen.x + d.x, c->pen.y + d.y, c->pen.z + d.z});
}

typedef struct deformed_ctx {
    const ftm_mesh *m;
    const double *x;
    const int32_t *v;
} deformed_ctx;

static ftm_vec3 deformed_fd(void *u, ftm_vec3 d)
{
    deformed_ctx *c = u;
    return eq19(c->m, c->x, c->v, d);
}

static void test_stiffness_finite_differences(void **state)
{
    ftm_scene *scene = NULL;
    assert_int_equal(ftm_scene_builtin("default", &scene, NULL), FTM_OK);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    ftm_sim_def def = ftm_scene_sim_def(scene);
    /* K is the stiffness with the rest of the tissue held: depth 0 of the
     * paper's far field is exactly that (the elastic one moves the ring) */
    def.far_field = FTM_FAR_FIELD_FIXED;
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &sim, NULL), FTM_OK);
    int32_t v[3];
    top_triangle(m, v);

    /* 1. neighbours at rest, through the simulation's own reaction: a
     * press with a sideways drag (stretched and compressed springs) */
    rest_ctx rc = {sim, v, {0.0011, -0.0007, -0.004}};
    held_reaction(sim, v, rc.pen);
    double K[9];
    assert_int_equal(ftm_sim_contact_stiffness(sim, 0, K), 3);
    check_against(K, rest_fd, &rc, 1e-6);
    /* restoring along the press: pushing further in raises the upward force */
    assert_true(K[8] < 0);
    /* no such group: zero */
    double Z[9];
    assert_int_equal(ftm_sim_contact_stiffness(sim, 5, Z), 0);
    for (int i = 0; i < 9; i++)
        assert_true(Z[i] == 0.0);

    /* 2. a deformed state (the tissue around has followed for 300 steps at
     * depth 10), against Eq. 19 evaluated independently */
    ftm_sim_reset(sim);
    assert_int_equal(ftm_sim_set_depth(sim, 10), FTM_OK);
    ftm_contact c[3];
    contacts_for(v, rc.pen, c);
    assert_int_equal(ftm_sim_set_contacts(sim, c, 3, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, 300), FTM_OK);
    const double *x = ftm_sim_positions(sim);
    ftm_vec3 F = ftm_sim_reaction(sim, 0), G = eq19(m, x, v, (ftm_vec3){0, 0, 0});
    assert_true(fabs(F.x - G.x) + fabs(F.y - G.y) + fabs(F.z - G.z) < 1e-12 * (1 + fabs(F.z)));
    assert_true(F.z > 0.1); /* pushes the probe back out */
    assert_int_equal(ftm_sim_contact_stiffness(sim, 0, K), 3);
    deformed_ctx dc = {m, x, v};
    check_against(K, deformed_fd, &dc, 1e-7);

    /* the secant scale: below 1 once the layers have followed (the force is
     * softer than the held stiffness predicts), and then K pen = F along pen */
    double S[9];
    memcpy(S, K, sizeof S);
    ftm_stiffness_make_passive(S);
    double alpha = ftm_stiffness_secant_scale(S, F, rc.pen);
    assert_true(alpha > 0.05 && alpha < 0.95);
    double pSp = 0;
    const double p[3] = {rc.pen.x, rc.pen.y, rc.pen.z};
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            pSp += p[a] * S[3 * a + b] * p[b];
    assert_true(fabs(pSp - (F.x * p[0] + F.y * p[1] + F.z * p[2])) < 1e-9 * fabs(pSp));

    /* held: the first tick of a press from rest, where F = K_held pen when the
     * springs are linear enough, so alpha is close to 1 (and never above) */
    ftm_vec3 Fh = held_reaction(sim, v, rc.pen);
    double Kh[9];
    ftm_sim_contact_stiffness(sim, 0, Kh);
    assert_true(F.z < Fh.z); /* the tissue that followed pushes back less */
    ftm_stiffness_make_passive(Kh);
    double ah = ftm_stiffness_secant_scale(Kh, Fh, rc.pen);
    assert_true(ah > 0.7 && ah <= 1.0);
    /* no penetration: unchanged */
    double U[9] = {-1, 0, 0, 0, -1, 0, 0, 0, -1};
    assert_true(ftm_stiffness_secant_scale(U, (ftm_vec3){0, 0, 1}, (ftm_vec3){0, 0, 0}) == 1.0);
    assert_true(U[0] == -1 && U[8] == -1);
    /* a force pulling along the penetration: alpha 0, no model */
    assert_true(ftm_stiffness_secant_scale(U, (ftm_vec3){0, 0, -1}, (ftm_vec3){0, 0, -0.001}) ==
                0.0);
    assert_true(U[8] == 0.0);

    ftm_sim_destroy(sim);
    ftm_scene_destroy(scene);
}

static void test_make_passive(void **state)
{
    /* already passive (symmetric, negative definite): unchanged */
    double A[9] = {-300, 20, 0, 20, -100, 10, 0, 10, -50};
    double B[9];
    memcpy(B, A, sizeof A);
    ftm_stiffness_make_passive(B);
    for (int i = 0; i < 9; i++)
        assert_true(fabs(A[i] - B[i]) < 1e-9 * 300);
    /* an indefinite one (a compressed spring's transverse term): the part
     * along the growing direction goes, the rest stays */
    double C[9] = {40, 0, 0, 0, -100, 0, 0, 0, -200};
    ftm_stiffness_make_passive(C);
    assert_true(fabs(C[0]) < 1e-12 && fabs(C[4] + 100) < 1e-12 && fabs(C[8] + 200) < 1e-12);
    /* a rotated indefinite one: v^T K v <= 0 for every v afterwards, and
     * the non-symmetric part is gone */
    double D[9] = {10, 35, -3, 5, -80, 7, 2, 9, -20};
    ftm_stiffness_make_passive(D);
    for (int r = 0; r < 3; r++)
        for (int cc = 0; cc < 3; cc++)
            assert_true(fabs(D[3 * r + cc] - D[3 * cc + r]) < 1e-12);
    srand(7);
    for (int k = 0; k < 1000; k++) {
        double u[3] = {rand() / (double)RAND_MAX - 0.5, rand() / (double)RAND_MAX - 0.5,
                       rand() / (double)RAND_MAX - 0.5};
        double q = 0;
        for (int r = 0; r < 3; r++)
            for (int cc = 0; cc < 3; cc++)
                q += u[r] * D[3 * r + cc] * u[cc];
        assert_true(q <= 1e-10);
    }
}

static void test_wire_reaction_model(void **state)
{
    ftm_wire_reaction re[2];
    memset(re, 0, sizeof re);
    re[0] = (ftm_wire_reaction){.group = 0, .participant = 11, .probe = 0, .force = {0, 0, 1.25}};
    re[0].has_model = true;
    re[0].hip = (ftm_vec3){0.035, 0.035, 0.106};
    re[0].has_plane = true;
    re[0].contact_point = (ftm_vec3){0.035, 0.035, 0.11};
    re[0].contact_normal = (ftm_vec3){0.6, 0, 0.8};
    for (int i = 0; i < 9; i++)
        re[0].stiffness[i] = -100.0 * (i + 1) / 3.0; /* not exact in binary: bit-exact check */
    re[1] = (ftm_wire_reaction){.group = 4, .participant = 12, .probe = 0, .force = {0.5, 0, 0}};
    ftm_wire_msg msg;
    memset(&msg, 0, sizeof msg);
    msg.kind = FTM_WIRE_TICK;
    msg.u.tick.tick = 9;
    msg.u.tick.depth = 10;
    msg.u.tick.reaction_count = 2;
    msg.u.tick.reactions = re;
    uint8_t *buf = NULL;
    size_t n = 0;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_wire_encode(&msg, &buf, &n, &err), FTM_OK);
    ftm_wire_msg out;
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, buf, n, NULL, &out, &err), FTM_OK);
    free(buf);
    ftm_wire_reaction got;
    assert_true(ftm_replay_find_reaction(&out.u.tick, 11, 0, &got));
    assert_true(got.has_model);
    assert_memory_equal(&got.hip, &re[0].hip, sizeof got.hip);
    assert_memory_equal(got.stiffness, re[0].stiffness, sizeof got.stiffness);
    assert_true(got.has_plane);
    assert_memory_equal(&got.contact_point, &re[0].contact_point, sizeof got.contact_point);
    assert_memory_equal(&got.contact_normal, &re[0].contact_normal, sizeof got.contact_normal);
    /* into the haptic loop: the force model evaluates at the server's HIP
     * to the server's force, and follows K away from it */
    ftm_wire_reaction m0 = got;
    ftm_haptic_sample hs = ftm_haptic_sample_from_reaction(&m0, 3.0, (ftm_vec3){1, 1, 1});
    assert_true(hs.time == 3.0 && hs.has_stiffness && hs.has_plane);
    assert_memory_equal(&hs.hip, &re[0].hip, sizeof hs.hip);
    ftm_force_renderer fr;
    ftm_haptic_def hd = ftm_default_haptic_def();
    ftm_force_renderer_init(&fr, &hd);
    assert_int_equal(ftm_force_renderer_push(&fr, &hs, 3.0), FTM_OK);
    ftm_vec3 at = ftm_force_renderer_model(&fr, 3.0, re[0].hip);
    assert_memory_equal(&at, &re[0].force, sizeof at);
    ftm_vec3 moved = {re[0].hip.x, re[0].hip.y, re[0].hip.z - 0.001};
    at = ftm_force_renderer_model(&fr, 3.0, moved);
    assert_true(fabs(at.z - (re[0].force.z - 0.001 * re[0].stiffness[8])) < 1e-12);
    hs = ftm_haptic_sample_from_reaction(NULL, 4.0, (ftm_vec3){1, 2, 3});
    assert_true(hs.force.x == 0 && hs.force.z == 0 && hs.hip.y == 2 && !hs.has_stiffness);

    assert_true(ftm_replay_find_reaction(&out.u.tick, 12, 0, &got));
    assert_false(got.has_model);
    assert_false(got.has_plane);
    assert_true(got.force.x == 0.5);
    assert_false(ftm_replay_find_reaction(&out.u.tick, 13, 0, &got));
    ftm_wire_msg_free(&out);

    /* the encoder refuses what the decoder would */
    re[0].stiffness[4] = NAN;
    assert_int_equal(ftm_wire_encode(&msg, &buf, &n, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "reactions[0].stiffness[4]"));
    re[0].stiffness[4] = 1;
    re[0].contact_normal = (ftm_vec3){0, 0, 2};
    assert_int_equal(ftm_wire_encode(&msg, &buf, &n, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "reactions[0].contact_normal has length 2 (must be 1)"));
    re[0].contact_normal = (ftm_vec3){0, 0, 1};

    /* malformed payloads crafted with the generated structs */
    Ftm__V1__TickFrame tf = FTM__V1__TICK_FRAME__INIT;
    tf.has_version = tf.has_tick = tf.has_depth = tf.has_state_hash = 1;
    tf.version = 1;
    Ftm__V1__Vec3 f = FTM__V1__VEC3__INIT, h = FTM__V1__VEC3__INIT;
    f.has_x = f.has_y = f.has_z = 1;
    h.has_x = h.has_y = 1; /* no z */
    Ftm__V1__ProbeReaction r = FTM__V1__PROBE_REACTION__INIT;
    r.has_group = r.has_participant_id = r.has_probe = 1;
    r.force = &f;
    double k[9] = {0};
    r.n_stiffness = 5;
    r.stiffness = k;
    Ftm__V1__ProbeReaction *rp = &r;
    tf.n_reactions = 1;
    tf.reactions = &rp;
    uint8_t pb[512];
    size_t len = protobuf_c_message_pack(&tf.base, pb);
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, pb, len, NULL, &out, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "reactions[0].stiffness has 5 values (0 or 9)"));
    r.n_stiffness = 9;
    len = protobuf_c_message_pack(&tf.base, pb);
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, pb, len, NULL, &out, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "stiffness and hip must come together"));
    r.hip = &h;
    len = protobuf_c_message_pack(&tf.base, pb);
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, pb, len, NULL, &out, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "missing field reactions[0].hip.z"));
    h.has_z = 1;
    len = protobuf_c_message_pack(&tf.base, pb);
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, pb, len, NULL, &out, &err), FTM_OK);
    assert_true(out.u.tick.reactions[0].has_model);
    ftm_wire_msg_free(&out);
    r.contact_point = &f; /* a point without a normal */
    len = protobuf_c_message_pack(&tf.base, pb);
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, pb, len, NULL, &out, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "contact_point and contact_normal must come together"));
    r.contact_point = NULL;
    /* an old sender (no model fields) still decodes: force alone */
    r.n_stiffness = 0;
    r.hip = NULL;
    len = protobuf_c_message_pack(&tf.base, pb);
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, pb, len, NULL, &out, &err), FTM_OK);
    assert_false(out.u.tick.reactions[0].has_model);
    ftm_wire_msg_free(&out);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stiffness_finite_differences),
        cmocka_unit_test(test_make_passive),
        cmocka_unit_test(test_wire_reaction_model),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
