/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Orbit camera for the client: it circles a target point (azimuth about the
 * world z axis, which is "up" in every FTM scene, and elevation above the
 * xy plane) at a distance, and pans the target in the view plane. Matrices
 * are column-major 4x4 floats, as OpenGL takes them. No GL here. */
#ifndef FTM_CLIENT_CAMERA_H
#define FTM_CLIENT_CAMERA_H

#include "ftm/base.h"

typedef struct ftm_camera {
    ftm_vec3 target;
    double distance;  /* [m] from target to eye */
    double azimuth;   /* [rad] about +z, 0 looks along +y */
    double elevation; /* [rad] above the xy plane, limited to +-89 deg */
    double fovy;      /* [rad] vertical field of view */
    double radius;    /* scene radius, for clip planes and pan/zoom speed */
} ftm_camera;

/* A default view of the box [lo, hi]: from the front-right, 35 deg above. */
void ftm_camera_frame(ftm_camera *c, ftm_vec3 lo, ftm_vec3 hi);

/* Mouse motion in pixels turned into camera motion (h_px: the height of
 * the view in the same pixels, ftm_camera_view_height). */
void ftm_camera_orbit(ftm_camera *c, double dx_px, double dy_px);
void ftm_camera_pan(ftm_camera *c, double dx_px, double dy_px, double h_px);
void ftm_camera_zoom(ftm_camera *c, double steps); /* > 0: closer */

ftm_vec3 ftm_camera_eye(const ftm_camera *c);
/* Unit vectors of the view: right, up (on screen) and forward (into it). */
void ftm_camera_basis(const ftm_camera *c, ftm_vec3 *right, ftm_vec3 *up, ftm_vec3 *fwd);

/* The view is drawn over the whole w x h window but framed in the rows
 * below its top `top` pixels, which the HUD covers: the target is drawn at
 * the centre of those rows and the field of view spans their height, so
 * what the camera frames is not hidden under the HUD. `top` is clamped to
 * 0 .. 60 % of h; this gives the height of the rows the view is framed in. */
double ftm_camera_view_height(int h, double top);

/* proj * view for a w x h window whose top `top` pixel rows are kept clear. */
void ftm_camera_matrix(const ftm_camera *c, int w, int h, double top, float out[16]);

/* Window pixel (x right, y down, origin top-left) of a world point in the
 * same view; false when it is behind the camera. */
bool ftm_camera_project(const ftm_camera *c, int w, int h, double top, ftm_vec3 p, double *px,
                        double *py);

#endif
