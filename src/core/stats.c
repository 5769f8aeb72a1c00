/* Cloud statistics and clean-up: bounding box, nearest-neighbour spacing
 * (the unit of every "multiple of the spacing" parameter), exact duplicates,
 * isolated outliers, and merging of duplicates.
 *
 * Exact duplicates are found with a hash table on the coordinates (O(n)),
 * so a cloud made mostly of copies of a few points costs no more than any
 * other. Spacing and density are then measured on the distinct points only:
 * a duplicate's nearest neighbour at distance 0 says nothing about sampling
 * density. The outlier test is the statistical outlier filter of Rusu et
 * al. ("Towards 3D point cloud based object maps for household
 * environments", RAS 2008, sec. 4): mean distance to the k nearest
 * neighbours against the cloud-wide distribution, here relative to its
 * median (robust to the outliers themselves). Merging with a tolerance is
 * greedy in input order: each point not yet merged keeps its place and
 * absorbs every later point closer than the tolerance, so the kept points
 * are at least the tolerance apart and the result does not depend on the
 * thread count. */
#include "core/grid.h"

#include <stdlib.h>
#include <string.h>

/* Largest k for the density test (the queries keep results on the stack). */
#define OUTLIER_K_MAX 256

tessel_stats_params tessel_stats_params_default(void)
{
    tessel_stats_params p;
    p.sample_size = 100000;
    p.outlier_k = 8;
    p.outlier_factor = 5.0;
    p.threads = 0;
    return p;
}

static bool cloud_ok(const tessel_cloud *cloud)
{
    if (!cloud || (cloud->count > 0 && !cloud->xyz))
        return false;
    for (size_t i = 0; i < 3 * cloud->count; i++)
        if (!isfinite(cloud->xyz[i]))
            return false;
    return true;
}

/* ---- exact duplicates ---- */

static inline uint32_t float_bits(float v)
{
    uint32_t u;
    v += 0.0f; /* -0 becomes +0: they compare equal, so they must hash equal */
    memcpy(&u, &v, sizeof u);
    return u;
}

static inline uint64_t point_hash(const float *p)
{
    uint64_t h = float_bits(p[0]);
    h = h * 0x9E3779B97F4A7C15ull ^ float_bits(p[1]);
    h = h * 0x9E3779B97F4A7C15ull ^ float_bits(p[2]);
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    return h ^ (h >> 32);
}

/* rep[i] = the first index whose point equals point i (i itself for first
 * occurrences). Open addressing, table of at least 2n slots. Returns the
 * number of distinct points in *distinct. */
static tessel_status exact_representatives(const float *xyz, size_t n, uint32_t *rep,
                                           size_t *distinct)
{
    size_t slots = 16;
    while (slots < 2 * n) {
        if (slots > SIZE_MAX / 4)
            return TESSEL_ERR_NOMEM;
        slots *= 2;
    }
    uint32_t *table = tsl_alloc_array(slots, sizeof *table);
    if (!table)
        return TESSEL_ERR_NOMEM;
    memset(table, 0xff, slots * sizeof *table); /* TESSEL_NONE */
    size_t mask = slots - 1, count = 0;
    for (size_t i = 0; i < n; i++) {
        const float *p = xyz + 3 * i;
        size_t s = (size_t)point_hash(p) & mask;
        for (;;) {
            uint32_t j = table[s];
            if (j == TESSEL_NONE) {
                table[s] = (uint32_t)i;
                rep[i] = (uint32_t)i;
                count++;
                break;
            }
            const float *o = xyz + 3 * (size_t)j;
            if (o[0] == p[0] && o[1] == p[1] && o[2] == p[2]) {
                rep[i] = j;
                break;
            }
            s = (s + 1) & mask;
        }
    }
    free(table);
    *distinct = count;
    return TESSEL_OK;
}

/* ---- medians ---- */

/* Value of rank k (0-based) of a[0..n), reordering a. Quickselect with a
 * median-of-three pivot; a pass budget falls back to qsort. */
