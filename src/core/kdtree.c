/* Neighbour search: an exact kd-tree (Bentley 1975; Friedman, Bentley and
 * Finkel 1977) with the incremental box distance of Arya and Mount (1993),
 * the refinement nanoflann uses.
 *
 * Layout. The index keeps its own copy of the points as 16-byte records
 * {x, y, z, original index}, reordered so every subtree is one contiguous
 * range: a leaf's points share cache lines, and queries read the caller's
 * array only to recompute distances the caller gave no room for (more than
 * 256 results without a dist2 array). Nodes are stored in depth-first
 * order (the left child follows its parent). Each split cuts the node's
 * points at the median of the axis of widest extent, so the tree shape
 * depends on the count only: the node number of every right child is known
 * before the left subtree is built, which lets the build run subtrees as
 * independent OpenMP tasks and still produce the same tree for any thread
 * count. The median is found by quickselect with a branch-free partition
 * (twice as fast as Floyd-Rivest's branchy one here). An inner node
 * stores the largest coordinate of its left part and the smallest of its
 * right part on the split axis (the gap between them prunes for free).
 *
 * Queries descend into the nearer child first and visit the other one only
 * if the box distance — the sum of the three per-axis distances to the
 * nearest cutting planes seen on the path — can still beat the current
 * k-th distance. Each per-axis term is computed with the same float
 * operations, in the same order, as a point's distance, and rounding is
 * monotone, so the bound never exceeds the float distance of any point in
 * the subtree: results are exactly those of a brute-force scan, ties
 * (equal float distances) broken by increasing index. That argument needs
 * each product rounded on its own: no fused multiply-add (GCC in ISO C mode
 * does not contract; clang is told below).
 *
 * Measured against a uniform grid and nanoflann: docs/neighbours.md. */
#include "core/core.h"

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#include <stdlib.h>
#include <string.h>

#if defined(__SSE__) || defined(_M_X64)
#include <xmmintrin.h>
#endif

/* Leaves hold at most this many points (between half of it and all of it
 * with median splits). Chosen by measurement: docs/neighbours.md. */
#define KD_LEAF_MAX 16
/* Subtrees with more points than this are built as separate OpenMP tasks. */
#define KD_TASK_MIN 131072
/* Sorted insertion beats a heap up to this k (docs/neighbours.md); above, knn uses a heap. */
#define KD_SORTED_MAX 128
/* knn without a dist2 array keeps the distances on the stack up to this k. */
#define KD_STACK_K 256

typedef struct kd_point {
    float x[3];
    uint32_t id; /* index in the caller's array */
} kd_point;

/* Inner node: axis 0..2, lo/hi = bounds of the two parts on that axis,
 * right = node number of the right child. Leaf: axis == KD_LEAF,
 * start/count = its range of points. */
#define KD_LEAF 3u
typedef struct kd_node {
    union {
        float lo;
        uint32_t start;
    } a;
    union {
        float hi;
        uint32_t count;
    } b;
    uint32_t right;
    uint32_t axis;
} kd_node;

struct tessel_index {
    size_t count;
    const float *xyz; /* caller's array (only for queries without dist2) */
    kd_point *pts;    /* count records in tree order */
    kd_node *nodes;
    size_t node_count;
};

/* ------------------------------------------------------------------------ */
/* Build                                                                     */
/* ------------------------------------------------------------------------ */

/* Number of nodes of the tree over n points: 1 for a leaf, else 1 plus the
 * nodes of floor(n/2) and ceil(n/2). Sizes at one depth differ by at most
 * one, so the pair (f(m), f(m+1)) follows from (f(h), f(h+1)), h = m/2:
 * O(log n). */
static void node_count_pair(size_t m, size_t *fm, size_t *fm1)
{
    if (m + 1 <= KD_LEAF_MAX) {
        *fm = *fm1 = 1;
        return;
    }
    size_t h = m / 2, fh, fh1;
    node_count_pair(h, &fh, &fh1);
    /* m = 2h or 2h+1; m+1 = 2h+1 or 2h+2 */
    size_t f_m, f_m1;
    if (m % 2 == 0) {
        f_m = 1 + fh + fh;                 /* halves h, h */
        f_m1 = 1 + fh + fh1;               /* halves h, h+1 */
    } else {
        f_m = 1 + fh + fh1;                /* halves h, h+1 */
        f_m1 = 1 + fh1 + fh1;              /* halves h+1, h+1 */
    }
    *fm = m <= KD_LEAF_MAX ? 1 : f_m;
    *fm1 = f_m1;
}

