/* Benchmark of the noisy-cloud stages (src/smooth/, src/smooth/cluster.c,
 * src/smooth/simplify.c):
 *   1. throughput: smoothing (medians of three runs; also with the spacing
 *      estimated inside, as a default caller runs it), clustering and
 *      representatives on a fixed-seed noisy sphere (default 1,000,000
 *      points), 1 and 2 threads;
 *   2. accuracy on real data (with --data DIR): for NAME in bunny elephant
 *      knot2, the RMS distance from NAME.pd.n05.ply to the true surface
 *      NAME.gt.ply before and after smoothing, and of the representatives;
 *      reduced sizes for a grid of n_min, sigma_max and max_diameter;
 *   3. sharp features: on the real data, the distance to the true surface
 *      by distance to its creases (edges over 20 degrees: knot2.gt.ply is
 *      a tube of eight flat sides); a noisy cube (noise 0.5% of the
 *      diagonal), the distance to the cube near its edges and on its faces
 *      before and after.
 * Distances are exact point-to-triangle distances (closest point on a
 * triangle, Ericson, "Real-Time Collision Detection" 5.1.5) found through a
 * uniform grid of triangles.
 *
 * usage: bench_smooth [--n POINTS] [--data DIR] [--passes P] [--skip-speed] */
#include "tessel.h"
#include "bench_data.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 12345;
static double urand(void) { return bench_unif(&rng_state); }
static double gauss(void) { return bench_gauss(&rng_state); }

/* ---- point to mesh distance ---- */

typedef struct tri_grid {
    const tessel_mesh *m;
    double lo[3], cell;
    long dim[3];
    size_t *start; /* cells + 1 */
    uint32_t *tri; /* triangle ids by cell */
} tri_grid;

static long clampl(long v, long a, long b)
{
    return v < a ? a : (v > b ? b : v);
}

static void tri_box(const tri_grid *g, uint32_t t, long lo[3], long hi[3])
{
    const uint32_t *ix = g->m->triangles + 3 * (size_t)t;
    for (int a = 0; a < 3; a++) {
        double mn = INFINITY, mx = -INFINITY;
        for (int k = 0; k < 3; k++) {
            double v = g->m->xyz[3 * (size_t)ix[k] + a];
            mn = fmin(mn, v);
            mx = fmax(mx, v);
        }
        lo[a] = clampl((long)floor((mn - g->lo[a]) / g->cell), 0, g->dim[a] - 1);
        hi[a] = clampl((long)floor((mx - g->lo[a]) / g->cell), 0, g->dim[a] - 1);
    }
}

static int tri_grid_build(tri_grid *g, const tessel_mesh *m)
{
    memset(g, 0, sizeof *g);
    g->m = m;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < m->vertex_count; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], m->xyz[3 * i + a]);
            hi[a] = fmax(hi[a], m->xyz[3 * i + a]);
        }
    double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
    /* About one triangle per cell on a surface. */
    g->cell = diag / sqrt((double)m->triangle_count) * 1.5;
    size_t cells = 1;
    for (int a = 0; a < 3; a++) {
        g->lo[a] = lo[a] - 0.1 * diag;
        g->dim[a] = (long)((hi[a] - lo[a] + 0.2 * diag) / g->cell) + 1;
        cells *= (size_t)g->dim[a];
    }
    g->start = calloc(cells + 1, sizeof *g->start);
    if (!g->start)
        return -1;
    for (int pass = 0; pass < 2; pass++) {
        for (uint32_t t = 0; t < m->triangle_count; t++) {
            long a[3], b[3];
            tri_box(g, t, a, b);
            for (long x = a[0]; x <= b[0]; x++)
                for (long y = a[1]; y <= b[1]; y++)
                    for (long z = a[2]; z <= b[2]; z++) {
                        size_t c = ((size_t)x * g->dim[1] + y) * g->dim[2] + z;
                        if (pass == 0)
                            g->start[c + 1]++;
                        else
                            g->tri[g->start[c]++] = t;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < cells; c++)
                g->start[c + 1] += g->start[c];
            g->tri = malloc((g->start[cells] + 1) * sizeof *g->tri);
            if (!g->tri)
                return -1;
        } else {
            for (size_t c = cells; c > 0; c--)
                g->start[c] = g->start[c - 1];
            g->start[0] = 0;
        }
    }
    return 0;
}

