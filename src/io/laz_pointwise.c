/* Pointwise LAZ items (compressors 1 and 2, point formats 0-5): POINT10,
 * GPSTIME11, RGB12 and BYTE versions 1 and 2, WAVEPACKET13 version 1, and
 * the dispatch of a chunk to them or to the layered decoder.
 *
 * Format description: Isenburg, "LASzip: lossless compression of LiDAR
 * data" (PE&RS 79(2), 2013), sections on the point10, gpstime and rgb
 * predictors, and the reference decoder's item readers (LASzip's
 * lasreaditemcompressed_v1 and _v2), which fix the bit-exact behaviour:
 *  - POINT10 v2: a 6-bit "changed" symbol; the return/flags byte,
 *    classification and user data each through a model chosen by their last
 *    value; intensity predicted per return context m (from the number of
 *    returns n and the return number r); X and Y differences predicted by the
 *    streaming median of the last five differences of context m, their
 *    contexts sharpened by the k of X; Z predicted by the last Z of return
 *    level l. v1: X and Y by the median of three, fewer contexts, the changed
 *    fields after the coordinates.
 *  - GPSTIME11 v2: four interleaved time sequences; a difference coded as a
 *    multiple (-10..500) of the sequence's last difference plus a corrector,
 *    or a full 64-bit value; v1: one sequence, multiples 0..509.
 *  - RGB12 v2: which of the six colour bytes changed, each byte as a
 *    difference from the last value, green and blue predicted from red's
 *    change; v1: integer corrections per byte.
 *  - BYTE: each extra byte as a difference from its last value.
 *  - WAVEPACKET13: descriptor index, offset (same, last + size, last +
 *    32-bit difference, or raw), size, return point and x y z as integers.
 * Arithmetic that overflows in the reference wraps here too (done on
 * unsigned integers). */
#include "io/laz_items.h"

#include <stdlib.h>
#include <string.h>

/* Return map and level of LASzip's point10 contexts (laszip_common_v2):
 * n and r are three bits each, invalid pairs mapped to contexts of their
 * own. */
static const uint8_t p10_return_map[8][8] = {
    {15, 14, 13, 12, 11, 10, 9, 8}, {14, 0, 1, 3, 6, 10, 10, 9},
    {13, 1, 2, 4, 7, 11, 11, 10},   {12, 3, 4, 5, 8, 12, 12, 11},
    {11, 6, 7, 8, 9, 13, 13, 12},   {10, 10, 11, 12, 13, 14, 14, 13},
    {9, 10, 11, 12, 13, 14, 15, 14}, {8, 9, 10, 11, 12, 13, 14, 15}};
static const uint8_t p10_return_level[8][8] = {
    {0, 1, 2, 3, 4, 5, 6, 7}, {1, 0, 1, 2, 3, 4, 5, 6}, {2, 1, 0, 1, 2, 3, 4, 5},
    {3, 2, 1, 0, 1, 2, 3, 4}, {4, 3, 2, 1, 0, 1, 2, 3}, {5, 4, 3, 2, 1, 0, 1, 2},
    {6, 5, 4, 3, 2, 1, 0, 1}, {7, 6, 5, 4, 3, 2, 1, 0}};

/* The fields of a point10 record (20 bytes). */
typedef struct p10_point {
    uint32_t x, y, z;      /* int32 bit patterns: sums wrap */
    uint16_t intensity;
    uint8_t bits;          /* return number 0-2, number of returns 3-5, scan direction 6, edge 7 */
    uint8_t cls, sar, ud;
    uint16_t psid;
} p10_point;

typedef struct p10_state {
    int version;
    p10_point last;
    /* v2 */
    uint16_t last_intensity[16];
    int32_t last_height[8];
    laz_median5 xdiff[16], ydiff[16];
    laz_model scan_angle[2];
    /* v1 */
    int32_t last_x_diff[3], last_y_diff[3];
    int last_incr;
    laz_ic ic_sar;
    /* both */
    laz_model changed;
    laz_ic ic_intensity, ic_psid, ic_dx, ic_dy, ic_z;
    laz_model bit_byte[256], cls_model[256], ud_model[256];
    uint8_t bit_byte_ready[256], cls_ready[256], ud_ready[256];
} p10_state;

typedef struct gps_state {
    int version;
    uint64_t last_gps[4];
    int32_t last_diff[4], extreme[4];
    unsigned last, next;
    laz_model multi, zero_diff;
    laz_ic ic;
} gps_state;

typedef struct rgb_state {
    int version;
    uint16_t last[3];
    laz_model byte_used;
    laz_model diff[6];     /* v2 */
    laz_ic ic;             /* v1 */
} rgb_state;

typedef struct byte_state {
    int version;
    size_t n;
    uint8_t *last;
    laz_model *models;     /* v2: n */
    laz_ic ic;             /* v1: n contexts */
} byte_state;

typedef struct wave_state {
    uint8_t last[29];
    int32_t last_diff_32;
    uint32_t sym_last_offset_diff;
    laz_model packet_index, offset_diff[4];
    laz_ic ic_offset_diff, ic_packet_size, ic_return_point, ic_xyz;
} wave_state;

typedef struct pw_item {
    uint16_t type, size;
    void *state;
} pw_item;

struct laz_decoder {
    int layered;
    int v2_p10;            /* POINT10 [GPSTIME11] [RGB12], all version 2: pw_chunk_v2 */
    unsigned n_items;
    size_t record_length;
    pw_item items[LAZ_MAX_ITEMS];
    laz_layered *ly;
};

/* ---- POINT10 ---- */

static void p10_load(p10_point *p, const uint8_t *b)
{
    p->x = laz_rd32(b);
    p->y = laz_rd32(b + 4);
    p->z = laz_rd32(b + 8);
    p->intensity = laz_rd16(b + 12);
    p->bits = b[14];
    p->cls = b[15];
    p->sar = b[16];
    p->ud = b[17];
    p->psid = laz_rd16(b + 18);
}

