/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Mesh loading: dispatch by file extension, plus the pieces every loader
 * shares (argument checks, bounded file reading, array growth, and the final
 * commit of parsed data into the builder).
 *
 * Each loader parses into its own arrays and validates everything before it
 * calls ftm_load_commit(), so a malformed file never touches the builder. */
#include "load_internal.h"

#include "error.h"
#include "material.h"
#include "ftm/internal/text.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Mesh files above this size are refused rather than read into memory. */
#define FTM_LOAD_MAX_BYTES ((size_t)256 << 20)

/* Checked before any file is read, so a bad material is reported as such and
 * not as a side effect of the first spring. */
int ftm_load_check_args(const ftm_mesh_builder *builder, const char *path,
                        const ftm_material_def *material, ftm_error *err)
{
    if (!path)
        return ftm_error_set(err, FTM_EINVAL, "mesh loader: path is NULL");
    if (!builder)
        return ftm_error_set(err, FTM_EINVAL, "%s: mesh builder is NULL", path);
    if (!material)
        return ftm_error_set(err, FTM_EINVAL, "%s: material is NULL", path);
    char who[FTM_ERROR_MESSAGE_MAX / 2];
    snprintf(who, sizeof who, "%.200s: material", path);
    return ftm_material_check(material, who, err);
}

int ftm_load_read_file(const char *path, char **data, size_t *length, ftm_error *err)
{
    return ftm_text_read_file(path, FTM_LOAD_MAX_BYTES, data, length, err);
}

/* Returns an array with room for at least `needed` elements (growing
 * geometrically), or NULL on overflow or out of memory, in which case the old
 * array is still valid and must be freed by the caller. */
void *ftm_load_grow(void *array, size_t *capacity, size_t needed, size_t elem_size)
{
    if (needed <= *capacity)
        return array;
    size_t cap = *capacity ? *capacity : 64;
    while (cap < needed) {
        if (cap > SIZE_MAX / 2)
            return NULL;
        cap *= 2;
    }
    if (cap > SIZE_MAX / elem_size)
        return NULL;
    void *p = realloc(array, cap * elem_size);
    if (p)
        *capacity = cap;
    return p;
}

/* An edge as one sortable key: smaller index in the high half. */
static uint64_t edge_key(int32_t a, int32_t b)
{
    uint32_t lo = (uint32_t)(a < b ? a : b), hi = (uint32_t)(a < b ? b : a);
    return (uint64_t)lo << 32 | hi;
}

static int compare_keys(const void *pa, const void *pb)
{
    uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
    return (a > b) - (a < b);
}

/* Spring stiffness for the edge a->b (generate.h's axis-scaling rule).
 * The difference is scaled by its largest component first so that very short
 * or very long edges neither underflow nor overflow when squared. */
static double edge_stiffness(const ftm_material_def *m, const double *pa, const double *pb)
{
    double dx = pb[0] - pa[0], dy = pb[1] - pa[1], dz = pb[2] - pa[2];
    double big = fmax(fabs(dx), fmax(fabs(dy), fabs(dz)));
    if (!(big > 0) || !isfinite(big))
        return NAN;
    dx /= big;
    dy /= big;
    dz /= big;
    double len2 = dx * dx + dy * dy + dz * dz;
    return m->stiffness *
           (m->axis_scale.x * dx * dx + m->axis_scale.y * dy * dy + m->axis_scale.z * dz * dz) /
           len2;
}

/* Adds parsed, validated data to the builder. Indices in tris/tets are
 * 0-based into pos (3 doubles per node). Springs go on every tetrahedron edge
 * and, if tri_edges, every triangle edge; each edge is added once.
 * Everything that can be rejected for a reason in the data is checked before
 * the first builder call; after that only the builder itself running out of
 * memory can fail half way. */
