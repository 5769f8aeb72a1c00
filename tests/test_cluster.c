/* BSP clustering (src/smooth/cluster.c) and representatives (src/smooth/simplify.c):
 * clusters partition the cloud, obey the flatness and diameter rules, nest
 * when the rules get stricter, do not depend on the thread count;
 * representatives lie on the surface; isolated outliers get none. */
#include "smooth/smooth.h"
#include "tessel.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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

/* Unit sphere, Fibonacci spiral, radial Gaussian noise of sigma. */
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

/* Jittered side x side grid on the unit square of z = 0. */
static void make_plane(tessel_cloud *c, size_t side)
{
    CHECK(tessel_cloud_alloc(c, side * side, 0, 0) == TESSEL_OK);
    for (size_t i = 0; i < side; i++)
        for (size_t j = 0; j < side; j++) {
            float *p = c->xyz + 3 * (i * side + j);
            p[0] = (float)((i + 0.25 + 0.5 * urand()) / side);
            p[1] = (float)((j + 0.25 + 0.5 * urand()) / side);
            p[2] = 0.0f;
        }
}

/* Checks that the clusters partition the cloud and obey the flatness and
 * diameter rules. */
static void check_clusters(const tessel_cloud *c, const tessel_clusters *cl,
                           const tessel_cluster_params *p)
{
    size_t n = c->count;
    CHECK(cl->point_count == n && cl->count >= 1 && cl->count <= n);
    CHECK(cl->offsets[0] == 0 && cl->offsets[cl->count] == n);
    uint8_t *seen = calloc(n, 1);
    size_t out_of_range = 0, dup = 0, bad_label = 0, unsorted = 0, empty = 0, too_wide = 0,
           too_curved = 0;
    double rmax = 0.5 * p->max_diameter * cl->spacing;
    for (size_t k = 0; k < cl->count; k++) {
        size_t a = cl->offsets[k], b = cl->offsets[k + 1];
        empty += b <= a;
        double s[3] = {0, 0, 0};
        for (size_t i = a; i < b; i++) {
            uint32_t id = cl->order[i];
            if (id >= n) {
                out_of_range++;
                continue;
            }
            dup += seen[id]++ != 0;
            bad_label += cl->labels[id] != k;
            unsorted += i > a && cl->order[i - 1] >= id;
            for (int d = 0; d < 3; d++)
                s[d] += c->xyz[3 * (size_t)id + d];
        }
        if (out_of_range || b <= a)
            continue;
        double m = (double)(b - a), cen[3] = {s[0] / m, s[1] / m, s[2] / m};
        double cov[9] = {0}, far = 0;
        for (size_t i = a; i < b; i++) {
            const float *q = c->xyz + 3 * (size_t)cl->order[i];
            double e[3] = {q[0] - cen[0], q[1] - cen[1], q[2] - cen[2]};
            far = fmax(far, tsl_norm(e));
            for (int r = 0; r < 3; r++)
                for (int t = 0; t < 3; t++)
                    cov[3 * r + t] += e[r] * e[t];
        }
        too_wide += far > rmax * (1 + 1e-9);
        double w[3], v[9];
        tsl_eigen_sym3(cov, w, v);
        double sum = w[0] + w[1] + w[2];
        if (b - a > p->n_min && sum > 0)
            too_curved += w[0] / sum > p->sigma_max * (1 + 1e-6);
    }
    size_t missing = 0;
    for (size_t i = 0; i < n; i++)
        missing += seen[i] == 0;
    free(seen);
    CHECK_MSG(dup == 0 && missing == 0, "%zu duplicated, %zu missing", dup, missing);
    CHECK(out_of_range == 0 && bad_label == 0 && unsorted == 0 && empty == 0);
    CHECK_MSG(too_wide == 0, "%zu clusters wider than the limit", too_wide);
    CHECK_MSG(too_curved == 0, "%zu clusters with more than n_min points too curved",
              too_curved);
}

/* Every cluster of `fine` lies inside one cluster of `coarse`. */
static bool nested(const tessel_clusters *fine, const tessel_clusters *coarse)
{
    for (size_t k = 0; k < fine->count; k++) {
        uint32_t want = coarse->labels[fine->order[fine->offsets[k]]];
        for (size_t i = fine->offsets[k]; i < fine->offsets[k + 1]; i++)
            if (coarse->labels[fine->order[i]] != want)
                return false;
    }
    return true;
}

