/* The I/O core: number scanning and formatting against the C library, the
 * builder's rules (non-finite points, faces, grids, limits, offsets), exact
 * round trips of georeferenced coordinates, atomic writes (missing folder,
 * a write that fails halfway, refused formats: the destination is untouched
 * and no temporary is left), read errors, format detection, reading from
 * a pipe, and the streaming mesh writer against tessel_mesh_write. */
#include "io/io.h"
#include "test.h"

#include <dirent.h>
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static uint64_t rng_state = 0x2545f4914f6cdd1dull;
static uint64_t rnd_u64(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}
static double rnd(void) { return (double)(rnd_u64() >> 11) / 9007199254740992.0; }

static char tmpdir[256];

static void path_in(char *buf, size_t n, const char *name)
{
    snprintf(buf, n, "%s/%s", tmpdir, name);
}

/* Number of entries in the test folder (besides . and ..), and whether any
 * is a leftover temporary. */
static size_t dir_entries(const char *dir, int *temporaries)
{
    size_t n = 0;
    *temporaries = 0;
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        n++;
        if (strstr(e->d_name, ".tmp-"))
            (*temporaries)++;
    }
    closedir(d);
    return n;
}

static bool file_equals(const char *path, const uint8_t *data, size_t size)
{
    uint8_t *d;
    size_t n;
    if (tsl_read_file(path, &d, &n, NULL) != TESSEL_OK)
        return false;
    bool eq = n == size && memcmp(d, data, n) == 0;
    free(d);
    return eq;
}

static bool same_files(const char *a, const char *b)
{
    uint8_t *d;
    size_t n;
    if (tsl_read_file(a, &d, &n, NULL) != TESSEL_OK)
        return false;
    bool eq = file_equals(b, d, n);
    free(d);
    return eq;
}

/* ---- scanning ---- */

/* Scans text held in an exact-size heap buffer (no terminator), so reading
 * past the end is an ASan error. */
static bool scan_exact(const char *text, double *v, size_t *used)
{
    size_t n = strlen(text);
    char *buf = malloc(n ? n : 1);
    memcpy(buf, text, n);
    const char *p = buf;
    bool ok = tsl_scan_double(&p, buf + n, v);
    /* Found by comparison: gcc 12 -O3 flags "p - buf" as a use after free. */
    size_t left = n;
    while (left && p != buf + (n - left))
        left--;
    *used = n - left;
    free(buf);
    return ok;
}

static void test_scan(void)
{
    static const struct {
        const char *text;
        double value;
        size_t used;
    } cases[] = {
        {"0", 0, 1},
        {"-0.5", -0.5, 4},
        {"+7", 7, 2},
        {".25", 0.25, 3},
        {"5.", 5, 2},
        {"1e3", 1000, 3},
        {"1E-2", 0.01, 4},
        {"1e", 1, 1},
        {"1e+", 1, 1},
        {"2.5x", 2.5, 3},
        {"  \t3", 3, 4},
        {"1,5", 1, 1},
        {"123456789012345678901234567890", 123456789012345678901234567890.0, 30},
        {"0.000000000000000000000000000001", 1e-30, 32},
        {"4.9406564584124654e-324", 4.9406564584124654e-324, 23},
        {"1.7976931348623157e308", 1.7976931348623157e308, 22},
        {"9007199254740993", 9007199254740992.0, 16},
        {"1e400", INFINITY, 5},
        {"-1e400", -INFINITY, 6},
        {"1e-400", 0.0, 6},
        {"inf", INFINITY, 3},
        {"-Infinity", -INFINITY, 9},
        {"INF ", INFINITY, 3},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double v = -12345;
        size_t used = 0;
        bool ok = scan_exact(cases[i].text, &v, &used);
        CHECK_MSG(ok && v == cases[i].value && used == cases[i].used,
                  "'%s' -> %d %.17g used %zu", cases[i].text, ok, v, used);
    }
    static const char *const nans[] = {"nan", "NaN", "-nan", "nan(0x7)"};
    for (size_t i = 0; i < sizeof nans / sizeof nans[0]; i++) {
        double v = 0;
        size_t used;
        CHECK(scan_exact(nans[i], &v, &used) && isnan(v) && used == strlen(nans[i]));
    }
    static const char *const bad[] = {"", " ", "-", "+", ".", "e5", "abc", "-.e1", "in", "na"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        double v;
        size_t used;
        CHECK_MSG(!scan_exact(bad[i], &v, &used), "'%s' accepted", bad[i]);
    }
    /* Random doubles, printed many ways: the same value as strtod. */
    size_t mismatches = 0;
    for (int i = 0; i < 200000; i++) {
        uint64_t bits = rnd_u64();
        double d;
        memcpy(&d, &bits, sizeof d);
        if (!isfinite(d))
            continue;
        if (i % 3 == 0)
            d = (rnd() - 0.5) * pow(10.0, (double)(rnd_u64() % 40) - 20.0);
        char buf[512];
        switch (i % 5) {
        case 0: snprintf(buf, sizeof buf, "%.17g", d); break;
        case 1: snprintf(buf, sizeof buf, "%.15g", d); break;
        case 2: snprintf(buf, sizeof buf, "%.6e", d); break;
        case 3: snprintf(buf, sizeof buf, "%.3f", d); break;
        default: snprintf(buf, sizeof buf, "%.20e", d); break;
        }
        double v;
        size_t used;
        if (!scan_exact(buf, &v, &used) || used != strlen(buf) || v != strtod(buf, NULL))
            mismatches++;
    }
    CHECK_MSG(mismatches == 0, "%zu mismatches against strtod", mismatches);

    /* Integers, with their overflow edges. */
    const char *t = "18446744073709551615";
    const char *p = t;
    uint64_t u;
    CHECK(tsl_scan_u64(&p, t + strlen(t), &u) && u == UINT64_MAX && p == t + 20);
    t = "18446744073709551616";
    p = t;
    CHECK(!tsl_scan_u64(&p, t + strlen(t), &u) && p == t);
    t = "-1";
    p = t;
    CHECK(!tsl_scan_u64(&p, t + 2, &u));
    int64_t s;
    t = "-9223372036854775808";
    p = t;
    CHECK(tsl_scan_i64(&p, t + strlen(t), &s) && s == INT64_MIN);
    t = "9223372036854775808";
    p = t;
    CHECK(!tsl_scan_i64(&p, t + strlen(t), &s));
    t = " +42 ";
    p = t;
    CHECK(tsl_scan_i64(&p, t + strlen(t), &s) && s == 42 && p == t + 4);
    t = "12345";
    p = t;
    CHECK(tsl_scan_u64(&p, t + 3, &u) && u == 123); /* bounded by end */
    t = "- 5";
    p = t;
    CHECK(!tsl_scan_i64(&p, t + 3, &s));
}

