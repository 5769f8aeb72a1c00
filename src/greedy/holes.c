/* Small holes of a held greedy mesh reopened and meshed again, and the
 * count of the mesh (components, boundary edges, points by fate) that
 * decides whether a repair stays, with the fragments it drops
 * (docs/greedy.md, "Small holes" and "Fragments"; not in Gopi & Krishnan
 * 2002). After a first count over the
 * whole mesh, a repair is counted around what it changed when that
 * provably leaves the components as they were: at 10^7 points each count
 * over the whole mesh took 0.4 s for a repair of a few hundred triangles. */
#include "greedy/greedy.h"

/* The front that closes a small hole sees the points within this many
 * spheres of influence of the hole's vertices (local.c). */
#define HOLE_CONTEXT 6.0

/* Pieces of fewer triangles than this are dropped, when the mesh has a
 * piece of SPECK_BESIDE times more. A component of SPECK_GATE triangles
 * or more can lose a few without becoming such a piece. */
#define SPECK_TRIANGLES 64
#define SPECK_BESIDE 64
#define SPECK_GATE (SPECK_BESIDE * SPECK_TRIANGLES)

/* Flags in hole[] the vertices of the boundary loops of at most max_hole
 * edges; returns how many loops, or -1 without memory. Only the
 * half-edges between vertices of open fans (sum: tsl_open_fans of the
 * mesh) are matched, by sorting. */
static long small_loops(const uint32_t *tri, size_t nt, size_t n, const uint64_t *sum,
                        uint32_t max_hole, int threads, uint8_t *hole)
{
    uint64_t *half = NULL;
    uint32_t *next = NULL, *from = NULL;
    long loops = -1;
    size_t nh = 0, nf = 0;
    ptrdiff_t corners = 3 * (ptrdiff_t)nt;
    /* The half-edges between open fans, in any order: sorted below. */
#pragma omp parallel for schedule(static) reduction(+ : nh) num_threads(tsl_threads(threads))
    for (ptrdiff_t i = 0; i < corners; i++)
        nh += sum[tri[i]] && sum[tri[i % 3 == 2 ? i - 2 : i + 1]];
    half = tsl_alloc_array(nh + 1, sizeof *half);
    next = tsl_alloc_array(n + 1, sizeof *next);
    from = tsl_alloc_array(nh + 1, sizeof *from);
    if (!half || !next || !from)
        goto done;
    size_t at = 0;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (ptrdiff_t i = 0; i < corners; i++) {
        uint64_t a = tri[i], b = tri[i % 3 == 2 ? i - 2 : i + 1];
        if (sum[a] && sum[b]) /* the edge's key, its direction in the low bit */
            half[__atomic_fetch_add(&at, 1, __ATOMIC_RELAXED)] =
                a < b ? (a << 33 | b << 1) : (b << 33 | a << 1 | 1);
    }
    qsort(half, nh, sizeof *half, tsl_cmp_u64);
    memset(next, 0xff, (n + 1) * sizeof *next);
    for (size_t i = 0; i < nh;) {
        size_t j = i;
        while (j < nh && half[j] >> 1 == half[i] >> 1)
            j++;
        if (j - i == 1) {
            uint32_t lo = (uint32_t)(half[i] >> 33), hi = (uint32_t)(half[i] >> 1) & 0xffffffffu;
            uint32_t a = half[i] & 1 ? hi : lo, b = half[i] & 1 ? lo : hi;
            if (next[a] == NONE)
                from[nf++] = a;
            next[a] = next[a] == NONE ? b : (uint32_t)n; /* n: two open edges (a pinch) */
        }
        i = j;
    }
    /* Each loop once, from its lowest vertex. */
    qsort(from, nf, sizeof *from, tsl_cmp_u32);
    loops = 0;
    for (size_t i = 0; i < nf; i++) {
        uint32_t v = from[i], k = 0, x = v, low = v;
        while (k <= max_hole && next[x] < n && (k == 0 || x != v)) {
            low = x < low ? x : low;
            x = next[x];
            k++;
        }
        if (x != v || k < 3 || k > max_hole || low != v)
            continue;
        loops++;
        do {
            hole[x] = 1;
            x = next[x];
        } while (x != v);
    }
done:
    free(half);
    free(next);
    free(from);
    return loops;
}

