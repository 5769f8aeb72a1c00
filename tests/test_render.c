/* Rendering: coverage of a centred sphere against the analytic disc,
 * back-face colour for flipped triangles, red boundary for holes, empty
 * meshes, determinism across thread counts, the contact sheet, and the CLI's
 * PNG output. */
#include "core/core.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

enum { NLAT = 64, NLON = 128 };

/* A UV sphere of radius 1 at the origin, outward counter-clockwise. */
static tessel_mesh uv_sphere(void)
{
    size_t nv = 2 + (NLAT - 1) * NLON, nf = 2 * NLON * (NLAT - 1);
    tessel_mesh m;
    if (tessel_mesh_alloc(&m, nv, nf, 0, 0) != TESSEL_OK)
        abort();
    const double pi = 3.14159265358979323846;
    float *v = m.xyz;
    v[0] = 0, v[1] = 1, v[2] = 0;    /* north pole (Y up) */
    v[3] = 0, v[4] = -1, v[5] = 0;   /* south pole */
    for (int i = 1; i < NLAT; i++)
        for (int j = 0; j < NLON; j++) {
            double th = pi * i / NLAT, ph = 2 * pi * j / NLON;
            float *p = v + 3 * (2 + (size_t)(i - 1) * NLON + (size_t)j);
            p[0] = (float)(sin(th) * sin(ph));
            p[1] = (float)cos(th);
            p[2] = (float)(sin(th) * cos(ph));
        }
    uint32_t *t = m.triangles;
#define RING(i, j) ((uint32_t)(2 + ((i) - 1) * NLON + ((j) % NLON)))
    for (int j = 0; j < NLON; j++) {
        *t++ = 0, *t++ = RING(1, j), *t++ = RING(1, j + 1);
        *t++ = 1, *t++ = RING(NLAT - 1, j + 1), *t++ = RING(NLAT - 1, j);
    }
    for (int i = 1; i < NLAT - 1; i++)
        for (int j = 0; j < NLON; j++) {
            uint32_t a = RING(i, j), b = RING(i, j + 1), c = RING(i + 1, j), d = RING(i + 1, j + 1);
            *t++ = a, *t++ = c, *t++ = d;
            *t++ = a, *t++ = d, *t++ = b;
        }
#undef RING
    return m;
}

typedef struct counts {
    size_t background, front, back, red, other;
} counts;

static counts classify_pixels(const uint8_t *rgb, size_t n, const tessel_render_params *p)
{
    counts c = {0, 0, 0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        const uint8_t *x = rgb + 3 * i;
        if (memcmp(x, p->background, 3) == 0)
            c.background++;
        else if (x[0] > 200 && x[1] < 60 && x[2] < 60)
            c.red++;
        else if (x[2] > x[0] + 40)
            c.back++; /* the blue back colour, shaded */
        else if (abs(x[0] - x[2]) < 40 && x[0] > 40)
            c.front++; /* the warm grey front colour, shaded */
        else
            c.other++;
    }
    return c;
}

static void test_sphere_coverage(void)
{
    tessel_mesh m = uv_sphere();
    tessel_render_params p = tessel_render_params_default();
    p.width = 400;
    p.height = 300;
    const double pi = 3.14159265358979323846;
    /* Fitted to 90% of the shorter side: a disc of radius 0.45 * 300 px. */
    double want = pi * 135.0 * 135.0 / (400.0 * 300.0);
    uint8_t *rgb = malloc(400 * 300 * 3);
    tessel_view views[] = {TESSEL_VIEW_FRONT, TESSEL_VIEW_TOP, TESSEL_VIEW_ISO, TESSEL_VIEW_LEFT};
    for (size_t k = 0; k < sizeof views / sizeof *views; k++) {
        p.view = views[k];
        CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
        counts c = classify_pixels(rgb, 400 * 300, &p);
        double share = (double)(400 * 300 - c.background) / (400.0 * 300.0);
        CHECK_MSG(fabs(share - want) < 0.02 * want, "view %d: share %.4f, want %.4f",
                  (int)views[k], share, want);
        CHECK_MSG(c.back == 0 && c.red == 0, "view %d: %zu back, %zu red pixels",
                  (int)views[k], c.back, c.red);
        CHECK(c.front > 0.95 * (400 * 300 - c.background));
        /* The centre faces the headlight: brightest front colour. */
        const uint8_t *mid = rgb + 3 * (150 * 400 + 200);
        CHECK(abs(mid[0] - p.front_color[0]) <= 2 && abs(mid[2] - p.front_color[2]) <= 2);
    }
    free(rgb);
    tessel_mesh_free(&m);
}

