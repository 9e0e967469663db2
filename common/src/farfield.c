/* The elastic far field: the whole body's compliance at the region's edge
 * (farfield.h says what and why). Three parts: the body's stiffness
 * factorised once (profile LDL^T), Green's columns of loaded nodes, and per
 * step the contact solve that places the ring. */
#include "farfield.h"

#include "error.h"
#include "sim_elem.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

struct ftm_far {
    int32_t n;      /* mesh nodes */
    int32_t ndof;   /* 3 per free node */
    int32_t *dof;   /* node -> its first dof (nodes in reverse order), -1: fixed */
    /* profile LDL^T of K: row r holds columns first[r] .. r at val + rowp[r],
     * L below the diagonal (unit diagonal implied), D on it */
    int32_t *first;
    size_t *rowp;
    double *val;
    bool factored; /* val holds K until the first solve needs the factor */
    uint64_t key;  /* of K's profile and the surface nodes: the cache file's name */
    /* Green's columns: col[c] (NULL until computed) holds for every node j
     * the 3x3 block G_jc row-major (response of j to a unit force at c) */
    float **col;
    int32_t ncols;  /* columns computed */
    /* the current K is kscale times the one factorised */
    double kscale;

    /* the ring of the current region: nodes, their displacement (3 each) */
    int32_t *ring;
    int32_t nring, ring_cap;
    double *u;
    uint32_t *mark; /* mark[i] == gen: i is in the ring */
    uint32_t gen;

    /* contact solve: the displacement contacts' G_dd (3 nd square) as LDL^T */
    bool dd_valid;
    int32_t nd;
    double *dd;
    double *rhs; /* 3 nd */
    size_t dd_cap;
};

/* ---- set-up: the stiffness at rest ---- */

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Calls fn(user, i, j, K_ij) for every coupled pair of free nodes with
 * dof(j) <= dof(i) (the lower profile), K_ij the 3x3 block row-major. For
 * springs the tangent of Eq. 6 at rest; for element forces the assembled
 * element stiffness (the linear one: the tangent of every element model at
 * rest). */
typedef void (*block_fn)(void *user, int32_t i, int32_t j, const double k[9]);

static void spring_block(const ftm_mesh *m, int32_t a, int32_t b, double kab, double len,
                         double out[9])
{
    const double *Xa = m->rest + 3 * a, *Xb = m->rest + 3 * b;
    double r[3] = {Xa[0] - Xb[0], Xa[1] - Xb[1], Xa[2] - Xb[2]};
    double d = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) + FTM_LEN_EPS;
    double q = len / d; /* 1 for a link at its natural length */
    for (int p = 0; p < 3; p++)
        for (int s = 0; s < 3; s++)
            out[3 * p + s] = kab * (q * (r[p] / d) * (r[s] / d) + (p == s ? 1.0 - q : 0.0));
}

static void for_each_block(const ftm_sim *sim, const ftm_far *f, block_fn fn, void *user)
{
    const ftm_mesh *m = sim->m;
    double blk[9];
    if (sim->elem) {
        const int32_t *start, *node;
        const double *k;
        ftm_elem_rows(sim->elem, &start, &node, &k);
        for (int32_t i = 0; i < m->node_count; i++) {
            if (f->dof[i] < 0)
                continue;
            for (int32_t q = start[i]; q < start[i + 1]; q++) {
                int32_t j = node[q];
                if (f->dof[j] >= 0 && f->dof[j] <= f->dof[i])
                    fn(user, i, j, k + 9 * (size_t)q);
            }
        }
        return;
    }
    for (int32_t i = 0; i < m->node_count; i++) {
        if (f->dof[i] < 0)
            continue;
        double diag[9] = {0};
        for (int32_t q = m->adj_start[i]; q < m->adj_start[i + 1]; q++) {
            int32_t j = m->adj_node[q];
            spring_block(m, i, j, m->adj_k[q], m->adj_len[q], blk);
            for (int e = 0; e < 9; e++)
                diag[e] += blk[e];
            if (f->dof[j] >= 0 && f->dof[j] < f->dof[i]) {
                for (int e = 0; e < 9; e++)
                    blk[e] = -blk[e];
                fn(user, i, j, blk);
            }
        }
        fn(user, i, i, diag);
    }
}

static void profile_block(void *user, int32_t i, int32_t j, const double k[9])
{
    (void)k;
    ftm_far *f = user;
    int32_t r0 = f->dof[i], c0 = f->dof[j];
    for (int p = 0; p < 3; p++)
        if (c0 < f->first[r0 + p])
            f->first[r0 + p] = c0;
}

