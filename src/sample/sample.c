/* Points drawn uniformly over a mesh's area, with optional isotropic
 * Gaussian noise: the dense inputs of real shapes that benches and tests
 * need (what users do in CloudCompare or meshlab).
 *
 * A point picks its triangle with probability proportional to its area
 * (binary search in the prefix sums of the areas, taken in index order),
 * then a uniform point of the triangle (Turk 1990, "Generating random
 * points in triangles": with r1 = sqrt(u1), (1 - r1) a + r1 (1 - u2) b +
 * r1 u2 c), then noise from the Box-Muller transform. The random numbers
 * come from xoshiro256** (Blackman & Vigna 2018), one stream per block of
 * BLOCK points seeded by splitmix64 from the seed and the block's number:
 * the same seed gives the same points for any thread count. */
#include "core/core.h"

#include <stdlib.h>
#include <string.h>

#define BLOCK 65536

tessel_sample_params tessel_sample_params_default(void)
{
    tessel_sample_params p;
    memset(&p, 0, sizeof p);
    p.noise = 0.0;
    p.noise_rel = 0.0;
    p.seed = 1;
    p.normals = 1;
    p.threads = 0;
    return p;
}

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

typedef struct rng {
    uint64_t s[4];
} rng;

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static uint64_t rng_next(rng *r)
{
    uint64_t *s = r->s;
    uint64_t out = rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return out;
}

/* Uniform in [0, 1), 53 bits. */
static inline double rng_unit(rng *r) { return (double)(rng_next(r) >> 11) * 0x1.0p-53; }

static void rng_seed(rng *r, uint64_t seed, uint64_t block)
{
    uint64_t x = seed ^ (block * 0xD1B54A32D192ED03ULL);
    for (int i = 0; i < 4; i++)
        r->s[i] = splitmix64(&x);
}

/* Two independent standard normal numbers (Box-Muller). */
static void gauss2(rng *r, double out[2])
{
    double u = 1.0 - rng_unit(r); /* (0, 1]: log is finite */
    double v = rng_unit(r);
    double m = sqrt(-2.0 * log(u)), a = 2.0 * acos(-1.0) * v;
    out[0] = m * cos(a);
    out[1] = m * sin(a);
}

static void corner(const tessel_mesh *m, uint32_t v, double out[3])
{
    tsl_load(m->xyz + 3 * (size_t)v, out);
}

/* Prefix sums of the triangles' areas (twice the area, in index order:
 * the same sums on any machine); *total their sum. Triangles with an
 * index out of range are an error. */
static tessel_status area_sums(const tessel_mesh *m, double **out, double *total)
{
    size_t nt = m->triangle_count;
    double *cum = tsl_alloc_array(nt, sizeof *cum);
    if (!cum)
        return TESSEL_ERR_NOMEM;
    double sum = 0.0;
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *v = m->triangles + 3 * t;
        if (v[0] >= m->vertex_count || v[1] >= m->vertex_count || v[2] >= m->vertex_count) {
            free(cum);
            return TESSEL_ERR_INVALID_ARG;
        }
        double a[3], b[3], c[3], u[3], w[3], n[3];
        corner(m, v[0], a);
        corner(m, v[1], b);
        corner(m, v[2], c);
        tsl_sub(b, a, u);
        tsl_sub(c, a, w);
        tsl_cross(u, w, n);
        double area = tsl_norm(n);
        sum += isfinite(area) ? area : 0.0;
        cum[t] = sum;
    }
    *out = cum;
    *total = sum;
    return TESSEL_OK;
}

/* The first triangle whose prefix sum exceeds x (x < total). */
static size_t pick(const double *cum, size_t nt, double x)
{
    size_t lo = 0, hi = nt - 1;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cum[mid] > x)
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

static double mesh_diagonal(const tessel_mesh *m)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < m->vertex_count; v++)
        for (int k = 0; k < 3; k++) {
            double x = m->xyz[3 * v + k];
            lo[k] = x < lo[k] ? x : lo[k];
            hi[k] = x > hi[k] ? x : hi[k];
        }
    double d[3];
    tsl_sub(hi, lo, d);
    return m->vertex_count ? tsl_norm(d) : 0.0;
}

