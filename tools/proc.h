/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Running the session's programs from a benchmark (`ftm bench net`,
 * `ftm bench tick`): start one with its output in files, wait for it with a
 * deadline, read what it wrote. POSIX only; no DDS, no wire layer. */
#ifndef FTM_TOOLS_PROC_H
#define FTM_TOOLS_PROC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

double ftm_proc_now_s(void);           /* monotonic clock [s] */
void ftm_proc_sleep_s(double s);

/* Starts argv[0] with stdout and stderr to the files out and err; with
 * dds_uri, CYCLONEDDS_URI set to it; with cpu >= 0, bound to that CPU (cpu
 * -1: any), or to every CPU but `cpu` when cpu <= -2 (the CPU -cpu - 2 is
 * kept for another process). The child's pid, or -1. */
pid_t ftm_proc_spawn(char *const argv[], const char *out, const char *err, const char *dds_uri,
                     int cpu);

/* Waits for pid up to timeout s, then SIGKILLs it. Its exit status (128 +
 * the signal if a signal ended it), or -1. */
int ftm_proc_wait(pid_t pid, double timeout);

/* A whole file as a string (malloc'd), or NULL. */
char *ftm_proc_slurp(const char *path);

/* Whether the file holds `text` within timeout s (polled every 50 ms). */
bool ftm_proc_wait_text(const char *path, const char *text, double timeout);

/* A program beside this one's executable: the path of `rel` relative to
 * its directory (one of two static buffers). NULL if /proc/self/exe fails. */
const char *ftm_proc_sibling(const char *rel);

/* Removes a directory and everything under it (symbolic links not
 * followed). 0, or -1 with errno. */
int ftm_proc_remove_tree(const char *dir);

/* ftm-server and ftm-bot for a benchmark: *server and *bot as given, or
 * (NULL) the ones beside this executable (../server, ../bot). 0, or -1
 * after saying on stderr, as `who`, what is missing and which options
 * name them. */
int ftm_proc_find_programs(const char *who, const char **server, const char **bot);

/* In an ftm-server log's text, its closing line "N ticks in S s (R ticks/s),
 * M missed": the counts read, and where the line's numbers start (to read
 * on from), or NULL when it is not there. */
const char *ftm_proc_server_ticks(const char *log, uint64_t *ticks, double *seconds,
                                  uint64_t *missed);

/* q-quantile of v[0..n) by nearest rank (sorts v); NAN when n is 0. */
double ftm_proc_quantile(double *v, size_t n, double q);

#endif
