/* SPDX-License-Identifier: GPL-3.0-or-later */
/* OpenGL 3.3 core drawing; see render.h. Mesa provides the entry points
 * directly (GL_GLEXT_PROTOTYPES), so no loader is needed. */
#include "render.h"
#include "render_gl.h"

#include "font.h"
#include "tissues.h"
#include "volume_render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define VERT_FLOATS 7 /* position 3, normal 3, displacement 1 */
#define TEXT_FLOATS 8 /* x y u v r g b a */

struct ftm_render {
    GLuint lit, flat, text; /* programs */
    GLint lit_mvp, lit_model, lit_eye, lit_color, lit_usemap, lit_full;
    /* the surface of a mesh with labels: the same shading, each triangle in
     * its tissue's colour (a program of its own, so that the surface of a
     * mesh without labels costs what it did) */
    GLuint tis;
    GLint tis_mvp, tis_model, tis_eye, tis_usemap, tis_full, tis_tricolor;
    GLint flat_mvp, flat_color, flat_size;
    GLint text_screen, text_tex;

    GLuint surf_vao, surf_vbo, surf_ibo;
    GLuint sph_vao, sph_vbo, sph_ibo;
    GLint sph_count;
    GLuint cyl_vao, cyl_vbo, cyl_ibo; /* the instrument's shaft: a unit cylinder */
    GLint cyl_count;
    GLuint dyn_vao, dyn_vbo; /* lines and points */
    GLuint text_vao, text_vbo, font_tex;

    const ftm_mesh *mesh;
    int32_t ntri, nvert;
    int32_t *tri;    /* 3 * ntri render-vertex indices */
    int32_t *node;   /* render vertex -> mesh node */
    float *rest;     /* 3 * nvert */
    float *verts;    /* VERT_FLOATS * nvert */
    double link;
    /* the tissues: a colour per drawn triangle (RGBA8) in a buffer texture
     * the surface shader reads by gl_PrimitiveID; the legend's rows */
    GLuint tri_tbo, tri_tex;
    int32_t *tri_label; /* ntri: each drawn triangle's label */
    bool labelled; /* the mesh's elements carry labels: colour by them */
    ftm_tissue tissues[FTM_RENDER_MAX_TISSUES];
    int32_t ntissues;
    float legend_box[4]; /* where the legend was drawn last (x0, y0, x1, y1; 0s: not) */
    ftm_scene_tool tool; /* the scene's instrument; zeros: scaled to the links */

    float *scratch; /* dynamic vertices */
    size_t scratch_cap;

    ftm_volume_render *vol;
    /* the control lattice's cage over a volume: the surface's edges but
     * each triangle's longest (a quad's diagonal), as lines */
    GLuint cage_vao, cage_ibo;
    GLsizei cage_count;
};

ftm_render_opts ftm_render_default_opts(void)
{
    return (ftm_render_opts){.colormap = true,
                             .colormap_full = 0.0,
                             .region = false,
                             .hud = true,
                             .text_scale = 2,
                             .volume = true,
                             .cut = false,
                             .volume_step = 1,
                             .help = NULL,
                             .nhelp = 0,
                             .volume_scale = 0.0,
                             .legend = true};
}

/* ---- shaders --------------------------------------------------------------------------- */

static const char *lit_vs =
    "#version 330 core\n"
    "layout(location=0) in vec3 a_pos;\n"
    "layout(location=1) in vec3 a_nrm;\n"
    "layout(location=2) in float a_disp;\n"
    "uniform mat4 u_mvp;\n"
    "uniform mat4 u_model;\n"
    "out vec3 v_pos; out vec3 v_nrm; out float v_disp;\n"
    "void main() {\n"
    "  vec4 w = u_model * vec4(a_pos, 1.0);\n"
    "  v_pos = w.xyz; v_nrm = mat3(u_model) * a_nrm; v_disp = a_disp;\n"
    "  gl_Position = u_mvp * w;\n"
    "}\n";

/* Tissue, not plastic: a wrapped diffuse (light bleeds past the terminator,
 * as under a wet, translucent surface), a reddish tint where it turns away
 * (the light that scattered inside), a narrow wet highlight. Two lights: a
 * head light and a key light from above; both sides lit, so open meshes
 * look right from behind. The colour map (blue-teal-yellow-red) shows only
 * where the tissue moved: away from the dent the tissue keeps its colour. */
#define LIT_FS_BODY                                                                               \
    "in vec3 v_pos; in vec3 v_nrm; in float v_disp;\n"                                            \
    "uniform vec3 u_eye; uniform vec3 u_color; uniform int u_usemap; uniform float u_full;\n"     \
    "#ifdef TISSUES\n"                                                                            \
    "uniform samplerBuffer u_tricolor;\n"                                                         \
    "vec3 tissue_color() { return texelFetch(u_tricolor, gl_PrimitiveID).rgb; }\n"                \
    "#else\n"                                                                                     \
    "vec3 tissue_color() { return u_color; }\n"                                                   \
    "#endif\n"                                                                                    \
    "out vec4 o_color;\n"                                                                         \
    FTM_GL_RAMP_GLSL                                                                              \
    "void main() {\n"                                                                             \
    "  vec3 n = normalize(v_nrm);\n"                                                              \
    "  vec3 v = normalize(u_eye - v_pos);\n"                                                      \
    "  if (dot(n, v) < 0.0) n = -n;\n"                                                            \
    "  vec3 tissue = tissue_color();\n"                                                           \
    "  vec3 base = tissue;\n"                                                                     \
    "  if (u_usemap != 0) {\n"                                                                    \
    "    float t = v_disp / u_full;\n"                                                            \
    "    base = mix(tissue, ramp(t), smoothstep(0.1, 0.35, t));\n"                                \
    "  }\n"                                                                                       \
    "  vec3 key = normalize(vec3(0.3, -0.4, 1.0));\n"                                             \
    "  float wv = (dot(n, v) + 0.4) / 1.4, wk = (dot(n, key) + 0.4) / 1.4;\n"                     \
    "  float d = 0.55 * max(wv, 0.0) + 0.35 * max(wk, 0.0);\n"                                    \
    "  vec3 scatter = vec3(0.30, 0.04, 0.03) * (1.0 - max(dot(n, v), 0.0));\n"                    \
    "  vec3 h = normalize(key + v);\n"                                                            \
    "  float sp = 0.35 * pow(max(dot(n, h), 0.0), 80.0);\n"                                       \
    "  o_color = vec4(base * (0.18 + d) + scatter * base + vec3(sp), 1.0);\n"                     \
    "}\n"
static const char *lit_fs = "#version 330 core\n" LIT_FS_BODY;
static const char *tis_fs = "#version 330 core\n#define TISSUES 1\n" LIT_FS_BODY;

static const char *flat_vs =
    "#version 330 core\n"
    "layout(location=0) in vec3 a_pos;\n"
    "uniform mat4 u_mvp; uniform float u_size;\n"
    "void main() { gl_Position = u_mvp * vec4(a_pos, 1.0); gl_PointSize = u_size; }\n";

static const char *flat_fs =
    "#version 330 core\n"
    "uniform vec4 u_color; out vec4 o_color;\n"
    "void main() { o_color = u_color; }\n";

static const char *text_vs =
    "#version 330 core\n"
    "layout(location=0) in vec2 a_pos;\n"
    "layout(location=1) in vec2 a_uv;\n"
    "layout(location=2) in vec4 a_color;\n"
    "uniform vec2 u_screen;\n"
    "out vec2 v_uv; out vec4 v_color;\n"
    "void main() {\n"
    "  v_uv = a_uv; v_color = a_color;\n"
    "  gl_Position = vec4(a_pos.x / u_screen.x * 2.0 - 1.0, 1.0 - a_pos.y / u_screen.y * 2.0, 0.0, 1.0);\n"
    "}\n";