static size_t node_count(size_t n)
{
    size_t a, b;
    node_count_pair(n, &a, &b);
    return a;
}

static void swap_pts(kd_point *a, kd_point *b)
{
    kd_point t = *a;
    *a = *b;
    *b = t;
}

/* Heap sort of p[0..n) on axis: the fallback that bounds quickselect's
 * worst case (introselect). */
static void sift_axis(kd_point *p, size_t n, size_t i, int axis)
{
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n)
            return;
        if (c + 1 < n && p[c + 1].x[axis] > p[c].x[axis])
            c++;
        if (!(p[c].x[axis] > p[i].x[axis]))
            return;
        swap_pts(&p[c], &p[i]);
        i = c;
    }
}

static void heapsort_axis(kd_point *p, size_t n, int axis)
{
    for (size_t i = n / 2; i-- > 0;)
        sift_axis(p, n, i, axis);
    for (size_t end = n; end-- > 1;) {
        swap_pts(&p[0], &p[end]);
        sift_axis(p, end, 0, axis);
    }
}

/* Moves the records of p[0..n) whose key passes the test (key < pivot, or
 * key <= pivot when or_equal) to the front, keeping nothing; returns their
 * number. Branch-free Lomuto partition: the outcome of each comparison only
 * moves the write position, so unpredictable keys cost no mispredictions. */
static size_t partition_keys(kd_point *p, size_t n, float pivot, int axis, int or_equal)
{
    size_t store = 0;
    if (or_equal) {
        for (size_t i = 0; i < n; i++) {
            kd_point x = p[i];
            size_t c = x.x[axis] <= pivot;
            p[i] = p[store];
            p[store] = x;
            store += c;
        }
    } else {
        for (size_t i = 0; i < n; i++) {
            kd_point x = p[i];
            size_t c = x.x[axis] < pivot;
            p[i] = p[store];
            p[store] = x;
            store += c;
        }
    }
    return store;
}

static float median3(float a, float b, float c)
{
    return a < b ? (b < c ? b : (a < c ? c : a)) : (a < c ? a : (b < c ? c : b));
}

/* Rearranges p[0..n) so p[nth] holds the value it would have if sorted on
 * axis, with nothing greater before it and nothing smaller after it.
 * Quickselect (Hoare 1961) around a median of three (of nine on large
 * ranges) with the branch-free partition above; when few keys fall below
 * the pivot a second pass gathers the keys equal to it, so many duplicates
 * stay linear. A pass budget bounds the worst case with a heap sort (as
 * introselect does). */
static void select_axis(kd_point *p, size_t n, size_t nth, int axis)
{
    size_t lo = 0, hi = n; /* the answer is in [lo, hi) */
    int budget = 64;
    while (hi - lo > 16) {
        if (budget-- == 0) {
            heapsort_axis(p + lo, hi - lo, axis);
            return;
        }
        size_t m = hi - lo, mid = lo + m / 2;
        float pivot;
        if (m > 1024) {
            size_t s = m / 8;
            pivot = median3(median3(p[lo].x[axis], p[lo + s].x[axis], p[lo + 2 * s].x[axis]),
                            median3(p[mid - s].x[axis], p[mid].x[axis], p[mid + s].x[axis]),
                            median3(p[hi - 1 - 2 * s].x[axis], p[hi - 1 - s].x[axis],
                                    p[hi - 1].x[axis]));
        } else {
            pivot = median3(p[lo].x[axis], p[mid].x[axis], p[hi - 1].x[axis]);
        }
        size_t less = lo + partition_keys(p + lo, m, pivot, axis, 0);
        if (nth < less) {
            hi = less;
        } else if (less - lo < m / 8) {
            /* [less, hi) >= pivot and holds the pivot itself. */
            size_t equal = less + partition_keys(p + less, hi - less, pivot, axis, 1);
            if (nth < equal)
                return; /* p[nth] == pivot */
            lo = equal;
        } else {
            lo = less;
        }
    }
    for (size_t i = lo + 1; i < hi; i++) {
        kd_point x = p[i];
        size_t j = i;
        for (; j > lo && x.x[axis] < p[j - 1].x[axis]; j--)
            p[j] = p[j - 1];
        p[j] = x;
    }
}

/* Bounding box of p[0..n), n >= 1. With SSE a record's 16 bytes are one
 * vector (the id lane is ignored); two accumulators halve the dependency
 * chain. The build spends most of its time here. */
