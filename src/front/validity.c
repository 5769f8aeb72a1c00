/* Validity of a triangle the front is about to add: condition (ii) of
 * Mederos, Velho & de Figueiredo 2003, section 2.4, made strict so that
 * the output is a valid surface whatever the input. The paper's projection
 * test (projected onto the plane bisecting their normals, a new triangle
 * and an existing one may not overlap around a shared vertex, nor when
 * they share nothing and are close in height), folds along shared edges
 * within pi/2 + eps2, the vertices' normal cones, and an exact
 * intersection test against every triangle the hash grid lists near it
 * (core/predicates.c), so that the front never self-intersects. */
#include "front/front.h"

#include <float.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Validity of a new triangle                                                */
/* ------------------------------------------------------------------------ */

/* Orthonormal u, v spanning the plane with unit normal n. */
static void plane_frame(const double n[3], double u[3], double v[3])
{
    double a[3] = {1.0, 0.0, 0.0};
    if (fabs(n[0]) > 0.6) {
        a[0] = 0.0;
        a[1] = 1.0;
    }
    tsl_cross(n, a, u);
    tsl_normalize(u);
    tsl_cross(n, u, v);
}

static inline void project2(const double p[3], const double o[3], const double u[3],
                            const double v[3], double out[2])
{
    double d[3];
    tsl_sub(p, o, d);
    out[0] = tsl_dot(d, u);
    out[1] = tsl_dot(d, v);
}

static inline double cross2(const double a[2], const double b[2])
{
    return a[0] * b[1] - a[1] * b[0];
}

/* How two triangles lie in a projection: clearly apart, overlapping, or
 * too close to tell in floating point. */
enum { PROJ_APART, PROJ_UNSURE, PROJ_OVERLAP };

/* Twice the signed area of the projection of (0, a, b) onto the plane with
 * unit normal n: the 2D cross product there, n . (a x b). */
static inline double det_n(const double n[3], const double a[3], const double b[3])
{
    return n[0] * (a[1] * b[2] - a[2] * b[1]) + n[1] * (a[2] * b[0] - a[0] * b[2]) +
           n[2] * (a[0] * b[1] - a[1] * b[0]);
}

/* Squared length of a's projection onto the plane with unit normal n. */
static inline double len2_n(const double n[3], const double a[3])
{
    double h = tsl_dot(a, n);
    return dmax(tsl_dot(a, a) - h * h, 0.0);
}

/* Where direction d lies with respect to the sector from p counter-
 * clockwise to q (narrower than pi), given pd = cross(p, d), dq = cross(d,
 * q) and the squared lengths: +1 clearly inside, -1 clearly outside, 0 on
 * its boundary within a relative tolerance (sine 1e-6). */
static int sector_side(double pd, double dq, double lp, double ld, double lq)
{
    const double tol2 = 1e-12;
    bool in_a = pd > 0.0 && pd * pd > tol2 * lp * ld;
    bool in_b = dq > 0.0 && dq * dq > tol2 * ld * lq;
    bool out_a = pd < 0.0 && pd * pd > tol2 * lp * ld;
    bool out_b = dq < 0.0 && dq * dq > tol2 * ld * lq;
    if (in_a && in_b)
        return 1;
    return out_a || out_b ? -1 : 0;
}

/* X's sector at one of its vertices in that vertex's tangent plane (unit
 * normal nrm): its two edge vectors, their squared projected lengths and
 * whether X is folded there. It depends on X and the vertex only, so it is
 * computed once per new triangle and vertex, not once per neighbour. */
typedef struct af_sector {
    double p1[3], q1[3];
    double lp1, lq1;
    bool folded;
    bool ready;
} af_sector;

static void sector_of(const double *px[3], int ix, const double nrm[3], af_sector *sec)
{
    const double *o = px[ix];
    tsl_sub(px[(ix + 1) % 3], o, sec->p1);
    tsl_sub(px[(ix + 2) % 3], o, sec->q1);
    sec->folded = det_n(nrm, sec->p1, sec->q1) <= 0.0;
    sec->lp1 = len2_n(nrm, sec->p1);
    sec->lq1 = len2_n(nrm, sec->q1);
    sec->ready = true;
}

/* The paper's projection test for two triangles X and E sharing the vertex
 * at position ix of X and ie of E, projected onto the vertex's tangent
 * plane (unit normal nrm, facing it; sec = X's sector there). Sectors
 * around the shared vertex: apart when every bounding ray of each is
 * clearly outside the other (both are narrower than pi, so neither can
 * contain the other). Disjoint projections also mean disjoint triangles in
 * space (beyond the shared vertex), so PROJ_APART spares the exact test. */
