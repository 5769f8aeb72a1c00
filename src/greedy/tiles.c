/* Greedy projection in tiles: more than tile_points points are cut into
 * tiles (core/tiles.c), each tile's points meshed by their own front in
 * parallel and its diagonals flipped, the tiles' triangles near a cut
 * dropped (a front that saw only one side of the cut made them), and a
 * front over the points near the cuts (local.c), started from the
 * triangles there (the `existing` triangles of tessel_greedy_params),
 * closes the seams as a front closes any place where two fronts meet. The
 * tiles depend on the points and tile_points only, so the result does not
 * depend on the thread count. */
#include "greedy/greedy.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* Triangles with a vertex within this many spheres of influence (mu times
 * the mean spacing) of a cut are dropped: a tile's front placed them
 * without the points beyond the cut. */
#define TILE_BAND 1.0

/* Tiles are oriented against each other by their triangles within this
 * many mean spacings beyond the band of a cut, each with its nearest
 * triangle of another component within this many beyond the two bands (as
 * the advancing front's tiles, front/tiles.c). One spacing gives every
 * pair of components across a cut votes all along it; each spacing more
 * added as many queries, each over more triangles (10^7 points: 2.5 s
 * with 4, 0.8 s with 1, the same mesh). */
#define TILE_VOTE_REACH 1.0
#define TILE_PAIR_REACH 4.0

/* The front that closes the seams sees the points within this many bands
 * of a dropped triangle beyond the band (its guard tests against their
 * triangles), as out of core (slabs.c). */
#define TILE_CONTEXT 3.0

/* Progress of parts meshed in parallel (tiles, seams): the calling thread
 * reports `stage` at base + scale * (parts finished) / parts; a
 * cancellation it hears stops every part at its next report. */
typedef struct part_ctx {
    const tessel_callbacks *user;
    const char *stage;
    double base, scale;
    size_t parts;
    atomic_int *finished, *cancel;
} part_ctx;

static int part_progress(void *data, const char *stage, double fraction)
{
    (void)stage;
    (void)fraction;
    part_ctx *c = data;
    if (omp_get_thread_num() == 0 &&
        tsl_progress(c->user, c->stage,
                     c->base + c->scale * (double)atomic_load(c->finished) / (double)c->parts) !=
            TESSEL_OK)
        atomic_store(c->cancel, 1);
    return atomic_load(c->cancel);
}

/* The tiles' components oriented against each other across the cuts (a
 * tile's front cannot know which side of a closed surface is out, and two
 * tiles that disagree leave a seam no front can close): tsl_orient_tiles
 * with the front's reaches, in mean spacings beyond the band. Components it
 * leaves out (contradicted by their neighbours, small pieces at a cut) are
 * dropped, their points flagged in seed: the front that closes the seams
 * meshes them again. */
static tessel_status orient_tiles(const tessel_cloud *cloud, gp_collect *all, const tsl_tiles *cut,
                                  double band, double spacing, size_t tile_points, int threads,
                                  uint8_t *seed)
{
    size_t count = all->count, ncomp = 0;
    uint32_t *comp = tsl_alloc_array(count + 1, sizeof *comp);
    uint8_t *drop = NULL;
    tessel_status st = comp ? tsl_triangle_components(all->tris, count, cloud->count, threads,
                                                      comp, &ncomp)
                            : TESSEL_ERR_NOMEM;
    if (st)
        goto done;
    if (!(drop = tsl_alloc_array(ncomp + 1, sizeof *drop))) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    st = tsl_orient_tiles(all->tris, comp, count, ncomp, cloud->xyz, cut->dcut, cut->cut_axis,
                          band + TILE_VOTE_REACH * spacing,
                          2.0 * band + TILE_PAIR_REACH * spacing, tile_points / 4, threads,
                          drop);
    if (st)
        goto done;
    size_t w = 0;
    for (size_t t = 0; t < count; t++) {
        const uint32_t *v = all->tris + 3 * t;
        if (drop[comp[t]]) {
            seed[v[0]] = seed[v[1]] = seed[v[2]] = 1;
            continue;
        }
        memmove(all->tris + 3 * w, v, 3 * sizeof *v);
        w++;
    }
    all->count = w;
done:
    free(comp);
    free(drop);
    return st;
}

