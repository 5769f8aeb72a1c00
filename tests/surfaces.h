/* Header-only generators of point samples on analytic surfaces, for tests
 * and benchmarks. Every generator is deterministic (fixed-seed xorshift) and
 * fills a tessel_cloud with points and their true unit normals (outward on
 * closed surfaces).
 *
 * Even samples use dart throwing (Poisson-disk sampling): random points on
 * the surface are accepted when no accepted point is closer than r, until
 * `tries` candidates per expected point were drawn; the result has minimum
 * distance r and mean nearest-neighbour distance about 1.1 r.
 *
 *   surf_sphere          unit sphere
 *   surf_torus           torus, major radius R, minor radius r0 (genus 1)
 *   surf_genus2          closed genus-2 surface: a tube around a figure
 *                        eight, the implicit surface
 *                        (x^2 (1 - x^2) - y^2)^2 + z^2 = 0.01,
 *                        sampled by projecting random points onto it
 *   surf_plane_hole      square [-1,1]^2 in z = 0 minus the disk of radius
 *                        0.4 (open surface, two boundary loops)
 *   surf_thin_box        closed box 2 x 2 x thickness: two sheets closer
 *                        than the sampling can separate when thickness < r
 *   surf_sphere_varying  unit sphere whose spacing grows from r_min at the
 *                        south pole to r_max at the north pole
 *   surf_sphere_fibonacci  n points of the Fibonacci lattice on the unit
 *                        sphere, jittered (fast: for 10^7-point benchmarks)
 *   surf_sphere_random   n points uniformly at random on the unit sphere,
 *                        coordinates only (not an even sample)
 *   surf_pent_torus_random  n points uniformly at random on a torus whose
 *                        cross-section is a regular pentagon (creases of 72
 *                        degrees), coordinates only
 *   surf_two_spheres     two unit spheres, centres (0,0,0) and
 *                        (2 + gap,0,0), coordinates only; with
 *                        surf_two_spheres_inward, the percent of a mesh's
 *                        area that faces its own sphere's centre
 *   surf_noise           adds Gaussian noise along random directions
 */
#ifndef TESSEL_TESTS_SURFACES_H
#define TESSEL_TESTS_SURFACES_H

#include "tessel.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define SURF_PI 3.14159265358979323846

typedef struct surf_rng {
    uint64_t s;
} surf_rng;

static inline uint64_t surf_next(surf_rng *r)
{
    /* xorshift64* */
    r->s ^= r->s >> 12;
    r->s ^= r->s << 25;
    r->s ^= r->s >> 27;
    return r->s * 2685821657736338717ull;
}
static inline surf_rng surf_seed(uint64_t seed)
{
    surf_rng r = {seed * 0x9E3779B97F4A7C15ull + 0x2545F4914F6CDD1Dull};
    if (!r.s)
        r.s = 1;
    for (int i = 0; i < 4; i++)
        surf_next(&r);
    return r;
}
/* Uniform in [0, 1). */
static inline double surf_uniform(surf_rng *r) { return (double)(surf_next(r) >> 11) * 0x1.0p-53; }
static inline double surf_gauss(surf_rng *r)
{
    double u = surf_uniform(r), v = surf_uniform(r);
    if (u < 1e-300)
        u = 1e-300;
    return sqrt(-2.0 * log(u)) * cos(2.0 * SURF_PI * v);
}

/* A surface for dart throwing: draws a random point (and its normal) on the
 * surface; returns 0 when the draw failed (it is then retried). */
typedef int (*surf_draw_fn)(surf_rng *r, const void *ctx, double p[3], double n[3]);
/* Local minimum distance at p (NULL: constant r). */
typedef double (*surf_radius_fn)(const void *ctx, const double p[3]);

/* ---- dart throwing with a hashed grid of accepted points ---- */

typedef struct surf_dart {
    double r_max;            /* largest radius: the grid cell */
    size_t slots;            /* hash slots (power of two) */
    uint64_t *keys;          /* cell key + 1 */
    uint32_t *head;          /* first point in the cell */
    uint32_t *next;          /* per point */
    double *pts;             /* accepted points */
    float *nrm;
    size_t count, cap;
} surf_dart;

