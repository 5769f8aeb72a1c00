/* The editable mesh of the checked local edits (flips: mesh/flip.c;
 * splits: mesh/split.c): storage, twins and topology, the triangle grid
 * and the exact check of an edit's new triangles, and the blocks that let
 * edits run in parallel deterministically.
 *
 * The mesh is held as corners and twins (half-edge 3 t + i runs from
 * tri[3 t + i] to tri[3 t + (i + 1) % 3]), an edge map and the triangle
 * hash grid (mesh/trigrid.c). Every edit is checked before it is kept: its
 * new triangles must not turn by more than 60 degrees from the ones they
 * replace, and must not intersect any triangle of the mesh beyond shared
 * vertices and edges (exact predicates). An edit that fails is undone, so
 * the mesh stays manifold, oriented and free of self-intersections. */
#include "mesh/edit.h"

#include <stdlib.h>
#include <string.h>

static tessel_status map_grow(tsl_edge_map *m)
{
    tsl_edge_map bigger;
    tessel_status st = tsl_edge_map_init(&bigger, m->slots);
    if (st) {
        tsl_edge_map_free(&bigger);
        return st;
    }
    for (size_t s = 0; s < m->slots; s++)
        if (m->slot[s].key) {
            size_t t = tsl_edge_map_slot(&bigger, m->slot[s].key);
            while (bigger.slot[t].key)
                t = (t + 1) & (bigger.slots - 1);
            bigger.slot[t] = m->slot[s];
            bigger.count++;
        }
    tsl_edge_map_free(m);
    *m = bigger;
    return TESSEL_OK;
}

tessel_status tsl_edge_map_init(tsl_edge_map *m, size_t expected)
{
    m->slots = 64;
    while (m->slots < 2 * expected)
        m->slots *= 2;
    m->count = 0;
    m->slot = tsl_calloc_array(m->slots, sizeof *m->slot);
    return m->slot ? TESSEL_OK : TESSEL_ERR_NOMEM;
}

void tsl_edge_map_free(tsl_edge_map *m)
{
    free(m->slot);
    memset(m, 0, sizeof *m);
}

/* Sets the half-edge of {a, b}, adding the edge if new. */
tessel_status tsl_edge_map_put(tsl_edge_map *m, uint32_t a, uint32_t b, uint32_t he)
{
    if (2 * (m->count + 1) > m->slots) {
        tessel_status st = map_grow(m);
        if (st)
            return st;
    }
    uint64_t key = tsl_edge_key(a, b);
    size_t s = tsl_edge_map_slot(m, key);
    while (m->slot[s].key && m->slot[s].key != key)
        s = (s + 1) & (m->slots - 1);
    if (!m->slot[s].key) {
        m->slot[s].key = key;
        m->count++;
    }
    m->slot[s].val = he;
    return TESSEL_OK;
}

/* tsl_edge_map_put for several threads filling a map at once: the map was sized
 * for every key (no growth), each key is put once, and nobody reads it
 * until all are in. The caller sets m->count after. */
void tsl_edge_map_put_shared(tsl_edge_map *m, uint32_t a, uint32_t b, uint32_t he)
{
    uint64_t key = tsl_edge_key(a, b);
    for (size_t s = tsl_edge_map_slot(m, key);; s = (s + 1) & (m->slots - 1)) {
        uint64_t empty = 0;
        if (__atomic_compare_exchange_n(&m->slot[s].key, &empty, key, false, __ATOMIC_RELAXED,
                                        __ATOMIC_RELAXED)) {
            m->slot[s].val = he;
            return;
        }
    }
}

void tsl_edge_map_del(tsl_edge_map *m, uint32_t a, uint32_t b)
{
    uint64_t key = tsl_edge_key(a, b);
    size_t s = tsl_edge_map_slot(m, key);
    while (m->slot[s].key && m->slot[s].key != key)
        s = (s + 1) & (m->slots - 1);
    if (!m->slot[s].key)
        return;
    /* Backward shift: pull later entries of the probe run into the gap. */
    size_t gap = s;
    for (size_t j = (gap + 1) & (m->slots - 1); m->slot[j].key; j = (j + 1) & (m->slots - 1)) {
        size_t home = tsl_edge_map_slot(m, m->slot[j].key);
        bool movable = gap <= j ? (home <= gap || home > j) : (home <= gap && home > j);
        if (movable) {
            m->slot[gap] = m->slot[j];
            gap = j;
        }
    }
    m->slot[gap].key = 0;
    m->count--;
}

