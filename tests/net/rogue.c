/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-rogue: a hostile participant for the session tests (tests/net,
 * mode rogue). It joins a running session and sends, one after the other,
 * every kind of bad input the protocol must survive: garbage bytes, a
 * well-formed envelope whose payload does not decode (truncated, NaN), an
 * oversized payload, a payload of huge repeated counts, a message of the
 * wrong kind on a topic, and well-formed messages that its role forbids or
 * that forge another participant's id. Each step is printed on stdout as
 * `rogue: STEP` so the test can match it with the server's logged reason.
 *
 * With --forge it is instead a forger of the server (tests/net/net_forge.sh):
 * server statuses and control replies of its own making, see forge(). With
 * --impersonate it is a certified participant of a secured session that
 * writes, in its own name, messages naming another participant or the
 * server's role (tests/net/net_secure.sh), see impersonate(). With
 * --elevated it is a certified trainee that signed itself a server's or an
 * instructor's permissions and hands them to Cyclone past ftm_wire's check
 * (tests/net/net_secure.sh), see elevated().
 *
 * The wrong-kind envelope needs a raw DDS writer (ftm_wire always writes a
 * kind on its own topic); everything else goes through ftm_wire, raw
 * payloads with ftm_wire_publish_raw. */
#include "ftm/clock.h"
#include "ftm/wire.h"

#include "ftm_envelope.h"

#include <dds/dds.h>

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct buf {
    uint8_t *p;
    size_t n, cap;
} buf;

static void put(buf *b, const void *d, size_t n)
{
    if (b->n + n > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->n + n)
            cap *= 2;
        uint8_t *q = realloc(b->p, cap);
        if (!q) {
            fprintf(stderr, "rogue: out of memory\n");
            exit(3);
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->n, d, n);
    b->n += n;
}

static void varint(buf *b, uint64_t v)
{
    uint8_t c[10];
    size_t n = 0;
    do {
        c[n++] = (uint8_t)((v & 0x7f) | (v > 0x7f ? 0x80 : 0));
        v >>= 7;
    } while (v);
    put(b, c, n);
}

static void key(buf *b, uint32_t field, uint32_t wire) { varint(b, (uint64_t)field << 3 | wire); }

static void f64(buf *b, uint32_t field, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    key(b, field, 1);
    uint8_t c[8];
    for (int i = 0; i < 8; i++)
        c[i] = (uint8_t)(u >> (8 * i));
    put(b, c, 8);
}

/* A ProbeInput (proto/ftm.proto) with one sample, encoded by hand so that
 * it can carry what the encoder refuses (a NaN coordinate). */
static void probe_input_bytes(buf *b, uint32_t participant, double x, double y, double z)
{
    buf vec = {0}, smp = {0};
    f64(&vec, 1, x);
    f64(&vec, 2, y);
    f64(&vec, 3, z);
    key(&smp, 1, 0);
    varint(&smp, 0);
    key(&smp, 2, 0);
    varint(&smp, 12345);
    key(&smp, 3, 2);
    varint(&smp, vec.n);
    put(&smp, vec.p, vec.n);
    key(b, 1, 0);
    varint(b, FTM_WIRE_VERSION);
    key(b, 2, 0);
    varint(b, participant);
    key(b, 3, 0);
    varint(b, 0);
    key(b, 4, 2);
    varint(b, smp.n);
    put(b, smp.p, smp.n);
    free(vec.p);
    free(smp.p);
}

static void pause_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static int fails;

static void step(const char *what, int rc, const ftm_error *err)
{
    if (rc) {
        fprintf(stderr, "rogue: %s: could not send: %s\n", what, err->message);
        fails++;
    }
    printf("rogue: %s\n", what);
    fflush(stdout);
    pause_ms(60); /* one step per server drain, easy to read in the log */
}

static int raw(ftm_wire_transport *t, int kind, const void *p, size_t n, const char *what)
{
    ftm_error err = {0, ""};
    int rc = ftm_wire_publish_raw(t, kind, p, n, &err);
    step(what, rc, &err);
    return rc;
}

