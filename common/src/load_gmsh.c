/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Gmsh MSH 4.1 ASCII loader.
 *
 * Reads $MeshFormat, $Entities (the physical groups of volumes: element
 * labels), $Nodes and $Elements; every other section is skipped.
 * The parser is line based, in the layout Gmsh (and meshio) write: one node
 * tag per line, then one coordinate line per node, one line per element.
 * Node tags may be sparse; they are mapped to 0-based indices in order of
 * appearance. $Nodes must precede $Elements (as Gmsh writes it), so element
 * errors can be reported on their own line. */
#include "load_internal.h"

#include "error.h"
#include "ftm/internal/text.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define QUOTE_MAX 40
#define QUOTE(len) ((int)((len) > QUOTE_MAX ? QUOTE_MAX : (len)))
/* Most tokens on one line we ever need (a 125-node hexahedron plus its tag). */
#define MAX_TOKENS 128

enum { ELEM_LINE = 1, ELEM_TRIANGLE = 2, ELEM_QUAD = 3, ELEM_TETRAHEDRON = 4,
       ELEM_HEXAHEDRON = 5, ELEM_PRISM = 6, ELEM_PYRAMID = 7, ELEM_POINT = 15 };

typedef struct tag_entry {
    int64_t tag;
    int32_t index;
} tag_entry;

/* A volume group's name in $PhysicalNames: its elements' label's. */
typedef struct physical_name {
    int32_t label;
    char name[FTM_MESH_LABEL_NAME_MAX + 1];
} physical_name;

/* A volume entity of $Entities: its physical group is its elements' label. */
typedef struct volume_entity {
    int64_t tag;
    int32_t line;
    int32_t physical_count;
    int64_t physical[2]; /* the first two, for messages */
} volume_entity;

/* Volume elements of one kind as read: corners, label, line and tag. */
typedef struct elem_list {
    int32_t *v; /* corners per element */
    int32_t *label;
    int32_t *line;
    int64_t *tag;
    size_t count, v_cap, label_cap, line_cap, tag_cap;
    size_t labelled; /* elements with a label >= 1 */
} elem_list;

typedef struct msh_state {
    const char *path;
    ftm_text text;
    /* The current line split into tokens. */
    const char *tok[MAX_TOKENS];
    size_t toklen[MAX_TOKENS];
    size_t ntok;
    bool too_long; /* the line had more than MAX_TOKENS tokens */

    double *pos; /* 3 per node */
    size_t pos_cap;
    int32_t *node_line; /* line of each node's tag, for "repeated" messages */
    size_t node_line_cap;
    size_t node_count;
    tag_entry *tags; /* sorted by tag after $Nodes */
    size_t tags_cap;

    int32_t *tris;
    size_t tri_count, tri_cap;
    elem_list tets, hexes;

    bool have_entities;
    /* $PhysicalNames of volume groups: a label's name, for display */
    struct physical_name *names;
    size_t name_count, name_cap;
    volume_entity *volumes; /* sorted by tag after $Entities */
    size_t volume_count, volume_cap;
} msh_state;

/* Nodes per element type, for the types Gmsh defines (0: unknown). */
static int nodes_per_element(int64_t type)
{
    static const int table[] = {
        0,  2,  3,  4,  4,  8,  6,  5,  3,  6,  9, /* 0..10 */
        10, 27, 18, 14, 1,  8,  20, 15, 13, 9,     /* 11..20 */
        10, 12, 15, 15, 21, 4,  5,  6,  20, 35, 56 /* 21..31 */
    };
    if (type >= 0 && type < (int64_t)(sizeof table / sizeof table[0]))
        return table[type];
    if (type == 92)
        return 64;
    if (type == 93)
        return 125;
    return 0;
}

/* What a Gmsh element type is, for messages. */
static const char *element_name(int64_t type)
{
    static const char *const names[] = {
        NULL,
        "2-node line",
        "3-node triangle",
        "4-node quadrangle",
        "4-node tetrahedron",
        "8-node hexahedron",
        "6-node prism",
        "5-node pyramid",
        "3-node line",
        "6-node triangle",
        "9-node quadrangle",
        "10-node tetrahedron",
        "27-node hexahedron",
        "18-node prism",
        "14-node pyramid",
        "1-node point",
        "8-node quadrangle",
        "20-node hexahedron",
        "15-node prism",
        "13-node pyramid",
    };
    if (type >= 1 && type < (int64_t)(sizeof names / sizeof names[0]))
        return names[type];
    return "higher-order element";
}

/* Reads the next non-blank line into s->tok; false at end of file. */
static bool next_line(msh_state *s)
{
    const char *line;
    size_t len;
    while (ftm_text_next_line(&s->text, &line, &len)) {
        const char *cur = line, *end = line + len;
        s->ntok = 0;
        s->too_long = false;
        const char *tok;
        size_t toklen;
        while (ftm_text_token(&cur, end, &tok, &toklen)) {
            if (s->ntok == MAX_TOKENS) {
                s->too_long = true;
                break;
            }
            s->tok[s->ntok] = tok;
            s->toklen[s->ntok] = toklen;
            s->ntok++;
        }
        if (s->ntok > 0)
            return true;
    }
    return false;
}

