/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The server's side of a session under hostile or broken peers: the message
 * handlers (status, probe input, session control, gone and lost events), the
 * probe collision and the tick logic of ftm-server, which no other target
 * reaches. The input is turned into a sequence of well-formed messages
 * (what the decoder passes on: fuzz_wire covers the decoder), each from one
 * of six senders at a tick, written as a recording's inputs; then
 *
 *   ftm-server --inputs IN --record OUT   runs them through the handlers and
 *                                         records the frames it publishes;
 *   ftm-server --replay OUT               applies those frames as a replica
 *                                         does and re-runs the inputs
 *
 * (each a server of its own from an ftm_server_def, server.h).
 *
 * Properties: the server takes every input without a crash or a hang, and
 * whatever the peers sent, its frames bring a replica to its exact state at
 * every frame and keyframe (the hashes), its inputs reproduce its frames,
 * and the session report (--report) of the run and of the replay are the
 * same bytes. A small lattice (5x5x5) keeps a run to milliseconds.
 *
 * Input: a byte choosing the push limit (0xff: none; else bit 0: 5 mm or
 * the scene's 4 cm), then
 * records of a selector byte (low 3 bits: the kind, see make(), 3 a gone
 * and 4 a lost event; high bit: a longer wait), a wait in ticks, a sender
 * and the kind's fields, each read as bytes; the input running out reads
 * zeros. */
#include "fuzz.h"

#include "record.h"
#include "digest.h"
#include "server.h"

#include "ftm/scene.h"
#include "ftm/wire.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static bool same_file(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    bool same = fa && fb;
    if (same) {
        int ca, cb;
        do {
            ca = getc(fa);
            cb = getc(fb);
        } while (ca == cb && ca != EOF);
        same = ca == cb;
    }
    if (fa)
        fclose(fa);
    if (fb)
        fclose(fb);
    return same;
}

static const char scene_text[] =
    "[scene]\nname = fuzz-session\n"
    "[mesh]\ngenerator = lattice3d\nnx = 5\nny = 5\nnz = 5\nspacing = 0.01\nstencil = 18\n"
    "fixed_faces = zmin\n"
    "[material]\nmass = 0.001\ndamping = 0.3\nstiffness = 50\n"
    "[sim]\ntime_step = 1e-3\ndepth = 4\n";

#define MAX_ENTRIES 192
#define MAX_TICKS 1200 /* per input: ticks are the cost (three runs of each) */

typedef struct bytes {
    const uint8_t *p;
    size_t n, at;
} bytes;

static unsigned u8(bytes *b) { return b->at < b->n ? b->p[b->at++] : 0u; }

/* A coordinate around the 4 cm cube: mostly near it, sometimes far away or
 * enormous (still finite: the encoder refuses what the decoder would). */
static double coord(bytes *b)
{
    unsigned m = u8(b);
    double v = -0.01 + 0.06 * (double)u8(b) / 255.0;
    if (m == 0xff)
        return 1e300;
    if (m == 0xfe)
        return -1e3;
    return (m & 0xf0) == 0xf0 ? v * 100.0 : v;
}

static double pick(bytes *b, const double *table, unsigned n) { return table[u8(b) % n]; }

/* The message of a kind (0, 5: status, 5 a synced trainee's; 1, 6, 7: probe
 * input; 2: session control) from the input into m. */
static void make(bytes *b, unsigned kind, uint32_t sender, uint64_t tick, ftm_wire_msg *m,
                 ftm_wire_probe_sample *samples)
{
    static const double mass[] = {0.001, 0.002, 1e-9, 1e3, 0.0, -1.0};
    static const double damping[] = {0.3, 0.0, 3.0, 1e6, -0.1};
    static const double stiffness[] = {50.0, 100.0, 1e-6, 1e7, 0.0};
    static const double scale[] = {1.0, 2.0, 0.5, 1e-4, 0.0};
    memset(m, 0, sizeof *m);
    unsigned other = u8(b);
    uint32_t who = (other & 7) == 7 ? 1 + other % 8 : sender; /* sometimes not the sender */
    switch (kind) {
    case 0: /* status */
    case 5: {
        m->kind = FTM_WIRE_STATUS;
        ftm_wire_status *st = &m->u.status;
        st->participant = who;
        st->role = (ftm_wire_role)(kind == 5 ? FTM_WIRE_ROLE_TRAINEE : 1 + u8(b) % 5);
        st->state = (ftm_wire_state)(kind == 5 ? FTM_WIRE_STATE_SYNCED : 1 + u8(b) % 4);
        unsigned back = u8(b);
        st->last_applied_tick = tick > back ? tick - back : 0;
        st->state_hash = u8(b);
        st->replay_ns_per_tick = 20000.0;
        snprintf(st->name, sizeof st->name, "fuzz %u", (unsigned)sender);
        break;
    }
    case 1: /* probe input */
    case 6:
    case 7: {
        m->kind = FTM_WIRE_PROBE_INPUT;
        ftm_wire_probe_input *in = &m->u.probe_input;
        in->participant = who;
        unsigned back = u8(b);
        in->last_tick_seen = tick > back ? tick - back : 0;
        in->sample_count = 1 + (int32_t)(u8(b) % 4);
        for (int32_t i = 0; i < in->sample_count; i++) {
            unsigned pr = u8(b);
            samples[i].probe = pr == 0xff ? -1 : (int32_t)(pr % 5); /* 4: out of range */
            samples[i].device_time_ns = tick * 1000000u;
            samples[i].position = (ftm_vec3){coord(b), coord(b), coord(b)};
        }
        in->samples = samples;
        break;
    }
    case 2: { /* session control */
        m->kind = FTM_WIRE_CONTROL;
        ftm_wire_control *c = &m->u.control;
        c->issuer = who;
        c->command_id = tick;
        c->command = (ftm_wire_command)(1 + u8(b) % 6); /* 6: unknown, the encoder refuses */
        c->tissue = (ftm_wire_tissue){pick(b, mass, 6), pick(b, damping, 5), pick(b, stiffness, 5),
                                      {pick(b, scale, 5), pick(b, scale, 5), pick(b, scale, 5)}};
        c->depth_min = (int32_t)(u8(b) % 10) - 1;
        c->depth_max = (int32_t)(u8(b) % 10) - 1;
        break;
    }
    default:
        break;
    }
}