/* New triangles may turn at most this much from the ones they replace. */
#define MAX_TURN_DEG 60.0

tessel_status tsl_edit_init(tsl_edit *e)
{
    memset(e, 0, sizeof *e);
    e->cos_turn = cos(MAX_TURN_DEG * acos(-1.0) / 180.0);
    e->serial = tsl_calloc_array(1, sizeof *e->serial);
    return e->serial ? TESSEL_OK : TESSEL_ERR_NOMEM;
}

void tsl_edit_free(tsl_edit *e)
{
    free(e->xyz_own);
    free(e->rgb);
    free(e->tri);
    free(e->twin);
    free(e->box);
    tsl_edge_map_free(&e->edges);
    tsl_trigrid_free(&e->grid);
    free(e->pinched);
    if (e->serial)
        tsl_edit_worker_free(e->serial);
    free(e->serial);
    memset(e, 0, sizeof *e);
}

/* ------------------------------------------------------------------------ */
/* Geometry and the triangle grid                                           */
/* ------------------------------------------------------------------------ */

/* Cross product of triangle t's edges (twice its area along its normal). */
void tsl_edit_tri_cross(const tsl_edit *r, uint32_t t, double n[3])
{
    double a[3], b[3], c[3], u[3], v[3];
    tsl_edit_point(r, r->tri[3 * (size_t)t], a);
    tsl_edit_point(r, r->tri[3 * (size_t)t + 1], b);
    tsl_edit_point(r, r->tri[3 * (size_t)t + 2], c);
    tsl_sub(b, a, u);
    tsl_sub(c, a, v);
    tsl_cross(u, v, n);
}

static void tri_box(const tsl_edit *r, uint32_t t, double lo[3], double hi[3])
{
    for (int c = 0; c < 3; c++) {
        lo[c] = INFINITY;
        hi[c] = -INFINITY;
    }
    for (int i = 0; i < 3; i++) {
        const float *p = r->xyz + 3 * (size_t)r->tri[3 * (size_t)t + i];
        for (int c = 0; c < 3; c++) {
            lo[c] = p[c] < lo[c] ? p[c] : lo[c];
            hi[c] = p[c] > hi[c] ? p[c] : hi[c];
        }
    }
}

/* Lists triangle t in the grid at the box recorded for it. */
tessel_status tsl_edit_grid_list(tsl_edit *r, uint32_t t)
{
    const float *b = r->box + 6 * (size_t)t;
    const double lo[3] = {b[0], b[1], b[2]}, hi[3] = {b[3], b[4], b[5]};
    return tsl_trigrid_insert(&r->grid, t, lo, hi);
}

/* Records triangle t's box (exact: the corners are floats). */
static void box_record(tsl_edit *r, uint32_t t)
{
    double lo[3], hi[3];
    tri_box(r, t, lo, hi);
    float *b = r->box + 6 * (size_t)t;
    for (int c = 0; c < 3; c++) {
        float l = (float)lo[c], h = (float)hi[c];
        __atomic_store(&b[c], &l, __ATOMIC_RELAXED);
        __atomic_store(&b[3 + c], &h, __ATOMIC_RELAXED);
    }
}

/* Records triangle t's new box and lists it in the grid there (in a
 * parallel phase: in the tsl_edit_worker's overlay), unless the cells it is listed
 * in for its previous box hold the new one (a triangle is always listed in
 * every cell of its recorded box). fresh: t is new (no previous box).
 * *listed: whether it was listed now. */
tessel_status tsl_edit_grid_add(tsl_edit *r, tsl_edit_worker *w, uint32_t t, bool fresh,
                                bool *listed)
{
    float *b = r->box + 6 * (size_t)t;
    double olo[3] = {0.0, 0.0, 0.0}, ohi[3] = {0.0, 0.0, 0.0};
    if (!fresh)
        for (int c = 0; c < 3; c++)
            olo[c] = b[c], ohi[c] = b[3 + c];
    box_record(r, t);
    const double lo[3] = {b[0], b[1], b[2]}, hi[3] = {b[3], b[4], b[5]};
    *listed = fresh || !tsl_trigrid_covers(&r->grid, olo, ohi, lo, hi);
    if (!*listed)
        return TESSEL_OK;
    return tsl_trigrid_insert(w->parallel ? &w->overlay : &r->grid, t, lo, hi);
}

