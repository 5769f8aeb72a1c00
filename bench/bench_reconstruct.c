/* tessel_reconstruct on a cloud file, timed around the library call alone:
 * the C side of bench_python.py, which times tessel.reconstruct from Python
 * on the same points (docs/python.md, "Overhead").
 *
 * usage: bench_reconstruct CLOUD [RUNS] [auto|greedy|smooth]
 * Reads CLOUD once, then runs tessel_reconstruct RUNS times (default 3)
 * with default parameters and the method given (default auto), and prints
 * one JSON object: the wall seconds of each call, the library's own timing
 * of each (summary.seconds), the median and minimum of the first, the
 * triangles. */
#include "bench_data.h"

#include <tessel.h>

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc > 4) {
        fprintf(stderr, "usage: bench_reconstruct CLOUD [RUNS] [auto|greedy|smooth]\n");
        return 1;
    }
    int runs = argc > 2 ? atoi(argv[2]) : 3;
    if (runs < 1 || runs > 100) {
        fprintf(stderr, "bench_reconstruct: RUNS must be 1..100\n");
        return 1;
    }
    tessel_reconstruct_params p = tessel_reconstruct_params_default();
    if (argc > 3) {
        if (strcmp(argv[3], "greedy") == 0)
            p.method = TESSEL_METHOD_GREEDY;
        else if (strcmp(argv[3], "smooth") == 0)
            p.method = TESSEL_METHOD_SMOOTH;
        else if (strcmp(argv[3], "auto") != 0) {
            fprintf(stderr, "bench_reconstruct: method must be auto, greedy or smooth\n");
            return 1;
        }
    }
    tessel_cloud cloud;
    tessel_diag diag;
    tessel_status st = tessel_cloud_read(&cloud, argv[1], NULL, &diag);
    if (st != TESSEL_OK) {
        fprintf(stderr, "bench_reconstruct: %s: %s\n", argv[1],
                diag.message[0] ? diag.message : tessel_status_str(st));
        return 1;
    }
    double seconds[100], inside[100];
    size_t triangles = 0;
    for (int r = 0; r < runs && st == TESSEL_OK; r++) {
        tessel_mesh mesh;
        tessel_reconstruct_summary summary;
        double t0 = bench_now();
        st = tessel_reconstruct(&cloud, &p, NULL, &mesh, &summary);
        seconds[r] = bench_now() - t0;
        inside[r] = summary.seconds;
        triangles = mesh.triangle_count;
        tessel_mesh_free(&mesh);
    }
    size_t n = cloud.count;
    tessel_cloud_free(&cloud);
    if (st != TESSEL_OK) {
        fprintf(stderr, "bench_reconstruct: %s\n", tessel_status_str(st));
        return 1;
    }
    printf("{\"points\": %zu, \"triangles\": %zu, \"seconds\": [", n, triangles);
    for (int r = 0; r < runs; r++)
        printf("%s%.6f", r ? ", " : "", seconds[r]);
    printf("], \"library_seconds\": [");
    for (int r = 0; r < runs; r++)
        printf("%s%.6f", r ? ", " : "", inside[r]);
    qsort(seconds, (size_t)runs, sizeof *seconds, cmp_double);
    printf("], \"median_seconds\": %.6f, \"min_seconds\": %.6f}\n", seconds[runs / 2],
           seconds[0]);
    return 0;
}
