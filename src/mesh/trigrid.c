/* The triangle hash grid: a uniform grid hashed on cell coordinates, each
 * triangle listed in every cell its bounding box meets. The advancing front
 * and the refinement's checked edits ask it for the triangles near a new
 * one, to test them exactly (core/predicates.c); queries from several
 * threads at once each carry their own result (tsl_trigrid_hits). */
#include "mesh/mesh.h"

#include <stdlib.h>
#include <string.h>

#define NONE TESSEL_NONE

#define GRID_AXIS_CELLS 2097151 /* 2^21 - 1: three axes pack into 63 bits */

/* The first, empty table of cells. */
static tessel_status grid_alloc(tsl_trigrid *g)
{
    g->slots = 1024;
    g->keys = tsl_calloc_array(g->slots, sizeof *g->keys);
    g->heads = tsl_alloc_array(g->slots, sizeof *g->heads);
    if (!g->keys || !g->heads) {
        tsl_trigrid_free(g);
        return TESSEL_ERR_NOMEM;
    }
    return TESSEL_OK;
}

tessel_status tsl_trigrid_init(tsl_trigrid *g, const double lo[3], const double hi[3],
                               double cell)
{
    memset(g, 0, sizeof *g);
    double extent = 0.0;
    for (int i = 0; i < 3; i++) {
        g->origin[i] = lo[i];
        if (hi[i] - lo[i] > extent)
            extent = hi[i] - lo[i];
    }
    if (!(cell > 0.0) || !isfinite(cell))
        cell = 1.0;
    /* Keep every coordinate within 21 bits however sparse the points. */
    if (extent / cell > (double)(GRID_AXIS_CELLS - 2))
        cell = extent / (double)(GRID_AXIS_CELLS - 2);
    g->inv_cell = 1.0 / cell;
    return grid_alloc(g);
}

tessel_status tsl_trigrid_init_like(tsl_trigrid *g, const tsl_trigrid *like)
{
    memset(g, 0, sizeof *g);
    memcpy(g->origin, like->origin, sizeof g->origin);
    g->inv_cell = like->inv_cell;
    return grid_alloc(g);
}

void tsl_trigrid_free(tsl_trigrid *g)
{
    if (!g)
        return;
    free(g->keys);
    free(g->heads);
    free(g->ent_tri);
    free(g->ent_next);
    tsl_trigrid_hits_free(&g->hits);
    memset(g, 0, sizeof *g);
}

static inline int32_t grid_coord(const tsl_trigrid *g, double x, int axis)
{
    double c = floor((x - g->origin[axis]) * g->inv_cell);
    if (!(c >= 0.0))
        return 0;
    if (c > (double)GRID_AXIS_CELLS)
        return GRID_AXIS_CELLS;
    return (int32_t)c;
}

static inline uint64_t grid_key(int32_t x, int32_t y, int32_t z)
{
    return ((uint64_t)x << 42 | (uint64_t)y << 21 | (uint64_t)z) + 1;
}

static inline size_t grid_slot(const tsl_trigrid *g, uint64_t key)
{
    uint64_t h = key * 0x9E3779B97F4A7C15ULL;
    return (size_t)(h ^ (h >> 29)) & (g->slots - 1);
}

/* Moves the cells into a table of the given number of slots (a power of
 * two, more than the cells used). */
static tessel_status grid_rehash(tsl_trigrid *g, size_t slots)
{
    uint64_t *keys = tsl_calloc_array(slots, sizeof *keys);
    uint32_t *heads = tsl_alloc_array(slots, sizeof *heads);
    if (!keys || !heads) {
        free(keys);
        free(heads);
        return TESSEL_ERR_NOMEM;
    }
    uint64_t *old_keys = g->keys;
    uint32_t *old_heads = g->heads;
    size_t old_slots = g->slots;
    g->keys = keys;
    g->heads = heads;
    g->slots = slots;
    for (size_t i = 0; i < old_slots; i++) {
        if (!old_keys[i])
            continue;
        size_t s = grid_slot(g, old_keys[i]);
        while (keys[s])
            s = (s + 1) & (slots - 1);
        keys[s] = old_keys[i];
        heads[s] = old_heads[i];
    }
    free(old_keys);
    free(old_heads);
    return TESSEL_OK;
}

/* Room for this many entries in both entry arrays. */
static tessel_status ent_reserve(tsl_trigrid *g, size_t entries)
{
    if (entries <= g->ent_cap)
        return TESSEL_OK;
    size_t cap = g->ent_cap, cap2 = g->ent_cap;
    if (tsl_grow((void **)&g->ent_tri, &cap, entries, sizeof *g->ent_tri) ||
        tsl_grow((void **)&g->ent_next, &cap2, entries, sizeof *g->ent_next))
        return TESSEL_ERR_NOMEM;
    g->ent_cap = cap < cap2 ? cap : cap2;
    return TESSEL_OK;
}

tessel_status tsl_trigrid_reserve(tsl_trigrid *g, size_t entries, size_t cells)
{
    size_t slots = g->slots;
    while ((cells + 1) * 2 > slots && slots <= SIZE_MAX / 4)
        slots *= 2;
    if (slots > g->slots && grid_rehash(g, slots))
        return TESSEL_ERR_NOMEM;
    return ent_reserve(g, entries);
}