static const char *text_fs =
    "#version 330 core\n"
    "in vec2 v_uv; in vec4 v_color; uniform sampler2D u_tex; out vec4 o_color;\n"
    "void main() { float a = texture(u_tex, v_uv).r; o_color = vec4(v_color.rgb, v_color.a * a); }\n";

int ftm_gl_fail(ftm_error *err, const char *what, const char *log)
{
    if (err) {
        err->code = FTM_EINVAL;
        snprintf(err->message, sizeof err->message, "OpenGL: %s: %s", what, log);
    }
    return FTM_EINVAL;
}

static GLuint shader(GLenum type, const char *src, const char *what, ftm_error *err)
{
    GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[400];
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        ftm_gl_fail(err, what, log);
        glDeleteShader(s);
        return 0;
    }
    return s;
}

GLuint ftm_gl_program(const char *vs, const char *fs, const char *what, ftm_error *err)
{
    GLuint v = shader(GL_VERTEX_SHADER, vs, what, err);
    if (!v)
        return 0;
    GLuint f = shader(GL_FRAGMENT_SHADER, fs, what, err);
    if (!f) {
        glDeleteShader(v);
        return 0;
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[400];
        glGetProgramInfoLog(p, sizeof log, NULL, log);
        ftm_gl_fail(err, what, log);
        glDeleteProgram(p);
        return 0;
    }
    return p;
}

/* ---- a unit sphere for markers (subdivided octahedron) ----------------------------------- */

static void make_sphere(ftm_render *r)
{
    enum { LEVEL = 3 };
    int ntri = 8 << (2 * LEVEL);
    float *v = malloc((size_t)ntri * 3 * VERT_FLOATS * sizeof *v);
    GLuint *idx = malloc((size_t)ntri * 3 * sizeof *idx);
    if (!v || !idx) {
        free(v);
        free(idx);
        r->sph_count = 0;
        return;
    }
    /* each octant face split into a LEVEL-times subdivided grid, projected */
    static const int oct[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                  {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    static const float axes[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1},
                                     {0, 0, -1}};
    int k = 0, div = 1 << LEVEL;
    for (int f = 0; f < 8; f++) {
        const float *A = axes[oct[f][0]], *B = axes[oct[f][1]], *C = axes[oct[f][2]];
        for (int i = 0; i < div; i++)
            for (int j = 0; j < div - i; j++)
                for (int t = 0; t < 2; t++) {
                    int uv[3][2];
                    if (t == 0) {
                        uv[0][0] = i, uv[0][1] = j;
                        uv[1][0] = i + 1, uv[1][1] = j;
                        uv[2][0] = i, uv[2][1] = j + 1;
                    } else {
                        if (j + i + 1 >= div)
                            continue;
                        uv[0][0] = i + 1, uv[0][1] = j;
                        uv[1][0] = i + 1, uv[1][1] = j + 1;
                        uv[2][0] = i, uv[2][1] = j + 1;
                    }
                    for (int c = 0; c < 3; c++) {
                        float a = (float)uv[c][0] / div, b = (float)uv[c][1] / div, w = 1 - a - b;
                        float p[3];
                        for (int d = 0; d < 3; d++)
                            p[d] = w * A[d] + a * B[d] + b * C[d];
                        float len = sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
                        float *o = v + (size_t)k * VERT_FLOATS;
                        for (int d = 0; d < 3; d++)
                            o[d] = o[3 + d] = p[d] / len;
                        o[6] = 0;
                        idx[k] = (GLuint)k;
                        k++;
                    }
                }
    }
    r->sph_count = k;
    glBindVertexArray(r->sph_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->sph_vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)k * VERT_FLOATS * sizeof *v), v,
                 GL_STATIC_DRAW);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->sph_ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)((size_t)k * sizeof *idx), idx,
                 GL_STATIC_DRAW);
    free(v);
    free(idx);
}

/* ---- a unit cylinder for the instrument's shaft: radius 1 about +z, z in 0..1 ----------- */

static void make_cylinder(ftm_render *r)
{
    enum { SEG = 20 };
    float v[(SEG + 1) * 2 * VERT_FLOATS];
    GLuint idx[SEG * 6];
    for (int i = 0; i <= SEG; i++) {
        double t = 2.0 * 3.14159265358979323846 * i / SEG;
        float c = (float)cos(t), s = (float)sin(t);
        for (int e = 0; e < 2; e++) {
            float *o = v + (size_t)(2 * i + e) * VERT_FLOATS;
            o[0] = c, o[1] = s, o[2] = (float)e;
            o[3] = c, o[4] = s, o[5] = 0;
            o[6] = 0;
        }
    }
    for (int i = 0; i < SEG; i++) {
        GLuint a = (GLuint)(2 * i), b = a + 1, c = a + 2, d = a + 3;
        GLuint q[6] = {a, c, b, b, c, d};
        memcpy(idx + 6 * i, q, sizeof q);
    }
    r->cyl_count = SEG * 6;
    glBindVertexArray(r->cyl_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->cyl_vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)sizeof v, v, GL_STATIC_DRAW);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->cyl_ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)sizeof idx, idx, GL_STATIC_DRAW);
}

void ftm_gl_texture_params(GLenum target, GLint filter)
{
    glTexParameteri(target, GL_TEXTURE_MIN_FILTER, filter);
    glTexParameteri(target, GL_TEXTURE_MAG_FILTER, filter);
    glTexParameteri(target, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(target, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    if (target == GL_TEXTURE_3D)
        glTexParameteri(target, GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE);
}

void ftm_gl_layout_331(void)
{
    _Static_assert(VERT_FLOATS == 7, "the surface's vertices are laid out 3, 3, 1");
    GLsizei stride = VERT_FLOATS * sizeof(float);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, (void *)0);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride, (void *)(3 * sizeof(float)));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, stride, (void *)(6 * sizeof(float)));
}

int ftm_render_create(ftm_render **out, ftm_error *err)
{
    ftm_render *r = calloc(1, sizeof *r);
    if (!r)
        return ftm_gl_fail(err, "render", "out of memory");
    r->lit = ftm_gl_program(lit_vs, lit_fs, "surface shader", err);
    r->flat = r->lit ? ftm_gl_program(flat_vs, flat_fs, "line shader", err) : 0;
    r->text = r->flat ? ftm_gl_program(text_vs, text_fs, "text shader", err) : 0;
    r->tis = r->text ? ftm_gl_program(lit_vs, tis_fs, "tissue shader", err) : 0;
    if (!r->tis || ftm_volume_render_create(&r->vol, err)) {
        ftm_render_destroy(r);
        return FTM_EINVAL;
    }
    r->lit_mvp = glGetUniformLocation(r->lit, "u_mvp");
    r->lit_model = glGetUniformLocation(r->lit, "u_model");
    r->lit_eye = glGetUniformLocation(r->lit, "u_eye");
    r->lit_color = glGetUniformLocation(r->lit, "u_color");
    r->lit_usemap = glGetUniformLocation(r->lit, "u_usemap");
    r->lit_full = glGetUniformLocation(r->lit, "u_full");
    r->tis_mvp = glGetUniformLocation(r->tis, "u_mvp");
    r->tis_model = glGetUniformLocation(r->tis, "u_model");
    r->tis_eye = glGetUniformLocation(r->tis, "u_eye");
    r->tis_usemap = glGetUniformLocation(r->tis, "u_usemap");
    r->tis_full = glGetUniformLocation(r->tis, "u_full");
    r->tis_tricolor = glGetUniformLocation(r->tis, "u_tricolor");
    r->flat_mvp = glGetUniformLocation(r->flat, "u_mvp");
    r->flat_color = glGetUniformLocation(r->flat, "u_color");
    r->flat_size = glGetUniformLocation(r->flat, "u_size");
    r->text_screen = glGetUniformLocation(r->text, "u_screen");
    r->text_tex = glGetUniformLocation(r->text, "u_tex");

    glGenVertexArrays(1, &r->surf_vao);
    glGenBuffers(1, &r->surf_vbo);
    glGenBuffers(1, &r->surf_ibo);
    glBindVertexArray(r->surf_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->surf_vbo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->surf_ibo);
    ftm_gl_layout_331();

    glGenBuffers(1, &r->tri_tbo);
    glGenTextures(1, &r->tri_tex);

    glGenVertexArrays(1, &r->sph_vao);
    glGenBuffers(1, &r->sph_vbo);
    glGenBuffers(1, &r->sph_ibo);
    glBindVertexArray(r->sph_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->sph_vbo);
    ftm_gl_layout_331();
    make_sphere(r);

    glGenVertexArrays(1, &r->cyl_vao);
    glGenBuffers(1, &r->cyl_vbo);
    glGenBuffers(1, &r->cyl_ibo);
    glBindVertexArray(r->cyl_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->cyl_vbo);
    ftm_gl_layout_331();
    make_cylinder(r);

    glGenVertexArrays(1, &r->dyn_vao);
    glGenBuffers(1, &r->dyn_vbo);
    glBindVertexArray(r->dyn_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->dyn_vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), (void *)0);

    glGenVertexArrays(1, &r->text_vao);
    glGenBuffers(1, &r->text_vbo);
    glBindVertexArray(r->text_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->text_vbo);
    GLsizei ts = TEXT_FLOATS * sizeof(float);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, ts, (void *)0);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, ts, (void *)(2 * sizeof(float)));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, ts, (void *)(4 * sizeof(float)));
    glBindVertexArray(0);

    enum { AW = FTM_FONT_COUNT * FTM_FONT_CELL_W, AH = FTM_FONT_CELL_H };
    static uint8_t atlas[AW * AH];
    ftm_font_pixels(atlas);
    glGenTextures(1, &r->font_tex);
    glBindTexture(GL_TEXTURE_2D, r->font_tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, AW, AH, 0, GL_RED, GL_UNSIGNED_BYTE, atlas);
    ftm_gl_texture_params(GL_TEXTURE_2D, GL_NEAREST);
    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        char msg[64];
        snprintf(msg, sizeof msg, "GL error 0x%x", e);
        ftm_render_destroy(r);
        return ftm_gl_fail(err, "set-up", msg);
    }
    *out = r;
    return FTM_OK;
}

