/* Greedy projection out of core: the cloud in slabs along one axis, meshed
 * one after another with only a band of the previous slab in memory.
 *
 * A step meshes its slab as a cloud of its own (tiles, seams and flips as
 * in core), drops the slab's triangles near its lower cut (a front that saw
 * only one side made them, as tiles.c drops a tile's), orients the slab's
 * components against the band carried from the step before, and closes the
 * gap by a front over band and slab from their triangles (params.existing).
 * The band's lowest points are frozen: their other triangles were written
 * already, so the front must not add any there. Then the triangles near the
 * next cut are dropped, those far below it written, and the rest carried,
 * with the points they use and the unmeshed points near the cut. */
#include "greedy/greedy.h"

/* Reach of the band dropped on each side of a cut, in spheres of influence
 * (mu times the mean spacing), as the tiles' (tiles.c). */
#define SWEEP_BAND 1.0
/* Triangles carried below the dropped band, in bands: context for the
 * front that closes the gap (its guard tests against them). */
#define SWEEP_CONTEXT 3.0
/* Orientation votes, in mean spacings beyond the band (as tiles.c). */
#define SWEEP_VOTE_REACH 4.0
#define SWEEP_PAIR_REACH 4.0

void tsl_gp_slabs_init(tsl_gp_slabs *s, int axis, const tsl_gp_tile_runner *runner)
{
    memset(s, 0, sizeof *s);
    s->axis = axis;
    s->runner = runner;
}

static void free_band(tsl_gp_slabs *s)
{
    free(s->xyz);
    free(s->normals);
    free(s->gid);
    free(s->frozen);
    free(s->tri);
    s->xyz = s->normals = NULL;
    s->gid = s->tri = NULL;
    s->frozen = NULL;
    s->np = s->nt = 0;
}

void tsl_gp_slabs_free(tsl_gp_slabs *s)
{
    free_band(s);
}

/* The carried band and the slab as one cloud (band first), with the global
 * ids and frozen marks of its points. */
static tessel_status join_cloud(const tsl_gp_slabs *s, const tessel_cloud *slab,
                                const uint32_t *gid, tessel_cloud *c, uint32_t **cgid,
                                uint8_t **frozen)
{
    size_t nc = s->np, n = nc + slab->count;
    int normals = slab->normals != NULL;
    *cgid = tsl_alloc_array(n, sizeof **cgid);
    *frozen = tsl_calloc_array(n, 1);
    tessel_status st = *cgid && *frozen ? tessel_cloud_alloc(c, n, normals, 0) : TESSEL_ERR_NOMEM;
    if (st)
        return st;
    memcpy(c->offset, slab->offset, sizeof c->offset);
    if (nc) {
        memcpy(c->xyz, s->xyz, 3 * nc * sizeof *c->xyz);
        if (normals)
            memcpy(c->normals, s->normals, 3 * nc * sizeof *c->normals);
        memcpy(*cgid, s->gid, nc * sizeof **cgid);
        memcpy(*frozen, s->frozen, nc);
    }
    memcpy(c->xyz + 3 * nc, slab->xyz, 3 * slab->count * sizeof *c->xyz);
    if (normals)
        memcpy(c->normals + 3 * nc, slab->normals, 3 * slab->count * sizeof *c->normals);
    memcpy(*cgid + nc, gid, slab->count * sizeof **cgid);
    return TESSEL_OK;
}

/* The slab meshed alone, its triangles in the joined cloud's numbering
 * (shifted by the band's points), less those with a vertex within reach of
 * the lower cut when there is a band. *mu and *spacing: the slab's. */
