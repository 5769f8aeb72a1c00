/* Edge splits of a triangle mesh, checked (mesh/edit.c): one at a time,
 * or many in parallel blocks, deterministically (tsl_edit_splits). The
 * refinement (Mederos, Velho & de Figueiredo 2003, section 2.5) chooses
 * the edges and the new vertices' positions. */
#include "mesh/edit.h"

#include <stdlib.h>
#include <string.h>

/* Whether the triangles of the edge at h (twin g) are skinny (the paper's
 * ratio test: a triangle whose shortest edge is under min_ratio times its
 * longest is not divided). */
static bool split_skinny(const tsl_edit *r, uint32_t h, uint32_t g, double min_ratio)
{
    uint32_t sides[2] = {h / 3, g == NONE ? NONE : g / 3};
    for (int s = 0; s < 2; s++) {
        if (sides[s] == NONE)
            continue;
        double p[3][3], lmin = INFINITY, lmax = 0.0;
        for (int i = 0; i < 3; i++)
            tsl_edit_point(r, r->tri[3 * (size_t)sides[s] + i], p[i]);
        for (int i = 0; i < 3; i++) {
            double d[3];
            tsl_sub(p[(i + 1) % 3], p[i], d);
            double l = tsl_norm(d);
            lmin = l < lmin ? l : lmin;
            lmax = l > lmax ? l : lmax;
        }
        if (!(lmin >= min_ratio * lmax))
            return true;
    }
    return false;
}

/* Splits the edge at h at pos into the vertex m and the triangles T3 (and
 * T4 when the edge has a twin), whose room the caller made. */
static void split_apply(tsl_edit *r, uint32_t h, const float pos[3], uint32_t m, uint32_t T3,
                        uint32_t T4, split_info *s)
{
    uint32_t g = r->twin[h];
    uint32_t T1 = h / 3, i = h % 3, T2 = g == NONE ? NONE : g / 3, j = g == NONE ? 0 : g % 3;
    s->T1 = T1, s->T2 = T2, s->i = i, s->j = j, s->m = m, s->T3 = T3;
    s->T4 = T2 == NONE ? NONE : T4;
    memcpy(s->tri, r->tri + 3 * (size_t)T1, 3 * sizeof *s->tri);
    memcpy(s->twin, r->twin + 3 * (size_t)T1, 3 * sizeof *s->twin);
    box_load(r, T1, s->box);
    double old1[3], old2[3] = {0.0, 0.0, 0.0};
    tsl_edit_tri_cross(r, T1, old1);
    tsl_normalize(old1);
    if (T2 != NONE) {
        memcpy(s->tri + 3, r->tri + 3 * (size_t)T2, 3 * sizeof *s->tri);
        memcpy(s->twin + 3, r->twin + 3 * (size_t)T2, 3 * sizeof *s->twin);
        box_load(r, T2, s->box + 6);
        tsl_edit_tri_cross(r, T2, old2);
        tsl_normalize(old2);
    }
    uint32_t x = r->tri[3 * T1 + i], y = r->tri[3 * T1 + (i + 1) % 3];
    uint32_t a = r->tri[3 * T1 + (i + 2) % 3];
    s->x = x, s->y = y, s->a = a, s->b = NONE;
    for (int c = 0; c < 3; c++)
        r->xyz_own[3 * (size_t)m + c] = pos[c];
    if (r->rgb)
        for (int c = 0; c < 3; c++)
            r->rgb[3 * (size_t)m + c] =
                (uint8_t)((r->rgb[3 * (size_t)x + c] + r->rgb[3 * (size_t)y + c] + 1) / 2);
    uint32_t h_ya = 3 * T1 + (i + 1) % 3, tw_ya = r->twin[h_ya];
    r->tri[3 * T1 + (i + 1) % 3] = m;
    r->tri[3 * T3] = m;
    r->tri[3 * T3 + 1] = y;
    r->tri[3 * T3 + 2] = a;
    uint32_t tw_xb = NONE;
    if (T2 != NONE) {
        s->b = r->tri[3 * T2 + (j + 2) % 3];
        tw_xb = r->twin[3 * T2 + (j + 1) % 3];
        r->tri[3 * T2 + (j + 1) % 3] = m;
        r->tri[3 * T4] = m;
        r->tri[3 * T4 + 1] = x;
        r->tri[3 * T4 + 2] = s->b;
    }
    /* Twins. T1: x->m (slot i), m->a (slot i+1), a->x (slot i+2, kept). */
    set_twin(r, 3 * T1 + (i + 1) % 3, 3 * T3 + 2); /* m->a / a->m */
    set_twin(r, 3 * T3 + 1, tw_ya);                /* y->a */
    if (T2 != NONE) {
        set_twin(r, 3 * T1 + i, 3 * T4);               /* x->m / m->x */
        set_twin(r, 3 * T3, 3 * T2 + j);               /* m->y / y->m */
        set_twin(r, 3 * T2 + (j + 1) % 3, 3 * T4 + 2); /* m->b / b->m */
        set_twin(r, 3 * T4 + 1, tw_xb);                /* x->b */
    } else {
        set_twin(r, 3 * T1 + i, NONE);
        set_twin(r, 3 * T3, NONE);
    }
    s->news[0] = T1, s->news[1] = T3, s->news[2] = T2, s->news[3] = T4;
    s->count = T2 != NONE ? 4 : 2;
    for (int c = 0; c < 3; c++) {
        s->olds[0][c] = s->olds[1][c] = old1[c];
        s->olds[2][c] = s->olds[3][c] = old2[c];
    }
}

