/* tessel_world_to_local: double world coordinates give the very floats and
 * offset a reader gives for the same points (a binary PLY of doubles parsed
 * from memory), on UTM-like, ECEF-like and ordinary clouds with strays;
 * non-finite or too large coordinates are refused. */
#include "test.h"

#include <tessel.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng = 0x9e3779b97f4a7c15u;

static double rnd(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

/* The same points through the PLY reader. */
static tessel_status read_as_ply(const double *world, size_t n, tessel_cloud *cloud)
{
    char header[160];
    int hl = snprintf(header, sizeof header,
                      "ply\nformat binary_little_endian 1.0\nelement vertex %zu\n"
                      "property double x\nproperty double y\nproperty double z\nend_header\n",
                      n);
    size_t size = (size_t)hl + n * 24;
    unsigned char *buf = malloc(size);
    if (!buf)
        return TESSEL_ERR_NOMEM;
    memcpy(buf, header, (size_t)hl);
    memcpy(buf + hl, world, n * 24); /* x86-64 and aarch64 are little-endian */
    tessel_diag diag;
    tessel_status st = tessel_cloud_parse(cloud, buf, size, "world.ply", NULL, &diag);
    free(buf);
    return st;
}

static void check_cloud(const double base[3], double extent, size_t n, size_t strays)
{
    double *world = malloc(n * 3 * sizeof *world);
    float *xyz = malloc(n * 3 * sizeof *xyz);
    CHECK(world && xyz);
    if (!world || !xyz)
        return;
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++)
            world[3 * i + a] = base[a] + (rnd() - 0.5) * extent;
    for (size_t s = 0; s < strays && s < n; s++) {
        size_t i = (s * 7919) % n;
        world[3 * i] = s % 2 ? 0.0 : -1e5;
        world[3 * i + 2] = s % 3 ? 1e-300 : 1e15;
    }
    double offset[3];
    CHECK(tessel_world_to_local(world, n, xyz, offset) == TESSEL_OK);
    tessel_cloud cloud;
    CHECK(read_as_ply(world, n, &cloud) == TESSEL_OK);
    CHECK(cloud.count == n);
    if (cloud.count == n) {
        CHECK(memcmp(cloud.offset, offset, sizeof offset) == 0);
        CHECK(memcmp(cloud.xyz, xyz, n * 3 * sizeof *xyz) == 0);
    }
    tessel_cloud_free(&cloud);
    free(world);
    free(xyz);
}

int main(void)
{
    const double utm[3] = {500123.25, 4649776.5, 231.0};
    const double ecef[3] = {4201234.0, 172345.0, 4779876.0};
    const double small[3] = {1.0, -2.0, 0.5};
    const double edge[3] = {4096.5, -4097.0, 0.0};
    check_cloud(utm, 1000.0, 20000, 0);
    check_cloud(utm, 50.0, 3000, 17);
    check_cloud(ecef, 8000.0, 10000, 3);
    check_cloud(small, 2.0, 5000, 0);
    check_cloud(edge, 3.0, 5000, 2);
    check_cloud(small, 2.0, 1, 0);

    /* Refused: NaN, infinity, beyond 1e15; nothing written. */
    double bad[6] = {1, 2, 3, 4, 5, 6};
    float out[6] = {7, 7, 7, 7, 7, 7};
    double offset[3] = {9, 9, 9};
    const double refused[] = {NAN, INFINITY, -INFINITY, 2e15};
    for (size_t k = 0; k < sizeof refused / sizeof *refused; k++) {
        bad[4] = refused[k];
        CHECK(tessel_world_to_local(bad, 2, out, offset) == TESSEL_ERR_INVALID_ARG);
        CHECK(out[0] == 7 && offset[0] == 9);
    }
    CHECK(tessel_world_to_local(NULL, 1, out, offset) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_world_to_local(NULL, 0, NULL, offset) == TESSEL_OK);
    CHECK(offset[0] == 0 && offset[1] == 0 && offset[2] == 0);
    return TEST_SUMMARY();
}