static void p10_store(const p10_point *p, uint8_t *b)
{
    laz_wr32(b, p->x);
    laz_wr32(b + 4, p->y);
    laz_wr32(b + 8, p->z);
    laz_wr16(b + 12, p->intensity);
    b[14] = p->bits;
    b[15] = p->cls;
    b[16] = p->sar;
    b[17] = p->ud;
    laz_wr16(b + 18, p->psid);
}

static void p10_free(p10_state *s)
{
    laz_model_free(&s->changed);
    laz_model_free(&s->scan_angle[0]);
    laz_model_free(&s->scan_angle[1]);
    laz_ic_free(&s->ic_intensity);
    laz_ic_free(&s->ic_psid);
    laz_ic_free(&s->ic_sar);
    laz_ic_free(&s->ic_dx);
    laz_ic_free(&s->ic_dy);
    laz_ic_free(&s->ic_z);
    for (int i = 0; i < 256; i++) {
        laz_model_free(&s->bit_byte[i]);
        laz_model_free(&s->cls_model[i]);
        laz_model_free(&s->ud_model[i]);
    }
    free(s);
}

static p10_state *p10_create(int version)
{
    p10_state *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->version = version;
    int bad = laz_model_alloc(&s->changed, 64);
    if (version == 1) {
        bad |= laz_ic_alloc(&s->ic_dx, 32, 1, 8, 0);
        bad |= laz_ic_alloc(&s->ic_dy, 32, 20, 8, 0);
        bad |= laz_ic_alloc(&s->ic_z, 32, 20, 8, 0);
        bad |= laz_ic_alloc(&s->ic_intensity, 16, 1, 8, 0);
        bad |= laz_ic_alloc(&s->ic_sar, 8, 2, 8, 0);
        bad |= laz_ic_alloc(&s->ic_psid, 16, 1, 8, 0);
    } else {
        bad |= laz_ic_alloc(&s->ic_intensity, 16, 4, 8, 0);
        bad |= laz_model_alloc(&s->scan_angle[0], 256);
        bad |= laz_model_alloc(&s->scan_angle[1], 256);
        bad |= laz_ic_alloc(&s->ic_psid, 16, 1, 8, 0);
        bad |= laz_ic_alloc(&s->ic_dx, 32, 2, 8, 0);
        bad |= laz_ic_alloc(&s->ic_dy, 32, 22, 8, 0);
        bad |= laz_ic_alloc(&s->ic_z, 32, 20, 8, 0);
    }
    if (bad) {
        p10_free(s);
        return NULL;
    }
    return s;
}

static void p10_init(p10_state *s, const uint8_t *raw)
{
    laz_model_init(&s->changed);
    laz_ic_init(&s->ic_intensity);
    laz_ic_init(&s->ic_psid);
    laz_ic_init(&s->ic_dx);
    laz_ic_init(&s->ic_dy);
    laz_ic_init(&s->ic_z);
    memset(s->bit_byte_ready, 0, sizeof s->bit_byte_ready);
    memset(s->cls_ready, 0, sizeof s->cls_ready);
    memset(s->ud_ready, 0, sizeof s->ud_ready);
    p10_load(&s->last, raw);
    if (s->version == 1) {
        laz_ic_init(&s->ic_sar);
        for (int i = 0; i < 3; i++)
            s->last_x_diff[i] = s->last_y_diff[i] = 0;
        s->last_incr = 0;
    } else {
        laz_model_init(&s->scan_angle[0]);
        laz_model_init(&s->scan_angle[1]);
        for (int i = 0; i < 16; i++) {
            laz_median5_init(&s->xdiff[i]);
            laz_median5_init(&s->ydiff[i]);
            s->last_intensity[i] = 0;
            s->last_height[i / 2] = 0;
        }
        s->last.intensity = 0; /* the reference predicts from 0, not the raw point */
    }
}

/* A byte through the model its last value selects (made on first use). */
LAZ_INLINE uint8_t p10_byte(laz_dec *d, laz_model *models, uint8_t *ready, uint8_t last)
{
    laz_model *m = laz_lazy_model(d, &models[last], &ready[last], 256);
    return m ? (uint8_t)laz_decode_symbol(d, m) : last;
}

static inline int32_t median3(const int32_t v[3])
{
    if (v[0] < v[1]) {
        if (v[1] < v[2])
            return v[1];
        return v[0] < v[2] ? v[2] : v[0];
    }
    if (v[0] < v[2])
        return v[0];
    return v[1] < v[2] ? v[2] : v[1];
}

static void p10_read_v1(p10_state *s, laz_dec *d, uint8_t *out)
{
    p10_point *p = &s->last;
    int32_t mx = median3(s->last_x_diff), my = median3(s->last_y_diff);
    int32_t xd = laz_ic_decompress(&s->ic_dx, d, mx, 0);
    p->x += (uint32_t)xd;
    uint32_t k = s->ic_dx.k;
    int32_t yd = laz_ic_decompress(&s->ic_dy, d, my, k < 19 ? k : 19);
    p->y += (uint32_t)yd;
    k = (k + s->ic_dy.k) / 2;
    p->z = (uint32_t)laz_ic_decompress(&s->ic_z, d, laz_i32(p->z), k < 19 ? k : 19);
    uint32_t changed = laz_decode_symbol(d, &s->changed);
    if (changed) {
        if (changed & 32)
            p->intensity = (uint16_t)laz_ic_decompress(&s->ic_intensity, d, p->intensity, 0);
        if (changed & 16)
            p->bits = p10_byte(d, s->bit_byte, s->bit_byte_ready, p->bits);
        if (changed & 8)
            p->cls = p10_byte(d, s->cls_model, s->cls_ready, p->cls);
        if (changed & 4)
            p->sar = (uint8_t)laz_ic_decompress(&s->ic_sar, d, p->sar, k < 3);
        if (changed & 2)
            p->ud = p10_byte(d, s->ud_model, s->ud_ready, p->ud);
        if (changed & 1)
            p->psid = (uint16_t)laz_ic_decompress(&s->ic_psid, d, p->psid, 0);
    }
    s->last_x_diff[s->last_incr] = xd;
    s->last_y_diff[s->last_incr] = yd;
    if (++s->last_incr > 2)
        s->last_incr = 0;
    p10_store(p, out);
}

