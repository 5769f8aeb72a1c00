/* Greedy projection reconstruction (Gopi & Krishnan 2002, "A fast and
 * efficient projection-based approach for surface reconstruction").
 *
 * Points are bucketed in the paper's dexel array (section 3: a 2D array of
 * columns, points sorted by depth in each). A breadth-first front grows
 * from a seed: each reference point R takes the free, fringe and boundary
 * points in a box of half-size mu*m around it, keeps those in the sphere of
 * influence (section 4.1, "distance criterion"), projects them on the plane
 * whose normal is the average of R's triangle normals (PCA for a seed;
 * nearest axis plane with --plane axis, section 6.1), orders them by angle,
 * removes the ones in R's invisible region, the ones that see R in theirs
 * and the ones hidden behind boundary edges of candidates (the three
 * visibility rules and Theorem 4.1), optionally drops skinny neighbours
 * (angle criterion, Figure 3), and joins consecutive survivors, leaving a
 * gap wider than alpha open (section 4.2).
 *
 * What the paper leaves to its sampling assumptions is enforced here,
 * exactly, for every triangle: (1) topology: each point's triangles form one
 * fan at all times (open or closed), every edge has at most two triangles
 * used in opposite directions, so the mesh is manifold and consistently
 * oriented by construction; (2) geometry: a triangle is accepted only if it
 * is not degenerate and meets no held triangle except in a shared vertex or
 * edge (exact orient2d/orient3d), nor, if the front made it, lies on one
 * as a second layer. Triangles are held while a live point is near enough
 * for a later triangle to reach them and streamed out after. See
 * docs/greedy.md. */
#include "greedy/greedy.h"

#include "core/grid.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static void frame_axes(gp_frame *f, int axis_plane)
{
    if (axis_plane) {
        int k = 0;
        if (fabs(f->n[1]) > fabs(f->n[k]))
            k = 1;
        if (fabs(f->n[2]) > fabs(f->n[k]))
            k = 2;
        double sgn_ = f->n[k] >= 0.0 ? 1.0 : -1.0;
        for (int i = 0; i < 3; i++)
            f->n[i] = f->u[i] = f->v[i] = 0.0;
        f->n[k] = sgn_;
        f->u[sgn_ > 0 ? (k + 1) % 3 : (k + 2) % 3] = 1.0;
        f->v[sgn_ > 0 ? (k + 2) % 3 : (k + 1) % 3] = 1.0;
        return;
    }
    int k = 0;
    if (fabs(f->n[1]) < fabs(f->n[k]))
        k = 1;
    if (fabs(f->n[2]) < fabs(f->n[k]))
        k = 2;
    double ax[3] = {0, 0, 0};
    ax[k] = 1.0;
    tsl_cross(f->n, ax, f->u);
    tsl_normalize(f->u);
    tsl_cross(f->n, f->u, f->v);
}

/* Normal of the least-squares plane through R (the origin) and the given
 * relative positions. */
static int pca_normal(const gp_cand *c, size_t count, double n[3])
{
    double mean[3] = {0, 0, 0};
    for (size_t i = 0; i < count; i++)
        for (int k = 0; k < 3; k++)
            mean[k] += c[i].rel[k];
    for (int k = 0; k < 3; k++)
        mean[k] /= (double)(count + 1);
    double cov[9] = {0};
    for (size_t i = 0; i <= count; i++) {
        double d[3];
        for (int k = 0; k < 3; k++)
            d[k] = (i < count ? c[i].rel[k] : 0.0) - mean[k];
        for (int r = 0; r < 3; r++)
            for (int q = 0; q < 3; q++)
                cov[3 * r + q] += d[r] * d[q];
    }
    double w[3], v[9];
    tsl_eigen_sym3(cov, w, v);
    if (!(w[1] > 0.0))
        return 0; /* collinear */
    n[0] = v[0];
    n[1] = v[3];
    n[2] = v[6];
    return tsl_normalize(n);
}

static tessel_status cand_push(gp *g, uint32_t idx, const double rel[3])
{
    if (grow((void **)&g->cand, &g->cand_cap, g->cand_count + 1, sizeof *g->cand))
        return TESSEL_ERR_NOMEM;
    gp_cand *c = &g->cand[g->cand_count++];
    c->idx = idx;
    c->kept = 1;
    c->rel[0] = rel[0];
    c->rel[1] = rel[1];
    c->rel[2] = rel[2];
    c->d2 = tsl_dot(rel, rel);
    c->x = c->y = c->key = 0.0;
    return TESSEL_OK;
}

/* Projects the candidates; those that fall onto R are dropped (they cannot
 * be ordered). Returns 0 if one of the required points (keep_a, keep_b)
 * projects onto R. */
static int project_cands(gp *g, const gp_frame *f, uint32_t keep_a, uint32_t keep_b)
{
    size_t w = 0;
    for (size_t i = 0; i < g->cand_count; i++) {
        gp_cand *c = &g->cand[i];
        c->x = tsl_dot(c->rel, f->u);
        c->y = tsl_dot(c->rel, f->v);
        if (!(c->x * c->x + c->y * c->y > 1e-12 * c->d2)) {
            if (c->idx == keep_a || c->idx == keep_b)
                return 0;
            continue;
        }
        g->cand[w++] = *c;
    }
    g->cand_count = w;
    return 1;
}

static int cmp_cand(const void *pa, const void *pb)
{
    const gp_cand *a = pa, *b = pb;
    if (a->key != b->key)
        return a->key < b->key ? -1 : 1;
    return a->idx < b->idx ? -1 : (a->idx > b->idx);
}

static void sort_cands(gp *g)
{
    /* Insertion sort: a few dozen candidates. */
    gp_cand *c = g->cand;
    for (size_t i = 1; i < g->cand_count; i++) {
        gp_cand x = c[i];
        size_t j = i;
        while (j > 0 && cmp_cand(&c[j - 1], &x) > 0) {
            c[j] = c[j - 1];
            j--;
        }
        c[j] = x;
    }
}

/* Of two kept candidates in exactly the same direction from R (a regular
 * grid has many), the farther is hidden behind the nearer: dropped (a
 * triangle through both would be degenerate). R's boundary neighbours end_a
 * and end_b are never dropped. The candidates must be sorted by angle. */
static void drop_hidden(gp *g, uint32_t end_a, uint32_t end_b)
{
    const double o[2] = {0.0, 0.0};
    for (size_t i = 0; i < g->cand_count; i++) {
        gp_cand *a = &g->cand[i];
        if (a->kept != 1)
            continue;
        for (size_t j = i + 1; j < g->cand_count && g->cand[j].key - a->key < 1e-9; j++) {
            gp_cand *b = &g->cand[j];
            double pa[2] = {a->x, a->y}, pb[2] = {b->x, b->y};
            if (b->kept != 1 || tsl_orient2d(o, pa, pb) != 0.0 || a->x * b->x + a->y * b->y <= 0.0)
                continue;
            int a_end = a->idx == end_a || a->idx == end_b;
            int b_end = b->idx == end_a || b->idx == end_b;
            gp_cand *drop = (b->d2 > a->d2 && !b_end) || a_end ? b : a;
            if (!(drop == a ? a_end : b_end))
                drop->kept = 0;
            if (a->kept != 1)
                break;
        }
    }
}

/* Visibility rules 2 and 3 of section 4.1 on the kept candidates: drop
 * those that have R in their invisible region (between their two boundary
 * edges) and those hidden from R by a boundary edge of a candidate
 * (Theorem 4.1: no other edge needs testing). ends: candidates never
 * dropped (R's own boundary neighbours). */
