/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The client's session thread ("replay" in the paper's Fig. 14): joins a
 * session over DDS, replays the server's tick frames with ftm_replay, sends
 * the trainee's probe input and the instructor's commands, watches for bad
 * input (a silent or departed server, a scene it cannot load, malformed
 * frames), and publishes what the render thread draws as a snapshot
 * (ftm_client_view) under a mutex: the render thread copies it and never
 * touches the simulation. */
#ifndef FTM_CLIENT_SESSION_H
#define FTM_CLIENT_SESSION_H

#include "ftm/scene.h"
#include "ftm/wire.h"
#include "pending.h" /* ftm_pending: commands waiting for their reply */
#include "tissue.h"  /* ftm_tissue_range: what the server accepts */

#define FTM_CLIENT_MAX_PROBES 64
#define FTM_CLIENT_MAX_PARTS 32
#define FTM_CLIENT_PICK 9 /* sessions the waiting screen offers (keys 1..9) */

/* This participant's probe 0 after each applied frame: its reaction in
 * that frame (NULL: not in contact, zero force), or valid = false when force
 * must stop (bad input, server gone, replica not synced; why says which).
 * tick_time: the tick's time on the server's session clock, tick / tick
 * rate [s] (frames arrive in bursts: their arrival times are no tick
 * spacing; ftm_haptic_timebase maps it). Called on the session thread; the
 * haptic loop takes it from here. */
typedef void (*ftm_client_force_fn)(void *user, uint64_t tick, double tick_time,
                                    const ftm_wire_reaction *reaction, bool valid, const char *why);

/* The trainee's HIP samples since the previous call (probe 0, oldest
 * first, device_time_ns set): the session thread sends them to the server
 * every millisecond. Returns how many were written (<= max). */
typedef int (*ftm_client_hip_fn)(void *user, ftm_wire_probe_sample *out, int max);

typedef struct ftm_client_config {
    ftm_wire_role role;
    const char *scene;   /* local scene override; NULL: the announced scene id */
    const char *session; /* default "ftm" */
    const char *dds_config;
    const char *dds_security; /* DDS Security bundle directory; NULL: none */
    uint32_t domain, id;
    const char *name;
    double server_timeout; /* [s] without tick frames before the server counts as gone */
    bool hold;             /* stop applying frames at the first tick >= hold_tick */
    uint64_t hold_tick;
    ftm_log_fn log;
    void *log_user;
    ftm_client_force_fn on_force;
    void *force_user;
    ftm_client_hip_fn take_hips; /* trainee; NULL: no probe input */
    void *hip_user;
} ftm_client_config;

typedef struct ftm_client_probe {
    uint32_t participant;
    int32_t probe;
    bool own;         /* this client's probe (its HIP is the render thread's to fill in) */
    bool have_hip;    /* HIP position known (trainees publish it) */
    ftm_vec3 hip;
    bool in_contact;  /* a contact group with a reaction in the last frame */
    ftm_vec3 contact; /* centroid of the group's contact nodes, current positions */
    ftm_vec3 force;   /* reaction force [N] */
    bool push_limited; /* the server shortened its push to the limit (HIP too deep) */
    /* the contact's rest-surface point where it began and outward normal
     * (the server's release rule: the HIP back on this plane's outside) */
    bool has_plane;
    ftm_vec3 plane_point, plane_normal;
} ftm_client_probe;

typedef struct ftm_client_part {
    uint32_t id;
    ftm_wire_role role;
    ftm_wire_state state;
    uint64_t tick;
    char name[FTM_WIRE_DISPLAY_MAX];
    /* a trainee's probe 0 as the frames received so far show it (report.h):
     * time in contact and the peak reaction force */
    uint64_t contact_ticks, peak_tick;
    double peak_force;
    bool peak_unstable; /* the peak came while the guard substepped (report.h) */
    bool left; /* gone, its row kept for those figures (parts.h) */
} ftm_client_part;

