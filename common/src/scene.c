/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Scene files: INI-like text ("[section]", "key = value", "#" comments)
 * describing a mesh, its material, simulation parameters and scripted loads.
 * The format is documented in docs/scene-format.md.
 *
 * Parsing runs in two passes: the text is read into a plain specification
 * (every key remembers its line), then the mesh is built and everything that
 * depends on it (node indices, fixed nodes, load targets) is checked, so an
 * error always names the line of the key that caused it. */
#include "ftm/scene.h"

#include "ftm/generate.h"
#include "ftm/load.h"

#include "error.h"
#include "scene_builtin.h"
#include "ftm/internal/text.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SCENE_MAX_BYTES ((size_t)1 << 20)   /* scene files are small; refuse anything big */
#define SCENE_NAME_MAX 128                  /* bytes, including the terminator */
#define SCENE_MAX_LOADS 100000
#define SCENE_MAX_LATTICE_NODES ((int64_t)1 << 24)
#define SCENE_MAX_LATTICE_AXIS ((int64_t)1 << 20)
#define SCENE_MAX_DEPTH 1000000
#define SCENE_MAX_SUBSTEPS 65536
#define SCENE_DEFAULT_STEPS 1000
#define SCENE_DEFAULT_STENCIL 18
#define SCENE_MAX_PHANTOM_VOXELS 256
#define SCENE_MAX_VOLUME_AXIS 4096
#define ALL_FACES                                                                                  \
    (FTM_FACE_XMIN | FTM_FACE_XMAX | FTM_FACE_YMIN | FTM_FACE_YMAX | FTM_FACE_ZMIN | FTM_FACE_ZMAX)

struct ftm_scene {
    char name[SCENE_NAME_MAX];
    ftm_mesh *mesh;
    ftm_sim_def sim;
    int32_t steps;
    ftm_scene_load *loads;
    int32_t load_count;
    ftm_material_def material;     /* [material], as the mesh was built with */
    bool has_fem;                  /* a [fem] section was given */
    double young, poisson, density; /* [fem]; density 0 = not given */
    ftm_label_material *label_materials; /* [fem LABEL], in the file's order */
    int32_t label_material_count;
    char (*label_names)[FTM_SCENE_LABEL_NAME_MAX + 1]; /* their `name`s ("": none) */
    ftm_volume *volume;            /* [volume], with generator = volume */
    ftm_ffd *ffd;
    ftm_label_map *volume_labels;  /* [volume] labels: on the image's voxels; NULL: none */
    ftm_scene_tool tool;           /* [tool]; zeros = not given */
};

/* ---------------------------------------------------------------- keys */

typedef enum section {
    SEC_NONE,
    SEC_SCENE,
    SEC_MESH,
    SEC_MATERIAL,
    SEC_SIM,
    SEC_LOAD,
    SEC_FEM,
    SEC_VOLUME,
    SEC_FEM_LABEL, /* [fem LABEL]: the [fem] of one mesh label's elements */
    SEC_TOOL,
    SEC_MATERIAL_LABEL, /* [material LABEL]: the link stiffness of one label's elements */
    SEC_COUNT
} section;

static const char *const section_names[SEC_COUNT] = {
    "", "scene", "mesh", "material", "sim", "load", "fem", "volume", "fem LABEL", "tool",
    "material LABEL"};

typedef enum key {
    K_NAME,
    K_DESCRIPTION,
    K_GENERATOR,
    K_FILE,
    K_NX,
    K_NY,
    K_NZ,
    K_SPACING,
    K_STENCIL,
    K_CLASS_SCALE,
    K_FIXED_FACES,
    K_FIXED_NODES,
    K_FIXED_BOX,
    K_FIXED_LABEL,
    K_SLIDE_NODES,
    K_SLIDE_BOX,
    K_GROUND_SPRINGS,
    K_SLIDE_LABEL,
    K_GROUND_LABEL,
    K_MASS,
    K_DAMPING,
    K_STIFFNESS,
    K_AXIS_SCALE,
    K_TIME_STEP,
    K_DEPTH,
    K_ORDER,
    K_STEPS,
    K_SLEEP_TOLERANCE,
    K_REGION_SLEEP_STEPS,
    K_GUARD,
    K_GUARD_MOTION,
    K_MAX_SUBSTEPS,
    K_FORCES,
    K_FAR_FIELD,
    K_YOUNG,
    K_POISSON,
    K_DENSITY,
    K_MASS_SCALING,
    K_VOLUME_FILE,
    K_PHANTOM,
    K_VOXELS,
    K_SIZE,
    K_NODES,
    K_VOLUME_STENCIL,
    K_HARD,
    K_AIR,
    K_FIT_SURFACE,
    K_FIX,
    K_WINDOW,
    K_SCALE,
    K_ORIGIN,
    K_AXES,
    K_VOLUME_LABELS,
    K_TIP_RADIUS,
    K_SHAFT_RADIUS,
    K_SHAFT_LENGTH,
    K_NODE, /* first [load] key: load keys are recorded per load */
    K_KIND,
    K_VALUE,
    K_GROUP,
    K_START,
    K_END,
    K_RELEASE,
    K_RAMP,
    K_COUNT
} key;

#define LOAD_KEY_COUNT (K_COUNT - K_NODE)

static const struct {
    section sec;
    const char *name;
    bool repeatable; /* may be given several times; values accumulate */
} key_table[K_COUNT] = {
    [K_NAME] = {SEC_SCENE, "name", false},
    [K_DESCRIPTION] = {SEC_SCENE, "description", false},
    [K_GENERATOR] = {SEC_MESH, "generator", false},
    [K_FILE] = {SEC_MESH, "file", false},
    [K_NX] = {SEC_MESH, "nx", false},
    [K_NY] = {SEC_MESH, "ny", false},
    [K_NZ] = {SEC_MESH, "nz", false},
    [K_SPACING] = {SEC_MESH, "spacing", false},
    [K_STENCIL] = {SEC_MESH, "stencil", false},
    [K_CLASS_SCALE] = {SEC_MESH, "class_scale", false},
    [K_FIXED_FACES] = {SEC_MESH, "fixed_faces", false},
    [K_FIXED_NODES] = {SEC_MESH, "fixed_nodes", true},
    [K_FIXED_LABEL] = {SEC_MESH, "fixed_label", true},
    [K_FIXED_BOX] = {SEC_MESH, "fixed_box", true},
    [K_SLIDE_NODES] = {SEC_MESH, "slide_nodes", true},
    [K_SLIDE_BOX] = {SEC_MESH, "slide_box", true},
    [K_GROUND_SPRINGS] = {SEC_MESH, "ground_springs", true},
    [K_SLIDE_LABEL] = {SEC_MESH, "slide_label", true},
    [K_GROUND_LABEL] = {SEC_MESH, "ground_label", true},
    [K_MASS] = {SEC_MATERIAL, "mass", false},
    [K_DAMPING] = {SEC_MATERIAL, "damping", false},
    [K_STIFFNESS] = {SEC_MATERIAL, "stiffness", false},
    [K_AXIS_SCALE] = {SEC_MATERIAL, "axis_scale", false},
    [K_TIME_STEP] = {SEC_SIM, "time_step", false},
    [K_DEPTH] = {SEC_SIM, "depth", false},
    [K_ORDER] = {SEC_SIM, "order", false},
    [K_STEPS] = {SEC_SIM, "steps", false},
    [K_SLEEP_TOLERANCE] = {SEC_SIM, "sleep_tolerance", false},
    [K_REGION_SLEEP_STEPS] = {SEC_SIM, "region_sleep_steps", false},
    [K_GUARD] = {SEC_SIM, "guard", false},
    [K_GUARD_MOTION] = {SEC_SIM, "guard_motion", false},
    [K_MAX_SUBSTEPS] = {SEC_SIM, "max_substeps", false},
    [K_FORCES] = {SEC_SIM, "forces", false},
    [K_FAR_FIELD] = {SEC_SIM, "far_field", false},
    [K_YOUNG] = {SEC_FEM, "young", false},
    [K_POISSON] = {SEC_FEM, "poisson", false},
    [K_DENSITY] = {SEC_FEM, "density", false},
    [K_MASS_SCALING] = {SEC_FEM, "mass_scaling", false},
    [K_VOLUME_FILE] = {SEC_VOLUME, "file", false},
    [K_PHANTOM] = {SEC_VOLUME, "phantom", false},
    [K_VOXELS] = {SEC_VOLUME, "voxels", false},
    [K_SIZE] = {SEC_VOLUME, "size", false},
    [K_NODES] = {SEC_VOLUME, "nodes", false},
    [K_VOLUME_STENCIL] = {SEC_VOLUME, "stencil", false},
    [K_HARD] = {SEC_VOLUME, "hard", false},
    [K_AIR] = {SEC_VOLUME, "air", false},
    [K_FIT_SURFACE] = {SEC_VOLUME, "fit_surface", false},
    [K_TIP_RADIUS] = {SEC_TOOL, "tip_radius", false},
    [K_SHAFT_RADIUS] = {SEC_TOOL, "shaft_radius", false},
    [K_SHAFT_LENGTH] = {SEC_TOOL, "shaft_length", false},
    [K_FIX] = {SEC_VOLUME, "fix", false},
    [K_WINDOW] = {SEC_VOLUME, "window", false},
    [K_SCALE] = {SEC_VOLUME, "scale", false},
    [K_ORIGIN] = {SEC_VOLUME, "origin", false},
    [K_AXES] = {SEC_VOLUME, "axes", false},
    [K_VOLUME_LABELS] = {SEC_VOLUME, "labels", false},
    [K_NODE] = {SEC_LOAD, "node", false},
    [K_KIND] = {SEC_LOAD, "kind", false},
    [K_VALUE] = {SEC_LOAD, "value", false},
    [K_GROUP] = {SEC_LOAD, "group", false},
    [K_START] = {SEC_LOAD, "start", false},
    [K_END] = {SEC_LOAD, "end", false},
    [K_RELEASE] = {SEC_LOAD, "release", false},
    [K_RAMP] = {SEC_LOAD, "ramp", false},
};

/* ------------------------------------------------------- specification */

typedef enum generator { GEN_NONE, GEN_LATTICE2D, GEN_LATTICE3D, GEN_VOLUME } generator;

typedef struct fixed_index {
    int64_t input;
    int32_t line;
} fixed_index;

typedef struct fixed_box {
    double lo[3], hi[3];
} fixed_box;

/* slide_nodes, slide_box (a normal) and ground_springs (a stiffness) */
typedef enum bc_kind { BC_SLIDE, BC_SLIDE_BOX, BC_GROUND, BC_SLIDE_LABEL, BC_GROUND_LABEL } bc_kind;
typedef struct bc_spec {
    bc_kind kind;
    int32_t line;
    double normal[3]; /* slides */
    double k;         /* ground springs, N/m */
    int64_t input;    /* slide_nodes, ground_springs: one node each; *_label: the label */
    fixed_box box;    /* slide_box */
} bc_spec;

typedef struct load_spec {
    int32_t line;                     /* line of the [load] header */
    int32_t key_line[LOAD_KEY_COUNT]; /* where each key was set, 0 = not set */
    bool nearest;                     /* node given as "nearest x y z" */
    int64_t input;                    /* input index when !nearest */
    ftm_vec3 point;                   /* when nearest */
    ftm_scene_load load;              /* contact.node is filled in once the mesh exists */
} load_spec;

/* A [fem LABEL] section: where it and its keys are. */
typedef struct label_fem {
    int32_t line, young_line, poisson_line, density_line, name_line;
    ftm_label_material mat;
    char name[FTM_SCENE_LABEL_NAME_MAX + 1]; /* `name`: what the client's legend shows */
} label_fem;

/* A [material LABEL] section: the spring stiffness of one label. */
typedef struct label_spring {
    int32_t line, stiffness_line;
    int32_t label;
    double stiffness;
} label_spring;

typedef struct spec {
    int32_t key_line[K_COUNT]; /* line where each (non-load) key was last set, 0 = unset */
    int32_t section_line[SEC_COUNT];
    char name[SCENE_NAME_MAX];
    /* [mesh] */
    generator gen;
    char *file;
    int64_t nx, ny, nz;
    double spacing[3];
    int spacing_count;
    int64_t stencil;
    double class_scale[3];
    uint32_t fixed_faces;
    fixed_index *fixed_nodes;
    size_t fixed_node_count, fixed_node_cap;
    fixed_box *fixed_boxes;
    size_t fixed_box_count, fixed_box_cap;
    fixed_index *fixed_labels; /* fixed_label: input = the label */
    size_t fixed_label_count, fixed_label_cap;
    bc_spec *bcs; /* slide_nodes, slide_box, ground_springs in the file's order */
    size_t bc_count, bc_cap;
    /* [material] */
    ftm_material_def material;
    /* [sim] */
    ftm_sim_def sim;
    int64_t steps;
    /* [fem] */
    double young, poisson, density;
    /* [tool] */
    ftm_scene_tool tool;
    /* [fem LABEL] */
    label_fem *label_fems;
    size_t label_fem_count, label_fem_cap;
    /* [material LABEL] */
    label_spring *label_springs;
    size_t label_spring_count, label_spring_cap;
    /* [volume] */
    char *volume_file;
    char *volume_labels_file;      /* [volume] labels */
    ftm_volume_phantom_def phantom;
    ftm_volume_load_def volume_load;
    ftm_volume_lattice_def volume_lattice; /* its material is [material]'s */
    /* [load] */
    load_spec *loads;
    size_t load_count, load_cap;
} spec;

typedef struct parser {
    const char *name;     /* file name for messages */
    const char *base_dir; /* directory that mesh file paths are relative to; NULL = cwd */
    int32_t line;         /* current line */
    int32_t last_line;    /* number of lines in the text */
    ftm_error *err;
    spec s;
} parser;