static void tri_grid_free(tri_grid *g)
{
    free(g->start);
    free(g->tri);
}

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Squared distance from p to triangle abc. */
static double point_triangle_d2(const double p[3], const double a[3], const double b[3],
                                const double c[3])
{
    double ab[3], ac[3], ap[3], q[3];
    for (int i = 0; i < 3; i++)
        ab[i] = b[i] - a[i], ac[i] = c[i] - a[i], ap[i] = p[i] - a[i];
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        memcpy(q, a, sizeof q);
        goto done;
    }
    double bp[3];
    for (int i = 0; i < 3; i++)
        bp[i] = p[i] - b[i];
    double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        memcpy(q, b, sizeof q);
        goto done;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + v * ab[i];
        goto done;
    }
    double cp[3];
    for (int i = 0; i < 3; i++)
        cp[i] = p[i] - c[i];
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        memcpy(q, c, sizeof q);
        goto done;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double w = d2 / (d2 - d6);
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + w * ac[i];
        goto done;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int i = 0; i < 3; i++)
            q[i] = b[i] + w * (c[i] - b[i]);
        goto done;
    }
    {
        double den = 1.0 / (va + vb + vc), v = vb * den, w = vc * den;
        for (int i = 0; i < 3; i++)
            q[i] = a[i] + ab[i] * v + ac[i] * w;
    }
done:;
    double e[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    return dot3(e, e);
}

/* Distance from p (mesh coordinates) to the mesh: rings of cells around
 * p's cell until no unvisited cell can be nearer. */