/* Whether every point q[0 .. count) lies strictly on one side of the plane
 * through o with normal n = e1 x e2 (e1, e2: two edges from o, squared
 * lengths given), with certainty: the plane test in double carries a
 * rounding error far below 1e-12 |e1| |e2| |q - o| when the inputs are
 * floats, so a larger value has the sign of the exact one. Lets most pairs
 * of neighbouring triangles skip the exact test (whose answer "apart" it
 * then gives: a triangle whose vertices off the other's shared ones lie
 * strictly on one side of the other's plane meets it at most in those). */
static bool clearly_one_side(const double o[3], const double n[3], double k2, const double *q[3],
                             int count)
{
    int side = 0;
    for (int j = 0; j < count; j++) {
        double d[3];
        tsl_sub(q[j], o, d);
        double s = tsl_dot(n, d);
        if (!(s * s > k2 * tsl_dot(d, d)))
            return false;
        int sj = s > 0.0 ? 1 : -1;
        if (side && sj != side)
            return false;
        side = sj;
    }
    return true;
}

/* A triangle being checked: ids, coordinates, box, bounding sphere. */
typedef struct new_tri {
    const uint32_t *v;
    double p[3][3];
    double lo[3], hi[3], centroid[3], radius;
    double n[3], k2; /* e1 x e2 and the certainty bound of clearly_one_side */
} new_tri;

/* Fills n and k2 (see clearly_one_side) for the triangle p. */
static void plane_of(const double p[3][3], double n[3], double *k2)
{
    double e1[3], e2[3];
    tsl_sub(p[1], p[0], e1);
    tsl_sub(p[2], p[0], e2);
    tsl_cross(e1, e2, n);
    *k2 = 1e-24 * tsl_dot(e1, e1) * tsl_dot(e2, e2);
}

/* Exact intersection test of a new triangle x with e (vertex ids ev,
 * corners pe), behind the certain plane filters. */
static bool meets(const new_tri *x, const uint32_t ev[3], const double pe[3][3])
{
    const double *qe[3], *qx[3];
    int ne = 0, nx = 0;
    for (int j = 0; j < 3; j++) {
        if (ev[j] != x->v[0] && ev[j] != x->v[1] && ev[j] != x->v[2])
            qe[ne++] = pe[j];
        if (x->v[j] != ev[0] && x->v[j] != ev[1] && x->v[j] != ev[2])
            qx[nx++] = x->p[j];
    }
    if (ne == 0)
        return true; /* the same three vertices */
    if (clearly_one_side(x->p[0], x->n, x->k2, qe, ne))
        return false;
    double n[3], k2;
    plane_of(pe, n, &k2);
    if (clearly_one_side(pe[0], n, k2, qx, nx))
        return false;
    const double *pp[3] = {x->p[0], x->p[1], x->p[2]};
    const double *pq[3] = {pe[0], pe[1], pe[2]};
    return tsl_triangles_intersect(x->v, pp, ev, pq);
}

/* The count triangles news[] of one operation (already written into the
 * mesh) each keep to their predecessor's unit normal old_n[q], are not
 * degenerate, and intersect neither each other nor any other triangle of
 * the mesh beyond shared vertices and edges (exact). One grid query covers
 * them all; the grid knows the changed triangles at their old place, so they
 * are tested against each other explicitly. */
