/* The mesh checker's geometry (check.c describes the figures): a
 * bounding volume hierarchy over the triangles' boxes, Morton-ordered
 * (Lauterbach et al. 2009), its pairs tested exactly for
 * self-intersections, exact point-to-triangle distances through it
 * (Ericson, "Real-Time Collision Detection", 5.1.5), and surfaces sampled
 * uniformly by area with MT19937-64 for the reference figures. */
#include "check/check.h"

#include <stdlib.h>
#include <string.h>

/* Stable LSD radix sort of 64-bit keys (16-bit digits); tmp has n slots.
 * Digits that are the same in every key are skipped. */
static tessel_status radix_sort_u64(uint64_t *keys, uint64_t *tmp, size_t n)
{
    size_t *count = tsl_calloc_array(65536, sizeof *count);
    if (!count)
        return TESSEL_ERR_NOMEM;
    uint64_t *src = keys, *dst = tmp;
    for (int shift = 0; shift < 64; shift += 16) {
        memset(count, 0, 65536 * sizeof *count);
        for (size_t i = 0; i < n; i++)
            count[(src[i] >> shift) & 0xffff]++;
        if (n == 0 || count[(src[0] >> shift) & 0xffff] == n)
            continue;
        size_t sum = 0;
        for (size_t d = 0; d < 65536; d++) {
            size_t c = count[d];
            count[d] = sum;
            sum += c;
        }
        for (size_t i = 0; i < n; i++)
            dst[count[(src[i] >> shift) & 0xffff]++] = src[i];
        uint64_t *t = src;
        src = dst;
        dst = t;
    }
    if (src != keys)
        memcpy(keys, src, n * sizeof *keys);
    free(count);
    return TESSEL_OK;
}

/* Canonical vertex ids: the smallest index with bit-identical coordinates
 * (+0 and -0 are the same coordinate). Open-addressing hash, inserted in
 * index order, so the result is deterministic. */
static tessel_status canonical_vertices(const tessel_mesh *m, uint32_t **out)
{
    size_t nv = m->vertex_count, cap = 16;
    while (cap < 2 * nv)
        cap *= 2;
    uint32_t *canon = tsl_alloc_array(nv, sizeof *canon);
    uint32_t *table = tsl_alloc_array(cap, sizeof *table);
    if (!canon || !table) {
        free(canon);
        free(table);
        return TESSEL_ERR_NOMEM;
    }
    memset(table, 0xff, cap * sizeof *table);
    for (size_t v = 0; v < nv; v++) {
        const float *p = m->xyz + 3 * v;
        canon[v] = (uint32_t)v;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            continue;
        uint32_t bits[3];
        for (int k = 0; k < 3; k++) {
            float c = p[k] == 0.0f ? 0.0f : p[k];
            memcpy(&bits[k], &c, 4);
        }
        uint64_t h = bits[0] * 0x9E3779B97F4A7C15ULL;
        h = (h ^ bits[1]) * 0xC2B2AE3D27D4EB4FULL;
        h = (h ^ bits[2]) * 0x165667B19E3779F9ULL;
        h ^= h >> 29;
        size_t slot = (size_t)h & (cap - 1);
        for (;;) {
            uint32_t w = table[slot];
            if (w == UINT32_MAX) {
                table[slot] = (uint32_t)v;
                break;
            }
            const float *q = m->xyz + 3 * (size_t)w;
            if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) {
                canon[v] = w;
                break;
            }
            slot = (slot + 1) & (cap - 1);
        }
    }
    free(table);
    *out = canon;
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Bounding volume hierarchy over axis-aligned boxes                         */
/* ------------------------------------------------------------------------ */

static void bvh_free(bvh *b)
{
    free(b->nodes);
    free(b->order);
    free(b->box);
    memset(b, 0, sizeof *b);
}

/* Float bounds that contain the double interval [lo, hi]. */
static inline float round_down(double x)
{
    float f = (float)x;
    return (double)f > x ? nextafterf(f, -INFINITY) : f;
}
static inline float round_up(double x)
{
    float f = (float)x;
    return (double)f < x ? nextafterf(f, INFINITY) : f;
}

/* Spreads the low 10 bits of x to every third bit. */
static uint32_t morton_spread(uint32_t x)
{
    x &= 0x3ff;
    x = (x | (x << 16)) & 0x030000ff;
    x = (x | (x << 8)) & 0x0300f00f;
    x = (x | (x << 4)) & 0x030c30c3;
    x = (x | (x << 2)) & 0x09249249;
    return x;
}

/* Split point of a Morton-sorted range: where its highest differing code
 * bit flips (so a node covers one cell of the implicit octree), or the
 * middle when all codes are equal. */
