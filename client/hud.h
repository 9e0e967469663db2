/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The HUD's text: what the client shows in the top-left corner. */
#ifndef FTM_CLIENT_HUD_H
#define FTM_CLIENT_HUD_H

#include "client_session.h"

#define FTM_HUD_LINES 48
#define FTM_HUD_WIDTH 96

typedef struct ftm_hud_info {
    ftm_wire_role role;
    uint32_t id;
    const char *session; /* its name, in its own case; NULL: not shown */
    double fps, frame_ms;
    int32_t triangles;
    bool haptic;          /* a haptic loop runs (trainee) */
    ftm_vec3 force;       /* force the loop displays [N] */
    int haptic_flags;     /* FTM_HAPTIC_* */
    const char *renderer; /* "extrapolate" / "model" */
    bool colormap, region;
    bool tissues;          /* the mesh has labels: the legend's key l */
    int volume;            /* the scene's volume: 1 drawn, -1 not (its surface is), 0 none */
    int32_t volume_slices; /* drawn in the last frame */
    double colormap_full; /* [m] */
    const char *last_command; /* instructor: what was sent last; may be NULL */
    /* instructor: what became of a command, shown for a few seconds ("stiffness
     * 80 N/m: applied at tick 1234"); NULL: nothing to show */
    const char *command_outcome;
    bool outcome_bad; /* refused, unanswered or not sent */
    /* a trainee's own probe: where it is (FTM_HUD_PROBE_*), probe_mm its
     * height above the surface below it or its push depth [mm] */
    int probe_where;
    double probe_mm;
    bool help; /* the help overlay is shown (F1, ?): the hint line says how to close it */
} ftm_hud_info;

enum {
    FTM_HUD_PROBE_UNKNOWN = 0,
    FTM_HUD_PROBE_ABOVE,         /* probe_mm above the surface straight below it */
    FTM_HUD_PROBE_PRESSING,      /* in contact, probe_mm below where the contact began */
    FTM_HUD_PROBE_NOTHING_BELOW, /* beside the tissue: no surface below it */
};

/* Fills lines[i] (each FTM_HUD_WIDTH bytes) and returns how many. */
int ftm_hud_lines(const ftm_client_view *v, const ftm_hud_info *info,
                  char lines[FTM_HUD_LINES][FTM_HUD_WIDTH]);

/* The help overlay (F1, ?): each mouse action and key this client offers,
 * for its role; mouse_probe: a trainee's probe follows the mouse; volume:
 * the scene has a volume (its keys); tissues: its mesh has labels (the
 * legend's key). Returns the lines written. */
int ftm_hud_help(ftm_wire_role role, bool mouse_probe, bool volume, bool tissues,
                 char lines[FTM_HUD_LINES][FTM_HUD_WIDTH]);

/* Wraps lines[0..n) to at most cols characters (at spaces where it can,
 * continuation rows indented two columns), in place, up to FTM_HUD_LINES
 * rows: a narrow window (640 px) shows every line whole. Returns the rows. */
int ftm_hud_wrap(char lines[FTM_HUD_LINES][FTM_HUD_WIDTH], int n, int cols);

/* The HUD's columns in a window w pixels wide at text scale px (HUD pixels
 * per font pixel), at least 24. */
int ftm_hud_columns(int w, int px);

/* An instructor's key as a session command, from what the view shows.
 * what: "pause", "resume", "reset", "depth max +1", "depth max -1",
 * "stiffer" (stiffness x 1.25), "softer" (/ 1.25) or "scene tissue" (the
 * scene's own tissue back). true: *c is filled
 * (issuer and command id are the sender's) and label names the command
 * with its value ("stiffness 62.5 N/m", "depth max 5"). false: the key can
 * do nothing now (a limit reached, no session, the server away): label
 * says why, for the HUD ("depth max -1: not sent: the ceiling is at the
 * floor (2)"), and nothing is to be sent. */
bool ftm_hud_instructor_key(const ftm_client_view *v, ftm_wire_command cmd, const char *what,
                            ftm_wire_control *c, char *label, size_t cap);

#endif
