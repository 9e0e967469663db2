/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Haptic devices: where the haptic loop (haptic.h) reads the haptic
 * interface point (HIP) and writes the force (docs/haptics.md, "Devices").
 *
 * A device is a table of functions (ftm_device_ops) over a private object,
 * plus a definition (ftm_device_def) that maps the device's own workspace to
 * the scene: hip_scene = offset + position_scale * hip_device and
 * force_device = force_scale * force_scene, clamped to max_force. Drivers
 * report native coordinates; ftm_device_read / ftm_device_write apply the
 * mapping, so a new driver (OpenHaptics, Force Dimension, CHAI3D, Falcon)
 * only fills in ftm_device_ops (see docs/haptics.md, "Adding a device").
 *
 * Built in: the mouse probe (the GL client feeds it cursor events; the HIP
 * moves on a plane in front of the camera, the wheel pushes it in and out)
 * and the scripted device (a trajectory file, for tests and benchmarks).
 *
 * Threads: read, write, start and stop run on the haptic thread only. The
 * mouse calls (ftm_mouse_*) may come from any thread (the GL thread): they
 * take the device's own lock. Library ftm_haptic: C + pthreads only. */
#ifndef FTM_CLIENT_DEVICE_H
#define FTM_CLIENT_DEVICE_H

#include "ftm/base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_device_ops {
    const char *name; /* "mouse", "script", "phantom", ... */
    /* Optional: called by ftm_haptic_start before the first tick (open the
     * device, calibrate). A failure makes ftm_haptic_start fail. */
    int (*start)(void *self, ftm_error *err);
    /* Every tick: the HIP in device coordinates at time now [s, haptic
     * clock]. A negative return means the device is lost: the loop renders
     * no force until it reads again. */
    int (*read)(void *self, double now, ftm_vec3 *hip);
    /* Every tick after read: the force to display, device coordinates [N]. */
    void (*write)(void *self, double now, ftm_vec3 force);
    /* Optional: after the last tick (a zero force has been written). */
    void (*stop)(void *self);
    /* Frees self. */
    void (*destroy)(void *self);
} ftm_device_ops;

typedef struct ftm_device_def {
    double position_scale; /* scene metres per device unit (default 1) */
    ftm_vec3 offset;       /* scene position of the device origin [m] (default 0) */
    double force_scale;    /* device units per newton (default 1) */
    double max_force;      /* the device's own limit, device units (default INFINITY) */
} ftm_device_def;

ftm_device_def ftm_default_device_def(void);

typedef struct ftm_device {
    const ftm_device_ops *ops;
    void *self;
    ftm_device_def def;
} ftm_device;

/* Wraps a driver: ops (static, outlives the device) and its object self
 * (ops->destroy frees it in ftm_device_destroy). def NULL: defaults. */
int ftm_device_create(const ftm_device_ops *ops, void *self, const ftm_device_def *def,
                      ftm_device **out, ftm_error *err);
void ftm_device_destroy(ftm_device *d);

/* The haptic loop's calls: map between device and scene coordinates.
 * read rejects a non-finite position (returns FTM_EINVAL). */
int ftm_device_read(ftm_device *d, double now, ftm_vec3 *hip_scene);
void ftm_device_write(ftm_device *d, double now, ftm_vec3 force_scene);

/* ---- mouse probe ---------------------------------------------------- */

/* The camera the cursor is seen through. forward, right, up: orthonormal
 * camera axes (right-handed, forward = viewing direction). */
typedef struct ftm_mouse_view {
    ftm_vec3 eye;
    ftm_vec3 forward, right, up;
    double fov_y;       /* vertical field of view [rad], in (0, pi) */
    /* the rows the view is framed in [px], > 0 (ftm_camera_view_height:
     * below the HUD; only cursor motion is unprojected, so where they start
     * does not matter) */
    double width, height;
} ftm_mouse_view;

/* A mouse probe whose HIP starts at hip0 [scene m]. scroll_step: metres the
 * HIP moves along the viewing direction per wheel unit (<= 0: 1 mm).
 * smoothing: time constant [s] of the low-pass the haptic thread applies to
 * the cursor's HIP (cursor events come at the display rate, ~60 Hz; without
 * it the force would step every frame); 0 = none, < 0 = default 15 ms. */
int ftm_mouse_create(const ftm_device_def *def, ftm_vec3 hip0, double scroll_step,
                     double smoothing, ftm_device **out, ftm_error *err);

