/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The compliance of a held body (compliance.h says what and why): its
 * stiffness at rest assembled and factorised (profile LDL^T), Green's
 * columns solved for, shared within the process and cached on disk. */
#include "compliance.h"

#include "error.h"
#include "sim_elem.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

struct ftm_compliance {
    int32_t n;      /* mesh nodes */
    int32_t ndof;   /* 3 per free node */
    int32_t *dof;   /* node -> its first dof (nodes in reverse order), -1: fixed */
    /* profile LDL^T of K: row r holds columns first[r] .. r at val + rowp[r],
     * L below the diagonal (unit diagonal implied), D on it */
    int32_t *first;
    size_t *rowp;
    double *val;
    bool factored; /* val holds K until the first solve needs the factor */
    uint64_t key;  /* of K's profile and the surface nodes */
    /* Green's columns: col[c] (NULL until computed) holds for every node j
     * the 3x3 block G_jc row-major (response of j to a unit force at c) */
    float **col;
    uint8_t *own; /* own[c]: col[c] was allocated here (not in the mapped file) */
    /* slot[c] > 0: col[c] is the mapped file's column slot[c] - 1, whose
     * checksum colsum[slot[c] - 1] is checked at its first use; then 0 */
    int32_t *slot;
    const uint64_t *colsum;
    void *map;     /* the cache file mapped (columns of the surface nodes point into it) */
    size_t map_len;
    int32_t refs;  /* simulations using it; kept a while at 0 (registry) */
    struct ftm_compliance *next;
};

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- the stiffness at rest ---- */

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

/* Node i's constraints as a block of K (docs/scene-format.md): k_g I for
 * its springs to ground, and for each normal n it may not move along a
 * penalty a n n^T, a = FTM_SLIDE_PENALTY times the largest diagonal entry of
 * its block `diag` (the body's own stiffness there): its motion along n is
 * then about 1e-8 of what it would be free, and the far field places it on
 * its plane exactly (ftm_far_impose). False: node i has none. */
#define FTM_SLIDE_PENALTY 1e8
static bool constraint_block(const ftm_mesh *m, int32_t i, const double diag[9], double out[9])
{
    if (!m->bc || !m->bc[i])
        return false;
    double dmax = diag[0] > diag[4] ? diag[0] : diag[4];
    dmax = dmax > diag[8] ? dmax : diag[8];
    const double a = FTM_SLIDE_PENALTY * (dmax > 0.0 ? dmax : 1.0);
    for (int e = 0; e < 9; e++)
        out[e] = e % 4 == 0 ? m->ground_k[i] : 0.0;
    for (int q = 0; q < (m->bc[i] & FTM_BC_SLIDES); q++) {
        const double *n = m->bc_n + 6 * (size_t)i + 3 * q;
        for (int p = 0; p < 3; p++)
            for (int t = 0; t < 3; t++)
                out[3 * p + t] += a * n[p] * n[t];
    }
    return true;
}

static void for_each_block(const ftm_sim *sim, const ftm_mesh *m, const ftm_compliance *g,
                           block_fn fn, void *user)
{
    double blk[9];
    if (sim->elem) {
        const int32_t *start, *node;
        const double *k;
        ftm_elem_rows(sim->elem, &start, &node, &k);
        for (int32_t i = 0; i < m->node_count; i++) {
            if (g->dof[i] < 0)
                continue;
            for (int32_t q = start[i]; q < start[i + 1]; q++) {
                int32_t j = node[q];
                if (g->dof[j] >= 0 && g->dof[j] <= g->dof[i])
                    fn(user, i, j, k + 9 * (size_t)q);
                if (j == i && constraint_block(m, i, k + 9 * (size_t)q, blk))
                    fn(user, i, i, blk);
            }
        }
        return;
    }
    for (int32_t i = 0; i < m->node_count; i++) {
        if (g->dof[i] < 0)
            continue;
        double diag[9] = {0};
        for (int32_t q = m->adj_start[i]; q < m->adj_start[i + 1]; q++) {
            int32_t j = m->adj_node[q];
            spring_block(m, i, j, m->adj_k[q], m->adj_len[q], blk);
            for (int e = 0; e < 9; e++)
                diag[e] += blk[e];
            if (g->dof[j] >= 0 && g->dof[j] < g->dof[i]) {
                for (int e = 0; e < 9; e++)
                    blk[e] = -blk[e];
                fn(user, i, j, blk);
            }
        }
        fn(user, i, i, diag);
        if (constraint_block(m, i, diag, blk))
            fn(user, i, i, blk);
    }
}

