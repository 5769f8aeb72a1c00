/* What greedy does with the whole mesh held (not in Gopi & Krishnan 2002;
 * docs/greedy.md): the front's triangles are kept until it stops, then
 *
 * 1. regions meshed inside out are found and rebuilt. The front orients
 *    each new triangle like the triangles already at its reference point
 *    (section 4.2). Where it steps from one sheet onto another that faces
 *    it closer than the sampling can separate (a hand on a thigh), it
 *    carries the wrong side across, and the region behind the step comes
 *    out inside out although every edge agrees with its neighbours. Only a
 *    global test sees it: the ray-parity check of src/mesh/orient.c, or, when
 *    the points have normals or a viewpoint, their verdict (a noisy scan
 *    folds the front over itself the same way). The regions found facing
 *    the wrong way are flipped, their rims and the triangles
 *    at points left with two fans (tsl_single_fans) dropped, and the front
 *    runs again from what is left (params.existing) to mesh the seams.
 * 1a. fragments, pieces of a few triangles beside a large one, are
 *    dropped (tsl_gp_drop_specks_and_count, holes.c);
 * 1b. small holes the front's ear clipping could not close are reopened
 *    and meshed again by a front over the points near them
 *    (tsl_gp_reopen_holes, holes.c).
 * 2. diagonals are flipped where the two angles facing them add up to
 *    more than pi, the Delaunay rule (tsl_flip_diagonals, with the
 *    refinement's checks). Joining
 *    consecutive neighbours in angle order leaves many slivers, mostly
 *    where two parts of the front meet; the flips remove most of them
 *    without moving or adding a vertex.
 * 3. folded flaps, a point of three triangles outside the triangle of its
 *    neighbours (one triangle lies flat over the other two), become that
 *    triangle (unfold_flaps).
 *
 * Then everything goes to the sink. */
#include "greedy/greedy.h"

/* The flips after tiles leave triangles with an edge over this many times
 * the mean longest edge of those they look at as they are. */
#define FLIP_LONG 3.0

/* Flags the vertices of the triangles marked 2 (the rims to drop): only
 * they can be left with more than one fan. */
static uint8_t *rim_vertices(const uint32_t *tri, size_t nt, const uint8_t *mark, size_t nv)
{
    uint8_t *touched = tsl_calloc_array(nv, sizeof *touched);
    for (size_t t = 0; touched && t < nt; t++)
        if (mark[t] == 2)
            for (int k = 0; k < 3; k++)
                touched[tri[3 * t + (size_t)k]] = 1;
    return touched;
}

/* The second pass's summary describes the output; the work of the first
 * (seeds, holes, refusals) is added to it. */
static void merge_summary(tessel_recon_summary *out, const tessel_recon_summary *first)
{
    out->tiles = first->tiles;
    out->seeds += first->seeds;
    out->holes_closed += first->holes_closed;
    out->rejected_intersecting += first->rejected_intersecting;
    out->flips += first->flips;
    out->reoriented = first->reoriented;
}

/* The front once more over every point from the triangles in all (as
 * params.existing), its new triangles added to all, with the mu the mesh
 * was made with (the tiles' largest, not the whole cloud's estimate). */
static tessel_status front_again(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                 const char *stage, const tessel_callbacks *callbacks,
                                 gp_collect *all, uint8_t *fate, tessel_recon_summary *summary)
{
    gp_collect more = {NULL, 0, 0};
    tessel_greedy_params again = *params;
    again.existing = all->tris;
    again.existing_count = all->count;
    if (summary->mu > 0.0) {
        again.mu = summary->mu;
        again.mu_from_sampling = 0;
    }
    tessel_recon_summary first = *summary;
    tessel_triangle_sink hold = {tsl_gp_collect_emit, &more};
    tessel_status s = tsl_gp_pass(cloud, &again, stage, callbacks, &hold, fate, summary);
    if (s == TESSEL_OK) {
        merge_summary(summary, &first);
        s = tsl_gp_collect_emit(all, more.tris, more.count);
    }
    free(more.tris);
    return s;
}