static uint32_t morton_split(const uint32_t *code, uint32_t start, uint32_t end)
{
    uint32_t first = code[start], last = code[end - 1];
    if (first == last)
        return start + (end - start) / 2;
    uint32_t bit = 31;
    while (!(((first ^ last) >> bit) & 1u))
        bit--;
    /* first position in (start, end) whose code has the bit set */
    uint32_t lo = start + 1, hi = end - 1;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if ((code[mid] >> bit) & 1u)
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

static uint32_t bvh_build_range(bvh *b, const uint32_t *code, uint32_t start, uint32_t end)
{
    uint32_t id = (uint32_t)b->node_count++;
    bvh_node *nd = &b->nodes[id];
    nd->start = start;
    nd->end = end;
    if (end - start <= BVH_LEAF) {
        nd->right = 0;
        for (int k = 0; k < 3; k++) {
            nd->lo[k] = INFINITY;
            nd->hi[k] = -INFINITY;
        }
        for (uint32_t i = start; i < end; i++) {
            const float *bx = b->box + 6 * (size_t)i;
            for (int k = 0; k < 3; k++) {
                nd->lo[k] = fminf(nd->lo[k], bx[k]);
                nd->hi[k] = fmaxf(nd->hi[k], bx[3 + k]);
            }
        }
        return id;
    }
    uint32_t mid = morton_split(code, start, end);
    uint32_t left = bvh_build_range(b, code, start, mid);
    uint32_t right = bvh_build_range(b, code, mid, end);
    nd = &b->nodes[id];
    nd->right = right;
    for (int k = 0; k < 3; k++) {
        nd->lo[k] = fminf(b->nodes[left].lo[k], b->nodes[right].lo[k]);
        nd->hi[k] = fmaxf(b->nodes[left].hi[k], b->nodes[right].hi[k]);
    }
    return id;
}

/* Builds a hierarchy over n boxes (box[6i..6i+5] = lo xyz, hi xyz): boxes
 * sorted by the 30-bit Morton code of their centres (ties by id), ranges
 * split where the highest differing code bit flips. Deterministic; depth at
 * most 30 + log2(n), within BVH_STACK. The boxes are copied in leaf order. */
static tessel_status bvh_build(bvh *b, const float *box, size_t n)
{
    memset(b, 0, sizeof *b);
    if (n == 0)
        return TESSEL_OK;
    if (n >= UINT32_MAX / 2)
        return TESSEL_ERR_LIMIT;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            double c = 0.5 * ((double)box[6 * i + k] + box[6 * i + 3 + k]);
            lo[k] = fmin(lo[k], c);
            hi[k] = fmax(hi[k], c);
        }
    uint64_t *keys = tsl_alloc_array(n, sizeof *keys);
    uint64_t *tmp = tsl_alloc_array(n, sizeof *tmp);
    b->order = tsl_alloc_array(n, sizeof *b->order);
    b->box = tsl_alloc_array(n, 6 * sizeof *b->box);
    b->nodes = tsl_alloc_array(2 * n, sizeof *b->nodes);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!keys || !tmp || !b->order || !b->box || !b->nodes)
        goto fail;
    double scale[3];
    for (int k = 0; k < 3; k++)
        scale[k] = hi[k] > lo[k] ? 1023.0 / (hi[k] - lo[k]) : 0.0;
    for (size_t i = 0; i < n; i++) {
        uint32_t code = 0;
        for (int k = 0; k < 3; k++) {
            double c = 0.5 * ((double)box[6 * i + k] + box[6 * i + 3 + k]);
            double q = (c - lo[k]) * scale[k];
            uint32_t qi = q > 0.0 ? (uint32_t)fmin(q, 1023.0) : 0u;
            code |= morton_spread(qi) << k;
        }
        keys[i] = ((uint64_t)code << 32) | (uint64_t)i;
    }
    st = radix_sort_u64(keys, tmp, n);
    if (st != TESSEL_OK)
        goto fail;
    /* tmp is free again: it keeps the sorted codes for the splits. */
    uint32_t *code = (uint32_t *)tmp;
    for (size_t i = 0; i < n; i++) {
        uint32_t id = (uint32_t)(keys[i] & 0xffffffffu);
        b->order[i] = id;
        code[i] = (uint32_t)(keys[i] >> 32);
        memcpy(b->box + 6 * i, box + 6 * (size_t)id, 6 * sizeof *box);
    }
    free(keys);
    bvh_build_range(b, code, 0, (uint32_t)n);
    free(tmp);
    return TESSEL_OK;
fail:
    free(keys);
    free(tmp);
    bvh_free(b);
    return st;
}

/* Squared distance from q to a node's box (a lower bound for anything in
 * it: the float box contains the exact one). */
static inline double box_dist2(const bvh_node *nd, const double q[3])
{
    double d2 = 0.0;
    for (int k = 0; k < 3; k++) {
        double d = 0.0;
        if (q[k] < nd->lo[k])
            d = nd->lo[k] - q[k];
        else if (q[k] > nd->hi[k])
            d = q[k] - nd->hi[k];
        d2 += d * d;
    }
    return d2;
}

