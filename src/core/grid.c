/* A uniform grid of points sorted by cell: the neighbour structure of the
 * smoothing passes (src/smooth/), which serve all the points of a cell
 * from the runs of the cells around it. Building it is a radix sort,
 * linear in the number of points. Declarations and the small inline
 * helpers are in src/core/grid.h. */
#include "core/grid.h"

#include <stdlib.h>
#include <string.h>

void tsl_grid_free(tsl_grid *g)
{
    free(g->perm);
    free(g->sxyz);
    free(g->key);
    free(g->start);
    free(g->slot);
    memset(g, 0, sizeof *g);
}

/* One stable counting-sort pass on byte `sh` of the keys, the input cut
 * into `parts` consecutive slices sorted by as many threads: each slice
 * counts its own bytes, and slice t's items of a byte go after those of
 * the slices before it, so the order is the stable one for any number of
 * slices. count holds parts rows of 256. */
static void radix_pass(const uint64_t *k0, const uint32_t *i0, uint64_t *k1, uint32_t *i1,
                       size_t n, int sh, size_t (*count)[256], int parts)
{
#pragma omp parallel for num_threads(parts) schedule(static, 1)
    for (int t = 0; t < parts; t++) {
        size_t lo = n * (size_t)t / (size_t)parts, hi = n * (size_t)(t + 1) / (size_t)parts;
        memset(count[t], 0, sizeof count[t]);
        for (size_t i = lo; i < hi; i++)
            count[t][(k0[i] >> sh) & 0xff]++;
    }
    size_t sum = 0;
    for (int b = 0; b < 256; b++)
        for (int t = 0; t < parts; t++) {
            size_t c = count[t][b];
            count[t][b] = sum;
            sum += c;
        }
#pragma omp parallel for num_threads(parts) schedule(static, 1)
    for (int t = 0; t < parts; t++) {
        size_t lo = n * (size_t)t / (size_t)parts, hi = n * (size_t)(t + 1) / (size_t)parts;
        for (size_t i = lo; i < hi; i++) {
            size_t dst = count[t][(k0[i] >> sh) & 0xff]++;
            k1[dst] = k0[i];
            i1[dst] = i0[i];
        }
    }
}

/* Sorts the points by cell with a stable LSD radix sort on the Morton key
 * (only the bytes in use), so equal cells keep increasing point order
 * whatever the thread count. */
tessel_status tsl_grid_build(tsl_grid *g, const float *xyz, size_t n, double cell,
                             int threads)
{
    memset(g, 0, sizeof *g);
    /* Minima and maxima are exact: any thread count gives the same box. */
    float lx = INFINITY, ly = INFINITY, lz = INFINITY, hx = -INFINITY, hy = -INFINITY,
          hz = -INFINITY;
#pragma omp parallel for num_threads(threads) schedule(static) \
    reduction(min : lx, ly, lz) reduction(max : hx, hy, hz)
    for (size_t i = 0; i < n; i++) {
        const float *q = xyz + 3 * i;
        lx = q[0] < lx ? q[0] : lx, ly = q[1] < ly ? q[1] : ly, lz = q[2] < lz ? q[2] : lz;
        hx = q[0] > hx ? q[0] : hx, hy = q[1] > hy ? q[1] : hy, hz = q[2] > hz ? q[2] : hz;
    }
    double lo[3] = {lx, ly, lz}, hi[3] = {hx, hy, hz};
    /* 21 bits per axis; a coarser grid is still exact, only slower. */
    double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    if (ext / cell > 2000000.0)
        cell = ext / 2000000.0;
    g->c = cell;
    uint32_t maxdim = 1;
    for (int a = 0; a < 3; a++) {
        g->origin[a] = lo[a];
        g->dims[a] = (uint32_t)floor((hi[a] - lo[a]) / cell) + 1;
        maxdim = g->dims[a] > maxdim ? g->dims[a] : maxdim;
    }
    int bits = 1;
    while (bits < 21 && (1u << bits) < maxdim)
        bits++;
    int passes = (3 * bits + 7) / 8;
    g->n = n;

    size_t(*count)[256] = NULL;
    uint64_t *k0 = tsl_alloc_array(n, sizeof *k0), *k1 = tsl_alloc_array(n, sizeof *k1);
    uint32_t *i0 = tsl_alloc_array(n, sizeof *i0), *i1 = tsl_alloc_array(n, sizeof *i1);
    g->sxyz = tsl_alloc_array(n, 3 * sizeof(float));
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!k0 || !k1 || !i0 || !i1 || !g->sxyz)
        goto done;
