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
 * edge (exact orient2d/orient3d). Triangles are held while a live point is
 * near enough for a later triangle to reach them and streamed out after.
 * See docs/greedy.md. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- point states (section 4: free, fringe, boundary, completed) ---- */
enum {
    ST_FREE = 0,     /* no triangle */
    ST_FRINGE = 1,   /* has triangles, not yet a reference point */
    ST_BOUNDARY = 2, /* was a reference point, fan still open */
    ST_DONE = 3,     /* fan closed: completed */
    ST_DEAD = 4,     /* left out (duplicate, isolated, ...) */
    ST_MASK = 7,
    ST_QUEUED = 8,   /* in the breadth-first queue */
    ST_VISITS = 16   /* bits 4-5: times processed as a reference point */
};

#define NONE TESSEL_NONE
/* Boundary points are looked at again when a neighbour changes their fan,
 * at most this many times in all. */
#define MAX_VISITS 3
/* Triangles per batch sent to the sink. */
#define OUT_BATCH 8192

typedef struct gp_tri {
    uint32_t v[3];    /* counter-clockwise seen from outside */
    uint32_t next[3]; /* next held triangle in the list of v[k]; next[0] is
                         the free-list link of an unused slot */
} gp_tri;

enum { TF_ALIVE = 1, TF_LONG = 2, TF_EXISTING = 4 };

/* A point of the box around R. */
typedef struct gp_box {
    uint32_t idx;
    float dinf;      /* L-infinity distance to R */
    double rel[3];   /* position relative to R */
} gp_box;

/* A candidate neighbour of R in R's projection frame. */
typedef struct gp_cand {
    uint32_t idx;
    uint8_t kept;    /* survives the pruning */
    double x, y;     /* projection on R's plane (R at the origin) */
    double key;      /* pseudo-angle, [0, 4), from the start of the sector */
    double d2;       /* squared 3D distance to R */
    double rel[3];
} gp_cand;

/* Cached box of a held triangle near R (for the guard). */
typedef struct gp_gtri {
    uint32_t t;
    float lo[3], hi[3];
} gp_gtri;

/* R's free sector in its projection: new triangles lie in the cone from
 * e's direction counter-clockwise to s's, the mesh around R in the rest.
 * The projection is linear, so triangles whose images are disjoint (or meet
 * only in the images of shared vertices and edges) do not meet in space:
 * held triangles that provably stay out of the cone need no exact test. */
typedef struct gp_cone {
    int on;           /* 0: no certificate (a seed: every triangle is tested) */
    int convex;       /* the free sector is under 180 degrees */
    uint32_t R, e, s;
    double e2[2], s2[2], bis[2];
    double eu[2], su[2];  /* unit directions of e2, s2 */
    double eps;       /* margin for the rounding of projections */
} gp_cone;

/* Projections of points on the current reference point's plane, cached by
 * point index (direct-mapped; valid while stamp matches). */
#define PCACHE 1024
typedef struct gp_pcache {
    uint32_t idx, stamp;
    double x, y;
    unsigned flags;       /* CONE_* tests the point passes */
} gp_pcache;

typedef struct gp {
    /* input and parameters */
    const tessel_cloud *cloud;
    size_t n;
    double mu, cos_alpha, beta, max_spacing;
    int plane_axis;
    const tessel_callbacks *cb;
    const tessel_triangle_sink *sink;

    /* points in dexel order */
    float *xyz;
    uint32_t *orig;       /* dexel order -> input index */
    uint8_t *state;
    uint32_t *head;       /* first held triangle at the point */
    uint32_t *ls, *le;    /* ends of the point's fan: its link path runs
                             ls -> ... -> le counter-clockwise */
    uint32_t *label;      /* component label (union-find), NONE if unused */
    float *maxe;          /* longest edge ever at the point (0: none) */

    /* dexel array: columns over axes au, av; depth along ad */
    int ad, au, av;
    double glo[3];
    double cell, inv_cell;
    uint32_t nu, nv;
    uint32_t *col;        /* nu*nv+1 column starts */

    /* lengths (world units) */
    double spacing;       /* mean nearest-neighbour distance */
    double m_cap;         /* cap on m */
    double m_floor;       /* floor on m (near-duplicates) */
    double ell;           /* long-triangle threshold (max edge) */
    double delta;         /* guard margin: ell / sqrt(3) */

    /* retirement blocks */
    double inv_block;
    uint32_t bn[3];
    uint32_t *blive;      /* live points in the block */
    uint8_t *bdead;       /* dead blocks among the 27 around it */

    /* triangle pool */
    gp_tri *tri;
    uint32_t *tstamp;
    uint8_t *tflag;
    size_t tcap, tused, talive;
    uint32_t tfree;
    size_t created_since_sweep, alive_after_sweep;
    /* long triangles: hashed grid of cell edge 1 / lg_inv, every triangle
     * listed in the cells its box overlaps */
    double lg_inv;
    uint64_t *lg_keys;    /* cell key + 1, 0 = empty slot */
    uint32_t *lg_head;    /* first entry of the cell */
    size_t lg_slots, lg_used;
    uint32_t *lt_tri, *lt_next; /* entries */
    size_t lt_cap, lt_used;
    uint32_t lt_free;

    /* breadth-first queue (ring) and seeds */
    uint32_t *queue;
    size_t qhead, qcount;
    uint32_t *seed_order; /* dexel indices by increasing depth */
    size_t seed_cursor;

    /* components: union-find over labels */
    uint32_t *uf;
    size_t uf_count, uf_cap;

    /* output batch */
    uint32_t *out;
    size_t out_count;

    /* per-reference scratch */
    gp_box *box;
    size_t box_count, box_cap;
    gp_cand *cand;
    size_t cand_count, cand_cap;
    uint32_t *seq;
    size_t seq_count, seq_cap;
    gp_gtri *gt;
    size_t gt_count, gt_cap;
    uint32_t stamp;
    gp_cone cone;         /* of the current reference point */
    gp_pcache *pc;        /* PCACHE entries */

    tessel_recon_summary sum;
    size_t processed;
    long boundary_edges;
} gp;

/* ------------------------------------------------------------------------ */
/* Small helpers                                                             */
/* ------------------------------------------------------------------------ */

static inline int sgn(double x) { return (x > 0.0) - (x < 0.0); }

static inline void pos(const gp *g, uint32_t i, double out[3])
{
    const float *p = g->xyz + 3 * (size_t)i;
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[2];
}

static inline int st(const gp *g, uint32_t i) { return g->state[i] & ST_MASK; }
static inline int is_live(const gp *g, uint32_t i)
{
    int s = st(g, i);
    return s == ST_FREE || s == ST_FRINGE || s == ST_BOUNDARY;
}

/* Pseudo-angle of (x, y) in [0, 4): monotone in atan2 taken in [0, 2pi)
 * (the paper's quadrant + sin^2 ordering does the same job). */
static inline double pseudo_angle(double x, double y)
{
    double p = fabs(y) / (fabs(x) + fabs(y));
    if (x >= 0.0)
        return y >= 0.0 ? p : 4.0 - p;
    return y >= 0.0 ? 2.0 - p : 2.0 + p;
}

static inline double wrap4(double k) { return k < 0.0 ? k + 4.0 : (k >= 4.0 ? k - 4.0 : k); }

static tessel_status grow(void **p, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return TESSEL_OK;
    return tsl_grow(p, cap, need, size);
}

/* ------------------------------------------------------------------------ */
/* Exact triangle tests (same semantics as the mesh check, src/check.c)      */
/* ------------------------------------------------------------------------ */

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
static int collinear3(const double a[3], const double b[3], const double c[3])
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

/* ------------------------------------------------------------------------ */
/* Bucketing: the dexel array (section 3)                                    */
/* ------------------------------------------------------------------------ */

typedef struct gp_sortrec {
    float d, a, b;
    uint32_t i;
} gp_sortrec;

