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

/* Moves count values from process `from` to process `to` (point to point,
 * in pieces of at most PIECE). */
static void move_array(MPI_Comm comm, int from, int to, void *buf, size_t count,
                       MPI_Datatype type, size_t size)
{
    int rank;
    MPI_Comm_rank(comm, &rank);
    for (size_t i = 0; i < count; i += PIECE) {
        int n = (int)(count - i < PIECE ? count - i : PIECE);
        if (rank == from)
            MPI_Send((char *)buf + i * size, n, type, to, 0, comm);
        else if (rank == to)
            MPI_Recv((char *)buf + i * size, n, type, from, 0, comm, MPI_STATUS_IGNORE);
    }
}

/* The part of process r (pt) to root, or to every process when root < 0. */
static void share_part(MPI_Comm comm, int root, int r, void *buf, size_t count,
                       MPI_Datatype type, size_t size)
{
    if (root < 0)
        bcast_array(comm, r, buf, count, type, size);
    else if (r != root)
        move_array(comm, r, root, buf, count, type, size);
}

/* The cloud from each process's part b, on root (every process when
 * root < 0): offset chosen, floats as tessel_cloud_read stores them, the
 * parts in order. A process that does not get the cloud converts its part
 * in place of the cloud's arrays and sends it. */
static tessel_status join_parts(MPI_Comm comm, int root, const char *path,
                                const tessel_read_params *params, tsl_builder *b,
                                tessel_cloud *cloud, tessel_diag *diag)
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
    bool whole = root < 0 || rank == root;
    st = tessel_cloud_alloc(cloud, (size_t)(whole ? pt.total : mine), attr[0], attr[1]);
    if ((st = agree(comm, st)) != TESSEL_OK)
        goto done;
    memcpy(cloud->offset, offset, sizeof offset);
    size_t at = whole ? (size_t)pt.start[rank] : 0;
    for (size_t i = 0; i < 3 * b->count; i++)
        cloud->xyz[3 * at + i] = tsl_local_coord(b->xyz[i], offset[i % 3]);
    if (attr[0] && b->count)
        memcpy(cloud->normals + 3 * at, b->normals, 3 * b->count * sizeof *cloud->normals);
    if (attr[1] && b->count)
        memcpy(cloud->rgb + 3 * at, b->rgb, 3 * b->count);
    tsl_builder_free(b);
    for (int r = 0; r < size; r++) {
        size_t from = whole ? (size_t)pt.start[r] : 0, n = (size_t)pt.count[r];
        share_part(comm, root, r, cloud->xyz + 3 * from, 3 * n, MPI_FLOAT, sizeof *cloud->xyz);
        if (attr[0])
            share_part(comm, root, r, cloud->normals + 3 * from, 3 * n, MPI_FLOAT,
                       sizeof *cloud->normals);
        if (attr[1])
            share_part(comm, root, r, cloud->rgb + 3 * from, 3 * n, MPI_BYTE, 1);
    }
    if (whole)
        cloud->dropped_nonfinite = (size_t)dropped_all;
    else
        tessel_cloud_free(cloud);
done:
    free(pt.count);
    free(pt.start);
    return st;
}

tessel_status tessel_mpi_cloud_read(MPI_Comm comm, int root, const char *path,
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
        int reader = root < 0 ? 0 : root;
        st = rank == reader ? tessel_cloud_read(cloud, path, params, diag) : TESSEL_OK;
        if ((st = agree_diag(comm, st, diag)) != TESSEL_OK) {
            tessel_cloud_free(cloud);
            return st;
        }
        return root < 0 ? tessel_mpi_cloud_share(comm, 0, TESSEL_OK, cloud) : TESSEL_OK;
    }
    st = join_parts(comm, root, path, params, &b, cloud, diag);
    tsl_builder_free(&b);
    if ((st = agree_diag(comm, st, diag)) != TESSEL_OK)
        tessel_cloud_free(cloud);
    return st;
}

typedef struct ranks {
    MPI_Comm comm;
    int rank, size;
    int tile_threads; /* each process's threads for its tiles */
    bool joined;      /* process 0: the runner was called */
} ranks;

static int owner(const ranks *r, size_t k)
{
    return (int)(k % (size_t)r->size);
}

/* What process 0 tells the others when it starts the tiles, or when it
 * ends without them: its status (not OK: stop) and the tiles (0: none). */
