/* Storage for the greedy projection reconstruction (Gopi & Krishnan 2002):
 * the dexel array of section 3 (columns of points sorted by depth, queried
 * with axis-aligned boxes, section 4.1), the pool of held triangles with
 * each point's list and fan (link path), the retirement blocks that decide
 * when a triangle can leave memory (section 6: only triangles near the
 * front are kept), the guard's grids of held triangles (short ones by
 * centroid cell, long ones by every cell their box overlaps), and the
 * set-up. */
#include "greedy/greedy.h"

/* ---- bucketing: the dexel array (section 3) ---- */

typedef struct gp_sortrec {
    float d, a, b;
    uint32_t i;
} gp_sortrec;

static int cmp_double(const void *pa, const void *pb)
{
    double a = *(const double *)pa, b = *(const double *)pb;
    return a < b ? -1 : (a > b);
}

static int cmp_sortrec(const void *pa, const void *pb)
{
    const gp_sortrec *x = pa, *y = pb;
    if (x->d != y->d)
        return x->d < y->d ? -1 : 1;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    if (x->b != y->b)
        return x->b < y->b ? -1 : 1;
    return x->i < y->i ? -1 : (x->i > y->i);
}

/* Sorts the cloud into columns of edge `cell` over the two axes other than
 * the depth axis (dexel order) and fills xyz and orig. Within a column points
 * go by depth, then the other coordinates, then input index, so exact
 * duplicates end up adjacent and the order is deterministic. */
static tessel_status build_dexels(gp *g, const double ext[3], double cell)
{
    const float *src = g->cloud->xyz;
    size_t n = g->n;
    /* Bound the column array: at most 4 columns per point (plus a floor). */
    size_t max_cols = 4 * n + 4096;
    for (;;) {
        double cu = ext[g->au] / cell + 1.0, cv = ext[g->av] / cell + 1.0;
        if (cu * cv <= (double)max_cols && cu < 4e9 && cv < 4e9)
            break;
        cell *= 1.5;
    }
    g->cell = cell;
    g->inv_cell = 1.0 / cell;
    g->nu = (uint32_t)(ext[g->au] / cell) + 1;
    g->nv = (uint32_t)(ext[g->av] / cell) + 1;
    size_t ncols = (size_t)g->nu * g->nv;
    free(g->col);
    g->col = tsl_calloc_array(ncols + 1, sizeof *g->col);
    uint32_t *ord = tsl_alloc_array(n ? n : 1, sizeof *ord);
    if (!g->col || !ord) {
        free(ord);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        const float *p = src + 3 * i;
        uint32_t iu = grid_coord(p[g->au], g->glo[g->au], g->inv_cell, g->nu);
        uint32_t iv = grid_coord(p[g->av], g->glo[g->av], g->inv_cell, g->nv);
        g->col[(size_t)iv * g->nu + iu + 1]++;
    }
    for (size_t c = 0; c < ncols; c++)
        g->col[c + 1] += g->col[c];
    size_t maxcol = 0;
    for (size_t c = 0; c < ncols; c++)
        if (g->col[c + 1] - g->col[c] > maxcol)
            maxcol = g->col[c + 1] - g->col[c];
    /* Place (stable: input order inside a column), using col[c] as cursor
     * and shifting back afterwards. */
    for (size_t i = 0; i < n; i++) {
        const float *p = src + 3 * i;
        uint32_t iu = grid_coord(p[g->au], g->glo[g->au], g->inv_cell, g->nu);
        uint32_t iv = grid_coord(p[g->av], g->glo[g->av], g->inv_cell, g->nv);
        ord[g->col[(size_t)iv * g->nu + iu]++] = (uint32_t)i;
    }
    for (size_t c = ncols; c > 0; c--)
        g->col[c] = g->col[c - 1];
    g->col[0] = 0;
    gp_sortrec *rec = tsl_alloc_array(maxcol ? maxcol : 1, sizeof *rec);
    if (!rec) {
        free(ord);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t c = 0; c < ncols; c++) {
        size_t s = g->col[c], e = g->col[c + 1];
        for (size_t k = s; k < e; k++) {
            const float *p = src + 3 * (size_t)ord[k];
            rec[k - s].d = p[g->ad];
            rec[k - s].a = p[g->au];
            rec[k - s].b = p[g->av];
            rec[k - s].i = ord[k];
        }
        /* Insertion sort for the usual few dozen points per column. */
        if (e - s > 64) {
            qsort(rec, e - s, sizeof *rec, cmp_sortrec);
        } else {
            for (size_t k = 1; k < e - s; k++) {
                gp_sortrec x = rec[k];
                size_t j = k;
                while (j > 0 && cmp_sortrec(&rec[j - 1], &x) > 0) {
                    rec[j] = rec[j - 1];
                    j--;
                }
                rec[j] = x;
            }
        }
        for (size_t k = s; k < e; k++) {
            uint32_t i = rec[k - s].i;
            g->orig[k] = i;
            memcpy(g->xyz + 3 * k, src + 3 * (size_t)i, 3 * sizeof(float));
        }
    }
    free(rec);
    free(ord);
    return TESSEL_OK;
}

/* Collects into g->box (live) and g->boxd (completed, with triangles)
 * every point other than R that is not dead and lies in the axis-aligned
 * box of half-size `half` around R (section 4.1, first stage of the
 * distance criterion). Completed points whose triangles have all left
 * memory cost nothing further. */
