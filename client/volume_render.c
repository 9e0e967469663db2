/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Embedded volume drawn as deformed, textured slices; see volume_render.h. */
#include "volume_render.h"

#include "render_gl.h"
#include "tissues.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SLICES_PER_CELL 10 /* a node plane and the 9 planes up to the next (paper 4.2) */
#define SUB 2              /* quads per lattice cell along each in-plane axis */
#define VFLOATS 10         /* position 3, texture coordinate 3, displacement 1, ray 3 */
/* Intensity of air: transparent below (the shader), and blocks with nothing
 * above it within a voxel get no quads. */
#define AIR 0.08
/* The slices are drawn at 1 / ds of the window's resolution, over the
 * rectangle their quads cover on screen, then scaled up over the window:
 * ds (1..DOWNSAMPLE_MAX) keeps the scale asked for (framebuffer pixels
 * per voxel), so that a volume drawn large costs what it costs small and
 * still shows every voxel. */
#define DOWNSAMPLE_MAX 16
#define REACH_MAX 4 /* blocks a slice's quads reach aside for its oblique rays */

/* The slices' shader, compiled in variants (llvmpipe runs a shader's every
 * line under lane masks, whether a branch is taken or not, so a variant
 * holds only what it draws): bit 0 the colour map, bit 1 a slice per
 * plane (one sample), bit 2 the cut-away's section, bit 3 the tissues'
 * colours from a label map (compiled when a volume with one is set). */
enum { VAR_MAP = 1, VAR_ONE = 2, VAR_SECTION = 4, VAR_LABELS = 8, VARIANTS = 16 };

typedef struct vol_prog {
    GLuint prog;
    GLint u_mvp, u_tex, u_depth, u_usedepth, u_air, u_full, u_eye;
    GLint u_planes, u_axis, u_tscale, u_voxels, u_spacing, u_trange, u_labels;
} vol_prog;

struct ftm_volume_render {
    vol_prog progs[VARIANTS]; /* (VAR_SECTION | VAR_ONE unused) */
    /* the slices are drawn into a framebuffer of 1 / ds the window's size
     * (over the part they cover), then blended over the window; the
     * window's depth is copied into a texture of the same size, which the
     * slices' shader reads */
    GLuint fbo, fbo_color, zfbo, fbo_depth, comp, comp_vao;
    GLint comp_tex, comp_origin, comp_scale;
    int fw, fh;
    bool depth_copy; /* the window's depth copies (false: a format it cannot copy) */
    GLuint vao, vbo, ibo, tex;
    GLuint ltex; /* the label map's tissue colours (A 1 where labelled), 0: none */

    const ftm_volume *vol;
    const ftm_ffd *ffd;
    int32_t n[3];      /* lattice points per axis */
    int32_t nodes;     /* the lattice mesh's node count */
    double lo[3], hi[3];   /* the lattice's rest box */
    double tlo[3], tsz[3]; /* the image's box (texture coordinates) */
    double voxel[3];       /* voxel size */
    int32_t nvox[3];       /* voxels per axis */
    float *u;          /* displacement of each lattice point, 3 each */
    /* blocks: the lattice's cells split SUB times along each axis */
    int32_t nb[3];
    uint8_t *occ;      /* per block (x fastest): tissue within a voxel of it */
    double olo[3], ohi[3]; /* the rest box of the blocks with tissue */

    /* the axis built: its planes (ns, gb x gc vertices each, in-plane axis
     * b = a + 1 fastest), the vertices of the planes drawn, their quads */
    int built;         /* -1: none */
    int32_t ns, gb, gc;
    float *verts;
    size_t verts_cap;
    uint8_t *used;     /* per vertex of the axis: in a quad drawn */
    GLuint *idx;
    size_t idx_cap;
    int8_t *dir;       /* per plane: +1 or -1 drawn (its slice samples that way), 0 not */
    double *centre;    /* per plane: its deformed centroid along the axis */
    double *key;
    int32_t *planes;   /* drawn, back to front */
    GLsizei *count;    /* per plane: indices */
    size_t *first;     /* per plane: first index */
    GLsizei *dcount;
    const void **doff;
    /* what the quads and vertices were made for */
    int quads_axis, quads_step, quads_reach;
    int32_t quads_up, quads_face;
    double verts_eye[3];
    bool dirty;        /* displacements or planes changed since the vertices */
    int32_t slices;    /* drawn last (before any: the most planes along an axis) */
};

/* v_ray: the ray from the eye through the vertex, in the rest space of the
 * image (the inverse of the deformation's Jacobian applied to it), so that
 * the fragment can step through the planes behind its slice. v_cz, v_dz:
 * clip-space z and w of the vertex and of the ray's direction in world
 * space, for the depth test of each sample (both linear across a
 * triangle). */
static const char *vol_vs =
    "layout(location=0) in vec3 a_pos;\n"
    "layout(location=1) in vec3 a_tex;\n"
    "layout(location=2) in float a_disp;\n"
    "layout(location=3) in vec3 a_ray;\n"
    "uniform mat4 u_mvp; uniform vec3 u_eye;\n"
    "uniform vec3 u_axis, u_tscale, u_voxels; uniform float u_spacing;\n"
    "out vec3 v_pos; out vec3 v_tex; out float v_disp; out vec3 v_ray;\n"
    "out vec2 v_cz, v_dz;\n"
    "out float v_density; out vec3 v_light;\n"
    "void main() {\n"
    "  v_pos = a_pos; v_tex = a_tex; v_disp = a_disp; v_ray = a_ray;\n"
    "  gl_Position = u_mvp * vec4(a_pos, 1.0);\n"
    "  v_cz = gl_Position.zw;\n"
    "  v_dz = (u_mvp * vec4(a_pos - u_eye, 0.0)).zw;\n"
    /* a slice per plane: the path to the next plane (in voxels) and the
     * head light's direction vary slowly across a slice, so per vertex */
    "  float ra = max(abs(dot(a_ray, u_axis)), 0.2 * length(a_ray));\n"
    "  v_density = length(a_ray * (u_spacing / ra) * u_tscale * u_voxels);\n"
    "  v_light = normalize(u_eye - a_pos);\n"
    "}\n";

/* Each slice stands for u_planes planes: its own and those behind it along
 * the ray through the fragment, composited front to back here and blended
 * as one (premultiplied) over the slices behind: the same samples, in the
 * same order, as drawing every plane, with fewer triangles to set up and
 * fragments to blend. The samples stop at the end of the lattice's box
 * along the axis and at the opaque parts (the window's depth, u_depth).
 * With a slice per plane (ONE) there is one sample, and the path and the
 * light come from the vertices. The transfer function, for intensities as
 * on CT or the phantom (air 0, soft tissue about 0.2 to 0.6, bone 1): air
 * transparent; low soft tissue a faint grey; the skin (about 0.45) a warm,
 * half-transparent shell; brain-like tissue pink and faint; hard tissue
 * white and the most opaque. Boundaries (a strong gradient) are more
 * opaque than the inside of a tissue, so the head reads as solid and the
 * structures inside show; they are lit by a head light, the gradient
 * standing for the normal. Opacities are per voxel and corrected for the
 * path between two planes along the ray, in voxels (density d):
 * 1 - (1 - a)^d by its series to a^2, for the opacities here (a <= 0.21)
 * within 0.6 % at d = 0.5..2 and 4 % at the steepest rays (d = 3.5). The
 * cut-away's section (SECTION) is the plane's intensity, opaque. */
