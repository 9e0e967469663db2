/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The force transmittal simulation (Choi, Sun, Heng 2004).
 *
 * Each step:
 *  1. the contact nodes form layer L0; a depth-synchronised breadth-first
 *     search from all of them builds layers L1..Ln (n = penetration depth);
 *     overlapping regions merge. The layers are cached and reused while the
 *     set of contact nodes and the depth are unchanged.
 *  2. nodes are updated layer by layer with the explicit central-difference
 *     scheme (Eqs. 5-8), each using its neighbours' already-updated positions;
 *     nodes beyond layer n stay where they are.
 *  3. nodes that were displaced and have left the contact region (after a
 *     release, or when the contact moved) keep relaxing, in ascending node
 *     order, until they are back at rest; then they are put to sleep (set
 *     exactly to their rest position and no longer touched).
 * A scene with no contact and nothing relaxing costs a counter increment.
 *
 * Determinism: the same mesh, definition and sequence of calls give a
 * bit-identical state on every run and machine (the core is built without
 * floating-point contraction or fast-math). ftm_sim_hash() fingerprints it.
 *
 * Not thread-safe: one thread per ftm_sim; the mesh may be shared. */
#ifndef FTM_SIM_H
#define FTM_SIM_H

#include "ftm/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_sim ftm_sim;

/* Update order inside a layer. The paper (section 3.1.4) finds the intra-layer
 * order immaterial; these variants make use of that and are compared by
 * `ftm bench table3`. */
typedef enum ftm_order {
    /* Layers in BFS order; inside a layer, nodes grouped into independent sets
     * (no two adjacent), each set in BFS order. Gauss-Seidel like the paper,
     * but consecutive updates do not wait on each other. Default. */
    FTM_ORDER_LAYER_COLORED = 0,
    /* Exactly the BFS traversal order of the paper's Fig. 5. */
    FTM_ORDER_BFS = 1,
    /* Each layer computed from the state before the layer, then committed:
     * earlier layers are already updated, nodes of the same layer are not. */
    FTM_ORDER_LAYER_JACOBI = 2,
} ftm_order;

/* Internal forces of the integrator. The paper's model is springs; the
 * element forces use the mesh's hexahedra and tetrahedra: the linear elastic
 * element stiffness of the FEM reference, or the neo-Hookean solid
 * (docs/accuracy.md, docs/calculix.md). */
typedef enum ftm_forces {
    FTM_FORCES_SPRINGS = 0,    /* Voigt links (Eq. 6), the default */
    FTM_FORCES_LINEAR_FEM = 1, /* f_e = K_e (x_e - X_e): small displacements */
    /* co-rotational f_e = R K_e (R^T x_e - X_e), R the rotation of the element's
     * centre (I where it is inverted): large rotations */
    FTM_FORCES_COROT_FEM = 2,
    /* compressible neo-Hookean, W = mu/2 (J^(-2/3) I1 - 3) + kappa/2 (J - 1)^2
     * (CalculiX's *HYPERELASTIC, NEO HOOKE with C10 = mu/2, D1 = 2/kappa,
     * mu and kappa from young and poisson): large strains. An element
     * inverted at a quadrature point (J <= 0) fails the step: it is undone
     * and substepped, guard or not, and FTM_EUNSTABLE if that cannot help */
    FTM_FORCES_NEO_HOOKEAN = 3,
} ftm_forces;

/* What holds the contact region at its edge. The paper holds every node
 * beyond the penetration depth at rest (FIXED), so a shallow region is
 * clamped close to the contact and feels stiffer (+57 % at depth 2 on the
 * elastin cube). ELASTIC places the nodes just beyond the region where the
 * whole body's linear static solution puts them under the current contacts
 * (precomputed compliance of the surface nodes, docs/core.md "Far field"):
 * at equilibrium the contact forces and the region's displacements are the
 * whole body's at every depth, at a cost still set by the region. It needs
 * a held body (fixed nodes), and takes a precomputation at creation. */