tessel_status tsl_edit_check_news(const tsl_edit *r, tsl_edit_worker *w, const uint32_t *news,
                                  int count, const double (*old_n)[3], bool *ok)
{
    *ok = false;
    new_tri nt[4];
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int q = 0; q < count; q++) {
        new_tri *x = &nt[q];
        x->v = r->tri + 3 * (size_t)news[q];
        for (int i = 0; i < 3; i++)
            tsl_edit_point(r, x->v[i], x->p[i]);
        plane_of(x->p, x->n, &x->k2);
        double n[3] = {x->n[0], x->n[1], x->n[2]};
        if (!tsl_normalize(n) || tsl_dot(n, old_n[q]) < r->cos_turn)
            return TESSEL_OK;
        const double *pp[3] = {x->p[0], x->p[1], x->p[2]};
        if (tsl_triangle_degenerate(pp))
            return TESSEL_OK;
        x->radius = 0.0;
        for (int c = 0; c < 3; c++) {
            x->lo[c] = fmin(x->p[0][c], fmin(x->p[1][c], x->p[2][c]));
            x->hi[c] = fmax(x->p[0][c], fmax(x->p[1][c], x->p[2][c]));
            x->centroid[c] = (x->p[0][c] + x->p[1][c] + x->p[2][c]) / 3.0;
            lo[c] = x->lo[c] < lo[c] ? x->lo[c] : lo[c];
            hi[c] = x->hi[c] > hi[c] ? x->hi[c] : hi[c];
        }
        for (int i = 0; i < 3; i++) {
            double d[3];
            tsl_sub(x->p[i], x->centroid, d);
            double l = tsl_norm(d);
            x->radius = l > x->radius ? l : x->radius;
        }
    }
    for (int a = 0; a < count; a++)
        for (int b = a + 1; b < count; b++)
            if (meets(&nt[a], nt[b].v, (const double(*)[3])nt[b].p))
                return TESSEL_OK;
    tessel_status st = tsl_trigrid_hits_begin(&w->hits);
    if (!st)
        st = tsl_trigrid_collect(&r->grid, lo, hi, &w->hits);
    if (!st && w->parallel)
        st = tsl_trigrid_collect(&w->overlay, lo, hi, &w->hits);
    if (st)
        return st;
    for (size_t i = 0; i < w->hits.count; i++) {
        uint32_t e = w->hits.found[i];
        if (e >= (w->id_end ? w->id_end : r->nt))
            continue;
        /* The box of e where it is now (the grid may list it elsewhere). */
        float eb[6];
        box_load(r, e, eb);
        if (eb[3] < lo[0] || eb[0] > hi[0] || eb[4] < lo[1] || eb[1] > hi[1] || eb[5] < lo[2] ||
            eb[2] > hi[2])
            continue;
        bool is_new = false;
        for (int q = 0; q < count; q++)
            is_new |= news[q] == e;
        if (is_new)
            continue;
        const uint32_t *ev = r->tri + 3 * (size_t)e;
        double p[3][3], ce[3] = {0.0, 0.0, 0.0}, re = -1.0;
        for (int j = 0; j < 3; j++)
            tsl_edit_point(r, ev[j], p[j]);
        for (int q = 0; q < count; q++) {
            const new_tri *x = &nt[q];
            if (eb[3] < x->lo[0] || eb[0] > x->hi[0] || eb[4] < x->lo[1] || eb[1] > x->hi[1] ||
                eb[5] < x->lo[2] || eb[2] > x->hi[2])
                continue;
            const uint32_t *tv = x->v;
            bool shares = false;
            for (int a = 0; a < 3; a++)
                shares |= tv[a] == ev[0] || tv[a] == ev[1] || tv[a] == ev[2];
            if (!shares) {
                /* Bounding spheres apart. */
                if (re < 0.0) {
                    double re2 = 0.0;
                    for (int c = 0; c < 3; c++)
                        ce[c] = (p[0][c] + p[1][c] + p[2][c]) / 3.0;
                    for (int j = 0; j < 3; j++) {
                        double d[3];
                        tsl_sub(p[j], ce, d);
                        double l = tsl_dot(d, d);
                        re2 = l > re2 ? l : re2;
                    }
                    re = sqrt(re2);
                }
                double d[3];
                tsl_sub(ce, x->centroid, d);
                double reach = x->radius + re;
                if (tsl_dot(d, d) > reach * reach)
                    continue;
            }
            if (meets(x, ev, (const double(*)[3])p))
                return TESSEL_OK;
        }
    }
    *ok = true;
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Storage, twins and topology                                              */
/* ------------------------------------------------------------------------ */

