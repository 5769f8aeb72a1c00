/* The smooth method over MPI (include/tessel_mpi.h, docs/mpi.md): process 0
 * runs the pipeline as one process does (src/pipeline/) with a runner for
 * the tiles of its advancing front over the representatives: tile k's
 * inputs (points, normal lines, nearest distances, neighbours within the
 * tile, starting triangles) go to process k mod size, which runs the
 * tile's front (tsl_af_tile_run) and sends back its triangles; process 0
 * joins the tiles and goes on alone. A tile's front depends on the tile
 * alone: the same bytes for any number of processes. */
#include "front/front.h"
#include "mpi/mpi.h"
#include "pipeline/pipeline.h"
#include "tessel_mpi.h"

#include <stdlib.h>
#include <string.h>

/* A tile's inputs and its starting triangles, between process 0 (from) and
 * the tile's process (to): t has the room on both sides. */
static void move_inputs(MPI_Comm comm, int from, int to, af *t, uint32_t *start, size_t nstart)
{
    size_t m = t->n, blocks = 1 + (t->pnormals != NULL) + (t->lines != NULL);
    tsl_mpi_move(comm, from, to, t->own, 3 * m * blocks, MPI_FLOAT, sizeof *t->own);
    tsl_mpi_move(comm, from, to, t->knn, m * t->k, MPI_UINT32_T, sizeof *t->knn);
    tsl_mpi_move(comm, from, to, t->nnd, m, MPI_FLOAT, sizeof *t->nnd);
    tsl_mpi_move(comm, from, to, t->dup, m, MPI_BYTE, 1);
    tsl_mpi_move(comm, from, to, t->ln, 3 * m, MPI_FLOAT, sizeof *t->ln);
    tsl_mpi_move(comm, from, to, start, 3 * nstart, MPI_UINT32_T, sizeof *start);
}

/* A tile's front back, from its process (from) to process 0: triangles
 * (removed ones as TESSEL_NONE), how many were removed, its counts. */
static void move_result(MPI_Comm comm, int from, af *t)
{
    uint64_t deleted = t->deleted;
    tsl_mpi_move(comm, from, 0, t->tri, 3 * t->nt, MPI_UINT32_T, sizeof *t->tri);
    tsl_mpi_move(comm, from, 0, &deleted, 1, MPI_UINT64_T, sizeof deleted);
    tsl_mpi_move(comm, from, 0, &t->stats, sizeof t->stats, MPI_BYTE, 1);
    t->deleted = (size_t)deleted;
}

/* ---- process 0 ---- */

/* One of process 0's own tiles. */
static tessel_status mesh_one(const void *job, size_t k)
{
    return tsl_af_tile((const tsl_af_tiles_job *)job, k, NULL);
}

/* Each other process's tiles to it, tile by tile (the inputs are made
 * here, one tile at a time, and agreed on before they move). */
static tessel_status send_tiles(const ranks *r, const tsl_af_tiles_job *job)
{
    for (size_t k = 0; k < job->count; k++) {
        if (tsl_mpi_owner(r, k) == 0)
            continue;
        af t;
        tessel_status st = tsl_mpi_agree(r->comm, tsl_af_tile_inputs(job, k, &t));
        if (st == TESSEL_OK)
            move_inputs(r->comm, 0, tsl_mpi_owner(r, k), &t, (uint32_t *)job->start +
                        3 * job->sfrom[k], job->sfrom[k + 1] - job->sfrom[k]);
        tsl_af_free(&t);
        if (st != TESSEL_OK)
            return st;
    }
    return TESSEL_OK;
}

/* The other processes' fronts back into job->tiles. */
static tessel_status receive_tiles(const ranks *r, const tsl_af_tiles_job *job)
{
    size_t nt = job->count;
    uint64_t *counts = tsl_calloc_array(nt + 1, sizeof *counts);
    tessel_status st = tsl_mpi_agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM);
    if (st != TESSEL_OK) {
        free(counts);
        return st;
    }
    tsl_mpi_sum_counts(r, counts, nt);
    for (size_t k = 0; k < nt && st == TESSEL_OK; k++) {
        af *t = &job->tiles[k];
        if (tsl_mpi_owner(r, k) == 0)
            continue;
        t->nt = (size_t)counts[k];
        t->tri = tsl_alloc_array(3 * t->nt + 1, sizeof *t->tri);
        st = t->tri ? TESSEL_OK : TESSEL_ERR_NOMEM;
    }
    free(counts);
    if ((st = tsl_mpi_agree(r->comm, st)) != TESSEL_OK)
        return st;
    for (size_t k = 0; k < nt; k++)
        if (tsl_mpi_owner(r, k) != 0)
            move_result(r->comm, tsl_mpi_owner(r, k), &job->tiles[k]);
    return TESSEL_OK;
}

static tessel_status run_ranks(void *ctx, const tsl_af_tiles_job *job)
{
    const ranks *r = ctx;
    const af *s = job->s;
    tessel_status st = tsl_progress(job->cb, "front", 0.0);
    tiles_head h = {.status = (int32_t)st, .kind = TILES_FRONT, .count = job->count,
                    .normals = s->pnormals != NULL, .lines = s->lines != NULL, .k = s->k,
                    .cell = s->cell, .front = *job->p};
    tsl_mpi_head(r, h);
    if (st != TESSEL_OK)
        return st;
    uint64_t *range = NULL, *sfrom = NULL;
    st = tsl_mpi_bcast_sizes(r, job->count, job->range, &range);
    if (st == TESSEL_OK)
        st = tsl_mpi_bcast_sizes(r, job->count, job->sfrom, &sfrom);
    free(range);
    free(sfrom);
    if (st == TESSEL_OK)
        st = send_tiles(r, job);
    if (st == TESSEL_OK)
        st = tsl_mpi_agree(r->comm, tsl_mpi_each_mine(r, job->count, mesh_one, job));
    if (st == TESSEL_OK)
        st = receive_tiles(r, job);
    return st;
}

