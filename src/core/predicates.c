/* Robust geometric predicates: orient2d and orient3d whose sign is exact.
 *
 * J. R. Shewchuk, "Adaptive Precision Floating-Point Arithmetic and Fast
 * Robust Geometric Predicates", Discrete & Computational Geometry 18 (1997):
 * section 2 (expansion arithmetic: Two-Sum, Two-Product, Fast-Expansion-Sum,
 * Scale-Expansion with zero elimination) and section 4 (the orientation
 * predicates and their error bounds). Each predicate first evaluates the
 * determinant in plain double arithmetic and returns it when its magnitude
 * exceeds the forward error bound (Shewchuk's stage A bound, the common case).
 * Otherwise the differences are formed as exact expansions (one term when the
 * subtraction was exact, two otherwise) and the determinant is evaluated
 * exactly in expansion arithmetic; the sign of its most significant term is
 * the sign of the true determinant. Shewchuk's intermediate stages B and C are
 * folded into that one exact path: when the differences are exact (inputs are
 * floats of similar magnitude, the usual case) the expansions stay short and
 * the exact path costs a few hundred flops.
 *
 * Requires IEEE double arithmetic with round-to-nearest and no extended
 * precision (SSE2 on x86-64, any AArch64). Products must not be contracted
 * into fused multiply-adds behind our back: ISO C mode (which our CMake uses)
 * makes gcc keep them apart, the pragma below does it for clang, and where a
 * fast hardware fma exists Two-Product uses it explicitly. */
#include "core/core.h"

#include <math.h>

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* Shewchuk's epsilon: half an ulp of 1.0, 2^-53. */
#define TSL_EPS (1.0 / 9007199254740992.0)
/* 2^ceil(53/2) + 1, splits a double into two 26-bit halves. */
#define TSL_SPLITTER 134217729.0

static const double ccw_bound_a = (3.0 + 16.0 * TSL_EPS) * TSL_EPS;
static const double o3d_bound_a = (7.0 + 56.0 * TSL_EPS) * TSL_EPS;

/* ---- error-free transformations ---- */

/* a + b = x + y exactly, |a| >= |b| required. */
static inline void fast_two_sum(double a, double b, double *x, double *y)
{
    double s = a + b;
    double bv = s - a;
    *x = s;
    *y = b - bv;
}

/* a + b = x + y exactly. */
static inline void two_sum(double a, double b, double *x, double *y)
{
    double s = a + b;
    double bv = s - a;
    double av = s - bv;
    *x = s;
    *y = (a - av) + (b - bv);
}

/* a - b = x + y exactly. */
static inline void two_diff(double a, double b, double *x, double *y)
{
    double d = a - b;
    double bv = a - d;
    double av = d + bv;
    *x = d;
    *y = (a - av) + (bv - b);
}

#ifndef FP_FAST_FMA
static inline void split(double a, double *hi, double *lo)
{
    double c = TSL_SPLITTER * a;
    double abig = c - a;
    *hi = c - abig;
    *lo = a - *hi;
}
#endif

/* a * b = x + y exactly (no overflow / underflow assumed). */
static inline void two_product(double a, double b, double *x, double *y)
{
    double p = a * b;
    *x = p;
#ifdef FP_FAST_FMA
    *y = fma(a, b, -p);
#else
    double ahi, alo, bhi, blo;
    split(a, &ahi, &alo);
    split(b, &bhi, &blo);
    double err1 = p - ahi * bhi;
    double err2 = err1 - alo * bhi;
    double err3 = err2 - ahi * blo;
    *y = alo * blo - err3;
#endif
}

/* ---- expansions: arrays of non-overlapping doubles, increasing magnitude,
 * zero terms removed (a zero expansion is the single term 0). ---- */

/* h = e + f. h has room for elen + flen terms and must not alias e or f.
 * Returns the length of h. (Shewchuk's Fast-Expansion-Sum-Zeroelim, written
 * so that it never reads past the end of e or f.) */