/* ---- the count ---- */

void tsl_gp_count_free(gp_count *c)
{
    free(c->comp);
    free(c->size);
    free(c->used);
    free(c->open);
    memset(c, 0, sizeof *c);
}

/* used: the points on a triangle of tri (nt of them), each thread setting
 * the bits of its own words. */
static void mark_used(const uint32_t *tri, size_t nt, size_t n, int threads, uint64_t *used)
{
    size_t words = n / 64 + 1;
    memset(used, 0, words * sizeof *used);
#pragma omp parallel num_threads(tsl_threads(threads))
    {
        uint32_t lo, width;
        tsl_thread_share(words, &lo, &width);
        for (size_t i = 0; i < 3 * nt; i++) {
            uint32_t v = tri[i];
            if ((v >> 6) - lo < width)
                used[v >> 6] |= (uint64_t)1 << (v & 63);
        }
    }
}

/* c->comp[v] for the used points (components numbered in the order of
 * their lowest point) and c->size[] their triangles, c->ncomp, c->most.
 * A component's root is its lowest point, so one pass in point order
 * meets each root before the rest of its component. */
static tessel_status label_components(const gp_collect *all, size_t n, int threads, gp_count *c)
{
    uint32_t *comp = c->comp;
    tsl_vertex_components(all->tris, all->count, n, threads, comp);
    c->ncomp = 0;
    for (size_t v = 0; v < n; v++)
        comp[v] = !tsl_bit(c->used, (uint32_t)v) ? TESSEL_NONE
                  : comp[v] == v                 ? (uint32_t)c->ncomp++
                                                 : comp[comp[v]];
    ptrdiff_t nt = (ptrdiff_t)all->count;
    free(c->size);
    if (!(c->size = tsl_calloc_array(c->ncomp + 1, sizeof *c->size)))
        return TESSEL_ERR_NOMEM;
    uint32_t most = 0;
#pragma omp parallel num_threads(tsl_threads(threads))
    {
        uint32_t lo, width;
        tsl_thread_share(c->ncomp, &lo, &width);
        for (ptrdiff_t t = 0; t < nt; t++) {
            uint32_t k = comp[all->tris[3 * t]];
            if (k - lo < width)
                c->size[k]++;
        }
#pragma omp barrier
#pragma omp for schedule(static) reduction(max : most)
        for (ptrdiff_t k = 0; k < (ptrdiff_t)c->ncomp; k++)
            most = c->size[k] > most ? c->size[k] : most;
    }
    c->most = most;
    return TESSEL_OK;
}

tessel_status tsl_gp_drop_specks_and_count(size_t n, gp_collect *all, uint8_t *fate, int threads,
                                           gp_count *c, tessel_recon_summary *summary)
{
    size_t words = n / 64 + 1;
    if (!c->comp && (!(c->comp = tsl_alloc_array(n + 1, sizeof *c->comp)) ||
                     !(c->used = tsl_alloc_array(words, sizeof *c->used)) ||
                     !(c->open = tsl_alloc_array(n + 1, sizeof *c->open)))) {
        tsl_gp_count_free(c);
        return TESSEL_ERR_NOMEM;
    }
    mark_used(all->tris, all->count, n, threads, c->used);
    tessel_status st = label_components(all, n, threads, c);
    if (st)
        return st;
    size_t components = c->ncomp;
    if (c->most >= SPECK_GATE) {
        size_t w = 0;
        for (size_t t = 0; t < all->count; t++) {
            uint32_t *v = all->tris + 3 * t;
            if (c->size[c->comp[v[0]]] < SPECK_TRIANGLES) {
                fate[v[0]] = fate[v[1]] = fate[v[2]] = FATE_CLOSED_IN;
                continue;
            }
            memmove(all->tris + 3 * w++, v, 3 * sizeof *v);
        }
        if (w < all->count) {
            all->count = w;
            mark_used(all->tris, all->count, n, threads, c->used);
            for (size_t k = 0; k < c->ncomp; k++)
                components -= c->size[k] < SPECK_TRIANGLES;
        }
    }
    /* Every vertex has a single fan: one boundary edge per open fan. */
    tsl_open_fans(all->tris, all->count, n, threads, c->open);
    size_t count[FATE_UNTRIANGULATED + 1] = {0}, boundary = 0;
    ptrdiff_t nv = (ptrdiff_t)n;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads)) \
    reduction(+ : count[:FATE_UNTRIANGULATED + 1], boundary)
    for (ptrdiff_t i = 0; i < nv; i++) {
        count[tsl_bit(c->used, (uint32_t)i) ? FATE_USED : fate[i]]++;
        boundary += c->open[i] != 0;
    }
    summary->boundary_edges = boundary;
    summary->components = components;
    summary->points_used = count[FATE_USED];
    summary->left_duplicate = count[FATE_DUPLICATE];
    summary->left_isolated = count[FATE_ISOLATED];
    summary->left_closed_in = count[FATE_CLOSED_IN];
    summary->left_untriangulated = count[FATE_UNTRIANGULATED];
    summary->triangles = all->count;
    summary->points_in = n;
    return TESSEL_OK;
}