static int cmp_sortrec(const void *pa, const void *pb)
{
    const gp_sortrec *x = pa, *y = pb;
    if (x->d != y->d)
        return x->d < y->d ? -1 : 1;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    if (x->b != y->b)
        return x->b < y->b ? -1 : 1;
    return x->i < y->i ? -1 : (x->i > y->i);
}

static inline uint32_t grid_coord(double x, double lo, double inv, uint32_t count)
{
    double c = (x - lo) * inv;
    if (!(c > 0.0))
        return 0;
    if (c >= (double)(count - 1))
        return count - 1;
    return (uint32_t)c;
}

/* Sorts the cloud into columns of edge `cell` over the two axes other than
 * the depth axis (dexel order) and fills xyz and orig. Within a column points
 * go by depth, then the other coordinates, then input index, so exact
 * duplicates end up adjacent and the order is deterministic. */
static tessel_status build_dexels(gp *g, const double ext[3], double cell)
{
    const float *src = g->cloud->xyz;
    size_t n = g->n;
    /* Bound the column array: at most 4 columns per point (plus a floor). */
    size_t max_cols = 4 * n + 4096;
    for (;;) {
        double cu = ext[g->au] / cell + 1.0, cv = ext[g->av] / cell + 1.0;
        if (cu * cv <= (double)max_cols && cu < 4e9 && cv < 4e9)
            break;
        cell *= 1.5;
    }
    g->cell = cell;
    g->inv_cell = 1.0 / cell;
    g->nu = (uint32_t)(ext[g->au] / cell) + 1;
    g->nv = (uint32_t)(ext[g->av] / cell) + 1;
    size_t ncols = (size_t)g->nu * g->nv;
    free(g->col);
    g->col = tsl_calloc_array(ncols + 1, sizeof *g->col);
    uint32_t *ord = tsl_alloc_array(n ? n : 1, sizeof *ord);
    if (!g->col || !ord) {
        free(ord);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        const float *p = src + 3 * i;
        uint32_t iu = grid_coord(p[g->au], g->glo[g->au], g->inv_cell, g->nu);
        uint32_t iv = grid_coord(p[g->av], g->glo[g->av], g->inv_cell, g->nv);
        g->col[(size_t)iv * g->nu + iu + 1]++;
    }
    for (size_t c = 0; c < ncols; c++)
        g->col[c + 1] += g->col[c];
    size_t maxcol = 0;
    for (size_t c = 0; c < ncols; c++)
        if (g->col[c + 1] - g->col[c] > maxcol)
            maxcol = g->col[c + 1] - g->col[c];
    /* Place (stable: input order inside a column), using col[c] as cursor
     * and shifting back afterwards. */
    for (size_t i = 0; i < n; i++) {
        const float *p = src + 3 * i;
        uint32_t iu = grid_coord(p[g->au], g->glo[g->au], g->inv_cell, g->nu);
        uint32_t iv = grid_coord(p[g->av], g->glo[g->av], g->inv_cell, g->nv);
        ord[g->col[(size_t)iv * g->nu + iu]++] = (uint32_t)i;
    }
    for (size_t c = ncols; c > 0; c--)
        g->col[c] = g->col[c - 1];
    g->col[0] = 0;
    gp_sortrec *rec = tsl_alloc_array(maxcol ? maxcol : 1, sizeof *rec);
    if (!rec) {
        free(ord);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t c = 0; c < ncols; c++) {
        size_t s = g->col[c], e = g->col[c + 1];
        for (size_t k = s; k < e; k++) {
            const float *p = src + 3 * (size_t)ord[k];
            rec[k - s].d = p[g->ad];
            rec[k - s].a = p[g->au];
            rec[k - s].b = p[g->av];
            rec[k - s].i = ord[k];
        }
        if (e - s > 1)
            qsort(rec, e - s, sizeof *rec, cmp_sortrec);
        for (size_t k = s; k < e; k++) {
            uint32_t i = rec[k - s].i;
            g->orig[k] = i;
            memcpy(g->xyz + 3 * k, src + 3 * (size_t)i, 3 * sizeof(float));
        }
    }
    free(rec);
    free(ord);
    return TESSEL_OK;
}

/* Collects into g->box every point other than R that is not dead and lies
 * in the axis-aligned box of half-size `half` around R (section 4.1, first
 * stage of the distance criterion). Completed points whose triangles have
 * all left memory cost nothing further. */
static tessel_status scan_box(gp *g, uint32_t R, double half)
{
    double c[3];
    pos(g, R, c);
    const int ad = g->ad, au = g->au, av = g->av;
    double lo_d = c[ad] - half, hi_d = c[ad] + half;
    uint32_t iu0 = grid_coord(c[au] - half, g->glo[au], g->inv_cell, g->nu);
    uint32_t iu1 = grid_coord(c[au] + half, g->glo[au], g->inv_cell, g->nu);
    uint32_t iv0 = grid_coord(c[av] - half, g->glo[av], g->inv_cell, g->nv);
    uint32_t iv1 = grid_coord(c[av] + half, g->glo[av], g->inv_cell, g->nv);
    g->box_count = 0;
    for (uint32_t iv = iv0; iv <= iv1; iv++) {
        for (uint32_t iu = iu0; iu <= iu1; iu++) {
            size_t col = (size_t)iv * g->nu + iu;
            uint32_t s = g->col[col], e = g->col[col + 1];
            if (s == e)
                continue;
            uint32_t lo = s, hi = e;
            while (lo < hi) {
                uint32_t mid = lo + (hi - lo) / 2;
                if ((double)g->xyz[3 * (size_t)mid + ad] < lo_d)
                    lo = mid + 1;
                else
                    hi = mid;
            }
            for (uint32_t i = lo; i < e; i++) {
                const float *p = g->xyz + 3 * (size_t)i;
                if ((double)p[ad] > hi_d)
                    break;
                int s_i = st(g, i);
                if (i == R || s_i == ST_DEAD || (s_i == ST_DONE && g->head[i] == NONE))
                    continue;
                double r0 = p[0] - c[0], r1 = p[1] - c[1], r2 = p[2] - c[2];
                double a0 = fabs(r0), a1 = fabs(r1), a2 = fabs(r2);
                double dinf = a0 > a1 ? a0 : a1;
                dinf = dinf > a2 ? dinf : a2;
                if (dinf > half)
                    continue;
                if (g->box_count == g->box_cap &&
                    grow((void **)&g->box, &g->box_cap, g->box_count + 1, sizeof *g->box))
                    return TESSEL_ERR_NOMEM;
                gp_box *b = &g->box[g->box_count++];
                b->idx = i;
                b->dinf = (float)dinf;
                b->rel[0] = r0;
                b->rel[1] = r1;
                b->rel[2] = r2;
            }
        }
    }
    return TESSEL_OK;
}

/* Distance from point i to its nearest point (state filter: live points
 * only when live_only) with positive distance, searching boxes that double
 * from `start` up to `limit`. Returns INFINITY when there is none within
 * limit. Uses g->box as scratch. */
static tessel_status nearest(gp *g, uint32_t i, int live_only, double start, double limit,
                             double *dist)
{
    *dist = INFINITY;
    for (double h = start;; h *= 2.0) {
        if (h > limit)
            h = limit;
        tessel_status s = scan_box(g, i, h);
        if (s != TESSEL_OK)
            return s;
        double best = INFINITY;
        for (size_t k = 0; k < g->box_count; k++) {
            const gp_box *b = &g->box[k];
            if (live_only && !is_live(g, b->idx))
                continue;
            double d2 = tsl_dot(b->rel, b->rel);
            if (d2 > 0.0 && d2 < best)
                best = d2;
        }
        /* Found within the box's inscribed sphere: exact nearest. */
        if (best <= h * h) {
            *dist = sqrt(best);
            return TESSEL_OK;
        }
        if (h >= limit) {
            if (best <= limit * limit)
                *dist = sqrt(best);
            return TESSEL_OK;
        }
    }
}

