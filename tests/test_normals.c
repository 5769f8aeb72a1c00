/* Normals: a plane gives +-z, all consistent; on a sphere and a torus every
 * normal is within a few degrees of the analytic outward normal and points
 * outward; two separate spheres are both outward; with a viewpoint, normals
 * face it; 1 and 2 threads give the same bits; progress is reported and can
 * cancel. */
#include "tessel.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double PI = 3.141592653589793;

static uint64_t rng_state = 99;
static double unif(void)
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

static void sphere_point(float *p, const double c[3], double r)
{
    double z = 2 * unif() - 1, phi = 2 * PI * unif(), s = sqrt(1 - z * z);
    p[0] = (float)(c[0] + r * s * cos(phi));
    p[1] = (float)(c[1] + r * s * sin(phi));
    p[2] = (float)(c[2] + r * z);
}

/* Largest angle (degrees) between estimated and reference normals, signed
 * (orientation counts) or not. */
typedef void (*ref_fn)(const float *p, double n[3]);

static double worst_angle(const tessel_cloud *c, ref_fn ref, int signed_angle)
{
    double worst = 0.0;
    for (size_t i = 0; i < c->count; i++) {
        double r[3];
        ref(c->xyz + 3 * i, r);
        const float *n = c->normals + 3 * i;
        double d = n[0] * r[0] + n[1] * r[1] + n[2] * r[2];
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (!signed_angle)
            d = fabs(d);
        double a = acos(fmin(1.0, fmax(-1.0, d / len))) * 180.0 / PI;
        if (!(a <= worst))
            worst = a;
    }
    return worst;
}

static double sphere_c[3] = {0.3, -0.2, 0.1};
static void sphere_ref(const float *p, double n[3])
{
    for (int a = 0; a < 3; a++)
        n[a] = p[a] - sphere_c[a];
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int a = 0; a < 3; a++)
        n[a] /= l;
}

static const double TR = 1.0, Tr = 0.4;
static void torus_ref(const float *p, double n[3])
{
    double rho = sqrt((double)p[0] * p[0] + (double)p[1] * p[1]);
    double cx = TR * p[0] / rho, cy = TR * p[1] / rho;
    n[0] = p[0] - cx;
    n[1] = p[1] - cy;
    n[2] = p[2];
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int a = 0; a < 3; a++)
        n[a] /= l;
}

static void up_ref(const float *p, double n[3])
{
    (void)p;
    n[0] = n[1] = 0.0;
    n[2] = 1.0;
}

/* Two spheres: the reference is the nearer centre's outward direction. */
static double two_c[2][3] = {{0, 0, 0}, {5, 1, -2}};
static void two_ref(const float *p, double n[3])
{
    double best = INFINITY;
    for (int s = 0; s < 2; s++) {
        double d[3], l;
        for (int a = 0; a < 3; a++)
            d[a] = p[a] - two_c[s][a];
        l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (fabs(l - 1.0) < best) {
            best = fabs(l - 1.0);
            for (int a = 0; a < 3; a++)
                n[a] = d[a] / l;
        }
    }
}

typedef struct progress_log {
    int calls, cancel_at;
    double last;
    int monotone;
} progress_log;

static int on_progress(void *user, const char *stage, double fraction)
{
    progress_log *log = user;
    log->calls++;
    if (strcmp(stage, "normals") != 0 || fraction < log->last || fraction > 1.0)
        log->monotone = 0;
    log->last = fraction;
    return log->cancel_at > 0 && log->calls >= log->cancel_at;
}

static void test_plane(void)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 3000, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < c.count; i++) {
        c.xyz[3 * i] = (float)unif();
        c.xyz[3 * i + 1] = (float)unif();
        c.xyz[3 * i + 2] = 2.0f;
    }
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_OK && c.normals);
    /* Every normal exactly +-z, and all the same sign (+z: the seed). */
    CHECK(worst_angle(&c, up_ref, 1) < 1e-3);
    /* Unoriented: still +-z. */
    tessel_normals_params p = tessel_normals_params_default();
    p.orient = 0;
    CHECK(tessel_normals_estimate(&c, &p, NULL) == TESSEL_OK);
    CHECK(worst_angle(&c, up_ref, 0) < 1e-3);
    tessel_cloud_free(&c);
}