static void add_block(void *user, int32_t i, int32_t j, const double k[9])
{
    ftm_far *f = user;
    int32_t r0 = f->dof[i], c0 = f->dof[j];
    for (int p = 0; p < 3; p++) {
        int32_t r = r0 + p;
        double *row = f->val + f->rowp[r] - f->first[r];
        for (int s = 0; s < 3; s++)
            if (c0 + s <= r)
                row[c0 + s] += k[3 * p + s];
    }
}

/* In-place profile LDL^T (Crout by rows): row r's entries become
 * L[r][c] (c < r) and D[r]. Returns the first row whose pivot is not
 * positive against its diagonal (the body is not held there), or -1. */
static int32_t factorise(ftm_far *f)
{
    for (int32_t r = 0; r < f->ndof; r++) {
        double *row = f->val + f->rowp[r] - f->first[r]; /* row[c] = A[r][c] */
        const int32_t fr = f->first[r];
        /* row[c] <- U[r][c] = L[r][c] D[c] */
        for (int32_t c = fr; c < r; c++) {
            const double *rc = f->val + f->rowp[c] - f->first[c];
            int32_t k0 = fr > f->first[c] ? fr : f->first[c];
            double t = row[c];
            for (int32_t k = k0; k < c; k++)
                t -= row[k] * rc[k];
            row[c] = t;
        }
        double d = row[r], a = row[r];
        for (int32_t c = fr; c < r; c++) {
            const double dc = (f->val + f->rowp[c] - f->first[c])[c];
            double l = row[c] / dc;
            d -= row[c] * l;
            row[c] = l;
        }
        if (!(d > 1e-10 * a))
            return r;
        row[r] = d;
    }
    return -1;
}

static int32_t node_of_dof(const ftm_far *f, int32_t dof)
{
    for (int32_t i = 0; i < f->n; i++)
        if (f->dof[i] >= 0 && f->dof[i] == dof - dof % 3)
            return i;
    return -1;
}

/* Factorises K in place the first time a solve needs it. */
static int ensure_factored(ftm_far *f, const ftm_mesh *m, ftm_log_fn log, void *log_user,
                           ftm_error *err)
{
    if (f->factored)
        return FTM_OK;
    const double t0 = now_s();
    int32_t bad = factorise(f);
    if (bad >= 0) {
        int32_t node = node_of_dof(f, bad);
        return ftm_error_set(err, FTM_EINVAL,
                             "far_field = elastic: the body is not held: its stiffness is "
                             "singular at node %d (input index %d) of %d free nodes (a body or a "
                             "part of it with no fixed node, or a node no link or element holds "
                             "in some direction); fix nodes or use far_field = fixed",
                             (int)node, node >= 0 ? (int)m->input_of_node[node] : -1,
                             (int)(f->ndof / 3));
    }
    f->factored = true;
    const double tf = now_s() - t0;
    if (tf > 1.0)
        ftm_logf(log, log_user, FTM_LOG_INFO,
                 "far field: stiffness of %d free nodes factorised in %.1f s (%zu entries)",
                 (int)(f->ndof / 3), tf, f->rowp[f->ndof]);
    return FTM_OK;
}

/* ---- Green's columns ---- */

/* Solves K X = B for nb right-hand sides in place: b holds ndof rows of nb
 * doubles (dof-major). Forward, diagonal and backward passes in fixed order;
 * the right-hand sides are independent lanes, so the vector builds below
 * give the same bits as the plain one. */
static inline __attribute__((always_inline)) void solve_body(const ftm_far *f, double *b,
                                                             int32_t nb)
{
    const int32_t n = f->ndof;
    for (int32_t r = 0; r < n; r++) {
        const double *row = f->val + f->rowp[r] - f->first[r];
        double *br = b + (size_t)r * nb;
        for (int32_t k = f->first[r]; k < r; k++) {
            const double l = row[k];
            const double *bk = b + (size_t)k * nb;
            for (int32_t q = 0; q < nb; q++)
                br[q] -= l * bk[q];
        }
    }
    for (int32_t r = 0; r < n; r++) {
        const double d = (f->val + f->rowp[r] - f->first[r])[r];
        double *br = b + (size_t)r * nb;
        for (int32_t q = 0; q < nb; q++)
            br[q] /= d;
    }
    for (int32_t r = n - 1; r >= 0; r--) {
        const double *row = f->val + f->rowp[r] - f->first[r];
        const double *br = b + (size_t)r * nb;
        for (int32_t k = f->first[r]; k < r; k++) {
            const double l = row[k];
            double *bk = b + (size_t)k * nb;
            for (int32_t q = 0; q < nb; q++)
                bk[q] -= l * br[q];
        }
    }
}