/* Takes split s back: T1 and T2 as they were (corners, twins both ways,
 * boxes); m, T3 and T4 are left unreferenced. */
static void split_undo(tsl_edit *r, const split_info *s)
{
    const uint32_t T[2] = {s->T1, s->T2};
    for (int k = 0; k < 2 && T[k] != NONE; k++) {
        memcpy(r->tri + 3 * (size_t)T[k], s->tri + 3 * k, 3 * sizeof *s->tri);
        box_store(r, T[k], s->box + 6 * k);
    }
    for (int k = 0; k < 2 && T[k] != NONE; k++)
        for (uint32_t q = 0; q < 3; q++)
            set_twin(r, 3 * T[k] + q, s->twin[3 * k + q]);
}

/* The edge map after split s: x-y gone, its six (or four) edges at their
 * half-edges. */
static tessel_status split_map(tsl_edit *r, const split_info *s)
{
    uint32_t T1 = s->T1, T2 = s->T2, T3 = s->T3, T4 = s->T4, i = s->i, j = s->j, m = s->m;
    tessel_status st;
    tsl_edge_map_del(&r->edges, s->x, s->y);
    if ((st = tsl_edge_map_put(&r->edges, s->x, m, 3 * T1 + i)) ||
        (st = tsl_edge_map_put(&r->edges, m, s->y, 3 * T3)) ||
        (st = tsl_edge_map_put(&r->edges, m, s->a, 3 * T1 + (i + 1) % 3)) ||
        (st = tsl_edge_map_put(&r->edges, s->y, s->a, 3 * T3 + 1)))
        return st;
    if (T2 != NONE && ((st = tsl_edge_map_put(&r->edges, m, s->b, 3 * T2 + (j + 1) % 3)) ||
                       (st = tsl_edge_map_put(&r->edges, s->x, s->b, 3 * T4 + 1))))
        return st;
    return TESSEL_OK;
}

/* The boxes of split s's triangles, listed where they left their cells
 * (in the tsl_edit_worker's overlay in a parallel phase). */
static tessel_status split_grid(tsl_edit *r, tsl_edit_worker *w, const split_info *s)
{
    for (int q = 0; q < s->count; q++) {
        bool listed; /* T3 and T4 are new */
        tessel_status st = tsl_edit_grid_add(r, w, s->news[q], q % 2 == 1, &listed);
        if (st)
            return st;
    }
    return TESSEL_OK;
}

/* Splits edge {u, v} at position pos (a new vertex; colour the mean of the
 * ends), serially: checked, then kept or taken back. *done reports
 * whether it was kept. */
