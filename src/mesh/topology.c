/* Mesh topology shared by the methods: the corners of each vertex, the
 * removal of triangles that leave a vertex with more than one fan, and
 * connected components by shared vertices. */
#include "mesh/mesh.h"

#include <stdlib.h>
#include <string.h>

tessel_status tsl_vertex_corners(const uint32_t *tri, size_t nt, size_t nv, uint32_t **start,
                                 uint32_t **corner)
{
    uint32_t *s = tsl_calloc_array(nv + 1, sizeof *s);
    uint32_t *c = tsl_alloc_array(3 * nt + 1, sizeof *c);
    if (!s || !c) {
        free(s);
        free(c);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < 3 * nt; i++)
        s[tri[i] + 1]++;
    for (size_t v = 0; v < nv; v++)
        s[v + 1] += s[v];
    for (size_t i = 0; i < 3 * nt; i++)
        c[s[tri[i]]++] = (uint32_t)i;
    /* The fill advanced every start to the next vertex's; shift back. */
    memmove(s + 1, s, nv * sizeof *s);
    s[0] = 0;
    *start = s;
    *corner = c;
    return TESSEL_OK;
}

/* The triangles at the vertices of `want` (a bit per vertex) that are not
 * in sub yet, appended to it (flag IN_SUB), and those vertices marked
 * covered: every triangle at a covered vertex is in sub. One pass over the
 * triangles: a vertex's star is gathered when it is first judged, so the
 * cost follows the number of rounds, not a table of every vertex's corners
 * (10^7 points: 0.9 s for a few hundred vertices at a hole). */
#define ALIVE 1u
#define IN_SUB 2u

typedef struct fan_sub {
    uint32_t *t;
    size_t count, cap;
} fan_sub;


static tessel_status gather_stars(const uint32_t *tri, size_t nt, uint8_t *flag,
                                  const uint64_t *want, fan_sub *sub)
{
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *v = tri + 3 * t;
        if ((flag[t] & IN_SUB) || !(tsl_bit(want, v[0]) || tsl_bit(want, v[1]) || tsl_bit(want, v[2])))
            continue;
        if (tsl_grow((void **)&sub->t, &sub->cap, sub->count + 1, sizeof *sub->t))
            return TESSEL_ERR_NOMEM;
        sub->t[sub->count++] = (uint32_t)t;
        flag[t] |= IN_SUB;
    }
    return TESSEL_OK;
}

/* Whether vertex v, with the corners c[0 .. m) of its alive triangles, has
 * more than one border edge leaving it (more than one fan). */
static bool several_fans(const uint32_t *tri, const uint32_t *c, size_t m)
{
    unsigned border = 0;
    for (size_t a = 0; a < m && border < 2; a++) {
        uint32_t after = tri[3 * (c[a] / 3) + (c[a] + 1) % 3];
        bool twin = false;
        for (size_t b = 0; b < m && !twin; b++)
            twin = tri[3 * (c[b] / 3) + (c[b] + 2) % 3] == after;
        border += !twin;
    }
    return border > 1;
}

