/* Mesh check: topology, validity and accuracy figures of a triangle mesh.
 *
 * Every figure follows the definitions of the independent evaluator our
 * results are compared with (meshcheck; docs/check.md lists them), so the
 * numbers agree on the same file:
 *  - Topology (edges, boundary, manifoldness, orientation, components,
 *    Euler characteristic, genus) uses vertex indices as given and ignores
 *    triangles with a repeated index; zero-area triangles take part.
 *    Edges are grouped by bucketing half-edges on their smaller vertex.
 *    A vertex is manifold when the link formed by the opposite edges of its
 *    triangles is one path or one cycle. Orientability is decided by
 *    2-colouring triangles with a union-find that carries parities.
 *  - Degenerate triangles: a repeated index, or three exactly collinear
 *    vertices (robust orientation predicates, src/core/predicates.c).
 *  - Self-intersections: pairs of non-degenerate triangles whose bounding
 *    boxes overlap (found with a bounding volume hierarchy over the boxes,
 *    Morton-ordered as in Lauterbach et al. 2009, "Fast BVH construction on
 *    GPUs") are tested exactly: closed triangles meet iff an edge of one
 *    meets the other, and a segment meets a triangle iff it reaches the
 *    triangle's plane and the line through it passes every edge on the same
 *    side (signs of orient3d, Plücker-style); coplanar configurations are
 *    decided with orient2d in a coordinate projection where the triangle
 *    stays non-degenerate. Vertices with bit-identical coordinates count as
 *    one; a pair that shares an edge intersects only when the two triangles
 *    are coplanar and fold onto the same side of it, a pair sharing a vertex
 *    only when the edge opposite that vertex in one meets the other.
 *  - Distances (--input, --reference) are point-to-triangle distances
 *    (Ericson, "Real-Time Collision Detection", section 5.1.5; a sliver,
 *    smallest angle's sine below 1e-5, measured as its three edges) through
 *    the same hierarchy. Surfaces are sampled uniformly by area with
 *    MT19937-64 (Matsumoto & Nishimura 1998; Nishimura 2000) and fixed
 *    seeds, as the evaluator does, so the same samples are drawn.
 * Work is threaded with OpenMP over triangles and samples; every sum is
 * taken in index order afterwards, so results do not depend on the thread
 * count. */
#include "check/check.h"

#include <stdlib.h>
#include <string.h>

tessel_check_params tessel_check_params_default(void)
{
    tessel_check_params p;
    memset(&p, 0, sizeof p);
    p.self_intersections = 1;
    p.input = NULL;
    p.reference = NULL;
    p.tau = 0.0;
    p.samples = 200000;
    p.threads = 0;
    return p;
}

int tessel_mesh_report_valid(const tessel_mesh_report *r)
{
    if (!r || r->triangles == 0)
        return 0;
    return r->nonmanifold_edges == 0 && r->nonmanifold_vertices == 0 &&
           r->orientation_conflicts == 0 && r->duplicate_triangles == 0 &&
           r->degenerate_triangles == 0 &&
           (r->self_intersections == 0 || r->self_intersections == SIZE_MAX);
}

/* ------------------------------------------------------------------------ */
/* Small helpers                                                             */
/* ------------------------------------------------------------------------ */

/* Union-find whose links carry the parity "flipped relative to parent". */
typedef struct parity_uf {
    uint32_t *parent, *size;
    uint8_t *par;
} parity_uf;

static uint32_t puf_find(parity_uf *u, uint32_t x, uint8_t *parity)
{
    uint32_t r = x;
    uint8_t acc = 0;
    while (u->parent[r] != r) {
        acc ^= u->par[r];
        r = u->parent[r];
    }
    /* Compress, keeping each node's parity relative to the root. */
    uint8_t cur = acc;
    for (uint32_t y = x; u->parent[y] != y;) {
        uint32_t next = u->parent[y];
        uint8_t py = u->par[y];
        u->parent[y] = r;
        u->par[y] = cur;
        cur ^= py;
        y = next;
    }
    *parity = acc;
    return r;
}

