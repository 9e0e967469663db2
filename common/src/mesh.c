/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Mesh builder and the immutable mesh: validation, link de-duplication,
 * surface extraction from tetrahedra, locality ordering, CSR adjacency. */
#include "mesh_internal.h"

#include "error.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct ftm_mesh_builder {
    int32_t node_count, node_cap;
    ftm_node_def *nodes;
    int32_t link_count, link_cap;
    ftm_link_def *links; /* rest_length resolved, a < b */
    int32_t tri_count, tri_cap;
    int32_t *tris;
    int32_t tet_count, tet_cap;
    int32_t *tets;
    int32_t hex_count, hex_cap;
    int32_t *hexes;
    /* Element labels (tissues), NULL until the first label is set; then one
     * per element, 0 where none was set. */
    int32_t *tet_labels, *hex_labels;
    int32_t tet_label_cap, hex_label_cap; /* in elements */
    /* Partial constraints and ground springs (input order), NULL until the
     * first is set: the normals a node may not move along, orthonormal,
     * and the stiffness of its springs to ground. */
    struct builder_bc {
        double n[2][3];
        double k;
        int32_t count;
    } *bc;
    int32_t bc_cap;
    ftm_label_name *label_names;
    int32_t label_name_count, label_name_cap;
    /* open-addressing set of link keys (a << 32 | b), for de-duplication */
    uint64_t *link_keys;
    uint32_t key_cap; /* power of two, 0 = none yet */
};

static bool grow_labels(int32_t **labels, int32_t *cap, int32_t need);

static bool grow(void **ptr, int32_t *cap, int32_t need, size_t elem)
{
    if (need <= *cap)
        return true;
    if (need > INT32_MAX / 2)
        return false;
    int32_t ncap = *cap ? *cap : 64;
    while (ncap < need)
        ncap *= 2;
    void *p = realloc(*ptr, (size_t)ncap * elem);
    if (!p)
        return false;
    *ptr = p;
    *cap = ncap;
    return true;
}

ftm_node_def ftm_default_node_def(void)
{
    return (ftm_node_def){.position = {0, 0, 0}, .mass = 1.0, .damping = 0.0, .fixed = false};
}

ftm_link_def ftm_default_link_def(void)
{
    return (ftm_link_def){.a = -1, .b = -1, .stiffness = 1.0, .rest_length = -1.0};
}

ftm_mesh_build_def ftm_default_mesh_build_def(void)
{
    return (ftm_mesh_build_def){.reorder = true, .surface_from_tetrahedra = true};
}

ftm_mesh_builder *ftm_mesh_builder_create(void)
{
    return calloc(1, sizeof(ftm_mesh_builder));
}

void ftm_mesh_builder_destroy(ftm_mesh_builder *b)
{
    if (!b)
        return;
    free(b->nodes);
    free(b->links);
    free(b->tris);
    free(b->tets);
    free(b->hexes);
    free(b->tet_labels);
    free(b->hex_labels);
    free(b->bc);
    free(b->label_names);
    free(b->link_keys);
    free(b);
}

int32_t ftm_mesh_builder_node_count(const ftm_mesh_builder *b)
{
    return b->node_count;
}

int ftm_mesh_builder_node_position(const ftm_mesh_builder *b, int32_t node, ftm_vec3 *out)
{
    if (!b || !out || node < 0 || node >= b->node_count)
        return FTM_ERANGE;
    *out = b->nodes[node].position;
    return FTM_OK;
}

int ftm_mesh_builder_set_fixed(ftm_mesh_builder *b, int32_t node, bool fixed)
{
    if (!b || node < 0 || node >= b->node_count)
        return FTM_ERANGE;
    b->nodes[node].fixed = fixed;
    return FTM_OK;
}

/* The builder's constraint record of node, zeroed records for every node
 * added so far; NULL: no memory. */
static struct builder_bc *builder_bc(ftm_mesh_builder *b, int32_t node)
{
    const int32_t old = b->bc ? b->bc_cap : 0;
    if (!grow((void **)&b->bc, &b->bc_cap, b->node_count, sizeof *b->bc))
        return NULL;
    if (b->bc_cap > old)
        memset(b->bc + old, 0, (size_t)(b->bc_cap - old) * sizeof *b->bc);
    return &b->bc[node];
}

int ftm_mesh_builder_add_slide(ftm_mesh_builder *b, int32_t node, ftm_vec3 normal)
{
    if (!b || node < 0 || node >= b->node_count)
        return FTM_ERANGE;
    const double v[3] = {normal.x, normal.y, normal.z};
    const double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!isfinite(len) || !(len > 0.0))
        return FTM_EINVAL;
    struct builder_bc *c = builder_bc(b, node);
    if (!c)
        return FTM_ENOMEM;
    /* Gram-Schmidt against the normals the node has: what is left of v is
     * the new direction (an axis stays an exact axis: its dot products with
     * other axes are exact zeros) */
    double r[3] = {v[0] / len, v[1] / len, v[2] / len};
    for (int32_t q = 0; q < c->count; q++) {
        const double *n = c->n[q];
        const double dot = r[0] * n[0] + r[1] * n[1] + r[2] * n[2];
        for (int d = 0; d < 3; d++)
            r[d] -= dot * n[d];
    }
    const double rl = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    if (rl <= 1e-9)
        return FTM_OK; /* a plane the node is on already */
    if (c->count == 2)
        return FTM_EINVAL; /* three directions: the node is fixed */
    for (int d = 0; d < 3; d++)
        c->n[c->count][d] = r[d] / rl;
    c->count++;
    return FTM_OK;
}

int ftm_mesh_builder_add_ground_spring(ftm_mesh_builder *b, int32_t node, double stiffness)
{
    if (!b || node < 0 || node >= b->node_count)
        return FTM_ERANGE;
    if (!isfinite(stiffness) || !(stiffness > 0.0))
        return FTM_EINVAL;
    struct builder_bc *c = builder_bc(b, node);
    if (!c)
        return FTM_ENOMEM;
    if (!isfinite(c->k + stiffness))
        return FTM_EINVAL;
    c->k += stiffness;
    return FTM_OK;
}