static tessel_status mesh_slab(const tsl_gp_slabs *s, const tessel_cloud *slab,
                               const tessel_greedy_params *params,
                               const tessel_callbacks *callbacks, gp_collect *out,
                               tessel_recon_summary *sum)
{
    gp_collect mine = {NULL, 0, 0};
    tessel_triangle_sink sink = {tsl_gp_collect_emit, &mine};
    tessel_greedy_params p = *params;
    p.orient_check = 0;
    tessel_status st = slab->count < 3 ? TESSEL_OK
                                       : tsl_reconstruct_greedy_with(slab, &p, s->runner,
                                                                     callbacks, &sink, sum);
    if (st == TESSEL_ERR_TOO_FEW_POINTS) /* a slab of duplicates: the band's front meshes it */
        st = TESSEL_OK;
    if (st) {
        free(mine.tris);
        return st;
    }
    double reach = SWEEP_BAND * sum->mu * sum->spacing;
    if (s->reach > reach)
        reach = s->reach;
    uint8_t *touched = tsl_calloc_array(slab->count + 1, 1);
    if (!touched) {
        free(mine.tris);
        return TESSEL_ERR_NOMEM;
    }
    size_t w = 0;
    for (size_t t = 0; t < mine.count; t++) {
        uint32_t *v = mine.tris + 3 * t;
        bool near = false;
        for (int k = 0; k < 3; k++)
            near |= s->np && slab->xyz[3 * (size_t)v[k] + (size_t)s->axis] < s->cut + reach;
        if (near) {
            touched[v[0]] = touched[v[1]] = touched[v[2]] = 1;
            continue;
        }
        memmove(mine.tris + 3 * w, v, 3 * sizeof *v);
        w++;
    }
    mine.count = w;
    /* A point that lost some of its triangles keeps one fan (the front
     * cannot resume from two). */
    st = tsl_single_fans(slab->count, mine.tris, &mine.count, touched, NULL, NULL);
    free(touched);
    for (size_t i = 0; i < 3 * mine.count; i++)
        mine.tris[i] += (uint32_t)s->np;
    *out = mine;
    return st;
}

static void turn(uint32_t *v)
{
    uint32_t tmp = v[1];
    v[1] = v[2];
    v[2] = tmp;
}

/* The slab's components (after the band's, which come first in tri)
 * oriented against the band's across the cut (tsl_orient_tiles). The band's
 * triangles were written in part already, so a band component stays as it
 * is: one the forest turned is turned back (a slab component between two
 * band components that disagree then meets one of them the wrong way: a
 * boundary, not a mesh turned inside out). Slab components the orientation
 * leaves out are dropped, their points marked in redo for the front that
 * closes the gap to mesh again. */
static tessel_status orient_slab(const tsl_gp_slabs *s, const tessel_cloud *c, gp_collect *all,
                                 double reach, double spacing, size_t small, int threads,
                                 uint8_t *redo)
{
    size_t count = all->count, ncomp = 0, band_tris = s->nt;
    uint32_t *comp = tsl_alloc_array(count + 1, sizeof *comp);
    float *dcut = tsl_alloc_array(c->count + 1, sizeof *dcut);
    uint8_t *axis = tsl_alloc_array(c->count + 1, 1);
    uint8_t *drop = NULL;
    uint32_t *saved = tsl_alloc_array(3 * band_tris + 1, sizeof *saved);
    tessel_status st = comp && dcut && axis && saved
                           ? tsl_triangle_components(all->tris, count, c->count, threads, comp,
                                                     &ncomp)
                           : TESSEL_ERR_NOMEM;
    if (st)
        goto done;
    if (!(drop = tsl_alloc_array(ncomp + 1, sizeof *drop))) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    for (size_t i = 0; i < c->count; i++)
        dcut[i] = (float)fabs((double)c->xyz[3 * i + (size_t)s->axis] - s->cut);
    memset(axis, s->axis, c->count);
    memcpy(saved, all->tris, 3 * band_tris * sizeof *saved);
    st = tsl_orient_tiles(all->tris, comp, count, ncomp, c->xyz, dcut, axis,
                          reach + SWEEP_VOTE_REACH * spacing,
                          2.0 * reach + SWEEP_PAIR_REACH * spacing, small, threads, drop);
    if (st)
        goto done;
    /* Components are numbered by their first triangle: the band's come
     * first, and no slab triangle shares a vertex with them. */
    size_t band_comps = band_tris ? comp[band_tris - 1] + 1 : 0;
    for (size_t t = 0; t < band_tris; t++)
        if (memcmp(saved + 3 * t, all->tris + 3 * t, 3 * sizeof *saved))
            turn(all->tris + 3 * t);
    size_t w = 0;
    for (size_t t = 0; t < count; t++) {
        if (t >= band_tris && comp[t] >= band_comps && drop[comp[t]]) {
            for (int k = 0; k < 3; k++)
                redo[all->tris[3 * t + (size_t)k]] = 1;
            continue;
        }
        memmove(all->tris + 3 * w, all->tris + 3 * t, 3 * sizeof *all->tris);
        w++;
    }
    all->count = w;
done:
    free(comp);
    free(dcut);
    free(axis);
    free(drop);
    free(saved);
    return st;
}

/* Diagonal flips on the triangles with no frozen vertex; those with one
 * (their vertex's other triangles are written already) are fixed, and
 * still checked against. */
