/* Cloud statistics: a regular grid's spacing is its step; bounding box in
 * world coordinates; duplicates counted and merged exactly (attributes and
 * organized grid follow); merging with a tolerance; planted far points found
 * as outliers and left out of the spacing; thread count does not change
 * anything; the smoothing's grid measures the same spacing as the
 * kd-tree, bit for bit. */
#include "tessel.h"
#include "core/grid.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 777;
static double unif(void)
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

/* nx*ny grid with step h on the plane z = 0.5. */
static void grid_cloud(tessel_cloud *c, int nx, int ny, float h)
{
    CHECK(tessel_cloud_alloc(c, (size_t)nx * ny, 0, 0) == TESSEL_OK);
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            float *p = c->xyz + 3 * ((size_t)j * nx + i);
            p[0] = (float)i * h;
            p[1] = (float)j * h;
            p[2] = 0.5f;
        }
}

static void test_grid_spacing(void)
{
    tessel_cloud c;
    grid_cloud(&c, 300, 200, 0.25f);
    c.offset[0] = 1000.0;
    c.offset[2] = -5.0;
    tessel_cloud_stats s;
    tessel_stats_params p = tessel_stats_params_default();
    CHECK(tessel_cloud_stats_compute(&c, &p, &s) == TESSEL_OK);
    CHECK(fabs(s.mean_spacing - 0.25) < 1e-6);
    CHECK(fabs(s.median_spacing - 0.25) < 1e-6);
    CHECK(s.exact_duplicates == 0);
    CHECK(s.outliers == 0);
    CHECK(s.bbox_min[0] == 1000.0 && s.bbox_max[0] == 1000.0 + 299 * 0.25);
    CHECK(s.bbox_min[1] == 0.0 && s.bbox_max[1] == 199 * 0.25);
    CHECK(s.bbox_min[2] == -4.5 && s.bbox_max[2] == -4.5);
    CHECK(fabs(s.diagonal - hypot(299 * 0.25, 199 * 0.25)) < 1e-9);
    double sp = 0.0;
    CHECK(tessel_cloud_spacing(&c, &sp) == TESSEL_OK && fabs(sp - 0.25) < 1e-6);
    /* Sampling a few points gives the same answer on a regular grid. */
    p.sample_size = 10;
    CHECK(tessel_cloud_stats_compute(&c, &p, &s) == TESSEL_OK);
    CHECK(fabs(s.mean_spacing - 0.25) < 1e-6);

    /* Every point doubled (and one tripled): spacing unchanged, duplicates
     * counted, merged back exactly. */
    tessel_cloud d;
    CHECK(tessel_cloud_alloc(&d, 2 * c.count + 1, 1, 1) == TESSEL_OK);
    for (size_t i = 0; i < c.count; i++) {
        memcpy(d.xyz + 3 * (2 * i), c.xyz + 3 * i, 3 * sizeof(float));
        memcpy(d.xyz + 3 * (2 * i + 1), c.xyz + 3 * i, 3 * sizeof(float));
        for (int a = 0; a < 3; a++) {
            d.normals[3 * (2 * i) + a] = (float)a;
            d.normals[3 * (2 * i + 1) + a] = -1.0f;
            d.rgb[3 * (2 * i) + a] = (uint8_t)(i * 7 + (size_t)a);
            d.rgb[3 * (2 * i + 1) + a] = 0;
        }
    }
    memcpy(d.xyz + 3 * (2 * c.count), c.xyz, 3 * sizeof(float));
    /* -0 equals +0: one more duplicate of point 0 if its x is 0. */
    d.xyz[3 * (2 * c.count)] = -0.0f;
    CHECK(tessel_cloud_stats_compute(&d, NULL, &s) == TESSEL_OK);
    CHECK(s.exact_duplicates == c.count + 1);
    CHECK(fabs(s.mean_spacing - 0.25) < 1e-6);
    size_t removed = 0;
    CHECK(tessel_cloud_merge_duplicates(&d, 0.0, &removed) == TESSEL_OK);
    CHECK(removed == c.count + 1 && d.count == c.count);
    CHECK(memcmp(d.xyz, c.xyz, c.count * 3 * sizeof(float)) == 0);
    int attrs_ok = 1;
    for (size_t i = 0; i < d.count; i++)
        for (int a = 0; a < 3; a++)
            attrs_ok &= d.normals[3 * i + a] == (float)a &&
                        d.rgb[3 * i + a] == (uint8_t)(i * 7 + (size_t)a);
    CHECK(attrs_ok);
    CHECK(tessel_cloud_merge_duplicates(&d, 0.0, &removed) == TESSEL_OK && removed == 0);
    tessel_cloud_free(&d);
    tessel_cloud_free(&c);
}