tessel_status tsl_edit_reserve(tsl_edit *r, size_t more_v, size_t more_t)
{
    /* Vertex ids and half-edge ids 3 t + i stay below TESSEL_NONE. */
    if (r->nv + more_v >= UINT32_MAX || r->nt + more_t >= UINT32_MAX / 3)
        return TESSEL_ERR_LIMIT;
    if (r->nv + more_v > r->cap_v) {
        size_t c1 = r->cap_v, c2 = r->cap_v;
        if (tsl_grow((void **)&r->xyz_own, &c1, r->nv + more_v, 3 * sizeof *r->xyz_own) ||
            (r->rgb && tsl_grow((void **)&r->rgb, &c2, r->nv + more_v, 3)))
            return TESSEL_ERR_NOMEM;
        r->xyz = r->xyz_own;
        r->cap_v = r->rgb && c2 < c1 ? c2 : c1;
    }
    if (r->nt + more_t > r->cap_t) {
        size_t c1 = r->cap_t, c2 = r->cap_t;
        size_t c3 = r->cap_t;
        if (tsl_grow((void **)&r->tri, &c1, r->nt + more_t, 3 * sizeof *r->tri) ||
            tsl_grow((void **)&r->twin, &c2, r->nt + more_t, 3 * sizeof *r->twin) ||
            tsl_grow((void **)&r->box, &c3, r->nt + more_t, 6 * sizeof *r->box))
            return TESSEL_ERR_NOMEM;
        r->cap_t = c1 < c2 ? c1 : c2;
        r->cap_t = c3 < r->cap_t ? c3 : r->cap_t;
    }
    return TESSEL_OK;
}

/* Every triangle has three distinct vertices, all in range. */
static bool corners_valid(const tsl_edit *r)
{
    for (size_t t = 0; t < r->nt; t++) {
        const uint32_t *v = r->tri + 3 * t;
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2] || v[0] >= r->nv || v[1] >= r->nv ||
            v[2] >= r->nv)
            return false;
    }
    return true;
}

/* Whether the edge {a, b} exists, h being a half-edge leaving a: walks a's
 * fan (one fan: the mesh is vertex-manifold) one way to the end or all
 * round, then the other way. Used instead of the edge map when only
 * flipping. */
bool tsl_edit_edge_exists(const tsl_edit *r, uint32_t h, uint32_t b)
{
    uint32_t e = h;
    do {
        if (tsl_he_to(r, e) == b || tsl_he_from(r, he_prev(e)) == b)
            return true;
        e = r->twin[he_prev(e)];
    } while (e != NONE && e != h);
    if (e == h)
        return false;
    for (e = r->twin[h]; e != NONE; e = r->twin[e]) {
        e = he_next(e);
        if (tsl_he_to(r, e) == b || tsl_he_from(r, he_prev(e)) == b)
            return true;
    }
    return false;
}

/* Twins without an edge map, vertex by vertex from its corners: corner c
 * at a is the half-edge a -> x (x = tsl_he_to) and follows y -> a (y the
 * source of he_prev(c)); the twin of a -> x is he_prev of the corner whose
 * y is x. INVALID_ARG for a triangle with a repeated or bad vertex, an
 * edge run twice the same way or in more than two triangles, and (when
 * pinched is NULL) a vertex with more than one fan (tsl_edit_edge_exists needs
 * one); else such vertices are flagged in pinched[0 .. nv). */