static bool line_is(const msh_state *s, const char *word)
{
    return s->ntok == 1 && s->toklen[0] == strlen(word) &&
           memcmp(s->tok[0], word, s->toklen[0]) == 0;
}

/* Next line inside section `section`, which must hold data (not a $ line). */
static int data_line(msh_state *s, const char *section, const char *what, ftm_error *err)
{
    if (!next_line(s))
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: file ends inside $%s (expected %s)", s->path,
                             s->text.line, section, what);
    if (s->tok[0][0] == '$')
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: expected %s, found '%.*s'", s->path,
                             s->text.line, what, QUOTE(s->toklen[0]), s->tok[0]);
    return FTM_OK;
}

/* Section end marker, e.g. "$EndNodes". */
static int end_line(msh_state *s, const char *section, ftm_error *err)
{
    char want[32];
    snprintf(want, sizeof want, "$End%s", section);
    if (!next_line(s))
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: file ends inside $%s (expected %s)", s->path,
                             s->text.line, section, want);
    if (!line_is(s, want))
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: expected %s, found '%.*s'", s->path,
                             s->text.line, want, QUOTE(s->toklen[0]), s->tok[0]);
    return FTM_OK;
}

/* Parses token i as an integer in [lo, hi]; `what` names it in messages. */
static int int_token(msh_state *s, size_t i, int64_t lo, int64_t hi, const char *what,
                     int64_t *out, ftm_error *err)
{
    const char *why = ftm_text_read_int(s->tok[i], s->toklen[i], out);
    if (why)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad %s '%.*s': %s", s->path, s->text.line,
                             what, QUOTE(s->toklen[i]), s->tok[i], why);
    if (*out < lo || *out > hi)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: %s %lld out of range", s->path,
                             s->text.line, what, (long long)*out);
    return FTM_OK;
}

static int expect_tokens(msh_state *s, size_t n, const char *what, ftm_error *err)
{
    if (s->ntok != n || s->too_long)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: %s needs %zu values, found %s%zu", s->path,
                             s->text.line, what, n, s->too_long ? "over " : "", s->ntok);
    return FTM_OK;
}

static int parse_format(msh_state *s, ftm_error *err)
{
    int rc = data_line(s, "MeshFormat", "version, file type and data size", err);
    if (rc < 0)
        return rc;
    if ((rc = expect_tokens(s, 3, "$MeshFormat", err)) < 0)
        return rc;
    double version;
    if (!ftm_text_parse_double(s->tok[0], s->toklen[0], &version) || version != 4.1)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: MSH version '%.*s' not supported (need 4.1)", s->path,
                             s->text.line, QUOTE(s->toklen[0]), s->tok[0]);
    int64_t file_type, data_size;
    if ((rc = int_token(s, 1, 0, 1, "file type", &file_type, err)) < 0)
        return rc;
    if (file_type == 1)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: binary MSH not supported (save as ASCII MSH 4.1)", s->path,
                             s->text.line);
    if ((rc = int_token(s, 2, 1, 64, "data size", &data_size, err)) < 0)
        return rc;
    return end_line(s, "MeshFormat", err);
}

static int compare_tags(const void *pa, const void *pb)
{
    const tag_entry *a = pa, *b = pb;
    if (a->tag != b->tag)
        return (a->tag > b->tag) - (a->tag < b->tag);
    return (a->index > b->index) - (a->index < b->index);
}

static int compare_tag_only(const void *pa, const void *pb)
{
    const tag_entry *a = pa, *b = pb;
    return (a->tag > b->tag) - (a->tag < b->tag);
}

static int32_t find_tag(const msh_state *s, int64_t tag)
{
    if (s->node_count == 0)
        return -1; /* bsearch must not be given a NULL array */
    const tag_entry key = {.tag = tag};
    const tag_entry *e = bsearch(&key, s->tags, s->node_count, sizeof *s->tags, compare_tag_only);
    return e ? e->index : -1;
}