typedef enum ftm_far_field {
    FTM_FAR_FIELD_FIXED = 0,   /* nodes beyond the depth at rest: the paper's model, the default */
    FTM_FAR_FIELD_ELASTIC = 1, /* the region's edge where the whole body would be */
} ftm_far_field;

/* The range of ftm_sim_def.time_step [s]: below it the Eq. 8 coefficients
 * m / h^2 leave double's range for ordinary masses, above it nothing in
 * soft tissue is resolved. */
#define FTM_MIN_TIME_STEP 1e-12
#define FTM_MAX_TIME_STEP 1e3

/* A material for the elements of one mesh label (ftm_mesh_tetrahedron_label,
 * _hexahedron_label): the body's parts, e.g. grey and white matter, each
 * with its own elastic constants. */
typedef struct ftm_label_material {
    int32_t label;         /* >= 1, as the mesh's elements carry it */
    double young, poisson; /* as ftm_sim_def's */
    /* [kg/m^3] of the label's elements' lumped masses; 0: the def's
     * density. > 0 needs the def's density > 0 too (the other elements'
     * masses then come from it, not from the mesh's node masses). */
    double density;
} ftm_label_material;

typedef struct ftm_sim_def {
    double time_step;       /* h [s], FTM_MIN_TIME_STEP..FTM_MAX_TIME_STEP (default 1e-3) */
    int32_t depth;          /* penetration depth n >= 0 (default 10) */
    ftm_order order;
    /* Relaxing nodes sleep when |x - X| and |x - x_prev| are both below
     * sleep_tolerance * mean link length (default 1e-6). */
    double sleep_tolerance;
    /* The contact region under an unchanged load sleeps after this many
     * consecutive steps in which no node moved more than sleep_tolerance *
     * mean link length; 0 disables region sleep (default 0). */
    int32_t region_sleep_steps;
    /* Stability guard: a step in which a node moves more than
     * guard_motion * (its shortest link's rest length), or to a non-finite
     * position, is rolled back and redone with twice as many substeps, up to
     * max_substeps (default 0.5 and 64). guard = false skips the check. */
    bool guard;
    double guard_motion;
    int32_t max_substeps;
    /* Reuse layers and schedule while the contact node set and the depth are
     * unchanged (default true); false searches again every step, as the
     * paper's timing did (used by `ftm bench table3`). */
    bool cache_layers;
    /* For a mesh in the plane z = 0 (every rest z is +0.0, like the 2D
     * lattice) under loads with z = 0: the colored and jacobi orders' sweep
     * leaves z out, which gives the same bits, since z then stays exactly
     * +0.0 (default true). A load or a loaded state with z != 0 switches to
     * the full sweep until ftm_sim_reset or a planar ftm_sim_load_state;
     * false always runs the full sweep (tests and `ftm bench table3`
     * compare the two). */
    bool planar_kernel;
    ftm_log_fn log; /* warnings (time step above critical) and guard events */
    void *log_user;
    /* Internal forces (default FTM_FORCES_SPRINGS). With element forces a
     * node's force is the sum of its elements' rows of K_e (x_e - X_e) (or the
     * co-rotated form, or the neo-Hookean nodal forces), links only shape the
     * layers and the guard; young > 0 and -1 < poisson < 0.5 are required,
     * and density > 0 [kg/m^3] replaces the mesh's node masses by lumped
     * element masses (0 keeps them). */
    ftm_forces forces;
    double young, poisson, density;
    ftm_far_field far_field; /* default FTM_FAR_FIELD_FIXED */
    /* Selective mass scaling (element forces only; default false): a node
     * whose row of K would put the critical time step (the Gershgorin bound,
     * ftm_sim_critical_time_step) below time_step gets the least extra mass
     * that puts it at time_step, as explicit FEM codes do for the few small
     * elements of a mesh from a scan. The log says how many nodes and how
     * much mass; the others keep their lumped masses. */
    bool mass_scaling;
    /* Per-label materials (default none): an element whose label is one of
     * these takes its young, poisson (and density, if set), any other
     * element the def's own. Each label once and carried by some element of
     * the mesh; element forces only (FTM_EINVAL with springs, whose links
     * carry their stiffness). Every element model honours them (linear,
     * co-rotational, neo-Hookean: each element's own moduli), and so does
     * the elastic far field (its compliance is of the assembled K). The
     * simulation keeps its own copy. */
    const ftm_label_material *label_materials;
    int32_t label_material_count;
} ftm_sim_def;