static tessel_status split_edge(tsl_edit *r, uint32_t u, uint32_t v, const float pos[3],
                                double min_ratio, bool *done)
{
    *done = false;
    uint32_t h = tsl_edge_map_get(&r->edges, u, v);
    if (h == NONE)
        return TESSEL_OK;
    uint32_t g = r->twin[h];
    if (split_skinny(r, h, g, min_ratio)) {
        r->counts.skipped_skinny++;
        return TESSEL_OK;
    }
    tessel_status st = tsl_edit_reserve(r, 1, 2);
    if (st)
        return st;
    uint32_t m = (uint32_t)r->nv++, T3 = (uint32_t)r->nt++;
    uint32_t T4 = g == NONE ? NONE : (uint32_t)r->nt++;
    split_info s;
    split_apply(r, h, pos, m, T3, T4, &s);
    bool ok;
    if ((st = tsl_edit_check_news(r, r->serial, s.news, s.count, (const double(*)[3])s.olds, &ok)))
        return st;
    if (!ok) {
        split_undo(r, &s);
        r->nt -= (size_t)(s.count / 2);
        r->nv--;
        r->counts.skipped_invalid++;
        return TESSEL_OK;
    }
    if ((st = split_map(r, &s)) || (st = split_grid(r, r->serial, &s)))
        return st;
    r->counts.splits++;
    *done = true;
    return TESSEL_OK;
}

/* The block of the split of the edge at h at pos (tsl_edit_pair_key), or NONE for
 * the serial tail: a border edge, a long triangle, or a new vertex more
 * than a cell outside the pair's box. New triangles then stay within 3
 * cells of the block's pair centre, and the pairs of two blocks of a
 * colour within 3 cells of centres more than BLOCK_CELLS apart. */
static uint32_t split_key(const tsl_edit *r, const blocks *b, uint32_t h, const float pos[3])
{
    uint32_t key = tsl_edit_pair_key(r, b, h);
    if (key == NONE)
        return NONE;
    float b1[6], b2[6];
    box_load(r, h / 3, b1);
    box_load(r, twin_load(r, h) / 3, b2);
    double cell = b->reach / LONG_CELLS;
    for (int k = 0; k < 3; k++) {
        double lo = (b1[k] < b2[k] ? b1[k] : b2[k]) - cell;
        double hi = (b1[3 + k] > b2[3 + k] ? b1[3 + k] : b2[3 + k]) + cell;
        if (!(pos[k] >= lo && pos[k] <= hi))
            return NONE;
    }
    return key;
}

/* The half-edge of {u, v} in a parallel phase: the edge map as the phase
 * began, unless a split of this block moved it. */
static uint32_t phase_edge(const tsl_edit *r, const tsl_edit_worker *w, uint32_t u, uint32_t v)
{
    uint32_t h = w->moved.count ? tsl_edge_map_get(&w->moved, u, v) : NONE;
    return h != NONE ? h : tsl_edge_map_get(&r->edges, u, v);
}

static bool remember_moved(tsl_edit_worker *w, uint32_t a, uint32_t b, uint32_t h)
{
    if (tsl_edge_map_put(&w->moved, a, b, h) ||
        !tsl_push_u32(&w->moved_ab, &w->nmoved, &w->cap_moved, a) ||
        !tsl_push_u32(&w->moved_ab, &w->nmoved, &w->cap_moved, b))
        return false;
    return true;
}

/* One block of a parallel phase: the splits jobs[list[0 .. n)] of key
 * `key`, in order, each checked against the mesh as the earlier ones of
 * the block left it (with the tsl_edit_worker's own ids for the new vertices and
 * triangles, and its overlay grid). The splits kept go into the log; then
 * all are taken back, newest first, and the merge makes them again with
 * the mesh's next ids. Splits whose pair changed block go to the tail. */
