/* SPDX-License-Identifier: GPL-3.0-or-later */
/* TetGen .node/.ele loader.
 *
 * .node: "<#points> [<dim=3> [<#attributes> [<boundary markers 0|1>]]]", then
 *        "<index> <x> <y> <z> [attributes...] [marker]" per point.
 * .ele:  "<#tetrahedra> [<nodes per tet 4|10> [<#attributes>]]", then
 *        "<index> <n1> ... <nk> [attributes...]" per tetrahedron.
 * '#' starts a comment anywhere. Point indices must run consecutively from
 * 0 or 1 (TetGen's -z switch); the .ele file must use the same base.
 * For 10-node tetrahedra only the 4 corners are used. */
#include "load_internal.h"

#include "error.h"
#include "ftm/internal/text.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define QUOTE_MAX 40
#define QUOTE(len) ((int)((len) > QUOTE_MAX ? QUOTE_MAX : (len)))

/* One open file and the data line being parsed. */
typedef struct tg_file {
    const char *path;
    char *data;
    size_t length;
    ftm_text text;
    const char *cur, *end; /* rest of the current line, comment stripped */
} tg_file;

typedef struct tg_mesh {
    double *pos; /* 3 per point */
    size_t point_count, pos_cap;
    int64_t base; /* index of the first point: 0 or 1 */
    int32_t *tets;
    size_t tet_count, tet_cap;
    int32_t *labels; /* per tetrahedron: its first attribute, TetGen's region (-A) */
    size_t label_cap;
    size_t labelled; /* tetrahedra with a label >= 1 */
    int32_t *tet_line; /* per tetrahedron: its line and index in the .ele file, */
    int64_t *tet_index; /* for "repeated" messages */
    size_t tet_line_cap, tet_index_cap;
} tg_mesh;

static int open_file(tg_file *f, const char *path, ftm_error *err)
{
    f->path = path;
    int rc = ftm_load_read_file(path, &f->data, &f->length, err);
    if (rc < 0) {
        f->data = NULL;
        return rc;
    }
    ftm_text_init(&f->text, path, f->data, f->length);
    return FTM_OK;
}

/* Advances to the next line with data; false at end of file. */
static bool next_data_line(tg_file *f)
{
    const char *line;
    size_t len;
    while (ftm_text_next_line(&f->text, &line, &len)) {
        const char *hash = memchr(line, '#', len);
        f->cur = line;
        f->end = hash ? hash : line + len;
        const char *probe = f->cur, *tok;
        size_t toklen;
        if (ftm_text_token(&probe, f->end, &tok, &toklen))
            return true;
    }
    return false;
}

/* Number of tokens left on the current line (does not consume them). */
static size_t tokens_left(const tg_file *f)
{
    const char *p = f->cur, *tok;
    size_t len, n = 0;
    while (ftm_text_token(&p, f->end, &tok, &len))
        n++;
    return n;
}

/* Next token as an integer / a finite double; `what` names it in messages.
 * Callers check tokens_left() first, so a token is always there. */
static int next_int(tg_file *f, const char *what, int64_t *out, ftm_error *err)
{
    const char *tok = f->cur, *why = "missing";
    size_t len = 0;
    if (!ftm_text_token(&f->cur, f->end, &tok, &len) ||
        (why = ftm_text_read_int(tok, len, out)) != NULL)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad %s '%.*s': %s", f->path, f->text.line,
                             what, QUOTE(len), tok, why);
    return FTM_OK;
}

static int next_double(tg_file *f, const char *what, double *out, ftm_error *err)
{
    const char *tok = f->cur, *why = "missing";
    size_t len = 0;
    if (!ftm_text_token(&f->cur, f->end, &tok, &len) ||
        (why = ftm_text_read_double(tok, len, out)) != NULL)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad %s '%.*s': %s", f->path, f->text.line,
                             what, QUOTE(len), tok, why);
    return FTM_OK;
}

/* Reads an optional header field: the default if the line has no more tokens. */
static int header_field(tg_file *f, const char *what, int64_t fallback, int64_t *out,
                        ftm_error *err)
{
    if (tokens_left(f) == 0) {
        *out = fallback;
        return FTM_OK;
    }
    return next_int(f, what, out, err);
}