static void test_merge_grid_and_tolerance(void)
{
    /* Organized 4x2 grid: cells 0..7 hold points 0..6 and one empty cell;
     * points 3 and 5 repeat points 1 and 2. */
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 7, 0, 0) == TESSEL_OK);
    float pts[7][3] = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {1, 0, 0},
                       {0, 1, 0}, {2, 0, 0}, {3, 1, 0}};
    memcpy(c.xyz, pts, sizeof pts);
    c.width = 4;
    c.height = 2;
    c.grid = malloc(8 * sizeof *c.grid);
    uint32_t cells[8] = {0, 1, 2, 3, TESSEL_NONE, 4, 5, 6};
    memcpy(c.grid, cells, sizeof cells);
    size_t removed = 0;
    CHECK(tessel_cloud_merge_duplicates(&c, 0.0, &removed) == TESSEL_OK && removed == 2);
    CHECK(c.count == 5);
    uint32_t want[8] = {0, 1, 2, 1, TESSEL_NONE, 3, 2, 4};
    CHECK(memcmp(c.grid, want, sizeof want) == 0);
    CHECK(c.xyz[3 * 3 + 1] == 1.0f && c.xyz[3 * 4] == 3.0f);
    tessel_cloud_free(&c);

    /* Tolerance: clusters of jittered copies around well separated centres
     * collapse to one point each, the first of the cluster in input order. */
    enum { CENTRES = 500, COPIES = 6 };
    CHECK(tessel_cloud_alloc(&c, CENTRES * COPIES, 0, 1) == TESSEL_OK);
    for (size_t j = 0; j < COPIES; j++)
        for (size_t i = 0; i < CENTRES; i++) {
            size_t k = j * CENTRES + i; /* copies interleaved through the array */
            float *p = c.xyz + 3 * k;
            p[0] = (float)(i % 20) + (j ? (float)(unif() - 0.5) * 0.02f : 0.0f);
            p[1] = (float)(i / 20) + (j ? (float)(unif() - 0.5) * 0.02f : 0.0f);
            p[2] = (j ? (float)(unif() - 0.5) * 0.02f : 0.0f);
            c.rgb[3 * k] = (uint8_t)j;
        }
    CHECK(tessel_cloud_merge_duplicates(&c, 0.1, &removed) == TESSEL_OK);
    CHECK(removed == CENTRES * (COPIES - 1) && c.count == CENTRES);
    int first_kept = 1;
    for (size_t i = 0; i < c.count; i++)
        first_kept &= c.rgb[3 * i] == 0 && c.xyz[3 * i] == (float)(i % 20) &&
                      c.xyz[3 * i + 1] == (float)(i / 20) && c.xyz[3 * i + 2] == 0.0f;
    CHECK(first_kept);
    /* A tolerance below the separation of the centres merges nothing more. */
    CHECK(tessel_cloud_merge_duplicates(&c, 0.9, &removed) == TESSEL_OK && removed == 0);
    tessel_cloud_free(&c);

    CHECK(tessel_cloud_merge_duplicates(NULL, 0.0, &removed) == TESSEL_ERR_INVALID_ARG);
}