static void free_mesh(ftm_render *r)
{
    free(r->tri);
    free(r->tri_label);
    r->tri_label = NULL;
    free(r->node);
    free(r->rest);
    free(r->verts);
    r->tri = r->node = NULL;
    r->rest = r->verts = NULL;
    r->ntri = r->nvert = 0;
    r->mesh = NULL;
    r->labelled = false;
    r->ntissues = 0;
}

void ftm_render_destroy(ftm_render *r)
{
    if (!r)
        return;
    free_mesh(r);
    free(r->scratch);
    ftm_volume_render_destroy(r->vol);
    glDeleteBuffers(1, &r->cage_ibo);
    glDeleteVertexArrays(1, &r->cage_vao);
    GLuint bufs[] = {r->surf_vbo, r->surf_ibo, r->sph_vbo, r->sph_ibo,
                     r->cyl_vbo,  r->cyl_ibo,  r->dyn_vbo, r->text_vbo};
    glDeleteBuffers(8, bufs);
    GLuint vaos[] = {r->surf_vao, r->sph_vao, r->cyl_vao, r->dyn_vao, r->text_vao};
    glDeleteVertexArrays(5, vaos);
    glDeleteTextures(1, &r->font_tex);
    glDeleteBuffers(1, &r->tri_tbo);
    glDeleteTextures(1, &r->tri_tex);
    glDeleteProgram(r->lit);
    glDeleteProgram(r->flat);
    glDeleteProgram(r->text);
    glDeleteProgram(r->tis);
    free(r);
}

/* The tissues' colours of the kept triangles into the buffer texture. */
static int upload_tissues(ftm_render *r, const int32_t *label, ftm_error *err)
{
    uint8_t *rgba = malloc((size_t)r->ntri * 4 + 1);
    if (!rgba)
        return ftm_gl_fail(err, "mesh", "out of memory");
    for (int32_t t = 0; t < r->ntri; t++) {
        float c[3];
        ftm_tissue_color(label[t], c);
        for (int k = 0; k < 3; k++)
            rgba[4 * (size_t)t + k] = (uint8_t)(c[k] * 255.0f + 0.5f);
        rgba[4 * (size_t)t + 3] = 255;
    }
    glBindBuffer(GL_TEXTURE_BUFFER, r->tri_tbo);
    glBufferData(GL_TEXTURE_BUFFER, (GLsizeiptr)((size_t)r->ntri * 4), rgba, GL_STATIC_DRAW);
    glBindTexture(GL_TEXTURE_BUFFER, r->tri_tex);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_RGBA8, r->tri_tbo);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
    free(rgba);
    return FTM_OK;
}

int ftm_render_set_mesh(ftm_render *r, const ftm_mesh *mesh, const ftm_scene *scene,
                        ftm_error *err)
{
    free_mesh(r);
    if (!mesh)
        return FTM_OK;
    int32_t n = ftm_mesh_node_count(mesh), nt = ftm_mesh_triangle_count(mesh);
    const int32_t *t = ftm_mesh_triangles(mesh);
    int32_t *map = malloc((size_t)n * sizeof *map);
    int32_t *label = malloc(((size_t)nt + 1) * sizeof *label);
    r->tri = malloc(((size_t)nt * 3 + 1) * sizeof *r->tri);
    r->node = malloc(((size_t)n + 1) * sizeof *r->node);
    if (!map || !label || !r->tri || !r->node || ftm_tissue_surface_labels(mesh, label)) {
        free(map);
        free(label);
        free_mesh(r);
        return ftm_gl_fail(err, "mesh", "out of memory");
    }
    /* only surface nodes are drawn: compact them to render vertices; a face
     * between two elements (a file's triangle where two tissues meet) is
     * inside the body and left out: the outer surface shows where the
     * tissues meet by their colours */
    for (int32_t i = 0; i < n; i++)
        map[i] = -1;
    int32_t nv = 0, kept = 0;
    for (int32_t f = 0; f < nt; f++) {
        if (label[f] == FTM_TISSUE_INTERIOR)
            continue;
        for (int k = 0; k < 3; k++) {
            int32_t a = t[3 * f + k];
            if (map[a] < 0) {
                map[a] = nv;
                r->node[nv++] = a;
            }
            r->tri[3 * kept + k] = map[a];
        }
        label[kept++] = label[f];
    }
    free(map);
    nt = kept;
    r->ntissues = ftm_tissue_list(label, nt, mesh, scene, r->tissues, FTM_RENDER_MAX_TISSUES);
    /* a colour per triangle in a buffer texture: GL 3.3 promises 65536
     * texels, most drivers far more; past it, one colour and no legend */
    GLint tbo_max = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &tbo_max);
    r->labelled = ftm_mesh_has_labels(mesh) && nt <= tbo_max;
    r->rest = malloc(((size_t)nv * 3 + 1) * sizeof *r->rest);
    r->verts = malloc(((size_t)nv * VERT_FLOATS + 1) * sizeof *r->verts);
    if (!r->rest || !r->verts) {
        free(label);
        free_mesh(r);
        return ftm_gl_fail(err, "mesh", "out of memory");
    }
    for (int32_t i = 0; i < nv; i++) {
        ftm_vec3 p = ftm_mesh_rest_position(mesh, r->node[i]);
        r->rest[3 * i] = (float)p.x;
        r->rest[3 * i + 1] = (float)p.y;
        r->rest[3 * i + 2] = (float)p.z;
    }
    r->mesh = mesh;
    r->ntri = nt;
    r->nvert = nv;
    r->link = ftm_mesh_mean_link_length(mesh);
    r->tri_label = label;
    if (r->labelled && upload_tissues(r, label, err)) {
        free_mesh(r);
        return FTM_ENOMEM;
    }
    glBindVertexArray(r->surf_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->surf_vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)nv * VERT_FLOATS * sizeof(float)), NULL,
                 GL_STREAM_DRAW);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->surf_ibo);
    /* int32 indices are GLuint on every platform FTM builds on */
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)((size_t)nt * 3 * sizeof(GLuint)), r->tri,
                 GL_STATIC_DRAW);
    glBindVertexArray(0);
    return FTM_OK;
}

