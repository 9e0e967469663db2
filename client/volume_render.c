/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Embedded volume drawn as deformed, textured slices; see volume_render.h. */
#include "volume_render.h"

#include "render_gl.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SLICES_PER_CELL 10 /* a node plane and the 9 slices up to the next (paper 4.2) */
#define SUB 2              /* quads per lattice cell along each in-plane axis */
#define VFLOATS 7          /* position 3, texture coordinate 3, displacement 1 (ftm_gl_layout_331) */
/* Intensity of air: transparent below (the shader), and cells with nothing
 * above it within a voxel get no quads. */
#define AIR 0.08
/* The slices are drawn at 1 / DOWNSAMPLE of the window's resolution: a
 * software renderer's fill rate is the limit (~90 slices over the image),
 * and a 64-voxel image drawn 400 pixels wide loses nothing. */
#define DOWNSAMPLE 3

typedef struct slice_axis {
    int32_t ns, gb, gc; /* slices; vertices of a slice along its two in-plane axes */
    GLuint ibo;
    GLsizei *count;  /* per slice: indices */
    size_t *first;   /* per slice: first index */
} slice_axis;

struct ftm_volume_render {
    GLuint prog;
    GLint u_mvp, u_tex, u_air, u_density, u_usemap, u_full, u_eye, u_section;
    /* the slices are drawn into a framebuffer of 1 / DOWNSAMPLE the window's
     * size (with its depth), then blended over the window */
    GLuint fbo, fbo_color, fbo_depth, comp, comp_vao;
    GLint comp_tex;
    int fw, fh;
    bool depth_copy; /* the window's depth copies into it (false: not tested) */
    GLuint vao, vbo, tex;

    const ftm_volume *vol;
    const ftm_ffd *ffd;
    int32_t n[3];      /* lattice points per axis */
    int32_t nodes;     /* the lattice mesh's node count */
    double lo[3], hi[3];   /* the lattice's rest box */
    double tlo[3], tsz[3]; /* the image's box (texture coordinates) */
    double voxel[3];       /* voxel size */
    float *u;          /* displacement of each lattice point, 3 each */
    slice_axis ax[3];

    float *verts;      /* ns * gb * gc vertices of the axis built */
    size_t verts_cap;
    double *centre;    /* per slice: its deformed centroid along the axis */
    double *key;       /* per slice: its distance from the eye along the axis */
    int32_t *order;
    GLsizei *dcount;
    const void **doff;
    int built;         /* axis whose vertices are in vbo (-1: none) */
    int32_t slices;    /* of the axis drawn last (before any: the most along an axis) */
    bool dirty;        /* displacements changed since */
};

static const char *vol_vs =
    "#version 330 core\n"
    "layout(location=0) in vec3 a_pos;\n"
    "layout(location=1) in vec3 a_tex;\n"
    "layout(location=2) in float a_disp;\n"
    "uniform mat4 u_mvp;\n"
    "out vec3 v_pos; out vec3 v_tex; out float v_disp;\n"
    "void main() {\n"
    "  v_pos = a_pos; v_tex = a_tex; v_disp = a_disp;\n"
    "  gl_Position = u_mvp * vec4(a_pos, 1.0);\n"
    "}\n";

/* The transfer function, for intensities as on CT or the phantom (air 0,
 * soft tissue about 0.2 to 0.6, bone 1): air transparent; low soft tissue
 * a faint grey; the skin (about 0.45) a warm, half-transparent shell;
 * brain-like tissue pink and faint; hard tissue white and the most opaque.
 * Boundaries (a strong gradient) are more opaque than the inside of a
 * tissue, so the head reads as solid and the structures inside show;
 * they are lit by a head light, the gradient standing for the normal.
 * Opacities are per voxel and corrected for the slices' spacing
 * (u_density: the path through one slice, in voxels). */
