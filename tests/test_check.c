/* Mesh check: exact predicates, topology on hand-made meshes with known
 * answers, and agreement with the independent evaluator meshcheck.
 *
 * tests/data/check/NAME.off are small meshes written by
 * tests/data/check/make_meshes.py; NAME.expected is meshcheck's JSON output
 * for them (the commands are in that script's header; meshcheck itself is
 * not part of this project). Counts must agree exactly; lengths, areas and
 * angles within a relative 1e-7 (meshcheck prints 10 significant digits and
 * computes closest points with another algorithm; both draw the same
 * samples, so in practice all printed digits agree); percentages within
 * 0.01 points (a sample exactly at the threshold could fall either way after
 * rounding; one sample of 20000 is 0.005 points). */
#include "check/check.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

/* ---- helpers ---- */

static char *slurp(const char *path)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, fp) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    if (buf)
        buf[n] = '\0';
    fclose(fp);
    return buf;
}

/* The OFF subset make_meshes.py writes ("OFF", counts, vertices, "3 a b c"
 * faces). A local reader keeps this test about the check alone. */
static bool read_off(const char *name, tessel_mesh *m)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/check/%s", TESSEL_TEST_DATA, name);
    char *text = slurp(path);
    if (!text)
        return false;
    char *p = text + 3;
    unsigned long nv = strtoul(p, &p, 10), nf = strtoul(p, &p, 10);
    strtoul(p, &p, 10);
    bool ok = tessel_mesh_alloc(m, nv, nf, 0, 0) == TESSEL_OK;
    for (size_t i = 0; ok && i < 3 * nv; i++)
        m->xyz[i] = (float)strtod(p, &p);
    for (size_t f = 0; ok && f < nf; f++) {
        ok = strtoul(p, &p, 10) == 3;
        for (int k = 0; k < 3; k++)
            m->triangles[3 * f + k] = (uint32_t)strtoul(p, &p, 10);
    }
    free(text);
    return ok;
}

static bool read_off_cloud(const char *name, tessel_cloud *c)
{
    tessel_mesh m;
    if (!read_off(name, &m))
        return false;
    bool ok = tessel_cloud_alloc(c, m.vertex_count, 0, 0) == TESSEL_OK;
    if (ok)
        memcpy(c->xyz, m.xyz, m.vertex_count * 3 * sizeof(float));
    tessel_mesh_free(&m);
    return ok;
}

/* The number after "key": in a meshcheck JSON object; NaN for null. */
static bool json_number(const char *json, const char *key, double *out)
{
    char pat[128];
    snprintf(pat, sizeof pat, "\"%s\": ", key);
    const char *p = strstr(json, pat);
    if (!p)
        return false;
    p += strlen(pat);
    if (strncmp(p, "null", 4) == 0)
        *out = NAN;
    else if (strncmp(p, "true", 4) == 0)
        *out = 1;
    else if (strncmp(p, "false", 5) == 0)
        *out = 0;
    else
        *out = strtod(p, NULL);
    return true;
}

static tessel_mesh make_mesh(const float *xyz, size_t nv, const uint32_t *tris, size_t nf)
{
    tessel_mesh m;
    if (tessel_mesh_alloc(&m, nv, nf, 0, 0) != TESSEL_OK)
        abort();
    memcpy(m.xyz, xyz, nv * 3 * sizeof *xyz);
    memcpy(m.triangles, tris, nf * 3 * sizeof *tris);
    return m;
}

static tessel_mesh_report check(const tessel_mesh *m)
{
    tessel_mesh_report r;
    memset(&r, 0, sizeof r);
    tessel_status st = tessel_mesh_check(m, NULL, &r);
    CHECK(st == TESSEL_OK);
    return r;
}

/* ---- predicates ---- */

