/* Mesh refinement against a point cloud: step 5 of Mederos, Velho & de
 * Figueiredo 2003, "Smooth surface reconstruction from noisy clouds",
 * section 2.5.
 *
 * Each round looks at every edge uv: its midpoint m, the normal n_m (the
 * normalised sum of u's and v's normals, each the area-weighted mean normal
 * of its star) and a = mean over the k nearest cloud points p of
 * (p - m).n_m, the offset along n_m of the least-squares closest point to
 * the cloud. When |a| > eps the edge is split at Q(m + a n_m), Q being the
 * robust projection operator of section 2.1, and so are its one or two
 * triangles (a-u-v becomes a-u-m' and a-m'-v), unless one of them is too
 * skinny (shortest / longest edge below a ratio). Then diagonals are
 * flipped wherever the other diagonal of two adjacent triangles is shorter.
 *
 * The per-edge work (neighbour search, fit, projection) runs in parallel;
 * splits and flips are then applied one at a time in a fixed order (longest
 * edge first), each checked before it is kept: its new triangles must not
 * turn by more than 60 degrees from the ones they replace, and must not
 * intersect any triangle of the mesh beyond shared vertices and edges
 * (exact predicates, the advancing front's triangle hash grid). A split or
 * flip that fails is undone, so the mesh stays manifold, oriented and free
 * of self-intersections. */
#include "mesh/mesh.h"
#include "smooth/smooth.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#define NONE TESSEL_NONE
#define MAX_K 256
/* New triangles may turn at most this much from the ones they replace. */
#define MAX_TURN_DEG 60.0
/* Flip passes per round at most (each pass flips every improvable edge). */
#define MAX_FLIP_PASSES 6

tessel_refine_params tessel_refine_params_default(void)
{
    tessel_refine_params p;
    memset(&p, 0, sizeof p);
    p.rounds = 2;
    p.k = 16;
    p.min_offset = 0.1;
    p.min_edge_length = 1.5;
    p.min_edge_ratio = 0.2;
    p.flip = 1;
    p.threads = 0;
    return p;
}

/* Open-addressing map from an undirected edge to one of its half-edges,
 * with backward-shift deletion. A slot holds key and value together: a
 * lookup that misses the cache costs one line, not two. */
typedef struct edge_slot {
    uint64_t key; /* (min << 32 | max) + 1; 0 = empty */
    uint32_t val;
} edge_slot;

typedef struct edge_map {
    edge_slot *slot;
    size_t slots, count;
} edge_map;

typedef struct rf {
    const float *xyz; /* the vertices: xyz_own, or the caller's points when
                         only flipping (tsl_flip_diagonals never splits) */
    float *xyz_own;   /* the refinement's own copy, which grows */
    uint8_t *rgb; /* NULL when the mesh has no colours */
    size_t nv, cap_v;
    uint32_t *tri;  /* 3 per triangle */
    uint32_t *twin; /* per half-edge 3t+i (tri[3t+i] -> tri[3t+(i+1)%3]) */
    float *box;     /* per triangle: lo[3], hi[3] of its current corners */
    size_t nt, cap_t;
    edge_map edges;
    tsl_trigrid grid;
    double cos_turn;
    bool delaunay; /* the flip rule: see flip_edge */
    /* The previous round's fits: edge -> index into fit_sum (3 floats per
     * edge, the sum over its midpoint's k nearest cloud points of p - m).
     * Vertices never move, so an edge that survives a round keeps its
     * midpoint, its neighbours and this sum. */
    edge_map fit_of;
    float *fit_sum;
    tessel_refine_stats stats;
    double lo[3], hi[3]; /* the triangles' box when the grid was built */
    struct worker *serial; /* the checks and flips outside parallel phases */
    /* pinched[v]: vertex v (v < npinched) has more than one fan; NULL when
     * none has. edge_exists sees one fan only, so their flips go to the
     * serial tail, which asks the edge map. */
    uint8_t *pinched;
    size_t npinched;
} rf;

/* One split: the edge x -> y (half-edge h = slot i of T1 = (x, y, a)) and
 * its twin (slot j of T2 = (y, x, b), or none) become x - m - y; T1 turns
 * into (x, m, a) and T3 = (m, y, a) is new, T2 into (y, m, b) and T4 =
 * (m, x, b). What it replaced is kept to take it back. */
typedef struct split_info {
    uint32_t x, y, a, b, m, T1, T2, T3, T4, i, j;
    uint32_t news[4];
    int count;           /* 2 without T2, else 4 */
    double olds[4][3];   /* unit normals of the triangles each new one replaces */
    uint32_t tri[6], twin[6];
    float box[12];
} split_info;

/* What one thread checks and flips with. Serially (splits, and the flips
 * of the serial tail) the checks query the mesh's grid, and a flip updates
 * the grid and the edge map at once. In a parallel phase of the flips (see
 * flip_passes) those two are only read: the triangles a flip changes go
 * into the thread's overlay grid, which the later checks of its block
 * query too, and the flip into a log that is applied after the phase. */
typedef struct worker {
    tsl_trigrid_hits hits;
    bool parallel;
    tsl_trigrid overlay;
    uint32_t *log; /* per flip: T1, T2, u, v, a, b */
    size_t nlog, cap_log;
    uint32_t *seg; /* per block done: its key and the end of its part of log */
    size_t nseg, cap_seg;
    uint32_t *next; /* half-edges to look at in the next pass */
    size_t nnext, cap_next;
    uint32_t *tail; /* pairs that left their block, for the pass's tail */
    size_t ntail, cap_tail;
    size_t flips, invalid;
    tessel_status status;
    /* The parallel splits (split_passes): ids below id_end are triangles
     * (0: below r->nt); the block's splits, to take back at its end; the
     * edges they moved, which the mesh's edge map does not know yet; the
     * worker's own vertex and triangle ids for them. */
    size_t id_end;
    split_info *undo;
    size_t nundo, cap_undo;
    edge_map moved;
    uint32_t *moved_ab; /* the moved edges' ends, to clear the map */
    size_t nmoved, cap_moved;
    uint32_t base_v, base_t;
    size_t skinny;
} worker;

static inline uint64_t edge_key(uint32_t a, uint32_t b)
{
    uint64_t lo = a < b ? a : b, hi = a < b ? b : a;
    return (lo << 32 | hi) + 1;
}

static inline size_t map_slot(const edge_map *m, uint64_t key)
{
    uint64_t h = key * 0x9E3779B97F4A7C15ULL;
    return (size_t)(h ^ (h >> 31)) & (m->slots - 1);
}

static tessel_status map_init(edge_map *m, size_t expected)
{
    m->slots = 64;
    while (m->slots < 2 * expected)
        m->slots *= 2;
    m->count = 0;
    m->slot = tsl_calloc_array(m->slots, sizeof *m->slot);
    return m->slot ? TESSEL_OK : TESSEL_ERR_NOMEM;
}

static void map_free(edge_map *m)
{
    free(m->slot);
    memset(m, 0, sizeof *m);
}

static uint32_t map_get(const edge_map *m, uint32_t a, uint32_t b)
{
    uint64_t key = edge_key(a, b);
    for (size_t s = map_slot(m, key); m->slot[s].key; s = (s + 1) & (m->slots - 1))
        if (m->slot[s].key == key)
            return m->slot[s].val;
    return NONE;
}

/* Asks for the line of {a, b}'s home slot ahead of a map_get. */
static inline void map_prefetch(const edge_map *m, uint32_t a, uint32_t b)
{
    __builtin_prefetch(&m->slot[map_slot(m, edge_key(a, b))]);
}

static tessel_status map_grow(edge_map *m)
{
    edge_map bigger;
    tessel_status st = map_init(&bigger, m->slots);
    if (st) {
        map_free(&bigger);
        return st;
    }
    for (size_t s = 0; s < m->slots; s++)
        if (m->slot[s].key) {
            size_t t = map_slot(&bigger, m->slot[s].key);
            while (bigger.slot[t].key)
                t = (t + 1) & (bigger.slots - 1);
            bigger.slot[t] = m->slot[s];
            bigger.count++;
        }
    map_free(m);
    *m = bigger;
    return TESSEL_OK;
}

/* Sets the half-edge of {a, b}, adding the edge if new. */
static tessel_status map_put(edge_map *m, uint32_t a, uint32_t b, uint32_t he)
{
    if (2 * (m->count + 1) > m->slots) {
        tessel_status st = map_grow(m);
        if (st)
            return st;
    }
    uint64_t key = edge_key(a, b);
    size_t s = map_slot(m, key);
    while (m->slot[s].key && m->slot[s].key != key)
        s = (s + 1) & (m->slots - 1);
    if (!m->slot[s].key) {
        m->slot[s].key = key;
        m->count++;
    }
    m->slot[s].val = he;
    return TESSEL_OK;
}

/* map_put for several threads filling a map at once: the map was sized
 * for every key (no growth), each key is put once, and nobody reads it
 * until all are in. The caller sets m->count after. */
static void map_put_shared(edge_map *m, uint32_t a, uint32_t b, uint32_t he)
{
    uint64_t key = edge_key(a, b);
    for (size_t s = map_slot(m, key);; s = (s + 1) & (m->slots - 1)) {
        uint64_t empty = 0;
        if (__atomic_compare_exchange_n(&m->slot[s].key, &empty, key, false, __ATOMIC_RELAXED,
                                        __ATOMIC_RELAXED)) {
            m->slot[s].val = he;
            return;
        }
    }
}

