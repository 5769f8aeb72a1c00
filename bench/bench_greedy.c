/* Greedy projection reconstruction benchmark (src/greedy/, Gopi & Krishnan
 * 2002). Synthetic input: n points of the jittered Fibonacci lattice on the
 * unit sphere (tests/surfaces.h), an even sampling of a closed surface,
 * from 10^4 to 10^7 points; or the given files. Each run is a child
 * process, so its peak memory is its own. Triangles stream into the mesh
 * writer and a PLY file (--write DIR; the default), as `tessel
 * reconstruct` does, or into a counting sink (--count). By default the
 * triangles are held for the orientation check and the diagonal flips
 * (src/greedy/held.c), as `tessel reconstruct` does; --stream sends them on
 * as they are final (`tessel reconstruct --stream`). The front runs on
 * one core; the orientation check and the flips use OpenMP's threads:
 * OMP_NUM_THREADS=1 keeps the whole run on one core.
 *
 * Prints for each input: triangles, boundary edges, components, points
 * left out, the reconstruction time (input already in memory) with points/s
 * by the wall clock and by the process's CPU time (the same on an idle
 * machine), the most triangles held at once, and the peak memory of the
 * process per point, in all and beyond the input cloud.
 *
 *   bench_greedy [--sizes 1e4,1e5,1e6,1e7] [--count | --write DIR]
 *                [--mu M] [--stream] [FILE...]
 *
 * Targets (issue 3): 1,000,000 points/s on one core; under 100 bytes per
 * point at 10^7 points when streaming to a file. PCL's
 * GreedyProjectionTriangulation on the same inputs is bench_greedy_pcl
 * (built with -DTESSEL_BENCH_PEERS=ON when PCL is installed); figures in
 * docs/greedy.md. */
#include "tessel.h"
#include "bench_data.h"
#include "../tests/surfaces.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

typedef struct counter {
    size_t triangles;
    uint64_t checksum;
} counter;

static tessel_status count_sink(void *user, const uint32_t *t, size_t n)
{
    counter *c = user;
    c->triangles += n;
    for (size_t i = 0; i < 3 * n; i += 97)
        c->checksum += t[i];
    return TESSEL_OK;
}

typedef struct options {
    const char *write_dir; /* NULL: count only */
    double mu;
    int stream;            /* no orientation check, no flips */
} options;

/* One reconstruction and one line of output. */
static int measure(const tessel_cloud *cloud, const options *o, const char *what)
{
    tessel_greedy_params p = tessel_greedy_params_default();
    if (o->mu > 0)
        p.mu = o->mu;
    p.orient_check = !o->stream;
    p.flip = !o->stream;
    size_t input = cloud->count * 12 + (cloud->normals ? cloud->count * 12 : 0);
    counter c = {0, 0};
    tessel_triangle_sink sink = {count_sink, &c};
    tessel_mesh_writer *w = NULL;
    char path[4096];
    if (o->write_dir) {
        snprintf(path, sizeof path, "%s/bench_greedy_%d.ply", o->write_dir, (int)getpid());
        tessel_diag d;
        if (tessel_mesh_writer_open(&w, path, cloud, NULL, 1, &d) != TESSEL_OK) {
            fprintf(stderr, "bench_greedy: %s: %s\n", path, d.message);
            return 1;
        }
        sink = tessel_mesh_writer_sink(w);
    }
    tessel_recon_summary sum;
    double t0 = bench_now(), c0 = bench_cpu_now();
    tessel_status s = tessel_reconstruct_greedy(cloud, &p, NULL, &sink, &sum);
    double t = bench_now() - t0, ct = bench_cpu_now() - c0;
    double tw = 0.0;
    if (w) {
        double t1 = bench_now();
        if (s == TESSEL_OK)
            s = tessel_mesh_writer_close(w, NULL);
        else
            tessel_mesh_writer_abort(w);
        tw = bench_now() - t1;
        remove(path);
    }
    if (s != TESSEL_OK) {
        fprintf(stderr, "bench_greedy: %s: %s\n", what, tessel_status_str(s));
        return 1;
    }
    size_t rss = bench_peak_rss_bytes();
    double n = (double)cloud->count;
    printf("%-22s %9zu pts %9zu tris %6zu bnd %3zu comp %5zu left  %8.3f s %8.0f pts/s "
           "(cpu %8.0f)  held %8zu  %5.1f B/pt (%5.1f beyond input)%s",
           what, cloud->count, sum.triangles, sum.boundary_edges, sum.components,
           cloud->count - sum.points_used, t, n / t, n / ct, sum.peak_held_triangles,
           (double)rss / n, rss > input ? (double)(rss - input) / n : 0.0,
           w ? "" : "  [count sink]");
    printf("  %s", o->stream ? "[streamed]" : "[held, checked, flipped]");
    if (w)
        printf("  write %.2f s", tw);
    printf("\n");
    fflush(stdout);
    return 0;
}

