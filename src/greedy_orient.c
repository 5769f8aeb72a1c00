/* Regions the greedy front meshed inside out, found and rebuilt (not in
 * Gopi & Krishnan 2002; docs/greedy.md).
 *
 * The front orients each new triangle like the triangles already at its
 * reference point (section 4.2). Where it steps from one sheet onto another
 * that faces it closer than the sampling can separate (a hand on a thigh),
 * it carries the wrong side across, and the region behind the step comes
 * out inside out although every edge agrees with its neighbours. Only a
 * global test sees it: the ray-parity check of src/orient.c, which needs
 * the whole mesh. So this pass holds every triangle, flips the regions the
 * rays find facing inward, drops their rims and the triangles at points
 * left with two fans, and runs the front again from what is left
 * (params.existing) to mesh the seams. */
#include "greedy_internal.h"

/* Out-edges v -> a at v with no triangle bringing a -> v back: one per
 * open fan, the mesh being consistently oriented. */
static size_t open_fans(const uint32_t *tri, const uint32_t *corner, uint32_t lo, uint32_t hi)
{
    size_t open = 0;
    for (uint32_t i = lo; i < hi; i++) {
        uint32_t c = corner[i], a = tri[c - c % 3 + (c % 3 + 1) % 3];
        int back = 0;
        for (uint32_t j = lo; j < hi && !back; j++) {
            uint32_t d = corner[j];
            back = tri[d - d % 3 + (d % 3 + 2) % 3] == a;
        }
        open += !back;
    }
    return open;
}

/* Drops the triangles at points with more than one open fan until no such
 * point is left: the front restarts only from single fans
 * (tsl_gp_import_existing). Dropping a point's triangles can split a
 * neighbour's fan. (Keeping each point's largest fan instead drops a third
 * as many triangles on man.ply but leaves more pieces the front cannot
 * join again: 25 components against 17.) */
static tessel_status single_fans(uint32_t *tri, size_t *count, size_t nv)
{
    for (;;) {
        size_t nt = *count;
        uint32_t *start = NULL, *corner = NULL;
        uint8_t *drop = tsl_calloc_array(nt + 1, sizeof *drop);
        tessel_status s = drop ? tsl_vertex_corners(tri, nt, nv, &start, &corner)
                               : TESSEL_ERR_NOMEM;
        if (s != TESSEL_OK) {
            free(drop);
            return s;
        }
        size_t dropped = 0;
        for (size_t v = 0; v < nv; v++) {
            if (open_fans(tri, corner, start[v], start[v + 1]) < 2)
                continue;
            for (uint32_t i = start[v]; i < start[v + 1]; i++) {
                dropped += !drop[corner[i] / 3];
                drop[corner[i] / 3] = 1;
            }
        }
        free(start);
        free(corner);
        size_t kept = 0;
        for (size_t t = 0; t < nt; t++)
            if (!drop[t])
                memmove(tri + 3 * kept++, tri + 3 * t, 3 * sizeof *tri);
        free(drop);
        *count = kept;
        if (!dropped)
            return TESSEL_OK;
    }
}

/* Flips the triangles marked 1 and drops those marked 2, in place. */
static size_t apply_marks(uint32_t *tri, size_t nt, const uint8_t *mark)
{
    size_t kept = 0;
    for (size_t t = 0; t < nt; t++) {
        if (mark[t] == 2)
            continue;
        uint32_t a = tri[3 * t], b = tri[3 * t + 1], c = tri[3 * t + 2];
        uint32_t *w = tri + 3 * kept++;
        w[0] = a;
        w[1] = mark[t] ? c : b;
        w[2] = mark[t] ? b : c;
    }
    return kept;
}

/* The second pass's summary describes the output; the work of the first
 * (seeds, holes, refusals) is added to it. */
static void merge_summary(tessel_recon_summary *out, const tessel_recon_summary *first,
                          size_t existing)
{
    out->triangles += existing;
    out->seeds += first->seeds;
    out->holes_closed += first->holes_closed;
    out->rejected_intersecting += first->rejected_intersecting;
}

tessel_status tsl_gp_oriented(const tessel_cloud *cloud, const tessel_greedy_params *params,
                              const tessel_callbacks *callbacks,
                              const tessel_triangle_sink *sink, tessel_recon_summary *summary)
{
    gp_collect all = {NULL, 0, 0}, more = {NULL, 0, 0};
    tessel_triangle_sink hold = {tsl_gp_collect_emit, &all};
    uint8_t *mark = NULL;
    size_t flipped = 0;
    tessel_status s = tsl_gp_pass(cloud, params, "greedy", callbacks, &hold, summary);
    if (s == TESSEL_OK && !(mark = tsl_alloc_array(all.count + 1, sizeof *mark)))
        s = TESSEL_ERR_NOMEM;
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, "orientation check", 0.0);
    if (s == TESSEL_OK)
        s = tsl_orient_check(cloud->xyz, cloud->count, all.tris, all.count, 0, mark, &flipped);
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, "orientation check", 1.0);
    if (s == TESSEL_OK && flipped) {
        all.count = apply_marks(all.tris, all.count, mark);
        free(mark);
        mark = NULL;
        s = single_fans(all.tris, &all.count, cloud->count);
        tessel_greedy_params again = *params;
        again.existing = all.tris;
        again.existing_count = all.count;
        tessel_recon_summary first = *summary;
        hold.user_data = &more;
        if (s == TESSEL_OK)
            s = tsl_gp_pass(cloud, &again, "greedy: orientation repair", callbacks, &hold,
                            summary);
        if (s == TESSEL_OK) {
            merge_summary(summary, &first, all.count);
            summary->reoriented = flipped;
            s = tsl_gp_collect_emit(&all, more.tris, more.count);
        }
    }
    if (s == TESSEL_OK && all.count > summary->peak_held_triangles)
        summary->peak_held_triangles = all.count;
    for (size_t t = 0; s == TESSEL_OK && t < all.count; t += OUT_BATCH) {
        size_t n = all.count - t < OUT_BATCH ? all.count - t : OUT_BATCH;
        s = sink->emit(sink->user_data, all.tris + 3 * t, n);
    }
    free(mark);
    free(all.tris);
    free(more.tris);
    return s;
}