__attribute__((target("avx512f"))) static void solve_avx512(const ftm_far *f, double *b,
                                                            int32_t nb)
{
    solve_body(f, b, nb);
}

__attribute__((target("avx2"))) static void solve_avx2(const ftm_far *f, double *b, int32_t nb)
{
    solve_body(f, b, nb);
}

static void solve_plain(const ftm_far *f, double *b, int32_t nb) { solve_body(f, b, nb); }

static void solve(const ftm_far *f, double *b, int32_t nb)
{
    if (__builtin_cpu_supports("avx512f"))
        solve_avx512(f, b, nb);
    else if (__builtin_cpu_supports("avx2"))
        solve_avx2(f, b, nb);
    else
        solve_plain(f, b, nb);
}

#define COL_BATCH 8 /* nodes per solve: 24 right-hand sides */

/* Green's columns of nodes[0..count-1] (free, not yet computed). */
static int compute_columns(ftm_far *f, const int32_t *nodes, int32_t count, ftm_log_fn log,
                           void *log_user, bool progress)
{
    const size_t nd = (size_t)f->ndof;
    double *b = malloc(nd * 3 * COL_BATCH * sizeof *b + 1);
    if (!b)
        return FTM_ENOMEM;
    const double t0 = now_s();
    double told = t0;
    bool told_any = false;
    for (int32_t s = 0; s < count; s += COL_BATCH) {
        const int32_t nb = count - s < COL_BATCH ? count - s : COL_BATCH, w = 3 * nb;
        memset(b, 0, nd * (size_t)w * sizeof *b);
        for (int32_t q = 0; q < nb; q++)
            for (int p = 0; p < 3; p++)
                b[(size_t)(f->dof[nodes[s + q]] + p) * (size_t)w + (size_t)(3 * q + p)] = 1.0;
        solve(f, b, w);
        for (int32_t q = 0; q < nb; q++) {
            float *g = malloc((size_t)f->n * 9 * sizeof *g);
            if (!g) {
                free(b);
                return FTM_ENOMEM;
            }
            for (int32_t j = 0; j < f->n; j++) {
                float *gj = g + 9 * (size_t)j;
                if (f->dof[j] < 0) {
                    memset(gj, 0, 9 * sizeof *gj);
                    continue;
                }
                /* G_jc[p][s]: dof p of j under a unit force along s at c */
                for (int p = 0; p < 3; p++)
                    for (int t = 0; t < 3; t++)
                        gj[3 * p + t] = (float)b[(size_t)(f->dof[j] + p) * (size_t)w +
                                                 (size_t)(3 * q + t)];
            }
            f->col[nodes[s + q]] = g;
            f->ncols++;
        }
        const double t = now_s();
        if (progress && t - told > 1.0) {
            ftm_logf(log, log_user, FTM_LOG_INFO,
                     "far field: Green's columns of %d of %d surface nodes (%.1f s)",
                     (int)(s + nb), (int)count, t - t0);
            told = t;
            told_any = true;
        }
    }
    if (told_any)
        ftm_logf(log, log_user, FTM_LOG_INFO, "far field: %d Green's columns in %.1f s",
                 (int)count, now_s() - t0);
    free(b);
    return FTM_OK;
}

void ftm_far_free(ftm_far *f)
{
    if (!f)
        return;
    if (f->col)
        for (int32_t i = 0; i < f->n; i++)
            free(f->col[i]);
    free(f->col);
    free(f->dof);
    free(f->first);
    free(f->rowp);
    free(f->val);
    free(f->ring);
    free(f->u);
    free(f->mark);
    free(f->dd);
    free(f->rhs);
    free(f);
}

/* ---- the cache: the same bits every time, so computed once per machine ----
 * A file per stiffness in $FTM_CACHE_DIR (default $XDG_CACHE_HOME/ftm or
 * ~/.cache/ftm; FTM_CACHE_DIR set empty: none), named by a hash of K's
 * profile and the surface nodes; it holds their Green's columns and a
 * checksum. A file that does not match is ignored and rewritten. */

#define CACHE_MAGIC "FTMFAR01"

static uint64_t mix(uint64_t h, uint64_t v)
{
    h ^= v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ULL;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebULL;
    h ^= h >> 31;
    return h;
}