int ftm_load_commit(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                    const double *pos, size_t node_count, const int32_t *tris, size_t tri_count,
                    bool tri_edges, const int32_t *tets, size_t tet_count, ftm_error *err)
{
    int32_t offset = ftm_mesh_builder_node_count(builder);
    if (offset < 0)
        return ftm_error_set(err, FTM_EINVAL, "%s: mesh builder is unusable", path);
    if (node_count > (size_t)(INT32_MAX - offset))
        return ftm_error_set(err, FTM_ERANGE, "%s: %zu nodes do not fit in the mesh builder", path,
                             node_count);
    if (tri_count > INT32_MAX / 3 || tet_count > INT32_MAX / 6)
        return ftm_error_set(err, FTM_ERANGE, "%s: too many elements", path);

    size_t key_count = (tri_edges ? 3 * tri_count : 0) + 6 * tet_count;
    uint64_t *keys = malloc((key_count ? key_count : 1) * sizeof *keys);
    if (!keys)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    size_t n = 0;
    if (tri_edges) {
        for (size_t i = 0; i < tri_count; i++) {
            const int32_t *t = tris + 3 * i;
            keys[n++] = edge_key(t[0], t[1]);
            keys[n++] = edge_key(t[1], t[2]);
            keys[n++] = edge_key(t[2], t[0]);
        }
    }
    for (size_t i = 0; i < tet_count; i++) {
        const int32_t *t = tets + 4 * i;
        for (int a = 0; a < 4; a++)
            for (int b = a + 1; b < 4; b++)
                keys[n++] = edge_key(t[a], t[b]);
    }
    /* Sorting makes shared edges adjacent (and the link order deterministic). */
    qsort(keys, n, sizeof *keys, compare_keys);
    size_t edge_count = 0;
    for (size_t i = 0; i < n; i++)
        if (edge_count == 0 || keys[i] != keys[edge_count - 1])
            keys[edge_count++] = keys[i];

    double *stiffness = malloc((edge_count ? edge_count : 1) * sizeof *stiffness);
    if (!stiffness) {
        free(keys);
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    }
    for (size_t i = 0; i < edge_count; i++) {
        const double *pa = pos + 3 * (keys[i] >> 32), *pb = pos + 3 * (keys[i] & 0xffffffffu);
        /* The builder takes the rest length as sqrt of exactly this sum and
         * refuses a zero: check it here so the builder is never half filled. */
        double dx = pb[0] - pa[0], dy = pb[1] - pa[1], dz = pb[2] - pa[2];
        double len2 = dx * dx + dy * dy + dz * dz;
        if (!(isfinite(len2) && len2 > 0)) {
            int rc = ftm_error_set(err, FTM_ERANGE,
                                   "%s: edge (%g %g %g)-(%g %g %g) is too %s for a spring", path,
                                   pa[0], pa[1], pa[2], pb[0], pb[1], pb[2],
                                   len2 > 0 ? "long" : "short");
            free(stiffness);
            free(keys);
            return rc;
        }
        double k = edge_stiffness(material, pa, pb);
        if (!(isfinite(k) && k > 0)) {
            int rc = ftm_error_set(err, FTM_EINVAL,
                                   "%s: edge (%g %g %g)-(%g %g %g) gets spring stiffness %g "
                                   "(check material stiffness and axis_scale)",
                                   path, pa[0], pa[1], pa[2], pb[0], pb[1], pb[2], k);
            free(stiffness);
            free(keys);
            return rc;
        }
        stiffness[i] = k;
    }

    int rc = FTM_OK;
    const char *what = NULL;
    for (size_t i = 0; i < node_count && rc >= 0; i++) {
        ftm_node_def def = {
            .position = {pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]},
            .mass = material->node_mass,
            .damping = material->node_damping,
            .fixed = false,
        };
        int32_t idx = ftm_mesh_builder_add_node(builder, &def);
        rc = idx < 0 ? idx : FTM_OK;
        what = "node";
    }
    for (size_t i = 0; i < edge_count && rc >= 0; i++) {
        ftm_link_def def = {
            .a = offset + (int32_t)(keys[i] >> 32),
            .b = offset + (int32_t)(keys[i] & 0xffffffffu),
            .stiffness = stiffness[i],
            .rest_length = -1.0,
        };
        rc = ftm_mesh_builder_add_link(builder, &def);
        what = "spring";
    }
    for (size_t i = 0; i < tri_count && rc >= 0; i++) {
        const int32_t *t = tris + 3 * i;
        rc = ftm_mesh_builder_add_triangle(builder, offset + t[0], offset + t[1], offset + t[2]);
        what = "triangle";
    }
    for (size_t i = 0; i < tet_count && rc >= 0; i++) {
        const int32_t *t = tets + 4 * i;
        rc = ftm_mesh_builder_add_tetrahedron(builder, offset + t[0], offset + t[1], offset + t[2],
                                              offset + t[3]);
        what = "tetrahedron";
    }
    free(stiffness);
    free(keys);
    if (rc < 0)
        return ftm_error_set(err, rc, "%s: mesh builder refused a %s: %s", path, what,
                             ftm_strerror(rc));
    return FTM_OK;
}

