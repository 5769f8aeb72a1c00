/* Robust smoothing of noisy point clouds: the projection operator Q of
 * Mederos, Velho & de Figueiredo, "Smooth surface reconstruction from noisy
 * clouds" (2003), section 2.1 (details in their "Robust smoothing of noisy
 * point clouds", 2004). A point p moves to Q(p) = p + t* n*, where the plane
 * through p + t n with unit normal n minimises
 *     sum over neighbours q of rho(h_q) w(|q - p|),   h_q = n.(q - p) - t,
 * rho(x) = 1 - exp(-x^2 / 2 sigma_rho^2) (a robust error norm: a point far
 * from the plane costs at most 1, so it cannot drag the plane) and
 * w(x) = exp(-x^2 / 2 sigma_w^2) (locality). Setting the gradient to zero
 * gives a weighted least-squares problem with weights
 * w(|q - p|) exp(-h_q^2 / 2 sigma_rho^2), so we solve it by iteratively
 * reweighted least squares: for fixed weights the best plane passes through
 * the weighted centroid with the normal of the smallest eigenvalue of the
 * weighted covariance (weighted PCA), and t is the weighted mean height.
 * The first plane is the one with the Gaussian weights alone.
 *
 * Beyond the paper (params.quadric, on by default): Q(p) is the foot point
 * on the robust plane lifted by the height of a weighted least-squares
 * quadric fitted over that plane with the same robust weights, which
 * removes most of the plane's shrinkage on curved parts (docs/smooth.md).
 *
 * Neighbours: the k nearest points within 3 sigma_w (beyond it w < 1.1%).
 * Arbitrary points (tessel_project) find them with the kd-tree. The first
 * smoothing pass, where the queries are the cloud itself, sorts the points
 * into a grid of cells a little wider than the distance to the k-th
 * neighbour and serves all points of a cell from the same 27 cells (more
 * rings of cells for the rare point whose neighbours reach farther): the
 * same neighbours as the kd-tree, at a fraction of the cost. Where the
 * density is far above the mean the cells are sized for (the near field
 * of a range scan), a cell's 27 would hold thousands of points and the
 * kd-tree answers its points instead. Later passes
 * reuse those neighbours at their new positions and take one more IRLS
 * step from the previous pass's normal (with the quadric: its height over
 * the plane across that normal, and its own normal at the point). Every
 * output position depends only on the previous pass's positions, so points
 * are independent: OpenMP loops with per-point output slots give the same
 * bits for any thread count. */
#include "core/grid.h"
#include "smooth/smooth.h"

#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

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

struct tessel_projector {
    const tessel_index *index; /* over xyz */
    tessel_index *own;         /* index, when built here (else borrowed) */
    const float *xyz;
    const float *normals; /* orientation reference, may be NULL */
    size_t count;
    fit_ctl ctl;
    int has_viewpoint;
    double viewpoint[3]; /* local coordinates */
};

tessel_smooth_params tessel_smooth_params_default(void)
{
    tessel_smooth_params p;
    memset(&p, 0, sizeof p);
    p.k = 30;
    p.sigma_rho = 2.0;
    p.sigma_w = 3.0;
    p.passes = 2;
    p.max_iterations = 20;
    p.tolerance = 1e-2;
    p.min_neighbors = 6;
    p.spacing = 0.0;
    p.threads = 0;
    p.quadric = 1;
    p.sigma_rho_later = 1.0;
    p.aggregate = 0;
    p.exclude_self = 0;
    return p;
}

static tessel_status check_params(const tessel_smooth_params *p)
{
    if (p->k < 3 || p->k > SMOOTH_MAX_K)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->sigma_rho > 0.0) || !isfinite(p->sigma_rho) || !(p->sigma_w > 0.0) ||
        !isfinite(p->sigma_w))
        return TESSEL_ERR_INVALID_ARG;
    if (p->passes < 1 || p->passes > 100)
        return TESSEL_ERR_INVALID_ARG;
    if (p->max_iterations < 1 || p->max_iterations > 1000)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->tolerance > 0.0) || !isfinite(p->tolerance))
        return TESSEL_ERR_INVALID_ARG;
    if (p->min_neighbors < 3 || p->min_neighbors > p->k)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->spacing >= 0.0) || !isfinite(p->spacing))
        return TESSEL_ERR_INVALID_ARG;
    if (p->quadric != 0 && p->quadric != 1)
        return TESSEL_ERR_INVALID_ARG;
    if (p->aggregate != 0 && p->aggregate != 1)
        return TESSEL_ERR_INVALID_ARG;
    if (p->exclude_self != 0 && p->exclude_self != 1)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->sigma_rho_later > 0.0) || !isfinite(p->sigma_rho_later))
        return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

/* Ridge penalty of the quadric's curvature terms in a first pass and the
 * projector (see frame_height), which see the full noise: measured on the
 * noisy scans of docs/smooth.md, it lowers the error on flat parts more
 * than it costs on curved ones. It also halves the quadric's correction
 * on clean curved data. Later passes, whose input is already smooth, fit
 * the quadric without it. */
#define QUAD_RIDGE 10.0

static void ctl_setup(fit_ctl *f, const tessel_smooth_params *p, double h, double sigma_rho)
{
    double sw = p->sigma_w * h, sr = sigma_rho * h;
    f->h = h;
    f->inv_2sw2 = 1.0 / (2.0 * sw * sw);
    f->inv_2sr2 = 1.0 / (2.0 * sr * sr);
    f->rmax = 3.0 * sw;
    f->tol_t = p->tolerance * h;
    f->tol_n = p->tolerance;
    f->quad_max = 2.0 * sr;
    f->ridge = QUAD_RIDGE;
    f->quadric = p->quadric;
    f->exclude_self = p->exclude_self;
    f->k = p->k;
    f->max_iterations = p->max_iterations;
    f->min_neighbors = p->min_neighbors;
}

/* ---- fitting ---- */

/* Unit eigenvector of the smallest eigenvalue of the covariance m (as in
 * tsl_sym3_values). Returns false when no plane is defined: the two
 * largest eigenvalues are not both positive (all points on a line or at
 * one spot). When the smallest eigenvalue is close to the middle one the
 * cross product is inaccurate, so Jacobi rotations decide instead. */
static bool smallest_eigenvector(const double m[6], double n[3])
{
    double l[3];
    if (!tsl_sym3_values(m, l) || !(l[2] > 0.0) || !(l[1] > 1e-12 * l[2]))
        return false;
    if (l[1] - l[0] < 1e-4 * l[2]) {
        double a[9] = {m[0], m[1], m[2], m[1], m[3], m[4], m[2], m[4], m[5]}, w[3], v[9];
        tsl_eigen_sym3(a, w, v);
        n[0] = v[0], n[1] = v[3], n[2] = v[6];
        return w[2] > 0.0 && w[1] > 1e-12 * w[2];
    }
    return tsl_sym3_vector(m, l[0], n);
}

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

static void fit_pad(fit_buf *b)
{
    b->mp = (b->m + FIT_LANES - 1) / FIT_LANES * FIT_LANES;
    for (size_t j = b->filled; j < b->mp; j++)
        b->x[j] = b->y[j] = b->z[j] = 0.0f;
}

/* Weighted moments about the query: W, sums of om d and of om d d^T. */
TSL_CLONES static void plane_moments(fit_buf *b, double W[1], double s[3], double mm[6])
{
    const size_t mp = b->mp;
    float *ox = b->t[0], *oy = b->t[1], *oz = b->t[2];
    for (size_t j = 0; j < mp; j++) {
        ox[j] = b->om[j] * b->x[j];
        oy[j] = b->om[j] * b->y[j];
        oz[j] = b->om[j] * b->z[j];
    }
    W[0] = lane_sum(b->om, mp);
    s[0] = lane_sum(ox, mp), s[1] = lane_sum(oy, mp), s[2] = lane_sum(oz, mp);
    mm[0] = lane_dot(ox, b->x, mp), mm[1] = lane_dot(ox, b->y, mp);
    mm[2] = lane_dot(ox, b->z, mp), mm[3] = lane_dot(oy, b->y, mp);
    mm[4] = lane_dot(oy, b->z, mp), mm[5] = lane_dot(oz, b->z, mp);
}

/* Plane of the weighted neighbours: centroid c and unit normal n. */
static bool plane_from_moments(double W, const double s[3], const double mm[6], double c[3],
                               double n[3])
{
    if (!(W > 1e-30))
        return false;
    c[0] = s[0] / W, c[1] = s[1] / W, c[2] = s[2] / W;
    double cov[6] = {mm[0] / W - c[0] * c[0], mm[1] / W - c[0] * c[1], mm[2] / W - c[0] * c[2],
                     mm[3] / W - c[1] * c[1], mm[4] / W - c[1] * c[2], mm[5] / W - c[2] * c[2]};
    return smallest_eigenvector(cov, n);
}

/* Robust weights om = w exp(-h^2 / 2 sigma_rho^2) for the plane n.d = t,
 * w the Gaussian distance weight (one exp for both). */
