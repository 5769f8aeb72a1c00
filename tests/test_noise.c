/* The noise estimate (src/core/noise.c) against the known sigma of
 * generated surfaces: a sphere and a plane with Gaussian noise from 0.2 to
 * 10 surface spacings, and clean ones; the same for any thread count and
 * under a permutation of the points. */
#include "core/core.h"
#include "surfaces.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

/* n points uniform on the unit sphere, plus isotropic noise sigma. */
static tessel_status noisy_sphere(tessel_cloud *c, size_t n, double sigma, uint64_t seed)
{
    tessel_status st = surf_sphere_random(c, n, seed);
    if (st == TESSEL_OK && sigma > 0.0)
        surf_noise(c, sigma, seed + 1);
    return st;
}

/* n points uniform on a square of side 2 in z = 0, plus noise sigma. */
static tessel_status noisy_plane(tessel_cloud *c, size_t n, double sigma, uint64_t seed)
{
    tessel_status st = tessel_cloud_alloc(c, n, 0, 0);
    if (st)
        return st;
    surf_rng r = surf_seed(seed);
    for (size_t i = 0; i < n; i++) {
        c->xyz[3 * i] = (float)(2.0 * surf_uniform(&r) - 1.0);
        c->xyz[3 * i + 1] = (float)(2.0 * surf_uniform(&r) - 1.0);
        c->xyz[3 * i + 2] = 0.0f;
    }
    if (sigma > 0.0)
        surf_noise(c, sigma, seed + 1);
    return TESSEL_OK;
}

static void test_known_sigma(void)
{
    const double ratios[] = {0.2, 0.5, 1.0, 2.0, 5.0, 10.0};
    const size_t n = 200000;
    for (int shape = 0; shape < 2; shape++) {
        /* Surface spacing 1 / sqrt(density): area 4 pi or 4 over n. */
        double hs = sqrt((shape ? 4.0 : 4.0 * acos(-1.0)) / (double)n);
        for (size_t i = 0; i < sizeof ratios / sizeof ratios[0]; i++) {
            double sigma = ratios[i] * hs;
            tessel_cloud c;
            tessel_status st = shape ? noisy_plane(&c, n, sigma, 11 + i)
                                     : noisy_sphere(&c, n, sigma, 11 + i);
            CHECK(st == TESSEL_OK);
            tessel_noise_estimate e;
            double t0 = tsl_seconds();
            CHECK(tessel_cloud_noise(&c, 0, &e) == TESSEL_OK);
            double dt = tsl_seconds() - t0;
            printf("%s, sigma %.2f surface spacings: estimate %.4g / %.4g = %.3f, spacing %.4g / "
                   "%.4g, %.3f s\n",
                   shape ? "plane" : "sphere", ratios[i], e.sigma, sigma, e.sigma / sigma,
                   e.surface_spacing, hs, dt);
            CHECK_MSG(fabs(e.sigma / sigma - 1.0) < 0.15, "%s sigma %.2f h: estimate off by %.0f%%",
                      shape ? "plane" : "sphere", ratios[i], 100.0 * (e.sigma / sigma - 1.0));
            CHECK_MSG(fabs(e.surface_spacing / hs - 1.0) < 0.15, "spacing %g, true %g",
                      e.surface_spacing, hs);
            tessel_cloud_free(&c);
        }
        /* Clean: far below the smallest noise above. */
        tessel_cloud c;
        CHECK((shape ? noisy_plane(&c, n, 0.0, 5) : noisy_sphere(&c, n, 0.0, 5)) == TESSEL_OK);
        tessel_noise_estimate e;
        CHECK(tessel_cloud_noise(&c, 0, &e) == TESSEL_OK);
        CHECK_MSG(e.noise_ratio < 0.05, "clean %s: %.3f surface spacings",
                  shape ? "plane" : "sphere", e.noise_ratio);
        tessel_cloud_free(&c);
    }
}

static void test_invariance(void)
{
    tessel_cloud c;
    CHECK(noisy_sphere(&c, 50000, 0.01, 3) == TESSEL_OK);
    tessel_noise_estimate a, b, p;
    CHECK(tessel_cloud_noise(&c, 1, &a) == TESSEL_OK);
    CHECK(tessel_cloud_noise(&c, 2, &b) == TESSEL_OK);
    CHECK(a.sigma == b.sigma && a.surface_spacing == b.surface_spacing);
    /* Reversed order: another subsample of seeds, the same answer within
     * the estimate's own scatter. */
    for (size_t i = 0; i < c.count / 2; i++)
        for (int k = 0; k < 3; k++) {
            float t = c.xyz[3 * i + k];
            c.xyz[3 * i + k] = c.xyz[3 * (c.count - 1 - i) + k];
            c.xyz[3 * (c.count - 1 - i) + k] = t;
        }
    CHECK(tessel_cloud_noise(&c, 0, &p) == TESSEL_OK);
    CHECK_MSG(fabs(p.sigma / a.sigma - 1.0) < 0.05, "%g against %g", p.sigma, a.sigma);
    tessel_cloud_free(&c);
    /* Too few points to say anything. */
    CHECK(noisy_sphere(&c, 20, 0.0, 3) == TESSEL_OK);
    CHECK(tessel_cloud_noise(&c, 0, &a) == TESSEL_ERR_TOO_FEW_POINTS);
    tessel_cloud_free(&c);
}

int main(void)
{
    test_known_sigma();
    test_invariance();
    return TEST_SUMMARY();
}
