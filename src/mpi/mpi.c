/* tessel over MPI (include/tessel_mpi.h, docs/mpi.md). The cloud goes from
 * one process to all; greedy projection's tiles (greedy/tiles.c) are meshed
 * tile k by process k mod size, and every process receives every tile's
 * triangles, so each closes the seams, checks the orientation and flips the
 * diagonals exactly as one process does: the same bytes for any number of
 * processes. Collective failures: a status is agreed (MPI_Allreduce, the
 * largest code) before any step that the processes must take together. */
#include <mpi.h>

#include <stdlib.h>
#include <string.h>

#include "greedy/greedy.h"
#include "tessel_mpi.h"

/* MPI counts are int: arrays go in pieces of at most 2^28 elements. */
#define PIECE ((size_t)1 << 28)

static tessel_status agree(MPI_Comm comm, tessel_status mine)
{
    int in = (int)mine, out = 0;
    MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_MAX, comm);
    return (tessel_status)out;
}

static void bcast_array(MPI_Comm comm, int root, void *buf, size_t count, MPI_Datatype type,
                        size_t size)
{
    for (size_t i = 0; i < count; i += PIECE) {
        size_t n = count - i < PIECE ? count - i : PIECE;
        MPI_Bcast((char *)buf + i * size, (int)n, type, root, comm);
    }
}

/* What a cloud is besides its arrays, as root sends it. */
typedef struct cloud_head {
    uint64_t count, dropped;
    uint32_t width, height;
    int32_t normals, rgb, grid, has_viewpoint;
    double offset[3], viewpoint[3];
} cloud_head;

tessel_status tessel_mpi_cloud_share(MPI_Comm comm, int root, tessel_status status,
                                     tessel_cloud *cloud)
{
    int rank;
    MPI_Comm_rank(comm, &rank);
    int st = (int)status;
    MPI_Bcast(&st, 1, MPI_INT, root, comm);
    if (st != TESSEL_OK)
        return (tessel_status)st;
    cloud_head h;
    memset(&h, 0, sizeof h);
    if (rank == root) {
        h.count = cloud->count;
        h.dropped = cloud->dropped_nonfinite;
        h.width = cloud->width;
        h.height = cloud->height;
        h.normals = cloud->normals != NULL;
        h.rgb = cloud->rgb != NULL;
        h.grid = cloud->grid != NULL;
        h.has_viewpoint = cloud->has_viewpoint;
        memcpy(h.offset, cloud->offset, sizeof h.offset);
        memcpy(h.viewpoint, cloud->viewpoint, sizeof h.viewpoint);
    }
    MPI_Bcast(&h, (int)sizeof h, MPI_BYTE, root, comm);
    tessel_status mine = TESSEL_OK;
    size_t cells = (size_t)h.width * h.height;
    if (rank != root) {
        mine = tessel_cloud_alloc(cloud, (size_t)h.count, h.normals, h.rgb);
        if (mine == TESSEL_OK && h.grid) {
            cloud->grid = tsl_alloc_array(cells, sizeof *cloud->grid);
            mine = cloud->grid ? TESSEL_OK : TESSEL_ERR_NOMEM;
        }
        if (mine == TESSEL_OK) {
            cloud->dropped_nonfinite = (size_t)h.dropped;
            cloud->width = h.width;
            cloud->height = h.height;
            cloud->has_viewpoint = h.has_viewpoint;
            memcpy(cloud->offset, h.offset, sizeof h.offset);
            memcpy(cloud->viewpoint, h.viewpoint, sizeof h.viewpoint);
        }
    }
    tessel_status all = agree(comm, mine);
    if (all != TESSEL_OK) {
        if (rank != root)
            tessel_cloud_free(cloud);
        return all;
    }
    bcast_array(comm, root, cloud->xyz, 3 * cloud->count, MPI_FLOAT, sizeof *cloud->xyz);
    if (h.normals)
        bcast_array(comm, root, cloud->normals, 3 * cloud->count, MPI_FLOAT,
                    sizeof *cloud->normals);
    if (h.rgb)
        bcast_array(comm, root, cloud->rgb, 3 * cloud->count, MPI_BYTE, 1);
    if (h.grid)
        bcast_array(comm, root, cloud->grid, cells, MPI_UINT32_T, sizeof *cloud->grid);
    return TESSEL_OK;
}