static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static float select_float(float *a, size_t n, size_t k)
{
    size_t lo = 0, hi = n; /* answer in [lo, hi) */
    int budget = 64;
    while (hi - lo > 16) {
        if (budget-- == 0) {
            qsort(a + lo, hi - lo, sizeof *a, cmp_float);
            return a[k];
        }
        size_t mid = lo + (hi - lo) / 2;
        float x = a[lo], y = a[mid], z = a[hi - 1];
        float pivot = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
        size_t i = lo, j = hi - 1;
        for (;;) {
            while (a[i] < pivot)
                i++;
            while (a[j] > pivot)
                j--;
            if (i >= j)
                break;
            float t = a[i];
            a[i] = a[j];
            a[j] = t;
            i++;
            j--;
        }
        /* [lo, j] <= pivot <= [j+1, hi) */
        if (k <= j)
            hi = j + 1;
        else
            lo = j + 1;
    }
    qsort(a + lo, hi - lo, sizeof *a, cmp_float);
    return a[k];
}

/* Median (mean of the two middle values for even n), reordering a. */
static double median_float(float *a, size_t n)
{
    if (n == 0)
        return 0.0;
    size_t h = n / 2;
    double upper = select_float(a, n, h);
    if (n % 2)
        return upper;
    /* After selecting rank h, a[0..h) holds the h smallest values. */
    float lower = a[0];
    for (size_t i = 1; i < h; i++)
        lower = a[i] > lower ? a[i] : lower;
    return 0.5 * ((double)lower + upper);
}

/* ---- distinct points and their index ---- */

typedef struct distinct_set {
    size_t count;       /* distinct points */
    float *xyz;         /* count*3, in first-occurrence order */
    uint32_t *mult;     /* copies of each distinct point (>= 1) */
    tessel_index *index;
    size_t duplicates;  /* cloud->count - count */
} distinct_set;

static void distinct_free(distinct_set *d)
{
    tessel_index_destroy(d->index);
    free(d->xyz);
    free(d->mult);
    memset(d, 0, sizeof *d);
}

static tessel_status distinct_build(const tessel_cloud *cloud, distinct_set *d)
{
    memset(d, 0, sizeof *d);
    size_t n = cloud->count;
    uint32_t *rep = tsl_alloc_array(n, sizeof *rep);
    if (!rep)
        return TESSEL_ERR_NOMEM;
    size_t m = 0;
    tessel_status st = exact_representatives(cloud->xyz, n, rep, &m);
    if (st == TESSEL_OK) {
        d->xyz = tsl_alloc_array(m, 3 * sizeof *d->xyz);
        d->mult = tsl_calloc_array(m, sizeof *d->mult);
        if (!d->xyz || !d->mult)
            st = TESSEL_ERR_NOMEM;
    }
    if (st == TESSEL_OK) {
        /* Reuse rep: a first occurrence's slot becomes its distinct number. */
        size_t next = 0;
        for (size_t i = 0; i < n; i++) {
            if (rep[i] == i) {
                memcpy(d->xyz + 3 * next, cloud->xyz + 3 * i, 3 * sizeof(float));
                d->mult[next] = 1;
                rep[i] = (uint32_t)next++;
            } else {
                d->mult[rep[rep[i]]]++;
            }
        }
        d->count = m;
        d->duplicates = n - m;
        st = tessel_index_build(&d->index, d->xyz, m);
    }
    free(rep);
    if (st != TESSEL_OK)
        distinct_free(d);
    return st;
}

/* Nearest-neighbour distances beyond this many medians are isolated points
 * (stray returns, far outliers): left out of the mean, which a single point
 * 10^5 spacings away would otherwise double on a cloud of 10^5 points. The
 * shared scans, range scans included, stay below 20. */
#define SPACING_OUTLIER_MEDIANS 32.0

/* The s-th of m evenly strided picks among count (always < count): the
 * spacing sample, which spacing_of and tsl_grid_spacing must draw alike
 * for their values to agree. */
static inline size_t sample_pick(size_t s, size_t count, size_t m)
{
    return (size_t)((double)s * (double)count / (double)m);
}

/* Median of the sample's nearest-neighbour distances dist[0 .. m) (sorted:
 * scratch of m), and their mean without isolated points. */
