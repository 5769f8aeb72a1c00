/* The entropy decoder of LAZ, private to src/io/laz*.c: a range decoder with
 * adaptive symbol and bit models, and the integer decompressor that codes a
 * value as a prediction plus a corrector.
 *
 * Format description: the LASzip compressor (Isenburg, "LASzip: lossless
 * compression of LiDAR data", Photogrammetric Engineering & Remote Sensing
 * 79(2), 2013), whose coder is Amir Said's FastAC ("Introduction to
 * Arithmetic Coding - Theory and Practice", HP Labs report HPL-2004-76):
 * 32-bit range, renormalisation a byte at a time below 2^24, symbol models
 * whose cumulative distribution is rebuilt from counts every update cycle
 * (15-bit probabilities, a lookup table for more than 16 symbols), bit models
 * with 13-bit probabilities. The behaviour here matches the reference decoder
 * (LASzip's arithmeticdecoder, arithmeticmodel and integercompressor) bit for
 * bit, which a LAZ reader must: the streams carry no redundancy.
 *
 * Integer decompressor (LASzip's IntegerCompressor): a corrector c = real -
 * pred, folded into [corr_min, corr_max] of a `bits`-wide range, is coded as
 * k (its bit length, one adaptive model per context), then c itself: k = 0
 * means c is 0 or 1 (a bit model), k < 32 gives the offset inside
 * [-(2^k - 1), -2^(k-1)] or [2^(k-1) + 1, 2^k] with one model per k (the high
 * bits_high bits through the model, the rest raw), k = 32 means corr_min.
 *
 * Hostile input: a read past the end of the stream yields zeros and raises
 * LAZ_FAIL_DATA in *fail; impossible raw values raise LAZ_FAIL_CORRUPT. Every
 * array index a decoded symbol reaches is bounded by its model's alphabet, so
 * a corrupt stream gives wrong values and a flag, never an out-of-bounds
 * access; callers stop at the first flagged point. */
#ifndef TESSEL_IO_LAZ_CODER_H
#define TESSEL_IO_LAZ_CODER_H

#include <stddef.h>
#include <stdint.h>

/* Forced inlining keeps the decoder's state in registers; under the
 * sanitizers it only makes clang take many minutes over the pair's loop. */
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LAZ_NO_FORCED_INLINE 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define LAZ_NO_FORCED_INLINE 1
#endif
#if defined(__GNUC__) && !defined(LAZ_NO_FORCED_INLINE)
#define LAZ_INLINE static inline __attribute__((always_inline))
#else
#define LAZ_INLINE static inline
#endif

enum {
    LAZ_FAIL_DATA = 1,     /* the stream ended before the points did */
    LAZ_FAIL_CORRUPT = 2,  /* a value the encoder cannot have written */
    LAZ_FAIL_NOMEM = 4
};

enum { LAZ_MIN_LENGTH = 0x01000000u, LAZ_BM_SHIFT = 13, LAZ_DM_SHIFT = 15 };

/* Entries of UINT32_MAX after a model's distribution, so that a search may
 * read up to seven past the last symbol. */
enum { LAZ_DIST_PAD = 7 };

typedef struct laz_dec {
    const uint8_t *p, *end;
    uint32_t value, length;
    int *fail;             /* flags of the chunk being decoded */
} laz_dec;

typedef struct laz_bitmodel {
    uint32_t bit_0_prob, bit_0_count, bit_count, update_cycle, until_update;
} laz_bitmodel;

typedef struct laz_model {
    uint32_t *dist;        /* cumulative distribution, `symbols` (+ LAZ_DIST_PAD) entries */
    uint32_t *count;       /* symbol counts, `symbols` entries */
    uint16_t *table;       /* decoder table (table_size + 2), NULL for <= 16 symbols */
    uint32_t symbols, last_symbol, table_size, table_shift;
    uint32_t total_count, update_cycle, until_update;
} laz_model;

typedef struct laz_ic {
    uint32_t contexts, bits_high, corr_bits, corr_range;
    int32_t corr_min;
    uint32_t k;            /* k of the last decompressed value */
    laz_model *mbits;      /* per context, corr_bits + 1 symbols */
    laz_bitmodel corr0;
    laz_model corr[32];    /* corr[k - 1] for k = 1..corr_bits, made on first use */
    uint8_t corr_ready[32];
} laz_ic;

/* ---- models (laz_coder.c) ---- */

