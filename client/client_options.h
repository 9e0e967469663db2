/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-client's command line (docs/client.md): its option table (the
 * parser and --help, ftm/options.h) and the checks of its outputs before
 * anything is opened. */
#ifndef FTM_CLIENT_OPTIONS_H
#define FTM_CLIENT_OPTIONS_H

#include <stdbool.h>
#include <stdint.h>

typedef struct ftm_client_options {
    const char *role, *scene, *session, *config, *security, *name, *log_path, *device, *renderer;
    const char *commands; /* instructor: timed session commands (bot script format) */
    bool device_given, renderer_given; /* (trainee options: said for another role, refused) */
    uint32_t domain, id;
    double server_timeout, duration;
    struct {
        int width, height;
    } size;
    int swap_interval, msaa;
    int max_fps; /* frames per second at most (0: uncapped; --bench: uncapped) */
    const char *screenshot;
    bool shot_hold; /* --screenshot-tick given */
    uint64_t shot_tick;
    int64_t shot_contact; /* < 0: not asked */
    double shot_after;    /* > 0: at this time whatever the state */
    double shot_timeout;
    double bench;
    bool json;
    bool list; /* --list: print the domain's sessions and exit */
    bool colormap, no_colormap, region, no_hud, no_volume, cut, verbose;
    int volume_step;
    double volume_scale; /* the slices' framebuffer pixels per voxel */
    double colormap_full; /* [m]; given in mm */
} ftm_client_options;

/* The command line into *o (defaults first). Returns -1 to go on, else the
 * exit status: 0 after --help, 2 refused (said on stderr). */
int ftm_client_options_parse(int argc, char **argv, ftm_client_options *o);

/* Before anything is opened for writing, as ftm-server checks its own: an
 * output that is a file the client reads (--commands, the --device
 * script, --config, a --scene file; the same file by device and inode:
 * another name, a link) would be destroyed before it is read, and an
 * output that cannot be written is better said now. Returns 0, or 2 (a bad
 * argument) after saying which. */
int ftm_client_options_check_outputs(const ftm_client_options *o);

#endif
