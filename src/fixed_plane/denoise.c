/* Denoising along the rays of a scan from one position, before the
 * fixed-plane modes mesh it: a range scanner's noise lies along its lines
 * of sight (Gopi & Krishnan 2002, section 5), so each point keeps its ray
 * and only its range changes. Around each point, its k nearest neighbours
 * get a plane by iteratively reweighted least squares (Gaussian weights on
 * the distance, scale twice the neighbourhood's mean spacing, and on the
 * height above the current plane, scale twice the noise, so that a surface
 * across a depth step does not pull); the point moves along its ray onto
 * that plane, by at most MAX_MOVE noise sigmas, which keeps points at
 * steps and grazing angles from running off; a second pass over the moved
 * points smooths further (on the synthetic room scan, normal consistency
 * against the true room 0.64 as scanned, 0.86 after one pass, 0.92 after
 * two). The noise is the cloud's own estimate (tessel_cloud_noise) unless
 * given. Each pass computes every point from the positions it starts with,
 * so the result does not depend on the thread count. */
#include "fixed_plane/fixed_plane.h"

#include <stdlib.h>
#include <string.h>

#define MAX_K 256
#define IRLS_ROUNDS 4
#define MAX_MOVE 3.0

tessel_ray_denoise_params tessel_ray_denoise_params_default(void)
{
    tessel_ray_denoise_params p;
    memset(&p, 0, sizeof p);
    p.k = 0;
    p.passes = 2;
    p.noise = 0.0;
    p.use_viewpoint = 0;
    p.threads = 0;
    return p;
}

/* The new position of point i (xyz, with its neighbours idx[0 .. k)) on
 * its ray from vp. */
static void denoise_point(const float *xyz, size_t i, const uint32_t *idx, const float *d2,
                          size_t k, const double vp[3], double sigma, float out[3])
{
    double q[3];
    tsl_load(xyz + 3 * i, q);
    memcpy(out, xyz + 3 * i, 3 * sizeof *out);
    double mean_d2 = 0.0;
    for (size_t j = 0; j < k; j++)
        mean_d2 += d2[j];
    mean_d2 /= (double)k;
    double inv_w = 1.0 / (2.0 * mean_d2 + 1e-300), inv_h = 1.0 / (2.0 * (2.0 * sigma) * (2.0 * sigma));
    double n[3] = {0.0, 0.0, 0.0}, c[3] = {q[0], q[1], q[2]};
    bool have = false;
    for (int round = 0; round < IRLS_ROUNDS; round++) {
        double W = 0.0, s[3] = {0.0, 0.0, 0.0};
        double w[MAX_K];
        for (size_t j = 0; j < k; j++) {
            double p[3];
            tsl_load(xyz + 3 * (size_t)idx[j], p);
            double wj = exp(-(double)d2[j] * inv_w);
            if (have) {
                double e[3];
                tsl_sub(p, c, e);
                double h = tsl_dot(e, n);
                wj *= exp(-h * h * inv_h);
            }
            w[j] = wj;
            W += wj;
            for (int a = 0; a < 3; a++)
                s[a] += wj * p[a];
        }
        if (!(W > 0.0))
            return;
        double cn[3] = {s[0] / W, s[1] / W, s[2] / W}, m[9] = {0};
        for (size_t j = 0; j < k; j++) {
            double p[3], e[3];
            tsl_load(xyz + 3 * (size_t)idx[j], p);
            tsl_sub(p, cn, e);
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++)
                    m[3 * a + b] += w[j] * e[a] * e[b];
        }
        double ev[3], vec[9];
        tsl_eigen_sym3(m, ev, vec);
        for (int a = 0; a < 3; a++)
            n[a] = vec[3 * a];
        memcpy(c, cn, sizeof c);
        have = tsl_normalize(n);
        if (!have)
            return;
    }
    /* Along the ray vp -> q onto the plane (c, n). */
    double d[3], e[3];
    tsl_sub(q, vp, d);
    if (!tsl_normalize(d))
        return;
    double dn = tsl_dot(d, n);
    tsl_sub(c, q, e);
    double h = tsl_dot(e, n);
    if (fabs(dn) < 1e-3)
        return;
    double t = h / dn, lim = MAX_MOVE * sigma;
    t = t > lim ? lim : t < -lim ? -lim : t;
    for (int a = 0; a < 3; a++)
        out[a] = (float)(q[a] + t * d[a]);
}