/* ---- the seams, cut by cut ----
 * A selected point goes with the first cut on its way down the bisection
 * that lies within SEAM_GROUP bands of it, or with the last cut on that
 * way when none does. The groups are closed level by level, the deepest
 * cuts first: each group's front sees its points and, as context, the
 * points of the groups below it within SEAM_GROUP + TILE_CONTEXT bands of
 * its cut, closed already (where two cuts meet, the deeper one's seam ends
 * short of the other, whose front then closes the junction). Points within
 * a band of a group's edge (SEAM_GROUP bands from a cut above) are left to
 * that cut's front, which sees both sides; the other vertices of the
 * triangles at a group's points join it, frozen, so that its guard sees
 * every triangle there. The groups of one depth lie in different parts of
 * the bisection, at least SEAM_GROUP bands inside them, and are closed in
 * parallel, their triangles appended in the order of the groups. These
 * fronts only grow from the triangles there: a fresh seed in a piece a
 * tile dropped, seen from one side, came out facing the other way from its
 * neighbours beyond the cut. What no front reached is closed last by one
 * front over it and its surroundings, which may seed. One front over every
 * selected point took 6 s at 10^7 points (64 tiles) on one core. */
#define SEAM_GROUP 2.0

/* A growing list of triangle indices. */
typedef struct id_list {
    uint32_t *id;
    size_t count, cap;
} id_list;

static tessel_status id_push(id_list *l, uint32_t x)
{
    if (tsl_grow((void **)&l->id, &l->cap, l->count + 1, sizeof *l->id))
        return TESSEL_ERR_NOMEM;
    l->id[l->count++] = x;
    return TESSEL_OK;
}

void tsl_gp_seam_group_run(const tsl_gp_seams_job *job, size_t i, const tessel_callbacks *cb)
{
    gp_seam_group *g = &job->groups[i];
    size_t m = g->m;
    uint8_t *fr = tsl_alloc_array(m + 1, 1);
    if (!fr) {
        g->st = TESSEL_ERR_NOMEM;
        return;
    }
    for (size_t j = 0; j < m; j++)
        fr[j] = job->frozen[g->ids[j]];
    g->st = tsl_gp_front_over(job->cloud, g->ids, m, g->inside, g->ninside, fr, job->params, true,
                              "greedy: seams", cb, &g->more, job->fate, job->made, &g->sum);
    free(fr);
}

/* The default runner of a level's groups: this process's threads, progress
 * reported by the calling thread. */
static tessel_status seams_on_threads(const tsl_gp_seams_job *job, double done, double share)
{
    atomic_int cancel, finished;
    atomic_init(&cancel, 0);
    atomic_init(&finished, 0);
    part_ctx ctx = {job->callbacks, "greedy: seams", done, share, job->count, &finished, &cancel};
    tessel_callbacks cb = {part_progress, NULL, &ctx};
    long long count = (long long)job->count;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(job->params->threads))
    for (long long ii = 0; ii < count; ii++) {
        tsl_gp_seam_group_run(job, (size_t)ii, &cb);
        atomic_fetch_add(&finished, 1);
    }
    tessel_status st = TESSEL_OK;
    for (size_t i = 0; i < job->count && !st; i++)
        st = job->groups[i].st;
    return st;
}

/* The node of depth `depth` on the way down to tile k, or TESSEL_NONE. */
static uint32_t node_above(const tsl_tiles *cut, size_t k, int depth)
{
    uint32_t v = 0;
    while (v != TESSEL_NONE && cut->node[v].depth < depth)
        v = k < cut->node[v].mid ? cut->node[v].low : cut->node[v].high;
    return v;
}

/* The distance of point p (in tile k) to the nearest cut above depth
 * `depth` on the way down to its tile. */