/* ------------------------------------------------------------------------ */
/* Exact intersection tests                                                  */
/* ------------------------------------------------------------------------ */

/* Two non-degenerate triangles, given by canonical vertex ids ca, cb and
 * coordinates pa, pb, intersect in more than their shared vertex or edge.
 * Identical vertex sets are duplicates, counted as such, not here. */
static bool faces_intersect(const uint32_t ca[3], const uint32_t cb[3], const double *pa[3],
                            const double *pb[3])
{
    bool same = true;
    for (int i = 0; i < 3; i++)
        same = same && (ca[i] == cb[0] || ca[i] == cb[1] || ca[i] == cb[2]);
    return !same && tsl_triangles_intersect(ca, pa, cb, pb);
}

/* ------------------------------------------------------------------------ */
/* Distances and sampling                                                    */
/* ------------------------------------------------------------------------ */

static double point_segment_dist2(const double p[3], const double a[3], const double b[3])
{
    double ab[3], ap[3], d[3];
    tsl_sub(b, a, ab);
    tsl_sub(p, a, ap);
    double len2 = tsl_dot(ab, ab), t = len2 > 0.0 ? tsl_dot(ap, ab) / len2 : 0.0;
    t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
    for (int k = 0; k < 3; k++)
        d[k] = ap[k] - t * ab[k];
    return tsl_dot(d, d);
}

/* A sliver: the sine of its smallest angle below 1e-5. The closest-point
 * regions' 2x2 determinants cancel there and could place the nearest point
 * far off the triangle, so it is measured as its three edges, which lie
 * within its width of it. n: the cross product of two of its edges. */
static bool is_sliver(const double *t, const double n[3])
{
    double e[3];
    for (int i = 0; i < 3; i++) {
        double d[3];
        tsl_sub(t + 3 * ((i + 1) % 3), t + 3 * i, d);
        e[i] = tsl_dot(d, d);
    }
    double longest = fmax(e[0], fmax(e[1], e[2])), shortest = fmin(e[0], fmin(e[1], e[2]));
    double middle = e[0] + e[1] + e[2] - longest - shortest;
    /* |n| = longest * middle * sin(smallest angle) */
    return !(tsl_dot(n, n) > 1e-10 * longest * middle);
}

static double point_edges_dist2(const double p[3], const double *t)
{
    return fmin(point_segment_dist2(p, t, t + 3),
                fmin(point_segment_dist2(p, t + 3, t + 6), point_segment_dist2(p, t + 6, t)));
}

/* Squared distance from p to triangle abc (Ericson 5.1.5: Voronoi regions
 * of the vertices, then edges, then the face); not for slivers. */
static double point_triangle_dist2(const double p[3], const double a[3], const double b[3],
                                   const double c[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3], x[3];
    tsl_sub(b, a, ab);
    tsl_sub(c, a, ac);
    tsl_sub(p, a, ap);
    double d1 = tsl_dot(ab, ap), d2 = tsl_dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        x[0] = a[0], x[1] = a[1], x[2] = a[2];
        goto done;
    }
    tsl_sub(p, b, bp);
    double d3 = tsl_dot(ab, bp), d4 = tsl_dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        x[0] = b[0], x[1] = b[1], x[2] = b[2];
        goto done;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double v = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++)
            x[k] = a[k] + v * ab[k];
        goto done;
    }
    tsl_sub(p, c, cp);
    double d5 = tsl_dot(ab, cp), d6 = tsl_dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        x[0] = c[0], x[1] = c[1], x[2] = c[2];
        goto done;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double w = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++)
            x[k] = a[k] + w * ac[k];
        goto done;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++)
            x[k] = b[k] + w * (c[k] - b[k]);
        goto done;
    }
    {
        double denom = 1.0 / (va + vb + vc);
        double v = vb * denom, w = vc * denom;
        for (int k = 0; k < 3; k++)
            x[k] = a[k] + ab[k] * v + ac[k] * w;
    }
done:;
    double d[3];
    tsl_sub(p, x, d);
    return tsl_dot(d, d);
}

void tsl_check_surface_free(surface *s)
{
    free(s->tri);
    free(s->cum);
    free(s->sliver);
    bvh_free(&s->tree);
    memset(s, 0, sizeof *s);
}

/* shift: added to m's local coordinates to bring them into the frame of the
 * checked mesh. kind: per-triangle classification of m. */
