#include "io/stream.h"
#include <stdlib.h>
#include <string.h>
tessel_status tsl_cloud_stream(const char *path, const tessel_read_params *params,
                               size_t chunk_points, tsl_chunk_fn fn, void *user,
                               tsl_stream_info *info, tessel_diag *diag)
{
    tessel_cloud c;
    tessel_status st = tessel_cloud_read(&c, path, params, diag);
    if (st) return st;
    memset(info, 0, sizeof *info);
    info->has_normals = c.normals != NULL; info->has_rgb = c.rgb != NULL; info->points = c.count;
    double *x = malloc(3 * chunk_points * sizeof *x);
    for (size_t i = 0; i < c.count && !st; i += chunk_points) {
        size_t m = c.count - i < chunk_points ? c.count - i : chunk_points;
        for (size_t j = 0; j < 3 * m; j++) x[j] = c.offset[j % 3] + (double)c.xyz[3 * i + j];
        st = fn(user, x, c.normals ? c.normals + 3 * i : NULL, c.rgb ? c.rgb + 3 * i : NULL, m);
    }
    free(x);
    tessel_cloud_free(&c);
    return st;
}
