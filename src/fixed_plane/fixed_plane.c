/* Fixed-plane reconstruction: height fields, range scans, organized grids.
 *
 * Gopi & Krishnan 2002, section 5 ("Triangulating terrain data") and 5.1:
 * when the data are a height field or come from a scanner with one centre
 * of projection, the projection plane of the general method is fixed, the
 * dexel array becomes two-dimensional with one representative point per
 * dexel, the neighbours of a point come only from adjacent dexels, the
 * sphere of influence is set slightly above the noise level, and the
 * visibility and angle tests are dropped because every candidate is
 * visible. Noise, being mostly along the projection direction, no longer
 * disturbs the triangulation (section 5, and 6.1 on fixed planes).
 *
 * Three ways to get the dexel array, one triangulator:
 *   height  the cloud is projected on a plane (least variance, or normal to
 *           an axis); square dexels; depth = height.
 *   range   directions from the viewpoint in (theta, phi) about a pole axis;
 *           depth = range.
 *   grid    the organized cloud's own grid, every point its own dexel.
 * Representative (height, range): among the dexel's points whose depth is
 * in the middle half of its depths, the one nearest the dexel centre; an
 * empty dexel next to spare points takes the nearest (one-dexel sampling
 * gaps), its triangles checked for overlap in projection.
 * The triangulator walks the 2x2 blocks of adjacent dexels, joins the
 * shorter diagonal, keeps a triangle when its three edges pass the
 * sphere-of-influence test (see tessel.h) and it is not flipped seen along
 * the projection direction, removes the few triangles that would make a
 * vertex non-manifold (two fans touching at one vertex), closes the small
 * polar ring of a full (theta, phi) scan and streams the rest in row order.
 * Orientation comes from the array's parametrization, so it is consistent
 * by construction. docs/fixed_plane.md has the details and measurements.
 */
#include "fixed_plane/fixed_plane.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

tessel_fixed_plane_params tessel_fixed_plane_params_default(void)
{
    tessel_fixed_plane_params p;
    memset(&p, 0, sizeof p);
    p.mode = TESSEL_FIXED_PLANE_HEIGHT;
    p.axis = -1;
    p.columns = 0;
    p.rows = 0;
    p.cell = 0.0;
    p.points_per_dexel = 3.0;
    p.use_viewpoint = 0;
    p.max_angle = 80.0;
    p.noise = 0.0;
    p.noise_factor = 6.0;
    p.threads = 0;
    return p;
}

/* ------------------------------------------------------------------------ */
/* Noise estimate and orientation                                            */
/* ------------------------------------------------------------------------ */

/* Puts the k-th smallest of a[0..n) at a[k] (three-way partition: many
 * equal values, e.g. the zero residuals of clean data, stay linear). */
static void fp_float_select(float *a, size_t n, size_t k)
{
    size_t lo = 0, hi = n;
    while (hi - lo > 1) {
        float x0 = a[lo], x1 = a[lo + (hi - lo) / 2], x2 = a[hi - 1];
        float pivot = x0 < x1 ? (x1 < x2 ? x1 : (x0 < x2 ? x2 : x0))
                              : (x0 < x2 ? x0 : (x1 < x2 ? x2 : x1));
        size_t lt = lo, i = lo, gt = hi;
        while (i < gt) {
            float v = a[i];
            if (v < pivot) {
                a[i++] = a[lt];
                a[lt++] = v;
            } else if (v > pivot) {
                a[i] = a[--gt];
                a[gt] = v;
            } else {
                i++;
            }
        }
        if (k < lt)
            hi = lt;
        else if (k >= gt)
            lo = gt;
        else
            return;
    }
}

/* Residual of c against the plane through l, r, u, measured along the
 * projection direction and scaled to the deviation of one point: the
 * intersection of c's line with the plane is sum(lambda_i p_i), whose
 * noise adds sum(lambda_i^2) to c's own. Negative when unusable. */
static double fp_residual(const fp_ctx *x, const fp_vrec *c, const fp_vrec *l,
                          const fp_vrec *r, const fp_vrec *u)
{
    double L[3], e1[3], e2[3], n[3], w[3], lc[3];
    tsl_load(l->p, L);
    for (int k = 0; k < 3; k++) {
        e1[k] = (double)r->p[k] - L[k];
        e2[k] = (double)u->p[k] - L[k];
        lc[k] = L[k] - (double)c->p[k];
        w[k] = x->kind == FP_RAY ? c->d[k] : x->dir[k];
    }
    tsl_cross(e1, e2, n);
    double nn = tsl_dot(n, n), den = tsl_dot(n, w);
    if (!(nn > 0.0) || fabs(den) < 0.2 * sqrt(nn))
        return -1.0;
    double t = tsl_dot(n, lc) / den;
    double q[3], lq[3], cr[3];
    for (int k = 0; k < 3; k++) {
        q[k] = (double)c->p[k] + t * w[k];
        lq[k] = q[k] - L[k];
    }
    tsl_cross(e1, lq, cr);
    double lu = tsl_dot(cr, n) / nn;
    tsl_cross(lq, e2, cr);
    double lr = tsl_dot(cr, n) / nn;
    double ll = 1.0 - lu - lr;
    if (ll < -0.5 || ll > 1.5 || lu < -0.5 || lu > 1.5 || lr < -0.5 || lr > 1.5)
        return -1.0;
    return fabs(t) / sqrt(1.0 + ll * ll + lu * lu + lr * lr);
}