static const char *vol_fs =
    "#version 330 core\n"
    "in vec3 v_pos; in vec3 v_tex; in float v_disp;\n"
    "uniform sampler3D u_tex; uniform float u_air, u_density, u_full; uniform int u_usemap;\n"
    "uniform vec3 u_eye; uniform int u_section;\n"
    "out vec4 o_color;\n"
    FTM_GL_RAMP_GLSL
    "void main() {\n"
    "  vec4 s = texture(u_tex, v_tex);\n"
    "  float v = s.r;\n"
    "  if (v < u_air) discard;\n"
    "  vec3 g = s.gba - 0.5;\n"
    "  float gm = length(g);\n"
    "  float a = 0.05 * smoothstep(u_air, 0.40, v) + 0.16 * smoothstep(0.65, 1.0, v);\n"
    "  a *= mix(0.12, 1.0, smoothstep(0.02, 0.15, gm));\n"
    "  vec3 c = mix(vec3(0.55, 0.56, 0.62), vec3(0.96, 0.62, 0.42), smoothstep(0.12, 0.42, v));\n"
    "  c = mix(c, vec3(0.90, 0.50, 0.52), smoothstep(0.48, 0.58, v));\n"
    "  c = mix(c, vec3(1.0, 0.96, 0.88), smoothstep(0.68, 0.95, v));\n"
    "  if (u_section != 0) c = mix(vec3(min(1.0, 1.15 * v)), c, 0.3);\n"
    "  if (u_usemap != 0) {\n"
    "    float t = v_disp / u_full;\n"
    "    c = mix(c, ramp(t), 0.85 * smoothstep(0.03, 0.25, t));\n"
    "  }\n"
    "  if (u_section != 0) { o_color = vec4(c, 1.0); return; }\n"
    "  vec3 l = normalize(u_eye - v_pos);\n"
    "  float d = gm > 1e-4 ? abs(dot(g / gm, l)) : 1.0;\n"
    "  float lit = 0.4 + 0.6 * d;\n"
    "  c = c * mix(1.0, lit, smoothstep(0.01, 0.06, gm)) + vec3(0.12 * pow(d, 24.0) * smoothstep(0.02, 0.1, gm));\n"
    "  o_color = vec4(c, 1.0 - pow(1.0 - a, u_density));\n"
    "}\n";

/* The slices' framebuffer over the window: premultiplied colour, scaled up
 * (bilinear) with a triangle that covers the window. */
static const char *comp_vs =
    "#version 330 core\n"
    "out vec2 v_uv;\n"
    "void main() {\n"
    "  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));\n"
    "  v_uv = p; gl_Position = vec4(2.0 * p - 1.0, 0.0, 1.0);\n"
    "}\n";

static const char *comp_fs =
    "#version 330 core\n"
    "in vec2 v_uv; uniform sampler2D u_tex; out vec4 o_color;\n"
    "void main() { o_color = texture(u_tex, v_uv); }\n";

int ftm_volume_render_create(ftm_volume_render **out, ftm_error *err)
{
    ftm_volume_render *vr = calloc(1, sizeof *vr);
    if (!vr)
        return ftm_gl_fail(err, "volume", "out of memory");
    vr->prog = ftm_gl_program(vol_vs, vol_fs, "volume shader", err);
    vr->comp = vr->prog ? ftm_gl_program(comp_vs, comp_fs, "volume composite shader", err) : 0;
    if (!vr->comp) {
        glDeleteProgram(vr->prog);
        free(vr);
        return FTM_EINVAL;
    }
    vr->comp_tex = glGetUniformLocation(vr->comp, "u_tex");
    glGenVertexArrays(1, &vr->comp_vao);
    vr->depth_copy = true;
    vr->u_mvp = glGetUniformLocation(vr->prog, "u_mvp");
    vr->u_tex = glGetUniformLocation(vr->prog, "u_tex");
    vr->u_air = glGetUniformLocation(vr->prog, "u_air");
    vr->u_density = glGetUniformLocation(vr->prog, "u_density");
    vr->u_usemap = glGetUniformLocation(vr->prog, "u_usemap");
    vr->u_full = glGetUniformLocation(vr->prog, "u_full");
    vr->u_section = glGetUniformLocation(vr->prog, "u_section");
    vr->u_eye = glGetUniformLocation(vr->prog, "u_eye");
    glGenVertexArrays(1, &vr->vao);
    glGenBuffers(1, &vr->vbo);
    glBindVertexArray(vr->vao);
    glBindBuffer(GL_ARRAY_BUFFER, vr->vbo);
    ftm_gl_layout_331();
    glBindVertexArray(0);
    vr->built = -1;
    *out = vr;
    return FTM_OK;
}