static int parse_nodes(msh_state *s, ftm_error *err)
{
    int rc = data_line(s, "Nodes", "the $Nodes header", err);
    if (rc < 0 || (rc = expect_tokens(s, 4, "$Nodes header", err)) < 0)
        return rc;
    int64_t nblocks, nnodes, minmax;
    if ((rc = int_token(s, 0, 0, INT64_MAX, "entity block count", &nblocks, err)) < 0 ||
        (rc = int_token(s, 1, 0, INT64_MAX, "node count", &nnodes, err)) < 0 ||
        (rc = int_token(s, 2, 0, INT64_MAX, "minimum node tag", &minmax, err)) < 0 ||
        (rc = int_token(s, 3, 0, INT64_MAX, "maximum node tag", &minmax, err)) < 0)
        return rc;
    if (nnodes > INT32_MAX)
        return ftm_error_set(err, FTM_ERANGE, "%s:%d: %lld nodes are more than supported", s->path,
                             s->text.line, (long long)nnodes);

    /* Counts are only trusted as far as the content bears them out: arrays
     * grow with the lines actually read. */
    for (int64_t b = 0; b < nblocks; b++) {
        if ((rc = data_line(s, "Nodes", "a node entity block header", err)) < 0 ||
            (rc = expect_tokens(s, 4, "node entity block header", err)) < 0)
            return rc;
        int64_t dim, entity, parametric, count;
        if ((rc = int_token(s, 0, 0, 3, "entity dimension", &dim, err)) < 0 ||
            (rc = int_token(s, 1, INT32_MIN, INT32_MAX, "entity tag", &entity, err)) < 0 ||
            (rc = int_token(s, 2, 0, 1, "parametric flag", &parametric, err)) < 0 ||
            (rc = int_token(s, 3, 0, INT64_MAX, "block node count", &count, err)) < 0)
            return rc;
        if (count > nnodes - (int64_t)s->node_count)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: block of %lld nodes would exceed the %lld nodes "
                                 "announced in the $Nodes header",
                                 s->path, s->text.line, (long long)count, (long long)nnodes);
        size_t first = s->node_count, n = (size_t)count;
        /* Tags first, one per line ... */
        for (size_t i = 0; i < n; i++) {
            int64_t tag;
            if ((rc = data_line(s, "Nodes", "a node tag", err)) < 0 ||
                (rc = expect_tokens(s, 1, "node tag line", err)) < 0 ||
                (rc = int_token(s, 0, 1, INT64_MAX, "node tag", &tag, err)) < 0)
                return rc;
            tag_entry *t = ftm_load_grow(s->tags, &s->tags_cap, first + i + 1, sizeof *t);
            if (!t)
                return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
            s->tags = t;
            int32_t *l = ftm_load_grow(s->node_line, &s->node_line_cap, first + i + 1, sizeof *l);
            if (!l)
                return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
            s->node_line = l;
            t[first + i] = (tag_entry){.tag = tag, .index = (int32_t)(first + i)};
            l[first + i] = s->text.line;
        }
        /* ... then coordinates, one line per node: x y z, plus u [v [w]] if parametric. */
        size_t want = 3 + (parametric ? (size_t)dim : 0);
        double *p = ftm_load_grow(s->pos, &s->pos_cap, 3 * (first + n), sizeof *p);
        if (!p && n > 0)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
        if (p)
            s->pos = p;
        for (size_t i = 0; i < n; i++) {
            if ((rc = data_line(s, "Nodes", "node coordinates", err)) < 0 ||
                (rc = expect_tokens(s, want, "node coordinate line", err)) < 0)
                return rc;
            for (size_t c = 0; c < want; c++) {
                double v;
                const char *why = ftm_text_read_double(s->tok[c], s->toklen[c], &v);
                if (why)
                    return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad node coordinate '%.*s': %s",
                                         s->path, s->text.line, QUOTE(s->toklen[c]), s->tok[c],
                                         why);
                if (c < 3)
                    s->pos[3 * (first + i) + c] = v;
            }
        }
        s->node_count = first + n;
    }
    if ((rc = end_line(s, "Nodes", err)) < 0)
        return rc;
    if ((int64_t)s->node_count != nnodes)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: $Nodes header announces %lld nodes, blocks hold %zu",
                             s->path, s->text.line, (long long)nnodes, s->node_count);

    /* Sort for lookup (by tag, then order of appearance). A repeated tag
     * forms a run; its second entry is the repeat. Report the repeat that
     * comes first in the file, as a one-pass reader would. */
    if (s->node_count > 0)
        qsort(s->tags, s->node_count, sizeof *s->tags, compare_tags);
    size_t repeat = 0; /* position in tags of the earliest repeat; 0 = none */
    for (size_t i = 1; i < s->node_count; i++) {
        bool second_of_run = s->tags[i].tag == s->tags[i - 1].tag &&
                             (i < 2 || s->tags[i - 2].tag != s->tags[i].tag);
        if (second_of_run && (repeat == 0 || s->tags[i].index < s->tags[repeat].index))
            repeat = i;
    }
    if (repeat > 0)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: node tag %lld repeated (first on line %d)",
                             s->path, s->node_line[s->tags[repeat].index],
                             (long long)s->tags[repeat].tag,
                             s->node_line[s->tags[repeat - 1].index]);
    return FTM_OK;
}

static bool same_position(const double *pos, int32_t a, int32_t b)
{
    const double *pa = pos + 3 * (size_t)a, *pb = pos + 3 * (size_t)b;
    return pa[0] == pb[0] && pa[1] == pb[1] && pa[2] == pb[2];
}

/* Resolves and checks the corner tags of an element on the current line
 * (tokens 1..n, n <= 8) into v. */
