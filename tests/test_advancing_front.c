/* Advancing-front triangulation (src/front/) on analytic
 * samples: a sphere and a torus must come out closed, manifold, outward and
 * with the right Euler characteristic; a disc with exactly one border loop;
 * two close parallel sheets as two components; a sphere with noise of a
 * fifth and of a third of the spacing, shuffled, still closed; an open
 * tube keeps its two end loops; every result
 * free of self-intersections (exact check); second normal lines whose sign
 * does not matter. Also duplicates, bad input and the exact triangle test
 * on hand-made cases. */
#include "test.h"

#include "front/front.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

/* Deterministic uniform numbers in [0, 1). */
static double rnd(uint64_t *state)
{
    *state = *state * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*state >> 11) / 9007199254740992.0;
}

static tessel_cloud make_cloud(size_t n)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
    return c;
}

/* Fibonacci sphere of radius 1: even spacing. */
static tessel_cloud sphere(size_t n)
{
    tessel_cloud c = make_cloud(n);
    double ga = PI * (3.0 - sqrt(5.0));
    for (size_t i = 0; i < n; i++) {
        double z = 1.0 - 2.0 * ((double)i + 0.5) / (double)n;
        double r = sqrt(1.0 - z * z), th = ga * (double)i;
        c.xyz[3 * i] = (float)(r * cos(th));
        c.xyz[3 * i + 1] = (float)(r * sin(th));
        c.xyz[3 * i + 2] = (float)z;
    }
    return c;
}

/* Torus R = 1, r = 0.4 on a jittered (u, v) grid with rows scaled by the
 * local circumference, so spacing is about even. */
static tessel_cloud torus(size_t rows, uint64_t seed)
{
    const double R = 1.0, r = 0.4;
    size_t cap = 0;
    double spacing = 2.0 * PI * r / (double)rows;
    for (size_t j = 0; j < rows; j++) {
        double v = 2.0 * PI * (double)j / (double)rows;
        cap += (size_t)(2.0 * PI * (R + r * cos(v)) / spacing);
    }
    tessel_cloud c = make_cloud(cap);
    size_t m = 0;
    for (size_t j = 0; j < rows; j++) {
        double v0 = 2.0 * PI * (double)j / (double)rows;
        size_t cols = (size_t)(2.0 * PI * (R + r * cos(v0)) / spacing);
        for (size_t i = 0; i < cols && m < cap; i++) {
            double v = v0 + 0.3 * (rnd(&seed) - 0.5) * 2.0 * PI / (double)rows;
            double u = 2.0 * PI * ((double)i + 0.5 * (double)(j % 2) +
                                   0.3 * (rnd(&seed) - 0.5)) / (double)cols;
            c.xyz[3 * m] = (float)((R + r * cos(v)) * cos(u));
            c.xyz[3 * m + 1] = (float)((R + r * cos(v)) * sin(u));
            c.xyz[3 * m + 2] = (float)(r * sin(v));
            m++;
        }
    }
    c.count = m;
    return c;
}

/* Jittered hexagonal grid in the square [-1,1]^2 at height z (disc: keep
 * radius < 1). Exactly planar, the hardest case for exact tests. */
static size_t sheet(float *xyz, size_t cap, double h, double z, int disc, uint64_t *seed)
{
    size_t m = 0;
    double dy = h * sqrt(3.0) / 2.0;
    for (double y = -1.0; y <= 1.0; y += dy) {
        int row = (int)floor((y + 1.0) / dy + 0.5);
        for (double x = -1.0 + (row % 2) * h / 2.0; x <= 1.0; x += h) {
            double px = x + 0.2 * h * (rnd(seed) - 0.5);
            double py = y + 0.2 * h * (rnd(seed) - 0.5);
            if (disc && px * px + py * py > 1.0)
                continue;
            if (m < cap) {
                xyz[3 * m] = (float)px;
                xyz[3 * m + 1] = (float)py;
                xyz[3 * m + 2] = (float)z;
            }
            m++;
        }
    }
    return m;
}

typedef struct topo {
    size_t edges, boundary_edges, nonmanifold_edges, misoriented_edges;
    size_t bad_border_vertices, used_vertices;
    long euler;
} topo;

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Topology counted independently of the library: directed edges sorted by
 * their undirected key. A vertex of a manifold has 0 or 2 border edges. */
