/* LAZ and COPC reading, private to the library (src/io/laz.c).
 *
 * LAZ is LAS whose point records are compressed by LASzip; COPC is a LAZ 1.4
 * file whose chunks are the nodes of an octree. The whole-file reader
 * (tsl_laz_parse, called by the LAS reader when the format byte says
 * "compressed") decodes every chunk, in parallel, into LAS records and hands
 * them to the LAS reader's emission, so LAZ gives exactly the cloud its LAS
 * twin gives.
 *
 * The chunk interface lets a reader walk a LAZ file a chunk at a time
 * without holding the decoded points (or, from a file, the compressed ones):
 *
 *     tsl_laz *z;
 *     tsl_laz_open_file(&z, path, &diag);          // header, VLRs, chunk table
 *     const tsl_laz_info *info = tsl_laz_get_info(z);
 *     uint8_t *rec = malloc(info->max_chunk_points * info->record_length);
 *     size_t n;
 *     while (tsl_laz_read_next(z, rec, &n, &diag) == TESSEL_OK && n > 0)
 *         use n records of info->record_length bytes (the LAS layout of
 *         point format info->format: X Y Z int32 at bytes 0..11, ...);
 *     tsl_laz_close(z);
 *
 * tsl_laz_read_chunk(z, k, ...) reads chunk k directly (a file without a
 * chunk table is decoded up to k first). A tsl_laz is used by one thread at a
 * time; tsl_laz_decode_all decodes a memory-backed one on `threads`
 * threads. Every error names the file and a byte offset. */
#ifndef TESSEL_IO_LAZ_H
#define TESSEL_IO_LAZ_H

#include "io/io.h"

typedef struct tsl_laz tsl_laz;

typedef struct tsl_laz_info {
    tsl_las_header header;     /* format, record_length, count, scale, offset, bounds */
    unsigned compressor;       /* 1 pointwise, 2 pointwise chunked, 3 layered chunked */
    uint32_t chunk_size;       /* points per chunk; UINT32_MAX: variable (from the table) */
    size_t chunk_count;
    size_t max_chunk_points;   /* the largest chunk: a caller's buffer, in records */
    int has_table;             /* 0: chunk starts are found by decoding in order */
    int copc;                  /* COPC: chunks carry octree node bounds */
} tsl_laz_info;

/* Opens LAZ data in memory (the whole file; it must outlive the reader).
 * TESSEL_ERR_UNSUPPORTED for what LASzip defines but tessel does not
 * decode (unknown compressor, coder, item type or version). */
tessel_status tsl_laz_open_memory(tsl_laz **laz, const uint8_t *data, size_t size,
                                  const char *name, tessel_diag *diag);
/* Opens a LAZ file: reads its header, VLRs and chunk table, and each chunk's
 * bytes when the chunk is read. */
tessel_status tsl_laz_open_file(tsl_laz **laz, const char *path, tessel_diag *diag);
void tsl_laz_close(tsl_laz *laz);

const tsl_laz_info *tsl_laz_get_info(const tsl_laz *laz);
/* Points in chunk k (k < chunk_count), after the header's count caps them. */
size_t tsl_laz_chunk_points(const tsl_laz *laz, size_t k);
/* COPC: the bounds of chunk k's octree node (world coordinates); false when
 * the file has no COPC hierarchy or the hierarchy does not list chunk k. */
bool tsl_laz_chunk_bounds(const tsl_laz *laz, size_t k, double min[3], double max[3]);

/* Decodes chunk k into records (tsl_laz_chunk_points(k) records). */
tessel_status tsl_laz_read_chunk(tsl_laz *laz, size_t k, uint8_t *records, tessel_diag *diag);
/* Decodes the chunk after the last one read (the first at the start) into
 * records (room for max_chunk_points); *count = 0 after the last chunk. */
tessel_status tsl_laz_read_next(tsl_laz *laz, uint8_t *records, size_t *count,
                                tessel_diag *diag);
/* Decodes every point into records (header.count records) on `threads`
 * threads (0: the OpenMP default); chunks are decoded in parallel when
 * their starts are known, in file order otherwise. The records and the
 * error reported (the first bad chunk in file order) do not depend on the
 * thread count. */
tessel_status tsl_laz_decode_all(tsl_laz *laz, uint8_t *records, int threads,
                                 tessel_diag *diag);
/* The same for the chunks k with select[k] set (select NULL: all), their
 * records packed in file order. */
tessel_status tsl_laz_decode_chunks(tsl_laz *laz, const uint8_t *select, uint8_t *records,
                                    int threads, tessel_diag *diag);

/* The chunks a read of z into b decodes: with b's box and a COPC
 * hierarchy, (*select)[k] says which (the nodes that meet the box, and the
 * chunks the hierarchy does not list), else *select is NULL (all);
 * *points: the points in them. TESSEL_ERR_LIMIT above b's limit (without
 * a box; with one, emission counts the points inside). Free *select. */
tessel_status tsl_laz_select(tsl_laz *z, const tsl_builder *b, uint8_t **select,
                             uint64_t *points, tessel_diag *diag);

/* The LAS reader's entry for compressed files: h is the checked header of
 * data. Decodes all points and emits them as tsl_parse_las does. */
tessel_status tsl_laz_parse(const uint8_t *data, size_t size, const char *name,
                            const tsl_las_header *h, tsl_builder *b, tessel_diag *diag);

#endif /* TESSEL_IO_LAZ_H */
