/* The core layer, private to the library: diagnostics, checked size
 * arithmetic, memory, progress, threads, small vector helpers, union-find,
 * eigen-solvers, exact predicates and the kd-tree's storage order. Every
 * other folder of src/ builds on it. Not installed. */
#ifndef TESSEL_CORE_H
#define TESSEL_CORE_H

#include "tessel.h"

#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* OpenMP's runtime, or its one-thread answers in a build without OpenMP
 * (TESSEL_OPENMP=OFF): the pragmas are then ignored and every loop runs on
 * one thread. Results do not depend on the thread count either way. */
#ifdef _OPENMP
#include <omp.h>
#else
static inline int omp_get_thread_num(void) { return 0; }
static inline int omp_get_num_threads(void) { return 1; }
#endif

/* The share [*lo, *lo + *width) of the indices 0 .. n (n < 2^32) that the
 * calling thread of a parallel region owns: scatters over a mesh's
 * vertices run with each thread writing its own share only, every thread
 * reading all triangles (atomic updates cost more than the scatter). */
static inline void tsl_thread_share(size_t n, uint32_t *lo, uint32_t *width)
{
    size_t parts = (size_t)omp_get_num_threads(), me = (size_t)omp_get_thread_num();
    *lo = (uint32_t)(n * me / parts);
    *width = (uint32_t)(n * (me + 1) / parts) - *lo;
}

/* Bit v of a bit set of 64-bit words. */
static inline bool tsl_bit(const uint64_t *bits, uint32_t v)
{
    return bits[v >> 6] >> (v & 63) & 1u;
}

#if defined(__GNUC__)
#define TSL_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define TSL_PRINTF(a, b)
#endif

/* Fills diag (if not NULL): file name, line (0 = none), byte offset
 * (has_offset = 0: none) and a printf-style message. */
void tsl_diag_set(tessel_diag *diag, const char *file, uint64_t line, int has_offset,
                  uint64_t offset, const char *fmt, ...) TSL_PRINTF(6, 7);

/* a*b and a+b into *out; false on overflow. */
static inline bool tsl_mul_size(size_t a, size_t b, size_t *out)
{
    if (a != 0 && b > SIZE_MAX / a)
        return false;
    *out = a * b;
    return true;
}
static inline bool tsl_add_size(size_t a, size_t b, size_t *out)
{
    if (b > SIZE_MAX - a)
        return false;
    *out = a + b;
    return true;
}

/* qsort / bsearch order of uint64_t. */
/* Closed float boxes [alo, ahi] and [blo, bhi] meet. */
static inline bool tsl_boxes_overlap(const float *alo, const float *ahi, const float *blo,
                                     const float *bhi)
{
    return alo[0] <= bhi[0] && blo[0] <= ahi[0] && alo[1] <= bhi[1] && blo[1] <= ahi[1] &&
           alo[2] <= bhi[2] && blo[2] <= ahi[2];
}

