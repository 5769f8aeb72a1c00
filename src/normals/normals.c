/* Normal estimation and consistent orientation (Hoppe, DeRose, Duchamp,
 * McDonald and Stuetzle, "Surface reconstruction from unorganized points",
 * SIGGRAPH 1992, sec. 3.2 and 3.3).
 *
 * Estimation (sec. 3.2): each point's tangent plane is fitted to its k
 * nearest neighbours (itself included) by principal component analysis;
 * the normal is the eigenvector of the smallest eigenvalue of their
 * covariance. Per point, threaded, exact neighbours: any thread count gives
 * the same bits.
 *
 * Orientation (sec. 3.3): the sign is propagated along a minimum spanning
 * tree of the symmetric k-NN graph ("Riemannian graph"), flipping n_j when
 * n_i . n_j < 0 along each tree edge (i, j). Hoppe et al. weight an edge
 * 1 - |n_i . n_j|, so the tree prefers to cross between nearly parallel
 * planes, where that test is reliable. We add how poorly each end's
 * neighbourhood defines a plane, (1 - c_i) + (1 - c_j) with
 * c = l1 / (l0 + l1) from the covariance eigenvalues l0 <= l1 <= l2
 * (c is 1 for a clean plane, 1/2 for a line or an isotropic blob): unreliable
 * normals then end up as leaves of the tree instead of relays. On the
 * noisy evaluation clouds (bench/README.md) this cut the normals pointing the wrong
 * way by up to 60% and never made it worse (docs/neighbours.md).
 *
 * Each connected component of the graph starts at its point of largest z:
 * no point of the component is above it, so it lies on the top supporting
 * plane of the component's convex hull; where the surface is smooth it is
 * tangent to that plane there, and the outward normal of a closed surface at
 * a point of its convex hull points away from the hull, i.e. +z. The seed
 * is therefore given n.z > 0 and the tree carries that outward sign to the
 * rest of the component. (Hoppe et al. seed at the largest z too.)
 *
 * A cloud with a viewpoint (a single scan) needs no propagation: every
 * point was seen from there, so the side of the surface it lies on faces
 * the viewpoint, and each normal is turned towards it. This is also right
 * for a room scanned from inside, where "+z at the top" would point every
 * normal out of the room.
 *
 * Prim's algorithm with an indexed binary heap: O(n k log n) time; memory
 * is the neighbour lists (n*k indices), the reverse edges the lists do not
 * already hold in both directions, and about 40 bytes per point, allocated
 * once. All of it works on points renumbered in the kd-tree's storage
 * order, where neighbours are near in memory. The traversal is sequential
 * and fully determined by the data (ties broken by position), so the result
 * does not depend on the thread count either. */
#include "core/core.h"

#include <stdlib.h>
#include <string.h>

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#define NORMALS_K_MIN 3
#define NORMALS_K_MAX 256
/* knn + PCA run in this many slices, with a progress call after each. */
#define NORMALS_SLICES 24
/* Progress calls during the spanning-tree traversal. */
#define ORIENT_STEPS 16

tessel_normals_params tessel_normals_params_default(void)
{
    tessel_normals_params p;
    p.k = 16;
    p.orient = 1;
    p.threads = 0;
    return p;
}

/* The index's float squared distance: same association and, like the
 * index, no fused multiply-add, so the reverse-edge test compares equal
 * values bit for bit. */