tessel_status tsl_check_surface_build(surface *s, const tessel_mesh *m, const uint8_t *kind,
                                   const double shift[3])
{
    memset(s, 0, sizeof *s);
    size_t n = 0;
    for (size_t f = 0; f < m->triangle_count; f++)
        n += kind[f] == KIND_OK;
    s->tri = tsl_alloc_array(n, 9 * sizeof *s->tri);
    s->cum = tsl_alloc_array(n, sizeof *s->cum);
    s->sliver = tsl_alloc_array(n, sizeof *s->sliver);
    float *box = tsl_alloc_array(n, 6 * sizeof *box);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!s->tri || !s->cum || !s->sliver || !box)
        goto fail;
    double acc = 0.0;
    for (size_t f = 0; f < m->triangle_count; f++) {
        if (kind[f] != KIND_OK)
            continue;
        double *t = s->tri + 9 * s->count;
        for (int k = 0; k < 3; k++) {
            const float *v = m->xyz + 3 * (size_t)m->triangles[3 * f + k];
            for (int d = 0; d < 3; d++)
                t[3 * k + d] = (double)v[d] + shift[d];
        }
        double u[3], w[3], nrm[3];
        tsl_sub(t + 3, t, u);
        tsl_sub(t + 6, t, w);
        tsl_cross(u, w, nrm);
        double len = tsl_norm(nrm);
        if (!(len > 0.0 && isfinite(len)))
            continue;
        acc += 0.5 * len;
        s->cum[s->count] = acc;
        s->sliver[s->count] = is_sliver(t, nrm);
        for (int k = 0; k < 9; k++)
            s->slack = fmax(s->slack, 1e-9 * fabs(t[k]));
        float *bx = box + 6 * s->count;
        for (int d = 0; d < 3; d++) {
            bx[d] = round_down(fmin(t[d], fmin(t[3 + d], t[6 + d])));
            bx[3 + d] = round_up(fmax(t[d], fmax(t[3 + d], t[6 + d])));
        }
        s->count++;
    }
    st = bvh_build(&s->tree, box, s->count);
    if (st != TESSEL_OK)
        goto fail;
    free(box);
    return TESSEL_OK;
fail:
    free(box);
    tsl_check_surface_free(s);
    return st;
}

/* Distance from q to the surface (which must not be empty). bound is an
 * upper bound of the distance known beforehand (INFINITY if none): subtrees
 * farther than it are never opened. The result is the smallest computed
 * triangle distance either way. */
static double surface_distance(const surface *s, const double q[3], double bound,
                               uint32_t *face)
{
    double best = INFINITY;
    uint32_t nearest = 0;
    if (bound < INFINITY) {
        double b = bound * (1.0 + 1e-9) + s->slack; /* rounding of the bound */
        best = b * b;
    }
    bool found = false;
    uint32_t stack[BVH_STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const bvh_node *nd = &s->tree.nodes[stack[--top]];
        if (box_dist2(nd, q) >= best)
            continue;
        if (nd->right == 0) {
            for (uint32_t i = nd->start; i < nd->end; i++) {
                const double *t = s->tri + 9 * (size_t)s->tree.order[i];
                double d2 = s->sliver[s->tree.order[i]] ? point_edges_dist2(q, t)
                                                        : point_triangle_dist2(q, t, t + 3, t + 6);
                if (d2 < best) {
                    best = d2;
                    nearest = s->tree.order[i];
                    found = true;
                }
            }
            continue;
        }
        uint32_t l = (uint32_t)(nd - s->tree.nodes) + 1, r = nd->right;
        double dl = box_dist2(&s->tree.nodes[l], q), dr = box_dist2(&s->tree.nodes[r], q);
        /* Push the farther child first so the nearer one is searched first. */
        if (dl <= dr) {
            if (dr < best)
                stack[top++] = r;
            if (dl < best)
                stack[top++] = l;
        } else {
            if (dl < best)
                stack[top++] = l;
            if (dr < best)
                stack[top++] = r;
        }
    }
    if (!found && bound < INFINITY)
        return surface_distance(s, q, INFINITY, face); /* a bound that was too tight */
    if (face)
        *face = nearest;
    return sqrt(best);
}

/* Points whose distance to a surface is wanted: doubles, or floats plus a
 * shift into the surface's frame. */
typedef struct query_points {
    size_t count;
    const double *xyz;  /* count*3, or NULL */
    const float *fxyz;  /* count*3 when xyz is NULL */
    double shift[3];
} query_points;

static inline bool query_get(const query_points *qp, size_t i, double q[3])
{
    if (qp->xyz) {
        q[0] = qp->xyz[3 * i], q[1] = qp->xyz[3 * i + 1], q[2] = qp->xyz[3 * i + 2];
    } else {
        const float *f = qp->fxyz + 3 * i;
        if (!isfinite(f[0]) || !isfinite(f[1]) || !isfinite(f[2]))
            return false;
        for (int k = 0; k < 3; k++)
            q[k] = (double)f[k] + qp->shift[k];
    }
    return true;
}

/* Queries run in blocks of this many points, consecutive in Morton order. */
#define QUERY_BLOCK 32

