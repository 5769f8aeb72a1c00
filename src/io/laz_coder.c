/* Adaptive models and the integer decompressor of the LAZ entropy decoder
 * (the description is in laz_coder.h: Said's FastAC as LASzip adapted it).
 *
 * Symbol model: counts start at 1; every update cycle (first (n+6)/2
 * symbols, then 5/4 as long, at most 8(n+6)) the counts are halved once
 * their total passes 2^15 and the distribution is rebuilt as
 * floor(2^31/total * cumulative count) >> 16, with a lookup table of
 * 2^table_bits entries (the smallest table_bits >= 3 with n <= 2^(bits+2))
 * for alphabets of more than 16 symbols. Bit model: the same with counts of
 * zeros and of all bits, total at most 2^13, cycles of 4 growing by 5/4 up
 * to 64. */
#include "io/laz_coder.h"

#include <stdlib.h>
#include <string.h>

int laz_model_alloc(laz_model *m, uint32_t symbols)
{
    memset(m, 0, sizeof *m);
    if (symbols < 2 || symbols > (1u << 11))
        return -1;
    uint32_t table_bits = 0, table_size = 0;
    if (symbols > 16) {
        table_bits = 3;
        while (symbols > (1u << (table_bits + 2)))
            ++table_bits;
        table_size = 1u << table_bits;
    }
    size_t words = 2 * (size_t)symbols + LAZ_DIST_PAD;
    size_t bytes = words * sizeof(uint32_t) + (table_size ? table_size + 2 : 0) * sizeof(uint16_t);
    uint32_t *store = malloc(bytes);
    if (!store)
        return -1;
    m->dist = store;
    for (uint32_t k = 0; k < LAZ_DIST_PAD; k++)
        m->dist[symbols + k] = UINT32_MAX; /* above any dv: counts stop at the end */
    m->count = store + symbols + LAZ_DIST_PAD;
    m->table = table_size ? (uint16_t *)(m->count + symbols) : NULL;
    m->symbols = symbols;
    m->last_symbol = symbols - 1;
    m->table_size = table_size;
    m->table_shift = table_size ? LAZ_DM_SHIFT - table_bits : 0;
    return 0;
}

void laz_model_free(laz_model *m)
{
    if (m) {
        free(m->dist);
        memset(m, 0, sizeof *m);
    }
}

void laz_model_init(laz_model *m)
{
    for (uint32_t k = 0; k < m->symbols; k++)
        m->count[k] = 1;
    m->total_count = 0;
    m->update_cycle = m->symbols;
    laz_model_update(m);
    m->until_update = m->update_cycle = (m->symbols + 6) >> 1;
}

void laz_model_update(laz_model *m)
{
    if ((m->total_count += m->update_cycle) > (1u << LAZ_DM_SHIFT)) {
        m->total_count = 0;
        for (uint32_t n = 0; n < m->symbols; n++)
            m->total_count += (m->count[n] = (m->count[n] + 1) >> 1);
    }
    uint32_t sum = 0, scale = 0x80000000u / m->total_count;
    uint32_t *restrict dist = m->dist;
    const uint32_t *restrict count = m->count;
    if (!m->table) {
        for (uint32_t k = 0; k < m->symbols; k++) {
            dist[k] = (scale * sum) >> (31 - LAZ_DM_SHIFT);
            sum += count[k];
        }
    } else {
        /* The decoder table: table[s] is the last symbol whose distribution
         * starts below s << table_shift (0 for s = 0), so the symbol of a
         * value v lies in [table[v >> shift], table[(v >> shift) + 1]].
         * Built without branches: each symbol stores itself at the slot it
         * starts in (the last to start in a slot stays), then a running
         * maximum fills the slots no symbol starts in. */
        uint16_t *restrict t = m->table + 1;
        uint32_t size = m->table_size, shift = m->table_shift;
        memset(t, 0, ((size_t)size + 1) * sizeof *t);
        for (uint32_t k = 0; k < m->symbols; k++) {
            uint32_t v = (scale * sum) >> (31 - LAZ_DM_SHIFT);
            dist[k] = v;
            t[v >> shift] = (uint16_t)k;
            sum += count[k];
        }
        uint16_t run = 0; /* in a register: no store-to-load chain */
        for (uint32_t s = 0; s <= size; s++) {
            run = t[s] > run ? t[s] : run;
            t[s] = run;
        }
        m->table[0] = 0;
    }
    m->update_cycle = (5 * m->update_cycle) >> 2;
    uint32_t max_cycle = (m->symbols + 6) << 3;
    if (m->update_cycle > max_cycle)
        m->update_cycle = max_cycle;
    m->until_update = m->update_cycle;
}