/* Requires parity(a) ^ parity(b) == d; false on a contradiction. */
static bool puf_unite(parity_uf *u, uint32_t a, uint32_t b, uint8_t d)
{
    uint8_t pa, pb;
    uint32_t ra = puf_find(u, a, &pa), rb = puf_find(u, b, &pb);
    if (ra == rb)
        return (uint8_t)(pa ^ pb) == d;
    if (u->size[ra] > u->size[rb]) {
        uint32_t t = ra;
        ra = rb;
        rb = t;
    }
    u->parent[ra] = rb;
    u->par[ra] = (uint8_t)(pa ^ pb ^ d);
    u->size[rb] += u->size[ra];
    return true;
}

/* Sorts a small array of (a, b) uint32 pairs lexicographically. Buckets are
 * vertex stars, so insertion sort is right for all but pathological stars;
 * those fall back to qsort. */
typedef struct pair_u32 {
    uint32_t a, b;
} pair_u32;

static int cmp_pair(const void *x, const void *y)
{
    const pair_u32 *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    if (p->b != q->b)
        return p->b < q->b ? -1 : 1;
    return 0;
}

static void sort_pairs(pair_u32 *v, size_t n)
{
    if (n > 32) {
        qsort(v, n, sizeof *v, cmp_pair);
        return;
    }
    for (size_t i = 1; i < n; i++) {
        pair_u32 x = v[i];
        size_t j = i;
        while (j > 0 && cmp_pair(&v[j - 1], &x) > 0) {
            v[j] = v[j - 1];
            j--;
        }
        v[j] = x;
    }
}

/* ------------------------------------------------------------------------ */
/* Per-mesh preparation                                                      */
/* ------------------------------------------------------------------------ */

/* Checks indices and coordinates, classifies every triangle. */
tessel_status tsl_check_classify(const tessel_mesh *m, uint8_t **kind_out, int threads)
{
    *kind_out = NULL;
    if (m->triangle_count > 0 && (!m->triangles || !m->xyz))
        return TESSEL_ERR_INVALID_ARG;
    if (m->vertex_count >= UINT32_MAX || m->triangle_count >= UINT32_MAX / 2)
        return TESSEL_ERR_LIMIT;
    for (size_t i = 0; i < 3 * m->triangle_count; i++) {
        uint32_t v = m->triangles[i];
        if (v >= m->vertex_count)
            return TESSEL_ERR_INVALID_ARG;
        const float *p = m->xyz + 3 * (size_t)v;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return TESSEL_ERR_INVALID_ARG;
    }
    uint8_t *kind = tsl_alloc_array(m->triangle_count, 1);
    if (!kind)
        return TESSEL_ERR_NOMEM;
    ptrdiff_t nf = (ptrdiff_t)m->triangle_count;
#pragma omp parallel for schedule(static) num_threads(threads)
    for (ptrdiff_t f = 0; f < nf; f++) {
        const uint32_t *t = m->triangles + 3 * f;
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
            kind[f] = KIND_REPEATED;
            continue;
        }
        double a[3], b[3], c[3];
        tsl_load(m->xyz + 3 * (size_t)t[0], a);
        tsl_load(m->xyz + 3 * (size_t)t[1], b);
        tsl_load(m->xyz + 3 * (size_t)t[2], c);
        const double *p[3] = {a, b, c};
        kind[f] = tsl_triangle_degenerate(p) ? KIND_ZERO_AREA : KIND_OK;
    }
    *kind_out = kind;
    return TESSEL_OK;
}

/* Bounding-box diagonal of the vertices referenced by a triangle (all
 * vertices when there are no triangles). */
double tsl_check_bbox_diagonal(const tessel_mesh *m)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    bool any = false;
    for (size_t i = 0; i < (m->triangle_count ? 3 * m->triangle_count : m->vertex_count); i++) {
        size_t v = m->triangle_count ? m->triangles[i] : i;
        const float *p = m->xyz + 3 * v;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            continue;
        any = true;
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], p[k]);
            hi[k] = fmax(hi[k], p[k]);
        }
    }
    if (!any)
        return NAN;
    double d[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    return tsl_norm(d);
}

/* ------------------------------------------------------------------------ */
/* Figures                                                                   */
/* ------------------------------------------------------------------------ */

/* Duplicate triangles: same sorted vertex triple as an earlier one. Triples
 * are bucketed on their smallest vertex, then sorted within a bucket. */