static const char *vol_fs =
    "in vec3 v_pos; in vec3 v_tex; in float v_disp; in vec3 v_ray; in vec2 v_cz, v_dz;\n"
    "in float v_density; in vec3 v_light;\n"
    "uniform sampler3D u_tex; uniform sampler2D u_depth; uniform int u_usedepth;\n"
    "uniform float u_air, u_full;\n"
    "uniform vec3 u_eye; uniform int u_planes;\n"
    "uniform vec3 u_axis, u_tscale, u_voxels; uniform float u_spacing; uniform vec2 u_trange;\n"
    "out vec4 o_color;\n"
    FTM_GL_RAMP_GLSL
    /* a labelled voxel's tissue colour (nearest: no blend of two tissues)
     * in place of the intensity's; its opacity stays the intensity's */
    "#ifdef LABELS\n"
    "uniform sampler3D u_labels;\n"
    "vec3 tissue(vec3 c, vec3 t) { vec4 l = texture(u_labels, t); return mix(c, l.rgb, l.a); }\n"
    "#else\n"
    "#define tissue(c, t) (c)\n"
    "#endif\n"
    "vec3 base(float v) {\n"
    "  vec3 c = mix(vec3(0.55, 0.56, 0.62), vec3(0.96, 0.62, 0.42), smoothstep(0.12, 0.42, v));\n"
    "  c = mix(c, vec3(0.90, 0.50, 0.52), smoothstep(0.48, 0.58, v));\n"
    "  return mix(c, vec3(1.0, 0.96, 0.88), smoothstep(0.68, 0.95, v));\n"
    "}\n"
    /* a sample's colour (premultiplied), its opacity for the path d */
    "vec4 sample1(vec4 s, vec3 t, vec3 l, float density, float da, vec3 mapc, float map) {\n"
    "  float v = s.r;\n"
    "  vec3 g = s.gba - 0.5;\n"
    "  float gm = length(g);\n"
    "  float a = 0.05 * smoothstep(u_air, 0.40, v) + 0.16 * smoothstep(0.65, 1.0, v);\n"
    "  a *= mix(0.12, 1.0, smoothstep(0.02, 0.15, gm));\n"
    "#ifdef MAP\n"
    "  vec3 c = mix(tissue(base(v), t), mapc, map);\n"
    "#else\n"
    "  vec3 c = tissue(base(v), t);\n"
    "#endif\n"
    "  float dl = gm > 1e-4 ? abs(dot(g, l)) / gm : 1.0;\n"
    "  float d4 = dl * dl; d4 *= d4;\n"
    "  float d24 = d4 * d4; d24 *= d24 * d4 * d4;\n"
    "  c = c * mix(1.0, 0.4 + 0.6 * dl, smoothstep(0.01, 0.06, gm)) +\n"
    "      vec3(0.12 * d24 * smoothstep(0.02, 0.1, gm));\n"
    "  a = density * a * (1.0 - da * a);\n"
    "  return vec4(c * a, a);\n"
    "}\n"
    "void main() {\n"
    "  float map = 0.0; vec3 mapc = vec3(0.0);\n"
    "#ifdef MAP\n"
    "  float tm = v_disp / u_full;\n"
    "  mapc = ramp(tm); map = 0.85 * smoothstep(0.03, 0.25, tm);\n"
    "#endif\n"
    "#if defined(SECTION)\n"
    "  float v = texture(u_tex, v_tex).r;\n"
    "  if (v < u_air) discard;\n"
    "  vec3 c = tissue(mix(vec3(min(1.0, 1.15 * v)), base(v), 0.3), v_tex);\n"
    "  o_color = vec4(mix(c, mapc, map), 1.0);\n"
    "#elif defined(ONE)\n"
    "  if (u_usedepth != 0 &&\n"
    "      (2.0 * texelFetch(u_depth, ivec2(gl_FragCoord.xy), 0).r - 1.0) * v_cz.y <= v_cz.x)\n"
    "    discard;\n"
    "  vec4 s = texture(u_tex, v_tex);\n"
    "  if (s.r < u_air) discard;\n"
    "  o_color = sample1(s, v_tex, v_light, v_density, 0.5 * (v_density - 1.0), mapc, map);\n"
    "#else\n"
    /* one plane further along the ray: in texture coordinates, in voxels */
    "  float ra = max(abs(dot(v_ray, u_axis)), 0.2 * length(v_ray));\n"
    "  vec3 st = v_ray * (u_spacing / ra) * u_tscale;\n"
    "  float density = length(st * u_voxels);\n"
    /* the planes left before the box's end along the axis */
    "  float ta = dot(v_tex, u_axis), sa = dot(st, u_axis);\n"
    "  float left = sa > 0.0 ? (u_trange.y - ta) / sa : sa < 0.0 ? (u_trange.x - ta) / sa : 1e9;\n"
    "  int planes = min(u_planes, int(floor(left)) + 1);\n"
    /* and before the opaque parts: clip-space z - w zd along the ray is
     * linear in the plane count (the step in world space taken as the rest
     * space's) */
    "  if (u_usedepth != 0) {\n"
    "    float zd = 2.0 * texelFetch(u_depth, ivec2(gl_FragCoord.xy), 0).r - 1.0;\n"
    "    vec3 d = v_pos - u_eye;\n"
    "    float w = u_spacing / max(abs(dot(d, u_axis)), 0.2 * length(d));\n"
    "    float b = zd * v_cz.y - v_cz.x, g = w * (v_dz.x - zd * v_dz.y);\n"
    "    if (b <= 0.0) discard;\n"
    "    if (g > 0.0) planes = min(planes, int(ceil(b / g)));\n"
    "  }\n"
    "  vec3 l = normalize(u_eye - v_pos);\n"
    "  float da = 0.5 * (density - 1.0);\n"
    "  vec4 acc = vec4(0.0);\n"
    "  vec3 t = v_tex;\n"
    "  for (int k = 0; k < planes; k++, t += st) {\n"
    "    vec4 s = texture(u_tex, t);\n"
    "    if (s.r < u_air) continue;\n"
    "    acc += (1.0 - acc.a) * sample1(s, t, l, density, da, mapc, map);\n"
    "  }\n"
    "  if (acc.a <= 0.0) discard;\n"
    "  o_color = acc;\n"
    "#endif\n"
    "}\n";

/* The slices' framebuffer over the window: premultiplied colour, scaled up
 * (bilinear), a triangle over the window cut to the rectangle drawn. */
static const char *comp_vs =
    "#version 330 core\n"
    "void main() {\n"
    "  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));\n"
    "  gl_Position = vec4(2.0 * p - 1.0, 0.0, 1.0);\n"
    "}\n";

static const char *comp_fs =
    "#version 330 core\n"
    "uniform sampler2D u_tex; uniform vec2 u_origin, u_scale; out vec4 o_color;\n"
    "void main() { o_color = texture(u_tex, (gl_FragCoord.xy - u_origin) * u_scale); }\n";