static int cmp_u64(const void *x, const void *y)
{
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return a < b ? -1 : a > b;
}

/* The cage's lines: each triangle's two shorter edges at rest, once each. */
static int make_cage(ftm_render *r)
{
    r->cage_count = 0;
    if (!r->ntri)
        return 0;
    uint64_t *e = malloc((size_t)r->ntri * 2 * sizeof *e);
    if (!e)
        return -1;
    size_t n = 0;
    for (int32_t t = 0; t < r->ntri; t++) {
        const int32_t *v = r->tri + 3 * t;
        double len[3];
        for (int k = 0; k < 3; k++) {
            const float *p = r->rest + 3 * v[k], *q = r->rest + 3 * v[(k + 1) % 3];
            len[k] = (double)(p[0] - q[0]) * (p[0] - q[0]) + (double)(p[1] - q[1]) * (p[1] - q[1]) +
                     (double)(p[2] - q[2]) * (p[2] - q[2]);
        }
        int longest = len[0] >= len[1] && len[0] >= len[2] ? 0 : len[1] >= len[2] ? 1 : 2;
        for (int k = 0; k < 3; k++) {
            if (k == longest)
                continue;
            uint32_t a = (uint32_t)v[k], b = (uint32_t)v[(k + 1) % 3];
            e[n++] = a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
        }
    }
    qsort(e, n, sizeof *e, cmp_u64);
    GLuint *idx = malloc(2 * n * sizeof *idx + 1);
    if (!idx) {
        free(e);
        return -1;
    }
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (i == 0 || e[i] != e[i - 1]) {
            idx[m++] = (GLuint)(e[i] >> 32);
            idx[m++] = (GLuint)(e[i] & 0xffffffffu);
        }
    free(e);
    if (!r->cage_vao) {
        glGenVertexArrays(1, &r->cage_vao);
        glGenBuffers(1, &r->cage_ibo);
    }
    glBindVertexArray(r->cage_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->surf_vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, VERT_FLOATS * sizeof(float), (void *)0);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->cage_ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(m * sizeof *idx), idx, GL_STATIC_DRAW);
    glBindVertexArray(0);
    free(idx);
    r->cage_count = (GLsizei)m;
    return 0;
}

int ftm_render_set_volume(ftm_render *r, const ftm_volume *volume, const ftm_ffd *ffd,
                          const ftm_label_map *labels, ftm_error *err)
{
    r->cage_count = 0;
    int rc = ftm_volume_render_set(r->vol, volume, ffd, labels,
                                   r->mesh ? ftm_mesh_node_count(r->mesh) : 0, err);
    if (rc == FTM_OK && ftm_volume_render_active(r->vol) && make_cage(r))
        return ftm_gl_fail(err, "volume", "out of memory");
    return rc;
}

bool ftm_render_has_volume(const ftm_render *r) { return ftm_volume_render_active(r->vol); }
int32_t ftm_render_volume_slices(const ftm_render *r) { return ftm_volume_render_slices(r->vol); }

int32_t ftm_render_triangle_count(const ftm_render *r) { return r->ntri; }

int ftm_render_tissue_point(const ftm_render *r, int32_t label, ftm_vec3 eye, ftm_vec3 *point)
{
    double best = 0.5; /* facing the eye at least this much (cosine) */
    int found = 0;
    for (int32_t t = 0; r->verts && t < r->ntri; t++) {
        if (r->tri_label[t] != label)
            continue;
        double c[3] = {0, 0, 0}, e1[3], e2[3];
        const float *p[3];
        for (int k = 0; k < 3; k++)
            p[k] = r->verts + (size_t)r->tri[3 * t + k] * VERT_FLOATS;
        for (int d = 0; d < 3; d++) {
            c[d] = ((double)p[0][d] + p[1][d] + p[2][d]) / 3.0;
            e1[d] = (double)p[1][d] - p[0][d];
            e2[d] = (double)p[2][d] - p[0][d];
        }
        const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                             e1[0] * e2[1] - e1[1] * e2[0]};
        const double to[3] = {eye.x - c[0], eye.y - c[1], eye.z - c[2]};
        const double ln = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]),
                     lt = sqrt(to[0] * to[0] + to[1] * to[1] + to[2] * to[2]);
        if (!(ln > 0 && lt > 0))
            continue;
        const double facing = fabs(n[0] * to[0] + n[1] * to[1] + n[2] * to[2]) / (ln * lt);
        if (facing <= best)
            continue;
        /* not hidden: the first surface along the eye's ray is this one */
        const ftm_vec3 dir = {-to[0] / lt, -to[1] / lt, -to[2] / lt};
        double dist;
        if (!ftm_render_surface_along(r, eye, dir, &dist, NULL) || dist < lt * (1 - 1e-4))
            continue;
        best = facing;
        *point = (ftm_vec3){c[0], c[1], c[2]};
        found = 1;
    }
    return found;
}

void ftm_render_legend_box(const ftm_render *r, float box[4])
{
    memcpy(box, r->legend_box, sizeof r->legend_box);
}

int32_t ftm_render_tissues(const ftm_render *r, const ftm_tissue **out)
{
    if (out)
        *out = r->tissues;
    return r->labelled ? r->ntissues : 0;
}
double ftm_render_link_length(const ftm_render *r) { return r->link; }

void ftm_render_update(ftm_render *r, const ftm_client_view *v)
{
    if (!r->mesh)
        return;
    ftm_volume_render_update(r->vol, v->pos, v->node_count);
    bool have = v->pos && v->node_count == ftm_mesh_node_count(r->mesh);
    float *o = r->verts;
    for (int32_t i = 0; i < r->nvert; i++) {
        float *q = o + (size_t)i * VERT_FLOATS;
        const float *rp = r->rest + 3 * i;
        if (have) {
            const double *p = v->pos + 3 * (size_t)r->node[i];
            q[0] = (float)p[0];
            q[1] = (float)p[1];
            q[2] = (float)p[2];
            double dx = p[0] - rp[0], dy = p[1] - rp[1], dz = p[2] - rp[2];
            q[6] = (float)sqrt(dx * dx + dy * dy + dz * dz);
        } else {
            q[0] = rp[0];
            q[1] = rp[1];
            q[2] = rp[2];
            q[6] = 0;
        }
        q[3] = q[4] = q[5] = 0;
    }
    /* area-weighted vertex normals of the deformed surface */
    for (int32_t t = 0; t < r->ntri; t++) {
        float *a = o + (size_t)r->tri[3 * t] * VERT_FLOATS;
        float *b = o + (size_t)r->tri[3 * t + 1] * VERT_FLOATS;
        float *c = o + (size_t)r->tri[3 * t + 2] * VERT_FLOATS;
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                      e1[0] * e2[1] - e1[1] * e2[0]};
        for (int d = 0; d < 3; d++) {
            a[3 + d] += n[d];
            b[3 + d] += n[d];
            c[3 + d] += n[d];
        }
    }
    glBindBuffer(GL_ARRAY_BUFFER, r->surf_vbo);
    glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)((size_t)r->nvert * VERT_FLOATS * sizeof(float)),
                    r->verts);
}

/* ---- the instrument -------------------------------------------------------------------------- */

#define TIP_LINKS 0.3
#define SHAFT_RADIUS_LINKS 0.12
#define SHAFT_LINKS 6.0