static inline uint64_t surf_cell_key(int64_t x, int64_t y, int64_t z)
{
    return ((uint64_t)(x & 0x1FFFFF) << 42) | ((uint64_t)(y & 0x1FFFFF) << 21) |
           (uint64_t)(z & 0x1FFFFF);
}

static inline size_t surf_slot(const surf_dart *d, uint64_t key, int insert)
{
    size_t h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 17) & (d->slots - 1);
    while (d->keys[h] && d->keys[h] != key + 1)
        h = (h + 1) & (d->slots - 1);
    if (insert && !d->keys[h])
        d->keys[h] = key + 1;
    return h;
}

static inline int surf_dart_free(const surf_dart *d, const double p[3], double r)
{
    int64_t c[3];
    for (int k = 0; k < 3; k++)
        c[k] = (int64_t)floor(p[k] / d->r_max);
    for (int64_t z = c[2] - 1; z <= c[2] + 1; z++)
        for (int64_t y = c[1] - 1; y <= c[1] + 1; y++)
            for (int64_t x = c[0] - 1; x <= c[0] + 1; x++) {
                size_t h = surf_slot(d, surf_cell_key(x, y, z), 0);
                if (!d->keys[h])
                    continue;
                for (uint32_t i = d->head[h]; i != UINT32_MAX; i = d->next[i]) {
                    const double *q = d->pts + 3 * (size_t)i;
                    double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
                    if (dx * dx + dy * dy + dz * dz < r * r)
                        return 0;
                }
            }
    return 1;
}

/* Throws tries * expected darts; accepted points go to cloud (with
 * normals). Returns TESSEL_ERR_NOMEM on allocation failure. */
