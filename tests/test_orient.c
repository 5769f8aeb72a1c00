/* The orientation check by ray parity (src/mesh/orient.c) on a triangulated
 * sphere whose triangles' windings the test sets: it must find a region
 * turned inward, mark its rim, and leave alone what parity cannot judge
 * (a whole component, an open surface). And tiles oriented against each
 * other across a cut (src/mesh/tile_orient.c) that a plane meets at a
 * shallow angle. And the removal of triangles at vertices with several
 * fans (src/mesh/topology.c), which the repairs after an orientation check
 * rely on. */
#include "mesh/mesh.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define RINGS 24
#define SECTORS 48

/* xyz and tri hold 2 + (rings - 1) sectors vertices and 2 rings sectors
 * triangles. */
typedef struct sphere_mesh {
    float *xyz;
    uint32_t *tri;
    size_t nv, nt;
    int rings, sectors;
} sphere_mesh;

static uint32_t ring_vertex(const sphere_mesh *m, int i, int j)
{
    if (i == 0)
        return 0;
    if (i == m->rings)
        return (uint32_t)(1 + (m->rings - 1) * m->sectors);
    return (uint32_t)(1 + (i - 1) * m->sectors + j % m->sectors);
}

static void centroid(const sphere_mesh *m, size_t t, double c[3])
{
    for (int k = 0; k < 3; k++)
        c[k] = (m->xyz[3 * m->tri[3 * t] + (size_t)k] + m->xyz[3 * m->tri[3 * t + 1] + (size_t)k] +
                m->xyz[3 * m->tri[3 * t + 2] + (size_t)k]) /
               3.0;
}

static void add_tri(sphere_mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    if (a == b || b == c || a == c)
        return;
    uint32_t *v = m->tri + 3 * m->nt++;
    v[0] = a;
    v[1] = b;
    v[2] = c;
}

/* A UV sphere of radius 1, every triangle facing out. */
static void make_sphere(sphere_mesh *m)
{
    m->nv = m->nt = 0;
    for (int i = 0; i <= m->rings; i++)
        for (int j = 0; j < (i == 0 || i == m->rings ? 1 : m->sectors); j++) {
            double th = PI * i / m->rings, ph = 2.0 * PI * j / m->sectors;
            float *p = m->xyz + 3 * ring_vertex(m, i, j);
            p[0] = (float)(sin(th) * cos(ph));
            p[1] = (float)(sin(th) * sin(ph));
            p[2] = (float)cos(th);
            m->nv++;
        }
    for (int i = 0; i < m->rings; i++)
        for (int j = 0; j < m->sectors; j++) {
            uint32_t a = ring_vertex(m, i, j), b = ring_vertex(m, i + 1, j),
                     c = ring_vertex(m, i + 1, j + 1), d = ring_vertex(m, i, j + 1);
            add_tri(m, a, b, c);
            add_tri(m, a, c, d);
        }
    /* Winding outward whatever the formula above gives. */
    for (size_t t = 0; t < m->nt; t++) {
        double p[3][3], u[3], w[3], n[3], c[3];
        for (int i = 0; i < 3; i++)
            tsl_load(m->xyz + 3 * (size_t)m->tri[3 * t + (size_t)i], p[i]);
        tsl_sub(p[1], p[0], u);
        tsl_sub(p[2], p[0], w);
        tsl_cross(u, w, n);
        centroid(m, t, c);
        if (tsl_dot(n, c) < 0.0) {
            uint32_t x = m->tri[3 * t + 1];
            m->tri[3 * t + 1] = m->tri[3 * t + 2];
            m->tri[3 * t + 2] = x;
        }
    }
}

static void reverse_where(sphere_mesh *m, double zmin)
{
    for (size_t t = 0; t < m->nt; t++) {
        double c[3];
        centroid(m, t, c);
        if (c[2] > zmin) {
            uint32_t x = m->tri[3 * t + 1];
            m->tri[3 * t + 1] = m->tri[3 * t + 2];
            m->tri[3 * t + 2] = x;
        }
    }
}