/* ---- offsets, local coordinates and text formatting ---- */

/* Whether a + b is exact in double (Knuth's TwoSum error is zero). */
static bool exact_sum(double a, double b)
{
    double s = a + b, bb = s - a;
    return (a - (s - bb)) + (b - bb) == 0.0;
}

static bool same_bits(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

/* Checks, for one (world, offset) pair, what the round trip needs from
 * tsl_local_coord and tsl_format_coord. Returns a bit mask of failures:
 * 1 offset + f not exact, 2 not idempotent, 4 floor changed within 2^24,
 * 8 outside the 1e15 readers keep, 16 more than one float ulp off,
 * 32 text does not read back (floor and float). */
static unsigned local_coord_failures(double world, double offset)
{
    unsigned bad = 0;
    float f = tsl_local_coord(world, offset);
    double s = offset + (double)f;
    if (!exact_sum(offset, (double)f))
        bad |= 1;
    if (!same_bits(tsl_local_coord(s, offset), f))
        bad |= 2;
    if (fabs(world - offset) < 16777214.0 && floor(s) != floor(world))
        bad |= 4;
    if (fabs(s) > 1e15)
        bad |= 8;
    double ulp = (double)nextafterf(fabsf(f), INFINITY) - (double)fabsf(f);
    if (fabs(s - world) > ulp * 1.000001 + fabs(world) * 1e-16)
        bad |= 16;
    char buf[64];
    int n = tsl_format_coord(buf, offset, f);
    const char *p = buf;
    double v;
    if (n <= 0 || n >= 32 || !tsl_scan_double(&p, buf + n, &v) || p != buf + n ||
        floor(v) != floor(s) || !same_bits(tsl_local_coord(v, offset), f))
        bad |= 32;
    return bad;
}

/* A world coordinate for the local-coordinate checks: near the offset at
 * every scale, on and just off integers, tiny, huge, far on the other side. */
static double tricky_world(double offset, int kind)
{
    double r = rnd() - 0.5, w;
    switch (kind % 10) {
    case 0: w = offset + r * pow(2.0, (double)(rnd_u64() % 80) - 40.0); break;
    case 1: /* just off an integer */
        w = offset + floor(r * 64) + (rnd() < 0.5 ? -1 : 1) * pow(2.0, -(double)(rnd_u64() % 70));
        break;
    case 2: w = r * pow(10.0, -(double)(rnd_u64() % 320)); break; /* tiny, denormal */
    case 3: w = (rnd() < 0.5 ? -1e15 : 1e15) * (1.0 - rnd() * 1e-9); break;
    case 4: w = r * 2e15; break;
    case 5: w = offset + (r < 0 ? -1 : 1) * (16777216.0 + floor(r * 8) + rnd() * 2); break;
    case 6: w = floor(offset + r * 1e6); break; /* on an integer */
    case 7: w = -offset + r * 100; break;
    case 8: w = offset + r * 2e7; break;
    default: w = nextafter(offset + floor(r * 10), rnd() < 0.5 ? -INFINITY : INFINITY); break;
    }
    if (!(fabs(w) <= 1e15))
        w = copysign(1e15, w);
    return w;
}

static void test_local_coord(void)
{
    /* Integer offsets of every size (the rule gives 0 or a median beyond
     * 4096) and worlds anywhere a reader keeps: strays put local
     * coordinates far below 1, negative, in (-1, 1) and up to 2e15. */
    static const double offsets[] = {0,      4097,     -4097,   500000,   -700000,
                                     5400000, 6378137, -6378137, 123456789, -999999999999999.0,
                                     999999999999999.0, 562949953421311.0};
    size_t fails[6] = {0}, unordered = 0, total = 0;
    for (size_t o = 0; o < sizeof offsets / sizeof offsets[0]; o++) {
        for (int i = 0; i < 40000; i++) {
            double offset = offsets[o];
            if (i % 7 == 6 && fabs(offset) < 5e14)
                offset = floor(offset * (0.5 + rnd()));
            double w = tricky_world(offset, i);
            unsigned bad = local_coord_failures(w, offset);
            for (int k = 0; k < 6; k++)
                fails[k] += (bad >> k) & 1;
            /* Monotone: the next double up never gets a smaller float. */
            double w2 = i % 2 ? nextafter(w, INFINITY) : w + fabs(w) * rnd() * 1e-7;
            if (w2 <= 1e15 && tsl_local_coord(w2, offset) < tsl_local_coord(w, offset))
                unordered++;
            total++;
        }
    }
    CHECK_MSG(fails[0] == 0 && fails[1] == 0 && fails[2] == 0 && fails[3] == 0 &&
                  fails[4] == 0 && fails[5] == 0 && unordered == 0,
              "of %zu: inexact %zu, not idempotent %zu, floor %zu, range %zu, ulp %zu, "
              "text %zu, not monotone %zu",
              total, fails[0], fails[1], fails[2], fails[3], fails[4], fails[5], unordered);

    /* Never up across an integer, on both sides of zero; far values go
     * toward zero. */
    CHECK(tsl_local_coord(700000.99999999, 700000) == nextafterf(1.0f, 0.0f));
    CHECK(tsl_local_coord(699998.999999999, 700000) == nextafterf(-1.0f, -INFINITY));
    CHECK(tsl_local_coord(-1e-20, 5000) == nextafterf(-5000.0f, -INFINITY)); /* t inexact */
    CHECK(floor(5000.0 + (double)tsl_local_coord(-1e-20, 5000)) == -1.0);
    CHECK(tsl_local_coord(-1e-300, 0) < 0.0f); /* not -0.0: floor -1 kept */
    CHECK(tsl_local_coord(-1e15, 1e15) >= -2e15f &&
          1e15 + (double)tsl_local_coord(-1e15, 1e15) >= -1e15);
    CHECK(1e15 + (double)tsl_local_coord(-999999999999999.875, 1e15) >= -1e15);
}

/* floor of the lower median of the points j*n/m (m = min(n, 8192)): the
 * documented rule, by brute force (insertion sort). */
static double median_floor(const double *xyz, size_t n, int axis)
{
    size_t m = n < 8192 ? n : 8192;
    double *v = malloc(m * sizeof *v);
    for (size_t j = 0; j < m; j++) {
        double x = xyz[3 * (size_t)((uint64_t)j * n / m) + (size_t)axis];
        size_t k = j;
        while (k > 0 && v[k - 1] > x) {
            v[k] = v[k - 1];
            k--;
        }
        v[k] = x;
    }
    double c = floor(v[(m - 1) / 2]);
    free(v);
    return c;
}

static double rule_offset(const double *xyz, size_t n, int axis)
{
    double c = median_floor(xyz, n, axis);
    return c >= -4096 && c <= 4096 ? 0.0 : c;
}

static void test_offsets(void)
{
    double off[3];
    CHECK(tsl_choose_offset(NULL, 0, off) == TESSEL_OK && off[0] == 0 && off[1] == 0 &&
          off[2] == 0);
    /* Thresholds: the median's floor decides, per axis. */
    const double edge[3][3] = {{4096.99, -4096.0, 4097.0},
                               {4096.5, -4096.5, -4097.0},
                               {0.0, -5000.0, 1e9}};
    CHECK(tsl_choose_offset(&edge[0][0], 1, off) == TESSEL_OK && off[0] == 0 &&
          off[1] == 0 && off[2] == 4097);
    CHECK(tsl_choose_offset(&edge[1][0], 1, off) == TESSEL_OK && off[0] == 0 &&
          off[1] == -4097 && off[2] == -4097);
    /* Three points: the middle one; the order does not matter. */
    CHECK(tsl_choose_offset(&edge[0][0], 3, off) == TESSEL_OK && off[0] == 0 &&
          off[1] == -4097 && off[2] == 4097);

    /* The bulk decides, not the extremes: 10^6 points of UTM-like data
     * with 1% strays at the origin, at -1e5 and at 1e15. The offset lies
     * inside the bulk and is what the documented rule gives. */
    size_t n = 1000000;
    double *xyz = malloc(n * 3 * sizeof *xyz);
    static const double base[3] = {500000.0, 5400000.0, 200.0}, strays[3] = {0, -1e5, 1e15};
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++)
            xyz[3 * i + k] = base[k] + rnd() * 1000.0;
        if (rnd_u64() % 100 == 0) {
            double stray = strays[rnd_u64() % 3];
            for (int k = 0; k < 3; k++)
                xyz[3 * i + k] = stray;
        }
    }
    CHECK(tsl_choose_offset(xyz, n, off) == TESSEL_OK);
    for (int k = 0; k < 2; k++) {
        CHECK_MSG(off[k] >= base[k] && off[k] <= base[k] + 1000.0 &&
                      off[k] == rule_offset(xyz, n, k),
                  "axis %d: offset %.17g", k, off[k]);
    }
    CHECK(off[2] == 0); /* z: within 4096 */
    /* Few points: the lower median of all of them. */
    for (size_t m = 1; m <= 9; m++) {
        CHECK(tsl_choose_offset(xyz, m, off) == TESSEL_OK);
        for (int k = 0; k < 3; k++) {
            /* floor(median) == off[k], or within [-4096, 4096] for 0 */
            double lo = off[k] != 0 ? off[k] : -4096, hi = off[k] != 0 ? off[k] : 4096;
            size_t below = 0, upto = 0;
            for (size_t i = 0; i < m; i++) {
                below += floor(xyz[3 * i + k]) < lo;
                upto += floor(xyz[3 * i + k]) <= hi;
            }
            CHECK_MSG(below <= (m - 1) / 2 && upto > (m - 1) / 2,
                      "%zu points, axis %d: offset %.17g", m, k, off[k]);
        }
    }
    free(xyz);

    char buf[64];
    tsl_format_coord(buf, 0, 0.1f);
    CHECK(strcmp(buf, "0.1") == 0);
    tsl_format_coord(buf, 499999, 1.25f);
    CHECK(strcmp(buf, "500000.25") == 0);
    tsl_format_coord(buf, 500000, -0.75f);
    CHECK(strcmp(buf, "499999.25") == 0);
    tsl_format_coord(buf, 0, NAN);
    CHECK(strcmp(buf, "nan") == 0);
    /* A locale with a decimal comma changes nothing (when installed). */
    if (setlocale(LC_NUMERIC, "de_DE.UTF-8") || setlocale(LC_NUMERIC, "fr_FR.UTF-8")) {
        tsl_format_coord(buf, 0, 2.5f);
        CHECK(strcmp(buf, "2.5") == 0);
        const char *t = "3.75";
        double v;
        CHECK(tsl_scan_double(&t, t + 4, &v) && v == 3.75);
        setlocale(LC_NUMERIC, "C");
    }
}