static tessel_status visibility(gp *g, uint32_t R, const gp_frame *f, uint32_t end_a,
                                uint32_t end_b)
{
    size_t nc = g->cand_count;
    /* Rule 2. */
    for (size_t i = 0; i < nc; i++) {
        gp_cand *c = &g->cand[i];
        if (c->kept != 1 || c->idx == end_a || c->idx == end_b || g->head[c->idx] == NONE)
            continue;
        uint32_t cs = g->ls[c->idx], ce = g->le[c->idx];
        if (cs == R || ce == R)
            continue;
        double ps[2], pe[2];
        project_point(g, R, f, cs, ps);
        project_point(g, R, f, ce, pe);
        double ax = ps[0] - c->x, ay = ps[1] - c->y;
        double bx = pe[0] - c->x, by = pe[1] - c->y;
        double rx = -c->x, ry = -c->y;
        double ar = cross2(ax, ay, rx, ry), rb = cross2(rx, ry, bx, by);
        int inside = cross2(ax, ay, bx, by) >= 0.0 ? (ar > 0.0 && rb > 0.0)
                                                    : (ar > 0.0 || rb > 0.0);
        if (inside)
            c->kept = 0;
    }
    /* Rule 3: boundary edges of the candidates as occluders; the ones that
     * may be hidden listed first. */
    if (grow((void **)&g->hide, &g->hide_cap, nc, sizeof *g->hide))
        return TESSEL_ERR_NOMEM;
    size_t nh = 0;
    for (size_t i = 0; i < nc; i++) {
        const gp_cand *x = &g->cand[i];
        if (x->kept == 1 && x->idx != end_a && x->idx != end_b)
            g->hide[nh++] = (uint32_t)i;
    }
    for (size_t j = 0; j < nc; j++) {
        const gp_cand *o = &g->cand[j];
        if (g->head[o->idx] == NONE)
            continue;
        for (int side = 0; side < 2; side++) {
            uint32_t other = side ? g->le[o->idx] : g->ls[o->idx];
            if (other == R)
                continue;
            double q[2];
            project_point(g, R, f, other, q);
            double px = o->x, py = o->y;
            for (size_t h = 0; h < nh; h++) {
                gp_cand *x = &g->cand[g->hide[h]];
                if (x->kept != 1 || x->idx == o->idx || x->idx == other)
                    continue;
                double o1 = cross2(x->x, x->y, px, py), o2 = cross2(x->x, x->y, q[0], q[1]);
                if (!((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0)))
                    continue;
                double ex = q[0] - px, ey = q[1] - py;
                double o3 = cross2(ex, ey, -px, -py), o4 = cross2(ex, ey, x->x - px, x->y - py);
                if ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
                    x->kept = 0;
            }
        }
    }
    return TESSEL_OK;
}

enum { TRY_OK = 0, TRY_FAIL, TRY_LEAD };

/* Tries to add the fan triangles (R, seq[j+i], seq[j+i+1]), i < cnt, as one
 * step: geometry (section 4.2 and the exact checks), then every point's fan
 * stays single, then no intersection. lead_last: the point that would need
 * the next triangle of the walk to attach is seq[j+cnt] (forward walk) or
 * seq[j] (backward walk). */
static tessel_status try_fan(gp *g, uint32_t R, const gp_frame *f, size_t j, int cnt,
                             int lead_last, int *result)
{
    *result = TRY_FAIL;
    double pr[3];
    pos(g, R, pr);
    double cap2 = 4.0 * g->rho_cap * g->rho_cap;
    for (int i = 0; i < cnt; i++) {
        const gp_cand *a = &g->cand[g->seq[j + (size_t)i]];
        const gp_cand *b = &g->cand[g->seq[j + (size_t)i + 1]];
        double o[2] = {0.0, 0.0}, pa2[2] = {a->x, a->y}, pb2[2] = {b->x, b->y};
        if (!(tsl_orient2d(o, pa2, pb2) > 0.0))
            return TESSEL_OK;
        /* Alpha (object space). */
        if (tsl_dot(a->rel, b->rel) < g->cos_alpha * sqrt(a->d2 * b->d2))
            return TESSEL_OK;
        double ab[3];
        tsl_sub(a->rel, b->rel, ab);
        if (tsl_dot(ab, ab) > cap2 || a->d2 > cap2 || b->d2 > cap2)
            return TESSEL_OK;
        /* Invariant 1: no free candidate may end up inside (it could never
         * be reached again). Points with triangles are protected by the
         * exact guard instead. */
        for (size_t k = 0; k < g->cand_count; k++) {
            const gp_cand *c = &g->cand[k];
            if (c->kept || c->idx == a->idx || c->idx == b->idx || g->head[c->idx] != NONE)
                continue;
            if (cross2(a->x, a->y, c->x, c->y) > 0.0 && cross2(c->x, c->y, b->x, b->y) > 0.0 &&
                cross2(b->x - a->x, b->y - a->y, c->x - a->x, c->y - a->y) > 0.0)
                return TESSEL_OK;
        }
        /* The same for the free points beyond rho, which a triangle to one
         * of R's boundary neighbours may reach past. */
        for (size_t k = 0; k < g->far_count; k++) {
            const double *c = g->far[k];
            if (cross2(a->x, a->y, c[0], c[1]) > 0.0 && cross2(c[0], c[1], b->x, b->y) > 0.0 &&
                cross2(b->x - a->x, b->y - a->y, c[0] - a->x, c[1] - a->y) > 0.0)
                return TESSEL_OK;
        }
        /* With the cone certificate, the triangle must provably lie in the
         * free cone: both ends inside it (or R's boundary neighbours) and
         * neither boundary ray inside the angle a R b. */
        const gp_cone *cn = &g->cone;
        if (cn->on) {
            const gp_cand *ends[2] = {a, b};
            for (int q = 0; q < 2; q++) {
                const gp_cand *x = ends[q];
                if (x->idx == cn->e || x->idx == cn->s)
                    continue;
                double ce = cross2(cn->e2[0], cn->e2[1], x->x, x->y);
                double cs = cross2(x->x, x->y, cn->s2[0], cn->s2[1]);
                int in = cn->convex ? (ce > cn->eps && cs > cn->eps)
                                    : (ce > cn->eps || cs > cn->eps);
                if (!in)
                    return TESSEL_OK;
            }
            for (int q = 0; q < 2; q++) {
                uint32_t ray = q ? cn->s : cn->e;
                const double *d = q ? cn->s2 : cn->e2;
                if (a->idx == ray || b->idx == ray)
                    continue;
                if (!(cross2(a->x, a->y, d[0], d[1]) < -cn->eps ||
                      cross2(d[0], d[1], b->x, b->y) < -cn->eps))
                    return TESSEL_OK;
            }
        }
        double qa[3], qb[3];
        pos(g, a->idx, qa);
        pos(g, b->idx, qb);
        if (tsl_gp_collinear3(pr, qa, qb))
            return TESSEL_OK;
        /* Steep (the fixed plane of height fields takes walls on purpose). */
        double nt[3];
        tsl_cross(a->rel, b->rel, nt);
        if (!g->plane_axis && tsl_dot(nt, f->n) < STEEP_COS * tsl_norm(nt))
            return TESSEL_OK;
        if (tsl_gp_edge_exists(g, R, a->idx) || tsl_gp_edge_exists(g, a->idx, b->idx) ||
            tsl_gp_edge_exists(g, b->idx, R))
            return TESSEL_OK;
    }
    /* Fans: R gets seq[j] -> ... -> seq[j+cnt]; the first point seq[j+1] ->
     * R; inner points seq[j+i+1] -> R -> seq[j+i-1]; the last R ->
     * seq[j+cnt-1]. */
    uint32_t pts[4];
    int how[4];
    uint32_t sa[4], sb[4];
    for (int i = 0; i <= cnt; i++) {
        pts[i] = g->cand[g->seq[j + (size_t)i]].idx;
        uint32_t before = i > 0 ? g->cand[g->seq[j + (size_t)i - 1]].idx : R;
        uint32_t after = i < cnt ? g->cand[g->seq[j + (size_t)i + 1]].idx : R;
        sa[i] = after;
        sb[i] = before;
        int edges = (i > 0) + (i < cnt);
        how[i] = tsl_gp_link_check(g, pts[i], after, before, edges);
        if (how[i] == LINK_FAIL) {
            int lead = lead_last ? i == cnt : i == 0;
            *result = lead ? TRY_LEAD : TRY_FAIL;
            return TESSEL_OK;
        }
    }
    int how_r = tsl_gp_link_check(g, R, pts[0], pts[cnt], cnt);
    if (how_r == LINK_FAIL)
        return TESSEL_OK;
    tessel_status gs = tsl_gp_guard_ready(g);
    if (gs != TESSEL_OK)
        return gs;
    for (int i = 0; i < cnt; i++) {
        uint32_t v[3] = {R, pts[i], pts[i + 1]};
        const gp_cand *a = &g->cand[g->seq[j + (size_t)i]];
        const gp_cand *b = &g->cand[g->seq[j + (size_t)i + 1]];
        double qa[2] = {a->x, a->y}, qb[2] = {b->x, b->y};
        if (!tsl_gp_guard_ok(g, v, qa, qb, 1)) {
            g->sum.rejected_intersecting++;
            return TESSEL_OK;
        }
    }
    /* Apply. */
    for (int i = 0; i < cnt; i++) {
        uint32_t t;
        tessel_status s = tsl_gp_tri_add(g, R, pts[i], pts[i + 1], 0, &t);
        if (s != TESSEL_OK)
            return s;
        if (grow((void **)&g->gt, &g->gt_cap, g->gt_count + 1, sizeof *g->gt))
            return TESSEL_ERR_NOMEM;
        gp_gtri *e = &g->gt[g->gt_count++];
        e->t = t;
        tsl_gp_tri_box(g, g->tri[t].v, e->lo, e->hi);
        /* Its projection, for the fan certificate of the next ones. */
        const gp_cand *a = &g->cand[g->seq[j + (size_t)i]];
        const gp_cand *b = &g->cand[g->seq[j + (size_t)i + 1]];
        e->fan = 1;
        e->p1[0] = a->x;
        e->p1[1] = a->y;
        e->p2[0] = b->x;
        e->p2[1] = b->y;
    }
    tsl_gp_link_apply(g, R, pts[0], pts[cnt], how_r, 1);
    for (int i = 0; i <= cnt; i++)
        tsl_gp_link_apply(g, pts[i], sa[i], sb[i], how[i], 0);
    *result = TRY_OK;
    return TESSEL_OK;
}

