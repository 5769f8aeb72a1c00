/* Benchmark of the noisy-cloud pipeline (tessel_reconstruct_smooth: smooth,
 * cluster, reduce, advancing front, refine), with the time of every stage
 * as in Table 1 of Mederos, Velho & de Figueiredo 2003:
 *   1. sizes: a fixed-seed torus (radii 1 and 0.35) sampled at random with
 *      Gaussian noise of --noise times the mean spacing (default 0.5; the
 *      shared .pd.n05 scans have about 1), 10^4 .. 10^7 points (the
 *      largest given by --max), each size in its own process (its peak
 *      memory is its own) and run --runs times (default 3): medians of the
 *      wall seconds of each stage and of the whole pipeline's wall and CPU
 *      seconds, input points per wall second and per CPU second (the
 *      latter times the thread count is what the cores give when nothing
 *      else runs on them), and the peak resident bytes per input point
 *      (input cloud included); --tile N: the front's tile_points (0: one
 *      front);
 *   2. with --data DIR: every NAME.pd.n05.ply and NAME.pd.ply in DIR, with
 *      the result's quality against NAME.gt.ply (F-score at 1% of the
 *      diagonal, Chamfer distance, boundary and non-manifold edges,
 *      self-intersecting pairs, components) from tessel_mesh_check, and
 *      --out DIR writes the meshes;
 *   3. with --data DIR --jitter K: each NAME.pd.n05.ply again on K copies
 *      moved by Gaussian jitter of 2e-6 of its diagonal (far below the
 *      scans' precision; copy k uses seed k), and how many copies meet the
 *      targets of the issue: F >= 99.5, boundary edges under 0.1%, no
 *      non-manifold element or self-intersection, and as many components
 *      as the reference. The pipeline is deterministic, so this is how
 *      much its result depends on the last bits of the input (--out DIR
 *      writes these meshes too, and each copy's cloud beside its mesh);
 *   4. with --data DIR --renoise K: each NAME.pd.ply (the clean sample)
 *      with K new draws of the noise of the .pd.n05 files (Gaussian, sigma
 *      0.5% of the diagonal per axis; draw k uses seed k), against the same
 *      targets: how the pipeline does on scans it was not tuned on
 *      (--out DIR as with --jitter).
 *
 * usage: bench_pipeline [--max N] [--runs R] [--threads T] [--refine R] [--refine-k K]
 *                       [--tile N] [--noise X] [--data DIR] [--out DIR] [--jitter K]
 *                       [--renoise K] [--skip-sizes] */
#include "tessel.h"
#include "bench_data.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

static uint64_t rng_state;
static double noise_h = 0.5;
static double urand(void) { return bench_unif(&rng_state); }
static double gauss(void) { return bench_gauss(&rng_state); }

/* n points uniformly at random on the torus (radii 1, 0.35) plus Gaussian
 * noise of sigma = noise_h times the expected mean spacing per axis. */
static int noisy_torus(tessel_cloud *c, size_t n, uint64_t seed)
{
    if (tessel_cloud_alloc(c, n, 0, 0) != TESSEL_OK)
        return 0;
    rng_state = seed;
    const double R = 1.0, r = 0.35, area = 4.0 * 9.8696044010893586 * R * r;
    /* Mean nearest-neighbour distance of a uniform random sample. */
    double spacing = 0.5 * sqrt(area / (double)n);
    for (size_t i = 0; i < n;) {
        double u = 6.283185307179586 * urand(), v = 6.283185307179586 * urand();
        if (urand() * (R + r) > R + r * cos(v))
            continue;
        double rr = R + r * cos(v);
        double p[3] = {rr * cos(u), rr * sin(u), r * sin(v)};
        for (int k = 0; k < 3; k++)
            c->xyz[3 * i + (size_t)k] = (float)(p[k] + noise_h * spacing * gauss());
        i++;
    }
    return 1;
}

static void print_row(const char *name, size_t n, double seconds, double cpu,
                      const tessel_smooth_recon_stats *s)
{
    printf("%-22s %10zu %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %9.3f %9zu %10zu %8zu\n",
           name, n, s->seconds_spacing, s->seconds_smooth, s->seconds_simplify,
           s->seconds_front, s->seconds_refine, seconds, cpu, (double)n / seconds / 1e6,
           s->representatives, s->triangles, s->border_edges);
}

