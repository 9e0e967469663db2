/* What the session's programs (ftm-server, ftm-bot, ftm-client) check on
 * their command lines alike, beyond an option's own range (ftm/options.h):
 * a DDS domain, a display name, and outputs that are no input. */
#ifndef FTM_SESSION_CLI_H
#define FTM_SESSION_CLI_H

#include "ftm/options.h"

#include <stdbool.h>

/* An integer option's value for a whole argument v of option opt; if it is no such integer,
 * says "PROGRAM: OPT must be an integer in LO..HI (got 'V')" and returns -1. */
int ftm_option_int_arg(const char *program, const char *opt, const char *v, long long lo,
                       long long hi, long long *out);
/* The largest DDS domain an option may name: UINT32_MAX is Cyclone's "the
 * configuration's default", which no wrapped "-1" may pick by accident. */
#define FTM_OPTION_DOMAIN_MAX 4294967294LL
/* A display name (--name) as the protocol carries it: 1..63 bytes, no
 * control characters (the codec refuses them: they would reach others'
 * terminals). If not, says "PROGRAM: --name ..." and returns -1. */
int ftm_option_name_arg(const char *program, const char *v);
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
