/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Scratch files for the targets whose parsers read paths. */
#include "fuzz.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char scratch_dir[512];
static char paths[8][640];
static char names[8][64];

static void remove_scratch(void)
{
    for (int i = 0; i < 8; i++)
        if (names[i][0])
            unlink(paths[i]);
    if (scratch_dir[0])
        rmdir(scratch_dir);
}

/* libFuzzer's -close_fd_mask=2 silences the parsers' messages by pointing
 * fd 2 at /dev/null before the first input; a copy taken before main keeps
 * the property failures visible. */
static int report_fd = 2;

__attribute__((constructor)) static void keep_stderr(void)
{
    int fd = dup(2);
    if (fd >= 0)
        report_fd = fd;
}

_Noreturn void fuzz_fail(const char *file, int line, const char *what)
{
    char msg[512];
    int n = snprintf(msg, sizeof msg, "%s:%d: property failed: %s\n", file, line, what);
    if (n > 0 && write(report_fd, msg, (size_t)n < sizeof msg ? (size_t)n : sizeof msg - 1) < 0)
        n = 0; /* nothing more to try; abort() says the rest */
    abort();
}

const char *fuzz_write_file(const char *name, const void *data, size_t size)
{
    if (!scratch_dir[0]) {
        const char *tmp = getenv("TMPDIR");
        snprintf(scratch_dir, sizeof scratch_dir, "%s/ftm-fuzz-XXXXXX", tmp && *tmp ? tmp : "/tmp");
        if (!mkdtemp(scratch_dir)) {
            perror("fuzz: mkdtemp");
            abort();
        }
        atexit(remove_scratch);
    }
    int slot = -1;
    for (int i = 0; i < 8 && slot < 0; i++)
        if (strcmp(names[i], name) == 0 || !names[i][0])
            slot = i;
    if (slot < 0 || strlen(name) >= sizeof names[0])
        fuzz_fail(__FILE__, __LINE__, "scratch file slots");
    snprintf(names[slot], sizeof names[slot], "%s", name);
    snprintf(paths[slot], sizeof paths[slot], "%s/%s", scratch_dir, name);
    FILE *f = fopen(paths[slot], "wb");
    if (!f || (size && fwrite(data, 1, size, f) != size) || fclose(f) != 0) {
        perror("fuzz: writing a scratch file");
        abort();
    }
    return paths[slot];
}