static double mesh_distance(const tri_grid *g, const double p[3])
{
    long c[3];
    for (int a = 0; a < 3; a++)
        c[a] = clampl((long)floor((p[a] - g->lo[a]) / g->cell), 0, g->dim[a] - 1);
    long maxr = g->dim[0] + g->dim[1] + g->dim[2];
    double best = INFINITY;
    for (long r = 0; r <= maxr; r++) {
        for (long x = c[0] - r; x <= c[0] + r; x++) {
            if (x < 0 || x >= g->dim[0])
                continue;
            for (long y = c[1] - r; y <= c[1] + r; y++) {
                if (y < 0 || y >= g->dim[1])
                    continue;
                for (long z = c[2] - r; z <= c[2] + r; z++) {
                    if (z < 0 || z >= g->dim[2])
                        continue;
                    if (labs(x - c[0]) != r && labs(y - c[1]) != r && labs(z - c[2]) != r)
                        continue;
                    size_t cell = ((size_t)x * g->dim[1] + y) * g->dim[2] + z;
                    for (size_t i = g->start[cell]; i < g->start[cell + 1]; i++) {
                        const uint32_t *t = g->m->triangles + 3 * (size_t)g->tri[i];
                        double v[3][3];
                        for (int k = 0; k < 3; k++)
                            for (int a = 0; a < 3; a++)
                                v[k][a] = g->m->xyz[3 * (size_t)t[k] + a];
                        double d2 = point_triangle_d2(p, v[0], v[1], v[2]);
                        best = d2 < best ? d2 : best;
                    }
                }
            }
        }
        /* Every unvisited cell is beyond the box of rings 0..r. */
        double bound = INFINITY;
        for (int a = 0; a < 3; a++) {
            double blo = g->lo[a] + (double)(c[a] - r) * g->cell;
            double bhi = g->lo[a] + (double)(c[a] + r + 1) * g->cell;
            bound = fmin(bound, fmin(p[a] - blo, bhi - p[a]));
        }
        if (bound > 0 && best <= bound * bound)
            break;
    }
    return sqrt(best);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Distance of every point of c to the mesh, into d. */
static void point_distances(const tri_grid *g, const tessel_cloud *c, double *d)
{
#pragma omp parallel for schedule(dynamic, 1024)
    for (size_t i = 0; i < c->count; i++) {
        double p[3];
        for (int a = 0; a < 3; a++)
            p[a] = c->xyz[3 * i + a] + c->offset[a] - g->m->offset[a];
        d[i] = mesh_distance(g, p);
    }
}

/* RMS, max and (when med is not NULL) median distance of the cloud's
 * points to the mesh (world coordinates). */
static void cloud_distance3(const tri_grid *g, const tessel_cloud *c, double *rms, double *mx,
                            double *med)
{
    double *d = malloc(c->count * sizeof *d);
    if (!d) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    point_distances(g, c, d);
    double s = 0, m = 0;
    for (size_t i = 0; i < c->count; i++) {
        s += d[i] * d[i];
        m = d[i] > m ? d[i] : m;
    }
    *rms = sqrt(s / (double)c->count);
    *mx = m;
    if (med) {
        qsort(d, c->count, sizeof *d, cmp_double);
        *med = d[c->count / 2];
    }
    free(d);
}

static void cloud_distance(const tri_grid *g, const tessel_cloud *c, double *rms, double *mx)
{
    cloud_distance3(g, c, rms, mx, NULL);
}

/* ---- 1. throughput ---- */

static void noisy_sphere(tessel_cloud *c, size_t n, double sigma)
{
    if (tessel_cloud_alloc(c, n, 0, 0) != TESSEL_OK) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    /* Random positions (not a spiral): a scan-like, unsorted input. */
    for (size_t i = 0; i < n; i++) {
        double z = 2 * urand() - 1, a = 6.283185307179586 * urand(), r = sqrt(1 - z * z);
        double s = 1 + sigma * gauss();
        c->xyz[3 * i] = (float)(s * r * cos(a));
        c->xyz[3 * i + 1] = (float)(s * r * sin(a));
        c->xyz[3 * i + 2] = (float)(s * z);
    }
}

/* Median of three. */
static double median3(double a, double b, double c)
{
    return a > b ? (b > c ? b : (a > c ? c : a)) : (a > c ? a : (b > c ? c : b));
}

/* Smooths c three times with p: median wall and CPU seconds. */
static int time_smooth(const tessel_cloud *c, const tessel_smooth_params *p, double *wall,
                       double *cpu, tessel_smooth_stats *st)
{
    double w[3], u[3];
    for (int r = 0; r < 3; r++) {
        tessel_cloud out;
        double t0 = bench_now(), c0 = bench_cpu_now();
        if (tessel_smooth(c, &out, p, NULL, st) != TESSEL_OK)
            return -1;
        w[r] = bench_now() - t0, u[r] = bench_cpu_now() - c0;
        tessel_cloud_free(&out);
    }
    *wall = median3(w[0], w[1], w[2]);
    *cpu = median3(u[0], u[1], u[2]);
    return 0;
}

static void bench_speed(size_t n)
{
    tessel_cloud c, out, reps;
    /* Noise of about a third of the spacing of n points on the sphere. */
    double noise = 0.3 * sqrt(4 * 3.141592653589793 / (double)n);
    noisy_sphere(&c, n, noise);
    printf(
        "## Throughput: noisy unit sphere, %zu points (uniform random, radial noise %.5f)\n\n",
        n, noise);
    double t0 = bench_now(), c0 = bench_cpu_now(), h;
    if (tessel_cloud_spacing(&c, &h) != TESSEL_OK)
        return;
    printf("spacing estimate: h = %.5f in %.3f s wall, %.3f s CPU\n\n", h, bench_now() - t0,
           bench_cpu_now() - c0);
    printf("Medians of three runs. CPU us/pt: process CPU time per point (all threads, all "
           "passes); points/s on 2 idle cores = 2e6 / that (the figure to read when other "
           "jobs share the machine).\n\n");
    printf("| stage | threads | wall s | cpu s | points/s (wall) | CPU us/pt | points/s on 2 "
           "cores (CPU) | notes |\n");
    printf("|---|---|---|---|---|---|---|---|\n");
    for (int th = 1; th <= 2; th++) {
        tessel_smooth_params p = tessel_smooth_params_default();
        p.spacing = h;
        p.threads = th;
        tessel_smooth_stats st;
        double w, cpu;
        if (th == 2) { /* the paper's plane operator, same passes */
            p.quadric = 0;
            if (time_smooth(&c, &p, &w, &cpu, &st) != 0)
                return;
            printf("| smooth, plane (k=%u, %u passes) | %d | %.3f | %.3f | %.0f | %.3f | %.0f | "
                   "%.2f IRLS iterations |\n",
                   p.k, p.passes, th, w, cpu, n / w, 1e6 * cpu / n, 2.0 * n / cpu,
                   st.mean_iterations);
            p.quadric = 1;
            /* As a caller with default parameters runs it: h estimated. */
            p.spacing = 0.0;
            if (time_smooth(&c, &p, &w, &cpu, &st) != 0)
                return;
            printf("| smooth, quadric, h estimated inside (k=%u, %u passes) | %d | %.3f | %.3f "
                   "| %.0f | %.3f | %.0f | spacing estimate included |\n",
                   p.k, p.passes, th, w, cpu, n / w, 1e6 * cpu / n, 2.0 * n / cpu);
            p.spacing = h;
            p.aggregate = 1;
            for (uint32_t passes = 2; passes <= 3; passes++) {
                p.passes = passes;
                if (time_smooth(&c, &p, &w, &cpu, &st) != 0)
                    return;
                printf("| smooth, quadric + aggregate (k=%u, %u passes) | %d | %.3f | %.3f | "
                       "%.0f | %.3f | %.0f | |\n",
                       p.k, p.passes, th, w, cpu, n / w, 1e6 * cpu / n, 2.0 * n / cpu);
            }
            p = tessel_smooth_params_default();
            p.spacing = h;
            p.threads = th;
        }
        if (time_smooth(&c, &p, &w, &cpu, &st) != 0)
            return;
        printf("| smooth, quadric (k=%u, %u passes) | %d | %.3f | %.3f | %.0f | %.3f | %.0f | "
               "%.2f IRLS iterations, %zu unfit |\n",
               p.k, p.passes, th, w, cpu, n / w, 1e6 * cpu / n, 2.0 * n / cpu,
               st.mean_iterations, st.unfit);
        if (tessel_smooth(&c, &out, &p, NULL, &st) != TESSEL_OK)
            return;
        tessel_simplify_params sp = tessel_simplify_params_default();
        sp.cluster.spacing = sp.projection.spacing = h;
        sp.cluster.threads = sp.projection.threads = th;
        tessel_clusters cl;
        t0 = bench_now(), c0 = bench_cpu_now();
        if (tessel_cluster(&out, &sp.cluster, NULL, &cl) != TESSEL_OK)
            return;
        double w1 = bench_now() - t0, cpu1 = bench_cpu_now() - c0;
        t0 = bench_now(), c0 = bench_cpu_now();
        tessel_simplify_stats ss;
        if (tessel_representatives(&out, &cl, &sp, NULL, &reps, &ss) != TESSEL_OK)
            return;
        double w2 = bench_now() - t0, cpu2 = bench_cpu_now() - c0;
        printf("| cluster | %d | %.3f | %.3f | %.0f | %.3f | %.0f | %zu clusters |\n", th, w1,
               cpu1, n / w1, 1e6 * cpu1 / n, 2.0 * n / cpu1, cl.count);
        printf("| representatives | %d | %.3f | %.3f | %.0f | %.3f | %.0f | %zu points (%.1fx "
               "fewer) |\n",
               th, w2, cpu2, n / w2, 1e6 * cpu2 / n, 2.0 * n / cpu2, reps.count,
               (double)n / reps.count);
        tessel_clusters_free(&cl);
        tessel_cloud_free(&reps);
        tessel_cloud_free(&out);
    }
    printf("\n");
    tessel_cloud_free(&c);
}

/* ---- where the error is on real data: near the reference's creases ---- */

/* A reference edge is a crease where the normals of its two triangles
 * differ by more than this (knot2.gt.ply is a tube of eight flat sides,
 * 45 degrees apart). */
#define CREASE_DEG 20.0

typedef struct edge_ref {
    uint32_t a, b, t;
} edge_ref;

static int cmp_edge_ref(const void *x, const void *y)
{
    const edge_ref *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    return p->b < q->b ? -1 : p->b > q->b;
}

static void unit_normal(const tessel_mesh *m, uint32_t t, double n[3])
{
    const uint32_t *v = m->triangles + 3 * (size_t)t;
    double e1[3], e2[3];
    for (int a = 0; a < 3; a++) {
        e1[a] = (double)m->xyz[3 * (size_t)v[1] + a] - m->xyz[3 * (size_t)v[0] + a];
        e2[a] = (double)m->xyz[3 * (size_t)v[2] + a] - m->xyz[3 * (size_t)v[0] + a];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double l = sqrt(dot3(n, n));
    for (int a = 0; a < 3; a++)
        n[a] = l > 0 ? n[a] / l : 0.0;
}

/* The reference's creases as segments (6 doubles each, mesh coordinates);
 * returns their number, 0 (and *seg NULL) when there are none. */
static size_t crease_segments(const tessel_mesh *m, double **seg)
{
    size_t ne = 3 * m->triangle_count, ns = 0;
    edge_ref *e = malloc((ne ? ne : 1) * sizeof *e);
    *seg = malloc((ne ? ne : 1) * 6 * sizeof **seg);
    if (!e || !*seg) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    for (size_t t = 0; t < m->triangle_count; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = m->triangles[3 * t + k], b = m->triangles[3 * t + (k + 1) % 3];
            e[3 * t + k] = (edge_ref){a < b ? a : b, a < b ? b : a, (uint32_t)t};
        }
    qsort(e, ne, sizeof *e, cmp_edge_ref);
    const double cos_crease = cos(CREASE_DEG * 3.141592653589793 / 180.0);
    for (size_t i = 0; i + 1 < ne; i++) {
        if (e[i].a != e[i + 1].a || e[i].b != e[i + 1].b)
            continue;
        double n0[3], n1[3];
        unit_normal(m, e[i].t, n0);
        unit_normal(m, e[i + 1].t, n1);
        if (fabs(dot3(n0, n1)) >= cos_crease)
            continue;
        for (int a = 0; a < 3; a++) {
            (*seg)[6 * ns + a] = m->xyz[3 * (size_t)e[i].a + a];
            (*seg)[6 * ns + 3 + a] = m->xyz[3 * (size_t)e[i].b + a];
        }
        ns++;
    }
    free(e);
    if (ns == 0) {
        free(*seg);
        *seg = NULL;
    }
    return ns;
}

static double segment_distance(const double *s, const double p[3])
{
    double d[3], w[3];
    for (int a = 0; a < 3; a++) {
        d[a] = s[3 + a] - s[a];
        w[a] = p[a] - s[a];
    }
    double dd = dot3(d, d), t = dd > 0 ? dot3(w, d) / dd : 0.0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double r = 0;
    for (int a = 0; a < 3; a++) {
        double x = w[a] - t * d[a];
        r += x * x;
    }
    return sqrt(r);
}

/* RMS distance to the reference before (c) and after (s) smoothing, by the
 * distance of the point's true position (truth: the same points without
 * noise) to the nearest crease, in h: on a faceted reference, how much of
 * what the smoothing leaves is the creases it rounds. Brute force over the
 * crease segments (a few thousand). */
static void crease_rows(const char *name, const tri_grid *g, const tessel_cloud *truth,
                        const tessel_cloud *c, const tessel_cloud *s, double h)
{
    double *seg;
    size_t ns = crease_segments(g->m, &seg);
    if (ns == 0) {
        printf("| %s | no edge over %.0f degrees | | | | |\n", name, CREASE_DEG);
        return;
    }
    size_t n = c->count;
    double *d0 = malloc(n * sizeof *d0), *d1 = malloc(n * sizeof *d1);
    int *bin = malloc(n * sizeof *bin);
    if (!d0 || !d1 || !bin) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    point_distances(g, c, d0);
    point_distances(g, s, d1);
    static const double limits[] = {1, 2, 4};
#pragma omp parallel for schedule(dynamic, 256)
    for (size_t i = 0; i < n; i++) {
        double p[3], best = INFINITY;
        for (int a = 0; a < 3; a++)
            p[a] = truth->xyz[3 * i + a] + truth->offset[a] - g->m->offset[a];
        for (size_t k = 0; k < ns; k++)
            best = fmin(best, segment_distance(seg + 6 * k, p));
        int b = 0;
        while (b < 3 && best / h >= limits[b])
            b++;
        bin[i] = b;
    }
    double s0[4] = {0, 0, 0, 0}, s1[4] = {0, 0, 0, 0}, all1 = 0;
    size_t cnt[4] = {0, 0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        s0[bin[i]] += d0[i] * d0[i];
        s1[bin[i]] += d1[i] * d1[i];
        cnt[bin[i]]++;
        all1 += d1[i] * d1[i];
    }
    static const char *label[] = {"< 1 h", "1-2 h", "2-4 h", "> 4 h"};
    for (int b = 0; b < 4; b++)
        if (cnt[b])
            printf("| %s (%zu crease edges) | %s | %zu | %.3f / %.3f | %.2fx | %.0f%% |\n", name,
                   ns, label[b], cnt[b], sqrt(s0[b] / cnt[b]) / h, sqrt(s1[b] / cnt[b]) / h,
                   sqrt(s0[b] / s1[b]), 100 * s1[b] / all1);
    free(d0);
    free(d1);
    free(bin);
    free(seg);
}

/* ---- 2. real data ---- */

/* Variants of the aggregation table: quadric, aggregate, passes, sigma_w,
 * exclude_self. */
static const double agg_variants[][5] = {
    {1, 0, 2, 3, 0}, {1, 1, 2, 3, 0}, {1, 1, 3, 3, 0}, {0, 0, 2, 3, 0}, {0, 1, 2, 3, 0},
    {0, 1, 2, 2.5, 0}, {1, 0, 2, 3, 1}, {1, 1, 2, 3, 1}, {1, 1, 3, 3, 1}};
#define N_AGG (sizeof agg_variants / sizeof *agg_variants)

/* The scans with a noisy sample and a reference surface in the data folder. */
static const char *const names[] = {"bunny", "elephant", "knot2"};

/* DIR/NAME.pd.n05.ply and DIR/NAME.gt.ply; false (with a table row saying
 * so) when either cannot be read. */
static bool read_data(const char *dir, const char *name, tessel_cloud *c, tessel_mesh *gt)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s.pd.n05.ply", dir, name);
    if (tessel_cloud_read(c, path, NULL, NULL) != TESSEL_OK) {
        printf("| %s | (cannot read %s) |\n", name, path);
        return false;
    }
    snprintf(path, sizeof path, "%s/%s.gt.ply", dir, name);
    if (tessel_mesh_read(gt, path, NULL, NULL) != TESSEL_OK) {
        printf("| %s | (cannot read %s) |\n", name, path);
        tessel_cloud_free(c);
        return false;
    }
    return true;
}

/* The section on creases: each file smoothed with the defaults. */
static void bench_creases(const char *dir)
{
    printf("## Where the error is: near the reference's creases (defaults)\n\n");
    printf("Reference edges whose two triangles' normals differ by over %.0f degrees are "
           "creases. Points binned by the distance of their true position (NAME.pd.ply: the "
           "same points without noise) to the nearest one; RMS "
           "distance to the reference in h before / after; share: of the smoothed cloud's "
           "squared distances.\n\n",
           CREASE_DEG);
    printf("| data | to a crease | points | RMS before / after (h) | gain | share |\n");
    printf("|---|---|---|---|---|---|\n");
    for (size_t f = 0; f < sizeof names / sizeof *names; f++) {
        tessel_cloud c, s, truth;
        tessel_mesh gt;
        if (!read_data(dir, names[f], &c, &gt))
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s.pd.ply", dir, names[f]);
        if (tessel_cloud_read(&truth, path, NULL, NULL) != TESSEL_OK) {
            printf("| %s | (cannot read %s) |\n", names[f], path);
        } else if (truth.count != c.count) {
            printf("| %s | (%s is not the noisy cloud's points) |\n", names[f], path);
            tessel_cloud_free(&truth);
        } else {
            tri_grid g;
            double h;
            if (tri_grid_build(&g, &gt) == 0 && tessel_cloud_spacing(&c, &h) == TESSEL_OK &&
                tessel_smooth(&c, &s, NULL, NULL, NULL) == TESSEL_OK) {
                crease_rows(names[f], &g, &truth, &c, &s, h);
                tessel_cloud_free(&s);
                tri_grid_free(&g);
            }
            tessel_cloud_free(&truth);
        }
        tessel_cloud_free(&c);
        tessel_mesh_free(&gt);
    }
    printf("\n");
}

static void bench_data(const char *dir, uint32_t passes)
{
    double agg_gain[3][N_AGG], agg_time[3][N_AGG];
    bool have[3] = {false, false, false};
    printf("## Accuracy: DIR/NAME.pd.n05.ply against NAME.gt.ply\n\n");
    printf("RMS / max: distance to the true surface in %% of its bounding-box diagonal; "
           "median gain: ratio of the median distances. Times are wall seconds.\n\n");
    printf(
        "| data | points | h/diag %% | noisy RMS / max | smoothed RMS / max (passes) | gain | "
        "median gain | time | reps | reps RMS / max | time |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (size_t f = 0; f < sizeof names / sizeof *names; f++) {
        tessel_cloud c, s, r;
        tessel_mesh gt;
        if (!read_data(dir, names[f], &c, &gt))
            continue;
        tri_grid g;
        if (tri_grid_build(&g, &gt) != 0)
            return;
        double lo[3] = {INFINITY, INFINITY, INFINITY},
               hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < gt.vertex_count; i++)
            for (int a = 0; a < 3; a++) {
                lo[a] = fmin(lo[a], gt.xyz[3 * i + a]);
                hi[a] = fmax(hi[a], gt.xyz[3 * i + a]);
            }
        double diag =
            sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                 (hi[2] - lo[2]) * (hi[2] - lo[2]));
        double r0, m0, r1, m1, r2, m2, h, md0, md1;
        cloud_distance3(&g, &c, &r0, &m0, &md0);
        tessel_cloud_spacing(&c, &h);
        tessel_smooth_params p = tessel_smooth_params_default();
        p.passes = passes;
        double t0 = bench_now();
        if (tessel_smooth(&c, &s, &p, NULL, NULL) != TESSEL_OK)
            return;
        double ts = bench_now() - t0;
        cloud_distance3(&g, &s, &r1, &m1, &md1);
        t0 = bench_now();
        tessel_simplify_stats ss;
        if (tessel_simplify(&s, &r, NULL, NULL, &ss) != TESSEL_OK)
            return;
        double tr = bench_now() - t0;
        cloud_distance(&g, &r, &r2, &m2);
        printf(
            "| %s | %zu | %.3f | %.3f / %.3f | %.3f / %.3f (%u) | %.2fx | %.2fx | %.3f | %zu | "
            "%.3f / %.3f | %.3f |\n",
            names[f], c.count, 100 * h / diag, 100 * r0 / diag, 100 * m0 / diag,
            100 * r1 / diag, 100 * m1 / diag, passes, r0 / r1, md0 / md1, ts, r.count,
            100 * r2 / diag, 100 * m2 / diag, tr);

        /* Sensitivity: 1-3 passes and sigma_rho. */
        if (f == 0) {
            printf("\n%s, smoothing parameters (RMS %% of diagonal):\n\n", names[f]);
            printf("| operator | sigma_rho | later | sigma_w | k | passes | RMS | gain "
                   "|\n|---|---|---|---|---|---|---|---|\n");
            /* quadric, sigma_rho, sigma_rho_later, sigma_w, k, passes */
            static const double grid[][6] = {
                {0, 2, 2, 2.5, 24, 2}, {0, 2, 1, 3, 30, 2},   {1, 2, 1, 3, 30, 1},
                {1, 2, 1, 3, 24, 2},   {1, 2, 1, 3, 30, 2},   {1, 2, 2, 3, 30, 2},
                {1, 2, 0.7, 3, 30, 2}, {1, 2, 1, 2.5, 30, 2}, {1, 2.5, 1, 3, 30, 2},
                {1, 2, 1, 3, 32, 2},   {1, 2, 1, 3, 30, 3},   {1, 2, 1, 3, 24, 3}};
            for (size_t i = 0; i < sizeof grid / sizeof *grid; i++) {
                tessel_cloud s2;
                tessel_smooth_params q = tessel_smooth_params_default();
                q.quadric = (int)grid[i][0];
                q.sigma_rho = grid[i][1], q.sigma_rho_later = grid[i][2];
                q.sigma_w = grid[i][3];
                q.k = (uint32_t)grid[i][4], q.passes = (uint32_t)grid[i][5];
                if (tessel_smooth(&c, &s2, &q, NULL, NULL) != TESSEL_OK)
                    return;
                double rr, mm;
                cloud_distance(&g, &s2, &rr, &mm);
                printf("| %s | %.1f | %.1f | %.1f | %u | %u | %.4f | %.2fx |\n",
                       q.quadric ? "quadric" : "plane", q.sigma_rho, q.sigma_rho_later,
                       q.sigma_w, q.k, q.passes, 100 * rr / diag, r0 / rr);
                tessel_cloud_free(&s2);
            }
            printf("\n%s, reduced size (smoothed cloud of %zu points):\n\n", names[f], s.count);
            printf("| n_min | sigma_max | max_diameter | representatives | reps RMS |\n");
            printf("|---|---|---|---|---|\n");
            static const double cg[][3] = {
                {10, 0.01, 8},    {10, 0.01, 4},        {10, 0.01, 12},
                {10, 0.002, 12},  {5, 0.002, 12},       {20, 0.002, 12},
                {10, 0.0005, 12}, {10, 0.01, INFINITY}, {10, 0.002, INFINITY}};
            for (size_t i = 0; i < sizeof cg / sizeof *cg; i++) {
                tessel_simplify_params q = tessel_simplify_params_default();
                q.cluster.n_min = (uint32_t)cg[i][0];
                q.cluster.sigma_max = cg[i][1];
                q.cluster.max_diameter = cg[i][2];
                tessel_cloud r3;
                if (tessel_simplify(&s, &r3, &q, NULL, NULL) != TESSEL_OK)
                    return;
                double rr, mm;
                cloud_distance(&g, &r3, &rr, &mm);
                printf("| %u | %g | %g | %zu | %.4f |\n", q.cluster.n_min, q.cluster.sigma_max,
                       q.cluster.max_diameter, r3.count, 100 * rr / diag);
                tessel_cloud_free(&r3);
            }
            printf("\n| data | points | h/diag %% | noisy RMS / max | smoothed RMS / max "
                   "(passes) | "
                   "gain | median gain | time | reps | reps RMS / max | time |\n");
            printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
        }
        for (size_t v = 0; v < N_AGG; v++) {
            tessel_cloud s2;
            tessel_smooth_params q = tessel_smooth_params_default();
            q.quadric = (int)agg_variants[v][0];
            q.aggregate = (int)agg_variants[v][1];
            q.passes = (uint32_t)agg_variants[v][2];
            q.sigma_w = agg_variants[v][3];
            q.exclude_self = (int)agg_variants[v][4];
            t0 = bench_now();
            if (tessel_smooth(&c, &s2, &q, NULL, NULL) != TESSEL_OK)
                return;
            agg_time[f][v] = bench_now() - t0;
            double rr, mm;
            cloud_distance(&g, &s2, &rr, &mm);
            agg_gain[f][v] = r0 / rr;
            tessel_cloud_free(&s2);
        }
        have[f] = true;
        tri_grid_free(&g);
        tessel_cloud_free(&r);
        tessel_cloud_free(&s);
        tessel_cloud_free(&c);
        tessel_mesh_free(&gt);
    }
    printf("\nAggregation and exclusion (params.aggregate, params.exclude_self): RMS gain "
           "(wall seconds)\n\n");
    printf("| operator | aggregate | passes | sigma_w | exclude self |");
    for (size_t f = 0; f < 3; f++)
        if (have[f])
            printf(" %s |", names[f]);
    printf("\n|---|---|---|---|---|");
    for (size_t f = 0; f < 3; f++)
        if (have[f])
            printf("---|");
    printf("\n");
    for (size_t v = 0; v < N_AGG; v++) {
        printf("| %s | %s | %.0f | %.1f | %s |", agg_variants[v][0] ? "quadric" : "plane",
               agg_variants[v][1] ? "yes" : "no", agg_variants[v][2], agg_variants[v][3],
               agg_variants[v][4] ? "yes" : "no");
        for (size_t f = 0; f < 3; f++)
            if (have[f])
                printf(" %.2fx (%.3f) |", agg_gain[f][v], agg_time[f][v]);
        printf("\n");
    }
    printf("\n");
}

