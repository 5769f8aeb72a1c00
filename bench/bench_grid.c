/* The alternative we measured before settling on the kd-tree: exact k-nearest
 * neighbours on a uniform grid (hashed cells, points sorted by cell, shells
 * of cells searched outwards until the k-th distance is inside the searched
 * block). Compared with tessel_index on the same queries, one thread, CPU
 * time, best of three; results checked equal. docs/neighbours.md has the
 * figures. The library does not use this code.
 *
 * Usage: bench_grid [FILE.ply...]   (default: torus samples, 10^5 and 10^6)
 * The grid's cell size is chosen for a target mean occupancy of the
 * non-empty cells (2, 4 and 8 points are tried). */
#include "tessel.h"

#include "bench_data.h"

#include <stdbool.h>

typedef struct gpoint {
    float x[3];
    uint32_t id;
} gpoint;

typedef struct grid {
    float lo[3], h, inv_h;
    gpoint *pts;         /* sorted by cell */
    uint64_t *keys;      /* hash slots: cell key + 1, 0 = empty */
    uint32_t *start, *count;
    size_t mask;
} grid;

static uint64_t cell_key(int64_t i, int64_t j, int64_t k)
{
    return ((uint64_t)i << 42) | ((uint64_t)j << 21) | (uint64_t)k;
}

static size_t hash64(uint64_t x)
{
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdull;
    x ^= x >> 33;
    return (size_t)x;
}

static int cmp_u64pair(const void *a, const void *b)
{
    const uint64_t *x = a, *y = b;
    return x[0] < y[0] ? -1 : x[0] > y[0] ? 1 : (x[1] < y[1] ? -1 : x[1] > y[1]);
}

/* Cell of every point, sorted; returns the number of distinct cells. */
static size_t sort_cells(const float *xyz, size_t n, const float lo[3], float inv_h,
                         uint64_t *kv)
{
    for (size_t i = 0; i < n; i++) {
        int64_t c[3];
        for (int a = 0; a < 3; a++)
            c[a] = (int64_t)((xyz[3 * i + a] - lo[a]) * inv_h);
        kv[2 * i] = cell_key(c[0], c[1], c[2]);
        kv[2 * i + 1] = i;
    }
    qsort(kv, n, 2 * sizeof *kv, cmp_u64pair);
    size_t cells = 0;
    for (size_t i = 0; i < n; i++)
        cells += i == 0 || kv[2 * i] != kv[2 * i - 2];
    return cells;
}

static void grid_build(grid *g, const float *xyz, size_t n, double occupancy)
{
    float hi[3];
    for (int a = 0; a < 3; a++)
        g->lo[a] = hi[a] = xyz[a];
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float v = xyz[3 * i + a];
            g->lo[a] = v < g->lo[a] ? v : g->lo[a];
            hi[a] = v > hi[a] ? v : hi[a];
        }
    double vol = 1.0;
    for (int a = 0; a < 3; a++)
        vol *= (double)(hi[a] - g->lo[a]) + 1e-9;
    uint64_t *kv = malloc(n * 2 * sizeof *kv);
    /* Volume-uniform guess, then one correction assuming the points lie on
     * a surface (occupancy grows as h^2). */
    double h = cbrt(vol / (double)n);
    size_t cells = sort_cells(xyz, n, g->lo, (float)(1.0 / h), kv);
    h *= sqrt(occupancy / ((double)n / (double)cells));
    g->h = (float)h;
    g->inv_h = (float)(1.0 / h);
    cells = sort_cells(xyz, n, g->lo, g->inv_h, kv);

    size_t slots = 16;
    while (slots < 2 * cells)
        slots *= 2;
    g->mask = slots - 1;
    g->keys = calloc(slots, sizeof *g->keys);
    g->start = malloc(slots * sizeof *g->start);
    g->count = malloc(slots * sizeof *g->count);
    g->pts = malloc(n * sizeof *g->pts);
    for (size_t i = 0; i < n; i++) {
        size_t src = (size_t)kv[2 * i + 1];
        for (int a = 0; a < 3; a++)
            g->pts[i].x[a] = xyz[3 * src + a];
        g->pts[i].id = (uint32_t)src;
        if (i == 0 || kv[2 * i] != kv[2 * i - 2]) {
            size_t s = hash64(kv[2 * i]) & g->mask;
            while (g->keys[s])
                s = (s + 1) & g->mask;
            g->keys[s] = kv[2 * i] + 1;
            g->start[s] = (uint32_t)i;
            g->count[s] = 0;
        }
        size_t s = hash64(kv[2 * i]) & g->mask;
        while (g->keys[s] != kv[2 * i] + 1)
            s = (s + 1) & g->mask;
        g->count[s]++;
    }
    free(kv);
}

static void grid_free(grid *g)
{
    free(g->pts);
    free(g->keys);
    free(g->start);
    free(g->count);
}

static inline void insert(float *d, uint32_t *id, size_t k, size_t *cnt, float dd,
                          uint32_t ii)
{
    size_t pos;
    if (*cnt < k)
        pos = (*cnt)++;
    else if (dd < d[k - 1] || (dd == d[k - 1] && ii < id[k - 1]))
        pos = k - 1;
    else
        return;
    while (pos > 0 && (dd < d[pos - 1] || (dd == d[pos - 1] && ii < id[pos - 1]))) {
        d[pos] = d[pos - 1];
        id[pos] = id[pos - 1];
        pos--;
    }
    d[pos] = dd;
    id[pos] = ii;
}