/* ------------------------------------------------------------------------ */
/* Retirement blocks: a triangle leaves memory once no live point is near    */
/* enough for a later triangle to reach it                                   */
/* ------------------------------------------------------------------------ */

static inline size_t block_of(const gp *g, const float p[3])
{
    uint32_t b[3];
    for (int k = 0; k < 3; k++)
        b[k] = grid_coord(p[k], g->glo[k], g->inv_block, g->bn[k]);
    return ((size_t)b[2] * g->bn[1] + b[1]) * g->bn[0] + b[0];
}

/* One more dead block around each of the 27 blocks near block b. */
static void block_died(gp *g, size_t b)
{
    uint32_t bx = (uint32_t)(b % g->bn[0]);
    uint32_t by = (uint32_t)(b / g->bn[0] % g->bn[1]);
    uint32_t bz = (uint32_t)(b / g->bn[0] / g->bn[1]);
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                long x = (long)bx + dx, y = (long)by + dy, z = (long)bz + dz;
                if (x < 0 || y < 0 || z < 0 || x >= (long)g->bn[0] || y >= (long)g->bn[1] ||
                    z >= (long)g->bn[2])
                    continue;
                g->bdead[((size_t)z * g->bn[1] + (size_t)y) * g->bn[0] + (size_t)x]++;
            }
}

/* Point i stops being live (completed or left out). */
static void point_settled(gp *g, uint32_t i)
{
    size_t b = block_of(g, g->xyz + 3 * (size_t)i);
    if (--g->blive[b] == 0)
        block_died(g, b);
}

static tessel_status init_blocks(gp *g, const double ext[3], double width)
{
    for (;;) {
        double total = 1.0;
        for (int k = 0; k < 3; k++)
            total *= ext[k] / width + 1.0;
        if (total <= (double)((size_t)1 << 21))
            break;
        width *= 1.25;
    }
    g->inv_block = 1.0 / width;
    size_t nb = 1;
    for (int k = 0; k < 3; k++) {
        g->bn[k] = (uint32_t)(ext[k] / width) + 1;
        nb *= g->bn[k];
    }
    g->blive = tsl_calloc_array(nb, sizeof *g->blive);
    g->bdead = tsl_calloc_array(nb, sizeof *g->bdead);
    if (!g->blive || !g->bdead)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < g->n; i++)
        if (st(g, (uint32_t)i) != ST_DEAD)
            g->blive[block_of(g, g->xyz + 3 * i)]++;
    /* Neighbours outside the grid count as dead. */
    for (size_t b = 0; b < nb; b++) {
        uint32_t c[3] = {(uint32_t)(b % g->bn[0]), (uint32_t)(b / g->bn[0] % g->bn[1]),
                         (uint32_t)(b / g->bn[0] / g->bn[1])};
        int inside = 1;
        for (int k = 0; k < 3; k++)
            inside *= 1 + (c[k] > 0) + (c[k] + 1 < g->bn[k]);
        g->bdead[b] = (uint8_t)(27 - inside);
    }
    for (size_t b = 0; b < nb; b++)
        if (g->blive[b] == 0)
            block_died(g, b);
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Triangle pool, fans and output                                            */
/* ------------------------------------------------------------------------ */

static tessel_status flush_out(gp *g)
{
    if (g->out_count == 0)
        return TESSEL_OK;
    tessel_status s = g->sink->emit(g->sink->user_data, g->out, g->out_count);
    g->out_count = 0;
    return s;
}

static inline int tri_pos(const gp_tri *t, uint32_t v)
{
    return t->v[0] == v ? 0 : (t->v[1] == v ? 1 : 2);
}

/* Some held triangle uses the directed edge x -> y. */
static int edge_exists(const gp *g, uint32_t x, uint32_t y)
{
    for (uint32_t t = g->head[x]; t != NONE;) {
        const gp_tri *T = &g->tri[t];
        int k = tri_pos(T, x);
        if (T->v[(k + 1) % 3] == y)
            return 1;
        t = T->next[k];
    }
    return 0;
}

static size_t fan_size(const gp *g, uint32_t x)
{
    size_t c = 0;
    for (uint32_t t = g->head[x]; t != NONE; t = g->tri[t].next[tri_pos(&g->tri[t], x)])
        c++;
    return c;
}

static void tri_box(const gp *g, const uint32_t v[3], float lo[3], float hi[3])
{
    const float *a = g->xyz + 3 * (size_t)v[0], *b = g->xyz + 3 * (size_t)v[1],
                *c = g->xyz + 3 * (size_t)v[2];
    for (int k = 0; k < 3; k++) {
        float l = a[k], h = a[k];
        l = b[k] < l ? b[k] : l;
        h = b[k] > h ? b[k] : h;
        l = c[k] < l ? c[k] : l;
        h = c[k] > h ? c[k] : h;
        lo[k] = l;
        hi[k] = h;
    }
}

/* ---- long triangles: those with an edge longer than ell can meet a new
 * triangle without having a vertex in the box the guard looks at, so they
 * are also listed in a hashed grid ---- */

static void lg_cells(const gp *g, const float lo[3], const float hi[3], uint32_t c0[3],
                     uint32_t c1[3])
{
    for (int k = 0; k < 3; k++) {
        double a = (lo[k] - g->glo[k]) * g->lg_inv, b = (hi[k] - g->glo[k]) * g->lg_inv;
        c0[k] = a > 0.0 ? (a < 2097151.0 ? (uint32_t)a : 2097151u) : 0u;
        c1[k] = b > 0.0 ? (b < 2097151.0 ? (uint32_t)b : 2097151u) : 0u;
    }
}

static inline uint64_t lg_key(uint32_t x, uint32_t y, uint32_t z)
{
    return ((uint64_t)x << 42) | ((uint64_t)y << 21) | (uint64_t)z;
}

static inline size_t lg_find(const gp *g, uint64_t key)
{
    size_t mask = g->lg_slots - 1;
    size_t h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 20) & mask;
    while (g->lg_keys[h] && g->lg_keys[h] != key + 1)
        h = (h + 1) & mask;
    return h;
}

/* Doubles the table (or creates it), dropping cells whose list is empty. */
static tessel_status lg_rehash(gp *g)
{
    size_t slots = g->lg_slots ? 2 * g->lg_slots : 1024;
    uint64_t *ok = g->lg_keys;
    uint32_t *oh = g->lg_head;
    size_t os = g->lg_slots;
    g->lg_keys = tsl_calloc_array(slots, sizeof *g->lg_keys);
    g->lg_head = tsl_alloc_array(slots, sizeof *g->lg_head);
    if (!g->lg_keys || !g->lg_head) {
        free(g->lg_keys);
        free(g->lg_head);
        g->lg_keys = ok;
        g->lg_head = oh;
        return TESSEL_ERR_NOMEM;
    }
    g->lg_slots = slots;
    g->lg_used = 0;
    for (size_t i = 0; i < os; i++) {
        if (!ok[i] || oh[i] == NONE)
            continue;
        size_t h = lg_find(g, ok[i] - 1);
        g->lg_keys[h] = ok[i];
        g->lg_head[h] = oh[i];
        g->lg_used++;
    }
    free(ok);
    free(oh);
    return TESSEL_OK;
}

