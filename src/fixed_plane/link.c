/* The triangulator of the fixed-plane modes (Gopi & Krishnan 2002,
 * section 5): each 2x2 block of adjacent dexels gets its shorter diagonal
 * and keeps a triangle when its three edges pass the sphere-of-influence
 * test (see tessel.h) and it faces the right way seen along the
 * projection direction. The block codes are the hot loop: a row's common
 * case is computed without branches, the rest block by block. */
#include "fixed_plane/fixed_plane.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* The dexel array and the edge test                                         */
/* ------------------------------------------------------------------------ */

void tsl_fp_row(const fp_ctx *x, uint32_t r, fp_vrec *out)
{
    const uint32_t *row = x->idx + (size_t)r * x->w;
    for (uint32_t c = 0; c < x->w; c++) {
        fp_vrec *v = &out[c];
        uint32_t i = row[c];
        v->ok = 0;
        if (i == TESSEL_NONE)
            continue;
        const float *p = x->xyz + 3 * (size_t)i;
        v->p[0] = p[0];
        v->p[1] = p[1];
        v->p[2] = p[2];
        if (x->kind == FP_RAY) {
            float dx = p[0] - x->vp[0], dy = p[1] - x->vp[1], dz = p[2] - x->vp[2];
            float rng = sqrtf(dx * dx + dy * dy + dz * dz);
            if (!(rng > 0.0f) || !(rng < FLT_MAX))
                continue;
            float inv = 1.0f / rng;
            v->d[0] = dx * inv;
            v->d[1] = dy * inv;
            v->d[2] = dz * inv;
            v->w = rng;
        } else {
            float hgt = x->dir[0] * p[0] + x->dir[1] * p[1] + x->dir[2] * p[2];
            if (!(fabsf(hgt) < FLT_MAX))
                continue;
            v->w = hgt;
        }
        v->ok = 1;
    }
}

/* The sphere-of-influence test of tessel.h; both entries valid. Writes the
 * squared length. */
int tsl_fp_edge(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b, float *len2)
{
    float dx = a->p[0] - b->p[0], dy = a->p[1] - b->p[1], dz = a->p[2] - b->p[2];
    float l2 = dx * dx + dy * dy + dz * dz;
    float s2;
    if (x->kind == FP_RAY) {
        float ex = a->d[0] - b->d[0], ey = a->d[1] - b->d[1], ez = a->d[2] - b->d[2];
        float rm = a->w < b->w ? a->w : b->w;
        s2 = rm * rm * (ex * ex + ey * ey + ez * ez);
    } else {
        float dh = a->w - b->w;
        s2 = l2 - dh * dh;
    }
    *len2 = l2;
    return l2 <= x->reach2 * s2 + x->margin2;
}

/* A triangle (in the array's counter-clockwise order) is kept when it
 * faces the expected way seen along the projection direction; zero area
 * (exactly, from float inputs) counts as flipped. The sign of
 * ((b - a) x (c - a)) . w, with w the plane normal or the direction to the
 * viewpoint, in double: the differences of floats and their products are
 * exact there, so a zero cross product is a true zero. */
static int fp_facing_exact(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b,
                           const fp_vrec *c)
{
    double e1[3] = {(double)b->p[0] - a->p[0], (double)b->p[1] - a->p[1],
                    (double)b->p[2] - a->p[2]};
    double e2[3] = {(double)c->p[0] - a->p[0], (double)c->p[1] - a->p[1],
                    (double)c->p[2] - a->p[2]};
    double n[3];
    tsl_cross(e1, e2, n);
    if (n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0)
        return 0;
    double s;
    if (x->kind == FP_RAY)
        s = n[0] * ((double)x->vp[0] - a->p[0]) + n[1] * ((double)x->vp[1] - a->p[1]) +
            n[2] * ((double)x->vp[2] - a->p[2]);
    else
        s = n[0] * x->dir[0] + n[1] * x->dir[1] + n[2] * x->dir[2];
    return x->orient > 0 ? s > 0.0 : s < 0.0;
}