/* ---- builder ---- */

static void test_builder(void)
{
    /* Non-finite points dropped, faces using them dropped, others remapped. */
    tsl_builder b;
    tsl_builder_init(&b, NULL);
    CHECK(tsl_builder_attributes(&b, 1, 0) == TESSEL_OK);
    const double pts[6][3] = {{0, 0, 0}, {1, 0, 0}, {NAN, 0, 0},
                              {0, 1, 0}, {0, INFINITY, 0}, {1, 1, -INFINITY}};
    for (int i = 0; i < 6; i++) {
        float n[3] = {0, 0, (float)i};
        CHECK(tsl_builder_point(&b, pts[i], n, NULL) == TESSEL_OK);
    }
    const uint32_t quad[4] = {0, 1, 5, 3}, tri1[3] = {0, 1, 3}, tri2[3] = {3, 2, 1},
                   line[2] = {0, 1};
    CHECK(tsl_builder_polygon(&b, quad, 4) == TESSEL_OK); /* (0 1 5) dropped, (0 5 3) dropped */
    CHECK(tsl_builder_polygon(&b, tri1, 3) == TESSEL_OK);
    CHECK(tsl_builder_polygon(&b, tri2, 3) == TESSEL_OK); /* uses 2: dropped */
    CHECK(tsl_builder_polygon(&b, line, 2) == TESSEL_OK); /* ignored */
    CHECK(b.tri_count == 4);
    tessel_mesh m;
    CHECK(tsl_builder_finish_mesh(&b, &m) == TESSEL_OK);
    CHECK(m.vertex_count == 3 && m.triangle_count == 1);
    CHECK(m.triangle_count == 1 && m.triangles[0] == 0 && m.triangles[1] == 1 &&
          m.triangles[2] == 2);
    CHECK(m.normals && m.normals[2] == 0 && m.normals[5] == 1 && m.normals[8] == 3);
    CHECK(m.xyz[6] == 0 && m.xyz[7] == 1);
    tessel_mesh_free(&m);
    tsl_builder_free(&b);

    /* Absurd magnitudes (a hostile LAS scale) are dropped like NaN: kept,
     * world - offset would overflow the float storage. */
    tsl_builder_init(&b, NULL);
    const double huge[3][3] = {{1.7e308, 0, 0}, {-1.7e308, 0, 0}, {1, 2, 3}};
    for (int i = 0; i < 3; i++)
        CHECK(tsl_builder_point(&b, huge[i], NULL, NULL) == TESSEL_OK);
    tessel_cloud hc;
    CHECK(tsl_builder_finish_cloud(&b, &hc) == TESSEL_OK);
    CHECK(hc.count == 1 && hc.dropped_nonfinite == 2);
    CHECK(hc.count == 1 && hc.xyz[0] == 1.0f && hc.xyz[2] == 3.0f);
    tessel_cloud_free(&hc);

    /* Organized grid: cells map to kept points or TESSEL_NONE. */
    tsl_builder_init(&b, NULL);
    for (int cell = 0; cell < 6; cell++) {
        double p[3] = {cell, 0, cell % 2 ? NAN : 0};
        CHECK(tsl_builder_point(&b, p, NULL, NULL) == TESSEL_OK);
    }
    b.width = 3;
    b.height = 2;
    tessel_cloud c;
    CHECK(tsl_builder_finish_cloud(&b, &c) == TESSEL_OK);
    CHECK(c.count == 3 && c.dropped_nonfinite == 3 && c.width == 3 && c.height == 2 && c.grid);
    const uint32_t want[6] = {0, TESSEL_NONE, 1, TESSEL_NONE, 2, TESSEL_NONE};
    CHECK(c.grid && memcmp(c.grid, want, sizeof want) == 0);
    CHECK(c.xyz[3] == 2 && c.xyz[6] == 4);
    tessel_cloud_free(&c);
    tsl_builder_free(&b);
    /* A grid that does not match the point count is refused. */
    tsl_builder_init(&b, NULL);
    double o[3] = {0, 0, 0};
    CHECK(tsl_builder_point(&b, o, NULL, NULL) == TESSEL_OK);
    b.width = 2;
    b.height = 1;
    CHECK(tsl_builder_finish_cloud(&b, &c) == TESSEL_ERR_PARSE);
    tsl_builder_free(&b);

    /* Limits. */
    tessel_read_params rp = tessel_read_params_default();
    rp.max_points = 1000;
    rp.max_faces = 10;
    tsl_builder_init(&b, &rp);
    tessel_status st = TESSEL_OK;
    size_t pushed = 0;
    while (st == TESSEL_OK && pushed < 5000) {
        st = tsl_builder_point(&b, o, NULL, NULL);
        if (st == TESSEL_OK)
            pushed++;
    }
    CHECK(st == TESSEL_ERR_LIMIT && pushed == 1000);
    CHECK(tsl_builder_reserve(&b, 1001, 0) == TESSEL_ERR_LIMIT);
    CHECK(tsl_builder_reserve(&b, 10, 11) == TESSEL_ERR_LIMIT);
    const uint32_t poly[12] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
    CHECK(tsl_builder_polygon(&b, poly, 12) == TESSEL_OK); /* exactly 10 */
    CHECK(tsl_builder_polygon(&b, poly, 3) == TESSEL_ERR_LIMIT);
    tsl_builder_free(&b);

    /* Growth over many points; attributes declared late are zero-filled;
     * xyz stored as float(world - offset), the offset by the rule. */
    tsl_builder_init(&b, NULL);
    double *world = malloc(100000 * 3 * sizeof *world);
    for (int i = 0; i < 100000; i++) {
        double *p = world + 3 * i;
        p[0] = 6378137.0 + i * 0.01;
        p[1] = -1000.0 + i * 0.001;
        p[2] = i * 0.5;
        uint8_t rgb[3] = {1, 2, 3};
        if (i == 50)
            CHECK(tsl_builder_attributes(&b, 0, 1) == TESSEL_OK);
        CHECK(tsl_builder_point(&b, p, NULL, i >= 50 ? rgb : NULL) == TESSEL_OK);
    }
    CHECK(tsl_builder_finish_cloud(&b, &c) == TESSEL_OK);
    CHECK(c.count == 100000 && c.rgb && c.rgb[0] == 0 && c.rgb[3 * 60] == 1);
    /* x and z: the sample's median, mid-range; y stays within 4096 */
    CHECK(c.offset[0] == rule_offset(world, 100000, 0) && c.offset[0] > 6378137.0 + 400 &&
          c.offset[0] < 6378137.0 + 600);
    CHECK(c.offset[1] == 0.0);
    CHECK(c.offset[2] == rule_offset(world, 100000, 2) && c.offset[2] > 20000 &&
          c.offset[2] < 30000);
    bool exact = true;
    for (int i = 0; i < 100000 && exact; i++)
        for (int k = 0; k < 3; k++)
            exact = exact && c.xyz[3 * i + k] == (float)(world[3 * i + k] - c.offset[k]);
    CHECK(exact);
    free(world);
    tessel_cloud_free(&c);
    tsl_builder_free(&b);

    /* Never rounded up across an integer: the offset survives. */
    tsl_builder_init(&b, NULL);
    double edge[3] = {700000.99999999, 10, 10}; /* 1.0f to nearest */
    CHECK(tsl_builder_point(&b, edge, NULL, NULL) == TESSEL_OK);
    CHECK(tsl_builder_finish_cloud(&b, &c) == TESSEL_OK);
    CHECK_MSG(c.offset[0] == 700000.0 && c.xyz[0] == nextafterf(1.0f, 0.0f), "%.17g %.9g",
              c.offset[0], (double)c.xyz[0]);
    tessel_cloud_free(&c);
    tsl_builder_free(&b);
}

