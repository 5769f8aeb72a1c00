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

#include "core/core.h"
#include "io/outfile.h"

#include <stdio.h>

/* ---- reading ---- */

typedef struct tsl_builder tsl_builder;
/* Sink mode: receives b->count finite points (b->xyz, and b->normals /
 * b->rgb when declared); a status other than TESSEL_OK stops the parse. */
typedef tessel_status (*tsl_flush_fn)(void *user, const tsl_builder *b);

struct tsl_builder {
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
    const double *bbox;              /* LAS/LAZ: keep points in it (tessel_read_params.bbox) */
    /* Sink mode (tsl_builder_sink), for streaming: every chunk points go
     * to flush instead of piling up, so memory stays O(chunk). */
    tsl_flush_fn flush;              /* NULL: collect everything */
    void *flush_user;
    size_t chunk;                    /* points per flush */
    uint64_t flushed;                /* points pushed before the current ones */
    uint64_t dropped;                /* non-finite points not flushed */
};

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

/* Drops the non-finite points pushed so far (finishing's rule), compacting
 * the arrays; returns how many. */
size_t tsl_builder_keep_finite(tsl_builder *b);

/* Switches b to sink mode: from now on tsl_builder_point hands every chunk
 * (>= 1) points to fn, non-finite ones dropped and counted in b->dropped,
 * and reuses the arrays; tsl_builder_reserve never sizes beyond chunk.
 * Grids, viewpoints and faces are not collected. */
void tsl_builder_sink(tsl_builder *b, size_t chunk, tsl_flush_fn fn, void *user);
/* Sink mode: hands the points pushed since the last flush (maybe none) to
 * the sink; the end of a parse calls it for the last, short chunk. No-op
 * otherwise. */
tessel_status tsl_builder_flush(tsl_builder *b);
/* Points pushed so far, flushed or not: what a parser numbers by. */
static inline uint64_t tsl_builder_pushed(const tsl_builder *b)
{
    return b->flushed + b->count;
}
/* Sink mode: the next point flushes the chunk held now. */
static inline bool tsl_builder_full(const tsl_builder *b)
{
    return b->flush && b->count == b->cap && b->cap >= b->chunk;
}

/* Moves the result out (the builder is left empty). */
tessel_status tsl_builder_finish_cloud(tsl_builder *b, tessel_cloud *cloud);
tessel_status tsl_builder_finish_mesh(tsl_builder *b, tessel_mesh *mesh);
void tsl_builder_free(tsl_builder *b);

/* Chooses the per-axis offset for count finite points (xyz: count*3
 * doubles, world coordinates): with c = floor of the lower median of an
 * index-strided sample of at most 8192 points (the points j*count/m, j < m),
 * the offset is 0 when -4096 <= c <= 4096, c otherwise. The median follows
 * the bulk, not the extremes: stray points (a scanner's origin under UTM
 * data) cannot push the bulk's local coordinates out to where floats are
 * coarse, and it minimises the mean |local coordinate|. The rule looks only
 * at the floor of one sampled point, whose local coordinate lies in [0, 1)
 * or in [-4096, 4097); tsl_local_coord keeps that floor, and is monotone,
 * so writing offset + xyz and reading back gives the same offset and floats
 * (docs/formats.md). TESSEL_ERR_NOMEM when the sample cannot be allocated;
 * offset is then all 0. */
tessel_status tsl_choose_offset(const double *xyz, size_t count, double offset[3]);
/* The points the rule samples, for a reader that holds the cloud in parts
 * (src/mpi/): m = tsl_offset_samples(count) of them, the j-th at index
 * tsl_offset_sample_at(j, count, m); tsl_offset_of_samples gives the offset
 * from their 3*m coordinates in that order. */
size_t tsl_offset_samples(size_t count);
static inline size_t tsl_offset_sample_at(size_t j, size_t count, size_t m)
{
    return (size_t)((uint64_t)j * count / m);
}
tessel_status tsl_offset_of_samples(const double *sample, size_t m, double offset[3]);

/* The stored float for a world coordinate and an integer offset
 * (|world| <= 1e15, |offset| <= 1e15): float(t), t = world - offset taken
 * exactly (d + e, Knuth's TwoSum), rounded to nearest (0 as +0) except
 *  - |t| < 2^24: never up across an integer (the float below is taken), so
 *    floor(offset + f) == floor(world);
 *  - |t| >= 2^24 (floats are integers there): toward zero, so offset + f
 *    lies between offset and world and stays within the 1e15 readers keep.
 * f is nondecreasing in world, offset + f is exact in double, and
 * tsl_local_coord(offset + f, offset) == f: a written and re-read
 * coordinate comes back as the same float. Shared by the builder and the
 * text formatter, which must round alike. */
