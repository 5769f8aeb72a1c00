/* Refinement (src/refine/) and the whole noisy-cloud pipeline
 * (src/pipeline/). Refinement of a coarse sphere against a dense
 * sample must bring the surface closer to the sphere while the mesh stays
 * closed, manifold, oriented and free of self-intersections, give the same
 * bits for any thread count, leave a plane alone and refuse invalid meshes.
 * The pipeline, on generated noisy surfaces without normals: a sphere and a
 * torus come out closed with the right genus and outward; a plane with a
 * hole keeps its two borders; two close parallel sheets stay two
 * components. */
#include "pipeline/pipeline.h"
#include "smooth/smooth.h"
#include "test.h"

#include "surfaces.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

static tessel_mesh_report check(const tessel_mesh *m)
{
    tessel_check_params cp = tessel_check_params_default();
    tessel_mesh_report r;
    memset(&r, 0, sizeof r);
    CHECK(tessel_mesh_check(m, &cp, &r) == TESSEL_OK);
    return r;
}

static bool valid_closed(const tessel_mesh_report *r, long genus)
{
    return tessel_mesh_report_valid(r) && r->self_intersections == 0 &&
           r->boundary_edges == 0 && r->components == 1 && r->genus == genus;
}

/* Mean and largest | |c| - 1 | over triangle centroids and edge midpoints:
 * how far the piecewise-linear surface is from the unit sphere. */
static void sphere_error(const tessel_mesh *m, double *mean, double *max)
{
    double sum = 0.0, mx = 0.0;
    size_t n = 0;
    for (size_t t = 0; t < m->triangle_count; t++) {
        const float *p[3];
        for (int i = 0; i < 3; i++)
            p[i] = m->xyz + 3 * (size_t)m->triangles[3 * t + i];
        for (int s = 0; s < 4; s++) {
            double c[3];
            for (int k = 0; k < 3; k++)
                c[k] = s == 3 ? (p[0][k] + p[1][k] + p[2][k]) / 3.0
                              : 0.5 * (p[s][k] + p[(s + 1) % 3][k]);
            double e = fabs(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) - 1.0);
            sum += e;
            mx = e > mx ? e : mx;
            n++;
        }
    }
    *mean = sum / (double)n;
    *max = mx;
}

static double signed_volume(const tessel_mesh *m)
{
    double v = 0.0;
    for (size_t t = 0; t < m->triangle_count; t++) {
        const float *a = m->xyz + 3 * m->triangles[3 * t];
        const float *b = m->xyz + 3 * m->triangles[3 * t + 1];
        const float *c = m->xyz + 3 * m->triangles[3 * t + 2];
        v += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) +
              a[1] * ((double)b[2] * c[0] - (double)b[0] * c[2]) +
              a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) /
             6.0;
    }
    return v;
}

static bool same_mesh(const tessel_mesh *a, const tessel_mesh *b)
{
    return a->vertex_count == b->vertex_count && a->triangle_count == b->triangle_count &&
           memcmp(a->xyz, b->xyz, 3 * a->vertex_count * sizeof *a->xyz) == 0 &&
           memcmp(a->triangles, b->triangles, 3 * a->triangle_count * sizeof *a->triangles) ==
               0;
}

static int cmp_tri(const void *pa, const void *pb)
{
    const uint32_t *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a[i] != b[i])
            return a[i] < b[i] ? -1 : 1;
    return 0;
}

/* The same vertices and the same oriented triangles, in any order. */
static bool same_surface(const tessel_mesh *a, const tessel_mesh *b)
{
    if (a->vertex_count != b->vertex_count || a->triangle_count != b->triangle_count ||
        memcmp(a->xyz, b->xyz, 3 * a->vertex_count * sizeof *a->xyz) != 0)
        return false;
    size_t n = a->triangle_count;
    uint32_t *t[2] = {malloc(3 * n * sizeof(uint32_t)), malloc(3 * n * sizeof(uint32_t))};
    bool same = t[0] && t[1];
    for (int m = 0; m < 2 && same; m++) {
        const uint32_t *src = m ? b->triangles : a->triangles;
        for (size_t i = 0; i < n; i++) {
            int r = src[3 * i] < src[3 * i + 1] ? (src[3 * i] < src[3 * i + 2] ? 0 : 2)
                                                : (src[3 * i + 1] < src[3 * i + 2] ? 1 : 2);
            for (int k = 0; k < 3; k++)
                t[m][3 * i + k] = src[3 * i + (r + k) % 3];
        }
        qsort(t[m], n, 3 * sizeof(uint32_t), cmp_tri);
    }
    same = same && memcmp(t[0], t[1], 3 * n * sizeof(uint32_t)) == 0;
    free(t[0]);
    free(t[1]);
    return same;
}

static tessel_status copy_mesh(tessel_mesh *dst, const tessel_mesh *src)
{
    tessel_status st = tessel_mesh_alloc(dst, src->vertex_count, src->triangle_count,
                                         src->normals != NULL, src->rgb != NULL);
    if (st)
        return st;
    memcpy(dst->xyz, src->xyz, 3 * src->vertex_count * sizeof *src->xyz);
    memcpy(dst->triangles, src->triangles, 3 * src->triangle_count * sizeof *src->triangles);
    if (src->normals)
        memcpy(dst->normals, src->normals, 3 * src->vertex_count * sizeof *src->normals);
    if (src->rgb)
        memcpy(dst->rgb, src->rgb, 3 * src->vertex_count);
    return TESSEL_OK;
}