TSL_CLONES static void plane_weights(fit_buf *b, const double n[3], double t, float inv_2sr2)
{
    const float nx = (float)n[0], ny = (float)n[1], nz = (float)n[2], tf = (float)t;
    const size_t mp = b->mp;
    for (size_t j = 0; j < mp; j++) {
        float hq = nx * b->x[j] + ny * b->y[j] + nz * b->z[j] - tf;
        float e = b->ew[j] - (hq * hq) * inv_2sr2;
        b->om[j] = e > EXP_MIN ? e : EXP_MIN;
    }
    for (size_t j = 0; j < mp; j++)
        b->om[j] = b->on[j] * fast_exp(b->om[j]);
}

/* Solves the symmetric positive definite 6x6 system a x = r by LDL^T
 * (no square roots on the dependency chain, unlike Cholesky); false when a
 * is not positive definite to working precision. Only x[first..5] are
 * computed: the back substitution needs none of the others. */
static bool solve6(const double a[6][6], const double r[6], int first, double x[6])
{
    double L[6][6], inv[6];
    for (int i = 0; i < 6; i++) {
        double LD[6]; /* L[i][j] D[j] */
        for (int j = 0; j < i; j++) {
            double s = a[i][j];
            for (int k = 0; k < j; k++)
                s -= LD[k] * L[j][k];
            LD[j] = s;
            L[i][j] = s * inv[j];
        }
        double s = a[i][i];
        for (int k = 0; k < i; k++)
            s -= LD[k] * L[i][k];
        if (!(s > 1e-12 * a[i][i]))
            return false;
        inv[i] = 1.0 / s;
    }
    double y[6];
    for (int i = 0; i < 6; i++) {
        double s = r[i];
        for (int k = 0; k < i; k++)
            s -= L[i][k] * y[k];
        y[i] = s;
    }
    for (int i = 5; i >= first; i--) {
        double s = y[i] * inv[i];
        for (int k = i + 1; k < 6; k++)
            s -= L[k][i] * x[k];
        x[i] = s;
    }
    return true;
}

/* Beyond the paper: the height of the surface above the robust plane at
 * the query, from a weighted least-squares quadric
 *     z = a u^2 + b uv + c v^2 + d u + e v + f
 * over the plane (u, v in the plane through the query's foot point, in
 * units of h; z the height above the plane), with the plane's robust
 * weights. Q(p) then lies f above the plane's point instead of on it, which
 * removes the plane's bias on curved parts (about r^2 / 2R for a
 * neighbourhood of radius r on a surface of radius R). The same weighted
 * sums give the weighted covariance, hence the next plane of the
 * iteration, so one pass over the neighbours does both. */
typedef struct frame_sums {
    double e1[3], e2[3]; /* plane axes, length 1/h */
    double n[3], t;      /* the plane n.d = t the weights belong to */
    double s[22];        /* moments, see frame_sweep */
} frame_sums;

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

static void surface_set(fit_surface *sf, const frame_sums *fs, const double c[6])
{
    double m[3];
    for (int a = 0; a < 3; a++) {
        sf->e1[a] = (float)fs->e1[a];
        sf->e2[a] = (float)fs->e2[a];
        sf->n[a] = (float)fs->n[a];
        m[a] = fs->n[a] - c[3] * fs->e1[a] - c[4] * fs->e2[a];
    }
    if (!tsl_normalize(m))
        tsl_load(sf->n, m);
    sf->t = (float)fs->t;
    for (int i = 0; i < 6; i++)
        sf->c[i] = (float)c[i];
    for (int a = 0; a < 3; a++)
        sf->normal[a] = (float)m[a];
}

static void surface_set_plane(fit_surface *sf, const double n[3], double t)
{
    memset(sf, 0, sizeof *sf);
    for (int a = 0; a < 3; a++)
        sf->n[a] = sf->normal[a] = (float)n[a];
    sf->t = (float)t;
}

/* One pass over the neighbours with weights om for the plane (n, t): the
 * 15 moments of om u^i v^j (i + j <= 4), the 6 of om z u^i v^j (i + j <=
 * 2) and that of om z^2. Order of s: 1, u, v, uu, uv, vv, uuu, uuv, uvv,
 * vvv, uuuu, uuuv, uuvv, uvvv, vvvv, z, zu, zv, zuu, zuv, zvv, zz. */
TSL_CLONES static void frame_sweep(fit_buf *b, const double n[3], double t, double inv_h,
                                   frame_sums *fs)
{
    double a[3] = {0, 0, 0};
    a[fabs(n[0]) < 0.6 ? 0 : 1] = 1.0;
    tsl_cross(a, n, fs->e1);
    double l = inv_h / tsl_norm(fs->e1);
    fs->e1[0] *= l, fs->e1[1] *= l, fs->e1[2] *= l;
    tsl_cross(n, fs->e1, fs->e2); /* |e2| = |e1| = 1/h */
    fs->n[0] = n[0], fs->n[1] = n[1], fs->n[2] = n[2], fs->t = t;
    const float ux = (float)fs->e1[0], uy = (float)fs->e1[1], uz = (float)fs->e1[2];
    const float vx = (float)fs->e2[0], vy = (float)fs->e2[1], vz = (float)fs->e2[2];
    const float nx = (float)n[0], ny = (float)n[1], nz = (float)n[2], tf = (float)t;
    const size_t mp = b->mp;
    float *u = b->t[0], *v = b->t[1], *oz = b->t[2], *uu = b->t[3], *uv = b->t[4];
    float *vv = b->t[5], *ou = b->t[6], *ov = b->t[7], *ouu = b->t[8], *ouv = b->t[9];
    float *ovv = b->t[10], *z = b->t[11];
    const float *o = b->om;
    for (size_t j = 0; j < mp; j++) {
        float x = b->x[j], y = b->y[j], zz = b->z[j];
        float uj = ux * x + uy * y + uz * zz, vj = vx * x + vy * y + vz * zz;
        float zj = nx * x + ny * y + nz * zz - tf;
        u[j] = uj, v[j] = vj, z[j] = zj;
        oz[j] = o[j] * zj;
        uu[j] = uj * uj, uv[j] = uj * vj, vv[j] = vj * vj;
        ou[j] = o[j] * uj, ov[j] = o[j] * vj;
        ouu[j] = o[j] * uu[j], ouv[j] = o[j] * uv[j], ovv[j] = o[j] * vv[j];
    }
    double *S = fs->s;
    S[0] = lane_sum(o, mp), S[1] = lane_sum(ou, mp), S[2] = lane_sum(ov, mp);
    S[3] = lane_sum(ouu, mp), S[4] = lane_sum(ouv, mp), S[5] = lane_sum(ovv, mp);
    S[6] = lane_dot(ouu, u, mp), S[7] = lane_dot(ouu, v, mp);
    S[8] = lane_dot(ouv, v, mp), S[9] = lane_dot(ovv, v, mp);
    S[10] = lane_dot(ouu, uu, mp), S[11] = lane_dot(ouu, uv, mp);
    S[12] = lane_dot(ouu, vv, mp), S[13] = lane_dot(ouv, vv, mp);
    S[14] = lane_dot(ovv, vv, mp);
    S[15] = lane_sum(oz, mp), S[16] = lane_dot(oz, u, mp), S[17] = lane_dot(oz, v, mp);
    S[18] = lane_dot(oz, uu, mp), S[19] = lane_dot(oz, uv, mp), S[20] = lane_dot(oz, vv, mp);
    S[21] = lane_dot(oz, z, mp);
}

/* The weighted plane from the sums: unit normal n2 and offset t2 (the
 * plane n2.d = t2 through the weighted centroid). The covariance is taken
 * in the frame (u, v, z / h), orthonormal up to the common scale 1/h. */
static bool frame_plane(const frame_sums *fs, double inv_h, double n2[3], double *t2)
{
    const double *S = fs->s, W = S[0];
    if (!(W > 1e-30))
        return false;
    double c0 = S[1] / W, c1 = S[2] / W, c2 = S[15] * inv_h / W;
    double cov[6] = {S[3] / W - c0 * c0,
                     S[4] / W - c0 * c1,
                     S[16] * inv_h / W - c0 * c2,
                     S[5] / W - c1 * c1,
                     S[17] * inv_h / W - c1 * c2,
                     S[21] * inv_h * inv_h / W - c2 * c2};
    double ev[3];
    if (!smallest_eigenvector(cov, ev))
        return false;
    double h = 1.0 / inv_h, c[3];
    for (int a = 0; a < 3; a++) {
        n2[a] = (ev[0] * fs->e1[a] + ev[1] * fs->e2[a]) * h + ev[2] * fs->n[a];
        /* centroid relative to the query, world units */
        c[a] = (c0 * fs->e1[a] + c1 * fs->e2[a]) * h * h + (c2 * h + fs->t) * fs->n[a];
    }
    if (!tsl_normalize(n2))
        return false;
    *t2 = tsl_dot(n2, c);
    return true;
}