/* Whether c is a Delaunay neighbour of R (the origin) among the points of
 * seq in the projection: the bisector of R and c keeps a piece of positive
 * length on the border of R's Voronoi cell. The bisector is c / 2 + t c^perp;
 * each other point q bounds t through |x - q| >= |x|. */
static bool voronoi_neighbour(const gp *g, const gp_cand *c)
{
    double lo = -INFINITY, hi = INFINITY;
    for (size_t i = 0; i < g->seq_count; i++) {
        const gp_cand *q = &g->cand[g->seq[i]];
        if (q == c)
            continue;
        double a = 2.0 * (c->x * q->y - c->y * q->x);
        double rhs = q->x * q->x + q->y * q->y - (c->x * q->x + c->y * q->y);
        if (a > 0.0)
            hi = dmin(hi, rhs / a);
        else if (a < 0.0)
            lo = dmax(lo, rhs / a);
        else if (rhs < 0.0)
            return false;
    }
    return lo < hi;
}

/* Keeps of the candidates between R's boundary neighbours only R's
 * Delaunay neighbours in the projection (as Gopi, Krishnan & Silva 2000
 * do), fringe points too. Section 4.2 joins R to every visible candidate,
 * which leaves long thin triangles for the diagonal flips to undo. A
 * dropped point is outside the circumcircle of every fan triangle, so the
 * fan does not cover it: a free one is taken by a later reference point, a
 * fringe one keeps its own fan open for its turn. */
static void delaunay_fan(gp *g)
{
    for (size_t i = 1; i + 1 < g->seq_count; i++) {
        gp_cand *c = &g->cand[g->seq[i]];
        if (!voronoi_neighbour(g, c))
            c->kept = 0;
    }
    size_t w = 1;
    for (size_t i = 1; i + 1 < g->seq_count; i++)
        if (g->cand[g->seq[i]].kept)
            g->seq[w++] = g->seq[i];
    g->seq[w++] = g->seq[g->seq_count - 1];
    g->seq_count = w;
}

/* Angle criterion (section 4.1, Figure 3): while a neighbour makes an angle
 * below beta at R with the next one, drop it if that traps no point, i.e. it
 * lies beyond the edge joining its two neighbours, and leaves no gap wider
 * than alpha. Only free points are dropped (a fringe point must stay to
 * attach its fan). */
static void angle_criterion(gp *g)
{
    if (!(g->beta > 0.0))
        return;
    double cb = cos(g->beta);
    for (;;) {
        size_t best = 0;
        double best_cos = cb;
        for (size_t i = 1; i + 1 < g->seq_count; i++) {
            const gp_cand *p = &g->cand[g->seq[i - 1]], *c = &g->cand[g->seq[i]],
                          *q = &g->cand[g->seq[i + 1]];
            if (g->head[c->idx] != NONE)
                continue;
            double c1 = tsl_dot(p->rel, c->rel) / sqrt(p->d2 * c->d2);
            double c2 = tsl_dot(c->rel, q->rel) / sqrt(c->d2 * q->d2);
            double cm = c1 > c2 ? c1 : c2;
            if (!(cm > best_cos))
                continue;
            if (!(cross2(q->x - p->x, q->y - p->y, c->x - p->x, c->y - p->y) < 0.0))
                continue; /* would be trapped */
            if (!(cross2(p->x, p->y, q->x, q->y) > 0.0) ||
                tsl_dot(p->rel, q->rel) < g->cos_alpha * sqrt(p->d2 * q->d2))
                continue;
            best = i;
            best_cos = cm;
        }
        if (best == 0)
            return;
        g->cand[g->seq[best]].kept = 0;
        memmove(g->seq + best, g->seq + best + 1, (g->seq_count - best - 1) * sizeof *g->seq);
        g->seq_count--;
    }
}

/* Connects consecutive points of seq around R (section 4.2): a forward
 * walk from R's incoming boundary neighbour, a backward walk from its
 * outgoing one; what they leave between them stays open. */
static tessel_status walk(gp *g, uint32_t R, const gp_frame *f)
{
    size_t k = g->seq_count - 1;
    size_t j = 0;
    int r;
    tessel_status s;
    while (j < k) {
        if ((s = try_fan(g, R, f, j, 1, 1, &r)) != TESSEL_OK)
            return s;
        if (r == TRY_OK) {
            j++;
            continue;
        }
        if (r == TRY_LEAD && j + 2 <= k) {
            if ((s = try_fan(g, R, f, j, 2, 1, &r)) != TESSEL_OK)
                return s;
            if (r == TRY_OK) {
                j += 2;
                continue;
            }
        }
        break;
    }
    size_t l = k;
    while (l > j && st(g, R) != ST_DONE) {
        if ((s = try_fan(g, R, f, l - 1, 1, 0, &r)) != TESSEL_OK)
            return s;
        if (r == TRY_OK) {
            l--;
            continue;
        }
        if (r == TRY_LEAD && l >= j + 2) {
            if ((s = try_fan(g, R, f, l - 2, 2, 0, &r)) != TESSEL_OK)
                return s;
            if (r == TRY_OK) {
                l -= 2;
                continue;
            }
        }
        break;
    }
    return TESSEL_OK;
}

/* f's box of the new triangles: R and the given candidates (relative to R). */
static void fan_box(const gp *g, gp_frame *f, const uint32_t *idx, size_t count)
{
    for (int a = 0; a < 3; a++)
        f->flo[a] = f->fhi[a] = 0.0;
    for (size_t i = 0; i < count; i++) {
        const double *r = g->cand[idx[i]].rel;
        for (int a = 0; a < 3; a++) {
            f->flo[a] = dmin(f->flo[a], r[a]);
            f->fhi[a] = dmax(f->fhi[a], r[a]);
        }
    }
}

/* Lists the free points of the box farther than rho from R but not farther
 * than its farthest boundary neighbour: only candidates are checked for
 * being trapped, and a triangle to a boundary neighbour beyond rho may
 * cover such a point (Invariant 1). */
static tessel_status far_points(gp *g, const gp_frame *f)
{
    g->far_count = 0;
    double rho2 = f->rho * f->rho, reach2 = 0.0;
    for (size_t i = 0; i < g->seq_count; i++)
        reach2 = dmax(reach2, g->cand[g->seq[i]].d2);
    if (!(reach2 > rho2))
        return TESSEL_OK;
    for (size_t k = 0; k < g->box_count; k++) {
        const gp_box *x = &g->box[k];
        double d2 = tsl_dot(x->rel, x->rel);
        if (d2 <= rho2 || d2 > reach2 || g->head[x->idx] != NONE || !is_live(g, x->idx))
            continue;
        if (grow((void **)&g->far, &g->far_cap, g->far_count + 1, sizeof *g->far))
            return TESSEL_ERR_NOMEM;
        g->far[g->far_count][0] = tsl_dot(x->rel, f->u);
        g->far[g->far_count][1] = tsl_dot(x->rel, f->v);
        g->far_count++;
    }
    return TESSEL_OK;
}