static double cut_distance_above(const tsl_tiles *cut, const float *xyz, size_t p, size_t k,
                                 int depth)
{
    double d = INFINITY;
    for (uint32_t v = 0; v != TESSEL_NONE && cut->node[v].depth < depth;
         v = k < cut->node[v].mid ? cut->node[v].low : cut->node[v].high)
        d = fmin(d, fabs((double)xyz[3 * p + cut->node[v].axis] - cut->node[v].at));
    return d;
}

/* Puts point p in the group of the cut of depth `level` on its way, by
 * slot[p] (the group's number in the level), when it is that cut's or its
 * context, and out of the groups' edge zones. */
static void seam_slot(const tessel_cloud *cloud, const tsl_tiles *cut, const uint32_t *group,
                      const uint32_t *gid, size_t p, int level, double near, double edge,
                      uint32_t *slot)
{
    uint32_t own = group[p], k = cut->tile_of[p], v = node_above(cut, k, level);
    if (v == TESSEL_NONE)
        return;
    if (own != v) {
        const tsl_tile_node *nd = &cut->node[v];
        if (cut->node[own].depth <= level ||
            !(fabs((double)cloud->xyz[3 * p + nd->axis] - nd->at) < near))
            return;
    }
    if (cut_distance_above(cut, cloud->xyz, p, k, level) < edge)
        return;
    slot[p] = gid[v];
}

/* The groups of the cuts of depth `level` (see above) closed, their
 * triangles appended to all and to list (the triangles of all that may
 * meet a selected point). slot, local and frozen: per point, TESSEL_NONE,
 * any and 0 before and after. */
static tessel_status seam_level(const tessel_cloud *cloud, const tsl_tiles *cut,
                                const uint32_t *group, const uint32_t *selected, size_t nsel,
                                int level, double near, double edge,
                                const tessel_greedy_params *params,
                                const tsl_gp_tile_runner *runner,
                                const tessel_callbacks *callbacks, double done, double share,
                                gp_collect *all, id_list *list, uint32_t *slot, uint32_t *local,
                                uint8_t *frozen, uint8_t *fate, uint8_t *made,
                                tessel_recon_summary *summary)
{
    size_t nodes = cut->nodes, ng = 0;
    uint32_t *gid = tsl_alloc_array(nodes + 1, sizeof *gid);
    if (!gid)
        return TESSEL_ERR_NOMEM;
    for (size_t v = 0; v < nodes; v++)
        gid[v] = cut->node[v].depth == level ? (uint32_t)ng++ : TESSEL_NONE;
    size_t *count = tsl_calloc_array(ng + 1, sizeof *count);
    gp_seam_group *g = tsl_calloc_array(ng + 1, sizeof *g);
    id_list pts = {NULL, 0, 0};
    uint32_t *ids = NULL;
    tessel_status st = count && g ? TESSEL_OK : TESSEL_ERR_NOMEM;
    /* Each selected point's slot on the threads (it writes its own). */
    long long nselected = st ? 0 : (long long)nsel;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(params->threads))
    for (long long ii = 0; ii < nselected; ii++)
        seam_slot(cloud, cut, group, gid, selected[ii], level, near, edge, slot);
    for (size_t i = 0; !st && i < nsel; i++)
        if (slot[selected[i]] != TESSEL_NONE)
            st = id_push(&pts, selected[i]);
    /* The other vertices of the triangles at a group's points join it,
     * frozen: its guard then sees every triangle at its points (without
     * them, a front at a group's edge laid a second sheet over triangles it
     * could not see). */
    for (size_t i = 0; !st && i < list->count; i++) {
        const uint32_t *v = all->tris + 3 * (size_t)list->id[i];
        uint32_t s = TESSEL_NONE;
        for (int c = 0; c < 3; c++)
            s = slot[v[c]] != TESSEL_NONE ? slot[v[c]] : s;
        for (int c = 0; s != TESSEL_NONE && !st && c < 3; c++)
            if (slot[v[c]] == TESSEL_NONE) {
                slot[v[c]] = s;
                frozen[v[c]] = 1;
                st = id_push(&pts, v[c]);
            }
    }
    /* Each group's points: its selected ones in increasing order, then
     * those joined. */
    for (size_t i = 0; !st && i < pts.count; i++)
        local[pts.id[i]] = (uint32_t)count[slot[pts.id[i]]]++;
    if (!st && !(ids = tsl_alloc_array(pts.count + 1, sizeof *ids)))
        st = TESSEL_ERR_NOMEM;
    for (size_t i = 0, at = 0; !st && i < ng; at += count[i], i++)
        g[i].ids = ids + at;
    for (size_t i = 0; !st && i < pts.count; i++) {
        gp_seam_group *x = &g[slot[pts.id[i]]];
        ids[(size_t)(x->ids - ids) + x->m++] = pts.id[i];
    }
    /* The triangles among a group's points resume its front; a point with
     * one beyond them (where long triangles join two groups' points) is
     * frozen: its fan is not all there. */
    for (size_t i = 0; !st && i < list->count; i++) {
        const uint32_t *v = all->tris + 3 * (size_t)list->id[i];
        uint32_t s0 = slot[v[0]];
        if (s0 == TESSEL_NONE || slot[v[1]] != s0 || slot[v[2]] != s0) {
            for (int c = 0; c < 3; c++)
                if (slot[v[c]] != TESSEL_NONE)
                    frozen[v[c]] = 1;
            continue;
        }
        gp_seam_group *x = &g[s0];
        if (tsl_grow((void **)&x->inside, &x->cap_inside, x->ninside + 1,
                     3 * sizeof *x->inside)) {
            st = TESSEL_ERR_NOMEM;
            break;
        }
        for (int c = 0; c < 3; c++)
            x->inside[3 * x->ninside + (size_t)c] = local[v[c]];
        x->ninside++;
    }
    if (!st) {
        tsl_gp_seams_job job = {cloud, params, g, ng, frozen, fate, made, callbacks};
        st = runner && runner->seams ? runner->seams(runner->ctx, &job)
                                     : seams_on_threads(&job, done, share);
    }
    /* The new triangles in the order of the groups. */
    for (size_t i = 0; !st && i < ng; i++) {
        size_t before = all->count;
        st = tsl_gp_collect_emit(all, g[i].more.tris, g[i].more.count);
        for (size_t t = before; !st && t < all->count; t++)
            st = id_push(list, (uint32_t)t);
        summary->seeds += g[i].sum.seeds;
        summary->holes_closed += g[i].sum.holes_closed;
        summary->rejected_intersecting += g[i].sum.rejected_intersecting;
    }
    for (size_t i = 0; i < pts.count; i++) {
        slot[pts.id[i]] = TESSEL_NONE;
        frozen[pts.id[i]] = 0;
    }
    for (size_t i = 0; g && i < ng; i++) {
        free(g[i].inside);
        free(g[i].more.tris);
    }
    free(g);
    free(ids);
    free(pts.id);
    free(count);
    free(gid);
    return st;
}