typedef struct token {
    const char *s;
    size_t n;
} token;

#define MAX_TOKENS 8

/* ------------------------------------------------------------- errors */

#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
static int
fail_at(const parser *p, int32_t line, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int rc = ftm_text_verror(p->err, code, p->name, line, fmt, ap);
    va_end(ap);
    return rc;
}

/* Prints at most this many characters of an offending token. */
static int shown(size_t n)
{
    return n > 40 ? 40 : (int)n;
}

/* ------------------------------------------------------------- values */

static bool token_is(token t, const char *word)
{
    size_t n = strlen(word);
    return t.n == n && memcmp(t.s, word, n) == 0;
}

/* Splits value into whitespace-separated tokens; the count must lie in [min, max]. */
static int split(const parser *p, const char *keyname, const char *v, size_t vlen, token *out,
                 int min, int max, int *count)
{
    const char *cur = v, *end = v + vlen;
    int n = 0;
    token t;
    while (ftm_text_token(&cur, end, &t.s, &t.n)) {
        if (n == max) {
            if (min == max)
                return fail_at(p, p->line, FTM_EPARSE, "%s: expected %d value%s, got more", keyname,
                               max, max == 1 ? "" : "s");
            return fail_at(p, p->line, FTM_EPARSE, "%s: expected at most %d values, got more",
                           keyname, max);
        }
        out[n++] = t;
    }
    if (n < min) {
        if (min == max)
            return fail_at(p, p->line, FTM_EPARSE, "%s: expected %d value%s, got %d", keyname, min,
                           min == 1 ? "" : "s", n);
        return fail_at(p, p->line, FTM_EPARSE, "%s: expected at least %d values, got %d", keyname,
                       min, n);
    }
    *count = n;
    return FTM_OK;
}

static int number(const parser *p, const char *keyname, token t, double *out)
{
    const char *why = ftm_text_read_double(t.s, t.n, out);
    if (why)
        return fail_at(p, p->line, FTM_EPARSE, "%s: expected a finite number, got '%.*s': %s",
                       keyname, shown(t.n), t.s, why);
    return FTM_OK;
}

static int integer(const parser *p, const char *keyname, token t, int64_t lo, int64_t hi,
                   int64_t *out)
{
    int64_t v = 0;
    const char *why = ftm_text_read_int(t.s, t.n, &v);
    if (why)
        return fail_at(p, p->line, FTM_EPARSE, "%s: expected an integer, got '%.*s': %s", keyname,
                       shown(t.n), t.s, why);
    if (v < lo || v > hi)
        return fail_at(p, p->line, FTM_EINVAL, "%s must be between %lld and %lld, got %lld",
                       keyname, (long long)lo, (long long)hi, (long long)v);
    *out = v;
    return FTM_OK;
}

/* One number in (0, inf) if positive, else in [0, inf). */
static int scalar(const parser *p, const char *keyname, const char *v, size_t vlen, bool positive,
                  double *out)
{
    token t[1];
    int n = 0;
    double x = 0;
    int rc = split(p, keyname, v, vlen, t, 1, 1, &n);
    if (rc == FTM_OK)
        rc = number(p, keyname, t[0], &x);
    if (rc != FTM_OK)
        return rc;
    if (positive ? !(x > 0) : !(x >= 0))
        return fail_at(p, p->line, FTM_EINVAL, "%s must be %s, got %.*s", keyname,
                       positive ? "> 0" : ">= 0", shown(t[0].n), t[0].s);
    *out = x;
    return FTM_OK;
}

static int one_integer(const parser *p, const char *keyname, const char *v, size_t vlen,
                       int64_t lo, int64_t hi, int64_t *out)
{
    token t[1];
    int n = 0;
    int rc = split(p, keyname, v, vlen, t, 1, 1, &n);
    return rc != FTM_OK ? rc : integer(p, keyname, t[0], lo, hi, out);
}

/* Exactly three numbers; positive: each must be > 0. */
static int triple(const parser *p, const char *keyname, const char *v, size_t vlen, bool positive,
                  double out[3])
{
    token t[3];
    int n = 0;
    int rc = split(p, keyname, v, vlen, t, 3, 3, &n);
    if (rc != FTM_OK)
        return rc;
    double x[3];
    for (int i = 0; i < 3; i++) {
        if ((rc = number(p, keyname, t[i], &x[i])) != FTM_OK)
            return rc;
        if (positive && !(x[i] > 0))
            return fail_at(p, p->line, FTM_EINVAL, "%s: every value must be > 0, got %.*s",
                           keyname, shown(t[i].n), t[i].s);
    }
    memcpy(out, x, sizeof x);
    return FTM_OK;
}

/* One word out of a NULL-terminated list; returns its index in *out. */
static int word(const parser *p, const char *keyname, const char *v, size_t vlen,
                const char *const *choices, const char *expected, int *out)
{
    token t[1];
    int n = 0;
    int rc = split(p, keyname, v, vlen, t, 1, 1, &n);
    if (rc != FTM_OK)
        return rc;
    for (int i = 0; choices[i]; i++) {
        if (token_is(t[0], choices[i])) {
            *out = i;
            return FTM_OK;
        }
    }
    return fail_at(p, p->line, FTM_EPARSE, "%s: unknown value '%.*s' (expected %s)", keyname,
                   shown(t[0].n), t[0].s, expected);
}

/* Grows a dynamic array by one element; returns a pointer to it or NULL. */
static void *push(void **items, size_t *count, size_t *cap, size_t size)
{
    if (*count == *cap) {
        size_t ncap = *cap ? *cap * 2 : 8;
        void *n = realloc(*items, ncap * size);
        if (!n)
            return NULL;
        *items = n;
        *cap = ncap;
    }
    void *slot = (char *)*items + *count * size;
    memset(slot, 0, size);
    (*count)++;
    return slot;
}

/* ----------------------------------------------------- key assignment */

/* Box faces: any of xmin .. zmax, or all, or none. */
static int faces_value(const parser *p, const char *kn, const char *v, size_t vlen,
                       uint32_t *out)
{
    static const char *const faces[] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax", NULL};
    token t[MAX_TOKENS];
    int n = 0, rc;
    if ((rc = split(p, kn, v, vlen, t, 1, MAX_TOKENS, &n)) != FTM_OK)
        return rc;
    uint32_t mask = 0;
    for (int i = 0; i < n; i++) {
        bool none = token_is(t[i], "none"), all = token_is(t[i], "all");
        if ((none || all) && n > 1)
            return fail_at(p, p->line, FTM_EPARSE, "%s: '%s' cannot be combined with other faces",
                           kn, none ? "none" : "all");
        if (none)
            break;
        if (all) {
            mask = ALL_FACES;
            break;
        }
        int f = -1;
        for (int j = 0; faces[j]; j++)
            if (token_is(t[i], faces[j]))
                f = j;
        if (f < 0)
            return fail_at(p, p->line, FTM_EPARSE,
                           "%s: unknown face '%.*s' (expected xmin xmax ymin ymax zmin zmax, all "
                           "or none)",
                           kn, shown(t[i].n), t[i].s);
        mask |= 1u << f; /* FTM_FACE_* follow the order of faces[] */
    }
    *out = mask;
    return FTM_OK;
}

/* A path: the rest of the line, so that paths may contain spaces. */
static int path_value(const parser *p, const char *v, size_t vlen, char **out)
{
    if (vlen > 4096)
        return fail_at(p, p->line, FTM_EINVAL, "file: path too long");
    *out = malloc(vlen + 1);
    if (!*out)
        return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
    memcpy(*out, v, vlen);
    (*out)[vlen] = '\0';
    return FTM_OK;
}

static int set_volume_key(parser *p, key k, const char *kn, const char *v, size_t vlen)
{
    spec *s = &p->s;
    token t[3];
    int n = 0, rc;
    int64_t iv = 0;
    double x[3];
    switch (k) {
    case K_VOLUME_FILE:
        return path_value(p, v, vlen, &s->volume_file);
    case K_VOLUME_LABELS:
        free(s->volume_labels_file); /* (a repeated key is refused before this) */
        s->volume_labels_file = NULL;
        return path_value(p, v, vlen, &s->volume_labels_file);
    case K_PHANTOM: {
        static const char *const phantoms[] = {"head", NULL};
        int which;
        return word(p, kn, v, vlen, phantoms, "head", &which);
    }
    case K_VOXELS:
        if ((rc = one_integer(p, kn, v, vlen, 8, SCENE_MAX_PHANTOM_VOXELS, &iv)) != FTM_OK)
            return rc;
        s->phantom.voxels = (int32_t)iv;
        return FTM_OK;
    case K_SIZE:
        return scalar(p, kn, v, vlen, true, &s->phantom.size);
    case K_NODES: /* one count for every axis, or three */
        if ((rc = split(p, kn, v, vlen, t, 1, 3, &n)) != FTM_OK)
            return rc;
        if (n == 2)
            return fail_at(p, p->line, FTM_EPARSE,
                           "nodes: expected 1 value (all axes) or 3 (x y z), got 2");
        for (int i = 0; i < n; i++) {
            if ((rc = integer(p, kn, t[i], 2, SCENE_MAX_VOLUME_AXIS, &iv)) != FTM_OK)
                return rc;
            s->volume_lattice.nodes[i] = (int32_t)iv;
        }
        for (int i = n; i < 3; i++)
            s->volume_lattice.nodes[i] = s->volume_lattice.nodes[0];
        if ((int64_t)s->volume_lattice.nodes[0] * s->volume_lattice.nodes[1] *
                s->volume_lattice.nodes[2] > SCENE_MAX_LATTICE_NODES)
            return fail_at(p, p->line, FTM_ERANGE, "nodes: more than %lld lattice points",
                           (long long)SCENE_MAX_LATTICE_NODES);
        return FTM_OK;
    case K_VOLUME_STENCIL:
        if ((rc = one_integer(p, kn, v, vlen, INT32_MIN, INT32_MAX, &iv)) != FTM_OK)
            return rc;
        if (iv != 6 && iv != 18 && iv != 26)
            return fail_at(p, p->line, FTM_EINVAL, "stencil must be 6, 18 or 26, got %lld",
                           (long long)iv);
        s->volume_lattice.stencil = (ftm_stencil)iv;
        return FTM_OK;
    case K_HARD: /* any number: above 1 fixes nothing */
        if ((rc = split(p, kn, v, vlen, t, 1, 1, &n)) != FTM_OK)
            return rc;
        return number(p, kn, t[0], &s->volume_lattice.hard_threshold);
    case K_AIR:
        return scalar(p, kn, v, vlen, false, &s->volume_lattice.air_threshold);
    case K_FIT_SURFACE: {
        static const char *const bools[] = {"on", "off", "true", "false", "yes", "no", "1", "0",
                                            NULL};
        int b;
        if ((rc = word(p, kn, v, vlen, bools, "on or off", &b)) != FTM_OK)
            return rc;
        s->volume_lattice.fit_surface = (b % 2) == 0;
        return FTM_OK;
    }
    case K_FIX:
        return faces_value(p, kn, v, vlen, &s->volume_lattice.fixed_faces);
    case K_WINDOW:
        if ((rc = split(p, kn, v, vlen, t, 2, 2, &n)) != FTM_OK ||
            (rc = number(p, kn, t[0], &x[0])) != FTM_OK ||
            (rc = number(p, kn, t[1], &x[1])) != FTM_OK)
            return rc;
        if (!(x[0] >= 0 && x[0] < x[1] && x[1] <= 100))
            return fail_at(p, p->line, FTM_EINVAL,
                           "window: percentiles LOW HIGH need 0 <= LOW < HIGH <= 100, got %g %g",
                           x[0], x[1]);
        s->volume_load.low_percentile = x[0];
        s->volume_load.high_percentile = x[1];
        return FTM_OK;
    case K_SCALE:
        return scalar(p, kn, v, vlen, true, &s->volume_load.scale);
    case K_ORIGIN:
        if ((rc = triple(p, kn, v, vlen, false, x)) != FTM_OK)
            return rc;
        s->volume_load.origin = s->phantom.origin = (ftm_vec3){x[0], x[1], x[2]};
        return FTM_OK;
    case K_AXES: {
        static const char *const axes[] = {"scanner", "stored", NULL};
        int which;
        if ((rc = word(p, kn, v, vlen, axes, "scanner or stored", &which)) != FTM_OK)
            return rc;
        s->volume_load.axes = which == 0 ? FTM_VOLUME_AXES_SCANNER : FTM_VOLUME_AXES_STORED;
        return FTM_OK;
    }
    default:
        return fail_at(p, p->line, FTM_EPARSE, "internal: key %s in [volume]", kn);
    }
}


/* A repeatable key's list of integers min..INT32_MAX (fixed_nodes,
 * fixed_label), any number of them, each remembered with its line. */
static int index_list(parser *p, const char *kn, const char *v, size_t vlen, int64_t min,
                      fixed_index **list, size_t *count, size_t *cap, const char *what)
{
    const char *cur = v, *end = v + vlen;
    token one;
    int n = 0, rc;
    while (ftm_text_token(&cur, end, &one.s, &one.n)) {
        int64_t x = 0;
        if ((rc = integer(p, kn, one, min, INT32_MAX, &x)) != FTM_OK)
            return rc;
        fixed_index *fi = push((void **)list, count, cap, sizeof *fi);
        if (!fi)
            return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
        fi->input = x;
        fi->line = p->line;
        n++;
    }
    if (n == 0)
        return fail_at(p, p->line, FTM_EPARSE, "%s: expected %s", kn, what);
    return FTM_OK;
}

