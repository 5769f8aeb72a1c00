/* The hole repair's count (src/greedy/holes.c): a repair counted around
 * what it changed gives what a count of the whole mesh gives, on a sphere
 * with holes punched in it (far apart, so that each repair's groups are
 * pieces of one component, and next to each other). */
#include "greedy/greedy.h"
#include "surfaces.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

/* Removes the triangles at each point of holes[] (a hole of its fan's
 * rim, the point left out). */
static void punch(gp_collect *all, const uint32_t *holes, size_t nh)
{
    size_t w = 0;
    for (size_t t = 0; t < all->count; t++) {
        const uint32_t *v = all->tris + 3 * t;
        bool hit = false;
        for (size_t h = 0; h < nh; h++)
            hit = hit || v[0] == holes[h] || v[1] == holes[h] || v[2] == holes[h];
        if (!hit)
            memmove(all->tris + 3 * w++, v, 3 * sizeof *v);
    }
    all->count = w;
}

/* The count after one repair round against a count of the whole mesh. */
static void check_round(const char *name, const tessel_cloud *c, const uint32_t *holes, size_t nh,
                        bool local)
{
    tessel_greedy_params p = tessel_greedy_params_default();
    gp_collect all = {NULL, 0, 0};
    tessel_triangle_sink sink = {tsl_gp_collect_emit, &all};
    tessel_recon_summary sum;
    CHECK(tessel_reconstruct_greedy(c, &p, NULL, &sink, &sum) == TESSEL_OK);
    size_t n = c->count;
    punch(&all, holes, nh);
    uint8_t *fate = calloc(n, 1), *dirty = calloc(n, 1), *fate2 = malloc(n);
    gp_count count = {0}, again = {0};
    tessel_recon_summary before = sum, after;
    CHECK(tsl_gp_drop_specks_and_count(n, &all, fate, 0, &count, &before) == TESSEL_OK);
    CHECK_MSG(before.boundary_edges >= 3 * nh, "%s: %zu boundary edges punched", name,
              before.boundary_edges);
    after = before;
    bool holes_left;
    CHECK(tsl_gp_reopen_holes(c, &p, NULL, &all, fate, dirty, &count, &after, 0, &holes_left) ==
          TESSEL_OK);
    CHECK_MSG(holes_left && after.boundary_edges < before.boundary_edges,
              "%s: %zu -> %zu boundary edges", name, before.boundary_edges, after.boundary_edges);
    CHECK_MSG(count.local == (local ? 1u : 0u), "%s: %zu repairs counted locally", name,
              count.local);
    gp_collect copy = {malloc(3 * all.count * sizeof *all.tris + 1), all.count, all.count};
    memcpy(copy.tris, all.tris, 3 * all.count * sizeof *all.tris);
    memcpy(fate2, fate, n);
    tessel_recon_summary full = after;
    CHECK(tsl_gp_drop_specks_and_count(n, &copy, fate2, 0, &again, &full) == TESSEL_OK);
    CHECK_MSG(copy.count == all.count && full.boundary_edges == after.boundary_edges &&
                  full.components == after.components && full.points_used == after.points_used &&
                  full.left_closed_in == after.left_closed_in &&
                  full.left_untriangulated == after.left_untriangulated &&
                  full.triangles == after.triangles,
              "%s: counted %zu boundary edges, %zu components, %zu points used; the whole "
              "mesh has %zu, %zu, %zu",
              name, after.boundary_edges, after.components, after.points_used,
              full.boundary_edges, full.components, full.points_used);
    CHECK(memcmp(again.open, count.open, n * sizeof *count.open) == 0);
    CHECK(memcmp(again.used, count.used, (n / 64 + 1) * sizeof *count.used) == 0);
    for (size_t v = 0; v < n; v++)
        if (again.used[v >> 6] >> (v & 63) & 1)
            CHECK(again.size[again.comp[v]] == count.size[count.comp[v]]);
    printf("%-16s %zu -> %zu boundary edges, %zu component(s)\n", name, before.boundary_edges,
           after.boundary_edges, after.components);
    tsl_gp_count_free(&count);
    tsl_gp_count_free(&again);
    free(all.tris);
    free(copy.tris);
    free(fate);
    free(fate2);
    free(dirty);
}

int main(void)
{
    tessel_cloud big, small;
    CHECK(surf_sphere_fibonacci(&big, 20000, 0.2, 7) == TESSEL_OK);
    CHECK(surf_sphere_fibonacci(&small, 1500, 0.2, 7) == TESSEL_OK);
    const uint32_t apart[] = {1000, 12000}, close[] = {5000, 5001, 5002};
    check_round("two holes apart", &big, apart, 2, true);
    check_round("holes together", &big, close, 3, true);
    /* Under 4,096 triangles a component could become a fragment: the
     * whole mesh is counted. */
    check_round("small sphere", &small, apart, 1, false);
    tessel_cloud_free(&big);
    tessel_cloud_free(&small);
    return TEST_SUMMARY();
}