/* ---- a repair's count, around what it changed ----
 * A repair removes the triangles `gone` and adds `made`. The triangles
 * of the mesh after it with a point on either (the collar, made among
 * them) join their points into groups, the removed triangles theirs into
 * clusters. Each group's points used before must be of one component
 * (none joined), every group must have one (no piece of new triangles
 * only), each cluster's points still on the mesh must lie in one group
 * (none split: a path of before through removed triangles enters and
 * leaves them at points of one cluster and goes round through that group)
 * and every cluster must have one (none emptied). Then the components are
 * those of before; when none falls under SPECK_GATE triangles either (no
 * speck to drop), the counts change only at the repair's points and at
 * those whose fate the front set, and the mesh is not counted again. */

/* A repair's triangles: removed, and made (at the end of the mesh). */
typedef struct repair {
    const uint32_t *gone, *made;
    size_t ngone, nmade;
} repair;

/* The repair's points by number (open addressing from point to number),
 * in two union-finds: `group` over the collar's triangles, `cluster` over
 * the removed ones. */
typedef struct repair_points {
    uint32_t *key, *id; /* the table: point, its number + 1 (0: empty) */
    size_t mask;
    uint32_t *point, *group, *cluster, *label, *via;
    uint8_t *after;  /* on a triangle of the mesh after the repair */
    uint8_t *before; /* on a triangle before it */
    size_t count;
} repair_points;

static uint32_t *slot_of(const repair_points *p, uint32_t v)
{
    size_t h = (size_t)tsl_mix64(v) & p->mask;
    while (p->id[h] && p->key[h] != v)
        h = (h + 1) & p->mask;
    return &p->id[h];
}

/* v's number, or TESSEL_NONE when v is not one of the repair's points. */
static uint32_t number_of(const repair_points *p, uint32_t v)
{
    uint32_t id = *slot_of(p, v);
    return id ? id - 1 : TESSEL_NONE;
}

static void join_points(repair_points *p, uint32_t *parent, const uint32_t *v, bool after,
                        const uint64_t *used)
{
    uint32_t k3[3];
    for (int k = 0; k < 3; k++) {
        uint32_t *id = slot_of(p, v[k]);
        if (!*id) {
            size_t i = p->count++;
            p->key[id - p->id] = v[k];
            *id = (uint32_t)p->count;
            p->point[i] = v[k];
            p->group[i] = p->cluster[i] = (uint32_t)i;
            p->after[i] = 0;
            p->before[i] = tsl_bit(used, v[k]);
        }
        k3[k] = *id - 1;
        p->after[k3[k]] |= after;
    }
    tsl_uf_unite(parent, k3[0], k3[1]);
    tsl_uf_unite(parent, k3[0], k3[2]);
}

static void repair_points_free(repair_points *p)
{
    free(p->key);
    free(p->id);
    free(p->point);
    free(p->group);
    free(p->cluster);
    free(p->label);
    free(p->via);
    free(p->after);
    free(p->before);
}

