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
 * Neighbours: the k nearest points within 3 sigma_w (beyond it w < 1.1%).
 * Arbitrary points (tessel_project) find them with the kd-tree. A smoothing
 * pass, where the queries are the cloud itself, sorts the points into a
 * grid of cells a little wider than the distance to the k-th neighbour and
 * serves all points of a cell from the same 27 cells (more rings of cells
 * for the rare point whose neighbours reach farther): the same neighbours
 * as the kd-tree, at a fraction of the cost. Every output position depends
 * only on the previous pass's positions, so points are independent: an
 * OpenMP loop over cells with per-point output slots gives the same bits
 * for any thread count. */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
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
    uint32_t k, max_iterations, min_neighbors;
} fit_ctl;

struct tessel_projector {
    tessel_index *index;
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
    p.k = 24;
    p.sigma_rho = 2.0;
    p.sigma_w = 2.5;
    p.passes = 2;
    p.max_iterations = 20;
    p.tolerance = 1e-3;
    p.min_neighbors = 6;
    p.spacing = 0.0;
    p.threads = 0;
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
    return TESSEL_OK;
}

static void ctl_setup(fit_ctl *f, const tessel_smooth_params *p, double h)
{
    double sw = p->sigma_w * h, sr = p->sigma_rho * h;
    f->h = h;
    f->inv_2sw2 = 1.0 / (2.0 * sw * sw);
    f->inv_2sr2 = 1.0 / (2.0 * sr * sr);
    f->rmax = 3.0 * sw;
    f->tol_t = p->tolerance * h;
    f->tol_n = p->tolerance;
    f->k = p->k;
    f->max_iterations = p->max_iterations;
    f->min_neighbors = p->min_neighbors;
}

/* ---- plane fitting ---- */

/* Unit eigenvector of the smallest eigenvalue of the symmetric matrix
 * m = {a00, a01, a02, a11, a12, a22}. Returns false when no plane is
 * defined: the two largest eigenvalues are not both positive (all points on
 * a line or at one spot). Closed-form eigenvalues (trigonometric solution
 * of the characteristic cubic) and the eigenvector as the longest cross
 * product of two rows of m - l1 I. When l1 is close to l2 that vector is
 * inaccurate (and the closed form's l1, l2 are only good to ~1e-8 l3 when
 * they are nearly equal), so Jacobi rotations decide instead. */
static bool smallest_eigenvector(const double m[6], double n[3])
{
    double a00 = m[0], a01 = m[1], a02 = m[2], a11 = m[3], a12 = m[4], a22 = m[5];
    double q = (a00 + a11 + a22) / 3.0;
    double b00 = a00 - q, b11 = a11 - q, b22 = a22 - q;
    double p1 = a01 * a01 + a02 * a02 + a12 * a12;
    double p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1;
    if (!(p2 > 0.0))
        return false; /* a multiple of the identity: a point or nothing */
    double p = sqrt(p2 / 6.0);
    double det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) +
                 a02 * (a01 * a12 - b11 * a02);
    double r = det / (2.0 * p * p * p);
    r = r < -1.0 ? -1.0 : (r > 1.0 ? 1.0 : r);
    double phi = acos(r) / 3.0;
    double l3 = q + 2.0 * p * cos(phi);
    double l1 = q + 2.0 * p * cos(phi + 2.0943951023931957);
    double l2 = 3.0 * q - l1 - l3;
    if (!(l3 > 0.0) || !(l2 > 1e-12 * l3))
        return false;
    if (l2 - l1 < 1e-4 * l3) {
        double a[9] = {a00, a01, a02, a01, a11, a12, a02, a12, a22}, w[3], v[9];
        tsl_eigen_sym3(a, w, v);
        n[0] = v[0], n[1] = v[3], n[2] = v[6];
        return w[2] > 0.0 && w[1] > 1e-12 * w[2];
    }
    double r0[3] = {a00 - l1, a01, a02}, r1[3] = {a01, a11 - l1, a12};
    double r2[3] = {a02, a12, a22 - l1}, c[3][3];
    tsl_cross(r0, r1, c[0]);
    tsl_cross(r0, r2, c[1]);
    tsl_cross(r1, r2, c[2]);
    int best = 0;
    double bl = tsl_dot(c[0], c[0]);
    for (int i = 1; i < 3; i++) {
        double l = tsl_dot(c[i], c[i]);
        if (l > bl)
            bl = l, best = i;
    }
    double inv = 1.0 / sqrt(bl);
    n[0] = c[best][0] * inv, n[1] = c[best][1] * inv, n[2] = c[best][2] * inv;
    return true;
}