typedef struct ranks {
    MPI_Comm comm;
    int rank, size;
} ranks;

/* This process's tiles, on its threads (no progress from inside: the
 * callbacks are not called from worker threads). */
static tessel_status mesh_mine(const ranks *r, const tsl_gp_tiles_job *job)
{
    size_t nt = job->count;
    tessel_status *status = tsl_alloc_array(nt, sizeof *status);
    if (!status)
        return TESSEL_ERR_NOMEM;
    long long count = (long long)nt;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(job->params->threads))
    for (long long kk = 0; kk < count; kk++) {
        size_t k = (size_t)kk;
        status[k] = k % (size_t)r->size == (size_t)r->rank ? tsl_gp_tile_mesh(job, k, NULL)
                                                          : TESSEL_OK;
    }
    tessel_status st = TESSEL_OK;
    for (size_t k = 0; k < nt && !st; k++)
        st = status[k];
    free(status);
    return st;
}

/* Every tile's triangles and summary from its process to all. */
static tessel_status share_tiles(const ranks *r, const tsl_gp_tiles_job *job)
{
    size_t nt = job->count;
    uint64_t *counts = tsl_calloc_array(nt, sizeof *counts);
    tessel_status mine = counts ? TESSEL_OK : TESSEL_ERR_NOMEM;
    if (agree(r->comm, mine) != TESSEL_OK) {
        free(counts);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t k = (size_t)r->rank; k < nt; k += (size_t)r->size)
        counts[k] = job->parts[k].count;
    MPI_Allreduce(MPI_IN_PLACE, counts, (int)nt, MPI_UINT64_T, MPI_SUM, r->comm);
    for (size_t k = 0; k < nt && mine == TESSEL_OK; k++) {
        gp_collect *c = &job->parts[k];
        if (k % (size_t)r->size == (size_t)r->rank || !counts[k])
            continue;
        c->tris = tsl_alloc_array((size_t)counts[k], 3 * sizeof *c->tris);
        c->count = c->cap = (size_t)counts[k];
        if (!c->tris) {
            c->count = c->cap = 0;
            mine = TESSEL_ERR_NOMEM;
        }
    }
    free(counts);
    if ((mine = agree(r->comm, mine)) != TESSEL_OK)
        return mine;
    for (size_t k = 0; k < nt; k++) {
        int owner = (int)(k % (size_t)r->size);
        gp_collect *c = &job->parts[k];
        bcast_array(r->comm, owner, c->tris, 3 * c->count, MPI_UINT32_T, sizeof *c->tris);
        MPI_Bcast(&job->sums[k], (int)sizeof job->sums[k], MPI_BYTE, owner, r->comm);
    }
    return TESSEL_OK;
}

static tessel_status run_ranks(void *ctx, const tsl_gp_tiles_job *job)
{
    const ranks *r = ctx;
    tessel_status st = tsl_progress(job->callbacks, "greedy", 0.0);
    if (st == TESSEL_OK)
        st = mesh_mine(r, job);
    if ((st = agree(r->comm, st)) != TESSEL_OK)
        return st;
    if ((st = share_tiles(r, job)) != TESSEL_OK)
        return st;
    return tsl_progress(job->callbacks, "greedy", 0.5);
}

tessel_status tessel_mpi_reconstruct_greedy(MPI_Comm comm, const tessel_cloud *cloud,
                                            const tessel_greedy_params *params,
                                            const tessel_callbacks *callbacks,
                                            const tessel_triangle_sink *sink,
                                            tessel_recon_summary *summary)
{
    ranks r = {comm, 0, 1};
    MPI_Comm_rank(comm, &r.rank);
    MPI_Comm_size(comm, &r.size);
    tsl_gp_tile_runner runner = {run_ranks, &r};
    tessel_status st =
        tsl_reconstruct_greedy_with(cloud, params, &runner, callbacks, sink, summary);
    /* What follows the tiles runs on each process alone: agree at the end
     * so that no process keeps a result another could not make. */
    return agree(comm, st);
}