typedef struct tiles_head {
    int32_t status, normals, has_viewpoint;
    uint64_t count;
    double offset[3], viewpoint[3]; /* the cloud's, which a tile's copy keeps */
} tiles_head;

static tiles_head bcast_head(const ranks *r, tiles_head h)
{
    MPI_Bcast(&h, (int)sizeof h, MPI_BYTE, 0, r->comm);
    return h;
}

/* The tiles' point ranges (count + 1 starts), from process 0 to all. */
static tessel_status bcast_starts(const ranks *r, size_t count, const size_t *from,
                                  uint64_t **start)
{
    *start = tsl_alloc_array(count + 1, sizeof **start);
    tessel_status st = agree(r->comm, *start ? TESSEL_OK : TESSEL_ERR_NOMEM);
    if (st != TESSEL_OK)
        return st;
    for (size_t k = 0; from && k <= count; k++)
        (*start)[k] = from[k];
    bcast_array(r->comm, 0, *start, count + 1, MPI_UINT64_T, sizeof **start);
    return TESSEL_OK;
}

/* The counts of every tile's triangles, summed over the processes (each
 * knows its own tiles'). */
static void share_counts(const ranks *r, uint64_t *counts, size_t nt)
{
    for (size_t k = 0; k < nt; k += PIECE) {
        int n = (int)(nt - k < PIECE ? nt - k : PIECE);
        MPI_Allreduce(MPI_IN_PLACE, counts + k, n, MPI_UINT64_T, MPI_SUM, r->comm);
    }
}

/* ---- process 0 ---- */

/* Its own tiles, on its threads (no progress from inside: the callbacks
 * are not called from worker threads). */
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
        status[k] = owner(r, k) == 0 ? tsl_gp_tile_mesh(job, k, NULL) : TESSEL_OK;
    }
    tessel_status st = TESSEL_OK;
    for (size_t k = 0; k < nt && !st; k++)
        st = status[k];
    free(status);
    return st;
}

/* Every other process's tiles, point by point in the tile's order, to it. */
static tessel_status send_tiles(const ranks *r, const tsl_gp_tiles_job *job)
{
    const tsl_tiles *cut = job->cut;
    size_t most = 0;
    for (size_t k = 0; k < job->count; k++)
        most = cut->start[k + 1] - cut->start[k] > most ? cut->start[k + 1] - cut->start[k] : most;
    float *buf = tsl_alloc_array(3 * most + 1, sizeof *buf);
    tessel_status st = agree(r->comm, buf ? TESSEL_OK : TESSEL_ERR_NOMEM);
    for (size_t k = 0; st == TESSEL_OK && k < job->count; k++) {
        if (owner(r, k) == 0)
            continue;
        const uint32_t *ids = cut->ids + cut->start[k];
        size_t m = cut->start[k + 1] - cut->start[k];
        for (int block = 0; block < 1 + (job->cloud->normals != NULL); block++) {
            const float *src = block ? job->cloud->normals : job->cloud->xyz;
            for (size_t i = 0; i < m; i++)
                memcpy(buf + 3 * i, src + 3 * (size_t)ids[i], 3 * sizeof *buf);
            move_array(r->comm, 0, owner(r, k), buf, 3 * m, MPI_FLOAT, sizeof *buf);
        }
    }
    free(buf);
    return st;
}

/* The other processes' tiles back: triangles (mapped from the tile's
 * order to the cloud's), summaries and fates. */