/* Plane of the weighted points from their moments: W = sum om,
 * s = sum om d, mm = sum om d d^T (upper triangle). Writes the centroid c
 * and the unit normal n. Moments about the query point, which lies within
 * the neighbourhood, lose nothing to cancellation at these scales. */
static bool plane_from_moments(double W, const double s[3], const double mm[6], double c[3],
                               double n[3])
{
    if (!(W > 1e-300))
        return false;
    c[0] = s[0] / W, c[1] = s[1] / W, c[2] = s[2] / W;
    double cov[6] = {mm[0] / W - c[0] * c[0], mm[1] / W - c[0] * c[1], mm[2] / W - c[0] * c[2],
                     mm[3] / W - c[1] * c[1], mm[4] / W - c[1] * c[2], mm[5] / W - c[2] * c[2]};
    return smallest_eigenvector(cov, n);
}

static inline void moments_add(double o, const double d[3], double *W, double s[3],
                               double mm[6])
{
    *W += o;
    double ox = o * d[0], oy = o * d[1], oz = o * d[2];
    s[0] += ox, s[1] += oy, s[2] += oz;
    mm[0] += ox * d[0], mm[1] += ox * d[1], mm[2] += ox * d[2];
    mm[3] += oy * d[1], mm[4] += oy * d[2], mm[5] += oz * d[2];
}

/* exp(-x) for x >= 0, in single precision: weights need no more, and
 * expf is about twice as fast as exp. */
static inline double weight(double x)
{
    return (double)expf((float)-x);
}

/* The robust fit for one query from its neighbours d[j] (positions minus
 * the query, sorted by distance). On success writes the unit normal n and
 * the offset t (Q = q + t n) and the IRLS iterations; w is scratch of m
 * doubles. Returns false when there is no fit (too few neighbours, or all
 * of them on a line). */
static bool robust_fit(const fit_ctl *f, const double (*d)[3], size_t m, double *w, double n[3],
                       double *t_out, uint32_t *iterations)
{
    if (m < f->min_neighbors)
        return false;
    double W = 0.0, s[3] = {0, 0, 0}, mm[6] = {0, 0, 0, 0, 0, 0}, c[3];
    for (size_t j = 0; j < m; j++) {
        w[j] = weight(tsl_dot(d[j], d[j]) * f->inv_2sw2);
        moments_add(w[j], d[j], &W, s, mm);
    }
    if (!plane_from_moments(W, s, mm, c, n))
        return false;
    double t = tsl_dot(n, c);

    /* IRLS: reweight by the robust norm's influence exp(-h^2 / 2 sr^2) and
     * refit. A step whose weights collapse keeps the previous plane. */
    uint32_t it = 0;
    while (it < f->max_iterations) {
        it++;
        W = 0.0;
        memset(s, 0, sizeof s);
        memset(mm, 0, sizeof mm);
        for (size_t j = 0; j < m; j++) {
            double hq = tsl_dot(n, d[j]) - t;
            moments_add(w[j] * weight(hq * hq * f->inv_2sr2), d[j], &W, s, mm);
        }
        double n2[3];
        if (!plane_from_moments(W, s, mm, c, n2))
            break;
        if (tsl_dot(n2, n) < 0.0)
            n2[0] = -n2[0], n2[1] = -n2[1], n2[2] = -n2[2];
        double t2 = tsl_dot(n2, c), x[3];
        tsl_cross(n, n2, x);
        bool done = fabs(t2 - t) <= f->tol_t && tsl_dot(x, x) <= f->tol_n * f->tol_n;
        n[0] = n2[0], n[1] = n2[1], n[2] = n2[2];
        t = t2;
        if (done)
            break;
    }
    *t_out = t;
    *iterations = it;
    return true;
}

/* The normal of an unfit point: smallest-eigenvalue direction of the plain
 * covariance of its neighbours (Jacobi yields a unit vector even for
 * coincident points, where the direction is arbitrary). */
