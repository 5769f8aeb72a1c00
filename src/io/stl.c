/* Binary STL writer (3D Systems, "StereoLithography Interface
 * Specification", 1989): an 80-byte header, a little-endian uint32 triangle
 * count, then per triangle a facet normal and three vertices as 12 float32
 * and a uint16 attribute (0).
 *
 * STL has no shared vertices: each facet carries its own world coordinates
 * (offset + xyz, rounded to float - georeferenced meshes lose precision
 * there, which is why PLY or OBJ are preferred for them). The normal is the
 * unit right-hand normal of the facet, computed in double in the local frame;
 * degenerate facets get a zero normal, as readers expect. There is no STL
 * reader: STL is a triangle soup, so meshes should come in as PLY/OBJ/OFF. */
#include "io/io.h"

#include <string.h>

static void put_f32(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    p[0] = (uint8_t)u;
    p[1] = (uint8_t)(u >> 8);
    p[2] = (uint8_t)(u >> 16);
    p[3] = (uint8_t)(u >> 24);
}

static tessel_status stl_begin(FILE *fp, const tsl_vertices *v, size_t vertex_count,
                               size_t face_count, const tessel_write_params *params)
{
    (void)v;
    (void)vertex_count;
    (void)params;
    if ((uint64_t)face_count > UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    /* The header must not start with "solid": readers would take the file
     * for ASCII STL. */
    uint8_t head[84];
    memset(head, ' ', 80);
    static const char text[] = "binary STL written by tessel " TESSEL_VERSION_STRING;
    memcpy(head, text, sizeof text - 1);
    uint32_t n = (uint32_t)face_count;
    for (int k = 0; k < 4; k++)
        head[80 + k] = (uint8_t)(n >> (8 * k));
    if (fwrite(head, 1, sizeof head, fp) != sizeof head)
        return TESSEL_ERR_IO;
    return TESSEL_OK;
}

static tessel_status stl_faces(FILE *fp, const tsl_vertices *v, const uint32_t *tris,
                               const uint32_t *orig, size_t n,
                               const tessel_write_params *params)
{
    (void)tris;
    (void)params;
    uint8_t rec[50];
    for (size_t t = 0; t < n; t++) {
        double p[3][3];
        for (int c = 0; c < 3; c++)
            tsl_load(v->xyz + 3 * (size_t)orig[3 * t + c], p[c]);
        double e1[3], e2[3], nrm[3];
        tsl_sub(p[1], p[0], e1);
        tsl_sub(p[2], p[0], e2);
        tsl_cross(e1, e2, nrm);
        if (!tsl_normalize(nrm))
            nrm[0] = nrm[1] = nrm[2] = 0.0;
        for (int k = 0; k < 3; k++)
            put_f32(rec + 4 * k, (float)nrm[k]);
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                put_f32(rec + 12 + 12 * c + 4 * k, (float)(v->offset[k] + p[c][k]));
        rec[48] = rec[49] = 0;
        if (fwrite(rec, 1, sizeof rec, fp) != sizeof rec)
            return TESSEL_ERR_IO;
    }
    return TESSEL_OK;
}

const tsl_format_writer tsl_writer_stl = {TESSEL_FORMAT_STL, stl_begin, NULL, stl_faces,
                                          NULL};