static void header(void)
{
    printf("%-22s %10s %8s %8s %8s %8s %8s %8s %8s %9s %9s %10s %8s\n", "input", "points",
           "h (s)", "smooth", "cluster", "front", "refine", "total", "cpu", "Mpts/s", "reps",
           "triangles", "border");
}

#define MAX_RUNS 15

static double median(double *v, int n)
{
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j] < v[j - 1]; j--) {
            double t = v[j];
            v[j] = v[j - 1];
            v[j - 1] = t;
        }
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* One size, runs times on the same cloud: the medians of every column. */
static int run_size(size_t n, int runs, const tessel_smooth_recon_params *p)
{
    tessel_cloud c;
    if (!noisy_torus(&c, n, 42 + n)) {
        fprintf(stderr, "bench_pipeline: out of memory at %zu points\n", n);
        return 1;
    }
    double col[7][MAX_RUNS];
    tessel_smooth_recon_stats s;
    for (int r = 0; r < runs; r++) {
        tessel_mesh m;
        double t0 = bench_now(), c0 = bench_cpu_now();
        tessel_status st = tessel_reconstruct_smooth(&c, p, NULL, &m, &s);
        double secs = bench_now() - t0, cpu = bench_cpu_now() - c0;
        tessel_mesh_free(&m);
        if (st != TESSEL_OK) {
            fprintf(stderr, "bench_pipeline: %zu points: %s\n", n, tessel_status_str(st));
            tessel_cloud_free(&c);
            return 1;
        }
        double v[7] = {s.seconds_spacing, s.seconds_smooth, s.seconds_simplify, s.seconds_front,
                       s.seconds_refine, secs, cpu};
        for (int k = 0; k < 7; k++)
            col[k][r] = v[k];
    }
    tessel_cloud_free(&c);
    double med[7];
    for (int k = 0; k < 7; k++)
        med[k] = median(col[k], runs);
    printf("torus %-16.0e %10zu %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %9.3f %10.3f %8.1f "
           "%9zu %10zu %8zu\n",
           (double)n, n, med[0], med[1], med[2], med[3], med[4], med[5], med[6],
           (double)n / med[5] / 1e6, (double)n / med[6] / 1e6,
           (double)bench_peak_rss_bytes() / (double)n, s.representatives, s.triangles,
           s.border_edges);
    return 0;
}