static void plain_normal(const double (*d)[3], size_t m, double n[3])
{
    double W = 0.0, s[3] = {0, 0, 0}, mm[6] = {0, 0, 0, 0, 0, 0}, c[3] = {0, 0, 0};
    for (size_t j = 0; j < m; j++)
        moments_add(1.0, d[j], &W, s, mm);
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

/* Sign convention (returns true when it flipped n): agree with the nearest
 * cloud point's normal when the cloud has normals, else face the viewpoint
 * when there is one. */
static bool orient(const float *normals, const float *nearest_normal, int has_viewpoint,
                   const double viewpoint[3], const float q[3], double n[3])
{
    double ref[3];
    if (normals) {
        tsl_load(nearest_normal, ref);
    } else if (has_viewpoint) {
        ref[0] = viewpoint[0] - q[0];
        ref[1] = viewpoint[1] - q[1];
        ref[2] = viewpoint[2] - q[2];
    } else {
        return false;
    }
    if (tsl_dot(n, ref) < 0.0) {
        n[0] = -n[0], n[1] = -n[1], n[2] = -n[2];
        return true;
    }
    return false;
}

/* Fit, orient and write one result. d holds the all_m neighbours found
 * (sorted by distance), of which the first m are within the cut-off.
 * Returns true when fitted. */
static bool solve_one(const fit_ctl *f, const float q[3], const double (*d)[3], size_t m,
                      size_t all_m, const float *normals, const float *nearest_normal,
                      int has_viewpoint, const double viewpoint[3], double *scratch,
                      float out[3], float normal[3], uint32_t *iterations)
{
    double n[3], t = 0.0;
    uint32_t its = 0;
    bool fit = robust_fit(f, d, m, scratch, n, &t, &its);
    if (!fit)
        plain_normal(d, all_m, n);
    if (orient(normals, nearest_normal, has_viewpoint, viewpoint, q, n))
        t = -t; /* t is the offset along n */
    if (fit) {
        out[0] = (float)(q[0] + t * n[0]);
        out[1] = (float)(q[1] + t * n[1]);
        out[2] = (float)(q[2] + t * n[2]);
    } else {
        out[0] = q[0], out[1] = q[1], out[2] = q[2];
    }
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

tessel_status tessel_projector_create(tessel_projector **projector, const tessel_cloud *cloud,
                                      const tessel_smooth_params *params)
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
    st = tessel_index_build(&pr->index, cloud->xyz, cloud->count);
    if (st != TESSEL_OK) {
        free(pr);
        return st;
    }
    pr->xyz = cloud->xyz;
    pr->normals = cloud->normals;
    pr->count = cloud->count;
    if (cloud->has_viewpoint) {
        pr->has_viewpoint = 1;
        for (int i = 0; i < 3; i++)
            pr->viewpoint[i] = cloud->viewpoint[i] - cloud->offset[i];
    }
    ctl_setup(&pr->ctl, &p, h);
    *projector = pr;
    return TESSEL_OK;
}

void tessel_projector_destroy(tessel_projector *projector)
{
    if (!projector)
        return;
    tessel_index_destroy(projector->index);
    free(projector);
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
    double d[SMOOTH_MAX_K][3], scratch[SMOOTH_MAX_K];

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
        d[j][0] = (double)x[0] - q[0];
        d[j][1] = (double)x[1] - q[1];
        d[j][2] = (double)x[2] - q[2];
        m += d2[j] <= r2;
    }
    const float *nn = pr->normals ? pr->normals + 3 * (size_t)idx[0] : NULL;
    uint32_t its;
    bool fit = solve_one(f, q, (const double(*)[3])d, m, all_m, pr->normals, nn,
                         pr->has_viewpoint, pr->viewpoint, scratch, out, normal, &its);
    if (iterations)
        *iterations = its;
    return fit ? TESSEL_OK : TESSEL_ERR_TOO_FEW_POINTS;
}

/* ---- the grid of a smoothing pass ---- */

/* Points sorted by cell (Morton order of the cell coordinates, so nearby
 * cells are near in memory), each cell a run. */
typedef struct cell_grid {
    double origin[3];
    double c; /* cell size */
    uint32_t dims[3];
    size_t n, ncell;
    uint32_t *perm;  /* sorted position -> point index */
    float *sxyz;     /* n*3 coordinates in sorted order */
    uint64_t *key;   /* ncell cell keys, increasing */
    uint32_t *start; /* ncell + 1 run starts */
    uint32_t *slot;  /* open-addressing hash: key -> cell, or
                        UINT32_MAX; hmask + 1 slots */
    size_t hmask;
} cell_grid;

