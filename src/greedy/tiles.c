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

/* Progress of the tiles: the calling thread reports the tiles finished;
 * a cancellation it hears stops every tile at its next report. */
typedef struct tile_ctx {
    const tessel_callbacks *user;
    size_t tiles;
    atomic_int *finished, *cancel;
} tile_ctx;

static int tile_progress(void *data, const char *stage, double fraction)
{
    (void)stage;
    (void)fraction;
    tile_ctx *c = data;
    if (omp_get_thread_num() == 0 &&
        tsl_progress(c->user, "greedy",
                     0.5 * (double)atomic_load(c->finished) / (double)c->tiles) != TESSEL_OK)
        atomic_store(c->cancel, 1);
    return atomic_load(c->cancel);
}

/* The points ids[0 .. m) of cloud as a cloud of their own (positions,
 * normals, viewpoint and offset). */
static tessel_status tile_cloud(const tessel_cloud *cloud, const uint32_t *ids, size_t m,
                                tessel_cloud *out)
{
    tessel_status st = tessel_cloud_alloc(out, m, cloud->normals != NULL, 0);
    if (st)
        return st;
    for (size_t i = 0; i < m; i++) {
        memcpy(out->xyz + 3 * i, cloud->xyz + 3 * (size_t)ids[i], 3 * sizeof *out->xyz);
        if (cloud->normals)
            memcpy(out->normals + 3 * i, cloud->normals + 3 * (size_t)ids[i],
                   3 * sizeof *out->normals);
    }
    memcpy(out->offset, cloud->offset, sizeof out->offset);
    memcpy(out->viewpoint, cloud->viewpoint, sizeof out->viewpoint);
    out->has_viewpoint = cloud->has_viewpoint;
    return TESSEL_OK;
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
    tessel_status st = comp ? tsl_triangle_components(all->tris, count, cloud->count, comp, &ncomp)
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

tessel_status tsl_gp_tile_mesh(const tsl_gp_tiles_job *job, size_t k,
                               const tessel_callbacks *cb)
{
    const uint32_t *ids = job->cut->ids + job->cut->start[k];
    size_t m = job->cut->start[k + 1] - job->cut->start[k];
    gp_collect *out = &job->parts[k];
    tessel_cloud sub;
    tessel_status st = tile_cloud(job->cloud, ids, m, &sub);
    if (st)
        return st;
    uint8_t *fate = tsl_alloc_array(m + 1, 1);
    if (!fate) {
        tessel_cloud_free(&sub);
        return TESSEL_ERR_NOMEM;
    }
    tessel_triangle_sink sink = {tsl_gp_collect_emit, out};
    st = tsl_gp_pass(&sub, job->params, "greedy", cb, &sink, fate, &job->sums[k]);
    for (size_t i = 0; st == TESSEL_OK && i < m; i++)
        job->fate[ids[i]] = fate[i];
    free(fate);
    /* The tile's flips here, on one thread, leave the pass over the whole
     * mesh only the seams and repairs to flip. */
    if (st == TESSEL_OK && job->params->flip)
        st = tsl_flip_diagonals(sub.xyz, sub.count, out->tris, out->count, NULL, 1,
                                &job->sums[k].flips);
    tessel_cloud_free(&sub);
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
    tile_ctx *ctx = tsl_alloc_array(nt, sizeof *ctx);
    tessel_callbacks *tcb = tsl_alloc_array(nt, sizeof *tcb);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!status || !ctx || !tcb)
        goto done;
    atomic_int cancel, finished;
    atomic_init(&cancel, 0);
    atomic_init(&finished, 0);
    for (size_t k = 0; k < nt; k++) {
        ctx[k] = (tile_ctx){job->callbacks, nt, &finished, &cancel};
        tcb[k] = (tessel_callbacks){tile_progress, NULL, &ctx[k]};
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
    tessel_status st = tsl_tiles_cut(cloud->xyz, cloud->count, params->tile_points, cut);
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

tessel_status tsl_gp_tiles_help(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                const tsl_gp_tile_runner *runner,
                                const tessel_callbacks *callbacks)
{
    tsl_tiles cut = {0};
    gp_collect *parts = NULL;
    tessel_recon_summary *sums = NULL;
    tessel_cloud sorted;
    uint32_t *perm;
    tessel_status st = tsl_gp_space_order(cloud, params->threads, &sorted, &perm);
    if (st)
        return st;
    uint8_t *fate = tsl_alloc_array(cloud->count + 1, 1);
    st = fate ? mesh_tiles(&sorted, params, runner, callbacks, &cut, &parts, &sums, fate)
              : TESSEL_ERR_NOMEM;
    free_tiles(&cut, parts, sums);
    free(fate);
    tessel_cloud_free(&sorted);
    free(perm);
    return st;
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
    if ((st = tsl_single_fans(n, all->tris, &all->count, touched)) ||
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
    tsl_open_fans(all->tris, all->count, n, open);
    for (size_t i = 0; i < n; i++) {
        sel[i] = cut.dcut[i] < reach;
        seed[i] |= open[i] != 0;
    }
    free(open);
    if ((st = tsl_gp_select_near(cloud->xyz, n, seed, TILE_CONTEXT * reach, sel)))
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
    st = tsl_gp_local_pass(cloud, sel, &sp, "greedy: seams", callbacks, all, fate, dirty,
                           summary);
done:
    free_tiles(&cut, parts, sums);
    free(touched);
    free(seed);
    free(sel);
    return st;
}
