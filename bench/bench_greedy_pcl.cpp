// tessel's greedy projection (tessel_reconstruct_greedy) next to PCL's
// GreedyProjectionTriangulation on the same inputs, in the same run: the
// jittered Fibonacci sphere of bench_greedy (tests/surfaces.h) at the given
// sizes, or the given files. Built only when PCL is found (optional target
// in bench/CMakeLists.txt); the project itself does not need PCL.
//
// PCL is set up as the issue specifies: normals from the 20 nearest
// neighbours (NormalEstimation, kd-tree), search radius 5 times the mean
// spacing, mu 2.5, and PCL's documented example values for the rest
// (100 nearest neighbours, maximum surface angle 45 degrees, angles 10 and
// 120 degrees, no normal consistency). PCL runs on one core (GP3 has no
// threads), tessel with its defaults (every core); triangles are counted,
// not written. Prints the time of each, PCL with and without its
// normal estimation, and the ratio (PCL total / tessel), by the wall clock
// and by the process CPU time.
//
//   bench_greedy_pcl [--sizes 1e4,1e5] [FILE...]
#include "tessel.h"
#include "bench_data.h"
#include "../tests/surfaces.h"

#include <pcl/common/io.h>
#include <pcl/features/normal_3d.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/surface/gp3.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

static tessel_status count_sink(void *user, const uint32_t *, size_t n)
{
    *static_cast<size_t *>(user) += n;
    return TESSEL_OK;
}

static int compare(const tessel_cloud *cloud, const char *what)
{
    // tessel
    size_t tris = 0;
    tessel_triangle_sink sink = {count_sink, &tris};
    tessel_recon_summary sum;
    tessel_greedy_params p = tessel_greedy_params_default();
    double t0 = bench_now(), c0 = bench_cpu_now();
    tessel_status s = tessel_reconstruct_greedy(cloud, &p, nullptr, &sink, &sum);
    double t_tessel = bench_now() - t0, c_tessel = bench_cpu_now() - c0;
    if (s != TESSEL_OK) {
        std::fprintf(stderr, "bench_greedy_pcl: %s: %s\n", what, tessel_status_str(s));
        return 1;
    }
    // PCL: normals, then GP3
    pcl::PointCloud<pcl::PointXYZ>::Ptr xyz(new pcl::PointCloud<pcl::PointXYZ>);
    xyz->resize(cloud->count);
    for (size_t i = 0; i < cloud->count; i++)
        (*xyz)[i] = pcl::PointXYZ(cloud->xyz[3 * i], cloud->xyz[3 * i + 1], cloud->xyz[3 * i + 2]);
    double t1 = bench_now(), c1 = bench_cpu_now();
    pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
    pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
    pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
    tree->setInputCloud(xyz);
    ne.setInputCloud(xyz);
    ne.setSearchMethod(tree);
    ne.setKSearch(20);
    ne.compute(*normals);
    pcl::PointCloud<pcl::PointNormal>::Ptr pn(new pcl::PointCloud<pcl::PointNormal>);
    pcl::concatenateFields(*xyz, *normals, *pn);
    double t2 = bench_now();
    pcl::search::KdTree<pcl::PointNormal>::Ptr tree2(new pcl::search::KdTree<pcl::PointNormal>);
    tree2->setInputCloud(pn);
    pcl::GreedyProjectionTriangulation<pcl::PointNormal> gp3;
    pcl::PolygonMesh mesh;
    gp3.setSearchRadius(5.0 * sum.spacing);
    gp3.setMu(2.5);
    gp3.setMaximumNearestNeighbors(100);
    gp3.setMaximumSurfaceAngle(M_PI / 4);
    gp3.setMinimumAngle(M_PI / 18);
    gp3.setMaximumAngle(2 * M_PI / 3);
    gp3.setNormalConsistency(false);
    gp3.setInputCloud(pn);
    gp3.setSearchMethod(tree2);
    gp3.reconstruct(mesh);
    double t3 = bench_now(), c_pcl = bench_cpu_now() - c1;
    double t_pcl = t3 - t1;
    std::printf("%-20s %9zu pts  tessel %8.3f s %9zu tris  |  PCL %8.3f s (normals %.3f, gp3 "
                "%.3f) %9zu tris  |  PCL / tessel %6.1fx (gp3 alone %.1fx)  |  CPU: tessel "
                "%.3f s, PCL %.3f s, %.1fx\n",
                what, cloud->count, t_tessel, tris, t_pcl, t2 - t1, t3 - t2,
                mesh.polygons.size(), t_pcl / t_tessel, (t3 - t2) / t_tessel, c_tessel, c_pcl,
                c_pcl / c_tessel);
    std::fflush(stdout);
    return 0;
}

int main(int argc, char **argv)
{
    std::string sizes = "1e4,1e5";
    int rc = 0, files = 0;
    for (int i = 1; i < argc; i++) {
        if (std::strcmp(argv[i], "--sizes") == 0 && i + 1 < argc) {
            sizes = argv[++i];
        } else if (argv[i][0] == '-') {
            std::fprintf(stderr, "usage: bench_greedy_pcl [--sizes 1e4,1e5] [FILE...]\n");
            return 2;
        } else {
            files++;
            tessel_cloud c;
            tessel_diag d;
            if (tessel_cloud_read(&c, argv[i], nullptr, &d) != TESSEL_OK) {
                std::fprintf(stderr, "bench_greedy_pcl: %s: %s\n", argv[i], d.message);
                return 1;
            }
            const char *base = std::strrchr(argv[i], '/');
            rc |= compare(&c, base ? base + 1 : argv[i]);
            tessel_cloud_free(&c);
        }
    }
    if (files)
        return rc;
    const char *sz = sizes.c_str();
    while (*sz) {
        char *end;
        double n = std::strtod(sz, &end);
        if (end == sz || !(n >= 100)) {
            std::fprintf(stderr, "bench_greedy_pcl: bad size list '%s'\n", sizes.c_str());
            return 2;
        }
        tessel_cloud c;
        if (surf_sphere_fibonacci(&c, (size_t)n, 0.2, 1) != TESSEL_OK)
            return 1;
        std::free(c.normals);
        c.normals = nullptr;
        char what[64];
        std::snprintf(what, sizeof what, "sphere %.0e", n);
        rc |= compare(&c, what);
        tessel_cloud_free(&c);
        sz = *end == ',' ? end + 1 : end;
    }
    return rc;
}
