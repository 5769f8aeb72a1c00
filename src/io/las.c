/* ASPRS LAS reader, versions 1.0-1.4, point data record formats 0-10
 * (ASPRS "LAS Specification 1.4 - R15", 2019: section 2.2 public header
 * block, 2.4 variable length records, 2.5 extended VLRs, 2.6 point data
 * record formats).
 *
 * Every record stores X, Y, Z as int32 at bytes 0..11; world coordinates are
 * X * scale + offset, computed in double and handed to the builder, which
 * picks the float frame. Formats 2, 3, 5, 7, 8 and 10 carry 16-bit RGB. The
 * record length may exceed the format's minimum (extra bytes): the excess is
 * skipped. Nothing is trusted before it is bounds-checked against the file
 * size: the header, every VLR and EVLR, and the point count (legacy 32-bit or
 * the 1.4 64-bit one) times the record length. LAZ (compressed point data:
 * bit 7 of the format byte) goes to the LAZ decoder (src/io/laz.c), which
 * shares the header and the emission of records with this file. */
#include "io/io.h"
#include "io/laz.h"

#include <string.h>

/* Header sizes of the versions (1.0-1.2, 1.3 adds the waveform offset, 1.4
 * adds EVLRs and the 64-bit counts). */
enum { LAS_HEADER_MIN = 227, LAS_HEADER_13 = 235, LAS_HEADER_14 = 375 };
enum { LAS_VLR_HEADER = 54, LAS_EVLR_HEADER = 60 };