tessel_status tsl_gp_scan_box(gp *g, uint32_t R, double half)
{
    double c[3];
    pos(g, R, c);
    const int ad = g->ad, au = g->au, av = g->av;
    /* Float bounds, widened by an ulp, reject most points outside the box
     * before the exact double test (float rounding is monotone). */
    const float *cf = g->xyz + 3 * (size_t)R;
    const float hf = tsl_float_up((float)half);
    const float lo_f = tsl_float_down((float)(c[ad] - half));
    const float hi_f = tsl_float_up((float)(c[ad] + half));
    const float cu = cf[au], cv = cf[av], cd = cf[ad];
    const double shell = half + 1e-6 * half;
    uint32_t iu0 = grid_coord(c[au] - half, g->glo[au], g->inv_cell, g->nu);
    uint32_t iu1 = grid_coord(c[au] + half, g->glo[au], g->inv_cell, g->nu);
    uint32_t iv0 = grid_coord(c[av] - half, g->glo[av], g->inv_cell, g->nv);
    uint32_t iv1 = grid_coord(c[av] + half, g->glo[av], g->inv_cell, g->nv);
    g->box_count = g->boxd_count = 0;
    for (uint32_t iv = iv0; iv <= iv1; iv++) {
        for (uint32_t iu = iu0; iu <= iu1; iu++) {
            size_t col = (size_t)iv * g->nu + iu;
            uint32_t s = g->col[col], e = g->col[col + 1];
            uint32_t lo = s, hi = e;
            while (lo < hi) {
                uint32_t mid = lo + (hi - lo) / 2;
                if (g->xyz[3 * (size_t)mid + ad] < lo_f)
                    lo = mid + 1;
                else
                    hi = mid;
            }
            for (uint32_t i = lo; i < e; i++) {
                const float *p = g->xyz + 3 * (size_t)i;
                if (p[ad] > hi_f)
                    break;
                float du = fabsf(p[au] - cu), dv = fabsf(p[av] - cv), dd = fabsf(p[ad] - cd);
                float df = du > dv ? du : dv;
                df = df > dd ? df : dd;
                /* df is the L-infinity distance rounded to float: a point
                 * within half has df <= hf. */
                if (df > hf || i == R)
                    continue;
                double dinf = (double)df;
                int s_i = st(g, i);
                if (s_i == ST_DEAD)
                    continue;
                /* Completed points without triangles are done with; a
                 * point whose float distance rounds beyond half is kept
                 * only if it has triangles near enough. */
                if (s_i == ST_DONE || dinf > half) {
                    if (g->head[i] == NONE)
                        continue;
                    if (dinf > half && dinf - shell > (double)g->maxe[i] * (1.0 + 1e-6))
                        continue;
                }
                gp_box *b;
                if (s_i == ST_DONE) {
                    if (g->boxd_count == g->boxd_cap &&
                        grow((void **)&g->boxd, &g->boxd_cap, g->boxd_count + 1, sizeof *b))
                        return TESSEL_ERR_NOMEM;
                    b = &g->boxd[g->boxd_count++];
                } else {
                    if (g->box_count == g->box_cap &&
                        grow((void **)&g->box, &g->box_cap, g->box_count + 1, sizeof *b))
                        return TESSEL_ERR_NOMEM;
                    b = &g->box[g->box_count++];
                }
                b->idx = i;
                b->dinf = df;
                b->rel[0] = p[0] - c[0];
                b->rel[1] = p[1] - c[1];
                b->rel[2] = p[2] - c[2];
            }
        }
    }
    return TESSEL_OK;
}

/* Distance from point i to its nearest point (state filter: live points
 * only when live_only) with positive distance, searching boxes that double
 * from `start` up to `limit`. Returns INFINITY when there is none within
 * limit. Uses g->box as scratch. */
tessel_status tsl_gp_nearest(gp *g, uint32_t i, int live_only, double start, double limit,
                             double *dist)
{
    *dist = INFINITY;
    for (double h = start;; h *= 2.0) {
        if (h > limit)
            h = limit;
        tessel_status s = tsl_gp_scan_box(g, i, h);
        if (s != TESSEL_OK)
            return s;
        double best = INFINITY;
        size_t nb = g->box_count + (live_only ? 0 : g->boxd_count);
        for (size_t k = 0; k < nb; k++) {
            const gp_box *b = k < g->box_count ? &g->box[k] : &g->boxd[k - g->box_count];
            double d2 = tsl_dot(b->rel, b->rel);
            if (d2 > 0.0 && d2 < best)
                best = d2;
        }
        /* Found within the box's inscribed sphere: exact nearest. */
        if (best <= h * h) {
            *dist = sqrt(best);
            return TESSEL_OK;
        }
        if (h >= limit) {
            if (best <= limit * limit)
                *dist = sqrt(best);
            return TESSEL_OK;
        }
    }
}

/* ---- retirement blocks: a triangle leaves memory once no live point is
 * near enough for a later triangle to reach it ---- */



/* One more dead block around each of the 27 blocks near block b. */
static void block_died(gp *g, size_t b)
{
    uint32_t bx = (uint32_t)(b % g->bn[0]);
    uint32_t by = (uint32_t)(b / g->bn[0] % g->bn[1]);
    uint32_t bz = (uint32_t)(b / g->bn[0] / g->bn[1]);
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                long x = (long)bx + dx, y = (long)by + dy, z = (long)bz + dz;
                if (x < 0 || y < 0 || z < 0 || x >= (long)g->bn[0] || y >= (long)g->bn[1] ||
                    z >= (long)g->bn[2])
                    continue;
                g->bdead[((size_t)z * g->bn[1] + (size_t)y) * g->bn[0] + (size_t)x]++;
            }
}

double tsl_gp_local_delta(const gp *g, uint32_t R, double core)
{
    /* A short triangle meeting the box has its first vertex within ell of
     * it. */
    const float *r = g->xyz + 3 * (size_t)R;
    double w = core + g->ell;
    uint32_t b0[3], b1[3];
    for (int k = 0; k < 3; k++) {
        b0[k] = grid_coord(r[k] - w, g->glo[k], g->inv_block, g->bn[k]);
        b1[k] = grid_coord(r[k] + w, g->glo[k], g->inv_block, g->bn[k]);
    }
    float l = 0.0f;
    for (uint32_t z = b0[2]; z <= b1[2]; z++)
        for (uint32_t y = b0[1]; y <= b1[1]; y++)
            for (uint32_t x = b0[0]; x <= b1[0]; x++) {
                float bl = g->bmaxl[((size_t)z * g->bn[1] + y) * g->bn[0] + x];
                l = bl > l ? bl : l;
            }
    double d = (double)l / sqrt(3.0) * (1.0 + 1e-6);
    return d < g->delta ? d : g->delta;
}

/* Point i stops being live (completed or left out). */
void tsl_gp_point_settled(gp *g, uint32_t i)
{
    size_t b = block_of(g, g->xyz + 3 * (size_t)i);
    if (--g->blive[b] == 0)
        block_died(g, b);
}