/* The collar: the triangles of the mesh with a point flagged in mark (a
 * bit per point), in order. */
static uint32_t *collar_of(const gp_collect *all, const uint64_t *mark, int threads,
                           size_t *count)
{
    ptrdiff_t nt = (ptrdiff_t)all->count;
    size_t m = 0, at = 0;
#pragma omp parallel for schedule(static) reduction(+ : m) num_threads(tsl_threads(threads))
    for (ptrdiff_t t = 0; t < nt; t++) {
        const uint32_t *v = all->tris + 3 * t;
        m += tsl_bit(mark, v[0]) || tsl_bit(mark, v[1]) || tsl_bit(mark, v[2]);
    }
    uint32_t *list = tsl_alloc_array(m + 1, sizeof *list);
    *count = m;
    if (!list)
        return NULL;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (ptrdiff_t t = 0; t < nt; t++) {
        const uint32_t *v = all->tris + 3 * t;
        if (tsl_bit(mark, v[0]) || tsl_bit(mark, v[1]) || tsl_bit(mark, v[2]))
            list[__atomic_fetch_add(&at, 1, __ATOMIC_RELAXED)] = (uint32_t)t;
    }
    qsort(list, m, sizeof *list, tsl_cmp_u32);
    return list;
}

/* The repair's points with their groups and clusters. */
static tessel_status gather_points(size_t n, const gp_collect *all, const repair *r,
                                   const gp_count *c, int threads, repair_points *p)
{
    memset(p, 0, sizeof *p);
    uint64_t *mark = tsl_calloc_array(n / 64 + 1, sizeof *mark);
    if (!mark)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < 3 * (r->ngone + r->nmade); i++) {
        uint32_t v = i < 3 * r->ngone ? r->gone[i] : r->made[i - 3 * r->ngone];
        mark[v >> 6] |= (uint64_t)1 << (v & 63);
    }
    size_t ncollar = 0;
    uint32_t *collar = collar_of(all, mark, threads, &ncollar);
    free(mark);
    if (!collar)
        return TESSEL_ERR_NOMEM;
    size_t cap = 3 * (ncollar + r->ngone) + 1, table = 2;
    while (table < 2 * cap)
        table *= 2;
    p->mask = table - 1;
    if (!(p->key = tsl_alloc_array(table, sizeof *p->key)) ||
        !(p->id = tsl_calloc_array(table, sizeof *p->id)) ||
        !(p->point = tsl_alloc_array(cap, sizeof *p->point)) ||
        !(p->group = tsl_alloc_array(cap, sizeof *p->group)) ||
        !(p->cluster = tsl_alloc_array(cap, sizeof *p->cluster)) ||
        !(p->label = tsl_alloc_array(cap, sizeof *p->label)) ||
        !(p->via = tsl_alloc_array(cap, sizeof *p->via)) ||
        !(p->after = tsl_alloc_array(cap, 1)) || !(p->before = tsl_alloc_array(cap, 1))) {
        free(collar);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < ncollar; i++)
        join_points(p, p->group, all->tris + 3 * (size_t)collar[i], true, c->used);
    for (size_t t = 0; t < r->ngone; t++)
        join_points(p, p->cluster, r->gone + 3 * t, false, c->used);
    free(collar);
    return TESSEL_OK;
}

/* Whether the components after the repair are those of before (see
 * above), with each group's component in p->label[] (by group root). */
