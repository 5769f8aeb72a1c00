/* tessel over MPI (include/tessel_mpi.h, docs/mpi.md). The cloud goes from
 * one process to all; greedy projection's tiles (greedy/tiles.c) are meshed
 * tile k by process k mod size and sent to process 0, which closes the
 * seams, checks the orientation and flips the diagonals exactly as one
 * process does: the same bytes for any number of processes. Failures: a
 * status is agreed (MPI_Allreduce, the largest code) before any step that
 * the processes take together, and process 0's final status goes to all. */
#include <mpi.h>

#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "greedy/greedy.h"
#include "io/io.h"
#include "io/stream.h"
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

/* ---- reading in parts ---- */

static int any_part(void *ctx, int mine)
{
    int out = 0;
    MPI_Allreduce(&mine, &out, 1, MPI_INT, MPI_LOR, *(MPI_Comm *)ctx);
    return out;
}

/* The agreed status; on failure every process gets the diagnostic of the
 * first process that failed. */
static tessel_status agree_diag(MPI_Comm comm, tessel_status mine, tessel_diag *diag)
{
    tessel_status all = agree(comm, mine);
    if (all == TESSEL_OK)
        return all;
    int rank, size, first;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    int me = mine != TESSEL_OK ? rank : size;
    MPI_Allreduce(&me, &first, 1, MPI_INT, MPI_MIN, comm);
    tessel_diag d;
    memset(&d, 0, sizeof d);
    if (rank == first && diag)
        d = *diag;
    MPI_Bcast(&d, (int)sizeof d, MPI_BYTE, first, comm);
    if (diag)
        *diag = d;
    return all;
}

/* Every process's share of the points, and where it starts. */
typedef struct parts {
    uint64_t *count, *start;
    uint64_t total;
} parts;

/* The offset of the whole cloud (tsl_choose_offset's rule) from the
 * samples each part holds. */
static tessel_status part_offset(MPI_Comm comm, const parts *pt, int rank, int size,
                                 const double *xyz, double offset[3])
{
    size_t m = tsl_offset_samples((size_t)pt->total);
    double *sample = tsl_alloc_array(m + 1, 3 * sizeof *sample);
    int *counts = tsl_alloc_array((size_t)size, sizeof *counts);
    int *displs = tsl_alloc_array((size_t)size, sizeof *displs);
    tessel_status st = sample && counts && displs ? TESSEL_OK : TESSEL_ERR_NOMEM;
    if ((st = agree(comm, st)) != TESSEL_OK)
        goto done;
    /* Sample j is point tsl_offset_sample_at(j): increasing in j, so the
     * samples of the parts follow one another in the order of the parts. */
    for (int r = 0; r < size; r++)
        counts[r] = 0;
    for (size_t j = 0, r = 0; j < m; j++) {
        uint64_t at = tsl_offset_sample_at(j, (size_t)pt->total, m);
        while (at >= pt->start[r] + pt->count[r])
            r++;
        counts[r] += 3;
        if ((int)r == rank)
            memcpy(sample + 3 * j, xyz + 3 * (at - pt->start[r]), 3 * sizeof *sample);
    }
    for (int r = 0, at = 0; r < size; r++) {
        displs[r] = at;
        at += counts[r];
    }
    MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DOUBLE, sample, counts, displs, MPI_DOUBLE, comm);
    st = agree(comm, tsl_offset_of_samples(sample, m, offset));
done:
    free(sample);
    free(counts);
    free(displs);
    return st;
}

/* The whole cloud on every process from each one's part b: offset chosen,
 * floats as tessel_cloud_read stores them, the parts shared in order. */