static int expect_count(tg_file *f, size_t want, const char *what, ftm_error *err)
{
    size_t have = tokens_left(f);
    if (have != want)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: %s needs %zu values, found %zu", f->path,
                             f->text.line, what, want, have);
    return FTM_OK;
}

/* Reading stops after the announced count, so trailing data means the
 * header's count is wrong (or the file was concatenated): refuse it. */
static int expect_end(tg_file *f, int64_t count, const char *what, ftm_error *err)
{
    if (next_data_line(f))
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: data after the %lld %s the header announces",
                             f->path, f->text.line, (long long)count, what);
    return FTM_OK;
}

static int read_nodes(tg_file *f, tg_mesh *m, ftm_error *err)
{
    if (!next_data_line(f))
        return ftm_error_set(err, FTM_EPARSE, "%s: %s", f->path,
                             f->length == 0 ? "file is empty" : "no header line");
    int rc;
    int64_t count, dim, nattr, nmarker;
    if (tokens_left(f) > 4)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: .node header has more than 4 values",
                             f->path, f->text.line);
    if ((rc = next_int(f, "point count", &count, err)) < 0 ||
        (rc = header_field(f, "dimension", 3, &dim, err)) < 0 ||
        (rc = header_field(f, "attribute count", 0, &nattr, err)) < 0 ||
        (rc = header_field(f, "boundary marker flag", 0, &nmarker, err)) < 0)
        return rc;
    if (count <= 0)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: point count %lld (need at least 1)",
                             f->path, f->text.line, (long long)count);
    if (count > INT32_MAX)
        return ftm_error_set(err, FTM_ERANGE, "%s:%d: %lld points are more than supported",
                             f->path, f->text.line, (long long)count);
    if (dim != 3)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: dimension %lld not supported (need 3)",
                             f->path, f->text.line, (long long)dim);
    if (nattr < 0 || nattr > INT32_MAX)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad attribute count %lld", f->path,
                             f->text.line, (long long)nattr);
    if (nmarker != 0 && nmarker != 1)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: boundary marker flag %lld (need 0 or 1)",
                             f->path, f->text.line, (long long)nmarker);

    size_t fields = 4 + (size_t)nattr + (size_t)nmarker;
    /* The arrays grow with the lines actually present, never from the count. */
    for (int64_t i = 0; i < count; i++) {
        if (!next_data_line(f))
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: file ends after %lld of %lld points",
                                 f->path, f->text.line, (long long)i, (long long)count);
        int64_t index;
        double xyz[3], attr;
        if ((rc = expect_count(f, fields, "point line", err)) < 0 ||
            (rc = next_int(f, "point index", &index, err)) < 0)
            return rc;
        if (i == 0) {
            if (index != 0 && index != 1)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: first point index %lld (must be 0 or 1)", f->path,
                                     f->text.line, (long long)index);
            m->base = index;
        } else if (index != m->base + i) {
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: point index %lld out of sequence (expected %lld)",
                                 f->path, f->text.line, (long long)index,
                                 (long long)(m->base + i));
        }
        for (int c = 0; c < 3; c++)
            if ((rc = next_double(f, "coordinate", &xyz[c], err)) < 0)
                return rc;
        for (int64_t a = 0; a < nattr; a++)
            if ((rc = next_double(f, "point attribute", &attr, err)) < 0)
                return rc;
        if (nmarker) {
            int64_t marker;
            if ((rc = next_int(f, "boundary marker", &marker, err)) < 0)
                return rc;
        }
        double *p = ftm_load_grow(m->pos, &m->pos_cap, 3 * (m->point_count + 1), sizeof *p);
        if (!p)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", f->path);
        m->pos = p;
        memcpy(p + 3 * m->point_count, xyz, sizeof xyz);
        m->point_count++;
    }
    return expect_end(f, count, "points", err);
}

static bool same_position(const double *pos, int32_t a, int32_t b)
{
    const double *pa = pos + 3 * (size_t)a, *pb = pos + 3 * (size_t)b;
    return pa[0] == pb[0] && pa[1] == pb[1] && pa[2] == pb[2];
}