static void bbox_of(const kd_point *p, size_t n, float mn[3], float mx[3])
{
#if defined(__SSE__) || defined(_M_X64)
    __m128 lo0 = _mm_loadu_ps(p[0].x), hi0 = lo0, lo1 = lo0, hi1 = lo0;
    size_t i = 1;
    for (; i + 1 < n; i += 2) {
        __m128 a = _mm_loadu_ps(p[i].x), b = _mm_loadu_ps(p[i + 1].x);
        lo0 = _mm_min_ps(lo0, a);
        hi0 = _mm_max_ps(hi0, a);
        lo1 = _mm_min_ps(lo1, b);
        hi1 = _mm_max_ps(hi1, b);
    }
    if (i < n) {
        __m128 a = _mm_loadu_ps(p[i].x);
        lo0 = _mm_min_ps(lo0, a);
        hi0 = _mm_max_ps(hi0, a);
    }
    float lo[4], hi[4];
    _mm_storeu_ps(lo, _mm_min_ps(lo0, lo1));
    _mm_storeu_ps(hi, _mm_max_ps(hi0, hi1));
    for (int a = 0; a < 3; a++) {
        mn[a] = lo[a];
        mx[a] = hi[a];
    }
#else
    for (int a = 0; a < 3; a++)
        mn[a] = mx[a] = p[0].x[a];
    for (size_t i = 1; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float v = p[i].x[a];
            mn[a] = v < mn[a] ? v : mn[a];
            mx[a] = v > mx[a] ? v : mx[a];
        }
    }
#endif
}

/* Builds the subtree over pts[begin, begin+n) into nodes[node...], given
 * the points' bounding box. */
static void build_node(tessel_index *ix, size_t node, size_t begin, size_t n,
                       const float mn[3], const float mx[3])
{
    kd_node *nd = &ix->nodes[node];
    if (n <= KD_LEAF_MAX) {
        nd->axis = KD_LEAF;
        nd->a.start = (uint32_t)begin;
        nd->b.count = (uint32_t)n;
        nd->right = 0;
        return;
    }
    int axis = 0;
    for (int a = 1; a < 3; a++)
        if (mx[a] - mn[a] > mx[axis] - mn[axis])
            axis = a;
    kd_point *p = ix->pts + begin;
    size_t half = n / 2;
    select_axis(p, n, half, axis);

    float lmn[3], lmx[3], rmn[3], rmx[3];
    bbox_of(p, half, lmn, lmx);
    bbox_of(p + half, n - half, rmn, rmx);
    size_t left = node + 1, right = node + 1 + node_count(half);
    nd->axis = (uint32_t)axis;
    nd->a.lo = lmx[axis];
    nd->b.hi = rmn[axis];
    nd->right = (uint32_t)right;

    if (n >= KD_TASK_MIN) {
#pragma omp task default(shared) firstprivate(left, begin, half) \
    shared(lmn, lmx)
        build_node(ix, left, begin, half, lmn, lmx);
        build_node(ix, right, begin + half, n - half, rmn, rmx);
#pragma omp taskwait
    } else {
        build_node(ix, left, begin, half, lmn, lmx);
        build_node(ix, right, begin + half, n - half, rmn, rmx);
    }
}

