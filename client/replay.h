/* Deterministic replay of a session's tick frames (docs/protocol.md,
 * "Ticks, heartbeats and replay").
 *
 * A replica holds its own copy of the scene and applies the server's tick
 * frames with libftm exactly as the server ran them (ftm_replay_step: set
 * depth, set contacts, step), checks the frame's state hash after every
 * tick, finds lost frames from the envelope's sequence gaps, and resyncs from
 * a keyframe when it can no longer be trusted. Used by ftm-bot and, later,
 * the GL client; the server uses ftm_replay_step, ftm_replay_sim_def and
 * ftm_replay_scene_digest so both sides run the same code.
 *
 * Library ftm_replay: libftm + ftm_wire, no GL, no threads of its own. One
 * thread per ftm_replay. */
#ifndef FTM_CLIENT_REPLAY_H
#define FTM_CLIENT_REPLAY_H

#include "ftm/scene.h"
#include "ftm/wire.h"

#ifdef __cplusplus
extern "C" {
#endif

#define FTM_REPLAY_DIGEST_SIZE 32

/* The simulation definition a session runs a scene with (server and every
 * replica): the scene's, without its log callback. Region sleep included:
 * keyframes carry the contacts and the integrator's mode, so a replica
 * restores a sleeping region as it is (docs/protocol.md). */
ftm_sim_def ftm_replay_sim_def(const ftm_scene *scene);

/* SHA-256 over a canonical encoding of what determines the dynamics: the
 * mesh as built (rest positions, masses, damping, fixed flags, adjacency with
 * stiffness and rest lengths, surface triangles) and the session's sim
 * definition. Two peers with equal digests replay bit-identically. */
void ftm_replay_scene_digest(const ftm_scene *scene, uint8_t out[FTM_REPLAY_DIGEST_SIZE]);

/* SHA-256 of arbitrary bytes (FIPS 180-4). */
void ftm_sha256(const void *data, size_t size, uint8_t out[32]);

/* One tick, exactly as the server runs it: ftm_sim_set_depth(depth),
 * ftm_sim_set_contacts(contacts), ftm_sim_step(). */
int ftm_replay_step(ftm_sim *sim, int32_t depth, const ftm_contact *contacts, int32_t count,
                    ftm_error *err);

/* ---- tissue parameters (docs/protocol.md, "Tissue parameters") ----
 * The instructor may change the tissue's mass, damping and stiffness during a
 * session. The server and every replica then switch their simulation to a
 * mesh with the new material (ftm_mesh_with_material, always made from the
 * scene's own mesh, so it depends on the parameters alone), at the same tick:
 * the tick frame of that tick carries the parameters, keyframes carry the
 * ones in force. */

/* The scene's own parameters (its [material]). */
ftm_wire_tissue ftm_replay_scene_tissue(const ftm_scene *scene);

/* The material a simulation of a scene runs with. Zero-initialise, set scene. */
typedef struct ftm_replay_material {
    const ftm_scene *scene;
    bool changed;           /* current differs from the scene's */
    ftm_wire_tissue current; /* valid when changed */
    ftm_mesh *mesh;         /* the mesh of current (owned); NULL: the scene's mesh */
} ftm_replay_material;

/* Switches sim (a simulation of mat->scene's mesh or one made by an earlier
 * call) to tissue t (NULL: the scene's own); takes effect at its next step.
 * No-op when t is already in force. On error (invalid parameters, a material
 * too stiff for the time step, element forces, out of memory) nothing
 * changes and err says why. */
int ftm_replay_set_tissue(ftm_replay_material *mat, ftm_sim *sim, const ftm_wire_tissue *t,
                          ftm_error *err);
/* The parameters in force. */
ftm_wire_tissue ftm_replay_tissue_now(const ftm_replay_material *mat);
/* Frees the mesh; only after the simulation is destroyed. */
void ftm_replay_material_free(ftm_replay_material *mat);

/* The keyframe message of a simulation's current state: nodes not at rest,
 * contacts, mode, and the tissue of mat when it differs from the scene's
 * (mat NULL: the scene's). Arrays are malloc'ed into *out (free with
 * ftm_replay_keyframe_free). */
int ftm_replay_make_keyframe(const ftm_sim *sim, const ftm_replay_material *mat,
                             ftm_wire_keyframe *out, ftm_error *err);
void ftm_replay_keyframe_free(ftm_wire_keyframe *k);

typedef struct ftm_replay ftm_replay;

typedef struct ftm_replay_stats {
    uint64_t frames_received;  /* tick frames handed to ftm_replay_on_tick */
    uint64_t frames_applied;   /* frames stepped (re-applications included) */
    uint64_t idle_ticks;       /* ticks the server did not send (idle), stepped here */
    uint64_t stale_frames;     /* frames at or before the current tick, ignored */
    uint64_t rule_breaks;      /* frames that broke the idle rule: dropped, resync */
    uint64_t mismatches;       /* hash mismatches */
    uint64_t gaps;             /* frames with a sequence gap */
    uint64_t resyncs;          /* times the replica entered RESYNCING */
    uint64_t keyframes_loaded; /* keyframes restored */
    uint64_t keyframes_unusable; /* keyframes that could not be continued from */
    double replay_ns_total;    /* time spent in ftm_replay_step */
    double replay_ns_max;      /* worst ftm_replay_step since ftm_replay_take_max */
} ftm_replay_stats;

/* The replica of scene (which must outlive it). log may be NULL. */
int ftm_replay_create(const ftm_scene *scene, ftm_log_fn log, void *log_user, ftm_replay **out,
                      ftm_error *err);
void ftm_replay_destroy(ftm_replay *r);

/* Checks an announcement against this build and the local scene: the
 * server core's arithmetic revision (FTM_EVERSION if it is not this
 * build's: hashes could never match), then the scene's digest, node count
 * and time step (FTM_EINVAL). A message names the mismatch. */
int ftm_replay_check_announce(const ftm_replay *r, const ftm_wire_announce *a, ftm_error *err);

/* Whether our participant id is ours, from a status of the server. The
 * server hears an id only from the first process it heard with it, until
 * that one leaves or is lost; its statuses list the other processes that
 * use the id (ftm_wire_status.ignored_*, by origin), as long as they are
 * heard. So a server's status that lists our id with our origin
 * (ftm_wire_transport_origin) says our id is TAKEN: the server ignores us.
 * Once TAKEN, the first server status that does not list us says the id
 * is OURS_AGAIN (the holder left, the server now hears us). One that lists
 * our id with another origin says a NEWCOMER uses it and is ignored. Each
 * is said once per change (*told, zeroed at the start and when another
 * server is joined); anything else says NOTHING. The server decides, not
 * the order in which the processes heard each other, so two processes
 * started together agree with it. */
typedef enum ftm_id_claim {
    FTM_ID_NOTHING = 0,
    FTM_ID_TAKEN,
    FTM_ID_NEWCOMER,
    FTM_ID_OURS_AGAIN,
} ftm_id_claim;
typedef struct ftm_id_told {
    bool taken, newcomer;
} ftm_id_told;
ftm_id_claim ftm_replay_id_verdict(ftm_id_told *told, const ftm_wire_status *server_status,
                                   uint32_t own_id, uint64_t own_origin);

/* Whether a status of the server lists us among the processes it listens
 * to (ftm_wire_status.holder_*: our id with our origin): the positive
 * confirmation that it hears this process under our id. Until the newest
 * server status says so, a trainee sends no probe input and renders no
 * force: before the server has heard us, the reaction under our id may be
 * another process's, and "not listed as ignored" proves nothing. Servers
 * before the list existed never confirm (docs/protocol.md). */
bool ftm_replay_id_held(const ftm_wire_status *server_status, uint32_t own_id,
                        uint64_t own_origin);

/* The server confirms our id in a status sent the moment it first hears us
 * (statuses are reliable, transient-local): on loopback it comes with the
 * sync, ~12 ms after the start. Without it for this long [ns] the server
 * will not confirm (one older than the confirmation) or does not hear us:
 * ftm-client and ftm-bot say so. */
#define FTM_ID_CONFIRM_WAIT_NS 3000000000LL

/* Whether rx comes from the server process a client follows: *id and
 * *origin (0 until the first announcement, which sets them) name it. Any
 * participant can write on any topic under any id (DDS has no
 * authentication here), so a replica must not step frames, nor a trainee
 * take its id's confirmation, from whoever sends them: only the process
 * whose announcement came first, by id and origin (the hash of its DDS
 * participant GUID), counts. A new process under that id is followed from
 * its announcement once the one followed has left or is gone (server_left:
 * a restarted server); the caller's on_announce tells the two apart. */
bool ftm_replay_from_server(uint32_t *id, uint64_t *origin, const ftm_wire_received *rx,
                            bool server_left);


/* A received tick frame (r->msg.kind == FTM_WIRE_TICK). Synced: applies it
 * (after stepping any ticks the server left out as idle), checks the hash;
 * a sequence gap or a mismatch switches to RESYNCING. Not synced: keeps it
 * for after the keyframe. Returns FTM_OK or FTM_ENOMEM. */
int ftm_replay_on_tick(ftm_replay *r, const ftm_wire_received *rx);

/* A received keyframe. Not synced: restores it if the frames received since
 * can continue it, and applies those; synced: checks it against the state
 * at its tick and restores it if the server's state differs (reset). */
int ftm_replay_on_keyframe(ftm_replay *r, const ftm_wire_keyframe *k);

ftm_wire_state ftm_replay_state(const ftm_replay *r);
uint64_t ftm_replay_tick(const ftm_replay *r);   /* last applied tick */
uint64_t ftm_replay_hash(const ftm_replay *r);   /* ftm_sim_hash now */
/* Server tick and hash of the last frame applied (hash is what the server
 * said; equal to ftm_replay_hash when synced). */
const ftm_wire_tick *ftm_replay_last_frame(const ftm_replay *r);
void ftm_replay_get_stats(const ftm_replay *r, ftm_replay_stats *stats);
/* Returns replay_ns_max and starts a new maximum (per status period). */
double ftm_replay_take_max(ftm_replay *r);
ftm_sim *ftm_replay_sim(ftm_replay *r);
/* The tissue parameters the replica's simulation runs with now. */
ftm_wire_tissue ftm_replay_tissue(const ftm_replay *r);

/* The reaction of one probe (participant, probe index) in a tick frame, e.g.
 * ftm_replay_last_frame(r): with the server's local force model when it sent
 * one (out->has_model: F(x) = force + stiffness (x - hip), for
 * FTM_HAPTIC_FORCE_MODEL in haptic.h). false if the frame has no reaction
 * for it (the probe is not in contact: zero force). */
static inline bool ftm_replay_find_reaction(const ftm_wire_tick *t, uint32_t participant,
                                            int32_t probe, ftm_wire_reaction *out)
{
    for (int32_t i = 0; t && i < t->reaction_count; i++) {
        if (t->reactions[i].participant == participant && t->reactions[i].probe == probe) {
            *out = t->reactions[i];
            return true;
        }
    }
    return false;
}

/* ---- an instructor's commands and the server's replies (ControlReply) ----
 * ftm-client and ftm-bot remember each SessionControl they sent until the
 * server's reply to it arrives (docs/protocol.md): a command with no reply
 * within FTM_REPLY_TIMEOUT_NS (lost while no server listened, e.g. across a
 * server restart) is reported as unanswered, never forgotten silently. */
#define FTM_PENDING_MAX 64
#define FTM_PENDING_WHAT 96
#define FTM_REPLY_TIMEOUT_NS (3 * 1000000000LL)
/* room for any outcome text below */
#define FTM_OUTCOME_TEXT (FTM_PENDING_WHAT + FTM_WIRE_REASON_MAX + 64)

typedef struct ftm_pending_cmd {
    uint64_t id;
    int64_t sent_ns;
    char what[FTM_PENDING_WHAT]; /* e.g. "stiffness 80 N/m" */
} ftm_pending_cmd;

typedef struct ftm_pending {
    ftm_pending_cmd cmd[FTM_PENDING_MAX]; /* oldest first */
    int32_t n;
} ftm_pending;

/* Remembers a command just sent. With FTM_PENDING_MAX waiting (a server
 * that never answers), the oldest is given up first: written to text as
 * unanswered, and true returned (else false, text empty). */
bool ftm_pending_add(ftm_pending *p, uint64_t id, const char *what, int64_t now_ns, char *text,
                     size_t cap);

/* Forgets a command (one that could not be sent after all). */
void ftm_pending_forget(ftm_pending *p, uint64_t id);

/* A reply addressed to us: writes what became of the command, "stiffness 80
 * N/m: applied at tick 1234", "...: changed at tick T: REASON", "...:
 * refused: REASON", and forgets the command. A reply to no pending command
 * (a duplicate, or one the timeout gave up) still gets a text, naming the
 * command by its id; returns false then. */
bool ftm_pending_reply(ftm_pending *p, const ftm_wire_control_reply *r, char *text, size_t cap);

/* The oldest command sent more than timeout_ns before now and still without
 * a reply: forgotten, and "WHAT: no reply from the server in 3 s" written to
 * text. false when there is none. */
bool ftm_pending_expired(ftm_pending *p, int64_t now_ns, int64_t timeout_ns, char *text,
                         size_t cap);

#ifdef __cplusplus
}
#endif
#endif