static size_t count_marked(const uint8_t *mark, size_t nt)
{
    size_t n = 0;
    for (size_t t = 0; t < nt; t++)
        n += mark[t] != 0;
    return n;
}

static float small_xyz[3 * (2 + (RINGS - 1) * SECTORS)];
static uint32_t small_tri[3 * 2 * RINGS * SECTORS];
static sphere_mesh m = {small_xyz, small_tri, 0, 0, RINGS, SECTORS};
static uint8_t mark[2 * RINGS * SECTORS], mark2[2 * RINGS * SECTORS];

static void test_outward(void)
{
    make_sphere(&m);
    size_t flipped = 1;
    CHECK(tsl_orient_check(m.xyz, m.nv, m.tri, m.nt, 1, mark, &flipped) == TESSEL_OK);
    CHECK(flipped == 0 && count_marked(mark, m.nt) == 0);
}

/* The cap above z = 0.5 wound inward: every cap triangle marked, nothing
 * else; 2 exactly on the cap's rim. The same for any thread count. */
static void test_inward_cap(void)
{
    make_sphere(&m);
    reverse_where(&m, 0.5);
    size_t flipped = 0, cap = 0, wrong = 0, rim_wrong = 0;
    CHECK(tsl_orient_check(m.xyz, m.nv, m.tri, m.nt, 2, mark, &flipped) == TESSEL_OK);
    for (size_t t = 0; t < m.nt; t++) {
        double c[3];
        centroid(&m, t, c);
        bool in_cap = c[2] > 0.5;
        cap += in_cap;
        wrong += in_cap != (mark[t] != 0);
        if (!in_cap)
            continue;
        /* On the rim: shares an edge with a triangle outside the cap. */
        bool rim = false;
        for (size_t u = 0; u < m.nt && !rim; u++) {
            double d[3];
            centroid(&m, u, d);
            if (d[2] > 0.5)
                continue;
            int shared = 0;
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    shared += m.tri[3 * t + (size_t)i] == m.tri[3 * u + (size_t)j];
            rim = shared == 2;
        }
        rim_wrong += rim != (mark[t] == 2);
    }
    CHECK_MSG(cap > 100 && wrong == 0 && rim_wrong == 0 && flipped == cap,
              "cap of %zu: %zu misjudged, %zu rim marks wrong, %zu flipped", cap, wrong,
              rim_wrong, flipped);
    CHECK(tsl_orient_check(m.xyz, m.nv, m.tri, m.nt, 1, mark2, &flipped) == TESSEL_OK);
    CHECK(memcmp(mark, mark2, m.nt) == 0);
}

/* A whole sphere inward is one component: its orientation is the front's
 * business, not this check's. */
static void test_whole_inward(void)
{
    make_sphere(&m);
    reverse_where(&m, -2.0);
    size_t flipped = 1;
    CHECK(tsl_orient_check(m.xyz, m.nv, m.tri, m.nt, 1, mark, &flipped) == TESSEL_OK);
    CHECK(flipped == 0 && count_marked(mark, m.nt) == 0);
}

/* An open cap (the sphere above z = 0.6) with its top wound inward: the
 * rays leave through the opening whichever way they point, so parity
 * cannot judge and nothing is marked. */
static void test_open_cap(void)
{
    make_sphere(&m);
    size_t w = 0;
    for (size_t t = 0; t < m.nt; t++) {
        double c[3];
        centroid(&m, t, c);
        if (c[2] > 0.6)
            memmove(m.tri + 3 * w++, m.tri + 3 * t, 3 * sizeof *m.tri);
    }
    m.nt = w;
    reverse_where(&m, 0.85);
    size_t flipped = 1;
    CHECK(tsl_orient_check(m.xyz, m.nv, m.tri, m.nt, 1, mark, &flipped) == TESSEL_OK);
    CHECK_MSG(m.nt > 200 && flipped == 0, "open cap of %zu: %zu marked", m.nt, flipped);
}