/* d[i] = distance from point i to s (NaN for non-finite points). Points
 * are visited in Morton order in fixed blocks; within a block each search
 * starts from the bound the previous point gives (its distance plus the
 * step between them, by the triangle inequality), which prunes far
 * queries hard. Blocks do not depend on the thread count, so neither do
 * the results. */
static tessel_status surface_distances(const surface *s, const query_points *qp, double *d,
                                       uint32_t *face, int threads)
{
    size_t n = qp->count;
    if (n == 0)
        return TESSEL_OK;
    if (n >= UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    uint64_t *keys = tsl_alloc_array(n, sizeof *keys);
    uint64_t *tmp = tsl_alloc_array(n, sizeof *tmp);
    if (!keys || !tmp) {
        free(keys);
        free(tmp);
        return TESSEL_ERR_NOMEM;
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++) {
        double q[3];
        if (!query_get(qp, i, q))
            continue;
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], q[k]);
            hi[k] = fmax(hi[k], q[k]);
        }
    }
    double scale[3];
    for (int k = 0; k < 3; k++)
        scale[k] = hi[k] > lo[k] ? 1023.0 / (hi[k] - lo[k]) : 0.0;
    for (size_t i = 0; i < n; i++) {
        double q[3];
        uint32_t code = 0;
        if (query_get(qp, i, q))
            for (int k = 0; k < 3; k++) {
                double c = (q[k] - lo[k]) * scale[k];
                code |= morton_spread(c > 0.0 ? (uint32_t)fmin(c, 1023.0) : 0u) << k;
            }
        keys[i] = ((uint64_t)code << 32) | (uint64_t)i;
    }
    tessel_status st = radix_sort_u64(keys, tmp, n);
    free(tmp);
    if (st != TESSEL_OK) {
        free(keys);
        return st;
    }
    ptrdiff_t blocks = (ptrdiff_t)((n + QUERY_BLOCK - 1) / QUERY_BLOCK);
#pragma omp parallel for schedule(dynamic, 8) num_threads(threads)
    for (ptrdiff_t b = 0; b < blocks; b++) {
        size_t end = (size_t)b * QUERY_BLOCK + QUERY_BLOCK;
        if (end > n)
            end = n;
        double prev[3] = {0, 0, 0}, prev_d = INFINITY;
        for (size_t k = (size_t)b * QUERY_BLOCK; k < end; k++) {
            size_t i = (size_t)(keys[k] & 0xffffffffu);
            double q[3];
            if (!query_get(qp, i, q)) {
                d[i] = NAN;
                continue;
            }
            double step[3];
            tsl_sub(q, prev, step);
            double bound = prev_d < INFINITY ? prev_d + tsl_norm(step) : INFINITY;
            d[i] = surface_distance(s, q, bound, face ? &face[i] : NULL);
            prev[0] = q[0], prev[1] = q[1], prev[2] = q[2];
            prev_d = d[i];
        }
    }
    free(keys);
    return TESSEL_OK;
}

/* MT19937-64 (the generator std::mt19937_64 implements). */
typedef struct mt64 {
    uint64_t mt[312];
    int idx;
} mt64;

static void mt64_seed(mt64 *g, uint64_t seed)
{
    g->mt[0] = seed;
    for (int i = 1; i < 312; i++)
        g->mt[i] = 6364136223846793005ULL * (g->mt[i - 1] ^ (g->mt[i - 1] >> 62)) + (uint64_t)i;
    g->idx = 312;
}

static uint64_t mt64_next(mt64 *g)
{
    if (g->idx >= 312) {
        for (int i = 0; i < 312; i++) {
            uint64_t x = (g->mt[i] & 0xFFFFFFFF80000000ULL) |
                         (g->mt[(i + 1) % 312] & 0x7FFFFFFFULL);
            uint64_t xa = x >> 1;
            if (x & 1)
                xa ^= 0xB5026F5AA96619E9ULL;
            g->mt[i] = g->mt[(i + 156) % 312] ^ xa;
        }
        g->idx = 0;
    }
    uint64_t x = g->mt[g->idx++];
    x ^= (x >> 29) & 0x5555555555555555ULL;
    x ^= (x << 17) & 0x71D67FFFEDA60000ULL;
    x ^= (x << 37) & 0xFFF7EEE000000000ULL;
    x ^= x >> 43;
    return x;
}

static inline double mt64_unit(mt64 *g)
{
    return (double)(mt64_next(g) >> 11) * (1.0 / 9007199254740992.0);
}

/* n points uniformly distributed by area over s (n*3 doubles), and the
 * triangle each lies on. */
