/* What greedy does with the whole mesh held (not in Gopi & Krishnan 2002;
 * docs/greedy.md): the front's triangles are kept until it stops, then
 *
 * 1. regions meshed inside out are found and rebuilt. The front orients
 *    each new triangle like the triangles already at its reference point
 *    (section 4.2). Where it steps from one sheet onto another that faces
 *    it closer than the sampling can separate (a hand on a thigh), it
 *    carries the wrong side across, and the region behind the step comes
 *    out inside out although every edge agrees with its neighbours. Only a
 *    global test sees it: the ray-parity check of src/mesh/orient.c, or, when
 *    the points have normals or a viewpoint, their verdict (a noisy scan
 *    folds the front over itself the same way). The regions found facing
 *    the wrong way are flipped, their rims and the triangles
 *    at points left with two fans (tsl_single_fans) dropped, and the front
 *    runs again from what is left (params.existing) to mesh the seams.
 * 2. diagonals are flipped where the two angles facing them add up to
 *    more than pi, the Delaunay rule (tsl_flip_diagonals, with the
 *    refinement's checks). Joining
 *    consecutive neighbours in angle order leaves many slivers, mostly
 *    where two parts of the front meet; the flips remove most of them
 *    without moving or adding a vertex.
 *
 * Then everything goes to the sink. */
#include "greedy/greedy.h"

/* Flags the vertices of the triangles marked 2 (the rims to drop): only
 * they can be left with more than one fan. */
static uint8_t *rim_vertices(const uint32_t *tri, size_t nt, const uint8_t *mark, size_t nv)
{
    uint8_t *touched = tsl_calloc_array(nv, sizeof *touched);
    for (size_t t = 0; touched && t < nt; t++)
        if (mark[t] == 2)
            for (int k = 0; k < 3; k++)
                touched[tri[3 * t + (size_t)k]] = 1;
    return touched;
}

/* The second pass's summary describes the output; the work of the first
 * (seeds, holes, refusals) is added to it. */
static void merge_summary(tessel_recon_summary *out, const tessel_recon_summary *first,
                          size_t existing)
{
    out->triangles += existing;
    out->tiles = first->tiles;
    out->seeds += first->seeds;
    out->holes_closed += first->holes_closed;
    out->rejected_intersecting += first->rejected_intersecting;
    out->flips += first->flips;
}

/* Step 1: the orientation check (by ray parity, or by the points' normals
 * or viewpoint when the cloud has them), and the repair when a region is
 * found inside out; all holds the mesh before and after. */
static tessel_status check_and_repair(const tessel_cloud *cloud,
                                      const tessel_greedy_params *params,
                                      const tessel_callbacks *callbacks, gp_collect *all,
                                      tessel_recon_summary *summary)
{
    gp_collect more = {NULL, 0, 0};
    uint8_t *mark = tsl_alloc_array(all->count + 1, sizeof *mark);
    size_t flipped = 0;
    tessel_status s = mark ? tsl_progress(callbacks, "orientation check", 0.0)
                           : TESSEL_ERR_NOMEM;
    bool known_side = cloud->has_viewpoint ||
                      (cloud->normals && tsl_normals_signed(cloud->normals, all->tris, all->count));
    if (s == TESSEL_OK && known_side) {
        /* The scanner's side, in the points' frame. */
        double vp[3];
        for (int k = 0; k < 3; k++)
            vp[k] = cloud->viewpoint[k] - cloud->offset[k];
        s = tsl_orient_check_toward(cloud->xyz, cloud->count, all->tris, all->count,
                                    cloud->has_viewpoint ? NULL : cloud->normals, vp, params->threads, mark,
                                    &flipped);
    } else if (s == TESSEL_OK) {
        s = tsl_orient_check(cloud->xyz, cloud->count, all->tris, all->count, params->threads, mark,
                             &flipped);
    }
    if (s == TESSEL_OK)
        s = tsl_progress(callbacks, "orientation check", 1.0);
    if (s == TESSEL_OK && flipped) {
        uint8_t *touched = rim_vertices(all->tris, all->count, mark, cloud->count);
        all->count = tsl_orient_apply(all->tris, all->count, mark, all->tris);
        free(mark);
        mark = NULL;
        s = touched ? tsl_single_fans(cloud->count, all->tris, &all->count, touched)
                    : TESSEL_ERR_NOMEM;
        free(touched);
        tessel_greedy_params again = *params;
        again.existing = all->tris;
        again.existing_count = all->count;
        tessel_recon_summary first = *summary;
        tessel_triangle_sink hold = {tsl_gp_collect_emit, &more};
        if (s == TESSEL_OK)
            s = tsl_gp_pass(cloud, &again, "greedy: orientation repair", callbacks, &hold,
                            summary);
        if (s == TESSEL_OK) {
            merge_summary(summary, &first, all->count);
            summary->reoriented = flipped;
            s = tsl_gp_collect_emit(all, more.tris, more.count);
        }
    }
    free(mark);
    free(more.tris);
    return s;
}

tessel_status tsl_gp_held(const tessel_cloud *cloud, const tessel_greedy_params *params,
                          bool check, const tsl_gp_tile_runner *runner,
                          const tessel_callbacks *callbacks,
                          const tessel_triangle_sink *sink, tessel_recon_summary *summary)
{
    gp_collect all = {NULL, 0, 0};
    tessel_triangle_sink hold = {tsl_gp_collect_emit, &all};
    tessel_status s = params->tile_points && cloud->count > params->tile_points &&
                              !params->existing_count
                          ? tsl_gp_tiled_pass(cloud, params, runner, callbacks, &all, summary)
                          : tsl_gp_pass(cloud, params, "greedy", callbacks, &hold, summary);
    if (s == TESSEL_OK && check)
        s = check_and_repair(cloud, params, callbacks, &all, summary);
    if (s == TESSEL_OK && params->flip) {
        /* Added to the tiles' flips, when there were tiles. */
        size_t flips = 0;
        s = tsl_progress(callbacks, "diagonal flips", 0.0);
        if (s == TESSEL_OK)
            s = tsl_flip_diagonals(cloud->xyz, cloud->count, all.tris, all.count, params->threads,
                                   &flips);
        if (s == TESSEL_OK)
            s = tsl_progress(callbacks, "diagonal flips", 1.0);
        summary->flips += flips;
    }
    if (s == TESSEL_OK && all.count > summary->peak_held_triangles)
        summary->peak_held_triangles = all.count;
    for (size_t t = 0; s == TESSEL_OK && t < all.count; t += OUT_BATCH) {
        size_t n = all.count - t < OUT_BATCH ? all.count - t : OUT_BATCH;
        s = sink->emit(sink->user_data, all.tris + 3 * t, n);
    }
    free(all.tris);
    return s;
}