static void map_del(edge_map *m, uint32_t a, uint32_t b)
{
    uint64_t key = edge_key(a, b);
    size_t s = map_slot(m, key);
    while (m->slot[s].key && m->slot[s].key != key)
        s = (s + 1) & (m->slots - 1);
    if (!m->slot[s].key)
        return;
    /* Backward shift: pull later entries of the probe run into the gap. */
    size_t gap = s;
    for (size_t j = (gap + 1) & (m->slots - 1); m->slot[j].key; j = (j + 1) & (m->slots - 1)) {
        size_t home = map_slot(m, m->slot[j].key);
        bool movable = gap <= j ? (home <= gap || home > j) : (home <= gap && home > j);
        if (movable) {
            m->slot[gap] = m->slot[j];
            gap = j;
        }
    }
    m->slot[gap].key = 0;
    m->count--;
}

/* ------------------------------------------------------------------------ */
/* Geometry helpers                                                          */
/* ------------------------------------------------------------------------ */

static inline void vtx(const rf *r, uint32_t v, double out[3])
{
    tsl_load(r->xyz + 3 * (size_t)v, out);
}

static inline uint32_t he_from(const rf *r, uint32_t h) { return r->tri[h]; }
static inline uint32_t he_to(const rf *r, uint32_t h)
{
    return r->tri[h - h % 3 + (h % 3 + 1) % 3];
}

/* Cross product of triangle t's edges (twice its area along its normal). */
static void tri_cross(const rf *r, uint32_t t, double n[3])
{
    double a[3], b[3], c[3], u[3], v[3];
    vtx(r, r->tri[3 * (size_t)t], a);
    vtx(r, r->tri[3 * (size_t)t + 1], b);
    vtx(r, r->tri[3 * (size_t)t + 2], c);
    tsl_sub(b, a, u);
    tsl_sub(c, a, v);
    tsl_cross(u, v, n);
}

static void tri_box(const rf *r, uint32_t t, double lo[3], double hi[3])
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
static tessel_status grid_list(rf *r, uint32_t t)
{
    const float *b = r->box + 6 * (size_t)t;
    const double lo[3] = {b[0], b[1], b[2]}, hi[3] = {b[3], b[4], b[5]};
    return tsl_trigrid_insert(&r->grid, t, lo, hi);
}

/* Records triangle t's box (exact: the corners are floats). */
static void box_record(rf *r, uint32_t t)
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

/* Triangle t's recorded box. In a parallel phase of the flips a check may
 * find, through a listing left from an earlier place, a triangle that
 * another thread is flipping far away; either box it reads is far, so the
 * box test rejects it, and the relaxed atomic accesses (plain moves)
 * make that read well defined. */
static inline void box_load(const rf *r, uint32_t t, float out[6])
{
    const float *b = r->box + 6 * (size_t)t;
    for (int c = 0; c < 6; c++)
        __atomic_load(&b[c], &out[c], __ATOMIC_RELAXED);
}

/* Restores triangle t's recorded box (as box_load reads it). */
static inline void box_store(rf *r, uint32_t t, const float in[6])
{
    float *b = r->box + 6 * (size_t)t;
    for (int c = 0; c < 6; c++) {
        float v = in[c];
        __atomic_store(&b[c], &v, __ATOMIC_RELAXED);
    }
}

/* Records triangle t's new box and lists it in the grid there (in a
 * parallel phase: in the worker's overlay), unless the cells it is listed
 * in for its previous box hold the new one (a triangle is always listed in
 * every cell of its recorded box). fresh: t is new (no previous box).
 * *listed: whether it was listed now. */
static tessel_status grid_add(rf *r, worker *w, uint32_t t, bool fresh, bool *listed)
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
static bool clearly_one_side(const double o[3], const double n[3], double k2,
                             const double *q[3], int count)
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
static tessel_status check_news(const rf *r, worker *w, const uint32_t *news, int count,
                                const double (*old_n)[3], bool *ok)
{
    *ok = false;
    new_tri nt[4];
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int q = 0; q < count; q++) {
        new_tri *x = &nt[q];
        x->v = r->tri + 3 * (size_t)news[q];
        for (int i = 0; i < 3; i++)
            vtx(r, x->v[i], x->p[i]);
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
        if (eb[3] < lo[0] || eb[0] > hi[0] || eb[4] < lo[1] || eb[1] > hi[1] ||
            eb[5] < lo[2] || eb[2] > hi[2])
            continue;
        bool is_new = false;
        for (int q = 0; q < count; q++)
            is_new |= news[q] == e;
        if (is_new)
            continue;
        const uint32_t *ev = r->tri + 3 * (size_t)e;
        double p[3][3], ce[3] = {0.0, 0.0, 0.0}, re = -1.0;
        for (int j = 0; j < 3; j++)
            vtx(r, ev[j], p[j]);
        for (int q = 0; q < count; q++) {
            const new_tri *x = &nt[q];
            if (eb[3] < x->lo[0] || eb[0] > x->hi[0] || eb[4] < x->lo[1] ||
                eb[1] > x->hi[1] || eb[5] < x->lo[2] || eb[2] > x->hi[2])
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
/* Storage                                                                   */
/* ------------------------------------------------------------------------ */

static tessel_status reserve(rf *r, size_t more_v, size_t more_t)
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

/* Twins are stored and, where a parallel phase of the flips may read a
 * pair that another thread owns (pair_key), loaded with relaxed atomics
 * (plain moves): such a read only finds the pair is not the reader's. */
static inline void set_twin(rf *r, uint32_t h, uint32_t g)
{
    __atomic_store_n(&r->twin[h], g, __ATOMIC_RELAXED);
    if (g != NONE)
        __atomic_store_n(&r->twin[g], h, __ATOMIC_RELAXED);
}

static inline uint32_t twin_load(const rf *r, uint32_t h)
{
    return __atomic_load_n(&r->twin[h], __ATOMIC_RELAXED);
}

/* Every triangle has three distinct vertices, all in range. */
static bool corners_valid(const rf *r)
{
    for (size_t t = 0; t < r->nt; t++) {
        const uint32_t *v = r->tri + 3 * t;
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2] || v[0] >= r->nv || v[1] >= r->nv ||
            v[2] >= r->nv)
            return false;
    }
    return true;
}

static inline uint32_t he_next(uint32_t h) { return h - h % 3 + (h % 3 + 1) % 3; }
static inline uint32_t he_prev(uint32_t h) { return h - h % 3 + (h % 3 + 2) % 3; }

/* Whether the edge {a, b} exists, h being a half-edge leaving a: walks a's
 * fan (one fan: the mesh is vertex-manifold) one way to the end or all
 * round, then the other way. Used instead of the edge map when only
 * flipping. */
static bool edge_exists(const rf *r, uint32_t h, uint32_t b)
{
    uint32_t e = h;
    do {
        if (he_to(r, e) == b || he_from(r, he_prev(e)) == b)
            return true;
        e = r->twin[he_prev(e)];
    } while (e != NONE && e != h);
    if (e == h)
        return false;
    for (e = r->twin[h]; e != NONE; e = r->twin[e]) {
        e = he_next(e);
        if (he_to(r, e) == b || he_from(r, he_prev(e)) == b)
            return true;
    }
    return false;
}

/* Twins without an edge map, vertex by vertex from its corners: corner c
 * at a is the half-edge a -> x (x = he_to) and follows y -> a (y the
 * source of he_prev(c)); the twin of a -> x is he_prev of the corner whose
 * y is x. INVALID_ARG for a triangle with a repeated or bad vertex, an
 * edge run twice the same way or in more than two triangles, and (when
 * pinched is NULL) a vertex with more than one fan (edge_exists needs
 * one); else such vertices are flagged in pinched[0 .. nv). */
static tessel_status build_twins(rf *r, int threads, uint8_t *pinched)
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
                out[k] = he_to(r, c[k]);
                in[k] = he_from(r, he_prev(c[k]));
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
            for (uint32_t k = first; k != NONE && seen <= n;
                 k = next[k] == first ? NONE : next[k])
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

/* Twins (build_twins, in parallel) and the edge map (each edge at its
 * half-edge of smaller id), and r->pinched for vertices with more than one
 * fan; INVALID_ARG for a non-manifold or inconsistently oriented mesh or a
 * triangle with a repeated or bad vertex. */