static tessel_status long_register(gp *g, uint32_t t)
{
    float lo[3], hi[3];
    uint32_t c0[3], c1[3];
    tri_box(g, g->tri[t].v, lo, hi);
    lg_cells(g, lo, hi, c0, c1);
    for (uint32_t z = c0[2]; z <= c1[2]; z++)
        for (uint32_t y = c0[1]; y <= c1[1]; y++)
            for (uint32_t x = c0[0]; x <= c1[0]; x++) {
                tessel_status s;
                if (2 * (g->lg_used + 1) > g->lg_slots && (s = lg_rehash(g)) != TESSEL_OK)
                    return s;
                uint64_t key = lg_key(x, y, z);
                size_t h = lg_find(g, key);
                if (!g->lg_keys[h]) {
                    g->lg_keys[h] = key + 1;
                    g->lg_head[h] = NONE;
                    g->lg_used++;
                }
                uint32_t e = g->lt_free;
                if (e != NONE) {
                    g->lt_free = g->lt_next[e];
                } else {
                    if (g->lt_used == g->lt_cap) {
                        size_t cap = g->lt_cap ? 2 * g->lt_cap : 1024;
                        uint32_t *a = realloc(g->lt_tri, cap * sizeof *a);
                        if (!a)
                            return TESSEL_ERR_NOMEM;
                        g->lt_tri = a;
                        uint32_t *b = realloc(g->lt_next, cap * sizeof *b);
                        if (!b)
                            return TESSEL_ERR_NOMEM;
                        g->lt_next = b;
                        g->lt_cap = cap;
                    }
                    e = (uint32_t)g->lt_used++;
                }
                g->lt_tri[e] = t;
                g->lt_next[e] = g->lg_head[h];
                g->lg_head[h] = e;
            }
    return TESSEL_OK;
}

static void long_unregister(gp *g, uint32_t t)
{
    float lo[3], hi[3];
    uint32_t c0[3], c1[3];
    tri_box(g, g->tri[t].v, lo, hi);
    lg_cells(g, lo, hi, c0, c1);
    for (uint32_t z = c0[2]; z <= c1[2]; z++)
        for (uint32_t y = c0[1]; y <= c1[1]; y++)
            for (uint32_t x = c0[0]; x <= c1[0]; x++) {
                size_t h = lg_find(g, lg_key(x, y, z));
                if (!g->lg_keys[h])
                    continue;
                uint32_t *link = &g->lg_head[h];
                while (*link != NONE && g->lt_tri[*link] != t)
                    link = &g->lt_next[*link];
                if (*link != NONE) {
                    uint32_t e = *link;
                    *link = g->lt_next[e];
                    g->lt_next[e] = g->lt_free;
                    g->lt_free = e;
                }
            }
}

static tessel_status tri_alloc(gp *g, uint32_t *out)
{
    uint32_t t = g->tfree;
    if (t != NONE) {
        g->tfree = g->tri[t].next[0];
    } else {
        if (g->tused == g->tcap) {
            size_t cap = g->tcap ? 2 * g->tcap : 1024;
            if (cap >= NONE)
                return TESSEL_ERR_LIMIT;
            gp_tri *nt = realloc(g->tri, cap * sizeof *nt);
            if (!nt)
                return TESSEL_ERR_NOMEM;
            g->tri = nt;
            uint32_t *ns = realloc(g->tstamp, cap * sizeof *ns);
            if (!ns)
                return TESSEL_ERR_NOMEM;
            g->tstamp = ns;
            uint8_t *nf = realloc(g->tflag, cap * sizeof *nf);
            if (!nf)
                return TESSEL_ERR_NOMEM;
            g->tflag = nf;
            g->tcap = cap;
        }
        t = (uint32_t)g->tused++;
    }
    g->tstamp[t] = 0;
    g->tflag[t] = TF_ALIVE;
    *out = t;
    return TESSEL_OK;
}

/* Emits (unless it was given as existing) and frees held triangle t. */
static tessel_status tri_retire(gp *g, uint32_t t)
{
    gp_tri *T = &g->tri[t];
    if (!(g->tflag[t] & TF_EXISTING)) {
        for (int k = 0; k < 3; k++)
            g->out[3 * g->out_count + (size_t)k] = g->orig[T->v[k]];
        if (++g->out_count == OUT_BATCH) {
            tessel_status s = flush_out(g);
            if (s != TESSEL_OK)
                return s;
        }
        g->sum.triangles++;
    }
    if (g->tflag[t] & TF_LONG)
        long_unregister(g, t);
    for (int k = 0; k < 3; k++) {
        uint32_t v = T->v[k];
        uint32_t *link = &g->head[v];
        while (*link != t) {
            gp_tri *U = &g->tri[*link];
            link = &U->next[tri_pos(U, v)];
        }
        *link = T->next[k];
    }
    g->tflag[t] = 0;
    T->next[0] = g->tfree;
    g->tfree = t;
    g->talive--;
    return TESSEL_OK;
}

/* Retires every held triangle whose surroundings have no live point left. */
static tessel_status sweep(gp *g, int all)
{
    for (size_t t = 0; t < g->tused; t++) {
        if (!(g->tflag[t] & TF_ALIVE))
            continue;
        if (!all && g->bdead[block_of(g, g->xyz + 3 * (size_t)g->tri[t].v[0])] != 27)
            continue;
        tessel_status s = tri_retire(g, (uint32_t)t);
        if (s != TESSEL_OK)
            return s;
    }
    g->created_since_sweep = 0;
    g->alive_after_sweep = g->talive;
    return TESSEL_OK;
}

/* ---- components: union-find over labels ---- */

static uint32_t uf_find(gp *g, uint32_t x)
{
    while (g->uf[x] != x) {
        g->uf[x] = g->uf[g->uf[x]];
        x = g->uf[x];
    }
    return x;
}

static tessel_status uf_new(gp *g, uint32_t *label)
{
    if (grow((void **)&g->uf, &g->uf_cap, g->uf_count + 1, sizeof *g->uf))
        return TESSEL_ERR_NOMEM;
    *label = (uint32_t)g->uf_count;
    g->uf[g->uf_count] = (uint32_t)g->uf_count;
    g->uf_count++;
    return TESSEL_OK;
}

static void uf_union(gp *g, uint32_t a, uint32_t b)
{
    a = uf_find(g, a);
    b = uf_find(g, b);
    if (a != b)
        g->uf[a < b ? b : a] = a < b ? a : b;
}

static void enqueue(gp *g, uint32_t i)
{
    if (g->state[i] & ST_QUEUED)
        return;
    g->state[i] |= ST_QUEUED;
    g->queue[(g->qhead + g->qcount) % g->n] = i;
    g->qcount++;
}

/* Links triangle (a, b, c) into the pool and the points' lists; counts
 * boundary edges and joins components. Fans are updated by the caller. */
static tessel_status tri_add(gp *g, uint32_t a, uint32_t b, uint32_t c, int existing,
                             uint32_t *out)
{
    uint32_t v[3] = {a, b, c};
    for (int k = 0; k < 3; k++)
        g->boundary_edges += edge_exists(g, v[(k + 1) % 3], v[k]) ? -1 : 1;
    uint32_t t;
    tessel_status s = tri_alloc(g, &t);
    if (s != TESSEL_OK)
        return s;
    gp_tri *T = &g->tri[t];
    uint32_t lab = NONE;
    for (int k = 0; k < 3; k++) {
        T->v[k] = v[k];
        T->next[k] = g->head[v[k]];
        g->head[v[k]] = t;
        if (g->label[v[k]] != NONE) {
            if (lab == NONE)
                lab = g->label[v[k]];
            else
                uf_union(g, lab, g->label[v[k]]);
        }
    }
    if (lab == NONE && (s = uf_new(g, &lab)) != TESSEL_OK)
        return s;
    for (int k = 0; k < 3; k++)
        if (g->label[v[k]] == NONE)
            g->label[v[k]] = lab;
    if (existing)
        g->tflag[t] |= TF_EXISTING;
    double pa[3], pb[3], pc[3], d[3];
    pos(g, a, pa);
    pos(g, b, pb);
    pos(g, c, pc);
    double l2[3];
    tsl_sub(pa, pb, d);
    l2[0] = tsl_dot(d, d); /* ab */
    tsl_sub(pb, pc, d);
    l2[1] = tsl_dot(d, d); /* bc */
    tsl_sub(pc, pa, d);
    l2[2] = tsl_dot(d, d); /* ca */
    double e2 = fmax(l2[0], fmax(l2[1], l2[2]));
    /* Rounded up so that it bounds the true length. */
    float la = (float)(sqrt(fmax(l2[0], l2[2])) * (1.0 + 1e-6));
    float lb = (float)(sqrt(fmax(l2[0], l2[1])) * (1.0 + 1e-6));
    float lc = (float)(sqrt(fmax(l2[1], l2[2])) * (1.0 + 1e-6));
    if (la > g->maxe[a])
        g->maxe[a] = la;
    if (lb > g->maxe[b])
        g->maxe[b] = lb;
    if (lc > g->maxe[c])
        g->maxe[c] = lc;
    if (e2 > g->ell * g->ell) {
        g->tflag[t] |= TF_LONG;
        if ((s = long_register(g, t)) != TESSEL_OK)
            return s;
    }
    g->talive++;
    g->created_since_sweep++;
    if (g->talive > g->sum.peak_held_triangles)
        g->sum.peak_held_triangles = g->talive;
    if (out)
        *out = t;
    return TESSEL_OK;
}