/* Triangles whose centroid lies in front (z > 0.9): what the front view
 * sees in the middle. */
static bool in_front(const tessel_mesh *m, size_t t)
{
    double z = 0;
    for (int k = 0; k < 3; k++)
        z += m->xyz[3 * (size_t)m->triangles[3 * t + k] + 2];
    return z / 3 > 0.9;
}

static void test_flipped_and_hole(void)
{
    tessel_render_params p = tessel_render_params_default();
    p.width = 320;
    p.height = 320;
    p.view = TESSEL_VIEW_FRONT;
    uint8_t *rgb = malloc(320 * 320 * 3);

    tessel_mesh m = uv_sphere();
    size_t flipped = 0;
    for (size_t t = 0; t < m.triangle_count; t++)
        if (in_front(&m, t)) {
            uint32_t x = m.triangles[3 * t + 1];
            m.triangles[3 * t + 1] = m.triangles[3 * t + 2];
            m.triangles[3 * t + 2] = x;
            flipped++;
        }
    CHECK(flipped > 10);
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
    counts c = classify_pixels(rgb, 320 * 320, &p);
    CHECK_MSG(c.back > 1000 && c.red == 0, "flipped: %zu back, %zu red", c.back, c.red);
    const uint8_t *mid = rgb + 3 * (160 * 320 + 160);
    CHECK(mid[2] > mid[0] + 40); /* the centre is back-coloured */
    tessel_mesh_free(&m);

    /* Remove the same triangles: a hole, ringed in red, through which the
     * inside (back faces) of the far side shows. */
    m = uv_sphere();
    size_t kept = 0;
    for (size_t t = 0; t < m.triangle_count; t++)
        if (!in_front(&m, t)) {
            memmove(m.triangles + 3 * kept, m.triangles + 3 * t, 3 * sizeof(uint32_t));
            kept++;
        }
    m.triangle_count = kept;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
    c = classify_pixels(rgb, 320 * 320, &p);
    CHECK_MSG(c.red > 100 && c.back > 1000, "hole: %zu red, %zu back", c.red, c.back);
    /* Seen from behind, the hole is hidden by the sphere: no red. */
    p.view = TESSEL_VIEW_BACK;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
    c = classify_pixels(rgb, 320 * 320, &p);
    CHECK_MSG(c.red == 0, "hole from behind: %zu red", c.red);
    /* boundary = 0 turns the ring off */
    p.view = TESSEL_VIEW_FRONT;
    p.boundary = 0;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
    c = classify_pixels(rgb, 320 * 320, &p);
    CHECK(c.red == 0);
    tessel_mesh_free(&m);
    free(rgb);
}

static void test_empty_and_cloud(void)
{
    tessel_render_params p = tessel_render_params_default();
    p.width = 64;
    p.height = 48;
    uint8_t rgb[64 * 48 * 3];
    tessel_mesh empty;
    memset(&empty, 0, sizeof empty);
    for (int v = TESSEL_VIEW_FRONT; v <= TESSEL_VIEW_ALL; v++) {
        p.view = (tessel_view)v;
        memset(rgb, 7, sizeof rgb);
        CHECK(tessel_render(&empty, &p, rgb) == TESSEL_OK);
    }
    p.view = TESSEL_VIEW_ISO;
    counts c = classify_pixels(rgb, 64 * 48, &p);
    (void)c;
    CHECK(tessel_render(&empty, &p, rgb) == TESSEL_OK);
    c = classify_pixels(rgb, 64 * 48, &p);
    CHECK(c.background == 64 * 48);

    /* A cloud (no triangles) of a sphere's vertices: splats cover roughly
     * the disc; a single point still draws. */
    tessel_mesh m = uv_sphere();
    m.triangle_count = 0;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
    c = classify_pixels(rgb, 64 * 48, &p);
    CHECK(c.background < 64 * 48 && c.background > 64 * 48 / 4);
    m.vertex_count = 1;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
    c = classify_pixels(rgb, 64 * 48, &p);
    CHECK(c.background < 64 * 48);
    tessel_mesh_free(&m);

    /* Bad arguments. */
    m = uv_sphere();
    p.width = 0;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_ERR_INVALID_ARG);
    p.width = 64;
    m.triangles[5] = (uint32_t)m.vertex_count;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_ERR_INVALID_ARG);
    CHECK(tessel_render(NULL, &p, rgb) == TESSEL_ERR_INVALID_ARG);
    /* Non-finite vertices are skipped, not drawn across the image. */
    m.triangles[5] = 0;
    m.xyz[3 * 5] = NAN;
    m.xyz[3 * 9 + 1] = INFINITY;
    p.edges = 1;
    p.points = 1;
    CHECK(tessel_render(&m, &p, rgb) == TESSEL_OK);
    tessel_mesh_free(&m);
    CHECK(tessel_view_from_name("iso") == TESSEL_VIEW_ISO);
    CHECK(tessel_view_from_name("all") == TESSEL_VIEW_ALL);
    CHECK(tessel_view_from_name("sideways") == -1);
}