void ftm_render_instrument(const ftm_render *r, const ftm_client_probe *p, ftm_instrument *out)
{
    double link = r->link > 0 ? r->link : 0.01;
    ftm_vec3 a = {0, 0, 1};
    if (p->in_contact && p->has_plane) {
        const ftm_vec3 n = p->plane_normal;
        double len = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
        if (len > 0 && isfinite(len))
            a = (ftm_vec3){n.x / len, n.y / len, n.z / len};
    }
    /* the scene's own tool where it gives one, each size on its own */
    *out = (ftm_instrument){p->hip, a, r->tool.tip_radius > 0 ? r->tool.tip_radius : TIP_LINKS * link,
                            r->tool.shaft_radius > 0 ? r->tool.shaft_radius
                                                     : SHAFT_RADIUS_LINKS * link,
                            r->tool.shaft_length > 0 ? r->tool.shaft_length : SHAFT_LINKS * link};
}

int ftm_render_surface_along(const ftm_render *r, ftm_vec3 from, ftm_vec3 dir, double *dist,
                             ftm_vec3 *normal)
{
    if (!r->mesh || !r->verts)
        return 0;
    double best = INFINITY;
    ftm_vec3 bn = {0, 0, 0};
    const double o[3] = {from.x, from.y, from.z}, d[3] = {dir.x, dir.y, dir.z};
    for (int32_t t = 0; t < r->ntri; t++) {
        const float *A = r->verts + (size_t)r->tri[3 * t] * VERT_FLOATS;
        const float *B = r->verts + (size_t)r->tri[3 * t + 1] * VERT_FLOATS;
        const float *C = r->verts + (size_t)r->tri[3 * t + 2] * VERT_FLOATS;
        double e1[3], e2[3], s[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = (double)B[k] - A[k];
            e2[k] = (double)C[k] - A[k];
            s[k] = o[k] - A[k];
        }
        /* Moller-Trumbore */
        double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                        d[0] * e2[1] - d[1] * e2[0]};
        double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (fabs(det) < 1e-18)
            continue;
        double u = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) / det;
        if (u < 0 || u > 1)
            continue;
        double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                       s[0] * e1[1] - s[1] * e1[0]};
        double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
        if (v < 0 || u + v > 1)
            continue;
        double tt = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
        if (tt >= 0 && tt < best) {
            best = tt;
            double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                           e1[0] * e2[1] - e1[1] * e2[0]};
            double nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            bn = nl > 0 ? (ftm_vec3){n[0] / nl, n[1] / nl, n[2] / nl} : (ftm_vec3){0, 0, 1};
        }
    }
    if (!isfinite(best))
        return 0;
    *dist = best;
    if (normal)
        *normal = bn;
    return 1;
}

/* Model matrix of a unit shape scaled by sx, sy along two unit vectors
 * perpendicular to axis, sz along it, then moved to at. */
static void oriented(float m[16], ftm_vec3 at, ftm_vec3 axis, double sx, double sz)
{
    ftm_vec3 h = fabs(axis.x) < 0.9 ? (ftm_vec3){1, 0, 0} : (ftm_vec3){0, 1, 0};
    ftm_vec3 e1 = {axis.y * h.z - axis.z * h.y, axis.z * h.x - axis.x * h.z,
                   axis.x * h.y - axis.y * h.x};
    double l = sqrt(e1.x * e1.x + e1.y * e1.y + e1.z * e1.z);
    e1 = (ftm_vec3){e1.x / l, e1.y / l, e1.z / l};
    ftm_vec3 e2 = {axis.y * e1.z - axis.z * e1.y, axis.z * e1.x - axis.x * e1.z,
                   axis.x * e1.y - axis.y * e1.x};
    const float c[16] = {(float)(e1.x * sx),   (float)(e1.y * sx),   (float)(e1.z * sx),   0,
                         (float)(e2.x * sx),   (float)(e2.y * sx),   (float)(e2.z * sx),   0,
                         (float)(axis.x * sz), (float)(axis.y * sz), (float)(axis.z * sz), 0,
                         (float)at.x,          (float)at.y,          (float)at.z,          1};
    memcpy(m, c, sizeof c);
}

/* ---- drawing ------------------------------------------------------------------------------- */

static float *scratch(ftm_render *r, size_t floats)
{
    if (floats > r->scratch_cap) {
        size_t c = floats + floats / 2 + 256;
        float *q = realloc(r->scratch, c * sizeof *q);
        if (!q)
            return NULL;
        r->scratch = q;
        r->scratch_cap = c;
    }
    return r->scratch;
}

void ftm_render_participant_color(uint32_t participant, float c[3])
{
    /* by id, the same in every view: the instructor, the observers and the
     * trainee herself see trainee 11 in one colour (ids are consecutive:
     * neighbours differ) */
    static const float palette[8][3] = {{0.20f, 0.90f, 0.35f}, {0.95f, 0.55f, 0.10f},
                                        {0.10f, 0.75f, 0.95f}, {0.95f, 0.30f, 0.60f},
                                        {0.60f, 0.35f, 0.90f}, {0.95f, 0.90f, 0.20f},
                                        {0.55f, 0.85f, 0.20f}, {0.90f, 0.90f, 0.90f}};
    const float *q = palette[(participant + 5u) % 8u]; /* trainee 11 green, 12 orange */
    c[0] = q[0], c[1] = q[1], c[2] = q[2];
}

static void probe_color(const ftm_client_probe *p, float c[3])
{
    ftm_render_participant_color(p->participant, c);
}

static void sphere_at(ftm_render *r, ftm_vec3 at, double radius, const float color[3])
{
    float s = (float)radius;
    float model[16] = {s, 0, 0, 0, 0, s, 0, 0, 0, 0, s, 0, (float)at.x, (float)at.y, (float)at.z, 1};
    glUniformMatrix4fv(r->lit_model, 1, GL_FALSE, model);
    glUniform3fv(r->lit_color, 1, color);
    glDrawElements(GL_TRIANGLES, r->sph_count, GL_UNSIGNED_INT, (void *)0);
}

static void text_quad(float *o, float x0, float y0, float x1, float y1, float u0, float v0, float u1,
                      float v1, const float col[4])
{
    const float q[6][4] = {{x0, y0, u0, v0}, {x1, y0, u1, v0}, {x1, y1, u1, v1},
                           {x0, y0, u0, v0}, {x1, y1, u1, v1}, {x0, y1, u0, v1}};
    for (int i = 0; i < 6; i++) {
        float *p = o + i * TEXT_FLOATS;
        memcpy(p, q[i], 4 * sizeof(float));
        memcpy(p + 4, col, 4 * sizeof(float));
    }
}

/* Appends a box and/or text; returns vertices written. */
static int text_box(float *o, float x, float y, float w, float h, const float col[4])
{
    float u = (float)(127 - FTM_FONT_FIRST) / FTM_FONT_COUNT;
    float du = 0.5f / (FTM_FONT_COUNT * FTM_FONT_CELL_W);
    text_quad(o, x, y, x + w, y + h, u + du, 0.1f, u + du, 0.1f, col);
    return 6;
}

static int text_line(float *o, float x, float y, float px, const char *s, const float col[4])
{
    int n = 0;
    for (const char *c = s; *c; c++, x += FTM_FONT_CELL_W * px) {
        if (*c == ' ')
            continue;
        int g = ftm_font_glyph((unsigned char)*c);
        float u0 = (float)g / FTM_FONT_COUNT, u1 = (float)(g + 1) / FTM_FONT_COUNT;
        text_quad(o + (size_t)n * TEXT_FLOATS, x, y, x + FTM_FONT_CELL_W * px,
                  y + FTM_FONT_CELL_H * px, u0, 0.0f, u1, 1.0f, col);
        n += 6;
    }
    return n;
}

/* HUD pixels per font pixel, and the height of one HUD line */
static float text_px(const ftm_render_opts *o)
{
    return (float)(o->text_scale > 0 ? o->text_scale : 1);
}

static float line_height(const ftm_render_opts *o)
{
    return (FTM_FONT_CELL_H + 2) * text_px(o);
}

double ftm_render_hud_height(const ftm_render_opts *o, int nhud)
{
    return o->hud && nhud > 0 ? 14.0 + nhud * (double)line_height(o) : 0.0;
}