/* ---- fans ----
 * The triangles at a point with an open fan have link path ls -> ... -> le:
 * triangle (p, x, y) contributes the link edge x -> y. A new link segment
 * a -> ... -> b (from one or two new triangles) keeps a single fan when it
 * is prepended (b == ls), appended (a == le), or closes the fan (both, with
 * at least three triangles in all), or when the point had no triangle. */
enum { LINK_FAIL = 0, LINK_NEW, LINK_PREPEND, LINK_APPEND, LINK_CLOSE };

static int link_check(const gp *g, uint32_t p, uint32_t a, uint32_t b, int edges)
{
    if (g->head[p] == NONE)
        return LINK_NEW;
    if (st(g, p) == ST_DONE)
        return LINK_FAIL;
    uint32_t s = g->ls[p], e = g->le[p];
    if (b == s && a == e)
        return fan_size(g, p) + (size_t)edges >= 3 ? LINK_CLOSE : LINK_FAIL;
    if (b == s)
        return LINK_PREPEND;
    if (a == e)
        return LINK_APPEND;
    return LINK_FAIL;
}

/* Applies a checked link change to point p (not the reference point). */
static void link_apply(gp *g, uint32_t p, uint32_t a, uint32_t b, int how, int is_ref)
{
    switch (how) {
    case LINK_NEW:
        g->ls[p] = a;
        g->le[p] = b;
        if (!is_ref && st(g, p) == ST_FREE) {
            g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_FRINGE);
            g->sum.points_used++;
            enqueue(g, p);
        } else if (is_ref && st(g, p) == ST_FREE) {
            g->sum.points_used++;
        }
        break;
    case LINK_PREPEND:
        g->ls[p] = a;
        break;
    case LINK_APPEND:
        g->le[p] = b;
        break;
    case LINK_CLOSE:
        g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_DONE);
        g->ls[p] = g->le[p] = NONE;
        point_settled(g, p);
        return;
    default:
        return;
    }
    /* A boundary point whose fan a neighbour changed may close now. */
    if (!is_ref && st(g, p) == ST_BOUNDARY && (g->state[p] >> 4) < MAX_VISITS)
        enqueue(g, p);
}

/* ------------------------------------------------------------------------ */
/* The reference point (section 4)                                           */
/* ------------------------------------------------------------------------ */

typedef struct gp_frame {
    double n[3], u[3], v[3];
    double rho;        /* radius of the sphere of influence */
    double reach;      /* every new triangle lies within reach of R */
} gp_frame;

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

static void project_point(const gp *g, uint32_t R, const gp_frame *f, uint32_t i, double xy[2])
{
    const float *p = g->xyz + 3 * (size_t)i, *r = g->xyz + 3 * (size_t)R;
    double d[3] = {(double)p[0] - r[0], (double)p[1] - r[1], (double)p[2] - r[2]};
    xy[0] = tsl_dot(d, f->u);
    xy[1] = tsl_dot(d, f->v);
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

static inline double cross2(double ax, double ay, double bx, double by)
{
    return ax * by - ay * bx;
}

/* Visibility rules 2 and 3 of section 4.1 on the kept candidates: drop
 * those that have R in their invisible region (between their two boundary
 * edges) and those hidden from R by a boundary edge of a candidate
 * (Theorem 4.1: no other edge needs testing). ends: candidates never
 * dropped (R's own boundary neighbours). */
static void visibility(gp *g, uint32_t R, const gp_frame *f, uint32_t end_a, uint32_t end_b)
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
    /* Rule 3: boundary edges of the candidates as occluders. */
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
            for (size_t i = 0; i < nc; i++) {
                gp_cand *x = &g->cand[i];
                if (x->kept != 1 || x->idx == end_a || x->idx == end_b || x->idx == o->idx ||
                    x->idx == other)
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
}

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

static unsigned cone_flags(const gp_cone *c, uint32_t v, const double q[2])
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

static tessel_status guard_push(gp *g, uint32_t t, const gp_cone *cone, const gp_frame *f)
{
    g->tstamp[t] = g->stamp;
    const gp_tri *T = &g->tri[t];
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
    tri_box(g, T->v, e->lo, e->hi);
    return TESSEL_OK;
}

/* Collects the held triangles that a new triangle within f->reach of R
 * could meet and that the cone does not rule out: those with a vertex in
 * the box of half-size reach + delta (a triangle whose vertices all lie
 * outside has an edge longer than ell and is in the long-triangle grid). A
 * point whose projection is farther from the free cone than its longest
 * edge cannot have a triangle reaching the cone: skipped whole. */
static tessel_status guard_collect(gp *g, uint32_t R, const gp_frame *f, int use_cone)
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
    tessel_status s;
    for (size_t k = 0; k < g->box_count; k++) {
        const gp_box *b = &g->box[k];
        uint32_t v = b->idx;
        if ((double)b->dinf > half || g->head[v] == NONE)
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
            if (g->tstamp[t] != g->stamp && (s = guard_push(g, t, &cone, f)) != TESSEL_OK)
                return s;
            t = T->next[tri_pos(T, v)];
        }
    }
    /* R's own triangles (R is not in its box). */
    for (uint32_t t = g->head[R]; t != NONE;) {
        const gp_tri *T = &g->tri[t];
        if (g->tstamp[t] != g->stamp && (s = guard_push(g, t, &cone, f)) != TESSEL_OK)
            return s;
        t = T->next[tri_pos(T, R)];
    }
    /* Long triangles of the cells the box overlaps. */
    if (!g->lg_slots)
        return TESSEL_OK;
    const float *r = g->xyz + 3 * (size_t)R;
    float lo[3], hi[3];
    for (int k = 0; k < 3; k++) {
        lo[k] = (float)(r[k] - half);
        hi[k] = (float)(r[k] + half);
    }
    uint32_t c0[3], c1[3];
    lg_cells(g, lo, hi, c0, c1);
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
                    float tl[3], th[3];
                    tri_box(g, g->tri[t].v, tl, th);
                    if (tl[0] > hi[0] || th[0] < lo[0] || tl[1] > hi[1] || th[1] < lo[1] ||
                        tl[2] > hi[2] || th[2] < lo[2])
                        continue;
                    if ((s = guard_push(g, t, &cone, f)) != TESSEL_OK)
                        return s;
                }
            }
    return TESSEL_OK;
}

/* The new triangle v meets no collected held triangle except in a shared
 * vertex or edge. */
