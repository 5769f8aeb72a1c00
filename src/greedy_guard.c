/* Exact validity guard of the greedy projection reconstruction: a new
 * triangle is accepted only if it meets no held triangle except in a shared
 * vertex or edge, decided with exact orient2d/orient3d (same semantics as
 * the mesh check, src/check.c). Most held triangles are ruled out without a
 * test by the free-cone certificate: the projection on R's plane is linear,
 * so triangles whose images stay out of R's free sector cannot meet the new
 * triangles, which lie in it. The paper (Gopi & Krishnan 2002, section 4.1,
 * Theorem 4.1) relies on its sampling assumptions here instead. */
#include "greedy_internal.h"

/* Exact: a, b, c collinear (a zero-area triangle). */
int tsl_gp_collinear3(const double a[3], const double b[3], const double c[3])
{
    const double *p[3] = {a, b, c};
    return tsl_triangle_degenerate(p);
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
        if (tsl_triangles_intersect(v, pa, T->v, pb))
            return 0;
    }
    return 1;
}