static uint64_t hash_bytes(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    size_t k = 0;
    for (; k + 8 <= n; k += 8) {
        uint64_t v;
        memcpy(&v, b + k, 8);
        h = mix(h, v);
    }
    uint64_t v = 0;
    memcpy(&v, b + k, n - k);
    return mix(h, v ^ (uint64_t)n);
}

static bool cache_dir(char *out, size_t cap)
{
    const char *d = getenv("FTM_CACHE_DIR");
    int w;
    if (d)
        w = snprintf(out, cap, "%s", d);
    else if ((d = getenv("XDG_CACHE_HOME")) && d[0])
        w = snprintf(out, cap, "%s/ftm", d);
    else if ((d = getenv("HOME")) && d[0])
        w = snprintf(out, cap, "%s/.cache/ftm", d);
    else
        return false;
    return out[0] && w > 0 && (size_t)w < cap;
}

static bool cache_path(const ftm_far *f, char *out, size_t cap)
{
    char dir[1024];
    if (!cache_dir(dir, sizeof dir))
        return false;
    int w = snprintf(out, cap, "%s/far-%016llx.bin", dir, (unsigned long long)f->key);
    return w > 0 && (size_t)w < cap;
}

typedef struct cache_head {
    char magic[8];
    uint32_t revision, n;
    uint64_t key;
    int32_t nsurf, pad;
} cache_head;

static bool cache_load(ftm_far *f, const int32_t *surf, int32_t ns)
{
    char path[1100];
    if (!cache_path(f, path, sizeof path))
        return false;
    FILE *in = fopen(path, "rb");
    if (!in)
        return false;
    cache_head h;
    bool ok = fread(&h, sizeof h, 1, in) == 1 && memcmp(h.magic, CACHE_MAGIC, 8) == 0 &&
              h.revision == FTM_ARITHMETIC_REVISION && h.n == (uint32_t)f->n && h.key == f->key &&
              h.nsurf == ns;
    uint64_t sum = hash_bytes(0, &h, sizeof h);
    int32_t *got = NULL;
    const size_t per = (size_t)f->n * 9;
    if (ok) {
        got = malloc(((size_t)ns + 1) * sizeof *got);
        ok = got && fread(got, sizeof *got, (size_t)ns, in) == (size_t)ns &&
             memcmp(got, surf, (size_t)ns * sizeof *got) == 0;
        if (ok)
            sum = hash_bytes(sum, got, (size_t)ns * sizeof *got);
    }
    for (int32_t s = 0; ok && s < ns; s++) {
        float *g = malloc(per * sizeof *g);
        ok = g && fread(g, sizeof *g, per, in) == per;
        if (ok) {
            sum = hash_bytes(sum, g, per * sizeof *g);
            f->col[surf[s]] = g;
        } else {
            free(g);
        }
    }
    uint64_t want = 0;
    ok = ok && fread(&want, sizeof want, 1, in) == 1 && want == sum && fgetc(in) == EOF;
    fclose(in);
    free(got);
    if (!ok) /* anything else is no cache: drop what was read */
        for (int32_t s = 0; s < ns; s++) {
            free(f->col[surf[s]]);
            f->col[surf[s]] = NULL;
        }
    else
        f->ncols = ns;
    return ok;
}

/* Best effort: written to a temporary file and renamed, so a reader sees a
 * whole file or none; a failure only costs the next run the computation. */
static void cache_save(const ftm_far *f, const int32_t *surf, int32_t ns, ftm_log_fn log,
                       void *log_user)
{
    char dir[1024], path[1100], tmp[1200];
    if (!cache_dir(dir, sizeof dir) || !cache_path(f, path, sizeof path))
        return;
    /* the directory and its parent (~/.cache), private to the user */
    char parent[1024];
    snprintf(parent, sizeof parent, "%s", dir);
    char *slash = strrchr(parent, '/');
    if (slash && slash != parent) {
        *slash = '\0';
        (void)mkdir(parent, 0700);
    }
    if (mkdir(dir, 0700) != 0 && errno != EEXIST)
        return;
    snprintf(tmp, sizeof tmp, "%s.%ld.tmp", path, (long)getpid());
    FILE *out = fopen(tmp, "wb");
    if (!out)
        return;
    cache_head h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, CACHE_MAGIC, 8);
    h.revision = FTM_ARITHMETIC_REVISION;
    h.n = (uint32_t)f->n;
    h.key = f->key;
    h.nsurf = ns;
    bool ok = fwrite(&h, sizeof h, 1, out) == 1;
    uint64_t sum = hash_bytes(0, &h, sizeof h);
    ok = ok && fwrite(surf, sizeof *surf, (size_t)ns, out) == (size_t)ns;
    sum = hash_bytes(sum, surf, (size_t)ns * sizeof *surf);
    const size_t per = (size_t)f->n * 9;
    for (int32_t s = 0; ok && s < ns; s++) {
        ok = fwrite(f->col[surf[s]], sizeof(float), per, out) == per;
        sum = hash_bytes(sum, f->col[surf[s]], per * sizeof(float));
    }
    ok = ok && fwrite(&sum, sizeof sum, 1, out) == 1;
    ok = fclose(out) == 0 && ok;
    if (ok && rename(tmp, path) == 0) {
        ftm_logf(log, log_user, FTM_LOG_INFO, "far field: cached in %s", path);
        return;
    }
    remove(tmp);
}