static void grid_free(cell_grid *g)
{
    free(g->perm);
    free(g->sxyz);
    free(g->key);
    free(g->start);
    free(g->slot);
    memset(g, 0, sizeof *g);
}

static uint64_t spread21(uint32_t v)
{
    uint64_t x = v & 0x1fffffu;
    x = (x | x << 32) & 0x1f00000000ffffull;
    x = (x | x << 16) & 0x1f0000ff0000ffull;
    x = (x | x << 8) & 0x100f00f00f00f00full;
    x = (x | x << 4) & 0x10c30c30c30c30c3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
}
static inline uint64_t morton(uint32_t x, uint32_t y, uint32_t z)
{
    return spread21(x) | spread21(y) << 1 | spread21(z) << 2;
}

static inline uint32_t cell_of(const cell_grid *g, const float *p, int axis)
{
    double v = floor((p[axis] - g->origin[axis]) / g->c);
    if (v < 0.0)
        v = 0.0;
    if (v > (double)(g->dims[axis] - 1))
        v = (double)(g->dims[axis] - 1);
    return (uint32_t)v;
}

static inline size_t hash_key(uint64_t key)
{
    return (size_t)((key * 0x9E3779B97F4A7C15ull) >> 32);
}

/* Sorts the points by cell with a stable LSD radix sort on the Morton key
 * (only the bytes in use), so equal cells keep increasing point order. */
static tessel_status grid_build(cell_grid *g, const float *xyz, size_t n, double cell)
{
    memset(g, 0, sizeof *g);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            double v = xyz[3 * i + a];
            lo[a] = v < lo[a] ? v : lo[a];
            hi[a] = v > hi[a] ? v : hi[a];
        }
    /* 21 bits per axis; a coarser grid is still exact, only slower. */
    double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    if (ext / cell > 2000000.0)
        cell = ext / 2000000.0;
    g->c = cell;
    uint32_t maxdim = 1;
    for (int a = 0; a < 3; a++) {
        g->origin[a] = lo[a];
        g->dims[a] = (uint32_t)floor((hi[a] - lo[a]) / cell) + 1;
        maxdim = g->dims[a] > maxdim ? g->dims[a] : maxdim;
    }
    int bits = 1;
    while (bits < 21 && (1u << bits) < maxdim)
        bits++;
    int passes = (3 * bits + 7) / 8;
    g->n = n;

    uint64_t *k0 = tsl_alloc_array(n, sizeof *k0), *k1 = tsl_alloc_array(n, sizeof *k1);
    uint32_t *i0 = tsl_alloc_array(n, sizeof *i0), *i1 = tsl_alloc_array(n, sizeof *i1);
    g->sxyz = tsl_alloc_array(n, 3 * sizeof(float));
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!k0 || !k1 || !i0 || !i1 || !g->sxyz)
        goto done;
    for (size_t i = 0; i < n; i++) {
        const float *p = xyz + 3 * i;
        k0[i] = morton(cell_of(g, p, 0), cell_of(g, p, 1), cell_of(g, p, 2));
        i0[i] = (uint32_t)i;
    }
    for (int pass = 0; pass < passes; pass++) {
        size_t count[257] = {0};
        int sh = 8 * pass;
        for (size_t i = 0; i < n; i++)
            count[((k0[i] >> sh) & 0xff) + 1]++;
        for (int b = 0; b < 256; b++)
            count[b + 1] += count[b];
        for (size_t i = 0; i < n; i++) {
            size_t dst = count[(k0[i] >> sh) & 0xff]++;
            k1[dst] = k0[i];
            i1[dst] = i0[i];
        }
        uint64_t *tk = k0;
        k0 = k1, k1 = tk;
        uint32_t *ti = i0;
        i0 = i1, i1 = ti;
    }
    size_t ncell = 0;
    for (size_t i = 0; i < n; i++)
        ncell += i == 0 || k0[i] != k0[i - 1];
    g->key = tsl_alloc_array(ncell, sizeof *g->key);
    g->start = tsl_alloc_array(ncell + 1, sizeof *g->start);
    if (!g->key || !g->start)
        goto done;
    size_t c = 0;
    for (size_t i = 0; i < n; i++) {
        if (i == 0 || k0[i] != k0[i - 1]) {
            g->key[c] = k0[i];
            g->start[c++] = (uint32_t)i;
        }
        memcpy(g->sxyz + 3 * i, xyz + 3 * (size_t)i0[i], 3 * sizeof(float));
    }
    g->start[ncell] = (uint32_t)n;
    g->ncell = ncell;
    /* Cell lookups by hashing: a quarter full at most. */
    size_t slots = 64;
    while (slots < 4 * ncell)
        slots *= 2;
    g->slot = tsl_alloc_array(slots, sizeof *g->slot);
    if (!g->slot)
        goto done;
    memset(g->slot, 0xff, slots * sizeof *g->slot);
    g->hmask = slots - 1;
    for (size_t i = 0; i < ncell; i++) {
        size_t h = hash_key(g->key[i]) & g->hmask;
        while (g->slot[h] != UINT32_MAX)
            h = (h + 1) & g->hmask;
        g->slot[h] = (uint32_t)i;
    }
    g->perm = i0;
    i0 = NULL;
    st = TESSEL_OK;