/* Robust noise estimate: 1.4826 * median residual over a sample of rows. */
static tessel_status fp_estimate_noise(const fp_ctx *x, double *sigma)
{
    *sigma = 0.0;
    if (x->w < 3 || x->h < 2)
        return TESSEL_OK;
    uint32_t step = 1;
    while ((uint64_t)(x->h / step) * x->w > (uint64_t)FP_SAMPLE)
        step++;
    size_t cap = (size_t)(x->h / step + 1) * x->w;
    float *res = tsl_alloc_array(cap, sizeof(float));
    fp_vrec *rows = tsl_alloc_array((size_t)2 * x->w, sizeof(fp_vrec));
    if (!res || !rows) {
        free(res);
        free(rows);
        return TESSEL_ERR_NOMEM;
    }
    size_t n = 0;
    for (uint32_t r = 1; r < x->h; r += step) {
        fp_vrec *up = rows, *mid = rows + x->w;
        tsl_fp_row(x, r - 1, up);
        tsl_fp_row(x, r, mid);
        for (uint32_t c = 1; c + 1 < x->w; c++) {
            if (!mid[c].ok || !mid[c - 1].ok || !mid[c + 1].ok || !up[c].ok)
                continue;
            double d = fp_residual(x, &mid[c], &mid[c - 1], &mid[c + 1], &up[c]);
            if (d >= 0.0 && n < cap)
                res[n++] = (float)d;
        }
    }
    if (n >= 8) {
        fp_float_select(res, n, n / 2);
        *sigma = 1.4826 * (double)res[n / 2];
    }
    free(res);
    free(rows);
    return TESSEL_OK;
}

/* Which way the array's counter-clockwise order faces the viewpoint: a
 * vote over a sample of complete blocks (ray kind only). */
static void fp_vote_orientation(fp_ctx *x)
{
    x->orient = 1;
    if (x->kind != FP_RAY || x->ch == 0 || x->cw == 0)
        return;
    fp_vrec *rows = tsl_alloc_array((size_t)2 * x->w, sizeof(fp_vrec));
    if (!rows)
        return; /* keeps +1; the facing test then drops wrong triangles */
    uint32_t step = 1;
    while ((uint64_t)(x->ch / step) * x->cw > (uint64_t)FP_SAMPLE)
        step++;
    int64_t vote = 0;
    fp_ctx probe = *x;
    for (uint32_t r = 0; r < x->ch; r += step) {
        fp_vrec *a = rows, *b = rows + x->w;
        tsl_fp_row(x, r, a);
        tsl_fp_row(x, r + 1 == x->h ? 0 : r + 1, b);
        for (uint32_t c = 0; c < x->cw; c++) {
            uint32_t cn = c + 1 == x->w ? 0 : c + 1;
            if (!a[c].ok || !a[cn].ok || !b[cn].ok)
                continue;
            probe.orient = 1;
            if (tsl_fp_facing(&probe, &a[c], &a[cn], &b[cn]))
                vote++;
            else {
                probe.orient = -1;
                if (tsl_fp_facing(&probe, &a[c], &a[cn], &b[cn]))
                    vote--;
            }
        }
    }
    free(rows);
    x->orient = vote < 0 ? -1 : 1;
}

/* Grid mode: the first and last rows (columns) of a full 360 degree scan
 * are neighbours: their rays are about one step apart. */