/* A sphere of 1.96 million triangles, so that the rays come from a
 * sample of one triangle in 30, with small flaps (separate triangles)
 * lifted a tenth of a triangle above 3,000 of its triangles, each covering
 * that triangle's centroid and no other: the rays from such a triangle
 * cross the flap, an odd count. A region must not turn on the votes of
 * one triangle: nothing is marked. Then the cap above z = 0.5 wound
 * inward: it turns, flaps or not. */
static void test_sampled_rays(void)
{
    enum { BIG_RINGS = 700, BIG_SECTORS = 1400, FLAPS = 3000 };
    size_t nv = 2 + (size_t)(BIG_RINGS - 1) * BIG_SECTORS + 3 * FLAPS,
           nt = 2 * (size_t)BIG_RINGS * BIG_SECTORS + FLAPS;
    sphere_mesh b = {malloc(3 * nv * sizeof(float)), malloc(3 * nt * sizeof(uint32_t)), 0, 0,
                     BIG_RINGS, BIG_SECTORS};
    uint8_t *marks = malloc(nt);
    CHECK(b.xyz && b.tri && marks);
    if (!b.xyz || !b.tri || !marks)
        goto done;
    make_sphere(&b);
    size_t sphere_nt = b.nt;
    for (int f = 0; f < FLAPS; f++) {
        size_t t = ((size_t)f * 653 + 1000) % sphere_nt;
        double p[3][3], c[3] = {0, 0, 0}, u[3], w[3], n[3];
        for (int i = 0; i < 3; i++) {
            tsl_load(b.xyz + 3 * (size_t)b.tri[3 * t + (size_t)i], p[i]);
            for (int k = 0; k < 3; k++)
                c[k] += p[i][k] / 3.0;
        }
        tsl_sub(p[1], p[0], u);
        tsl_sub(p[2], p[0], w);
        tsl_cross(u, w, n);
        double size = sqrt(tsl_norm(n));
        tsl_normalize(n);
        /* A copy of the triangle shrunk to a fifth about its centroid. */
        uint32_t *v = b.tri + 3 * b.nt++;
        for (int i = 0; i < 3; i++) {
            v[i] = (uint32_t)b.nv++;
            for (int k = 0; k < 3; k++)
                b.xyz[3 * (size_t)v[i] + (size_t)k] =
                    (float)(c[k] + 0.2 * (p[i][k] - c[k]) + 0.1 * size * n[k]);
        }
    }
    size_t flipped = 1;
    CHECK(tsl_orient_check(b.xyz, b.nv, b.tri, b.nt, 2, marks, &flipped) == TESSEL_OK);
    CHECK_MSG(flipped == 0 && count_marked(marks, b.nt) == 0,
              "flaps over single triangles: %zu triangles turned", flipped);
    reverse_where(&b, 0.5);
    size_t cap = 0, missed = 0, beyond = 0;
    CHECK(tsl_orient_check(b.xyz, b.nv, b.tri, b.nt, 2, marks, &flipped) == TESSEL_OK);
    for (size_t t = 0; t < sphere_nt; t++) {
        double c[3];
        centroid(&b, t, c);
        cap += c[2] > 0.5;
        missed += c[2] > 0.5 && !marks[t];
        beyond += c[2] <= 0.5 && marks[t];
    }
    /* From sampled votes the rim is found to within a ring of triangles
     * (the averaging's reach), not exactly. */
    CHECK_MSG(cap > 100000 && missed + beyond < 4 * BIG_SECTORS,
              "cap of %zu: %zu missed, %zu beyond", cap, missed, beyond);
done:
    free(b.xyz);
    free(b.tri);
    free(marks);
}

/* A plane meeting the cut x = 0 at 20 degrees, meshed on each side beyond
 * a band of 3 (a grid of unit spacing), the far side's triangles turned:
 * the gap is 3 / sin(20 deg) = 8.8 wide along the plane on each side,
 * beyond the pair radius of 2 bands and 4 spacings, so the search must
 * widen with the angle for the two sides to meet and agree. */