static inline int tsl_cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* A 64-bit hash of z (SplitMix64's finaliser): for hashed subsets and
 * set fingerprints, the same on every machine. */
static inline uint64_t tsl_mix64(uint64_t z)
{
    z += 0x9E3779B97F4A7C15ULL;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* malloc(count*size) with overflow check; NULL on overflow or failure. */
void *tsl_alloc_array(size_t count, size_t size);
/* calloc-like, zeroed. */
void *tsl_calloc_array(size_t count, size_t size);
/* Grows *ptr (holding *cap elements of size bytes) to at least need
 * elements, doubling. Returns TESSEL_ERR_NOMEM on failure (ptr unchanged). */
tessel_status tsl_grow(void **ptr, size_t *cap, size_t need, size_t size);
/* realloc of *ptr (old_bytes in use) to new_bytes, keeping the contents;
 * large blocks get the huge-page advice of tsl_alloc_array. Returns
 * TESSEL_ERR_NOMEM on failure (*ptr unchanged). */
tessel_status tsl_resize(void **ptr, size_t old_bytes, size_t new_bytes);
/* Monotonic wall-clock seconds, for the stage times of the stats. */
double tsl_seconds(void);

/* Progress helper: calls the callback if set; returns TESSEL_ERR_CANCELLED
 * when it asks to stop. */
tessel_status tsl_progress(const tessel_callbacks *cb, const char *stage, double fraction);
void tsl_log(const tessel_callbacks *cb, tessel_log_level level, const char *fmt, ...)
    TSL_PRINTF(3, 4);

/* Sets the OpenMP thread count for the next parallel region from a params
 * field (0 = leave the OpenMP default, which honours OMP_NUM_THREADS). */
int tsl_threads(int requested);

/* ---- small vector math on double[3] ---- */
static inline double tsl_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void tsl_sub(const double a[3], const double b[3], double out[3])
{
    out[0] = a[0] - b[0];
    out[1] = a[1] - b[1];
    out[2] = a[2] - b[2];
}
static inline void tsl_cross(const double a[3], const double b[3], double out[3])
{
    double x = a[1] * b[2] - a[2] * b[1];
    double y = a[2] * b[0] - a[0] * b[2];
    double z = a[0] * b[1] - a[1] * b[0];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}
static inline double tsl_norm(const double a[3]) { return sqrt(tsl_dot(a, a)); }
static inline bool tsl_normalize(double a[3])
{
    double n = tsl_norm(a);
    if (!(n > 0.0))
        return false;
    a[0] /= n;
    a[1] /= n;
    a[2] /= n;
    return true;
}
/* Unit normal of triangle (x, y, z) into n (left unnormalized when the
 * triangle is degenerate); returns twice its area. */
static inline double tsl_tri_normal(const double x[3], const double y[3], const double z[3],
                                   double n[3])
{
    double u[3], v[3];
    tsl_sub(y, x, u);
    tsl_sub(z, x, v);
    tsl_cross(u, v, n);
    double len = tsl_norm(n);
    if (len > 0.0) {
        n[0] /= len;
        n[1] /= len;
        n[2] /= len;
    }
    return len;
}
static inline void tsl_load(const float *p, double out[3])
{
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[2];
}

/* Union-find: the root of x, halving the path to it. */
static inline uint32_t tsl_uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

/* Union-find: joins the sets of a and b under the smaller of their roots,
 * so that a set's root is its smallest member whatever the order of the
 * unions (results that depend on the root do not depend on that order). */
static inline void tsl_uf_unite(uint32_t *parent, uint32_t a, uint32_t b)
{
    a = tsl_uf_find(parent, a);
    b = tsl_uf_find(parent, b);
    if (a < b)
        parent[b] = a;
    else if (b < a)
        parent[a] = b;
}

/* A least-squares quadric height field z = a + b u + c v + d u^2 + e uv +
 * f v^2 over the points idx[0 .. k) whose distance from the axis through q
 * is at most sqrt(rho2), in the tangent frame of all k (PCA), refitted
 * without the points beyond 3 residual standard deviations (another sheet)
 * until none is dropped (core/noise.c). work holds 4 k doubles. False with
 * fewer than 24 points in the cylinder or a singular fit. */
typedef struct tsl_height {
    double var;       /* residual variance of the last fit */
    size_t inliers;   /* points within the trimming limit */
    double normal[3]; /* unit axis of the frame */
    double height;    /* the quadric at q: q + height * normal is on it */
    double frame[2][3], scale, coef[6]; /* the tangent axes, 1 / rho and
                                           a .. f (u, v scaled by it) */
} tsl_height;
bool tsl_height_fit(const float *xyz, const float q[3], const uint32_t *idx, size_t k,
                    double rho2, double *work, tsl_height *out);
/* How far along h->normal the point q + d is from the quadric (positive:
 * the quadric is that far on the normal's side). */
double tsl_height_offset(const tsl_height *h, const double d[3]);

/* qsort comparison of uint32_t values, ascending. */
int tsl_cmp_u32(const void *a, const void *b);

/* Eigen-decomposition of a symmetric 3x3 matrix (row-major a[9]).
 * Eigenvalues ascending in w[3]; column i of v (v[3*r+i]) is the unit
 * eigenvector of w[i]. Jacobi rotations: accurate for near-degenerate
 * covariances, which is where normals are decided. */
void tsl_eigen_sym3(const double a[9], double w[3], double v[9]);

/* The same for a covariance m = {a00, a01, a02, a11, a12, a22} (symmetric,
 * positive semi-definite) without rotations, several times cheaper:
 * tsl_sym3_values gives the eigenvalues ascending in l[3], the smallest as
 * the smallest root of the characteristic cubic by Newton's method from 0
 * (below every root, where Newton rises monotonically to it; cheaper than
 * the trigonometric closed form, whose acos and cos cost more than the
 * whole iteration), the other two from the deflated quadratic; false when
 * the trace is not positive. tsl_sym3_vector gives a unit vector of the
 * null space of m - l I, the longest cross product of two of its rows;
 * false when all vanish. That vector is accurate only for an eigenvalue l
 * well apart from the other two: callers take tsl_eigen_sym3 when the gap
 * is under 1e-4 of the largest eigenvalue. */
bool tsl_sym3_values(const double m[6], double l[3]);
bool tsl_sym3_vector(const double m[6], double l, double v[3]);

/* ---- robust orientation predicates (src/core/predicates.c, Shewchuk 1997) ----
 * The SIGN of the result is exact (filtered double evaluation, exact
 * expansion arithmetic when the filter cannot decide); the magnitude is an
 * approximation. Exact for any inputs whose products neither overflow nor
 * underflow, which covers every float coordinate.
 * tsl_orient2d: > 0 when a, b, c turn counter-clockwise, < 0 clockwise, 0
 *   when collinear (twice the signed area of abc).
 * tsl_orient3d: > 0 when d lies below the plane through a, b, c, "below"
 *   meaning a, b, c appear counter-clockwise seen from above; < 0 above; 0
 *   when coplanar (det[a-d; b-d; c-d], six times the signed volume). */
double tsl_orient2d(const double a[2], const double b[2], const double c[2]);
double tsl_orient3d(const double a[3], const double b[3], const double c[3],
                    const double d[3]);

/* Exactly collinear vertices (zero area). */
bool tsl_triangle_degenerate(const double *p[3]);
/* Two non-degenerate triangles with vertex ids ia, ib and coordinates pa,
 * pb intersect in more than their shared vertex or edge (exact, closed
 * triangles). Triangles with three shared ids count as intersecting. */
bool tsl_triangles_intersect(const uint32_t ia[3], const double *pa[3], const uint32_t ib[3],
                             const double *pb[3]);

/* ---- neighbour search (src/core/kdtree.c) ---- */

/* Writes the index's count point indices in its storage order (leaf by
 * leaf). Self-queries issued in this order find the tree in cache: 1.7x
 * the queries/s of random order on 10^6 points. */
void tsl_index_order(const tessel_index *index, uint32_t *order);

/* ---- tiles (src/core/tiles.c) ---- */

/* A cut of the bisection: the tiles [first, mid) lie below coordinate
 * `at` along `axis`, [mid, end) above; the tiles' further cuts are the
 * nodes low and high (TESSEL_NONE: a single tile there). */
typedef struct tsl_tile_node {
    double at;
    uint32_t first, mid, end, low, high;
    uint8_t axis, depth;
} tsl_tile_node;

/* A point set cut into tiles by recursive median bisection (each part
 * along the longest side of its box) until each has at most max_points
 * points; the cut depends on the points and max_points only. */

typedef struct tsl_tiles {
    size_t count;      /* tiles */
    size_t *start;     /* count + 1: tile k's points are ids[start[k] .. start[k + 1]) */
    uint32_t *ids;     /* the points by tile, in increasing index within a tile */
    uint32_t *tile_of; /* per point: its tile */
    float *dcut;       /* per point: distance to the nearest cut bounding its
                          tile (INFINITY with one tile) */
    uint8_t *cut_axis; /* per point: the axis that cut runs across */
    tsl_tile_node *node; /* the cuts in preorder (the first cuts the whole set) */
    size_t nodes;
} tsl_tiles;

tessel_status tsl_tiles_cut(const float *xyz, size_t n, size_t max_points, int threads,
                            tsl_tiles *t);
void tsl_tiles_free(tsl_tiles *t);

#endif /* TESSEL_CORE_H */
