/* Robust smoothing (src/smooth/): noisy plane and sphere with known
 * surfaces, robustness to outliers, sharp edges of a cube, the projector,
 * independence from thread count and input order, argument checks. */
#include "pipeline/pipeline.h"
#include "smooth/smooth.h"
#include "tessel.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- deterministic random numbers and generators ---- */

static uint64_t rng_state;
static double urand(void) /* [0, 1) */
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}
static double gauss(void)
{
    double u = urand(), v = urand();
    return sqrt(-2.0 * log(u + 1e-300)) * cos(6.283185307179586 * v);
}

/* n points on the unit square of z = 0 (jittered grid, spacing ~ 1/side),
 * with Gaussian noise of sigma in z. */
static void make_plane(tessel_cloud *c, size_t side, double sigma)
{
    CHECK(tessel_cloud_alloc(c, side * side, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < side; i++)
        for (size_t j = 0; j < side; j++) {
            float *p = c->xyz + 3 * (i * side + j);
            p[0] = (float)((i + 0.25 + 0.5 * urand()) / side);
            p[1] = (float)((j + 0.25 + 0.5 * urand()) / side);
            p[2] = (float)(sigma * gauss());
        }
}

/* n points on the unit sphere (Fibonacci spiral: even spacing), moved
 * radially by Gaussian noise of sigma. */
static void make_sphere(tessel_cloud *c, size_t n, double sigma)
{
    CHECK(tessel_cloud_alloc(c, n, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < n; i++) {
        double z = 1.0 - (2.0 * i + 1.0) / n;
        double r = sqrt(1.0 - z * z), a = 2.399963229728653 * i;
        double s = 1.0 + sigma * gauss();
        c->xyz[3 * i] = (float)(s * r * cos(a));
        c->xyz[3 * i + 1] = (float)(s * r * sin(a));
        c->xyz[3 * i + 2] = (float)(s * z);
    }
}

/* The surface of the cube [-1,1]^3: per face a jittered side x side grid,
 * plus Gaussian noise of sigma in all three directions. */
static void make_cube(tessel_cloud *c, size_t side, double sigma)
{
    CHECK(tessel_cloud_alloc(c, 6 * side * side, 0, 0) == TESSEL_OK);
    size_t k = 0;
    for (int f = 0; f < 6; f++)
        for (size_t i = 0; i < side; i++)
            for (size_t j = 0; j < side; j++) {
                double u = -1.0 + 2.0 * (i + 0.25 + 0.5 * urand()) / side;
                double v = -1.0 + 2.0 * (j + 0.25 + 0.5 * urand()) / side;
                double w = (f & 1) ? 1.0 : -1.0;
                double p[3];
                int ax = f / 2;
                p[ax] = w;
                p[(ax + 1) % 3] = u;
                p[(ax + 2) % 3] = v;
                for (int d = 0; d < 3; d++)
                    c->xyz[3 * k + d] = (float)(p[d] + sigma * gauss());
                k++;
            }
}

/* Distance from p to the surface of the cube [-1,1]^3. */
static double cube_distance(const float *p)
{
    double q[3], out2 = 0.0, inmax = -1e300;
    for (int d = 0; d < 3; d++) {
        q[d] = fabs(p[d]) - 1.0;
        if (q[d] > 0)
            out2 += q[d] * q[d];
        if (q[d] > inmax)
            inmax = q[d];
    }
    return out2 > 0 ? sqrt(out2) : -inmax;
}
/* Distance from p to the nearest cube edge line segment region: how close
 * to a sharp feature it is. */
static double cube_edge_distance(const float *p)
{
    double a[3];
    for (int d = 0; d < 3; d++)
        a[d] = 1.0 - fabs(p[d]);
    /* An edge is where two coordinates are at +-1. */
    double best = 1e300;
    for (int d = 0; d < 3; d++) {
        double x = a[(d + 1) % 3], y = a[(d + 2) % 3];
        double e = sqrt(x * x + y * y);
        if (e < best)
            best = e;
    }
    return best;
}

static double rms_z(const tessel_cloud *c)
{
    double s = 0;
    for (size_t i = 0; i < c->count; i++)
        s += (double)c->xyz[3 * i + 2] * c->xyz[3 * i + 2];
    return sqrt(s / c->count);
}
static double rms_sphere(const tessel_cloud *c)
{
    double s = 0;
    for (size_t i = 0; i < c->count; i++) {
        const float *p = c->xyz + 3 * i;
        double r = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
        s += (r - 1.0) * (r - 1.0);
    }
    return sqrt(s / c->count);
}

/* ---- tests ---- */

static void test_plane(void)
{
    rng_state = 1;
    tessel_cloud in, out;
    const size_t side = 120;
    const double h = 1.0 / side;
    make_plane(&in, side, 0.5 * h);
    tessel_smooth_params p = tessel_smooth_params_default();
    p.passes = 1;
    tessel_smooth_stats st;
    CHECK(tessel_smooth(&in, &out, &p, NULL, &st) == TESSEL_OK);
    CHECK(out.count == in.count && out.normals != NULL);
    double before = rms_z(&in), after = rms_z(&out);
    CHECK_MSG(after * 3.0 < before, "plane rms %g -> %g", before, after);
    CHECK_MSG(st.spacing > 0.3 * h && st.spacing < 1.5 * h, "spacing %g, grid %g", st.spacing,
              h);
    CHECK(st.unfit == 0);
    CHECK(st.mean_iterations >= 1.0 && st.mean_iterations < p.max_iterations);
    CHECK(st.rms_displacement > 0.0 && st.max_displacement >= st.rms_displacement);
    /* Normals are unit and, away from the border (where the neighbourhood
     * is one-sided and the noise tilts the fit), near vertical; points move
     * along them. */
    size_t bad = 0, inner = 0;
    double tang = 0, mean_nz = 0;
    for (size_t i = 0; i < out.count; i++) {
        const float *n = out.normals + 3 * i, *q = in.xyz + 3 * i;
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        bad += fabs(len - 1.0) > 1e-5;
        if (q[0] < 4 * h || q[0] > 1 - 4 * h || q[1] < 4 * h || q[1] > 1 - 4 * h)
            continue;
        inner++;
        bad += fabs(n[2]) < 0.9;
        mean_nz += fabs(n[2]);
        double dx = out.xyz[3 * i] - q[0], dy = out.xyz[3 * i + 1] - q[1];
        tang = fmax(tang, sqrt(dx * dx + dy * dy));
    }
    CHECK_MSG(bad == 0, "%zu bad normals", bad);
    CHECK_MSG(mean_nz / inner > 0.99, "mean |n_z| %g", mean_nz / inner);
    CHECK_MSG(tang < 0.5 * h, "tangential move %g h", tang / h);
    tessel_cloud_free(&out);

    /* Two passes smooth further than one. */
    p.passes = 2;
    CHECK(tessel_smooth(&in, &out, &p, NULL, NULL) == TESSEL_OK);
    double after2 = rms_z(&out);
    CHECK_MSG(after2 < after, "two passes %g, one pass %g", after2, after);
    tessel_cloud_free(&out);
    tessel_cloud_free(&in);
}

static void test_sphere(void)
{
    rng_state = 2;
    tessel_cloud in, out;
    const size_t n = 20000;
    /* spacing ~ sqrt(4 pi / n) = 0.025; noise half of it. */
    make_sphere(&in, n, 0.0125);
    tessel_smooth_stats st;
    CHECK(tessel_smooth(&in, &out, NULL, NULL, &st) == TESSEL_OK);
    double before = rms_sphere(&in), after = rms_sphere(&out);
    CHECK_MSG(after * 3.0 < before, "sphere rms %g -> %g", before, after);
    /* Normals are radial, to within what noise of half the spacing allows
     * on 24 neighbours. */
    size_t bad = 0;
    double mean_c = 0;
    for (size_t i = 0; i < out.count; i++) {
        const float *q = out.xyz + 3 * i, *nn = out.normals + 3 * i;
        double r = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        double c = fabs(q[0] * nn[0] + q[1] * nn[1] + q[2] * nn[2]) / r;
        bad += c < 0.9;
        mean_c += c;
    }
    CHECK_MSG(bad == 0, "%zu normals not radial", bad);
    CHECK_MSG(mean_c / n > 0.99, "mean |cos| %g", mean_c / n);
    tessel_cloud_free(&out);

    /* With input normals (outward), output normals agree with them. */
    CHECK(tessel_cloud_copy(&out, &in) == TESSEL_OK);
    tessel_cloud with_n = out;
    with_n.normals = malloc(3 * n * sizeof(float));
    for (size_t i = 0; i < n; i++) {
        const float *q = in.xyz + 3 * i;
        double r = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        for (int d = 0; d < 3; d++)
            with_n.normals[3 * i + d] = (float)(q[d] / r);
    }
    tessel_cloud sm;
    CHECK(tessel_smooth(&with_n, &sm, NULL, NULL, NULL) == TESSEL_OK);
    size_t inward = 0;
    for (size_t i = 0; i < n; i++) {
        const float *q = sm.xyz + 3 * i, *nn = sm.normals + 3 * i;
        inward += q[0] * nn[0] + q[1] * nn[1] + q[2] * nn[2] < 0;
    }
    CHECK_MSG(inward == 0, "%zu normals flipped against the input's", inward);
    tessel_cloud_free(&sm);
    tessel_cloud_free(&with_n);

    /* A viewpoint at the centre: normals face inward. */
    in.has_viewpoint = 1;
    CHECK(tessel_smooth(&in, &sm, NULL, NULL, NULL) == TESSEL_OK);
    size_t outward = 0;
    for (size_t i = 0; i < n; i++) {
        const float *q = sm.xyz + 3 * i, *nn = sm.normals + 3 * i;
        outward += q[0] * nn[0] + q[1] * nn[1] + q[2] * nn[2] > 0;
    }
    CHECK_MSG(outward == 0, "%zu normals not facing the viewpoint", outward);
    CHECK(sm.has_viewpoint == 1);
    tessel_cloud_free(&sm);
    tessel_cloud_free(&in);
}

/* Outliers near the surface (a layer 3 h above it, one for every four
 * points, inside the neighbourhoods of k = 48) must not pull the smoothed
 * plane, where plain weighted least squares is pulled by a third of h. Far
 * outliers have no fit and stay where they are. */
static void test_outliers(void)
{
    rng_state = 3;
    const size_t side = 100, n_near = side * side / 4, n_far = 20;
    const double h = 1.0 / side;
    tessel_cloud plane, in;
    make_plane(&plane, side, 0.0);
    size_t n = plane.count + n_near + n_far;
    CHECK(tessel_cloud_alloc(&in, n, 0, 0) == TESSEL_OK);
    memcpy(in.xyz, plane.xyz, plane.count * 3 * sizeof(float));
    for (size_t i = 0; i < n_near; i++) {
        float *q = in.xyz + 3 * (plane.count + i);
        q[0] = (float)urand();
        q[1] = (float)urand();
        q[2] = (float)(3.0 * h);
    }
    for (size_t i = 0; i < n_far; i++) {
        float *q = in.xyz + 3 * (plane.count + n_near + i);
        q[0] = (float)urand();
        q[1] = (float)urand();
        q[2] = (float)(50.0 * h * (1 + i));
    }
    tessel_smooth_params p = tessel_smooth_params_default();
    p.spacing = h; /* the outliers would shrink the estimate */
    p.k = 48;
    p.sigma_rho = 1.0;
    p.sigma_w = 2.0;
    p.passes = 1;
    tessel_smooth_stats st;
    tessel_cloud robust, plain;
    CHECK(tessel_smooth(&in, &robust, &p, NULL, &st) == TESSEL_OK);
    CHECK_MSG(st.unfit == n_far, "unfit %zu", st.unfit);
    p.sigma_rho = 1e6; /* rho(x) ~ x^2: ordinary weighted least squares */
    CHECK(tessel_smooth(&in, &plain, &p, NULL, NULL) == TESSEL_OK);
    double worst_r = 0, worst_p = 0;
    /* Inliers away from the border (where a plane fit is unbiased). */
    for (size_t i = 0; i < plane.count; i++) {
        const float *q = in.xyz + 3 * i;
        if (q[0] < 0.1 || q[0] > 0.9 || q[1] < 0.1 || q[1] > 0.9)
            continue;
        worst_r = fmax(worst_r, fabs(robust.xyz[3 * i + 2]));
        worst_p = fmax(worst_p, fabs(plain.xyz[3 * i + 2]));
    }
    CHECK_MSG(worst_r < 0.02 * h, "robust fit pulled by %g h", worst_r / h);
    CHECK_MSG(worst_p > 0.2 * h, "plain fit pulled only by %g h", worst_p / h);
    /* Far outliers keep their position. */
    for (size_t i = plane.count + n_near; i < n; i++)
        CHECK(memcmp(robust.xyz + 3 * i, in.xyz + 3 * i, 3 * sizeof(float)) == 0);
    tessel_cloud_free(&robust);
    tessel_cloud_free(&plain);
    tessel_cloud_free(&plane);
    tessel_cloud_free(&in);
}

/* Sharp edges. On a noise-free cube, points within 2 h of an edge move
 * off the surface (the neighbourhood straddles both faces), but with a
 * small sigma_rho the robust norm discounts the other face and they move
 * much less than with plain weighted least squares. With noise and one
 * pass of sigma_w = 2 the error drops 3x on the faces and still drops near
 * the edges (the defaults, two passes of 2.5, remove more noise on the
 * faces and round the edges more: bench/bench_smooth.c measures both). */
static void test_cube_edges(void)
{
    rng_state = 4;
    const size_t side = 60;
    const double h = 2.0 / side;
    tessel_cloud clean, noisy, a, b;
    make_cube(&clean, side, 0.0);
    tessel_smooth_params p = tessel_smooth_params_default();
    p.spacing = h;
    p.sigma_rho = 0.5;
    p.sigma_w = 2.0;
    p.passes = 1;
    CHECK(tessel_smooth(&clean, &a, &p, NULL, NULL) == TESSEL_OK);
    p.sigma_rho = 1e6;
    CHECK(tessel_smooth(&clean, &b, &p, NULL, NULL) == TESSEL_OK);
    double er = 0, ep = 0, far = 0;
    size_t m = 0;
    for (size_t i = 0; i < clean.count; i++) {
        if (cube_edge_distance(clean.xyz + 3 * i) > 2 * h) {
            far = fmax(far, fabs(cube_distance(a.xyz + 3 * i)));
            continue;
        }
        double dr = cube_distance(a.xyz + 3 * i), dp = cube_distance(b.xyz + 3 * i);
        er += dr * dr;
        ep += dp * dp;
        m++;
    }
    er = sqrt(er / m);
    ep = sqrt(ep / m);
    CHECK_MSG(er < 0.7 * ep, "edge rms robust %g h, plain %g h", er / h, ep / h);
    CHECK_MSG(far < 0.05 * h, "flat parts moved by %g h", far / h);
    tessel_cloud_free(&a);
    tessel_cloud_free(&b);

    make_cube(&noisy, side, 0.3 * h);
    p = tessel_smooth_params_default();
    p.sigma_w = 2.0; /* wider neighbourhoods and more passes round edges more */
    p.passes = 1;
    p.spacing = 0.7 * h; /* about what the estimate gives on a jittered grid */
    CHECK(tessel_smooth(&noisy, &a, &p, NULL, NULL) == TESSEL_OK);
    double e0 = 0, e1 = 0, f0 = 0, f1 = 0;
    size_t me = 0, mf = 0;
    for (size_t i = 0; i < noisy.count; i++) {
        double d0 = cube_distance(noisy.xyz + 3 * i), d1 = cube_distance(a.xyz + 3 * i);
        double e = cube_edge_distance(clean.xyz + 3 * i);
        if (e <= 2 * h) {
            e0 += d0 * d0, e1 += d1 * d1, me++;
        } else if (e > 4 * h) {
            f0 += d0 * d0, f1 += d1 * d1, mf++;
        }
    }
    e0 = sqrt(e0 / me), e1 = sqrt(e1 / me), f0 = sqrt(f0 / mf), f1 = sqrt(f1 / mf);
    CHECK_MSG(f1 * 3 < f0, "faces rms %g -> %g", f0, f1);
    CHECK_MSG(e1 < e0, "edges rms %g -> %g", e0, e1);
    tessel_cloud_free(&a);
    tessel_cloud_free(&noisy);
    tessel_cloud_free(&clean);
}

/* Smooths `in` reversed with p and counts the points whose position is
 * not bit for bit that of `out` (the output for `in`), reversed. */
static size_t differ_reversed(const tessel_cloud *in, const tessel_cloud *out,
                              const tessel_smooth_params *p)
{
    tessel_cloud rev, o;
    CHECK(tessel_cloud_alloc(&rev, in->count, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < in->count; i++)
        memcpy(rev.xyz + 3 * i, in->xyz + 3 * (in->count - 1 - i), 3 * sizeof(float));
    CHECK(tessel_smooth(&rev, &o, p, NULL, NULL) == TESSEL_OK);
    size_t diff = 0;
    for (size_t i = 0; i < in->count; i++)
        diff += memcmp(out->xyz + 3 * i, o.xyz + 3 * (in->count - 1 - i), 3 * sizeof(float)) != 0;
    tessel_cloud_free(&o);
    tessel_cloud_free(&rev);
    return diff;
}

static void test_threads_and_order(void)
{
    rng_state = 5;
    tessel_cloud in, o1, o2, o3;
    make_sphere(&in, 8000, 0.02);
    tessel_smooth_params p = tessel_smooth_params_default();
    p.passes = 2;
    p.threads = 1;
    CHECK(tessel_smooth(&in, &o1, &p, NULL, NULL) == TESSEL_OK);
    p.threads = 2;
    CHECK(tessel_smooth(&in, &o2, &p, NULL, NULL) == TESSEL_OK);
    p.threads = 3;
    CHECK(tessel_smooth(&in, &o3, &p, NULL, NULL) == TESSEL_OK);
    size_t bytes = in.count * 3 * sizeof(float);
    CHECK(memcmp(o1.xyz, o2.xyz, bytes) == 0 && memcmp(o1.xyz, o3.xyz, bytes) == 0);
    CHECK(memcmp(o1.normals, o2.normals, bytes) == 0 &&
          memcmp(o1.normals, o3.normals, bytes) == 0);
    tessel_cloud_free(&o2);
    tessel_cloud_free(&o3);

    /* Reversing the input reverses the output, bit for bit (the spacing is
     * given: its estimate samples points by position in the array). */
    p.spacing = 0.03;
    tessel_cloud_free(&o1);
    CHECK(tessel_smooth(&in, &o1, &p, NULL, NULL) == TESSEL_OK);
    size_t diff = differ_reversed(&in, &o1, &p);
    CHECK_MSG(diff == 0, "%zu points differ after reversing the input", diff);
    tessel_cloud_free(&o1);
    tessel_cloud_free(&in);
}

/* Mean |cosine| between the normals and the radial direction. */
static double mean_radial_cos(const tessel_cloud *c)
{
    double sum = 0;
    for (size_t i = 0; i < c->count; i++) {
        const float *q = c->xyz + 3 * i, *nn = c->normals + 3 * i;
        double r = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        sum += fabs(q[0] * nn[0] + q[1] * nn[1] + q[2] * nn[2]) / r;
    }
    return sum / (double)c->count;
}

/* params.aggregate: on a sphere of radius 12.6 h with noise as large as
 * the spacing (as on the noisy scans' thin parts), averaging each point's
 * projections onto its neighbours' fits leaves clearly less error than its
 * own fit alone (measured 0.348 h -> 0.309 h), and the averaged normals stay
 * radial; the result does not depend on the thread count or the input
 * order, and a far point without a fit stays where it is. */
static void test_aggregate(void)
{
    rng_state = 14;
    const size_t n = 2000;
    const double h = sqrt(4.0 * 3.141592653589793 / (double)n);
    tessel_cloud in, plain, agg;
    make_sphere(&in, n + 1, h);
    float far[3] = {5.0f, 5.0f, 5.0f};
    memcpy(in.xyz + 3 * n, far, sizeof far);
    tessel_smooth_params p = tessel_smooth_params_default();
    p.spacing = h;
    CHECK(tessel_smooth(&in, &plain, &p, NULL, NULL) == TESSEL_OK);
    p.aggregate = 1;
    tessel_smooth_stats st;
    CHECK(tessel_smooth(&in, &agg, &p, NULL, &st) == TESSEL_OK);
    CHECK(memcmp(agg.xyz + 3 * n, far, sizeof far) == 0);
    CHECK_MSG(st.unfit == 2, "%zu unfit fits (the far point, twice)", st.unfit);
    agg.count = plain.count = in.count = n; /* the sphere only */
    double before = rms_sphere(&in), one = rms_sphere(&plain), avg = rms_sphere(&agg);
    CHECK_MSG(avg < 0.93 * one, "rms %g -> %g, aggregated %g", before, one, avg);
    double cos_agg = mean_radial_cos(&agg), cos_one = mean_radial_cos(&plain);
    CHECK_MSG(cos_agg > 0.98 && cos_agg >= cos_one, "mean |cos| %g, own fits %g", cos_agg,
              cos_one);
    agg.count = plain.count = in.count = n + 1;

    tessel_cloud o2;
    p.threads = 1;
    CHECK(tessel_smooth(&in, &o2, &p, NULL, NULL) == TESSEL_OK);
    size_t bytes = in.count * 3 * sizeof(float);
    CHECK(memcmp(o2.xyz, agg.xyz, bytes) == 0 && memcmp(o2.normals, agg.normals, bytes) == 0);
    tessel_cloud_free(&o2);
    p.threads = 0;
    size_t diff = differ_reversed(&in, &agg, &p);
    CHECK_MSG(diff == 0, "%zu points differ after reversing the input", diff);
    tessel_cloud_free(&agg);
    tessel_cloud_free(&plain);
    tessel_cloud_free(&in);
}

static void test_projector(void)
{
    rng_state = 6;
    tessel_cloud plane;
    const size_t side = 50;
    make_plane(&plane, side, 0.0);
    tessel_projector *pr = NULL;
    CHECK(tessel_projector_create(&pr, &plane, NULL) == TESSEL_OK);
    double h = tessel_projector_spacing(pr);
    CHECK(h > 0.3 / side && h < 1.5 / side);
    float q[3] = {0.5f, 0.5f, (float)(0.7 * h)}, o[3], nn[3];
    uint32_t its = 0;
    CHECK(tessel_project(pr, q, o, nn, &its) == TESSEL_OK);
    CHECK_MSG(fabs(o[2]) < 1e-6 && fabs(o[0] - 0.5) < 1e-6 && fabs(o[1] - 0.5) < 1e-6,
              "projected to %g %g %g", o[0], o[1], o[2]);
    CHECK(fabs(fabs(nn[2]) - 1.0) < 1e-6);
    CHECK(its >= 1);
    /* Far from the cloud: no fit, the point stays. */
    float far[3] = {0.5f, 0.5f, 10.0f};
    CHECK(tessel_project(pr, far, o, nn, &its) == TESSEL_ERR_TOO_FEW_POINTS);
    CHECK(memcmp(o, far, sizeof o) == 0 && its == 0);
    CHECK(fabs(sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]) - 1.0) < 1e-5);
    tessel_projector_destroy(pr);
    tessel_projector_destroy(NULL);
    tessel_cloud_free(&plane);
}

/* A projector on a borrowed kd-tree (the pipeline shares one over the
 * smoothed cloud) projects to the same bits as one with its own tree, and
 * gives out its tree only for the cloud it was made from. */
static void test_projector_shared_index(void)
{
    rng_state = 7;
    tessel_cloud plane;
    make_plane(&plane, 40, 0.02);
    tessel_smooth_params p = tessel_smooth_params_default();
    tessel_projector *own = NULL, *other = NULL, *borrowed = NULL;
    CHECK(tessel_projector_create(&own, &plane, &p) == TESSEL_OK);
    const tessel_index *ix = tsl_projector_index(own, plane.xyz, plane.count);
    CHECK(ix != NULL);
    CHECK(tsl_projector_index(own, plane.xyz, plane.count - 1) == NULL);
    CHECK(tsl_projector_index(own, plane.xyz + 3, plane.count) == NULL);
    CHECK(tsl_projector_index(NULL, plane.xyz, plane.count) == NULL);
    /* Other fit parameters, same tree. */
    p.k = 16;
    p.sigma_w = 1.5;
    CHECK(tessel_projector_create(&other, &plane, &p) == TESSEL_OK);
    CHECK(tsl_projector_create_on(&borrowed, &plane, &p, ix) == TESSEL_OK);
    CHECK(tsl_projector_index(borrowed, plane.xyz, plane.count) == ix);
    size_t differ = 0;
    for (int i = 0; i < 200; i++) {
        float q[3] = {(float)urand(), (float)urand(), (float)(0.05 * (urand() - 0.5))};
        float a[3], b[3], na[3], nb[3];
        tessel_status sa = tessel_project(other, q, a, na, NULL);
        tessel_status sb = tessel_project(borrowed, q, b, nb, NULL);
        differ += sa != sb || memcmp(a, b, sizeof a) != 0 || memcmp(na, nb, sizeof na) != 0;
    }
    CHECK_MSG(differ == 0, "%zu of 200 projections differ", differ);
    /* The borrowed tree outlives the borrower: destroy the borrower first,
     * then its lender still works. */
    tessel_projector_destroy(borrowed);
    float q[3] = {0.5f, 0.5f, 0.0f}, o[3];
    CHECK(tessel_project(own, q, o, NULL, NULL) == TESSEL_OK);
    tessel_projector_destroy(other);
    tessel_projector_destroy(own);
    tessel_cloud_free(&plane);
}

/* Points whose smoothed position or normal differs from the projector's
 * answer for the same point (unfit: the projector's unfit count). */
static size_t projector_mismatches(const tessel_cloud *c, const tessel_smooth_params *p,
                                   const tessel_cloud *out, size_t *unfit)
{
    tessel_projector *pr = NULL;
    CHECK(tessel_projector_create(&pr, c, p) == TESSEL_OK);
    size_t diff = 0;
    *unfit = 0;
    for (size_t i = 0; i < c->count && pr; i++) {
        float o[3], nn[3];
        tessel_status ps = tessel_project(pr, c->xyz + 3 * i, o, nn, NULL);
        *unfit += ps != TESSEL_OK;
        diff += memcmp(o, out->xyz + 3 * i, sizeof o) != 0 ||
                (ps == TESSEL_OK && memcmp(nn, out->normals + 3 * i, sizeof nn) != 0);
    }
    tessel_projector_destroy(pr);
    return diff;
}

/* A smoothing pass finds neighbours with its own grid; the projector uses
 * the kd-tree. Both must give the same neighbours, hence the same bits, on
 * a cloud with uneven density (sparse parts need the outer ring of cells,
 * a dense clump overflows the block buffer) and exact duplicates (ties). */
static void test_pass_matches_projector(void)
{
    rng_state = 9;
    const size_t n_plane = 6000, n_clump = 3000, n_dup = 400, n_sparse = 300;
    size_t n = n_plane + n_clump + n_dup + n_sparse;
    tessel_cloud c, out;
    CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
    size_t i = 0;
    for (; i < n_plane; i++) { /* wavy sheet */
        double x = urand(), y = urand();
        c.xyz[3 * i] = (float)x, c.xyz[3 * i + 1] = (float)y;
        c.xyz[3 * i + 2] = (float)(0.05 * sin(6 * x) + 0.002 * gauss());
    }
    /* 100x denser patch: its blocks of cells are crowded, so the first
     * pass takes its neighbours from the kd-tree there. */
    for (; i < n_plane + n_clump; i++) {
        c.xyz[3 * i] = (float)(0.5 + 0.05 * urand());
        c.xyz[3 * i + 1] = (float)(0.5 + 0.05 * urand());
        c.xyz[3 * i + 2] = (float)(0.05 * sin(3.0) + 0.001 * gauss());
    }
    for (; i < n_plane + n_clump + n_dup; i++) /* 40 points x 10 copies */
        memcpy(c.xyz + 3 * i, c.xyz + 3 * ((i - n_plane - n_clump) / 10 * 37),
               3 * sizeof(float));
    for (; i < n; i++) { /* sparse sheet beside it */
        c.xyz[3 * i] = (float)(1.2 + 0.6 * urand());
        c.xyz[3 * i + 1] = (float)urand();
        c.xyz[3 * i + 2] = (float)(0.003 * gauss());
    }
    /* Default scales; then a wide Gaussian, where the grid's cells are
     * smaller than half the cut-off and far neighbours come from a tree. */
    for (int wide = 0; wide < 2; wide++) {
        tessel_smooth_params p = tessel_smooth_params_default();
        p.spacing = 0.01;
        p.passes = 1;
        if (wide)
            p.sigma_w = 8;
        tessel_smooth_stats st;
        CHECK(tessel_smooth(&c, &out, &p, NULL, &st) == TESSEL_OK);
        size_t unfit = 0;
        size_t diff = projector_mismatches(&c, &p, &out, &unfit);
        CHECK_MSG(diff == 0, "sigma_w %g: %zu of %zu points differ", p.sigma_w, diff, n);
        CHECK(unfit == st.unfit);
        CHECK(st.unfit < n_sparse); /* the sparse sheet has some fits */
        tessel_cloud_free(&out);
    }
    tessel_cloud_free(&c);
}

/* More copies of a point than k make its k-th neighbour distance 0, which
 * the grid search's threshold once started from (the next query never
 * ended) and halved towards. Two clouds: 40 copies of one point before a
 * wavy sheet, and 300 points with 35 copies each. Smoothing must finish
 * and still agree with the projector bit for bit. */
static void test_copies_beyond_k(void)
{
    rng_state = 15;
    for (int every = 0; every < 2; every++) {
        const size_t distinct = every ? 300 : 3000, copies = every ? 35 : 40;
        size_t n = every ? distinct * copies : copies + distinct;
        tessel_cloud c, out;
        CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
        for (size_t i = 0; i < n; i++) {
            size_t src = every ? i / copies * copies : (i < copies ? 0 : i);
            if (src != i) {
                memcpy(c.xyz + 3 * i, c.xyz + 3 * src, 3 * sizeof(float));
                continue;
            }
            double x = urand(), y = urand();
            c.xyz[3 * i] = (float)x, c.xyz[3 * i + 1] = (float)y;
            c.xyz[3 * i + 2] = (float)(0.05 * sin(6 * x) + 0.002 * gauss());
        }
        tessel_smooth_params p = tessel_smooth_params_default();
        p.passes = 1;
        CHECK(p.k < copies);
        tessel_smooth_stats st;
        CHECK(tessel_smooth(&c, &out, &p, NULL, &st) == TESSEL_OK);
        size_t unfit = 0;
        size_t diff = projector_mismatches(&c, &p, &out, &unfit);
        CHECK_MSG(diff == 0, "%zu copies: %zu of %zu points differ", copies, diff, n);
        CHECK(unfit == st.unfit);
        tessel_cloud_free(&out);
        tessel_cloud_free(&c);
    }
}

/* A point is left out of its own fit (exclude_self; off by default): on a
 * clean plane, one point raised by half a spacing (well within the robust
 * scale, so no outlier) comes back onto the plane, since its neighbours
 * alone define the fit; with the point in its fit it keeps a share of its
 * offset. */
static void test_exclude_self(void)
{
    rng_state = 21;
    const size_t side = 60;
    tessel_cloud c, with, without;
    make_plane(&c, side, 0.0);
    const size_t raised = (side / 2) * side + side / 2;
    const double h = 1.0 / side;
    c.xyz[3 * raised + 2] = (float)(0.5 * h);
    tessel_smooth_params p = tessel_smooth_params_default();
    CHECK(p.exclude_self == 0);
    p.spacing = 0.7 * h;
    p.passes = 1;
    CHECK(tessel_smooth(&c, &with, &p, NULL, NULL) == TESSEL_OK);
    p.exclude_self = 1;
    CHECK(tessel_smooth(&c, &without, &p, NULL, NULL) == TESSEL_OK);
    double z_out = without.xyz[3 * raised + 2] / h, z_in = with.xyz[3 * raised + 2] / h;
    CHECK_MSG(fabs(z_out) < 0.01, "left out of its fit: still %.4f h above the plane", z_out);
    CHECK_MSG(z_in > 0.03, "in its fit: %.4f h above the plane", z_in);
    tessel_cloud_free(&with);
    tessel_cloud_free(&without);
    p.exclude_self = 2;
    CHECK(tessel_smooth(&c, &with, &p, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_cloud_free(&c);
}

/* Beyond the paper: the quadric over the robust plane. On a clean sphere
 * the plane operator pulls every point inward by about r^2 / 2R (r the
 * neighbourhood's radius); the projector's quadric follows the curvature
 * (damped by its ridge penalty, which halves the correction), and a later
 * pass fits it without the penalty. With noise, smoothing with the quadric
 * shrinks the sphere much less than the plane does. */
static void test_quadric(void)
{
    rng_state = 10;
    tessel_cloud clean, noisy, a, b;
    make_sphere(&clean, 12000, 0.0);
    tessel_smooth_params p = tessel_smooth_params_default();
    tessel_projector *pq = NULL, *pp = NULL;
    CHECK(tessel_projector_create(&pq, &clean, &p) == TESSEL_OK);
    p.quadric = 0;
    CHECK(tessel_projector_create(&pp, &clean, &p) == TESSEL_OK);
    double eq = 0, ep = 0;
    size_t tilted = 0;
    for (size_t i = 0; i < clean.count; i += 7) {
        float oq[3], op[3], nq[3];
        CHECK(tessel_project(pq, clean.xyz + 3 * i, oq, nq, NULL) == TESSEL_OK);
        CHECK(tessel_project(pp, clean.xyz + 3 * i, op, NULL, NULL) == TESSEL_OK);
        double rq = sqrt((double)oq[0] * oq[0] + (double)oq[1] * oq[1] + (double)oq[2] * oq[2]);
        double rp = sqrt((double)op[0] * op[0] + (double)op[1] * op[1] + (double)op[2] * op[2]);
        eq = fmax(eq, fabs(rq - 1.0));
        ep = fmax(ep, fabs(rp - 1.0));
        tilted += fabs(oq[0] * nq[0] + oq[1] * nq[1] + oq[2] * nq[2]) / rq < 0.999;
    }
    CHECK_MSG(tilted == 0, "%zu normals not radial", tilted);
    double h = tessel_projector_spacing(pq);
    CHECK_MSG(ep > 0.02 * h, "plane error only %g h", ep / h);
    CHECK_MSG(eq < 0.75 * ep, "quadric error %g h, plane %g h", eq / h, ep / h);
    /* A second pass (no penalty) adds almost nothing to the first one's
     * error, where a second plane pass adds as much again. */
    double e1[2], e2[2];
    for (int q = 0; q < 2; q++) {
        p = tessel_smooth_params_default();
        p.quadric = q;
        p.spacing = h;
        for (uint32_t passes = 1; passes <= 2; passes++) {
            p.passes = passes;
            CHECK(tessel_smooth(&clean, &a, &p, NULL, NULL) == TESSEL_OK);
            (passes == 1 ? e1 : e2)[q] = rms_sphere(&a);
            tessel_cloud_free(&a);
        }
    }
    CHECK_MSG(e2[0] > 1.7 * e1[0], "plane: %g h after one pass, %g h after two", e1[0] / h,
              e2[0] / h);
    CHECK_MSG(e2[1] < e1[1] + 0.1 * (e2[0] - e1[0]),
              "quadric: %g h after one pass, %g h after two", e1[1] / h, e2[1] / h);
    tessel_projector_destroy(pq);
    tessel_projector_destroy(pp);

    make_sphere(&noisy, 12000, 0.016);
    p = tessel_smooth_params_default();
    CHECK(tessel_smooth(&noisy, &a, &p, NULL, NULL) == TESSEL_OK);
    p.quadric = 0;
    CHECK(tessel_smooth(&noisy, &b, &p, NULL, NULL) == TESSEL_OK);
    double ma = 0, mb = 0;
    for (size_t i = 0; i < noisy.count; i++) {
        const float *u = a.xyz + 3 * i, *v = b.xyz + 3 * i;
        ma += sqrt((double)u[0] * u[0] + (double)u[1] * u[1] + (double)u[2] * u[2]) - 1.0;
        mb += sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]) - 1.0;
    }
    ma /= (double)noisy.count, mb /= (double)noisy.count;
    CHECK_MSG(mb < -0.1 * h, "plane shrinks by only %g h", -mb / h);
    CHECK_MSG(fabs(ma) < 0.5 * fabs(mb), "mean radius error %g h (plane %g h)", ma / h,
              mb / h);
    CHECK(rms_sphere(&a) < rms_sphere(&b));
    tessel_cloud_free(&a);
    tessel_cloud_free(&b);
    tessel_cloud_free(&noisy);
    tessel_cloud_free(&clean);
}

/* A regular lattice has many neighbours at exactly equal distances: the
 * pass's sort (by quantised rank, exact order where two share a rank) must
 * still pick and order them as the kd-tree does (ties by point index). */
static void test_lattice_ties(void)
{
    const size_t side = 70;
    tessel_cloud c, out;
    CHECK(tessel_cloud_alloc(&c, side * side, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < side; i++)
        for (size_t j = 0; j < side; j++) {
            float *q = c.xyz + 3 * (i * side + j);
            q[0] = (float)i, q[1] = (float)j;
            q[2] = (float)(0.3 * sin(0.2 * (double)i) * cos(0.15 * (double)j));
        }
    tessel_smooth_params p = tessel_smooth_params_default();
    p.spacing = 1.0;
    p.passes = 1;
    for (int q = 0; q < 2; q++) {
        p.quadric = q;
        CHECK(tessel_smooth(&c, &out, &p, NULL, NULL) == TESSEL_OK);
        tessel_projector *pr = NULL;
        CHECK(tessel_projector_create(&pr, &c, &p) == TESSEL_OK);
        size_t diff = 0;
        for (size_t i = 0; i < c.count; i++) {
            float o[3], nn[3];
            CHECK(tessel_project(pr, c.xyz + 3 * i, o, nn, NULL) == TESSEL_OK);
            diff += memcmp(o, out.xyz + 3 * i, sizeof o) != 0 ||
                    memcmp(nn, out.normals + 3 * i, sizeof nn) != 0;
        }
        CHECK_MSG(diff == 0, "quadric %d: %zu of %zu points differ", q, diff, c.count);
        tessel_projector_destroy(pr);
        tessel_cloud_free(&out);
    }
    tessel_cloud_free(&c);
}

/* Later passes reuse the first pass's neighbours and start from its
 * normals: still the same bits for any thread count, with and without
 * input normals, and the same for the plane operator. */
static void test_later_passes(void)
{
    rng_state = 11;
    tessel_cloud in, o1, o2;
    make_sphere(&in, 4000, 0.025);
    for (int variant = 0; variant < 3; variant++) {
        tessel_smooth_params p = tessel_smooth_params_default();
        p.passes = 3;
        p.quadric = variant != 2;
        if (variant == 1) {
            in.normals = malloc(3 * in.count * sizeof(float));
            for (size_t i = 0; i < in.count; i++)
                for (int d = 0; d < 3; d++)
                    in.normals[3 * i + d] = in.xyz[3 * i + d];
        }
        p.threads = 1;
        CHECK(tessel_smooth(&in, &o1, &p, NULL, NULL) == TESSEL_OK);
        p.threads = 2;
        CHECK(tessel_smooth(&in, &o2, &p, NULL, NULL) == TESSEL_OK);
        size_t bytes = in.count * 3 * sizeof(float);
        CHECK_MSG(memcmp(o1.xyz, o2.xyz, bytes) == 0 && memcmp(o1.normals, o2.normals, bytes) == 0,
                  "variant %d differs between 1 and 2 threads", variant);
        /* More passes keep smoothing; the quadric does not shrink the
         * sphere away. */
        double r = rms_sphere(&o1), r0 = rms_sphere(&in);
        CHECK_MSG(r < (variant == 2 ? 1.0 : 0.5) * r0, "variant %d: rms %g after 3 passes, %g before",
                  variant, r, r0);
        if (variant == 1) {
            size_t inward = 0;
            for (size_t i = 0; i < in.count; i++) {
                const float *q = o1.xyz + 3 * i, *nn = o1.normals + 3 * i;
                inward += q[0] * nn[0] + q[1] * nn[1] + q[2] * nn[2] < 0;
            }
            CHECK_MSG(inward == 0, "%zu normals flipped after 3 passes", inward);
        }
        tessel_cloud_free(&o1);
        tessel_cloud_free(&o2);
    }
    tessel_cloud_free(&in);
}

/* Collinear points have no plane: every point is unfit and stays. */
static void test_degenerate(void)
{
    tessel_cloud line, out;
    CHECK(tessel_cloud_alloc(&line, 100, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < 100; i++)
        line.xyz[3 * i] = (float)i;
    tessel_smooth_stats st;
    CHECK(tessel_smooth(&line, &out, NULL, NULL, &st) == TESSEL_OK);
    CHECK(st.unfit == 100 * tessel_smooth_params_default().passes);
    CHECK(memcmp(out.xyz, line.xyz, 300 * sizeof(float)) == 0);
    tessel_cloud_free(&out);

    /* All points equal: no spacing, no smoothing. */
    memset(line.xyz, 0, 300 * sizeof(float));
    CHECK(tessel_smooth(&line, &out, NULL, NULL, NULL) == TESSEL_ERR_TOO_FEW_POINTS);
    CHECK(out.xyz == NULL && out.count == 0);
    line.count = 2;
    CHECK(tessel_smooth(&line, &out, NULL, NULL, NULL) == TESSEL_ERR_TOO_FEW_POINTS);
    line.count = 100;
    tessel_cloud_free(&line);
}

static void test_args(void)
{
    tessel_cloud c, out;
    rng_state = 7;
    make_plane(&c, 10, 0.0);
    tessel_smooth_params bad[11];
    for (int i = 0; i < 11; i++)
        bad[i] = tessel_smooth_params_default();
    bad[0].k = 2;
    bad[1].k = 1000;
    bad[2].sigma_rho = 0;
    bad[3].sigma_w = NAN;
    bad[4].passes = 0;
    bad[5].tolerance = -1;
    bad[6].min_neighbors = bad[6].k + 1; /* > k */
    bad[7].spacing = -1;
    bad[8].quadric = 2;
    bad[9].sigma_rho_later = 0;
    bad[10].sigma_rho_later = INFINITY;
    for (int i = 0; i < 11; i++)
        CHECK_MSG(tessel_smooth(&c, &out, &bad[i], NULL, NULL) == TESSEL_ERR_INVALID_ARG,
                  "bad params %d accepted", i);
    CHECK(tessel_smooth(NULL, &out, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_smooth(&c, NULL, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    tessel_projector *pr = (tessel_projector *)&c;
    CHECK(tessel_projector_create(&pr, &c, &bad[0]) == TESSEL_ERR_INVALID_ARG && pr == NULL);
    /* Non-finite coordinates are refused, not smoothed into garbage. */
    c.xyz[7] = NAN;
    CHECK(tessel_smooth(&c, &out, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_projector_create(&pr, &c, NULL) == TESSEL_ERR_INVALID_ARG && pr == NULL);
    c.xyz[7] = INFINITY;
    tessel_clusters cl;
    CHECK(tessel_cluster(&c, NULL, NULL, &cl) == TESSEL_ERR_INVALID_ARG && cl.labels == NULL);
    tessel_cloud_free(&c);
}

static int cancel_at_half(void *user, const char *stage, double f)
{
    (void)stage;
    *(int *)user += 1;
    return f >= 0.5;
}

static void test_cancel(void)
{
    rng_state = 8;
    tessel_cloud c, out;
    make_plane(&c, 200, 0.001);
    tessel_smooth_params p = tessel_smooth_params_default();
    p.passes = 2;
    int calls = 0;
    tessel_callbacks cb = {cancel_at_half, NULL, &calls};
    CHECK(tessel_smooth(&c, &out, &p, &cb, NULL) == TESSEL_ERR_CANCELLED);
    CHECK(out.xyz == NULL && calls >= 2);
    tessel_cloud_free(&c);
}

/* The noisy pipeline's smoothing in the grid's order: the same points,
 * normals and statistics as in the input's order, each point's colour
 * and organized-grid cell going with it. */
static void test_grid_order(void)
{
    tessel_cloud c, a, b;
    rng_state = 99;
    make_plane(&c, 60, 0.005);
    size_t n = c.count;
    c.rgb = malloc(3 * n);
    c.grid = malloc(n * sizeof *c.grid);
    CHECK(c.rgb && c.grid);
    c.width = 60, c.height = 60;
    for (size_t i = 0; i < n; i++) {
        c.rgb[3 * i] = (uint8_t)i, c.rgb[3 * i + 1] = (uint8_t)(i >> 8), c.rgb[3 * i + 2] = 7;
        c.grid[n - 1 - i] = (uint32_t)i; /* cells in reverse point order */
    }
    tessel_smooth_params p = tessel_smooth_params_default();
    p.passes = 1;
    tessel_smooth_stats sa, sb;
    double t;
    CHECK(tsl_smooth_timed(&c, &a, &p, NULL, &sa, false, &t) == TESSEL_OK);
    CHECK(tsl_smooth_timed(&c, &b, &p, NULL, &sb, true, &t) == TESSEL_OK);
    CHECK(sa.spacing == sb.spacing && sa.rms_displacement == sb.rms_displacement &&
          sa.max_displacement == sb.max_displacement);
    size_t moved = 0, same = 0;
    for (size_t cell = 0; cell < n; cell++) {
        uint32_t i = a.grid[cell], j = b.grid[cell];
        CHECK(i < n && j < n);
        if (i >= n || j >= n)
            continue;
        moved += i != j;
        same += memcmp(a.xyz + 3 * i, b.xyz + 3 * j, 3 * sizeof(float)) == 0 &&
                memcmp(a.normals + 3 * i, b.normals + 3 * j, 3 * sizeof(float)) == 0 &&
                memcmp(a.rgb + 3 * i, b.rgb + 3 * j, 3) == 0;
    }
    CHECK_MSG(same == n, "%zu of %zu cells hold the same point", same, n);
    CHECK(moved > n / 2); /* the orders do differ */
    tessel_cloud_free(&a);
    tessel_cloud_free(&b);
    tessel_cloud_free(&c);
}

int main(void)
{
    test_grid_order();
    test_plane();
    test_sphere();
    test_outliers();
    test_cube_edges();
    test_threads_and_order();
    test_aggregate();
    test_projector();
    test_projector_shared_index();
    test_pass_matches_projector();
    test_copies_beyond_k();
    test_quadric();
    test_exclude_self();
    test_lattice_ties();
    test_later_passes();
    test_degenerate();
    test_args();
    test_cancel();
    return TEST_SUMMARY();
}
