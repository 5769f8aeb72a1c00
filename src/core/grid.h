/* Private: a uniform grid of points sorted by cell (src/core/grid.c), the
 * neighbour structure of the smoothing passes (src/smooth/). Cells are
 * numbered by the Morton code of their integer coordinates, so nearby
 * cells are near in memory; each occupied cell is a run of the sorted
 * points, found through an open-addressing hash. Not installed. */
#ifndef TESSEL_GRID_H
#define TESSEL_GRID_H

#include "core/core.h"

typedef struct tsl_grid {
    double origin[3];
    double c; /* cell size */
    uint32_t dims[3];
    size_t n, ncell;
    uint32_t *perm;  /* sorted position -> point index */
    float *sxyz;     /* n*3 coordinates in sorted order */
    uint64_t *key;   /* ncell cell keys, increasing */
    uint32_t *start; /* ncell + 1 run starts */
    uint32_t *slot;  /* open-addressing hash: key -> cell, or
                        UINT32_MAX; hmask + 1 slots */
    size_t hmask;
} tsl_grid;

/* Sorts the n points into cells of side `cell` (widened when the box
 * would need more than 2^21 cells per axis; a coarser grid is still exact,
 * only slower). Points keep increasing index order within a cell, so the
 * grid is the same for any thread count. */
tessel_status tsl_grid_build(tsl_grid *g, const float *xyz, size_t n, double cell,
                             int threads);
void tsl_grid_free(tsl_grid *g);

/* A cell for tsl_grid_build a little wider than the distance from a point
 * to its k-th nearest (wider cells cost more candidates, narrower ones more
 * outer rings: 1.3 times is the cheapest measured for the smoothing). The
 * density comes from how many cells a strided sample of at most 2^16
 * points occupies in a coarse grid (a surface crosses cells of side c with
 * about 2/3 c^2 of its area each). The cell changes no result of a search,
 * only its speed. */
double tsl_grid_knn_cell(const float *xyz, size_t n, size_t k);

/* Runs of the cells at Chebyshev distance `ring` (0 or 1) from cell cc,
 * appended to run[] (pairs of sorted positions) after nrun runs; returns
 * the new number of runs (at most nrun + 26). */
size_t tsl_grid_ring(const tsl_grid *g, const uint32_t cc[3], int ring, uint32_t *run,
                     size_t nrun);

/* The mean spacing of the n points g holds (xyz, in their order), exactly
 * as tessel_cloud_spacing measures it (the same value), with the nearest
 * neighbours found in g instead of a kd-tree: src/core/stats.c. */
tessel_status tsl_grid_spacing(const tsl_grid *g, const float *xyz, size_t n, int threads,
                               double *spacing);

static inline uint64_t tsl_spread21(uint32_t v)
{
    uint64_t x = v & 0x1fffffu;
    x = (x | x << 32) & 0x1f00000000ffffull;
    x = (x | x << 16) & 0x1f0000ff0000ffull;
    x = (x | x << 8) & 0x100f00f00f00f00full;
    x = (x | x << 4) & 0x10c30c30c30c30c3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
}
static inline uint64_t tsl_morton(uint32_t x, uint32_t y, uint32_t z)
{
    return tsl_spread21(x) | tsl_spread21(y) << 1 | tsl_spread21(z) << 2;
}

/* Cell coordinate of p along axis, clamped to the grid. */
static inline uint32_t tsl_grid_cell(const tsl_grid *g, const float *p, int axis)
{
    double v = floor((p[axis] - g->origin[axis]) / g->c);
    if (v < 0.0)
        v = 0.0;
    if (v > (double)(g->dims[axis] - 1))
        v = (double)(g->dims[axis] - 1);
    return (uint32_t)v;
}

static inline size_t tsl_grid_hash(uint64_t key)
{
    return (size_t)((key * 0x9E3779B97F4A7C15ull) >> 32);
}

/* Index of the cell with this key, or SIZE_MAX when it is empty. */
static inline size_t tsl_grid_find(const tsl_grid *g, uint64_t key)
{
    for (size_t h = tsl_grid_hash(key) & g->hmask;; h = (h + 1) & g->hmask) {
        uint32_t c = g->slot[h];
        if (c == UINT32_MAX)
            return SIZE_MAX;
        if (g->key[c] == key)
            return c;
    }
}

/* Calls visit(ctx, x, y, z) for every cell of the grid at Chebyshev
 * distance ring from cell cc (cc itself for ring 0), in a fixed order:
 * the whole z columns of the shell's sides, only their two end cells
 * inside. */
static inline void tsl_grid_shell(const tsl_grid *g, const uint32_t cc[3], int64_t ring,
                                  void (*visit)(void *ctx, int64_t x, int64_t y, int64_t z),
                                  void *ctx)
{
    for (int64_t dx = -ring; dx <= ring; dx++) {
        int64_t x = (int64_t)cc[0] + dx;
        if (x < 0 || x >= g->dims[0])
            continue;
        for (int64_t dy = -ring; dy <= ring; dy++) {
            int64_t y = (int64_t)cc[1] + dy;
            if (y < 0 || y >= g->dims[1])
                continue;
            int side = dx == -ring || dx == ring || dy == -ring || dy == ring;
            for (int64_t dz = -ring; dz <= ring; dz += side ? 1 : 2 * ring) {
                int64_t z = (int64_t)cc[2] + dz;
                if (z >= 0 && z < g->dims[2])
                    visit(ctx, x, y, z);
            }
        }
    }
}

/* Squared distance from q to the box of cell (x, y, z), in float like the
 * point distances, rounded down a little so that it never exceeds the
 * float distance of a point inside. */
static inline float tsl_grid_box_d2(const tsl_grid *g, const float *q, int64_t x, int64_t y,
                                    int64_t z)
{
    int64_t c[3] = {x, y, z};
    double s = 0.0;
    for (int a = 0; a < 3; a++) {
        double lo = g->origin[a] + (double)c[a] * g->c, hi = lo + g->c, e = 0.0;
        if (q[a] < lo)
            e = lo - q[a];
        else if (q[a] > hi)
            e = q[a] - hi;
        s += e * e;
    }
    return (float)(s * (1.0 - 1e-5));
}

#endif /* TESSEL_GRID_H */
