/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Checks on ftm-client screenshots (tests/client_gl/client_gl.sh).
 *
 *   client-png-check compare BEFORE.png AFTER.png X Y R
 *       both images are not blank, have the same size, and the pixels within
 *       R pixels of (X, Y) (the contact, from the client's screenshot line)
 *       changed: at least 10% of them by more than 40 (sum over R, G, B).
 *   client-png-check banner IMAGE.png
 *       the image shows text and the red error banner (a band of
 *       banner-red pixels near the top, where ftm-client draws it).
 *   client-png-check drawn IMAGE.png X Y R
 *       something is drawn around (X, Y) (the middle of the view: a volume):
 *       at least 90% of the pixels within R of it differ from the
 *       background (the colour of the bottom corners, which must agree), and
 *       the image's corners below its top quarter are background.
 *   client-png-check similar A.png B.png X Y R M
 *       the two pictures of one scene agree within R pixels of (X, Y): their
 *       mean difference is at most M per channel (0..255), and at most 2% of
 *       the pixels differ by more than 4 M (mean over R, G, B). A volume
 *       drawn with fewer slices against all of them: banding fails it.
 *   client-png-check steel IMAGE.png X Y R
 *       the instrument's shaft is drawn at (X, Y) (its middle, from the
 *       client's screenshot line): at least a third of the pixels within R
 *       of it have the shaft's steel hue (the chromaticity of the colour
 *       render.h gives it, within 0.03) and are lit (R + G + B > 180), which
 *       neither the background nor the tissue (its colour or the map) is.
 *   client-png-check hudfit IMAGE.png Y1
 *       the HUD's text (R + G + B >= 600) in rows 0..Y1 is there (200+
 *       pixels) and none of it is in the last 4 columns: nothing cut off.
 *   client-png-check hue IMAGE.png X0 Y0 X1 Y1 R G B
 *       at least 12 lit pixels (R + G + B > 150) of the colour (R, G, B),
 *       0..1, by chromaticity within 0.04, in the box: a participant's name
 *       label drawn in the participant's colour.
 *   client-png-check nearest IMAGE.png X0 Y0 X1 Y1 P R1 G1 B1 R2 G2 B2 [R G B ...]
 *       of the lit pixels (R + G + B > 150) in the box, at least P percent
 *       are nearest (by chromaticity) the first of the colours given (0..1):
 *       a translucent volume's tissue colour, blended over the background,
 *       told from the other tissues' colours.
 *   client-png-check panel IMAGE.png X Y R
 *       the help overlay (F1) covers the square of half-side R around (X, Y):
 *       at least half its pixels are of the panel's deep blue, and some of
 *       its text (white) is there.
 * Exit 0 pass, 1 fail (with the reason), 2 usage or unreadable file. */
#include <math.h>
#include <stdbool.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct image {
    int w, h;
    unsigned char *rgb; /* top-down */
} image;

static int load(const char *path, image *im)
{
    memset(im, 0, sizeof *im);
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "%s: cannot open\n", path);
        return -1;
    }
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info || setjmp(png_jmpbuf(png))) {
        fprintf(stderr, "%s: not a readable PNG\n", path);
        png_destroy_read_struct(&png, &info, NULL);
        fclose(f);
        free(im->rgb);
        im->rgb = NULL;
        return -1;
    }
    png_init_io(png, f);
    png_read_info(png, info);
    png_set_strip_16(png);
    png_set_strip_alpha(png);
    png_set_palette_to_rgb(png);
    png_set_gray_to_rgb(png);
    png_read_update_info(png, info);
    int w = (int)png_get_image_width(png, info), h = (int)png_get_image_height(png, info);
    if (png_get_rowbytes(png, info) != (size_t)w * 3) {
        fprintf(stderr, "%s: unexpected pixel format\n", path);
        png_destroy_read_struct(&png, &info, NULL);
        fclose(f);
        return -1;
    }
    im->rgb = malloc((size_t)w * h * 3);
    png_bytep *rows = malloc((size_t)h * sizeof *rows);
    if (!im->rgb || !rows) {
        fprintf(stderr, "%s: out of memory\n", path);
        exit(2);
    }
    for (int y = 0; y < h; y++)
        rows[y] = im->rgb + (size_t)y * w * 3;
    png_read_image(png, rows);
    free(rows);
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    im->w = w;
    im->h = h;
    return 0;
}