static void test_sphere_rules(void)
{
    rng_state = 1;
    tessel_cloud noisy, c;
    make_sphere(&noisy, 20000, 0.01);
    CHECK(tessel_smooth(&noisy, &c, NULL, NULL, NULL) == TESSEL_OK);
    tessel_cluster_params p = tessel_cluster_params_default();
    tessel_clusters cl, cl2;
    CHECK(tessel_cluster(&c, &p, NULL, &cl) == TESSEL_OK);
    CHECK(cl.spacing > 0);
    check_clusters(&c, &cl, &p);
    CHECK_MSG(cl.count > 200 && cl.count < 5000, "%zu clusters", cl.count);
    tessel_clusters_free(&cl);

    /* Rules chosen so that each of them decides some splits here. */
    p.sigma_max = 0.001;
    p.n_min = 10;
    p.max_diameter = 12;
    CHECK(tessel_cluster(&c, &p, NULL, &cl) == TESSEL_OK);
    check_clusters(&c, &cl, &p);

    /* A stricter flatness rule refines the tree: more clusters, nested in
     * the old ones (a diameter change moves cuts, so it only changes the
     * count). */
    tessel_cluster_params q = p;
    q.n_min = 5;
    q.sigma_max = 0.0005;
    q.spacing = cl.spacing;
    CHECK(tessel_cluster(&c, &q, NULL, &cl2) == TESSEL_OK);
    check_clusters(&c, &cl2, &q);
    CHECK(cl2.count > cl.count);
    CHECK(nested(&cl2, &cl));
    tessel_clusters_free(&cl2);

    /* Each rule alone: looser gives fewer clusters, nested. */
    for (int rule = 0; rule < 3; rule++) {
        q = p;
        q.spacing = cl.spacing;
        if (rule == 0)
            q.n_min = 40;
        else if (rule == 1)
            q.sigma_max = 0.002;
        else
            q.max_diameter = 20;
        CHECK(tessel_cluster(&c, &q, NULL, &cl2) == TESSEL_OK);
        check_clusters(&c, &cl2, &q);
        CHECK_MSG(cl2.count < cl.count, "rule %d: %zu vs %zu", rule, cl2.count, cl.count);
        CHECK_MSG(rule == 2 || nested(&cl, &cl2), "rule %d not nested", rule);
        tessel_clusters_free(&cl2);
    }

    /* Thread count does not matter. */
    for (int t = 1; t <= 3; t++) {
        q = p;
        q.threads = t;
        CHECK(tessel_cluster(&c, &q, NULL, &cl2) == TESSEL_OK);
        CHECK(cl2.count == cl.count &&
              memcmp(cl2.labels, cl.labels, c.count * sizeof *cl.labels) == 0 &&
              memcmp(cl2.order, cl.order, c.count * sizeof *cl.order) == 0);
        tessel_clusters_free(&cl2);
    }
    tessel_clusters_free(&cl);
    tessel_clusters_free(&cl);
    tessel_clusters_free(NULL);
    tessel_cloud_free(&c);
    tessel_cloud_free(&noisy);
}

/* A flat square never splits for flatness: without a diameter bound it is
 * one cluster; with one, clusters stay within it. */
static void test_plane(void)
{
    rng_state = 2;
    tessel_cloud c;
    make_plane(&c, 100);
    tessel_cluster_params p = tessel_cluster_params_default();
    p.max_diameter = INFINITY;
    tessel_clusters cl;
    CHECK(tessel_cluster(&c, &p, NULL, &cl) == TESSEL_OK);
    CHECK(cl.count == 1);
    tessel_clusters_free(&cl);
    p.max_diameter = 8;
    p.spacing = 0.01;
    CHECK(tessel_cluster(&c, &p, NULL, &cl) == TESSEL_OK);
    check_clusters(&c, &cl, &p);
    /* A disc of diameter 8 h holds ~50 points; cuts make clusters
     * smaller, but not tiny. */
    double mean = (double)c.count / cl.count;
    CHECK_MSG(mean > 10 && mean < 60, "%g points per cluster", mean);
    tessel_clusters_free(&cl);

    /* All points equal: one cluster, whatever the rules. */
    memset(c.xyz, 0, c.count * 3 * sizeof(float));
    p.sigma_max = 0;
    CHECK(tessel_cluster(&c, &p, NULL, &cl) == TESSEL_OK);
    CHECK(cl.count == 1 && cl.offsets[1] == c.count);
    tessel_clusters_free(&cl);
    tessel_cloud_free(&c);
}

