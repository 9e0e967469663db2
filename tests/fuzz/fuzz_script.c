/* ftm-bot scripts: the bot's loader (ftm_script_load, a path) and the
 * scripted haptic device's parser (ftm_script_device_parse, a buffer) read
 * the same format. Properties: either rejects with an error, or yields a
 * script whose times are >= 0 and increase, and whose interpolated positions
 * are finite. */
#include "fuzz.h"

#include "device.h"
#include "script.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_write_file("f.bot", data, size);
    ftm_script sc;
    memset(&sc, 0, sizeof sc);
    if (ftm_script_load(path, &sc) == 0) {
        for (int32_t i = 0; i < sc.npts; i++)
            fuzz_check(sc.pts[i].t >= 0 && (i == 0 || sc.pts[i].t > sc.pts[i - 1].t));
        fuzz_check(sc.ncmds >= 0 && sc.ncmds <= FTM_SCRIPT_COMMANDS_MAX);
        if (sc.npts > 0) {
            double t0 = sc.pts[0].t, t1 = sc.pts[sc.npts - 1].t;
            for (int k = -1; k <= 5; k++) {
                ftm_vec3 p = ftm_script_at(&sc, t0 + (t1 - t0) * k / 4.0);
                fuzz_check(isfinite(p.x) && isfinite(p.y) && isfinite(p.z));
            }
        }
        ftm_script_free(&sc);
    }

    ftm_device_def def = ftm_default_device_def();
    ftm_device *d = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_script_device_parse((const char *)data, size, "f.bot", &def, &d, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && d == NULL && strstr(err.message, "f.bot") != NULL);
        return 0;
    }
    double dur = ftm_script_device_duration(d);
    fuzz_check(isfinite(dur) && dur >= 0);
    for (int k = -1; k <= 5; k++) {
        ftm_vec3 p;
        fuzz_check(ftm_script_device_position(d, dur * k / 4.0, &p) == FTM_OK);
        fuzz_check(isfinite(p.x) && isfinite(p.y) && isfinite(p.z));
    }
    ftm_device_destroy(d);
    return 0;
}