static bool same_components(repair_points *p, const repair *r, const gp_count *c)
{
    for (size_t i = 0; i < p->count; i++)
        p->label[i] = p->via[i] = TESSEL_NONE;
    for (size_t i = 0; i < p->count; i++) {
        if (!p->after[i])
            continue;
        uint32_t g = tsl_uf_find(p->group, (uint32_t)i);
        uint32_t *via = &p->via[tsl_uf_find(p->cluster, (uint32_t)i)];
        if (*via == TESSEL_NONE)
            *via = g;
        if (*via != g)
            return false; /* split */
        if (!p->before[i])
            continue;
        uint32_t k = c->comp[p->point[i]];
        if (p->label[g] == TESSEL_NONE)
            p->label[g] = k;
        if (p->label[g] != k)
            return false; /* joined */
    }
    for (size_t i = 0; i < p->count; i++)
        if (p->after[i] && tsl_uf_find(p->group, (uint32_t)i) == i && p->label[i] == TESSEL_NONE)
            return false; /* new triangles only */
    for (size_t t = 0; t < r->ngone; t++)
        if (p->via[tsl_uf_find(p->cluster, number_of(p, r->gone[3 * t]))] == TESSEL_NONE)
            return false; /* emptied */
    return true;
}

/* A component and its change in triangles. */
typedef struct comp_delta {
    uint32_t comp;
    long delta;
} comp_delta;

static int cmp_comp(const void *pa, const void *pb)
{
    const comp_delta *a = pa, *b = pb;
    return (a->comp > b->comp) - (a->comp < b->comp);
}

static comp_delta *delta_of(comp_delta *d, size_t nd, uint32_t comp)
{
    comp_delta key = {comp, 0};
    return bsearch(&key, d, nd, sizeof *d, cmp_comp);
}

/* The repair's components with their change in triangles (by component,
 * *nd of them), or NULL when one would fall under SPECK_GATE triangles
 * (or without memory: *st). */
static comp_delta *comp_deltas(repair_points *p, const repair *r, const gp_count *c, size_t *nd,
                               tessel_status *st)
{
    size_t m = 0, k = 0;
    for (size_t i = 0; i < p->count; i++)
        m += p->after[i] && tsl_uf_find(p->group, (uint32_t)i) == i;
    comp_delta *d = tsl_alloc_array(m + 1, sizeof *d);
    if (!d) {
        *st = TESSEL_ERR_NOMEM;
        return NULL;
    }
    m = 0;
    for (size_t i = 0; i < p->count; i++)
        if (p->after[i] && tsl_uf_find(p->group, (uint32_t)i) == i)
            d[m++] = (comp_delta){p->label[i], 0};
    qsort(d, m, sizeof *d, cmp_comp);
    for (size_t i = 0; i < m; i++)
        if (!k || d[k - 1].comp != d[i].comp)
            d[k++] = d[i];
    bool ok = true;
    for (size_t t = 0; ok && t < r->ngone; t++) {
        comp_delta *x = delta_of(d, k, c->comp[r->gone[3 * t]]);
        ok = x != NULL;
        if (x)
            x->delta--;
    }
    for (size_t t = 0; ok && t < r->nmade; t++)
        delta_of(d, k, p->label[tsl_uf_find(p->group, number_of(p, r->made[3 * t]))])->delta++;
    for (size_t i = 0; ok && i < k; i++)
        ok = (long)c->size[d[i].comp] + d[i].delta >= SPECK_GATE;
    if (!ok) {
        free(d);
        return NULL;
    }
    *nd = k;
    return d;
}

/* One triangle's share of tsl_open_fans, added (sign 1) or taken away (-1). */
static void open_fans_add(uint64_t *sum, const uint32_t *v, int sign)
{
    for (int k = 0; k < 3; k++) {
        uint64_t ab = tsl_mix64(v[(k + 1) % 3]), ba = tsl_mix64(v[k]);
        sum[v[k]] += sign > 0 ? ab : -ab;
        sum[v[(k + 1) % 3]] -= sign > 0 ? ba : -ba;
    }
}

/* The repair into the count (after: the points' use after it) or out of
 * it again: open fans, used points, components' triangles. */
static void count_change(const repair *r, const repair_points *p, const comp_delta *d, size_t nd,
                         bool after, gp_count *c)
{
    for (size_t t = 0; t < r->ngone; t++)
        open_fans_add(c->open, r->gone + 3 * t, after ? -1 : 1);
    for (size_t t = 0; t < r->nmade; t++)
        open_fans_add(c->open, r->made + 3 * t, after ? 1 : -1);
    for (size_t i = 0; i < p->count; i++) {
        uint32_t v = p->point[i];
        uint64_t bit = (uint64_t)1 << (v & 63);
        c->used[v >> 6] = (after ? p->after[i] : p->before[i]) ? c->used[v >> 6] | bit
                                                                : c->used[v >> 6] & ~bit;
    }
    for (size_t i = 0; i < nd; i++)
        c->size[d[i].comp] += (uint32_t)(after ? d[i].delta : -d[i].delta);
}