tessel_status tessel_index_build(tessel_index **index, const float *xyz, size_t count)
{
    if (!index)
        return TESSEL_ERR_INVALID_ARG;
    *index = NULL;
    if (!xyz && count > 0)
        return TESSEL_ERR_INVALID_ARG;
    /* Indices are uint32_t and TESSEL_NONE marks "no neighbour". */
    if (count >= (size_t)UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    for (size_t i = 0; i < 3 * count; i++)
        if (!isfinite(xyz[i]))
            return TESSEL_ERR_INVALID_ARG;

    tessel_index *ix = calloc(1, sizeof *ix);
    if (!ix)
        return TESSEL_ERR_NOMEM;
    ix->count = count;
    ix->xyz = xyz;
    ix->node_count = count ? node_count(count) : 0;
    ix->pts = tsl_alloc_array(count, sizeof *ix->pts);
    ix->nodes = tsl_alloc_array(ix->node_count, sizeof *ix->nodes);
    if (!ix->pts || !ix->nodes) {
        tessel_index_destroy(ix);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < count; i++) {
        ix->pts[i].x[0] = xyz[3 * i];
        ix->pts[i].x[1] = xyz[3 * i + 1];
        ix->pts[i].x[2] = xyz[3 * i + 2];
        ix->pts[i].id = (uint32_t)i;
    }
    if (count > 0) {
        float mn[3], mx[3];
        bbox_of(ix->pts, count, mn, mx);
        if (count >= KD_TASK_MIN) {
#pragma omp parallel
#pragma omp single
            build_node(ix, 0, 0, count, mn, mx);
        } else {
            build_node(ix, 0, 0, count, mn, mx);
        }
    }
    *index = ix;
    return TESSEL_OK;
}

void tessel_index_destroy(tessel_index *index)
{
    if (!index)
        return;
    free(index->pts);
    free(index->nodes);
    free(index);
}

/* ------------------------------------------------------------------------ */
/* Result sets                                                               */
/* ------------------------------------------------------------------------ */

/* The float squared distance, always with this association, so box bounds
 * (same per-axis terms, same order) never exceed it. */
static inline float dist2_of(const float p[3], const float q[3])
{
    float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

/* (d, i) strictly before (e, j): nearer, or as near with a smaller index. */
static inline bool before(float d, uint32_t i, float e, uint32_t j)
{
    return d < e || (d == e && i < j);
}

/* A result set of at most cap entries in the caller's arrays. Modes:
 * sorted insertion (small k, distances stored), or a max-heap on (d, id)
 * whose distances are stored, or recomputed from the caller's points when
 * the caller gave no distance array and cap exceeds the stack buffer. */
typedef struct result_set {
    uint32_t *id;
    float *d;          /* NULL: recompute from xyz */
    const float *xyz;
    const float *q;
    size_t cap, cnt;
    size_t total;      /* radius: every point within the radius */
    float worst;       /* k-th distance once full, else the pruning limit */
    bool sorted;       /* knn: sorted-insertion mode, else heap */
    bool heap;         /* radius: entries form a heap (else unordered) */
} result_set;

static inline float rs_d(const result_set *rs, size_t i)
{
    return rs->d ? rs->d[i] : dist2_of(rs->xyz + 3 * (size_t)rs->id[i], rs->q);
}

static void heap_sift_down(result_set *rs, size_t i, size_t n)
{
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n)
            return;
        float dc = rs_d(rs, c);
        if (c + 1 < n) {
            float dc1 = rs_d(rs, c + 1);
            if (before(dc, rs->id[c], dc1, rs->id[c + 1])) {
                c++;
                dc = dc1;
            }
        }
        float di = rs_d(rs, i);
        if (!before(di, rs->id[i], dc, rs->id[c]))
            return;
        uint32_t t = rs->id[i];
        rs->id[i] = rs->id[c];
        rs->id[c] = t;
        if (rs->d) {
            rs->d[i] = dc;
            rs->d[c] = di;
        }
        i = c;
    }
}

static void heap_sift_up(result_set *rs, size_t i)
{
    while (i > 0) {
        size_t parent = (i - 1) / 2;
        float dp = rs_d(rs, parent), di = rs_d(rs, i);
        if (!before(dp, rs->id[parent], di, rs->id[i]))
            return;
        uint32_t t = rs->id[i];
        rs->id[i] = rs->id[parent];
        rs->id[parent] = t;
        if (rs->d) {
            rs->d[i] = dp;
            rs->d[parent] = di;
        }
        i = parent;
    }
}

/* Heap into ascending order. */
static void heap_finish(result_set *rs)
{
    for (size_t end = rs->cnt; end > 1; end--) {
        uint32_t t = rs->id[0];
        rs->id[0] = rs->id[end - 1];
        rs->id[end - 1] = t;
        if (rs->d) {
            float f = rs->d[0];
            rs->d[0] = rs->d[end - 1];
            rs->d[end - 1] = f;
        }
        heap_sift_down(rs, 0, end - 1);
    }
}