static void test_refine_sphere(void)
{
    /* A coarse triangulation (about 200 vertices) of the unit sphere and a
     * dense sample of it. */
    tessel_cloud coarse, dense;
    CHECK(surf_sphere(&coarse, 0.25, 1) == TESSEL_OK);
    CHECK(surf_sphere_fibonacci(&dense, 20000, 0.3, 2) == TESSEL_OK);
    tessel_mesh m;
    CHECK(tessel_advancing_front(&coarse, NULL, NULL, &m, NULL) == TESSEL_OK);
    tessel_mesh_report r0 = check(&m);
    CHECK(valid_closed(&r0, 0));
    double mean0, max0;
    sphere_error(&m, &mean0, &max0);

    tessel_mesh m2;
    CHECK(copy_mesh(&m2, &m) == TESSEL_OK);
    tessel_refine_params rp = tessel_refine_params_default();
    rp.threads = 1;
    tessel_refine_stats rs;
    CHECK(tessel_refine(&m, &dense, NULL, &rp, NULL, &rs) == TESSEL_OK);
    tessel_mesh_report r1 = check(&m);
    CHECK_MSG(valid_closed(&r1, 0), "refined sphere: %zu boundary, %zu self-intersections, "
                                    "%zu components",
              r1.boundary_edges, r1.self_intersections, r1.components);
    CHECK(r1.oriented && signed_volume(&m) > 0.0);
    CHECK(rs.splits > 0 && rs.flips > 0);
    CHECK(m.triangle_count == r0.triangles + 2 * rs.splits);
    CHECK(m.vertex_count == coarse.count + rs.splits);
    double mean1, max1;
    sphere_error(&m, &mean1, &max1);
    CHECK_MSG(mean1 < 0.5 * mean0, "surface error %g -> %g", mean0, mean1);
    CHECK(max1 < max0);
    /* New vertices lie on the sphere (Q projects onto the dense sample). */
    double worst = 0.0;
    for (size_t v = coarse.count; v < m.vertex_count; v++) {
        const float *p = m.xyz + 3 * v;
        double e = fabs(sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]) -
                        1.0);
        worst = e > worst ? e : worst;
    }
    CHECK_MSG(worst < 0.01, "new vertex %g off the sphere", worst);
    /* Vertex normals updated for every vertex, unit and outward. */
    CHECK(m.normals != NULL);
    size_t bad_normals = 0;
    for (size_t v = 0; v < m.vertex_count; v++) {
        const float *p = m.xyz + 3 * v, *n = m.normals + 3 * v;
        double d = p[0] * n[0] + p[1] * n[1] + p[2] * n[2];
        bad_normals += d < 0.9;
    }
    CHECK(bad_normals == 0);
    printf("refine sphere: %zu -> %zu triangles, error mean %.4f -> %.4f, max %.4f -> %.4f\n",
           r0.triangles, m.triangle_count, mean0, mean1, max0, max1);

    /* Same bits with two threads. */
    rp.threads = 2;
    CHECK(tessel_refine(&m2, &dense, NULL, &rp, NULL, NULL) == TESSEL_OK);
    CHECK(same_mesh(&m, &m2));
    tessel_mesh_free(&m);
    tessel_mesh_free(&m2);
    tessel_cloud_free(&coarse);
    tessel_cloud_free(&dense);
}

/* The parallel splits (split_passes) on a mesh of many blocks: a noisy
 * triangulation of the unit sphere (edges about 0.03; blocks 16 mean
 * edges wide: 64 blocks, 3 to 8 of each colour with splits) refined
 * against a dense sample. One, two and three threads give the same bits; the mesh
 * stays valid and closed, and each split adds one vertex and two
 * triangles. */
static void test_refine_split_blocks(void)
{
    tessel_cloud coarse, dense;
    CHECK(surf_sphere(&coarse, 0.025, 41) == TESSEL_OK);
    free(coarse.normals);
    coarse.normals = NULL;
    surf_noise(&coarse, 0.005, 42);
    CHECK(surf_sphere_fibonacci(&dense, 100000, 0.3, 43) == TESSEL_OK);
    tessel_mesh m[3];
    tessel_refine_stats rs[3];
    tessel_mesh_report r0;
    for (int t = 0; t < 3; t++) {
        CHECK(tessel_advancing_front(&coarse, NULL, NULL, &m[t], NULL) == TESSEL_OK);
        if (t == 0)
            r0 = check(&m[0]);
        tessel_refine_params rp = tessel_refine_params_default();
        rp.rounds = 1;
        rp.threads = t + 1;
        CHECK(tessel_refine(&m[t], &dense, NULL, &rp, NULL, &rs[t]) == TESSEL_OK);
    }
    tessel_mesh_report r = check(&m[0]);
    CHECK_MSG(tessel_mesh_report_valid(&r) && r.self_intersections == 0 &&
                  r.boundary_edges == r0.boundary_edges,
              "split blocks: %zu self-intersections, %zu boundary edges (%zu before)",
              r.self_intersections, r.boundary_edges, r0.boundary_edges);
    CHECK_MSG(rs[0].splits > 1000, "split blocks: %zu splits", (size_t)rs[0].splits);
    CHECK(m[0].vertex_count == coarse.count + rs[0].splits);
    CHECK(m[0].triangle_count == r0.triangles + 2 * rs[0].splits);
    CHECK(same_mesh(&m[0], &m[1]) && same_mesh(&m[0], &m[2]));
    printf("split blocks: %zu -> %zu triangles, %zu splits, %zu refused\n", r0.triangles,
           m[0].triangle_count, (size_t)rs[0].splits, (size_t)rs[0].skipped_invalid);
    for (int t = 0; t < 3; t++)
        tessel_mesh_free(&m[t]);
    tessel_cloud_free(&coarse);
    tessel_cloud_free(&dense);
}

static void test_refine_rounds(void)
{
    /* A finer triangulation, most of whose edges survive the first round:
     * the second round reuses their fits. One call of two rounds and two
     * calls of one round (which fit every edge again) give the same
     * surface (the triangles may come in another order). */
    tessel_cloud coarse, dense;
    CHECK(surf_sphere(&coarse, 0.09, 3) == TESSEL_OK);
    CHECK(surf_sphere_fibonacci(&dense, 20000, 0.3, 4) == TESSEL_OK);
    tessel_mesh m, m2;
    CHECK(tessel_advancing_front(&coarse, NULL, NULL, &m, NULL) == TESSEL_OK);
    CHECK(copy_mesh(&m2, &m) == TESSEL_OK);
    tessel_refine_params rp = tessel_refine_params_default();
    tessel_refine_stats rs;
    CHECK(tessel_refine(&m, &dense, NULL, &rp, NULL, &rs) == TESSEL_OK);
    rp.rounds = 1;
    tessel_refine_stats r1, r2;
    CHECK(tessel_refine(&m2, &dense, NULL, &rp, NULL, &r1) == TESSEL_OK);
    CHECK(!same_surface(&m, &m2));
    CHECK(tessel_refine(&m2, &dense, NULL, &rp, NULL, &r2) == TESSEL_OK);
    CHECK(r1.splits > 0 && r2.splits > 0);
    CHECK(rs.splits == r1.splits + r2.splits && rs.far_edges == r1.far_edges + r2.far_edges);
    CHECK(same_surface(&m, &m2));
    printf("refine rounds: %zu vertices, splits %zu + %zu\n", coarse.count, r1.splits,
           r2.splits);
    tessel_mesh_free(&m);
    tessel_mesh_free(&m2);
    tessel_cloud_free(&coarse);
    tessel_cloud_free(&dense);
}

static void test_refine_plane(void)
{
    /* A plane is already fitted: no edge is far from the cloud. */
    tessel_cloud coarse, dense;
    CHECK(surf_plane_hole(&coarse, 0.2, 3) == TESSEL_OK);
    CHECK(surf_plane_hole(&dense, 0.03, 4) == TESSEL_OK);
    tessel_mesh m;
    CHECK(tessel_advancing_front(&coarse, NULL, NULL, &m, NULL) == TESSEL_OK);
    size_t before = m.triangle_count;
    tessel_refine_stats rs;
    CHECK(tessel_refine(&m, &dense, NULL, NULL, NULL, &rs) == TESSEL_OK);
    CHECK(rs.splits == 0 && rs.far_edges == 0);
    CHECK(m.triangle_count == before);
    tessel_mesh_report r = check(&m);
    CHECK(tessel_mesh_report_valid(&r) && r.self_intersections == 0);
    tessel_mesh_free(&m);
    tessel_cloud_free(&coarse);
    tessel_cloud_free(&dense);
}