static int32_t surface_nodes(const ftm_mesh *m, int32_t *out, uint8_t *seen)
{
    int32_t c = 0;
    for (int32_t t = 0; t < 3 * m->tri_count; t++) {
        int32_t v = m->tris[t];
        if (!seen[v] && !m->fixed[v]) {
            seen[v] = 1;
            out[c++] = v;
        }
    }
    return c;
}

/* Factor and columns for the stiffness of sim's current mesh into f. */
static int build(ftm_sim *sim, ftm_far *f, ftm_error *err)
{
    const ftm_mesh *m = sim->m;
    const int32_t n = m->node_count;
    int32_t nfree = 0;
    for (int32_t i = n - 1; i >= 0; i--)
        f->dof[i] = m->fixed[i] ? -1 : 3 * nfree++;
    f->ndof = 3 * nfree;
    if (nfree == 0)
        return ftm_error_set(err, FTM_EINVAL,
                             "far_field = elastic: every node of the mesh is fixed: nothing to "
                             "hold the region");
    f->first = malloc((size_t)f->ndof * sizeof *f->first);
    f->rowp = malloc(((size_t)f->ndof + 1) * sizeof *f->rowp);
    if (!f->first || !f->rowp)
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    for (int32_t r = 0; r < f->ndof; r++)
        f->first[r] = r - r % 3; /* the node's own block */
    for_each_block(sim, f, profile_block, f);
    size_t entries = 0;
    for (int32_t r = 0; r < f->ndof; r++) {
        f->rowp[r] = entries;
        entries += (size_t)(r - f->first[r] + 1);
    }
    f->rowp[f->ndof] = entries;
    /* the surface nodes' columns, a float 3x3 block per node each */
    uint8_t *seen = calloc((size_t)n + 1, 1);
    int32_t *surf = malloc(((size_t)n + 1) * sizeof *surf);
    if (!seen || !surf) {
        free(seen);
        free(surf);
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    }
    int32_t ns = surface_nodes(m, surf, seen);
    free(seen);
    size_t bytes = entries * sizeof(double) + (size_t)ns * (size_t)n * 9 * sizeof(float);
    if (bytes > FTM_FAR_MAX_BYTES) {
        free(surf);
        return ftm_error_set(err, FTM_ENOMEM,
                             "far_field = elastic: the precomputation would take %.0f MiB (a "
                             "profile factor of %zu entries for %d free nodes, and Green's columns "
                             "of %d surface nodes over %d nodes), more than the %.0f MiB allowed: "
                             "use far_field = fixed or a coarser mesh",
                             (double)bytes / 1048576.0, entries, (int)nfree, (int)ns, (int)n,
                             (double)FTM_FAR_MAX_BYTES / 1048576.0);
    }
    f->val = calloc(entries + 1, sizeof *f->val);
    if (!f->val) {
        free(surf);
        return ftm_error_set(err, FTM_ENOMEM,
                             "far_field = elastic: out of memory for a profile factor of %zu "
                             "entries (%.0f MiB)",
                             entries, (double)entries * 8.0 / 1048576.0);
    }
    for_each_block(sim, f, add_block, f);
    /* the cache's key: the stiffness and the nodes whose columns it holds */
    uint64_t key = mix(0x46544d4641520001ULL, (uint64_t)f->ndof);
    key = hash_bytes(key, f->dof, (size_t)n * sizeof *f->dof);
    key = hash_bytes(key, f->first, (size_t)f->ndof * sizeof *f->first);
    key = hash_bytes(key, f->val, entries * sizeof *f->val);
    f->key = hash_bytes(key, surf, (size_t)ns * sizeof *surf);
    int rc = FTM_OK;
    if (!cache_load(f, surf, ns)) {
        rc = ensure_factored(f, m, sim->def.log, sim->def.log_user, err);
        if (!rc && compute_columns(f, surf, ns, sim->def.log, sim->def.log_user, true) != FTM_OK)
            rc = ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory for the "
                                                "Green's columns of %d surface nodes", (int)ns);
        if (!rc)
            cache_save(f, surf, ns, sim->def.log, sim->def.log_user);
    }
    free(surf);
    return rc;
}

