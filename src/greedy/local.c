/* Local passes of the front: a place of a held mesh (a seam between tiles,
 * a small hole) meshed again by a front over the points near it only,
 * resumed from the triangles among them. A pass over every point would
 * first rebuild every fan of the mesh (10^6 points: 1.5 s for a seam pass
 * whose work lies within a few spacings of three cuts). */
#include "greedy/greedy.h"

/* Grid cells at most for the selection (the cell grows to stay under). */
#define NEAR_CELLS (1u << 24)

tessel_status tsl_gp_near_build(const float *xyz, size_t n, const uint8_t *seed, double radius,
                                tsl_gp_near *g)
{
    memset(g, 0, sizeof *g);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; seed[i] && k < 3; k++) {
            lo[k] = fmin(lo[k], xyz[3 * i + (size_t)k] - radius);
            hi[k] = fmax(hi[k], xyz[3 * i + (size_t)k] + radius);
        }
    if (!(lo[0] <= hi[0]))
        return TESSEL_OK; /* no seed: no cell */
    /* Cells of half the radius: a point within radius of a seed is in a
     * cell at most two cells' gap from the seed's (the stencil below). */
    double cell = radius > 0.0 ? 0.5 * radius : 1.0;
    size_t cells;
    for (;;) {
        cells = 1;
        for (int k = 0; k < 3; k++) {
            double d = floor((hi[k] - lo[k]) / cell) + 1.0;
            g->dim[k] = d < (double)NEAR_CELLS ? (size_t)d : NEAR_CELLS;
            cells = cells * g->dim[k] < NEAR_CELLS ? cells * g->dim[k] : NEAR_CELLS + 1;
        }
        if (cells <= NEAR_CELLS)
            break;
        cell *= 2.0;
    }
    memcpy(g->lo, lo, sizeof g->lo);
    g->cell = cell;
    int reach = (int)ceil(radius / cell) + 1;
    uint8_t *mark = tsl_calloc_array(cells, 1);
    g->near = tsl_calloc_array(cells, 1);
    if (!mark || !g->near) {
        free(mark);
        tsl_gp_near_free(g);
        return TESSEL_ERR_NOMEM;
    }
    const size_t *dim = g->dim;
    for (size_t i = 0; i < n; i++) {
        if (!seed[i])
            continue;
        size_t c[3];
        for (int k = 0; k < 3; k++)
            c[k] = (size_t)((xyz[3 * i + (size_t)k] - lo[k]) / cell);
        mark[(c[0] * dim[1] + c[1]) * dim[2] + c[2]] = 1;
    }
    /* Every cell whose gap to a marked one is at most radius. */
    double gap2 = (radius / cell) * (radius / cell);
    for (size_t x = 0; x < dim[0]; x++)
        for (size_t y = 0; y < dim[1]; y++)
            for (size_t z = 0; z < dim[2]; z++) {
                if (!mark[(x * dim[1] + y) * dim[2] + z])
                    continue;
                for (int a = -reach; a <= reach; a++)
                    for (int b = -reach; b <= reach; b++)
                        for (int d = -reach; d <= reach; d++) {
                            double ga = abs(a) > 1 ? abs(a) - 1 : 0, gb = abs(b) > 1 ? abs(b) - 1 : 0,
                                   gd = abs(d) > 1 ? abs(d) - 1 : 0;
                            long u = (long)x + a, v = (long)y + b, w = (long)z + d;
                            if (ga * ga + gb * gb + gd * gd > gap2 || u < 0 || v < 0 || w < 0 ||
                                u >= (long)dim[0] || v >= (long)dim[1] || w >= (long)dim[2])
                                continue;
                            g->near[((size_t)u * dim[1] + (size_t)v) * dim[2] + (size_t)w] = 1;
                        }
            }
    free(mark);
    return TESSEL_OK;
}

bool tsl_gp_near_box(const tsl_gp_near *g, const double lo[3], const double hi[3])
{
    if (!g->near)
        return false;
    size_t from[3], to[3];
    for (int k = 0; k < 3; k++) {
        double a = (lo[k] - g->lo[k]) / g->cell, b = (hi[k] - g->lo[k]) / g->cell;
        if (!(b >= 0.0 && a < (double)g->dim[k]))
            return false; /* beyond the cells (or NaN) */
        from[k] = a > 0.0 ? (size_t)a : 0;
        to[k] = b < (double)g->dim[k] ? (size_t)b : g->dim[k] - 1;
    }
    for (size_t x = from[0]; x <= to[0]; x++)
        for (size_t y = from[1]; y <= to[1]; y++)
            for (size_t z = from[2]; z <= to[2]; z++)
                if (g->near[(x * g->dim[1] + y) * g->dim[2] + z])
                    return true;
    return false;
}

void tsl_gp_near_free(tsl_gp_near *g)
{
    free(g->near);
    memset(g, 0, sizeof *g);
}

tessel_status tsl_gp_select_near(const float *xyz, size_t n, const uint8_t *seed, double radius,
                                 int threads, uint8_t *sel)
{
    tsl_gp_near g;
    tessel_status st = tsl_gp_near_build(xyz, n, seed, radius, &g);
    ptrdiff_t m = st ? 0 : (ptrdiff_t)n;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (ptrdiff_t i = 0; i < m; i++) {
        double p[3];
        tsl_load(xyz + 3 * i, p);
        sel[i] |= tsl_gp_near_box(&g, p, p);
    }
    tsl_gp_near_free(&g);
    return st;
}

void tsl_gp_select_meshed(size_t n, const uint8_t *fate, const float *dcut, double reach,
                          uint8_t *sel)
{
    for (size_t i = 0; i < n; i++)
        if (fate[i] != FATE_USED && !(dcut && dcut[i] < reach))
            sel[i] = 0;
}