static int element_corners(msh_state *s, int n, int32_t *v, ftm_error *err)
{
    int64_t tags[8];
    int rc;
    for (int i = 0; i < n; i++) {
        if ((rc = int_token(s, (size_t)i + 1, 1, INT64_MAX, "node tag", &tags[i], err)) < 0)
            return rc;
        v[i] = find_tag(s, tags[i]);
        if (v[i] < 0)
            return ftm_error_set(err, FTM_ERANGE, "%s:%d: element refers to unknown node tag %lld",
                                 s->path, s->text.line, (long long)tags[i]);
    }
    for (int i = 0; i < n; i++) {
        for (int j = i + 1; j < n; j++) {
            if (v[i] == v[j])
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: degenerate element: node tag %lld repeated",
                                     s->path, s->text.line, (long long)tags[i]);
            if (same_position(s->pos, v[i], v[j]))
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: degenerate element: nodes %lld and %lld coincide",
                                     s->path, s->text.line, (long long)tags[i], (long long)tags[j]);
        }
    }
    return FTM_OK;
}

/* Appends a triangle (its corners on the current line). */
static int add_triangle(msh_state *s, ftm_error *err)
{
    int32_t v[3];
    int rc = element_corners(s, 3, v, err);
    if (rc < 0)
        return rc;
    if (s->tri_count >= INT32_MAX / 6)
        return ftm_error_set(err, FTM_ERANGE, "%s:%d: too many elements", s->path, s->text.line);
    int32_t *a = ftm_load_grow(s->tris, &s->tri_cap, 3 * (s->tri_count + 1), sizeof *a);
    if (!a)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
    s->tris = a;
    memcpy(a + 3 * s->tri_count++, v, sizeof v);
    return FTM_OK;
}

/* Appends a tetrahedron or hexahedron (corners on the current line) with its
 * label, line and tag; its shape must be a positive volume, as Gmsh orders
 * the corners. */
static int add_volume_element(msh_state *s, int64_t type, int64_t tag, int32_t label,
                              ftm_error *err)
{
    const bool hex = type == ELEM_HEXAHEDRON;
    const int n = hex ? 8 : 4;
    elem_list *e = hex ? &s->hexes : &s->tets;
    int32_t v[8];
    int rc = element_corners(s, n, v, err);
    if (rc < 0)
        return rc;
    ftm_load_shape shape = hex ? ftm_load_hex_shape(s->pos, v) : ftm_load_tet_shape(s->pos, v);
    if (shape == FTM_LOAD_SHAPE_INVERTED)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: element %lld (%s) is inverted: negative volume, its nodes in "
                             "mirrored order (Gmsh's order has a positive volume)",
                             s->path, s->text.line, (long long)tag, element_name(type));
    if (shape == FTM_LOAD_SHAPE_DEGENERATE)
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: element %lld (%s) is degenerate: %s",
                             s->path, s->text.line, (long long)tag, element_name(type),
                             hex ? "flat or twisted (its volume is not positive at every corner)"
                                 : "flat (its corners are nearly in one plane)");
    if (s->tets.count + s->hexes.count >= INT32_MAX / 24)
        return ftm_error_set(err, FTM_ERANGE, "%s:%d: too many elements", s->path, s->text.line);
    size_t i = e->count;
    int32_t *a = ftm_load_grow(e->v, &e->v_cap, (size_t)n * (i + 1), sizeof *a);
    if (a)
        e->v = a;
    int32_t *g = ftm_load_grow(e->label, &e->label_cap, i + 1, sizeof *g);
    if (g)
        e->label = g;
    int32_t *l = ftm_load_grow(e->line, &e->line_cap, i + 1, sizeof *l);
    if (l)
        e->line = l;
    int64_t *t = ftm_load_grow(e->tag, &e->tag_cap, i + 1, sizeof *t);
    if (t)
        e->tag = t;
    if (!a || !g || !l || !t)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
    memcpy(a + (size_t)n * i, v, (size_t)n * sizeof *v);
    g[i] = label;
    l[i] = s->text.line;
    t[i] = tag;
    e->labelled += label > 0;
    e->count++;
    return FTM_OK;
}

static int compare_volumes(const void *pa, const void *pb)
{
    const volume_entity *a = pa, *b = pb;
    if (a->tag != b->tag)
        return (a->tag > b->tag) - (a->tag < b->tag);
    return (a->line > b->line) - (a->line < b->line);
}

static int compare_volume_tags(const void *pa, const void *pb)
{
    const volume_entity *a = pa, *b = pb;
    return (a->tag > b->tag) - (a->tag < b->tag);
}

/* $Entities: points, curves and surfaces are counted over; each volume line
 * "tag minX minY minZ maxX maxY maxZ numPhysicalTags physicalTag ...
 * numBoundingSurfaces surfaceTag ..." gives its physical groups. */
