/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The device wrapper (device.h): driver table plus the mapping between the
 * device's workspace and the scene. */
#include "device.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

ftm_device_def ftm_default_device_def(void)
{
    return (ftm_device_def){
        .position_scale = 1.0, .offset = {0, 0, 0}, .force_scale = 1.0, .max_force = INFINITY};
}

static int fail(ftm_error *err, int code, const char *msg)
{
    if (err) {
        err->code = code;
        snprintf(err->message, sizeof err->message, "device: %s", msg);
    }
    return code;
}

int ftm_device_create(const ftm_device_ops *ops, void *self, const ftm_device_def *def,
                      ftm_device **out, ftm_error *err)
{
    ftm_device_def d = def ? *def : ftm_default_device_def();
    if (!ops || !ops->read || !ops->write)
        return fail(err, FTM_EINVAL, "driver table without read or write");
    if (!isfinite(d.position_scale) || d.position_scale == 0)
        return fail(err, FTM_EINVAL, "position_scale must be finite and non-zero");
    if (!isfinite(d.force_scale) || d.force_scale == 0)
        return fail(err, FTM_EINVAL, "force_scale must be finite and non-zero");
    if (!isfinite(d.offset.x) || !isfinite(d.offset.y) || !isfinite(d.offset.z))
        return fail(err, FTM_EINVAL, "offset must be finite");
    if (!(d.max_force > 0))
        return fail(err, FTM_EINVAL, "max_force must be > 0");
    ftm_device *dev = malloc(sizeof *dev);
    if (!dev)
        return fail(err, FTM_ENOMEM, "out of memory");
    *dev = (ftm_device){ops, self, d};
    *out = dev;
    return FTM_OK;
}

void ftm_device_destroy(ftm_device *d)
{
    if (!d)
        return;
    if (d->ops->destroy)
        d->ops->destroy(d->self);
    free(d);
}

int ftm_device_read(ftm_device *d, double now, ftm_vec3 *hip_scene)
{
    ftm_vec3 p;
    int rc = d->ops->read(d->self, now, &p);
    if (rc)
        return rc < 0 ? rc : FTM_EINVAL;
    if (!isfinite(p.x) || !isfinite(p.y) || !isfinite(p.z))
        return FTM_EINVAL;
    double s = d->def.position_scale;
    *hip_scene = (ftm_vec3){d->def.offset.x + s * p.x, d->def.offset.y + s * p.y,
                            d->def.offset.z + s * p.z};
    return FTM_OK;
}

void ftm_device_write(ftm_device *d, double now, ftm_vec3 f)
{
    double s = d->def.force_scale;
    ftm_vec3 g = {s * f.x, s * f.y, s * f.z};
    double m = sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
    if (!isfinite(m)) {
        g = (ftm_vec3){0, 0, 0};
    } else if (m > d->def.max_force) {
        double k = d->def.max_force / m;
        g = (ftm_vec3){g.x * k, g.y * k, g.z * k};
    }
    d->ops->write(d->self, now, g);
}