/* Compiles variant `var` of the slices' shader into vr->progs[var]. */
static int compile_variant(ftm_volume_render *vr, int var, ftm_error *err)
{
    char head[128];
    snprintf(head, sizeof head, "#version 330 core\n%s%s%s%s", var & VAR_MAP ? "#define MAP\n" : "",
             var & VAR_ONE ? "#define ONE\n" : "", var & VAR_SECTION ? "#define SECTION\n" : "",
             var & VAR_LABELS ? "#define LABELS\n" : "");
    size_t hn = strlen(head), vn = strlen(vol_vs), fn = strlen(vol_fs);
    char *vs = malloc(hn + vn + 1), *fs = malloc(hn + fn + 1);
    if (!vs || !fs) {
        free(vs);
        free(fs);
        return ftm_gl_fail(err, "volume", "out of memory");
    }
    memcpy(vs, head, hn);
    memcpy(vs + hn, vol_vs, vn + 1);
    memcpy(fs, head, hn);
    memcpy(fs + hn, vol_fs, fn + 1);
    vol_prog *p = &vr->progs[var];
    p->prog = ftm_gl_program(vs, fs, "volume shader", err);
    free(vs);
    free(fs);
    if (!p->prog)
        return FTM_EINVAL;
    static const struct {
        const char *name;
        size_t at;
    } uni[] = {
        {"u_mvp", offsetof(vol_prog, u_mvp)},
        {"u_tex", offsetof(vol_prog, u_tex)},
        {"u_depth", offsetof(vol_prog, u_depth)},
        {"u_usedepth", offsetof(vol_prog, u_usedepth)},
        {"u_air", offsetof(vol_prog, u_air)},
        {"u_full", offsetof(vol_prog, u_full)},
        {"u_eye", offsetof(vol_prog, u_eye)},
        {"u_planes", offsetof(vol_prog, u_planes)},
        {"u_axis", offsetof(vol_prog, u_axis)},
        {"u_tscale", offsetof(vol_prog, u_tscale)},
        {"u_voxels", offsetof(vol_prog, u_voxels)},
        {"u_spacing", offsetof(vol_prog, u_spacing)},
        {"u_trange", offsetof(vol_prog, u_trange)},
        {"u_labels", offsetof(vol_prog, u_labels)},
    };
    for (size_t i = 0; i < sizeof uni / sizeof uni[0]; i++)
        *(GLint *)((char *)p + uni[i].at) = glGetUniformLocation(p->prog, uni[i].name);
    return FTM_OK;
}

static void delete_programs(ftm_volume_render *vr)
{
    for (int v = 0; v < VARIANTS; v++)
        if (vr->progs[v].prog)
            glDeleteProgram(vr->progs[v].prog);
    if (vr->comp)
        glDeleteProgram(vr->comp);
}

int ftm_volume_render_create(ftm_volume_render **out, ftm_error *err)
{
    ftm_volume_render *vr = calloc(1, sizeof *vr);
    if (!vr)
        return ftm_gl_fail(err, "volume", "out of memory");
    for (int v = 0; v < VAR_LABELS; v++) { /* the label variants when needed */
        if ((v & VAR_SECTION) && (v & VAR_ONE))
            continue;
        if (compile_variant(vr, v, err)) {
            delete_programs(vr);
            free(vr);
            return FTM_EINVAL;
        }
    }
    vr->comp = ftm_gl_program(comp_vs, comp_fs, "volume composite shader", err);
    if (!vr->comp) {
        delete_programs(vr);
        free(vr);
        return FTM_EINVAL;
    }
    vr->comp_tex = glGetUniformLocation(vr->comp, "u_tex");
    vr->comp_origin = glGetUniformLocation(vr->comp, "u_origin");
    vr->comp_scale = glGetUniformLocation(vr->comp, "u_scale");
    glGenVertexArrays(1, &vr->comp_vao);
    vr->depth_copy = true;
    glGenVertexArrays(1, &vr->vao);
    glGenBuffers(1, &vr->vbo);
    glGenBuffers(1, &vr->ibo);
    glBindVertexArray(vr->vao);
    glBindBuffer(GL_ARRAY_BUFFER, vr->vbo);
    static const int sizes[4] = {3, 3, 1, 3};
    for (int i = 0, at = 0; i < 4; at += sizes[i], i++) {
        glEnableVertexAttribArray((GLuint)i);
        glVertexAttribPointer((GLuint)i, sizes[i], GL_FLOAT, GL_FALSE, VFLOATS * sizeof(float),
                              (const void *)(uintptr_t)(at * sizeof(float)));
    }
    glBindVertexArray(0);
    vr->built = -1;
    *out = vr;
    return FTM_OK;
}

static void clear(ftm_volume_render *vr)
{
    if (vr->tex)
        glDeleteTextures(1, &vr->tex);
    if (vr->ltex)
        glDeleteTextures(1, &vr->ltex);
    vr->tex = vr->ltex = 0;
    void *arrays[] = {vr->u,      vr->occ,  vr->verts,  vr->used,  vr->idx,    vr->dir,
                      vr->centre, vr->key,  vr->planes, vr->count, vr->first, vr->dcount,
                      (void *)vr->doff};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; i++)
        free(arrays[i]);
    vr->u = vr->verts = NULL;
    vr->occ = vr->used = NULL;
    vr->idx = NULL;
    vr->dir = NULL;
    vr->centre = vr->key = NULL;
    vr->planes = NULL;
    vr->count = vr->dcount = NULL;
    vr->first = NULL;
    vr->doff = NULL;
    vr->verts_cap = vr->idx_cap = 0;
    vr->vol = NULL;
    vr->ffd = NULL;
    vr->built = -1;
}

void ftm_volume_render_destroy(ftm_volume_render *vr)
{
    if (!vr)
        return;
    clear(vr);
    glDeleteBuffers(1, &vr->vbo);
    glDeleteBuffers(1, &vr->ibo);
    glDeleteVertexArrays(1, &vr->vao);
    glDeleteVertexArrays(1, &vr->comp_vao);
    glDeleteFramebuffers(1, &vr->fbo);
    glDeleteFramebuffers(1, &vr->zfbo);
    glDeleteTextures(1, &vr->fbo_color);
    glDeleteTextures(1, &vr->fbo_depth);
    delete_programs(vr);
    free(vr);
}

bool ftm_volume_render_active(const ftm_volume_render *vr) { return vr && vr->vol && vr->ffd; }

int32_t ftm_volume_render_slices(const ftm_volume_render *vr)
{
    return ftm_volume_render_active(vr) ? vr->slices : 0;
}

/* Which blocks hold more than air, within a voxel of their faces (trilinear
 * filtering reaches that far); 1 per block, x fastest. */
static uint8_t *occupied_blocks(const ftm_volume_render *vr)
{
    const int32_t *nc = vr->nb;
    uint8_t *occ = calloc((size_t)nc[0] * nc[1] * nc[2], 1);
    if (!occ)
        return NULL;
    ftm_volume_info in = ftm_volume_get_info(vr->vol);
    const uint8_t *d = ftm_volume_data(vr->vol);
    const int32_t nv[3] = {in.nx, in.ny, in.nz};
    const uint8_t air = (uint8_t)(AIR * 255.0);
    /* per axis and voxel index: the range of blocks within a voxel of it */
    int32_t *range[3];
    for (int a = 0; a < 3; a++) {
        range[a] = malloc(2 * (size_t)nv[a] * sizeof **range);
        if (!range[a]) {
            for (int b = 0; b < a; b++)
                free(range[b]);
            free(occ);
            return NULL;
        }
        double span = vr->hi[a] - vr->lo[a];
        for (int32_t i = 0; i < nv[a]; i++) {
            double x = vr->tlo[a] + (i + 0.5) * vr->voxel[a];
            double f0 = (x - vr->voxel[a] - vr->lo[a]) / span * nc[a];
            double f1 = (x + vr->voxel[a] - vr->lo[a]) / span * nc[a];
            int32_t k0 = (int32_t)floor(f0), k1 = (int32_t)floor(f1);
            range[a][2 * i] = k0 < 0 ? 0 : k0 >= nc[a] ? nc[a] - 1 : k0;
            range[a][2 * i + 1] = k1 < 0 ? 0 : k1 >= nc[a] ? nc[a] - 1 : k1;
        }
    }
    for (int32_t k = 0; k < in.nz; k++)
        for (int32_t j = 0; j < in.ny; j++)
            for (int32_t i = 0; i < in.nx; i++) {
                if (d[i + (size_t)in.nx * (j + (size_t)in.ny * k)] < air)
                    continue;
                for (int32_t z = range[2][2 * k]; z <= range[2][2 * k + 1]; z++)
                    for (int32_t y = range[1][2 * j]; y <= range[1][2 * j + 1]; y++)
                        for (int32_t x = range[0][2 * i]; x <= range[0][2 * i + 1]; x++)
                            occ[x + (size_t)nc[0] * (y + (size_t)nc[1] * z)] = 1;
            }
    for (int a = 0; a < 3; a++)
        free(range[a]);
    return occ;
}

