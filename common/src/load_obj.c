/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Wavefront OBJ loader: vertices ("v") and polygonal faces ("f").
 *
 * Faces may only use vertices defined above them (this is what makes
 * negative, relative indices well defined, and lets every face be checked
 * with its own line number). Polygons are fanned from their first vertex. */
#include "load_internal.h"

#include "error.h"
#include "ftm/internal/text.h"

#include <stdlib.h>
#include <string.h>

/* Longest piece of offending text quoted in a message. */
#define QUOTE_MAX 40
#define QUOTE(len) ((int)((len) > QUOTE_MAX ? QUOTE_MAX : (len)))

typedef struct obj_state {
    const char *path;
    int32_t line;
    double *pos; /* 3 per vertex */
    size_t vertex_count, pos_cap;
    int32_t *tris; /* 3 per triangle, 0-based */
    size_t tri_count, tri_cap;
    int32_t *face; /* vertices of the face being read */
    size_t face_cap;
    int32_t *used; /* per vertex: line of the last face that used it (0: none) */
    size_t used_count, used_cap;
} obj_state;

static bool token_is(const char *tok, size_t len, const char *word)
{
    return len == strlen(word) && memcmp(tok, word, len) == 0;
}

/* "v x y z [w]" (also tolerates trailing vertex colours "r g b [a]"). */
static int parse_vertex(obj_state *s, const char *cur, const char *end, ftm_error *err)
{
    double v[7];
    int n = 0;
    const char *tok;
    size_t len;
    while (ftm_text_token(&cur, end, &tok, &len)) {
        if (n == 7)
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: vertex has too many values", s->path,
                                 s->line);
        const char *why = ftm_text_read_double(tok, len, &v[n]);
        if (why)
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad vertex coordinate '%.*s': %s",
                                 s->path, s->line, QUOTE(len), tok, why);
        n++;
    }
    if (n < 3)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: vertex needs x y z coordinates", s->path,
                             s->line);
    if (s->vertex_count >= INT32_MAX)
        return ftm_error_set(err, FTM_ERANGE, "%s:%d: too many vertices", s->path, s->line);
    double *p = ftm_load_grow(s->pos, &s->pos_cap, 3 * (s->vertex_count + 1), sizeof *p);
    if (!p)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
    s->pos = p;
    memcpy(p + 3 * s->vertex_count, v, 3 * sizeof *v);
    s->vertex_count++;
    return FTM_OK;
}

/* True if [tok, tok+len) is empty or an integer (texture/normal references
 * are checked for form only: they are not used). */
static bool optional_int(const char *tok, size_t len)
{
    int64_t dummy;
    return len == 0 || ftm_text_parse_int(tok, len, &dummy);
}

/* One face corner: "a", "a/b", "a/b/c" or "a//c"; resolves a (1-based or
 * negative relative) to a 0-based vertex index. */
static int parse_corner(obj_state *s, const char *tok, size_t len, int32_t *out, ftm_error *err)
{
    const char *end = tok + len;
    const char *s1 = memchr(tok, '/', len);
    const char *s2 = s1 ? memchr(s1 + 1, '/', (size_t)(end - s1 - 1)) : NULL;
    int64_t idx = 0;
    const char *why = ftm_text_read_int(tok, (size_t)((s1 ? s1 : end) - tok), &idx);
    if (why)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad face vertex '%.*s': %s", s->path,
                             s->line, QUOTE(len), tok, why);
    bool ok = true;
    if (s1 && !s2) /* a/b: b required */
        ok = s1 + 1 < end && optional_int(s1 + 1, (size_t)(end - s1 - 1));
    else if (s2) /* a/b/c or a//c: c required, no further slash */
        ok = optional_int(s1 + 1, (size_t)(s2 - s1 - 1)) && s2 + 1 < end &&
             !memchr(s2 + 1, '/', (size_t)(end - s2 - 1)) &&
             optional_int(s2 + 1, (size_t)(end - s2 - 1));
    if (!ok)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad face vertex '%.*s'", s->path, s->line,
                             QUOTE(len), tok);
    int64_t count = (int64_t)s->vertex_count;
    if (idx == 0)
        return ftm_error_set(err, FTM_ERANGE,
                             "%s:%d: face index 0 is invalid (OBJ indices start at 1)",
                             s->path, s->line);
    int64_t resolved = idx > 0 ? idx - 1 : count + idx;
    if (resolved < 0 || resolved >= count)
        return ftm_error_set(err, FTM_ERANGE,
                             "%s:%d: face index %lld out of range (%lld vertices defined so far)",
                             s->path, s->line, (long long)idx, (long long)count);
    *out = (int32_t)resolved;
    return FTM_OK;
}

static bool same_position(const double *pos, int32_t a, int32_t b)
{
    const double *pa = pos + 3 * (size_t)a, *pb = pos + 3 * (size_t)b;
    return pa[0] == pb[0] && pa[1] == pb[1] && pa[2] == pb[2];
}

