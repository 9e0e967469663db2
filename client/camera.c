/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Orbit camera; see camera.h. Matrices are computed in double and handed
 * to GL as float. */
#include "camera.h"

#include <math.h>

static const double pi = 3.14159265358979323846;

static ftm_vec3 v3(double x, double y, double z) { return (ftm_vec3){x, y, z}; }
static ftm_vec3 add(ftm_vec3 a, ftm_vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static ftm_vec3 scale(ftm_vec3 a, double s) { return v3(a.x * s, a.y * s, a.z * s); }
static double dot(ftm_vec3 a, ftm_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

void ftm_camera_frame(ftm_camera *c, ftm_vec3 lo, ftm_vec3 hi)
{
    c->target = scale(add(lo, hi), 0.5);
    ftm_vec3 d = v3(hi.x - lo.x, hi.y - lo.y, hi.z - lo.z);
    c->radius = 0.5 * sqrt(dot(d, d));
    if (!(c->radius > 0))
        c->radius = 0.05;
    c->fovy = 40.0 * pi / 180.0;
    c->azimuth = -30.0 * pi / 180.0;
    c->elevation = 35.0 * pi / 180.0;
    /* the bounding sphere about fills the height */
    c->distance = c->radius / tan(0.5 * c->fovy) * 1.05;
}

void ftm_camera_orbit(ftm_camera *c, double dx_px, double dy_px)
{
    c->azimuth -= dx_px * 0.008;
    c->elevation += dy_px * 0.008;
    double lim = 89.0 * pi / 180.0;
    if (c->elevation > lim)
        c->elevation = lim;
    if (c->elevation < -lim)
        c->elevation = -lim;
    c->azimuth = fmod(c->azimuth, 2.0 * pi);
}

void ftm_camera_basis(const ftm_camera *c, ftm_vec3 *right, ftm_vec3 *up, ftm_vec3 *fwd)
{
    double ce = cos(c->elevation), se = sin(c->elevation);
    double ca = cos(c->azimuth), sa = sin(c->azimuth);
    /* eye sits at target - fwd * distance; azimuth 0 looks along +y */
    ftm_vec3 f = v3(sa * ce, ca * ce, -se);
    ftm_vec3 r = v3(ca, -sa, 0.0);
    ftm_vec3 u = v3(r.y * f.z - r.z * f.y, r.z * f.x - r.x * f.z, r.x * f.y - r.y * f.x);
    if (right)
        *right = r;
    if (up)
        *up = u;
    if (fwd)
        *fwd = f;
}

void ftm_camera_pan(ftm_camera *c, double dx_px, double dy_px, double h_px)
{
    ftm_vec3 r, u;
    ftm_camera_basis(c, &r, &u, NULL);
    /* one pixel = the height of a pixel at the target's distance */
    double m = 2.0 * c->distance * tan(0.5 * c->fovy) / (h_px > 1 ? h_px : 1);
    c->target = add(c->target, add(scale(r, -dx_px * m), scale(u, dy_px * m)));
}

void ftm_camera_zoom(ftm_camera *c, double steps)
{
    c->distance *= pow(0.9, steps);
    double lo = 0.02 * c->radius, hi = 50.0 * c->radius;
    if (c->distance < lo)
        c->distance = lo;
    if (c->distance > hi)
        c->distance = hi;
}

ftm_vec3 ftm_camera_eye(const ftm_camera *c)
{
    ftm_vec3 f;
    ftm_camera_basis(c, NULL, NULL, &f);
    return add(c->target, scale(f, -c->distance));
}

double ftm_camera_view_height(int h, double top)
{
    double hh = h > 0 ? (double)h : 1.0;
    if (!(top > 0)) /* NaN too */
        top = 0;
    if (top > 0.6 * hh)
        top = 0.6 * hh;
    return hh - top;
}

/* proj * view in double, column-major: the projection of a viewport of the
 * free rows (w x hf), then its clip-space y squeezed into them:
 * y' = y hf / h - w_clip top / h, which maps the free rows' top edge (y = w_clip)
 * to NDC 1 - 2 top / h and their bottom edge to -1. */
static void matrix(const ftm_camera *c, int w, int h, double top, double m[16])
{
    const double hh = h > 0 ? (double)h : 1.0, hf = ftm_camera_view_height(h, top);
    const double aspect = (w > 0 ? (double)w : 1.0) / hf, sy = hf / hh, oy = (hf - hh) / hh;
    ftm_vec3 r, u, f;
    ftm_camera_basis(c, &r, &u, &f);
    ftm_vec3 e = ftm_camera_eye(c);
    double view[16] = {r.x, u.x, -f.x, 0, r.y, u.y, -f.y, 0, r.z, u.z, -f.z, 0,
                       -dot(r, e), -dot(u, e), dot(f, e), 1};
    double zn = c->distance - 3.0 * c->radius, zf = c->distance + 3.0 * c->radius;
    if (zn < c->distance * 0.01)
        zn = c->distance * 0.01;
    double t = 1.0 / tan(0.5 * c->fovy);
    double proj[16] = {t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (zf + zn) / (zn - zf), -1,
                       0, 0, 2 * zf * zn / (zn - zf), 0};
    for (int col = 0; col < 4; col++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += proj[k * 4 + row] * view[col * 4 + k];
            m[col * 4 + row] = s;
        }
    for (int col = 0; col < 4; col++)
        m[col * 4 + 1] = sy * m[col * 4 + 1] + oy * m[col * 4 + 3];
}

void ftm_camera_matrix(const ftm_camera *c, int w, int h, double top, float out[16])
{
    double m[16];
    matrix(c, w, h, top, m);
    for (int i = 0; i < 16; i++)
        out[i] = (float)m[i];
}

bool ftm_camera_project(const ftm_camera *c, int w, int h, double top, ftm_vec3 p, double *px,
                        double *py)
{
    double m[16];
    matrix(c, w, h, top, m);
    double x = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
    double y = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
    double ww = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
    if (!(ww > 0))
        return false;
    *px = (x / ww * 0.5 + 0.5) * w;
    *py = (1.0 - (y / ww * 0.5 + 0.5)) * h;
    return true;
}
