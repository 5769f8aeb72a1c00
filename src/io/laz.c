/* LAZ (LASzip-compressed LAS) and COPC reader: the "laszip encoded" VLR,
 * the chunk table, chunk by chunk or whole-file decoding in parallel.
 *
 * Format description: Isenburg, "LASzip: lossless compression of LiDAR
 * data" (PE&RS 79(2), 2013); the LASzip VLR and chunk table as the reference
 * implementation (LASzip's laszip.cpp unpack and lasreadpoint.cpp) reads
 * them; "Cloud Optimized Point Cloud Specification 1.0" (copc.io, 2021) for
 * the COPC info VLR and hierarchy EVLR.
 *
 *  - VLR (user ID "laszip encoded", record 22204): compressor u16 (1
 *    pointwise, 2 pointwise chunked, 3 layered chunked), coder u16 (0:
 *    arithmetic), version u8 u8 u16, options u32, chunk size u32 (points per
 *    chunk; 0xFFFFFFFF: variable, from the table), two i64 for special
 *    EVLRs, item count u16, then per item type, size, version (u16 each).
 *    The items, in order, must make up the LAS record of the header's point
 *    format: POINT10 [GPSTIME11] [RGB12] [WAVEPACKET13] [BYTE] for 0-5,
 *    POINT14 [RGB14 | RGBNIR14] [WAVEPACKET14] [BYTE14] for 6-10.
 *  - Compressor 1: one stream from the point data offset. Compressors 2
 *    and 3: an i64 at the point data offset gives the chunk table's
 *    position; chunks follow it. The table: u32 version (0), u32 chunk
 *    count, then an arithmetic stream (integer decompressor, 32 bits, 2
 *    contexts) of each chunk's point count (variable chunks only, context 0,
 *    predicted by the previous count) and byte size (context 1, predicted by
 *    the previous size). As LASzip does: a position of -1 means the
 *    position is in the last 8 bytes of the file; a position equal to the
 *    point data offset (the writer was interrupted) or a table that cannot
 *    be read means chunks of the fixed size are found by decoding them in
 *    order (each starts where the one before ended); variable chunks then
 *    cannot be read.
 *  - COPC: the info VLR ("copc", 1) gives the root octree cube (centre and
 *    half size) and the root hierarchy page; a page lists nodes (depth and
 *    x y z key, offset, byte size, point count: -1 for a child page). Each
 *    node with points is one LAZ chunk, whose bounds follow from its key.
 *
 * Hostile input: nothing is read before it is bounds-checked against the
 * file; a chunk's announced points are at most 4096 per compressed byte
 * (the coder's most skewed models reach about 1000; a point costs at least
 * four adaptive symbols); decoding stops at the first point that reads past
 * its stream, and every error names the chunk and a byte offset. */
#include "io/laz.h"

#include "io/laz_items.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { LAZ_VLR_RECORD = 22204, LAZ_MAX_POINTS_PER_BYTE = 4096 };
/* Without a chunk table, a file-backed reader reads at most this many bytes
 * past a chunk's start per raw byte of its points (a compressed chunk is
 * smaller than its raw points; twice leaves room for any real coder). */
enum { LAZ_SEQ_WINDOW_FACTOR = 2, LAZ_SEQ_WINDOW_EXTRA = 65536 };

struct tsl_laz {
    char name[512];
    const uint8_t *data;      /* memory: the whole file */
    uint64_t size;            /* file size */
    FILE *fp;                 /* file: read on demand */
    uint8_t *head;            /* file: the bytes before the point data */
    uint8_t *buf;             /* file: the bytes of the chunk being decoded */
    size_t buf_cap;
    tsl_laz_info info;
    laz_item items[LAZ_MAX_ITEMS];
    unsigned n_items;
    uint64_t chunks_start;    /* the first chunk's byte offset */
    uint64_t region_end;      /* end of the compressed point data */
    uint64_t *starts;         /* chunk_count + 1: byte offsets (sequential: known up to `known`) */
    uint64_t *first;          /* chunk_count + 1: index of each chunk's first point */
    size_t known;             /* sequential: starts[0..known] are known */
    size_t next_chunk;        /* tsl_laz_read_next */
    laz_decoder *dec;         /* for the chunk interface */
    uint8_t *scratch;         /* sequential skipping: one chunk of records */
    double (*node_min)[3], (*node_max)[3];
    uint8_t *has_node;
};