/* Allocates a model of 2..2048 symbols; 0 or -1 (no memory). */
int laz_model_alloc(laz_model *m, uint32_t symbols);
void laz_model_free(laz_model *m);
/* Resets to the uniform distribution (the state of a new chunk). */
void laz_model_init(laz_model *m);
void laz_model_update(laz_model *m);
void laz_bitmodel_init(laz_bitmodel *m);
void laz_bitmodel_update(laz_bitmodel *m);

/* Integer decompressor of `bits` bits (range 0: 2^bits; bits 32: any int),
 * `contexts` contexts. 0 or -1. */
int laz_ic_alloc(laz_ic *ic, uint32_t bits, uint32_t contexts, uint32_t bits_high,
                 uint32_t range);
void laz_ic_free(laz_ic *ic);
void laz_ic_init(laz_ic *ic);

/* Starts decoding the bytes [p, end). */
void laz_dec_init(laz_dec *d, const uint8_t *p, const uint8_t *end, int *fail);

/* ---- the decoder (inline: the item decoders call these per field) ---- */

/* The last of the bounds dist[sym..n-1] at or below dv (dist[sym] is): the
 * rare wide bin of a decoder table, out of line to keep the inlined symbol
 * decoder short. */
uint32_t laz_bisect(const uint32_t *dist, uint32_t sym, uint32_t n, uint32_t dv);

/* laz_lazy_model's first use in a chunk: m allocated if need be and reset;
 * NULL and LAZ_FAIL_NOMEM in *fail when it cannot be. */
laz_model *laz_model_first_use(laz_model *m, uint8_t *ready, uint32_t symbols, int *fail);

LAZ_INLINE uint32_t laz_byte(laz_dec *d)
{
    if (d->p < d->end)
        return *d->p++;
    *d->fail |= LAZ_FAIL_DATA;
    return 0;
}

/* Renormalisation a byte at a time: the stream's last bytes and corrupt
 * states (the encoder never leaves a zero range). */
LAZ_INLINE void laz_renorm_slow(laz_dec *d)
{
    if (d->length >= LAZ_MIN_LENGTH)
        return;
    if (d->length == 0) { /* only a corrupt state gets here; never loop on it */
        *d->fail |= LAZ_FAIL_CORRUPT;
        d->length = 0xFFFFFFFFu;
        return;
    }
    do {
        d->value = (d->value << 8) | laz_byte(d);
    } while ((d->length <<= 8) < LAZ_MIN_LENGTH);
}

/* Leading zero bits of x > 0. */
static inline unsigned laz_clz(uint32_t x)
{
#if defined(__GNUC__)
    return (unsigned)__builtin_clz(x);
#else
    unsigned n = 0;
    while (!(x & 0x80000000u)) {
        x <<= 1;
        ++n;
    }
    return n;
#endif
}

/* Brings the range back to at least 2^24 after every symbol: the bytes it
 * needs (0 to 3, from the range's leading zeros) shifted in at once from a
 * 4-byte read, so that whether a symbol renormalises, a coin toss, costs no
 * branch. Within 4 bytes of the stream's end, byte by byte. */
LAZ_INLINE void laz_renorm(laz_dec *d)
{
    if (d->length == 0 || d->end - d->p < 4) {
        laz_renorm_slow(d);
        return;
    }
    unsigned shift = (laz_clz(d->length) >> 3) << 3; /* 0, 8, 16 or 24 */
    uint64_t next = (uint64_t)d->p[0] << 24 | (uint64_t)d->p[1] << 16 |
                    (uint64_t)d->p[2] << 8 | d->p[3];
    d->value = (uint32_t)(((uint64_t)d->value << shift) | (next >> (32 - shift)));
    d->length <<= shift;
    d->p += shift >> 3;
}

LAZ_INLINE uint32_t laz_decode_bit(laz_dec *d, laz_bitmodel *m)
{
    uint32_t x = m->bit_0_prob * (d->length >> LAZ_BM_SHIFT);
    uint32_t sym = d->value >= x;
    if (sym == 0) {
        d->length = x;
        ++m->bit_0_count;
    } else {
        d->value -= x;
        d->length -= x;
    }
    laz_renorm(d);
    if (--m->until_update == 0)
        laz_bitmodel_update(m);
    return sym;
}