tessel_status tsl_gp_subcloud(const tessel_cloud *cloud, const uint32_t *ids, size_t m,
                             tessel_cloud *out)
{
    tessel_status st = tessel_cloud_alloc(out, m, cloud->normals != NULL, 0);
    if (st)
        return st;
    for (size_t i = 0; i < m; i++) {
        memcpy(out->xyz + 3 * i, cloud->xyz + 3 * (size_t)ids[i], 3 * sizeof *out->xyz);
        if (cloud->normals)
            memcpy(out->normals + 3 * i, cloud->normals + 3 * (size_t)ids[i],
                   3 * sizeof *out->normals);
    }
    memcpy(out->offset, cloud->offset, sizeof out->offset);
    memcpy(out->viewpoint, cloud->viewpoint, sizeof out->viewpoint);
    out->has_viewpoint = cloud->has_viewpoint;
    return TESSEL_OK;
}

tessel_status tsl_gp_front_local(const tessel_cloud *lc, const uint32_t *inside, size_t ninside,
                                 const uint8_t *frozen, const tessel_greedy_params *params,
                                 bool grow_only, const char *stage,
                                 const tessel_callbacks *callbacks, gp_collect *more,
                                 uint8_t *fate, tessel_recon_summary *sum)
{
    tessel_greedy_params lp = *params;
    lp.tile_points = 0;
    lp.existing = inside;
    lp.existing_count = ninside;
    lp.frozen = frozen;
    tessel_triangle_sink hold = {tsl_gp_collect_emit, more};
    return grow_only ? tsl_gp_grow(lc, &lp, stage, callbacks, &hold, fate, sum)
                     : tsl_gp_pass(lc, &lp, stage, callbacks, &hold, fate, sum);
}

tessel_status tsl_gp_front_over(const tessel_cloud *cloud, const uint32_t *ids, size_t m,
                                const uint32_t *inside, size_t ninside, const uint8_t *frozen,
                                const tessel_greedy_params *params, bool grow_only,
                                const char *stage, const tessel_callbacks *callbacks,
                                gp_collect *more, uint8_t *fate, uint8_t *made,
                                tessel_recon_summary *sum)
{
    if (m < 3)
        return TESSEL_OK;
    tessel_cloud lc;
    tessel_status st = tsl_gp_subcloud(cloud, ids, m, &lc);
    if (st)
        return st;
    uint8_t *lfate = tsl_alloc_array(m, 1);
    st = lfate ? tsl_gp_front_local(&lc, inside, ninside, frozen, params, grow_only, stage,
                                    callbacks, more, lfate, sum)
               : TESSEL_ERR_NOMEM;
    if (!st)
        tsl_gp_front_back(ids, m, lfate, more, fate, made);
    tessel_cloud_free(&lc);
    free(lfate);
    return st;
}

void tsl_gp_front_back(const uint32_t *ids, size_t m, const uint8_t *lfate, gp_collect *more,
                       uint8_t *fate, uint8_t *made)
{
    for (size_t i = 0; i < 3 * more->count; i++) {
        uint32_t w = ids[more->tris[i]];
        more->tris[i] = w;
        made[w] = 1;
    }
    for (size_t j = 0; j < m; j++)
        fate[ids[j]] = lfate[j];
}

tessel_status tsl_gp_local_pass(const tessel_cloud *cloud, const uint8_t *sel,
                                const tessel_greedy_params *params, const char *stage,
                                const tessel_callbacks *callbacks, gp_collect *all,
                                uint8_t *fate, uint8_t *made, tessel_recon_summary *summary)
{
    size_t n = cloud->count, nt = all->count, m = 0;
    uint32_t *map = tsl_alloc_array(n + 1, sizeof *map), *back = NULL;
    uint8_t *frozen = NULL;
    gp_collect inside = {NULL, 0, 0}, more = {NULL, 0, 0};
    tessel_status st = map ? TESSEL_OK : TESSEL_ERR_NOMEM;
    for (size_t i = 0; !st && i < n; i++)
        map[i] = sel[i] ? (uint32_t)m++ : NONE;
    if (!st && (!(back = tsl_alloc_array(m + 1, sizeof *back)) ||
                !(frozen = tsl_calloc_array(m + 1, 1))))
        st = TESSEL_ERR_NOMEM;
    for (size_t i = 0; !st && i < n; i++)
        if (map[i] != NONE)
            back[map[i]] = (uint32_t)i;
    /* The triangles among the points resume the front; a point with a
     * triangle beyond them is frozen (its fan is not all here). */
    for (size_t t = 0; !st && t < nt; t++) {
        const uint32_t *v = all->tris + 3 * t;
        uint32_t w[3] = {map[v[0]], map[v[1]], map[v[2]]};
        if (w[0] != NONE && w[1] != NONE && w[2] != NONE) {
            st = tsl_gp_collect_emit(&inside, w, 1);
            continue;
        }
        for (int k = 0; k < 3; k++)
            if (w[k] != NONE)
                frozen[w[k]] = 1;
    }
    tessel_recon_summary local;
    memset(&local, 0, sizeof local);
    if (!st)
        st = tsl_gp_front_over(cloud, back, m, inside.tris, inside.count, frozen, params, false,
                               stage, callbacks, &more, fate, made, &local);
    if (!st)
        st = tsl_gp_collect_emit(all, more.tris, more.count);
    summary->seeds += local.seeds;
    summary->holes_closed += local.holes_closed;
    summary->rejected_intersecting += local.rejected_intersecting;
    free(map);
    free(back);
    free(frozen);
    free(inside.tris);
    free(more.tris);
    return st;
}
