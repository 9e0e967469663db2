/* SPDX-License-Identifier: GPL-3.0-or-later */
/* A small bitmap font for the HUD: 5x7 glyphs in 6x8 cells, designed for
 * this project (no font data from elsewhere). Printable ASCII, lower case
 * its own (with one-row descenders in the cell's spacing row), so that a
 * session's or a participant's name shows in its own case. No GL here: render.c builds a texture from
 * ftm_font_pixels. */
#ifndef FTM_CLIENT_FONT_H
#define FTM_CLIENT_FONT_H

#include <stdint.h>

#define FTM_FONT_CELL_W 6 /* glyph 5 + 1 column of spacing */
#define FTM_FONT_CELL_H 8 /* glyph 7 + 1 row of spacing */
#define FTM_FONT_FIRST 32
#define FTM_FONT_COUNT 96 /* 32..126, plus a solid block at 127 for filled boxes */

/* Index of the glyph drawing character c ('?' for anything unknown). */
int ftm_font_glyph(unsigned char c);

/* Writes the atlas: FTM_FONT_COUNT cells side by side, one byte per pixel
 * (0 or 255), row 0 at the top. out must hold FTM_FONT_COUNT * CELL_W * CELL_H. */
void ftm_font_pixels(uint8_t *out);

#endif
