/* SPDX-License-Identifier: GPL-3.0-or-later */
/* STL surfaces (binary and ASCII) through Assimp (libassimp), with our own
 * checks in front and behind: the file's size is bounded, its kind is told
 * from its bytes before Assimp sees it (Assimp would otherwise try its
 * other importers on anything), vertices are joined by exact position (STL
 * repeats them for every facet), and every facet is checked, its number
 * (and, in ASCII, its line) named. Library ftm_stl, beside libftm
 * (ftm/stl.h says why). */
#include "ftm/stl.h"

#include "ftm/internal/load.h"

#include <assimp/cimport.h>
#include <assimp/scene.h>

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* As for the text formats (load.c). */
#define STL_MAX_BYTES ((size_t)256 << 20)

static int read_binary_file(const char *path, uint8_t **data, size_t *size, ftm_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return ftm_error_set(err, FTM_EIO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = 1 << 16, n = 0;
    uint8_t *buf = malloc(cap);
    int rc = buf ? FTM_OK : ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    while (rc == FTM_OK) {
        if (n == cap) {
            if (cap > STL_MAX_BYTES) {
                rc = ftm_error_set(err, FTM_ERANGE, "%s: file larger than %zu bytes", path,
                                   STL_MAX_BYTES);
                break;
            }
            uint8_t *nb = realloc(buf, cap * 2);
            if (!nb) {
                rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory reading the file", path);
                break;
            }
            buf = nb;
            cap *= 2;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f))
                rc = ftm_error_set(err, FTM_EIO, "%s: read error at byte %zu", path, n);
            break;
        }
    }
    fclose(f);
    if (rc != FTM_OK) {
        free(buf);
        return rc;
    }
    *data = buf;
    *size = n;
    return FTM_OK;
}

/* Binary: an 80-byte header, a uint32 facet count, 50 bytes a facet (which
 * also decides when the header starts with "solid", as some exporters
 * write). ASCII: "solid" first, after blanks. */
typedef enum stl_kind { STL_NONE, STL_BINARY, STL_ASCII } stl_kind;

static stl_kind stl_kind_of(const uint8_t *d, size_t size, uint32_t *facets)
{
    if (size >= 84) {
        uint32_t n;
        memcpy(&n, d + 80, 4); /* little-endian, as the format says (and x86-64, arm64) */
        if ((uint64_t)size == 84 + 50 * (uint64_t)n) {
            *facets = n;
            return STL_BINARY;
        }
    }
    size_t i = 0;
    while (i < size && (d[i] == ' ' || d[i] == '\t' || d[i] == '\r' || d[i] == '\n'))
        i++;
    if (size - i >= 5 && memcmp(d + i, "solid", 5) == 0)
        return STL_ASCII;
    return STL_NONE;
}

/* Lines of the "facet" keywords of an ASCII STL, in order: facet k's line
 * for messages (Assimp keeps the facets in file order). */
static int32_t *ascii_facet_lines(const uint8_t *d, size_t size, size_t *count)
{
    size_t cap = 64, n = 0;
    int32_t *lines = malloc(cap * sizeof *lines);
    if (!lines)
        return NULL;
    int32_t line = 1;
    for (size_t i = 0; i < size; i++) {
        if (d[i] == '\n') {
            line++;
            continue;
        }
        bool start = i == 0 || d[i - 1] == '\n' || d[i - 1] == ' ' || d[i - 1] == '\t';
        if (start && size - i >= 6 && memcmp(d + i, "facet", 5) == 0 &&
            (d[i + 5] == ' ' || d[i + 5] == '\t')) {
            if (n == cap) {
                int32_t *nl = realloc(lines, 2 * cap * sizeof *lines);
                if (!nl) {
                    free(lines);
                    return NULL;
                }
                lines = nl;
                cap *= 2;
            }
            lines[n++] = line;
        }
    }
    *count = n;
    return lines;
}

/* Where a facet is, for messages: "NAME:LINE: facet K" or "NAME: facet K". */
static void facet_where(char *out, size_t cap, const char *path, const int32_t *lines,
                        size_t nlines, size_t facet)
{
    if (lines && facet < nlines)
        snprintf(out, cap, "%.200s:%d: facet %zu", path, (int)lines[facet], facet + 1);
    else
        snprintf(out, cap, "%.200s: facet %zu", path, facet + 1);
}

typedef struct edge_use {
    int32_t a, b; /* directed, as the facet has it */
    int32_t facet;
} edge_use;