static tessel_status receive_tiles(const ranks *r, const tsl_gp_tiles_job *job)
{
    size_t nt = job->count;
    const tsl_tiles *cut = job->cut;
    uint64_t *counts = tsl_calloc_array(nt, sizeof *counts);
    if (agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM) != TESSEL_OK) {
        free(counts);
        return TESSEL_ERR_NOMEM;
    }
    share_counts(r, counts, nt);
    size_t most = 0;
    tessel_status mine = TESSEL_OK;
    for (size_t k = 0; k < nt && mine == TESSEL_OK; k++) {
        gp_collect *c = &job->parts[k];
        most = cut->start[k + 1] - cut->start[k] > most ? cut->start[k + 1] - cut->start[k] : most;
        if (owner(r, k) == 0 || !counts[k])
            continue;
        c->tris = tsl_alloc_array((size_t)counts[k], 3 * sizeof *c->tris);
        c->count = c->cap = c->tris ? (size_t)counts[k] : 0;
        mine = c->tris ? TESSEL_OK : TESSEL_ERR_NOMEM;
    }
    free(counts);
    uint8_t *fate = mine == TESSEL_OK ? tsl_alloc_array(most + 1, 1) : NULL;
    if ((mine = agree(r->comm, fate ? TESSEL_OK : TESSEL_ERR_NOMEM)) != TESSEL_OK) {
        free(fate);
        return mine;
    }
    for (size_t k = 0; k < nt; k++) {
        int from = owner(r, k);
        if (from == 0)
            continue;
        gp_collect *c = &job->parts[k];
        const uint32_t *ids = cut->ids + cut->start[k];
        size_t m = cut->start[k + 1] - cut->start[k];
        move_array(r->comm, from, 0, c->tris, 3 * c->count, MPI_UINT32_T, sizeof *c->tris);
        for (size_t i = 0; i < 3 * c->count; i++)
            c->tris[i] = ids[c->tris[i]];
        move_array(r->comm, from, 0, &job->sums[k], sizeof job->sums[k], MPI_BYTE, 1);
        move_array(r->comm, from, 0, fate, m, MPI_BYTE, 1);
        for (size_t i = 0; i < m; i++)
            job->fate[ids[i]] = fate[i];
    }
    free(fate);
    return TESSEL_OK;
}

/* Process 0's runner: the other processes' tiles sent to them, its own
 * meshed, theirs received; it then goes on alone (seams, orientation,
 * flips, output). */
static tessel_status run_ranks(void *ctx, const tsl_gp_tiles_job *job)
{
    ranks *r = ctx;
    r->joined = true;
    tessel_status st = tsl_progress(job->callbacks, "greedy", 0.0);
    const tessel_cloud *c = job->cloud;
    tiles_head h = {(int32_t)st, c->normals != NULL, c->has_viewpoint, job->count, {0}, {0}};
    memcpy(h.offset, c->offset, sizeof h.offset);
    memcpy(h.viewpoint, c->viewpoint, sizeof h.viewpoint);
    bcast_head(r, h);
    if (st != TESSEL_OK)
        return st;
    uint64_t *start;
    if ((st = bcast_starts(r, job->count, job->cut->start, &start)) != TESSEL_OK)
        return st;
    free(start);
    if ((st = send_tiles(r, job)) != TESSEL_OK)
        return st;
    st = mesh_mine(r, job);
    if ((st = agree(r->comm, st)) != TESSEL_OK)
        return st;
    if ((st = receive_tiles(r, job)) != TESSEL_OK)
        return st;
    return tsl_progress(job->callbacks, "greedy", 0.5);
}

/* ---- the other processes ---- */

/* A process's own tiles: their points as received, their meshes. */
typedef struct own_tiles {
    size_t count;        /* tiles of this process */
    size_t *k;           /* their numbers */
    tessel_cloud *cloud; /* their points, in the tile's order */
    gp_collect *parts;
    tessel_recon_summary *sums;
    uint8_t **fate;
} own_tiles;

static void own_free(own_tiles *o)
{
    for (size_t j = 0; j < o->count; j++) {
        if (o->cloud)
            tessel_cloud_free(&o->cloud[j]);
        if (o->parts)
            free(o->parts[j].tris);
        if (o->fate)
            free(o->fate[j]);
    }
    free(o->k);
    free(o->cloud);
    free(o->parts);
    free(o->sums);
    free(o->fate);
    memset(o, 0, sizeof *o);
}

/* Room for this process's tiles of h (starts: their point ranges). */
static tessel_status own_alloc(const ranks *r, const tiles_head *h, const uint64_t *start,
                               own_tiles *o)
{
    size_t nt = (size_t)h->count;
    o->count = nt / (size_t)r->size + (nt % (size_t)r->size > (size_t)r->rank);
    o->k = tsl_calloc_array(o->count + 1, sizeof *o->k);
    o->cloud = tsl_calloc_array(o->count + 1, sizeof *o->cloud);
    o->parts = tsl_calloc_array(o->count + 1, sizeof *o->parts);
    o->sums = tsl_calloc_array(o->count + 1, sizeof *o->sums);
    o->fate = tsl_calloc_array(o->count + 1, sizeof *o->fate);
    if (!o->k || !o->cloud || !o->parts || !o->sums || !o->fate)
        return TESSEL_ERR_NOMEM;
    for (size_t j = 0; j < o->count; j++) {
        size_t k = (size_t)r->rank + j * (size_t)r->size, m = (size_t)(start[k + 1] - start[k]);
        o->k[j] = k;
        tessel_cloud *c = &o->cloud[j];
        if (tessel_cloud_alloc(c, m, h->normals, 0) != TESSEL_OK ||
            !(o->fate[j] = tsl_alloc_array(m + 1, 1)))
            return TESSEL_ERR_NOMEM;
        memcpy(c->offset, h->offset, sizeof c->offset);
        memcpy(c->viewpoint, h->viewpoint, sizeof c->viewpoint);
        c->has_viewpoint = h->has_viewpoint;
    }
    return TESSEL_OK;
}