/* ---- the other processes ---- */

/* Own tile j of a serving process: its front. */
typedef struct own_fronts {
    const ranks *r;
    const tiles_head *h;
    af *tiles;
    uint32_t **start;
    const uint64_t *sfrom;
} own_fronts;

static tessel_status run_own(const void *ctx, size_t j)
{
    const own_fronts *o = ctx;
    size_t k = (size_t)o->r->rank + j * (size_t)o->r->size;
    return tsl_af_tile_run(&o->tiles[j], o->h->cell, o->start[j],
                           (size_t)(o->sfrom[k + 1] - o->sfrom[k]), NULL);
}

/* This process's tiles of h (their point ranges and starting triangles'
 * offsets), received one by one, run on its threads, sent back. */
tessel_status tsl_mpi_serve_front(const ranks *r, const tiles_head *h)
{
    size_t nt = (size_t)h->count;
    size_t mine = nt / (size_t)r->size + (nt % (size_t)r->size > (size_t)r->rank);
    uint64_t *range = NULL, *sfrom = NULL, *counts = NULL;
    af *tiles = NULL;
    uint32_t **start = NULL;
    /* Every failure below is agreed: process 0 stops at the same step. */
    tessel_status st = tsl_mpi_bcast_sizes(r, nt, NULL, &range);
    if (st == TESSEL_OK)
        st = tsl_mpi_bcast_sizes(r, nt, NULL, &sfrom);
    if (st != TESSEL_OK)
        goto done;
    tiles = tsl_calloc_array(mine + 1, sizeof *tiles);
    start = tsl_calloc_array(mine + 1, sizeof *start);
    tessel_status room = tiles && start ? TESSEL_OK : TESSEL_ERR_NOMEM;
    for (size_t k = 0, j = 0; k < nt; k++) {
        if (tsl_mpi_owner(r, k) == 0)
            continue;
        bool own = tsl_mpi_owner(r, k) == r->rank;
        size_t ns = (size_t)(sfrom[k + 1] - sfrom[k]);
        tessel_status here = own ? room : TESSEL_OK;
        if (own && here == TESSEL_OK)
            here = tsl_af_tile_alloc(&tiles[j], (size_t)(range[k + 1] - range[k]), h->k,
                                     &h->front, h->normals, h->lines);
        if (own && here == TESSEL_OK && !(start[j] = tsl_alloc_array(3 * ns + 1, sizeof **start)))
            here = TESSEL_ERR_NOMEM;
        if ((st = tsl_mpi_agree(r->comm, here)) != TESSEL_OK)
            goto done;
        if (own) {
            move_inputs(r->comm, 0, r->rank, &tiles[j], start[j], ns);
            j++;
        }
    }
    own_fronts o = {r, h, tiles, start, sfrom};
    if ((st = tsl_mpi_agree(r->comm, tsl_mpi_each(r, mine, run_own, &o))) != TESSEL_OK)
        goto done;
    counts = tsl_calloc_array(nt + 1, sizeof *counts);
    if ((st = tsl_mpi_agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM)) != TESSEL_OK)
        goto done;
    for (size_t j = 0; j < mine; j++)
        counts[(size_t)r->rank + j * (size_t)r->size] = tiles[j].nt;
    tsl_mpi_sum_counts(r, counts, nt);
    if ((st = tsl_mpi_agree(r->comm, TESSEL_OK)) != TESSEL_OK) /* receive_tiles' room */
        goto done;
    for (size_t j = 0; j < mine; j++)
        move_result(r->comm, r->rank, &tiles[j]);
done:
    for (size_t j = 0; j < mine && tiles && start; j++) {
        tsl_af_free(&tiles[j]);
        free(start[j]);
    }
    free(counts);
    free(tiles);
    free(start);
    free(range);
    free(sfrom);
    return st;
}

tessel_status tessel_mpi_reconstruct_smooth(MPI_Comm comm, const tessel_cloud *cloud,
                                            const tessel_smooth_recon_params *params,
                                            const tessel_callbacks *callbacks,
                                            tessel_mesh *mesh, tessel_smooth_recon_stats *stats)
{
    tessel_smooth_recon_params p = params ? *params : tessel_smooth_recon_params_default();
    ranks r = tsl_mpi_ranks(comm, p.threads);
    if (r.rank != 0) {
        if (mesh)
            memset(mesh, 0, sizeof *mesh);
        return tsl_mpi_final(&r, tsl_mpi_serve(&r));
    }
    tsl_af_tile_runner runner = {run_ranks, &r};
    /* The stages besides the tiles run on process 0's threads and those of
     * the processes beside it, which wait without a core. */
    p.threads = r.last_threads;
    tessel_status st = tsl_reconstruct_smooth_with(cloud, &p, &runner, callbacks, mesh, stats);
    return tsl_mpi_done(&r, st);
}