static void clear(ftm_volume_render *vr)
{
    for (int a = 0; a < 3; a++) {
        if (vr->ax[a].ibo)
            glDeleteBuffers(1, &vr->ax[a].ibo);
        free(vr->ax[a].count);
        free(vr->ax[a].first);
    }
    memset(vr->ax, 0, sizeof vr->ax);
    if (vr->tex)
        glDeleteTextures(1, &vr->tex);
    vr->tex = 0;
    free(vr->u);
    free(vr->verts);
    free(vr->centre);
    free(vr->key);
    free(vr->order);
    free(vr->dcount);
    free(vr->doff);
    vr->u = vr->verts = NULL;
    vr->centre = vr->key = NULL;
    vr->order = NULL;
    vr->dcount = NULL;
    vr->doff = NULL;
    vr->verts_cap = 0;
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
    glDeleteVertexArrays(1, &vr->vao);
    glDeleteVertexArrays(1, &vr->comp_vao);
    glDeleteFramebuffers(1, &vr->fbo);
    glDeleteTextures(1, &vr->fbo_color);
    glDeleteRenderbuffers(1, &vr->fbo_depth);
    glDeleteProgram(vr->prog);
    glDeleteProgram(vr->comp);
    free(vr);
}

bool ftm_volume_render_active(const ftm_volume_render *vr) { return vr && vr->vol && vr->ffd; }

int32_t ftm_volume_render_slices(const ftm_volume_render *vr)
{
    return ftm_volume_render_active(vr) ? vr->slices : 0;
}

/* Which blocks hold more than air, within a voxel of their faces (trilinear
 * filtering reaches that far): the lattice's cells split SUB times along
 * each axis (a slice's quads, SUB slabs of slices); 1 per block, x fastest. */
static uint8_t *occupied_blocks(const ftm_volume_render *vr)
{
    const int32_t c0 = (vr->n[0] - 1) * SUB, c1 = (vr->n[1] - 1) * SUB, c2 = (vr->n[2] - 1) * SUB;
    uint8_t *occ = calloc((size_t)c0 * c1 * c2, 1);
    if (!occ)
        return NULL;
    ftm_volume_info in = ftm_volume_get_info(vr->vol);
    const uint8_t *d = ftm_volume_data(vr->vol);
    const int32_t nv[3] = {in.nx, in.ny, in.nz}, nc[3] = {c0, c1, c2};
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
                            occ[x + (size_t)c0 * (y + (size_t)c1 * z)] = 1;
            }
    for (int a = 0; a < 3; a++)
        free(range[a]);
    return occ;
}

/* The index buffer of the slices perpendicular to axis a: slice s is
 * vertices s * gb * gc .. (a grid, in-plane axis b = a + 1 fastest, then
 * c = a + 2), its quads over occupied cells. */
static int build_axis(ftm_volume_render *vr, int a, const uint8_t *occ)
{
    slice_axis *x = &vr->ax[a];
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    x->ns = (vr->n[a] - 1) * SLICES_PER_CELL + 1;
    x->gb = (vr->n[b] - 1) * SUB + 1;
    x->gc = (vr->n[c] - 1) * SUB + 1;
    size_t quads = (size_t)(x->gb - 1) * (x->gc - 1);
    GLuint *idx = malloc((size_t)x->ns * quads * 6 * sizeof *idx + 1);
    x->count = calloc((size_t)x->ns, sizeof *x->count);
    x->first = calloc((size_t)x->ns, sizeof *x->first);
    if (!idx || !x->count || !x->first) {
        free(idx);
        return -1;
    }
    const int32_t c0 = (vr->n[0] - 1) * SUB, c1 = (vr->n[1] - 1) * SUB;
    size_t k = 0;
    for (int32_t s = 0; s < x->ns; s++) {
        x->first[s] = k;
        /* the block along a the slice lies in; on a block's face, in two */
        int32_t ka = s * SUB / SLICES_PER_CELL, kprev = ka - 1;
        if (ka > (vr->n[a] - 1) * SUB - 1)
            ka = (vr->n[a] - 1) * SUB - 1;
        if ((s * SUB) % SLICES_PER_CELL != 0 || kprev < 0)
            kprev = ka;
        GLuint base = (GLuint)((size_t)s * x->gb * x->gc);
        for (int32_t qc = 0; qc + 1 < x->gc; qc++)
            for (int32_t qb = 0; qb + 1 < x->gb; qb++) {
                int32_t cell[3], prev[3];
                cell[a] = ka, prev[a] = kprev;
                cell[b] = prev[b] = qb;
                cell[c] = prev[c] = qc;
                if (!occ[cell[0] + (size_t)c0 * (cell[1] + (size_t)c1 * cell[2])] &&
                    !occ[prev[0] + (size_t)c0 * (prev[1] + (size_t)c1 * prev[2])])
                    continue;
                GLuint v00 = base + (GLuint)(qb + x->gb * qc), v10 = v00 + 1;
                GLuint v01 = v00 + (GLuint)x->gb, v11 = v01 + 1;
                const GLuint q[6] = {v00, v10, v11, v00, v11, v01};
                memcpy(idx + k, q, sizeof q);
                k += 6;
            }
        x->count[s] = (GLsizei)(k - x->first[s]);
    }
    glGenBuffers(1, &x->ibo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, x->ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(k * sizeof *idx), idx, GL_STATIC_DRAW);
    free(idx);
    return 0;
}