/* The texels: R the intensity, smoothed a little (half its own, half its 6
 * neighbours', so that a voxelised boundary shows fewer terraces), GBA its
 * gradient (central differences, intensity per voxel, + 0.5), the normal
 * of the shading and the boundaries' opacity: one texture fetch per
 * sample gives all four. */
static uint8_t *shading_texels(const ftm_volume *volume)
{
    ftm_volume_info in = ftm_volume_get_info(volume);
    const uint8_t *d = ftm_volume_data(volume);
    const int32_t n[3] = {in.nx, in.ny, in.nz};
    const size_t stride[3] = {1, (size_t)in.nx, (size_t)in.nx * in.ny};
    uint8_t *t = malloc(4 * stride[2] * in.nz);
    if (!t)
        return NULL;
    for (int32_t k = 0; k < in.nz; k++)
        for (int32_t j = 0; j < in.ny; j++)
            for (int32_t i = 0; i < in.nx; i++) {
                const int32_t at[3] = {i, j, k};
                size_t c = i + stride[1] * j + stride[2] * k;
                double sum = 0, g[3];
                for (int a = 0; a < 3; a++) { /* clamped at the box's faces */
                    double lo = d[at[a] > 0 ? c - stride[a] : c];
                    double hi = d[at[a] + 1 < n[a] ? c + stride[a] : c];
                    sum += lo + hi;
                    g[a] = 0.5 * (hi - lo) / 255.0;
                }
                uint8_t *o = t + 4 * c;
                o[0] = (uint8_t)lrint(0.5 * d[c] + sum / 12.0);
                for (int a = 0; a < 3; a++)
                    o[1 + a] = (uint8_t)lrint(255.0 * fmin(fmax(g[a] + 0.5, 0.0), 1.0));
            }
    return t;
}

/* The label map's texels: the tissue's colour (client/tissues.c, as the
 * surface's), alpha 255 where labelled (> 0), 0 where not (the intensity's
 * colour shows). */
static uint8_t *label_texels(const ftm_label_map *labels)
{
    ftm_volume_info in = ftm_label_map_get_info(labels);
    const int32_t *d = ftm_label_map_data(labels);
    const size_t n = (size_t)in.nx * in.ny * in.nz;
    uint8_t *t = calloc(4 * n, 1);
    if (!t)
        return NULL;
    for (size_t i = 0; i < n; i++) {
        if (d[i] <= 0)
            continue;
        float c[3];
        ftm_tissue_color(d[i], c);
        for (int k = 0; k < 3; k++)
            t[4 * i + k] = (uint8_t)lrintf(255.0f * c[k]);
        t[4 * i + 3] = 255;
    }
    return t;
}

/* Uploads the label map's colours (nearest: a voxel is one tissue), and
 * compiles the shader's label variants the first time. */
/* A new RGBA8 3D texture in *tex of nx x ny x nz texels, filtered by filter,
 * texels freed; what names it in the error (FTM_OK, or ftm_gl_fail's code). */
