/* Tiles of the advancing front: more than tile_points points are cut
 * into tiles by recursive median bisection, the tiles' fronts run in
 * parallel, their components are oriented against each other, and the
 * front over all points starts from their triangles to close the seams.
 * Also the start of a front from a caller's mesh
 * (tsl_advancing_front_from). */
#include "front/front.h"

#include <float.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Tiles                                                                     */
/* ------------------------------------------------------------------------ */

/* More than tile_points points are cut into tiles by recursive median
 * bisection, each part along the longest side of its box. Each tile's front
 * runs on the tile's points alone, the tiles in parallel. The triangles of
 * all tiles, less those with a vertex within TILE_BAND mean spacings of a
 * cut, then become the mesh the front over all points starts from: its
 * border edges are the front, and it closes the seams as it closes any
 * place where two fronts meet. Tiles depend on the points and tile_points
 * only, so the result does not depend on the thread count. */
#define TILE_BAND 0.5

/* The tiles' components are oriented against each other by their
 * triangles within this many mean spacings beyond the band of a cut ... */
#define TILE_VOTE_REACH 4.0
/* ... each with its nearest triangle of another component within this
 * many mean spacings beyond the two bands (see tsl_orient_tiles). */
#define TILE_PAIR_REACH 4.0
/* Share of the progress bar given to the tiles (the front over all points,
 * which starts with their triangles, reports the rest). */
#define TILE_PROGRESS 0.9

/* Progress of the tiles: the calling thread reports the tiles finished
 * plus its current tile's part (the callback is never called from two
 * threads); a cancellation stops every tile. */
typedef struct tile_ctx {
    const tessel_callbacks *user;
    size_t tiles;
    atomic_int *finished, *cancel;
} tile_ctx;

static int tile_progress(void *data, const char *stage, double fraction)
{
    tile_ctx *c = data;
    if (atomic_load(c->cancel))
        return 1;
    if (omp_get_thread_num() != 0)
        return 0;
    double done = ((double)atomic_load(c->finished) + fraction) / (double)c->tiles;
    if (tsl_progress(c->user, stage, TILE_PROGRESS * (done < 1.0 ? done : 1.0)) != TESSEL_OK) {
        atomic_store(c->cancel, 1);
        return 1;
    }
    return 0;
}

tessel_status tsl_af_tile_alloc(af *t, size_t m, uint32_t k, const tessel_front_params *p,
                                bool normals, bool lines)
{
    memset(t, 0, sizeof *t);
    t->n = m;
    t->k = k;
    tsl_af_params(t, p);
    size_t blocks = 1 + normals + lines;
    t->own = tsl_alloc_array(3 * m * blocks + 1, sizeof *t->own);
    t->knn = tsl_alloc_array(m * (size_t)k + 1, sizeof *t->knn);
    t->nnd = tsl_alloc_array(m + 1, sizeof *t->nnd);
    t->dup = tsl_alloc_array(m + 1, sizeof *t->dup);
    t->ln = tsl_alloc_array(3 * m + 1, sizeof *t->ln);
    t->vsign = tsl_calloc_array(m + 1, sizeof *t->vsign);
    if (!t->own || !t->knn || !t->nnd || !t->dup || !t->ln || !t->vsign)
        return TESSEL_ERR_NOMEM;
    t->xyz = t->own;
    t->pnormals = normals ? t->own + 3 * m : NULL;
    t->lines = lines ? t->own + 3 * m * (blocks - 1) : NULL;
    return TESSEL_OK;
}