#define GRID_U 61
#define GRID_V 21
static void test_tiles_shallow_cut(void)
{
    static float xyz[3 * GRID_U * GRID_V], dcut[GRID_U * GRID_V];
    static uint8_t axis[GRID_U * GRID_V];
    static uint32_t tri[6 * GRID_U * GRID_V], comp[2 * GRID_U * GRID_V];
    const double theta = 20.0 * PI / 180.0, band = 3.0, gap = band / sin(theta);
    for (int i = 0; i < GRID_U; i++)
        for (int j = 0; j < GRID_V; j++) {
            size_t v = (size_t)i * GRID_V + (size_t)j;
            double u = i - GRID_U / 2;
            xyz[3 * v] = (float)(-u * sin(theta));
            xyz[3 * v + 1] = (float)j;
            xyz[3 * v + 2] = (float)(u * cos(theta));
            dcut[v] = fabsf(xyz[3 * v]);
            axis[v] = 0;
        }
    size_t nt = 0;
    for (int i = 0; i + 1 < GRID_U; i++) {
        double u0 = i - GRID_U / 2, u1 = u0 + 1.0;
        int side = u1 <= -gap ? 0 : u0 >= gap ? 1 : -1;
        for (int j = 0; side >= 0 && j + 1 < GRID_V; j++) {
            uint32_t a = (uint32_t)(i * GRID_V + j), b = a + GRID_V, c = b + 1, d = a + 1;
            uint32_t q[2][3] = {{a, b, c}, {a, c, d}};
            for (int k = 0; k < 2; k++, nt++) {
                tri[3 * nt] = q[k][0];
                tri[3 * nt + 1] = side ? q[k][2] : q[k][1];
                tri[3 * nt + 2] = side ? q[k][1] : q[k][2];
                comp[nt] = (uint32_t)side;
            }
        }
    }
    uint8_t drop[2];
    CHECK(tsl_orient_tiles(tri, comp, nt, 2, xyz, dcut, axis, band + 4.0, 2.0 * band + 4.0, 2.0,
                           0, drop) == TESSEL_OK);
    /* Every triangle's normal along the first one's. */
    double n0[3], n[3], p[3][3];
    size_t against = 0;
    for (size_t t = 0; t < nt; t++) {
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++)
                p[k][c] = xyz[3 * (size_t)tri[3 * t + (size_t)k] + (size_t)c];
        tsl_tri_normal(p[0], p[1], p[2], t ? n : n0);
        against += t && n[0] * n0[0] + n[1] * n0[1] + n[2] * n0[2] < 0.0;
    }
    CHECK_MSG(against == 0 && !drop[0] && !drop[1],
              "shallow cut: %zu of %zu triangles against the first", against, nt);
}

/* A closed box whose top face, turned inward, sends its rays straight
 * through vertices of the bottom face: the top and the sides are a grid of
 * squares 3 units wide and the bottom one of unit squares, so every top
 * triangle's centroid lies over a bottom vertex with six triangles around
 * it. Counting each triangle the ray meets there would give six crossings
 * (outward); a ray crosses the bottom once. */
#define BOX 18
static uint32_t box_id[BOX + 1][BOX + 1][BOX + 1];
static float box_xyz[3 * 4 * (BOX + 1) * (BOX + 1)];
static uint32_t box_tri[3 * 2 * 2 * BOX * BOX];
static size_t box_nv, box_nt;

static uint32_t box_vertex(int x, int y, int z)
{
    if (box_id[x][y][z] == TESSEL_NONE) {
        box_xyz[3 * box_nv] = (float)x;
        box_xyz[3 * box_nv + 1] = (float)y;
        box_xyz[3 * box_nv + 2] = (float)z;
        box_id[x][y][z] = (uint32_t)box_nv++;
    }
    return box_id[x][y][z];
}

/* The squares of side `step` on the face of axis k at height `at`, facing
 * +k when out is set (else -k), two triangles each. */
