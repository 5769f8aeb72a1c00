/* Robust smoothing of noisy point clouds: the projection operator Q of
 * Mederos, Velho & de Figueiredo, "Smooth surface reconstruction from noisy
 * clouds" (2003), section 2.1 (details in their "Robust smoothing of noisy
 * point clouds", 2004). A point p moves to Q(p) = p + t* n*, where the plane
 * through p + t n with unit normal n minimises
 *     sum over neighbours q of rho(h_q) w(|q - p|),   h_q = n.(q - p) - t,
 * rho(x) = 1 - exp(-x^2 / 2 sigma_rho^2) (a robust error norm: a point far
 * from the plane costs at most 1, so it cannot drag the plane) and
 * w(x) = exp(-x^2 / 2 sigma_w^2) (locality). Setting the gradient to zero
 * gives a weighted least-squares problem with weights
 * w(|q - p|) exp(-h_q^2 / 2 sigma_rho^2), so we solve it by iteratively
 * reweighted least squares: for fixed weights the best plane passes through
 * the weighted centroid with the normal of the smallest eigenvalue of the
 * weighted covariance (weighted PCA), and t is the weighted mean height.
 * The first plane is the one with the Gaussian weights alone.
 *
 * Beyond the paper (params.quadric, on by default): Q(p) is the foot point
 * on the robust plane lifted by the height of a weighted least-squares
 * quadric fitted over that plane with the same robust weights, which
 * removes most of the plane's shrinkage on curved parts (docs/smooth.md).
 *
 * Neighbours: the k nearest points within 3 sigma_w (beyond it w < 1.1%).
 * Arbitrary points (tessel_project) find them with the kd-tree. The first
 * smoothing pass, where the queries are the cloud itself, sorts the points
 * into a grid of cells a little wider than the distance to the k-th
 * neighbour and serves all points of a cell from the same 27 cells (more
 * rings of cells for the rare point whose neighbours reach farther): the
 * same neighbours as the kd-tree, at a fraction of the cost. Where the
 * density is far above the mean the cells are sized for (the near field
 * of a range scan), a cell's 27 would hold thousands of points and the
 * kd-tree answers its points instead. Later passes
 * reuse those neighbours at their new positions and take one more IRLS
 * step from the previous pass's normal (with the quadric: its height over
 * the plane across that normal, and its own normal at the point). Every
 * output position depends only on the previous pass's positions, so points
 * are independent: OpenMP loops with per-point output slots give the same
 * bits for any thread count. */
#include "core/grid.h"
#include "smooth/smooth.h"

#include <stdlib.h>
#include <string.h>

tessel_smooth_params tessel_smooth_params_default(void)
{
    tessel_smooth_params p;
    memset(&p, 0, sizeof p);
    p.k = 30;
    p.sigma_rho = 2.0;
    p.sigma_w = 3.0;
    p.passes = 2;
    p.max_iterations = 20;
    p.tolerance = 1e-2;
    p.min_neighbors = 6;
    p.spacing = 0.0;
    p.threads = 0;
    p.quadric = 1;
    p.sigma_rho_later = 1.0;
    p.aggregate = 0;
    p.exclude_self = 0;
    return p;
}

tessel_status tsl_smooth_check_params(const tessel_smooth_params *p)
{
    if (p->k < 3 || p->k > SMOOTH_MAX_K)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->sigma_rho > 0.0) || !isfinite(p->sigma_rho) || !(p->sigma_w > 0.0) ||
        !isfinite(p->sigma_w))
        return TESSEL_ERR_INVALID_ARG;
    if (p->passes < 1 || p->passes > 100)
        return TESSEL_ERR_INVALID_ARG;
    if (p->max_iterations < 1 || p->max_iterations > 1000)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->tolerance > 0.0) || !isfinite(p->tolerance))
        return TESSEL_ERR_INVALID_ARG;
    if (p->min_neighbors < 3 || p->min_neighbors > p->k)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->spacing >= 0.0) || !isfinite(p->spacing))
        return TESSEL_ERR_INVALID_ARG;
    if (p->quadric != 0 && p->quadric != 1)
        return TESSEL_ERR_INVALID_ARG;
    if (p->aggregate != 0 && p->aggregate != 1)
        return TESSEL_ERR_INVALID_ARG;
    if (p->exclude_self != 0 && p->exclude_self != 1)
        return TESSEL_ERR_INVALID_ARG;
    if (!(p->sigma_rho_later > 0.0) || !isfinite(p->sigma_rho_later))
        return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

/* ---- neighbour search on the grid (src/core/grid.c) ---- */

/* The k nearest within the cut-off, sorted by (distance, index) as the
 * kd-tree orders them. */
typedef struct topk {
    size_t cnt, k;
    float d[SMOOTH_MAX_K];
    uint32_t id[SMOOTH_MAX_K];  /* point index (topk_block leaves it out) */
    uint32_t pos[SMOOTH_MAX_K]; /* sorted position */
} topk;

static inline bool before(float d, uint32_t i, float e, uint32_t j)
{
    return d < e || (d == e && i < j);
}

/* Offers one candidate to t. */
static inline void topk_add(topk *t, float d, uint32_t id, uint32_t pos)
{
    size_t j = t->cnt;
    if (j == t->k) {
        if (!before(d, id, t->d[j - 1], t->id[j - 1]))
            return;
        j--;
    } else {
        t->cnt++;
    }
    while (j > 0 && before(d, id, t->d[j - 1], t->id[j - 1])) {
        t->d[j] = t->d[j - 1];
        t->id[j] = t->id[j - 1];
        t->pos[j] = t->pos[j - 1];
        j--;
    }
    t->d[j] = d;
    t->id[j] = id;
    t->pos[j] = pos;
}