/* The two sides of "WHAT : LIST" (slide_nodes, slide_box, ground_springs). */
static int colon_sides(parser *p, const char *kn, const char *v, size_t vlen, const char *form,
                       const char **right, size_t *rlen, size_t *llen)
{
    const char *colon = memchr(v, ':', vlen);
    if (!colon)
        return fail_at(p, p->line, FTM_EPARSE, "%s: expected %s", kn, form);
    *llen = (size_t)(colon - v);
    *right = colon + 1;
    *rlen = vlen - *llen - 1;
    return FTM_OK;
}

/* A normal: x, y or z, or three numbers not all zero. */
static int normal_value(parser *p, const char *kn, const char *v, size_t vlen, double n[3])
{
    token t[3];
    int count = 0, rc;
    if ((rc = split(p, kn, v, vlen, t, 1, 3, &count)) != FTM_OK)
        return rc;
    if (count == 1 && t[0].n == 1 && t[0].s[0] >= 'x' && t[0].s[0] <= 'z') {
        n[0] = n[1] = n[2] = 0.0;
        n[t[0].s[0] - 'x'] = 1.0;
        return FTM_OK;
    }
    if (count != 3)
        return fail_at(p, p->line, FTM_EPARSE,
                       "%s: the normal is x, y, z or three numbers NX NY NZ, got '%.*s'", kn,
                       shown(vlen), v);
    for (int i = 0; i < 3; i++)
        if ((rc = number(p, kn, t[i], &n[i])) != FTM_OK)
            return rc;
    double l2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if (!(l2 > 0.0) || !isfinite(l2))
        return fail_at(p, p->line, FTM_EINVAL,
                       "%s: the normal %g %g %g has %s length: it gives no direction", kn, n[0],
                       n[1], n[2], l2 > 0.0 ? "no finite" : "zero");
    return FTM_OK;
}

/* slide_nodes = NORMAL : NODES, slide_box = NORMAL : BOX, ground_springs =
 * STIFFNESS : NODES; one bc_spec per node (box). */
static int bc_value(parser *p, key k, const char *kn, const char *v, size_t vlen)
{
    spec *s = &p->s;
    const char *form = k == K_SLIDE_NODES    ? "NORMAL : NODES (normal x, y, z or NX NY NZ)"
                       : k == K_SLIDE_BOX    ? "NORMAL : XMIN YMIN ZMIN XMAX YMAX ZMAX"
                       : k == K_SLIDE_LABEL  ? "NORMAL : LABELS (element labels >= 1)"
                       : k == K_GROUND_LABEL ? "STIFFNESS : LABELS (N/m; element labels >= 1)"
                                             : "STIFFNESS : NODES (stiffness in N/m)";
    const bool labels = k == K_SLIDE_LABEL || k == K_GROUND_LABEL;
    const char *right = v;
    size_t rlen = 0, llen = 0;
    int rc;
    if ((rc = colon_sides(p, kn, v, vlen, form, &right, &rlen, &llen)) != FTM_OK)
        return rc;
    bc_spec b = {.kind = k == K_SLIDE_NODES    ? BC_SLIDE
                         : k == K_SLIDE_BOX    ? BC_SLIDE_BOX
                         : k == K_SLIDE_LABEL  ? BC_SLIDE_LABEL
                         : k == K_GROUND_LABEL ? BC_GROUND_LABEL
                                               : BC_GROUND,
                 .line = p->line};
    if (k == K_GROUND_SPRINGS || k == K_GROUND_LABEL) {
        if ((rc = scalar(p, kn, v, llen, false, &b.k)) != FTM_OK)
            return rc;
        if (!(b.k > 0.0) || !isfinite(b.k))
            return fail_at(p, p->line, FTM_EINVAL,
                           "%s: the stiffness must be > 0 N/m and finite, got %g", kn, b.k);
    } else if ((rc = normal_value(p, kn, v, llen, b.normal)) != FTM_OK) {
        return rc;
    }
    if (k == K_SLIDE_BOX) {
        token t[6];
        double x[6];
        int n = 0;
        if ((rc = split(p, kn, right, rlen, t, 6, 6, &n)) != FTM_OK)
            return rc;
        for (int i = 0; i < 6; i++)
            if ((rc = number(p, kn, t[i], &x[i])) != FTM_OK)
                return rc;
        for (int i = 0; i < 3; i++)
            if (x[i] > x[i + 3])
                return fail_at(p, p->line, FTM_EINVAL,
                               "slide_box: min %c (%g) is greater than max %c (%g)", 'x' + i, x[i],
                               'x' + i, x[i + 3]);
        memcpy(b.box.lo, x, sizeof b.box.lo);
        memcpy(b.box.hi, x + 3, sizeof b.box.hi);
        bc_spec *e = push((void **)&s->bcs, &s->bc_count, &s->bc_cap, sizeof *e);
        if (!e)
            return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
        *e = b;
        return FTM_OK;
    }
    const char *cur = right, *end = right + rlen;
    token one;
    int count = 0;
    while (ftm_text_token(&cur, end, &one.s, &one.n)) {
        if ((rc = integer(p, kn, one, labels ? 1 : 0, INT32_MAX, &b.input)) != FTM_OK)
            return rc;
        bc_spec *e = push((void **)&s->bcs, &s->bc_count, &s->bc_cap, sizeof *e);
        if (!e)
            return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
        *e = b;
        count++;
    }
    if (count == 0)
        return fail_at(p, p->line, FTM_EPARSE, "%s: expected %s", kn, form);
    return FTM_OK;
}

static int set_mesh_key(parser *p, key k, const char *kn, const char *v, size_t vlen)
{
    spec *s = &p->s;
    token t[MAX_TOKENS];
    int n = 0, rc;
    switch (k) {
    case K_GENERATOR: {
        if ((rc = split(p, kn, v, vlen, t, 1, 1, &n)) != FTM_OK)
            return rc;
        if (token_is(t[0], "lattice2d"))
            s->gen = GEN_LATTICE2D;
        else if (token_is(t[0], "lattice3d"))
            s->gen = GEN_LATTICE3D;
        else if (token_is(t[0], "volume"))
            s->gen = GEN_VOLUME;
        else
            return fail_at(p, p->line, FTM_ENOENT,
                           "generator: unknown generator '%.*s' (expected lattice2d, lattice3d "
                           "or volume)",
                           shown(t[0].n), t[0].s);
        return FTM_OK;
    }
    case K_FILE:
        return path_value(p, v, vlen, &s->file);
    case K_NX:
        return one_integer(p, kn, v, vlen, 2, SCENE_MAX_LATTICE_AXIS, &s->nx);
    case K_NY:
        return one_integer(p, kn, v, vlen, 2, SCENE_MAX_LATTICE_AXIS, &s->ny);
    case K_NZ:
        return one_integer(p, kn, v, vlen, 2, SCENE_MAX_LATTICE_AXIS, &s->nz);
    case K_SPACING: {
        double x[3];
        if ((rc = split(p, kn, v, vlen, t, 1, 3, &n)) != FTM_OK)
            return rc;
        if (n == 2)
            return fail_at(p, p->line, FTM_EPARSE,
                           "spacing: expected 1 value (all axes) or 3 (x y z), got 2");
        for (int i = 0; i < n; i++) {
            if ((rc = number(p, kn, t[i], &x[i])) != FTM_OK)
                return rc;
            if (!(x[i] > 0))
                return fail_at(p, p->line, FTM_EINVAL, "spacing must be > 0, got %.*s",
                               shown(t[i].n), t[i].s);
        }
        for (int i = 0; i < 3; i++)
            s->spacing[i] = x[n == 1 ? 0 : i];
        s->spacing_count = n;
        return FTM_OK;
    }
    case K_STENCIL:
        if ((rc = one_integer(p, kn, v, vlen, INT32_MIN, INT32_MAX, &s->stencil)) != FTM_OK)
            return rc;
        if (s->stencil != 6 && s->stencil != 18 && s->stencil != 26)
            return fail_at(p, p->line, FTM_EINVAL, "stencil must be 6, 18 or 26, got %lld",
                           (long long)s->stencil);
        return FTM_OK;
    case K_CLASS_SCALE:
        return triple(p, kn, v, vlen, true, s->class_scale);
    case K_FIXED_FACES:
        return faces_value(p, kn, v, vlen, &s->fixed_faces);
    case K_FIXED_NODES:
        return index_list(p, kn, v, vlen, 0, &s->fixed_nodes, &s->fixed_node_count,
                          &s->fixed_node_cap, "node indices");
    case K_SLIDE_NODES:
    case K_SLIDE_BOX:
    case K_GROUND_SPRINGS:
    case K_SLIDE_LABEL:
    case K_GROUND_LABEL:
        return bc_value(p, k, kn, v, vlen);
    case K_FIXED_LABEL: /* element labels, >= 1; checked against the mesh once built */
        return index_list(p, kn, v, vlen, 1, &s->fixed_labels, &s->fixed_label_count,
                          &s->fixed_label_cap, "element labels");
    case K_FIXED_BOX: {
        double x[6];
        if ((rc = split(p, kn, v, vlen, t, 6, 6, &n)) != FTM_OK)
            return rc;
        for (int i = 0; i < 6; i++)
            if ((rc = number(p, kn, t[i], &x[i])) != FTM_OK)
                return rc;
        for (int i = 0; i < 3; i++)
            if (x[i] > x[i + 3])
                return fail_at(p, p->line, FTM_EINVAL,
                               "fixed_box: min %c (%g) is greater than max %c (%g)", 'x' + i, x[i],
                               'x' + i, x[i + 3]);
        fixed_box *b =
            push((void **)&s->fixed_boxes, &s->fixed_box_count, &s->fixed_box_cap, sizeof *b);
        if (!b)
            return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
        memcpy(b->lo, x, sizeof b->lo);
        memcpy(b->hi, x + 3, sizeof b->hi);
        return FTM_OK;
    }
    default:
        return fail_at(p, p->line, FTM_EPARSE, "internal: key %s in [mesh]", kn);
    }
}

/* Length of the well-formed UTF-8 sequence at s (n bytes left), 0 if none:
 * no overlong forms, no surrogates, nothing above U+10FFFF. A name is
 * printed in JSON summaries, which must be valid UTF-8. */
static size_t utf8_char(const unsigned char *s, size_t n)
{
    if (s[0] < 0x80)
        return 1;
    size_t len = s[0] >= 0xC2 && s[0] <= 0xDF ? 2 : s[0] >= 0xE0 && s[0] <= 0xEF ? 3
                 : s[0] >= 0xF0 && s[0] <= 0xF4                           ? 4
                                                                          : 0;
    if (len == 0 || len > n)
        return 0;
    for (size_t i = 1; i < len; i++)
        if ((s[i] & 0xC0) != 0x80)
            return 0;
    if ((s[0] == 0xE0 && s[1] < 0xA0) || (s[0] == 0xED && s[1] > 0x9F) ||
        (s[0] == 0xF0 && s[1] < 0x90) || (s[0] == 0xF4 && s[1] > 0x8F))
        return 0;
    return len;
}