static void spacing_stats(const float *dist, float *sorted, size_t m, double *mean,
                          double *median)
{
    memcpy(sorted, dist, m * sizeof *dist);
    *median = median_float(sorted, m);
    double limit = SPACING_OUTLIER_MEDIANS * *median, sum = 0.0;
    size_t used = 0;
    for (size_t s = 0; s < m; s++)
        if (dist[s] <= limit) {
            sum += dist[s];
            used++;
        }
    *mean = used ? sum / (double)used : 0.0;
}

/* Mean (without isolated points) and median distance from evenly strided
 * distinct points to their nearest distinct neighbour; both 0 when there
 * are fewer than two. */
static tessel_status spacing_of(const distinct_set *d, size_t sample_size, int threads,
                                double *mean, double *median)
{
    *mean = *median = 0.0;
    if (d->count < 2)
        return TESSEL_OK;
    size_t m = sample_size == 0 ? 1 : sample_size;
    if (m > d->count)
        m = d->count;
    float *dist = tsl_alloc_array(m, sizeof *dist);
    float *sorted = tsl_alloc_array(m, sizeof *sorted);
    uint32_t *slot = tsl_alloc_array(d->count, sizeof *slot);
    uint32_t *order = tsl_alloc_array(d->count, sizeof *order);
    if (!dist || !sorted || !slot || !order) {
        free(dist);
        free(sorted);
        free(slot);
        free(order);
        return TESSEL_ERR_NOMEM;
    }
    /* The sample, evenly strided. It is queried in the
     * index's storage order, so that consecutive queries walk the same
     * part of the tree (at 10^6 points the tree does not fit in cache and
     * queries in input order wait on memory); each result goes to its
     * sample's slot, so the sums below see the same order as before. */
    for (size_t i = 0; i < d->count; i++)
        slot[i] = UINT32_MAX;
    for (size_t s = 0; s < m; s++)
        slot[sample_pick(s, d->count, m)] = (uint32_t)s;
    tsl_index_order(d->index, order);
    size_t nq = 0;
    for (size_t j = 0; j < d->count; j++)
        if (slot[order[j]] != UINT32_MAX)
            order[nq++] = order[j];
    ptrdiff_t ms = (ptrdiff_t)nq;
    int nthreads = tsl_threads(threads);
    (void)nthreads;
#pragma omp parallel for schedule(dynamic, 256) num_threads(nthreads)
    for (ptrdiff_t q = 0; q < ms; q++) {
        size_t i = order[q];
        uint32_t idx[2];
        float d2[2];
        tessel_index_knn(d->index, d->xyz + 3 * i, 2, idx, d2);
        dist[slot[i]] = sqrtf(d2[1]);
    }
    free(slot);
    free(order);
    spacing_stats(dist, sorted, m, mean, median);
    free(sorted);
    free(dist);
    return TESSEL_OK;
}

/* Distinct points whose mean distance to their k nearest distinct
 * neighbours exceeds factor times the median of that mean; each counts with
 * its copies. */
static tessel_status outliers_of(const distinct_set *d, uint32_t k, double factor,
                                 int threads, size_t *outliers)
{
    *outliers = 0;
    if (d->count <= k)
        return TESSEL_OK;
    float *mean = tsl_alloc_array(d->count, sizeof *mean);
    float *sorted = tsl_alloc_array(d->count, sizeof *sorted);
    uint32_t *order = tsl_alloc_array(d->count, sizeof *order);
    if (!mean || !sorted || !order) {
        free(mean);
        free(sorted);
        free(order);
        return TESSEL_ERR_NOMEM;
    }
    /* Queries in the index's storage order run faster (warm caches). */
    tsl_index_order(d->index, order);
    ptrdiff_t n = (ptrdiff_t)d->count;
    int nthreads = tsl_threads(threads);
    (void)nthreads;
#pragma omp parallel for schedule(dynamic, 256) num_threads(nthreads)
    for (ptrdiff_t t = 0; t < n; t++) {
        size_t i = order[t];
        uint32_t idx[OUTLIER_K_MAX + 1];
        float d2[OUTLIER_K_MAX + 1];
        size_t got = tessel_index_knn(d->index, d->xyz + 3 * i, k + 1, idx, d2);
        double sum = 0.0;
        for (size_t j = 1; j < got; j++) /* entry 0 is the point itself */
            sum += sqrt((double)d2[j]);
        mean[i] = (float)(sum / (double)(got - 1));
    }
    free(order);
    memcpy(sorted, mean, d->count * sizeof *mean);
    double limit = factor * median_float(sorted, d->count);
    size_t count = 0;
    for (size_t i = 0; i < d->count; i++)
        if ((double)mean[i] > limit)
            count += d->mult[i];
    *outliers = count;
    free(mean);
    free(sorted);
    return TESSEL_OK;
}