static topo count_topology(const tessel_mesh *m)
{
    topo r;
    memset(&r, 0, sizeof r);
    size_t nt = m->triangle_count, nv = m->vertex_count;
    uint64_t *keys = malloc(3 * nt * sizeof *keys);
    size_t *bnd = calloc(nv, sizeof *bnd);
    size_t *deg = calloc(nv, sizeof *deg);
    for (size_t t = 0; t < nt; t++)
        for (int i = 0; i < 3; i++) {
            uint64_t a = m->triangles[3 * t + i], b = m->triangles[3 * t + (i + 1) % 3];
            uint64_t lo = a < b ? a : b, hi = a < b ? b : a;
            keys[3 * t + i] = (lo << 33) | (hi << 1) | (a < b ? 0 : 1);
            deg[a]++;
        }
    qsort(keys, 3 * nt, sizeof *keys, cmp_u64);
    for (size_t i = 0; i < 3 * nt;) {
        size_t j = i;
        while (j < 3 * nt && keys[j] >> 1 == keys[i] >> 1)
            j++;
        r.edges++;
        if (j - i == 1) {
            r.boundary_edges++;
            bnd[keys[i] >> 33]++;
            bnd[(keys[i] >> 1) & 0xFFFFFFFFu]++;
        } else if (j - i > 2) {
            r.nonmanifold_edges++;
        } else if ((keys[i] & 1) == (keys[i + 1] & 1)) {
            r.misoriented_edges++;
        }
        i = j;
    }
    for (size_t v = 0; v < nv; v++)
        if (deg[v]) {
            r.used_vertices++;
            if (bnd[v] != 0 && bnd[v] != 2)
                r.bad_border_vertices++;
        }
    r.euler = (long)r.used_vertices - (long)r.edges + (long)nt;
    free(keys);
    free(bnd);
    free(deg);
    return r;
}

static tessel_mesh_report check_mesh(const tessel_mesh *m, const tessel_cloud *input)
{
    tessel_check_params cp = tessel_check_params_default();
    cp.input = input;
    tessel_mesh_report rep;
    CHECK(tessel_mesh_check(m, &cp, &rep) == TESSEL_OK);
    return rep;
}

static double signed_volume(const tessel_mesh *m)
{
    double v = 0.0;
    for (size_t t = 0; t < m->triangle_count; t++) {
        const float *a = m->xyz + 3 * m->triangles[3 * t];
        const float *b = m->xyz + 3 * m->triangles[3 * t + 1];
        const float *c = m->xyz + 3 * m->triangles[3 * t + 2];
        v += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) +
              a[1] * ((double)b[2] * c[0] - (double)b[0] * c[2]) +
              a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) /
             6.0;
    }
    return v;
}

/* Triangulates c into m and checks it: manifold, consistently oriented,
 * borders through single vertices, valid and free of self-intersections
 * (exact); its topology and report for the caller's own checks. */
static void front_checked(const tessel_cloud *c, tessel_mesh *m, tessel_front_stats *st,
                          topo *tp, tessel_mesh_report *rep)
{
    CHECK(tessel_advancing_front(c, NULL, NULL, m, st) == TESSEL_OK);
    *tp = count_topology(m);
    *rep = check_mesh(m, c);
    CHECK(tp->nonmanifold_edges == 0 && tp->misoriented_edges == 0 &&
          tp->bad_border_vertices == 0);
    CHECK(tessel_mesh_report_valid(rep) && rep->self_intersections == 0);
}