/* The seams of the tiles over the selected points (sel), closed as the
 * comment above says. */
static tessel_status close_seams(const tessel_cloud *cloud, const tsl_tiles *cut,
                                 const uint8_t *sel, double reach,
                                 const tessel_greedy_params *params,
                                 const tsl_gp_tile_runner *runner,
                                 const tessel_callbacks *callbacks, gp_collect *all, uint8_t *fate,
                                 uint8_t *made, tessel_recon_summary *summary)
{
    size_t n = cloud->count, nodes = cut->nodes, nsel = 0;
    uint32_t *group = tsl_alloc_array(n + 1, sizeof *group);
    uint32_t *slot = tsl_alloc_array(n + 1, sizeof *slot);
    uint32_t *local = tsl_alloc_array(n + 1, sizeof *local);
    uint32_t *selected = NULL;
    uint8_t *frozen = tsl_calloc_array(n + 1, 1), *again = NULL;
    id_list list = {NULL, 0, 0}; /* the triangles of all with a selected vertex */
    tessel_status st = group && slot && local && frozen ? TESSEL_OK : TESSEL_ERR_NOMEM;
    for (size_t p = 0; !st && p < n; p++) {
        slot[p] = TESSEL_NONE;
        nsel += sel[p] != 0;
    }
    if (!st && !(selected = tsl_alloc_array(nsel + 1, sizeof *selected)))
        st = TESSEL_ERR_NOMEM;
    nsel = 0;
    for (size_t p = 0; !st && p < n; p++) {
        if (!sel[p])
            continue;
        selected[nsel++] = (uint32_t)p;
        uint32_t k = cut->tile_of[p];
        for (uint32_t v = 0; v != TESSEL_NONE;) {
            const tsl_tile_node *nd = &cut->node[v];
            group[p] = v;
            if (fabs((double)cloud->xyz[3 * p + nd->axis] - nd->at) < SEAM_GROUP * reach)
                break;
            v = k < nd->mid ? nd->low : nd->high;
        }
    }
    for (size_t t = 0; !st && t < all->count; t++) {
        const uint32_t *v = all->tris + 3 * t;
        if (sel[v[0]] || sel[v[1]] || sel[v[2]])
            st = id_push(&list, (uint32_t)t);
    }
    int deepest = 0;
    for (size_t v = 0; v < nodes; v++)
        deepest = cut->node[v].depth > deepest ? cut->node[v].depth : deepest;
    double share = 1.0 / (double)(deepest + 1);
    for (int level = deepest; !st && level >= 0; level--)
        st = seam_level(cloud, cut, group, selected, nsel, level,
                        (SEAM_GROUP + TILE_CONTEXT) * reach, (SEAM_GROUP + 1.0) * reach, params,
                        runner, callbacks, share * (double)(deepest - level), share, all, &list, slot,
                        local, frozen, fate, made, summary);
    /* What the fronts could not reach from the triangles around it: one
     * front over it and its surroundings, which may seed. */
    size_t left = 0;
    for (size_t i = 0; !st && i < nsel; i++) {
        uint32_t p = selected[i];
        frozen[p] = fate[p] == FATE_UNREACHED;
        left += frozen[p];
    }
    if (!st && left && !(again = tsl_calloc_array(n + 1, 1)))
        st = TESSEL_ERR_NOMEM;
    if (!st && left)
        st = tsl_gp_select_near(cloud->xyz, n, frozen, TILE_CONTEXT * reach, params->threads,
                                again);
    if (!st && left) {
        for (size_t p = 0; p < n; p++)
            again[p] = again[p] && sel[p] && (fate[p] == FATE_USED || frozen[p]);
        st = tsl_gp_local_pass(cloud, again, params, "greedy: seams", callbacks, all, fate, made,
                               summary);
    }
    free(group);
    free(slot);
    free(local);
    free(selected);
    free(frozen);
    free(again);
    free(list.id);
    return st;
}