static int expansion_sum(int elen, const double *e, int flen, const double *f, double *h)
{
    int ei = 0, fi = 0, hn = 0;
    double q, qnew, hh, g;
#define TSL_NEXT(out)                                                          \
    do {                                                                       \
        if (fi >= flen || (ei < elen && (f[fi] > e[ei]) == (f[fi] > -e[ei])))  \
            (out) = e[ei++];                                                   \
        else                                                                   \
            (out) = f[fi++];                                                   \
    } while (0)
    TSL_NEXT(q);
    if (ei + fi < elen + flen) {
        TSL_NEXT(g);
        fast_two_sum(g, q, &qnew, &hh);
        q = qnew;
        if (hh != 0.0)
            h[hn++] = hh;
        while (ei + fi < elen + flen) {
            TSL_NEXT(g);
            two_sum(q, g, &qnew, &hh);
            q = qnew;
            if (hh != 0.0)
                h[hn++] = hh;
        }
    }
#undef TSL_NEXT
    if (q != 0.0 || hn == 0)
        h[hn++] = q;
    return hn;
}

/* h = e * b. h has room for 2 * elen terms and must not alias e. */
static int scale_expansion(int elen, const double *e, double b, double *h)
{
    int hn = 0;
    double q, hh, p1, p0, sum;
    two_product(e[0], b, &q, &hh);
    if (hh != 0.0)
        h[hn++] = hh;
    for (int i = 1; i < elen; i++) {
        two_product(e[i], b, &p1, &p0);
        two_sum(q, p0, &sum, &hh);
        if (hh != 0.0)
            h[hn++] = hh;
        fast_two_sum(p1, sum, &q, &hh);
        if (hh != 0.0)
            h[hn++] = hh;
    }
    if (q != 0.0 || hn == 0)
        h[hn++] = q;
    return hn;
}

/* Largest expansion any product below builds: (2 * 2 * 2) * 2 * 2 terms per
 * triple product of two-term differences, times 3 (orient3d). */
#define TSL_EXP_MAX 192

/* h = e * f for short expansions (elen * flen * 2 <= TSL_EXP_MAX). */
static int expansion_product(int elen, const double *e, int flen, const double *f, double *h)
{
    double part[TSL_EXP_MAX], acc[TSL_EXP_MAX], tmp[TSL_EXP_MAX];
    int accn = 1;
    acc[0] = 0.0;
    for (int i = 0; i < flen; i++) {
        int pn = scale_expansion(elen, e, f[i], part);
        int tn = expansion_sum(accn, acc, pn, part, tmp);
        for (int k = 0; k < tn; k++)
            acc[k] = tmp[k];
        accn = tn;
    }
    for (int k = 0; k < accn; k++)
        h[k] = acc[k];
    return accn;
}

static void negate(int n, double *e)
{
    for (int i = 0; i < n; i++)
        e[i] = -e[i];
}

/* a - b as an expansion of one or two terms. */
static int diff_expansion(double a, double b, double out[2])
{
    double x, y;
    two_diff(a, b, &x, &y);
    if (y == 0.0) {
        out[0] = x;
        return 1;
    }
    out[0] = y;
    out[1] = x;
    return 2;
}

/* e1 * f1 - e2 * f2 into h (room for TSL_EXP_MAX). */
static int cross_term(int e1n, const double *e1, int f1n, const double *f1, int e2n,
                      const double *e2, int f2n, const double *f2, double *h)
{
    double p[TSL_EXP_MAX], q[TSL_EXP_MAX];
    int pn = expansion_product(e1n, e1, f1n, f1, p);
    int qn = expansion_product(e2n, e2, f2n, f2, q);
    negate(qn, q);
    return expansion_sum(pn, p, qn, q, h);
}

static double orient2d_exact(const double a[2], const double b[2], const double c[2])
{
    double acx[2], acy[2], bcx[2], bcy[2], h[TSL_EXP_MAX];
    int acxn = diff_expansion(a[0], c[0], acx);
    int acyn = diff_expansion(a[1], c[1], acy);
    int bcxn = diff_expansion(b[0], c[0], bcx);
    int bcyn = diff_expansion(b[1], c[1], bcy);
    int n = cross_term(acxn, acx, bcyn, bcy, acyn, acy, bcxn, bcx, h);
    return h[n - 1];
}

double tsl_orient2d(const double a[2], const double b[2], const double c[2])
{
    double detleft = (a[0] - c[0]) * (b[1] - c[1]);
    double detright = (a[1] - c[1]) * (b[0] - c[0]);
    double det = detleft - detright;
    double detsum;
    if (detleft > 0.0) {
        if (detright <= 0.0)
            return det;
        detsum = detleft + detright;
    } else if (detleft < 0.0) {
        if (detright >= 0.0)
            return det;
        detsum = -detleft - detright;
    } else {
        return det;
    }
    double bound = ccw_bound_a * detsum;
    if (det >= bound || -det >= bound)
        return det;
    return orient2d_exact(a, b, c);
}