#pragma omp parallel for num_threads(threads) schedule(static)
    for (size_t i = 0; i < n; i++) {
        const float *p = xyz + 3 * i;
        k0[i] = tsl_morton(tsl_grid_cell(g, p, 0), tsl_grid_cell(g, p, 1), tsl_grid_cell(g, p, 2));
        i0[i] = (uint32_t)i;
    }
    int parts = threads > 0 ? threads : 1;
    count = tsl_alloc_array((size_t)parts, sizeof *count);
    if (!count)
        goto done;
    for (int pass = 0; pass < passes; pass++) {
        radix_pass(k0, i0, k1, i1, n, 8 * pass, count, parts);
        uint64_t *tk = k0;
        k0 = k1, k1 = tk;
        uint32_t *ti = i0;
        i0 = i1, i1 = ti;
    }
    size_t ncell = 0;
    for (size_t i = 0; i < n; i++)
        ncell += i == 0 || k0[i] != k0[i - 1];
    g->key = tsl_alloc_array(ncell, sizeof *g->key);
    g->start = tsl_alloc_array(ncell + 1, sizeof *g->start);
    if (!g->key || !g->start)
        goto done;
    size_t c = 0;
    for (size_t i = 0; i < n; i++) {
        if (i == 0 || k0[i] != k0[i - 1]) {
            g->key[c] = k0[i];
            g->start[c++] = (uint32_t)i;
        }
    }
#pragma omp parallel for num_threads(parts) schedule(static)
    for (size_t i = 0; i < n; i++)
        memcpy(g->sxyz + 3 * i, xyz + 3 * (size_t)i0[i], 3 * sizeof(float));
    g->start[ncell] = (uint32_t)n;
    g->ncell = ncell;
    /* Cell lookups by hashing: a quarter full at most. */
    size_t slots = 64;
    while (slots < 4 * ncell)
        slots *= 2;
    g->slot = tsl_alloc_array(slots, sizeof *g->slot);
    if (!g->slot)
        goto done;
    memset(g->slot, 0xff, slots * sizeof *g->slot);
    g->hmask = slots - 1;
    for (size_t i = 0; i < ncell; i++) {
        size_t h = tsl_grid_hash(g->key[i]) & g->hmask;
        while (g->slot[h] != UINT32_MAX)
            h = (h + 1) & g->hmask;
        g->slot[h] = (uint32_t)i;
    }
    g->perm = i0;
    i0 = NULL;
    st = TESSEL_OK;
done:
    free(count);
    free(k0);
    free(k1);
    free(i0);
    free(i1);
    if (st != TESSEL_OK)
        tsl_grid_free(g);
    return st;
}

size_t tsl_grid_ring(const tsl_grid *g, const uint32_t cc[3], int ring, uint32_t *run,
                     size_t nrun)
{
    for (int dx = -ring; dx <= ring; dx++)
        for (int dy = -ring; dy <= ring; dy++)
            for (int dz = -ring; dz <= ring; dz++) {
                if (abs(dx) != ring && abs(dy) != ring && abs(dz) != ring)
                    continue;
                int64_t x = (int64_t)cc[0] + dx, y = (int64_t)cc[1] + dy,
                        z = (int64_t)cc[2] + dz;
                if (x < 0 || y < 0 || z < 0 || x >= g->dims[0] || y >= g->dims[1] ||
                    z >= g->dims[2])
                    continue;
                size_t ci = tsl_grid_find(g, tsl_morton((uint32_t)x, (uint32_t)y, (uint32_t)z));
                if (ci == SIZE_MAX)
                    continue;
                run[2 * nrun] = g->start[ci];
                run[2 * nrun + 1] = g->start[ci + 1];
                nrun++;
            }
    return nrun;
}

