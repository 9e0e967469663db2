/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Command-line checks of the session's programs (cli.h). */
#include "cli.h"

#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

int ftm_option_parse_display_name(const ftm_option *o, const char *v, void *field, char *why,
                                  size_t cap)
{
    const size_t n = strlen(v);
    if (n == 0 || n > FTM_DISPLAY_NAME_MAX) {
        snprintf(why, cap, "must be 1..%d bytes (got %zu)", FTM_DISPLAY_NAME_MAX, n);
        return -1;
    }
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)v[i] < 0x20 || (unsigned char)v[i] == 0x7f) {
            snprintf(why, cap, "has control character 0x%02x at byte %zu", (unsigned char)v[i], i);
            return -1;
        }
    memcpy(field, &v, sizeof v);
    return 0;
}

bool ftm_option_output_is_input(const ftm_option_path *in, int nin, const ftm_option_path *out,
                                int nout, int *in_i, int *out_i)
{
    for (int k = 0; k < nin; k++) {
        struct stat si, so;
        if (stat(in[k].path, &si) != 0)
            continue; /* nothing to destroy; reading it fails with its own error */
        for (int i = 0; i < nout; i++) {
            if (stat(out[i].path, &so) == 0 && so.st_dev == si.st_dev && so.st_ino == si.st_ino) {
                *in_i = k;
                *out_i = i;
                return true;
            }
        }
    }
    return false;
}