static inline float tsl_local_coord(double world, double offset)
{
    double d = world - offset;
    if (d == 0.0)
        return 0.0f; /* never -0.0f: offset + -0.0f reads back as +0.0f */
    float f = (float)d;
    double fd = (double)f;
    /* No double lies strictly between t and d, so comparing f with t is
     * comparing with d, and on a tie looking at the sign of e. */
    double e = 0.0;
    if (fd == d) {
        double bb = d - world;
        e = (world - (d - bb)) + (-offset - bb);
        if (e == 0.0)
            return f; /* t is this float */
    }
    bool above = fd > d || (fd == d && e < 0);
    if (fabs(d) < 16777216.0 || (d == 16777216.0 && e < 0) || (d == -16777216.0 && e > 0)) {
        /* Every integer here is a float, so f > t crosses an integer
         * exactly when f is one: then take the float below. */
        if (above && fd == (double)(int32_t)fd)
            f = nextafterf(f, -INFINITY);
    } else if (d > 0 ? above : fd < d || (fd == d && e > 0)) {
        f = nextafterf(f, 0.0f);
    }
    return f;
}

/* Per-format parsers. data/size is the whole file; name is for diagnostics.
 * want_faces: 0 skips face data quickly (cloud reads). */
typedef tessel_status (*tsl_parse_fn)(const uint8_t *data, size_t size, const char *name,
                                      int want_faces, tsl_builder *b, tessel_diag *diag);

/* The part of a read before parsing, shared by tessel_cloud_parse and the
 * streaming reader: params (NULL: defaults) checked, the format chosen
 * (params, then name's extension, then data's first bytes), b initialised
 * with the limits and box. diag says why on failure. */
tessel_status tsl_read_setup(const uint8_t *data, size_t size, const char *name,
                             const tessel_read_params *params, tsl_builder *b,
                             tsl_parse_fn *fn, tessel_diag *diag);

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
/* Part `part` of `parts` of a PLY file's vertex records (records
 * count * part / parts up to count * (part + 1) / parts) into b, after the
 * checks tsl_parse_ply makes of the header; *whole when the file cannot be
 * read in parts (ascii, records of varying size up to the vertices, an
 * organized grid or a viewpoint): nothing is read then. */
tessel_status tsl_parse_ply_part(const uint8_t *data, size_t size, const char *name, size_t part,
                                 size_t parts, tsl_builder *b, bool *whole, tessel_diag *diag);

/* ---- LAS header and records, shared by the LAS and LAZ readers ---- */

/* A LAS public header block, checked (src/io/las.c). */
typedef struct tsl_las_header {
    unsigned minor;              /* LAS 1.minor, 0..4 */
    unsigned format;             /* point data record format 0..10, compression bits removed */
    int compressed;              /* format byte had bit 7 (or 6) set: LAZ */
    size_t header_size, point_offset, record_length;
    uint32_t vlr_count;
    uint64_t count;              /* points: the 1.4 64-bit count when it is set */
    double scale[3], offset[3];  /* world = integer * scale + offset */
    double min[3], max[3];       /* the header's bounds */
    uint64_t evlr_start;         /* 1.4 extended VLRs (count 0: none) */
    uint32_t evlr_count;
} tsl_las_header;

/* Checks and reads the header and walks the VLRs. data holds at least the
 * first min(file_size, point offset) bytes of a file of file_size bytes.
 * Errors name the field's byte offset. Point counts against the bytes that
 * follow are the caller's to check (they differ for LAZ). */
tessel_status tsl_las_header_parse(const uint8_t *data, size_t size, uint64_t file_size,
                                   const char *name, tsl_las_header *h, tessel_diag *diag);

/* Finds a VLR (user ID, record ID) among the header's VLRs: its payload
 * (inside data[header_size, point_offset)) and length, or NULL. */
const uint8_t *tsl_las_find_vlr(const uint8_t *data, const tsl_las_header *h,
                                const char *user_id, unsigned record_id, size_t *length);

/* What tsl_parse_las checks before it emits: the header, and for
 * uncompressed data the point count against the bytes that follow and the
 * EVLRs; *n is then the number of records at h->point_offset (0 for LAZ,
 * whose count the LAZ reader checks). */
