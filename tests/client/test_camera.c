/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The client's camera (client/camera.c), no GL: the view is framed in the
 * rows below the HUD, and what the camera frames there is what it
 * projects there; panning follows the cursor in that view. */
#include "camera.h"

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

static const int W = 960, H = 600;

/* the default scene's tissue: a 12 cm cube standing on z = 0 */
static ftm_camera framed(void)
{
    ftm_camera c;
    ftm_camera_frame(&c, (ftm_vec3){0, 0, 0}, (ftm_vec3){0.11, 0.11, 0.11});
    return c;
}

static void px_of(const ftm_camera *c, double top, ftm_vec3 p, double *x, double *y)
{
    assert_true(ftm_camera_project(c, W, H, top, p, x, y));
}

/* The float matrix ftm_render_draw uses agrees with the projection that
 * screenshots and tests report. */
static void matrix_px(const ftm_camera *c, double top, ftm_vec3 p, double *x, double *y)
{
    float m[16];
    ftm_camera_matrix(c, W, H, top, m);
    double cx = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
    double cy = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
    double cw = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
    *x = (cx / cw * 0.5 + 0.5) * W;
    *y = (1.0 - (cy / cw * 0.5 + 0.5)) * H;
}

static void view_height_clamps(void **state)
{
    (void)state;
    assert_true(ftm_camera_view_height(H, 0) == H);
    assert_true(ftm_camera_view_height(H, 254) == H - 254);
    assert_true(ftm_camera_view_height(H, -5) == H);
    assert_true(ftm_camera_view_height(H, NAN) == H);
    /* a HUD taller than 60 % of the window leaves the view 40 % */
    assert_true(fabs(ftm_camera_view_height(H, 500) - 0.4 * H) < 1e-9);
    assert_true(fabs(ftm_camera_view_height(H, INFINITY) - 0.4 * H) < 1e-9);
    assert_true(ftm_camera_view_height(0, 0) == 1.0);
}

/* The target is drawn at the centre of the rows below the HUD. */
static void target_centred_below_top(void **state)
{
    (void)state;
    ftm_camera c = framed();
    const double tops[] = {0, 109, 254, 360};
    for (size_t i = 0; i < sizeof tops / sizeof *tops; i++) {
        double x, y, mx, my;
        px_of(&c, tops[i], c.target, &x, &y);
        assert_true(fabs(x - 0.5 * W) < 1e-6);
        assert_true(fabs(y - (tops[i] + 0.5 * (H - tops[i]))) < 1e-6);
        matrix_px(&c, tops[i], c.target, &mx, &my);
        assert_true(fabs(mx - x) < 1e-3 && fabs(my - y) < 1e-3);
    }
}

/* The framed tissue, every corner of it, lies in the rows below the HUD
 * (an instructor's HUD of 12 lines covers 254 of 600 rows): what the view
 * is for is not hidden under the text. */
static void frame_clear_of_hud(void **state)
{
    (void)state;
    ftm_camera c = framed();
    const double tops[] = {0, 109, 254};
    for (size_t i = 0; i < sizeof tops / sizeof *tops; i++)
        for (int k = 0; k < 8; k++) {
            ftm_vec3 p = {k & 1 ? 0.11 : 0, k & 2 ? 0.11 : 0, k & 4 ? 0.11 : 0};
            double x, y, mx, my;
            px_of(&c, tops[i], p, &x, &y);
            assert_true(x >= 0 && x <= W);
            assert_true(y >= tops[i] && y <= H);
            matrix_px(&c, tops[i], p, &mx, &my);
            assert_true(fabs(mx - x) < 1e-3 && fabs(my - y) < 1e-3);
        }
    /* with the HUD's rows ignored, the top face would be drawn under a
     * 254-row HUD: the test above is not empty */
    double top_face = H;
    for (int k = 0; k < 4; k++) {
        double x, y;
        px_of(&c, 0, (ftm_vec3){k & 1 ? 0.11 : 0, k & 2 ? 0.11 : 0, 0.11}, &x, &y);
        top_face = fmin(top_face, y);
    }
    assert_true(top_face < 254);
}

/* A point at the target's depth follows a pan of (dx, dy) pixels by the
 * same pixels when the pan is given the view's height. */
static void pan_follows_cursor(void **state)
{
    (void)state;
    const double top = 254;
    ftm_camera c = framed();
    ftm_vec3 p = c.target;
    double x0, y0, x1, y1;
    px_of(&c, top, p, &x0, &y0);
    ftm_camera_pan(&c, 40, -25, ftm_camera_view_height(H, top));
    px_of(&c, top, p, &x1, &y1);
    assert_true(fabs((x1 - x0) - 40) < 1e-6);
    assert_true(fabs((y1 - y0) - (-25)) < 1e-6);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(view_height_clamps),
        cmocka_unit_test(target_centred_below_top),
        cmocka_unit_test(frame_clear_of_hud),
        cmocka_unit_test(pan_follows_cursor),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