tessel_status tessel_cloud_stats_compute(const tessel_cloud *cloud,
                                         const tessel_stats_params *params,
                                         tessel_cloud_stats *stats)
{
    if (!stats)
        return TESSEL_ERR_INVALID_ARG;
    memset(stats, 0, sizeof *stats);
    tessel_stats_params p = params ? *params : tessel_stats_params_default();
    if (!cloud_ok(cloud) || p.outlier_k == 0 || p.outlier_k > OUTLIER_K_MAX ||
        !(p.outlier_factor > 0.0))
        return TESSEL_ERR_INVALID_ARG;
    if (cloud->count == 0)
        return TESSEL_ERR_TOO_FEW_POINTS;

    float mn[3], mx[3];
    for (int a = 0; a < 3; a++)
        mn[a] = mx[a] = cloud->xyz[a];
    for (size_t i = 1; i < cloud->count; i++)
        for (int a = 0; a < 3; a++) {
            float v = cloud->xyz[3 * i + a];
            mn[a] = v < mn[a] ? v : mn[a];
            mx[a] = v > mx[a] ? v : mx[a];
        }
    double diag2 = 0.0;
    for (int a = 0; a < 3; a++) {
        stats->bbox_min[a] = cloud->offset[a] + (double)mn[a];
        stats->bbox_max[a] = cloud->offset[a] + (double)mx[a];
        double e = (double)mx[a] - (double)mn[a];
        diag2 += e * e;
    }
    stats->diagonal = sqrt(diag2);

    distinct_set d;
    tessel_status st = distinct_build(cloud, &d);
    if (st != TESSEL_OK)
        return st;
    stats->exact_duplicates = d.duplicates;
    st = spacing_of(&d, p.sample_size, p.threads, &stats->mean_spacing,
                    &stats->median_spacing);
    if (st == TESSEL_OK)
        st = outliers_of(&d, p.outlier_k, p.outlier_factor, p.threads, &stats->outliers);
    distinct_free(&d);
    return st;
}

/* Rings of cells a nearest-neighbour search on the grid looks through
 * before it leaves the point to the kd-tree: the cells are several
 * spacings wide, so only isolated points (far outliers, the grid then
 * stretched by them) need more. */
#define SPACING_MAX_RING 3

/* One ring of nearest_distinct_d2's search. */
typedef struct nearest_scan {
    const tsl_grid *g;
    const float *q;
    float best;
    bool any; /* some cell of the ring may hold a nearer point */
} nearest_scan;

static void nearest_cell(void *ctx, int64_t x, int64_t y, int64_t z)
{
    nearest_scan *c = ctx;
    const tsl_grid *g = c->g;
    const float *q = c->q;
    if (tsl_grid_box_d2(g, q, x, y, z) > c->best)
        return;
    c->any = true;
    size_t ci = tsl_grid_find(g, tsl_morton((uint32_t)x, (uint32_t)y, (uint32_t)z));
    if (ci == SIZE_MAX)
        return;
    for (uint32_t t = g->start[ci]; t < g->start[ci + 1]; t++) {
        const float *p = g->sxyz + 3 * (size_t)t;
        if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2])
            continue;
        float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
        float d = (dx * dx + dy * dy) + dz * dz;
        c->best = d < c->best ? d : c->best;
    }
}

/* Squared distance from point q to the nearest point of g with other
 * coordinates: rings of cells around q's until no cell beyond can hold a
 * nearer one (tsl_grid_box_d2 rounds down). The distances are those of the
 * kd-tree (same float expression), so the minimum is the same value;
 * INFINITY when every point equals q, NAN when SPACING_MAX_RING rings do
 * not settle it. */