static inline tessel_status surf_throw(tessel_cloud *cloud, surf_draw_fn draw,
                                       surf_radius_fn radius, const void *ctx, double r_max,
                                       size_t expected, double tries, uint64_t seed)
{
    memset(cloud, 0, sizeof *cloud);
    surf_dart d;
    memset(&d, 0, sizeof d);
    d.r_max = r_max;
    d.slots = 1024;
    while (d.slots < 4 * expected + 1024)
        d.slots *= 2;
    d.keys = (uint64_t *)calloc(d.slots, sizeof *d.keys);
    d.head = (uint32_t *)malloc(d.slots * sizeof *d.head);
    d.cap = expected + 1024;
    d.next = (uint32_t *)malloc(d.cap * sizeof *d.next);
    d.pts = (double *)malloc(d.cap * 3 * sizeof *d.pts);
    d.nrm = (float *)malloc(d.cap * 3 * sizeof *d.nrm);
    tessel_status st = TESSEL_OK;
    if (!d.keys || !d.head || !d.next || !d.pts || !d.nrm)
        st = TESSEL_ERR_NOMEM;
    surf_rng rng = surf_seed(seed);
    size_t total = (size_t)(tries * (double)expected);
    for (size_t t = 0; t < total && st == TESSEL_OK; t++) {
        double p[3], n[3];
        if (!draw(&rng, ctx, p, n))
            continue;
        double r = radius ? radius(ctx, p) : r_max;
        if (!surf_dart_free(&d, p, r))
            continue;
        if (d.count == d.cap) {
            /* Grow everything that is per point; rehash if the table fills. */
            size_t cap = d.cap * 2;
            uint32_t *nx = (uint32_t *)realloc(d.next, cap * sizeof *nx);
            double *np = nx ? (double *)realloc(d.pts, cap * 3 * sizeof *np) : NULL;
            float *nn = np ? (float *)realloc(d.nrm, cap * 3 * sizeof *nn) : NULL;
            if (nx)
                d.next = nx;
            if (np)
                d.pts = np;
            if (nn)
                d.nrm = nn;
            if (!nx || !np || !nn) {
                st = TESSEL_ERR_NOMEM;
                break;
            }
            d.cap = cap;
        }
        if (4 * d.count >= d.slots) {
            size_t slots = d.slots * 2;
            uint64_t *keys = (uint64_t *)calloc(slots, sizeof *keys);
            uint32_t *head = (uint32_t *)malloc(slots * sizeof *head);
            if (!keys || !head) {
                free(keys);
                free(head);
                st = TESSEL_ERR_NOMEM;
                break;
            }
            free(d.keys);
            free(d.head);
            d.keys = keys;
            d.head = head;
            d.slots = slots;
            for (size_t i = 0; i < d.count; i++) {
                const double *q = d.pts + 3 * i;
                uint64_t key = surf_cell_key((int64_t)floor(q[0] / r_max),
                                             (int64_t)floor(q[1] / r_max),
                                             (int64_t)floor(q[2] / r_max));
                size_t h = surf_slot(&d, key, 0);
                if (!d.keys[h]) {
                    d.keys[h] = key + 1;
                    d.head[h] = UINT32_MAX;
                }
                d.next[i] = d.head[h];
                d.head[h] = (uint32_t)i;
            }
        }
        uint64_t key = surf_cell_key((int64_t)floor(p[0] / r_max), (int64_t)floor(p[1] / r_max),
                                     (int64_t)floor(p[2] / r_max));
        size_t h = surf_slot(&d, key, 0);
        if (!d.keys[h]) {
            d.keys[h] = key + 1;
            d.head[h] = UINT32_MAX;
        }
        size_t i = d.count++;
        memcpy(d.pts + 3 * i, p, 3 * sizeof *p);
        for (int k = 0; k < 3; k++)
            d.nrm[3 * i + (size_t)k] = (float)n[k];
        d.next[i] = d.head[h];
        d.head[h] = (uint32_t)i;
    }
    if (st == TESSEL_OK)
        st = tessel_cloud_alloc(cloud, d.count, 1, 0);
    if (st == TESSEL_OK) {
        for (size_t i = 0; i < 3 * d.count; i++)
            cloud->xyz[i] = (float)d.pts[i];
        memcpy(cloud->normals, d.nrm, d.count * 3 * sizeof *d.nrm);
    }
    free(d.keys);
    free(d.head);
    free(d.next);
    free(d.pts);
    free(d.nrm);
    return st;
}

/* ---- surfaces ---- */

static inline int surf_draw_sphere(surf_rng *r, const void *ctx, double p[3], double n[3])
{
    (void)ctx;
    double v[3] = {surf_gauss(r), surf_gauss(r), surf_gauss(r)};
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l < 1e-12)
        return 0;
    for (int k = 0; k < 3; k++)
        p[k] = n[k] = v[k] / l;
    return 1;
}

/* Unit sphere, minimum distance r (about 4 pi / (0.85 r^2) points). */
static inline tessel_status surf_sphere(tessel_cloud *c, double r, uint64_t seed)
{
    size_t expected = (size_t)(4.0 * SURF_PI / (0.8 * r * r)) + 16;
    return surf_throw(c, surf_draw_sphere, NULL, NULL, r, expected, 30.0, seed);
}

/* Two unit spheres sampled like surf_sphere(r), the second moved by
 * 2 + gap along x; coordinates only (as most files come: no normals). */
static inline tessel_status surf_two_spheres(tessel_cloud *c, double r, double gap,
                                             uint64_t seed)
{
    tessel_cloud one;
    tessel_status s = surf_sphere(&one, r, seed);
    if (s != TESSEL_OK)
        return s;
    s = tessel_cloud_alloc(c, 2 * one.count, 0, 0);
    for (size_t i = 0; s == TESSEL_OK && i < one.count; i++)
        for (int k = 0; k < 3; k++) {
            float x = one.xyz[3 * i + (size_t)k];
            c->xyz[3 * i + (size_t)k] = x;
            c->xyz[3 * (one.count + i) + (size_t)k] = k == 0 ? x + 2.0f + (float)gap : x;
        }
    tessel_cloud_free(&one);
    return s;
}