static int compare_edges(const void *pa, const void *pb)
{
    const edge_use *x = pa, *y = pb;
    int32_t xa = x->a < x->b ? x->a : x->b, xb = x->a < x->b ? x->b : x->a;
    int32_t ya = y->a < y->b ? y->a : y->b, yb = y->a < y->b ? y->b : y->a;
    if (xa != ya)
        return (xa > ya) - (xa < ya);
    if (xb != yb)
        return (xb > yb) - (xb < yb);
    return (x->facet > y->facet) - (x->facet < y->facet);
}

/* A closed surface: every edge in two facets that cross it in opposite
 * directions. The first edge that is not names its facet(s). */
static int check_closed(const ftm_surface *s, const char *path, const int32_t *lines,
                        size_t nlines, ftm_error *err)
{
    size_t n = 3 * (size_t)s->triangle_count;
    edge_use *e = malloc((n ? n : 1) * sizeof *e);
    if (!e)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    for (int32_t t = 0; t < s->triangle_count; t++)
        for (int k = 0; k < 3; k++)
            e[3 * (size_t)t + (size_t)k] = (edge_use){.a = s->triangles[3 * t + k],
                                                      .b = s->triangles[3 * t + (k + 1) % 3],
                                                      .facet = t};
    qsort(e, n, sizeof *e, compare_edges);
    int rc = FTM_OK;
    for (size_t i = 0; i < n && rc == FTM_OK;) {
        size_t j = i + 1;
        while (j < n && compare_edges(&(edge_use){e[j].a, e[j].b, 0},
                                      &(edge_use){e[i].a, e[i].b, 0}) == 0)
            j++;
        const double *p = s->positions + 3 * (size_t)e[i].a, *q = s->positions + 3 * (size_t)e[i].b;
        char where[300];
        facet_where(where, sizeof where, path, lines, nlines, (size_t)e[i].facet);
        if (j - i != 2)
            rc = ftm_error_set(err, FTM_EPARSE,
                               "%s: the surface is not closed: its edge (%g %g %g)-(%g %g %g) is "
                               "in %zu facet%s, not 2; a volume needs a closed surface",
                               where, p[0], p[1], p[2], q[0], q[1], q[2], j - i,
                               j - i == 1 ? "" : "s");
        else if (e[i].a == e[i + 1].a)
            rc = ftm_error_set(err, FTM_EPARSE,
                               "%s: facet %d is oriented against it across the edge (%g %g "
                               "%g)-(%g %g %g): the surface's facets must all face outward (or "
                               "all inward)",
                               where, (int)e[i + 1].facet + 1, p[0], p[1], p[2], q[0], q[1], q[2]);
        i = j;
    }
    free(e);
    return rc;
}

/* Six times the volume a closed surface encloses (divergence theorem):
 * negative when its facets face inward. */
static double enclosed_volume(const ftm_surface *s)
{
    double v = 0;
    for (int32_t t = 0; t < s->triangle_count; t++) {
        const double *a = s->positions + 3 * (size_t)s->triangles[3 * t],
                     *b = s->positions + 3 * (size_t)s->triangles[3 * t + 1],
                     *c = s->positions + 3 * (size_t)s->triangles[3 * t + 2];
        v += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
             a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    return v;
}

static void flip_facets(ftm_surface *s)
{
    for (int32_t t = 0; t < s->triangle_count; t++) {
        int32_t x = s->triangles[3 * t + 1];
        s->triangles[3 * t + 1] = s->triangles[3 * t + 2];
        s->triangles[3 * t + 2] = x;
    }
}

void ftm_surface_destroy(ftm_surface *s)
{
    if (!s)
        return;
    free(s->positions);
    free(s->triangles);
    free(s);
}

typedef struct corner_key {
    const double *p;
    int32_t at;
} corner_key;

static int compare_corner_keys(const void *pa, const void *pb)
{
    const corner_key *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a->p[i] != b->p[i])
            return (a->p[i] > b->p[i]) - (a->p[i] < b->p[i]);
    return (a->at > b->at) - (a->at < b->at);
}

/* Facets given as 3 corner positions each (9 doubles): corners at one
 * position become one vertex, numbered in order of first appearance; then
 * each facet is checked (distinct corners, not on one line). */
