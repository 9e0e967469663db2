/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The built-in scenes: their texts, read as scene files are (docs/scenes/
 * has copies of them; test_cli checks they are the same), and their names. */
#include "scene_builtin.h"

#include "ftm/scene.h"

#include <stdio.h>
#include <string.h>

/* Built-in scenes are scene text, so they read exactly like files
 * (docs/scenes/ has copies of them). builtin_texts[i] belongs to builtin_names[i]. */
static const char *const builtin_names[] = {"default", "table3", "membrane", "head", "palpation",
                                            NULL};

static const char *const builtin_texts[] = {
    /* default */
    "# A 12x12x12 cube of soft tissue resting on its bottom face. A probe pushes\n"
    "# the centre of the top face 4 mm down, lets go at 0.5 s, and the tissue\n"
    "# relaxes back to rest.\n"
    "[scene]\n"
    "name = default\n"
    "[mesh]\n"
    "generator = lattice3d\n"
    "nx = 12\n"
    "ny = 12\n"
    "nz = 12\n"
    "spacing = 0.01\n"
    "stencil = 18\n"
    "fixed_faces = zmin\n"
    "[material]\n"
    "mass = 0.001\n"
    "# Heavy damping, as in real tissue; the layer-by-layer update needs some\n"
    "# (docs/core.md, \"Known limitation\").\n"
    "damping = 0.3\n"
    "stiffness = 50\n"
    "[sim]\n"
    "time_step = 1e-3\n"
    "depth = 8\n"
    "# beyond the depth, where the whole body would be: the force the probe\n"
    "# feels does not depend on the depth (docs/core.md, \"Far field\")\n"
    "far_field = elastic\n"
    "steps = 2000\n"
    "[load]\n"
    "# lattice point (6, 6, 11): input index 6 + 12 * (6 + 12 * 11)\n"
    "node = 1662\n"
    "kind = displacement\n"
    "value = 0 0 -0.004\n"
    "start = 0\n"
    "release = 0.5\n",
    /* table3 */
    "# The setup of Table 3 in Choi, Sun & Heng (2004): a 50x50 triangular\n"
    "# lattice with its border fixed and a constant in-plane force on the centre.\n"
    "[scene]\n"
    "name = table3\n"
    "[mesh]\n"
    "generator = lattice2d\n"
    "nx = 50\n"
    "ny = 50\n"
    "spacing = 1\n"
    "fixed_faces = xmin xmax ymin ymax\n"
    "[material]\n"
    "mass = 1\n"
    "damping = 1\n"
    "stiffness = 1\n"
    "[sim]\n"
    "time_step = 0.1\n"
    "depth = 20\n"
    "steps = 1000\n"
    "[load]\n"
    "# lattice point (25, 25): input index 25 + 50 * 25\n"
    "node = 1275\n"
    "kind = force\n"
    "value = 0 -1 0\n",
    /* membrane */
    "# A 30x30 triangular sheet clamped at its border. A force in the sheet's\n"
    "# plane pulls the centre node: it rises over 0.2 s, is held, and is released\n"
    "# at 1 s; the sheet then relaxes back to rest. (The force is in-plane because\n"
    "# a flat, unstretched spring sheet has no linear stiffness across its plane.)\n"
    "[scene]\n"
    "name = membrane\n"
    "[mesh]\n"
    "generator = lattice2d\n"
    "nx = 30\n"
    "ny = 30\n"
    "spacing = 0.01\n"
    "fixed_faces = all\n"
    "[material]\n"
    "mass = 0.001\n"
    "damping = 0.15\n"
    "stiffness = 20\n"
    "[sim]\n"
    "time_step = 1e-3\n"
    "depth = 10\n"
    "steps = 2000\n"
    "[load]\n"
    "# lattice point (15, 15): input index 15 + 30 * 15\n"
    "node = 465\n"
    "kind = force\n"
    "value = 0 -0.05 0\n"
    "ramp = linear\n"
    "start = 0\n"
    "end = 0.2\n"
    "release = 1\n",
    /* head */
    "# Paper section 4.2: a head image embedded in a 10x10x10 mass-spring control\n"
    "# lattice (z up). The synthetic phantom stands in for a scan: cells of air\n"
    "# are left out, lattice points in the skull are fixed. A probe presses the\n"
    "# top of the head 5 mm down, lets go at 0.5 s, and the tissue relaxes.\n"
    "[scene]\n"
    "name = head\n"
    "[mesh]\n"
    "generator = volume\n"
    "[volume]\n"
    "phantom = head\n"
    "voxels = 64\n"
    "size = 0.2\n"
    "nodes = 10 10 10\n"
    "stencil = 18\n"
    "# the skull is thinner than a cell: a point whose half-cell cube is\n"
    "# mostly bone (mean 0.62; brain is 0.55, bone 1) is in the skull\n"
    "hard = 0.62\n"
    "air = 0.05\n"
    "fit_surface = on\n"
    "[material]\n"
    "mass = 0.01\n"
    "damping = 1\n"
    "stiffness = 250\n"
    "[sim]\n"
    "time_step = 1e-3\n"
    "depth = 8\n"
    "steps = 2000\n"
    "[load]\n"
    "# the top lattice point nearest the centre of the box's top face: (5, 5, 9)\n"
    "node = nearest 0.1 0.1 0.2\n"
    "kind = displacement\n"
    "value = 0 0 -0.005\n"
    "start = 0\n"
    "release = 0.5\n",
    /* palpation */
    "# A block of soft tissue to palpate, the main job's training scene: a\n"
    "# 12x12x12 lattice of 1 cm hexahedra (11 cm a side) resting on its bottom\n"
    "# face, in the accurate model (docs/feel.md): neo-Hookean element forces\n"
    "# (E = 12 kPa, nu = 0.45: soft tissue, about 1.2 N at a 5 mm press by a\n"
    "# probe and 2.2 N at 9 mm) and the elastic far field, so what a trainee\n"
    "# feels does not depend on the depth the server picks. A probe's triangle\n"
    "# presses the top face's centre 5 mm over 0.3 s, holds, lets go at 1 s.\n"
    "[scene]\n"
    "name = palpation\n"
    "[mesh]\n"
    "generator = lattice3d\n"
    "nx = 12\n"
    "ny = 12\n"
    "nz = 12\n"
    "spacing = 0.01\n"
    "stencil = 18\n"
    "fixed_faces = zmin\n"
    "[material]\n"
    "# the links shape the layers and the stability guard; the forces are the\n"
    "# elements'. Nodal damping: its masses are the elements' (1 g inside).\n"
    "mass = 0.001\n"
    "damping = 0.3\n"
    "stiffness = 50\n"
    "[fem]\n"
    "young = 12e3\n"
    "poisson = 0.45\n"
    "density = 1000\n"
    "[sim]\n"
    "time_step = 1e-3\n"
    "depth = 4\n"
    "forces = neo-hookean\n"
    "far_field = elastic\n"
    "steps = 2000\n"
    "[tool]\n"
    "tip_radius = 0.004\n"
    "shaft_radius = 0.0015\n"
    "shaft_length = 0.12\n"
    "[load]\n"
    "# lattice points (6, 6, 11), (7, 6, 11) and (6, 7, 11): a top-face triangle\n"
    "node = 1662\n"
    "kind = displacement\n"
    "value = 0 0 -0.005\n"
    "ramp = linear\n"
    "end = 0.3\n"
    "release = 1\n"
    "[load]\n"
    "node = 1663\n"
    "kind = displacement\n"
    "value = 0 0 -0.005\n"
    "ramp = linear\n"
    "end = 0.3\n"
    "release = 1\n"
    "[load]\n"
    "node = 1674\n"
    "kind = displacement\n"
    "value = 0 0 -0.005\n"
    "ramp = linear\n"
    "end = 0.3\n"
    "release = 1\n",
};