static int set_key(parser *p, key k, const char *kn, const char *v, size_t vlen)
{
    spec *s = &p->s;
    int rc;
    int64_t iv = 0;
    switch (k) {
    case K_NAME:
        if (vlen >= SCENE_NAME_MAX)
            return fail_at(p, p->line, FTM_EINVAL, "name longer than %d bytes",
                           SCENE_NAME_MAX - 1);
        for (size_t i = 0, c; i < vlen; i += c) {
            if ((unsigned char)v[i] < 0x20 || v[i] == 0x7f)
                return fail_at(p, p->line, FTM_EINVAL, "name contains a control character");
            if ((c = utf8_char((const unsigned char *)v + i, vlen - i)) == 0)
                return fail_at(p, p->line, FTM_EINVAL, "name is not valid UTF-8 (byte %zu)",
                               i + 1);
        }
        memcpy(s->name, v, vlen);
        s->name[vlen] = '\0';
        return FTM_OK;
    case K_DESCRIPTION:
        return FTM_OK; /* free text for readers of the file */
    case K_MASS:
        return scalar(p, kn, v, vlen, true, &s->material.node_mass);
    case K_DAMPING:
        return scalar(p, kn, v, vlen, false, &s->material.node_damping);
    case K_STIFFNESS:
        return scalar(p, kn, v, vlen, true, &s->material.stiffness);
    case K_AXIS_SCALE: {
        double x[3];
        if ((rc = triple(p, kn, v, vlen, true, x)) != FTM_OK)
            return rc;
        s->material.axis_scale = (ftm_vec3){x[0], x[1], x[2]};
        return FTM_OK;
    }
    case K_TIME_STEP:
        if ((rc = scalar(p, kn, v, vlen, true, &s->sim.time_step)) != FTM_OK)
            return rc;
        if (s->sim.time_step < FTM_MIN_TIME_STEP || s->sim.time_step > FTM_MAX_TIME_STEP)
            return fail_at(p, p->line, FTM_EINVAL, "%s must be in %g..%g s, got %g", kn,
                           FTM_MIN_TIME_STEP, FTM_MAX_TIME_STEP, s->sim.time_step);
        return FTM_OK;
    case K_DEPTH:
        if ((rc = one_integer(p, kn, v, vlen, 0, SCENE_MAX_DEPTH, &iv)) != FTM_OK)
            return rc;
        s->sim.depth = (int32_t)iv;
        return FTM_OK;
    case K_ORDER: {
        static const char *const orders[] = {"colored", "bfs", "jacobi", NULL};
        static const ftm_order values[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                           FTM_ORDER_LAYER_JACOBI};
        int o;
        if ((rc = word(p, kn, v, vlen, orders, "colored, bfs or jacobi", &o)) != FTM_OK)
            return rc;
        s->sim.order = values[o];
        return FTM_OK;
    }
    case K_STEPS:
        return one_integer(p, kn, v, vlen, 0, INT32_MAX, &s->steps);
    case K_SLEEP_TOLERANCE:
        return scalar(p, kn, v, vlen, false, &s->sim.sleep_tolerance);
    case K_REGION_SLEEP_STEPS:
        if ((rc = one_integer(p, kn, v, vlen, 0, INT32_MAX, &iv)) != FTM_OK)
            return rc;
        s->sim.region_sleep_steps = (int32_t)iv;
        return FTM_OK;
    case K_GUARD: {
        static const char *const bools[] = {"on", "off", "true", "false", "yes", "no", "1", "0",
                                            NULL};
        int b;
        if ((rc = word(p, kn, v, vlen, bools, "on or off", &b)) != FTM_OK)
            return rc;
        s->sim.guard = (b % 2) == 0;
        return FTM_OK;
    }
    case K_GUARD_MOTION:
        return scalar(p, kn, v, vlen, true, &s->sim.guard_motion);
    case K_MAX_SUBSTEPS:
        if ((rc = one_integer(p, kn, v, vlen, 1, SCENE_MAX_SUBSTEPS, &iv)) != FTM_OK)
            return rc;
        s->sim.max_substeps = (int32_t)iv;
        return FTM_OK;
    case K_FORCES: { /* element forces take the [fem] material (checked later) */
        static const char *const names[] = {"springs", "linear-fem", "corot-fem", "neo-hookean",
                                            NULL};
        static const ftm_forces values[] = {FTM_FORCES_SPRINGS, FTM_FORCES_LINEAR_FEM,
                                            FTM_FORCES_COROT_FEM, FTM_FORCES_NEO_HOOKEAN};
        int f;
        if ((rc = word(p, kn, v, vlen, names, "springs, linear-fem, corot-fem or neo-hookean",
                       &f)) != FTM_OK)
            return rc;
        s->sim.forces = values[f];
        return FTM_OK;
    }
    case K_FAR_FIELD: { /* elastic needs a held body: checked when the simulation is made */
        static const char *const names[] = {"fixed", "elastic", NULL};
        static const ftm_far_field values[] = {FTM_FAR_FIELD_FIXED, FTM_FAR_FIELD_ELASTIC};
        int f;
        if ((rc = word(p, kn, v, vlen, names, "fixed or elastic", &f)) != FTM_OK)
            return rc;
        s->sim.far_field = values[f];
        return FTM_OK;
    }
    case K_YOUNG:
        return scalar(p, kn, v, vlen, true, &s->young);
    case K_TIP_RADIUS:
    case K_SHAFT_RADIUS:
    case K_SHAFT_LENGTH: { /* metres: a hand tool, from a needle to a finger */
        double *out = k == K_TIP_RADIUS     ? &s->tool.tip_radius
                      : k == K_SHAFT_RADIUS ? &s->tool.shaft_radius
                                            : &s->tool.shaft_length;
        if ((rc = scalar(p, kn, v, vlen, true, out)) != FTM_OK)
            return rc;
        if (*out > 1.0)
            return fail_at(p, p->line, FTM_EPARSE, "%s must be at most 1 m, got %g", kn, *out);
        return FTM_OK;
    }
    case K_POISSON: {
        token t[1];
        int n = 0;
        double x = 0;
        if ((rc = split(p, kn, v, vlen, t, 1, 1, &n)) != FTM_OK ||
            (rc = number(p, kn, t[0], &x)) != FTM_OK)
            return rc;
        if (!(x > -1.0 && x < 0.5))
            return fail_at(p, p->line, FTM_EINVAL, "poisson must be > -1 and < 0.5, got %.*s",
                           shown(t[0].n), t[0].s);
        s->poisson = x;
        return FTM_OK;
    }
    case K_DENSITY:
        return scalar(p, kn, v, vlen, true, &s->density);
    case K_MASS_SCALING: {
        static const char *const bools[] = {"on", "off", "true", "false", "yes", "no", "1", "0",
                                            NULL};
        int b;
        if ((rc = word(p, kn, v, vlen, bools, "on or off", &b)) != FTM_OK)
            return rc;
        s->sim.mass_scaling = (b % 2) == 0;
        return FTM_OK;
    }
    default:
        if (key_table[k].sec == SEC_VOLUME)
            return set_volume_key(p, k, kn, v, vlen);
        return set_mesh_key(p, k, kn, v, vlen);
    }
}

static int set_load_key(parser *p, load_spec *ls, key k, const char *kn, const char *v,
                        size_t vlen)
{
    ftm_scene_load *l = &ls->load;
    token t[4];
    int n = 0, rc;
    int64_t iv = 0;
    switch (k) {
    case K_NODE:
        if ((rc = split(p, kn, v, vlen, t, 1, 4, &n)) != FTM_OK)
            return rc;
        if (token_is(t[0], "nearest")) {
            if (n != 4)
                return fail_at(p, p->line, FTM_EPARSE,
                               "node: expected 'nearest X Y Z' with three coordinates");
            double x[3];
            for (int i = 0; i < 3; i++)
                if ((rc = number(p, kn, t[i + 1], &x[i])) != FTM_OK)
                    return rc;
            ls->nearest = true;
            ls->point = (ftm_vec3){x[0], x[1], x[2]};
            return FTM_OK;
        }
        if (n != 1)
            return fail_at(p, p->line, FTM_EPARSE,
                           "node: expected an input node index or 'nearest X Y Z'");
        ls->nearest = false;
        return integer(p, kn, t[0], 0, INT32_MAX, &ls->input);
    case K_KIND: {
        static const char *const kinds[] = {"force", "displacement", NULL};
        int kd;
        if ((rc = word(p, kn, v, vlen, kinds, "force or displacement", &kd)) != FTM_OK)
            return rc;
        l->contact.kind = kd == 0 ? FTM_CONTACT_FORCE : FTM_CONTACT_DISPLACEMENT;
        return FTM_OK;
    }
    case K_VALUE: {
        double x[3];
        if ((rc = triple(p, kn, v, vlen, false, x)) != FTM_OK)
            return rc;
        l->contact.value = (ftm_vec3){x[0], x[1], x[2]};
        return FTM_OK;
    }
    case K_GROUP:
        if ((rc = one_integer(p, kn, v, vlen, 0, FTM_MAX_CONTACT_GROUP, &iv)) != FTM_OK)
            return rc;
        l->contact.group = (int32_t)iv;
        return FTM_OK;
    case K_START:
        return scalar(p, kn, v, vlen, false, &l->start);
    case K_END:
        return scalar(p, kn, v, vlen, false, &l->end);
    case K_RELEASE:
        if ((rc = split(p, kn, v, vlen, t, 1, 1, &n)) != FTM_OK)
            return rc;
        if (token_is(t[0], "never")) {
            l->release = INFINITY;
            return FTM_OK;
        }
        return scalar(p, kn, v, vlen, false, &l->release);
    case K_RAMP: {
        static const char *const ramps[] = {"constant", "linear", "triangle", NULL};
        static const ftm_ramp values[] = {FTM_RAMP_CONSTANT, FTM_RAMP_LINEAR, FTM_RAMP_TRIANGLE};
        int r;
        if ((rc = word(p, kn, v, vlen, ramps, "constant, linear or triangle", &r)) != FTM_OK)
            return rc;
        l->ramp = values[r];
        return FTM_OK;
    }
    default:
        return fail_at(p, p->line, FTM_EPARSE, "internal: key %s in [load]", kn);
    }
}

/* ------------------------------------------------------------ lines */