static double orient3d_exact(const double a[3], const double b[3], const double c[3],
                             const double d[3])
{
    double ad[3][2], bd[3][2], cd[3][2];
    int adn[3], bdn[3], cdn[3];
    for (int k = 0; k < 3; k++) {
        adn[k] = diff_expansion(a[k], d[k], ad[k]);
        bdn[k] = diff_expansion(b[k], d[k], bd[k]);
        cdn[k] = diff_expansion(c[k], d[k], cd[k]);
    }
    /* det = adz (bdx cdy - cdx bdy) + bdz (cdx ady - adx cdy)
     *     + cdz (adx bdy - bdx ady), as in Shewchuk's orient3d. */
    double m[TSL_EXP_MAX / 2 + 1], t1[TSL_EXP_MAX], t2[TSL_EXP_MAX], t3[TSL_EXP_MAX];
    double s12[TSL_EXP_MAX * 2], all[TSL_EXP_MAX * 3];
    int mn, n1, n2, n3;
    mn = cross_term(bdn[0], bd[0], cdn[1], cd[1], cdn[0], cd[0], bdn[1], bd[1], m);
    n1 = expansion_product(mn, m, adn[2], ad[2], t1);
    mn = cross_term(cdn[0], cd[0], adn[1], ad[1], adn[0], ad[0], cdn[1], cd[1], m);
    n2 = expansion_product(mn, m, bdn[2], bd[2], t2);
    mn = cross_term(adn[0], ad[0], bdn[1], bd[1], bdn[0], bd[0], adn[1], ad[1], m);
    n3 = expansion_product(mn, m, cdn[2], cd[2], t3);
    int n12 = expansion_sum(n1, t1, n2, t2, s12);
    int n = expansion_sum(n12, s12, n3, t3, all);
    return all[n - 1];
}

/* a * b - c * d, exactly, as an expansion of at most four terms. */
static int two_cross(double a, double b, double c, double d, double h[4])
{
    double p[2], q[2];
    int pn = 0, qn = 0;
    double x, y;
    two_product(a, b, &x, &y);
    if (y != 0.0)
        p[pn++] = y;
    if (x != 0.0 || pn == 0)
        p[pn++] = x;
    two_product(c, d, &x, &y);
    if (y != 0.0)
        q[qn++] = -y;
    if (x != 0.0 || qn == 0)
        q[qn++] = -x;
    return expansion_sum(pn, p, qn, q, h);
}

/* orient3d from its nine differences when they are exact (so from float
 * inputs, as almost always here): fixed-size expansions, no copies. The
 * value is exact, like orient3d_exact's; only its low terms may differ. */
static double orient3d_exact_diffs(double adx, double ady, double adz, double bdx, double bdy,
                                   double bdz, double cdx, double cdy, double cdz)
{
    double bc[4], ca[4], ab[4], t1[8], t2[8], t3[8], s12[16], all[24];
    int bcn = two_cross(bdx, cdy, cdx, bdy, bc);
    int can = two_cross(cdx, ady, adx, cdy, ca);
    int abn = two_cross(adx, bdy, bdx, ady, ab);
    int n1 = scale_expansion(bcn, bc, adz, t1);
    int n2 = scale_expansion(can, ca, bdz, t2);
    int n3 = scale_expansion(abn, ab, cdz, t3);
    int n12 = expansion_sum(n1, t1, n2, t2, s12);
    int n = expansion_sum(n12, s12, n3, t3, all);
    return all[n - 1];
}

/* Whether a - b is exact in double. */
static inline bool diff_exact(double a, double b)
{
    double x, y;
    two_diff(a, b, &x, &y);
    return y == 0.0;
}