static void test_outliers(void)
{
    /* 20000 points on a unit sphere plus 25 far points. */
    enum { N = 20000, FAR = 25 };
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, N + FAR, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < N + FAR; i++) {
        double z = 2 * unif() - 1, phi = 6.283185307179586 * unif();
        double r = sqrt(1 - z * z), scale = 1.0;
        if (i >= N)
            scale = 3.0 + unif(); /* isolated, far outside */
        c.xyz[3 * i] = (float)(scale * r * cos(phi));
        c.xyz[3 * i + 1] = (float)(scale * r * sin(phi));
        c.xyz[3 * i + 2] = (float)(scale * z);
    }
    tessel_stats_params p = tessel_stats_params_default();
    tessel_cloud_stats s1, s2;
    p.threads = 1;
    CHECK(tessel_cloud_stats_compute(&c, &p, &s1) == TESSEL_OK);
    CHECK_MSG(s1.outliers == FAR, "found %zu outliers, planted %d", s1.outliers, FAR);
    p.threads = 2;
    CHECK(tessel_cloud_stats_compute(&c, &p, &s2) == TESSEL_OK);
    CHECK(memcmp(&s1, &s2, sizeof s1) == 0);
    /* Duplicated outliers count with their copies. */
    tessel_cloud d;
    CHECK(tessel_cloud_alloc(&d, c.count + 2, 0, 0) == TESSEL_OK);
    memcpy(d.xyz, c.xyz, c.count * 3 * sizeof(float));
    memcpy(d.xyz + 3 * c.count, c.xyz + 3 * N, 3 * sizeof(float));
    memcpy(d.xyz + 3 * (c.count + 1), c.xyz + 3 * N, 3 * sizeof(float));
    CHECK(tessel_cloud_stats_compute(&d, NULL, &s2) == TESSEL_OK);
    CHECK(s2.outliers == FAR + 2 && s2.exact_duplicates == 2);
    tessel_cloud_free(&d);
    /* The mean spacing of an even sample on a sphere of area 4 pi with N
     * points is about 0.5 * sqrt(4 pi / N) (nearest neighbour in a Poisson
     * process); uniform random points: within a factor 2. */
    double expect = 0.5 * sqrt(4 * 3.141592653589793 / N);
    CHECK(s1.mean_spacing > 0.5 * expect && s1.mean_spacing < 2 * expect);
    tessel_cloud_free(&c);
}

/* A few far points (stray returns of a scanner) must not set the unit of
 * every length: without leaving them out, three points 10^5 away would
 * make the mean spacing of this 0.25 grid about 5. */
static void test_spacing_far_points(void)
{
    tessel_cloud g, c;
    grid_cloud(&g, 300, 200, 0.25f);
    CHECK(tessel_cloud_alloc(&c, g.count + 3, 0, 0) == TESSEL_OK);
    memcpy(c.xyz, g.xyz, 3 * g.count * sizeof *c.xyz);
    const float far[3][3] = {{1e5f, 0.0f, 0.5f}, {-1e5f, 3e4f, 0.5f}, {10.0f, 10.0f, 2e5f}};
    memcpy(c.xyz + 3 * g.count, far, sizeof far);
    double sp = 0.0;
    CHECK_MSG(tessel_cloud_spacing(&c, &sp) == TESSEL_OK && fabs(sp - 0.25) < 1e-6,
              "spacing with far points %g", sp);
    tessel_cloud_stats s;
    CHECK(tessel_cloud_stats_compute(&c, NULL, &s) == TESSEL_OK);
    CHECK(fabs(s.mean_spacing - 0.25) < 1e-6 && fabs(s.median_spacing - 0.25) < 1e-6);
    CHECK(s.outliers == 3);
    tessel_cloud_free(&c);
    tessel_cloud_free(&g);
}

static void test_edges(void)
{
    tessel_cloud c;
    tessel_cloud_stats s;
    double sp;
    memset(&c, 0, sizeof c);
    CHECK(tessel_cloud_stats_compute(&c, NULL, &s) == TESSEL_ERR_TOO_FEW_POINTS);
    CHECK(tessel_cloud_spacing(&c, &sp) == TESSEL_ERR_TOO_FEW_POINTS);
    CHECK(tessel_cloud_stats_compute(NULL, NULL, &s) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_cloud_alloc(&c, 50, 0, 0) == TESSEL_OK);
    /* All points equal: stats fine (spacing 0), spacing itself refuses. */
    CHECK(tessel_cloud_stats_compute(&c, NULL, &s) == TESSEL_OK);
    CHECK(s.exact_duplicates == 49 && s.mean_spacing == 0.0 && s.diagonal == 0.0);
    CHECK(tessel_cloud_spacing(&c, &sp) == TESSEL_ERR_TOO_FEW_POINTS);
    c.xyz[4] = NAN;
    CHECK(tessel_cloud_stats_compute(&c, NULL, &s) == TESSEL_ERR_INVALID_ARG);
    c.xyz[4] = 0.0f;
    tessel_stats_params p = tessel_stats_params_default();
    p.outlier_k = 0;
    CHECK(tessel_cloud_stats_compute(&c, &p, &s) == TESSEL_ERR_INVALID_ARG);
    size_t removed;
    CHECK(tessel_cloud_merge_duplicates(&c, 0.0, &removed) == TESSEL_OK && removed == 49);
    CHECK(c.count == 1);
    tessel_cloud_free(&c);
}