static void box_face(int k, int at, int step, bool out)
{
    for (int a = 0; a < BOX; a += step)
        for (int b = 0; b < BOX; b += step) {
            int c[4][3], uv[4][2] = {{a, b}, {a + step, b}, {a + step, b + step}, {a, b + step}};
            uint32_t v[4];
            for (int i = 0; i < 4; i++) {
                c[i][k] = at;
                c[i][(k + 1) % 3] = uv[i][0];
                c[i][(k + 2) % 3] = uv[i][1];
                v[i] = box_vertex(c[i][0], c[i][1], c[i][2]);
            }
            uint32_t t[2][3] = {{v[0], v[1], v[2]}, {v[0], v[2], v[3]}};
            for (int j = 0; j < 2; j++) {
                uint32_t *w = box_tri + 3 * box_nt++;
                w[0] = t[j][0];
                w[1] = out ? t[j][1] : t[j][2];
                w[2] = out ? t[j][2] : t[j][1];
            }
        }
}

static void test_rays_through_vertices(void)
{
    memset(box_id, 0xff, sizeof box_id);
    box_nv = box_nt = 0;
    box_face(2, BOX, 3, false); /* the top, turned inward: first */
    size_t top = box_nt;
    box_face(2, 0, 1, false);
    for (int k = 0; k < 2; k++) {
        box_face(k, 0, 3, false);
        box_face(k, BOX, 3, true);
    }
    static uint8_t bmark[3 * 2 * 2 * BOX * BOX];
    size_t flipped = 0;
    CHECK(tsl_orient_check(box_xyz, box_nv, box_tri, box_nt, 2, bmark, &flipped) == TESSEL_OK);
    size_t top_marked = count_marked(bmark, top);
    /* The averaging takes the top's rim to its outward neighbours'
     * side; nothing else may turn. */
    CHECK_MSG(2 * top_marked > top && flipped == top_marked,
              "rays through vertices: %zu of the %zu inward triangles found, %zu marked", top_marked,
              top, flipped);
}

/* Border edges leaving vertex v among the nt triangles: more than one is
 * more than one fan. */
static unsigned fans_at(const uint32_t *tri, size_t nt, uint32_t v)
{
    unsigned border = 0;
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            if (tri[3 * t + (size_t)k] != v)
                continue;
            uint32_t after = tri[3 * t + (size_t)(k + 1) % 3];
            bool twin = false;
            for (size_t u = 0; u < nt && !twin; u++)
                for (int i = 0; i < 3; i++)
                    twin = twin || (tri[3 * u + (size_t)i] == v &&
                                    tri[3 * u + (size_t)(i + 2) % 3] == after);
            border += !twin;
        }
    return border;
}

/* The sphere less a pseudo-random fraction of its triangles (and, for
 * `local`, only those at a few vertices), so that many vertices have
 * several fans: afterwards none may have, the triangles kept stay in their
 * order and touched comes back cleared. */