static int fp_detect_wrap(const fp_ctx *x, int along_rows)
{
    uint32_t n = along_rows ? x->h : x->w, other = along_rows ? x->w : x->h;
    if (x->kind != FP_RAY || n < 3 || other == 0)
        return 0;
    uint32_t step = other > 512 ? other / 512 : 1;
    size_t cap = other / step + 1, m = 0;
    float *wrapd = tsl_alloc_array(cap, sizeof(float));
    float *stepd = tsl_alloc_array(cap, sizeof(float));
    int wrap = 0;
    if (wrapd && stepd) {
        fp_vrec v[3];
        fp_ctx one = *x;
        for (uint32_t k = 0; k < other && m < cap; k += step) {
            uint32_t pos[3] = {0, 1, n - 1};
            for (int j = 0; j < 3; j++) {
                uint32_t i = along_rows ? x->idx[(size_t)pos[j] * x->w + k]
                                        : x->idx[(size_t)k * x->w + pos[j]];
                one.idx = &i;
                one.w = 1;
                tsl_fp_row(&one, 0, &v[j]);
            }
            if (!v[0].ok || !v[1].ok || !v[2].ok)
                continue;
            float s = 0, t = 0;
            for (int j = 0; j < 3; j++) {
                s += (v[0].d[j] - v[1].d[j]) * (v[0].d[j] - v[1].d[j]);
                t += (v[0].d[j] - v[2].d[j]) * (v[0].d[j] - v[2].d[j]);
            }
            stepd[m] = sqrtf(s);
            wrapd[m] = sqrtf(t);
            m++;
        }
        if (m >= 3) {
            fp_float_select(stepd, m, m / 2);
            fp_float_select(wrapd, m, m / 2);
            float s = stepd[m / 2], t = wrapd[m / 2];
            wrap = s > 0.0f && t >= 0.5f * s && t <= 1.5f * s;
        }
    }
    free(wrapd);
    free(stepd);
    return wrap;
}

/* ------------------------------------------------------------------------ */
/* Emission                                                                  */
/* ------------------------------------------------------------------------ */

static tessel_status fp_emit(const fp_ctx *x, const uint8_t *codes,
                             const tessel_triangle_sink *sink, const tessel_callbacks *cb,
                             size_t *count)
{
    /* Room for a whole block row: the row loop writes without checks. */
    size_t cap = (size_t)2 * x->cw > FP_BATCH ? (size_t)2 * x->cw : FP_BATCH;
    uint32_t *buf = tsl_alloc_array(3 * cap, sizeof(uint32_t));
    if (!buf)
        return TESSEL_ERR_NOMEM;
    size_t n = 0, total = 0;
    tessel_status status = TESSEL_OK;
    const int flip = x->orient < 0;
    for (uint32_t r = 0; r < x->ch && status == TESSEL_OK; r++) {
        if (n + (size_t)2 * x->cw > cap) {
            status = sink->emit(sink->user_data, buf, n);
            total += n;
            n = 0;
            if (status != TESSEL_OK)
                break;
        }
        const uint8_t *row = codes + (size_t)r * x->cw;
        const uint32_t *top = x->idx + (size_t)r * x->w;
        const uint32_t *bot = x->idx + (size_t)(r + 1 == x->h ? 0 : r + 1) * x->w;
        uint32_t *o = buf + 3 * n;
        /* t0 = (A, B, d ? C : D), t1 = (d ? B : A, D, C); flip swaps the
         * last two corners. Both are written, the pointer advances only
         * past those that exist. */
        for (uint32_t c = 0; c < x->cw; c++) {
            unsigned code = row[c];
            uint32_t cn = c + 1 == x->w ? 0 : c + 1;
            uint32_t A = top[c], B = top[cn], C = bot[c], D = bot[cn];
            uint32_t X = (code & 1) ? C : D, Y = (code & 1) ? B : A;
            o[0] = A;
            o[1] = flip ? X : B;
            o[2] = flip ? B : X;
            o += 3 * ((code >> 1) & 1u);
            o[0] = Y;
            o[1] = flip ? C : D;
            o[2] = flip ? D : C;
            o += 3 * ((code >> 2) & 1u);
        }
        n = (size_t)(o - buf) / 3;
        if (status == TESSEL_OK && (r & 1023u) == 1023u)
            status = tsl_progress(cb, "triangles", 0.5 + 0.5 * (double)r / x->ch);
    }
    if (status == TESSEL_OK && n > 0) {
        status = sink->emit(sink->user_data, buf, n);
        total += n;
    }
    free(buf);
    *count = total;
    return status;
}

/* ------------------------------------------------------------------------ */
/* Polar caps                                                                */
/* ------------------------------------------------------------------------ */

/* A 360-degree (theta, phi) scan leaves a small hole at the pole: its first
 * (or last) theta line is a ring of points round the pole, half a step away
 * from it, that no block closes. When that ring is complete - every point
 * present, every ring edge on a triangle - and small (within 1.5 theta steps
 * of its mean direction), it is closed by a zig-zag strip across it.
 * Every new edge passes the edge test and every new triangle faces the
 * viewpoint the same way, else the ring stays open. The ring is convex seen
 * from the viewpoint, so the strip neither folds nor crosses the blocks;
 * each ring vertex gets the missing side of its fan. */