static float nearest_distinct_d2(const tsl_grid *g, const float *q)
{
    uint32_t cc[3] = {tsl_grid_cell(g, q, 0), tsl_grid_cell(g, q, 1), tsl_grid_cell(g, q, 2)};
    nearest_scan c = {g, q, INFINITY, false};
    for (int64_t ring = 0; ring <= SPACING_MAX_RING; ring++) {
        c.any = false;
        tsl_grid_shell(g, cc, ring, nearest_cell, &c);
        if (!c.any && ring > 0)
            return c.best;
    }
    return NAN;
}

/* A point of a crowded cell: coordinates and sorted position. */
typedef struct run_point {
    float x[3];
    uint32_t t;
} run_point;

static int cmp_run_point(const void *a, const void *b)
{
    const run_point *p = a, *q = b;
    for (int c = 0; c < 3; c++)
        if (p->x[c] != q->x[c])
            return p->x[c] < q->x[c] ? -1 : 1;
    return (p->t > q->t) - (p->t < q->t);
}

/* Cells holding more points than this sort them to find their copies. */
#define FIRST_SCAN_MAX 64

/* is_first[i] = 1 when no point of smaller index equals point i (the
 * distinct points of exact_representatives). Equal points share a cell,
 * whose run keeps increasing index order, so each cell is settled on its
 * own: in parallel, reading the grid's sorted copy in order. */
static tessel_status grid_first_occurrences(const tsl_grid *g, int threads, uint8_t *is_first)
{
    long long ncell = (long long)g->ncell;
    const float *xyz = g->sxyz;
    size_t big_len = 0; /* the most points in a crowded cell */
    for (size_t c = 0; c < g->ncell; c++) {
        size_t len = g->start[c + 1] - g->start[c];
        if (len > FIRST_SCAN_MAX && len > big_len)
            big_len = len;
    }
    (void)threads;
#pragma omp parallel for schedule(dynamic, 1024) num_threads(tsl_threads(threads))
    for (long long c = 0; c < ncell; c++) {
        size_t b = g->start[c], e = g->start[c + 1];
        if (e - b > FIRST_SCAN_MAX)
            continue;
        for (size_t t = b; t < e; t++) {
            const float *p = xyz + 3 * t;
            uint8_t first = 1;
            for (size_t u = b; u < t && first; u++) {
                const float *q = xyz + 3 * u;
                first = !(q[0] == p[0] && q[1] == p[1] && q[2] == p[2]);
            }
            is_first[g->perm[t]] = first;
        }
    }
    if (big_len) {
        /* Crowded cells (many copies of one point): sorted, serially. */
        run_point *big = tsl_alloc_array(big_len, sizeof *big);
        if (!big)
            return TESSEL_ERR_NOMEM;
        for (size_t c = 0; c < g->ncell; c++) {
            size_t b = g->start[c], len = g->start[c + 1] - b;
            if (len <= FIRST_SCAN_MAX)
                continue;
            for (size_t j = 0; j < len; j++) {
                memcpy(big[j].x, xyz + 3 * (b + j), sizeof big[j].x);
                big[j].t = (uint32_t)(b + j);
            }
            qsort(big, len, sizeof *big, cmp_run_point);
            for (size_t j = 0; j < len; j++) {
                const float *p = big[j].x, *q = j ? big[j - 1].x : NULL;
                is_first[g->perm[big[j].t]] =
                    !q || !(q[0] == p[0] && q[1] == p[1] && q[2] == p[2]);
            }
        }
        free(big);
    }
    return TESSEL_OK;
}

