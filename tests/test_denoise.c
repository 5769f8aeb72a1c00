/* Denoising along the rays (src/fixed_plane/denoise.c): a noisy scan of
 * two parallel walls with a depth step between them, seen from one point.
 * The points stay on their rays, get closer to their wall, and the step
 * stays a step; the same bits for any thread count. */
#include "surfaces.h"
#include "tessel.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 200
#define H 150

/* Rays from the origin through a W x H grid on z = 1; the left half hits
 * the wall z = 2, the right half z = 3; range noise sigma along the ray. */
static tessel_status scan(tessel_cloud *c, double sigma, float *truth)
{
    tessel_status st = tessel_cloud_alloc(c, (size_t)W * H, 0, 0);
    if (st)
        return st;
    surf_rng r = surf_seed(9);
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            size_t k = (size_t)j * W + i;
            double d[3] = {(i - W / 2) / (double)W, (j - H / 2) / (double)W, 1.0};
            double z = i < W / 2 ? 2.0 : 3.0, len = sqrt(d[0] * d[0] + d[1] * d[1] + 1.0);
            double t = z * len + sigma * surf_gauss(&r); /* range */
            for (int a = 0; a < 3; a++) {
                c->xyz[3 * k + a] = (float)(d[a] / len * t);
                truth[3 * k + a] = (float)(d[a] * z);
            }
        }
    c->has_viewpoint = 1;
    return TESSEL_OK;
}

/* RMS distance of the points from their walls (z = 2 or 3) and the
 * largest distance of a point from its ray. */
static void errors(const tessel_cloud *c, const float *truth, double *rms, double *off_ray)
{
    double s = 0.0, worst = 0.0;
    for (size_t k = 0; k < c->count; k++) {
        const float *p = c->xyz + 3 * k, *q = truth + 3 * k;
        double e = (double)p[2] - q[2];
        s += e * e;
        /* |p x q| / |q|: distance of p from the ray through q. */
        double x[3] = {(double)p[1] * q[2] - (double)p[2] * q[1],
                       (double)p[2] * q[0] - (double)p[0] * q[2],
                       (double)p[0] * q[1] - (double)p[1] * q[0]};
        double dq = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        double off = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / dq;
        worst = off > worst ? off : worst;
    }
    *rms = sqrt(s / (double)c->count);
    *off_ray = worst;
}

static void test_walls(void)
{
    const double sigma = 0.01;
    float *truth = malloc((size_t)W * H * 3 * sizeof *truth);
    tessel_cloud c, d;
    CHECK(truth && scan(&c, sigma, truth) == TESSEL_OK);
    CHECK(scan(&d, sigma, truth) == TESSEL_OK);
    double before, off;
    errors(&c, truth, &before, &off);
    tessel_ray_denoise_params p = tessel_ray_denoise_params_default();
    tessel_ray_denoise_stats s;
    p.threads = 1;
    CHECK(tessel_denoise_along_rays(&c, &p, &s) == TESSEL_OK);
    p.threads = 2;
    CHECK(tessel_denoise_along_rays(&d, &p, NULL) == TESSEL_OK);
    CHECK(!memcmp(c.xyz, d.xyz, c.count * 3 * sizeof *c.xyz));
    double after;
    errors(&c, truth, &after, &off);
    printf("walls: noise %.4g (estimated %.4g), %u neighbours, RMS %.4g -> %.4g, off the rays "
           "%.2g\n",
           sigma, s.noise, s.k, before, after, off);
    CHECK_MSG(after < 0.4 * before, "RMS %g -> %g", before, after);
    CHECK_MSG(off < 1e-5, "a point left its ray by %g", off);
    /* The step: no point near it moved to the other wall. */
    size_t crossed = 0;
    for (size_t k = 0; k < c.count; k++)
        crossed += fabs((double)c.xyz[3 * k + 2] - truth[3 * k + 2]) > 0.5;
    CHECK(crossed == 0);
    /* No viewpoint, no rays. */
    c.has_viewpoint = 0;
    CHECK(tessel_denoise_along_rays(&c, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_cloud_free(&c);
    tessel_cloud_free(&d);
    free(truth);
}

int main(void)
{
    test_walls();
    return TEST_SUMMARY();
}