static tessel_status flip_free(const tessel_cloud *c, const uint8_t *frozen, gp_collect *all,
                               int threads, size_t *flips)
{
    size_t n = all->count;
    uint8_t *fixed = tsl_alloc_array(n + 1, 1);
    if (!fixed)
        return TESSEL_ERR_NOMEM;
    for (size_t t = 0; t < n; t++) {
        const uint32_t *v = all->tris + 3 * t;
        fixed[t] = frozen[v[0]] || frozen[v[1]] || frozen[v[2]];
    }
    tessel_status st = tsl_flip_diagonals(c->xyz, c->count, all->tris, n, fixed, threads, flips);
    free(fixed);
    return st;
}

/* The gap at the cut closed by a front over the points near it only: the
 * band and the slab's points up to (1 + SWEEP_CONTEXT) reaches above the
 * cut (free ones up to two reaches: farther up they are points the slab's
 * front left out, and stay out) and those of slab components the
 * orientation dropped, from the triangles among them; points
 * with triangles beyond that are frozen, as the band's lowest. Then the
 * flips there. The slab's other triangles are as mesh_slab left them, its
 * seams between tiles closed and flipped already. */
static tessel_status close_gap(const tsl_gp_slabs *s, const tessel_cloud *c, uint8_t *frozen,
                               const uint8_t *redo, gp_collect *all, double reach,
                               const tessel_greedy_params *params,
                               const tessel_callbacks *callbacks, tessel_recon_summary *seam,
                               size_t *flips)
{
    const int ax = s->axis;
    double top = s->cut + (1.0 + SWEEP_CONTEXT) * reach, top_free = s->cut + 2.0 * reach;
    size_t n = c->count, nt = all->count;
    uint8_t *used = tsl_calloc_array(n + 1, 1), *fz = NULL;
    uint32_t *map = tsl_alloc_array(n + 1, sizeof *map), *back = NULL, *sel = NULL;
    gp_collect local = {NULL, 0, 0};
    tessel_cloud lc;
    memset(&lc, 0, sizeof lc);
    tessel_status st = used && map ? TESSEL_OK : TESSEL_ERR_NOMEM;
    for (size_t i = 0; !st && i < 3 * nt; i++)
        used[all->tris[i]] = 1;
    size_t m = 0;
    for (size_t i = 0; !st && i < n; i++) {
        double x = c->xyz[3 * i + (size_t)ax];
        bool in = i < s->np || redo[i] || x < (used[i] ? top : top_free);
        map[i] = in ? (uint32_t)m++ : NONE;
    }
    if (!st && (!(back = tsl_alloc_array(m + 1, sizeof *back)) ||
                !(fz = tsl_calloc_array(m + 1, 1)) ||
                !(sel = tsl_alloc_array(nt + 1, sizeof *sel)) ||
                tessel_cloud_alloc(&lc, m, c->normals != NULL, 0)))
        st = TESSEL_ERR_NOMEM;
    size_t ns = 0;
    for (size_t i = 0; !st && i < n; i++) {
        uint32_t j = map[i];
        if (j == NONE)
            continue;
        back[j] = (uint32_t)i;
        fz[j] = frozen[i];
        memcpy(lc.xyz + 3 * (size_t)j, c->xyz + 3 * i, 3 * sizeof *lc.xyz);
        if (c->normals)
            memcpy(lc.normals + 3 * (size_t)j, c->normals + 3 * i, 3 * sizeof *lc.normals);
    }
    if (!st) {
        memcpy(lc.offset, c->offset, sizeof lc.offset);
        for (size_t t = 0; t < nt; t++) {
            const uint32_t *v = all->tris + 3 * t;
            bool in = map[v[0]] != NONE && map[v[1]] != NONE && map[v[2]] != NONE;
            if (in) {
                uint32_t w[3] = {map[v[0]], map[v[1]], map[v[2]]};
                if ((st = tsl_gp_collect_emit(&local, w, 1)))
                    break;
                sel[ns++] = (uint32_t)t;
                continue;
            }
            for (int k = 0; k < 3; k++)
                if (map[v[k]] != NONE)
                    fz[map[v[k]]] = 1; /* its fan goes on beyond */
        }
    }
    if (!st) {
        tessel_greedy_params sp = *params;
        sp.tile_points = 0;
        sp.orient_check = 0;
        sp.flip = 0;
        sp.existing = local.tris;
        sp.existing_count = local.count;
        sp.frozen = fz;
        gp_collect more = {NULL, 0, 0};
        tessel_triangle_sink hold = {tsl_gp_collect_emit, &more};
        st = tsl_reconstruct_greedy_with(&lc, &sp, NULL, callbacks, &hold, seam);
        if (!st)
            st = tsl_gp_collect_emit(&local, more.tris, more.count);
        free(more.tris);
    }
    if (!st && params->flip)
        st = flip_free(&lc, fz, &local, params->threads, flips);
    /* Back into the step's mesh: the triangles taken keep their slots (the
     * flips rewrote them in place), the new ones follow. */
    for (size_t t = 0; !st && t < ns; t++)
        for (int k = 0; k < 3; k++)
            all->tris[3 * (size_t)sel[t] + (size_t)k] = back[local.tris[3 * t + (size_t)k]];
    for (size_t t = ns; !st && t < local.count; t++) {
        uint32_t w[3];
        for (int k = 0; k < 3; k++)
            w[k] = back[local.tris[3 * t + (size_t)k]];
        st = tsl_gp_collect_emit(all, w, 1);
    }
    tessel_cloud_free(&lc);
    free(used);
    free(map);
    free(back);
    free(fz);
    free(sel);
    free(local.tris);
    return st;
}