tessel_status tsl_edit_twins(tsl_edit *r, int threads, uint8_t *pinched)
{
    if (!corners_valid(r))
        return TESSEL_ERR_INVALID_ARG;
    uint32_t *start, *corner;
    tessel_status st = tsl_vertex_corners(r->tri, r->nt, r->nv, &start, &corner);
    if (st)
        return st;
    uint32_t most = 0;
    for (size_t v = 0; v < r->nv; v++)
        most = start[v + 1] - start[v] > most ? start[v + 1] - start[v] : most;
    ptrdiff_t nv = (ptrdiff_t)r->nv;
    bool nomem = false, invalid = false;
    /* Each vertex writes the twins of its own corners only. */
#pragma omp parallel num_threads(tsl_threads(threads)) reduction(|| : nomem, invalid)
    {
        uint32_t *out = tsl_alloc_array(most, sizeof *out);
        uint32_t *in = tsl_alloc_array(most, sizeof *in);
        uint32_t *next = tsl_alloc_array(most, sizeof *next);
        if (!out || !in || !next)
            nomem = true;
#pragma omp for schedule(dynamic, 1024)
        for (ptrdiff_t v = 0; v < nv; v++) {
            if (nomem || invalid)
                continue;
            const uint32_t *c = corner + start[v];
            uint32_t n = start[v + 1] - start[v];
            for (uint32_t k = 0; k < n; k++) {
                out[k] = tsl_he_to(r, c[k]);
                in[k] = tsl_he_from(r, he_prev(c[k]));
            }
            /* next[k]: the corner across the edge v -> out[k], NONE on the
             * border. */
            for (uint32_t k = 0; k < n; k++) {
                next[k] = NONE;
                for (uint32_t j = 0; j < n; j++) {
                    if (j != k && out[j] == out[k])
                        invalid = true;
                    if (in[j] == out[k]) {
                        if (next[k] != NONE)
                            invalid = true;
                        next[k] = j;
                    }
                }
                r->twin[c[k]] = next[k] == NONE ? NONE : he_prev(c[next[k]]);
            }
            /* One fan: from the corner no other corner leads to (a border),
             * or from any corner when the fan is closed, the walk meets all
             * n (in now flags the corners some corner leads to). */
            for (uint32_t k = 0; k < n; k++)
                in[k] = 0;
            for (uint32_t k = 0; k < n; k++)
                if (next[k] != NONE)
                    in[next[k]] = 1;
            uint32_t first = 0, seen = 0;
            for (uint32_t k = 0; k < n; k++)
                if (!in[k])
                    first = k;
            for (uint32_t k = first; k != NONE && seen <= n; k = next[k] == first ? NONE : next[k])
                seen++;
            if (n && seen != n) {
                if (pinched)
                    pinched[v] = 1;
                else
                    invalid = true;
            }
        }
        free(out);
        free(in);
        free(next);
    }
    free(start);
    free(corner);
    return nomem ? TESSEL_ERR_NOMEM : invalid ? TESSEL_ERR_INVALID_ARG : TESSEL_OK;
}

/* Twins (tsl_edit_twins, in parallel) and the edge map (each edge at its
 * half-edge of smaller id), and r->pinched for vertices with more than one
 * fan; INVALID_ARG for a non-manifold or inconsistently oriented mesh or a
 * triangle with a repeated or bad vertex. */
tessel_status tsl_edit_topology(tsl_edit *r, int threads)
{
    size_t nh = 3 * r->nt;
    uint8_t *pinched = tsl_calloc_array(r->nv + 1, sizeof *pinched);
    tessel_status st = pinched ? tsl_edit_twins(r, threads, pinched) : TESSEL_ERR_NOMEM;
    size_t edges = 0;
    ptrdiff_t count = (ptrdiff_t)nh;
    if (!st) {
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads)) reduction(+ : edges)
        for (ptrdiff_t h = 0; h < count; h++)
            edges += r->twin[h] == NONE || r->twin[h] > (uint32_t)h;
        st = tsl_edge_map_init(&r->edges, edges);
    }
    if (!st) {
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
        for (ptrdiff_t h = 0; h < count; h++)
            if (r->twin[h] == NONE || r->twin[h] > (uint32_t)h)
                tsl_edge_map_put_shared(&r->edges, tsl_he_from(r, (uint32_t)h),
                                        tsl_he_to(r, (uint32_t)h), (uint32_t)h);
        r->edges.count = edges;
    }
    size_t any = 0;
    for (size_t v = 0; v < r->nv && pinched; v++)
        any += pinched[v];
    if (st || !any) {
        free(pinched);
        return st;
    }
    r->pinched = pinched;
    r->npinched = r->nv;
    return TESSEL_OK;
}

/* Whether the pair at half-edge h would make an edge at a vertex of
 * several fans (see tsl_edit.pinched). */
bool tsl_edit_pair_pinched(const tsl_edit *r, uint32_t h, uint32_t g)
{
    if (!r->pinched)
        return false;
    uint32_t a = r->tri[he_prev(h)], b = r->tri[he_prev(g)];
    return (a < r->npinched && r->pinched[a]) || (b < r->npinched && r->pinched[b]);
}