tessel_status tsl_grid_spacing(const tsl_grid *g, const float *xyz, size_t n, int threads,
                               double *spacing)
{
    *spacing = 0.0;
    if (n < 2)
        return TESSEL_ERR_TOO_FEW_POINTS;
    tessel_stats_params p = tessel_stats_params_default();
    uint32_t *first = tsl_alloc_array(n, sizeof *first);
    uint32_t *slot = tsl_alloc_array(n, sizeof *slot);
    uint8_t *is_first = tsl_alloc_array(n, 1);
    size_t d = 0;
    tessel_status st = first && slot && is_first ? grid_first_occurrences(g, threads, is_first)
                                                 : TESSEL_ERR_NOMEM;
    float *dist = NULL, *sorted = NULL;
    size_t m = 0;
    if (st == TESSEL_OK) {
        /* The first occurrences in order: the distinct points as
         * distinct_build lists them. */
        for (size_t i = 0; i < n; i++)
            if (is_first[i])
                first[d++] = (uint32_t)i;
        m = p.sample_size < d ? p.sample_size : d;
        dist = tsl_alloc_array(m ? m : 1, sizeof *dist);
        sorted = tsl_alloc_array(m ? m : 1, sizeof *sorted);
        if (!dist || !sorted)
            st = TESSEL_ERR_NOMEM;
    }
    if (st == TESSEL_OK && d >= 2) {
        /* The sample of spacing_of, queried in the grid's order (nearby
         * queries in a row find their cells in cache). */
        for (size_t i = 0; i < n; i++)
            slot[i] = UINT32_MAX;
        for (size_t s = 0; s < m; s++)
            slot[first[sample_pick(s, d, m)]] = (uint32_t)s;
        size_t nq = 0;
        for (size_t t = 0; t < n; t++) {
            uint32_t i = g->perm[t];
            if (slot[i] != UINT32_MAX)
                first[nq++] = (uint32_t)t;
        }
        long long count = (long long)nq;
#pragma omp parallel for schedule(dynamic, 256) num_threads(tsl_threads(threads))
        for (long long k = 0; k < count; k++) {
            uint32_t t = first[k];
            dist[slot[g->perm[t]]] = sqrtf(nearest_distinct_d2(g, g->sxyz + 3 * (size_t)t));
        }
        /* Points the rings did not settle: the kd-tree of spacing_of. */
        size_t open = 0;
        for (size_t k = 0; k < m; k++)
            open += isnan(dist[k]);
        distinct_set ds;
        if (open && (st = distinct_build(&(tessel_cloud){.count = n, .xyz = (float *)xyz},
                                         &ds)) == TESSEL_OK) {
            for (size_t k = 0; k < nq; k++) {
                const float *q = g->sxyz + 3 * (size_t)first[k];
                float *dk = &dist[slot[g->perm[first[k]]]];
                if (!isnan(*dk))
                    continue;
                uint32_t idx[2];
                float d2[2];
                tessel_index_knn(ds.index, q, 2, idx, d2);
                *dk = sqrtf(d2[1]);
            }
            distinct_free(&ds);
        }
        double mean, median;
        if (st == TESSEL_OK) {
            spacing_stats(dist, sorted, m, &mean, &median);
            *spacing = mean;
        }
    }
    free(first);
    free(slot);
    free(is_first);
    free(dist);
    free(sorted);
    if (st == TESSEL_OK && !(*spacing > 0.0))
        st = TESSEL_ERR_TOO_FEW_POINTS;
    return st;
}

tessel_status tessel_cloud_spacing(const tessel_cloud *cloud, double *spacing)
{
    if (!spacing)
        return TESSEL_ERR_INVALID_ARG;
    *spacing = 0.0;
    if (!cloud_ok(cloud))
        return TESSEL_ERR_INVALID_ARG;
    if (cloud->count < 2)
        return TESSEL_ERR_TOO_FEW_POINTS;
    tessel_stats_params p = tessel_stats_params_default();
    distinct_set d;
    tessel_status st = distinct_build(cloud, &d);
    if (st != TESSEL_OK)
        return st;
    double mean = 0.0, median = 0.0;
    st = spacing_of(&d, p.sample_size, p.threads, &mean, &median);
    distinct_free(&d);
    if (st != TESSEL_OK)
        return st;
    /* All points equal: there is no spacing to measure lengths in. */
    if (!(mean > 0.0))
        return TESSEL_ERR_TOO_FEW_POINTS;
    *spacing = mean;
    return TESSEL_OK;
}

/* ---- merging ---- */

/* keep[i] = index of the point that absorbs point i (i itself if kept),
 * greedy in input order with radius queries. */
