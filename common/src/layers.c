#include "layers.h"

#include <stdlib.h>
#include <string.h>

int ftm_layering_init(ftm_layering *ly, int32_t n)
{
    memset(ly, 0, sizeof *ly);
    ly->visit = calloc((size_t)n, sizeof *ly->visit);
    ly->queue = malloc(((size_t)n + 1) * sizeof *ly->queue);
    ly->order = malloc(((size_t)n + 1) * sizeof *ly->order);
    ly->set_start = malloc(((size_t)n + 1) * sizeof *ly->set_start);
    ly->set_color = malloc((size_t)n + 1);
    ly->start_cap = 64;
    ly->start = malloc((size_t)ly->start_cap * sizeof *ly->start);
    if (!ly->visit || !ly->queue || !ly->order || !ly->set_start || !ly->set_color ||
        !ly->start) {
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

/* The mesh's padded adjacency rows give every node the same trip count,
 * cheaper to run than the CSR rows (depth 20 of Table 3: 5.2 -> 4.6 us), but
 * their padding slots (the node itself, already visited) are checked too:
 * used unless they would add more than a quarter to the links checked. */
static bool use_padded_rows(const ftm_mesh *m)
{
    size_t slots = (size_t)m->node_count * (size_t)m->max_degree;
    size_t links = (size_t)m->adj_start[m->node_count];
    return slots <= links + links / 4;
}

/* Visits u's neighbours in adjacency order; each one not yet in the region
 * joins it: ON_NEW(v) runs after it is marked. */
#define FOR_NEW_NEIGHBOURS(u, ON_NEW)                                                          \
    do {                                                                                       \
        if (padded) {                                                                          \
            const int32_t *restrict row_ = m->pad_node + (size_t)(u) * deg;                    \
            for (size_t e_ = 0; e_ < deg; e_++) {                                              \
                const int32_t v = row_[e_];                                                    \
                if (visit[v] != gen) { /* branch-free was slower (docs/benchmarks.md) */       \
                    visit[v] = gen;                                                            \
                    ON_NEW;                                                                    \
                }                                                                              \
            }                                                                                  \
        } else {                                                                               \
            for (int32_t e_ = adj_start[u]; e_ < adj_start[(u) + 1]; e_++) {                   \
                const int32_t v = adj_node[e_];                                                \
                if (visit[v] != gen) {                                                         \
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

/* The search, compiled once with and once without sets. Without them the
 * BFS queue is the update order itself, written directly, and no colours are
 * counted. */
static inline __attribute__((always_inline)) int search(ftm_layering *ly, const ftm_mesh *m,
                                                        const int32_t *src, int32_t ns,
                                                        int32_t depth, bool want_sets)
{
    const uint32_t gen = ly->gen;
    uint32_t *restrict visit = ly->visit;
    int32_t *restrict queue = want_sets ? ly->queue : ly->order;
    const int32_t *restrict adj_start = m->adj_start, *restrict adj_node = m->adj_node;
    const size_t deg = (size_t)m->max_degree;
    const bool padded = use_padded_rows(m);
    const uint8_t *color = m->color;
    /* colour counts of the layer being sorted and of the one being found */
    int32_t counts[2][FTM_SHARED_COLOR + 1] = {{0}};
    int32_t count = 0;
    for (int32_t s = 0; s < ns; s++) {
        visit[src[s]] = gen;
        queue[count++] = src[s];
        if (want_sets)
            counts[0][color[src[s]]]++;
    }
    ly->sets = 0;
    ly->start[0] = 0;
    /* all sources advance together: layer l+1 is everything first reached from layer l */
    int32_t layer = 0, head = 0;
    while (head < count) {
        if (reserve_starts(ly, layer + 2))
            return FTM_ENOMEM;
        const int32_t end = count;
        int32_t *next = counts[(layer + 1) & 1];
        for (int32_t k = head; layer < depth && k < end; k++) {
            const int32_t u = queue[k];
            FOR_NEW_NEIGHBOURS(u, {
                queue[count++] = v;
                if (want_sets)
                    next[color[v]]++;
            });
        }
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
}

int ftm_layering_build(ftm_layering *ly, const ftm_mesh *m, const int32_t *src, int32_t ns,
                       int32_t depth, bool want_sets)
{
    if (++ly->gen == 0) { /* stamp wrapped: the only time the array is cleared */
        memset(ly->visit, 0, (size_t)m->node_count * sizeof *ly->visit);
        ly->gen = 1;
    }
    return want_sets ? search(ly, m, src, ns, depth, true) : search(ly, m, src, ns, depth, false);
}
