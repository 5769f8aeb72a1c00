/* Reading over MPI (include/tessel_mpi.h, docs/mpi.md): a cloud read in
 * parts, each process its own (src/io/stream.c tsl_cloud_read_part), joined
 * on one process or on all; or read by one process and sent to all. */
#include "io/io.h"
#include "io/stream.h"
#include "mpi/mpi.h"
#include "tessel_mpi.h"

#include <stdlib.h>
#include <string.h>

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
    tessel_status all = tsl_mpi_agree(comm, mine);
    if (all != TESSEL_OK) {
        if (rank != root)
            tessel_cloud_free(cloud);
        return all;
    }
    tsl_mpi_bcast(comm, root, cloud->xyz, 3 * cloud->count, MPI_FLOAT, sizeof *cloud->xyz);
    if (h.normals)
        tsl_mpi_bcast(comm, root, cloud->normals, 3 * cloud->count, MPI_FLOAT,
                    sizeof *cloud->normals);
    if (h.rgb)
        tsl_mpi_bcast(comm, root, cloud->rgb, 3 * cloud->count, MPI_BYTE, 1);
    if (h.grid)
        tsl_mpi_bcast(comm, root, cloud->grid, cells, MPI_UINT32_T, sizeof *cloud->grid);
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
    tessel_status all = tsl_mpi_agree(comm, mine);
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
    if ((st = tsl_mpi_agree(comm, st)) != TESSEL_OK)
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
    st = tsl_mpi_agree(comm, tsl_offset_of_samples(sample, m, offset));
done:
    free(sample);
    free(counts);
    free(displs);
    return st;
}

/* The part of process r (pt) to root, or to every process when root < 0. */
static void share_part(MPI_Comm comm, int root, int r, void *buf, size_t count,
                       MPI_Datatype type, size_t size)
{
    if (root < 0)
        tsl_mpi_bcast(comm, r, buf, count, type, size);
    else if (r != root)
        tsl_mpi_move(comm, r, root, buf, count, type, size);
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
    tessel_status st = tsl_mpi_agree(comm, pt.count && pt.start ? TESSEL_OK : TESSEL_ERR_NOMEM);
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
    if ((st = tsl_mpi_agree(comm, st)) != TESSEL_OK)
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

