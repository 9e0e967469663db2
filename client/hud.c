/* SPDX-License-Identifier: GPL-3.0-or-later */
/* HUD text; see hud.h. */
#include "hud.h"

#include "font.h"
#include "haptic.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static double norm(ftm_vec3 f) { return sqrt(f.x * f.x + f.y * f.y + f.z * f.z); }

/* The order the participants are listed in: by role (the server, then
 * trainees, instructors, observers), then by id, so that a line stays
 * where the instructor last read it whoever joins or leaves. */
static int32_t listing_order(const ftm_client_view *v, int32_t order[FTM_CLIENT_MAX_PARTS])
{
    int32_t n = v->nparts < FTM_CLIENT_MAX_PARTS ? v->nparts : FTM_CLIENT_MAX_PARTS;
    for (int32_t i = 0; i < n; i++) {
        const ftm_client_part *p = &v->parts[i];
        int32_t k = i;
        for (; k > 0; k--) {
            const ftm_client_part *q = &v->parts[order[k - 1]];
            if (q->role < p->role || (q->role == p->role && q->id <= p->id))
                break;
            order[k] = order[k - 1];
        }
        order[k] = i;
    }
    return n;
}

/* What became of a command or a key, for a few seconds: two lines at
 * most, broken at a space (a refusal's reason is long). */
static int outcome_lines(const ftm_hud_info *in, char lines[FTM_HUD_LINES][FTM_HUD_WIDTH], int n)
{
    if (!in->command_outcome || n > FTM_HUD_LINES - 2)
        return n;
    const char *t = in->command_outcome, *mark = in->outcome_bad ? "!! " : "";
    int room = FTM_HUD_WIDTH - 1 - (int)strlen(mark), len = (int)strlen(t);
    int cut = len;
    if (len > room) {
        cut = room;
        while (cut > room / 2 && t[cut] != ' ')
            cut--;
    }
    snprintf(lines[n++], FTM_HUD_WIDTH, "%s%.*s", mark, cut, t);
    if (cut < len)
        snprintf(lines[n++], FTM_HUD_WIDTH, "%s%s", mark[0] ? "   " : "", t + cut + (t[cut] == ' '));
    return n;
}

