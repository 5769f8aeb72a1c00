/* The reader back end shared by every format: parsers push raw
 * double-precision points and polygons, and finishing applies, once for all
 * formats, the rules of docs/formats.md:
 *  - points with a NaN or infinite coordinate are dropped and counted
 *    (faces using one are dropped too, the others are renumbered);
 *  - organized clouds (width*height set by the parser) get a grid that maps
 *    every cell to its kept point or TESSEL_NONE;
 *  - the per-axis double offset is chosen by tsl_choose_offset from the
 *    median of an even sample of the finite points (so a few stray points
 *    far from the bulk cannot push the bulk's local coordinates out to where
 *    floats are coarse), and xyz is stored as tsl_local_coord(world,
 *    offset), rounded so that a round trip through a writer gives back the
 *    very same floats and offset.
 * Storage grows geometrically; the double array is converted to floats in
 * place, so finishing needs no second copy of the points. */
#include "io/io.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A median in [-4096, 4097) keeps offset 0: floats resolve ~0.5 mm up to
 * 4096, and ordinary data stays untouched. */
#define OFFSET_LIMIT 4096.0
/* Points the median is taken over: index-strided, so choosing the offset
 * costs the same on 10^7 points as on 10^4. */
#define OFFSET_SAMPLE 8192

void tsl_builder_init(tsl_builder *b, const tessel_read_params *params)
{
    memset(b, 0, sizeof *b);
    tessel_read_params def = tessel_read_params_default();
    if (!params)
        params = &def;
    b->max_points = params->max_points;
    b->max_faces = params->max_faces;
    /* Indices are uint32 and TESSEL_NONE is reserved. */
    if (b->max_points > (uint64_t)UINT32_MAX - 1)
        b->max_points = (uint64_t)UINT32_MAX - 1;
}

void tsl_builder_free(tsl_builder *b)
{
    if (!b)
        return;
    free(b->xyz);
    free(b->normals);
    free(b->rgb);
    free(b->tris);
    uint64_t mp = b->max_points, mf = b->max_faces;
    memset(b, 0, sizeof *b);
    b->max_points = mp;
    b->max_faces = mf;
}

/* Resizes every point array to new_cap points. */
static tessel_status resize_points(tsl_builder *b, size_t new_cap)
{
    /* tsl_resize: a 10^6-point cloud's arrays get huge pages, which saves
     * a quarter of a whole run's page faults. */
    size_t bytes, old = b->cap;
    tessel_status st;
    if (!tsl_mul_size(new_cap, 3 * sizeof(double), &bytes))
        return TESSEL_ERR_NOMEM;
    if ((st = tsl_resize((void **)&b->xyz, old * 3 * sizeof(double), bytes)))
        return st;
    if (b->has_normals && (st = tsl_resize((void **)&b->normals, old * 3 * sizeof(float),
                                           new_cap * 3 * sizeof(float) + 1)))
        return st;
    if (b->has_rgb && (st = tsl_resize((void **)&b->rgb, old * 3, new_cap * 3 + 1)))
        return st;
    b->cap = new_cap;
    return TESSEL_OK;
}

tessel_status tsl_builder_attributes(tsl_builder *b, int has_normals, int has_rgb)
{
    /* Declared late (after points): earlier points get zero attributes. */
    if (has_normals && !b->has_normals) {
        float *n = tsl_calloc_array(b->cap ? b->cap : 1, 3 * sizeof(float));
        if (!n)
            return TESSEL_ERR_NOMEM;
        b->normals = n;
        b->has_normals = 1;
    }
    if (has_rgb && !b->has_rgb) {
        uint8_t *c = tsl_calloc_array(b->cap ? b->cap : 1, 3);
        if (!c)
            return TESSEL_ERR_NOMEM;
        b->rgb = c;
        b->has_rgb = 1;
    }
    if (!has_normals && b->has_normals && b->count == 0) {
        free(b->normals);
        b->normals = NULL;
        b->has_normals = 0;
    }
    if (!has_rgb && b->has_rgb && b->count == 0) {
        free(b->rgb);
        b->rgb = NULL;
        b->has_rgb = 0;
    }
    return TESSEL_OK;
}

