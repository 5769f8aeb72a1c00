/* Reader throughput for LAS and XYZ on generated files in memory (so the
 * disk does not enter the figure): points/s and bytes/point through the
 * public tessel_cloud_parse, median of three runs. Data: n points of a
 * fixed-seed torus (bench_data.h) moved to UTM-like coordinates (offset
 * 637000, 5120000, 300) so the double-offset path is exercised.
 *  - LAS 1.2, point format 3 (34 bytes, RGB), scale 0.001;
 *  - XYZ text "x y z" with 3 decimals, and the same with normals.
 * For comparison, the XYZ text is also parsed by a plain strtod loop (no
 * checks, no builder): the cost of the C library alone.
 *
 * Usage: bench_formats [N]   (default 1000000 points) */
#include "tessel.h"

#include "bench_data.h"

#define UTM_X 637000.0
#define UTM_Y 5120000.0
#define UTM_Z 300.0
#define SCALE 0.001

static void put16(uint8_t *p, unsigned v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static void put32(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; k++)
        p[k] = (uint8_t)(v >> (8 * k));
}
static void putf64(uint8_t *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    for (int k = 0; k < 8; k++)
        p[k] = (uint8_t)(u >> (8 * k));
}

/* World coordinate k of point i (torus scaled to a 200 m wide tile). */
static double world(const float *xyz, size_t i, int k)
{
    static const double base[3] = {UTM_X, UTM_Y, UTM_Z};
    return base[k] + 100.0 * xyz[3 * i + k];
}

static uint8_t *make_las(const float *xyz, size_t n, size_t *size)
{
    const size_t hs = 227, rec = 34;
    *size = hs + n * rec;
    uint8_t *d = calloc(*size, 1);
    if (!d)
        return NULL;
    memcpy(d, "LASF", 4);
    d[24] = 1;
    d[25] = 2;
    put16(d + 94, (unsigned)hs);
    put32(d + 96, (uint32_t)hs);
    d[104] = 3;
    put16(d + 105, (unsigned)rec);
    put32(d + 107, (uint32_t)n);
    static const double base[3] = {UTM_X, UTM_Y, UTM_Z};
    for (int k = 0; k < 3; k++) {
        putf64(d + 131 + 8 * k, SCALE);
        putf64(d + 155 + 8 * k, base[k]);
    }
    for (size_t i = 0; i < n; i++) {
        uint8_t *r = d + hs + i * rec;
        for (int k = 0; k < 3; k++)
            put32(r + 4 * k, (uint32_t)(int32_t)lround((world(xyz, i, k) - base[k]) / SCALE));
        for (int k = 0; k < 3; k++)
            put16(r + 28 + 2 * k, (unsigned)(i * (k + 1) * 97) & 0xFFFF);
    }
    return d;
}

static char *make_xyz(const float *xyz, size_t n, int normals, size_t *size)
{
    size_t cap = n * (normals ? 80 : 48) + 1;
    char *t = malloc(cap);
    if (!t)
        return NULL;
    size_t len = 0;
    for (size_t i = 0; i < n; i++) {
        len += (size_t)snprintf(t + len, cap - len, "%.3f %.3f %.3f", world(xyz, i, 0),
                                world(xyz, i, 1), world(xyz, i, 2));
        if (normals)
            len += (size_t)snprintf(t + len, cap - len, " %.6f %.6f %.6f", 0.0, 0.6, 0.8);
        t[len++] = '\n';
    }
    *size = len;
    return t;
}

/* Seconds for one parse; checks the count. */
static double time_parse(const void *data, size_t size, const char *name, size_t n)
{
    tessel_cloud c;
    tessel_diag d;
    double t0 = bench_now();
    tessel_status st = tessel_cloud_parse(&c, data, size, name, NULL, &d);
    double t = bench_now() - t0;
    if (st != TESSEL_OK || c.count != n) {
        fprintf(stderr, "bench_formats: %s: %s (%s)\n", name, tessel_status_str(st),
                d.message);
        exit(1);
    }
    tessel_cloud_free(&c);
    return t;
}

/* The floor for text: strtod on every number, nothing else. */
static double time_strtod(const char *text, size_t n, double *checksum)
{
    double t0 = bench_now();
    const char *p = text;
    double sum = 0;
    for (size_t i = 0; i < 3 * n; i++) {
        char *end;
        sum += strtod(p, &end);
        p = end;
    }
    *checksum = sum;
    return bench_now() - t0;
}

static void report(const char *what, size_t n, size_t bytes, double a, double b, double c)
{
    double t = bench_median3(a, b, c);
    printf("%-28s %10zu points %7.1f MB %6.1f bytes/point %8.3f s %8.2f Mpoints/s\n", what,
           n, bytes / 1e6, (double)bytes / (double)n, t, n / t / 1e6);
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? (size_t)strtoull(argv[1], NULL, 10) : 1000000;
    if (n == 0) {
        fprintf(stderr, "usage: bench_formats [N]\n");
        return 1;
    }
    float *xyz = bench_torus(n, 42);
    size_t las_size, xyz_size, xyzn_size;
    uint8_t *las = make_las(xyz, n, &las_size);
    char *txt = make_xyz(xyz, n, 0, &xyz_size);
    char *txtn = make_xyz(xyz, n, 1, &xyzn_size);
    if (!xyz || !las || !txt || !txtn) {
        fprintf(stderr, "bench_formats: out of memory\n");
        return 1;
    }
    printf("tessel %s, reader throughput (median of 3, in memory)\n", tessel_version());
    report("LAS 1.2 format 3", n, las_size, time_parse(las, las_size, "b.las", n),
           time_parse(las, las_size, "b.las", n), time_parse(las, las_size, "b.las", n));
    report("XYZ x y z", n, xyz_size, time_parse(txt, xyz_size, "b.xyz", n),
           time_parse(txt, xyz_size, "b.xyz", n), time_parse(txt, xyz_size, "b.xyz", n));
    report("XYZ x y z nx ny nz", n, xyzn_size, time_parse(txtn, xyzn_size, "b.xyz", n),
           time_parse(txtn, xyzn_size, "b.xyz", n), time_parse(txtn, xyzn_size, "b.xyz", n));
    double s1, s2, s3;
    report("strtod loop (x y z, floor)", n, xyz_size, time_strtod(txt, n, &s1),
           time_strtod(txt, n, &s2), time_strtod(txt, n, &s3));
    printf("(strtod checksum %.6g)\n", s1 + s2 + s3);
    free(xyz);
    free(las);
    free(txt);
    free(txtn);
    return 0;
}