int ftm_hud_lines(const ftm_client_view *v, const ftm_hud_info *in,
                  char lines[FTM_HUD_LINES][FTM_HUD_WIDTH])
{
    int n = 0;
#define LINE(...) snprintf(lines[n++], FTM_HUD_WIDTH, __VA_ARGS__)
    LINE("%s %u  %s  %s%s%sscene %s", ftm_wire_role_name(in->role), in->id,
         ftm_wire_state_name(v->state), in->session ? "session " : "",
         in->session ? in->session : "", in->session ? "  " : "",
         v->scene_name[0] ? v->scene_name : "-");
    if (!v->announced && v->nsessions > 0) {
        /* the waiting screen's picker: the sessions that are there */
        LINE("sessions on this domain: a key 1..%d or a click joins one", (int)v->nsessions);
        for (int32_t i = 0; i < v->nsessions && i < FTM_CLIENT_PICK; i++)
            LINE("  %d  %s  (%s)", (int)i + 1, v->sessions[i], v->sessions_about[i]);
    }
    LINE("tick %" PRIu64 "%s  depth %d [%d..%d]  lag %" PRId64 " ticks (%.1f ms)", v->tick,
         v->paused ? " paused" : "", (int)v->depth, (int)v->depth_min, (int)v->depth_max,
         v->lag_ticks, v->latency_ms);
    if (in->volume > 0)
        LINE("fps %.1f (%.1f ms)  volume: %d slices, %d-triangle lattice", in->fps, in->frame_ms,
             (int)in->volume_slices, (int)in->triangles);
    else
        LINE("fps %.1f (%.1f ms)  %d triangles", in->fps, in->frame_ms, (int)in->triangles);
    if (in->haptic) {
        const char *why = "";
        if (in->haptic_flags & (FTM_HAPTIC_DISCONNECTED | FTM_HAPTIC_DEVICE_LOST))
            why = "  OFF";
        else if ((in->haptic_flags & FTM_HAPTIC_STALE) && norm(in->force) > 1e-6)
            why = "  fading"; /* (a zero force out of contact fades nothing) */
        else if (in->haptic_flags & FTM_HAPTIC_CLAMPED)
            why = "  clamped";
        LINE("force %.3f N (%.2f %.2f %.2f)  %s%s", norm(in->force), in->force.x, in->force.y,
             in->force.z, in->renderer ? in->renderer : "", why);
    }
    if (in->probe_where == FTM_HUD_PROBE_ABOVE)
        LINE("probe %.1f mm above the surface (wheel: down)", in->probe_mm);
    else if (in->probe_where == FTM_HUD_PROBE_PRESSING)
        LINE("probe pressing %.1f mm deep (wheel: along the normal)", in->probe_mm);
    else if (in->probe_where == FTM_HUD_PROBE_NOTHING_BELOW)
        LINE("probe beside the tissue: nothing below it (drag it over; u: back above)");
    if (in->role == FTM_WIRE_ROLE_TRAINEE && v->own_contact_ticks > 0)
        LINE("you: %.1f s in contact, peak %.2f N", (double)v->own_contact_ticks /
             (v->rate_hz ? v->rate_hz : 1), v->own_peak_force);
    /* reaction forces of every probe in contact (what the server computed) */
    for (int32_t i = 0; i < v->nprobes && n < FTM_HUD_LINES - 12; i++) {
        const ftm_client_probe *p = &v->probes[i];
        if (!p->in_contact)
            continue;
        LINE("reaction %u/%d %.3f N%s%s", p->participant, (int)p->probe, norm(p->force),
             p->own ? " (you)" : "", p->push_limited ? "  too deep: push limited" : "");
    }
    if (v->mismatches || v->resyncs || v->rejected)
        LINE("mismatches %" PRIu64 "  resyncs %" PRIu64 "  rejected %" PRIu64, v->mismatches,
             v->resyncs, v->rejected);
    if (in->role == FTM_WIRE_ROLE_INSTRUCTOR) {
        LINE("tissue k %.4g N/m  d %.4g N s/m  m %.4g kg", v->tissue.stiffness,
             v->tissue.node_damping, v->tissue.node_mass);
        if (v->range_valid) {
            /* what the server accepts (session/tissue.h), and how hard it works */
            const ftm_tissue_range *r = &v->range;
            char dmin[32] = "any", mmin[32] = "any";
            if (r->damping_min > 0.0)
                snprintf(dmin, sizeof dmin, ">= %.3g", r->damping_min);
            if (r->mass_min > 0.0)
                snprintf(mmin, sizeof mmin, ">= %.3g", r->mass_min);
            LINE("stable range: k <= %.4g N/m  d %s  m %s  (at most %d substeps)", r->stiffness_max,
                 dmin, mmin, (int)r->max_substeps);
        }
        LINE("%sserver substeps %d per tick  lag %" PRId64 " ticks%s", v->substeps > 1 ? "!! " : "",
             (int)(v->substeps > 0 ? v->substeps : 1), v->lag_ticks,
             v->substeps > 1 ? ": past the stable step (t: scene tissue)" : "");
        LINE("participants:");
        int32_t order[FTM_CLIENT_MAX_PARTS], nparts = listing_order(v, order), i = 0;
        for (; i < nparts && n < FTM_HUD_LINES - 7; i++) {
            const ftm_client_part *p = &v->parts[order[i]];
            if (p->contact_ticks > 0) /* a trainee that has touched: the figures to debrief */
                LINE("  %u %s %s tick %" PRIu64 " %s  %.1f s in contact, peak %.2f N%s", p->id,
                     ftm_wire_role_name(p->role),
                     p->left ? "left" : ftm_wire_state_name(p->state), p->tick, p->name,
                     (double)p->contact_ticks / (v->rate_hz ? v->rate_hz : 1), p->peak_force,
                     p->peak_unstable ? " (unstable)" : "");
            else
                LINE("  %u %s %s tick %" PRIu64 " %s", p->id, ftm_wire_role_name(p->role),
                     p->left ? "left" : ftm_wire_state_name(p->state), p->tick, p->name);
        }
        /* say so rather than cut the list silently */
        if (i < nparts || v->parts_unlisted)
            LINE("  ... %s", v->parts_unlisted ? "more participants than the list holds"
                                               : "more not shown");
        LINE("keys: space pause/resume  backspace reset  +/- depth max  k/j stiffness  t scene tissue");
        if (in->last_command)
            LINE("sent: %s", in->last_command);
        n = outcome_lines(in, lines, n);
    }
    if (in->role != FTM_WIRE_ROLE_INSTRUCTOR) /* (a key this role cannot use, say) */
        n = outcome_lines(in, lines, n);
    if (in->volume)
        LINE("map %s (full %.1f mm)  region %s  volume %s   c/b/h/v/x/n%s [ ] home  F1 help",
             in->colormap ? "on" : "off", in->colormap_full * 1e3, in->region ? "on" : "off",
             in->volume > 0 ? "on" : "off", in->tissues ? "/l" : "");
    else
        LINE("map %s (full %.1f mm)  region %s   c/b/h%s [ ] home  F1 help",
             in->colormap ? "on" : "off", in->colormap_full * 1e3, in->region ? "on" : "off",
             in->tissues ? "/l" : "");
#undef LINE
    return n;
}

