/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The DDS transport over loopback (deploy/cyclonedds-loopback.xml: no
 * multicast, peer 127.0.0.1). The remote side is this executable run again
 * as a child process (`--peer ROLE DOMAIN SESSION IN_FD OUT_FD`), so data
 * really crosses the loopback interface; parent and child synchronise over
 * pipes. Every wait is bounded. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "ftm/wire.h"

#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define SEC 1000000000LL
#define NTICKS 300
#define PARENT_ID 1000u
#define CHILD_ID 2000u

static uint32_t domain_id;
static int session_counter;

/* ---- log capture ---------------------------------------------------------- */

typedef struct logbuf {
    pthread_mutex_t lock;
    char text[8192];
    size_t len;
} logbuf;

static void capture_log(void *user, ftm_log_level level, const char *message)
{
    (void)level;
    logbuf *b = user;
    pthread_mutex_lock(&b->lock);
    int n = snprintf(b->text + b->len, sizeof b->text - b->len, "%s\n", message);
    if (n > 0 && b->len + (size_t)n < sizeof b->text)
        b->len += (size_t)n;
    pthread_mutex_unlock(&b->lock);
}

/* ---- helpers -------------------------------------------------------------- */

/* Whether the line that starts at line ends with suffix. */
static bool line_ends_with(const char *line, const char *suffix)
{
    const size_t n = strcspn(line, "\n"), k = strlen(suffix);
    return n >= k && memcmp(line + n - k, suffix, k) == 0;
}

static ftm_wire_transport *open_transport(const char *session, uint32_t id, uint32_t pub,
                                          uint32_t sub, logbuf *log)
{
    ftm_wire_transport_def def;
    memset(&def, 0, sizeof def);
    def.config = FTM_LOOPBACK_CONFIG;
    def.domain_id = domain_id;
    def.session = session;
    def.participant_id = id;
    def.publish = pub;
    def.subscribe = sub;
    def.log = log ? capture_log : NULL;
    def.log_user = log;
    ftm_wire_transport *t = NULL;
    ftm_error err = {0, ""};
    int rc = ftm_wire_transport_create(&def, &t, &err);
    if (rc) {
        fprintf(stderr, "transport_create: %s\n", err.message);
        return NULL;
    }
    return t;
}

static ftm_wire_msg make_tick(uint64_t tick, ftm_contact *c)
{
    *c = (ftm_contact){.node = (int32_t)(tick % 50), .group = 0, .kind = FTM_CONTACT_FORCE,
                       .value = {0.001 * (double)tick, -0.5, 1.0 / 3.0}};
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_TICK;
    m.u.tick = (ftm_wire_tick){
        .tick = tick, .depth = 10, .contact_count = 1, .contacts = c, .reaction_count = 0,
        .reactions = NULL, .state_hash = tick * 0x9e3779b97f4a7c15u, .send_time_ns = 0};
    return m;
}

static ftm_wire_msg make_keyframe(uint64_t tick, int32_t *nodes, double *pos)
{
    for (int i = 0; i < 4; i++) {
        nodes[i] = 3 * i;
        for (int c = 0; c < 3; c++)
            pos[3 * i + c] = (double)tick + 0.125 * i + c;
    }
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_KEYFRAME;
    m.u.keyframe = (ftm_wire_keyframe){
        .tick = tick, .state_hash = tick ^ 0xabcdu, .node_count = 100, .depth = 10, .count = 4,
        .nodes = nodes, .positions = pos, .previous = pos};
    return m;
}

/* Reads one byte from fd within timeout_ms; -1 on timeout/EOF/error. */
static int read_byte(int fd, int timeout_ms)
{
    struct pollfd p = {fd, POLLIN, 0};
    int rc;
    do
        rc = poll(&p, 1, timeout_ms);
    while (rc < 0 && errno == EINTR);
    if (rc <= 0)
        return -1;
    unsigned char c;
    return read(fd, &c, 1) == 1 ? c : -1;
}

static void write_byte(int fd, char c)
{
    if (write(fd, &c, 1) != 1)
        perror("write");
}

typedef struct child {
    pid_t pid;
    int to_child, from_child;
} child;