static tessel_status init_blocks(gp *g, const double ext[3], double width)
{
    for (;;) {
        double total = 1.0;
        for (int k = 0; k < 3; k++)
            total *= ext[k] / width + 1.0;
        if (total <= (double)((size_t)1 << 21))
            break;
        width *= 1.25;
    }
    g->inv_block = 1.0 / width;
    size_t nb = 1;
    for (int k = 0; k < 3; k++) {
        g->bn[k] = (uint32_t)(ext[k] / width) + 1;
        nb *= g->bn[k];
    }
    g->blive = tsl_calloc_array(nb, sizeof *g->blive);
    g->bdead = tsl_calloc_array(nb, sizeof *g->bdead);
    g->bmaxl = tsl_calloc_array(nb, sizeof *g->bmaxl);
    if (!g->blive || !g->bdead || !g->bmaxl)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < g->n; i++)
        if (st(g, (uint32_t)i) != ST_DEAD)
            g->blive[block_of(g, g->xyz + 3 * i)]++;
    /* Neighbours outside the grid count as dead. */
    for (size_t b = 0; b < nb; b++) {
        uint32_t c[3] = {(uint32_t)(b % g->bn[0]), (uint32_t)(b / g->bn[0] % g->bn[1]),
                         (uint32_t)(b / g->bn[0] / g->bn[1])};
        int inside = 1;
        for (int k = 0; k < 3; k++)
            inside *= 1 + (c[k] > 0) + (c[k] + 1 < g->bn[k]);
        g->bdead[b] = (uint8_t)(27 - inside);
    }
    for (size_t b = 0; b < nb; b++)
        if (g->blive[b] == 0)
            block_died(g, b);
    return TESSEL_OK;
}

/* ---- triangle pool, fans and output ---- */

tessel_status tsl_gp_flush_out(gp *g)
{
    if (g->out_count == 0)
        return TESSEL_OK;
    tessel_status s = g->sink->emit(g->sink->user_data, g->out, g->out_count);
    g->out_count = 0;
    return s;
}

/* Some held triangle uses the directed edge x -> y. */
int tsl_gp_edge_exists(const gp *g, uint32_t x, uint32_t y)
{
    for (uint32_t t = g->head[x]; t != NONE;) {
        const gp_tri *T = &g->tri[t];
        int k = tri_pos(T, x);
        if (T->v[(k + 1) % 3] == y)
            return 1;
        t = T->next[k];
    }
    return 0;
}

static size_t fan_size(const gp *g, uint32_t x)
{
    size_t c = 0;
    for (uint32_t t = g->head[x]; t != NONE; t = g->tri[t].next[tri_pos(&g->tri[t], x)])
        c++;
    return c;
}

/* ---- hashed cell tables (gp_cells) ---- */

/* Rebuilds the table with room for four times its non-empty cells (at
 * least 1024 slots), dropping the cells whose list is empty: the front
 * leaves empty cells behind, so the table follows the held band instead of
 * growing with every cell ever used. With no cell emptied it doubles. */
static tessel_status cells_rebuild(gp_cells *c)
{
    size_t live = 0;
    for (size_t i = 0; i < c->slots; i++)
        live += c->slot[i].key && c->slot[i].head != NONE;
    size_t slots = 1024;
    while (slots < 4 * (live + 1))
        slots *= 2;
    gp_cells n = {tsl_calloc_array(slots, sizeof *n.slot), slots, 0};
    if (!n.slot)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < c->slots; i++) {
        if (!c->slot[i].key || c->slot[i].head == NONE)
            continue;
        n.slot[cells_find(&n, c->slot[i].key - 1)] = c->slot[i];
        n.used++;
    }
    free(c->slot);
    *c = n;
    return TESSEL_OK;
}

/* The slot of key's cell, which is added with an empty list when missing
 * (the table grows first when half full). */
static tessel_status cells_slot(gp_cells *c, uint64_t key, size_t *slot)
{
    tessel_status s;
    if (2 * (c->used + 1) > c->slots && (s = cells_rebuild(c)) != TESSEL_OK)
        return s;
    size_t h = cells_find(c, key);
    if (!c->slot[h].key) {
        c->slot[h].key = key + 1;
        c->slot[h].head = NONE;
        c->used++;
    }
    *slot = h;
    return TESSEL_OK;
}

static void cells_free(gp_cells *c)
{
    free(c->slot);
    memset(c, 0, sizeof *c);
}

/* ---- long triangles: those with an edge longer than ell can meet a new
 * triangle without having a vertex in the box the guard looks at, so they
 * are also listed in a hashed grid ---- */

void tsl_gp_lg_cells(const gp *g, const float lo[3], const float hi[3], uint32_t c0[3],
                     uint32_t c1[3])
{
    for (int k = 0; k < 3; k++) {
        double a = (lo[k] - g->glo[k]) * g->lg_inv, b = (hi[k] - g->glo[k]) * g->lg_inv;
        c0[k] = a > 0.0 ? (a < 2097151.0 ? (uint32_t)a : 2097151u) : 0u;
        c1[k] = b > 0.0 ? (b < 2097151.0 ? (uint32_t)b : 2097151u) : 0u;
    }
}

static tessel_status long_register(gp *g, uint32_t t)
{
    float lo[3], hi[3];
    uint32_t c0[3], c1[3];
    tsl_gp_tri_box(g, g->tri[t].v, lo, hi);
    tsl_gp_lg_cells(g, lo, hi, c0, c1);
    for (uint32_t z = c0[2]; z <= c1[2]; z++)
        for (uint32_t y = c0[1]; y <= c1[1]; y++)
            for (uint32_t x = c0[0]; x <= c1[0]; x++) {
                size_t h;
                tessel_status s = cells_slot(&g->lg, lg_key(x, y, z), &h);
                if (s != TESSEL_OK)
                    return s;
                uint32_t e = g->lt_free;
                if (e != NONE) {
                    g->lt_free = g->lt_next[e];
                } else {
                    if (g->lt_used == g->lt_cap) {
                        size_t ct = g->lt_cap, cn = g->lt_cap;
                        if (grow((void **)&g->lt_tri, &ct, g->lt_used + 1, sizeof *g->lt_tri) ||
                            grow((void **)&g->lt_next, &cn, g->lt_used + 1, sizeof *g->lt_next))
                            return TESSEL_ERR_NOMEM;
                        g->lt_cap = ct < cn ? ct : cn;
                    }
                    e = (uint32_t)g->lt_used++;
                }
                g->lt_tri[e] = t;
                g->lt_next[e] = g->lg.slot[h].head;
                g->lg.slot[h].head = e;
            }
    return TESSEL_OK;
}