/* Percent of the area of triangles tri[0 .. nt) over xyz, on two spheres
 * made by surf_two_spheres(gap), whose normal points towards the centre of
 * the sphere the triangle lies on. */
static inline double surf_two_spheres_inward(const float *xyz, const uint32_t *tri, size_t nt,
                                             double gap)
{
    double inward = 0.0, area = 0.0;
    for (size_t t = 0; t < nt; t++) {
        double p[3][3], u[3], w[3], n[3], o[3];
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++)
                p[i][k] = xyz[3 * (size_t)tri[3 * t + (size_t)i] + (size_t)k];
        for (int k = 0; k < 3; k++) {
            u[k] = p[1][k] - p[0][k];
            w[k] = p[2][k] - p[0][k];
            o[k] = (p[0][k] + p[1][k] + p[2][k]) / 3.0;
        }
        o[0] -= o[0] < 1.0 + 0.5 * gap ? 0.0 : 2.0 + gap; /* from its centre */
        n[0] = u[1] * w[2] - u[2] * w[1];
        n[1] = u[2] * w[0] - u[0] * w[2];
        n[2] = u[0] * w[1] - u[1] * w[0];
        double a = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        area += a;
        if (n[0] * o[0] + n[1] * o[1] + n[2] * o[2] < 0.0)
            inward += a;
    }
    return area > 0.0 ? 100.0 * inward / area : 100.0;
}

typedef struct surf_torus_ctx {
    double R, r0;
} surf_torus_ctx;

static inline int surf_draw_torus(surf_rng *r, const void *ctx, double p[3], double n[3])
{
    const surf_torus_ctx *t = (const surf_torus_ctx *)ctx;
    double u = 2.0 * SURF_PI * surf_uniform(r), v = 2.0 * SURF_PI * surf_uniform(r);
    /* Area element (R + r0 cos v): accept proportionally. */
    if (surf_uniform(r) * (t->R + t->r0) > t->R + t->r0 * cos(v))
        return 0;
    double cu = cos(u), su = sin(u), cv = cos(v), sv = sin(v);
    p[0] = (t->R + t->r0 * cv) * cu;
    p[1] = (t->R + t->r0 * cv) * su;
    p[2] = t->r0 * sv;
    n[0] = cv * cu;
    n[1] = cv * su;
    n[2] = sv;
    return 1;
}

static inline tessel_status surf_torus(tessel_cloud *c, double R, double r0, double r,
                                       uint64_t seed)
{
    surf_torus_ctx t = {R, r0};
    double area = 4.0 * SURF_PI * SURF_PI * R * r0;
    size_t expected = (size_t)(area / (0.8 * r * r)) + 16;
    return surf_throw(c, surf_draw_torus, NULL, &t, r, expected, 60.0, seed);
}

/* Genus 2: f = (x^2 (1 - x^2) - y^2)^2 + z^2 - 0.01. */
static inline double surf_g2_f(const double p[3], double grad[3])
{
    double x = p[0], y = p[1], z = p[2];
    double gq = x * x * (1.0 - x * x) - y * y;
    grad[0] = 2.0 * gq * (2.0 * x - 4.0 * x * x * x);
    grad[1] = 2.0 * gq * (-2.0 * y);
    grad[2] = 2.0 * z;
    return gq * gq + z * z - 0.01;
}

static inline int surf_draw_genus2(surf_rng *r, const void *ctx, double p[3], double n[3])
{
    (void)ctx;
    double q[3] = {-1.2 + 2.4 * surf_uniform(r), -0.7 + 1.4 * surf_uniform(r),
                   -0.12 + 0.24 * surf_uniform(r)};
    double g[3];
    for (int it = 0; it < 40; it++) {
        double f = surf_g2_f(q, g);
        double gg = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if (gg < 1e-14)
            return 0;
        for (int k = 0; k < 3; k++)
            q[k] -= f * g[k] / gg;
        if (fabs(f) < 1e-13)
            break;
    }
    double f = surf_g2_f(q, g);
    double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (fabs(f) > 1e-10 || gl < 1e-9)
        return 0;
    for (int k = 0; k < 3; k++) {
        p[k] = q[k];
        n[k] = g[k] / gl;
    }
    return 1;
}

