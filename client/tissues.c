/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Surface triangles' tissues, colours and legend rows; see tissues.h. */
#include "tissues.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Tissue-like and told apart side by side: rose (grey matter, muscle
 * surface), ivory (white matter, fat), dark red (muscle), liver brown,
 * bluish cartilage, yellow fat, vessel purple, bile green, orange, slate. */
static const float palette[FTM_TISSUE_PALETTE][3] = {
    {0.80f, 0.36f, 0.40f}, {0.93f, 0.86f, 0.66f}, {0.66f, 0.20f, 0.18f}, {0.52f, 0.30f, 0.20f},
    {0.60f, 0.72f, 0.80f}, {0.92f, 0.74f, 0.30f}, {0.55f, 0.36f, 0.62f}, {0.52f, 0.64f, 0.38f},
    {0.90f, 0.55f, 0.26f}, {0.50f, 0.52f, 0.58f}};

void ftm_tissue_color(int32_t label, float c[3])
{
    if (label <= 0) { /* the client's tissue colour, as before labels */
        c[0] = 0.86f, c[1] = 0.56f, c[2] = 0.52f;
        return;
    }
    memcpy(c, palette[(label - 1) % FTM_TISSUE_PALETTE], 3 * sizeof(float));
}

static bool has(const int32_t *v, int n, int32_t x)
{
    for (int i = 0; i < n; i++)
        if (v[i] == x)
            return true;
    return false;
}

int ftm_tissue_surface_labels(const ftm_mesh *mesh, int32_t *labels)
{
    const int32_t n = ftm_mesh_node_count(mesh), ntri = ftm_mesh_triangle_count(mesh);
    const int32_t ntet = ftm_mesh_tetrahedron_count(mesh), nhex = ftm_mesh_hexahedron_count(mesh);
    const int32_t *tri = ftm_mesh_triangles(mesh), *tet = ftm_mesh_tetrahedra(mesh),
                  *hex = ftm_mesh_hexahedra(mesh);
    const int32_t *tl = ftm_mesh_tetrahedron_labels(mesh), *hl = ftm_mesh_hexahedron_labels(mesh);
    if (ntet + nhex == 0) { /* a surface: no elements to take a label from */
        memset(labels, 0, (size_t)ntri * sizeof *labels);
        return FTM_OK;
    }
    /* the elements at each node (CSR): tetrahedron e is e, hexahedron e is ntet + e */
    const size_t entries = 4 * (size_t)ntet + 8 * (size_t)nhex;
    int32_t *start = calloc((size_t)n + 1, sizeof *start);
    int32_t *elem = malloc(entries * sizeof *elem);
    if (!start || !elem) {
        free(start);
        free(elem);
        return FTM_ENOMEM;
    }
    for (size_t i = 0; i < 4 * (size_t)ntet; i++)
        start[tet[i] + 1]++;
    for (size_t i = 0; i < 8 * (size_t)nhex; i++)
        start[hex[i] + 1]++;
    for (int32_t i = 0; i < n; i++)
        start[i + 1] += start[i];
    int32_t *fill = malloc(((size_t)n + 1) * sizeof *fill);
    if (!fill) {
        free(start);
        free(elem);
        return FTM_ENOMEM;
    }
    memcpy(fill, start, (size_t)n * sizeof *fill);
    for (int32_t e = 0; e < ntet; e++)
        for (int k = 0; k < 4; k++)
            elem[fill[tet[4 * (size_t)e + k]]++] = e;
    for (int32_t e = 0; e < nhex; e++)
        for (int k = 0; k < 8; k++)
            elem[fill[hex[8 * (size_t)e + k]]++] = ntet + e;
    free(fill);
    for (int32_t t = 0; t < ntri; t++) {
        const int32_t a = tri[3 * (size_t)t], b = tri[3 * (size_t)t + 1], c = tri[3 * (size_t)t + 2];
        int found = 0;
        int32_t label = 0;
        for (int32_t i = start[a]; i < start[a + 1]; i++) {
            const int32_t e = elem[i];
            const bool is_tet = e < ntet;
            const int32_t *v = is_tet ? tet + 4 * (size_t)e : hex + 8 * (size_t)(e - ntet);
            if (!has(v, is_tet ? 4 : 8, b) || !has(v, is_tet ? 4 : 8, c))
                continue;
            if (found++ == 0)
                label = is_tet ? (tl ? tl[e] : 0) : (hl ? hl[e - ntet] : 0);
        }
        labels[t] = found > 1 ? FTM_TISSUE_INTERIOR : label;
    }
    free(start);
    free(elem);
    return FTM_OK;
}

static int cmp_i32(const void *x, const void *y)
{
    int32_t a = *(const int32_t *)x, b = *(const int32_t *)y;
    return a < b ? -1 : a > b;
}

int32_t ftm_tissue_list(const int32_t *labels, int32_t ntri, const ftm_mesh *mesh,
                        const ftm_scene *scene, ftm_tissue *out, int32_t cap)
{
    if (ntri <= 0 || cap <= 0)
        return 0;
    int32_t *sorted = malloc((size_t)ntri * sizeof *sorted);
    if (!sorted)
        return 0;
    memcpy(sorted, labels, (size_t)ntri * sizeof *sorted);
    qsort(sorted, (size_t)ntri, sizeof *sorted, cmp_i32);
    double young0 = 0;
    int32_t nmat = 0;
    const ftm_label_material *mats = NULL;
    if (scene) {
        if (!ftm_scene_fem_material(scene, &young0, NULL, NULL))
            young0 = 0;
        mats = ftm_scene_label_materials(scene, &nmat);
    }
    int32_t count = 0;
    for (int32_t i = 0; i < ntri && count < cap;) {
        const int32_t label = sorted[i];
        int32_t j = i;
        while (j < ntri && sorted[j] == label)
            j++;
        if (label != FTM_TISSUE_INTERIOR) {
            ftm_tissue *t = &out[count++];
            memset(t, 0, sizeof *t);
            t->label = label;
            t->triangles = j - i;
            ftm_tissue_color(label, t->color);
            const char *name = scene && label > 0 ? ftm_scene_label_name(scene, label) : NULL;
            if (!name && mesh && label > 0)
                name = ftm_mesh_label_name(mesh, label);
            if (name)
                snprintf(t->name, sizeof t->name, "%s", name);
            else if (label > 0)
                snprintf(t->name, sizeof t->name, "label %d", (int)label);
            else
                snprintf(t->name, sizeof t->name, "unlabelled");
            t->young = young0; /* [fem]: every label without its own section */
            for (int32_t m = 0; m < nmat; m++)
                if (mats[m].label == label)
                    t->young = mats[m].young;
        }
        i = j;
    }
    free(sorted);
    return count;
}

void ftm_tissue_legend_text(const ftm_tissue *t, char *buf, size_t cap)
{
    if (!(t->young > 0)) {
        snprintf(buf, cap, "%s", t->name);
        return;
    }
    /* E in the unit that keeps it short: soft tissue is Pa to MPa */
    const double e = t->young;
    if (e >= 1e6)
        snprintf(buf, cap, "%s  E %.3g MPa", t->name, e / 1e6);
    else if (e >= 1e3)
        snprintf(buf, cap, "%s  E %.3g kPa", t->name, e / 1e3);
    else
        snprintf(buf, cap, "%s  E %.3g Pa", t->name, e);
}
