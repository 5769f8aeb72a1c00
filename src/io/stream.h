/* Chunked reading of a cloud file of any size, for out-of-core work
 * (src/io/stream.c). */
#ifndef TESSEL_IO_STREAM_H
#define TESSEL_IO_STREAM_H

#include "core/core.h"

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

#endif