/* Offers (d, id) to a knn set; d <= rs->worst already holds. */
static inline void knn_add(result_set *rs, float d, uint32_t id)
{
    if (rs->sorted) {
        size_t pos;
        if (rs->cnt < rs->cap) {
            pos = rs->cnt++;
        } else {
            if (!before(d, id, rs->d[rs->cap - 1], rs->id[rs->cap - 1]))
                return;
            pos = rs->cap - 1;
        }
        while (pos > 0 && before(d, id, rs->d[pos - 1], rs->id[pos - 1])) {
            rs->d[pos] = rs->d[pos - 1];
            rs->id[pos] = rs->id[pos - 1];
            pos--;
        }
        rs->d[pos] = d;
        rs->id[pos] = id;
        if (rs->cnt == rs->cap)
            rs->worst = rs->d[rs->cap - 1];
        return;
    }
    if (rs->cnt < rs->cap) {
        size_t i = rs->cnt++;
        rs->id[i] = id;
        if (rs->d)
            rs->d[i] = d;
        heap_sift_up(rs, i);
    } else {
        if (!before(d, id, rs_d(rs, 0), rs->id[0]))
            return;
        rs->id[0] = id;
        if (rs->d)
            rs->d[0] = d;
        heap_sift_down(rs, 0, rs->cnt);
    }
    if (rs->cnt == rs->cap)
        rs->worst = rs_d(rs, 0);
}

/* ------------------------------------------------------------------------ */
/* Queries                                                                   */
/* ------------------------------------------------------------------------ */

typedef struct query {
    const tessel_index *ix;
    float q[3];
    float box[3]; /* per-axis squared distance to the nearest cut on the path */
    result_set *rs;
} query;

static void knn_node(query *s, uint32_t node)
{
    const kd_node *nd = &s->ix->nodes[node];
    if (nd->axis == KD_LEAF) {
        const kd_point *p = s->ix->pts + nd->a.start;
        result_set *rs = s->rs;
        for (uint32_t i = 0; i < nd->b.count; i++) {
            float d = dist2_of(p[i].x, s->q);
            if (d <= rs->worst)
                knn_add(rs, d, p[i].id);
        }
        return;
    }
    uint32_t axis = nd->axis;
    float qa = s->q[axis];
    float dlo = qa - nd->a.lo, dhi = qa - nd->b.hi;
    uint32_t near, far;
    float cut;
    if (dlo + dhi < 0.0f) { /* nearer the left part */
        near = node + 1;
        far = nd->right;
        cut = dhi * dhi;
    } else {
        near = nd->right;
        far = node + 1;
        cut = dlo * dlo;
    }
    knn_node(s, near);
    float saved = s->box[axis];
    /* Both are lower bounds on this axis; keep the larger. */
    if (cut < saved)
        cut = saved;
    s->box[axis] = cut;
    float bound = (s->box[0] + s->box[1]) + s->box[2];
    if (bound <= s->rs->worst)
        knn_node(s, far);
    s->box[axis] = saved;
}

/* knn into caller arrays; d may be NULL. Returns the number written. */
static size_t knn_query(const tessel_index *ix, const float q[3], size_t k, uint32_t *idx,
                        float *d)
{
    if (!ix || !q || !idx || k == 0 || ix->count == 0)
        return 0;
    if (!isfinite(q[0]) || !isfinite(q[1]) || !isfinite(q[2]))
        return 0;
    if (k > ix->count)
        k = ix->count;
    float stack_d[KD_STACK_K];
    result_set rs = {
        .id = idx,
        .d = d ? d : (k <= KD_STACK_K ? stack_d : NULL),
        .xyz = ix->xyz,
        .q = q,
        .cap = k,
        .worst = INFINITY,
    };
    rs.sorted = rs.d != NULL && k <= KD_SORTED_MAX;
    query s = {.ix = ix, .q = {q[0], q[1], q[2]}, .rs = &rs};
    knn_node(&s, 0);
    if (!rs.sorted)
        heap_finish(&rs);
    return rs.cnt;
}

size_t tessel_index_knn(const tessel_index *index, const float q[3], size_t k,
                        uint32_t *idx, float *dist2)
{
    return knn_query(index, q, k, idx, dist2);
}

/* Radius search: counts every point within r2. The first cap found are
 * appended unordered; only when more arrive do they become a heap that
 * keeps the nearest cap. */
static void radius_add(result_set *rs, float d, uint32_t id)
{
    if (rs->cnt < rs->cap) {
        rs->id[rs->cnt] = id;
        if (rs->d)
            rs->d[rs->cnt] = d;
        rs->cnt++;
        return;
    }
    if (rs->cap == 0)
        return;
    if (!rs->heap) {
        for (size_t i = rs->cnt / 2; i-- > 0;)
            heap_sift_down(rs, i, rs->cnt);
        rs->heap = true;
    }
    if (!before(d, id, rs_d(rs, 0), rs->id[0]))
        return;
    rs->id[0] = id;
    if (rs->d)
        rs->d[0] = d;
    heap_sift_down(rs, 0, rs->cnt);
}