static void scan_cell(const grid *g, int64_t i, int64_t j, int64_t k, const float q[3],
                      float *d, uint32_t *id, size_t kk, size_t *cnt)
{
    if (i < 0 || j < 0 || k < 0)
        return;
    uint64_t key = cell_key(i, j, k) + 1;
    size_t s = hash64(key - 1) & g->mask;
    while (g->keys[s] && g->keys[s] != key)
        s = (s + 1) & g->mask;
    if (!g->keys[s])
        return;
    const gpoint *p = g->pts + g->start[s];
    for (uint32_t t = 0; t < g->count[s]; t++) {
        float dx = p[t].x[0] - q[0], dy = p[t].x[1] - q[1], dz = p[t].x[2] - q[2];
        float dd = (dx * dx + dy * dy) + dz * dz;
        if (*cnt < kk || dd <= d[kk - 1])
            insert(d, id, kk, cnt, dd, p[t].id);
    }
}

/* Exact knn: shells of cells at Chebyshev distance r = 0, 1, ... until the
 * k-th distance is within the searched block's distance. */
static size_t grid_knn(const grid *g, size_t n, const float q[3], size_t k, uint32_t *id,
                       float *d)
{
    int64_t c[3];
    float margin = INFINITY;
    for (int a = 0; a < 3; a++) {
        float f = (q[a] - g->lo[a]) * g->inv_h;
        c[a] = (int64_t)f;
        float frac = f - (float)c[a];
        float m = (frac < 1.0f - frac ? frac : 1.0f - frac) * g->h;
        margin = m < margin ? m : margin;
    }
    size_t cnt = 0, want = k < n ? k : n;
    for (int64_t r = 0;; r++) {
        for (int64_t i = -r; i <= r; i++)
            for (int64_t j = -r; j <= r; j++) {
                bool edge = i == -r || i == r || j == -r || j == r;
                for (int64_t l = -r; l <= r; l += edge ? 1 : 2 * r)
                    scan_cell(g, c[0] + i, c[1] + j, c[2] + l, q, d, id, want, &cnt);
            }
        float reach = (float)r * g->h + margin;
        if (cnt == want && d[want - 1] < reach * reach * 0.9999f)
            return cnt;
        if ((double)r * g->h > 4e3)
            return cnt;
    }
}

static void compare(const char *name, const float *xyz, size_t n)
{
    static const size_t ks[3] = {8, 16, 32};
    uint32_t *ia = malloc(n * 32 * sizeof *ia), *ib = malloc(n * 32 * sizeof *ib);
    float *da = malloc(n * 32 * sizeof *da), *db = malloc(n * 32 * sizeof *db);
    double tb = 1e30, tq[3] = {1e30, 1e30, 1e30};
    for (int run = 0; run < 3; run++) {
        tessel_index *ix = NULL;
        double t0 = bench_cpu_now();
        tessel_index_build(&ix, xyz, n);
        double t1 = bench_cpu_now();
        tb = t1 - t0 < tb ? t1 - t0 : tb;
        for (int ki = 0; ki < 3; ki++) {
            t0 = bench_cpu_now();
            tessel_index_knn_batch(ix, xyz, n, ks[ki], ia, da, 1);
            t1 = bench_cpu_now();
            tq[ki] = t1 - t0 < tq[ki] ? t1 - t0 : tq[ki];
        }
        tessel_index_destroy(ix);
    }
    printf("%-20s %9zu kd-tree          build %.3f s  knn/s k=8 %9.0f  k=16 %9.0f  "
           "k=32 %9.0f\n",
           name, n, tb, n / tq[0], n / tq[1], n / tq[2]);
    static const double occ[3] = {2.0, 4.0, 8.0};
    for (int oi = 0; oi < 3; oi++) {
        double gb = 1e30, gq[3] = {1e30, 1e30, 1e30};
        size_t mismatches = 0;
        for (int run = 0; run < 3; run++) {
            grid g;
            double t0 = bench_cpu_now();
            grid_build(&g, xyz, n, occ[oi]);
            double t1 = bench_cpu_now();
            gb = t1 - t0 < gb ? t1 - t0 : gb;
            for (int ki = 0; ki < 3; ki++) {
                size_t k = ks[ki];
                t0 = bench_cpu_now();
                for (size_t i = 0; i < n; i++)
                    grid_knn(&g, n, xyz + 3 * i, k, ib + i * k, db + i * k);
                t1 = bench_cpu_now();
                gq[ki] = t1 - t0 < gq[ki] ? t1 - t0 : gq[ki];
                if (run == 0) {
                    tessel_index *ix = NULL;
                    tessel_index_build(&ix, xyz, n);
                    tessel_index_knn_batch(ix, xyz, n, k, ia, da, 1);
                    tessel_index_destroy(ix);
                    mismatches += memcmp(ia, ib, n * k * sizeof *ia) != 0;
                }
            }
            grid_free(&g);
        }
        printf("%-20s %9zu grid, %g per cell build %.3f s  knn/s k=8 %9.0f  k=16 %9.0f  "
               "k=32 %9.0f%s\n",
               name, n, occ[oi], gb, n / gq[0], n / gq[1], n / gq[2],
               mismatches ? "  RESULTS DIFFER" : "");
        fflush(stdout);
    }
    free(ia);
    free(ib);
    free(da);
    free(db);
}

int main(int argc, char **argv)
{
    printf("one thread, CPU seconds, best of 3; queries = every point\n");
    for (int i = 1; i < argc; i++) {
        size_t n;
        float *xyz = bench_read_ply(argv[i], &n);
        if (!xyz)
            return 1;
        const char *base = strrchr(argv[i], '/');
        compare(base ? base + 1 : argv[i], xyz, n);
        free(xyz);
    }
    if (argc < 2) {
        for (size_t n = 100000; n <= 1000000; n *= 10) {
            float *xyz = bench_torus(n, 42);
            char name[32];
            snprintf(name, sizeof name, "torus-%zu", n);
            compare(name, xyz, n);
            free(xyz);
        }
    }
    return 0;
}