/* Step 1: the orientation check (by ray parity, or by the points' normals
 * or viewpoint when the cloud has them), and the repair when a region is
 * found inside out; all holds the mesh before and after. */
static tessel_status check_and_repair(const tessel_cloud *cloud,
                                      const tessel_greedy_params *params,
                                      const tessel_callbacks *callbacks, gp_collect *all,
                                      uint8_t *fate, tessel_recon_summary *summary)
{
    uint8_t *mark = tsl_alloc_array(all->count + 1, sizeof *mark);
    size_t flipped = 0;
    tessel_status s = mark ? tsl_progress(callbacks, "orientation check", 0.0)
                           : TESSEL_ERR_NOMEM;
    bool known_side = cloud->has_viewpoint ||
                      (cloud->normals && tsl_normals_signed(cloud->normals, all->tris, all->count));
    if (s == TESSEL_OK && known_side) {
        /* The scanner's side, in the points' frame. */
        double vp[3];
        for (int k = 0; k < 3; k++)
            vp[k] = cloud->viewpoint[k] - cloud->offset[k];
        s = tsl_orient_check_toward(cloud->xyz, cloud->count, all->tris, all->count,
                                    cloud->has_viewpoint ? NULL : cloud->normals, vp, params->threads, mark,
                                    &flipped);
    } else if (s == TESSEL_OK) {
        s = tsl_orient_check(cloud->xyz, cloud->count, all->tris, all->count, params->threads, mark,
                             &flipped);
    }
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, "orientation check", 1.0);
    if (s == TESSEL_OK && flipped) {
        uint8_t *touched = rim_vertices(all->tris, all->count, mark, cloud->count);
        all->count = tsl_orient_apply(all->tris, all->count, mark, all->tris);
        free(mark);
        mark = NULL;
        s = touched ? tsl_single_fans(cloud->count, all->tris, &all->count, touched, NULL, NULL)
                    : TESSEL_ERR_NOMEM;
        free(touched);
        if (s == TESSEL_OK)
            s = front_again(cloud, params, "greedy: orientation repair", callbacks, all, fate,
                            summary);
        summary->reoriented = flipped;
    }
    free(mark);
    return s;
}

/* Step 2 after tiles: the tiles flipped their own triangles, so only
 * those with a vertex on a triangle made since (seams, repairs: dirty)
 * are flipped, less those with an edge over FLIP_LONG mean edges (a few
 * slivers at borders, which would widen the part below for all), in a
 * part of the mesh that holds every triangle such a flip could meet (the
 * rest fixed). tsl_flip_diagonals keeps new diagonals within the longest
 * edge L of the triangles it flips, so a flip stays within L of each
 * vertex of its pair: the part holds every triangle whose box meets the
 * cells within L of those vertices. */
