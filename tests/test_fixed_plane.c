/* Fixed-plane reconstruction (src/fixed_plane/): height fields with known
 * heights (a plane, a paraboloid, a step that must stay open), a room
 * scanned from inside (range mode, unorganized), organized grids (a depth
 * camera, a full 360 degree scan), georeferenced offsets, determinism and
 * error handling. Every mesh is checked by an independent topology check
 * (edge- and vertex-manifold, oriented, boundary loops, Euler number) and
 * against the true surface. */
#include "test.h"
#include "tessel.h"

/* The CLI entry and its helpers, compiled in: the test calls it as tessel
 * reconstruct would. */
#include "../tools/cli.c"
#include "../tools/cmd_reconstruct_fixed.c"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PI 3.14159265358979323846

/* ---- random numbers (fixed seeds) ---- */

static uint64_t rng_state;
static uint64_t rng_next(void)
{
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
static double rng_uniform(void) { return (double)(rng_next() >> 11) * (1.0 / 9007199254740992.0); }
static double rng_gauss(void)
{
    double u = rng_uniform(), v = rng_uniform();
    if (u < 1e-300)
        u = 1e-300;
    return sqrt(-2.0 * log(u)) * cos(2.0 * PI * v);
}

/* ---- triangle collection ---- */

typedef struct tris {
    uint32_t *t;
    size_t n, cap;
} tris;

static tessel_status collect(void *user, const uint32_t *t, size_t count)
{
    tris *c = user;
    if (c->n + count > c->cap) {
        size_t cap = c->cap ? c->cap : 1024;
        while (cap < c->n + count)
            cap *= 2;
        uint32_t *p = realloc(c->t, cap * 3 * sizeof(uint32_t));
        if (!p)
            return TESSEL_ERR_NOMEM;
        c->t = p;
        c->cap = cap;
    }
    memcpy(c->t + 3 * c->n, t, count * 3 * sizeof(uint32_t));
    c->n += count;
    return TESSEL_OK;
}

static tessel_status run(const tessel_cloud *cloud, const tessel_fixed_plane_params *p, tris *out,
                         tessel_fixed_plane_stats *st)
{
    memset(out, 0, sizeof *out);
    tessel_triangle_sink sink = {collect, out};
    return tessel_reconstruct_fixed_plane(cloud, p, NULL, &sink, st);
}

/* ---- independent topology check ---- */

typedef struct topo {
    size_t vertices, edges, boundary_edges, boundary_loops;
    size_t nonmanifold_edges, nonmanifold_vertices, misoriented_edges, degenerate;
    long euler;
} topo;

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint32_t uf_find(uint32_t *par, uint32_t a)
{
    while (par[a] != a)
        a = par[a] = par[par[a]];
    return a;
}

static topo check_topology(const tris *m, size_t nverts)
{
    topo r;
    memset(&r, 0, sizeof r);
    size_t n = m->n;
    uint64_t *dir = malloc((3 * n + 1) * sizeof(uint64_t));
    uint64_t *und = malloc((3 * n + 1) * sizeof(uint64_t));
    uint8_t *used = calloc(nverts + 1, 1);
    for (size_t i = 0; i < n; i++) {
        const uint32_t *t = m->t + 3 * i;
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
            r.degenerate++;
        for (int k = 0; k < 3; k++) {
            uint32_t a = t[k], b = t[(k + 1) % 3];
            used[a] = 1;
            dir[3 * i + k] = (uint64_t)a << 32 | b;
            und[3 * i + k] = a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
        }
    }
    qsort(dir, 3 * n, sizeof(uint64_t), cmp_u64);
    qsort(und, 3 * n, sizeof(uint64_t), cmp_u64);
    for (size_t i = 1; i < 3 * n; i++)
        if (dir[i] == dir[i - 1])
            r.misoriented_edges++;
    /* boundary edges and their loops (union-find over boundary vertices) */
    uint32_t *par = malloc((nverts + 1) * sizeof(uint32_t));
    uint8_t *onb = calloc(nverts + 1, 1);
    for (size_t v = 0; v < nverts; v++)
        par[v] = (uint32_t)v;
    for (size_t i = 0; i < 3 * n;) {
        size_t j = i;
        while (j < 3 * n && und[j] == und[i])
            j++;
        r.edges++;
        if (j - i > 2)
            r.nonmanifold_edges++;
        if (j - i == 1) {
            r.boundary_edges++;
            uint32_t a = (uint32_t)(und[i] >> 32), b = (uint32_t)und[i];
            onb[a] = onb[b] = 1;
            par[uf_find(par, a)] = uf_find(par, b);
        }
        i = j;
    }
    for (size_t v = 0; v < nverts; v++) {
        r.vertices += used[v];
        if (onb[v] && uf_find(par, (uint32_t)v) == v)
            r.boundary_loops++;
    }
    r.euler = (long)r.vertices - (long)r.edges + (long)n;
    /* vertex manifoldness: the link of each vertex is connected */
    size_t *start = calloc(nverts + 2, sizeof(size_t));
    for (size_t i = 0; i < 3 * n; i++)
        start[m->t[i] + 1]++;
    for (size_t v = 0; v < nverts; v++)
        start[v + 1] += start[v];
    uint32_t *inc = malloc((3 * n + 1) * sizeof(uint32_t));
    size_t *fill = malloc((nverts + 1) * sizeof(size_t));
    memcpy(fill, start, (nverts + 1) * sizeof(size_t));
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++)
            inc[fill[m->t[3 * i + k]]++] = (uint32_t)i;
    uint32_t *lpar = malloc((nverts + 1) * sizeof(uint32_t));
    uint32_t *mark = calloc(nverts + 1, sizeof(uint32_t));
    for (size_t v = 0; v < nverts; v++)
        lpar[v] = (uint32_t)v;
    for (size_t v = 0; v < nverts; v++) {
        if (!used[v])
            continue;
        /* union link vertices of each incident triangle */
        for (size_t k = start[v]; k < start[v + 1]; k++) {
            const uint32_t *t = m->t + 3 * inc[k];
            uint32_t a = TESSEL_NONE, b = TESSEL_NONE;
            for (int j = 0; j < 3; j++) {
                if (t[j] == v)
                    continue;
                if (a == TESSEL_NONE)
                    a = t[j];
                else
                    b = t[j];
            }
            if (a != TESSEL_NONE && b != TESSEL_NONE)
                lpar[uf_find(lpar, a)] = uf_find(lpar, b);
        }
        size_t comps = 0;
        for (size_t k = start[v]; k < start[v + 1]; k++) {
            const uint32_t *t = m->t + 3 * inc[k];
            for (int j = 0; j < 3; j++) {
                if (t[j] == v || mark[t[j]] == v + 1)
                    continue;
                mark[t[j]] = (uint32_t)v + 1;
                comps += uf_find(lpar, t[j]) == t[j];
            }
        }
        if (comps > 1)
            r.nonmanifold_vertices++;
        /* reset the link vertices */
        for (size_t k = start[v]; k < start[v + 1]; k++) {
            const uint32_t *t = m->t + 3 * inc[k];
            for (int j = 0; j < 3; j++)
                lpar[t[j]] = t[j];
        }
    }
    free(mark);
    free(lpar);
    free(fill);
    free(inc);
    free(start);
    free(onb);
    free(par);
    free(used);
    free(dir);
    free(und);
    return r;
}

