/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The participant core: what every participant of a session does, whatever
 * it shows (docs/protocol.md, "Writing a new client"; docs/design.md). One
 * core serves ftm-bot (bot/bot.c) and ftm-client's session thread
 * (client/client_session.c):
 *
 *   - the transport: a DDS participant with the topics of its role;
 *   - joining: the announcement is checked (the trust rule, claims.h), the
 *     scene loaded, the replica made (replica.h) and asked for a keyframe;
 *     a restarted server (another process) is rejoined;
 *   - statuses: JOINING for the first second, then the replica's state at
 *     once when it changes, and every 500 ms;
 *   - the server gone and back: a LEAVING status says it left; a `gone`
 *     event (its DDS lease expired) may be a stall of either side, and
 *     whatever the same process sends afterwards brings it back;
 *   - ids: what the server says of ours (taken, ours again, confirmed);
 *     probe input and force only under an id the server confirms;
 *   - commands: sent, remembered until the server's reply, reported.
 *
 * The program keeps what is its own (the bot's script and log, the client's
 * view and haptics) and hears of the rest through hooks. A core belongs to
 * one thread; ftm_participant_send_control may be called from any. */
#ifndef FTM_SESSION_PARTICIPANT_H
#define FTM_SESSION_PARTICIPANT_H

#include "claims.h"
#include "pending.h"
#include "replica.h"
#include "sessions.h"

#include "ftm/scene.h"
#include "ftm/wire.h"

/* What the program hears of. Every hook may be NULL; all run on the
 * core's thread (ftm_participant_turn), outcome also on the thread of
 * ftm_participant_send_control. */
typedef struct ftm_participant_hooks {
    /* Force must stop now (an id no longer confirmed, the server gone or
     * restarted, a scene that does not fit); why says which. */
    void (*force_off)(void *user, const char *why);
    /* The scene the replica runs on, loaded (by name: an id or a file). It
     * stays valid until ftm_participant_destroy, also after a restart. */
    void (*scene_loaded)(void *user, const ftm_scene *scene, const char *name);
    /* The session cannot be replayed: loading: the scene could not be
     * loaded; else the announcement does not fit it (err->code
     * FTM_EVERSION: another arithmetic revision, FTM_EINVAL: another
     * scene). Logged already. */
    void (*scene_refused)(void *user, bool loading, const char *name, const ftm_error *err);
    /* The server restarted (a new process): the replica starts afresh.
     * Not called for a server that resumed the same lesson (its
     * announcement's lesson start is the one before): the session goes
     * on, only the replica resyncs from its keyframe. */
    void (*restarted)(void *user);
    /* A tick frame from the server. taken_ns: the wall clock when this
     * thread took it, before the replica did; stepped: the replica's tick
     * moved; new_frame: ftm_replay_last_frame is a frame applied now. */
    void (*frame)(void *user, const ftm_wire_received *rx, int64_t taken_ns, bool stepped,
                  bool new_frame);
    /* A keyframe from the server, after the replica took it. */
    void (*keyframe)(void *user, bool stepped);
    /* A status, or a `gone` event, of any participant but this process's
     * id (from_server: of the server process this core follows). */
    void (*status)(void *user, const ftm_wire_received *rx, bool from_server);
    /* Probe input of the others (def.watch_probes). */
    void (*probe_input)(void *user, const ftm_wire_received *rx);
    /* What became of one of our commands (logged already): outcome an
     * FTM_WIRE_OUTCOME_*, or 0 when it went unanswered; known: it was
     * waiting (else a duplicate reply, or one the timeout gave up). */
    void (*outcome)(void *user, const char *text, int outcome, bool known);
} ftm_participant_hooks;

typedef struct ftm_participant_def {
    ftm_wire_role role;   /* trainee, instructor or observer */
    uint32_t id;          /* != 0 */
    uint32_t domain;
    const char *session;  /* NULL: "ftm" */
    const char *name;     /* display name in statuses; NULL: the role's name */
    const char *scene;    /* local scene (name or file); NULL: the announced id */
    const char *dds_config, *dds_security;
    bool watch_probes;    /* also read the others' probe input (hooks.probe_input) */
    /* estimate what a press on the scene feels like when it loads
     * (info.scene_feel): a person's client says a scene a hand cannot feel;
     * a bot need not spend the 0.05-0.5 s before its join */
    bool feel_check;
    bool hold;            /* stop taking frames at the first tick >= hold_tick */
    uint64_t hold_tick;
    ftm_log_fn log;       /* the core's messages; NULL: silent */
    void *log_user;
    ftm_participant_hooks hooks;
    void *hooks_user;
} ftm_participant_def;

/* What the core knows, for its program to read (on the core's thread). */
#define FTM_PARTICIPANT_PICK 9 /* sessions offered to pick from (keys 1..9) */