/* The texels: R the intensity, smoothed a little (half its own, half its 6
 * neighbours', so that a voxelised boundary shows fewer terraces), GBA its
 * gradient (central differences, intensity per voxel, + 0.5), the normal
 * of the shading and the boundaries' opacity: one texture fetch per
 * fragment gives all four. */
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

int ftm_volume_render_set(ftm_volume_render *vr, const ftm_volume *volume, const ftm_ffd *ffd,
                          int32_t node_count, ftm_error *err)
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
    for (int a = 0; a < 3; a++) {
        vr->lo[a] = l[a];
        vr->hi[a] = h[a];
        vr->tlo[a] = o[a];
        vr->voxel[a] = sp[a];
        vr->tsz[a] = nv[a] * sp[a];
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
    int32_t most = 0;
    uint8_t *occ = occupied_blocks(vr);
    vr->u = calloc(3 * npts, sizeof *vr->u);
    bool ok = occ && vr->u;
    glBindVertexArray(vr->vao); /* (the index buffers are bound to a vertex array) */
    for (int a = 0; a < 3 && ok; a++) {
        ok = build_axis(vr, a, occ) == 0;
        if (ok && vr->ax[a].ns > most)
            most = vr->ax[a].ns;
    }
    vr->slices = most;
    glBindVertexArray(0);
    free(occ);
    if (ok) {
        vr->centre = calloc((size_t)most, sizeof *vr->centre);
        vr->key = calloc((size_t)most, sizeof *vr->key);
        vr->order = calloc((size_t)most, sizeof *vr->order);
        vr->dcount = calloc((size_t)most, sizeof *vr->dcount);
        vr->doff = calloc((size_t)most, sizeof *vr->doff);
        ok = vr->centre && vr->key && vr->order && vr->dcount && vr->doff;
    }
    if (!ok) {
        clear(vr);
        return ftm_gl_fail(err, "volume", "out of memory");
    }
    uint8_t *texels = shading_texels(volume);
    if (!texels) {
        clear(vr);
        return ftm_gl_fail(err, "volume", "out of memory");
    }
    glGenTextures(1, &vr->tex);
    glBindTexture(GL_TEXTURE_3D, vr->tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage3D(GL_TEXTURE_3D, 0, GL_RGBA8, in.nx, in.ny, in.nz, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                 texels);
    free(texels);
    ftm_gl_texture_params(GL_TEXTURE_3D, GL_LINEAR);
    glBindTexture(GL_TEXTURE_3D, 0);
    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        char msg[64];
        snprintf(msg, sizeof msg, "GL error 0x%x uploading the image", e);
        clear(vr);
        return ftm_gl_fail(err, "volume", msg);
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

/* The vertices of every slice perpendicular to axis a: the free-form
 * deformation of each rest point (the trilinear blend of its cell's corner
 * displacements, as ftm_ffd_map), with the slices' centroids along a. */
static int fill_axis(ftm_volume_render *vr, int a)
{
    const slice_axis *x = &vr->ax[a];
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    size_t nvert = (size_t)x->ns * x->gb * x->gc;
    if (nvert * VFLOATS > vr->verts_cap) {
        float *q = realloc(vr->verts, nvert * VFLOATS * sizeof *q);
        if (!q)
            return -1;
        vr->verts = q;
        vr->verts_cap = nvert * VFLOATS;
    }
    const int32_t *n = vr->n;
    float *o = vr->verts;
    for (int32_t s = 0; s < x->ns; s++) {
        double t[3], f[3], sum = 0;
        int32_t cell[3];
        t[a] = (double)s / SLICES_PER_CELL;
        locate(t[a], n[a], &cell[a], &f[a]);
        for (int32_t qc = 0; qc < x->gc; qc++) {
            t[c] = (double)qc / SUB;
            locate(t[c], n[c], &cell[c], &f[c]);
            for (int32_t qb = 0; qb < x->gb; qb++, o += VFLOATS) {
                t[b] = (double)qb / SUB;
                locate(t[b], n[b], &cell[b], &f[b]);
                double d[3] = {0, 0, 0};
                for (int corner = 0; corner < 8; corner++) {
                    int32_t p[3];
                    double w = 1;
                    for (int k = 0; k < 3; k++) {
                        int up = (corner >> k) & 1;
                        p[k] = cell[k] + up;
                        w *= up ? f[k] : 1 - f[k];
                    }
                    if (w == 0)
                        continue;
                    const float *u = vr->u + 3 * (p[0] + (size_t)n[0] * (p[1] + (size_t)n[1] * p[2]));
                    d[0] += w * u[0];
                    d[1] += w * u[1];
                    d[2] += w * u[2];
                }
                for (int k = 0; k < 3; k++) {
                    double rest = vr->lo[k] + t[k] / (n[k] - 1) * (vr->hi[k] - vr->lo[k]);
                    o[k] = (float)(rest + d[k]);
                    o[3 + k] = (float)((rest - vr->tlo[k]) / vr->tsz[k]);
                }
                o[6] = (float)sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                sum += o[a];
            }
        }
        vr->centre[s] = sum / ((double)x->gb * x->gc);
    }
    glBindBuffer(GL_ARRAY_BUFFER, vr->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(nvert * VFLOATS * sizeof(float)), vr->verts,
                 GL_STREAM_DRAW);
    return 0;
}

/* The slices' framebuffer at fw x fh; false when it cannot be made. */
static bool framebuffer(ftm_volume_render *vr, int fw, int fh)
{
    if (vr->fbo && vr->fw == fw && vr->fh == fh)
        return true;
    if (!vr->fbo) {
        glGenFramebuffers(1, &vr->fbo);
        glGenTextures(1, &vr->fbo_color);
        glGenRenderbuffers(1, &vr->fbo_depth);
    }
    glBindTexture(GL_TEXTURE_2D, vr->fbo_color);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, fw, fh, 0, GL_RGBA, GL_UNSIGNED_BYTE, NULL);
    ftm_gl_texture_params(GL_TEXTURE_2D, GL_LINEAR);
    glBindTexture(GL_TEXTURE_2D, 0);
    glBindRenderbuffer(GL_RENDERBUFFER, vr->fbo_depth);
    /* the window's own depth format (GLFW's default), for the depth copy */
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH24_STENCIL8, fw, fh);
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    glBindFramebuffer(GL_FRAMEBUFFER, vr->fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, vr->fbo_color, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER,
                              vr->fbo_depth);
    bool ok = glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    vr->fw = ok ? fw : 0;
    vr->fh = ok ? fh : 0;
    return ok;
}