done:
    free(k0);
    free(k1);
    free(i0);
    free(i1);
    if (st != TESSEL_OK)
        grid_free(g);
    return st;
}

/* Index of the cell with this key, or SIZE_MAX when it is empty. */
static size_t grid_find(const cell_grid *g, uint64_t key)
{
    for (size_t h = hash_key(key) & g->hmask;; h = (h + 1) & g->hmask) {
        uint32_t c = g->slot[h];
        if (c == UINT32_MAX)
            return SIZE_MAX;
        if (g->key[c] == key)
            return c;
    }
}

/* Runs of the cells at Chebyshev distance `ring` (0 or 1) from cell cc,
 * appended to run[] (pairs of sorted positions). */
static size_t grid_ring(const cell_grid *g, const uint32_t cc[3], int ring, uint32_t *run,
                        size_t nrun)
{
    for (int dx = -ring; dx <= ring; dx++)
        for (int dy = -ring; dy <= ring; dy++)
            for (int dz = -ring; dz <= ring; dz++) {
                if (abs(dx) != ring && abs(dy) != ring && abs(dz) != ring)
                    continue;
                int64_t x = (int64_t)cc[0] + dx, y = (int64_t)cc[1] + dy,
                        z = (int64_t)cc[2] + dz;
                if (x < 0 || y < 0 || z < 0 || x >= g->dims[0] || y >= g->dims[1] ||
                    z >= g->dims[2])
                    continue;
                size_t ci = grid_find(g, morton((uint32_t)x, (uint32_t)y, (uint32_t)z));
                if (ci == SIZE_MAX)
                    continue;
                run[2 * nrun] = g->start[ci];
                run[2 * nrun + 1] = g->start[ci + 1];
                nrun++;
            }
    return nrun;
}

/* The k nearest within the cut-off, sorted by (distance, index) as the
 * kd-tree orders them. */