int ftm_hud_help(ftm_wire_role role, bool mouse_probe, bool volume, bool tissues,
                 char lines[FTM_HUD_LINES][FTM_HUD_WIDTH])
{
    int n = 0;
    const bool trainee = role == FTM_WIRE_ROLE_TRAINEE, instructor = role == FTM_WIRE_ROLE_INSTRUCTOR;
#define LINE(...) snprintf(lines[n++], FTM_HUD_WIDTH, __VA_ARGS__)
    LINE("Help: the %s's mouse and keys  (F1 or ? closes)", ftm_wire_role_name(role));
    LINE(" ");
    LINE("Mouse");
    if (trainee && mouse_probe) {
        LINE("  left drag          move the probe across, on the plane facing you");
        LINE("  wheel              lower / raise the probe, 1 mm a notch; in contact,");
        LINE("                     in and out along the surface's normal");
        LINE("  right drag         orbit the camera");
        LINE("  ctrl + wheel       zoom");
    } else {
        LINE("  left drag          orbit the camera");
        LINE("  right drag         pan");
        LINE("  wheel              zoom");
    }
    LINE("  shift + left drag, middle drag: pan");
    LINE(" ");
    LINE("Keys");
    if (trainee && mouse_probe)
        LINE("  u                  the probe back above the tissue");
    if (trainee)
        LINE("  m                  haptic renderer: model / extrapolate");
    if (instructor) {
        LINE("  space              pause / resume the session");
        LINE("  backspace          reset the tissue to rest");
        LINE("  + / -              depth ceiling up / down");
        LINE("  k / j              stiffer / softer tissue (x 1.25, / 1.25)");
        LINE("  t                  the scene's own tissue back");
    }
    LINE("  c  b  h            colour map, BFS region, HUD on / off");
    LINE("  [  ]               colour map range / 1.5, x 1.5");
    if (volume)
        LINE("  v  x  n            volume on / off, cut away, slices per plane");
    if (tissues)
        LINE("  l                  the tissues' legend on / off");
    LINE("  arrows, PgUp/PgDn  orbit, zoom;  Home: the view back");
    LINE("  Esc, q             quit");
    if (!instructor)
        LINE("  (space, backspace, + - k j t are the instructor's)");
#undef LINE
    return n;
}

