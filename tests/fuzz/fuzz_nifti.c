/* SPDX-License-Identifier: GPL-3.0-or-later */
/* NIfTI-1 volumes (ftm_volume_parse_nifti, ftm_volume_load): scans a user
 * gives. Input: byte 0 picks the way in, even = bytes in memory, odd = a
 * file (which may be gzip-compressed); the rest is the file. Properties: a
 * rejected file gets FTM_EPARSE, FTM_EINVAL or FTM_ENOMEM and a message
 * naming it, and no volume; an accepted one has dimensions that the file's
 * bytes hold, a finite positive voxel size, samples in [0, 1], and its
 * control lattice (when not all air) embeds it so that the lattice at rest
 * maps a point to itself. */
#include "fuzz.h"

#include "ftm/volume.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void check_volume(const ftm_volume *v, size_t size, int in_memory)
{
    ftm_volume_info in = ftm_volume_get_info(v);
    fuzz_check(in.nx >= 1 && in.ny >= 1 && in.nz >= 1);
    uint64_t count = (uint64_t)in.nx * (uint64_t)in.ny * (uint64_t)in.nz;
    if (in_memory)
        fuzz_check(count <= size); /* at least a byte a voxel, after the header */
    fuzz_check(in.spacing.x > 0 && in.spacing.y > 0 && in.spacing.z > 0);
    fuzz_check(isfinite(in.spacing.x) && isfinite(in.spacing.y) && isfinite(in.spacing.z));
    fuzz_check(ftm_volume_data(v) != NULL);
    ftm_vec3 c = {in.origin.x + 0.5 * in.nx * in.spacing.x,
                  in.origin.y + 0.5 * in.ny * in.spacing.y,
                  in.origin.z + 0.5 * in.nz * in.spacing.z};
    double s = ftm_volume_sample(v, c);
    fuzz_check(s >= 0.0 && s <= 1.0);

    ftm_volume_lattice_def d = ftm_default_volume_lattice_def();
    d.nodes[0] = d.nodes[1] = d.nodes[2] = 3;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    fuzz_check(b != NULL);
    int32_t points[27];
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_generate_volume_lattice(b, v, &d, points, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc == FTM_EINVAL && err.message[0] != '\0');
        ftm_mesh_builder_destroy(b);
        return;
    }
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    ftm_mesh *mesh = NULL;
    rc = ftm_mesh_build(b, &bd, &mesh, &err);
    ftm_mesh_builder_destroy(b);
    if (rc != FTM_OK) { /* a voxel size too small for a link's length */
        fuzz_check(rc < 0 && err.message[0] != '\0');
        return;
    }
    for (int i = 0; i < 27; i++)
        points[i] = points[i] < 0 ? -1 : ftm_mesh_node_of_input(mesh, points[i]);
    ftm_ffd *ffd = NULL;
    rc = ftm_ffd_create(mesh, v, d.nodes, points, &ffd, &err);
    fuzz_check(rc == FTM_OK);
    int32_t n = ftm_mesh_node_count(mesh);
    double *pos = malloc(3 * (size_t)n * sizeof *pos);
    fuzz_check(pos != NULL);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 r = ftm_mesh_rest_position(mesh, i);
        pos[3 * i] = r.x;
        pos[3 * i + 1] = r.y;
        pos[3 * i + 2] = r.z;
    }
    ftm_vec3 p = ftm_ffd_map(ffd, pos, c);
    fuzz_check(p.x == c.x && p.y == c.y && p.z == c.z);
    free(pos);
    ftm_ffd_destroy(ffd);
    ftm_mesh_destroy(mesh);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    int in_memory = (data[0] & 1) == 0;
    const uint8_t *file = data + 1;
    size_t n = size - 1;
    ftm_volume *v = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc;
    if (in_memory) {
        rc = ftm_volume_parse_nifti(file, n, "m.nii", NULL, &v, &err);
    } else {
        const char *path = fuzz_write_file("m.nii", file, n);
        rc = ftm_volume_load(path, NULL, &v, &err);
    }
    if (rc != FTM_OK) {
        fuzz_check(rc == FTM_EPARSE || rc == FTM_EINVAL || rc == FTM_ENOMEM);
        fuzz_check(err.message[0] != '\0');
        fuzz_check(strstr(err.message, "m.nii") != NULL); /* names the file */
        fuzz_check(v == NULL);
        return 0;
    }
    fuzz_check(v != NULL);
    check_volume(v, n, in_memory);
    ftm_volume_destroy(v);
    return 0;
}