static tessel_status count_duplicates(const tessel_mesh *m, size_t *out)
{
    size_t nv = m->vertex_count, nf = m->triangle_count;
    size_t *start = tsl_calloc_array(nv + 1, sizeof *start);
    pair_u32 *items = tsl_alloc_array(nf, sizeof *items);
    if (!start || !items) {
        free(start);
        free(items);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t f = 0; f < nf; f++) {
        const uint32_t *t = m->triangles + 3 * f;
        uint32_t lo = t[0] < t[1] ? t[0] : t[1];
        lo = lo < t[2] ? lo : t[2];
        start[lo + 1]++;
    }
    for (size_t v = 0; v < nv; v++)
        start[v + 1] += start[v];
    for (size_t f = 0; f < nf; f++) {
        uint32_t s[3] = {m->triangles[3 * f], m->triangles[3 * f + 1], m->triangles[3 * f + 2]};
        for (int i = 0; i < 2; i++)
            for (int j = 0; j < 2 - i; j++)
                if (s[j] > s[j + 1]) {
                    uint32_t t = s[j];
                    s[j] = s[j + 1];
                    s[j + 1] = t;
                }
        items[start[s[0]]++] = (pair_u32){s[1], s[2]};
    }
    /* start[v] now ends bucket v; bucket v begins where v-1 ended. */
    size_t dup = 0, begin = 0;
    for (size_t v = 0; v < nv; v++) {
        size_t end = start[v];
        sort_pairs(items + begin, end - begin);
        for (size_t i = begin + 1; i < end; i++)
            dup += items[i].a == items[i - 1].a && items[i].b == items[i - 1].b;
        begin = end;
    }
    free(start);
    free(items);
    *out = dup;
    return TESSEL_OK;
}

/* The half-edges bucketed on their smaller vertex, and each vertex's
 * triangles, of the triangles without a repeated index. */
typedef struct edge_buckets {
    size_t *estart, *vstart; /* after the fill: the end of bucket v */
    pair_u32 *half;          /* (larger vertex, 2 f + (runs forward)) */
    uint32_t *inc;           /* triangles round each vertex */
    size_t nt;               /* triangles bucketed */
} edge_buckets;

static void buckets_free(edge_buckets *b)
{
    free(b->estart);
    free(b->vstart);
    free(b->half);
    free(b->inc);
}

static tessel_status buckets_fill(const tessel_mesh *m, const uint8_t *kind, edge_buckets *b)
{
    size_t nv = m->vertex_count, nf = m->triangle_count;
    b->estart = tsl_calloc_array(nv + 1, sizeof *b->estart);
    b->vstart = tsl_calloc_array(nv + 1, sizeof *b->vstart);
    b->half = tsl_alloc_array(nf, 3 * sizeof *b->half);
    b->inc = tsl_alloc_array(nf, 3 * sizeof *b->inc);
    b->nt = 0;
    if (!b->estart || !b->vstart || !b->half || !b->inc)
        return TESSEL_ERR_NOMEM;
    for (size_t f = 0; f < nf; f++) {
        if (kind[f] == KIND_REPEATED)
            continue;
        b->nt++;
        const uint32_t *t = m->triangles + 3 * f;
        for (int k = 0; k < 3; k++) {
            uint32_t a = t[k], c = t[(k + 1) % 3];
            b->estart[(a < c ? a : c) + 1]++;
            b->vstart[a + 1]++;
        }
    }
    for (size_t v = 0; v < nv; v++) {
        b->estart[v + 1] += b->estart[v];
        b->vstart[v + 1] += b->vstart[v];
    }
    for (size_t f = 0; f < nf; f++) {
        if (kind[f] == KIND_REPEATED)
            continue;
        const uint32_t *t = m->triangles + 3 * f;
        for (int k = 0; k < 3; k++) {
            uint32_t a = t[k], c = t[(k + 1) % 3];
            uint32_t lo = a < c ? a : c, hi = a < c ? c : a;
            b->half[b->estart[lo]++] = (pair_u32){hi, (uint32_t)(2 * f + (a < c))};
            b->inc[b->vstart[a]++] = (uint32_t)f;
        }
    }
    return TESSEL_OK;
}

/* Edges, boundary edges and loops, non-manifold edges, orientation
 * conflicts, orientability and edge-connected components, from the
 * buckets (sorted here). */