LAZ_INLINE uint32_t laz_decode_symbol(laz_dec *d, laz_model *m)
{
    uint32_t sym, x, y = d->length;
    if (m->table) {
        uint32_t dv = d->value / (d->length >>= LAZ_DM_SHIFT);
        uint32_t t = dv >> m->table_shift;
        if (t > m->table_size) /* value <= length keeps t in range; belt and braces */
            t = m->table_size;
        const uint32_t *dist = m->dist;
        sym = m->table[t];
        uint32_t n = m->table[t + 1] + 1;
        if (n - sym <= 8) { /* the usual narrow bin: count, without branches */
            const uint32_t *q = dist + sym;
            sym += (q[1] <= dv) + (q[2] <= dv) + (q[3] <= dv) + (q[4] <= dv) +
                   (q[5] <= dv) + (q[6] <= dv) + (q[7] <= dv);
        } else {
            sym = laz_bisect(dist, sym, n, dv);
        }
        x = dist[sym] * d->length;
        if (sym != m->last_symbol)
            y = m->dist[sym + 1] * d->length;
    } else {
        x = sym = 0;
        uint32_t n = m->symbols;
        d->length >>= LAZ_DM_SHIFT;
        uint32_t k = n >> 1;
        do {
            uint32_t z = d->length * m->dist[k];
            if (z > d->value) {
                n = k;
                y = z;
            } else {
                sym = k;
                x = z;
            }
        } while ((k = (sym + n) >> 1) != sym);
    }
    d->value -= x;
    d->length = y - x;
    laz_renorm(d);
    ++m->count[sym];
    if (--m->until_update == 0)
        laz_model_update(m);
    return sym;
}

/* Raw bits (1..19) at a uniform probability. */
LAZ_INLINE uint32_t laz_read_bits_short(laz_dec *d, uint32_t bits)
{
    uint32_t sym = d->value / (d->length >>= bits);
    d->value -= d->length * sym;
    laz_renorm(d);
    if (sym >> bits) {
        *d->fail |= LAZ_FAIL_CORRUPT;
        sym &= (1u << bits) - 1;
    }
    return sym;
}

/* Raw bits, 1..32 (more than 19 as a 16-bit low part first). */
LAZ_INLINE uint32_t laz_read_bits(laz_dec *d, uint32_t bits)
{
    if (bits > 19) {
        uint32_t lo = laz_read_bits_short(d, 16);
        return (laz_read_bits_short(d, bits - 16) << 16) | lo;
    }
    return laz_read_bits_short(d, bits);
}

LAZ_INLINE uint32_t laz_read_int(laz_dec *d)
{
    uint32_t lo = laz_read_bits_short(d, 16);
    return (laz_read_bits_short(d, 16) << 16) | lo;
}

LAZ_INLINE uint64_t laz_read_int64(laz_dec *d)
{
    uint64_t lo = laz_read_int(d);
    return ((uint64_t)laz_read_int(d) << 32) | lo;
}

/* A model made and reset on its first use in a chunk (*ready cleared when
 * the chunk begins). NULL when it cannot be allocated (LAZ_FAIL_NOMEM). */
LAZ_INLINE laz_model *laz_lazy_model(laz_dec *d, laz_model *m, uint8_t *ready,
                                        uint32_t symbols)
{
    return *ready ? m : laz_model_first_use(m, ready, symbols, d->fail);
}

/* Two's complement of a 32-bit pattern, without relying on the conversion
 * of out-of-range values. */
static inline int32_t laz_i32(uint32_t u)
{
    return u <= 0x7FFFFFFFu ? (int32_t)u : -(int32_t)(~u) - 1;
}

/* The corrector once its bit length k (a symbol of ic->mbits[context]) is
 * decoded, in two steps: the symbol that k selects (laz_ic_high: a bit for
 * k = 0, the high bits for k < 32), then the low bits and the sign
 * (laz_ic_low). */
LAZ_INLINE uint32_t laz_ic_high(laz_ic *ic, laz_dec *d, uint32_t k)
{
    ic->k = k;
    if (k == 0)
        return laz_decode_bit(d, &ic->corr0);
    if (k >= 32)
        return 0;
    laz_model *m = laz_lazy_model(d, &ic->corr[k - 1], &ic->corr_ready[k - 1],
                                  1u << (k <= ic->bits_high ? k : ic->bits_high));
    return m ? laz_decode_symbol(d, m) : 0; /* no model: the chunk fails (NOMEM) */
}

LAZ_INLINE int32_t laz_ic_low(laz_ic *ic, laz_dec *d, uint32_t k, uint32_t c)
{
    if (k == 0)
        return (int32_t)c;
    if (k >= 32)
        return ic->corr_min;
    if (k > ic->bits_high) {
        uint32_t k1 = k - ic->bits_high;
        c = (c << k1) | laz_read_bits(d, k1);
    }
    /* c >= 2^(k-1): the positive interval, else the negative one (a select,
     * not a branch: the sign is a coin toss) */
    uint32_t adj = c >= (1u << (k - 1)) ? 1u : 1u - (1u << k);
    return laz_i32(c + adj);
}