static void test_sphere(void)
{
    tessel_cloud c = sphere(4000);
    tessel_mesh m;
    tessel_front_stats st;
    CHECK(tessel_advancing_front(&c, NULL, NULL, &m, &st) == TESSEL_OK);
    topo tp = count_topology(&m);
    tessel_mesh_report rep = check_mesh(&m, &c);
    CHECK_MSG(tp.boundary_edges == 0, "sphere: %zu boundary edges", tp.boundary_edges);
    CHECK(tp.nonmanifold_edges == 0 && tp.misoriented_edges == 0 && tp.bad_border_vertices == 0);
    CHECK_MSG(tp.euler == 2, "sphere: euler %ld", tp.euler);
    CHECK(tp.used_vertices == c.count);
    CHECK(m.triangle_count == 2 * c.count - 4);
    CHECK(tessel_mesh_report_valid(&rep));
    CHECK_MSG(rep.self_intersections == 0, "%zu", rep.self_intersections);
    CHECK(rep.nonmanifold_vertices == 0 && rep.components == 1);
    /* Outward: positive volume close to the ball's 4/3 pi. */
    double vol = signed_volume(&m);
    CHECK_MSG(vol > 0.99 * 4.0 / 3.0 * PI && vol < 4.0 / 3.0 * PI, "volume %g", vol);
    CHECK(st.triangles == m.triangle_count && st.border_edges == 0);
    printf("sphere: %zu triangles, %zu seeds, %zu bridges, min angle %.1f\n",
           m.triangle_count, st.seeds, st.bridges, rep.min_angle_deg);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

static void test_torus(void)
{
    tessel_cloud c = torus(40, 7);
    tessel_mesh m;
    tessel_front_stats st;
    CHECK(tessel_advancing_front(&c, NULL, NULL, &m, &st) == TESSEL_OK);
    topo tp = count_topology(&m);
    tessel_mesh_report rep = check_mesh(&m, &c);
    CHECK_MSG(tp.boundary_edges == 0, "torus: %zu boundary edges", tp.boundary_edges);
    CHECK(tp.nonmanifold_edges == 0 && tp.misoriented_edges == 0 && tp.bad_border_vertices == 0);
    CHECK_MSG(tp.euler == 0, "torus: euler %ld", tp.euler);
    CHECK(tessel_mesh_report_valid(&rep));
    CHECK(rep.self_intersections == 0 && rep.components == 1 && rep.genus == 1);
    CHECK(signed_volume(&m) > 0.0);
    CHECK(st.bridges >= 1); /* a genus-1 surface needs joins of borders */
    printf("torus: %zu points, %zu triangles, %zu seeds, %zu bridges\n", c.count,
           m.triangle_count, st.seeds, st.bridges);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

static void test_disc(void)
{
    uint64_t seed = 3;
    size_t n = sheet(NULL, 0, 0.05, 0.0, 1, &seed);
    tessel_cloud c = make_cloud(n);
    seed = 3;
    sheet(c.xyz, n, 0.05, 0.0, 1, &seed);
    tessel_mesh m;
    topo tp;
    tessel_mesh_report rep;
    front_checked(&c, &m, NULL, &tp, &rep);
    CHECK_MSG(tp.euler == 1, "disc: euler %ld", tp.euler);
    CHECK(rep.boundary_loops == 1 && rep.components == 1);
    CHECK(tp.used_vertices == c.count);
    /* The border follows the circle: about 2 pi / h edges. */
    double expect = 2.0 * PI / 0.05;
    CHECK_MSG(tp.boundary_edges > 0.6 * expect && tp.boundary_edges < 1.5 * expect,
              "disc border %zu edges", tp.boundary_edges);
    printf("disc: %zu points, %zu triangles, %zu border edges\n", c.count, m.triangle_count,
           tp.boundary_edges);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

/* An open tube of radius 2 h (13 points a ring, rings h apart, every
 * other one turned by half a step): its two end loops are borders of the
 * surface, two spacings in radius, which the hole closing used to take for
 * holes the front left and cap. A loop whose triangles stand across it is
 * not closed. */
static void test_open_tube(void)
{
    const size_t ring = 13, rings = 21;
    const double h = 1.0, r = 2.0 * h;
    tessel_cloud c = make_cloud(ring * rings);
    for (size_t j = 0; j < rings; j++)
        for (size_t i = 0; i < ring; i++) {
            double a = 2.0 * PI * ((double)i + 0.5 * (double)(j % 2)) / (double)ring;
            float *p = c.xyz + 3 * (j * ring + i);
            p[0] = (float)(r * cos(a));
            p[1] = (float)(r * sin(a));
            p[2] = (float)((double)j * h);
        }
    tessel_mesh m;
    tessel_front_stats st;
    topo tp;
    tessel_mesh_report rep;
    front_checked(&c, &m, &st, &tp, &rep);
    CHECK(tp.used_vertices == c.count && rep.components == 1);
    /* An annulus: Euler characteristic 0, the two rings as its borders. */
    CHECK_MSG(tp.euler == 0 && rep.boundary_loops == 2 && tp.boundary_edges == 2 * ring,
              "open tube: euler %ld, %zu border loops, %zu border edges, %zu hole triangles",
              tp.euler, rep.boundary_loops, tp.boundary_edges, st.hole_triangles);
    printf("open tube: %zu triangles, %zu border edges\n", m.triangle_count, tp.boundary_edges);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}

static void test_two_sheets(void)
{
    /* Spacing 0.05, sheets 0.25 apart: far beyond eps1 times the spacing,
     * close enough that their triangles' boxes meet in the grid. */
    uint64_t seed = 11;
    size_t n1 = sheet(NULL, 0, 0.05, 0.0, 0, &seed);
    size_t n2 = sheet(NULL, 0, 0.05, 0.25, 0, &seed);
    tessel_cloud c = make_cloud(n1 + n2);
    seed = 11;
    sheet(c.xyz, n1, 0.05, 0.0, 0, &seed);
    sheet(c.xyz + 3 * n1, n2, 0.05, 0.25, 0, &seed);
    tessel_mesh m;
    CHECK(tessel_advancing_front(&c, NULL, NULL, &m, NULL) == TESSEL_OK);
    topo tp = count_topology(&m);
    tessel_mesh_report rep = check_mesh(&m, &c);
    CHECK(tp.nonmanifold_edges == 0 && tp.misoriented_edges == 0 && tp.bad_border_vertices == 0);
    CHECK_MSG(rep.components == 2 && rep.boundary_loops == 2, "%zu components %zu loops",
              rep.components, rep.boundary_loops);
    CHECK(tp.euler == 2);
    CHECK(tessel_mesh_report_valid(&rep) && rep.self_intersections == 0);
    /* No triangle spans the two sheets. */
    size_t spanning = 0;
    for (size_t t = 0; t < m.triangle_count; t++) {
        float z0 = m.xyz[3 * m.triangles[3 * t] + 2];
        for (int i = 1; i < 3; i++)
            if (m.xyz[3 * m.triangles[3 * t + i] + 2] != z0)
                spanning++;
    }
    CHECK(spanning == 0);
    tessel_mesh_free(&m);
    tessel_cloud_free(&c);
}


/* Fibonacci sphere with Gaussian noise of sigma times the spacing, in
 * random order. */
static tessel_cloud noisy_sphere(size_t n, double sigma, uint64_t seed)
{
    tessel_cloud c = sphere(n);
    double h = sqrt(4.0 * PI / (double)n);
    for (size_t i = 0; i < 3 * n; i++) {
        double u = rnd(&seed) + 1e-300, v = rnd(&seed);
        c.xyz[i] = (float)(c.xyz[i] + sigma * h * sqrt(-2.0 * log(u)) * cos(2.0 * PI * v));
    }
    for (size_t i = n - 1; i > 0; i--) {
        size_t j = (size_t)(rnd(&seed) * (double)(i + 1));
        for (int k = 0; k < 3; k++) {
            float t = c.xyz[3 * i + k];
            c.xyz[3 * i + k] = c.xyz[3 * j + k];
            c.xyz[3 * j + k] = t;
        }
    }
    return c;
}

static void test_noisy_sphere(void)
{
    /* Noise of a fifth of the spacing in every direction: triangle normals
     * scatter by tens of degrees, fronts meet crookedly; the surface must
     * still close, and stay valid. */
    for (int trial = 0; trial < 2; trial++) {
        double sigma = trial ? 0.3 : 0.2;
        tessel_cloud c = noisy_sphere(4000, sigma, 17 + (uint64_t)trial);
        tessel_mesh m;
        tessel_front_stats st;
        CHECK(tessel_advancing_front(&c, NULL, NULL, &m, &st) == TESSEL_OK);
        tessel_mesh_report rep = check_mesh(&m, &c);
        CHECK(tessel_mesh_report_valid(&rep) && rep.self_intersections == 0);
        CHECK_MSG(rep.boundary_edges == 0 && rep.components == 1 && rep.genus == 0,
                  "noisy sphere %.1f: %zu boundary edges, %zu components", sigma,
                  rep.boundary_edges, rep.components);
        CHECK(signed_volume(&m) > 0.0);
        CHECK(st.unused_points < c.count / 3);
        printf("noisy sphere (sigma %.1f h): %zu triangles, %zu unused points, %zu bridges, "
               "%zu hole triangles\n",
               sigma, m.triangle_count, st.unused_points, st.bridges, st.hole_triangles);
        tessel_mesh_free(&m);
        tessel_cloud_free(&c);
    }
}

/* Holes the fronts leave where noise makes them meet crookedly: at 0.45
 * spacings of noise some need a triangulation other than the least-area
 * one (which meets the surface around), built from triangles the mesh
 * allows. Every sphere of the series must close. */
static void test_noisy_holes(void)
{
    size_t open = 0;
    for (uint64_t seed = 1; seed <= 40; seed++) {
        tessel_cloud c = noisy_sphere(4000, 0.45, 1000 + seed);
        tessel_mesh m;
        CHECK(tessel_advancing_front(&c, NULL, NULL, &m, NULL) == TESSEL_OK);
        tessel_mesh_report rep = check_mesh(&m, &c);
        CHECK(tessel_mesh_report_valid(&rep) && rep.self_intersections == 0);
        CHECK_MSG(rep.boundary_edges == 0 && rep.components == 1,
                  "noisy sphere %d: %zu boundary edges, %zu components", (int)seed,
                  rep.boundary_edges, rep.components);
        open += rep.boundary_edges;
        tessel_mesh_free(&m);
        tessel_cloud_free(&c);
    }
    printf("40 noisy spheres (sigma 0.45 h): %zu boundary edges\n", open);
}

/* Second normal lines (tsl_advancing_front_lines, as the pipeline passes
 * the representatives' fitted normals): their sign means nothing, so
 * flipping any of them changes nothing; NULL is tessel_advancing_front;
 * with the true normals of a noisy sphere the surface is valid and closed. */
static void test_lines(void)
{
    tessel_cloud c = noisy_sphere(3000, 0.3, 29);
    float *lines = malloc(3 * c.count * sizeof *lines);
    float *flipped = malloc(3 * c.count * sizeof *flipped);
    uint64_t seed = 5;
    for (size_t i = 0; i < c.count; i++) {
        double p[3] = {c.xyz[3 * i], c.xyz[3 * i + 1], c.xyz[3 * i + 2]};
        double len = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        float sign = rnd(&seed) < 0.5 ? -1.0f : 1.0f;
        for (int k = 0; k < 3; k++) {
            lines[3 * i + k] = (float)(p[k] / len);
            flipped[3 * i + k] = sign * lines[3 * i + k];
        }
    }
    tessel_mesh a, b, plain, none;
    tessel_front_stats sa, sb;
    CHECK(tsl_advancing_front_lines(&c, lines, NULL, NULL, &a, &sa) == TESSEL_OK);
    CHECK(tsl_advancing_front_lines(&c, flipped, NULL, NULL, &b, &sb) == TESSEL_OK);
    CHECK(a.triangle_count == b.triangle_count &&
          !memcmp(a.triangles, b.triangles, 3 * a.triangle_count * sizeof *a.triangles));
    CHECK(tsl_advancing_front_lines(&c, NULL, NULL, NULL, &none, NULL) == TESSEL_OK);
    CHECK(tessel_advancing_front(&c, NULL, NULL, &plain, NULL) == TESSEL_OK);
    CHECK(none.triangle_count == plain.triangle_count &&
          !memcmp(none.triangles, plain.triangles,
                  3 * none.triangle_count * sizeof *none.triangles));
    tessel_mesh_report rep = check_mesh(&a, &c);
    CHECK(tessel_mesh_report_valid(&rep) && rep.self_intersections == 0);
    CHECK_MSG(rep.boundary_edges == 0 && rep.components == 1 && rep.genus == 0,
              "lines: %zu boundary edges, %zu components", rep.boundary_edges, rep.components);
    CHECK(signed_volume(&a) > 0.0);
    printf("noisy sphere with normal lines: %zu triangles (%zu without), %zu unused points\n",
           a.triangle_count, plain.triangle_count, sa.unused_points);
    tessel_mesh_free(&a);
    tessel_mesh_free(&b);
    tessel_mesh_free(&plain);
    tessel_mesh_free(&none);
    free(lines);
    free(flipped);
    tessel_cloud_free(&c);
}

/* Tiles (tile_points): the same surfaces cut into tiles, fronts in
 * parallel, seams closed by a front over all points. The seams must not
 * show: closed surfaces stay closed with their genus, the disc keeps one
 * border loop; the result is the same for one and two threads, and
 * differs from the single front's (the tiles were used); closed ones face
 * outward. */
static bool same_mesh(const tessel_mesh *a, const tessel_mesh *b)
{
    return a->triangle_count == b->triangle_count &&
           memcmp(a->triangles, b->triangles, 3 * a->triangle_count * sizeof *a->triangles) == 0;
}

static void check_tiled(const char *name, const tessel_cloud *c, size_t tile_points, long euler,
                        size_t loops)
{
    tessel_front_params p = tessel_front_params_default();
    p.tile_points = 0;
    tessel_mesh whole, one, two;
    CHECK(tessel_advancing_front(c, &p, NULL, &whole, NULL) == TESSEL_OK);
    p.tile_points = tile_points;
    p.threads = 1;
    tessel_front_stats st;
    CHECK(tessel_advancing_front(c, &p, NULL, &one, &st) == TESSEL_OK);
    p.threads = 2;
    CHECK(tessel_advancing_front(c, &p, NULL, &two, NULL) == TESSEL_OK);
    CHECK_MSG(same_mesh(&one, &two), "%s: tiles depend on the thread count", name);
    CHECK_MSG(!same_mesh(&one, &whole), "%s: the tiles were not used", name);
    topo tp = count_topology(&one);
    tessel_mesh_report rep = check_mesh(&one, c);
    CHECK(tp.nonmanifold_edges == 0 && tp.misoriented_edges == 0 && tp.bad_border_vertices == 0);
    CHECK(tessel_mesh_report_valid(&rep) && rep.self_intersections == 0);
    CHECK_MSG(tp.euler == euler && rep.components == 1 && rep.boundary_loops == loops,
              "%s in tiles of %zu: euler %ld, %zu components, %zu border loops (%zu edges)", name,
              tile_points, tp.euler, rep.components, rep.boundary_loops, tp.boundary_edges);
    size_t used_whole = count_topology(&whole).used_vertices;
    CHECK_MSG(tp.used_vertices > used_whole * 99 / 100, "%s: %zu points used (one front: %zu)",
              name, tp.used_vertices, used_whole);
    CHECK(loops > 0 || signed_volume(&one) > 0.0);
    printf("%s in tiles of %zu: %zu triangles (one front: %zu), %zu seeds, %zu bridges\n", name,
           tile_points, one.triangle_count, whole.triangle_count, st.seeds, st.bridges);
    tessel_mesh_free(&whole);
    tessel_mesh_free(&one);
    tessel_mesh_free(&two);
}

static void test_tiles(void)
{
    tessel_cloud s = noisy_sphere(20000, 0.2, 5);
    check_tiled("noisy sphere", &s, 2500, 2, 0);
    tessel_cloud_free(&s);
    tessel_cloud t = torus(60, 9);
    check_tiled("torus", &t, 3000, 0, 0);
    tessel_cloud_free(&t);
    uint64_t seed = 3;
    size_t n = sheet(NULL, 0, 0.02, 0.0, 1, &seed);
    tessel_cloud d = make_cloud(n);
    seed = 3;
    sheet(d.xyz, n, 0.02, 0.0, 1, &seed);
    check_tiled("disc", &d, 2000, 1, 1);
    tessel_cloud_free(&d);
    /* Tiles of fewer than 256 points are refused. */
    tessel_cloud c = sphere(1000);
    tessel_front_params p = tessel_front_params_default();
    p.tile_points = 100;
    tessel_mesh m;
    CHECK(tessel_advancing_front(&c, &p, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_cloud_free(&c);
}

static void test_duplicates_and_errors(void)
{
    /* Every point twice: the copies stay unused, the surface is the same. */
    tessel_cloud a = sphere(1000), b = make_cloud(2000);
    memcpy(b.xyz, a.xyz, 3000 * sizeof *a.xyz);
    memcpy(b.xyz + 3000, a.xyz, 3000 * sizeof *a.xyz);
    tessel_mesh ma, mb;
    tessel_front_stats sa, sb;
    CHECK(tessel_advancing_front(&a, NULL, NULL, &ma, &sa) == TESSEL_OK);
    CHECK(tessel_advancing_front(&b, NULL, NULL, &mb, &sb) == TESSEL_OK);
    CHECK(ma.triangle_count == mb.triangle_count && sb.unused_points == 1000);
    bool only_first = true;
    for (size_t i = 0; i < 3 * mb.triangle_count; i++)
        only_first &= mb.triangles[i] < 1000;
    CHECK(only_first);
    tessel_mesh_report rep = check_mesh(&mb, NULL);
    CHECK(tessel_mesh_report_valid(&rep) && rep.boundary_edges == 0);
    tessel_mesh_free(&ma);
    tessel_mesh_free(&mb);

    /* Bad input. */
    tessel_mesh m;
    CHECK(tessel_advancing_front(NULL, NULL, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_advancing_front(&a, NULL, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_front_params p = tessel_front_params_default();
    p.max_edge_ratio = 0.5;
    CHECK(tessel_advancing_front(&a, &p, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    p = tessel_front_params_default();
    p.k = 100;
    CHECK(tessel_advancing_front(&a, &p, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    size_t n = a.count;
    a.count = 2;
    CHECK(tessel_advancing_front(&a, NULL, NULL, &m, NULL) == TESSEL_ERR_TOO_FEW_POINTS);
    CHECK(m.triangle_count == 0 && m.triangles == NULL);
    a.count = n;
    a.xyz[5] = NAN;
    CHECK(tessel_advancing_front(&a, NULL, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    /* Collinear points: no triangle, no failure. */
    tessel_cloud line = make_cloud(50);
    for (size_t i = 0; i < 50; i++)
        line.xyz[3 * i] = (float)i;
    tessel_front_stats sl;
    CHECK(tessel_advancing_front(&line, NULL, NULL, &m, &sl) == TESSEL_OK);
    CHECK(m.triangle_count == 0 && sl.unused_points == 50);
    tessel_mesh_free(&m);
    /* All at one place. */
    memset(line.xyz, 0, 150 * sizeof *line.xyz);
    CHECK(tessel_advancing_front(&line, NULL, NULL, &m, &sl) == TESSEL_OK);
    CHECK(m.triangle_count == 0 && sl.unused_points == 50);
    tessel_mesh_free(&m);
    tessel_cloud_free(&line);
    tessel_cloud_free(&a);
    tessel_cloud_free(&b);
}

/* The exact triangle test on hand-made cases. */
static void test_triangle_test(void)
{
    double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0};
    const double *t1[3] = {a, b, c};
    uint32_t i1[3] = {0, 1, 2};
    /* Coplanar, sharing edge a-b, apex on the other side: no overlap. */
    double d[3] = {0.5, -1, 0};
    const double *t2[3] = {b, a, d};
    uint32_t i2[3] = {1, 0, 3};
    CHECK(!tsl_triangles_intersect(i1, t1, i2, t2));
    /* Same edge, apex on the same side: overlap. */
    double e[3] = {0.5, 0.5, 0};
    const double *t3[3] = {b, a, e};
    CHECK(tsl_triangles_intersect(i1, t1, i2, t3));
    /* Sharing vertex a only, the other through the first's interior. */
    double f[3] = {0.3, 0.3, 1}, g[3] = {0.3, 0.3, -1};
    const double *t4[3] = {a, f, g};
    uint32_t i4[3] = {0, 4, 5};
    CHECK(tsl_triangles_intersect(i1, t1, i4, t4));
    /* Sharing vertex a, touching only there. */
    double h[3] = {-1, -1, 1}, k[3] = {-1, 0, 1};
    const double *t5[3] = {a, h, k};
    CHECK(!tsl_triangles_intersect(i1, t1, i4, t5));
    /* Disjoint ids, piercing; and just apart (exactly at z = 1e-30 above). */
    double p1[3] = {0.2, 0.2, -1}, p2[3] = {0.2, 0.2, 1}, p3[3] = {0.25, 0.2, 1};
    const double *t6[3] = {p1, p2, p3};
    uint32_t i6[3] = {6, 7, 8};
    CHECK(tsl_triangles_intersect(i1, t1, i6, t6));
    double q1[3] = {0.2, 0.2, 1e-30}, q2[3] = {0.4, 0.2, 1e-30}, q3[3] = {0.2, 0.4, 1};
    const double *t7[3] = {q1, q2, q3};
    CHECK(!tsl_triangles_intersect(i1, t1, i6, t7));
    const double *deg[3] = {a, b, b};
    CHECK(tsl_triangle_degenerate(deg) && !tsl_triangle_degenerate(t1));
}

/* Triangle (a, b, c) as its rotation with the smallest id first (same
 * orientation), packed for sorting. */
typedef struct tri_key {
    uint32_t v[3];
} tri_key;

static tri_key rotated(const uint32_t *t)
{
    int i = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
    tri_key k = {{t[i], t[(i + 1) % 3], t[(i + 2) % 3]}};
    return k;
}

static int cmp_tri_key(const void *pa, const void *pb)
{
    return memcmp(pa, pb, sizeof(tri_key));
}

/* The front from a starting mesh (what the pipeline's hole repair runs):
 * a closed noisy sphere less a cap of triangles closes again, valid, and
 * keeps every starting triangle as it was. */
static void test_front_from_start(void)
{
    tessel_cloud c = noisy_sphere(4000, 0.2, 5);
    tessel_mesh whole, again;
    CHECK(tessel_advancing_front(&c, NULL, NULL, &whole, NULL) == TESSEL_OK);
    uint32_t *start = malloc(3 * whole.triangle_count * sizeof *start);
    size_t kept = 0;
    for (size_t t = 0; t < whole.triangle_count; t++) {
        const uint32_t *v = whole.triangles + 3 * t;
        bool in_cap = false;
        for (int i = 0; i < 3; i++)
            in_cap |= c.xyz[3 * (size_t)v[i] + 2] > 0.8f;
        if (!in_cap)
            memcpy(start + 3 * kept++, v, 3 * sizeof *v);
    }
    CHECK(kept < whole.triangle_count * 95 / 100);
    tessel_front_stats st;
    CHECK(tsl_advancing_front_from(&c, NULL, NULL, start, kept, NULL, &again, &st) ==
          TESSEL_OK);
    tessel_mesh_report rep = check_mesh(&again, &c);
    CHECK(tessel_mesh_report_valid(&rep) && rep.self_intersections == 0);
    CHECK_MSG(rep.boundary_edges == 0 && rep.components == 1 && rep.genus == 0,
              "front from a start: %zu boundary edges, %zu components", rep.boundary_edges,
              rep.components);
    CHECK(signed_volume(&again) > 0.0);
    /* Every starting triangle is in the result, oriented as it was. */
    tri_key *have = malloc(again.triangle_count * sizeof *have);
    for (size_t t = 0; t < again.triangle_count; t++)
        have[t] = rotated(again.triangles + 3 * t);
    qsort(have, again.triangle_count, sizeof *have, cmp_tri_key);
    size_t missing = 0;
    for (size_t t = 0; t < kept; t++) {
        tri_key k = rotated(start + 3 * t);
        missing += !bsearch(&k, have, again.triangle_count, sizeof *have, cmp_tri_key);
    }
    CHECK_MSG(missing == 0, "%zu of %zu starting triangles lost", missing, kept);
    printf("front from %zu of %zu triangles: %zu triangles, %zu seeds\n", kept,
           whole.triangle_count, again.triangle_count, st.seeds);
    /* In tiles (each from the starting triangles inside it, the ones in
     * the band along a cut made again by the front that joins them): the
     * same closed surface, the same for one and two threads, and all but
     * the starting triangles near the cuts kept. */
    tessel_front_params tp = tessel_front_params_default();
    tp.tile_points = 1000;
    tessel_mesh tiled[2];
    for (int t = 0; t < 2; t++) {
        tp.threads = t + 1;
        CHECK(tsl_advancing_front_from(&c, NULL, &tp, start, kept, NULL, &tiled[t], NULL) ==
              TESSEL_OK);
    }
    CHECK(tiled[0].triangle_count == tiled[1].triangle_count &&
          memcmp(tiled[0].triangles, tiled[1].triangles,
                 3 * tiled[0].triangle_count * sizeof *tiled[0].triangles) == 0);
    rep = check_mesh(&tiled[0], &c);
    CHECK(tessel_mesh_report_valid(&rep) && rep.self_intersections == 0);
    CHECK_MSG(rep.boundary_edges == 0 && rep.components == 1 && rep.genus == 0,
              "tiled front from a start: %zu boundary edges, %zu components", rep.boundary_edges,
              rep.components);
    CHECK(signed_volume(&tiled[0]) > 0.0);
    tri_key *tiled_have = malloc(tiled[0].triangle_count * sizeof *tiled_have);
    for (size_t t = 0; t < tiled[0].triangle_count; t++)
        tiled_have[t] = rotated(tiled[0].triangles + 3 * t);
    qsort(tiled_have, tiled[0].triangle_count, sizeof *tiled_have, cmp_tri_key);
    size_t remade = 0;
    for (size_t t = 0; t < kept; t++) {
        tri_key k = rotated(start + 3 * t);
        remade += !bsearch(&k, tiled_have, tiled[0].triangle_count, sizeof *tiled_have,
                           cmp_tri_key);
    }
    CHECK_MSG(remade > 0 && remade < kept / 4, "tiled: %zu of %zu starting triangles made again",
              remade, kept);
    printf("tiled front from a start: %zu of %zu starting triangles made again\n", remade, kept);
    free(tiled_have);
    tessel_mesh_free(&tiled[0]);
    tessel_mesh_free(&tiled[1]);
    /* A starting triangle with an id beyond the points is refused. */
    start[1] = (uint32_t)c.count;
    tessel_mesh bad;
    CHECK(tsl_advancing_front_from(&c, NULL, NULL, start, kept, NULL, &bad, NULL) ==
          TESSEL_ERR_INVALID_ARG);
    free(have);
    free(start);
    tessel_mesh_free(&again);
    tessel_mesh_free(&whole);
    tessel_cloud_free(&c);
}

int main(void)
{
    test_sphere();
    test_torus();
    test_disc();
    test_open_tube();
    test_two_sheets();
    test_noisy_sphere();
    test_noisy_holes();
    test_front_from_start();
    test_lines();
    test_tiles();
    test_duplicates_and_errors();
    test_triangle_test();
    return TEST_SUMMARY();
}