ftm_sim_def ftm_default_sim_def(void);

typedef enum ftm_contact_kind {
    FTM_CONTACT_FORCE = 0,        /* value: external force F_i [N] */
    FTM_CONTACT_DISPLACEMENT = 1, /* value: imposed displacement x_i - X_i [m] */
} ftm_contact_kind;

/* The largest contact group: reactions are kept per group up to the largest in use. */
#define FTM_MAX_CONTACT_GROUP (1 << 20)

typedef struct ftm_contact {
    int32_t node;  /* mesh index, not fixed */
    int32_t group; /* probe/contact id 0..FTM_MAX_CONTACT_GROUP, for reaction forces (Eq. 19) */
    ftm_contact_kind kind;
    ftm_vec3 value;
} ftm_contact;

typedef struct ftm_sim_stats {
    uint64_t step;            /* steps taken */
    int32_t depth;            /* current penetration depth */
    int32_t layers;           /* layers in the contact region (<= depth + 1) */
    int32_t region_nodes;     /* nodes in the contact region */
    int32_t relaxing_nodes;   /* displaced nodes outside the region, relaxing */
    int32_t updated_nodes;    /* node updates in the last step (all substeps) */
    int32_t substeps;         /* current substeps per step (1 unless the guard raised it) */
    bool region_sleeping;     /* contact region at rest under its load */
    uint64_t searches;        /* breadth-first searches run (cache misses) */
    uint64_t guard_events;    /* steps rolled back by the guard */
    uint64_t unstable_steps;  /* steps that failed even at max_substeps */
    uint64_t planar_sweeps;   /* group sweeps that left z out (planar_kernel) */
    int32_t far_nodes;        /* elastic far field: nodes placed beyond the region */
} ftm_sim_stats;

int ftm_sim_create(const ftm_mesh *mesh, const ftm_sim_def *def, ftm_sim **out, ftm_error *err);
void ftm_sim_destroy(ftm_sim *sim);

/* Replaces the whole contact set (count may be 0: release). Validates every
 * entry (index range, fixed node, finite value, a node listed twice) and on
 * error changes nothing. Layers are recomputed only if the node set changed. */
int ftm_sim_set_contacts(ftm_sim *sim, const ftm_contact *contacts, int32_t count, ftm_error *err);

/* Changes the penetration depth (0..1e6); takes effect at the next step. */
int ftm_sim_set_depth(ftm_sim *sim, int32_t depth);

/* Advances one time step. Returns FTM_OK, or FTM_EUNSTABLE when the step
 * diverged even at max_substeps: the state is then left as before the call
 * (no NaN ever enters it). */
int ftm_sim_step(ftm_sim *sim);

/* Runs steps until count steps are done or one fails. */
int ftm_sim_run(ftm_sim *sim, int32_t count);

/* Current positions, 3 doubles per node in mesh order; valid until the next
 * call that changes the simulation. */
const double *ftm_sim_positions(const ftm_sim *sim);
ftm_vec3 ftm_sim_position(const ftm_sim *sim, int32_t node);

/* Reaction force of a contact group (Eq. 19): minus the sum of the spring
 * forces on the group's displacement-contact nodes, as of the last step. */
ftm_vec3 ftm_sim_reaction(const ftm_sim *sim, int32_t group);

