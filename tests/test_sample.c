/* Sampling a mesh (src/sample/): points on the surface, spread by area,
 * the noise asked for, normals of their triangles, the same points for the
 * same seed on any thread count, and clear errors. */
#include "tessel.h"
#include "test.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

/* Two triangles in the plane z = 0: (0,0)-(1,0)-(0,1) of area 1/2 and
 * (2,0)-(5,0)-(2,1) of area 3/2. */
static tessel_status two_triangles(tessel_mesh *m)
{
    tessel_status st = tessel_mesh_alloc(m, 6, 2, 0, 0);
    if (st)
        return st;
    const float v[18] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0, 5, 0, 0, 2, 1, 0};
    const uint32_t t[6] = {0, 1, 2, 3, 4, 5};
    memcpy(m->xyz, v, sizeof v);
    memcpy(m->triangles, t, sizeof t);
    return TESSEL_OK;
}

static void test_on_surface_and_by_area(void)
{
    tessel_mesh m;
    CHECK(two_triangles(&m) == TESSEL_OK);
    tessel_cloud c;
    const size_t n = 100000;
    CHECK(tessel_mesh_sample(&m, n, NULL, NULL, &c) == TESSEL_OK);
    CHECK(c.count == n && c.normals != NULL);
    size_t in_first = 0, outside = 0, bad_normal = 0;
    for (size_t i = 0; i < c.count; i++) {
        const float *p = c.xyz + 3 * i, *q = c.normals + 3 * i;
        bool first = p[0] <= 1.0f + 1e-6f;
        in_first += first;
        /* Inside its triangle (up to float rounding), in the plane. */
        if (p[2] != 0.0f || p[1] < 0.0f ||
            (first ? p[0] < 0.0f || p[0] + p[1] > 1.0f + 1e-6f
                   : p[0] < 2.0f || (p[0] - 2.0f) / 3.0f + p[1] > 1.0f + 1e-6f))
            outside++;
        bad_normal += q[0] != 0.0f || q[1] != 0.0f || q[2] != 1.0f;
    }
    CHECK(outside == 0 && bad_normal == 0);
    /* A quarter of the area: 25,000 expected, standard deviation 137. */
    CHECK_MSG(fabs((double)in_first - 0.25 * (double)n) < 5.0 * 137.0, "%zu in the small one",
              in_first);
    /* Uniform inside: the mean of the small triangle's points is its
     * centroid (1/3, 1/3) within 5 standard errors (0.236 / sqrt(25,000)). */
    double sx = 0.0, sy = 0.0;
    for (size_t i = 0; i < c.count; i++)
        if (c.xyz[3 * i] <= 1.0f) {
            sx += c.xyz[3 * i];
            sy += c.xyz[3 * i + 1];
        }
    sx /= (double)in_first;
    sy /= (double)in_first;
    CHECK_MSG(fabs(sx - 1.0 / 3.0) < 0.0075 && fabs(sy - 1.0 / 3.0) < 0.0075, "centroid %g %g",
              sx, sy);
    tessel_cloud_free(&c);
    tessel_mesh_free(&m);
}

static void test_noise(void)
{
    tessel_mesh m;
    CHECK(two_triangles(&m) == TESSEL_OK);
    tessel_sample_params p = tessel_sample_params_default();
    p.noise = 0.01;
    tessel_cloud c;
    CHECK(tessel_mesh_sample(&m, 200000, &p, NULL, &c) == TESSEL_OK);
    double s2 = 0.0, s1 = 0.0;
    for (size_t i = 0; i < c.count; i++) {
        s1 += c.xyz[3 * i + 2];
        s2 += (double)c.xyz[3 * i + 2] * c.xyz[3 * i + 2];
    }
    double mean = s1 / (double)c.count, sd = sqrt(s2 / (double)c.count - mean * mean);
    CHECK_MSG(fabs(sd - 0.01) < 0.0002 && fabs(mean) < 0.0002, "z: mean %g, sd %g", mean, sd);
    tessel_cloud_free(&c);
    /* Relative to the diagonal: sqrt(26) here. */
    p.noise = 0.0;
    p.noise_rel = 0.001;
    CHECK(tessel_mesh_sample(&m, 200000, &p, NULL, &c) == TESSEL_OK);
    s2 = 0.0;
    for (size_t i = 0; i < c.count; i++)
        s2 += (double)c.xyz[3 * i + 2] * c.xyz[3 * i + 2];
    sd = sqrt(s2 / (double)c.count);
    CHECK_MSG(fabs(sd / (0.001 * sqrt(26.0)) - 1.0) < 0.02, "relative noise: sd %g", sd);
    tessel_cloud_free(&c);
    tessel_mesh_free(&m);
}

static void test_deterministic(void)
{
    tessel_mesh m;
    CHECK(two_triangles(&m) == TESSEL_OK);
    tessel_sample_params p = tessel_sample_params_default();
    p.noise = 0.05;
    p.seed = 7;
    tessel_cloud a, b, c;
    p.threads = 1;
    CHECK(tessel_mesh_sample(&m, 300001, &p, NULL, &a) == TESSEL_OK);
    p.threads = 2;
    CHECK(tessel_mesh_sample(&m, 300001, &p, NULL, &b) == TESSEL_OK);
    p.seed = 8;
    CHECK(tessel_mesh_sample(&m, 300001, &p, NULL, &c) == TESSEL_OK);
    CHECK(!memcmp(a.xyz, b.xyz, 3 * a.count * sizeof *a.xyz));
    CHECK(memcmp(a.xyz, c.xyz, 3 * a.count * sizeof *a.xyz) != 0);
    tessel_cloud_free(&a);
    tessel_cloud_free(&b);
    tessel_cloud_free(&c);
    tessel_mesh_free(&m);
}

static int cancel_at_half(void *user, const char *stage, double fraction)
{
    (void)user;
    (void)stage;
    return fraction >= 0.5;
}

static void test_errors(void)
{
    tessel_mesh m;
    tessel_cloud c;
    CHECK(two_triangles(&m) == TESSEL_OK);
    CHECK(tessel_mesh_sample(&m, 0, NULL, NULL, &c) == TESSEL_ERR_INVALID_ARG);
    tessel_sample_params p = tessel_sample_params_default();
    p.noise = -1.0;
    CHECK(tessel_mesh_sample(&m, 10, &p, NULL, &c) == TESSEL_ERR_INVALID_ARG);
    p.noise = NAN;
    CHECK(tessel_mesh_sample(&m, 10, &p, NULL, &c) == TESSEL_ERR_INVALID_ARG);
    /* Cancelled: nothing left allocated, *out zeroed. */
    tessel_callbacks cb = {cancel_at_half, NULL, NULL};
    CHECK(tessel_mesh_sample(&m, 4000000, NULL, &cb, &c) == TESSEL_ERR_CANCELLED);
    CHECK(c.xyz == NULL && c.count == 0);
    m.triangles[4] = 6; /* out of range */
    CHECK(tessel_mesh_sample(&m, 10, NULL, NULL, &c) == TESSEL_ERR_INVALID_ARG);
    /* No area: collinear corners. */
    m.triangles[4] = 4;
    for (int k = 0; k < 18; k++)
        m.xyz[k] = k % 3 == 0 ? (float)k : 0.0f;
    CHECK(tessel_mesh_sample(&m, 10, NULL, NULL, &c) == TESSEL_ERR_TOO_FEW_POINTS);
    tessel_mesh_free(&m);
}

int main(void)
{
    test_on_surface_and_by_area();
    test_noise();
    test_deterministic();
    test_errors();
    return TEST_SUMMARY();
}
