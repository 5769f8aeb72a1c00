/* Private plumbing shared by the readers and writers in src/io/.
 *
 * Readers push raw double-precision points and polygons into a tsl_builder;
 * tsl_builder_finish_cloud/mesh then applies the rules common to every
 * format in one place: non-finite points dropped and counted (faces that use
 * them dropped too), organized grids mapped to the kept points, the double
 * offset chosen, coordinates stored as float.
 *
 * Writers write through a tsl_outfile (temporary file + rename) and are
 * split in three calls (begin / vertices / faces) so the in-memory writer and
 * the streaming writer share every format's code. */
#ifndef TESSEL_IO_INTERNAL_H
#define TESSEL_IO_INTERNAL_H

#include "../internal.h"

#include <stdio.h>

/* ---- reading ---- */

typedef struct tsl_builder {
    uint64_t max_points, max_faces;  /* from tessel_read_params */
    size_t count, cap;
    double *xyz;                     /* count*3 */
    float *normals;                  /* count*3 when has_normals */
    uint8_t *rgb;                    /* count*3 when has_rgb */
    int has_normals, has_rgb;
    size_t tri_count, tri_cap;
    uint32_t *tris;                  /* tri_count*3, indices into the pushed points */
    uint32_t width, height;          /* organized layout, 0 if none */
    double viewpoint[3];
    int has_viewpoint;
} tsl_builder;

void tsl_builder_init(tsl_builder *b, const tessel_read_params *params);
/* Declares which attributes follow (call before the first point). */
tessel_status tsl_builder_attributes(tsl_builder *b, int has_normals, int has_rgb);
/* Pre-sizes for points / triangles a header announced. Only call it once the
 * announced counts were checked against the bytes actually available, so a
 * lying header cannot trigger a huge allocation. Fails with
 * TESSEL_ERR_LIMIT above max_points / max_faces. */
tessel_status tsl_builder_reserve(tsl_builder *b, size_t points, size_t triangles);
/* Appends a point; normal and rgb are read only when declared (may be NULL
 * otherwise). Non-finite coordinates are accepted here and dropped at
 * finish. TESSEL_ERR_LIMIT past max_points. */
tessel_status tsl_builder_point(tsl_builder *b, const double xyz[3], const float *normal,
                                const uint8_t *rgb);
/* Appends a polygon of n >= 3 vertex indices as a fan of n-2 triangles.
 * Indices must already be validated (< point count) by the parser, which
 * knows where they came from. Polygons with fewer than 3 vertices are
 * ignored. TESSEL_ERR_LIMIT past max_faces. */
tessel_status tsl_builder_polygon(tsl_builder *b, const uint32_t *idx, size_t n);

/* Moves the result out (the builder is left empty). */
tessel_status tsl_builder_finish_cloud(tsl_builder *b, tessel_cloud *cloud);
tessel_status tsl_builder_finish_mesh(tsl_builder *b, tessel_mesh *mesh);
void tsl_builder_free(tsl_builder *b);

/* Chooses the offset for world coordinates with bounding box [lo, hi] per
 * axis: 0 when -4096 <= lo and hi < 4097 (floats keep ~0.5 mm there),
 * floor(lo) - 1 otherwise (local coordinates >= 1). Together with the
 * builder's rounding (never up across an integer) this is a fixed point:
 * writing offset + xyz as doubles and reading back gives the same floats
 * and offset (docs/formats.md). */
double tsl_choose_offset(double lo, double hi);

/* Per-format parsers. data/size is the whole file; name is for diagnostics.
 * want_faces: 0 skips face data quickly (cloud reads). */
typedef tessel_status (*tsl_parse_fn)(const uint8_t *data, size_t size, const char *name,
                                      int want_faces, tsl_builder *b, tessel_diag *diag);

tessel_status tsl_parse_ply(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag);
tessel_status tsl_parse_xyz(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag);
tessel_status tsl_parse_obj(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag);
tessel_status tsl_parse_off(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag);
tessel_status tsl_parse_pcd(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag);
tessel_status tsl_parse_las(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag);