double tsl_orient3d(const double a[3], const double b[3], const double c[3], const double d[3])
{
    double adx = a[0] - d[0], bdx = b[0] - d[0], cdx = c[0] - d[0];
    double ady = a[1] - d[1], bdy = b[1] - d[1], cdy = c[1] - d[1];
    double adz = a[2] - d[2], bdz = b[2] - d[2], cdz = c[2] - d[2];
    double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
    double cdxady = cdx * ady, adxcdy = adx * cdy;
    double adxbdy = adx * bdy, bdxady = bdx * ady;
    double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
    double permanent = (fabs(bdxcdy) + fabs(cdxbdy)) * fabs(adz) +
                       (fabs(cdxady) + fabs(adxcdy)) * fabs(bdz) +
                       (fabs(adxbdy) + fabs(bdxady)) * fabs(cdz);
    double bound = o3d_bound_a * permanent;
    if (det > bound || -det > bound)
        return det;
    bool exact = true;
    for (int k = 0; k < 3; k++)
        exact = exact && diff_exact(a[k], d[k]) && diff_exact(b[k], d[k]) &&
                diff_exact(c[k], d[k]);
    if (exact)
        return orient3d_exact_diffs(adx, ady, adz, bdx, bdy, bdz, cdx, cdy, cdz);
    return orient3d_exact(a, b, c, d);
}

/* ------------------------------------------------------------------------ */
/* Exact triangle tests: closed triangles meeting, decided by the signs of  */
/* orient2d/orient3d only (used by the check, the advancing front, greedy). */
/* ------------------------------------------------------------------------ */

static inline int sgn(double x) { return (x > 0.0) - (x < 0.0); }
/* Plain minimum / maximum of finite numbers (fmin/fmax handle NaN and are
 * function calls). */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

/* Coordinate axis to drop so that the non-degenerate triangle abc projects
 * to a non-degenerate triangle; its projected orientation sign in *orient
 * (0 when abc is collinear). */
static int drop_axis(const double a[3], const double b[3], const double c[3], int *orient)
{
    double u[3], v[3], n[3];
    tsl_sub(b, a, u);
    tsl_sub(c, a, v);
    tsl_cross(u, v, n);
    int first = 0;
    if (fabs(n[1]) > fabs(n[first]))
        first = 1;
    if (fabs(n[2]) > fabs(n[first]))
        first = 2;
    for (int t = 0; t < 3; t++) {
        int drop = (first + t) % 3;
        int i = (drop + 1) % 3, j = (drop + 2) % 3;
        double pa[2] = {a[i], a[j]}, pb[2] = {b[i], b[j]}, pc[2] = {c[i], c[j]};
        int s = sgn(tsl_orient2d(pa, pb, pc));
        if (s != 0) {
            *orient = s;
            return drop;
        }
    }
    *orient = 0;
    return 0;
}

bool tsl_triangle_degenerate(const double *p[3])
{
    int o;
    drop_axis(p[0], p[1], p[2], &o);
    return o == 0;
}

static inline void drop2(const double p[3], int drop, double out[2])
{
    out[0] = p[(drop + 1) % 3];
    out[1] = p[(drop + 2) % 3];
}

/* r on the closed segment pq, given p, q, r collinear. */
static bool on_segment2(const double p[2], const double q[2], const double r[2])
{
    return dmin(p[0], q[0]) <= r[0] && r[0] <= dmax(p[0], q[0]) && dmin(p[1], q[1]) <= r[1] &&
           r[1] <= dmax(p[1], q[1]);
}

static bool segments_meet2(const double p[2], const double q[2], const double a[2],
                           const double b[2])
{
    int d1 = sgn(tsl_orient2d(p, q, a)), d2 = sgn(tsl_orient2d(p, q, b));
    int d3 = sgn(tsl_orient2d(a, b, p)), d4 = sgn(tsl_orient2d(a, b, q));
    if (d1 * d2 < 0 && d3 * d4 < 0)
        return true;
    return (d1 == 0 && on_segment2(p, q, a)) || (d2 == 0 && on_segment2(p, q, b)) ||
           (d3 == 0 && on_segment2(a, b, p)) || (d4 == 0 && on_segment2(a, b, q));
}

static bool in_triangle2(const double p[2], const double a[2], const double b[2],
                         const double c[2], int o)
{
    return sgn(tsl_orient2d(a, b, p)) * o >= 0 && sgn(tsl_orient2d(b, c, p)) * o >= 0 &&
           sgn(tsl_orient2d(c, a, p)) * o >= 0;
}

