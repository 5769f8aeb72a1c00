/* The collective steps and the tiles' protocol of src/mpi/ (mpi.h). */
#include "mpi/mpi.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif

void tsl_mpi_wait(MPI_Request *req)
{
    int done = 0;
    while (MPI_Test(req, &done, MPI_STATUS_IGNORE) == MPI_SUCCESS && !done) {
        struct timespec nap = {0, 100000};
        nanosleep(&nap, NULL);
    }
}

tessel_status tsl_mpi_agree(MPI_Comm comm, tessel_status mine)
{
    int in = (int)mine, out = 0;
    MPI_Request req;
    MPI_Iallreduce(&in, &out, 1, MPI_INT, MPI_MAX, comm, &req);
    tsl_mpi_wait(&req);
    return (tessel_status)out;
}

void tsl_mpi_bcast(MPI_Comm comm, int root, void *buf, size_t count, MPI_Datatype type,
                   size_t size)
{
    for (size_t i = 0; i < count; i += PIECE) {
        size_t n = count - i < PIECE ? count - i : PIECE;
        MPI_Request req;
        MPI_Ibcast((char *)buf + i * size, (int)n, type, root, comm, &req);
        tsl_mpi_wait(&req);
    }
}

void tsl_mpi_move(MPI_Comm comm, int from, int to, void *buf, size_t count, MPI_Datatype type,
                  size_t size)
{
    int rank;
    MPI_Comm_rank(comm, &rank);
    for (size_t i = 0; i < count; i += PIECE) {
        int n = (int)(count - i < PIECE ? count - i : PIECE);
        MPI_Request req;
        if (rank == from)
            MPI_Isend((char *)buf + i * size, n, type, to, 0, comm, &req);
        else if (rank == to)
            MPI_Irecv((char *)buf + i * size, n, type, from, 0, comm, &req);
        else
            continue;
        tsl_mpi_wait(&req);
    }
}

ranks tsl_mpi_ranks(MPI_Comm comm, int threads)
{
    ranks r = {comm, 0, 1, threads, threads};
    MPI_Comm_rank(comm, &r.rank);
    MPI_Comm_size(comm, &r.size);
    MPI_Comm node;
    int beside = 1;
    if (MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node) ==
        MPI_SUCCESS) {
        MPI_Comm_size(node, &beside);
        MPI_Comm_free(&node);
    }
    int one = tsl_threads(threads);
#ifdef _OPENMP
    int cores = omp_get_num_procs();
#else
    int cores = 1;
#endif
    long want = (long)one * beside;
    if (want > cores)
        want = cores > one ? cores : one;
    r.last_threads = (int)want;
    return r;
}

/* Items 0 .. count), those of this process only when mine. */
static tessel_status each(const ranks *r, size_t count, bool mine,
                          tessel_status (*one)(const void *ctx, size_t k), const void *ctx)
{
    tessel_status *status = tsl_alloc_array(count + 1, sizeof *status);
    if (!status)
        return TESSEL_ERR_NOMEM;
    long long n = (long long)count;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(r->tile_threads))
    for (long long kk = 0; kk < n; kk++) {
        size_t k = (size_t)kk;
        status[k] = !mine || tsl_mpi_owner(r, k) == r->rank ? one(ctx, k) : TESSEL_OK;
    }
    tessel_status st = TESSEL_OK;
    for (size_t k = 0; k < count && !st; k++)
        st = status[k];
    free(status);
    return st;
}

tessel_status tsl_mpi_each_mine(const ranks *r, size_t count,
                                tessel_status (*tile)(const void *job, size_t k),
                                const void *job)
{
    return each(r, count, true, tile, job);
}

tessel_status tsl_mpi_each(const ranks *r, size_t count,
                           tessel_status (*one)(const void *ctx, size_t j), const void *ctx)
{
    return each(r, count, false, one, ctx);
}

tiles_head tsl_mpi_head(const ranks *r, tiles_head h)
{
    tsl_mpi_bcast(r->comm, 0, &h, sizeof h, MPI_BYTE, 1);
    return h;
}

tessel_status tsl_mpi_bcast_sizes(const ranks *r, size_t count, const size_t *from,
                                  uint64_t **out)
{
    *out = tsl_alloc_array(count + 1, sizeof **out);
    tessel_status st = tsl_mpi_agree(r->comm, *out ? TESSEL_OK : TESSEL_ERR_NOMEM);
    if (st != TESSEL_OK)
        return st;
    for (size_t k = 0; from && k <= count; k++)
        (*out)[k] = from[k];
    tsl_mpi_bcast(r->comm, 0, *out, count + 1, MPI_UINT64_T, sizeof **out);
    return TESSEL_OK;
}

void tsl_mpi_sum_counts(const ranks *r, uint64_t *counts, size_t nt)
{
    for (size_t k = 0; k < nt; k += PIECE) {
        int n = (int)(nt - k < PIECE ? nt - k : PIECE);
        MPI_Request req;
        MPI_Iallreduce(MPI_IN_PLACE, counts + k, n, MPI_UINT64_T, MPI_SUM, r->comm, &req);
        tsl_mpi_wait(&req);
    }
}

/* A failure while serving is agreed with process 0, which goes on to its
 * end and then says it is done: the loop ends there. */
tessel_status tsl_mpi_serve(const ranks *r)
{
    for (;;) {
        tiles_head h = tsl_mpi_head(r, (tiles_head){0});
        if (h.kind == TILES_DONE)
            return (tessel_status)h.status;
        if (h.status != TESSEL_OK)
            continue;
        (void)(h.kind == TILES_GREEDY  ? tsl_mpi_serve_greedy(r, &h)
               : h.kind == TILES_SEAMS ? tsl_mpi_serve_seams(r, &h)
                                       : tsl_mpi_serve_front(r, &h));
    }
}

tessel_status tsl_mpi_final(const ranks *r, tessel_status mine)
{
    int st = (int)mine;
    tsl_mpi_bcast(r->comm, 0, &st, 1, MPI_INT, sizeof st);
    return (tessel_status)st;
}

tessel_status tsl_mpi_done(const ranks *r, tessel_status st)
{
    tsl_mpi_head(r, (tiles_head){.status = (int32_t)st, .kind = TILES_DONE});
    return tsl_mpi_final(r, st);
}