tessel_status tsl_af_tile_inputs(const tsl_af_tiles_job *job, size_t k, af *t)
{
    const af *g = job->s;
    const uint32_t *ids = job->ids + job->range[k];
    size_t m = job->range[k + 1] - job->range[k];
    tessel_status st = tsl_af_tile_alloc(t, m, g->k, job->p, g->pnormals != NULL,
                                         g->lines != NULL);
    if (st)
        return st;
    float *xyz = t->own, *nrm = (float *)t->pnormals, *lines = (float *)t->lines;
    for (size_t u = 0; u < m; u++) {
        size_t i = ids[u];
        memcpy(xyz + 3 * u, g->xyz + 3 * i, 3 * sizeof *xyz);
        if (nrm)
            memcpy(nrm + 3 * u, g->pnormals + 3 * i, 3 * sizeof *nrm);
        if (lines)
            memcpy(lines + 3 * u, g->lines + 3 * i, 3 * sizeof *lines);
        memcpy(t->ln + 3 * u, g->ln + 3 * i, 3 * sizeof *t->ln);
        t->nnd[u] = g->nnd[i];
        t->dup[u] = g->dup[i];
        const uint32_t *row = g->knn + i * g->k;
        uint32_t *out = t->knn + u * g->k, got = 0;
        for (uint32_t j = 0; j < g->k; j++)
            if (row[j] != NONE && job->tile_of[row[j]] == k)
                out[got++] = job->local[row[j]];
        for (; got < g->k; got++)
            out[got] = NONE;
    }
    return TESSEL_OK;
}

tessel_status tsl_af_tile_run(af *t, double cell, const uint32_t *start, size_t nstart,
                              const tessel_callbacks *cb)
{
    tessel_status st = tsl_af_alloc_mesh(t, cell);
    if (!st && nstart)
        st = tsl_af_place_start(t, start, nstart);
    return st ? st : tsl_af_run_fronts(t, cb);
}

tessel_status tsl_af_tile(const tsl_af_tiles_job *job, size_t k, const tessel_callbacks *cb)
{
    af *t = &job->tiles[k];
    tessel_status st = tsl_af_tile_inputs(job, k, t);
    return st ? st
              : tsl_af_tile_run(t, job->s->cell, job->start + 3 * job->sfrom[k],
                                job->sfrom[k + 1] - job->sfrom[k], cb);
}

/* The default runner: the tiles on this process's threads, the calling
 * thread reporting the tiles finished plus its current tile's part (the
 * callback is never called from two threads); a cancellation stops every
 * tile. */
static tessel_status run_threads(void *unused, const tsl_af_tiles_job *job)
{
    (void)unused;
    size_t nt = job->count;
    tile_ctx *ctx = tsl_alloc_array(nt + 1, sizeof *ctx);
    tessel_callbacks *tcb = tsl_alloc_array(nt + 1, sizeof *tcb);
    tessel_status *status = tsl_alloc_array(nt + 1, sizeof *status);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!ctx || !tcb || !status)
        goto done;
    atomic_int cancel, finished;
    atomic_init(&cancel, 0);
    atomic_init(&finished, 0);
    for (size_t k = 0; k < nt; k++) {
        ctx[k].user = job->cb;
        ctx[k].tiles = nt;
        ctx[k].finished = &finished;
        ctx[k].cancel = &cancel;
        tcb[k].progress = tile_progress;
        tcb[k].log = NULL;
        tcb[k].user_data = &ctx[k];
    }
    long long count = (long long)nt;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(job->p->threads))
    for (long long kk = 0; kk < count; kk++) {
        size_t k = (size_t)kk;
        status[k] = tsl_af_tile(job, k, &tcb[k]);
        atomic_fetch_add(&finished, 1);
    }
    st = TESSEL_OK;
    for (size_t k = 0; k < nt && !st; k++)
        st = status[k];
done:
    free(ctx);
    free(tcb);
    free(status);
    return st;
}

/* Makes the triangles of s (a starting mesh: the tiles' or a caller's) a
 * front: every edge on one triangle becomes a border edge, queued, linked
 * along its loop. */