/* Builds seq = e, candidates of the free sector by angle, s, for R whose fan
 * runs s -> ... -> e, and triangulates it. Candidate keys must be relative to
 * e's direction. */
static tessel_status fill_sector(gp *g, uint32_t R, gp_frame *f)
{
    uint32_t e = g->le[R], s = g->ls[R];
    double ks = -1.0;
    for (size_t i = 0; i < g->cand_count; i++)
        if (g->cand[i].idx == s)
            ks = g->cand[i].key;
    if (!(ks > 0.0))
        return TESSEL_OK;
    /* Rule 1: R's invisible region is its fan's sector, from s to e. */
    for (size_t i = 0; i < g->cand_count; i++) {
        gp_cand *c = &g->cand[i];
        if (c->idx == e || c->idx == s)
            c->kept = 1;
        else if (!(c->key > 0.0 && c->key < ks))
            c->kept = 2; /* mesh side: neither kept nor a trap candidate */
    }
    tessel_status st_ = visibility(g, R, f, e, s);
    if (st_ != TESSEL_OK)
        return st_;
    sort_cands(g);
    drop_hidden(g, e, s);
    g->seq_count = 0;
    g->empty_gap = 0;
    size_t need = g->cand_count + 2;
    if (grow((void **)&g->seq, &g->seq_cap, need, sizeof *g->seq))
        return TESSEL_ERR_NOMEM;
    size_t ie = 0, is = 0;
    for (size_t i = 0; i < g->cand_count; i++) {
        if (g->cand[i].idx == e)
            ie = i;
        if (g->cand[i].idx == s)
            is = i;
    }
    g->seq[g->seq_count++] = (uint32_t)ie;
    for (size_t i = 0; i < g->cand_count; i++) {
        const gp_cand *c = &g->cand[i];
        if (c->kept == 1 && c->idx != e && c->idx != s)
            g->seq[g->seq_count++] = (uint32_t)i;
    }
    g->seq[g->seq_count++] = (uint32_t)is;
    /* Nothing at all between R's boundary neighbours: the sphere was too
     * small for the sampling there. */
    g->empty_gap = g->seq_count == 2;
    /* Points on the mesh side are not trap candidates. */
    for (size_t i = 0; i < g->cand_count; i++)
        if (g->cand[i].kept == 2)
            g->cand[i].kept = 1, g->cand[i].key = -1.0;
    angle_criterion(g);
    delaunay_fan(g);
    fan_box(g, f, g->seq, g->seq_count);
    if ((st_ = far_points(g, f)) != TESSEL_OK)
        return st_;
    /* The held triangles are collected at the walk's first guard test. */
    tsl_gp_guard_defer(g, R, f, 1);
    st_ = walk(g, R, f);
    g->guard_pending = 0;
    return st_;
}

/* Sets R's state after it was a reference point (Invariant 2). */
static void finish_ref(gp *g, uint32_t R)
{
    int s = st(g, R);
    if (s == ST_DONE || s == ST_DEAD)
        return;
    if (g->head[R] == NONE)
        return;
    g->state[R] = (uint8_t)((g->state[R] & ~ST_MASK) | ST_BOUNDARY);
}

/* Gathers the candidates of R: live points of the box within rho, plus the
 * required ones. One pass collects the live points within b (rho <= b)
 * and finds the nearest, which sets rho; the rest are dropped after. */
static tessel_status gather(gp *g, double b, double m0, double mu, gp_frame *f,
                            uint32_t req_a, uint32_t req_b)
{
    double dmin2 = INFINITY;
    /* dinf is rounded to float, hence the margin. */
    double skip = b * (1.0 + 1e-6);
    g->cand_count = 0;
    for (size_t k = 0; k < g->box_count; k++) {
        const gp_box *x = &g->box[k];
        if ((double)x->dinf > skip && x->idx != req_a && x->idx != req_b)
            continue;
        double d2 = tsl_dot(x->rel, x->rel);
        if (d2 == 0.0)
            continue;
        if ((double)x->dinf <= b && d2 < dmin2)
            dmin2 = d2;
        tessel_status s = cand_push(g, x->idx, x->rel);
        if (s != TESSEL_OK)
            return s;
    }
    double m = m0;
    if (dmin2 < m * m)
        m = sqrt(dmin2);
    if (m < g->m_floor)
        m = g->m_floor;
    f->rho = dmin(mu * m, g->rho_cap);
    double rho2 = f->rho * f->rho;
    f->reach = f->rho;
    size_t w = 0;
    for (size_t i = 0; i < g->cand_count; i++) {
        const gp_cand *c = &g->cand[i];
        if (c->d2 > rho2 && c->idx != req_a && c->idx != req_b)
            continue;
        if (c->d2 > f->reach * f->reach)
            f->reach = sqrt(c->d2);
        if (w != i)
            g->cand[w] = *c;
        w++;
    }
    g->cand_count = w;
    return TESSEL_OK;
}

/* R's fan, its sphere of influence, its candidates and the fill. */
static tessel_status process_pass(gp *g, uint32_t R, double scale)
{
    double pr[3];
    pos(g, R, pr);
    gp_frame f;
    double nsum[3] = {0, 0, 0};
    double m0 = INFINITY;
    for (uint32_t t = g->head[R]; t != NONE;) {
        const gp_tri *T = &g->tri[t];
        int k = tri_pos(T, R);
        double a[3], b[3], da[3], db[3], nn[3];
        pos(g, T->v[(k + 1) % 3], a);
        pos(g, T->v[(k + 2) % 3], b);
        tsl_sub(a, pr, da);
        tsl_sub(b, pr, db);
        tsl_cross(da, db, nn);
        if (tsl_normalize(nn))
            for (int q = 0; q < 3; q++)
                nsum[q] += nn[q];
        m0 = dmin(m0, dmin(tsl_dot(da, da), tsl_dot(db, db)));
        t = T->next[k];
    }
    m0 = sqrt(m0);
    if (m0 > g->m_cap)
        m0 = g->m_cap;
    if (m0 < g->m_floor)
        m0 = g->m_floor;
    uint32_t e = g->le[R], s = g->ls[R];
    double pe[3], ps[3], d[3];
    pos(g, e, pe);
    pos(g, s, ps);
    tsl_sub(pe, pr, d);
    double re = tsl_norm(d);
    tsl_sub(ps, pr, d);
    double rs = tsl_norm(d);
    double b = dmin(scale * g->mu * m0, g->rho_cap);
    double core = dmax(b, dmax(re, rs));
    f.delta = tsl_gp_local_delta(g, R, core);
    tessel_status st_ = tsl_gp_scan_box(g, R, core);
    if (st_ != TESSEL_OK)
        return st_;
    if ((st_ = gather(g, b, m0, scale * g->mu, &f, e, s)) != TESSEL_OK)
        return st_;
    for (int q = 0; q < 3; q++)
        f.n[q] = nsum[q];
    if (!tsl_normalize(f.n) && !pca_normal(g->cand, g->cand_count, f.n)) {
        finish_ref(g, R);
        return TESSEL_OK;
    }
    frame_axes(&f, g->plane_axis);
    if (!project_cands(g, &f, e, s)) {
        finish_ref(g, R);
        return TESSEL_OK;
    }
    double ke = 0.0;
    for (size_t i = 0; i < g->cand_count; i++)
        if (g->cand[i].idx == e)
            ke = pseudo_angle(g->cand[i].x, g->cand[i].y);
    for (size_t i = 0; i < g->cand_count; i++) {
        gp_cand *c = &g->cand[i];
        c->key = wrap4(pseudo_angle(c->x, c->y) - ke);
    }
    if ((st_ = fill_sector(g, R, &f)) != TESSEL_OK)
        return st_;
    finish_ref(g, R);
    return TESSEL_OK;
}