static tessel_status edge_figures(const tessel_mesh *m, const uint8_t *kind, edge_buckets *b,
                                  tessel_mesh_report *r)
{
    size_t nv = m->vertex_count, nf = m->triangle_count;
    tessel_status st = TESSEL_ERR_NOMEM;
    uint32_t *comp = tsl_alloc_array(nf, sizeof *comp);
    uint32_t *bnd = tsl_alloc_array(nv, sizeof *bnd);
    uint8_t *on_boundary = tsl_calloc_array(nv, 1);
    parity_uf ori = {tsl_alloc_array(nf, sizeof(uint32_t)), tsl_alloc_array(nf, sizeof(uint32_t)),
                     tsl_calloc_array(nf, 1)};
    if (!comp || !bnd || !on_boundary || !ori.parent || !ori.size || !ori.par)
        goto done;
    for (size_t f = 0; f < nf; f++) {
        comp[f] = (uint32_t)f;
        ori.parent[f] = (uint32_t)f;
        ori.size[f] = 1;
    }
    for (size_t v = 0; v < nv; v++)
        bnd[v] = (uint32_t)v;
    size_t ne = 0, nb = 0, nnm = 0, ninc = 0;
    bool orientable = true;
    size_t begin = 0;
    for (size_t lo = 0; lo < nv; lo++) {
        size_t end = b->estart[lo];
        pair_u32 *half = b->half;
        /* Within a bucket, sort by (hi, face); fills went in face order. */
        sort_pairs(half + begin, end - begin);
        for (size_t i = begin; i < end;) {
            size_t j = i;
            while (j < end && half[j].a == half[i].a)
                j++;
            size_t c = j - i;
            ne++;
            if (c == 1) {
                nb++;
                tsl_uf_unite(bnd, (uint32_t)lo, half[i].a);
                on_boundary[lo] = on_boundary[half[i].a] = 1;
            } else {
                for (size_t t = i + 1; t < j; t++)
                    tsl_uf_unite(comp, half[i].b >> 1, half[t].b >> 1);
                if (c == 2) {
                    uint8_t fa = half[i].b & 1, fb = half[i + 1].b & 1;
                    if (fa == fb)
                        ninc++;
                    /* Consistent iff the faces run the edge in opposite
                     * directions: parity differs iff one must be flipped. */
                    if (!puf_unite(&ori, half[i].b >> 1, half[i + 1].b >> 1,
                                   (uint8_t)(fa ^ fb ^ 1)))
                        orientable = false;
                } else {
                    nnm++;
                }
            }
            i = j;
        }
        begin = end;
    }
    size_t ncomp = 0;
    for (size_t f = 0; f < nf; f++)
        if (kind[f] != KIND_REPEATED && tsl_uf_find(comp, (uint32_t)f) == f)
            ncomp++;
    size_t nloops = 0;
    for (size_t v = 0; v < nv; v++)
        if (on_boundary[v] && tsl_uf_find(bnd, (uint32_t)v) == v)
            nloops++;
    r->edges = ne;
    r->boundary_edges = nb;
    r->boundary_loops = nloops;
    r->nonmanifold_edges = nnm;
    r->orientation_conflicts = ninc;
    r->oriented = ninc == 0;
    r->orientable = orientable;
    r->components = ncomp;
    st = TESSEL_OK;
done:
    free(comp);
    free(bnd);
    free(on_boundary);
    free(ori.parent);
    free(ori.size);
    free(ori.par);
    return st;
}