int ftm_far_create(ftm_sim *sim, ftm_error *err)
{
    const int32_t n = sim->m->node_count;
    ftm_far *f = calloc(1, sizeof *f);
    if (!f)
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    f->n = n;
    f->kscale = 1.0;
    f->dof = malloc(((size_t)n + 1) * sizeof *f->dof);
    f->col = calloc((size_t)n + 1, sizeof *f->col);
    f->mark = calloc((size_t)n + 1, sizeof *f->mark);
    if (!f->dof || !f->col || !f->mark) {
        ftm_far_free(f);
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    }
    int rc = build(sim, f, err);
    if (rc) {
        ftm_far_free(f);
        return rc;
    }
    sim->far = f;
    return FTM_OK;
}

/* ---- the ring ---- */

int32_t ftm_far_ring_count(const ftm_far *f) { return f ? f->nring : 0; }
const int32_t *ftm_far_ring_nodes(const ftm_far *f) { return f->ring; }
bool ftm_far_in_ring(const ftm_far *f, int32_t node) { return f && f->mark[node] == f->gen; }
void ftm_far_contacts_changed(ftm_far *f)
{
    if (f)
        f->dd_valid = false;
}

static int ring_push(ftm_far *f, int32_t i)
{
    if (f->nring == f->ring_cap) {
        int32_t cap = f->ring_cap ? 2 * f->ring_cap : 256;
        int32_t *r = realloc(f->ring, (size_t)cap * sizeof *r);
        if (!r)
            return FTM_ENOMEM;
        f->ring = r;
        double *u = realloc(f->u, (size_t)cap * 3 * sizeof *u);
        if (!u)
            return FTM_ENOMEM;
        f->u = u;
        f->ring_cap = cap;
    }
    f->ring[f->nring++] = i;
    f->mark[i] = f->gen;
    return FTM_OK;
}

static void next_gen(ftm_far *f)
{
    if (++f->gen == 0) { /* wrapped: clear the stamps once */
        memset(f->mark, 0, (size_t)f->n * sizeof *f->mark);
        f->gen = 1;
    }
}

/* Neighbours of i through the forces: the element rows, or the links. */
static void neighbours(const ftm_sim *sim, int32_t i, const int32_t **nb, int32_t *count)
{
    if (sim->elem) {
        const int32_t *start, *node;
        const double *k;
        ftm_elem_rows(sim->elem, &start, &node, &k);
        *nb = node + start[i];
        *count = start[i + 1] - start[i];
    } else {
        *nb = sim->m->adj_node + sim->m->adj_start[i];
        *count = sim->m->adj_start[i + 1] - sim->m->adj_start[i];
    }
}

int32_t ftm_far_rebuild_ring(ftm_sim *sim, int32_t *cand)
{
    ftm_far *f = sim->far;
    const ftm_layering *ly = &sim->ly;
    /* the old ring, to hand back what leaves it */
    int32_t old = f->nring;
    int32_t *olds = NULL;
    if (old > 0) {
        olds = malloc((size_t)old * sizeof *olds);
        if (!olds)
            return FTM_ENOMEM;
        memcpy(olds, f->ring, (size_t)old * sizeof *olds);
    }
    next_gen(f);
    f->nring = 0;
    int rc = FTM_OK;
    const int32_t region = ly->gen ? ly->count : 0;
    /* every free node outside the region that a region node's forces read */
    for (int32_t k = 0; k < region && !rc; k++) {
        const int32_t *nb;
        int32_t deg;
        neighbours(sim, ly->order[k], &nb, &deg);
        for (int32_t q = 0; q < deg && !rc; q++) {
            int32_t j = nb[q];
            if (!sim->m->fixed[j] && f->mark[j] != f->gen && !ftm_layering_contains(ly, j))
                rc = ring_push(f, j);
        }
    }
    if (rc) {
        free(olds);
        return rc;
    }
    /* ascending: a fixed order for the solve and the hash's neighbours */
    for (int32_t a = 1; a < f->nring; a++) { /* insertion: mostly ordered already */
        int32_t v = f->ring[a], b = a;
        while (b > 0 && f->ring[b - 1] > v) {
            f->ring[b] = f->ring[b - 1];
            b--;
        }
        f->ring[b] = v;
    }
    int32_t added = 0;
    for (int32_t k = 0; k < old; k++) {
        int32_t i = olds[k];
        if (f->mark[i] != f->gen && !ftm_layering_contains(ly, i))
            cand[added++] = i;
    }
    free(olds);
    f->dd_valid = false;
    return added;
}

