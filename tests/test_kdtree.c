/* kd-tree against brute force: knn and radius on random, duplicated,
 * collinear and coplanar points; k larger than the cloud; radius 0; the
 * batch call against single queries and for 1 vs 2 threads. */
#include "tessel.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 12345;
static double unif(void)
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

/* Same float formula as the index. */
static float dist2(const float *p, const float *q)
{
    float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

typedef struct {
    float d;
    uint32_t i;
} pair;

static int cmp_pair(const void *a, const void *b)
{
    const pair *x = a, *y = b;
    if (x->d != y->d)
        return x->d < y->d ? -1 : 1;
    return x->i < y->i ? -1 : (x->i > y->i);
}

/* All points sorted by (distance, index). */
static pair *brute(const float *xyz, size_t n, const float *q)
{
    pair *p = malloc((n ? n : 1) * sizeof *p);
    for (size_t i = 0; i < n; i++) {
        p[i].d = dist2(xyz + 3 * i, q);
        p[i].i = (uint32_t)i;
    }
    qsort(p, n, sizeof *p, cmp_pair);
    return p;
}

/* Checks knn and radius for nq queries (queries: half on points, half
 * random in the box [lo, hi]^3). Returns the number of mismatches. */
static int check_cloud(const char *what, const float *xyz, size_t n, size_t k, float radius,
                       int nq, float lo, float hi)
{
    tessel_index *ix = NULL;
    CHECK(tessel_index_build(&ix, xyz, n) == TESSEL_OK);
    if (!ix)
        return 1;
    size_t cap = k + 5;
    uint32_t *idx = malloc(cap * sizeof *idx), *idx2 = malloc(cap * sizeof *idx2);
    float *d2 = malloc(cap * sizeof *d2);
    int bad = 0;
    for (int t = 0; t < nq; t++) {
        float q[3];
        if (t % 2 == 0 && n > 0) {
            memcpy(q, xyz + 3 * ((size_t)t * 7919 % n), sizeof q);
        } else {
            for (int a = 0; a < 3; a++)
                q[a] = lo + (hi - lo) * (float)unif();
        }
        pair *ref = brute(xyz, n, q);
        size_t want = k < n ? k : n;
        size_t got = tessel_index_knn(ix, q, k, idx, d2);
        int ok = got == want;
        for (size_t j = 0; ok && j < got; j++)
            ok = idx[j] == ref[j].i && d2[j] == ref[j].d;
        /* Same indices without a distance array. */
        size_t got2 = tessel_index_knn(ix, q, k, idx2, NULL);
        ok = ok && got2 == got && memcmp(idx, idx2, got * sizeof *idx) == 0;
        if (!ok) {
            bad++;
            fprintf(stderr, "%s: knn mismatch at query %d (k=%zu)\n", what, t, k);
        }

        float r2 = radius * radius;
        size_t total = 0;
        while (total < n && ref[total].d <= r2)
            total++;
        size_t rc = tessel_index_radius(ix, q, radius, idx, d2, cap);
        ok = rc == total;
        for (size_t j = 0; ok && j < (total < cap ? total : cap); j++)
            ok = idx[j] == ref[j].i && d2[j] == ref[j].d;
        size_t rc2 = tessel_index_radius(ix, q, radius, idx2, NULL, cap);
        ok = ok && rc2 == total &&
             memcmp(idx, idx2, (total < cap ? total : cap) * sizeof *idx) == 0;
        ok = ok && tessel_index_radius(ix, q, radius, NULL, NULL, 0) == total;
        if (!ok) {
            bad++;
            fprintf(stderr, "%s: radius mismatch at query %d: %zu vs %zu\n", what, t, rc,
                    total);
        }
        free(ref);
    }
    CHECK_MSG(bad == 0, "%s: %d mismatches", what, bad);
    free(idx);
    free(idx2);
    free(d2);
    tessel_index_destroy(ix);
    return bad;
}

static float *random_cloud(size_t n, float scale)
{
    float *xyz = malloc(n * 3 * sizeof *xyz + 1);
    for (size_t i = 0; i < 3 * n; i++)
        xyz[i] = scale * (float)unif();
    return xyz;
}

static void test_random(void)
{
    float *xyz = random_cloud(3000, 1.0f);
    check_cloud("random k=1", xyz, 3000, 1, 0.05f, 100, -0.1f, 1.1f);
    check_cloud("random k=16", xyz, 3000, 16, 0.08f, 200, -0.1f, 1.1f);
    /* Heap path (k above the sorted-insertion limit), and k > 256 without
     * distances (recomputed). */
    check_cloud("random k=100", xyz, 3000, 100, 0.15f, 60, -0.5f, 1.5f);
    check_cloud("random k=300", xyz, 3000, 300, 0.3f, 30, 0.0f, 1.0f);
    /* Coarse coordinates: many exactly equal distances, ties by index. */
    for (size_t i = 0; i < 3 * 3000; i++)
        xyz[i] = floorf(xyz[i] * 8.0f);
    check_cloud("integer lattice", xyz, 3000, 20, 2.0f, 200, 0.0f, 8.0f);
    free(xyz);
}

static void test_degenerate(void)
{
    enum { N = 2000 };
    float *xyz = malloc(N * 3 * sizeof *xyz);
    /* Many identical points (plus a few others): the tie order is the index. */
    for (size_t i = 0; i < N; i++) {
        float v = i % 10 == 0 ? (float)unif() : 0.5f;
        xyz[3 * i] = xyz[3 * i + 1] = xyz[3 * i + 2] = v;
    }
    check_cloud("duplicates", xyz, N, 32, 0.01f, 50, 0.4f, 0.6f);
    check_cloud("duplicates k=300", xyz, N, 300, 0.0f, 20, 0.5f, 0.5f);
    /* All identical. */
    for (size_t i = 0; i < 3 * N; i++)
        xyz[i] = 1.0f;
    check_cloud("identical", xyz, N, 17, 0.0f, 10, 1.0f, 1.0f);
    /* A line. */
    for (size_t i = 0; i < N; i++) {
        float t = (float)unif();
        xyz[3 * i] = t;
        xyz[3 * i + 1] = 2.0f * t;
        xyz[3 * i + 2] = -t;
    }
    check_cloud("line", xyz, N, 12, 0.01f, 100, 0.0f, 1.0f);
    /* A plane z = 3. */
    for (size_t i = 0; i < N; i++) {
        xyz[3 * i] = (float)unif();
        xyz[3 * i + 1] = (float)unif();
        xyz[3 * i + 2] = 3.0f;
    }
    check_cloud("plane", xyz, N, 16, 0.05f, 100, 0.0f, 3.0f);
    /* Tiny clouds: k > count, single point, radius 0. */
    check_cloud("five points", xyz, 5, 9, 0.5f, 10, 0.0f, 1.0f);
    check_cloud("one point", xyz, 1, 4, 0.0f, 4, 0.0f, 1.0f);
    free(xyz);
}

static void test_api_edges(void)
{
    tessel_index *ix = NULL;
    float xyz[6] = {0, 0, 0, 1, 0, 0};
    uint32_t idx[4];
    float d2[4];
    CHECK(tessel_index_build(NULL, xyz, 2) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_index_build(&ix, NULL, 2) == TESSEL_ERR_INVALID_ARG);
    float bad[3] = {0, NAN, 0};
    CHECK(tessel_index_build(&ix, bad, 1) == TESSEL_ERR_INVALID_ARG && ix == NULL);
    /* Empty index: valid, every query finds nothing. */
    CHECK(tessel_index_build(&ix, NULL, 0) == TESSEL_OK && ix != NULL);
    CHECK(tessel_index_knn(ix, xyz, 3, idx, d2) == 0);
    CHECK(tessel_index_radius(ix, xyz, 1.0f, idx, d2, 4) == 0);
    tessel_index_destroy(ix);
    tessel_index_destroy(NULL);

    CHECK(tessel_index_build(&ix, xyz, 2) == TESSEL_OK);
    /* Radius 0 finds the point itself only; negative radius nothing. */
    CHECK(tessel_index_radius(ix, xyz + 3, 0.0f, idx, d2, 4) == 1 && idx[0] == 1);
    CHECK(tessel_index_radius(ix, xyz + 3, -1.0f, idx, d2, 4) == 0);
    /* Cap smaller than the total: the nearest, and the total returned. */
    CHECK(tessel_index_radius(ix, xyz, 2.0f, idx, d2, 1) == 2 && idx[0] == 0);
    CHECK(tessel_index_knn(ix, xyz, 0, idx, d2) == 0);
    /* Batch padding when k > count. */
    uint32_t bidx[8];
    float bd[8];
    CHECK(tessel_index_knn_batch(ix, xyz, 2, 4, bidx, bd, 1) == TESSEL_OK);
    CHECK(bidx[0] == 0 && bidx[1] == 1 && bidx[2] == TESSEL_NONE && bidx[3] == TESSEL_NONE);
    CHECK(bidx[4] == 1 && bidx[5] == 0 && isinf(bd[6]) && isinf(bd[7]));
    CHECK(tessel_index_knn_batch(ix, NULL, 2, 4, bidx, bd, 1) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_index_knn_batch(NULL, xyz, 2, 4, bidx, bd, 1) == TESSEL_ERR_INVALID_ARG);
    tessel_index_destroy(ix);
}

/* Batch equals single queries, and 1 thread equals 2 threads. */
static void test_batch(void)
{
    enum { N = 200000, K = 16 };
    float *xyz = random_cloud(N, 10.0f);
    tessel_index *ix = NULL;
    CHECK(tessel_index_build(&ix, xyz, N) == TESSEL_OK);
    uint32_t *a = malloc((size_t)N * K * sizeof *a), *b = malloc((size_t)N * K * sizeof *b);
    float *da = malloc((size_t)N * K * sizeof *da), *db = malloc((size_t)N * K * sizeof *db);
    CHECK(tessel_index_knn_batch(ix, xyz, N, K, a, da, 1) == TESSEL_OK);
    CHECK(tessel_index_knn_batch(ix, xyz, N, K, b, db, 2) == TESSEL_OK);
    CHECK(memcmp(a, b, (size_t)N * K * sizeof *a) == 0);
    CHECK(memcmp(da, db, (size_t)N * K * sizeof *da) == 0);
    int bad = 0;
    for (size_t i = 0; i < N; i += 997) {
        uint32_t idx[K];
        float d2[K];
        size_t got = tessel_index_knn(ix, xyz + 3 * i, K, idx, d2);
        if (got != K || memcmp(idx, a + i * K, sizeof idx) != 0 ||
            memcmp(d2, da + i * K, sizeof d2) != 0)
            bad++;
        if (a[i * K] != i && da[i * K] != 0.0f) /* self is at distance 0 */
            bad++;
    }
    CHECK_MSG(bad == 0, "%d batch rows differ from single queries", bad);
    /* The large tree (built with tasks) against brute force on a few. */
    check_cloud("large", xyz, N, K, 0.3f, 20, 0.0f, 10.0f);
    /* A large cloud of only three distinct points: the median selection
     * must stay linear (it would be quadratic without grouping equal keys)
     * and ties still go by index. */
    for (size_t i = 0; i < 3 * (size_t)N; i++)
        xyz[i] = (float)((i / 3) % 3);
    check_cloud("three values", xyz, N, 40, 0.5f, 6, 0.0f, 2.0f);
    free(a);
    free(b);
    free(da);
    free(db);
    free(xyz);
    tessel_index_destroy(ix);
}

int main(void)
{
    test_random();
    test_degenerate();
    test_api_edges();
    test_batch();
    return TEST_SUMMARY();
}