static tessel_status fp_cap_ring(const fp_ctx *x, const uint8_t *codes, int along_rows,
                                 int last, uint32_t *out, size_t *count)
{
    /* ring: column c0 (rows wrap) or row r0 (columns wrap) */
    const uint32_t n = along_rows ? x->h : x->w;
    const uint32_t line = last ? (along_rows ? x->w - 1 : x->h - 1) : 0;
    const uint32_t next = last ? line - 1 : line + 1;
    *count = 0;
    fp_vrec *ring = tsl_alloc_array(n, sizeof(fp_vrec));
    float *steps = tsl_alloc_array(n, sizeof(float));
    uint32_t *ids = tsl_alloc_array(n, sizeof(uint32_t));
    tessel_status status = ring && steps && ids ? TESSEL_OK : TESSEL_ERR_NOMEM;
    int ok = status == TESSEL_OK;
    fp_ctx one = *x;
    one.w = 1;
    double mean[3] = {0, 0, 0};
    for (uint32_t k = 0; ok && k < n; k++) {
        size_t at = along_rows ? (size_t)k * x->w + line : (size_t)line * x->w + k;
        size_t nb = along_rows ? (size_t)k * x->w + next : (size_t)next * x->w + k;
        fp_vrec other;
        ids[k] = x->idx[at];
        one.idx = &x->idx[at];
        tsl_fp_row(&one, 0, &ring[k]);
        one.idx = &x->idx[nb];
        tsl_fp_row(&one, 0, &other);
        ok = ring[k].ok;
        steps[k] = 0.0f;
        if (ok && other.ok)
            for (int j = 0; j < 3; j++)
                steps[k] += (ring[k].d[j] - other.d[j]) * (ring[k].d[j] - other.d[j]);
        for (int j = 0; ok && j < 3; j++)
            mean[j] += ring[k].d[j];
        /* the block holding ring edge k -> k+1 must have its triangle */
        if (ok) {
            size_t b;
            unsigned want_t1;
            if (along_rows) {
                b = (size_t)k * x->cw + (last ? x->w - 2 : 0);
                want_t1 = last ? 0u : 1u; /* c = 0: A-C; c = w-1: B-D */
            } else {
                b = (size_t)(last ? x->h - 2 : 0) * x->cw + k;
                want_t1 = last ? 1u : 0u; /* r = 0: A-B; r = h-1: C-D */
            }
            unsigned code = codes[b], diag = code & 1u;
            unsigned t = along_rows ? (diag ? 1u - want_t1 : want_t1) : want_t1;
            ok = (code & (t ? FP_T1 : FP_T0)) != 0;
        }
    }
    if (ok && tsl_normalize(mean)) {
        float radius = 0.0f;
        for (uint32_t k = 0; k < n; k++) {
            float e = 0.0f;
            for (int j = 0; j < 3; j++)
                e += ((float)mean[j] - ring[k].d[j]) * ((float)mean[j] - ring[k].d[j]);
            radius = e > radius ? e : radius;
        }
        fp_float_select(steps, n, n / 2);
        float step = steps[n / 2]; /* squared chords */
        ok = step > 0.0f && radius <= 2.25f * step;
    } else {
        ok = 0;
    }
    /* zig-zag strip: (l, l+1, r) and (l, r-1, r), all facing one way */
    int sign = 0;
    size_t m = 0;
    for (uint32_t l = 0, r = n - 1, toggle = 1; ok && r - l >= 2; toggle ^= 1u) {
        uint32_t a = l, b = toggle ? l + 1 : r - 1, c = r;
        float len2;
        ok = tsl_fp_edge(x, &ring[a], &ring[c], &len2) && tsl_fp_edge(x, &ring[b], &ring[a], &len2) &&
             tsl_fp_edge(x, &ring[b], &ring[c], &len2);
        if (!ok)
            break;
        fp_ctx probe = *x;
        probe.orient = 1;
        int s = tsl_fp_facing(&probe, &ring[a], &ring[b], &ring[c]) ? 1 : 0;
        probe.orient = -1;
        s = s ? 1 : tsl_fp_facing(&probe, &ring[a], &ring[b], &ring[c]) ? -1 : 0;
        ok = s != 0 && (sign == 0 || s == sign);
        sign = s;
        /* counter-clockwise seen from the viewpoint */
        out[3 * m] = ids[a];
        out[3 * m + 1] = ids[s > 0 ? b : c];
        out[3 * m + 2] = ids[s > 0 ? c : b];
        m++;
        if (toggle)
            l++;
        else
            r--;
    }
    if (ok)
        *count = m;
    free(ring);
    free(steps);
    free(ids);
    return status;
}