static child spawn_peer(const char *role, const char *session)
{
    int down[2], up[2];
    assert_int_equal(pipe(down), 0);
    assert_int_equal(pipe(up), 0);
    child c = {-1, down[1], up[0]};
    char dom[16], in[16], out[16];
    snprintf(dom, sizeof dom, "%u", domain_id);
    snprintf(in, sizeof in, "%d", down[0]);
    snprintf(out, sizeof out, "%d", up[1]);
    char *argv[] = {"test_wire_transport", "--peer", (char *)role, dom, (char *)session,
                    in, out, NULL};
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        close(down[1]);
        close(up[0]);
        execv("/proc/self/exe", argv);
        _exit(127);
    }
    close(down[0]);
    close(up[1]);
    c.pid = pid;
    return c;
}

/* Waits (bounded) for the child to exit; returns its exit status or -1. */
static int finish_peer(child *c)
{
    close(c->to_child); /* EOF tells the child to leave */
    close(c->from_child);
    for (int i = 0; i < 1500; i++) {
        int status;
        pid_t r = waitpid(c->pid, &status, WNOHANG);
        if (r == c->pid)
            return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        struct timespec ts = {0, 10000000};
        nanosleep(&ts, NULL);
    }
    kill(c->pid, SIGKILL);
    waitpid(c->pid, NULL, 0);
    return -1;
}

/* Receives warm-up frames (tick 0) until one arrives, tells the child to go,
 * and returns the sequence number of the last warm-up frame taken; the
 * frames after it must follow without gaps. */
static uint64_t warm_up(ftm_wire_transport *t, child *c, ftm_wire_received *first)
{
    ftm_error err = {0, ""};
    ftm_wire_received r;
    int rc = ftm_wire_receive(t, FTM_WIRE_TICK, &r, 20 * SEC, &err);
    if (rc)
        fail_msg("warm-up: %s", err.message);
    assert_true(r.msg.u.tick.tick == 0);
    uint64_t seq = r.seq;
    ftm_wire_received_free(&r);
    write_byte(c->to_child, 'g');
    for (;;) {
        rc = ftm_wire_receive(t, FTM_WIRE_TICK, &r, 10 * SEC, &err);
        if (rc)
            fail_msg("after warm-up: %s", err.message);
        if (r.msg.u.tick.tick != 0) {
            *first = r;
            return seq;
        }
        assert_true(r.seq == seq + 1 && r.gap == 0);
        seq = r.seq;
        ftm_wire_received_free(&r);
    }
}

static void new_session(char *buf, size_t size)
{
    snprintf(buf, size, "test-%ld-%d", (long)getpid(), ++session_counter);
}

/* ---- the child's roles ------------------------------------------------------- */