/* Points of a strided sample per occupied cell of side `cell`: a small
 * open-addressing set (slots entries, a power of two of at least twice
 * the sample, cleared here) of the sample's cell keys. *cells gets the
 * number of occupied cells (of the sample). */
static double sample_per_cell(const float *xyz, size_t n, size_t stride, const double lo[3],
                              double cell, uint64_t *set, size_t slots, size_t *cells)
{
    size_t m = (n + stride - 1) / stride;
    memset(set, 0, slots * sizeof *set);
    size_t used = 0;
    for (size_t i = 0; i < n; i += stride) {
        uint32_t c[3];
        for (int a = 0; a < 3; a++) {
            double v = floor(((double)xyz[3 * i + (size_t)a] - lo[a]) / cell);
            c[a] = v < 0.0 ? 0u : v > 2097151.0 ? 2097151u : (uint32_t)v;
        }
        uint64_t key = tsl_morton(c[0], c[1], c[2]) + 1;
        size_t h = tsl_grid_hash(key) & (slots - 1);
        while (set[h] && set[h] != key)
            h = (h + 1) & (slots - 1);
        if (!set[h]) {
            set[h] = key;
            used++;
        }
    }
    *cells = used;
    return (double)m / (double)used;
}

double tsl_grid_knn_cell(const float *xyz, size_t n, size_t k)
{
    /* At most 2^16 sample points (their box is all that is needed: the
     * cell only has to fit the density); coarse cells that hold 8 to 256
     * of them, so that hardly any occupied cell is missed by the sample
     * and the surface is still nearly flat within one. The first guess is
     * the spacing of n points on a square of the box's extent. */
    size_t stride = n > 65536 ? n / 65536 : 1;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i += stride)
        for (int a = 0; a < 3; a++) {
            double v = xyz[3 * i + (size_t)a];
            lo[a] = v < lo[a] ? v : lo[a];
            hi[a] = v > hi[a] ? v : hi[a];
        }
    double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    if (n < 2 || !(ext > 0.0))
        return 1.0;
    double cell = 8.0 * ext / sqrt((double)n), per = 0.0;
    /* One set for every round (fresh pages for each would cost more than
     * the counting). */
    size_t slots = 64, cells = 0;
    while (slots < 2 * ((n + stride - 1) / stride))
        slots *= 2;
    uint64_t *set = tsl_alloc_array(slots, sizeof *set);
    if (!set)
        return 1.0; /* out of memory: any cell is exact */
    for (int round = 0; round < 40; round++) {
        if (cell > ext) {
            cell = ext;
            per = sample_per_cell(xyz, n, stride, lo, cell, set, slots, &cells);
            break;
        }
        per = sample_per_cell(xyz, n, stride, lo, cell, set, slots, &cells);
        if (per < 8.0 && cells > 1)
            cell *= 2.0;
        else if (per > 256.0 && cell > 1e-30)
            cell *= 0.5;
        else
            break;
    }
    free(set);
    /* Points of the whole cloud per occupied cell, and the density they
     * give (a surface crosses cells of side c with about 2/3 c^2 of its
     * area each), hence the distance to the k-th neighbour. */
    double m = per * (double)n / (double)((n + stride - 1) / stride);
    double rk = cell * sqrt((double)k * (2.0 / 3.0) / (3.141592653589793 * m));
    return rk > 0.0 && isfinite(rk) ? 1.3 * rk : ext;
}