/* ------------------------------------------------------------------------ */
/* Blocks of parallel edits                                                 */
/* ------------------------------------------------------------------------ */

/* Appends x to the array *a of *n (capacity *cap). */
bool tsl_push_u32(uint32_t **a, size_t *n, size_t *cap, uint32_t x)
{
    if (*n == *cap && tsl_grow((void **)a, cap, *n + 1, sizeof **a))
        return false;
    (*a)[(*n)++] = x;
    return true;
}

void tsl_edit_worker_free(tsl_edit_worker *w)
{
    tsl_trigrid_hits_free(&w->hits);
    tsl_trigrid_free(&w->overlay);
    free(w->log);
    free(w->seg);
    free(w->next);
    free(w->tail);
    free(w->undo);
    tsl_edge_map_free(&w->moved);
    free(w->moved_ab);
    memset(w, 0, sizeof *w);
}

void tsl_edit_blocks_init(const tsl_edit *r, blocks *b)
{
    double cell = 1.0 / r->grid.inv_cell;
    b->reach = LONG_CELLS * cell;
    b->size = BLOCK_CELLS * cell;
    for (;;) {
        size_t count = 1;
        for (int k = 0; k < 3; k++) {
            double n = floor((r->hi[k] - r->lo[k]) / b->size) + 1.0;
            b->n[k] = n < (double)MAX_BLOCKS ? (int)n : (int)MAX_BLOCKS;
            count *= (size_t)b->n[k];
        }
        if (count <= MAX_BLOCKS) {
            b->count = (uint32_t)count;
            break;
        }
        b->size *= 2.0;
    }
    memcpy(b->origin, r->lo, sizeof b->origin);
}

/* The key (colour count + block) of the pair at half-edge h, or NONE when
 * one of its triangles is long (the tail takes it). */
uint32_t tsl_edit_pair_key(const tsl_edit *r, const blocks *b, uint32_t h)
{
    uint32_t g = twin_load(r, h);
    if (g == NONE)
        return NONE;
    float b1[6], b2[6];
    box_load(r, h / 3, b1);
    box_load(r, g / 3, b2);
    uint32_t id = 0, colour = 0;
    for (int k = 2; k >= 0; k--) {
        if (b1[3 + k] - b1[k] > b->reach || b2[3 + k] - b2[k] > b->reach)
            return NONE;
        double lo = b1[k] < b2[k] ? b1[k] : b2[k],
               hi = b1[3 + k] > b2[3 + k] ? b1[3 + k] : b2[3 + k];
        double x = floor((0.5 * (lo + hi) - b->origin[k]) / b->size);
        int c = x < 0.0 ? 0 : x >= (double)b->n[k] ? b->n[k] - 1 : (int)x;
        colour |= (uint32_t)(c & 1) << k;
        id = id * (uint32_t)b->n[k] + (uint32_t)c;
    }
    return colour * b->count + id;
}

static int cmp_seg(const void *a, const void *b)
{
    uint32_t x = ((const seg_ref *)a)->key, y = ((const seg_ref *)b)->key;
    return (x > y) - (x < y);
}

/* The blocks the workers did in a phase, by key: (key, tsl_edit_worker, index of
 * the block's part of the tsl_edit_worker's log); *m of them. */
seg_ref *tsl_edit_blocks_done(const tsl_edit_worker *ws, int nw, size_t *m)
{
    size_t nseg = 0;
    for (int t = 0; t < nw; t++)
        nseg += ws[t].nseg / 2;
    seg_ref *order = tsl_alloc_array(nseg ? nseg : 1, sizeof *order);
    *m = 0;
    if (!order)
        return NULL;
    for (int t = 0; t < nw; t++)
        for (size_t k = 0; k < ws[t].nseg / 2; k++)
            order[(*m)++] = (seg_ref){ws[t].seg[2 * k], (uint32_t)t, k};
    if (*m)
        qsort(order, *m, sizeof *order, cmp_seg);
    return order;
}

/* After a phase's merge: the workers' tails into *tail, their logs
 * emptied for the next phase. */