static void test_threads_and_sheet(void)
{
    tessel_mesh m = uv_sphere();
    tessel_render_params p = tessel_render_params_default();
    p.width = 301;
    p.height = 203;
    p.edges = 1;
    p.points = 1;
    p.view = TESSEL_VIEW_ALL;
    size_t n = 301 * 203 * 3;
    uint8_t *a = malloc(n), *b = malloc(n);
    p.threads = 1;
    CHECK(tessel_render(&m, &p, a) == TESSEL_OK);
    p.threads = 3;
    CHECK(tessel_render(&m, &p, b) == TESSEL_OK);
    CHECK(memcmp(a, b, n) == 0);
    /* Every quadrant of the sheet shows the sphere around its centre. */
    uint32_t cx[2] = {75, 226}, cy[2] = {50, 152};
    for (int i = 0; i < 4; i++) {
        const uint8_t *px = a + 3 * ((size_t)cy[i / 2] * 301 + cx[i % 2]);
        CHECK_MSG(memcmp(px, p.background, 3) != 0, "cell %d empty", i);
    }
    free(a);
    free(b);
    tessel_mesh_free(&m);
}

/* The CLI writes a PNG of the right size from a point file. */
static void test_cli_png(void)
{
    const char *xyz = "test_render_cloud.xyz", *png = "test_render_cloud.png";
    FILE *fp = fopen(xyz, "w");
    CHECK(fp != NULL);
    if (!fp)
        return;
    for (int i = 0; i < 500; i++)
        fprintf(fp, "%g %g %g\n", cos(i * 0.1), sin(i * 0.1), i * 0.01);
    fclose(fp);
    remove(png);
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "\"%s\" render %s %s --size 120x80 --view front --quiet",
             TESSEL_CLI, xyz, png);
    CHECK(system(cmd) == 0);
    uint8_t head[24] = {0};
    fp = fopen(png, "rb");
    CHECK(fp != NULL);
    if (fp) {
        CHECK(fread(head, 1, 24, fp) == 24);
        fclose(fp);
    }
    static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    CHECK(memcmp(head, sig, 8) == 0);
    uint32_t w = (uint32_t)head[16] << 24 | head[17] << 16 | head[18] << 8 | head[19];
    uint32_t h = (uint32_t)head[20] << 24 | head[21] << 16 | head[22] << 8 | head[23];
    CHECK(w == 120 && h == 80);
    /* A bad size is a usage error (exit 1) and leaves no file behind. */
    remove(png);
    snprintf(cmd, sizeof cmd, "\"%s\" render %s %s --size 0x80 --quiet 2>/dev/null",
             TESSEL_CLI, xyz, png);
    int rc = system(cmd);
    CHECK(rc != -1 && WIFEXITED(rc) && WEXITSTATUS(rc) == 1);
    fp = fopen(png, "rb");
    CHECK(fp == NULL);
    if (fp)
        fclose(fp);
    remove(xyz);
    remove(png);
}

int main(void)
{
    test_sphere_coverage();
    test_flipped_and_hole();
    test_empty_and_cloud();
    test_threads_and_sheet();
    test_cli_png();
    return TEST_SUMMARY();
}