static inline float dist2_of(const float *p, const float *q)
{
    float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

/* PCA normal of point i from its k neighbours; *planarity gets
 * l1 / (l0 + l1) (see the file comment). */
static void pca_normal(const float *xyz, size_t i, const uint32_t *nb, size_t k, float out[3],
                       float *planarity)
{
    const float *p = xyz + 3 * i;
    double mean[3] = {0, 0, 0}, c[6] = {0, 0, 0, 0, 0, 0};
    /* Coordinates relative to the point itself keep the sums small. */
    for (size_t j = 0; j < k; j++) {
        const float *q = xyz + 3 * (size_t)nb[j];
        double d[3] = {(double)q[0] - p[0], (double)q[1] - p[1], (double)q[2] - p[2]};
        mean[0] += d[0];
        mean[1] += d[1];
        mean[2] += d[2];
        c[0] += d[0] * d[0];
        c[1] += d[0] * d[1];
        c[2] += d[0] * d[2];
        c[3] += d[1] * d[1];
        c[4] += d[1] * d[2];
        c[5] += d[2] * d[2];
    }
    double inv = 1.0 / (double)k;
    for (int a = 0; a < 3; a++)
        mean[a] *= inv;
    double a9[9];
    a9[0] = c[0] * inv - mean[0] * mean[0];
    a9[1] = a9[3] = c[1] * inv - mean[0] * mean[1];
    a9[2] = a9[6] = c[2] * inv - mean[0] * mean[2];
    a9[4] = c[3] * inv - mean[1] * mean[1];
    a9[5] = a9[7] = c[4] * inv - mean[1] * mean[2];
    a9[8] = c[5] * inv - mean[2] * mean[2];
    double w[3], v[9];
    tsl_eigen_sym3(a9, w, v);
    double n[3] = {v[0], v[3], v[6]}; /* column 0: smallest eigenvalue */
    /* Jacobi may leave a tiny negative l0 on exact planes. */
    double l0 = w[0] > 0.0 ? w[0] : 0.0, l1 = w[1] > 0.0 ? w[1] : 0.0;
    *planarity = l0 + l1 > 0.0 ? (float)(l1 / (l0 + l1)) : 0.5f;
    if (!(w[2] > 0.0) || !tsl_normalize(n)) {
        /* All neighbours at one spot: no plane to fit; any unit vector is
         * as good as another, +z keeps the output finite. */
        n[0] = n[1] = 0.0;
        n[2] = 1.0;
    }
    out[0] = (float)n[0];
    out[1] = (float)n[1];
    out[2] = (float)n[2];
}

/* ---- orientation ---- */

/* Indexed binary min-heap on (key, node). */
typedef struct prim_heap {
    uint32_t *heap; /* nodes */
    uint32_t *pos;  /* node -> heap slot; HEAP_OUT before, HEAP_DONE after */
    float *key;     /* node -> best edge cost to the tree */
    size_t size;
} prim_heap;

#define HEAP_OUT UINT32_MAX
#define HEAP_DONE (UINT32_MAX - 1)

static inline bool heap_less(const prim_heap *h, uint32_t a, uint32_t b)
{
    return h->key[a] < h->key[b] || (h->key[a] == h->key[b] && a < b);
}

static void heap_up(prim_heap *h, size_t i)
{
    uint32_t x = h->heap[i];
    while (i > 0) {
        size_t parent = (i - 1) / 2;
        uint32_t y = h->heap[parent];
        if (!heap_less(h, x, y))
            break;
        h->heap[i] = y;
        h->pos[y] = (uint32_t)i;
        i = parent;
    }
    h->heap[i] = x;
    h->pos[x] = (uint32_t)i;
}

static void heap_down(prim_heap *h, size_t i)
{
    uint32_t x = h->heap[i];
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= h->size)
            break;
        if (c + 1 < h->size && heap_less(h, h->heap[c + 1], h->heap[c]))
            c++;
        uint32_t y = h->heap[c];
        if (!heap_less(h, y, x))
            break;
        h->heap[i] = y;
        h->pos[y] = (uint32_t)i;
        i = c;
    }
    h->heap[i] = x;
    h->pos[x] = (uint32_t)i;
}

static uint32_t heap_pop(prim_heap *h)
{
    uint32_t top = h->heap[0];
    h->size--;
    if (h->size > 0) {
        h->heap[0] = h->heap[h->size];
        heap_down(h, 0);
    }
    h->pos[top] = HEAP_DONE;
    return top;
}

/* Offers node w at cost c (w not yet in the tree). */
static void heap_offer(prim_heap *h, uint32_t w, float c, uint32_t *from, uint32_t v)
{
    if (h->pos[w] == HEAP_OUT) {
        h->key[w] = c;
        from[w] = v;
        h->heap[h->size] = w;
        heap_up(h, h->size++);
    } else if (c < h->key[w]) {
        h->key[w] = c;
        from[w] = v;
        heap_up(h, h->pos[w]);
    }
}

/* Hoppe's edge weight plus the planarity term (file comment). */
static inline float edge_cost(const float *nrm, const float *planarity, uint32_t a, uint32_t b)
{
    const float *x = nrm + 3 * (size_t)a, *y = nrm + 3 * (size_t)b;
    float d = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    return (1.0f - fabsf(d)) + ((1.0f - planarity[a]) + (1.0f - planarity[b]));
}

static inline void flip(float *n)
{
    n[0] = -n[0];
    n[1] = -n[1];
    n[2] = -n[2];
}

/* Orients nrm (n unit normals) along minimum spanning trees of the
 * symmetric graph given by the neighbour lists nb (n rows of k). kth2[i] is
 * the squared distance of row i's last neighbour. */