/* The summary after the repair, whose components are those of before:
 * boundary edges and points by fate change only at the repair's points
 * and at those the front looked at (sel), whose fate was fate_before. */
static void count_repair(size_t n, const repair *r, const repair_points *p, const comp_delta *d,
                         size_t nd, const uint8_t *sel, const uint8_t *fate_before,
                         const uint8_t *fate, size_t triangles, gp_count *c,
                         tessel_recon_summary *summary)
{
    long count[FATE_UNTRIANGULATED + 1] = {0}, boundary = 0;
    /* Points of the front's that are not the repair's keep their use. */
    for (size_t i = 0; i < n; i++)
        if (sel[i] && number_of(p, (uint32_t)i) == TESSEL_NONE && !tsl_bit(c->used, (uint32_t)i)) {
            count[fate_before[i]]--;
            count[fate[i]]++;
        }
    for (size_t i = 0; i < p->count; i++) {
        uint32_t v = p->point[i];
        count[p->before[i] ? FATE_USED : fate_before[v]]--;
        boundary -= c->open[v] != 0;
    }
    count_change(r, p, d, nd, true, c);
    for (size_t i = 0; i < p->count; i++) {
        uint32_t v = p->point[i];
        count[p->after[i] ? FATE_USED : fate[v]]++;
        boundary += c->open[v] != 0;
    }
    /* The points the repair brings in join their group's component. */
    for (size_t i = 0; i < p->count; i++)
        if (p->after[i] && !p->before[i])
            c->comp[p->point[i]] = p->label[tsl_uf_find(p->group, (uint32_t)i)];
    summary->boundary_edges += (size_t)boundary;
    summary->points_used += (size_t)count[FATE_USED];
    summary->left_duplicate += (size_t)count[FATE_DUPLICATE];
    summary->left_isolated += (size_t)count[FATE_ISOLATED];
    summary->left_closed_in += (size_t)count[FATE_CLOSED_IN];
    summary->left_untriangulated += (size_t)count[FATE_UNTRIANGULATED];
    summary->triangles = triangles;
}

/* ---- the repair ---- */

/* Whether the repair r is counted here: *d (NULL: count the whole mesh),
 * with *p its points. */
static tessel_status count_locally(size_t n, const gp_collect *all, const repair *r,
                                   const uint8_t *sel, const uint8_t *fate_before,
                                   const uint8_t *fate, int threads, gp_count *c,
                                   repair_points *p, comp_delta **d, size_t *nd,
                                   tessel_recon_summary *summary)
{
    *d = NULL;
    if (!c->comp || c->most < SPECK_GATE)
        return TESSEL_OK;
    tessel_status st = gather_points(n, all, r, c, threads, p);
    if (!st && same_components(p, r, c))
        *d = comp_deltas(p, r, c, nd, &st);
    if (*d) {
        count_repair(n, r, p, *d, *nd, sel, fate_before, fate, all->count, c, summary);
        c->local++;
    }
    return st;
}