static int peer_main(int argc, char **argv)
{
    if (argc < 7)
        return 2;
    const char *role = argv[2];
    domain_id = (uint32_t)atoi(argv[3]);
    const char *session = argv[4];
    int in = atoi(argv[5]), out = atoi(argv[6]);
    ftm_error err = {0, ""};
    int rc = 0;
    ftm_contact c;

    if (strcmp(role, "ticks") == 0 || strcmp(role, "garbage") == 0) {
        ftm_wire_transport *t = open_transport(session, CHILD_ID, FTM_WIRE_KIND_BIT(FTM_WIRE_TICK),
                                               0, NULL);
        if (!t)
            return 3;
        if (ftm_wire_wait_matched(t, FTM_WIRE_TICK, 1, 20 * SEC, &err)) {
            ftm_wire_transport_destroy(t);
            return 4;
        }
        /* A volatile reader may miss what is written right after matching
         * (before it has heard the writer's first heartbeat): send warm-up
         * frames (tick 0) until the parent has received one. */
        int go = -1;
        for (int i = 0; i < 1000 && go != 'g'; i++) {
            ftm_wire_msg w = make_tick(0, &c);
            if (ftm_wire_publish(t, &w, &err))
                break;
            go = read_byte(in, 20);
        }
        if (go != 'g') {
            ftm_wire_transport_destroy(t);
            return 4;
        }
        if (strcmp(role, "ticks") == 0) {
            for (uint64_t i = 1; i <= NTICKS && !rc; i++) {
                ftm_wire_msg m = make_tick(i, &c);
                rc = ftm_wire_publish(t, &m, &err);
            }
        } else {
            /* good, garbage, oversized garbage, then four good ones */
            ftm_wire_msg m = make_tick(1, &c);
            rc = ftm_wire_publish(t, &m, &err);
            static const uint8_t junk[] = {0x08, 0x01, 0x42, 0x7f, 0x00, 0x12};
            rc = rc ? rc : ftm_wire_publish_raw(t, FTM_WIRE_TICK, junk, sizeof junk, &err);
            size_t big = FTM_WIRE_CAP_TICK + 100;
            uint8_t *zeros = calloc(big, 1);
            rc = rc ? rc : ftm_wire_publish_raw(t, FTM_WIRE_TICK, zeros, big, &err);
            free(zeros);
            for (uint64_t i = 2; i <= 5 && !rc; i++) {
                m = make_tick(i, &c);
                rc = ftm_wire_publish(t, &m, &err);
            }
        }
        if (!rc)
            rc = ftm_wire_flush(t, 20 * SEC, &err);
        if (rc)
            fprintf(stderr, "peer %s: %s\n", role, err.message);
        read_byte(in, 30000); /* until the parent is done */
        ftm_wire_transport_destroy(t);
        return rc ? 5 : 0;
    }
    if (strcmp(role, "keyframes") == 0) {
        ftm_wire_transport *t = open_transport(
            session, CHILD_ID,
            FTM_WIRE_KIND_BIT(FTM_WIRE_KEYFRAME) | FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE), 0, NULL);
        if (!t)
            return 3;
        int32_t nodes[4];
        double pos[12];
        for (uint64_t tick = 10; tick <= 30 && !rc; tick += 10) {
            ftm_wire_msg m = make_keyframe(tick, nodes, pos);
            rc = ftm_wire_publish(t, &m, &err);
        }
        ftm_wire_msg a;
        memset(&a, 0, sizeof a);
        a.kind = FTM_WIRE_ANNOUNCE;
        snprintf(a.u.announce.scene_id, sizeof a.u.announce.scene_id, "cube");
        a.u.announce.digest_len = 1;
        a.u.announce.tick_rate_hz = 1000;
        a.u.announce.time_step = 1e-3;
        a.u.announce.depth = 10;
        a.u.announce.depth_max = 20;
        a.u.announce.tissue = (ftm_wire_tissue){1e-3, 0.1, 1.0, {1, 1, 1}};
        a.u.announce.node_count = 100;
        a.u.announce.tick = 30;
        rc = rc ? rc : ftm_wire_publish(t, &a, &err);
        rc = rc ? rc : ftm_wire_flush(t, 10 * SEC, &err);
        if (rc)
            fprintf(stderr, "peer keyframes: %s\n", err.message);
        write_byte(out, 'r');
        read_byte(in, 30000);
        ftm_wire_transport_destroy(t);
        return rc ? 5 : 0;
    }
    return 2;
}

/* ---- tests --------------------------------------------------------------------- */

static void test_ticks_in_order(void **state)
{
    (void)state;
    char session[64];
    new_session(session, sizeof session);
    child c = spawn_peer("ticks", session);
    logbuf log = {PTHREAD_MUTEX_INITIALIZER, "", 0};
    ftm_wire_transport *t = open_transport(session, PARENT_ID, 0, FTM_WIRE_KIND_BIT(FTM_WIRE_TICK), &log);
    assert_non_null(t);
    ftm_error err = {0, ""};
    int rc = ftm_wire_wait_matched(t, FTM_WIRE_TICK, 1, 20 * SEC, &err);
    if (rc)
        fail_msg("%s", err.message);
    ftm_wire_received r;
    uint64_t base = warm_up(t, &c, &r);
    for (uint64_t i = 1; i <= NTICKS; i++) {
        if (i > 1) {
            rc = ftm_wire_receive(t, FTM_WIRE_TICK, &r, 10 * SEC, &err);
            if (rc)
                fail_msg("tick %llu: %s", (unsigned long long)i, err.message);
        }
        assert_int_equal(r.sender, CHILD_ID);
        assert_true(r.seq == base + i);
        assert_true(r.gap == 0);
        assert_true(r.msg.u.tick.tick == i);
        assert_true(r.msg.u.tick.state_hash == i * 0x9e3779b97f4a7c15u);
        assert_int_equal(r.msg.u.tick.contact_count, 1);
        assert_int_equal(r.msg.u.tick.contacts[0].node, (int)(i % 50));
        ftm_wire_received_free(&r);
    }
    ftm_wire_stats st;
    assert_int_equal(ftm_wire_get_stats(t, FTM_WIRE_TICK, &st, &err), FTM_OK);
    assert_true(st.received == NTICKS + base);
    assert_true(st.rejected == 0);
    assert_true(st.missing == 0);
    ftm_wire_transport_destroy(t);
    assert_int_equal(finish_peer(&c), 0);
}

