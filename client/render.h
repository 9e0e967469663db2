/* SPDX-License-Identifier: GPL-3.0-or-later */
/* OpenGL 3.3 core drawing of the client: the deformed surface (normals
 * recomputed from the replayed positions), an optional colour map of the
 * displacement magnitude, the probes (HIPs) and their contacts, the active
 * BFS region, the HUD text, and a scene's embedded volume (volume_render.h)
 * in place of the surface, which is then a light wireframe. Runs on the render thread only, with the
 * context current. */
#ifndef FTM_CLIENT_RENDER_H
#define FTM_CLIENT_RENDER_H

#include "camera.h"
#include "client_session.h"
#include "tissues.h"

typedef struct ftm_render ftm_render;

typedef struct ftm_render_opts {
    bool colormap;        /* colour by |x - X| instead of the tissue colour */
    double colormap_full; /* [m] displacement drawn at the top of the map */
    bool region;          /* draw the BFS region's nodes */
    bool hud;
    int text_scale;       /* HUD pixels per font pixel */
    bool volume;          /* the scene's volume, if it has one, rather than its surface */
    bool cut;             /* the volume's half nearer the eye left out: its inside shows */
    int volume_step;      /* draw every step-th slice: 1 (the paper's 9 between node
                           * planes), 2, 5 or 10 (the node planes only) */
    /* the help overlay's lines (F1), drawn in a panel in the middle of the
     * window over everything; nhelp 0: none */
    const char *const *help;
    int nhelp;
    double volume_scale;  /* the slices' framebuffer pixels per voxel (0: default) */
    bool legend;          /* the tissues' legend, for a mesh with labels (key l) */
} ftm_render_opts;

ftm_render_opts ftm_render_default_opts(void);

/* Compiles the shaders and makes the buffers and the font texture. */
int ftm_render_create(ftm_render **out, ftm_error *err);
void ftm_render_destroy(ftm_render *r);

/* The surface to draw: triangles of mesh (NULL: none), but those two
 * elements share (inside the body); each in the colour of its element's
 * label when the mesh has labels (tissues.h), named after scene's (may be
 * NULL) label names for the legend. */
int ftm_render_set_mesh(ftm_render *r, const ftm_mesh *mesh, const ftm_scene *scene,
                        ftm_error *err);
int32_t ftm_render_triangle_count(const ftm_render *r);
/* The legend's tissues (*out; may be NULL), in increasing label order: how
 * many, 0 for a mesh without labels. */
#define FTM_RENDER_MAX_TISSUES 256
int32_t ftm_render_tissues(const ftm_render *r, const ftm_tissue **out);
/* Where the last frame drew the legend: x0, y0, x1, y1 in pixels from the
 * top left; all 0 when it drew none. */
void ftm_render_legend_box(const ftm_render *r, float box[4]);
/* A point of tissue `label` the eye sees (the centre of its drawn triangle
 * that faces the eye most, not hidden by another): 1 and *point, or 0 (none
 * in sight). For a screenshot's checks. */
int ftm_render_tissue_point(const ftm_render *r, int32_t label, ftm_vec3 eye, ftm_vec3 *point);
/* Mean link length of the mesh set (0 without one): sizes the probe markers. */
double ftm_render_link_length(const ftm_render *r);

/* The instrument drawn at a probe: a tip sphere whose lowest point is the
 * HIP (the point the server collides) and a shaft from its centre along
 * the tool's axis: the outward normal where its contact began while in
 * contact, else straight up (+z, "up" in every FTM scene), the way the
 * wheel moves the mouse probe. Sizes from the scene's mean link length
 * (the scene format has no tool model): tip radius 0.3 links, shaft
 * radius 0.12 links, shaft 6 links long. */
/* the shaft's colour (steel), lit as the surface is */
#define FTM_SHAFT_R 0.66f
#define FTM_SHAFT_G 0.70f
#define FTM_SHAFT_B 0.76f
typedef struct ftm_instrument {
    ftm_vec3 tip;  /* the HIP */
    ftm_vec3 axis; /* unit, from the tip up the shaft */
    double tip_radius, shaft_radius, shaft_length; /* [m] */
} ftm_instrument;
void ftm_render_instrument(const ftm_render *r, const ftm_client_probe *p, ftm_instrument *out);

/* The scene's instrument ([tool]; zeros: sizes scaled to the mesh's links). */
void ftm_render_set_tool(ftm_render *r, ftm_scene_tool tool);

/* A participant's colour (RGB 0..1), by id: the same in every view. */
void ftm_render_participant_color(uint32_t participant, float c[3]);

/* The deformed surface (as last updated) along the ray from `from` in the
 * unit direction dir: 1 with *dist [m] to the nearest hit ahead and the
 * hit triangle's unit normal (either side; may be NULL), 0 when the ray
 * misses it (or no mesh). */
int ftm_render_surface_along(const ftm_render *r, ftm_vec3 from, ftm_vec3 dir, double *dist,
                             ftm_vec3 *normal);

/* The scene's volume and its embedding in the mesh set (both NULL: none),
 * and its label map (NULL: none; drawn in the tissues' colours,
 * volume_render.h); uploads the image. */
int ftm_render_set_volume(ftm_render *r, const ftm_volume *volume, const ftm_ffd *ffd,
                          const ftm_label_map *labels, ftm_error *err);
bool ftm_render_has_volume(const ftm_render *r);
/* Slices of the volume along the axis drawn last (0: no volume). */
int32_t ftm_render_volume_slices(const ftm_render *r);

/* New positions: recomputes normals and displacements, uploads them. */
void ftm_render_update(ftm_render *r, const ftm_client_view *v);

/* Pixel rows the HUD panel of nhud lines covers at the top (0 when off). */
double ftm_render_hud_height(const ftm_render_opts *o, int nhud);
/* The rows the view keeps clear for that HUD: its height rounded up to a
 * whole number of 4-line steps, so that a line more or less (a reaction, a
 * participant, a command's outcome) seldom moves the view. */
double ftm_render_view_top(const ftm_render_opts *o, int nhud);

/* One frame into the current framebuffer (w x h pixels): scene, framed in
 * the rows below the top `top` ones (ftm_camera_matrix), then hud lines at
 * the top left and the banner (if any) at the top centre. */
void ftm_render_draw(ftm_render *r, const ftm_client_view *v, const ftm_camera *cam, int w, int h,
                     double top, const ftm_render_opts *o, const char *const *hud, int nhud);

#endif