/* Each size in its own process: its peak memory is its own. */
static int in_child(size_t n, int runs, const tessel_smooth_recon_params *p)
{
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0)
        return 1;
    if (pid == 0) {
        int rc = run_size(n, runs, p);
        fflush(stdout);
        _exit(rc);
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
        ;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

static void run_sizes(size_t max, int runs, const tessel_smooth_recon_params *p)
{
    printf("Noisy torus, random sampling, noise %.2g h; medians of %d runs: wall seconds per "
           "stage (h = spacing estimate; cluster = clusters + representatives), total wall "
           "and cpu (CPU seconds of all threads), million input points per wall second and "
           "per CPU second, peak resident bytes per input point\n",
           noise_h, runs);
    printf("%-22s %10s %8s %8s %8s %8s %8s %8s %8s %9s %10s %8s %9s %10s %8s\n", "input",
           "points", "h (s)", "smooth", "cluster", "front", "refine", "total", "cpu",
           "Mpts/s", "Mpts/cpu-s", "B/pt", "reps", "triangles", "border");
    for (size_t n = 10000; n <= max; n *= 10)
        if (in_child(n, runs, p))
            return;
}

static void run_file(const char *dir, const char *name, const char *suffix, const char *out,
                     const tessel_smooth_recon_params *p)
{
    char path[1024], ref_path[1024];
    snprintf(path, sizeof path, "%s/%s.%s.ply", dir, name, suffix);
    snprintf(ref_path, sizeof ref_path, "%s/%s.gt.ply", dir, name);
    tessel_cloud c;
    tessel_mesh ref, m;
    if (tessel_cloud_read(&c, path, NULL, NULL) != TESSEL_OK)
        return;
    if (tessel_mesh_read(&ref, ref_path, NULL, NULL) != TESSEL_OK) {
        tessel_cloud_free(&c);
        return;
    }
    tessel_smooth_recon_stats s;
    double t0 = bench_now(), c0 = bench_cpu_now();
    tessel_status st = tessel_reconstruct_smooth(&c, p, NULL, &m, &s);
    double secs = bench_now() - t0, cpu = bench_cpu_now() - c0;
    if (st != TESSEL_OK) {
        fprintf(stderr, "bench_pipeline: %s: %s\n", path, tessel_status_str(st));
    } else {
        char label[128];
        snprintf(label, sizeof label, "%s.%s", name, suffix);
        print_row(label, c.count, secs, cpu, &s);
        tessel_check_params cp = tessel_check_params_default();
        cp.reference = &ref;
        tessel_mesh_report r;
        if (tessel_mesh_check(&m, &cp, &r) == TESSEL_OK)
            printf("%-22s F %.3f  chamfer %.3e  boundary %zu/%zu = %.3f%%  non-manifold "
                   "e/v %zu/%zu  self-int %zu  components %zu  genus %ld\n",
                   "", r.fscore, r.chamfer / r.reference_bbox_diagonal, r.boundary_edges,
                   r.edges, r.edges ? 100.0 * (double)r.boundary_edges / (double)r.edges : 0.0,
                   r.nonmanifold_edges, r.nonmanifold_vertices, r.self_intersections,
                   r.components, r.genus);
        if (out) {
            char op[1024];
            snprintf(op, sizeof op, "%s/%s.%s.smooth.ply", out, name, suffix);
            tessel_mesh_write(&m, op, NULL, NULL);
        }
    }
    tessel_mesh_free(&m);
    tessel_mesh_free(&ref);
    tessel_cloud_free(&c);
}

/* Whether m meets the targets against ref (of ref_components components);
 * prints its row. */
static int meets_targets(const tessel_mesh *m, const tessel_mesh *ref, size_t ref_components,
                         const char *label)
{
    tessel_check_params cp = tessel_check_params_default();
    cp.reference = ref;
    tessel_mesh_report r;
    if (tessel_mesh_check(m, &cp, &r) != TESSEL_OK)
        return 0;
    double bnd = r.edges ? 100.0 * (double)r.boundary_edges / (double)r.edges : 100.0;
    int ok = r.fscore >= 99.5 && bnd < 0.1 && r.nonmanifold_edges == 0 &&
             r.nonmanifold_vertices == 0 && r.self_intersections == 0 &&
             r.components == ref_components;
    printf("%-26s F %.3f  boundary %.3f%%  components %zu  self-int %zu  %s\n", label,
           r.fscore, bnd, r.components, r.self_intersections, ok ? "ok" : "MISSED");
    return ok;
}

/* copies of NAME.SUFFIX.ply, each moved by Gaussian noise of sigma times
 * its diagonal per axis (copy k with seed k), through the pipeline; prints
 * how many meet the targets. */
static void run_copies(const char *dir, const char *name, const char *suffix, double sigma,
                       const char *what, int copies, const char *out,
                       const tessel_smooth_recon_params *p)
{
    char path[1024], ref_path[1024];
    snprintf(path, sizeof path, "%s/%s.%s.ply", dir, name, suffix);
    snprintf(ref_path, sizeof ref_path, "%s/%s.gt.ply", dir, name);
    tessel_cloud c;
    tessel_mesh ref;
    if (tessel_cloud_read(&c, path, NULL, NULL) != TESSEL_OK)
        return;
    if (tessel_mesh_read(&ref, ref_path, NULL, NULL) != TESSEL_OK) {
        tessel_cloud_free(&c);
        return;
    }
    tessel_check_params cp = tessel_check_params_default();
    cp.self_intersections = 0;
    tessel_mesh_report rr;
    size_t ref_components = tessel_mesh_check(&ref, &cp, &rr) == TESSEL_OK ? rr.components : 0;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < c.count; i++)
        for (int k = 0; k < 3; k++) {
            float x = c.xyz[3 * i + (size_t)k];
            lo[k] = x < lo[k] ? x : lo[k];
            hi[k] = x > hi[k] ? x : hi[k];
        }
    double diag = sqrt((double)(hi[0] - lo[0]) * (hi[0] - lo[0]) +
                       (double)(hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (double)(hi[2] - lo[2]) * (hi[2] - lo[2]));
    float *orig = malloc(3 * c.count * sizeof *orig);
    if (!orig) {
        tessel_mesh_free(&ref);
        tessel_cloud_free(&c);
        return;
    }
    memcpy(orig, c.xyz, 3 * c.count * sizeof *orig);
    int met = 0;
    for (int k = 1; k <= copies; k++) {
        uint64_t s = (uint64_t)k * 0x9E3779B97F4A7C15ULL;
        for (size_t i = 0; i < 3 * c.count; i++)
            c.xyz[i] = (float)(orig[i] + sigma * diag * bench_gauss(&s));
        tessel_mesh m;
        char label[128];
        snprintf(label, sizeof label, "%s.%s %s %d", name, suffix, what, k);
        if (tessel_reconstruct_smooth(&c, p, NULL, &m, NULL) == TESSEL_OK) {
            met += meets_targets(&m, &ref, ref_components, label);
            if (out) {
                char op[1024];
                snprintf(op, sizeof op, "%s/%s.%s.%s%d.smooth.ply", out, name, suffix, what, k);
                tessel_mesh_write(&m, op, NULL, NULL);
                snprintf(op, sizeof op, "%s/%s.%s.%s%d.ply", out, name, suffix, what, k);
                tessel_cloud_write(&c, op, NULL, NULL);
            }
        }
        tessel_mesh_free(&m);
    }
    printf("%s.%s: targets met in %d of %d copies (%s)\n", name, suffix, met, copies, what);
    free(orig);
    tessel_mesh_free(&ref);
    tessel_cloud_free(&c);
}

int main(int argc, char **argv)
{
    size_t max = 1000000;
    int runs = 3;
    const char *dir = NULL, *out = NULL;
    int skip_sizes = 0, jitter = 0, renoise = 0;
    tessel_smooth_recon_params p = tessel_smooth_recon_params_default();
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--max") && i + 1 < argc)
            max = (size_t)strtod(argv[++i], NULL);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc &&
                 (runs = atoi(argv[i + 1])) >= 1 && runs <= MAX_RUNS)
            i++;
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            p.threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--refine") && i + 1 < argc)
            p.refine.rounds = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--refine-k") && i + 1 < argc)
            p.refine.k = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--tile") && i + 1 < argc)
            p.front.tile_points = (size_t)strtod(argv[++i], NULL);
        else if (!strcmp(argv[i], "--data") && i + 1 < argc)
            dir = argv[++i];
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            out = argv[++i];
        else if (!strcmp(argv[i], "--noise") && i + 1 < argc &&
                 (noise_h = strtod(argv[i + 1], NULL)) >= 0.0 && noise_h < 100.0)
            i++;
        else if (!strcmp(argv[i], "--jitter") && i + 1 < argc)
            jitter = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--renoise") && i + 1 < argc)
            renoise = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--skip-sizes"))
            skip_sizes = 1;
        else {
            fprintf(stderr,
                    "usage: bench_pipeline [--max N] [--runs R (1..15)] [--threads T] [--refine R] "
                    "[--refine-k K] "
                    "[--tile N] [--noise X] [--data DIR] [--out DIR] [--jitter K] "
                    "[--renoise K] [--skip-sizes]\n");
            return 1;
        }
    }
    if (!skip_sizes)
        run_sizes(max, runs, &p);
    if (dir) {
        printf("\nFiles in %s (quality against NAME.gt.ply; F-score at 1%% of its "
               "diagonal)\n",
               dir);
        header();
        static const char *const names[] = {"bunny", "elephant", "knot2"};
        static const char *const suffixes[] = {"pd.n05", "pd"};
        for (size_t k = 0; k < 3; k++)
            for (size_t j = 0; j < 2; j++)
                run_file(dir, names[k], suffixes[j], out, &p);
        if (jitter > 0) {
            printf("\nJittered copies of the noisy files (2e-6 of the diagonal)\n");
            for (size_t k = 0; k < 3; k++)
                run_copies(dir, names[k], "pd.n05", 2e-6, "jitter", jitter, out, &p);
        }
        if (renoise > 0) {
            printf("\nNew noise draws on the clean samples (sigma 0.5%% of the diagonal)\n");
            for (size_t k = 0; k < 3; k++)
                run_copies(dir, names[k], "pd", 5e-3, "noise", renoise, out, &p);
        }
    }
    return 0;
}
