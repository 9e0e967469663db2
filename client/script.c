/* ftm-bot scripts: parsing and interpolation (script.h, docs/bot-script.md). */
#include "script.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int ftm_script_load(const char *path, ftm_script *sc)
{
    memset(sc, 0, sizeof *sc);
    sc->leave = -1.0;
    ftm_script_text text;
    ftm_error err = {0, ""};
    if (ftm_script_text_read(path, &text, &err) != FTM_OK) {
        fprintf(stderr, "%s\n", err.message);
        return -1;
    }
    for (int32_t i = 0; i < text.ncmds; i++)
        sc->cmds[i] = (ftm_script_command){text.cmds[i], false};
    sc->ncmds = text.ncmds;
    sc->pts = text.pts; /* ours now */
    sc->npts = text.npts;
    sc->join = text.join;
    sc->leave = text.leave;
    return 0;
}

const char *ftm_script_control(const ftm_script_command *c, const ftm_wire_tissue *now,
                               ftm_wire_control *out)
{
    memset(out, 0, sizeof *out);
    out->tissue = *now;
    const double *v = c->e.value;
    switch (c->e.keyword) {
    case FTM_SCRIPT_KW_PAUSE: out->command = FTM_WIRE_CMD_PAUSE; return "pause";
    case FTM_SCRIPT_KW_RESUME: out->command = FTM_WIRE_CMD_RESUME; return "resume";
    case FTM_SCRIPT_KW_RESET: out->command = FTM_WIRE_CMD_RESET; return "reset";
    case FTM_SCRIPT_KW_DEPTH:
        out->command = FTM_WIRE_CMD_DEPTH_LIMITS;
        out->depth_min = (int32_t)v[0];
        out->depth_max = (int32_t)v[1];
        return "depth limits";
    case FTM_SCRIPT_KW_STIFFNESS:
        out->command = FTM_WIRE_CMD_TISSUE;
        out->tissue.stiffness = v[0];
        return "stiffness";
    case FTM_SCRIPT_KW_DAMPING:
        out->command = FTM_WIRE_CMD_TISSUE;
        out->tissue.node_damping = v[0];
        return "damping";
    case FTM_SCRIPT_KW_MASS:
        out->command = FTM_WIRE_CMD_TISSUE;
        out->tissue.node_mass = v[0];
        return "mass";
    }
    return "unknown";
}

ftm_vec3 ftm_script_at(const ftm_script *sc, double t)
{
    return ftm_script_points_at(sc->pts, sc->npts, t);
}

void ftm_script_free(ftm_script *sc)
{
    free(sc->pts);
    sc->pts = NULL;
    sc->npts = 0;
}
