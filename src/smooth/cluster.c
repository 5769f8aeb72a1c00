/* BSP clustering of a (smoothed) point cloud: Mederos, Velho & de
 * Figueiredo, "Smooth surface reconstruction from noisy clouds" (2003),
 * section 2.2, after Pauly, Gross & Kobbelt 2002. A node's covariance
 * eigenvalues l1 <= l2 <= l3 give its flatness sigma = l1 / (l1 + l2 + l3);
 * a node with more than n_min points and sigma > sigma_max is split by its
 * regression plane (through the centroid, normal to the smallest
 * eigenvector), as in the paper. We add one rule: a node whose points do
 * not all lie within max_diameter/2 of its centroid is split by the plane
 * through the centroid across its largest eigenvector (Pauly's split).
 * Without it a flat region is one cluster with one representative however
 * large it is, and regression-plane splits of a curved cap leave a ring
 * whose centroid (and so its representative) sits at the cap's centre,
 * far from the ring's own points. Leaves are the clusters.
 *
 * Each node is partitioned stably inside one array of points, so every
 * leaf is a contiguous, increasing run of point indices, and leaves ordered
 * by position are the tree's depth-first order. Subtrees run as OpenMP
 * tasks on disjoint ranges; the arithmetic of a node does not depend on
 * which thread runs it, so the result is the same for any thread count. */
#include "smooth/smooth.h"

#include <stdlib.h>
#include <string.h>

/* Nodes smaller than this are not worth a task of their own. */
#define CLUSTER_TASK_MIN 4096u

tessel_cluster_params tessel_cluster_params_default(void)
{
    tessel_cluster_params p;
    memset(&p, 0, sizeof p);
    p.sigma_max = 0.01;
    p.n_min = 10;
    p.max_diameter = 8.0;
    p.spacing = 0.0;
    p.threads = 0;
    return p;
}

void tessel_clusters_free(tessel_clusters *clusters)
{
    if (!clusters)
        return;
    free(clusters->labels);
    free(clusters->order);
    free(clusters->offsets);
    memset(clusters, 0, sizeof *clusters);
}

/* A point as the partition moves it: coordinates next to the index, so a
 * node's passes read one contiguous run instead of gathering through a
 * permutation (the top levels touch every point in random input order). */
typedef struct bsp_point {
    float x[3];
    uint32_t id;
} bsp_point;

typedef struct bsp {
    bsp_point *pts;      /* the points being partitioned */
    bsp_point *scratch;  /* same size, for stable partitions */
    uint8_t *leaf_start; /* leaf_start[i] = 1 where a leaf's run begins */
    double sigma_max;
    double max_r2; /* (max_diameter / 2)^2, world units */
    uint32_t n_min;
} bsp;

/* Decides how node [lo, hi) splits: writes the plane (centroid c, normal
 * dir) and returns true, or returns false for a leaf. */
static bool split_plane(const bsp *b, size_t lo, size_t hi, double c[3], double dir[3])
{
    size_t m = hi - lo;
    if (m < 2)
        return false;
    /* Centroid, then covariance about it (two passes: no cancellation). */
    double s[3] = {0, 0, 0};
    for (size_t i = lo; i < hi; i++) {
        const float *p = b->pts[i].x;
        s[0] += p[0];
        s[1] += p[1];
        s[2] += p[2];
    }
    for (int k = 0; k < 3; k++)
        c[k] = s[k] / (double)m;
    double a[9] = {0}, r2max = 0.0;
    for (size_t i = lo; i < hi; i++) {
        const float *p = b->pts[i].x;
        double x = p[0] - c[0], y = p[1] - c[1], z = p[2] - c[2];
        a[0] += x * x;
        a[1] += x * y;
        a[2] += x * z;
        a[4] += y * y;
        a[5] += y * z;
        a[8] += z * z;
        double r2 = x * x + y * y + z * z;
        if (r2 > r2max)
            r2max = r2;
    }
    a[3] = a[1];
    a[6] = a[2];
    a[7] = a[5];
    double w[3], v[9];
    tsl_eigen_sym3(a, w, v);
    int col;
    if (r2max > b->max_r2) {
        col = 2; /* too wide: cut across the longest axis */
    } else {
        double sum = w[0] + w[1] + w[2];
        double flat = sum > 0.0 ? w[0] / sum : 0.0;
        if (m <= b->n_min || !(flat > b->sigma_max))
            return false;
        col = 0; /* curved: cut by the regression plane */
    }
    dir[0] = v[col];
    dir[1] = v[3 + col];
    dir[2] = v[6 + col];
    return true;
}

/* Stable partition of [lo, hi) by the side of the plane; returns the first
 * index of the positive side. */
static size_t partition(bsp *b, size_t lo, size_t hi, const double c[3], const double dir[3])
{
    size_t neg = 0;
    for (size_t i = lo; i < hi; i++) {
        const float *p = b->pts[i].x;
        double h = (p[0] - c[0]) * dir[0] + (p[1] - c[1]) * dir[1] + (p[2] - c[2]) * dir[2];
        neg += h < 0.0;
    }
    size_t a = lo, z = lo + neg;
    for (size_t i = lo; i < hi; i++) {
        const float *p = b->pts[i].x;
        double h = (p[0] - c[0]) * dir[0] + (p[1] - c[1]) * dir[1] + (p[2] - c[2]) * dir[2];
        b->scratch[h < 0.0 ? a++ : z++] = b->pts[i];
    }
    memcpy(b->pts + lo, b->scratch + lo, (hi - lo) * sizeof *b->pts);
    return lo + neg;
}