/* The return context of a POINT10 v2 point: number of returns n, return
 * map m and level l. */
typedef struct p10_ctx {
    uint32_t n, m, l;
} p10_ctx;

/* POINT10 v2 comes in steps, each a symbol or an integer then what follows
 * from it, so that two chunks decoded together can go step by step: the
 * "changed" symbol, the return byte, the other fields it names, then X, Y
 * and Z. */
LAZ_INLINE void p10_bits_v2(p10_state *s, laz_dec *d, uint32_t changed)
{
    if (changed & 32)
        s->last.bits = p10_byte(d, s->bit_byte, s->bit_byte_ready, s->last.bits);
}

static inline p10_ctx p10_ctx_v2(const p10_state *s)
{
    uint32_t r = s->last.bits & 7, n = (s->last.bits >> 3) & 7;
    p10_ctx c = {n, p10_return_map[n][r], p10_return_level[n][r]};
    return c;
}

/* Field j (0 intensity, 1 classification, 2 scan angle, 3 user data, 4
 * point source) as `changed` says. The intensity of an unchanged point is
 * its context's last one: always the last point's, unless the returns
 * changed. */
LAZ_INLINE void p10_field_v2(p10_state *s, laz_dec *d, uint32_t changed, p10_ctx c, int j)
{
    p10_point *p = &s->last;
    switch (j) {
    case 0:
        if (changed & 16) {
            p->intensity = (uint16_t)laz_ic_decompress(
                &s->ic_intensity, d, s->last_intensity[c.m], c.m < 3 ? c.m : 3);
            s->last_intensity[c.m] = p->intensity;
        } else {
            p->intensity = s->last_intensity[c.m];
        }
        break;
    case 1:
        if (changed & 8)
            p->cls = p10_byte(d, s->cls_model, s->cls_ready, p->cls);
        break;
    case 2:
        if (changed & 4)
            p->sar = (uint8_t)(laz_decode_symbol(d, &s->scan_angle[(p->bits >> 6) & 1]) +
                               p->sar);
        break;
    case 3:
        if (changed & 2)
            p->ud = p10_byte(d, s->ud_model, s->ud_ready, p->ud);
        break;
    default:
        if (changed & 1)
            p->psid = (uint16_t)laz_ic_decompress(&s->ic_psid, d, p->psid, 0);
        break;
    }
}

/* The prediction and context of X, Y and Z, then the decoded value's use. */
static inline int32_t p10_x_pred(const p10_state *s, p10_ctx c) { return s->xdiff[c.m].v[2]; }
static inline uint32_t p10_x_ctx(p10_ctx c) { return c.n == 1; }

static inline void p10_x_set(p10_state *s, p10_ctx c, int32_t diff)
{
    s->last.x += (uint32_t)diff;
    laz_median5_add(&s->xdiff[c.m], diff);
}

static inline int32_t p10_y_pred(const p10_state *s, p10_ctx c) { return s->ydiff[c.m].v[2]; }

static inline uint32_t p10_y_ctx(const p10_state *s, p10_ctx c)
{
    uint32_t k = s->ic_dx.k;
    return (c.n == 1) + (k < 20 ? (k & ~1u) : 20);
}

static inline void p10_y_set(p10_state *s, p10_ctx c, int32_t diff)
{
    s->last.y += (uint32_t)diff;
    laz_median5_add(&s->ydiff[c.m], diff);
}

static inline int32_t p10_z_pred(const p10_state *s, p10_ctx c) { return s->last_height[c.l]; }

static inline uint32_t p10_z_ctx(const p10_state *s, p10_ctx c)
{
    uint32_t k = (s->ic_dx.k + s->ic_dy.k) / 2;
    return (c.n == 1) + (k < 18 ? (k & ~1u) : 18);
}

static inline void p10_z_set(p10_state *s, p10_ctx c, int32_t z, uint8_t *out)
{
    s->last.z = (uint32_t)z;
    s->last_height[c.l] = z;
    p10_store(&s->last, out);
}

LAZ_INLINE void p10_read_v2(p10_state *s, laz_dec *d, uint8_t *out)
{
    uint32_t changed = laz_decode_symbol(d, &s->changed);
    p10_bits_v2(s, d, changed);
    p10_ctx c = p10_ctx_v2(s);
    for (int j = 0; j < 5; j++)
        p10_field_v2(s, d, changed, c, j);
    p10_x_set(s, c, laz_ic_decompress(&s->ic_dx, d, p10_x_pred(s, c), p10_x_ctx(c)));
    p10_y_set(s, c, laz_ic_decompress(&s->ic_dy, d, p10_y_pred(s, c), p10_y_ctx(s, c)));
    p10_z_set(s, c, laz_ic_decompress(&s->ic_z, d, p10_z_pred(s, c), p10_z_ctx(s, c)), out);
}

/* POINT10 v2 of two chunks (a: sa, da; b: sb, db) in lockstep:
 * each step of the one, then of the other. */