static void msg(ftm_wire_transport *t, const ftm_wire_msg *m, const char *what)
{
    ftm_error err = {0, ""};
    step(what, ftm_wire_publish(t, m, &err), &err);
}

static void status(ftm_wire_transport *t, uint32_t id, uint32_t named, ftm_wire_role role,
                   ftm_wire_state state)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    m.u.status.participant = named ? named : id;
    m.u.status.role = role;
    m.u.status.state = state;
    snprintf(m.u.status.name, sizeof m.u.status.name, "rogue");
    ftm_error err = {0, ""};
    if (ftm_wire_publish(t, &m, &err))
        fprintf(stderr, "rogue: status: %s\n", err.message);
}

/* --security DIR: the identity every transport of this process uses (a
 * rogue with a certificate of another room); NULL: unsecured. */
static const char *g_security;
/* --cyclone FILE: a Cyclone DDS <Security> configuration of the rogue's own
 * making, which this process's domain gets instead of the one ftm_wire
 * makes from g_security after checking it (see elevated()). */
static const char *g_cyclone;

/* A participant of the session under id that publishes and subscribes to
 * the kinds given (bit masks); exits 3 if DDS will not have it. */
static ftm_wire_transport *transport(const char *config, uint32_t domain, const char *session,
                                     uint32_t id, uint32_t publish, uint32_t subscribe)
{
    ftm_wire_transport_def d;
    memset(&d, 0, sizeof d);
    d.config = config;
    d.security = g_security;
    d.domain_id = domain;
    d.session = session;
    d.participant_id = id;
    d.publish = publish;
    d.subscribe = subscribe;
    ftm_wire_transport *t = NULL;
    ftm_error err = {0, ""};
    if (g_cyclone) {
        /* the domain made first, with the rogue's own security settings: the
         * transport then finds it made and shares it (ftm_wire's make_domain) */
        char uri[4200];
        snprintf(uri, sizeof uri, "%s%s,file://%s", config ? "file://" : "", config ? config : "",
                 g_cyclone);
        const dds_entity_t dom = dds_create_domain(domain, uri);
        if (dom < 0 && dom != DDS_RETCODE_PRECONDITION_NOT_MET) {
            fprintf(stderr, "rogue: dds_create_domain with %s: %s\n", g_cyclone,
                    dds_strretcode(dom));
            exit(3);
        }
    }
    if (ftm_wire_transport_create(&d, &t, &err)) {
        fprintf(stderr, "rogue: %s\n", err.message);
        exit(3);
    }
    return t;
}

static ftm_wire_transport *join(const char *config, uint32_t domain, const char *session,
                                uint32_t id, ftm_wire_role role)
{
    ftm_wire_transport *t =
        transport(config, domain, session, id,
                  FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) | FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT) |
                      FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL) | FTM_WIRE_KIND_BIT(FTM_WIRE_TICK) |
                      FTM_WIRE_KIND_BIT(FTM_WIRE_KEYFRAME),
                  FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE));
    ftm_error err = {0, ""};
    /* the server's readers must see us before anything is sent */
    if (ftm_wire_wait_matched(t, FTM_WIRE_PROBE_INPUT, 1, 5000000000LL, &err) ||
        ftm_wire_wait_matched(t, FTM_WIRE_CONTROL, 1, 5000000000LL, &err)) {
        fprintf(stderr, "rogue: %s\n", err.message);
        exit(3);
    }
    status(t, id, 0, role, FTM_WIRE_STATE_SYNCED);
    pause_ms(300); /* the server learns our role */
    return t;
}

/* The wrong kind on a topic: an envelope saying "session control" written
 * on the probe input topic, through a DDS writer of our own. */
