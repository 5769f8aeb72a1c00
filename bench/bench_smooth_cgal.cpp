// tessel's robust smoothing and simplification next to CGAL's
// jet_smooth_point_set (k = 24) and hierarchy_simplify_point_set (size 10,
// maximum variation 0.33), on the same clouds in the same run: wall time and
// RMS distance to the true surface (CGAL AABB tree, exact point-triangle
// distance). Built only when CGAL, Eigen and a C++ compiler are found (see
// bench/CMakeLists.txt); the library does not need them.
//
// usage: bench_smooth_cgal DIR [NAME...]   (reads DIR/NAME.pd.n05.ply and
//        DIR/NAME.gt.ply; names default to bunny elephant knot2)
#include "tessel.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/hierarchy_simplify_point_set.h>
#include <CGAL/jet_smooth_point_set.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#endif

typedef CGAL::Simple_cartesian<double> K;
typedef K::Point_3 Point;
typedef K::Triangle_3 Triangle;
typedef std::vector<Triangle>::const_iterator TriIt;
typedef CGAL::AABB_triangle_primitive<K, TriIt> Primitive;
typedef CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>> Tree;

static double seconds_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

static double rms(const Tree &tree, const std::vector<Point> &pts)
{
    double s = 0;
    for (const Point &p : pts)
        s += CGAL::to_double(tree.squared_distance(p));
    return std::sqrt(s / double(pts.size()));
}

static std::vector<Point> points_of(const tessel_cloud &c)
{
    std::vector<Point> v;
    v.reserve(c.count);
    for (size_t i = 0; i < c.count; i++)
        v.emplace_back(c.xyz[3 * i] + c.offset[0], c.xyz[3 * i + 1] + c.offset[1],
                       c.xyz[3 * i + 2] + c.offset[2]);
    return v;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        std::fprintf(stderr, "usage: bench_smooth_cgal DIR [NAME...]\n");
        return 1;
    }
    std::vector<std::string> names;
    for (int i = 2; i < argc; i++)
        names.push_back(argv[i]);
    if (names.empty())
        names = {"bunny", "elephant", "knot2"};
#ifdef CGAL_LINKED_WITH_TBB
    const char *concurrency = "CGAL parallel (TBB)";
#else
    const char *concurrency = "CGAL sequential (no TBB)";
#endif
    std::printf("# tessel %s vs CGAL %s (%s)\n\n", tessel_version(), CGAL_VERSION_STR,
                concurrency);
    std::printf("RMS distance to the true surface in %% of its bounding-box diagonal; "
                "wall seconds.\n\n");
    std::printf(
        "| data | points | noisy RMS | tessel smooth RMS | time | CGAL jet k=24 RMS | time |"
        " tessel simplify: points | RMS | time | CGAL hierarchy: points | RMS | time |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const std::string &name : names) {
        std::string in = std::string(argv[1]) + "/" + name + ".pd.n05.ply";
        std::string gt = std::string(argv[1]) + "/" + name + ".gt.ply";
        tessel_cloud cloud;
        tessel_mesh mesh;
        if (tessel_cloud_read(&cloud, in.c_str(), nullptr, nullptr) != TESSEL_OK ||
            tessel_mesh_read(&mesh, gt.c_str(), nullptr, nullptr) != TESSEL_OK) {
            std::printf("| %s | cannot read %s or %s |\n", name.c_str(), in.c_str(),
                        gt.c_str());
            continue;
        }
        std::vector<Triangle> tris;
        for (size_t t = 0; t < mesh.triangle_count; t++) {
            Point v[3];
            for (int k = 0; k < 3; k++) {
                const float *p = mesh.xyz + 3 * size_t(mesh.triangles[3 * t + k]);
                v[k] =
                    Point(p[0] + mesh.offset[0], p[1] + mesh.offset[1], p[2] + mesh.offset[2]);
            }
            tris.emplace_back(v[0], v[1], v[2]);
        }
        Tree tree(tris.begin(), tris.end());
        tree.accelerate_distance_queries();
        double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
        for (const Triangle &t : tris)
            for (int k = 0; k < 3; k++)
                for (int a = 0; a < 3; a++) {
                    lo[a] = std::min(lo[a], t[k][a]);
                    hi[a] = std::max(hi[a], t[k][a]);
                }
        double diag =
            std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                      (hi[2] - lo[2]) * (hi[2] - lo[2]));
        double pct = 100.0 / diag;
        std::vector<Point> noisy = points_of(cloud);
        double r0 = rms(tree, noisy);

        // tessel: smoothing (defaults), then cluster + representatives.
        tessel_cloud smooth, reps;
        auto t0 = std::chrono::steady_clock::now();
        if (tessel_smooth(&cloud, &smooth, nullptr, nullptr, nullptr) != TESSEL_OK)
            return 1;
        double ts = seconds_since(t0);
        t0 = std::chrono::steady_clock::now();
        if (tessel_simplify(&smooth, &reps, nullptr, nullptr, nullptr) != TESSEL_OK)
            return 1;
        double tr = seconds_since(t0);
        double r1 = rms(tree, points_of(smooth)), r2 = rms(tree, points_of(reps));

        // CGAL: jet smoothing, then hierarchy simplification of its output.
        std::vector<Point> jet = noisy;
        t0 = std::chrono::steady_clock::now();
        CGAL::jet_smooth_point_set<CGAL::Parallel_if_available_tag>(jet, 24);
        double tj = seconds_since(t0);
        double r3 = rms(tree, jet);
        std::vector<Point> hier = jet;
        t0 = std::chrono::steady_clock::now();
        auto keep_end = CGAL::hierarchy_simplify_point_set(
            hier, CGAL::parameters::size(10).maximum_variation(0.33));
        hier.erase(keep_end, hier.end());
        double th = seconds_since(t0);
        double r4 = rms(tree, hier);

        std::printf(
            "| %s | %zu | %.4f | %.4f | %.3f | %.4f | %.3f | %zu | %.4f | %.3f | %zu | %.4f "
            "| %.3f |\n",
            name.c_str(), cloud.count, r0 * pct, r1 * pct, ts, r3 * pct, tj, reps.count,
            r2 * pct, tr, hier.size(), r4 * pct, th);
        tessel_cloud_free(&reps);
        tessel_cloud_free(&smooth);
        tessel_cloud_free(&cloud);
        tessel_mesh_free(&mesh);
    }
    return 0;
}