tessel_status tsl_builder_reserve(tsl_builder *b, size_t points, size_t triangles)
{
    if ((uint64_t)points > b->max_points || (uint64_t)triangles > b->max_faces)
        return TESSEL_ERR_LIMIT;
    if (b->flush) {
        /* A chunk at most, and faces are not kept. */
        points = points < b->chunk ? points : b->chunk;
        triangles = 0;
    }
    if (points > b->cap) {
        tessel_status st = resize_points(b, points);
        if (st != TESSEL_OK)
            return st;
    }
    if (triangles > b->tri_cap) {
        size_t bytes;
        if (!tsl_mul_size(triangles, 3 * sizeof(uint32_t), &bytes))
            return TESSEL_ERR_NOMEM;
        tessel_status st = tsl_resize((void **)&b->tris, b->tri_cap * 3 * sizeof(uint32_t), bytes);
        if (st != TESSEL_OK)
            return st;
        b->tri_cap = triangles;
    }
    return TESSEL_OK;
}

/* Room for one more point: the arrays grown, or in sink mode the full
 * chunk flushed. */
static tessel_status make_room(tsl_builder *b)
{
    /* In sink mode the arrays hold a chunk, not all points so far. */
    if (tsl_builder_pushed(b) >= b->max_points)
        return TESSEL_ERR_LIMIT;
    if (b->count < b->cap)
        return TESSEL_OK;
    if (tsl_builder_full(b))
        return tsl_builder_flush(b);
    size_t new_cap = b->cap < 1024 ? 1024 : b->cap + b->cap / 2;
    if ((uint64_t)new_cap > b->max_points)
        new_cap = (size_t)b->max_points;
    if (b->flush && new_cap > b->chunk)
        new_cap = b->chunk;
    return resize_points(b, new_cap);
}

tessel_status tsl_builder_point(tsl_builder *b, const double xyz[3], const float *normal,
                                const uint8_t *rgb)
{
    if (b->count == b->cap || b->flush) {
        tessel_status st = make_room(b);
        if (st != TESSEL_OK)
            return st;
    }
    size_t i = b->count;
    memcpy(b->xyz + 3 * i, xyz, 3 * sizeof(double));
    if (b->has_normals) {
        if (normal)
            memcpy(b->normals + 3 * i, normal, 3 * sizeof(float));
        else
            memset(b->normals + 3 * i, 0, 3 * sizeof(float));
    }
    if (b->has_rgb) {
        if (rgb)
            memcpy(b->rgb + 3 * i, rgb, 3);
        else
            memset(b->rgb + 3 * i, 0, 3);
    }
    b->count++;
    return TESSEL_OK;
}

tessel_status tsl_builder_polygon(tsl_builder *b, const uint32_t *idx, size_t n)
{
    if (n < 3 || b->flush)
        return TESSEL_OK;
    size_t add = n - 2;
    if ((uint64_t)b->tri_count + add > b->max_faces)
        return TESSEL_ERR_LIMIT;
    size_t need = b->tri_count + add;
    if (need > b->tri_cap) {
        size_t new_cap = b->tri_cap < 1024 ? 1024 : b->tri_cap + b->tri_cap / 2;
        if (new_cap < need)
            new_cap = need;
        if ((uint64_t)new_cap > b->max_faces)
            new_cap = (size_t)b->max_faces;
        size_t bytes;
        if (!tsl_mul_size(new_cap, 3 * sizeof(uint32_t), &bytes))
            return TESSEL_ERR_NOMEM;
        tessel_status st = tsl_resize((void **)&b->tris, b->tri_cap * 3 * sizeof(uint32_t), bytes);
        if (st != TESSEL_OK)
            return st;
        b->tri_cap = new_cap;
    }
    uint32_t *t = b->tris + 3 * b->tri_count;
    for (size_t k = 1; k + 1 < n; k++) {
        t[0] = idx[0];
        t[1] = idx[k];
        t[2] = idx[k + 1];
        t += 3;
    }
    b->tri_count = need;
    return TESSEL_OK;
}

static int cmp_double(const void *pa, const void *pb)
{
    double a = *(const double *)pa, b = *(const double *)pb;
    return (a > b) - (a < b);
}

size_t tsl_offset_samples(size_t count)
{
    return count < OFFSET_SAMPLE ? count : OFFSET_SAMPLE;
}

tessel_status tsl_offset_of_samples(const double *sample, size_t m, double offset[3])
{
    offset[0] = offset[1] = offset[2] = 0.0;
    if (m == 0)
        return TESSEL_OK;
    double *v = tsl_alloc_array(m, sizeof(double));
    if (!v)
        return TESSEL_ERR_NOMEM;
    for (int a = 0; a < 3; a++) {
        for (size_t j = 0; j < m; j++)
            v[j] = sample[3 * j + (size_t)a];
        /* The lower median: an actual sample value, so its floor is one of
         * the sampled points' floors (what makes the rule round-trip). */
        qsort(v, m, sizeof *v, cmp_double);
        double c = floor(v[(m - 1) / 2]);
        if (c < -OFFSET_LIMIT || c > OFFSET_LIMIT)
            offset[a] = c;
    }
    free(v);
    return TESSEL_OK;
}