/* The quadric's coefficients c (as in fit_surface): its height above the
 * plane at the query's foot point is c[5], its slope there (df/du, df/dv,
 * world units per h) c[3], c[4]; the curvature terms c[0..2] only when
 * `full` (a fit_surface wants them; skipping them saves 0.7% of the
 * smoothing's instructions). The curvature terms
 * carry a ridge penalty of `ridge` times the total weight (u, v in h), a
 * prior that keeps noisy flat neighbourhoods near the plane. False when
 * the system is singular. */
static bool frame_height(const frame_sums *fs, double ridge, bool full, double c[6])
{
    /* Unknowns (a, b, c, d, e, f); moment indices: 1, u, v, uu, uv, vv,
     * uuu, uuv, uvv, vvv, uuuu, uuuv, uuvv, uvvv, vvvv. */
    const double *S = fs->s, W = S[0];
    double M[6][6] = {
        {S[10], S[11], S[12], S[6], S[7], S[3]}, {S[11], S[12], S[13], S[7], S[8], S[4]},
        {S[12], S[13], S[14], S[8], S[9], S[5]}, {S[6], S[7], S[8], S[3], S[4], S[1]},
        {S[7], S[8], S[9], S[4], S[5], S[2]},    {S[3], S[4], S[5], S[1], S[2], S[0]},
    };
    double r[6] = {S[18], S[19], S[20], S[16], S[17], S[15]};
    if (!(W > 1e-30))
        return false;
    for (int i = 0; i < 3; i++)
        M[i][i] += ridge * W;
    return solve6(M, r, full ? 0 : 3, c);
}

/* A later pass's fit with the quadric: the point already lies on the
 * previous fit, so the robust weights belong to the plane through it
 * across the previous normal n, and Q is the quadric's height over that
 * plane, as the general IRLS step would give; the new normal is the
 * quadric's own at the point (its slope tilts n), which saves that step's
 * weighted plane and eigen-solve and is closer to the true normal on the
 * noisy scans (docs/smooth.md). False, with n unchanged, when the quadric
 * is singular or out of range: the caller falls back to the plane step. */
static bool warm_quadric(const fit_ctl *f, fit_buf *b, double n[3], double move[3],
                         fit_surface *surf)
{
    frame_sums q;
    double c[6], m[3];
    plane_weights(b, n, 0.0, (float)f->inv_2sr2);
    frame_sweep(b, n, 0.0, 1.0 / f->h, &q);
    if (!frame_height(&q, f->ridge, surf != NULL, c) || !(fabs(c[5]) <= f->quad_max))
        return false;
    double hq = c[5];
    for (int a = 0; a < 3; a++)
        m[a] = n[a] - c[3] * q.e1[a] - c[4] * q.e2[a];
    if (!tsl_normalize(m))
        return false;
    if (surf)
        surface_set(surf, &q, c);
    move[0] = hq * n[0], move[1] = hq * n[1], move[2] = hq * n[2];
    n[0] = m[0], n[1] = m[1], n[2] = m[2];
    return true;
}

/* The robust fit for one query from its neighbours (offsets, sorted by
 * distance). On success writes the unit normal n, the displacement move
 * (Q = q + move) and the IRLS iterations. Returns false when there is no
 * fit (too few neighbours, or all of them on a line).
 *
 * IRLS: robust weights for the current plane, then the weighted plane of
 * the neighbours, until the plane settles. The first plane is the
 * Gaussian-weighted one (start == NULL: a first pass, the projector), or
 * the plane through the query across the previous pass's normal `start`
 * (later passes: the point already lies on the previous fit), which takes
 * one step: each pass continues the iteration instead of restarting it
 * (with the quadric, that step is warm_quadric).
 * Q is the foot point on the last plane the weights belong to, lifted by
 * the quadric's height over it (quadric on), or the foot point on the
 * final plane (the paper's operator). */
TSL_CLONES static bool robust_fit(const fit_ctl *f, fit_buf *b, const float *start,
                                  double n[3], double move[3], uint32_t *iterations,
                                  fit_surface *surf)
{
    if (b->m < f->min_neighbors)
        return false;
    fit_pad(b);
    const float inv_2sw2 = (float)f->inv_2sw2;
    const size_t mp = b->mp;
    for (size_t j = 0; j < mp; j++)
        b->ew[j] = -(b->x[j] * b->x[j] + b->y[j] * b->y[j] + b->z[j] * b->z[j]) * inv_2sw2;
    for (size_t j = 0; j < mp; j++)
        b->on[j] = j < b->m ? 1.0f : 0.0f;
    /* The point itself (offset exactly 0) would enter with the largest
     * weight and keep a share of its own noise (its leverage). */
    if (f->exclude_self)
        for (size_t j = 0; j < b->m; j++)
            if (b->x[j] == 0.0f && b->y[j] == 0.0f && b->z[j] == 0.0f)
                b->on[j] = 0.0f;
    const float inv_2sr2 = (float)f->inv_2sr2;
    const double inv_h = 1.0 / f->h;
    double t = 0.0;
    uint32_t max_it = f->max_iterations;
    if (start) {
        tsl_load(start, n);
        if (!tsl_normalize(n))
            return false;
        max_it = 1;
        if (f->quadric && warm_quadric(f, b, n, move, surf)) {
            *iterations = 1;
            return true;
        }
    } else {
        double W, s[3], mm[6], c[3];
        for (size_t j = 0; j < mp; j++)
            b->om[j] = b->ew[j] > EXP_MIN ? b->ew[j] : EXP_MIN;
        for (size_t j = 0; j < mp; j++)
            b->om[j] = b->on[j] * fast_exp(b->om[j]);
        plane_moments(b, &W, s, mm);
        if (!plane_from_moments(W, s, mm, c, n))
            return false;
        t = tsl_dot(n, c);
    }

    frame_sums fs;
    memset(&fs, 0, sizeof fs); /* (GCC cannot see that `have` guards it) */
    bool have = false;         /* fs holds the sums of a successful step */
    bool stepped = false; /* some step gave a plane */
    uint32_t it = 0;
    while (it < max_it) {
        it++;
        plane_weights(b, n, t, inv_2sr2);
        double n2[3], t2;
        if (f->quadric) {
            frame_sweep(b, n, t, inv_h, &fs);
            if (!frame_plane(&fs, inv_h, n2, &t2))
                break;
            have = true;
        } else {
            double W, s[3], mm[6], c[3];
            plane_moments(b, &W, s, mm);
            if (!plane_from_moments(W, s, mm, c, n2))
                break;
            t2 = tsl_dot(n2, c);
        }
        stepped = true;
        if (tsl_dot(n2, n) < 0.0)
            n2[0] = -n2[0], n2[1] = -n2[1], n2[2] = -n2[2], t2 = -t2;
        double x[3];
        tsl_cross(n, n2, x);
        bool done = fabs(t2 - t) <= f->tol_t && tsl_dot(x, x) <= f->tol_n * f->tol_n;
        n[0] = n2[0], n[1] = n2[1], n[2] = n2[2];
        t = t2;
        if (done)
            break;
    }
    if (start && !stepped)
        return false; /* the warm start's step failed: no plane at all */
    *iterations = it;
    double c[6];
    if (have && frame_height(&fs, f->ridge, surf != NULL, c) && fabs(c[5]) <= f->quad_max) {
        double h0 = fs.t + c[5];
        move[0] = h0 * fs.n[0], move[1] = h0 * fs.n[1], move[2] = h0 * fs.n[2];
        if (surf)
            surface_set(surf, &fs, c);
    } else {
        move[0] = t * n[0], move[1] = t * n[1], move[2] = t * n[2];
        if (surf)
            surface_set_plane(surf, n, t);
    }
    return true;
}

/* The normal of an unfit point: smallest-eigenvalue direction of the plain
 * covariance of its neighbours (Jacobi yields a unit vector even for
 * coincident points, where the direction is arbitrary). */
static void plain_normal(const fit_buf *b, double n[3])
{
    double W = 0.0, s[3] = {0, 0, 0}, mm[6] = {0, 0, 0, 0, 0, 0}, c[3] = {0, 0, 0};
    for (size_t j = 0; j < b->filled; j++) {
        double d[3] = {b->x[j], b->y[j], b->z[j]};
        W += 1.0;
        s[0] += d[0], s[1] += d[1], s[2] += d[2];
        mm[0] += d[0] * d[0], mm[1] += d[0] * d[1], mm[2] += d[0] * d[2];
        mm[3] += d[1] * d[1], mm[4] += d[1] * d[2], mm[5] += d[2] * d[2];
    }
    if (W > 0.0)
        c[0] = s[0] / W, c[1] = s[1] / W, c[2] = s[2] / W;
    double a[9], w[3], v[9];
    a[0] = W > 0 ? mm[0] / W - c[0] * c[0] : 0.0;
    a[1] = a[3] = W > 0 ? mm[1] / W - c[0] * c[1] : 0.0;
    a[2] = a[6] = W > 0 ? mm[2] / W - c[0] * c[2] : 0.0;
    a[4] = W > 0 ? mm[3] / W - c[1] * c[1] : 0.0;
    a[5] = a[7] = W > 0 ? mm[4] / W - c[1] * c[2] : 0.0;
    a[8] = W > 0 ? mm[5] / W - c[2] * c[2] : 0.0;
    tsl_eigen_sym3(a, w, v);
    n[0] = v[0], n[1] = v[3], n[2] = v[6];
}