static void test_single_fans(bool local, uint32_t seed)
{
    make_sphere(&m);
    static uint32_t before[3 * 2 * RINGS * SECTORS];
    static uint8_t touched[2 + (RINGS - 1) * SECTORS];
    memset(touched, 0, sizeof touched);
    size_t w = 0;
    uint32_t x = seed;
    for (size_t t = 0; t < m.nt; t++) {
        x = x * 1664525u + 1013904223u;
        const uint32_t *v = m.tri + 3 * t;
        bool near = !local || v[0] % 97 < 3 || v[1] % 97 < 3 || v[2] % 97 < 3;
        if (near && (x >> 24) < 80) { /* about a third, where dropped */
            touched[v[0]] = touched[v[1]] = touched[v[2]] = 1;
            continue;
        }
        memcpy(m.tri + 3 * w++, v, 3 * sizeof *v);
    }
    m.nt = w;
    memcpy(before, m.tri, 3 * m.nt * sizeof *before);
    size_t nt = m.nt, several = 0;
    for (uint32_t v = 0; v < m.nv; v++)
        several += fans_at(m.tri, nt, v) > 1;
    CHECK_MSG(several > 0, "single fans: the test mesh has no vertex with several fans");
    CHECK(tsl_single_fans(m.nv, m.tri, &nt, touched, NULL, NULL) == TESSEL_OK);
    size_t left = 0;
    for (uint32_t v = 0; v < m.nv; v++) {
        left += fans_at(m.tri, nt, v) > 1;
        CHECK_MSG(!touched[v], "single fans: vertex %u still touched", v);
    }
    CHECK_MSG(left == 0, "single fans (%s, seed %u): %zu vertices with several fans of %zu",
              local ? "local" : "everywhere", seed, left, several);
    /* In order: the kept triangles are a subsequence of those before. */
    size_t j = 0;
    for (size_t t = 0; t < m.nt && j < nt; t++)
        j += memcmp(before + 3 * t, m.tri + 3 * j, 3 * sizeof *before) == 0;
    CHECK_MSG(j == nt, "single fans: the kept triangles are out of order");
    CHECK_MSG(nt < m.nt && nt > m.nt / 4, "single fans: %zu of %zu triangles kept", nt, m.nt);
}

/* Components of many pieces joined in parallel: the same roots (the
 * smallest vertex of each piece) as a serial union-find, on 1, 2 and 4
 * threads. Triangles stay within blocks of 64 vertices, a few join
 * neighbouring blocks, some are removed (first vertex TESSEL_NONE). */
static void test_components_threads(void)
{
    enum { NV = 1 << 18, NT = 3 * NV / 2 };
    uint32_t *tri = malloc(3 * NT * sizeof *tri);
    uint32_t *ref = malloc(NV * sizeof *ref), *root = malloc(NV * sizeof *root);
    CHECK(tri && ref && root);
    if (!tri || !ref || !root)
        goto done;
    uint32_t x = 7;
    for (size_t t = 0; t < NT; t++) {
        uint32_t r[4];
        for (int k = 0; k < 4; k++)
            r[k] = x = x * 1664525u + 1013904223u;
        uint32_t base = (r[0] >> 8) % (NV / 64) * 64;
        uint32_t span = (r[3] >> 20) % 500 == 0 ? 128 : 64;
        for (int k = 0; k < 3; k++)
            tri[3 * t + (size_t)k] = (base + (r[k + 1] >> 12) % span) % NV;
        if ((r[3] >> 16) % 50 == 0)
            tri[3 * t] = TESSEL_NONE;
    }
    for (uint32_t v = 0; v < NV; v++)
        ref[v] = v;
    for (size_t t = 0; t < NT; t++) {
        const uint32_t *c = tri + 3 * t;
        if (c[0] == TESSEL_NONE)
            continue;
        tsl_uf_unite(ref, c[0], c[1]);
        tsl_uf_unite(ref, c[0], c[2]);
    }
    size_t pieces = 0;
    for (uint32_t v = 0; v < NV; v++) {
        ref[v] = tsl_uf_find(ref, v);
        pieces += ref[v] == v;
    }
    CHECK_MSG(pieces > 1000 && pieces < NV / 2, "components: %zu pieces", pieces);
    const int threads[3] = {1, 2, 4};
    for (int i = 0; i < 3; i++) {
        tsl_vertex_components(tri, NT, NV, threads[i], root);
        size_t differ = 0;
        for (uint32_t v = 0; v < NV; v++)
            differ += root[v] != ref[v];
        CHECK_MSG(differ == 0, "components on %d threads: %zu roots differ", threads[i], differ);
    }
done:
    free(tri);
    free(ref);
    free(root);
}

int main(void)
{
    test_components_threads();
    test_tiles_shallow_cut();
    test_outward();
    test_inward_cap();
    test_whole_inward();
    test_open_cap();
    test_rays_through_vertices();
    test_sampled_rays();
    for (uint32_t seed = 1; seed <= 3; seed++) {
        test_single_fans(false, seed);
        test_single_fans(true, seed);
    }
    return TEST_SUMMARY();
}
