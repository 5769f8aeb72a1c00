// The whole noisy-cloud pipeline, tessel_reconstruct_smooth, next to its
// peers on the same noisy scans in the same run:
//  - CGAL: jet_smooth_point_set (k = 24), hierarchy_simplify_point_set
//    (size 10, maximum variation 0.33), then
//    Advancing_front_surface_reconstruction (defaults) of the simplified
//    points - the CGAL emulation of Mederos et al. 2003 that the issue
//    quotes;
//  - Open3D: screened Poisson at depth 9 (bench_pipeline_open3d.py, run with
//    the system's python3 when it can import open3d), normals estimated
//    from 30 neighbours and oriented by Open3D's tangent-plane method.
// Every mesh is measured with tessel_mesh_check against NAME.gt.ply, with
// meshcheck's definitions (docs/check.md): F-score at 1% of the reference's
// diagonal, Chamfer distance (in % of that diagonal), boundary edges,
// non-manifold edges and vertices, self-intersecting pairs, orientation
// conflicts, components; and wall seconds. Built only with
// -DTESSEL_BENCH_PEERS=ON when CGAL, Eigen and a C++ compiler are found (see
// bench/CMakeLists.txt); the library does not need them.
//
// usage: bench_pipeline_cgal DIR [--open3d SCRIPT | --no-open3d] [--threads T]
//        [--out OUTDIR] [NAME...]   (reads DIR/NAME.pd.n05.ply and
//        DIR/NAME.gt.ply; names default to bunny elephant knot2)
#include "tessel.h"

#include <CGAL/Advancing_front_surface_reconstruction.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/hierarchy_simplify_point_set.h>
#include <CGAL/jet_smooth_point_set.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#endif

typedef CGAL::Exact_predicates_inexact_constructions_kernel K;
typedef K::Point_3 Point;
typedef std::array<std::size_t, 3> Facet;

#ifndef TESSEL_OPEN3D_SCRIPT
#define TESSEL_OPEN3D_SCRIPT "bench_pipeline_open3d.py"
#endif

static double seconds_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// One row of the table: method, time and quality against the reference.
static void row(const char *name, const char *method, double secs, const char *stages,
                const tessel_mesh *m, const tessel_mesh *ref, int threads)
{
    tessel_check_params cp = tessel_check_params_default();
    cp.reference = ref;
    cp.threads = threads;
    tessel_mesh_report r;
    if (tessel_mesh_check(m, &cp, &r) != TESSEL_OK) {
        std::printf("| %s | %s | %.3f | check failed |\n", name, method, secs);
        return;
    }
    std::printf("| %s | %s | %.3f | %s | %zu | %.3f | %.4f | %zu (%.3f%%) | %zu/%zu | %zu | %zu "
                "| %zu |\n",
                name, method, secs, stages, r.triangles, r.fscore,
                100.0 * r.chamfer / r.reference_bbox_diagonal, r.boundary_edges,
                r.edges ? 100.0 * double(r.boundary_edges) / double(r.edges) : 0.0,
                r.nonmanifold_edges, r.nonmanifold_vertices, r.self_intersections,
                r.orientation_conflicts, r.components);
}

// Open3D's Poisson through the script: writes out_path, returns its time in
// seconds (as the script measures it, reading excluded), or -1.
static double run_open3d(const std::string &script, const std::string &in,
                         const std::string &out_path, int threads)
{
    std::string cmd = "OMP_NUM_THREADS=" + std::to_string(threads > 0 ? threads : 2) +
                      " /usr/bin/python3 '" + script + "' '" + in + "' '" + out_path +
                      "' 2>/dev/null";
    FILE *p = popen(cmd.c_str(), "r");
    if (!p)
        return -1.0;
    double secs = -1.0;
    if (std::fscanf(p, "%lf", &secs) != 1)
        secs = -1.0;
    if (pclose(p) != 0)
        return -1.0;
    return secs;
}

static bool open3d_available()
{
    return std::system("/usr/bin/python3 -c 'import open3d' >/dev/null 2>&1") == 0;
}