/* 64-bit fingerprint of the dynamic state: the position and previous position
 * of every node not exactly at rest, and the step counter. Two simulations of
 * the same mesh have equal hashes iff (barring collisions) their states are
 * bit-identical. Cost: proportional to the number of nodes not at rest. */
uint64_t ftm_sim_hash(const ftm_sim *sim);

/* Revision of the core's arithmetic: raised whenever a change makes the same
 * scene and inputs give other bits (2: one division per pair of links,
 * 2026-11-25; 3: co-rotational forces evaluated per element at the substep's
 * start, in vector lanes, 2026-11-28; 4: their polar decomposition stops
 * on the determinant, 2026-11-28; 5: a co-rotational tetrahedron's fourth
 * force is minus the sum of the other three, 2026-11-29; 6: the polar
 * decomposition stops one step sooner, with R to 5e-11, 2026-11-29).
 * Hashes and
 * replays agree only between
 * cores of one revision, so a session announces its server's
 * (ftm_wire_announce.arithmetic). */
#define FTM_ARITHMETIC_REVISION 6u
uint32_t ftm_arithmetic_revision(void);

void ftm_sim_get_stats(const ftm_sim *sim, ftm_sim_stats *stats);

/* The layers of the current contact region (after a step or set_contacts):
 * layer_count layers; nodes of layer l are order[start[l] .. start[l+1]-1]
 * in update order. Arrays valid until the next call that changes the sim. */
int32_t ftm_sim_layers(ftm_sim *sim, const int32_t **order, const int32_t **start);

/* Kinetic energy estimate sum 1/2 m |x - x_prev|^2 / h^2 and spring potential
 * energy (links and springs to ground) over the nodes not at rest (for tests
 * and diagnostics). */
double ftm_sim_kinetic_energy(const ftm_sim *sim);
double ftm_sim_potential_energy(const ftm_sim *sim);

/* Switches to another mesh of the same shape (ftm_mesh_same_shape), e.g. one
 * with changed tissue parameters (ftm_mesh_with_material), keeping the state:
 * positions, contacts, depth, substeps. Takes effect at the next step; the
 * caller keeps the mesh alive while the simulation uses it. With element
 * forces the new links' stiffness must be the original links' times one
 * factor, which multiplies Young's modulus (every element model's forces
 * are linear in E); the mesh's damping takes effect, and its masses unless
 * the elements' density gives them. FTM_EINVAL (nothing changed) for
 * another shape, element forces whose links change by different factors,
 * or a material too stiff for the time step even at max_substeps. */
int ftm_sim_set_mesh(ftm_sim *sim, const ftm_mesh *mesh, ftm_error *err);

/* Puts every node back at rest and forgets contacts; keeps the definition. */
void ftm_sim_reset(ftm_sim *sim);

const ftm_mesh *ftm_sim_mesh(const ftm_sim *sim);

/* ---- keyframes: saving and restoring the dynamic state ----
 * For deterministic replay (server -> clients, docs/protocol.md): a state
 * saved on one simulation and loaded into another of the same mesh and
 * definition continues bit-identically. That state is: position and previous
 * position of every node not at rest, the contacts, the depth, the step
 * counter and the integrator's mode below. */

/* The integrator's internal mode (stability guard and region sleep). */
typedef struct ftm_sim_mode {
    int32_t substeps;          /* substeps per step, 1..max_substeps */
    int32_t steps_at_substeps; /* clean steps since substeps last changed */
    int32_t quiet_steps;       /* region sleep: consecutive quiet steps */
    bool region_sleeping;      /* region sleep: the region is asleep */
    /* the energy guard's account: energy the loads may have supplied (< 0:
     * not kept, restarts at the next step) and the energy after the last step */
    double energy_budget;
    double energy_prev;
} ftm_sim_mode;

void ftm_sim_get_mode(const ftm_sim *sim, ftm_sim_mode *mode);

