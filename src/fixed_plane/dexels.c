/* The dexel array of the height and range modes (Gopi & Krishnan 2002,
 * section 5): the frame (the plane of least variance or normal to an
 * axis; directions in (theta, phi) about a pole from the viewpoint), the
 * array's size from the density, the points bucketed into dexels, one
 * representative per dexel (among the points whose depth is in the middle
 * half of the dexel's, the one nearest its centre), and empty dexels next
 * to spare points filled (one-dexel sampling gaps). */
#include "fixed_plane/fixed_plane.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Dexels: bucketing and one representative per dexel                       */
/* ------------------------------------------------------------------------ */

/* A point in its dexel: depth, index, position in the dexel (0..65535
 * along each axis). */
typedef struct fp_pair {
    float depth;
    uint32_t index;
    uint16_t u, v;
} fp_pair;

static inline int fp_pair_less(fp_pair a, fp_pair b)
{
    return a.depth < b.depth || (a.depth == b.depth && a.index < b.index);
}

/* Puts the k-th smallest of a[0..n) (by depth, then index) at a[k]. */
static void fp_pair_select(fp_pair *a, size_t n, size_t k)
{
    size_t lo = 0, hi = n;
    while (hi - lo > 16) {
        size_t mid = lo + (hi - lo) / 2;
        /* median of three as pivot, moved to hi-1 */
        fp_pair *p0 = &a[lo], *p1 = &a[mid], *p2 = &a[hi - 1], t;
        if (fp_pair_less(*p1, *p0)) { t = *p0; *p0 = *p1; *p1 = t; }
        if (fp_pair_less(*p2, *p0)) { t = *p0; *p0 = *p2; *p2 = t; }
        if (fp_pair_less(*p2, *p1)) { t = *p1; *p1 = *p2; *p2 = t; }
        t = *p1; *p1 = a[hi - 1]; a[hi - 1] = t;
        fp_pair pivot = a[hi - 1];
        size_t s = lo;
        for (size_t i = lo; i + 1 < hi; i++) {
            if (fp_pair_less(a[i], pivot)) {
                t = a[i]; a[i] = a[s]; a[s] = t;
                s++;
            }
        }
        t = a[s]; a[s] = a[hi - 1]; a[hi - 1] = t;
        if (k == s)
            return;
        if (k < s)
            hi = s;
        else
            lo = s + 1;
    }
    for (size_t i = lo + 1; i < hi; i++) {
        fp_pair v = a[i];
        size_t j = i;
        while (j > lo && fp_pair_less(v, a[j - 1])) {
            a[j] = a[j - 1];
            j--;
        }
        a[j] = v;
    }
}

/* atan2 to ~1e-5 rad: the dexel of a point only needs a fixed, monotonic
 * rule, and libm's atan2 would be most of the bucketing time. */
static float fp_atan2(float y, float x)
{
    float ax = fabsf(x), ay = fabsf(y);
    float mx = ax > ay ? ax : ay, mn = ax > ay ? ay : ax;
    if (mx == 0.0f)
        return 0.0f;
    float z = mn / mx, z2 = z * z;
    float a = z * (0.99997726f +
                   z2 * (-0.33262347f +
                         z2 * (0.19354346f +
                               z2 * (-0.11643287f + z2 * (0.05265332f + z2 * -0.01172120f)))));
    if (ay > ax)
        a = 1.57079633f - a;
    if (x < 0.0f)
        a = 3.14159265f - a;
    return y < 0.0f ? -a : a;
}