/* Not blank: a spread of luminance and more than min_colours colours
 * (a frame without a scene, only text, has few). */
static int not_blank(const char *path, const image *im, unsigned min_colours)
{
    double s = 0, s2 = 0;
    size_t n = (size_t)im->w * im->h;
    unsigned distinct = 0;
    static unsigned char seen[1 << 15];
    memset(seen, 0, sizeof seen);
    for (size_t i = 0; i < n; i++) {
        const unsigned char *p = im->rgb + 3 * i;
        double l = 0.3 * p[0] + 0.59 * p[1] + 0.11 * p[2];
        s += l;
        s2 += l * l;
        unsigned key = (unsigned)(p[0] >> 3) << 10 | (unsigned)(p[1] >> 3) << 5 | (p[2] >> 3);
        if (!seen[key]) {
            seen[key] = 1;
            distinct++;
        }
    }
    double mean = s / n, sd = s2 / n - mean * mean;
    sd = sd > 0 ? sqrt(sd) : 0;
    printf("%s: %dx%d, luminance mean %.1f sd %.1f, %u colours (5-bit)\n", path, im->w, im->h, mean,
           sd, distinct);
    if (sd < 5.0 || distinct < min_colours) {
        printf("FAIL: %s looks blank\n", path);
        return -1;
    }
    return 0;
}

/* The verdict on two loaded images of the same scene. */
static int compare_images(const char *pa, const image *a, const char *pb, const image *b, int cx,
                          int cy, int r)
{
    if (not_blank(pa, a, 20) || not_blank(pb, b, 20))
        return 1;
    if (a->w != b->w || a->h != b->h) {
        printf("FAIL: sizes differ: %dx%d and %dx%d\n", a->w, a->h, b->w, b->h);
        return 1;
    }
    if (cx < 0 || cy < 0 || cx >= a->w || cy >= a->h) {
        printf("FAIL: contact pixel (%d, %d) outside the image\n", cx, cy);
        return 1;
    }
    long inside = 0, changed = 0, far = 0, far_changed = 0;
    for (int y = 0; y < a->h; y++)
        for (int x = 0; x < a->w; x++) {
            const unsigned char *p = a->rgb + ((size_t)y * a->w + x) * 3;
            const unsigned char *q = b->rgb + ((size_t)y * a->w + x) * 3;
            int d = abs(p[0] - q[0]) + abs(p[1] - q[1]) + abs(p[2] - q[2]);
            long dx = x - cx, dy = y - cy;
            if (dx * dx + dy * dy <= (long)r * r) {
                inside++;
                changed += d > 40;
            } else if (dx * dx + dy * dy > 16L * r * r) {
                far++;
                far_changed += d > 40;
            }
        }
    double fin = inside ? (double)changed / inside : 0, ffar = far ? (double)far_changed / far : 0;
    printf("around the contact (%d, %d), radius %d: %ld of %ld pixels changed (%.1f%%); "
           "beyond 4 radii: %.2f%%\n",
           cx, cy, r, changed, inside, 100 * fin, 100 * ffar);
    if (fin < 0.10) {
        printf("FAIL: the pixels around the contact did not change\n");
        return 1;
    }
    if (fin < 2 * ffar) {
        printf("FAIL: the change is not concentrated at the contact\n");
        return 1;
    }
    printf("PASS\n");
    return 0;
}

static int compare(const char *pa, const char *pb, int cx, int cy, int r)
{
    image a, b;
    if (load(pa, &a))
        return 2;
    if (load(pb, &b)) {
        free(a.rgb);
        return 2;
    }
    int rc = compare_images(pa, &a, pb, &b, cx, cy, r);
    free(a.rgb);
    free(b.rgb);
    return rc;
}

