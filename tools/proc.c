/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Processes of a session benchmark: see proc.h. */
#define _GNU_SOURCE /* sched_setaffinity */
#include "proc.h"

#include <errno.h>
#include <ftw.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

double ftm_proc_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void ftm_proc_sleep_s(double s)
{
    struct timespec ts = {(time_t)s, (long)((s - floor(s)) * 1e9)};
    nanosleep(&ts, NULL);
}

static void bind_cpu(int cpu)
{
    if (cpu == -1)
        return;
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    cpu_set_t set;
    CPU_ZERO(&set);
    if (cpu >= 0) {
        CPU_SET(cpu, &set);
    } else {
        for (long c = 0; c < ncpu && c < CPU_SETSIZE; c++)
            if (c != -cpu - 2)
                CPU_SET((int)c, &set);
        if (CPU_COUNT(&set) == 0)
            return; /* one CPU: share it */
    }
    if (sched_setaffinity(0, sizeof set, &set))
        fprintf(stderr, "cannot bind to cpu %d: %s (running unbound)\n", cpu, strerror(errno));
}

pid_t ftm_proc_spawn(char *const argv[], const char *out, const char *err, const char *dds_uri,
                     int cpu)
{
    pid_t pid = fork();
    if (pid != 0)
        return pid;
    int fo = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int fe = open(err, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fo < 0 || fe < 0 || dup2(fo, 1) < 0 || dup2(fe, 2) < 0)
        _exit(126);
    close(fo);
    close(fe);
    if (dds_uri)
        setenv("CYCLONEDDS_URI", dds_uri, 1);
    bind_cpu(cpu);
    execv(argv[0], argv);
    fprintf(stderr, "cannot run %s: %s\n", argv[0], strerror(errno));
    _exit(127);
}

int ftm_proc_wait(pid_t pid, double timeout)
{
    double end = ftm_proc_now_s() + timeout;
    int st = 0;
    for (;;) {
        pid_t r = waitpid(pid, &st, WNOHANG);
        if (r == pid)
            break;
        if (r < 0)
            return -1;
        if (ftm_proc_now_s() > end) {
            kill(pid, SIGKILL);
            waitpid(pid, &st, 0);
            break;
        }
        ftm_proc_sleep_s(0.05);
    }
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + (WIFSIGNALED(st) ? WTERMSIG(st) : 0);
}

char *ftm_proc_slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s) {
        size_t got = fread(s, 1, (size_t)n, f);
        s[got] = '\0';
    }
    fclose(f);
    return s;
}

bool ftm_proc_wait_text(const char *path, const char *text, double timeout)
{
    double end = ftm_proc_now_s() + timeout;
    while (ftm_proc_now_s() < end) {
        char *s = ftm_proc_slurp(path);
        bool found = s && strstr(s, text);
        free(s);
        if (found)
            return true;
        ftm_proc_sleep_s(0.05);
    }
    return false;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double ftm_proc_quantile(double *v, size_t n, double q)
{
    if (n == 0)
        return NAN;
    qsort(v, n, sizeof *v, cmp_double);
    size_t k = (size_t)ceil(q * (double)n);
    return v[k ? k - 1 : 0];
}

const char *ftm_proc_sibling(const char *rel)
{
    static char buf[2][1024];
    static int k;
    char self[900];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return NULL;
    self[n] = '\0';
    char *slash = strrchr(self, '/');
    if (slash)
        *slash = '\0';
    k ^= 1;
    snprintf(buf[k], sizeof buf[k], "%s/%s", self, rel);
    return buf[k];
}

static int remove_one(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)st, (void)flag, (void)ftw;
    return remove(path);
}

int ftm_proc_remove_tree(const char *dir)
{
    return nftw(dir, remove_one, 16, FTW_DEPTH | FTW_PHYS);
}

int ftm_proc_find_programs(const char *who, const char **server, const char **bot)
{
    if (!*server)
        *server = ftm_proc_sibling("../server/ftm-server");
    if (!*bot)
        *bot = ftm_proc_sibling("../bot/ftm-bot");
    if (*server && *bot && access(*server, X_OK) == 0 && access(*bot, X_OK) == 0)
        return 0;
    fprintf(stderr, "%s: cannot find ftm-server/ftm-bot (%s, %s); use --server and --bot\n", who,
            *server ? *server : "?", *bot ? *bot : "?");
    return -1;
}

const char *ftm_proc_server_ticks(const char *log, uint64_t *ticks, double *seconds,
                                  uint64_t *missed)
{
    const char *p = strstr(log, " ticks in ");
    if (!p)
        return NULL;
    while (p > log && p[-1] >= '0' && p[-1] <= '9')
        p--;
    double rate;
    if (sscanf(p, "%" SCNu64 " ticks in %lf s (%lf ticks/s), %" SCNu64 " missed", ticks, seconds,
               &rate, missed) != 4)
        return NULL;
    return p;
}