static tessel_status build_topology(rf *r, int threads)
{
    size_t nh = 3 * r->nt;
    uint8_t *pinched = tsl_calloc_array(r->nv + 1, sizeof *pinched);
    tessel_status st = pinched ? build_twins(r, threads, pinched) : TESSEL_ERR_NOMEM;
    size_t edges = 0;
    ptrdiff_t count = (ptrdiff_t)nh;
    if (!st) {
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads)) reduction(+ : edges)
        for (ptrdiff_t h = 0; h < count; h++)
            edges += r->twin[h] == NONE || r->twin[h] > (uint32_t)h;
        st = map_init(&r->edges, edges);
    }
    if (!st) {
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
        for (ptrdiff_t h = 0; h < count; h++)
            if (r->twin[h] == NONE || r->twin[h] > (uint32_t)h)
                map_put_shared(&r->edges, he_from(r, (uint32_t)h), he_to(r, (uint32_t)h),
                               (uint32_t)h);
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
 * several fans (see rf.pinched). */
static bool pair_pinched(const rf *r, uint32_t h, uint32_t g)
{
    if (!r->pinched)
        return false;
    uint32_t a = r->tri[he_prev(h)], b = r->tri[he_prev(g)];
    return (a < r->npinched && r->pinched[a]) || (b < r->npinched && r->pinched[b]);
}

/* ------------------------------------------------------------------------ */
/* Split and flip                                                            */
/* ------------------------------------------------------------------------ */


/* Whether the triangles of the edge at h (twin g) are skinny (the paper's
 * ratio test: a triangle whose shortest edge is under min_ratio times its
 * longest is not divided). */
static bool split_skinny(const rf *r, uint32_t h, uint32_t g, double min_ratio)
{
    uint32_t sides[2] = {h / 3, g == NONE ? NONE : g / 3};
    for (int s = 0; s < 2; s++) {
        if (sides[s] == NONE)
            continue;
        double p[3][3], lmin = INFINITY, lmax = 0.0;
        for (int i = 0; i < 3; i++)
            vtx(r, r->tri[3 * (size_t)sides[s] + i], p[i]);
        for (int i = 0; i < 3; i++) {
            double d[3];
            tsl_sub(p[(i + 1) % 3], p[i], d);
            double l = tsl_norm(d);
            lmin = l < lmin ? l : lmin;
            lmax = l > lmax ? l : lmax;
        }
        if (!(lmin >= min_ratio * lmax))
            return true;
    }
    return false;
}

/* Splits the edge at h at pos into the vertex m and the triangles T3 (and
 * T4 when the edge has a twin), whose room the caller made. */
static void split_apply(rf *r, uint32_t h, const float pos[3], uint32_t m, uint32_t T3,
                        uint32_t T4, split_info *s)
{
    uint32_t g = r->twin[h];
    uint32_t T1 = h / 3, i = h % 3, T2 = g == NONE ? NONE : g / 3, j = g == NONE ? 0 : g % 3;
    s->T1 = T1, s->T2 = T2, s->i = i, s->j = j, s->m = m, s->T3 = T3;
    s->T4 = T2 == NONE ? NONE : T4;
    memcpy(s->tri, r->tri + 3 * (size_t)T1, 3 * sizeof *s->tri);
    memcpy(s->twin, r->twin + 3 * (size_t)T1, 3 * sizeof *s->twin);
    box_load(r, T1, s->box);
    double old1[3], old2[3] = {0.0, 0.0, 0.0};
    tri_cross(r, T1, old1);
    tsl_normalize(old1);
    if (T2 != NONE) {
        memcpy(s->tri + 3, r->tri + 3 * (size_t)T2, 3 * sizeof *s->tri);
        memcpy(s->twin + 3, r->twin + 3 * (size_t)T2, 3 * sizeof *s->twin);
        box_load(r, T2, s->box + 6);
        tri_cross(r, T2, old2);
        tsl_normalize(old2);
    }
    uint32_t x = r->tri[3 * T1 + i], y = r->tri[3 * T1 + (i + 1) % 3];
    uint32_t a = r->tri[3 * T1 + (i + 2) % 3];
    s->x = x, s->y = y, s->a = a, s->b = NONE;
    for (int c = 0; c < 3; c++)
        r->xyz_own[3 * (size_t)m + c] = pos[c];
    if (r->rgb)
        for (int c = 0; c < 3; c++)
            r->rgb[3 * (size_t)m + c] = (uint8_t)((r->rgb[3 * (size_t)x + c] +
                                                   r->rgb[3 * (size_t)y + c] + 1) / 2);
    uint32_t h_ya = 3 * T1 + (i + 1) % 3, tw_ya = r->twin[h_ya];
    r->tri[3 * T1 + (i + 1) % 3] = m;
    r->tri[3 * T3] = m;
    r->tri[3 * T3 + 1] = y;
    r->tri[3 * T3 + 2] = a;
    uint32_t tw_xb = NONE;
    if (T2 != NONE) {
        s->b = r->tri[3 * T2 + (j + 2) % 3];
        tw_xb = r->twin[3 * T2 + (j + 1) % 3];
        r->tri[3 * T2 + (j + 1) % 3] = m;
        r->tri[3 * T4] = m;
        r->tri[3 * T4 + 1] = x;
        r->tri[3 * T4 + 2] = s->b;
    }
    /* Twins. T1: x->m (slot i), m->a (slot i+1), a->x (slot i+2, kept). */
    set_twin(r, 3 * T1 + (i + 1) % 3, 3 * T3 + 2); /* m->a / a->m */
    set_twin(r, 3 * T3 + 1, tw_ya);                /* y->a */
    if (T2 != NONE) {
        set_twin(r, 3 * T1 + i, 3 * T4);               /* x->m / m->x */
        set_twin(r, 3 * T3, 3 * T2 + j);               /* m->y / y->m */
        set_twin(r, 3 * T2 + (j + 1) % 3, 3 * T4 + 2); /* m->b / b->m */
        set_twin(r, 3 * T4 + 1, tw_xb);                /* x->b */
    } else {
        set_twin(r, 3 * T1 + i, NONE);
        set_twin(r, 3 * T3, NONE);
    }
    s->news[0] = T1, s->news[1] = T3, s->news[2] = T2, s->news[3] = T4;
    s->count = T2 != NONE ? 4 : 2;
    for (int c = 0; c < 3; c++) {
        s->olds[0][c] = s->olds[1][c] = old1[c];
        s->olds[2][c] = s->olds[3][c] = old2[c];
    }
}

/* Takes split s back: T1 and T2 as they were (corners, twins both ways,
 * boxes); m, T3 and T4 are left unreferenced. */
static void split_undo(rf *r, const split_info *s)
{
    const uint32_t T[2] = {s->T1, s->T2};
    for (int k = 0; k < 2 && T[k] != NONE; k++) {
        memcpy(r->tri + 3 * (size_t)T[k], s->tri + 3 * k, 3 * sizeof *s->tri);
        box_store(r, T[k], s->box + 6 * k);
    }
    for (int k = 0; k < 2 && T[k] != NONE; k++)
        for (uint32_t q = 0; q < 3; q++)
            set_twin(r, 3 * T[k] + q, s->twin[3 * k + q]);
}

/* The edge map after split s: x-y gone, its six (or four) edges at their
 * half-edges. */
static tessel_status split_map(rf *r, const split_info *s)
{
    uint32_t T1 = s->T1, T2 = s->T2, T3 = s->T3, T4 = s->T4, i = s->i, j = s->j, m = s->m;
    tessel_status st;
    map_del(&r->edges, s->x, s->y);
    if ((st = map_put(&r->edges, s->x, m, 3 * T1 + i)) ||
        (st = map_put(&r->edges, m, s->y, 3 * T3)) ||
        (st = map_put(&r->edges, m, s->a, 3 * T1 + (i + 1) % 3)) ||
        (st = map_put(&r->edges, s->y, s->a, 3 * T3 + 1)))
        return st;
    if (T2 != NONE && ((st = map_put(&r->edges, m, s->b, 3 * T2 + (j + 1) % 3)) ||
                       (st = map_put(&r->edges, s->x, s->b, 3 * T4 + 1))))
        return st;
    return TESSEL_OK;
}

/* The boxes of split s's triangles, listed where they left their cells
 * (in the worker's overlay in a parallel phase). */
static tessel_status split_grid(rf *r, worker *w, const split_info *s)
{
    for (int q = 0; q < s->count; q++) {
        bool listed; /* T3 and T4 are new */
        tessel_status st = grid_add(r, w, s->news[q], q % 2 == 1, &listed);
        if (st)
            return st;
    }
    return TESSEL_OK;
}

/* Splits edge {u, v} at position pos (a new vertex; colour the mean of the
 * ends), serially: checked, then kept or taken back. *done reports
 * whether it was kept. */
static tessel_status split_edge(rf *r, uint32_t u, uint32_t v, const float pos[3],
                                double min_ratio, bool *done)
{
    *done = false;
    uint32_t h = map_get(&r->edges, u, v);
    if (h == NONE)
        return TESSEL_OK;
    uint32_t g = r->twin[h];
    if (split_skinny(r, h, g, min_ratio)) {
        r->stats.skipped_skinny++;
        return TESSEL_OK;
    }
    tessel_status st = reserve(r, 1, 2);
    if (st)
        return st;
    uint32_t m = (uint32_t)r->nv++, T3 = (uint32_t)r->nt++;
    uint32_t T4 = g == NONE ? NONE : (uint32_t)r->nt++;
    split_info s;
    split_apply(r, h, pos, m, T3, T4, &s);
    bool ok;
    if ((st = check_news(r, r->serial, s.news, s.count, (const double(*)[3])s.olds, &ok)))
        return st;
    if (!ok) {
        split_undo(r, &s);
        r->nt -= (size_t)(s.count / 2);
        r->nv--;
        r->stats.skipped_invalid++;
        return TESSEL_OK;
    }
    if ((st = split_map(r, &s)) || (st = split_grid(r, r->serial, &s)))
        return st;
    r->stats.splits++;
    *done = true;
    return TESSEL_OK;
}

/* The angles opposite the diagonal {u, v}, at a and at b, add up to more
 * than pi: cot A + cot B < 0, with cot at o = (e1 . e2) / |e1 x e2|,
 * compared multiplied out (no division by a zero area). The pair is then
 * not locally Delaunay, and the other diagonal raises its smallest angle. */
static bool opposite_angles_over_pi(const double pu[3], const double pv[3], const double pa[3],
                                    const double pb[3])
{
    double e1[3], e2[3], e3[3], e4[3], ca[3], cb[3];
    tsl_sub(pu, pa, e1);
    tsl_sub(pv, pa, e2);
    tsl_sub(pu, pb, e3);
    tsl_sub(pv, pb, e4);
    tsl_cross(e1, e2, ca);
    tsl_cross(e3, e4, cb);
    double sa = tsl_norm(ca), sb = tsl_norm(cb);
    return tsl_dot(e1, e2) * sb + tsl_dot(e3, e4) * sa < -1e-9 * sa * sb;
}

/* The other diagonal {a, b} is shorter than {u, v}, by a margin so that no
 * edge flips back and forth (the paper's rule). */
static bool other_diagonal_shorter(const double pu[3], const double pv[3], const double pa[3],
                                   const double pb[3])
{
    double d1[3], d2[3];
    tsl_sub(pv, pu, d1);
    tsl_sub(pb, pa, d2);
    return tsl_dot(d2, d2) < (1.0 - 1e-6) * tsl_dot(d1, d1);
}

static void worker_free(worker *w)
{
    tsl_trigrid_hits_free(&w->hits);
    tsl_trigrid_free(&w->overlay);
    free(w->log);
    free(w->seg);
    free(w->next);
    free(w->tail);
    free(w->undo);
    map_free(&w->moved);
    free(w->moved_ab);
    memset(w, 0, sizeof *w);
}

/* Appends x to the array *a of *n (capacity *cap). */
static bool push(uint32_t **a, size_t *n, size_t *cap, uint32_t x)
{
    if (*n == *cap && tsl_grow((void **)a, cap, *n + 1, sizeof **a))
        return false;
    (*a)[(*n)++] = x;
    return true;
}

/* Whether the pair at half-edge h asks for a flip by the rule (see
 * flip_edge), as its triangles stand. */
static bool rule_holds(const rf *r, uint32_t h)
{
    uint32_t g = r->twin[h];
    if (g == NONE)
        return false;
    uint32_t T1 = h / 3, i = h % 3, T2 = g / 3, j = g % 3;
    uint32_t a = r->tri[3 * T1 + (i + 2) % 3], b = r->tri[3 * T2 + (j + 2) % 3];
    if (a == b)
        return false;
    double pu[3], pv[3], pa[3], pb[3];
    vtx(r, r->tri[3 * T1 + i], pu);
    vtx(r, r->tri[3 * T1 + (i + 1) % 3], pv);
    vtx(r, a, pa);
    vtx(r, b, pb);
    return r->delaunay ? opposite_angles_over_pi(pu, pv, pa, pb)
                       : other_diagonal_shorter(pu, pv, pa, pb);
}

/* The edge map after the flip of {u, v} to {a, b}, T1 = (u, b, a) and T2 =
 * (v, a, b); nothing when refinement keeps no map (the greedy flips). */
static tessel_status flip_map(rf *r, uint32_t T1, uint32_t T2, uint32_t u, uint32_t v,
                              uint32_t a, uint32_t b)
{
    if (!r->edges.slot)
        return TESSEL_OK;
    tessel_status st;
    map_del(&r->edges, u, v);
    if ((st = map_put(&r->edges, a, b, 3 * T1 + 1)) || (st = map_put(&r->edges, u, b, 3 * T1)) ||
        (st = map_put(&r->edges, a, u, 3 * T1 + 2)) || (st = map_put(&r->edges, v, a, 3 * T2)) ||
        (st = map_put(&r->edges, b, v, 3 * T2 + 2)))
        return st;
    return TESSEL_OK;
}

/* Flips the diagonal {u, v} of its two triangles when the rule asks for it
 * (r->delaunay: the opposite angles add up to more than pi; else the
 * paper's: the other diagonal is shorter) and the result is valid.
 * *again: refused for a reason outside the two triangles (the other
 * diagonal exists, or the flip would cut the mesh), so a later pass must
 * look at it again even if they stay as they are. */
static tessel_status flip_edge(rf *r, worker *w, uint32_t h, bool *done, bool *again)
{
    *done = false;
    *again = false;
    uint32_t g = r->twin[h];
    if (g == NONE)
        return TESSEL_OK;
    uint32_t T1 = h / 3, i = h % 3, T2 = g / 3, j = g % 3;
    uint32_t u = r->tri[3 * T1 + i], v = r->tri[3 * T1 + (i + 1) % 3];
    uint32_t a = r->tri[3 * T1 + (i + 2) % 3], b = r->tri[3 * T2 + (j + 2) % 3];
    if (a == b)
        return TESSEL_OK;
    double pu[3], pv[3], pa[3], pb[3];
    vtx(r, u, pu);
    vtx(r, v, pv);
    vtx(r, a, pa);
    vtx(r, b, pb);
    /* The rule first; then the edge map (a cache miss on large meshes),
     * which a parallel phase does not update: there the fan of a. */
    if (r->delaunay ? !opposite_angles_over_pi(pu, pv, pa, pb)
                    : !other_diagonal_shorter(pu, pv, pa, pb))
        return TESSEL_OK;
    *again = true;
    if (r->edges.slot && !w->parallel ? map_get(&r->edges, a, b) != NONE
                                      : edge_exists(r, 3 * T1 + (i + 2) % 3, b))
        return TESSEL_OK;
    double n1[3], n2[3], avg[3];
    tri_cross(r, T1, n1);
    tri_cross(r, T2, n2);
    for (int c = 0; c < 3; c++)
        avg[c] = n1[c] + n2[c];
    if (!tsl_normalize(avg))
        return TESSEL_OK;
    uint32_t tw_vA = r->twin[3 * T1 + (i + 1) % 3], tw_Au = r->twin[3 * T1 + (i + 2) % 3];
    uint32_t tw_uB = r->twin[3 * T2 + (j + 1) % 3], tw_Bv = r->twin[3 * T2 + (j + 2) % 3];
    uint32_t save_tri[6], save_twin[6];
    memcpy(save_tri, r->tri + 3 * (size_t)T1, 3 * sizeof *save_tri);
    memcpy(save_tri + 3, r->tri + 3 * (size_t)T2, 3 * sizeof *save_tri);
    memcpy(save_twin, r->twin + 3 * (size_t)T1, 3 * sizeof *save_twin);
    memcpy(save_twin + 3, r->twin + 3 * (size_t)T2, 3 * sizeof *save_twin);
    /* (u, v, a) + (v, u, b) -> (u, b, a) + (v, a, b). */
    uint32_t *t1 = r->tri + 3 * (size_t)T1, *t2 = r->tri + 3 * (size_t)T2;
    t1[0] = u, t1[1] = b, t1[2] = a;
    t2[0] = v, t2[1] = a, t2[2] = b;
    set_twin(r, 3 * T1, tw_uB);
    set_twin(r, 3 * T1 + 1, 3 * T2 + 1);
    set_twin(r, 3 * T1 + 2, tw_Au);
    set_twin(r, 3 * T2, tw_vA);
    set_twin(r, 3 * T2 + 2, tw_Bv);
    uint32_t news[2] = {T1, T2};
    const double olds[2][3] = {{avg[0], avg[1], avg[2]}, {avg[0], avg[1], avg[2]}};
    bool ok;
    tessel_status st = check_news(r, w, news, 2, olds, &ok);
    if (st)
        return st;
    if (!ok) {
        memcpy(r->tri + 3 * (size_t)T1, save_tri, 3 * sizeof *save_tri);
        memcpy(r->tri + 3 * (size_t)T2, save_tri + 3, 3 * sizeof *save_tri);
        memcpy(r->twin + 3 * (size_t)T1, save_twin, 3 * sizeof *save_twin);
        memcpy(r->twin + 3 * (size_t)T2, save_twin + 3, 3 * sizeof *save_twin);
        for (uint32_t q = 0; q < 3; q++) {
            set_twin(r, 3 * T1 + q, r->twin[3 * T1 + q]);
            set_twin(r, 3 * T2 + q, r->twin[3 * T2 + q]);
        }
        w->invalid++;
        return TESSEL_OK;
    }
    if (w->parallel) {
        const uint32_t rec[6] = {T1, T2, u, v, a, b};
        for (int k = 0; k < 6; k++)
            if (!push(&w->log, &w->nlog, &w->cap_log, rec[k]))
                return TESSEL_ERR_NOMEM;
    } else if ((st = flip_map(r, T1, T2, u, v, a, b))) {
        return st;
    }
    bool listed1, listed2;
    if ((st = grid_add(r, w, T1, false, &listed1)) || (st = grid_add(r, w, T2, false, &listed2)))
        return st;
    if (w->parallel) {
        /* Which of the two the merge must list in the mesh's grid. */
        w->log[w->nlog - 6] |= (uint32_t)listed1 << 31;
        w->log[w->nlog - 5] |= (uint32_t)listed2 << 31;
    }
    w->flips++;
    *done = true;
    *again = false;
    return TESSEL_OK;
}

/* The flips run in passes. A pass looks at the edges marked for it: at
 * first every edge; then the six of the two triangles of every flip (on
 * both sides) and those refused for a reason outside their own two
 * triangles (every other edge would be refused again for the same reason;
 * on 10^6 points the later passes flip a few hundred edges out of
 * 900,000).
 *
 * A pass runs in parallel, deterministically. Space is cut into blocks of
 * BLOCK_CELLS grid cells a side, coloured by the parity of their three
 * coordinates. Each pair of triangles whose boxes both fit in LONG_CELLS
 * cells goes to the block of its box's centre; the eight colours take
 * turns, and the blocks of one colour are flipped in parallel, each in
 * half-edge order by one thread. Two blocks of a colour are at least a
 * block apart, so the boxes of their pairs are more than BLOCK_CELLS - 2
 * LONG_CELLS cells apart: neither flip reads a triangle, a twin or a grid
 * cell the other writes, and none can meet the other's new triangles.
 * Pairs with a longer triangle, and pairs whose block changed because a
 * neighbour flipped first, are done after the colours, serially, in
 * half-edge order (the tail). The result depends on the mesh only, not on
 * the thread count. */
#define BLOCK_CELLS 8
#define LONG_CELLS 2
/* Blocks at most (larger blocks beyond): a pass's counting sort has 8
 * counters per block, cleared every pass. */
#define MAX_BLOCKS (1u << 18)

typedef struct blocks {
    double origin[3], size, reach;
    int n[3];
    uint32_t count; /* blocks; keys run over 8 count (colour-major) */
} blocks;

static void blocks_init(const rf *r, blocks *b)
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
static uint32_t pair_key(const rf *r, const blocks *b, uint32_t h)
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
        double lo = b1[k] < b2[k] ? b1[k] : b2[k], hi = b1[3 + k] > b2[3 + k] ? b1[3 + k] : b2[3 + k];
        double x = floor((0.5 * (lo + hi) - b->origin[k]) / b->size);
        int c = x < 0.0 ? 0 : x >= (double)b->n[k] ? b->n[k] - 1 : (int)x;
        colour |= (uint32_t)(c & 1) << k;
        id = id * (uint32_t)b->n[k] + (uint32_t)c;
    }
    return colour * b->count + id;
}