/* Reads a whole file into memory (NUL-terminated for text parsers; *size
 * excludes the NUL). */
tessel_status tsl_read_file(const char *path, uint8_t **data, size_t *size,
                            tessel_diag *diag);

/* ---- text scanning helpers for the text formats ---- */

/* Parses a double at *p (strtod semantics, no locale surprises: '.' only),
 * stopping at end. Advances *p. Returns false when no number is there. */
bool tsl_scan_double(const char **p, const char *end, double *out);
/* Parses an unsigned decimal integer; false on none or overflow of uint64. */
bool tsl_scan_u64(const char **p, const char *end, uint64_t *out);
/* Parses a signed decimal integer; false on none or overflow of int64. */
bool tsl_scan_i64(const char **p, const char *end, int64_t *out);

/* ---- writing ---- */

/* A destination file written under a temporary name in the same folder and
 * renamed over `path` by commit. abort removes the temporary. */
typedef struct tsl_outfile {
    FILE *fp;
    char *path;
    char *tmp_path;
} tsl_outfile;

tessel_status tsl_outfile_open(tsl_outfile *out, const char *path, tessel_diag *diag);
/* Flushes, checks for write errors, closes and renames. On failure the
 * temporary is removed and diag names the path. */
tessel_status tsl_outfile_commit(tsl_outfile *out, tessel_diag *diag);
void tsl_outfile_abort(tsl_outfile *out);

/* What a writer writes: vertex arrays (world = offset + xyz). */
typedef struct tsl_vertices {
    size_t count;
    const float *xyz;
    const float *normals;   /* NULL: none written */
    const uint8_t *rgb;     /* NULL: none written */
    double offset[3];
} tsl_vertices;

/* A format writer in three steps, all writing to fp:
 *   begin(v, vertex_count, face_count)  header (counts known up front)
 *   vertices(v, subset, n)              n vertices: v's points subset[i], or
 *                                       the first n when subset is NULL
 *   faces(v, tris, orig, n)             n triangles; tris index the vertices
 *                                       in the order they were written;
 *                                       orig gives the same triangles in v's
 *                                       own numbering, for formats that
 *                                       store coordinates (STL).
 *   end()                               trailer, may be NULL
 * A NULL begin/vertices means the format stores no such section. Return
 * TESSEL_ERR_IO on write errors (checked with ferror by the caller too). */
typedef struct tsl_format_writer {
    tessel_format format;
    tessel_status (*begin)(FILE *fp, const tsl_vertices *v, size_t vertex_count,
                           size_t face_count, const tessel_write_params *params);
    tessel_status (*vertices)(FILE *fp, const tsl_vertices *v, const uint32_t *subset,
                              size_t n, const tessel_write_params *params);
    tessel_status (*faces)(FILE *fp, const tsl_vertices *v, const uint32_t *tris,
                           const uint32_t *orig, size_t n,
                           const tessel_write_params *params);
    tessel_status (*end)(FILE *fp, const tessel_write_params *params);
} tsl_format_writer;

extern const tsl_format_writer tsl_writer_ply;
extern const tsl_format_writer tsl_writer_xyz;   /* also CSV via params->format */
extern const tsl_format_writer tsl_writer_obj;
extern const tsl_format_writer tsl_writer_off;
extern const tsl_format_writer tsl_writer_stl;

/* A whole cloud as PLY, keeping what tsl_vertices cannot carry: an
 * organized cloud is written as all width*height cells in row order (NaN
 * coordinates for missing cells) with "comment organized W H", and the
 * viewpoint as "comment viewpoint X Y Z" (src/io/ply.c). */
tessel_status tsl_ply_write_cloud(FILE *fp, const tessel_cloud *cloud,
                                  const tessel_write_params *params);

/* Formats a world coordinate (offset + f) so that reading it back as a
 * double and applying tsl_choose_offset gives the same float and offset:
 * "%.9g" of the float when offset is 0, "%.17g" of the double sum else.
 * Returns the length written to buf (size >= 32). */
int tsl_format_coord(char *buf, double offset, float f);

#endif /* TESSEL_IO_INTERNAL_H */
