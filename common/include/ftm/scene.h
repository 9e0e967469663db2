/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Scenes: a mesh (generator or file), material, simulation parameters and a
 * scripted load, from a human-readable text file (docs/scene-format.md) or a
 * built-in name. Used by `ftm sim`, and later by the server and clients, which
 * must build the same mesh from the same scene to replay bit-identically. */
#ifndef FTM_SCENE_H
#define FTM_SCENE_H

#include "ftm/generate.h"
#include "ftm/sim.h"
#include "ftm/labels.h"
#include "ftm/volume.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_scene ftm_scene;

/* How a scripted load's magnitude varies with time t (seconds since start). */
typedef enum ftm_ramp {
    FTM_RAMP_CONSTANT = 0, /* full value from start until end */
    FTM_RAMP_LINEAR = 1,   /* 0 at start rising linearly to full value at end, then held until release */
    FTM_RAMP_TRIANGLE = 2, /* 0 at start, full value at the midpoint, 0 again at end */
} ftm_ramp;

/* One scripted load: a contact active from start to release (seconds). */
typedef struct ftm_scene_load {
    ftm_contact contact; /* node is a mesh index; value is the full magnitude */
    double start;        /* [s] */
    double end;          /* [s], for ramps */
    double release;      /* [s]; INFINITY = never */
    ftm_ramp ramp;
} ftm_scene_load;

/* Parses a scene file. Errors name the file and line. */
int ftm_scene_load_file(const char *path, ftm_scene **out, ftm_error *err);
/* Parses scene text held in memory; name is used in error messages. */
int ftm_scene_parse(const char *text, size_t length, const char *name, ftm_scene **out,
                    ftm_error *err);
/* Built-in scenes by name (see ftm_scene_builtin_names). */
int ftm_scene_builtin(const char *name, ftm_scene **out, ftm_error *err);
/* NULL-terminated list of built-in scene names. */
const char *const *ftm_scene_builtin_names(void);
/* A name that is a built-in loads it, anything else is read as a file. */
int ftm_scene_open(const char *name_or_path, ftm_scene **out, ftm_error *err);
/* As ftm_scene_open, for a scene named by another machine (a server's
 * announcement, a deployment's configuration): when name_or_path is neither
 * a built-in nor a file, the file of the same base name is looked for in each
 * directory of `search` (':'-separated, in order; NULL or "" for none). The
 * path opened is written to `path` (the name for a built-in) when path_cap
 * is not 0. FTM_ENOENT names every place tried. */
int ftm_scene_open_search(const char *name_or_path, const char *search, ftm_scene **out,
                          char *path, size_t path_cap, ftm_error *err);
void ftm_scene_destroy(ftm_scene *scene);

const char *ftm_scene_name(const ftm_scene *scene);
const ftm_mesh *ftm_scene_mesh(const ftm_scene *scene);
ftm_sim_def ftm_scene_sim_def(const ftm_scene *scene);
/* The word a scene's `[sim] forces` uses for a force model ("springs",
 * "linear-fem", "corot-fem", "neo-hookean"); "?" for no model. */
const char *ftm_forces_name(ftm_forces forces);
/* The model the scene runs, in one line for a log or a summary: the force
 * model and its material, the far field, the depth; for springs, whether
 * the mesh could take element forces (volume elements) or not (a surface).
 * snprintf's contract: the length the whole line needs. */
int ftm_scene_describe_model(const ftm_scene *scene, char *buf, size_t size);
/* The [material] the scene's mesh was built with (for ftm_mesh_with_material). */
ftm_material_def ftm_scene_material(const ftm_scene *scene);
int32_t ftm_scene_steps(const ftm_scene *scene); /* default number of steps to run */
int32_t ftm_scene_load_count(const ftm_scene *scene);
const ftm_scene_load *ftm_scene_loads(const ftm_scene *scene);

/* The elastic material of the scene's [fem] section (the linear FEM
 * reference, `ftm fem`): Young's modulus [Pa], Poisson's ratio and density
 * [kg/m^3] (0 when the scene gives none). Returns false, writing nothing, when
 * the scene has no [fem] section. Any pointer may be NULL. */
bool ftm_scene_fem_material(const ftm_scene *scene, double *young, double *poisson,
                            double *density);
