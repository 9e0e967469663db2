/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-bot scripts: parsing and interpolation (script.h, docs/bot-script.md). */
#include "script.h"

#include <inttypes.h>
#include <math.h>
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
    for (int32_t i = 0; i < text.nexpects; i++)
        sc->expects[i] = (ftm_script_check){.e = text.expects[i]};
    sc->nexpects = text.nexpects;
    sc->pts = text.pts; /* ours now */
    sc->npts = text.npts;
    sc->join = text.join;
    sc->leave = text.leave;
    sc->session_clock = text.session_clock;
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

void ftm_script_command_text(const ftm_script_command *c, char *text, size_t cap)
{
    const double *v = c->e.value;
    switch (c->e.keyword) {
    case FTM_SCRIPT_KW_DEPTH:
        snprintf(text, cap, "depth limits %d..%d", (int)v[0], (int)v[1]);
        return;
    case FTM_SCRIPT_KW_STIFFNESS: snprintf(text, cap, "stiffness %g N/m", v[0]); return;
    case FTM_SCRIPT_KW_DAMPING: snprintf(text, cap, "damping %g N s/m", v[0]); return;
    case FTM_SCRIPT_KW_MASS: snprintf(text, cap, "mass %g kg", v[0]); return;
    default: {
        ftm_wire_control ctl;
        const ftm_wire_tissue none = {0, 0, 0, {0, 0, 0}};
        snprintf(text, cap, "%s", ftm_script_control(c, &none, &ctl));
        return;
    }
    }
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

void ftm_script_expect_frame(ftm_script *sc, double t, uint64_t tick, ftm_vec3 force,
                             bool contact)
{
    const double f = sqrt(force.x * force.x + force.y * force.y + force.z * force.z);
    for (int32_t i = 0; i < sc->nexpects; i++) {
        ftm_script_check *c = &sc->expects[i];
        if (!(t >= c->e.t0 && t <= c->e.t1))
            continue;
        if (c->frames == 0 || f < c->min)
            c->min = f;
        if (c->frames == 0 || f > c->max) {
            c->max = f;
            c->max_t = t;
        }
        c->frames++;
        c->in_contact += contact;
        bool bad = false;
        if (c->e.kind == FTM_SCRIPT_EXPECT_FORCE)
            bad = !(f >= c->e.lo && f <= c->e.hi);
        else if (c->e.kind == FTM_SCRIPT_EXPECT_CONTACT)
            bad = contact != c->e.contact;
        if (bad && !c->broken) {
            c->broken = true;
            c->bad_t = t;
            c->bad_f = f;
            c->bad_tick = tick;
        }
    }
}

int ftm_script_expect_report(const ftm_script *sc, const char *name, double end, FILE *f)
{
    int failed = 0;
    for (int32_t i = 0; i < sc->nexpects; i++) {
        const ftm_script_check *c = &sc->expects[i];
        const ftm_script_expect *e = &c->e;
        char what[160];
        if (e->kind == FTM_SCRIPT_EXPECT_CONTACT)
            snprintf(what, sizeof what, "expect %g %g contact %s", e->t0, e->t1,
                     e->contact ? "yes" : "no");
        else
            snprintf(what, sizeof what, "expect %g %g %s %g %g", e->t0, e->t1,
                     e->kind == FTM_SCRIPT_EXPECT_PEAK ? "peak" : "force", e->lo, e->hi);
        fprintf(f, "%s:%d: %s: ", name, (int)e->line, what);
        const long long n = (long long)c->frames;
        const char *fr = n == 1 ? "frame" : "frames";
        const bool ok = !c->broken && end >= e->t1 && n > 0 &&
                        (e->kind != FTM_SCRIPT_EXPECT_PEAK || (c->max >= e->lo && c->max <= e->hi));
        /* the most telling reason first: a frame that broke it, a window
         * the bot did not see to its end, no frames at all */
        if (c->broken && e->kind == FTM_SCRIPT_EXPECT_CONTACT)
            fprintf(f, "FAILED: %s contact at t = %.3f s (tick %" PRIu64 "); %lld of %lld %s in "
                       "contact\n", e->contact ? "not in" : "in", c->bad_t, c->bad_tick,
                    (long long)c->in_contact, n, fr);
        else if (c->broken)
            fprintf(f, "FAILED: %.4g N at t = %.3f s (tick %" PRIu64 "); min %.4g max %.4g N "
                       "over %lld %s\n", c->bad_f, c->bad_t, c->bad_tick, c->min, c->max, n, fr);
        else if (end < e->t1)
            fprintf(f, "FAILED: the bot stopped at t = %.3f s, before the window's end\n", end);
        else if (n == 0)
            fprintf(f, "FAILED: no frames in the window\n");
        else if (!ok)
            fprintf(f, "FAILED: peak %.4g N at t = %.3f s over %lld %s\n", c->max, c->max_t, n,
                    fr);
        else if (e->kind == FTM_SCRIPT_EXPECT_CONTACT)
            fprintf(f, "ok (%lld %s, %s in contact)\n", n, fr, e->contact ? "all" : "none");
        else if (e->kind == FTM_SCRIPT_EXPECT_PEAK)
            fprintf(f, "ok (peak %.4g N at t = %.3f s over %lld %s)\n", c->max, c->max_t, n, fr);
        else
            fprintf(f, "ok (min %.4g max %.4g N over %lld %s)\n", c->min, c->max, n, fr);
        failed += !ok;
    }
    return failed;
}