bool ftm_mesh_builder_node_fixed(const ftm_mesh_builder *b, int32_t node)
{
    return b && node >= 0 && node < b->node_count && b->nodes[node].fixed;
}

/* Calls fn(user, node) for every node of every element labelled `label`
 * (a node of several such elements more than once); returns how many
 * elements carry the label. */
static int32_t for_label_nodes(const ftm_mesh_builder *b, int32_t label,
                               void (*fn)(void *user, int32_t node), void *user)
{
    if (!b || label < 1)
        return 0;
    int32_t found = 0;
    for (int32_t e = 0; b->tet_labels && e < b->tet_count; e++)
        if (b->tet_labels[e] == label) {
            for (int k = 0; k < 4; k++)
                fn(user, b->tets[4 * (size_t)e + k]);
            found++;
        }
    for (int32_t e = 0; b->hex_labels && e < b->hex_count; e++)
        if (b->hex_labels[e] == label) {
            for (int k = 0; k < 8; k++)
                fn(user, b->hexes[8 * (size_t)e + k]);
            found++;
        }
    return found;
}

static void mark_node(void *user, int32_t node) { ((uint8_t *)user)[node] = 1; }

int32_t ftm_mesh_builder_label_nodes(const ftm_mesh_builder *b, int32_t label, uint8_t *mark)
{
    return for_label_nodes(b, label, mark_node, mark);
}

static void fix_node(void *user, int32_t node)
{
    ((ftm_mesh_builder *)user)->nodes[node].fixed = true;
}

int32_t ftm_mesh_builder_fix_label(ftm_mesh_builder *b, int32_t label)
{
    return for_label_nodes(b, label, fix_node, b);
}

static bool finite3(ftm_vec3 v)
{
    return isfinite(v.x) && isfinite(v.y) && isfinite(v.z);
}

int32_t ftm_mesh_builder_add_node(ftm_mesh_builder *b, const ftm_node_def *def)
{
    if (!b || !def || !finite3(def->position) || !(def->mass > 0.0) || !isfinite(def->mass) ||
        !(def->damping >= 0.0) || !isfinite(def->damping))
        return FTM_EINVAL;
    if (!grow((void **)&b->nodes, &b->node_cap, b->node_count + 1, sizeof *b->nodes))
        return FTM_ENOMEM;
    b->nodes[b->node_count] = *def;
    return b->node_count++;
}

static uint64_t mix64(uint64_t x)
{
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ULL;
    x ^= x >> 33;
    return x;
}

/* Inserts key; returns 1 if new, 0 if present, negative on allocation failure. */
static int key_insert(ftm_mesh_builder *b, uint64_t key)
{
    if ((uint64_t)(b->link_count + 1) * 2 > b->key_cap) {
        uint32_t ncap = b->key_cap ? b->key_cap * 2 : 256;
        uint64_t *nk = malloc((size_t)ncap * sizeof *nk);
        if (!nk)
            return FTM_ENOMEM;
        memset(nk, 0xff, (size_t)ncap * sizeof *nk);
        for (uint32_t i = 0; i < b->key_cap; i++) {
            uint64_t k = b->link_keys[i];
            if (k == UINT64_MAX)
                continue;
            uint32_t h = (uint32_t)mix64(k) & (ncap - 1);
            while (nk[h] != UINT64_MAX)
                h = (h + 1) & (ncap - 1);
            nk[h] = k;
        }
        free(b->link_keys);
        b->link_keys = nk;
        b->key_cap = ncap;
    }
    uint32_t h = (uint32_t)mix64(key) & (b->key_cap - 1);
    while (b->link_keys[h] != UINT64_MAX) {
        if (b->link_keys[h] == key)
            return 0;
        h = (h + 1) & (b->key_cap - 1);
    }
    b->link_keys[h] = key;
    return 1;
}

static double dist(ftm_vec3 p, ftm_vec3 q)
{
    double dx = p.x - q.x, dy = p.y - q.y, dz = p.z - q.z;
    return sqrt(dx * dx + dy * dy + dz * dz);
}

int ftm_mesh_builder_add_link(ftm_mesh_builder *b, const ftm_link_def *def)
{
    if (!b || !def)
        return FTM_EINVAL;
    if (def->a < 0 || def->b < 0 || def->a >= b->node_count || def->b >= b->node_count)
        return FTM_ERANGE;
    if (def->a == def->b || !(def->stiffness > 0.0) || !isfinite(def->stiffness) ||
        !isfinite(def->rest_length))
        return FTM_EINVAL;
    int32_t lo = def->a < def->b ? def->a : def->b, hi = def->a < def->b ? def->b : def->a;
    double len = def->rest_length;
    if (len < 0.0)
        len = dist(b->nodes[lo].position, b->nodes[hi].position);
    if (!(len > 0.0))
        return FTM_EINVAL; /* coincident nodes: no direction at rest */
    if (!grow((void **)&b->links, &b->link_cap, b->link_count + 1, sizeof *b->links))
        return FTM_ENOMEM;
    int r = key_insert(b, (uint64_t)lo << 32 | (uint32_t)hi);
    if (r <= 0)
        return r; /* duplicate (0): first definition wins */
    b->links[b->link_count++] = (ftm_link_def){.a = lo, .b = hi, .stiffness = def->stiffness,
                                               .rest_length = len};
    return FTM_OK;
}

static bool distinct_in_range(const int32_t *v, int n, int32_t count)
{
    for (int i = 0; i < n; i++) {
        if (v[i] < 0 || v[i] >= count)
            return false;
        for (int j = 0; j < i; j++)
            if (v[i] == v[j])
                return false;
    }
    return true;
}