static int upload_rgba3d(GLuint *tex, int32_t nx, int32_t ny, int32_t nz, uint8_t *texels,
                         GLint filter, const char *what, ftm_error *err)
{
    glGenTextures(1, tex);
    glBindTexture(GL_TEXTURE_3D, *tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage3D(GL_TEXTURE_3D, 0, GL_RGBA8, nx, ny, nz, 0, GL_RGBA, GL_UNSIGNED_BYTE, texels);
    free(texels);
    ftm_gl_texture_params(GL_TEXTURE_3D, filter);
    glBindTexture(GL_TEXTURE_3D, 0);
    GLenum e = glGetError();
    if (e == GL_NO_ERROR)
        return FTM_OK;
    char msg[64];
    snprintf(msg, sizeof msg, "GL error 0x%x uploading %s", e, what);
    return ftm_gl_fail(err, "volume", msg);
}

static int set_labels(ftm_volume_render *vr, const ftm_label_map *labels, ftm_error *err)
{
    ftm_volume_info li = ftm_label_map_get_info(labels);
    if (li.nx != vr->nvox[0] || li.ny != vr->nvox[1] || li.nz != vr->nvox[2]) {
        char msg[160];
        snprintf(msg, sizeof msg, "label map of %dx%dx%d voxels on an image of %dx%dx%d",
                 (int)li.nx, (int)li.ny, (int)li.nz, (int)vr->nvox[0], (int)vr->nvox[1],
                 (int)vr->nvox[2]);
        return ftm_gl_fail(err, "volume", msg);
    }
    for (int v = VAR_LABELS; v < VARIANTS; v++)
        if (!((v & VAR_SECTION) && (v & VAR_ONE)) && !vr->progs[v].prog &&
            compile_variant(vr, v, err))
            return FTM_EINVAL;
    uint8_t *texels = label_texels(labels);
    if (!texels)
        return ftm_gl_fail(err, "volume", "out of memory");
    return upload_rgba3d(&vr->ltex, li.nx, li.ny, li.nz, texels, GL_NEAREST, "the label map", err);
}

int ftm_volume_render_set(ftm_volume_render *vr, const ftm_volume *volume, const ftm_ffd *ffd,
                          const ftm_label_map *labels, int32_t node_count, ftm_error *err)
{
    clear(vr);
    if (!volume || !ffd)
        return FTM_OK;
    vr->vol = volume;
    vr->ffd = ffd;
    vr->nodes = node_count;
    ftm_ffd_nodes(ffd, vr->n);
    if (vr->n[0] < 2 || vr->n[1] < 2 || vr->n[2] < 2) {
        clear(vr);
        return ftm_gl_fail(err, "volume", "a lattice of fewer than 2 points along an axis");
    }
    ftm_vec3 lo = ftm_ffd_point_rest(ffd, 0, 0, 0);
    ftm_vec3 hi = ftm_ffd_point_rest(ffd, vr->n[0] - 1, vr->n[1] - 1, vr->n[2] - 1);
    ftm_volume_info in = ftm_volume_get_info(volume);
    const double l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
    const double o[3] = {in.origin.x, in.origin.y, in.origin.z};
    const double sp[3] = {in.spacing.x, in.spacing.y, in.spacing.z};
    const int32_t nv[3] = {in.nx, in.ny, in.nz};
    int32_t most = 0, grid = 0;
    for (int a = 0; a < 3; a++) {
        vr->lo[a] = l[a];
        vr->hi[a] = h[a];
        vr->tlo[a] = o[a];
        vr->voxel[a] = sp[a];
        vr->nvox[a] = nv[a];
        vr->tsz[a] = nv[a] * sp[a];
        vr->nb[a] = (vr->n[a] - 1) * SUB;
        int32_t ns = (vr->n[a] - 1) * SLICES_PER_CELL + 1;
        int32_t g = ((vr->n[(a + 1) % 3] - 1) * SUB + 1) * ((vr->n[(a + 2) % 3] - 1) * SUB + 1);
        most = ns > most ? ns : most;
        grid = ns * g > grid ? ns * g : grid;
    }
    GLint max3d = 0;
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
    if (in.nx > max3d || in.ny > max3d || in.nz > max3d) {
        char msg[128];
        snprintf(msg, sizeof msg, "image of %dx%dx%d voxels: larger than this GL's 3D textures (%d)",
                 (int)in.nx, (int)in.ny, (int)in.nz, (int)max3d);
        clear(vr);
        return ftm_gl_fail(err, "volume", msg);
    }
    size_t npts = (size_t)vr->n[0] * vr->n[1] * vr->n[2];
    vr->slices = most;
    vr->u = calloc(3 * npts, sizeof *vr->u);
    vr->occ = occupied_blocks(vr);
    vr->used = calloc((size_t)grid, 1);
    vr->dir = calloc((size_t)most, sizeof *vr->dir);
    vr->centre = calloc((size_t)most, sizeof *vr->centre);
    vr->key = calloc((size_t)most, sizeof *vr->key);
    vr->planes = calloc((size_t)most, sizeof *vr->planes);
    vr->count = calloc((size_t)most, sizeof *vr->count);
    vr->first = calloc((size_t)most, sizeof *vr->first);
    vr->dcount = calloc((size_t)most, sizeof *vr->dcount);
    vr->doff = calloc((size_t)most, sizeof *vr->doff);
    uint8_t *texels = shading_texels(volume);
    if (!vr->u || !vr->occ || !vr->used || !vr->dir || !vr->centre || !vr->key || !vr->planes ||
        !vr->count || !vr->first || !vr->dcount || !vr->doff || !texels) {
        free(texels);
        clear(vr);
        return ftm_gl_fail(err, "volume", "out of memory");
    }
    /* the rest box of the blocks with tissue (the whole box if none) */
    int32_t bl[3] = {vr->nb[0], vr->nb[1], vr->nb[2]}, bh[3] = {-1, -1, -1};
    for (int32_t k = 0; k < vr->nb[2]; k++)
        for (int32_t j = 0; j < vr->nb[1]; j++)
            for (int32_t i = 0; i < vr->nb[0]; i++)
                if (vr->occ[i + (size_t)vr->nb[0] * (j + (size_t)vr->nb[1] * k)]) {
                    const int32_t at[3] = {i, j, k};
                    for (int a = 0; a < 3; a++) {
                        bl[a] = at[a] < bl[a] ? at[a] : bl[a];
                        bh[a] = at[a] > bh[a] ? at[a] : bh[a];
                    }
                }
    for (int a = 0; a < 3; a++) {
        bool none = bh[0] < 0;
        vr->olo[a] = vr->lo[a] + (vr->hi[a] - vr->lo[a]) * (none ? 0 : bl[a]) / vr->nb[a];
        vr->ohi[a] = vr->lo[a] + (vr->hi[a] - vr->lo[a]) * (none ? vr->nb[a] : bh[a] + 1) / vr->nb[a];
    }
    int rc = upload_rgba3d(&vr->tex, in.nx, in.ny, in.nz, texels, GL_LINEAR, "the image", err);
    if (rc) {
        clear(vr);
        return rc;
    }
    if (labels && (rc = set_labels(vr, labels, err)) != FTM_OK) {
        clear(vr);
        return rc;
    }
    vr->dirty = true;
    return FTM_OK;
}

void ftm_volume_render_update(ftm_volume_render *vr, const double *pos, int32_t node_count)
{
    if (!ftm_volume_render_active(vr))
        return;
    bool have = pos && node_count == vr->nodes;
    float *u = vr->u;
    for (int32_t iz = 0; iz < vr->n[2]; iz++)
        for (int32_t iy = 0; iy < vr->n[1]; iy++)
            for (int32_t ix = 0; ix < vr->n[0]; ix++, u += 3) {
                int32_t node = have ? ftm_ffd_point_node(vr->ffd, ix, iy, iz) : -1;
                if (node < 0 || node >= node_count) {
                    u[0] = u[1] = u[2] = 0;
                    continue;
                }
                ftm_vec3 r = ftm_ffd_point_rest(vr->ffd, ix, iy, iz);
                const double *p = pos + 3 * (size_t)node;
                u[0] = (float)(p[0] - r.x);
                u[1] = (float)(p[1] - r.y);
                u[2] = (float)(p[2] - r.z);
            }
    vr->dirty = true;
}

/* A lattice coordinate (in cells) as its cell and the place in it. */
static void locate(double t, int32_t n, int32_t *cell, double *f)
{
    int32_t i = (int32_t)floor(t);
    if (i > n - 2)
        i = n - 2;
    if (i < 0)
        i = 0;
    *cell = i;
    *f = t - i;
}

/* The vertices of the drawn planes perpendicular to axis a: the free-form
 * deformation of each rest point (the trilinear blend of its cell's corner
 * displacements, as ftm_ffd_map) and the ray from the eye taken back to the
 * rest space through the deformation's Jacobian there (J = I + du/dX; its
 * adjugate gives J^-1 up to the factor det J > 0), with the planes'
 * centroids along a. */
static int fill_vertices(ftm_volume_render *vr, int a, const double eye[3])
{
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    size_t nvert = (size_t)vr->ns * vr->gb * vr->gc;
    if (nvert * VFLOATS > vr->verts_cap) {
        float *q = realloc(vr->verts, nvert * VFLOATS * sizeof *q);
        if (!q)
            return -1;
        vr->verts = q;
        vr->verts_cap = nvert * VFLOATS;
    }
    const int32_t *n = vr->n;
    double cellsz[3];
    for (int k = 0; k < 3; k++)
        cellsz[k] = (vr->hi[k] - vr->lo[k]) / (n[k] - 1);
    for (int32_t s = 0; s < vr->ns; s++) {
        if (!vr->count[s])
            continue;
        float *o = vr->verts + (size_t)s * vr->gb * vr->gc * VFLOATS;
        double t[3], f[3], sum = 0;
        int32_t cell[3];
        t[a] = (double)s / SLICES_PER_CELL;
        locate(t[a], n[a], &cell[a], &f[a]);
        for (int32_t qc = 0; qc < vr->gc; qc++) {
            t[c] = (double)qc / SUB;
            locate(t[c], n[c], &cell[c], &f[c]);
            for (int32_t qb = 0; qb < vr->gb; qb++, o += VFLOATS) {
                t[b] = (double)qb / SUB;
                locate(t[b], n[b], &cell[b], &f[b]);
                double d[3] = {0, 0, 0}, J[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
                for (int corner = 0; corner < 8; corner++) {
                    int32_t p[3];
                    double w = 1, wd[3] = {1, 1, 1}; /* the weight, its derivatives */
                    for (int k = 0; k < 3; k++) {
                        int up = (corner >> k) & 1;
                        p[k] = cell[k] + up;
                        double wk = up ? f[k] : 1 - f[k], dk = (up ? 1.0 : -1.0) / cellsz[k];
                        for (int m = 0; m < 3; m++)
                            wd[m] *= m == k ? dk : wk;
                        w *= wk;
                    }
                    const float *u = vr->u + 3 * (p[0] + (size_t)n[0] * (p[1] + (size_t)n[1] * p[2]));
                    for (int i = 0; i < 3; i++) {
                        d[i] += w * u[i];
                        for (int m = 0; m < 3; m++)
                            J[i][m] += wd[m] * u[i];
                    }
                }
                double pos[3];
                for (int k = 0; k < 3; k++) {
                    double rest = vr->lo[k] + t[k] / (n[k] - 1) * (vr->hi[k] - vr->lo[k]);
                    pos[k] = rest + d[k];
                    o[k] = (float)pos[k];
                    o[3 + k] = (float)((rest - vr->tlo[k]) / vr->tsz[k]);
                }
                o[6] = (float)sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                /* adj(J) (pos - eye) */
                const double r[3] = {pos[0] - eye[0], pos[1] - eye[1], pos[2] - eye[2]};
                double adj[3][3];
                for (int i = 0; i < 3; i++)
                    for (int m = 0; m < 3; m++) {
                        int i1 = (m + 1) % 3, i2 = (m + 2) % 3, m1 = (i + 1) % 3, m2 = (i + 2) % 3;
                        adj[i][m] = J[i1][m1] * J[i2][m2] - J[i1][m2] * J[i2][m1];
                    }
                double det = J[0][0] * adj[0][0] + J[0][1] * adj[1][0] + J[0][2] * adj[2][0];
                for (int i = 0; i < 3; i++) {
                    double v = adj[i][0] * r[0] + adj[i][1] * r[1] + adj[i][2] * r[2];
                    o[7 + i] = (float)(det > 1e-6 ? v : r[i]); /* inverted or flat: the ray as is */
                }
                sum += o[a];
            }
        }
        vr->centre[s] = sum / ((double)vr->gb * vr->gc);
    }
    glBindBuffer(GL_ARRAY_BUFFER, vr->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(nvert * VFLOATS * sizeof(float)), vr->verts,
                 GL_STREAM_DRAW);
    return 0;
}

/* The blocks along axis a that planes p0..p1 touch (a plane on a block's
 * face touches both). */
static void block_span(const ftm_volume_render *vr, int a, int32_t p0, int32_t p1, int32_t *k0,
                       int32_t *k1)
{
    int32_t lo = p0 < p1 ? p0 : p1, hi = p0 < p1 ? p1 : p0;
    *k0 = (lo * SUB - 1) / SLICES_PER_CELL; /* (floors toward 0: -1 / 10 is 0) */
    *k1 = hi * SUB / SLICES_PER_CELL;
    *k1 = *k1 > vr->nb[a] - 1 ? vr->nb[a] - 1 : *k1;
}

/* The quads of the drawn planes (vr->dir) and the face: a slice's quad is
 * kept when a block of tissue lies within its slab (the step planes it
 * samples, along a) and reach blocks aside (where its oblique rays go);
 * the face's by its own plane. Marks the vertices used. */
static int build_quads(ftm_volume_render *vr, int a, int step, int reach, int32_t face)
{
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    size_t need = 0;
    for (int32_t s = 0; s < vr->ns; s++)
        need += vr->dir[s] || s == face ? (size_t)(vr->gb - 1) * (vr->gc - 1) * 6 : 0;
    if (need > vr->idx_cap) {
        GLuint *q = realloc(vr->idx, need * sizeof *q);
        if (!q)
            return -1;
        vr->idx = q;
        vr->idx_cap = need;
    }
    memset(vr->used, 0, (size_t)vr->ns * vr->gb * vr->gc);
    const size_t sx = 1, sy = (size_t)vr->nb[0], sz = (size_t)vr->nb[0] * vr->nb[1];
    const size_t stride[3] = {sx, sy, sz};
    size_t k = 0;
    for (int32_t s = 0; s < vr->ns; s++) {
        vr->first[s] = k;
        vr->count[s] = 0;
        if (!vr->dir[s] && s != face)
            continue;
        int32_t end = s == face && !vr->dir[s] ? s : s + vr->dir[s] * (step - 1);
        end = end < 0 ? 0 : end > vr->ns - 1 ? vr->ns - 1 : end;
        int32_t ka0, ka1;
        block_span(vr, a, s, end, &ka0, &ka1);
        int r = s == face && !vr->dir[s] ? 0 : reach;
        GLuint base = (GLuint)((size_t)s * vr->gb * vr->gc);
        for (int32_t qc = 0; qc + 1 < vr->gc; qc++)
            for (int32_t qb = 0; qb + 1 < vr->gb; qb++) {
                bool any = false;
                for (int32_t kc = qc - r; kc <= qc + r && !any; kc++)
                    for (int32_t kb = qb - r; kb <= qb + r && !any; kb++) {
                        if (kb < 0 || kc < 0 || kb >= vr->nb[b] || kc >= vr->nb[c])
                            continue;
                        size_t at = (size_t)kb * stride[b] + (size_t)kc * stride[c];
                        for (int32_t ka = ka0; ka <= ka1 && !any; ka++)
                            any = vr->occ[at + (size_t)ka * stride[a]];
                    }
                if (!any)
                    continue;
                GLuint v00 = base + (GLuint)(qb + vr->gb * qc), v10 = v00 + 1;
                GLuint v01 = v00 + (GLuint)vr->gb, v11 = v01 + 1;
                const GLuint q[6] = {v00, v10, v11, v00, v11, v01};
                memcpy(vr->idx + k, q, sizeof q);
                k += 6;
                vr->used[v00] = vr->used[v10] = vr->used[v01] = vr->used[v11] = 1;
            }
        vr->count[s] = (GLsizei)(k - vr->first[s]);
    }
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, vr->ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(k * sizeof *vr->idx), vr->idx,
                 GL_STATIC_DRAW);
    return 0;
}

/* The slices' framebuffer (colour) and the depth copy's, at least need_w x
 * need_h (grown in steps of 64 pixels, never shrunk); false when they
 * cannot be made. */
static bool framebuffer(ftm_volume_render *vr, int need_w, int need_h)
{
    if (vr->fbo && vr->fw >= need_w && vr->fh >= need_h)
        return true;
    int fw = need_w > vr->fw ? (need_w + 63) / 64 * 64 : vr->fw;
    int fh = need_h > vr->fh ? (need_h + 63) / 64 * 64 : vr->fh;
    if (!vr->fbo) {
        glGenFramebuffers(1, &vr->fbo);
        glGenFramebuffers(1, &vr->zfbo);
        glGenTextures(1, &vr->fbo_color);
        glGenTextures(1, &vr->fbo_depth);
    }
    /* 16 bits: a slice of faint tissue adds less than 8 bits resolve */
    glBindTexture(GL_TEXTURE_2D, vr->fbo_color);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA16, fw, fh, 0, GL_RGBA, GL_UNSIGNED_SHORT, NULL);
    ftm_gl_texture_params(GL_TEXTURE_2D, GL_LINEAR);
    /* the window's own depth format (GLFW's default), for the depth copy */
    glBindTexture(GL_TEXTURE_2D, vr->fbo_depth);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH24_STENCIL8, fw, fh, 0, GL_DEPTH_STENCIL,
                 GL_UNSIGNED_INT_24_8, NULL);
    ftm_gl_texture_params(GL_TEXTURE_2D, GL_NEAREST);
    glBindTexture(GL_TEXTURE_2D, 0);
    glBindFramebuffer(GL_FRAMEBUFFER, vr->fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, vr->fbo_color, 0);
    bool ok = glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
    glBindFramebuffer(GL_FRAMEBUFFER, vr->zfbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_TEXTURE_2D,
                           vr->fbo_depth, 0);
    ok = ok && glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    vr->fw = ok ? fw : 0;
    vr->fh = ok ? fh : 0;
    return ok;
}

