/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Linear static FEM: sparse assembly of K over the mesh's hexahedra and
 * tetrahedra, elimination of the constrained dofs, one CHOLMOD factorisation
 * reused by every load case. docs/fem.md describes the method. */
#include "ftm/fem.h"

#include "fem_internal.h"

#include <cholmod.h>

#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* A factor whose pivots span more than this ratio (CHOLMOD's rough rcond,
 * min/max of diag(D) or of diag(L)^2) is taken as singular: rounding, not the
 * body, kept it from being exactly singular. Well-posed meshes stay far above
 * (docs/fem.md gives figures). */
#define FEM_RCOND_SINGULAR 1e-11

struct ftm_fem {
    const ftm_mesh *mesh;
    int32_t nodes;
    /* K over all dofs as 3x3 node blocks, compressed rows: row (node) i holds
     * blocks for nodes col[row_start[i] .. row_start[i+1]-1], ascending. */
    int64_t *row_start;
    int32_t *col;
    double *val; /* 9 per block, row-major */
    /* reduced numbering: free dof -> 0..free-1, constrained -> -1 */
    int32_t *reduced;
    /* Sliding nodes (ftm_mesh_slide_normals): their dofs are in the node's
     * own frame, rot[9 i] = R_i row-major with columns the normals, then
     * tangents (K's blocks hold R_i^T K_ij R_j); the first dofs, along the
     * normals, are constrained to 0. NULL when no node slides; rotated[i]. */
    double *rot;
    uint8_t *rotated;
    int64_t free_dofs;
    int64_t constrained;
    cholmod_common cc;
    bool cc_started;
    cholmod_factor *factor;
    cholmod_dense *rhs, *x, *y, *e; /* reused by every solve */
    double *work;                   /* free-dof residual for the refinement step */
    double *first;                  /* free-dof solution before the refinement */
    ftm_fem_stats stats;
};