static int topology_ok(const topo *t)
{
    return t->nonmanifold_edges == 0 && t->nonmanifold_vertices == 0 &&
           t->misoriented_edges == 0 && t->degenerate == 0;
}

/* The library's own mesh check (exact self-intersection test) on the mesh
 * output: valid, and the same triangles as the streamed ones. */
static void check_mesh_valid(const tessel_cloud *c, const tessel_fixed_plane_params *p,
                             const tris *streamed, const char *what)
{
    tessel_mesh mesh;
    tessel_fixed_plane_stats st;
    CHECK(tessel_reconstruct_fixed_plane_mesh(c, p, NULL, &mesh, &st) == TESSEL_OK);
    CHECK_MSG(mesh.triangle_count == streamed->n, "%s: %zu vs %zu triangles", what,
              mesh.triangle_count, streamed->n);
    tessel_check_params cp = tessel_check_params_default();
    tessel_mesh_report r;
    CHECK(tessel_mesh_check(&mesh, &cp, &r) == TESSEL_OK);
    CHECK_MSG(tessel_mesh_report_valid(&r),
              "%s: nm edges %zu nm vertices %zu conflicts %zu self-intersections %zu "
              "duplicates %zu degenerate %zu",
              what, r.nonmanifold_edges, r.nonmanifold_vertices, r.orientation_conflicts,
              r.self_intersections, r.duplicate_triangles, r.degenerate_triangles);
    CHECK(r.unreferenced_vertices == 0);
    tessel_mesh_free(&mesh);
}