static void split_block(tsl_edit *r, const blocks *b, tsl_edit_worker *w, uint32_t key,
                        const tsl_split_job *jobs, const uint32_t *list, size_t n, double min_ratio)
{
    tsl_trigrid_clear(&w->overlay);
    uint32_t next_v = w->base_v, next_t = w->base_t;
    for (size_t k = 0; k < n && !w->status; k++) {
        const tsl_split_job *jb = &jobs[list[k]];
        uint32_t h = phase_edge(r, w, jb->u, jb->v);
        if (h == NONE)
            continue;
        if (split_key(r, b, h, jb->pos) != key) {
            if (!tsl_push_u32(&w->tail, &w->ntail, &w->cap_tail, list[k]))
                w->status = TESSEL_ERR_NOMEM;
            continue;
        }
        if (split_skinny(r, h, twin_load(r, h), min_ratio)) {
            w->skinny++;
            continue;
        }
        if (w->nundo == w->cap_undo &&
            tsl_grow((void **)&w->undo, &w->cap_undo, w->nundo + 1, sizeof *w->undo)) {
            w->status = TESSEL_ERR_NOMEM;
            break;
        }
        split_info *s = &w->undo[w->nundo];
        split_apply(r, h, jb->pos, next_v, next_t, next_t + 1, s);
        bool ok;
        if ((w->status =
                 tsl_edit_check_news(r, w, s->news, s->count, (const double(*)[3])s->olds, &ok)))
            break;
        if (!ok) {
            split_undo(r, s);
            w->invalid++;
            continue;
        }
        next_v++;
        next_t += 2;
        w->nundo++;
        /* y-a and x-b moved to T3 and T4; the other edges are new or
         * stayed where they were. */
        if (!tsl_push_u32(&w->log, &w->nlog, &w->cap_log, list[k]) ||
            !remember_moved(w, s->y, s->a, 3 * s->T3 + 1) ||
            !remember_moved(w, s->x, s->b, 3 * s->T4 + 1)) {
            w->status = TESSEL_ERR_NOMEM;
            break;
        }
        if ((w->status = split_grid(r, w, s)))
            break;
    }
    while (w->nundo)
        split_undo(r, &w->undo[--w->nundo]);
    for (size_t k = 0; k < w->nmoved; k += 2)
        tsl_edge_map_del(&w->moved, w->moved_ab[k], w->moved_ab[k + 1]);
    w->nmoved = 0;
    if (!w->status && (!tsl_push_u32(&w->seg, &w->nseg, &w->cap_seg, key) ||
                       !tsl_push_u32(&w->seg, &w->nseg, &w->cap_seg, (uint32_t)w->nlog)))
        w->status = TESSEL_ERR_NOMEM;
}

/* A split the phase kept, made again in the mesh with its next ids. */
static tessel_status split_again(tsl_edit *r, const tsl_split_job *jb)
{
    uint32_t h = tsl_edge_map_get(&r->edges, jb->u, jb->v);
    if (h == NONE || r->twin[h] == NONE)
        return TESSEL_ERR_INTERNAL;
    uint32_t m = (uint32_t)r->nv++, T3 = (uint32_t)r->nt++, T4 = (uint32_t)r->nt++;
    split_info s;
    split_apply(r, h, jb->pos, m, T3, T4, &s);
    tessel_status st = split_map(r, &s);
    if (!st)
        st = split_grid(r, r->serial, &s);
    r->counts.splits++;
    return st;
}

/* After a phase: the splits kept by every block, in key order, made again
 * in the mesh; the tails gathered. */
static tessel_status split_merge(tsl_edit *r, tsl_edit_worker *ws, int nw,
                                 const tsl_split_job *jobs, uint32_t **tail, size_t *ntail,
                                 size_t *cap_tail)
{
    size_t m;
    seg_ref *order = tsl_edit_blocks_done(ws, nw, &m);
    if (!order)
        return TESSEL_ERR_NOMEM;
    tessel_status st = TESSEL_OK;
    for (size_t k = 0; k < m && !st; k++) {
        const tsl_edit_worker *w = &ws[order[k].tsl_edit_worker];
        size_t s = order[k].index;
        size_t from = s ? w->seg[2 * s - 1] : 0, to = w->seg[2 * s + 1];
        for (size_t f = from; f < to && !st; f++)
            st = split_again(r, &jobs[w->log[f]]);
    }
    free(order);
    return st ? st : tsl_edit_gather_tails(ws, nw, tail, ntail, cap_tail);
}

/* The splits of jobs[want[0 .. n)] (want in Morton order), in parallel
 * and deterministically, as the flips (tsl_edit_flips): each split goes to
 * the block of its pair (split_key); the eight colours take turns, the
 * blocks of a colour are split in parallel, each in order by one thread,
 * and a merge makes their splits in the mesh in key order; splits with a
 * long triangle, on the border, reaching outside their pair or whose pair
 * changed block are made serially after the colours, in order. The
 * result depends on the mesh only, not on the thread count; it is not
 * that of one serial pass in Morton order (a split may see a neighbour's
 * split that the serial pass made later, or not see one it made
 * earlier). */