/* ---- exact round trips of georeferenced clouds ---- */

/* Values a stray point takes: a scanner's origin, far negative, the 1e15
 * readers keep, tiny and denormal numbers, just off an integer. */
static double stray_value(double bulk)
{
    static const double v[] = {0.0,     -1e5,   1e5,        -1e15,  1e15, -1e-20,
                               1e-300,  -5e-324, -0.0,      0.5,    -1.0 - 1e-12};
    size_t k = (size_t)(rnd_u64() % (sizeof v / sizeof v[0] + 3));
    if (k < sizeof v / sizeof v[0])
        return v[k];
    if (k == sizeof v / sizeof v[0])
        return -bulk + rnd();  /* the mirror of the bulk */
    return (rnd() - 0.5) * pow(10.0, (double)(rnd_u64() % 16)); /* anywhere */
}

/* Writes a cloud in every format that stores points, reads it back, writes
 * and reads again: offsets and floats must be identical bit for bit. */
static void round_trip_all_formats(const tessel_cloud *c0, const char *what)
{
    static const struct {
        const char *name;
        int ascii;
    } files[] = {{"geo.ply", 0}, {"geo.ply", 1}, {"geo.xyz", 0},
                 {"geo.csv", 0}, {"geo.obj", 0}, {"geo.off", 0}};
    char path[512];
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        tessel_write_params wp = tessel_write_params_default();
        wp.ascii = files[f].ascii;
        path_in(path, sizeof path, files[f].name);
        const tessel_cloud *src = c0;
        tessel_cloud back[2];
        for (int pass = 0; pass < 2; pass++) {
            tessel_diag d;
            CHECK(tessel_cloud_write(src, path, &wp, &d) == TESSEL_OK);
            tessel_status st = tessel_cloud_read(&back[pass], path, NULL, &d);
            CHECK_MSG(st == TESSEL_OK, "%s %s: %s", what, files[f].name, d.message);
            if (st != TESSEL_OK)
                break;
            const tessel_cloud *r = &back[pass];
            CHECK_MSG(r->count == c0->count &&
                          memcmp(r->offset, c0->offset, sizeof c0->offset) == 0 &&
                          memcmp(r->xyz, c0->xyz, c0->count * 12) == 0,
                      "%s, %s%s, pass %d: not exact (offset %.17g %.17g %.17g, was %.17g "
                      "%.17g %.17g; %zu points, was %zu)",
                      what, files[f].name, files[f].ascii ? " ascii" : "", pass,
                      r->offset[0], r->offset[1], r->offset[2], c0->offset[0],
                      c0->offset[1], c0->offset[2], r->count, c0->count);
            src = r;
            if (pass == 1) {
                tessel_cloud_free(&back[0]);
                tessel_cloud_free(&back[1]);
            } else if (st != TESSEL_OK) {
                break;
            }
        }
        unlink(path);
    }
}

