/* Item decoders of LAZ chunks, private to src/io/laz*.c.
 *
 * A LAZ point is a sequence of items (the "laszip encoded" VLR lists their
 * type, size and version) whose concatenation is the LAS point record. The
 * first point of a chunk is stored raw; every later point is predicted from
 * the one before. Two families:
 *  - pointwise (compressors 1 and 2; laz_pointwise.c): all items of a point
 *    in one arithmetic stream, items POINT10, GPSTIME11, RGB12, WAVEPACKET13
 *    and BYTE, versions 1 and 2 (WAVEPACKET13: 1), point formats 0-5;
 *  - layered (compressor 3; laz_layered.c): after the raw point, the chunk's
 *    point count and the byte size of every layer, then each layer as its own
 *    stream (POINT14: XY with returns and channel, Z, classification, flags,
 *    intensity, scan angle, user data, point source, GPS time; RGB; NIR;
 *    wave packet; one per extra byte), items POINT14, RGB14, RGBNIR14,
 *    WAVEPACKET14, BYTE14, versions 3 and 4 (2: as 3), point formats 6-10.
 * A decoder object holds every model of its items; it is reused chunk after
 * chunk (each chunk starts from fresh models) by one thread at a time. */
#ifndef TESSEL_IO_LAZ_ITEMS_H
#define TESSEL_IO_LAZ_ITEMS_H

#include "io/laz_coder.h"

enum laz_item_type {
    LAZ_BYTE = 0,
    LAZ_POINT10 = 6,
    LAZ_GPSTIME11 = 7,
    LAZ_RGB12 = 8,
    LAZ_WAVEPACKET13 = 9,
    LAZ_POINT14 = 10,
    LAZ_RGB14 = 11,
    LAZ_RGBNIR14 = 12,
    LAZ_WAVEPACKET14 = 13,
    LAZ_BYTE14 = 14
};

enum { LAZ_MAX_ITEMS = 16 };

/* A layered chunk whose layer sizes do not fit in its bytes. */
enum { LAZ_FAIL_LAYOUT = 8 };

typedef struct laz_item {
    uint16_t type, size, version;
} laz_item;

/* What a failed chunk reports: its LAZ_FAIL_* flags, the first point that
 * could not be decoded (index in the chunk) and the byte offset, from the
 * chunk's start, of the data that ran out or did not fit. */
typedef struct laz_chunk_status {
    int fail;
    size_t point;
    size_t at;
} laz_chunk_status;

typedef struct laz_decoder laz_decoder;

/* A decoder for the items (already validated by laz.c: known types and
 * versions, pointwise or layered as `layered` says). NULL: no memory. */
laz_decoder *laz_decoder_create(const laz_item *items, unsigned n_items, int layered);
void laz_decoder_destroy(laz_decoder *dec);

/* Decodes the `count` points of the chunk [p, end) into out (count records,
 * record_length = the items' total size apart). *consumed: the bytes the
 * chunk used (pointwise: up to the arithmetic decoder's last read; layered:
 * up to the end of its last layer). Returns 0 or fills st and returns its
 * fail flags. Work is bounded by count and the flags stop it early. */
int laz_decode_chunk(laz_decoder *dec, const uint8_t *p, const uint8_t *end, size_t count,
                     uint8_t *out, size_t *consumed, laz_chunk_status *st);

/* Two chunks of one file, each with its own decoder: the same results as
 * laz_decode_chunk on each, faster for formats 0-3 (version 2 items), whose
 * two streams are decoded together, in lockstep symbol by symbol. */
void laz_decode_chunk2(laz_decoder *dec[2], const uint8_t *p[2], const uint8_t *end[2],
                       const size_t count[2], uint8_t *out[2], size_t consumed[2],
                       laz_chunk_status st[2]);

/* RGB12 v2 and RGB14: the colour c from the last one (byte_used: 128
 * symbols, diff: six models of 256), in steps so that two chunks can
 * alternate symbol by symbol: which bytes changed (a symbol of byte_used),
 * the changed bytes' symbols in the reference's order (laz_rgb_byte for
 * j = 0..5), then the colour from them (laz_rgb_combine). Here and below,
 * inline: the callers in both item files keep their decoder in registers
 * through them. */
static const uint8_t laz_rgb_order[6] = {0, 1, 2, 4, 3, 5};

/* The j-th changed-byte symbol of colour code sym into corr (0: unchanged;
 * green and blue only when the code says they differ from red). */
LAZ_INLINE void laz_rgb_byte(laz_dec *d, laz_model diff_model[6], uint32_t sym, int j,
                             uint32_t corr[6])
{
    uint32_t b = laz_rgb_order[j];
    corr[b] = (sym & (1u << b)) && (b < 2 || (sym & 64))
                  ? laz_decode_symbol(d, &diff_model[b])
                  : 0;
}