static bool is_blank(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

static void trim(const char **s, size_t *n)
{
    while (*n > 0 && is_blank(**s)) {
        (*s)++;
        (*n)--;
    }
    while (*n > 0 && is_blank((*s)[*n - 1]))
        (*n)--;
}

/* A '#' at the start of a line or after a blank starts a comment, so values
 * such as file names can still contain '#' inside a word. */
static size_t strip_comment(const char *line, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (line[i] == '#' && (i == 0 || is_blank(line[i - 1])))
            return i;
    return n;
}

#define SCENE_MAX_LABEL_FEMS 65536

/* The LABEL of a [WHAT LABEL] header. */
static int section_label(parser *p, const char *what, const char *v, size_t n, long long *out)
{
    trim(&v, &n);
    char buf[32];
    long long label = 0;
    char *end = NULL;
    if (n > 0 && n < sizeof buf) {
        memcpy(buf, v, n);
        buf[n] = '\0';
        errno = 0;
        label = strtoll(buf, &end, 10);
    }
    if (n == 0 || n >= sizeof buf || *end != '\0' || errno || buf[0] == '+' || label < 1 ||
        label > INT32_MAX)
        return fail_at(p, p->line, FTM_EPARSE,
                       "[%s %.*s]: a label is a whole number 1 .. %d, as the mesh's elements "
                       "carry it (a Gmsh physical group, a TetGen region)",
                       what, shown(n), v, INT32_MAX);
    *out = label;
    return FTM_OK;
}

/* [material LABEL]: the link stiffness of one mesh label's elements. */
static int open_label_spring(parser *p, const char *v, size_t n, section *cur)
{
    spec *sp = &p->s;
    long long label = 0;
    int rc = section_label(p, "material", v, n, &label);
    if (rc)
        return rc;
    for (size_t i = 0; i < sp->label_spring_count; i++)
        if (sp->label_springs[i].label == label)
            return fail_at(p, p->line, FTM_EPARSE,
                           "duplicate section [material %lld] (first at line %d)", label,
                           (int)sp->label_springs[i].line);
    if (sp->label_spring_count >= SCENE_MAX_LABEL_FEMS)
        return fail_at(p, p->line, FTM_ERANGE, "more than %d [material LABEL] sections",
                       SCENE_MAX_LABEL_FEMS);
    label_spring *ls = push((void **)&sp->label_springs, &sp->label_spring_count,
                            &sp->label_spring_cap, sizeof *ls);
    if (!ls)
        return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
    *ls = (label_spring){.line = p->line, .label = (int32_t)label};
    if (!sp->section_line[SEC_MATERIAL_LABEL])
        sp->section_line[SEC_MATERIAL_LABEL] = p->line;
    *cur = SEC_MATERIAL_LABEL;
    return FTM_OK;
}

/* stiffness in the [material LABEL] being read. */
static int label_spring_key(parser *p, const char *kname, size_t kn, const char *v, size_t vn)
{
    label_spring *ls = &p->s.label_springs[p->s.label_spring_count - 1];
    if (!(kn == 9 && memcmp(kname, "stiffness", 9) == 0))
        return fail_at(p, p->line, FTM_EPARSE,
                       "unknown key '%.*s' in [material %d] (a label's section takes stiffness; "
                       "mass and damping are per node, the body's, in [material])",
                       shown(kn), kname, (int)ls->label);
    if (ls->stiffness_line)
        return fail_at(p, p->line, FTM_EPARSE, "duplicate key 'stiffness' (first at line %d)",
                       (int)ls->stiffness_line);
    if (vn == 0)
        return fail_at(p, p->line, FTM_EPARSE, "stiffness: missing value");
    int rc = scalar(p, "stiffness", v, vn, true, &ls->stiffness);
    if (rc == FTM_OK)
        ls->stiffness_line = p->line;
    return rc;
}

/* [fem LABEL]: young, poisson and density for the elements of one mesh label. */
static int open_label_fem(parser *p, const char *v, size_t n, section *cur)
{
    spec *sp = &p->s;
    long long label = 0;
    int rc = section_label(p, "fem", v, n, &label);
    if (rc)
        return rc;
    for (size_t i = 0; i < sp->label_fem_count; i++)
        if (sp->label_fems[i].mat.label == label)
            return fail_at(p, p->line, FTM_EPARSE, "duplicate section [fem %lld] (first at line %d)",
                           label, (int)sp->label_fems[i].line);
    if (sp->label_fem_count >= SCENE_MAX_LABEL_FEMS)
        return fail_at(p, p->line, FTM_ERANGE, "more than %d [fem LABEL] sections",
                       SCENE_MAX_LABEL_FEMS);
    label_fem *lf = push((void **)&sp->label_fems, &sp->label_fem_count, &sp->label_fem_cap,
                         sizeof *lf);
    if (!lf)
        return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
    *lf = (label_fem){.line = p->line, .mat = {.label = (int32_t)label}};
    if (!sp->section_line[SEC_FEM_LABEL])
        sp->section_line[SEC_FEM_LABEL] = p->line;
    *cur = SEC_FEM_LABEL;
    return FTM_OK;
}

/* `name` in a [fem LABEL]: the tissue's name for a legend, printable ASCII
 * (the client's font), unique among the labels. */
static int label_fem_name(parser *p, label_fem *lf, const char *v, size_t vn)
{
    if (lf->name_line)
        return fail_at(p, p->line, FTM_EPARSE, "duplicate key 'name' (first at line %d)",
                       (int)lf->name_line);
    if (vn == 0)
        return fail_at(p, p->line, FTM_EPARSE, "name: missing value");
    if (vn > FTM_SCENE_LABEL_NAME_MAX)
        return fail_at(p, p->line, FTM_EPARSE, "name: at most %d characters, got %zu",
                       FTM_SCENE_LABEL_NAME_MAX, vn);
    for (size_t i = 0; i < vn; i++)
        if ((unsigned char)v[i] < 0x20 || (unsigned char)v[i] > 0x7e)
            return fail_at(p, p->line, FTM_EPARSE,
                           "name: character %zu is not printable ASCII (byte 0x%02x)", i + 1,
                           (unsigned)(unsigned char)v[i]);
    for (size_t i = 0; i + 1 < p->s.label_fem_count; i++) {
        const label_fem *o = &p->s.label_fems[i];
        if (o->name_line && strlen(o->name) == vn && memcmp(o->name, v, vn) == 0)
            return fail_at(p, p->line, FTM_EPARSE, "name '%s' already names label %d (line %d)",
                           o->name, (int)o->mat.label, (int)o->name_line);
    }
    memcpy(lf->name, v, vn);
    lf->name[vn] = '\0';
    lf->name_line = p->line;
    return FTM_OK;
}

/* young, poisson, density or name in the [fem LABEL] being read. */
static int label_fem_key(parser *p, const char *kname, size_t kn, const char *v, size_t vn)
{
    label_fem *lf = &p->s.label_fems[p->s.label_fem_count - 1];
    if (kn == 4 && memcmp(kname, "name", 4) == 0)
        return label_fem_name(p, lf, v, vn);
    bool young = kn == 5 && memcmp(kname, "young", 5) == 0;
    bool poisson = kn == 7 && memcmp(kname, "poisson", 7) == 0;
    bool density = kn == 7 && memcmp(kname, "density", 7) == 0;
    if (!young && !poisson && !density)
        return fail_at(p, p->line, FTM_EPARSE,
                       "unknown key '%.*s' in [fem %d] (a label's section takes young, poisson, "
                       "density and name)",
                       shown(kn), kname, (int)lf->mat.label);
    const char *name = young ? "young" : poisson ? "poisson" : "density";
    int32_t *seen = young ? &lf->young_line : poisson ? &lf->poisson_line : &lf->density_line;
    if (*seen)
        return fail_at(p, p->line, FTM_EPARSE, "duplicate key '%s' (first at line %d)", name,
                       (int)*seen);
    if (vn == 0)
        return fail_at(p, p->line, FTM_EPARSE, "%s: missing value", name);
    int rc;
    if (young || density) {
        rc = scalar(p, name, v, vn, true, young ? &lf->mat.young : &lf->mat.density);
    } else {
        token t[1];
        int nt = 0;
        double x = 0;
        if ((rc = split(p, "poisson", v, vn, t, 1, 1, &nt)) == FTM_OK &&
            (rc = number(p, "poisson", t[0], &x)) == FTM_OK && !(x > -1.0 && x < 0.5))
            rc = fail_at(p, p->line, FTM_EINVAL, "poisson must be > -1 and < 0.5, got %.*s",
                         shown(t[0].n), t[0].s);
        lf->mat.poisson = x;
    }
    if (rc == FTM_OK)
        *seen = p->line;
    return rc;
}

static int open_section(parser *p, const char *s, size_t n, section *cur)
{
    spec *sp = &p->s;
    if (n < 2 || s[n - 1] != ']')
        return fail_at(p, p->line, FTM_EPARSE, "section header must look like [name]");
    const char *nm = s + 1;
    size_t nn = n - 2;
    trim(&nm, &nn);
    section sec = SEC_NONE;
    for (int i = 1; i < SEC_COUNT; i++) {
        if (strlen(section_names[i]) == nn && memcmp(section_names[i], nm, nn) == 0)
            sec = (section)i;
    }
    if (nn > 3 && memcmp(nm, "fem", 3) == 0 && (nm[3] == ' ' || nm[3] == '\t'))
        return open_label_fem(p, nm + 4, nn - 4, cur);
    if (nn > 8 && memcmp(nm, "material", 8) == 0 && (nm[8] == ' ' || nm[8] == '\t'))
        return open_label_spring(p, nm + 9, nn - 9, cur);
    if (sec == SEC_NONE)
        return fail_at(p, p->line, FTM_EPARSE,
                       "unknown section [%.*s] (expected scene, mesh, material, material LABEL, "
                       "sim, load, fem, fem LABEL, volume or tool)",
                       shown(nn), nm);
    if (sec == SEC_LOAD) {
        if (sp->load_count >= SCENE_MAX_LOADS)
            return fail_at(p, p->line, FTM_ERANGE, "more than %d [load] sections",
                           SCENE_MAX_LOADS);
        load_spec *ls = push((void **)&sp->loads, &sp->load_count, &sp->load_cap, sizeof *ls);
        if (!ls)
            return fail_at(p, p->line, FTM_ENOMEM, "out of memory");
        ls->line = p->line;
        ls->load.contact.kind = FTM_CONTACT_FORCE;
        ls->load.release = INFINITY;
        ls->load.ramp = FTM_RAMP_CONSTANT;
    } else if (sp->section_line[sec]) {
        return fail_at(p, p->line, FTM_EPARSE, "duplicate section [%s] (first at line %d)",
                       section_names[sec], (int)sp->section_line[sec]);
    }
    sp->section_line[sec] = p->line;
    *cur = sec;
    return FTM_OK;
}

static int key_value(parser *p, const char *s, size_t n, section cur)
{
    spec *sp = &p->s;
    const char *eq = memchr(s, '=', n);
    if (!eq)
        return fail_at(p, p->line, FTM_EPARSE, "expected 'key = value' or '[section]', got '%.*s'",
                       shown(n), s);
    const char *kname = s, *v = eq + 1;
    size_t kn = (size_t)(eq - s), vn = n - kn - 1;
    trim(&kname, &kn);
    trim(&v, &vn);
    if (kn == 0)
        return fail_at(p, p->line, FTM_EPARSE, "missing key before '='");
    if (cur == SEC_NONE)
        return fail_at(p, p->line, FTM_EPARSE, "key '%.*s' outside a section", shown(kn), kname);
    if (cur == SEC_FEM_LABEL)
        return label_fem_key(p, kname, kn, v, vn);
    if (cur == SEC_MATERIAL_LABEL)
        return label_spring_key(p, kname, kn, v, vn);
    int k = -1;
    for (int i = 0; i < K_COUNT; i++) {
        if (key_table[i].sec == cur && strlen(key_table[i].name) == kn &&
            memcmp(key_table[i].name, kname, kn) == 0)
            k = i;
    }
    if (k < 0) {
        /* A known key in the wrong section gets a hint where it belongs. */
        for (int i = 0; i < K_COUNT; i++)
            if (strlen(key_table[i].name) == kn && memcmp(key_table[i].name, kname, kn) == 0)
                return fail_at(p, p->line, FTM_EPARSE,
                               "unknown key '%s' in [%s] (it belongs in [%s])", key_table[i].name,
                               section_names[cur], section_names[key_table[i].sec]);
        return fail_at(p, p->line, FTM_EPARSE, "unknown key '%.*s' in [%s]", shown(kn), kname,
                       section_names[cur]);
    }
    const char *name = key_table[k].name;
    if (vn == 0)
        return fail_at(p, p->line, FTM_EPARSE, "%s: missing value", name);

    int32_t *seen;
    if (cur == SEC_LOAD)
        seen = &sp->loads[sp->load_count - 1].key_line[k - K_NODE];
    else
        seen = &sp->key_line[k];
    if (*seen && !key_table[k].repeatable)
        return fail_at(p, p->line, FTM_EPARSE, "duplicate key '%s' (first at line %d)", name,
                       (int)*seen);
    int rc = cur == SEC_LOAD
                 ? set_load_key(p, &sp->loads[sp->load_count - 1], (key)k, name, v, vn)
                 : set_key(p, (key)k, name, v, vn);
    if (rc == FTM_OK)
        *seen = p->line;
    return rc;
}

static int parse_text(parser *p, const char *text, size_t length)
{
    ftm_text t;
    ftm_text_init(&t, p->name, text, length);
    const char *line;
    size_t n;
    section cur = SEC_NONE;
    while (ftm_text_next_line(&t, &line, &n)) {
        p->line = t.line;
        n = strip_comment(line, n);
        trim(&line, &n);
        if (n == 0)
            continue;
        int rc = line[0] == '[' ? open_section(p, line, n, &cur) : key_value(p, line, n, cur);
        if (rc != FTM_OK)
            return rc;
    }
    p->last_line = t.line > 0 ? t.line : 1;
    return FTM_OK;
}

/* ------------------------------------------------------- building */

/* Line to blame for a missing key: its section header, else the end of the text. */
static int32_t section_or_end(const parser *p, section sec)
{
    return p->s.section_line[sec] ? p->s.section_line[sec] : p->last_line;
}

/* [volume] goes with generator = volume, and gives an image one way. */
static int check_volume_keys(const parser *p)
{
    const spec *s = &p->s;
    const int32_t *kl = s->key_line;
    if (s->gen != GEN_VOLUME)
        return fail_at(p, s->section_line[SEC_VOLUME], FTM_EPARSE,
                       "[volume] is only used with [mesh] generator = volume");
    if (!s->section_line[SEC_VOLUME])
        return fail_at(p, kl[K_GENERATOR], FTM_EPARSE,
                       "the volume generator needs a [volume] section (file or phantom)");
    if (kl[K_VOLUME_FILE] && kl[K_PHANTOM])
        return fail_at(p, kl[K_PHANTOM], FTM_EPARSE,
                       "[volume] has both file (line %d) and phantom; give one",
                       (int)kl[K_VOLUME_FILE]);
    if (!kl[K_VOLUME_FILE] && !kl[K_PHANTOM])
        return fail_at(p, s->section_line[SEC_VOLUME], FTM_EPARSE,
                       "[volume] needs 'file = PATH' (NIfTI) or 'phantom = head'");
    static const key phantom_only[] = {K_VOXELS, K_SIZE},
                     file_only[] = {K_WINDOW, K_SCALE, K_AXES};
    for (size_t i = 0; i < sizeof phantom_only / sizeof *phantom_only; i++)
        if (kl[K_VOLUME_FILE] && kl[phantom_only[i]])
            return fail_at(p, kl[phantom_only[i]], FTM_EPARSE,
                           "%s is only used with a phantom (a file gives its own)",
                           key_table[phantom_only[i]].name);
    for (size_t i = 0; i < sizeof file_only / sizeof *file_only; i++)
        if (kl[K_PHANTOM] && kl[file_only[i]])
            return fail_at(p, kl[file_only[i]], FTM_EPARSE, "%s is only used with a file",
                           key_table[file_only[i]].name);
    return FTM_OK;
}

static int check_mesh_keys(const parser *p)
{
    const spec *s = &p->s;
    const int32_t *kl = s->key_line;
    if (kl[K_GENERATOR] && kl[K_FILE])
        return fail_at(p, kl[K_FILE], FTM_EPARSE,
                       "[mesh] has both generator (line %d) and file; give one",
                       (int)kl[K_GENERATOR]);
    if (!kl[K_GENERATOR] && !kl[K_FILE])
        return fail_at(p, section_or_end(p, SEC_MESH), FTM_EPARSE,
                       "[mesh] needs 'generator = lattice2d|lattice3d|volume' or 'file = PATH'");
    static const key lattice_keys[] = {K_NX, K_NY, K_NZ, K_SPACING, K_STENCIL, K_CLASS_SCALE,
                                       K_FIXED_FACES};
    for (size_t i = 0; i < sizeof lattice_keys / sizeof lattice_keys[0]; i++) {
        key k = lattice_keys[i];
        if (!kl[k])
            continue;
        if (s->gen == GEN_NONE)
            return fail_at(p, kl[k], FTM_EPARSE, "%s is only used with a generator%s",
                           key_table[k].name,
                           k == K_FIXED_FACES ? "; use fixed_nodes or fixed_box with a file" : "");
        if (s->gen == GEN_VOLUME)
            return fail_at(p, kl[k], FTM_EPARSE,
                           "%s is not used by the volume generator (its lattice is set in "
                           "[volume]%s)",
                           key_table[k].name,
                           k == K_FIXED_FACES ? ": fix = FACES"
                           : k == K_STENCIL   ? ": stencil"
                                              : "");
        bool only3d = k == K_NZ || k == K_STENCIL || k == K_CLASS_SCALE;
        if (s->gen == GEN_LATTICE2D && only3d)
            return fail_at(p, kl[k], FTM_EPARSE, "%s is not used by lattice2d", key_table[k].name);
    }
    if (s->gen == GEN_LATTICE2D) {
        if (s->spacing_count > 1)
            return fail_at(p, kl[K_SPACING], FTM_EPARSE,
                           "spacing: lattice2d takes a single spacing");
        if (s->fixed_faces & (FTM_FACE_ZMIN | FTM_FACE_ZMAX)) {
            if (s->fixed_faces != ALL_FACES) /* "all" means the four sides in 2D */
                return fail_at(p, kl[K_FIXED_FACES], FTM_EINVAL,
                               "fixed_faces: lattice2d has no zmin/zmax faces");
        }
    }
    if (s->gen == GEN_VOLUME || s->section_line[SEC_VOLUME])
        return check_volume_keys(p);
    if (s->gen != GEN_NONE) {
        static const key required[] = {K_NX, K_NY, K_NZ, K_SPACING};
        for (size_t i = 0; i < sizeof required / sizeof required[0]; i++) {
            key k = required[i];
            if (k == K_NZ && s->gen == GEN_LATTICE2D)
                continue;
            if (!kl[k])
                return fail_at(p, kl[K_GENERATOR], FTM_EPARSE, "%s generator needs %s",
                               s->gen == GEN_LATTICE2D ? "lattice2d" : "lattice3d",
                               key_table[k].name);
        }
        int64_t total = s->nx * s->ny * (s->gen == GEN_LATTICE3D ? s->nz : 1);
        if (total > SCENE_MAX_LATTICE_NODES)
            return fail_at(p, kl[K_GENERATOR], FTM_ERANGE,
                           "lattice of %lld nodes is larger than the limit of %lld",
                           (long long)total, (long long)SCENE_MAX_LATTICE_NODES);
    }
    return FTM_OK;
}

/* A path relative to the scene file's directory (*out NULL: path as given). */
static int scene_path(const parser *p, const char *file, int32_t line, char **out)
{
    *out = NULL;
    if (!p->base_dir || !p->base_dir[0] || file[0] == '/')
        return FTM_OK;
    size_t dl = strlen(p->base_dir), fl = strlen(file);
    bool slash = p->base_dir[dl - 1] == '/'; /* base "/" for "/x.scene" */
    char *joined = malloc(dl + fl + 2);
    if (!joined)
        return fail_at(p, line, FTM_ENOMEM, "out of memory");
    memcpy(joined, p->base_dir, dl);
    if (!slash)
        joined[dl++] = '/';
    memcpy(joined + dl, file, fl + 1);
    *out = joined;
    return FTM_OK;
}

/* The image of [volume] and its control lattice. point_input gets room for
 * every lattice point (volume.h). */
static int fill_volume(const parser *p, ftm_mesh_builder *b, ftm_volume **volume,
                       int32_t **point_input, ftm_error *sub)
{
    const spec *s = &p->s;
    int rc;
    if (s->volume_file) {
        char *joined = NULL;
        int32_t line = s->key_line[K_VOLUME_FILE];
        if ((rc = scene_path(p, s->volume_file, line, &joined)) != FTM_OK)
            return rc;
        rc = ftm_volume_load(joined ? joined : s->volume_file, &s->volume_load, volume, sub);
        free(joined);
        if (rc != FTM_OK)
            return fail_at(p, line, rc, "%s", sub->message[0] ? sub->message : ftm_strerror(rc));
    } else if ((rc = ftm_volume_phantom(&s->phantom, volume, sub)) != FTM_OK) {
        return fail_at(p, s->key_line[K_PHANTOM], rc, "%s", sub->message);
    }
    ftm_volume_lattice_def d = s->volume_lattice;
    d.material = s->material;
    const int32_t *n = d.nodes;
    *point_input = malloc((size_t)n[0] * n[1] * n[2] * sizeof **point_input);
    if (!*point_input)
        return fail_at(p, s->section_line[SEC_VOLUME], FTM_ENOMEM, "out of memory");
    rc = ftm_generate_volume_lattice(b, *volume, &d, *point_input, sub);
    if (rc != FTM_OK)
        return fail_at(p, s->section_line[SEC_VOLUME], rc, "%s", sub->message);
    return FTM_OK;
}

/* [volume] labels: a label map on the image's grid (the same voxels, voxel
 * size and box, within a hundredth of a voxel), read as the image is
 * (axes, origin, scale), for the client to colour the image by tissue. */
static int load_volume_labels(const parser *p, const ftm_volume *volume, ftm_label_map **out)
{
    const spec *s = &p->s;
    const int32_t line = s->key_line[K_VOLUME_LABELS];
    const char *what = s->volume_file ? s->volume_file : "the phantom";
    char *joined = NULL;
    int rc = scene_path(p, s->volume_labels_file, line, &joined);
    if (rc != FTM_OK)
        return rc;
    ftm_label_map_def d = ftm_default_label_map_def();
    if (s->volume_file) {
        d.axes = s->volume_load.axes;
        d.origin = s->volume_load.origin;
        d.scale = s->volume_load.scale;
    } else { /* the phantom's box starts at its origin, on the file's own axes */
        d.axes = FTM_VOLUME_AXES_STORED;
        d.origin = s->phantom.origin;
    }
    ftm_error sub;
    ftm_error_clear(&sub);
    rc = ftm_label_map_load(joined ? joined : s->volume_labels_file, &d, out, &sub);
    free(joined);
    if (rc != FTM_OK)
        return fail_at(p, line, rc, "labels: %s", sub.message[0] ? sub.message : ftm_strerror(rc));
    const ftm_volume_info a = ftm_label_map_get_info(*out), b = ftm_volume_get_info(volume);
    const char *file = s->volume_labels_file;
    if (a.nx != b.nx || a.ny != b.ny || a.nz != b.nz)
        return fail_at(p, line, FTM_EINVAL,
                       "labels: %s is %dx%dx%d voxels, the image (%s) %dx%dx%d: a label map "
                       "must be on the image's grid",
                       file, (int)a.nx, (int)a.ny, (int)a.nz, what, (int)b.nx, (int)b.ny,
                       (int)b.nz);
    const double as[3] = {a.spacing.x, a.spacing.y, a.spacing.z},
                 bs[3] = {b.spacing.x, b.spacing.y, b.spacing.z},
                 ao[3] = {a.origin.x, a.origin.y, a.origin.z},
                 bo[3] = {b.origin.x, b.origin.y, b.origin.z};
    const int32_t nv[3] = {b.nx, b.ny, b.nz};
    for (int i = 0; i < 3; i++) { /* the box's far end within a hundredth of a voxel too */
        if (!(fabs(as[i] - bs[i]) * nv[i] <= 0.01 * bs[i]))
            return fail_at(p, line, FTM_EINVAL,
                           "labels: %s has voxels of %g x %g x %g mm, the image (%s) %g x %g x "
                           "%g mm: a label map must be on the image's grid",
                           file, 1e3 * as[0], 1e3 * as[1], 1e3 * as[2], what, 1e3 * bs[0],
                           1e3 * bs[1], 1e3 * bs[2]);
        if (!(fabs(ao[i] - bo[i]) <= 0.01 * bs[i]))
            return fail_at(p, line, FTM_EINVAL,
                           "labels: %s's box starts at (%g, %g, %g) mm, the image's (%s) at "
                           "(%g, %g, %g) mm: a label map must be on the image's grid",
                           file, 1e3 * ao[0], 1e3 * ao[1], 1e3 * ao[2], what, 1e3 * bo[0],
                           1e3 * bo[1], 1e3 * bo[2]);
    }
    return FTM_OK;
}

/* Fills a builder with the generated or loaded mesh; for the volume
 * generator also the image and where each lattice point went. */
static int fill_builder(const parser *p, ftm_mesh_builder *b, ftm_volume **volume,
                        int32_t **point_input)
{
    const spec *s = &p->s;
    ftm_error sub;
    ftm_error_clear(&sub);
    int rc;
    int32_t line;
    if (s->gen == GEN_LATTICE2D) {
        ftm_lattice2d_def d = ftm_default_lattice2d_def();
        d.nx = (int32_t)s->nx;
        d.ny = (int32_t)s->ny;
        d.spacing = s->spacing[0];
        d.material = s->material;
        d.fixed_faces = s->fixed_faces & (FTM_FACE_XMIN | FTM_FACE_XMAX | FTM_FACE_YMIN |
                                          FTM_FACE_YMAX);
        rc = ftm_generate_lattice2d(b, &d, &sub);
        line = s->key_line[K_GENERATOR];
    } else if (s->gen == GEN_LATTICE3D) {
        ftm_lattice3d_def d = ftm_default_lattice3d_def();
        d.nx = (int32_t)s->nx;
        d.ny = (int32_t)s->ny;
        d.nz = (int32_t)s->nz;
        d.spacing = (ftm_vec3){s->spacing[0], s->spacing[1], s->spacing[2]};
        d.stencil = (ftm_stencil)s->stencil;
        d.material = s->material;
        memcpy(d.class_scale, s->class_scale, sizeof d.class_scale);
        d.fixed_faces = s->fixed_faces;
        rc = ftm_generate_lattice3d(b, &d, &sub);
        line = s->key_line[K_GENERATOR];
    } else if (s->gen == GEN_VOLUME) {
        return fill_volume(p, b, volume, point_input, &sub);
    } else {
        /* Relative paths are relative to the scene file's directory. */
        char *joined = NULL;
        if ((rc = scene_path(p, s->file, s->key_line[K_FILE], &joined)) != FTM_OK)
            return rc;
        rc = ftm_load_mesh(b, joined ? joined : s->file, &s->material, &sub);
        free(joined);
        line = s->key_line[K_FILE];
    }
    if (rc != FTM_OK)
        return fail_at(p, line, rc, "%s", sub.message[0] ? sub.message : ftm_strerror(rc));
    return FTM_OK;
}

static bool in_box(const fixed_box *b, ftm_vec3 x)
{
    return x.x >= b->lo[0] && x.x <= b->hi[0] && x.y >= b->lo[1] && x.y <= b->hi[1] &&
           x.z >= b->lo[2] && x.z <= b->hi[2];
}

/* fixed_nodes, fixed_label and fixed_box, on top of what the generator
 * fixed. Node indices were checked against the node count already; a label
 * that no element carries is an error (a typo would otherwise hold nothing). */
static int apply_fixed(const parser *p, ftm_mesh_builder *b)
{
    const spec *s = &p->s;
    for (size_t i = 0; i < s->fixed_node_count; i++)
        ftm_mesh_builder_set_fixed(b, (int32_t)s->fixed_nodes[i].input, true);
    for (size_t i = 0; i < s->fixed_label_count; i++)
        if (ftm_mesh_builder_fix_label(b, (int32_t)s->fixed_labels[i].input) == 0)
            return fail_at(p, s->fixed_labels[i].line, FTM_EINVAL,
                           "fixed_label: no element of the mesh has label %lld (%d tetrahedra, "
                           "%d hexahedra)",
                           (long long)s->fixed_labels[i].input,
                           (int)ftm_mesh_builder_tetrahedron_count(b),
                           (int)ftm_mesh_builder_hexahedron_count(b));
    if (!s->fixed_box_count)
        return FTM_OK;
    for (int32_t i = 0, n = ftm_mesh_builder_node_count(b); i < n; i++) {
        ftm_vec3 x;
        ftm_mesh_builder_node_position(b, i, &x);
        for (size_t j = 0; j < s->fixed_box_count; j++)
            if (in_box(&s->fixed_boxes[j], x))
                ftm_mesh_builder_set_fixed(b, i, true);
    }
    return FTM_OK;
}

/* One slide or ground spring on input node i (after apply_fixed): a node
 * is fixed or sliding, not both. */
static int constrain_node(const parser *p, ftm_mesh_builder *b, const bc_spec *c, int32_t i)
{
    static const char *const names[] = {[BC_SLIDE] = "slide_nodes",
                                        [BC_SLIDE_BOX] = "slide_box",
                                        [BC_GROUND] = "ground_springs",
                                        [BC_SLIDE_LABEL] = "slide_label",
                                        [BC_GROUND_LABEL] = "ground_label"};
    const char *kn = names[c->kind];
    const bool ground = c->kind == BC_GROUND || c->kind == BC_GROUND_LABEL;
    if (i >= ftm_mesh_builder_node_count(b))
        return fail_at(p, c->line, FTM_ERANGE, "%s: node %d out of range (mesh has %d nodes)", kn,
                       (int)i, (int)ftm_mesh_builder_node_count(b));
    if (ftm_mesh_builder_node_fixed(b, i))
        return fail_at(p, c->line, FTM_EINVAL,
                       "%s: node %d is fixed too (fixed_nodes, fixed_faces, fixed_label or "
                       "fixed_box): a node is fixed or %s, not both",
                       kn, (int)i, ground ? "on a spring to ground" : "sliding");
    int rc = ground
                 ? ftm_mesh_builder_add_ground_spring(b, i, c->k)
                 : ftm_mesh_builder_add_slide(b, i, (ftm_vec3){c->normal[0], c->normal[1],
                                                               c->normal[2]});
    if (rc == FTM_EINVAL && !ground)
        return fail_at(p, c->line, rc,
                       "%s: node %d would slide along no direction (three independent normals): "
                       "fix it instead",
                       kn, (int)i);
    if (rc != FTM_OK)
        return fail_at(p, c->line, rc, "%s: node %d: %s", kn, (int)i, ftm_strerror(rc));
    return FTM_OK;
}

/* slide_nodes, slide_box, ground_springs, slide_label and ground_label, in
 * the file's order. A node named by index that is fixed is refused; a box
 * or a label may hold fixed nodes, which stay fixed. */
static int apply_constraints(const parser *p, ftm_mesh_builder *b)
{
    const spec *s = &p->s;
    int rc = FTM_OK;
    for (size_t k = 0; rc == FTM_OK && k < s->bc_count; k++) {
        const bc_spec *c = &s->bcs[k];
        if (c->kind == BC_SLIDE || c->kind == BC_GROUND) {
            rc = constrain_node(p, b, c, c->input > INT32_MAX ? INT32_MAX : (int32_t)c->input);
            continue;
        }
        if (c->kind == BC_SLIDE_LABEL || c->kind == BC_GROUND_LABEL) {
            const int32_t n = ftm_mesh_builder_node_count(b);
            uint8_t *mark = calloc((size_t)n + 1, 1);
            if (!mark)
                return fail_at(p, c->line, FTM_ENOMEM, "out of memory");
            if (ftm_mesh_builder_label_nodes(b, (int32_t)c->input, mark) == 0)
                rc = fail_at(p, c->line, FTM_EINVAL,
                             "%s: no element of the mesh has label %lld (%d tetrahedra, %d "
                             "hexahedra)",
                             c->kind == BC_SLIDE_LABEL ? "slide_label" : "ground_label",
                             (long long)c->input, (int)ftm_mesh_builder_tetrahedron_count(b),
                             (int)ftm_mesh_builder_hexahedron_count(b));
            for (int32_t i = 0; rc == FTM_OK && i < n; i++)
                if (mark[i] && !ftm_mesh_builder_node_fixed(b, i)) /* fixed stays fixed */
                    rc = constrain_node(p, b, c, i);
            free(mark);
            continue;
        }
        int32_t hits = 0;
        for (int32_t i = 0, n = ftm_mesh_builder_node_count(b); rc == FTM_OK && i < n; i++) {
            ftm_vec3 x;
            ftm_mesh_builder_node_position(b, i, &x);
            if (in_box(&c->box, x)) { /* (a fixed node in it stays fixed) */
                if (!ftm_mesh_builder_node_fixed(b, i))
                    rc = constrain_node(p, b, c, i);
                hits++;
            }
        }
        if (rc == FTM_OK && hits == 0)
            return fail_at(p, c->line, FTM_EINVAL, "slide_box: no node lies in the box");
    }
    return rc;
}

static int apply_label_springs(const parser *p, ftm_mesh **m);

/* The mesh, and for the volume generator the image and its embedding. */
static int build_mesh(const parser *p, ftm_scene *scene)
{
    const spec *s = &p->s;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    if (!b)
        return fail_at(p, section_or_end(p, SEC_MESH), FTM_ENOMEM, "out of memory");
    int32_t *points = NULL; /* lattice point -> input index, then mesh node */
    ftm_mesh **out = &scene->mesh;
    int rc = fill_builder(p, b, &scene->volume, &points);
    if (rc == FTM_OK && s->volume_labels_file)
        rc = load_volume_labels(p, scene->volume, &scene->volume_labels);
    if (rc == FTM_OK) {
        int32_t n = ftm_mesh_builder_node_count(b);
        for (size_t i = 0; i < s->fixed_node_count; i++) {
            if (s->fixed_nodes[i].input >= n) {
                rc = fail_at(p, s->fixed_nodes[i].line, FTM_ERANGE,
                             "fixed_nodes: node %lld out of range (mesh has %d nodes)",
                             (long long)s->fixed_nodes[i].input, (int)n);
                break;
            }
        }
    }
    if (rc == FTM_OK)
        rc = apply_fixed(p, b);
    if (rc == FTM_OK)
        rc = apply_constraints(p, b);
    if (rc == FTM_OK) {
        ftm_error sub;
        ftm_error_clear(&sub);
        ftm_mesh_build_def bd = ftm_default_mesh_build_def();
        rc = ftm_mesh_build(b, &bd, out, &sub);
        if (rc != FTM_OK)
            rc = fail_at(p, section_or_end(p, SEC_MESH), rc, "%s", sub.message);
    }
    if (rc == FTM_OK)
        rc = apply_label_springs(p, out);
    if (rc == FTM_OK && s->gen == GEN_VOLUME) {
        const int32_t *n = s->volume_lattice.nodes;
        for (size_t i = 0, count = (size_t)n[0] * n[1] * n[2]; i < count; i++)
            points[i] = points[i] < 0 ? -1 : ftm_mesh_node_of_input(*out, points[i]);
        ftm_error sub;
        ftm_error_clear(&sub);
        rc = ftm_ffd_create(*out, scene->volume, n, points, &scene->ffd, &sub);
        if (rc != FTM_OK)
            rc = fail_at(p, s->section_line[SEC_VOLUME], rc, "%s", sub.message);
    }
    free(points);
    ftm_mesh_builder_destroy(b);
    return rc;
}

static int check_material(const parser *p)
{
    const spec *s = &p->s;
    if (!s->section_line[SEC_MATERIAL])
        return fail_at(p, p->last_line, FTM_EPARSE,
                       "missing [material] section (mass and stiffness are required)");
    if (!s->key_line[K_MASS])
        return fail_at(p, s->section_line[SEC_MATERIAL], FTM_EPARSE, "[material] needs mass");
    if (!s->key_line[K_STIFFNESS])
        return fail_at(p, s->section_line[SEC_MATERIAL], FTM_EPARSE,
                       "[material] needs stiffness");
    return FTM_OK;
}

/* [fem] is optional, but once given it needs both elastic constants. */
static int check_fem(const parser *p)
{
    const spec *s = &p->s;
    if (!s->section_line[SEC_FEM] && s->sim.forces != FTM_FORCES_SPRINGS)
        return fail_at(p, s->key_line[K_FORCES], FTM_EPARSE,
                       "element forces need a [fem] section (young, poisson, density)");
    if (!s->section_line[SEC_FEM])
        return FTM_OK;
    if (!s->key_line[K_YOUNG])
        return fail_at(p, s->section_line[SEC_FEM], FTM_EPARSE,
                       "[fem] needs young (Young's modulus in Pa)");
    if (!s->key_line[K_POISSON])
        return fail_at(p, s->section_line[SEC_FEM], FTM_EPARSE,
                       "[fem] needs poisson (Poisson's ratio)");
    return FTM_OK;
}

/* [fem LABEL]: beside a [fem] (the other elements' material), both
 * constants, and forces that honour them. Whether the mesh has the label is
 * checked once it is built (check_label_fems_in_mesh). */
static int check_label_fems(const parser *p)
{
    const spec *s = &p->s;
    if (s->label_fem_count == 0)
        return FTM_OK;
    const label_fem *first = &s->label_fems[0];
    if (!s->section_line[SEC_FEM])
        return fail_at(p, first->line, FTM_EPARSE,
                       "[fem %d] needs a [fem] section too: its material is that of the "
                       "elements of every other label, or none",
                       (int)first->mat.label);
    for (size_t i = 0; i < s->label_fem_count; i++) {
        const label_fem *lf = &s->label_fems[i];
        if (!lf->young_line)
            return fail_at(p, lf->line, FTM_EPARSE, "[fem %d] needs young (Young's modulus in Pa)",
                           (int)lf->mat.label);
        if (!lf->poisson_line)
            return fail_at(p, lf->line, FTM_EPARSE, "[fem %d] needs poisson (Poisson's ratio)",
                           (int)lf->mat.label);
    }
    for (size_t i = 0; i < s->label_fem_count; i++) {
        const label_fem *lf = &s->label_fems[i];
        if (lf->density_line && !(s->density > 0))
            return fail_at(p, lf->density_line, FTM_EPARSE,
                           "[fem %d]: a density per label needs [fem] density too (the other "
                           "elements' masses would be the mesh's node masses)",
                           (int)lf->mat.label);
    }
    return FTM_OK;
}

/* [material LABEL]: beside a [material] (the other elements' links), with
 * its stiffness. */
static int check_label_springs(const parser *p)
{
    const spec *s = &p->s;
    for (size_t i = 0; i < s->label_spring_count; i++)
        if (!s->label_springs[i].stiffness_line)
            return fail_at(p, s->label_springs[i].line, FTM_EPARSE,
                           "[material %d] needs stiffness", (int)s->label_springs[i].label);
    return FTM_OK;
}

/* A label carried by some element of the mesh. */
static bool mesh_has_label(const ftm_mesh *m, int32_t label)
{
    for (int32_t e = 0, n = ftm_mesh_hexahedron_count(m); e < n; e++)
        if (ftm_mesh_hexahedron_label(m, e) == label)
            return true;
    for (int32_t e = 0, n = ftm_mesh_tetrahedron_count(m); e < n; e++)
        if (ftm_mesh_tetrahedron_label(m, e) == label)
            return true;
    return false;
}

/* [material LABEL]: the links of the labels' elements take their
 * stiffness (ftm_mesh_with_label_stiffness, the factor the label's
 * stiffness over [material]'s), *m replaced by that mesh. */
static int apply_label_springs(const parser *p, ftm_mesh **m)
{
    const spec *s = &p->s;
    const size_t n = s->label_spring_count;
    if (n == 0)
        return FTM_OK;
    for (size_t i = 0; i < n; i++)
        if (!mesh_has_label(*m, s->label_springs[i].label))
            return fail_at(p, s->label_springs[i].line, FTM_EPARSE,
                           "[material %d]: no element of the mesh has label %d%s",
                           (int)s->label_springs[i].label, (int)s->label_springs[i].label,
                           ftm_mesh_has_labels(*m) ? "" : " (the mesh has no labels)");
    int32_t *labels = malloc(n * sizeof *labels);
    double *factor = malloc(n * sizeof *factor);
    int rc = labels && factor ? FTM_OK : FTM_ENOMEM;
    ftm_mesh *out = NULL;
    ftm_error sub;
    ftm_error_clear(&sub);
    if (rc == FTM_OK) {
        for (size_t i = 0; i < n; i++) {
            labels[i] = s->label_springs[i].label;
            factor[i] = s->label_springs[i].stiffness / s->material.stiffness;
        }
        rc = ftm_mesh_with_label_stiffness(*m, labels, factor, (int32_t)n, &out, &sub);
    }
    free(labels);
    free(factor);
    if (rc != FTM_OK)
        return fail_at(p, s->label_springs[0].line, rc, "%s",
                       sub.message[0] ? sub.message : "out of memory");
    ftm_mesh_destroy(*m);
    *m = out;
    return FTM_OK;
}

/* Every [fem LABEL] names a label some element of the mesh carries. */
static int check_label_fems_in_mesh(const parser *p, const ftm_mesh *m)
{
    const spec *s = &p->s;
    for (size_t i = 0; i < s->label_fem_count; i++) {
        const int32_t label = s->label_fems[i].mat.label;
        if (!mesh_has_label(m, label))
            return fail_at(p, s->label_fems[i].line, FTM_EPARSE,
                           "[fem %d]: no element of the mesh has label %d%s", (int)label,
                           (int)label,
                           ftm_mesh_has_labels(m) ? "" : " (the mesh has no labels)");
    }
    return FTM_OK;
}

/* Checks the times of every load (keys may come in any order, hence afterwards). */
static int check_load_times(const parser *p, load_spec *ls)
{
    ftm_scene_load *l = &ls->load;
    const int32_t *kl = ls->key_line;
    int32_t end_line = kl[K_END - K_NODE];
    if (!kl[K_NODE - K_NODE])
        return fail_at(p, ls->line, FTM_EPARSE, "[load] needs node");
    if (!kl[K_VALUE - K_NODE])
        return fail_at(p, ls->line, FTM_EPARSE, "[load] needs value");
    if (!end_line)
        l->end = l->start; /* only ramps use end */
    if (l->ramp != FTM_RAMP_CONSTANT) {
        if (!end_line)
            return fail_at(p, kl[K_RAMP - K_NODE], FTM_EPARSE, "a %s ramp needs end",
                           l->ramp == FTM_RAMP_LINEAR ? "linear" : "triangle");
        if (!(l->end > l->start))
            return fail_at(p, end_line, FTM_EINVAL, "end (%g) must be after start (%g)", l->end,
                           l->start);
    } else if (end_line && l->end < l->start) {
        return fail_at(p, end_line, FTM_EINVAL, "end (%g) must not be before start (%g)", l->end,
                       l->start);
    }
    int32_t rl = kl[K_RELEASE - K_NODE];
    if (rl && !(l->release > l->start))
        return fail_at(p, rl, FTM_EINVAL, "release (%g) must be after start (%g)", l->release,
                       l->start);
    return FTM_OK;
}

typedef struct load_key {
    int32_t node;
    double start, release;
    int32_t line;
} load_key;

static int compare_load_keys(const void *a, const void *b)
{
    const load_key *x = a, *y = b;
    if (x->node != y->node)
        return x->node < y->node ? -1 : 1;
    if (x->start != y->start)
        return x->start < y->start ? -1 : 1;
    return x->line < y->line ? -1 : x->line > y->line;
}

/* Resolves load targets to mesh indices and rejects fixed targets and two
 * loads on one node at the same time (the simulation takes one contact per node). */
static int resolve_loads(const parser *p, const ftm_mesh *mesh, ftm_scene_load *out)
{
    const spec *s = &p->s;
    int32_t n = ftm_mesh_node_count(mesh);
    for (size_t i = 0; i < s->load_count; i++) {
        const load_spec *ls = &s->loads[i];
        int32_t line = ls->key_line[0];
        int32_t node;
        if (ls->nearest) {
            node = ftm_mesh_nearest_node(mesh, ls->point);
            if (node < 0 || node >= n)
                return fail_at(p, line, FTM_ERANGE, "node: no node near (%g, %g, %g)",
                               ls->point.x, ls->point.y, ls->point.z);
        } else {
            if (ls->input >= n)
                return fail_at(p, line, FTM_ERANGE, "node %lld out of range (mesh has %d nodes)",
                               (long long)ls->input, (int)n);
            node = ftm_mesh_node_of_input(mesh, (int32_t)ls->input);
        }
        if (ftm_mesh_fixed(mesh, node))
            return fail_at(p, line, FTM_EINVAL, "node %d is fixed and cannot take a load",
                           (int)ftm_mesh_input_of_node(mesh, node));
        out[i] = ls->load;
        out[i].contact.node = node;
    }
    if (s->load_count < 2)
        return FTM_OK;
    load_key *keys = malloc(s->load_count * sizeof *keys);
    if (!keys)
        return fail_at(p, p->last_line, FTM_ENOMEM, "out of memory");
    for (size_t i = 0; i < s->load_count; i++)
        keys[i] = (load_key){out[i].contact.node, out[i].start, out[i].release,
                             s->loads[i].line};
    qsort(keys, s->load_count, sizeof *keys, compare_load_keys);
    /* Sorted by node, then start: a load overlaps an earlier one on the same
     * node iff it starts before the latest release seen so far on that node. */
    int rc = FTM_OK;
    size_t latest = 0; /* index in keys of the latest-releasing load on this node */
    for (size_t i = 1; i < s->load_count && rc == FTM_OK; i++) {
        if (keys[i].node != keys[latest].node) {
            latest = i;
            continue;
        }
        if (keys[i].start < keys[latest].release)
            rc = fail_at(p, keys[i].line, FTM_EINVAL,
                         "load on node %d overlaps in time with the load at line %d",
                         (int)ftm_mesh_input_of_node(mesh, keys[i].node), (int)keys[latest].line);
        else if (keys[i].release > keys[latest].release)
            latest = i;
    }
    free(keys);
    return rc;
}

/* Scene name from a file name: base name without its extension. */
static void default_name(const char *path, char out[SCENE_NAME_MAX])
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    size_t n = strlen(base);
    const char *dot = strrchr(base, '.');
    if (dot && dot != base)
        n = (size_t)(dot - base);
    if (n >= SCENE_NAME_MAX)
        n = SCENE_NAME_MAX - 1;
    memcpy(out, base, n);
    out[n] = '\0';
}

