/* Noise of a cloud, from the cloud alone: how far its points stray from
 * the surface they sample, and how densely they sample it.
 *
 * Around each of a set of seed points spread over the cloud, its K nearest
 * neighbours (a ball of radius R) fix a tangent frame (PCA). The points of
 * a narrow cylinder about the seed's axis, of radius rho = R sqrt(C / K)
 * so that it holds about C points, get a least-squares quadric height
 * field z = a + b u + c v + d u^2 + e uv + f v^2, and the variance of
 * their residuals, RSS / (count - 6), estimates sigma^2 at that seed. The
 * quadric takes up the tilt of the frame and the surface's curvature
 * (what is left is third order in rho, far below the noise at C points),
 * and the cylinder runs through the whole ball, so its heights are cut
 * only beyond H = sqrt(R^2 - rho^2): a seed counts when H >= SLAB sigma,
 * where the cut takes under 0.01% of the variance. This is the residual
 * estimator of local fits (Mitra, Nguyen & Guibas 2004, "Estimating
 * surface normals in noisy point cloud data", section 3) with the
 * curvature fitted rather than bounded. sigma is the median over the
 * seeds (robust to seeds on edges and thin parts, where one quadric does
 * not fit). When too few balls reach above the noise, the cloud is
 * subsampled four times coarser and the balls grow accordingly. The
 * surface density is the neighbours' count over the area of their ball.
 *
 * Large clouds are estimated on a subsample of at most SUBSAMPLE points
 * (chosen by a hash of the index, so that scan order does not alias):
 * sigma does not depend on the density, and the density is scaled back.
 * The result does not depend on the thread count. */
#include "core/core.h"

#include <stdlib.h>
#include <string.h>

#define SUBSAMPLE ((size_t)1 << 18)
#define SEEDS 1024
#define MIN_SEEDS 64 /* fewer seeds with a slab: no estimate */
#define BALL 1024    /* the largest ball */
#define K_MIN 64     /* the smallest */
#define CYLINDER 48  /* C, at most half the ball */
#define MIN_FIT 24   /* fewer points in a cylinder: no estimate there */
#define SLAB 3.0

/* Points beyond TRIM residual standard deviations are left out of the
 * next fit, at most TRIM_ROUNDS times; a Gaussian within +-3 sigma keeps
 * TRIM_VARIANCE of its variance. */
#define TRIM 3.0
#define TRIM_ROUNDS 6
#define TRIM_VARIANCE 0.97334