static void surface_sample(const surface *s, size_t n, uint64_t seed, double *pts,
                           uint32_t *face)
{
    mt64 g;
    mt64_seed(&g, seed);
    double total = s->cum[s->count - 1];
    for (size_t i = 0; i < n; i++) {
        double target = mt64_unit(&g) * total;
        /* upper_bound: the first triangle whose running area exceeds target */
        size_t lo = 0, hi = s->count;
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (s->cum[mid] <= target)
                lo = mid + 1;
            else
                hi = mid;
        }
        if (lo >= s->count)
            lo = s->count - 1;
        const double *t = s->tri + 9 * lo;
        face[i] = (uint32_t)lo;
        double su = sqrt(mt64_unit(&g)), r = mt64_unit(&g);
        double wa = 1.0 - su, wb = su * (1.0 - r), wc = su * r;
        for (int d = 0; d < 3; d++)
            pts[3 * i + d] = wa * t[d] + wb * t[3 + d] + wc * t[6 + d];
    }
}

/* Mean and max distance from n samples of `from` to `to`, and the share
 * (percent) closer than tau. */
typedef struct dir_stats {
    double mean, max, pct_within, normal_cos;
} dir_stats;

/* Unit normal of triangle t of s. */
static void face_normal(const surface *s, uint32_t t, double n[3])
{
    const double *p = s->tri + 9 * (size_t)t;
    double u[3], v[3];
    tsl_sub(p + 3, p, u);
    tsl_sub(p + 6, p, v);
    tsl_cross(u, v, n);
    tsl_normalize(n);
}

/* Mean and max distance from n samples of `from` to `to`, the share
 * (percent) closer than tau, and the mean |cos| between each sample's
 * normal and the normal of the nearest triangle of `to`. */
static tessel_status directed(const surface *from, const surface *to, size_t n, uint64_t seed,
                              double tau, int threads, dir_stats *out)
{
    out->mean = out->max = out->pct_within = out->normal_cos = NAN;
    if (from->count == 0 || to->count == 0 || n == 0 || !(from->cum[from->count - 1] > 0.0))
        return TESSEL_OK;
    double *pts = tsl_alloc_array(n, 3 * sizeof *pts);
    double *d = tsl_alloc_array(n, sizeof *d);
    uint32_t *src = tsl_alloc_array(n, sizeof *src);
    uint32_t *dst = tsl_alloc_array(n, sizeof *dst);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!pts || !d || !src || !dst)
        goto done;
    surface_sample(from, n, seed, pts, src);
    query_points qp = {n, pts, NULL, {0, 0, 0}};
    if ((st = surface_distances(to, &qp, d, dst, threads)) != TESSEL_OK)
        goto done;
    double sum = 0.0, mx = 0.0, cos_sum = 0.0;
    size_t within = 0;
    for (size_t i = 0; i < n; i++) {
        sum += d[i];
        if (d[i] > mx)
            mx = d[i];
        within += d[i] < tau;
        double a[3], b[3];
        face_normal(from, src[i], a);
        face_normal(to, dst[i], b);
        cos_sum += fabs(tsl_dot(a, b));
    }
    out->mean = sum / (double)n;
    out->max = mx;
    out->pct_within = 100.0 * (double)within / (double)n;
    out->normal_cos = cos_sum / (double)n;
done:
    free(pts);
    free(d);
    free(src);
    free(dst);
    return st;
}

