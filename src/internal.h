/* Private declarations shared by the library's stages: diagnostics, checked
 * size arithmetic, small vector helpers, progress. Not installed. */
#ifndef TESSEL_INTERNAL_H
#define TESSEL_INTERNAL_H

#include "tessel.h"

#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

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

/* malloc(count*size) with overflow check; NULL on overflow or failure. */
void *tsl_alloc_array(size_t count, size_t size);
/* calloc-like, zeroed. */
void *tsl_calloc_array(size_t count, size_t size);
/* Grows *ptr (holding *cap elements of size bytes) to at least need
 * elements, doubling. Returns TESSEL_ERR_NOMEM on failure (ptr unchanged). */
tessel_status tsl_grow(void **ptr, size_t *cap, size_t need, size_t size);

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
static inline void tsl_load(const float *p, double out[3])
{
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[2];
}

/* Eigen-decomposition of a symmetric 3x3 matrix (row-major a[9]).
 * Eigenvalues ascending in w[3]; column i of v (v[3*r+i]) is the unit
 * eigenvector of w[i]. Jacobi rotations: accurate for near-degenerate
 * covariances, which is where normals are decided. */
void tsl_eigen_sym3(const double a[9], double w[3], double v[9]);

/* ---- robust orientation predicates (src/predicates.c, Shewchuk 1997) ----
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

#endif /* TESSEL_INTERNAL_H */