double ftm_render_view_top(const ftm_render_opts *o, int nhud)
{
    const double step = 4.0 * line_height(o);
    return ceil(ftm_render_hud_height(o, nhud) / step) * step;
}

/* A participant's name as the view knows it ("trainee N" without one). */
static void participant_label(const ftm_client_view *v, const ftm_client_probe *p, char *out,
                              size_t cap)
{
    const char *name = NULL;
    for (int32_t j = 0; j < v->nparts && !name; j++)
        if (v->parts[j].id == p->participant && v->parts[j].name[0])
            name = v->parts[j].name;
    /* the id too: two trainees may share a name (bots default to one) */
    if (name)
        snprintf(out, cap, "%s (%u%s)", name, p->participant, p->own ? ", you" : "");
    else
        snprintf(out, cap, "trainee %u%s", p->participant, p->own ? " (you)" : "");
}

/* Each instrument's name at the top of its shaft, in its colour: who is
 * pressing where, in every view. Returns vertices written. */
/* The legend (key l): a panel at the bottom left (the bottom right when
 * the HUD reaches down there), a swatch of each tissue's colour and its
 * name and E; at most LEGEND_ROWS rows, then how many more. Writes its box
 * (x0, y0, x1, y1; all 0 when there is none) and returns its rows. */
#define LEGEND_ROWS 12
static int legend_layout(const ftm_render *r, const ftm_render_opts *o, int w, int h,
                         float hud_bottom, float hud_right, char rows[LEGEND_ROWS + 2][96],
                         float box[4])
{
    box[0] = box[1] = box[2] = box[3] = 0;
    const ftm_tissue *t;
    int32_t nt = ftm_render_tissues(r, &t);
    if (!o->legend || nt <= 0)
        return 0;
    int n = 0;
    snprintf(rows[n++], 96, "tissues (l: hide)");
    for (int32_t i = 0; i < nt && i < LEGEND_ROWS; i++)
        ftm_tissue_legend_text(&t[i], rows[n++], 96);
    if (nt > LEGEND_ROWS)
        snprintf(rows[n++], 96, "... %d more", (int)(nt - LEGEND_ROWS));
    const float px = text_px(o), lh = line_height(o), sw = FTM_FONT_CELL_H * px;
    size_t cols = 0;
    for (int i = 0; i < n; i++)
        if (strlen(rows[i]) > cols)
            cols = strlen(rows[i]);
    const float bw = (float)cols * FTM_FONT_CELL_W * px + sw + 20, bh = (float)n * lh + 8;
    float x0 = 6, y0 = (float)h - 6 - bh;
    if (y0 < hud_bottom + 6 && hud_right + 12 + bw <= (float)w)
        x0 = (float)w - 6 - bw; /* beside the HUD, not over it */
    box[0] = x0, box[1] = y0, box[2] = x0 + bw, box[3] = y0 + bh;
    return n;
}

static int legend_draw(const ftm_render *r, const ftm_render_opts *o, char rows[][96], int n,
                       const float box[4], float *buf)
{
    const ftm_tissue *t;
    int32_t nt = ftm_render_tissues(r, &t);
    const float px = text_px(o), lh = line_height(o), sw = FTM_FONT_CELL_H * px;
    const float bg[4] = {0.05f, 0.06f, 0.08f, 0.70f}, fg[4] = {0.92f, 0.95f, 0.90f, 1.0f};
    int k = text_box(buf, box[0], box[1], box[2] - box[0], box[3] - box[1], bg);
    for (int i = 0; i < n; i++) {
        const float y = box[1] + 6 + (float)i * lh;
        float x = box[0] + 6;
        const int ti = i - 1; /* row 0 is the title */
        if (ti >= 0 && ti < nt && ti < LEGEND_ROWS) {
            const float c[4] = {t[ti].color[0], t[ti].color[1], t[ti].color[2], 1.0f};
            k += text_box(buf + (size_t)k * TEXT_FLOATS, x, y, sw, sw, c);
        }
        k += text_line(buf + (size_t)k * TEXT_FLOATS, x + (i > 0 ? sw + 8 : 0), y, px, rows[i], fg);
    }
    return k;
}

static int probe_labels(const ftm_render *r, const ftm_client_view *v, const float mvp[16],
                        int w, int h, float px, float below, const float legend[4], float *buf)
{
    int n = 0, placed = 0;
    float boxes[16][4]; /* labels placed so far: x0, y0, x1, y1 */
    for (int32_t i = 0; i < v->nprobes; i++) {
        const ftm_client_probe *p = &v->probes[i];
        if (!p->have_hip)
            continue;
        ftm_instrument in;
        ftm_render_instrument(r, p, &in);
        const double up = 2.0 * in.tip_radius + in.shaft_length;
        const double x[3] = {in.tip.x + up * in.axis.x, in.tip.y + up * in.axis.y,
                             in.tip.z + up * in.axis.z};
        double c[4];
        for (int k = 0; k < 4; k++)
            c[k] = mvp[k] * x[0] + mvp[4 + k] * x[1] + mvp[8 + k] * x[2] + mvp[12 + k];
        if (!(c[3] > 1e-9))
            continue; /* behind the eye */
        const float sx = (float)((c[0] / c[3] * 0.5 + 0.5) * w);
        const float sy = (float)((0.5 - c[1] / c[3] * 0.5) * h);
        if (sx < -200 || sx > (float)w + 200 || sy > (float)h + 50) /* above: slides down */
            continue;
        char label[FTM_WIRE_DISPLAY_MAX + 16];
        participant_label(v, p, label, sizeof label);
        label[40] = '\0';
        float col[4] = {0, 0, 0, 1};
        ftm_render_participant_color(p->participant, col);
        const float tw = (float)strlen(label) * FTM_FONT_CELL_W * px;
        /* not under the HUD: down the shaft to just below it; not over
         * another's label: a line further down */
        const float lh = FTM_FONT_CELL_H * px + 6;
        float bx = sx + 6, by = fmaxf(sy - FTM_FONT_CELL_H * px - 4, below + 6);
        /* not over the legend: beside it */
        if (legend[2] > legend[0] && bx - 3 < legend[2] && bx + tw + 3 > legend[0] &&
            by - 2 < legend[3] && by + lh > legend[1])
            bx = legend[2] + 6;
        for (int moved = 1; moved;) {
            moved = 0;
            for (int k = 0; k < placed; k++)
                if (bx < boxes[k][2] && bx + tw > boxes[k][0] && by < boxes[k][3] &&
                    by + lh > boxes[k][1]) {
                    by = boxes[k][3] + 1;
                    moved = 1;
                }
        }
        if (placed < 16) {
            boxes[placed][0] = bx - 3, boxes[placed][1] = by - 2;
            boxes[placed][2] = bx + tw + 3, boxes[placed][3] = by + lh - 2;
            placed++;
        }
        const float bg[4] = {0.05f, 0.06f, 0.08f, 0.65f};
        n += text_box(buf + (size_t)n * TEXT_FLOATS, bx - 3, by - 2, tw + 6,
                      FTM_FONT_CELL_H * px + 4, bg);
        n += text_line(buf + (size_t)n * TEXT_FLOATS, bx, by, px, label, col);
    }
    return n;
}