/* A fringe or boundary point as reference point. */
static tessel_status process(gp *g, uint32_t R)
{
    g->state[R] = (uint8_t)(g->state[R] + ST_VISITS);
    double scale = 1.0;
    for (int step = 0;; step++, scale *= GROW) {
        tessel_status s = process_pass(g, R, scale);
        if (s != TESSEL_OK || st(g, R) == ST_DONE || step == GROW_STEPS || !g->empty_gap)
            return s;
    }
}

/* Sum of the unit normals of p's triangles. */
static void fan_normal(const gp *g, uint32_t p, double n[3])
{
    n[0] = n[1] = n[2] = 0.0;
    for (uint32_t t = g->head[p]; t != NONE;) {
        const gp_tri *T = &g->tri[t];
        double a[3], b[3], c[3], u[3], v[3], nn[3];
        pos(g, T->v[0], a);
        pos(g, T->v[1], b);
        pos(g, T->v[2], c);
        tsl_sub(b, a, u);
        tsl_sub(c, a, v);
        tsl_cross(u, v, nn);
        if (tsl_normalize(nn))
            for (int k = 0; k < 3; k++)
                n[k] += nn[k];
        t = T->next[tri_pos(T, p)];
    }
}

/* Sign of a seed's normal: agree with the triangles already around it, else
 * with the input normal, else face the viewpoint, else point to -depth (the
 * seed is the lowest free point, so -depth is outward on a closed surface).
 * The triangles around it are those at points within `reach` that lie near
 * the seed's tangent plane (within 27 degrees): points of a facing sheet (a
 * hand beside a thigh) lie along the normal and would flip the seed. Nearer
 * points weigh more. Uses g->box and g->boxd. */
static tessel_status orient_seed(gp *g, uint32_t R, double n[3], double reach)
{
    double ref[3] = {0, 0, 0};
    tessel_status s = tsl_gp_scan_box(g, R, reach);
    if (s != TESSEL_OK)
        return s;
    for (size_t i = 0; i < g->box_count + g->boxd_count; i++) {
        const gp_box *b = i < g->box_count ? &g->box[i] : &g->boxd[i - g->box_count];
        if (g->head[b->idx] == NONE)
            continue;
        double d2 = tsl_dot(b->rel, b->rel), h = tsl_dot(b->rel, n);
        if (h * h > 0.25 * (d2 - h * h))
            continue;
        double fan[3];
        fan_normal(g, b->idx, fan);
        for (int k = 0; k < 3; k++)
            ref[k] += fan[k] / d2;
    }
    if (!(tsl_dot(ref, ref) > 0.0)) {
        const tessel_cloud *c = g->cloud;
        if (c->normals) {
            for (int k = 0; k < 3; k++)
                ref[k] = c->normals[3 * (size_t)g->orig[R] + (size_t)k];
        } else if (c->has_viewpoint) {
            for (int k = 0; k < 3; k++)
                ref[k] = c->viewpoint[k] - (c->offset[k] + g->xyz[3 * (size_t)R + (size_t)k]);
        } else {
            ref[g->ad] = -1.0;
        }
    }
    if (tsl_dot(n, ref) < 0.0)
        for (int k = 0; k < 3; k++)
            n[k] = -n[k];
    return TESSEL_OK;
}

static void settle_dead(gp *g, uint32_t R, int fate)
{
    size_t *count[] = {NULL, &g->sum.left_duplicate, &g->sum.left_isolated,
                       &g->sum.left_closed_in, &g->sum.left_untriangulated};
    g->state[R] = (uint8_t)((g->state[R] & ~ST_MASK) | ST_DEAD |
                            (fate - FATE_DUPLICATE) * ST_WHY);
    tsl_gp_point_settled(g, R);
    (*count[fate])++;
}

/* Whether R lies on a held triangle near it: its foot on the triangle's
 * plane falls inside the triangle and it is within COVER_HEIGHT of the
 * triangle's longest edge off that plane. Such a point was passed over by
 * the front (Invariant 1 breaks where the sampling is not locally uniform:
 * two points much closer than their neighbours); a front seeded there would
 * lay a second sheet over the surface. Looks at the triangles of the points
 * of the last box scan. */
static int covered(const gp *g, uint32_t R)
{
    double pr[3];
    pos(g, R, pr);
    size_t nb = g->box_count + g->boxd_count;
    for (size_t k = 0; k < nb; k++) {
        uint32_t q = k < g->box_count ? g->box[k].idx : g->boxd[k - g->box_count].idx;
        for (uint32_t t = g->head[q]; t != NONE;) {
            const gp_tri *T = &g->tri[t];
            int kq = tri_pos(T, q);
            t = T->next[kq];
            double p[3][3], e[3][3], n[3], d[3];
            for (int j = 0; j < 3; j++)
                pos(g, T->v[j], p[j]);
            double l2 = 0.0;
            for (int j = 0; j < 3; j++) {
                tsl_sub(p[(j + 1) % 3], p[j], e[j]);
                l2 = dmax(l2, tsl_dot(e[j], e[j]));
            }
            tsl_cross(e[0], e[1], n);
            double nn = tsl_dot(n, n);
            if (!(nn > 0.0))
                continue;
            tsl_sub(pr, p[0], d);
            double h = tsl_dot(n, d);
            if (h * h > COVER_HEIGHT * COVER_HEIGHT * l2 * nn)
                continue;
            int inside = 1;
            for (int j = 0; j < 3 && inside; j++) {
                double r[3], c[3];
                tsl_sub(pr, p[j], r);
                tsl_cross(e[j], r, c);
                inside = tsl_dot(c, n) >= 0.0;
            }
            if (inside)
                return 1;
        }
    }
    return 0;
}

/* A free point as seed (sections 3-4.1: m from its nearest point, PCA
 * plane). Its first triangle joins two angularly consecutive candidates;
 * then it is completed like any fringe point. */