LAZ_INLINE void p10_read2_v2(p10_state *sa, laz_dec *da, p10_state *sb, laz_dec *db,
                             uint8_t *out_a, uint8_t *out_b)
{
    uint32_t cha = laz_decode_symbol(da, &sa->changed);
    uint32_t chb = laz_decode_symbol(db, &sb->changed);
    p10_bits_v2(sa, da, cha);
    p10_bits_v2(sb, db, chb);
    p10_ctx ca = p10_ctx_v2(sa), cb = p10_ctx_v2(sb);
    for (int j = 0; j < 5; j++) {
        p10_field_v2(sa, da, cha, ca, j);
        p10_field_v2(sb, db, chb, cb, j);
    }
    int32_t v[2];
    laz_ic_decompress2(&sa->ic_dx, da, p10_x_pred(sa, ca), p10_x_ctx(ca), &sb->ic_dx, db,
                       p10_x_pred(sb, cb), p10_x_ctx(cb), v);
    p10_x_set(sa, ca, v[0]);
    p10_x_set(sb, cb, v[1]);
    laz_ic_decompress2(&sa->ic_dy, da, p10_y_pred(sa, ca), p10_y_ctx(sa, ca), &sb->ic_dy, db,
                       p10_y_pred(sb, cb), p10_y_ctx(sb, cb), v);
    p10_y_set(sa, ca, v[0]);
    p10_y_set(sb, cb, v[1]);
    laz_ic_decompress2(&sa->ic_z, da, p10_z_pred(sa, ca), p10_z_ctx(sa, ca), &sb->ic_z, db,
                       p10_z_pred(sb, cb), p10_z_ctx(sb, cb), v);
    p10_z_set(sa, ca, v[0], out_a);
    p10_z_set(sb, cb, v[1], out_b);
}

/* ---- GPSTIME11 ---- */

enum {
    GPS_MULTI = 500,
    GPS_MULTI_MINUS = -10,
    GPS_V2_UNCHANGED = GPS_MULTI - GPS_MULTI_MINUS + 1,  /* 511 */
    GPS_V2_CODE_FULL = GPS_MULTI - GPS_MULTI_MINUS + 2,  /* 512 */
    GPS_V2_TOTAL = GPS_MULTI - GPS_MULTI_MINUS + 6,      /* 516 */
    GPS_V1_MULTIMAX = 512
};

static void gps_free(gps_state *s)
{
    laz_model_free(&s->multi);
    laz_model_free(&s->zero_diff);
    laz_ic_free(&s->ic);
    free(s);
}

static gps_state *gps_create(int version)
{
    gps_state *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->version = version;
    int bad;
    if (version == 1)
        bad = laz_model_alloc(&s->multi, GPS_V1_MULTIMAX) |
              laz_model_alloc(&s->zero_diff, 3) | laz_ic_alloc(&s->ic, 32, 6, 8, 0);
    else
        bad = laz_model_alloc(&s->multi, GPS_V2_TOTAL) |
              laz_model_alloc(&s->zero_diff, 6) | laz_ic_alloc(&s->ic, 32, 9, 8, 0);
    if (bad) {
        gps_free(s);
        return NULL;
    }
    return s;
}

static void gps_init(gps_state *s, const uint8_t *raw)
{
    laz_model_init(&s->multi);
    laz_model_init(&s->zero_diff);
    laz_ic_init(&s->ic);
    s->last = s->next = 0;
    for (int i = 0; i < 4; i++) {
        s->last_gps[i] = 0;
        s->last_diff[i] = 0;
        s->extreme[i] = 0;
    }
    s->last_gps[0] = laz_rd64(raw);
}

static void gps_read_v1(gps_state *s, laz_dec *d, uint8_t *out)
{
    uint32_t multi;
    if (s->last_diff[0] == 0) {
        multi = laz_decode_symbol(d, &s->zero_diff);
        if (multi == 1) {
            s->last_diff[0] = laz_ic_decompress(&s->ic, d, 0, 0);
            s->last_gps[0] += (uint64_t)(int64_t)s->last_diff[0];
        } else if (multi == 2) {
            s->last_gps[0] = laz_read_int64(d);
        }
    } else {
        multi = laz_decode_symbol(d, &s->multi);
        if (multi < GPS_V1_MULTIMAX - 2) {
            int32_t diff;
            uint32_t last = (uint32_t)s->last_diff[0];
            if (multi == 1) {
                diff = laz_ic_decompress(&s->ic, d, s->last_diff[0], 1);
                s->last_diff[0] = diff;
                s->extreme[0] = 0;
            } else if (multi == 0) {
                diff = laz_ic_decompress(&s->ic, d, s->last_diff[0] / 4, 2);
                if (++s->extreme[0] > 3) {
                    s->last_diff[0] = diff;
                    s->extreme[0] = 0;
                }
            } else if (multi < 10) {
                diff = laz_ic_decompress(&s->ic, d, laz_i32(multi * last), 3);
            } else if (multi < 50) {
                diff = laz_ic_decompress(&s->ic, d, laz_i32(multi * last), 4);
            } else {
                diff = laz_ic_decompress(&s->ic, d, laz_i32(multi * last), 5);
                if (multi == GPS_V1_MULTIMAX - 3 && ++s->extreme[0] > 3) {
                    s->last_diff[0] = diff;
                    s->extreme[0] = 0;
                }
            }
            s->last_gps[0] += (uint64_t)(int64_t)diff;
        } else if (multi < GPS_V1_MULTIMAX - 1) {
            s->last_gps[0] = laz_read_int64(d);
        }
    }
    laz_wr64(out, s->last_gps[0]);
}

/* The model of the next symbol of a GPSTIME11 v2 point. */
static inline laz_model *gps_model_v2(gps_state *s)
{
    return s->last_diff[s->last] == 0 ? &s->zero_diff : &s->multi;
}

/* A time in full, starting the next of the four sequences (its high half
 * predicted from the current sequence's). */