static void test_orient2d(void)
{
    /* Kettner et al.'s classic: points within a few ulps of the line y = x
     * through (12,12) and (24,24); the sign must follow y - x exactly. */
    const double eps = 1.0 / 9007199254740992.0; /* 2^-53 */
    double q[2] = {12, 12}, r[2] = {24, 24};
    int wrong = 0, naive_wrong = 0;
    for (int i = 0; i < 64; i++)
        for (int j = 0; j < 64; j++) {
            double p[2] = {0.5 + i * eps, 0.5 + j * eps};
            int want = (j > i) - (j < i);
            double o = tsl_orient2d(p, q, r);
            wrong += ((o > 0) - (o < 0)) != want;
            double naive = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
            naive_wrong += ((naive > 0) - (naive < 0)) != want;
        }
    CHECK_MSG(wrong == 0, "%d wrong signs", wrong);
    CHECK(naive_wrong > 0); /* the test does reach the hard cases */
    double a[2] = {0, 0}, b[2] = {1, 0}, c[2] = {0, 1};
    CHECK(tsl_orient2d(a, b, c) > 0);
    CHECK(tsl_orient2d(a, c, b) < 0);
}

static void test_orient3d(void)
{
    /* The plane x = y through (12,12,0), (24,24,0), (12,12,1), and points
     * within ulps of it: the sign must follow y - x. */
    const double eps = 1.0 / 9007199254740992.0;
    double a[3] = {12, 12, 0}, b[3] = {24, 24, 0}, c[3] = {12, 12, 1};
    double off[3] = {0, 1, 0};
    int s = tsl_orient3d(a, b, c, off) > 0 ? 1 : -1; /* side of y > x */
    int wrong = 0;
    for (int i = 0; i < 48; i++)
        for (int j = 0; j < 48; j++) {
            double d[3] = {0.5 + i * eps, 0.5 + j * eps, 0.7};
            int want = s * ((j > i) - (j < i));
            double o = tsl_orient3d(a, b, c, d);
            wrong += ((o > 0) - (o < 0)) != want;
        }
    CHECK_MSG(wrong == 0, "%d wrong signs", wrong);
    /* Shewchuk's convention: positive when d is below abc (ccw from above). */
    double p0[3] = {0, 0, 0}, p1[3] = {1, 0, 0}, p2[3] = {0, 1, 0}, up[3] = {0, 0, 1};
    double down[3] = {0, 0, -1};
    CHECK(tsl_orient3d(p0, p1, p2, up) < 0);
    CHECK(tsl_orient3d(p0, p1, p2, down) > 0);
    /* Exactly coplanar points far from the origin with awkward floats: the
     * naive determinant is rarely exactly zero there. */
    int nonzero = 0;
    for (int k = 1; k < 200; k++) {
        double base[3] = {1000.1f * k, -77.3f * k, 3.7f};
        double u[3] = {0.25, 0.5, 0.125}, v[3] = {-0.5, 0.375, 1.0};
        double pa[3], pb[3], pc[3], pd[3];
        for (int t = 0; t < 3; t++) {
            pa[t] = base[t];
            pb[t] = base[t] + u[t];
            pc[t] = base[t] + v[t];
            pd[t] = base[t] + 3 * u[t] - 2 * v[t];
        }
        nonzero += tsl_orient3d(pa, pb, pc, pd) != 0.0;
    }
    CHECK_MSG(nonzero == 0, "%d coplanar quadruples not zero", nonzero);
}

/* Integer multiples of 2^-16 (a grid of floats, as the library's
 * coordinates are): differences below 2^28 steps, so the determinant is
 * exact in 128-bit integers, an oracle for the sign. */
__extension__ typedef __int128 i128;

static int exact_sign3(const double a[3], const double b[3], const double c[3],
                       const double d[3])
{
    int64_t m[3][3];
    for (int k = 0; k < 3; k++) {
        m[0][k] = (int64_t)((a[k] - d[k]) * 65536.0);
        m[1][k] = (int64_t)((b[k] - d[k]) * 65536.0);
        m[2][k] = (int64_t)((c[k] - d[k]) * 65536.0);
    }
    i128 det = (i128)m[0][2] * ((i128)m[1][0] * m[2][1] - (i128)m[2][0] * m[1][1]) +
               (i128)m[1][2] * ((i128)m[2][0] * m[0][1] - (i128)m[0][0] * m[2][1]) +
               (i128)m[2][2] * ((i128)m[0][0] * m[1][1] - (i128)m[1][0] * m[0][1]);
    return (det > 0) - (det < 0);
}

