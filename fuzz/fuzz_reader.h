/* Body shared by the fuzz_<format>.c targets: parse the input as a cloud
 * and as a mesh with the format forced, then check the invariants every
 * reader promises (finite coordinates, indices in range). */
#ifndef TESSEL_FUZZ_READER_H
#define TESSEL_FUZZ_READER_H

#include "tessel.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void fuzz_check_cloud(const tessel_cloud *c)
{
    for (size_t i = 0; i < c->count * 3; i++)
        if (!isfinite(c->xyz[i]))
            abort();
    if (c->grid) {
        for (size_t i = 0; i < (size_t)c->width * c->height; i++)
            if (c->grid[i] != TESSEL_NONE && c->grid[i] >= c->count)
                abort();
    }
}

static void fuzz_check_mesh(const tessel_mesh *m)
{
    for (size_t i = 0; i < m->triangle_count * 3; i++)
        if (m->triangles[i] >= m->vertex_count)
            abort();
}

static int fuzz_reader(const uint8_t *data, size_t size, tessel_format format)
{
    tessel_read_params rp = tessel_read_params_default();
    rp.format = format;
    /* Small limits keep the fuzzer fast; the limits themselves are tested. */
    rp.max_points = 1u << 20;
    rp.max_faces = 1u << 20;
    tessel_diag diag;
    tessel_cloud cloud;
    if (tessel_cloud_parse(&cloud, data, size, "fuzz", &rp, &diag) == TESSEL_OK) {
        fuzz_check_cloud(&cloud);
        tessel_cloud_free(&cloud);
    }
    tessel_mesh mesh;
    if (tessel_mesh_parse(&mesh, data, size, "fuzz", &rp, &diag) == TESSEL_OK) {
        fuzz_check_mesh(&mesh);
        tessel_mesh_free(&mesh);
    }
    return 0;
}

#endif