tessel_status tsl_single_fans(size_t n, uint32_t *tri, size_t *count, uint8_t *touched,
                              uint32_t **gone, size_t *ngone)
{
    size_t nt = *count, words = n / 64 + 1;
    uint8_t *flag = tsl_alloc_array(nt + 1, sizeof *flag);
    uint64_t *want = tsl_calloc_array(words, sizeof *want);
    uint64_t *covered = tsl_calloc_array(words, sizeof *covered);
    uint32_t *slot = tsl_alloc_array(n + 1, sizeof *slot);
    uint32_t *todo = tsl_alloc_array(n + 1, sizeof *todo);
    uint32_t *later = tsl_alloc_array(n + 1, sizeof *later);
    uint32_t *first = NULL, *corner = NULL;
    fan_sub sub = {NULL, 0, 0};
    size_t cap_first = 0, cap_corner = 0;
    tessel_status st = flag && want && covered && slot && todo && later ? TESSEL_OK
                                                                       : TESSEL_ERR_NOMEM;
    if (st)
        goto done;
    memset(flag, ALIVE, nt);
    memset(slot, 0xff, n * sizeof *slot);
    size_t ntodo = 0;
    for (size_t v = 0; v < n; v++)
        if (touched[v])
            todo[ntodo++] = (uint32_t)v;
    while (ntodo) {
        /* Each round judges its vertices on the triangles alive when it
         * starts, then drops: dropping at one vertex as soon as it is seen
         * would change what the next one sees, and more pieces get cut off
         * (man.ply, greedy's repair: 24 components against 17). */
        bool more = false;
        for (size_t q = 0; q < ntodo; q++) {
            uint32_t v = todo[q];
            if (!tsl_bit(covered, v)) {
                want[v >> 6] |= (uint64_t)1 << (v & 63);
                covered[v >> 6] |= (uint64_t)1 << (v & 63);
                more = true;
            }
        }
        if (more && (st = gather_stars(tri, nt, flag, want, &sub)))
            goto done;
        if (more)
            memset(want, 0, words * sizeof *want);
        /* The alive corners of this round's vertices, from sub. */
        if (tsl_grow((void **)&first, &cap_first, ntodo + 1, sizeof *first)) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        memset(first, 0, (ntodo + 1) * sizeof *first);
        for (size_t q = 0; q < ntodo; q++)
            slot[todo[q]] = (uint32_t)q;
        for (size_t i = 0; i < sub.count; i++)
            for (int k = 0; k < 3 && (flag[sub.t[i]] & ALIVE); k++) {
                uint32_t q = slot[tri[3 * (size_t)sub.t[i] + (size_t)k]];
                if (q != TESSEL_NONE)
                    first[q + 1]++;
            }
        for (size_t q = 0; q < ntodo; q++)
            first[q + 1] += first[q];
        if (tsl_grow((void **)&corner, &cap_corner, (size_t)first[ntodo] + 1, sizeof *corner)) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        for (size_t i = 0; i < sub.count; i++)
            for (int k = 0; k < 3 && (flag[sub.t[i]] & ALIVE); k++) {
                uint32_t q = slot[tri[3 * (size_t)sub.t[i] + (size_t)k]];
                if (q != TESSEL_NONE)
                    corner[first[q]++] = 3 * sub.t[i] + (uint32_t)k;
            }
        /* The fill advanced every first to the next vertex's; shift back. */
        memmove(first + 1, first, ntodo * sizeof *first);
        first[0] = 0;
        size_t nbad = 0;
        for (size_t q = 0; q < ntodo; q++) {
            uint32_t v = todo[q];
            touched[v] = 0;
            slot[v] = TESSEL_NONE;
            if (several_fans(tri, corner + first[q], first[q + 1] - first[q]))
                todo[nbad++] = (uint32_t)q; /* nbad <= q: read already */
        }
        size_t next = 0;
        for (size_t b = 0; b < nbad; b++) {
            uint32_t q = todo[b];
            for (uint32_t a = first[q]; a < first[q + 1]; a++) {
                uint32_t t = corner[a] / 3;
                if (!(flag[t] & ALIVE))
                    continue;
                flag[t] &= (uint8_t)~ALIVE;
                for (int i = 0; i < 3; i++) {
                    uint32_t w = tri[3 * t + (uint32_t)i];
                    if (!touched[w]) {
                        touched[w] = 1;
                        later[next++] = w;
                    }
                }
            }
        }
        uint32_t *swap = todo;
        todo = later;
        later = swap;
        ntodo = next;
    }
    size_t kept = 0, dropped = 0;
    if (gone) {
        for (size_t t = 0; t < nt; t++)
            dropped += !(flag[t] & ALIVE);
        if (!(*gone = tsl_alloc_array(3 * dropped + 1, sizeof **gone))) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        *ngone = dropped;
        dropped = 0;
    }
    for (size_t t = 0; t < nt; t++) {
        if (flag[t] & ALIVE)
            memmove(tri + 3 * kept++, tri + 3 * t, 3 * sizeof *tri);
        else if (gone)
            memcpy(*gone + 3 * dropped++, tri + 3 * t, 3 * sizeof *tri);
    }
    *count = kept;
done:
    free(flag);
    free(want);
    free(covered);
    free(slot);
    free(todo);
    free(later);
    free(first);
    free(corner);
    free(sub.t);
    return st;
}