int ftm_mesh_builder_add_triangle(ftm_mesh_builder *b, int32_t a, int32_t c1, int32_t c2)
{
    int32_t v[3] = {a, c1, c2};
    if (!b)
        return FTM_EINVAL;
    if (!distinct_in_range(v, 3, b->node_count))
        return FTM_ERANGE;
    if (!grow((void **)&b->tris, &b->tri_cap, (b->tri_count + 1) * 3, sizeof *b->tris))
        return FTM_ENOMEM;
    memcpy(b->tris + 3 * b->tri_count++, v, sizeof v);
    return FTM_OK;
}

int ftm_mesh_builder_add_tetrahedron(ftm_mesh_builder *b, int32_t a, int32_t c1, int32_t c2,
                                     int32_t d)
{
    int32_t v[4] = {a, c1, c2, d};
    if (!b)
        return FTM_EINVAL;
    if (!distinct_in_range(v, 4, b->node_count))
        return FTM_ERANGE;
    if (!grow((void **)&b->tets, &b->tet_cap, (b->tet_count + 1) * 4, sizeof *b->tets))
        return FTM_ENOMEM;
    if (b->tet_labels && !grow_labels(&b->tet_labels, &b->tet_label_cap, b->tet_count + 1))
        return FTM_ENOMEM;
    memcpy(b->tets + 4 * b->tet_count, v, sizeof v);
    if (b->tet_labels)
        b->tet_labels[b->tet_count] = 0;
    b->tet_count++;
    return FTM_OK;
}

int ftm_mesh_builder_add_hexahedron(ftm_mesh_builder *b, const int32_t nodes[8])
{
    if (!b || !nodes)
        return FTM_EINVAL;
    if (!distinct_in_range(nodes, 8, b->node_count))
        return FTM_ERANGE;
    if (!grow((void **)&b->hexes, &b->hex_cap, (b->hex_count + 1) * 8, sizeof *b->hexes))
        return FTM_ENOMEM;
    if (b->hex_labels && !grow_labels(&b->hex_labels, &b->hex_label_cap, b->hex_count + 1))
        return FTM_ENOMEM;
    memcpy(b->hexes + 8 * b->hex_count, nodes, 8 * sizeof *nodes);
    if (b->hex_labels)
        b->hex_labels[b->hex_count] = 0;
    b->hex_count++;
    return FTM_OK;
}

int32_t ftm_mesh_builder_tetrahedron_count(const ftm_mesh_builder *b)
{
    return b ? b->tet_count : FTM_EINVAL;
}

int32_t ftm_mesh_builder_hexahedron_count(const ftm_mesh_builder *b)
{
    return b ? b->hex_count : FTM_EINVAL;
}

/* Room for `need` labels; entries added are 0. */
static bool grow_labels(int32_t **labels, int32_t *cap, int32_t need)
{
    int32_t old = *labels ? *cap : 0;
    if (*labels && need <= *cap)
        return true;
    int32_t ncap = old > 0 ? old : 64;
    while (ncap < need) {
        if (ncap > INT32_MAX / 2)
            return false;
        ncap *= 2;
    }
    int32_t *p = realloc(*labels, (size_t)ncap * sizeof *p);
    if (!p)
        return false;
    memset(p + old, 0, (size_t)(ncap - old) * sizeof *p);
    *labels = p;
    *cap = ncap;
    return true;
}

static int set_label(int32_t **labels, int32_t *cap, int32_t count, int32_t element,
                     int32_t label)
{
    if (element < 0 || element >= count)
        return FTM_ERANGE;
    if (label < 0)
        return FTM_EINVAL;
    if (!*labels && !grow_labels(labels, cap, count))
        return FTM_ENOMEM;
    (*labels)[element] = label;
    return FTM_OK;
}

int ftm_mesh_builder_set_tetrahedron_label(ftm_mesh_builder *b, int32_t tet, int32_t label)
{
    if (!b)
        return FTM_EINVAL;
    return set_label(&b->tet_labels, &b->tet_label_cap, b->tet_count, tet, label);
}

int ftm_mesh_builder_set_hexahedron_label(ftm_mesh_builder *b, int32_t hex, int32_t label)
{
    if (!b)
        return FTM_EINVAL;
    return set_label(&b->hex_labels, &b->hex_label_cap, b->hex_count, hex, label);
}

/* ---- surface of a tetrahedral mesh: faces that belong to one tet only ---- */

typedef struct face_rec {
    int32_t key[3]; /* sorted vertices */
    int32_t v[3];   /* outward-oriented vertices */
} face_rec;

static int cmp_face(const void *pa, const void *pb)
{
    const face_rec *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a->key[i] != b->key[i])
            return a->key[i] < b->key[i] ? -1 : 1;
    /* equal keys: order by oriented vertices so the sort is total (deterministic) */
    for (int i = 0; i < 3; i++)
        if (a->v[i] != b->v[i])
            return a->v[i] < b->v[i] ? -1 : 1;
    return 0;
}

static void sort3(int32_t *k)
{
    int32_t t;
    if (k[0] > k[1]) { t = k[0]; k[0] = k[1]; k[1] = t; }
    if (k[1] > k[2]) { t = k[1]; k[1] = k[2]; k[2] = t; }
    if (k[0] > k[1]) { t = k[0]; k[0] = k[1]; k[1] = t; }
}

static double orient(const ftm_node_def *n, int32_t a, int32_t b, int32_t c, int32_t d)
{
    ftm_vec3 pa = n[a].position, pb = n[b].position, pc = n[c].position, pd = n[d].position;
    double ux = pb.x - pa.x, uy = pb.y - pa.y, uz = pb.z - pa.z;
    double vx = pc.x - pa.x, vy = pc.y - pa.y, vz = pc.z - pa.z;
    double wx = pd.x - pa.x, wy = pd.y - pa.y, wz = pd.z - pa.z;
    return ux * (vy * wz - vz * wy) - uy * (vx * wz - vz * wx) + uz * (vx * wy - vy * wx);
}

