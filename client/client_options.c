/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-client's command line (client_options.h). */
#include "client_options.h"
#include "cli.h"
#include "volume_render.h"

#include "ftm/options.h"

#include <errno.h>
#include <float.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int parse_role(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    if (strcmp(v, "trainee") && strcmp(v, "instructor") && strcmp(v, "observer")) {
        snprintf(why, cap, "must be trainee, instructor or observer (got '%s')", v);
        return -1;
    }
    memcpy(field, &v, sizeof v);
    return 0;
}

/* two whole numbers and an x, nothing else ("100x100junk", " 100x 100") */
static int parse_size(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    const char *x = strchr(v, 'x');
    long long w = 0, h = 0;
    if (!x || !ftm_option_int(v, (size_t)(x - v), 64, 8192, &w) ||
        !ftm_option_int(x + 1, strlen(x + 1), 64, 8192, &h)) {
        snprintf(why, cap, "must be WxH, each 64..8192 (got '%s')", v);
        return -1;
    }
    const int size[2] = {(int)w, (int)h};
    memcpy(field, size, sizeof size);
    return 0;
}

/* a divisor of the 10 slices per lattice cell, so that the node planes stay */
static int parse_volume_step(const ftm_option *o, const char *v, void *field, char *why,
                             size_t cap)
{
    long long n = 0;
    if (!ftm_option_int(v, strlen(v), 1, 10, &n) || 10 % n != 0) {
        snprintf(why, cap, "must be 1, 2, 5 or 10, a divisor of the 10 slices per lattice cell "
                           "(got '%s')", v);
        return -1;
    }
    const int step = (int)n;
    memcpy(field, &step, sizeof step);
    return 0;
}