static void wrong_kind(uint32_t domain, const char *session, uint32_t id)
{
    dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
    dds_entity_t tp = pp > 0 ? dds_create_topic(pp, &ftm_wire_Envelope_desc,
                                                ftm_wire_topic_name(FTM_WIRE_PROBE_INPUT), NULL, NULL)
                             : pp;
    dds_entity_t wr = tp > 0 ? dds_create_writer(pp, tp, NULL, NULL) : tp;
    if (wr < 0) {
        fprintf(stderr, "rogue: raw DDS writer: %s\n", dds_strretcode(wr));
        fails++;
        if (pp > 0)
            dds_delete(pp);
        return;
    }
    for (int i = 0; i < 100; i++) { /* wait for the server's reader */
        dds_publication_matched_status_t ms;
        if (dds_get_publication_matched_status(wr, &ms) == 0 && ms.current_count > 0)
            break;
        pause_ms(20);
    }
    /* the server's best-effort reader drops samples of a writer it has not
     * discovered yet: give discovery the other way round time too */
    pause_ms(500);
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL;
    m.u.control.issuer = id;
    m.u.control.command_id = 1;
    m.u.control.command = FTM_WIRE_CMD_RESET;
    uint8_t *payload = NULL;
    size_t size = 0;
    ftm_error err = {0, ""};
    if (ftm_wire_encode(&m, &payload, &size, &err)) {
        fprintf(stderr, "rogue: %s\n", err.message);
        exit(3);
    }
    ftm_wire_Envelope env;
    memset(&env, 0, sizeof env);
    snprintf(env.session, sizeof env.session, "%s", session);
    env.sender = id;
    env.kind = FTM_WIRE_CONTROL;
    env.seq = 1;
    env.payload._length = env.payload._maximum = (uint32_t)size;
    env.payload._buffer = payload;
    env.payload._release = false;
    dds_return_t rc = dds_write(wr, &env);
    if (rc < 0) {
        fprintf(stderr, "rogue: dds_write: %s\n", dds_strretcode(rc));
        fails++;
    }
    printf("rogue: wrong kind on the probe input topic\n");
    fflush(stdout);
    pause_ms(200); /* best effort: let it go out before the writer is deleted */
    free(payload);
    dds_delete(pp);
}

/* --forge: a process that passes itself off as the server. Two DDS
 * participants, one under the server's id (a copied --id) and one under
 * id + 92 (nobody's), both claiming role SERVER, for `seconds`:
 * - for every process heard under participant `taken` (the holder and the
 *   one the server ignores), a server status listing that process as the
 *   holder of the id: the ignored one must not believe it may press;
 * - a server status listing `innocent`'s process as ignored: it must not
 *   believe its id is taken;
 * - for every SessionControl heard, an APPLIED ControlReply at once
 *   (before the server's own): the issuer must not count it.
 * Each kind is printed once on stdout (`rogue: forged ...`). */
#define FORGE_ORIGINS 4
#define FORGE_HEARD 64
static ftm_wire_transport *forger(const char *config, uint32_t domain, const char *session,
                                  uint32_t id)
{
    return transport(config, domain, session, id,
                     FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) | FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL_REPLY),
                     FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) | FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL));
}