static void test_sphere_torus(void)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 6000, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < c.count; i++)
        sphere_point(c.xyz + 3 * i, sphere_c, 1.0);
    progress_log log = {0, 0, 0.0, 1};
    tessel_callbacks cb = {on_progress, NULL, &log};
    CHECK(tessel_normals_estimate(&c, NULL, &cb) == TESSEL_OK);
    double w = worst_angle(&c, sphere_ref, 1);
    CHECK_MSG(w < 5.0, "sphere: worst oriented angle %.2f degrees", w);
    CHECK_MSG(log.calls >= 10 && log.calls <= 100 && log.monotone && log.last == 1.0,
              "%d progress calls, last %g", log.calls, log.last);

    /* Cancelling leaves the normals as they were. */
    float *before = malloc(c.count * 3 * sizeof *before);
    memcpy(before, c.normals, c.count * 3 * sizeof *before);
    progress_log stop = {0, 5, 0.0, 1};
    tessel_callbacks cb2 = {on_progress, NULL, &stop};
    CHECK(tessel_normals_estimate(&c, NULL, &cb2) == TESSEL_ERR_CANCELLED);
    CHECK(memcmp(before, c.normals, c.count * 3 * sizeof *before) == 0);
    free(before);
    tessel_cloud_free(&c);

    /* Torus, area-uniform samples. */
    CHECK(tessel_cloud_alloc(&c, 30000, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < c.count;) {
        double u = 2 * PI * unif(), v = 2 * PI * unif();
        if (unif() * (TR + Tr) > TR + Tr * cos(v))
            continue;
        c.xyz[3 * i] = (float)((TR + Tr * cos(v)) * cos(u));
        c.xyz[3 * i + 1] = (float)((TR + Tr * cos(v)) * sin(u));
        c.xyz[3 * i + 2] = (float)(Tr * sin(v));
        i++;
    }
    tessel_normals_params p = tessel_normals_params_default();
    p.threads = 1;
    CHECK(tessel_normals_estimate(&c, &p, NULL) == TESSEL_OK);
    /* Random samples make lopsided neighbourhoods; on the inner equator
     * (curvatures 2.5 and -1.7) that tilts the plane fit by up to ~5
     * degrees. */
    w = worst_angle(&c, torus_ref, 1);
    CHECK_MSG(w < 7.0, "torus: worst oriented angle %.2f degrees", w);
    /* Same bits with two threads. */
    float *one = malloc(c.count * 3 * sizeof *one);
    memcpy(one, c.normals, c.count * 3 * sizeof *one);
    p.threads = 2;
    CHECK(tessel_normals_estimate(&c, &p, NULL) == TESSEL_OK);
    CHECK(memcmp(one, c.normals, c.count * 3 * sizeof *one) == 0);
    free(one);
    tessel_cloud_free(&c);
}

static void test_two_spheres(void)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 8000, 0, 0) == TESSEL_OK);
    /* Interleaved, so neither sphere is all first in the array. */
    for (size_t i = 0; i < c.count; i++)
        sphere_point(c.xyz + 3 * i, two_c[i % 2], 1.0);
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_OK);
    double w = worst_angle(&c, two_ref, 1);
    CHECK_MSG(w < 5.0, "two spheres: worst oriented angle %.2f degrees", w);
    tessel_cloud_free(&c);
}

/* With a viewpoint every normal faces it: a sphere seen from its centre
 * (a room scanned from inside) gets inward normals, a plane seen from
 * below gets -z. */
static void inward_ref(const float *p, double n[3])
{
    sphere_ref(p, n);
    for (int a = 0; a < 3; a++)
        n[a] = -n[a];
}

static void test_viewpoint(void)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 6000, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < c.count; i++)
        sphere_point(c.xyz + 3 * i, sphere_c, 1.0);
    /* World viewpoint at the centre, with a local frame offset. */
    for (int a = 0; a < 3; a++) {
        c.offset[a] = 100.0 * (a + 1);
        c.viewpoint[a] = c.offset[a] + sphere_c[a];
    }
    c.has_viewpoint = 1;
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_OK);
    double w = worst_angle(&c, inward_ref, 1);
    CHECK_MSG(w < 5.0, "inside view: worst angle %.2f degrees", w);
    tessel_cloud_free(&c);

    CHECK(tessel_cloud_alloc(&c, 2000, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < c.count; i++) {
        c.xyz[3 * i] = (float)unif();
        c.xyz[3 * i + 1] = (float)unif();
    }
    c.viewpoint[0] = c.viewpoint[1] = 0.5;
    c.viewpoint[2] = -3.0;
    c.has_viewpoint = 1;
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_OK);
    int down = 1;
    for (size_t i = 0; i < c.count; i++)
        down &= c.normals[3 * i + 2] < -0.999f;
    CHECK(down);
    tessel_cloud_free(&c);
}

static void test_edges(void)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 5, 0, 0) == TESSEL_OK);
    float pts[5][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0.5f, 0.5f, 0}};
    memcpy(c.xyz, pts, sizeof pts);
    /* k above the count: all points used. */
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_OK);
    CHECK(worst_angle(&c, up_ref, 1) < 1e-3);
    tessel_normals_params p = tessel_normals_params_default();
    p.k = 2;
    CHECK(tessel_normals_estimate(&c, &p, NULL) == TESSEL_ERR_INVALID_ARG);
    p.k = 257;
    CHECK(tessel_normals_estimate(&c, &p, NULL) == TESSEL_ERR_INVALID_ARG);
    /* All points equal: finite unit normals all the same. */
    memset(c.xyz, 0, 15 * sizeof(float));
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_OK);
    int finite = 1;
    for (size_t i = 0; i < 15; i++)
        finite &= isfinite(c.normals[i]);
    CHECK(finite);
    c.count = 2;
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_ERR_TOO_FEW_POINTS);
    c.count = 5;
    c.xyz[0] = NAN;
    CHECK(tessel_normals_estimate(&c, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_cloud_free(&c);
    CHECK(tessel_normals_estimate(NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
}

int main(void)
{
    test_plane();
    test_sphere_torus();
    test_two_spheres();
    test_viewpoint();
    test_edges();
    return TEST_SUMMARY();
}
