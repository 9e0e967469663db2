/* SPDX-License-Identifier: GPL-3.0-or-later */
/* What the session's programs (ftm-server, ftm-bot, ftm-client) check on
 * their command lines alike, beyond an option's own range (ftm/options.h):
 * a DDS domain, a display name, and outputs that are no input. */
#ifndef FTM_SESSION_CLI_H
#define FTM_SESSION_CLI_H

#include "ftm/options.h"
#include "ftm/wire.h"

#include <stdbool.h>

/* The largest DDS domain an option may name: UINT32_MAX is Cyclone's "the
 * configuration's default", which no wrapped "-1" may pick by accident. */
#define FTM_OPTION_DOMAIN_MAX 4294967294LL

/* A display name (--name) as the protocol carries it: 1..63 bytes, no
 * control characters (the codec refuses them: they would reach others'
 * terminals). An ftm_option_parse_fn for a const char * field. */
#define FTM_DISPLAY_NAME_MAX (FTM_WIRE_DISPLAY_MAX - 1)
int ftm_option_parse_display_name(const ftm_option *o, const char *v, void *field, char *why,
                                  size_t cap);

/* A file a program reads or writes, with the option that names it. */
typedef struct ftm_option_path {
    const char *opt, *path;
} ftm_option_path;
/* Whether an output is one of the inputs, the same file by device and
 * inode (another name, a symlink, a hard link): writing it would destroy
 * the input before it is read. If so, *in_i and *out_i say which; inputs
 * or outputs that do not exist are never the same. */
bool ftm_option_output_is_input(const ftm_option_path *in, int nin, const ftm_option_path *out,
                                int nout, int *in_i, int *out_i);

#endif