static uint16_t rd_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static uint32_t rd_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}
static uint64_t rd_u64(const uint8_t *p)
{
    return (uint64_t)rd_u32(p) | ((uint64_t)rd_u32(p + 4) << 32);
}
static int32_t rd_i32(const uint8_t *p)
{
    uint32_t u = rd_u32(p);
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}
static double rd_f64(const uint8_t *p)
{
    uint64_t u = rd_u64(p);
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

/* Minimum record length of each point data record format and the byte
 * offset of its RGB triple (0: no colour). Spec tables 7-17. */
static const uint16_t las_min_length[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static const uint8_t las_rgb_offset[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

/* Walks the VLRs between the header and the point data. The count in the
 * header is only believed while records fit: some writers leave garbage
 * there (a region with no room for another record header ends the walk),
 * but a record whose stated length runs past the point data contradicts the
 * header and is an error. */
static tessel_status las_check_vlrs(const uint8_t *data, size_t header_size,
                                    size_t point_offset, uint32_t vlr_count,
                                    const char *name, tessel_diag *diag)
{
    size_t pos = header_size;
    for (uint32_t i = 0; i < vlr_count; i++) {
        if (point_offset - pos < LAS_VLR_HEADER)
            break;
        size_t len = rd_u16(data + pos + 20);
        if (len > point_offset - pos - LAS_VLR_HEADER) {
            tsl_diag_set(diag, name, 0, 1, pos,
                         "LAS variable length record %u of %u (%zu bytes) runs past the "
                         "point data at byte %zu",
                         i + 1, vlr_count, len, point_offset);
            return TESSEL_ERR_PARSE;
        }
        pos += LAS_VLR_HEADER + len;
    }
    return TESSEL_OK;
}

/* Extended VLRs (1.4) follow the point data; each must lie inside the
 * file. */
static tessel_status las_check_evlrs(const uint8_t *data, size_t size, size_t points_end,
                                     uint64_t start, uint32_t count, const char *name,
                                     tessel_diag *diag)
{
    if (count == 0)
        return TESSEL_OK;
    if (start < points_end || start > size) {
        tsl_diag_set(diag, name, 0, 1, 235,
                     "LAS header puts %u extended VLRs at byte %llu, outside the %zu "
                     "bytes after the point data (which ends at byte %zu)",
                     count, (unsigned long long)start, size - points_end, points_end);
        return TESSEL_ERR_PARSE;
    }
    size_t pos = (size_t)start;
    for (uint32_t i = 0; i < count; i++) {
        if (size - pos < LAS_EVLR_HEADER) {
            tsl_diag_set(diag, name, 0, 1, pos,
                         "LAS extended VLR %u of %u: the file ends inside its header", i + 1,
                         count);
            return TESSEL_ERR_PARSE;
        }
        uint64_t len = rd_u64(data + pos + 20);
        if (len > size - pos - LAS_EVLR_HEADER) {
            tsl_diag_set(diag, name, 0, 1, pos,
                         "LAS extended VLR %u of %u (%llu bytes) runs past the end of the "
                         "file (%zu bytes)",
                         i + 1, count, (unsigned long long)len, size);
            return TESSEL_ERR_PARSE;
        }
        pos += LAS_EVLR_HEADER + (size_t)len;
    }
    return TESSEL_OK;
}

static bool las_usable_scale(double s) { return isfinite(s) && s != 0.0; }

tessel_status tsl_las_header_parse(const uint8_t *data, size_t size, uint64_t file_size,
                                   const char *name, tsl_las_header *h, tessel_diag *diag)
{
    memset(h, 0, sizeof *h);
    if (size < 4 || memcmp(data, "LASF", 4) != 0) {
        tsl_diag_set(diag, name, 0, 1, 0, "not a LAS file: missing \"LASF\" signature");
        return TESSEL_ERR_PARSE;
    }
    if (size < LAS_HEADER_MIN) {
        tsl_diag_set(diag, name, 0, 1, size,
                     "LAS header truncated: the file has %zu bytes, the header needs %d",
                     size, LAS_HEADER_MIN);
        return TESSEL_ERR_PARSE;
    }
    unsigned major = data[24], minor = data[25];
    if (major != 1 || minor > 4) {
        tsl_diag_set(diag, name, 0, 1, 24,
                     "LAS version %u.%u is not supported (1.0 to 1.4 are)", major, minor);
        return TESSEL_ERR_UNSUPPORTED;
    }
    h->minor = minor;
    h->header_size = rd_u16(data + 94);
    h->point_offset = rd_u32(data + 96);
    h->vlr_count = rd_u32(data + 100);
    unsigned format = data[104];
    h->record_length = rd_u16(data + 105);
    h->count = rd_u32(data + 107);

    size_t needed_header = minor >= 4 ? LAS_HEADER_14 : minor == 3 ? LAS_HEADER_13
                                                                  : LAS_HEADER_MIN;
    if (h->header_size < needed_header) {
        tsl_diag_set(diag, name, 0, 1, 94,
                     "LAS %u.%u header size %zu is below the %zu bytes that version needs",
                     major, minor, h->header_size, needed_header);
        return TESSEL_ERR_PARSE;
    }
    if (h->header_size > size) {
        tsl_diag_set(diag, name, 0, 1, 94,
                     "LAS header size %zu exceeds the file size (%llu bytes)", h->header_size,
                     (unsigned long long)file_size);
        return TESSEL_ERR_PARSE;
    }
    if (h->point_offset < h->header_size || h->point_offset > file_size ||
        h->point_offset > size) {
        tsl_diag_set(diag, name, 0, 1, 96,
                     "LAS offset to point data %zu lies outside [header size %zu, file "
                     "size %llu]",
                     h->point_offset, h->header_size, (unsigned long long)file_size);
        return TESSEL_ERR_PARSE;
    }
    /* LASzip marks compressed point data with bit 7 (early versions bit 6). */
    h->compressed = (format & 0xC0) != 0;
    if (h->compressed)
        format &= 0x3F;
    if (format > 10) {
        tsl_diag_set(diag, name, 0, 1, 104,
                     "LAS point data record format %u is not supported (0 to 10 are)",
                     format);
        return TESSEL_ERR_UNSUPPORTED;
    }
    h->format = format;
    if (h->record_length < las_min_length[format]) {
        tsl_diag_set(diag, name, 0, 1, 105,
                     "LAS point record length %zu is shorter than the %u bytes of point "
                     "format %u",
                     h->record_length, las_min_length[format], format);
        return TESSEL_ERR_PARSE;
    }
    if (minor >= 4) {
        /* The 64-bit count is authoritative in 1.4; the legacy field is 0
         * for formats 6-10 and for more than 2^32-1 points. */
        uint64_t count64 = rd_u64(data + 247);
        if (count64 != 0 || format >= 6)
            h->count = count64;
        h->evlr_start = rd_u64(data + 235);
        h->evlr_count = rd_u32(data + 243);
    }
    for (int k = 0; k < 3; k++) {
        h->scale[k] = rd_f64(data + 131 + 8 * k);
        h->offset[k] = rd_f64(data + 155 + 8 * k);
        h->max[k] = rd_f64(data + 179 + 16 * k);
        h->min[k] = rd_f64(data + 187 + 16 * k);
        if (!las_usable_scale(h->scale[k]) || !isfinite(h->offset[k])) {
            tsl_diag_set(diag, name, 0, 1, (uint64_t)(131 + 8 * k),
                         "LAS %c scale factor %g / offset %g is not usable", "XYZ"[k],
                         h->scale[k], h->offset[k]);
            return TESSEL_ERR_PARSE;
        }
    }
    return las_check_vlrs(data, h->header_size, h->point_offset, h->vlr_count, name, diag);
}

const uint8_t *tsl_las_find_vlr(const uint8_t *data, const tsl_las_header *h,
                                const char *user_id, unsigned record_id, size_t *length)
{
    /* The same walk as las_check_vlrs, which has accepted it. */
    size_t pos = h->header_size, ulen = strlen(user_id);
    for (uint32_t i = 0; i < h->vlr_count; i++) {
        if (h->point_offset - pos < LAS_VLR_HEADER)
            break;
        size_t len = rd_u16(data + pos + 20);
        const uint8_t *uid = data + pos + 2;
        if (rd_u16(data + pos + 18) == record_id && ulen <= 16 &&
            memcmp(uid, user_id, ulen) == 0 && (ulen == 16 || uid[ulen] == 0)) {
            *length = len;
            return data + pos + LAS_VLR_HEADER;
        }
        pos += LAS_VLR_HEADER + len;
    }
    *length = 0;
    return NULL;
}

static void las_world(const uint8_t *rec, const tsl_las_header *h, double xyz[3])
{
    for (int k = 0; k < 3; k++)
        xyz[k] = (double)rd_i32(rec + 4 * k) * h->scale[k] + h->offset[k];
}

static bool las_in_box(const double xyz[3], const double *box)
{
    return xyz[0] >= box[0] && xyz[1] >= box[1] && xyz[2] >= box[2] && xyz[0] <= box[3] &&
           xyz[1] <= box[4] && xyz[2] <= box[5];
}

bool tsl_las_has_rgb(const tsl_las_header *h) { return las_rgb_offset[h->format] != 0; }

int tsl_las_rgb_shift(const uint8_t *records, size_t n, const tsl_las_header *h)
{
    unsigned rgb_at = las_rgb_offset[h->format];
    if (!rgb_at)
        return 0;
    for (size_t i = 0; i < n; i++) {
        const uint8_t *c = records + i * h->record_length + rgb_at;
        if (rd_u16(c) > 255 || rd_u16(c + 2) > 255 || rd_u16(c + 4) > 255)
            return 8;
    }
    return 0;
}

tessel_status tsl_las_emit(const uint8_t *records, size_t n, const tsl_las_header *h,
                           int rgb_shift, const char *name, uint64_t at, tsl_builder *b,
                           tessel_diag *diag)
{
    size_t record_length = h->record_length;
    size_t kept = n;
    if (b->bbox) {
        kept = 0;
        for (size_t i = 0; i < n; i++) {
            double xyz[3];
            las_world(records + i * record_length, h, xyz);
            kept += las_in_box(xyz, b->bbox);
        }
    }
    if (kept > b->max_points) {
        tsl_diag_set(diag, name, 0, 1, h->minor >= 4 ? 247 : 107,
                     "LAS file has %zu points%s, above the limit of %llu", kept,
                     b->bbox ? " in the bounding box" : "",
                     (unsigned long long)b->max_points);
        return TESSEL_ERR_LIMIT;
    }
    const uint8_t *rec = records;
    unsigned rgb_at = las_rgb_offset[h->format];
    if (rgb_shift < 0)
        rgb_shift = tsl_las_rgb_shift(records, n, h);
    /* The records' numbers in the file, for messages (a streamed read
     * emits a window at a time). */
    uint64_t first = at >= h->point_offset ? (at - h->point_offset) / record_length : 0;
    tessel_status st = tsl_builder_attributes(b, 0, rgb_at != 0);
    if (st == TESSEL_OK)
        st = tsl_builder_reserve(b, kept, 0);
    if (st != TESSEL_OK) {
        tsl_diag_set(diag, name, 0, 0, 0, "cannot hold %zu LAS points: %s", kept,
                     tessel_status_str(st));
        return st;
    }
    for (size_t i = 0; i < n; i++, rec += record_length) {
        double xyz[3];
        las_world(rec, h, xyz);
        if (b->bbox && !las_in_box(xyz, b->bbox))
            continue;
        uint8_t rgb[3];
        if (rgb_at) {
            for (int k = 0; k < 3; k++)
                rgb[k] = (uint8_t)(rd_u16(rec + rgb_at + 2 * k) >> rgb_shift);
        }
        st = tsl_builder_point(b, xyz, NULL, rgb_at ? rgb : NULL);
        if (st != TESSEL_OK) {
            tsl_diag_set(diag, name, 0, 1, at + (uint64_t)(rec - records),
                         "LAS point %llu: %s", (unsigned long long)(first + i),
                         tessel_status_str(st));
            return st;
        }
    }
    return TESSEL_OK;
}

tessel_status tsl_las_check(const uint8_t *data, size_t size, const char *name,
                            tsl_las_header *h, size_t *n, tessel_diag *diag)
{
    *n = 0;
    tessel_status st = tsl_las_header_parse(data, size, size, name, h, diag);
    if (st != TESSEL_OK || h->compressed)
        return st;
    size_t available = size - h->point_offset;
    if (h->count > available / h->record_length) {
        tsl_diag_set(diag, name, 0, 1, h->point_offset,
                     "LAS header announces %llu points of %zu bytes from byte %zu, but "
                     "only %zu bytes follow (room for %zu points)",
                     (unsigned long long)h->count, h->record_length, h->point_offset,
                     available, available / h->record_length);
        return TESSEL_ERR_PARSE;
    }
    size_t points_end = h->point_offset + (size_t)h->count * h->record_length;
    if (h->minor >= 4) {
        st = las_check_evlrs(data, size, points_end, h->evlr_start, h->evlr_count, name, diag);
        if (st != TESSEL_OK)
            return st;
    }
    *n = (size_t)h->count;
    return TESSEL_OK;
}

tessel_status tsl_parse_las(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag)
{
    (void)want_faces;
    tsl_las_header h;
    size_t n;
    tessel_status st = tsl_las_check(data, size, name, &h, &n, diag);
    if (st != TESSEL_OK)
        return st;
    if (h.compressed)
        return tsl_laz_parse(data, size, name, &h, b, diag);
    return tsl_las_emit(data + h.point_offset, n, &h, -1, name, h.point_offset, b, diag);
}