static double grid_coord(uint64_t r) { return (double)((int64_t)(r % (1u << 24)) - (1 << 23)) / 65536.0; }

static void test_orient3d_near_planes(void)
{
    /* Points d = a + i (b - a) + j (c - a) exactly on the plane of three
     * grid points, and the same moved by one grid step: zero or a sign
     * decided by one unit of a 75-bit product. The coordinates' differences
     * are exact in double, the case the exact stage takes first. */
    uint64_t state = 12345;
    int wrong = 0, zero = 0;
    for (int n = 0; n < 100000; n++) {
        double p[4][3];
        for (int v = 0; v < 3; v++)
            for (int k = 0; k < 3; k++) {
                state = state * 6364136223846793005ull + 1442695040888963407ull;
                p[v][k] = grid_coord(state >> 20);
            }
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        int i = (int)(state >> 61) - 3, j = (int)((state >> 58) & 7) - 3;
        int move = (int)((state >> 40) % 3) - 1, axis = (int)((state >> 30) % 3);
        for (int k = 0; k < 3; k++)
            p[3][k] = p[0][k] + i * (p[1][k] - p[0][k]) + j * (p[2][k] - p[0][k]) +
                      (k == axis ? move / 65536.0 : 0.0);
        int want = exact_sign3(p[0], p[1], p[2], p[3]);
        double o = tsl_orient3d(p[0], p[1], p[2], p[3]);
        wrong += ((o > 0) - (o < 0)) != want;
        zero += want == 0;
    }
    CHECK_MSG(wrong == 0, "%d wrong signs", wrong);
    CHECK_MSG(zero > 30000, "%d coplanar", zero);
}

/* ---- hand-made meshes ---- */

static const float oct_v[] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
static const uint32_t oct_f[] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4,
                                 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};

static void test_octahedron(void)
{
    tessel_mesh m = make_mesh(oct_v, 6, oct_f, 8);
    tessel_mesh_report r = check(&m);
    CHECK(r.vertices == 6 && r.triangles == 8 && r.edges == 12);
    CHECK(r.euler == 2 && r.genus == 0 && r.components == 1);
    CHECK(r.boundary_edges == 0 && r.boundary_loops == 0);
    CHECK(r.nonmanifold_edges == 0 && r.nonmanifold_vertices == 0);
    CHECK(r.oriented && r.orientable && r.orientation_conflicts == 0);
    CHECK(r.self_intersections == 0 && r.duplicate_triangles == 0);
    CHECK(r.degenerate_triangles == 0);
    CHECK(fabs(r.min_angle_deg - 60) < 1e-9 && fabs(r.max_angle_deg - 60) < 1e-9);
    CHECK(fabs(r.area - 4 * sqrt(3.0)) < 1e-9);
    CHECK(tessel_mesh_report_valid(&r));

    /* The same under a translation (offset and local shift): counts equal. */
    for (size_t i = 0; i < 18; i++)
        m.xyz[i] += 1000.0f;
    tessel_mesh_report r2 = check(&m);
    CHECK(r2.euler == 2 && r2.genus == 0 && r2.self_intersections == 0);
    tessel_mesh_free(&m);

    /* One hole: drop a triangle. */
    m = make_mesh(oct_v, 6, oct_f, 7);
    r = check(&m);
    CHECK(r.boundary_edges == 3 && r.boundary_loops == 1 && r.genus == -1);
    CHECK(r.euler == 1 && tessel_mesh_report_valid(&r));
    tessel_mesh_free(&m);

    /* A flipped triangle: three conflicting edges, still orientable. */
    uint32_t flipped[24];
    memcpy(flipped, oct_f, sizeof flipped);
    flipped[1] = 4;
    flipped[2] = 2;
    m = make_mesh(oct_v, 6, flipped, 8);
    r = check(&m);
    CHECK(r.orientation_conflicts == 3 && !r.oriented && r.orientable);
    CHECK(r.genus == 0 && !tessel_mesh_report_valid(&r));
    tessel_mesh_free(&m);

    /* A duplicate (reversed) triangle and a degenerate one. */
    uint32_t extra[30];
    memcpy(extra, oct_f, sizeof oct_f);
    extra[24] = 4, extra[25] = 2, extra[26] = 0; /* same set as triangle 0 */
    extra[27] = 0, extra[28] = 0, extra[29] = 1; /* repeated index */
    m = make_mesh(oct_v, 6, extra, 10);
    r = check(&m);
    CHECK(r.duplicate_triangles == 1 && r.degenerate_triangles == 1);
    CHECK(r.nonmanifold_edges == 3 && !tessel_mesh_report_valid(&r));
    tessel_mesh_free(&m);
}