static tessel_status fp_cap_poles(const fp_ctx *x, const uint8_t *codes,
                                  const tessel_triangle_sink *sink, size_t *triangles,
                                  int *poles)
{
    *poles = 0;
    if (x->kind != FP_RAY || (x->wrap_r == x->wrap_c) || x->w < 3 || x->h < 3)
        return TESSEL_OK;
    const int along_rows = x->wrap_r;
    const uint32_t n = along_rows ? x->h : x->w;
    uint32_t *tris = tsl_alloc_array((size_t)3 * n, sizeof(uint32_t));
    if (!tris)
        return TESSEL_ERR_NOMEM;
    tessel_status status = TESSEL_OK;
    for (int last = 0; last < 2 && status == TESSEL_OK; last++) {
        size_t count = 0;
        status = fp_cap_ring(x, codes, along_rows, last, tris, &count);
        if (status == TESSEL_OK && count > 0) {
            status = sink->emit(sink->user_data, tris, count);
            *triangles += count;
            (*poles)++;
        }
    }
    free(tris);
    return status;
}

/* ------------------------------------------------------------------------ */
/* The whole reconstruction                                                  */
/* ------------------------------------------------------------------------ */

static tessel_status fp_check_params(const tessel_fixed_plane_params *p)
{
    if ((unsigned)p->mode > (unsigned)TESSEL_FIXED_PLANE_GRID)
        return TESSEL_ERR_INVALID_ARG;
    if (p->axis < -1 || p->axis > 2)
        return TESSEL_ERR_INVALID_ARG;
    if ((p->columns == 0) != (p->rows == 0))
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->cell >= 0.0) || !isfinite(p->cell))
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->points_per_dexel >= 1.0) || !isfinite(p->points_per_dexel))
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->max_angle > 0.0 && p->max_angle < 90.0))
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->noise >= 0.0) || !isfinite(p->noise))
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->noise_factor >= 0.0) || !isfinite(p->noise_factor))
        return TESSEL_ERR_INVALID_ARG;
    if (p->use_viewpoint && !(isfinite(p->viewpoint[0]) && isfinite(p->viewpoint[1]) &&
                              isfinite(p->viewpoint[2])))
        return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

/* Grid mode: the organized cloud's own grid is the array; every index must
 * be a point or TESSEL_NONE. */
static tessel_status setup_grid(const tessel_cloud *cloud, const double vp_world[3],
                                const tessel_callbacks *callbacks, fp_ctx *x,
                                tessel_fixed_plane_stats *st)
{
    if (!cloud->grid || cloud->width == 0 || cloud->height == 0) {
        tsl_log(callbacks, TESSEL_LOG_WARNING,
                "grid mode needs an organized cloud (a width x height grid, as in PCD "
                "WIDTH/HEIGHT or PLY 'comment organized W H'); this cloud is "
                "unorganized: use the height or range mode");
        return TESSEL_ERR_INVALID_ARG;
    }
    size_t cells, reps = 0;
    if (!tsl_mul_size(cloud->width, cloud->height, &cells))
        return TESSEL_ERR_LIMIT;
    /* One branch-free pass that also counts the points. */
    uint32_t bad = 0;
    const uint32_t count32 = (uint32_t)cloud->count;
    for (size_t k = 0; k < cells; k++) {
        uint32_t g = cloud->grid[k];
        reps += g != TESSEL_NONE;
        bad |= (g != TESSEL_NONE) & (g >= count32);
    }
    if (bad)
        return TESSEL_ERR_INVALID_ARG;
    x->kind = FP_RAY;
    x->w = cloud->width;
    x->h = cloud->height;
    x->idx = cloud->grid;
    for (int k = 0; k < 3; k++)
        x->vp[k] = (float)(vp_world[k] - cloud->offset[k]);
    x->wrap_r = fp_detect_wrap(x, 1);
    x->wrap_c = fp_detect_wrap(x, 0);
    st->representatives = reps;
    memcpy(st->viewpoint, vp_world, sizeof st->viewpoint);
    return TESSEL_OK;
}

/* Height and range modes: the frame, every point mapped, the array sized
 * (a range scan covering the whole circle of phi wraps round), the points
 * bucketed and one representative per dexel in dx->rep (the caller frees
 * dx->rep and dx->filled_slots). */
