/* Advancing-front triangulation of a point set: step 4 of Mederos, Velho &
 * de Figueiredo 2003, "Smooth surface reconstruction from noisy clouds",
 * section 2.4 (Algorithms 1 and 2).
 *
 * A surface grows from a seed triangle (a point, its nearest neighbour and
 * the neighbour that maximises the angle at it). Border half-edges form
 * loops, each with the surface on its left; a FIFO holds the edges still to
 * be processed (the paper's list L). For a border edge uv with triangle usv,
 * GET_POINT takes the candidates t among the k nearest neighbours of u and v
 * that satisfy (i) the triangle vut turns at most theta from usv, theta
 * widening by eps2 up to pi/2 + eps2, (iii) max(|ut|, |vt|) < eps1 d_min,
 * (iv) the angles at u and v stay below phi, and picks the one with the
 * largest angle utv that passes (ii), validity.
 *
 * Validity is where this implementation is stricter than the paper, so that
 * the output is a valid surface whatever the input:
 *  - Combinatorial: every edge keeps at most two triangles, used in opposite
 *    directions, and every vertex keeps a single fan (a disc or half-disc)
 *    after every step. A triangle to a point on a non-adjacent part of the
 *    border (the paper's join of two border components or split of one)
 *    would give that point a second fan, so it is added together with a
 *    second triangle that fills the wedge between the new triangle and one
 *    of the point's border edges (a "bridge"). Ears (the point is the next
 *    or previous vertex along the loop) and hole closing (a loop of three)
 *    close border edges.
 *  - Geometric, the paper's projection test: projected onto the plane
 *    bisecting their normals, a new triangle and an existing one that share
 *    a vertex may not overlap around it, and two that share nothing may not
 *    overlap when they are close in height; triangles sharing an edge may not
 *    fold beyond pi/2 + eps2.
 *  - Exact: no new triangle may intersect an existing triangle beyond a
 *    shared vertex or edge, decided with Shewchuk's orientation predicates
 *    against every triangle whose bounding box meets it (a hash grid). So
 *    the output never self-intersects.
 * When the front stops, the next seed is taken among the unused points, so
 * every connected component gets its own surface. At the end, every closed
 * component is turned outward (positive signed volume), and open ones agree
 * with the points' normals when there are any. */
#include "front/front.h"

#include <float.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

tessel_front_params tessel_front_params_default(void)
{
    tessel_front_params p;
    memset(&p, 0, sizeof p);
    p.k = 16;
    p.theta_deg = 30.0;
    p.theta_step_deg = 15.0;
    p.max_edge_ratio = 3.0;
    p.max_angle_deg = 140.0;
    p.normal_angle_deg = 60.0;
    p.max_hole_radius = 2.5;
    p.orient = 1;
    p.tile_points = 65536;
    p.threads = 0;
    return p;
}

/* ------------------------------------------------------------------------ */
/* Mesh bookkeeping                                                          */
/* ------------------------------------------------------------------------ */

/* 1 when the undirected edge {x, y} is on some triangle. */
bool tsl_af_edge_exists(const af *s, uint32_t x, uint32_t y)
{
    for (uint32_t c = s->vhead[x]; c != NONE; c = s->cnext[c]) {
        const uint32_t *t = s->tri + 3 * (size_t)(c / 3);
        if (t[0] == y || t[1] == y || t[2] == y)
            return true;
    }
    return false;
}

void tsl_af_tri_box(const double *p[3], double lo[3], double hi[3])
{
    for (int i = 0; i < 3; i++) {
        lo[i] = dmin(p[0][i], dmin(p[1][i], p[2][i]));
        hi[i] = dmax(p[0][i], dmax(p[1][i], p[2][i]));
    }
}

tessel_status tsl_af_add_triangle(af *s, uint32_t x, uint32_t y, uint32_t z, uint32_t *id)
{
    if (s->nt + 1 > s->cap_t) {
        size_t cap = s->cap_t * 2, c1 = 3 * s->cap_t, c2 = s->cap_t, c3 = 3 * s->cap_t;
        if (tsl_grow((void **)&s->tri, &c1, 3 * cap, sizeof *s->tri) ||
            tsl_grow((void **)&s->ti, &c2, cap, sizeof *s->ti) ||
            tsl_grow((void **)&s->cnext, &c3, 3 * cap, sizeof *s->cnext))
            return TESSEL_ERR_NOMEM;
        s->cap_t = cap;
    }
    uint32_t t = (uint32_t)s->nt;
    uint32_t v[3] = {x, y, z};
    double p[3][3], n[3];
    for (int i = 0; i < 3; i++) {
        point(s, v[i], p[i]);
        s->tri[3 * (size_t)t + i] = v[i];
        uint32_t c = 3 * t + (uint32_t)i;
        s->cnext[c] = s->vhead[v[i]];
        s->vhead[v[i]] = c;
    }
    tsl_tri_normal(p[0], p[1], p[2], n);
    for (int i = 0; i < 3; i++)
        for (int c = 0; c < 3; c++)
            s->star[3 * (size_t)v[i] + c] += (float)n[c];
    for (int i = 0; i < 3; i++)
        if (!s->vsign[v[i]]) {
            const float *l = s->ln + 3 * (size_t)v[i];
            s->vsign[v[i]] = n[0] * l[0] + n[1] * l[1] + n[2] * l[2] < 0.0 ? -1 : 1;
            if (s->lines) {
                l = s->lines + 3 * (size_t)v[i];
                s->vsign2[v[i]] = n[0] * l[0] + n[1] * l[1] + n[2] * l[2] < 0.0 ? -1 : 1;
            }
        }
    af_tinfo *info = &s->ti[t];
    for (int i = 0; i < 3; i++) {
        double d[3];
        tsl_sub(p[(i + 1) % 3], p[i], d);
        s->max_edge = dmax(s->max_edge, tsl_norm(d));
    }
    const double *pp[3] = {p[0], p[1], p[2]};
    double lo[3], hi[3];
    tsl_af_tri_box(pp, lo, hi);
    for (int i = 0; i < 3; i++) {
        info->n[i] = (float)n[i];
        info->lo[i] = (float)lo[i]; /* exact: the corners are floats */
        info->hi[i] = (float)hi[i];
    }
    s->nt++;
    *id = t;
    return tsl_trigrid_insert(&s->grid, t, lo, hi);
}