/* Union-find shared by threads. A link is made only from a root to a
 * smaller root, by compare-and-swap, and path halving only moves a
 * non-root's parent to one of its ancestors: every set ends rooted at its
 * smallest member, as tsl_uf_unite's do, whatever the interleaving. */
static uint32_t find_shared(uint32_t *parent, uint32_t x)
{
    for (;;) {
        uint32_t p = __atomic_load_n(&parent[x], __ATOMIC_RELAXED);
        if (p == x)
            return x;
        uint32_t g = __atomic_load_n(&parent[p], __ATOMIC_RELAXED);
        if (g != p)
            __atomic_store_n(&parent[x], g, __ATOMIC_RELAXED);
        x = g;
    }
}

static void unite_shared(uint32_t *parent, uint32_t a, uint32_t b)
{
    for (;;) {
        a = find_shared(parent, a);
        b = find_shared(parent, b);
        if (a == b)
            return;
        uint32_t hi = a > b ? a : b, lo = a > b ? b : a, expect = hi;
        if (__atomic_compare_exchange_n(&parent[hi], &expect, lo, false, __ATOMIC_RELAXED,
                                        __ATOMIC_RELAXED))
            return;
    }
}

void tsl_vertex_components(const uint32_t *tri, size_t nt, size_t nv, int threads,
                           uint32_t *root)
{
    ptrdiff_t n = (ptrdiff_t)nv, m = (ptrdiff_t)nt;
#pragma omp parallel num_threads(tsl_threads(threads))
    {
#pragma omp for schedule(static)
        for (ptrdiff_t v = 0; v < n; v++)
            root[v] = (uint32_t)v;
#pragma omp for schedule(static)
        for (ptrdiff_t t = 0; t < m; t++) {
            const uint32_t *c = tri + 3 * t;
            if (c[0] == TESSEL_NONE)
                continue;
            unite_shared(root, c[0], c[1]);
            unite_shared(root, c[0], c[2]);
        }
        /* Read-only walks here: a thread halving a path could overwrite
         * a root just written with a vertex below it. */
#pragma omp for schedule(static)
        for (ptrdiff_t v = 0; v < n; v++) {
            uint32_t r = (uint32_t)v, p;
            while ((p = __atomic_load_n(&root[r], __ATOMIC_RELAXED)) != r)
                r = p;
            __atomic_store_n(&root[v], r, __ATOMIC_RELAXED);
        }
    }
}

tessel_status tsl_triangle_components(const uint32_t *tri, size_t nt, size_t nv, int threads,
                                      uint32_t *comp, size_t *ncomp)
{
    uint32_t *root = tsl_alloc_array(nv + 1, sizeof *root);
    uint32_t *label = tsl_alloc_array(nv + 1, sizeof *label);
    *ncomp = 0;
    if (!root || !label) {
        free(root);
        free(label);
        return TESSEL_ERR_NOMEM;
    }
    tsl_vertex_components(tri, nt, nv, threads, root);
    for (size_t v = 0; v < nv; v++)
        label[v] = TESSEL_NONE;
    for (size_t t = 0; t < nt; t++) {
        uint32_t r = root[tri[3 * t]];
        if (label[r] == TESSEL_NONE)
            label[r] = (uint32_t)(*ncomp)++;
        comp[t] = label[r];
    }
    free(root);
    free(label);
    return TESSEL_OK;
}

void tsl_open_fans(const uint32_t *tri, size_t nt, size_t nv, int threads, uint64_t *sum)
{
    memset(sum, 0, nv * sizeof *sum);
    /* Wrapping sums: the same in any order. */
#pragma omp parallel num_threads(tsl_threads(threads))
    {
        uint32_t lo, width;
        tsl_thread_share(nv, &lo, &width);
        for (size_t t = 0; t < nt; t++)
            for (int k = 0; k < 3; k++) {
                uint32_t a = tri[3 * t + (size_t)k], b = tri[3 * t + (size_t)(k + 1) % 3];
                if (a - lo < width)
                    sum[a] += tsl_mix64(b);
                if (b - lo < width)
                    sum[b] -= tsl_mix64(a);
            }
    }
}