#define O ftm_client_options
#define SECONDS FTM_OPTION_SECONDS_MAX
static const ftm_option option_table[] = {
    FTM_OPT_CUSTOM("role", "trainee|instructor|observer", O, role, parse_role,
                   "the participant's role (default observer)"),
    FTM_OPT_SECTION("session:"),
    FTM_OPT_STRING("session", "NAME", O, session, "session name (default ftm)"),
    FTM_OPT_INT("domain", "N", O, domain, 0, FTM_OPTION_DOMAIN_MAX, "DDS domain (default 0)"),
    FTM_OPT_STRING("config", "FILE", O, config, "Cyclone DDS configuration (deploy/cyclonedds-*.xml)"),
    FTM_OPT_STRING("security", "DIR", O, security,
                   "DDS Security: this participant's identity and permissions\n"
                   "(deploy/ftm-security issue DIR NAME --role ROLE)"),
    FTM_OPT_STRING("scene", "NAME|FILE", O, scene, "local scene (default: the announced scene id)"),
    FTM_OPT_INT("id", "N", O, id, 0, UINT32_MAX, "participant id (default 0: from pid and time)"),
    FTM_OPT_CUSTOM("name", "TEXT", O, name, ftm_option_parse_display_name,
                   "display name, 1..63 bytes, no control characters"),
    FTM_OPT_DOUBLE("server-timeout", "S", O, server_timeout, 0, SECONDS, FTM_OPTION_ABOVE_LO,
                   "seconds",
                   "no tick frames for S s (paused: no server status, sent\n"
                   "every 0.5 s): server counted as gone (default 3)"),
    FTM_OPT_SECTION("instructor:"),
    FTM_OPT_STRING("commands", "FILE", O, commands,
                   "send the timed commands of an ftm-bot script (pause,\n"
                   "resume, reset, stiffness, damping, mass, depth;\n"
                   "docs/bot-script.md) once synced"),
    FTM_OPT_SECTION("trainee:"),
    FTM_OPT_STRING("device", "mouse|script:FILE", O, device, "probe device (default mouse)"),
    FTM_OPT_STRING("renderer", "model|extrapolate", O, renderer,
                   "haptic force renderer (default model)"),
    FTM_OPT_SECTION("view:"),
    FTM_OPT_CUSTOM("size", "WxH", O, size, parse_size, "window size (default 1280x800)"),
    FTM_OPT_FLAG("colormap", O, colormap,
                 "the displacement colour map at start, around the dent only\n"
                 "(key c; off by default: the tissue's own colour)"),
    FTM_OPT_FLAG("no-colormap", O, no_colormap, "no colour map at start (the default)"),
    FTM_OPT_FLAG("region", O, region, "the BFS region drawn at start (key b)"),
    FTM_OPT_FLAG("no-hud", O, no_hud, "no HUD at start (key h)"),
    FTM_OPT_FLAG("no-volume", O, no_volume, "a scene's surface, not its volume (key v)"),
    FTM_OPT_FLAG("cut", O, cut, "the volume cut away through its middle (key x)"),
    FTM_OPT_CUSTOM("volume-step", "N", O, volume_step, parse_volume_step,
                   "a volume's planes per slice drawn: 1 (default: a slice per\n"
                   "plane, 9 between node planes, as the paper), 2, 5, 10 (key\n"
                   "n); each slice samples its N planes: nearly the same picture"),
    FTM_OPT_DOUBLE("volume-scale", "PX", O, volume_scale, 0, FTM_VOLUME_SCALE_MAX,
                   FTM_OPTION_ABOVE_LO, NULL,
                   "a volume's slices drawn at PX pixels per voxel of its\n"
                   "image, then scaled up over the window (default 1.5; at most\n"
                   "the window's resolution, 16 for it)"),
    FTM_OPT_DOUBLE("colormap-full", "MM", O, colormap_full, 0, DBL_MAX, 0, "millimetres",
                   "displacement at the top of the colour map"),
    FTM_OPT_INT("swap-interval", "N", O, swap_interval, -1, 8,
                "0: no vsync (default 1; -1: adaptive where the driver has it)"),
    FTM_OPT_INT("max-fps", "N", O, max_fps, 0, 1000,
                "draw at most N frames a second, also where the swap\n"
                "interval does not throttle (Xvfb); 0: uncapped (default 60;\n"
                "--bench measures uncapped)"),
    FTM_OPT_INT("msaa", "N", O, msaa, 0, 16,
                "multisample anti-aliasing samples (default 0; 4 looks\n"
                "better on a GPU, costs much under llvmpipe)"),
    FTM_OPT_SECTION("headless:"),
    FTM_OPT_STRING("screenshot", "FILE.png", O, screenshot,
                   "render until the latest tick is applied, save, exit"),
    FTM_OPT_INT("screenshot-tick", "T", O, shot_tick, 0, INT64_MAX,
                "... stop replaying at the first tick >= T instead"),
    FTM_OPT_INT("screenshot-contact", "N", O, shot_contact, 0, INT64_MAX,
                "... wait until a contact has lasted N ticks"),
    FTM_OPT_DOUBLE("screenshot-after", "S", O, shot_after, 0, SECONDS, 0, "seconds",
                   "... take it S s after start, whatever the state"),
    FTM_OPT_DOUBLE("screenshot-timeout", "S", O, shot_timeout, 0, SECONDS, FTM_OPTION_ABOVE_LO,
                   "seconds", "give up after S s: save what is shown, exit 1 (default 60)"),
    FTM_OPT_DOUBLE("bench", "S", O, bench, 0, SECONDS, 0, "seconds",
                   "measure the frame rate for S s once synced, exit"),
    FTM_OPT_FLAG("json", O, json, "--bench result as JSON too"),
    FTM_OPT_DOUBLE("duration", "S", O, duration, 0, SECONDS, 0, "seconds", "exit after S s"),
    FTM_OPT_FLAG("list", O, list,
                 "list the sessions on --domain (scene, server, age, who is there),\n"
                 "heard for 1.5 s (or --duration S), then exit: no window"),
    FTM_OPT_STRING("log", "FILE", O, log_path, "also write the log there"),
    FTM_OPT_FLAG("verbose", O, verbose, "debug messages"),
    {0}};
#undef O
#undef SECONDS

static const ftm_option_set option_set = {
    "ftm-client", "usage: ftm-client [--role trainee|instructor|observer] [options]", option_table,
    "Exit status: 0 done; 1 --screenshot/--bench could not finish in time; 2 usage;\n"
    "3 set-up failure."};