static int run_sphere(size_t n, const options *o)
{
    tessel_cloud cloud;
    if (surf_sphere_fibonacci(&cloud, n, 0.2, 1) != TESSEL_OK)
        return 1;
    /* As read from a file: coordinates only. */
    free(cloud.normals);
    cloud.normals = NULL;
    char what[64];
    snprintf(what, sizeof what, "sphere %.0e", (double)n);
    int rc = measure(&cloud, o, what);
    tessel_cloud_free(&cloud);
    return rc;
}

static int run_file(const char *path, const options *o)
{
    tessel_cloud cloud;
    tessel_diag d;
    if (tessel_cloud_read(&cloud, path, NULL, &d) != TESSEL_OK) {
        fprintf(stderr, "bench_greedy: %s: %s\n", path, d.message);
        return 1;
    }
    const char *base = strrchr(path, '/');
    int rc = measure(&cloud, o, base ? base + 1 : path);
    tessel_cloud_free(&cloud);
    return rc;
}

/* Each run in its own process: its peak memory is its own. */
static int in_child(size_t n, const char *file, const options *o)
{
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0)
        return 1;
    if (pid == 0)
        _exit(file ? run_file(file, o) : run_sphere(n, o));
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
        ;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

int main(int argc, char **argv)
{
    const char *sizes = "1e4,1e5,1e6";
    options o = {"/tmp", 0.0, 0};
    int nfiles = 0, rc = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--sizes") == 0 && i + 1 < argc)
            sizes = argv[++i];
        else if (strcmp(argv[i], "--count") == 0)
            o.write_dir = NULL;
        else if (strcmp(argv[i], "--write") == 0 && i + 1 < argc)
            o.write_dir = argv[++i];
        else if (strcmp(argv[i], "--mu") == 0 && i + 1 < argc)
            o.mu = atof(argv[++i]);
        else if (strcmp(argv[i], "--stream") == 0)
            o.stream = 1;
        else if (argv[i][0] == '-') {
            fprintf(stderr, "usage: bench_greedy [--sizes 1e4,1e5,1e6,1e7] "
                            "[--count | --write DIR] [--mu M] [--stream] [FILE...]\n");
            return 2;
        } else
            nfiles++;
    }
    printf("tessel %s greedy projection benchmark (the front on one core; the check and the "
           "flips on OMP_NUM_THREADS threads)\n",
           tessel_version());
    if (nfiles) {
        for (int i = 1; i < argc; i++) {
            if (strcmp(argv[i], "--sizes") == 0 || strcmp(argv[i], "--write") == 0 ||
                strcmp(argv[i], "--mu") == 0) {
                i++;
                continue;
            }
            if (argv[i][0] != '-')
                rc |= in_child(0, argv[i], &o);
        }
        return rc;
    }
    const char *sz = sizes;
    while (*sz) {
        char *end;
        double n = strtod(sz, &end);
        if (end == sz || !(n >= 100)) {
            fprintf(stderr, "bench_greedy: bad size list '%s'\n", sizes);
            return 2;
        }
        rc |= in_child((size_t)n, NULL, &o);
        sz = *end == ',' ? end + 1 : end;
    }
    return rc;
}