static int read_elements(tg_file *f, tg_mesh *m, ftm_error *err)
{
    if (!next_data_line(f))
        return ftm_error_set(err, FTM_EPARSE, "%s: %s", f->path,
                             f->length == 0 ? "file is empty" : "no header line");
    int rc;
    int64_t count, corners, nattr;
    if (tokens_left(f) > 3)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: .ele header has more than 3 values",
                             f->path, f->text.line);
    if ((rc = next_int(f, "tetrahedron count", &count, err)) < 0 ||
        (rc = header_field(f, "nodes per tetrahedron", 4, &corners, err)) < 0 ||
        (rc = header_field(f, "attribute count", 0, &nattr, err)) < 0)
        return rc;
    if (count <= 0)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: tetrahedron count %lld (need at least 1)",
                             f->path, f->text.line, (long long)count);
    if (count > INT32_MAX / 6)
        return ftm_error_set(err, FTM_ERANGE, "%s:%d: %lld tetrahedra are more than supported",
                             f->path, f->text.line, (long long)count);
    if (corners != 4 && corners != 10)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: %lld nodes per tetrahedron (need 4 or 10)",
                             f->path, f->text.line, (long long)corners);
    if (nattr < 0 || nattr > INT32_MAX)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad attribute count %lld", f->path,
                             f->text.line, (long long)nattr);

    size_t fields = 1 + (size_t)corners + (size_t)nattr;
    int64_t first = m->base, last = m->base + (int64_t)m->point_count - 1;
    for (int64_t i = 0; i < count; i++) {
        if (!next_data_line(f))
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: file ends after %lld of %lld tetrahedra",
                                 f->path, f->text.line, (long long)i, (long long)count);
        int64_t index, node[10];
        double attr, region = 0;
        if ((rc = expect_count(f, fields, "tetrahedron line", err)) < 0 ||
            (rc = next_int(f, "tetrahedron index", &index, err)) < 0)
            return rc;
        for (int64_t c = 0; c < corners; c++) {
            if ((rc = next_int(f, "node index", &node[c], err)) < 0)
                return rc;
            /* Mid-edge nodes of 10-node tets are unused but must exist too. */
            if (node[c] < first || node[c] > last)
                return ftm_error_set(err, FTM_ERANGE,
                                     "%s:%d: node index %lld out of range (points are %lld..%lld)",
                                     f->path, f->text.line, (long long)node[c], (long long)first,
                                     (long long)last);
        }
        for (int64_t a = 0; a < nattr; a++) {
            if ((rc = next_double(f, "tetrahedron attribute", &attr, err)) < 0)
                return rc;
            if (a == 0)
                region = attr;
        }
        /* the region attribute is the element's label: a whole number */
        if (!(region >= 0 && region <= INT32_MAX && region == floor(region)))
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: tetrahedron %lld has region attribute %g, not a label "
                                 "(a whole number: 0 for none, 1 .. 2147483647)",
                                 f->path, f->text.line, (long long)index, region);
        int32_t v[4];
        for (int c = 0; c < 4; c++)
            v[c] = (int32_t)(node[c] - m->base);
        for (int a = 0; a < 4; a++) {
            for (int b = a + 1; b < 4; b++) {
                if (v[a] == v[b])
                    return ftm_error_set(err, FTM_EPARSE,
                                         "%s:%d: degenerate tetrahedron: node %lld repeated",
                                         f->path, f->text.line, (long long)node[a]);
                if (same_position(m->pos, v[a], v[b]))
                    return ftm_error_set(err, FTM_EPARSE,
                                         "%s:%d: degenerate tetrahedron: nodes %lld and %lld "
                                         "coincide",
                                         f->path, f->text.line, (long long)node[a],
                                         (long long)node[b]);
            }
        }
        ftm_load_shape shape = ftm_load_tet_shape(m->pos, v);
        if (shape != FTM_LOAD_SHAPE_OK)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: tetrahedron %lld is %s", f->path, f->text.line,
                                 (long long)index,
                                 shape == FTM_LOAD_SHAPE_INVERTED
                                     ? "inverted (negative volume: TetGen orders the corners "
                                       "so that the fourth sees the first three "
                                       "counter-clockwise)"
                                     : "degenerate (its corners are nearly in one plane)");
        int32_t *t = ftm_load_grow(m->tets, &m->tet_cap, 4 * (m->tet_count + 1), sizeof *t);
        if (t)
            m->tets = t;
        int32_t *g = ftm_load_grow(m->labels, &m->label_cap, m->tet_count + 1, sizeof *g);
        if (g)
            m->labels = g;
        int32_t *l = ftm_load_grow(m->tet_line, &m->tet_line_cap, m->tet_count + 1, sizeof *l);
        if (l)
            m->tet_line = l;
        int64_t *x = ftm_load_grow(m->tet_index, &m->tet_index_cap, m->tet_count + 1, sizeof *x);
        if (x)
            m->tet_index = x;
        if (!t || !g || !l || !x)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", f->path);
        memcpy(t + 4 * m->tet_count, v, sizeof v);
        g[m->tet_count] = (int32_t)region;
        m->labelled += region >= 1;
        l[m->tet_count] = f->text.line;
        x[m->tet_count] = index;
        m->tet_count++;
    }
    if ((rc = expect_end(f, count, "tetrahedra", err)) < 0)
        return rc;
    size_t orig = 0, again = 0;
    rc = ftm_load_find_repeated_tet(m->tets, m->tet_count, &orig, &again);
    if (rc == FTM_ENOMEM)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", f->path);
    if (rc > 0)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: tetrahedron %lld has the same four nodes as tetrahedron "
                             "%lld (line %d)",
                             f->path, m->tet_line[again], (long long)m->tet_index[again],
                             (long long)m->tet_index[orig], m->tet_line[orig]);
    /* labels on every tetrahedron or none: one without would have no material */
    if (m->labelled > 0 && m->labelled < m->tet_count)
        for (size_t i = 0; i < m->tet_count; i++)
            if (m->labels[i] == 0)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: tetrahedron %lld has region attribute 0 (no label) "
                                     "while %zu others have one: label every tetrahedron or none",
                                     f->path, m->tet_line[i], (long long)m->tet_index[i],
                                     m->labelled);
    return FTM_OK;
}

