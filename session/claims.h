/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Which process an id belongs to, as the server says, and which process is
 * the server: the rules a participant follows before it believes a status,
 * a frame or a force under an id (docs/protocol.md: Messages,
 * ParticipantStatus; Size caps and hostile input). Pure functions of the
 * messages received. */
#ifndef FTM_SESSION_CLAIMS_H
#define FTM_SESSION_CLAIMS_H

#include "ftm/wire.h"

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

#endif