/* Whether p lies in the closed triangle (a, b, c), a facing one, seen along
 * the projection direction: no edge has p strictly on its outer side. */
static int fp_covers(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b, const fp_vrec *c,
                     const fp_vrec *p)
{
    return !fp_facing_exact(x, b, a, p) && !fp_facing_exact(x, c, b, p) &&
           !fp_facing_exact(x, a, c, p);
}

/* The same, first in float: when |s| exceeds 1e-5 of the sum of the
 * magnitudes of its terms (float rounding is below 1e-6 of it), the float
 * sign is the exact one; only near-degenerate triangles take the double
 * path. */
int tsl_fp_facing(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b,
                            const fp_vrec *c)
{
    float e1x = b->p[0] - a->p[0], e1y = b->p[1] - a->p[1], e1z = b->p[2] - a->p[2];
    float e2x = c->p[0] - a->p[0], e2y = c->p[1] - a->p[1], e2z = c->p[2] - a->p[2];
    float wx, wy, wz;
    if (x->kind == FP_RAY) {
        wx = x->vp[0] - a->p[0];
        wy = x->vp[1] - a->p[1];
        wz = x->vp[2] - a->p[2];
    } else {
        wx = x->dir[0];
        wy = x->dir[1];
        wz = x->dir[2];
    }
    float ax = e1y * e2z, bx = e1z * e2y, ay = e1z * e2x, by = e1x * e2z;
    float az = e1x * e2y, bz = e1y * e2x;
    float sv = (ax - bx) * wx + (ay - by) * wy + (az - bz) * wz;
    float mag = fabsf(wx) * (fabsf(ax) + fabsf(bx)) + fabsf(wy) * (fabsf(ay) + fabsf(by)) +
                fabsf(wz) * (fabsf(az) + fabsf(bz));
    if (fabsf(sv) > 1e-5f * mag)
        return x->orient > 0 ? sv > 0.0f : sv < 0.0f;
    return fp_facing_exact(x, a, b, c);
}