static uint64_t mix64(uint64_t z)
{
    z += 0x9E3779B97F4A7C15ULL;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* About `want` points of c (all when it has fewer), chosen by a hash of
 * their index, copied; *m of them. NULL on failure. */
static float *subsample(const tessel_cloud *c, size_t want, size_t *m)
{
    size_t n = c->count;
    uint64_t limit = want >= n ? UINT64_MAX : (uint64_t)((double)want / (double)n * 0x1.0p64);
    size_t count = 0;
    for (size_t i = 0; i < n; i++)
        count += mix64(i) <= limit;
    float *xyz = tsl_alloc_array(count ? count : 1, 3 * sizeof *xyz);
    if (!xyz)
        return NULL;
    size_t j = 0;
    for (size_t i = 0; i < n; i++)
        if (mix64(i) <= limit)
            memcpy(xyz + 3 * j++, c->xyz + 3 * i, 3 * sizeof *xyz);
    *m = count;
    return xyz;
}

/* Solves the symmetric 6x6 system a x = b (Gaussian elimination with
 * partial pivoting); false when it is singular. */
static bool solve6(double a[6][6], double b[6], double x[6])
{
    for (int c = 0; c < 6; c++) {
        int p = c;
        for (int r = c + 1; r < 6; r++)
            if (fabs(a[r][c]) > fabs(a[p][c]))
                p = r;
        if (!(fabs(a[p][c]) > 1e-300))
            return false;
        if (p != c) {
            for (int k = 0; k < 6; k++) {
                double t = a[c][k];
                a[c][k] = a[p][k];
                a[p][k] = t;
            }
            double t = b[c];
            b[c] = b[p];
            b[p] = t;
        }
        for (int r = c + 1; r < 6; r++) {
            double f = a[r][c] / a[c][c];
            for (int k = c; k < 6; k++)
                a[r][k] -= f * a[c][k];
            b[r] -= f * b[c];
        }
    }
    for (int c = 5; c >= 0; c--) {
        double s = b[c];
        for (int k = c + 1; k < 6; k++)
            s -= a[c][k] * x[k];
        x[c] = s / a[c][c];
    }
    return true;
}

bool tsl_height_fit(const float *xyz, const float q[3], const uint32_t *idx, size_t k,
                    double rho2, double *work, tsl_height *out)
{
    double c[3] = {0.0, 0.0, 0.0}, m[9] = {0};
    for (size_t i = 0; i < k; i++)
        for (int a = 0; a < 3; a++)
            c[a] += xyz[3 * (size_t)idx[i] + a];
    for (int a = 0; a < 3; a++)
        c[a] /= (double)k;
    for (size_t i = 0; i < k; i++) {
        const float *p = xyz + 3 * (size_t)idx[i];
        double d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                m[3 * a + b] += d[a] * d[b];
    }
    double w[3], v[9];
    tsl_eigen_sym3(m, w, v);
    double e[3][3];
    for (int a = 0; a < 3; a++)
        for (int r = 0; r < 3; r++)
            e[a][r] = v[3 * r + (2 - a)]; /* e[2]: the smallest eigenvalue's vector */
    size_t n = 0;
    for (size_t i = 0; i < k; i++) {
        const float *p = xyz + 3 * (size_t)idx[i];
        double d[3] = {(double)p[0] - q[0], (double)p[1] - q[1], (double)p[2] - q[2]};
        double u = tsl_dot(d, e[0]), t = tsl_dot(d, e[1]);
        if (u * u + t * t > rho2)
            continue;
        work[4 * n] = u;
        work[4 * n + 1] = t;
        work[4 * n + 2] = tsl_dot(d, e[2]);
        work[4 * n + 3] = 0.0; /* squared residual of the last fit */
        n++;
    }
    if (n < MIN_FIT)
        return false;
    /* Least squares in scaled coordinates (u, v in units of rho), then
     * again without the points beyond TRIM residuals (another sheet within
     * the ball: the far wall of a thin tube), until none is dropped. */
    double s = 1.0 / sqrt(rho2), limit2 = INFINITY, sigma2 = 0.0, x[6];
    size_t kept = n;
    for (int round = 0; round < TRIM_ROUNDS; round++) {
        double A[6][6] = {{0}}, B[6] = {0};
        size_t used = 0;
        for (size_t i = 0; i < n; i++) {
            double u = work[4 * i] * s, t = work[4 * i + 1] * s, z = work[4 * i + 2];
            if (work[4 * i + 3] > limit2)
                continue;
            double f[6] = {1.0, u, t, u * u, u * t, t * t};
            for (int a = 0; a < 6; a++) {
                for (int b = 0; b < 6; b++)
                    A[a][b] += f[a] * f[b];
                B[a] += f[a] * z;
            }
            used++;
        }
        if (used < MIN_FIT || !solve6(A, B, x))
            return false;
        double rss = 0.0;
        size_t within = 0;
        for (size_t i = 0; i < n; i++) {
            double u = work[4 * i] * s, t = work[4 * i + 1] * s, z = work[4 * i + 2];
            double r = z - (x[0] + x[1] * u + x[2] * t + x[3] * u * u + x[4] * u * t +
                            x[5] * t * t);
            bool in = work[4 * i + 3] <= limit2;
            work[4 * i + 3] = r * r;
            if (in)
                rss += r * r;
        }
        /* A fit on the points within +-TRIM sigma sees TRIM_VARIANCE of
         * the variance. */
        sigma2 = rss / (double)(used - 6) / (round ? TRIM_VARIANCE : 1.0);
        limit2 = TRIM * TRIM * sigma2;
        for (size_t i = 0; i < n; i++)
            within += work[4 * i + 3] <= limit2;
        if (round && within == kept)
            break;
        kept = within;
    }
    out->var = sigma2;
    out->inliers = kept;
    out->height = x[0];
    out->scale = s;
    for (int a = 0; a < 3; a++) {
        out->normal[a] = e[2][a];
        out->frame[0][a] = e[0][a];
        out->frame[1][a] = e[1][a];
    }
    memcpy(out->coef, x, sizeof x);
    return true;
}

double tsl_height_offset(const tsl_height *h, const double d[3])
{
    double u = tsl_dot(d, h->frame[0]) * h->scale, t = tsl_dot(d, h->frame[1]) * h->scale;
    const double *x = h->coef;
    return x[0] + x[1] * u + x[2] * t + x[3] * u * u + x[4] * u * t + x[5] * t * t -
           tsl_dot(d, h->normal);
}

enum { SEED_NONE, SEED_NOISY, SEED_SLAB };

/* One seed's estimate at the smallest ball (K_MIN, 2 K_MIN, ... k nearest)
 * whose cylinder reaches above the noise: *var and *density there.
 * Returns SEED_SLAB, SEED_NOISY when no ball reaches above the noise, or
 * SEED_NONE when it has too few neighbours. */
static int seed_estimate(const tessel_index *ix, const float *xyz, const float q[3], size_t k,
                         uint32_t *idx, float *d2, double *work, double *var, double *density)
{
    int why = SEED_NONE;
    /* Each ball queried as it is reached: a clean cloud's first ball
     * settles it, and a query costs with its size. The K nearest come in
     * order of distance, then index, so each ball holds the same points in
     * the same order as a prefix of one query of k would. */
    for (size_t K = K_MIN; K <= k; K = 2 * K < k && 2 * K > K ? 2 * K : (K == k ? k + 1 : k)) {
        if (tessel_index_knn(ix, q, K, idx, d2) < K)
            return SEED_NONE;
        double R2 = (double)d2[K - 1];
        size_t C = K / 2 < CYLINDER ? K / 2 : CYLINDER;
        double rho2 = R2 * (double)C / (double)K;
        tsl_height fit;
        if (!tsl_height_fit(xyz, q, idx, K, rho2, work, &fit))
            continue;
        double v = fit.var;
        size_t in = fit.inliers;
        if (R2 - rho2 < SLAB * SLAB * v) {
            why = SEED_NOISY;
            continue;
        }
        *var = v;
        /* The surface's points in the cylinder (within +-TRIM sigma: all
         * but 0.27%) over its cross-section. */
        *density = (double)in / 0.9973 / (acos(-1.0) * rho2);
        return SEED_SLAB;
    }
    return why;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of a[0 .. n) (sorts a). */
static double median(double *a, size_t n)
{
    qsort(a, n, sizeof *a, cmp_double);
    return n % 2 ? a[n / 2] : 0.5 * (a[n / 2 - 1] + a[n / 2]);
}

/* The estimate on a subsample of xyz (m points): the medians of sigma^2
 * and of the density (points per area of their ball) over the seeds that
 * see a slab (*used of them); *noisy: more seeds found no ball reaching
 * above the noise than found a slab (a coarser subsample has wider
 * balls). */
static tessel_status estimate_on(const float *xyz, size_t m, int threads, double *sigma2,
                                 double *density, size_t *used, bool *noisy)
{
    *sigma2 = *density = 0.0;
    *noisy = false;
    *used = 0;
    size_t k = m - 1 < BALL ? m - 1 : BALL;
    size_t seeds = m < SEEDS ? m : SEEDS;
    tessel_index *ix = NULL;
    tessel_status st = tessel_index_build(&ix, xyz, m);
    double *var = tsl_alloc_array(seeds, sizeof *var);
    double *dens = tsl_alloc_array(seeds, sizeof *dens);
    uint8_t *flag = tsl_calloc_array(seeds, 1); /* SEED_* */
    if (st == TESSEL_OK && (!var || !dens || !flag))
        st = TESSEL_ERR_NOMEM;
    bool nomem = false;
    long long ns = (long long)seeds;
    if (st == TESSEL_OK) {
#pragma omp parallel num_threads(tsl_threads(threads)) reduction(|| : nomem)
        {
            uint32_t *idx = tsl_alloc_array(k, sizeof *idx);
            float *d2 = tsl_alloc_array(k, sizeof *d2);
            double *work = tsl_alloc_array(k, 4 * sizeof *work);
            nomem = !idx || !d2 || !work;
#pragma omp for schedule(dynamic, 8)
            for (long long s = 0; s < ns; s++) {
                if (nomem)
                    continue;
                const float *q = xyz + 3 * (size_t)((double)s * (double)m / (double)seeds);
                flag[s] = (uint8_t)seed_estimate(ix, xyz, q, k, idx, d2, work, &var[s], &dens[s]);
            }
            free(idx);
            free(d2);
            free(work);
        }
        if (nomem)
            st = TESSEL_ERR_NOMEM;
    }
    if (st == TESSEL_OK) {
        size_t noise_bound = 0, n = 0;
        for (size_t s = 0; s < seeds; s++) {
            noise_bound += flag[s] == SEED_NOISY;
            if (flag[s] == SEED_SLAB) {
                var[n] = var[s];
                dens[n] = dens[s];
                n++;
            }
        }
        *noisy = noise_bound > n;
        *used = n;
        if (n) {
            *sigma2 = median(var, n);
            *density = median(dens, n);
        }
    }
    tessel_index_destroy(ix);
    free(var);
    free(dens);
    free(flag);
    return st;
}

tessel_status tessel_cloud_noise(const tessel_cloud *cloud, int threads,
                                 tessel_noise_estimate *out)
{
    if (!cloud || !out || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    memset(out, 0, sizeof *out);
    if (cloud->count < 2 * MIN_FIT)
        return TESSEL_ERR_TOO_FEW_POINTS;
    tessel_status st = TESSEL_OK;
    double sigma2 = 0.0, density = 0.0;
    bool noisy = false;
    size_t want = SUBSAMPLE, m = 0, used = 0;
    for (;;) {
        float *xyz = subsample(cloud, want, &m);
        if (!xyz)
            return TESSEL_ERR_NOMEM;
        st = m > 2 * MIN_FIT ? estimate_on(xyz, m, threads, &sigma2, &density, &used, &noisy)
                             : TESSEL_ERR_TOO_FEW_POINTS;
        free(xyz);
        if (st != TESSEL_OK)
            return st;
        /* Coarser while most balls stay inside the noise. */
        if (!noisy || want / 4 < 4 * BALL)
            break;
        want = (m < want ? m : want) / 4;
    }
    if (used < MIN_SEEDS)
        return TESSEL_ERR_TOO_FEW_POINTS;
    out->sigma = sqrt(sigma2);
    out->samples = used;
    density *= (double)cloud->count / (double)m;
    out->surface_spacing = density > 0.0 ? 1.0 / sqrt(density) : 0.0;
    out->noise_ratio = out->surface_spacing > 0.0 ? out->sigma / out->surface_spacing : 0.0;
    return TESSEL_OK;
}