#define DEPTH_CEILING_MAX 1000000 /* the protocol's largest depth (ftm_sim_set_depth's) */

bool ftm_hud_instructor_key(const ftm_client_view *v, ftm_wire_command cmd, const char *what,
                            ftm_wire_control *c, char *label, size_t cap)
{
    memset(c, 0, sizeof *c);
    if (!v->announced) {
        snprintf(label, cap, "%s: not sent: no session joined yet", what);
        return false;
    }
    if (v->server_away) {
        snprintf(label, cap, "%s: not sent: the server is away (%s)", what, v->banner);
        return false;
    }
    c->command = cmd;
    c->tissue = v->tissue;
    c->depth_min = v->depth_min;
    c->depth_max = v->depth_max;
    snprintf(label, cap, "%s", what);
    if (cmd == FTM_WIRE_CMD_TISSUE && strcmp(what, "scene tissue") == 0) {
        if (ftm_replay_tissue_equal(&v->tissue, &v->scene_tissue)) {
            snprintf(label, cap, "%s: not sent: the scene's own tissue is in force", what);
            return false;
        }
        c->tissue = v->scene_tissue;
        snprintf(label, cap, "scene tissue (k %.4g N/m, d %.4g N s/m)", c->tissue.stiffness,
                 c->tissue.node_damping);
    } else if (cmd == FTM_WIRE_CMD_TISSUE) {
        if (strcmp(what, "stiffer") == 0)
            c->tissue.stiffness *= 1.25;
        else
            c->tissue.stiffness /= 1.25;
        snprintf(label, cap, "stiffness %.4g N/m", c->tissue.stiffness);
    }
    if (cmd == FTM_WIRE_CMD_DEPTH_LIMITS) {
        bool up = strcmp(what, "depth max +1") == 0;
        if (up && c->depth_max >= DEPTH_CEILING_MAX) {
            snprintf(label, cap, "%s: not sent: the ceiling is at the largest depth (%d)", what,
                     (int)c->depth_max);
            return false;
        }
        if (!up && c->depth_max <= c->depth_min) {
            /* a server without --adaptive 1 announces floor = ceiling = its depth */
            snprintf(label, cap,
                     "%s: not sent: the depth is fixed at %d (floor = ceiling); a server started "
                     "without --adaptive 1 holds it there",
                     what, (int)c->depth_min);
            return false;
        }
        const bool fixed = c->depth_max <= c->depth_min;
        c->depth_max += up ? 1 : -1;
        snprintf(label, cap, "depth max %d%s", (int)c->depth_max,
                 up && fixed ? " (moves the depth only on a server started with --adaptive 1)" : "");
    }
    return true;
}

int ftm_hud_columns(int w, int px)
{
    int cols = (w - 24) / (FTM_FONT_CELL_W * (px > 0 ? px : 1));
    return cols < 24 ? 24 : cols;
}

int ftm_hud_wrap(char lines[FTM_HUD_LINES][FTM_HUD_WIDTH], int n, int cols)
{
    if (cols >= FTM_HUD_WIDTH - 1)
        return n;
    char in[FTM_HUD_LINES][FTM_HUD_WIDTH];
    memcpy(in, lines, sizeof in);
    int rows = 0;
    for (int i = 0; i < n && rows < FTM_HUD_LINES; i++) {
        const char *p = in[i];
        bool first = true;
        while (*p && rows < FTM_HUD_LINES) {
            const int indent = first ? 0 : 2, room = cols - indent;
            int len = (int)strlen(p), take = len <= room ? len : room;
            if (take < len) { /* at the last space that leaves half a row or more */
                int sp = take;
                while (sp > room / 2 && p[sp] != ' ')
                    sp--;
                if (p[sp] == ' ')
                    take = sp;
            }
            snprintf(lines[rows++], FTM_HUD_WIDTH, "%*s%.*s", indent, "", take, p);
            p += take;
            while (*p == ' ')
                p++;
            first = false;
        }
    }
    return rows;
}