static void profile_block(void *user, int32_t i, int32_t j, const double k[9])
{
    (void)k;
    ftm_compliance *g = user;
    int32_t r0 = g->dof[i], c0 = g->dof[j];
    for (int p = 0; p < 3; p++)
        if (c0 < g->first[r0 + p])
            g->first[r0 + p] = c0;
}

static void add_block(void *user, int32_t i, int32_t j, const double k[9])
{
    ftm_compliance *g = user;
    int32_t r0 = g->dof[i], c0 = g->dof[j];
    for (int p = 0; p < 3; p++) {
        int32_t r = r0 + p;
        double *row = g->val + g->rowp[r] - g->first[r];
        for (int s = 0; s < 3; s++)
            if (c0 + s <= r)
                row[c0 + s] += k[3 * p + s];
    }
}

/* In-place profile LDL^T (Crout by rows): row r's entries become
 * L[r][c] (c < r) and D[r]. Returns the first row whose pivot is not
 * positive against its diagonal (the body is not held there), or -1. */
static int32_t factorise(ftm_compliance *g)
{
    for (int32_t r = 0; r < g->ndof; r++) {
        double *row = g->val + g->rowp[r] - g->first[r]; /* row[c] = A[r][c] */
        const int32_t fr = g->first[r];
        /* row[c] <- U[r][c] = L[r][c] D[c] */
        for (int32_t c = fr; c < r; c++) {
            const double *rc = g->val + g->rowp[c] - g->first[c];
            int32_t k0 = fr > g->first[c] ? fr : g->first[c];
            double t = row[c];
            for (int32_t k = k0; k < c; k++)
                t -= row[k] * rc[k];
            row[c] = t;
        }
        double d = row[r], a = row[r];
        for (int32_t c = fr; c < r; c++) {
            const double dc = (g->val + g->rowp[c] - g->first[c])[c];
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

static int32_t node_of_dof(const ftm_compliance *g, int32_t dof)
{
    for (int32_t i = 0; i < g->n; i++)
        if (g->dof[i] >= 0 && g->dof[i] == dof - dof % 3)
            return i;
    return -1;
}

/* Factorises K in place the first time a solve needs it. */
static int ensure_factored(ftm_compliance *g, const ftm_mesh *m, ftm_log_fn log, void *log_user,
                           ftm_error *err)
{
    if (g->factored)
        return FTM_OK;
    const double t0 = now_s();
    int32_t bad = factorise(g);
    if (bad >= 0) {
        int32_t node = node_of_dof(g, bad);
        return ftm_error_set(err, FTM_EINVAL,
                             "far_field = elastic: the body is not held: its stiffness is "
                             "singular at node %d (input index %d) of %d free nodes (a body or a "
                             "part of it with no fixed node, or a node no link or element holds "
                             "in some direction); fix nodes or use far_field = fixed",
                             (int)node, node >= 0 && m ? (int)m->input_of_node[node] : -1,
                             (int)(g->ndof / 3));
    }
    g->factored = true;
    const double tf = now_s() - t0;
    if (tf > 1.0)
        ftm_logf(log, log_user, FTM_LOG_INFO,
                 "far field: stiffness of %d free nodes factorised in %.1f s (%zu entries)",
                 (int)(g->ndof / 3), tf, g->rowp[g->ndof]);
    return FTM_OK;
}

/* ---- Green's columns ---- */

/* Solves K X = B for nb right-hand sides in place: b holds ndof rows of nb
 * doubles (dof-major). Forward, diagonal and backward passes in fixed order;
 * the right-hand sides are independent lanes, so the vector builds below
 * give the same bits as the plain one. */
static inline __attribute__((always_inline)) void solve_body(const ftm_compliance *g, double *b,
                                                             int32_t nb)
{
    const int32_t n = g->ndof;
    for (int32_t r = 0; r < n; r++) {
        const double *row = g->val + g->rowp[r] - g->first[r];
        double *br = b + (size_t)r * nb;
        for (int32_t k = g->first[r]; k < r; k++) {
            const double l = row[k];
            const double *bk = b + (size_t)k * nb;
            for (int32_t q = 0; q < nb; q++)
                br[q] -= l * bk[q];
        }
    }
    for (int32_t r = 0; r < n; r++) {
        const double d = (g->val + g->rowp[r] - g->first[r])[r];
        double *br = b + (size_t)r * nb;
        for (int32_t q = 0; q < nb; q++)
            br[q] /= d;
    }
    for (int32_t r = n - 1; r >= 0; r--) {
        const double *row = g->val + g->rowp[r] - g->first[r];
        const double *br = b + (size_t)r * nb;
        for (int32_t k = g->first[r]; k < r; k++) {
            const double l = row[k];
            double *bk = b + (size_t)k * nb;
            for (int32_t q = 0; q < nb; q++)
                bk[q] -= l * br[q];
        }
    }
}

__attribute__((target("avx512f"))) static void solve_avx512(const ftm_compliance *g, double *b,
                                                            int32_t nb)
{
    solve_body(g, b, nb);
}

__attribute__((target("avx2"))) static void solve_avx2(const ftm_compliance *g, double *b, int32_t nb)
{
    solve_body(g, b, nb);
}

static void solve_plain(const ftm_compliance *g, double *b, int32_t nb) { solve_body(g, b, nb); }

/* the widest kernel allowed (tests compare them): 2 AVX-512, 1 AVX2, 0 plain */
static _Atomic int kernel_limit = 2;

void ftm_compliance_limit_kernel(int widest) { kernel_limit = widest; }

static void solve(const ftm_compliance *g, double *b, int32_t nb)
{
    const int limit = kernel_limit;
    if (limit >= 2 && __builtin_cpu_supports("avx512f"))
        solve_avx512(g, b, nb);
    else if (limit >= 1 && __builtin_cpu_supports("avx2"))
        solve_avx2(g, b, nb);
    else
        solve_plain(g, b, nb);
}

#define COL_BATCH 8 /* nodes per solve: 24 right-hand sides */

/* Green's columns of nodes[0..count-1] (free, not yet computed). */
static int compute_columns(ftm_compliance *g, const int32_t *nodes, int32_t count, ftm_log_fn log,
                           void *log_user, bool progress)
{
    const size_t nd = (size_t)g->ndof;
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
                b[(size_t)(g->dof[nodes[s + q]] + p) * (size_t)w + (size_t)(3 * q + p)] = 1.0;
        solve(g, b, w);
        for (int32_t q = 0; q < nb; q++) {
            float *col = malloc((size_t)g->n * 9 * sizeof *col);
            if (!col) {
                free(b);
                return FTM_ENOMEM;
            }
            for (int32_t j = 0; j < g->n; j++) {
                float *gj = col + 9 * (size_t)j;
                if (g->dof[j] < 0) {
                    memset(gj, 0, 9 * sizeof *gj);
                    continue;
                }
                /* G_jc[p][s]: dof p of j under a unit force along s at c */
                for (int p = 0; p < 3; p++)
                    for (int t = 0; t < 3; t++)
                        gj[3 * p + t] = (float)b[(size_t)(g->dof[j] + p) * (size_t)w +
                                                 (size_t)(3 * q + t)];
            }
            g->col[nodes[s + q]] = col;
            g->own[nodes[s + q]] = 1;
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

/* ---- the cache: the same bits every time, so computed once per machine ----
 * A file per stiffness in $FTM_CACHE_DIR (default $XDG_CACHE_HOME/ftm or
 * ~/.cache/ftm; FTM_CACHE_DIR set empty: none), named by a hash of K's
 * profile and the surface nodes; it holds their Green's columns and a
 * checksum. A file that does not match is ignored and rewritten. */

#define CACHE_MAGIC "FTMFAR03"

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

/* A streaming 64-bit hash of bytes: four independent lanes over 32-byte
 * chunks (fast: it reads tens of megabytes at every start), mixed at the
 * end. For a file's integrity and a cache key, not against an adversary. */
typedef struct hasher {
    uint64_t lane[4];
    unsigned char buf[32];
    size_t fill;
    uint64_t total;
} hasher;

static void hasher_init(hasher *h, uint64_t seed)
{
    memset(h, 0, sizeof *h);
    for (int k = 0; k < 4; k++)
        h->lane[k] = mix(seed, (uint64_t)k);
}

static inline void hasher_chunk(uint64_t lane[4], const unsigned char *p)
{
    for (int k = 0; k < 4; k++) {
        uint64_t v;
        memcpy(&v, p + 8 * k, 8);
        uint64_t x = (lane[k] ^ v) * 0x9fb21c651e98df25ULL;
        lane[k] = (x << 29) | (x >> 35);
    }
}

static void hasher_update(hasher *h, const void *data, size_t n)
{
    const unsigned char *p = data;
    h->total += n;
    if (h->fill) {
        size_t take = 32 - h->fill < n ? 32 - h->fill : n;
        memcpy(h->buf + h->fill, p, take);
        h->fill += take;
        p += take;
        n -= take;
        if (h->fill < 32)
            return;
        hasher_chunk(h->lane, h->buf);
        h->fill = 0;
    }
    for (; n >= 32; p += 32, n -= 32)
        hasher_chunk(h->lane, p);
    memcpy(h->buf, p, n);
    h->fill = n;
}

static uint64_t hasher_final(const hasher *h)
{
    unsigned char tail[32] = {0};
    memcpy(tail, h->buf, h->fill);
    uint64_t lane[4] = {h->lane[0], h->lane[1], h->lane[2], h->lane[3]};
    hasher_chunk(lane, tail);
    uint64_t r = mix(h->total, lane[0]);
    for (int k = 1; k < 4; k++)
        r = mix(r, lane[k]);
    return r;
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

static bool cache_path(const ftm_compliance *g, char *out, size_t cap)
{
    char dir[1024];
    if (!cache_dir(dir, sizeof dir))
        return false;
    int w = snprintf(out, cap, "%s/far-%016llx.bin", dir, (unsigned long long)g->key);
    return w > 0 && (size_t)w < cap;
}

typedef struct cache_head {
    char magic[8];
    uint32_t revision, n;
    uint64_t key;
    int32_t nsurf, pad;
} cache_head;

/* The file: the head, the surface nodes (int32, padded to 8 bytes), a
 * checksum per column, a checksum of all that, then the columns (float,
 * n x 9 each). Mapped, not read: the columns are used in place, the
 * processes of a machine share the pages, and a column's checksum is
 * checked when it is first used (ftm_compliance_ensure), so that opening
 * costs nothing however large the body. */
static size_t cache_index_size(int32_t ns)
{
    size_t surf = ((size_t)ns * sizeof(int32_t) + 7) & ~(size_t)7;
    return sizeof(cache_head) + surf + (size_t)ns * sizeof(uint64_t) + sizeof(uint64_t);
}

static size_t cache_size(int32_t n, int32_t ns)
{
    return cache_index_size(ns) + (size_t)ns * (size_t)n * 9 * sizeof(float);
}

static uint64_t column_sum(const float *col, int32_t n)
{
    hasher hs;
    hasher_init(&hs, 0x434f4c);
    hasher_update(&hs, col, (size_t)n * 9 * sizeof *col);
    return hasher_final(&hs);
}

static bool cache_load(ftm_compliance *g, const int32_t *surf, int32_t ns)
{
    char path[1100];
    if (!cache_path(g, path, sizeof path))
        return false;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return false;
    const size_t want = cache_size(g->n, ns), index = cache_index_size(ns);
    struct stat st;
    void *map = MAP_FAILED;
    if (fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && (uint64_t)st.st_size == (uint64_t)want)
        map = mmap(NULL, want, PROT_READ, MAP_PRIVATE, fd, 0);
    close(fd);
    if (map == MAP_FAILED)
        return false;
    const unsigned char *b = map;
    cache_head h;
    memcpy(&h, b, sizeof h);
    bool ok = memcmp(h.magic, CACHE_MAGIC, 8) == 0 && h.revision == FTM_ARITHMETIC_REVISION &&
              h.n == (uint32_t)g->n && h.key == g->key && h.nsurf == ns &&
              memcmp(b + sizeof h, surf, (size_t)ns * sizeof *surf) == 0;
    if (ok) {
        hasher hs;
        hasher_init(&hs, 0);
        hasher_update(&hs, b, index - sizeof(uint64_t));
        uint64_t sum;
        memcpy(&sum, b + index - sizeof sum, sizeof sum);
        ok = sum == hasher_final(&hs);
    }
    if (!ok) { /* anything else is no cache */
        munmap(map, want);
        return false;
    }
    const float *cols = (const float *)(b + index);
    g->colsum = (const uint64_t *)(b + index - sizeof(uint64_t) - (size_t)ns * sizeof(uint64_t));
    for (int32_t k = 0; k < ns; k++) {
        g->col[surf[k]] = (float *)(cols + (size_t)k * (size_t)g->n * 9);
        g->slot[surf[k]] = k + 1; /* mapped, its checksum not yet checked */
    }
    g->map = map;
    g->map_len = want;
    return true;
}

/* Best effort: written to a temporary file and renamed, so a reader sees a
 * whole file or none; a failure only costs the next run the computation. */
static void cache_save(const ftm_compliance *g, const int32_t *surf, int32_t ns, ftm_log_fn log,
                       void *log_user)
{
    char dir[1024], path[1100], tmp[1200];
    if (!cache_dir(dir, sizeof dir) || !cache_path(g, path, sizeof path))
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
    h.n = (uint32_t)g->n;
    h.key = g->key;
    h.nsurf = ns;
    const size_t index = cache_index_size(ns);
    unsigned char *head = calloc(index, 1);
    if (!head) {
        fclose(out);
        remove(tmp);
        return;
    }
    memcpy(head, &h, sizeof h);
    memcpy(head + sizeof h, surf, (size_t)ns * sizeof *surf);
    unsigned char *sums = head + index - sizeof(uint64_t) - (size_t)ns * sizeof(uint64_t);
    for (int32_t k = 0; k < ns; k++) {
        uint64_t cs = column_sum(g->col[surf[k]], g->n);
        memcpy(sums + (size_t)k * sizeof cs, &cs, sizeof cs);
    }
    hasher hs;
    hasher_init(&hs, 0);
    hasher_update(&hs, head, index - sizeof(uint64_t));
    uint64_t sum = hasher_final(&hs);
    memcpy(head + index - sizeof sum, &sum, sizeof sum);
    bool ok = fwrite(head, 1, index, out) == index;
    free(head);
    const size_t per = (size_t)g->n * 9;
    for (int32_t k = 0; ok && k < ns; k++)
        ok = fwrite(g->col[surf[k]], sizeof(float), per, out) == per;
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

/* K of sim's forces on mesh m into g (dofs, profile, values, unfactorised),
 * the surface nodes (*surf, *ns) and the key. */
static int assemble(const ftm_sim *sim, const ftm_mesh *m, ftm_compliance *g, int32_t **surf_out,
                    int32_t *ns_out, ftm_error *err)
{
    const int32_t n = m->node_count;
    int32_t nfree = 0;
    for (int32_t i = n - 1; i >= 0; i--)
        g->dof[i] = m->fixed[i] ? -1 : 3 * nfree++;
    g->ndof = 3 * nfree;
    if (nfree == 0)
        return ftm_error_set(err, FTM_EINVAL,
                             "far_field = elastic: every node of the mesh is fixed: nothing to "
                             "hold the region");
    g->first = malloc((size_t)g->ndof * sizeof *g->first);
    g->rowp = malloc(((size_t)g->ndof + 1) * sizeof *g->rowp);
    if (!g->first || !g->rowp)
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    for (int32_t r = 0; r < g->ndof; r++)
        g->first[r] = r - r % 3; /* the node's own block */
    for_each_block(sim, m, g, profile_block, g);
    size_t entries = 0;
    for (int32_t r = 0; r < g->ndof; r++) {
        g->rowp[r] = entries;
        entries += (size_t)(r - g->first[r] + 1);
    }
    g->rowp[g->ndof] = entries;
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
    if (bytes > FTM_COMPLIANCE_MAX_BYTES) {
        free(surf);
        return ftm_error_set(err, FTM_ENOMEM,
                             "far_field = elastic: the precomputation would take %.0f MiB (a "
                             "profile factor of %zu entries for %d free nodes, and Green's columns "
                             "of %d surface nodes over %d nodes), more than the %.0f MiB allowed: "
                             "use far_field = fixed or a coarser mesh",
                             (double)bytes / 1048576.0, entries, (int)nfree, (int)ns, (int)n,
                             (double)FTM_COMPLIANCE_MAX_BYTES / 1048576.0);
    }
    g->val = calloc(entries + 1, sizeof *g->val);
    if (!g->val) {
        free(surf);
        return ftm_error_set(err, FTM_ENOMEM,
                             "far_field = elastic: out of memory for a profile factor of %zu "
                             "entries (%.0f MiB)",
                             entries, (double)entries * 8.0 / 1048576.0);
    }
    for_each_block(sim, m, g, add_block, g);
    /* the cache's key: the stiffness and the nodes whose columns it holds */
    hasher h;
    hasher_init(&h, 0x46544d4641520002ULL);
    hasher_update(&h, &g->ndof, sizeof g->ndof);
    hasher_update(&h, g->dof, (size_t)n * sizeof *g->dof);
    hasher_update(&h, g->first, (size_t)g->ndof * sizeof *g->first);
    hasher_update(&h, g->val, entries * sizeof *g->val);
    hasher_update(&h, surf, (size_t)ns * sizeof *surf);
    g->key = hasher_final(&h);
    *surf_out = surf;
    *ns_out = ns;
    return FTM_OK;
}

/* ---- the process's registry ---- */

static pthread_mutex_t registry_lock = PTHREAD_MUTEX_INITIALIZER;
static ftm_compliance *registry; /* most recently used first */
/* unused compliances kept for the next simulation of the same body (a
 * replica made per input, a restarted session) */
#define REGISTRY_KEEP 2

static void compliance_free(ftm_compliance *g)
{
    if (!g)
        return;
    if (g->col && g->own)
        for (int32_t i = 0; i < g->n; i++)
            if (g->own[i])
                free(g->col[i]);
    free(g->own);
    free(g->slot);
    if (g->map)
        munmap(g->map, g->map_len);
    free(g->col);
    free(g->dof);
    free(g->first);
    free(g->rowp);
    free(g->val);
    free(g);
}

/* Frees unused entries beyond the REGISTRY_KEEP most recent. Under the lock. */
static void registry_trim(void)
{
    int32_t unused = 0;
    for (ftm_compliance **p = &registry; *p;) {
        ftm_compliance *g = *p;
        if (g->refs == 0 && ++unused > REGISTRY_KEEP) {
            *p = g->next;
            compliance_free(g);
        } else {
            p = &g->next;
        }
    }
}

int ftm_compliance_acquire(const ftm_sim *sim, const ftm_mesh *m, ftm_compliance **out,
                           ftm_error *err)
{
    const int32_t n = m->node_count;
    ftm_compliance *g = calloc(1, sizeof *g);
    if (!g)
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    g->n = n;
    g->dof = malloc(((size_t)n + 1) * sizeof *g->dof);
    g->col = calloc((size_t)n + 1, sizeof *g->col);
    g->own = calloc((size_t)n + 1, sizeof *g->own);
    g->slot = calloc((size_t)n + 1, sizeof *g->slot);
    if (!g->dof || !g->col || !g->own || !g->slot) {
        compliance_free(g);
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    }
    int32_t *surf = NULL, ns = 0;
    int rc = assemble(sim, m, g, &surf, &ns, err);
    if (rc) {
        free(surf);
        compliance_free(g);
        return rc;
    }
    pthread_mutex_lock(&registry_lock);
    ftm_compliance **p = &registry;
    while (*p && ((*p)->key != g->key || (*p)->n != n))
        p = &(*p)->next;
    if (*p) { /* the same stiffness: share it, most recent first */
        ftm_compliance *hit = *p;
        *p = hit->next;
        hit->next = registry;
        registry = hit;
        hit->refs++;
        pthread_mutex_unlock(&registry_lock);
        free(surf);
        compliance_free(g);
        *out = hit;
        return FTM_OK;
    }
    /* computed under the lock: another simulation of the same body waits
     * for this one instead of computing it too */
    if (!cache_load(g, surf, ns)) {
        rc = ensure_factored(g, m, sim->def.log, sim->def.log_user, err);
        if (!rc && compute_columns(g, surf, ns, sim->def.log, sim->def.log_user, true) != FTM_OK)
            rc = ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory for the "
                                                "Green's columns of %d surface nodes", (int)ns);
        if (!rc)
            cache_save(g, surf, ns, sim->def.log, sim->def.log_user);
    }
    free(surf);
    if (rc) {
        pthread_mutex_unlock(&registry_lock);
        compliance_free(g);
        return rc;
    }
    g->refs = 1;
    g->next = registry;
    registry = g;
    registry_trim();
    pthread_mutex_unlock(&registry_lock);
    *out = g;
    return FTM_OK;
}

void ftm_compliance_release(ftm_compliance *g)
{
    if (!g)
        return;
    pthread_mutex_lock(&registry_lock);
    g->refs--;
    registry_trim();
    pthread_mutex_unlock(&registry_lock);
}

int ftm_compliance_ensure(ftm_compliance *g, int32_t node, ftm_log_fn log, void *log_user)
{
    pthread_mutex_lock(&registry_lock);
    int rc = FTM_OK;
    if (g->slot[node] > 0) { /* from the cache file: checked at its first use */
        const int32_t k = g->slot[node] - 1;
        g->slot[node] = 0;
        if (column_sum(g->col[node], g->n) != g->colsum[k]) {
            ftm_logf(log, log_user, FTM_LOG_WARN,
                     "far field: the cached column of node %d is damaged: computed again",
                     (int)node);
            g->col[node] = NULL;
        }
    }
    if (!g->col[node]) {
        /* (a held body: a cached file was made from a factor that exists) */
        rc = ensure_factored(g, NULL, log, log_user, NULL);
        if (!rc)
            rc = compute_columns(g, &node, 1, log, log_user, false);
    }
    pthread_mutex_unlock(&registry_lock);
    return rc;
}

const float *const *ftm_compliance_columns(const ftm_compliance *g)
{
    return (const float *const *)g->col;
}
