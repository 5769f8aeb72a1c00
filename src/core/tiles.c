/* Tiles of a point set, for the methods that mesh parts in parallel and
 * then close the seams: recursive median bisection, each part cut along
 * the longest side of its box, until every tile has at most max_points
 * points. The cut depends on the points and max_points only, never on the
 * thread count (the halves of a part are cut side by side). */
#include "core/core.h"

#include <stdlib.h>
#include <string.h>

typedef struct tile_key {
    float c;
    uint32_t id;
} tile_key;

static inline bool key_less(tile_key a, tile_key b)
{
    return a.c < b.c || (a.c == b.c && a.id < b.id);
}

static int cmp_key(const void *pa, const void *pb)
{
    const tile_key *a = pa, *b = pb;
    return key_less(*a, *b) ? -1 : key_less(*b, *a);
}

/* Puts the k-th smallest of a[0 .. n) at k, smaller keys before it and
 * larger after (quickselect; keys are distinct through the ids). */
static void select_key(tile_key *a, size_t n, size_t k)
{
    long long lo = 0, hi = (long long)n - 1;
    for (int rounds = 0; hi > lo; rounds++) {
        if (rounds == 64) { /* a pathological order: sort the rest */
            qsort(a + lo, (size_t)(hi - lo + 1), sizeof *a, cmp_key);
            return;
        }
        long long mid = lo + (hi - lo) / 2;
        tile_key tmp;
#define SWAP_KEYS(x, y) (tmp = a[x], a[x] = a[y], a[y] = tmp)
        if (key_less(a[mid], a[lo]))
            SWAP_KEYS(mid, lo);
        if (key_less(a[hi], a[lo]))
            SWAP_KEYS(hi, lo);
        if (key_less(a[hi], a[mid]))
            SWAP_KEYS(hi, mid);
        tile_key pivot = a[mid];
        long long i = lo - 1, j = hi + 1;
        for (;;) {
            do
                i++;
            while (key_less(a[i], pivot));
            do
                j--;
            while (key_less(pivot, a[j]));
            if (i >= j)
                break;
            SWAP_KEYS(i, j);
        }
#undef SWAP_KEYS
        if ((long long)k <= j)
            hi = j;
        else
            lo = j + 1;
    }
}

/* Tiles in a part of m points: each cut halves a part, so the shape of the
 * bisection (and with it every node's number and first tile) depends on m
 * alone, which lets the halves be cut side by side. */
static size_t tiles_of(size_t m, size_t max_points)
{
    return m <= max_points ? 1 : tiles_of(m / 2, max_points) + tiles_of(m - m / 2, max_points);
}

/* Parts smaller than this are cut by the thread that made them. */
#define TASK_POINTS ((size_t)1 << 16)

/* Cuts ids[lo .. hi) into tiles of at most max_points points, the first
 * numbered `tile` (their ranges into start[]), its cuts numbered from
 * `node` in preorder (into node[]); dcut[i] becomes the distance of point
 * i to the nearest cut bounding its tile, cut_axis[i] that cut's axis. The
 * lower half goes to another task when large: every part writes its own
 * points, tiles and nodes. */