/* Representatives of a smoothed noisy sphere lie on the sphere (within the
 * inward bias of a plane fit on a curved surface), one per cluster, with
 * radial normals. */
static void test_representatives(void)
{
    rng_state = 3;
    tessel_cloud noisy, c, r;
    make_sphere(&noisy, 20000, 0.01);
    CHECK(tessel_smooth(&noisy, &c, NULL, NULL, NULL) == TESSEL_OK);
    tessel_simplify_params p = tessel_simplify_params_default();
    tessel_simplify_stats st;
    CHECK(tessel_simplify(&c, &r, &p, NULL, &st) == TESSEL_OK);
    CHECK(st.clusters == st.representatives && st.unfit == 0 && r.count == st.clusters);
    CHECK(r.normals != NULL && r.rgb == NULL);
    double h = st.spacing, rms_r = 0, rms_c = 0, worst = 0, mean_cos = 0;
    for (size_t i = 0; i < r.count; i++) {
        const float *q = r.xyz + 3 * i, *nn = r.normals + 3 * i;
        double rad = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        rms_r += (rad - 1) * (rad - 1);
        worst = fmax(worst, fabs(rad - 1));
        mean_cos += fabs(q[0] * nn[0] + q[1] * nn[1] + q[2] * nn[2]) / rad;
    }
    for (size_t i = 0; i < c.count; i++) {
        const float *q = c.xyz + 3 * i;
        double rad = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        rms_c += (rad - 1) * (rad - 1);
    }
    rms_r = sqrt(rms_r / r.count);
    rms_c = sqrt(rms_c / c.count);
    CHECK_MSG(rms_r < 0.2 * h, "representatives rms %g h (smoothed points %g h)", rms_r / h,
              rms_c / h);
    CHECK_MSG(worst < 0.5 * h, "a representative %g h off the sphere", worst / h);
    CHECK_MSG(mean_cos / r.count > 0.99, "mean |cos| %g", mean_cos / r.count);

    /* Same as clustering, then representatives. */
    tessel_clusters cl;
    tessel_cloud r2;
    p.cluster.spacing = st.spacing;
    p.projection.spacing = st.spacing;
    CHECK(tessel_cluster(&c, &p.cluster, NULL, &cl) == TESSEL_OK);
    CHECK(tessel_representatives(&c, &cl, &p, NULL, &r2, NULL) == TESSEL_OK);
    CHECK(r2.count == r.count && memcmp(r2.xyz, r.xyz, r.count * 3 * sizeof(float)) == 0);
    tessel_cloud_free(&r2);

    /* With a projector made outside, on another projector's kd-tree (the
     * pipeline's way): the same representatives. */
    tessel_projector *lender = NULL, *pr = NULL;
    tessel_smooth_params other = tessel_smooth_params_default();
    other.spacing = st.spacing;
    CHECK(tessel_projector_create(&lender, &c, &other) == TESSEL_OK);
    CHECK(tsl_projector_create_on(&pr, &c, &p.projection,
                                  tsl_projector_index(lender, c.xyz, c.count)) == TESSEL_OK);
    CHECK(tsl_representatives_with(&c, &cl, &p, pr, NULL, &r2, NULL) == TESSEL_OK);
    CHECK(r2.count == r.count && memcmp(r2.xyz, r.xyz, r.count * 3 * sizeof(float)) == 0 &&
          memcmp(r2.normals, r.normals, r.count * 3 * sizeof(float)) == 0);
    tessel_cloud_free(&r2);
    tessel_projector_destroy(pr);
    tessel_projector_destroy(lender);

    /* Thread count does not matter. */
    p.projection.threads = 1;
    CHECK(tessel_representatives(&c, &cl, &p, NULL, &r2, NULL) == TESSEL_OK);
    CHECK(r2.count == r.count && memcmp(r2.xyz, r.xyz, r.count * 3 * sizeof(float)) == 0 &&
          memcmp(r2.normals, r.normals, r.count * 3 * sizeof(float)) == 0);
    tessel_cloud_free(&r2);

    /* Clusters of another cloud are refused. */
    c.count--;
    CHECK(tessel_representatives(&c, &cl, &p, NULL, &r2, NULL) == TESSEL_ERR_INVALID_ARG);
    c.count++;
    tessel_clusters_free(&cl);
    tessel_cloud_free(&r);
    tessel_cloud_free(&c);
    tessel_cloud_free(&noisy);
}