static void long_unregister(gp *g, uint32_t t)
{
    float lo[3], hi[3];
    uint32_t c0[3], c1[3];
    tsl_gp_tri_box(g, g->tri[t].v, lo, hi);
    tsl_gp_lg_cells(g, lo, hi, c0, c1);
    for (uint32_t z = c0[2]; z <= c1[2]; z++)
        for (uint32_t y = c0[1]; y <= c1[1]; y++)
            for (uint32_t x = c0[0]; x <= c1[0]; x++) {
                size_t h = cells_find(&g->lg, lg_key(x, y, z));
                if (!g->lg.slot[h].key)
                    continue;
                uint32_t *link = &g->lg.slot[h].head;
                while (*link != NONE && g->lt_tri[*link] != t)
                    link = &g->lt_next[*link];
                if (*link != NONE) {
                    uint32_t e = *link;
                    *link = g->lt_next[e];
                    g->lt_next[e] = g->lt_free;
                    g->lt_free = e;
                }
            }
}

/* Key of the cell of short triangle t's centroid. */
static uint64_t short_key(const gp *g, uint32_t t)
{
    const uint32_t *v = g->tri[t].v;
    uint32_t c[3];
    for (int k = 0; k < 3; k++) {
        double x = ((double)g->xyz[3 * (size_t)v[0] + (size_t)k] +
                    (double)g->xyz[3 * (size_t)v[1] + (size_t)k] +
                    (double)g->xyz[3 * (size_t)v[2] + (size_t)k]) / 3.0;
        c[k] = sg_coord(g, x, k);
    }
    return lg_key(c[0], c[1], c[2]);
}

/* Lists short triangle t in the cell of its centroid. */
static tessel_status short_register(gp *g, uint32_t t)
{
    size_t h;
    tessel_status s = cells_slot(&g->sg, short_key(g, t), &h);
    if (s != TESSEL_OK)
        return s;
    g->tsg_next[t] = g->sg.slot[h].head;
    g->sg.slot[h].head = t;
    return TESSEL_OK;
}

static void short_unregister(gp *g, uint32_t t)
{
    size_t h = cells_find(&g->sg, short_key(g, t));
    uint32_t *link = &g->sg.slot[h].head;
    while (*link != t)
        link = &g->tsg_next[*link];
    *link = g->tsg_next[t];
}

static tessel_status tri_alloc(gp *g, uint32_t *out)
{
    uint32_t t = g->tfree;
    if (t != NONE) {
        g->tfree = g->tri[t].next[0];
    } else {
        if (g->tused == g->tcap) {
            size_t cap = g->tcap ? g->tcap + g->tcap / 2 : 1024;
            if (cap >= NONE)
                return TESSEL_ERR_LIMIT;
            /* tsl_resize: huge pages once an array reaches 4 MB. */
            size_t old = g->tcap;
            if (tsl_resize((void **)&g->tri, old * sizeof *g->tri, cap * sizeof *g->tri) ||
                tsl_resize((void **)&g->tflag, old * sizeof *g->tflag, cap * sizeof *g->tflag) ||
                tsl_resize((void **)&g->tblock, old * sizeof *g->tblock,
                           cap * sizeof *g->tblock) ||
                tsl_resize((void **)&g->tstamp, old * sizeof *g->tstamp,
                           cap * sizeof *g->tstamp) ||
                tsl_resize((void **)&g->tsg_next, old * sizeof *g->tsg_next,
                           cap * sizeof *g->tsg_next) ||
                tsl_resize((void **)&g->tbox, old * 6 * sizeof *g->tbox,
                           cap * 6 * sizeof *g->tbox))
                return TESSEL_ERR_NOMEM;
            g->tcap = cap;
        }
        t = (uint32_t)g->tused++;
    }
    g->tflag[t] = TF_ALIVE;
    g->tstamp[t] = 0;
    *out = t;
    return TESSEL_OK;
}

/* Emits (unless it was given as existing) and frees held triangle t. */
static tessel_status tri_retire(gp *g, uint32_t t)
{
    gp_tri *T = &g->tri[t];
    if (!(g->tflag[t] & TF_EXISTING)) {
        for (int k = 0; k < 3; k++)
            g->out[3 * g->out_count + (size_t)k] = g->orig[T->v[k]];
        if (++g->out_count == OUT_BATCH) {
            tessel_status s = tsl_gp_flush_out(g);
            if (s != TESSEL_OK)
                return s;
        }
        g->sum.triangles++;
    }
    if (g->tflag[t] & TF_LONG)
        long_unregister(g, t);
    else
        short_unregister(g, t);
    for (int k = 0; k < 3; k++) {
        uint32_t v = T->v[k];
        uint32_t *link = &g->head[v];
        while (*link != t) {
            gp_tri *U = &g->tri[*link];
            link = &U->next[tri_pos(U, v)];
        }
        *link = T->next[k];
    }
    g->tflag[t] = 0;
    T->next[0] = g->tfree;
    g->tfree = t;
    g->talive--;
    return TESSEL_OK;
}

/* Retires every held triangle whose surroundings have no live point left. */
/* No live point in the blocks within k rings of block b. */
static int blocks_dead(const gp *g, size_t b, long k)
{
    long c[3] = {(long)(b % g->bn[0]), (long)(b / g->bn[0] % g->bn[1]),
                 (long)(b / g->bn[0] / g->bn[1])};
    long lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = c[a] - k < 0 ? 0 : c[a] - k;
        hi[a] = c[a] + k >= (long)g->bn[a] ? (long)g->bn[a] - 1 : c[a] + k;
    }
    for (long z = lo[2]; z <= hi[2]; z++)
        for (long y = lo[1]; y <= hi[1]; y++)
            for (long x = lo[0]; x <= hi[0]; x++)
                if (g->blive[((size_t)z * g->bn[1] + (size_t)y) * g->bn[0] + (size_t)x])
                    return 0;
    return 1;
}

/* Triangle t can never meet a later triangle: a later one lies within
 * 2 * rho_cap of a live point (its reference point), t within its longest
 * edge of its first vertex, and no live point is that near. Blocks are
 * 2 * rho_cap + ell wide, so for triangles up to ell the 27 blocks around
 * suffice; longer ones look further. */