static tessel_status setup_dexels(const tessel_cloud *cloud, const tessel_fixed_plane_params *p,
                                  const double vp_world[3], int have_vp,
                                  const tessel_callbacks *callbacks, fp_ctx *x, fp_dexels *dx,
                                  tessel_fixed_plane_stats *st)
{
    fp_frame f;
    double gap = 0.0;
    if (p->mode == TESSEL_FIXED_PLANE_HEIGHT) {
        tsl_fp_height_frame(cloud, p->axis, &f);
    } else {
        if (!have_vp) {
            tsl_log(callbacks, TESSEL_LOG_WARNING,
                    "range mode needs the scanner position: give a viewpoint (the "
                    "cloud has none)");
            return TESSEL_ERR_INVALID_ARG;
        }
        double vpl[3];
        for (int k = 0; k < 3; k++)
            vpl[k] = vp_world[k] - cloud->offset[k];
        tsl_fp_range_frame(cloud, vpl, &f, &gap);
        tsl_fp_scan_order(cloud, &f);
        for (int k = 0; k < 3; k++)
            x->vp[k] = (float)vpl[k];
        memcpy(st->viewpoint, vp_world, sizeof st->viewpoint);
    }
    tessel_status status = tsl_progress(callbacks, "dexels", 0.0);
    if (status != TESSEL_OK)
        return status;
    fp_mapped *map = tsl_alloc_array(cloud->count, sizeof(fp_mapped));
    if (!map)
        return TESSEL_ERR_NOMEM;
    float lo[2], hi[2];
    size_t valid = tsl_fp_map_all(cloud, &f, map, lo, hi, x->threads);
    if (valid == 0) {
        lo[0] = lo[1] = 0.0f;
        hi[0] = hi[1] = 0.0f;
    }
    /* A scan covering the whole circle of phi wraps round: no seam.
     * Decided on the sample's widest empty sector against the cell. */
    int full = -1;
    if (f.kind == FP_RAY) {
        int pa = f.transpose ? 1 : 0;
        status = tsl_fp_size(map, cloud->count, &f, lo, hi, p, valid, -1, dx);
        if (status == TESSEL_OK && gap < 2.0 * dx->cell[pa] && (double)hi[pa] - lo[pa] > FP_PI) {
            full = pa;
            lo[pa] = 0.0f;
        }
    }
    if (status == TESSEL_OK)
        status = tsl_fp_size(map, cloud->count, &f, lo, hi, p, valid, full, dx);
    /* A dexel array far finer than the points would be empty dexels
     * only, and could ask for gigabytes. */
    if (status == TESSEL_OK && (double)dx->w * dx->h > 16.0 * (double)valid + (double)(1u << 20)) {
        tsl_log(callbacks, TESSEL_LOG_WARNING,
                "a %u x %u dexel array for %zu points is far finer than the "
                "sampling: choose a larger cell or fewer dexels",
                dx->w, dx->h, valid);
        status = TESSEL_ERR_LIMIT;
    }
    dx->wrap_c = full == 0;
    dx->wrap_r = full == 1;
    dx->lo[0] = lo[0];
    dx->lo[1] = lo[1];
    if (status == TESSEL_OK) {
        tsl_fp_assign(map, cloud->count, dx, x->threads);
        status = tsl_fp_bucket(map, cloud->count, dx, x->threads, callbacks);
    }
    free(map);
    if (status != TESSEL_OK)
        return status;
    x->kind = f.kind;
    x->w = dx->w;
    x->h = dx->h;
    x->idx = dx->rep;
    x->wrap_c = dx->wrap_c && dx->w >= 3;
    x->wrap_r = dx->wrap_r && dx->h >= 3;
    if (f.kind == FP_PLANE)
        for (int k = 0; k < 3; k++)
            x->dir[k] = (float)f.e[2][k];
    for (int k = 0; k < 3; k++)
        st->axis[k] = f.e[2][k];
    st->cell[0] = dx->cell[0];
    st->cell[1] = dx->cell[1];
    st->representatives = dx->reps;
    st->dexels_filled = dx->filled;
    return TESSEL_OK;
}

/* The block codes of every block, in parallel over bands of rows. */
static tessel_status block_codes(const fp_ctx *x, uint8_t *codes,
                                 const tessel_callbacks *callbacks, tessel_fixed_plane_stats *st)
{
    tessel_status status = TESSEL_OK;
    for (uint32_t band = 0; status == TESSEL_OK && band < x->ch;) {
        uint32_t nb = (uint32_t)x->threads * 16u, rows_per = FP_BLOCK_ROWS;
        uint64_t band_end64 = (uint64_t)band + (uint64_t)nb * rows_per;
        uint32_t band_end = band_end64 > x->ch ? x->ch : (uint32_t)band_end64;
        uint32_t blocks = (band_end - band + rows_per - 1) / rows_per;
        size_t missing = 0, open = 0, folded = 0;
        int failed = 0;
        int nt = x->threads;
        (void)nt;
#pragma omp parallel num_threads(nt) reduction(+ : missing, open, folded, failed)
        {
            fp_scratch sc;
            tessel_status ss = tsl_fp_scratch_alloc(&sc, x->w);
            /* Every thread must meet the worksharing loop. */
#pragma omp for schedule(dynamic, 1)
            for (int64_t bi = 0; bi < (int64_t)blocks; bi++) {
                if (ss != TESSEL_OK) {
                    failed++;
                    continue;
                }
                uint32_t r0 = band + (uint32_t)bi * rows_per;
                uint32_t r1 = r0 + rows_per > band_end ? band_end : r0 + rows_per;
                fp_counts cnt = {0, 0, 0};
                tsl_fp_codes_rows(x, r0, r1, codes, &sc, &cnt);
                missing += cnt.missing;
                open += cnt.open;
                folded += cnt.folded;
            }
            free(sc.mem);
        }
        if (failed)
            status = TESSEL_ERR_NOMEM;
        st->cells_missing += missing;
        st->cells_open += open;
        st->triangles_folded += folded;
        band = band_end;
        if (status == TESSEL_OK)
            status = tsl_progress(callbacks, "triangles", 0.4 * (double)band / x->ch);
    }
    return status;
}