typedef struct ftm_participant_info {
    /* the server process followed (0 until its first announcement) */
    uint32_t server_id;
    uint64_t server_origin;
    uint64_t server_start;  /* its announced start (a restart changes it) */
    uint64_t lesson_start;  /* its announced lesson start (a resumed lesson keeps it) */
    bool have_ann;
    ftm_wire_announce ann;  /* its last announcement */
    /* left: a LEAVING status or a `gone` event; gone: by the event (its
     * lease expired), and anything the same process sends brings it back */
    bool server_left, server_gone;
    int64_t server_left_ns;
    /* after a `gone`, until its next announcement: whether it is the same
     * process or a restarted one is not known yet */
    bool need_announce;
    uint32_t restarts;      /* server restarts rejoined */
    uint32_t resumes;       /* of them, servers that resumed the same lesson */
    int64_t last_frame_ns;  /* monotonic: the last tick frame (or paused status) */
    uint64_t keyframes_heard, foreign;
    bool scene_failed;      /* the announced scene could not be loaded */
    /* ids: taken (the server hears another process under ours), held (it
     * confirms this one), the wait for that confirmation */
    bool id_taken, id_held, id_late;
    int64_t held_since_ns;
    bool synced, ever_synced; /* the replica is synced now; was once */
    /* no announcement for 3 s: the sessions the domain has (sessions.h),
     * looked for once, then every 30 s while none comes */
    bool sessions_scanned;
    char sessions_heard[192]; /* their names, quoted, comma-separated; "" none */
    /* what a press on the loaded scene feels like (ftm_scene_press_estimate
     * at FTM_PRESS_ESTIMATE_DEPTH): ftm_press_verdict (-1 far too soft, 1
     * far too stiff, 0 in or near palpation's range, or no estimate) and
     * the log's line ("" before a scene or without an estimate) */
    int scene_feel;
    char scene_feel_text[192];
    /* the announced ones among them, sorted by name, for a picker (the
     * client's waiting screen) */
    int32_t nsessions;
    ftm_session_seen sessions[FTM_PARTICIPANT_PICK];
} ftm_participant_info;

typedef struct ftm_participant ftm_participant;

/* The transport (publishing and reading what the role does) and the core;
 * nothing is sent yet (ftm_participant_join). */
int ftm_participant_create(const ftm_participant_def *def, ftm_participant **out, ftm_error *err);
/* Publishes the JOINING status: from now on the first second's statuses
 * say JOINING (what another process with our id hears of us first). */
void ftm_participant_join(ftm_participant *p);

/* One turn of the participant's loop: the announcement, statuses, probe
 * input, replies (and unanswered commands), a keyframe, then tick frames,
 * waiting up to wait_ns for the first and taking them for at most 10 ms.
 * Returns true if frames are left for the next turn. */
bool ftm_participant_turn(ftm_participant *p, int64_t wait_ns);
/* Whether the replica is held at def.hold_tick (it then takes nothing). */
bool ftm_participant_held(const ftm_participant *p);

/* The status the time calls for (JOINING in the first second after
 * joining, then the replica's state at once when it changes, and every
 * 500 ms); true if one was sent. */
bool ftm_participant_status_due(ftm_participant *p, int64_t now_ns);
/* Publishes LEAVING and writes out what is queued (up to 1 s). */
void ftm_participant_leave(ftm_participant *p);
void ftm_participant_destroy(ftm_participant *p);

/* Whether a trainee may send probe input (and render force) now: synced
 * once, the server there, our id confirmed ours. */
bool ftm_participant_id_ours(const ftm_participant *p);
bool ftm_participant_may_press(const ftm_participant *p);
/* Probe input (samples oldest first), when ftm_participant_may_press;
 * false if not sent. */
bool ftm_participant_send_probe(ftm_participant *p, const ftm_wire_probe_sample *samples, int n);

/* An instructor's command: issuer and command_id filled in, sent, and
 * waiting for its reply under the name what ("stiffness 80 N/m"). Any
 * thread. */
int ftm_participant_send_control(ftm_participant *p, ftm_wire_control *c, const char *what,
                                 ftm_error *err);
/* The oldest command still waiting, forgotten, its name into what (for a
 * program that stops); false when none waits. */
bool ftm_participant_pending_pop(ftm_participant *p, char *what, size_t cap);
int32_t ftm_participant_pending_count(ftm_participant *p);

const ftm_participant_info *ftm_participant_get_info(const ftm_participant *p);
ftm_replay *ftm_participant_replica(ftm_participant *p); /* NULL: none (yet) */
const ftm_scene *ftm_participant_scene(const ftm_participant *p);
ftm_wire_state ftm_participant_state(const ftm_participant *p); /* JOINING without a replica */
ftm_wire_transport *ftm_participant_wire(ftm_participant *p);

#endif
