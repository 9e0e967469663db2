/* SPDX-License-Identifier: GPL-3.0-or-later */
/* PNG output of the client's window (--screenshot). No GL here: the caller
 * reads the pixels (glReadPixels gives rows bottom-up) and this writes them
 * top-down with libpng. */
#ifndef FTM_CLIENT_SCREENSHOT_H
#define FTM_CLIENT_SCREENSHOT_H

#include "ftm/base.h"

#include <stdint.h>

/* rgb: w*h*3 bytes, rows bottom-up (OpenGL's order), tightly packed.
 * FTM_EIO with a message naming the file on failure. */
int ftm_screenshot_write_png(const char *path, int w, int h, const uint8_t *rgb, ftm_error *err);

#endif