static int guard_ok(gp *g, const uint32_t v[3])
{
    float lo[3], hi[3];
    tri_box(g, v, lo, hi);
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
    (void)f;
    double pr[3];
    pos(g, R, pr);
    double rcap = g->mu * g->m_cap;
    double cap2 = 4.0 * rcap * rcap;
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
        if (collinear3(pr, qa, qb))
            return TESSEL_OK;
        if (edge_exists(g, R, a->idx) || edge_exists(g, a->idx, b->idx) ||
            edge_exists(g, b->idx, R))
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
        how[i] = link_check(g, pts[i], after, before, edges);
        if (how[i] == LINK_FAIL) {
            int lead = lead_last ? i == cnt : i == 0;
            *result = lead ? TRY_LEAD : TRY_FAIL;
            return TESSEL_OK;
        }
    }
    int how_r = link_check(g, R, pts[0], pts[cnt], cnt);
    if (how_r == LINK_FAIL)
        return TESSEL_OK;
    for (int i = 0; i < cnt; i++) {
        uint32_t v[3] = {R, pts[i], pts[i + 1]};
        if (!guard_ok(g, v)) {
            g->sum.rejected_intersecting++;
            return TESSEL_OK;
        }
    }
    /* Apply. */
    for (int i = 0; i < cnt; i++) {
        uint32_t t;
        tessel_status s = tri_add(g, R, pts[i], pts[i + 1], 0, &t);
        if (s != TESSEL_OK)
            return s;
        if (grow((void **)&g->gt, &g->gt_cap, g->gt_count + 1, sizeof *g->gt))
            return TESSEL_ERR_NOMEM;
        gp_gtri *e = &g->gt[g->gt_count++];
        e->t = t;
        g->tstamp[t] = g->stamp;
        tri_box(g, g->tri[t].v, e->lo, e->hi);
    }
    link_apply(g, R, pts[0], pts[cnt], how_r, 1);
    for (int i = 0; i <= cnt; i++)
        link_apply(g, pts[i], sa[i], sb[i], how[i], 0);
    *result = TRY_OK;
    return TESSEL_OK;
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

/* Builds seq = e, candidates of the free sector by angle, s, for R whose fan
 * runs s -> ... -> e, and triangulates it. Candidate keys must be relative to
 * e's direction. */
static tessel_status fill_sector(gp *g, uint32_t R, const gp_frame *f)
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
    visibility(g, R, f, e, s);
    sort_cands(g);
    g->seq_count = 0;
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
    /* Points on the mesh side are not trap candidates. */
    for (size_t i = 0; i < g->cand_count; i++)
        if (g->cand[i].kept == 2)
            g->cand[i].kept = 1, g->cand[i].key = -1.0;
    angle_criterion(g);
    return walk(g, R, f);
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
 * required ones. */
static tessel_status gather(gp *g, double b, double m0, double mu, gp_frame *f,
                            uint32_t req_a, uint32_t req_b)
{
    double dmin2 = INFINITY;
    for (size_t k = 0; k < g->box_count; k++) {
        const gp_box *x = &g->box[k];
        if ((double)x->dinf > b || !is_live(g, x->idx))
            continue;
        double d2 = tsl_dot(x->rel, x->rel);
        if (d2 > 0.0 && d2 < dmin2)
            dmin2 = d2;
    }
    double m = m0;
    if (dmin2 < m * m)
        m = sqrt(dmin2);
    if (m < g->m_floor)
        m = g->m_floor;
    f->rho = mu * m;
    double rho2 = f->rho * f->rho;
    f->reach = f->rho;
    g->cand_count = 0;
    for (size_t k = 0; k < g->box_count; k++) {
        const gp_box *x = &g->box[k];
        if (!is_live(g, x->idx))
            continue;
        double d2 = tsl_dot(x->rel, x->rel);
        if (d2 == 0.0)
            continue;
        if (d2 > rho2 && x->idx != req_a && x->idx != req_b)
            continue;
        if (d2 > f->reach * f->reach)
            f->reach = sqrt(d2);
        tessel_status s = cand_push(g, x->idx, x->rel);
        if (s != TESSEL_OK)
            return s;
    }
    return TESSEL_OK;
}

/* R's fan, its sphere of influence, its candidates and the fill. */
static tessel_status process_pass(gp *g, uint32_t R)
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
        m0 = fmin(m0, fmin(tsl_dot(da, da), tsl_dot(db, db)));
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
    double b = g->mu * m0;
    double half = fmax(b, fmax(re, rs)) + g->delta;
    tessel_status st_ = scan_box(g, R, half);
    if (st_ != TESSEL_OK)
        return st_;
    if ((st_ = gather(g, b, m0, g->mu, &f, e, s)) != TESSEL_OK)
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
    if ((st_ = guard_collect(g, R, &f, 1)) != TESSEL_OK)
        return st_;
    if ((st_ = fill_sector(g, R, &f)) != TESSEL_OK)
        return st_;
    finish_ref(g, R);
    return TESSEL_OK;
}

/* A fringe or boundary point as reference point. */
static tessel_status process(gp *g, uint32_t R)
{
    g->state[R] = (uint8_t)(g->state[R] + ST_VISITS);
    return process_pass(g, R);
}

/* Sign of a seed's normal: agree with the triangles already around it, else
 * with the input normal, else face the viewpoint, else point to -depth (the
 * seed is the lowest free point, so -depth is outward on a closed surface). */