/* One pass: every point from the positions the pass starts with. */
static tessel_status denoise_pass(tessel_cloud *cloud, size_t k, const double vp[3],
                                  double sigma, int threads)
{
    tessel_index *ix = NULL;
    float *out = tsl_alloc_array(cloud->count, 3 * sizeof *out);
    tessel_status st = out ? tessel_index_build(&ix, cloud->xyz, cloud->count) : TESSEL_ERR_NOMEM;
    if (st != TESSEL_OK) {
        free(out);
        return st;
    }
    bool nomem = false;
    long long n = (long long)cloud->count;
#pragma omp parallel num_threads(tsl_threads(threads)) reduction(|| : nomem)
    {
        uint32_t *idx = tsl_alloc_array(k + 1, sizeof *idx);
        float *d2 = tsl_alloc_array(k + 1, sizeof *d2);
        nomem = !idx || !d2;
#pragma omp for schedule(dynamic, 1024)
        for (long long i = 0; i < n; i++) {
            if (nomem)
                continue;
            size_t got = tessel_index_knn(ix, cloud->xyz + 3 * (size_t)i, k + 1, idx, d2);
            /* The point itself comes first: its neighbours after it. */
            if (got > 1)
                denoise_point(cloud->xyz, (size_t)i, idx + 1, d2 + 1, got - 1, vp, sigma,
                              out + 3 * (size_t)i);
            else
                memcpy(out + 3 * (size_t)i, cloud->xyz + 3 * (size_t)i, 3 * sizeof *out);
        }
        free(idx);
        free(d2);
    }
    tessel_index_destroy(ix);
    if (nomem) {
        free(out);
        return TESSEL_ERR_NOMEM;
    }
    free(cloud->xyz);
    cloud->xyz = out;
    return TESSEL_OK;
}

tessel_status tessel_denoise_along_rays(tessel_cloud *cloud, const tessel_ray_denoise_params *params,
                                        tessel_ray_denoise_stats *stats)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!cloud || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_ray_denoise_params p = params ? *params : tessel_ray_denoise_params_default();
    if (p.k > MAX_K || p.passes < 1 || p.passes > 10 || !(p.noise >= 0.0) || !isfinite(p.noise))
        return TESSEL_ERR_INVALID_ARG;
    double vp[3] = {0.0, 0.0, 0.0};
    if (p.use_viewpoint) {
        memcpy(vp, p.viewpoint, sizeof vp);
    } else if (cloud->has_viewpoint) {
        memcpy(vp, cloud->viewpoint, sizeof vp);
    } else {
        return TESSEL_ERR_INVALID_ARG; /* no rays without a viewpoint */
    }
    for (int a = 0; a < 3; a++)
        vp[a] -= cloud->offset[a];
    if (cloud->count < 16)
        return TESSEL_ERR_TOO_FEW_POINTS;
    double sigma = p.noise, hs = 0.0;
    tessel_status st = TESSEL_OK;
    if (!(sigma > 0.0) || p.k == 0) {
        tessel_noise_estimate e;
        if ((st = tessel_cloud_noise(cloud, p.threads, &e)) != TESSEL_OK)
            return st;
        if (!(sigma > 0.0))
            sigma = e.sigma;
        hs = e.surface_spacing;
    }
    /* Enough neighbours to average the noise down, over a disc of about
     * three noise sigmas (16 to 64). */
    size_t k = p.k;
    if (k == 0) {
        double r = 3.0 * sigma, want = hs > 0.0 ? acos(-1.0) * r * r / (hs * hs) : 16.0;
        k = want < 16.0 ? 16 : want > 64.0 ? 64 : (size_t)want;
    }
    if (k > cloud->count - 1)
        k = cloud->count - 1;
    if (stats) {
        stats->noise = sigma;
        stats->k = (uint32_t)k;
    }
    if (!(sigma > 0.0))
        return TESSEL_OK; /* nothing to remove */
    float *orig = tsl_alloc_array(cloud->count, 3 * sizeof *orig);
    if (!orig)
        return TESSEL_ERR_NOMEM;
    memcpy(orig, cloud->xyz, cloud->count * 3 * sizeof *orig);
    for (uint32_t pass = 0; pass < p.passes && st == TESSEL_OK; pass++)
        st = denoise_pass(cloud, k, vp, sigma, p.threads);
    if (st != TESSEL_OK) {
        free(orig);
        return st;
    }
    double moved = 0.0;
    for (size_t i = 0; i < cloud->count; i++) {
        double a[3], b[3], e[3];
        tsl_load(orig + 3 * i, a);
        tsl_load(cloud->xyz + 3 * i, b);
        tsl_sub(b, a, e);
        moved += tsl_dot(e, e);
    }
    free(orig);
    if (stats)
        stats->rms_move = sqrt(moved / (double)cloud->count);
    return TESSEL_OK;
}
