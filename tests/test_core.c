/* Status strings, ownership helpers and the 3x3 eigen-solver. */
#include "core/core.h"
#include "test.h"

#include <string.h>

static void test_status(void)
{
    CHECK(strcmp(tessel_status_str(TESSEL_OK), "ok") == 0);
    CHECK(strcmp(tessel_status_str(TESSEL_ERR_PARSE), "malformed input") == 0);
    CHECK(strcmp(tessel_status_str((tessel_status)999), "unknown status") == 0);
    CHECK(strcmp(tessel_version(), TESSEL_VERSION_STRING) == 0);
}

static void test_alloc_free(void)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 10, 1, 1) == TESSEL_OK);
    CHECK(c.count == 10 && c.xyz && c.normals && c.rgb);
    c.xyz[29] = 5.0f;
    tessel_cloud d;
    CHECK(tessel_cloud_copy(&d, &c) == TESSEL_OK);
    CHECK(d.xyz != c.xyz && d.xyz[29] == 5.0f);
    tessel_cloud_free(&c);
    tessel_cloud_free(&d);
    CHECK(c.xyz == NULL && c.count == 0);
    tessel_cloud_free(&c); /* twice is fine */
    tessel_cloud_free(NULL);
    tessel_mesh m;
    CHECK(tessel_mesh_alloc(&m, 4, 2, 0, 0) == TESSEL_OK);
    CHECK(m.vertex_count == 4 && m.triangle_count == 2 && !m.normals);
    tessel_mesh_free(&m);
    tessel_mesh_free(NULL);
    size_t out;
    CHECK(!tsl_mul_size(SIZE_MAX / 2, 3, &out));
    CHECK(tsl_alloc_array(SIZE_MAX / 2, 3) == NULL);
}

static void test_eigen(void)
{
    /* Covariance of a plane z = 0 with spread 4 in x, 1 in y. */
    double a[9] = {4, 0, 0, 0, 1, 0, 0, 0, 0};
    double w[3], v[9];
    tsl_eigen_sym3(a, w, v);
    CHECK(fabs(w[0]) < 1e-12 && fabs(w[1] - 1) < 1e-12 && fabs(w[2] - 4) < 1e-12);
    CHECK(fabs(fabs(v[3 * 2 + 0]) - 1) < 1e-12); /* smallest: z axis */
    /* A rotated matrix: check A v = w v for each pair. */
    double b[9] = {2, 1, 0.5, 1, 3, 0.25, 0.5, 0.25, 1};
    tsl_eigen_sym3(b, w, v);
    CHECK(w[0] <= w[1] && w[1] <= w[2]);
    for (int i = 0; i < 3; i++) {
        for (int r = 0; r < 3; r++) {
            double av = 0;
            for (int k = 0; k < 3; k++)
                av += b[3 * r + k] * v[3 * k + i];
            CHECK(fabs(av - w[i] * v[3 * r + i]) < 1e-10);
        }
    }
}

int main(void)
{
    test_status();
    test_alloc_free();
    test_eigen();
    return TEST_SUMMARY();
}