static void tri_normal(const tessel_cloud *c, const uint32_t *t, double n[3], double ctr[3])
{
    const float *a = c->xyz + 3 * (size_t)t[0], *b = c->xyz + 3 * (size_t)t[1],
                *d = c->xyz + 3 * (size_t)t[2];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double e2[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    for (int k = 0; k < 3; k++)
        ctr[k] = (a[k] + b[k] + d[k]) / 3.0;
}

/* ---- height fields ---- */

typedef double (*height_fn)(double x, double y);
static double h_plane(double x, double y) { return 0.3 * x - 0.2 * y + 1.0; }
static double h_parab(double x, double y) { return 0.5 * ((x - 0.5) * (x - 0.5) + (y - 0.5) * (y - 0.5)); }
static double h_ramp(double x, double y)
{
    (void)y;
    return x < 0.5 ? 0.0 : x < 0.55 ? x - 0.5 : 0.05;
}
static double h_step(double x, double y)
{
    (void)y;
    return x < 0.5 ? 0.0 : 0.4;
}

/* n points on [0,1]^2 with heights f + noise: uniformly at random, or
 * (jittered) on a sqrt(n) x sqrt(n) lattice, each moved at random within
 * its lattice cell, like the even spacing of airborne LIDAR. */
static void make_terrain_sampled(tessel_cloud *c, size_t n, height_fn f, double sigma,
                                 uint64_t seed, int jittered)
{
    rng_state = seed;
    size_t side = (size_t)sqrt((double)n);
    if (jittered)
        n = side * side;
    tessel_cloud_alloc(c, n, 0, 0);
    for (size_t i = 0; i < n; i++) {
        double x = rng_uniform(), y = rng_uniform();
        if (jittered) {
            x = ((double)(i % side) + x) / (double)side;
            y = ((double)(i / side) + y) / (double)side;
        }
        c->xyz[3 * i] = (float)x;
        c->xyz[3 * i + 1] = (float)y;
        c->xyz[3 * i + 2] = (float)(f(x, y) + sigma * rng_gauss());
    }
}

static void make_terrain(tessel_cloud *c, size_t n, height_fn f, double sigma, uint64_t seed)
{
    make_terrain_sampled(c, n, f, sigma, seed, 1);
}

static void test_plane(void)
{
    tessel_cloud c;
    make_terrain(&c, 20000, h_plane, 0.0, 1);
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.axis = 2;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    topo t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    CHECK_MSG(t.boundary_loops == 1, "loops %zu", t.boundary_loops);
    CHECK_MSG(t.euler == 1, "euler %ld", t.euler); /* a disk */
    CHECK(st.triangles == m.n);
    CHECK(st.representatives > 5000 && st.representatives < 20000);
    /* representatives: one per occupied dexel, each a used vertex */
    CHECK(t.vertices <= st.representatives);
    CHECK_MSG(t.vertices > 0.99 * st.representatives, "%zu of %zu", t.vertices,
              st.representatives);
    /* nearly every block triangulated: the disk has no inner holes */
    CHECK_MSG(st.triangles > 1.9 * (double)(st.columns - 1) * (st.rows - 1) -
                                 2.0 * (double)st.cells_missing,
              "triangles %zu", st.triangles);
    CHECK(st.cells_open == 0);
    CHECK_MSG(st.noise < 1e-5, "noise %g", st.noise);
    /* every triangle is up-facing and lies in the plane */
    int up = 1;
    double maxerr = 0;
    for (size_t i = 0; i < m.n; i++) {
        double n[3], ctr[3];
        tri_normal(&c, m.t + 3 * i, n, ctr);
        if (!(n[2] > 0))
            up = 0;
        double e = fabs(ctr[2] - h_plane(ctr[0], ctr[1]));
        if (e > maxerr)
            maxerr = e;
    }
    CHECK(up);
    CHECK_MSG(maxerr < 1e-5, "max error %g", maxerr);
    check_mesh_valid(&c, &p, &m, "plane");

    /* The plane of least variance is the same plane: same result up to
     * the in-plane frame, so the same numbers of triangles +-5%. */
    tessel_fixed_plane_params q = tessel_fixed_plane_params_default();
    tris m2;
    tessel_fixed_plane_stats st2;
    CHECK(run(&c, &q, &m2, &st2) == TESSEL_OK);
    double nz = 1.0 / sqrt(1 + 0.09 + 0.04);
    CHECK_MSG(fabs(st2.axis[2] - nz) < 1e-3 && fabs(st2.axis[0] + 0.3 * nz) < 1e-3,
              "axis %g %g %g", st2.axis[0], st2.axis[1], st2.axis[2]);
    topo t2 = check_topology(&m2, c.count);
    CHECK(topology_ok(&t2));
    CHECK(t2.boundary_loops == 1);
    for (size_t i = 0; i < m2.n; i++) {
        double n[3], ctr[3];
        tri_normal(&c, m2.t + 3 * i, n, ctr);
        if (!(n[0] * st2.axis[0] + n[1] * st2.axis[1] + n[2] * st2.axis[2] > 0)) {
            CHECK_MSG(0, "triangle %zu not facing +normal", i);
            break;
        }
    }
    free(m2.t);
    free(m.t);
    tessel_cloud_free(&c);
}

static void test_paraboloid_noise(void)
{
    const double sigma = 0.002;
    tessel_cloud c;
    make_terrain(&c, 40000, h_parab, sigma, 2);
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.axis = 2;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    topo t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    CHECK_MSG(t.boundary_loops == 1 && t.euler == 1, "loops %zu euler %ld", t.boundary_loops,
              t.euler);
    CHECK(st.noise_estimated);
    CHECK_MSG(st.noise > 0.7 * sigma && st.noise < 1.4 * sigma, "noise %g vs %g", st.noise,
              sigma);
    /* centroids within the noise of the true surface */
    double sum = 0, maxerr = 0;
    for (size_t i = 0; i < m.n; i++) {
        double n[3], ctr[3];
        tri_normal(&c, m.t + 3 * i, n, ctr);
        double e = fabs(ctr[2] - h_parab(ctr[0], ctr[1]));
        sum += e;
        if (e > maxerr)
            maxerr = e;
        if (!(n[2] > 0)) {
            CHECK_MSG(0, "triangle %zu faces down", i);
            break;
        }
    }
    CHECK_MSG(sum / m.n < sigma, "mean error %g", sum / m.n);
    CHECK_MSG(maxerr < 5 * sigma, "max error %g", maxerr);
    check_mesh_valid(&c, &p, &m, "paraboloid");
    /* an explicit grid: exactly columns x rows dexels */
    p.columns = 50;
    p.rows = 40;
    tris m2;
    CHECK(run(&c, &p, &m2, &st) == TESSEL_OK);
    CHECK(st.columns == 50 && st.rows == 40);
    CHECK(st.representatives == 2000);
    CHECK_MSG(m2.n == 2 * 49 * 39, "triangles %zu", m2.n);
    free(m2.t);
    free(m.t);
    tessel_cloud_free(&c);
}

static void test_step_open(void)
{
    tessel_cloud c;
    make_terrain(&c, 20000, h_step, 0.001, 3);
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.axis = 2;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    topo t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    /* two pieces, each a disk; no triangle climbs the step */
    CHECK_MSG(t.boundary_loops == 2 && t.euler == 2, "loops %zu euler %ld", t.boundary_loops,
              t.euler);
    size_t bridging = 0;
    for (size_t i = 0; i < m.n; i++) {
        float lo = 1e9f, hi = -1e9f;
        for (int k = 0; k < 3; k++) {
            float z = c.xyz[3 * (size_t)m.t[3 * i + k] + 2];
            lo = z < lo ? z : lo;
            hi = z > hi ? z : hi;
        }
        bridging += hi - lo > 0.2f;
    }
    CHECK_MSG(bridging == 0, "%zu triangles bridge the step", bridging);
    CHECK(st.cells_open > 0);
    check_mesh_valid(&c, &p, &m, "step");
    free(m.t);
    tessel_cloud_free(&c);
    /* the same step as a 45 degree ramp 0.05 wide: a slope, joined */
    make_terrain(&c, 20000, h_ramp, 0.001, 3);
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    CHECK_MSG(t.boundary_loops == 1 && t.euler == 1, "ramp: loops %zu euler %ld",
              t.boundary_loops, t.euler);
    free(m.t);
    tessel_cloud_free(&c);
}

/* ---- a room scanned from inside ---- */

typedef struct scene {
    double lo[3], hi[3];       /* the room box */
    double sc[3], sr;          /* a sphere */
    double blo[3], bhi[3];     /* a free-standing block */
    double vp[3];
} scene;

/* Both objects float, so that any triangle joining two of them is wrong. */
static const scene room = {
    {0, 0, 0}, {6, 4, 3}, {4.2, 2.5, 1.2}, 0.5, {1.0, 0.6, 0.4}, {2.0, 1.4, 1.0}, {3.0, 2.0, 1.5}};

/* Distance from p to the surface of object obj. */
static double object_distance(const scene *s, int obj, const double p[3])
{
    if (obj == 1) {
        double d[3] = {p[0] - s->sc[0], p[1] - s->sc[1], p[2] - s->sc[2]};
        return fabs(sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - s->sr);
    }
    const double *lo = obj == 0 ? s->lo : s->blo, *hi = obj == 0 ? s->hi : s->bhi;
    double out2 = 0, in = INFINITY;
    for (int k = 0; k < 3; k++) {
        double e = p[k] < lo[k] ? lo[k] - p[k] : p[k] > hi[k] ? p[k] - hi[k] : 0;
        out2 += e * e;
        in = fmin(in, fmin(p[k] - lo[k], hi[k] - p[k]));
    }
    return out2 > 0 ? sqrt(out2) : in;
}

/* Distance along unit d from the viewpoint to the first surface; *obj =
 * 0 walls, 1 sphere, 2 block. */
static double cast(const scene *s, const double d[3], int *obj)
{
    double best = INFINITY;
    *obj = 0;
    for (int k = 0; k < 3; k++) {
        if (d[k] > 0)
            best = fmin(best, (s->hi[k] - s->vp[k]) / d[k]);
        else if (d[k] < 0)
            best = fmin(best, (s->lo[k] - s->vp[k]) / d[k]);
    }
    double oc[3] = {s->vp[0] - s->sc[0], s->vp[1] - s->sc[1], s->vp[2] - s->sc[2]};
    double b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    double cc = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - s->sr * s->sr;
    double disc = b * b - cc;
    if (disc > 0) {
        double t = -b - sqrt(disc);
        if (t > 0 && t < best) {
            best = t;
            *obj = 1;
        }
    }
    double t0 = 0, t1 = INFINITY;
    int hit = 1;
    for (int k = 0; k < 3 && hit; k++) {
        if (d[k] == 0) {
            if (s->vp[k] < s->blo[k] || s->vp[k] > s->bhi[k])
                hit = 0;
            continue;
        }
        double a = (s->blo[k] - s->vp[k]) / d[k], e = (s->bhi[k] - s->vp[k]) / d[k];
        if (a > e) {
            double tmp = a;
            a = e;
            e = tmp;
        }
        t0 = fmax(t0, a);
        t1 = fmin(t1, e);
        if (t0 > t1)
            hit = 0;
    }
    if (hit && t0 > 0 && t0 < best) {
        best = t0;
        *obj = 2;
    }
    return best;
}

/* A (theta, phi) scan: rows x cols rays, theta from 0 to pi, range noise
 * sigma; labels[i] is the object of point i. organized: grid set (rows of
 * constant phi... row-major cols x rows as a PCD would store it). */
static void scan_room(tessel_cloud *c, uint8_t **labels, uint32_t cols, uint32_t rows,
                      double sigma, int organized, double jitter, uint64_t seed)
{
    rng_state = seed;
    size_t n = (size_t)cols * rows;
    tessel_cloud_alloc(c, n, 0, 0);
    *labels = malloc(n);
    if (organized) {
        c->width = cols;
        c->height = rows;
        c->grid = malloc(n * sizeof(uint32_t));
    }
    for (uint32_t r = 0; r < rows; r++) {
        for (uint32_t k = 0; k < cols; k++) {
            double th = (k + 0.5 + jitter * (rng_uniform() - 0.5)) * PI / cols;
            double ph = (r + 0.5 + jitter * (rng_uniform() - 0.5)) * 2 * PI / rows;
            double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
            int obj;
            double t = cast(&room, d, &obj) + sigma * rng_gauss();
            size_t i = (size_t)r * cols + k;
            for (int j = 0; j < 3; j++)
                c->xyz[3 * i + j] = (float)(room.vp[j] + t * d[j]);
            (*labels)[i] = (uint8_t)obj;
            if (organized)
                c->grid[i] = (uint32_t)i;
        }
    }
    c->has_viewpoint = 1;
    memcpy(c->viewpoint, room.vp, sizeof c->viewpoint);
}

/* Checks a scan's mesh: topology, facing the viewpoint, no triangle
 * joining two objects, centroids near the true surface. */
static void check_scan_mesh(const tessel_cloud *c, const uint8_t *labels, const tris *m,
                            double sigma, const char *what)
{
    topo t = check_topology(m, c->count);
    CHECK_MSG(topology_ok(&t), "%s: nm edges %zu nm vertices %zu misoriented %zu degenerate %zu",
              what, t.nonmanifold_edges, t.nonmanifold_vertices, t.misoriented_edges,
              t.degenerate);
    size_t away = 0, bridge = 0, far = 0;
    double sum = 0;
    for (size_t i = 0; i < m->n; i++) {
        const uint32_t *tr = m->t + 3 * i;
        double n[3], ctr[3];
        tri_normal(c, tr, n, ctr);
        double tovp[3] = {room.vp[0] - ctr[0], room.vp[1] - ctr[1], room.vp[2] - ctr[2]};
        if (!(n[0] * tovp[0] + n[1] * tovp[1] + n[2] * tovp[2] > 0))
            away++;
        if (labels[tr[0]] != labels[tr[1]] || labels[tr[1]] != labels[tr[2]])
            bridge++;
        double e = object_distance(&room, labels[tr[0]], ctr);
        sum += e;
        /* a triangle across a crease (room corners, block edges) cuts it by
         * up to a third of its size */
        double longest = 0;
        for (int k = 0; k < 3; k++) {
            const float *a = c->xyz + 3 * (size_t)tr[k], *b = c->xyz + 3 * (size_t)tr[(k + 1) % 3];
            double l = sqrt((double)(a[0] - b[0]) * (a[0] - b[0]) +
                            (double)(a[1] - b[1]) * (a[1] - b[1]) +
                            (double)(a[2] - b[2]) * (a[2] - b[2]));
            longest = fmax(longest, l);
        }
        far += e > 6 * sigma + longest / 3;
    }
    CHECK_MSG(away == 0, "%s: %zu of %zu triangles face away from the viewpoint", what, away,
              m->n);
    CHECK_MSG(bridge == 0, "%s: %zu triangles bridge two objects", what, bridge);
    CHECK_MSG(far == 0, "%s: %zu triangles off the surface", what, far);
    CHECK_MSG(m->n == 0 || sum / m->n < 1.2 * sigma, "%s: mean distance %g (sigma %g)", what,
              sum / m->n, sigma);
}

/* Uniform random sampling has one-dexel gaps everywhere: filled from
 * neighbouring dexels, they leave only a few holes. */
static void test_uniform_sampling(void)
{
    tessel_cloud c;
    make_terrain_sampled(&c, 40000, h_parab, 0.002, 10, 0);
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.axis = 2;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    topo t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    CHECK(st.dexels_filled > 0);
    long holes = 1 - t.euler;
    CHECK_MSG(holes >= 0 && holes < (long)(st.representatives / 400), "%ld holes", holes);
    check_mesh_valid(&c, &p, &m, "uniform");
    free(m.t);
    tessel_cloud_free(&c);
}

/* A lattice with one or two points per site at heights one step apart
 * (two interleaved layers, no height field), flat and on a slope. Filled
 * dexels then take points that lie exactly on a neighbour's edge; before
 * the exact test in space, their triangles met those edges in T-junctions
 * (3 to 25 self-intersecting pairs on such clouds). */
static void test_lattice_layers(void)
{
    for (int slope = 0; slope < 2; slope++) {
        for (uint64_t seed = 1; seed <= 3; seed++) {
            enum { N = 200 };
            tessel_cloud c;
            CHECK(tessel_cloud_alloc(&c, 2 * N * N, 0, 0) == TESSEL_OK);
            rng_state = seed;
            size_t n = 0;
            for (int i = 0; i < N; i++)
                for (int j = 0; j < N; j++) {
                    int copies = 1 + (int)(rng_next() % 2);
                    for (int k = 0; k < copies; k++) {
                        c.xyz[3 * n] = (float)i;
                        c.xyz[3 * n + 1] = (float)j;
                        c.xyz[3 * n + 2] =
                            (float)(slope ? 0.1 * i + 0.05 * j : 0.0) + (float)(rng_next() % 2);
                        n++;
                    }
                }
            c.count = n;
            tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
            tris m;
            tessel_fixed_plane_stats st;
            CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
            CHECK(st.dexels_filled > 0);
            topo t = check_topology(&m, c.count);
            CHECK(topology_ok(&t));
            check_mesh_valid(&c, &p, &m, slope ? "lattice layers on a slope" : "lattice layers");
            free(m.t);
            tessel_cloud_free(&c);
        }
    }
}

static void test_range_room(void)
{
    const double sigma = 0.004;
    tessel_cloud c;
    uint8_t *labels;
    scan_room(&c, &labels, 200, 400, sigma, 0, 0.8, 4);
    /* shuffle: range mode must not depend on the input order */
    for (size_t i = c.count - 1; i > 0; i--) {
        size_t j = rng_next() % (i + 1);
        for (int k = 0; k < 3; k++) {
            float tmp = c.xyz[3 * i + k];
            c.xyz[3 * i + k] = c.xyz[3 * j + k];
            c.xyz[3 * j + k] = tmp;
        }
        uint8_t l = labels[i];
        labels[i] = labels[j];
        labels[j] = l;
    }
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_RANGE;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    CHECK(st.wrap_columns + st.wrap_rows == 1); /* phi wraps, whichever way stored */
    CHECK(st.triangles > 0 && st.triangles == m.n);
    CHECK_MSG(st.noise > 0.6 * sigma && st.noise < 1.6 * sigma, "noise %g", st.noise);
    check_scan_mesh(&c, labels, &m, sigma, "range");
    check_mesh_valid(&c, &p, &m, "range");
    topo t = check_topology(&m, c.count);
    /* the sphere and the block come out as separate pieces: at least 3
     * components means at least 3 boundary loops (plus the poles) */
    CHECK_MSG(t.boundary_loops >= 3, "loops %zu", t.boundary_loops);

    /* the same with two threads and with one: identical */
    tessel_fixed_plane_params p1 = p, p2 = p;
    p1.threads = 1;
    p2.threads = 2;
    tris a, b;
    CHECK(run(&c, &p1, &a, NULL) == TESSEL_OK);
    CHECK(run(&c, &p2, &b, NULL) == TESSEL_OK);
    CHECK(a.n == b.n && a.n == m.n && memcmp(a.t, b.t, a.n * 12) == 0 &&
          memcmp(a.t, m.t, a.n * 12) == 0);
    free(a.t);
    free(b.t);

    /* a viewpoint is needed */
    c.has_viewpoint = 0;
    tris e;
    CHECK(run(&c, &p, &e, NULL) == TESSEL_ERR_INVALID_ARG);
    free(e.t);
    p.use_viewpoint = 1;
    memcpy(p.viewpoint, room.vp, sizeof p.viewpoint);
    tris f;
    CHECK(run(&c, &p, &f, NULL) == TESSEL_OK && f.n == m.n);
    free(f.t);
    free(m.t);
    free(labels);
    tessel_cloud_free(&c);
}

static void test_grid_room(void)
{
    const double sigma = 0.004;
    tessel_cloud c;
    uint8_t *labels;
    scan_room(&c, &labels, 150, 300, sigma, 1, 0.0, 5);
    /* a few missing returns */
    size_t missing = 0;
    for (size_t i = 0; i < c.count; i += 97) {
        c.grid[i] = TESSEL_NONE;
        missing++;
    }
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_GRID;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    CHECK(st.representatives == c.count - missing);
    CHECK_MSG(st.wrap_rows == 1 && st.wrap_columns == 0, "wrap %d %d", st.wrap_rows,
              st.wrap_columns);
    check_scan_mesh(&c, labels, &m, sigma, "grid");
    check_mesh_valid(&c, &p, &m, "grid");
    CHECK_MSG(st.noise > 0.8 * sigma && st.noise < 1.25 * sigma, "grid noise %g", st.noise);
    /* every triangle uses only grid points; none a missing one */
    int ok = 1;
    for (size_t i = 0; i < c.count; i += 97)
        for (size_t k = 0; k < 3 * m.n; k++)
            if (m.t[k] == i)
                ok = 0;
    CHECK(ok);
    /* holes: the missing points, the two poles and the discontinuities */
    topo t = check_topology(&m, c.count);
    CHECK_MSG(t.boundary_loops <= missing + 2 + 40, "loops %zu", t.boundary_loops);

    /* an unorganized cloud is rejected, with a message */
    free(c.grid);
    c.grid = NULL;
    c.width = c.height = 0;
    tris e;
    CHECK(run(&c, &p, &e, NULL) == TESSEL_ERR_INVALID_ARG);
    free(e.t);
    free(m.t);
    free(labels);
    tessel_cloud_free(&c);
}

/* A full (theta, phi) scan leaves a ring of points half a step from each
 * pole; both rings are closed, and the result stays valid. */
static void test_poles(void)
{
    tessel_cloud c;
    uint8_t *labels;
    scan_room(&c, &labels, 100, 200, 0.004, 1, 0.0, 13);
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_GRID;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    CHECK_MSG(st.poles_closed == 2, "%d poles closed", st.poles_closed);
    topo t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    check_scan_mesh(&c, labels, &m, 0.004, "poles");
    check_mesh_valid(&c, &p, &m, "poles");
    /* every ring point now has a closed fan: no boundary edge joins two
     * points of the first column */
    size_t ring_boundary = 0;
    for (size_t i = 0; i < m.n; i++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = m.t[3 * i + k], b = m.t[3 * i + (k + 1) % 3];
            if (a % 100 != 0 || b % 100 != 0)
                continue;
            int twin = 0;
            for (size_t j = 0; j < m.n && !twin; j++)
                for (int q = 0; q < 3; q++)
                    twin |= m.t[3 * j + q] == b && m.t[3 * j + (q + 1) % 3] == a;
            ring_boundary += !twin;
        }
    CHECK_MSG(ring_boundary == 0, "%zu open ring edges", ring_boundary);
    free(m.t);
    free(labels);
    tessel_cloud_free(&c);
}

/* A pinhole depth camera looking along +z at a wall with a box in front,
 * NaN (missing) where nothing was returned. */
static void count_warnings(void *user, tessel_log_level level, const char *message)
{
    (void)message;
    *(int *)user += level == TESSEL_LOG_WARNING;
}

static void test_grid_camera(void)
{
    const uint32_t W = 160, H = 120;
    const double f = 140.0, sigma = 0.002;
    tessel_cloud c;
    tessel_cloud_alloc(&c, (size_t)W * H, 0, 0);
    c.width = W;
    c.height = H;
    c.grid = malloc((size_t)W * H * sizeof(uint32_t));
    uint8_t *labels = malloc((size_t)W * H);
    rng_state = 6;
    size_t n = 0;
    for (uint32_t v = 0; v < H; v++) {
        for (uint32_t u = 0; u < W; u++) {
            double x = (u - W / 2.0) / f, y = (v - H / 2.0) / f;
            double z = 3.0;
            int obj = 0;
            if (fabs(x * 1.5) < 0.4 && fabs(y * 1.5) < 0.3) {
                z = 1.5; /* the box front */
                obj = 1;
            }
            if (u < 6 && v < 6) { /* no return in a corner */
                c.grid[(size_t)v * W + u] = TESSEL_NONE;
                continue;
            }
            z += sigma * rng_gauss();
            c.xyz[3 * n] = (float)(x * z);
            c.xyz[3 * n + 1] = (float)(y * z);
            c.xyz[3 * n + 2] = (float)z;
            labels[n] = (uint8_t)obj;
            c.grid[(size_t)v * W + u] = (uint32_t)n;
            n++;
        }
    }
    c.count = n;
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_GRID;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK); /* no viewpoint: the origin */
    CHECK(st.wrap_rows == 0 && st.wrap_columns == 0);
    topo t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    /* the wall's outline and the hole the box leaves in it; the box */
    CHECK_MSG(t.boundary_loops == 3, "loops %zu", t.boundary_loops);
    CHECK_MSG(t.euler == 1, "euler %ld", t.euler); /* annulus 0 + disk 1 */
    size_t away = 0, bridge = 0;
    for (size_t i = 0; i < m.n; i++) {
        const uint32_t *tr = m.t + 3 * i;
        double nn[3], ctr[3];
        tri_normal(&c, tr, nn, ctr);
        if (!(nn[0] * -ctr[0] + nn[1] * -ctr[1] + nn[2] * -ctr[2] > 0))
            away++;
        bridge += labels[tr[0]] != labels[tr[1]] || labels[tr[1]] != labels[tr[2]];
    }
    CHECK_MSG(away == 0, "%zu facing away", away);
    CHECK_MSG(bridge == 0, "%zu bridging", bridge);
    /* almost all cells triangulated apart from the box outline */
    CHECK_MSG(m.n > 2 * (W - 1) * (H - 1) - 2 * 2 * (160 + 120) - 2 * 49,
              "triangles %zu", m.n);

    free(m.t);
    memset(&m, 0, sizeof m);

    /* The same points with the grid scrambled are no camera image: most
     * triangles face away, and the library says so (the camera's own grid
     * above: no warning). */
    int warned = 0;
    tessel_callbacks cb = {NULL, count_warnings, &warned};
    CHECK(tessel_reconstruct_fixed_plane(&c, &p, &cb, &(tessel_triangle_sink){collect, &m},
                                         &st) == TESSEL_OK);
    CHECK(warned == 0);
    free(m.t);
    memset(&m, 0, sizeof m);
    for (size_t i = (size_t)W * H - 1; i > 0; i--) {
        size_t j = rng_next() % (i + 1);
        uint32_t g = c.grid[i];
        c.grid[i] = c.grid[j];
        c.grid[j] = g;
    }
    CHECK(tessel_reconstruct_fixed_plane(&c, &p, &cb, &(tessel_triangle_sink){collect, &m},
                                         &st) == TESSEL_OK);
    CHECK_MSG(warned == 1 && st.triangles_folded > st.triangles, "warned %d, folded %zu of %zu",
              warned, st.triangles_folded, st.triangles_folded + st.triangles);
    topo ts = check_topology(&m, c.count);
    CHECK(topology_ok(&ts));
    free(m.t);
    free(labels);
    tessel_cloud_free(&c);
}