/* The scene's [fem LABEL] sections, in the file's order (*count of them;
 * NULL and 0 without any): the materials of the elements of those labels,
 * the [fem] material being every other element's (ftm fem passes them to
 * ftm_fem as per-element materials). count may be NULL. */
const ftm_label_material *ftm_scene_label_materials(const ftm_scene *scene, int32_t *count);
/* The `name` a [fem LABEL] section gives its label (printable ASCII, at
 * most FTM_SCENE_LABEL_NAME_MAX characters: a legend's "grey matter"); NULL
 * when the scene names it nowhere. */
#define FTM_SCENE_LABEL_NAME_MAX 40
const char *ftm_scene_label_name(const ftm_scene *scene, int32_t label);

/* The scene's [tool] (docs/scene-format.md): the instrument a trainee holds,
 * as the client draws it [m]; 0 where the scene gives none (the client then
 * scales its own to the mesh). The physics does not use it: the contact is
 * the point at the tip (paper section 3.3). */
typedef struct ftm_scene_tool {
    double tip_radius, shaft_radius, shaft_length;
} ftm_scene_tool;
ftm_scene_tool ftm_scene_get_tool(const ftm_scene *scene);

/* The scene's [volume] (paper section 4.2): the image, and its embedding in
 * the scene's mesh, which is then the volume's control lattice
 * (docs/scene-format.md). NULL both for a scene without one. */
const ftm_volume *ftm_scene_volume(const ftm_scene *scene);
const ftm_ffd *ftm_scene_ffd(const ftm_scene *scene);
/* [volume] labels: the label map on the image's voxels (the same counts,
 * voxel size and box), for drawing the image by tissue; NULL without one. */
const ftm_label_map *ftm_scene_volume_labels(const ftm_scene *scene);

/* The contacts the script prescribes at simulation time t [s]: writes at most
 * capacity entries and returns how many are active (loads not yet started or
 * already released are left out; ramps scale the value). */
int32_t ftm_scene_contacts_at(const ftm_scene *scene, double t, ftm_contact *contacts,
                              int32_t capacity);

/* ---- what a press feels like (docs/feel.md, "Can a trainee feel it") ---- */

/* What a 5-10 mm press gives on soft tissue a hand palpates, in newtons. */
#define FTM_PALPATION_MIN_N 1.0
#define FTM_PALPATION_MAX_N 10.0
/* The press depth the server and client estimate a scene's feel at [m]. */
#define FTM_PRESS_ESTIMATE_DEPTH 0.0075

typedef struct ftm_press_estimate {
    int32_t triangle; /* the surface triangle pressed; -1: the scene's scripted press */
    ftm_vec3 point;   /* where (rest): the first pressed node, or the top point */
    ftm_vec3 push;    /* the displacement imposed on its free vertices [m] */
    double depth;     /* |push| [m] */
    double force;     /* the reaction's magnitude, held press [N] */
    int32_t substeps; /* the guard's substeps at the end (1: stable as given) */
} ftm_press_estimate;

/* The force of a press `depth` deep, made as the server makes a probe's (a
 * triangle's vertices displaced together) on the scene's own model, depth
 * and far field: where the scene scripts a press, its first displacement
 * group's nodes (up to three) along that load's direction; else the surface
 * triangle at the top (the one the vertical through the bounding box's
 * centre crosses highest, else the highest facing up) along its inward
 * normal. Ramped over 0.25 s, held 0.25 s, the reaction averaged over the
 * last 50 ms. Costs half a simulated second of the contact region.
 * FTM_ENOENT: nothing to press (a planar mesh with no load); FTM_EUNSTABLE:
 * the press diverged. triangle is -1 for a scripted press. */
int ftm_scene_press_estimate(const ftm_scene *scene, double depth, ftm_press_estimate *out,
                             ftm_error *err);
/* -1 a decade or more below the palpation range, 1 a decade above, else 0. */
int ftm_press_verdict(const ftm_press_estimate *e);
/* The estimate in one line for a log ("a 7.5 mm press on the top gives
 * 0.0146 N: far softer than ..."); snprintf's contract. */
int ftm_press_describe(const ftm_press_estimate *e, char *buf, size_t size);

#ifdef __cplusplus
}
#endif
#endif