static int retirable(const gp *g, uint32_t t)
{
    const gp_tri *T = &g->tri[t];
    size_t b = g->tblock[t];
    if (g->bdead[b] != 27)
        return 0;
    if (!(g->tflag[t] & TF_LONG))
        return 1;
    double p[3][3], d[3], l2 = 0.0;
    for (int k = 0; k < 3; k++)
        pos(g, T->v[k], p[k]);
    for (int k = 0; k < 3; k++) {
        tsl_sub(p[k], p[(k + 1) % 3], d);
        l2 = fmax(l2, tsl_dot(d, d));
    }
    long rings = (long)ceil((2.0 * g->rho_cap + sqrt(l2)) * g->inv_block);
    return rings <= 1 || blocks_dead(g, b, rings);
}

tessel_status tsl_gp_sweep(gp *g, int all)
{
    for (size_t t = 0; t < g->tused; t++) {
        if (!(g->tflag[t] & TF_ALIVE))
            continue;
        if (!all && !retirable(g, (uint32_t)t))
            continue;
        tessel_status s = tri_retire(g, (uint32_t)t);
        if (s != TESSEL_OK)
            return s;
    }
    g->created_since_sweep = 0;
    g->alive_after_sweep = g->talive;
    return TESSEL_OK;
}

/* ---- components: union-find over labels ---- */

static tessel_status uf_new(gp *g, uint32_t *label)
{
    if (grow((void **)&g->uf, &g->uf_cap, g->uf_count + 1, sizeof *g->uf))
        return TESSEL_ERR_NOMEM;
    *label = (uint32_t)g->uf_count;
    g->uf[g->uf_count] = (uint32_t)g->uf_count;
    g->uf_count++;
    return TESSEL_OK;
}

static void uf_union(gp *g, uint32_t a, uint32_t b)
{
    a = tsl_uf_find(g->uf, a);
    b = tsl_uf_find(g->uf, b);
    if (a != b)
        g->uf[a < b ? b : a] = a < b ? a : b;
}

static void enqueue(gp *g, uint32_t i)
{
    if (g->state[i] & ST_QUEUED)
        return;
    g->state[i] |= ST_QUEUED;
    g->queue[(g->qhead + g->qcount) % g->n] = i;
    g->qcount++;
}

/* Links triangle (a, b, c) into the pool and the points' lists and joins
 * components. Fans are updated by the caller. */
tessel_status tsl_gp_tri_add(gp *g, uint32_t a, uint32_t b, uint32_t c, int existing,
                             uint32_t *out)
{
    uint32_t v[3] = {a, b, c};
    uint32_t t;
    tessel_status s = tri_alloc(g, &t);
    if (s != TESSEL_OK)
        return s;
    gp_tri *T = &g->tri[t];
    uint32_t lab = NONE;
    for (int k = 0; k < 3; k++) {
        T->v[k] = v[k];
        T->next[k] = g->head[v[k]];
        g->head[v[k]] = t;
        if (g->label[v[k]] != NONE) {
            if (lab == NONE)
                lab = g->label[v[k]];
            else
                uf_union(g, lab, g->label[v[k]]);
        }
    }
    if (lab == NONE && (s = uf_new(g, &lab)) != TESSEL_OK)
        return s;
    for (int k = 0; k < 3; k++)
        if (g->label[v[k]] == NONE)
            g->label[v[k]] = lab;
    if (existing)
        g->tflag[t] |= TF_EXISTING;
    tsl_gp_tri_box(g, v, g->tbox + 6 * (size_t)t, g->tbox + 6 * (size_t)t + 3);
    g->tblock[t] = (uint32_t)block_of(g, g->xyz + 3 * (size_t)a);
    double pa[3], pb[3], pc[3], d[3];
    pos(g, a, pa);
    pos(g, b, pb);
    pos(g, c, pc);
    double l[3];
    tsl_sub(pa, pb, d);
    l[0] = sqrt(tsl_dot(d, d)); /* ab */
    tsl_sub(pb, pc, d);
    l[1] = sqrt(tsl_dot(d, d)); /* bc */
    tsl_sub(pc, pa, d);
    l[2] = sqrt(tsl_dot(d, d)); /* ca */
    double lmax = dmax(l[0], dmax(l[1], l[2]));
    /* Rounded up so that it bounds the true length. */
    float la = (float)(dmax(l[0], l[2]) * (1.0 + 1e-6));
    float lb = (float)(dmax(l[0], l[1]) * (1.0 + 1e-6));
    float lc = (float)(dmax(l[1], l[2]) * (1.0 + 1e-6));
    if (la > g->maxe[a])
        g->maxe[a] = la;
    if (lb > g->maxe[b])
        g->maxe[b] = lb;
    if (lc > g->maxe[c])
        g->maxe[c] = lc;
    if (lmax > g->ell) {
        g->tflag[t] |= TF_LONG;
        if ((s = long_register(g, t)) != TESSEL_OK)
            return s;
    } else {
        float lm = (float)(lmax * (1.0 + 1e-6));
        float *bl = &g->bmaxl[g->tblock[t]];
        if (lm > *bl)
            *bl = lm;
        if ((s = short_register(g, t)) != TESSEL_OK)
            return s;
    }
    g->talive++;
    g->created_since_sweep++;
    if (g->talive > g->sum.peak_held_triangles)
        g->sum.peak_held_triangles = g->talive;
    if (out)
        *out = t;
    return TESSEL_OK;
}

int tsl_gp_link_check(const gp *g, uint32_t p, uint32_t a, uint32_t b, int edges)
{
    if (g->head[p] == NONE)
        return LINK_NEW;
    if (st(g, p) == ST_DONE)
        return LINK_FAIL;
    uint32_t s = g->ls[p], e = g->le[p];
    if (b == s && a == e)
        return fan_size(g, p) + (size_t)edges >= 3 ? LINK_CLOSE : LINK_FAIL;
    if (b == s)
        return LINK_PREPEND;
    if (a == e)
        return LINK_APPEND;
    return LINK_FAIL;
}

/* Applies a checked link change to point p (not the reference point). */
void tsl_gp_link_apply(gp *g, uint32_t p, uint32_t a, uint32_t b, int how, int is_ref)
{
    switch (how) {
    case LINK_NEW:
        g->ls[p] = a;
        g->le[p] = b;
        if (!is_ref && st(g, p) == ST_FREE) {
            g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_FRINGE);
            g->sum.points_used++;
            enqueue(g, p);
        } else if (is_ref && st(g, p) == ST_FREE) {
            g->sum.points_used++;
        }
        break;
    case LINK_PREPEND:
        g->ls[p] = a;
        break;
    case LINK_APPEND:
        g->le[p] = b;
        break;
    case LINK_CLOSE:
        g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_DONE);
        g->ls[p] = g->le[p] = NONE;
        tsl_gp_point_settled(g, p);
        return;
    default:
        return;
    }
    /* A boundary point whose fan a neighbour changed may close now. */
    if (!is_ref && st(g, p) == ST_BOUNDARY && (g->state[p] >> 4) < MAX_VISITS)
        enqueue(g, p);
}

