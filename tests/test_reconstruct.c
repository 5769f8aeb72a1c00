/* The one entry point (src/reconstruct/): the method auto picks on clean,
 * noisy and organized clouds, an explicit method winning, and a valid mesh
 * from each. */
#include "surfaces.h"
#include "tessel.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void check_valid(const tessel_mesh *m, const char *what)
{
    tessel_check_params cp = tessel_check_params_default();
    tessel_mesh_report r;
    CHECK(tessel_mesh_check(m, &cp, &r) == TESSEL_OK);
    CHECK_MSG(tessel_mesh_report_valid(&r) && r.triangles > 0, "%s: not a valid mesh", what);
}

/* A plane scanned as an organized w x h grid from a viewpoint above it. */
static tessel_status organized(tessel_cloud *c, uint32_t w, uint32_t h)
{
    tessel_status st = tessel_cloud_alloc(c, (size_t)w * h, 0, 0);
    if (st)
        return st;
    c->grid = malloc((size_t)w * h * sizeof *c->grid);
    if (!c->grid)
        return TESSEL_ERR_NOMEM;
    c->width = w;
    c->height = h;
    for (uint32_t r = 0; r < h; r++)
        for (uint32_t k = 0; k < w; k++) {
            size_t i = (size_t)r * w + k;
            c->xyz[3 * i] = (float)k / (float)w - 0.5f;
            c->xyz[3 * i + 1] = (float)r / (float)h - 0.5f;
            c->xyz[3 * i + 2] = 0.0f;
            c->grid[i] = (uint32_t)i;
        }
    c->viewpoint[2] = 2.0;
    c->has_viewpoint = 1;
    return TESSEL_OK;
}

static void test_auto(void)
{
    tessel_cloud c;
    tessel_method_choice ch;
    tessel_mesh m;
    tessel_reconstruct_summary s;

    /* Clean: greedy projection. */
    CHECK(surf_sphere_random(&c, 20000, 1) == TESSEL_OK);
    CHECK(tessel_choose_method(&c, NULL, &ch) == TESSEL_OK);
    CHECK_MSG(ch.method == TESSEL_METHOD_GREEDY && ch.measured && ch.noise_ratio < 0.1,
              "clean sphere: %s at %.2f spacings", tessel_method_name(ch.method), ch.noise_ratio);
    CHECK(tessel_reconstruct(&c, NULL, NULL, &m, &s) == TESSEL_OK);
    CHECK(s.choice.method == TESSEL_METHOD_GREEDY && s.triangles == m.triangle_count);
    check_valid(&m, "clean sphere");
    tessel_mesh_free(&m);

    /* Noisy (one surface spacing): the smooth method, a closed sphere. */
    double hs = sqrt(4.0 * acos(-1.0) / 20000.0);
    surf_noise(&c, hs, 2);
    CHECK(tessel_choose_method(&c, NULL, &ch) == TESSEL_OK);
    CHECK_MSG(ch.method == TESSEL_METHOD_SMOOTH && fabs(ch.noise_ratio - 1.0) < 0.2,
              "noisy sphere: %s at %.2f spacings", tessel_method_name(ch.method), ch.noise_ratio);
    CHECK(tessel_reconstruct(&c, NULL, NULL, &m, &s) == TESSEL_OK);
    CHECK(s.choice.method == TESSEL_METHOD_SMOOTH && s.boundary_edges == 0);
    check_valid(&m, "noisy sphere");
    tessel_mesh_free(&m);

    /* An explicit method wins. */
    tessel_reconstruct_params p = tessel_reconstruct_params_default();
    p.method = TESSEL_METHOD_GREEDY;
    CHECK(tessel_choose_method(&c, &p, &ch) == TESSEL_OK);
    CHECK(ch.method == TESSEL_METHOD_GREEDY && !ch.measured);
    tessel_cloud_free(&c);

    /* Organized with a viewpoint: the range mode. */
    CHECK(organized(&c, 120, 100) == TESSEL_OK);
    CHECK(tessel_choose_method(&c, NULL, &ch) == TESSEL_OK);
    CHECK(ch.method == TESSEL_METHOD_FIXED_PLANE && ch.mode == TESSEL_FIXED_PLANE_RANGE);
    CHECK(tessel_reconstruct(&c, NULL, NULL, &m, &s) == TESSEL_OK);
    /* About 3 points per dexel: 4,000 dexels, two triangles each. */
    CHECK_MSG(s.choice.method == TESSEL_METHOD_FIXED_PLANE && m.triangle_count > 7000,
              "organized plane: %zu triangles", m.triangle_count);
    check_valid(&m, "organized plane");
    tessel_mesh_free(&m);
    CHECK(!s.denoised);
    /* The same scan with range noise: denoised along its rays first. */
    surf_rng rng = surf_seed(3);
    for (size_t i = 0; i < c.count; i++)
        c.xyz[3 * i + 2] += (float)(0.01 * surf_gauss(&rng));
    CHECK(tessel_reconstruct(&c, NULL, NULL, &m, &s) == TESSEL_OK);
    CHECK_MSG(s.denoised && s.denoise.rms_move > 0.005, "noisy organized plane: denoised %d",
              s.denoised);
    check_valid(&m, "noisy organized plane");
    tessel_mesh_free(&m);
    /* Without its viewpoint it is a cloud like any other: noisy. */
    c.has_viewpoint = 0;
    CHECK(tessel_choose_method(&c, NULL, &ch) == TESSEL_OK);
    CHECK(ch.method == TESSEL_METHOD_SMOOTH);
    tessel_cloud_free(&c);

    /* Bad arguments. */
    CHECK(tessel_choose_method(NULL, NULL, &ch) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_reconstruct(NULL, NULL, NULL, &m, NULL) == TESSEL_ERR_INVALID_ARG);
    CHECK(!strcmp(tessel_method_name(TESSEL_METHOD_SMOOTH), "smooth"));
}

int main(void)
{
    test_auto();
    return TEST_SUMMARY();
}