LAZ_INLINE void gps_full_v2(gps_state *s, laz_dec *d)
{
    s->next = (s->next + 1) & 3;
    uint32_t hi = (uint32_t)laz_ic_decompress(
        &s->ic, d, laz_i32((uint32_t)(s->last_gps[s->last] >> 32)), 8);
    s->last_gps[s->next] = ((uint64_t)hi << 32) | laz_read_int(d);
    s->last = s->next;
    s->last_diff[s->last] = 0;
    s->extreme[s->last] = 0;
}

/* What follows symbol `multi` of gps_model_v2: 1 when the time is decoded,
 * 0 when the sequence switched (another symbol follows). */
LAZ_INLINE int gps_round_v2(gps_state *s, laz_dec *d, uint32_t multi)
{
    unsigned last = s->last;
    if (s->last_diff[last] == 0) {
        if (multi == 1) {
            s->last_diff[last] = laz_ic_decompress(&s->ic, d, 0, 0);
            s->last_gps[last] += (uint64_t)(int64_t)s->last_diff[last];
            s->extreme[last] = 0;
        } else if (multi == 2) {
            gps_full_v2(s, d);
        } else if (multi > 2) {
            s->last = (last + multi - 2) & 3;
            return 0;
        }
    } else {
        if (multi == 1) {
            s->last_gps[last] +=
                (uint64_t)(int64_t)laz_ic_decompress(&s->ic, d, s->last_diff[last], 1);
            s->extreme[last] = 0;
        } else if (multi < GPS_V2_UNCHANGED) {
            int32_t diff = laz_gps_multi_diff(&s->ic, d, &s->last_diff[last],
                                              &s->extreme[last], multi);
            s->last_gps[last] += (uint64_t)(int64_t)diff;
        } else if (multi == GPS_V2_CODE_FULL) {
            gps_full_v2(s, d);
        } else if (multi > GPS_V2_CODE_FULL) {
            s->last = (last + multi - GPS_V2_CODE_FULL) & 3;
            return 0;
        }
    }
    return 1;
}

/* A GPSTIME11 v2 point whose first symbol is `multi`. A sequence switch
 * re-reads; the encoder switches at most once per point, so four symbols
 * bound a corrupt stream. */
LAZ_INLINE void gps_finish_v2(gps_state *s, laz_dec *d, uint32_t multi, uint8_t *out)
{
    int round = 1;
    while (!gps_round_v2(s, d, multi)) {
        if (round++ == 4) {
            *d->fail |= LAZ_FAIL_CORRUPT;
            break;
        }
        multi = laz_decode_symbol(d, gps_model_v2(s));
    }
    laz_wr64(out, s->last_gps[s->last]);
}

LAZ_INLINE void gps_read_v2(gps_state *s, laz_dec *d, uint8_t *out)
{
    gps_finish_v2(s, d, laz_decode_symbol(d, gps_model_v2(s)), out);
}

/* GPSTIME11 v2 of two chunks: both first symbols, then the rest of each. */
LAZ_INLINE void gps_read2_v2(gps_state *sa, laz_dec *da, gps_state *sb, laz_dec *db,
                             uint8_t *out_a, uint8_t *out_b)
{
    uint32_t ma = laz_decode_symbol(da, gps_model_v2(sa));
    uint32_t mb = laz_decode_symbol(db, gps_model_v2(sb));
    gps_finish_v2(sa, da, ma, out_a);
    gps_finish_v2(sb, db, mb, out_b);
}

/* ---- RGB12 ---- */

static void rgb_free(rgb_state *s)
{
    laz_model_free(&s->byte_used);
    for (int i = 0; i < 6; i++)
        laz_model_free(&s->diff[i]);
    laz_ic_free(&s->ic);
    free(s);
}

static rgb_state *rgb_create(int version)
{
    rgb_state *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->version = version;
    int bad;
    if (version == 1) {
        bad = laz_model_alloc(&s->byte_used, 64) | laz_ic_alloc(&s->ic, 8, 6, 8, 0);
    } else {
        bad = laz_model_alloc(&s->byte_used, 128);
        for (int i = 0; i < 6; i++)
            bad |= laz_model_alloc(&s->diff[i], 256);
    }
    if (bad) {
        rgb_free(s);
        return NULL;
    }
    return s;
}

static void rgb_init(rgb_state *s, const uint8_t *raw)
{
    laz_model_init(&s->byte_used);
    if (s->version == 1) {
        laz_ic_init(&s->ic);
    } else {
        for (int i = 0; i < 6; i++)
            laz_model_init(&s->diff[i]);
    }
    for (int i = 0; i < 3; i++)
        s->last[i] = laz_rd16(raw + 2 * i);
}

static void rgb_read_v1(rgb_state *s, laz_dec *d, uint8_t *out)
{
    uint32_t sym = laz_decode_symbol(d, &s->byte_used);
    uint16_t c[3];
    for (int i = 0; i < 3; i++) {
        uint32_t lo = s->last[i] & 0xFF, hi = s->last[i] >> 8;
        if (sym & (1u << (2 * i)))
            lo = (uint32_t)laz_ic_decompress(&s->ic, d, (int32_t)lo, 2 * i) & 0xFFFF;
        if (sym & (1u << (2 * i + 1)))
            hi = (uint32_t)laz_ic_decompress(&s->ic, d, (int32_t)hi, 2 * i + 1);
        c[i] = (uint16_t)(lo | (hi << 8));
    }
    for (int i = 0; i < 3; i++) {
        s->last[i] = c[i];
        laz_wr16(out + 2 * i, c[i]);
    }
}

static inline void rgb_set_v2(rgb_state *s, uint32_t sym, const uint32_t corr[6], uint8_t *out)
{
    uint16_t c[3];
    laz_rgb_combine(sym, corr, s->last, c);
    for (int i = 0; i < 3; i++) {
        s->last[i] = c[i];
        laz_wr16(out + 2 * i, c[i]);
    }
}