static void free_spec(spec *s)
{
    free(s->file);
    free(s->volume_file);
    free(s->volume_labels_file);
    free(s->fixed_nodes);
    free(s->fixed_boxes);
    free(s->fixed_labels);
    free(s->bcs);
    free(s->loads);
    free(s->label_fems);
    free(s->label_springs);
}

static int parse_scene(const char *text, size_t length, const char *name, const char *base_dir,
                       ftm_scene **out, ftm_error *err)
{
    if (!text || !out || !name)
        return ftm_error_set(err, FTM_EINVAL, "ftm_scene_parse: NULL argument");
    if (length > SCENE_MAX_BYTES)
        return ftm_error_set(err, FTM_ERANGE, "%s: scene larger than %zu bytes", name,
                             SCENE_MAX_BYTES);
    /* Values are handled as counted strings, but a NUL would still cut file paths short. */
    const char *nul = memchr(text, '\0', length);
    if (nul) {
        int32_t line = 1;
        for (const char *c = text; c < nul; c++)
            line += *c == '\n';
        return ftm_error_set(err, FTM_EPARSE, "%s:%d: NUL byte in scene text", name, (int)line);
    }
    parser p;
    memset(&p, 0, sizeof p);
    p.name = name;
    p.base_dir = base_dir;
    p.err = err;
    /* The format's own documented defaults, not the library's. */
    p.s.material = ftm_default_material_def();
    p.s.material.node_damping = 0;
    p.s.material.axis_scale = (ftm_vec3){1, 1, 1};
    p.s.sim = ftm_default_sim_def();
    p.s.sim.log = NULL;
    p.s.sim.log_user = NULL;
    p.s.steps = SCENE_DEFAULT_STEPS;
    p.s.stencil = SCENE_DEFAULT_STENCIL;
    p.s.class_scale[0] = p.s.class_scale[1] = p.s.class_scale[2] = 1;
    p.s.phantom = ftm_default_volume_phantom_def();
    p.s.volume_load = ftm_default_volume_load_def();
    p.s.volume_lattice = ftm_default_volume_lattice_def();
    default_name(name, p.s.name);

    ftm_scene *scene = NULL;
    int rc = parse_text(&p, text, length);
    if (rc == FTM_OK && !p.s.section_line[SEC_MESH])
        rc = fail_at(&p, p.last_line, FTM_EPARSE, "missing [mesh] section");
    if (rc == FTM_OK)
        rc = check_mesh_keys(&p);
    if (rc == FTM_OK)
        rc = check_material(&p);
    if (rc == FTM_OK)
        rc = check_fem(&p);
    if (rc == FTM_OK)
        rc = check_label_fems(&p);
    if (rc == FTM_OK)
        rc = check_label_springs(&p);
    for (size_t i = 0; rc == FTM_OK && i < p.s.load_count; i++)
        rc = check_load_times(&p, &p.s.loads[i]);
    if (rc == FTM_OK) {
        scene = calloc(1, sizeof *scene);
        if (!scene)
            rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", name);
    }
    if (rc == FTM_OK)
        rc = build_mesh(&p, scene);
    if (rc == FTM_OK)
        rc = check_label_fems_in_mesh(&p, scene->mesh);
    if (rc == FTM_OK && p.s.label_fem_count) {
        scene->label_materials = malloc(p.s.label_fem_count * sizeof *scene->label_materials);
        if (!scene->label_materials)
            rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", name);
        scene->label_names = malloc(p.s.label_fem_count * sizeof *scene->label_names);
        if (rc == FTM_OK && !scene->label_names)
            rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", name);
        for (size_t i = 0; rc == FTM_OK && i < p.s.label_fem_count; i++) {
            scene->label_materials[i] = p.s.label_fems[i].mat;
            memcpy(scene->label_names[i], p.s.label_fems[i].name, sizeof scene->label_names[i]);
        }
        scene->label_material_count = (int32_t)p.s.label_fem_count;
    }
    if (rc == FTM_OK && p.s.sim.forces != FTM_FORCES_SPRINGS &&
        ftm_mesh_hexahedron_count(scene->mesh) + ftm_mesh_tetrahedron_count(scene->mesh) == 0)
        rc = fail_at(&p, p.s.key_line[K_FORCES], FTM_EPARSE,
                     "element forces need hexahedra or tetrahedra (lattice3d, .msh or .node), "
                     "this mesh has none");
    if (rc == FTM_OK && p.s.load_count) {
        scene->loads = calloc(p.s.load_count, sizeof *scene->loads);
        if (!scene->loads)
            rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", name);
        else
            rc = resolve_loads(&p, scene->mesh, scene->loads);
    }
    if (rc == FTM_OK) {
        memcpy(scene->name, p.s.name, sizeof scene->name);
        scene->sim = p.s.sim;
        if (scene->sim.forces != FTM_FORCES_SPRINGS) { /* the [fem] material */
            scene->sim.young = p.s.young;
            scene->sim.poisson = p.s.poisson;
            scene->sim.density = p.s.density;
            scene->sim.label_materials = scene->label_materials;
            scene->sim.label_material_count = scene->label_material_count;
        }
        scene->steps = (int32_t)p.s.steps;
        scene->load_count = (int32_t)p.s.load_count;
        scene->has_fem = p.s.section_line[SEC_FEM] != 0;
        scene->material = p.s.material;
        scene->young = p.s.young;
        scene->poisson = p.s.poisson;
        scene->density = p.s.density;
        scene->tool = p.s.tool;
        *out = scene;
        scene = NULL;
    }
    ftm_scene_destroy(scene);
    free_spec(&p.s);
    return rc;
}