static long peak_rss_kb(void)
{
    struct rusage u;
    return getrusage(RUSAGE_SELF, &u) == 0 ? u.ru_maxrss : 0; /* KB on Linux */
}

/* A caller's mesh with one triangle far larger than its mean edge: a fine
 * patch (edges of 0.001) and, apart from it, a triangle 10 across. The
 * refinement's triangle grid had cells of two mean edges, and that triangle
 * alone covered 1.6e7 of them (about 500 MB); the grid must stay small. */
static void test_refine_large_triangle(void)
{
    enum { N = 20 };
    tessel_mesh m;
    size_t nt = 2 * (N - 1) * (N - 1) + 1;
    CHECK(tessel_mesh_alloc(&m, N * N + 3, nt, 0, 0) == TESSEL_OK);
    for (int y = 0; y < N; y++)
        for (int x = 0; x < N; x++) {
            float *p = m.xyz + 3 * (y * N + x);
            p[0] = 0.001f * (float)x;
            p[1] = 0.001f * (float)y;
            p[2] = 0.0f;
        }
    const float big[9] = {20, 10, 10, 10, 20, 10, 10, 10, 20};
    memcpy(m.xyz + 3 * N * N, big, sizeof big);
    size_t t = 0;
    for (uint32_t y = 0; y + 1 < N; y++)
        for (uint32_t x = 0; x + 1 < N; x++) {
            uint32_t a = y * N + x, b = a + 1, c = a + N, d = c + 1;
            uint32_t two[6] = {a, b, d, a, d, c};
            memcpy(m.triangles + 3 * t, two, sizeof two);
            t += 2;
        }
    uint32_t last[3] = {N * N, N * N + 1, N * N + 2};
    memcpy(m.triangles + 3 * t, last, sizeof last);
    tessel_cloud cloud;
    CHECK(tessel_cloud_alloc(&cloud, m.vertex_count, 0, 0) == TESSEL_OK);
    memcpy(cloud.xyz, m.xyz, 3 * m.vertex_count * sizeof *m.xyz);
    long before = peak_rss_kb();
    tessel_refine_params rp = tessel_refine_params_default();
    rp.rounds = 1;
    CHECK(tessel_refine(&m, &cloud, NULL, &rp, NULL, NULL) == TESSEL_OK);
    long grown = peak_rss_kb() - before;
    CHECK_MSG(grown < 64 * 1024, "peak memory grew by %ld KB", grown);
    tessel_mesh_report r = check(&m);
    CHECK(tessel_mesh_report_valid(&r) && r.self_intersections == 0);
    tessel_mesh_free(&m);
    tessel_cloud_free(&cloud);
}

/* A vertex with two fans: a tent (u, v, a) + (v, u, b) whose ridge uv the
 * Delaunay rule would flip to ab (the angles at a and b add up to 239
 * degrees), while the edge ab already exists in a triangle (a, b, w)
 * hanging below, a fan of its own at a and at b. The flip would put ab in
 * three triangles; the parallel flips see one fan of a vertex only, so
 * such pairs go to the serial pass, which asks the edge map and refuses. */
static void test_refine_pinched(void)
{
    const float xyz[15] = {-1, 0, 0.5f, 1, 0, 0.5f, 0, 0.3f, 0, 0, -0.3f, 0, 0, 0, -1};
    const uint32_t tris[9] = {0, 1, 2, 1, 0, 3, 2, 3, 4};
    tessel_mesh m;
    tessel_cloud cloud;
    CHECK(tessel_mesh_alloc(&m, 5, 3, 0, 0) == TESSEL_OK);
    CHECK(tessel_cloud_alloc(&cloud, 5, 0, 0) == TESSEL_OK);
    memcpy(m.xyz, xyz, sizeof xyz);
    memcpy(m.triangles, tris, sizeof tris);
    memcpy(cloud.xyz, xyz, sizeof xyz);
    tessel_refine_params p = tessel_refine_params_default();
    p.rounds = 1;
    p.min_offset = 1e9; /* flips only */
    tessel_refine_stats s;
    CHECK(tessel_refine(&m, &cloud, NULL, &p, NULL, &s) == TESSEL_OK);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(r.nonmanifold_edges == 0 && s.flips == 0 && m.triangle_count == 3 &&
                  memcmp(m.triangles, tris, sizeof tris) == 0,
              "pinched: %zu non-manifold edges, %zu flips", r.nonmanifold_edges,
              (size_t)s.flips);
    /* Without the hanging triangle the same tent flips. */
    m.triangle_count = 2;
    CHECK(tessel_refine(&m, &cloud, NULL, &p, NULL, &s) == TESSEL_OK);
    CHECK(s.flips == 1 && m.triangle_count == 2);
    tessel_mesh_free(&m);
    tessel_cloud_free(&cloud);
}