int main(int argc, char **argv)
{
    std::string dir, script = TESSEL_OPEN3D_SCRIPT, out;
    bool use_open3d = true;
    int threads = 0;
    std::vector<std::string> names;
    for (int i = 1; i < argc; i++) {
        std::string a = argv[i];
        if (a == "--open3d" && i + 1 < argc)
            script = argv[++i];
        else if (a == "--no-open3d")
            use_open3d = false;
        else if (a == "--threads" && i + 1 < argc)
            threads = std::atoi(argv[++i]);
        else if (a == "--out" && i + 1 < argc)
            out = argv[++i];
        else if (dir.empty())
            dir = a;
        else
            names.push_back(a);
    }
    if (dir.empty()) {
        std::fprintf(stderr, "usage: bench_pipeline_cgal DIR [--open3d SCRIPT | --no-open3d] "
                             "[--threads T] [--out OUTDIR] [NAME...]\n");
        return 1;
    }
    if (names.empty())
        names = {"bunny", "elephant", "knot2"};
    if (use_open3d && !open3d_available()) {
        std::printf("(python3 cannot import open3d: Open3D rows skipped)\n");
        use_open3d = false;
    }
#ifdef CGAL_LINKED_WITH_TBB
    const char *concurrency = "CGAL parallel (TBB)";
    std::unique_ptr<tbb::global_control> limit;
    if (threads > 0)
        limit.reset(new tbb::global_control(tbb::global_control::max_allowed_parallelism,
                                            std::size_t(threads)));
#else
    const char *concurrency = "CGAL sequential (no TBB)";
#endif
    std::printf("# tessel %s vs CGAL %s (%s)%s\n\n", tessel_version(), CGAL_VERSION_STR,
                concurrency, use_open3d ? " and Open3D (python3)" : "");
    std::printf("Wall seconds of the whole reconstruction (reading excluded); quality "
                "against NAME.gt.ply with meshcheck's definitions: F-score at 1%% of its "
                "diagonal, Chamfer in %% of it.\n\n");
    std::printf("| data | method | seconds | stages (s) | triangles | F | Chamfer %% | "
                "boundary edges | non-manifold e/v | self-int. | orient. conflicts | "
                "components |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const std::string &name : names) {
        std::string in = dir + "/" + name + ".pd.n05.ply";
        std::string gt = dir + "/" + name + ".gt.ply";
        tessel_cloud cloud;
        tessel_mesh ref;
        if (tessel_cloud_read(&cloud, in.c_str(), nullptr, nullptr) != TESSEL_OK) {
            std::printf("| %s | cannot read %s |\n", name.c_str(), in.c_str());
            continue;
        }
        if (tessel_mesh_read(&ref, gt.c_str(), nullptr, nullptr) != TESSEL_OK) {
            std::printf("| %s | cannot read %s |\n", name.c_str(), gt.c_str());
            tessel_cloud_free(&cloud);
            continue;
        }

        // tessel, defaults.
        {
            tessel_smooth_recon_params p = tessel_smooth_recon_params_default();
            p.threads = threads;
            tessel_smooth_recon_stats s;
            tessel_mesh m;
            auto t0 = std::chrono::steady_clock::now();
            tessel_status st = tessel_reconstruct_smooth(&cloud, &p, nullptr, &m, &s);
            double secs = seconds_since(t0);
            if (st != TESSEL_OK) {
                std::printf("| %s | tessel | failed: %s |\n", name.c_str(),
                            tessel_status_str(st));
            } else {
                char stages[160];
                std::snprintf(stages, sizeof stages,
                              "smooth %.3f, cluster %.3f, front %.3f, refine %.3f",
                              s.seconds_spacing + s.seconds_smooth, s.seconds_simplify,
                              s.seconds_front, s.seconds_refine);
                row(name.c_str(), "tessel smooth", secs, stages, &m, &ref, threads);
                if (!out.empty())
                    tessel_mesh_write(&m, (out + "/" + name + ".tessel.ply").c_str(), nullptr,
                                      nullptr);
                tessel_mesh_free(&m);
            }
        }

        // CGAL: jet smoothing, hierarchy simplification, advancing front.
        {
            std::vector<Point> pts;
            pts.reserve(cloud.count);
            for (size_t i = 0; i < cloud.count; i++)
                pts.emplace_back(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
            auto t0 = std::chrono::steady_clock::now();
            CGAL::jet_smooth_point_set<CGAL::Parallel_if_available_tag>(pts, 24);
            double tj = seconds_since(t0);
            auto t1 = std::chrono::steady_clock::now();
            auto keep_end = CGAL::hierarchy_simplify_point_set(
                pts, CGAL::parameters::size(10).maximum_variation(0.33));
            pts.erase(keep_end, pts.end());
            double th = seconds_since(t1);
            auto t2 = std::chrono::steady_clock::now();
            std::vector<Facet> facets;
            CGAL::advancing_front_surface_reconstruction(pts.begin(), pts.end(),
                                                         std::back_inserter(facets));
            double ta = seconds_since(t2);
            double secs = seconds_since(t0);
            tessel_mesh m;
            if (tessel_mesh_alloc(&m, pts.size(), facets.size(), 0, 0) != TESSEL_OK)
                return 1;
            for (size_t i = 0; i < pts.size(); i++)
                for (int k = 0; k < 3; k++)
                    m.xyz[3 * i + size_t(k)] = float(pts[i][k]);
            for (size_t t = 0; t < facets.size(); t++)
                for (int k = 0; k < 3; k++)
                    m.triangles[3 * t + size_t(k)] = uint32_t(facets[t][size_t(k)]);
            for (int k = 0; k < 3; k++)
                m.offset[k] = cloud.offset[k];
            char stages[160];
            std::snprintf(stages, sizeof stages, "jet %.3f, hierarchy %.3f, AFSR %.3f", tj, th,
                          ta);
            row(name.c_str(), "CGAL jet+hierarchy+AFSR", secs, stages, &m, &ref, threads);
            if (!out.empty())
                tessel_mesh_write(&m, (out + "/" + name + ".cgal.ply").c_str(), nullptr,
                                  nullptr);
            tessel_mesh_free(&m);
        }

        // Open3D Poisson, depth 9.
        if (use_open3d) {
            std::string tmp = (out.empty() ? std::string("/tmp") : out) + "/" + name +
                              ".open3d." + std::to_string(long(getpid())) + ".ply";
            double secs = run_open3d(script, in, tmp, threads);
            tessel_mesh m;
            if (secs < 0 || tessel_mesh_read(&m, tmp.c_str(), nullptr, nullptr) != TESSEL_OK) {
                std::printf("| %s | Open3D Poisson depth 9 | failed |\n", name.c_str());
            } else {
                row(name.c_str(), "Open3D Poisson depth 9", secs, "normals + Poisson", &m,
                    &ref, threads);
                tessel_mesh_free(&m);
            }
            if (out.empty())
                std::remove(tmp.c_str());
        }
        tessel_mesh_free(&ref);
        tessel_cloud_free(&cloud);
    }
    return 0;
}