static tessel_status seed(gp *g, uint32_t R)
{
    double m;
    tessel_status s = tsl_gp_nearest(g, R, 1, g->spacing, g->m_cap, &m);
    if (s != TESSEL_OK)
        return s;
    if (!(m <= g->m_cap)) {
        /* Nothing live nearby: alone, or enclosed by the finished mesh. */
        double any;
        if ((s = tsl_gp_nearest(g, R, 0, g->spacing, g->m_cap, &any)) != TESSEL_OK)
            return s;
        settle_dead(g, R, any <= g->m_cap ? FATE_CLOSED_IN : FATE_ISOLATED);
        return TESSEL_OK;
    }
    if (m < g->m_floor)
        m = g->m_floor;
    gp_frame f;
    double b = g->mu * m;
    if ((s = tsl_gp_scan_box(g, R, b + g->delta)) != TESSEL_OK)
        return s;
    if ((s = gather(g, b, m, g->mu, &f, NONE, NONE)) != TESSEL_OK)
        return s;
    size_t done_near = 0;
    done_near = g->boxd_count;
    /* Fewer than SEED_MIN neighbours make a splinter, not a surface. */
    if (g->cand_count < SEED_MIN || !pca_normal(g->cand, g->cand_count, f.n)) {
        settle_dead(g, R, done_near ? FATE_CLOSED_IN : FATE_UNTRIANGULATED);
        return TESSEL_OK;
    }
    /* A free point whose neighbours are mostly on the mesh already, whose
     * box holds far more completed points than live ones, or that lies on
     * a held triangle (covered), was left behind by the front (noise beside
     * the surface, a spot it could not enter, a point passed over): a new
     * front here would only make splinters or a second sheet. The count of
     * completed points sees what covered cannot: triangles that have left
     * memory. */
    size_t meshed = 0;
    for (size_t i = 0; i < g->cand_count; i++)
        meshed += g->head[g->cand[i].idx] != NONE;
    if (2 * meshed > g->cand_count || g->boxd_count > SEED_DONE_RATIO * g->box_count ||
        covered(g, R)) {
        settle_dead(g, R, FATE_CLOSED_IN);
        return TESSEL_OK;
    }
    /* Orientation from up to four spheres around. */
    if ((s = orient_seed(g, R, f.n, 4.0 * f.rho)) != TESSEL_OK)
        return s;
    f.delta = tsl_gp_local_delta(g, R, f.reach);
    frame_axes(&f, g->plane_axis);
    project_cands(g, &f, NONE, NONE);
    for (size_t i = 0; i < g->cand_count; i++)
        g->cand[i].key = pseudo_angle(g->cand[i].x, g->cand[i].y);
    if ((s = visibility(g, R, &f, NONE, NONE)) != TESSEL_OK)
        return s;
    sort_cands(g);
    drop_hidden(g, NONE, NONE);
    for (int a = 0; a < 3; a++)
        f.flo[a] = f.fhi[a] = 0.0;
    for (size_t i = 0; i < g->cand_count; i++)
        for (int a = 0; a < 3; a++) {
            f.flo[a] = fmin(f.flo[a], g->cand[i].rel[a]);
            f.fhi[a] = fmax(f.fhi[a], g->cand[i].rel[a]);
        }
    if ((s = tsl_gp_guard_collect(g, R, &f, 0)) != TESSEL_OK)
        return s;
    /* Kept candidates in angular order; start after the widest gap. */
    size_t nk = 0;
    if (grow((void **)&g->seq, &g->seq_cap, g->cand_count + 2, sizeof *g->seq))
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < g->cand_count; i++)
        if (g->cand[i].kept)
            g->seq[nk++] = (uint32_t)i;
    int made = 0;
    g->far_count = 0; /* every candidate lies within rho */
    if (nk >= 2) {
        size_t start = 0;
        double widest = -1.0;
        for (size_t i = 0; i < nk; i++) {
            double k0 = g->cand[g->seq[i]].key, k1 = g->cand[g->seq[(i + 1) % nk]].key;
            double gap = wrap4(k1 - k0);
            if (nk == 1 || gap > widest) {
                widest = gap;
                start = (i + 1) % nk;
            }
        }
        /* Rotate so the walk starts after the widest gap. */
        uint32_t *tmp = g->seq + nk; /* room for a pair */
        for (size_t t = 0; t < nk && !made; t++) {
            size_t i0 = (start + t) % nk, i1 = (i0 + 1) % nk;
            if (nk == 2 && t == 1)
                break;
            tmp[0] = g->seq[i0];
            tmp[1] = g->seq[i1];
            uint32_t save0 = g->seq[0], save1 = g->seq[1];
            g->seq[0] = tmp[0];
            g->seq[1] = tmp[1];
            int r;
            s = try_fan(g, R, &f, 0, 1, 1, &r);
            g->seq[0] = save0;
            g->seq[1] = save1;
            if (s != TESSEL_OK)
                return s;
            if (r == TRY_OK)
                made = 1;
        }
    }
    if (!made) {
        settle_dead(g, R, done_near ? FATE_CLOSED_IN : FATE_UNTRIANGULATED);
        return TESSEL_OK;
    }
    g->sum.seeds++;
    /* R now has one triangle; fill the rest of its circle like a fringe
     * point, keys measured from its incoming neighbour. */
    uint32_t e = g->le[R];
    double ke = 0.0;
    for (size_t i = 0; i < g->cand_count; i++)
        if (g->cand[i].idx == e)
            ke = pseudo_angle(g->cand[i].x, g->cand[i].y);
    for (size_t i = 0; i < g->cand_count; i++) {
        gp_cand *c = &g->cand[i];
        c->key = wrap4(pseudo_angle(c->x, c->y) - ke);
    }
    g->state[R] = (uint8_t)(g->state[R] + ST_VISITS);
    if ((s = fill_sector(g, R, &f)) != TESSEL_OK)
        return s;
    finish_ref(g, R);
    return TESSEL_OK;
}


/* ------------------------------------------------------------------------ */
/* Closing small holes (not in the paper)                                    */
/* ------------------------------------------------------------------------ */

/* Triangle (v, u, w) closing v's fan, where u -> v -> w runs along the
 * boundary: exact checks (not degenerate, fans stay single, no
 * intersection), then added. *ok tells whether it was. */
static tessel_status try_ear(gp *g, uint32_t v, uint32_t u, uint32_t w, int *ok)
{
    *ok = 0;
    double pv[3], pu[3], pw[3], d[3];
    pos(g, v, pv);
    pos(g, u, pu);
    pos(g, w, pw);
    if (tsl_gp_collinear3(pv, pu, pw) || tsl_gp_edge_exists(g, v, u) ||
        tsl_gp_edge_exists(g, u, w) || tsl_gp_edge_exists(g, w, v))
        return TESSEL_OK;
    int hv = tsl_gp_link_check(g, v, u, w, 1);
    int hu = tsl_gp_link_check(g, u, w, v, 1);
    int hw = tsl_gp_link_check(g, w, v, u, 1);
    if (hv == LINK_FAIL || hu == LINK_FAIL || hw == LINK_FAIL)
        return TESSEL_OK;
    gp_frame f;
    memset(&f, 0, sizeof f);
    tsl_sub(pu, pv, d);
    f.reach = tsl_norm(d);
    for (int a = 0; a < 3; a++) {
        f.flo[a] = fmin(0.0, d[a]);
        f.fhi[a] = fmax(0.0, d[a]);
    }
    tsl_sub(pw, pv, d);
    f.reach = fmax(f.reach, tsl_norm(d));
    for (int a = 0; a < 3; a++) {
        f.flo[a] = fmin(f.flo[a], d[a]);
        f.fhi[a] = fmax(f.fhi[a], d[a]);
    }
    f.delta = tsl_gp_local_delta(g, v, f.reach);
    tessel_status s = tsl_gp_guard_collect(g, v, &f, 0);
    if (s != TESSEL_OK)
        return s;
    uint32_t tv[3] = {v, u, w};
    if (!tsl_gp_guard_ok(g, tv, NULL, NULL, 0)) {
        g->sum.rejected_intersecting++;
        return TESSEL_OK;
    }
    if ((s = tsl_gp_tri_add(g, v, u, w, 0, NULL)) != TESSEL_OK)
        return s;
    tsl_gp_link_apply(g, v, u, w, hv, 1);
    tsl_gp_link_apply(g, u, w, v, hu, 1);
    tsl_gp_link_apply(g, w, v, u, hw, 1);
    *ok = 1;
    return TESSEL_OK;
}

/* Ear clipping of the loop L[0..k) (each entry's successor is the next):
 * the ear at L[i] is the triangle (L[i], L[i-1], L[i+1]); it must turn the
 * same way as L[i]'s fan (a convex corner; the last triangle has no choice)
 * and its new edge must not exceed lim. The smallest angle goes first; one
 * the exact checks refuse gives way to the next.
 * dry: only these tests, on a copy, to learn whether the whole loop can be
 * closed. */
static tessel_status clip_loop(gp *g, uint32_t *L, size_t k, double lim, int dry, int *done)
{
    *done = 0;
    uint64_t refused = 0; /* ears at this k that try_ear refused (the first 64) */
    while (k >= 3) {
        size_t best = k;
        double best_cos = -2.0;
        for (size_t i = 0; i < k; i++) {
            if (i < 64 && (refused >> i & 1))
                continue;
            uint32_t u = L[(i + k - 1) % k], v = L[i], w = L[(i + 1) % k];
            double pv[3], pu[3], pw[3], a[3], b[3], uw[3], en[3];
            pos(g, v, pv);
            pos(g, u, pu);
            pos(g, w, pw);
            tsl_sub(pu, pv, a);
            tsl_sub(pw, pv, b);
            tsl_sub(pw, pu, uw);
            if (k > 3 && tsl_dot(uw, uw) > lim * lim)
                continue;
            tsl_cross(a, b, en);
            if (k > 3 && !(tsl_dot(en, g->hn + 3 * i) > 0.0))
                continue;
            double c = tsl_dot(a, b) / sqrt(tsl_dot(a, a) * tsl_dot(b, b));
            if (c > best_cos) {
                best_cos = c;
                best = i;
            }
        }
        if (best == k)
            return TESSEL_OK;
        if (!dry) {
            int ok;
            tessel_status s =
                try_ear(g, L[best], L[(best + k - 1) % k], L[(best + 1) % k], &ok);
            if (s != TESSEL_OK)
                return s;
            if (!ok) { /* another ear may pass: the other diagonal of a quad */
                if (best >= 64)
                    return TESSEL_OK;
                refused |= (uint64_t)1 << best;
                continue;
            }
        }
        refused = 0;
        if (k == 3)
            break;
        memmove(L + best, L + best + 1, (k - best - 1) * sizeof *L);
        memmove(g->hn + 3 * best, g->hn + 3 * (best + 1), 3 * (k - best - 1) * sizeof *g->hn);
        k--;
    }
    *done = 1;
    return TESSEL_OK;
}