static int sector_relation(const af_sector *sec, const double *px[3], const double *pe[3],
                           int ix, int ie, const double nrm[3])
{
    const double *o = px[ix];
    const double *p1 = sec->p1, *q1 = sec->q1;
    double p2[3], q2[3];
    tsl_sub(pe[(ie + 1) % 3], o, p2);
    tsl_sub(pe[(ie + 2) % 3], o, q2);
    if (sec->folded || det_n(nrm, p2, q2) <= 0.0)
        return PROJ_OVERLAP; /* folded in this projection */
    double lp1 = sec->lp1, lq1 = sec->lq1;
    double lp2 = len2_n(nrm, p2), lq2 = len2_n(nrm, q2);
    double d_p1p2 = det_n(nrm, p1, p2), d_p1q2 = det_n(nrm, p1, q2);
    double d_q1p2 = det_n(nrm, q1, p2), d_q1q2 = det_n(nrm, q1, q2);
    int s1 = sector_side(d_p1p2, -d_q1p2, lp1, lp2, lq1); /* p2 in X */
    int s2 = sector_side(d_p1q2, -d_q1q2, lp1, lq2, lq1); /* q2 in X */
    int s3 = sector_side(-d_p1p2, d_p1q2, lp2, lp1, lq2); /* p1 in E */
    int s4 = sector_side(-d_q1p2, d_q1q2, lp2, lq1, lq2); /* q1 in E */
    if (s1 > 0 || s2 > 0 || s3 > 0 || s4 > 0)
        return PROJ_OVERLAP;
    return s1 < 0 && s2 < 0 && s3 < 0 && s4 < 0 ? PROJ_APART : PROJ_UNSURE;
}

/* The same test for triangles sharing no vertex, projected onto the plane
 * with unit normal nrm: a separating axis among the six edges. */
static int projected_relation(const double *px[3], const double *pe[3], const double nrm[3])
{
    double u[3], v[3], x[3][2], y[3][2];
    plane_frame(nrm, u, v);
    for (int i = 0; i < 3; i++) {
        project2(px[i], px[0], u, v, x[i]);
        project2(pe[i], px[0], u, v, y[i]);
    }
    /* Separating axis among the six edges (both counter-clockwise). */
    double scale = 0.0;
    for (int i = 0; i < 3; i++)
        for (int c = 0; c < 2; c++)
            scale = dmax(scale, dmax(fabs(x[i][c]), fabs(y[i][c])));
    double tol = 1e-9 * scale * scale;
    int result = PROJ_OVERLAP;
    for (int pass = 0; pass < 2; pass++) {
        double(*a)[2] = pass ? y : x;
        double(*b)[2] = pass ? x : y;
        for (int i = 0; i < 3; i++) {
            const double *p = a[i], *q = a[(i + 1) % 3];
            double ed[2] = {q[0] - p[0], q[1] - p[1]};
            double worst = -INFINITY;
            for (int j = 0; j < 3; j++) {
                double w[2] = {b[j][0] - p[0], b[j][1] - p[1]};
                worst = dmax(worst, cross2(ed, w));
            }
            if (worst < -tol)
                return PROJ_APART;
            if (worst <= tol)
                result = PROJ_UNSURE;
        }
    }
    return result;
}

/* Fills x from ids; false when the triangle is degenerate. */
bool tsl_af_make_tri(const af *s, uint32_t a, uint32_t b, uint32_t c, af_tri *x)
{
    x->v[0] = a;
    x->v[1] = b;
    x->v[2] = c;
    x->cos_fold = s->cos_theta_max;
    x->exact_only = false;
    for (int i = 0; i < 3; i++)
        point(s, x->v[i], x->p[i]);
    double area2 = tsl_tri_normal(x->p[0], x->p[1], x->p[2], x->n);
    x->maxlen = 0.0;
    for (int i = 0; i < 3; i++) {
        double d[3];
        tsl_sub(x->p[(i + 1) % 3], x->p[i], d);
        x->maxlen = dmax(x->maxlen, tsl_norm(d));
    }
    double r2 = 0.0;
    for (int k = 0; k < 3; k++)
        x->centroid[k] = (x->p[0][k] + x->p[1][k] + x->p[2][k]) / 3.0;
    for (int i = 0; i < 3; i++) {
        double d[3];
        tsl_sub(x->p[i], x->centroid, d);
        r2 = dmax(r2, tsl_dot(d, d));
    }
    x->radius = sqrt(r2);
    /* Sine of the smallest angle is at least area2 / maxlen^2. */
    if (!(area2 > 1e-9 * x->maxlen * x->maxlen))
        return false;
    const double *pp[3] = {x->p[0], x->p[1], x->p[2]};
    return !tsl_triangle_degenerate(pp);
}