static tessel_status join_parts(MPI_Comm comm, const char *path, const tessel_read_params *params,
                                tsl_builder *b, tessel_cloud *cloud, tessel_diag *diag)
{
    int rank, size;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    parts pt = {tsl_calloc_array((size_t)size, sizeof *pt.count),
                tsl_calloc_array((size_t)size, sizeof *pt.start), 0};
    tessel_status st = agree(comm, pt.count && pt.start ? TESSEL_OK : TESSEL_ERR_NOMEM);
    if (st != TESSEL_OK)
        goto done;
    uint64_t mine = b->count, dropped = b->dropped, dropped_all = 0;
    MPI_Allgather(&mine, 1, MPI_UINT64_T, pt.count, 1, MPI_UINT64_T, comm);
    MPI_Allreduce(&dropped, &dropped_all, 1, MPI_UINT64_T, MPI_SUM, comm);
    for (int r = 0; r < size; r++) {
        pt.start[r] = pt.total;
        pt.total += pt.count[r];
    }
    int attr[2] = {b->has_normals, b->has_rgb};
    MPI_Allreduce(MPI_IN_PLACE, attr, 2, MPI_INT, MPI_LOR, comm);
    uint64_t limit = params ? params->max_points : tessel_read_params_default().max_points;
    if (pt.total > limit) {
        tsl_diag_set(diag, path, 0, 0, 0, "%llu points, above the limit of %llu",
                     (unsigned long long)pt.total, (unsigned long long)limit);
        st = TESSEL_ERR_LIMIT;
        goto done;
    }
    double offset[3];
    if ((st = part_offset(comm, &pt, rank, size, b->xyz, offset)) != TESSEL_OK)
        goto done;
    st = tessel_cloud_alloc(cloud, (size_t)pt.total, attr[0], attr[1]);
    if ((st = agree(comm, st)) != TESSEL_OK)
        goto done;
    memcpy(cloud->offset, offset, sizeof offset);
    size_t at = (size_t)pt.start[rank];
    for (size_t i = 0; i < 3 * b->count; i++)
        cloud->xyz[3 * at + i] = tsl_local_coord(b->xyz[i], cloud->offset[i % 3]);
    if (attr[0] && b->count)
        memcpy(cloud->normals + 3 * at, b->normals, 3 * b->count * sizeof *cloud->normals);
    if (attr[1] && b->count)
        memcpy(cloud->rgb + 3 * at, b->rgb, 3 * b->count);
    tsl_builder_free(b);
    for (int r = 0; r < size; r++) {
        size_t from = (size_t)pt.start[r], n = (size_t)pt.count[r];
        bcast_array(comm, r, cloud->xyz + 3 * from, 3 * n, MPI_FLOAT, sizeof *cloud->xyz);
        if (attr[0])
            bcast_array(comm, r, cloud->normals + 3 * from, 3 * n, MPI_FLOAT,
                        sizeof *cloud->normals);
        if (attr[1])
            bcast_array(comm, r, cloud->rgb + 3 * from, 3 * n, MPI_BYTE, 1);
    }
    cloud->dropped_nonfinite = (size_t)dropped_all;
done:
    free(pt.count);
    free(pt.start);
    return st;
}

tessel_status tessel_mpi_cloud_read(MPI_Comm comm, const char *path,
                                    const tessel_read_params *params, tessel_cloud *cloud,
                                    tessel_diag *diag)
{
    int rank, size;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    memset(cloud, 0, sizeof *cloud);
    tsl_builder b;
    bool whole = false;
    tessel_status st = tsl_cloud_read_part(path, params, (size_t)rank, (size_t)size, any_part,
                                           &comm, &b, &whole, diag);
    if ((st = agree_diag(comm, st, diag)) != TESSEL_OK) {
        tsl_builder_free(&b);
        return st;
    }
    int any_whole = whole;
    MPI_Allreduce(MPI_IN_PLACE, &any_whole, 1, MPI_INT, MPI_LOR, comm);
    if (any_whole) {
        tsl_builder_free(&b);
        st = rank == 0 ? tessel_cloud_read(cloud, path, params, diag) : TESSEL_OK;
        if ((st = agree_diag(comm, st, diag)) != TESSEL_OK) {
            tessel_cloud_free(cloud);
            return st;
        }
        return tessel_mpi_cloud_share(comm, 0, TESSEL_OK, cloud);
    }
    st = join_parts(comm, path, params, &b, cloud, diag);
    tsl_builder_free(&b);
    if ((st = agree_diag(comm, st, diag)) != TESSEL_OK)
        tessel_cloud_free(cloud);
    return st;
}