/* ---- set-up ---- */

void tsl_gp_free(gp *g)
{
    free(g->xyz);
    free(g->orig);
    free(g->state);
    free(g->head);
    free(g->ls);
    free(g->le);
    free(g->label);
    free(g->maxe);
    free(g->col);
    free(g->blive);
    free(g->bdead);
    free(g->bmaxl);
    cells_free(&g->lg);
    free(g->tri);
    free(g->tflag);
    free(g->tblock);
    free(g->tstamp);
    free(g->lt_tri);
    free(g->lt_next);
    cells_free(&g->sg);
    free(g->tsg_next);
    free(g->tbox);
    free(g->queue);
    free(g->seed_order);
    free(g->uf);
    free(g->out);
    free(g->box);
    free(g->boxd);
    free(g->cand);
    free(g->seq);
    free(g->far);
    free(g->hide);
    free(g->gt);
    free(g->pmark);
    free(g->hn);
}

static inline uint32_t depth_key(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

/* Seed order: dexel indices by increasing depth (LSD radix sort, stable;
 * g->queue serves as scratch). The keys travel with the indices, so no
 * pass reads the points through the permutation (on the 10^6 sphere that
 * was 6.3 M cache misses of 33 M in the whole front). */
static tessel_status order_seeds(gp *g)
{
    uint32_t *a = g->seed_order, *b = g->queue;
    uint32_t *ka = tsl_alloc_array(g->n ? g->n : 1, sizeof *ka);
    uint32_t *kb = tsl_alloc_array(g->n ? g->n : 1, sizeof *kb);
    if (!ka || !kb) {
        free(ka);
        free(kb);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < g->n; i++) {
        a[i] = (uint32_t)i;
        ka[i] = depth_key(g->xyz[3 * i + g->ad]);
    }
    for (int shift = 0; shift < 32; shift += 8) {
        size_t count[257] = {0};
        for (size_t i = 0; i < g->n; i++)
            count[((ka[i] >> shift) & 255) + 1]++;
        for (int k = 0; k < 256; k++)
            count[k + 1] += count[k];
        for (size_t i = 0; i < g->n; i++) {
            size_t to = count[(ka[i] >> shift) & 255]++;
            b[to] = a[i];
            kb[to] = ka[i];
        }
        uint32_t *t = a;
        a = b;
        b = t;
        t = ka;
        ka = kb;
        kb = t;
    }
    /* Four passes: the result is back in seed_order. */
    free(ka);
    free(kb);
    return TESSEL_OK;
}

/* Mean distance to the nearest other point, on an even sample. */
/* Mean nearest distance over a sample of the points (far outliers left
 * out), and the coefficient of variation of those distances. */
/* mu from the sampling (tessel_greedy_params.mu_from_sampling): the median
 * over a sample of d1 / mean(d1 .. d6), the nearest distance against the
 * mean of the six nearest, is 0.507 for a uniform random sample (points
 * come in close pairs), 0.73 for Poisson-disk samples and 0.59-0.88 for
 * the vertices of scanned meshes, where mu 2 does best (man.ply: 15
 * components at mu 2, 16-47 at 2.6-3; a uniform random bunny of 10^6
 * points: 8 components at mu 2, 1 at 2.5-3). */
#define MU_EVEN 2.0
#define MU_RANDOM 3.0
#define RATIO_EVEN 0.58
#define RATIO_RANDOM 0.51
#define RATIO_SAMPLE 2048


/* d1 / mean(d1 .. d6) at point i, boxes doubling from start up to limit;
 * NaN with fewer than six neighbours within limit. */
static tessel_status nearest_ratio(gp *g, uint32_t i, double start, double limit, double *ratio)
{
    *ratio = NAN;
    for (double h = start;; h *= 2.0) {
        if (h > limit)
            h = limit;
        tessel_status s = tsl_gp_scan_box(g, i, h);
        if (s != TESSEL_OK)
            return s;
        double d[6];
        int n = 0;
        size_t nb = g->box_count + g->boxd_count;
        for (size_t k = 0; k < nb; k++) {
            const gp_box *b = k < g->box_count ? &g->box[k] : &g->boxd[k - g->box_count];
            double d2 = tsl_dot(b->rel, b->rel);
            if (!(d2 > 0.0) || d2 > h * h)
                continue;
            /* Insertion into the six smallest. */
            int j = n < 6 ? n++ : 6;
            while (j > 0 && d[j - 1] > d2) {
                if (j < 6)
                    d[j] = d[j - 1];
                j--;
            }
            if (j < 6)
                d[j] = d2;
        }
        if (n == 6) {
            double m = 0.0;
            for (int j = 0; j < 6; j++)
                m += sqrt(d[j]);
            *ratio = 6.0 * sqrt(d[0]) / m;
            return TESSEL_OK;
        }
        if (h >= limit)
            return TESSEL_OK;
    }
}

/* mu from the median nearest-distance ratio over a sample of the points. */
static tessel_status mu_from_sampling(gp *g, double spacing, double *mu)
{
    size_t k = g->n < RATIO_SAMPLE ? g->n : RATIO_SAMPLE, used = 0;
    double *r = tsl_alloc_array(k ? k : 1, sizeof *r);
    if (!r)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < k; i++) {
        uint32_t idx = (uint32_t)((double)i * (double)g->n / (double)k);
        double x;
        tessel_status s = nearest_ratio(g, idx, spacing, 16.0 * spacing, &x);
        if (s != TESSEL_OK) {
            free(r);
            return s;
        }
        if (x == x)
            r[used++] = x;
    }
    if (used) {
        qsort(r, used, sizeof *r, cmp_double);
        double t = (RATIO_EVEN - r[used / 2]) / (RATIO_EVEN - RATIO_RANDOM);
        *mu = MU_EVEN + (MU_RANDOM - MU_EVEN) * (t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t);
    }
    free(r);
    return TESSEL_OK;
}