static int similar(const char *pa, const char *pb, int cx, int cy, int r, double m)
{
    image a, b;
    if (load(pa, &a))
        return 2;
    if (load(pb, &b)) {
        free(a.rgb);
        return 2;
    }
    int rc = 1;
    if (not_blank(pa, &a, 20) || not_blank(pb, &b, 20))
        goto out;
    if (a.w != b.w || a.h != b.h) {
        printf("FAIL: sizes differ: %dx%d and %dx%d\n", a.w, a.h, b.w, b.h);
        goto out;
    }
    double sum = 0;
    long n = 0, off = 0;
    for (int y = cy - r; y <= cy + r; y++)
        for (int x = cx - r; x <= cx + r; x++) {
            long dx = x - cx, dy = y - cy;
            if (x < 0 || y < 0 || x >= a.w || y >= a.h || dx * dx + dy * dy > (long)r * r)
                continue;
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            const unsigned char *q = b.rgb + ((size_t)y * a.w + x) * 3;
            double d = (abs(p[0] - q[0]) + abs(p[1] - q[1]) + abs(p[2] - q[2])) / 3.0;
            sum += d;
            off += d > 4 * m;
            n++;
        }
    if (!n) {
        printf("FAIL: (%d, %d) radius %d outside the image\n", cx, cy, r);
        goto out;
    }
    printf("within %d of (%d, %d): mean difference %.2f per channel, %.2f%% of pixels by more "
           "than %g\n", r, cx, cy, sum / n, 100.0 * off / n, 4 * m);
    if (sum / n > m || off > n / 50)
        printf("FAIL: the pictures differ\n");
    else {
        printf("PASS\n");
        rc = 0;
    }
out:
    free(a.rgb);
    free(b.rgb);
    return rc;
}

static int banner(const char *path)
{
    image a;
    if (load(path, &a))
        return 2;
    if (not_blank(path, &a, 2)) {
        free(a.rgb);
        return 1;
    }
    /* ftm-client draws the banner near the top (below its HUD): red (0.70,
     * 0.08, 0.06) at 88% over the dark background */
    int y0 = 0, y1 = a.h / 2;
    long red = 0;
    for (int y = y0; y < y1; y++)
        for (int x = 0; x < a.w; x++) {
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            red += p[0] > 130 && p[1] < 60 && p[2] < 60;
        }
    printf("%s: %ld banner-red pixels in rows %d..%d\n", path, red, y0, y1);
    free(a.rgb);
    if (red < 2000) {
        printf("FAIL: no error banner on screen\n");
        return 1;
    }
    printf("PASS\n");
    return 0;
}

static int dist3(const unsigned char *p, const unsigned char *q)
{
    return abs(p[0] - q[0]) + abs(p[1] - q[1]) + abs(p[2] - q[2]);
}

static int drawn(const char *path, int cx, int cy, int r)
{
    image a;
    if (load(path, &a))
        return 2;
    int rc = 1;
    const unsigned char *bg = a.rgb + (size_t)(a.h - 1) * a.w * 3;
    const unsigned char *bg2 = bg + (size_t)(a.w - 1) * 3;
    long inside = 0, differ = 0, corner = 0, corner_differ = 0;
    const int c = 40; /* corner patches, c x c pixels */
    if (not_blank(path, &a, 20))
        goto out;
    if (dist3(bg, bg2) > 6) {
        printf("FAIL: the bottom corners differ (%d %d %d vs %d %d %d): no background there\n",
               bg[0], bg[1], bg[2], bg2[0], bg2[1], bg2[2]);
        goto out;
    }
    for (int y = 0; y < a.h; y++)
        for (int x = 0; x < a.w; x++) {
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            long dx = x - cx, dy = y - cy;
            if (dx * dx + dy * dy <= (long)r * r) {
                inside++;
                differ += dist3(p, bg) > 30;
            }
            if (y >= a.h / 4 && (y < a.h / 4 + c || y >= a.h - c) && (x < c || x >= a.w - c)) {
                corner++;
                corner_differ += dist3(p, bg) > 6;
            }
        }
    printf("%s: background %d %d %d; within %d of (%d, %d): %ld of %ld pixels drawn (%.1f%%); "
           "corners: %ld of %ld not background\n",
           path, bg[0], bg[1], bg[2], r, cx, cy, differ, inside,
           inside ? 100.0 * differ / inside : 0.0, corner_differ, corner);
    if (!inside || differ < 0.9 * inside)
        printf("FAIL: the middle of the view is not drawn\n");
    else if (corner_differ > corner / 100)
        printf("FAIL: something is drawn in the corners\n");
    else {
        printf("PASS\n");
        rc = 0;
    }
out:
    free(a.rgb);
    return rc;
}

/* the shaft's colour, as client/render.h gives it (FTM_SHAFT_R, _G, _B) */
static const double shaft_rgb[3] = {0.66, 0.70, 0.76};