/* After the front has stopped: closes the boundary loops of at most
 * max_hole edges that ear clipping can close completely with edges of at
 * most 2 mu times the loop's mean edge. */
static tessel_status close_holes(gp *g)
{
    if (g->max_hole < 3)
        return TESSEL_OK;
    size_t cap = (size_t)g->max_hole + 1;
    uint32_t *L = tsl_alloc_array(2 * cap, sizeof *L);
    if (!L || grow((void **)&g->hn, &g->hn_cap, 6 * cap, sizeof *g->hn)) {
        free(L);
        return TESSEL_ERR_NOMEM;
    }
    tessel_status s = TESSEL_OK;
    for (uint32_t p = 0; p < g->n && s == TESSEL_OK; p++) {
        if (!is_live(g, p) || g->head[p] == NONE)
            continue;
        size_t k = 0;
        uint32_t x = p, low = p;
        do {
            L[k++] = x;
            low = x < low ? x : low;
            x = g->ls[x];
        } while (x != p && x != NONE && k <= g->max_hole);
        if (x != p || k < 3 || low != p)
            continue;
        double len = 0.0;
        for (size_t i = 0; i < k; i++) {
            double a[3], b[3], d[3];
            pos(g, L[i], a);
            pos(g, L[(i + 1) % k], b);
            tsl_sub(b, a, d);
            len += tsl_norm(d);
        }
        double lim = 2.0 * g->mu * len / (double)k;
        memcpy(L + cap, L, k * sizeof *L);
        for (size_t i = 0; i < k; i++) {
            fan_normal(g, L[i], g->hn + 3 * i);
            memcpy(g->hn + 3 * (cap + i), g->hn + 3 * i, 3 * sizeof *g->hn);
        }
        int done;
        if ((s = clip_loop(g, L + cap, k, lim, 1, &done)) != TESSEL_OK || !done)
            continue;
        for (size_t i = 0; i < k; i++)
            memcpy(g->hn + 3 * i, g->hn + 3 * (cap + i), 3 * sizeof *g->hn);
        if ((s = clip_loop(g, L, k, lim, 0, &done)) == TESSEL_OK && done)
            g->sum.holes_closed++;
    }
    free(L);
    return s;
}

/* ------------------------------------------------------------------------ */
/* The main loop                                                             */
/* ------------------------------------------------------------------------ */

static tessel_status progress(gp *g)
{
    double f = (double)g->processed / (double)g->n;
    return tsl_progress(g->cb, g->stage, f < 1.0 ? f : 1.0);
}

static tessel_status run(gp *g)
{
    tessel_status s;
    for (;;) {
        while (g->qcount) {
            uint32_t R = g->queue[g->qhead];
            g->qhead = (g->qhead + 1) % g->n;
            g->qcount--;
            g->state[R] &= (uint8_t)~ST_QUEUED;
            int sr = st(g, R);
            if (sr != ST_FRINGE && sr != ST_BOUNDARY)
                continue;
            if ((s = process(g, R)) != TESSEL_OK)
                return s;
            if ((++g->processed & 4095) == 0 && (s = progress(g)) != TESSEL_OK)
                return s;
            if (g->created_since_sweep >= 16384 &&
                4 * g->created_since_sweep >= g->alive_after_sweep &&
                (s = tsl_gp_sweep(g, 0)) != TESSEL_OK)
                return s;
        }
        if (g->grow_only)
            return TESSEL_OK;
        while (g->seed_cursor < g->n && st(g, g->seed_order[g->seed_cursor]) != ST_FREE)
            g->seed_cursor++;
        if (g->seed_cursor == g->n)
            return TESSEL_OK;
        if ((s = seed(g, g->seed_order[g->seed_cursor])) != TESSEL_OK)
            return s;
        if ((++g->processed & 4095) == 0 && (s = progress(g)) != TESSEL_OK)
            return s;
    }
}

/* ------------------------------------------------------------------------ */
/* Public API                                                                */
/* ------------------------------------------------------------------------ */

tessel_greedy_params tessel_greedy_params_default(void)
{
    tessel_greedy_params p;
    memset(&p, 0, sizeof p);
    p.mu = 2.0;
    p.mu_from_sampling = 1;
    p.max_angle = 120.0;
    p.min_angle = 0.0;
    p.plane = TESSEL_GREEDY_PLANE_PCA;
    p.max_spacing = 4.0;
    p.max_hole = 16;
    p.existing = NULL;
    p.existing_count = 0;
    p.frozen = NULL;
    p.orient_check = 1;
    p.flip = 1;
    p.tile_points = 262144;
    p.threads = 0;
    return p;
}

/* One pass of the front over the cloud (sections 3-4) with checked
 * params; progress under `stage`. */
static tessel_status front_pass(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                bool grow_only, const char *stage,
                                const tessel_callbacks *callbacks,
                                const tessel_triangle_sink *sink, uint8_t *fate,
                                tessel_recon_summary *summary)
{
    const tessel_greedy_params p = *params;
    gp g;
    memset(&g, 0, sizeof g);
    g.grow_only = grow_only;
    g.cloud = cloud;
    g.n = cloud->count;
    g.mu = p.mu;
    g.mu_from_sampling = p.mu_from_sampling != 0;
    g.cos_alpha = cos(p.max_angle * 3.14159265358979323846 / 180.0);
    g.beta = p.min_angle * 3.14159265358979323846 / 180.0;
    g.max_spacing = p.max_spacing;
    g.max_hole = p.max_hole;
    g.plane_axis = p.plane == TESSEL_GREEDY_PLANE_AXIS;
    g.cb = callbacks;
    g.stage = stage;
    g.sink = sink;
    g.sum.points_in = g.n;
    tessel_status s = tsl_gp_init(&g);
    if (s == TESSEL_OK && p.existing_count)
        s = tsl_gp_import_existing(&g, p.existing, p.existing_count, p.frozen);
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, stage, 0.0);
    if (s == TESSEL_OK)
        s = run(&g);
    if (s == TESSEL_OK)
        s = close_holes(&g);
    if (s == TESSEL_OK)
        s = tsl_gp_sweep(&g, 1);
    if (s == TESSEL_OK)
        s = tsl_gp_flush_out(&g);
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, stage, 1.0);
    if (s == TESSEL_OK) {
        /* Every point of an open fan has two boundary edges (the mesh is
         * vertex-manifold), every boundary edge two such points. */
        for (size_t i = 0; i < g.n; i++) {
            int si = g.state[i] & ST_MASK;
            g.sum.boundary_edges += si == ST_FRINGE || si == ST_BOUNDARY;
        }
        for (size_t i = 0; i < g.uf_count; i++)
            g.sum.components += g.uf[i] == i;
        *summary = g.sum;
        for (size_t i = 0; fate && i < g.n; i++) {
            int si = g.state[i] & ST_MASK;
            fate[g.orig[i]] = (uint8_t)(si == ST_DEAD   ? FATE_DUPLICATE + g.state[i] / ST_WHY
                                        : si == ST_FREE ? FATE_UNREACHED
                                                        : FATE_USED);
        }
        tsl_log(callbacks, TESSEL_LOG_DEBUG,
                "%s: %zu of %zu points used, %zu triangles, %zu components, "
                "%zu boundary edges, spacing %g",
                stage, g.sum.points_used, g.sum.points_in, g.sum.triangles, g.sum.components,
                g.sum.boundary_edges, g.sum.spacing);
    }
    tsl_gp_free(&g);
    return s;
}

tessel_status tsl_gp_pass(const tessel_cloud *cloud, const tessel_greedy_params *params,
                          const char *stage, const tessel_callbacks *callbacks,
                          const tessel_triangle_sink *sink, uint8_t *fate,
                          tessel_recon_summary *summary)
{
    return front_pass(cloud, params, false, stage, callbacks, sink, fate, summary);
}

tessel_status tsl_gp_grow(const tessel_cloud *cloud, const tessel_greedy_params *params,
                          const char *stage, const tessel_callbacks *callbacks,
                          const tessel_triangle_sink *sink, uint8_t *fate,
                          tessel_recon_summary *summary)
{
    return front_pass(cloud, params, true, stage, callbacks, sink, fate, summary);
}