static int parse_entities(msh_state *s, ftm_error *err)
{
    int rc = data_line(s, "Entities", "the $Entities header", err);
    if (rc < 0 || (rc = expect_tokens(s, 4, "$Entities header", err)) < 0)
        return rc;
    int64_t count[4];
    static const char *const what[4] = {"point count", "curve count", "surface count",
                                        "volume count"};
    for (int i = 0; i < 4; i++)
        if ((rc = int_token(s, (size_t)i, 0, INT64_MAX, what[i], &count[i], err)) < 0)
            return rc;
    for (int dim = 0; dim < 4; dim++) {
        for (int64_t k = 0; k < count[dim]; k++) {
            if ((rc = data_line(s, "Entities", "an entity line", err)) < 0)
                return rc;
            if (dim < 3)
                continue; /* their physical groups label no volume element */
            int64_t tag, nphys, x;
            if (s->ntok < 8)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: volume entity line needs at least 8 values, found %zu",
                                     s->path, s->text.line, s->ntok);
            if ((rc = int_token(s, 0, INT32_MIN, INT32_MAX, "volume entity tag", &tag, err)) < 0)
                return rc;
            for (size_t c = 1; c < 7; c++) {
                double b;
                const char *why = ftm_text_read_double(s->tok[c], s->toklen[c], &b);
                if (why)
                    return ftm_error_set(err, FTM_EPARSE, "%s:%d: bad bounding box value '%.*s': %s",
                                         s->path, s->text.line, QUOTE(s->toklen[c]), s->tok[c],
                                         why);
            }
            if ((rc = int_token(s, 7, 0, MAX_TOKENS, "physical tag count", &nphys, err)) < 0)
                return rc;
            if (s->ntok < 9 + (size_t)nphys) /* the tags, then the bounding surface count */
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: volume entity %lld announces %lld physical tags, the "
                                     "line holds %zu values",
                                     s->path, s->text.line, (long long)tag, (long long)nphys,
                                     s->ntok);
            volume_entity ve = {.tag = tag, .line = s->text.line, .physical_count = (int32_t)nphys};
            for (int64_t j = 0; j < nphys; j++) {
                if ((rc = int_token(s, 8 + (size_t)j, INT32_MIN, INT32_MAX, "physical tag", &x,
                                    err)) < 0)
                    return rc;
                if (j < 2)
                    ve.physical[j] = x;
            }
            int64_t nbound;
            if ((rc = int_token(s, 8 + (size_t)nphys, 0, INT64_MAX, "bounding surface count",
                                &nbound, err)) < 0)
                return rc;
            /* a long line keeps only its first MAX_TOKENS tokens: count it then */
            if (!s->too_long && (int64_t)s->ntok != 9 + nphys + nbound)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: volume entity %lld: %lld physical tags and %lld "
                                     "bounding surfaces need %lld values, the line holds %zu",
                                     s->path, s->text.line, (long long)tag, (long long)nphys,
                                     (long long)nbound, (long long)(9 + nphys + nbound), s->ntok);
            volume_entity *v =
                ftm_load_grow(s->volumes, &s->volume_cap, s->volume_count + 1, sizeof *v);
            if (!v)
                return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
            s->volumes = v;
            v[s->volume_count++] = ve;
        }
    }
    if ((rc = end_line(s, "Entities", err)) < 0)
        return rc;
    if (s->volume_count > 0)
        qsort(s->volumes, s->volume_count, sizeof *s->volumes, compare_volumes);
    for (size_t i = 1; i < s->volume_count; i++)
        if (s->volumes[i].tag == s->volumes[i - 1].tag)
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: volume entity %lld repeated (first on "
                                                  "line %d)",
                                 s->path, s->volumes[i].line, (long long)s->volumes[i].tag,
                                 s->volumes[i - 1].line);
    return FTM_OK;
}

/* The label of the volume elements of entity `entity` (block header on the
 * current line): its one physical group, or 0 when it has none. */
static int entity_label(msh_state *s, int64_t entity, int32_t *label, ftm_error *err)
{
    *label = 0;
    if (!s->have_entities)
        return FTM_OK; /* no physical groups in the file: unlabelled */
    const volume_entity key = {.tag = entity};
    const volume_entity *v =
        s->volume_count ? bsearch(&key, s->volumes, s->volume_count, sizeof *s->volumes,
                                  compare_volume_tags)
                        : NULL;
    if (!v)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: elements of volume entity %lld, which $Entities does not list",
                             s->path, s->text.line, (long long)entity);
    if (v->physical_count > 1)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: volume entity %lld is in %d physical groups (%lld, %lld%s; "
                             "line %d): an element's label must be one",
                             s->path, s->text.line, (long long)entity, (int)v->physical_count,
                             (long long)v->physical[0], (long long)v->physical[1],
                             v->physical_count > 2 ? ", ..." : "", v->line);
    if (v->physical_count == 1) {
        if (v->physical[0] <= 0)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: volume entity %lld has physical tag %lld (line %d): a "
                                 "label must be >= 1",
                                 s->path, s->text.line, (long long)entity,
                                 (long long)v->physical[0], v->line);
        *label = (int32_t)v->physical[0];
    }
    return FTM_OK;
}

