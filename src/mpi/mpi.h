/* What the files of src/mpi/ share (private; include/tessel_mpi.h is the
 * API): collective steps in pieces MPI's int counts can take, and the
 * tiles' protocol. Process 0 runs a method as one process does, with a
 * runner that sends tile k to process k mod size and takes it back; the
 * others serve tiles until process 0 says it is done, then wait for its
 * final status. Failures: a status is agreed (MPI_Allreduce, the largest
 * code) before any step the processes take together. */
#ifndef TESSEL_MPI_PRIVATE_H
#define TESSEL_MPI_PRIVATE_H

#include <mpi.h>

#include "core/core.h"

/* MPI counts are int: arrays go in pieces of at most 2^28 elements. */
#define PIECE ((size_t)1 << 28)

/* Every wait below is for a request tested every 0.1 ms, the core given
 * up in between: a process that waits (Open MPI's blocking calls poll
 * without rest) must not take a core from one that works, process 0 runs
 * on the cores of the processes beside it. */
void tsl_mpi_wait(MPI_Request *req);
/* The largest status of all processes. */
tessel_status tsl_mpi_agree(MPI_Comm comm, tessel_status mine);
/* count values from root to all, in pieces. */
void tsl_mpi_bcast(MPI_Comm comm, int root, void *buf, size_t count, MPI_Datatype type,
                   size_t size);
/* count values from process `from` to process `to`, in pieces (no-op on
 * the other processes). */
void tsl_mpi_move(MPI_Comm comm, int from, int to, void *buf, size_t count, MPI_Datatype type,
                  size_t size);

typedef struct ranks {
    MPI_Comm comm;
    int rank, size;
    int tile_threads; /* each process's threads for its tiles */
    int last_threads; /* process 0's threads after the tiles */
} ranks;

/* comm's ranks; process 0's threads after the tiles: threads (0: OpenMP's
 * default) times the processes on its machine, at most the cores it may
 * run on (the others wait without a core meanwhile). */
ranks tsl_mpi_ranks(MPI_Comm comm, int threads);

static inline int tsl_mpi_owner(const ranks *r, size_t k)
{
    return (int)(k % (size_t)r->size);
}

/* What process 0 says when it hands out tiles, or when it is done. */
enum { TILES_DONE = 0, TILES_GREEDY = 1, TILES_FRONT = 2, TILES_SEAMS = 3 };
typedef struct tiles_head {
    int32_t status, kind, normals, lines, has_viewpoint;
    uint32_t k;          /* front: neighbours per point */
    uint64_t count;      /* tiles (seams: groups) */
    double offset[3], viewpoint[3]; /* greedy, seams: the cloud's, kept by a tile's copy */
    double cell;         /* front: the triangle grid's cell */
    tessel_front_params front; /* front: the parameters it runs with */
} tiles_head;

/* This process's tiles among count (k with tsl_mpi_owner(r, k) == r->rank),
 * each by tile(job, k), on r->tile_threads threads (no progress from
 * inside: the callbacks are not called from worker threads); the first
 * failure in tile order. */
tessel_status tsl_mpi_each_mine(const ranks *r, size_t count,
                                tessel_status (*tile)(const void *job, size_t k),
                                const void *job);
/* one(ctx, j) for every j < count, on r->tile_threads threads (a process's
 * own tiles or groups, numbered among themselves); the first failure. */
tessel_status tsl_mpi_each(const ranks *r, size_t count,
                           tessel_status (*one)(const void *ctx, size_t j), const void *ctx);
/* Process 0's head to all (the others pass anything). */
tiles_head tsl_mpi_head(const ranks *r, tiles_head h);
/* count + 1 sizes or offsets from process 0 (from) to all, into *out. */
tessel_status tsl_mpi_bcast_sizes(const ranks *r, size_t count, const size_t *from,
                                  uint64_t **out);
/* Per-tile counts, each known by its tile's process, summed on all. */
void tsl_mpi_sum_counts(const ranks *r, uint64_t *counts, size_t nt);
/* The other processes' side: tiles served until process 0 is done. */
tessel_status tsl_mpi_serve(const ranks *r);
/* Process 0's last word and everyone's result: its status, waited for
 * without spinning. */
tessel_status tsl_mpi_final(const ranks *r, tessel_status mine);
/* Process 0's end of a method: done with tiles, then its final status. */
tessel_status tsl_mpi_done(const ranks *r, tessel_status st);

/* The tiles of each kind, on a process other than 0 (greedy.c, front.c);
 * the groups of a level of greedy seams (greedy.c). */
tessel_status tsl_mpi_serve_greedy(const ranks *r, const tiles_head *h);
tessel_status tsl_mpi_serve_seams(const ranks *r, const tiles_head *h);
tessel_status tsl_mpi_serve_front(const ranks *r, const tiles_head *h);

#endif
