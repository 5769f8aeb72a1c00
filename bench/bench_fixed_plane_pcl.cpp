// tessel's grid mode next to PCL's OrganizedFastMesh on the same organized
// inputs, in the same run: the synthetic room scans of bench_fixed_plane
// (bench_fixed_plane_scene.h) and, optionally, organized PLY/PCD files.
// Built only when PCL is found (bench/CMakeLists.txt).
//
//   bench_fixed_plane_pcl [--sizes 1e6,1e7] [--file PATH ...]
//
// Both run on one thread. PCL returns a std::vector<pcl::Vertices>; tessel
// streams into a counting sink, which favours it slightly, so it also runs
// collecting into a vector. Wall clock and CPU time are both printed (they
// differ on a shared machine); ratios are PCL time / tessel time. OrganizedFastMesh uses TRIANGLE_ADAPTIVE_CUT
// with the scan's viewpoint for its shadow test, the closest to tessel's
// shorter diagonal and depth-jump test.
#include "tessel.h"
#include "bench_data.h"
#include "bench_fixed_plane_scene.h"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/surface/organized_fast_mesh.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

struct Timing {
    double wall, cpu;
};

struct Collect {
    std::vector<uint32_t> tris;
    size_t count = 0;
};

static tessel_status collect(void *user, const uint32_t *t, size_t n)
{
    Collect *c = static_cast<Collect *>(user);
    c->tris.insert(c->tris.end(), t, t + 3 * n);
    c->count += n;
    return TESSEL_OK;
}

static tessel_status count_only(void *user, const uint32_t *, size_t n)
{
    static_cast<Collect *>(user)->count += n;
    return TESSEL_OK;
}

// Best of a few runs (wall clock and CPU time each).
template <class F> static Timing best_time(size_t n, F f)
{
    int reps = n < 2000000 ? 5 : 2;
    Timing best = {std::numeric_limits<double>::infinity(),
                   std::numeric_limits<double>::infinity()};
    for (int k = 0; k < reps; k++) {
        double t0 = bench_now(), c0 = bench_cpu_now();
        f();
        double t = bench_now() - t0, c = bench_cpu_now() - c0;
        best.wall = t < best.wall ? t : best.wall;
        best.cpu = c < best.cpu ? c : best.cpu;
    }
    return best;
}

static int compare(const tessel_cloud &cloud, const char *what)
{
    const uint32_t W = cloud.width, H = cloud.height;
    const size_t cells = (size_t)W * H;
    // The same grid as a PCL organized cloud, NaN where no point.
    pcl::PointCloud<pcl::PointXYZ>::Ptr pc(new pcl::PointCloud<pcl::PointXYZ>);
    pc->width = W;
    pc->height = H;
    pc->is_dense = false;
    pc->points.resize(cells);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (size_t k = 0; k < cells; k++) {
        uint32_t i = cloud.grid[k];
        pcl::PointXYZ &p = pc->points[k];
        if (i == TESSEL_NONE) {
            p.x = p.y = p.z = nan;
        } else {
            p.x = cloud.xyz[3 * (size_t)i] + (float)cloud.offset[0];
            p.y = cloud.xyz[3 * (size_t)i + 1] + (float)cloud.offset[1];
            p.z = cloud.xyz[3 * (size_t)i + 2] + (float)cloud.offset[2];
        }
    }
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_GRID;
    p.threads = 1;
    Collect counted, kept;
    tessel_triangle_sink count_sink = {count_only, &counted};
    tessel_triangle_sink keep_sink = {collect, &kept};
    tessel_status st = TESSEL_OK;
    Timing t_count = best_time(cloud.count, [&] {
        counted.count = 0;
        st = tessel_reconstruct_fixed_plane(&cloud, &p, nullptr, &count_sink, nullptr);
    });
    if (st != TESSEL_OK) {
        std::fprintf(stderr, "tessel: %s\n", tessel_status_str(st));
        return 1;
    }
    kept.tris.reserve(6 * cells);
    Timing t_keep = best_time(cloud.count, [&] {
        kept.tris.clear();
        kept.count = 0;
        st = tessel_reconstruct_fixed_plane(&cloud, &p, nullptr, &keep_sink, nullptr);
    });

    pcl::OrganizedFastMesh<pcl::PointXYZ> ofm;
    ofm.setTrianglePixelSize(1);
    ofm.setTriangulationType(pcl::OrganizedFastMesh<pcl::PointXYZ>::TRIANGLE_ADAPTIVE_CUT);
    if (cloud.has_viewpoint)
        ofm.setViewpoint(Eigen::Vector3f((float)cloud.viewpoint[0], (float)cloud.viewpoint[1],
                                         (float)cloud.viewpoint[2]));
    ofm.setInputCloud(pc);
    std::vector<pcl::Vertices> polys;
    Timing t_pcl = best_time(cloud.count, [&] {
        polys.clear();
        ofm.reconstruct(polys);
    });

    double n = (double)cloud.count;
    std::printf("%-24s %10zu pts | tessel %9zu tris %6.2f M pts/s (cpu %6.2f; %6.2f into a "
                "vector) | PCL %9zu tris %6.2f M pts/s (cpu %6.2f) | ratio %.1fx (cpu %.1fx, "
                "vector %.1fx)\n",
                what, cloud.count, counted.count, n / t_count.wall / 1e6,
                n / t_count.cpu / 1e6, n / t_keep.cpu / 1e6, polys.size(),
                n / t_pcl.wall / 1e6, n / t_pcl.cpu / 1e6, t_pcl.wall / t_count.wall,
                t_pcl.cpu / t_count.cpu, t_pcl.cpu / t_keep.cpu);
    std::fflush(stdout);
    return 0;
}