int ftm_client_options_parse(int argc, char **argv, ftm_client_options *o)
{
    *o = (ftm_client_options){.role = "observer", .session = "ftm", .server_timeout = 3.0,
                   .size = {1280, 800}, .swap_interval = 1, .max_fps = 60, .shot_contact = -1,
                   .shot_timeout = 60.0, .volume_step = FTM_VOLUME_STEP_DEFAULT,
                   .volume_scale = FTM_VOLUME_SCALE_DEFAULT, .device = "mouse",
                   .renderer = "model"};
    uint64_t given = 0;
    int rc = ftm_options_parse(&option_set, argc, argv, o, &given, NULL);
    if (rc != FTM_OPTIONS_OK)
        return rc == FTM_OPTIONS_HELP ? 0 : 2;
    o->device_given = ftm_options_given(&option_set, given, "device");
    o->renderer_given = ftm_options_given(&option_set, given, "renderer");
    o->shot_hold = ftm_options_given(&option_set, given, "screenshot-tick");
    if (o->list && !ftm_options_given(&option_set, given, "duration"))
        o->duration = 1.5;
    o->colormap_full *= 1e-3; /* mm */
    return -1;
}

/* Says why an output at path cannot be written, or returns NULL: checked
 * at start, where writing it fails only at the end (a screenshot after its
 * wait). why holds the message. in_dir: the file is made anew in its
 * directory (a screenshot, written under another name first), which must
 * then be writable even if the file exists. */
static const char *unwritable(const char *path, bool in_dir, char *why, size_t n)
{
    struct stat st;
    if (!path[0])
        return snprintf(why, n, "an empty path"), why;
    /* a screenshot is renamed over its path: over a symbolic link, a
     * device or a FIFO (/dev/null as root) that would replace the node */
    if (in_dir && lstat(path, &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode))
        return snprintf(why, n, "is not a regular file (a symbolic link, a device or a "
                                "FIFO): name a file"), why;
    if (stat(path, &st) == 0) {
        if (S_ISDIR(st.st_mode))
            return snprintf(why, n, "is a directory"), why;
        if (access(path, W_OK) != 0)
            return snprintf(why, n, "cannot be written: %s", strerror(errno)), why;
        if (!in_dir)
            return NULL; /* (--log /dev/null) */
    }
    char dir[4096];
    const char *slash = strrchr(path, '/');
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else if (slash == path)
        snprintf(dir, sizeof dir, "/");
    else
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
    if (stat(dir, &st) != 0)
        return snprintf(why, n, "its directory %s: %s", dir, strerror(errno)), why;
    if (!S_ISDIR(st.st_mode))
        return snprintf(why, n, "%s is not a directory", dir), why;
    if (access(dir, W_OK | X_OK) != 0)
        return snprintf(why, n, "its directory %s cannot be written: %s", dir, strerror(errno)), why;
    return NULL;
}

int ftm_client_options_check_outputs(const ftm_client_options *o)
{
    ftm_option_path in[4], out[2];
    int nin = 0, nout = 0;
    if (o->commands)
        in[nin++] = (ftm_option_path){"--commands", o->commands};
    if (o->device && strncmp(o->device, "script:", 7) == 0)
        in[nin++] = (ftm_option_path){"--device", o->device + 7};
    if (o->config)
        in[nin++] = (ftm_option_path){"--config", o->config};
    if (o->scene)
        in[nin++] = (ftm_option_path){"--scene", o->scene}; /* a scene's name is no file: skipped */
    if (o->log_path)
        out[nout++] = (ftm_option_path){"--log", o->log_path};
    if (o->screenshot)
        out[nout++] = (ftm_option_path){"--screenshot", o->screenshot};
    for (int i = 0; i < nout; i++) {
        char why[300];
        if (unwritable(out[i].path, out[i].path == o->screenshot, why, sizeof why)) {
            fprintf(stderr, "ftm-client: %s '%s': %s\n", out[i].opt, out[i].path, why);
            return 2;
        }
        if (i == 1 && strcmp(out[0].path, out[1].path) == 0) {
            fprintf(stderr, "ftm-client: --log and --screenshot are the same file %s\n", out[1].path);
            return 2;
        }
    }
    int k, i;
    if (ftm_option_output_is_input(in, nin, out, nout, &k, &i)) {
        fprintf(stderr, "ftm-client: %s %s is the file %s %s reads: it would be overwritten; "
                        "write to another file\n", out[i].opt, out[i].path, in[k].opt, in[k].path);
        return 2;
    }
    return 0;
}