/* Sign convention: agree with the nearest cloud point's normal when the
 * cloud has normals, else face the viewpoint when there is one. */
static void orient(const float *nearest_normal, int has_viewpoint, const double viewpoint[3],
                   const float q[3], double n[3])
{
    double ref[3];
    if (nearest_normal) {
        tsl_load(nearest_normal, ref);
    } else if (has_viewpoint) {
        ref[0] = viewpoint[0] - q[0];
        ref[1] = viewpoint[1] - q[1];
        ref[2] = viewpoint[2] - q[2];
    } else {
        return;
    }
    if (tsl_dot(n, ref) < 0.0)
        n[0] = -n[0], n[1] = -n[1], n[2] = -n[2];
}

/* Fit, orient and write one result (b as described at fit_buf; start:
 * the normal to start the iterations from, or NULL for the Gaussian-weighted
 * plane). Returns true when fitted. */
static bool solve_one(const fit_ctl *f, const float q[3], fit_buf *b, const float *start,
                      const float *nearest_normal, int has_viewpoint, const double viewpoint[3],
                      float out[3], float normal[3], uint32_t *iterations, fit_surface *surf)
{
    double n[3], move[3] = {0, 0, 0};
    uint32_t its = 0;
    bool fit = robust_fit(f, b, start, n, move, &its, surf);
    if (!fit) {
        plain_normal(b, n);
        if (surf)
            surf->t = NAN;
    }
    orient(nearest_normal, has_viewpoint, viewpoint, q, n);
    out[0] = (float)(q[0] + move[0]);
    out[1] = (float)(q[1] + move[1]);
    out[2] = (float)(q[2] + move[2]);
    if (normal)
        normal[0] = (float)n[0], normal[1] = (float)n[1], normal[2] = (float)n[2];
    *iterations = its;
    return fit;
}
/* ---- the projector ---- */

/* The spacing to use: the params' one, or the cloud's estimate. */
static tessel_status resolve_spacing(const tessel_cloud *cloud, double given, double *h)
{
    if (given > 0.0) {
        *h = given;
        return TESSEL_OK;
    }
    tessel_status st = tessel_cloud_spacing(cloud, h);
    if (st != TESSEL_OK)
        return st;
    /* All points equal: no scale to smooth at. */
    if (!(*h > 0.0) || !isfinite(*h))
        return TESSEL_ERR_TOO_FEW_POINTS;
    return TESSEL_OK;
}