static int forge(const char *config, uint32_t domain, const char *session, uint32_t server_id,
                 uint32_t taken, uint32_t innocent, double seconds)
{
    ftm_wire_transport *t[2] = {forger(config, domain, session, server_id),
                                forger(config, domain, session, server_id + 92)};
    uint64_t taken_origin[FORGE_ORIGINS] = {0}, innocent_origin = 0;
    int ntaken = 0;
    bool told_holder = false, told_ignored = false, told_reply = false;
    uint64_t replies = 0, statuses = 0, heard_status = 0, heard_control = 0;
    uint32_t heard[FORGE_HEARD];
    int nheard = 0;
    const int64_t end = ftm_clock_mono_ns() + (int64_t)(seconds * 1e9);
    int64_t next_status = 0;
    ftm_wire_msg m;
    ftm_error err = {0, ""};
    while (ftm_clock_mono_ns() < end) {
        ftm_wire_received rx;
        /* whose processes there are: what the statuses' origins say */
        while (ftm_wire_receive(t[0], FTM_WIRE_STATUS, &rx, 0, NULL) == FTM_OK) {
            heard_status++;
            /* who can be heard: one line per sender (net_secure.sh) */
            bool seen = false;
            for (int i = 0; i < nheard; i++)
                seen |= heard[i] == rx.sender;
            if (!seen && nheard < FORGE_HEARD) {
                heard[nheard++] = rx.sender;
                printf("rogue: heard participant %u\n", rx.sender);
                fflush(stdout);
            }
            if (!rx.gone && rx.origin && rx.msg.u.status.role == FTM_WIRE_ROLE_TRAINEE) {
                if (rx.sender == innocent)
                    innocent_origin = rx.origin;
                bool known = false;
                for (int i = 0; i < ntaken; i++)
                    known |= taken_origin[i] == rx.origin;
                if (rx.sender == taken && !known && ntaken < FORGE_ORIGINS)
                    taken_origin[ntaken++] = rx.origin;
            }
            ftm_wire_received_free(&rx);
        }
        /* answer every command first, "applied", from both identities */
        while (ftm_wire_receive(t[0], FTM_WIRE_CONTROL, &rx, 1000000, NULL) == FTM_OK) {
            heard_control++;
            memset(&m, 0, sizeof m);
            m.kind = FTM_WIRE_CONTROL_REPLY;
            m.u.control_reply.issuer = rx.msg.u.control.issuer;
            m.u.control_reply.command_id = rx.msg.u.control.command_id;
            m.u.control_reply.outcome = FTM_WIRE_OUTCOME_APPLIED;
            m.u.control_reply.tick = 1;
            for (int k = 0; k < 2; k++)
                if (ftm_wire_publish(t[k], &m, &err))
                    fprintf(stderr, "rogue: control reply: %s\n", err.message);
            replies++;
            if (!told_reply) {
                printf("rogue: forged an applied control reply (participant %u, command %" PRIu64
                       ")\n", m.u.control_reply.issuer, m.u.control_reply.command_id);
                fflush(stdout);
                told_reply = true;
            }
            ftm_wire_received_free(&rx);
        }
        if (ftm_clock_mono_ns() < next_status)
            continue;
        next_status = ftm_clock_mono_ns() + 20000000; /* 50 Hz: between any two of the server's */
        for (int i = 0; i <= ntaken; i++) {
            memset(&m, 0, sizeof m);
            m.kind = FTM_WIRE_STATUS;
            ftm_wire_status *st = &m.u.status;
            st->role = FTM_WIRE_ROLE_SERVER;
            st->state = FTM_WIRE_STATE_SYNCED;
            snprintf(st->name, sizeof st->name, "rogue server");
            if (i < ntaken) {
                st->holder_participant[0] = taken;
                st->holder_origin[0] = taken_origin[i];
                st->holder_count = 1;
            }
            if (innocent_origin) {
                st->ignored_participant[0] = innocent;
                st->ignored_origin[0] = innocent_origin;
                st->ignored_count = 1;
            }
            if (!st->holder_count && !st->ignored_count)
                continue;
            for (int k = 0; k < 2; k++) {
                st->participant = k ? server_id + 92 : server_id;
                if (ftm_wire_publish(t[k], &m, &err))
                    fprintf(stderr, "rogue: status: %s\n", err.message);
            }
            statuses++;
        }
        if (ntaken >= 2 && !told_holder) {
            printf("rogue: forged server statuses confirming participant %u for each of its %d "
                   "processes\n", taken, ntaken);
            fflush(stdout);
            told_holder = true;
        }
        if (innocent_origin && !told_ignored) {
            printf("rogue: forged server status ignoring participant %u\n", innocent);
            fflush(stdout);
            told_ignored = true;
        }
    }
    for (int k = 0; k < 2; k++) {
        ftm_wire_flush(t[k], 1000000000LL, NULL);
        ftm_wire_transport_destroy(t[k]);
    }
    printf("rogue: forge done: %" PRIu64 " statuses, %" PRIu64 " replies; heard %" PRIu64
           " statuses, %" PRIu64 " commands\n",
           statuses, replies, heard_status, heard_control);
    return 0;
}