#define BUILTIN_COUNT (sizeof builtin_texts / sizeof builtin_texts[0])
_Static_assert(sizeof builtin_names / sizeof builtin_names[0] == BUILTIN_COUNT + 1,
               "every built-in scene needs a name and a text");

const char *const *ftm_scene_builtin_names(void)
{
    return builtin_names;
}

int ftm_scene_builtin_index(const char *name)
{
    for (size_t i = 0; i < BUILTIN_COUNT; i++)
        if (strcmp(builtin_names[i], name) == 0)
            return (int)i;
    return -1;
}

void ftm_scene_builtin_list(char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (size_t i = 0; i < BUILTIN_COUNT && used < size; i++) {
        int n = snprintf(buf + used, size - used, "%s%s", i ? ", " : "", builtin_names[i]);
        if (n < 0)
            break;
        used += (size_t)n;
    }
}

int ftm_scene_builtin(const char *name, ftm_scene **out, ftm_error *err)
{
    if (!name || !out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_scene_builtin: NULL argument");
    int i = ftm_scene_builtin_index(name);
    if (i < 0) {
        char names[256];
        ftm_scene_builtin_list(names, sizeof names);
        return ftm_error_set(err, FTM_ENOENT, "unknown built-in scene '%s' (built-ins: %s)", name,
                             names);
    }
    char label[64];
    snprintf(label, sizeof label, "builtin:%s", name);
    return ftm_scene_parse(builtin_texts[i], strlen(builtin_texts[i]), label, out, err);
}