/* Marks for the next pass the six edges of the two triangles of a flip at
 * h, on both sides. */
static bool mark_flipped(const rf *r, uint32_t h, uint32_t g, uint8_t *look, worker *w)
{
    const uint32_t quad[2] = {h / 3, g / 3};
    for (int q = 0; q < 2; q++)
        for (uint32_t i = 0; i < 3; i++) {
            uint32_t e = 3 * quad[q] + i, f = r->twin[e];
            if (look) {
                look[e] = 1;
                if (f != NONE)
                    look[f] = 1;
            } else if (!push(&w->next, &w->nnext, &w->cap_next, e) ||
                       (f != NONE && !push(&w->next, &w->nnext, &w->cap_next, f))) {
                return false;
            }
        }
    return true;
}

/* One block of a parallel phase: the pairs list[0 .. n) of key `key`. */
static void flip_block(rf *r, const blocks *b, worker *w, uint32_t key, const uint32_t *list,
                       size_t n)
{
    /* The overlay holds this block's flips only: the other blocks of the
     * phase are far, and the log carries everything to the mesh's grid. */
    tsl_trigrid_clear(&w->overlay);
    for (size_t k = 0; k < n && !w->status; k++) {
        uint32_t h = list[k], g = twin_load(r, h);
        if (g == NONE)
            continue;
        if (pair_key(r, b, h) != key || pair_pinched(r, h, g)) {
            if (!push(&w->tail, &w->ntail, &w->cap_tail, h))
                w->status = TESSEL_ERR_NOMEM;
            continue;
        }
        bool done, again;
        if ((w->status = flip_edge(r, w, h, &done, &again)))
            break;
        if (done ? !mark_flipped(r, h, g, NULL, w)
                 : again && !push(&w->next, &w->nnext, &w->cap_next, h))
            w->status = TESSEL_ERR_NOMEM;
    }
    if (!w->status && (!push(&w->seg, &w->nseg, &w->cap_seg, key) ||
                       !push(&w->seg, &w->nseg, &w->cap_seg, (uint32_t)w->nlog)))
        w->status = TESSEL_ERR_NOMEM;
}