/* ASCII-only, locale-independent case-insensitive comparison. */
static bool ext_equals(const char *ext, const char *want)
{
    for (; *ext && *want; ext++, want++) {
        char c = *ext;
        if (c >= 'A' && c <= 'Z')
            c = (char)(c - 'A' + 'a');
        if (c != *want)
            return false;
    }
    return *ext == *want;
}

int ftm_load_mesh(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                  ftm_error *err)
{
    if (!path)
        return ftm_error_set(err, FTM_EINVAL, "mesh loader: path is NULL");
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    if (!dot || dot == base)
        return ftm_error_set(err, FTM_EINVAL,
                             "%s: unknown mesh format (no file extension; expected .obj, .msh "
                             "or .node)",
                             path);
    if (ext_equals(dot, ".obj"))
        return ftm_load_obj(builder, path, material, err);
    if (ext_equals(dot, ".msh"))
        return ftm_load_gmsh(builder, path, material, err);
    if (ext_equals(dot, ".node"))
        return ftm_load_tetgen(builder, path, material, err);
    return ftm_error_set(err, FTM_EINVAL,
                         "%s: unknown mesh format '%s' (expected .obj, .msh or .node)", path, dot);
}

/* A tetrahedron's corners in increasing order, and where it was in the input. */
typedef struct tet_key {
    int32_t v[4];
    size_t at;
} tet_key;

static int compare_tet_keys(const void *pa, const void *pb)
{
    const tet_key *a = pa, *b = pb;
    for (int i = 0; i < 4; i++)
        if (a->v[i] != b->v[i])
            return (a->v[i] > b->v[i]) - (a->v[i] < b->v[i]);
    return (a->at > b->at) - (a->at < b->at);
}

int ftm_load_find_repeated_tet(const int32_t *tets, size_t count, size_t *first, size_t *second)
{
    if (count < 2)
        return 0;
    tet_key *keys = malloc(count * sizeof *keys);
    if (!keys)
        return FTM_ENOMEM;
    for (size_t t = 0; t < count; t++) {
        tet_key *k = &keys[t];
        k->at = t;
        for (int i = 0; i < 4; i++) { /* insertion sort of the corners */
            int32_t x = tets[4 * t + (size_t)i];
            int j = i;
            for (; j > 0 && k->v[j - 1] > x; j--)
                k->v[j] = k->v[j - 1];
            k->v[j] = x;
        }
    }
    qsort(keys, count, sizeof *keys, compare_tet_keys);
    /* Equal corners form a run ordered by position: its first entry is the
     * original, its second the repeat a one-pass reader would meet first. */
    int found = 0;
    for (size_t i = 1; i < count; i++) {
        bool second_of_run = memcmp(keys[i].v, keys[i - 1].v, sizeof keys[i].v) == 0 &&
                             (i < 2 || memcmp(keys[i].v, keys[i - 2].v, sizeof keys[i].v) != 0);
        if (second_of_run && (!found || keys[i].at < *second)) {
            *first = keys[i - 1].at;
            *second = keys[i].at;
            found = 1;
        }
    }
    free(keys);
    return found;
}