static tessel_status check_cloud(const tessel_cloud *cloud)
{
    if (!cloud || (cloud->count > 0 && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;
    if (cloud->count >= (size_t)TESSEL_NONE)
        return TESSEL_ERR_LIMIT;
    /* Readers drop non-finite points; a caller's array might not have. */
    for (size_t i = 0; i < 3 * cloud->count; i++)
        if (!isfinite(cloud->xyz[i]))
            return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

tessel_status tsl_projector_create_on(tessel_projector **projector, const tessel_cloud *cloud,
                                     const tessel_smooth_params *params,
                                     const tessel_index *index)
{
    if (!projector)
        return TESSEL_ERR_INVALID_ARG;
    *projector = NULL;
    tessel_smooth_params p = params ? *params : tessel_smooth_params_default();
    tessel_status st = check_params(&p);
    if (st == TESSEL_OK)
        st = check_cloud(cloud);
    if (st != TESSEL_OK)
        return st;
    double h;
    st = resolve_spacing(cloud, p.spacing, &h);
    if (st != TESSEL_OK)
        return st;
    tessel_projector *pr = calloc(1, sizeof *pr);
    if (!pr)
        return TESSEL_ERR_NOMEM;
    if (!index) {
        st = tessel_index_build(&pr->own, cloud->xyz, cloud->count);
        if (st != TESSEL_OK) {
            free(pr);
            return st;
        }
        index = pr->own;
    }
    pr->index = index;
    pr->xyz = cloud->xyz;
    pr->normals = cloud->normals;
    pr->count = cloud->count;
    if (cloud->has_viewpoint) {
        pr->has_viewpoint = 1;
        for (int i = 0; i < 3; i++)
            pr->viewpoint[i] = cloud->viewpoint[i] - cloud->offset[i];
    }
    ctl_setup(&pr->ctl, &p, h, p.sigma_rho);
    *projector = pr;
    return TESSEL_OK;
}

tessel_status tessel_projector_create(tessel_projector **projector, const tessel_cloud *cloud,
                                      const tessel_smooth_params *params)
{
    return tsl_projector_create_on(projector, cloud, params, NULL);
}

void tessel_projector_destroy(tessel_projector *projector)
{
    if (!projector)
        return;
    tessel_index_destroy(projector->own);
    free(projector);
}

const tessel_index *tsl_projector_index(const tessel_projector *projector, const float *xyz,
                                        size_t count)
{
    if (!projector || projector->xyz != xyz || projector->count != count)
        return NULL;
    return projector->index;
}

double tessel_projector_spacing(const tessel_projector *projector)
{
    return projector ? projector->ctl.h : 0.0;
}

tessel_status tessel_project(const tessel_projector *pr, const float q[3], float out[3],
                             float normal[3], uint32_t *iterations)
{
    uint32_t idx[SMOOTH_MAX_K];
    float d2[SMOOTH_MAX_K];
    fit_buf b;

    if (iterations)
        *iterations = 0;
    if (!pr || !q || !out)
        return TESSEL_ERR_INVALID_ARG;
    const fit_ctl *f = &pr->ctl;
    size_t all_m = tessel_index_knn(pr->index, q, f->k, idx, d2);
    size_t m = 0;
    float r2 = (float)(f->rmax * f->rmax);
    for (size_t j = 0; j < all_m; j++) {
        const float *x = pr->xyz + 3 * (size_t)idx[j];
        b.x[j] = x[0] - q[0];
        b.y[j] = x[1] - q[1];
        b.z[j] = x[2] - q[2];
        m += d2[j] <= r2;
    }
    b.m = m;
    b.filled = all_m;
    const float *nn = pr->normals ? pr->normals + 3 * (size_t)idx[0] : NULL;
    uint32_t its;
    bool fit =
        solve_one(f, q, &b, NULL, nn, pr->has_viewpoint, pr->viewpoint, out, normal, &its, NULL);
    if (iterations)
        *iterations = its;
    return fit ? TESSEL_OK : TESSEL_ERR_TOO_FEW_POINTS;
}

/* ---- neighbour search on the grid (src/grid.c) ---- */

/* The k nearest within the cut-off, sorted by (distance, index) as the
 * kd-tree orders them. */
typedef struct topk {
    size_t cnt, k;
    float d[SMOOTH_MAX_K];
    uint32_t id[SMOOTH_MAX_K];  /* point index (topk_block leaves it out) */
    uint32_t pos[SMOOTH_MAX_K]; /* sorted position */
} topk;

static inline bool before(float d, uint32_t i, float e, uint32_t j)
{
    return d < e || (d == e && i < j);
}

/* Offers one candidate to t. */
static inline void topk_add(topk *t, float d, uint32_t id, uint32_t pos)
{
    size_t j = t->cnt;
    if (j == t->k) {
        if (!before(d, id, t->d[j - 1], t->id[j - 1]))
            return;
        j--;
    } else {
        t->cnt++;
    }
    while (j > 0 && before(d, id, t->d[j - 1], t->id[j - 1])) {
        t->d[j] = t->d[j - 1];
        t->id[j] = t->id[j - 1];
        t->pos[j] = t->pos[j - 1];
        j--;
    }
    t->d[j] = d;
    t->id[j] = id;
    t->pos[j] = pos;
}

static inline float dist2(const float *p, const float *q)
{
    float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

/* Offers every point of the runs to t. */
static void topk_scan(topk *t, const tsl_grid *g, const float *q, const uint32_t *run,
                      size_t nrun, float r2max)
{
    for (size_t r = 0; r < nrun; r++)
        for (uint32_t s = run[2 * r]; s < run[2 * r + 1]; s++) {
            float d = dist2(g->sxyz + 3 * (size_t)s, q);
            if (d <= r2max)
                topk_add(t, d, g->perm[s], s);
        }
}

/* Offers to t every point of the cells at Chebyshev distance ring (>= 2)
 * from cell cc that can still hold one of the k nearest. */
typedef struct ring_scan {
    topk *t;
    const tsl_grid *g;
    const float *q;
    float r2max;
} ring_scan;

static void ring_cell(void *ctx, int64_t x, int64_t y, int64_t z)
{
    ring_scan *c = ctx;
    topk *t = c->t;
    float worst = t->cnt == t->k ? t->d[t->cnt - 1] : c->r2max;
    if (tsl_grid_box_d2(c->g, c->q, x, y, z) > worst)
        return;
    size_t ci = tsl_grid_find(c->g, tsl_morton((uint32_t)x, (uint32_t)y, (uint32_t)z));
    if (ci == SIZE_MAX)
        return;
    uint32_t run[2] = {c->g->start[ci], c->g->start[ci + 1]};
    topk_scan(t, c->g, c->q, run, 1, c->r2max);
}

static void topk_ring(topk *t, const tsl_grid *g, const float *q, const uint32_t cc[3],
                      int64_t ring, float r2max)
{
    ring_scan c = {t, g, q, r2max};
    tsl_grid_shell(g, cc, ring, ring_cell, &c);
}

/* The candidates of one cell (its 27-cell block) copied side by side, so
 * that the distances of a query to all of them vectorise. */
#define BLOCK_CAP 1024u
typedef struct block {
    size_t m;
    float x[BLOCK_CAP], y[BLOCK_CAP], z[BLOCK_CAP];
    uint32_t pos[BLOCK_CAP];
    /* Squared distances to the current query as their bit patterns, which
     * order like the (non-negative) values and compare as integers, which
     * vectorises where float comparisons do not (GCC keeps a branch for
     * them under -ftrapping-math). */
    int32_t d[BLOCK_CAP + 8];  /* padded with +infinity */
    int32_t cd[BLOCK_CAP + 8]; /* those of the candidates, padded */
    int16_t cq[BLOCK_CAP + 8];   /* the same, quantised to 16 bits */
    int16_t rank[BLOCK_CAP + 8]; /* candidates before each */
    uint32_t cj[BLOCK_CAP];  /* candidates' block slots */
    uint64_t sel[BLOCK_CAP]; /* candidates sorted as (distance, slot) */
} block;

static inline uint32_t float_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

/* Point index of a selection key's block slot. */
static inline uint32_t block_id(const block *b, const tsl_grid *g, uint64_t key)
{
    return g->perm[b->pos[(uint32_t)key]];
}

/* Number of the first m (rounded up to 8) values <= thr: eight partial
 * counts, which vectorise. */
static inline size_t count_below(const int32_t *d, size_t m, int32_t thr)
{
    uint32_t c[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (size_t j0 = 0; j0 < m; j0 += 8)
        for (int l = 0; l < 8; l++)
            c[l] += (uint32_t)(d[j0 + (size_t)l] <= thr);
    return (size_t)c[0] + c[1] + c[2] + c[3] + c[4] + c[5] + c[6] + c[7];
}

/* Block slots whose distance bits are <= tb, into b->cj; returns their
 * number. Eight at a time: groups with none below (whole cells away from
 * the query) are skipped; within a group, branch-free (always store,
 * advance when it passes). */
static inline size_t block_select(block *b, size_t m, int32_t tb)
{
    size_t ns = 0;
    for (size_t j0 = 0; j0 < m; j0 += 8) {
        if (count_below(b->d + j0, 8, tb) == 0)
            continue;
        for (size_t j = j0; j < j0 + 8; j++) {
            b->cj[ns] = (uint32_t)j;
            ns += b->d[j] <= tb;
        }
    }
    return ns;
}

/* The k nearest of the block within r2max. A threshold that admits a
 * little more than k candidates (from the previous query's k-th distance,
 * *guess) picks a few; they are sorted as 64-bit keys (distance bits, which
 * order like the distances since they are >= 0, then block slot), equal
 * distances reordered by point index, and the first k kept. */
TSL_CLONES static void topk_block(topk *t, block *b, const tsl_grid *g, const float *q,
                                  float r2max, float *guess)
{
    const size_t m = b->m;
    const float qx = q[0], qy = q[1], qz = q[2];
    float thr = *guess < r2max ? *guess : r2max;
    /* k or more copies of one point make the k-th distance 0: the guess
     * from such a query, and the halving below, must stop above 0, or the
     * loops never end (they hung on such clouds). A 64th of a cell's
     * square is far below any k-th distance the cells are sized for, and
     * the selection is exact whatever the threshold. */
    const float least = (float)(g->c * g->c) * (1.0f / 64.0f);
    if (thr < least)
        thr = least < r2max ? least : r2max;
    for (size_t j = 0; j < m; j++) {
        float dx = b->x[j] - qx, dy = b->y[j] - qy, dz = b->z[j] - qz;
        float d = (dx * dx + dy * dy) + dz * dz;
        memcpy(&b->d[j], &d, sizeof d);
    }
    const int32_t inf_bits = 0x7f800000;
    for (size_t j = m; j < ((m + 7) & ~(size_t)7); j++)
        b->d[j] = inf_bits;
    /* A threshold that admits at least k (or all within the cut-off) and,
     * for the sort below, not many more. */
    size_t ns;
    bool shrunk = false;
    for (;;) {
        ns = block_select(b, m, (int32_t)float_bits(thr));
        if (ns < t->k && thr < r2max) {
            thr = thr * 1.15f < r2max ? thr * 1.15f : r2max;
            continue;
        }
        if (ns > 2 * t->k + 16 && !shrunk) {
            /* Far too many for the sort: halve while k remain. */
            shrunk = true;
            float half = 0.5f * thr;
            bool smaller = false;
            while (half >= least && count_below(b->d, m, (int32_t)float_bits(half)) >= t->k)
                thr = half, half *= 0.5f, smaller = true;
            if (smaller)
                continue;
        }
        break;
    }
    /* Sort by rank: candidate i goes to the number of candidates before it
     * in (distance, slot) order. Quadratic, but branch-free and vectorised,
     * and ns is only a little more than k. */
    size_t np = (ns + 7) & ~(size_t)7;
    for (size_t i = 0; i < ns; i++)
        b->cd[i] = b->d[b->cj[i]];
    for (size_t i = ns; i < np; i++)
        b->cd[i] = inf_bits;
    /* The ranks are counted on 16-bit quantised distances (monotonic, so
     * they order as the distances except within a quantum): eight to a
     * vector instead of four. Candidates that share a quantum share a rank,
     * which sends the rare query with such a pair (or an exact tie) to the
     * exact count below. */
    const float scale = 65000.0f / thr;
    for (size_t i = 0; i < np; i++) {
        float d;
        memcpy(&d, &b->cd[i], sizeof d);
        float qv = d * scale;
        b->cq[i] = (int16_t)((int32_t)(qv < 65000.0f ? qv : 65535.0f) - 32768);
    }
    memset(b->sel, 0xff, ns * sizeof *b->sel); /* no key: NaN distance bits */
    memset(b->rank, 0, np * sizeof *b->rank);
    size_t jr = 0;
    for (; jr + 4 <= ns; jr += 4) { /* four at a time: fewer loads and stores */
        const int16_t q0 = b->cq[jr], q1 = b->cq[jr + 1], q2 = b->cq[jr + 2];
        const int16_t q3 = b->cq[jr + 3];
        for (size_t i = 0; i < np; i++) {
            int16_t c = b->cq[i];
            b->rank[i] = (int16_t)(b->rank[i] + (q0 < c) + (q1 < c) + (q2 < c) + (q3 < c));
        }
    }
    for (; jr < ns; jr++) {
        const int16_t qj = b->cq[jr];
        for (size_t i = 0; i < np; i++)
            b->rank[i] = (int16_t)(b->rank[i] + (qj < b->cq[i]));
    }
    bool tie = false;
    for (size_t i = 0; i < ns; i++) {
        uint32_t r = (uint32_t)b->rank[i];
        tie |= b->sel[r] != UINT64_MAX;
        b->sel[r] = (uint64_t)(uint32_t)b->cd[i] << 32 | b->cj[i];
    }
    if (tie) { /* equal distances share a rank: count earlier equals too */
        for (size_t i = 0; i < ns; i++) {
            const int32_t di = b->cd[i];
            uint32_t r = 0;
            for (size_t j = 0; j < ns; j++)
                r += b->cd[j] < di || (b->cd[j] == di && j < i);
            b->sel[r] = (uint64_t)(uint32_t)di << 32 | b->cj[i];
        }
    }
    size_t keep = ns < t->k ? ns : t->k;
    if (keep > 0 && tie) {
        /* Equal distances go in point-index order (rare): within runs that
         * are kept whole, and at the cut, where the run [a, end) gives its
         * smallest indices to the slots up to keep. */
        uint64_t dk = b->sel[keep - 1] >> 32;
        size_t a = keep - 1, end = keep;
        while (a > 0 && b->sel[a - 1] >> 32 == dk)
            a--;
        while (end < ns && b->sel[end] >> 32 == dk)
            end++;
        for (size_t i = 1; i < a; i++)
            for (size_t j = i; j > 0 && b->sel[j] >> 32 == b->sel[j - 1] >> 32 &&
                               block_id(b, g, b->sel[j]) < block_id(b, g, b->sel[j - 1]);
                 j--) {
                uint64_t v = b->sel[j];
                b->sel[j] = b->sel[j - 1], b->sel[j - 1] = v;
            }
        for (size_t i = a; i < keep && end - a > 1; i++) {
            size_t best = i;
            for (size_t j = i + 1; j < end; j++)
                if (block_id(b, g, b->sel[j]) < block_id(b, g, b->sel[best]))
                    best = j;
            uint64_t v = b->sel[i];
            b->sel[i] = b->sel[best], b->sel[best] = v;
        }
    }
    for (size_t i = 0; i < keep; i++) {
        uint32_t j = (uint32_t)b->sel[i], bits = (uint32_t)(b->sel[i] >> 32);
        t->pos[i] = b->pos[j];
        memcpy(&t->d[i], &bits, sizeof(float));
    }
    t->cnt = keep;
    /* Next query: a little above this k-th distance. */
    if (keep > 0)
        *guess = t->d[keep - 1] * 1.12f;
}

/* ---- smoothing passes ---- */

/* Points per progress report / cancellation check (at least). */
#define SMOOTH_CHUNK ((size_t)1 << 18)

/* One smoothing run. Everything is indexed by sorted position (the grid's
 * order: points of a cell side by side, cells in Morton order), so that
 * the neighbours of nearby points are nearby in memory. */
typedef struct pass_ctx {
    const fit_ctl *f;
    const tsl_grid *g;
    const float *cur_xyz;  /* positions this pass reads, by sorted position */
    const float *ref_nrm;  /* orientation reference by sorted position, or
                              NULL */
    int has_viewpoint;
    double viewpoint[3];
    float *out_xyz, *out_nrm;
    uint32_t *nb;  /* k neighbour slots (sorted positions) per point */
    uint16_t *cnt; /* neighbours per point */
    fit_surface *surf; /* each point's fitted surface (params.aggregate), or
                          NULL */
    struct crowd *crowd; /* for crowded blocks */
} pass_ctx;

typedef struct pass_count {
    size_t unfit, unconverged;
    uint64_t iterations;
} pass_count;

static void count_fit(pass_count *c, bool fit, uint32_t its, uint32_t max_iterations)
{
    if (!fit) {
        c->unfit++;
    } else {
        c->iterations += its;
        c->unconverged += its >= max_iterations;
    }
}

/* Records point s's neighbours t (sorted positions, for the later passes)
 * and smooths it. */
static inline void fit_first(const pass_ctx *x, fit_buf *fb, uint32_t s, const topk *t,
                             pass_count *pc)
{
    const tsl_grid *g = x->g;
    const fit_ctl *f = x->f;
    const float *q = g->sxyz + 3 * (size_t)s;
    for (size_t j = 0; j < t->cnt; j++) {
        const float *p = g->sxyz + 3 * (size_t)t->pos[j];
        fb->x[j] = p[0] - q[0];
        fb->y[j] = p[1] - q[1];
        fb->z[j] = p[2] - q[2];
    }
    if (x->nb) {
        memcpy(x->nb + (size_t)s * f->k, t->pos, t->cnt * sizeof *x->nb);
        x->cnt[s] = (uint16_t)t->cnt;
    }
    fb->m = fb->filled = t->cnt;
    uint32_t its;
    const float *nn = x->ref_nrm && t->cnt ? x->ref_nrm + 3 * (size_t)t->pos[0] : NULL;
    bool fit = solve_one(f, q, fb, NULL, nn, x->has_viewpoint, x->viewpoint,
                         x->out_xyz + 3 * (size_t)s, x->out_nrm + 3 * (size_t)s, &its,
                         x->surf ? x->surf + s : NULL);
    count_fit(pc, fit, its, f->max_iterations);
}

/* For crowded blocks: a kd-tree over the cloud and each point's sorted
 * position, built by the first thread that meets one. A random sample's
 * fullest cell often passes the bound that makes a crowded block possible
 * (27 times it over BLOCK_CAP) while no block is crowded: 10^6 points on a
 * torus have cells of up to 38 points and none of their blocks over 1024,
 * and building the tree anyway cost a tenth of the pass. */
typedef struct crowd {
    const float *xyz; /* the cloud */
    const tsl_grid *g;
    tessel_index *index;
    uint32_t *pos_of;
    tessel_status st; /* of the build */
} crowd;

static tessel_status crowd_build(crowd *c)
{
    size_t n = c->g->n;
    tessel_status st = tessel_index_build(&c->index, c->xyz, n);
    if (st != TESSEL_OK)
        return st;
    if (!(c->pos_of = tsl_alloc_array(n ? n : 1, sizeof *c->pos_of)))
        return TESSEL_ERR_NOMEM;
    for (size_t s = 0; s < n; s++)
        c->pos_of[c->g->perm[s]] = (uint32_t)s;
    return TESSEL_OK;
}

/* True once the tree is there; false if building it failed (c->st). */
static bool crowd_ready(crowd *c)
{
    bool ok;
#ifdef _OPENMP
#pragma omp critical(tsl_smooth_crowd)
#endif
    {
        if (!c->pos_of && c->st == TESSEL_OK)
            c->st = crowd_build(c);
        ok = c->st == TESSEL_OK;
    }
    return ok;
}

/* The points of a crowded cell: their k nearest within the cut-off from
 * the kd-tree, which returns them in the same order as the grid search. */
static void crowded_cell(const pass_ctx *x, fit_buf *fb, size_t ci, pass_count *pc)
{
    const tsl_grid *g = x->g;
    if (!crowd_ready(x->crowd))
        return; /* the pass reports x->crowd->st */
    const float r2max = (float)(x->f->rmax * x->f->rmax);
    topk t;
    t.k = x->f->k;
    for (uint32_t s = g->start[ci]; s < g->start[ci + 1]; s++) {
        size_t got =
            tessel_index_knn(x->crowd->index, g->sxyz + 3 * (size_t)s, t.k, t.id, t.d);
        t.cnt = 0;
        while (t.cnt < got && t.d[t.cnt] <= r2max) {
            t.pos[t.cnt] = x->crowd->pos_of[t.id[t.cnt]];
            t.cnt++;
        }
        fit_first(x, fb, s, &t, pc);
    }
}

/* First pass over the points of cell ci: finds the k nearest neighbours
 * within the cut-off (recorded for the later passes) and smooths. b is
 * scratch. */
TSL_CLONES static void search_cell(const pass_ctx *x, block *b, fit_buf *fb, size_t ci,
                                   pass_count *pc)
{
    const tsl_grid *g = x->g;
    const fit_ctl *f = x->f;
    uint32_t run1[2 * 27];
    size_t n1 = 0;
    topk t;
    const float r2max = (float)(f->rmax * f->rmax);

    uint32_t cc[3];
    const float *first = g->sxyz + 3 * (size_t)g->start[ci];
    for (int a = 0; a < 3; a++)
        cc[a] = tsl_grid_cell(g, first, a);
    n1 = tsl_grid_ring(g, cc, 0, run1, 0);
    n1 = tsl_grid_ring(g, cc, 1, run1, n1);
    size_t m = 0;
    for (size_t r = 0; r < n1; r++)
        m += run1[2 * r + 1] - run1[2 * r];
    /* A crowded block (density far above the mean the cells are sized
     * for) would cost every query a scan of all its points. */
    if (m > BLOCK_CAP) {
        crowded_cell(x, fb, ci, pc);
        return;
    }
    b->m = 0;
    for (size_t r = 0; r < n1; r++)
        for (uint32_t s = run1[2 * r]; s < run1[2 * r + 1]; s++) {
            const float *p = g->sxyz + 3 * (size_t)s;
            b->x[b->m] = p[0], b->y[b->m] = p[1], b->z[b->m] = p[2];
            b->pos[b->m++] = s;
        }
    float guess = (float)(g->c * g->c);

    for (uint32_t s = g->start[ci]; s < g->start[ci + 1]; s++) {
        const float *q = g->sxyz + 3 * (size_t)s;
        t.cnt = 0;
        t.k = f->k;
        bool ids = false; /* t.id filled (the block leaves it) */
        topk_block(&t, b, g, q, r2max, &guess);
        /* The cells within Chebyshev distance `ring` hold every point
         * within `cover` of q; widen until that reaches the k-th neighbour
         * (or the cut-off). Cells at the grid's border cover everything
         * beyond it. */
        const double slack = 1.0 - 1e-6; /* rounding of the float distances */
        for (int64_t ring = 1;; ring++) {
            double cover = INFINITY;
            for (int a = 0; a < 3; a++) {
                double lo = (int64_t)cc[a] - ring <= 0
                                ? INFINITY
                                : q[a] - (g->origin[a] + ((double)cc[a] - (double)ring) * g->c);
                double hi =
                    (int64_t)cc[a] + ring >= (int64_t)g->dims[a] - 1
                        ? INFINITY
                        : g->origin[a] + ((double)cc[a] + (double)ring + 1.0) * g->c - q[a];
                cover = fmin(cover, fmin(lo, hi));
            }
            double need = t.cnt < t.k ? f->rmax : fmin(sqrt((double)t.d[t.cnt - 1]), f->rmax);
            if (need < cover * slack)
                break;
            if (!ids) { /* the ring's candidates compare by point index too */
                for (size_t j = 0; j < t.cnt; j++)
                    t.id[j] = g->perm[t.pos[j]];
                ids = true;
            }
            topk_ring(&t, g, q, cc, ring + 1, r2max);
        }
        fit_first(x, fb, s, &t, pc);
    }
}

/* A later pass for sorted positions [s0, s1): the first pass's neighbours
 * at their current positions. */
TSL_CLONES static void refit_range(const pass_ctx *x, fit_buf *fb, size_t s0, size_t s1,
                                   pass_count *pc)
{
    const fit_ctl *f = x->f;
    const float *cur = x->cur_xyz;
    for (size_t s = s0; s < s1; s++) {
        const float *q = cur + 3 * s;
        const uint32_t *nb = x->nb + s * f->k;
        size_t m = x->cnt[s];
        for (size_t j = 0; j < m; j++) {
            const float *p = cur + 3 * (size_t)nb[j];
            fb->x[j] = p[0] - q[0];
            fb->y[j] = p[1] - q[1];
            fb->z[j] = p[2] - q[2];
        }
        fb->m = fb->filled = m;
        uint32_t its;
        const float *nn = x->ref_nrm && m ? x->ref_nrm + 3 * (size_t)nb[0] : NULL;
        bool fit = solve_one(f, q, fb, x->ref_nrm + 3 * s, nn, x->has_viewpoint, x->viewpoint,
                             x->out_xyz + 3 * s, x->out_nrm + 3 * s, &its,
                             x->surf ? x->surf + s : NULL);
        count_fit(pc, fit, its, f->max_iterations);
    }
}

/* Beyond the paper (params.aggregate): after a pass, each fitted point
 * moves to the weighted mean of its projections (along each surface's
 * normal) onto the surfaces fitted at its neighbours and at itself, with
 * weights exp(-d^2 / 2 (AGG_SIGMA h)^2), d its distance from that fit's
 * origin; its normal becomes the same weighted mean of the fits' normals
 * (each at its own origin: a normal extrapolated by the fitted curvature
 * is noisier, measured on a small noisy sphere). In its own fit a point's
 * own noise has the largest leverage (docs/smooth.md, "Limits"); its
 * neighbours' fits weigh it less, so the mean keeps less of it, as
 * patch-based image denoisers average their overlapping patch estimates.
 * The point reads the pass's fit origins and surfaces and writes only its
 * own position and normal: in place, for any order of points. 1.5 h
 * measured best of 1.5, 2 and 3 h on the noisy scans. */
#define AGG_SIGMA 1.5

TSL_CLONES static void aggregate_range(const pass_ctx *x, fit_buf *b, size_t s0, size_t s1)
{
    const fit_ctl *f = x->f;
    const float inv_2s2 = (float)(1.0 / (2.0 * AGG_SIGMA * AGG_SIGMA * f->h * f->h));
    /* Scratch from the fit buffer: per surface the exponent of its weight,
     * the point's move onto it and its normal; then the weights, the
     * weighted normals and the sums, over FIT_LANES lanes in a fixed
     * order. */
    float *e = b->ew, *w = b->om, *y[3] = {b->x, b->y, b->z}, *nm[3] = {b->t[0], b->t[1], b->t[2]};
    for (size_t s = s0; s < s1; s++) {
        if (isnan(x->surf[s].t))
            continue; /* unfit points stay */
        float *p = x->out_xyz + 3 * s, *pn = x->out_nrm + 3 * s;
        const uint32_t *nb = x->nb + s * f->k;
        size_t m = 0;
        for (size_t i = 0; i < x->cnt[s]; i++) {
            const fit_surface *sf = x->surf + nb[i];
            if (isnan(sf->t))
                continue;
            const float *o = x->cur_xyz + 3 * (size_t)nb[i];
            float d[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
            float ex = -(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * inv_2s2;
            e[m] = ex > EXP_MIN ? ex : EXP_MIN;
            float u = sf->e1[0] * d[0] + sf->e1[1] * d[1] + sf->e1[2] * d[2];
            float v = sf->e2[0] * d[0] + sf->e2[1] * d[1] + sf->e2[2] * d[2];
            float z = sf->n[0] * d[0] + sf->n[1] * d[1] + sf->n[2] * d[2];
            const float *c = sf->c;
            float lift = sf->t + c[0] * u * u + c[1] * u * v + c[2] * v * v + c[3] * u +
                         c[4] * v + c[5] - z;
            for (int a = 0; a < 3; a++) {
                y[a][m] = lift * sf->n[a]; /* the move onto this surface */
                nm[a][m] = sf->normal[a];
            }
            m++;
        }
        if (m == 0)
            continue;
        size_t mp = (m + FIT_LANES - 1) / FIT_LANES * FIT_LANES;
        for (size_t j = m; j < mp; j++) {
            e[j] = EXP_MIN;
            for (int a = 0; a < 3; a++)
                y[a][j] = nm[a][j] = 0.0f;
        }
        for (size_t j = 0; j < mp; j++)
            w[j] = j < m ? fast_exp(e[j]) : 0.0f;
        /* Weighted normals, whose sign follows the point's (the surfaces
         * are unoriented). */
        for (size_t j = 0; j < mp; j++) {
            float gx = nm[0][j], gy = nm[1][j], gz = nm[2][j];
            float r = gx * pn[0] + gy * pn[1] + gz * pn[2] < 0.0f ? -w[j] : w[j];
            nm[0][j] = r * gx, nm[1][j] = r * gy, nm[2][j] = r * gz;
        }
        double W = lane_sum(w, mp), dy[3], nacc[3];
        for (int a = 0; a < 3; a++) {
            dy[a] = lane_dot(w, y[a], mp);
            nacc[a] = lane_sum(nm[a], mp);
        }
        double nl = sqrt(nacc[0] * nacc[0] + nacc[1] * nacc[1] + nacc[2] * nacc[2]);
        if (!(W > 0.0) || !(nl > 0.0))
            continue;
        for (int a = 0; a < 3; a++) {
            p[a] = (float)(p[a] + dy[a] / W);
            pn[a] = (float)(nacc[a] / nl);
        }
    }
}

/* The smoothed cloud res (positions and normals already in the grid's
 * order) takes the grid's order for the input's colours and organized
 * grid too; pos[i] is input point i's place. */
static void to_grid_order(tessel_cloud *res, const tessel_cloud *cloud, const tsl_grid *g,
                          const uint32_t *pos)
{
    size_t n = cloud->count;
    if (res->rgb)
        for (size_t s = 0; s < n; s++)
            memcpy(res->rgb + 3 * s, cloud->rgb + 3 * (size_t)g->perm[s], 3);
    if (res->grid) {
        size_t cells = (size_t)res->width * res->height;
        for (size_t c = 0; c < cells; c++)
            if (res->grid[c] != TESSEL_NONE)
                res->grid[c] = pos[res->grid[c]];
    }
}

tessel_status tessel_smooth(const tessel_cloud *cloud, tessel_cloud *out,
                            const tessel_smooth_params *params,
                            const tessel_callbacks *callbacks, tessel_smooth_stats *stats)
{
    double unused;
    return tsl_smooth_timed(cloud, out, params, callbacks, stats, false, &unused);
}

tessel_status tsl_smooth_timed(const tessel_cloud *cloud, tessel_cloud *out,
                               const tessel_smooth_params *params,
                               const tessel_callbacks *callbacks, tessel_smooth_stats *stats,
                               bool grid_order, double *seconds_spacing)
{
    *seconds_spacing = 0.0;
    if (!out)
        return TESSEL_ERR_INVALID_ARG;
    memset(out, 0, sizeof *out);
    if (stats)
        memset(stats, 0, sizeof *stats);
    tessel_smooth_params p = params ? *params : tessel_smooth_params_default();
    tessel_status st = check_params(&p);
    if (st == TESSEL_OK)
        st = check_cloud(cloud);
    if (st != TESSEL_OK)
        return st;

    const size_t n = cloud->count;
    int threads = tsl_threads(p.threads);
    (void)threads;
    /* The grid comes first: when h is not given, its cells find the
     * nearest neighbours that measure it (tessel_cloud_spacing's value,
     * without building a kd-tree). Cells a little wider than the distance
     * to the k-th neighbour, at most the cut-off 3 sigma_w h. */
    tsl_grid g;
    memset(&g, 0, sizeof g);
    double h = p.spacing, cell = tsl_grid_knn_cell(cloud->xyz, n, p.k);
    if (h > 0.0)
        cell = fmin(cell, 3.0 * p.sigma_w * h);
    st = tsl_grid_build(&g, cloud->xyz, n, cell, threads);
    if (st == TESSEL_OK && !(h > 0.0)) {
        double t0 = tsl_seconds();
        st = tsl_grid_spacing(&g, cloud->xyz, n, threads, &h);
        if (st == TESSEL_OK && !isfinite(h))
            st = TESSEL_ERR_TOO_FEW_POINTS; /* no scale to smooth at */
        if (st == TESSEL_OK && g.c > 3.0 * p.sigma_w * h) {
            tsl_grid_free(&g);
            st = tsl_grid_build(&g, cloud->xyz, n, 3.0 * p.sigma_w * h, threads);
        }
        *seconds_spacing = tsl_seconds() - t0;
    }
    if (st != TESSEL_OK) {
        tsl_grid_free(&g);
        return st;
    }
    fit_ctl f_first, f_later;
    ctl_setup(&f_first, &p, h, p.sigma_rho);
    ctl_setup(&f_later, &p, h, p.sigma_rho_later);
    f_later.ridge = 0.0; /* see QUAD_RIDGE */

    float *buf[4] = {NULL, NULL, NULL, NULL}; /* xyz a, xyz b, normals a, b */
    uint32_t *nb = NULL;
    uint16_t *cnt = NULL;
    float *ref0 = NULL;
    uint32_t *pos = NULL; /* with grid_order: each input point's place */
    fit_surface *surf = NULL;
    crowd cw;
    memset(&cw, 0, sizeof cw);
    tessel_cloud res;
    memset(&res, 0, sizeof res);
    for (int i = 0; i < 4; i++)
        if (!(buf[i] = tsl_alloc_array(n, 3 * sizeof(float))))
            st = TESSEL_ERR_NOMEM;
    /* The neighbour lists serve later passes and the aggregation only
     * (one pass, as the noisy pipeline runs, writes 120 bytes per point
     * less). */
    bool keep_nb = p.passes > 1 || p.aggregate;
    if (keep_nb) {
        nb = tsl_alloc_array(n, (size_t)p.k * sizeof *nb);
        cnt = tsl_alloc_array(n, sizeof *cnt);
    }
    if (p.aggregate)
        surf = tsl_alloc_array(n, sizeof *surf);
    if ((keep_nb && (!nb || !cnt)) || (p.aggregate && !surf))
        st = TESSEL_ERR_NOMEM;
    if (st != TESSEL_OK)
        goto done;

    pass_ctx x;
    memset(&x, 0, sizeof x);
    x.g = &g;
    x.nb = nb;
    x.cnt = cnt;
    x.surf = surf;
    x.crowd = &cw;
    if (cloud->has_viewpoint) {
        x.has_viewpoint = 1;
        for (int i = 0; i < 3; i++)
            x.viewpoint[i] = cloud->viewpoint[i] - cloud->offset[i];
    }
    pass_count total = {0, 0, 0};
    cw.xyz = cloud->xyz;
    cw.g = &g;
    if (cloud->normals) {
        if (!(ref0 = tsl_alloc_array(n, 3 * sizeof(float)))) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        for (size_t s = 0; s < n; s++)
            memcpy(ref0 + 3 * s, cloud->normals + 3 * (size_t)g.perm[s], 3 * sizeof(float));
    }

    /* Pass 1: neighbour search on the input and the paper's operator (the
     * projector's bits). Later passes: the same neighbours, moved. */
    for (uint32_t pass = 0; pass < p.passes; pass++) {
        int a = pass & 1;
        x.f = pass == 0 ? &f_first : &f_later;
        x.cur_xyz = pass == 0 ? g.sxyz : buf[1 - a];
        x.ref_nrm = pass == 0 ? ref0 : buf[3 - a];
        x.out_xyz = buf[a];
        x.out_nrm = buf[2 + a];
        size_t c0 = 0, s0 = 0;
        for (;;) {
            size_t c1 = c0, s1 = s0;
            if (pass == 0) {
                if (c0 >= g.ncell)
                    break;
                c1 = c0 + 1;
                while (c1 < g.ncell && g.start[c1] - g.start[c0] < SMOOTH_CHUNK)
                    c1++;
                s0 = g.start[c0];
            } else {
                if (s0 >= n)
                    break;
                s1 = s0 + SMOOTH_CHUNK < n ? s0 + SMOOTH_CHUNK : n;
            }
            st = tsl_progress(callbacks, "smooth",
                              ((double)pass + (double)s0 / (double)n) / p.passes);
            if (st != TESSEL_OK)
                goto done;
            size_t c_unfit = 0, c_unconv = 0;
            uint64_t c_iter = 0;
            /* Integer reductions only: the sums do not depend on the order. */
#ifdef _OPENMP
#pragma omp parallel num_threads(threads) reduction(+ : c_unfit, c_unconv, c_iter)
#endif
            {
                block b; /* per-thread scratch, ~20 KB */
                fit_buf fb;
                pass_count pc = {0, 0, 0};
                b.m = 0;
                if (pass == 0) {
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 16)
#endif
                    for (size_t ci = c0; ci < c1; ci++)
                        search_cell(&x, &b, &fb, ci, &pc);
                } else {
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
                    for (size_t s = s0; s < s1; s += 256)
                        refit_range(&x, &fb, s, s + 256 < s1 ? s + 256 : s1, &pc);
                }
                c_unfit += pc.unfit;
                c_unconv += pc.unconverged;
                c_iter += pc.iterations;
            }
            if (cw.st != TESSEL_OK) {
                st = cw.st;
                goto done;
            }
            total.unfit += c_unfit;
            total.unconverged += c_unconv;
            total.iterations += c_iter;
            c0 = c1;
            s0 = pass == 0 ? s0 : s1;
        }
        if (surf) {
#ifdef _OPENMP
#pragma omp parallel num_threads(threads)
#endif
            {
                fit_buf fb;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
                for (size_t s = 0; s < n; s += 4096)
                    aggregate_range(&x, &fb, s, s + 4096 < n ? s + 4096 : n);
            }
        }
    }
    st = tsl_progress(callbacks, "smooth", 1.0);
    if (st != TESSEL_OK)
        goto done;

    /* Back to the input's order, or the colours and the organized grid to
     * the grid's. The input's positions and normals are not copied: the
     * result's are the last pass's, taken as they are or permuted. */
    {
        tessel_cloud rest = *cloud;
        rest.xyz = rest.normals = NULL;
        st = tessel_cloud_copy(&res, &rest);
    }
    if (st != TESSEL_OK)
        goto done;
    int last = (int)((p.passes - 1) & 1);
    if (grid_order) {
        /* The last pass's buffers are the result as they are. */
        res.xyz = buf[last];
        res.normals = buf[2 + last];
        buf[last] = buf[2 + last] = NULL;
    } else {
        res.xyz = tsl_alloc_array(n, 3 * sizeof(float));
        res.normals = tsl_alloc_array(n, 3 * sizeof(float));
        if (!res.xyz || !res.normals) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        /* perm is a permutation: every thread writes its own slots. */
#ifdef _OPENMP
#pragma omp parallel for num_threads(threads) schedule(static)
#endif
        for (size_t s = 0; s < n; s++) {
            size_t i = g.perm[s];
            memcpy(res.xyz + 3 * i, buf[last] + 3 * s, 3 * sizeof(float));
            memcpy(res.normals + 3 * i, buf[2 + last] + 3 * s, 3 * sizeof(float));
        }
    }
    if (grid_order) {
        if (!(pos = tsl_alloc_array(n, sizeof *pos))) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        for (size_t s = 0; s < n; s++)
            pos[g.perm[s]] = (uint32_t)s;
        to_grid_order(&res, cloud, &g, pos);
    }

    if (stats) {
        /* Serial, so the floating-point sums do not depend on threads. */
        double sum2 = 0.0, mx = 0.0;
        for (size_t i = 0; i < n; i++) {
            double u[3], v[3], e[3];
            tsl_load(cloud->xyz + 3 * i, u);
            tsl_load(res.xyz + 3 * (pos ? (size_t)pos[i] : i), v);
            tsl_sub(u, v, e);
            double d2 = tsl_dot(e, e);
            sum2 += d2;
            mx = d2 > mx ? d2 : mx;
        }
        size_t fitted = (size_t)p.passes * n - total.unfit;
        stats->spacing = h;
        stats->unfit = total.unfit;
        stats->unconverged = total.unconverged;
        stats->mean_iterations = fitted ? (double)total.iterations / (double)fitted : 0.0;
        stats->rms_displacement = sqrt(sum2 / (double)n);
        stats->max_displacement = sqrt(mx);
    }
    *out = res;
    memset(&res, 0, sizeof res);

done:
    tsl_grid_free(&g);
    tessel_index_destroy(cw.index);
    free(cw.pos_of);
    for (int i = 0; i < 4; i++)
        free(buf[i]);
    free(nb);
    free(cnt);
    free(ref0);
    free(pos);
    free(surf);
    tessel_cloud_free(&res);
    if (st != TESSEL_OK && stats)
        memset(stats, 0, sizeof *stats);
    return st;
}