static tessel_status border_of_mesh(af *s)
{
    size_t first = s->ne;
    for (size_t t = 0; t < s->nt; t++)
        for (int i = 0; i < 3; i++) {
            uint32_t x = s->tri[3 * t + i], y = s->tri[3 * t + (i + 1) % 3];
            bool twin = false;
            for (uint32_t c = s->vhead[x]; c != NONE && !twin; c = s->cnext[c])
                twin = s->tri[3 * (size_t)(c / 3) + (c + 2) % 3] == y;
            if (twin)
                continue;
            uint32_t id;
            tessel_status st = tsl_af_new_edge(s, x, y, (uint32_t)t, &id);
            if (st)
                return st;
            s->vout[x] = id;
            s->vin[y] = id;
        }
    for (size_t e = first; e < s->ne; e++)
        link_edges(s, (uint32_t)e, s->vout[s->e[e].to]);
    for (size_t i = 0; i < s->n; i++)
        s->used += s->vhead[i] != NONE;
    return TESSEL_OK;
}

/* Adds tri[0 .. count) to s, less those whose component comp[t] is dropped
 * (drop NULL: none), and makes their border edges the front. */
static tessel_status import_mesh(af *s, const uint32_t *tri, size_t count, const uint32_t *comp,
                                 const uint8_t *drop)
{
    for (size_t t = 0; t < count; t++) {
        uint32_t id;
        if (drop && drop[comp[t]])
            continue;
        tessel_status st = tsl_af_add_triangle(s, tri[3 * t], tri[3 * t + 1], tri[3 * t + 2], &id);
        if (st)
            return st;
    }
    return border_of_mesh(s);
}

/* Places the tiles' triangles (tiles[0 .. nt), points ids[range]) in s,
 * less the band along the cuts and the components tsl_orient_tiles drops,
 * the rest oriented against each other. */
static tessel_status place_tiles(af *s, const af *tiles, const size_t *range, size_t nt,
                                 const uint32_t *ids, const float *dcut,
                                 const uint8_t *cut_axis, double mean_nn, size_t small,
                                 int threads)
{
    size_t total = 0;
    for (size_t k = 0; k < nt; k++)
        total += tiles[k].nt - tiles[k].deleted;
    double band = TILE_BAND * mean_nn;
    uint32_t *tri = tsl_alloc_array(3 * total + 1, sizeof *tri);
    uint8_t *touched = tsl_calloc_array(s->n, sizeof *touched);
    uint32_t *comp = tsl_alloc_array(total + 1, sizeof *comp);
    uint8_t *drop = NULL;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!tri || !touched || !comp)
        goto done;
    size_t count = 0;
    for (size_t k = 0; k < nt; k++) {
        const af *a = &tiles[k];
        for (size_t t = 0; t < a->nt; t++) {
            if (a->tri[3 * t] == NONE)
                continue;
            uint32_t v[3];
            bool keep = true;
            for (int i = 0; i < 3; i++) {
                v[i] = ids[range[k] + a->tri[3 * t + i]];
                keep = keep && !(dcut[v[i]] < band);
            }
            if (!keep) {
                for (int i = 0; i < 3; i++)
                    touched[v[i]] = 1;
                continue;
            }
            memcpy(tri + 3 * count, v, sizeof v);
            count++;
        }
    }
    if ((st = tsl_single_fans(s->n, tri, &count, touched, NULL, NULL)))
        goto done;
    /* Components (edge-connected: every vertex has a single fan). */
    size_t ncomp;
    if ((st = tsl_triangle_components(tri, count, s->n, threads, comp, &ncomp)))
        goto done;
    if (!(drop = tsl_alloc_array(ncomp + 1, sizeof *drop))) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    if ((st = tsl_orient_tiles(tri, comp, count, ncomp, s->xyz, dcut, cut_axis,
                               band + TILE_VOTE_REACH * mean_nn,
                               2.0 * band + TILE_PAIR_REACH * mean_nn, small, threads, drop)))
        goto done;
    st = import_mesh(s, tri, count, comp, drop);
done:
    free(tri);
    free(touched);
    free(comp);
    free(drop);
    return st;
}

/* The tile holding all three corners of triangle v, or NONE. */
static inline uint32_t tile_holding(const uint32_t *tile_of, const uint32_t v[3])
{
    uint32_t k = tile_of[v[0]];
    return tile_of[v[1]] == k && tile_of[v[2]] == k ? k : NONE;
}

/* Fronts in tiles of at most p->tile_points points, in parallel, each from
 * the triangles of start[0 .. nstart) with all three corners in it; their
 * triangles, less the seams, become s's starting mesh. */