static tessel_status merge_map_tolerance(const tessel_cloud *cloud, double tolerance,
                                         uint32_t *keep)
{
    tessel_index *ix = NULL;
    tessel_status st = tessel_index_build(&ix, cloud->xyz, cloud->count);
    if (st != TESSEL_OK)
        return st;
    size_t cap = 64;
    uint32_t *idx = tsl_alloc_array(cap, sizeof *idx);
    float *d2 = tsl_alloc_array(cap, sizeof *d2);
    float r = (float)tolerance;
    float r2 = r * r;
    for (size_t i = 0; i < cloud->count; i++)
        keep[i] = TESSEL_NONE;
    for (size_t i = 0; i < cloud->count && idx && d2; i++) {
        if (keep[i] != TESSEL_NONE)
            continue;
        keep[i] = (uint32_t)i;
        const float *q = cloud->xyz + 3 * i;
        size_t total = tessel_index_radius(ix, q, r, idx, d2, cap);
        if (total > cap) {
            /* Grow to fit every neighbour, then ask again. */
            size_t ncap = total;
            free(idx);
            free(d2);
            idx = tsl_alloc_array(ncap, sizeof *idx);
            d2 = tsl_alloc_array(ncap, sizeof *d2);
            if (!idx || !d2)
                break;
            cap = ncap;
            total = tessel_index_radius(ix, q, r, idx, d2, cap);
        }
        for (size_t j = 0; j < total; j++)
            if (d2[j] < r2 && idx[j] > i && keep[idx[j]] == TESSEL_NONE)
                keep[idx[j]] = (uint32_t)i;
    }
    if (!idx || !d2)
        st = TESSEL_ERR_NOMEM;
    free(idx);
    free(d2);
    tessel_index_destroy(ix);
    return st;
}

tessel_status tessel_cloud_merge_duplicates(tessel_cloud *cloud, double tolerance,
                                            size_t *removed)
{
    if (removed)
        *removed = 0;
    if (!cloud_ok(cloud) || !(tolerance >= 0.0) || !isfinite(tolerance))
        return TESSEL_ERR_INVALID_ARG;
    size_t n = cloud->count;
    if (n < 2)
        return TESSEL_OK;
    uint32_t *keep = tsl_alloc_array(n, sizeof *keep);
    if (!keep)
        return TESSEL_ERR_NOMEM;
    tessel_status st;
    if (tolerance == 0.0) {
        size_t distinct;
        st = exact_representatives(cloud->xyz, n, keep, &distinct);
    } else {
        st = merge_map_tolerance(cloud, tolerance, keep);
    }
    if (st != TESSEL_OK) {
        free(keep);
        return st;
    }
    /* Compact in place, keeping order; keep[] becomes old -> new index. */
    size_t next = 0;
    for (size_t i = 0; i < n; i++) {
        if (keep[i] != i) {
            keep[i] = keep[keep[i]]; /* the absorber comes first: already new */
            continue;
        }
        if (next != i) {
            memmove(cloud->xyz + 3 * next, cloud->xyz + 3 * i, 3 * sizeof(float));
            if (cloud->normals)
                memmove(cloud->normals + 3 * next, cloud->normals + 3 * i,
                        3 * sizeof(float));
            if (cloud->rgb)
                memmove(cloud->rgb + 3 * next, cloud->rgb + 3 * i, 3);
        }
        keep[i] = (uint32_t)next++;
    }
    /* An organized cell whose point was merged now shows the point that
     * absorbed it, so the grid keeps its coverage. */
    if (cloud->grid) {
        size_t cells = (size_t)cloud->width * cloud->height;
        for (size_t c = 0; c < cells; c++)
            if (cloud->grid[c] != TESSEL_NONE && cloud->grid[c] < n)
                cloud->grid[c] = keep[cloud->grid[c]];
    }
    free(keep);
    size_t gone = n - next;
    cloud->count = next;
    if (gone > 0 && next > 0) {
        /* Give memory back; failure to shrink is harmless. */
        float *x = realloc(cloud->xyz, next * 3 * sizeof(float));
        if (x)
            cloud->xyz = x;
        if (cloud->normals) {
            float *nn = realloc(cloud->normals, next * 3 * sizeof(float));
            if (nn)
                cloud->normals = nn;
        }
        if (cloud->rgb) {
            uint8_t *c = realloc(cloud->rgb, next * 3);
            if (c)
                cloud->rgb = c;
        }
    }
    if (removed)
        *removed = gone;
    return TESSEL_OK;
}
