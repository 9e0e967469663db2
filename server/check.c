/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-server --check (docs/deploy.md): everything a session needs is set
 * up as for the session, the rest tried without starting it, and what the
 * session would be is printed: exit 0 if it would start, 3 if not. For an
 * ExecStartPre= of the service and for whoever writes its options. */
#define _GNU_SOURCE /* pthread_setaffinity_np */
#include "rooms.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Whether a file may be created in the directory of `path` (dir: path is the
 * directory itself); a reason in `why` if not. */
static bool can_create_in(const char *path, bool dir, char *why, size_t cap)
{
    char d[1024];
    snprintf(d, sizeof d, "%s", path);
    if (!dir) {
        char *slash = strrchr(d, '/');
        if (!slash)
            snprintf(d, sizeof d, ".");
        else if (slash == d)
            d[1] = '\0';
        else
            *slash = '\0';
    }
    struct stat st;
    if (stat(d, &st) != 0) {
        snprintf(why, cap, "%s: %s", d, strerror(errno));
        return false;
    }
    if (!S_ISDIR(st.st_mode)) {
        snprintf(why, cap, "%s: not a directory", d);
        return false;
    }
    if (access(d, W_OK | X_OK) != 0) {
        snprintf(why, cap, "%s: %s", d, strerror(errno));
        return false;
    }
    return true;
}

/* The scene, the session and whether another server serves it already
 * (its status comes within a status period); returns the failures. */
static int check_session(server *s)
{
    int bad = 0;
    printf("scene       %s", s->o.scene);
    if (strcmp(s->scene_path, s->o.scene) != 0)
        printf(" (%s)", s->scene_path);
    printf(": %d nodes\ndigest      ", (int)ftm_mesh_node_count(s->mesh));
    for (int i = 0; i < FTM_REPLAY_DIGEST_SIZE; i++)
        printf("%02x", s->digest[i]);
    printf(" (every participant must load a scene with this digest)\n");
    printf("session     '%s' on DDS domain %u, participant id %u, configuration %s\n",
           s->o.session, s->o.domain, s->o.id,
           s->o.config ? s->o.config : getenv("CYCLONEDDS_URI") ? getenv("CYCLONEDDS_URI")
                                                                : "Cyclone's default");
    if (s->o.security)
        printf("security    DDS Security with the identity in %s (checked)\n", s->o.security);
    const uint64_t until = srv_now() + 700000000u;
    for (uint64_t now = srv_now(); now < until; now = srv_now()) {
        ftm_wire_received rx;
        if (ftm_wire_receive(s->pub.wire, FTM_WIRE_STATUS, &rx, (int64_t)(until - now), NULL))
            break;
        const bool server_role = !rx.gone && rx.msg.u.status.role == FTM_WIRE_ROLE_SERVER;
        if (server_role) {
            printf("session     FAILS: already served by another ftm-server ('%s', at tick "
                   "%" PRIu64 ")\n", rx.msg.u.status.name, rx.msg.u.status.last_applied_tick);
            bad++;
        }
        ftm_wire_received_free(&rx);
        if (server_role)
            break;
    }
    printf("ticks       %.0f Hz, depth %d, adaptive %s (range %d..%d), keyframe every %g s\n",
           s->o.rate, (int)s->tk.depth, s->o.adaptive ? "on" : "off", (int)s->per.ctl.def.floor,
           (int)s->per.ctl.def.max, s->o.keyframe_every);
    if (isfinite(s->tk.max_push))
        printf("push limit  %.4g m\n", s->tk.max_push);
    else
        printf("push limit  none\n");
    return bad;
}

/* Where recordings, logs and the report go, and the metrics' address
 * (listened on, then closed); returns the failures. */
static int check_outputs(server *s)
{
    int bad = 0;
    char why[1200];
    struct {
        const char *what, *path;
        bool dir;
    } files[] = {{"recording", s->o.record_dir ? s->o.record_dir : s->o.record, s->o.record_dir != NULL},
                 {"control log", s->o.control_log, false},
                 {"report", s->o.report, false},
                 {"log", s->o.log_path, false}};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        if (!files[i].path)
            continue;
        struct stat st;
        if (!files[i].dir && stat(files[i].path, &st) == 0 && S_ISDIR(st.st_mode)) {
            printf("%-11s FAILS: %s is a directory, not a file\n", files[i].what, files[i].path);
            bad++;
        } else if (can_create_in(files[i].path, files[i].dir, why, sizeof why)) {
            printf("%-11s %s%s\n", files[i].what, files[i].path,
                   files[i].dir ? "/ (a new file per run)" : "");
        } else {
            printf("%-11s FAILS: cannot create files in %s\n", files[i].what, why);
            bad++;
        }
    }
    if (s->o.metrics_port > 0) {
        ftm_error err = {0, ""};
        ftm_metrics *m = NULL;
        if (ftm_metrics_start(s->o.metrics_addr, (uint16_t)s->o.metrics_port, &m, &err)) {
            printf("metrics     FAILS: %s\n", err.message);
            bad++;
        } else {
            char url[128];
            srv_metrics_url(&s->o, url, sizeof url);
            printf("metrics     %s (listened, then closed)\n", url);
            ftm_metrics_stop(m);
        }
    }
    return bad;
}

/* Whether real-time scheduling and the CPU asked for are permitted (tried,
 * then undone); said, never a failure: the server would run without. */
static void check_realtime(server *s)
{
    struct sched_param sp = {.sched_priority = s->o.rt_priority}, was;
    int policy, e = pthread_getschedparam(pthread_self(), &policy, &was);
    if (!e)
        e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (e) {
        printf("real-time   not permitted (%s): the tick thread would run at default "
               "scheduling\n", strerror(e));
    } else {
        pthread_setschedparam(pthread_self(), policy, &was);
        printf("real-time   SCHED_FIFO priority %d permitted\n", (int)s->o.rt_priority);
    }
    /* tried, not read off the affinity mask: taskset's mask is where a
     * process starts, not a limit; a cpuset or a CPU that is not there is */
    cpu_set_t given, one;
    if (s->o.rt_cpu >= 0 && !pthread_getaffinity_np(pthread_self(), sizeof given, &given)) {
        CPU_ZERO(&one);
        CPU_SET(s->o.rt_cpu, &one);
        int pe = pthread_setaffinity_np(pthread_self(), sizeof one, &one);
        pthread_setaffinity_np(pthread_self(), sizeof given, &given);
        if (pe)
            printf("real-time   cpu %d not permitted (%s): the tick thread would run on no "
                   "CPU in particular\n", (int)s->o.rt_cpu, strerror(pe));
        else
            printf("real-time   cpu %d permitted\n", (int)s->o.rt_cpu);
    }
}

int srv_check_setup(server *s)
{
    int bad = check_session(s);
    bad += check_outputs(s);
    if (s->o.rt_priority > 0)
        check_realtime(s);
    printf("ftm-server --check: %s\n", bad ? "the session would NOT start" : "ok");
    fflush(stdout);
    return bad ? 3 : 0;
}