static void test_torus_and_cones(void)
{
    /* Torus 10 x 6: genus 1, Euler 0. */
    enum { NU = 10, NV = 6 };
    float v[NU * NV * 3];
    uint32_t f[NU * NV * 6];
    for (int i = 0; i < NU; i++)
        for (int j = 0; j < NV; j++) {
            double a = 2 * 3.14159265358979 * i / NU, b = 2 * 3.14159265358979 * j / NV;
            float *p = v + 3 * (i * NV + j);
            p[0] = (float)((2 + 0.7 * cos(b)) * cos(a));
            p[1] = (float)((2 + 0.7 * cos(b)) * sin(a));
            p[2] = (float)(0.7 * sin(b));
            uint32_t q00 = (uint32_t)(i * NV + j), q10 = (uint32_t)(((i + 1) % NU) * NV + j);
            uint32_t q01 = (uint32_t)(i * NV + (j + 1) % NV);
            uint32_t q11 = (uint32_t)(((i + 1) % NU) * NV + (j + 1) % NV);
            uint32_t *t = f + 6 * (i * NV + j);
            t[0] = q00, t[1] = q10, t[2] = q11, t[3] = q00, t[4] = q11, t[5] = q01;
        }
    tessel_mesh m = make_mesh(v, NU * NV, f, NU * NV * 2);
    tessel_mesh_report r = check(&m);
    CHECK(r.euler == 0 && r.genus == 1 && r.boundary_edges == 0);
    CHECK(r.self_intersections == 0 && tessel_mesh_report_valid(&r));
    tessel_mesh_free(&m);

    /* Two closed cones (tetrahedra) touching at their apex. */
    const float cv[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, -1, 0, 0, 0, -1, 0, 0, 0, -1};
    const uint32_t cf[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3,
                           0, 5, 4, 0, 4, 6, 0, 6, 5, 4, 5, 6};
    m = make_mesh(cv, 7, cf, 8);
    r = check(&m);
    CHECK(r.nonmanifold_vertices == 1 && r.nonmanifold_edges == 0);
    CHECK(r.components == 2 && r.euler == 3 && r.genus == -1);
    CHECK(r.self_intersections == 0 && !tessel_mesh_report_valid(&r));
    tessel_mesh_free(&m);

    /* A non-manifold edge: three triangles on one edge. */
    const float ev[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5f, 0.5f, 1};
    const uint32_t ef[] = {0, 1, 2, 0, 2, 3, 0, 2, 4};
    m = make_mesh(ev, 5, ef, 3);
    r = check(&m);
    CHECK(r.nonmanifold_edges == 1 && !tessel_mesh_report_valid(&r));
    tessel_mesh_free(&m);
}