static void test_georeferenced(void)
{
    static const double base[5][3] = {
        {500000.0, 5400000.0, 200.0},            /* UTM */
        {4200000.0, -700000.0, 4700000.0},       /* ECEF */
        {-5000.25, 4095.75, -4096.0},            /* around the threshold */
        {-3.0, 0.0, 1.0},                        /* ordinary data */
        {999999999990000.0, -999999999990000.0, 123456789.0}, /* at the limit */
    };
    const size_t bulk = 20000;
    double *world = malloc((bulk + 64) * 3 * sizeof *world);
    bool *is_stray = malloc(bulk + 64);
    for (int set = 0; set < 5; set++) {
        for (int strays = 0; strays < 2; strays++) {
            /* The bulk, with points exactly on the integer; then, in the
             * second pass, 1-64 stray points at random places in the order,
             * a scanner's origin among them. */
            double extent = set == 2 ? 1.5 : 2000.0;
            size_t n = bulk, ns = strays ? 1 + (size_t)(rnd_u64() % 64) : 0;
            for (size_t i = 0; i < bulk; i++)
                for (int k = 0; k < 3; k++)
                    world[3 * i + k] = base[set][k] + (i < 3 && k == (int)i ? 0 : rnd() * extent);
            memset(is_stray, 0, bulk + 64);
            for (size_t s = 0; s < ns; s++) {
                size_t at = (size_t)(rnd_u64() % (n + 1));
                memmove(world + 3 * at + 3, world + 3 * at, (n - at) * 3 * sizeof *world);
                memmove(is_stray + at + 1, is_stray + at, n - at);
                for (int k = 0; k < 3; k++)
                    world[3 * at + k] = s == 0 ? 0.0 : stray_value(base[set][k]);
                is_stray[at] = true;
                n++;
            }
            tsl_builder b;
            tsl_builder_init(&b, NULL);
            for (size_t i = 0; i < n; i++)
                CHECK(tsl_builder_point(&b, world + 3 * i, NULL, NULL) == TESSEL_OK);
            tessel_cloud c0;
            CHECK(tsl_builder_finish_cloud(&b, &c0) == TESSEL_OK);
            CHECK(c0.count == n);
            /* Precision kept whatever the strays: the offset lies in the
             * bulk's integer range (or is 0 with the bulk near 4096), so
             * every bulk coordinate is stored within 2^-11 m (half a mm:
             * one float ulp at 4096, as without strays). Before, a stray at
             * 0 moved UTM local coordinates out to 5e5-5e6: 30-500 mm. */
            double worst = 0;
            bool inside = true;
            for (int k = 0; k < 3; k++) {
                double lo = floor(base[set][k]), hi = floor(base[set][k] + extent);
                inside = inside && (c0.offset[k] == 0 ? fabs(lo) <= 4096 || fabs(hi) <= 4096
                                                      : c0.offset[k] >= lo && c0.offset[k] <= hi);
            }
            for (size_t i = 0; i < n && c0.count == n; i++)
                for (int k = 0; k < 3 && !is_stray[i]; k++)
                    worst = fmax(worst, fabs(c0.offset[k] + (double)c0.xyz[3 * i + k] -
                                             world[3 * i + k]));
            char what[64];
            snprintf(what, sizeof what, "set %d with %zu strays", set, ns);
            CHECK_MSG(inside && worst <= 1.0 / 2048,
                      "%s: offset %.17g %.17g %.17g, worst error %.3g", what, c0.offset[0],
                      c0.offset[1], c0.offset[2], worst);
            round_trip_all_formats(&c0, what);
            tessel_cloud_free(&c0);
        }
    }
    free(world);
    free(is_stray);
}

/* ---- atomic writes and read errors ---- */