LAZ_INLINE void rgb_read_v2(rgb_state *s, laz_dec *d, uint8_t *out)
{
    uint32_t sym = laz_decode_symbol(d, &s->byte_used), corr[6];
    for (int j = 0; j < 6; j++)
        laz_rgb_byte(d, s->diff, sym, j, corr);
    rgb_set_v2(s, sym, corr, out);
}

/* RGB12 v2 of two chunks in lockstep, symbol by symbol. */
LAZ_INLINE void rgb_read2_v2(rgb_state *sa, laz_dec *da, rgb_state *sb, laz_dec *db,
                             uint8_t *out_a, uint8_t *out_b)
{
    uint32_t syma = laz_decode_symbol(da, &sa->byte_used), ca[6];
    uint32_t symb = laz_decode_symbol(db, &sb->byte_used), cb[6];
    for (int j = 0; j < 6; j++) {
        laz_rgb_byte(da, sa->diff, syma, j, ca);
        laz_rgb_byte(db, sb->diff, symb, j, cb);
    }
    rgb_set_v2(sa, syma, ca, out_a);
    rgb_set_v2(sb, symb, cb, out_b);
}

/* ---- BYTE ---- */

static void byte_free(byte_state *s)
{
    if (s->models)
        for (size_t i = 0; i < s->n; i++)
            laz_model_free(&s->models[i]);
    free(s->models);
    laz_ic_free(&s->ic);
    free(s->last);
    free(s);
}

static byte_state *byte_create(int version, size_t n)
{
    byte_state *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->version = version;
    s->n = n;
    s->last = malloc(n);
    int bad = s->last == NULL;
    if (!bad && version == 1) {
        bad = laz_ic_alloc(&s->ic, 8, (uint32_t)n, 8, 0);
    } else if (!bad) {
        s->models = calloc(n, sizeof *s->models);
        bad = s->models == NULL;
        for (size_t i = 0; !bad && i < n; i++)
            bad = laz_model_alloc(&s->models[i], 256);
    }
    if (bad) {
        byte_free(s);
        return NULL;
    }
    return s;
}

static void byte_init(byte_state *s, const uint8_t *raw)
{
    if (s->version == 1)
        laz_ic_init(&s->ic);
    else
        for (size_t i = 0; i < s->n; i++)
            laz_model_init(&s->models[i]);
    memcpy(s->last, raw, s->n);
}

static void byte_read(byte_state *s, laz_dec *d, uint8_t *out)
{
    if (s->version == 1) {
        for (size_t i = 0; i < s->n; i++)
            out[i] = (uint8_t)laz_ic_decompress(&s->ic, d, s->last[i], (uint32_t)i);
    } else {
        for (size_t i = 0; i < s->n; i++)
            out[i] = (uint8_t)(s->last[i] + laz_decode_symbol(d, &s->models[i]));
    }
    memcpy(s->last, out, s->n);
}

/* ---- WAVEPACKET13 ---- */

static void wave_free(wave_state *s)
{
    laz_model_free(&s->packet_index);
    for (int i = 0; i < 4; i++)
        laz_model_free(&s->offset_diff[i]);
    laz_ic_free(&s->ic_offset_diff);
    laz_ic_free(&s->ic_packet_size);
    laz_ic_free(&s->ic_return_point);
    laz_ic_free(&s->ic_xyz);
    free(s);
}

static wave_state *wave_create(void)
{
    wave_state *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    int bad = laz_model_alloc(&s->packet_index, 256);
    for (int i = 0; i < 4; i++)
        bad |= laz_model_alloc(&s->offset_diff[i], 4);
    bad |= laz_ic_alloc(&s->ic_offset_diff, 32, 1, 8, 0);
    bad |= laz_ic_alloc(&s->ic_packet_size, 32, 1, 8, 0);
    bad |= laz_ic_alloc(&s->ic_return_point, 32, 1, 8, 0);
    bad |= laz_ic_alloc(&s->ic_xyz, 32, 3, 8, 0);
    if (bad) {
        wave_free(s);
        return NULL;
    }
    return s;
}

static void wave_init(wave_state *s, const uint8_t *raw)
{
    laz_model_init(&s->packet_index);
    for (int i = 0; i < 4; i++)
        laz_model_init(&s->offset_diff[i]);
    laz_ic_init(&s->ic_offset_diff);
    laz_ic_init(&s->ic_packet_size);
    laz_ic_init(&s->ic_return_point);
    laz_ic_init(&s->ic_xyz);
    s->last_diff_32 = 0;
    s->sym_last_offset_diff = 0;
    memcpy(s->last, raw, 29);
}

static void wave_read(wave_state *s, laz_dec *d, uint8_t *out)
{
    const uint8_t *l = s->last + 1;
    out[0] = (uint8_t)laz_decode_symbol(d, &s->packet_index);
    uint64_t offset = laz_rd64(l);
    uint32_t size = laz_rd32(l + 8);
    s->sym_last_offset_diff = laz_decode_symbol(d, &s->offset_diff[s->sym_last_offset_diff]);
    if (s->sym_last_offset_diff == 1) {
        offset += size;
    } else if (s->sym_last_offset_diff == 2) {
        s->last_diff_32 = laz_ic_decompress(&s->ic_offset_diff, d, s->last_diff_32, 0);
        offset += (uint64_t)(int64_t)s->last_diff_32;
    } else if (s->sym_last_offset_diff == 3) {
        offset = laz_read_int64(d);
    }
    laz_wr64(out + 1, offset);
    laz_wr32(out + 9, (uint32_t)laz_ic_decompress(&s->ic_packet_size, d, laz_i32(size), 0));
    laz_wr32(out + 13, (uint32_t)laz_ic_decompress(&s->ic_return_point, d,
                                                   laz_i32(laz_rd32(l + 12)), 0));
    for (int k = 0; k < 3; k++)
        laz_wr32(out + 17 + 4 * k, (uint32_t)laz_ic_decompress(
                                       &s->ic_xyz, d, laz_i32(laz_rd32(l + 16 + 4 * k)),
                                       (uint32_t)k));
    memcpy(s->last, out, 29);
}