LAZ_INLINE int32_t laz_ic_corrector(laz_ic *ic, laz_dec *d, uint32_t context)
{
    uint32_t k = laz_decode_symbol(d, &ic->mbits[context]);
    return laz_ic_low(ic, d, k, laz_ic_high(ic, d, k));
}

/* The value of prediction pred plus corrector corr, folded into range. */
LAZ_INLINE int32_t laz_ic_value(const laz_ic *ic, int32_t pred, int32_t corr)
{
    uint32_t real = (uint32_t)pred + (uint32_t)corr;
    if (laz_i32(real) < 0)
        real += ic->corr_range;
    else if (real >= ic->corr_range && ic->corr_range)
        real -= ic->corr_range;
    return laz_i32(real);
}

/* The value predicted by pred, in [0, 2^bits) for bits < 32 (callers cast),
 * any int32 for 32 bits. Sums wrap as the reference's do. */
LAZ_INLINE int32_t laz_ic_decompress(laz_ic *ic, laz_dec *d, int32_t pred,
                                        uint32_t context)
{
    return laz_ic_value(ic, pred, laz_ic_corrector(ic, d, context));
}

/* Two values from two independent streams (a: ia, da; b: ib, db) in
 * lockstep: both bit lengths, both high parts, then both low parts, so
 * that the core decodes the two symbol chains at once and a mispredicted
 * branch on the one stream's k (resolved when its symbol is) does not hold
 * back the other's symbol. */
LAZ_INLINE void laz_ic_decompress2(laz_ic *ia, laz_dec *da, int32_t pa, uint32_t ca,
                                   laz_ic *ib, laz_dec *db, int32_t pb, uint32_t cb,
                                   int32_t out[2])
{
    uint32_t ka = laz_decode_symbol(da, &ia->mbits[ca]);
    uint32_t kb = laz_decode_symbol(db, &ib->mbits[cb]);
    uint32_t ha = laz_ic_high(ia, da, ka);
    uint32_t hb = laz_ic_high(ib, db, kb);
    out[0] = laz_ic_value(ia, pa, laz_ic_low(ia, da, ka, ha));
    out[1] = laz_ic_value(ib, pb, laz_ic_low(ib, db, kb, hb));
}

/* LASzip's five-value streaming median of coordinate differences. */
typedef struct laz_median5 {
    int32_t v[5];
    int high;
} laz_median5;

static inline void laz_median5_init(laz_median5 *m)
{
    m->v[0] = m->v[1] = m->v[2] = m->v[3] = m->v[4] = 0;
    m->high = 1;
}

static inline void laz_median5_add(laz_median5 *m, int32_t v)
{
    int32_t *a = m->v;
    if (m->high) {
        if (v < a[2]) {
            a[4] = a[3];
            a[3] = a[2];
            if (v < a[0]) {
                a[2] = a[1];
                a[1] = a[0];
                a[0] = v;
            } else if (v < a[1]) {
                a[2] = a[1];
                a[1] = v;
            } else {
                a[2] = v;
            }
        } else {
            if (v < a[3]) {
                a[4] = a[3];
                a[3] = v;
            } else {
                a[4] = v;
            }
            m->high = 0;
        }
    } else {
        if (a[2] < v) {
            a[0] = a[1];
            a[1] = a[2];
            if (a[4] < v) {
                a[2] = a[3];
                a[3] = a[4];
                a[4] = v;
            } else if (a[3] < v) {
                a[2] = a[3];
                a[3] = v;
            } else {
                a[2] = v;
            }
        } else {
            if (a[1] < v) {
                a[0] = a[1];
                a[1] = v;
            } else {
                a[0] = v;
            }
            m->high = 1;
        }
    }
}

/* Bytes of a record, little-endian. */
static inline uint16_t laz_rd16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static inline uint32_t laz_rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}
static inline uint64_t laz_rd64(const uint8_t *p)
{
    return (uint64_t)laz_rd32(p) | ((uint64_t)laz_rd32(p + 4) << 32);
}
static inline void laz_wr16(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static inline void laz_wr32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}
static inline void laz_wr64(uint8_t *p, uint64_t v)
{
    laz_wr32(p, (uint32_t)v);
    laz_wr32(p + 4, (uint32_t)(v >> 32));
}

/* U8_CLAMP of the reference. */
static inline uint32_t laz_clamp8(int32_t v) { return v < 0 ? 0u : v > 255 ? 255u : (uint32_t)v; }

#endif /* TESSEL_IO_LAZ_CODER_H */
