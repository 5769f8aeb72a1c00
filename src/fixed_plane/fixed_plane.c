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
#include "core/core.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#define FP_PI 3.14159265358979323846

/* Points sampled for the frame (PCA), the automatic cell and the noise. */
#define FP_SAMPLE 65536u
/* Triangles per sink call. */
#define FP_BATCH 16384u
/* Rows per parallel block (progress is reported between blocks). */
#define FP_BLOCK_ROWS 64u

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
/* The dexel array and the edge test                                         */
/* ------------------------------------------------------------------------ */

enum { FP_PLANE = 0, FP_RAY = 1 };

typedef struct fp_ctx {
    const float *xyz;
    uint32_t w, h;           /* array columns, rows */
    const uint32_t *idx;     /* w*h point indices or TESSEL_NONE */
    int wrap_c, wrap_r;      /* last column (row) adjacent to the first */
    uint32_t cw, ch;         /* blocks per row, block rows */
    int kind;                /* FP_PLANE or FP_RAY */
    float dir[3];            /* FP_PLANE: unit normal of the plane */
    float vp[3];             /* FP_RAY: viewpoint in the local frame */
    float reach2;            /* 1 / cos^2(max_angle) */
    float margin2;
    int orient;              /* sign of the facing test for (A, B, D) order */
    int threads;
} fp_ctx;

/* One array entry with what the edge test needs. */
typedef struct fp_vrec {
    float p[3];
    float d[3];              /* FP_RAY: unit direction from the viewpoint */
    float w;                 /* FP_PLANE: height; FP_RAY: range */
    uint32_t ok;             /* a usable point */
} fp_vrec;