static inline tessel_status surf_genus2(tessel_cloud *c, double r, uint64_t seed)
{
    size_t expected = (size_t)(3.0 / (0.8 * r * r)) + 16;
    return surf_throw(c, surf_draw_genus2, NULL, NULL, r, expected, 40.0, seed);
}

static inline int surf_draw_plane_hole(surf_rng *r, const void *ctx, double p[3], double n[3])
{
    (void)ctx;
    p[0] = -1.0 + 2.0 * surf_uniform(r);
    p[1] = -1.0 + 2.0 * surf_uniform(r);
    p[2] = 0.0;
    if (p[0] * p[0] + p[1] * p[1] < 0.16)
        return 0;
    n[0] = n[1] = 0.0;
    n[2] = 1.0;
    return 1;
}

static inline tessel_status surf_plane_hole(tessel_cloud *c, double r, uint64_t seed)
{
    size_t expected = (size_t)((4.0 - 0.16 * SURF_PI) / (0.8 * r * r)) + 16;
    return surf_throw(c, surf_draw_plane_hole, NULL, NULL, r, expected, 30.0, seed);
}

typedef struct surf_box_ctx {
    double h[3]; /* half sizes */
} surf_box_ctx;

static inline int surf_draw_box(surf_rng *r, const void *ctx, double p[3], double n[3])
{
    const surf_box_ctx *b = (const surf_box_ctx *)ctx;
    double a[3] = {b->h[1] * b->h[2], b->h[0] * b->h[2], b->h[0] * b->h[1]};
    double t = surf_uniform(r) * (a[0] + a[1] + a[2]);
    int k = t < a[0] ? 0 : (t < a[0] + a[1] ? 1 : 2);
    double side = surf_uniform(r) < 0.5 ? -1.0 : 1.0;
    for (int i = 0; i < 3; i++) {
        p[i] = b->h[i] * (2.0 * surf_uniform(r) - 1.0);
        n[i] = 0.0;
    }
    p[k] = side * b->h[k];
    n[k] = side;
    return 1;
}

/* Closed box 2 x 2 x thickness centred at the origin. */
static inline tessel_status surf_thin_box(tessel_cloud *c, double thickness, double r,
                                          uint64_t seed)
{
    surf_box_ctx b = {{1.0, 1.0, 0.5 * thickness}};
    double area = 8.0 + 8.0 * thickness;
    size_t expected = (size_t)(area / (0.8 * r * r)) + 16;
    return surf_throw(c, surf_draw_box, NULL, &b, r, expected, 30.0, seed);
}

typedef struct surf_vary_ctx {
    double r_min, r_max;
} surf_vary_ctx;

static inline double surf_vary_radius(const void *ctx, const double p[3])
{
    const surf_vary_ctx *v = (const surf_vary_ctx *)ctx;
    return v->r_min + (v->r_max - v->r_min) * 0.5 * (p[2] + 1.0);
}

static inline tessel_status surf_sphere_varying(tessel_cloud *c, double r_min, double r_max,
                                                uint64_t seed)
{
    surf_vary_ctx v = {r_min, r_max};
    double rm = 0.5 * (r_min + r_max);
    size_t expected = (size_t)(4.0 * SURF_PI / (0.8 * rm * rm) * 1.5) + 16;
    /* Darts proportional to the densest part so that it fills up. */
    double tries = 30.0 * (r_max / r_min) * (r_max / r_min) / 1.5;
    return surf_throw(c, surf_draw_sphere, surf_vary_radius, &v, r_max, expected, tries, seed);
}

/* n points of the Fibonacci lattice on the unit sphere, each moved by up to
 * jitter times the lattice spacing (then put back on the sphere). */