/* Sorts what radius_add kept. */
static void radius_finish(result_set *rs)
{
    if (!rs->heap && rs->d && rs->cnt <= KD_SORTED_MAX) {
        for (size_t i = 1; i < rs->cnt; i++) {
            float d = rs->d[i];
            uint32_t id = rs->id[i];
            size_t j = i;
            while (j > 0 && before(d, id, rs->d[j - 1], rs->id[j - 1])) {
                rs->d[j] = rs->d[j - 1];
                rs->id[j] = rs->id[j - 1];
                j--;
            }
            rs->d[j] = d;
            rs->id[j] = id;
        }
        return;
    }
    if (!rs->heap)
        for (size_t i = rs->cnt / 2; i-- > 0;)
            heap_sift_down(rs, i, rs->cnt);
    heap_finish(rs);
}

static void radius_node(query *s, uint32_t node, float r2)
{
    const kd_node *nd = &s->ix->nodes[node];
    if (nd->axis == KD_LEAF) {
        const kd_point *p = s->ix->pts + nd->a.start;
        result_set *rs = s->rs;
        for (uint32_t i = 0; i < nd->b.count; i++) {
            float d = dist2_of(p[i].x, s->q);
            if (d <= r2) {
                rs->total++;
                radius_add(rs, d, p[i].id);
            }
        }
        return;
    }
    uint32_t axis = nd->axis;
    float qa = s->q[axis];
    float dlo = qa - nd->a.lo, dhi = qa - nd->b.hi;
    uint32_t near, far;
    float cut;
    if (dlo + dhi < 0.0f) {
        near = node + 1;
        far = nd->right;
        cut = dhi * dhi;
    } else {
        near = nd->right;
        far = node + 1;
        cut = dlo * dlo;
    }
    radius_node(s, near, r2);
    float saved = s->box[axis];
    if (cut < saved)
        cut = saved;
    s->box[axis] = cut;
    float bound = (s->box[0] + s->box[1]) + s->box[2];
    if (bound <= r2)
        radius_node(s, far, r2);
    s->box[axis] = saved;
}

size_t tessel_index_radius(const tessel_index *index, const float q[3], float radius,
                           uint32_t *idx, float *dist2, size_t cap)
{
    if (!index || !q || index->count == 0 || !(radius >= 0.0f))
        return 0;
    if (!isfinite(q[0]) || !isfinite(q[1]) || !isfinite(q[2]))
        return 0;
    if (!idx)
        cap = 0;
    float stack_d[KD_STACK_K];
    result_set rs = {
        .id = idx,
        .d = dist2 ? dist2 : (cap <= KD_STACK_K ? stack_d : NULL),
        .xyz = index->xyz,
        .q = q,
        .cap = cap,
    };
    query s = {.ix = index, .q = {q[0], q[1], q[2]}, .rs = &rs};
    radius_node(&s, 0, radius * radius);
    radius_finish(&rs);
    return rs.total;
}

tessel_status tessel_index_knn_batch(const tessel_index *index, const float *queries,
                                     size_t query_count, size_t k, uint32_t *idx,
                                     float *dist2, int threads)
{
    if (!index || (query_count > 0 && (!queries || !idx)))
        return TESSEL_ERR_INVALID_ARG;
    size_t slots;
    if (!tsl_mul_size(query_count, k, &slots) || query_count > (size_t)PTRDIFF_MAX)
        return TESSEL_ERR_INVALID_ARG;
    if (k == 0 || query_count == 0)
        return TESSEL_OK;
    ptrdiff_t nq = (ptrdiff_t)query_count;
    int nthreads = tsl_threads(threads);
    (void)nthreads;
#pragma omp parallel for schedule(dynamic, 256) num_threads(nthreads)
    for (ptrdiff_t i = 0; i < nq; i++) {
        uint32_t *row = idx + (size_t)i * k;
        float *drow = dist2 ? dist2 + (size_t)i * k : NULL;
        size_t got = knn_query(index, queries + 3 * (size_t)i, k, row, drow);
        for (size_t j = got; j < k; j++) {
            row[j] = TESSEL_NONE;
            if (drow)
                drow[j] = INFINITY;
        }
    }
    return TESSEL_OK;
}

void tsl_index_order(const tessel_index *index, uint32_t *order)
{
    for (size_t i = 0; i < index->count; i++)
        order[i] = index->pts[i].id;
}