/* The window's pixels the drawn quads cover ([x0, x1) x [y0, y1)); the
 * whole window when a vertex is behind the eye or not finite. False: none. */
static bool screen_rect(const ftm_volume_render *vr, const float m[16], int w, int h, double r[4])
{
    r[0] = r[1] = INFINITY;
    r[2] = r[3] = -INFINITY;
    const size_t per = (size_t)vr->gb * vr->gc;
    for (int32_t s = 0; s < vr->ns; s++) {
        if (!vr->count[s])
            continue;
        for (size_t i = (size_t)s * per; i < (size_t)(s + 1) * per; i++) {
            if (!vr->used[i])
                continue;
            const float *p = vr->verts + i * VFLOATS;
            double cx = (double)m[0] * p[0] + (double)m[4] * p[1] + (double)m[8] * p[2] + m[12];
            double cy = (double)m[1] * p[0] + (double)m[5] * p[1] + (double)m[9] * p[2] + m[13];
            double cw = (double)m[3] * p[0] + (double)m[7] * p[1] + (double)m[11] * p[2] + m[15];
            if (!(cw > 1e-9) || !isfinite(cx) || !isfinite(cy)) {
                r[0] = r[1] = 0;
                r[2] = w;
                r[3] = h;
                return true;
            }
            double px = (cx / cw * 0.5 + 0.5) * w, py = (cy / cw * 0.5 + 0.5) * h;
            r[0] = fmin(r[0], px);
            r[2] = fmax(r[2], px);
            r[1] = fmin(r[1], py);
            r[3] = fmax(r[3], py);
        }
    }
    r[0] = fmax(r[0], 0.0);
    r[1] = fmax(r[1], 0.0);
    r[2] = fmin(r[2], (double)w);
    r[3] = fmin(r[3], (double)h);
    return r[2] > r[0] && r[3] > r[1];
}

