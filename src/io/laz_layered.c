/* Layered LAZ items (compressor 3, LAS 1.4 point formats 6-10): POINT14,
 * RGB14, RGBNIR14, WAVEPACKET14 and BYTE14, versions 3 and 4 (2, from an
 * early writer, decodes as 3).
 *
 * Format description: the LASzip 1.4 "layered chunked" compressor (rapidlasso,
 * "LAZ 1.4 compression: native extension of LASzip for the new point types",
 * 2017) and its reference decoder (LASzip's lasreaditemcompressed_v3/_v4),
 * which fix the bit-exact behaviour. A chunk is
 *   raw first point | u32 point count | u32 byte size of every layer | layers
 * and every layer is its own arithmetic stream: POINT14 has nine (returns,
 * channel and XY; Z; classification; flags; intensity; scan angle; user data;
 * point source; GPS time), RGB14 one, RGBNIR14 two, WAVEPACKET14 one, BYTE14
 * one per byte. A layer of 0 bytes did not change within the chunk: its field
 * keeps the first point's value. Only the XY layer is always decoded.
 *
 * Every item keeps four contexts, one per scanner channel, made when the
 * channel first appears in the chunk from the last point of the channel
 * before. The "changed" symbol of a point (context from the last point's
 * return and whether its GPS time changed) says whether the channel, the
 * point source, the GPS time, the scan angle, the number of returns and the
 * return number changed. Versions 3 and 4 differ in the context the other
 * items use, and in what they predict from after a switch: v3 passes the
 * channel only on points where it changed (0 otherwise, as the reference's
 * per-point context variable starts at 0), and an item switching to a
 * channel it has used before predicts that point from the last value of the
 * channel it switched from (the reference refreshes its `last_item` pointer
 * only for a new channel; the encoder does the same, so this is kept). v4
 * passes the current channel always and predicts from it. */
#include "io/laz_items.h"

#include <stdlib.h>
#include <string.h>