/* Shorter diagonal, exactly: a 2x2 grid whose quad is a kite. */
static void test_grid_diagonal(void)
{
    tessel_cloud c;
    tessel_cloud_alloc(&c, 4, 0, 0);
    c.width = 2;
    c.height = 2;
    c.grid = malloc(4 * sizeof(uint32_t));
    /* A (0,0) B (1,0) C (0,1) D (1,1) in a plane z = 5, D pulled towards A:
     * A-D is shorter than B-C */
    const float pts[4][3] = {{0, 0, 5}, {1, 0, 5}, {0, 1, 5}, {0.6f, 0.6f, 5}};
    for (int i = 0; i < 4; i++) {
        memcpy(c.xyz + 3 * i, pts[i], sizeof pts[i]);
        c.grid[i] = (uint32_t)i;
    }
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_GRID;
    p.noise = 1e-6;
    tris m;
    CHECK(run(&c, &p, &m, NULL) == TESSEL_OK);
    CHECK(m.n == 2);
    int has_ad = 0;
    for (size_t i = 0; i < m.n; i++) {
        int a = 0, d = 0;
        for (int k = 0; k < 3; k++) {
            a |= m.t[3 * i + k] == 0;
            d |= m.t[3 * i + k] == 3;
        }
        has_ad += a && d;
    }
    CHECK(has_ad == 2);
    free(m.t);
    /* now D pulled away: B-C is shorter */
    c.xyz[9] = 1.4f;
    c.xyz[10] = 1.4f;
    CHECK(run(&c, &p, &m, NULL) == TESSEL_OK);
    CHECK(m.n == 2);
    int has_bc = 0;
    for (size_t i = 0; i < m.n; i++) {
        int b = 0, cc = 0;
        for (int k = 0; k < 3; k++) {
            b |= m.t[3 * i + k] == 1;
            cc |= m.t[3 * i + k] == 2;
        }
        has_bc += b && cc;
    }
    CHECK(has_bc == 2);
    free(m.t);
    tessel_cloud_free(&c);
}