static int extract_surface(const ftm_mesh_builder *b, int32_t **tris_out, int32_t *count_out)
{
    size_t nf = (size_t)b->tet_count * 4;
    face_rec *f = malloc((nf ? nf : 1) * sizeof *f);
    if (!f)
        return FTM_ENOMEM;
    static const int fv[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    for (int32_t t = 0; t < b->tet_count; t++) {
        const int32_t *v = b->tets + 4 * t;
        /* with a positive orientation these faces have outward normals */
        bool flip = orient(b->nodes, v[0], v[1], v[2], v[3]) < 0.0;
        for (int k = 0; k < 4; k++) {
            face_rec *r = &f[4 * (size_t)t + (size_t)k];
            r->v[0] = v[fv[k][0]];
            r->v[1] = flip ? v[fv[k][2]] : v[fv[k][1]];
            r->v[2] = flip ? v[fv[k][1]] : v[fv[k][2]];
            memcpy(r->key, r->v, sizeof r->key);
            sort3(r->key);
        }
    }
    qsort(f, nf, sizeof *f, cmp_face);
    int32_t *tris = malloc((nf ? nf : 1) * 3 * sizeof *tris);
    if (!tris) {
        free(f);
        return FTM_ENOMEM;
    }
    int32_t n = 0;
    for (size_t i = 0; i < nf;) {
        size_t j = i + 1;
        while (j < nf && memcmp(f[j].key, f[i].key, sizeof f[i].key) == 0)
            j++;
        if (j - i == 1) {
            memcpy(tris + 3 * (size_t)n, f[i].v, sizeof f[i].v);
            n++;
        }
        i = j;
    }
    free(f);
    *tris_out = tris;
    *count_out = n;
    return FTM_OK;
}

/* ---- Cuthill-McKee order: a BFS from a peripheral node, neighbours by degree,
 * so every breadth-first region is a compact range of indices ---- */

typedef struct csr {
    int32_t *start, *nb;
} csr;

static int build_csr(int32_t n, int32_t nl, const ftm_link_def *links, csr *g)
{
    g->start = calloc((size_t)n + 1, sizeof *g->start);
    g->nb = malloc(((size_t)nl * 2 + 1) * sizeof *g->nb);
    if (!g->start || !g->nb)
        return FTM_ENOMEM;
    for (int32_t l = 0; l < nl; l++) {
        g->start[links[l].a + 1]++;
        g->start[links[l].b + 1]++;
    }
    for (int32_t i = 0; i < n; i++)
        g->start[i + 1] += g->start[i];
    int32_t *fill = malloc(((size_t)n + 1) * sizeof *fill);
    if (!fill)
        return FTM_ENOMEM;
    memcpy(fill, g->start, (size_t)n * sizeof *fill);
    for (int32_t l = 0; l < nl; l++) {
        g->nb[fill[links[l].a]++] = links[l].b;
        g->nb[fill[links[l].b]++] = links[l].a;
    }
    free(fill);
    return FTM_OK;
}

/* BFS from root over unvisited nodes; appends to order; returns last node. */
static int32_t cm_bfs(const csr *g, int32_t root, int32_t *order, int32_t *count, uint8_t *seen,
                      int32_t *tmp)
{
    int32_t head = *count;
    order[(*count)++] = root;
    seen[root] = 1;
    int32_t last = root;
    while (head < *count) {
        int32_t u = order[head++];
        last = u;
        int32_t nt = 0;
        for (int32_t e = g->start[u]; e < g->start[u + 1]; e++)
            if (!seen[g->nb[e]]) {
                seen[g->nb[e]] = 1;
                tmp[nt++] = g->nb[e];
            }
        /* insertion sort by (degree, index): small lists */
        for (int32_t i = 1; i < nt; i++) {
            int32_t v = tmp[i], dv = g->start[v + 1] - g->start[v], j = i - 1;
            while (j >= 0) {
                int32_t w = tmp[j], dw = g->start[w + 1] - g->start[w];
                if (dw < dv || (dw == dv && w < v))
                    break;
                tmp[j + 1] = w;
                j--;
            }
            tmp[j + 1] = v;
        }
        for (int32_t i = 0; i < nt; i++)
            order[(*count)++] = tmp[i];
    }
    return last;
}

static int cuthill_mckee(int32_t n, const csr *g, int32_t *order)
{
    uint8_t *seen = calloc((size_t)n, 1);
    int32_t *tmp = malloc(((size_t)n + 1) * sizeof *tmp);
    if (!seen || !tmp) {
        free(seen);
        free(tmp);
        return FTM_ENOMEM;
    }
    int32_t count = 0;
    for (int32_t s = 0; s < n; s++) {
        if (seen[s])
            continue;
        /* pseudo-peripheral root: the last node of a BFS from s (one sweep) */
        int32_t c0 = count;
        int32_t far = cm_bfs(g, s, order, &count, seen, tmp);
        for (int32_t i = c0; i < count; i++)
            seen[order[i]] = 0;
        count = c0;
        cm_bfs(g, far, order, &count, seen, tmp);
    }
    free(seen);
    free(tmp);
    return FTM_OK;
}

void ftm_mesh_destroy(ftm_mesh *m)
{
    if (!m)
        return;
    free(m->rest);
    free(m->mass);
    free(m->damping);
    free(m->fixed);
    free(m->min_link);
    free(m->fixed_hops);
    free(m->adj_start);
    free(m->adj_node);
    free(m->adj_k);
    free(m->adj_len);
    free(m->pad_node);
    free(m->color);
    free(m->pad_kl);
    free(m->link_a);
    free(m->link_b);
    free(m->link_k);
    free(m->link_len);
    free(m->tris);
    free(m->tets);
    free(m->hexes);
    free(m->tet_labels);
    free(m->hex_labels);
    free(m->bc);
    free(m->bc_n);
    free(m->ground_k);
    free(m->label_names);
    free(m->node_of_input);
    free(m->input_of_node);
    free(m);
}

/* A deep copy; keep in step with ftm_mesh_destroy (every array it frees). */
static void *dup(const void *src, size_t bytes)
{
    void *p = malloc(bytes ? bytes : 1);
    if (p && bytes)
        memcpy(p, src, bytes);
    return p;
}

ftm_mesh *ftm_mesh_clone(const ftm_mesh *m)
{
    ftm_mesh *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    *c = *m;
    size_t n = (size_t)m->node_count, e = (size_t)m->adj_start[m->node_count],
           nl = (size_t)m->link_count, slots = n * (size_t)m->max_degree + 1;
    c->rest = dup(m->rest, n * 3 * sizeof(double));
    c->mass = dup(m->mass, n * sizeof(double));
    c->damping = dup(m->damping, n * sizeof(double));
    c->fixed = dup(m->fixed, n);
    c->min_link = dup(m->min_link, n * sizeof(double));
    c->fixed_hops = dup(m->fixed_hops, n * sizeof(int32_t));
    c->adj_start = dup(m->adj_start, (n + 1) * sizeof(int32_t));
    c->adj_node = dup(m->adj_node, e * sizeof(int32_t));
    c->adj_k = dup(m->adj_k, e * sizeof(double));
    c->adj_len = dup(m->adj_len, e * sizeof(double));
    const bool pad = m->pad_node != NULL;
    c->pad_node = pad ? dup(m->pad_node, slots * sizeof(int32_t)) : NULL;
    c->color = dup(m->color, n);
    c->pad_kl = pad ? dup(m->pad_kl, slots * 2 * sizeof(double)) : NULL;
    c->link_a = dup(m->link_a, nl * sizeof(int32_t));
    c->link_b = dup(m->link_b, nl * sizeof(int32_t));
    c->link_k = dup(m->link_k, nl * sizeof(double));
    c->link_len = dup(m->link_len, nl * sizeof(double));
    c->tris = dup(m->tris, (size_t)m->tri_count * 3 * sizeof(int32_t));
    c->tets = dup(m->tets, (size_t)m->tet_count * 4 * sizeof(int32_t));
    c->hexes = dup(m->hexes, (size_t)m->hex_count * 8 * sizeof(int32_t));
    c->tet_labels = m->tet_labels ? dup(m->tet_labels, (size_t)m->tet_count * sizeof(int32_t)) : NULL;
    c->hex_labels = m->hex_labels ? dup(m->hex_labels, (size_t)m->hex_count * sizeof(int32_t)) : NULL;
    c->bc = m->bc ? dup(m->bc, n) : NULL;
    c->bc_n = m->bc ? dup(m->bc_n, n * 6 * sizeof(double)) : NULL;
    c->ground_k = m->bc ? dup(m->ground_k, n * sizeof(double)) : NULL;
    c->label_names = m->label_names ? dup(m->label_names, (size_t)m->label_name_count *
                                                              sizeof *m->label_names)
                                    : NULL;
    c->node_of_input = dup(m->node_of_input, n * sizeof(int32_t));
    c->input_of_node = dup(m->input_of_node, n * sizeof(int32_t));
    if (!c->rest || !c->mass || !c->damping || !c->fixed || !c->min_link || !c->fixed_hops ||
        !c->adj_start || !c->adj_node || !c->adj_k || !c->adj_len || (pad && !c->pad_node) || !c->color ||
        (pad && !c->pad_kl) || !c->link_a || !c->link_b || !c->link_k || !c->link_len || !c->tris ||
        !c->tets || !c->hexes || !c->node_of_input || !c->input_of_node ||
        (m->tet_labels && !c->tet_labels) || (m->hex_labels && !c->hex_labels) ||
        (m->bc && (!c->bc || !c->bc_n || !c->ground_k)) ||
        (m->label_names && !c->label_names)) {
        ftm_mesh_destroy(c);
        return NULL;
    }
    return c;
}

/* The builder's partial constraints and ground springs in mesh order; a
 * fixed node keeps neither. A normal with a z component takes a planar
 * mesh's planar sweep away (the sweep would not write z). */
static int copy_constraints(const ftm_mesh_builder *b, const int32_t *order, ftm_mesh *m)
{
    const int32_t n = m->node_count;
    bool any = false;
    for (int32_t i = 0; b->bc && i < n && !any; i++) {
        const int32_t in = order[i];
        any = in < b->bc_cap && !b->nodes[in].fixed && (b->bc[in].count || b->bc[in].k > 0.0);
    }
    if (!any)
        return FTM_OK;
    m->bc = calloc((size_t)n, 1);
    m->bc_n = calloc((size_t)n * 6, sizeof *m->bc_n);
    m->ground_k = calloc((size_t)n, sizeof *m->ground_k);
    if (!m->bc || !m->bc_n || !m->ground_k)
        return FTM_ENOMEM;
    for (int32_t i = 0; i < n; i++) {
        const int32_t in = order[i];
        if (in >= b->bc_cap || b->nodes[in].fixed)
            continue;
        const struct builder_bc *c = &b->bc[in];
        m->bc[i] = (uint8_t)(c->count | (c->k > 0.0 ? FTM_BC_SPRING : 0));
        m->ground_k[i] = c->k;
        for (int32_t q = 0; q < c->count; q++) {
            memcpy(m->bc_n + 6 * (size_t)i + 3 * q, c->n[q], 3 * sizeof(double));
            if (c->n[q][2] != 0.0)
                m->planar = false;
        }
    }
    return FTM_OK;
}

typedef struct nb_link {
    int32_t node, link;
} nb_link;

static int cmp_nb(const void *a, const void *b)
{
    int32_t x = ((const nb_link *)a)->node, y = ((const nb_link *)b)->node;
    return (x > y) - (x < y);
}

int ftm_mesh_build(const ftm_mesh_builder *b, const ftm_mesh_build_def *def, ftm_mesh **out,
                   ftm_error *err)
{
    ftm_mesh_build_def d = def ? *def : ftm_default_mesh_build_def();
    if (!b || !out)
        return ftm_error_set(err, FTM_EINVAL, "mesh build: null argument");
    if (b->node_count == 0)
        return ftm_error_set(err, FTM_EINVAL, "mesh build: the mesh has no nodes");
    int32_t n = b->node_count, nl = b->link_count;
    ftm_mesh *m = calloc(1, sizeof *m);
    csr g = {0};
    int32_t *order = NULL, *fill = NULL, *surf = NULL;
    nb_link *row = NULL;
    int rc = FTM_ENOMEM;
    if (!m)
        goto fail;
    m->node_count = n;
    m->link_count = nl;
    m->rest = malloc((size_t)n * 3 * sizeof *m->rest);
    m->mass = malloc((size_t)n * sizeof *m->mass);
    m->damping = malloc((size_t)n * sizeof *m->damping);
    m->fixed = malloc((size_t)n);
    m->min_link = malloc((size_t)n * sizeof *m->min_link);
    m->node_of_input = malloc((size_t)n * sizeof(int32_t));
    m->input_of_node = malloc((size_t)n * sizeof(int32_t));
    m->adj_start = calloc((size_t)n + 1, sizeof(int32_t));
    m->adj_node = malloc(((size_t)nl * 2 + 1) * sizeof(int32_t));
    m->adj_k = malloc(((size_t)nl * 2 + 1) * sizeof(double));
    m->adj_len = malloc(((size_t)nl * 2 + 1) * sizeof(double));
    m->link_a = malloc(((size_t)nl + 1) * sizeof(int32_t));
    m->link_b = malloc(((size_t)nl + 1) * sizeof(int32_t));
    m->link_k = malloc(((size_t)nl + 1) * sizeof(double));
    m->link_len = malloc(((size_t)nl + 1) * sizeof(double));
    order = malloc((size_t)n * sizeof *order);
    fill = malloc(((size_t)n + 1) * sizeof *fill);
    if (!m->rest || !m->mass || !m->damping || !m->fixed || !m->min_link || !m->node_of_input ||
        !m->input_of_node || !m->adj_start || !m->adj_node || !m->adj_k || !m->adj_len ||
        !m->link_a || !m->link_b || !m->link_k || !m->link_len || !order || !fill)
        goto fail;

    if (d.reorder) {
        if (build_csr(n, nl, b->links, &g) != FTM_OK || cuthill_mckee(n, &g, order) != FTM_OK)
            goto fail;
    } else {
        for (int32_t i = 0; i < n; i++)
            order[i] = i;
    }
    for (int32_t i = 0; i < n; i++) {
        m->input_of_node[i] = order[i];
        m->node_of_input[order[i]] = i;
    }
    for (int32_t i = 0; i < n; i++) {
        const ftm_node_def *nd = &b->nodes[order[i]];
        m->rest[3 * i] = nd->position.x;
        m->rest[3 * i + 1] = nd->position.y;
        m->rest[3 * i + 2] = nd->position.z;
        m->mass[i] = nd->mass;
        m->damping[i] = nd->damping;
        m->fixed[i] = nd->fixed ? 1 : 0;
        m->min_link[i] = INFINITY;
    }
    double len_sum = 0.0;
    for (int32_t l = 0; l < nl; l++) {
        int32_t a = m->node_of_input[b->links[l].a], c = m->node_of_input[b->links[l].b];
        m->link_a[l] = a < c ? a : c;
        m->link_b[l] = a < c ? c : a;
        m->link_k[l] = b->links[l].stiffness;
        m->link_len[l] = b->links[l].rest_length;
        len_sum += m->link_len[l];
        m->adj_start[a + 1]++;
        m->adj_start[c + 1]++;
    }
    m->mean_link_length = nl ? len_sum / nl : 1.0;
    m->planar = true;
    for (int32_t i = 0; i < n && m->planar; i++)
        m->planar = ftm_is_plus_zero(m->rest[3 * i + 2]);
    if (copy_constraints(b, order, m) != FTM_OK)
        goto fail;
    for (int32_t i = 0; i < n; i++)
        m->adj_start[i + 1] += m->adj_start[i];
    memcpy(fill, m->adj_start, (size_t)n * sizeof *fill);
    /* neighbour lists sorted by neighbour index (deterministic order) */
    for (int32_t l = 0; l < nl; l++) {
        int32_t a = m->link_a[l], c = m->link_b[l];
        m->adj_node[fill[a]++] = l; /* temporarily the link id */
        m->adj_node[fill[c]++] = l;
    }
    m->max_degree = 0;
    for (int32_t i = 0; i < n; i++)
        if (m->adj_start[i + 1] - m->adj_start[i] > m->max_degree)
            m->max_degree = m->adj_start[i + 1] - m->adj_start[i];
    row = malloc(((size_t)m->max_degree + 1) * sizeof *row);
    if (!row)
        goto fail;
    for (int32_t i = 0; i < n; i++) {
        int32_t s = m->adj_start[i], deg = m->adj_start[i + 1] - s;
        for (int32_t k = 0; k < deg; k++) {
            int32_t l = m->adj_node[s + k];
            row[k].node = m->link_a[l] == i ? m->link_b[l] : m->link_a[l];
            row[k].link = l;
        }
        qsort(row, (size_t)deg, sizeof *row, cmp_nb);
        for (int32_t k = 0; k < deg; k++) {
            int32_t l = row[k].link;
            m->adj_node[s + k] = row[k].node;
            m->adj_k[s + k] = m->link_k[l];
            m->adj_len[s + k] = m->link_len[l];
            if (m->link_len[l] < m->min_link[i])
                m->min_link[i] = m->link_len[l];
        }
    }


    /* Greedy colouring in node order: no two adjacent nodes share a colour
     * below 63 (63 collects the rest). Any layer's nodes of one colour are
     * then an independent set, so the per-step search needs no colouring. */
    m->color = malloc((size_t)n + 1);
    if (!m->color)
        goto fail;
    for (int32_t i = 0; i < n; i++) {
        uint64_t used = 0;
        for (int32_t e = m->adj_start[i]; e < m->adj_start[i + 1]; e++)
            if (m->adj_node[e] < i)
                used |= 1ULL << m->color[m->adj_node[e]];
        m->color[i] = (uint8_t)__builtin_ctzll(~used | 1ULL << 63);
    }

    /* Padded copy for the vectorised integrator: max_degree slots per node.
     * A padding slot is a link to the node itself with k = -0.0, kl = 0,
     * whose force term (-0 - 0/eps) * (x - x) is exactly -0.0, the additive
     * identity, so padded and unpadded sums round the same. */
    size_t slots = (size_t)n * (size_t)m->max_degree + 1;
    const bool pad = ftm_mesh_pad_rows_fit((size_t)n, m->max_degree, (size_t)m->adj_start[n]);
    m->pad_node = pad ? malloc(slots * sizeof *m->pad_node) : NULL;
    m->pad_kl = pad ? malloc(slots * 2 * sizeof *m->pad_kl) : NULL;
    if (pad && (!m->pad_node || !m->pad_kl))
        goto fail;
    for (int32_t i = 0; pad && i < n; i++) {
        int32_t s = m->adj_start[i], deg = m->adj_start[i + 1] - s;
        size_t base = (size_t)i * (size_t)m->max_degree;
        for (int32_t k = 0; k < m->max_degree; k++) {
            m->pad_node[base + k] = k < deg ? m->adj_node[s + k] : i;
            m->pad_kl[2 * (base + k)] = k < deg ? m->adj_k[s + k] : -0.0;
            m->pad_kl[2 * (base + k) + 1] = k < deg ? m->adj_len[s + k] : 0.0;
        }
    }

    /* Hops to the nearest fixed node, by a breadth-first search from all of
     * them: a contact region of depth d holds no fixed node when each source
     * is more than d hops away, and its schedule then skips no node beyond
     * the sources (ftm_sim_rebuild_schedule). */
    m->fixed_hops = malloc(((size_t)n + 1) * sizeof *m->fixed_hops);
    if (!m->fixed_hops)
        goto fail;
    {
        int32_t head = 0, tail = 0; /* order[] is free now: the queue */
        for (int32_t i = 0; i < n; i++) {
            m->fixed_hops[i] = m->fixed[i] ? 0 : INT32_MAX;
            if (m->fixed[i])
                order[tail++] = i;
        }
        while (head < tail) {
            const int32_t u = order[head++];
            for (int32_t e = m->adj_start[u]; e < m->adj_start[u + 1]; e++) {
                const int32_t v = m->adj_node[e];
                if (m->fixed_hops[v] == INT32_MAX) {
                    m->fixed_hops[v] = m->fixed_hops[u] + 1;
                    order[tail++] = v;
                }
            }
        }
    }

    /* surface */
    const int32_t *src_tris = b->tris;
    int32_t tri_count = b->tri_count;
    if (tri_count == 0 && b->tet_count > 0 && d.surface_from_tetrahedra) {
        if (extract_surface(b, &surf, &tri_count) != FTM_OK)
            goto fail;
        src_tris = surf;
    }
    m->tri_count = tri_count;
    m->tris = malloc(((size_t)tri_count * 3 + 1) * sizeof *m->tris);
    m->tet_count = b->tet_count;
    m->tets = malloc(((size_t)b->tet_count * 4 + 1) * sizeof *m->tets);
    m->hex_count = b->hex_count;
    m->hexes = malloc(((size_t)b->hex_count * 8 + 1) * sizeof *m->hexes);
    if (!m->tris || !m->tets || !m->hexes)
        goto fail;
    for (size_t i = 0; i < (size_t)b->hex_count * 8; i++)
        m->hexes[i] = m->node_of_input[b->hexes[i]];
    for (size_t i = 0; i < (size_t)tri_count * 3; i++)
        m->tris[i] = m->node_of_input[src_tris[i]];
    for (size_t i = 0; i < (size_t)b->tet_count * 4; i++)
        m->tets[i] = m->node_of_input[b->tets[i]];
    if (b->tet_labels) {
        m->tet_labels = dup(b->tet_labels, (size_t)b->tet_count * sizeof(int32_t));
        if (!m->tet_labels)
            goto fail;
    }
    if (b->hex_labels) {
        m->hex_labels = dup(b->hex_labels, (size_t)b->hex_count * sizeof(int32_t));
        if (!m->hex_labels)
            goto fail;
    }
    if (b->label_name_count) {
        m->label_names = dup(b->label_names, (size_t)b->label_name_count * sizeof *b->label_names);
        if (!m->label_names)
            goto fail;
        m->label_name_count = b->label_name_count;
    }

    free(row);
    free(surf);
    free(order);
    free(fill);
    free(g.start);
    free(g.nb);
    *out = m;
    ftm_error_clear(err);
    return FTM_OK;
fail:
    free(row);
    free(surf);
    free(order);
    free(fill);
    free(g.start);
    free(g.nb);
    ftm_mesh_destroy(m);
    return ftm_error_set(err, rc, "mesh build: out of memory (%d nodes, %d links)", (int)n,
                         (int)nl);
}

/* ---- accessors ---- */

int32_t ftm_mesh_node_count(const ftm_mesh *m) { return m->node_count; }
int32_t ftm_mesh_link_count(const ftm_mesh *m) { return m->link_count; }
int32_t ftm_mesh_triangle_count(const ftm_mesh *m) { return m->tri_count; }
int32_t ftm_mesh_tetrahedron_count(const ftm_mesh *m) { return m->tet_count; }
int32_t ftm_mesh_hexahedron_count(const ftm_mesh *m) { return m->hex_count; }
const int32_t *ftm_mesh_hexahedra(const ftm_mesh *m) { return m->hexes; }
double ftm_mesh_mean_link_length(const ftm_mesh *m) { return m->mean_link_length; }
int32_t ftm_mesh_max_degree(const ftm_mesh *m) { return m->max_degree; }
const int32_t *ftm_mesh_triangles(const ftm_mesh *m) { return m->tris; }
const int32_t *ftm_mesh_tetrahedra(const ftm_mesh *m) { return m->tets; }
const int32_t *ftm_mesh_tetrahedron_labels(const ftm_mesh *m) { return m->tet_labels; }
const int32_t *ftm_mesh_hexahedron_labels(const ftm_mesh *m) { return m->hex_labels; }

int32_t ftm_mesh_tetrahedron_label(const ftm_mesh *m, int32_t tet)
{
    if (tet < 0 || tet >= m->tet_count)
        return FTM_ERANGE;
    return m->tet_labels ? m->tet_labels[tet] : 0;
}

int32_t ftm_mesh_hexahedron_label(const ftm_mesh *m, int32_t hex)
{
    if (hex < 0 || hex >= m->hex_count)
        return FTM_ERANGE;
    return m->hex_labels ? m->hex_labels[hex] : 0;
}

bool ftm_mesh_has_labels(const ftm_mesh *m)
{
    return m->tet_labels != NULL || m->hex_labels != NULL;
}

int ftm_mesh_builder_set_label_name(ftm_mesh_builder *b, int32_t label, const char *name)
{
    if (!b || label < 1 || !name || !name[0])
        return FTM_EINVAL;
    int32_t i = 0;
    while (i < b->label_name_count && b->label_names[i].label != label)
        i++;
    if (i == b->label_name_count) {
        if (i >= FTM_MESH_MAX_LABEL_NAMES)
            return FTM_ERANGE;
        if (!grow((void **)&b->label_names, &b->label_name_cap, i + 1, sizeof *b->label_names))
            return FTM_ENOMEM;
        b->label_name_count++;
    }
    ftm_label_name *e = &b->label_names[i];
    e->label = label;
    snprintf(e->name, sizeof e->name, "%s", name);
    return FTM_OK;
}

const char *ftm_mesh_label_name(const ftm_mesh *m, int32_t label)
{
    for (int32_t i = 0; i < m->label_name_count; i++)
        if (m->label_names[i].label == label)
            return m->label_names[i].name;
    return NULL;
}

ftm_vec3 ftm_mesh_rest_position(const ftm_mesh *m, int32_t i)
{
    return (ftm_vec3){m->rest[3 * i], m->rest[3 * i + 1], m->rest[3 * i + 2]};
}

double ftm_mesh_mass(const ftm_mesh *m, int32_t i) { return m->mass[i]; }
double ftm_mesh_damping(const ftm_mesh *m, int32_t i) { return m->damping[i]; }
bool ftm_mesh_fixed(const ftm_mesh *m, int32_t i) { return m->fixed[i] != 0; }

int32_t ftm_mesh_slide_normals(const ftm_mesh *m, int32_t i, ftm_vec3 normals[2])
{
    if (i < 0 || i >= m->node_count)
        return FTM_ERANGE;
    const int32_t count = m->bc ? m->bc[i] & FTM_BC_SLIDES : 0;
    for (int32_t q = 0; normals && q < count; q++) {
        const double *nq = m->bc_n + 6 * (size_t)i + 3 * q;
        normals[q] = (ftm_vec3){nq[0], nq[1], nq[2]};
    }
    return count;
}

double ftm_mesh_ground_stiffness(const ftm_mesh *m, int32_t i)
{
    return m->ground_k && i >= 0 && i < m->node_count ? m->ground_k[i] : 0.0;
}

bool ftm_mesh_has_slides(const ftm_mesh *m)
{
    for (int32_t i = 0; m->bc && i < m->node_count; i++)
        if (m->bc[i] & FTM_BC_SLIDES)
            return true;
    return false;
}

bool ftm_mesh_has_ground_springs(const ftm_mesh *m)
{
    for (int32_t i = 0; m->bc && i < m->node_count; i++)
        if (m->bc[i] & FTM_BC_SPRING)
            return true;
    return false;
}

int32_t ftm_mesh_neighbors(const ftm_mesh *m, int32_t i, const int32_t **nb, const double **k,
                           const double **len)
{
    int32_t s = m->adj_start[i];
    if (nb)
        *nb = m->adj_node + s;
    if (k)
        *k = m->adj_k + s;
    if (len)
        *len = m->adj_len + s;
    return m->adj_start[i + 1] - s;
}

void ftm_mesh_link(const ftm_mesh *m, int32_t l, int32_t *a, int32_t *b, double *k, double *len)
{
    if (a) *a = m->link_a[l];
    if (b) *b = m->link_b[l];
    if (k) *k = m->link_k[l];
    if (len) *len = m->link_len[l];
}

int32_t ftm_mesh_node_of_input(const ftm_mesh *m, int32_t input)
{
    if (input < 0 || input >= m->node_count)
        return FTM_ERANGE;
    return m->node_of_input[input];
}

int32_t ftm_mesh_input_of_node(const ftm_mesh *m, int32_t node)
{
    if (node < 0 || node >= m->node_count)
        return FTM_ERANGE;
    return m->input_of_node[node];
}

double ftm_mesh_critical_time_step(const ftm_mesh *m)
{
    double lambda = 0.0;
    for (int32_t i = 0; i < m->node_count; i++) {
        if (m->fixed[i])
            continue;
        double s = 0.0;
        for (int32_t e = m->adj_start[i]; e < m->adj_start[i + 1]; e++) {
            int32_t j = m->adj_node[e];
            s += m->adj_k[e] * (1.0 / m->mass[i] + 1.0 / sqrt(m->mass[i] * m->mass[j]));
        }
        if (m->ground_k) /* a spring to ground: its own row, k_g / m_i */
            s += m->ground_k[i] / m->mass[i];
        if (s > lambda)
            lambda = s;
    }
    return lambda > 0.0 ? 2.0 / sqrt(lambda) : INFINITY;
}

int32_t ftm_mesh_nearest_node(const ftm_mesh *m, ftm_vec3 p)
{
    int32_t best = 0;
    double bd = INFINITY;
    for (int32_t i = 0; i < m->node_count; i++) {
        double dx = m->rest[3 * i] - p.x, dy = m->rest[3 * i + 1] - p.y,
               dz = m->rest[3 * i + 2] - p.z;
        double d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < bd) {
            bd = d2;
            best = i;
        }
    }
    return best;
}
