/* libFuzzer target for reading in parts (src/io/stream.c
 * tsl_cloud_parse_part, what tessel-mpi's processes run): the input is read
 * as PLY and as LAS/LAZ whole and in 1, 2 and 3 parts. When the whole read
 * succeeds every part must, and the parts joined (offset from the joined
 * points, floats as the builder stores them) must be the whole read's
 * cloud bit for bit; when it fails some part must fail (or the joined count
 * exceed the limit). A file that cannot be read in parts must say so. */
#include "io/io.h"
#include "io/stream.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The colour flag: the first round collects every part's, the second
 * answers with their OR, as MPI_Allreduce would. */
typedef struct flags {
    int any, round;
} flags;

static int any_flag(void *ctx, int mine)
{
    flags *f = ctx;
    if (f->round == 0)
        f->any |= mine;
    return f->round == 0 ? mine : f->any;
}

/* The parts of b[0 .. parts) joined into one cloud as join_parts does. */
static int joined_equals(tsl_builder *b, size_t parts, const tessel_cloud *c, uint64_t limit)
{
    size_t n = 0, dropped = 0;
    for (size_t p = 0; p < parts; p++) {
        n += b[p].count;
        dropped += b[p].dropped;
    }
    if (n > limit)
        return -1; /* the join fails */
    if (n != c->count || dropped != c->dropped_nonfinite)
        return 0;
    double *xyz = malloc(3 * n * sizeof *xyz + 1);
    if (!xyz)
        return 1;
    for (size_t p = 0, at = 0; p < parts; at += b[p].count, p++)
        if (b[p].count)
            memcpy(xyz + 3 * at, b[p].xyz, 3 * b[p].count * sizeof *xyz);
    double offset[3];
    int same = tsl_choose_offset(xyz, n, offset) == TESSEL_OK &&
               memcmp(offset, c->offset, sizeof offset) == 0;
    for (size_t i = 0; same && i < 3 * n; i++) {
        float f = tsl_local_coord(xyz[i], offset[i % 3]);
        same = memcmp(&f, &c->xyz[i], sizeof f) == 0;
    }
    free(xyz);
    for (size_t p = 0, at = 0; same && p < parts; at += b[p].count, p++) {
        if (c->normals && b[p].count)
            same = b[p].has_normals && memcmp(c->normals + 3 * at, b[p].normals,
                                              3 * b[p].count * sizeof *c->normals) == 0;
        if (same && c->rgb && b[p].count)
            same = b[p].has_rgb && memcmp(c->rgb + 3 * at, b[p].rgb, 3 * b[p].count) == 0;
        if (same && b[p].count)
            same = !b[p].has_normals == !c->normals && !b[p].has_rgb == !c->rgb;
    }
    return same;
}

static void check(const uint8_t *data, size_t size, tessel_format format, size_t parts)
{
    tessel_read_params rp = tessel_read_params_default();
    rp.format = format;
    rp.max_points = 1u << 20;
    rp.max_faces = 1u << 20;
    tessel_diag diag;
    tessel_cloud whole;
    tessel_status sw = tessel_cloud_parse(&whole, data, size, "fuzz", &rp, &diag);
    tsl_builder b[3];
    flags f = {0, 0};
    int failed = 0, in_parts = 1;
    for (f.round = 0; f.round < 2; f.round++) {
        failed = 0;
        for (size_t p = 0; p < parts; p++) {
            bool whole_only = false;
            tessel_status st = tsl_cloud_parse_part(data, size, "fuzz", &rp, p, parts, any_flag,
                                                    &f, &b[p], &whole_only, &diag);
            failed |= st != TESSEL_OK;
            in_parts &= !whole_only;
            if (f.round == 0)
                tsl_builder_free(&b[p]);
        }
    }
    if (in_parts && sw == TESSEL_OK && failed)
        abort(); /* a part failed where the whole read did not */
    if (in_parts && sw == TESSEL_OK) {
        int same = joined_equals(b, parts, &whole, rp.max_points);
        if (same == 0)
            abort(); /* the parts do not give the whole read's cloud */
    }
    if (in_parts && sw != TESSEL_OK && !failed && joined_equals(b, parts, &whole, rp.max_points) != -1)
        abort(); /* the whole read failed, the parts did not */
    for (size_t p = 0; p < parts; p++)
        tsl_builder_free(&b[p]);
    if (sw == TESSEL_OK)
        tessel_cloud_free(&whole);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    for (size_t parts = 1; parts <= 3; parts++) {
        check(data, size, TESSEL_FORMAT_PLY, parts);
        check(data, size, TESSEL_FORMAT_LAS, parts);
    }
    return 0;
}