tessel_status tsl_check_self_intersections(const tessel_mesh *m, const uint8_t *kind, int threads,
                                        size_t *pairs_out, size_t *faces_out)
{
    size_t nf = m->triangle_count, n = 0;
    uint32_t *canon = NULL, *ids = NULL, *pairs = NULL;
    float *box = NULL;
    uint8_t *hit = NULL;
    bvh tree;
    memset(&tree, 0, sizeof tree);
    tessel_status st = canonical_vertices(m, &canon);
    if (st != TESSEL_OK)
        return st;
    st = TESSEL_ERR_NOMEM;
    for (size_t f = 0; f < nf; f++)
        n += kind[f] == KIND_OK;
    ids = tsl_alloc_array(n, sizeof *ids);
    box = tsl_alloc_array(n, 6 * sizeof *box);
    pairs = tsl_calloc_array(n, sizeof *pairs);
    hit = tsl_calloc_array(nf, 1);
    if (!ids || !box || !pairs || !hit)
        goto done;
    n = 0;
    for (size_t f = 0; f < nf; f++) {
        if (kind[f] != KIND_OK)
            continue;
        ids[n] = (uint32_t)f;
        float *bx = box + 6 * n;
        for (int d = 0; d < 3; d++) {
            bx[d] = INFINITY;
            bx[3 + d] = -INFINITY;
        }
        for (int k = 0; k < 3; k++) {
            const float *p = m->xyz + 3 * (size_t)m->triangles[3 * f + k];
            for (int d = 0; d < 3; d++) {
                bx[d] = fminf(bx[d], p[d]);
                bx[3 + d] = fmaxf(bx[3 + d], p[d]);
            }
        }
        n++;
    }
    st = bvh_build(&tree, box, n);
    if (st != TESSEL_OK)
        goto done;
    ptrdiff_t nn = (ptrdiff_t)n;
    /* Query q (a leaf position) pairs with the positions after it only, so
     * each pair is seen once and whole subtrees before q are skipped;
     * consecutive queries walk the same paths. */
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
    for (ptrdiff_t q = 0; q < nn; q++) {
        const float *bi = tree.box + 6 * q;
        uint32_t fi = ids[tree.order[q]], ci[3];
        double pi[3][3];
        const double *pip[3] = {pi[0], pi[1], pi[2]};
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->triangles[3 * (size_t)fi + k];
            ci[k] = canon[v];
            tsl_load(m->xyz + 3 * (size_t)v, pi[k]);
        }
        uint32_t stack[BVH_STACK], count = 0;
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const bvh_node *nd = &tree.nodes[stack[--top]];
            if (nd->end <= (uint32_t)q + 1 ||
                !tsl_boxes_overlap(bi, bi + 3, nd->lo, nd->hi))
                continue;
            if (nd->right != 0) {
                stack[top++] = nd->right;
                stack[top++] = (uint32_t)(nd - tree.nodes) + 1;
                continue;
            }
            uint32_t first = nd->start > (uint32_t)q + 1 ? nd->start : (uint32_t)q + 1;
            for (uint32_t r = first; r < nd->end; r++) {
                const float *bj = tree.box + 6 * (size_t)r;
                if (!tsl_boxes_overlap(bi, bi + 3, bj, bj + 3))
                    continue;
                uint32_t fj = ids[tree.order[r]], cj[3];
                double pj[3][3];
                const double *pjp[3] = {pj[0], pj[1], pj[2]};
                for (int k = 0; k < 3; k++) {
                    uint32_t v = m->triangles[3 * (size_t)fj + k];
                    cj[k] = canon[v];
                    tsl_load(m->xyz + 3 * (size_t)v, pj[k]);
                }
                if (faces_intersect(ci, cj, pip, pjp)) {
                    count++;
                    /* Racing writes all store 1: the result is the same. */
#pragma omp atomic write
                    hit[fi] = 1;
#pragma omp atomic write
                    hit[fj] = 1;
                }
            }
        }
        pairs[q] = count;
    }
    size_t total = 0, faces = 0;
    for (size_t i = 0; i < n; i++)
        total += pairs[i];
    for (size_t f = 0; f < nf; f++)
        faces += hit[f];
    *pairs_out = total;
    *faces_out = faces;
    st = TESSEL_OK;
done:
    free(canon);
    free(ids);
    free(box);
    free(pairs);
    free(hit);
    bvh_free(&tree);
    return st;
}