static tessel_status estimate_spacing(gp *g, double *spacing)
{
    size_t k = g->n < 2048 ? g->n : 2048;
    double sum = 0.0;
    size_t used = 0;
    double limit = 64.0 * g->cell;
    for (size_t i = 0; i < k; i++) {
        uint32_t idx = (uint32_t)((double)i * (double)g->n / (double)k);
        double d;
        tessel_status s = tsl_gp_nearest(g, idx, 0, 0.5 * g->cell, limit, &d);
        if (s != TESSEL_OK)
            return s;
        if (d <= limit) {
            sum += d;
            used++;
        }
    }
    *spacing = used ? sum / (double)used : 0.0;
    return TESSEL_OK;
}

/* Of exact duplicates, init keeps the first in dexel order. When an
 * existing triangle names another of them, or another is frozen, that one
 * is kept instead: the caller's triangles and the new ones must name the
 * same point (else the two meet at a position without sharing a vertex).
 * The former keep becomes a duplicate of it. Points left out but for
 * duplicates come later, so every dead point here is a duplicate. Of two
 * both named the first keeps the position (such a mesh touches itself
 * there, which the mesh check calls invalid). */
static tessel_status adopt_used_duplicates(gp *g, const uint32_t *tris, size_t count,
                                           const uint8_t *frozen, const uint32_t *inv)
{
    uint8_t *named = tsl_calloc_array(g->n, sizeof *named);
    if (!named)
        return TESSEL_ERR_NOMEM;
    for (size_t c = 0; c < 3 * count; c++)
        if (tris[c] < g->n)
            named[inv[tris[c]]] = 1;
    for (size_t i = 0; frozen && i < g->n; i++)
        named[i] |= frozen[g->orig[i]];
    for (size_t c = 0; c < 3 * count + g->n; c++) {
        uint32_t v;
        if (c < 3 * count && tris[c] < g->n)
            v = inv[tris[c]];
        else if (c >= 3 * count && frozen && frozen[g->orig[c - 3 * count]])
            v = (uint32_t)(c - 3 * count);
        else
            continue;
        uint32_t k = v;
        while (st(g, k) == ST_DEAD)
            k = g->ls[k];
        if (k == v || named[k])
            continue;
        uint8_t sv = g->state[v];
        g->state[v] = g->state[k];
        g->state[k] = sv;
        g->ls[v] = g->ls[k];
        g->ls[k] = v;
        named[k] = 1; /* its other duplicates reach v through it */
    }
    free(named);
    return TESSEL_OK;
}

/* Imports params->existing: links the triangles, then derives every touched
 * point's fan; fans that are not a single path or cycle, or edges used twice
 * in one direction, make the input invalid. A frozen point (frozen may be
 * NULL) is completed as it stands, whatever its fan here, also with no
 * triangle here (its triangles are elsewhere: no new one may touch it). */
tessel_status tsl_gp_import_existing(gp *g, const uint32_t *tris, size_t count,
                                     const uint8_t *frozen)
{
    uint32_t *inv = tsl_alloc_array(g->n, sizeof *inv);
    if (!inv)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < g->n; i++)
        inv[g->orig[i]] = (uint32_t)i;
    tessel_status s = adopt_used_duplicates(g, tris, count, frozen, inv);
    for (size_t t = 0; t < count && s == TESSEL_OK; t++) {
        uint32_t v[3];
        for (int k = 0; k < 3; k++) {
            uint32_t o = tris[3 * t + (size_t)k];
            if (o >= g->n) {
                s = TESSEL_ERR_INVALID_ARG;
                break;
            }
            v[k] = inv[o];
            while (st(g, v[k]) == ST_DEAD)
                v[k] = g->ls[v[k]]; /* a duplicate: its kept twin */
        }
        if (s != TESSEL_OK)
            break;
        if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0]) {
            s = TESSEL_ERR_INVALID_ARG;
            break;
        }
        s = tsl_gp_tri_add(g, v[0], v[1], v[2], 1, NULL);
    }
    free(inv);
    if (s != TESSEL_OK)
        return s;
    for (size_t t = 0; t < g->tused; t++) {
        for (int k = 0; k < 3; k++) {
            uint32_t p = g->tri[t].v[k];
            if (st(g, p) != ST_FREE)
                continue;
            if (frozen && frozen[g->orig[p]]) {
                g->sum.points_used++;
                g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_DONE);
                tsl_gp_point_settled(g, p);
                continue;
            }
            /* Link edges x -> y of p's triangles; a path or a cycle? */
            size_t edges = 0;
            uint32_t start = NONE;
            for (uint32_t u = g->head[p]; u != NONE;) {
                const gp_tri *T = &g->tri[u];
                int q = tri_pos(T, p);
                uint32_t x = T->v[(q + 1) % 3];
                int has_in = 0;
                size_t outs = 0;
                for (uint32_t w = g->head[p]; w != NONE;) {
                    const gp_tri *W = &g->tri[w];
                    int r = tri_pos(W, p);
                    has_in |= W->v[(r + 2) % 3] == x;
                    outs += W->v[(r + 1) % 3] == x;
                    w = W->next[r];
                }
                if (outs > 1)
                    return TESSEL_ERR_INVALID_ARG;
                if (!has_in) {
                    if (start != NONE)
                        return TESSEL_ERR_INVALID_ARG; /* two fans */
                    start = x;
                }
                edges++;
                u = T->next[q];
            }
            /* Walk the link from start (or any edge for a cycle). */
            uint32_t first = start;
            if (first == NONE) {
                const gp_tri *T = &g->tri[g->head[p]];
                first = T->v[(tri_pos(T, p) + 1) % 3];
            }
            uint32_t x = first, last = first;
            size_t walked = 0;
            for (;;) {
                uint32_t y = NONE;
                for (uint32_t w = g->head[p]; w != NONE;) {
                    const gp_tri *W = &g->tri[w];
                    int r = tri_pos(W, p);
                    if (W->v[(r + 1) % 3] == x)
                        y = W->v[(r + 2) % 3];
                    w = W->next[r];
                }
                if (y == NONE)
                    break;
                walked++;
                last = y;
                x = y;
                if (x == first || walked > edges)
                    break;
            }
            if (walked != edges)
                return TESSEL_ERR_INVALID_ARG;
            g->sum.points_used++;
            if (start == NONE) {
                if (edges < 3)
                    return TESSEL_ERR_INVALID_ARG;
                g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_DONE);
                tsl_gp_point_settled(g, p);
            } else {
                g->ls[p] = start;
                g->le[p] = last;
                g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_FRINGE);
                enqueue(g, p);
            }
        }
    }
    for (size_t p = 0; frozen && p < g->n; p++)
        if (frozen[g->orig[p]] && st(g, (uint32_t)p) == ST_FREE) {
            g->sum.points_used++;
            g->state[p] = (uint8_t)((g->state[p] & ~ST_MASK) | ST_DONE);
            tsl_gp_point_settled(g, (uint32_t)p);
        }
    return TESSEL_OK;
}