/* LASzip's return contexts for 4-bit r and n (laszip_common_v3). */
static const uint8_t map6[16][16] = {
    {0, 1, 2, 3, 4, 5, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5}, {1, 0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3},
    {2, 1, 2, 4, 4, 4, 4, 4, 4, 4, 4, 3, 3, 3, 3, 3}, {3, 3, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {3, 3, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {4, 3, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4},
    {5, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 4, 4, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5}};
static const uint8_t level8[16][16] = {
    {0, 1, 2, 3, 4, 5, 6, 7, 7, 7, 7, 7, 7, 7, 7, 7}, {1, 0, 1, 2, 3, 4, 5, 6, 7, 7, 7, 7, 7, 7, 7, 7},
    {2, 1, 0, 1, 2, 3, 4, 5, 6, 7, 7, 7, 7, 7, 7, 7}, {3, 2, 1, 0, 1, 2, 3, 4, 5, 6, 7, 7, 7, 7, 7, 7},
    {4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6, 7, 7, 7, 7, 7}, {5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6, 7, 7, 7, 7},
    {6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6, 7, 7, 7}, {7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6, 7, 7},
    {7, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6, 7}, {7, 7, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6},
    {7, 7, 7, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5}, {7, 7, 7, 7, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4},
    {7, 7, 7, 7, 7, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3}, {7, 7, 7, 7, 7, 7, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2},
    {7, 7, 7, 7, 7, 7, 7, 7, 6, 5, 4, 3, 2, 1, 0, 1}, {7, 7, 7, 7, 7, 7, 7, 7, 7, 6, 5, 4, 3, 2, 1, 0}};

enum {
    L_XY, L_Z, L_CLASS, L_FLAGS, L_INTENSITY, L_SCAN_ANGLE, L_USER_DATA, L_SOURCE, L_GPS,
    P14_LAYERS
};

enum { GPS14_CODE_FULL = 511, GPS14_TOTAL = 515 };

/* The fields of a point14 record (30 bytes). */
typedef struct p14_point {
    uint32_t x, y, z;
    uint16_t intensity;
    uint8_t r, n;            /* return number, number of returns: 4 bits each */
    uint8_t class_flags;     /* 4 bits */
    uint8_t channel;         /* 2 bits */
    uint8_t scan_dir, edge;
    uint8_t cls, ud;
    uint16_t scan_angle;     /* int16 bit pattern */
    uint16_t psid;
    uint64_t gps;            /* double bit pattern */
    int gps_change;          /* of the last point: a context */
} p14_point;

typedef struct p14_ctx {
    int used;                /* made in this chunk */
    p14_point last;
    uint16_t last_intensity[8];
    int32_t last_z[8];
    laz_median5 xdiff[12], ydiff[12];
    laz_model changed[8], channel_model, rn_gps_same;
    laz_model nr[16], rn[16];
    uint8_t nr_ready[16], rn_ready[16];
    laz_ic ic_dx, ic_dy, ic_z, ic_intensity, ic_scan_angle, ic_psid, ic_gps;
    laz_model cls[64], flags[64], ud[64];
    uint8_t cls_ready[64], flags_ready[64], ud_ready[64];
    unsigned seq, next_seq;  /* GPS time sequences */
    uint64_t last_gps[4];
    int32_t last_diff[4], extreme[4];
    laz_model gps_multi, gps_zero;
} p14_ctx;

typedef struct p14_item {
    int version;
    unsigned cur;
    p14_ctx *ctx[4];
    laz_dec layer[P14_LAYERS];
    uint32_t bytes[P14_LAYERS];
} p14_item;

typedef struct rgb14_ctx {
    int used;
    uint16_t last[4];        /* RGB (and NIR) */
    laz_model byte_used, diff[6];
    laz_model nir_used, nir_diff[2];
} rgb14_ctx;

typedef struct wave14_ctx {
    int used;
    uint8_t last[29];
    int32_t last_diff_32;
    uint32_t sym_last_offset_diff;
    laz_model packet_index, offset_diff[4];
    laz_ic ic_offset_diff, ic_packet_size, ic_return_point, ic_xyz;
} wave14_ctx;

typedef struct byte14_ctx {
    int used;
    uint8_t *last;
    laz_model *models;
} byte14_ctx;

typedef struct ly_item {
    uint16_t type, size, version;
    unsigned cur;
    unsigned n_layers;
    uint32_t bytes[2];        /* RGB14, WAVEPACKET14: [0]; RGBNIR14: RGB, NIR */
    laz_dec dec[2];
    uint32_t *byte_sizes;     /* BYTE14: size entries */
    laz_dec *byte_dec;        /* BYTE14: size decoders */
    void *ctx[4];             /* rgb14_ctx / wave14_ctx / byte14_ctx, made on first use */
} ly_item;

struct laz_layered {
    unsigned n_items;
    p14_item p14;
    ly_item items[LAZ_MAX_ITEMS]; /* items[0] unused: POINT14 */
};

/* ---- POINT14 ---- */

static void p14_load(p14_point *p, const uint8_t *b)
{
    p->x = laz_rd32(b);
    p->y = laz_rd32(b + 4);
    p->z = laz_rd32(b + 8);
    p->intensity = laz_rd16(b + 12);
    p->r = b[14] & 15;
    p->n = b[14] >> 4;
    p->class_flags = b[15] & 15;
    p->channel = (b[15] >> 4) & 3;
    p->scan_dir = (b[15] >> 6) & 1;
    p->edge = b[15] >> 7;
    p->cls = b[16];
    p->ud = b[17];
    p->scan_angle = laz_rd16(b + 18);
    p->psid = laz_rd16(b + 20);
    p->gps = laz_rd64(b + 22);
    p->gps_change = 0;
}

static void p14_store(const p14_point *p, uint8_t *b)
{
    laz_wr32(b, p->x);
    laz_wr32(b + 4, p->y);
    laz_wr32(b + 8, p->z);
    laz_wr16(b + 12, p->intensity);
    b[14] = (uint8_t)(p->r | (p->n << 4));
    b[15] = (uint8_t)(p->class_flags | (p->channel << 4) | (p->scan_dir << 6) | (p->edge << 7));
    b[16] = p->cls;
    b[17] = p->ud;
    laz_wr16(b + 18, p->scan_angle);
    laz_wr16(b + 20, p->psid);
    laz_wr64(b + 22, p->gps);
}

static void p14_ctx_free(p14_ctx *c)
{
    if (!c)
        return;
    for (int i = 0; i < 8; i++)
        laz_model_free(&c->changed[i]);
    laz_model_free(&c->channel_model);
    laz_model_free(&c->rn_gps_same);
    for (int i = 0; i < 16; i++) {
        laz_model_free(&c->nr[i]);
        laz_model_free(&c->rn[i]);
    }
    for (int i = 0; i < 64; i++) {
        laz_model_free(&c->cls[i]);
        laz_model_free(&c->flags[i]);
        laz_model_free(&c->ud[i]);
    }
    laz_ic_free(&c->ic_dx);
    laz_ic_free(&c->ic_dy);
    laz_ic_free(&c->ic_z);
    laz_ic_free(&c->ic_intensity);
    laz_ic_free(&c->ic_scan_angle);
    laz_ic_free(&c->ic_psid);
    laz_ic_free(&c->ic_gps);
    laz_model_free(&c->gps_multi);
    laz_model_free(&c->gps_zero);
    free(c);
}

static p14_ctx *p14_ctx_create(void)
{
    p14_ctx *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    int bad = 0;
    for (int i = 0; i < 8; i++)
        bad |= laz_model_alloc(&c->changed[i], 128);
    bad |= laz_model_alloc(&c->channel_model, 3);
    bad |= laz_model_alloc(&c->rn_gps_same, 13);
    bad |= laz_ic_alloc(&c->ic_dx, 32, 2, 8, 0);
    bad |= laz_ic_alloc(&c->ic_dy, 32, 22, 8, 0);
    bad |= laz_ic_alloc(&c->ic_z, 32, 20, 8, 0);
    bad |= laz_ic_alloc(&c->ic_intensity, 16, 4, 8, 0);
    bad |= laz_ic_alloc(&c->ic_scan_angle, 16, 2, 8, 0);
    bad |= laz_ic_alloc(&c->ic_psid, 16, 1, 8, 0);
    bad |= laz_ic_alloc(&c->ic_gps, 32, 9, 8, 0);
    bad |= laz_model_alloc(&c->gps_multi, GPS14_TOTAL);
    bad |= laz_model_alloc(&c->gps_zero, 5);
    if (bad) {
        p14_ctx_free(c);
        return NULL;
    }
    return c;
}

/* Makes context k current-ready from the point `from` (the raw first point,
 * or the last point of the channel before). 0 or -1 (no memory). */
static int p14_ctx_start(p14_item *s, unsigned k, const p14_point *from)
{
    if (!s->ctx[k] && !(s->ctx[k] = p14_ctx_create()))
        return -1;
    p14_ctx *c = s->ctx[k];
    for (int i = 0; i < 8; i++)
        laz_model_init(&c->changed[i]);
    laz_model_init(&c->channel_model);
    laz_model_init(&c->rn_gps_same);
    memset(c->nr_ready, 0, sizeof c->nr_ready);
    memset(c->rn_ready, 0, sizeof c->rn_ready);
    memset(c->cls_ready, 0, sizeof c->cls_ready);
    memset(c->flags_ready, 0, sizeof c->flags_ready);
    memset(c->ud_ready, 0, sizeof c->ud_ready);
    laz_ic_init(&c->ic_dx);
    laz_ic_init(&c->ic_dy);
    laz_ic_init(&c->ic_z);
    laz_ic_init(&c->ic_intensity);
    laz_ic_init(&c->ic_scan_angle);
    laz_ic_init(&c->ic_psid);
    laz_ic_init(&c->ic_gps);
    laz_model_init(&c->gps_multi);
    laz_model_init(&c->gps_zero);
    for (int i = 0; i < 12; i++) {
        laz_median5_init(&c->xdiff[i]);
        laz_median5_init(&c->ydiff[i]);
    }
    for (int i = 0; i < 8; i++) {
        c->last_z[i] = laz_i32(from->z);
        c->last_intensity[i] = from->intensity;
    }
    c->seq = c->next_seq = 0;
    for (int i = 0; i < 4; i++) {
        c->last_gps[i] = 0;
        c->last_diff[i] = 0;
        c->extreme[i] = 0;
    }
    c->last_gps[0] = from->gps;
    c->last = *from;
    c->last.gps_change = 0;
    c->used = 1;
    return 0;
}

/* A symbol through a model made on first use in the chunk, or `fallback`
 * when it cannot be allocated (the flag stops the chunk). */
LAZ_INLINE uint32_t lazy_symbol(laz_dec *d, laz_model *m, uint8_t *ready, uint32_t symbols,
                            uint32_t fallback)
{
    laz_model *lm = laz_lazy_model(d, m, ready, symbols);
    return lm ? laz_decode_symbol(d, lm) : fallback;
}

LAZ_INLINE void p14_read_gps(p14_ctx *c, laz_dec *d)
{
    /* The encoder switches sequence at most once per point. */
    for (int round = 0; round < 4; round++) {
        unsigned seq = c->seq;
        if (c->last_diff[seq] == 0) {
            uint32_t multi = laz_decode_symbol(d, &c->gps_zero);
            if (multi == 0) {
                c->last_diff[seq] = laz_ic_decompress(&c->ic_gps, d, 0, 0);
                c->last_gps[seq] += (uint64_t)(int64_t)c->last_diff[seq];
                c->extreme[seq] = 0;
            } else if (multi == 1) {
                c->next_seq = (c->next_seq + 1) & 3;
                uint32_t hi = (uint32_t)laz_ic_decompress(
                    &c->ic_gps, d, laz_i32((uint32_t)(c->last_gps[seq] >> 32)), 8);
                c->last_gps[c->next_seq] = ((uint64_t)hi << 32) | laz_read_int(d);
                c->seq = c->next_seq;
                c->last_diff[c->seq] = 0;
                c->extreme[c->seq] = 0;
            } else {
                c->seq = (seq + multi - 1) & 3;
                continue;
            }
        } else {
            uint32_t multi = laz_decode_symbol(d, &c->gps_multi);
            if (multi == 1) {
                c->last_gps[seq] += (uint64_t)(int64_t)laz_ic_decompress(
                    &c->ic_gps, d, c->last_diff[seq], 1);
                c->extreme[seq] = 0;
            } else if (multi < GPS14_CODE_FULL) {
                int32_t diff = laz_gps_multi_diff(&c->ic_gps, d, &c->last_diff[seq],
                                                  &c->extreme[seq], multi);
                c->last_gps[seq] += (uint64_t)(int64_t)diff;
            } else if (multi == GPS14_CODE_FULL) {
                c->next_seq = (c->next_seq + 1) & 3;
                uint32_t hi = (uint32_t)laz_ic_decompress(
                    &c->ic_gps, d, laz_i32((uint32_t)(c->last_gps[seq] >> 32)), 8);
                c->last_gps[c->next_seq] = ((uint64_t)hi << 32) | laz_read_int(d);
                c->seq = c->next_seq;
                c->last_diff[c->seq] = 0;
                c->extreme[c->seq] = 0;
            } else {
                c->seq = (seq + multi - GPS14_CODE_FULL) & 3;
                continue;
            }
        }
        return;
    }
    *d->fail |= LAZ_FAIL_CORRUPT;
}

/* One point; returns the context the other items use. */
LAZ_INLINE unsigned p14_read(p14_item *s, uint8_t *out, int *fail)
{
    /* every layer's decoder is copied in and out, so that its state stays
     * in registers (model updates could otherwise alias it) */
    laz_dec xyd = s->layer[L_XY], *xy = &xyd;
    p14_ctx *c = s->ctx[s->cur];
    p14_point *last = &c->last;
    unsigned lpr = (last->r == 1 ? 1u : 0u) + (last->r >= last->n ? 2u : 0u) +
                   (last->gps_change ? 4u : 0u);
    uint32_t changed = laz_decode_symbol(xy, &c->changed[lpr]);
    unsigned context = 0;
    if (changed & (1u << 6)) {
        uint32_t diff = laz_decode_symbol(xy, &c->channel_model);
        unsigned channel = (s->cur + diff + 1) % 4;
        if ((!s->ctx[channel] || !s->ctx[channel]->used) &&
            p14_ctx_start(s, channel, last) != 0) {
            *fail |= LAZ_FAIL_NOMEM;
            s->layer[L_XY] = xyd;
            return 0;
        }
        s->cur = channel;
        context = channel;
        c = s->ctx[channel];
        last = &c->last;
        last->channel = (uint8_t)channel;
    }
    if (s->version >= 4)
        context = s->cur;
    int psid_change = (changed >> 5) & 1;
    int gps_change = (changed >> 4) & 1;
    int angle_change = (changed >> 3) & 1;

    uint32_t n = last->n, r = last->r;
    if (changed & (1u << 2)) {
        n = lazy_symbol(xy, &c->nr[last->n], &c->nr_ready[last->n], 16, n);
        last->n = (uint8_t)n;
    }
    switch (changed & 3) {
    case 0: break;
    case 1: r = (r + 1) % 16; break;
    case 2: r = (r + 15) % 16; break;
    default:
        if (gps_change)
            r = lazy_symbol(xy, &c->rn[r], &c->rn_ready[r], 16, r);
        else
            r = (r + laz_decode_symbol(xy, &c->rn_gps_same) + 2) % 16;
        break;
    }
    last->r = (uint8_t)r;
    unsigned m = map6[n][r], l = level8[n][r];
    unsigned cpr = (r == 1 ? 2u : 0u) + (r >= n ? 1u : 0u);
    unsigned idx = (m << 1) | (unsigned)gps_change;

    int32_t diff = laz_ic_decompress(&c->ic_dx, xy, c->xdiff[idx].v[2], n == 1);
    last->x += (uint32_t)diff;
    laz_median5_add(&c->xdiff[idx], diff);
    uint32_t k = c->ic_dx.k;
    diff = laz_ic_decompress(&c->ic_dy, xy, c->ydiff[idx].v[2],
                             (n == 1) + (k < 20 ? (k & ~1u) : 20));
    last->y += (uint32_t)diff;
    laz_median5_add(&c->ydiff[idx], diff);
    s->layer[L_XY] = xyd;

    if (s->bytes[L_Z]) {
        laz_dec d = s->layer[L_Z];
        k = (c->ic_dx.k + c->ic_dy.k) / 2;
        last->z = (uint32_t)laz_ic_decompress(&c->ic_z, &d, c->last_z[l],
                                              (n == 1) + (k < 18 ? (k & ~1u) : 18));
        c->last_z[l] = laz_i32(last->z);
        s->layer[L_Z] = d;
    }
    if (s->bytes[L_CLASS]) {
        laz_dec d = s->layer[L_CLASS];
        unsigned ccc = ((last->cls & 0x1Fu) << 1) + (cpr == 3 ? 1u : 0u);
        last->cls = (uint8_t)lazy_symbol(&d, &c->cls[ccc], &c->cls_ready[ccc],
                                         256, last->cls);
        s->layer[L_CLASS] = d;
    }
    if (s->bytes[L_FLAGS]) {
        laz_dec d = s->layer[L_FLAGS];
        unsigned lf = (unsigned)(last->edge << 5) | (unsigned)(last->scan_dir << 4) |
                      last->class_flags;
        uint32_t f = lazy_symbol(&d, &c->flags[lf], &c->flags_ready[lf], 64,
                                 lf);
        last->edge = (f >> 5) & 1;
        last->scan_dir = (f >> 4) & 1;
        last->class_flags = f & 15;
        s->layer[L_FLAGS] = d;
    }
    if (s->bytes[L_INTENSITY]) {
        laz_dec d = s->layer[L_INTENSITY];
        unsigned ic = (cpr << 1) | (unsigned)gps_change;
        uint16_t v = (uint16_t)laz_ic_decompress(&c->ic_intensity, &d,
                                                 c->last_intensity[ic], cpr);
        c->last_intensity[ic] = v;
        last->intensity = v;
        s->layer[L_INTENSITY] = d;
    }
    if (s->bytes[L_SCAN_ANGLE] && angle_change) {
        laz_dec d = s->layer[L_SCAN_ANGLE];
        last->scan_angle = (uint16_t)laz_ic_decompress(&c->ic_scan_angle, &d,
                                                       (int16_t)last->scan_angle,
                                                       (uint32_t)gps_change);
        s->layer[L_SCAN_ANGLE] = d;
    }
    if (s->bytes[L_USER_DATA]) {
        laz_dec d = s->layer[L_USER_DATA];
        unsigned u = last->ud / 4u;
        last->ud = (uint8_t)lazy_symbol(&d, &c->ud[u], &c->ud_ready[u],
                                        256, last->ud);
        s->layer[L_USER_DATA] = d;
    }
    if (s->bytes[L_SOURCE] && psid_change) {
        laz_dec d = s->layer[L_SOURCE];
        last->psid = (uint16_t)laz_ic_decompress(&c->ic_psid, &d, last->psid, 0);
        s->layer[L_SOURCE] = d;
    }
    if (s->bytes[L_GPS] && gps_change) {
        laz_dec d = s->layer[L_GPS];
        p14_read_gps(c, &d);
        last->gps = c->last_gps[c->seq];
        s->layer[L_GPS] = d;
    }
    p14_store(last, out);
    last->gps_change = gps_change;
    return context;
}

/* ---- RGB14, RGBNIR14 ---- */

static void rgb14_ctx_free(rgb14_ctx *c)
{
    if (!c)
        return;
    laz_model_free(&c->byte_used);
    for (int i = 0; i < 6; i++)
        laz_model_free(&c->diff[i]);
    laz_model_free(&c->nir_used);
    laz_model_free(&c->nir_diff[0]);
    laz_model_free(&c->nir_diff[1]);
    free(c);
}

static rgb14_ctx *rgb14_ctx_create(int nir)
{
    rgb14_ctx *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    int bad = laz_model_alloc(&c->byte_used, 128);
    for (int i = 0; i < 6; i++)
        bad |= laz_model_alloc(&c->diff[i], 256);
    if (nir)
        bad |= laz_model_alloc(&c->nir_used, 4) | laz_model_alloc(&c->nir_diff[0], 256) |
               laz_model_alloc(&c->nir_diff[1], 256);
    if (bad) {
        rgb14_ctx_free(c);
        return NULL;
    }
    return c;
}

static void wave14_ctx_free(wave14_ctx *c)
{
    if (!c)
        return;
    laz_model_free(&c->packet_index);
    for (int i = 0; i < 4; i++)
        laz_model_free(&c->offset_diff[i]);
    laz_ic_free(&c->ic_offset_diff);
    laz_ic_free(&c->ic_packet_size);
    laz_ic_free(&c->ic_return_point);
    laz_ic_free(&c->ic_xyz);
    free(c);
}

static wave14_ctx *wave14_ctx_create(void)
{
    wave14_ctx *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    int bad = laz_model_alloc(&c->packet_index, 256);
    for (int i = 0; i < 4; i++)
        bad |= laz_model_alloc(&c->offset_diff[i], 4);
    bad |= laz_ic_alloc(&c->ic_offset_diff, 32, 1, 8, 0);
    bad |= laz_ic_alloc(&c->ic_packet_size, 32, 1, 8, 0);
    bad |= laz_ic_alloc(&c->ic_return_point, 32, 1, 8, 0);
    bad |= laz_ic_alloc(&c->ic_xyz, 32, 3, 8, 0);
    if (bad) {
        wave14_ctx_free(c);
        return NULL;
    }
    return c;
}

static void byte14_ctx_free(byte14_ctx *c, size_t n)
{
    if (!c)
        return;
    if (c->models)
        for (size_t i = 0; i < n; i++)
            laz_model_free(&c->models[i]);
    free(c->models);
    free(c->last);
    free(c);
}

static byte14_ctx *byte14_ctx_create(size_t n)
{
    byte14_ctx *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    c->last = malloc(n);
    c->models = calloc(n, sizeof *c->models);
    int bad = !c->last || !c->models;
    for (size_t i = 0; !bad && i < n; i++)
        bad = laz_model_alloc(&c->models[i], 256);
    if (bad) {
        byte14_ctx_free(c, n);
        return NULL;
    }
    return c;
}

static void item_ctx_free(ly_item *it, void *c)
{
    switch (it->type) {
    case LAZ_RGB14:
    case LAZ_RGBNIR14: rgb14_ctx_free(c); break;
    case LAZ_WAVEPACKET14: wave14_ctx_free(c); break;
    case LAZ_BYTE14: byte14_ctx_free(c, it->size); break;
    default: break;
    }
}

static int ctx_used(const ly_item *it, unsigned k)
{
    if (!it->ctx[k])
        return 0;
    switch (it->type) {
    case LAZ_RGB14:
    case LAZ_RGBNIR14: return ((rgb14_ctx *)it->ctx[k])->used;
    case LAZ_WAVEPACKET14: return ((wave14_ctx *)it->ctx[k])->used;
    case LAZ_BYTE14: return ((byte14_ctx *)it->ctx[k])->used;
    default: return 0;
    }
}

/* Where an item's context keeps its last value. */
static uint8_t *ctx_last_bytes(ly_item *it, unsigned k, uint8_t *scratch)
{
    switch (it->type) {
    case LAZ_RGB14:
    case LAZ_RGBNIR14: {
        rgb14_ctx *c = it->ctx[k];
        for (int i = 0; i < 4; i++)
            laz_wr16(scratch + 2 * i, c->last[i]);
        return scratch;
    }
    case LAZ_WAVEPACKET14: return ((wave14_ctx *)it->ctx[k])->last;
    case LAZ_BYTE14: return ((byte14_ctx *)it->ctx[k])->last;
    default: return scratch;
    }
}

/* Makes context k of an item from the item bytes `from`. 0 or -1. */
static int item_ctx_start(ly_item *it, unsigned k, const uint8_t *from)
{
    switch (it->type) {
    case LAZ_RGB14:
    case LAZ_RGBNIR14: {
        int nir = it->type == LAZ_RGBNIR14;
        if (!it->ctx[k] && !(it->ctx[k] = rgb14_ctx_create(nir)))
            return -1;
        rgb14_ctx *c = it->ctx[k];
        laz_model_init(&c->byte_used);
        for (int i = 0; i < 6; i++)
            laz_model_init(&c->diff[i]);
        if (nir) {
            laz_model_init(&c->nir_used);
            laz_model_init(&c->nir_diff[0]);
            laz_model_init(&c->nir_diff[1]);
        }
        for (int i = 0; i < (nir ? 4 : 3); i++)
            c->last[i] = laz_rd16(from + 2 * i);
        c->used = 1;
        return 0;
    }
    case LAZ_WAVEPACKET14: {
        if (!it->ctx[k] && !(it->ctx[k] = wave14_ctx_create()))
            return -1;
        wave14_ctx *c = it->ctx[k];
        laz_model_init(&c->packet_index);
        for (int i = 0; i < 4; i++)
            laz_model_init(&c->offset_diff[i]);
        laz_ic_init(&c->ic_offset_diff);
        laz_ic_init(&c->ic_packet_size);
        laz_ic_init(&c->ic_return_point);
        laz_ic_init(&c->ic_xyz);
        c->last_diff_32 = 0;
        c->sym_last_offset_diff = 0;
        memcpy(c->last, from, 29);
        c->used = 1;
        return 0;
    }
    case LAZ_BYTE14: {
        if (!it->ctx[k] && !(it->ctx[k] = byte14_ctx_create(it->size)))
            return -1;
        byte14_ctx *c = it->ctx[k];
        for (size_t i = 0; i < it->size; i++)
            laz_model_init(&c->models[i]);
        memcpy(c->last, from, it->size);
        c->used = 1;
        return 0;
    }
    default: return -1;
    }
}

static void rgb14_read(ly_item *it, rgb14_ctx *c, uint16_t *last, uint8_t *out)
{
    uint16_t v[4];
    if (it->bytes[0]) {
        laz_dec d = it->dec[0]; /* in registers while it decodes */
        laz_rgb_decode(&d, &c->byte_used, c->diff, last, v);
        it->dec[0] = d;
        memcpy(last, v, 3 * sizeof *v);
    } else {
        memcpy(v, last, 3 * sizeof *v);
    }
    if (it->type == LAZ_RGBNIR14) {
        if (it->bytes[1]) {
            laz_dec *d = &it->dec[1];
            uint32_t sym = laz_decode_symbol(d, &c->nir_used);
            uint32_t lo = last[3] & 0xFF, hi = last[3] >> 8;
            if (sym & 1)
                lo = (laz_decode_symbol(d, &c->nir_diff[0]) + lo) & 0xFF;
            if (sym & 2)
                hi = (laz_decode_symbol(d, &c->nir_diff[1]) + hi) & 0xFF;
            last[3] = (uint16_t)(lo | (hi << 8));
        }
        v[3] = last[3];
    }
    for (int i = 0; i < (it->type == LAZ_RGBNIR14 ? 4 : 3); i++)
        laz_wr16(out + 2 * i, v[i]);
}

static void wave14_read(ly_item *it, wave14_ctx *c, uint8_t *last, uint8_t *out)
{
    if (!it->bytes[0]) {
        memcpy(out, last, 29);
        return;
    }
    laz_dec *d = &it->dec[0];
    const uint8_t *l = last + 1;
    out[0] = (uint8_t)laz_decode_symbol(d, &c->packet_index);
    uint64_t offset = laz_rd64(l);
    uint32_t size = laz_rd32(l + 8);
    c->sym_last_offset_diff = laz_decode_symbol(d, &c->offset_diff[c->sym_last_offset_diff]);
    if (c->sym_last_offset_diff == 1) {
        offset += size;
    } else if (c->sym_last_offset_diff == 2) {
        c->last_diff_32 = laz_ic_decompress(&c->ic_offset_diff, d, c->last_diff_32, 0);
        offset += (uint64_t)(int64_t)c->last_diff_32;
    } else if (c->sym_last_offset_diff == 3) {
        offset = laz_read_int64(d);
    }
    laz_wr64(out + 1, offset);
    laz_wr32(out + 9, (uint32_t)laz_ic_decompress(&c->ic_packet_size, d, laz_i32(size), 0));
    laz_wr32(out + 13, (uint32_t)laz_ic_decompress(&c->ic_return_point, d,
                                                   laz_i32(laz_rd32(l + 12)), 0));
    for (int k = 0; k < 3; k++)
        laz_wr32(out + 17 + 4 * k,
                 (uint32_t)laz_ic_decompress(&c->ic_xyz, d, laz_i32(laz_rd32(l + 16 + 4 * k)),
                                             (uint32_t)k));
    memcpy(last, out, 29);
}

static void byte14_read(ly_item *it, byte14_ctx *c, uint8_t *last, uint8_t *out)
{
    for (size_t i = 0; i < it->size; i++) {
        if (it->byte_sizes[i]) {
            last[i] = (uint8_t)(last[i] + laz_decode_symbol(&it->byte_dec[i], &c->models[i]));
        }
        out[i] = last[i];
    }
}

/* One item of one point in `context`. The value predicted from is the
 * current context's, except (before v4) on a switch to a channel used
 * before, where the reference keeps predicting from the channel it left. */
static void item_read(ly_item *it, unsigned context, uint8_t *out, int *fail)
{
    unsigned from = it->cur;
    if (context != it->cur) {
        it->cur = context;
        if (!ctx_used(it, context)) {
            uint8_t scratch[8];
            uint8_t tmp[64];
            const uint8_t *src = ctx_last_bytes(it, from, scratch);
            /* copy first: the source may be the context being made */
            if (it->size <= sizeof tmp) {
                memcpy(tmp, src, it->type == LAZ_RGB14 ? 6 : it->size);
                src = tmp;
            }
            if (item_ctx_start(it, context, src) != 0) {
                *fail |= LAZ_FAIL_NOMEM;
                return;
            }
            from = context;
        }
        if (it->version >= 4)
            from = context; /* v4 predicts from the channel it switched to */
    }
    switch (it->type) {
    case LAZ_RGB14:
    case LAZ_RGBNIR14:
        rgb14_read(it, it->ctx[it->cur], ((rgb14_ctx *)it->ctx[from])->last, out);
        break;
    case LAZ_WAVEPACKET14:
        wave14_read(it, it->ctx[it->cur], ((wave14_ctx *)it->ctx[from])->last, out);
        break;
    case LAZ_BYTE14:
        byte14_read(it, it->ctx[it->cur], ((byte14_ctx *)it->ctx[from])->last, out);
        break;
    default: break;
    }
}

/* ---- the layered decoder ---- */

laz_layered *laz_layered_create(const laz_item *items, unsigned n_items)
{
    if (n_items == 0 || n_items > LAZ_MAX_ITEMS || items[0].type != LAZ_POINT14)
        return NULL;
    laz_layered *ly = calloc(1, sizeof *ly);
    if (!ly)
        return NULL;
    ly->n_items = n_items;
    ly->p14.version = items[0].version;
    for (unsigned i = 1; i < n_items; i++) {
        ly_item *it = &ly->items[i];
        it->type = items[i].type;
        it->size = items[i].size;
        it->version = items[i].version;
        if (it->type == LAZ_BYTE14) {
            it->byte_sizes = calloc(it->size, sizeof *it->byte_sizes);
            it->byte_dec = calloc(it->size, sizeof *it->byte_dec);
            if (!it->byte_sizes || !it->byte_dec) {
                laz_layered_destroy(ly);
                return NULL;
            }
        }
    }
    return ly;
}

void laz_layered_destroy(laz_layered *ly)
{
    if (!ly)
        return;
    for (int k = 0; k < 4; k++)
        p14_ctx_free(ly->p14.ctx[k]);
    for (unsigned i = 1; i < ly->n_items; i++) {
        ly_item *it = &ly->items[i];
        for (int k = 0; k < 4; k++)
            item_ctx_free(it, it->ctx[k]);
        free(it->byte_sizes);
        free(it->byte_dec);
    }
    free(ly);
}

/* Reads the chunk's layer sizes after the raw point and the count, and
 * points every layer's decoder at its bytes. 0, or LAZ_FAIL_LAYOUT with
 * st->at set. */
static int ly_layout(laz_layered *ly, const uint8_t *chunk, const uint8_t *end, size_t rl,
                     size_t count, int *fail, size_t *consumed, laz_chunk_status *st)
{
    size_t avail = (size_t)(end - chunk);
    size_t pos = rl + 4; /* raw point, point count */
    size_t n_sizes = P14_LAYERS;
    for (unsigned i = 1; i < ly->n_items; i++) {
        ly_item *it = &ly->items[i];
        n_sizes += it->type == LAZ_BYTE14 ? it->size : it->type == LAZ_RGBNIR14 ? 2 : 1;
    }
    if (avail < pos || (avail - pos) / 4 < n_sizes) {
        st->at = avail;
        return LAZ_FAIL_DATA;
    }
    const uint8_t *q = chunk + pos;
    uint64_t total = 0;
    p14_item *s = &ly->p14;
    for (int k = 0; k < P14_LAYERS; k++, q += 4)
        total += s->bytes[k] = laz_rd32(q);
    for (unsigned i = 1; i < ly->n_items; i++) {
        ly_item *it = &ly->items[i];
        if (it->type == LAZ_BYTE14) {
            for (size_t b = 0; b < it->size; b++, q += 4)
                total += it->byte_sizes[b] = laz_rd32(q);
        } else {
            it->n_layers = it->type == LAZ_RGBNIR14 ? 2 : 1;
            for (unsigned b = 0; b < it->n_layers; b++, q += 4)
                total += it->bytes[b] = laz_rd32(q);
        }
    }
    pos = (size_t)(q - chunk);
    if (total > avail - pos) {
        st->at = rl + 4;
        return LAZ_FAIL_LAYOUT;
    }
    if (count > 1 && s->bytes[L_XY] == 0) {
        st->at = rl + 4;
        return LAZ_FAIL_LAYOUT;
    }
    const uint8_t *p = chunk + pos;
    for (int k = 0; k < P14_LAYERS; k++) {
        if (s->bytes[k] && count > 1)
            laz_dec_init(&s->layer[k], p, p + s->bytes[k], fail);
        p += s->bytes[k];
    }
    for (unsigned i = 1; i < ly->n_items; i++) {
        ly_item *it = &ly->items[i];
        if (it->type == LAZ_BYTE14) {
            for (size_t b = 0; b < it->size; b++) {
                if (it->byte_sizes[b] && count > 1)
                    laz_dec_init(&it->byte_dec[b], p, p + it->byte_sizes[b], fail);
                p += it->byte_sizes[b];
            }
        } else {
            for (unsigned b = 0; b < it->n_layers; b++) {
                if (it->bytes[b] && count > 1)
                    laz_dec_init(&it->dec[b], p, p + it->bytes[b], fail);
                p += it->bytes[b];
            }
        }
    }
    *consumed = (size_t)(p - chunk);
    return 0;
}

/* The end of the first layer that ran dry (for the error's byte offset). */
static size_t ly_dry_layer(laz_layered *ly, const uint8_t *chunk, size_t fallback)
{
    for (int k = 0; k < P14_LAYERS; k++) {
        laz_dec *d = &ly->p14.layer[k];
        if (ly->p14.bytes[k] && d->p == d->end)
            return (size_t)(d->end - chunk);
    }
    for (unsigned i = 1; i < ly->n_items; i++) {
        ly_item *it = &ly->items[i];
        size_t n = it->type == LAZ_BYTE14 ? it->size : it->n_layers;
        for (size_t b = 0; b < n; b++) {
            laz_dec *d = it->type == LAZ_BYTE14 ? &it->byte_dec[b] : &it->dec[b];
            uint32_t bytes = it->type == LAZ_BYTE14 ? it->byte_sizes[b] : it->bytes[b];
            if (bytes && d->p == d->end)
                return (size_t)(d->end - chunk);
        }
    }
    return fallback;
}

int laz_layered_chunk(laz_layered *ly, const uint8_t *p, const uint8_t *end, size_t count,
                      uint8_t *out, size_t record_length, size_t *consumed,
                      laz_chunk_status *st)
{
    size_t rl = record_length;
    if ((size_t)(end - p) < rl) {
        st->fail = LAZ_FAIL_DATA;
        st->at = (size_t)(end - p);
        return st->fail;
    }
    memcpy(out, p, rl);
    int fail = ly_layout(ly, p, end, rl, count, &st->fail, consumed, st);
    if (fail) {
        st->fail = fail;
        return fail;
    }
    /* Contexts from the raw point: its channel for every item. */
    p14_item *s = &ly->p14;
    p14_point first;
    p14_load(&first, p);
    for (int k = 0; k < 4; k++)
        if (s->ctx[k])
            s->ctx[k]->used = 0;
    s->cur = first.channel;
    if (p14_ctx_start(s, s->cur, &first) != 0) {
        st->fail = LAZ_FAIL_NOMEM;
        return st->fail;
    }
    const uint8_t *raw = p + 30;
    for (unsigned i = 1; i < ly->n_items; i++) {
        ly_item *it = &ly->items[i];
        for (int k = 0; k < 4; k++)
            if (it->ctx[k])
                switch (it->type) {
                case LAZ_RGB14:
                case LAZ_RGBNIR14: ((rgb14_ctx *)it->ctx[k])->used = 0; break;
                case LAZ_WAVEPACKET14: ((wave14_ctx *)it->ctx[k])->used = 0; break;
                case LAZ_BYTE14: ((byte14_ctx *)it->ctx[k])->used = 0; break;
                default: break;
                }
        it->cur = s->cur;
        if (item_ctx_start(it, it->cur, raw) != 0) {
            st->fail = LAZ_FAIL_NOMEM;
            return st->fail;
        }
        raw += it->size;
    }
    size_t i = 1;
    for (; i < count && !st->fail; i++) {
        uint8_t *rec = out + i * rl;
        unsigned context = p14_read(s, rec, &st->fail);
        uint8_t *q = rec + 30;
        for (unsigned j = 1; j < ly->n_items; j++) {
            item_read(&ly->items[j], context, q, &st->fail);
            q += ly->items[j].size;
        }
    }
    if (st->fail) {
        st->point = i - 1;
        st->at = ly_dry_layer(ly, p, *consumed);
    }
    return st->fail;
}