static void test_late_joiner_gets_last_keyframe(void **state)
{
    (void)state;
    char session[64];
    new_session(session, sizeof session);
    child c = spawn_peer("keyframes", session);
    /* join only after the peer has published all three keyframes */
    assert_int_equal(read_byte(c.from_child, 20000), 'r');
    ftm_wire_transport *t = open_transport(
        session, PARENT_ID, 0,
        FTM_WIRE_KIND_BIT(FTM_WIRE_KEYFRAME) | FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE), NULL);
    assert_non_null(t);
    ftm_error err = {0, ""};
    ftm_wire_received r;
    int rc = ftm_wire_receive(t, FTM_WIRE_KEYFRAME, &r, 20 * SEC, &err);
    if (rc)
        fail_msg("%s", err.message);
    assert_true(r.msg.u.keyframe.tick == 30);
    assert_true(r.seq == 3);
    assert_true(r.gap == 0); /* first message from this sender: baseline */
    assert_int_equal(r.msg.u.keyframe.count, 4);
    assert_true(r.msg.u.keyframe.positions[11] == 30 + 0.375 + 2);
    ftm_wire_received_free(&r);
    /* only the latest one is kept */
    assert_int_equal(ftm_wire_receive(t, FTM_WIRE_KEYFRAME, &r, SEC / 2, &err), FTM_ETIMEDOUT);
    assert_non_null(strstr(err.message, "keyframe"));
    rc = ftm_wire_receive(t, FTM_WIRE_ANNOUNCE, &r, 10 * SEC, &err);
    if (rc)
        fail_msg("%s", err.message);
    assert_string_equal(r.msg.u.announce.scene_id, "cube");
    assert_int_equal(r.msg.u.announce.node_count, 100);
    ftm_wire_received_free(&r);
    ftm_wire_transport_destroy(t);
    assert_int_equal(finish_peer(&c), 0);
}

static void test_malformed_rejected_then_good(void **state)
{
    (void)state;
    char session[64];
    new_session(session, sizeof session);
    child c = spawn_peer("garbage", session);
    logbuf log = {PTHREAD_MUTEX_INITIALIZER, "", 0};
    ftm_wire_transport *t = open_transport(session, PARENT_ID, 0, FTM_WIRE_KIND_BIT(FTM_WIRE_TICK), &log);
    assert_non_null(t);
    ftm_error err = {0, ""};
    int rc = ftm_wire_wait_matched(t, FTM_WIRE_TICK, 1, 20 * SEC, &err);
    if (rc)
        fail_msg("%s", err.message);
    ftm_wire_received r;
    uint64_t base = warm_up(t, &c, &r);
    const uint64_t want_seq[5] = {1, 4, 5, 6, 7}, want_gap[5] = {0, 2, 0, 0, 0};
    for (int i = 0; i < 5; i++) {
        if (i > 0) {
            rc = ftm_wire_receive(t, FTM_WIRE_TICK, &r, 10 * SEC, &err);
            if (rc)
                fail_msg("good tick %d: %s", i + 1, err.message);
        }
        assert_true(r.msg.u.tick.tick == (uint64_t)i + 1);
        assert_true(r.seq == base + want_seq[i]);
        assert_true(r.gap == want_gap[i]);
        ftm_wire_received_free(&r);
    }
    ftm_wire_stats st;
    assert_int_equal(ftm_wire_get_stats(t, FTM_WIRE_TICK, &st, &err), FTM_OK);
    assert_true(st.received == 5 + base);
    assert_true(st.rejected == 2);
    assert_true(st.missing == 2);
    assert_non_null(strstr(st.last_reject, "exceeds"));
    pthread_mutex_lock(&log.lock);
    char want1[128], want2[128];
    snprintf(want1, sizeof want1,
             "rejected message from participant 2000 seq %llu: tick frame: malformed at byte",
             (unsigned long long)base + 2);
    snprintf(want2, sizeof want2,
             "rejected message from participant 2000 seq %llu: tick frame: payload of",
             (unsigned long long)base + 3);
    char *first = strstr(log.text, want1);
    char *second = strstr(log.text, want2);
    if (!first || !second)
        fail_msg("log lacks the reasons:\n%s", log.text);
    /* each with its code's symbolic name at the end of the line */
    if (!line_ends_with(first, "(FTM_EPARSE)") || !line_ends_with(second, "(FTM_ETOOBIG)"))
        fail_msg("log lacks the codes' names:\n%s", log.text);
    pthread_mutex_unlock(&log.lock);
    ftm_wire_transport_destroy(t);
    assert_int_equal(finish_peer(&c), 0);
}