typedef struct ranks {
    MPI_Comm comm;
    int rank, size;
    int tile_threads; /* each process's threads for its tiles */
    bool joined;      /* the runner was called (it took part in the tiles' steps) */
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
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(r->tile_threads))
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

static int owner(const ranks *r, size_t k)
{
    return (int)(k % (size_t)r->size);
}

/* Point-to-point in pieces of at most PIECE elements (the same pieces on
 * both sides). */
static void send_array(const ranks *r, const void *buf, size_t count, MPI_Datatype type,
                       size_t size)
{
    for (size_t i = 0; i < count; i += PIECE) {
        size_t n = count - i < PIECE ? count - i : PIECE;
        MPI_Send((const char *)buf + i * size, (int)n, type, 0, 0, r->comm);
    }
}

static void recv_array(const ranks *r, int from, void *buf, size_t count, MPI_Datatype type,
                       size_t size)
{
    for (size_t i = 0; i < count; i += PIECE) {
        size_t n = count - i < PIECE ? count - i : PIECE;
        MPI_Recv((char *)buf + i * size, (int)n, type, from, 0, r->comm, MPI_STATUS_IGNORE);
    }
}

/* Every tile's triangles and summary from its process to process 0. */
static tessel_status gather_tiles(const ranks *r, const tsl_gp_tiles_job *job)
{
    size_t nt = job->count;
    uint64_t *counts = tsl_calloc_array(nt, sizeof *counts);
    if (agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM) != TESSEL_OK) {
        free(counts);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t k = (size_t)r->rank; k < nt; k += (size_t)r->size)
        counts[k] = job->parts[k].count;
    MPI_Allreduce(MPI_IN_PLACE, counts, (int)nt, MPI_UINT64_T, MPI_SUM, r->comm);
    tessel_status mine = TESSEL_OK;
    for (size_t k = 0; r->rank == 0 && k < nt && mine == TESSEL_OK; k++) {
        gp_collect *c = &job->parts[k];
        if (owner(r, k) == 0 || !counts[k])
            continue;
        c->tris = tsl_alloc_array((size_t)counts[k], 3 * sizeof *c->tris);
        c->count = c->cap = c->tris ? (size_t)counts[k] : 0;
        mine = c->tris ? TESSEL_OK : TESSEL_ERR_NOMEM;
    }
    free(counts);
    if ((mine = agree(r->comm, mine)) != TESSEL_OK)
        return mine;
    /* Each tile's fates, packed in the tile's order of points. */
    size_t most = 0;
    for (size_t k = 0; k < nt; k++) {
        size_t m = job->cut->start[k + 1] - job->cut->start[k];
        most = m > most ? m : most;
    }
    uint8_t *fate = tsl_alloc_array(most + 1, 1);
    if ((mine = agree(r->comm, fate ? TESSEL_OK : TESSEL_ERR_NOMEM)) != TESSEL_OK) {
        free(fate);
        return mine;
    }
    for (size_t k = 0; k < nt; k++) {
        int from = owner(r, k);
        gp_collect *c = &job->parts[k];
        const uint32_t *ids = job->cut->ids + job->cut->start[k];
        size_t m = job->cut->start[k + 1] - job->cut->start[k];
        if (from == 0)
            continue;
        if (r->rank == from) {
            send_array(r, c->tris, 3 * c->count, MPI_UINT32_T, sizeof *c->tris);
            MPI_Send(&job->sums[k], (int)sizeof job->sums[k], MPI_BYTE, 0, 0, r->comm);
            for (size_t i = 0; i < m; i++)
                fate[i] = job->fate[ids[i]];
            send_array(r, fate, m, MPI_BYTE, 1);
        } else if (r->rank == 0) {
            recv_array(r, from, c->tris, 3 * c->count, MPI_UINT32_T, sizeof *c->tris);
            MPI_Recv(&job->sums[k], (int)sizeof job->sums[k], MPI_BYTE, from, 0, r->comm,
                     MPI_STATUS_IGNORE);
            recv_array(r, from, fate, m, MPI_BYTE, 1);
            for (size_t i = 0; i < m; i++)
                job->fate[ids[i]] = fate[i];
        }
    }
    free(fate);
    return TESSEL_OK;
}