/* ------------------------------------------------------- public API */

int ftm_scene_parse(const char *text, size_t length, const char *name, ftm_scene **out,
                    ftm_error *err)
{
    return parse_scene(text, length, name, NULL, out, err);
}

int ftm_scene_load_file(const char *path, ftm_scene **out, ftm_error *err)
{
    if (!path || !out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_scene_load_file: NULL argument");
    char *data = NULL;
    size_t length = 0;
    int rc = ftm_text_read_file(path, SCENE_MAX_BYTES, &data, &length, err);
    if (rc != FTM_OK)
        return rc;
    /* Mesh files are looked up next to the scene file. */
    char *dir = NULL;
    const char *slash = strrchr(path, '/');
    if (slash) {
        size_t n = slash == path ? 1 : (size_t)(slash - path); /* "/x.scene" -> "/" */
        dir = malloc(n + 1);
        if (!dir) {
            free(data);
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
        }
        memcpy(dir, path, n);
        dir[n] = '\0';
    }
    rc = parse_scene(data, length, path, dir, out, err);
    free(dir);
    free(data);
    return rc;
}

int ftm_scene_open(const char *name_or_path, ftm_scene **out, ftm_error *err)
{
    if (!name_or_path || !out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_scene_open: NULL argument");
    if (ftm_scene_builtin_index(name_or_path) >= 0)
        return ftm_scene_builtin(name_or_path, out, err);
    /* A bare word that is no file was most likely meant as a built-in name. */
    FILE *f = fopen(name_or_path, "rb");
    if (!f && !strchr(name_or_path, '/') && !strchr(name_or_path, '.')) {
        char names[256];
        ftm_scene_builtin_list(names, sizeof names);
        return ftm_error_set(err, FTM_ENOENT,
                             "unknown scene '%s': not a built-in (%s) and no such file",
                             name_or_path, names);
    }
    if (f)
        fclose(f);
    return ftm_scene_load_file(name_or_path, out, err);
}

int ftm_scene_open_search(const char *name_or_path, const char *search, ftm_scene **out,
                          char *path, size_t path_cap, ftm_error *err)
{
    if (!name_or_path || !out || (path_cap && !path))
        return ftm_error_set(err, FTM_EINVAL, "ftm_scene_open_search: NULL argument");
    *out = NULL;
    if (path_cap)
        path[0] = '\0';
    FILE *f = NULL;
    if (ftm_scene_builtin_index(name_or_path) >= 0 || (f = fopen(name_or_path, "rb"))) {
        if (path_cap)
            snprintf(path, path_cap, "%s", name_or_path);
        if (!f)
            return ftm_scene_builtin(name_or_path, out, err);
        fclose(f);
        return ftm_scene_load_file(name_or_path, out, err);
    }
    const char *base = strrchr(name_or_path, '/');
    base = base ? base + 1 : name_or_path;
    /* the places tried, for the error; a long search list is cut with "..." */
    char tried[320];
    int used = snprintf(tried, sizeof tried, "%s", name_or_path);
    char cand[4096];
    for (const char *d = search; base[0] && d && *d;) {
        const char *end = strchr(d, ':');
        size_t len = end ? (size_t)(end - d) : strlen(d);
        if (len > 0 && len + strlen(base) + 2 <= sizeof cand) {
            memcpy(cand, d, len);
            snprintf(cand + len, sizeof cand - len, "/%s", base);
            if ((f = fopen(cand, "rb"))) {
                fclose(f);
                if (path_cap)
                    snprintf(path, path_cap, "%s", cand);
                return ftm_scene_load_file(cand, out, err);
            }
            if (used >= 0 && (size_t)used < sizeof tried)
                used += snprintf(tried + used, sizeof tried - (size_t)used, ", %s", cand);
        }
        d = end ? end + 1 : d + len;
    }
    if (used < 0 || (size_t)used >= sizeof tried)
        memcpy(tried + sizeof tried - 4, "...", 4);
    if (!search || !*search)
        return ftm_scene_open(name_or_path, out, err); /* its own message */
    char names[256];
    ftm_scene_builtin_list(names, sizeof names);
    return ftm_error_set(err, FTM_ENOENT, "scene '%s' not found: not a built-in (%s); tried %s",
                         name_or_path, names, tried);
}

void ftm_scene_destroy(ftm_scene *scene)
{
    if (!scene)
        return;
    ftm_mesh_destroy(scene->mesh);
    ftm_ffd_destroy(scene->ffd);
    ftm_volume_destroy(scene->volume);
    ftm_label_map_destroy(scene->volume_labels);
    free(scene->loads);
    free(scene->label_materials);
    free(scene->label_names);
    free(scene);
}

const char *ftm_scene_name(const ftm_scene *scene)
{
    return scene->name;
}

const ftm_mesh *ftm_scene_mesh(const ftm_scene *scene)
{
    return scene->mesh;
}

ftm_sim_def ftm_scene_sim_def(const ftm_scene *scene)
{
    return scene->sim;
}

ftm_material_def ftm_scene_material(const ftm_scene *scene) { return scene->material; }

int32_t ftm_scene_steps(const ftm_scene *scene)
{
    return scene->steps;
}

int32_t ftm_scene_load_count(const ftm_scene *scene)
{
    return scene->load_count;
}

const ftm_scene_load *ftm_scene_loads(const ftm_scene *scene)
{
    return scene->loads;
}

const ftm_label_material *ftm_scene_label_materials(const ftm_scene *scene, int32_t *count)
{
    if (count)
        *count = scene->label_material_count;
    return scene->label_materials;
}

const char *ftm_scene_label_name(const ftm_scene *scene, int32_t label)
{
    for (int32_t i = 0; i < scene->label_material_count; i++)
        if (scene->label_materials[i].label == label)
            return scene->label_names[i][0] ? scene->label_names[i] : NULL;
    return NULL;
}

bool ftm_scene_fem_material(const ftm_scene *scene, double *young, double *poisson,
                            double *density)
{
    if (!scene->has_fem)
        return false;
    if (young)
        *young = scene->young;
    if (poisson)
        *poisson = scene->poisson;
    if (density)
        *density = scene->density;
    return true;
}

const ftm_volume *ftm_scene_volume(const ftm_scene *scene)
{
    return scene->volume;
}

const ftm_ffd *ftm_scene_ffd(const ftm_scene *scene)
{
    return scene->ffd;
}

const ftm_label_map *ftm_scene_volume_labels(const ftm_scene *scene)
{
    return scene->volume_labels;
}

/* Fraction of the full value a load applies at time t (start <= t < release). */
static double ramp_factor(const ftm_scene_load *l, double t)
{
    switch (l->ramp) {
    case FTM_RAMP_LINEAR:
        if (t >= l->end)
            return 1.0;
        return (t - l->start) / (l->end - l->start);
    case FTM_RAMP_TRIANGLE: {
        double mid = l->start + 0.5 * (l->end - l->start);
        if (t >= l->end)
            return 0.0;
        if (t <= mid)
            return (t - l->start) / (mid - l->start);
        return (l->end - t) / (l->end - mid);
    }
    case FTM_RAMP_CONSTANT:
    default:
        return 1.0;
    }
}

int32_t ftm_scene_contacts_at(const ftm_scene *scene, double t, ftm_contact *contacts,
                              int32_t capacity)
{
    int32_t n = 0;
    for (int32_t i = 0; i < scene->load_count; i++) {
        const ftm_scene_load *l = &scene->loads[i];
        if (!(t >= l->start) || t >= l->release)
            continue;
        if (n < capacity) {
            double f = ramp_factor(l, t);
            ftm_contact c = l->contact;
            if (f != 1.0) { /* leave the full value bit-exact */
                c.value.x *= f;
                c.value.y *= f;
                c.value.z *= f;
            }
            contacts[n] = c;
        }
        n++;
    }
    return n;
}

ftm_scene_tool ftm_scene_get_tool(const ftm_scene *scene)
{
    return scene ? scene->tool : (ftm_scene_tool){0, 0, 0};
}