static inline int fp_map(const fp_frame *f, const float *p, float *s, float *t, float *depth)
{
    if (f->kind == FP_PLANE) {
        double x = p[0], y = p[1], z = p[2];
        *s = (float)(f->e[0][0] * x + f->e[0][1] * y + f->e[0][2] * z);
        *t = (float)(f->e[1][0] * x + f->e[1][1] * y + f->e[1][2] * z);
        *depth = (float)(f->e[2][0] * x + f->e[2][1] * y + f->e[2][2] * z);
    } else {
        float dx = (float)(p[0] - f->vp[0]), dy = (float)(p[1] - f->vp[1]),
              dz = (float)(p[2] - f->vp[2]);
        float a = (float)f->e[0][0] * dx + (float)f->e[0][1] * dy + (float)f->e[0][2] * dz;
        float b = (float)f->e[1][0] * dx + (float)f->e[1][1] * dy + (float)f->e[1][2] * dz;
        float c = (float)f->e[2][0] * dx + (float)f->e[2][1] * dy + (float)f->e[2][2] * dz;
        float rho = sqrtf(a * a + b * b);
        float phi = fp_atan2(b, a) - (float)f->phi0;
        if (phi < 0.0f)
            phi += (float)(2.0 * FP_PI);
        if (phi >= (float)(2.0 * FP_PI))
            phi -= (float)(2.0 * FP_PI);
        float theta = fp_atan2(rho, c);
        *s = f->transpose ? theta : phi;
        *t = f->transpose ? phi : theta;
        *depth = sqrtf(rho * rho + c * c);
        if (!(*depth > 0.0f))
            return 0;
    }
    return isfinite(*s) && isfinite(*t) && isfinite(*depth);
}

/* Strided sample of at most FP_SAMPLE point indices. */
static size_t fp_sample_step(size_t n)
{
    return n > FP_SAMPLE ? (n + FP_SAMPLE - 1) / FP_SAMPLE : 1;
}