static tessel_status flip_dirty(const tessel_cloud *cloud, gp_collect *all, const uint8_t *dirty,
                                int threads, size_t *flips)
{
    size_t n = cloud->count, nt = all->count, m = 0;
    uint8_t *flip = tsl_alloc_array(nt + 1, 1), *seed = tsl_calloc_array(n + 1, 1);
    tsl_gp_near near = {0};
    tessel_status s = flip && seed ? TESSEL_OK : TESSEL_ERR_NOMEM;
    ptrdiff_t count_t = s == TESSEL_OK ? (ptrdiff_t)nt : 0;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (ptrdiff_t t = 0; t < count_t; t++) {
        const uint32_t *v = all->tris + 3 * t;
        flip[t] = dirty[v[0]] || dirty[v[1]] || dirty[v[2]];
    }
    /* The mean in triangle order, on one thread: the same sum for any
     * thread count (the dirty triangles are a few percent). */
    double sum = 0.0;
    size_t count = 0;
    for (ptrdiff_t t = 0; t < count_t; t++)
        if (flip[t]) {
            sum += sqrt(tsl_longest_edge2(cloud->xyz, all->tris + 3 * t, 1, NULL));
            count++;
        }
    double cap = count ? FLIP_LONG * sum / (double)count : 0.0, l2 = 0.0;
#pragma omp parallel for schedule(static) reduction(max : l2) num_threads(tsl_threads(threads))
    for (ptrdiff_t t = 0; t < count_t; t++) {
        const uint32_t *v = all->tris + 3 * t;
        double e2 = flip[t] ? tsl_longest_edge2(cloud->xyz, v, 1, NULL) : 0.0;
        flip[t] = flip[t] && e2 <= cap * cap;
        if (!flip[t])
            continue;
        l2 = e2 > l2 ? e2 : l2;
        for (int k = 0; k < 3; k++)
            __atomic_store_n(&seed[v[k]], 1, __ATOMIC_RELAXED);
    }
    if (s == TESSEL_OK)
        s = tsl_gp_near_build(cloud->xyz, n, seed, sqrt(l2), &near);
#pragma omp parallel for schedule(static) reduction(+ : m) num_threads(tsl_threads(threads))
    for (ptrdiff_t t = 0; t < count_t; t++) {
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int k = 0; !flip[t] && k < 3; k++)
            for (int c = 0; c < 3; c++) {
                float x = cloud->xyz[3 * (size_t)all->tris[3 * (size_t)t + (size_t)k] + (size_t)c];
                lo[c] = x < lo[c] ? x : lo[c];
                hi[c] = x > hi[c] ? x : hi[c];
            }
        const double dlo[3] = {lo[0], lo[1], lo[2]}, dhi[3] = {hi[0], hi[1], hi[2]};
        flip[t] = flip[t] ? 2 : tsl_gp_near_box(&near, dlo, dhi) ? 1 : 0;
        m += flip[t] != 0;
    }
    uint32_t *part = tsl_alloc_array(3 * m + 1, sizeof *part);
    uint32_t *at = tsl_alloc_array(m + 1, sizeof *at);
    uint8_t *fixed = tsl_alloc_array(m + 1, 1);
    if (s == TESSEL_OK && (!part || !at || !fixed))
        s = TESSEL_ERR_NOMEM;
    m = 0;
    for (size_t t = 0; s == TESSEL_OK && t < nt; t++) {
        if (!flip[t])
            continue;
        memcpy(part + 3 * m, all->tris + 3 * t, 3 * sizeof *part);
        fixed[m] = flip[t] == 1;
        at[m++] = (uint32_t)t;
    }
    if (s == TESSEL_OK)
        s = tsl_flip_diagonals(cloud->xyz, n, part, m, fixed, threads, flips);
    for (size_t i = 0; s == TESSEL_OK && i < m; i++)
        memcpy(all->tris + 3 * (size_t)at[i], part + 3 * i, 3 * sizeof *part);
    tsl_gp_near_free(&near);
    free(flip);
    free(seed);
    free(part);
    free(at);
    free(fixed);
    return s;
}

/* Unit normal of triangle (a, b, c) of the cloud's points (0 if degenerate). */
static void normal_of(const float *xyz, uint32_t a, uint32_t b, uint32_t c, double n[3])
{
    double p[3][3];
    tsl_load(xyz + 3 * (size_t)a, p[0]);
    tsl_load(xyz + 3 * (size_t)b, p[1]);
    tsl_load(xyz + 3 * (size_t)c, p[2]);
    tsl_tri_normal(p[0], p[1], p[2], n);
}

static int cmp_pair(const void *pa, const void *pb)
{
    const uint32_t *a = pa, *b = pb;
    return a[0] != b[0] ? (a[0] < b[0] ? -1 : 1) : (a[1] > b[1]) - (a[1] < b[1]);
}

/* Point v's closed fan of three triangles (V, A, B), (V, B, C), (V, C, A),
 * listed in t, as the triangle (A, B, C) it should be when v lies outside
 * that triangle: one of the three lies folded flat over the other two (the
 * ear that closed a 3-edge hole over a fold). 0 if the fan is not such a
 * flap. deg: triangles per point (4 meaning four or more). */