tessel_status tsl_gp_reopen_holes(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                  const tessel_callbacks *callbacks, gp_collect *all,
                                  uint8_t *fate, uint8_t *dirty, gp_count *c,
                                  tessel_recon_summary *summary, int rings, bool *holes)
{
    *holes = false;
    if (params->max_hole < 3)
        return TESSEL_OK;
    size_t n = cloud->count, nd = 0;
    int threads = params->threads;
    uint8_t *hole = tsl_calloc_array(n + 1, 1), *touched = tsl_calloc_array(n + 1, 1);
    uint8_t *sel = tsl_calloc_array(n + 1, 1), *saved_fate = NULL;
    gp_collect old = *all, gone = {NULL, 0, 0};
    uint32_t *gone_fans = NULL;
    size_t ngone_fans = 0;
    repair_points p = {0};
    comp_delta *d = NULL;
    long loops = hole && touched && sel
                     ? small_loops(all->tris, all->count, n, c->open, params->max_hole, threads,
                                   hole)
                     : -1;
    *holes = loops > 0;
    tessel_status s = loops < 0 ? TESSEL_ERR_NOMEM : TESSEL_OK;
    if (loops <= 0)
        goto done;
    /* The loops' vertices and `rings` rings of triangles around them
     * (sel as scratch). */
    ptrdiff_t nt = (ptrdiff_t)old.count;
    for (int r = 0; r < rings; r++) {
        memcpy(sel, hole, n);
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
        for (ptrdiff_t t = 0; t < nt; t++) {
            const uint32_t *v = old.tris + 3 * t;
            if (sel[v[0]] || sel[v[1]] || sel[v[2]])
                for (int k = 0; k < 3; k++)
                    __atomic_store_n(&hole[v[k]], 1, __ATOMIC_RELAXED);
        }
    }
    memset(sel, 0, n);
    /* The kept triangles go to a new array of the old one's room (growing
     * past it would double it): the old one, as it was, is what an undone
     * repair goes back to. */
    if (!(saved_fate = tsl_alloc_array(n, 1)) ||
        !(all->tris = tsl_alloc_array(3 * old.cap + 1, sizeof *all->tris))) {
        all->tris = old.tris;
        s = TESSEL_ERR_NOMEM;
        goto done;
    }
    all->count = 0;
    memcpy(saved_fate, fate, n);
    tessel_recon_summary before = *summary;
    s = tsl_gp_select_near(cloud->xyz, n, hole, HOLE_CONTEXT * summary->mu * summary->spacing,
                           threads, sel);
    tsl_gp_select_meshed(n, fate, NULL, 0.0, sel);
    for (size_t t = 0; s == TESSEL_OK && t < old.count; t++) {
        const uint32_t *v = old.tris + 3 * t;
        if (hole[v[0]] || hole[v[1]] || hole[v[2]]) {
            touched[v[0]] = touched[v[1]] = touched[v[2]] = 1;
            s = tsl_gp_collect_emit(&gone, v, 1);
            continue;
        }
        memcpy(all->tris + 3 * all->count++, v, 3 * sizeof *v);
    }
    tessel_greedy_params hp = *params;
    hp.mu = summary->mu;
    hp.mu_from_sampling = 0;
    if (s == TESSEL_OK)
        s = tsl_single_fans(n, all->tris, &all->count, touched, &gone_fans, &ngone_fans);
    if (s == TESSEL_OK)
        s = tsl_gp_collect_emit(&gone, gone_fans, ngone_fans);
    size_t from = all->count;
    if (s == TESSEL_OK)
        s = tsl_gp_local_pass(cloud, sel, &hp, "greedy: hole repair", callbacks, all, fate,
                              dirty, summary);
    repair r = {gone.tris, all->tris + 3 * from, gone.count, all->count - from};
    if (s == TESSEL_OK)
        s = count_locally(n, all, &r, sel, saved_fate, fate, threads, c, &p, &d, &nd, summary);
    if (s == TESSEL_OK && !d)
        s = tsl_gp_drop_specks_and_count(n, all, fate, threads, c, summary);
    if (s != TESSEL_OK)
        goto done;
    /* Joined or split, or more open: undone. */
    if (summary->components != before.components ||
        summary->boundary_edges > before.boundary_edges) {
        if (d)
            count_change(&r, &p, d, nd, false, c);
        free(all->tris);
        *all = old;
        memcpy(fate, saved_fate, n);
        if (!d) /* the count of the mesh as it was, again */
            s = tsl_gp_drop_specks_and_count(n, all, fate, threads, c, summary);
        *summary = before;
    }
done:
    if (old.tris != all->tris)
        free(old.tris);
    free(hole);
    free(touched);
    free(sel);
    free(saved_fate);
    free(gone.tris);
    free(gone_fans);
    repair_points_free(&p);
    free(d);
    return s;
}