tessel_status tsl_gp_tile_mesh_cloud(const tessel_cloud *sub, const tessel_greedy_params *params,
                                     const tessel_callbacks *cb, gp_collect *out, uint8_t *fate,
                                     tessel_recon_summary *sum)
{
    tessel_triangle_sink sink = {tsl_gp_collect_emit, out};
    tessel_status st = tsl_gp_pass(sub, params, "greedy", cb, &sink, fate, sum);
    /* The tile's flips here, on one thread, leave the pass over the whole
     * mesh only the seams and repairs to flip. */
    if (st == TESSEL_OK && params->flip)
        st = tsl_flip_diagonals(sub->xyz, sub->count, out->tris, out->count, NULL, 1,
                                &sum->flips);
    return st;
}

tessel_status tsl_gp_tile_mesh(const tsl_gp_tiles_job *job, size_t k,
                               const tessel_callbacks *cb)
{
    const uint32_t *ids = job->cut->ids + job->cut->start[k];
    size_t m = job->cut->start[k + 1] - job->cut->start[k];
    gp_collect *out = &job->parts[k];
    tessel_cloud sub;
    tessel_status st = tsl_gp_subcloud(job->cloud, ids, m, &sub);
    if (st)
        return st;
    uint8_t *fate = tsl_alloc_array(m + 1, 1);
    st = fate ? tsl_gp_tile_mesh_cloud(&sub, job->params, cb, out, fate, &job->sums[k])
              : TESSEL_ERR_NOMEM;
    tessel_cloud_free(&sub);
    for (size_t i = 0; st == TESSEL_OK && i < m; i++)
        job->fate[ids[i]] = fate[i];
    free(fate);
    for (size_t i = 0; st == TESSEL_OK && i < 3 * out->count; i++)
        out->tris[i] = ids[out->tris[i]];
    return st;
}

