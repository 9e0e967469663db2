/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "ftm/internal/layers.h"
#include "mesh_internal.h"

#include <stdlib.h>
#include <string.h>

int ftm_layering_init(ftm_layering *ly, int32_t n)
{
    memset(ly, 0, sizeof *ly);
    ly->visit = calloc((size_t)n, sizeof *ly->visit);
    ly->queue = malloc(((size_t)n + 1) * sizeof *ly->queue);
    /* 16 spare entries: the vector split stores 16 at a time */
    ly->order = malloc(((size_t)n + 16) * sizeof *ly->order);
    ly->qcol = calloc((size_t)n + 16, 1); /* read 16 at a time, past the end too */
    ly->set_start = malloc(((size_t)n + 1) * sizeof *ly->set_start);
    ly->set_color = malloc((size_t)n + 1);
    ly->start_cap = 64;
    ly->start = malloc((size_t)ly->start_cap * sizeof *ly->start);
    if (!ly->visit || !ly->queue || !ly->order || !ly->qcol || !ly->set_start ||
        !ly->set_color || !ly->start) {
        ftm_layering_free(ly);
        return FTM_ENOMEM;
    }
    ly->start[0] = 0;
    return FTM_OK;
}

void ftm_layering_free(ftm_layering *ly)
{
    free(ly->visit);
    free(ly->queue);
    free(ly->order);
    free(ly->qcol);
    free(ly->start);
    free(ly->set_start);
    free(ly->set_color);
    memset(ly, 0, sizeof *ly);
}

/* Stable counting sort of the layer queue[s..e) by mesh colour into
 * order[s..e), recording one set per colour present; pos holds the layer's
 * count of each colour (counted as the search found the nodes) and is
 * left zeroed. */
static void sort_layer(ftm_layering *ly, const uint8_t *color, int32_t *pos, int32_t s,
                       int32_t e)
{
    int32_t p = s;
    for (int c = 0; c <= FTM_SHARED_COLOR && p < e; c++) {
        int32_t n = pos[c];
        if (n == 0)
            continue;
        ly->set_start[ly->sets] = p;
        ly->set_color[ly->sets++] = (uint8_t)c;
        pos[c] = p;
        p += n;
    }
    for (int32_t k = s; k < e; k++) {
        int32_t u = ly->queue[k];
        ly->order[pos[color[u]]++] = u;
    }
    memset(pos, 0, (FTM_SHARED_COLOR + 1) * sizeof *pos);
}

#if defined(__x86_64__)
#include <immintrin.h>

/* What sort_layer does, for AVX-512: the layer queue[s..e) split by colour
 * into order[s..e), given the colours of its nodes (qcol, as the search
 * found them) and the set of colours present. For each colour, 16 nodes at
 * a time, those of that colour are compressed to the front of a vector
 * (keeping their order) and the vector is stored whole: order has 16 spare
 * entries, and what lands past the set is overwritten by the next one. */
__attribute__((target("avx512f,popcnt"))) static void
split_layer16(ftm_layering *ly, const uint8_t *qcol, uint64_t present, int32_t s, int32_t e)
{
    int32_t p = s;
    for (; present; present &= present - 1) {
        const int c = __builtin_ctzll(present);
        ly->set_start[ly->sets] = p;
        ly->set_color[ly->sets++] = (uint8_t)c;
        const __m512i cv = _mm512_set1_epi32(c);
        for (int32_t k = s; k < e; k += 16) {
            const __mmask16 valid = e - k >= 16 ? (__mmask16)0xFFFF
                                                : (__mmask16)((1u << (e - k)) - 1);
            const __m512i ids = _mm512_maskz_loadu_epi32(valid, ly->queue + k);
            const __m512i col = _mm512_cvtepu8_epi32(_mm_loadu_si128((const __m128i *)(qcol + k)));
            const __mmask16 hit = _mm512_mask_cmpeq_epi32_mask(valid, col, cv);
            _mm512_storeu_si512(ly->order + p, _mm512_maskz_compress_epi32(hit, ids));
            p += (int32_t)_mm_popcnt_u32(hit);
        }
    }
}
#endif

/* Visits u's neighbours in adjacency order; each one not yet in the region
 * joins it: ON_NEW(v) runs after it is marked. Most checks find a node
 * already marked (the layer's own and the inner one's), so the new node's
 * path is marked unlikely and laid out of line; the padded row's loop is
 * unrolled by two (GCC 12, depth 20 of Table 3: 4.9 -> 3.7 us, as clang 14
 * compiles the plain loop; a branch-free check was slower). */
