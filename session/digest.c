/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The scene digest (digest.h), by OpenSSL's EVP SHA-256. */
#include "digest.h"
#include "step.h"

#include <openssl/evp.h>
#include <string.h>

/* The canonical encoding goes through a buffer: the mesh is written eight
 * bytes at a time, and one EVP update per value would cost more than the
 * hashing (about 10^7 values for a 100,000-node mesh). */
typedef struct hasher {
    EVP_MD_CTX *ctx;
    uint8_t buf[4096];
    size_t fill;
} hasher;

static void put(hasher *h, const void *data, size_t n)
{
    if (h->fill + n > sizeof h->buf) {
        EVP_DigestUpdate(h->ctx, h->buf, h->fill);
        h->fill = 0;
    }
    if (n > sizeof h->buf) {
        EVP_DigestUpdate(h->ctx, data, n);
        return;
    }
    memcpy(h->buf + h->fill, data, n);
    h->fill += n;
}

/* Little-endian, whatever the host. */
static void put_u64(hasher *h, uint64_t v)
{
    uint8_t b[8];
    for (int i = 0; i < 8; i++)
        b[i] = (uint8_t)(v >> (8 * i));
    put(h, b, 8);
}

static void put_f64(hasher *h, double d)
{
    uint64_t v;
    memcpy(&v, &d, sizeof v);
    put_u64(h, v);
}

static void put_mesh(hasher *h, const ftm_mesh *m)
{
    int32_t n = ftm_mesh_node_count(m);
    put_u64(h, (uint64_t)n);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 p = ftm_mesh_rest_position(m, i);
        put_f64(h, p.x);
        put_f64(h, p.y);
        put_f64(h, p.z);
        put_f64(h, ftm_mesh_mass(m, i));
        put_f64(h, ftm_mesh_damping(m, i));
        put_u64(h, ftm_mesh_fixed(m, i));
        const int32_t *nb;
        const double *k, *l;
        int32_t deg = ftm_mesh_neighbors(m, i, &nb, &k, &l);
        put_u64(h, (uint64_t)deg);
        for (int32_t j = 0; j < deg; j++) {
            put_u64(h, (uint64_t)nb[j]);
            put_f64(h, k[j]);
            put_f64(h, l[j]);
        }
    }
    int32_t nt = ftm_mesh_triangle_count(m);
    const int32_t *t = ftm_mesh_triangles(m);
    put_u64(h, (uint64_t)nt);
    for (int32_t i = 0; i < 3 * nt; i++)
        put_u64(h, (uint64_t)t[i]);
    /* sliding nodes and springs to ground: appended only where the mesh has
     * some, so the other scenes keep the digests they had */
    if (!ftm_mesh_has_slides(m) && !ftm_mesh_has_ground_springs(m))
        return;
    put(h, "constraints", 11);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 nv[2];
        const int32_t c = ftm_mesh_slide_normals(m, i, nv);
        put_u64(h, (uint64_t)c);
        for (int32_t q = 0; q < c; q++) {
            put_f64(h, nv[q].x);
            put_f64(h, nv[q].y);
            put_f64(h, nv[q].z);
        }
        put_f64(h, ftm_mesh_ground_stiffness(m, i));
    }
}

int ftm_replay_scene_digest(const ftm_scene *scene, uint8_t out[FTM_REPLAY_DIGEST_SIZE])
{
    memset(out, 0, FTM_REPLAY_DIGEST_SIZE);
    hasher h = {.ctx = EVP_MD_CTX_new()};
    if (!h.ctx || !EVP_DigestInit_ex(h.ctx, EVP_sha256(), NULL)) {
        EVP_MD_CTX_free(h.ctx);
        return FTM_ENOMEM;
    }
    put(&h, "ftm.v1 scene", 12);
    put_mesh(&h, ftm_scene_mesh(scene));
    ftm_sim_def d = ftm_replay_sim_def(scene);
    put_f64(&h, d.time_step);
    put_u64(&h, (uint64_t)d.depth);
    put_u64(&h, (uint64_t)d.order);
    put_f64(&h, d.sleep_tolerance);
    put_u64(&h, (uint64_t)d.region_sleep_steps);
    put_u64(&h, d.guard);
    put_f64(&h, d.guard_motion);
    put_u64(&h, (uint64_t)d.max_substeps);
    put_u64(&h, d.cache_layers);
    /* element forces and their materials, per label too, and the elastic
     * far field: appended only where they apply, so a spring scene with the
     * paper's far field keeps the digest it always had */
    if (d.forces != FTM_FORCES_SPRINGS) {
        put(&h, "elements", 8);
        put_u64(&h, (uint64_t)d.forces);
        put_f64(&h, d.young);
        put_f64(&h, d.poisson);
        put_f64(&h, d.density);
        put_u64(&h, (uint64_t)d.label_material_count);
        for (int32_t i = 0; i < d.label_material_count; i++) {
            put_u64(&h, (uint64_t)d.label_materials[i].label);
            put_f64(&h, d.label_materials[i].young);
            put_f64(&h, d.label_materials[i].poisson);
            put_f64(&h, d.label_materials[i].density);
        }
    }
    if (d.far_field != FTM_FAR_FIELD_FIXED) {
        put(&h, "far field", 9);
        put_u64(&h, (uint64_t)d.far_field);
    }
    if (d.mass_scaling) /* the masses, and so every step, change with it */
        put(&h, "mass scaling", 12);
    EVP_DigestUpdate(h.ctx, h.buf, h.fill);
    unsigned int len = 0;
    int ok = EVP_DigestFinal_ex(h.ctx, out, &len);
    EVP_MD_CTX_free(h.ctx);
    if (!ok || len != FTM_REPLAY_DIGEST_SIZE) {
        memset(out, 0, FTM_REPLAY_DIGEST_SIZE);
        return FTM_ENOMEM;
    }
    return FTM_OK;
}

int ftm_sha256(const void *data, size_t size, uint8_t out[32])
{
    unsigned int len = 0;
    if (!EVP_Digest(data, size, out, &len, EVP_sha256(), NULL) || len != 32)
        return FTM_ENOMEM;
    return FTM_OK;
}