tessel_status tsl_choose_offset(const double *xyz, size_t count, double offset[3])
{
    offset[0] = offset[1] = offset[2] = 0.0;
    size_t m = tsl_offset_samples(count);
    double *sample = tsl_alloc_array(m + 1, 3 * sizeof(double));
    if (!sample)
        return TESSEL_ERR_NOMEM;
    for (size_t j = 0; j < m; j++)
        memcpy(sample + 3 * j, xyz + 3 * tsl_offset_sample_at(j, count, m), 3 * sizeof(double));
    tessel_status st = tsl_offset_of_samples(sample, m, offset);
    free(sample);
    return st;
}

/* Coordinates beyond this magnitude are treated like NaN: no real survey is
 * that large (the Earth's radius is 6.4e6 m), and keeping them would make
 * world - offset overflow the float storage (a hostile LAS scale can produce
 * 1e300). */
#define TSL_MAX_COORD 1e15

static bool point_finite(const double *p)
{
    return fabs(p[0]) <= TSL_MAX_COORD && fabs(p[1]) <= TSL_MAX_COORD &&
           fabs(p[2]) <= TSL_MAX_COORD;
}

tessel_status tessel_world_to_local(const double *world, size_t count, float *xyz,
                                   double offset[3])
{
    if (!offset || (count && (!world || !xyz)))
        return TESSEL_ERR_INVALID_ARG;
    for (size_t i = 0; i < count; i++)
        if (!point_finite(world + 3 * i))
            return TESSEL_ERR_INVALID_ARG;
    double off[3];
    tessel_status st = tsl_choose_offset(world, count, off);
    if (st != TESSEL_OK)
        return st;
    for (size_t j = 0; j < 3 * count; j++)
        xyz[j] = tsl_local_coord(world[j], off[j % 3]);
    memcpy(offset, off, sizeof off);
    return TESSEL_OK;
}

/* Drops non-finite points, compacting all arrays; fills remap (old index
 * -> new or TESSEL_NONE) when given. Returns the points kept. */
static size_t keep_finite(tsl_builder *b, uint32_t *remap)
{
    size_t kept = 0;
    for (size_t i = 0; i < b->count; i++) {
        const double *p = b->xyz + 3 * i;
        if (!point_finite(p)) {
            if (remap)
                remap[i] = TESSEL_NONE;
            continue;
        }
        if (remap)
            remap[i] = (uint32_t)kept;
        if (kept != i) {
            memmove(b->xyz + 3 * kept, p, 3 * sizeof(double));
            if (b->has_normals)
                memmove(b->normals + 3 * kept, b->normals + 3 * i, 3 * sizeof(float));
            if (b->has_rgb)
                memmove(b->rgb + 3 * kept, b->rgb + 3 * i, 3);
        }
        kept++;
    }
    return kept;
}

/* Drops non-finite points (keep_finite), chooses the offset and converts
 * xyz to floats in place (b->xyz then holds count*3 floats). On failure
 * (no memory for the offset's sample) the points are compacted but still
 * doubles. */
static tessel_status compact_points(tsl_builder *b, uint32_t *remap, double offset[3],
                                    size_t *dropped)
{
    size_t kept = keep_finite(b, remap);
    *dropped = b->count - kept;
    b->count = kept;
    tessel_status st = tsl_choose_offset(b->xyz, kept, offset);
    if (st != TESSEL_OK)
        return st;
    /* In place: float j lands at byte 4j, below double j's byte 8j, which
     * has been read already. memcpy keeps it free of aliasing trouble. */
    unsigned char *mem = (unsigned char *)b->xyz;
    for (size_t i = 0; i < kept; i++) {
        for (int a = 0; a < 3; a++) {
            size_t j = 3 * i + (size_t)a;
            double w;
            memcpy(&w, mem + 8 * j, sizeof w);
            float f = tsl_local_coord(w, offset[a]);
            memcpy(mem + 4 * j, &f, sizeof f);
        }
    }
    return TESSEL_OK;
}

void tsl_builder_sink(tsl_builder *b, size_t chunk, tsl_flush_fn fn, void *user)
{
    b->flush = fn;
    b->flush_user = user;
    b->chunk = chunk ? chunk : 1;
}

tessel_status tsl_builder_flush(tsl_builder *b)
{
    if (!b->flush)
        return TESSEL_OK;
    /* The same rule finishing applies: a chunk holds finite points only. */
    size_t pushed = b->count, kept = keep_finite(b, NULL);
    b->dropped += pushed - kept;
    b->count = kept;
    tessel_status st = b->flush(b->flush_user, b);
    b->flushed += pushed;
    b->count = 0;
    return st;
}