/* Splits the step's mesh at the next cut: triangles with a vertex within
 * reach of it dropped, those wholly below the carried context written
 * (global ids, to out), the rest carried with the points they use and
 * every point at or above the context; frozen marks follow the written
 * triangles. next_cut INFINITY: the last slab, everything written. */
static tessel_status split(tsl_gp_slabs *s, const tessel_cloud *c, const uint32_t *gid,
                           uint8_t *frozen, const gp_collect *all, double next_cut,
                           double reach, const tessel_triangle_sink *out, size_t *written)
{
    const int ax = s->axis;
    double lim_drop = next_cut - reach, lim_write = next_cut - (1.0 + SWEEP_CONTEXT) * reach;
    size_t n = c->count;
    uint8_t *keep = tsl_calloc_array(n + 1, 1), *touched = tsl_calloc_array(n + 1, 1);
    uint32_t *batch = tsl_alloc_array(3 * OUT_BATCH, sizeof *batch);
    uint32_t *tri = tsl_alloc_array(3 * all->count + 1, sizeof *tri);
    uint32_t *map = tsl_alloc_array(n + 1, sizeof *map);
    tessel_status st = keep && touched && batch && tri && map ? TESSEL_OK : TESSEL_ERR_NOMEM;
    size_t nb = 0, nt = 0;
    *written = 0;
    for (size_t t = 0; !st && t < all->count; t++) {
        const uint32_t *v = all->tris + 3 * t;
        double top = -INFINITY;
        for (int k = 0; k < 3; k++) {
            double x = c->xyz[3 * (size_t)v[k] + (size_t)ax];
            top = x > top ? x : top;
        }
        if (top >= lim_drop) {
            touched[v[0]] = touched[v[1]] = touched[v[2]] = 1;
            continue;
        }
        if (top < lim_write) {
            for (int k = 0; k < 3; k++) {
                batch[3 * nb + (size_t)k] = gid[v[k]];
                frozen[v[k]] = 1;
            }
            if (++nb == OUT_BATCH) {
                st = out->emit(out->user_data, batch, nb);
                *written += nb;
                nb = 0;
            }
            continue;
        }
        memcpy(tri + 3 * nt, v, 3 * sizeof *v);
        nt++;
    }
    if (!st && nb) {
        st = out->emit(out->user_data, batch, nb);
        *written += nb;
    }
    /* Carried points that lost triangles keep one fan, as in mesh_slab;
     * frozen ones are completed as they stand. */
    for (size_t i = 0; i < n; i++)
        touched[i] &= (uint8_t)!frozen[i];
    if (!st)
        st = tsl_single_fans(n, tri, &nt, touched, NULL, NULL);
    for (size_t i = 0; !st && i < 3 * nt; i++)
        keep[tri[i]] = 1;
    size_t np = 0;
    for (size_t i = 0; !st && i < n; i++) {
        keep[i] |= c->xyz[3 * i + (size_t)ax] >= lim_write;
        map[i] = keep[i] ? (uint32_t)np++ : NONE;
    }
    float *xyz = NULL, *normals = NULL;
    uint32_t *ids = NULL;
    uint8_t *fz = NULL;
    if (!st) {
        xyz = tsl_alloc_array(3 * np + 1, sizeof *xyz);
        normals = c->normals ? tsl_alloc_array(3 * np + 1, sizeof *normals) : NULL;
        ids = tsl_alloc_array(np + 1, sizeof *ids);
        fz = tsl_alloc_array(np + 1, 1);
        if (!xyz || (c->normals && !normals) || !ids || !fz)
            st = TESSEL_ERR_NOMEM;
    }
    if (!st) {
        for (size_t i = 0; i < n; i++) {
            uint32_t j = map[i];
            if (j == NONE)
                continue;
            memcpy(xyz + 3 * (size_t)j, c->xyz + 3 * i, 3 * sizeof *xyz);
            if (normals)
                memcpy(normals + 3 * (size_t)j, c->normals + 3 * i, 3 * sizeof *normals);
            ids[j] = gid[i];
            fz[j] = frozen[i];
        }
        for (size_t i = 0; i < 3 * nt; i++)
            tri[i] = map[tri[i]];
        free_band(s);
        s->np = np;
        s->xyz = xyz;
        s->normals = normals;
        s->gid = ids;
        s->frozen = fz;
        s->nt = nt;
        s->tri = tri;
        tri = NULL;
        s->cut = next_cut;
        s->reach = reach;
    } else {
        free(xyz);
        free(normals);
        free(ids);
        free(fz);
    }
    free(keep);
    free(touched);
    free(batch);
    free(tri);
    free(map);
    return st;
}