/* Largest angle of x, as its cosine (smaller = wider). */
double tsl_af_min_cos_angle(const af_tri *x)
{
    double m = 1.0;
    for (int i = 0; i < 3; i++) {
        double u[3], v[3];
        tsl_sub(x->p[(i + 1) % 3], x->p[i], u);
        tsl_sub(x->p[(i + 2) % 3], x->p[i], v);
        double c = tsl_dot(u, v) / (tsl_norm(u) * tsl_norm(v));
        m = dmin(m, c);
    }
    return m;
}

/* True when the new triangle x cannot coexist with the existing or pending
 * triangle with vertex ids ev, coordinates pe and unit normal ne. star[i]
 * is the tangent plane normal at x's vertex i, sec[i] x's sector there
 * (filled on first use), xlo/xhi x's bounding box, elo/ehi E's. */
static bool conflict(const af_tri *x, const double star[3][3], af_sector sec[3],
                     const double xlo[3], const double xhi[3], const uint32_t ev[3],
                     const double *pe[3], const double elo[3], const double ehi[3],
                     const double ne[3])
{
    const double *px[3] = {x->p[0], x->p[1], x->p[2]};
    int shared = 0, sx[3], se[3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (x->v[i] == ev[j]) {
                sx[shared] = i;
                se[shared] = j;
                shared++;
            }
    if (shared == 3)
        return true;
    double d = tsl_dot(x->n, ne);
    if (shared == 2) {
        /* Opposite directions along the common edge (orientation), a fold no
         * sharper than theta_max, no coplanar overlap. */
        bool dx = (sx[0] + 1) % 3 == sx[1];
        bool de = (se[0] + 1) % 3 == se[1];
        if (dx == de || d < x->cos_fold)
            return true;
        return tsl_triangles_intersect(x->v, px, ev, pe);
    }
    /* Boxes: X's own and X's grown by half its longest edge, for the
     * projection test of triangles sharing nothing. */
    bool touches = true;
    if (shared == 0) {
        double margin = 0.5 * x->maxlen;
        for (int c = 0; c < 3; c++) {
            double lo = xlo[c], hi = xhi[c];
            if (ehi[c] < lo - margin || elo[c] > hi + margin)
                return false;
            if (ehi[c] < lo || elo[c] > hi)
                touches = false;
        }
    }
    int rel = PROJ_UNSURE;
    if (x->exact_only) {
        /* validity only */
    } else if (shared == 1) {
        /* The paper's test: the triangle against the star of the shared
         * vertex, in the vertex's tangent plane (star normal). */
        const double *nrm = star[sx[0]];
        if (tsl_dot(nrm, x->n) > 0.1 && tsl_dot(nrm, ne) > 0.1) {
            if (!sec[sx[0]].ready)
                sector_of(px, sx[0], nrm, &sec[sx[0]]);
            rel = sector_relation(&sec[sx[0]], px, pe, sx[0], se[0], nrm);
        }
    } else if (d > 0.0) {
        /* Sharing nothing: in the plane bisecting both normals, when close
         * in height (farther, overlapping projections are another layer). */
        double nrm[3] = {x->n[0] + ne[0], x->n[1] + ne[1], x->n[2] + ne[2]};
        tsl_normalize(nrm);
        /* Centroids and bounding radii first: discs apart in the plane
         * mean projections apart. */
        double ce[3], delta[3], re2 = 0.0;
        for (int c = 0; c < 3; c++)
            ce[c] = (pe[0][c] + pe[1][c] + pe[2][c]) / 3.0;
        for (int i = 0; i < 3; i++) {
            double dd[3];
            tsl_sub(pe[i], ce, dd);
            re2 = dmax(re2, tsl_dot(dd, dd));
        }
        tsl_sub(ce, x->centroid, delta);
        double h = tsl_dot(delta, nrm), reach = x->radius + sqrt(re2);
        bool near = fabs(h) < 0.5 * x->maxlen;
        if (tsl_dot(delta, delta) - h * h > reach * reach)
            rel = PROJ_APART;
        else if (near || touches)
            rel = projected_relation(px, pe, nrm);
        if (rel == PROJ_OVERLAP && !near)
            rel = PROJ_UNSURE;
    }
    if (rel == PROJ_OVERLAP)
        return true;
    if (rel == PROJ_APART)
        return false;
    if (!touches)
        return false;
    return tsl_triangles_intersect(x->v, px, ev, pe);
}

static bool agrees(const double n[3], const float *l, int sign, double cos_limit)
{
    double d = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
    if (sign == 0)
        d = fabs(d);
    else if (sign < 0)
        d = -d;
    return d >= cos_limit;
}

/* The triangle's normal lies within the normal cone around each vertex's
 * surface normal, oriented as the surface took it (either way for a vertex
 * not yet on the surface). This keeps the front from folding back over
 * itself where noise lets folds pass the dihedral test (i). With a second
 * set of lines (the pipeline's: the normals of the robust fit at each
 * representative, local where the plane of its k nearest representatives
 * spans a tip or a narrow part), agreeing with either line is enough. */
bool tsl_af_normals_agree(const af *s, const af_tri *x, double cos_limit)
{
    for (int i = 0; i < 3; i++) {
        uint32_t v = x->v[i];
        if (!agrees(x->n, s->ln + 3 * (size_t)v, s->vsign[v], cos_limit) &&
            !(s->lines && agrees(x->n, s->lines + 3 * (size_t)v, s->vsign2[v], cos_limit)))
            return false;
    }
    return true;
}

/* *ok: x may be added to the mesh (together with `other`, a triangle added
 * in the same step, or NULL). */
tessel_status tsl_af_check_triangle(af *s, const af_tri *x, const af_tri *other, bool *ok)
{
    *ok = false;
    /* Tangent planes of the vertices: their stars' mean normal (with x's). */
    double star[3][3];
    for (int i = 0; i < 3; i++) {
        const float *sum = s->star + 3 * (size_t)x->v[i];
        for (int c = 0; c < 3; c++)
            star[i][c] = x->n[c] + sum[c];
        if (!tsl_normalize(star[i]))
            for (int c = 0; c < 3; c++)
                star[i][c] = x->n[c];
    }
    const double *px[3] = {x->p[0], x->p[1], x->p[2]};
    double lo[3], hi[3], xlo[3], xhi[3];
    tsl_af_tri_box(px, xlo, xhi);
    memcpy(lo, xlo, sizeof lo);
    memcpy(hi, xhi, sizeof hi);
    af_sector sec[3];
    for (int i = 0; i < 3; i++)
        sec[i].ready = false;
    /* The projection test looks half an edge above and below. */
    double margin = 0.5 * x->maxlen;
    for (int i = 0; i < 3; i++) {
        lo[i] -= margin;
        hi[i] += margin;
    }
    tessel_status st = tsl_trigrid_query(&s->grid, lo, hi);
    if (st)
        return st;
    for (size_t i = 0; i < s->grid.hits.count; i++) {
        uint32_t t = s->grid.hits.found[i];
        const af_tinfo *info = &s->ti[t];
        /* The box first: it rejects about a quarter, and erased triangles
         * are rare. */
        if (info->hi[0] < lo[0] || info->lo[0] > hi[0] || info->hi[1] < lo[1] ||
            info->lo[1] > hi[1] || info->hi[2] < lo[2] || info->lo[2] > hi[2])
            continue;
        if (s->tri[3 * (size_t)t] == NONE)
            continue;
        const uint32_t *ev = s->tri + 3 * (size_t)t;
        double q[3][3], ne[3] = {info->n[0], info->n[1], info->n[2]};
        /* The stored box is exact (float corners). */
        double elo[3] = {info->lo[0], info->lo[1], info->lo[2]};
        double ehi[3] = {info->hi[0], info->hi[1], info->hi[2]};
        for (int j = 0; j < 3; j++)
            point(s, ev[j], q[j]);
        const double *pe[3] = {q[0], q[1], q[2]};
        if (conflict(x, star, sec, xlo, xhi, ev, pe, elo, ehi, ne))
            return TESSEL_OK;
    }
    if (other) {
        const double *pe[3] = {other->p[0], other->p[1], other->p[2]};
        double elo[3], ehi[3];
        tsl_af_tri_box(pe, elo, ehi);
        if (conflict(x, star, sec, xlo, xhi, other->v, pe, elo, ehi, other->n))
            return TESSEL_OK;
    }
    *ok = true;
    return TESSEL_OK;
}