tessel_status tsl_edit_gather_tails(tsl_edit_worker *ws, int nw, uint32_t **tail, size_t *ntail,
                                    size_t *cap_tail)
{
    for (int t = 0; t < nw; t++) {
        tsl_edit_worker *w = &ws[t];
        for (size_t k = 0; k < w->ntail; k++)
            if (!tsl_push_u32(tail, ntail, cap_tail, w->tail[k]))
                return TESSEL_ERR_NOMEM;
        w->nlog = w->nseg = w->ntail = 0;
    }
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Normals and the grid of the whole mesh                                   */
/* ------------------------------------------------------------------------ */

/* Area-weighted vertex normals (unnormalised sums, then unit). */
tessel_status tsl_edit_vertex_normals(const tsl_edit *r, double **out)
{
    double *n = tsl_calloc_array(3 * r->nv, sizeof *n);
    if (!n)
        return TESSEL_ERR_NOMEM;
    for (size_t t = 0; t < r->nt; t++) {
        double c[3];
        tsl_edit_tri_cross(r, (uint32_t)t, c);
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++)
                n[3 * (size_t)r->tri[3 * t + i] + k] += c[k];
    }
    for (size_t v = 0; v < r->nv; v++)
        tsl_normalize(n + 3 * v);
    *out = n;
    return TESSEL_OK;
}

/* Cells covered by the triangles' recorded boxes in a grid of the given
 * cell from origin, counted up to limit. */
static double cells_covered(const tsl_edit *r, const double origin[3], double cell, double limit)
{
    double total = 0.0;
    for (size_t t = 0; t < r->nt && total <= limit; t++) {
        const float *b = r->box + 6 * t;
        double cells = 1.0;
        for (int c = 0; c < 3; c++)
            cells *= floor((b[3 + c] - origin[c]) / cell) - floor((b[c] - origin[c]) / cell) + 1.0;
        total += cells;
    }
    return total;
}

/* The cell, doubled until the triangles cover at most 16 cells each on
 * average: a caller's mesh may hold a triangle far larger than its mean
 * edge (one large triangle among small ones filled gigabytes with cells).
 * The grid only culls candidates, so the cell changes no result; the
 * meshes of the pipeline keep two mean edges. */
static double grid_cell(const tsl_edit *r, const double origin[3], double cell, double *entries)
{
    *entries = 0.0;
    if (!(cell > 0.0) || !isfinite(cell))
        return cell; /* tsl_trigrid_init's fallback */
    const double limit = 16.0 * (double)r->nt + 1024.0;
    while ((*entries = cells_covered(r, origin, cell, limit)) > limit)
        cell *= 2.0;
    return cell;
}

/* A fresh grid for the round, with cells two mean edges wide: the edges
 * shrink from round to round. It boxes the triangles, not every vertex: a
 * point no triangle uses (an outlier the front left out) must not stretch
 * the cells. */
tessel_status tsl_edit_grid(tsl_edit *r)
{
    tsl_trigrid_free(&r->grid);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double mean_len = 0.0;
    for (size_t t = 0; t < r->nt; t++) {
        box_record(r, (uint32_t)t);
        const float *b = r->box + 6 * t;
        for (int k = 0; k < 3; k++) {
            lo[k] = b[k] < lo[k] ? b[k] : lo[k];
            hi[k] = b[3 + k] > hi[k] ? b[3 + k] : hi[k];
        }
        double a[3], c[3], d[3];
        tsl_edit_point(r, r->tri[3 * t], a);
        tsl_edit_point(r, r->tri[3 * t + 1], c);
        tsl_sub(c, a, d);
        mean_len += tsl_norm(d);
    }
    mean_len /= (double)r->nt;
    memcpy(r->lo, lo, sizeof r->lo);
    memcpy(r->hi, hi, sizeof r->hi);
    /* Sized beforehand: growing the grid insert by insert cost 40% more on
     * 2,000,000 triangles (copies and rehashes). A cell holds about 16
     * entries on the meshes of the project. */
    double entries;
    double cell = grid_cell(r, lo, 2.0 * mean_len, &entries);
    tessel_status st = tsl_trigrid_init(&r->grid, lo, hi, cell);
    if (!st)
        st = tsl_trigrid_reserve(&r->grid, (size_t)entries, (size_t)(entries / 16.0));
    for (size_t t = 0; t < r->nt && !st; t++)
        st = tsl_edit_grid_list(r, (uint32_t)t);
    return st;
}