tessel_status tsl_trigrid_insert(tsl_trigrid *g, uint32_t tri, const double lo[3],
                                 const double hi[3])
{
    int32_t c0[3], c1[3];
    for (int i = 0; i < 3; i++) {
        c0[i] = grid_coord(g, lo[i], i);
        c1[i] = grid_coord(g, hi[i], i);
    }
    if ((size_t)tri >= g->id_end)
        g->id_end = (size_t)tri + 1;
    for (int32_t x = c0[0]; x <= c1[0]; x++)
        for (int32_t y = c0[1]; y <= c1[1]; y++)
            for (int32_t z = c0[2]; z <= c1[2]; z++) {
                if ((g->used + 1) * 2 > g->slots && grid_rehash(g, 2 * g->slots))
                    return TESSEL_ERR_NOMEM;
                if (ent_reserve(g, g->entries + 1))
                    return TESSEL_ERR_NOMEM;
                uint64_t key = grid_key(x, y, z);
                size_t s = grid_slot(g, key);
                while (g->keys[s] && g->keys[s] != key)
                    s = (s + 1) & (g->slots - 1);
                uint32_t ent = (uint32_t)g->entries++;
                g->ent_tri[ent] = tri;
                if (!g->keys[s]) {
                    g->keys[s] = key;
                    g->used++;
                    g->ent_next[ent] = NONE;
                } else {
                    g->ent_next[ent] = g->heads[s];
                }
                g->heads[s] = ent;
            }
    return TESSEL_OK;
}

tessel_status tsl_trigrid_query(tsl_trigrid *g, const double lo[3], const double hi[3])
{
    tessel_status st = tsl_trigrid_hits_begin(&g->hits);
    return st ? st : tsl_trigrid_collect(g, lo, hi, &g->hits);
}

bool tsl_trigrid_covers(const tsl_trigrid *g, const double olo[3], const double ohi[3],
                        const double lo[3], const double hi[3])
{
    for (int i = 0; i < 3; i++)
        if (grid_coord(g, lo[i], i) < grid_coord(g, olo[i], i) ||
            grid_coord(g, hi[i], i) > grid_coord(g, ohi[i], i))
            return false;
    return true;
}

void tsl_trigrid_clear(tsl_trigrid *g)
{
    if (g->used)
        memset(g->keys, 0, g->slots * sizeof *g->keys);
    g->used = 0;
    g->entries = 0;
}

#define HITS_MIN 256

static inline size_t seen_slot(uint32_t t, size_t cap)
{
    return (size_t)((uint32_t)(t * 2654435761u) ^ (t >> 15)) & (cap - 1);
}

/* Whether t is in the result already; if not, records it in the set. */
static inline bool seen_add(tsl_trigrid_hits *h, uint32_t t)
{
    uint64_t mark = (uint64_t)h->now << 32;
    size_t s = seen_slot(t, h->seen_cap);
    while ((h->seen[s] & ~(uint64_t)UINT32_MAX) == mark) {
        if ((uint32_t)h->seen[s] == t)
            return true;
        s = (s + 1) & (h->seen_cap - 1);
    }
    h->seen[s] = mark | t;
    return false;
}

/* A set of twice the capacity holding the result's ids. */
static tessel_status seen_grow(tsl_trigrid_hits *h)
{
    size_t cap = 2 * h->seen_cap;
    uint64_t *seen = tsl_calloc_array(cap, sizeof *seen);
    if (!seen)
        return TESSEL_ERR_NOMEM;
    free(h->seen);
    h->seen = seen;
    h->seen_cap = cap;
    h->now = 1;
    for (size_t i = 0; i < h->count; i++)
        seen_add(h, h->found[i]);
    return TESSEL_OK;
}

tessel_status tsl_trigrid_hits_begin(tsl_trigrid_hits *h)
{
    h->count = 0;
    if (!h->seen) {
        h->seen = tsl_calloc_array(HITS_MIN, sizeof *h->seen);
        h->found = tsl_alloc_array(HITS_MIN, sizeof *h->found);
        if (!h->seen || !h->found) {
            tsl_trigrid_hits_free(h);
            return TESSEL_ERR_NOMEM;
        }
        h->seen_cap = h->found_cap = HITS_MIN;
        h->now = 0;
    }
    if (++h->now == 0) {
        memset(h->seen, 0, h->seen_cap * sizeof *h->seen);
        h->now = 1;
    }
    return TESSEL_OK;
}

tessel_status tsl_trigrid_collect(const tsl_trigrid *g, const double lo[3], const double hi[3],
                                  tsl_trigrid_hits *h)
{
    if (!g->used)
        return TESSEL_OK;
    int32_t c0[3], c1[3];
    for (int i = 0; i < 3; i++) {
        c0[i] = grid_coord(g, lo[i], i);
        c1[i] = grid_coord(g, hi[i], i);
    }
    for (int32_t x = c0[0]; x <= c1[0]; x++)
        for (int32_t y = c0[1]; y <= c1[1]; y++)
            for (int32_t z = c0[2]; z <= c1[2]; z++) {
                uint64_t key = grid_key(x, y, z);
                size_t s = grid_slot(g, key);
                while (g->keys[s] && g->keys[s] != key)
                    s = (s + 1) & (g->slots - 1);
                if (!g->keys[s])
                    continue;
                for (uint32_t ent = g->heads[s]; ent != NONE; ent = g->ent_next[ent]) {
                    uint32_t t = g->ent_tri[ent];
                    if (seen_add(h, t))
                        continue;
                    if (h->count == h->found_cap &&
                        tsl_grow((void **)&h->found, &h->found_cap, h->count + 1,
                                 sizeof *h->found))
                        return TESSEL_ERR_NOMEM;
                    h->found[h->count++] = t;
                    if (2 * h->count > h->seen_cap && seen_grow(h))
                        return TESSEL_ERR_NOMEM;
                }
            }
    return TESSEL_OK;
}

void tsl_trigrid_hits_free(tsl_trigrid_hits *h)
{
    free(h->seen);
    free(h->found);
    memset(h, 0, sizeof *h);
}