typedef struct topk {
    size_t cnt, k;
    float d[SMOOTH_MAX_K];
    uint32_t id[SMOOTH_MAX_K];  /* point index */
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
static void topk_scan(topk *t, const cell_grid *g, const float *q, const uint32_t *run,
                      size_t nrun, float r2max)
{
    for (size_t r = 0; r < nrun; r++)
        for (uint32_t s = run[2 * r]; s < run[2 * r + 1]; s++) {
            float d = dist2(g->sxyz + 3 * (size_t)s, q);
            if (d <= r2max)
                topk_add(t, d, g->perm[s], s);
        }
}

/* Squared distance from q to the box of cell (x, y, z), in float like the
 * point distances, rounded down a little so that it never exceeds the
 * float distance of a point inside. */
static inline float cell_box_d2(const cell_grid *g, const float *q, int64_t x, int64_t y,
                                int64_t z)
{
    int64_t c[3] = {x, y, z};
    double s = 0.0;
    for (int a = 0; a < 3; a++) {
        double lo = g->origin[a] + (double)c[a] * g->c, hi = lo + g->c, e = 0.0;
        if (q[a] < lo)
            e = lo - q[a];
        else if (q[a] > hi)
            e = q[a] - hi;
        s += e * e;
    }
    return (float)(s * (1.0 - 1e-5));
}

/* Offers to t every point of the cells at Chebyshev distance ring (>= 2)
 * from cell cc that can still hold one of the k nearest. */
static void topk_ring(topk *t, const cell_grid *g, const float *q, const uint32_t cc[3],
                      int64_t ring, float r2max)
{
    for (int64_t dx = -ring; dx <= ring; dx++) {
        int64_t x = (int64_t)cc[0] + dx;
        if (x < 0 || x >= g->dims[0])
            continue;
        for (int64_t dy = -ring; dy <= ring; dy++) {
            int64_t y = (int64_t)cc[1] + dy;
            if (y < 0 || y >= g->dims[1])
                continue;
            bool side = dx == -ring || dx == ring || dy == -ring || dy == ring;
            /* Off the sides only the two end cells of the z column. */
            for (int64_t dz = -ring; dz <= ring; dz += side ? 1 : 2 * ring) {
                int64_t z = (int64_t)cc[2] + dz;
                if (z < 0 || z >= g->dims[2])
                    continue;
                float worst = t->cnt == t->k ? t->d[t->cnt - 1] : r2max;
                if (cell_box_d2(g, q, x, y, z) > worst)
                    continue;
                size_t ci = grid_find(g, morton((uint32_t)x, (uint32_t)y, (uint32_t)z));
                if (ci == SIZE_MAX)
                    continue;
                uint32_t run[2] = {g->start[ci], g->start[ci + 1]};
                topk_scan(t, g, q, run, 1, r2max);
            }
        }
    }
}

/* The candidates of one cell (its 27-cell block) copied side by side, so
 * that the distances of a query to all of them vectorise. */
#define BLOCK_CAP 1024u
typedef struct block {
    size_t m;
    float x[BLOCK_CAP], y[BLOCK_CAP], z[BLOCK_CAP];
    uint32_t pos[BLOCK_CAP];
    uint64_t sel[BLOCK_CAP];
} block;

static inline uint32_t float_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

/* Point index of a selection key's block slot. */
static inline uint32_t block_id(const block *b, const cell_grid *g, uint64_t key)
{
    return g->perm[b->pos[(uint32_t)key]];
}

/* The k nearest of the block within r2max. A threshold that admits a
 * little more than k candidates (from the previous query's k-th distance,
 * *guess) picks a few; they are sorted as 64-bit keys (distance bits, which
 * order like the distances since they are >= 0, then block slot), equal
 * distances reordered by point index, and the first k kept. */
static void topk_block(topk *t, block *b, const cell_grid *g, const float *q, float r2max,
                       float *guess)
{
    const size_t m = b->m;
    const float qx = q[0], qy = q[1], qz = q[2];
    float thr = *guess < r2max ? *guess : r2max;
    size_t ns;
    for (;;) {
        ns = 0;
        /* Branch-free compaction: always store, advance when it passes. */
        for (size_t j = 0; j < m; j++) {
            float dx = b->x[j] - qx, dy = b->y[j] - qy, dz = b->z[j] - qz;
            float d = (dx * dx + dy * dy) + dz * dz;
            b->sel[ns] = (uint64_t)float_bits(d) << 32 | j;
            ns += d <= thr;
        }
        if (ns >= t->k || thr >= r2max)
            break;
        thr = thr * 2.0f < r2max ? thr * 2.0f : r2max;
    }
    for (size_t i = 1; i < ns; i++) {
        uint64_t v = b->sel[i];
        size_t j = i;
        while (j > 0 && b->sel[j - 1] > v) {
            b->sel[j] = b->sel[j - 1];
            j--;
        }
        b->sel[j] = v;
    }
    size_t keep = ns < t->k ? ns : t->k;
    if (keep > 0) {
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
        t->id[i] = g->perm[b->pos[j]];
        memcpy(&t->d[i], &bits, sizeof(float));
    }
    t->cnt = keep;
    /* Next query: a little above this k-th distance. */
    if (keep > 0)
        *guess = t->d[keep - 1] * 1.25f;
}

/* ---- smoothing passes ---- */

/* Points per progress report / cancellation check (at least). */
#define SMOOTH_CHUNK ((size_t)1 << 16)

typedef struct pass_ctx {
    const fit_ctl *f;
    const cell_grid *g;
    const float *normals; /* the current cloud's, by point index; or NULL */
    int has_viewpoint;
    double viewpoint[3];
    float *out_xyz, *out_nrm;
} pass_ctx;

/* Smooths the points of cell ci, with b as scratch. Adds to the
 * counters. */
static void smooth_cell(const pass_ctx *x, block *b, size_t ci, size_t *unfit, size_t *unconv,
                        uint64_t *iters)
{
    const cell_grid *g = x->g;
    const fit_ctl *f = x->f;
    uint32_t run1[2 * 27];
    size_t n1 = 0;
    topk t;
    double d[SMOOTH_MAX_K][3], scratch[SMOOTH_MAX_K];
    const float r2max = (float)(f->rmax * f->rmax);

    uint32_t cc[3];
    const float *first = g->sxyz + 3 * (size_t)g->start[ci];
    for (int a = 0; a < 3; a++)
        cc[a] = cell_of(g, first, a);
    n1 = grid_ring(g, cc, 0, run1, 0);
    n1 = grid_ring(g, cc, 1, run1, n1);
    size_t m = 0;
    for (size_t r = 0; r < n1; r++)
        m += run1[2 * r + 1] - run1[2 * r];
    /* A crowded block (very uneven density) is scanned run by run. */
    bool blocked = m <= BLOCK_CAP;
    if (blocked) {
        b->m = 0;
        for (size_t r = 0; r < n1; r++)
            for (uint32_t s = run1[2 * r]; s < run1[2 * r + 1]; s++) {
                const float *p = g->sxyz + 3 * (size_t)s;
                b->x[b->m] = p[0], b->y[b->m] = p[1], b->z[b->m] = p[2];
                b->pos[b->m++] = s;
            }
    }
    float guess = (float)(g->c * g->c);

    for (uint32_t s = g->start[ci]; s < g->start[ci + 1]; s++) {
        const float *q = g->sxyz + 3 * (size_t)s;
        t.cnt = 0;
        t.k = f->k;
        if (blocked)
            topk_block(&t, b, g, q, r2max, &guess);
        else
            topk_scan(&t, g, q, run1, n1, r2max);
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
            topk_ring(&t, g, q, cc, ring + 1, r2max);
        }
        for (size_t j = 0; j < t.cnt; j++) {
            const float *p = g->sxyz + 3 * (size_t)t.pos[j];
            d[j][0] = (double)p[0] - q[0];
            d[j][1] = (double)p[1] - q[1];
            d[j][2] = (double)p[2] - q[2];
        }
        uint32_t id = g->perm[s], its;
        const float *nn = x->normals ? x->normals + 3 * (size_t)t.id[0] : NULL;
        bool fit = solve_one(f, q, (const double(*)[3])d, t.cnt, t.cnt, x->normals, nn,
                             x->has_viewpoint, x->viewpoint, scratch,
                             x->out_xyz + 3 * (size_t)id, x->out_nrm + 3 * (size_t)id, &its);
        if (!fit) {
            (*unfit)++;
        } else {
            *iters += its;
            *unconv += its >= f->max_iterations;
        }
    }
}

