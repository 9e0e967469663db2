/* ftm-client's session thread (client/client_session.c) without GL, against
 * a real ftm-server on loopback; tests/client/client_session.sh starts the
 * server (and a bot) and then this program:
 *
 *   test_session MODE DOMAIN SESSION CONFIG ID SCRIPT SECONDS
 *
 *   idtaken  a trainee (device: SCRIPT, in free space) whose id a pressing
 *            bot already uses: once it knows the id is taken, the force
 *            written to its device is zero and its view shows no probe,
 *            force, contact time or peak of its own (they are the bot's).
 *   idback   the same, but the bot leaves first: the client is told the id is
 *            its own again, and its force and figures come back.
 *   slow     a trainee whose replay is 3x slower than the ticks (each frame
 *            handed to the haptic side sleeps): it never catches up, yet
 *            must not go silent (the script checks that the server did not
 *            declare it lost), nor say it probably was.
 *   pause    an instructor pauses the session for longer than the server
 *            timeout (1 s here): the banner says paused, not silent, and no
 *            "no tick frames" is logged; after the resume the banner goes.
 *
 * on_force and take_hips are those of client/client_main.c. Exit 0 pass, 1
 * fail (saying why). */
#include "client_session.h"
#include "device.h"
#include "haptic.h"
#include "haptic_wire.h"

#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct tapp {
    ftm_haptic *hap;
    bool hap_connected;
    ftm_haptic_timebase timebase;
    ftm_device *inner;
    double frame_sleep; /* [s] per frame handed to on_force (slow mode) */
    atomic_bool taken, back;
    atomic_int nonzero_after_taken;
    atomic_int frames;
    atomic_int silent_logged, lost_logged;
    double t0;
} tapp;