static uint16_t rd16(const uint8_t *p) { return laz_rd16(p); }
static uint32_t rd32(const uint8_t *p) { return laz_rd32(p); }
static uint64_t rd64(const uint8_t *p) { return laz_rd64(p); }
static double rdf64(const uint8_t *p)
{
    uint64_t u = rd64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* Where the header keeps the point count it announced. */
static uint64_t count_field(const tsl_las_header *h) { return h->minor >= 4 ? 247 : 107; }

/* ---- byte access: memory or file ---- */

/* [offset, offset + len) of the file, or NULL (diag set) when it is not
 * there. A file-backed reader reuses one buffer: the pointer is valid until
 * the next call. */
static const uint8_t *laz_bytes(tsl_laz *z, uint64_t offset, size_t len, tessel_diag *diag,
                                const char *what)
{
    if (offset > z->size || len > z->size - offset) {
        tsl_diag_set(diag, z->name, 0, 1, offset,
                     "LAZ %s (%zu bytes at byte %llu) runs past the end of the file (%llu "
                     "bytes)",
                     what, len, (unsigned long long)offset, (unsigned long long)z->size);
        return NULL;
    }
    if (z->data)
        return z->data + offset;
    if (len > z->buf_cap) {
        uint8_t *nb = realloc(z->buf, len ? len : 1);
        if (!nb) {
            tsl_diag_set(diag, z->name, 0, 1, offset, "cannot hold the %zu bytes of LAZ %s",
                         len, what);
            return NULL;
        }
        z->buf = nb;
        z->buf_cap = len;
    }
    if (fseeko(z->fp, (off_t)offset, SEEK_SET) != 0 || fread(z->buf, 1, len, z->fp) != len) {
        tsl_diag_set(diag, z->name, 0, 1, offset, "cannot read LAZ %s (%zu bytes)", what,
                     len);
        return NULL;
    }
    return z->buf;
}

/* ---- the laszip VLR ---- */

static const char *item_name(unsigned type)
{
    switch (type) {
    case LAZ_BYTE: return "BYTE";
    case LAZ_POINT10: return "POINT10";
    case LAZ_GPSTIME11: return "GPSTIME11";
    case LAZ_RGB12: return "RGB12";
    case LAZ_WAVEPACKET13: return "WAVEPACKET13";
    case LAZ_POINT14: return "POINT14";
    case LAZ_RGB14: return "RGB14";
    case LAZ_RGBNIR14: return "RGBNIR14";
    case LAZ_WAVEPACKET14: return "WAVEPACKET14";
    case LAZ_BYTE14: return "BYTE14";
    default: return "unknown";
    }
}

/* Sizes and decodable versions of each item type. */
static bool item_supported(const laz_item *it)
{
    switch (it->type) {
    case LAZ_POINT10: return it->size == 20 && (it->version == 1 || it->version == 2);
    case LAZ_GPSTIME11: return it->size == 8 && (it->version == 1 || it->version == 2);
    case LAZ_RGB12: return it->size == 6 && (it->version == 1 || it->version == 2);
    case LAZ_BYTE: return it->size >= 1 && (it->version == 1 || it->version == 2);
    case LAZ_WAVEPACKET13: return it->size == 29 && it->version == 1;
    case LAZ_POINT14: return it->size == 30 && it->version >= 2 && it->version <= 4;
    case LAZ_RGB14: return it->size == 6 && it->version >= 2 && it->version <= 4;
    case LAZ_RGBNIR14: return it->size == 8 && it->version >= 2 && it->version <= 4;
    case LAZ_WAVEPACKET14: return it->size == 29 && (it->version == 3 || it->version == 4);
    case LAZ_BYTE14: return it->size >= 1 && it->version >= 2 && it->version <= 4;
    default: return false;
    }
}

/* The items of each point format, without the optional extra bytes. */
static const uint8_t format_items[11][4] = {
    {LAZ_POINT10},
    {LAZ_POINT10, LAZ_GPSTIME11},
    {LAZ_POINT10, LAZ_RGB12},
    {LAZ_POINT10, LAZ_GPSTIME11, LAZ_RGB12},
    {LAZ_POINT10, LAZ_GPSTIME11, LAZ_WAVEPACKET13},
    {LAZ_POINT10, LAZ_GPSTIME11, LAZ_RGB12, LAZ_WAVEPACKET13},
    {LAZ_POINT14},
    {LAZ_POINT14, LAZ_RGB14},
    {LAZ_POINT14, LAZ_RGBNIR14},
    {LAZ_POINT14, LAZ_WAVEPACKET14},
    {LAZ_POINT14, LAZ_RGBNIR14, LAZ_WAVEPACKET14}};
static const uint8_t format_item_count[11] = {1, 2, 2, 3, 3, 4, 1, 2, 2, 2, 3};

static tessel_status laz_parse_vlr(tsl_laz *z, const uint8_t *vlr, size_t len, uint64_t at,
                                   tessel_diag *diag)
{
    const tsl_las_header *h = &z->info.header;
    if (len < 34 || (len - 34) % 6 != 0 || len == 34) {
        tsl_diag_set(diag, z->name, 0, 1, at,
                     "LAZ \"laszip encoded\" VLR has %zu bytes: it needs 34 plus 6 per item",
                     len);
        return TESSEL_ERR_PARSE;
    }
    unsigned compressor = rd16(vlr), coder = rd16(vlr + 2);
    uint32_t chunk_size = rd32(vlr + 12);
    unsigned n_items = rd16(vlr + 32);
    if (n_items != (len - 34) / 6) {
        tsl_diag_set(diag, z->name, 0, 1, at + 32,
                     "LAZ VLR lists %u items but has room for %zu", n_items, (len - 34) / 6);
        return TESSEL_ERR_PARSE;
    }
    if (coder != 0) {
        tsl_diag_set(diag, z->name, 0, 1, at + 2,
                     "LAZ coder %u is not supported (0, arithmetic, is)", coder);
        return TESSEL_ERR_UNSUPPORTED;
    }
    if (compressor < 1 || compressor > 3) {
        tsl_diag_set(diag, z->name, 0, 1, at,
                     "LAZ compressor %u is not supported (1 pointwise, 2 pointwise chunked, "
                     "3 layered chunked are)",
                     compressor);
        return TESSEL_ERR_UNSUPPORTED;
    }
    if (n_items > LAZ_MAX_ITEMS) {
        tsl_diag_set(diag, z->name, 0, 1, at + 32, "LAZ VLR lists %u items (at most %d)",
                     n_items, LAZ_MAX_ITEMS);
        return TESSEL_ERR_UNSUPPORTED;
    }
    size_t total = 0;
    for (unsigned i = 0; i < n_items; i++) {
        laz_item *it = &z->items[i];
        it->type = rd16(vlr + 34 + 6 * i);
        it->size = rd16(vlr + 36 + 6 * i);
        it->version = rd16(vlr + 38 + 6 * i);
        if (!item_supported(it)) {
            tsl_diag_set(diag, z->name, 0, 1, at + 34 + 6 * i,
                         "LAZ item %u (%s, type %u, %u bytes, version %u) is not supported",
                         i + 1, item_name(it->type), it->type, it->size, it->version);
            return TESSEL_ERR_UNSUPPORTED;
        }
        total += it->size;
    }
    z->n_items = n_items;
    if (total != h->record_length) {
        tsl_diag_set(diag, z->name, 0, 1, at + 34,
                     "LAZ items make %zu-byte records, the header says %zu", total,
                     h->record_length);
        return TESSEL_ERR_PARSE;
    }
    /* The items must be the point format's, in its order. */
    unsigned f = h->format, want = format_item_count[f];
    bool ok = n_items == want || n_items == want + 1;
    for (unsigned i = 0; ok && i < want; i++)
        ok = z->items[i].type == format_items[f][i];
    if (ok && n_items == want + 1)
        ok = z->items[want].type == (f >= 6 ? LAZ_BYTE14 : LAZ_BYTE);
    if (!ok) {
        tsl_diag_set(diag, z->name, 0, 1, at + 34,
                     "LAZ items (%s%s%s...) do not make the records of point format %u",
                     item_name(z->items[0].type), n_items > 1 ? ", " : "",
                     n_items > 1 ? item_name(z->items[1].type) : "", f);
        return TESSEL_ERR_PARSE;
    }
    if ((compressor == 3) != (f >= 6)) {
        tsl_diag_set(diag, z->name, 0, 1, at,
                     "LAZ compressor %u cannot hold point format %u (formats 6-10 need the "
                     "layered compressor 3, formats 0-5 compressor 1 or 2)",
                     compressor, f);
        return TESSEL_ERR_UNSUPPORTED;
    }
    z->info.compressor = compressor;
    z->info.chunk_size = compressor == 1 || chunk_size == 0 ? UINT32_MAX : chunk_size;
    if (compressor == 1)
        z->info.chunk_size = UINT32_MAX;
    return TESSEL_OK;
}

/* ---- chunks ---- */

static tessel_status laz_alloc_chunks(tsl_laz *z, size_t n, tessel_diag *diag)
{
    z->info.chunk_count = n;
    z->starts = calloc(n + 1, sizeof *z->starts);
    z->first = calloc(n + 1, sizeof *z->first);
    if (!z->starts || !z->first) {
        tsl_diag_set(diag, z->name, 0, 0, 0, "cannot hold a table of %zu LAZ chunks", n);
        return TESSEL_ERR_NOMEM;
    }
    return TESSEL_OK;
}

/* Chunks of the fixed size, starts found by decoding in order. */
static tessel_status laz_sequential_chunks(tsl_laz *z, uint64_t start, tessel_diag *diag)
{
    uint64_t n = z->info.header.count;
    uint64_t cs = z->info.chunk_size == UINT32_MAX ? (n ? n : 1) : z->info.chunk_size;
    uint64_t chunks = (n + cs - 1) / cs;
    if (chunks > SIZE_MAX / sizeof(uint64_t) - 1) {
        tsl_diag_set(diag, z->name, 0, 1, count_field(&z->info.header),
                     "LAZ file announces %llu points",
                     (unsigned long long)n);
        return TESSEL_ERR_PARSE;
    }
    tessel_status st = laz_alloc_chunks(z, (size_t)chunks, diag);
    if (st != TESSEL_OK)
        return st;
    for (size_t k = 0; k <= chunks; k++)
        z->first[k] = (uint64_t)k * cs < n ? (uint64_t)k * cs : n;
    z->starts[0] = start;
    z->known = 0;
    z->info.has_table = 0;
    return TESSEL_OK;
}

/* Reads the chunk table at `pos`. TESSEL_OK, or TESSEL_ERR_PARSE with diag
 * set when it is not there or not sane (the caller decides whether that is
 * fatal). */
static tessel_status laz_read_table(tsl_laz *z, uint64_t pos, tessel_diag *diag)
{
    uint64_t n = z->info.header.count;
    bool variable = z->info.chunk_size == UINT32_MAX;
    if (pos < z->chunks_start || pos > z->size || z->size - pos < 8) {
        tsl_diag_set(diag, z->name, 0, 1, z->info.header.point_offset,
                     "LAZ chunk table position %llu lies outside the chunk data (bytes %llu "
                     "to %llu)",
                     (unsigned long long)pos, (unsigned long long)z->chunks_start,
                     (unsigned long long)z->size);
        return TESSEL_ERR_PARSE;
    }
    const uint8_t *t = laz_bytes(z, pos, 8, diag, "chunk table");
    if (!t)
        return TESSEL_ERR_PARSE;
    uint32_t version = rd32(t), count = rd32(t + 4);
    if (version != 0) {
        tsl_diag_set(diag, z->name, 0, 1, pos, "LAZ chunk table version %u (0 expected)",
                     version);
        return TESSEL_ERR_PARSE;
    }
    /* Every chunk holds its first point raw. */
    uint64_t max_chunks = (pos - z->chunks_start) / z->info.header.record_length;
    if (count > max_chunks) {
        tsl_diag_set(diag, z->name, 0, 1, pos + 4,
                     "LAZ chunk table lists %u chunks, more than the %llu bytes before it "
                     "can hold",
                     count, (unsigned long long)(pos - z->chunks_start));
        return TESSEL_ERR_PARSE;
    }
    if (!variable) {
        uint64_t need = (n + z->info.chunk_size - 1) / z->info.chunk_size;
        if (count < need) {
            tsl_diag_set(diag, z->name, 0, 1, pos + 4,
                         "LAZ chunk table lists %u chunks; %llu points in chunks of %u need "
                         "%llu",
                         count, (unsigned long long)n, z->info.chunk_size,
                         (unsigned long long)need);
            return TESSEL_ERR_PARSE;
        }
    }
    tessel_status st = laz_alloc_chunks(z, count, diag);
    if (st != TESSEL_OK)
        return st;
    uint32_t *sizes = malloc(((size_t)count + 1) * sizeof *sizes);
    uint32_t *counts = malloc(((size_t)count + 1) * sizeof *counts);
    laz_ic ic;
    memset(&ic, 0, sizeof ic);
    if (!sizes || !counts || laz_ic_alloc(&ic, 32, 2, 8, 0) != 0) {
        free(sizes);
        free(counts);
        laz_ic_free(&ic);
        tsl_diag_set(diag, z->name, 0, 0, 0, "cannot hold a table of %u LAZ chunks", count);
        return TESSEL_ERR_NOMEM;
    }
    st = TESSEL_OK;
    if (count > 0) {
        /* Each entry takes a few bytes (a 32-bit corrector at most about 7):
         * no need to read the EVLRs that may follow. */
        uint64_t want = 16 + 24 * (uint64_t)count, rest = z->size - pos - 8;
        size_t len = (size_t)(want < rest ? want : rest);
        const uint8_t *s = laz_bytes(z, pos + 8, len, diag, "chunk table");
        if (!s)
            st = TESSEL_ERR_PARSE;
        int fail = 0;
        laz_dec d;
        if (s) {
            laz_dec_init(&d, s, s + len, &fail);
            laz_ic_init(&ic);
        }
        for (uint32_t i = 0; s && i < count && !fail; i++) {
            if (variable)
                counts[i] = (uint32_t)laz_ic_decompress(&ic, &d, i ? laz_i32(counts[i - 1]) : 0,
                                                        0);
            sizes[i] = (uint32_t)laz_ic_decompress(&ic, &d, i ? laz_i32(sizes[i - 1]) : 0, 1);
        }
        if (s && fail) {
            tsl_diag_set(diag, z->name, 0, 1, pos + 8,
                         "LAZ chunk table (%u chunks at byte %llu) is truncated or corrupt",
                         count, (unsigned long long)pos);
            st = TESSEL_ERR_PARSE;
        }
    }
    laz_ic_free(&ic);
    /* Starts, point counts, and their sanity against the file. */
    uint64_t at = z->chunks_start, first = 0;
    for (uint32_t i = 0; st == TESSEL_OK && i < count; i++) {
        uint64_t pts = variable ? counts[i] : z->info.chunk_size;
        if (first + pts > n)
            pts = n - first;
        z->starts[i] = at;
        z->first[i] = first;
        if (sizes[i] == 0 && pts > 0) {
            tsl_diag_set(diag, z->name, 0, 1, at,
                         "LAZ chunk %u of %u (at byte %llu) has 0 bytes for %llu points",
                         i + 1, count, (unsigned long long)at, (unsigned long long)pts);
            st = TESSEL_ERR_PARSE;
            break;
        }
        if (sizes[i] > pos - at) {
            tsl_diag_set(diag, z->name, 0, 1, at,
                         "LAZ chunk %u of %u (%u bytes at byte %llu) runs past the chunk "
                         "table at byte %llu",
                         i + 1, count, sizes[i], (unsigned long long)at,
                         (unsigned long long)pos);
            st = TESSEL_ERR_PARSE;
            break;
        }
        if (pts > 1 + (uint64_t)LAZ_MAX_POINTS_PER_BYTE * sizes[i]) {
            tsl_diag_set(diag, z->name, 0, 1, at,
                         "LAZ chunk %u of %u announces %llu points in %u bytes", i + 1, count,
                         (unsigned long long)pts, sizes[i]);
            st = TESSEL_ERR_PARSE;
            break;
        }
        at += sizes[i];
        first += pts;
    }
    if (st == TESSEL_OK) {
        z->starts[count] = at;
        z->first[count] = first;
        if (first < n) {
            tsl_diag_set(diag, z->name, 0, 1, pos + 4,
                         "LAZ chunk table holds %llu points, the header announces %llu",
                         (unsigned long long)first, (unsigned long long)n);
            st = TESSEL_ERR_PARSE;
        }
    }
    free(sizes);
    free(counts);
    if (st == TESSEL_OK) {
        z->info.has_table = 1;
        z->known = count;
    } else {
        free(z->starts);
        free(z->first);
        z->starts = z->first = NULL;
        z->info.chunk_count = 0;
    }
    return st;
}

/* The chunk layout after the header and VLR. */
static tessel_status laz_setup_chunks(tsl_laz *z, tessel_diag *diag)
{
    const tsl_las_header *h = &z->info.header;
    uint64_t n = h->count;
    z->region_end = z->size;
    if (h->minor >= 4 && h->evlr_count > 0 && h->evlr_start >= h->point_offset &&
        h->evlr_start <= z->size)
        z->region_end = h->evlr_start;
    if (z->info.compressor == 1) {
        z->chunks_start = h->point_offset;
        if (n > 1 + (uint64_t)LAZ_MAX_POINTS_PER_BYTE * (z->region_end - z->chunks_start)) {
            tsl_diag_set(diag, z->name, 0, 1, count_field(h),
                         "LAZ header announces %llu points in %llu bytes of point data",
                         (unsigned long long)n,
                         (unsigned long long)(z->region_end - z->chunks_start));
            return TESSEL_ERR_PARSE;
        }
        tessel_status st = laz_sequential_chunks(z, z->chunks_start, diag);
        if (st == TESSEL_OK) {
            z->info.has_table = 1; /* one chunk, its start is known */
            z->known = z->info.chunk_count;
            z->starts[z->info.chunk_count] = z->region_end;
        }
        return st;
    }
    if (n == 0)
        return laz_alloc_chunks(z, 0, diag);
    const uint8_t *p = laz_bytes(z, h->point_offset, 8, diag, "chunk table position");
    if (!p)
        return TESSEL_ERR_PARSE;
    int64_t pos;
    uint64_t u = rd64(p);
    memcpy(&pos, &u, sizeof pos);
    z->chunks_start = h->point_offset + 8;
    bool variable = z->info.chunk_size == UINT32_MAX;
    if (pos == -1) {
        /* written to a stream: the position is in the last 8 bytes */
        if (z->size >= z->chunks_start + 8 &&
            (p = laz_bytes(z, z->size - 8, 8, diag, "chunk table position")) != NULL) {
            u = rd64(p);
            memcpy(&pos, &u, sizeof pos);
        }
    }
    tessel_status st;
    if ((uint64_t)pos == h->point_offset) {
        st = TESSEL_ERR_PARSE; /* the writer never came back to fill it in */
        tsl_diag_set(diag, z->name, 0, 1, h->point_offset,
                     "LAZ chunk table is missing (its position was never written)");
    } else {
        st = laz_read_table(z, (uint64_t)pos, diag);
        if (st == TESSEL_OK)
            z->region_end = (uint64_t)pos;
    }
    if (st == TESSEL_ERR_NOMEM)
        return st;
    if (st != TESSEL_OK) {
        if (variable)
            return st; /* diag says why: variable chunks need the table */
        if (n > 1 + (uint64_t)LAZ_MAX_POINTS_PER_BYTE * (z->region_end - z->chunks_start)) {
            tsl_diag_set(diag, z->name, 0, 1, count_field(h),
                         "LAZ header announces %llu points in %llu bytes of point data",
                         (unsigned long long)n,
                         (unsigned long long)(z->region_end - z->chunks_start));
            return TESSEL_ERR_PARSE;
        }
        return laz_sequential_chunks(z, z->chunks_start, diag);
    }
    return TESSEL_OK;
}

/* ---- COPC ---- */

/* The chunk that starts at `offset`, or SIZE_MAX. */
static size_t chunk_at(const tsl_laz *z, uint64_t offset)
{
    size_t lo = 0, hi = z->info.chunk_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (z->starts[mid] < offset)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < z->info.chunk_count && z->starts[lo] == offset ? lo : SIZE_MAX;
}

/* Reads the COPC hierarchy (if any): node bounds per chunk. A broken
 * hierarchy only loses the bounds (the file still reads as LAZ). */
static void laz_read_copc(tsl_laz *z, const uint8_t *head)
{
    const tsl_las_header *h = &z->info.header;
    size_t len;
    const uint8_t *info = tsl_las_find_vlr(head, h, "copc", 1, &len);
    if (!info || len < 160 || !z->info.has_table || z->info.chunk_count == 0)
        return;
    double centre[3], half = rdf64(info + 24);
    for (int k = 0; k < 3; k++)
        centre[k] = rdf64(info + 8 * k);
    uint64_t root = rd64(info + 40), root_size = rd64(info + 48);
    if (!(half > 0) || !isfinite(half) || !isfinite(centre[0]) || !isfinite(centre[1]) ||
        !isfinite(centre[2]))
        return;
    size_t n = z->info.chunk_count;
    z->node_min = calloc(n, sizeof *z->node_min);
    z->node_max = calloc(n, sizeof *z->node_max);
    z->has_node = calloc(n, 1);
    /* pages to visit: offsets and sizes (a page's entries can add pages) */
    size_t cap = 64, top = 0, visited = 0;
    uint64_t (*stack)[2] = malloc(cap * sizeof *stack);
    if (!z->node_min || !z->node_max || !z->has_node || !stack) {
        free(stack);
        return;
    }
    stack[top][0] = root;
    stack[top][1] = root_size;
    top++;
    uint64_t budget = z->size / 32 + 1; /* entries: a page cannot list more than the file holds */
    while (top > 0 && visited < budget) {
        top--;
        uint64_t off = stack[top][0], size = stack[top][1];
        if (size % 32 != 0 || size > z->size)
            continue;
        uint8_t *page = malloc(size ? (size_t)size : 1);
        const uint8_t *src = page ? laz_bytes(z, off, (size_t)size, NULL, "COPC page") : NULL;
        if (!src) {
            free(page);
            continue;
        }
        memcpy(page, src, (size_t)size);
        for (uint64_t e = 0; e < size / 32 && visited < budget; e++, visited++) {
            const uint8_t *q = page + 32 * e;
            int32_t d = (int32_t)rd32(q), key[3];
            for (int k = 0; k < 3; k++)
                key[k] = (int32_t)rd32(q + 4 + 4 * k);
            uint64_t offset = rd64(q + 16);
            int32_t bytes = (int32_t)rd32(q + 24), points = (int32_t)rd32(q + 28);
            if (points == -1) {
                if (bytes > 0 && top < 4096) {
                    if (top == cap) {
                        void *ns = realloc(stack, 2 * cap * sizeof *stack);
                        if (!ns)
                            continue;
                        stack = ns;
                        cap *= 2;
                    }
                    stack[top][0] = offset;
                    stack[top][1] = (uint64_t)bytes;
                    top++;
                }
                continue;
            }
            if (points <= 0 || d < 0 || d > 30)
                continue;
            size_t c = chunk_at(z, offset);
            if (c == SIZE_MAX)
                continue;
            double side = 2.0 * half / (double)(1u << d);
            for (int k = 0; k < 3; k++) {
                z->node_min[c][k] = centre[k] - half + side * key[k];
                z->node_max[c][k] = z->node_min[c][k] + side;
            }
            z->has_node[c] = 1;
            z->info.copc = 1;
        }
        free(page);
    }
    free(stack);
}

/* ---- opening ---- */

static tessel_status laz_open_common(tsl_laz *z, const uint8_t *head, size_t head_size,
                                     tessel_diag *diag)
{
    tsl_las_header *h = &z->info.header;
    tessel_status st = tsl_las_header_parse(head, head_size, z->size, z->name, h, diag);
    if (st != TESSEL_OK)
        return st;
    if (!h->compressed) {
        tsl_diag_set(diag, z->name, 0, 1, 104,
                     "not a LAZ file: the point data are not compressed (format byte 0x%02x)",
                     head[104]);
        return TESSEL_ERR_PARSE;
    }
    size_t len;
    const uint8_t *vlr = tsl_las_find_vlr(head, h, "laszip encoded", LAZ_VLR_RECORD, &len);
    if (!vlr) {
        tsl_diag_set(diag, z->name, 0, 1, 104,
                     "LAZ compressed point data (format byte 0x%02x) without the \"laszip "
                     "encoded\" VLR (record %d) that describes it: cannot decode",
                     head[104], LAZ_VLR_RECORD);
        return TESSEL_ERR_UNSUPPORTED;
    }
    st = laz_parse_vlr(z, vlr, len, (uint64_t)(vlr - head), diag);
    if (st != TESSEL_OK)
        return st;
    st = laz_setup_chunks(z, diag);
    if (st != TESSEL_OK)
        return st;
    size_t max = 0;
    for (size_t k = 0; k < z->info.chunk_count; k++) {
        size_t pts = (size_t)(z->first[k + 1] - z->first[k]);
        if (pts > max)
            max = pts;
    }
    z->info.max_chunk_points = max;
    laz_read_copc(z, head);
    return TESSEL_OK;
}

static void laz_set_name(tsl_laz *z, const char *name)
{
    snprintf(z->name, sizeof z->name, "%s", name ? name : "");
}

tessel_status tsl_laz_open_memory(tsl_laz **laz, const uint8_t *data, size_t size,
                                  const char *name, tessel_diag *diag)
{
    *laz = NULL;
    tsl_laz *z = calloc(1, sizeof *z);
    if (!z) {
        tsl_diag_set(diag, name, 0, 0, 0, "out of memory");
        return TESSEL_ERR_NOMEM;
    }
    laz_set_name(z, name);
    z->data = data;
    z->size = size;
    tessel_status st = laz_open_common(z, data, size, diag);
    if (st != TESSEL_OK) {
        tsl_laz_close(z);
        return st;
    }
    *laz = z;
    return TESSEL_OK;
}

tessel_status tsl_laz_open_file(tsl_laz **laz, const char *path, tessel_diag *diag)
{
    *laz = NULL;
    tsl_laz *z = calloc(1, sizeof *z);
    if (!z) {
        tsl_diag_set(diag, path, 0, 0, 0, "out of memory");
        return TESSEL_ERR_NOMEM;
    }
    laz_set_name(z, path);
    tessel_status st = TESSEL_OK;
    z->fp = fopen(path, "rb");
    if (!z->fp || fseeko(z->fp, 0, SEEK_END) != 0) {
        tsl_diag_set(diag, path, 0, 0, 0, "cannot open: %s", strerror(errno));
        st = TESSEL_ERR_IO;
    }
    off_t end = st == TESSEL_OK ? ftello(z->fp) : -1;
    if (st == TESSEL_OK && end < 0) {
        tsl_diag_set(diag, path, 0, 0, 0, "cannot size: %s", strerror(errno));
        st = TESSEL_ERR_IO;
    }
    if (st == TESSEL_OK) {
        z->size = (uint64_t)end;
        /* the header tells how far the VLRs go */
        size_t first = z->size < 375 ? (size_t)z->size : 375;
        uint8_t hdr[375];
        memset(hdr, 0, sizeof hdr);
        const uint8_t *b = laz_bytes(z, 0, first, diag, "header");
        if (!b) {
            st = TESSEL_ERR_IO;
        } else {
            memcpy(hdr, b, first);
            size_t head = first;
            if (first >= 100) {
                uint32_t po = rd32(hdr + 96);
                head = po > z->size ? (size_t)z->size : po;
                if (head < first)
                    head = first;
            }
            z->head = malloc(head ? head : 1);
            b = z->head ? laz_bytes(z, 0, head, diag, "header and VLRs") : NULL;
            if (!b) {
                st = z->head ? TESSEL_ERR_IO : TESSEL_ERR_NOMEM;
            } else {
                memcpy(z->head, b, head);
                st = laz_open_common(z, z->head, head, diag);
            }
        }
    }
    if (st != TESSEL_OK) {
        tsl_laz_close(z);
        return st;
    }
    *laz = z;
    return TESSEL_OK;
}

void tsl_laz_close(tsl_laz *z)
{
    if (!z)
        return;
    if (z->fp)
        fclose(z->fp);
    laz_decoder_destroy(z->dec);
    free(z->head);
    free(z->buf);
    free(z->starts);
    free(z->first);
    free(z->scratch);
    free(z->node_min);
    free(z->node_max);
    free(z->has_node);
    free(z);
}

const tsl_laz_info *tsl_laz_get_info(const tsl_laz *laz) { return &laz->info; }

size_t tsl_laz_chunk_points(const tsl_laz *z, size_t k)
{
    return k < z->info.chunk_count ? (size_t)(z->first[k + 1] - z->first[k]) : 0;
}

bool tsl_laz_chunk_bounds(const tsl_laz *z, size_t k, double min[3], double max[3])
{
    if (!z->has_node || k >= z->info.chunk_count || !z->has_node[k])
        return false;
    for (int i = 0; i < 3; i++) {
        min[i] = z->node_min[k][i];
        max[i] = z->node_max[k][i];
    }
    return true;
}

/* ---- decoding ---- */

/* Explains a failed chunk. */
static tessel_status laz_chunk_error(const tsl_laz *z, size_t k, uint64_t start,
                                     const laz_chunk_status *cs, tessel_diag *diag)
{
    size_t pts = tsl_laz_chunk_points(z, k);
    if (cs->fail & LAZ_FAIL_NOMEM) {
        tsl_diag_set(diag, z->name, 0, 1, start, "out of memory decoding LAZ chunk %zu of %zu",
                     k + 1, z->info.chunk_count);
        return TESSEL_ERR_NOMEM;
    }
    if (cs->fail & LAZ_FAIL_LAYOUT) {
        tsl_diag_set(diag, z->name, 0, 1, start + cs->at,
                     "LAZ chunk %zu of %zu (at byte %llu): its layer sizes do not fit in its "
                     "bytes",
                     k + 1, z->info.chunk_count, (unsigned long long)start);
        return TESSEL_ERR_PARSE;
    }
    if (cs->fail & LAZ_FAIL_DATA) {
        tsl_diag_set(diag, z->name, 0, 1, start + cs->at,
                     "LAZ chunk %zu of %zu (at byte %llu) is truncated: its data end at byte "
                     "%llu, at point %zu of %zu",
                     k + 1, z->info.chunk_count, (unsigned long long)start,
                     (unsigned long long)(start + cs->at), cs->point + 1, pts);
        return TESSEL_ERR_PARSE;
    }
    tsl_diag_set(diag, z->name, 0, 1, start + cs->at,
                 "LAZ chunk %zu of %zu (at byte %llu) is corrupt: impossible value at point "
                 "%zu of %zu",
                 k + 1, z->info.chunk_count, (unsigned long long)start, cs->point + 1, pts);
    return TESSEL_ERR_PARSE;
}

/* The bytes chunk k may use, [start, end): its table entry, or (no table)
 * up to the point data's end, at most a window past its start for a file. */
static uint64_t chunk_end(const tsl_laz *z, size_t k)
{
    if (z->info.has_table)
        return z->starts[k + 1];
    uint64_t end = z->region_end;
    if (!z->data) {
        uint64_t pts = z->first[k + 1] - z->first[k];
        uint64_t window = pts * z->info.header.record_length * LAZ_SEQ_WINDOW_FACTOR +
                          LAZ_SEQ_WINDOW_EXTRA;
        if (z->starts[k] + window < end)
            end = z->starts[k] + window;
    }
    return end;
}

/* Decodes chunk k (its start known) with dec. */
static tessel_status laz_decode_one(tsl_laz *z, laz_decoder *dec, size_t k, uint8_t *records,
                                    tessel_diag *diag)
{
    uint64_t start = z->starts[k], end = chunk_end(z, k);
    if (start > end || end > z->size) {
        tsl_diag_set(diag, z->name, 0, 1, start,
                     "LAZ chunk %zu of %zu starts at byte %llu, past the point data",
                     k + 1, z->info.chunk_count, (unsigned long long)start);
        return TESSEL_ERR_PARSE;
    }
    const uint8_t *p = laz_bytes(z, start, (size_t)(end - start), diag, "chunk");
    if (!p)
        return TESSEL_ERR_PARSE;
    size_t consumed;
    laz_chunk_status cs;
    laz_decode_chunk(dec, p, p + (end - start), tsl_laz_chunk_points(z, k), records,
                     &consumed, &cs);
    if (cs.fail)
        return laz_chunk_error(z, k, start, &cs, diag);
    if (!z->info.has_table && k + 1 > z->known) {
        z->starts[k + 1] = start + consumed;
        z->known = k + 1;
    }
    return TESSEL_OK;
}

static tessel_status laz_need_decoder(tsl_laz *z, tessel_diag *diag)
{
    if (z->dec)
        return TESSEL_OK;
    z->dec = laz_decoder_create(z->items, z->n_items, z->info.compressor == 3);
    if (!z->dec) {
        tsl_diag_set(diag, z->name, 0, 0, 0, "out of memory for the LAZ decoder");
        return TESSEL_ERR_NOMEM;
    }
    return TESSEL_OK;
}

tessel_status tsl_laz_read_chunk(tsl_laz *z, size_t k, uint8_t *records, tessel_diag *diag)
{
    if (k >= z->info.chunk_count) {
        tsl_diag_set(diag, z->name, 0, 0, 0, "LAZ chunk %zu does not exist (%zu chunks)",
                     k + 1, z->info.chunk_count);
        return TESSEL_ERR_INVALID_ARG;
    }
    tessel_status st = laz_need_decoder(z, diag);
    if (st != TESSEL_OK)
        return st;
    /* Without a table, decode the chunks before k to find where k starts. */
    while (!z->info.has_table && z->known < k) {
        if (!z->scratch &&
            !(z->scratch = tsl_alloc_array(z->info.max_chunk_points,
                                           z->info.header.record_length))) {
            tsl_diag_set(diag, z->name, 0, 0, 0, "out of memory for a LAZ chunk");
            return TESSEL_ERR_NOMEM;
        }
        st = laz_decode_one(z, z->dec, z->known, z->scratch, diag);
        if (st != TESSEL_OK)
            return st;
    }
    return laz_decode_one(z, z->dec, k, records, diag);
}

tessel_status tsl_laz_read_next(tsl_laz *z, uint8_t *records, size_t *count,
                                tessel_diag *diag)
{
    *count = 0;
    if (z->next_chunk >= z->info.chunk_count)
        return TESSEL_OK;
    tessel_status st = tsl_laz_read_chunk(z, z->next_chunk, records, diag);
    if (st == TESSEL_OK)
        *count = tsl_laz_chunk_points(z, z->next_chunk++);
    return st;
}

/* Decodes the selected chunks among k..k+step-1 (step 1 or 2, as many as
 * the file has) from memory with a table: chunk j into records + dest[j]
 * records, its status into cs[j]. Two chunks go together when both are
 * selected and there are two decoders; dec[0] NULL: out of memory. */
static void laz_decode_pair(const tsl_laz *z, laz_decoder *dec[2], const uint8_t *select,
                            size_t k, size_t step, uint8_t *records, const uint64_t *dest,
                            laz_chunk_status *cs)
{
    size_t rl = z->info.header.record_length, m = 0, js[2];
    for (size_t j = k; j < k + step && j < z->info.chunk_count; j++)
        if (!select || select[j])
            js[m++] = j;
    const uint8_t *p[2], *end[2];
    size_t count[2], consumed[2];
    uint8_t *out[2];
    for (size_t t = 0; t < m; t++) {
        p[t] = z->data + z->starts[js[t]];
        end[t] = z->data + z->starts[js[t] + 1];
        count[t] = tsl_laz_chunk_points(z, js[t]);
        out[t] = records + dest[js[t]] * rl;
    }
    if (m == 2 && dec[0] && dec[1]) {
        laz_chunk_status st[2];
        laz_decode_chunk2(dec, p, end, count, out, consumed, st);
        cs[js[0]] = st[0];
        cs[js[1]] = st[1];
        return;
    }
    for (size_t t = 0; t < m; t++) {
        if (dec[0])
            laz_decode_chunk(dec[0], p[t], end[t], count[t], out[t], &consumed[t],
                             &cs[js[t]]);
        else
            cs[js[t]].fail = LAZ_FAIL_NOMEM;
    }
}

/* Decodes the chunks with select[k] set (all when select is NULL) into
 * records, packed in file order. */
static tessel_status laz_decode(tsl_laz *z, const uint8_t *select, uint8_t *records,
                                int threads, tessel_diag *diag)
{
    size_t n = z->info.chunk_count, rl = z->info.header.record_length;
    uint64_t *dest = malloc((n + 1) * sizeof *dest);
    if (!dest) {
        tsl_diag_set(diag, z->name, 0, 0, 0, "out of memory for %zu LAZ chunks", n);
        return TESSEL_ERR_NOMEM;
    }
    dest[0] = 0;
    for (size_t k = 0; k < n; k++)
        dest[k + 1] = dest[k] + (!select || select[k] ? z->first[k + 1] - z->first[k] : 0);
    tessel_status st = TESSEL_OK;
    if (!z->data || !z->info.has_table || n < 2) {
        for (size_t k = 0; k < n && st == TESSEL_OK; k++)
            if (!select || select[k])
                st = tsl_laz_read_chunk(z, k, records + dest[k] * rl, diag);
        free(dest);
        return st;
    }
    laz_chunk_status *cs = calloc(n, sizeof *cs);
    if (!cs) {
        free(dest);
        tsl_diag_set(diag, z->name, 0, 0, 0, "out of memory for %zu LAZ chunks", n);
        return TESSEL_ERR_NOMEM;
    }
    /* Two decoders per thread, which takes the chunks two by two (decoded
     * together, laz_decode_chunk2), unless that would leave a thread idle;
     * every chunk writes its own records and its own status, so the result
     * is that of the sequential loop. */
    int nt = tsl_threads(threads);
    size_t step = n >= 2 * (size_t)nt ? 2 : 1;
#pragma omp parallel num_threads(nt)
    {
        laz_decoder *dec[2] = {
            laz_decoder_create(z->items, z->n_items, z->info.compressor == 3),
            step == 2 ? laz_decoder_create(z->items, z->n_items, z->info.compressor == 3)
                      : NULL};
#pragma omp for schedule(dynamic, 1)
        for (size_t u = 0; u < (n + step - 1) / step; u++)
            laz_decode_pair(z, dec, select, u * step, step, records, dest, cs);
        laz_decoder_destroy(dec[0]);
        laz_decoder_destroy(dec[1]);
    }
    for (size_t k = 0; k < n && st == TESSEL_OK; k++)
        if (cs[k].fail)
            st = laz_chunk_error(z, k, z->starts[k], &cs[k], diag);
    free(cs);
    free(dest);
    return st;
}

tessel_status tsl_laz_decode_all(tsl_laz *z, uint8_t *records, int threads,
                                 tessel_diag *diag)
{
    return laz_decode(z, NULL, records, threads, diag);
}

tessel_status tsl_laz_decode_chunks(tsl_laz *z, const uint8_t *select, uint8_t *records,
                                    int threads, tessel_diag *diag)
{
    return laz_decode(z, select, records, threads, diag);
}

/* Whether two closed boxes {min, max} meet. */
static bool boxes_meet(const double lo[3], const double hi[3], const double *box)
{
    for (int k = 0; k < 3; k++)
        if (hi[k] < box[k] || lo[k] > box[k + 3])
            return false;
    return true;
}

tessel_status tsl_laz_select(tsl_laz *z, const tsl_builder *b, uint8_t **select,
                             uint64_t *points, tessel_diag *diag)
{
    const tsl_las_header *zh = &z->info.header;
    /* COPC and a box: only the chunks whose node meets it (a chunk the
     * hierarchy does not list is decoded). The emission filters points. */
    size_t chunks = z->info.chunk_count;
    uint64_t n = zh->count;
    *select = NULL;
    if (b->bbox && z->info.copc && (*select = malloc(chunks ? chunks : 1)) != NULL) {
        n = 0;
        for (size_t k = 0; k < chunks; k++) {
            double lo[3], hi[3];
            (*select)[k] = !tsl_laz_chunk_bounds(z, k, lo, hi) || boxes_meet(lo, hi, b->bbox);
            n += (*select)[k] ? tsl_laz_chunk_points(z, k) : 0;
        }
    }
    *points = n;
    if (n > b->max_points && !b->bbox) {
        tsl_diag_set(diag, z->name, 0, 1, count_field(zh),
                     "LAS file has %llu points, above the limit of %llu",
                     (unsigned long long)n, (unsigned long long)b->max_points);
        return TESSEL_ERR_LIMIT;
    }
    return TESSEL_OK;
}

tessel_status tsl_laz_parse(const uint8_t *data, size_t size, const char *name,
                            const tsl_las_header *h, tsl_builder *b, tessel_diag *diag)
{
    (void)h; /* checked again by the open, which needs it in its own struct */
    tsl_laz *z;
    tessel_status st = tsl_laz_open_memory(&z, data, size, name, diag);
    if (st != TESSEL_OK)
        return st;
    const tsl_las_header *zh = &z->info.header;
    uint8_t *select;
    uint64_t n;
    st = tsl_laz_select(z, b, &select, &n, diag);
    uint8_t *records = NULL;
    if (st == TESSEL_OK && n && !(records = tsl_alloc_array((size_t)n, zh->record_length))) {
        tsl_diag_set(diag, name, 0, 0, 0, "cannot hold %llu decoded LAZ points",
                     (unsigned long long)n);
        st = TESSEL_ERR_NOMEM;
    }
    if (st == TESSEL_OK)
        st = laz_decode(z, select, records, 0, diag);
    if (st == TESSEL_OK)
        st = tsl_las_emit(records, (size_t)n, zh, -1, name, zh->point_offset, b, diag);
    free(records);
    free(select);
    tsl_laz_close(z);
    return st;
}
