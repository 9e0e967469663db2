/* SPDX-License-Identifier: GPL-3.0-or-later */
/* FTM wire layer: the protocol codec (protobuf, proto/ftm.proto) and the DDS
 * transport (Cyclone DDS, one topic per message kind). docs/protocol.md is
 * the protocol's reference; this header is the C API over it.
 *
 * Library ftm_wire, beside libftm: the physics core has no wire formats or
 * DDS in it. From the core this layer uses only ftm/base.h (errors, vectors)
 * and the ftm_contact type, so a tick frame's contacts go straight into
 * ftm_sim_set_contacts().
 *
 * Errors follow ftm/base.h: a negative FTM_E* code (its list holds the wire's
 * codes too) and an ftm_error message naming the message kind, the
 * field or byte offset and the problem, e.g.
 *   "tick frame: contact 3: node 912 out of range (scene has 400 nodes)".
 * Bad input from a peer is never fatal: it is rejected with such a message. */
#ifndef FTM_WIRE_H
#define FTM_WIRE_H

#include "ftm/base.h"
#include "ftm/sim.h" /* ftm_contact */

#ifdef __cplusplus
extern "C" {
#endif

/* Protocol version carried in every message (package ftm.v1). */
#define FTM_WIRE_VERSION 1u

/* The wire's error codes (FTM_ETOOBIG, FTM_EBUDGET, FTM_EVERSION,
 * FTM_ETIMEDOUT, FTM_EDDS, FTM_EAGAIN, FTM_EACCESS) are in the one list of
 * ftm/base.h, which ftm_strerror and ftm_err_name know. */

/* The same as ftm_strerror; kept for callers from before the one list. */
const char *ftm_wire_strerror(int code);

/* Message kinds; the values are ftm.v1.Kind and Envelope.kind. */
typedef enum ftm_wire_kind {
    FTM_WIRE_ANNOUNCE = 1,    /* SceneAnnounce: server -> all */
    FTM_WIRE_PROBE_INPUT = 2, /* ProbeInput: trainee -> server */
    FTM_WIRE_TICK = 3,        /* TickFrame: server -> all */
    FTM_WIRE_KEYFRAME = 4,    /* Keyframe: server -> late joiners, resync */
    FTM_WIRE_STATUS = 5,      /* ParticipantStatus: everyone -> all */
    FTM_WIRE_CONTROL = 6,     /* SessionControl: instructor -> server */
    FTM_WIRE_CONTROL_REPLY = 7, /* ControlReply: server -> all (the issuer reads it) */
} ftm_wire_kind;
#define FTM_WIRE_KIND_MIN 1
#define FTM_WIRE_KIND_MAX 7
#define FTM_WIRE_KIND_BIT(k) (1u << (k))
#define FTM_WIRE_ALL_KINDS 0xfeu

/* "tick frame", "keyframe", ...; "unknown kind" for anything else. */
const char *ftm_wire_kind_name(int kind);

/* ---- Messages --------------------------------------------------------- */

#define FTM_WIRE_NAME_MAX 128      /* scene id incl. NUL */
#define FTM_WIRE_DIGEST_MAX 64     /* content digest bytes */
#define FTM_WIRE_DISPLAY_MAX 64    /* participant display name incl. NUL */
#define FTM_WIRE_SAMPLES_MAX 4096  /* probe samples per ProbeInput */
/* Most ticks one tick frame may be ahead of the one before it. The server
 * sends a frame at least every 10 s (its --heartbeat limit) at <= 100 kHz;
 * this is twice that. Replicas and the replay of a recording step every
 * skipped tick (~0.2 us at rest), so the bound also caps what a forged
 * frame or recording entry costs them. */
#define FTM_WIRE_MAX_TICK_GAP 2000000u
#define FTM_WIRE_REACTIONS_MAX 4096
#define FTM_WIRE_IGNORED_MAX 16 /* ignored processes in a server's status */
#define FTM_WIRE_HOLDERS_MAX 64 /* processes listened to, in a server's status */

typedef struct ftm_wire_tissue {
    double node_mass;    /* [kg] > 0 */
    double node_damping; /* [N s/m] >= 0 */
    double stiffness;    /* [N/m] > 0 */
    ftm_vec3 axis_scale; /* > 0 each */
} ftm_wire_tissue;

typedef struct ftm_wire_announce {
    char scene_id[FTM_WIRE_NAME_MAX];
    uint8_t digest[FTM_WIRE_DIGEST_MAX];
    int32_t digest_len; /* 1..FTM_WIRE_DIGEST_MAX */
    uint32_t tick_rate_hz; /* > 0 */
    double time_step;      /* [s] > 0 */
    int32_t depth;
    int32_t depth_min, depth_max;
    ftm_wire_tissue tissue;
    int32_t node_count; /* > 0 */
    uint64_t tick;
    bool paused;
    uint64_t server_start_ns; /* the server process's start (its incarnation); 0: not sent */
    uint32_t arithmetic; /* the server core's ftm_arithmetic_revision(); 0: not sent (revision 1) */
    uint64_t lesson_start_ns; /* when the lesson began (a resumed server: not its own start); 0: not sent */
} ftm_wire_announce;

typedef struct ftm_wire_probe_sample {
    int32_t probe;
    uint64_t device_time_ns;
    ftm_vec3 position;
} ftm_wire_probe_sample;

typedef struct ftm_wire_probe_input {
    uint32_t participant;
    uint64_t last_tick_seen;
    int32_t sample_count; /* 0..FTM_WIRE_SAMPLES_MAX */
    ftm_wire_probe_sample *samples;
} ftm_wire_probe_input;

typedef struct ftm_wire_reaction {
    int32_t group;
    uint32_t participant;
    int32_t probe;
    ftm_vec3 force;
    /* local force model (docs/haptics.md): F(x) = force + stiffness (x - hip) */
    bool has_model;        /* hip and stiffness below are valid */
    ftm_vec3 hip;          /* [m] the HIP the force was computed for */
    double stiffness[9];   /* dF/dx [N/m], row-major */
    /* the contact's plane: released when (x - contact_point) . contact_normal >= 0 */
    bool has_plane;           /* contact_point and contact_normal are valid */
    ftm_vec3 contact_point;   /* [m] rest coordinates */
    ftm_vec3 contact_normal;  /* outward, unit length */
    /* the HIP is beyond the server's push limit: the push was shortened (and
     * has_model is false: the force does not follow the HIP) */
    bool push_limited;
} ftm_wire_reaction;

typedef struct ftm_wire_tick {
    uint64_t tick;
    int32_t depth;
    int32_t contact_count;
    ftm_contact *contacts; /* node, group, kind, value */
    int32_t reaction_count; /* 0..FTM_WIRE_REACTIONS_MAX */
    ftm_wire_reaction *reactions;
    uint64_t state_hash;
    uint64_t send_time_ns; /* server CLOCK_REALTIME at publish; 0: absent */
    /* tissue parameters changed by the instructor: in force from this tick's
     * step on (applied before it); absent on every other tick */
    bool has_tissue;
    ftm_wire_tissue tissue;
} ftm_wire_tick;

typedef struct ftm_wire_keyframe {
    uint64_t tick;
    uint64_t state_hash;
    int32_t node_count; /* mesh nodes */
    int32_t depth;
    int32_t count;      /* nodes not at rest */
    int32_t *nodes;     /* count, strictly ascending */
    double *positions;  /* 3 * count */
    double *previous;   /* 3 * count */
    /* the tissue parameters in force after this tick; absent: the scene's */
    bool has_tissue;
    ftm_wire_tissue tissue;
    /* the integrator's mode after this tick; absent: ftm_sim_load_state's default */
    bool has_mode;
    ftm_sim_mode mode;
    int32_t contact_count; /* the contacts of this tick */
    ftm_contact *contacts;
} ftm_wire_keyframe;

typedef enum ftm_wire_role {
    FTM_WIRE_ROLE_SERVER = 1,
    FTM_WIRE_ROLE_TRAINEE = 2,
    FTM_WIRE_ROLE_INSTRUCTOR = 3,
    FTM_WIRE_ROLE_OBSERVER = 4,
    FTM_WIRE_ROLE_BOT = 5,
} ftm_wire_role;

typedef enum ftm_wire_state {
    FTM_WIRE_STATE_JOINING = 1,
    FTM_WIRE_STATE_SYNCED = 2,
    FTM_WIRE_STATE_RESYNCING = 3,
    FTM_WIRE_STATE_LEAVING = 4,
} ftm_wire_state;

typedef struct ftm_wire_status {
    uint32_t participant;
    ftm_wire_role role;
    ftm_wire_state state;
    uint64_t last_applied_tick;
    uint64_t state_hash;
    double replay_ns_per_tick; /* >= 0 */
    double replay_ns_max;      /* >= 0 */
    char name[FTM_WIRE_DISPLAY_MAX];
    /* The server's status only: processes it ignores because another holds
     * their participant id, by id and origin (ftm_wire_received.origin,
     * ftm_wire_transport_origin). */
    int32_t ignored_count; /* 0..FTM_WIRE_IGNORED_MAX */
    uint32_t ignored_participant[FTM_WIRE_IGNORED_MAX];
    uint64_t ignored_origin[FTM_WIRE_IGNORED_MAX];
    /* The server's status only: the process it listens to under each id it
     * holds, by id and origin; each id at most once. */
    int32_t holder_count; /* 0..FTM_WIRE_HOLDERS_MAX */
    uint32_t holder_participant[FTM_WIRE_HOLDERS_MAX];
    uint64_t holder_origin[FTM_WIRE_HOLDERS_MAX];
} ftm_wire_status;

typedef enum ftm_wire_command {
    FTM_WIRE_CMD_PAUSE = 1,
    FTM_WIRE_CMD_RESUME = 2,
    FTM_WIRE_CMD_RESET = 3,
    FTM_WIRE_CMD_TISSUE = 4,       /* uses tissue */
    FTM_WIRE_CMD_DEPTH_LIMITS = 5, /* uses depth_min, depth_max */
} ftm_wire_command;

typedef struct ftm_wire_control {
    uint32_t issuer;
    uint64_t command_id;
    ftm_wire_command command;
    ftm_wire_tissue tissue;
    int32_t depth_min, depth_max;
} ftm_wire_control;

/* What became of a session command (ftm.v1.ControlOutcome). */
typedef enum ftm_wire_outcome {
    FTM_WIRE_OUTCOME_APPLIED = 1, /* in force as sent (or already was) */
    FTM_WIRE_OUTCOME_CHANGED = 2, /* in force with values the server adjusted (reason says how) */
    FTM_WIRE_OUTCOME_REFUSED = 3, /* nothing changed (reason says why) */
} ftm_wire_outcome;

#define FTM_WIRE_REASON_MAX 128 /* a reply's reason incl. NUL */

typedef struct ftm_wire_control_reply {
    uint32_t issuer;     /* the command's sender */
    uint64_t command_id; /* its command_id */
    ftm_wire_outcome outcome;
    uint64_t tick; /* the server's tick when it handled the command */
    /* no control characters; non-empty for CHANGED and REFUSED */
    char reason[FTM_WIRE_REASON_MAX];
} ftm_wire_control_reply;

/* Lower-case name of an outcome ("applied", "changed", "refused"); "unknown"
 * for anything else. */
const char *ftm_wire_outcome_name(ftm_wire_outcome outcome);

/* One message of any kind. Arrays in a decoded message are owned by it
 * (release with ftm_wire_msg_free); in a message being encoded they are the
 * caller's. Zero-initialise, set kind, fill the member of that kind. */
typedef struct ftm_wire_msg {
    ftm_wire_kind kind;
    union {
        ftm_wire_announce announce;
        ftm_wire_probe_input probe_input;
        ftm_wire_tick tick;
        ftm_wire_keyframe keyframe;
        ftm_wire_status status;
        ftm_wire_control control;
        ftm_wire_control_reply control_reply;
    } u;
    void *storage; /* decoder-owned memory; NULL otherwise */
} ftm_wire_msg;

/* Frees what the decoder allocated and zeroes the message; NULL is fine. */
void ftm_wire_msg_free(ftm_wire_msg *msg);

/* ---- Codec ------------------------------------------------------------ */

/* Default payload caps per kind [bytes]. */
#define FTM_WIRE_CAP_ANNOUNCE (64u * 1024u)
#define FTM_WIRE_CAP_PROBE_INPUT (256u * 1024u)
#define FTM_WIRE_CAP_TICK (2u * 1024u * 1024u)
#define FTM_WIRE_CAP_KEYFRAME (16u * 1024u * 1024u)
#define FTM_WIRE_CAP_STATUS (4u * 1024u)
#define FTM_WIRE_CAP_CONTROL (4u * 1024u)
#define FTM_WIRE_CAP_CONTROL_REPLY (4u * 1024u)

/* Decoding limits; zero-initialised means all defaults. */
typedef struct ftm_wire_limits {
    size_t max_payload; /* 0: the kind's FTM_WIRE_CAP_* */
    /* Bytes protobuf-c may allocate while unpacking one message;
     * 0: 64 KiB + 16 x payload size. Honest messages need < 4 x. */
    size_t max_memory;
    /* Mesh nodes, for checking node indices (from the announcement);
     * 0: unknown, indices are only checked against INT32_MAX. */
    int32_t node_count;
} ftm_wire_limits;

/* The payload cap of a kind (FTM_WIRE_CAP_*), 0 for an unknown kind. */
size_t ftm_wire_default_cap(int kind);

/* Checks msg and encodes it. On success *out is a malloc'ed buffer of *size
 * bytes (free() it). Rejects what a decoder would reject: NaN/infinite
 * values, counts out of range, unknown enums, a payload over the cap. */
int ftm_wire_encode(const ftm_wire_msg *msg, uint8_t **out, size_t *size, ftm_error *err);

/* Decodes a payload of the given kind into *out (owning its arrays). Checks,
 * in this order: size cap (FTM_ETOOBIG), protobuf well-formedness
 * (FTM_EPARSE, naming the byte offset and field), the memory budget
 * (FTM_EBUDGET), version (FTM_EVERSION), required fields (FTM_EPARSE),
 * values (FTM_EINVAL: NaN, unknown enum, inconsistent lengths) and indices
 * (FTM_ERANGE). limits may be NULL. On error *out is zeroed. */
int ftm_wire_decode(int kind, const void *data, size_t size, const ftm_wire_limits *limits,
                    ftm_wire_msg *out, ftm_error *err);

/* ---- Transport -------------------------------------------------------- */

typedef struct ftm_wire_transport ftm_wire_transport;

typedef struct ftm_wire_transport_def {
    /* Cyclone DDS configuration: XML text (starts with '<') or the path of
     * an XML file (deploy/cyclonedds-*.xml). NULL: Cyclone's default,
     * i.e. $CYCLONEDDS_URI or built-in defaults. */
    const char *config;
    /* DDS Security: the directory of this participant's identity and
     * permissions (deploy/ftm-security issue: identity_ca.pem,
     * permissions_ca.pem, cert.pem, key.pem, governance.p7s,
     * permissions.p7s), checked here and added to the configuration; NULL:
     * no security (docs/deploy.md, "Securing a session"). Errors name the
     * file and the cause; a bundle of a room with one CA (ca.pem), or whose
     * two CAs are one, is refused (CVE-2023-24011); an endpoint the
     * permissions do not grant fails with FTM_EACCESS. */
    const char *security;
    /* secured: the role this program runs as (0: not checked); an identity
     * issued for another role is refused even where its grants would do,
     * since the others reject statuses whose role is not the certificate's */
    ftm_wire_role role;
    uint32_t domain_id;      /* DDS domain, default 0 */
    const char *session;     /* session name, 1..63 bytes; the topic key */
    /* Read the messages of every session on the domain, not only `session`'s
     * (ftm_wire_received.session says whose): for finding sessions
     * (ftm-client --list). Such a transport publishes nothing. */
    bool any_session;
    uint32_t participant_id; /* this participant's id (Envelope.sender), != 0 */
    uint32_t publish;        /* FTM_WIRE_KIND_BIT()s of the kinds written */
    uint32_t subscribe;      /* FTM_WIRE_KIND_BIT()s of the kinds read */
    int32_t queue_capacity;  /* messages waiting to be written; 0: 4096 */
    ftm_wire_limits limits;  /* for decoding received messages */
    ftm_log_fn log;          /* rejected messages, DDS trouble; NULL: silent */
    void *log_user;
    /* > 0: run the publishing thread SCHED_FIFO at this priority (1..99)
     * where permitted, else at default scheduling (logged); 0: default */
    int32_t publisher_priority;
} ftm_wire_transport_def;

/* Creates a DDS participant in the domain (creating the domain with the
 * given configuration if this process has none with that id yet), the
 * topics, writers and readers with the protocol's QoS, and the publishing
 * thread. Several transports per process are fine (they then share the
 * first one's domain configuration). */
int ftm_wire_transport_create(const ftm_wire_transport_def *def, ftm_wire_transport **out,
                              ftm_error *err);

/* Writes out what is queued (for up to 2 s), stops the publishing thread,
 * deletes the DDS entities. Orderly leave: publish a STATE_LEAVING status
 * first. NULL is fine. */
void ftm_wire_transport_destroy(ftm_wire_transport *t);

/* Encodes msg on the caller's thread and queues it; the publishing thread
 * writes it to DDS. Never blocks on the network (safe from a 1 kHz loop).
 * The message gets the next sequence number of its kind. FTM_EAGAIN when
 * the queue is full (the message is dropped and counted, no number used). */
int ftm_wire_publish(ftm_wire_transport *t, const ftm_wire_msg *msg, ftm_error *err);

/* Queues an already encoded payload as it is (for relays and tests: the
 * payload is not checked). */
int ftm_wire_publish_raw(ftm_wire_transport *t, int kind, const void *payload, size_t size,
                         ftm_error *err);

/* Waits up to timeout_ns until the queue is empty and every reliable
 * reader has acknowledged what was written. FTM_ETIMEDOUT otherwise. */
int ftm_wire_flush(ftm_wire_transport *t, int64_t timeout_ns, ftm_error *err);

/* Runs the publishing thread on CPU cpu only (>= 0). With the caller's
 * thread on the same CPU at a lower real-time priority, a frame queued is
 * written at once, by a context switch instead of a wake-up of another
 * (possibly idle) core. FTM_EINVAL, or the error of the system call. */
int ftm_wire_pin_publisher(ftm_wire_transport *t, int cpu, ftm_error *err);

/* This process's origin, as others see it in ftm_wire_received.origin
 * (never 0). */
uint64_t ftm_wire_transport_origin(const ftm_wire_transport *t);

/* Waits up to timeout_ns until the writer (if this side publishes kind) or
 * else the reader of kind is matched with at least count remote endpoints. */
int ftm_wire_wait_matched(ftm_wire_transport *t, int kind, int32_t count, int64_t timeout_ns,
                          ftm_error *err);

/* A received message. */
typedef struct ftm_wire_received {
    ftm_wire_msg msg;      /* decoded; release with ftm_wire_received_free */
    uint32_t sender;       /* Envelope.sender */
    char session[64];      /* Envelope.session, with def.any_session only (else "") */
    /* The process it came from: a hash of its DDS participant's GUID, the
     * same in every process (0: no longer known). Two processes that give
     * one sender id differ here; ftm_wire_transport_origin is our own. */
    uint64_t origin;
    uint64_t seq;          /* Envelope.seq */
    /* Messages of this kind from this sender (and origin) that never
     * arrived between the previous one received and this one (0: none
     * missing). The first message seen from a sender sets the baseline and
     * has gap 0. */
    uint64_t gap;
    int64_t source_time_ns; /* writer's clock at dds_write */
    /* CLOCK_REALTIME when the message reached this process (taken in
     * Cyclone's receive thread, before the caller's thread got to it) */
    int64_t arrival_ns;
    size_t payload_size; /* bytes of the encoded message (Envelope.payload) */
    /* Status kind only: the sender's status instance is gone (it left, its
     * writer was deleted or its lease expired); msg is then empty. */
    bool gone;
} ftm_wire_received;

void ftm_wire_received_free(ftm_wire_received *r);

/* Takes the next message of kind, waiting up to timeout_ns (0: poll).
 * Messages that fail to decode (or are on the wrong topic for their kind,
 * or from another session) are logged with the reason, counted and
 * skipped. Returns FTM_OK, FTM_ETIMEDOUT or an error. One thread per kind. */
int ftm_wire_receive(ftm_wire_transport *t, int kind, ftm_wire_received *out, int64_t timeout_ns,
                     ftm_error *err);

/* Counters of one kind, since creation. */
typedef struct ftm_wire_stats {
    uint64_t published;     /* messages handed to dds_write successfully */
    uint64_t queue_full;    /* dropped by ftm_wire_publish: queue full */
    uint64_t write_errors;  /* dds_write failures (logged) */
    uint64_t received;      /* messages decoded and returned */
    uint64_t rejected;      /* malformed/foreign messages skipped (logged) */
    uint64_t missing;       /* sum of the gaps seen */
    uint64_t deadline_missed; /* status kind: a participant was silent too long */
    /* From Cyclone's writer statistics (0 when not available). */
    uint64_t rexmit_bytes;
    uint64_t throttle_count;
    int32_t matched;        /* remote endpoints currently matched */
    char last_reject[FTM_ERROR_MESSAGE_MAX]; /* reason of the last rejection */
} ftm_wire_stats;

int ftm_wire_get_stats(ftm_wire_transport *t, int kind, ftm_wire_stats *stats, ftm_error *err);

/* With DDS Security, every writer publishes in the partition
 * FTM_WIRE_PARTITION_PREFIX ROLE "." ID (e.g. "ftm.trainee.11"), which the
 * permissions grant that identity alone (deploy/ftm-security), and readers
 * read FTM_WIRE_PARTITION_PREFIX "*": a message whose sender id or role
 * disagrees with its writer's partition is rejected (docs/protocol.md). */
#define FTM_WIRE_PARTITION_PREFIX "ftm."

/* The DDS topic name of a kind, e.g. "ftm_v1_tick_frame"; NULL if unknown. */
const char *ftm_wire_topic_name(int kind);

/* Lower-case names of a role and a participant state, for logs and
 * displays ("trainee", "synced"); "unknown" for a value outside the enum. */
const char *ftm_wire_role_name(ftm_wire_role role);
const char *ftm_wire_state_name(ftm_wire_state state);

struct ftm_scene;
/* Opens the scene a SceneAnnounce's scene_id (or a --scene option) names, as
 * every FTM program resolves it: a built-in name; a file as given; else the
 * file of that base name in the directories of the FTM_SCENE_PATH environment
 * variable (':'-separated), then in share/ftm/scenes beside the program's
 * bin/ directory, then in the installed share/ftm/scenes. A server and its
 * clients may so name a scene file that lives at different paths on their
 * machines; the announcement's content digest tells whether they loaded the
 * same. The path opened goes to `path` when path_cap is not 0. */
int ftm_wire_open_scene(const char *scene_id, struct ftm_scene **out, char *path, size_t path_cap,
                        ftm_error *err);
/* The search list ftm_wire_open_scene uses, ':'-separated. */
void ftm_wire_scene_search(char *buf, size_t cap);

#ifdef __cplusplus
}
#endif
#endif