/* A vertex whose triangles would form two fans touching only at the
 * vertex (a bowtie) keeps one fan. 3x3 grid on the plane z = 10 seen from
 * the origin with (0,1), (0,2), (2,0), (2,1) missing: the NW block makes
 * (0,0)-(1,1)-(1,0), the SE block (1,1)-(1,2)-(2,2); they share only the
 * centre. */
static void test_vertex_manifold(void)
{
    tessel_cloud c;
    tessel_cloud_alloc(&c, 9, 0, 0);
    c.width = 3;
    c.height = 3;
    c.grid = malloc(9 * sizeof(uint32_t));
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++) {
            int i = r * 3 + k;
            c.xyz[3 * i] = (float)k;
            c.xyz[3 * i + 1] = (float)r;
            c.xyz[3 * i + 2] = 10.0f;
            c.grid[i] = (uint32_t)i;
        }
    c.grid[1] = c.grid[2] = c.grid[6] = c.grid[7] = TESSEL_NONE;
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_GRID;
    tris m;
    tessel_fixed_plane_stats st;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    CHECK_MSG(m.n == 1 && st.triangles_nonmanifold == 1, "%zu triangles, %zu removed", m.n,
              st.triangles_nonmanifold);
    topo t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    /* without the fix the two would be there: drop a missing corner back
     * in and both blocks join through it */
    free(m.t);
    c.grid[7] = 7;
    CHECK(run(&c, &p, &m, &st) == TESSEL_OK);
    CHECK_MSG(m.n == 4 && st.triangles_nonmanifold == 0, "%zu triangles", m.n);
    t = check_topology(&m, c.count);
    CHECK(topology_ok(&t));
    free(m.t);
    tessel_cloud_free(&c);
}

