/* Chunked reading of a cloud file of any size, for out-of-core work
 * (src/io/stream.c). */
#ifndef TESSEL_IO_STREAM_H
#define TESSEL_IO_STREAM_H

#include "core/core.h"
#include "io/io.h"

/* Receives count points: xyz (3*count world coordinates), normals (3*count)
 * and rgb (3*count) or NULL when the file has none. Valid during the call
 * only. A status other than TESSEL_OK stops the read. */
typedef tessel_status (*tsl_chunk_fn)(void *user, const double *xyz, const float *normals,
                                      const uint8_t *rgb, size_t count);

typedef struct tsl_stream_info {
    int has_normals, has_rgb;
    uint64_t points;   /* finite points delivered */
    uint64_t dropped;  /* points with a non-finite coordinate, not delivered */
} tsl_stream_info;

/* Reads the cloud at path (params as tessel_cloud_read's, NULL: defaults:
 * format, max_points, the LAS/LAZ box) and hands its finite points to fn in
 * file order, in chunks of at most chunk_points (> 0; a chunk is shorter
 * by the non-finite points it had, and chunks left empty are skipped), in
 * double world coordinates: the points tessel_cloud_read gives, before its
 * float conversion. A status other than TESSEL_OK from fn stops the read
 * and is returned (how a caller cancels). On an error fn may have had the
 * chunks before it; diag names the file and the place as
 * tessel_cloud_read's does. Memory: O(chunk_points) for regular files (and
 * one LASzip chunk for LAZ), O(file) for pipes. Organized grids,
 * viewpoints and faces are not read. The file must not be truncated while
 * it is read (it is mapped). */
tessel_status tsl_cloud_stream(const char *path, const tessel_read_params *params,
                               size_t chunk_points, tsl_chunk_fn fn, void *user,
                               tsl_stream_info *info, tessel_diag *diag);

/* Whether any part's flag is set: every part of a read in parts calls it
 * once, in step with the others (MPI_Allreduce in src/mpi/), or none does. */
typedef int (*tsl_any_fn)(void *ctx, int mine);

/* Part `part` of `parts` of the cloud at path, for readers that run side by
 * side, each on its part: the records n * part / parts up to
 * n * (part + 1) / parts of a binary PLY file's vertices or a LAS file's
 * points, or for LAZ the LASzip chunks whose first point falls there (all
 * parts together read every record once, in file order). b (initialised
 * here, freed by the caller in any case) receives the part's finite points
 * in world coordinates, its non-finite ones counted in b->dropped. The
 * checks and messages are tessel_cloud_read's (the header's on every part);
 * a LAS or LAZ file with colours calls any once for the 16-bit shift, which
 * the whole file decides. *whole: the file cannot be read in parts (another
 * format, ascii PLY, an organized grid, ...): nothing is read, the caller
 * reads it whole. A part's limit (params->max_points) applies to the part
 * alone: the caller checks the sum. */
tessel_status tsl_cloud_read_part(const char *path, const tessel_read_params *params,
                                  size_t part, size_t parts, tsl_any_fn any, void *ctx,
                                  tsl_builder *b, bool *whole, tessel_diag *diag);
/* The same from the file's bytes in memory (name for messages). */
tessel_status tsl_cloud_parse_part(const uint8_t *data, size_t size, const char *name,
                                   const tessel_read_params *params, size_t part, size_t parts,
                                   tsl_any_fn any, void *ctx, tsl_builder *b, bool *whole,
                                   tessel_diag *diag);

#endif