/* tsl_grid_spacing against tessel_cloud_spacing: the same value (==) and
 * status, on a random sphere; with exact copies (one at -0 where the
 * original is +0); with far points that stretch the grid (the kd-tree
 * answers them); with a second tiny cluster far away; with many copies of
 * few points (crowded cells); a line; all points equal; and through
 * tessel_smooth, which measures h on its grid. */
static void grid_spacing_case(const char *name, const tessel_cloud *c)
{
    double want = 0.0, got = 0.0;
    tessel_status sw = tessel_cloud_spacing(c, &want);
    tsl_grid g;
    CHECK(tsl_grid_build(&g, c->xyz, c->count, tsl_grid_knn_cell(c->xyz, c->count, 30), 2) ==
          TESSEL_OK);
    tessel_status sg = tsl_grid_spacing(&g, c->xyz, c->count, 2, &got);
    CHECK_MSG(sw == sg && want == got, "%s: kd-tree %.17g (%d), grid %.17g (%d)", name, want,
              (int)sw, got, (int)sg);
    tsl_grid_free(&g);
}

static void test_grid_spacing_same(void)
{
    tessel_cloud c;
    size_t n = 20000;
    CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < n; i++) {
        double z = 2.0 * unif() - 1.0, t = 6.283185307179586 * unif(), r = sqrt(1.0 - z * z);
        c.xyz[3 * i] = (float)(r * cos(t));
        c.xyz[3 * i + 1] = (float)(r * sin(t));
        c.xyz[3 * i + 2] = (float)z;
    }
    grid_spacing_case("sphere", &c);
    for (size_t i = 0; i < n; i += 7)
        memcpy(c.xyz + 3 * (i + 1 < n ? i + 1 : i), c.xyz + 3 * i, 3 * sizeof(float));
    c.xyz[0] = 0.0f;
    c.xyz[3] = -0.0f;
    c.xyz[1] = c.xyz[4], c.xyz[2] = c.xyz[5];
    grid_spacing_case("copies", &c);
    for (size_t i = 0; i < 5; i++)
        c.xyz[3 * (100 + i)] = (float)(1000.0 * (double)(i + 1));
    grid_spacing_case("far points", &c);
    for (size_t i = 0; i < 10; i++)
        for (int a = 0; a < 3; a++)
            c.xyz[3 * (200 + i) + (size_t)a] = 50.0f + 1e-3f * (float)(i * (size_t)(a + 1));
    grid_spacing_case("far cluster", &c);
    tessel_smooth_params p = tessel_smooth_params_default();
    p.passes = 1;
    tessel_cloud out;
    tessel_smooth_stats st;
    double want = 0.0;
    CHECK(tessel_cloud_spacing(&c, &want) == TESSEL_OK);
    CHECK(tessel_smooth(&c, &out, &p, NULL, &st) == TESSEL_OK && st.spacing == want);
    tessel_cloud_free(&out);
    /* 250 distinct points, each copied 80 times in interleaved order:
     * cells of more than 64 points, where copies are found by sorting. */
    float base[3 * 250];
    memcpy(base, c.xyz + 3 * 1000, sizeof base);
    for (size_t i = 0; i < n; i++)
        memcpy(c.xyz + 3 * i, base + 3 * ((i * 7919) % 250), 3 * sizeof(float));
    grid_spacing_case("crowded copies", &c);
    for (size_t i = 0; i < n; i++) {
        c.xyz[3 * i] = (float)i * 0.01f;
        c.xyz[3 * i + 1] = c.xyz[3 * i + 2] = 0.0f;
    }
    grid_spacing_case("line", &c);
    for (size_t i = 0; i < 3 * n; i++)
        c.xyz[i] = 1.0f;
    grid_spacing_case("all equal", &c);
    tessel_cloud_free(&c);
}

int main(void)
{
    test_grid_spacing_same();
    test_grid_spacing();
    test_merge_grid_and_tolerance();
    test_outliers();
    test_spacing_far_points();
    test_edges();
    return TEST_SUMMARY();
}