tessel_status tsl_edit_splits(tsl_edit *r, const tsl_split_job *jobs, const uint32_t *want,
                              size_t n, double min_ratio, int threads)
{
    int nw = tsl_threads(threads);
    blocks b;
    tsl_edit_blocks_init(r, &b);
    uint32_t *key = tsl_alloc_array(n + 1, sizeof *key);
    uint32_t *sorted = tsl_alloc_array(n + 1, sizeof *sorted);
    uint32_t *start = tsl_calloc_array(8 * (size_t)b.count + 1, sizeof *start);
    uint32_t *blist = tsl_alloc_array(8 * (size_t)b.count + 1, sizeof *blist);
    tsl_edit_worker *ws = tsl_calloc_array((size_t)nw, sizeof *ws);
    uint32_t *tail = NULL;
    size_t ntail = 0, cap_tail = 0, most = 0, nsorted = 0;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!key || !sorted || !start || !blist || !ws)
        goto done;
    st = TESSEL_OK;
    for (size_t k = 0; k < n && !st; k++) {
        const tsl_split_job *jb = &jobs[want[k]];
        uint32_t h = tsl_edge_map_get(&r->edges, jb->u, jb->v);
        key[k] = h == NONE ? NONE : split_key(r, &b, h, jb->pos);
        if (key[k] == NONE) {
            if (!tsl_push_u32(&tail, &ntail, &cap_tail, want[k]))
                st = TESSEL_ERR_NOMEM;
            continue;
        }
        start[key[k] + 1]++;
    }
    for (size_t k = 0; k < 8 * (size_t)b.count; k++) {
        most = start[k + 1] > most ? start[k + 1] : most;
        start[k + 1] += start[k];
    }
    for (size_t k = 0; k < n; k++)
        if (key[k] != NONE) {
            sorted[start[key[k]]++] = want[k];
            nsorted++;
        }
    /* start[k] is now the end of key k's splits. Room for the merges' ids
     * (below nv + n and nt + 2 n) and, beyond, each tsl_edit_worker's own. */
    size_t nv0 = r->nv, nt0 = r->nt;
    if (!st)
        st = tsl_edit_reserve(r, n + (size_t)nw * most, 2 * n + 2 * (size_t)nw * most);
    for (int t = 0; t < nw && !st; t++) {
        ws[t].parallel = true;
        ws[t].base_v = (uint32_t)(nv0 + n + (size_t)t * most);
        ws[t].base_t = (uint32_t)(nt0 + 2 * n + 2 * (size_t)t * most);
        ws[t].id_end = nt0 + 2 * n + 2 * (size_t)nw * most;
        if (!(st = tsl_trigrid_init_like(&ws[t].overlay, &r->grid)))
            st = tsl_edge_map_init(&ws[t].moved, 64);
    }
    for (uint32_t colour = 0; colour < 8 && !st && nsorted; colour++) {
        size_t nb = 0;
        for (uint32_t k = colour * b.count; k < (colour + 1) * b.count; k++)
            if (start[k] > (k ? start[k - 1] : 0))
                blist[nb++] = k;
        ptrdiff_t count = (ptrdiff_t)nb;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nw)
        for (ptrdiff_t q = 0; q < count; q++) {
            uint32_t k = blist[q];
            size_t from = k ? start[k - 1] : 0;
            tsl_edit_worker *w = &ws[omp_get_thread_num()];
            split_block(r, &b, w, k, jobs, sorted + from, start[k] - from, min_ratio);
        }
        for (int t = 0; t < nw && !st; t++) {
            st = ws[t].status;
            r->counts.skipped_skinny += ws[t].skinny;
            r->counts.skipped_invalid += ws[t].invalid;
            ws[t].skinny = ws[t].invalid = 0;
        }
        if (!st)
            st = split_merge(r, ws, nw, jobs, &tail, &ntail, &cap_tail);
    }
    /* The tail in the jobs' order. */
    if (!st && ntail)
        qsort(tail, ntail, sizeof *tail, tsl_cmp_u32);
    for (size_t k = 0; k < ntail && !st; k++) {
        bool done_split;
        const tsl_split_job *jb = &jobs[tail[k]];
        st = split_edge(r, jb->u, jb->v, jb->pos, min_ratio, &done_split);
    }
done:
    for (int t = 0; ws && t < nw; t++)
        tsl_edit_worker_free(&ws[t]);
    free(ws);
    free(key);
    free(sorted);
    free(start);
    free(blist);
    free(tail);
    return st;
}