/* What the render thread draws. Arrays are owned by the view. */
typedef struct ftm_client_view {
    uint64_t version;      /* changes whenever anything below does */
    const ftm_mesh *mesh;  /* NULL until the scene is loaded; lives as long as the session */
    /* the scene's volume and its embedding in mesh (NULL: none; as long) */
    const ftm_volume *volume;
    const ftm_ffd *ffd;
    ftm_scene_tool tool; /* the scene's [tool]; zeros: none given */
    const ftm_scene *scene; /* the scene itself (its label names, materials; as long) */
    char scene_name[FTM_WIRE_NAME_MAX];
    int32_t node_count;
    double *pos; /* 3 * node_count, the replica's positions */
    int32_t pos_cap;

    bool announced, synced_once, paused;
    ftm_wire_state state;
    uint64_t tick;        /* last applied tick */
    int32_t depth;        /* depth the server chose for that tick */
    int32_t depth_min, depth_max;
    uint32_t rate_hz;
    ftm_wire_tissue tissue;
    /* the scene's own tissue (instructor's restore key), the stable range
     * around the one in force (session/tissue.h: what the server accepts)
     * and the substeps per step the replica, as the server, takes now */
    ftm_wire_tissue scene_tissue;
    bool range_valid;
    ftm_tissue_range range;
    int32_t substeps;
    int64_t lag_ticks;    /* server's tick now (estimated) - applied tick */
    double latency_ms;    /* server write -> received, last frame */
    bool caught_up;       /* synced, every frame received so far applied */
    uint64_t contact_ticks; /* consecutive applied ticks with a contact */

    int32_t nprobes;
    ftm_client_probe probes[FTM_CLIENT_MAX_PROBES];
    int32_t nparts;
    ftm_client_part parts[FTM_CLIENT_MAX_PARTS];
    bool parts_unlisted;  /* more participants than parts holds are in the session */

    int32_t region_count; /* nodes of the active BFS region */
    int32_t *region;
    int32_t region_cap;

    bool force_valid;     /* false: force dropped to zero (bad input) */
    ftm_vec3 own_force;
    uint64_t own_contact_ticks; /* a trainee's own probe 0, as ftm_client_part's figures */
    double own_peak_force;
    char banner[256];     /* empty: all well */
    bool banner_error;
    /* the server left or went silent: commands would not be heard */
    bool server_away;
    /* instructor: what became of the latest command (the server's reply, or
     * none within FTM_REPLY_TIMEOUT_NS); outcome_seq counts them (0: none yet) */
    char outcome[FTM_OUTCOME_TEXT];
    bool outcome_bad; /* refused or unanswered */
    uint64_t outcome_seq;

    uint64_t frames, mismatches, resyncs, rejected;
    /* no server announces our session: the sessions that are announced on
     * the domain (looked for after 3 s, then every 30 s), for the waiting
     * screen's picker; nsessions 0: none heard (or not looked yet) */
    int32_t nsessions;
    char sessions[FTM_CLIENT_PICK][64];
    char sessions_about[FTM_CLIENT_PICK][80]; /* "scene palpation, 1 trainee" */
} ftm_client_view;

typedef struct ftm_client_session ftm_client_session;

/* Creates the DDS transport and starts the session thread. */
int ftm_client_session_start(const ftm_client_config *cfg, ftm_client_session **out,
                             ftm_error *err);
/* Publishes LEAVING, stops the thread, frees everything. NULL is fine. */
void ftm_client_session_stop(ftm_client_session *s);

/* Copies the shared view into *dst if it changed since dst->version;
 * returns true if it did. dst starts zeroed; free with ftm_client_view_free. */
bool ftm_client_session_snapshot(ftm_client_session *s, ftm_client_view *dst);
void ftm_client_view_free(ftm_client_view *v);

/* Whether to collect the active BFS region for the view (costs a copy). */
void ftm_client_session_want_region(ftm_client_session *s, bool on);

/* Instructor: publishes a session command (issuer and command_id are
 * filled in) and waits for the server's reply to it, which the session
 * thread logs and puts in the view (outcome) under the name `what` ("stiffness
 * 80 N/m"). Any thread. */
int ftm_client_session_control(ftm_client_session *s, ftm_wire_control *c, const char *what,
                               ftm_error *err);

#endif