static tessel_status push_edge(af *s, uint32_t e)
{
    if (s->q_count == s->q_cap) {
        size_t cap = s->q_cap ? s->q_cap * 2 : 1024;
        uint32_t *q = tsl_alloc_array(cap, sizeof *q);
        if (!q)
            return TESSEL_ERR_NOMEM;
        for (size_t i = 0; i < s->q_count; i++)
            q[i] = s->queue[(s->q_head + i) & (s->q_cap - 1)];
        free(s->queue);
        s->queue = q;
        s->q_head = 0;
        s->q_cap = cap;
    }
    s->queue[(s->q_head + s->q_count) & (s->q_cap - 1)] = e;
    s->q_count++;
    return TESSEL_OK;
}

tessel_status tsl_af_new_edge(af *s, uint32_t from, uint32_t to, uint32_t tri, uint32_t *id)
{
    if ((s->ne + 1 > s->cap_e &&
         tsl_grow((void **)&s->e, &s->cap_e, s->ne + 1, sizeof *s->e)) ||
        tsl_grow((void **)&s->fresh, &s->cap_fresh, s->n_fresh + 1, sizeof *s->fresh))
        return TESSEL_ERR_NOMEM;
    s->fresh[s->n_fresh++] = (uint32_t)s->ne;
    uint32_t id_ = (uint32_t)s->ne++;
    af_edge *e = &s->e[id_];
    e->from = from;
    e->to = to;
    e->prev = e->next = NONE;
    e->tri = tri;
    e->state = EDGE_ACTIVE;
    e->retries = 0;
    e->unfilled = 0;
    e->mark = 0;
    *id = id_;
    return push_edge(s, id_);
}

/* A dead border edge at vertex v gets another chance: its surroundings
 * changed. */