/* ---- 3. sharp features ---- */

static double cube_distance(const float *p)
{
    double out2 = 0.0, inmax = -INFINITY;
    for (int d = 0; d < 3; d++) {
        double q = fabs(p[d]) - 1.0;
        if (q > 0)
            out2 += q * q;
        inmax = fmax(inmax, q);
    }
    return out2 > 0 ? sqrt(out2) : -inmax;
}
static double cube_edge_distance(const float *p)
{
    double best = INFINITY;
    for (int d = 0; d < 3; d++) {
        double x = 1.0 - fabs(p[(d + 1) % 3]), y = 1.0 - fabs(p[(d + 2) % 3]);
        best = fmin(best, sqrt(x * x + y * y));
    }
    return best;
}

static void bench_cube(void)
{
    const size_t side = 100; /* 60,000 points */
    const double diag = 2 * sqrt(3.0), noise = 0.005 * diag;
    tessel_cloud clean, c;
    if (tessel_cloud_alloc(&clean, 6 * side * side, 0, 0) != TESSEL_OK ||
        tessel_cloud_alloc(&c, 6 * side * side, 0, 0) != TESSEL_OK)
        return;
    size_t k = 0;
    for (int f = 0; f < 6; f++)
        for (size_t i = 0; i < side; i++)
            for (size_t j = 0; j < side; j++, k++) {
                double u = -1 + 2 * (i + 0.25 + 0.5 * urand()) / side;
                double v = -1 + 2 * (j + 0.25 + 0.5 * urand()) / side, p[3];
                int ax = f / 2;
                p[ax] = (f & 1) ? 1 : -1;
                p[(ax + 1) % 3] = u;
                p[(ax + 2) % 3] = v;
                for (int d = 0; d < 3; d++) {
                    clean.xyz[3 * k + d] = (float)p[d];
                    c.xyz[3 * k + d] = (float)(p[d] + noise * gauss());
                }
            }
    double h;
    tessel_cloud_spacing(&c, &h);
    printf("## Sharp features: cube [-1,1]^3, %zu points, Gaussian noise %.4f (0.5%% of the "
           "diagonal, %.2f h)\n\n",
           c.count, noise, noise / h);
    printf("RMS distance to the cube (in units of h = %.4f) by distance of the point's true "
           "position from the nearest edge:\n\n",
           h);
    printf("| operator | passes | < 1 h | 1-2 h | 2-4 h | > 4 h (faces) "
           "|\n|---|---|---|---|---|---|\n");
    const double bins[] = {1, 2, 4, INFINITY};
    for (int run = -1; run < 7; run++) {
        tessel_smooth_params p = tessel_smooth_params_default();
        tessel_cloud s;
        const tessel_cloud *src = &c;
        const char *name = "input";
        uint32_t passes = 0;
        if (run >= 0) {
            passes = p.passes = run % 2 ? 2 : 1;
            name = "robust quadric (defaults)";
            if (run >= 2 && run < 4) {
                p.quadric = 0;
                name = "robust plane (the paper)";
            } else if (run >= 4 && run < 6) {
                p.quadric = 0;
                p.sigma_rho = p.sigma_rho_later = 1e6;
                name = "plain weighted PCA plane";
            } else if (run == 6) {
                p.sigma_rho = 1.0;
                p.passes = passes = 2;
                name = "robust quadric, sigma_rho 1";
            }
            if (tessel_smooth(&c, &s, &p, NULL, NULL) != TESSEL_OK)
                return;
            src = &s;
        }
        double sum[4] = {0}, cnt[4] = {0};
        for (size_t i = 0; i < c.count; i++) {
            double e = cube_edge_distance(clean.xyz + 3 * i) / h,
                   d = cube_distance(src->xyz + 3 * i);
            int b = 0;
            while (e >= bins[b])
                b++;
            sum[b] += d * d;
            cnt[b]++;
        }
        printf("| %s | %u |", name, passes);
        for (int b = 0; b < 4; b++)
            printf(" %.3f |", sqrt(sum[b] / cnt[b]) / h);
        printf("\n");
        if (run >= 0)
            tessel_cloud_free(&s);
    }
    printf("\n");
    tessel_cloud_free(&c);
    tessel_cloud_free(&clean);
}

int main(int argc, char **argv)
{
    size_t n = 1000000;
    const char *dir = NULL;
    uint32_t passes = tessel_smooth_params_default().passes;
    int speed = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--n") && i + 1 < argc)
            n = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--data") && i + 1 < argc)
            dir = argv[++i];
        else if (!strcmp(argv[i], "--passes") && i + 1 < argc)
            passes = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--skip-speed"))
            speed = 0;
        else {
            fprintf(stderr, "usage: bench_smooth [--n POINTS] [--data DIR] [--passes P] "
                            "[--skip-speed]\n");
            return 1;
        }
    }
    printf("# bench_smooth (tessel %s)\n\n", tessel_version());
    if (speed && n >= 100)
        bench_speed(n);
    if (dir) {
        bench_data(dir, passes < 1 ? 1 : passes);
        bench_creases(dir);
    }
    bench_cube();
    return 0;
}