static const char *scene_path;
static ftm_record_header header;

static void init(void)
{
    scene_path = strdup(fuzz_write_file("session.scene", scene_text, sizeof scene_text - 1));
    ftm_scene *scene = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (!scene_path || ftm_scene_open(scene_path, &scene, &err) != FTM_OK)
        fuzz_fail(__FILE__, __LINE__, err.message);
    snprintf(header.scene_id, sizeof header.scene_id, "%s", scene_path);
    ftm_replay_scene_digest(scene, header.digest);
    header.digest_len = FTM_REPLAY_DIGEST_SIZE;
    header.tick_rate_hz = 1000;
    header.depth_max = header.depth_min = 4;
    header.node_count = ftm_mesh_node_count(ftm_scene_mesh(scene));
    ftm_scene_destroy(scene);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!scene_path)
        init();
    ftm_error err;
    memset(&err, 0, sizeof err);
    bytes b = {data, size, 0};
    /* the push limit: the scene's size (the server's default), 5 mm, or none
     * (a recording made before there was one: slow, huge pushes diverge) */
    unsigned lim = u8(&b);
    header.max_penetration = lim == 0xff ? 0.0 : (lim & 1) ? 0.005 : 0.04;
    char in_path[512], out_path[512];
    snprintf(in_path, sizeof in_path, "%s", fuzz_write_file("in.rec", "", 0));
    snprintf(out_path, sizeof out_path, "%s", fuzz_write_file("out.rec", "", 0));
    ftm_record_writer *w = NULL;
    fuzz_check(ftm_record_create(in_path, &header, &w, &err) == FTM_OK);
    uint64_t tick = 0;
    int entries = 0;
    while (b.at < b.n && entries < MAX_ENTRIES) {
        unsigned sel = u8(&b);
        unsigned wait = u8(&b) % 16;
        if (sel & 0x80)
            wait += 2u * u8(&b);
        if (tick + wait > MAX_TICKS)
            break;
        tick += wait;
        uint32_t sender = 2 + u8(&b) % 6; /* the server is 1 */
        unsigned kind = sel & 7;
        ftm_record_entry e = {.tick = tick, .kind = FTM_WIRE_STATUS, .sender = sender,
                              .incoming = true};
        uint8_t *buf = NULL;
        if (kind == 3)
            e.gone = true;
        else if (kind == 4)
            e.lost = true;
        else {
            ftm_wire_msg m;
            ftm_wire_probe_sample samples[4];
            make(&b, kind, sender, tick, &m, samples);
            if (ftm_wire_encode(&m, &buf, &e.size, &err) != FTM_OK)
                continue; /* a value the decoder would refuse: not passed on */
            e.kind = (int)m.kind;
            e.payload = buf;
        }
        fuzz_check(ftm_record_write(w, &e, &err) == FTM_OK);
        free(buf);
        entries++;
    }
    /* a last event a tick later, so that there is a tick frame to check */
    ftm_record_entry last = {.tick = tick + 1, .kind = FTM_WIRE_STATUS, .sender = 2,
                             .incoming = true, .gone = true};
    fuzz_check(ftm_record_write(w, &last, &err) == FTM_OK);
    fuzz_check(ftm_record_close(w, &err) == FTM_OK);

    char rep_run[512], rep_check[512];
    snprintf(rep_run, sizeof rep_run, "%s", fuzz_write_file("run.json", "", 0));
    snprintf(rep_check, sizeof rep_check, "%s", fuzz_write_file("check.json", "", 0));
    /* ftm-server --inputs IN --record OUT --scene S --report R, then
     * ftm-server --replay OUT --scene S --report R2: two servers from
     * definitions of their own, in one process */
    ftm_server_def run = ftm_default_server_def();
    run.inputs = in_path;
    run.record = out_path;
    run.scene = scene_path;
    run.report = rep_run;
    fuzz_check(ftm_server_run(&run) == 0);
    ftm_server_def check = ftm_default_server_def();
    check.replay = out_path;
    check.scene = scene_path;
    check.report = rep_check;
    fuzz_check(ftm_server_run(&check) == 0);
    /* the session report of the run and of its replay: the same bytes */
    fuzz_check(same_file(rep_run, rep_check));
    return 0;
}
