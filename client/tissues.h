/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The tissues a mesh's surface shows: the label of the element each surface
 * triangle bounds (a Gmsh physical group, a TetGen region, a scan's label),
 * a colour per label and the legend's names. No GL: the renderer
 * (render.c) draws with it, test_tissues checks it. */
#ifndef FTM_CLIENT_TISSUES_H
#define FTM_CLIENT_TISSUES_H

#include "ftm/mesh.h"
#include "ftm/scene.h"

#include <stdbool.h>
#include <stdint.h>

/* A surface triangle that is a face two elements share (a file's triangle
 * between two tissues): inside the body, not drawn. */
#define FTM_TISSUE_INTERIOR (-1)

/* The label of the element each of the mesh's surface triangles bounds
 * (labels[t] for triangle t; 0 for an unlabelled element or a triangle that
 * bounds none, a surface mesh's), or FTM_TISSUE_INTERIOR for a face shared
 * by two elements. FTM_OK, or FTM_ENOMEM. */
int ftm_tissue_surface_labels(const ftm_mesh *mesh, int32_t *labels);

/* A label's colour (RGB 0..1): label 0 (unlabelled) the default tissue
 * colour, others from a palette of tissue-like colours distinguishable side
 * by side (it repeats after FTM_TISSUE_PALETTE labels). */
#define FTM_TISSUE_PALETTE 10
void ftm_tissue_color(int32_t label, float c[3]);

/* One row of the legend. */
#define FTM_TISSUE_NAME_MAX 48
typedef struct ftm_tissue {
    int32_t label;     /* 0: unlabelled */
    int32_t triangles; /* surface triangles drawn in it */
    float color[3];
    /* the scene's name ([fem LABEL] name), else the mesh's (a Gmsh physical
     * name), else "label N" ("unlabelled") */
    char name[FTM_TISSUE_NAME_MAX];
    double young;                   /* [Pa] from [fem LABEL] or [fem]; 0: not known */
} ftm_tissue;

/* The tissues of labels[0..ntri) (as ftm_tissue_surface_labels wrote them
 * for mesh), in increasing label order, at most cap of them (the rest left
 * out); named from scene, then mesh, and with E from scene (either may be
 * NULL: "label N", E unknown). Returns how many were written. A mesh without
 * labels has one, label 0. */
int32_t ftm_tissue_list(const int32_t *labels, int32_t ntri, const ftm_mesh *mesh,
                        const ftm_scene *scene, ftm_tissue *out, int32_t cap);

/* A legend row's text: "grey matter  E 2 kPa" (E left out when unknown). */
void ftm_tissue_legend_text(const ftm_tissue *t, char *buf, size_t cap);

#endif