/* On a scan seen from its own viewpoint, or a height field, few triangles
 * face away (0-6% of those made on the LAS files and the room scan we test
 * with); more than were made means the input is not what the mode
 * assumes, and the mesh, still manifold, may cross itself. */
static void warn_folded(const tessel_fixed_plane_params *p, const tessel_fixed_plane_stats *st,
                        const tessel_callbacks *callbacks)
{
    if (st->triangles_folded <= st->triangles)
        return;
    tsl_log(callbacks, TESSEL_LOG_WARNING,
            "%zu triangles faced away from the %s and were dropped, more than the %zu "
            "made: %s",
            st->triangles_folded,
            p->mode == TESSEL_FIXED_PLANE_HEIGHT ? "plane's normal" : "viewpoint", st->triangles,
            p->mode == TESSEL_FIXED_PLANE_HEIGHT
                ? "the cloud is no height field seen along it (another axis?)"
            : p->mode == TESSEL_FIXED_PLANE_RANGE
                ? "is the viewpoint the scanner's?"
                : "is the viewpoint the camera's, and the grid its image?");
}

/* The whole reconstruction: the array (the organized grid, or dexels),
 * the noise and the orientation, the block codes, then the filled
 * dexels untangled, vertex manifoldness, emission and the polar caps. */