static tessel_status mesh_own(const ranks *r, const tessel_greedy_params *params, own_tiles *o)
{
    tessel_status *status = tsl_alloc_array(o->count + 1, sizeof *status);
    if (!status)
        return TESSEL_ERR_NOMEM;
    tessel_greedy_params tp = *params;
    tp.tile_points = 0;
    long long count = (long long)o->count;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(r->tile_threads))
    for (long long jj = 0; jj < count; jj++) {
        size_t j = (size_t)jj;
        status[j] = tsl_gp_tile_mesh_cloud(&o->cloud[j], &tp, NULL, &o->parts[j], o->fate[j],
                                           &o->sums[j]);
        tessel_cloud_free(&o->cloud[j]);
    }
    tessel_status st = TESSEL_OK;
    for (size_t j = 0; j < o->count && !st; j++)
        st = status[j];
    free(status);
    return st;
}

/* A process other than 0: receives its tiles, meshes them, sends them back
 * (the other side of run_ranks). */
static tessel_status serve(const ranks *r, const tessel_greedy_params *params)
{
    tiles_head h = bcast_head(r, (tiles_head){0});
    if (h.status != TESSEL_OK || h.count == 0)
        return (tessel_status)h.status;
    uint64_t *start = NULL;
    own_tiles o = {0};
    tessel_status st = bcast_starts(r, (size_t)h.count, NULL, &start);
    if (st != TESSEL_OK)
        return st;
    st = agree(r->comm, own_alloc(r, &h, start, &o)); /* send_tiles' agreement */
    for (size_t j = 0; st == TESSEL_OK && j < o.count; j++) {
        size_t m = o.cloud[j].count;
        move_array(r->comm, 0, r->rank, o.cloud[j].xyz, 3 * m, MPI_FLOAT, sizeof(float));
        if (h.normals)
            move_array(r->comm, 0, r->rank, o.cloud[j].normals, 3 * m, MPI_FLOAT,
                       sizeof(float));
    }
    if (st == TESSEL_OK)
        st = agree(r->comm, mesh_own(r, params, &o));
    uint64_t *counts = NULL;
    if (st == TESSEL_OK) {
        counts = tsl_calloc_array((size_t)h.count, sizeof *counts);
        st = agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM);
    }
    if (st == TESSEL_OK) {
        for (size_t j = 0; j < o.count; j++)
            counts[o.k[j]] = o.parts[j].count;
        share_counts(r, counts, (size_t)h.count);
        st = agree(r->comm, TESSEL_OK); /* receive_tiles' room */
    }
    for (size_t j = 0; st == TESSEL_OK && j < o.count; j++) {
        size_t m = (size_t)(start[o.k[j] + 1] - start[o.k[j]]);
        move_array(r->comm, r->rank, 0, o.parts[j].tris, 3 * o.parts[j].count, MPI_UINT32_T,
                   sizeof(uint32_t));
        move_array(r->comm, r->rank, 0, &o.sums[j], sizeof o.sums[j], MPI_BYTE, 1);
        move_array(r->comm, r->rank, 0, o.fate[j], m, MPI_BYTE, 1);
    }
    free(counts);
    free(start);
    own_free(&o);
    return st;
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
    /* The others' failures are agreed with process 0, whose final status
     * says how it ended. */
    if (r.rank != 0) {
        (void)serve(&r, &p);
        return final_status(&r, TESSEL_OK);
    }
    tessel_status st = tsl_reconstruct_greedy_with(cloud, &p, &runner, callbacks, sink, summary);
    /* Without tiles (one tile's worth of points, or a failure before them)
     * the others still wait for the head: none. */
    if (!r.joined)
        bcast_head(&r, (tiles_head){.status = (int32_t)st});
    return final_status(&r, st);
}
