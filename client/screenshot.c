/* SPDX-License-Identifier: GPL-3.0-or-later */
/* PNG writing with libpng; see screenshot.h. */
#include "screenshot.h"

#include <errno.h>
#include <fcntl.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int fail(ftm_error *err, const char *path, const char *why)
{
    if (err) {
        err->code = FTM_EIO;
        snprintf(err->message, sizeof err->message, "screenshot %s: %s", path, why);
    }
    return FTM_EIO;
}

int ftm_screenshot_write_png(const char *path, int w, int h, const uint8_t *rgb, ftm_error *err)
{
    if (w <= 0 || h <= 0 || !rgb)
        return fail(err, path, "empty image");
    /* rows top-down for PNG: glReadPixels gave them bottom-up */
    png_bytep *rows = malloc((size_t)h * sizeof *rows);
    if (!rows)
        return fail(err, path, "out of memory");
    for (int y = 0; y < h; y++)
        rows[y] = (png_bytep)(rgb + (size_t)(h - 1 - y) * (size_t)w * 3);
    /* written under a temporary name in the same directory, then renamed
     * over path: a failed write leaves no partial file (nor spoils one
     * that was there) */
    size_t tlen = strlen(path) + 48;
    char *tmp = malloc(tlen);
    if (!tmp) {
        free(rows);
        return fail(err, path, "out of memory");
    }
    int fd = -1;
    errno = 0;
    for (int i = 0; i < 100 && fd < 0; i++) { /* (open, not mkstemp: the umask applies) */
        snprintf(tmp, tlen, "%s.tmp-%ld-%d", path, (long)getpid(), i);
        fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd < 0 && errno != EEXIST)
            break;
    }
    FILE *f = fd >= 0 ? fdopen(fd, "wb") : NULL;
    if (!f) {
        int e = errno;
        if (fd >= 0) {
            close(fd);
            unlink(tmp);
        }
        free(tmp);
        free(rows);
        return fail(err, path, strerror(e));
    }
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_write_struct(&png, &info);
        fclose(f);
        unlink(tmp);
        free(tmp);
        free(rows);
        return fail(err, path, "libpng initialisation failed");
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        fclose(f);
        unlink(tmp);
        free(tmp);
        free(rows);
        return fail(err, path, "libpng write error");
    }
    png_init_io(png, f);
    png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    png_write_image(png, rows);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    free(rows);
    if (fflush(f) != 0 || fsync(fileno(f)) != 0) {
        int e = errno;
        fclose(f);
        unlink(tmp);
        free(tmp);
        return fail(err, path, strerror(e));
    }
    if (fclose(f) != 0 || rename(tmp, path) != 0) {
        int e = errno;
        unlink(tmp);
        free(tmp);
        return fail(err, path, strerror(e));
    }
    free(tmp);
    return FTM_OK;
}