/* The default runner: the tiles on this process's threads, progress
 * reported by the calling thread. */
static tessel_status run_threads(void *unused, const tsl_gp_tiles_job *job)
{
    (void)unused;
    size_t nt = job->count;
    tessel_status *status = tsl_alloc_array(nt, sizeof *status);
    part_ctx *ctx = tsl_alloc_array(nt, sizeof *ctx);
    tessel_callbacks *tcb = tsl_alloc_array(nt, sizeof *tcb);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!status || !ctx || !tcb)
        goto done;
    atomic_int cancel, finished;
    atomic_init(&cancel, 0);
    atomic_init(&finished, 0);
    for (size_t k = 0; k < nt; k++) {
        ctx[k] = (part_ctx){job->callbacks, "greedy", 0.0, 0.5, nt, &finished, &cancel};
        tcb[k] = (tessel_callbacks){part_progress, NULL, &ctx[k]};
    }
    long long count = (long long)nt;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(job->params->threads))
    for (long long kk = 0; kk < count; kk++) {
        size_t k = (size_t)kk;
        status[k] = tsl_gp_tile_mesh(job, k, &tcb[k]);
        atomic_fetch_add(&finished, 1);
    }
    st = TESSEL_OK;
    for (size_t k = 0; k < nt && !st; k++)
        st = status[k];
done:
    free(status);
    free(ctx);
    free(tcb);
    return st;
}

/* The tiles of a tiled pass, meshed by runner (NULL: this process's
 * threads) into parts[k] and sums[k] (the caller frees them with
 * free_tiles, also on failure). */
static tessel_status mesh_tiles(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                const tsl_gp_tile_runner *runner,
                                const tessel_callbacks *callbacks, tsl_tiles *cut,
                                gp_collect **parts, tessel_recon_summary **sums, uint8_t *fate)
{
    *parts = NULL;
    *sums = NULL;
    tessel_status st = tsl_tiles_cut(cloud->xyz, cloud->count, params->tile_points,
                                     params->threads, cut);
    if (st)
        return st;
    *parts = tsl_calloc_array(cut->count, sizeof **parts);
    *sums = tsl_calloc_array(cut->count, sizeof **sums);
    if (!*parts || !*sums)
        return TESSEL_ERR_NOMEM;
    tessel_greedy_params tp = *params;
    tp.tile_points = 0;
    tsl_gp_tiles_job job = {cloud, &tp, cut, cut->count, callbacks, *parts, *sums, fate};
    return runner ? runner->run(runner->ctx, &job) : run_threads(NULL, &job);
}

static void free_tiles(tsl_tiles *cut, gp_collect *parts, tessel_recon_summary *sums)
{
    for (size_t k = 0; parts && k < cut->count; k++)
        free(parts[k].tris);
    free(parts);
    free(sums);
    tsl_tiles_free(cut);
}