static int parse_elements(msh_state *s, ftm_error *err)
{
    int rc = data_line(s, "Elements", "the $Elements header", err);
    if (rc < 0 || (rc = expect_tokens(s, 4, "$Elements header", err)) < 0)
        return rc;
    int64_t nblocks, nelems, minmax, seen = 0;
    if ((rc = int_token(s, 0, 0, INT64_MAX, "entity block count", &nblocks, err)) < 0 ||
        (rc = int_token(s, 1, 0, INT64_MAX, "element count", &nelems, err)) < 0 ||
        (rc = int_token(s, 2, 0, INT64_MAX, "minimum element tag", &minmax, err)) < 0 ||
        (rc = int_token(s, 3, 0, INT64_MAX, "maximum element tag", &minmax, err)) < 0)
        return rc;
    for (int64_t b = 0; b < nblocks; b++) {
        if ((rc = data_line(s, "Elements", "an element entity block header", err)) < 0 ||
            (rc = expect_tokens(s, 4, "element entity block header", err)) < 0)
            return rc;
        int64_t dim, entity, type, count;
        if ((rc = int_token(s, 0, 0, 3, "entity dimension", &dim, err)) < 0 ||
            (rc = int_token(s, 1, INT32_MIN, INT32_MAX, "entity tag", &entity, err)) < 0 ||
            (rc = int_token(s, 2, INT32_MIN, INT32_MAX, "element type", &type, err)) < 0 ||
            (rc = int_token(s, 3, 0, INT64_MAX, "block element count", &count, err)) < 0)
            return rc;
        if (count > nelems - seen)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: block of %lld elements would exceed the %lld elements "
                                 "announced in the $Elements header",
                                 s->path, s->text.line, (long long)count, (long long)nelems);
        int nodes = nodes_per_element(type);
        if (nodes == 0)
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: unknown element type %lld", s->path,
                                 s->text.line, (long long)type);
        const bool volume = type == ELEM_TETRAHEDRON || type == ELEM_HEXAHEDRON;
        if (type == ELEM_PRISM || type == ELEM_PYRAMID)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: element type %lld (%s) not supported: FTM's volume "
                                 "elements are 4-node tetrahedra and 8-node hexahedra (the "
                                 "element forces and the FEM reference have no %s); mesh with "
                                 "tetrahedra only, or with hexahedra only",
                                 s->path, s->text.line, (long long)type, element_name(type),
                                 type == ELEM_PRISM ? "prisms" : "pyramids");
        if (!volume && type != ELEM_TRIANGLE && type != ELEM_LINE && type != ELEM_QUAD &&
            type != ELEM_POINT)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: element type %lld (%s) not supported: a second- or "
                                 "higher-order element; FTM's elements are linear (springs join "
                                 "corners, the element forces are those of 4-node tetrahedra "
                                 "and 8-node hexahedra): export with element order 1 (Gmsh: "
                                 "Mesh.ElementOrder = 1)",
                                 s->path, s->text.line, (long long)type, element_name(type));
        if (volume && dim != 3)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: %s elements (type %lld) in an entity of dimension %lld "
                                 "(volume elements belong to volumes, dimension 3)",
                                 s->path, s->text.line, element_name(type), (long long)type,
                                 (long long)dim);
        int32_t label = 0;
        if (volume && (rc = entity_label(s, entity, &label, err)) < 0)
            return rc;
        for (int64_t i = 0; i < count; i++) {
            if ((rc = data_line(s, "Elements", "an element line", err)) < 0)
                return rc;
            if (s->ntok != (size_t)nodes + 1 || s->too_long)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: element of type %lld needs a tag and %d node tags, "
                                     "found %s%zu values",
                                     s->path, s->text.line, (long long)type, nodes,
                                     s->too_long ? "over " : "", s->ntok);
            int64_t tag;
            if ((rc = int_token(s, 0, 1, INT64_MAX, "element tag", &tag, err)) < 0)
                return rc;
            if (volume) {
                rc = add_volume_element(s, type, tag, label, err);
            } else if (type == ELEM_TRIANGLE) {
                rc = add_triangle(s, err);
            } else {
                /* Skipped (points, lines, quadrangles: boundaries and groups of
                 * lower dimension), but its tags must still be numbers. */
                int64_t t;
                for (size_t j = 1; j < s->ntok && rc >= 0; j++)
                    rc = int_token(s, j, 1, INT64_MAX, "node tag", &t, err);
            }
            if (rc < 0)
                return rc;
        }
        seen += count;
    }
    if ((rc = end_line(s, "Elements", err)) < 0)
        return rc;
    if (seen != nelems)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: $Elements header announces %lld elements, blocks hold %lld",
                             s->path, s->text.line, (long long)nelems, (long long)seen);
    for (int k = 0; k < 2; k++) {
        const elem_list *e = k ? &s->hexes : &s->tets;
        const char *kind = k ? "hexahedron" : "tetrahedron";
        size_t orig = 0, again = 0;
        rc = ftm_load_find_repeated(e->v, k ? 8 : 4, e->count, &orig, &again);
        if (rc == FTM_ENOMEM)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
        if (rc > 0)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: element %lld has the same %s nodes as element %lld "
                                 "(line %d), a repeated %s",
                                 s->path, e->line[again], (long long)e->tag[again],
                                 k ? "eight" : "four", (long long)e->tag[orig], e->line[orig],
                                 kind);
    }
    if (s->tets.count > 0 && s->hexes.count > 0)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: element %lld is a hexahedron, element %lld (line %d) a "
                             "tetrahedron: one kind of volume element per mesh (they would meet "
                             "without conforming faces; pyramids, which join them, are not "
                             "supported)",
                             s->path, s->hexes.line[0], (long long)s->hexes.tag[0],
                             (long long)s->tets.tag[0], s->tets.line[0]);
    /* labels on every volume element or none: one without has no material */
    const elem_list *e = s->hexes.count ? &s->hexes : &s->tets;
    if (e->labelled > 0 && e->labelled < e->count)
        for (size_t i = 0; i < e->count; i++)
            if (e->label[i] == 0)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: element %lld belongs to no physical group while %zu "
                                     "others have one: label every volume element or none",
                                     s->path, e->line[i], (long long)e->tag[i], e->labelled);
    return FTM_OK;
}