uint32_t laz_bisect(const uint32_t *dist, uint32_t sym, uint32_t n, uint32_t dv)
{
    while (n > sym + 1) {
        uint32_t k = (sym + n) >> 1;
        if (dist[k] > dv)
            n = k;
        else
            sym = k;
    }
    return sym;
}

laz_model *laz_model_first_use(laz_model *m, uint8_t *ready, uint32_t symbols, int *fail)
{
    if (!m->dist && laz_model_alloc(m, symbols) != 0) {
        *fail |= LAZ_FAIL_NOMEM;
        return NULL;
    }
    laz_model_init(m);
    *ready = 1;
    return m;
}

void laz_bitmodel_init(laz_bitmodel *m)
{
    m->bit_0_count = 1;
    m->bit_count = 2;
    m->bit_0_prob = 1u << (LAZ_BM_SHIFT - 1);
    m->update_cycle = m->until_update = 4;
}

void laz_bitmodel_update(laz_bitmodel *m)
{
    if ((m->bit_count += m->update_cycle) > (1u << LAZ_BM_SHIFT)) {
        m->bit_count = (m->bit_count + 1) >> 1;
        m->bit_0_count = (m->bit_0_count + 1) >> 1;
        if (m->bit_0_count == m->bit_count)
            ++m->bit_count;
    }
    uint32_t scale = 0x80000000u / m->bit_count;
    m->bit_0_prob = (m->bit_0_count * scale) >> (31 - LAZ_BM_SHIFT);
    m->update_cycle = (5 * m->update_cycle) >> 2;
    if (m->update_cycle > 64)
        m->update_cycle = 64;
    m->until_update = m->update_cycle;
}

int laz_ic_alloc(laz_ic *ic, uint32_t bits, uint32_t contexts, uint32_t bits_high,
                 uint32_t range)
{
    memset(ic, 0, sizeof *ic);
    ic->contexts = contexts;
    ic->bits_high = bits_high;
    if (range) {
        uint32_t r = range;
        ic->corr_bits = 0;
        while (r) {
            r >>= 1;
            ic->corr_bits++;
        }
        if (range == (1u << (ic->corr_bits - 1)))
            ic->corr_bits--;
        ic->corr_range = range;
        ic->corr_min = -(int32_t)(range / 2);
    } else if (bits && bits < 32) {
        ic->corr_bits = bits;
        ic->corr_range = 1u << bits;
        ic->corr_min = -(int32_t)(ic->corr_range / 2);
    } else {
        ic->corr_bits = 32;
        ic->corr_range = 0;
        ic->corr_min = INT32_MIN;
    }
    ic->mbits = calloc(contexts, sizeof *ic->mbits);
    if (!ic->mbits)
        return -1;
    for (uint32_t i = 0; i < contexts; i++)
        if (laz_model_alloc(&ic->mbits[i], ic->corr_bits + 1) != 0)
            return -1;
    return 0;
}

void laz_ic_free(laz_ic *ic)
{
    if (!ic)
        return;
    if (ic->mbits)
        for (uint32_t i = 0; i < ic->contexts; i++)
            laz_model_free(&ic->mbits[i]);
    free(ic->mbits);
    for (int k = 0; k < 32; k++)
        laz_model_free(&ic->corr[k]);
    memset(ic, 0, sizeof *ic);
}

void laz_ic_init(laz_ic *ic)
{
    for (uint32_t i = 0; i < ic->contexts; i++)
        laz_model_init(&ic->mbits[i]);
    laz_bitmodel_init(&ic->corr0);
    memset(ic->corr_ready, 0, sizeof ic->corr_ready);
    ic->k = 0;
}

void laz_dec_init(laz_dec *d, const uint8_t *p, const uint8_t *end, int *fail)
{
    d->p = p;
    d->end = end;
    d->fail = fail;
    d->length = 0xFFFFFFFFu;
    d->value = laz_byte(d) << 24;
    d->value |= laz_byte(d) << 16;
    d->value |= laz_byte(d) << 8;
    d->value |= laz_byte(d);
}