static uint8_t fp_block(const fp_ctx *x, const fp_vrec *A, const fp_vrec *B,
                        const fp_vrec *C, const fp_vrec *D, int ab, int cd, int ac, int bd,
                        fp_counts *cnt)
{
    unsigned have = A->ok + B->ok + C->ok + D->ok;
    if (have < 3) {
        cnt->missing++;
        return 0;
    }
    float l_ad = 0, l_bc = 0;
    unsigned code = 0, want, made = 0, edges_fail = 0;
    if (have == 4) {
        int ok_ad = tsl_fp_edge(x, A, D, &l_ad), ok_bc = tsl_fp_edge(x, B, C, &l_bc);
        want = 2;
        /* The shorter diagonal; the other one when it makes more triangles
         * (a quad that is not convex in projection folds on one diagonal). */
        unsigned try_first = ok_ad && (!ok_bc || l_ad <= l_bc) ? 0u : 1u;
        unsigned best_code = 0, best_made = 0, best_fail = 1, best_folded = 0, tried = 0;
        for (unsigned k = 0; k < 2; k++) {
            unsigned d = k == 0 ? try_first : 1u - try_first;
            if (!(d == 0 ? ok_ad : ok_bc))
                continue;
            unsigned cc = d, fail = 0, folded = 0;
            int e0 = d == 0 ? ab && bd : ab && ac;
            int e1 = d == 0 ? cd && ac : bd && cd;
            if (e0) {
                if (d == 0 ? tsl_fp_facing(x, A, B, D) : tsl_fp_facing(x, A, B, C))
                    cc |= FP_T0;
                else
                    folded++;
            }
            if (e1) {
                if (d == 0 ? tsl_fp_facing(x, A, D, C) : tsl_fp_facing(x, B, D, C))
                    cc |= FP_T1;
                else
                    folded++;
            }
            fail = !e0 || !e1;
            unsigned nm = ((cc & FP_T0) != 0) + ((cc & FP_T1) != 0);
            if (!tried++ || nm > best_made) {
                best_code = cc;
                best_made = nm;
                best_fail = fail;
                best_folded = folded;
            }
            if (nm == 2)
                break;
        }
        code = best_code;
        edges_fail = best_fail;
        cnt->folded += best_folded;
        /* One triangle of the quad: the fourth point, which other blocks'
         * triangles use, must lie outside it, or those triangles would
         * overlap it seen along the projection direction (a quad folded at
         * that point whose other diagonal failed the edge test). */
        if (best_made == 1) {
            int t0 = (code & FP_T0) != 0;
            int inside = code & FP_DIAG_BC
                             ? (t0 ? fp_covers(x, A, B, C, D) : fp_covers(x, B, D, C, A))
                             : (t0 ? fp_covers(x, A, B, D, C) : fp_covers(x, A, D, C, B));
            if (inside) {
                code &= (unsigned)~(FP_T0 | FP_T1);
                cnt->folded++;
            }
        }
    } else {
        want = 1;
        int e;
        if (!D->ok) {
            code = FP_DIAG_BC;
            e = ab && ac && tsl_fp_edge(x, B, C, &l_bc);
            if (e && tsl_fp_facing(x, A, B, C))
                code |= FP_T0;
            else if (e)
                cnt->folded++;
        } else if (!A->ok) {
            code = FP_DIAG_BC;
            e = bd && cd && tsl_fp_edge(x, B, C, &l_bc);
            if (e && tsl_fp_facing(x, B, D, C))
                code |= FP_T1;
            else if (e)
                cnt->folded++;
        } else if (!B->ok) {
            e = cd && ac && tsl_fp_edge(x, A, D, &l_ad);
            if (e && tsl_fp_facing(x, A, D, C))
                code |= FP_T1;
            else if (e)
                cnt->folded++;
        } else {
            e = ab && bd && tsl_fp_edge(x, A, D, &l_ad);
            if (e && tsl_fp_facing(x, A, B, D))
                code |= FP_T0;
            else if (e)
                cnt->folded++;
        }
        edges_fail = !e;
    }
    made = ((code & FP_T0) != 0) + ((code & FP_T1) != 0);
    if (edges_fail && made < want)
        cnt->open++;
    return (uint8_t)code;
}

tessel_status tsl_fp_scratch_alloc(fp_scratch *sc, uint32_t w)
{
    size_t n = (size_t)w + 1;
    memset(sc, 0, sizeof *sc);
    /* 2 rows x 8 arrays + 4 edge arrays, 4 bytes each */
    sc->mem = tsl_alloc_array(n, (2 * 8 + 4) * sizeof(float));
    if (!sc->mem)
        return TESSEL_ERR_NOMEM;
    float *f = sc->mem;
    for (int k = 0; k < 2; k++) {
        fp_soa *r = &sc->row[k];
        r->px = f, f += n;
        r->py = f, f += n;
        r->pz = f, f += n;
        r->dx = f, f += n;
        r->dy = f, f += n;
        r->dz = f, f += n;
        r->w = f, f += n;
        r->ok = (int32_t *)f, f += n;
    }
    sc->hk[0] = (int32_t *)f, f += n;
    sc->hk[1] = (int32_t *)f, f += n;
    sc->vk = (int32_t *)f, f += n;
    sc->len2 = f;
    return TESSEL_OK;
}

/* Loads array row r: positions, and directions and ranges (ray) or heights
 * (plane). Missing or unusable points have ok = 0 and zero coordinates. */
