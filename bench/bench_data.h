/* What the benchmarks share: a fixed-seed random generator, a sampler of a
 * torus surface and a deterministic query radius (the neighbour benchmarks,
 * bench_kdtree.c and the optional bench_nanoflann.cpp), a minimal reader
 * for binary little-endian PLY vertices (float or double x y z first),
 * wall and CPU clocks and the peak resident memory. Valid C11 and C++11 so
 * the C and C++ programs measure exactly the same points. */
#ifndef TESSEL_BENCH_DATA_H
#define TESSEL_BENCH_DATA_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

/* splitmix64: tiny, fixed-seed, identical in C and C++. */
static inline uint64_t bench_rng(uint64_t *s)
{
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static inline double bench_unif(uint64_t *s)
{
    return (double)(bench_rng(s) >> 11) * (1.0 / 9007199254740992.0);
}
/* Standard normal (Box-Muller, one of the pair). */
static inline double bench_gauss(uint64_t *s)
{
    double u = bench_unif(s), v = bench_unif(s);
    return sqrt(-2.0 * log(u + 1e-300)) * cos(6.283185307179586 * v);
}

#define BENCH_TORUS_R 1.0
#define BENCH_TORUS_r 0.35

/* n points uniformly distributed (by area) on a torus with radii 1 and
 * 0.35, in random order. Returns a malloc'd n*3 array or NULL. */
static inline float *bench_torus(size_t n, uint64_t seed)
{
    float *xyz = (float *)malloc(n * 3 * sizeof(float) + 1);
    if (!xyz)
        return NULL;
    uint64_t s = seed;
    const double two_pi = 6.283185307179586;
    for (size_t i = 0; i < n;) {
        double u = two_pi * bench_unif(&s), v = two_pi * bench_unif(&s);
        /* Area element is proportional to R + r cos v: rejection. */
        double w = bench_unif(&s) * (BENCH_TORUS_R + BENCH_TORUS_r);
        if (w > BENCH_TORUS_R + BENCH_TORUS_r * cos(v))
            continue;
        double rr = BENCH_TORUS_R + BENCH_TORUS_r * cos(v);
        xyz[3 * i] = (float)(rr * cos(u));
        xyz[3 * i + 1] = (float)(rr * sin(u));
        xyz[3 * i + 2] = (float)(BENCH_TORUS_r * sin(v));
        i++;
    }
    return xyz;
}

/* Query radius for about 16 neighbours: the mean distance to the 16th
 * nearest point (self included) over 16 evenly strided points, brute force.
 * Deterministic, so both benchmarks use the same radius. */
static inline float bench_radius16(const float *xyz, size_t n)
{
    enum { K = 16, S = 16 };
    if (n < K)
        return 0.0f;
    double sum = 0.0;
    for (int s = 0; s < S; s++) {
        const float *q = xyz + 3 * ((size_t)s * (n / S));
        float best[K];
        for (int j = 0; j < K; j++)
            best[j] = INFINITY;
        for (size_t i = 0; i < n; i++) {
            float dx = xyz[3 * i] - q[0], dy = xyz[3 * i + 1] - q[1],
                  dz = xyz[3 * i + 2] - q[2];
            float d = (dx * dx + dy * dy) + dz * dz;
            if (d < best[K - 1]) {
                int j = K - 1;
                while (j > 0 && best[j - 1] > d) {
                    best[j] = best[j - 1];
                    j--;
                }
                best[j] = d;
            }
        }
        sum += sqrt((double)best[K - 1]);
    }
    return (float)(sum / S);
}

/* Reads the vertex positions of a binary little-endian PLY whose vertex
 * element comes first and starts with x y z (float or double; further
 * scalar properties are skipped). Returns a malloc'd count*3 array, or NULL
 * with a message on stderr. Enough for the benchmark's real scans; the
 * library's reader is tessel_cloud_read. */
static inline float *bench_read_ply(const char *path, size_t *count)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "bench: cannot open %s\n", path);
        return NULL;
    }
    char line[512];
    size_t n = 0, stride = 0;
    int in_vertex = 0, nprops = 0, is_double = 0, ok = 0;
    while (fgets(line, sizeof line, f)) {
        unsigned long long v;
        char type[32], name[64];
        if (strncmp(line, "format", 6) == 0 && !strstr(line, "binary_little_endian"))
            break;
        if (sscanf(line, "element vertex %llu", &v) == 1) {
            n = (size_t)v;
            in_vertex = 1;
        } else if (strncmp(line, "element", 7) == 0) {
            in_vertex = 0;
        } else if (in_vertex && sscanf(line, "property %31s %63s", type, name) == 2) {
            size_t size = (!strcmp(type, "double") || !strcmp(type, "float64")) ? 8
                          : (!strcmp(type, "float") || !strcmp(type, "float32") ||
                             !strcmp(type, "int") || !strcmp(type, "uint"))
                              ? 4
                          : (!strcmp(type, "uchar") || !strcmp(type, "char")) ? 1
                                                                               : 0;
            if (size == 0)
                break;
            if (nprops == 0)
                is_double = size == 8;
            stride += size;
            nprops++;
        } else if (strncmp(line, "end_header", 10) == 0) {
            ok = n > 0 && nprops >= 3;
            break;
        }
    }
    float *xyz = ok ? (float *)malloc(n * 3 * sizeof(float)) : NULL;
    unsigned char *rec = ok ? (unsigned char *)malloc(stride) : NULL;
    for (size_t i = 0; xyz && rec && i < n; i++) {
        if (fread(rec, 1, stride, f) != stride) {
            free(xyz);
            xyz = NULL;
            break;
        }
        for (int a = 0; a < 3; a++) {
            if (is_double) {
                double d;
                memcpy(&d, rec + 8 * a, 8);
                xyz[3 * i + a] = (float)d;
            } else {
                memcpy(&xyz[3 * i + a], rec + 4 * a, 4);
            }
        }
    }
    free(rec);
    fclose(f);
    if (!xyz)
        fprintf(stderr, "bench: %s: not a binary little-endian PLY with x y z\n", path);
    *count = xyz ? n : 0;
    return xyz;
}

static inline double bench_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU time of the process: for one-thread figures it is the work's own
 * time, which other jobs on the machine disturb much less than wall time. */
static inline double bench_cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Peak resident memory of the process so far, bytes (Linux reports KiB). */
static inline size_t bench_peak_rss_bytes(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (size_t)ru.ru_maxrss * 1024u;
}

/* One-thread figures in CPU time, threaded ones in wall time. */
static inline double bench_clock(int one_thread)
{
    return one_thread ? bench_cpu_now() : bench_now();
}

/* Repetitions so that one timing covers at least 2*10^5 queries (and as
 * many builds of a small cloud): small sets alone finish in a few
 * milliseconds, where one scheduler hiccup changes the figure. */
static inline int bench_reps(size_t n, size_t queries)
{
    (void)n;
    return queries >= 200000 ? 1 : (int)((200000 + queries - 1) / (queries ? queries : 1));
}

/* Median of three. */
static inline double bench_median3(double a, double b, double c)
{
    if (a > b) {
        double t = a;
        a = b;
        b = t;
    }
    if (b > c)
        b = c;
    return a > b ? a : b;
}

#endif
