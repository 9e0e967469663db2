/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Scene files (ftm_scene_parse), then a short run of what they describe:
 * the parameters a user may get wrong reach the core. Properties: a rejected
 * scene gets a negative code and a message naming the file; an accepted one
 * makes a simulation (or is refused with a message) whose steps end OK or
 * FTM_EUNSTABLE, leave no NaN in the state, leave the state unchanged when
 * a step is refused, and run twice to the same hash.
 *
 * Kept out: lattices over 40 nodes a side and phantoms over 64 voxels a side
 * (the parser's own limits are unit tested; big meshes only make the fuzzer
 * slow), elastic far fields over ELASTIC_MAX_NODES nodes, and paths into /dev, /proc
 * or /sys (a scene may name any readable file, and /dev/stdin would block). */
#include "fuzz.h"

#include "ftm/scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SIM_MAX_NODES 3000
/* a scene far past its critical step makes the guard substep every step:
 * 40 steps of one such (a 26-neighbour 10 x 11 x 5 lattice at h = 0.05, run
 * twice) took 7.5 s in the fuzz build and over libFuzzer's 10 s on a busy
 * machine */
#define SIM_MAX_STEPS 16
/* the elastic far field's precomputation grows with the mesh (2 s for the
 * 12^3 default scene in a release build, ten times that under ASan): its
 * scenes are run up to this size, and without the per-machine cache */
#define ELASTIC_MAX_NODES 400

static int contains(const char *text, size_t size, const char *word)
{
    size_t n = strlen(word);
    for (size_t i = 0; i + n <= size; i++)
        if (memcmp(text + i, word, n) == 0)
            return 1;
    return 0;
}

/* Whether a number above limit follows `key` on a line it starts
 * ([volume]'s "nodes = 10 10 10", "voxels = 64"). */
static int key_over(const char *text, size_t size, const char *key, long limit)
{
    size_t n = strlen(key);
    for (size_t i = 0; i + n <= size; i++) {
        if (memcmp(text + i, key, n) != 0)
            continue;
        size_t b = i; /* the key starts its line (fixed_nodes is another key) */
        while (b > 0 && (text[b - 1] == ' ' || text[b - 1] == '\t'))
            b--;
        if (b > 0 && text[b - 1] != '\n')
            continue;
        long v = 0;
        size_t digits = 0;
        for (size_t j = i + n; j < size && text[j] != '\n'; j++) {
            if (text[j] >= '0' && text[j] <= '9') {
                v = 10 * v + (text[j] - '0');
                if (++digits >= 8 || v > limit)
                    return 1;
            } else {
                v = 0;
                digits = 0;
            }
        }
    }
    return 0;
}

static int too_big(const char *text, size_t size)
{
    if (key_over(text, size, "nodes", 40) || key_over(text, size, "voxels", 64))
        return 1;
    if (contains(text, size, "/dev") || contains(text, size, "/proc") ||
        contains(text, size, "/sys"))
        return 1;
    /* lines "n[xyz] = N" with N > 40 */
    for (size_t i = 0; i + 1 < size; i++) {
        if (text[i] != 'n' || (text[i + 1] != 'x' && text[i + 1] != 'y' && text[i + 1] != 'z'))
            continue;
        size_t j = i + 2;
        while (j < size && (text[j] == ' ' || text[j] == '\t' || text[j] == '='))
            j++;
        size_t digits = 0;
        long v = 0;
        while (j < size && text[j] >= '0' && text[j] <= '9' && digits < 8) {
            v = 10 * v + (text[j] - '0');
            j++;
            digits++;
        }
        if (digits == 8 || v > 40)
            return 1;
    }
    return 0;
}

static int positions_finite(const ftm_sim *sim, int32_t n)
{
    const double *x = ftm_sim_positions(sim);
    for (int32_t i = 0; i < 3 * n; i++)
        if (!isfinite(x[i]))
            return 0;
    return 1;
}

/* Runs the scene's loads for up to SIM_MAX_STEPS steps; returns the hash. */
static uint64_t run(const ftm_scene *scene, const ftm_mesh *mesh)
{
    ftm_sim_def def = ftm_scene_sim_def(scene);
    if (def.far_field == FTM_FAR_FIELD_ELASTIC && ftm_mesh_node_count(mesh) > ELASTIC_MAX_NODES)
        return 0;
    ftm_sim *sim = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_sim_create(mesh, &def, &sim, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && err.message[0] != '\0');
        return 0;
    }
    int32_t n = ftm_mesh_node_count(mesh);
    int32_t loads = ftm_scene_load_count(scene);
    ftm_contact *c = malloc((size_t)(loads > 0 ? loads : 1) * sizeof *c);
    fuzz_check(c != NULL);
    int32_t steps = ftm_scene_steps(scene);
    if (steps > SIM_MAX_STEPS)
        steps = SIM_MAX_STEPS;
    for (int32_t s = 0; s < steps; s++) {
        int32_t k = ftm_scene_contacts_at(scene, (double)s * def.time_step, c, loads);
        fuzz_check(k >= 0 && k <= loads);
        rc = ftm_sim_set_contacts(sim, c, k, &err);
        if (rc != FTM_OK) {
            fuzz_check(rc < 0 && err.message[0] != '\0');
            break;
        }
        uint64_t before = ftm_sim_hash(sim);
        rc = ftm_sim_step(sim);
        fuzz_check(rc == FTM_OK || rc == FTM_EUNSTABLE);
        fuzz_check(positions_finite(sim, n));
        if (rc == FTM_EUNSTABLE) {
            fuzz_check(ftm_sim_hash(sim) == before);
            break;
        }
    }
    uint64_t h = ftm_sim_hash(sim);
    free(c);
    ftm_sim_destroy(sim);
    return h;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *text = (const char *)data;
    setenv("FTM_CACHE_DIR", "", 1);
    if (too_big(text, size))
        return 0;
    ftm_scene *scene = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_scene_parse(text, size, "fuzz.scene", &scene, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && scene == NULL);
        fuzz_check(strstr(err.message, "fuzz.scene") != NULL);
        return 0;
    }
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    fuzz_check(mesh != NULL);
    if (ftm_mesh_node_count(mesh) <= SIM_MAX_NODES)
        fuzz_check(run(scene, mesh) == run(scene, mesh));
    ftm_scene_destroy(scene);
    return 0;
}