/* The HUD fits the window: its text (bright pixels) in rows 0..y1 is
 * there, and none of it touches the last 4 columns (text running past the
 * right edge would). */
static int hudfit(const char *path, int y1)
{
    image a;
    if (load(path, &a))
        return 2;
    long text = 0, edge = 0;
    for (int y = 0; y <= y1 && y < a.h; y++)
        for (int x = 0; x < a.w; x++) {
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            if (p[0] + p[1] + p[2] < 600)
                continue;
            text++;
            edge += x >= a.w - 4;
        }
    free(a.rgb);
    printf("%s: %dx%d, HUD rows 0..%d: %ld bright pixels, %ld at the right edge\n", path, a.w,
           a.h, y1, text, edge);
    if (text < 200) {
        printf("FAIL: no HUD text\n");
        return 1;
    }
    if (edge > 0) {
        printf("FAIL: the HUD's text runs past the right edge\n");
        return 1;
    }
    printf("PASS\n");
    return 0;
}

/* Pixels of colour (r, g, b) (0..1; by chromaticity, bright ones) in the
 * box x0..x1, y0..y1: a participant's name label drawn in its colour. */
static int hue_box(const char *path, int x0, int y0, int x1, int y1, double r, double g, double b)
{
    image a;
    if (load(path, &a))
        return 2;
    const double want[3] = {r, g, b}, sum0 = r + g + b;
    long inside = 0, match = 0;
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
            if (x < 0 || y < 0 || x >= a.w || y >= a.h)
                continue;
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            int sum = p[0] + p[1] + p[2];
            inside++;
            if (sum <= 150)
                continue;
            bool hue = true;
            for (int k = 0; k < 3; k++)
                hue = hue && fabs((double)p[k] / sum - want[k] / sum0) <= 0.04;
            match += hue;
        }
    free(a.rgb);
    printf("%s: in (%d, %d)..(%d, %d): %ld of %ld pixels of colour (%.2f, %.2f, %.2f)\n", path, x0,
           y0, x1, y1, match, inside, r, g, b);
    if (match < 12) {
        printf("FAIL: nothing of that colour there\n");
        return 1;
    }
    printf("PASS\n");
    return 0;
}

/* Lit pixels in the box whose chromaticity is nearest colours[0] of the n
 * given (3 each), at least `share` percent of them. */
static int nearest_box(const char *path, int x0, int y0, int x1, int y1, double share,
                       const double *colors, int n)
{
    image a;
    if (load(path, &a))
        return 2;
    long lit = 0, first = 0;
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
            if (x < 0 || y < 0 || x >= a.w || y >= a.h)
                continue;
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            const int sum = p[0] + p[1] + p[2];
            if (sum <= 150)
                continue;
            lit++;
            int best = 0;
            double bd = INFINITY;
            for (int c = 0; c < n; c++) {
                const double *w = colors + 3 * c, ws = w[0] + w[1] + w[2];
                double d = 0;
                for (int k = 0; k < 3; k++)
                    d += pow((double)p[k] / sum - w[k] / ws, 2);
                if (d < bd)
                    bd = d, best = c;
            }
            first += best == 0;
        }
    free(a.rgb);
    printf("%s: in (%d, %d)..(%d, %d): %ld of %ld lit pixels nearest (%.2f, %.2f, %.2f)\n", path,
           x0, y0, x1, y1, first, lit, colors[0], colors[1], colors[2]);
    if (lit < 20 || 100.0 * (double)first < share * (double)lit) {
        printf("FAIL: fewer than %g %% of them\n", share);
        return 1;
    }
    printf("PASS\n");
    return 0;
}

static int steel(const char *path, int cx, int cy, int r)
{
    image a;
    if (load(path, &a))
        return 2;
    const double sum0 = shaft_rgb[0] + shaft_rgb[1] + shaft_rgb[2];
    long inside = 0, match = 0;
    for (int y = cy - r; y <= cy + r; y++)
        for (int x = cx - r; x <= cx + r; x++) {
            long dx = x - cx, dy = y - cy;
            if (x < 0 || y < 0 || x >= a.w || y >= a.h || dx * dx + dy * dy > (long)r * r)
                continue;
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            int sum = p[0] + p[1] + p[2];
            inside++;
            if (sum <= 180)
                continue;
            bool hue = true;
            for (int k = 0; k < 3; k++)
                hue = hue && fabs((double)p[k] / sum - shaft_rgb[k] / sum0) <= 0.03;
            match += hue;
        }
    free(a.rgb);
    printf("%s: within %d of (%d, %d): %ld of %ld pixels of the shaft's steel\n", path, r, cx, cy,
           match, inside);
    if (!inside || 3 * match < inside) {
        printf("FAIL: no instrument shaft drawn there\n");
        return 1;
    }
    printf("PASS\n");
    return 0;
}