static int flap_link(const float *xyz, const uint32_t *tris, const uint32_t t[3], uint32_t v,
                     const uint8_t *deg, uint32_t abc[3])
{
    uint32_t x[3], y[3];
    for (int i = 0; i < 3; i++) {
        const uint32_t *T = tris + 3 * (size_t)t[i];
        int k = T[0] == v ? 0 : T[1] == v ? 1 : 2;
        x[i] = T[(k + 1) % 3];
        y[i] = T[(k + 2) % 3];
    }
    /* The fan closes: each triangle's second corner is the next one's first. */
    int next[3];
    for (int i = 0; i < 3; i++) {
        next[i] = -1;
        for (int j = 0; j < 3; j++)
            if (j != i && x[j] == y[i])
                next[i] = j;
        if (next[i] < 0)
            return 0;
    }
    abc[0] = x[0];
    abc[1] = x[next[0]];
    abc[2] = x[next[next[0]]];
    /* A point of exactly three triangles would be left with one (a
     * tetrahedron's faces): not a flap. */
    for (int i = 0; i < 3; i++)
        if (deg[abc[i]] < 4)
            return 0;
    double n[3], m[3];
    normal_of(xyz, abc[0], abc[1], abc[2], n);
    if (!(tsl_dot(n, n) > 0.0))
        return 0;
    int agree = 0;
    for (int i = 0; i < 3; i++) {
        normal_of(xyz, v, x[i], y[i], m);
        agree += tsl_dot(m, n) > 0.0;
    }
    return agree == 2;
}

/* A flap found: its point, its three triangles and the triangle that
 * would replace them, with that triangle's box. */
typedef struct flap {
    uint32_t v, t[3], abc[3];
    float lo[3], hi[3];
    bool crossed;
} flap;

static int cmp_flap_lo(const void *pa, const void *pb)
{
    const flap *a = pa, *b = pb;
    return (a->lo[0] > b->lo[0]) - (a->lo[0] < b->lo[0]);
}

static bool crosses(const float *xyz, const uint32_t ia[3], const uint32_t ib[3])
{
    double a[3][3], b[3][3];
    for (int i = 0; i < 3; i++) {
        tsl_load(xyz + 3 * (size_t)ia[i], a[i]);
        tsl_load(xyz + 3 * (size_t)ib[i], b[i]);
    }
    const double *pa[3] = {a[0], a[1], a[2]}, *pb[3] = {b[0], b[1], b[2]};
    return !tsl_triangle_degenerate(pb) && tsl_triangles_intersect(ia, pa, ib, pb);
}

/* Marks the flaps whose new triangle would cross a triangle of the mesh
 * other than its own three, or another flap's new triangle: on clouds
 * far from the paper's sampling (a lattice's coplanar rows) the fold can
 * hold other triangles between its sheets. Flaps by their boxes' low x;
 * each triangle meets those within the widest flap box of its own. */
static void mark_crossed(const float *xyz, const gp_collect *all, flap *f, size_t nf,
                         int threads)
{
    qsort(f, nf, sizeof *f, cmp_flap_lo);
    float wide = 0.0f;
    for (size_t k = 0; k < nf; k++)
        wide = f[k].hi[0] - f[k].lo[0] > wide ? f[k].hi[0] - f[k].lo[0] : wide;
    /* Each triangle's tests on the threads; a flap once crossed stays so
     * (the flag only ever becomes true: the same for any thread count). */
    ptrdiff_t nt = (ptrdiff_t)all->count;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (ptrdiff_t t = 0; t < nt; t++) {
        const uint32_t *v = all->tris + 3 * t;
        float lo[3], hi[3];
        tsl_tri_box(xyz, v, lo, hi);
        size_t a = 0, b = nf; /* the first flap with lo[0] >= lo - wide */
        while (a < b) {
            size_t mid = a + (b - a) / 2;
            if (f[mid].lo[0] < lo[0] - wide)
                a = mid + 1;
            else
                b = mid;
        }
        for (size_t k = a; k < nf && f[k].lo[0] <= hi[0]; k++)
            if (!__atomic_load_n(&f[k].crossed, __ATOMIC_RELAXED) && (uint32_t)t != f[k].t[0] &&
                (uint32_t)t != f[k].t[1] && (uint32_t)t != f[k].t[2] &&
                tsl_boxes_overlap(lo, hi, f[k].lo, f[k].hi) && crosses(xyz, f[k].abc, v))
                __atomic_store_n(&f[k].crossed, true, __ATOMIC_RELAXED);
    }
    for (size_t k = 0; k < nf; k++)
        for (size_t j = k + 1; j < nf && f[j].lo[0] <= f[k].hi[0]; j++)
            if (tsl_boxes_overlap(f[k].lo, f[k].hi, f[j].lo, f[j].hi) &&
                crosses(xyz, f[k].abc, f[j].abc))
                f[k].crossed = f[j].crossed = true;
}