static inline tessel_status surf_sphere_fibonacci(tessel_cloud *c, size_t n, double jitter,
                                                  uint64_t seed)
{
    memset(c, 0, sizeof *c);
    tessel_status st = tessel_cloud_alloc(c, n, 1, 0);
    if (st != TESSEL_OK)
        return st;
    surf_rng rng = surf_seed(seed);
    double golden = SURF_PI * (3.0 - sqrt(5.0));
    double step = sqrt(4.0 * SURF_PI / (double)n);
    for (size_t i = 0; i < n; i++) {
        double z = 1.0 - (2.0 * (double)i + 1.0) / (double)n;
        double rr = sqrt(1.0 - z * z), phi = golden * (double)i;
        double p[3] = {rr * cos(phi), rr * sin(phi), z};
        for (int k = 0; k < 3; k++)
            p[k] += jitter * step * (2.0 * surf_uniform(&rng) - 1.0);
        double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        for (int k = 0; k < 3; k++) {
            c->xyz[3 * i + (size_t)k] = (float)(p[k] / l);
            c->normals[3 * i + (size_t)k] = (float)(p[k] / l);
        }
    }
    return TESSEL_OK;
}

/* n points drawn uniformly at random on the unit sphere (no spacing
 * between them: some pairs come far closer than the mean spacing), without
 * normals, as a random sampler of a mesh gives them. */
static inline tessel_status surf_sphere_random(tessel_cloud *c, size_t n, uint64_t seed)
{
    memset(c, 0, sizeof *c);
    tessel_status st = tessel_cloud_alloc(c, n, 0, 0);
    if (st != TESSEL_OK)
        return st;
    surf_rng rng = surf_seed(seed);
    for (size_t i = 0; i < n; i++) {
        double p[3] = {surf_gauss(&rng), surf_gauss(&rng), surf_gauss(&rng)};
        double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        for (int k = 0; k < 3; k++)
            c->xyz[3 * i + (size_t)k] = (float)(p[k] / l);
    }
    return TESSEL_OK;
}

/* Torus of major radius 1 whose cross-section is a regular pentagon of
 * circumradius 0.25 in the (distance from the z axis, z) plane. Uniform on
 * the area: a side picked at random, then a point on it kept with
 * probability proportional to its distance from the axis. */
#define SURF_PENT_R 0.25
static inline tessel_status surf_pent_torus_random(tessel_cloud *c, size_t n, uint64_t seed)
{
    memset(c, 0, sizeof *c);
    tessel_status st = tessel_cloud_alloc(c, n, 0, 0);
    if (st != TESSEL_OK)
        return st;
    surf_rng rng = surf_seed(seed);
    for (size_t i = 0; i < n;) {
        int j = (int)(5.0 * surf_uniform(&rng)) % 5;
        double a0 = 2.0 * SURF_PI * j / 5.0, a1 = 2.0 * SURF_PI * (j + 1) / 5.0;
        double s = surf_uniform(&rng), phi = 2.0 * SURF_PI * surf_uniform(&rng);
        double rho = 1.0 + SURF_PENT_R * ((1.0 - s) * cos(a0) + s * cos(a1));
        double z = SURF_PENT_R * ((1.0 - s) * sin(a0) + s * sin(a1));
        if (surf_uniform(&rng) * (1.0 + SURF_PENT_R) > rho)
            continue;
        c->xyz[3 * i] = (float)(rho * cos(phi));
        c->xyz[3 * i + 1] = (float)(rho * sin(phi));
        c->xyz[3 * i + 2] = (float)z;
        i++;
    }
    return TESSEL_OK;
}
/* Moves every point by a Gaussian vector of standard deviation sigma per
 * axis (normals are left as they were: the true ones). */
static inline void surf_noise(tessel_cloud *c, double sigma, uint64_t seed)
{
    surf_rng rng = surf_seed(seed ^ 0xA5A5A5A5u);
    for (size_t i = 0; i < 3 * c->count; i++)
        c->xyz[i] = (float)(c->xyz[i] + sigma * surf_gauss(&rng));
}

#endif /* TESSEL_TESTS_SURFACES_H */
