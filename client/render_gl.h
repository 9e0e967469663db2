/* SPDX-License-Identifier: GPL-3.0-or-later */
/* What the client's drawing code shares between its files (render.c, the
 * surface, probes and HUD; volume_render.c, the embedded volume): shader
 * programs and the displacement colour map. Render thread only, with the
 * context current. */
#ifndef FTM_CLIENT_RENDER_GL_H
#define FTM_CLIENT_RENDER_GL_H

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "ftm/base.h"

/* Compiles and links a program; 0 and err filled ("OpenGL: WHAT: log") on
 * failure. */
GLuint ftm_gl_program(const char *vs, const char *fs, const char *what, ftm_error *err);
/* The same error for anything else that fails while setting up. */
int ftm_gl_fail(ftm_error *err, const char *what, const char *log);

/* Attributes 0, 1 and 2 of vertices of 7 floats (3, 3 and 1: position,
 * normal or texture coordinate, displacement) in the bound array buffer,
 * into the bound vertex array. */
void ftm_gl_layout_331(void);
/* Filter (GL_NEAREST, GL_LINEAR) both ways and clamp to edge on every axis
 * of the texture bound to target (GL_TEXTURE_2D, GL_TEXTURE_3D). */
void ftm_gl_texture_params(GLenum target, GLint filter);

/* GLSL source of `vec3 ramp(float t)`: the displacement colour map (blue at
 * 0, through teal and yellow, to red at 1), for every shader that colours
 * by displacement (a string literal, to paste into a shader's source). */
#define FTM_GL_RAMP_GLSL                                                                          \
    "vec3 ramp(float t) {\n"                                                                      \
    "  t = clamp(t, 0.0, 1.0);\n"                                                                 \
    "  vec3 c0 = vec3(0.22,0.33,0.72), c1 = vec3(0.16,0.66,0.62), c2 = vec3(0.95,0.84,0.25),\n"   \
    "       c3 = vec3(0.86,0.14,0.10);\n"                                                         \
    "  if (t < 1.0/3.0) return mix(c0, c1, t * 3.0);\n"                                           \
    "  if (t < 2.0/3.0) return mix(c1, c2, t * 3.0 - 1.0);\n"                                     \
    "  return mix(c2, c3, t * 3.0 - 2.0);\n"                                                      \
    "}\n"

#endif