tessel_status tsl_gp_init(gp *g)
{
    size_t n = g->n;
    const float *src = g->cloud->xyz;
    g->xyz = tsl_alloc_array(n, 3 * sizeof(float));
    g->orig = tsl_alloc_array(n, sizeof *g->orig);
    g->state = tsl_calloc_array(n, 1);
    g->head = tsl_alloc_array(n, sizeof *g->head);
    g->ls = tsl_alloc_array(n, sizeof *g->ls);
    g->le = tsl_alloc_array(n, sizeof *g->le);
    g->label = tsl_alloc_array(n, sizeof *g->label);
    g->maxe = tsl_calloc_array(n, sizeof *g->maxe);
    g->queue = tsl_alloc_array(n, sizeof *g->queue);
    g->seed_order = tsl_alloc_array(n, sizeof *g->seed_order);
    g->out = tsl_alloc_array(OUT_BATCH, 3 * sizeof *g->out);
    g->pmark = tsl_calloc_array(n, sizeof *g->pmark);
    if (!g->xyz || !g->orig || !g->state || !g->head || !g->ls || !g->le || !g->label ||
        !g->queue || !g->seed_order || !g->out || !g->maxe || !g->pmark)
        return TESSEL_ERR_NOMEM;
    memset(g->head, 0xff, n * sizeof *g->head);
    memset(g->ls, 0xff, n * sizeof *g->ls);
    memset(g->le, 0xff, n * sizeof *g->le);
    memset(g->label, 0xff, n * sizeof *g->label);
    g->tfree = NONE;
    g->lt_free = NONE;

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            double x = src[3 * i + (size_t)k];
            if (!isfinite(x))
                return TESSEL_ERR_INVALID_ARG;
            lo[k] = dmin(lo[k], x);
            hi[k] = dmax(hi[k], x);
        }
    /* The arrays cover a robust extent: from the 0.1% to the 99.9%
     * quantile of a sample, widened by 5%. Points beyond land in the border
     * columns and blocks (coordinates are clamped), so one far outlier does
     * not stretch every column over the whole cloud. */
    double ext[3];
    size_t ns = n < 8192 ? n : 8192;
    double *sample = tsl_alloc_array(ns, sizeof *sample);
    if (!sample)
        return TESSEL_ERR_NOMEM;
    for (int k = 0; k < 3; k++) {
        for (size_t i = 0; i < ns; i++)
            sample[i] = src[3 * (size_t)((double)i * (double)n / (double)ns) + (size_t)k];
        qsort(sample, ns, sizeof *sample, cmp_double);
        double qlo = sample[ns / 1000], qhi = sample[ns - 1 - ns / 1000];
        double pad = 0.05 * (qhi - qlo);
        double rlo = fmax(lo[k], qlo - pad), rhi = fmin(hi[k], qhi + pad);
        g->glo[k] = rlo;
        ext[k] = rhi - rlo;
    }
    free(sample);
    g->ad = 0;
    for (int k = 1; k < 3; k++)
        if (ext[k] > ext[g->ad])
            g->ad = k;
    g->au = (g->ad + 1) % 3;
    g->av = (g->ad + 2) % 3;
    double emax = fmax(ext[0], fmax(ext[1], ext[2]));
    if (!(emax > 0.0))
        emax = 1.0;
    double area = ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0];
    if (!(area > 0.0))
        area = emax * emax;
    double cell = 3.0 * sqrt(area / (double)n);
    if (!(cell > 0.0))
        cell = emax;
    tessel_status s = build_dexels(g, ext, cell);
    if (s != TESSEL_OK)
        return s;
    double spacing;
    if ((s = estimate_spacing(g, &spacing)) != TESSEL_OK)
        return s;
    if (!(spacing > 0.0))
        spacing = g->cell / 3.0;
    if (g->cell < 2.0 * spacing || g->cell > 5.0 * spacing) {
        if ((s = build_dexels(g, ext, 3.0 * spacing)) != TESSEL_OK)
            return s;
    }
    g->spacing = spacing;
    g->sum.spacing = spacing;
    if (g->mu_from_sampling && spacing > 0.0 &&
        (s = mu_from_sampling(g, spacing, &g->mu)) != TESSEL_OK)
        return s;
    g->sum.mu = g->mu;
    g->m_cap = g->max_spacing * spacing;
    g->m_floor = 0.05 * spacing;
    /* Edges reach mu times the nearest distance, which on uniformly random
     * samples is often twice the mean: there 43% of the triangles of a 10^6
     * bunny had an edge over 3 spacings (none on even samples). Long
     * triangles are listed in every cell of the long grid their box meets,
     * which the guard then walks (--stream: 6.9 -> 5.7 s, 160 -> 121 MiB). */
    g->ell = ELL_MU * g->mu * spacing;
    g->delta = g->ell / sqrt(3.0);
    g->lg_inv = 1.0 / (2.0 * (g->mu * spacing + g->delta));
    g->sg_inv = 1.0 / g->ell;

    /* Exact duplicates (adjacent in dexel order): keep the first. */
    size_t ncols = (size_t)g->nu * g->nv;
    for (size_t c = 0; c < ncols; c++)
        for (uint32_t i = g->col[c] + 1; i < g->col[c + 1]; i++) {
            const float *p = g->xyz + 3 * (size_t)i, *q = p - 3;
            if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]) {
                uint32_t keep = st(g, i - 1) == ST_DEAD ? g->ls[i - 1] : i - 1;
                g->state[i] = ST_DEAD;
                g->ls[i] = keep;
                g->sum.left_duplicate++;
            }
        }
    g->rho_cap = g->mu * g->m_cap;
    if ((s = init_blocks(g, ext, 2.0 * g->rho_cap + g->ell)) != TESSEL_OK)
        return s;
    return order_seeds(g);
}