static void make_cloud(tessel_cloud *c, size_t n)
{
    tessel_cloud_alloc(c, n, 1, 1);
    for (size_t i = 0; i < 3 * n; i++) {
        c->xyz[i] = (float)(rnd() * 10);
        c->normals[i] = (float)rnd();
        c->rgb[i] = (uint8_t)i;
    }
}

static void test_atomic(void)
{
    char path[512], missing[512];
    int temps;
    tessel_cloud c;
    make_cloud(&c, 100000);
    size_t before = dir_entries(tmpdir, &temps);

    /* A folder that does not exist. */
    path_in(missing, sizeof missing, "no/such/folder/out.ply");
    tessel_diag d;
    CHECK(tessel_cloud_write(&c, missing, NULL, &d) == TESSEL_ERR_IO);
    CHECK(strcmp(d.file, missing) == 0 && strstr(d.message, strerror(ENOENT)));
    CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);
    tessel_mesh_writer *mw;
    CHECK(tessel_mesh_writer_open(&mw, missing, &c, NULL, 1, &d) == TESSEL_ERR_IO && !mw);
    CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);

    /* A destination that exists, then writes that fail. */
    path_in(path, sizeof path, "keep.ply");
    static const uint8_t original[] = "original content\n";
    FILE *f = fopen(path, "wb");
    fwrite(original, 1, sizeof original - 1, f);
    fclose(f);
    chmod(path, 0640);
    before = dir_entries(tmpdir, &temps);

    /* Refused before writing: no triangles in STL, bad indices, no format. */
    char stl[512];
    path_in(stl, sizeof stl, "keep.stl");
    CHECK(tessel_cloud_write(&c, stl, NULL, &d) == TESSEL_ERR_UNSUPPORTED);
    tessel_mesh m;
    memset(&m, 0, sizeof m);
    uint32_t tri[3] = {0, 1, 100000};
    m.vertex_count = c.count;
    m.xyz = c.xyz;
    m.triangle_count = 1;
    m.triangles = tri;
    CHECK(tessel_mesh_write(&m, path, NULL, &d) == TESSEL_ERR_INVALID_ARG);
    CHECK(strstr(d.message, "triangle 0 uses vertex 100000") != NULL);
    char noext[512];
    path_in(noext, sizeof noext, "noext");
    CHECK(tessel_cloud_write(&c, noext, NULL, &d) == TESSEL_ERR_INVALID_ARG);
    CHECK(file_equals(path, original, sizeof original - 1));
    CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);

    /* Halfway: the file size limit makes a write fail after 64 KiB. */
    struct rlimit old, lim;
    getrlimit(RLIMIT_FSIZE, &old);
    signal(SIGXFSZ, SIG_IGN);
    lim = old;
    lim.rlim_cur = 65536;
    if (setrlimit(RLIMIT_FSIZE, &lim) == 0) {
        CHECK(tessel_cloud_write(&c, path, NULL, &d) == TESSEL_ERR_IO);
        CHECK(strcmp(d.file, path) == 0 && strstr(d.message, "write failed") != NULL);
        tessel_write_params wp = tessel_write_params_default();
        wp.ascii = 1;
        CHECK(tessel_cloud_write(&c, path, &wp, &d) == TESSEL_ERR_IO);
        /* the streaming writer fails at close */
        tessel_mesh_writer *w;
        CHECK(tessel_mesh_writer_open(&w, path, &c, NULL, 0, &d) == TESSEL_OK);
        uint32_t t3[3] = {0, 1, 2};
        CHECK(tessel_mesh_writer_add(w, t3, 1) == TESSEL_OK);
        CHECK(tessel_mesh_writer_close(w, &d) == TESSEL_ERR_IO);
        setrlimit(RLIMIT_FSIZE, &old);
        CHECK(file_equals(path, original, sizeof original - 1));
        CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);
    }
    signal(SIGXFSZ, SIG_DFL);

    /* Success replaces the file, keeping its mode. */
    CHECK(tessel_cloud_write(&c, path, NULL, &d) == TESSEL_OK);
    struct stat st;
    CHECK(stat(path, &st) == 0 && (st.st_mode & 0777) == 0640);
    CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);
    /* A new file gets 0666 minus the umask, not mkstemp's 0600. */
    mode_t mask = umask(022);
    char fresh[512];
    path_in(fresh, sizeof fresh, "fresh.xyz");
    CHECK(tessel_cloud_write(&c, fresh, NULL, &d) == TESSEL_OK);
    CHECK(stat(fresh, &st) == 0 && (st.st_mode & 0777) == 0644);
    umask(mask);
    unlink(fresh);
    unlink(path);
    tessel_cloud_free(&c);

    /* Read errors name the file and say why. */
    tessel_cloud r;
    path_in(path, sizeof path, "does-not-exist.ply");
    CHECK(tessel_cloud_read(&r, path, NULL, &d) == TESSEL_ERR_IO);
    CHECK(strcmp(d.file, path) == 0 && strstr(d.message, strerror(ENOENT)) != NULL);
    CHECK(r.count == 0 && r.xyz == NULL);
    CHECK(tessel_cloud_read(&r, tmpdir, NULL, &d) == TESSEL_ERR_IO);
    CHECK(strstr(d.message, "folder") != NULL);
    tessel_mesh rm;
    CHECK(tessel_mesh_read(&rm, path, NULL, &d) == TESSEL_ERR_IO);
}

/* ---- format names and detection ---- */

