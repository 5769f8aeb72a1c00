/* Chunked reading of a cloud file (src/io/stream.c). */
#ifndef TESSEL_IO_STREAM_H
#define TESSEL_IO_STREAM_H

#include "core/core.h"

typedef tessel_status (*tsl_chunk_fn)(void *user, const double *xyz, const float *normals,
                                      const uint8_t *rgb, size_t count);
typedef struct tsl_stream_info {
    int has_normals, has_rgb;
    uint64_t points;
    uint64_t dropped;
} tsl_stream_info;
tessel_status tsl_cloud_stream(const char *path, const tessel_read_params *params,
                               size_t chunk_points, tsl_chunk_fn fn, void *user,
                               tsl_stream_info *info, tessel_diag *diag);
#endif