/* The following return FTM_EINVAL if d is not a mouse probe or an argument
 * is not finite / out of range. Any thread. */
int ftm_mouse_set_view(ftm_device *d, const ftm_mouse_view *view);
/* Left button at cursor (px, py) [px, origin top left]: down starts a
 * drag, up ends it. */
int ftm_mouse_button(ftm_device *d, bool down, double px, double py);
/* Cursor moved. While dragging, the HIP moves by the cursor's motion on the
 * plane through the HIP perpendicular to the viewing direction (relative:
 * pressing the button never makes the HIP jump). */
int ftm_mouse_motion(ftm_device *d, double px, double py);
/* Wheel: dy > 0 pushes the HIP by dy * scroll_step along the push axis
 * (ftm_mouse_set_push_axis; by default away from the camera, into the
 * scene), dy < 0 pulls it back along the same line. */
int ftm_mouse_scroll(ftm_device *d, double dy);
/* The direction the wheel pushes the HIP (normalised here; zero: the
 * viewing direction again). The client sets it into the tissue along the
 * surface's normal where the contact began, so that pushing and pulling
 * back follow one line whatever the camera does meanwhile, and the contact
 * releases where it began (issue 27: along the view ray, after an orbit,
 * the way out dragged the tissue sideways). */
int ftm_mouse_set_push_axis(ftm_device *d, ftm_vec3 axis);
/* Limits the HIP's travel around a scene whose bounding box is lo..hi:
 * it stays within margin of the box, and at most max_depth inside it (a
 * HIP deeper than that is moved back to that depth below the nearest
 * face; a box thinner than 2 max_depth on any axis gives no depth limit,
 * the margin only). Without it the wheel, 1 mm per notch, drove a probe through
 * the whole organ and the shared session unstable. The HIP is moved inside
 * at once. FTM_EINVAL for an empty box or a negative or non-finite value. */
int ftm_mouse_set_limits(ftm_device *d, ftm_vec3 lo, ftm_vec3 hi, double max_depth, double margin);
/* Places the HIP (e.g. above the organ after loading a scene). */
int ftm_mouse_set_hip(ftm_device *d, ftm_vec3 hip);
/* A HIP left inside the tissue: the contact that began at point (on the
 * rest surface, outward normal) has ended with the HIP more than tolerance
 * [m] below that surface (an instructor's reset forgets contacts, and the
 * server starts one only where a probe crosses the surface inwards: a probe
 * left inside would press nothing, at 0 N). Moves the HIP back out along the
 * way it went in (from point to the HIP; along the normal where that grazes
 * the surface) to clearance [m] above the surface. Returns 1 moved (*moved_to,
 * may be NULL, the new HIP), 0 not inside, FTM_EINVAL (bad argument). */
int ftm_mouse_out_of_tissue(ftm_device *d, ftm_vec3 point, ftm_vec3 normal, double clearance,
                            double tolerance, ftm_vec3 *moved_to);
/* Where the cursor has put the HIP (before smoothing), scene coordinates. */
int ftm_mouse_target(ftm_device *d, ftm_vec3 *hip);

/* ---- scripted device ------------------------------------------------ */

/* A trajectory in the ftm-bot script format (docs/bot-script.md): lines
 * `t x y z` (seconds, metres), linearly interpolated, held before the first
 * and after the last point; `#` comments; the bot's commands are parsed
 * (script_text.h, the parser every reader of the format shares) and then
 * ignored. Time 0 is the first read. Errors name the file and line. */
int ftm_script_device_open(const char *path, const ftm_device_def *def, ftm_device **out,
                           ftm_error *err);
int ftm_script_device_parse(const char *text, size_t length, const char *name,
                            const ftm_device_def *def, ftm_device **out, ftm_error *err);
/* The scripted HIP at script time t (no clock involved). */
int ftm_script_device_position(const ftm_device *d, double t, ftm_vec3 *hip);
/* Script duration (time of the last point) [s]. */
double ftm_script_device_duration(const ftm_device *d);

/* What the haptic loop wrote to a scripted device so far (any thread). */
typedef struct ftm_script_device_log {
    uint64_t reads, writes;
    ftm_vec3 last_force;   /* device units */
    double max_force;      /* largest magnitude written */
    double last_write;     /* time of the last write [s, haptic clock] */
} ftm_script_device_log;
int ftm_script_device_get_log(ftm_device *d, ftm_script_device_log *log);

#ifdef __cplusplus
}
#endif
#endif