static void fp_soa_row(const fp_ctx *x, uint32_t r, fp_soa *o)
{
    const uint32_t w = x->w;
    const uint32_t *row = x->idx + (size_t)r * w;
    float *restrict px = o->px, *restrict py = o->py, *restrict pz = o->pz;
    float *restrict dx = o->dx, *restrict dy = o->dy, *restrict dz = o->dz, *restrict ww = o->w;
    int32_t *restrict ok = o->ok;
    for (uint32_t c = 0; c < w; c++) {
        uint32_t i = row[c];
        if (i == TESSEL_NONE) {
            px[c] = py[c] = pz[c] = 0.0f;
            ok[c] = 0;
            continue;
        }
        const float *p = x->xyz + 3 * (size_t)i;
        px[c] = p[0];
        py[c] = p[1];
        pz[c] = p[2];
        ok[c] = 1;
    }
    if (x->kind == FP_RAY) {
        const float vx = x->vp[0], vy = x->vp[1], vz = x->vp[2];
        for (uint32_t c = 0; c < w; c++) {
            float ex = px[c] - vx, ey = py[c] - vy, ez = pz[c] - vz;
            float rr = sqrtf(ex * ex + ey * ey + ez * ez);
            int good = ok[c] & (rr > 0.0f) & (rr < FLT_MAX);
            float inv = good ? 1.0f / rr : 0.0f;
            dx[c] = ex * inv;
            dy[c] = ey * inv;
            dz[c] = ez * inv;
            ww[c] = good ? rr : 0.0f;
            ok[c] = good;
        }
    } else {
        const float nx = x->dir[0], ny = x->dir[1], nz = x->dir[2];
        for (uint32_t c = 0; c < w; c++) {
            float h = nx * px[c] + ny * py[c] + nz * pz[c];
            int good = ok[c] & (fabsf(h) < FLT_MAX);
            dx[c] = dy[c] = dz[c] = 0.0f;
            ww[c] = good ? h : 0.0f;
            ok[c] = good;
        }
    }
    if (x->wrap_c) {
        px[w] = px[0], py[w] = py[0], pz[w] = pz[0];
        dx[w] = dx[0], dy[w] = dy[0], dz[w] = dz[0];
        ww[w] = ww[0], ok[w] = ok[0];
    }
}

/* out[i] = the edge test between entry oa + i of row a and ob + i of row
 * b (both present), for i < n; len2[i] its squared length. */
static void fp_soa_edges(const fp_ctx *x, const fp_soa *a, size_t oa, const fp_soa *b,
                         size_t ob, size_t n, int32_t *restrict out, float *restrict len2)
{
    const float *restrict apx = a->px + oa, *restrict apy = a->py + oa, *restrict apz = a->pz + oa;
    const float *restrict bpx = b->px + ob, *restrict bpy = b->py + ob, *restrict bpz = b->pz + ob;
    const float *restrict aw = a->w + oa, *restrict bw = b->w + ob;
    const int32_t *restrict aok = a->ok + oa, *restrict bok = b->ok + ob;
    const float reach2 = x->reach2, margin2 = x->margin2;
    if (x->kind == FP_RAY) {
        const float *restrict adx = a->dx + oa, *restrict ady = a->dy + oa,
                              *restrict adz = a->dz + oa;
        const float *restrict bdx = b->dx + ob, *restrict bdy = b->dy + ob,
                              *restrict bdz = b->dz + ob;
        for (size_t i = 0; i < n; i++) {
            float ex = apx[i] - bpx[i], ey = apy[i] - bpy[i], ez = apz[i] - bpz[i];
            float l2 = ex * ex + ey * ey + ez * ez;
            float fx = adx[i] - bdx[i], fy = ady[i] - bdy[i], fz = adz[i] - bdz[i];
            float rm = aw[i] < bw[i] ? aw[i] : bw[i];
            float s2 = rm * rm * (fx * fx + fy * fy + fz * fz);
            out[i] = (l2 <= reach2 * s2 + margin2) & aok[i] & bok[i];
            len2[i] = l2;
        }
    } else {
        for (size_t i = 0; i < n; i++) {
            float ex = apx[i] - bpx[i], ey = apy[i] - bpy[i], ez = apz[i] - bpz[i];
            float l2 = ex * ex + ey * ey + ez * ez;
            float dh = aw[i] - bw[i];
            float s2 = l2 - dh * dh;
            out[i] = (l2 <= reach2 * s2 + margin2) & aok[i] & bok[i];
            len2[i] = l2;
        }
    }
}