static tessel_status orient_normals(const float *xyz, size_t n, const uint32_t *nb, size_t k,
                                    const float *kth2, const float *planarity, float *nrm,
                                    const tessel_callbacks *cb)
{
    tessel_status st = TESSEL_OK;
    /* Reverse edges: j lists i but i does not list j. i is in row j iff it
     * is nearer than j's last neighbour, or as near and found in the row. */
    size_t *roff = tsl_calloc_array(n + 1, sizeof *roff);
    uint32_t *radj = NULL;
    uint32_t *parent = tsl_alloc_array(n, sizeof *parent);
    uint32_t *from = NULL;
    prim_heap h = {0};
    if (!roff || !parent) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    for (size_t pass = 0; pass < 2; pass++) {
        for (size_t i = 0; i < n; i++) {
            for (size_t e = 0; e < k; e++) {
                uint32_t j = nb[i * k + e];
                if (j == i)
                    continue;
                float d = dist2_of(xyz + 3 * i, xyz + 3 * (size_t)j);
                bool listed = d < kth2[j];
                if (d == kth2[j])
                    for (size_t f = 0; f < k && !listed; f++)
                        listed = nb[(size_t)j * k + f] == i;
                if (listed)
                    continue;
                if (pass == 0)
                    roff[j + 1]++;
                else
                    radj[roff[j]++] = (uint32_t)i;
            }
        }
        if (pass == 0) {
            for (size_t i = 0; i < n; i++)
                roff[i + 1] += roff[i];
            radj = tsl_alloc_array(roff[n], sizeof *radj);
            if (!radj) {
                st = TESSEL_ERR_NOMEM;
                goto done;
            }
        } else {
            /* The fill advanced each start to the next row's start. */
            for (size_t i = n; i > 0; i--)
                roff[i] = roff[i - 1];
            roff[0] = 0;
        }
    }

    /* Components (union-find over the lists) and their highest point, the
     * lowest index among equals. */
    for (size_t i = 0; i < n; i++)
        parent[i] = (uint32_t)i;
    for (size_t i = 0; i < n; i++)
        for (size_t e = 0; e < k; e++) {
            uint32_t a = tsl_uf_find(parent, (uint32_t)i), b = tsl_uf_find(parent, nb[i * k + e]);
            if (a != b) {
                if (a < b)
                    parent[b] = a;
                else
                    parent[a] = b;
            }
        }
    from = tsl_alloc_array(n, sizeof *from);
    h.heap = tsl_alloc_array(n, sizeof *h.heap);
    h.pos = tsl_alloc_array(n, sizeof *h.pos);
    h.key = tsl_alloc_array(n, sizeof *h.key);
    if (!from || !h.heap || !h.pos || !h.key) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    /* Roots are the smallest index of their component. from[root] holds
     * the component's highest point (lowest index among equals) until the
     * traversal of that component reads it. */
    for (size_t i = 0; i < n; i++) {
        uint32_t r = tsl_uf_find(parent, (uint32_t)i);
        if (r == i || xyz[3 * i + 2] > xyz[3 * (size_t)from[r] + 2])
            from[r] = (uint32_t)i;
    }
    for (size_t i = 0; i < n; i++)
        h.pos[i] = HEAP_OUT;

    size_t done_count = 0, next_report = n / ORIENT_STEPS + 1;
    for (size_t r = 0; r < n && st == TESSEL_OK; r++) {
        if (parent[r] != r)
            continue;
        size_t s = from[r];
        /* The seed: n.z > 0 (see the file comment). */
        if (nrm[3 * s + 2] < 0.0f)
            flip(nrm + 3 * s);
        h.key[s] = 0.0f;
        from[s] = (uint32_t)s;
        h.heap[0] = (uint32_t)s;
        h.pos[s] = 0;
        h.size = 1;
        while (h.size > 0) {
            uint32_t v = heap_pop(&h);
            if (from[v] != v) {
                const float *nu = nrm + 3 * (size_t)from[v];
                float *nv = nrm + 3 * (size_t)v;
                if (nu[0] * nv[0] + nu[1] * nv[1] + nu[2] * nv[2] < 0.0f)
                    flip(nv);
            }
            for (size_t e = 0; e < k; e++) {
                uint32_t w = nb[(size_t)v * k + e];
                if (h.pos[w] != HEAP_DONE)
                    heap_offer(&h, w, edge_cost(nrm, planarity, v, w), from, v);
            }
            for (size_t e = roff[v]; e < roff[v + 1]; e++) {
                uint32_t w = radj[e];
                if (h.pos[w] != HEAP_DONE)
                    heap_offer(&h, w, edge_cost(nrm, planarity, v, w), from, v);
            }
            if (++done_count >= next_report) {
                next_report += n / ORIENT_STEPS + 1;
                st = tsl_progress(cb, "normals", 0.7 + 0.3 * (double)done_count / (double)n);
                if (st != TESSEL_OK)
                    break;
            }
        }
    }
done:
    free(roff);
    free(radj);
    free(parent);
    free(from);
    free(h.heap);
    free(h.pos);
    free(h.key);
    return st;
}