/* ---- the decoder ---- */

laz_decoder *laz_decoder_create(const laz_item *items, unsigned n_items, int layered)
{
    if (n_items == 0 || n_items > LAZ_MAX_ITEMS)
        return NULL;
    laz_decoder *dec = calloc(1, sizeof *dec);
    if (!dec)
        return NULL;
    dec->layered = layered;
    dec->n_items = n_items;
    for (unsigned i = 0; i < n_items; i++)
        dec->record_length += items[i].size;
    if (layered) {
        dec->ly = laz_layered_create(items, n_items);
        if (!dec->ly) {
            free(dec);
            return NULL;
        }
        return dec;
    }
    /* item types rise: POINT10 6, GPSTIME11 7, RGB12 8 */
    dec->v2_p10 = items[0].type == LAZ_POINT10;
    for (unsigned i = 0; i < n_items; i++) {
        dec->v2_p10 &= items[i].version == 2 && items[i].type <= LAZ_RGB12 &&
                       (i == 0 || items[i].type > items[i - 1].type);
        pw_item *it = &dec->items[i];
        it->type = items[i].type;
        it->size = items[i].size;
        int v = items[i].version;
        switch (it->type) {
        case LAZ_POINT10: it->state = p10_create(v); break;
        case LAZ_GPSTIME11: it->state = gps_create(v); break;
        case LAZ_RGB12: it->state = rgb_create(v); break;
        case LAZ_BYTE: it->state = byte_create(v, it->size); break;
        case LAZ_WAVEPACKET13: it->state = wave_create(); break;
        default: it->state = NULL; break;
        }
        if (!it->state) {
            laz_decoder_destroy(dec);
            return NULL;
        }
    }
    return dec;
}

void laz_decoder_destroy(laz_decoder *dec)
{
    if (!dec)
        return;
    laz_layered_destroy(dec->ly);
    for (unsigned i = 0; i < dec->n_items; i++) {
        pw_item *it = &dec->items[i];
        if (!it->state)
            continue;
        switch (it->type) {
        case LAZ_POINT10: p10_free(it->state); break;
        case LAZ_GPSTIME11: gps_free(it->state); break;
        case LAZ_RGB12: rgb_free(it->state); break;
        case LAZ_BYTE: byte_free(it->state); break;
        case LAZ_WAVEPACKET13: wave_free(it->state); break;
        default: break;
        }
    }
    free(dec);
}

static void pw_read_point(laz_decoder *dec, laz_dec *d, uint8_t *out)
{
    for (unsigned i = 0; i < dec->n_items; i++) {
        pw_item *it = &dec->items[i];
        switch (it->type) {
        case LAZ_POINT10: {
            p10_state *s = it->state;
            if (s->version == 2)
                p10_read_v2(s, d, out);
            else
                p10_read_v1(s, d, out);
            break;
        }
        case LAZ_GPSTIME11: {
            gps_state *s = it->state;
            if (s->version == 2)
                gps_read_v2(s, d, out);
            else
                gps_read_v1(s, d, out);
            break;
        }
        case LAZ_RGB12: {
            rgb_state *s = it->state;
            if (s->version == 2)
                rgb_read_v2(s, d, out);
            else
                rgb_read_v1(s, d, out);
            break;
        }
        case LAZ_BYTE: byte_read(it->state, d, out); break;
        case LAZ_WAVEPACKET13: wave_read(it->state, d, out); break;
        default: break;
        }
        out += it->size;
    }
}

/* The items of a chunk of the common formats 0-3: POINT10, then GPSTIME11
 * and RGB12 as present, all version 2 (dec->v2_p10). */
typedef struct pw_v2 {
    p10_state *p10;
    gps_state *gps;
    rgb_state *rgb;
    size_t rl, at_rgb;
} pw_v2;

static pw_v2 pw_v2_items(const laz_decoder *dec)
{
    pw_v2 v = {dec->items[0].state, NULL, NULL, dec->record_length, 20};
    for (unsigned k = 1; k < dec->n_items; k++) {
        if (dec->items[k].type == LAZ_GPSTIME11)
            v.gps = dec->items[k].state;
        else
            v.rgb = dec->items[k].state;
    }
    v.at_rgb = v.gps ? 28 : 20;
    return v;
}

/* GPSTIME11 and RGB12 of a point, as present. */
LAZ_INLINE void pw_v2_tail(const pw_v2 *v, laz_dec *d, uint8_t *rec)
{
    if (v->gps)
        gps_read_v2(v->gps, d, rec + 20);
    if (v->rgb)
        rgb_read_v2(v->rgb, d, rec + v->at_rgb);
}

/* The same for two chunks in lockstep (both have the same items). */
LAZ_INLINE void pw_v2_tail2(const pw_v2 *va, laz_dec *da, const pw_v2 *vb, laz_dec *db,
                            uint8_t *ra, uint8_t *rb)
{
    if (va->gps)
        gps_read2_v2(va->gps, da, vb->gps, db, ra + 20, rb + 20);
    if (va->rgb)
        rgb_read2_v2(va->rgb, da, vb->rgb, db, ra + va->at_rgb, rb + vb->at_rgb);
}

/* Points i..count-1 of a formats 0-3 chunk: every item inlined, so the
 * arithmetic decoder stays in registers from point to point. Stops after
 * the point that raised a flag; returns the index past the last point
 * decoded. */