LAZ_INLINE void laz_rgb_combine(uint32_t sym, const uint32_t corr[6], const uint16_t last[3],
                                uint16_t c[3])
{
    uint32_t r, g, b;
    r = ((corr[0] + (last[0] & 0xFF)) & 0xFF) | (((corr[1] + (last[0] >> 8)) & 0xFF) << 8);
    if (sym & 64) {
        int32_t diff = (int32_t)(r & 0xFF) - (int32_t)(last[0] & 0xFF);
        g = sym & 4 ? (corr[2] + laz_clamp8(diff + (int32_t)(last[1] & 0xFF))) & 0xFF
                    : last[1] & 0xFFu;
        if (sym & 16) {
            int32_t d2 = (diff + ((int32_t)(g & 0xFF) - (int32_t)(last[1] & 0xFF))) / 2;
            b = (corr[4] + laz_clamp8(d2 + (int32_t)(last[2] & 0xFF))) & 0xFF;
        } else {
            b = last[2] & 0xFFu;
        }
        diff = (int32_t)(r >> 8) - (int32_t)(last[0] >> 8);
        g |= sym & 8 ? ((corr[3] + laz_clamp8(diff + (int32_t)(last[1] >> 8))) & 0xFF) << 8
                     : last[1] & 0xFF00u;
        if (sym & 32) {
            int32_t d2 = (diff + ((int32_t)(g >> 8) - (int32_t)(last[1] >> 8))) / 2;
            b |= ((corr[5] + laz_clamp8(d2 + (int32_t)(last[2] >> 8))) & 0xFF) << 8;
        } else {
            b |= last[2] & 0xFF00u;
        }
    } else {
        g = b = r;
    }
    c[0] = (uint16_t)r;
    c[1] = (uint16_t)g;
    c[2] = (uint16_t)b;
}

LAZ_INLINE void laz_rgb_decode(laz_dec *d, laz_model *byte_used, laz_model diff_model[6],
                               const uint16_t last[3], uint16_t c[3])
{
    uint32_t sym = laz_decode_symbol(d, byte_used), corr[6];
    for (int j = 0; j < 6; j++)
        laz_rgb_byte(d, diff_model, sym, j, corr);
    laz_rgb_combine(sym, corr, last, c);
}

/* GPS time difference of GPSTIME11 v2 and POINT14, for the codes 0 and
 * 2..510: a multiple (-10..500) of the sequence's last difference plus a
 * corrector (ic: 32 bits, 9 contexts); updates the last difference after
 * four extreme multiples in a row. */
enum { LAZ_GPS_MULTI = 500, LAZ_GPS_MULTI_MINUS = -10 };
LAZ_INLINE int32_t laz_gps_multi_diff(laz_ic *ic, laz_dec *d, int32_t *last_diff,
                                      int32_t *extreme, uint32_t multi)
{
    int32_t diff;
    uint32_t last = (uint32_t)*last_diff;
    if (multi == 0) {
        diff = laz_ic_decompress(ic, d, 0, 7);
        if (++*extreme > 3) {
            *last_diff = diff;
            *extreme = 0;
        }
    } else if (multi < LAZ_GPS_MULTI) {
        diff = laz_ic_decompress(ic, d, laz_i32(multi * last), multi < 10 ? 2 : 3);
    } else if (multi == LAZ_GPS_MULTI) {
        diff = laz_ic_decompress(ic, d, laz_i32(LAZ_GPS_MULTI * last), 4);
        if (++*extreme > 3) {
            *last_diff = diff;
            *extreme = 0;
        }
    } else {
        int32_t mm = LAZ_GPS_MULTI - (int32_t)multi; /* -1..-10 */
        if (mm > LAZ_GPS_MULTI_MINUS) {
            diff = laz_ic_decompress(ic, d, laz_i32((uint32_t)mm * last), 5);
        } else {
            diff = laz_ic_decompress(ic, d, laz_i32((uint32_t)LAZ_GPS_MULTI_MINUS * last), 6);
            if (++*extreme > 3) {
                *last_diff = diff;
                *extreme = 0;
            }
        }
    }
    return diff;
}

/* Layered decoding (laz_layered.c), called by laz_decode_chunk. */
typedef struct laz_layered laz_layered;
laz_layered *laz_layered_create(const laz_item *items, unsigned n_items);
void laz_layered_destroy(laz_layered *ly);
int laz_layered_chunk(laz_layered *ly, const uint8_t *p, const uint8_t *end, size_t count,
                      uint8_t *out, size_t record_length, size_t *consumed,
                      laz_chunk_status *st);

#endif /* TESSEL_IO_LAZ_ITEMS_H */