/* --input: input points that are mesh vertices, distances to the mesh. */
tessel_status tsl_check_input_figures(const tessel_mesh *m, const surface *s,
                                   const tessel_cloud *cloud, int threads,
                                   tessel_mesh_report *r)
{
    size_t np = cloud->count;
    if (np > 0 && !cloud->xyz)
        return TESSEL_ERR_INVALID_ARG;
    double shift[3];
    for (int k = 0; k < 3; k++)
        shift[k] = cloud->offset[k] - m->offset[k];
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    size_t finite = 0;
    for (size_t i = 0; i < np; i++) {
        const float *p = cloud->xyz + 3 * i;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            continue;
        finite++;
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], p[k]);
            hi[k] = fmax(hi[k], p[k]);
        }
    }
    double ext[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    double diag = finite ? tsl_norm(ext) : NAN;
    r->input_points = finite;
    r->input_bbox_diagonal = diag;
    r->input_as_vertices = 0;
    r->input_distance_mean = r->input_distance_rms = r->input_distance_max = NAN;
    if (finite == 0)
        return TESSEL_OK;

    /* Referenced vertices as zero-size boxes. */
    uint8_t *ref = tsl_calloc_array(m->vertex_count, 1);
    float *vbox = tsl_alloc_array(m->vertex_count, 6 * sizeof *vbox);
    double *d = tsl_alloc_array(np, sizeof *d);
    uint8_t *used = tsl_calloc_array(np, 1);
    bvh vt;
    memset(&vt, 0, sizeof vt);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!ref || !vbox || !d || !used)
        goto done;
    for (size_t i = 0; i < 3 * m->triangle_count; i++)
        ref[m->triangles[i]] = 1;
    size_t nref = 0;
    for (size_t v = 0; v < m->vertex_count; v++) {
        if (!ref[v])
            continue;
        for (int k = 0; k < 3; k++)
            vbox[6 * nref + k] = vbox[6 * nref + 3 + k] = m->xyz[3 * v + k];
        nref++;
    }
    st = bvh_build(&vt, vbox, nref);
    if (st != TESSEL_OK)
        goto done;
    if (s->count > 0) {
        query_points qp = {np, NULL, cloud->xyz, {shift[0], shift[1], shift[2]}};
        st = surface_distances(s, &qp, d, NULL, threads);
        if (st != TESSEL_OK)
            goto done;
    }
    const double tol = 1e-9 * diag;
    ptrdiff_t nn = (ptrdiff_t)np;
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads)
    for (ptrdiff_t i = 0; i < nn; i++) {
        const float *pf = cloud->xyz + 3 * i;
        if (nref == 0 || !isfinite(pf[0]) || !isfinite(pf[1]) || !isfinite(pf[2]))
            continue;
        double q[3] = {pf[0] + shift[0], pf[1] + shift[1], pf[2] + shift[2]};
        float qlo[3], qhi[3];
        for (int k = 0; k < 3; k++) {
            qlo[k] = round_down(q[k] - tol);
            qhi[k] = round_up(q[k] + tol);
        }
        uint32_t stack[BVH_STACK];
        int top = 0;
        stack[top++] = 0;
        while (top > 0 && !used[i]) {
            const bvh_node *nd = &vt.nodes[stack[--top]];
            if (!tsl_boxes_overlap(qlo, qhi, nd->lo, nd->hi))
                continue;
            if (nd->right != 0) {
                stack[top++] = nd->right;
                stack[top++] = (uint32_t)(nd - vt.nodes) + 1;
                continue;
            }
            for (uint32_t e = nd->start; e < nd->end; e++) {
                const float *vb = vt.box + 6 * (size_t)e;
                double dd[3] = {vb[0] - q[0], vb[1] - q[1], vb[2] - q[2]};
                if (sqrt(tsl_dot(dd, dd)) <= tol) {
                    used[i] = 1;
                    break;
                }
            }
        }
    }
    size_t nused = 0;
    for (size_t i = 0; i < np; i++)
        nused += used[i];
    r->input_as_vertices = nused;
    if (s->count > 0) {
        double sum = 0.0, sum2 = 0.0, mx = 0.0;
        for (size_t i = 0; i < np; i++) {
            if (isnan(d[i]))
                continue;
            sum += d[i];
            sum2 += d[i] * d[i];
            if (d[i] > mx)
                mx = d[i];
        }
        r->input_distance_mean = sum / (double)finite;
        r->input_distance_rms = sqrt(sum2 / (double)finite);
        r->input_distance_max = mx;
    }
    st = TESSEL_OK;
done:
    free(ref);
    free(vbox);
    free(d);
    free(used);
    bvh_free(&vt);
    return st;
}

/* --reference: Chamfer, Hausdorff, precision / recall / F-score. */
tessel_status tsl_check_reference_figures(const tessel_mesh *m, const surface *out,
                                       const tessel_check_params *p, int threads,
                                       tessel_mesh_report *r)
{
    const tessel_mesh *ref = p->reference;
    uint8_t *kind = NULL;
    surface rs;
    memset(&rs, 0, sizeof rs);
    tessel_status st = tsl_check_classify(ref, &kind, threads);
    if (st != TESSEL_OK)
        return st;
    double shift[3];
    for (int k = 0; k < 3; k++)
        shift[k] = ref->offset[k] - m->offset[k];
    st = tsl_check_surface_build(&rs, ref, kind, shift);
    free(kind);
    if (st != TESSEL_OK)
        return st;
    if (rs.count == 0) {
        tsl_check_surface_free(&rs);
        return TESSEL_ERR_INVALID_ARG; /* nothing to compare with */
    }
    double diag = tsl_check_bbox_diagonal(ref);
    double tau = p->tau > 0.0 ? p->tau : 0.01 * diag;
    size_t n = p->samples;
    dir_stats o2r, r2o;
    st = directed(out, &rs, n, SEED_MESH_SAMPLES, tau, threads, &o2r);
    if (st == TESSEL_OK)
        st = directed(&rs, out, n, SEED_REF_SAMPLES, tau, threads, &r2o);
    tsl_check_surface_free(&rs);
    if (st != TESSEL_OK)
        return st;
    bool empty = out->count == 0;
    r->reference_bbox_diagonal = diag;
    r->tau = tau;
    r->accuracy = o2r.mean;
    r->completeness = empty ? NAN : r2o.mean;
    r->chamfer = 0.5 * (o2r.mean + r2o.mean);
    r->hausdorff = isnan(o2r.max) || isnan(r2o.max) ? NAN : fmax(o2r.max, r2o.max);
    double prec = o2r.pct_within, rec = empty ? 0.0 : r2o.pct_within;
    r->precision = prec;
    r->recall = rec;
    r->fscore = empty ? 0.0 : (prec + rec > 0.0 ? 2.0 * prec * rec / (prec + rec) : 0.0);
    r->normal_consistency = o2r.normal_cos;
    r->normal_consistency_ref = empty ? NAN : r2o.normal_cos;
    return TESSEL_OK;
}