static inline float dist2(const float *p, const float *q)
{
    float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

/* Offers every point of the runs to t. */
static void topk_scan(topk *t, const tsl_grid *g, const float *q, const uint32_t *run,
                      size_t nrun, float r2max)
{
    for (size_t r = 0; r < nrun; r++)
        for (uint32_t s = run[2 * r]; s < run[2 * r + 1]; s++) {
            float d = dist2(g->sxyz + 3 * (size_t)s, q);
            if (d <= r2max)
                topk_add(t, d, g->perm[s], s);
        }
}

/* Offers to t every point of the cells at Chebyshev distance ring (>= 2)
 * from cell cc that can still hold one of the k nearest. */
typedef struct ring_scan {
    topk *t;
    const tsl_grid *g;
    const float *q;
    float r2max;
} ring_scan;

static void ring_cell(void *ctx, int64_t x, int64_t y, int64_t z)
{
    ring_scan *c = ctx;
    topk *t = c->t;
    float worst = t->cnt == t->k ? t->d[t->cnt - 1] : c->r2max;
    if (tsl_grid_box_d2(c->g, c->q, x, y, z) > worst)
        return;
    size_t ci = tsl_grid_find(c->g, tsl_morton((uint32_t)x, (uint32_t)y, (uint32_t)z));
    if (ci == SIZE_MAX)
        return;
    uint32_t run[2] = {c->g->start[ci], c->g->start[ci + 1]};
    topk_scan(t, c->g, c->q, run, 1, c->r2max);
}

static void topk_ring(topk *t, const tsl_grid *g, const float *q, const uint32_t cc[3],
                      int64_t ring, float r2max)
{
    ring_scan c = {t, g, q, r2max};
    tsl_grid_shell(g, cc, ring, ring_cell, &c);
}

/* The candidates of one cell (its 27-cell block) copied side by side, so
 * that the distances of a query to all of them vectorise. */
#define BLOCK_CAP 1024u
typedef struct block {
    size_t m;
    float x[BLOCK_CAP], y[BLOCK_CAP], z[BLOCK_CAP];
    uint32_t pos[BLOCK_CAP];
    /* Squared distances to the current query as their bit patterns, which
     * order like the (non-negative) values and compare as integers, which
     * vectorises where float comparisons do not (GCC keeps a branch for
     * them under -ftrapping-math). */
    int32_t d[BLOCK_CAP + 8];  /* padded with +infinity */
    int32_t cd[BLOCK_CAP + 8]; /* those of the candidates, padded */
    int16_t cq[BLOCK_CAP + 8];   /* the same, quantised to 16 bits */
    int16_t rank[BLOCK_CAP + 8]; /* candidates before each */
    uint32_t cj[BLOCK_CAP];  /* candidates' block slots */
    uint64_t sel[BLOCK_CAP]; /* candidates sorted as (distance, slot) */
} block;

static inline uint32_t float_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

/* Point index of a selection key's block slot. */
static inline uint32_t block_id(const block *b, const tsl_grid *g, uint64_t key)
{
    return g->perm[b->pos[(uint32_t)key]];
}

/* Number of the first m (rounded up to 8) values <= thr: eight partial
 * counts, which vectorise. */
static inline size_t count_below(const int32_t *d, size_t m, int32_t thr)
{
    uint32_t c[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (size_t j0 = 0; j0 < m; j0 += 8)
        for (int l = 0; l < 8; l++)
            c[l] += (uint32_t)(d[j0 + (size_t)l] <= thr);
    return (size_t)c[0] + c[1] + c[2] + c[3] + c[4] + c[5] + c[6] + c[7];
}

/* Block slots whose distance bits are <= tb, into b->cj; returns their
 * number. Eight at a time: groups with none below (whole cells away from
 * the query) are skipped; within a group, branch-free (always store,
 * advance when it passes). */
static inline size_t block_select(block *b, size_t m, int32_t tb)
{
    size_t ns = 0;
    for (size_t j0 = 0; j0 < m; j0 += 8) {
        if (count_below(b->d + j0, 8, tb) == 0)
            continue;
        for (size_t j = j0; j < j0 + 8; j++) {
            b->cj[ns] = (uint32_t)j;
            ns += b->d[j] <= tb;
        }
    }
    return ns;
}

/* The k nearest of the block within r2max. A threshold that admits a
 * little more than k candidates (from the previous query's k-th distance,
 * *guess) picks a few; they are sorted as 64-bit keys (distance bits, which
 * order like the distances since they are >= 0, then block slot), equal
 * distances reordered by point index, and the first k kept. */
TSL_CLONES static void topk_block(topk *t, block *b, const tsl_grid *g, const float *q,
                                  float r2max, float *guess)
{
    const size_t m = b->m;
    const float qx = q[0], qy = q[1], qz = q[2];
    float thr = *guess < r2max ? *guess : r2max;
    /* k or more copies of one point make the k-th distance 0: the guess
     * from such a query, and the halving below, must stop above 0, or the
     * loops never end (they hung on such clouds). A 64th of a cell's
     * square is far below any k-th distance the cells are sized for, and
     * the selection is exact whatever the threshold. */
    const float least = (float)(g->c * g->c) * (1.0f / 64.0f);
    if (thr < least)
        thr = least < r2max ? least : r2max;
    for (size_t j = 0; j < m; j++) {
        float dx = b->x[j] - qx, dy = b->y[j] - qy, dz = b->z[j] - qz;
        float d = (dx * dx + dy * dy) + dz * dz;
        memcpy(&b->d[j], &d, sizeof d);
    }
    const int32_t inf_bits = 0x7f800000;
    for (size_t j = m; j < ((m + 7) & ~(size_t)7); j++)
        b->d[j] = inf_bits;
    /* A threshold that admits at least k (or all within the cut-off) and,
     * for the sort below, not many more. */
    size_t ns;
    bool shrunk = false;
    for (;;) {
        ns = block_select(b, m, (int32_t)float_bits(thr));
        if (ns < t->k && thr < r2max) {
            thr = thr * 1.15f < r2max ? thr * 1.15f : r2max;
            continue;
        }
        if (ns > 2 * t->k + 16 && !shrunk) {
            /* Far too many for the sort: halve while k remain. */
            shrunk = true;
            float half = 0.5f * thr;
            bool smaller = false;
            while (half >= least && count_below(b->d, m, (int32_t)float_bits(half)) >= t->k)
                thr = half, half *= 0.5f, smaller = true;
            if (smaller)
                continue;
        }
        break;
    }
    /* Sort by rank: candidate i goes to the number of candidates before it
     * in (distance, slot) order. Quadratic, but branch-free and vectorised,
     * and ns is only a little more than k. */
    size_t np = (ns + 7) & ~(size_t)7;
    for (size_t i = 0; i < ns; i++)
        b->cd[i] = b->d[b->cj[i]];
    for (size_t i = ns; i < np; i++)
        b->cd[i] = inf_bits;
    /* The ranks are counted on 16-bit quantised distances (monotonic, so
     * they order as the distances except within a quantum): eight to a
     * vector instead of four. Candidates that share a quantum share a rank,
     * which sends the rare query with such a pair (or an exact tie) to the
     * exact count below. */
    const float scale = 65000.0f / thr;
    for (size_t i = 0; i < np; i++) {
        float d;
        memcpy(&d, &b->cd[i], sizeof d);
        float qv = d * scale;
        b->cq[i] = (int16_t)((int32_t)(qv < 65000.0f ? qv : 65535.0f) - 32768);
    }
    memset(b->sel, 0xff, ns * sizeof *b->sel); /* no key: NaN distance bits */
    memset(b->rank, 0, np * sizeof *b->rank);
    size_t jr = 0;
    for (; jr + 4 <= ns; jr += 4) { /* four at a time: fewer loads and stores */
        const int16_t q0 = b->cq[jr], q1 = b->cq[jr + 1], q2 = b->cq[jr + 2];
        const int16_t q3 = b->cq[jr + 3];
        for (size_t i = 0; i < np; i++) {
            int16_t c = b->cq[i];
            b->rank[i] = (int16_t)(b->rank[i] + (q0 < c) + (q1 < c) + (q2 < c) + (q3 < c));
        }
    }
    for (; jr < ns; jr++) {
        const int16_t qj = b->cq[jr];
        for (size_t i = 0; i < np; i++)
            b->rank[i] = (int16_t)(b->rank[i] + (qj < b->cq[i]));
    }
    bool tie = false;
    for (size_t i = 0; i < ns; i++) {
        uint32_t r = (uint32_t)b->rank[i];
        tie |= b->sel[r] != UINT64_MAX;
        b->sel[r] = (uint64_t)(uint32_t)b->cd[i] << 32 | b->cj[i];
    }
    if (tie) { /* equal distances share a rank: count earlier equals too */
        for (size_t i = 0; i < ns; i++) {
            const int32_t di = b->cd[i];
            uint32_t r = 0;
            for (size_t j = 0; j < ns; j++)
                r += b->cd[j] < di || (b->cd[j] == di && j < i);
            b->sel[r] = (uint64_t)(uint32_t)di << 32 | b->cj[i];
        }
    }
    size_t keep = ns < t->k ? ns : t->k;
    if (keep > 0 && tie) {
        /* Equal distances go in point-index order (rare): within runs that
         * are kept whole, and at the cut, where the run [a, end) gives its
         * smallest indices to the slots up to keep. */
        uint64_t dk = b->sel[keep - 1] >> 32;
        size_t a = keep - 1, end = keep;
        while (a > 0 && b->sel[a - 1] >> 32 == dk)
            a--;
        while (end < ns && b->sel[end] >> 32 == dk)
            end++;
        for (size_t i = 1; i < a; i++)
            for (size_t j = i; j > 0 && b->sel[j] >> 32 == b->sel[j - 1] >> 32 &&
                               block_id(b, g, b->sel[j]) < block_id(b, g, b->sel[j - 1]);
                 j--) {
                uint64_t v = b->sel[j];
                b->sel[j] = b->sel[j - 1], b->sel[j - 1] = v;
            }
        for (size_t i = a; i < keep && end - a > 1; i++) {
            size_t best = i;
            for (size_t j = i + 1; j < end; j++)
                if (block_id(b, g, b->sel[j]) < block_id(b, g, b->sel[best]))
                    best = j;
            uint64_t v = b->sel[i];
            b->sel[i] = b->sel[best], b->sel[best] = v;
        }
    }
    for (size_t i = 0; i < keep; i++) {
        uint32_t j = (uint32_t)b->sel[i], bits = (uint32_t)(b->sel[i] >> 32);
        t->pos[i] = b->pos[j];
        memcpy(&t->d[i], &bits, sizeof(float));
    }
    t->cnt = keep;
    /* Next query: a little above this k-th distance. */
    if (keep > 0)
        *guess = t->d[keep - 1] * 1.12f;
}

/* ---- smoothing passes ---- */

/* Points per progress report / cancellation check (at least). */
#define SMOOTH_CHUNK ((size_t)1 << 18)

/* One smoothing run. Everything is indexed by sorted position (the grid's
 * order: points of a cell side by side, cells in Morton order), so that
 * the neighbours of nearby points are nearby in memory. */
typedef struct pass_ctx {
    const fit_ctl *f;
    const tsl_grid *g;
    const float *cur_xyz;  /* positions this pass reads, by sorted position */
    const float *ref_nrm;  /* orientation reference by sorted position, or
                              NULL */
    int has_viewpoint;
    double viewpoint[3];
    float *out_xyz, *out_nrm;
    uint32_t *nb;  /* k neighbour slots (sorted positions) per point */
    uint16_t *cnt; /* neighbours per point */
    fit_surface *surf; /* each point's fitted surface (params.aggregate), or
                          NULL */
    struct crowd *crowd; /* for crowded blocks */
} pass_ctx;

typedef struct pass_count {
    size_t unfit, unconverged;
    uint64_t iterations;
} pass_count;

static void count_fit(pass_count *c, bool fit, uint32_t its, uint32_t max_iterations)
{
    if (!fit) {
        c->unfit++;
    } else {
        c->iterations += its;
        c->unconverged += its >= max_iterations;
    }
}

/* Records point s's neighbours t (sorted positions, for the later passes)
 * and smooths it. */
static inline void fit_first(const pass_ctx *x, fit_buf *fb, uint32_t s, const topk *t,
                             pass_count *pc)
{
    const tsl_grid *g = x->g;
    const fit_ctl *f = x->f;
    const float *q = g->sxyz + 3 * (size_t)s;
    for (size_t j = 0; j < t->cnt; j++) {
        const float *p = g->sxyz + 3 * (size_t)t->pos[j];
        fb->x[j] = p[0] - q[0];
        fb->y[j] = p[1] - q[1];
        fb->z[j] = p[2] - q[2];
    }
    if (x->nb) {
        memcpy(x->nb + (size_t)s * f->k, t->pos, t->cnt * sizeof *x->nb);
        x->cnt[s] = (uint16_t)t->cnt;
    }
    fb->m = fb->filled = t->cnt;
    uint32_t its;
    const float *nn = x->ref_nrm && t->cnt ? x->ref_nrm + 3 * (size_t)t->pos[0] : NULL;
    bool fit = tsl_smooth_solve_one(f, q, fb, NULL, nn, x->has_viewpoint, x->viewpoint,
                         x->out_xyz + 3 * (size_t)s, x->out_nrm + 3 * (size_t)s, &its,
                         x->surf ? x->surf + s : NULL);
    count_fit(pc, fit, its, f->max_iterations);
}

/* For crowded blocks: a kd-tree over the cloud and each point's sorted
 * position, built by the first thread that meets one. A random sample's
 * fullest cell often passes the bound that makes a crowded block possible
 * (27 times it over BLOCK_CAP) while no block is crowded: 10^6 points on a
 * torus have cells of up to 38 points and none of their blocks over 1024,
 * and building the tree anyway cost a tenth of the pass. */
typedef struct crowd {
    const float *xyz; /* the cloud */
    const tsl_grid *g;
    tessel_index *index;
    uint32_t *pos_of;
    tessel_status st; /* of the build */
} crowd;

static tessel_status crowd_build(crowd *c)
{
    size_t n = c->g->n;
    tessel_status st = tessel_index_build(&c->index, c->xyz, n);
    if (st != TESSEL_OK)
        return st;
    if (!(c->pos_of = tsl_alloc_array(n ? n : 1, sizeof *c->pos_of)))
        return TESSEL_ERR_NOMEM;
    for (size_t s = 0; s < n; s++)
        c->pos_of[c->g->perm[s]] = (uint32_t)s;
    return TESSEL_OK;
}

/* True once the tree is there; false if building it failed (c->st). */
static bool crowd_ready(crowd *c)
{
    bool ok;
#pragma omp critical(tsl_smooth_crowd)
    {
        if (!c->pos_of && c->st == TESSEL_OK)
            c->st = crowd_build(c);
        ok = c->st == TESSEL_OK;
    }
    return ok;
}

/* The points of a crowded cell: their k nearest within the cut-off from
 * the kd-tree, which returns them in the same order as the grid search. */
static void crowded_cell(const pass_ctx *x, fit_buf *fb, size_t ci, pass_count *pc)
{
    const tsl_grid *g = x->g;
    if (!crowd_ready(x->crowd))
        return; /* the pass reports x->crowd->st */
    const float r2max = (float)(x->f->rmax * x->f->rmax);
    topk t;
    t.k = x->f->k;
    for (uint32_t s = g->start[ci]; s < g->start[ci + 1]; s++) {
        size_t got =
            tessel_index_knn(x->crowd->index, g->sxyz + 3 * (size_t)s, t.k, t.id, t.d);
        t.cnt = 0;
        while (t.cnt < got && t.d[t.cnt] <= r2max) {
            t.pos[t.cnt] = x->crowd->pos_of[t.id[t.cnt]];
            t.cnt++;
        }
        fit_first(x, fb, s, &t, pc);
    }
}

/* First pass over the points of cell ci: finds the k nearest neighbours
 * within the cut-off (recorded for the later passes) and smooths. b is
 * scratch. */
TSL_CLONES static void search_cell(const pass_ctx *x, block *b, fit_buf *fb, size_t ci,
                                   pass_count *pc)
{
    const tsl_grid *g = x->g;
    const fit_ctl *f = x->f;
    uint32_t run1[2 * 27];
    size_t n1 = 0;
    topk t;
    const float r2max = (float)(f->rmax * f->rmax);

    uint32_t cc[3];
    const float *first = g->sxyz + 3 * (size_t)g->start[ci];
    for (int a = 0; a < 3; a++)
        cc[a] = tsl_grid_cell(g, first, a);
    n1 = tsl_grid_ring(g, cc, 0, run1, 0);
    n1 = tsl_grid_ring(g, cc, 1, run1, n1);
    size_t m = 0;
    for (size_t r = 0; r < n1; r++)
        m += run1[2 * r + 1] - run1[2 * r];
    /* A crowded block (density far above the mean the cells are sized
     * for) would cost every query a scan of all its points. */
    if (m > BLOCK_CAP) {
        crowded_cell(x, fb, ci, pc);
        return;
    }
    b->m = 0;
    for (size_t r = 0; r < n1; r++)
        for (uint32_t s = run1[2 * r]; s < run1[2 * r + 1]; s++) {
            const float *p = g->sxyz + 3 * (size_t)s;
            b->x[b->m] = p[0], b->y[b->m] = p[1], b->z[b->m] = p[2];
            b->pos[b->m++] = s;
        }
    float guess = (float)(g->c * g->c);

    for (uint32_t s = g->start[ci]; s < g->start[ci + 1]; s++) {
        const float *q = g->sxyz + 3 * (size_t)s;
        t.cnt = 0;
        t.k = f->k;
        bool ids = false; /* t.id filled (the block leaves it) */
        topk_block(&t, b, g, q, r2max, &guess);
        /* The cells within Chebyshev distance `ring` hold every point
         * within `cover` of q; widen until that reaches the k-th neighbour
         * (or the cut-off). Cells at the grid's border cover everything
         * beyond it. */
        const double slack = 1.0 - 1e-6; /* rounding of the float distances */
        for (int64_t ring = 1;; ring++) {
            double cover = INFINITY;
            for (int a = 0; a < 3; a++) {
                double lo = (int64_t)cc[a] - ring <= 0
                                ? INFINITY
                                : q[a] - (g->origin[a] + ((double)cc[a] - (double)ring) * g->c);
                double hi =
                    (int64_t)cc[a] + ring >= (int64_t)g->dims[a] - 1
                        ? INFINITY
                        : g->origin[a] + ((double)cc[a] + (double)ring + 1.0) * g->c - q[a];
                cover = fmin(cover, fmin(lo, hi));
            }
            double need = t.cnt < t.k ? f->rmax : fmin(sqrt((double)t.d[t.cnt - 1]), f->rmax);
            if (need < cover * slack)
                break;
            if (!ids) { /* the ring's candidates compare by point index too */
                for (size_t j = 0; j < t.cnt; j++)
                    t.id[j] = g->perm[t.pos[j]];
                ids = true;
            }
            topk_ring(&t, g, q, cc, ring + 1, r2max);
        }
        fit_first(x, fb, s, &t, pc);
    }
}

/* A later pass for sorted positions [s0, s1): the first pass's neighbours
 * at their current positions. */
TSL_CLONES static void refit_range(const pass_ctx *x, fit_buf *fb, size_t s0, size_t s1,
                                   pass_count *pc)
{
    const fit_ctl *f = x->f;
    const float *cur = x->cur_xyz;
    for (size_t s = s0; s < s1; s++) {
        const float *q = cur + 3 * s;
        const uint32_t *nb = x->nb + s * f->k;
        size_t m = x->cnt[s];
        for (size_t j = 0; j < m; j++) {
            const float *p = cur + 3 * (size_t)nb[j];
            fb->x[j] = p[0] - q[0];
            fb->y[j] = p[1] - q[1];
            fb->z[j] = p[2] - q[2];
        }
        fb->m = fb->filled = m;
        uint32_t its;
        const float *nn = x->ref_nrm && m ? x->ref_nrm + 3 * (size_t)nb[0] : NULL;
        bool fit = tsl_smooth_solve_one(f, q, fb, x->ref_nrm + 3 * s, nn, x->has_viewpoint, x->viewpoint,
                             x->out_xyz + 3 * s, x->out_nrm + 3 * s, &its,
                             x->surf ? x->surf + s : NULL);
        count_fit(pc, fit, its, f->max_iterations);
    }
}

/* Beyond the paper (params.aggregate): after a pass, each fitted point
 * moves to the weighted mean of its projections (along each surface's
 * normal) onto the surfaces fitted at its neighbours and at itself, with
 * weights exp(-d^2 / 2 (AGG_SIGMA h)^2), d its distance from that fit's
 * origin; its normal becomes the same weighted mean of the fits' normals
 * (each at its own origin: a normal extrapolated by the fitted curvature
 * is noisier, measured on a small noisy sphere). In its own fit a point's
 * own noise has the largest leverage (docs/smooth.md, "Limits"); its
 * neighbours' fits weigh it less, so the mean keeps less of it, as
 * patch-based image denoisers average their overlapping patch estimates.
 * The point reads the pass's fit origins and surfaces and writes only its
 * own position and normal: in place, for any order of points. 1.5 h
 * measured best of 1.5, 2 and 3 h on the noisy scans. */
#define AGG_SIGMA 1.5

TSL_CLONES static void aggregate_range(const pass_ctx *x, fit_buf *b, size_t s0, size_t s1)
{
    const fit_ctl *f = x->f;
    const float inv_2s2 = (float)(1.0 / (2.0 * AGG_SIGMA * AGG_SIGMA * f->h * f->h));
    /* Scratch from the fit buffer: per surface the exponent of its weight,
     * the point's move onto it and its normal; then the weights, the
     * weighted normals and the sums, over FIT_LANES lanes in a fixed
     * order. */
    float *e = b->ew, *w = b->om, *y[3] = {b->x, b->y, b->z}, *nm[3] = {b->t[0], b->t[1], b->t[2]};
    for (size_t s = s0; s < s1; s++) {
        if (isnan(x->surf[s].t))
            continue; /* unfit points stay */
        float *p = x->out_xyz + 3 * s, *pn = x->out_nrm + 3 * s;
        const uint32_t *nb = x->nb + s * f->k;
        size_t m = 0;
        for (size_t i = 0; i < x->cnt[s]; i++) {
            const fit_surface *sf = x->surf + nb[i];
            if (isnan(sf->t))
                continue;
            const float *o = x->cur_xyz + 3 * (size_t)nb[i];
            float d[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
            float ex = -(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * inv_2s2;
            e[m] = ex > EXP_MIN ? ex : EXP_MIN;
            float u = sf->e1[0] * d[0] + sf->e1[1] * d[1] + sf->e1[2] * d[2];
            float v = sf->e2[0] * d[0] + sf->e2[1] * d[1] + sf->e2[2] * d[2];
            float z = sf->n[0] * d[0] + sf->n[1] * d[1] + sf->n[2] * d[2];
            const float *c = sf->c;
            float lift = sf->t + c[0] * u * u + c[1] * u * v + c[2] * v * v + c[3] * u +
                         c[4] * v + c[5] - z;
            for (int a = 0; a < 3; a++) {
                y[a][m] = lift * sf->n[a]; /* the move onto this surface */
                nm[a][m] = sf->normal[a];
            }
            m++;
        }
        if (m == 0)
            continue;
        size_t mp = (m + FIT_LANES - 1) / FIT_LANES * FIT_LANES;
        for (size_t j = m; j < mp; j++) {
            e[j] = EXP_MIN;
            for (int a = 0; a < 3; a++)
                y[a][j] = nm[a][j] = 0.0f;
        }
        for (size_t j = 0; j < mp; j++)
            w[j] = j < m ? fast_exp(e[j]) : 0.0f;
        /* Weighted normals, whose sign follows the point's (the surfaces
         * are unoriented). */
        for (size_t j = 0; j < mp; j++) {
            float gx = nm[0][j], gy = nm[1][j], gz = nm[2][j];
            float r = gx * pn[0] + gy * pn[1] + gz * pn[2] < 0.0f ? -w[j] : w[j];
            nm[0][j] = r * gx, nm[1][j] = r * gy, nm[2][j] = r * gz;
        }
        double W = lane_sum(w, mp), dy[3], nacc[3];
        for (int a = 0; a < 3; a++) {
            dy[a] = lane_dot(w, y[a], mp);
            nacc[a] = lane_sum(nm[a], mp);
        }
        double nl = sqrt(nacc[0] * nacc[0] + nacc[1] * nacc[1] + nacc[2] * nacc[2]);
        if (!(W > 0.0) || !(nl > 0.0))
            continue;
        for (int a = 0; a < 3; a++) {
            p[a] = (float)(p[a] + dy[a] / W);
            pn[a] = (float)(nacc[a] / nl);
        }
    }
}

/* The smoothed cloud res (positions and normals already in the grid's
 * order) takes the grid's order for the input's colours and organized
 * grid too; pos[i] is input point i's place. */
static void to_grid_order(tessel_cloud *res, const tessel_cloud *cloud, const tsl_grid *g,
                          const uint32_t *pos)
{
    size_t n = cloud->count;
    if (res->rgb)
        for (size_t s = 0; s < n; s++)
            memcpy(res->rgb + 3 * s, cloud->rgb + 3 * (size_t)g->perm[s], 3);
    if (res->grid) {
        size_t cells = (size_t)res->width * res->height;
        for (size_t c = 0; c < cells; c++)
            if (res->grid[c] != TESSEL_NONE)
                res->grid[c] = pos[res->grid[c]];
    }
}

tessel_status tessel_smooth(const tessel_cloud *cloud, tessel_cloud *out,
                            const tessel_smooth_params *params,
                            const tessel_callbacks *callbacks, tessel_smooth_stats *stats)
{
    double unused;
    return tsl_smooth_timed(cloud, out, params, callbacks, stats, false, &unused);
}

/* The grid comes first: when h is not given, its cells find the nearest
 * neighbours that measure it (tessel_cloud_spacing's value, without
 * building a kd-tree). Cells a little wider than the distance to the k-th
 * neighbour, at most the cut-off 3 sigma_w h. */
static tessel_status grid_and_spacing(const tessel_cloud *cloud, const tessel_smooth_params *p,
                                      int threads, tsl_grid *g, double *h_out,
                                      double *seconds_spacing)
{
    size_t n = cloud->count;
    double h = p->spacing, cell = tsl_grid_knn_cell(cloud->xyz, n, p->k);
    if (h > 0.0)
        cell = fmin(cell, 3.0 * p->sigma_w * h);
    tessel_status st = tsl_grid_build(g, cloud->xyz, n, cell, threads);
    if (st == TESSEL_OK && !(h > 0.0)) {
        double t0 = tsl_seconds();
        st = tsl_grid_spacing(g, cloud->xyz, n, threads, &h);
        if (st == TESSEL_OK && !isfinite(h))
            st = TESSEL_ERR_TOO_FEW_POINTS; /* no scale to smooth at */
        if (st == TESSEL_OK && g->c > 3.0 * p->sigma_w * h) {
            tsl_grid_free(g);
            st = tsl_grid_build(g, cloud->xyz, n, 3.0 * p->sigma_w * h, threads);
        }
        *seconds_spacing = tsl_seconds() - t0;
    }
    *h_out = h;
    return st;
}

/* What the passes read and write, by sorted position. */
typedef struct pass_bufs {
    float *buf[4];      /* xyz a, xyz b, normals a, b: passes alternate */
    uint32_t *nb;       /* neighbour lists, for later passes and aggregation */
    uint16_t *cnt;
    float *ref0;        /* the input's normals, when it has some */
    fit_surface *surf;  /* params.aggregate */
} pass_bufs;

static void bufs_free(pass_bufs *b)
{
    for (int i = 0; i < 4; i++)
        free(b->buf[i]);
    free(b->nb);
    free(b->cnt);
    free(b->ref0);
    free(b->surf);
    memset(b, 0, sizeof *b);
}

static tessel_status bufs_alloc(const tessel_cloud *cloud, const tessel_smooth_params *p,
                                const tsl_grid *g, pass_bufs *b)
{
    size_t n = cloud->count;
    memset(b, 0, sizeof *b);
    tessel_status st = TESSEL_OK;
    for (int i = 0; i < 4; i++)
        if (!(b->buf[i] = tsl_alloc_array(n, 3 * sizeof(float))))
            st = TESSEL_ERR_NOMEM;
    /* The neighbour lists serve later passes and the aggregation only
     * (one pass, as the noisy pipeline runs, writes 120 bytes per point
     * less). */
    bool keep_nb = p->passes > 1 || p->aggregate;
    if (keep_nb) {
        b->nb = tsl_alloc_array(n, (size_t)p->k * sizeof *b->nb);
        b->cnt = tsl_alloc_array(n, sizeof *b->cnt);
    }
    if (p->aggregate)
        b->surf = tsl_alloc_array(n, sizeof *b->surf);
    if ((keep_nb && (!b->nb || !b->cnt)) || (p->aggregate && !b->surf))
        st = TESSEL_ERR_NOMEM;
    if (st == TESSEL_OK && cloud->normals) {
        if (!(b->ref0 = tsl_alloc_array(n, 3 * sizeof(float))))
            return TESSEL_ERR_NOMEM;
        for (size_t s = 0; s < n; s++)
            memcpy(b->ref0 + 3 * s, cloud->normals + 3 * (size_t)g->perm[s], 3 * sizeof(float));
    }
    return st;
}

/* One smoothing pass, chunk by chunk (progress between chunks). Pass 1:
 * the neighbour search on the input and the paper's operator (the
 * projector's bits); later passes: the same neighbours, moved. */
static tessel_status run_pass(pass_ctx *x, const tsl_grid *g, uint32_t pass, uint32_t passes,
                              int threads, const tessel_callbacks *callbacks, pass_count *total)
{
    size_t n = g->n, c0 = 0, s0 = 0;
    (void)threads;
    for (;;) {
        size_t c1 = c0, s1 = s0;
        if (pass == 0) {
            if (c0 >= g->ncell)
                break;
            c1 = c0 + 1;
            while (c1 < g->ncell && g->start[c1] - g->start[c0] < SMOOTH_CHUNK)
                c1++;
            s0 = g->start[c0];
        } else {
            if (s0 >= n)
                break;
            s1 = s0 + SMOOTH_CHUNK < n ? s0 + SMOOTH_CHUNK : n;
        }
        tessel_status st =
            tsl_progress(callbacks, "smooth", ((double)pass + (double)s0 / (double)n) / passes);
        if (st != TESSEL_OK)
            return st;
        size_t c_unfit = 0, c_unconv = 0;
        uint64_t c_iter = 0;
        /* Integer reductions only: the sums do not depend on the order. */
#pragma omp parallel num_threads(threads) reduction(+ : c_unfit, c_unconv, c_iter)
        {
            block b; /* per-thread scratch, ~20 KB */
            fit_buf fb;
            pass_count pc = {0, 0, 0};
            b.m = 0;
            if (pass == 0) {
#pragma omp for schedule(dynamic, 16)
                for (size_t ci = c0; ci < c1; ci++)
                    search_cell(x, &b, &fb, ci, &pc);
            } else {
#pragma omp for schedule(dynamic, 1)
                for (size_t s = s0; s < s1; s += 256)
                    refit_range(x, &fb, s, s + 256 < s1 ? s + 256 : s1, &pc);
            }
            c_unfit += pc.unfit;
            c_unconv += pc.unconverged;
            c_iter += pc.iterations;
        }
        if (x->crowd->st != TESSEL_OK)
            return x->crowd->st;
        total->unfit += c_unfit;
        total->unconverged += c_unconv;
        total->iterations += c_iter;
        c0 = c1;
        s0 = pass == 0 ? s0 : s1;
    }
    if (x->surf) {
#pragma omp parallel num_threads(threads)
        {
            fit_buf fb;
#pragma omp for schedule(dynamic, 1)
            for (size_t s = 0; s < n; s += 4096)
                aggregate_range(x, &fb, s, s + 4096 < n ? s + 4096 : n);
        }
    }
    return TESSEL_OK;
}

/* The result: the input's other attributes, and the last pass's positions
 * and normals (xyz, nrm by sorted position) back in the input's order, or,
 * with grid_order, as they are with the colours and the organized grid in
 * the grid's order (*pos: each input point's place). The input's
 * positions and normals are not copied. The last pass's buffers are taken
 * (set to NULL) when the result uses them as they are. */
static tessel_status make_result(const tessel_cloud *cloud, const tsl_grid *g, float **xyz,
                                 float **nrm, bool grid_order, int threads, tessel_cloud *res,
                                 uint32_t **pos)
{
    size_t n = cloud->count;
    (void)threads;
    tessel_cloud rest = *cloud;
    rest.xyz = rest.normals = NULL;
    tessel_status st = tessel_cloud_copy(res, &rest);
    if (st != TESSEL_OK)
        return st;
    if (grid_order) {
        res->xyz = *xyz;
        res->normals = *nrm;
        *xyz = *nrm = NULL;
        if (!(*pos = tsl_alloc_array(n, sizeof **pos)))
            return TESSEL_ERR_NOMEM;
        for (size_t s = 0; s < n; s++)
            (*pos)[g->perm[s]] = (uint32_t)s;
        to_grid_order(res, cloud, g, *pos);
        return TESSEL_OK;
    }
    res->xyz = tsl_alloc_array(n, 3 * sizeof(float));
    res->normals = tsl_alloc_array(n, 3 * sizeof(float));
    if (!res->xyz || !res->normals)
        return TESSEL_ERR_NOMEM;
    /* perm is a permutation: every thread writes its own slots. */
#pragma omp parallel for num_threads(threads) schedule(static)
    for (size_t s = 0; s < n; s++) {
        size_t i = g->perm[s];
        memcpy(res->xyz + 3 * i, *xyz + 3 * s, 3 * sizeof(float));
        memcpy(res->normals + 3 * i, *nrm + 3 * s, 3 * sizeof(float));
    }
    return TESSEL_OK;
}

/* The displacements and the fits' counts; serial, so the floating-point
 * sums do not depend on the thread count. */
static void fill_stats(const tessel_cloud *cloud, const tessel_cloud *res, const uint32_t *pos,
                       const tessel_smooth_params *p, double h, const pass_count *total,
                       tessel_smooth_stats *stats)
{
    size_t n = cloud->count;
    double sum2 = 0.0, mx = 0.0;
    for (size_t i = 0; i < n; i++) {
        double u[3], v[3], e[3];
        tsl_load(cloud->xyz + 3 * i, u);
        tsl_load(res->xyz + 3 * (pos ? (size_t)pos[i] : i), v);
        tsl_sub(u, v, e);
        double d2 = tsl_dot(e, e);
        sum2 += d2;
        mx = d2 > mx ? d2 : mx;
    }
    size_t fitted = (size_t)p->passes * n - total->unfit;
    stats->spacing = h;
    stats->unfit = total->unfit;
    stats->unconverged = total->unconverged;
    stats->mean_iterations = fitted ? (double)total->iterations / (double)fitted : 0.0;
    stats->rms_displacement = sqrt(sum2 / (double)n);
    stats->max_displacement = sqrt(mx);
}

/* The smoothing: the grid and the spacing, the passes, the result. */
tessel_status tsl_smooth_timed(const tessel_cloud *cloud, tessel_cloud *out,
                               const tessel_smooth_params *params,
                               const tessel_callbacks *callbacks, tessel_smooth_stats *stats,
                               bool grid_order, double *seconds_spacing)
{
    *seconds_spacing = 0.0;
    if (!out)
        return TESSEL_ERR_INVALID_ARG;
    memset(out, 0, sizeof *out);
    if (stats)
        memset(stats, 0, sizeof *stats);
    tessel_smooth_params p = params ? *params : tessel_smooth_params_default();
    tessel_status st = tsl_smooth_check_params(&p);
    if (st == TESSEL_OK)
        st = tsl_smooth_check_cloud(cloud);
    if (st != TESSEL_OK)
        return st;

    int threads = tsl_threads(p.threads);
    tsl_grid g;
    memset(&g, 0, sizeof g);
    double h;
    pass_bufs b;
    memset(&b, 0, sizeof b);
    crowd cw;
    memset(&cw, 0, sizeof cw);
    tessel_cloud res;
    memset(&res, 0, sizeof res);
    uint32_t *pos = NULL;
    if ((st = grid_and_spacing(cloud, &p, threads, &g, &h, seconds_spacing)) != TESSEL_OK ||
        (st = bufs_alloc(cloud, &p, &g, &b)) != TESSEL_OK)
        goto done;

    fit_ctl f_first, f_later;
    tsl_smooth_ctl_setup(&f_first, &p, h, p.sigma_rho);
    tsl_smooth_ctl_setup(&f_later, &p, h, p.sigma_rho_later);
    f_later.ridge = 0.0; /* see QUAD_RIDGE */
    pass_ctx x;
    memset(&x, 0, sizeof x);
    x.g = &g;
    x.nb = b.nb;
    x.cnt = b.cnt;
    x.surf = b.surf;
    x.crowd = &cw;
    if (cloud->has_viewpoint) {
        x.has_viewpoint = 1;
        for (int i = 0; i < 3; i++)
            x.viewpoint[i] = cloud->viewpoint[i] - cloud->offset[i];
    }
    cw.xyz = cloud->xyz;
    cw.g = &g;
    pass_count total = {0, 0, 0};
    for (uint32_t pass = 0; pass < p.passes && st == TESSEL_OK; pass++) {
        int a = pass & 1;
        x.f = pass == 0 ? &f_first : &f_later;
        x.cur_xyz = pass == 0 ? g.sxyz : b.buf[1 - a];
        x.ref_nrm = pass == 0 ? b.ref0 : b.buf[3 - a];
        x.out_xyz = b.buf[a];
        x.out_nrm = b.buf[2 + a];
        st = run_pass(&x, &g, pass, p.passes, threads, callbacks, &total);
    }
    if (st == TESSEL_OK)
        st = tsl_progress(callbacks, "smooth", 1.0);
    int last = (int)((p.passes - 1) & 1);
    if (st == TESSEL_OK)
        st = make_result(cloud, &g, &b.buf[last], &b.buf[2 + last], grid_order, threads, &res,
                         &pos);
    if (st != TESSEL_OK)
        goto done;
    if (stats)
        fill_stats(cloud, &res, pos, &p, h, &total, stats);
    *out = res;
    memset(&res, 0, sizeof res);

done:
    tsl_grid_free(&g);
    tessel_index_destroy(cw.index);
    free(cw.pos_of);
    bufs_free(&b);
    free(pos);
    tessel_cloud_free(&res);
    if (st != TESSEL_OK && stats)
        memset(stats, 0, sizeof *stats);
    return st;
}