typedef struct seg_ref {
    uint32_t key, worker;
    size_t index;
} seg_ref;

static int cmp_seg(const void *a, const void *b)
{
    uint32_t x = ((const seg_ref *)a)->key, y = ((const seg_ref *)b)->key;
    return (x > y) - (x < y);
}

/* The blocks the workers did in a phase, by key: (key, worker, index of
 * the block's part of the worker's log); *m of them. */
static seg_ref *blocks_done(const worker *ws, int nw, size_t *m)
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
static tessel_status gather_tails(worker *ws, int nw, uint32_t **tail, size_t *ntail,
                                  size_t *cap_tail)
{
    for (int t = 0; t < nw; t++) {
        worker *w = &ws[t];
        for (size_t k = 0; k < w->ntail; k++)
            if (!push(tail, ntail, cap_tail, w->tail[k]))
                return TESSEL_ERR_NOMEM;
        w->nlog = w->nseg = w->ntail = 0;
    }
    return TESSEL_OK;
}

/* After a phase: the flips of every block, in key order, into the edge
 * map and the grid; the marks into look; the tails gathered. */
static tessel_status merge_phase(rf *r, worker *ws, int nw, uint8_t *look, uint32_t **tail,
                                 size_t *ntail, size_t *cap_tail)
{
    size_t m;
    seg_ref *order = blocks_done(ws, nw, &m);
    if (!order)
        return TESSEL_ERR_NOMEM;
    tessel_status st = TESSEL_OK;
    for (size_t k = 0; k < m && !st; k++) {
        const worker *w = &ws[order[k].worker];
        size_t s = order[k].index;
        size_t from = s ? w->seg[2 * s - 1] : 0, to = w->seg[2 * s + 1];
        for (size_t f = from; f < to && !st; f += 6) {
            const uint32_t *x = w->log + f;
            const uint32_t top = (uint32_t)1 << 31;
            uint32_t T1 = x[0] & ~top, T2 = x[1] & ~top, u = x[2], v = x[3], a = x[4], b = x[5];
            if ((st = flip_map(r, T1, T2, u, v, a, b)))
                break;
            /* A triangle one of whose flips had to be listed is listed at
             * its box as it ends the phase; the boxes of the others stayed
             * within cells where they are listed already. */
            if ((x[0] & top && (st = grid_list(r, T1))) || (x[1] & top && (st = grid_list(r, T2))))
                break;
        }
    }
    free(order);
    for (int t = 0; t < nw; t++) {
        worker *w = &ws[t];
        for (size_t k = 0; k < w->nnext; k++)
            look[w->next[k]] = 1;
        w->nnext = 0;
    }
    return st ? st : gather_tails(ws, nw, tail, ntail, cap_tail);
}

/* The serial tail of a pass: the pairs tail[0 .. n), sorted, in order. */
static tessel_status flip_tail(rf *r, uint32_t *tail, size_t n, uint8_t *look, size_t *flips)
{
    if (n)
        qsort(tail, n, sizeof *tail, tsl_cmp_u32);
    worker *w = r->serial;
    for (size_t k = 0; k < n; k++) {
        uint32_t h = tail[k], g = r->twin[h];
        if ((k && tail[k - 1] == h) || g == NONE)
            continue;
        bool done, again;
        size_t before = w->flips;
        tessel_status st = flip_edge(r, w, h, &done, &again);
        if (st)
            return st;
        *flips += w->flips - before;
        if (done)
            mark_flipped(r, h, g, look, NULL);
        else if (again)
            look[h] = 1;
    }
    return TESSEL_OK;
}

static tessel_status flip_passes(rf *r, int threads)
{
    size_t nh = 3 * r->nt;
    int nw = tsl_threads(threads);
    /* A pair is taken at the smaller of its two half-edges. */
    uint8_t *look = tsl_alloc_array(nh ? nh : 1, 1);
    uint32_t *work = tsl_alloc_array(nh / 2 + 1, sizeof *work);
    uint32_t *key = tsl_alloc_array(nh / 2 + 1, sizeof *key);
    uint32_t *sorted = tsl_alloc_array(nh / 2 + 1, sizeof *sorted);
    worker *ws = tsl_calloc_array((size_t)nw, sizeof *ws);
    uint32_t *start = NULL, *tail = NULL;
    size_t ntail = 0, cap_tail = 0;
    blocks b;
    blocks_init(r, &b);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!look || !work || !key || !sorted || !ws ||
        !(start = tsl_calloc_array(8 * (size_t)b.count + 1, sizeof *start)))
        goto done;
    st = TESSEL_OK;
    for (int t = 0; t < nw && !st; t++) {
        ws[t].parallel = true;
        st = tsl_trigrid_init_like(&ws[t].overlay, &r->grid);
    }
    memset(look, 1, nh);
    for (int pass = 0; pass < MAX_FLIP_PASSES && !st; pass++) {
        /* The pairs to look at, each once (at its smaller half-edge), that
         * the rule asks to flip as the mesh stands (in parallel: a pair
         * that changes later in the pass is marked for the next one), by
         * key and in half-edge order within a key (counting sort). */
        size_t nwork = 0, flips = 0;
        ntail = 0;
        ptrdiff_t count = (ptrdiff_t)nh;
#pragma omp parallel for schedule(static) num_threads(nw)
        for (ptrdiff_t h = 0; h < count; h++) {
            if (!look[h])
                continue;
            uint32_t g = r->twin[h];
            look[h] = g != NONE && g > (uint32_t)h && rule_holds(r, (uint32_t)h) ? 2 : 0;
        }
        memset(start, 0, (8 * (size_t)b.count + 1) * sizeof *start);
        for (size_t h = 0; h < nh && !st; h++) {
            if (look[h] != 2)
                continue;
            look[h] = 0;
            uint32_t k = pair_key(r, &b, (uint32_t)h);
            if (k == NONE) {
                if (!push(&tail, &ntail, &cap_tail, (uint32_t)h))
                    st = TESSEL_ERR_NOMEM;
                continue;
            }
            work[nwork] = (uint32_t)h;
            key[nwork++] = k;
            start[k + 1]++;
        }
        for (size_t k = 0; k < 8 * (size_t)b.count; k++)
            start[k + 1] += start[k];
        for (size_t k = 0; k < nwork; k++)
            sorted[start[key[k]]++] = work[k];
        /* start[k] is now the end of key k's pairs. */
        for (uint32_t colour = 0; colour < 8 && !st; colour++) {
            /* The non-empty blocks of this colour, as (key) in work[]. */
            size_t nb = 0;
            for (uint32_t k = colour * b.count; k < (colour + 1) * b.count; k++)
                if (start[k] > (k ? start[k - 1] : 0))
                    work[nb++] = k;
            count = (ptrdiff_t)nb;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nw)
            for (ptrdiff_t q = 0; q < count; q++) {
                uint32_t k = work[q];
                size_t from = k ? start[k - 1] : 0;
                worker *w = &ws[omp_get_thread_num()];
                flip_block(r, &b, w, k, sorted + from, start[k] - from);
            }
            for (int t = 0; t < nw && !st; t++) {
                st = ws[t].status;
                flips += ws[t].flips;
                r->stats.flips += ws[t].flips;
                r->stats.skipped_invalid += ws[t].invalid;
                ws[t].flips = ws[t].invalid = 0;
            }
            if (!st)
                st = merge_phase(r, ws, nw, look, &tail, &ntail, &cap_tail);
        }
        if (!st)
            st = flip_tail(r, tail, ntail, look, &flips);
        if (!flips)
            break;
    }
    r->stats.flips += r->serial->flips;
    r->stats.skipped_invalid += r->serial->invalid;
    r->serial->flips = r->serial->invalid = 0;
done:
    for (int t = 0; ws && t < nw; t++)
        worker_free(&ws[t]);
    free(ws);
    free(look);
    free(work);
    free(key);
    free(sorted);
    free(start);
    free(tail);
    return st;
}