/* the help overlay's panel colour, as client/render.c draws it over the
 * dark background (its alpha blended over 0.11 0.12 0.15) */
static int panel(const char *path, int cx, int cy, int r)
{
    image a;
    if (load(path, &a))
        return 2;
    long inside = 0, match = 0, text = 0;
    for (int y = cy - r; y <= cy + r; y++)
        for (int x = cx - r; x <= cx + r; x++) {
            if (x < 0 || y < 0 || x >= a.w || y >= a.h)
                continue;
            const unsigned char *p = a.rgb + ((size_t)y * a.w + x) * 3;
            inside++;
            /* the panel: a deep blue, blue well above red and green */
            match += p[2] > p[0] + 40 && p[2] > p[1] + 30 && p[0] < 60;
            text += p[0] > 200 && p[1] > 200 && p[2] > 180;
        }
    free(a.rgb);
    printf("%s: within %d of (%d, %d): %ld of %ld pixels of the help panel, %ld of text\n", path,
           r, cx, cy, match, inside, text);
    if (!inside || 2 * match < inside || text < inside / 50) {
        printf("FAIL: no help overlay there\n");
        return 1;
    }
    printf("PASS\n");
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 4 && strcmp(argv[1], "hudfit") == 0)
        return hudfit(argv[2], atoi(argv[3]));
    if (argc == 10 && strcmp(argv[1], "hue") == 0)
        return hue_box(argv[2], atoi(argv[3]), atoi(argv[4]), atoi(argv[5]), atoi(argv[6]),
                       atof(argv[7]), atof(argv[8]), atof(argv[9]));
    if (argc >= 14 && (argc - 8) % 3 == 0 && argc <= 8 + 3 * 8 &&
        strcmp(argv[1], "nearest") == 0) {
        double colors[3 * 8];
        for (int i = 8; i < argc; i++)
            colors[i - 8] = atof(argv[i]);
        return nearest_box(argv[2], atoi(argv[3]), atoi(argv[4]), atoi(argv[5]), atoi(argv[6]),
                           atof(argv[7]), colors, (argc - 8) / 3);
    }
    if (argc == 6 && strcmp(argv[1], "steel") == 0)
        return steel(argv[2], atoi(argv[3]), atoi(argv[4]), atoi(argv[5]));
    if (argc == 6 && strcmp(argv[1], "panel") == 0)
        return panel(argv[2], atoi(argv[3]), atoi(argv[4]), atoi(argv[5]));
    if (argc == 7 && strcmp(argv[1], "compare") == 0)
        return compare(argv[2], argv[3], atoi(argv[4]), atoi(argv[5]), atoi(argv[6]));
    if (argc == 3 && strcmp(argv[1], "banner") == 0)
        return banner(argv[2]);
    if (argc == 6 && strcmp(argv[1], "drawn") == 0)
        return drawn(argv[2], atoi(argv[3]), atoi(argv[4]), atoi(argv[5]));
    if (argc == 8 && strcmp(argv[1], "similar") == 0)
        return similar(argv[2], argv[3], atoi(argv[4]), atoi(argv[5]), atoi(argv[6]),
                       atof(argv[7]));
    fprintf(stderr, "usage: client-png-check compare BEFORE.png AFTER.png X Y R\n"
                    "       client-png-check banner IMAGE.png\n"
                    "       client-png-check drawn IMAGE.png X Y R\n"
                    "       client-png-check similar A.png B.png X Y R M\n"
                    "       client-png-check steel IMAGE.png X Y R\n"
                    "       client-png-check hue IMAGE.png X0 Y0 X1 Y1 R G B\n"
                    "       client-png-check nearest IMAGE.png X0 Y0 X1 Y1 P R G B R G B...\n"
                    "       client-png-check hudfit IMAGE.png Y1\n"
                    "       client-png-check panel IMAGE.png X Y R\n");
    return 2;
}
