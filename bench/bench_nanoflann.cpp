/* The neighbour benchmark of bench_kdtree.c, measured with nanoflann on the
 * same data (bench_data.h: same generator, seed, queries and radius), so
 * bench/run_neighbours.sh can print both side by side. nanoflann's own
 * defaults: leaf size 10, exact search; queries threaded with OpenMP the
 * same way (dynamic schedule, chunks of 256). Built only when nanoflann.hpp
 * and a C++ compiler are found. Same usage and output as bench_kdtree. */
#include <nanoflann.hpp>

#include <cstdint>
#include <utility>
#include <vector>

#include "bench_data.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace {

struct Cloud {
    const float *xyz;
    size_t n;
    size_t kdtree_get_point_count() const { return n; }
    float kdtree_get_pt(size_t i, size_t dim) const { return xyz[3 * i + dim]; }
    template <class BBOX> bool kdtree_get_bbox(BBOX &) const { return false; }
};

typedef nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>,
                                            Cloud, 3, uint32_t>
    Tree;

const size_t ks[3] = {8, 16, 32};

int max_threads()
{
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

double time_knn(const Tree &tree, const float *q, size_t nq, size_t k, int threads,
                uint32_t *idx, float *d2, int reps)
{
    double t0 = bench_clock(threads == 1);
    ptrdiff_t n = (ptrdiff_t)nq;
    for (int r = 0; r < reps; r++) {
    (void)threads;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
#endif
    for (ptrdiff_t i = 0; i < n; i++) {
        nanoflann::KNNResultSet<float, uint32_t> rs(k);
        rs.init(idx + (size_t)i * k, d2 + (size_t)i * k);
        tree.findNeighbors(rs, q + 3 * (size_t)i, nanoflann::SearchParams());
    }
    }
    return (double)nq * reps / (bench_clock(threads == 1) - t0);
}

double time_radius(const Tree &tree, const float *q, size_t nq, float r, int threads,
                   double *total, int reps)
{
    double t0 = bench_clock(threads == 1);
    double sum = 0.0;
    ptrdiff_t n = (ptrdiff_t)nq * reps;
    (void)threads;
#ifdef _OPENMP
#pragma omp parallel num_threads(threads) reduction(+ : sum)
#endif
    {
        std::vector<std::pair<uint32_t, float>> matches;
        matches.reserve(256);
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 256)
#endif
        for (ptrdiff_t i = 0; i < n; i++) {
            matches.clear();
            sum += (double)tree.radiusSearch(q + 3 * ((size_t)i % nq), r * r, matches,
                                             nanoflann::SearchParams());
        }
    }
    *total = sum / reps;
    return (double)n / (bench_clock(threads == 1) - t0);
}