/* The points of block b: [b BLOCK, min(count, (b + 1) BLOCK)). */
static void sample_block(const tessel_mesh *m, const double *cum, double total, double sigma,
                         uint64_t seed, size_t b, size_t count, tessel_cloud *out)
{
    rng r;
    rng_seed(&r, seed, (uint64_t)b);
    size_t end = (b + 1) * (size_t)BLOCK < count ? (b + 1) * (size_t)BLOCK : count;
    for (size_t i = b * (size_t)BLOCK; i < end; i++) {
        size_t t = pick(cum, m->triangle_count, rng_unit(&r) * total);
        double r1 = sqrt(rng_unit(&r)), u2 = rng_unit(&r);
        double a[3], bb[3], c[3], p[3];
        const uint32_t *v = m->triangles + 3 * t;
        corner(m, v[0], a);
        corner(m, v[1], bb);
        corner(m, v[2], c);
        for (int k = 0; k < 3; k++)
            p[k] = (1.0 - r1) * a[k] + r1 * (1.0 - u2) * bb[k] + r1 * u2 * c[k];
        if (sigma > 0.0) {
            double g[4];
            gauss2(&r, g);
            gauss2(&r, g + 2);
            for (int k = 0; k < 3; k++)
                p[k] += sigma * g[k];
        }
        for (int k = 0; k < 3; k++)
            out->xyz[3 * i + k] = (float)p[k];
        if (out->normals) {
            double u[3], w[3], n[3];
            tsl_sub(bb, a, u);
            tsl_sub(c, a, w);
            tsl_cross(u, w, n);
            tsl_normalize(n);
            for (int k = 0; k < 3; k++)
                out->normals[3 * i + k] = (float)n[k];
        }
    }
}

tessel_status tessel_mesh_sample(const tessel_mesh *mesh, size_t count,
                                 const tessel_sample_params *params,
                                 const tessel_callbacks *callbacks, tessel_cloud *out)
{
    if (!out)
        return TESSEL_ERR_INVALID_ARG;
    memset(out, 0, sizeof *out);
    tessel_sample_params p = params ? *params : tessel_sample_params_default();
    if (!mesh || (mesh->vertex_count && !mesh->xyz) || (mesh->triangle_count && !mesh->triangles) ||
        count == 0 || !(p.noise >= 0.0) || !isfinite(p.noise) || !(p.noise_rel >= 0.0) ||
        !isfinite(p.noise_rel))
        return TESSEL_ERR_INVALID_ARG;
    if (count >= UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    double *cum = NULL, total = 0.0;
    tessel_status st = mesh->triangle_count ? area_sums(mesh, &cum, &total) : TESSEL_OK;
    if (st != TESSEL_OK)
        return st;
    if (!(total > 0.0) || !isfinite(total)) {
        free(cum);
        return TESSEL_ERR_TOO_FEW_POINTS; /* nothing to sample on */
    }
    double sigma = p.noise > 0.0 ? p.noise : p.noise_rel * mesh_diagonal(mesh);
    if ((st = tessel_cloud_alloc(out, count, p.normals != 0, false))) {
        free(cum);
        return st;
    }
    memcpy(out->offset, mesh->offset, sizeof out->offset);
    size_t blocks = (count + BLOCK - 1) / BLOCK, done = 0;
    int threads = tsl_threads(p.threads);
    (void)threads;
    /* In rounds, so that progress and cancellation are heard. */
    size_t round = 16 * (size_t)threads;
    st = tsl_progress(callbacks, "sample", 0.0);
    for (size_t b0 = 0; b0 < blocks && st == TESSEL_OK; b0 += round) {
        size_t b1 = b0 + round < blocks ? b0 + round : blocks;
        long long n = (long long)(b1 - b0);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
        for (long long b = 0; b < n; b++)
            sample_block(mesh, cum, total, sigma, p.seed, b0 + (size_t)b, count, out);
        done = b1;
        st = tsl_progress(callbacks, "sample", (double)done / (double)blocks);
    }
    free(cum);
    if (st != TESSEL_OK)
        tessel_cloud_free(out);
    return st;
}