/* Step 3: folded flaps, points of three triangles lying outside the
 * triangle of their three neighbours (see flap_link): the three become
 * that triangle and the point is left out, closed in by the surface,
 * unless that triangle would cross the mesh. Boundary edges and
 * components do not change. *count: flaps removed. */
static tessel_status unfold_flaps(const float *xyz, size_t n, gp_collect *all, int threads,
                                  uint8_t *fate, size_t *count)
{
    *count = 0;
    uint8_t *deg = tsl_calloc_array(n + 1, 1);
    if (!deg)
        return TESSEL_ERR_NOMEM;
    ptrdiff_t corners = 3 * (ptrdiff_t)all->count;
    size_t np = 0;
#pragma omp parallel num_threads(tsl_threads(threads))
    {
        uint32_t lo, width;
        tsl_thread_share(n, &lo, &width);
        for (ptrdiff_t i = 0; i < corners; i++) {
            uint32_t v = all->tris[i];
            if (v - lo < width)
                deg[v] += deg[v] < 4;
        }
#pragma omp barrier
#pragma omp for schedule(static) reduction(+ : np)
        for (ptrdiff_t i = 0; i < corners; i++)
            np += deg[all->tris[i]] == 3;
    }
    /* (point, triangle) pairs of the points of three triangles, by point. */
    uint32_t *pair = tsl_alloc_array(2 * np + 2, sizeof *pair);
    flap *f = tsl_alloc_array(np / 3 + 1, sizeof *f);
    uint8_t *taken = tsl_calloc_array(all->count + 1, 1);
    if (!pair || !f || !taken) {
        free(deg);
        free(pair);
        free(f);
        free(taken);
        return TESSEL_ERR_NOMEM;
    }
    /* The pairs in any order: sorted next (each pair is distinct). */
    size_t at = 0;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (ptrdiff_t i = 0; i < corners; i++)
        if (deg[all->tris[i]] == 3) {
            size_t k = __atomic_fetch_add(&at, 1, __ATOMIC_RELAXED);
            pair[2 * k] = all->tris[i];
            pair[2 * k + 1] = (uint32_t)(i / 3);
        }
    qsort(pair, np, 2 * sizeof *pair, cmp_pair);
    uint32_t *tris = all->tris;
    size_t nf = 0;
    for (size_t i = 0; i + 3 <= np; i += 3) {
        flap *x = &f[nf];
        x->v = pair[2 * i];
        for (int k = 0; k < 3; k++)
            x->t[k] = pair[2 * (i + (size_t)k) + 1];
        /* A flap found before took one of v's triangles: v has fewer now. */
        if (taken[x->t[0]] || taken[x->t[1]] || taken[x->t[2]] ||
            !flap_link(xyz, tris, x->t, x->v, deg, x->abc))
            continue;
        for (int k = 0; k < 3; k++) {
            taken[x->t[k]] = 1;
            deg[x->abc[k]] -= deg[x->abc[k]] < 4;
        }
        deg[x->v] = 0;
        tsl_tri_box(xyz, x->abc, x->lo, x->hi);
        double p[3][3];
        for (int k = 0; k < 3; k++)
            tsl_load(xyz + 3 * (size_t)x->abc[k], p[k]);
        const double *pp[3] = {p[0], p[1], p[2]};
        x->crossed = tsl_triangle_degenerate(pp);
        nf++;
    }
    mark_crossed(xyz, all, f, nf, threads);
    for (size_t k = 0; k < nf; k++) {
        if (f[k].crossed)
            continue;
        memcpy(tris + 3 * (size_t)f[k].t[0], f[k].abc, sizeof f[k].abc);
        tris[3 * (size_t)f[k].t[1]] = tris[3 * (size_t)f[k].t[2]] = TESSEL_NONE;
        fate[f[k].v] = FATE_CLOSED_IN;
        (*count)++;
    }
    if (*count) {
        size_t w = 0;
        for (size_t t = 0; t < all->count; t++)
            if (tris[3 * t] != TESSEL_NONE)
                memmove(tris + 3 * w++, tris + 3 * t, 3 * sizeof *tris);
        all->count = w;
    }
    free(pair);
    free(deg);
    free(f);
    free(taken);
    return TESSEL_OK;
}