static void logf_(const ftm_fem_def *def, const char *fmt, ...)
{
    if (!def->log)
        return;
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    def->log(def->log_user, FTM_LOG_INFO, msg);
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

ftm_fem_def ftm_default_fem_def(void)
{
    ftm_fem_def d;
    memset(&d, 0, sizeof d);
    d.material = ftm_default_fem_material();
    d.factorization = FTM_FEM_FACTOR_AUTO;
    return d;
}

/* ------------------------------------------------------------ pattern */

/* Element e's nodes: hexahedra first, then tetrahedra. */
typedef struct elements {
    const int32_t *hex, *tet;
    int32_t nh, nt;
} elements;

static int32_t element_size(const elements *el, int32_t e)
{
    return e < el->nh ? 8 : 4;
}

static const int32_t *element_nodes(const elements *el, int32_t e)
{
    return e < el->nh ? el->hex + 8 * (size_t)e : el->tet + 4 * (size_t)(e - el->nh);
}

static int compare_i32(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* Node adjacency through shared elements (each node is its own neighbour):
 * fills fem->row_start / col. *elem_count_out[i] = elements at node i. */
static int build_pattern(ftm_fem *fem, const elements *el, int32_t **elem_count_out,
                         ftm_error *err)
{
    int32_t n = fem->nodes, ne = el->nh + el->nt;
    int64_t *estart = calloc((size_t)n + 1, sizeof *estart);
    int32_t *count = calloc((size_t)n + 1, sizeof *count);
    int32_t *mark = malloc(((size_t)n + 1) * sizeof *mark);
    fem->row_start = calloc((size_t)n + 1, sizeof *fem->row_start);
    int32_t *elist = NULL;
    if (!estart || !count || !mark || !fem->row_start)
        goto oom;
    /* node -> elements, compressed */
    for (int32_t e = 0; e < ne; e++) {
        const int32_t *v = element_nodes(el, e);
        for (int32_t k = 0; k < element_size(el, e); k++)
            estart[v[k] + 1]++;
    }
    for (int32_t i = 0; i < n; i++) {
        count[i] = (int32_t)estart[i + 1];
        estart[i + 1] += estart[i];
    }
    elist = malloc(((size_t)estart[n] + 1) * sizeof *elist);
    if (!elist)
        goto oom;
    {
        int64_t *fill = fem->row_start; /* borrowed as a cursor, reset below */
        for (int32_t i = 0; i < n; i++)
            fill[i] = estart[i];
        for (int32_t e = 0; e < ne; e++) {
            const int32_t *v = element_nodes(el, e);
            for (int32_t k = 0; k < element_size(el, e); k++)
                elist[fill[v[k]]++] = e;
        }
    }
    /* two passes over the nodes: count distinct neighbours, then list them */
    for (int pass = 0; pass < 2; pass++) {
        for (int32_t i = 0; i < n; i++)
            mark[i] = -1;
        int64_t total = 0;
        for (int32_t i = 0; i < n; i++) {
            int64_t first = total;
            for (int64_t q = estart[i]; q < estart[i + 1]; q++) {
                int32_t e = elist[q];
                const int32_t *v = element_nodes(el, e);
                for (int32_t k = 0; k < element_size(el, e); k++) {
                    if (mark[v[k]] == i)
                        continue;
                    mark[v[k]] = i;
                    if (pass == 1)
                        fem->col[total] = v[k];
                    total++;
                }
            }
            if (estart[i] == estart[i + 1]) { /* no element: keep a diagonal block */
                if (pass == 1)
                    fem->col[total] = i;
                total++;
            }
            if (pass == 0)
                fem->row_start[i] = first;
            else
                qsort(fem->col + first, (size_t)(total - first), sizeof *fem->col, compare_i32);
        }
        if (pass == 0) {
            fem->row_start[n] = total;
            fem->col = malloc((size_t)total * sizeof *fem->col);
            fem->val = calloc((size_t)total * 9, sizeof *fem->val);
            if (!fem->col || !fem->val)
                goto oom;
        }
    }
    free(estart);
    free(elist);
    free(mark);
    *elem_count_out = count;
    return FTM_OK;
oom:
    free(estart);
    free(elist);
    free(mark);
    free(count);
    return ftm_error_set(err, FTM_ENOMEM, "ftm_fem_create: out of memory");
}

/* Position of block (i, j) in the compressed rows (j must be in the pattern). */
static int64_t block_at(const ftm_fem *fem, int32_t i, int32_t j)
{
    int64_t lo = fem->row_start[i], hi = fem->row_start[i + 1] - 1;
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if (fem->col[mid] < j)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

static void scatter(ftm_fem *fem, const int32_t *v, int nn, const double *ke)
{
    int n = 3 * nn;
    for (int a = 0; a < nn; a++)
        for (int b = 0; b < nn; b++) {
            double *blk = fem->val + 9 * block_at(fem, v[a], v[b]);
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    blk[3 * i + j] += ke[(3 * a + i) * n + 3 * b + j];
        }
}

/* ------------------------------------------------------------ assembly */

static void describe_nodes(const ftm_mesh *mesh, const int32_t *v, int nn, char *buf, size_t size)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int k = 0; k < nn && used < size; k++) {
        int w = snprintf(buf + used, size - used, "%s%d", k ? " " : "",
                         (int)ftm_mesh_input_of_node(mesh, v[k]));
        if (w < 0)
            break;
        used += (size_t)w;
    }
}

static int assemble(ftm_fem *fem, const ftm_fem_def *def, const elements *el, ftm_error *err)
{
    const ftm_mesh *mesh = fem->mesh;
    char nodes[128];
    ftm_vec3 x[8];
    double ke[576];
    for (int32_t h = 0; h < el->nh; h++) {
        const int32_t *v = el->hex + 8 * (size_t)h;
        const ftm_fem_material *m = def->hex_materials ? &def->hex_materials[h] : &def->material;
        for (int k = 0; k < 8; k++)
            x[k] = ftm_mesh_rest_position(mesh, v[k]);
        double min_det = 0;
        if (ftm_fem_hex_stiffness(x, m, ke, &min_det) != FTM_OK) {
            describe_nodes(mesh, v, 8, nodes, sizeof nodes);
            return ftm_error_set(err, FTM_EINVAL,
                                "hexahedron %d (input nodes %s) is inverted or degenerate: "
                                "Jacobian determinant %g at a Gauss point (must be > 0; nodes "
                                "go bottom face counter-clockwise seen from above, then top)",
                                (int)h, nodes, min_det);
        }
        scatter(fem, v, 8, ke);
    }
    /* Tetrahedra may come with either vertex order from a mesh file, but one
     * mesh uses one convention: a tetrahedron against the majority is folded. */
    int32_t positive = 0;
    for (int32_t t = 0; t < el->nt; t++) {
        const int32_t *v = el->tet + 4 * (size_t)t;
        for (int k = 0; k < 4; k++)
            x[k] = ftm_mesh_rest_position(mesh, v[k]);
        double vol = 0;
        const ftm_fem_material *m = def->tet_materials ? &def->tet_materials[t] : &def->material;
        if (ftm_fem_tet_stiffness(x, m, ke, &vol) != FTM_OK) {
            describe_nodes(mesh, v, 4, nodes, sizeof nodes);
            return ftm_error_set(err, FTM_EINVAL,
                                "tetrahedron %d (input nodes %s) is degenerate (volume %g)",
                                (int)t, nodes, vol);
        }
        positive += vol > 0;
    }
    bool majority_positive = 2 * (int64_t)positive >= el->nt;
    for (int32_t t = 0; t < el->nt; t++) {
        const int32_t *v = el->tet + 4 * (size_t)t;
        for (int k = 0; k < 4; k++)
            x[k] = ftm_mesh_rest_position(mesh, v[k]);
        double vol = 0;
        const ftm_fem_material *m = def->tet_materials ? &def->tet_materials[t] : &def->material;
        ftm_fem_tet_stiffness(x, m, ke, &vol);
        if ((vol > 0) != majority_positive) {
            describe_nodes(mesh, v, 4, nodes, sizeof nodes);
            return ftm_error_set(err, FTM_EINVAL,
                                "tetrahedron %d (input nodes %s) is inverted: signed volume %g, "
                                "but %d of the mesh's %d tetrahedra have the other orientation",
                                (int)t, nodes, vol,
                                (int)(majority_positive ? positive : el->nt - positive),
                                (int)el->nt);
        }
        scatter(fem, v, 4, ke);
    }
    return FTM_OK;
}

/* ------------------------------------------------------------ CHOLMOD */

static int factorise(ftm_fem *fem, const ftm_fem_def *def, ftm_error *err)
{
    int32_t n = fem->nodes;
    int64_t nf = fem->free_dofs;
    cholmod_common *c = &fem->cc;
    /* upper triangle of the reduced K, by columns (K is symmetric: column j = row j) */
    int64_t nnz = 0;
    for (int32_t i = 0; i < n; i++)
        for (int ci = 0; ci < 3; ci++) {
            int32_t j = fem->reduced[3 * (int64_t)i + ci];
            if (j < 0)
                continue;
            for (int64_t q = fem->row_start[i]; q < fem->row_start[i + 1]; q++)
                for (int cj = 0; cj < 3; cj++) {
                    int32_t r = fem->reduced[3 * (int64_t)fem->col[q] + cj];
                    nnz += r >= 0 && r <= j;
                }
        }
    if (nnz >= INT_MAX)
        return ftm_error_set(err, FTM_ERANGE,
                            "ftm_fem_create: %lld stiffness entries exceed CHOLMOD's int range",
                            (long long)nnz);
    cholmod_sparse *a =
        cholmod_allocate_sparse((size_t)nf, (size_t)nf, (size_t)nnz, 1, 1, 1, CHOLMOD_REAL, c);
    if (!a)
        return ftm_error_set(err, FTM_ENOMEM, "ftm_fem_create: CHOLMOD out of memory");
    int *ap = a->p, *ai = a->i;
    double *ax = a->x;
    int64_t k = 0;
    for (int32_t i = 0; i < n; i++)
        for (int ci = 0; ci < 3; ci++) {
            int32_t j = fem->reduced[3 * (int64_t)i + ci];
            if (j < 0)
                continue;
            ap[j] = (int)k;
            for (int64_t q = fem->row_start[i]; q < fem->row_start[i + 1]; q++)
                for (int cj = 0; cj < 3; cj++) {
                    int32_t r = fem->reduced[3 * (int64_t)fem->col[q] + cj];
                    if (r >= 0 && r <= j) {
                        ai[k] = r;
                        ax[k] = fem->val[9 * q + 3 * ci + cj];
                        k++;
                    }
                }
        }
    ap[nf] = (int)k;
    fem->stats.nnz = nnz;

    switch (def->factorization) {
    case FTM_FEM_FACTOR_SIMPLICIAL: c->supernodal = CHOLMOD_SIMPLICIAL; break;
    case FTM_FEM_FACTOR_SUPERNODAL: c->supernodal = CHOLMOD_SUPERNODAL; break;
    case FTM_FEM_FACTOR_AUTO:
    default: c->supernodal = CHOLMOD_AUTO; break;
    }
    double t0 = now_seconds();
    fem->factor = cholmod_analyze(a, c);
    int rc = FTM_OK;
    if (!fem->factor) {
        rc = ftm_error_set(err, c->status == CHOLMOD_OUT_OF_MEMORY ? FTM_ENOMEM : FTM_EINVAL,
                          "ftm_fem_create: CHOLMOD analysis failed (status %d)", c->status);
    } else {
        int ok = cholmod_factorize(a, fem->factor, c);
        if (!ok || c->status == CHOLMOD_OUT_OF_MEMORY) {
            rc = ftm_error_set(err, FTM_ENOMEM, "ftm_fem_create: CHOLMOD factorisation failed "
                                               "(status %d)", c->status);
        } else if (c->status == CHOLMOD_NOT_POSDEF) {
            rc = ftm_error_set(err, FTM_EINVAL,
                              "stiffness matrix is not positive definite (pivot %d of %lld): "
                              "unconstrained body or mechanism; fix enough nodes or dofs to "
                              "stop rigid motion",
                              (int)fem->factor->minor, (long long)nf);
        } else {
            double rcond = cholmod_rcond(fem->factor, c);
            fem->stats.rcond = rcond;
            if (!(rcond > FEM_RCOND_SINGULAR))
                rc = ftm_error_set(err, FTM_EINVAL,
                                  "stiffness matrix is singular (pivot ratio %.3g): "
                                  "unconstrained body or mechanism; fix enough nodes or dofs to "
                                  "stop rigid motion",
                                  rcond);
        }
    }
    fem->stats.factor_seconds = now_seconds() - t0;
    if (rc == FTM_OK) {
        fem->stats.factor_nnz = (int64_t)c->lnz;
        fem->stats.supernodal = fem->factor->is_super != 0;
        logf_(def, "fem: %lld free dofs, %lld entries in K, %lld in L (%s), factor %.3f s",
              (long long)nf, (long long)nnz, (long long)fem->stats.factor_nnz,
              fem->stats.supernodal ? "supernodal" : "simplicial", fem->stats.factor_seconds);
        fem->rhs = cholmod_allocate_dense((size_t)nf, 1, (size_t)nf, CHOLMOD_REAL, c);
        fem->work = malloc((size_t)nf * sizeof *fem->work);
        fem->first = malloc((size_t)nf * sizeof *fem->first);
        if (!fem->rhs || !fem->work || !fem->first)
            rc = ftm_error_set(err, FTM_ENOMEM, "ftm_fem_create: out of memory");
    }
    cholmod_free_sparse(&a, c);
    return rc;
}

/* ------------------------------------------------------------ constraints */

/* A unit vector normal to n (unit): the axis n is least along, less its
 * part along n. Exact for an axis n (another axis). */
static void tangent(const double n[3], double t[3])
{
    int a = 0;
    for (int d = 1; d < 3; d++)
        if (fabs(n[d]) < fabs(n[a]))
            a = d;
    double dot = n[a];
    for (int d = 0; d < 3; d++)
        t[d] = (d == a ? 1.0 : 0.0) - dot * n[d];
    double l = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    for (int d = 0; d < 3; d++)
        t[d] /= l;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* B = R_i^T B (left) or B = B R_j (right), B a 3x3 block row-major. */
static void rotate_block(double b[9], const double r[9], bool left)
{
    double o[9];
    for (int p = 0; p < 3; p++)
        for (int q = 0; q < 3; q++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++)
                s += left ? r[3 * k + p] * b[3 * k + q] : b[3 * p + k] * r[3 * k + q];
            o[3 * p + q] = s;
        }
    memcpy(b, o, sizeof o);
}

/* v = R^T v (to the node's frame) or R v (back). */
static void rotate_vec(double v[3], const double r[9], bool to_frame)
{
    double o[3];
    for (int p = 0; p < 3; p++)
        o[p] = to_frame ? r[p] * v[0] + r[3 + p] * v[1] + r[6 + p] * v[2]
                        : r[3 * p] * v[0] + r[3 * p + 1] * v[1] + r[3 * p + 2] * v[2];
    memcpy(v, o, sizeof o);
}

/* The mesh's springs to ground (k_g I on the node's diagonal block) and
 * sliding nodes (their blocks turned to the node's frame, whose first dofs
 * are then constrained: the normals eliminated exactly). */
static int mesh_constraints(ftm_fem *fem, const ftm_fem_def *def, ftm_error *err)
{
    const ftm_mesh *m = fem->mesh;
    const int32_t n = fem->nodes;
    for (int32_t i = 0; i < n; i++) {
        const double k = ftm_mesh_ground_stiffness(m, i);
        if (k <= 0.0 || ftm_mesh_fixed(m, i))
            continue;
        for (int64_t q = fem->row_start[i]; q < fem->row_start[i + 1]; q++)
            if (fem->col[q] == i)
                for (int d = 0; d < 3; d++)
                    fem->val[9 * q + 4 * d] += k;
    }
    if (!ftm_mesh_has_slides(m))
        return FTM_OK;
    fem->rot = calloc(9 * (size_t)n, sizeof *fem->rot);
    fem->rotated = calloc((size_t)n, 1);
    if (!fem->rot || !fem->rotated)
        return ftm_error_set(err, FTM_ENOMEM, "ftm_fem_create: out of memory");
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 nv[2];
        const int32_t c = ftm_mesh_slide_normals(m, i, nv);
        if (c <= 0 || ftm_mesh_fixed(m, i))
            continue;
        for (int d = 0; c > 0 && def->constrained && d < 3; d++)
            if (def->constrained[3 * (int64_t)i + d])
                return ftm_error_set(err, FTM_EINVAL,
                                     "node %d (input index) slides on a plane and has constrained "
                                     "dofs too: fix it or let it slide",
                                     (int)ftm_mesh_input_of_node(m, i));
        double col[3][3] = {{nv[0].x, nv[0].y, nv[0].z}};
        if (c == 2) {
            col[1][0] = nv[1].x;
            col[1][1] = nv[1].y;
            col[1][2] = nv[1].z;
        } else {
            tangent(col[0], col[1]);
        }
        cross(col[0], col[1], col[2]);
        double *r = fem->rot + 9 * (size_t)i;
        for (int p = 0; p < 3; p++)
            for (int q = 0; q < 3; q++)
                r[3 * p + q] = col[q][p];
        fem->rotated[i] = 1;
    }
    for (int32_t i = 0; i < n; i++)
        for (int64_t q = fem->row_start[i]; q < fem->row_start[i + 1]; q++) {
            const int32_t j = fem->col[q];
            if (fem->rotated[i])
                rotate_block(fem->val + 9 * q, fem->rot + 9 * (size_t)i, true);
            if (fem->rotated[j])
                rotate_block(fem->val + 9 * q, fem->rot + 9 * (size_t)j, false);
        }
    return FTM_OK;
}