static void bisect(const float *xyz, uint32_t *ids, tile_key *keys, size_t lo, size_t hi,
                   size_t max_points, int depth, uint32_t node, size_t tile, tsl_tiles *t)
{
    size_t m = hi - lo;
    if (m <= max_points) {
        t->start[tile] = lo;
        return;
    }
    float bl[3] = {INFINITY, INFINITY, INFINITY}, bh[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t u = lo; u < hi; u++)
        for (int c = 0; c < 3; c++) {
            float x = xyz[3 * (size_t)ids[u] + c];
            bl[c] = x < bl[c] ? x : bl[c];
            bh[c] = x > bh[c] ? x : bh[c];
        }
    int axis = 0;
    for (int c = 1; c < 3; c++)
        if (bh[c] - bl[c] > bh[axis] - bl[axis])
            axis = c;
    tile_key *k = keys + lo;
    for (size_t u = 0; u < m; u++) {
        k[u].c = xyz[3 * (size_t)ids[lo + u] + axis];
        k[u].id = ids[lo + u];
    }
    size_t half = m / 2;
    select_key(k, m, half);
    float left = -INFINITY;
    for (size_t u = 0; u < half; u++)
        left = k[u].c > left ? k[u].c : left;
    double cut = 0.5 * ((double)left + (double)k[half].c);
    for (size_t u = 0; u < m; u++) {
        ids[lo + u] = k[u].id;
        float d = (float)fabs((double)k[u].c - cut);
        if (d < t->dcut[k[u].id]) {
            t->dcut[k[u].id] = d;
            t->cut_axis[k[u].id] = (uint8_t)axis;
        }
    }
    size_t low_tiles = tiles_of(half, max_points);
    tsl_tile_node *nd = &t->node[node];
    nd->at = cut;
    nd->axis = (uint8_t)axis;
    nd->depth = (uint8_t)depth;
    nd->first = (uint32_t)tile;
    nd->mid = (uint32_t)(tile + low_tiles);
    nd->end = (uint32_t)(tile + tiles_of(m, max_points));
    nd->low = half > max_points ? node + 1 : TESSEL_NONE;
    nd->high = m - half > max_points ? node + (uint32_t)low_tiles : TESSEL_NONE;
#pragma omp task if (half >= TASK_POINTS)
    bisect(xyz, ids, keys, lo, lo + half, max_points, depth + 1, node + 1, tile, t);
    bisect(xyz, ids, keys, lo + half, hi, max_points, depth + 1, node + (uint32_t)low_tiles,
           tile + low_tiles, t);
}

void tsl_tiles_free(tsl_tiles *t)
{
    free(t->start);
    free(t->ids);
    free(t->tile_of);
    free(t->dcut);
    free(t->cut_axis);
    free(t->node);
    memset(t, 0, sizeof *t);
}

tessel_status tsl_tiles_cut(const float *xyz, size_t n, size_t max_points, int threads,
                            tsl_tiles *t)
{
    memset(t, 0, sizeof *t);
    if (max_points == 0)
        return TESSEL_ERR_INVALID_ARG;
    size_t cap = 2 * (n / max_points) + 2;
    t->start = tsl_alloc_array(cap + 1, sizeof *t->start);
    t->ids = tsl_alloc_array(n + 1, sizeof *t->ids);
    t->tile_of = tsl_alloc_array(n + 1, sizeof *t->tile_of);
    t->dcut = tsl_alloc_array(n + 1, sizeof *t->dcut);
    t->cut_axis = tsl_calloc_array(n + 1, 1);
    t->node = tsl_alloc_array(cap + 1, sizeof *t->node);
    tile_key *keys = tsl_alloc_array(n + 1, sizeof *keys);
    size_t *fill = NULL;
    if (!t->start || !t->ids || !t->tile_of || !t->dcut || !t->cut_axis || !t->node || !keys) {
        free(keys);
        tsl_tiles_free(t);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        t->ids[i] = (uint32_t)i;
        t->dcut[i] = INFINITY;
    }
    t->count = tiles_of(n, max_points);
    t->nodes = t->count - 1;
#pragma omp parallel num_threads(tsl_threads(threads))
#pragma omp single
    bisect(xyz, t->ids, keys, 0, n, max_points, 0, 0, 0, t);
    free(keys);
    t->start[t->count] = n;
    for (size_t k = 0; k < t->count; k++)
        for (size_t u = t->start[k]; u < t->start[k + 1]; u++)
            t->tile_of[t->ids[u]] = (uint32_t)k;
    /* Each tile's points in their input order, as one method's pass would
     * see them (seeds are taken in that order). */
    if (!(fill = tsl_alloc_array(t->count + 1, sizeof *fill))) {
        tsl_tiles_free(t);
        return TESSEL_ERR_NOMEM;
    }
    memcpy(fill, t->start, t->count * sizeof *fill);
    for (size_t i = 0; i < n; i++)
        t->ids[fill[t->tile_of[i]]++] = (uint32_t)i;
    free(fill);
    return TESSEL_OK;
}