tessel_status tessel_smooth(const tessel_cloud *cloud, tessel_cloud *out,
                            const tessel_smooth_params *params,
                            const tessel_callbacks *callbacks, tessel_smooth_stats *stats)
{
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
    double h;
    st = resolve_spacing(cloud, p.spacing, &h);
    if (st != TESSEL_OK)
        return st;
    fit_ctl f;
    ctl_setup(&f, &p, h);

    const size_t n = cloud->count;
    tessel_cloud cur;
    cell_grid g;
    memset(&g, 0, sizeof g);
    st = tessel_cloud_copy(&cur, cloud);
    if (st != TESSEL_OK)
        return st;
    float *next_xyz = tsl_alloc_array(n, 3 * sizeof(float));
    float *next_nrm = tsl_alloc_array(n, 3 * sizeof(float));
    if (!next_xyz || !next_nrm) {
        st = TESSEL_ERR_NOMEM;
        goto fail;
    }

    pass_ctx x;
    memset(&x, 0, sizeof x);
    x.f = &f;
    x.g = &g;
    if (cloud->has_viewpoint) {
        x.has_viewpoint = 1;
        for (int i = 0; i < 3; i++)
            x.viewpoint[i] = cloud->viewpoint[i] - cloud->offset[i];
    }
    int threads = tsl_threads(p.threads);
    (void)threads;
    size_t unfit = 0, unconverged = 0;
    uint64_t iter_sum = 0;
    /* Cells a little wider than the distance to the k-th neighbour, so
     * that the 27 cells around a point's own hold its neighbours for
     * nearly every point (wider cells cost more candidates, narrower ones
     * more outer rings: 1.3 times is the cheapest measured): a first grid
     * measures the points per occupied cell, m, which gives the surface
     * density (a surface crosses cells of side c with about 2/3 c^2 of its
     * area each), hence that distance. */
    double cell = fmin(3.0 * h * sqrt((double)p.k / 24.0), f.rmax);
    for (uint32_t pass = 0; pass < p.passes; pass++) {
        st = grid_build(&g, cur.xyz, n, cell);
        if (st == TESSEL_OK && pass == 0) {
            double m = (double)n / (double)g.ncell;
            double rk = g.c * sqrt((double)p.k * (2.0 / 3.0) / (3.141592653589793 * m));
            rk = fmin(1.3 * rk, f.rmax);
            if (fabs(rk - g.c) > 0.15 * g.c) {
                grid_free(&g);
                cell = rk;
                st = grid_build(&g, cur.xyz, n, cell);
            }
        }
        if (st != TESSEL_OK)
            goto fail;
        x.normals = cur.normals;
        x.out_xyz = next_xyz;
        x.out_nrm = next_nrm;
        size_t c0 = 0;
        while (c0 < g.ncell) {
            st = tsl_progress(callbacks, "smooth",
                              ((double)pass + (double)g.start[c0] / (double)n) / p.passes);
            if (st != TESSEL_OK)
                goto fail;
            size_t c1 = c0 + 1;
            while (c1 < g.ncell && g.start[c1] - g.start[c0] < SMOOTH_CHUNK)
                c1++;
            size_t c_unfit = 0, c_unconv = 0;
            uint64_t c_iter = 0;
            /* Integer reductions only: the sums do not depend on the order. */
#ifdef _OPENMP
#pragma omp parallel num_threads(threads) reduction(+ : c_unfit, c_unconv, c_iter)
#endif
            {
                block b; /* per-thread scratch, ~20 KB */
                b.m = 0;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 16)
#endif
                for (size_t ci = c0; ci < c1; ci++)
                    smooth_cell(&x, &b, ci, &c_unfit, &c_unconv, &c_iter);
            }
            unfit += c_unfit;
            unconverged += c_unconv;
            iter_sum += c_iter;
            c0 = c1;
        }
        grid_free(&g);
        /* The new positions become the cloud of the next pass. */
        float *tmp = cur.xyz;
        cur.xyz = next_xyz;
        next_xyz = tmp;
        tmp = cur.normals;
        cur.normals = next_nrm;
        next_nrm = tmp;
        if (!next_nrm && pass + 1 < p.passes) {
            next_nrm = tsl_alloc_array(n, 3 * sizeof(float));
            if (!next_nrm) {
                st = TESSEL_ERR_NOMEM;
                goto fail;
            }
        }
    }
    st = tsl_progress(callbacks, "smooth", 1.0);
    if (st != TESSEL_OK)
        goto fail;

    if (stats) {
        /* Serial, so the floating-point sums do not depend on threads. */
        double sum2 = 0.0, mx = 0.0;
        for (size_t i = 0; i < n; i++) {
            double a[3], b[3], e[3];
            tsl_load(cloud->xyz + 3 * i, a);
            tsl_load(cur.xyz + 3 * i, b);
            tsl_sub(a, b, e);
            double d2 = tsl_dot(e, e);
            sum2 += d2;
            mx = d2 > mx ? d2 : mx;
        }
        size_t fitted = (size_t)p.passes * n - unfit;
        stats->spacing = h;
        stats->unfit = unfit;
        stats->unconverged = unconverged;
        stats->mean_iterations = fitted ? (double)iter_sum / (double)fitted : 0.0;
        stats->rms_displacement = sqrt(sum2 / (double)n);
        stats->max_displacement = sqrt(mx);
    }
    free(next_xyz);
    free(next_nrm);
    *out = cur;
    return TESSEL_OK;

fail:
    grid_free(&g);
    free(next_xyz);
    free(next_nrm);
    tessel_cloud_free(&cur);
    if (stats)
        memset(stats, 0, sizeof *stats);
    return st;
}
