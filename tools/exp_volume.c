/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm experiment volume`: the paper's section 4.2. A volume (an MRI scan, or
 * the core's synthetic head) is embedded in a mass-spring control lattice
 * (10 x 10 x 10 points by default, as the paper), the lattice points inside
 * hard tissue are fixed, a probe presses the top of the volume with an
 * imposed displacement, the lattice runs to equilibrium with the force
 * transmittal model, and the volume follows by trilinear free-form
 * deformation (common/include/ftm/volume.h). Prints the figures (table or
 * --json) and, with --out DIR, writes the lattice nodes' displacements as
 * CSV and a picture of a mid-plane slice at rest, pressed, and the
 * displacement's magnitude, drawn by gnuplot. See docs/experiments.md. */
#include "bench.h"
#include "commands.h"
#include "experiments.h"
#include "gnuplot.h"

#include "ftm/ftm.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>


#define WHO "ftm experiment volume"

/* Exit statuses (commands.h): 1 the experiment failed, 2 bad arguments,
 * input, or an output that cannot be written. */
enum { EXIT_FAILED = 1, EXIT_USAGE = 2 };

/* The lattice's material, chosen from the lattice spacing so that any volume
 * and lattice size simulate stably (see choose_material). */
static const double tissue_density = 1000.0; /* [kg/m^3]: a node carries its cell's mass */
static const double tissue_young = 3000.0;   /* [Pa]: brain-like; link k = E * spacing */
static const double max_time_step = 1e-3;    /* [s], the server's tick */
static const int ramp_steps = 100;           /* the push rises linearly over these */
static const double rest_tol = 1e-6;         /* equilibrium: see ftm_exp_run_to_rest */
static const int rest_every = 100;
static const int max_steps = 200000;
static const int timed_steps = 500;    /* steps timed at equilibrium */
static const int unmap_iterations = 0; /* ftm_ffd_unmap's default (8) iterations */
static const int slice_pixels = 320;    /* the slice picture's longer side */
/* Hard tissue: the core's default threshold (0.9) wants a lattice point's
 * surroundings (a cube of one cell) nearly all bone; the phantom's skull,
 * about 10 mm thick, fills under half of a 22 mm cell of the 10^3 lattice,
 * and fixes none. 0.65 fixes the points whose cube is a fifth or more bone
 * (the rest brain, 0.55): the ring of points in the skull. */
static const double default_hard = 0.65;

typedef struct vol_opts {
    const char *volume_path; /* NULL: the phantom */
    int nodes, depth;
    double push_mm;
    double hard; /* hard-tissue threshold; > 1 fixes none */
    uint32_t fix_faces;
    int plane_normal; /* 1: x-z plane (normal y), 0: y-z plane (normal x) */
    const char *out_dir;
    bool json;
} vol_opts;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm experiment volume [--volume FILE.nii[.gz]] [--nodes N] [--depth D]\n"
            "                             [--push MM] [--hard T|none] [--fix FACES]\n"
            "                             [--plane xz|yz] [--out DIR] [--json]\n\n"
            "A volume embedded in a mass-spring control lattice (Choi, Sun, Heng 2004, section\n"
            "4.2): the lattice points in hard tissue are fixed, the top of the volume is pressed\n"
            "down, the lattice runs to equilibrium and the volume follows by trilinear free-form\n"
            "deformation.\n\n"
            "options:\n"
            "  --volume FILE   a NIfTI-1 image (.nii, .nii.gz); default: the synthetic head\n"
            "                  phantom\n"
            "  --nodes N       lattice points per axis, 2..100 (default 10, as the paper)\n"
            "  --depth D       penetration depth, 0..1000 layers (default 8)\n"
            "  --push MM       how far the probe presses the top down [mm] (default 12)\n"
            "  --hard T        fix the lattice points whose surroundings have a mean intensity\n"
            "                  of at least T (0..1, default 0.65: a fifth bone, bright as on\n"
            "                  CT);\n"
            "                  'none' fixes none (a T1 MRI's bone is dark)\n"
            "  --fix FACES     also fix faces of the box: comma-separated xmin,xmax,ymin,ymax,\n"
            "                  zmin,zmax, or 'none' (default)\n"
            "  --plane P       the pictured slice: xz (default) or yz, through the press\n"
            "  --out DIR       write DIR/volume_nodes.csv, the slice data and DIR/volume.png\n"
            "                  (the picture needs gnuplot; without it, it is skipped)\n"
            "  --json          print the results as one JSON object\n\n"
            "exit status: 0 success, 1 the experiment failed (a step diverged, no equilibrium,\n"
            "a fixed node moved), 2 bad arguments, an unreadable volume, or an output that\n"
            "cannot be written (a picture gnuplot failed to draw)\n");
}

/* "zmin,xmax" -> FTM_FACE_* mask; false on a word that is not a face. */
static bool parse_faces(const char *s, uint32_t *out)
{
    static const char *const names[6] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
    uint32_t mask = 0;
    if (strcmp(s, "none") == 0) {
        *out = 0;
        return true;
    }
    while (*s) {
        size_t n = strcspn(s, ",");
        int found = -1;
        for (int f = 0; f < 6; f++)
            if (strlen(names[f]) == n && strncmp(s, names[f], n) == 0)
                found = f;
        if (found < 0)
            return false;
        mask |= 1u << found;
        s += n;
        if (*s == ',')
            s++;
    }
    *out = mask;
    return mask != 0;
}

/* ---- the experiment ------------------------------------------------------ */

typedef struct vol_run {
    ftm_volume *volume;
    ftm_volume_info info;
    ftm_mesh *mesh;
    ftm_ffd *ffd;
    ftm_sim *sim;
    int32_t n[3];       /* lattice points per axis */
    int32_t *point_node; /* per lattice point: mesh node or -1 */
    ftm_material_def material;
    double time_step, critical_step;
    int warnings;
    char first_warning[256];
    /* the press */
    int32_t pressed[8];
    int pressed_count;
    ftm_vec3 press_point; /* centroid of the pressed nodes at rest */
} vol_run;

typedef struct vol_result {
    int32_t lattice_points, kept_nodes, fixed_nodes, links, cells, air_cells;
    int32_t region_nodes, layers;
    int steps;
    bool equilibrium;
    uint64_t guard_events;
    double max_node_disp, pressed_disp; /* [m] */
    int32_t fixed_moved;
    ftm_vec3 reaction; /* [N] */
    double lattice_match; /* max |ffd_map(X_point) - x_node| over kept points [m] */
    /* the displacement field u(X) = ffd_map(X) - X over points of the volume
     * with tissue (intensity >= the air threshold) [m] */
    int32_t field_points;
    double field_min, field_max, field_uz_min, field_uz_max, field_moved_fraction;
    double step_us;
} vol_result;

static void count_warning(void *user, ftm_log_level level, const char *message)
{
    vol_run *r = user;
    if (level < FTM_LOG_WARN)
        return;
    fprintf(stderr, WHO ": simulation: %s\n", message);
    if (r->warnings++ == 0)
        snprintf(r->first_warning, sizeof r->first_warning, "%s", message);
}

static double comp(ftm_vec3 v, int axis)
{
    return axis == 0 ? v.x : axis == 1 ? v.y : v.z;
}

static void set_comp(ftm_vec3 *v, int axis, double value)
{
    if (axis == 0)
        v->x = value;
    else if (axis == 1)
        v->y = value;
    else
        v->z = value;
}

static ftm_vec3 box_size(const ftm_volume_info *in)
{
    return (ftm_vec3){in->nx * in->spacing.x, in->ny * in->spacing.y, in->nz * in->spacing.z};
}

static int32_t point_index(const vol_run *r, int32_t ix, int32_t iy, int32_t iz)
{
    return ix + r->n[0] * (iy + r->n[1] * iz);
}

/* The kept lattice points in index order: from point *p on (start at 0),
 * the next that is a mesh node; its indices (ix, iy, iz) in idx and *p past
 * it. Returns its node, -1 at the end. */
static int32_t next_kept(const vol_run *r, int32_t *p, int32_t idx[3])
{
    for (int32_t total = r->n[0] * r->n[1] * r->n[2]; *p < total; (*p)++) {
        int32_t node = r->point_node[*p];
        if (node >= 0) {
            idx[0] = *p % r->n[0];
            idx[1] = *p / r->n[0] % r->n[1];
            idx[2] = *p / (r->n[0] * r->n[1]);
            (*p)++;
            return node;
        }
    }
    return -1;
}

static ftm_vec3 node_position(const double *x, int32_t node)
{
    return (ftm_vec3){x[3 * node], x[3 * node + 1], x[3 * node + 2]};
}

static double dist(ftm_vec3 a, ftm_vec3 b)
{
    return sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z));
}

/* Material and time step from the lattice spacing a (per axis): a node
 * carries its cell's mass (density a^3), a link has k = E * a (a cube of
 * tissue of edge a under a force F stretches by F / (E a)); every node has
 * the same mass and every link the same k, so the Gershgorin bound of the
 * core's critical step is lambda <= 2 k * stencil / m (ftm_mesh_critical_time_step),
 * the time step is at most half the critical one, and the damping twice
 * what the layer-by-layer update needs at that step (sim.c's
 * warn_low_damping: d / 2m >= 0.055 lambda h). The displacement-driven
 * equilibrium does not depend on these; the steps to reach it and the
 * reaction force do. */
static void choose_material(vol_run *r, ftm_stencil stencil)
{
    ftm_vec3 size = box_size(&r->info);
    double ax = size.x / (r->n[0] - 1), ay = size.y / (r->n[1] - 1), az = size.z / (r->n[2] - 1);
    double a = cbrt(ax * ay * az);
    ftm_material_def m = ftm_default_material_def();
    m.node_mass = tissue_density * ax * ay * az;
    m.stiffness = tissue_young * a;
    double lambda = 2.0 * m.stiffness * (double)stencil / m.node_mass;
    double h_crit = 2.0 / sqrt(lambda);
    r->time_step = fmin(max_time_step, 0.5 * h_crit);
    m.node_damping = 2.0 * (2.0 * m.node_mass * 0.055 * lambda * r->time_step);
    r->material = m;
}

static void vol_run_free(vol_run *r)
{
    ftm_sim_destroy(r->sim);
    ftm_ffd_destroy(r->ffd);
    ftm_mesh_destroy(r->mesh);
    ftm_volume_destroy(r->volume);
    free(r->point_node);
}

/* Prints an error of the core, naming the file when the message does not. */
static void print_error(const char *path, const ftm_error *err, int rc)
{
    const char *msg = err->message[0] ? err->message : ftm_strerror(rc);
    if (path && !strstr(msg, path))
        fprintf(stderr, WHO ": %s: %s\n", path, msg);
    else
        fprintf(stderr, WHO ": %s\n", msg);
}

/* Loads the volume and builds its lattice, mesh, FFD and simulation.
 * 0, or an exit status (the reason printed). */
static int setup(const vol_opts *o, vol_run *r)
{
    ftm_error err = {0};
    int rc;
    if (o->volume_path) {
        rc = ftm_volume_load(o->volume_path, NULL, &r->volume, &err);
    } else {
        ftm_volume_phantom_def pd = ftm_default_volume_phantom_def();
        rc = ftm_volume_phantom(&pd, &r->volume, &err);
    }
    if (rc) {
        print_error(o->volume_path, &err, rc);
        return rc == FTM_ENOMEM ? EXIT_FAILED : EXIT_USAGE;
    }
    r->info = ftm_volume_get_info(r->volume);
    ftm_volume_lattice_def ld = ftm_default_volume_lattice_def();
    for (int k = 0; k < 3; k++)
        ld.nodes[k] = r->n[k] = o->nodes;
    ld.hard_threshold = o->hard;
    ld.fixed_faces = o->fix_faces;
    choose_material(r, ld.stencil);
    ld.material = r->material;
    size_t points = (size_t)r->n[0] * (size_t)r->n[1] * (size_t)r->n[2];
    int32_t *point_input = malloc(points * sizeof *point_input);
    r->point_node = malloc(points * sizeof *r->point_node);
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    if (!point_input || !r->point_node || !mb) {
        free(point_input);
        ftm_mesh_builder_destroy(mb);
        fprintf(stderr, WHO ": out of memory\n");
        return EXIT_FAILED;
    }
    rc = ftm_generate_volume_lattice(mb, r->volume, &ld, point_input, &err);
    if (rc == FTM_OK)
        rc = ftm_mesh_build(mb, NULL, &r->mesh, &err);
    ftm_mesh_builder_destroy(mb);
    if (rc == FTM_OK) {
        for (size_t p = 0; p < points; p++)
            r->point_node[p] =
                point_input[p] < 0 ? -1 : ftm_mesh_node_of_input(r->mesh, point_input[p]);
        rc = ftm_ffd_create(r->mesh, r->volume, r->n, r->point_node, &r->ffd, &err);
    }
    free(point_input);
    if (rc) {
        fprintf(stderr, WHO ": control lattice: %s\n",
                err.message[0] ? err.message : ftm_strerror(rc));
        return rc == FTM_EINVAL ? EXIT_USAGE : EXIT_FAILED;
    }
    r->critical_step = ftm_mesh_critical_time_step(r->mesh);
    ftm_sim_def sd = ftm_default_sim_def();
    sd.time_step = r->time_step;
    sd.depth = o->depth;
    sd.log = count_warning;
    sd.log_user = r;
    rc = ftm_sim_create(r->mesh, &sd, &r->sim, &err);
    if (rc) {
        fprintf(stderr, WHO ": simulation: %s\n", err.message[0] ? err.message : ftm_strerror(rc));
        return EXIT_FAILED;
    }
    return 0;
}

/* The free kept node(s) nearest the centre of the top of the box: all
 * those equally near (four with an even lattice). 0, or -1 if every node is
 * fixed. */
static int find_press(vol_run *r)
{
    ftm_vec3 o = r->info.origin, size = box_size(&r->info);
    ftm_vec3 top = {o.x + 0.5 * size.x, o.y + 0.5 * size.y, o.z + size.z};
    int32_t count = ftm_mesh_node_count(r->mesh);
    double best = INFINITY;
    for (int32_t i = 0; i < count; i++)
        if (!ftm_mesh_fixed(r->mesh, i))
            best = fmin(best, dist(ftm_mesh_rest_position(r->mesh, i), top));
    if (!isfinite(best))
        return -1;
    double tol = 1e-9 * (best + cbrt(size.x * size.y * size.z));
    ftm_vec3 c = {0, 0, 0};
    r->pressed_count = 0;
    for (int32_t i = 0; i < count && r->pressed_count < 8; i++) {
        ftm_vec3 X = ftm_mesh_rest_position(r->mesh, i);
        if (!ftm_mesh_fixed(r->mesh, i) && dist(X, top) <= best + tol) {
            r->pressed[r->pressed_count++] = i;
            c.x += X.x;
            c.y += X.y;
            c.z += X.z;
        }
    }
    r->press_point =
        (ftm_vec3){c.x / r->pressed_count, c.y / r->pressed_count, c.z / r->pressed_count};
    return 0;
}

static int set_push(vol_run *r, double depth_m)
{
    ftm_contact c[8];
    for (int i = 0; i < r->pressed_count; i++)
        c[i] = (ftm_contact){.node = r->pressed[i],
                             .group = 0,
                             .kind = FTM_CONTACT_DISPLACEMENT,
                             .value = {0, 0, -depth_m}};
    ftm_error err = {0};
    int rc = ftm_sim_set_contacts(r->sim, c, r->pressed_count, &err);
    if (rc)
        fprintf(stderr, WHO ": contacts: %s\n", err.message);
    return rc;
}

/* The displacement field over the volume's tissue: u = ffd_map(X) - X at
 * voxel centres (every stride-th per axis, at most 64 per axis) whose
 * intensity is at least the lattice's air threshold. */
static void measure_field(const vol_run *r, vol_result *res)
{
    const ftm_volume_info *in = &r->info;
    const uint8_t *data = ftm_volume_data(r->volume);
    const double *x = ftm_sim_positions(r->sim);
    double air = ftm_default_volume_lattice_def().air_threshold;
    int sx = (in->nx + 63) / 64, sy = (in->ny + 63) / 64, sz = (in->nz + 63) / 64;
    int32_t points = 0, moved = 0;
    double umin = INFINITY, umax = 0.0, zmin = INFINITY, zmax = -INFINITY;
    for (int32_t k = sz / 2; k < in->nz; k += sz)
        for (int32_t j = sy / 2; j < in->ny; j += sy)
            for (int32_t i = sx / 2; i < in->nx; i += sx) {
                size_t v = (size_t)i + (size_t)in->nx * ((size_t)j + (size_t)in->ny * (size_t)k);
                if (data[v] / 255.0 < air)
                    continue;
                ftm_vec3 X = {in->origin.x + (i + 0.5) * in->spacing.x,
                              in->origin.y + (j + 0.5) * in->spacing.y,
                              in->origin.z + (k + 0.5) * in->spacing.z};
                ftm_vec3 p = ftm_ffd_map(r->ffd, x, X);
                double u = dist(p, X);
                points++;
                umin = fmin(umin, u);
                umax = fmax(umax, u);
                zmin = fmin(zmin, p.z - X.z);
                zmax = fmax(zmax, p.z - X.z);
                if (u > 1e-4)
                    moved++;
            }
    res->field_points = points;
    res->field_min = points ? umin : 0.0;
    res->field_max = umax;
    res->field_uz_min = points ? zmin : 0.0;
    res->field_uz_max = points ? zmax : 0.0;
    res->field_moved_fraction = points ? (double)moved / points : 0.0;
}

/* The run itself: push, equilibrium, the figures. 0 or an exit status. */
static int experiment(const vol_opts *o, vol_run *r, vol_result *res)
{
    memset(res, 0, sizeof *res);
    res->lattice_points = r->n[0] * r->n[1] * r->n[2];
    res->kept_nodes = ftm_mesh_node_count(r->mesh);
    res->links = ftm_mesh_link_count(r->mesh);
    res->cells = (r->n[0] - 1) * (r->n[1] - 1) * (r->n[2] - 1);
    res->air_cells = res->cells - ftm_mesh_hexahedron_count(r->mesh);
    for (int32_t i = 0; i < res->kept_nodes; i++)
        res->fixed_nodes += ftm_mesh_fixed(r->mesh, i);
    if (find_press(r)) {
        fprintf(stderr, WHO ": every lattice node is fixed: nothing to press\n");
        return EXIT_FAILED;
    }
    const double push = o->push_mm * 1e-3;
    int rc = FTM_OK;
    for (int s = 1; s <= ramp_steps && rc == FTM_OK; s++) {
        rc = set_push(r, push * s / ramp_steps);
        if (rc == FTM_OK)
            rc = ftm_sim_step(r->sim);
    }
    int steps = rc ? rc : ftm_exp_run_to_rest(r->sim, r->mesh, rest_tol, rest_every, max_steps);
    if (steps < 0) {
        fprintf(stderr, WHO ": the simulation failed: %s\n", ftm_strerror(steps));
        return EXIT_FAILED;
    }
    res->steps = ramp_steps + steps;
    res->equilibrium = steps < max_steps;
    ftm_sim_stats st;
    ftm_sim_get_stats(r->sim, &st);
    res->region_nodes = st.region_nodes;
    res->layers = st.layers;
    res->guard_events = st.guard_events;
    res->reaction = ftm_sim_reaction(r->sim, 0);
    const double *x = ftm_sim_positions(r->sim);
    res->max_node_disp = ftm_exp_max_displacement(r->sim, r->mesh);
    for (int i = 0; i < r->pressed_count; i++) {
        int32_t node = r->pressed[i];
        double u = dist(node_position(x, node), ftm_mesh_rest_position(r->mesh, node));
        res->pressed_disp = fmax(res->pressed_disp, u);
    }
    for (int32_t i = 0; i < res->kept_nodes; i++) {
        ftm_vec3 X = ftm_mesh_rest_position(r->mesh, i), p = node_position(x, i);
        if (ftm_mesh_fixed(r->mesh, i) && (p.x != X.x || p.y != X.y || p.z != X.z))
            res->fixed_moved++;
    }
    int32_t idx[3], node;
    for (int32_t pt = 0; (node = next_kept(r, &pt, idx)) >= 0;) {
        ftm_vec3 p = ftm_ffd_map(r->ffd, x, ftm_ffd_point_rest(r->ffd, idx[0], idx[1], idx[2]));
        res->lattice_match = fmax(res->lattice_match, dist(p, node_position(x, node)));
    }
    measure_field(r, res);
    /* the step's cost under the held load, at equilibrium */
    double t0 = ftm_bench_now_us();
    rc = ftm_sim_run(r->sim, timed_steps);
    res->step_us = (ftm_bench_now_us() - t0) / timed_steps;
    if (rc) {
        fprintf(stderr, WHO ": the simulation failed: %s\n", ftm_strerror(rc));
        return EXIT_FAILED;
    }
    return 0;
}

/* ---- the slice ------------------------------------------------------------ */

/* The pictured plane: axes a (across) and b = z (up), normal axis c, at
 * the lattice plane nearest the press point (so that the lattice's nodes
 * and links in it can be drawn). Pixels are squares of side px [m]. */
typedef struct vol_slice {
    int a, b, c;
    int32_t plane;  /* lattice index along c */
    double at;      /* the plane's coordinate along c [m] */
    double a0, b0;  /* the box's minimum along a and b [m] */
    double px;
    int w, h;
    float *rest, *deformed, *disp; /* w * h each, row j = b */
    double unmap_us, map_us;       /* the whole slice, once */
    double unmap_residual;         /* max |ffd_map(unmap(p)) - p| [m] */
    double disp_max;               /* [m] */
} vol_slice;

static void slice_free(vol_slice *s)
{
    free(s->rest);
    free(s->deformed);
    free(s->disp);
}

static ftm_vec3 slice_point(const vol_slice *s, int i, int j)
{
    ftm_vec3 p = {0, 0, 0};
    set_comp(&p, s->a, s->a0 + (i + 0.5) * s->px);
    set_comp(&p, s->b, s->b0 + (j + 0.5) * s->px);
    set_comp(&p, s->c, s->at);
    return p;
}

static int make_slice(const vol_opts *o, const vol_run *r, vol_slice *s)
{
    memset(s, 0, sizeof *s);
    s->c = o->plane_normal;
    s->a = 1 - o->plane_normal;
    s->b = 2;
    ftm_vec3 size = box_size(&r->info);
    double cell = comp(size, s->c) / (r->n[s->c] - 1);
    s->plane = (int32_t)lround((comp(r->press_point, s->c) - comp(r->info.origin, s->c)) / cell);
    s->plane = s->plane < 0 ? 0 : s->plane >= r->n[s->c] ? r->n[s->c] - 1 : s->plane;
    int32_t idx[3] = {0, 0, 0};
    idx[s->c] = s->plane;
    s->at = comp(ftm_ffd_point_rest(r->ffd, idx[0], idx[1], idx[2]), s->c);
    s->a0 = comp(r->info.origin, s->a);
    s->b0 = comp(r->info.origin, s->b);
    double ea = comp(size, s->a), eb = comp(size, s->b);
    s->px = fmax(ea, eb) / slice_pixels;
    s->w = (int)ceil(ea / s->px - 1e-9);
    s->h = (int)ceil(eb / s->px - 1e-9);
    size_t n = (size_t)s->w * (size_t)s->h;
    s->rest = malloc(n * sizeof *s->rest);
    s->deformed = malloc(n * sizeof *s->deformed);
    s->disp = malloc(n * sizeof *s->disp);
    ftm_vec3 *X = malloc(n * sizeof *X);
    if (!s->rest || !s->deformed || !s->disp || !X) {
        free(X);
        fprintf(stderr, WHO ": out of memory for a %d x %d slice\n", s->w, s->h);
        return EXIT_FAILED;
    }
    const double *x = ftm_sim_positions(r->sim);
    /* the inverse map of every pixel: what a renderer of the deformed slice does */
    double t0 = ftm_bench_now_us();
    for (int j = 0; j < s->h; j++)
        for (int i = 0; i < s->w; i++)
            X[(size_t)j * s->w + i] =
                ftm_ffd_unmap(r->ffd, x, slice_point(s, i, j), unmap_iterations);
    s->unmap_us = ftm_bench_now_us() - t0;
    /* the forward map of every pixel's rest point (the paper's renderer maps
     * its slices' vertices forward) */
    double check = 0.0;
    t0 = ftm_bench_now_us();
    for (int j = 0; j < s->h; j++)
        for (int i = 0; i < s->w; i++)
            check += ftm_ffd_map(r->ffd, x, slice_point(s, i, j)).z;
    s->map_us = ftm_bench_now_us() - t0;
    if (!isfinite(check))
        s->map_us = NAN;
    for (int j = 0; j < s->h; j++)
        for (int i = 0; i < s->w; i++) {
            size_t k = (size_t)j * s->w + i;
            ftm_vec3 p = slice_point(s, i, j);
            double u = dist(p, X[k]);
            s->rest[k] = (float)ftm_volume_sample(r->volume, p);
            s->deformed[k] = (float)ftm_volume_sample(r->volume, X[k]);
            s->disp[k] = (float)(u * 1e3);
            s->disp_max = fmax(s->disp_max, u);
            s->unmap_residual = fmax(s->unmap_residual, dist(ftm_ffd_map(r->ffd, x, X[k]), p));
        }
    free(X);
    return 0;
}

/* ---- outputs ---------------------------------------------------------------- */

typedef struct out_file {
    char path[4096];
    FILE *f;
} out_file;

static int out_open(const char *dir, const char *name, out_file *o)
{
    snprintf(o->path, sizeof o->path, "%s/%s", dir, name);
    o->f = fopen(o->path, "w");
    if (!o->f) {
        fprintf(stderr, WHO ": %s: cannot write: %s\n", o->path, strerror(errno));
        return -1;
    }
    return 0;
}

static int out_close(out_file *o)
{
    if (!o->f)
        return 0;
    FILE *f = o->f;
    o->f = NULL;
    return ftm_close_output(f, WHO, o->path);
}

static int write_matrix(const char *dir, const char *name, const vol_slice *s, const float *v)
{
    out_file o;
    if (out_open(dir, name, &o))
        return -1;
    for (int j = 0; j < s->h; j++) {
        for (int i = 0; i < s->w; i++)
            fprintf(o.f, i ? " %.4g" : "%.4g", v[(size_t)j * s->w + i]);
        fputc('\n', o.f);
    }
    return out_close(&o);
}

/* The lattice in the pictured plane, at rest or deformed, in mm from the
 * box's corner: links as segments (gnuplot blocks) and nodes with a colour
 * (free, fixed, pressed). */
static bool is_pressed(const vol_run *r, int32_t node)
{
    for (int i = 0; i < r->pressed_count; i++)
        if (r->pressed[i] == node)
            return true;
    return false;
}

static bool linked(const ftm_mesh *mesh, int32_t a, int32_t b)
{
    const int32_t *nb;
    const double *k, *l;
    int32_t count = ftm_mesh_neighbors(mesh, a, &nb, &k, &l);
    for (int32_t i = 0; i < count; i++)
        if (nb[i] == b)
            return true;
    return false;
}

static int32_t plane_node(const vol_run *r, const vol_slice *s, int32_t ia, int32_t ib)
{
    int32_t idx[3];
    idx[s->a] = ia;
    idx[s->b] = ib;
    idx[s->c] = s->plane;
    return r->point_node[point_index(r, idx[0], idx[1], idx[2])];
}

static void plane_xy(const vol_slice *s, ftm_vec3 p, double *u, double *v)
{
    *u = (comp(p, s->a) - s->a0) * 1e3;
    *v = (comp(p, s->b) - s->b0) * 1e3;
}

static int write_lattice(const char *dir, const char *links_name, const char *nodes_name,
                         const vol_run *r, const vol_slice *s, const double *x)
{
    out_file lk, nd;
    if (out_open(dir, links_name, &lk))
        return -1;
    if (out_open(dir, nodes_name, &nd)) {
        fclose(lk.f);
        return -1;
    }
    static const int steps[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    int32_t na = r->n[s->a], nb = r->n[s->b];
    for (int32_t ib = 0; ib < nb; ib++)
        for (int32_t ia = 0; ia < na; ia++) {
            int32_t node = plane_node(r, s, ia, ib);
            if (node < 0)
                continue;
            double u, v;
            plane_xy(s, node_position(x, node), &u, &v);
            long colour = is_pressed(r, node)            ? 0x00e5ff
                          : ftm_mesh_fixed(r->mesh, node) ? 0xff2020
                                                          : 0xffc000;
            fprintf(nd.f, "%.5g %.5g %ld\n", u, v, colour);
            for (int d = 0; d < 4; d++) {
                int32_t ja = ia + steps[d][0], jb = ib + steps[d][1];
                if (ja < 0 || ja >= na || jb < 0 || jb >= nb)
                    continue;
                int32_t other = plane_node(r, s, ja, jb);
                if (other < 0 || !linked(r->mesh, node, other))
                    continue;
                double u2, v2;
                plane_xy(s, node_position(x, other), &u2, &v2);
                fprintf(lk.f, "%.5g %.5g\n%.5g %.5g\n\n", u, v, u2, v2);
            }
        }
    int rc = out_close(&lk);
    return out_close(&nd) || rc ? -1 : 0;
}

static int write_nodes_csv(const char *dir, const vol_run *r)
{
    out_file o;
    if (out_open(dir, "volume_nodes.csv", &o))
        return -1;
    const double *x = ftm_sim_positions(r->sim);
    fprintf(o.f, "ix,iy,iz,node,fixed,pressed,x,y,z,ux,uy,uz\n");
    int32_t idx[3], node;
    for (int32_t pt = 0; (node = next_kept(r, &pt, idx)) >= 0;) {
        ftm_vec3 X = ftm_mesh_rest_position(r->mesh, node), p = node_position(x, node);
        fprintf(o.f, "%d,%d,%d,%d,%d,%d,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", idx[0], idx[1], idx[2],
                node, ftm_mesh_fixed(r->mesh, node), is_pressed(r, node), X.x, X.y, X.z, p.x - X.x,
                p.y - X.y, p.z - X.z);
    }
    return out_close(&o);
}

static void gp_file(FILE *f, const char *dir, const char *name)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    ftm_gnuplot_quote(f, path);
}

static const char *const axis_name = "xyz";

static int write_script(const vol_opts *o, const vol_run *r, const vol_slice *s, const char *title)
{
    out_file g;
    if (out_open(o->out_dir, "volume.gp", &g))
        return -1;
    FILE *f = g.f;
    double ea = s->w * s->px * 1e3, eb = s->h * s->px * 1e3;
    fprintf(f, "# drawn by `ftm experiment volume --out`; gnuplot %s/volume.gp redraws it\n",
            o->out_dir);
    /* three panels of equal size (the third's colour box in the right
     * margin), the canvas as high as the slice's aspect needs */
    const double width = 1650, left = 0.045, right = 0.935, bottom = 0.11, top = 0.86, gap = 0.05;
    double panel_px = (right - left - 2 * gap) / 3 * width;
    fprintf(f, "set terminal pngcairo noenhanced size %.0f,%ld font 'sans,10'\nset output ", width,
            lround(panel_px * eb / ea / (top - bottom)));
    gp_file(f, o->out_dir, "volume.png");
    fprintf(f,
            "\nset multiplot layout 1,3 title \"%s\" font 'sans,11' margins %g,%g,%g,%g "
            "spacing %g,0\n",
            title, left, right, bottom, top, gap);
    fprintf(f, "set size ratio -1\nset xrange [0:%.6g]\nset yrange [0:%.6g]\n", ea, eb);
    fprintf(f, "set xlabel '%c [mm]'\nset ylabel '%c [mm]'\nset tics out\n", axis_name[s->a],
            axis_name[s->b]);
    fprintf(f, "set key bottom right opaque box samplen 1 font 'sans,8'\n");
    fprintf(f, "px = %.9g\n", s->px * 1e3);
    fprintf(f, "set palette grey\nset cbrange [0:1]\nunset colorbox\n");
    const char *img = "matrix using (($1 + 0.5) * px):(($2 + 0.5) * px):3 with image notitle";
    const char *legend =
        "NaN with points pt 7 ps 0.8 lc rgb '#00e5ff' title 'pressed', "
        "NaN with points pt 7 ps 0.8 lc rgb '#ff2020' title 'fixed', "
        "NaN with points pt 7 ps 0.8 lc rgb '#ffc000' title 'free'";
    const char *links = "with lines lc rgb '#c0ff9020' lw 1 notitle";
    const char *nodes = "using 1:2:3 with points pt 7 ps 0.7 lc rgb variable notitle";
    static const char *const panel[3] = {"volume_rest.dat", "volume_deformed.dat",
                                         "volume_disp.dat"};
    for (int p = 0; p < 3; p++) {
        bool at_rest = p == 0;
        if (p == 0)
            fprintf(f, "set title 'at rest, %c = %.1f mm (lattice plane %d)'\n", axis_name[s->c],
                    (s->at - comp(r->info.origin, s->c)) * 1e3, (int)s->plane);
        else if (p == 1)
            fprintf(f, "set title 'pressed %.3g mm at the top, at equilibrium'\n", o->push_mm);
        else
            fprintf(f, "set title 'displacement |u| [mm]'\nset palette defined (0 '#000004', 1 "
                       "'#3b0f70', 2 '#8c2981', 3 '#de4968', 4 '#fe9f6d', 5 '#fcfdbf')\n"
                       "set cbrange [0:%.6g]\nset colorbox\n",
                    fmax(s->disp_max * 1e3, 1e-6));
        fprintf(f, "plot ");
        gp_file(f, o->out_dir, panel[p]);
        fprintf(f, " %s, \\\n     ", img);
        gp_file(f, o->out_dir, at_rest ? "volume_links_rest.dat" : "volume_links.dat");
        fprintf(f, " %s, \\\n     ", links);
        gp_file(f, o->out_dir, at_rest ? "volume_nodes_rest.dat" : "volume_nodes.dat");
        fprintf(f, " %s, \\\n     %s\n", nodes, legend);
    }
    fprintf(f, "unset multiplot\n");
    return out_close(&g);
}

/* Draws DIR/volume.gp: 0 drawn, 1 skipped (no gnuplot), -1 gnuplot failed. */
static int draw(const vol_opts *o)
{
    char script[4096];
    snprintf(script, sizeof script, "%s/volume.gp", o->out_dir);
    return ftm_gnuplot_run(WHO, script);
}

/* The volume's name for titles: the file's base name, or the phantom. */
static const char *volume_name(const vol_opts *o)
{
    if (!o->volume_path)
        return "synthetic head phantom";
    const char *slash = strrchr(o->volume_path, '/');
    return slash ? slash + 1 : o->volume_path;
}

/* Writes DIR's files and draws the picture. 0 or an exit status. */
static int write_outputs(const vol_opts *o, const vol_run *r, const vol_slice *s, bool *drawn)
{
    *drawn = false;
    const double *x = ftm_sim_positions(r->sim);
    double *rest = malloc((size_t)ftm_mesh_node_count(r->mesh) * 3 * sizeof *rest);
    if (!rest)
        return EXIT_FAILED;
    for (int32_t i = 0; i < ftm_mesh_node_count(r->mesh); i++) {
        ftm_vec3 X = ftm_mesh_rest_position(r->mesh, i);
        rest[3 * i] = X.x;
        rest[3 * i + 1] = X.y;
        rest[3 * i + 2] = X.z;
    }
    char title[512];
    int32_t fixed = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(r->mesh); i++)
        fixed += ftm_mesh_fixed(r->mesh, i);
    snprintf(title, sizeof title,
             "Volume in a %dx%dx%d control lattice (paper 4.2): %.200s; %d fixed nodes, depth %d",
             r->n[0], r->n[1], r->n[2], volume_name(o), (int)fixed, o->depth);
    for (char *c = title; *c; c++)
        if (*c == '"' || *c == '\\')
            *c = '_';
    int bad = write_nodes_csv(o->out_dir, r) ||
              write_matrix(o->out_dir, "volume_rest.dat", s, s->rest) ||
              write_matrix(o->out_dir, "volume_deformed.dat", s, s->deformed) ||
              write_matrix(o->out_dir, "volume_disp.dat", s, s->disp) ||
              write_lattice(o->out_dir, "volume_links_rest.dat", "volume_nodes_rest.dat", r, s,
                            rest) ||
              write_lattice(o->out_dir, "volume_links.dat", "volume_nodes.dat", r, s, x) ||
              write_script(o, r, s, title);
    free(rest);
    if (bad)
        return EXIT_USAGE;
    int d = draw(o);
    *drawn = d == 0;
    return d < 0 ? EXIT_USAGE : 0;
}

/* ---- report --------------------------------------------------------------- */

static void jstr(const char *s) { ftm_json_string(stdout, s); }

/* ,"key":value and ,"key":[a,b,c] */
static void jkey(const char *key, double v)
{
    printf(",\"%s\":", key);
    ftm_json_number(stdout, v, 6);
}

static void jvec(const char *key, double a, double b, double c)
{
    printf(",\"%s\":[", key);
    ftm_json_number(stdout, a, 6);
    putchar(',');
    ftm_json_number(stdout, b, 6);
    putchar(',');
    ftm_json_number(stdout, c, 6);
    putchar(']');
}

static void report_json(const vol_opts *o, const vol_run *r, const vol_result *res,
                        const vol_slice *s, bool drawn)
{
    const ftm_volume_info *in = &r->info;
    printf("{\"experiment\":\"volume\",\"volume\":");
    jstr(o->volume_path ? o->volume_path : "phantom");
    printf(",\"voxels\":[%d,%d,%d]", in->nx, in->ny, in->nz);
    jvec("voxel_mm", in->spacing.x * 1e3, in->spacing.y * 1e3, in->spacing.z * 1e3);
    printf(",\"nodes\":[%d,%d,%d],\"lattice_points\":%d,\"kept_nodes\":%d,\"fixed_nodes\":%d,"
           "\"links\":%d,\"cells\":%d,\"air_cells\":%d,\"pressed_nodes\":%d",
           r->n[0], r->n[1], r->n[2], res->lattice_points, res->kept_nodes, res->fixed_nodes,
           res->links, res->cells, res->air_cells, r->pressed_count);
    jkey("push_mm", o->push_mm);
    printf(",\"depth\":%d,\"region_nodes\":%d,\"layers\":%d", o->depth, res->region_nodes,
           res->layers);
    jkey("node_mass", r->material.node_mass);
    jkey("stiffness", r->material.stiffness);
    jkey("damping", r->material.node_damping);
    jkey("time_step", r->time_step);
    jkey("critical_time_step", r->critical_step);
    printf(",\"warnings\":%d,\"steps\":%d,\"equilibrium\":%s,\"guard_events\":%llu", r->warnings,
           res->steps, res->equilibrium ? "true" : "false", (unsigned long long)res->guard_events);
    jkey("max_node_displacement_mm", res->max_node_disp * 1e3);
    jkey("pressed_displacement_mm", res->pressed_disp * 1e3);
    printf(",\"fixed_moved\":%d", res->fixed_moved);
    jvec("reaction_n", res->reaction.x, res->reaction.y, res->reaction.z);
    jkey("lattice_match_mm", res->lattice_match * 1e3);
    printf(",\"field\":{\"points\":%d", res->field_points);
    jkey("min_mm", res->field_min * 1e3);
    jkey("max_mm", res->field_max * 1e3);
    jkey("uz_min_mm", res->field_uz_min * 1e3);
    jkey("uz_max_mm", res->field_uz_max * 1e3);
    jkey("moved_fraction", res->field_moved_fraction);
    printf("}");
    jkey("step_us", res->step_us);
    printf(",\"slice\":{\"plane\":\"%c%c\",\"lattice_plane\":%d,\"width\":%d,\"height\":%d",
           axis_name[s->a], axis_name[s->b], (int)s->plane, s->w, s->h);
    jkey("unmap_us", s->unmap_us);
    jkey("map_us", s->map_us);
    jkey("unmap_residual_mm", s->unmap_residual * 1e3);
    jkey("max_displacement_mm", s->disp_max * 1e3);
    printf("},\"png\":");
    if (drawn) {
        char path[4096];
        snprintf(path, sizeof path, "%s/volume.png", o->out_dir);
        jstr(path);
    } else {
        printf("null");
    }
    printf("}\n");
}

static void report_text(const vol_opts *o, const vol_run *r, const vol_result *res,
                        const vol_slice *s, bool drawn)
{
    const ftm_volume_info *in = &r->info;
    ftm_vec3 size = box_size(in);
    printf("volume in a control lattice (paper 4.2): %s, %d x %d x %d voxels of %.3g x %.3g x "
           "%.3g mm (%.0f x %.0f x %.0f mm)\n",
           o->volume_path ? o->volume_path : "synthetic head phantom", in->nx, in->ny, in->nz,
           in->spacing.x * 1e3, in->spacing.y * 1e3, in->spacing.z * 1e3, size.x * 1e3,
           size.y * 1e3, size.z * 1e3);
    printf("material per node: m = %.3g kg, k = %.3g N/m, d = %.3g N s/m; h = %.3g s "
           "(critical %.3g s)%s\n",
           r->material.node_mass, r->material.stiffness, r->material.node_damping, r->time_step,
           r->critical_step, r->warnings ? "" : ", no warning");
    if (r->warnings)
        printf("WARNING from the simulation (%d): %s\n", r->warnings, r->first_warning);
    printf("\n%-44s %d x %d x %d = %d\n", "lattice points", r->n[0], r->n[1], r->n[2],
           res->lattice_points);
    printf("%-44s %d (%d links)\n", "kept nodes", res->kept_nodes, res->links);
    printf("%-44s %d%s\n", "fixed nodes (hard tissue, faces)", res->fixed_nodes,
           res->fixed_nodes ? "" : "  (none: the lattice can move as a whole)");
    printf("%-44s %d of %d\n", "air cells dropped", res->air_cells, res->cells);
    printf("%-44s %d node(s), %.3g mm down\n", "press at the top centre", r->pressed_count,
           o->push_mm);
    printf("%-44s %d\n", "penetration depth", o->depth);
    printf("%-44s %d nodes in %d layers\n", "contact region", res->region_nodes, res->layers);
    printf("%-44s %d (%s)\n", "steps to equilibrium", res->steps,
           res->equilibrium ? "reached" : "NOT reached");
    printf("%-44s %.4g mm (pressed nodes %.4g mm)\n", "max node displacement",
           res->max_node_disp * 1e3, res->pressed_disp * 1e3);
    printf("%-44s %d%s\n", "fixed nodes moved", res->fixed_moved,
           res->fixed_moved ? "  FAILED" : " (none)");
    printf("%-44s (%.4g, %.4g, %.4g) N\n", "reaction force on the probe", res->reaction.x,
           res->reaction.y, res->reaction.z);
    printf("%-44s %.3g mm\n", "FFD at lattice points vs nodes", res->lattice_match * 1e3);
    printf("%-44s |u| %.3g .. %.4g mm, u_z %.4g .. %.3g mm; %.1f%% moved > 0.1 mm\n",
           "displacement field in the tissue", res->field_min * 1e3, res->field_max * 1e3,
           res->field_uz_min * 1e3, res->field_uz_max * 1e3, 100.0 * res->field_moved_fraction);
    printf("%-44s %.3g us\n", "mean step (under the held press)", res->step_us);
    printf("%-44s %d x %d px: unmap %.0f us (%.0f ns/px), map %.0f us; residual %.2g mm\n",
           "FFD of a full slice", s->w, s->h, s->unmap_us, s->unmap_us * 1e3 / (s->w * s->h),
           s->map_us, s->unmap_residual * 1e3);
    printf("%-44s %c%c plane, lattice plane %c = %d\n", "slice", axis_name[s->a],
           axis_name[s->b], axis_name[s->c], (int)s->plane);
    if (drawn)
        printf("%-44s %s/volume.png\n", "picture", o->out_dir);
}

/* ---- command line ------------------------------------------------------------ */

static int need_value(int argc, char **argv, int i)
{
    if (i + 1 >= argc) {
        fprintf(stderr, WHO ": %s needs a value\n", argv[i]);
        return -1;
    }
    return 0;
}

static int parse(int argc, char **argv, vol_opts *o)
{
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return -1;
        }
        if (strcmp(a, "--json") == 0) {
            o->json = true;
            continue;
        }
        if (a[0] != '-' || a[1] != '-') {
            fprintf(stderr, WHO ": unexpected argument '%s'\n", a);
            return EXIT_USAGE;
        }
        static const char *const valued[] = {"--volume", "--nodes", "--depth", "--push",
                                             "--hard",   "--fix",   "--plane", "--out"};
        bool known = false;
        for (size_t k = 0; k < sizeof valued / sizeof valued[0]; k++)
            known = known || strcmp(a, valued[k]) == 0;
        if (!known) {
            fprintf(stderr, WHO ": unknown option '%s'\n", a);
            usage(stderr);
            return EXIT_USAGE;
        }
        if (need_value(argc, argv, i))
            return EXIT_USAGE;
        const char *v = argv[++i];
        bool ok = true;
        if (strcmp(a, "--volume") == 0) {
            o->volume_path = v;
        } else if (strcmp(a, "--out") == 0) {
            o->out_dir = v;
        } else if (strcmp(a, "--nodes") == 0) {
            ok = ftm_cli_int(v, 2, 100, &o->nodes);
            if (!ok)
                fprintf(stderr, WHO ": --nodes must be a whole number of lattice points per axis, "
                                    "2..100 (got '%s')\n", v);
        } else if (strcmp(a, "--depth") == 0) {
            ok = ftm_cli_int(v, 0, 1000, &o->depth);
            if (!ok)
                fprintf(stderr, WHO ": --depth must be a whole number of layers, 0..1000 (got "
                                    "'%s')\n", v);
        } else if (strcmp(a, "--push") == 0) {
            ok = ftm_cli_double(v, &o->push_mm) && o->push_mm > 0 && o->push_mm <= 1000;
            if (!ok)
                fprintf(stderr, WHO ": --push must be a distance in mm above 0 and at most 1000 "
                                    "(got '%s')\n", v);
        } else if (strcmp(a, "--hard") == 0) {
            if (strcmp(v, "none") == 0)
                o->hard = 2.0; /* above 1: none */
            else
                ok = ftm_cli_double(v, &o->hard) && o->hard >= 0 && o->hard <= 1;
            if (!ok)
                fprintf(stderr, WHO ": --hard must be an intensity 0..1 or 'none' (got '%s')\n", v);
        } else if (strcmp(a, "--fix") == 0) {
            ok = parse_faces(v, &o->fix_faces);
            if (!ok)
                fprintf(stderr, WHO ": --fix must be 'none' or faces among xmin,xmax,ymin,ymax,"
                                    "zmin,zmax separated by commas (got '%s')\n", v);
        } else { /* --plane */
            ok = strcmp(v, "xz") == 0 || strcmp(v, "yz") == 0;
            o->plane_normal = strcmp(v, "yz") == 0 ? 0 : 1;
            if (!ok)
                fprintf(stderr, WHO ": --plane must be xz or yz (got '%s')\n", v);
        }
        if (!ok)
            return EXIT_USAGE;
    }
    return 0;
}

/* An --out directory that is not one fails before the experiment runs. */
static int check_out_dir(const char *dir)
{
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        fprintf(stderr, WHO ": --out %s: %s\n", dir,
                stat(dir, &st) != 0 ? strerror(errno) : "not a directory");
        return -1;
    }
    return 0;
}

int ftm_experiment_volume(int argc, char **argv, bool json)
{
    vol_opts o = {.volume_path = NULL,
                  .nodes = 10,
                  .depth = 8,
                  .push_mm = 12.0,
                  .hard = default_hard,
                  .fix_faces = 0,
                  .plane_normal = 1,
                  .out_dir = NULL,
                  .json = json};
    int rc = parse(argc, argv, &o);
    if (rc)
        return rc < 0 ? 0 : rc;
    if (o.out_dir && check_out_dir(o.out_dir))
        return EXIT_USAGE;
    vol_run r;
    memset(&r, 0, sizeof r);
    vol_result res;
    vol_slice s;
    memset(&s, 0, sizeof s);
    bool drawn = false;
    rc = setup(&o, &r);
    if (!rc)
        rc = experiment(&o, &r, &res);
    if (!rc)
        rc = make_slice(&o, &r, &s);
    bool measured = rc == 0;
    if (measured && o.out_dir)
        rc = write_outputs(&o, &r, &s, &drawn);
    if (measured) { /* the figures, also when an output failed (said why) */
        if (o.json)
            report_json(&o, &r, &res, &s, drawn);
        else
            report_text(&o, &r, &res, &s, drawn);
    }
    if (!rc && (!res.equilibrium || res.fixed_moved)) {
        fprintf(stderr, WHO ": %s\n",
                res.fixed_moved ? "a fixed node moved" : "no equilibrium within the step limit");
        rc = EXIT_FAILED;
    }
    slice_free(&s);
    vol_run_free(&r);
    return rc;
}