int main(int argc, char **argv)
{
    std::string sizes = "1e6,1e7";
    std::vector<const char *> files;
    for (int i = 1; i < argc; i++) {
        if (!std::strcmp(argv[i], "--sizes") && i + 1 < argc)
            sizes = argv[++i];
        else if (!std::strcmp(argv[i], "--file") && i + 1 < argc)
            files.push_back(argv[++i]);
        else {
            std::fprintf(stderr, "usage: bench_fixed_plane_pcl [--sizes 1e6,1e7] [--file PATH]...\n");
            return 2;
        }
    }
    std::printf("tessel %s grid mode vs PCL OrganizedFastMesh (TRIANGLE_ADAPTIVE_CUT), 1 thread\n",
                tessel_version());
    int rc = 0;
    for (const char *path : files) {
        tessel_cloud cloud;
        tessel_diag diag;
        std::memset(&diag, 0, sizeof diag);
        if (tessel_cloud_read(&cloud, path, nullptr, &diag) != TESSEL_OK || !cloud.grid) {
            std::fprintf(stderr, "bench_fixed_plane_pcl: %s: %s\n", path,
                         diag.message[0] ? diag.message : "not an organized cloud");
            rc = 1;
            continue;
        }
        const char *base = std::strrchr(path, '/');
        rc |= compare(cloud, base ? base + 1 : path);
        tessel_cloud_free(&cloud);
    }
    for (size_t pos = 0; pos < sizes.size();) {
        size_t end = sizes.find(',', pos);
        double n = std::atof(sizes.substr(pos, end == std::string::npos ? end : end - pos).c_str());
        pos = end == std::string::npos ? sizes.size() : end + 1;
        if (!(n >= 16))
            continue;
        uint32_t cols = (uint32_t)std::sqrt(n / 2.5), rows = (uint32_t)(n / cols);
        tessel_cloud cloud;
        if (tessel_cloud_alloc(&cloud, (size_t)cols * rows, 0, 0) != TESSEL_OK)
            return 1;
        scene_room_scan(cols, rows, 0.005, 2, cloud.xyz);
        std::memcpy(cloud.viewpoint, scene_vp, sizeof cloud.viewpoint);
        cloud.has_viewpoint = 1;
        cloud.width = cols;
        cloud.height = rows;
        cloud.grid = static_cast<uint32_t *>(std::malloc(cloud.count * sizeof(uint32_t)));
        for (size_t i = 0; i < cloud.count; i++)
            cloud.grid[i] = (uint32_t)i;
        char what[64];
        std::snprintf(what, sizeof what, "room scan %ux%u", cols, rows);
        rc |= compare(cloud, what);
        tessel_cloud_free(&cloud);
    }
    return rc;
}