/* ------------------------------------------------------------ public */

void ftm_fem_destroy(ftm_fem *fem)
{
    if (!fem)
        return;
    if (fem->cc_started) {
        cholmod_free_factor(&fem->factor, &fem->cc);
        cholmod_free_dense(&fem->rhs, &fem->cc);
        cholmod_free_dense(&fem->x, &fem->cc);
        cholmod_free_dense(&fem->y, &fem->cc);
        cholmod_free_dense(&fem->e, &fem->cc);
        cholmod_finish(&fem->cc);
    }
    free(fem->row_start);
    free(fem->col);
    free(fem->val);
    free(fem->reduced);
    free(fem->rot);
    free(fem->rotated);
    free(fem->work);
    free(fem->first);
    free(fem);
}

int ftm_fem_create(const ftm_mesh *mesh, const ftm_fem_def *def, ftm_fem **out, ftm_error *err)
{
    if (!mesh || !def || !out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_fem_create: NULL argument");
    elements el = {ftm_mesh_hexahedra(mesh), ftm_mesh_tetrahedra(mesh),
                   ftm_mesh_hexahedron_count(mesh), ftm_mesh_tetrahedron_count(mesh)};
    int32_t n = ftm_mesh_node_count(mesh);
    if (el.nh + (int64_t)el.nt == 0)
        return ftm_error_set(err, FTM_EINVAL,
                            "mesh has no hexahedra or tetrahedra: the FEM needs a volume mesh "
                            "(a lattice3d or a tetrahedral mesh file)");
    if ((int64_t)el.nh + el.nt > INT32_MAX || 3 * (int64_t)n >= INT_MAX)
        return ftm_error_set(err, FTM_ERANGE, "ftm_fem_create: mesh too large");
    /* materials first: the cheapest checks with the clearest messages */
    char what[64];
    int rc = ftm_fem_check_material(&def->material, "material", err);
    for (int32_t h = 0; rc == FTM_OK && def->hex_materials && h < el.nh; h++) {
        snprintf(what, sizeof what, "hexahedron %d", (int)h);
        rc = ftm_fem_check_material(&def->hex_materials[h], what, err);
    }
    for (int32_t t = 0; rc == FTM_OK && def->tet_materials && t < el.nt; t++) {
        snprintf(what, sizeof what, "tetrahedron %d", (int)t);
        rc = ftm_fem_check_material(&def->tet_materials[t], what, err);
    }
    if (rc != FTM_OK)
        return rc;

    ftm_fem *fem = calloc(1, sizeof *fem);
    if (!fem)
        return ftm_error_set(err, FTM_ENOMEM, "ftm_fem_create: out of memory");
    fem->mesh = mesh;
    fem->nodes = n;
    fem->stats.nodes = n;
    fem->stats.hexahedra = el.nh;
    fem->stats.tetrahedra = el.nt;
    fem->stats.dofs = 3 * (int64_t)n;

    double t0 = now_seconds();
    int32_t *elem_count = NULL;
    rc = build_pattern(fem, &el, &elem_count, err);
    if (rc == FTM_OK)
        rc = assemble(fem, def, &el, err);
    fem->stats.assemble_seconds = now_seconds() - t0;

    if (rc == FTM_OK)
        rc = mesh_constraints(fem, def, err);
    /* constraints: fixed nodes (all dofs), sliding nodes' normals, plus the
     * caller's dofs */
    if (rc == FTM_OK) {
        fem->reduced = malloc(3 * (size_t)n * sizeof *fem->reduced);
        if (!fem->reduced)
            rc = ftm_error_set(err, FTM_ENOMEM, "ftm_fem_create: out of memory");
    }
    for (int32_t i = 0; rc == FTM_OK && i < n; i++) {
        bool fixed = ftm_mesh_fixed(mesh, i);
        const int32_t slides = ftm_mesh_slide_normals(mesh, i, NULL);
        for (int c = 0; c < 3; c++) {
            int64_t dof = 3 * (int64_t)i + c;
            if (fixed || c < slides || (def->constrained && def->constrained[dof])) {
                fem->reduced[dof] = -1;
                fem->constrained++;
            } else {
                if (elem_count[i] == 0) {
                    rc = ftm_error_set(err, FTM_EINVAL,
                                      "node %d (input index) belongs to no element and is not "
                                      "fixed: its displacement is undetermined",
                                      (int)ftm_mesh_input_of_node(mesh, i));
                    break;
                }
                fem->reduced[dof] = (int32_t)fem->free_dofs++;
            }
        }
    }
    free(elem_count);
    fem->stats.constrained = fem->constrained;
    fem->stats.free_dofs = fem->free_dofs;

    if (rc == FTM_OK) {
        cholmod_start(&fem->cc);
        fem->cc_started = true;
        fem->cc.print = 0; /* errors come back as FTM codes with our own messages */
        fem->cc.error_handler = NULL;
        if (fem->free_dofs > 0)
            rc = factorise(fem, def, err);
    }
    if (rc != FTM_OK) {
        ftm_fem_destroy(fem);
        return rc;
    }
    *out = fem;
    return FTM_OK;
}

/* y = K_ff x over the free dofs (x, y in reduced numbering). */
static void multiply_free(const ftm_fem *fem, const double *x, double *y)
{
    for (int32_t i = 0; i < fem->nodes; i++)
        for (int ci = 0; ci < 3; ci++) {
            int32_t ri = fem->reduced[3 * (int64_t)i + ci];
            if (ri < 0)
                continue;
            double s = 0.0;
            for (int64_t q = fem->row_start[i]; q < fem->row_start[i + 1]; q++) {
                const double *blk = fem->val + 9 * q;
                for (int cj = 0; cj < 3; cj++) {
                    int32_t rj = fem->reduced[3 * (int64_t)fem->col[q] + cj];
                    if (rj >= 0)
                        s += blk[3 * ci + cj] * x[rj];
                }
            }
            y[ri] = s;
        }
}

static int solve_factor(ftm_fem *fem, ftm_error *err)
{
    if (!cholmod_solve2(CHOLMOD_A, fem->factor, fem->rhs, NULL, &fem->x, NULL, &fem->y, &fem->e,
                        &fem->cc))
        return ftm_error_set(err, FTM_ENOMEM, "ftm_fem_solve: CHOLMOD solve failed (status %d)",
                            fem->cc.status);
    return FTM_OK;
}

int ftm_fem_solve(ftm_fem *fem, const double *forces, const double *prescribed, double *u_out,
                  ftm_error *err)
{
    if (!fem || !u_out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_fem_solve: NULL argument");
    int32_t n = fem->nodes;
    for (int64_t d = 0; d < 3 * (int64_t)n; d++) {
        bool c = fem->reduced[d] < 0;
        if (!c && forces && !isfinite(forces[d]))
            return ftm_error_set(err, FTM_EINVAL, "ftm_fem_solve: force on node %d axis %c is %g",
                                (int)ftm_mesh_input_of_node(fem->mesh, (int32_t)(d / 3)),
                                (int)('x' + d % 3), forces[d]);
        if (c && prescribed && !isfinite(prescribed[d]))
            return ftm_error_set(err, FTM_EINVAL,
                                "ftm_fem_solve: prescribed displacement of node %d axis %c is %g",
                                (int)ftm_mesh_input_of_node(fem->mesh, (int32_t)(d / 3)),
                                (int)('x' + d % 3), prescribed[d]);
    }
    double t0 = now_seconds();
    /* b_f = f_f - K_fc u_c */
    double *b = fem->free_dofs ? fem->rhs->x : NULL;
    for (int32_t i = 0; i < n; i++)
        for (int ci = 0; ci < 3; ci++) {
            int64_t d = 3 * (int64_t)i + ci;
            int32_t ri = fem->reduced[d];
            if (ri < 0)
                continue;
            double s = forces ? forces[d] : 0.0;
            if (forces && fem->rotated && fem->rotated[i]) { /* in the node's frame */
                double v[3] = {forces[d - ci], forces[d - ci + 1], forces[d - ci + 2]};
                rotate_vec(v, fem->rot + 9 * (size_t)i, true);
                s = v[ci];
            }
            if (prescribed) {
                for (int64_t q = fem->row_start[i]; q < fem->row_start[i + 1]; q++) {
                    const double *blk = fem->val + 9 * q;
                    if (fem->rotated && fem->rotated[fem->col[q]])
                        continue; /* its constrained dofs are its normals: 0 */
                    for (int cj = 0; cj < 3; cj++) {
                        int64_t dj = 3 * (int64_t)fem->col[q] + cj;
                        if (fem->reduced[dj] < 0)
                            s -= blk[3 * ci + cj] * prescribed[dj];
                    }
                }
            }
            b[ri] = s;
        }
    if (fem->free_dofs) {
        int rc = solve_factor(fem, err);
        if (rc != FTM_OK)
            return rc;
        /* one step of iterative refinement against the assembled K:
         * x += K_ff^-1 (b - K_ff x) */
        int64_t nf = fem->free_dofs;
        const double *x = fem->x->x;
        multiply_free(fem, x, fem->work);
        for (int64_t k = 0; k < nf; k++)
            fem->work[k] = b[k] - fem->work[k];
        double *keep = fem->first;
        memcpy(keep, x, (size_t)nf * sizeof *keep);
        memcpy(b, fem->work, (size_t)nf * sizeof *b);
        rc = solve_factor(fem, err);
        if (rc != FTM_OK)
            return rc;
        x = fem->x->x;
        for (int64_t k = 0; k < nf; k++)
            keep[k] += x[k];
        for (int64_t d = 0; d < 3 * (int64_t)n; d++) {
            int32_t r = fem->reduced[d];
            const bool turned = fem->rotated && fem->rotated[d / 3];
            u_out[d] = r >= 0 ? keep[r] : (prescribed && !turned ? prescribed[d] : 0.0);
        }
        for (int32_t i = 0; fem->rotated && i < n; i++)
            if (fem->rotated[i])
                rotate_vec(u_out + 3 * (size_t)i, fem->rot + 9 * (size_t)i, false);
    } else {
        for (int64_t d = 0; d < 3 * (int64_t)n; d++)
            u_out[d] = prescribed ? prescribed[d] : 0.0;
    }
    fem->stats.solve_seconds += now_seconds() - t0;
    fem->stats.solves++;
    return FTM_OK;
}

void ftm_fem_residual(const ftm_fem *fem, const double *u, const double *forces, double *r_out)
{
    for (int32_t i = 0; i < fem->nodes; i++) {
        double ri[3];
        for (int ci = 0; ci < 3; ci++) {
            double s = 0.0;
            for (int64_t q = fem->row_start[i]; q < fem->row_start[i + 1]; q++) {
                const double *blk = fem->val + 9 * q;
                const int32_t j = fem->col[q];
                double uj[3] = {u[3 * (int64_t)j], u[3 * (int64_t)j + 1], u[3 * (int64_t)j + 2]};
                if (fem->rotated && fem->rotated[j]) /* K's blocks are in the nodes' frames */
                    rotate_vec(uj, fem->rot + 9 * (size_t)j, true);
                for (int cj = 0; cj < 3; cj++)
                    s += blk[3 * ci + cj] * uj[cj];
            }
            ri[ci] = s;
        }
        if (fem->rotated && fem->rotated[i])
            rotate_vec(ri, fem->rot + 9 * (size_t)i, false);
        for (int ci = 0; ci < 3; ci++) {
            int64_t d = 3 * (int64_t)i + ci;
            r_out[d] = ri[ci] - (forces ? forces[d] : 0.0);
        }
    }
}

ftm_fem_stats ftm_fem_get_stats(const ftm_fem *fem)
{
    return fem->stats;
}

const ftm_mesh *ftm_fem_mesh(const ftm_fem *fem)
{
    return fem->mesh;
}