/* ------------------------------------------------------------------------ */
/* Splits in parallel                                                        */
/* ------------------------------------------------------------------------ */

typedef struct split_job {
    uint32_t u, v;
    float pos[3];
} split_job;

/* The block of the split of the edge at h at pos (pair_key), or NONE for
 * the serial tail: a border edge, a long triangle, or a new vertex more
 * than a cell outside the pair's box. New triangles then stay within 3
 * cells of the block's pair centre, and the pairs of two blocks of a
 * colour within 3 cells of centres more than BLOCK_CELLS apart. */
static uint32_t split_key(const rf *r, const blocks *b, uint32_t h, const float pos[3])
{
    uint32_t key = pair_key(r, b, h);
    if (key == NONE)
        return NONE;
    float b1[6], b2[6];
    box_load(r, h / 3, b1);
    box_load(r, twin_load(r, h) / 3, b2);
    double cell = b->reach / LONG_CELLS;
    for (int k = 0; k < 3; k++) {
        double lo = (b1[k] < b2[k] ? b1[k] : b2[k]) - cell;
        double hi = (b1[3 + k] > b2[3 + k] ? b1[3 + k] : b2[3 + k]) + cell;
        if (!(pos[k] >= lo && pos[k] <= hi))
            return NONE;
    }
    return key;
}

/* The half-edge of {u, v} in a parallel phase: the edge map as the phase
 * began, unless a split of this block moved it. */
static uint32_t phase_edge(const rf *r, const worker *w, uint32_t u, uint32_t v)
{
    uint32_t h = w->moved.count ? map_get(&w->moved, u, v) : NONE;
    return h != NONE ? h : map_get(&r->edges, u, v);
}

static bool remember_moved(worker *w, uint32_t a, uint32_t b, uint32_t h)
{
    if (map_put(&w->moved, a, b, h) || !push(&w->moved_ab, &w->nmoved, &w->cap_moved, a) ||
        !push(&w->moved_ab, &w->nmoved, &w->cap_moved, b))
        return false;
    return true;
}

/* One block of a parallel phase: the splits jobs[list[0 .. n)] of key
 * `key`, in order, each checked against the mesh as the earlier ones of
 * the block left it (with the worker's own ids for the new vertices and
 * triangles, and its overlay grid). The splits kept go into the log; then
 * all are taken back, newest first, and the merge makes them again with
 * the mesh's next ids. Splits whose pair changed block go to the tail. */
static void split_block(rf *r, const blocks *b, worker *w, uint32_t key, const split_job *jobs,
                        const uint32_t *list, size_t n, double min_ratio)
{
    tsl_trigrid_clear(&w->overlay);
    uint32_t next_v = w->base_v, next_t = w->base_t;
    for (size_t k = 0; k < n && !w->status; k++) {
        const split_job *jb = &jobs[list[k]];
        uint32_t h = phase_edge(r, w, jb->u, jb->v);
        if (h == NONE)
            continue;
        if (split_key(r, b, h, jb->pos) != key) {
            if (!push(&w->tail, &w->ntail, &w->cap_tail, list[k]))
                w->status = TESSEL_ERR_NOMEM;
            continue;
        }
        if (split_skinny(r, h, twin_load(r, h), min_ratio)) {
            w->skinny++;
            continue;
        }
        if (w->nundo == w->cap_undo &&
            tsl_grow((void **)&w->undo, &w->cap_undo, w->nundo + 1, sizeof *w->undo)) {
            w->status = TESSEL_ERR_NOMEM;
            break;
        }
        split_info *s = &w->undo[w->nundo];
        split_apply(r, h, jb->pos, next_v, next_t, next_t + 1, s);
        bool ok;
        if ((w->status = check_news(r, w, s->news, s->count, (const double(*)[3])s->olds, &ok)))
            break;
        if (!ok) {
            split_undo(r, s);
            w->invalid++;
            continue;
        }
        next_v++;
        next_t += 2;
        w->nundo++;
        /* y-a and x-b moved to T3 and T4; the other edges are new or
         * stayed where they were. */
        if (!push(&w->log, &w->nlog, &w->cap_log, list[k]) ||
            !remember_moved(w, s->y, s->a, 3 * s->T3 + 1) ||
            !remember_moved(w, s->x, s->b, 3 * s->T4 + 1)) {
            w->status = TESSEL_ERR_NOMEM;
            break;
        }
        if ((w->status = split_grid(r, w, s)))
            break;
    }
    while (w->nundo)
        split_undo(r, &w->undo[--w->nundo]);
    for (size_t k = 0; k < w->nmoved; k += 2)
        map_del(&w->moved, w->moved_ab[k], w->moved_ab[k + 1]);
    w->nmoved = 0;
    if (!w->status && (!push(&w->seg, &w->nseg, &w->cap_seg, key) ||
                       !push(&w->seg, &w->nseg, &w->cap_seg, (uint32_t)w->nlog)))
        w->status = TESSEL_ERR_NOMEM;
}

/* A split the phase kept, made again in the mesh with its next ids. */
static tessel_status split_again(rf *r, const split_job *jb)
{
    uint32_t h = map_get(&r->edges, jb->u, jb->v);
    if (h == NONE || r->twin[h] == NONE)
        return TESSEL_ERR_INTERNAL;
    uint32_t m = (uint32_t)r->nv++, T3 = (uint32_t)r->nt++, T4 = (uint32_t)r->nt++;
    split_info s;
    split_apply(r, h, jb->pos, m, T3, T4, &s);
    tessel_status st = split_map(r, &s);
    if (!st)
        st = split_grid(r, r->serial, &s);
    r->stats.splits++;
    return st;
}

/* After a phase: the splits kept by every block, in key order, made again
 * in the mesh; the tails gathered. */
static tessel_status split_merge(rf *r, worker *ws, int nw, const split_job *jobs,
                                 uint32_t **tail, size_t *ntail, size_t *cap_tail)
{
    size_t m;
    seg_ref *order = blocks_done(ws, nw, &m);
    if (!order)
        return TESSEL_ERR_NOMEM;
    tessel_status st = TESSEL_OK;
    for (size_t k = 0; k < m && !st; k++) {
        const worker *w = &ws[order[k].worker];
        size_t s = order[k].index;
        size_t from = s ? w->seg[2 * s - 1] : 0, to = w->seg[2 * s + 1];
        for (size_t f = from; f < to && !st; f++)
            st = split_again(r, &jobs[w->log[f]]);
    }
    free(order);
    return st ? st : gather_tails(ws, nw, tail, ntail, cap_tail);
}

/* The splits of jobs[want[0 .. n)] (want in Morton order), in parallel
 * and deterministically, as the flips (flip_passes): each split goes to
 * the block of its pair (split_key); the eight colours take turns, the
 * blocks of a colour are split in parallel, each in order by one thread,
 * and a merge makes their splits in the mesh in key order; splits with a
 * long triangle, on the border, reaching outside their pair or whose pair
 * changed block are made serially after the colours, in order. The
 * result depends on the mesh only, not on the thread count; it is not
 * that of one serial pass in Morton order (a split may see a neighbour's
 * split that the serial pass made later, or not see one it made
 * earlier). */
static tessel_status split_passes(rf *r, const split_job *jobs, const uint32_t *want, size_t n,
                                  double min_ratio, int threads)
{
    int nw = tsl_threads(threads);
    blocks b;
    blocks_init(r, &b);
    uint32_t *key = tsl_alloc_array(n + 1, sizeof *key);
    uint32_t *sorted = tsl_alloc_array(n + 1, sizeof *sorted);
    uint32_t *start = tsl_calloc_array(8 * (size_t)b.count + 1, sizeof *start);
    uint32_t *blist = tsl_alloc_array(8 * (size_t)b.count + 1, sizeof *blist);
    worker *ws = tsl_calloc_array((size_t)nw, sizeof *ws);
    uint32_t *tail = NULL;
    size_t ntail = 0, cap_tail = 0, most = 0, nsorted = 0;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!key || !sorted || !start || !blist || !ws)
        goto done;
    st = TESSEL_OK;
    for (size_t k = 0; k < n && !st; k++) {
        const split_job *jb = &jobs[want[k]];
        uint32_t h = map_get(&r->edges, jb->u, jb->v);
        key[k] = h == NONE ? NONE : split_key(r, &b, h, jb->pos);
        if (key[k] == NONE) {
            if (!push(&tail, &ntail, &cap_tail, want[k]))
                st = TESSEL_ERR_NOMEM;
            continue;
        }
        start[key[k] + 1]++;
    }
    for (size_t k = 0; k < 8 * (size_t)b.count; k++) {
        most = start[k + 1] > most ? start[k + 1] : most;
        start[k + 1] += start[k];
    }
    for (size_t k = 0; k < n; k++)
        if (key[k] != NONE) {
            sorted[start[key[k]]++] = want[k];
            nsorted++;
        }
    /* start[k] is now the end of key k's splits. Room for the merges' ids
     * (below nv + n and nt + 2 n) and, beyond, each worker's own. */
    size_t nv0 = r->nv, nt0 = r->nt;
    if (!st)
        st = reserve(r, n + (size_t)nw * most, 2 * n + 2 * (size_t)nw * most);
    for (int t = 0; t < nw && !st; t++) {
        ws[t].parallel = true;
        ws[t].base_v = (uint32_t)(nv0 + n + (size_t)t * most);
        ws[t].base_t = (uint32_t)(nt0 + 2 * n + 2 * (size_t)t * most);
        ws[t].id_end = nt0 + 2 * n + 2 * (size_t)nw * most;
        if (!(st = tsl_trigrid_init_like(&ws[t].overlay, &r->grid)))
            st = map_init(&ws[t].moved, 64);
    }
    for (uint32_t colour = 0; colour < 8 && !st && nsorted; colour++) {
        size_t nb = 0;
        for (uint32_t k = colour * b.count; k < (colour + 1) * b.count; k++)
            if (start[k] > (k ? start[k - 1] : 0))
                blist[nb++] = k;
        ptrdiff_t count = (ptrdiff_t)nb;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nw)
        for (ptrdiff_t q = 0; q < count; q++) {
            uint32_t k = blist[q];
            size_t from = k ? start[k - 1] : 0;
            worker *w = &ws[omp_get_thread_num()];
            split_block(r, &b, w, k, jobs, sorted + from, start[k] - from, min_ratio);
        }
        for (int t = 0; t < nw && !st; t++) {
            st = ws[t].status;
            r->stats.skipped_skinny += ws[t].skinny;
            r->stats.skipped_invalid += ws[t].invalid;
            ws[t].skinny = ws[t].invalid = 0;
        }
        if (!st)
            st = split_merge(r, ws, nw, jobs, &tail, &ntail, &cap_tail);
    }
    /* The tail in the jobs' order. */
    if (!st && ntail)
        qsort(tail, ntail, sizeof *tail, tsl_cmp_u32);
    for (size_t k = 0; k < ntail && !st; k++) {
        bool done_split;
        const split_job *jb = &jobs[tail[k]];
        st = split_edge(r, jb->u, jb->v, jb->pos, min_ratio, &done_split);
    }