/* --impersonate VICTIM: joins as trainee `id` (its own, certified identity
 * in a secured session) and for `seconds` writes what a payload may claim
 * but its writer's certificate does not: a status under role SERVER with a
 * tick far ahead (would stop the server: the later of two servers stops), a
 * status and probe input naming VICTIM. */
static int impersonate(const char *config, uint32_t domain, const char *session, uint32_t id,
                       uint32_t victim, double seconds)
{
    ftm_wire_transport *t =
        transport(config, domain, session, id,
                  FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) | FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT),
                  FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE));
    ftm_error err = {0, ""};
    /* both writers matched before the clock starts: with DDS Security each
     * topic is matched on its own, and in an ASan build on a busy host the
     * status topic's match once came after the 2 s were over */
    if (ftm_wire_wait_matched(t, FTM_WIRE_PROBE_INPUT, 1, 5000000000LL, &err) ||
        ftm_wire_wait_matched(t, FTM_WIRE_STATUS, 1, 5000000000LL, &err)) {
        fprintf(stderr, "rogue: %s\n", err.message);
        exit(3);
    }
    ftm_wire_probe_sample smp = {.probe = 0, .device_time_ns = 1, .position = {0, 0, 0.2}};
    const int64_t end = ftm_clock_mono_ns() + (int64_t)(seconds * 1e9);
    uint64_t sent = 0;
    while (ftm_clock_mono_ns() < end) {
        ftm_wire_msg m;
        memset(&m, 0, sizeof m);
        m.kind = FTM_WIRE_STATUS;
        m.u.status.participant = id;
        m.u.status.role = FTM_WIRE_ROLE_SERVER;
        m.u.status.state = FTM_WIRE_STATE_SYNCED;
        m.u.status.last_applied_tick = 1000000000u;
        snprintf(m.u.status.name, sizeof m.u.status.name, "rogue server");
        int rc = ftm_wire_publish(t, &m, &err);
        m.u.status.participant = victim;
        m.u.status.role = FTM_WIRE_ROLE_TRAINEE;
        m.u.status.last_applied_tick = 0;
        rc |= ftm_wire_publish(t, &m, &err);
        memset(&m, 0, sizeof m);
        m.kind = FTM_WIRE_PROBE_INPUT;
        m.u.probe_input.participant = victim;
        m.u.probe_input.sample_count = 1;
        m.u.probe_input.samples = &smp;
        rc |= ftm_wire_publish(t, &m, &err);
        if (rc)
            fprintf(stderr, "rogue: %s\n", err.message);
        sent++;
        pause_ms(50);
    }
    printf("rogue: impersonated the server and participant %u (%" PRIu64 " rounds)\n", victim,
           sent);
    ftm_wire_flush(t, 1000000000LL, NULL);
    ftm_wire_transport_destroy(t);
    return 0;
}

/* The most remote endpoints kind has matched since the last call. */
static int32_t matched_max(ftm_wire_transport *t, int kind, int32_t seen)
{
    ftm_wire_stats st;
    if (ftm_wire_get_stats(t, kind, &st, NULL) == FTM_OK && st.matched > seen)
        return st.matched;
    return seen;
}

/* --elevated ROLE (server or instructor): a trainee of a secured room that
 * signed itself ROLE's permissions with its own key and certificate (what
 * CVE-2023-24011 lets pass where one CA signs both identities and
 * permissions), and hands them to Cyclone directly (--cyclone FILE, a
 * <Security> configuration naming the forged documents). ftm_wire would
 * refuse them: its check runs instead on --security DIR, a bundle of its
 * own whose role file says ROLE (the check vets the files it is shown; that
 * file only names the partition ftm.ROLE.ID its writers use). For
 * `seconds`:
 * - instructor: its status (role instructor) every 300 ms, and pause,
 *   resume, stiffness 200 N/m, reset, one every 200 ms, over and over;
 * - server: statuses claiming role server at a tick far ahead, every 50 ms
 *   (the later of two servers stops).
 * It reads nothing another rogue writes, so what its writer matched is the
 * session's, and prints it with what was answered. */