static int surface_of_corners(const double *xyz, size_t facets, const char *path,
                              const int32_t *lines, size_t nlines, ftm_surface **out,
                              ftm_error *err)
{
    const size_t nc = 3 * facets;
    corner_key *k = malloc(nc * sizeof *k);
    int32_t *rep = malloc(nc * sizeof *rep), *vid = malloc(nc * sizeof *vid);
    ftm_surface *s = calloc(1, sizeof *s);
    if (s) {
        s->triangles = malloc(nc * sizeof *s->triangles);
        s->positions = malloc(3 * nc * sizeof *s->positions);
    }
    int rc = FTM_OK;
    if (!k || !rep || !vid || !s || !s->triangles || !s->positions)
        rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    if (rc == FTM_OK) {
        for (size_t i = 0; i < nc; i++)
            k[i] = (corner_key){.p = xyz + 3 * i, .at = (int32_t)i};
        qsort(k, nc, sizeof *k, compare_corner_keys);
        for (size_t i = 0; i < nc;) { /* a run of one position: its first corner */
            size_t j = i + 1;
            while (j < nc && memcmp(k[j].p, k[i].p, 3 * sizeof(double)) == 0)
                j++;
            for (size_t m = i; m < j; m++)
                rep[k[m].at] = k[i].at;
            i = j;
        }
        int32_t nv = 0;
        for (size_t i = 0; i < nc; i++)
            vid[i] = -1;
        for (size_t i = 0; i < nc; i++) {
            int32_t r = rep[i];
            if (vid[r] < 0) {
                vid[r] = nv;
                memcpy(s->positions + 3 * (size_t)nv, xyz + 3 * (size_t)r, 3 * sizeof(double));
                nv++;
            }
            s->triangles[i] = vid[r];
        }
        s->vertex_count = nv;
        s->triangle_count = (int32_t)facets;
    }
    for (size_t f = 0; f < facets && rc == FTM_OK; f++) {
        const int32_t *t = s->triangles + 3 * f;
        const double *a = s->positions + 3 * (size_t)t[0], *b = s->positions + 3 * (size_t)t[1],
                     *c = s->positions + 3 * (size_t)t[2];
        char where[300];
        facet_where(where, sizeof where, path, lines, nlines, f);
        for (int i = 0; i < 3 && rc == FTM_OK; i++)
            if (t[i] == t[(i + 1) % 3])
                rc = ftm_error_set(err, FTM_EPARSE,
                                   "%s is degenerate: corners %d and %d are the same point (%g %g "
                                   "%g)",
                                   where, i + 1, (i + 1) % 3 + 1, s->positions[3 * t[i]],
                                   s->positions[3 * t[i] + 1], s->positions[3 * t[i] + 2]);
        if (rc != FTM_OK)
            break;
        double u[3], v[3], l2 = 0;
        for (int i = 0; i < 3; i++) {
            u[i] = b[i] - a[i];
            v[i] = c[i] - a[i];
        }
        for (int i = 0; i < 3; i++) { /* the longest edge, squared */
            const double *p = i == 0 ? a : i == 1 ? b : c, *q = i == 0 ? b : i == 1 ? c : a;
            double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                        (p[2] - q[2]) * (p[2] - q[2]);
            l2 = d2 > l2 ? d2 : l2;
        }
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                       u[0] * v[1] - u[1] * v[0]};
        double area2 = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(area2 > 1e-12 * l2) || !isfinite(area2))
            rc = ftm_error_set(err, FTM_EPARSE,
                               "%s is degenerate: its corners are on one line (%g %g %g), (%g %g "
                               "%g), (%g %g %g)",
                               where, a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]);
    }
    free(k);
    free(rep);
    free(vid);
    if (rc != FTM_OK) {
        ftm_surface_destroy(s);
        return rc;
    }
    *out = s;
    return FTM_OK;
}

/* The corners of every facet of every mesh of an Assimp scene. */
static int corners_of_scene(const struct aiScene *sc, const char *path, const int32_t *lines,
                            size_t nlines, double **xyz, size_t *facets, ftm_error *err)
{
    size_t nf = 0;
    for (unsigned m = 0; m < sc->mNumMeshes; m++)
        nf += sc->mMeshes[m]->mNumFaces;
    if (nf == 0)
        return ftm_error_set(err, FTM_EPARSE, "%s: no facets", path);
    if (nf > INT32_MAX / 6)
        return ftm_error_set(err, FTM_ERANGE, "%s: %zu facets are more than supported", path, nf);
    double *p = malloc(9 * nf * sizeof *p);
    if (!p)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    size_t f = 0;
    char where[300];
    for (unsigned m = 0; m < sc->mNumMeshes; m++) {
        const struct aiMesh *mesh = sc->mMeshes[m];
        for (unsigned k = 0; k < mesh->mNumFaces; k++, f++) {
            const struct aiFace *face = &mesh->mFaces[k];
            facet_where(where, sizeof where, path, lines, nlines, f);
            if (face->mNumIndices != 3) {
                free(p);
                return ftm_error_set(err, FTM_EPARSE, "%s has %u corners, not 3", where,
                                     face->mNumIndices);
            }
            for (int i = 0; i < 3; i++) {
                unsigned v = face->mIndices[i];
                if (v >= mesh->mNumVertices) {
                    free(p);
                    return ftm_error_set(err, FTM_EPARSE, "%s: corner %u out of range", where, v);
                }
                double *q = p + 9 * f + 3 * (size_t)i;
                q[0] = mesh->mVertices[v].x;
                q[1] = mesh->mVertices[v].y;
                q[2] = mesh->mVertices[v].z;
                if (!isfinite(q[0]) || !isfinite(q[1]) || !isfinite(q[2])) {
                    int rc = ftm_error_set(err, FTM_EPARSE,
                                           "%s: corner %d has a coordinate that is not finite "
                                           "(%g %g %g)",
                                           where, i + 1, q[0], q[1], q[2]);
                    free(p);
                    return rc;
                }
            }
        }
    }
    *xyz = p;
    *facets = nf;
    return FTM_OK;
}

