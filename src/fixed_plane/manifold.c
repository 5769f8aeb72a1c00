/* What the fixed-plane triangulator's block codes need before they are
 * emitted: vertex manifoldness (a vertex whose link has two fans keeps the
 * largest) and, round the dexels filled from a neighbour's spare points,
 * no two triangles overlapping in projection. */
#include "fixed_plane/fixed_plane.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

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

tessel_status tsl_fp_make_manifold(const fp_ctx *x, uint8_t *codes, size_t *removed)
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
void tsl_fp_untangle(const fp_ctx *x, uint8_t *codes, const uint32_t *slots, size_t n,
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