static int elevated(const char *config, uint32_t domain, const char *session, uint32_t id,
                    const char *role, double seconds)
{
    const bool server = strcmp(role, "server") == 0;
    if (!server && strcmp(role, "instructor") != 0) {
        fprintf(stderr, "rogue: --elevated %s: server or instructor\n", role);
        return 2;
    }
    const int kind = server ? FTM_WIRE_STATUS : FTM_WIRE_CONTROL;
    ftm_wire_transport *t =
        server ? transport(config, domain, session, id, FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS), 0)
               : transport(config, domain, session, id,
                           FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) | FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL),
                           FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL_REPLY));
    printf("rogue: elevated to %s\n", role);
    fflush(stdout);
    static const ftm_wire_command cycle[4] = {FTM_WIRE_CMD_PAUSE, FTM_WIRE_CMD_RESUME,
                                              FTM_WIRE_CMD_TISSUE, FTM_WIRE_CMD_RESET};
    const int64_t start = ftm_clock_mono_ns(), end = start + (int64_t)(seconds * 1e9);
    int64_t next_status = start, next_command = start + 300000000LL;
    uint64_t statuses = 0, commands = 0, answered = 0, applied = 0;
    int32_t matched = 0;
    ftm_error err = {0, ""};
    ftm_wire_msg m;
    while (ftm_clock_mono_ns() < end) {
        matched = matched_max(t, kind, matched);
        const int64_t now = ftm_clock_mono_ns();
        if (now >= next_status) {
            next_status = now + (server ? 50000000LL : 300000000LL);
            memset(&m, 0, sizeof m);
            m.kind = FTM_WIRE_STATUS;
            m.u.status.participant = id;
            m.u.status.role = server ? FTM_WIRE_ROLE_SERVER : FTM_WIRE_ROLE_INSTRUCTOR;
            m.u.status.state = FTM_WIRE_STATE_SYNCED;
            m.u.status.last_applied_tick = server ? 1000000000u : 0;
            snprintf(m.u.status.name, sizeof m.u.status.name, "rogue %s", role);
            if (ftm_wire_publish(t, &m, &err))
                fprintf(stderr, "rogue: status: %s\n", err.message);
            statuses++;
        }
        if (!server && now >= next_command) {
            next_command = now + 200000000LL;
            memset(&m, 0, sizeof m);
            m.kind = FTM_WIRE_CONTROL;
            m.u.control.issuer = id;
            m.u.control.command_id = commands + 1;
            m.u.control.command = cycle[commands % 4];
            m.u.control.tissue = (ftm_wire_tissue){.node_mass = 0.001,
                                                   .node_damping = 0.3,
                                                   .stiffness = 200,
                                                   .axis_scale = {1, 1, 1}};
            if (ftm_wire_publish(t, &m, &err))
                fprintf(stderr, "rogue: control: %s\n", err.message);
            commands++;
        }
        ftm_wire_received rx;
        while (!server && ftm_wire_receive(t, FTM_WIRE_CONTROL_REPLY, &rx, 0, NULL) == FTM_OK) {
            if (rx.msg.u.control_reply.issuer == id) {
                answered++;
                applied += rx.msg.u.control_reply.outcome == FTM_WIRE_OUTCOME_APPLIED;
            }
            ftm_wire_received_free(&rx);
        }
        pause_ms(10);
    }
    ftm_wire_flush(t, 1000000000LL, NULL);
    ftm_wire_transport_destroy(t);
    if (server)
        printf("rogue: elevated server %u: its status matched by %d readers at most; %" PRIu64
               " statuses sent\n", id, (int)matched, statuses);
    else
        printf("rogue: elevated instructor %u: its session control matched by %d readers at most; "
               "%" PRIu64 " commands sent, %" PRIu64 " answered, %" PRIu64 " applied\n",
               id, (int)matched, commands, answered, applied);
    return 0;
}