/* Splits [lo, hi) until leaves. Recurses into the smaller child and loops
 * on the larger, so the depth stays below log2(n) even for lopsided
 * splits. */
static void build(bsp *b, size_t lo, size_t hi)
{
    for (;;) {
        double c[3], dir[3];
        size_t mid = lo;
        if (split_plane(b, lo, hi, c, dir))
            mid = partition(b, lo, hi, c, dir);
        if (mid == lo || mid == hi) {
            /* A leaf, or a plane that failed to separate (rounding on
             * nearly coincident points): stop here. */
            b->leaf_start[lo] = 1;
            return;
        }
        size_t slo = lo, shi = mid, llo = mid, lhi = hi;
        if (mid - lo > hi - mid) {
            slo = mid, shi = hi, llo = lo, lhi = mid;
        }
        if (shi - slo >= CLUSTER_TASK_MIN) {
#pragma omp task firstprivate(b, slo, shi)
            build(b, slo, shi);
        } else {
            build(b, slo, shi);
        }
        lo = llo;
        hi = lhi;
    }
}

static tessel_status check_params(const tessel_cluster_params *p)
{
    if (!(p->sigma_max >= 0.0) || !(p->sigma_max <= 1.0 / 3.0 + 1e-12))
        return TESSEL_ERR_INVALID_ARG;
    if (p->n_min < 1)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->max_diameter > 0.0)) /* INFINITY is allowed, NaN is not */
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->spacing >= 0.0) || !isfinite(p->spacing))
        return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

tessel_status tessel_cluster(const tessel_cloud *cloud, const tessel_cluster_params *params,
                             const tessel_callbacks *callbacks, tessel_clusters *clusters)
{
    if (!clusters)
        return TESSEL_ERR_INVALID_ARG;
    memset(clusters, 0, sizeof *clusters);
    if (!cloud || (cloud->count > 0 && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_cluster_params p = params ? *params : tessel_cluster_params_default();
    tessel_status st = check_params(&p);
    if (st != TESSEL_OK)
        return st;
    const size_t n = cloud->count;
    if (n == 0)
        return TESSEL_ERR_TOO_FEW_POINTS;
    if (n >= (size_t)TESSEL_NONE)
        return TESSEL_ERR_LIMIT;
    for (size_t i = 0; i < 3 * n; i++)
        if (!isfinite(cloud->xyz[i]))
            return TESSEL_ERR_INVALID_ARG;

    /* The spacing is only needed to scale max_diameter. */
    double h = p.spacing;
    if (h == 0.0 && isfinite(p.max_diameter)) {
        st = tessel_cloud_spacing(cloud, &h);
        if (st != TESSEL_OK)
            return st;
    }
    st = tsl_progress(callbacks, "cluster", 0.0);
    if (st != TESSEL_OK)
        return st;

    bsp b;
    memset(&b, 0, sizeof b);
    b.sigma_max = p.sigma_max;
    b.n_min = p.n_min;
    double rmax = 0.5 * p.max_diameter * h;
    /* h == 0 (all points equal) makes every positive radius 0: coincident
     * points never split on diameter, so this is harmless. */
    b.max_r2 = isfinite(p.max_diameter) ? rmax * rmax : INFINITY;
    b.pts = tsl_alloc_array(n, sizeof *b.pts);
    b.scratch = tsl_alloc_array(n, sizeof *b.scratch);
    b.leaf_start = tsl_calloc_array(n, 1);
    uint32_t *labels = tsl_alloc_array(n, sizeof *labels);
    uint32_t *order = NULL;
    if (!b.pts || !b.scratch || !b.leaf_start || !labels) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    for (size_t i = 0; i < n; i++) {
        memcpy(b.pts[i].x, cloud->xyz + 3 * i, sizeof b.pts[i].x);
        b.pts[i].id = (uint32_t)i;
    }

    bsp *bp = &b;
#pragma omp parallel num_threads(tsl_threads(p.threads))
#pragma omp single
    build(bp, 0, n);
    free(b.scratch);
    b.scratch = NULL;
    order = tsl_alloc_array(n, sizeof *order);
    if (!order) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }

    size_t count = 0;
    for (size_t i = 0; i < n; i++)
        count += b.leaf_start[i];
    size_t *offsets = tsl_alloc_array(count + 1, sizeof *offsets);
    if (!offsets) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    size_t c = 0;
    for (size_t i = 0; i < n; i++) {
        if (b.leaf_start[i])
            offsets[c++] = i;
        order[i] = b.pts[i].id;
        labels[order[i]] = (uint32_t)(c - 1);
    }
    offsets[count] = n;

    clusters->point_count = n;
    clusters->count = count;
    clusters->labels = labels;
    clusters->order = order;
    clusters->offsets = offsets;
    clusters->spacing = h;
    labels = NULL;
    order = NULL;
    st = tsl_progress(callbacks, "cluster", 1.0);
    if (st != TESSEL_OK)
        tessel_clusters_free(clusters);

done:
    free(b.pts);
    free(b.scratch);
    free(order);
    free(b.leaf_start);
    free(labels);
    return st;
}