size_t tsl_builder_keep_finite(tsl_builder *b)
{
    size_t pushed = b->count;
    b->count = keep_finite(b, NULL);
    return pushed - b->count;
}

/* Shrinks the arrays to count points; failures to shrink are harmless. */
static void shrink(void **p, size_t bytes)
{
    void *q = realloc(*p, bytes ? bytes : 1);
    if (q)
        *p = q;
}

tessel_status tsl_builder_finish_cloud(tsl_builder *b, tessel_cloud *cloud)
{
    memset(cloud, 0, sizeof *cloud);
    uint32_t *grid = NULL;
    size_t cells = (size_t)b->width * b->height;
    if (b->width && b->height) {
        if (cells != b->count)
            return TESSEL_ERR_PARSE; /* parsers check this with a message */
        grid = tsl_alloc_array(cells, sizeof(uint32_t));
        if (!grid)
            return TESSEL_ERR_NOMEM;
    }
    size_t dropped = 0;
    tessel_status st = compact_points(b, grid, cloud->offset, &dropped);
    if (st != TESSEL_OK) {
        free(grid);
        return st;
    }
    size_t n = b->count;
    shrink((void **)&b->xyz, n * 3 * sizeof(float));
    cloud->xyz = (float *)(void *)b->xyz;
    if (b->has_normals) {
        shrink((void **)&b->normals, n * 3 * sizeof(float));
        cloud->normals = b->normals;
    }
    if (b->has_rgb) {
        shrink((void **)&b->rgb, n * 3);
        cloud->rgb = b->rgb;
    }
    cloud->count = n;
    cloud->dropped_nonfinite = dropped;
    if (grid) {
        cloud->grid = grid;
        cloud->width = b->width;
        cloud->height = b->height;
    }
    if (b->has_viewpoint) {
        memcpy(cloud->viewpoint, b->viewpoint, sizeof cloud->viewpoint);
        cloud->has_viewpoint = 1;
    }
    b->xyz = NULL;
    b->normals = NULL;
    b->rgb = NULL;
    tsl_builder_free(b);
    return TESSEL_OK;
}

tessel_status tsl_builder_finish_mesh(tsl_builder *b, tessel_mesh *mesh)
{
    memset(mesh, 0, sizeof *mesh);
    size_t original = b->count;
    for (size_t t = 0; t < 3 * b->tri_count; t++)
        if (b->tris[t] >= original)
            return TESSEL_ERR_INTERNAL; /* parsers validate indices */
    uint32_t *remap = NULL;
    bool any_nonfinite = false;
    for (size_t i = 0; i < original && !any_nonfinite; i++)
        any_nonfinite = !point_finite(b->xyz + 3 * i);
    if (any_nonfinite && b->tri_count) {
        remap = tsl_alloc_array(original, sizeof(uint32_t));
        if (!remap)
            return TESSEL_ERR_NOMEM;
    }
    size_t dropped = 0;
    tessel_status st = compact_points(b, remap, mesh->offset, &dropped);
    if (st != TESSEL_OK) {
        free(remap);
        return st;
    }
    size_t tris = b->tri_count;
    if (remap) {
        size_t kept = 0;
        for (size_t t = 0; t < b->tri_count; t++) {
            uint32_t a = remap[b->tris[3 * t]], c = remap[b->tris[3 * t + 1]],
                     d = remap[b->tris[3 * t + 2]];
            if (a == TESSEL_NONE || c == TESSEL_NONE || d == TESSEL_NONE)
                continue;
            b->tris[3 * kept] = a;
            b->tris[3 * kept + 1] = c;
            b->tris[3 * kept + 2] = d;
            kept++;
        }
        tris = kept;
        free(remap);
    }
    size_t n = b->count;
    shrink((void **)&b->xyz, n * 3 * sizeof(float));
    mesh->xyz = (float *)(void *)b->xyz;
    if (b->has_normals) {
        shrink((void **)&b->normals, n * 3 * sizeof(float));
        mesh->normals = b->normals;
    }
    if (b->has_rgb) {
        shrink((void **)&b->rgb, n * 3);
        mesh->rgb = b->rgb;
    }
    if (b->tris)
        shrink((void **)&b->tris, tris * 3 * sizeof(uint32_t));
    mesh->triangles = b->tris;
    mesh->vertex_count = n;
    mesh->triangle_count = tris;
    b->xyz = NULL;
    b->normals = NULL;
    b->rgb = NULL;
    b->tris = NULL;
    tsl_builder_free(b);
    return TESSEL_OK;
}