static void orient_seed(gp *g, uint32_t R, double n[3])
{
    double ref[3] = {0, 0, 0};
    for (size_t i = 0; i < g->cand_count; i++) {
        uint32_t c = g->cand[i].idx;
        /* Only neighbours near R's tangent plane vote: points of a facing
         * sheet (a hand beside a thigh) lie along the normal and would
         * flip the seed. */
        double h = tsl_dot(g->cand[i].rel, n);
        if (h * h > 0.25 * (g->cand[i].d2 - h * h))
            continue;
        for (uint32_t t = g->head[c]; t != NONE;) {
            const gp_tri *T = &g->tri[t];
            double a[3], b[3], cc[3], u[3], v[3], nn[3];
            pos(g, T->v[0], a);
            pos(g, T->v[1], b);
            pos(g, T->v[2], cc);
            tsl_sub(b, a, u);
            tsl_sub(cc, a, v);
            tsl_cross(u, v, nn);
            if (tsl_normalize(nn))
                for (int k = 0; k < 3; k++)
                    ref[k] += nn[k];
            t = T->next[tri_pos(T, c)];
        }
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
}

static void settle_dead(gp *g, uint32_t R, size_t *counter)
{
    g->state[R] = (uint8_t)((g->state[R] & ~ST_MASK) | ST_DEAD);
    point_settled(g, R);
    (*counter)++;
}

/* A free point as seed (sections 3-4.1: m from its nearest point, PCA
 * plane). Its first triangle joins two angularly consecutive candidates;
 * then it is completed like any fringe point. */
static tessel_status seed(gp *g, uint32_t R)
{
    double m;
    tessel_status s = nearest(g, R, 1, g->spacing, g->m_cap, &m);
    if (s != TESSEL_OK)
        return s;
    if (!(m <= g->m_cap)) {
        /* Nothing live nearby: alone, or enclosed by the finished mesh. */
        double any;
        if ((s = nearest(g, R, 0, g->spacing, g->m_cap, &any)) != TESSEL_OK)
            return s;
        settle_dead(g, R, any <= g->m_cap ? &g->sum.left_closed_in : &g->sum.left_isolated);
        return TESSEL_OK;
    }
    if (m < g->m_floor)
        m = g->m_floor;
    gp_frame f;
    double b = g->mu * m;
    if ((s = scan_box(g, R, b + g->delta)) != TESSEL_OK)
        return s;
    if ((s = gather(g, b, m, g->mu, &f, NONE, NONE)) != TESSEL_OK)
        return s;
    size_t done_near = 0;
    for (size_t k = 0; k < g->box_count; k++)
        done_near += st(g, g->box[k].idx) == ST_DONE;
    if (g->cand_count < 2 || !pca_normal(g->cand, g->cand_count, f.n)) {
        settle_dead(g, R, done_near ? &g->sum.left_closed_in : &g->sum.left_untriangulated);
        return TESSEL_OK;
    }
    orient_seed(g, R, f.n);
    frame_axes(&f, g->plane_axis);
    project_cands(g, &f, NONE, NONE);
    for (size_t i = 0; i < g->cand_count; i++)
        g->cand[i].key = pseudo_angle(g->cand[i].x, g->cand[i].y);
    visibility(g, R, &f, NONE, NONE);
    sort_cands(g);
    if ((s = guard_collect(g, R, &f, 0)) != TESSEL_OK)
        return s;
    /* Kept candidates in angular order; start after the widest gap. */
    size_t nk = 0;
    if (grow((void **)&g->seq, &g->seq_cap, g->cand_count + 2, sizeof *g->seq))
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < g->cand_count; i++)
        if (g->cand[i].kept)
            g->seq[nk++] = (uint32_t)i;
    int made = 0;
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
        settle_dead(g, R, done_near ? &g->sum.left_closed_in : &g->sum.left_untriangulated);
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
/* Set-up, existing triangles, the main loop                                 */
/* ------------------------------------------------------------------------ */

static void gp_free(gp *g)
{
    free(g->xyz);
    free(g->orig);
    free(g->state);
    free(g->head);
    free(g->ls);
    free(g->le);
    free(g->label);
    free(g->maxe);
    free(g->col);
    free(g->blive);
    free(g->bdead);
    free(g->lg_keys);
    free(g->lg_head);
    free(g->tri);
    free(g->tstamp);
    free(g->tflag);
    free(g->lt_tri);
    free(g->lt_next);
    free(g->queue);
    free(g->seed_order);
    free(g->uf);
    free(g->out);
    free(g->box);
    free(g->cand);
    free(g->seq);
    free(g->gt);
    free(g->pc);
}

static inline uint32_t depth_key(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

/* Seed order: dexel indices by increasing depth (LSD radix sort, stable;
 * g->queue serves as scratch). */
static void order_seeds(gp *g)
{
    uint32_t *a = g->seed_order, *b = g->queue;
    for (size_t i = 0; i < g->n; i++)
        a[i] = (uint32_t)i;
    for (int shift = 0; shift < 32; shift += 8) {
        size_t count[257] = {0};
        for (size_t i = 0; i < g->n; i++)
            count[((depth_key(g->xyz[3 * (size_t)a[i] + g->ad]) >> shift) & 255) + 1]++;
        for (int k = 0; k < 256; k++)
            count[k + 1] += count[k];
        for (size_t i = 0; i < g->n; i++)
            b[count[(depth_key(g->xyz[3 * (size_t)a[i] + g->ad]) >> shift) & 255]++] = a[i];
        uint32_t *t = a;
        a = b;
        b = t;
    }
    /* Four passes: the result is back in seed_order. */
}

/* Mean distance to the nearest other point, on an even sample. */
static tessel_status estimate_spacing(gp *g, double *spacing)
{
    size_t k = g->n < 2048 ? g->n : 2048;
    double sum = 0.0;
    size_t used = 0;
    double limit = 64.0 * g->cell;
    for (size_t i = 0; i < k; i++) {
        uint32_t idx = (uint32_t)((double)i * (double)g->n / (double)k);
        double d;
        tessel_status s = nearest(g, idx, 0, 0.5 * g->cell, limit, &d);
        if (s != TESSEL_OK)
            return s;
        if (d <= limit) {
            sum += d;
            used++;
        }
    }
    *spacing = used ? sum / (double)used : 0.0;
    return TESSEL_OK;
}

/* Imports params->existing: links the triangles, then derives every touched
 * point's fan; fans that are not a single path or cycle, or edges used twice
 * in one direction, make the input invalid. */
static tessel_status import_existing(gp *g, const uint32_t *tris, size_t count)
{
    uint32_t *inv = tsl_alloc_array(g->n, sizeof *inv);
    if (!inv)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < g->n; i++)
        inv[g->orig[i]] = (uint32_t)i;
    tessel_status s = TESSEL_OK;
    for (size_t t = 0; t < count && s == TESSEL_OK; t++) {
        uint32_t v[3];
        for (int k = 0; k < 3; k++) {
            uint32_t o = tris[3 * t + (size_t)k];
            if (o >= g->n) {
                s = TESSEL_ERR_INVALID_ARG;
                break;
            }
            v[k] = inv[o];
            if (st(g, v[k]) == ST_DEAD)
                v[k] = g->ls[v[k]]; /* a duplicate: its kept twin */
        }
        if (s != TESSEL_OK)
            break;
        if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0]) {
            s = TESSEL_ERR_INVALID_ARG;
            break;
        }
        s = tri_add(g, v[0], v[1], v[2], 1, NULL);
    }
    free(inv);
    if (s != TESSEL_OK)
        return s;
    for (size_t t = 0; t < g->tused; t++) {
        for (int k = 0; k < 3; k++) {
            uint32_t p = g->tri[t].v[k];
            if (st(g, p) != ST_FREE)
                continue;
            /* Link edges x -> y of p's triangles; a path or a cycle? */
            size_t edges = 0;
            uint32_t start = NONE;
            for (uint32_t u = g->head[p]; u != NONE;) {
                const gp_tri *T = &g->tri[u];
                int q = tri_pos(T, p);
                uint32_t x = T->v[(q + 1) % 3];
                int has_in = 0;
                size_t outs = 0;
                for (uint32_t w = g->head[p]; w != NONE;) {
                    const gp_tri *W = &g->tri[w];
                    int r = tri_pos(W, p);
                    has_in |= W->v[(r + 2) % 3] == x;
                    outs += W->v[(r + 1) % 3] == x;
                    w = W->next[r];
                }
                if (outs > 1)
                    return TESSEL_ERR_INVALID_ARG;
                if (!has_in) {
                    if (start != NONE)
                        return TESSEL_ERR_INVALID_ARG; /* two fans */
                    start = x;
                }
                edges++;
                u = T->next[q];
            }
            /* Walk the link from start (or any edge for a cycle). */
            uint32_t first = start;
            if (first == NONE) {
                const gp_tri *T = &g->tri[g->head[p]];
                first = T->v[(tri_pos(T, p) + 1) % 3];
            }
            uint32_t x = first, last = first;
            size_t walked = 0;
            for (;;) {
                uint32_t y = NONE;
                for (uint32_t w = g->head[p]; w != NONE;) {
                    const gp_tri *W = &g->tri[w];
                    int r = tri_pos(W, p);
                    if (W->v[(r + 1) % 3] == x)
                        y = W->v[(r + 2) % 3];
                    w = W->next[r];
                }
                if (y == NONE)
                    break;
                walked++;
                last = y;
                x = y;
                if (x == first || walked > edges)
                    break;
            }
            if (walked != edges)
                return TESSEL_ERR_INVALID_ARG;
            g->sum.points_used++;
            if (start == NONE) {
                if (edges < 3)
                    return TESSEL_ERR_INVALID_ARG;
                g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_DONE);
                point_settled(g, p);
            } else {
                g->ls[p] = start;
                g->le[p] = last;
                g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_FRINGE);
                enqueue(g, p);
            }
        }
    }
    return TESSEL_OK;
}