/* "mesh.node" -> "mesh.ele" ("MESH.NODE" -> "MESH.ELE"); a path without an
 * extension gets ".ele" appended. Returns NULL when out of memory. */
static char *ele_path_for(const char *node_path)
{
    const char *slash = strrchr(node_path, '/');
    const char *base = slash ? slash + 1 : node_path;
    const char *dot = strrchr(base, '.');
    size_t stem = dot && dot != base ? (size_t)(dot - node_path) : strlen(node_path);
    bool upper = dot && dot != base && dot[1] >= 'A' && dot[1] <= 'Z';
    char *p = malloc(stem + 5);
    if (p) {
        memcpy(p, node_path, stem);
        memcpy(p + stem, upper ? ".ELE" : ".ele", 5);
    }
    return p;
}

int ftm_load_tetgen(ftm_mesh_builder *builder, const char *node_path,
                    const ftm_material_def *material, ftm_error *err)
{
    int rc = ftm_load_check_args(builder, node_path, material, err);
    if (rc < 0)
        return rc;
    char *ele_path = ele_path_for(node_path);
    if (!ele_path)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", node_path);

    tg_file nodes = {0}, elements = {0};
    tg_mesh m = {0};
    rc = open_file(&nodes, node_path, err);
    if (rc >= 0)
        rc = read_nodes(&nodes, &m, err);
    if (rc >= 0)
        rc = open_file(&elements, ele_path, err);
    if (rc >= 0)
        rc = read_elements(&elements, &m, err);
    /* No .face file: the builder derives the surface from the tetrahedra. */
    if (rc >= 0)
        rc = ftm_load_commit(builder, node_path, material,
                             &(ftm_load_data){.pos = m.pos,
                                              .node_count = m.point_count,
                                              .tets = m.tets,
                                              .tet_labels = m.labelled ? m.labels : NULL,
                                              .tet_count = m.tet_count},
                             err);
    free(m.tet_index);
    free(m.tet_line);
    free(m.labels);
    free(m.tets);
    free(m.pos);
    free(elements.data);
    free(nodes.data);
    free(ele_path);
    return rc;
}
