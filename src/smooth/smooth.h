/* The smoothing, clustering and representatives (src/smooth/), private
 * to the library: the entry points the refinement and the noisy-cloud
 * pipeline share. Not installed. */
#ifndef TESSEL_SMOOTH_H
#define TESSEL_SMOOTH_H

#include "core/core.h"

#include <string.h>

/* ---- the projector's own index (src/smooth/), shared by the stages
 * that search the same cloud ---- */

/* The kd-tree over the projector's cloud, when that cloud's coordinates
 * are `xyz` with `count` points (the same array the projector was made
 * from); else NULL. */
const tessel_index *tsl_projector_index(const tessel_projector *projector, const float *xyz,
                                        size_t count);

/* tessel_smooth, also reporting the seconds spent measuring the spacing
 * when params->spacing is 0 (the noisy pipeline's first column). With
 * grid_order the output's points come in the order of the smoothing's grid
 * (cells in Morton order, nearby points near in memory) instead of the
 * input's: the noisy pipeline, which needs no point of the smoothed cloud
 * by its input index, works on it faster so. */
tessel_status tsl_smooth_timed(const tessel_cloud *cloud, tessel_cloud *out,
                               const tessel_smooth_params *params,
                               const tessel_callbacks *callbacks, tessel_smooth_stats *stats,
                               bool grid_order, double *seconds_spacing);
/* tessel_projector_create on the kd-tree `index` of cloud->xyz (built by
 * the caller, borrowed: it must outlive the projector), or on its own
 * kd-tree when index is NULL. */
tessel_status tsl_projector_create_on(tessel_projector **projector, const tessel_cloud *cloud,
                                     const tessel_smooth_params *params,
                                     const tessel_index *index);

/* tessel_representatives with a projector over `cloud` made by the caller
 * (tessel_projector_create with the projection parameters of params). */
tessel_status tsl_representatives_with(const tessel_cloud *cloud,
                                       const tessel_clusters *clusters,
                                       const tessel_simplify_params *params,
                                       const tessel_projector *projector,
                                       const tessel_callbacks *callbacks, tessel_cloud *out,
                                       tessel_simplify_stats *stats);

/* ---- private to src/smooth/: the robust fit's kernel (fit.c) and what
 * the smoothing passes (smooth.c) share with it ---- */

/* The per-point kernels are compiled twice, for AVX2 and for the baseline,
 * and the loader picks one per machine (GNU ifunc): the lane loops below
 * then run eight floats to a vector instead of four. AVX2 alone, without
 * FMA, does the same additions and multiplications in the same order, so
 * the output is the same bits on every machine (checked on the noisy scans
 * against a build with -DTESSEL_NO_CLONES, and by .ci/run on the bundled
 * bunny). */
#if defined(__x86_64__) && defined(__ELF__) && defined(__GNUC__) && !defined(TESSEL_NO_CLONES)
#define TSL_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define TSL_CLONES
#endif

/* Neighbour buffers live on the stack of each query, so k is capped. */
#define SMOOTH_MAX_K 256u

/* The scales of one operator, in world units. */
typedef struct fit_ctl {
    double h;        /* spacing */
    double inv_2sw2; /* 1 / (2 sigma_w^2) */
    double inv_2sr2; /* 1 / (2 sigma_rho^2) */
    double rmax;     /* neighbour cut-off, 3 sigma_w */
    double tol_t;    /* tolerance * h */
    double tol_n;    /* tolerance, radians */
    double quad_max; /* largest height of the quadric above the plane */
    double ridge;    /* penalty on the quadric's curvature terms */
    uint32_t k, max_iterations, min_neighbors;
    int quadric;      /* 1: height from the quadric over the plane */
    int exclude_self; /* 1: neighbours at the query's own position stay out */
} fit_ctl;

/* Ridge penalty of the quadric's curvature terms in a first pass and the
 * projector (see frame_height), which see the full noise: measured on the
 * noisy scans of docs/smooth.md, it lowers the error on flat parts more
 * than it costs on curved ones. It also halves the quadric's correction
 * on clean curved data. Later passes, whose input is already smooth, fit
 * the quadric without it. */
#define QUAD_RIDGE 10.0

/* e^x for -80 <= x <= 0 in single precision, in a form that vectorises
 * (no libm call, no branch): 2^(x log2 e) split into an integer power, put
 * into the exponent bits, and 2^f for |f| <= 1/2 by its degree-6 Taylor
 * polynomial (truncation < 1.3e-7). Relative error below 7e-7 for
 * -10 <= x <= 0 (where the weights that matter are) and below 4e-6 down to
 * -80, measured against exp on 10^7 arguments each (the rounding of
 * x log2 e grows with |x|). Callers clamp the argument to -80 in a
 * separate loop (e^-80 ~ 2e-35 is zero for every sum it enters): a clamp
 * inside the same loop keeps GCC from vectorising it. Weights need no more
 * precision. */