#define FOR_NEW_NEIGHBOURS(u, ON_NEW)                                                          \
    do {                                                                                       \
        if (padded) {                                                                          \
            const int32_t *restrict row_ = pad_node + (size_t)(u) * deg;                       \
            _Pragma("GCC unroll 2") for (size_t e_ = 0; e_ < deg; e_++) {                      \
                const int32_t v = row_[e_];                                                    \
                if (__builtin_expect(visit[v] != gen, 0)) {                                    \
                    visit[v] = gen;                                                            \
                    ON_NEW;                                                                    \
                }                                                                              \
            }                                                                                  \
        } else {                                                                               \
            for (int32_t e_ = adj_start[u]; e_ < adj_start[(u) + 1]; e_++) {                   \
                const int32_t v = adj_node[e_];                                                \
                if (__builtin_expect(visit[v] != gen, 0)) {                                    \
                    visit[v] = gen;                                                            \
                    ON_NEW;                                                                    \
                }                                                                              \
            }                                                                                  \
        }                                                                                      \
    } while (0)

/* Room for `need` layer starts. */
static int reserve_starts(ftm_layering *ly, int32_t need)
{
    if (need <= ly->start_cap)
        return FTM_OK;
    int32_t ncap = ly->start_cap * 2;
    int32_t *st = realloc(ly->start, (size_t)ncap * sizeof *st);
    if (!st)
        return FTM_ENOMEM;
    ly->start = st;
    ly->start_cap = ncap;
    return FTM_OK;
}

/* The search, compiled without sets, with sets split by sort_layer, and
 * (x86-64) with sets split by split_layer16 (vec). Without sets the BFS queue
 * is the update order itself, written directly, and no colours are counted.
 * With sort_layer the search counts each layer's colours; with vec it notes
 * each node's colour beside the queue and the colours present. */
static inline __attribute__((always_inline)) int search(ftm_layering *ly, const ftm_mesh *m,
                                                        const int32_t *src, int32_t ns,
                                                        int32_t depth, bool want_sets, bool vec)
{
    const uint32_t gen = ly->gen;
    uint32_t *restrict visit = ly->visit;
    int32_t *restrict queue = want_sets ? ly->queue : ly->order;
    const int32_t *restrict adj_start = m->adj_start, *restrict adj_node = m->adj_node;
    const int32_t *restrict pad_node = m->pad_node;
    const size_t deg = (size_t)m->max_degree;
    /* 5.2 -> 4.6 us at depth 20 of Table 3 */
    const bool padded = m->pad_node && ftm_mesh_pad_cheap(m);
    const uint8_t *color = m->color;
    /* colour counts of the layer being sorted and of the one being found */
    int32_t counts[2][FTM_SHARED_COLOR + 1] = {{0}};
    uint8_t *restrict qcol = ly->qcol;
    uint64_t present[2] = {0, 0}; /* with vec: colours of those layers, a bit each */
    int32_t count = 0;
#define NOTE_COLOUR(v, l)                                                                      \
    do {                                                                                       \
        if (vec) {                                                                             \
            qcol[count] = color[v];                                                            \
            present[l] |= 1ULL << color[v];                                                    \
        } else if (want_sets) {                                                                \
            counts[l][color[v]]++;                                                             \
        }                                                                                      \
    } while (0)
    for (int32_t s = 0; s < ns; s++) {
        visit[src[s]] = gen;
        NOTE_COLOUR(src[s], 0);
        queue[count++] = src[s];
    }
    ly->sets = 0;
    ly->start[0] = 0;
    /* all sources advance together: layer l+1 is everything first reached from layer l */
    int32_t layer = 0, head = 0;
    while (head < count) {
        if (reserve_starts(ly, layer + 2))
            return FTM_ENOMEM;
        const int32_t end = count;
        const int nx = (layer + 1) & 1;
        for (int32_t k = head; layer < depth && k < end; k++) {
            const int32_t u = queue[k];
            FOR_NEW_NEIGHBOURS(u, {
                NOTE_COLOUR(v, nx);
                queue[count++] = v;
            });
        }
#if defined(__x86_64__)
        if (vec) {
            split_layer16(ly, qcol, present[layer & 1], head, end);
            present[layer & 1] = 0;
        } else
#endif
        if (want_sets)
            sort_layer(ly, color, counts[layer & 1], head, end);
        head = end;
        ly->start[++layer] = end;
    }
    if (want_sets)
        ly->set_start[ly->sets] = count;
    ly->count = count;
    ly->layers = layer;
    return FTM_OK;
#undef NOTE_COLOUR
}

#if defined(__x86_64__)
__attribute__((target("avx512f,popcnt"))) static int search_sets16(ftm_layering *ly,
                                                                  const ftm_mesh *m,
                                                                  const int32_t *src, int32_t ns,
                                                                  int32_t depth)
{
    return search(ly, m, src, ns, depth, true, true);
}
#endif

int ftm_layering_build(ftm_layering *ly, const ftm_mesh *m, const int32_t *src, int32_t ns,
                       int32_t depth, bool want_sets)
{
    if (++ly->gen == 0) { /* stamp wrapped: the only time the array is cleared */
        memset(ly->visit, 0, (size_t)m->node_count * sizeof *ly->visit);
        ly->gen = 1;
    }
    if (!want_sets)
        return search(ly, m, src, ns, depth, false, false);
#if defined(__x86_64__)
    if (!ly->scalar_split && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("popcnt"))
        return search_sets16(ly, m, src, ns, depth);
#endif
    return search(ly, m, src, ns, depth, true, false);
}
