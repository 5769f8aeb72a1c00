/* libFuzzer target for the reconstruction methods: the input is a small
 * cloud, built so that the awkward cases come often (points on a coarse
 * lattice, hence exact duplicates, ties, collinear and coplanar runs; a
 * scale byte from 1e-6 to 1e6), and one method with some of its options.
 * Whatever the cloud, a method must return (no crash, no hang: run.sh gives
 * each input a time limit) and, when it succeeds, give a mesh that
 * tessel_mesh_check calls valid: manifold, consistently oriented, free of
 * self-intersections, duplicate and degenerate triangles. tessel.h promises
 * the fixed-plane modes all but the self-intersections, for clouds that are
 * no height field; height and range mode are checked for them all the same
 * (each find so far was a fault, now mended: docs/fixed_plane.md). Grid
 * mode is not: a grid of arbitrary points is no camera image, and its
 * triangles, all facing the viewpoint, can still cross. With the option
 * byte's top bit,
 * the methods that take a thread count run again on two threads and must
 * give the same mesh, bit for bit, and greedy (one thread) gets a
 * viewpoint at the lattice's centre, by which its orientation check votes.
 *
 * Input: byte 0 picks the method and options, byte 1 the scale, then three
 * bytes per point (at most MAX_POINTS): each coordinate is its byte's high
 * five bits as a lattice step plus its low three bits as a small offset. */
#include "tessel.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define MAX_POINTS 3000

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static double coordinate(uint8_t b, double scale)
{
    return scale * ((double)(b >> 3) + 0.01 * (double)(b & 7));
}

static void check_valid(const tessel_mesh *m, int self_intersections)
{
    if (m->triangle_count == 0)
        return;
    tessel_mesh_report r;
    tessel_check_params cp = tessel_check_params_default();
    cp.self_intersections = self_intersections;
    cp.threads = 1;
    if (tessel_mesh_check(m, &cp, &r) != TESSEL_OK || !tessel_mesh_report_valid(&r))
        abort();
}

/* The cloud's points as the rows of a grid of w columns (the last,
 * incomplete row dropped); 0 when too few points or no memory. */
static int organize(tessel_cloud *c, uint32_t w)
{
    uint32_t h = (uint32_t)(c->count / w);
    if (h < 2)
        return 0;
    c->grid = malloc((size_t)w * h * sizeof *c->grid);
    if (!c->grid)
        return 0;
    for (uint32_t i = 0; i < w * h; i++)
        c->grid[i] = i;
    c->count = (size_t)w * h;
    c->width = w;
    c->height = h;
    return 1;
}

/* The same call with two threads must give the same status and, on
 * success, the same mesh, bit for bit; frees m2. */
static void same_result(tessel_status s1, const tessel_mesh *m1, tessel_status s2,
                        tessel_mesh *m2)
{
    if (s1 != s2)
        abort();
    if (s2 != TESSEL_OK)
        return;
    if (m1->vertex_count != m2->vertex_count || m1->triangle_count != m2->triangle_count ||
        memcmp(m1->xyz, m2->xyz, 3 * m1->vertex_count * sizeof *m1->xyz) != 0 ||
        memcmp(m1->triangles, m2->triangles, 3 * m1->triangle_count * sizeof *m1->triangles) != 0)
        abort();
    tessel_mesh_free(m2);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2 + 9)
        return 0;
    const uint8_t opt = data[0];
    const double scale = pow(10.0, (double)(data[1] % 13) - 6.0);
    size_t n = (size - 2) / 3;
    if (n > MAX_POINTS)
        n = MAX_POINTS;
    tessel_cloud c;
    if (tessel_cloud_alloc(&c, n, 0, 0) != TESSEL_OK)
        return 0;
    for (size_t i = 0; i < 3 * n; i++)
        c.xyz[i] = (float)coordinate(data[2 + i], scale);

    tessel_mesh m;
    tessel_status st;
    int grid = 0;
    switch (opt % 5) {
    case 0:
    case 1: { /* greedy: default, or the paper's own triangles */
        tessel_greedy_params p = tessel_greedy_params_default();
        p.mu = 1.5 + (double)((opt >> 3) & 7) * 0.5;
        p.min_angle = (opt & 0x40) ? 10.0 : 0.0;
        if (opt % 5 == 1)
            p.flip = 0, p.orient_check = 0, p.max_hole = 0;
        if (opt & 0x80) { /* a scan: the check votes by the viewpoint */
            c.has_viewpoint = 1;
            c.viewpoint[0] = c.viewpoint[1] = c.viewpoint[2] = coordinate(128, scale);
        }
        st = tessel_reconstruct_greedy_mesh(&c, &p, NULL, &m, NULL);
        break;
    }
    case 2: { /* greedy with the axis plane */
        tessel_greedy_params p = tessel_greedy_params_default();
        p.plane = TESSEL_GREEDY_PLANE_AXIS;
        st = tessel_reconstruct_greedy_mesh(&c, &p, NULL, &m, NULL);
        break;
    }
    case 3: { /* height field; with bit 3 a range scan from the lattice's centre, with
               * bit 4 as well the points as an organized grid of 4 to 16 columns seen
               * from there */
        tessel_fixed_plane_params p = tessel_fixed_plane_params_default();
        p.threads = 1;
        if (opt & 0x08) {
            p.mode = TESSEL_FIXED_PLANE_RANGE;
            p.use_viewpoint = 1;
            p.viewpoint[0] = p.viewpoint[1] = p.viewpoint[2] = coordinate(128, scale);
        }
        if ((opt & 0x18) == 0x18) {
            if (!organize(&c, 4 + 4 * ((opt >> 5) & 3))) {
                tessel_cloud_free(&c);
                return 0;
            }
            p.mode = TESSEL_FIXED_PLANE_GRID;
            grid = 1;
        }
        st = tessel_reconstruct_fixed_plane_mesh(&c, &p, NULL, &m, NULL);
        if (opt & 0x80) {
            p.threads = 2;
            tessel_mesh m2;
            same_result(st, &m, tessel_reconstruct_fixed_plane_mesh(&c, &p, NULL, &m2, NULL),
                        &m2);
        }
        break;
    }
    default: { /* the smooth method */
        tessel_smooth_recon_params p = tessel_smooth_recon_params_default();
        p.threads = 1;
        p.refine.rounds = (opt >> 3) & 1 ? 2 : 0;
        if ((opt >> 4) & 1) /* the front in tiles and their seams */
            p.front.tile_points = 256;
        if ((opt >> 5) & 1) /* each point (and its copies) out of its own fit */
            p.smooth.exclude_self = 1;
        st = tessel_reconstruct_smooth(&c, &p, NULL, &m, NULL);
        if (opt & 0x80) {
            p.threads = 2;
            tessel_mesh m2;
            same_result(st, &m, tessel_reconstruct_smooth(&c, &p, NULL, &m2, NULL), &m2);
        }
        break;
    }
    }
    if (st == TESSEL_OK) {
        check_valid(&m, !grid);
        tessel_mesh_free(&m);
    }
    tessel_cloud_free(&c);
    return 0;
}