done:
    for (int t = 0; ws && t < nw; t++)
        worker_free(&ws[t]);
    free(ws);
    free(key);
    free(sorted);
    free(start);
    free(blist);
    free(tail);
    return st;
}

/* ------------------------------------------------------------------------ */
/* Rounds                                                                    */
/* ------------------------------------------------------------------------ */

/* Area-weighted vertex normals (unnormalised sums, then unit). */
static tessel_status vertex_normals(const rf *r, double **out)
{
    double *n = tsl_calloc_array(3 * r->nv, sizeof *n);
    if (!n)
        return TESSEL_ERR_NOMEM;
    for (size_t t = 0; t < r->nt; t++) {
        double c[3];
        tri_cross(r, (uint32_t)t, c);
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
static double cells_covered(const rf *r, const double origin[3], double cell, double limit)
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
static double grid_cell(const rf *r, const double origin[3], double cell, double *entries)
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
static tessel_status build_grid(rf *r)
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
        vtx(r, r->tri[3 * t], a);
        vtx(r, r->tri[3 * t + 1], c);
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
        st = grid_list(r, (uint32_t)t);
    return st;
}

typedef struct round_ctx {
    const tessel_index *index;
    const tessel_cloud *cloud;
    const tessel_projector *projector;
    double h, eps, min_len;
    uint32_t k;
    int threads;
} round_ctx;

/* How many edges ahead the fits ask for the previous round's fit: the
 * lookups land anywhere in a map of megabytes. */
#define FIT_AHEAD 8

/* Bits per axis of the cells that order the edges' neighbour searches. */
#define ORDER_BITS 6

/* Spreads the low ORDER_BITS bits of x three apart (Morton code). */
static uint32_t spread3(uint32_t x)
{
    uint32_t y = 0;
    for (int b = 0; b < ORDER_BITS; b++)
        y |= ((x >> b) & 1u) << (3 * b);
    return y;
}

/* The jobs' indices in Morton order of their midpoints' cells (a counting
 * sort over 2^(3 ORDER_BITS) cells of the mesh's box), so that consecutive
 * neighbour searches walk the same part of the kd-tree: on 10^6 points the
 * tree does not fit in cache and searches in edge order spend most of
 * their time waiting for memory. The splits follow the same order. */
static tessel_status spatial_order(const rf *r, const split_job *jobs, size_t ne,
                                   uint32_t **out)
{
    const size_t cells = (size_t)1 << (3 * ORDER_BITS);
    uint32_t *order = tsl_alloc_array(ne ? ne : 1, sizeof *order);
    uint32_t *key = tsl_alloc_array(ne ? ne : 1, sizeof *key);
    size_t *start = tsl_calloc_array(cells + 1, sizeof *start);
    if (!order || !key || !start) {
        free(order);
        free(key);
        free(start);
        return TESSEL_ERR_NOMEM;
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < r->nv; v++)
        for (int k = 0; k < 3; k++) {
            float x = r->xyz[3 * v + k];
            lo[k] = x < lo[k] ? x : lo[k];
            hi[k] = x > hi[k] ? x : hi[k];
        }
    double scale[3];
    for (int k = 0; k < 3; k++)
        scale[k] = hi[k] > lo[k] ? (double)((1 << ORDER_BITS) - 1) / ((double)hi[k] - lo[k]) : 0.0;
    for (size_t e = 0; e < ne; e++) {
        const float *a = r->xyz + 3 * (size_t)jobs[e].u, *b = r->xyz + 3 * (size_t)jobs[e].v;
        uint32_t m = 0;
        for (int k = 0; k < 3; k++) {
            double x = 0.5 * ((double)a[k] + b[k]) - lo[k];
            m |= spread3((uint32_t)(x * scale[k] + 0.5)) << k;
        }
        key[e] = m;
        start[m + 1]++;
    }
    for (size_t i = 0; i < cells; i++)
        start[i + 1] += start[i];
    for (size_t e = 0; e < ne; e++)
        order[start[key[e]]++] = (uint32_t)e;
    free(key);
    free(start);
    *out = order;
    return TESSEL_OK;
}

static tessel_status one_round(rf *r, const round_ctx *c, const tessel_refine_params *p,
                               bool keep_fits)
{
    /* Candidate edges: each undirected edge once (its half-edge with the
     * smaller id, or its only one). */
    size_t nh = 3 * r->nt, ne = 0;
    split_job *jobs = tsl_alloc_array(nh, sizeof *jobs);
    uint8_t *want = NULL, *fitted = NULL;
    float *sum = NULL;
    uint32_t *order = NULL;
    double *vn = NULL;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!jobs)
        goto done;
    for (size_t hh = 0; hh < nh; hh++) {
        uint32_t g = r->twin[hh];
        if (g != NONE && g < hh)
            continue;
        jobs[ne].u = he_from(r, (uint32_t)hh);
        jobs[ne].v = he_to(r, (uint32_t)hh);
        ne++;
    }
    want = tsl_calloc_array(ne ? ne : 1, 1);
    fitted = tsl_calloc_array(ne ? ne : 1, 1);
    sum = tsl_alloc_array(3 * (ne ? ne : 1), sizeof *sum);
    if (!want || !fitted || !sum || (st = vertex_normals(r, &vn)) ||
        (st = spatial_order(r, jobs, ne, &order)))
        goto done;
    size_t far = 0, unfit = 0;
    long long count = (long long)ne;
#pragma omp parallel for schedule(dynamic, 256) num_threads(tsl_threads(c->threads)) \
    reduction(+ : far, unfit)
    for (long long oo = 0; oo < count; oo++) {
        size_t ii = order[oo];
        split_job *jb = &jobs[ii];
        double pu[3], pv[3], d[3], m[3], nm[3];
        vtx(r, jb->u, pu);
        vtx(r, jb->v, pv);
        tsl_sub(pv, pu, d);
        double len = tsl_norm(d);
        if (!(len >= c->min_len))
            continue;
        for (int k = 0; k < 3; k++) {
            m[k] = 0.5 * (pu[k] + pv[k]);
            nm[k] = vn[3 * (size_t)jb->u + k] + vn[3 * (size_t)jb->v + k];
        }
        if (!tsl_normalize(nm))
            continue;
        float *ws = sum + 3 * ii;
        if (r->fit_sum && oo + FIT_AHEAD < count) {
            const split_job *ahead = &jobs[order[oo + FIT_AHEAD]];
            map_prefetch(&r->fit_of, ahead->u, ahead->v);
        }
        uint32_t known = r->fit_sum ? map_get(&r->fit_of, jb->u, jb->v) : NONE;
        if (known != NONE) {
            memcpy(ws, r->fit_sum + 3 * (size_t)known, 3 * sizeof *ws);
        } else {
            uint32_t idx[MAX_K];
            float q[3] = {(float)m[0], (float)m[1], (float)m[2]};
            size_t got = tessel_index_knn(c->index, q, c->k, idx, NULL);
            if (got != c->k)
                continue;
            double w[3] = {0.0, 0.0, 0.0};
            for (size_t s = 0; s < got; s++)
                for (int k = 0; k < 3; k++)
                    w[k] += (double)c->cloud->xyz[3 * (size_t)idx[s] + k] - m[k];
            for (int k = 0; k < 3; k++)
                ws[k] = (float)w[k];
        }
        fitted[ii] = 1;
        double a = (ws[0] * nm[0] + ws[1] * nm[1] + ws[2] * nm[2]) / (double)c->k;
        if (!(fabs(a) > c->eps))
            continue;
        far++;
        float target[3] = {(float)(m[0] + a * nm[0]), (float)(m[1] + a * nm[1]),
                           (float)(m[2] + a * nm[2])};
        if (tessel_project(c->projector, target, jb->pos, NULL, NULL) != TESSEL_OK) {
            unfit++;
            continue;
        }
        want[ii] = 1;
    }
    r->stats.far_edges += far;
    r->stats.unfit += unfit;
    /* Keep this round's fits for the next round (the edges of the mesh
     * before any split or flip; most of them survive). */
    map_free(&r->fit_of);
    free(r->fit_sum);
    r->fit_sum = NULL;
    if (keep_fits) {
        size_t nf = 0;
        for (size_t e = 0; e < ne; e++)
            nf += fitted[e];
        if ((st = map_init(&r->fit_of, nf)))
            goto done;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(c->threads))
        for (long long e = 0; e < count; e++)
            if (fitted[e])
                map_put_shared(&r->fit_of, jobs[e].u, jobs[e].v, (uint32_t)e);
        r->fit_of.count = nf;
        r->fit_sum = sum;
        sum = NULL;
    }
    /* Each edge once, in the Morton order of the fits (a split reads and
     * writes the mesh, its edge map and its grid around the edge, so
     * neighbouring splits in a row find them in cache), in parallel. */
    size_t nw = 0;
    for (size_t oo = 0; oo < ne; oo++)
        if (want[order[oo]])
            order[nw++] = order[oo];
    st = split_passes(r, jobs, order, nw, p->min_edge_ratio, c->threads);
    if (st)
        goto done;
    if (p->flip)
        st = flip_passes(r, c->threads);