/* Isolated outliers form their own clusters (the diameter rule), whose
 * centroids have no robust fit: no representative unless asked; colours
 * are cluster means. */
static void test_outliers_and_colour(void)
{
    rng_state = 4;
    tessel_cloud plane, c, r;
    make_plane(&plane, 60);
    size_t n = plane.count + 3;
    CHECK(tessel_cloud_alloc(&c, n, 0, 1) == TESSEL_OK);
    memcpy(c.xyz, plane.xyz, plane.count * 3 * sizeof(float));
    for (size_t i = 0; i < plane.count; i++) {
        c.rgb[3 * i] = 200;
        c.rgb[3 * i + 1] = (uint8_t)(i % 2 ? 100 : 101);
        c.rgb[3 * i + 2] = 0;
    }
    for (size_t i = plane.count; i < n; i++) {
        c.xyz[3 * i] = 0.5f;
        c.xyz[3 * i + 1] = 0.5f;
        c.xyz[3 * i + 2] = (float)(i - plane.count + 1);
    }
    tessel_simplify_params p = tessel_simplify_params_default();
    p.cluster.spacing = p.projection.spacing = 1.0 / 60;
    tessel_simplify_stats st;
    CHECK(tessel_simplify(&c, &r, &p, NULL, &st) == TESSEL_OK);
    CHECK_MSG(st.unfit == 3 && r.count == st.clusters - 3, "unfit %zu", st.unfit);
    size_t off = 0, bad_rgb = 0;
    for (size_t i = 0; i < r.count; i++) {
        off += fabs(r.xyz[3 * i + 2]) > 1e-6;
        bad_rgb += r.rgb[3 * i] != 200 || r.rgb[3 * i + 1] < 100 || r.rgb[3 * i + 1] > 101;
    }
    CHECK(off == 0 && bad_rgb == 0);
    tessel_cloud_free(&r);
    p.keep_unfit = 1;
    CHECK(tessel_simplify(&c, &r, &p, NULL, &st) == TESSEL_OK);
    CHECK(r.count == st.clusters);
    size_t lifted = 0;
    for (size_t i = 0; i < r.count; i++)
        lifted += r.xyz[3 * i + 2] >= 1.0f;
    CHECK(lifted == 3);
    tessel_cloud_free(&r);
    tessel_cloud_free(&c);
    tessel_cloud_free(&plane);
}

static void test_args(void)
{
    rng_state = 5;
    tessel_cloud c, r;
    make_plane(&c, 10);
    tessel_clusters cl;
    tessel_cluster_params bad[4];
    for (int i = 0; i < 4; i++)
        bad[i] = tessel_cluster_params_default();
    bad[0].sigma_max = 0.5;
    bad[1].n_min = 0;
    bad[2].max_diameter = 0;
    bad[3].spacing = NAN;
    for (int i = 0; i < 4; i++)
        CHECK_MSG(tessel_cluster(&c, &bad[i], NULL, &cl) == TESSEL_ERR_INVALID_ARG &&
                      cl.labels == NULL,
                  "bad params %d accepted", i);
    CHECK(tessel_cluster(NULL, NULL, NULL, &cl) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_cluster(&c, NULL, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    c.count = 0;
    CHECK(tessel_cluster(&c, NULL, NULL, &cl) == TESSEL_ERR_TOO_FEW_POINTS);
    c.count = 2;
    CHECK(tessel_simplify(&c, &r, NULL, NULL, NULL) == TESSEL_ERR_TOO_FEW_POINTS);
    c.count = 100;
    tessel_simplify_params sp = tessel_simplify_params_default();
    sp.projection.k = 1;
    CHECK(tessel_simplify(&c, &r, &sp, NULL, NULL) == TESSEL_ERR_INVALID_ARG);
    CHECK(r.xyz == NULL && r.count == 0);
    tessel_cloud_free(&c);
}

int main(void)
{
    test_sphere_rules();
    test_plane();
    test_representatives();
    test_outliers_and_colour();
    test_args();
    return TEST_SUMMARY();
}