tessel_status tsl_gp_slabs_step(tsl_gp_slabs *s, const tessel_cloud *slab, const uint32_t *gid,
                                double cut, double next_cut, const tessel_greedy_params *params,
                                const tessel_callbacks *callbacks,
                                const tessel_triangle_sink *out, tessel_recon_summary *summary)
{
    tessel_cloud c;
    memset(&c, 0, sizeof c);
    uint32_t *cgid = NULL;
    uint8_t *frozen = NULL;
    gp_collect all = {NULL, 0, 0};
    tessel_recon_summary ss, seam;
    memset(&ss, 0, sizeof ss);
    memset(&seam, 0, sizeof seam);
    if (!s->np)
        s->cut = cut;
    tessel_status st = mesh_slab(s, slab, params, callbacks, &all, &ss);
    double reach = SWEEP_BAND * ss.mu * ss.spacing, spacing = ss.spacing;
    if (s->reach > reach)
        reach = s->reach;
    if (!st)
        st = join_cloud(s, slab, gid, &c, &cgid, &frozen);
    uint8_t *redo = st ? NULL : tsl_calloc_array(c.count + 1, 1);
    if (!st && !redo)
        st = TESSEL_ERR_NOMEM;
    if (!st && s->nt) {
        /* The band's triangles first (orient_slab counts on it). */
        size_t need = all.count + s->nt;
        if (tsl_grow((void **)&all.tris, &all.cap, need, 3 * sizeof *all.tris)) {
            st = TESSEL_ERR_NOMEM;
        } else {
            memmove(all.tris + 3 * s->nt, all.tris, 3 * all.count * sizeof *all.tris);
            memcpy(all.tris, s->tri, 3 * s->nt * sizeof *all.tris);
            all.count = need;
        }
        if (!st)
            st = orient_slab(s, &c, &all, reach, spacing, params->tile_points / 4,
                                 params->threads, redo);
    }
    size_t flips = 0;
    if (!st && s->np)
        st = close_gap(s, &c, frozen, redo, &all, reach, params, callbacks, &seam, &flips);
    ss.flips += flips;
    size_t written = 0;
    if (!st)
        st = split(s, &c, cgid, frozen, &all, next_cut, reach, out, &written);
    if (!st) {
        summary->triangles += written;
        summary->seeds += ss.seeds + seam.seeds;
        summary->holes_closed += ss.holes_closed + seam.holes_closed;
        summary->rejected_intersecting += ss.rejected_intersecting + seam.rejected_intersecting;
        summary->flips += ss.flips;
        summary->tiles += ss.tiles ? ss.tiles : 1;
        if (all.count > summary->peak_held_triangles)
            summary->peak_held_triangles = all.count;
        if (ss.spacing > summary->spacing) {
            summary->spacing = ss.spacing;
            summary->mu = ss.mu;
        }
    }
    tessel_cloud_free(&c);
    free(cgid);
    free(frozen);
    free(redo);
    free(all.tris);
    return st;
}
