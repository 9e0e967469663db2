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

/* The 12 edges and 12 face diagonals of a hexahedron (corner pairs): the
 * edges alone would leave it free to shear, like lattice3d's 6-stencil. */
static const int8_t hex_springs[24][2] = {
    {0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6}, {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7},
    {0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 5}, {1, 4}, {1, 6}, {2, 5}, {2, 7}, {3, 6}, {3, 4}, {0, 7}};

/* A hexahedron's faces, outward for a positive Jacobian. */
static const int8_t hex_faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                       {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};

typedef struct quad_rec {
    int32_t key[4]; /* sorted corners */
    int32_t v[4];   /* outward order */
} quad_rec;

static int compare_quads(const void *pa, const void *pb)
{
    const quad_rec *a = pa, *b = pb;
    for (int i = 0; i < 4; i++)
        if (a->key[i] != b->key[i])
            return (a->key[i] > b->key[i]) - (a->key[i] < b->key[i]);
    for (int i = 0; i < 4; i++)
        if (a->v[i] != b->v[i])
            return (a->v[i] > b->v[i]) - (a->v[i] < b->v[i]);
    return 0;
}

/* The faces of the hexahedra that belong to one only, each as two
 * triangles (outward), sorted so the result does not depend on the order
 * of the elements' faces in memory. *tris is malloc'd (3 per triangle). */
static int hex_surface(const int32_t *hexes, size_t count, int32_t **tris, size_t *tri_count)
{
    size_t nf = 6 * count;
    quad_rec *f = malloc((nf ? nf : 1) * sizeof *f);
    int32_t *t = malloc((nf ? 2 * nf : 1) * 3 * sizeof *t);
    if (!f || !t) {
        free(f);
        free(t);
        return FTM_ENOMEM;
    }
    for (size_t h = 0; h < count; h++)
        for (int k = 0; k < 6; k++) {
            quad_rec *r = &f[6 * h + (size_t)k];
            for (int i = 0; i < 4; i++)
                r->v[i] = r->key[i] = hexes[8 * h + (size_t)hex_faces[k][i]];
            for (int i = 1; i < 4; i++) /* insertion sort of the key */
                for (int j = i; j > 0 && r->key[j - 1] > r->key[j]; j--) {
                    int32_t x = r->key[j];
                    r->key[j] = r->key[j - 1];
                    r->key[j - 1] = x;
                }
        }
    qsort(f, nf, sizeof *f, compare_quads);
    size_t n = 0;
    for (size_t i = 0; i < nf;) {
        size_t j = i + 1;
        while (j < nf && memcmp(f[j].key, f[i].key, sizeof f[i].key) == 0)
            j++;
        if (j - i == 1) {
            const int32_t *v = f[i].v;
            int32_t *o = t + 6 * n++;
            o[0] = v[0], o[1] = v[1], o[2] = v[2];
            o[3] = v[0], o[4] = v[2], o[5] = v[3];
        }
        i = j;
    }
    free(f);
    *tris = t;
    *tri_count = 2 * n;
    return FTM_OK;
}

/* Adds parsed, validated data to the builder (load_internal.h). Everything
 * that can be rejected for a reason in the data is checked before the first
 * builder call; after that only the builder itself running out of memory can
 * fail half way. */