/* ---- per step ---- */

static int ensure_column(ftm_sim *sim, int32_t node)
{
    ftm_far *f = sim->far;
    if (f->col[node])
        return FTM_OK;
    /* (a held body: the cache's file was made from a factor that exists) */
    int rc = ensure_factored(f, sim->m, sim->def.log, sim->def.log_user, NULL);
    if (rc)
        return rc;
    return compute_columns(f, &node, 1, sim->def.log, sim->def.log_user, false);
}

/* Block G_{a b} (3x3, row-major, doubles) of the columns. */
static void gblock(const ftm_far *f, int32_t a, int32_t b, double out[9])
{
    const float *g = f->col[b] + 9 * (size_t)a;
    for (int e = 0; e < 9; e++)
        out[e] = (double)g[e];
}

/* G_dd of the displacement contacts, symmetrised, factorised LDL^T. */
static int factor_dd(ftm_sim *sim)
{
    ftm_far *f = sim->far;
    const int32_t nd = sim->ndisp, w = 3 * nd;
    size_t need = (size_t)w * (size_t)w;
    if (need > f->dd_cap) {
        double *d = realloc(f->dd, (need + 1) * sizeof *d);
        double *r = realloc(f->rhs, ((size_t)w + 1) * sizeof *r);
        if (!d || !r) {
            if (d)
                f->dd = d;
            if (r)
                f->rhs = r;
            return FTM_ENOMEM;
        }
        f->dd = d;
        f->rhs = r;
        f->dd_cap = need;
    }
    double blk[9], blt[9];
    for (int32_t a = 0; a < nd; a++)
        for (int32_t b = 0; b < nd; b++) {
            gblock(f, sim->disp[a], sim->disp[b], blk);
            gblock(f, sim->disp[b], sim->disp[a], blt);
            for (int p = 0; p < 3; p++)
                for (int s = 0; s < 3; s++)
                    f->dd[(size_t)(3 * a + p) * (size_t)w + (size_t)(3 * b + s)] =
                        0.5 * (blk[3 * p + s] + blt[3 * s + p]);
        }
    /* dense LDL^T in place (SPD: a principal block of K^-1) */
    double *A = f->dd;
    for (int32_t r = 0; r < w; r++) {
        double *row = A + (size_t)r * (size_t)w;
        for (int32_t c = 0; c < r; c++) {
            const double *rc = A + (size_t)c * (size_t)w;
            double t = row[c];
            for (int32_t k = 0; k < c; k++)
                t -= row[k] * rc[k];
            row[c] = t;
        }
        double d = row[r];
        for (int32_t c = 0; c < r; c++) {
            double l = row[c] / A[(size_t)c * (size_t)w + (size_t)c];
            d -= row[c] * l;
            row[c] = l;
        }
        row[r] = d > 0.0 ? d : 1.0; /* (cannot happen for distinct free nodes) */
    }
    f->nd = nd;
    f->dd_valid = true;
    return FTM_OK;
}

static void solve_dd(const ftm_far *f, double *x)
{
    const int32_t w = 3 * f->nd;
    const double *A = f->dd;
    for (int32_t r = 0; r < w; r++)
        for (int32_t k = 0; k < r; k++)
            x[r] -= A[(size_t)r * (size_t)w + (size_t)k] * x[k];
    for (int32_t r = 0; r < w; r++)
        x[r] /= A[(size_t)r * (size_t)w + (size_t)r];
    for (int32_t r = w - 1; r >= 0; r--)
        for (int32_t k = 0; k < r; k++)
            x[k] -= A[(size_t)r * (size_t)w + (size_t)k] * x[r];
}