tessel_status tessel_reconstruct_greedy(const tessel_cloud *cloud,
                                        const tessel_greedy_params *params,
                                        const tessel_callbacks *callbacks,
                                        const tessel_triangle_sink *sink,
                                        tessel_recon_summary *summary)
{
    return tsl_reconstruct_greedy_with(cloud, params, NULL, callbacks, sink, summary);
}

/* Whether params (NULL: the defaults) are valid for cloud. */
static tessel_status params_status(const tessel_cloud *cloud, const tessel_greedy_params *p)
{
    if (!cloud || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->mu >= 1.2 && p->mu <= 10.0) || !(p->max_angle >= 60.0 && p->max_angle <= 175.0) ||
        !(p->min_angle >= 0.0 && p->min_angle <= 45.0) ||
        !(p->max_spacing >= 1.0 && p->max_spacing <= 1000.0) || p->max_hole > 1000 ||
        (p->plane != TESSEL_GREEDY_PLANE_PCA && p->plane != TESSEL_GREEDY_PLANE_AXIS) ||
        (p->existing_count && !p->existing) || (p->orient_check != 0 && p->orient_check != 1) ||
        (p->flip != 0 && p->flip != 1))
        return TESSEL_ERR_INVALID_ARG;
    if (cloud->count >= NONE)
        return TESSEL_ERR_LIMIT;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;
    return TESSEL_OK;
}

tessel_status tsl_gp_space_order(const tessel_cloud *cloud, int threads, tessel_cloud *sorted,
                                 uint32_t **perm)
{
    memset(sorted, 0, sizeof *sorted);
    *perm = NULL;
    size_t n = cloud->count;
    tsl_grid g;
    tessel_status st = tsl_grid_build(&g, cloud->xyz, n, tsl_grid_knn_cell(cloud->xyz, n, 16),
                                      tsl_threads(threads));
    if (st)
        return st;
    float *normals = cloud->normals ? tsl_alloc_array(n, 3 * sizeof *normals) : NULL;
    if (cloud->normals && !normals) {
        tsl_grid_free(&g);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; normals && i < n; i++)
        memcpy(normals + 3 * i, cloud->normals + 3 * (size_t)g.perm[i], 3 * sizeof *normals);
    sorted->count = n;
    sorted->xyz = g.sxyz;
    sorted->normals = normals;
    memcpy(sorted->offset, cloud->offset, sizeof sorted->offset);
    memcpy(sorted->viewpoint, cloud->viewpoint, sizeof sorted->viewpoint);
    sorted->has_viewpoint = cloud->has_viewpoint;
    *perm = g.perm;
    g.sxyz = NULL;
    g.perm = NULL;
    tsl_grid_free(&g);
    return TESSEL_OK;
}

/* Tiled clouds are meshed with their points in space order (cells of a
 * few spacings in Morton order): the passes over the whole mesh read
 * per-point arrays through the triangles, and a cloud in random order
 * (a sample, a merge of scans) made nearly every such read a cache miss
 * (10^7 points: 82 -> 67 s). The triangles go out in the caller's
 * indices. */
static tessel_status held_in_space_order(const tessel_cloud *cloud,
                                         const tessel_greedy_params *params, bool check,
                                         const tsl_gp_tile_runner *runner,
                                         const tessel_callbacks *callbacks,
                                         const tessel_triangle_sink *sink,
                                         tessel_recon_summary *summary)
{
    tessel_cloud sorted;
    uint32_t *perm;
    tessel_status st = tsl_gp_space_order(cloud, params->threads, &sorted, &perm);
    if (st)
        return st;
    st = tsl_gp_held(&sorted, params, check, runner, callbacks, perm, sink, summary);
    tessel_cloud_free(&sorted);
    free(perm);
    return st;
}

tessel_status tsl_reconstruct_greedy_with(const tessel_cloud *cloud,
                                          const tessel_greedy_params *params,
                                          const tsl_gp_tile_runner *runner,
                                          const tessel_callbacks *callbacks,
                                          const tessel_triangle_sink *sink,
                                          tessel_recon_summary *summary)
{
    double t0 = tsl_seconds();
    if (summary)
        memset(summary, 0, sizeof *summary);
    tessel_greedy_params p = params ? *params : tessel_greedy_params_default();
    if (!sink || !sink->emit)
        return TESSEL_ERR_INVALID_ARG;
    tessel_status valid = params_status(cloud, &p);
    if (valid != TESSEL_OK)
        return valid;
    tessel_recon_summary sum;
    memset(&sum, 0, sizeof sum);
    /* With existing triangles the caller holds the mesh, and checks it
     * whole (and their edges are not ours to flip). */
    bool check = p.orient_check && !p.existing_count;
    p.flip = p.flip && !p.existing_count;
    tessel_status s;
    bool tiled = !p.existing_count && p.tile_points && cloud->count > p.tile_points;
    if ((check || p.flip) && tiled)
        s = held_in_space_order(cloud, &p, check, runner, callbacks, sink, &sum);
    else if (check || p.flip)
        s = tsl_gp_held(cloud, &p, check, runner, callbacks, NULL, sink, &sum);
    else
        s = tsl_gp_pass(cloud, &p, "greedy", callbacks, sink, NULL, &sum);
    if (s != TESSEL_OK)
        return s;
    sum.seconds = tsl_seconds() - t0;
    if (summary)
        *summary = sum;
    return TESSEL_OK;
}

tessel_status tsl_gp_collect_emit(void *user, const uint32_t *tris, size_t count)
{
    gp_collect *c = user;
    size_t need;
    if (count == 0) /* tris may be NULL then, which memcpy may not take */
        return TESSEL_OK;
    if (!tsl_add_size(c->count, count, &need))
        return TESSEL_ERR_LIMIT;
    if (tsl_grow((void **)&c->tris, &c->cap, need, 3 * sizeof *c->tris))
        return TESSEL_ERR_NOMEM;
    memcpy(c->tris + 3 * c->count, tris, count * 3 * sizeof *tris);
    c->count = need;
    return TESSEL_OK;
}

tessel_status tessel_reconstruct_greedy_mesh(const tessel_cloud *cloud,
                                             const tessel_greedy_params *params,
                                             const tessel_callbacks *callbacks,
                                             tessel_mesh *mesh, tessel_recon_summary *summary)
{
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    gp_collect c = {NULL, 0, 0};
    tessel_triangle_sink sink = {tsl_gp_collect_emit, &c};
    tessel_status s = tessel_reconstruct_greedy(cloud, params, callbacks, &sink, summary);
    if (s != TESSEL_OK) {
        free(c.tris);
        return s;
    }
    /* Used points, in input order. */
    uint32_t *map = tsl_alloc_array(cloud->count, sizeof *map);
    if (!map) {
        free(c.tris);
        return TESSEL_ERR_NOMEM;
    }
    memset(map, 0xff, cloud->count * sizeof *map);
    for (size_t i = 0; i < 3 * c.count; i++)
        map[c.tris[i]] = 0;
    size_t used = 0;
    for (size_t i = 0; i < cloud->count; i++)
        if (map[i] == 0)
            map[i] = (uint32_t)used++;
    s = tessel_mesh_alloc(mesh, used, c.count, cloud->normals != NULL, cloud->rgb != NULL);
    if (s == TESSEL_OK) {
        for (size_t i = 0; i < cloud->count; i++) {
            uint32_t m = map[i];
            if (m == NONE)
                continue;
            memcpy(mesh->xyz + 3 * (size_t)m, cloud->xyz + 3 * i, 3 * sizeof(float));
            if (cloud->normals)
                memcpy(mesh->normals + 3 * (size_t)m, cloud->normals + 3 * i, 3 * sizeof(float));
            if (cloud->rgb)
                memcpy(mesh->rgb + 3 * (size_t)m, cloud->rgb + 3 * i, 3);
        }
        for (size_t i = 0; i < 3 * c.count; i++)
            mesh->triangles[i] = map[c.tris[i]];
        for (int k = 0; k < 3; k++)
            mesh->offset[k] = cloud->offset[k];
    }
    free(map);
    free(c.tris);
    return s;
}