static tessel_status gp_init(gp *g)
{
    size_t n = g->n;
    const float *src = g->cloud->xyz;
    g->xyz = tsl_alloc_array(n, 3 * sizeof(float));
    g->orig = tsl_alloc_array(n, sizeof *g->orig);
    g->state = tsl_calloc_array(n, 1);
    g->head = tsl_alloc_array(n, sizeof *g->head);
    g->ls = tsl_alloc_array(n, sizeof *g->ls);
    g->le = tsl_alloc_array(n, sizeof *g->le);
    g->label = tsl_alloc_array(n, sizeof *g->label);
    g->maxe = tsl_calloc_array(n, sizeof *g->maxe);
    g->queue = tsl_alloc_array(n, sizeof *g->queue);
    g->seed_order = tsl_alloc_array(n, sizeof *g->seed_order);
    g->out = tsl_alloc_array(OUT_BATCH, 3 * sizeof *g->out);
    g->pc = tsl_calloc_array(PCACHE, sizeof *g->pc);
    if (!g->xyz || !g->orig || !g->state || !g->head || !g->ls || !g->le || !g->label ||
        !g->queue || !g->seed_order || !g->out || !g->maxe || !g->pc)
        return TESSEL_ERR_NOMEM;
    memset(g->head, 0xff, n * sizeof *g->head);
    memset(g->ls, 0xff, n * sizeof *g->ls);
    memset(g->le, 0xff, n * sizeof *g->le);
    memset(g->label, 0xff, n * sizeof *g->label);
    g->tfree = NONE;
    g->lt_free = NONE;

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            double x = src[3 * i + (size_t)k];
            if (!isfinite(x))
                return TESSEL_ERR_INVALID_ARG;
            lo[k] = fmin(lo[k], x);
            hi[k] = fmax(hi[k], x);
        }
    double ext[3];
    for (int k = 0; k < 3; k++) {
        g->glo[k] = lo[k];
        ext[k] = hi[k] - lo[k];
    }
    g->ad = 0;
    for (int k = 1; k < 3; k++)
        if (ext[k] > ext[g->ad])
            g->ad = k;
    g->au = (g->ad + 1) % 3;
    g->av = (g->ad + 2) % 3;
    double emax = fmax(ext[0], fmax(ext[1], ext[2]));
    if (!(emax > 0.0))
        emax = 1.0;
    double area = ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0];
    if (!(area > 0.0))
        area = emax * emax;
    double cell = 3.0 * sqrt(area / (double)n);
    if (!(cell > 0.0))
        cell = emax;
    tessel_status s = build_dexels(g, ext, cell);
    if (s != TESSEL_OK)
        return s;
    double spacing;
    if ((s = estimate_spacing(g, &spacing)) != TESSEL_OK)
        return s;
    if (!(spacing > 0.0))
        spacing = g->cell / 3.0;
    if (g->cell < 2.0 * spacing || g->cell > 5.0 * spacing) {
        if ((s = build_dexels(g, ext, 3.0 * spacing)) != TESSEL_OK)
            return s;
    }
    g->spacing = spacing;
    g->sum.spacing = spacing;
    g->m_cap = g->max_spacing * spacing;
    g->m_floor = 0.05 * spacing;
    g->ell = 3.0 * spacing;
    g->delta = g->ell / sqrt(3.0);
    g->lg_inv = 1.0 / (2.0 * (g->mu * spacing + g->delta));

    /* Exact duplicates (adjacent in dexel order): keep the first. */
    size_t ncols = (size_t)g->nu * g->nv;
    for (size_t c = 0; c < ncols; c++)
        for (uint32_t i = g->col[c] + 1; i < g->col[c + 1]; i++) {
            const float *p = g->xyz + 3 * (size_t)i, *q = p - 3;
            if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]) {
                uint32_t keep = st(g, i - 1) == ST_DEAD ? g->ls[i - 1] : i - 1;
                g->state[i] = ST_DEAD;
                g->ls[i] = keep;
                g->sum.left_duplicate++;
            }
        }
    if ((s = init_blocks(g, ext, 4.0 * g->mu * g->m_cap + 2.0 * g->delta)) != TESSEL_OK)
        return s;
    order_seeds(g);
    return TESSEL_OK;
}

static tessel_status progress(gp *g)
{
    double f = (double)g->processed / (double)g->n;
    return tsl_progress(g->cb, "greedy", f < 1.0 ? f : 1.0);
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
            if (g->created_since_sweep >= 65536 &&
                g->created_since_sweep >= g->alive_after_sweep && (s = sweep(g, 0)) != TESSEL_OK)
                return s;
        }
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
    p.max_angle = 120.0;
    p.min_angle = 0.0;
    p.plane = TESSEL_GREEDY_PLANE_PCA;
    p.max_spacing = 4.0;
    p.existing = NULL;
    p.existing_count = 0;
    return p;
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

tessel_status tessel_reconstruct_greedy(const tessel_cloud *cloud,
                                        const tessel_greedy_params *params,
                                        const tessel_callbacks *callbacks,
                                        const tessel_triangle_sink *sink,
                                        tessel_recon_summary *summary)
{
    double t0 = now_seconds();
    if (summary)
        memset(summary, 0, sizeof *summary);
    tessel_greedy_params p = params ? *params : tessel_greedy_params_default();
    if (!cloud || !sink || !sink->emit || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    if (!(p.mu >= 1.2 && p.mu <= 10.0) || !(p.max_angle >= 60.0 && p.max_angle <= 175.0) ||
        !(p.min_angle >= 0.0 && p.min_angle <= 45.0) ||
        !(p.max_spacing >= 1.0 && p.max_spacing <= 1000.0) ||
        (p.plane != TESSEL_GREEDY_PLANE_PCA && p.plane != TESSEL_GREEDY_PLANE_AXIS) ||
        (p.existing_count && !p.existing))
        return TESSEL_ERR_INVALID_ARG;
    if (cloud->count >= NONE)
        return TESSEL_ERR_LIMIT;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;
    gp g;
    memset(&g, 0, sizeof g);
    g.cloud = cloud;
    g.n = cloud->count;
    g.mu = p.mu;
    g.cos_alpha = cos(p.max_angle * 3.14159265358979323846 / 180.0);
    g.beta = p.min_angle * 3.14159265358979323846 / 180.0;
    g.max_spacing = p.max_spacing;
    g.plane_axis = p.plane == TESSEL_GREEDY_PLANE_AXIS;
    g.cb = callbacks;
    g.sink = sink;
    g.sum.points_in = g.n;
    tessel_status s = gp_init(&g);
    if (s == TESSEL_OK && p.existing_count)
        s = import_existing(&g, p.existing, p.existing_count);
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, "greedy", 0.0);
    if (s == TESSEL_OK)
        s = run(&g);
    if (s == TESSEL_OK)
        s = sweep(&g, 1);
    if (s == TESSEL_OK)
        s = flush_out(&g);
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, "greedy", 1.0);
    if (s == TESSEL_OK) {
        g.sum.boundary_edges = (size_t)g.boundary_edges;
        for (size_t i = 0; i < g.uf_count; i++)
            g.sum.components += g.uf[i] == i;
        g.sum.seconds = now_seconds() - t0;
        if (summary)
            *summary = g.sum;
        tsl_log(callbacks, TESSEL_LOG_DEBUG,
                "greedy: %zu of %zu points used, %zu triangles, %zu components, "
                "%zu boundary edges, spacing %g",
                g.sum.points_used, g.sum.points_in, g.sum.triangles, g.sum.components,
                g.sum.boundary_edges, g.sum.spacing);
    }
    gp_free(&g);
    return s;
}

/* Collects the streamed triangles for tessel_reconstruct_greedy_mesh. */
typedef struct gp_collect {
    uint32_t *tris;
    size_t count, cap;
} gp_collect;

static tessel_status collect_emit(void *user, const uint32_t *tris, size_t count)
{
    gp_collect *c = user;
    size_t need;
    if (!tsl_add_size(c->count, count, &need))
        return TESSEL_ERR_LIMIT;
    if (need > c->cap) {
        size_t cap = c->cap ? c->cap : 4096;
        while (cap < need)
            cap *= 2;
        uint32_t *t = realloc(c->tris, cap * 3 * sizeof *t);
        if (!t)
            return TESSEL_ERR_NOMEM;
        c->tris = t;
        c->cap = cap;
    }
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
    tessel_triangle_sink sink = {collect_emit, &c};
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