static void sleep_s(double s)
{
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

static void on_log(void *user, ftm_log_level level, const char *msg)
{
    tapp *a = user;
    if (level < FTM_LOG_INFO)
        return;
    fprintf(stderr, "test_session [%7.3f] %s\n", ftm_haptic_clock() - a->t0, msg);
    if (strstr(msg, "is taken"))
        atomic_store(&a->taken, true);
    if (strstr(msg, "is ours again"))
        atomic_store(&a->back, true);
    if (strstr(msg, "no tick frames"))
        atomic_fetch_add(&a->silent_logged, 1);
    if (strstr(msg, "declared this client lost"))
        atomic_fetch_add(&a->lost_logged, 1);
}

/* the script device, with every force written counted */
static int w_read(void *self, double now, ftm_vec3 *hip)
{
    tapp *a = self;
    return ftm_device_read(a->inner, now, hip);
}

static void w_write(void *self, double now, ftm_vec3 f)
{
    tapp *a = self;
    if (atomic_load(&a->taken) && !atomic_load(&a->back) && (f.x != 0 || f.y != 0 || f.z != 0))
        atomic_fetch_add(&a->nonzero_after_taken, 1);
}

static const ftm_device_ops wrap_ops = {.name = "test", .read = w_read, .write = w_write};

static void on_force(void *user, uint64_t tick, double tick_time, const ftm_wire_reaction *r,
                     bool valid, const char *why)
{
    tapp *a = user;
    atomic_fetch_add(&a->frames, 1);
    if (a->frame_sleep > 0)
        sleep_s(a->frame_sleep);
    if (!a->hap)
        return;
    if (!valid) {
        if (a->hap_connected)
            ftm_haptic_set_connected(a->hap, false);
        a->hap_connected = false;
        return;
    }
    if (!a->hap_connected) {
        ftm_haptic_set_connected(a->hap, true);
        a->timebase = (ftm_haptic_timebase){0};
    }
    a->hap_connected = true;
    ftm_haptic_state st;
    ftm_haptic_get_state(a->hap, &st);
    double t = ftm_haptic_timebase_map(&a->timebase, tick_time, ftm_haptic_clock(), 0.1);
    ftm_haptic_sample s = ftm_haptic_sample_from_reaction(r, t, st.hip);
    ftm_haptic_push(a->hap, &s);
}

static int take_hips(void *user, ftm_wire_probe_sample *out, int max)
{
    tapp *a = user;
    ftm_haptic_hip h[64];
    int n = ftm_haptic_take_hips(a->hap, h, max < 64 ? max : 64);
    for (int i = 0; i < n; i++)
        out[i] = (ftm_wire_probe_sample){0, (uint64_t)(h[i].time * 1e9), h[i].hip};
    return n;
}

static int failures;
#define CHECK(cond, ...)                                                                          \
    do {                                                                                          \
        if (!(cond)) {                                                                            \
            fprintf(stderr, "FAIL: " __VA_ARGS__);                                                \
            fputc('\n', stderr);                                                                  \
            failures++;                                                                           \
        }                                                                                         \
    } while (0)

int main(int argc, char **argv)
{
    if (argc != 8) {
        fprintf(stderr, "usage: test_session idtaken|idback|slow|pause DOMAIN SESSION CONFIG ID SCRIPT "
                        "SECONDS\n");
        return 2;
    }
    const char *mode = argv[1];
    static tapp a;
    a.t0 = ftm_haptic_clock();
    bool trainee = strcmp(mode, "pause") != 0;
    ftm_error err = {0, ""};
    ftm_device *dev = NULL;
    if (trainee) {
        if (ftm_script_device_open(argv[6], NULL, &a.inner, &err) ||
            ftm_device_create(&wrap_ops, &a, NULL, &dev, &err)) {
            fprintf(stderr, "test_session: %s\n", err.message);
            return 1;
        }
        ftm_haptic_def hd = ftm_default_haptic_def();
        hd.realtime = false;
        if (ftm_haptic_create(&hd, dev, &a.hap, &err) || ftm_haptic_start(a.hap, &err)) {
            fprintf(stderr, "test_session: %s\n", err.message);
            return 1;
        }
        ftm_haptic_set_connected(a.hap, false);
    }
    ftm_client_config cc;
    memset(&cc, 0, sizeof cc);
    cc.role = trainee ? FTM_WIRE_ROLE_TRAINEE : FTM_WIRE_ROLE_INSTRUCTOR;
    cc.domain = (uint32_t)strtoul(argv[2], NULL, 10);
    cc.session = argv[3];
    cc.dds_config = argv[4];
    cc.id = (uint32_t)strtoul(argv[5], NULL, 10);
    cc.name = "test_session";
    cc.server_timeout = strcmp(mode, "pause") == 0 ? 1.0 : 3.0;
    cc.log = on_log;
    cc.log_user = &a;
    cc.on_force = on_force;
    cc.force_user = &a;
    if (trainee) {
        cc.take_hips = take_hips;
        cc.hip_user = &a;
    }
    if (strcmp(mode, "slow") == 0)
        a.frame_sleep = 3.0 / (double)(getenv("FTM_TEST_RATE") ? atoi(getenv("FTM_TEST_RATE")) : 500);
    ftm_client_session *s;
    if (ftm_client_session_start(&cc, &s, &err)) {
        fprintf(stderr, "test_session: %s\n", err.message);
        return 1;
    }
    const double secs = atof(argv[7]);
    ftm_client_view v;
    memset(&v, 0, sizeof v);
    int others_seen = 0, bad_own = 0, paused_views = 0, silent_banners = 0, paused_banners = 0;
    double paused_since = -1, resumed_at = -1, taken_at = -1;
    bool sent_pause = false, sent_resume = false, banner_after_resume = false;
    bool pause_answered = false, resume_answered = false; /* the server's replies in the view */
    for (double t = 0; t < secs; t = ftm_haptic_clock() - a.t0) {
        sleep_s(0.02);
        ftm_client_session_snapshot(s, &v);
        if (strstr(v.banner, "SILENT"))
            silent_banners++;
        if (taken_at < 0 && atomic_load(&a.taken))
            taken_at = t;
        /* (a view published before it may still be the newest for a moment) */
        if (strncmp(mode, "id", 2) == 0 && taken_at >= 0 && t - taken_at > 0.2 &&
            !atomic_load(&a.back)) {
            for (int32_t i = 0; i < v.nprobes; i++) {
                const ftm_client_probe *p = &v.probes[i];
                if (p->own)
                    bad_own++;
                if (p->participant == cc.id && p->in_contact &&
                    (p->force.x != 0 || p->force.y != 0 || p->force.z != 0))
                    others_seen++; /* the bot's reaction under our id: there to mistake */
            }
            if (v.own_force.x != 0 || v.own_force.y != 0 || v.own_force.z != 0 ||
                v.own_contact_ticks != 0 || v.own_peak_force != 0 || v.force_valid)
                bad_own++;
        }
        if (strcmp(mode, "pause") == 0) {
            ftm_wire_control c;
            memset(&c, 0, sizeof c);
            if (!sent_pause && v.synced_once && v.caught_up) {
                c.command = FTM_WIRE_CMD_PAUSE;
                CHECK(ftm_client_session_control(s, &c, c.command == FTM_WIRE_CMD_PAUSE ? "pause" : "resume", &err) == 0, "pause: %s", err.message);
                sent_pause = true;
            }
            if (v.paused) {
                paused_views++;
                if (paused_since < 0)
                    paused_since = t;
                if (strstr(v.banner, "PAUSED"))
                    paused_banners++;
            }
            /* held for 3 server timeouts, then resumed */
            if (!sent_resume && paused_since >= 0 && t - paused_since > 3 * cc.server_timeout) {
                c.command = FTM_WIRE_CMD_RESUME;
                CHECK(ftm_client_session_control(s, &c, c.command == FTM_WIRE_CMD_PAUSE ? "pause" : "resume", &err) == 0, "resume: %s", err.message);
                sent_resume = true;
            }
            if (sent_resume && !v.paused && resumed_at < 0)
                resumed_at = t;
            pause_answered |= strstr(v.outcome, "pause: applied after tick ") == v.outcome;
            resume_answered |= strstr(v.outcome, "resume: applied after tick ") == v.outcome;
            if (resumed_at >= 0 && t - resumed_at > 1.0 && v.banner[0])
                banner_after_resume = true;
        }
    }
    ftm_client_session_stop(s);
    ftm_haptic_destroy(a.hap);
    ftm_device_destroy(dev);
    ftm_device_destroy(a.inner);

    if (strcmp(mode, "idtaken") == 0) {
        CHECK(atomic_load(&a.taken), "the client never said its id is taken");
        CHECK(others_seen > 0, "no reaction of the other process seen: the test shows nothing");
        /* (a tick in flight when the force went off may still write one) */
        CHECK(atomic_load(&a.nonzero_after_taken) <= 2,
              "%d non-zero forces written to the device after the id was known taken",
              atomic_load(&a.nonzero_after_taken));
        CHECK(bad_own == 0, "%d views showed the other process's probe or figures as our own",
              bad_own);
    } else if (strcmp(mode, "idback") == 0) {
        CHECK(atomic_load(&a.taken), "the client never said its id is taken");
        CHECK(atomic_load(&a.back), "the client was not told the id is its own again after the "
                                    "holder left");
        CHECK(bad_own == 0, "%d views showed the other process's figures as our own while taken",
              bad_own);
        CHECK(v.force_valid, "the force did not come back with the id");
    } else if (strcmp(mode, "slow") == 0) {
        CHECK(v.synced_once, "never synced");
        CHECK(atomic_load(&a.frames) > 100, "only %d frames applied", atomic_load(&a.frames));
        CHECK(atomic_load(&a.lost_logged) == 0, "the client says it went silent while catching up");
    } else {
        CHECK(sent_pause && sent_resume && resumed_at >= 0, "pause/resume not seen");
        CHECK(pause_answered && resume_answered && !v.outcome_bad,
              "the server's replies to pause and resume were not in the view (last: '%s')",
              v.outcome);
        CHECK(paused_views > 0 && paused_banners > 0, "no PAUSED banner while paused");
        CHECK(silent_banners == 0, "%d views said SERVER SILENT during the pause", silent_banners);
        CHECK(atomic_load(&a.silent_logged) == 0, "\"no tick frames\" logged for a pause");
        CHECK(!banner_after_resume, "a banner stayed after the resume: '%s'", v.banner);
    }
    ftm_client_view_free(&v);
    if (failures)
        return 1;
    printf("PASS %s (%d frames)\n", mode, atomic_load(&a.frames));
    return 0;
}