tessel_status tsl_las_check(const uint8_t *data, size_t size, const char *name,
                            tsl_las_header *h, size_t *n, tessel_diag *diag);

/* Whether h's point format carries RGB. */
bool tsl_las_has_rgb(const tsl_las_header *h);
/* How far RGB is shifted down: 8 when a value of the n records exceeds
 * 255 (16-bit colours), else 0 (many writers store 8-bit values). A read
 * decides over all the records it emits. */
int tsl_las_rgb_shift(const uint8_t *records, size_t n, const tsl_las_header *h);

/* Hands n point records (record_length apart, as a LAS file stores them) to
 * the builder: world coordinates X * scale + offset in double, RGB shifted
 * down by rgb_shift (< 0: tsl_las_rgb_shift of these n); with b->bbox only
 * the points inside it. at: the records' byte offset in the file (for LAZ,
 * where they would be uncompressed), for diagnostics. */
tessel_status tsl_las_emit(const uint8_t *records, size_t n, const tsl_las_header *h,
                           int rgb_shift, const char *name, uint64_t at, tsl_builder *b,
                           tessel_diag *diag);

/* Reads a whole file into memory (NUL-terminated for text parsers; *size
 * excludes the NUL). */
tessel_status tsl_read_file(const char *path, uint8_t **data, size_t *size,
                            tessel_diag *diag);

/* ---- text scanning helpers for the text formats ---- */

/* Blanks between the tokens of a line: space, tab, and the CR of a CRLF
 * line end. */
static inline bool tsl_is_blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }
static inline const char *tsl_skip_blanks(const char *p, const char *end)
{
    while (p < end && tsl_is_blank(*p))
        p++;
    return p;
}

/* Parses a double at *p (strtod semantics, no locale surprises: '.' only),
 * stopping at end. Advances *p. Returns false when no number is there. */
bool tsl_scan_double(const char **p, const char *end, double *out);
/* Parses an unsigned decimal integer; false on none or overflow of uint64. */
bool tsl_scan_u64(const char **p, const char *end, uint64_t *out);
/* Parses a signed decimal integer; false on none or overflow of int64. */
bool tsl_scan_i64(const char **p, const char *end, int64_t *out);

/* ---- writing ---- */

/* What a writer writes: vertex arrays (world = offset + xyz). */
typedef struct tsl_vertices {
    size_t count;
    const float *xyz;
    const float *normals;   /* NULL: none written */
    const uint8_t *rgb;     /* NULL: none written */
    double offset[3];
} tsl_vertices;

/* Whether a writer writes v's normals / colours: v has them and params
 * (NULL: the defaults, which write both) asks for them. */
static inline bool tsl_writes_normals(const tsl_vertices *v, const tessel_write_params *params)
{
    return v->normals && (!params || params->write_normals);
}
static inline bool tsl_writes_rgb(const tsl_vertices *v, const tessel_write_params *params)
{
    return v->rgb && (!params || params->write_rgb);
}

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

/* Resolves params (NULL: defaults) and the format (AUTO: the extension of
 * path) into *eff and the writer; diag names path when neither tells. */
tessel_status tsl_write_setup(const char *path, const tessel_write_params *params,
                              tessel_write_params *eff, const tsl_format_writer **w,
                              tessel_diag *diag);
/* After a writer failed (st) or finished: commit, or abort with a message
 * naming path. */
tessel_status tsl_write_finish(tsl_outfile *out, tessel_status st, const char *path,
                               tessel_diag *diag);

/* A whole cloud as PLY, keeping what tsl_vertices cannot carry: an
 * organized cloud is written as all width*height cells in row order (NaN
 * coordinates for missing cells) with "comment organized W H", and the
 * viewpoint as "comment viewpoint X Y Z" (src/io/ply.c). */
tessel_status tsl_ply_write_cloud(FILE *fp, const tessel_cloud *cloud,
                                  const tessel_write_params *params);

/* Formats a world coordinate (offset + f) so that reading it back as a
 * double gives the same floor (all tsl_choose_offset looks at) and, through
 * tsl_local_coord, the same float: the shortest of "%.7g".."%.9g" of the
 * float when offset is 0, of "%.Nf" of the double sum else, that does; the
 * exact "%.17g" when none does. Returns the length written to buf
 * (size >= 32). */
int tsl_format_coord(char *buf, double offset, float f);

#endif /* TESSEL_IO_INTERNAL_H */