/* Closed segment pq meets closed non-degenerate triangle abc. */
static bool segment_triangle(const double p[3], const double q[3], const double a[3],
                             const double b[3], const double c[3])
{
    int sp = sgn(tsl_orient3d(a, b, c, p)), sq = sgn(tsl_orient3d(a, b, c, q));
    if (sp * sq > 0)
        return false;
    if (sp == 0 && sq == 0) {
        int o;
        int drop = drop_axis(a, b, c, &o);
        double p2[2], q2[2], a2[2], b2[2], c2[2];
        drop2(p, drop, p2);
        drop2(q, drop, q2);
        drop2(a, drop, a2);
        drop2(b, drop, b2);
        drop2(c, drop, c2);
        return in_triangle2(p2, a2, b2, c2, o) || in_triangle2(q2, a2, b2, c2, o) ||
               segments_meet2(p2, q2, a2, b2) || segments_meet2(p2, q2, b2, c2) ||
               segments_meet2(p2, q2, c2, a2);
    }
    /* The segment reaches the plane once; the line through it hits the
     * closed triangle iff it passes its three edges on the same side. */
    int s1 = sgn(tsl_orient3d(p, q, a, b));
    int s2 = sgn(tsl_orient3d(p, q, b, c));
    int s3 = sgn(tsl_orient3d(p, q, c, a));
    bool pos = s1 > 0 || s2 > 0 || s3 > 0;
    bool neg = s1 < 0 || s2 < 0 || s3 < 0;
    return !(pos && neg);
}

bool tsl_triangles_intersect(const uint32_t ia[3], const double *pa[3], const uint32_t ib[3],
                             const double *pb[3])
{
    int shared = 0, sa[3], sb[3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (ia[i] == ib[j]) {
                sa[shared] = i;
                sb[shared] = j;
                shared++;
            }
    if (shared == 3)
        return true;
    if (shared == 2) {
        /* Common edge pq: they overlap iff coplanar with both apexes on the
         * same side of pq. */
        const double *p = pa[sa[0]], *q = pa[sa[1]];
        const double *ra = pa[3 - sa[0] - sa[1]], *rb = pb[3 - sb[0] - sb[1]];
        if (tsl_orient3d(p, q, ra, rb) != 0.0)
            return false;
        int o;
        int drop = drop_axis(p, q, ra, &o);
        double p2[2], q2[2], rb2[2];
        drop2(p, drop, p2);
        drop2(q, drop, q2);
        drop2(rb, drop, rb2);
        return sgn(tsl_orient2d(p2, q2, rb2)) == o;
    }
    if (shared == 1) {
        /* Common vertex: they meet elsewhere iff the edge opposite it in one
         * meets the other. When that edge lies strictly on one side of the
         * other's plane, the triangle touches that plane at the common
         * vertex only: no meeting. */
        int i = sa[0], j = sb[0];
        const double *b1 = pb[(j + 1) % 3], *b2 = pb[(j + 2) % 3];
        const double *a1 = pa[(i + 1) % 3], *a2 = pa[(i + 2) % 3];
        if (sgn(tsl_orient3d(pa[0], pa[1], pa[2], b1)) *
                sgn(tsl_orient3d(pa[0], pa[1], pa[2], b2)) > 0 ||
            sgn(tsl_orient3d(pb[0], pb[1], pb[2], a1)) *
                sgn(tsl_orient3d(pb[0], pb[1], pb[2], a2)) > 0)
            return false;
        return segment_triangle(b1, b2, pa[0], pa[1], pa[2]) ||
               segment_triangle(a1, a2, pb[0], pb[1], pb[2]);
    }
    /* Disjoint ids: planes first, then the six edge-triangle tests (closed
     * triangles that meet always have an edge of one meeting the other). */
    int s0 = sgn(tsl_orient3d(pa[0], pa[1], pa[2], pb[0]));
    int s1 = sgn(tsl_orient3d(pa[0], pa[1], pa[2], pb[1]));
    int s2 = sgn(tsl_orient3d(pa[0], pa[1], pa[2], pb[2]));
    if ((s0 > 0 && s1 > 0 && s2 > 0) || (s0 < 0 && s1 < 0 && s2 < 0))
        return false;
    s0 = sgn(tsl_orient3d(pb[0], pb[1], pb[2], pa[0]));
    s1 = sgn(tsl_orient3d(pb[0], pb[1], pb[2], pa[1]));
    s2 = sgn(tsl_orient3d(pb[0], pb[1], pb[2], pa[2]));
    if ((s0 > 0 && s1 > 0 && s2 > 0) || (s0 < 0 && s1 < 0 && s2 < 0))
        return false;
    for (int t = 0; t < 3; t++) {
        if (segment_triangle(pa[t], pa[(t + 1) % 3], pb[0], pb[1], pb[2]))
            return true;
        if (segment_triangle(pb[t], pb[(t + 1) % 3], pa[0], pa[1], pa[2]))
            return true;
    }
    return false;
}