tessel_status tsl_gp_tiled_pass(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                const tsl_gp_tile_runner *runner,
                                const tessel_callbacks *callbacks, gp_collect *all,
                                uint8_t *fate, uint8_t *dirty, tessel_recon_summary *summary)
{
    tsl_tiles cut = {0};
    gp_collect *parts = NULL;
    tessel_recon_summary *sums = NULL;
    size_t n = cloud->count;
    uint8_t *touched = NULL, *seed = NULL, *sel = NULL;
    tessel_status st = mesh_tiles(cloud, params, runner, callbacks, &cut, &parts, &sums, fate);
    if (st)
        goto done;
    if (!(touched = tsl_calloc_array(n, 1)) || !(seed = tsl_calloc_array(n, 1)) ||
        !(sel = tsl_calloc_array(n, 1))) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    size_t nt = cut.count;
    /* The tiles' triangles, less those near a cut, in tile order. */
    double reach = 0.0, spacing = 0.0, mu = 0.0;
    for (size_t k = 0; k < nt; k++) {
        double r = TILE_BAND * sums[k].mu * sums[k].spacing;
        reach = r > reach ? r : reach;
        spacing = sums[k].spacing > spacing ? sums[k].spacing : spacing;
        mu = sums[k].mu > mu ? sums[k].mu : mu;
    }
    /* Each tile's kept triangles moved to the front of its array, in
     * parallel (a point belongs to one tile: no two write one flag), then
     * copied in tile order into room made once (appending them one by one
     * moved the whole growing array again and again: 10^7 points, 1 s),
     * each array freed once copied. */
    long long ntiles = (long long)nt;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(params->threads))
    for (long long kk = 0; kk < ntiles; kk++) {
        gp_collect *c = &parts[kk];
        size_t w = 0;
        for (size_t t = 0; t < c->count; t++) {
            const uint32_t *v = c->tris + 3 * t;
            if (cut.dcut[v[0]] < reach || cut.dcut[v[1]] < reach || cut.dcut[v[2]] < reach) {
                touched[v[0]] = touched[v[1]] = touched[v[2]] = 1;
                continue;
            }
            memmove(c->tris + 3 * w++, v, 3 * sizeof *v);
        }
        c->count = w;
    }
    size_t *at = tsl_alloc_array(nt + 1, sizeof *at);
    if (!at) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    at[0] = all->count;
    for (size_t k = 0; k < nt; k++)
        at[k + 1] = at[k] + parts[k].count;
    if (tsl_grow((void **)&all->tris, &all->cap, at[nt], 3 * sizeof *all->tris)) {
        free(at);
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(params->threads))
    for (long long kk = 0; kk < ntiles; kk++) {
        gp_collect *c = &parts[kk];
        if (c->count)
            memcpy(all->tris + 3 * at[kk], c->tris, 3 * c->count * sizeof *c->tris);
        free(c->tris);
        c->tris = NULL;
    }
    all->count = at[nt];
    free(at);
#if defined(__GLIBC__)
    /* The tiles' fronts freed their many arrays of a few MB in an order
     * that leaves the heap in holes glibc keeps: give them back (10^7
     * points: peak 1,530 -> 1,378 MB). */
    malloc_trim(0);
#endif
    memcpy(seed, touched, n);
    if ((st = tsl_single_fans(n, all->tris, &all->count, touched, NULL, NULL)) ||
        (st = orient_tiles(cloud, all, &cut, reach, spacing, params->tile_points,
                                  params->threads, seed)))
        goto done;
    /* The seams: a front over the points of the bands, and those near a
     * dropped triangle or a border of the tiles' mesh (a second look there,
     * with the neighbours beyond a cut: a tile's front closes fewer of the
     * notches at an open surface's border than one over all points), from
     * the triangles among them. */
    uint64_t *open = tsl_alloc_array(n + 1, sizeof *open);
    if (!open) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    tsl_open_fans(all->tris, all->count, n, params->threads, open);
    for (size_t i = 0; i < n; i++) {
        sel[i] = cut.dcut[i] < reach;
        seed[i] |= open[i] != 0;
    }
    free(open);
    if ((st = tsl_gp_select_near(cloud->xyz, n, seed, TILE_CONTEXT * reach, params->threads,
                                 sel)))
        goto done;
    tsl_gp_select_meshed(n, fate, cut.dcut, reach, sel);
    tessel_greedy_params sp = *params;
    sp.mu = mu;
    sp.mu_from_sampling = 0;
    for (size_t k = 0; k < nt; k++) {
        summary->seeds += sums[k].seeds;
        summary->holes_closed += sums[k].holes_closed;
        summary->rejected_intersecting += sums[k].rejected_intersecting;
        summary->flips += sums[k].flips;
        summary->spacing += sums[k].spacing * (double)sums[k].points_in / (double)n;
    }
    summary->mu = mu;
    summary->tiles = nt;
    st = close_seams(cloud, &cut, sel, reach, &sp, runner, callbacks, all, fate, dirty, summary);
done:
    free_tiles(&cut, parts, sums);
    free(touched);
    free(seed);
    free(sel);
    return st;
}