/* Which planes to draw (vr->dir): every step-th from the first beyond the
 * eye, away from it on both sides (each one's slice samples the step
 * planes behind it); a cut-away keeps the middle plane and those beyond it
 * from the eye, and draws the middle plane (*face; -1: none) as the
 * section. Returns the first plane beyond the eye along +a (at rest). */
static int32_t choose_planes(ftm_volume_render *vr, int a, const double e[3], bool cut, int step,
                             int32_t *face)
{
    const double span = vr->hi[a] - vr->lo[a], mid = 0.5 * (vr->lo[a] + vr->hi[a]);
    memset(vr->dir, 0, (size_t)vr->ns);
    double at = floor((e[a] - vr->lo[a]) / span * (vr->ns - 1)) + 1;
    int32_t up = at < 0 ? 0 : at > vr->ns ? vr->ns : (int32_t)at;
    int32_t from_up = up, from_down = up - 1;
    *face = -1;
    if (cut) {
        *face = (vr->ns - 1) / 2;
        if (e[a] >= mid) {
            from_up = vr->ns;
            from_down = *face < from_down ? *face : from_down;
        } else {
            from_down = -1;
            from_up = *face > from_up ? *face : from_up;
        }
    }
    for (int32_t s = from_up; s < vr->ns; s += step)
        vr->dir[s] = 1;
    for (int32_t s = from_down; s >= 0; s -= step)
        vr->dir[s] = -1;
    return up;
}

