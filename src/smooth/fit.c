/* The robust projection operator Q of Mederos, Velho & de Figueiredo
 * 2003, section 2.1 (smooth.c describes the method): for a query point,
 * iteratively reweighted least squares over its neighbours fit a plane
 * (and, beyond the paper, a quadric over it) with Gaussian distance
 * weights and robust height weights, and the point moves onto the fit.
 * The kernels run over FIT_LANES partial sums, so the result is the same
 * bits on every run and machine. Also the projector: Q over a fixed cloud
 * (tessel_project). */
#include "smooth/smooth.h"

#include <stdlib.h>
#include <string.h>

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

void tsl_smooth_ctl_setup(fit_ctl *f, const tessel_smooth_params *p, double h, double sigma_rho)
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
bool tsl_smooth_solve_one(const fit_ctl *f, const float q[3], fit_buf *b, const float *start,
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

tessel_status tsl_smooth_check_cloud(const tessel_cloud *cloud)
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
    tessel_status st = tsl_smooth_check_params(&p);
    if (st == TESSEL_OK)
        st = tsl_smooth_check_cloud(cloud);
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
    tsl_smooth_ctl_setup(&pr->ctl, &p, h, p.sigma_rho);
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
        tsl_smooth_solve_one(f, q, &b, NULL, nn, pr->has_viewpoint, pr->viewpoint, out, normal, &its, NULL);
    if (iterations)
        *iterations = its;
    return fit ? TESSEL_OK : TESSEL_ERR_TOO_FEW_POINTS;
}