static void test_crossing(void)
{
    /* Two triangles crossing; then the same moved apart by a tiny gap. */
    float v[] = {0, 0, 0, 2, 0, 0, 1, 2, 0, 1, 1, -1, 1, 1, 1, 1, 3, 0};
    const uint32_t f[] = {0, 1, 2, 3, 4, 5};
    tessel_mesh m = make_mesh(v, 6, f, 2);
    tessel_mesh_report r = check(&m);
    CHECK(r.self_intersections == 1 && r.self_intersecting_triangles == 2);
    CHECK(!tessel_mesh_report_valid(&r));
    /* Only touching at one point (a vertex on the other's face) counts. */
    m.xyz[9 + 2] = 0.0f;
    m.xyz[12 + 2] = 1.0f;
    r = check(&m);
    CHECK(r.self_intersections == 1);
    m.xyz[9 + 2] = 1.0f / (1 << 24);
    r = check(&m);
    CHECK(r.self_intersections == 0);
    /* Skipping the test reports SIZE_MAX. */
    tessel_check_params p = tessel_check_params_default();
    p.self_intersections = 0;
    CHECK(tessel_mesh_check(&m, &p, &r) == TESSEL_OK);
    CHECK(r.self_intersections == SIZE_MAX);
    tessel_mesh_free(&m);
}

static void test_bad_input(void)
{
    tessel_mesh_report r;
    const uint32_t bad[] = {0, 1, 7};
    tessel_mesh m = make_mesh(oct_v, 6, bad, 1);
    CHECK(tessel_mesh_check(&m, NULL, &r) == TESSEL_ERR_INVALID_ARG);
    m.triangles[2] = 2;
    m.xyz[0] = NAN;
    CHECK(tessel_mesh_check(&m, NULL, &r) == TESSEL_ERR_INVALID_ARG);
    tessel_mesh_free(&m);
    CHECK(tessel_mesh_check(NULL, NULL, &r) == TESSEL_ERR_INVALID_ARG);
    /* An empty mesh is checked, and is not valid. */
    tessel_mesh empty;
    memset(&empty, 0, sizeof empty);
    CHECK(tessel_mesh_check(&empty, NULL, &r) == TESSEL_OK);
    CHECK(r.triangles == 0 && r.euler == 0 && !tessel_mesh_report_valid(&r));
    CHECK(isnan(r.min_angle_deg));
}

/* ---- agreement with meshcheck ---- */

static void compare_count(const char *name, const char *json, const char *key, double got)
{
    double want;
    if (!json_number(json, key, &want)) {
        CHECK_MSG(0, "%s: key %s missing", name, key);
        return;
    }
    CHECK_MSG(want == got || (isnan(want) && got == -1), "%s: %s = %.17g, meshcheck %.17g",
              name, key, got, want);
}

static void compare_real(const char *name, const char *json, const char *key, double got,
                         double rel, double abs_tol)
{
    double want;
    if (!json_number(json, key, &want)) {
        CHECK_MSG(0, "%s: key %s missing", name, key);
        return;
    }
    double tol = fmax(abs_tol, rel * fabs(want));
    CHECK_MSG((isnan(want) && isnan(got)) || fabs(got - want) <= tol,
              "%s: %s = %.10g, meshcheck %.10g", name, key, got, want);
}