/* ---- georeferenced offsets, translation invariance ---- */

static void test_offset(void)
{
    tessel_cloud c;
    make_terrain(&c, 5000, h_parab, 0.001, 7);
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.axis = 2;
    tris a;
    CHECK(run(&c, &p, &a, NULL) == TESSEL_OK);
    /* the same local coordinates under a UTM-sized offset */
    c.offset[0] = 637000.0;
    c.offset[1] = 851000.0;
    c.offset[2] = 120.0;
    tris b;
    CHECK(run(&c, &p, &b, NULL) == TESSEL_OK);
    CHECK(a.n == b.n && memcmp(a.t, b.t, a.n * 12) == 0);
    /* the mesh keeps the offset and the exact local floats */
    tessel_mesh mesh;
    tessel_fixed_plane_stats st;
    CHECK(tessel_reconstruct_fixed_plane_mesh(&c, &p, NULL, &mesh, &st) == TESSEL_OK);
    CHECK(mesh.offset[0] == 637000.0 && mesh.offset[1] == 851000.0 && mesh.offset[2] == 120.0);
    CHECK(mesh.triangle_count == a.n);
    int same = 1;
    for (size_t i = 0; i < a.n * 3 && same; i++) {
        const float *p0 = c.xyz + 3 * (size_t)a.t[i];
        const float *p1 = mesh.xyz + 3 * (size_t)mesh.triangles[i];
        same = memcmp(p0, p1, 12) == 0;
    }
    CHECK(same);
    tessel_mesh_free(&mesh);
    free(a.t);
    free(b.t);
    tessel_cloud_free(&c);
}