static int parse_face(obj_state *s, const char *cur, const char *end, ftm_error *err)
{
    size_t n = 0;
    const char *tok;
    size_t len;
    while (ftm_text_token(&cur, end, &tok, &len)) {
        int32_t *f = ftm_load_grow(s->face, &s->face_cap, n + 1, sizeof *f);
        if (!f)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
        s->face = f;
        int rc = parse_corner(s, tok, len, &f[n], err);
        if (rc < 0)
            return rc;
        n++;
    }
    if (n < 3)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: face needs at least 3 vertices (has %zu)",
                             s->path, s->line, n);
    /* A repeated vertex would give a zero-length spring and a degenerate
     * triangle. Marking each vertex with the face's line keeps this linear in
     * the face's size (polygons of 10^5 corners exist); vertices defined since
     * the last face start unmarked. */
    if (s->used_count < s->vertex_count) {
        int32_t *u = ftm_load_grow(s->used, &s->used_cap, s->vertex_count, sizeof *u);
        if (!u)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
        s->used = u;
        memset(u + s->used_count, 0, (s->vertex_count - s->used_count) * sizeof *u);
        s->used_count = s->vertex_count;
    }
    for (size_t i = 0; i < n; i++) {
        if (s->used[s->face[i]] == s->line)
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: face repeats vertex %d", s->path,
                                 s->line, s->face[i] + 1);
        s->used[s->face[i]] = s->line;
    }
    if (s->tri_count + (n - 2) > INT32_MAX / 3)
        return ftm_error_set(err, FTM_ERANGE, "%s:%d: too many triangles", s->path, s->line);
    int32_t *t = ftm_load_grow(s->tris, &s->tri_cap, 3 * (s->tri_count + n - 2), sizeof *t);
    if (!t)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
    s->tris = t;
    for (size_t i = 1; i + 1 < n; i++) {
        int32_t tri[3] = {s->face[0], s->face[i], s->face[i + 1]};
        for (int e = 0; e < 3; e++) {
            int32_t a = tri[e], b = tri[(e + 1) % 3];
            if (same_position(s->pos, a, b))
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: face has coincident vertices %d and %d", s->path,
                                     s->line, a + 1, b + 1);
        }
        memcpy(t + 3 * s->tri_count, tri, sizeof tri);
        s->tri_count++;
    }
    return FTM_OK;
}

int ftm_load_obj(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                 ftm_error *err)
{
    int rc = ftm_load_check_args(builder, path, material, err);
    if (rc < 0)
        return rc;
    char *data;
    size_t length;
    rc = ftm_load_read_file(path, &data, &length, err);
    if (rc < 0)
        return rc;

    obj_state s = {.path = path};
    ftm_text text;
    ftm_text_init(&text, path, data, length);
    const char *line;
    size_t len;
    while (rc >= 0 && ftm_text_next_line(&text, &line, &len)) {
        s.line = text.line;
        const char *hash = memchr(line, '#', len);
        const char *end = hash ? hash : line + len;
        const char *cur = line, *tok;
        size_t toklen;
        if (!ftm_text_token(&cur, end, &tok, &toklen))
            continue;
        /* The reader skips a byte order mark that starts the file; one here
         * would hide the line's keyword, and the line would be dropped. */
        if (toklen >= 3 && memcmp(tok, "\xEF\xBB\xBF", 3) == 0) {
            rc = ftm_error_set(err, FTM_EPARSE,
                               "%s:%d: byte order mark (U+FEFF) inside the file (allowed only "
                               "at its start)",
                               path, s.line);
            break;
        }
        if (token_is(tok, toklen, "v"))
            rc = parse_vertex(&s, cur, end, err);
        else if (token_is(tok, toklen, "f"))
            rc = parse_face(&s, cur, end, err);
        /* Everything else (vt, vn, g, o, s, usemtl, mtllib, l, ...) carries
         * nothing a mass-spring model uses. */
    }
    if (rc >= 0) {
        if (length == 0)
            rc = ftm_error_set(err, FTM_EPARSE, "%s: file is empty", path);
        else if (s.vertex_count == 0)
            rc = ftm_error_set(err, FTM_EPARSE, "%s: no vertices ('v' lines)", path);
        else if (s.tri_count == 0)
            rc = ftm_error_set(err, FTM_EPARSE, "%s: no faces ('f' lines)", path);
        else
            rc = ftm_load_commit(builder, path, material,
                                 &(ftm_load_data){.pos = s.pos,
                                                  .node_count = s.vertex_count,
                                                  .tris = s.tris,
                                                  .tri_count = s.tri_count,
                                                  .tri_edges = true},
                                 err);
    }
    free(s.used);
    free(s.face);
    free(s.tris);
    free(s.pos);
    free(data);
    return rc;
}