void ftm_volume_render_draw(ftm_volume_render *vr, const float mvp[16], ftm_vec3 eye, bool colormap,
                            bool cut, int step, double scale, double full, int w, int h)
{
    if (!ftm_volume_render_active(vr))
        return;
    /* the lattice axis most aligned with the view of the box's centre */
    const double e[3] = {eye.x, eye.y, eye.z};
    double dir[3];
    for (int k = 0; k < 3; k++)
        dir[k] = 0.5 * (vr->lo[k] + vr->hi[k]) - e[k];
    int a = 0;
    for (int k = 1; k < 3; k++)
        if (fabs(dir[k]) > fabs(dir[a]))
            a = k;
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    if (step < 1 || step > SLICES_PER_CELL)
        step = 1;
    if (vr->built != a) {
        vr->built = a;
        vr->ns = (vr->n[a] - 1) * SLICES_PER_CELL + 1;
        vr->gb = (vr->n[b] - 1) * SUB + 1;
        vr->gc = (vr->n[c] - 1) * SUB + 1;
        vr->quads_axis = -1;
    }
    const double spacing = (vr->hi[a] - vr->lo[a]) / (vr->ns - 1);
    /* how far aside a slice's rays go in its slab: the most oblique ray to
     * a corner of the tissue's box, at most 5 planes aside per plane deep
     * (the shader's limit too), in blocks */
    double slope = 0;
    for (int corner = 0; corner < 8; corner++) {
        double d[3];
        for (int k = 0; k < 3; k++)
            d[k] = ((corner >> k) & 1 ? vr->ohi[k] : vr->olo[k]) - e[k];
        double side = hypot(d[b], d[c]), along = fabs(d[a]);
        slope = fmax(slope, along > 0.2 * side ? side / along : 5.0);
    }
    double block = fmin((vr->hi[b] - vr->lo[b]) / vr->nb[b], (vr->hi[c] - vr->lo[c]) / vr->nb[c]);
    int reach = (int)ceil((step - 1) * spacing * slope / block - 1e-9);
    reach = reach < 0 ? 0 : reach > REACH_MAX ? REACH_MAX : reach;
    int32_t face = -1;
    int32_t up = choose_planes(vr, a, e, cut, step, &face);
    glBindVertexArray(vr->vao);
    if (vr->quads_axis != a || vr->quads_step != step || vr->quads_reach != reach ||
        vr->quads_up != up || vr->quads_face != face) {
        if (build_quads(vr, a, step, reach, face)) {
            vr->quads_axis = -1;
            glBindVertexArray(0);
            return;
        }
        vr->quads_axis = a;
        vr->quads_step = step;
        vr->quads_reach = reach;
        vr->quads_up = up;
        vr->quads_face = face;
        vr->dirty = true;
    }
    if (vr->dirty || memcmp(vr->verts_eye, e, sizeof e) != 0) {
        if (fill_vertices(vr, a, e)) {
            vr->quads_axis = -1;
            glBindVertexArray(0);
            return;
        }
        memcpy(vr->verts_eye, e, sizeof e);
        vr->dirty = false;
    }
    /* back to front: slices farther from the eye along the axis first */
    int32_t nd = 0;
    for (int32_t s = 0; s < vr->ns; s++) {
        if (!vr->dir[s] || !vr->count[s])
            continue;
        double k = fabs(vr->centre[s] - e[a]);
        int32_t j = nd++;
        for (; j > 0 && vr->key[j - 1] < k; j--) {
            vr->key[j] = vr->key[j - 1];
            vr->planes[j] = vr->planes[j - 1];
        }
        vr->key[j] = k;
        vr->planes[j] = s;
    }
    for (int32_t i = 0; i < nd; i++) {
        int32_t s = vr->planes[i];
        vr->dcount[i] = vr->count[s];
        vr->doff[i] = (const void *)(uintptr_t)(vr->first[s] * sizeof(GLuint));
    }
    vr->slices = nd;
    double box[4];
    if (!screen_rect(vr, mvp, w, h, box)) {
        glBindVertexArray(0);
        return;
    }
    /* ds: window pixels per framebuffer pixel (along each axis), so that
     * the framebuffer has `scale` pixels per voxel along the rectangle's
     * diagonal, taken as the tissue's box's; 1 (the window's resolution) to
     * DOWNSAMPLE_MAX */
    double vox = 0, diag = hypot(box[2] - box[0], box[3] - box[1]);
    for (int k = 0; k < 3; k++) {
        double nv = (vr->ohi[k] - vr->olo[k]) / vr->voxel[k];
        vox += nv * nv;
    }
    if (!(scale > 0) || !isfinite(scale))
        scale = FTM_VOLUME_SCALE_DEFAULT;
    double ds = diag / (sqrt(vox) * scale);
    ds = !(ds > 1) ? 1 : ds > DOWNSAMPLE_MAX ? DOWNSAMPLE_MAX : ds;
    /* the window's rectangle, with a framebuffer pixel of margin for the
     * bilinear scaling, drawn over rw x rh framebuffer pixels: a viewport
     * transform after mvp */
    int rect[4];
    rect[0] = (int)fmax(0.0, floor(box[0] - ds));
    rect[1] = (int)fmax(0.0, floor(box[1] - ds));
    rect[2] = (int)fmin((double)w, ceil(box[2] + ds));
    rect[3] = (int)fmin((double)h, ceil(box[3] + ds));
    const int rx = rect[2] - rect[0], ry = rect[3] - rect[1];
    int rw = (int)ceil(rx / ds), rh = (int)ceil(ry / ds);
    rw = rw < 1 ? 1 : rw > rx ? rx : rw;
    rh = rh < 1 ? 1 : rh > ry ? ry : rh;
    bool low = framebuffer(vr, rw, rh);
    float m[16];
    memcpy(m, mvp, sizeof m);
    if (low) {
        double sx = (double)w / rx, sy = (double)h / ry;
        double tx = (double)(w - 2 * rect[0]) / rx - 1, ty = (double)(h - 2 * rect[1]) / ry - 1;
        for (int col = 0; col < 4; col++) {
            m[4 * col] = (float)(sx * mvp[4 * col] + tx * mvp[4 * col + 3]);
            m[4 * col + 1] = (float)(sy * mvp[4 * col + 1] + ty * mvp[4 * col + 3]);
        }
    }
    /* a slice per plane: one sample */
    const bool one = step == 1;
    const int lab = vr->ltex ? VAR_LABELS : 0;
    const int var = (colormap ? VAR_MAP : 0) | (one ? VAR_ONE : 0) | lab;
    const vol_prog *progs[2] = {&vr->progs[var],
                                &vr->progs[(colormap ? VAR_MAP : 0) | VAR_SECTION | lab]};
    /* the planes' texture coordinates along a, a hair wider for rounding */
    double t0 = (vr->lo[a] - vr->tlo[a]) / vr->tsz[a], t1 = (vr->hi[a] - vr->tlo[a]) / vr->tsz[a];
    double eps = 1e-4 * (t1 - t0);
    for (int i = 0; i < 2; i++) {
        const vol_prog *p = progs[i];
        glUseProgram(p->prog);
        glUniformMatrix4fv(p->u_mvp, 1, GL_FALSE, m);
        glUniform1f(p->u_air, (float)AIR);
        glUniform1f(p->u_full, (float)(full > 0 ? full : 1e-3));
        glUniform3f(p->u_eye, (float)eye.x, (float)eye.y, (float)eye.z);
        glUniform1i(p->u_planes, step);
        glUniform3f(p->u_axis, a == 0 ? 1.0f : 0.0f, a == 1 ? 1.0f : 0.0f, a == 2 ? 1.0f : 0.0f);
        glUniform3f(p->u_tscale, (float)(1 / vr->tsz[0]), (float)(1 / vr->tsz[1]),
                    (float)(1 / vr->tsz[2]));
        glUniform3f(p->u_voxels, (float)vr->nvox[0], (float)vr->nvox[1], (float)vr->nvox[2]);
        glUniform1f(p->u_spacing, (float)spacing);
        glUniform2f(p->u_trange, (float)(t0 - eps), (float)(t1 + eps));
        glUniform1i(p->u_tex, 1);
        glUniform1i(p->u_depth, 2);
        glUniform1i(p->u_usedepth, low && vr->depth_copy ? 1 : 0);
        if (lab)
            glUniform1i(p->u_labels, 3);
    }
    if (lab) {
        glActiveTexture(GL_TEXTURE3);
        glBindTexture(GL_TEXTURE_3D, vr->ltex);
    }
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_3D, vr->tex);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA); /* premultiplied */
    if (low) {
        /* the opaque parts' depth, so that they hide what is behind them */
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, vr->zfbo);
        glClearDepth(1.0);
        glClear(GL_DEPTH_BUFFER_BIT);
        if (vr->depth_copy) {
            glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
            glBlitFramebuffer(rect[0], rect[1], rect[2], rect[3], 0, 0, rw, rh,
                              GL_DEPTH_BUFFER_BIT, GL_NEAREST);
            if (glGetError() != GL_NO_ERROR) /* another depth format, multisampling */
                vr->depth_copy = false;
        }
        glBindFramebuffer(GL_FRAMEBUFFER, vr->fbo);
        glViewport(0, 0, rw, rh);
        glClearColor(0, 0, 0, 0);
        glClear(GL_COLOR_BUFFER_BIT);
        glDisable(GL_DEPTH_TEST); /* the shader tests each sample */
        glActiveTexture(GL_TEXTURE2);
        glBindTexture(GL_TEXTURE_2D, vr->fbo_depth);
        glActiveTexture(GL_TEXTURE1);
    }
    glDepthMask(GL_FALSE);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, vr->ibo);
    glUseProgram(progs[0]->prog);
    if (nd)
        glMultiDrawElements(GL_TRIANGLES, vr->dcount, GL_UNSIGNED_INT, vr->doff, nd);
    /* a cut-away's face, the middle plane, last and opaque: the section
     * through the tissue, as a scan viewer shows it */
    if (face >= 0 && vr->count[face]) {
        glUseProgram(progs[1]->prog);
        glDrawElements(GL_TRIANGLES, vr->count[face], GL_UNSIGNED_INT,
                       (const void *)(uintptr_t)(vr->first[face] * sizeof(GLuint)));
    }
    glDepthMask(GL_TRUE);
    if (low) {
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        glViewport(0, 0, w, h);
        glEnable(GL_SCISSOR_TEST);
        glScissor(rect[0], rect[1], rect[2] - rect[0], rect[3] - rect[1]);
        glUseProgram(vr->comp);
        glBindTexture(GL_TEXTURE_2D, vr->fbo_color); /* (unit 1) */
        glUniform1i(vr->comp_tex, 1);
        glUniform2f(vr->comp_origin, (float)rect[0], (float)rect[1]);
        glUniform2f(vr->comp_scale, (float)rw / ((float)rx * (float)vr->fw),
                    (float)rh / ((float)ry * (float)vr->fh));
        glBindVertexArray(vr->comp_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glBindTexture(GL_TEXTURE_2D, 0);
        glActiveTexture(GL_TEXTURE2);
        glBindTexture(GL_TEXTURE_2D, 0);
        glActiveTexture(GL_TEXTURE1);
        glDisable(GL_SCISSOR_TEST);
        glEnable(GL_DEPTH_TEST);
    }
    glBindVertexArray(0);
    glDisable(GL_BLEND);
    if (lab) {
        glActiveTexture(GL_TEXTURE3);
        glBindTexture(GL_TEXTURE_3D, 0);
    }
    glActiveTexture(GL_TEXTURE0);
}
