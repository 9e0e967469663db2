/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The client's PNG writer (client/screenshot.c): a screenshot is written
 * under a temporary name and renamed, so a failed write leaves neither a
 * partial file nor a spoiled one that was there, nor its temporary file. */
#include "screenshot.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int failures;
#define CHECK(cond, what)                                                                         \
    do {                                                                                          \
        if (!(cond)) {                                                                            \
            fprintf(stderr, "FAIL: %s (line %d)\n", what, __LINE__);                              \
            failures++;                                                                           \
        }                                                                                         \
    } while (0)

static int entries(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += strcmp(e->d_name, ".") != 0 && strcmp(e->d_name, "..") != 0;
    if (d)
        closedir(d);
    return n;
}

int main(void)
{
    char dir[] = "/tmp/ftm-test-screenshot.XXXXXX";
    if (!mkdtemp(dir))
        return 1;
    char a[256], b[256];
    snprintf(a, sizeof a, "%s/a.png", dir);
    snprintf(b, sizeof b, "%s/b.png", dir);
    ftm_error err = {0, ""};
    uint8_t px[4 * 3 * 3];
    memset(px, 200, sizeof px);
    CHECK(ftm_screenshot_write_png(a, 4, 3, px, &err) == FTM_OK, err.message);
    FILE *f = fopen(a, "rb");
    unsigned char sig[8] = {0};
    CHECK(f && fread(sig, 1, 8, f) == 8 && memcmp(sig, "\x89PNG\r\n\x1a\n", 8) == 0, "a.png is no PNG");
    if (f)
        fclose(f);
    CHECK(entries(dir) == 1, "files other than a.png left");

    /* a write libpng refuses half-way (a width over its limit) */
    f = fopen(b, "w");
    fputs("keep", f);
    fclose(f);
    const int w = 2000000;
    uint8_t *wide = calloc((size_t)w * 3, 1);
    CHECK(wide && ftm_screenshot_write_png(b, w, 1, wide, &err) == FTM_EIO, "a failed write succeeded");
    CHECK(strstr(err.message, b) != NULL, "the error does not name the file");
    free(wide);
    char buf[16] = {0};
    f = fopen(b, "r");
    CHECK(f && fread(buf, 1, sizeof buf - 1, f) == 4 && strcmp(buf, "keep") == 0,
          "the file that was there was spoiled");
    if (f)
        fclose(f);
    CHECK(entries(dir) == 2, "a temporary file was left");
    unlink(a);
    unlink(b);
    rmdir(dir);
    if (failures)
        return 1;
    printf("PASS\n");
    return 0;
}
