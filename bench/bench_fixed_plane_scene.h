/* Synthetic inputs of bench_fixed_plane (and its optional PCL comparison):
 * a terrain sampled like airborne LIDAR and a room scanned from inside by
 * a terrestrial scanner with range noise. Fixed seeds, generated row by row
 * straight into flat float arrays (no per-point allocation), so 10^8 points
 * cost 1.2 GB. Plain C that also compiles as C++. */
#ifndef BENCH_FIXED_PLANE_SCENE_H
#define BENCH_FIXED_PLANE_SCENE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#define SCENE_PI 3.14159265358979323846

static inline uint64_t scene_mix(uint64_t z)
{
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
static inline double scene_uniform(uint64_t *s)
{
    *s = scene_mix(*s);
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}
static inline double scene_gauss(uint64_t *s)
{
    double u = scene_uniform(s), v = scene_uniform(s);
    if (u < 1e-300)
        u = 1e-300;
    return sqrt(-2.0 * log(u)) * cos(2.0 * SCENE_PI * v);
}

/* Terrain over a 1000 m square: rolling hills, a 6 m cliff along x = 600,
 * height noise sigma. side x side points, each jittered within its cell of
 * a regular lattice (the even spacing of airborne LIDAR), in scan-line
 * order. */
static inline double scene_terrain_height(double x, double y)
{
    double h = 20.0 * sin(x * 0.006) * cos(y * 0.004) + 5.0 * sin(x * 0.031 + y * 0.017);
    return x > 600.0 ? h + 6.0 : h;
}

static inline void scene_terrain(size_t side, double sigma, uint64_t seed, float *xyz)
{
    const double step = 1000.0 / (double)side;
#pragma omp parallel for schedule(static)
    for (long long r = 0; r < (long long)side; r++) {
        uint64_t s = scene_mix(seed ^ ((uint64_t)r * 0x51ed2701ull));
        for (size_t c = 0; c < side; c++) {
            double x = ((double)c + scene_uniform(&s)) * step;
            double y = ((double)r + scene_uniform(&s)) * step;
            float *p = xyz + 3 * ((size_t)r * side + c);
            p[0] = (float)x;
            p[1] = (float)y;
            p[2] = (float)(scene_terrain_height(x, y) + sigma * scene_gauss(&s));
        }
    }
}

/* The room: an 8 x 6 x 3 m box, a sphere and a table-like block in it,
 * the scanner at VP. */
static const double scene_vp[3] = {3.0, 2.5, 1.6};

static inline double scene_box_hit(const double o[3], const double d[3], const double lo[3],
                                   const double hi[3])
{
    double t0 = 0.0, t1 = INFINITY;
    for (int k = 0; k < 3; k++) {
        if (d[k] == 0.0) {
            if (o[k] < lo[k] || o[k] > hi[k])
                return INFINITY;
            continue;
        }
        double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
        if (a > b) {
            double t = a;
            a = b;
            b = t;
        }
        t0 = a > t0 ? a : t0;
        t1 = b < t1 ? b : t1;
        if (t0 > t1)
            return INFINITY;
    }
    return t0 > 0.0 ? t0 : INFINITY;
}

/* Range from the scanner along unit d. */
static inline double scene_room_cast(const double d[3])
{
    static const double lo[3] = {0, 0, 0}, hi[3] = {8, 6, 3};
    static const double sc[3] = {5.5, 4.0, 1.0}, sr = 0.6;
    static const double tlo[3] = {0.8, 0.8, 0.7}, thi[3] = {2.2, 1.8, 0.8};
    static const double blo[3] = {5.0, 0.3, 0.0}, bhi[3] = {7.5, 1.0, 2.0};
    double best = INFINITY;
    for (int k = 0; k < 3; k++) {
        double t = d[k] > 0 ? (hi[k] - scene_vp[k]) / d[k]
                 : d[k] < 0 ? (lo[k] - scene_vp[k]) / d[k] : INFINITY;
        best = t < best ? t : best;
    }
    double oc[3] = {scene_vp[0] - sc[0], scene_vp[1] - sc[1], scene_vp[2] - sc[2]};
    double b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    double disc = b * b - (oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - sr * sr);
    if (disc > 0) {
        double t = -b - sqrt(disc);
        if (t > 0 && t < best)
            best = t;
    }
    double t = scene_box_hit(scene_vp, d, tlo, thi);
    best = t < best ? t : best;
    t = scene_box_hit(scene_vp, d, blo, bhi);
    return t < best ? t : best;
}

/* A terrestrial scan: rows of constant azimuth phi (a full turn), columns
 * of polar angle theta from straight up to 54 degrees below the horizon
 * (the tripod hides the rest), range noise sigma. cols x rows points in
 * row-major order, as the scanner delivers them. */
static inline void scene_room_scan(uint32_t cols, uint32_t rows, double sigma, uint64_t seed,
                                   float *xyz)
{
    const double th_max = 0.8 * SCENE_PI;
#pragma omp parallel for schedule(static)
    for (long long r = 0; r < (long long)rows; r++) {
        uint64_t s = scene_mix(seed ^ ((uint64_t)r * 0x2545f491ull));
        double ph = ((double)r + 0.5) * 2.0 * SCENE_PI / rows;
        double cp = cos(ph), sp = sin(ph);
        for (uint32_t c = 0; c < cols; c++) {
            double th = ((double)c + 0.5) * th_max / cols;
            double st = sin(th);
            double d[3] = {st * cp, st * sp, cos(th)};
            double t = scene_room_cast(d) + sigma * scene_gauss(&s);
            float *p = xyz + 3 * ((size_t)r * cols + c);
            for (int k = 0; k < 3; k++)
                p[k] = (float)(scene_vp[k] + t * d[k]);
        }
    }
}

#endif