static void draw_text(ftm_render *r, const ftm_client_view *v, int w, int h,
                      const ftm_render_opts *o, const char *const *hud, int nhud,
                      const float mvp[16])
{
    size_t chars = 3 + strlen(v->banner) + (size_t)v->nprobes * 60;
    for (int i = 0; i < nhud; i++)
        chars += strlen(hud[i]) + 1;
    for (int i = 0; o->help && i < o->nhelp; i++)
        chars += strlen(o->help[i]) + 1;
    float px = text_px(o), lh = line_height(o);
    float hud_bottom = o->hud && nhud > 0 ? (float)ftm_render_hud_height(o, nhud) : 0.0f;
    float hud_right = 0;
    for (int i = 0; o->hud && i < nhud; i++)
        hud_right = fmaxf(hud_right, 18 + (float)strlen(hud[i]) * FTM_FONT_CELL_W * px);
    char legend[LEGEND_ROWS + 2][96];
    int nlegend = legend_layout(r, o, w, h, hud_bottom, hud_right, legend, r->legend_box);
    for (int i = 0; i < nlegend; i++)
        chars += strlen(legend[i]) + 2;
    float *buf = scratch(r, (chars + 4) * 6 * TEXT_FLOATS);
    if (!buf)
        return;
    int n = probe_labels(r, v, mvp, w, h, px, hud_bottom, r->legend_box, buf); /* under the banners */
    if (nlegend)
        n += legend_draw(r, o, legend, nlegend, r->legend_box, buf + (size_t)n * TEXT_FLOATS);
    if (o->hud && nhud > 0) {
        size_t wmax = 0;
        for (int i = 0; i < nhud; i++)
            if (strlen(hud[i]) > wmax)
                wmax = strlen(hud[i]);
        const float bg[4] = {0.05f, 0.06f, 0.08f, 0.70f}, fg[4] = {0.92f, 0.95f, 0.90f, 1.0f};
        n += text_box(buf + (size_t)n * TEXT_FLOATS, 6, 6,
                      (float)wmax * FTM_FONT_CELL_W * px + 12, nhud * lh + 8, bg);
        for (int i = 0; i < nhud; i++)
            n += text_line(buf + (size_t)n * TEXT_FLOATS, 12, 12 + i * lh, px, hud[i], fg);
    }
    if (v->banner[0]) {
        /* long messages (file paths) wrap at spaces to fit the window */
        int cols = (int)(((float)w - 40) / (FTM_FONT_CELL_W * px));
        if (cols < 8)
            cols = 8;
        char rows[6][256];
        int nrows = 0, wmax = 0;
        const char *p = v->banner;
        while (*p && nrows < 6) {
            int len = (int)strlen(p);
            int take = len <= cols ? len : cols;
            if (take < len) {
                int sp = take;
                while (sp > cols / 2 && p[sp] != ' ')
                    sp--;
                if (p[sp] == ' ')
                    take = sp;
            }
            if (take > 255)
                take = 255;
            memcpy(rows[nrows], p, (size_t)take);
            rows[nrows][take] = '\0';
            if (take > wmax)
                wmax = take;
            nrows++;
            p += take;
            while (*p == ' ')
                p++;
        }
        float bw = (float)wmax * FTM_FONT_CELL_W * px;
        float bx = 0.5f * ((float)w - bw), by = (float)h * 0.12f;
        if (by < hud_bottom + 16) /* below the HUD, not over it */
            by = hud_bottom + 16;
        if (bx < 4)
            bx = 4;
        const float red[4] = {0.70f, 0.08f, 0.06f, 0.88f}, grey[4] = {0.20f, 0.22f, 0.26f, 0.85f};
        const float fg[4] = {1, 1, 1, 1};
        n += text_box(buf + (size_t)n * TEXT_FLOATS, bx - 10, by - 8, bw + 20,
                      (float)nrows * lh + 12, v->banner_error ? red : grey);
        for (int i = 0; i < nrows; i++) {
            float rx = 0.5f * ((float)w - (float)strlen(rows[i]) * FTM_FONT_CELL_W * px);
            n += text_line(buf + (size_t)n * TEXT_FLOATS, rx, by + (float)i * lh, px, rows[i], fg);
        }
    }
    if (o->help && o->nhelp > 0) {
        /* the help overlay: a deep blue panel in the middle, over the rest */
        size_t wmax = 0;
        for (int i = 0; i < o->nhelp; i++)
            if (strlen(o->help[i]) > wmax)
                wmax = strlen(o->help[i]);
        float hp = px, bw, bh;
        while (hp > 1 && ((float)wmax * FTM_FONT_CELL_W * hp + 32 > (float)w ||
                          (float)o->nhelp * (FTM_FONT_CELL_H + 2) * hp + 32 > (float)h))
            hp -= 1; /* a small window: a smaller font rather than cut off */
        bw = (float)wmax * FTM_FONT_CELL_W * hp;
        bh = (float)o->nhelp * (FTM_FONT_CELL_H + 2) * hp;
        float bx = 0.5f * ((float)w - bw), by = 0.5f * ((float)h - bh);
        if (bx < 16)
            bx = 16;
        if (by < 16)
            by = 16;
        const float bg[4] = {0.06f, 0.10f, 0.36f, 0.94f}, fg[4] = {1, 1, 1, 1};
        n += text_box(buf + (size_t)n * TEXT_FLOATS, bx - 16, by - 14, bw + 32, bh + 24, bg);
        for (int i = 0; i < o->nhelp; i++)
            n += text_line(buf + (size_t)n * TEXT_FLOATS, bx, by + (float)i * (FTM_FONT_CELL_H + 2) * hp,
                           hp, o->help[i], fg);
    }
    if (!n)
        return;
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(r->text);
    glUniform2f(r->text_screen, (float)w, (float)h);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, r->font_tex);
    glUniform1i(r->text_tex, 0);
    glBindVertexArray(r->text_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->text_vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)n * TEXT_FLOATS * sizeof(float)), buf,
                 GL_STREAM_DRAW);
    glDrawArrays(GL_TRIANGLES, 0, n);
    glDisable(GL_BLEND);
}