static void test_formats(void)
{
    static const struct {
        const char *path;
        tessel_format format;
    } paths[] = {
        {"a.ply", TESSEL_FORMAT_PLY}, {"A.PLY", TESSEL_FORMAT_PLY},
        {"x/y.z/scan.xyz", TESSEL_FORMAT_XYZ}, {"s.pts", TESSEL_FORMAT_XYZ},
        {"s.txt", TESSEL_FORMAT_XYZ}, {"s.asc", TESSEL_FORMAT_XYZ},
        {"s.csv", TESSEL_FORMAT_CSV}, {"m.obj", TESSEL_FORMAT_OBJ},
        {"m.Off", TESSEL_FORMAT_OFF}, {"m.stl", TESSEL_FORMAT_STL},
        {"c.pcd", TESSEL_FORMAT_PCD}, {"c.las", TESSEL_FORMAT_LAS},
        {"dir.ply/file", TESSEL_FORMAT_AUTO}, {".ply", TESSEL_FORMAT_AUTO},
        {"c.laz", TESSEL_FORMAT_AUTO}, {"plain", TESSEL_FORMAT_AUTO},
    };
    for (size_t i = 0; i < sizeof paths / sizeof paths[0]; i++)
        CHECK_MSG(tessel_format_from_path(paths[i].path) == paths[i].format, "%s",
                  paths[i].path);
    CHECK(tessel_format_from_path(NULL) == TESSEL_FORMAT_AUTO);
    CHECK(strcmp(tessel_format_name(TESSEL_FORMAT_PLY), "ply") == 0);
    CHECK(strcmp(tessel_format_name(TESSEL_FORMAT_LAS), "las") == 0);
    CHECK(strcmp(tessel_format_name((tessel_format)99), "unknown") == 0);

    /* Content sniffing with no name: each gives a triangle or 3 points. */
    static const struct {
        const char *text;
        size_t points, triangles;
    } contents[] = {
        {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
         "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
         3, 1},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", 3, 1},
        {"# comment\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 3, 1},
        {"0 0 0\n1 0 0\n0 1 0\n", 3, 0},
        {"0,0,0\n1,0,0\n0,1,0\n", 3, 0},
        {"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
         "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n0 0 0\n1 0 0\n"
         "0 1 0\n",
         3, 0},
    };
    for (size_t i = 0; i < sizeof contents / sizeof contents[0]; i++) {
        tessel_mesh m;
        tessel_diag d;
        tessel_status st =
            tessel_mesh_parse(&m, contents[i].text, strlen(contents[i].text), NULL, NULL, &d);
        CHECK_MSG(st == TESSEL_OK && m.vertex_count == contents[i].points &&
                      m.triangle_count == contents[i].triangles,
                  "content %zu: %s %s", i, tessel_status_str(st), d.message);
        if (st == TESSEL_OK)
            tessel_mesh_free(&m);
    }
    /* The name's extension wins over the content; STL is not read. */
    tessel_cloud c;
    tessel_diag d;
    CHECK(tessel_cloud_parse(&c, "0 0 0\n", 6, "x.ply", NULL, &d) == TESSEL_ERR_PARSE);
    CHECK(strcmp(d.file, "x.ply") == 0);
    CHECK(tessel_cloud_parse(&c, "solid", 5, "x.stl", NULL, &d) == TESSEL_ERR_UNSUPPORTED);
    CHECK(tessel_cloud_parse(&c, NULL, 0, NULL, NULL, &d) != TESSEL_OK || c.count == 0);
    tessel_cloud_free(&c);
}

/* A file that is not regular (a pipe) is read by growing the buffer from
 * 64 KB, here past the 4 MB where growth copies into huge-page advised
 * blocks: the cloud must equal the one read from the regular file. */
static void test_pipe_read(void)
{
    enum { N = 400000 }; /* 4.8 MB of binary floats */
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, N, 0, 0) == TESSEL_OK);
    if (!c.xyz)
        return;
    for (size_t i = 0; i < 3 * (size_t)N; i++)
        c.xyz[i] = (float)(rnd() * 2.0 - 1.0);
    char file[512], fifo[512];
    path_in(file, sizeof file, "pipe_src.ply");
    path_in(fifo, sizeof fifo, "pipe.ply");
    tessel_diag d;
    CHECK(tessel_cloud_write(&c, file, NULL, &d) == TESSEL_OK);
    CHECK(mkfifo(fifo, 0600) == 0);
    pid_t pid = fork();
    if (pid == 0) {
        /* The writer: copies the file into the pipe, then leaves without
         * running the parent's exit handlers. */
        FILE *in = fopen(file, "rb"), *out = fopen(fifo, "wb");
        char buf[1 << 16];
        size_t got;
        while (in && out && (got = fread(buf, 1, sizeof buf, in)) > 0)
            if (fwrite(buf, 1, got, out) != got)
                break;
        _exit(in && out && fclose(out) == 0 ? 0 : 1);
    }
    CHECK(pid > 0);
    tessel_cloud a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    if (pid > 0) {
        CHECK_MSG(tessel_cloud_read(&a, fifo, NULL, &d) == TESSEL_OK, "%s", d.message);
        int status = 1;
        CHECK(waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    CHECK(tessel_cloud_read(&b, file, NULL, &d) == TESSEL_OK);
    CHECK(a.count == N && b.count == N);
    if (a.count == N && b.count == N)
        CHECK(memcmp(a.xyz, b.xyz, 3 * (size_t)N * sizeof(float)) == 0);
    tessel_cloud_free(&a);
    tessel_cloud_free(&b);
    tessel_cloud_free(&c);
    remove(fifo);
    remove(file);
}

/* ---- streaming writer ---- */

/* Writes cloud + tris through the streaming writer in uneven batches. */
static tessel_status stream(const char *path, const tessel_cloud *c, const uint32_t *tris,
                            size_t nt, const tessel_write_params *wp, int compact)
{
    tessel_mesh_writer *w;
    tessel_diag d;
    tessel_status st = tessel_mesh_writer_open(&w, path, c, wp, compact, &d);
    if (st != TESSEL_OK)
        return st;
    tessel_triangle_sink sink = tessel_mesh_writer_sink(w);
    size_t done = 0, batch = 0;
    while (done < nt && st == TESSEL_OK) {
        size_t k = (batch++ * 7919) % 5000;
        if (k > nt - done)
            k = nt - done;
        st = sink.emit(sink.user_data, tris + 3 * done, k);
        done += k;
    }
    if (st != TESSEL_OK) {
        tessel_mesh_writer_abort(w);
        return st;
    }
    return tessel_mesh_writer_close(w, &d);
}

static void test_streaming(void)
{
    char spath[512], mpath[512];
    int temps;
    tessel_cloud c;
    make_cloud(&c, 30000);
    c.offset[0] = 123456.0;
    /* 150000 triangles (several spool batches) on the first 20000 points. */
    size_t nt = 150000;
    uint32_t *tris = malloc(nt * 3 * sizeof(uint32_t));
    for (size_t i = 0; i < 3 * nt; i++)
        tris[i] = (uint32_t)(rnd_u64() % 20000) * 3 / 2; /* some points unused */
    /* The same mesh in memory: full, and compacted by hand. */
    tessel_mesh full;
    memset(&full, 0, sizeof full);
    full.vertex_count = c.count;
    full.xyz = c.xyz;
    full.normals = c.normals;
    full.rgb = c.rgb;
    memcpy(full.offset, c.offset, sizeof full.offset);
    full.triangle_count = nt;
    full.triangles = tris;
    tessel_mesh compact = full;
    uint32_t *remap = malloc(c.count * sizeof(uint32_t));
    for (size_t i = 0; i < c.count; i++)
        remap[i] = TESSEL_NONE;
    for (size_t i = 0; i < 3 * nt; i++)
        remap[tris[i]] = 0;
    float *cx = malloc(c.count * 12), *cn = malloc(c.count * 12);
    uint8_t *cc = malloc(c.count * 3);
    size_t k = 0;
    for (size_t i = 0; i < c.count; i++) {
        if (remap[i] == TESSEL_NONE)
            continue;
        memcpy(cx + 3 * k, c.xyz + 3 * i, 12);
        memcpy(cn + 3 * k, c.normals + 3 * i, 12);
        memcpy(cc + 3 * k, c.rgb + 3 * i, 3);
        remap[i] = (uint32_t)k++;
    }
    uint32_t *ctris = malloc(nt * 3 * sizeof(uint32_t));
    for (size_t i = 0; i < 3 * nt; i++)
        ctris[i] = remap[tris[i]];
    compact.vertex_count = k;
    compact.xyz = cx;
    compact.normals = cn;
    compact.rgb = cc;
    compact.triangles = ctris;
    CHECK(k > 19000 && k <= 20000);

    static const struct {
        const char *ext;
        int ascii;
    } formats[] = {{"ply", 0}, {"ply", 1}, {"obj", 0}, {"off", 0}, {"stl", 0}};
    for (size_t f = 0; f < sizeof formats / sizeof formats[0]; f++) {
        char name[64];
        snprintf(name, sizeof name, "stream.%s", formats[f].ext);
        path_in(spath, sizeof spath, name);
        snprintf(name, sizeof name, "memory.%s", formats[f].ext);
        path_in(mpath, sizeof mpath, name);
        tessel_write_params wp = tessel_write_params_default();
        wp.ascii = formats[f].ascii;
        for (int comp = 0; comp < 2; comp++) {
            CHECK(stream(spath, &c, tris, nt, &wp, comp) == TESSEL_OK);
            CHECK(tessel_mesh_write(comp ? &compact : &full, mpath, &wp, NULL) == TESSEL_OK);
            CHECK_MSG(same_files(spath, mpath), "%s ascii=%d compact=%d differs",
                      formats[f].ext, formats[f].ascii, comp);
        }
        unlink(spath);
        unlink(mpath);
    }
    /* The PLY result reads back as the mesh. */
    path_in(spath, sizeof spath, "stream.ply");
    CHECK(stream(spath, &c, tris, nt, NULL, 1) == TESSEL_OK);
    tessel_mesh r;
    CHECK(tessel_mesh_read(&r, spath, NULL, NULL) == TESSEL_OK);
    CHECK(r.vertex_count == k && r.triangle_count == nt);
    CHECK(r.triangle_count == nt && memcmp(r.triangles, ctris, nt * 12) == 0);
    /* c's offset is not one a reader picks: compare world coordinates. */
    double worst = r.vertex_count == k ? 0.0 : INFINITY;
    for (size_t i = 0; i < 3 * k && r.vertex_count == k; i++)
        worst = fmax(worst, fabs((r.offset[i % 3] + r.xyz[i]) - (c.offset[i % 3] + cx[i])));
    CHECK_MSG(worst < 1e-6, "worst %g", worst);
    tessel_mesh_free(&r);

    /* Abort and failures leave the destination and the folder as they were. */
    size_t before = dir_entries(tmpdir, &temps);
    uint8_t *orig;
    size_t orig_size;
    CHECK(tsl_read_file(spath, &orig, &orig_size, NULL) == TESSEL_OK);
    tessel_mesh_writer *w;
    CHECK(tessel_mesh_writer_open(&w, spath, &c, NULL, 1, NULL) == TESSEL_OK);
    CHECK(tessel_mesh_writer_add(w, tris, 1000) == TESSEL_OK);
    CHECK(dir_entries(tmpdir, &temps) == before + 2 && temps == 2); /* output + spool */
    tessel_mesh_writer_abort(w);
    CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);
    CHECK(file_equals(spath, orig, orig_size));
    /* An index out of range: add refuses it, close reports it. */
    CHECK(tessel_mesh_writer_open(&w, spath, &c, NULL, 0, NULL) == TESSEL_OK);
    uint32_t bad[3] = {0, 1, 30000};
    CHECK(tessel_mesh_writer_add(w, bad, 1) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_mesh_writer_add(w, tris, 1) == TESSEL_ERR_INVALID_ARG);
    tessel_diag d;
    CHECK(tessel_mesh_writer_close(w, &d) == TESSEL_ERR_INVALID_ARG);
    CHECK(strcmp(d.file, spath) == 0);
    CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);
    CHECK(file_equals(spath, orig, orig_size));
    /* Point formats cannot hold triangles. */
    char xyz[512];
    path_in(xyz, sizeof xyz, "stream.xyz");
    CHECK(tessel_mesh_writer_open(&w, xyz, &c, NULL, 0, &d) == TESSEL_ERR_UNSUPPORTED);
    CHECK(dir_entries(tmpdir, &temps) == before && temps == 0);
    tessel_mesh_writer_abort(NULL);
    /* No triangles at all: a valid empty mesh (compact: no vertices). */
    CHECK(tessel_mesh_writer_open(&w, spath, &c, NULL, 1, NULL) == TESSEL_OK);
    CHECK(tessel_mesh_writer_close(w, NULL) == TESSEL_OK);
    CHECK(tessel_mesh_read(&r, spath, NULL, NULL) == TESSEL_OK);
    CHECK(r.vertex_count == 0 && r.triangle_count == 0);
    tessel_mesh_free(&r);
    unlink(spath);
    free(orig);
    free(ctris);
    free(cx);
    free(cn);
    free(cc);
    free(remap);
    free(tris);
    tessel_cloud_free(&c);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/tessel_test_io_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_scan();
    test_local_coord();
    test_offsets();
    test_builder();
    test_georeferenced();
    test_atomic();
    test_formats();
    test_pipe_read();
    test_streaming();
    int temps;
    CHECK(dir_entries(tmpdir, &temps) == 0);
    rmdir(tmpdir);
    return TEST_SUMMARY();
}