done:
    free(jobs);
    free(want);
    free(fitted);
    free(sum);
    free(order);
    free(vn);
    return st;
}

static tessel_status check_params(const tessel_refine_params *p)
{
    if (p->rounds > 20 || p->k < 1 || p->k > MAX_K || !(p->min_offset >= 0.0) ||
        !isfinite(p->min_offset) || !(p->min_edge_length >= 0.0) ||
        !isfinite(p->min_edge_length) || !(p->min_edge_ratio >= 0.0 && p->min_edge_ratio <= 1.0))
        return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

tessel_status tessel_refine(tessel_mesh *mesh, const tessel_cloud *cloud,
                            const tessel_projector *projector,
                            const tessel_refine_params *params,
                            const tessel_callbacks *callbacks, tessel_refine_stats *stats)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!mesh || !cloud || (mesh->vertex_count && !mesh->xyz) ||
        (mesh->triangle_count && !mesh->triangles) || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_refine_params p = params ? *params : tessel_refine_params_default();
    tessel_status st = check_params(&p);
    if (st)
        return st;
    for (int c = 0; c < 3; c++)
        if (mesh->offset[c] != cloud->offset[c])
            return TESSEL_ERR_INVALID_ARG;
    if (mesh->vertex_count >= UINT32_MAX / 2 || mesh->triangle_count >= UINT32_MAX / 8)
        return TESSEL_ERR_LIMIT;
    if (p.rounds == 0 || mesh->triangle_count == 0)
        return TESSEL_OK;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;

    rf r;
    memset(&r, 0, sizeof r);
    worker serial;
    memset(&serial, 0, sizeof serial);
    r.serial = &serial;
    tessel_projector *own = NULL;
    tessel_index *own_index = NULL;
    r.nv = mesh->vertex_count;
    r.nt = mesh->triangle_count;
    r.cap_v = r.nv + 16;
    r.cap_t = r.nt + 16;
    r.cos_turn = cos(MAX_TURN_DEG * acos(-1.0) / 180.0);
    r.xyz = r.xyz_own = tsl_alloc_array(3 * r.cap_v, sizeof *r.xyz_own);
    r.rgb = mesh->rgb ? tsl_alloc_array(3 * r.cap_v, 1) : NULL;
    r.tri = tsl_alloc_array(3 * r.cap_t, sizeof *r.tri);
    r.twin = tsl_alloc_array(3 * r.cap_t, sizeof *r.twin);
    r.box = tsl_alloc_array(6 * r.cap_t, sizeof *r.box);
    st = TESSEL_ERR_NOMEM;
    if (!r.xyz_own || !r.tri || !r.twin || !r.box || (mesh->rgb && !r.rgb))
        goto done;
    memcpy(r.xyz_own, mesh->xyz, 3 * r.nv * sizeof *r.xyz_own);
    if (r.rgb)
        memcpy(r.rgb, mesh->rgb, 3 * r.nv);
    memcpy(r.tri, mesh->triangles, 3 * r.nt * sizeof *r.tri);
    if ((st = build_topology(&r, p.threads)))
        goto done;
    if (!projector) {
        if ((st = tessel_projector_create(&own, cloud, NULL)))
            goto done;
        projector = own;
    }
    /* The projector's kd-tree when it is over this cloud, else our own. */
    const tessel_index *index = tsl_projector_index(projector, cloud->xyz, cloud->count);
    if (!index) {
        if ((st = tessel_index_build(&own_index, cloud->xyz, cloud->count)))
            goto done;
        index = own_index;
    }
    round_ctx c;
    c.index = index;
    c.cloud = cloud;
    c.projector = projector;
    c.h = tessel_projector_spacing(projector);
    c.eps = p.min_offset * c.h;
    c.min_len = p.min_edge_length * c.h;
    c.k = p.k < cloud->count ? p.k : (uint32_t)cloud->count;
    c.threads = p.threads;
    for (uint32_t round = 0; round < p.rounds; round++) {
        if ((st = tsl_progress(callbacks, "refine", (double)round / p.rounds)))
            goto done;
        if ((st = build_grid(&r)) || (st = one_round(&r, &c, &p, round + 1 < p.rounds)))
            goto done;
    }
    for (size_t h = 0; h < 3 * r.nt; h++)
        r.stats.border_edges += r.twin[h] == NONE;
    /* Commit into the caller's mesh. */
    {
        tessel_mesh out;
        if ((st = tessel_mesh_alloc(&out, r.nv, r.nt, mesh->normals != NULL, r.rgb != NULL)))
            goto done;
        memcpy(out.xyz, r.xyz, 3 * r.nv * sizeof *out.xyz);
        memcpy(out.triangles, r.tri, 3 * r.nt * sizeof *out.triangles);
        if (r.rgb)
            memcpy(out.rgb, r.rgb, 3 * r.nv);
        if (out.normals) {
            double *vn;
            if ((st = vertex_normals(&r, &vn))) {
                tessel_mesh_free(&out);
                goto done;
            }
            for (size_t v = 0; v < 3 * r.nv; v++)
                out.normals[v] = (float)vn[v];
            free(vn);
        }
        for (int k = 0; k < 3; k++)
            out.offset[k] = mesh->offset[k];
        tessel_mesh_free(mesh);
        *mesh = out;
    }
    st = tsl_progress(callbacks, "refine", 1.0);
done:
    if (stats)
        *stats = r.stats;
    tessel_index_destroy(own_index);
    tessel_projector_destroy(own);
    free(r.xyz_own);
    free(r.rgb);
    free(r.tri);
    free(r.twin);
    free(r.box);
    map_free(&r.edges);
    map_free(&r.fit_of);
    free(r.fit_sum);
    tsl_trigrid_free(&r.grid);
    free(r.pinched);
    worker_free(&serial);
    return st;
}

/* Numbers the vertices tri uses 0, 1, ... in order of first use: tri is
 * rewritten, (*local)[3 i ..] receives the position of the vertex now
 * numbered i, (*back)[i] its old number; *used of them. */
static tessel_status renumber(const float *xyz, size_t nv, uint32_t *tri, size_t nt,
                              uint32_t **back, float **local, size_t *used)
{
    *back = NULL;
    *local = NULL;
    for (size_t i = 0; i < 3 * nt; i++)
        if (tri[i] >= nv)
            return TESSEL_ERR_INVALID_ARG;
    uint32_t *fwd = tsl_alloc_array(nv ? nv : 1, sizeof *fwd);
    *back = tsl_alloc_array(nv ? nv : 1, sizeof **back);
    *local = tsl_alloc_array(3 * (nv ? nv : 1), sizeof **local);
    if (!fwd || !*back || !*local) {
        free(fwd);
        free(*back);
        free(*local);
        *back = NULL;
        *local = NULL;
        return TESSEL_ERR_NOMEM;
    }
    for (size_t v = 0; v < nv; v++)
        fwd[v] = NONE;
    uint32_t n = 0;
    for (size_t i = 0; i < 3 * nt; i++) {
        uint32_t v = tri[i];
        if (fwd[v] == NONE) {
            fwd[v] = n;
            (*back)[n] = v;
            memcpy(*local + 3 * (size_t)n, xyz + 3 * (size_t)v, 3 * sizeof **local);
            n++;
        }
        tri[i] = fwd[v];
    }
    free(fwd);
    *used = n;
    return TESSEL_OK;
}

tessel_status tsl_flip_diagonals(const float *xyz, size_t nv, uint32_t *tri, size_t nt,
                                 int threads, size_t *flips)
{
    *flips = 0;
    if (nv >= UINT32_MAX || nt >= UINT32_MAX / 3)
        return TESSEL_ERR_LIMIT;
    if (nt == 0)
        return TESSEL_OK;
    /* The used vertices in order of first use, in a copy: the triangles
     * come in the order the front made them, close together, while the
     * points may come in any order (on a Fibonacci sphere each point's
     * neighbours are far away in the file). Flipping reads the vertices of
     * every triangle around each pair; this made the twins and the grid
     * 0.55 -> 0.37 s on 2,000,000 triangles. Flips keep the vertices, and
     * the ids go back at the end. */
    uint32_t *back = NULL;
    float *local = NULL;
    size_t used;
    tessel_status st = renumber(xyz, nv, tri, nt, &back, &local, &used);
    if (st)
        return st;
    rf r;
    memset(&r, 0, sizeof r);
    worker serial;
    memset(&serial, 0, sizeof serial);
    r.serial = &serial;
    r.xyz = local;
    r.nv = used;
    r.tri = tri;
    r.nt = r.cap_t = nt;
    r.cos_turn = cos(MAX_TURN_DEG * acos(-1.0) / 180.0);
    r.delaunay = true;
    r.twin = tsl_alloc_array(3 * nt, sizeof *r.twin);
    r.box = tsl_alloc_array(6 * nt, sizeof *r.box);
    st = TESSEL_ERR_NOMEM;
    if (r.twin && r.box && !(st = build_twins(&r, 0, NULL)) && !(st = build_grid(&r)))
        st = flip_passes(&r, threads);
    for (size_t i = 0; i < 3 * nt; i++)
        tri[i] = back[tri[i]];
    free(back);
    free(local);
    *flips = r.stats.flips;
    free(r.twin);
    free(r.box);
    map_free(&r.edges);
    tsl_trigrid_free(&r.grid);
    free(r.pinched);
    worker_free(&serial);
    return st;
}