/* Two transports in this process (one domain): status, then the gone event
 * when the other participant leaves. */
static void test_in_process_status_and_leave(void **state)
{
    (void)state;
    char session[64];
    new_session(session, sizeof session);
    uint32_t status_bit = FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS);
    ftm_wire_transport *a = open_transport(session, 11, status_bit, status_bit, NULL);
    ftm_wire_transport *b = open_transport(session, 22, status_bit, status_bit, NULL);
    assert_non_null(a);
    assert_non_null(b);
    ftm_error err = {0, ""};
    assert_int_equal(ftm_wire_wait_matched(a, FTM_WIRE_STATUS, 1, 10 * SEC, &err), FTM_OK);
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    m.u.status = (ftm_wire_status){.participant = 11, .role = FTM_WIRE_ROLE_BOT,
                                   .state = FTM_WIRE_STATE_SYNCED, .last_applied_tick = 5,
                                   .state_hash = 6, .replay_ns_per_tick = 1.5,
                                   .replay_ns_max = 2.5, .name = "bot"};
    assert_int_equal(ftm_wire_publish(a, &m, &err), FTM_OK);
    ftm_wire_received r;
    int rc = ftm_wire_receive(b, FTM_WIRE_STATUS, &r, 10 * SEC, &err);
    if (rc)
        fail_msg("%s", err.message);
    assert_int_equal(r.sender, 11);
    assert_false(r.gone);
    /* the sender's origin is what it says of itself, and not ours: what a
     * server's list of ignored processes names (ftm_replay_id_verdict) */
    assert_true(r.origin != 0);
    assert_true(r.origin == ftm_wire_transport_origin(a));
    assert_true(r.origin != ftm_wire_transport_origin(b));
    assert_string_equal(r.msg.u.status.name, "bot");
    ftm_wire_received_free(&r);
    /* b does not hear itself */
    ftm_wire_msg mine = m;
    mine.u.status.participant = 22;
    assert_int_equal(ftm_wire_publish(b, &mine, &err), FTM_OK);
    assert_int_equal(ftm_wire_flush(b, 5 * SEC, &err), FTM_OK);
    assert_int_equal(ftm_wire_receive(b, FTM_WIRE_STATUS, &r, SEC / 5, &err), FTM_ETIMEDOUT);

    ftm_wire_transport_destroy(a);
    rc = ftm_wire_receive(b, FTM_WIRE_STATUS, &r, 10 * SEC, &err);
    if (rc)
        fail_msg("%s", err.message);
    assert_true(r.gone);
    assert_int_equal(r.sender, 11);
    ftm_wire_received_free(&r);
    ftm_wire_transport_destroy(b);
}

static void test_bad_config(void **state)
{
    (void)state;
    ftm_wire_transport_def def;
    memset(&def, 0, sizeof def);
    def.config = "/nonexistent/cyclone.xml";
    def.domain_id = domain_id;
    def.session = "x";
    def.participant_id = 1;
    ftm_wire_transport *t = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_wire_transport_create(&def, &t, &err), FTM_EIO);
    assert_non_null(strstr(err.message, "/nonexistent/cyclone.xml"));
    assert_null(t);
    def.config = FTM_LOOPBACK_CONFIG;
    def.participant_id = 0;
    assert_int_equal(ftm_wire_transport_create(&def, &t, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "participant_id"));
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--peer") == 0)
        return peer_main(argc, argv);
    /* a domain of our own so that concurrent test runs do not match */
    domain_id = 100u + (uint32_t)(getpid() % 120);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bad_config),
        cmocka_unit_test(test_ticks_in_order),
        cmocka_unit_test(test_late_joiner_gets_last_keyframe),
        cmocka_unit_test(test_malformed_rejected_then_good),
        cmocka_unit_test(test_in_process_status_and_leave),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