int ftm_far_prepare(ftm_sim *sim)
{
    ftm_far *f = sim->far;
    if (f->nring == 0)
        return FTM_OK;
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        int rc = ensure_column(sim, sim->contacts[c].node);
        if (rc)
            return rc;
    }
    if (!f->dd_valid) {
        int rc = factor_dd(sim);
        if (rc)
            return rc;
    }
    /* forces on the contacts in the factorised stiffness's units: F / kscale */
    const double inv = 1.0 / f->kscale;
    double blk[9];
    /* rhs = delta_d - G_df F', then y = G_dd^-1 rhs (the displacement
     * contacts' forces in those units) */
    for (int32_t a = 0, r = 0; a < sim->ncontacts; a++) {
        const ftm_contact *ca = &sim->contacts[a];
        if (ca->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        double *x = f->rhs + 3 * r++;
        x[0] = ca->value.x;
        x[1] = ca->value.y;
        x[2] = ca->value.z;
        for (int32_t b = 0; b < sim->ncontacts; b++) {
            const ftm_contact *cb = &sim->contacts[b];
            if (cb->kind != FTM_CONTACT_FORCE)
                continue;
            gblock(f, ca->node, cb->node, blk);
            double F[3] = {cb->value.x * inv, cb->value.y * inv, cb->value.z * inv};
            for (int p = 0; p < 3; p++)
                x[p] -= blk[3 * p] * F[0] + blk[3 * p + 1] * F[1] + blk[3 * p + 2] * F[2];
        }
    }
    if (f->nd > 0)
        solve_dd(f, f->rhs);
    for (int32_t k = 0; k < f->nring; k++) {
        const int32_t j = f->ring[k];
        double u[3] = {0.0, 0.0, 0.0};
        for (int32_t c = 0, r = 0; c < sim->ncontacts; c++) {
            const ftm_contact *ct = &sim->contacts[c];
            double F[3];
            if (ct->kind == FTM_CONTACT_DISPLACEMENT) {
                memcpy(F, f->rhs + 3 * r++, sizeof F);
            } else {
                F[0] = ct->value.x * inv;
                F[1] = ct->value.y * inv;
                F[2] = ct->value.z * inv;
            }
            const float *g = f->col[ct->node] + 9 * (size_t)j;
            for (int p = 0; p < 3; p++)
                u[p] += (double)g[3 * p] * F[0] + (double)g[3 * p + 1] * F[1] +
                        (double)g[3 * p + 2] * F[2];
        }
        memcpy(f->u + 3 * k, u, sizeof u);
    }
    return FTM_OK;
}

void ftm_far_impose(ftm_sim *sim)
{
    const ftm_far *f = sim->far;
    const double *rest = sim->m->rest;
    for (int32_t k = 0; k < f->nring; k++) {
        const int32_t i = f->ring[k];
        double *x = sim->x + 3 * i, *xp = sim->xp + 3 * i;
        for (int d = 0; d < 3; d++) {
            xp[d] = x[d];
            x[d] = rest[3 * i + d] + f->u[3 * k + d];
        }
    }
}

int ftm_far_set_mesh(ftm_sim *sim, const ftm_mesh *m, ftm_error *err)
{
    ftm_far *f = sim->far;
    const ftm_mesh *old = sim->m;
    /* one factor on every link: the columns scale by its inverse */
    double ratio = 0.0;
    bool uniform = !sim->elem && m->link_count == old->link_count;
    for (int32_t l = 0; uniform && l < m->link_count; l++) {
        double q = m->link_k[l] / old->link_k[l];
        if (l == 0)
            ratio = q;
        else if (q != ratio)
            uniform = false;
    }
    if (uniform && ratio > 0.0 && isfinite(ratio)) {
        f->kscale *= ratio;
        return FTM_OK;
    }
    /* otherwise everything again, for the new stiffness */
    ftm_far *nf = calloc(1, sizeof *nf);
    if (!nf)
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    nf->n = f->n;
    nf->kscale = 1.0;
    nf->dof = malloc(((size_t)f->n + 1) * sizeof *nf->dof);
    nf->col = calloc((size_t)f->n + 1, sizeof *nf->col);
    if (!nf->dof || !nf->col) {
        ftm_far_free(nf);
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    }
    const ftm_mesh *keep = sim->m;
    sim->m = m;
    int rc = build(sim, nf, err);
    sim->m = keep;
    if (rc) {
        ftm_far_free(nf);
        return rc;
    }
    /* swap the stiffness-dependent parts, keep the ring */
    for (int32_t i = 0; i < f->n; i++)
        free(f->col[i]);
    free(f->col);
    free(f->dof);
    free(f->first);
    free(f->rowp);
    free(f->val);
    f->col = nf->col;
    f->dof = nf->dof;
    f->first = nf->first;
    f->rowp = nf->rowp;
    f->val = nf->val;
    f->ndof = nf->ndof;
    f->ncols = nf->ncols;
    f->factored = nf->factored;
    f->key = nf->key;
    f->kscale = 1.0;
    f->dd_valid = false;
    nf->col = NULL;
    nf->dof = NULL;
    nf->first = NULL;
    nf->rowp = NULL;
    nf->val = NULL;
    ftm_far_free(nf);
    return FTM_OK;
}