tessel_status tessel_reconstruct_fixed_plane(const tessel_cloud *cloud,
                                             const tessel_fixed_plane_params *params,
                                             const tessel_callbacks *callbacks,
                                             const tessel_triangle_sink *sink,
                                             tessel_fixed_plane_stats *stats)
{
    double t_start = tsl_seconds();
    tessel_fixed_plane_params p = params ? *params : tessel_fixed_plane_params_default();
    tessel_fixed_plane_stats st;
    memset(&st, 0, sizeof st);
    if (stats)
        *stats = st;
    if (!cloud || !sink || !sink->emit || (cloud->count > 0 && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_status status = fp_check_params(&p);
    if (status != TESSEL_OK)
        return status;
    if (cloud->count >= UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    st.mode = p.mode;
    st.points_in = cloud->count;

    fp_ctx x;
    memset(&x, 0, sizeof x);
    x.xyz = cloud->xyz;
    x.threads = tsl_threads(p.threads);
    double cosa = cos(p.max_angle * FP_PI / 180.0);
    x.reach2 = (float)(1.0 / (cosa * cosa));

    double vp_world[3] = {0, 0, 0};
    int have_vp = 0;
    if (p.use_viewpoint) {
        memcpy(vp_world, p.viewpoint, sizeof vp_world);
        have_vp = 1;
    } else if (cloud->has_viewpoint) {
        memcpy(vp_world, cloud->viewpoint, sizeof vp_world);
        have_vp = 1;
    }

    fp_dexels dx;
    memset(&dx, 0, sizeof dx);
    if (p.mode == TESSEL_FIXED_PLANE_GRID)
        status = setup_grid(cloud, vp_world, callbacks, &x, &st);
    else
        status = setup_dexels(cloud, &p, vp_world, have_vp, callbacks, &x, &dx, &st);
    if (status != TESSEL_OK) {
        free(dx.rep);
        free(dx.filled_slots);
        return status;
    }
    st.seconds_dexels = tsl_seconds() - t_start;
    st.columns = x.w;
    st.rows = x.h;
    x.cw = x.w < 2 ? 0 : x.wrap_c ? x.w : x.w - 1;
    x.ch = x.h < 2 ? 0 : x.wrap_r ? x.h : x.h - 1;
    st.wrap_columns = x.wrap_c;
    st.wrap_rows = x.wrap_r;
    st.cells = (size_t)x.cw * x.ch;

    if (p.noise > 0.0) {
        st.noise = p.noise;
    } else {
        status = fp_estimate_noise(&x, &st.noise);
        st.noise_estimated = 1;
    }
    st.margin = p.noise_factor * st.noise;
    x.margin2 = (float)(st.margin * st.margin);
    fp_vote_orientation(&x);

    uint8_t *codes = NULL;
    if (status == TESSEL_OK && st.cells > 0) {
        codes = tsl_alloc_array(st.cells, 1);
        if (!codes)
            status = TESSEL_ERR_NOMEM;
    }
    if (status == TESSEL_OK)
        status = tsl_progress(callbacks, "triangles", 0.0);
    if (status == TESSEL_OK)
        status = block_codes(&x, codes, callbacks, &st);
    if (status == TESSEL_OK && codes && dx.filled)
        tsl_fp_untangle(&x, codes, dx.filled_slots, dx.filled, &st.triangles_folded);
    if (status == TESSEL_OK && codes)
        status = tsl_fp_make_manifold(&x, codes, &st.triangles_nonmanifold);
    if (status == TESSEL_OK && codes)
        status = fp_emit(&x, codes, sink, callbacks, &st.triangles);
    if (status == TESSEL_OK && codes)
        status = fp_cap_poles(&x, codes, sink, &st.triangles, &st.poles_closed);
    if (status == TESSEL_OK)
        warn_folded(&p, &st, callbacks);
    if (status == TESSEL_OK)
        status = tsl_progress(callbacks, "triangles", 1.0);
    free(codes);
    free(dx.rep);
    free(dx.filled_slots);
    st.seconds = tsl_seconds() - t_start;
    if (stats)
        *stats = st;
    return status;
}

/* ------------------------------------------------------------------------ */
/* Mesh output                                                               */
/* ------------------------------------------------------------------------ */

typedef struct fp_collect {
    uint32_t *tris;
    size_t count, cap;       /* in triangles */
} fp_collect;

static tessel_status fp_collect_emit(void *user, const uint32_t *tris, size_t count)
{
    fp_collect *c = user;
    size_t need;
    if (!tsl_add_size(c->count, count, &need))
        return TESSEL_ERR_NOMEM;
    tessel_status s = tsl_grow((void **)&c->tris, &c->cap, need, 3 * sizeof(uint32_t));
    if (s != TESSEL_OK)
        return s;
    memcpy(c->tris + 3 * c->count, tris, count * 3 * sizeof(uint32_t));
    c->count = need;
    return TESSEL_OK;
}

tessel_status tessel_reconstruct_fixed_plane_mesh(const tessel_cloud *cloud,
                                                  const tessel_fixed_plane_params *params,
                                                  const tessel_callbacks *callbacks,
                                                  tessel_mesh *mesh,
                                                  tessel_fixed_plane_stats *stats)
{
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    fp_collect col = {NULL, 0, 0};
    tessel_triangle_sink sink = {fp_collect_emit, &col};
    tessel_status status = tessel_reconstruct_fixed_plane(cloud, params, callbacks, &sink, stats);
    uint32_t *map = NULL;
    if (status == TESSEL_OK) {
        map = tsl_alloc_array(cloud->count, sizeof(uint32_t));
        if (!map)
            status = TESSEL_ERR_NOMEM;
    }
    if (status == TESSEL_OK) {
        for (size_t i = 0; i < cloud->count; i++)
            map[i] = TESSEL_NONE;
        for (size_t k = 0; k < 3 * col.count; k++)
            map[col.tris[k]] = 0;
        size_t used = 0;
        for (size_t i = 0; i < cloud->count; i++)
            if (map[i] != TESSEL_NONE)
                map[i] = (uint32_t)used++;
        status = tessel_mesh_alloc(mesh, used, col.count, cloud->normals != NULL,
                                   cloud->rgb != NULL);
        if (status == TESSEL_OK) {
            memcpy(mesh->offset, cloud->offset, sizeof mesh->offset);
            for (size_t i = 0; i < cloud->count; i++) {
                uint32_t j = map[i];
                if (j == TESSEL_NONE)
                    continue;
                memcpy(mesh->xyz + 3 * (size_t)j, cloud->xyz + 3 * i, 3 * sizeof(float));
                if (cloud->normals)
                    memcpy(mesh->normals + 3 * (size_t)j, cloud->normals + 3 * i,
                           3 * sizeof(float));
                if (cloud->rgb)
                    memcpy(mesh->rgb + 3 * (size_t)j, cloud->rgb + 3 * i, 3);
            }
            for (size_t k = 0; k < 3 * col.count; k++)
                mesh->triangles[k] = map[col.tris[k]];
        }
    }
    free(map);
    free(col.tris);
    return status;
}