static void compare_case(const char *expected, const char *mesh, const char *cloud,
                         const char *ref, uint32_t samples)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/check/%s", TESSEL_TEST_DATA, expected);
    char *json = slurp(path);
    tessel_mesh m, rm;
    tessel_cloud c;
    memset(&rm, 0, sizeof rm);
    memset(&c, 0, sizeof c);
    bool ok = json && read_off(mesh, &m) && (!cloud || read_off_cloud(cloud, &c)) &&
              (!ref || read_off(ref, &rm));
    CHECK_MSG(ok, "cannot read %s / %s", expected, mesh);
    if (!ok) {
        free(json);
        return;
    }
    tessel_check_params p = tessel_check_params_default();
    p.input = cloud ? &c : NULL;
    p.reference = ref ? &rm : NULL;
    p.samples = samples;
    tessel_mesh_report r;
    CHECK(tessel_mesh_check(&m, &p, &r) == TESSEL_OK);
    const char *n = expected;
    compare_count(n, json, "vertices", (double)r.vertices);
    compare_count(n, json, "faces", (double)r.triangles);
    compare_count(n, json, "unreferenced_vertices", (double)r.unreferenced_vertices);
    compare_count(n, json, "degenerate_faces", (double)r.degenerate_triangles);
    compare_count(n, json, "duplicate_faces", (double)r.duplicate_triangles);
    compare_count(n, json, "edges", (double)r.edges);
    compare_count(n, json, "boundary_edges", (double)r.boundary_edges);
    compare_count(n, json, "boundary_loops", (double)r.boundary_loops);
    compare_count(n, json, "nonmanifold_edges", (double)r.nonmanifold_edges);
    compare_count(n, json, "nonmanifold_vertices", (double)r.nonmanifold_vertices);
    compare_count(n, json, "components", (double)r.components);
    compare_count(n, json, "orientable", (double)r.orientable);
    compare_count(n, json, "inconsistently_oriented_edges", (double)r.orientation_conflicts);
    compare_count(n, json, "euler", (double)r.euler);
    compare_count(n, json, "genus", (double)r.genus);
    compare_count(n, json, "self_intersecting_pairs", (double)r.self_intersections);
    compare_count(n, json, "self_intersecting_faces", (double)r.self_intersecting_triangles);
    compare_real(n, json, "bbox_diag", r.bbox_diagonal, 1e-7, 0);
    compare_real(n, json, "area", r.area, 1e-7, 0);
    compare_real(n, json, "min_angle_deg_min", r.min_angle_deg, 1e-7, 0);
    compare_real(n, json, "min_angle_deg_mean", r.mean_min_angle_deg, 1e-7, 0);
    compare_real(n, json, "max_angle_deg_max", r.max_angle_deg, 1e-7, 0);
    if (cloud) {
        double d = r.input_bbox_diagonal;
        compare_count(n, json, "input_points", (double)r.input_points);
        compare_count(n, json, "input_points_used", (double)r.input_as_vertices);
        compare_real(n, json, "input_bbox_diag", d, 1e-7, 0);
        compare_real(n, json, "dist_input_to_mesh_mean_rel", r.input_distance_mean / d, 1e-7,
                     1e-12);
        compare_real(n, json, "dist_input_to_mesh_rms_rel", r.input_distance_rms / d, 1e-7,
                     1e-12);
        compare_real(n, json, "dist_input_to_mesh_max_rel", r.input_distance_max / d, 1e-7,
                     1e-12);
    }
    if (ref) {
        double d = r.reference_bbox_diagonal;
        compare_real(n, json, "ref_bbox_diag", d, 1e-7, 0);
        compare_real(n, json, "dist_out_to_ref_mean_rel", r.accuracy / d, 1e-7, 0);
        compare_real(n, json, "dist_ref_to_out_mean_rel", r.completeness / d, 1e-7, 0);
        compare_real(n, json, "chamfer_rel", r.chamfer / d, 1e-7, 0);
        compare_real(n, json, "hausdorff_rel", r.hausdorff / d, 1e-7, 0);
        compare_real(n, json, "precision", r.precision, 0, 0.01);
        compare_real(n, json, "recall", r.recall, 0, 0.01);
        compare_real(n, json, "fscore", r.fscore, 0, 0.01);
        compare_real(n, json, "tau_rel", r.tau / d, 1e-9, 0);
    }
    free(json);
    tessel_mesh_free(&m);
    tessel_mesh_free(&rm);
    tessel_cloud_free(&c);
}

