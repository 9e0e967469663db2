/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Label maps (ftm_label_map_parse_nifti, ftm_label_map_load): segmented
 * scans a user gives to a mesher. Input: byte 0 picks the way in (bit 0:
 * file, which may be gzip-compressed, else bytes in memory), the axes (bit
 * 1: stored, else scanner) and a mask (bit 2: threshold at 0.5); the rest is
 * the file. Properties: a rejected file gets FTM_EPARSE, FTM_EINVAL or
 * FTM_ENOMEM, a message naming it, and no map; an accepted one has
 * dimensions the file's bytes hold, a finite positive voxel size and a
 * finite box, labels 0 or 1 for a mask, and ftm_label_map_at gives each
 * voxel's own label at its centre. */
#include "fuzz.h"

#include "ftm/labels.h"

#include <math.h>
#include <string.h>

static void check_map(const ftm_label_map *m, size_t size, int in_memory, bool mask)
{
    ftm_volume_info in = ftm_label_map_get_info(m);
    fuzz_check(in.nx >= 1 && in.ny >= 1 && in.nz >= 1);
    uint64_t count = (uint64_t)in.nx * (uint64_t)in.ny * (uint64_t)in.nz;
    if (in_memory)
        fuzz_check(count <= size); /* at least a byte a voxel, after the header */
    fuzz_check(in.spacing.x > 0 && in.spacing.y > 0 && in.spacing.z > 0);
    fuzz_check(isfinite(in.spacing.x) && isfinite(in.spacing.y) && isfinite(in.spacing.z));
    fuzz_check(isfinite(in.origin.x + in.nx * in.spacing.x) &&
               isfinite(in.origin.y + in.ny * in.spacing.y) &&
               isfinite(in.origin.z + in.nz * in.spacing.z));
    const int32_t *d = ftm_label_map_data(m);
    fuzz_check(d != NULL);
    /* a few voxels: the first, the last, the middle */
    const int64_t probe[3][3] = {{0, 0, 0},
                                 {in.nx - 1, in.ny - 1, in.nz - 1},
                                 {in.nx / 2, in.ny / 2, in.nz / 2}};
    for (int k = 0; k < 3; k++) {
        const int64_t *p = probe[k];
        int32_t label = d[p[0] + in.nx * (p[1] + (int64_t)in.ny * p[2])];
        if (mask)
            fuzz_check(label == 0 || label == 1);
        ftm_vec3 c = {in.origin.x + ((double)p[0] + 0.5) * in.spacing.x,
                      in.origin.y + ((double)p[1] + 0.5) * in.spacing.y,
                      in.origin.z + ((double)p[2] + 0.5) * in.spacing.z};
        /* a centre whose coordinates round onto a voxel's face (huge boxes
         * of tiny voxels) may land in the neighbour: only check the others */
        double u[3] = {(c.x - in.origin.x) / in.spacing.x, (c.y - in.origin.y) / in.spacing.y,
                       (c.z - in.origin.z) / in.spacing.z};
        bool clean = true;
        for (int a = 0; a < 3; a++)
            clean = clean && fabs(u[a] - ((double)p[a] + 0.5)) < 0.25;
        if (clean)
            fuzz_check(ftm_label_map_at(m, c) == label);
    }
    fuzz_check(ftm_label_map_at(m, (ftm_vec3){NAN, in.origin.y, in.origin.z}) == 0);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    int in_memory = (data[0] & 1) == 0;
    ftm_label_map_def def = ftm_default_label_map_def();
    if (data[0] & 2)
        def.axes = FTM_VOLUME_AXES_STORED;
    def.threshold = (data[0] & 4) != 0;
    def.above = 0.5;
    const uint8_t *file = data + 1;
    size_t n = size - 1;
    ftm_label_map *m = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc;
    if (in_memory) {
        rc = ftm_label_map_parse_nifti(file, n, "m.nii", &def, &m, &err);
    } else {
        const char *path = fuzz_write_file("m.nii", file, n);
        rc = ftm_label_map_load(path, &def, &m, &err);
    }
    if (rc != FTM_OK) {
        fuzz_check(rc == FTM_EPARSE || rc == FTM_EINVAL || rc == FTM_ENOMEM);
        fuzz_check(err.message[0] != '\0');
        fuzz_check(strstr(err.message, "m.nii") != NULL); /* names the file */
        fuzz_check(m == NULL);
        return 0;
    }
    fuzz_check(m != NULL);
    check_map(m, n, in_memory, def.threshold);
    ftm_label_map_destroy(m);
    return 0;
}