static size_t pw_chunk_v2(const pw_v2 *v, laz_dec *dp, size_t i, size_t count, uint8_t *out)
{
    laz_dec d = *dp;
    for (; i < count && !*d.fail; i++) {
        uint8_t *rec = out + i * v->rl;
        p10_read_v2(v->p10, &d, rec);
        pw_v2_tail(v, &d, rec);
    }
    *dp = d;
    return i;
}

/* Points 1..count-1 of two formats 0-3 chunks at once, a and b in lockstep
 * symbol by symbol: the two streams are independent dependency chains,
 * which the core overlaps, where one chunk alone waits on every symbol. Each
 * chunk stops where it would alone: the rest of the longer one, and of
 * one whose partner raised a flag, goes on alone. i[]: as pw_chunk_v2's
 * return. */
static void pw_chunk2_v2(const pw_v2 *va, const pw_v2 *vb, laz_dec *dpa, laz_dec *dpb,
                         const size_t count[2], uint8_t *out[2], size_t i[2])
{
    laz_dec a = *dpa, b = *dpb;
    size_t n = count[0] < count[1] ? count[0] : count[1], j = 1;
    for (; j < n && !*a.fail && !*b.fail; j++) {
        uint8_t *ra = out[0] + j * va->rl, *rb = out[1] + j * vb->rl;
        p10_read2_v2(va->p10, &a, vb->p10, &b, ra, rb);
        pw_v2_tail2(va, &a, vb, &b, ra, rb);
    }
    i[0] = *a.fail ? j : pw_chunk_v2(va, &a, j, count[0], out[0]);
    i[1] = *b.fail ? j : pw_chunk_v2(vb, &b, j, count[1], out[1]);
    *dpa = a;
    *dpb = b;
}

/* The start of a pointwise chunk: its first point raw into out, the items
 * reset from it, the decoder on the bytes after it. 0: points 1..count-1
 * remain; 1: the chunk is done (*consumed and st set). */
static int pw_begin(laz_decoder *dec, const uint8_t *p, const uint8_t *end, size_t count,
                    uint8_t *out, size_t *consumed, laz_chunk_status *st, laz_dec *d)
{
    size_t rl = dec->record_length;
    if ((size_t)(end - p) < rl) {
        st->fail = LAZ_FAIL_DATA;
        st->at = (size_t)(end - p);
        return 1;
    }
    memcpy(out, p, rl);
    const uint8_t *raw = p;
    for (unsigned i = 0; i < dec->n_items; i++) {
        pw_item *it = &dec->items[i];
        switch (it->type) {
        case LAZ_POINT10: p10_init(it->state, raw); break;
        case LAZ_GPSTIME11: gps_init(it->state, raw); break;
        case LAZ_RGB12: rgb_init(it->state, raw); break;
        case LAZ_BYTE: byte_init(it->state, raw); break;
        case LAZ_WAVEPACKET13: wave_init(it->state, raw); break;
        default: break;
        }
        raw += it->size;
    }
    if (count == 1) {
        *consumed = rl;
        return 1;
    }
    laz_dec_init(d, p + rl, end, &st->fail);
    return 0;
}

/* The end of a pointwise chunk whose points up to i-1 were decoded. */
static int pw_end(const laz_dec *d, const uint8_t *p, size_t i, size_t *consumed,
                  laz_chunk_status *st)
{
    *consumed = (size_t)(d->p - p);
    if (st->fail) {
        st->point = i - 1; /* the point whose decoding raised the flag */
        st->at = *consumed;
    }
    return st->fail;
}

static void status_clear(size_t *consumed, laz_chunk_status *st)
{
    st->fail = 0;
    st->point = 0;
    st->at = 0;
    *consumed = 0;
}

int laz_decode_chunk(laz_decoder *dec, const uint8_t *p, const uint8_t *end, size_t count,
                     uint8_t *out, size_t *consumed, laz_chunk_status *st)
{
    status_clear(consumed, st);
    if (count == 0)
        return 0;
    if (dec->layered)
        return laz_layered_chunk(dec->ly, p, end, count, out, dec->record_length, consumed,
                                 st);
    laz_dec d;
    if (pw_begin(dec, p, end, count, out, consumed, st, &d))
        return st->fail;
    size_t i = 1;
    if (dec->v2_p10) {
        pw_v2 v = pw_v2_items(dec);
        i = pw_chunk_v2(&v, &d, 1, count, out);
    } else {
        for (; i < count && !st->fail; i++)
            pw_read_point(dec, &d, out + i * dec->record_length);
    }
    return pw_end(&d, p, i, consumed, st);
}

void laz_decode_chunk2(laz_decoder *dec[2], const uint8_t *p[2], const uint8_t *end[2],
                       const size_t count[2], uint8_t *out[2], size_t consumed[2],
                       laz_chunk_status st[2])
{
    if (dec[0]->layered || !dec[0]->v2_p10 || count[0] < 2 || count[1] < 2) {
        for (int k = 0; k < 2; k++)
            laz_decode_chunk(dec[k], p[k], end[k], count[k], out[k], &consumed[k], &st[k]);
        return;
    }
    laz_dec d[2];
    int done[2];
    for (int k = 0; k < 2; k++) {
        status_clear(&consumed[k], &st[k]);
        done[k] = pw_begin(dec[k], p[k], end[k], count[k], out[k], &consumed[k], &st[k], &d[k]);
    }
    pw_v2 v[2] = {pw_v2_items(dec[0]), pw_v2_items(dec[1])};
    size_t i[2] = {1, 1};
    if (!done[0] && !done[1])
        pw_chunk2_v2(&v[0], &v[1], &d[0], &d[1], count, out, i);
    else
        for (int k = 0; k < 2; k++)
            if (!done[k])
                i[k] = pw_chunk_v2(&v[k], &d[k], 1, count[k], out[k]);
    for (int k = 0; k < 2; k++)
        if (!done[k])
            pw_end(&d[k], p[k], i[k], &consumed[k], &st[k]);
}
