/* Exact validity guard of the greedy projection reconstruction: a new
 * triangle is accepted only if it meets no held triangle except in a shared
 * vertex or edge, decided with exact orient2d/orient3d (same semantics as
 * the mesh check, src/check.c). Most held triangles are ruled out without a
 * test by the free-cone certificate: the projection on R's plane is linear,
 * so triangles whose images stay out of R's free sector cannot meet the new
 * triangles, which lie in it. The paper (Gopi & Krishnan 2002, section 4.1,
 * Theorem 4.1) relies on its sampling assumptions here instead. */
#include "greedy_internal.h"

static int projection_axis(const double a[3], const double b[3], const double c[3],
                           int *orient)
{
    double u[3], v[3], nn[3];
    tsl_sub(b, a, u);
    tsl_sub(c, a, v);
    tsl_cross(u, v, nn);
    int first = 0;
    if (fabs(nn[1]) > fabs(nn[first]))
        first = 1;
    if (fabs(nn[2]) > fabs(nn[first]))
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

static inline void proj2(const double p[3], int drop, double out[2])
{
    out[0] = p[(drop + 1) % 3];
    out[1] = p[(drop + 2) % 3];
}

/* Exact: a, b, c collinear (a zero-area triangle). */
int tsl_gp_collinear3(const double a[3], const double b[3], const double c[3])
{
    for (int drop = 0; drop < 3; drop++) {
        double pa[2], pb[2], pc[2];
        proj2(a, drop, pa);
        proj2(b, drop, pb);
        proj2(c, drop, pc);
        if (tsl_orient2d(pa, pb, pc) != 0.0)
            return 0;
    }
    return 1;
}

static int on_segment2(const double p[2], const double q[2], const double r[2])
{
    return fmin(p[0], q[0]) <= r[0] && r[0] <= fmax(p[0], q[0]) && fmin(p[1], q[1]) <= r[1] &&
           r[1] <= fmax(p[1], q[1]);
}

static int segments_meet2(const double p[2], const double q[2], const double a[2],
                          const double b[2])
{
    int d1 = sgn(tsl_orient2d(p, q, a)), d2 = sgn(tsl_orient2d(p, q, b));
    int d3 = sgn(tsl_orient2d(a, b, p)), d4 = sgn(tsl_orient2d(a, b, q));
    if (d1 * d2 < 0 && d3 * d4 < 0)
        return 1;
    return (d1 == 0 && on_segment2(p, q, a)) || (d2 == 0 && on_segment2(p, q, b)) ||
           (d3 == 0 && on_segment2(a, b, p)) || (d4 == 0 && on_segment2(a, b, q));
}

static int in_triangle2(const double p[2], const double a[2], const double b[2],
                        const double c[2], int o)
{
    return sgn(tsl_orient2d(a, b, p)) * o >= 0 && sgn(tsl_orient2d(b, c, p)) * o >= 0 &&
           sgn(tsl_orient2d(c, a, p)) * o >= 0;
}

static int coplanar_segment_triangle(const double p[3], const double q[3], const double a[3],
                                     const double b[3], const double c[3])
{
    int o;
    int drop = projection_axis(a, b, c, &o);
    double p2[2], q2[2], a2[2], b2[2], c2[2];
    proj2(p, drop, p2);
    proj2(q, drop, q2);
    proj2(a, drop, a2);
    proj2(b, drop, b2);
    proj2(c, drop, c2);
    return in_triangle2(p2, a2, b2, c2, o) || in_triangle2(q2, a2, b2, c2, o) ||
           segments_meet2(p2, q2, a2, b2) || segments_meet2(p2, q2, b2, c2) ||
           segments_meet2(p2, q2, c2, a2);
}

/* Closed segment pq meets closed non-degenerate triangle abc. */
static int segment_triangle(const double p[3], const double q[3], const double a[3],
                            const double b[3], const double c[3])
{
    int sp = sgn(tsl_orient3d(a, b, c, p)), sq = sgn(tsl_orient3d(a, b, c, q));
    if (sp * sq > 0)
        return 0;
    if (sp == 0 && sq == 0)
        return coplanar_segment_triangle(p, q, a, b, c);
    int s1 = sgn(tsl_orient3d(p, q, a, b));
    int s2 = sgn(tsl_orient3d(p, q, b, c));
    int s3 = sgn(tsl_orient3d(p, q, c, a));
    int pos_ = s1 > 0 || s2 > 0 || s3 > 0;
    int neg = s1 < 0 || s2 < 0 || s3 < 0;
    return !(pos_ && neg);
}

static int triangles_meet(const double *a[3], const double *b[3])
{
    int s0 = sgn(tsl_orient3d(a[0], a[1], a[2], b[0]));
    int s1 = sgn(tsl_orient3d(a[0], a[1], a[2], b[1]));
    int s2 = sgn(tsl_orient3d(a[0], a[1], a[2], b[2]));
    if ((s0 > 0 && s1 > 0 && s2 > 0) || (s0 < 0 && s1 < 0 && s2 < 0))
        return 0;
    s0 = sgn(tsl_orient3d(b[0], b[1], b[2], a[0]));
    s1 = sgn(tsl_orient3d(b[0], b[1], b[2], a[1]));
    s2 = sgn(tsl_orient3d(b[0], b[1], b[2], a[2]));
    if ((s0 > 0 && s1 > 0 && s2 > 0) || (s0 < 0 && s1 < 0 && s2 < 0))
        return 0;
    for (int k = 0; k < 3; k++) {
        if (segment_triangle(a[k], a[(k + 1) % 3], b[0], b[1], b[2]))
            return 1;
        if (segment_triangle(b[k], b[(k + 1) % 3], a[0], a[1], a[2]))
            return 1;
    }
    return 0;
}

/* Non-degenerate triangles with vertex ids ia, ib and coordinates pa, pb
 * meet in more than their shared vertex or edge (a duplicate counts). */
static int faces_intersect(const uint32_t ia[3], const uint32_t ib[3], const double *pa[3],
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
        return 1;
    if (shared == 2) {
        const double *p = pa[sa[0]], *q = pa[sa[1]];
        const double *ra = pa[3 - sa[0] - sa[1]], *rb = pb[3 - sb[0] - sb[1]];
        if (tsl_orient3d(p, q, ra, rb) != 0.0)
            return 0;
        int o;
        int drop = projection_axis(p, q, ra, &o);
        double p2[2], q2[2], rb2[2];
        proj2(p, drop, p2);
        proj2(q, drop, q2);
        proj2(rb, drop, rb2);
        return sgn(tsl_orient2d(p2, q2, rb2)) == o;
    }
    if (shared == 1) {
        int i = sa[0], j = sb[0];
        return segment_triangle(pb[(j + 1) % 3], pb[(j + 2) % 3], pa[0], pa[1], pa[2]) ||
               segment_triangle(pa[(i + 1) % 3], pa[(i + 2) % 3], pb[0], pb[1], pb[2]);
    }
    return triangles_meet(pa, pb);
}


/* ---- the free-cone certificate and the guard ---- */

/* Squared distance from q to the free cone (0 inside). */
static inline double cone_dist2(const gp_cone *c, const double q[2])
{
    double ce = cross2(c->e2[0], c->e2[1], q[0], q[1]);
    double cs = cross2(q[0], q[1], c->s2[0], c->s2[1]);
    int inside = c->convex ? (ce >= 0.0 && cs >= 0.0) : (ce >= 0.0 || cs >= 0.0);
    if (inside)
        return 0.0;
    double best = q[0] * q[0] + q[1] * q[1];
    for (int k = 0; k < 2; k++) {
        const double *d = k ? c->su : c->eu;
        if (q[0] * d[0] + q[1] * d[1] > 0.0) {
            double x = cross2(d[0], d[1], q[0], q[1]);
            if (x * x < best)
                best = x * x;
        }
    }
    return best;
}

/* Per-point tests behind the certificate. A triangle stays out of the free
 * cone (except for R, e, s themselves) when its three vertices pass a
 * common test:
 *  - free sector over 180 degrees (mesh sector convex): the vertex is
 *    strictly inside the mesh sector (or is R, e or s);
 *  - free sector under 180 degrees: all three strictly beyond the line
 *    through R and e (e and R allowed on it), or beyond the line through R
 *    and s, or behind R across the bisector (R allowed). */
enum { CONE_IN_MESH = 1, CONE_SIDE_E = 2, CONE_SIDE_S = 4, CONE_BEHIND = 8 };

static inline unsigned cone_flags(const gp_cone *c, uint32_t v, const double q[2])
{
    if (v == c->R)
        return CONE_IN_MESH | CONE_SIDE_E | CONE_SIDE_S | CONE_BEHIND;
    unsigned f = 0;
    double ce = cross2(c->e2[0], c->e2[1], q[0], q[1]);
    double cs = cross2(q[0], q[1], c->s2[0], c->s2[1]);
    if (!c->convex) {
        if (v == c->e || v == c->s || (-cs > c->eps && -ce > c->eps))
            f |= CONE_IN_MESH;
        return f;
    }
    if (v == c->e || ce < -c->eps)
        f |= CONE_SIDE_E;
    if (v == c->s || cs < -c->eps)
        f |= CONE_SIDE_S;
    if (q[0] * c->bis[0] + q[1] * c->bis[1] < -c->eps)
        f |= CONE_BEHIND;
    return f;
}

/* R's projection of point i and its cone flags, through the cache. */
static inline unsigned project_cached(gp *g, uint32_t R, const gp_frame *f, uint32_t i,
                                      double xy[2])
{
    gp_pcache *c = &g->pc[i & (PCACHE - 1)];
    if (c->idx != i || c->stamp != g->stamp) {
        double q[2];
        project_point(g, R, f, i, q);
        c->idx = i;
        c->stamp = g->stamp;
        c->x = q[0];
        c->y = q[1];
        c->flags = g->cone.on ? cone_flags(&g->cone, i, q) : 0;
    }
    xy[0] = c->x;
    xy[1] = c->y;
    return c->flags;
}

static tessel_status guard_push(gp *g, uint32_t t, const gp_cone *cone, const gp_frame *f,
                                const float lo[3], const float hi[3])
{
    g->tstamp[t] = g->stamp;
    const gp_tri *T = &g->tri[t];
    /* Outside the new triangles' box: cannot meet them. */
    float tl[3], th[3];
    tsl_gp_tri_box(g, T->v, tl, th);
    if (tl[0] > hi[0] || th[0] < lo[0] || tl[1] > hi[1] || th[1] < lo[1] || tl[2] > hi[2] ||
        th[2] < lo[2])
        return TESSEL_OK;
    if (cone->on) {
        double q[2];
        unsigned fl = project_cached(g, cone->R, f, T->v[0], q);
        fl &= project_cached(g, cone->R, f, T->v[1], q);
        fl &= project_cached(g, cone->R, f, T->v[2], q);
        if (fl)
            return TESSEL_OK;
    }
    if (grow((void **)&g->gt, &g->gt_cap, g->gt_count + 1, sizeof *g->gt))
        return TESSEL_ERR_NOMEM;
    gp_gtri *e = &g->gt[g->gt_count++];
    e->t = t;
    memcpy(e->lo, tl, sizeof tl);
    memcpy(e->hi, th, sizeof th);
    return TESSEL_OK;
}

/* Collects the held triangles that a new triangle in the box [flo, fhi]
 * (within f->reach of R) could meet and that the cone does not rule out:
 * those with a vertex in the box of half-size reach + delta around R (a
 * triangle whose vertices all lie outside has an edge longer than ell and
 * is in the long-triangle grid). A point farther from the new triangles'
 * box, or whose projection is farther from the free cone, than its longest
 * edge cannot have a triangle reaching them: skipped whole. */
tessel_status tsl_gp_guard_collect(gp *g, uint32_t R, const gp_frame *f, int use_cone)
{
    double half = f->reach + g->delta;
    g->stamp++;
    if (g->stamp == 0) {
        for (size_t t = 0; t < g->tused; t++)
            g->tstamp[t] = 0;
        g->stamp = 1;
    }
    g->gt_count = 0;
    gp_cone cone;
    memset(&cone, 0, sizeof cone);
    cone.R = R;
    cone.e = cone.s = NONE;
    if (use_cone) {
        cone.on = 1;
        cone.e = g->le[R];
        cone.s = g->ls[R];
        project_point(g, R, f, cone.e, cone.e2);
        project_point(g, R, f, cone.s, cone.s2);
        cone.convex = cross2(cone.e2[0], cone.e2[1], cone.s2[0], cone.s2[1]) > 0.0;
        double le_ = sqrt(cone.e2[0] * cone.e2[0] + cone.e2[1] * cone.e2[1]);
        double ls_ = sqrt(cone.s2[0] * cone.s2[0] + cone.s2[1] * cone.s2[1]);
        cone.eu[0] = cone.e2[0] / le_;
        cone.eu[1] = cone.e2[1] / le_;
        cone.su[0] = cone.s2[0] / ls_;
        cone.su[1] = cone.s2[1] / ls_;
        cone.bis[0] = cone.eu[0] + cone.su[0];
        cone.bis[1] = cone.eu[1] + cone.su[1];
        double span = 2.0 * half + g->ell;
        cone.eps = 1e-9 * span * span;
    }
    g->cone = cone;
    const float *r = g->xyz + 3 * (size_t)R;
    float lo[3], hi[3];
    for (int k = 0; k < 3; k++) {
        /* The new triangles' box, rounded outward to floats. */
        lo[k] = nextafterf((float)(r[k] + f->flo[k]), -INFINITY);
        hi[k] = nextafterf((float)(r[k] + f->fhi[k]), INFINITY);
    }
    tessel_status s;
    for (size_t k = 0; k < g->box_count; k++) {
        const gp_box *b = &g->box[k];
        uint32_t v = b->idx;
        if ((double)b->dinf > half || g->head[v] == NONE)
            continue;
        /* v's triangles lie within its longest edge of it: none reaches the
         * new triangles' box if v is farther from it than that. */
        double out = 0.0;
        for (int a = 0; a < 3; a++)
            out = dmax(out, dmax(f->flo[a] - b->rel[a], b->rel[a] - f->fhi[a]));
        if (out > (double)g->maxe[v] * (1.0 + 1e-9) + 1e-9 * half)
            continue;
        if (cone.on) {
            double q[2] = {tsl_dot(b->rel, f->u), tsl_dot(b->rel, f->v)};
            gp_pcache *pc = &g->pc[v & (PCACHE - 1)];
            pc->idx = v;
            pc->stamp = g->stamp;
            pc->x = q[0];
            pc->y = q[1];
            pc->flags = cone_flags(&cone, v, q);
            double reach_v = (double)g->maxe[v] * (1.0 + 1e-9) + 1e-9 * half;
            if (cone_dist2(&cone, q) > reach_v * reach_v)
                continue;
        }
        for (uint32_t t = g->head[v]; t != NONE;) {
            const gp_tri *T = &g->tri[t];
            if (g->tstamp[t] != g->stamp && (s = guard_push(g, t, &cone, f, lo, hi)) != TESSEL_OK)
                return s;
            t = T->next[tri_pos(T, v)];
        }
    }
    /* R's own triangles (R is not in its box). */
    for (uint32_t t = g->head[R]; t != NONE;) {
        const gp_tri *T = &g->tri[t];
        if (g->tstamp[t] != g->stamp && (s = guard_push(g, t, &cone, f, lo, hi)) != TESSEL_OK)
            return s;
        t = T->next[tri_pos(T, R)];
    }
    /* Long triangles of the cells the box overlaps. */
    if (!g->lg_slots)
        return TESSEL_OK;
    uint32_t c0[3], c1[3];
    tsl_gp_lg_cells(g, lo, hi, c0, c1);
    for (uint32_t z = c0[2]; z <= c1[2]; z++)
        for (uint32_t y = c0[1]; y <= c1[1]; y++)
            for (uint32_t x = c0[0]; x <= c1[0]; x++) {
                size_t h = lg_find(g, lg_key(x, y, z));
                if (!g->lg_keys[h])
                    continue;
                for (uint32_t e = g->lg_head[h]; e != NONE; e = g->lt_next[e]) {
                    uint32_t t = g->lt_tri[e];
                    if (g->tstamp[t] == g->stamp)
                        continue;
                    if ((s = guard_push(g, t, &cone, f, lo, hi)) != TESSEL_OK)
                        return s;
                }
            }
    return TESSEL_OK;
}

/* The new triangle v meets no collected held triangle except in a shared
 * vertex or edge. */
int tsl_gp_guard_ok(gp *g, const uint32_t v[3])
{
    float lo[3], hi[3];
    tsl_gp_tri_box(g, v, lo, hi);
    double p[3][3];
    for (int k = 0; k < 3; k++)
        pos(g, v[k], p[k]);
    const double *pa[3] = {p[0], p[1], p[2]};
    for (size_t i = 0; i < g->gt_count; i++) {
        const gp_gtri *e = &g->gt[i];
        if (e->lo[0] > hi[0] || e->hi[0] < lo[0] || e->lo[1] > hi[1] || e->hi[1] < lo[1] ||
            e->lo[2] > hi[2] || e->hi[2] < lo[2])
            continue;
        const gp_tri *T = &g->tri[e->t];
        double q[3][3];
        for (int k = 0; k < 3; k++)
            pos(g, T->v[k], q[k]);
        const double *pb[3] = {q[0], q[1], q[2]};
        if (faces_intersect(v, T->v, pa, pb))
            return 0;
    }
    return 1;
}