tessel_status tsl_af_run_tiles(af *s, const tessel_front_params *p, double mean_nn,
                               const uint32_t *start, size_t nstart,
                               const tsl_af_tile_runner *runner, const tessel_callbacks *cb)
{
    tsl_tiles cut;
    tessel_status st = tsl_tiles_cut(s->xyz, s->n, p->tile_points, p->threads, &cut);
    if (st)
        return st;
    size_t cap = cut.count, nt = cut.count;
    const uint32_t *ids = cut.ids, *tile_of = cut.tile_of;
    const size_t *range = cut.start;
    const float *dcut = cut.dcut;
    uint32_t *local = tsl_alloc_array(s->n, sizeof *local);
    af *tiles = tsl_calloc_array(cap, sizeof *tiles);
    uint32_t *tstart = tsl_alloc_array(3 * nstart + 1, sizeof *tstart);
    size_t *sfrom = tsl_calloc_array(cap + 1, sizeof *sfrom);
    st = TESSEL_ERR_NOMEM;
    if (!local || !tiles || !tstart || !sfrom)
        goto done;
    for (size_t i = 0; i < s->n; i++)
        local[ids[i]] = (uint32_t)(i - range[tile_of[ids[i]]]);
    /* The starting triangles by tile, in their order, in local ids (those
     * across a cut are left to the front that joins the tiles). */
    for (size_t t = 0; t < nstart; t++) {
        uint32_t k = tile_holding(tile_of, start + 3 * t);
        if (k != NONE)
            sfrom[k + 1]++;
    }
    for (size_t k = 0; k < nt; k++)
        sfrom[k + 1] += sfrom[k];
    for (size_t t = 0; t < nstart; t++) {
        const uint32_t *v = start + 3 * t;
        uint32_t k = tile_holding(tile_of, v);
        if (k == NONE)
            continue;
        size_t at = 3 * sfrom[k]++;
        for (int i = 0; i < 3; i++)
            tstart[at + (size_t)i] = local[v[i]];
    }
    for (size_t k = nt; k-- > 0;) /* sfrom[k] was advanced to tile k's end */
        sfrom[k + 1] = sfrom[k];
    sfrom[0] = 0;
    tsl_af_tiles_job job = {s, p, nt, range, ids, tile_of, local, tstart, sfrom, cb, tiles};
    st = runner ? runner->run(runner->ctx, &job) : run_threads(NULL, &job);
    if (st)
        goto done;
    for (size_t k = 0; k < nt; k++) {
        s->stats.seeds += tiles[k].stats.seeds;
        s->stats.bridges += tiles[k].stats.bridges;
        s->stats.hole_triangles += tiles[k].stats.hole_triangles;
        s->stats.eroded_triangles += tiles[k].stats.eroded_triangles;
    }
    st = place_tiles(s, tiles, range, nt, ids, dcut, cut.cut_axis, mean_nn, p->tile_points / 4,
                     p->threads);
done:
    if (tiles)
        for (size_t k = 0; k < nt; k++)
            tsl_af_free(&tiles[k]);
    tsl_tiles_free(&cut);
    free(local);
    free(tiles);
    free(tstart);
    free(sfrom);
    return st;
}

/* Places the starting triangles in s (see tsl_advancing_front_from). */
tessel_status tsl_af_place_start(af *s, const uint32_t *start, size_t count)
{
    uint32_t *tri = tsl_alloc_array(3 * count + 1, sizeof *tri);
    uint8_t *touched = tsl_calloc_array(s->n, sizeof *touched);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!tri || !touched)
        goto done;
    memcpy(tri, start, 3 * count * sizeof *tri);
    for (size_t c = 0; c < 3 * count; c++)
        touched[tri[c]] = 1;
    if ((st = tsl_single_fans(s->n, tri, &count, touched, NULL, NULL)))
        goto done;
    st = import_mesh(s, tri, count, NULL, NULL);
done:
    free(tri);
    free(touched);
    return st;
}