static void fp_row(const fp_ctx *x, uint32_t r, fp_vrec *out)
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
static inline int fp_edge(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b, float *len2)
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
static inline int fp_facing(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b,
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

/* Block codes: bit 0 the diagonal (0: A-D, 1: B-C), bit 1 triangle t0,
 * bit 2 triangle t1, with corners A (r, c), B (r, c+1), C (r+1, c),
 * D (r+1, c+1) and, counter-clockwise in (column, row):
 *   diagonal A-D: t0 = (A, B, D), t1 = (A, D, C)
 *   diagonal B-C: t0 = (A, B, C), t1 = (B, D, C). */
enum { FP_DIAG_BC = 1, FP_T0 = 2, FP_T1 = 4 };

typedef struct fp_counts {
    size_t missing, open, folded;
} fp_counts;

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
        int ok_ad = fp_edge(x, A, D, &l_ad), ok_bc = fp_edge(x, B, C, &l_bc);
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
                if (d == 0 ? fp_facing(x, A, B, D) : fp_facing(x, A, B, C))
                    cc |= FP_T0;
                else
                    folded++;
            }
            if (e1) {
                if (d == 0 ? fp_facing(x, A, D, C) : fp_facing(x, B, D, C))
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
            e = ab && ac && fp_edge(x, B, C, &l_bc);
            if (e && fp_facing(x, A, B, C))
                code |= FP_T0;
            else if (e)
                cnt->folded++;
        } else if (!A->ok) {
            code = FP_DIAG_BC;
            e = bd && cd && fp_edge(x, B, C, &l_bc);
            if (e && fp_facing(x, B, D, C))
                code |= FP_T1;
            else if (e)
                cnt->folded++;
        } else if (!B->ok) {
            e = cd && ac && fp_edge(x, A, D, &l_ad);
            if (e && fp_facing(x, A, D, C))
                code |= FP_T1;
            else if (e)
                cnt->folded++;
        } else {
            e = ab && bd && fp_edge(x, A, D, &l_ad);
            if (e && fp_facing(x, A, B, D))
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

/* The block codes are the hot loop (every point, every mode). Rows are
 * held as structures of arrays and the common case - four points, the
 * shorter diagonal passing, both triangles facing the right way by a clear
 * margin - is computed for a whole row in loops without branches, which
 * the compiler vectorizes; the other blocks go through fp_block(). */
typedef struct fp_soa {
    float *px, *py, *pz, *dx, *dy, *dz, *w;
    int32_t *ok;
} fp_soa;

/* Scratch of one thread: two rows (w + 1 entries: with wrapped columns,
 * entry w repeats entry 0) and the per-row edge tests. */
typedef struct fp_scratch {
    fp_soa row[2];
    int32_t *hk[2], *vk;
    float *len2;             /* lengths fp_soa_edges() writes, unused here */
    void *mem;
} fp_scratch;

static tessel_status fp_scratch_alloc(fp_scratch *sc, uint32_t w)
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
 * fp_facing(): 1 when surely facing. ray is a constant at each call, so
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
static void fp_codes_rows(const fp_ctx *x, uint32_t r0, uint32_t r1, uint8_t *codes,
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

/* ------------------------------------------------------------------------ */
/* Vertex manifoldness                                                       */
/* ------------------------------------------------------------------------ */

/* The link of a vertex runs through its 8 array neighbours E, SE, S, SW, W,
 * NW, N, NE (positions 0..7, rows growing "south"); segment k joins
 * positions k and k+1. The four blocks around the vertex are quadrant
 * q = 0 (block to the SE, the vertex is its A corner), 1 (SW, B corner),
 * 2 (NW, D corner), 3 (NE, C corner); quadrant q covers segments 2q and
 * 2q+1. fp_seg[q][t][diag] is the 2-bit set of those segments that
 * triangle t (0: t0, 1: t1) of a block with that diagonal covers. */
static const uint8_t fp_seg[4][2][2] = {
    /* A corner: AD: t0 B-D (seg 0), t1 D-C (seg 1); BC: t0 B-C (both) */
    {{1, 2}, {3, 0}},
    /* B corner: AD: t0 A-D (both); BC: t0 A-C (seg 3), t1 D-C (seg 2) */
    {{3, 0}, {2, 1}},
    /* D corner: AD: t0 A-B (seg 5), t1 A-C (seg 4); BC: t1 B-C (both) */
    {{2, 1}, {0, 3}},
    /* C corner: AD: t1 A-D (both); BC: t0 A-B (seg 6), t1 B-D (seg 7) */
    {{0, 3}, {1, 2}},
};

/* Block (row, column) of quadrant q of vertex (r, c), or SIZE_MAX. */
static size_t fp_quad_block(const fp_ctx *x, uint32_t r, uint32_t c, int q)
{
    int64_t br = (q == 0 || q == 1) ? (int64_t)r : (int64_t)r - 1;
    int64_t bc = (q == 0 || q == 3) ? (int64_t)c : (int64_t)c - 1;
    if (br < 0) {
        if (!x->wrap_r)
            return SIZE_MAX;
        br += x->h;
    }
    if (bc < 0) {
        if (!x->wrap_c)
            return SIZE_MAX;
        bc += x->w;
    }
    if ((uint64_t)br >= x->ch || (uint64_t)bc >= x->cw)
        return SIZE_MAX;
    return (size_t)br * x->cw + (size_t)bc;
}

static unsigned fp_link_mask(const fp_ctx *x, const uint8_t *codes, uint32_t r, uint32_t c)
{
    unsigned m = 0;
    for (int q = 0; q < 4; q++) {
        size_t b = fp_quad_block(x, r, c, q);
        if (b == SIZE_MAX)
            continue;
        unsigned code = codes[b], diag = code & 1;
        if (code & FP_T0)
            m |= (unsigned)fp_seg[q][diag][0] << (2 * q);
        if (code & FP_T1)
            m |= (unsigned)fp_seg[q][diag][1] << (2 * q);
    }
    return m;
}

static unsigned fp_rotl8(unsigned m) { return ((m << 1) | (m >> 7)) & 0xffu; }

/* Number of separate fans in a link mask. */
static int fp_fans(unsigned m)
{
    if (m == 0xffu)
        return 1;
    unsigned starts = m & ~fp_rotl8(m);
    int n = 0;
    for (; starts; starts &= starts - 1)
        n++;
    return n;
}

typedef struct fp_stack {
    uint64_t *v;
    size_t n, cap;
} fp_stack;

/* The vertex of corner k (0 A, 1 B, 2 C, 3 D) of block b. */
static uint64_t fp_corner(const fp_ctx *x, size_t b, int k)
{
    uint32_t r = (uint32_t)(b / x->cw), c = (uint32_t)(b % x->cw);
    if (k & 1)
        c = c + 1 == x->w ? 0 : c + 1;
    if (k & 2)
        r = r + 1 == x->h ? 0 : r + 1;
    return (uint64_t)r * x->w + c;
}

/* Corners of the triangles: [diag][t] -> three corner numbers. */
static const int fp_tri_corners[2][2][3] = {
    {{0, 1, 3}, {0, 3, 2}},
    {{0, 1, 2}, {1, 3, 2}},
};

/* Keeps the largest fan of vertex (r, c) (ties: the first from E going
 * round), removes the triangles of the others and pushes their other
 * vertices, which may have lost their own single fan. */
static tessel_status fp_fix_vertex(const fp_ctx *x, uint8_t *codes, uint32_t r, uint32_t c,
                                   fp_stack *st, size_t *removed)
{
    unsigned m = fp_link_mask(x, codes, r, c);
    if (fp_fans(m) < 2)
        return TESSEL_OK;
    unsigned starts = m & ~fp_rotl8(m), keep = 0;
    int best = -1;
    for (int s = 0; s < 8; s++) {
        if (!(starts >> s & 1u))
            continue;
        unsigned run = 0;
        int len = 0;
        for (int k = s; (m >> (k & 7) & 1u) && len < 8; k++, len++)
            run |= 1u << (k & 7);
        if (len > best) {
            best = len;
            keep = run;
        }
    }
    unsigned drop = m & ~keep;
    uint64_t self = (uint64_t)r * x->w + c;
    for (int q = 0; q < 4; q++) {
        unsigned local = (drop >> (2 * q)) & 3u;
        if (!local)
            continue;
        size_t b = fp_quad_block(x, r, c, q);
        unsigned code = codes[b], diag = code & 1;
        for (int t = 0; t < 2; t++) {
            unsigned bit = t ? FP_T1 : FP_T0;
            if (!(code & bit) || !(fp_seg[q][diag][t] & local))
                continue;
            code &= ~bit;
            (*removed)++;
            for (int k = 0; k < 3; k++) {
                uint64_t v = fp_corner(x, b, fp_tri_corners[diag][t][k]);
                if (v == self)
                    continue;
                if (tsl_grow((void **)&st->v, &st->cap, st->n + 1, sizeof *st->v) != TESSEL_OK)
                    return TESSEL_ERR_NOMEM;
                st->v[st->n++] = v;
            }
        }
        codes[b] = (uint8_t)code;
    }
    return TESSEL_OK;
}

static tessel_status fp_make_manifold(const fp_ctx *x, uint8_t *codes, size_t *removed)
{
    uint8_t *bad = tsl_calloc_array(x->h, 1);
    if (!bad)
        return TESSEL_ERR_NOMEM;
    int nt = x->threads;
    (void)nt;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (int64_t r = 0; r < (int64_t)x->h; r++) {
        /* Block rows above and below the vertex row; a vertex whose four
         * blocks hold both their triangles has a closed fan. */
        const uint8_t *up = r > 0 ? codes + (size_t)(r - 1) * x->cw
                            : x->wrap_r ? codes + (size_t)(x->ch - 1) * x->cw
                                        : NULL;
        const uint8_t *dn = (uint64_t)r < x->ch ? codes + (size_t)r * x->cw : NULL;
        for (uint32_t c = 0; c < x->w; c++) {
            if (up && dn && c >= 1 && c < x->cw &&
                ((up[c - 1] & up[c] & dn[c - 1] & dn[c]) & (FP_T0 | FP_T1)) == (FP_T0 | FP_T1))
                continue;
            if (fp_fans(fp_link_mask(x, codes, (uint32_t)r, c)) > 1) {
                bad[r] = 1;
                break;
            }
        }
    }
    /* Fixes in raster order, each followed by its cascade: the result does
     * not depend on the thread count. */
    fp_stack st = {NULL, 0, 0};
    tessel_status status = TESSEL_OK;
    for (uint32_t r = 0; r < x->h && status == TESSEL_OK; r++) {
        if (!bad[r])
            continue;
        for (uint32_t c = 0; c < x->w && status == TESSEL_OK; c++) {
            status = fp_fix_vertex(x, codes, r, c, &st, removed);
            while (status == TESSEL_OK && st.n > 0) {
                uint64_t v = st.v[--st.n];
                status = fp_fix_vertex(x, codes, (uint32_t)(v / x->w), (uint32_t)(v % x->w),
                                       &st, removed);
            }
        }
    }
    free(st.v);
    free(bad);
    return status;
}

/* ------------------------------------------------------------------------ */
/* Filled dexels: no overlap in projection                                   */
/* ------------------------------------------------------------------------ */

/* 2D coordinates of a point seen along the projection direction: the
 * plane coordinates (height), or the gnomonic projection about the
 * direction axis (ray), which maps the straight edges of triangles seen
 * from the viewpoint to straight lines. */
typedef struct fp_proj {
    double o[3], e1[3], e2[3], ax[3];
    int ray;
} fp_proj;

static void fp_project(const fp_proj *pr, const float *p, double out[2])
{
    double d[3] = {p[0] - pr->o[0], p[1] - pr->o[1], p[2] - pr->o[2]};
    double a = tsl_dot(d, pr->e1), b = tsl_dot(d, pr->e2);
    if (pr->ray) {
        double z = tsl_dot(d, pr->ax);
        z = z > 1e-30 ? z : 1e-30;
        a /= z;
        b /= z;
    }
    out[0] = a;
    out[1] = b;
}

/* Interiors of two counter-clockwise triangles overlap: no edge of either
 * separates them (touching along shared vertices or edges is allowed). */
static int fp_overlap2(const double a[3][2], const double b[3][2])
{
    for (int pass = 0; pass < 2; pass++) {
        const double(*p)[2] = pass ? b : a, (*q)[2] = pass ? a : b;
        double scale = 0;
        for (int k = 0; k < 3; k++)
            scale = fmax(scale, fmax(fabs(p[k][0]), fabs(p[k][1])));
        for (int k = 0; k < 3; k++) {
            const double *u = p[k], *v = p[(k + 1) % 3];
            double nx = v[1] - u[1], ny = u[0] - v[0]; /* outward normal */
            double len = fabs(nx) + fabs(ny);
            double lim = u[0] * nx + u[1] * ny - 1e-12 * len * scale;
            int sep = 1;
            for (int j = 0; j < 3 && sep; j++)
                sep = q[j][0] * nx + q[j][1] * ny >= lim;
            if (sep)
                return 0;
        }
    }
    return 1;
}

/* Two triangles meet in space beyond their shared vertices or edge: a
 * triangle that only touches another in projection can still do that, as
 * when its edge runs along part of the other's (a T-junction; on lattice
 * data the filled point can lie exactly on a neighbour's edge). Exact; both
 * triangles passed the facing test, so neither is degenerate. */
static int fp_meet3(const uint32_t ia[3], const double pa[3][3], const uint32_t ib[3],
                    const double pb[3][3])
{
    for (int k = 0; k < 3; k++) {
        double lo = fmin(pa[0][k], fmin(pa[1][k], pa[2][k]));
        double hi = fmax(pa[0][k], fmax(pa[1][k], pa[2][k]));
        if (fmax(pb[0][k], fmax(pb[1][k], pb[2][k])) < lo ||
            fmin(pb[0][k], fmin(pb[1][k], pb[2][k])) > hi)
            return 0;
    }
    const double *qa[3] = {pa[0], pa[1], pa[2]}, *qb[3] = {pb[0], pb[1], pb[2]};
    return tsl_triangles_intersect(ia, qa, ib, qb);
}

/* The triangles of the blocks round each filled dexel that use its point
 * are dropped when they overlap another triangle in projection or meet it
 * in space beyond shared vertices and edges. */
static void fp_untangle(const fp_ctx *x, uint8_t *codes, const uint32_t *slots, size_t n,
                        size_t *dropped)
{
    enum { R = 2, MAXT = 2 * (2 * R + 1) * (2 * R + 1) };
    for (size_t s = 0; s < n; s++) {
        uint32_t r = slots[s] / x->w, c = slots[s] % x->w;
        uint32_t pidx = x->idx[slots[s]];
        fp_proj pr;
        memset(&pr, 0, sizeof pr);
        const float *pp = x->xyz + 3 * (size_t)pidx;
        double ax[3];
        if (x->kind == FP_RAY) {
            pr.ray = 1;
            for (int k = 0; k < 3; k++) {
                pr.o[k] = x->vp[k];
                ax[k] = pp[k] - x->vp[k];
            }
        } else {
            for (int k = 0; k < 3; k++)
                ax[k] = x->dir[k];
        }
        if (!tsl_normalize(ax))
            continue;
        memcpy(pr.ax, ax, sizeof ax);
        double t[3] = {1, 0, 0};
        if (fabs(ax[0]) > 0.6)
            t[0] = 0, t[1] = 1;
        tsl_cross(ax, t, pr.e2);
        tsl_normalize(pr.e2);
        tsl_cross(pr.e2, ax, pr.e1); /* e1 x e2 = ax */
        if (pr.ray) /* counter-clockwise as seen from the viewpoint */
            for (int k = 0; k < 3; k++)
                pr.e1[k] = -pr.e1[k];
        size_t blk[MAXT];
        int tt[MAXT], mine[MAXT];
        double pt[MAXT][3][2], p3[MAXT][3][3];
        uint32_t ids[MAXT][3];
        int nt = 0;
        for (int dr = -R; dr <= R; dr++) {
            for (int dc = -R; dc <= R; dc++) {
                int64_t br = (int64_t)r + dr, bc = (int64_t)c + dc;
                if (br < 0 || br >= (int64_t)x->ch) {
                    if (!x->wrap_r)
                        continue;
                    br = (br + (int64_t)x->h) % (int64_t)x->h;
                }
                if (bc < 0 || bc >= (int64_t)x->cw) {
                    if (!x->wrap_c)
                        continue;
                    bc = (bc + (int64_t)x->w) % (int64_t)x->w;
                }
                size_t b = (size_t)br * x->cw + (size_t)bc;
                unsigned code = codes[b];
                for (int k = 0; k < 2; k++) {
                    if (!(code & (k ? FP_T1 : FP_T0)))
                        continue;
                    blk[nt] = b;
                    tt[nt] = k;
                    mine[nt] = 0;
                    for (int j = 0; j < 3; j++) {
                        uint64_t v = fp_corner(x, b, fp_tri_corners[code & 1][k][j]);
                        uint32_t i = x->idx[v];
                        mine[nt] |= i == pidx;
                        ids[nt][j] = i;
                        tsl_load(x->xyz + 3 * (size_t)i, p3[nt][j]);
                        /* counter-clockwise in the projection */
                        int jj = x->orient < 0 && j ? 3 - j : j;
                        fp_project(&pr, x->xyz + 3 * (size_t)i, pt[nt][jj]);
                    }
                    nt++;
                }
            }
        }
        for (int a = 0; a < nt; a++) {
            if (!mine[a])
                continue;
            for (int b = 0; b < nt; b++) {
                if (b == a || !(codes[blk[b]] & (tt[b] ? FP_T1 : FP_T0)))
                    continue;
                if (fp_overlap2(pt[a], pt[b]) || fp_meet3(ids[a], p3[a], ids[b], p3[b])) {
                    codes[blk[a]] &= (uint8_t)~(tt[a] ? FP_T1 : FP_T0);
                    (*dropped)++;
                    break;
                }
            }
        }
    }
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
        fp_row(x, r - 1, up);
        fp_row(x, r, mid);
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
        fp_row(x, r, a);
        fp_row(x, r + 1 == x->h ? 0 : r + 1, b);
        for (uint32_t c = 0; c < x->cw; c++) {
            uint32_t cn = c + 1 == x->w ? 0 : c + 1;
            if (!a[c].ok || !a[cn].ok || !b[cn].ok)
                continue;
            probe.orient = 1;
            if (fp_facing(&probe, &a[c], &a[cn], &b[cn]))
                vote++;
            else {
                probe.orient = -1;
                if (fp_facing(&probe, &a[c], &a[cn], &b[cn]))
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
                fp_row(&one, 0, &v[j]);
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

/* The 2D frame of the dexels: each point maps to (s, t) and a depth;
 * height: in-plane coordinates and height; range: (phi, theta) about the
 * pole and the range. */
typedef struct fp_frame {
    int kind;
    double e[3][3];          /* rows: first axis, second axis, normal / pole */
    double vp[3];            /* range: viewpoint, local frame */
    double phi0;             /* range: phi measured from here */
    int transpose;           /* range: (s, t) = (theta, phi) instead of
                                (phi, theta): see fp_scan_order() */
} fp_frame;

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
static void fp_height_frame(const tessel_cloud *cloud, int axis, fp_frame *f)
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
static void fp_range_frame(const tessel_cloud *cloud, const double vp[3], fp_frame *f,
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

/* A point in the dexel frame: first its map (s, t) and depth; once the
 * array is sized, its dexel and its position (u, v) inside it (0..65535
 * each way), computed once for the bucketing, the representatives and the
 * filling. The depth stays in place. */
typedef union fp_mapped {
    struct {
        float s, t, depth;
    } st;
    struct {
        uint32_t id;   /* dexel, TESSEL_NONE for an unmapped point */
        uint16_t u, v;
        float depth;
    } dx;
} fp_mapped;

/* Range: which way the input runs. A scanner delivers its points profile
 * by profile; when consecutive points mostly step in theta, the array is
 * stored with theta along its rows (s = theta, t = phi), so that bucketing
 * writes and reads memory nearly in order instead of jumping a whole row per
 * point (2-3x faster at 10^8 points). The dexels are the same either way;
 * only rules that go in raster order (filling, fan fixes) may pick
 * differently among ties. */
static void fp_scan_order(const tessel_cloud *cloud, fp_frame *f)
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

typedef struct fp_dexels {
    uint32_t w, h;
    int wrap_c, wrap_r;      /* range: phi runs along columns or rows */
    double cell[2];
    float lo[2];             /* corner of dexel (0, 0) */
    uint32_t *rep;
    size_t reps, filled;
    uint32_t *filled_slots;  /* the filled dexels, in raster order */
} fp_dexels;

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
 * projection: fp_untangle() checks them. */
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
static tessel_status fp_bucket(const fp_mapped *map, size_t n, fp_dexels *dx, int nt,
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
static void fp_assign(fp_mapped *map, size_t n, const fp_dexels *dx, int nt)
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
static tessel_status fp_size(const fp_mapped *map, size_t n, const fp_frame *f,
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
static size_t fp_map_all(const tessel_cloud *cloud, const fp_frame *f, fp_mapped *map,
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
        fp_row(&one, 0, &ring[k]);
        one.idx = &x->idx[nb];
        fp_row(&one, 0, &other);
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
        ok = fp_edge(x, &ring[a], &ring[c], &len2) && fp_edge(x, &ring[b], &ring[a], &len2) &&
             fp_edge(x, &ring[b], &ring[c], &len2);
        if (!ok)
            break;
        fp_ctx probe = *x;
        probe.orient = 1;
        int s = fp_facing(&probe, &ring[a], &ring[b], &ring[c]) ? 1 : 0;
        probe.orient = -1;
        s = s ? 1 : fp_facing(&probe, &ring[a], &ring[b], &ring[c]) ? -1 : 0;
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

tessel_status tessel_reconstruct_fixed_plane(const tessel_cloud *cloud,
                                             const tessel_fixed_plane_params *params,
                                             const tessel_callbacks *callbacks,
                                             const tessel_triangle_sink *sink,
                                             tessel_fixed_plane_stats *stats)
{
    double t_start = tsl_seconds();
    tessel_fixed_plane_params p =
        params ? *params : tessel_fixed_plane_params_default();
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
    if (p.mode == TESSEL_FIXED_PLANE_GRID) {
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
        /* Every index must be a point (or TESSEL_NONE): one branch-free pass
         * that also counts the points. */
        uint32_t bad = 0;
        const uint32_t count32 = (uint32_t)cloud->count;
        for (size_t k = 0; k < cells; k++) {
            uint32_t g = cloud->grid[k];
            reps += g != TESSEL_NONE;
            bad |= (g != TESSEL_NONE) & (g >= count32);
        }
        if (bad)
            return TESSEL_ERR_INVALID_ARG;
        x.kind = FP_RAY;
        x.w = cloud->width;
        x.h = cloud->height;
        x.idx = cloud->grid;
        for (int k = 0; k < 3; k++)
            x.vp[k] = (float)(vp_world[k] - cloud->offset[k]);
        x.wrap_r = fp_detect_wrap(&x, 1);
        x.wrap_c = fp_detect_wrap(&x, 0);
        st.representatives = reps;
        memcpy(st.viewpoint, vp_world, sizeof st.viewpoint);
    } else {
        fp_frame f;
        double gap = 0.0;
        if (p.mode == TESSEL_FIXED_PLANE_HEIGHT) {
            fp_height_frame(cloud, p.axis, &f);
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
            fp_range_frame(cloud, vpl, &f, &gap);
            fp_scan_order(cloud, &f);
            for (int k = 0; k < 3; k++)
                x.vp[k] = (float)vpl[k];
            memcpy(st.viewpoint, vp_world, sizeof st.viewpoint);
        }
        status = tsl_progress(callbacks, "dexels", 0.0);
        if (status != TESSEL_OK)
            return status;
        fp_mapped *map = tsl_alloc_array(cloud->count, sizeof(fp_mapped));
        if (!map)
            return TESSEL_ERR_NOMEM;
        float lo[2], hi[2];
        size_t valid = fp_map_all(cloud, &f, map, lo, hi, x.threads);
        if (valid == 0) {
            lo[0] = lo[1] = 0.0f;
            hi[0] = hi[1] = 0.0f;
        }
        /* A scan covering the whole circle of phi wraps round: no seam.
         * Decided on the sample's widest empty sector against the cell. */
        int full = -1;
        if (f.kind == FP_RAY) {
            int pa = f.transpose ? 1 : 0;
            status = fp_size(map, cloud->count, &f, lo, hi, &p, valid, -1, &dx);
            if (status == TESSEL_OK && gap < 2.0 * dx.cell[pa] &&
                (double)hi[pa] - lo[pa] > FP_PI) {
                full = pa;
                lo[pa] = 0.0f;
            }
        }
        if (status == TESSEL_OK)
            status = fp_size(map, cloud->count, &f, lo, hi, &p, valid, full, &dx);
        /* A dexel array far finer than the points would be empty dexels
         * only, and could ask for gigabytes. */
        if (status == TESSEL_OK &&
            (double)dx.w * dx.h > 16.0 * (double)valid + (double)(1u << 20)) {
            tsl_log(callbacks, TESSEL_LOG_WARNING,
                    "a %u x %u dexel array for %zu points is far finer than the "
                    "sampling: choose a larger cell or fewer dexels",
                    dx.w, dx.h, valid);
            status = TESSEL_ERR_LIMIT;
        }
        dx.wrap_c = full == 0;
        dx.wrap_r = full == 1;
        dx.lo[0] = lo[0];
        dx.lo[1] = lo[1];
        if (status == TESSEL_OK) {
            fp_assign(map, cloud->count, &dx, x.threads);
            status = fp_bucket(map, cloud->count, &dx, x.threads, callbacks);
        }
        free(map);
        if (status != TESSEL_OK) {
            free(dx.rep);
            free(dx.filled_slots);
            return status;
        }
        x.kind = f.kind;
        x.w = dx.w;
        x.h = dx.h;
        x.idx = dx.rep;
        x.wrap_c = dx.wrap_c && dx.w >= 3;
        x.wrap_r = dx.wrap_r && dx.h >= 3;
        if (f.kind == FP_PLANE)
            for (int k = 0; k < 3; k++)
                x.dir[k] = (float)f.e[2][k];
        for (int k = 0; k < 3; k++)
            st.axis[k] = f.e[2][k];
        st.cell[0] = dx.cell[0];
        st.cell[1] = dx.cell[1];
        st.representatives = dx.reps;
        st.dexels_filled = dx.filled;
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
    /* Block codes, in parallel over bands of rows. */
    for (uint32_t band = 0; status == TESSEL_OK && band < x.ch;) {
        uint32_t nb = (uint32_t)x.threads * 16u, rows_per = FP_BLOCK_ROWS;
        uint64_t band_end64 = (uint64_t)band + (uint64_t)nb * rows_per;
        uint32_t band_end = band_end64 > x.ch ? x.ch : (uint32_t)band_end64;
        uint32_t blocks = (band_end - band + rows_per - 1) / rows_per;
        size_t missing = 0, open = 0, folded = 0;
        int failed = 0;
        int nt = x.threads;
        (void)nt;
#pragma omp parallel num_threads(nt) reduction(+ : missing, open, folded, failed)
        {
            fp_scratch sc;
            tessel_status ss = fp_scratch_alloc(&sc, x.w);
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
                fp_codes_rows(&x, r0, r1, codes, &sc, &cnt);
                missing += cnt.missing;
                open += cnt.open;
                folded += cnt.folded;
            }
            free(sc.mem);
        }
        if (failed)
            status = TESSEL_ERR_NOMEM;
        st.cells_missing += missing;
        st.cells_open += open;
        st.triangles_folded += folded;
        band = band_end;
        if (status == TESSEL_OK)
            status = tsl_progress(callbacks, "triangles", 0.4 * (double)band / x.ch);
    }
    if (status == TESSEL_OK && codes && dx.filled)
        fp_untangle(&x, codes, dx.filled_slots, dx.filled, &st.triangles_folded);
    if (status == TESSEL_OK && codes)
        status = fp_make_manifold(&x, codes, &st.triangles_nonmanifold);
    if (status == TESSEL_OK && codes)
        status = fp_emit(&x, codes, sink, callbacks, &st.triangles);
    if (status == TESSEL_OK && codes)
        status = fp_cap_poles(&x, codes, sink, &st.triangles, &st.poles_closed);
    /* On a scan seen from its own viewpoint, or a height field, few
     * triangles face away (0-6% of those made on the LAS files and the
     * room scan we test with); more than were made means the input is not
     * what the mode assumes, and the mesh, still manifold, may cross
     * itself. */
    if (status == TESSEL_OK && st.triangles_folded > st.triangles)
        tsl_log(callbacks, TESSEL_LOG_WARNING,
                "%zu triangles faced away from the %s and were dropped, more than the %zu "
                "made: %s",
                st.triangles_folded,
                p.mode == TESSEL_FIXED_PLANE_HEIGHT ? "plane's normal" : "viewpoint",
                st.triangles,
                p.mode == TESSEL_FIXED_PLANE_HEIGHT
                    ? "the cloud is no height field seen along it (another axis?)"
                    : p.mode == TESSEL_FIXED_PLANE_RANGE
                          ? "is the viewpoint the scanner's?"
                          : "is the viewpoint the camera's, and the grid its image?");
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
