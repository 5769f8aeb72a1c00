/* Binary PLY throughput through the public API: tessel_cloud_write then
 * tessel_cloud_read of a generated cloud (fixed-seed torus, bench_data.h),
 * once with local coordinates (float x y z, 12 bytes/point) and once moved
 * to UTM-like coordinates (double x y z, 24 bytes/point). Files go to a
 * folder given on the command line (default /tmp), so the figures include
 * the file system (page cache; no fsync). Prints the median of three runs
 * as MB/s and points/s, and the peak RSS of the process (getrusage).
 *
 * Usage: bench_io [N [FOLDER]]   (default N = 10^7) */
#include "tessel.h"

#include "bench_data.h"

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median3(double t[3])
{
    qsort(t, 3, sizeof t[0], cmp_double);
    return t[1];
}

static long peak_rss_mb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss / 1024; /* Linux: kilobytes */
}

static int run(const char *label, const tessel_cloud *cloud, const char *path)
{
    double tw[3], tr[3];
    size_t bytes = 0;
    for (int r = 0; r < 3; r++) {
        tessel_diag d;
        double t0 = bench_now();
        tessel_status st = tessel_cloud_write(cloud, path, NULL, &d);
        double t1 = bench_now();
        if (st != TESSEL_OK) {
            fprintf(stderr, "write %s: %s\n", path, d.message);
            return 1;
        }
        tessel_cloud back;
        st = tessel_cloud_read(&back, path, NULL, &d);
        double t2 = bench_now();
        if (st != TESSEL_OK) {
            fprintf(stderr, "read %s: %s\n", path, d.message);
            return 1;
        }
        if (back.count != cloud->count) {
            fprintf(stderr, "read back %zu points, wrote %zu\n", back.count, cloud->count);
            return 1;
        }
        tessel_cloud_free(&back);
        struct stat sb;
        stat(path, &sb);
        bytes = (size_t)sb.st_size;
        tw[r] = t1 - t0;
        tr[r] = t2 - t1;
    }
    double w = median3(tw), rd = median3(tr);
    double n = (double)cloud->count, mb = (double)bytes / 1e6;
    printf("%-28s %6.0f MB  write %7.1f MB/s %6.2f Mpts/s   read %7.1f MB/s %6.2f Mpts/s\n",
           label, mb, mb / w, n / w / 1e6, mb / rd, n / rd / 1e6);
    unlink(path);
    return 0;
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? (size_t)strtoull(argv[1], NULL, 10) : 10000000u;
    const char *dir = argc > 2 ? argv[2] : "/tmp";
    char path[1024];
    snprintf(path, sizeof path, "%s/bench_io_%ld.ply", dir, (long)getpid());

    tessel_cloud cloud;
    if (tessel_cloud_alloc(&cloud, 0, 0, 0) != TESSEL_OK)
        return 1;
    free(cloud.xyz);
    cloud.xyz = bench_torus(n, 42);
    if (!cloud.xyz)
        return 1;
    cloud.count = n;
    printf("bench_io: %zu points, binary little-endian PLY in %s, median of 3 runs\n", n, dir);
    int rc = run("float xyz (offset 0)", &cloud, path);
    /* UTM-like: a 200 m tile far from the origin, written as doubles. */
    for (size_t i = 0; i < 3 * n; i++)
        cloud.xyz[i] = 1.0f + 100.0f * (cloud.xyz[i] + 1.5f);
    cloud.offset[0] = 636999.0;
    cloud.offset[1] = 5119999.0;
    cloud.offset[2] = 299.0;
    rc |= run("double xyz (UTM offset)", &cloud, path);
    tessel_cloud_free(&cloud);
    printf("peak RSS %ld MB (%.1f bytes/point)\n", peak_rss_mb(),
           (double)peak_rss_mb() * 1048576.0 / (double)n);
    return rc;
}