#define EXP_MIN (-80.0f)
static inline float fast_exp(float x)
{
    float y = x * 1.44269504f;
    float r = (y + 12582912.0f) - 12582912.0f; /* nearest integer: 1.5 * 2^23 */
    float f = y - r;
    float p = 1.54035304e-4f;
    p = p * f + 1.33335581e-3f;
    p = p * f + 9.61812911e-3f;
    p = p * f + 5.55041087e-2f;
    p = p * f + 2.40226507e-1f;
    p = p * f + 6.93147181e-1f;
    p = p * f + 1.0f;
    uint32_t b;
    memcpy(&b, &p, sizeof b);
    b += (uint32_t)(int32_t)r << 23;
    memcpy(&p, &b, sizeof p);
    return p;
}

/* Neighbours of one query as offsets from it, structure of arrays, padded
 * with zeros to a multiple of FIT_LANES: the sums below run over FIT_LANES
 * independent partial sums, which compilers vectorise without reordering
 * any addition (so the result is the same bits on every run), and add them
 * up in a fixed order. */
#define FIT_LANES 8
#define FIT_CAP (SMOOTH_MAX_K + FIT_LANES)
typedef struct fit_buf {
    size_t m;      /* neighbours that enter the fit (within the cut-off) */
    size_t filled; /* slots holding coordinates (>= m): the k nearest */
    size_t mp;     /* m padded to a multiple of FIT_LANES */
    float x[FIT_CAP], y[FIT_CAP], z[FIT_CAP];
    float ew[FIT_CAP]; /* exponent of the Gaussian distance weight */
    float on[FIT_CAP]; /* 1 for the neighbours that enter the fit, else 0 */
    float om[FIT_CAP]; /* current IRLS weights */
    float t[12][FIT_CAP]; /* products for the moments */
} fit_buf;

/* Sum and dot product over the FIT_LANES partial sums, added up in a fixed
 * order. */
static inline float lanes_total(const float acc[FIT_LANES])
{
    float s[FIT_LANES];
    memcpy(s, acc, sizeof s);
    for (int w = FIT_LANES / 2; w > 0; w /= 2)
        for (int l = 0; l < w; l++)
            s[l] += s[l + w];
    return s[0];
}
static inline double lane_dot(const float *a, const float *b, size_t mp)
{
    float acc[FIT_LANES] = {0};
    for (size_t j0 = 0; j0 < mp; j0 += FIT_LANES)
        for (int l = 0; l < FIT_LANES; l++)
            acc[l] += a[j0 + (size_t)l] * b[j0 + (size_t)l];
    return (double)lanes_total(acc);
}
static inline double lane_sum(const float *a, size_t mp)
{
    float acc[FIT_LANES] = {0};
    for (size_t j0 = 0; j0 < mp; j0 += FIT_LANES)
        for (int l = 0; l < FIT_LANES; l++)
            acc[l] += a[j0 + (size_t)l];
    return (double)lanes_total(acc);
}

/* The surface one fit found, for params.aggregate: the points d (offsets
 * from the query's position) with
 *     n.d = t + c0 u^2 + c1 uv + c2 v^2 + c3 u + c4 v + c5,
 * u = e1.d, v = e2.d (e1, e2 of length 1/h, so u and v are in h), and
 * its unit normal at the origin's foot point (computed once here, read by
 * every neighbour). A plane has c = 0. t is NaN when the point has no
 * fit. */
typedef struct fit_surface {
    float e1[3], e2[3], n[3], t, c[6], normal[3];
} fit_surface;

tessel_status tsl_smooth_check_params(const tessel_smooth_params *p);

void tsl_smooth_ctl_setup(fit_ctl *f, const tessel_smooth_params *p, double h, double sigma_rho);

/* Fit, orient and write one result (b as described at fit_buf; start:
 * the normal to start the iterations from, or NULL for the Gaussian-weighted
 * plane). Returns true when fitted. */
bool tsl_smooth_solve_one(const fit_ctl *f, const float q[3], fit_buf *b, const float *start,
                      const float *nearest_normal, int has_viewpoint, const double viewpoint[3],
                      float out[3], float normal[3], uint32_t *iterations, fit_surface *surf);

tessel_status tsl_smooth_check_cloud(const tessel_cloud *cloud);

#endif /* TESSEL_SMOOTH_H */