/* The runner of every process: its share of the tiles, then all of them on
 * process 0, which goes on alone (seams, orientation, flips, output). */
static tessel_status run_ranks(void *ctx, const tsl_gp_tiles_job *job)
{
    ranks *r = ctx;
    r->joined = true;
    tessel_status st = tsl_progress(job->callbacks, "greedy", 0.0);
    if (st == TESSEL_OK)
        st = mesh_mine(r, job);
    if ((st = agree(r->comm, st)) != TESSEL_OK)
        return st;
    if ((st = gather_tiles(r, job)) != TESSEL_OK)
        return st;
    return tsl_progress(job->callbacks, "greedy", 0.5);
}

/* Waits for process 0's final status without holding a core: the others
 * have nothing to do meanwhile, and process 0 may use every core. */
static tessel_status final_status(const ranks *r, tessel_status mine)
{
    int st = (int)mine;
    MPI_Request req;
    MPI_Ibcast(&st, 1, MPI_INT, 0, r->comm, &req);
    int done = 0;
    while (MPI_Test(&req, &done, MPI_STATUS_IGNORE) == MPI_SUCCESS && !done) {
        struct timespec nap = {0, 2000000};
        nanosleep(&nap, NULL);
    }
    return (tessel_status)st;
}

/* Process 0's threads after the tiles: each process's, times the processes
 * on its machine, at most the machine's cores (but never fewer than one
 * process's). */
static int last_step_threads(int threads, int beside)
{
    int one = tsl_threads(threads);
#ifdef _OPENMP
    int cores = omp_get_num_procs();
#else
    int cores = 1;
#endif
    long want = (long)one * beside;
    if (want > cores)
        want = cores > one ? cores : one;
    return (int)want;
}

tessel_status tessel_mpi_reconstruct_greedy(MPI_Comm comm, const tessel_cloud *cloud,
                                            const tessel_greedy_params *params,
                                            const tessel_callbacks *callbacks,
                                            const tessel_triangle_sink *sink,
                                            tessel_recon_summary *summary)
{
    ranks r = {comm, 0, 1, 0, false};
    MPI_Comm_rank(comm, &r.rank);
    MPI_Comm_size(comm, &r.size);
    tsl_gp_tile_runner runner = {run_ranks, &r};
    tessel_greedy_params p = params ? *params : tessel_greedy_params_default();
    /* After the tiles the processes beside process 0 on its machine wait
     * without a core: process 0 takes their threads for the seams, the
     * orientation check and the flips (the mesh does not depend on it). */
    r.tile_threads = p.threads;
    MPI_Comm node;
    if (MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node) ==
        MPI_SUCCESS) {
        int beside = 1;
        MPI_Comm_size(node, &beside);
        MPI_Comm_free(&node);
        if (r.rank == 0)
            p.threads = last_step_threads(p.threads, beside);
    }
    bool tiled = tsl_gp_tiled(cloud, &p);
    tessel_status st;
    if (r.rank == 0)
        st = tsl_reconstruct_greedy_with(cloud, &p, &runner, callbacks, sink, summary);
    else if (tiled)
        st = tsl_gp_tiles_help(cloud, &p, &runner, callbacks);
    else
        st = TESSEL_OK;
    /* A process that failed before its tiles' steps still takes part in
     * the first, with its failure, so that no process waits for it. */
    if (tiled && !r.joined)
        agree(comm, st == TESSEL_OK ? TESSEL_ERR_INVALID_ARG : st);
    return final_status(&r, r.rank == 0 ? st : TESSEL_OK);
}