/* ---- errors, sinks, cancellation, degenerate input ---- */

static tessel_status failing_sink(void *user, const uint32_t *t, size_t count)
{
    (void)t;
    (void)count;
    (*(int *)user)++;
    return TESSEL_ERR_IO;
}

static int cancel_progress(void *user, const char *stage, double fraction)
{
    (void)user;
    (void)fraction;
    return strcmp(stage, "triangles") == 0;
}

static void test_errors(void)
{
    tessel_cloud c;
    make_terrain(&c, 3000, h_plane, 0.0, 8);
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    int calls = 0;
    tessel_triangle_sink bad = {failing_sink, &calls};
    CHECK(tessel_reconstruct_fixed_plane(&c, &p, NULL, &bad, NULL) == TESSEL_ERR_IO);
    CHECK(calls == 1);
    tris m;
    tessel_triangle_sink sink = {collect, &m};
    memset(&m, 0, sizeof m);
    tessel_callbacks cb = {cancel_progress, NULL, NULL};
    CHECK(tessel_reconstruct_fixed_plane(&c, &p, &cb, &sink, NULL) == TESSEL_ERR_CANCELLED);
    free(m.t);
    /* bad parameters */
    tessel_fixed_plane_params q = p;
    q.max_angle = 90;
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    q = p;
    q.columns = 10;
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    q = p;
    q.noise = -1;
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    q = p;
    q.points_per_dexel = 0.5;
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    q = p;
    q.columns = q.rows = 100000; /* 10^10 dexels for 3000 points */
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_LIMIT);
    q = p;
    q.cell = 1e-6; /* 10^12 dexels */
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_LIMIT);
    q = p;
    q.mode = (tessel_fixed_plane_mode)7;
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_reconstruct_fixed_plane(&c, &p, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    /* a grid index out of range */
    c.width = 10;
    c.height = 10;
    c.grid = malloc(100 * sizeof(uint32_t));
    for (int i = 0; i < 100; i++)
        c.grid[i] = (uint32_t)i;
    c.grid[55] = 1u << 30;
    q = p;
    q.mode = TESSEL_FIXED_PLANE_GRID;
    CHECK(run(&c, &q, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_cloud_free(&c);

    /* empty cloud, a single point, all points equal, NaN points */
    tessel_cloud e;
    memset(&e, 0, sizeof e);
    tessel_fixed_plane_stats st;
    CHECK(run(&e, &p, &m, &st) == TESSEL_OK && m.n == 0);
    free(m.t);
    tessel_cloud_alloc(&e, 1, 0, 0);
    CHECK(run(&e, &p, &m, &st) == TESSEL_OK && m.n == 0);
    free(m.t);
    tessel_cloud_free(&e);
    tessel_cloud_alloc(&e, 500, 0, 0);
    for (size_t i = 0; i < 500; i++)
        e.xyz[3 * i] = e.xyz[3 * i + 1] = e.xyz[3 * i + 2] = 1.5f;
    CHECK(run(&e, &p, &m, &st) == TESSEL_OK && m.n == 0);
    free(m.t);
    q = p;
    q.mode = TESSEL_FIXED_PLANE_RANGE;
    q.use_viewpoint = 1;
    CHECK(run(&e, &q, &m, &st) == TESSEL_OK && m.n == 0);
    free(m.t);
    q.viewpoint[0] = q.viewpoint[1] = q.viewpoint[2] = 1.5; /* points at the viewpoint */
    CHECK(run(&e, &q, &m, &st) == TESSEL_OK && m.n == 0);
    free(m.t);
    tessel_cloud_free(&e);
    make_terrain(&e, 2000, h_plane, 0.0, 9);
    for (size_t i = 0; i < e.count; i += 10)
        e.xyz[3 * i + 2] = NAN;
    CHECK(run(&e, &p, &m, &st) == TESSEL_OK && m.n > 1000);
    int nan_used = 0;
    for (size_t k = 0; k < 3 * m.n; k++)
        nan_used |= m.t[k] % 10 == 0;
    CHECK(!nan_used);
    free(m.t);
    tessel_cloud_free(&e);
}

/* ---- the CLI entry, called as tessel reconstruct would ---- */

static int run_cli(int n, const char *const *args)
{
    char *argv[16];
    for (int i = 0; i < n; i++)
        argv[i] = (char *)args[i];
    argv[n] = NULL;
    return cmd_reconstruct_fixed(n, argv);
}

static void test_cli(void)
{
    char dir[] = "/tmp/tessel_fp_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0);
        return;
    }
    char grid_in[64], terrain_in[64], tiny_in[64], out[64], out2[64];
    snprintf(grid_in, sizeof grid_in, "%s/grid.ply", dir);
    snprintf(tiny_in, sizeof tiny_in, "%s/tiny.xyz", dir);
    snprintf(terrain_in, sizeof terrain_in, "%s/terrain.ply", dir);
    snprintf(out, sizeof out, "%s/out.ply", dir);
    snprintf(out2, sizeof out2, "%s/out2.ply", dir);

    /* an organized scan with its viewpoint, through a PLY file */
    tessel_cloud c;
    uint8_t *labels;
    scan_room(&c, &labels, 60, 120, 0.004, 1, 0.0, 11);
    CHECK(tessel_cloud_write(&c, grid_in, NULL, NULL) == TESSEL_OK);
    const char *a1[] = {"reconstruct", grid_in, out, "--mode", "grid", "--quiet"};
    CHECK(run_cli(6, a1) == 0);
    tessel_mesh m;
    CHECK(tessel_mesh_read(&m, out, NULL, NULL) == TESSEL_OK);
    tris direct;
    tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
    p.mode = TESSEL_FIXED_PLANE_GRID;
    CHECK(run(&c, &p, &direct, NULL) == TESSEL_OK);
    CHECK_MSG(m.triangle_count == direct.n && m.triangle_count > 0, "%zu vs %zu",
              m.triangle_count, direct.n);
    tessel_check_params cp = tessel_check_params_default();
    tessel_mesh_report rep;
    CHECK(tessel_mesh_check(&m, &cp, &rep) == TESSEL_OK && tessel_mesh_report_valid(&rep));
    tessel_mesh_free(&m);
    free(direct.t);
    /* range mode reads the viewpoint from the file, or needs --viewpoint */
    const char *a2[] = {"reconstruct", grid_in, out2, "--mode", "range", "--quiet"};
    CHECK(run_cli(6, a2) == 0);
    free(labels);
    tessel_cloud_free(&c);

    /* a georeferenced terrain: world coordinates come back exactly */
    make_terrain(&c, 4000, h_parab, 0.001, 12);
    c.offset[0] = 500000.0;
    c.offset[1] = 4100000.0;
    c.offset[2] = 35.0;
    CHECK(tessel_cloud_write(&c, terrain_in, NULL, NULL) == TESSEL_OK);
    tessel_cloud back;
    CHECK(tessel_cloud_read(&back, terrain_in, NULL, NULL) == TESSEL_OK);
    const char *a3[] = {"reconstruct", terrain_in, out, "--mode", "height", "--axis", "z",
                        "--cell", "0.03", "--quiet"};
    CHECK(run_cli(10, a3) == 0);
    CHECK(tessel_mesh_read(&m, out, NULL, NULL) == TESSEL_OK);
    CHECK(m.triangle_count > 1000);
    size_t exact = 0;
    for (size_t v = 0; v < m.vertex_count; v++) {
        double wv[3];
        for (int k = 0; k < 3; k++)
            wv[k] = m.offset[k] + (double)m.xyz[3 * v + k];
        for (size_t i = 0; i < back.count; i++) {
            if (back.offset[0] + (double)back.xyz[3 * i] == wv[0] &&
                back.offset[1] + (double)back.xyz[3 * i + 1] == wv[1] &&
                back.offset[2] + (double)back.xyz[3 * i + 2] == wv[2]) {
                exact++;
                break;
            }
        }
    }
    CHECK_MSG(exact == m.vertex_count, "%zu of %zu vertices are input points", exact,
              m.vertex_count);
    CHECK(fabs(m.offset[0] + m.xyz[0] - 500000.0) < 2.0);
    tessel_mesh_free(&m);
    tessel_cloud_free(&back);

    /* wrong input or options: clear errors, no output written */
    remove(out2);
    const char *a4[] = {"reconstruct", terrain_in, out2, "--mode", "grid", "--quiet"};
    CHECK(run_cli(6, a4) == 2); /* unorganized */
    const char *a5[] = {"reconstruct", terrain_in, out2, "--mode", "range", "--quiet"};
    CHECK(run_cli(6, a5) == 1); /* no viewpoint */
    const char *a6[] = {"reconstruct", terrain_in, out2, "--mode", "sideways"};
    CHECK(run_cli(5, a6) == 1);
    const char *a7[] = {"reconstruct", terrain_in, out2, "--mode", "height", "--grid", "0x5"};
    CHECK(run_cli(7, a7) == 1);
    const char *a8[] = {"reconstruct", terrain_in, out2, "--mode", "height", "--max-angle",
                        "95"};
    CHECK(run_cli(7, a8) == 1);
    const char *a9[] = {"reconstruct", terrain_in, out2, "--mode", "range", "--viewpoint",
                        "1,2", "--quiet"};
    CHECK(run_cli(8, a9) == 1);
    const char *a10[] = {"reconstruct", "/nonexistent/in.ply", out2, "--mode", "height"};
    CHECK(run_cli(5, a10) == 2);
    /* fewer than three points: an error, as for the other methods, not an
     * empty mesh */
    FILE *tf = fopen(tiny_in, "w");
    CHECK(tf != NULL);
    if (tf) {
        fputs("0 0 0\n1 0 0\n", tf);
        fclose(tf);
    }
    const char *a12[] = {"reconstruct", tiny_in, out2, "--mode", "height", "--quiet"};
    CHECK(run_cli(6, a12) == 2);
    FILE *f = fopen(out2, "rb");
    CHECK(f == NULL);
    if (f)
        fclose(f);
    const char *a11[] = {"reconstruct", terrain_in, out2, "--mode", "range", "--viewpoint",
                         "500000.5,4100000.5,36", "--json"};
    CHECK(run_cli(8, a11) == 0);
    tessel_cloud_free(&c);
    remove(grid_in);
    remove(terrain_in);
    remove(tiny_in);
    remove(out);
    remove(out2);
    rmdir(dir);
}

int main(void)
{
    test_plane();
    test_paraboloid_noise();
    test_step_open();
    test_uniform_sampling();
    test_lattice_layers();
    test_range_room();
    test_grid_room();
    test_poles();
    test_grid_camera();
    test_grid_diagonal();
    test_vertex_manifold();
    test_offset();
    test_errors();
    test_cli();
    return TEST_SUMMARY();
}