int main(int argc, char **argv)
{
    const char *config = NULL, *session = "ftm", *elevate = NULL;
    uint32_t domain = 0, id = 0, victim = 0, taken = 0, innocent = 0, impersonated = 0;
    double forge_s = 0, impersonate_s = 0;
    for (int i = 1; i + 1 < argc; i += 2) {
        const char *a = argv[i], *v = argv[i + 1];
        char *end = NULL;
        errno = 0;
        if (strcmp(a, "--config") == 0)
            config = v;
        else if (strcmp(a, "--security") == 0)
            g_security = v;
        else if (strcmp(a, "--cyclone") == 0)
            g_cyclone = v;
        else if (strcmp(a, "--elevated") == 0)
            elevate = v;
        else if (strcmp(a, "--session") == 0)
            session = v;
        else if (strcmp(a, "--domain") == 0)
            domain = (uint32_t)strtoul(v, &end, 10);
        else if (strcmp(a, "--id") == 0)
            id = (uint32_t)strtoul(v, &end, 10);
        else if (strcmp(a, "--victim") == 0)
            victim = (uint32_t)strtoul(v, &end, 10);
        else if (strcmp(a, "--taken") == 0)
            taken = (uint32_t)strtoul(v, &end, 10);
        else if (strcmp(a, "--innocent") == 0)
            innocent = (uint32_t)strtoul(v, &end, 10);
        else if (strcmp(a, "--forge") == 0)
            forge_s = strtod(v, &end);
        else if (strcmp(a, "--impersonate") == 0)
            impersonated = (uint32_t)strtoul(v, &end, 10);
        else if (strcmp(a, "--for") == 0)
            impersonate_s = strtod(v, &end);
        else {
            fprintf(stderr, "rogue: unknown option %s\n", a);
            return 2;
        }
        if (end && (*end || errno)) {
            fprintf(stderr, "rogue: %s: bad number '%s'\n", a, v);
            return 2;
        }
    }
    if (argc % 2 == 1 && elevate && g_cyclone && g_security && id && impersonate_s > 0 &&
        impersonate_s < 60)
        return elevated(config, domain, session, id, elevate, impersonate_s);
    if (argc % 2 == 1 && forge_s > 0 && forge_s < 60 && id && taken && innocent)
        return forge(config, domain, session, id, taken, innocent, forge_s);
    if (argc % 2 == 1 && impersonated && impersonate_s > 0 && impersonate_s < 60 && id &&
        impersonated != id)
        return impersonate(config, domain, session, id, impersonated, impersonate_s);
    if (argc % 2 != 1 || id == 0 || victim == 0 || victim == id || victim == id + 1) {
        fprintf(stderr, "usage: ftm-rogue --id N --victim M [--config F] [--security DIR] "
                        "[--domain D] [--session S]   (uses ids N and N+1; M is a trainee to "
                        "impersonate)\n"
                        "       ftm-rogue --forge SECONDS --id SERVER --taken T --innocent I "
                        "[--config F] [--security DIR] [--domain D] [--session S]\n"
                        "       ftm-rogue --impersonate VICTIM --for SECONDS --id N "
                        "[--config F] [--security DIR] [--domain D] [--session S]\n"
                        "       ftm-rogue --elevated server|instructor --for SECONDS --id N "
                        "--cyclone SECURITY.xml --security DIR [--config F] [--domain D] "
                        "[--session S]\n");
        return 2;
    }

    /* 1. as an observer */
    ftm_wire_transport *t = join(config, domain, session, id, FTM_WIRE_ROLE_OBSERVER);
    uint8_t garbage[97];
    uint32_t lcg = 12345u;
    for (size_t i = 0; i < sizeof garbage; i++) {
        lcg = lcg * 1103515245u + 12345u;
        garbage[i] = (uint8_t)(lcg >> 23);
    }
    raw(t, FTM_WIRE_PROBE_INPUT, garbage, sizeof garbage, "garbage bytes");

    buf b = {0};
    probe_input_bytes(&b, id, 0.035, NAN, 0.105);
    raw(t, FTM_WIRE_PROBE_INPUT, b.p, b.n, "NaN coordinate");
    raw(t, FTM_WIRE_PROBE_INPUT, b.p, b.n - 5, "truncated payload");
    free(b.p);

    size_t big = FTM_WIRE_CAP_PROBE_INPUT + 4096;
    uint8_t *zeros = calloc(big, 1);
    if (!zeros)
        return 3;
    raw(t, FTM_WIRE_PROBE_INPUT, zeros, big, "oversized probe input");
    raw(t, FTM_WIRE_STATUS, zeros, FTM_WIRE_CAP_STATUS + 1, "oversized status");
    free(zeros);

    /* 100 000 empty samples in 200 kB: each unpacks into a whole
     * ProbeSample, far beyond the decoder's memory budget */
    buf huge = {0};
    for (int i = 0; i < 100000; i++) {
        key(&huge, 4, 2);
        varint(&huge, 0);
    }
    raw(t, FTM_WIRE_PROBE_INPUT, huge.p, huge.n, "huge repeated count");
    free(huge.p);

    wrong_kind(domain, session, id);

    ftm_wire_probe_sample smp = {0, 1, {0.035, 0.035, 0.100}};
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_PROBE_INPUT;
    m.u.probe_input.participant = id;
    m.u.probe_input.sample_count = 1;
    m.u.probe_input.samples = &smp;
    msg(t, &m, "observer sends probe input");

    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL;
    m.u.control.issuer = id;
    m.u.control.command_id = 1;
    m.u.control.command = FTM_WIRE_CMD_RESET;
    msg(t, &m, "observer sends session control");

    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    m.u.status.participant = victim;
    m.u.status.role = FTM_WIRE_ROLE_INSTRUCTOR;
    m.u.status.state = FTM_WIRE_STATE_SYNCED;
    msg(t, &m, "status naming another participant");

    /* a forged tick frame and keyframe: replicas must follow the server only */
    ftm_contact c = {0, 0, FTM_CONTACT_DISPLACEMENT, {0, 0, 0.01}};
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_TICK;
    m.u.tick.tick = 1000000;
    m.u.tick.contact_count = 1;
    m.u.tick.contacts = &c;
    m.u.tick.state_hash = 42;
    msg(t, &m, "forged tick frame");
    int32_t node = 0;
    double pos[3] = {0, 0, 0.5};
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_KEYFRAME;
    m.u.keyframe.tick = 1000000;
    m.u.keyframe.state_hash = 42;
    m.u.keyframe.node_count = 1728;
    m.u.keyframe.count = 1;
    m.u.keyframe.nodes = &node;
    m.u.keyframe.positions = pos;
    m.u.keyframe.previous = pos;
    msg(t, &m, "forged keyframe");

    /* 2. as a trainee (id + 1) */
    ftm_wire_transport *t2 = join(config, domain, session, id + 1, FTM_WIRE_ROLE_TRAINEE);
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL;
    m.u.control.issuer = id + 1;
    m.u.control.command_id = 1;
    m.u.control.command = FTM_WIRE_CMD_PAUSE;
    msg(t2, &m, "trainee sends session control");

    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_PROBE_INPUT;
    m.u.probe_input.participant = victim;
    m.u.probe_input.sample_count = 1;
    m.u.probe_input.samples = &smp;
    msg(t2, &m, "probe input in another participant's name");

    ftm_wire_probe_sample bad = {9, 1, {0.035, 0.035, 0.100}};
    m.u.probe_input.participant = id + 1;
    m.u.probe_input.samples = &bad;
    msg(t2, &m, "probe index out of range");

    /* leave in order; the forged keyframe dies with its writer */
    status(t, id, 0, FTM_WIRE_ROLE_OBSERVER, FTM_WIRE_STATE_LEAVING);
    status(t2, id + 1, 0, FTM_WIRE_ROLE_TRAINEE, FTM_WIRE_STATE_LEAVING);
    ftm_wire_flush(t, 2000000000LL, NULL);
    ftm_wire_flush(t2, 2000000000LL, NULL);
    ftm_wire_transport_destroy(t2);
    ftm_wire_transport_destroy(t);
    printf("rogue: done (%d steps not sent)\n", fails);
    return fails ? 1 : 0;
}