void ftm_volume_render_draw(ftm_volume_render *vr, const float mvp[16], ftm_vec3 eye, bool colormap,
                            bool cut, int step, double full, int w, int h)
{
    if (!ftm_volume_render_active(vr))
        return;
    /* the lattice axis most aligned with the view of the box's centre */
    const double e[3] = {eye.x, eye.y, eye.z};
    double dir[3], len = 0;
    for (int k = 0; k < 3; k++) {
        dir[k] = 0.5 * (vr->lo[k] + vr->hi[k]) - e[k];
        len += dir[k] * dir[k];
    }
    len = sqrt(len);
    int a = 0;
    for (int k = 1; k < 3; k++)
        if (fabs(dir[k]) > fabs(dir[a]))
            a = k;
    if (vr->dirty || vr->built != a) {
        if (fill_axis(vr, a)) {
            vr->built = -1;
            return;
        }
        vr->built = a;
        vr->dirty = false;
    }
    const slice_axis *x = &vr->ax[a];
    /* a divisor of the slices per cell, so that the node planes stay */
    if (step != 2 && step != 5 && step != 10)
        step = 1;
    vr->slices = (x->ns - 1) / step + 1;
    /* back to front: slices farther from the eye along the axis first */
    /* (insertion sort: the slices come nearly in order, one way or the other) */
    for (int32_t s = 0; s < x->ns; s++) {
        double k = vr->key[s] = fabs(vr->centre[s] - e[a]);
        int32_t i = s;
        for (; i > 0 && vr->key[vr->order[i - 1]] < k; i--)
            vr->order[i] = vr->order[i - 1];
        vr->order[i] = s;
    }
    int32_t nd = 0;
    const double mid = 0.5 * (vr->lo[a] + vr->hi[a]);
    /* a cut-away's face, the middle slice, is drawn last and opaque: the
     * section through the tissue, as a scan viewer shows it */
    const int32_t face = cut ? (x->ns - 1) / 2 : -1;
    for (int32_t i = 0; i < x->ns; i++) {
        int32_t s = vr->order[i];
        /* a cut-away keeps the middle slice and those beyond it (by the
         * slice's place at rest, so that the cut stays with the tissue) */
        const double at = vr->lo[a] + (vr->hi[a] - vr->lo[a]) * s / (x->ns - 1);
        if (!x->count[s] || s == face || s % step != 0 ||
            (cut && (at - mid) * (e[a] - mid) > 1e-9 * (vr->hi[a] - vr->lo[a])))
            continue;
        vr->dcount[nd] = x->count[s];
        vr->doff[nd] = (const void *)(uintptr_t)(x->first[s] * sizeof(GLuint));
        nd++;
    }
    /* the path through one slice, in voxels, along the view */
    double path = step * (vr->hi[a] - vr->lo[a]) / (x->ns - 1) / vr->voxel[a];
    double cosv = len > 0 ? fabs(dir[a]) / len : 1;
    glUseProgram(vr->prog);
    glUniformMatrix4fv(vr->u_mvp, 1, GL_FALSE, mvp);
    glUniform1f(vr->u_air, (float)AIR);
    glUniform1f(vr->u_density, (float)(path / (cosv > 0.2 ? cosv : 0.2)));
    glUniform1i(vr->u_usemap, colormap ? 1 : 0);
    glUniform1f(vr->u_full, (float)(full > 0 ? full : 1e-3));
    glUniform3f(vr->u_eye, (float)eye.x, (float)eye.y, (float)eye.z);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_3D, vr->tex);
    glUniform1i(vr->u_tex, 1);
    int fw = (w + DOWNSAMPLE - 1) / DOWNSAMPLE, fh = (h + DOWNSAMPLE - 1) / DOWNSAMPLE;
    bool low = framebuffer(vr, fw, fh);
    glEnable(GL_BLEND);
    if (low) {
        /* the opaque parts' depth, so that they hide what is behind them */
        glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, vr->fbo);
        glClearColor(0, 0, 0, 0);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        if (vr->depth_copy) {
            glBlitFramebuffer(0, 0, w, h, 0, 0, fw, fh, GL_DEPTH_BUFFER_BIT, GL_NEAREST);
            if (glGetError() != GL_NO_ERROR) /* another depth format, multisampling */
                vr->depth_copy = false;
        }
        glBindFramebuffer(GL_FRAMEBUFFER, vr->fbo);
        glViewport(0, 0, fw, fh);
        /* colour premultiplied, alpha accumulated: blended over the window below */
        glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    } else {
        glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    }
    glDepthMask(GL_FALSE);
    glBindVertexArray(vr->vao);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, x->ibo);
    glUniform1i(vr->u_section, 0);
    if (nd)
        glMultiDrawElements(GL_TRIANGLES, vr->dcount, GL_UNSIGNED_INT, vr->doff, nd);
    if (face >= 0 && x->count[face]) {
        glUniform1i(vr->u_section, 1);
        glDrawElements(GL_TRIANGLES, x->count[face], GL_UNSIGNED_INT,
                       (const void *)(uintptr_t)(x->first[face] * sizeof(GLuint)));
    }
    glDepthMask(GL_TRUE);
    if (low) {
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        glViewport(0, 0, w, h);
        glDisable(GL_DEPTH_TEST);
        glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
        glUseProgram(vr->comp);
        glBindTexture(GL_TEXTURE_2D, vr->fbo_color); /* (unit 1) */
        glUniform1i(vr->comp_tex, 1);
        glBindVertexArray(vr->comp_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glBindTexture(GL_TEXTURE_2D, 0);
        glEnable(GL_DEPTH_TEST);
    }
    glBindVertexArray(0);
    glDisable(GL_BLEND);
    glActiveTexture(GL_TEXTURE0);
}