tessel_status tsl_gp_held(const tessel_cloud *cloud, const tessel_greedy_params *params,
                          bool check, const tsl_gp_tile_runner *runner,
                          const tessel_callbacks *callbacks, const uint32_t *perm,
                          const tessel_triangle_sink *sink, tessel_recon_summary *summary)
{
    gp_collect all = {NULL, 0, 0};
    tessel_triangle_sink hold = {tsl_gp_collect_emit, &all};
    size_t n = cloud->count;
    uint8_t *fate = tsl_alloc_array(n + 1, 1), *dirty = tsl_calloc_array(n + 1, 1);
    bool tiled = params->tile_points && n > params->tile_points && !params->existing_count;
    tessel_status s = !fate || !dirty ? TESSEL_ERR_NOMEM
                      : tiled ? tsl_gp_tiled_pass(cloud, params, runner, callbacks, &all, fate,
                                                  dirty, summary)
                              : tsl_gp_pass(cloud, params, "greedy", callbacks, &hold, fate, summary);
    /* One front flipped nothing yet; nor did a repair of the orientation. */
    bool all_dirty = !tiled;
    if (s == TESSEL_OK && check) {
        size_t before = summary->reoriented;
        s = check_and_repair(cloud, params, callbacks, &all, fate, summary);
        all_dirty = all_dirty || summary->reoriented != before;
    }
    /* The mesh's count, from the first to each hole round. */
    gp_count count = {0};
    if (s == TESSEL_OK)
        s = tsl_gp_drop_specks_and_count(n, &all, fate, params->threads, &count, summary);
    bool holes = true;
    for (int round = 0; round < 3 && s == TESSEL_OK && holes && summary->boundary_edges; round++)
        s = tsl_gp_reopen_holes(cloud, params, callbacks, &all, fate, dirty, &count, summary,
                                round, &holes);
    tsl_gp_count_free(&count);
    if (s == TESSEL_OK && params->flip) {
        /* Added to the tiles' flips, when there were tiles. The flips
         * change no count of the summary. */
        size_t flips = 0;
        s = tsl_progress(callbacks, "diagonal flips", 0.0);
        if (s == TESSEL_OK)
            s = all_dirty ? tsl_flip_diagonals(cloud->xyz, n, all.tris, all.count, NULL,
                                               params->threads, &flips)
                          : flip_dirty(cloud, &all, dirty, params->threads, &flips);
        if (s == TESSEL_OK)
            s = tsl_progress(callbacks, "diagonal flips", 1.0);
        summary->flips += flips;
    }
    if (s == TESSEL_OK) {
        size_t flaps;
        s = unfold_flaps(cloud->xyz, n, &all, params->threads, fate, &flaps);
        summary->triangles -= 2 * flaps;
        summary->points_used -= flaps;
        summary->left_closed_in += flaps;
    }
    if (s == TESSEL_OK && all.count > summary->peak_held_triangles)
        summary->peak_held_triangles = all.count;
    ptrdiff_t corners = s == TESSEL_OK && perm ? 3 * (ptrdiff_t)all.count : 0;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(params->threads))
    for (ptrdiff_t i = 0; i < corners; i++)
        all.tris[i] = perm[all.tris[i]];
    for (size_t t = 0; s == TESSEL_OK && t < all.count; t += OUT_BATCH) {
        size_t m = all.count - t < OUT_BATCH ? all.count - t : OUT_BATCH;
        s = sink->emit(sink->user_data, all.tris + 3 * t, m);
    }
    free(all.tris);
    free(fate);
    free(dirty);
    return s;
}