/* $PhysicalNames: "dim tag \"name\"" lines. A volume group's (dim 3)
 * tag is its elements' label, and its name what the client's legend shows:
 * kept (cut to FTM_MESH_LABEL_NAME_MAX bytes, any byte that is not
 * printable ASCII shown as '?'). Other dimensions' names are checked and
 * dropped. */
static int parse_physical_names(msh_state *s, ftm_error *err)
{
    int rc = data_line(s, "PhysicalNames", "the number of names", err);
    int64_t count = 0;
    if (rc < 0 || (rc = expect_tokens(s, 1, "$PhysicalNames", err)) < 0 ||
        (rc = int_token(s, 0, 0, FTM_MESH_MAX_LABEL_NAMES, "number of names", &count, err)) < 0)
        return rc;
    for (int64_t i = 0; i < count; i++) {
        if ((rc = data_line(s, "PhysicalNames", "dimension, tag and \"name\"", err)) < 0)
            return rc;
        int64_t dim, tag;
        if (s->ntok < 3 || s->too_long)
            return ftm_error_set(err, FTM_EPARSE,
                                 "%s:%d: a physical name needs dimension, tag and \"name\"",
                                 s->path, s->text.line);
        if ((rc = int_token(s, 0, 0, 3, "physical dimension", &dim, err)) < 0 ||
            (rc = int_token(s, 1, 1, INT32_MAX, "physical tag", &tag, err)) < 0)
            return rc;
        /* the name runs from the third token to the line's last, quoted */
        const char *a = s->tok[2], *b = s->tok[s->ntok - 1] + s->toklen[s->ntok - 1];
        if (b - a < 2 || a[0] != '"' || b[-1] != '"')
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: physical name not in double quotes",
                                 s->path, s->text.line);
        if (dim != 3 || b - a == 2)
            continue;
        physical_name *g = ftm_load_grow(s->names, &s->name_cap, s->name_count + 1, sizeof *g);
        if (!g)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", s->path);
        s->names = g;
        physical_name *e = &g[s->name_count++];
        e->label = (int32_t)tag;
        size_t n = (size_t)(b - a - 2) < FTM_MESH_LABEL_NAME_MAX ? (size_t)(b - a - 2)
                                                               : FTM_MESH_LABEL_NAME_MAX;
        for (size_t k = 0; k < n; k++)
            e->name[k] = a[1 + k] >= 0x20 && a[1 + k] <= 0x7e ? a[1 + k] : '?';
        e->name[n] = '\0';
    }
    return end_line(s, "PhysicalNames", err);
}

/* Skips an unknown section ($NodeData, ...). */
static int skip_section(msh_state *s, ftm_error *err)
{
    const char *name = s->tok[0] + 1;
    size_t name_len = s->toklen[0] - 1;
    int32_t start = s->text.line;
    while (next_line(s)) {
        if (s->toklen[0] == name_len + 4 && memcmp(s->tok[0], "$End", 4) == 0 &&
            memcmp(s->tok[0] + 4, name, name_len) == 0)
            return FTM_OK;
    }
    return ftm_error_set(err, FTM_EPARSE, "%s:%d: section $%.*s is not closed by $End%.*s",
                         s->path, start, QUOTE(name_len), name, QUOTE(name_len), name);
}