static tessel_status revive(af *s, uint32_t v)
{
    if (v == NONE)
        return TESSEL_OK;
    uint32_t ids[2] = {s->vin[v], s->vout[v]};
    for (int i = 0; i < 2; i++) {
        uint32_t id = ids[i];
        if (id == NONE || s->e[id].state != EDGE_DEAD || s->e[id].retries >= MAX_RETRIES ||
            s->e[id].retries == ERODED)
            continue;
        s->e[id].state = EDGE_ACTIVE;
        s->e[id].retries++;
        tessel_status st = push_edge(s, id);
        if (st)
            return st;
    }
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* GET_POINT (Algorithm 2)                                                   */
/* ------------------------------------------------------------------------ */

static int cmp_cand(const void *pa, const void *pb)
{
    const af_cand *a = pa, *b = pb;
    if (a->level != b->level)
        return a->level < b->level ? -1 : 1;
    if (a->cos_t != b->cos_t)
        return a->cos_t < b->cos_t ? -1 : 1;
    return a->t < b->t ? -1 : (a->t > b->t);
}

/* Combinatorial case of triangle (b, a, t) on border edge id; false when it
 * would break the manifold (t interior, or an edge it needs already
 * exists). */
bool tsl_af_classify(const af *s, uint32_t id, uint32_t t, int *kind)
{
    const af_edge *e = &s->e[id];
    uint32_t a = e->from, b = e->to;
    if (is_free(s, t)) {
        *kind = PLAN_FREE;
        return true;
    }
    if (is_interior(s, t))
        return false;
    bool ear_a = s->e[e->prev].from == t;
    bool ear_b = s->e[e->next].to == t;
    if (ear_a && ear_b) {
        *kind = PLAN_HOLE;
        return true;
    }
    if (ear_b) {
        *kind = PLAN_EAR_B;
        return !tsl_af_edge_exists(s, a, t);
    }
    if (ear_a) {
        *kind = PLAN_EAR_A;
        return !tsl_af_edge_exists(s, t, b);
    }
    *kind = PLAN_BRIDGE_R;
    return !tsl_af_edge_exists(s, a, t) && !tsl_af_edge_exists(s, t, b);
}

/* New edge x-y within the length bound (iii). */
static bool short_enough(const af *s, const double *px, const double *py, uint32_t x,
                         uint32_t y)
{
    double d[3];
    tsl_sub(py, px, d);
    double lim = s->eps1 * dmin(s->nnd[x], s->nnd[y]);
    return tsl_norm(d) < lim;
}

/* The second triangle of a bridge to t; *ok when one of the two choices is
 * valid (the one with the shorter new edge is preferred). */
static tessel_status plan_bridge(af *s, uint32_t id, const af_tri *first, af_plan *plan,
                                 bool *ok)
{
    const af_edge *e = &s->e[id];
    uint32_t a = e->from, b = e->to, t = plan->t;
    uint32_t r = s->e[s->vout[t]].to, p = s->e[s->vin[t]].from;
    af_tri opt[2];
    bool valid[2] = {false, false};
    double len[2] = {INFINITY, INFINITY};
    /* (r, t, a) closes t->r and adds a->r; (b, t, p) closes p->t, adds p->b. */
    uint32_t tri_v[2][3] = {{r, t, a}, {b, t, p}};
    uint32_t ends[2][2] = {{a, r}, {p, b}};
    for (int o = 0; o < 2; o++) {
        uint32_t x = ends[o][0], y = ends[o][1];
        if (x == y || tsl_af_edge_exists(s, x, y))
            continue;
        if (!tsl_af_make_tri(s, tri_v[o][0], tri_v[o][1], tri_v[o][2], &opt[o]))
            continue;
        double px[3], py[3], d[3];
        point(s, x, px);
        point(s, y, py);
        if (!short_enough(s, px, py, x, y) || tsl_af_min_cos_angle(&opt[o]) <= s->cos_phi ||
            !tsl_af_normals_agree(s, &opt[o], s->cos_normal))
            continue;
        tsl_sub(py, px, d);
        len[o] = tsl_norm(d);
        bool v;
        tessel_status st = tsl_af_check_triangle(s, &opt[o], first, &v);
        if (st)
            return st;
        valid[o] = v;
    }
    *ok = valid[0] || valid[1];
    if (*ok) {
        int o = valid[0] && (!valid[1] || len[0] <= len[1]) ? 0 : 1;
        plan->kind = o == 0 ? PLAN_BRIDGE_R : PLAN_BRIDGE_P;
        plan->w = o == 0 ? r : p;
    }
    return TESSEL_OK;
}

static tessel_status find_plan(af *s, uint32_t id, af_plan *plan, bool *found)
{
    *found = false;
    const af_edge *e = &s->e[id];
    uint32_t a = e->from, b = e->to;
    const uint32_t *t0 = s->tri + 3 * (size_t)e->tri;
    uint32_t c = t0[0] != a && t0[0] != b ? t0[0] : t0[1] != a && t0[1] != b ? t0[1] : t0[2];
    const float *tn = s->ti[e->tri].n;
    double n1[3] = {tn[0], tn[1], tn[2]};
    double pa[3], pb[3], ab[3];
    point(s, a, pa);
    point(s, b, pb);
    tsl_sub(pb, pa, ab);
    double lab = tsl_norm(ab);
    double lim = s->eps1 * dmin(s->nnd[a], s->nnd[b]);

    af_cand cand[2 * MAX_K];
    size_t nc = 0;
    if (++s->seen_now == 0) {
        memset(s->seen, 0, s->n * sizeof *s->seen);
        s->seen_now = 1;
    }
    for (int side = 0; side < 2; side++) {
        const uint32_t *nb = s->knn + (size_t)(side ? b : a) * s->k;
        for (uint32_t j = 0; j < s->k; j++) {
            uint32_t t = nb[j];
            if (t == NONE || t == a || t == b || t == c || s->dup[t] || is_interior(s, t))
                continue;
            if (s->seen[t] == s->seen_now)
                continue;
            s->seen[t] = s->seen_now;
            double pt[3], at[3], bt[3];
            point(s, t, pt);
            tsl_sub(pt, pa, at);
            tsl_sub(pt, pb, bt);
            double la = tsl_norm(at), lb = tsl_norm(bt);
            if (!(dmax(la, lb) < lim)) /* (iii) */
                continue;
            /* (iv): angles at a and b below phi. */
            if (tsl_dot(ab, at) <= s->cos_phi * lab * la ||
                -tsl_dot(ab, bt) <= s->cos_phi * lab * lb)
                continue;
            /* (i): normal of (b, a, t) against the normal of (a, b, c). */
            double nt[3];
            double ba[3] = {-ab[0], -ab[1], -ab[2]};
            tsl_cross(ba, bt, nt);
            double area2 = tsl_norm(nt);
            if (!(area2 > 1e-9 * dmax(lab, dmax(la, lb)) * dmax(lab, dmax(la, lb))))
                continue;
            double cosd = tsl_dot(nt, n1) / area2;
            if (cosd < s->cos_theta_max)
                continue;
            int level = 0;
            while (cosd < s->cos_level[level])
                level++;
            cand[nc].t = t;
            cand[nc].level = level;
            cand[nc].cos_t = tsl_dot(at, bt) / (la * lb);
            nc++;
        }
    }
    /* Insertion sort: a few dozen candidates. */
    for (size_t i = 1; i < nc; i++) {
        af_cand key = cand[i];
        size_t j = i;
        while (j > 0 && cmp_cand(&key, &cand[j - 1]) < 0) {
            cand[j] = cand[j - 1];
            j--;
        }
        cand[j] = key;
    }
    for (size_t i = 0; i < nc; i++) {
        uint32_t t = cand[i].t;
        int kind;
        if (!tsl_af_classify(s, id, t, &kind))
            continue;
        af_tri x;
        if (!tsl_af_make_tri(s, b, a, t, &x))
            continue;
        /* A triangle that only closes border edges (ear, hole) cannot fold
         * the front back: it needs only to face the vertices' side. */
        bool closing = kind == PLAN_EAR_A || kind == PLAN_EAR_B || kind == PLAN_HOLE;
        if (closing)
            x.cos_fold = s->cos_closing_fold;
        if (!tsl_af_normals_agree(s, &x, closing ? s->cos_closing_normal : s->cos_normal))
            continue;
        bool ok;
        tessel_status st = tsl_af_check_triangle(s, &x, NULL, &ok);
        if (st)
            return st;
        if (!ok)
            continue;
        plan->kind = kind;
        plan->t = t;
        plan->w = NONE;
        if (kind == PLAN_BRIDGE_R) {
            st = plan_bridge(s, id, &x, plan, &ok);
            if (st)
                return st;
            if (!ok)
                continue;
        }
        *found = true;
        return TESSEL_OK;
    }
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Insertion (Algorithm 1)                                                   */
/* ------------------------------------------------------------------------ */

static void close_edge(af *s, uint32_t id) { s->e[id].state = EDGE_CLOSED; }

tessel_status tsl_af_commit(af *s, uint32_t id, const af_plan *plan)
{
    af_edge e = s->e[id];
    uint32_t a = e.from, b = e.to, t = plan->t, P = e.prev, N = e.next;
    uint32_t T, T2, A, B;
    bool was_free = is_free(s, t);
    tessel_status st = tsl_af_add_triangle(s, b, a, t, &T);
    if (st)
        return st;
    switch (plan->kind) {
    case PLAN_FREE:
        if ((st = tsl_af_new_edge(s, a, t, T, &A)) || (st = tsl_af_new_edge(s, t, b, T, &B)))
            return st;
        link_edges(s, P, A);
        link_edges(s, A, B);
        link_edges(s, B, N);
        s->vout[a] = A;
        s->vin[t] = A;
        s->vout[t] = B;
        s->vin[b] = B;
        close_edge(s, id);
        break;
    case PLAN_EAR_B: {
        uint32_t NN = s->e[N].next;
        if ((st = tsl_af_new_edge(s, a, t, T, &A)))
            return st;
        link_edges(s, P, A);
        link_edges(s, A, NN);
        s->vout[a] = A;
        s->vin[t] = A;
        s->vin[b] = s->vout[b] = NONE;
        close_edge(s, id);
        close_edge(s, N);
        break;
    }
    case PLAN_EAR_A: {
        uint32_t PP = s->e[P].prev;
        if ((st = tsl_af_new_edge(s, t, b, T, &B)))
            return st;
        link_edges(s, PP, B);
        link_edges(s, B, N);
        s->vout[t] = B;
        s->vin[b] = B;
        s->vin[a] = s->vout[a] = NONE;
        close_edge(s, P);
        close_edge(s, id);
        break;
    }
    case PLAN_HOLE:
        s->vin[a] = s->vout[a] = s->vin[b] = s->vout[b] = s->vin[t] = s->vout[t] = NONE;
        close_edge(s, P);
        close_edge(s, id);
        close_edge(s, N);
        break;
    case PLAN_BRIDGE_R: {
        /* (b, a, t) + (r, t, a): closes a->b and t->r, adds t->b and a->r. */
        uint32_t r = plan->w, R = s->vout[t], Rn = s->e[R].next, Pt = s->vin[t], C;
        if ((st = tsl_af_add_triangle(s, r, t, a, &T2)) || (st = tsl_af_new_edge(s, t, b, T, &B)) ||
            (st = tsl_af_new_edge(s, a, r, T2, &C)))
            return st;
        link_edges(s, P, C);
        link_edges(s, C, Rn);
        link_edges(s, Pt, B);
        link_edges(s, B, N);
        s->vout[a] = C;
        s->vin[r] = C;
        s->vout[t] = B;
        s->vin[b] = B;
        close_edge(s, id);
        close_edge(s, R);
        s->stats.bridges++;
        break;
    }
    case PLAN_BRIDGE_P: {
        /* (b, a, t) + (b, t, p): closes a->b and p->t, adds a->t and p->b. */
        uint32_t p = plan->w, Pt = s->vin[t], Pp = s->e[Pt].prev, R = s->vout[t], D;
        if ((st = tsl_af_add_triangle(s, b, t, p, &T2)) || (st = tsl_af_new_edge(s, a, t, T, &A)) ||
            (st = tsl_af_new_edge(s, p, b, T2, &D)))
            return st;
        link_edges(s, P, A);
        link_edges(s, A, R);
        link_edges(s, Pp, D);
        link_edges(s, D, N);
        s->vout[a] = A;
        s->vin[t] = A;
        s->vout[p] = D;
        s->vin[b] = D;
        close_edge(s, id);
        close_edge(s, Pt);
        s->stats.bridges++;
        break;
    }
    default:
        return TESSEL_ERR_INTERNAL;
    }
    if (was_free)
        s->used++;
    if ((st = revive(s, a)) || (st = revive(s, b)) || (st = revive(s, t)) ||
        (st = revive(s, plan->w)))
        return st;
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Seeds                                                                     */
/* ------------------------------------------------------------------------ */

/* Sign that makes a seed's normal agree with its surroundings: the nearest
 * existing triangle (by centroid, ties to the lower id) within reach, so
 * that fronts meeting later have matching orientations and can join; else
 * the points' normals when there are any; else +1. The search widens from
 * the seed's own size: a triangle whose centroid is within r of the
 * seed's meets the box of half-size r, so once the nearest found is that
 * close no wider box can hold a nearer one. One box of the whole reach
 * (twice the longest edge so far) made every seed cost a scan of a large
 * part of the mesh on scans with a few long edges. */
static tessel_status seed_sign(af *s, const af_tri *x, int *sign)
{
    *sign = 0;
    double c[3];
    for (int i = 0; i < 3; i++)
        c[i] = (x->p[0][i] + x->p[1][i] + x->p[2][i]) / 3.0;
    double reach = 2.0 * dmax(x->maxlen, s->max_edge);
    for (double r = 2.0 * x->maxlen; s->nt > 0; r *= 2.0) {
        bool last = !(r < reach);
        if (last)
            r = reach;
        double lo[3], hi[3];
        for (int i = 0; i < 3; i++) {
            lo[i] = c[i] - r;
            hi[i] = c[i] + r;
        }
        tessel_status st = tsl_trigrid_query(&s->grid, lo, hi);
        if (st)
            return st;
        double best = INFINITY;
        uint32_t best_t = NONE;
        for (size_t i = 0; i < s->grid.hits.count; i++) {
            uint32_t t = s->grid.hits.found[i];
            if (s->tri[3 * (size_t)t] == NONE)
                continue;
            double d2 = 0.0;
            for (int j = 0; j < 3; j++) {
                double m = 0.0;
                for (int q = 0; q < 3; q++)
                    m += s->xyz[3 * (size_t)s->tri[3 * (size_t)t + q] + j] / 3.0;
                d2 += (m - c[j]) * (m - c[j]);
            }
            if (d2 < best || (d2 == best && t < best_t)) {
                best = d2;
                best_t = t;
            }
        }
        if (best_t != NONE && (last || best <= r * r)) {
            double dot = 0.0;
            for (int j = 0; j < 3; j++)
                dot += x->n[j] * s->ti[best_t].n[j];
            *sign = dot < 0.0 ? -1 : 1;
            break;
        }
        if (last)
            break;
    }
    if (*sign == 0 && s->pnormals) {
        double sum = 0.0;
        for (int i = 0; i < 3; i++) {
            const float *m = s->pnormals + 3 * (size_t)x->v[i];
            sum += x->n[0] * m[0] + x->n[1] * m[1] + x->n[2] * m[2];
        }
        *sign = sum < 0.0 ? -1 : 1;
    }
    if (*sign == 0)
        *sign = 1;
    return TESSEL_OK;
}

/* Starts a front at point p (section 2.4): p, its nearest neighbour q and
 * the neighbour r of p that maximises the angle at r, all unused. */
static tessel_status try_seed(af *s, uint32_t p, bool *ok)
{
    *ok = false;
    if (!is_free(s, p) || s->dup[p])
        return TESSEL_OK;
    const uint32_t *nb = s->knn + (size_t)p * s->k;
    /* Only away from the surface built so far: a point next to it is in a
     * hole or a stray point, and a front from it could not join. */
    for (uint32_t j = 0; j < s->k; j++)
        if (nb[j] != NONE && !is_free(s, nb[j]))
            return TESSEL_OK;
    uint32_t q = nb[0];
    if (q == NONE || s->dup[q] || !is_free(s, q))
        return TESSEL_OK;
    double pp[3], pq[3];
    point(s, p, pp);
    point(s, q, pq);
    uint32_t best = NONE;
    double best_cos = 1.0;
    for (uint32_t j = 1; j < s->k; j++) {
        uint32_t r = nb[j];
        if (r == NONE || s->dup[r] || !is_free(s, r))
            continue;
        double pr[3], u[3], v[3];
        point(s, r, pr);
        tsl_sub(pp, pr, u);
        tsl_sub(pq, pr, v);
        double lu = tsl_norm(u), lv = tsl_norm(v);
        double lim = s->eps1 * dmin(s->nnd[p], s->nnd[q]);
        if (!(dmax(lu, lv) < lim))
            continue;
        double cr = tsl_dot(u, v) / (lu * lv);
        if (cr < best_cos) {
            af_tri x;
            if (!tsl_af_make_tri(s, p, q, r, &x) || tsl_af_min_cos_angle(&x) <= s->cos_phi)
                continue;
            best_cos = cr;
            best = r;
        }
    }
    if (best == NONE)
        return TESSEL_OK;
    af_tri x;
    tsl_af_make_tri(s, p, q, best, &x);
    int sign;
    tessel_status st = seed_sign(s, &x, &sign);
    if (st)
        return st;
    if (sign < 0)
        tsl_af_make_tri(s, p, best, q, &x);
    if (!tsl_af_normals_agree(s, &x, s->cos_normal))
        return TESSEL_OK;
    bool valid;
    if ((st = tsl_af_check_triangle(s, &x, NULL, &valid)))
        return st;
    if (!valid)
        return TESSEL_OK;
    uint32_t T, E[3];
    if ((st = tsl_af_add_triangle(s, x.v[0], x.v[1], x.v[2], &T)))
        return st;
    for (int i = 0; i < 3; i++)
        if ((st = tsl_af_new_edge(s, x.v[i], x.v[(i + 1) % 3], T, &E[i])))
            return st;
    for (int i = 0; i < 3; i++) {
        link_edges(s, E[i], E[(i + 1) % 3]);
        s->vout[x.v[i]] = E[i];
        s->vin[x.v[(i + 1) % 3]] = E[i];
    }
    s->used += 3;
    s->stats.seeds++;
    *ok = true;
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Orientation of the components                                             */
/* ------------------------------------------------------------------------ */

void tsl_af_flip_triangle(uint32_t v[3])
{
    uint32_t tmp = v[1];
    v[1] = v[2];
    v[2] = tmp;
}

/* Closed components outward by signed volume; open ones by the points'
 * normals when there are any, else by their signed volume about their
 * centroid (right for nearly closed surfaces, arbitrary for flat ones).
 * Components are vertex-connected, which is edge-connected since every
 * vertex has a single fan. Removed triangles (vertices NONE) are skipped. */
static tessel_status orient_components(af *s)
{
    uint32_t *parent = tsl_alloc_array(s->n, sizeof *parent);
    double *score = tsl_calloc_array(s->n, sizeof *score);
    double *centre = tsl_calloc_array(4 * s->n, sizeof *centre); /* sum xyz, count */
    uint8_t *open = tsl_calloc_array(s->n, sizeof *open);
    if (!parent || !score || !centre || !open) {
        free(parent);
        free(score);
        free(centre);
        free(open);
        return TESSEL_ERR_NOMEM;
    }
    tsl_vertex_components(s->tri, s->nt, s->n, 1, parent);
    for (size_t i = 0; i < s->ne; i++)
        if (s->e[i].state != EDGE_CLOSED)
            open[tsl_uf_find(parent, s->e[i].from)] = 1;
    /* Centroids, relative to each component's root vertex (accuracy far
     * from the origin). */
    for (size_t t = 0; t < s->nt; t++) {
        const uint32_t *v = s->tri + 3 * t;
        if (v[0] == NONE)
            continue;
        uint32_t root = tsl_uf_find(parent, v[0]);
        double o[3], p[3];
        point(s, root, o);
        for (int i = 0; i < 3; i++) {
            point(s, v[i], p);
            for (int c = 0; c < 3; c++)
                centre[4 * (size_t)root + c] += p[c] - o[c];
        }
        centre[4 * (size_t)root + 3] += 3.0;
    }
    for (size_t t = 0; t < s->nt; t++) {
        const uint32_t *v = s->tri + 3 * t;
        if (v[0] == NONE)
            continue;
        uint32_t root = tsl_uf_find(parent, v[0]);
        double p[3][3], o[3];
        const double *cs = centre + 4 * (size_t)root;
        point(s, root, o);
        for (int c = 0; c < 3; c++)
            o[c] += cs[c] / cs[3];
        for (int i = 0; i < 3; i++) {
            point(s, v[i], p[i]);
            tsl_sub(p[i], o, p[i]);
        }
        if (open[root] && s->pnormals) {
            double n[3], u[3], w[3];
            tsl_sub(p[1], p[0], u);
            tsl_sub(p[2], p[0], w);
            tsl_cross(u, w, n);
            for (int i = 0; i < 3; i++) {
                const float *m = s->pnormals + 3 * (size_t)v[i];
                score[root] += n[0] * m[0] + n[1] * m[1] + n[2] * m[2];
            }
        } else {
            double c[3];
            tsl_cross(p[1], p[2], c);
            score[root] += tsl_dot(p[0], c);
        }
    }
    for (size_t i = 0; i < s->n; i++)
        if (parent[i] == i && score[i] < 0.0)
            s->stats.flipped_components++;
    for (size_t t = 0; t < s->nt; t++) {
        uint32_t *v = s->tri + 3 * t;
        if (v[0] != NONE && score[tsl_uf_find(parent, v[0])] < 0.0)
            tsl_af_flip_triangle(v);
    }
    free(parent);
    free(score);
    free(centre);
    free(open);
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Driver                                                                    */
/* ------------------------------------------------------------------------ */

void tsl_af_free(af *s)
{
    free(s->knn);
    free(s->nnd);
    free(s->dup);
    free(s->seen);
    free(s->star);
    free(s->eroded);
    free(s->cos_level);
    free(s->ln);
    free(s->vsign);
    free(s->vsign2);
    free(s->tri);
    free(s->ti);
    free(s->cnext);
    free(s->vhead);
    free(s->vin);
    free(s->vout);
    free(s->e);
    free(s->fresh);
    free(s->queue);
    free(s->scratch_u);
    free(s->scratch_d);
    free(s->own);
    tsl_trigrid_free(&s->grid);
}

typedef struct xyz_key {
    float x, y, z;
    uint32_t id;
} xyz_key;

static int cmp_xyz(const void *pa, const void *pb)
{
    const xyz_key *a = pa, *b = pb;
    if (a->x != b->x)
        return a->x < b->x ? -1 : 1;
    if (a->y != b->y)
        return a->y < b->y ? -1 : 1;
    if (a->z != b->z)
        return a->z < b->z ? -1 : 1;
    return a->id < b->id ? -1 : (a->id > b->id);
}

/* Unit normal of the least-squares plane of a neighbourhood with
 * covariance cov (3 x 3): the smallest eigenvalue's eigenvector, without
 * rotations when that eigenvalue stands apart from the middle one (the
 * usual case), else Jacobi's. False when it is not defined. */
static bool plane_normal(const double cov[9], double n[3])
{
    const double m[6] = {cov[0], cov[1], cov[2], cov[4], cov[5], cov[8]};
    double l[3];
    if (tsl_sym3_values(m, l) && l[1] - l[0] >= 1e-4 * l[2] && tsl_sym3_vector(m, l[0], n))
        return true;
    double w[3], v[9];
    tsl_eigen_sym3(cov, w, v);
    n[0] = v[0], n[1] = v[3], n[2] = v[6];
    return tsl_normalize(n);
}

/* Exact duplicates (a point equal to one with a smaller index) are marked
 * and left out of the neighbour search, so that they neither use up the k
 * neighbours of their surroundings nor ever become vertices. For the other
 * points: the k nearest others, the local spacing d (mean distance to the
 * SPACING_NEIGHBOURS nearest) and the normal line (given, or fitted to the
 * neighbourhood). */
static tessel_status prepare_neighbours(af *s, int threads)
{
    size_t kq = (size_t)s->k + 1, rows;
    if (!tsl_mul_size(s->n, kq, &rows))
        return TESSEL_ERR_LIMIT;
    xyz_key *keys = tsl_alloc_array(s->n, sizeof *keys);
    float *uxyz = tsl_alloc_array(3 * s->n, sizeof *uxyz);
    uint32_t *umap = tsl_alloc_array(s->n, sizeof *umap);
    uint32_t *idx = tsl_alloc_array(rows, sizeof *idx);
    float *d2 = tsl_alloc_array(rows, sizeof *d2);
    s->knn = tsl_alloc_array(s->n * s->k, sizeof *s->knn);
    s->nnd = tsl_alloc_array(s->n, sizeof *s->nnd);
    s->dup = tsl_calloc_array(s->n, sizeof *s->dup);
    s->ln = tsl_alloc_array(s->n * 3, sizeof *s->ln);
    s->vsign = tsl_calloc_array(s->n, sizeof *s->vsign);
    tessel_index *index = NULL;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!keys || !uxyz || !umap || !idx || !d2 || !s->knn || !s->nnd || !s->dup || !s->ln ||
        !s->vsign)
        goto done;
    for (size_t i = 0; i < s->n; i++) {
        keys[i].x = s->xyz[3 * i];
        keys[i].y = s->xyz[3 * i + 1];
        keys[i].z = s->xyz[3 * i + 2];
        keys[i].id = (uint32_t)i;
    }
    qsort(keys, s->n, sizeof *keys, cmp_xyz);
    for (size_t i = 1; i < s->n; i++)
        if (keys[i].x == keys[i - 1].x && keys[i].y == keys[i - 1].y &&
            keys[i].z == keys[i - 1].z)
            s->dup[keys[i].id] = 1;
    size_t m = 0;
    for (size_t i = 0; i < s->n; i++) {
        if (s->dup[i]) {
            for (uint32_t j = 0; j < s->k; j++)
                s->knn[i * s->k + j] = NONE;
            s->nnd[i] = INFINITY;
            s->ln[3 * i] = s->ln[3 * i + 1] = 0.0f;
            s->ln[3 * i + 2] = 1.0f;
            continue;
        }
        memcpy(uxyz + 3 * m, s->xyz + 3 * i, 3 * sizeof *uxyz);
        umap[m++] = (uint32_t)i;
    }
    if ((st = tessel_index_build(&index, uxyz, m)))
        goto done;
    if ((st = tessel_index_knn_batch(index, uxyz, m, kq, idx, d2, threads)))
        goto done;
    const float *given = s->pnormals;
    long long count = (long long)m;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (long long uu = 0; uu < count; uu++) {
        size_t u = (size_t)uu, i = umap[u];
        const uint32_t *row = idx + u * kq;
        const float *rd = d2 + u * kq;
        uint32_t *out = s->knn + i * s->k;
        size_t got = 0;
        double sum = 0.0, mean[3] = {0.0, 0.0, 0.0}, cov[9] = {0.0};
        unsigned counted = 0, used = 0;
        for (size_t j = 0; j < kq; j++) {
            if (row[j] == NONE)
                continue;
            const float *q = uxyz + 3 * (size_t)row[j];
            for (int c = 0; c < 3; c++)
                mean[c] += q[c];
            used++;
            if (row[j] == u)
                continue;
            if (counted < SPACING_NEIGHBOURS) {
                sum += sqrt((double)rd[j]);
                counted++;
            }
            if (got < s->k)
                out[got++] = umap[row[j]];
        }
        for (; got < s->k; got++)
            out[got] = NONE;
        s->nnd[i] = counted ? (float)(sum / counted) : INFINITY;
        float *ln = s->ln + 3 * i;
        if (given) {
            double g[3] = {given[3 * i], given[3 * i + 1], given[3 * i + 2]};
            if (tsl_normalize(g) && isfinite(g[0] + g[1] + g[2])) {
                for (int c = 0; c < 3; c++)
                    ln[c] = (float)g[c];
                continue;
            }
        }
        /* Normal of the least-squares plane through the neighbourhood. */
        for (int c = 0; c < 3; c++)
            mean[c] /= used;
        for (size_t j = 0; j < kq; j++) {
            if (row[j] == NONE)
                continue;
            const float *q = uxyz + 3 * (size_t)row[j];
            double d[3] = {q[0] - mean[0], q[1] - mean[1], q[2] - mean[2]};
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++)
                    cov[3 * r + c] += d[r] * d[c];
        }
        double nrm[3];
        if (!plane_normal(cov, nrm)) {
            nrm[0] = 0.0;
            nrm[1] = 0.0;
            nrm[2] = 1.0;
        }
        for (int c = 0; c < 3; c++)
            ln[c] = (float)nrm[c];
    }
    st = TESSEL_OK;
done:
    tessel_index_destroy(index);
    free(keys);
    free(uxyz);
    free(umap);
    free(idx);
    free(d2);
    return st;
}

tessel_status tsl_af_run_fronts(af *s, const tessel_callbacks *cb)
{
    tessel_status st;
    size_t cursor = 0, steps = 0;
    for (;;) {
        while (s->q_count) {
            uint32_t id = s->queue[s->q_head];
            s->q_head = (s->q_head + 1) & (s->q_cap - 1);
            s->q_count--;
            if (s->e[id].state != EDGE_ACTIVE)
                continue;
            af_plan plan = {PLAN_FREE, NONE, NONE};
            bool found;
            if ((st = find_plan(s, id, &plan, &found)))
                return st;
            if (found) {
                if ((st = tsl_af_commit(s, id, &plan)))
                    return st;
            } else {
                s->e[id].state = EDGE_DEAD;
            }
            if ((++steps & 4095) == 0 &&
                (st = tsl_progress(cb, "front", (double)s->used / (double)s->n)))
                return st;
        }
        if ((st = tsl_af_fill_holes(s)))
            return st;
        if (s->q_count)
            continue;
        bool seeded = false;
        while (cursor < s->n && !seeded) {
            if ((st = try_seed(s, (uint32_t)cursor, &seeded)))
                return st;
            cursor++;
        }
        if (!seeded)
            return TESSEL_OK;
    }
}

/* Derived parameters (angles as cosines, limits) from p. */
void tsl_af_params(af *s, const tessel_front_params *p)
{
    const double deg = acos(-1.0) / 180.0;
    s->cos_phi = cos(p->max_angle_deg * deg);
    s->theta0 = p->theta_deg * deg;
    s->theta_step = p->theta_step_deg * deg;
    s->theta_max = 90.0 * deg + s->theta_step;
    s->cos_theta_max = cos(s->theta_max);
    s->eps1 = p->max_edge_ratio;
    s->cos_normal = cos(p->normal_angle_deg * deg);
    s->cos_closing_fold = cos(CLOSING_FOLD_DEG * deg);
    s->cos_closing_normal = cos(CLOSING_NORMAL_DEG * deg);
    s->cos_last_fold = cos(LAST_FOLD_DEG * deg);
    s->max_hole_radius = p->max_hole_radius;
}

/* The empty mesh over s's points (neighbours prepared), with a triangle
 * grid of the given cell size. */
tessel_status tsl_af_alloc_mesh(af *s, double cell)
{
    size_t cap = 2 * s->n + 16;
    s->cap_t = cap;
    s->tri = tsl_alloc_array(3 * cap, sizeof *s->tri);
    s->ti = tsl_alloc_array(cap, sizeof *s->ti);
    s->cnext = tsl_alloc_array(3 * cap, sizeof *s->cnext);
    s->vhead = tsl_alloc_array(s->n, sizeof *s->vhead);
    s->vin = tsl_alloc_array(s->n, sizeof *s->vin);
    s->vout = tsl_alloc_array(s->n, sizeof *s->vout);
    s->seen = tsl_calloc_array(s->n, sizeof *s->seen);
    s->star = tsl_calloc_array(3 * s->n, sizeof *s->star);
    s->eroded = tsl_calloc_array(s->n, sizeof *s->eroded);
    s->vsign2 = tsl_calloc_array(s->n, sizeof *s->vsign2);
    size_t levels = (size_t)ceil((s->theta_max - s->theta0) / s->theta_step) + 2;
    s->cos_level = tsl_alloc_array(levels, sizeof *s->cos_level);
    if (!s->tri || !s->ti || !s->cnext || !s->vhead || !s->vin || !s->vout || !s->seen ||
        !s->star || !s->eroded || !s->vsign2 || !s->cos_level)
        return TESSEL_ERR_NOMEM;
    /* Level j admits normals turned by up to theta0 + j eps2 (capped at
     * theta_max, which the candidate search enforces). */
    for (size_t j = 0; j + 1 < levels; j++)
        s->cos_level[j] = cos(dmin(s->theta0 + (double)j * s->theta_step, s->theta_max));
    s->cos_level[levels - 1] = -2.0;
    for (size_t i = 0; i < s->n; i++)
        s->vhead[i] = s->vin[i] = s->vout[i] = NONE;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < s->n; i++)
        for (int c = 0; c < 3; c++) {
            lo[c] = dmin(lo[c], s->xyz[3 * i + c]);
            hi[c] = dmax(hi[c], s->xyz[3 * i + c]);
        }
    s->cell = cell;
    return tsl_trigrid_init(&s->grid, lo, hi, cell);
}

static tessel_status check_params(const tessel_front_params *p)
{
    if (p->k < 3 || p->k > MAX_K || !(p->theta_deg >= 0.0 && p->theta_deg <= 90.0) ||
        !(p->theta_step_deg > 0.0 && p->theta_step_deg <= 90.0) ||
        !(p->max_edge_ratio > 1.0 && isfinite(p->max_edge_ratio)) ||
        !(p->max_angle_deg >= 60.0 && p->max_angle_deg <= 180.0) ||
        !(p->normal_angle_deg > 0.0 && p->normal_angle_deg <= 180.0) ||
        !(p->max_hole_radius >= 0.0 && isfinite(p->max_hole_radius)) ||
        (p->tile_points > 0 && p->tile_points < 256))
        return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

/* tsl_advancing_front_from with its tiles run by runner. */
static tessel_status front_from(const tessel_cloud *points, const float *lines,
                                const tessel_front_params *params, const uint32_t *start,
                                size_t start_count, const tsl_af_tile_runner *runner,
                                const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                tessel_front_stats *stats);

tessel_status tessel_advancing_front(const tessel_cloud *points,
                                     const tessel_front_params *params,
                                     const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                     tessel_front_stats *stats)
{
    return tsl_advancing_front_lines(points, NULL, params, callbacks, mesh, stats);
}

tessel_status tsl_advancing_front_lines(const tessel_cloud *points, const float *lines,
                                        const tessel_front_params *params,
                                        const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                        tessel_front_stats *stats)
{
    return tsl_advancing_front_from(points, lines, params, NULL, 0, callbacks, mesh, stats);
}

tessel_status tsl_advancing_front_lines_with(const tessel_cloud *points, const float *lines,
                                             const tessel_front_params *params,
                                             const tsl_af_tile_runner *runner,
                                             const tessel_callbacks *callbacks,
                                             tessel_mesh *mesh, tessel_front_stats *stats)
{
    return front_from(points, lines, params, NULL, 0, runner, callbacks, mesh, stats);
}

tessel_status tsl_advancing_front_from(const tessel_cloud *points, const float *lines,
                                       const tessel_front_params *params,
                                       const uint32_t *start, size_t start_count,
                                       const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                       tessel_front_stats *stats)
{
    return front_from(points, lines, params, start, start_count, NULL, callbacks, mesh, stats);
}

static tessel_status front_from(const tessel_cloud *points, const float *lines,
                                const tessel_front_params *params, const uint32_t *start,
                                size_t start_count, const tsl_af_tile_runner *runner,
                                const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                tessel_front_stats *stats)
{
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!points || (points->count && !points->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_front_params p = params ? *params : tessel_front_params_default();
    tessel_status st = check_params(&p);
    if (st)
        return st;
    if (points->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;
    /* Corner ids 3 t + i of up to about 2n triangles stay below 2^32. */
    if (points->count > (size_t)UINT32_MAX / 8)
        return TESSEL_ERR_LIMIT;
    for (size_t i = 0; i < 3 * points->count; i++)
        if (!isfinite(points->xyz[i]))
            return TESSEL_ERR_INVALID_ARG;
    if (start_count && !start)
        return TESSEL_ERR_INVALID_ARG;
    for (size_t i = 0; i < 3 * start_count; i++)
        if (start[i] >= points->count)
            return TESSEL_ERR_INVALID_ARG;

    af s;
    memset(&s, 0, sizeof s);
    s.xyz = points->xyz;
    s.pnormals = points->normals;
    s.lines = lines;
    s.n = points->count;
    s.k = p.k < s.n - 1 ? p.k : (uint32_t)(s.n - 1);
    tsl_af_params(&s, &p);

    if ((st = tsl_progress(callbacks, "front", 0.0)))
        return st;
    if ((st = prepare_neighbours(&s, p.threads)))
        goto fail;
    /* Grid cells about two typical edges wide. */
    double mean_nn = 0.0;
    size_t counted = 0;
    for (size_t i = 0; i < s.n; i++)
        if (isfinite(s.nnd[i])) {
            mean_nn += s.nnd[i];
            counted++;
        }
    mean_nn = counted ? mean_nn / (double)counted : 1.0;
    if ((st = tsl_af_alloc_mesh(&s, 3.0 * mean_nn)))
        goto fail;
    if (p.tile_points > 0 && s.n > p.tile_points) {
        if ((st = tsl_af_run_tiles(&s, &p, mean_nn, start, start_count, runner, callbacks)))
            goto fail;
    } else if (start_count && (st = tsl_af_place_start(&s, start, start_count))) {
        goto fail;
    }
    if ((st = tsl_af_run_fronts(&s, callbacks)))
        goto fail;
    if (p.orient && (st = orient_components(&s)))
        goto fail;

    int with_normals = points->normals != NULL, with_rgb = points->rgb != NULL;
    if ((st = tessel_mesh_alloc(mesh, s.n, s.nt - s.deleted, with_normals, with_rgb)))
        goto fail;
    memcpy(mesh->xyz, s.xyz, s.n * 3 * sizeof *mesh->xyz);
    if (with_normals)
        memcpy(mesh->normals, points->normals, s.n * 3 * sizeof *mesh->normals);
    if (with_rgb)
        memcpy(mesh->rgb, points->rgb, s.n * 3 * sizeof *mesh->rgb);
    for (int c = 0; c < 3; c++)
        mesh->offset[c] = points->offset[c];
    size_t kept = 0;
    for (size_t t = 0; t < s.nt; t++)
        if (s.tri[3 * t] != NONE) {
            memcpy(mesh->triangles + 3 * kept, s.tri + 3 * t, 3 * sizeof *mesh->triangles);
            kept++;
        }

    s.stats.triangles = kept;
    for (size_t i = 0; i < s.ne; i++)
        if (s.e[i].state != EDGE_CLOSED)
            s.stats.border_edges++;
    s.stats.unused_points = s.n - s.used;
    if (stats)
        *stats = s.stats;
    tsl_af_free(&s);
    st = tsl_progress(callbacks, "front", 1.0);
    if (st)
        tessel_mesh_free(mesh);
    return st;
fail:
    tsl_af_free(&s);
    tessel_mesh_free(mesh);
    return st;
}