void ftm_render_draw(ftm_render *r, const ftm_client_view *v, const ftm_camera *cam, int w, int h,
                     double top, const ftm_render_opts *o, const char *const *hud, int nhud)
{
    glViewport(0, 0, w, h);
    glClearColor(0.11f, 0.12f, 0.15f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    float mvp[16];
    ftm_camera_matrix(cam, w, h, top, mvp);
    ftm_vec3 eye = ftm_camera_eye(cam);
    static const float identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    double full = o->colormap_full > 0 ? o->colormap_full : (r->link > 0 ? 0.5 * r->link : 1e-3);

    /* the volume, when drawn, stands for the surface */
    bool volume = o->volume && ftm_volume_render_active(r->vol);
    glUseProgram(r->lit);
    glUniformMatrix4fv(r->lit_mvp, 1, GL_FALSE, mvp);
    glUniform3f(r->lit_eye, (float)eye.x, (float)eye.y, (float)eye.z);
    glUniform1f(r->lit_full, (float)full);
    if (r->mesh && r->ntri > 0 && !volume) {
        glUniformMatrix4fv(r->lit_model, 1, GL_FALSE, identity);
        glBindVertexArray(r->surf_vao);
        if (r->labelled) { /* each triangle its tissue's colour */
            glUseProgram(r->tis);
            glUniformMatrix4fv(r->tis_mvp, 1, GL_FALSE, mvp);
            glUniformMatrix4fv(r->tis_model, 1, GL_FALSE, identity);
            glUniform3f(r->tis_eye, (float)eye.x, (float)eye.y, (float)eye.z);
            glUniform1f(r->tis_full, (float)full);
            glUniform1i(r->tis_usemap, o->colormap ? 1 : 0);
            glUniform1i(r->tis_tricolor, 1);
            glActiveTexture(GL_TEXTURE1);
            glBindTexture(GL_TEXTURE_BUFFER, r->tri_tex);
            glActiveTexture(GL_TEXTURE0);
            glDrawElements(GL_TRIANGLES, 3 * r->ntri, GL_UNSIGNED_INT, (void *)0);
            glUseProgram(r->lit);
        } else {
            float tc[3];
            ftm_tissue_color(0, tc);
            glUniform3f(r->lit_color, tc[0], tc[1], tc[2]);
            glUniform1i(r->lit_usemap, o->colormap ? 1 : 0);
            glDrawElements(GL_TRIANGLES, 3 * r->ntri, GL_UNSIGNED_INT, (void *)0);
        }
    }
    /* probes: the instrument (tip and shaft) at each HIP, contact markers */
    glUniform1i(r->lit_usemap, 0);
    double link = r->link > 0 ? r->link : 0.01;
    glBindVertexArray(r->sph_vao);
    for (int32_t i = 0; i < v->nprobes; i++) {
        const ftm_client_probe *p = &v->probes[i];
        float c[3];
        probe_color(p, c);
        if (p->have_hip) {
            ftm_instrument in;
            ftm_render_instrument(r, p, &in);
            const ftm_vec3 a = in.axis, t = in.tip;
            const double rt = in.tip_radius;
            sphere_at(r, (ftm_vec3){t.x + rt * a.x, t.y + rt * a.y, t.z + rt * a.z}, rt, c);
        }
        if (p->in_contact) {
            const float white[3] = {0.97f, 0.97f, 0.97f};
            sphere_at(r, p->contact, 0.18 * link, white);
        }
    }
    glBindVertexArray(r->cyl_vao);
    glUniform3f(r->lit_color, FTM_SHAFT_R, FTM_SHAFT_G, FTM_SHAFT_B);
    for (int32_t i = 0; i < v->nprobes; i++) {
        const ftm_client_probe *p = &v->probes[i];
        if (!p->have_hip)
            continue;
        ftm_instrument in;
        ftm_render_instrument(r, p, &in);
        const ftm_vec3 a = in.axis, t = in.tip;
        float model[16];
        oriented(model, (ftm_vec3){t.x + in.tip_radius * a.x, t.y + in.tip_radius * a.y,
                                   t.z + in.tip_radius * a.z},
                 a, in.shaft_radius, in.shaft_length);
        glUniformMatrix4fv(r->lit_model, 1, GL_FALSE, model);
        glDrawElements(GL_TRIANGLES, r->cyl_count, GL_UNSIGNED_INT, (void *)0);
    }
    /* lines from each HIP to its contact; from each probe out of contact
     * down its axis to the surface below it, with a shadow there; the
     * region's nodes */
    enum { DISC = 24 };
    size_t nl = 0, nd = 0;
    ftm_vec3 below[FTM_CLIENT_MAX_PROBES], below_n[FTM_CLIENT_MAX_PROBES];
    bool has_below[FTM_CLIENT_MAX_PROBES];
    for (int32_t i = 0; i < v->nprobes; i++) {
        const ftm_client_probe *p = &v->probes[i];
        has_below[i] = false;
        if (p->have_hip && p->in_contact)
            nl++;
        else if (p->have_hip) {
            ftm_instrument in;
            ftm_render_instrument(r, p, &in);
            double dist;
            ftm_vec3 down = {-in.axis.x, -in.axis.y, -in.axis.z};
            if (ftm_render_surface_along(r, in.tip, down, &dist, &below_n[i])) {
                has_below[i] = true;
                below[i] = (ftm_vec3){in.tip.x + dist * down.x, in.tip.y + dist * down.y,
                                      in.tip.z + dist * down.z};
                nl++;
                nd++;
            }
        }
    }
    size_t npts = o->region && v->pos ? (size_t)v->region_count : 0;
    float *buf = scratch(r, (nl * 2 + nd * DISC * 3 + npts + 1) * 3);
    if (!buf)
        nl = nd = npts = 0;
    glUseProgram(r->flat);
    glUniformMatrix4fv(r->flat_mvp, 1, GL_FALSE, mvp);
    if (nl || npts) {
        size_t k = 0;
        for (int32_t i = 0; i < v->nprobes; i++) {
            const ftm_client_probe *p = &v->probes[i];
            if (!p->have_hip || !(p->in_contact || has_below[i]))
                continue;
            const ftm_vec3 e = p->in_contact ? p->contact : below[i];
            float seg[6] = {(float)p->hip.x, (float)p->hip.y, (float)p->hip.z,
                            (float)e.x,      (float)e.y,      (float)e.z};
            memcpy(buf + k, seg, sizeof seg);
            k += 6;
        }
        /* the shadows: discs on the surface below, a hair above it */
        for (int32_t i = 0; i < v->nprobes; i++) {
            if (!has_below[i])
                continue;
            ftm_vec3 n = below_n[i];
            if (n.x * v->probes[i].hip.x + n.y * v->probes[i].hip.y + n.z * v->probes[i].hip.z <
                n.x * below[i].x + n.y * below[i].y + n.z * below[i].z)
                n = (ftm_vec3){-n.x, -n.y, -n.z}; /* towards the probe */
            float m[16];
            const double lift = 0.02 * link;
            oriented(m, (ftm_vec3){below[i].x + lift * n.x, below[i].y + lift * n.y,
                                   below[i].z + lift * n.z},
                     n, r->tool.tip_radius > 0 ? r->tool.tip_radius : TIP_LINKS * link, 0.0);
            for (int j = 0; j < DISC; j++) {
                const double t0 = 2.0 * 3.14159265358979323846 * j / DISC,
                             t1 = 2.0 * 3.14159265358979323846 * (j + 1) / DISC;
                const double xy[3][2] = {{0, 0}, {cos(t0), sin(t0)}, {cos(t1), sin(t1)}};
                for (int q = 0; q < 3; q++)
                    for (int d = 0; d < 3; d++)
                        buf[k++] = (float)(m[d] * xy[q][0] + m[4 + d] * xy[q][1] + m[12 + d]);
            }
        }
        for (size_t i = 0; i < npts; i++) {
            const double *q = v->pos + 3 * (size_t)v->region[i];
            buf[k++] = (float)q[0];
            buf[k++] = (float)q[1];
            buf[k++] = (float)q[2];
        }
        glBindVertexArray(r->dyn_vao);
        glBindBuffer(GL_ARRAY_BUFFER, r->dyn_vbo);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(k * sizeof(float)), buf, GL_STREAM_DRAW);
        if (nl) {
            glUniform4f(r->flat_color, 1.0f, 1.0f, 1.0f, 1.0f);
            glDrawArrays(GL_LINES, 0, (GLsizei)(2 * nl));
        }
        if (nd) {
            glEnable(GL_BLEND);
            glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
            glDepthMask(GL_FALSE);
            glUniform4f(r->flat_color, 0.0f, 0.0f, 0.0f, 0.45f);
            glDrawArrays(GL_TRIANGLES, (GLint)(2 * nl), (GLsizei)(nd * DISC * 3));
            glDepthMask(GL_TRUE);
            glDisable(GL_BLEND);
        }
    }
    if (volume) {
        /* after everything opaque: the slices, back to front, then the
         * control lattice's surface as a faint cage over them */
        ftm_volume_render_draw(r->vol, mvp, eye, o->colormap, o->cut, o->volume_step,
                               o->volume_scale, full, w, h);
        if (r->mesh && r->cage_count > 0) {
            glUseProgram(r->flat);
            glEnable(GL_BLEND);
            glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
            glDepthMask(GL_FALSE);
            glUniform4f(r->flat_color, 0.75f, 0.85f, 1.0f, 0.14f);
            glBindVertexArray(r->cage_vao);
            glDrawElements(GL_LINES, r->cage_count, GL_UNSIGNED_INT, (void *)0);
            glDepthMask(GL_TRUE);
            glDisable(GL_BLEND);
        }
    }
    if (npts) {
        /* the region shows through the surface: it is mostly inside */
        glUseProgram(r->flat);
        glBindVertexArray(r->dyn_vao);
        glDisable(GL_DEPTH_TEST);
        glEnable(GL_PROGRAM_POINT_SIZE);
        glUniform1f(r->flat_size, 4.0f);
        glUniform4f(r->flat_color, 1.0f, 0.92f, 0.2f, 1.0f);
        glDrawArrays(GL_POINTS, (GLint)(2 * nl + nd * DISC * 3), (GLsizei)npts);
        glEnable(GL_DEPTH_TEST);
    }
    glBindVertexArray(0);
    draw_text(r, v, w, h, o, hud, nhud, mvp);
}

void ftm_render_set_tool(ftm_render *r, ftm_scene_tool tool) { r->tool = tool; }