/* Height frame: the plane normal to an axis, or of least variance. */
void tsl_fp_height_frame(const tessel_cloud *cloud, int axis, fp_frame *f)
{
    memset(f, 0, sizeof *f);
    f->kind = FP_PLANE;
    if (axis >= 0 && axis <= 2) {
        int a = axis, b = (axis + 1) % 3, c = (axis + 2) % 3;
        f->e[0][b] = 1.0; /* x: (y, z); y: (z, x); z: (x, y) — right-handed */
        f->e[1][c] = 1.0;
        f->e[2][a] = 1.0;
        return;
    }
    size_t n = cloud->count, step = fp_sample_step(n), m = 0;
    double mean[3] = {0, 0, 0}, cov[9] = {0};
    for (size_t i = 0; i < n; i += step) {
        const float *p = cloud->xyz + 3 * i;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            continue;
        for (int k = 0; k < 3; k++)
            mean[k] += p[k];
        m++;
    }
    if (m == 0) {
        f->e[0][0] = f->e[1][1] = f->e[2][2] = 1.0;
        return;
    }
    for (int k = 0; k < 3; k++)
        mean[k] /= (double)m;
    for (size_t i = 0; i < n; i += step) {
        const float *p = cloud->xyz + 3 * i;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            continue;
        double d[3] = {p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                cov[3 * a + b] += d[a] * d[b];
    }
    double wv[3], v[9];
    tsl_eigen_sym3(cov, wv, v);
    double nrm[3] = {v[0], v[3], v[6]}, u[3] = {v[2], v[5], v[8]};
    /* "Up": non-negative z, else the largest component positive. */
    int big = 0;
    for (int k = 1; k < 3; k++)
        if (fabs(nrm[k]) > fabs(nrm[big]))
            big = k;
    if (nrm[2] < 0.0 || (nrm[2] == 0.0 && nrm[big] < 0.0))
        for (int k = 0; k < 3; k++)
            nrm[k] = -nrm[k];
    tsl_normalize(nrm);
    double un = tsl_dot(u, nrm);
    for (int k = 0; k < 3; k++)
        u[k] -= un * nrm[k];
    tsl_normalize(u);
    double vv[3];
    tsl_cross(nrm, u, vv); /* u x v = n */
    for (int k = 0; k < 3; k++) {
        f->e[0][k] = u[k];
        f->e[1][k] = vv[k];
        f->e[2][k] = nrm[k];
    }
}

/* Range frame. The pole is the axis (z, x or y) for which the sample's
 * points spread most evenly over equal-angle (theta, phi) cells: the
 * scanner's own axis for a terrestrial scan (its samples are equal-angle
 * about the vertical), an axis across the view for a camera (whose view
 * axis as pole would crowd the data into tiny dexels round it). Evenness
 * is the coefficient of variation of the counts of occupied cells; z wins
 * unless another axis is clearly more even. phi starts after the widest
 * empty sector, so a partial scan does not straddle the cut. */
void tsl_fp_range_frame(const tessel_cloud *cloud, const double vp[3], fp_frame *f,
                           double *gap)
{
    memset(f, 0, sizeof *f);
    f->kind = FP_RAY;
    memcpy(f->vp, vp, sizeof f->vp);
    size_t n = cloud->count, step = fp_sample_step(n);
    enum { NT = 32, NP = 64 };
    uint32_t *bins = calloc((size_t)NT * NP, sizeof(uint32_t));
    int pole = 2;
    if (bins) {
        double best_cv = INFINITY;
        const int order[3] = {2, 0, 1};
        for (int o = 0; o < 3; o++) {
            int k = order[o], ka = (k + 1) % 3, kb = (k + 2) % 3;
            memset(bins, 0, (size_t)NT * NP * sizeof(uint32_t));
            for (size_t i = 0; i < n; i += step) {
                const float *p = cloud->xyz + 3 * i;
                double d[3] = {p[0] - vp[0], p[1] - vp[1], p[2] - vp[2]};
                if (!tsl_normalize(d) || !isfinite(d[0] + d[1] + d[2]))
                    continue;
                double th = atan2(sqrt(d[ka] * d[ka] + d[kb] * d[kb]), d[k]);
                double ph = atan2(d[kb], d[ka]);
                int bt = (int)(th / FP_PI * NT), bp = (int)((ph + FP_PI) / (2 * FP_PI) * NP);
                bt = bt < 0 ? 0 : bt >= NT ? NT - 1 : bt;
                bp = bp < 0 ? 0 : bp >= NP ? NP - 1 : bp;
                bins[bt * NP + bp]++;
            }
            double sum = 0, sum2 = 0, occ = 0;
            for (int j = 0; j < NT * NP; j++) {
                if (!bins[j])
                    continue;
                occ++;
                sum += bins[j];
                sum2 += (double)bins[j] * bins[j];
            }
            if (occ == 0)
                break;
            double mean = sum / occ, var = sum2 / occ - mean * mean;
            double cv = sqrt(var > 0 ? var : 0) / mean;
            if (o == 0 || cv < 0.8 * best_cv) {
                best_cv = cv;
                pole = k;
            }
        }
        free(bins);
    }
    int a = (pole + 1) % 3, b = (pole + 2) % 3;
    f->e[0][a] = 1.0;
    f->e[1][b] = 1.0;
    f->e[2][pole] = 1.0;
    /* Widest empty sector of phi over the sample, on 1/8 degree bins. */
    enum { BINS = 2880 };
    uint8_t *hit = calloc(BINS, 1);
    *gap = 0.0;
    f->phi0 = -FP_PI;
    if (!hit)
        return;
    for (size_t i = 0; i < n; i += step) {
        const float *p = cloud->xyz + 3 * i;
        double x = (p[0] - vp[0]) * f->e[0][0] + (p[1] - vp[1]) * f->e[0][1] +
                   (p[2] - vp[2]) * f->e[0][2];
        double y = (p[0] - vp[0]) * f->e[1][0] + (p[1] - vp[1]) * f->e[1][1] +
                   (p[2] - vp[2]) * f->e[1][2];
        if (!isfinite(x) || !isfinite(y) || (x == 0.0 && y == 0.0))
            continue;
        double phi = atan2(y, x);
        int k = (int)floor((phi + FP_PI) / (2.0 * FP_PI) * BINS);
        hit[k < 0 ? 0 : k >= BINS ? BINS - 1 : k] = 1;
    }
    int first = -1;
    for (int k = 0; k < BINS; k++)
        if (hit[k]) {
            first = k;
            break;
        }
    if (first >= 0) {
        int best = 0, best_end = first, run = 0;
        for (int j = 1; j <= BINS; j++) {
            int k = (first + j) % BINS;
            if (hit[k]) {
                if (run > best) {
                    best = run;
                    best_end = k;
                }
                run = 0;
            } else {
                run++;
            }
        }
        *gap = best * (2.0 * FP_PI / BINS);
        /* half a bin into the gap: the fast atan2 of fp_map() may differ
         * from this one by 1e-5 and must not wrap a point round */
        f->phi0 = -FP_PI + (best_end - 0.5) * (2.0 * FP_PI / BINS);
    }
    free(hit);
}

/* Range: which way the input runs. A scanner delivers its points profile
 * by profile; when consecutive points mostly step in theta, the array is
 * stored with theta along its rows (s = theta, t = phi), so that bucketing
 * writes and reads memory nearly in order instead of jumping a whole row per
 * point (2-3x faster at 10^8 points). The dexels are the same either way;
 * only rules that go in raster order (filling, fan fixes) may pick
 * differently among ties. */
void tsl_fp_scan_order(const tessel_cloud *cloud, fp_frame *f)
{
    size_t n = cloud->count, step = fp_sample_step(n), theta_fast = 0, phi_fast = 0;
    f->transpose = 0;
    for (size_t i = 0; i + 1 < n; i += step) {
        float s0, t0, d0, s1, t1, d1;
        if (!fp_map(f, cloud->xyz + 3 * i, &s0, &t0, &d0) ||
            !fp_map(f, cloud->xyz + 3 * (i + 1), &s1, &t1, &d1))
            continue;
        float dphi = fabsf(s0 - s1), dtheta = fabsf(t0 - t1);
        dphi = dphi > (float)FP_PI ? (float)(2.0 * FP_PI) - dphi : dphi;
        theta_fast += dtheta > dphi;
        phi_fast += dphi > dtheta;
    }
    f->transpose = theta_fast > phi_fast;
}

/* The dexel of a mapped point (s, t) and its position inside it, (u, v)
 * in [0, 1]^2. Points on or past the border go to the border dexels. */
static inline uint32_t fp_dexel_of(const fp_dexels *dx, float inv0, float inv1, float s,
                                   float t, float *u, float *v)
{
    const float w = (float)dx->w, h = (float)dx->h;
    float fs = (s - dx->lo[0]) * inv0, ft = (t - dx->lo[1]) * inv1;
    fs = fs < -1.0f ? -1.0f : fs > w + 1.0f ? w + 1.0f : fs;
    ft = ft < -1.0f ? -1.0f : ft > h + 1.0f ? h + 1.0f : ft;
    float cs = floorf(fs), ct = floorf(ft);
    float us = fs - cs, vt = ft - ct;
    int64_t c = (int64_t)cs, r = (int64_t)ct;
    if (dx->wrap_c) /* c is in [-1, w + 1] */
        c = c < 0 ? c + (int64_t)dx->w : c >= (int64_t)dx->w ? c - (int64_t)dx->w : c;
    else if (c < 0)
        c = 0, us = 0.0f;
    else if (c >= (int64_t)dx->w)
        c = (int64_t)dx->w - 1, us = 1.0f;
    if (dx->wrap_r)
        r = r < 0 ? r + (int64_t)dx->h : r >= (int64_t)dx->h ? r - (int64_t)dx->h : r;
    else if (r < 0)
        r = 0, vt = 0.0f;
    else if (r >= (int64_t)dx->h)
        r = (int64_t)dx->h - 1, vt = 1.0f;
    *u = us;
    *v = vt;
    return (uint32_t)((uint64_t)r * dx->w + (uint64_t)c);
}

/* Squared distance, in world units (height) or radians (range), from a
 * point at (u, v) in dexel (r + dr, c + dc) to the centre of dexel (r, c). */
static inline double fp_centre_d2(const fp_dexels *dx, float u, float v, int dr, int dc)
{
    double ds = (dc + u - 0.5) * dx->cell[0];
    double dt = (dr + v - 0.5) * dx->cell[1];
    return ds * ds + dt * dt;
}

/* Where the points of each dexel are: dexel k holds points
 * order[k == 0 ? 0 : start[k-1] .. start[k]) (after the scatter, start[k]
 * is the end of dexel k); map holds each point's dexel and position. */
typedef struct fp_buckets {
    const fp_mapped *map;
    uint32_t *start, *order;
} fp_buckets;

static inline double fp_centre_d2q(const fp_dexels *dx, const fp_mapped *m, int dr, int dc)
{
    return fp_centre_d2(dx, m->dx.u * (1.0f / 65535.0f), m->dx.v * (1.0f / 65535.0f), dr, dc);
}

/* A sampling gap of one dexel should not become a hole: an empty dexel
 * next to dexels holding spare points (not their representative) takes the
 * spare point nearest its centre, if it is nearer than the donor's own
 * representative (so the two keep their order and the blocks between them
 * do not fold). Raster order, first come first served; a taken point is
 * struck from its dexel's list. A filled dexel's point lies outside it,
 * which can still make its triangles overlap their neighbours in
 * projection: tsl_fp_untangle() checks them. */
static tessel_status fp_fill_empty(fp_dexels *dx, fp_buckets *bk)
{
    const uint32_t w = dx->w, h = dx->h;
    size_t filled = 0, cap = 0;
    for (uint32_t r = 0; r < h; r++) {
        for (uint32_t c = 0; c < w; c++) {
            size_t k = (size_t)r * w + c;
            if (dx->rep[k] != TESSEL_NONE)
                continue;
            double best = INFINITY;
            uint32_t *pick = NULL;
            for (int dr = -1; dr <= 1; dr++) {
                for (int dc = -1; dc <= 1; dc++) {
                    int64_t nr = (int64_t)r + dr, nc = (int64_t)c + dc;
                    if (nr < 0 || nr >= (int64_t)h) {
                        if (!dx->wrap_r)
                            continue;
                        nr = (nr + (int64_t)h) % (int64_t)h;
                    }
                    if (nc < 0 || nc >= (int64_t)w) {
                        if (!dx->wrap_c)
                            continue;
                        nc = (nc + (int64_t)w) % (int64_t)w;
                    }
                    size_t j = (size_t)nr * w + (size_t)nc;
                    uint32_t b = j == 0 ? 0 : bk->start[j - 1], e = bk->start[j];
                    if (e - b < 2)
                        continue;
                    double limit = fp_centre_d2q(dx, &bk->map[dx->rep[j]], dr, dc);
                    for (uint32_t q = b; q < e; q++) {
                        uint32_t i = bk->order[q];
                        if (i == TESSEL_NONE || i == dx->rep[j])
                            continue;
                        double d2 = fp_centre_d2q(dx, &bk->map[i], dr, dc);
                        if (!(d2 < limit))
                            continue;
                        if (d2 < best || (d2 == best && i < *pick)) {
                            best = d2;
                            pick = &bk->order[q];
                        }
                    }
                }
            }
            if (pick) {
                if (tsl_grow((void **)&dx->filled_slots, &cap, filled + 1, sizeof(uint32_t)) !=
                    TESSEL_OK)
                    return TESSEL_ERR_NOMEM;
                dx->rep[k] = *pick;
                *pick = TESSEL_NONE;
                dx->filled_slots[filled++] = (uint32_t)k;
            }
        }
    }
    dx->filled = filled;
    return TESSEL_OK;
}

/* The representative of a dexel's points a[0..n): among those whose depth
 * lies in the middle half (ranks ceil((n-1)/4) .. floor(3(n-1)/4); all of
 * them for one or two points), the one nearest the dexel's centre. Depth
 * outliers never win, and representatives sit near the dexel centres, so
 * the array stays regular in projection. */
static uint32_t fp_representative(const fp_dexels *dx, fp_pair *a, size_t n)
{
    size_t k1 = 0, k2 = n - 1;
    if (n > 2) {
        k1 = (n - 1 + 3) / 4;
        k2 = 3 * (n - 1) / 4;
        fp_pair_select(a, n, k1);
        if (k2 > k1)
            fp_pair_select(a + k1, n - k1, k2 - k1);
    }
    size_t best = k1;
    double bd = INFINITY;
    for (size_t k = k1; k <= k2; k++) {
        double d2 = fp_centre_d2(dx, a[k].u * (1.0f / 65535.0f), a[k].v * (1.0f / 65535.0f),
                                 0, 0);
        if (d2 < bd || (d2 == bd && fp_pair_less(a[k], a[best]))) {
            bd = d2;
            best = k;
        }
    }
    return a[best].index;
}

/* Buckets the mapped points into the w x h dexels (a stable counting sort
 * of point indices) and picks each dexel's representative. */
tessel_status tsl_fp_bucket(const fp_mapped *map, size_t n, fp_dexels *dx, int nt,
                               const tessel_callbacks *cb)
{
    size_t cells;
    if (!tsl_mul_size(dx->w, dx->h, &cells) || cells >= UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    fp_buckets bk = {map, NULL, NULL};
    bk.start = tsl_calloc_array(cells + 1, sizeof(uint32_t));
    dx->rep = tsl_alloc_array(cells, sizeof(uint32_t));
    if (!bk.start || !dx->rep) {
        free(bk.start);
        return TESSEL_ERR_NOMEM;
    }
    size_t valid = 0;
    for (size_t i = 0; i < n; i++) {
        uint32_t id = map[i].dx.id;
        if (id == TESSEL_NONE)
            continue;
        bk.start[id + 1]++;
        valid++;
    }
    uint32_t most = 0;
    for (size_t k = 0; k < cells; k++) {
        most = bk.start[k + 1] > most ? bk.start[k + 1] : most;
        bk.start[k + 1] += bk.start[k];
    }
    bk.order = tsl_alloc_array(valid, sizeof(uint32_t));
    if (!bk.order) {
        free(bk.start);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        uint32_t id = map[i].dx.id;
        if (id != TESSEL_NONE)
            bk.order[bk.start[id]++] = (uint32_t)i;
    }
    tessel_status status = tsl_progress(cb, "dexels", 0.7);
    uint32_t *rep = dx->rep;
    size_t reps = 0;
    int failed = 0;
    (void)nt;
#pragma omp parallel num_threads(nt) reduction(+ : reps, failed)
    {
        fp_pair *buf = tsl_alloc_array(most ? most : 1, sizeof(fp_pair));
#pragma omp for schedule(dynamic, 256)
        for (int64_t k = 0; k < (int64_t)cells; k++) {
            uint32_t b = k == 0 ? 0 : bk.start[k - 1], e = bk.start[k];
            rep[k] = b == e ? TESSEL_NONE : bk.order[b];
            if (e - b < 2) {
                reps += b < e;
                continue;
            }
            if (!buf) {
                failed++;
                continue;
            }
            for (uint32_t q = b; q < e; q++) {
                uint32_t i = bk.order[q];
                buf[q - b] = (fp_pair){map[i].dx.depth, i, map[i].dx.u, map[i].dx.v};
            }
            rep[k] = fp_representative(dx, buf, e - b);
            reps++;
        }
        free(buf);
    }
    if (failed && status == TESSEL_OK)
        status = TESSEL_ERR_NOMEM;
    dx->reps = reps;
    if (status == TESSEL_OK)
        status = fp_fill_empty(dx, &bk);
    dx->reps += dx->filled;
    free(bk.start);
    free(bk.order);
    return status;
}

/* Turns every map entry (s, t) into its dexel and position (see
 * fp_mapped). */
void tsl_fp_assign(fp_mapped *map, size_t n, const fp_dexels *dx, int nt)
{
    const float inv0 = (float)(1.0 / dx->cell[0]), inv1 = (float)(1.0 / dx->cell[1]);
    (void)nt;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (int64_t i = 0; i < (int64_t)n; i++) {
        fp_mapped *m = &map[i];
        float s = m->st.s, t = m->st.t, u, v;
        if (s != s) {
            m->dx.id = TESSEL_NONE;
            continue;
        }
        uint32_t id = fp_dexel_of(dx, inv0, inv1, s, t, &u, &v);
        m->dx.id = id;
        m->dx.u = (uint16_t)(u * 65535.0f + 0.5f);
        m->dx.v = (uint16_t)(v * 65535.0f + 0.5f);
    }
}

/* Chooses the array size: given, from a cell size, or so that occupied
 * dexels hold points_per_dexel points on average (the occupied area is
 * measured on a coarse probe grid filled with a sample). */
tessel_status tsl_fp_size(const fp_mapped *map, size_t n, const fp_frame *f,
                             const float lo[2], const float hi[2],
                             const tessel_fixed_plane_params *p, size_t valid, int full_axis,
                             fp_dexels *dx)
{
    double ext[2] = {(double)hi[0] - lo[0], (double)hi[1] - lo[1]};
    const int kind = f->kind, theta_axis = f->transpose ? 0 : 1;
    if (full_axis >= 0)
        ext[full_axis] = 2.0 * FP_PI;
    if (p->columns > 0 && p->rows > 0) {
        /* columns along phi and rows along theta, whichever way round the
         * array is stored */
        dx->w = f->transpose ? p->rows : p->columns;
        dx->h = f->transpose ? p->columns : p->rows;
        dx->cell[0] = ext[0] > 0 ? ext[0] / dx->w : 1.0;
        dx->cell[1] = ext[1] > 0 ? ext[1] / dx->h : 1.0;
        return TESSEL_OK;
    }
    double cell = p->cell;
    if (!(cell > 0.0)) {
        enum { PROBE = 128 };
        uint8_t *occ = calloc((size_t)PROBE * PROBE, 1);
        if (!occ)
            return TESSEL_ERR_NOMEM;
        double ps = ext[0] > 0 ? ext[0] / PROBE : 1.0, pt = ext[1] > 0 ? ext[1] / PROBE : 1.0;
        size_t step = fp_sample_step(n), m = 0;
        for (size_t i = 0; i < n; i += step) {
            const fp_mapped *q = &map[i];
            if (q->st.s != q->st.s)
                continue;
            int a = (int)((q->st.s - lo[0]) / ps), b = (int)((q->st.t - lo[1]) / pt);
            a = a < 0 ? 0 : a >= PROBE ? PROBE - 1 : a;
            b = b < 0 ? 0 : b >= PROBE ? PROBE - 1 : b;
            occ[(size_t)b * PROBE + a] = 1;
            m++;
        }
        /* With fewer sample points than probe cells the probe grid would
         * look sparse: use a coarser one (merge k x k probe cells). */
        int k = 1;
        while (k < PROBE && (double)m < 4.0 * (PROBE / k) * (PROBE / k))
            k *= 2;
        double area = 0.0;
        for (int b = 0; b < PROBE; b += k) {
            for (int a = 0; a < PROBE; a += k) {
                int any = 0;
                for (int j = b; j < b + k && !any; j++)
                    for (int i = a; i < a + k && !any; i++)
                        any = occ[(size_t)j * PROBE + i];
                if (!any)
                    continue;
                /* range: dexel area shrinks like sin(theta); the cell is
                 * set on the solid angle */
                double cellarea = ps * pt * k * k;
                if (kind == FP_RAY)
                    cellarea *= theta_axis ? sin(lo[1] + (b + 0.5 * k) * pt)
                                           : sin(lo[0] + (a + 0.5 * k) * ps);
                area += cellarea;
            }
        }
        free(occ);
        if (!(area > 0.0) || valid == 0)
            area = (ext[0] > 0 ? ext[0] : 1.0) * (ext[1] > 0 ? ext[1] : 1.0);
        cell = sqrt(area * p->points_per_dexel / (double)(valid ? valid : 1));
        if (!(cell > 0.0))
            cell = 1.0;
    }
    double cw = ceil(ext[0] / cell), ch = ceil(ext[1] / cell);
    if (cw < 1)
        cw = 1;
    if (ch < 1)
        ch = 1;
    if (cw * ch >= (double)UINT32_MAX || cw >= (double)UINT32_MAX ||
        ch >= (double)UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    dx->w = (uint32_t)cw;
    dx->h = (uint32_t)ch;
    dx->cell[0] = full_axis == 0 ? 2.0 * FP_PI / dx->w : cell;
    dx->cell[1] = full_axis == 1 ? 2.0 * FP_PI / dx->h : cell;
    return TESSEL_OK;
}

/* Maps every point once: map[i] = (s, t, depth), s = NaN for a point
 * that cannot be mapped; returns the number mapped and their
 * bounding box (parallel min/max are exact: no dependence on the thread
 * count). */
size_t tsl_fp_map_all(const tessel_cloud *cloud, const fp_frame *f, fp_mapped *map,
                         float lo[2], float hi[2], int nt)
{
    float l0 = FLT_MAX, l1 = FLT_MAX, h0 = -FLT_MAX, h1 = -FLT_MAX;
    size_t valid = 0;
    (void)nt;
#pragma omp parallel for schedule(static) reduction(min : l0, l1) reduction(max : h0, h1) \
    reduction(+ : valid) num_threads(nt)
    for (int64_t i = 0; i < (int64_t)cloud->count; i++) {
        float s, t, d;
        fp_mapped *m = &map[i];
        if (!fp_map(f, cloud->xyz + 3 * (size_t)i, &s, &t, &d)) {
            m->st.s = NAN;
            m->st.t = m->st.depth = 0.0f;
            continue;
        }
        m->st.s = s;
        m->st.t = t;
        m->st.depth = d;
        valid++;
        l0 = s < l0 ? s : l0;
        h0 = s > h0 ? s : h0;
        l1 = t < l1 ? t : l1;
        h1 = t > h1 ? t : h1;
    }
    lo[0] = l0;
    lo[1] = l1;
    hi[0] = h0;
    hi[1] = h1;
    return valid;
}