/* The contacts in force (as last set, in ascending node order); valid until
 * the next call that changes them. Returns their count. */
int32_t ftm_sim_contacts(const ftm_sim *sim, const ftm_contact **contacts);

/* Previous positions (x_prev), 3 doubles per node, like ftm_sim_positions. */
const double *ftm_sim_previous_positions(const ftm_sim *sim);

/* Replaces the dynamic state: every node at rest except nodes[0..count-1]
 * (strictly ascending, not fixed) with positions x and previous positions xp
 * (3 per listed node); the contacts (as for ftm_sim_set_contacts), the depth,
 * the step counter and the mode (NULL: one substep, region awake, the energy
 * account restarting). Validates
 * everything first and changes nothing on error. Cost O(node count). */
int ftm_sim_load_state(ftm_sim *sim, uint64_t step, int32_t depth, const int32_t *nodes,
                       const double *x, const double *xp, int32_t count,
                       const ftm_contact *contacts, int32_t ncontacts, const ftm_sim_mode *mode,
                       ftm_error *err);

/* ---- element forces (docs/accuracy.md) ---- */

/* The critical time step of the simulation's forces: ftm_mesh_critical_time_step
 * for springs; for element forces the Gershgorin bound on M^-1 K with the
 * assembled element stiffness and the simulation's (lumped) masses. For
 * neo-Hookean forces K is their tangent at rest (the linear K): a deformed
 * body's tangent differs, and the guard substeps if that needs it. */
double ftm_sim_critical_time_step(const ftm_sim *sim);

/* Node masses the simulation uses (lumped element masses when set), 1 per node. */
const double *ftm_sim_masses(const ftm_sim *sim);

/* Internal forces at positions x (3 per node, mesh order) into f_out (3 per
 * node): the spring forces sum_j f_ij, or the element forces, as the
 * integrator computes them (co-rotational: rotations from x). A node at
 * equilibrium has f = external force. Fixed nodes get their reactions'
 * negatives like any other node. FTM_ENOMEM possible; neo-Hookean:
 * FTM_EINVAL (f_out untouched) if an element is inverted at x. */
int ftm_sim_internal_forces(const ftm_sim *sim, const double *x, double *f_out);

/* ---- contact stiffness (for haptic force models, docs/haptics.md) ---- */

/* K = dF/dx [N/m], 3x3 row-major, of the reaction F of a contact group
 * (ftm_sim_reaction) with respect to a rigid motion dx of all the group's
 * displacement contacts (how a probe moves them), the rest of the tissue held
 * at its current positions: the tangent stiffness of the springs joining the
 * group's nodes to the others (Eq. 6) and of their springs to ground, at
 * the current state. Returns the
 * number of displacement contacts of the group (0: K is zero). Springs only:
 * with element forces (ftm_sim_def.forces) it returns 0. */
int32_t ftm_sim_contact_stiffness(const ftm_sim *sim, int32_t group, double K[9]);

/* Projects a stiffness onto the passive ones in place: its symmetric part
 * with positive eigenvalues (force growing along the motion, e.g. from
 * compressed springs' transverse terms) set to zero. F0 + K dx with such a
 * K derives from a potential that only resists motion. */
void ftm_stiffness_make_passive(double K[9]);

/* Scales a (passive) held-tissue stiffness in place to the reaction's own
 * secant along the penetration pen (HIP minus the contact's anchor on the
 * rest surface): K *= alpha, alpha = (F . pen) / (pen^T K pen) kept in
 * [0, 1]. The held stiffness is the response before the tissue around the
 * contact has moved; the layers then follow and the tissue feels softer
 * (a linear tissue pressed from rest has F = K_qs pen). Returns alpha (1 and
 * K unchanged when pen^T K pen is not negative). */
double ftm_stiffness_secant_scale(double K[9], ftm_vec3 force, ftm_vec3 pen);

#ifdef __cplusplus
}
#endif
#endif
