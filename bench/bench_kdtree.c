/* Neighbour search benchmark: build time, k-nearest queries per second for
 * k = 8, 16, 32 (one thread and all threads) and radius queries per second,
 * on fixed-seed torus samples of 10^4..10^7 points (bench_data.h) and on
 * any binary PLY given on the command line. Each figure is the median of
 * three runs. bench/bench_nanoflann.cpp measures nanoflann on the same
 * data; bench/run_neighbours.sh runs both and prints the comparison.
 *
 * Usage: bench_kdtree [--max-n N | --n N] [--queries Q] [FILE.ply...]
 * Sizes 10^4, 10^5, ... up to N (10^7), or only N with --n. Queries are the
 * first min(n, Q) points of the cloud (Q = 10^6 default), in the cloud's
 * order (random for the torus, scan order for the files).
 * Prints a table, and one "RESULT" line per data set for the script. */
#include "tessel.h"

#include "bench_data.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#define RADIUS_CAP 64

typedef struct figures {
    double build;     /* wall seconds, all threads */
    double build_1t;  /* CPU seconds, one thread */
    double knn[3][2]; /* [k = 8, 16, 32][1 thread, all] queries/s */
    double radius[2];
    double checksum;  /* sum of the k = 16 distances, to compare runs */
} figures;

static const size_t ks[3] = {8, 16, 32};

static double time_knn(const tessel_index *ix, const float *q, size_t nq, size_t k,
                       int threads, uint32_t *idx, float *d2, int reps)
{
    double t0 = bench_clock(threads == 1);
    for (int r = 0; r < reps; r++) {
        tessel_status st = tessel_index_knn_batch(ix, q, nq, k, idx, d2, threads);
        if (st != TESSEL_OK) {
            fprintf(stderr, "bench: knn_batch: %s\n", tessel_status_str(st));
            exit(1);
        }
    }
    return (double)nq * reps / (bench_clock(threads == 1) - t0);
}

static double time_radius(const tessel_index *ix, const float *q, size_t nq, float r,
                          int threads, double *total, int reps)
{
    double t0 = bench_clock(threads == 1);
    double sum = 0.0;
    ptrdiff_t n = (ptrdiff_t)nq * reps;
    (void)threads;
#ifdef _OPENMP
#pragma omp parallel num_threads(threads > 0 ? threads : omp_get_max_threads()) \
    reduction(+ : sum)
#endif
    {
        uint32_t idx[RADIUS_CAP];
        float d2[RADIUS_CAP];
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 256)
#endif
        for (ptrdiff_t i = 0; i < n; i++)
            sum += (double)tessel_index_radius(ix, q + 3 * ((size_t)i % nq), r, idx, d2,
                                               RADIUS_CAP);
    }
    *total = sum / reps;
    return (double)n / (bench_clock(threads == 1) - t0);
}

/* Builds reps times; seconds per build (CPU time when one_thread). */
static double time_build(const float *xyz, size_t n, int reps, int one_thread,
                         tessel_index **out)
{
#ifdef _OPENMP
    int saved = omp_get_max_threads();
    if (one_thread)
        omp_set_num_threads(1);
#endif
    tessel_index *ix = NULL;
    double t0 = bench_clock(one_thread);
    for (int rep = 0; rep < reps; rep++) {
        tessel_index_destroy(ix);
        tessel_status st = tessel_index_build(&ix, xyz, n);
        if (st != TESSEL_OK) {
            fprintf(stderr, "bench: build: %s\n", tessel_status_str(st));
            exit(1);
        }
    }
    double t = (bench_clock(one_thread) - t0) / reps;
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
    if (out)
        *out = ix;
    else
        tessel_index_destroy(ix);
    return t;
}

static int run(const char *name, const float *xyz, size_t n, size_t max_queries)
{
    size_t nq = n < max_queries ? n : max_queries;
    uint32_t *idx = malloc(nq * 32 * sizeof *idx);
    float *d2 = malloc(nq * 32 * sizeof *d2);
    if (!idx || !d2) {
        fprintf(stderr, "bench: out of memory\n");
        return 1;
    }
    float r = bench_radius16(xyz, n);
    int reps = bench_reps(n, nq);
    double build[3], build1[3], knn[3][2][3], rad[2][3], neighbours = 0.0;
    figures f = {0};
    for (int run_i = 0; run_i < 3; run_i++) {
        tessel_index *ix = NULL;
        build1[run_i] = time_build(xyz, n, reps, 1, NULL);
        build[run_i] = time_build(xyz, n, reps, 0, &ix);
        for (int ki = 0; ki < 3; ki++) {
            for (int ti = 0; ti < 2; ti++)
                knn[ki][ti][run_i] =
                    time_knn(ix, xyz, nq, ks[ki], ti == 0 ? 1 : 0, idx, d2, reps);
            if (ks[ki] == 16 && run_i == 0) {
                for (size_t i = 0; i < nq * 16; i++)
                    f.checksum += d2[i];
            }
        }
        for (int ti = 0; ti < 2; ti++)
            rad[ti][run_i] = time_radius(ix, xyz, nq, r, ti == 0 ? 1 : 0, &neighbours, reps);
        tessel_index_destroy(ix);
    }
    f.build = bench_median3(build[0], build[1], build[2]);
    f.build_1t = bench_median3(build1[0], build1[1], build1[2]);
    for (int ki = 0; ki < 3; ki++)
        for (int ti = 0; ti < 2; ti++)
            f.knn[ki][ti] = bench_median3(knn[ki][ti][0], knn[ki][ti][1], knn[ki][ti][2]);
    for (int ti = 0; ti < 2; ti++)
        f.radius[ti] = bench_median3(rad[ti][0], rad[ti][1], rad[ti][2]);

    printf("%-22s %10zu %8.3f %8.3f", name, n, f.build_1t, f.build);
    for (int ki = 0; ki < 3; ki++)
        printf(" %9.0f %9.0f", f.knn[ki][0], f.knn[ki][1]);
    printf(" %9.0f %9.0f  (r=%.4g, %.1f nbrs)\n", f.radius[0], f.radius[1], r,
           neighbours / (double)nq);
    printf("RESULT impl=tessel name=%s n=%zu queries=%zu build_1t=%.6f build=%.6f", name, n,
           nq, f.build_1t, f.build);
    for (int ki = 0; ki < 3; ki++)
        printf(" knn%zu_1t=%.0f knn%zu_mt=%.0f", ks[ki], f.knn[ki][0], ks[ki], f.knn[ki][1]);
    printf(" radius_1t=%.0f radius_mt=%.0f checksum16=%.9g\n", f.radius[0], f.radius[1],
           f.checksum);
    fflush(stdout);
    free(idx);
    free(d2);
    return 0;
}

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
    int threads = 1;
#ifdef _OPENMP
    threads = omp_get_max_threads();
#endif
    printf("tessel kd-tree, %d threads; queries/s for 1 thread and all threads\n", threads);
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