/* Position of x in the sorted, distinct lv[0 .. u). */
static size_t link_position(const uint32_t *lv, size_t u, uint32_t x)
{
    size_t lo = 0, hi = u;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (lv[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* Vertex manifoldness: the link (opposite edges of the incident
 * triangles) must be connected with every link vertex of degree <= 2.
 * *referenced: vertices on some triangle; *nonmanifold: those that fail. */
static tessel_status vertex_figures(const tessel_mesh *m, const edge_buckets *b,
                                    size_t *referenced, size_t *nonmanifold)
{
    size_t nv = m->vertex_count;
    size_t maxval = 0, nvref = 0, nnmv = 0, begin = 0;
    for (size_t v = 0; v < nv; v++) {
        size_t val = b->vstart[v] - begin;
        if (val > maxval)
            maxval = val;
        begin = b->vstart[v];
    }
    uint32_t *lv = tsl_alloc_array(2 * maxval + 1, sizeof *lv);
    uint32_t *ldeg = tsl_alloc_array(2 * maxval + 1, sizeof *ldeg);
    uint32_t *lpar = tsl_alloc_array(2 * maxval + 1, sizeof *lpar);
    if (!lv || !ldeg || !lpar) {
        free(lv);
        free(ldeg);
        free(lpar);
        return TESSEL_ERR_NOMEM;
    }
    begin = 0;
    for (size_t v = 0; v < nv; v++) {
        size_t end = b->vstart[v];
        if (end == begin)
            continue;
        nvref++;
        size_t n = 0;
        for (size_t i = begin; i < end; i++) {
            const uint32_t *t = m->triangles + 3 * (size_t)b->inc[i];
            int k = t[0] == v ? 0 : t[1] == v ? 1 : 2;
            lv[n++] = t[(k + 1) % 3];
            lv[n++] = t[(k + 2) % 3];
        }
        /* sort + unique (insertion sort: stars are small) */
        for (size_t i = 1; i < n; i++) {
            uint32_t x = lv[i];
            size_t j = i;
            while (j > 0 && lv[j - 1] > x) {
                lv[j] = lv[j - 1];
                j--;
            }
            lv[j] = x;
        }
        size_t u = 0;
        for (size_t i = 0; i < n; i++)
            if (u == 0 || lv[u - 1] != lv[i])
                lv[u++] = lv[i];
        for (size_t i = 0; i < u; i++) {
            ldeg[i] = 0;
            lpar[i] = (uint32_t)i;
        }
        size_t groups = u;
        bool ok = true;
        for (size_t i = begin; i < end; i++) {
            const uint32_t *t = m->triangles + 3 * (size_t)b->inc[i];
            int k = t[0] == v ? 0 : t[1] == v ? 1 : 2;
            uint32_t ends[2] = {t[(k + 1) % 3], t[(k + 2) % 3]}, pos[2];
            for (int e = 0; e < 2; e++) {
                pos[e] = (uint32_t)link_position(lv, u, ends[e]);
                if (++ldeg[pos[e]] > 2)
                    ok = false;
            }
            uint32_t ra = tsl_uf_find(lpar, pos[0]), rb = tsl_uf_find(lpar, pos[1]);
            if (ra != rb) {
                tsl_uf_unite(lpar, ra, rb);
                groups--;
            }
        }
        if (!ok || groups != 1)
            nnmv++;
        begin = end;
    }
    free(lv);
    free(ldeg);
    free(lpar);
    *referenced = nvref;
    *nonmanifold = nnmv;
    return TESSEL_OK;
}

/* Edges, boundary, manifoldness, orientation, components, Euler, genus. */
static tessel_status topology(const tessel_mesh *m, const uint8_t *kind, tessel_mesh_report *r)
{
    edge_buckets b;
    memset(&b, 0, sizeof b);
    size_t nvref = 0;
    tessel_status st = buckets_fill(m, kind, &b);
    if (st == TESSEL_OK)
        st = edge_figures(m, kind, &b, r);
    if (st == TESSEL_OK)
        st = vertex_figures(m, &b, &nvref, &r->nonmanifold_vertices);
    if (st == TESSEL_OK) {
        r->euler = (long)nvref - (long)r->edges + (long)b.nt;
        bool closed = b.nt > 0 && r->boundary_edges == 0;
        bool manifold = r->nonmanifold_edges == 0 && r->nonmanifold_vertices == 0;
        r->genus = closed && manifold && r->orientable
                       ? (2 * (long)r->components - r->euler) / 2
                       : -1;
    }
    buckets_free(&b);
    return st;
}

/* Angle statistics and area over non-degenerate triangles. */
static void quality(const tessel_mesh *m, const uint8_t *kind, tessel_mesh_report *r)
{
    const double deg = 180.0 / 3.14159265358979323846;
    size_t n = 0;
    double min_min = INFINITY, max_max = -INFINITY, sum_min = 0.0, area = 0.0;
    for (size_t f = 0; f < m->triangle_count; f++) {
        if (kind[f] != KIND_OK)
            continue;
        double p[3][3];
        for (int k = 0; k < 3; k++)
            tsl_load(m->xyz + 3 * (size_t)m->triangles[3 * f + k], p[k]);
        double amin = INFINITY, amax = -INFINITY;
        for (int k = 0; k < 3; k++) {
            double u[3], w[3], c[3];
            tsl_sub(p[(k + 1) % 3], p[k], u);
            tsl_sub(p[(k + 2) % 3], p[k], w);
            tsl_cross(u, w, c);
            double a = atan2(tsl_norm(c), tsl_dot(u, w)) * deg;
            amin = fmin(amin, a);
            amax = fmax(amax, a);
        }
        double u[3], w[3], c[3];
        tsl_sub(p[1], p[0], u);
        tsl_sub(p[2], p[0], w);
        tsl_cross(u, w, c);
        area += 0.5 * tsl_norm(c);
        n++;
        sum_min += amin;
        min_min = fmin(min_min, amin);
        max_max = fmax(max_max, amax);
    }
    r->area = area;
    r->min_angle_deg = n ? min_min : NAN;
    r->max_angle_deg = n ? max_max : NAN;
    r->mean_min_angle_deg = n ? sum_min / (double)n : NAN;
}

tessel_status tessel_mesh_check(const tessel_mesh *mesh, const tessel_check_params *params,
                                tessel_mesh_report *report)
{
    if (!mesh || !report)
        return TESSEL_ERR_INVALID_ARG;
    tessel_check_params p = params ? *params : tessel_check_params_default();
    tessel_mesh_report r;
    memset(&r, 0, sizeof r);
    r.self_intersections = SIZE_MAX;
    r.self_intersecting_triangles = SIZE_MAX;
    r.genus = -1;
    r.input_distance_mean = r.input_distance_rms = r.input_distance_max = NAN;
    r.input_bbox_diagonal = NAN;
    r.chamfer = r.hausdorff = r.accuracy = r.completeness = NAN;
    r.precision = r.recall = r.fscore = r.tau = r.reference_bbox_diagonal = NAN;
    r.normal_consistency = r.normal_consistency_ref = NAN;
    if (mesh->vertex_count > 0 && !mesh->xyz)
        return TESSEL_ERR_INVALID_ARG;
    int threads = tsl_threads(p.threads);

    uint8_t *kind = NULL;
    surface s;
    memset(&s, 0, sizeof s);
    tessel_status st = tsl_check_classify(mesh, &kind, threads);
    if (st != TESSEL_OK)
        return st;
    r.vertices = mesh->vertex_count;
    r.triangles = mesh->triangle_count;
    for (size_t f = 0; f < mesh->triangle_count; f++)
        r.degenerate_triangles += kind[f] != KIND_OK;
    {
        uint8_t *ref = tsl_calloc_array(mesh->vertex_count, 1);
        if (!ref) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        for (size_t i = 0; i < 3 * mesh->triangle_count; i++)
            ref[mesh->triangles[i]] = 1;
        for (size_t v = 0; v < mesh->vertex_count; v++)
            r.unreferenced_vertices += !ref[v];
        free(ref);
    }
    r.bbox_diagonal = tsl_check_bbox_diagonal(mesh);
    st = count_duplicates(mesh, &r.duplicate_triangles);
    if (st == TESSEL_OK)
        st = topology(mesh, kind, &r);
    if (st == TESSEL_OK && p.self_intersections)
        st = tsl_check_self_intersections(mesh, kind, threads, &r.self_intersections,
                                &r.self_intersecting_triangles);
    if (st != TESSEL_OK)
        goto done;
    quality(mesh, kind, &r);

    if (p.input || p.reference) {
        const double zero[3] = {0.0, 0.0, 0.0};
        st = tsl_check_surface_build(&s, mesh, kind, zero);
        if (st == TESSEL_OK && p.input)
            st = tsl_check_input_figures(mesh, &s, p.input, threads, &r);
        if (st == TESSEL_OK && p.reference)
            st = tsl_check_reference_figures(mesh, &s, &p, threads, &r);
    }
done:
    free(kind);
    tsl_check_surface_free(&s);
    if (st == TESSEL_OK)
        *report = r;
    return st;
}