static void test_meshcheck_agreement(void)
{
    static const char *const names[] = {"sphere", "hole", "torus", "nm_edge", "nm_vertex",
                                        "flipped", "duplicate", "degenerate", "two_components",
                                        "crossing", "soup", "soup_planar"};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        char off[64], exp[64];
        snprintf(off, sizeof off, "%s.off", names[i]);
        snprintf(exp, sizeof exp, "%s.expected", names[i]);
        compare_case(exp, off, NULL, NULL, 0);
    }
    compare_case("hole_vs_sphere.expected", "hole.off", "sphere_cloud.off", "sphere_fine.off",
                 20000);
    compare_case("sphere_vs_fine.expected", "sphere.off", "sphere_cloud.off", "sphere_fine.off",
                 20000);
}

/* Same figures whatever the thread count. */
static void test_threads(void)
{
    tessel_mesh m, ref;
    tessel_cloud c;
    if (!read_off("hole.off", &m) || !read_off("sphere_fine.off", &ref) ||
        !read_off_cloud("sphere_cloud.off", &c)) {
        CHECK(0);
        return;
    }
    tessel_check_params p = tessel_check_params_default();
    p.input = &c;
    p.reference = &ref;
    p.samples = 5000;
    tessel_mesh_report r[2];
    for (int t = 0; t < 2; t++) {
        p.threads = t == 0 ? 1 : 3;
        CHECK(tessel_mesh_check(&m, &p, &r[t]) == TESSEL_OK);
    }
    CHECK(r[0].edges == r[1].edges && r[0].self_intersections == r[1].self_intersections);
    CHECK(r[0].input_as_vertices == r[1].input_as_vertices);
    CHECK(r[0].input_distance_mean == r[1].input_distance_mean);
    CHECK(r[0].input_distance_max == r[1].input_distance_max);
    CHECK(r[0].chamfer == r[1].chamfer && r[0].hausdorff == r[1].hausdorff);
    CHECK(r[0].fscore == r[1].fscore);
    tessel_mesh_free(&m);
    tessel_mesh_free(&ref);
    tessel_cloud_free(&c);
}

/* The CLI: exit 0 for a valid manifold (boundaries allowed), 4 for an
 * invalid one, 2 for a missing file, 1 for a bad command line. */
static int run_cli(const char *args)
{
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "\"%s\" check %s > /dev/null 2>&1", TESSEL_CLI, args);
    int rc = system(cmd);
    return rc != -1 && WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

static void test_cli(void)
{
    char args[1536];
    const char *d = TESSEL_TEST_DATA "/check";
    snprintf(args, sizeof args, "%s/sphere.off", d);
    CHECK(run_cli(args) == 0);
    snprintf(args, sizeof args, "%s/hole.off --json", d);
    CHECK(run_cli(args) == 0);
    static const char *const invalid[] = {"nm_edge", "nm_vertex", "flipped", "duplicate",
                                          "degenerate", "crossing"};
    for (size_t i = 0; i < sizeof invalid / sizeof *invalid; i++) {
        snprintf(args, sizeof args, "%s/%s.off", d, invalid[i]);
        CHECK_MSG(run_cli(args) == 4, "%s", invalid[i]);
    }
    snprintf(args, sizeof args, "%s/hole.off --input %s/sphere_cloud.off --ref %s/sphere_fine.off "
             "--samples 2000 --tau-rel 0.02",
             d, d, d);
    CHECK(run_cli(args) == 0);
    snprintf(args, sizeof args, "%s/no_such_mesh.off", d);
    CHECK(run_cli(args) == 2);
    snprintf(args, sizeof args, "%s/sphere.off --ref %s/no_such_ref.off", d, d);
    CHECK(run_cli(args) == 2);
    snprintf(args, sizeof args, "%s/sphere.off --samples zero", d);
    CHECK(run_cli(args) == 1);
    CHECK(run_cli("") == 1);
}

int main(void)
{
    test_orient2d();
    test_orient3d();
    test_orient3d_near_planes();
    test_octahedron();
    test_torus_and_cones();
    test_crossing();
    test_bad_input();
    test_meshcheck_agreement();
    test_threads();
    test_cli();
    return TEST_SUMMARY();
}