/* Assimp's C API keeps the last import's error in one string for the
 * process: an import and the reading of its error go under this lock. */
static pthread_mutex_t assimp_lock = PTHREAD_MUTEX_INITIALIZER;

int ftm_surface_parse_stl(const void *data, size_t size, const char *name, bool closed,
                          ftm_surface **out, ftm_error *err)
{
    if (!name)
        name = "(stl)";
    if ((!data && size) || !out)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", name);
    *out = NULL;
    uint32_t nbin = 0;
    stl_kind kind = stl_kind_of(data, size, &nbin);
    if (kind == STL_NONE)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: not an STL file: neither binary (84 bytes, then 50 a facet: "
                             "%zu bytes do not fit the facet count at byte 80) nor ASCII "
                             "(\"solid\" first)",
                             name, size);
    if (size > UINT32_MAX)
        return ftm_error_set(err, FTM_ERANGE, "%s: file larger than 4 GiB", name);
    size_t nlines = 0;
    int32_t *lines = NULL;
    if (kind == STL_ASCII && !(lines = ascii_facet_lines(data, size, &nlines)))
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", name);
    /* no post-processing: the facets as the file has them; the hint keeps
     * Assimp to its STL reader, which our kind check has just vouched for */
    pthread_mutex_lock(&assimp_lock);
    const struct aiScene *sc = aiImportFileFromMemory(data, (unsigned)size, 0, "stl");
    if (!sc) {
        int rc = ftm_error_set(err, FTM_EPARSE, "%s: %s STL not read: %s", name,
                               kind == STL_ASCII ? "ASCII" : "binary", aiGetErrorString());
        pthread_mutex_unlock(&assimp_lock);
        free(lines);
        return rc;
    }
    pthread_mutex_unlock(&assimp_lock);
    double *xyz = NULL;
    size_t facets = 0;
    int rc = corners_of_scene(sc, name, lines, nlines, &xyz, &facets, err);
    aiReleaseImport(sc);
    ftm_surface *s = NULL;
    if (rc == FTM_OK)
        rc = surface_of_corners(xyz, facets, name, lines, nlines, &s, err);
    free(xyz);
    if (rc == FTM_OK && closed)
        rc = check_closed(s, name, lines, nlines, err);
    if (rc == FTM_OK && closed && enclosed_volume(s) < 0)
        flip_facets(s); /* all inward: turned outward */
    free(lines);
    if (rc != FTM_OK) {
        ftm_surface_destroy(s);
        return rc;
    }
    *out = s;
    return FTM_OK;
}

int ftm_surface_load(const char *path, bool closed, ftm_surface **out, ftm_error *err)
{
    if (!path || !out)
        return ftm_error_set(err, FTM_EINVAL, "surface loader: null argument");
    *out = NULL;
    uint8_t *data = NULL;
    size_t size = 0;
    int rc = read_binary_file(path, &data, &size, err);
    if (rc != FTM_OK)
        return rc;
    rc = ftm_surface_parse_stl(data, size, path, closed, out, err);
    free(data);
    return rc;
}

int ftm_load_stl(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                 ftm_error *err)
{
    int rc = ftm_load_check_args(builder, path, material, err);
    if (rc < 0)
        return rc;
    ftm_surface *s = NULL;
    if ((rc = ftm_surface_load(path, false, &s, err)) != FTM_OK)
        return rc;
    rc = ftm_load_commit(builder, path, material,
                         &(ftm_load_data){.pos = s->positions,
                                          .node_count = (size_t)s->vertex_count,
                                          .tris = s->triangles,
                                          .tri_count = (size_t)s->triangle_count,
                                          .tri_edges = true},
                         err);
    ftm_surface_destroy(s);
    return rc;
}
