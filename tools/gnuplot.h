/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Running gnuplot for the commands' pictures: a script the command wrote is
 * drawn if gnuplot is there, and skipped with a message if not. */
#ifndef FTM_TOOLS_GNUPLOT_H
#define FTM_TOOLS_GNUPLOT_H

#include <stddef.h>
#include <stdio.h>

/* gnuplot's path: $FTM_GNUPLOT (tests set it to a missing program), else
 * `gnuplot` searched on PATH. NULL if there is none. */
const char *ftm_gnuplot_find(char *buf, size_t size);

/* Runs gnuplot on script. 0 drawn, 1 skipped (no gnuplot: "WHO: gnuplot not
 * found: no picture ..." on stderr), -1 gnuplot failed ("WHO: ... failed: no
 * picture"). */
int ftm_gnuplot_run(const char *who, const char *script);

/* Writes s as a gnuplot single-quoted literal ('' stands for '). */
void ftm_gnuplot_quote(FILE *f, const char *s);

#endif
