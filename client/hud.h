/* The HUD's text: what the client shows in the top-left corner. */
#ifndef FTM_CLIENT_HUD_H
#define FTM_CLIENT_HUD_H

#include "client_session.h"

#define FTM_HUD_LINES 48
#define FTM_HUD_WIDTH 96

typedef struct ftm_hud_info {
    ftm_wire_role role;
    uint32_t id;
    double fps, frame_ms;
    int32_t triangles;
    bool haptic;          /* a haptic loop runs (trainee) */
    ftm_vec3 force;       /* force the loop displays [N] */
    int haptic_flags;     /* FTM_HAPTIC_* */
    const char *renderer; /* "extrapolate" / "model" */
    bool colormap, region;
    double colormap_full; /* [m] */
    const char *last_command; /* instructor: what was sent last; may be NULL */
    /* instructor: what became of a command, shown for a few seconds ("stiffness
     * 80 N/m: applied at tick 1234"); NULL: nothing to show */
    const char *command_outcome;
    bool outcome_bad; /* refused, unanswered or not sent */
} ftm_hud_info;

/* Fills lines[i] (each FTM_HUD_WIDTH bytes) and returns how many. */
int ftm_hud_lines(const ftm_client_view *v, const ftm_hud_info *info,
                  char lines[FTM_HUD_LINES][FTM_HUD_WIDTH]);

#endif
