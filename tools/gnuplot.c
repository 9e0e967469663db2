/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Running gnuplot (gnuplot.h). */
#include "gnuplot.h"

#include <spawn.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

const char *ftm_gnuplot_find(char *buf, size_t size)
{
    const char *env = getenv("FTM_GNUPLOT");
    if (env && *env)
        return access(env, X_OK) == 0 ? env : NULL;
    const char *path = getenv("PATH");
    if (!path)
        path = "/usr/bin:/bin";
    while (*path) {
        size_t n = strcspn(path, ":");
        snprintf(buf, size, "%.*s/gnuplot", (int)n, n ? path : ".");
        if (access(buf, X_OK) == 0)
            return buf;
        path += n;
        if (*path == ':')
            path++;
    }
    return NULL;
}

int ftm_gnuplot_run(const char *who, const char *script)
{
    char buf[4096];
    const char *gp = ftm_gnuplot_find(buf, sizeof buf);
    if (!gp) {
        fprintf(stderr,
                "%s: gnuplot not found: no picture (the data and %s are written; Debian: "
                "apt-get install gnuplot-nox)\n",
                who, script);
        return 1;
    }
    char *args[] = {(char *)"gnuplot", (char *)script, NULL};
    pid_t pid;
    int status = 0;
    if (posix_spawn(&pid, gp, NULL, NULL, args, environ) != 0 ||
        waitpid(pid, &status, 0) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "%s: %s %s failed: no picture\n", who, gp, script);
        return -1;
    }
    return 0;
}

void ftm_gnuplot_quote(FILE *f, const char *s)
{
    fputc('\'', f);
    for (; *s; s++) {
        if (*s == '\'')
            fputc('\'', f);
        fputc(*s, f);
    }
    fputc('\'', f);
}