int ftm_load_commit(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                    const ftm_load_data *d, ftm_error *err)
{
    int32_t offset = ftm_mesh_builder_node_count(builder);
    if (offset < 0)
        return ftm_error_set(err, FTM_EINVAL, "%s: mesh builder is unusable", path);
    if (d->node_count > (size_t)(INT32_MAX - offset))
        return ftm_error_set(err, FTM_ERANGE, "%s: %zu nodes do not fit in the mesh builder", path,
                             d->node_count);
    if (d->tri_count > INT32_MAX / 3 || d->tet_count > INT32_MAX / 6 ||
        d->hex_count > INT32_MAX / 24)
        return ftm_error_set(err, FTM_ERANGE, "%s: too many elements", path);

    const int32_t *tris = d->tris;
    size_t tri_count = d->tri_count;
    int32_t *hex_tris = NULL;
    if (tri_count == 0 && d->hex_count > 0) {
        if (hex_surface(d->hexes, d->hex_count, &hex_tris, &tri_count) != FTM_OK)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
        tris = hex_tris;
    }
    const bool tri_edges = d->tri_edges && d->tri_count > 0;
    size_t key_count = (tri_edges ? 3 * tri_count : 0) + 6 * d->tet_count + 24 * d->hex_count;
    uint64_t *keys = malloc((key_count ? key_count : 1) * sizeof *keys);
    if (!keys) {
        free(hex_tris);
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    }
    size_t n = 0;
    if (tri_edges) {
        for (size_t i = 0; i < tri_count; i++) {
            const int32_t *t = tris + 3 * i;
            keys[n++] = edge_key(t[0], t[1]);
            keys[n++] = edge_key(t[1], t[2]);
            keys[n++] = edge_key(t[2], t[0]);
        }
    }
    for (size_t i = 0; i < d->tet_count; i++) {
        const int32_t *t = d->tets + 4 * i;
        for (int a = 0; a < 4; a++)
            for (int b = a + 1; b < 4; b++)
                keys[n++] = edge_key(t[a], t[b]);
    }
    for (size_t i = 0; i < d->hex_count; i++) {
        const int32_t *h = d->hexes + 8 * i;
        for (int k = 0; k < 24; k++)
            keys[n++] = edge_key(h[hex_springs[k][0]], h[hex_springs[k][1]]);
    }
    /* Sorting makes shared edges adjacent (and the link order deterministic). */
    qsort(keys, n, sizeof *keys, compare_keys);
    size_t edge_count = 0;
    for (size_t i = 0; i < n; i++)
        if (edge_count == 0 || keys[i] != keys[edge_count - 1])
            keys[edge_count++] = keys[i];

    const double *pos = d->pos;
    double *stiffness = malloc((edge_count ? edge_count : 1) * sizeof *stiffness);
    int rc = FTM_OK;
    if (!stiffness)
        rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    for (size_t i = 0; i < edge_count && rc == FTM_OK; i++) {
        const double *pa = pos + 3 * (keys[i] >> 32), *pb = pos + 3 * (keys[i] & 0xffffffffu);
        /* The builder takes the rest length as sqrt of exactly this sum and
         * refuses a zero: check it here so the builder is never half filled. */
        double dx = pb[0] - pa[0], dy = pb[1] - pa[1], dz = pb[2] - pa[2];
        double len2 = dx * dx + dy * dy + dz * dz;
        if (!(isfinite(len2) && len2 > 0)) {
            rc = ftm_error_set(err, FTM_ERANGE,
                               "%s: edge (%g %g %g)-(%g %g %g) is too %s for a spring", path,
                               pa[0], pa[1], pa[2], pb[0], pb[1], pb[2],
                               len2 > 0 ? "long" : "short");
            break;
        }
        double k = edge_stiffness(material, pa, pb);
        if (!(isfinite(k) && k > 0)) {
            rc = ftm_error_set(err, FTM_EINVAL,
                               "%s: edge (%g %g %g)-(%g %g %g) gets spring stiffness %g "
                               "(check material stiffness and axis_scale)",
                               path, pa[0], pa[1], pa[2], pb[0], pb[1], pb[2], k);
            break;
        }
        stiffness[i] = k;
    }
    if (rc != FTM_OK) {
        free(stiffness);
        free(keys);
        free(hex_tris);
        return rc;
    }

    const char *what = NULL;
    for (size_t i = 0; i < d->node_count && rc >= 0; i++) {
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
    const int32_t tet0 = ftm_mesh_builder_tetrahedron_count(builder);
    for (size_t i = 0; i < d->tet_count && rc >= 0; i++) {
        const int32_t *t = d->tets + 4 * i;
        rc = ftm_mesh_builder_add_tetrahedron(builder, offset + t[0], offset + t[1], offset + t[2],
                                              offset + t[3]);
        if (rc >= 0 && d->tet_labels && d->tet_labels[i] != 0)
            rc = ftm_mesh_builder_set_tetrahedron_label(builder, tet0 + (int32_t)i,
                                                        d->tet_labels[i]);
        what = "tetrahedron";
    }
    const int32_t hex0 = ftm_mesh_builder_hexahedron_count(builder);
    for (size_t i = 0; i < d->hex_count && rc >= 0; i++) {
        int32_t h[8];
        for (int k = 0; k < 8; k++)
            h[k] = offset + d->hexes[8 * i + (size_t)k];
        rc = ftm_mesh_builder_add_hexahedron(builder, h);
        if (rc >= 0 && d->hex_labels && d->hex_labels[i] != 0)
            rc = ftm_mesh_builder_set_hexahedron_label(builder, hex0 + (int32_t)i,
                                                       d->hex_labels[i]);
        what = "hexahedron";
    }
    free(stiffness);
    free(keys);
    free(hex_tris);
    if (rc < 0)
        return ftm_error_set(err, rc, "%s: mesh builder refused a %s: %s", path, what,
                             ftm_strerror(rc));
    return FTM_OK;
}

static double triple(const double *o, const double *a, const double *b, const double *c)
{
    double u[3], v[3], w[3];
    for (int i = 0; i < 3; i++) {
        u[i] = a[i] - o[i];
        v[i] = b[i] - o[i];
        w[i] = c[i] - o[i];
    }
    return u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
           u[2] * (v[0] * w[1] - v[1] * w[0]);
}

static double longest_edge_cubed(const double *pos, const int32_t *v, int n)
{
    double l2 = 0;
    for (int a = 0; a < n; a++)
        for (int b = a + 1; b < n; b++) {
            const double *p = pos + 3 * (size_t)v[a], *q = pos + 3 * (size_t)v[b];
            double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
            double d2 = dx * dx + dy * dy + dz * dz;
            l2 = d2 > l2 ? d2 : l2;
        }
    return l2 * sqrt(l2);
}

ftm_load_shape ftm_load_tet_shape(const double *pos, const int32_t v[4])
{
    double six_v = triple(pos + 3 * (size_t)v[0], pos + 3 * (size_t)v[1], pos + 3 * (size_t)v[2],
                          pos + 3 * (size_t)v[3]);
    double bound = 1e-12 * longest_edge_cubed(pos, v, 4);
    if (!(fabs(six_v) > bound))
        return FTM_LOAD_SHAPE_DEGENERATE;
    return six_v > 0 ? FTM_LOAD_SHAPE_OK : FTM_LOAD_SHAPE_INVERTED;
}

ftm_load_shape ftm_load_hex_shape(const double *pos, const int32_t v[8])
{
    /* corner c's neighbours along the element's own axes (x, y, z) */
    static const int8_t axes[8][3] = {{1, 3, 4}, {2, 0, 5}, {3, 1, 6}, {0, 2, 7},
                                      {7, 5, 0}, {4, 6, 1}, {5, 7, 2}, {6, 4, 3}};
    double bound = 1e-12 * longest_edge_cubed(pos, v, 8);
    int positive = 0, negative = 0;
    for (int c = 0; c < 8; c++) {
        double j = triple(pos + 3 * (size_t)v[c], pos + 3 * (size_t)v[axes[c][0]],
                          pos + 3 * (size_t)v[axes[c][1]], pos + 3 * (size_t)v[axes[c][2]]);
        positive += j > bound;
        negative += j < -bound;
    }
    return positive == 8   ? FTM_LOAD_SHAPE_OK
           : negative == 8 ? FTM_LOAD_SHAPE_INVERTED
                           : FTM_LOAD_SHAPE_DEGENERATE;
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
    if (ext_equals(dot, ".stl")) /* Assimp stays out of the core: ftm/stl.h */
        return ftm_error_set(err, FTM_EINVAL,
                             "%s: STL is read by the ftm_stl library (ftm_load_stl), not by "
                             "libftm's loaders: convert the surface to .obj to use it here",
                             path);
    return ftm_error_set(err, FTM_EINVAL,
                         "%s: unknown mesh format '%s' (expected .obj, .msh or .node)", path, dot);
}

/* An element's corners in increasing order, and where it was in the input. */
typedef struct elem_key {
    int32_t v[8];
    size_t at;
} elem_key;

static int compare_elem_keys(const void *pa, const void *pb)
{
    const elem_key *a = pa, *b = pb;
    for (int i = 0; i < 8; i++)
        if (a->v[i] != b->v[i])
            return (a->v[i] > b->v[i]) - (a->v[i] < b->v[i]);
    return (a->at > b->at) - (a->at < b->at);
}

int ftm_load_find_repeated(const int32_t *elements, int corners, size_t count, size_t *first,
                           size_t *second)
{
    if (count < 2)
        return 0;
    elem_key *keys = malloc(count * sizeof *keys);
    if (!keys)
        return FTM_ENOMEM;
    for (size_t t = 0; t < count; t++) {
        elem_key *k = &keys[t];
        k->at = t;
        for (int i = 0; i < 8; i++)
            k->v[i] = INT32_MAX; /* unused slots of a tetrahedron */
        for (int i = 0; i < corners; i++) { /* insertion sort of the corners */
            int32_t x = elements[(size_t)corners * t + (size_t)i];
            int j = i;
            for (; j > 0 && k->v[j - 1] > x; j--)
                k->v[j] = k->v[j - 1];
            k->v[j] = x;
        }
    }
    qsort(keys, count, sizeof *keys, compare_elem_keys);
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

int ftm_load_find_repeated_tet(const int32_t *tets, size_t count, size_t *first, size_t *second)
{
    return ftm_load_find_repeated(tets, 4, count, first, second);
}