int run(const char *name, const float *xyz, size_t n, size_t max_queries)
{
    size_t nq = n < max_queries ? n : max_queries;
    std::vector<uint32_t> idx(nq * 32);
    std::vector<float> d2(nq * 32);
    float r = bench_radius16(xyz, n);
    Cloud cloud = {xyz, n};
    double build[3], build1[3], knn[3][2][3], rad[2][3], neighbours = 0.0, checksum = 0.0;
    int reps = bench_reps(n, nq);
    for (int run_i = 0; run_i < 3; run_i++) {
        /* nanoflann 1.4 builds on one thread: CPU time and wall time. */
        double c0 = bench_cpu_now();
        for (int rep = 0; rep < reps; rep++)
            Tree discard(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
        build1[run_i] = (bench_cpu_now() - c0) / reps;
        double t0 = bench_now();
        for (int rep = 1; rep < reps; rep++)
            Tree discard(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
        Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
        build[run_i] = (bench_now() - t0) / reps;
        for (int ki = 0; ki < 3; ki++) {
            for (int ti = 0; ti < 2; ti++)
                knn[ki][ti][run_i] = time_knn(tree, xyz, nq, ks[ki],
                                              ti == 0 ? 1 : max_threads(), idx.data(),
                                              d2.data(), reps);
            if (ks[ki] == 16 && run_i == 0)
                for (size_t i = 0; i < nq * 16; i++)
                    checksum += d2[i];
        }
        for (int ti = 0; ti < 2; ti++)
            rad[ti][run_i] =
                time_radius(tree, xyz, nq, r, ti == 0 ? 1 : max_threads(), &neighbours, reps);
    }
    double b = bench_median3(build[0], build[1], build[2]);
    double b1 = bench_median3(build1[0], build1[1], build1[2]);
    double kq[3][2], rq[2];
    for (int ki = 0; ki < 3; ki++)
        for (int ti = 0; ti < 2; ti++)
            kq[ki][ti] = bench_median3(knn[ki][ti][0], knn[ki][ti][1], knn[ki][ti][2]);
    for (int ti = 0; ti < 2; ti++)
        rq[ti] = bench_median3(rad[ti][0], rad[ti][1], rad[ti][2]);

    printf("%-22s %10zu %8.3f %8.3f", name, n, b1, b);
    for (int ki = 0; ki < 3; ki++)
        printf(" %9.0f %9.0f", kq[ki][0], kq[ki][1]);
    printf(" %9.0f %9.0f  (r=%.4g, %.1f nbrs)\n", rq[0], rq[1], r, neighbours / (double)nq);
    printf("RESULT impl=nanoflann name=%s n=%zu queries=%zu build_1t=%.6f build=%.6f", name,
           n, nq, b1, b);
    for (int ki = 0; ki < 3; ki++)
        printf(" knn%zu_1t=%.0f knn%zu_mt=%.0f", ks[ki], kq[ki][0], ks[ki], kq[ki][1]);
    printf(" radius_1t=%.0f radius_mt=%.0f checksum16=%.9g\n", rq[0], rq[1], checksum);
    fflush(stdout);
    return 0;
}

} // namespace

int main(int argc, char **argv)
{
    size_t min_n = 10000, max_n = 10000000, max_queries = 1000000;
    int files = 0, status = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--max-n") && i + 1 < argc)
            max_n = (size_t)strtoull(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--n") && i + 1 < argc)
            min_n = max_n = (size_t)strtoull(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--queries") && i + 1 < argc)
            max_queries = (size_t)strtoull(argv[++i], NULL, 10);
        else if (argv[i][0] == '-') {
            fprintf(stderr, "usage: %s [--max-n N | --n N] [--queries Q] [FILE.ply...]\n",
                    argv[0]);
            return 2;
        }
    }
    printf("nanoflann %d.%d.%d, %d threads; queries/s for 1 thread and all threads\n",
           NANOFLANN_VERSION >> 8, (NANOFLANN_VERSION >> 4) & 15, NANOFLANN_VERSION & 15,
           max_threads());
    printf("%-22s %10s %8s %8s %9s %9s %9s %9s %9s %9s %9s %9s\n", "data", "points",
           "build 1t", "build",
           "k8 1t", "k8 mt", "k16 1t", "k16 mt", "k32 1t", "k32 mt", "rad 1t", "rad mt");
    for (int i = 1; i < argc; i++) {
        if (argv[i][0] == '-') {
            i++;
            continue;
        }
        files++;
        size_t n;
        float *xyz = bench_read_ply(argv[i], &n);
        if (!xyz)
            return 1;
        const char *base = strrchr(argv[i], '/');
        status |= run(base ? base + 1 : argv[i], xyz, n, max_queries);
        free(xyz);
    }
    if (files == 0) {
        for (size_t n = min_n; n <= max_n; n *= 10) {
            float *xyz = bench_torus(n, 42);
            if (!xyz)
                return 1;
            char name[32];
            snprintf(name, sizeof name, "torus-%zu", n);
            status |= run(name, xyz, n, max_queries);
            free(xyz);
        }
    }
    return status;
}