static void test_refine_invalid(void)
{
    tessel_cloud cloud;
    CHECK(surf_sphere(&cloud, 0.3, 5) == TESSEL_OK);
    /* Three triangles on edge 0-1. */
    tessel_mesh m;
    CHECK(tessel_mesh_alloc(&m, 5, 3, 0, 0) == TESSEL_OK);
    const float xyz[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1};
    const uint32_t tris[9] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    memcpy(m.xyz, xyz, sizeof xyz);
    memcpy(m.triangles, tris, sizeof tris);
    CHECK(tessel_refine(&m, &cloud, NULL, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    CHECK(m.triangle_count == 3 && memcmp(m.triangles, tris, sizeof tris) == 0);
    /* Same direction twice on an edge. */
    m.triangle_count = 2;
    m.triangles[3] = 0, m.triangles[4] = 1, m.triangles[5] = 3;
    CHECK(tessel_refine(&m, &cloud, NULL, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    /* Frames differ. */
    m.triangles[3] = 1, m.triangles[4] = 0;
    m.offset[0] = 1.0;
    CHECK(tessel_refine(&m, &cloud, NULL, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    m.offset[0] = 0.0;
    tessel_refine_params bad = tessel_refine_params_default();
    bad.min_edge_ratio = 2.0;
    CHECK(tessel_refine(&m, &cloud, NULL, &bad, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_mesh_free(&m);
    tessel_cloud_free(&cloud);
}

/* Noisy clouds without normals through the whole pipeline. */
static tessel_mesh run_pipeline(tessel_cloud *c, double noise, uint64_t seed,
                                tessel_smooth_recon_stats *s)
{
    free(c->normals);
    c->normals = NULL;
    surf_noise(c, noise, seed);
    tessel_mesh m;
    tessel_status st = tessel_reconstruct_smooth(c, NULL, NULL, &m, s);
    CHECK_MSG(st == TESSEL_OK, "pipeline: %s", tessel_status_str(st));
    return m;
}

static void test_pipeline_sphere(void)
{
    tessel_cloud c;
    CHECK(surf_sphere(&c, 0.04, 6) == TESSEL_OK);
    tessel_smooth_recon_stats s;
    tessel_mesh m = run_pipeline(&c, 0.02, 7, &s);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(valid_closed(&r, 0), "noisy sphere: %zu boundary edges, %zu components",
              r.boundary_edges, r.components);
    CHECK(signed_volume(&m) > 0.0);
    double mean, max;
    sphere_error(&m, &mean, &max);
    CHECK_MSG(mean < 0.01 && max < 0.06, "noisy sphere error mean %g max %g", mean, max);
    CHECK(s.representatives < c.count / 3 && s.vertices > s.representatives);
    CHECK(s.seconds_total >= s.seconds_smooth + s.seconds_front);
    printf("pipeline sphere: %zu points (noise 0.02) -> %zu reps -> %zu triangles, error mean "
           "%.4f max %.4f\n",
           c.count, s.representatives, m.triangle_count, mean, max);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

static void test_pipeline_torus(void)
{
    tessel_cloud c;
    CHECK(surf_torus(&c, 1.0, 0.4, 0.04, 8) == TESSEL_OK);
    tessel_smooth_recon_stats s;
    tessel_mesh m = run_pipeline(&c, 0.015, 9, &s);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(valid_closed(&r, 1), "noisy torus: %zu boundary edges, genus %ld",
              r.boundary_edges, r.genus);
    CHECK(signed_volume(&m) > 0.0);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

static void test_pipeline_narrow_torus(void)
{
    /* A torus whose hole (0.16 across) is narrower than the clusters (up to
     * 8 spacings, 0.24 here): with this seed the front on the
     * representatives leaves holes around it (63 border edges), and the
     * second front, with extra representatives there, closes them. The
     * result is valid and closed; the torus's hole itself is below the
     * resolution of the representatives and ends up spanned (genus 0). */
    tessel_cloud c;
    CHECK(surf_torus(&c, 0.5, 0.42, 0.03, 1) == TESSEL_OK);
    surf_noise(&c, 0.015, 101);
    tessel_smooth_recon_stats s;
    tessel_mesh m;
    CHECK(tessel_reconstruct_smooth(&c, NULL, NULL, &m, &s) == TESSEL_OK);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(tessel_mesh_report_valid(&r) && r.self_intersections == 0 && r.components == 1,
              "narrow torus: %zu components, %zu self-intersections", r.components,
              r.self_intersections);
    CHECK_MSG(s.front.border_edges == 0 && r.boundary_edges == 0,
              "narrow torus: %zu border edges after the front, %zu in the result",
              s.front.border_edges, r.boundary_edges);
    CHECK(signed_volume(&m) > 0.0);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

static void test_pipeline_open(void)
{
    /* Square with a round hole: two borders, one component. */
    tessel_cloud c;
    CHECK(surf_plane_hole(&c, 0.02, 10) == TESSEL_OK);
    tessel_smooth_recon_stats s;
    tessel_mesh m = run_pipeline(&c, 0.01, 11, &s);
    tessel_mesh_report r = check(&m);
    CHECK(s.border_edges == r.boundary_edges && s.triangles == r.triangles);
    CHECK(tessel_mesh_report_valid(&r) && r.self_intersections == 0);
    CHECK_MSG(r.components == 1 && r.boundary_loops == 2, "plane with hole: %zu components, "
                                                          "%zu loops",
              r.components, r.boundary_loops);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

static void test_pipeline_sheets(void)
{
    /* Two parallel sheets 0.3 apart (14 spacings, 4 between neighbouring
     * representatives): two components. */
    tessel_cloud a, two;
    CHECK(surf_plane_hole(&a, 0.02, 12) == TESSEL_OK);
    CHECK(tessel_cloud_alloc(&two, 2 * a.count, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < a.count; i++)
        for (int k = 0; k < 3; k++) {
            two.xyz[3 * i + k] = a.xyz[3 * i + k];
            two.xyz[3 * (a.count + i) + k] = a.xyz[3 * i + k] + (k == 2 ? 0.3f : 0.0f);
        }
    tessel_mesh m = run_pipeline(&two, 0.01, 13, NULL);
    tessel_mesh_report r = check(&m);
    CHECK(tessel_mesh_report_valid(&r) && r.self_intersections == 0);
    CHECK_MSG(r.components == 2 && r.boundary_loops == 4, "sheets: %zu components, %zu loops",
              r.components, r.boundary_loops);
    size_t spanning = 0;
    for (size_t t = 0; t < m.triangle_count; t++) {
        float z[3];
        for (int i = 0; i < 3; i++)
            z[i] = m.xyz[3 * (size_t)m.triangles[3 * t + i] + 2];
        spanning += fabsf(z[0] - z[1]) > 0.15f || fabsf(z[0] - z[2]) > 0.15f;
    }
    CHECK(spanning == 0);
    tessel_mesh_free(&m);
    tessel_cloud_free(&a);
    tessel_cloud_free(&two);
}


static int cancel_at_refine(void *user, const char *stage, double fraction)
{
    (void)fraction;
    int *calls = user;
    ++*calls;
    return strcmp(stage, "refine") == 0;
}

/* One stray point far from the surface: the spacing (the unit of every
 * length of the pipeline) must come from the surface, and the sphere must
 * come out closed as without it (it used to become a few triangles). */
static void test_pipeline_far_point(void)
{
    tessel_cloud s, c;
    CHECK(surf_sphere(&s, 0.04, 6) == TESSEL_OK);
    free(s.normals);
    s.normals = NULL;
    surf_noise(&s, 0.02, 7);
    CHECK(tessel_cloud_alloc(&c, s.count + 1, 0, 0) == TESSEL_OK);
    memcpy(c.xyz, s.xyz, 3 * s.count * sizeof *c.xyz);
    const float far[3] = {1e4f, 0.0f, 0.0f};
    memcpy(c.xyz + 3 * s.count, far, sizeof far);
    tessel_smooth_recon_stats st;
    tessel_mesh m;
    CHECK(tessel_reconstruct_smooth(&c, NULL, NULL, &m, &st) == TESSEL_OK);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(valid_closed(&r, 0) && st.spacing < 0.1,
              "sphere with a far point: spacing %g, %zu triangles, %zu boundary edges, %zu "
              "components",
              st.spacing, m.triangle_count, r.boundary_edges, r.components);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
    tessel_cloud_free(&s);
}

static void test_pipeline_threads_and_cancel(void)
{
    /* Same bits for 1 and 2 threads; a progress callback that says stop
     * stops it with TESSEL_ERR_CANCELLED and no mesh. */
    tessel_cloud c;
    CHECK(surf_sphere(&c, 0.05, 20) == TESSEL_OK);
    free(c.normals);
    c.normals = NULL;
    surf_noise(&c, 0.02, 21);
    tessel_smooth_recon_params p = tessel_smooth_recon_params_default();
    tessel_mesh m1, m2;
    p.threads = 1;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &m1, NULL) == TESSEL_OK);
    p.threads = 2;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &m2, NULL) == TESSEL_OK);
    CHECK(m1.triangle_count > 0 && same_mesh(&m1, &m2));
    int calls = 0;
    tessel_callbacks cb = {cancel_at_refine, NULL, &calls};
    tessel_mesh m3;
    CHECK(tessel_reconstruct_smooth(&c, &p, &cb, &m3, NULL) == TESSEL_ERR_CANCELLED);
    CHECK(calls > 0 && m3.triangle_count == 0 && m3.triangles == NULL);
    tessel_mesh_free(&m1);
    tessel_mesh_free(&m2);
    tessel_cloud_free(&c);
}

/* Two spheres whose gap (0.02) is half the spacing: the front steps from
 * one onto the other as if they were one sheet and, without the
 * orientation check, meshes the second inside out (about half the area
 * faced inward with this seed). Every triangle must face away from its own
 * sphere's centre, and the two must stay apart. */
static void test_pipeline_touching_spheres(void)
{
    const double gap = 0.02;
    tessel_cloud c;
    CHECK(surf_two_spheres(&c, 0.04, gap, 21) == TESSEL_OK);
    surf_noise(&c, 0.004, 22);
    tessel_smooth_recon_stats s;
    tessel_mesh m;
    CHECK(tessel_reconstruct_smooth(&c, NULL, NULL, &m, &s) == TESSEL_OK);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(tessel_mesh_report_valid(&r) && r.self_intersections == 0 && r.components == 2,
              "touching spheres: %zu components, %zu self-intersections", r.components,
              r.self_intersections);
    double inward = surf_two_spheres_inward(m.xyz, m.triangles, m.triangle_count, gap);
    CHECK_MSG(inward < 1.0, "touching spheres: %.2f%% of the area faces inward", inward);
    CHECK(s.reoriented > 0);
    printf("touching spheres: %zu triangles turned outward, %.2f%% of the area inward, %zu "
           "border edges\n",
           s.reoriented, inward, r.boundary_edges);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

/* Appends to m a grid of n x n quads (2 n^2 triangles) at height z, or a
 * tetrahedron (4 triangles) at x when n is 0: separate components. */
static void add_piece(tessel_mesh *m, int n, float x, float z)
{
    size_t v0 = m->vertex_count, t0 = m->triangle_count;
    size_t nv = n ? (size_t)(n + 1) * (size_t)(n + 1) : 4, nt = n ? 2 * (size_t)n * (size_t)n : 4;
    m->xyz = realloc(m->xyz, 3 * (v0 + nv) * sizeof *m->xyz);
    m->triangles = realloc(m->triangles, 3 * (t0 + nt) * sizeof *m->triangles);
    CHECK(m->xyz && m->triangles);
    float *p = m->xyz + 3 * v0;
    uint32_t *t = m->triangles + 3 * t0, b = (uint32_t)v0;
    if (!n) {
        const float q[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        const uint32_t f[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
        for (int i = 0; i < 4; i++) {
            for (int k = 0; k < 3; k++) {
                p[3 * i + k] = q[i][k] + (k == 0 ? x : 0.0f);
                t[3 * i + k] = b + f[i][k];
            }
        }
    } else {
        for (int j = 0; j <= n; j++)
            for (int i = 0; i <= n; i++) {
                float *q = p + 3 * ((size_t)j * (size_t)(n + 1) + (size_t)i);
                q[0] = (float)i, q[1] = (float)j, q[2] = z;
            }
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                uint32_t a = b + (uint32_t)(j * (n + 1) + i), c = a + (uint32_t)(n + 1);
                const uint32_t q[6] = {a, a + 1, c + 1, a, c + 1, c};
                memcpy(t + 6 * ((size_t)j * (size_t)n + (size_t)i), q, sizeof q);
            }
    }
    m->vertex_count = v0 + nv;
    m->triangle_count = t0 + nt;
}

static size_t strays_of(const tessel_mesh *m)
{
    size_t n = 99, pieces = 99;
    CHECK(tsl_stray_pieces(m, &n, &pieces) == TESSEL_OK);
    CHECK(n + pieces > 0);
    return n;
}

/* Which components the pipeline's repair treats as stray pieces: those of
 * at most 1% of the triangles, unless there are more than 8 of them. */
static void test_stray_pieces(void)
{
    tessel_mesh m;
    memset(&m, 0, sizeof m);
    add_piece(&m, 20, 0.0f, 0.0f); /* 800 triangles */
    CHECK(strays_of(&m) == 0);
    add_piece(&m, 0, 50.0f, 0.0f); /* 4 of 804: under 1% */
    CHECK(strays_of(&m) == 1);
    add_piece(&m, 20, 0.0f, 5.0f); /* a second large piece is no stray */
    CHECK(strays_of(&m) == 1);
    for (int i = 0; i < 7; i++)
        add_piece(&m, 0, 60.0f + 3.0f * (float)i, 0.0f);
    CHECK(strays_of(&m) == 8);
    add_piece(&m, 0, 90.0f, 0.0f); /* nine: a scene of many pieces */
    CHECK(strays_of(&m) == 0);
    tessel_mesh_free(&m);
    memset(&m, 0, sizeof m);
    add_piece(&m, 7, 0.0f, 0.0f);  /* 98 triangles: the tetrahedron is 3.9% */
    add_piece(&m, 0, 50.0f, 0.0f);
    CHECK(strays_of(&m) == 0);
    tessel_mesh_free(&m);
}

/* A torus whose tube is 7.5 spacings across, under noise of one spacing:
 * the clusters (8 spacings wide at this noise) are coarse for the tube,
 * and with this seed the front cuts it in four places, closing each cut
 * on both sides: four closed pieces, and no border edge to show it. The
 * repair prefers attempts with fewer components (other than stray pieces),
 * then fewer border edges: the front again with extra representatives
 * joins the pieces into one. One cut is left, closed at both ends (genus 0
 * instead of 1): nothing counts it. */
static void test_pipeline_thin_torus(void)
{
    tessel_cloud c;
    CHECK(surf_torus(&c, 1.0, 0.075, 0.02, 4) == TESSEL_OK);
    tessel_smooth_recon_stats s;
    /* No thinning: on a tube under 4 noise sigmas in radius and 19 points
     * round, no neighbourhood is both a slab above the noise and flat, and
     * the noise estimate comes out two to three times too high (a known
     * limit, docs/noise.md); the repair is what this case tests. */
    tessel_smooth_recon_params p = tessel_smooth_recon_params_default();
    p.noise_ratio_max = 0.0;
    free(c.normals);
    c.normals = NULL;
    surf_noise(&c, 0.02, 4);
    tessel_mesh m;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &m, &s) == TESSEL_OK);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(tessel_mesh_report_valid(&r) && r.self_intersections == 0 && r.components == 1 &&
                  r.boundary_edges == 0,
              "thin torus: %zu components, %zu boundary edges, %zu self-intersections",
              r.components, r.boundary_edges, r.self_intersections);
    CHECK(strays_of(&m) == 0);
    printf("thin torus: noise %.2f surface spacings, %zu of %zu points used, %zu triangles, %zu "
           "components, genus %ld\n",
           s.noise_ratio, s.points_used, s.points, m.triangle_count, r.components, r.genus);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

/* A dense sphere under noise of four surface spacings: thinned to two and
 * each kept point fitted to its neighbours in the whole cloud, the mesh
 * lies much closer to the sphere than the noise (without the fit its RMS
 * error is RMS_UNFITTED sigma), closed, and the same for 1 and 2 threads. */
static void test_pipeline_dense_noise(void)
{
    const double sigma = 0.045; /* per coordinate, so also along the normal: 4 spacings */
    tessel_mesh m[2];
    tessel_smooth_recon_stats s;
    for (int run = 0; run < 2; run++) {
        tessel_cloud c;
        CHECK(surf_sphere_fibonacci(&c, 100000, 0.3, 7) == TESSEL_OK);
        free(c.normals);
        c.normals = NULL;
        surf_noise(&c, sigma, 7);
        tessel_smooth_recon_params p = tessel_smooth_recon_params_default();
        p.threads = run + 1;
        CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &m[run], &s) == TESSEL_OK);
        tessel_cloud_free(&c);
    }
    tessel_mesh_report r = check(&m[0]);
    CHECK_MSG(tessel_mesh_report_valid(&r) && r.self_intersections == 0 && r.components == 1 &&
                  r.boundary_edges == 0,
              "dense noisy sphere: %zu components, %zu boundary edges, %zu self-intersections",
              r.components, r.boundary_edges, r.self_intersections);
    CHECK_MSG(s.fitted && s.points_used < s.points / 2, "dense noisy sphere: fitted %d, %zu of %zu",
              s.fitted, s.points_used, s.points);
    double e2 = 0.0;
    for (size_t v = 0; v < m[0].vertex_count; v++) {
        const float *q = m[0].xyz + 3 * v;
        double d = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]) - 1.0;
        e2 += d * d;
    }
    double rms = sqrt(e2 / (double)m[0].vertex_count) / sigma;
    CHECK_MSG(rms < 0.2, "dense noisy sphere: RMS error %.3f noise sigmas", rms);
    CHECK(m[0].vertex_count == m[1].vertex_count && m[0].triangle_count == m[1].triangle_count &&
          !memcmp(m[0].xyz, m[1].xyz, 3 * m[0].vertex_count * sizeof *m[0].xyz) &&
          !memcmp(m[0].triangles, m[1].triangles, 3 * m[0].triangle_count * sizeof(uint32_t)));
    printf("dense noisy sphere: noise %.2f surface spacings, %zu of %zu points used, RMS error "
           "%.3f sigmas, %zu triangles\n",
           s.noise_ratio, s.points_used, s.points, rms, m[0].triangle_count);
    tessel_mesh_free(&m[0]);
    tessel_mesh_free(&m[1]);
}

/* A noise the caller measured already is used as given: the measured one
 * gives the same mesh as measuring again, a larger one thins the cloud
 * further, and a negative or NaN one is refused. */
static void test_pipeline_given_noise(void)
{
    tessel_cloud c;
    CHECK(surf_sphere_fibonacci(&c, 20000, 0.3, 5) == TESSEL_OK);
    free(c.normals);
    c.normals = NULL;
    surf_noise(&c, 2.0 * sqrt(4.0 * acos(-1.0) / 20000.0), 5); /* 2 surface spacings */
    tessel_noise_estimate e;
    CHECK(tessel_cloud_noise(&c, 0, &e) == TESSEL_OK);
    tessel_smooth_recon_params p = tessel_smooth_recon_params_default();
    tessel_mesh measured, given, larger;
    tessel_smooth_recon_stats sm, sg, sl;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &measured, &sm) == TESSEL_OK);
    p.noise = e.sigma;
    p.noise_ratio = e.noise_ratio;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &given, &sg) == TESSEL_OK);
    CHECK_MSG(sm.noise == e.sigma && sg.noise == e.sigma && same_mesh(&measured, &given),
              "given noise: measured %g, given %g, the same mesh %d", sm.noise, sg.noise,
              same_mesh(&measured, &given));
    p.noise = 2.0 * e.sigma;
    p.noise_ratio = 2.0 * e.noise_ratio;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &larger, &sl) == TESSEL_OK);
    CHECK_MSG(sl.noise == 2.0 * e.sigma && sl.points_used < sm.points_used,
              "twice the noise: %zu points used against %zu", sl.points_used, sm.points_used);
    tessel_mesh m;
    p.noise = -1.0;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    p.noise = e.sigma;
    p.noise_ratio = NAN;
    CHECK(tessel_reconstruct_smooth(&c, &p, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_mesh_free(&measured);
    tessel_mesh_free(&given);
    tessel_mesh_free(&larger);
    tessel_cloud_free(&c);
}

/* A small sphere (radius 0.08, 5 spacings) 0.3 from a unit sphere is an
 * object of its own: after the front it holds 100 of 21,826 triangles, a
 * stray piece to the repair, whose extra attempts around it must leave the
 * two apart and closed. */
static void test_pipeline_small_object(void)
{
    tessel_cloud big, small, c;
    CHECK(surf_sphere(&big, 0.015, 31) == TESSEL_OK);
    CHECK(surf_sphere(&small, 0.25, 32) == TESSEL_OK);
    CHECK(tessel_cloud_alloc(&c, big.count + small.count, 0, 0) == TESSEL_OK);
    memcpy(c.xyz, big.xyz, 3 * big.count * sizeof *c.xyz);
    for (size_t i = 0; i < small.count; i++)
        for (int k = 0; k < 3; k++)
            c.xyz[3 * (big.count + i) + (size_t)k] =
                0.08f * small.xyz[3 * i + (size_t)k] + (k == 0 ? 1.38f : 0.0f);
    tessel_smooth_recon_stats s;
    tessel_mesh m = run_pipeline(&c, 0.002, 33, &s);
    tessel_mesh_report r = check(&m);
    size_t small_tris = 0;
    for (size_t t = 0; t < m.triangle_count; t++)
        small_tris += m.xyz[3 * (size_t)m.triangles[3 * t]] > 1.2f;
    CHECK_MSG(tessel_mesh_report_valid(&r) && r.self_intersections == 0 &&
                  r.boundary_edges == 0 && r.components == 2 && small_tris > 0,
              "sphere and small sphere: %zu components, %zu boundary edges, %zu of %zu "
              "triangles on the small one",
              r.components, r.boundary_edges, small_tris, m.triangle_count);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
    tessel_cloud_free(&big);
    tessel_cloud_free(&small);
}

/* tsl_flip_diagonals, the flips greedy uses: a flat square split along
 * its longer diagonal turns to the other, and stays so; a flip that would
 * meet another triangle is refused; invalid inputs are refused. */
static void test_flip_diagonals(void)
{
    /* Rhombus 0 (0,0) 1 (2,0) 2 (3,1) 3 (1,1) split along 0-2 (angles at
     * 1 and 3 are 135 degrees: not Delaunay). Plus a far point 4 that no
     * triangle uses. */
    const float xyz[] = {0, 0, 0, 2, 0, 0, 3, 1, 0, 1, 1, 0, 100, 100, 100};
    uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
    size_t flips = 0;
    CHECK(tsl_flip_diagonals(xyz, 5, tri, 2, NULL, 1, &flips) == TESSEL_OK);
    CHECK(flips == 1);
    bool has13[2] = {false, false};
    for (int t = 0; t < 2; t++)
        for (int i = 0; i < 3; i++) {
            uint32_t a = tri[3 * t + i], b = tri[3 * t + (i + 1) % 3];
            has13[t] |= (a == 1 && b == 3) || (a == 3 && b == 1);
        }
    CHECK(has13[0] && has13[1]);
    /* Flipping again changes nothing: the pair is Delaunay now. */
    CHECK(tsl_flip_diagonals(xyz, 5, tri, 2, NULL, 1, &flips) == TESSEL_OK && flips == 0);
    /* The same rhombus with its points stored in another order (the flips
     * number the vertices afresh inside and must give the ids back). */
    const float shuffled[] = {100, 100, 100, 1, 1, 0, 3, 1, 0, 0, 0, 0, 2, 0, 0};
    uint32_t st[6] = {3, 4, 2, 3, 2, 1}; /* 0 -> 3, 1 -> 4, 2 -> 2, 3 -> 1 */
    CHECK(tsl_flip_diagonals(shuffled, 5, st, 2, NULL, 1, &flips) == TESSEL_OK && flips == 1);
    for (int t = 0; t < 2; t++) {
        bool has41 = false;
        for (int i = 0; i < 3; i++) {
            uint32_t a = st[3 * t + i], b = st[3 * t + (i + 1) % 3];
            has41 |= (a == 4 && b == 1) || (a == 1 && b == 4);
            CHECK(a == 1 || a == 2 || a == 3 || a == 4);
        }
        CHECK(has41);
    }
    /* Lifted at 3, the pair bounds a thin tetrahedron whose other two faces
     * the flip would make; a triangle rising from inside it (touching
     * neither old triangle) forbids the flip, which happens without it. */
    const float lifted[] = {0, 0, 0, 2, 0, 0, 3, 1, 0, 1, 1, 0.3f,
                            1.5f, 0.5f, 0.075f, 1.5f, 0.5f, 5, 1.6f, 0.6f, 5};
    uint32_t lt[9] = {0, 1, 2, 0, 2, 3, 4, 5, 6};
    CHECK(tsl_flip_diagonals(lifted, 7, lt, 3, NULL, 1, &flips) == TESSEL_OK && flips == 0);
    CHECK(memcmp(lt, (uint32_t[]){0, 1, 2, 0, 2, 3, 4, 5, 6}, sizeof lt) == 0);
    /* A fixed triangle keeps its edges, and still forbids a flip it would
     * meet. */
    uint32_t ft[9] = {0, 1, 2, 0, 2, 3, 4, 5, 6};
    CHECK(tsl_flip_diagonals(lifted, 7, ft, 3, (const uint8_t[]){0, 0, 1}, 1, &flips) ==
              TESSEL_OK &&
          flips == 0);
    CHECK(tsl_flip_diagonals(lifted, 7, ft, 2, (const uint8_t[]){0, 1}, 1, &flips) == TESSEL_OK &&
          flips == 0);
    CHECK(tsl_flip_diagonals(lifted, 7, lt, 2, NULL, 1, &flips) == TESSEL_OK && flips == 1);
    /* Two fans at vertex 0 (a bow tie), an edge in three triangles, an edge
     * run twice the same way, a bad index. */
    const float six[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1, 0, 0, 0, 1};
    uint32_t bowtie[6] = {0, 1, 2, 0, 3, 4};
    uint32_t three[9] = {0, 1, 2, 1, 0, 3, 1, 0, 4};
    uint32_t same_way[6] = {0, 1, 2, 0, 1, 3};
    uint32_t bad[3] = {0, 1, 6};
    CHECK(tsl_flip_diagonals(six, 6, bowtie, 2, NULL, 1, &flips) == TESSEL_ERR_INVALID_ARG);
    CHECK(memcmp(bowtie, (uint32_t[]){0, 1, 2, 0, 3, 4}, sizeof bowtie) == 0);
    CHECK(tsl_flip_diagonals(six, 6, three, 3, NULL, 1, &flips) == TESSEL_ERR_INVALID_ARG);
    CHECK(tsl_flip_diagonals(six, 6, same_way, 2, NULL, 1, &flips) == TESSEL_ERR_INVALID_ARG);
    CHECK(tsl_flip_diagonals(six, 6, bad, 1, NULL, 1, &flips) == TESSEL_ERR_INVALID_ARG);
}

/* Flips tri (nt triangles over xyz) on one thread, and a copy on two: both
 * must give the same bits. Returns the flips, 0 on a failure. */
static size_t flips_one_and_two(const float *xyz, size_t nv, uint32_t *tri, size_t nt)
{
    uint32_t *two = malloc(3 * nt * sizeof *two);
    CHECK(two != NULL);
    if (!two)
        return 0;
    memcpy(two, tri, 3 * nt * sizeof *tri);
    size_t flips1 = 0, flips2 = 0;
    CHECK(tsl_flip_diagonals(xyz, nv, tri, nt, NULL, 1, &flips1) == TESSEL_OK);
    CHECK(tsl_flip_diagonals(xyz, nv, two, nt, NULL, 2, &flips2) == TESSEL_OK);
    CHECK_MSG(flips1 == flips2 && memcmp(tri, two, 3 * nt * sizeof *tri) == 0,
              "%zu and %zu flips", flips1, flips2);
    free(two);
    return flips1;
}

/* The flips of tsl_flip_diagonals run block by block in parallel: on a
 * jittered latitude-longitude sphere (many blocks) whose quads are split
 * either way at random, one and two threads flip the same diagonals, and
 * the result is a valid closed sphere. */
static void test_flip_blocks(void)
{
    enum { RINGS = 90, SEGS = 180 };
    size_t nv = (size_t)(RINGS - 1) * SEGS + 2, nt = 2 * (size_t)SEGS * (RINGS - 1);
    float *xyz = malloc(3 * nv * sizeof *xyz);
    uint32_t *tri = malloc(3 * nt * sizeof *tri);
    CHECK(xyz && tri);
    if (!xyz || !tri)
        goto done;
    surf_rng seed = surf_seed(7);
    const double pi = acos(-1.0), jitter = 0.3 * pi / RINGS;
    xyz[0] = 0, xyz[1] = 0, xyz[2] = 1;
    xyz[3 * (nv - 1)] = 0, xyz[3 * (nv - 1) + 1] = 0, xyz[3 * (nv - 1) + 2] = -1;
    for (int j = 1; j < RINGS; j++)
        for (int i = 0; i < SEGS; i++) {
            double th = pi * j / RINGS + jitter * (surf_uniform(&seed) - 0.5);
            double ph = 2 * pi * (i + 0.3 * (surf_uniform(&seed) - 0.5)) / SEGS;
            float *p = xyz + 3 * (1 + (size_t)(j - 1) * SEGS + (size_t)i);
            p[0] = (float)(sin(th) * cos(ph)), p[1] = (float)(sin(th) * sin(ph));
            p[2] = (float)cos(th);
        }
    size_t t = 0;
#define V(j, i) ((j) == 0 ? 0u : (j) == RINGS ? (uint32_t)nv - 1 : 1u + (uint32_t)(((j) - 1) * SEGS + (i) % SEGS))
    for (int j = 0; j < RINGS; j++)
        for (int i = 0; i < SEGS; i++) {
            uint32_t a = V(j, i), b = V(j, i + 1), c = V(j + 1, i + 1), d = V(j + 1, i);
            uint32_t q[2][3] = {{a, c, b}, {a, d, c}};
            if (surf_uniform(&seed) < 0.5) {
                uint32_t r2[2][3] = {{a, d, b}, {b, d, c}};
                memcpy(q, r2, sizeof q);
            }
            for (int k = 0; k < 2; k++) {
                if (q[k][0] == q[k][1] || q[k][1] == q[k][2] || q[k][0] == q[k][2])
                    continue; /* the caps' quads are triangles */
                memcpy(tri + 3 * t++, q[k], sizeof q[k]);
            }
        }
#undef V
    nt = t;
    tessel_mesh m;
    memset(&m, 0, sizeof m);
    m.xyz = xyz, m.vertex_count = nv, m.triangles = tri, m.triangle_count = nt;
    tessel_mesh_report r = check(&m);
    CHECK_MSG(valid_closed(&r, 0), "before: %zu boundary edges, %zu self-intersections",
              r.boundary_edges, r.self_intersections);
    size_t flips = flips_one_and_two(xyz, nv, tri, nt);
    CHECK_MSG(flips > 1000, "%zu flips", flips);
    r = check(&m);
    CHECK_MSG(valid_closed(&r, 0), "%zu boundary edges, %zu self-intersections",
              r.boundary_edges, r.self_intersections);
done:
    free(xyz);
    free(tri);
}

/* The same on an open, wavy sheet (border edges) with one column of
 * quads stretched twentyfold: their long triangles go to the serial tail,
 * and the flips near them must still agree for one and two threads, leave
 * the border as it was and make no crossing. */
static void test_flip_blocks_tail(void)
{
    enum { NX = 160, NY = 160 };
    size_t nv = (size_t)NX * NY, nt = 2 * (size_t)(NX - 1) * (NY - 1);
    float *xyz = malloc(3 * nv * sizeof *xyz);
    uint32_t *tri = malloc(3 * nt * sizeof *tri);
    CHECK(xyz && tri);
    if (!xyz || !tri)
        goto done;
    surf_rng seed = surf_seed(11);
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            /* Column 80 onwards starts 20 units later: quads 79 are long. */
            double x = i + 0.3 * (surf_uniform(&seed) - 0.5) + (i >= NX / 2 ? 19.0 : 0.0);
            double y = j + 0.3 * (surf_uniform(&seed) - 0.5);
            float *p = xyz + 3 * ((size_t)j * NX + (size_t)i);
            p[0] = (float)x, p[1] = (float)y, p[2] = (float)(0.5 * sin(0.1 * x) * cos(0.13 * y));
        }
    size_t t = 0;
    for (int j = 0; j + 1 < NY; j++)
        for (int i = 0; i + 1 < NX; i++) {
            uint32_t a = (uint32_t)(j * NX + i), b = a + 1, c = a + NX + 1, d = a + NX;
            const uint32_t one[6] = {a, b, c, a, c, d}, other[6] = {a, b, d, b, c, d};
            memcpy(tri + 3 * t, surf_uniform(&seed) < 0.5 ? one : other, sizeof one);
            t += 2;
        }
    tessel_mesh m;
    memset(&m, 0, sizeof m);
    m.xyz = xyz, m.vertex_count = nv, m.triangles = tri, m.triangle_count = nt;
    tessel_mesh_report before = check(&m);
    size_t flips = flips_one_and_two(xyz, nv, tri, nt);
    CHECK_MSG(flips > 1000, "%zu flips", flips);
    tessel_mesh_report r = check(&m);
    CHECK_MSG(tessel_mesh_report_valid(&before) && tessel_mesh_report_valid(&r) &&
                  r.self_intersections == 0 && r.boundary_edges == before.boundary_edges &&
                  r.components == 1,
              "%zu boundary edges (%zu before), %zu self-intersections, %zu components",
              r.boundary_edges, before.boundary_edges, r.self_intersections, r.components);
done:
    free(xyz);
    free(tri);
}

int main(void)
{
    test_flip_diagonals();
    test_flip_blocks();
    test_flip_blocks_tail();
    test_refine_sphere();
    test_refine_rounds();
    test_refine_split_blocks();
    test_refine_plane();
    test_refine_invalid();
    test_refine_pinched();
    test_refine_large_triangle();
    test_pipeline_sphere();
    test_pipeline_torus();
    test_pipeline_narrow_torus();
    test_pipeline_open();
    test_pipeline_sheets();
    test_pipeline_touching_spheres();
    test_stray_pieces();
    test_pipeline_thin_torus();
    test_pipeline_dense_noise();
    test_pipeline_given_noise();
    test_pipeline_small_object();
    test_pipeline_far_point();
    test_pipeline_threads_and_cancel();
    return TEST_SUMMARY();
}
