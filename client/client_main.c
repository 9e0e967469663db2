/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-client: the thin GLFW/OpenGL client (docs/client.md).
 *
 * Threads, as in the paper's Fig. 14: the haptic loop (haptic.h, 1 kHz,
 * highest priority; trainees only), the session thread (client_session.h:
 * DDS, replay of the server's tick frames, watchdog) and rendering on the
 * main thread (GLFW wants it there). The render thread only ever sees a
 * copy of the replayed state (ftm_client_session_snapshot).
 *
 * Exit status: 0 done; 1 --screenshot/--bench could not finish in time
 * (a screenshot is still written); 2 usage; 3 set-up failure. */
#define GLFW_INCLUDE_NONE
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#include <GLFW/glfw3.h>

#include "camera.h"
#include "client_options.h"
#include "client_session.h"
#include "device.h"
#include "haptic.h"
#include "haptic_wire.h"
#include "font.h"
#include "hud.h"
#include "render.h"
#include "screenshot.h"
#include "script.h"
#include "sessions.h"

#include "ftm/clock.h"

#include <errno.h>
#include <inttypes.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define SEC FTM_NS_PER_S
#define MOUSE_MAX_DEPTH 0.2 /* the mouse probe's deepest push, as a part of the scene's size */
/* the mouse probe starts (and key u lifts it) this many link lengths above
 * the scene's top: a few wheel notches from the surface, inside the view */
#define PROBE_START_LINKS 1.5

typedef struct app {
    ftm_client_options o;
    ftm_wire_role role;
    int64_t t0;
    FILE *logf;
    ftm_client_session *sess;
    ftm_device *dev;
    ftm_haptic *hap;
    bool hap_connected; /* session thread only */
    ftm_haptic_timebase timebase; /* session thread only: tick times to our clock */
    ftm_haptic_def hap_def;
    GLFWwindow *win;
    ftm_render *ren;
    ftm_camera cam;
    bool cam_set;
    /* framebuffer rows at the top the view keeps clear for the HUD
     * (frame_top): drawn now, held, held until; fb_h: framebuffer height */
    double view_top, top_hold;
    int64_t top_hold_until;
    bool top_set;
    int fb_h;
    const ftm_mesh *drawn_mesh;
    /* a trainee's mouse probe: its contact's plane while in contact (to move
     * it out should the contact end with it inside), and the height the
     * probe starts at, above the scene (key u) */
    bool probe_touching;
    ftm_vec3 touch_point, touch_normal;
    double probe_lift_z;
    /* while in contact: the reaction's largest angle from the normal and
     * its peak, logged at the release (how cleanly it pushed and let go) */
    double touch_angle, touch_peak;
    int64_t touch_start;
    ftm_client_view view;
    ftm_render_opts ropts;
    bool help; /* the help overlay (F1, ?) */
    /* the waiting screen's picker: the HUD row (top first) of each session
     * offered, 0 for a row that is none, as drawn in the last frame; and
     * the name picked (the session switched to) */
    int pick_row[FTM_HUD_LINES];
    int pick_rows;
    char picked[64];
    double mx, my;
    int drag; /* 0 none, 1 orbit, 2 pan, 3 probe */
    char last_cmd[96];
    /* the HUD's command line: the latest outcome (the server's reply, or
     * this client's own "not sent: ..."), shown until notice_until */
    char notice[FTM_OUTCOME_TEXT];
    bool notice_bad;
    int64_t notice_until;
    uint64_t outcome_seen; /* view.outcome_seq taken into notice */
    ftm_script cmds; /* --commands */
    bool have_cmds;
} app;

static volatile sig_atomic_t g_stop;
static void on_signal(int sig) { (void)sig; g_stop = 1; }

static void app_log(void *user, ftm_log_level level, const char *msg)
{
    app *a = user;
    if (level < FTM_LOG_INFO && !a->o.verbose)
        return;
    const char *tag = level >= FTM_LOG_ERROR ? "error: " : level == FTM_LOG_WARN ? "warning: " : "";
    double t = (double)(ftm_clock_mono_ns() - a->t0) * 1e-9;
    fprintf(stderr, "ftm-client %u [%8.3f] %s%s\n", a->o.id, t, tag, msg);
    if (a->logf) {
        fprintf(a->logf, "[%8.3f] %s%s\n", t, tag, msg);
        fflush(a->logf);
    }
}

static void alog(app *a, ftm_log_level level, const char *fmt, ...)
{
    char buf[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    app_log(a, level, buf);
}

/* ---- haptics wiring (session thread -> haptic loop) ------------------------------------- */

static void on_force(void *user, uint64_t tick, double tick_time, const ftm_wire_reaction *r,
                     bool valid, const char *why)
{
    app *a = user;
    if (!a->hap)
        return;
    if (!valid) {
        if (a->hap_connected)
            ftm_haptic_set_connected(a->hap, false); /* zero force at once */
        a->hap_connected = false;
        return;
    }
    if (!a->hap_connected) {
        ftm_haptic_set_connected(a->hap, true);
        a->timebase = (ftm_haptic_timebase){0}; /* perhaps another server, another clock */
    }
    a->hap_connected = true;
    ftm_haptic_state st;
    ftm_haptic_get_state(a->hap, &st);
    /* the force model and contact plane when the server sent them; the
     * time is the tick's, on our clock (frames drained in a burst keep
     * their ticks' spacing for the extrapolator's slope) */
    double t = ftm_haptic_timebase_map(&a->timebase, tick_time, ftm_haptic_clock(),
                                       a->hap_def.stale_after);
    ftm_haptic_sample s = ftm_haptic_sample_from_reaction(r, t, st.hip);
    if (ftm_haptic_push(a->hap, &s))
        alog(a, FTM_LOG_WARN, "haptic: reaction force of tick %" PRIu64 " rejected", tick);
}

static int take_hips(void *user, ftm_wire_probe_sample *out, int max)
{
    app *a = user;
    ftm_haptic_hip h[64];
    int n = ftm_haptic_take_hips(a->hap, h, max < 64 ? max : 64);
    for (int i = 0; i < n; i++)
        out[i] = (ftm_wire_probe_sample){0, (uint64_t)(h[i].time * 1e9), h[i].hip};
    return n;
}

/* ---- input ------------------------------------------------------------------------------- */

#define NOTICE_NS (5 * SEC) /* how long a command's outcome stays on the HUD */

/* A command's outcome on the HUD for a few seconds, and in the log. */
static void notice(app *a, bool bad, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void notice(app *a, bool bad, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(a->notice, sizeof a->notice, fmt, ap);
    va_end(ap);
    a->notice_bad = bad;
    a->notice_until = ftm_clock_mono_ns() + NOTICE_NS;
    alog(a, bad ? FTM_LOG_WARN : FTM_LOG_INFO, "%s", a->notice);
}

/* what: the key or script command ("stiffer", "stiffness"); label: the
 * command with its value as the HUD names it ("stiffness 80 N/m"), under
 * which the session thread reports the server's reply */
static void send_control(app *a, ftm_wire_control *c, const char *what, const char *label)
{
    ftm_error err = {0, ""};
    if (ftm_client_session_control(a->sess, c, label, &err)) {
        notice(a, true, "%s: not sent: %s", label, err.message);
        snprintf(a->last_cmd, sizeof a->last_cmd, "%s FAILED", what);
        return;
    }
    if (c->command == FTM_WIRE_CMD_TISSUE)
        snprintf(a->last_cmd, sizeof a->last_cmd, "%s (k = %.4g N/m, d = %.4g N s/m, m = %.4g kg)",
                 what, c->tissue.stiffness, c->tissue.node_damping, c->tissue.node_mass);
    else if (c->command == FTM_WIRE_CMD_DEPTH_LIMITS)
        snprintf(a->last_cmd, sizeof a->last_cmd, "depth limits %d..%d", (int)c->depth_min,
                 (int)c->depth_max);
    else
        snprintf(a->last_cmd, sizeof a->last_cmd, "%s", what);
    alog(a, FTM_LOG_INFO, "sent %s", a->last_cmd);
}

/* A key's command. One that cannot do anything (a limit reached, no server
 * to hear it) is not sent, and the HUD says why at once. */
static void send_command(app *a, ftm_wire_command cmd, const char *what)
{
    if (a->role != FTM_WIRE_ROLE_INSTRUCTOR) { /* said on screen too, not only in the log */
        notice(a, true, "%s: an instructor's key (this client is a %s; F1: the keys)", what,
               a->o.role);
        return;
    }
    ftm_wire_control c;
    char label[FTM_OUTCOME_TEXT];
    if (!ftm_hud_instructor_key(&a->view, cmd, what, &c, label, sizeof label)) {
        notice(a, true, "%s", label);
        return;
    }
    send_control(a, &c, what, label);
}

/* --commands: the script's commands that are due, once synced (times from
 * the client's start, as ftm-bot plays them). Not while the server is
 * away: they wait until this client is synced with a server again. */
static void scripted_commands(app *a)
{
    if (!a->have_cmds || !a->view.synced_once || a->view.state != FTM_WIRE_STATE_SYNCED ||
        a->view.server_away)
        return;
    double t = (double)(ftm_clock_mono_ns() - a->t0) * 1e-9;
    for (int32_t i = 0; i < a->cmds.ncmds; i++) {
        ftm_script_command *sc = &a->cmds.cmds[i];
        if (sc->done || t < sc->e.t)
            continue;
        sc->done = true;
        ftm_wire_control c;
        const char *what = ftm_script_control(sc, &a->view.tissue, &c);
        char label[FTM_PENDING_WHAT];
        ftm_script_command_text(sc, label, sizeof label);
        send_control(a, &c, what, label);
    }
}

static void probe_lift(app *a); /* key u, below */
static bool start_session(app *a); /* below */

/* The waiting screen's picker: joins the k-th session offered instead of
 * the one asked for (a mistyped name waits forever otherwise). */
static void pick_session(app *a, int k)
{
    if (a->view.announced || k < 0 || k >= a->view.nsessions)
        return;
    snprintf(a->picked, sizeof a->picked, "%s", a->view.sessions[k]);
    alog(a, FTM_LOG_INFO, "picked session '%s' (was '%s'): joining it", a->picked, a->o.session);
    ftm_client_session_stop(a->sess);
    a->sess = NULL;
    ftm_client_view_free(&a->view);
    memset(&a->view, 0, sizeof a->view);
    ftm_error err = {0, ""};
    ftm_render_set_volume(a->ren, NULL, NULL, NULL, &err);
    ftm_render_set_mesh(a->ren, NULL, NULL, &err);
    a->drawn_mesh = NULL;
    a->o.session = a->picked;
    char title[160];
    snprintf(title, sizeof title, "ftm-client: %s, session %s", a->o.role, a->o.session);
    glfwSetWindowTitle(a->win, title);
    if (!start_session(a))
        glfwSetWindowShouldClose(a->win, GLFW_TRUE);
}

static void on_key(GLFWwindow *w, int key, int scancode, int action, int mods)
{
    app *a = glfwGetWindowUserPointer(w);
    if (action == GLFW_RELEASE)
        return;
    switch (key) {
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q: glfwSetWindowShouldClose(w, GLFW_TRUE); break;
    case GLFW_KEY_C: a->ropts.colormap = !a->ropts.colormap; break;
    case GLFW_KEY_B:
        a->ropts.region = !a->ropts.region;
        ftm_client_session_want_region(a->sess, a->ropts.region);
        break;
    case GLFW_KEY_H: a->ropts.hud = !a->ropts.hud; break;
    case GLFW_KEY_F1: a->help = !a->help; break;
    case GLFW_KEY_1: case GLFW_KEY_2: case GLFW_KEY_3: case GLFW_KEY_4: case GLFW_KEY_5:
    case GLFW_KEY_6: case GLFW_KEY_7: case GLFW_KEY_8: case GLFW_KEY_9:
        pick_session(a, key - GLFW_KEY_1);
        break;
    case GLFW_KEY_V: a->ropts.volume = !a->ropts.volume; break;
    case GLFW_KEY_L: a->ropts.legend = !a->ropts.legend; break;
    case GLFW_KEY_X: a->ropts.cut = !a->ropts.cut; break;
    case GLFW_KEY_N: /* fewer slices, then all again: 1, 2, 5, 10 */
        a->ropts.volume_step = a->ropts.volume_step == 1   ? 2
                               : a->ropts.volume_step == 2 ? 5
                               : a->ropts.volume_step == 5 ? 10
                                                           : 1;
        break;
    case GLFW_KEY_LEFT_BRACKET: a->ropts.colormap_full /= 1.5; break;
    case GLFW_KEY_RIGHT_BRACKET: a->ropts.colormap_full *= 1.5; break;
    case GLFW_KEY_HOME: a->cam_set = false; break;
    case GLFW_KEY_LEFT: ftm_camera_orbit(&a->cam, -20, 0); break;
    case GLFW_KEY_RIGHT: ftm_camera_orbit(&a->cam, 20, 0); break;
    case GLFW_KEY_UP: ftm_camera_orbit(&a->cam, 0, 20); break;
    case GLFW_KEY_DOWN: ftm_camera_orbit(&a->cam, 0, -20); break;
    case GLFW_KEY_PAGE_UP: ftm_camera_zoom(&a->cam, 1); break;
    case GLFW_KEY_PAGE_DOWN: ftm_camera_zoom(&a->cam, -1); break;
    case GLFW_KEY_M:
        if (a->hap) {
            ftm_haptic_state st;
            ftm_haptic_get_state(a->hap, &st);
            ftm_haptic_set_renderer(a->hap, st.renderer == FTM_HAPTIC_EXTRAPOLATE
                                                ? FTM_HAPTIC_FORCE_MODEL
                                                : FTM_HAPTIC_EXTRAPOLATE);
        }
        break;
    /* instructor */
    case GLFW_KEY_SPACE:
        if (action == GLFW_PRESS)
            send_command(a, a->view.paused ? FTM_WIRE_CMD_RESUME : FTM_WIRE_CMD_PAUSE,
                         a->view.paused ? "resume" : "pause");
        break;
    case GLFW_KEY_BACKSPACE:
        if (action == GLFW_PRESS)
            send_command(a, FTM_WIRE_CMD_RESET, "reset");
        break;
    case GLFW_KEY_EQUAL:
    case GLFW_KEY_KP_ADD: send_command(a, FTM_WIRE_CMD_DEPTH_LIMITS, "depth max +1"); break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: send_command(a, FTM_WIRE_CMD_DEPTH_LIMITS, "depth max -1"); break;
    case GLFW_KEY_K: send_command(a, FTM_WIRE_CMD_TISSUE, "stiffer"); break;
    case GLFW_KEY_J: send_command(a, FTM_WIRE_CMD_TISSUE, "softer"); break;
    case GLFW_KEY_T: send_command(a, FTM_WIRE_CMD_TISSUE, "scene tissue"); break;
    case GLFW_KEY_U: probe_lift(a); break;
    default: break;
    }
}

static bool mouse_probe(const app *a) { return a->dev && a->o.device && strcmp(a->o.device, "mouse") == 0; }

/* '?' by the character it types, whatever the keyboard's layout */
static void on_char(GLFWwindow *w, unsigned int codepoint)
{
    app *a = glfwGetWindowUserPointer(w);
    if (codepoint == '?')
        a->help = !a->help;
}

static void on_button(GLFWwindow *w, int button, int action, int mods)
{
    app *a = glfwGetWindowUserPointer(w);
    glfwGetCursorPos(w, &a->mx, &a->my);
    if (action == GLFW_RELEASE) {
        if (a->drag == 3)
            ftm_mouse_button(a->dev, false, a->mx, a->my);
        a->drag = 0;
        return;
    }
    if (button == GLFW_MOUSE_BUTTON_LEFT && !a->view.announced && a->view.nsessions > 0 &&
        a->ropts.hud) {
        /* a click on a session's row of the picker joins it */
        int ww, wh;
        glfwGetWindowSize(w, &ww, &wh);
        double y = wh > 0 && a->fb_h > 0 ? a->my * a->fb_h / wh : a->my;
        double lh = (FTM_FONT_CELL_H + 2) * (a->ropts.text_scale > 0 ? a->ropts.text_scale : 1);
        int row = (int)floor((y - 12.0) / lh);
        if (row >= 0 && row < a->pick_rows && a->pick_row[row] > 0) {
            pick_session(a, a->pick_row[row] - 1);
            return;
        }
    }
    bool shift = mods & GLFW_MOD_SHIFT;
    if (button == GLFW_MOUSE_BUTTON_LEFT && shift)
        a->drag = 2;
    else if (button == GLFW_MOUSE_BUTTON_LEFT && mouse_probe(a)) {
        a->drag = 3;
        ftm_mouse_button(a->dev, true, a->mx, a->my);
    } else if (button == GLFW_MOUSE_BUTTON_LEFT)
        a->drag = 1;
    else if (button == GLFW_MOUSE_BUTTON_RIGHT)
        a->drag = mouse_probe(a) ? 1 : 2;
    else if (button == GLFW_MOUSE_BUTTON_MIDDLE)
        a->drag = 2;
}

/* The rows of a window fh pixels high (window coordinates) in which the
 * view is framed, below what the HUD covers. */
static double view_rows(const app *a, int fh)
{
    double top = a->fb_h > 0 ? a->view_top * fh / a->fb_h : 0.0;
    return ftm_camera_view_height(fh, top);
}

static void on_cursor(GLFWwindow *w, double x, double y)
{
    app *a = glfwGetWindowUserPointer(w);
    double dx = x - a->mx, dy = y - a->my;
    a->mx = x;
    a->my = y;
    int fh;
    glfwGetWindowSize(w, NULL, &fh);
    if (a->drag == 1)
        ftm_camera_orbit(&a->cam, dx, dy);
    else if (a->drag == 2)
        ftm_camera_pan(&a->cam, dx, dy, view_rows(a, fh));
    else if (a->drag == 3)
        ftm_mouse_motion(a->dev, x, y);
}

static void on_scroll(GLFWwindow *w, double dx, double dy)
{
    app *a = glfwGetWindowUserPointer(w);
    if (mouse_probe(a) && !(glfwGetKey(w, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS))
        ftm_mouse_scroll(a->dev, -dy); /* wheel up pulls the probe back */
    else
        ftm_camera_zoom(&a->cam, dy);
}

static void on_glfw_error(int code, const char *msg)
{
    fprintf(stderr, "ftm-client: GLFW error 0x%x: %s\n", code, msg);
}

/* ---- the render loop ----------------------------------------------------------------------- */

static void mesh_box(const ftm_mesh *m, ftm_vec3 *lo, ftm_vec3 *hi)
{
    int32_t n = ftm_mesh_node_count(m);
    *lo = *hi = ftm_mesh_rest_position(m, 0);
    for (int32_t i = 1; i < n; i++) {
        ftm_vec3 p = ftm_mesh_rest_position(m, i);
        lo->x = fmin(lo->x, p.x), lo->y = fmin(lo->y, p.y), lo->z = fmin(lo->z, p.z);
        hi->x = fmax(hi->x, p.x), hi->y = fmax(hi->y, p.y), hi->z = fmax(hi->z, p.z);
    }
}

static void new_mesh(app *a)
{
    ftm_error err = {0, ""};
    ftm_render_set_tool(a->ren, a->view.tool);
    if (ftm_render_set_mesh(a->ren, a->view.mesh, a->view.scene, &err))
        alog(a, FTM_LOG_ERROR, "%s", err.message);
    const ftm_label_map *vlabels = a->view.scene ? ftm_scene_volume_labels(a->view.scene) : NULL;
    if (ftm_render_set_volume(a->ren, a->view.volume, a->view.ffd, vlabels, &err))
        alog(a, FTM_LOG_ERROR, "%s", err.message);
    a->drawn_mesh = a->view.mesh;
    a->cam_set = false;
    if (!a->view.mesh)
        return;
    alog(a, FTM_LOG_INFO, "drawing %d surface triangles", (int)ftm_render_triangle_count(a->ren));
    const ftm_tissue *tis;
    int32_t ntis = ftm_render_tissues(a->ren, &tis);
    if (ftm_mesh_has_labels(a->view.mesh) && ntis == 0)
        alog(a, FTM_LOG_WARN, "the mesh's elements carry labels, but its %d surface triangles are "
             "more than this OpenGL's buffer textures hold: one colour, no legend",
             (int)ftm_render_triangle_count(a->ren));
    for (int32_t i = 0; i < ntis; i++) {
        char row[96];
        ftm_tissue_legend_text(&tis[i], row, sizeof row);
        alog(a, FTM_LOG_INFO, "tissue: label %d, %s, %d surface triangles", (int)tis[i].label, row,
             (int)tis[i].triangles);
    }
    if (ftm_render_has_volume(a->ren)) {
        ftm_volume_info vi = ftm_volume_get_info(a->view.volume);
        alog(a, FTM_LOG_INFO, "drawing the scene's volume (%dx%dx%d voxels) as slices%s%s",
             (int)vi.nx, (int)vi.ny, (int)vi.nz, vlabels ? ", coloured by its label map" : "",
             a->ropts.volume ? "" : " (off: key v)");
    }
    if (mouse_probe(a)) { /* the probe starts above the middle of the top */
        ftm_vec3 lo, hi;
        mesh_box(a->view.mesh, &lo, &hi);
        /* its travel: within the scene's size around it, and at most a
         * fifth of that deep (docs/client.md, Devices) */
        double size = fmax(hi.x - lo.x, fmax(hi.y - lo.y, hi.z - lo.z));
        if (ftm_mouse_set_limits(a->dev, lo, hi, MOUSE_MAX_DEPTH * size, size))
            alog(a, FTM_LOG_WARN, "mouse probe: no travel limits for this scene");
        double l = ftm_render_link_length(a->ren);
        a->probe_lift_z = hi.z + PROBE_START_LINKS * l;
        a->probe_touching = false;
        ftm_mouse_set_hip(a->dev, (ftm_vec3){0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), a->probe_lift_z});
    }
}

static int cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return a < b ? -1 : a > b;
}

static double quantile(double *v, size_t n, double q)
{
    if (!n)
        return 0;
    qsort(v, n, sizeof *v, cmp_double);
    size_t k = (size_t)(q * (double)(n - 1) + 0.5);
    return v[k];
}

#define TOP_HOLD_NS (5 * SEC) /* as long as a notice line stays on the HUD */
#define TOP_EASE_S 0.15

/* The rows the view keeps clear at the top (hud px, ftm_render_view_top),
 * held at the largest of the last TOP_HOLD_NS so that a line that comes
 * and goes does not move the tissue back and forth, and eased over
 * ~TOP_EASE_S when it changes; at once with the HUD off. */
static double frame_top(app *a, double hud, int64_t now, double dt)
{
    if (hud >= a->top_hold || hud <= 0 || now >= a->top_hold_until) {
        a->top_hold = hud;
        a->top_hold_until = now + TOP_HOLD_NS;
    }
    double k = dt / TOP_EASE_S;
    if (!a->top_set || hud <= 0 || !(k < 1))
        k = 1;
    a->view_top += (a->top_hold - a->view_top) * k;
    a->top_set = true;
    return a->view_top;
}

static int save_screenshot(app *a, const ftm_client_view *v, int w, int h)
{
    uint8_t *px = malloc((size_t)w * (size_t)h * 3);
    if (!px) {
        alog(a, FTM_LOG_ERROR, "screenshot: out of memory");
        return -1;
    }
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, px);
    ftm_error err = {0, ""};
    int rc = ftm_screenshot_write_png(a->o.screenshot, w, h, px, &err);
    free(px);
    if (rc) {
        alog(a, FTM_LOG_ERROR, "%s", err.message);
        return -1;
    }
    /* where the first contact is on screen, for tests that look there */
    char where[64] = "contact none";
    for (int32_t i = 0; i < v->nprobes; i++) {
        double x, y;
        if (v->probes[i].in_contact &&
            ftm_camera_project(&a->cam, w, h, a->view_top, v->probes[i].contact, &x, &y)) {
            snprintf(where, sizeof where, "contact %.0f %.0f", x, y);
            break;
        }
    }
    /* and the middle of the first probe's shaft (the instrument drawn) */
    char shaft[48] = "shaft none", label[48] = "label none";
    for (int32_t i = 0; i < v->nprobes; i++) {
        ftm_instrument in;
        double x, y;
        if (!v->probes[i].have_hip)
            continue;
        ftm_render_instrument(a->ren, &v->probes[i], &in);
        const double k = in.tip_radius + 0.5 * in.shaft_length;
        const ftm_vec3 m = {in.tip.x + k * in.axis.x, in.tip.y + k * in.axis.y,
                            in.tip.z + k * in.axis.z};
        if (ftm_camera_project(&a->cam, w, h, a->view_top, m, &x, &y))
            snprintf(shaft, sizeof shaft, "shaft %.0f %.0f", x, y);
        /* the shaft's top: its name label starts just right of it, above */
        const double u = 2.0 * in.tip_radius + in.shaft_length;
        const ftm_vec3 top = {in.tip.x + u * in.axis.x, in.tip.y + u * in.axis.y,
                              in.tip.z + u * in.axis.z};
        if (ftm_camera_project(&a->cam, w, h, a->view_top, top, &x, &y))
            snprintf(label, sizeof label, "label %.0f %.0f", x, y);
        break;
    }
    printf("screenshot %s %dx%d tick %" PRIu64 " view-top %.0f %s %s %s\n", a->o.screenshot, w, h,
           v->tick, a->view_top, label, shaft, where);
    /* the legend and a point of each tissue in sight, for the tests' colour checks */
    float box[4];
    ftm_render_legend_box(a->ren, box);
    if (box[2] > box[0])
        printf("legend %.0f %.0f %.0f %.0f\n", box[0], box[1], box[2], box[3]);
    const ftm_tissue *tis;
    int32_t ntis = ftm_render_tissues(a->ren, &tis);
    const ftm_vec3 eye = ftm_camera_eye(&a->cam);
    for (int32_t i = 0; i < ntis; i++) {
        ftm_vec3 p;
        double x, y;
        if (ftm_render_tissue_point(a->ren, tis[i].label, eye, &p) &&
            ftm_camera_project(&a->cam, w, h, a->view_top, p, &x, &y))
            printf("tissue %d %.0f %.0f %.3f %.3f %.3f\n", (int)tis[i].label, x, y,
                   tis[i].color[0], tis[i].color[1], tis[i].color[2]);
    }
    fflush(stdout);
    alog(a, FTM_LOG_INFO, "screenshot %s: %dx%d, tick %" PRIu64 ", %s, view below row %.0f",
         a->o.screenshot, w, h, v->tick, where, a->view_top);
    return 0;
}

static bool shot_ready(const app *a, const ftm_client_view *v, double elapsed)
{
    if (a->o.shot_after > 0)
        return elapsed >= a->o.shot_after;
    if (!v->caught_up || !v->mesh || a->drawn_mesh != v->mesh || v->node_count == 0)
        return false;
    if (a->o.shot_hold && v->tick < a->o.shot_tick)
        return false;
    if (a->o.shot_contact >= 0 && v->contact_ticks < (uint64_t)a->o.shot_contact)
        return false;
    return true;
}

/* The HUD's figures, and the own probe's HIP straight from the haptic
 * loop (no delay) into what is drawn. */
static void hud_info(app *a, ftm_client_view *draw, ftm_hud_info *info, int64_t now, double fps)
{
    memset(info, 0, sizeof *info);
    if (a->hap) {
        ftm_haptic_state st;
        ftm_haptic_get_state(a->hap, &st);
        int32_t j = 0;
        while (j < draw->nprobes && !(draw->probes[j].own && draw->probes[j].probe == 0))
            j++;
        if (j == draw->nprobes && j < FTM_CLIENT_MAX_PROBES) {
            memset(&draw->probes[j], 0, sizeof draw->probes[j]);
            draw->probes[j].own = true;
            draw->probes[j].participant = a->o.id;
            draw->nprobes++;
        }
        if (j < draw->nprobes && st.ticks > 0) {
            ftm_client_probe *p = &draw->probes[j];
            p->have_hip = true;
            p->hip = st.hip;
            /* where the probe is: its push depth below the surface where the
             * contact began, or its height above the surface below it */
            if (p->in_contact && p->has_plane) {
                const ftm_vec3 n = p->plane_normal, h = p->hip, q = p->plane_point;
                double nn = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
                if (nn > 0) {
                    info->probe_where = FTM_HUD_PROBE_PRESSING;
                    info->probe_mm =
                        -((h.x - q.x) * n.x + (h.y - q.y) * n.y + (h.z - q.z) * n.z) / nn * 1e3;
                }
            } else if (!p->in_contact && a->view.mesh) {
                ftm_instrument in;
                ftm_render_instrument(a->ren, p, &in);
                double d;
                info->probe_where = FTM_HUD_PROBE_NOTHING_BELOW;
                if (ftm_render_surface_along(a->ren, in.tip,
                                             (ftm_vec3){-in.axis.x, -in.axis.y, -in.axis.z}, &d,
                                             NULL)) {
                    info->probe_where = FTM_HUD_PROBE_ABOVE;
                    info->probe_mm = d * 1e3;
                }
            }
        }
        info->haptic = true;
        info->force = st.force;
        info->haptic_flags = st.flags;
        info->renderer = ftm_haptic_renderer_name(st.renderer);
    }
    info->role = a->role;
    info->id = a->o.id;
    info->session = a->o.session;
    info->fps = fps;
    info->frame_ms = fps > 0 ? 1e3 / fps : 0;
    info->triangles = ftm_render_triangle_count(a->ren);
    info->colormap = a->ropts.colormap;
    info->region = a->ropts.region;
    info->tissues = ftm_render_tissues(a->ren, NULL) > 0;
    info->volume = ftm_render_has_volume(a->ren) ? (a->ropts.volume ? 1 : -1) : 0;
    info->volume_slices = ftm_render_volume_slices(a->ren);
    info->colormap_full =
        a->ropts.colormap_full > 0 ? a->ropts.colormap_full : 0.5 * ftm_render_link_length(a->ren);
    info->last_command = a->last_cmd[0] ? a->last_cmd : NULL;
    if (a->notice[0] && now < a->notice_until) {
        info->command_outcome = a->notice;
        info->outcome_bad = a->notice_bad;
    }
}

/* The mouse probe moves in the view as it is drawn now. */
static void mouse_view(app *a)
{
    ftm_mouse_view mv;
    mv.eye = ftm_camera_eye(&a->cam);
    ftm_camera_basis(&a->cam, &mv.right, &mv.up, &mv.forward);
    mv.fov_y = a->cam.fovy;
    int ww, wh;
    glfwGetWindowSize(a->win, &ww, &wh);
    mv.width = ww > 0 ? ww : 1;
    mv.height = view_rows(a, wh > 0 ? wh : 1);
    ftm_mouse_set_view(a->dev, &mv);
}

/* --bench: frame times once synced, for --bench seconds. */
typedef struct bench {
    double *dt;
    size_t n, cap;
    int64_t start;
} bench;

/* Takes one frame's time; true when the measurement is over (printed). */
static bool bench_frame(app *a, bench *b, double dt, int w, int h)
{
    if (!b->start) {
        b->start = ftm_clock_mono_ns();
        return false;
    }
    if (b->n == b->cap) {
        size_t c = b->cap ? 2 * b->cap : 4096;
        double *q = realloc(b->dt, c * sizeof *q);
        if (!q)
            return true;
        b->dt = q;
        b->cap = c;
    }
    b->dt[b->n++] = dt;
    if ((double)(ftm_clock_mono_ns() - b->start) * 1e-9 < a->o.bench)
        return false;
    const char *gl_renderer = (const char *)glGetString(GL_RENDERER);
    const int tris = (int)ftm_render_triangle_count(a->ren);
    double sum = 0;
    for (size_t i = 0; i < b->n; i++)
        sum += b->dt[i];
    double med = quantile(b->dt, b->n, 0.5), p90 = quantile(b->dt, b->n, 0.9);
    double p10 = quantile(b->dt, b->n, 0.1);
    printf("bench: %d triangles, %dx%d, %s: %zu frames in %.1f s = %.1f fps; frame "
           "time median %.2f ms (%.1f fps), p10 %.2f ms, p90 %.2f ms\n",
           tris, w, h, gl_renderer, b->n, sum, sum > 0 ? (double)b->n / sum : 0.0, med * 1e3,
           med > 0 ? 1.0 / med : 0.0, p10 * 1e3, p90 * 1e3);
    if (a->o.json)
        printf("{\"triangles\": %d, \"width\": %d, \"height\": %d, \"renderer\": \"%s\", "
               "\"frames\": %zu, \"seconds\": %.3f, \"fps_mean\": %.2f, "
               "\"frame_ms_median\": %.3f, \"fps_median\": %.2f, \"frame_ms_p10\": %.3f, "
               "\"frame_ms_p90\": %.3f}\n",
               tris, w, h, gl_renderer, b->n, sum, sum > 0 ? (double)b->n / sum : 0.0, med * 1e3,
               med > 0 ? 1.0 / med : 0.0, p10 * 1e3, p90 * 1e3);
    fflush(stdout);
    return true;
}

/* What the session thread has for this frame: the view, a command's
 * outcome, the scene's mesh, the camera framed on it. */
#define PROBE_CLEARANCE 0.003 /* [m] above the surface a probe is moved out to */
#define PROBE_INSIDE 0.0005   /* [m] deeper than this at release: left inside */

/* A trainee's mouse probe whose contact ended with it still inside the
 * tissue (an instructor's reset forgets every contact, and the server starts
 * one only where a probe crosses the surface inwards, so the probe would
 * press nothing, at 0 N, issue 27): moved back out above the surface where
 * its contact began, along the way it went in. The server's own release
 * (the HIP back on the outside) leaves it where it is. */
static void probe_out(app *a)
{
    if (!mouse_probe(a) || a->role != FTM_WIRE_ROLE_TRAINEE || !a->view.mesh)
        return;
    for (int32_t i = 0; i < a->view.nprobes; i++) {
        const ftm_client_probe *p = &a->view.probes[i];
        if (p->own && p->probe == 0 && p->in_contact && p->has_plane) {
            if (!a->probe_touching) {
                a->touch_angle = a->touch_peak = 0;
                a->touch_start = ftm_clock_mono_ns();
            }
            a->probe_touching = true;
            a->touch_point = p->plane_point;
            a->touch_normal = p->plane_normal;
            /* the wheel pushes and pulls along the normal where the contact
             * began, whatever the camera does meanwhile (issue 27) */
            const ftm_vec3 n = p->plane_normal;
            ftm_mouse_set_push_axis(a->dev, (ftm_vec3){-n.x, -n.y, -n.z});
            const ftm_vec3 f = p->force;
            double fn = sqrt(f.x * f.x + f.y * f.y + f.z * f.z);
            double nn = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
            if (fn > a->touch_peak)
                a->touch_peak = fn;
            if (fn > 0.05 && nn > 0) { /* (a tiny force's direction is noise) */
                double c = (f.x * n.x + f.y * n.y + f.z * n.z) / (fn * nn);
                double ang = acos(fmax(-1.0, fmin(1.0, c))) * 180.0 / 3.14159265358979323846;
                if (ang > a->touch_angle)
                    a->touch_angle = ang;
            }
            return;
        }
    }
    /* out of contact the wheel lowers the probe straight down (-z, "up" in
     * every FTM scene), along the line drawn to the surface below it */
    ftm_mouse_set_push_axis(a->dev, (ftm_vec3){0, 0, -1});
    if (!a->probe_touching || a->view.state != FTM_WIRE_STATE_SYNCED)
        return; /* (not synced: frames wait, the contact may go on) */
    a->probe_touching = false;
    alog(a, FTM_LOG_INFO,
         "probe: contact released after %.1f s; reaction at most %.0f deg from the surface "
         "normal, peak %.2f N",
         (double)(ftm_clock_mono_ns() - a->touch_start) * 1e-9, a->touch_angle, a->touch_peak);
    ftm_vec3 to;
    if (ftm_mouse_out_of_tissue(a->dev, a->touch_point, a->touch_normal, PROBE_CLEARANCE,
                                PROBE_INSIDE, &to) == 1)
        alog(a, FTM_LOG_INFO,
             "probe: the contact ended with the probe inside the tissue (reset?); moved out to "
             "(%.4f, %.4f, %.4f), %.1f mm above the surface",
             to.x, to.y, to.z, PROBE_CLEARANCE * 1e3);
}

/* Key u: the mouse probe back above the tissue, at the height it started
 * at, over where it is now (within the scene's box). */
static void probe_lift(app *a)
{
    if (!mouse_probe(a) || a->role != FTM_WIRE_ROLE_TRAINEE || !a->view.mesh) {
        notice(a, true, "u (probe up): only a trainee's mouse probe");
        return;
    }
    ftm_vec3 hip, lo, hi;
    ftm_mouse_target(a->dev, &hip);
    mesh_box(a->view.mesh, &lo, &hi);
    hip.x = fmin(fmax(hip.x, lo.x), hi.x);
    hip.y = fmin(fmax(hip.y, lo.y), hi.y);
    hip.z = a->probe_lift_z;
    ftm_mouse_set_hip(a->dev, hip);
    alog(a, FTM_LOG_INFO, "probe: back above the tissue at (%.4f, %.4f, %.4f) (key u)", hip.x,
         hip.y, hip.z);
}

static void take_view(app *a, int64_t now)
{
    bool changed = ftm_client_session_snapshot(a->sess, &a->view);
    if (a->view.outcome_seq != a->outcome_seen) { /* the session thread logged it */
        a->outcome_seen = a->view.outcome_seq;
        snprintf(a->notice, sizeof a->notice, "%s", a->view.outcome);
        a->notice_bad = a->view.outcome_bad;
        a->notice_until = now + NOTICE_NS;
    }
    scripted_commands(a);
    if (a->view.mesh != a->drawn_mesh)
        new_mesh(a);
    probe_out(a);
    if (changed)
        ftm_render_update(a->ren, &a->view);
    if (!a->cam_set && a->view.mesh) {
        ftm_vec3 lo, hi;
        mesh_box(a->view.mesh, &lo, &hi);
        ftm_camera_frame(&a->cam, lo, hi);
        a->cam_set = true;
    }
}

/* --max-fps: waits for the next frame's deadline, handling input meanwhile
 * (glfwWaitEventsTimeout runs the callbacks as events come). The swap
 * interval alone does not hold a rate where the display does not throttle
 * (Xvfb, some compositors), and an uncapped client drew 130-200 fps on a
 * classroom PC (issue 27). A frame later than a whole period moves the
 * deadline to now, rather than drawing a burst to catch up. */
static void pace(app *a, int64_t *deadline, int64_t period)
{
    int64_t now = ftm_clock_mono_ns();
    *deadline = *deadline ? *deadline + period : now + period;
    if (*deadline < now - period)
        *deadline = now;
    while ((now = ftm_clock_mono_ns()) < *deadline && !g_stop && !glfwWindowShouldClose(a->win))
        glfwWaitEventsTimeout((double)(*deadline - now) * 1e-9);
}

/* The render loop until the window closes, a signal, --duration, or a
 * --screenshot or --bench that is done. Returns the exit status. */
static int run(app *a)
{
    int rc_exit = 0;
    int64_t start = ftm_clock_mono_ns(), last = start;
    double fps = 0;
    bench b = {0};
    uint64_t frames = 0;
    int64_t deadline = 0;
    const int64_t period = a->o.max_fps > 0 && !(a->o.bench > 0) ? 1000000000LL / a->o.max_fps : 0;
    char lines[FTM_HUD_LINES][FTM_HUD_WIDTH], help_lines[FTM_HUD_LINES][FTM_HUD_WIDTH];
    const char *hud[FTM_HUD_LINES], *help[FTM_HUD_LINES];
    ftm_client_view draw;
    while (!glfwWindowShouldClose(a->win) && !g_stop) {
        glfwPollEvents();
        int64_t now = ftm_clock_mono_ns();
        double dt = (double)(now - last) * 1e-9;
        last = now;
        if (dt > 0)
            fps = fps > 0 ? 0.9 * fps + 0.1 / dt : 1.0 / dt;
        take_view(a, now);
        int w, h;
        glfwGetFramebufferSize(a->win, &w, &h);
        if (w <= 0 || h <= 0) {
            glfwWaitEventsTimeout(0.05);
            continue;
        }
        draw = a->view;
        ftm_hud_info info;
        hud_info(a, &draw, &info, now, fps);
        if (mouse_probe(a))
            mouse_view(a);
        int nhud = ftm_hud_lines(&draw, &info, lines);
        /* a narrow window: rows wrapped to its width, none cut off */
        nhud = ftm_hud_wrap(lines, nhud, ftm_hud_columns(w, a->ropts.text_scale));
        for (int i = 0; i < nhud; i++) {
            hud[i] = lines[i];
            /* a picker row: "  K  NAME  (...)" (hud.c) */
            const char *l = lines[i];
            int k = l[0] == ' ' && l[1] == ' ' && l[2] >= '1' && l[2] <= '9' && l[3] == ' ' &&
                            l[4] == ' '
                        ? l[2] - '0'
                        : 0;
            a->pick_row[i] = !draw.announced && k <= draw.nsessions ? k : 0;
        }
        a->pick_rows = nhud;
        a->ropts.nhelp = 0;
        if (a->help) {
            a->ropts.nhelp = ftm_hud_help(a->role, mouse_probe(a), ftm_render_has_volume(a->ren),
                                          ftm_render_tissues(a->ren, NULL) > 0, help_lines);
            for (int i = 0; i < a->ropts.nhelp; i++)
                help[i] = help_lines[i];
            a->ropts.help = help;
        }
        a->fb_h = h;
        double top = frame_top(a, ftm_render_view_top(&a->ropts, nhud), now, dt);
        ftm_render_draw(a->ren, &draw, &a->cam, w, h, top, &a->ropts, hud, nhud);
        const double el = (double)(now - start) * 1e-9;
        if (a->o.screenshot) {
            bool late = el > a->o.shot_timeout && !(a->o.shot_after > 0);
            if (shot_ready(a, &draw, el) || late) {
                if (late)
                    alog(a, FTM_LOG_ERROR,
                         "screenshot: condition not met in %.0f s (%s); saving what is shown",
                         a->o.shot_timeout, draw.banner[0] ? draw.banner : "no banner");
                if (save_screenshot(a, &draw, w, h) || late)
                    rc_exit = 1;
                break;
            }
        }
        glfwSwapBuffers(a->win);
        if (a->o.bench > 0 && draw.synced_once && a->drawn_mesh) {
            if (bench_frame(a, &b, dt, w, h))
                break;
        } else if (a->o.bench > 0 && el > 60.0) {
            alog(a, FTM_LOG_ERROR, "bench: not synced with a scene after 60 s");
            rc_exit = 1;
            break;
        }
        frames++;
        if (a->o.duration > 0 && el >= a->o.duration)
            break;
        if (period)
            pace(a, &deadline, period);
    }
    const double secs = (double)(ftm_clock_mono_ns() - start) * 1e-9;
    char how[48];
    if (period)
        snprintf(how, sizeof how, "--max-fps %d", a->o.max_fps);
    else
        snprintf(how, sizeof how, "%s", a->o.bench > 0 ? "uncapped for --bench" : "uncapped");
    alog(a, FTM_LOG_INFO, "drew %" PRIu64 " frames in %.2f s (%.1f fps; %s)", frames, secs,
         secs > 0 ? (double)frames / secs : 0.0, how);
    free(b.dt);
    return rc_exit;
}

/* The arguments taken together, the --commands script and a trainee's
 * device: refused before anything opens. Returns 0, or the exit status
 * (2 a bad argument, 3 out of memory). */
static int check_args(app *a)
{
    a->role = strcmp(a->o.role, "trainee") == 0      ? FTM_WIRE_ROLE_TRAINEE
              : strcmp(a->o.role, "instructor") == 0 ? FTM_WIRE_ROLE_INSTRUCTOR
                                                     : FTM_WIRE_ROLE_OBSERVER; /* (parse_role) */
    if (ftm_haptic_renderer_parse(a->o.renderer, &a->hap_def.renderer)) {
        fprintf(stderr, "ftm-client: --renderer must be model or extrapolate\n");
        return 2;
    }
    if (strcmp(a->o.device, "mouse") != 0 && strncmp(a->o.device, "script:", 7) != 0) {
        fprintf(stderr, "ftm-client: --device must be mouse or script:FILE\n");
        return 2;
    }
    if (a->o.commands && a->role != FTM_WIRE_ROLE_INSTRUCTOR) {
        fprintf(stderr, "ftm-client: --commands needs --role instructor\n");
        return 2;
    }
    if ((a->o.device_given || a->o.renderer_given) && a->role != FTM_WIRE_ROLE_TRAINEE) {
        fprintf(stderr, "ftm-client: %s needs --role trainee (an %s has no probe)\n",
                a->o.device_given ? "--device" : "--renderer", a->o.role);
        return 2;
    }
    if (ftm_client_options_check_outputs(&a->o))
        return 2;
    if (a->o.commands) {
        if (ftm_script_load(a->o.commands, &a->cmds)) /* says FILE:LINE: why */
            return 2;
        a->have_cmds = true;
        /* an instructor's probe feels nothing: refused, as by an instructor ftm-bot */
        if (a->cmds.nexpects > 0) {
            fprintf(stderr, "ftm-client: %s:%d: 'expect' is checked by a trainee ftm-bot only, "
                            "not by --commands\n", a->o.commands, (int)a->cmds.expects[0].e.line);
            return 2;
        }
    }
    if (a->role != FTM_WIRE_ROLE_TRAINEE)
        return 0;
    /* a trainee's device before the window: a bad script is a bad
     * argument (status 2), said before anything opens */
    ftm_error derr = {0, ""};
    struct stat st;
    const char *file = a->o.device + 7;
    int drc;
    if (strcmp(a->o.device, "mouse") == 0)
        drc = ftm_mouse_create(NULL, (ftm_vec3){0, 0, 1}, 0.0, -1.0, &a->dev, &derr);
    else if (stat(file, &st) == 0 && S_ISDIR(st.st_mode))
        drc = FTM_EIO, snprintf(derr.message, sizeof derr.message, "%s: is a directory", file);
    else
        drc = ftm_script_device_open(file, NULL, &a->dev, &derr); /* says FILE:LINE: why */
    if (drc) {
        fprintf(stderr, "ftm-client: --device %s: %s\n", a->o.device, derr.message);
        return drc == FTM_ENOMEM ? 3 : 2;
    }
    return 0;
}

/* The GLFW window, OpenGL 3.3 core and the renderer; false after saying why. */
static bool open_window(app *a)
{
    glfwSetErrorCallback(on_glfw_error);
    if (!glfwInit()) {
        alog(a, FTM_LOG_ERROR, "cannot initialise GLFW (no display? try xvfb-run)");
        return false;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_SAMPLES, a->o.msaa);
    char title[160];
    snprintf(title, sizeof title, "ftm-client: %s, session %s", a->o.role, a->o.session);
    a->win = glfwCreateWindow(a->o.size.width, a->o.size.height, title, NULL, NULL);
    if (!a->win) {
        alog(a, FTM_LOG_ERROR, "cannot open an OpenGL 3.3 core window");
        return false;
    }
    glfwMakeContextCurrent(a->win);
    glfwSwapInterval(a->o.bench > 0 ? 0 : a->o.swap_interval);
    if (a->o.msaa > 0)
        glEnable(GL_MULTISAMPLE);
    alog(a, FTM_LOG_INFO, "OpenGL %s on %s", (const char *)glGetString(GL_VERSION),
         (const char *)glGetString(GL_RENDERER));
    ftm_error err = {0, ""};
    if (ftm_render_create(&a->ren, &err)) {
        alog(a, FTM_LOG_ERROR, "%s", err.message);
        return false;
    }
    glfwSetWindowUserPointer(a->win, a);
    glfwSetKeyCallback(a->win, on_key);
    glfwSetCharCallback(a->win, on_char);
    glfwSetMouseButtonCallback(a->win, on_button);
    glfwSetCursorPosCallback(a->win, on_cursor);
    glfwSetScrollCallback(a->win, on_scroll);
    return true;
}

/* A trainee's 1 kHz haptic loop (highest priority) on its device, and the
 * session thread; false after saying why. */
static bool start(app *a)
{
    ftm_error err = {0, ""};
    if (a->role == FTM_WIRE_ROLE_TRAINEE) {
        ftm_haptic_def hd = ftm_default_haptic_def();
        hd.renderer = a->hap_def.renderer;
        hd.log = app_log;
        hd.log_user = a;
        a->hap_def = hd;
        if (ftm_haptic_create(&hd, a->dev, &a->hap, &err) || ftm_haptic_start(a->hap, &err)) {
            alog(a, FTM_LOG_ERROR, "haptic loop: %s", err.message);
            return false;
        }
        ftm_haptic_set_connected(a->hap, false); /* no force before the replica is synced */
    }
    return start_session(a);
}

/* The session thread, on a->o.session; false after saying why. */
static bool start_session(app *a)
{
    ftm_error err = {0, ""};
    ftm_client_config cc = {
        .role = a->role, .scene = a->o.scene, .session = a->o.session, .dds_config = a->o.config,
        .dds_security = a->o.security, .domain = a->o.domain, .id = a->o.id,
        .name = a->o.name ? a->o.name : a->o.role, .server_timeout = a->o.server_timeout,
        .hold = a->o.shot_hold, .hold_tick = a->o.shot_tick, .log = app_log, .log_user = a,
        .on_force = on_force, .force_user = a,
        .take_hips = a->hap ? take_hips : NULL, .hip_user = a};
    if (ftm_client_session_start(&cc, &a->sess, &err)) {
        alog(a, FTM_LOG_ERROR, "%s", err.message);
        return false;
    }
    ftm_client_session_want_region(a->sess, a->ropts.region);
    alog(a, FTM_LOG_INFO, "%s %u joining session '%s' on domain %u", a->o.role, a->o.id,
         a->o.session, a->o.domain);
    return true;
}

/* --list: the sessions on the domain, then exit (0; 3 when DDS fails). */
static int list_sessions(const ftm_client_options *o)
{
    ftm_sessions_def d = ftm_default_sessions_def();
    d.domain = o->domain;
    d.dds_config = o->config;
    d.dds_security = o->security;
    d.participant_id = o->id;
    d.seconds = o->duration;
    return ftm_sessions_list_command("ftm-client", &d);
}

int main(int argc, char **argv)
{
    static app aa;
    app *a = &aa;
    a->t0 = ftm_clock_mono_ns();
#ifdef __GLIBC__
    /* Mesa's llvmpipe allocates and frees megabytes a frame (a volume's
     * triangles in its bins); glibc would hand them back to the kernel and
     * fault them in again the next frame, which took most of a frame's
     * time on the head under a VM (docs/client.md, Frame rate): keep them */
    mallopt(M_TRIM_THRESHOLD, 256 << 20);
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
#endif
    int rc = ftm_client_options_parse(argc, argv, &a->o);
    if (rc >= 0)
        return rc;
    if (a->o.list)
        return list_sessions(&a->o);
    if (a->o.id == 0)
        a->o.id = (uint32_t)(((uint64_t)getpid() * 2654435761u) ^ (uint64_t)time(NULL)) | 1u;
    rc = check_args(a);
    if (rc == 0 && a->o.log_path && !(a->logf = fopen(a->o.log_path, "w"))) {
        fprintf(stderr, "ftm-client: cannot open %s: %s\n", a->o.log_path, strerror(errno));
        rc = 3;
    }
    if (rc == 0) {
        signal(SIGINT, on_signal);
        signal(SIGTERM, on_signal);
        a->ropts = ftm_render_default_opts();
        /* tissue's own colour by default: the map is a teaching aid (key c) */
        a->ropts.colormap = a->o.colormap && !a->o.no_colormap;
        a->ropts.region = a->o.region;
        a->ropts.hud = !a->o.no_hud;
        a->ropts.volume = !a->o.no_volume;
        a->ropts.cut = a->o.cut;
        a->ropts.volume_step = a->o.volume_step;
        a->ropts.volume_scale = a->o.volume_scale;
        a->ropts.colormap_full = a->o.colormap_full;
        /* window and GL first: without a display there is nothing to join for */
        rc = open_window(a) && start(a) ? run(a) : 3;
        ftm_client_session_stop(a->sess);
        ftm_haptic_destroy(a->hap);
        ftm_client_view_free(&a->view);
        ftm_render_destroy(a->ren);
        if (a->win)
            glfwDestroyWindow(a->win);
        glfwTerminate();
    }
    ftm_device_destroy(a->dev); /* (the haptic loop, its user, is gone) */
    if (a->have_cmds)
        ftm_script_free(&a->cmds);
    if (a->logf)
        fclose(a->logf);
    return rc;
}