/* Facing value (((b - a) x (c - a)) . w) against the magnitude bound of
 * tsl_fp_facing(): 1 when surely facing. ray is a constant at each call, so
 * the row kernel has no branch. */
static inline int32_t fp_facing_sure(int ray, const float v[3], float orient, float ax,
                                     float ay, float az, float bx, float by, float bz, float cx,
                                     float cy, float cz)
{
    float e1x = bx - ax, e1y = by - ay, e1z = bz - az;
    float e2x = cx - ax, e2y = cy - ay, e2z = cz - az;
    float wx = ray ? v[0] - ax : v[0], wy = ray ? v[1] - ay : v[1], wz = ray ? v[2] - az : v[2];
    float p1 = e1y * e2z, q1 = e1z * e2y, p2 = e1z * e2x, q2 = e1x * e2z;
    float p3 = e1x * e2y, q3 = e1y * e2x;
    float sv = ((p1 - q1) * wx + (p2 - q2) * wy + (p3 - q3) * wz) * orient;
    float mag = fabsf(wx) * (fabsf(p1) + fabsf(q1)) + fabsf(wy) * (fabsf(p2) + fabsf(q2)) +
                fabsf(wz) * (fabsf(p3) + fabsf(q3));
    return sv > 1e-5f * mag;
}

/* The edge test of fp_soa_edges() for the row kernel: a and b are the two
 * ends' (x, y, z, dx, dy, dz, w) and ok; writes the squared length. */
static inline int32_t fp_edge_v(int ray, float reach2, float margin2, const float a[7],
                                int32_t aok, const float b[7], int32_t bok, float *len2)
{
    float ex = a[0] - b[0], ey = a[1] - b[1], ez = a[2] - b[2];
    float l2 = ex * ex + ey * ey + ez * ez, s2;
    if (ray) {
        float fx = a[3] - b[3], fy = a[4] - b[4], fz = a[5] - b[5];
        float rm = a[6] < b[6] ? a[6] : b[6];
        s2 = rm * rm * (fx * fx + fy * fy + fz * fz);
    } else {
        float dh = a[6] - b[6];
        s2 = l2 - dh * dh;
    }
    *len2 = l2;
    return (l2 <= reach2 * s2 + margin2) & aok & bok;
}

/* The common case of a row of blocks (see above); 0xff marks the others. */
static inline void fp_row_kernel(int ray, const float v[3], float orient, float reach2,
                                 float margin2, uint32_t cw, const fp_soa *T, const fp_soa *B,
                                 const int32_t *restrict vk, const int32_t *restrict hkt,
                                 const int32_t *restrict hkb, uint8_t *restrict out)
{
    const float *restrict tx = T->px, *restrict ty = T->py, *restrict tz = T->pz;
    const float *restrict tdx = T->dx, *restrict tdy = T->dy, *restrict tdz = T->dz;
    const float *restrict tw = T->w;
    const int32_t *restrict tok = T->ok;
    const float *restrict bx = B->px, *restrict by = B->py, *restrict bz = B->pz;
    const float *restrict bdx = B->dx, *restrict bdy = B->dy, *restrict bdz = B->dz;
    const float *restrict bw = B->w;
    const int32_t *restrict bok = B->ok;
    for (uint32_t c = 0; c < cw; c++) {
        const float A[7] = {tx[c], ty[c], tz[c], tdx[c], tdy[c], tdz[c], tw[c]};
        const float Bq[7] = {tx[c + 1],  ty[c + 1],  tz[c + 1], tdx[c + 1],
                             tdy[c + 1], tdz[c + 1], tw[c + 1]};
        const float C[7] = {bx[c], by[c], bz[c], bdx[c], bdy[c], bdz[c], bw[c]};
        const float D[7] = {bx[c + 1],  by[c + 1],  bz[c + 1], bdx[c + 1],
                            bdy[c + 1], bdz[c + 1], bw[c + 1]};
        float adl, bcl;
        int32_t adk = fp_edge_v(ray, reach2, margin2, A, tok[c], D, bok[c + 1], &adl);
        int32_t bck = fp_edge_v(ray, reach2, margin2, Bq, tok[c + 1], C, bok[c], &bcl);
        int32_t d = 1 - (adk & ((1 - bck) | (adl <= bcl)));
        int32_t dok = d ? bck : adk;
        int32_t e0 = hkt[c] & (d ? vk[c] : vk[c + 1]);
        int32_t e1 = hkb[c] & (d ? vk[c + 1] : vk[c]);
        /* t0 = (A, B, d ? C : D), t1 = (d ? B : A, D, C) */
        float Xx = d ? C[0] : D[0], Xy = d ? C[1] : D[1], Xz = d ? C[2] : D[2];
        float Yx = d ? Bq[0] : A[0], Yy = d ? Bq[1] : A[1], Yz = d ? Bq[2] : A[2];
        int32_t f0 = fp_facing_sure(ray, v, orient, A[0], A[1], A[2], Bq[0], Bq[1], Bq[2], Xx,
                                    Xy, Xz);
        int32_t f1 = fp_facing_sure(ray, v, orient, Yx, Yy, Yz, D[0], D[1], D[2], C[0], C[1],
                                    C[2]);
        int32_t fast = dok & e0 & e1 & f0 & f1;
        out[c] = fast ? (uint8_t)(d | FP_T0 | FP_T1) : (uint8_t)0xff;
    }
}