static int parse_file(msh_state *s, ftm_error *err)
{
    if (!next_line(s))
        return ftm_error_set(err, FTM_EPARSE, "%s: file is empty", s->path);
    if (!line_is(s, "$MeshFormat"))
        return ftm_error_set(err, FTM_EPARSE,
                             "%s:%d: not a Gmsh MSH file (expected $MeshFormat, found '%.*s')",
                             s->path, s->text.line, QUOTE(s->toklen[0]), s->tok[0]);
    int rc = parse_format(s, err);
    bool have_nodes = false, have_elements = false, have_names = false;
    while (rc >= 0 && next_line(s)) {
        if (s->tok[0][0] != '$')
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: expected a section ($Name), found '%.*s'",
                                 s->path, s->text.line, QUOTE(s->toklen[0]), s->tok[0]);
        if (line_is(s, "$Nodes")) {
            if (have_nodes)
                return ftm_error_set(err, FTM_EPARSE, "%s:%d: second $Nodes section", s->path,
                                     s->text.line);
            have_nodes = true;
            rc = parse_nodes(s, err);
        } else if (line_is(s, "$Elements")) {
            if (!have_nodes)
                return ftm_error_set(err, FTM_EPARSE, "%s:%d: $Elements before $Nodes", s->path,
                                     s->text.line);
            if (have_elements)
                return ftm_error_set(err, FTM_EPARSE, "%s:%d: second $Elements section", s->path,
                                     s->text.line);
            have_elements = true;
            rc = parse_elements(s, err);
        } else if (line_is(s, "$Entities")) {
            if (s->have_entities)
                return ftm_error_set(err, FTM_EPARSE, "%s:%d: second $Entities section", s->path,
                                     s->text.line);
            if (have_elements)
                return ftm_error_set(err, FTM_EPARSE,
                                     "%s:%d: $Entities after $Elements (Gmsh writes it first)",
                                     s->path, s->text.line);
            s->have_entities = true;
            rc = parse_entities(s, err);
        } else if (line_is(s, "$PhysicalNames")) {
            if (have_names)
                return ftm_error_set(err, FTM_EPARSE, "%s:%d: second $PhysicalNames section",
                                     s->path, s->text.line);
            have_names = true;
            rc = parse_physical_names(s, err);
        } else if (line_is(s, "$MeshFormat")) {
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: second $MeshFormat section", s->path,
                                 s->text.line);
        } else if (s->ntok != 1 || s->toklen[0] < 2 ||
                   (s->toklen[0] >= 4 && memcmp(s->tok[0], "$End", 4) == 0)) {
            return ftm_error_set(err, FTM_EPARSE, "%s:%d: unexpected '%.*s'", s->path,
                                 s->text.line, QUOTE(s->toklen[0]), s->tok[0]);
        } else {
            rc = skip_section(s, err);
        }
    }
    if (rc < 0)
        return rc;
    if (!have_nodes)
        return ftm_error_set(err, FTM_EPARSE, "%s: no $Nodes section", s->path);
    if (!have_elements)
        return ftm_error_set(err, FTM_EPARSE, "%s: no $Elements section", s->path);
    if (s->tets.count == 0 && s->hexes.count == 0 && s->tri_count == 0)
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: no 4-node tetrahedra (type 4), 8-node hexahedra (type 5) or "
                             "3-node triangles (type 2)",
                             s->path);
    return FTM_OK;
}

int ftm_load_gmsh(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                  ftm_error *err)
{
    int rc = ftm_load_check_args(builder, path, material, err);
    if (rc < 0)
        return rc;
    char *data;
    size_t length;
    ftm_error read_err = {0};
    rc = ftm_load_read_file(path, &data, &length, &read_err);
    if (rc == FTM_EPARSE) /* the reader refuses NUL bytes: a binary MSH file */
        return ftm_error_set(err, rc, "%s: binary data in file (binary MSH not supported, "
                                      "save as ASCII MSH 4.1)", path);
    if (rc < 0)
        return ftm_error_set(err, rc, "%s", read_err.message);

    msh_state *s = calloc(1, sizeof *s);
    if (!s) {
        free(data);
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    }
    s->path = path;
    ftm_text_init(&s->text, path, data, length);
    rc = parse_file(s, err);
    if (rc >= 0)
        rc = ftm_load_commit(
            builder, path, material,
            &(ftm_load_data){.pos = s->pos,
                             .node_count = s->node_count,
                             .tris = s->tris,
                             .tri_count = s->tri_count,
                             .tri_edges = s->tets.count == 0 && s->hexes.count == 0,
                             .tets = s->tets.v,
                             .tet_labels = s->tets.labelled ? s->tets.label : NULL,
                             .tet_count = s->tets.count,
                             .hexes = s->hexes.v,
                             .hex_labels = s->hexes.labelled ? s->hexes.label : NULL,
                             .hex_count = s->hexes.count},
            err);
    /* the names of the labels the elements carry */
    for (size_t i = 0; rc >= 0 && i < s->name_count; i++)
        if (ftm_mesh_builder_set_label_name(builder, s->names[i].label, s->names[i].name) ==
            FTM_ENOMEM)
            rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    free(s->names);
    for (int k = 0; k < 2; k++) {
        elem_list *e = k ? &s->hexes : &s->tets;
        free(e->v);
        free(e->label);
        free(e->line);
        free(e->tag);
    }
    free(s->volumes);
    free(s->tris);
    free(s->tags);
    free(s->node_line);
    free(s->pos);
    free(s);
    free(data);
    return rc;
}
