/* Exact validity guard of the greedy projection reconstruction: a new
 * triangle is accepted only if it meets no held triangle except in a shared
 * vertex or edge, decided with exact orient2d/orient3d (same semantics as
 * the mesh check, src/check/). Most held triangles are ruled out without a
 * test by the free-cone certificate: the projection on R's plane is linear,
 * so triangles whose images stay out of R's free sector cannot meet the new
 * triangles, which lie in it. The paper (Gopi & Krishnan 2002, section 4.1,
 * Theorem 4.1) relies on its sampling assumptions here instead. The
 * front's triangles must also not lie on a held triangle as a second layer
 * (second_layer), which uniformly random samples otherwise make. */
#include "greedy/greedy.h"

/* Exact: a, b, c collinear (a zero-area triangle). */
int tsl_gp_collinear3(const double a[3], const double b[3], const double c[3])
{
    /* Filter: a cross product component clearly away from zero (bound far
     * above the rounding of the differences and products) settles it. */
    double u[3], v[3];
    tsl_sub(b, a, u);
    tsl_sub(c, a, v);
    for (int k = 0; k < 3; k++) {
        int i = (k + 1) % 3, j = (k + 2) % 3;
        double x = u[i] * v[j], y = u[j] * v[i];
        if (fabs(x - y) > 1e-14 * (fabs(x) + fabs(y)))
            return 0;
    }
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

/* Per-point marks of one collection (g->pmark): the stamp above, then
 * whether the point passes and its CONE_* flags. */
enum { PM_FLAGS = 15, PM_PASS = 16, PM_SHIFT = 6 };
#define PM_STAMP_MAX (UINT32_MAX >> PM_SHIFT)

/* Context of one collection. */
typedef struct gp_gctx {
    const gp_cone *cone;
    const gp_frame *f;
    const float *r;   /* R's position */
    double half;
    double tiny;      /* 1e-9 * half: rounding margin */
    uint32_t mark;    /* stamp << PM_SHIFT */
    float lo[3], hi[3];
} gp_gctx;

/* Whether some triangle of point v (at rel from R) could meet a new
 * triangle, and v's cone flags. Every point of a triangle lies within the
 * triangle's longest edge of each of its vertices, so a triangle meeting a
 * new one has all three vertices within their longest edge of the new
 * triangles' box and, in R's projection, of the free cone. Returns the
 * PM_PASS | flags bits (0: no triangle of v needs a test). */
static inline unsigned point_test(const gp *g, const gp_gctx *c, uint32_t v, const double rel[3])
{
    const gp_frame *f = c->f;
    double reach_v = (double)g->maxe[v] * (1.0 + 1e-9) + c->tiny;
    for (int a = 0; a < 3; a++)
        if (f->flo[a] - rel[a] > reach_v || rel[a] - f->fhi[a] > reach_v)
            return 0;
    /* The new triangles lie in the ball of radius reach around R. */
    double ball = f->reach + reach_v;
    if (tsl_dot(rel, rel) > ball * ball * (1.0 + 1e-9))
        return 0;
    if (!c->cone->on)
        return PM_PASS;
    double q[2] = {tsl_dot(rel, f->u), tsl_dot(rel, f->v)};
    if (cone_dist2(c->cone, q) > reach_v * reach_v)
        return 0;
    return PM_PASS | cone_flags(c->cone, v, q);
}

/* The marks of a triangle vertex w, computed once per collection. */
static inline uint32_t vertex_marks(gp *g, const gp_gctx *c, uint32_t w)
{
    uint32_t m = g->pmark[w];
    if ((m & ~(uint32_t)63) == c->mark)
        return m;
    const float *p = g->xyz + 3 * (size_t)w;
    double rel[3] = {(double)p[0] - c->r[0], (double)p[1] - c->r[1], (double)p[2] - c->r[2]};
    m = c->mark | point_test(g, c, w, rel);
    g->pmark[w] = m;
    return m;
}

/* Adds held triangle t (float box tl, th, known to overlap the new
 * triangles' box) to the collection unless the cone certificate rules it
 * out; flags: the AND of its vertices' cone flags. */
static inline tessel_status guard_push(gp *g, const gp_gctx *c, uint32_t t, unsigned flags,
                                       const float tl[3], const float th[3])
{
    if (c->cone->on && flags)
        return TESSEL_OK;
    if (g->gt_count == g->gt_cap &&
        grow((void **)&g->gt, &g->gt_cap, g->gt_count + 1, sizeof *g->gt))
        return TESSEL_ERR_NOMEM;
    gp_gtri *e = &g->gt[g->gt_count++];
    e->t = t;
    e->fan = 0;
    memcpy(e->lo, tl, 3 * sizeof *tl);
    memcpy(e->hi, th, 3 * sizeof *th);
    return TESSEL_OK;
}

/* Whether held triangle t's stored box overlaps the new triangles' box (the
 * first test: it rejects most and reads no vertex). */
static inline int box_meets(const gp *g, const gp_gctx *c, uint32_t t)
{
    const float *tl = g->tbox + 6 * (size_t)t, *th = tl + 3;
    return !(tl[0] > c->hi[0] || th[0] < c->lo[0] || tl[1] > c->hi[1] || th[1] < c->lo[1] ||
             tl[2] > c->hi[2] || th[2] < c->lo[2]);
}

/* Held triangle t, whose box meets the new triangles' box, if its three
 * vertices pass point_test. */
static tessel_status guard_consider(gp *g, const gp_gctx *c, uint32_t t)
{
    const gp_tri *T = &g->tri[t];
    const float *tl = g->tbox + 6 * (size_t)t, *th = tl + 3;
    unsigned fl = PM_PASS | PM_FLAGS;
    for (int j = 0; j < 3 && (fl & PM_PASS); j++)
        fl &= vertex_marks(g, c, T->v[j]);
    if (!(fl & PM_PASS))
        return TESSEL_OK;
    return guard_push(g, c, t, fl & PM_FLAGS, tl, th);
}

/* Collects the held triangles that a new triangle in the box [flo, fhi]
 * (within f->reach of R) could meet and that the cone does not rule out.
 * A triangle whose edges are at most L meets that box only if its centroid
 * lies within L / sqrt(3) of it (every point of a triangle is within
 * L / sqrt(3) of its centroid), and L / sqrt(3) <= f->delta for the short
 * triangles near R: those are found in the cells of the short-triangle grid
 * that the box widened by f->delta overlaps, each listed once. Longer
 * triangles are in the long-triangle grid. */
void tsl_gp_guard_defer(gp *g, uint32_t R, const gp_frame *f, int use_cone)
{
    double half = f->reach + f->delta;
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
    double span = 2.0 * half + g->ell;
    g->fan_eps = 1e-9 * span * span;
    g->guard_R = R;
    g->guard_f = f;
    g->guard_pending = 1;
}

tessel_status tsl_gp_guard_ready(gp *g)
{
    if (!g->guard_pending)
        return TESSEL_OK;
    g->guard_pending = 0;
    uint32_t R = g->guard_R;
    const gp_frame *f = g->guard_f;
    double half = f->reach + f->delta;
    g->stamp++;
    if (g->stamp > PM_STAMP_MAX) {
        memset(g->pmark, 0, g->n * sizeof *g->pmark);
        if (g->tused)
            memset(g->tstamp, 0, g->tused * sizeof *g->tstamp);
        g->stamp = 1;
    }
    gp_gctx c;
    c.cone = &g->cone;
    c.f = f;
    c.r = g->xyz + 3 * (size_t)R;
    c.half = half;
    c.tiny = 1e-9 * half;
    c.mark = g->stamp << PM_SHIFT;
    for (int k = 0; k < 3; k++) {
        /* The new triangles' box, rounded outward to floats. */
        c.lo[k] = tsl_float_down((float)(c.r[k] + f->flo[k]));
        c.hi[k] = tsl_float_up((float)(c.r[k] + f->fhi[k]));
    }
    tessel_status s;
    g->pmark[R] = c.mark | PM_PASS | PM_FLAGS;
    if (g->sg.slots) {
        double m = f->delta * (1.0 + 1e-6) + c.tiny;
        uint32_t q0[3], q1[3];
        for (int k = 0; k < 3; k++) {
            q0[k] = sg_coord(g, (double)c.lo[k] - m, k);
            q1[k] = sg_coord(g, (double)c.hi[k] + m, k);
        }
        for (uint32_t z = q0[2]; z <= q1[2]; z++)
            for (uint32_t y = q0[1]; y <= q1[1]; y++)
                for (uint32_t x = q0[0]; x <= q1[0]; x++) {
                    size_t h = cells_find(&g->sg, lg_key(x, y, z));
                    if (!g->sg.slot[h].key)
                        continue;
                    for (uint32_t t = g->sg.slot[h].head; t != NONE; t = g->tsg_next[t])
                        if (box_meets(g, &c, t) && (s = guard_consider(g, &c, t)) != TESSEL_OK)
                            return s;
                }
    }
    /* Long triangles of the cells the box overlaps, each once. */
    if (!g->lg.slots)
        return TESSEL_OK;
    uint32_t c0[3], c1[3];
    tsl_gp_lg_cells(g, c.lo, c.hi, c0, c1);
    for (uint32_t z = c0[2]; z <= c1[2]; z++)
        for (uint32_t y = c0[1]; y <= c1[1]; y++)
            for (uint32_t x = c0[0]; x <= c1[0]; x++) {
                size_t h = cells_find(&g->lg, lg_key(x, y, z));
                if (!g->lg.slot[h].key)
                    continue;
                for (uint32_t e = g->lg.slot[h].head; e != NONE; e = g->lt_next[e]) {
                    uint32_t t = g->lt_tri[e];
                    if (g->tstamp[t] == g->stamp)
                        continue;
                    g->tstamp[t] = g->stamp;
                    if (box_meets(g, &c, t) && (s = guard_consider(g, &c, t)) != TESSEL_OK)
                        return s;
                }
            }
    return TESSEL_OK;
}

tessel_status tsl_gp_guard_collect(gp *g, uint32_t R, const gp_frame *f, int use_cone)
{
    tsl_gp_guard_defer(g, R, f, use_cone);
    return tsl_gp_guard_ready(g);
}

/* Fan certificate: triangles N = (R, a, b) and O = (R, c, d) of R's fan
 * (a, b, c, d projected on R's plane, N counter-clockwise) meet only in
 * shared vertices or edges when O's vertices other than b lie strictly left
 * of the line from R through b (N lies on its closed right side and meets
 * it only in its edge Rb), or O's vertices other than a strictly right of
 * the line through a. The projection is linear: the images then meet only
 * in the images of R and a shared edge, so the triangles meet only there.
 * The margin covers the rounding of the projections. Consecutive triangles
 * of a fan, and most others, pass; the rest get the exact test. */
static inline int fan_separated(const uint32_t v[3], const double a[2], const double b[2],
                                const gp_tri *T, const gp_gtri *o, double eps)
{
    if (!(cross2(a[0], a[1], b[0], b[1]) > eps))
        return 0;
    const double *x[2] = {o->p1, o->p2};
    int left = 1, right = 1;
    for (int k = 0; k < 2; k++) {
        uint32_t id = T->v[k + 1];
        if (id != v[2] && !(cross2(b[0], b[1], x[k][0], x[k][1]) > eps))
            left = 0;
        if (id != v[1] && !(cross2(x[k][0], x[k][1], a[0], a[1]) > eps))
            right = 0;
    }
    return left || right;
}

/* The new triangle (v, p) as second_layer needs it: its normal n (e1 x e2),
 * its longest edge squared, a frame (u, t) of its plane and its image in
 * that frame, counter-clockwise. Made once per new triangle. */
typedef struct layer_ref {
    const uint32_t *v;
    const double (*p)[3];
    double n[3], nn, l2, u[3], t[3], a[3][2];
} layer_ref;

static void layer_ref_make(layer_ref *L, const uint32_t v[3], const double p[3][3])
{
    double e1[3], e2[3];
    L->v = v;
    L->p = p;
    tsl_sub(p[1], p[0], e1);
    tsl_sub(p[2], p[0], e2);
    tsl_cross(e1, e2, L->n);
    L->nn = tsl_dot(L->n, L->n);
    L->l2 = 0.0;
    for (int k = 0; k < 3; k++) {
        double d[3];
        tsl_sub(p[(k + 1) % 3], p[k], d);
        L->l2 = fmax(L->l2, tsl_dot(d, d));
    }
    memcpy(L->u, e1, sizeof L->u);
    tsl_cross(L->n, L->u, L->t);
    tsl_normalize(L->u);
    tsl_normalize(L->t);
    for (int k = 0; k < 3; k++) {
        double d[3];
        tsl_sub(p[k], p[0], d);
        L->a[k][0] = tsl_dot(d, L->u);
        L->a[k][1] = tsl_dot(d, L->t);
    }
}

/* Whether held triangle (w, q) lies on the new triangle L as a second
 * layer: facing the same way (normals within acos(LAYER_COS)), each vertex
 * within LAYER_HEIGHT of L's longest edge off L's plane, and the two
 * overlapping with positive area in that plane (no line through an edge of
 * either has the other on its outer side). The two need not cross, so the
 * exact test lets them pass; but the surface there would be covered twice,
 * and the loop left between the layers winds the wrong way. */
static int second_layer(const layer_ref *L, const uint32_t w[3], const double q[3][3])
{
    const double *p0 = L->p[0];
    double f1[3], f2[3], m[3];
    tsl_sub(q[1], q[0], f1);
    tsl_sub(q[2], q[0], f2);
    tsl_cross(f1, f2, m);
    double c = tsl_dot(m, L->n);
    if (!(c > 0.0) || c * c < LAYER_COS * LAYER_COS * tsl_dot(m, m) * L->nn)
        return 0;
    for (int k = 0; k < 3; k++) {
        if (w[k] == L->v[0] || w[k] == L->v[1] || w[k] == L->v[2])
            continue;
        double d[3];
        tsl_sub(q[k], p0, d);
        double h = tsl_dot(d, L->n);
        if (h * h > LAYER_HEIGHT * LAYER_HEIGHT * L->l2 * L->nn)
            return 0;
    }
    double b[3][2];
    for (int k = 0; k < 3; k++) {
        double d[3];
        tsl_sub(q[k], p0, d);
        b[k][0] = tsl_dot(d, L->u);
        b[k][1] = tsl_dot(d, L->t);
    }
    /* Both images are counter-clockwise (c > 0). A shared vertex projects
     * to the same point in both, so touching images are separated. */
    const double(*x)[2] = L->a, (*y)[2] = b;
    for (int s = 0; s < 2; s++) {
        for (int k = 0; k < 3; k++) {
            const double *o = x[k], *e = x[(k + 1) % 3];
            int outside = 1;
            for (int j = 0; j < 3 && outside; j++)
                outside = cross2(e[0] - o[0], e[1] - o[1], y[j][0] - o[0], y[j][1] - o[1]) <= 0.0;
            if (outside)
                return 0;
        }
        x = b;
        y = L->a;
    }
    return 1;
}

/* The new triangle v meets no collected held triangle except in a shared
 * vertex or edge; with layers, it lies on none as a second layer either
 * (see second_layer). */
int tsl_gp_guard_ok(gp *g, const uint32_t v[3], const double q1[2], const double q2[2],
                    int layers)
{
    float lo[3], hi[3];
    tsl_gp_tri_box(g, v, lo, hi);
    double p[3][3];
    const double *pa[3] = {p[0], p[1], p[2]};
    layer_ref ref;
    int have_p = 0;
    for (size_t i = 0; i < g->gt_count; i++) {
        const gp_gtri *e = &g->gt[i];
        if (e->lo[0] > hi[0] || e->hi[0] < lo[0] || e->lo[1] > hi[1] || e->hi[1] < lo[1] ||
            e->lo[2] > hi[2] || e->hi[2] < lo[2])
            continue;
        const gp_tri *T = &g->tri[e->t];
        if (e->fan && q1 && T->v[0] == v[0] && fan_separated(v, q1, q2, T, e, g->fan_eps))
            continue;
        if (!have_p) {
            for (int k = 0; k < 3; k++)
                pos(g, v[k], p[k]);
            if (layers)
                layer_ref_make(&ref, v, (const double(*)[3])p);
            have_p = 1;
        }
        double q[3][3];
        for (int k = 0; k < 3; k++)
            pos(g, T->v[k], q[k]);
        const double *pb[3] = {q[0], q[1], q[2]};
        if (tsl_triangles_intersect(v, pa, T->v, pb) ||
            (layers && second_layer(&ref, T->v, (const double(*)[3])q)))
            return 0;
    }
    return 1;
}