static inline fp_vrec fp_soa_get(const fp_soa *s, size_t c)
{
    fp_vrec v = {{s->px[c], s->py[c], s->pz[c]}, {s->dx[c], s->dy[c], s->dz[c]}, s->w[c],
                 (uint32_t)s->ok[c]};
    return v;
}

/* Codes of block rows [r0, r1), loading each array row once. */
void tsl_fp_codes_rows(const fp_ctx *x, uint32_t r0, uint32_t r1, uint8_t *codes,
                          fp_scratch *sc, fp_counts *cnt)
{
    const uint32_t w = x->w, cw = x->cw;
    const size_t nv = (size_t)w + (x->wrap_c ? 1 : 0); /* vertical edges incl. wrap copy */
    int cur = 0;
    fp_soa_row(x, r0, &sc->row[cur]);
    fp_soa_edges(x, &sc->row[cur], 0, &sc->row[cur], 1, cw, sc->hk[cur], sc->len2);
    for (uint32_t r = r0; r < r1; r++) {
        const fp_soa *T = &sc->row[cur], *B = &sc->row[cur ^ 1];
        fp_soa_row(x, r + 1 == x->h ? 0 : r + 1, &sc->row[cur ^ 1]);
        fp_soa_edges(x, B, 0, B, 1, cw, sc->hk[cur ^ 1], sc->len2);
        fp_soa_edges(x, T, 0, B, 0, nv, sc->vk, sc->len2);
        const int32_t *hkt = sc->hk[cur], *hkb = sc->hk[cur ^ 1];
        uint8_t *out = codes + (size_t)r * cw;
        if (x->kind == FP_RAY)
            fp_row_kernel(1, x->vp, (float)x->orient, x->reach2, x->margin2, cw, T, B, sc->vk,
                          hkt, hkb, out);
        else
            fp_row_kernel(0, x->dir, (float)x->orient, x->reach2, x->margin2, cw, T, B, sc->vk,
                          hkt, hkb, out);
        /* The rest, one block at a time. */
        for (uint32_t c = 0; c < cw; c++) {
            if (out[c] != 0xff)
                continue;
            fp_vrec A = fp_soa_get(T, c), Bv = fp_soa_get(T, c + 1), C = fp_soa_get(B, c),
                    D = fp_soa_get(B, c + 1);
            out[c] = fp_block(x, &A, &Bv, &C, &D, hkt[c], hkb[c], sc->vk[c], sc->vk[c + 1], cnt);
        }
        cur ^= 1;
    }
}
