/* tessel over MPI: the tiles of a reconstruction spread over the processes
 * of a communicator. Built when CMake finds MPI (library tessel_mpi, program
 * tessel-mpi); see docs/mpi.md.
 *
 * Every process of the communicator calls each function with the same
 * arguments (collective calls). The result is byte for byte what the
 * one-process function gives, for any number of processes and threads. */
#ifndef TESSEL_MPI_H
#define TESSEL_MPI_H

#include <mpi.h>

#include "tessel.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Sends root's cloud (positions, normals, colours, offset, organization and
 * viewpoint) to every process of comm; the others' *cloud must be empty
 * ({0}) and receive a copy they free with tessel_cloud_free. status is
 * root's status on entry (whether its cloud is valid, e.g. its read): a
 * failure there is returned on every process, which then keeps nothing. */
TESSEL_API tessel_status tessel_mpi_cloud_share(MPI_Comm comm, int root, tessel_status status,
                                                tessel_cloud *cloud);

/* tessel_cloud_read by all processes of comm, each reading its part of the
 * file: a binary PLY file's vertex records, a LAS file's point records or a
 * LAZ file's chunks are split evenly between the processes, each decodes
 * its own, and the parts are joined on process root (on every process when
 * root is TESSEL_MPI_ALL), whose cloud is then the one tessel_cloud_read
 * gives (points, order, offset, floats, normals, colours, points dropped);
 * the others' *cloud is left empty. Other formats (and PLY files with an
 * organized grid or records of varying size) are read by one process and
 * shared. On failure every process returns the status, with the message
 * of the first process that failed in *diag (may be NULL). */
#define TESSEL_MPI_ALL (-1)
TESSEL_API tessel_status tessel_mpi_cloud_read(MPI_Comm comm, int root, const char *path,
                                               const tessel_read_params *params,
                                               tessel_cloud *cloud, tessel_diag *diag);

/* tessel_reconstruct_greedy with the tiles (tessel_greedy_params.tile_points)
 * meshed by all processes of comm: process 0, which alone holds the cloud
 * (the others' may be empty: they receive the points of their tiles), sends
 * tile k to process k mod size, which meshes its tiles on params->threads
 * threads and sends them back, and the groups of each level of seams the
 * same way; process 0 then joins them (orientation check, flips) while the
 * others wait without spinning: on
 * params->threads (0: OpenMP's default) times the processes of comm on its
 * machine, at most the cores it may run on (omp_get_num_procs). Only
 * process 0's sink receives triangles and only its summary is filled; the
 * others may pass a sink that discards. A cloud of at most tile_points
 * points is one tile: process 0 meshes it alone. A failure on any process
 * (out of memory, a cancellation) is returned on every process. params must
 * be the same on every process. */
TESSEL_API tessel_status tessel_mpi_reconstruct_greedy(MPI_Comm comm, const tessel_cloud *cloud,
                                                       const tessel_greedy_params *params,
                                                       const tessel_callbacks *callbacks,
                                                       const tessel_triangle_sink *sink,
                                                       tessel_recon_summary *summary);

/* tessel_reconstruct_greedy_file (out of core, docs/outofcore.md) with each
 * slab's tiles meshed by all processes of comm as tessel_mpi_reconstruct_greedy
 * meshes a cloud's: process 0 reads in, sorts the points into slabs in its
 * scratch folder, sends each slab's tile k to process k mod size, joins the
 * tiles and the slabs, and writes out; the others hold only their tiles.
 * Every process passes the same arguments; only process 0 uses the paths,
 * and only its summary and diag are filled. out is the same bytes as
 * tessel_reconstruct_greedy_file's for any number of processes. A failure
 * on any process is returned on every process; no output or scratch file
 * is left. */
TESSEL_API tessel_status tessel_mpi_reconstruct_greedy_file(
    MPI_Comm comm, const char *in, const char *out, const tessel_read_params *read_params,
    const tessel_greedy_params *params, const tessel_write_params *write_params,
    const tessel_outofcore_params *op, const tessel_callbacks *callbacks,
    tessel_recon_summary *summary, tessel_diag *diag);

/* tessel_reconstruct_smooth with the tiles of its advancing front
 * (params->front.tile_points) run by all processes of comm: process 0, which
 * alone holds the cloud (the others' may be empty), runs the pipeline and
 * sends tile k's inputs to process k mod size, which runs the tile's front
 * on params->threads threads and sends its triangles back; the other stages
 * run on process 0 (with the threads of the processes beside it, as
 * tessel_mpi_reconstruct_greedy's last step). Only process 0's mesh and
 * stats are filled (the others' mesh is left empty). The same mesh as
 * tessel_reconstruct_smooth, bit for bit, for any number of processes. A
 * failure on any process is returned on every process. */
TESSEL_API tessel_status tessel_mpi_reconstruct_smooth(MPI_Comm comm, const tessel_cloud *cloud,
                                                       const tessel_smooth_recon_params *params,
                                                       const tessel_callbacks *callbacks,
                                                       tessel_mesh *mesh,
                                                       tessel_smooth_recon_stats *stats);

#ifdef __cplusplus
}
#endif

#endif
