/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Where FTM programs look for a scene named by another machine
 * (ftm_wire_open_scene): the search list is the deployment's business, so it
 * lives here, beside the protocol, and libftm only walks the list it is given. */
#include "wire_internal.h"

#include "ftm/scene.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifndef FTM_INSTALL_SCENE_DIR
#define FTM_INSTALL_SCENE_DIR "/usr/local/share/ftm/scenes"
#endif

static void append(char *buf, size_t cap, size_t *used, const char *dir, size_t len)
{
    if (len == 0 || *used + len + 2 > cap)
        return; /* no room: the rest of the list is dropped, never cut mid-path */
    if (*used)
        buf[(*used)++] = ':';
    memcpy(buf + *used, dir, len);
    *used += len;
    buf[*used] = '\0';
}

void ftm_wire_scene_search(char *buf, size_t cap)
{
    if (!buf || cap == 0)
        return;
    size_t used = 0;
    buf[0] = '\0';
    const char *env = getenv("FTM_SCENE_PATH");
    if (env)
        append(buf, cap, &used, env, strlen(env));
    /* <prefix>/bin/program -> <prefix>/share/ftm/scenes: an installed tree
     * works wherever it was installed (cmake --install --prefix DIR) */
    char exe[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) {
        exe[n] = '\0';
        char *slash = strrchr(exe, '/');
        if (slash) {
            *slash = '\0';
            char dir[PATH_MAX + 32];
            int len = snprintf(dir, sizeof dir, "%s/../share/ftm/scenes", exe);
            if (len > 0 && (size_t)len < sizeof dir)
                append(buf, cap, &used, dir, (size_t)len);
        }
    }
    append(buf, cap, &used, FTM_INSTALL_SCENE_DIR, strlen(FTM_INSTALL_SCENE_DIR));
}

int ftm_wire_open_scene(const char *scene_id, struct ftm_scene **out, char *path, size_t path_cap,
                        ftm_error *err)
{
    char search[8192];
    ftm_wire_scene_search(search, sizeof search);
    return ftm_scene_open_search(scene_id, search, out, path, path_cap, err);
}