tessel_status tessel_normals_estimate(tessel_cloud *cloud, const tessel_normals_params *params,
                                      const tessel_callbacks *callbacks)
{
    tessel_normals_params p = params ? *params : tessel_normals_params_default();
    if (!cloud || (cloud->count > 0 && !cloud->xyz) || p.k < NORMALS_K_MIN ||
        p.k > NORMALS_K_MAX)
        return TESSEL_ERR_INVALID_ARG;
    size_t n = cloud->count;
    if (n < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;
    size_t k = p.k < n ? p.k : n;
    size_t slots;
    if (!tsl_mul_size(n, k, &slots))
        return TESSEL_ERR_NOMEM;

    tessel_index *ix = NULL;
    tessel_status st = tessel_index_build(&ix, cloud->xyz, n);
    if (st != TESSEL_OK)
        return st; /* non-finite coordinates are refused there */

    /* Everything below works on points renumbered in the index's storage
     * order ("tree order"), where neighbours are close in memory: position t
     * is point order[t], and rank[] is the inverse. The graph arrays are
     * only needed for the spanning-tree orientation. */
    bool mst = p.orient && !cloud->has_viewpoint;
    double vp[3];
    for (int a = 0; a < 3; a++)
        vp[a] = cloud->viewpoint[a] - cloud->offset[a];
    uint32_t *order = tsl_alloc_array(n, sizeof *order);
    float *nrm = tsl_alloc_array(n, 3 * sizeof *nrm); /* tree order */
    float *out = tsl_alloc_array(n, 3 * sizeof *out);  /* input order */
    uint32_t *rank = NULL, *nb = NULL;
    float *kth2 = NULL, *xyz_t = NULL, *planarity = NULL;
    if (mst) {
        rank = tsl_alloc_array(n, sizeof *rank);
        nb = tsl_alloc_array(slots, sizeof *nb);
        kth2 = tsl_alloc_array(n, sizeof *kth2);
        planarity = tsl_alloc_array(n, sizeof *planarity);
        xyz_t = tsl_alloc_array(n, 3 * sizeof *xyz_t);
    }
    if (!order || !nrm || !out || (mst && (!rank || !nb || !kth2 || !planarity || !xyz_t))) {
        st = TESSEL_ERR_NOMEM;
    } else {
        tsl_index_order(ix, order);
        for (size_t t = 0; mst && t < n; t++) {
            rank[order[t]] = (uint32_t)t;
            memcpy(xyz_t + 3 * t, cloud->xyz + 3 * (size_t)order[t], 3 * sizeof(float));
        }
    }

    int nthreads = tsl_threads(p.threads);
    (void)nthreads;
    size_t slice = (n + NORMALS_SLICES - 1) / NORMALS_SLICES;
    for (size_t s0 = 0; s0 < n && st == TESSEL_OK; s0 += slice) {
        ptrdiff_t end = (ptrdiff_t)(n - s0 < slice ? n : s0 + slice);
#pragma omp parallel for schedule(dynamic, 512) num_threads(nthreads)
        for (ptrdiff_t t = (ptrdiff_t)s0; t < end; t++) {
            size_t i = order[t];
            uint32_t idx[NORMALS_K_MAX];
            float d2[NORMALS_K_MAX], plan;
            float *nt = nrm + 3 * (size_t)t;
            const float *pt = cloud->xyz + 3 * i;
            tessel_index_knn(ix, pt, k, idx, d2);
            pca_normal(cloud->xyz, i, idx, k, nt, &plan);
            if (mst) {
                planarity[t] = plan;
                kth2[t] = d2[k - 1];
                for (size_t j = 0; j < k; j++)
                    nb[(size_t)t * k + j] = rank[idx[j]];
            } else if (p.orient) {
                /* Seen from the viewpoint: face it (file comment). */
                double toward = nt[0] * (vp[0] - pt[0]) + nt[1] * (vp[1] - pt[1]) +
                                nt[2] * (vp[2] - pt[2]);
                if (toward < 0.0)
                    flip(nt);
            }
        }
        st = tsl_progress(callbacks, "normals", (mst ? 0.6 : 1.0) * (double)end / (double)n);
    }
    tessel_index_destroy(ix);
    free(rank);
    if (st == TESSEL_OK && mst) {
        st = tsl_progress(callbacks, "normals", 0.65);
        if (st == TESSEL_OK)
            st = orient_normals(xyz_t, n, nb, k, kth2, planarity, nrm, callbacks);
    }
    free(nb);
    free(kth2);
    free(xyz_t);
    free(planarity);
    if (st == TESSEL_OK)
        for (size_t t = 0; t < n; t++)
            memcpy(out + 3 * (size_t)order[t], nrm + 3 * t, 3 * sizeof(float));
    free(order);
    free(nrm);
    if (st != TESSEL_OK) {
        free(out);
        return st;
    }
    free(cloud->normals);
    cloud->normals = out;
    if (mst) /* the work is done: a cancel request here comes too late */
        (void)tsl_progress(callbacks, "normals", 1.0);
    return TESSEL_OK;
}
