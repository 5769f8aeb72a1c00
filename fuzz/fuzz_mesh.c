/* libFuzzer target for what takes a caller's mesh: tessel_mesh_check
 * (`tessel check` measures meshes from any tool, broken ones included) and
 * tessel_refine. The input is a small mesh whose vertices lie on a coarse
 * lattice and whose triangles are arbitrary index triples, so repeated
 * indices, duplicate and degenerate triangles, non-manifold fans, flipped
 * neighbours and crossings all come often.
 *
 * Checked: the check succeeds on every such mesh, gives the same report on
 * one and two threads, and its counts agree with each other; measured
 * against itself as reference a mesh has F-score 100. A mesh the check
 * calls valid stays valid through tessel_refine (tessel.h: every split and
 * flip keeps it manifold, oriented and free of self-intersections), one
 * valid but for vertices of several fans stays so (no edge of three
 * triangles, no crossing), and
 * greedy projection started from it as existing triangles adds only
 * triangles that keep it valid; any other mesh is refused or refined
 * without a crash.
 *
 * Input: byte 0 options, byte 1 the scale, byte 2 the vertex count (3 to
 * 64), three bytes per vertex (as fuzz_reconstruct: high five bits a
 * lattice step, low three a small offset), then three bytes per triangle
 * (indices modulo the vertex count, at most 256 triangles). */
#include "tessel.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define MAX_TRIANGLES 256

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static double coordinate(uint8_t b, double scale)
{
    return scale * ((double)(b >> 3) + 0.01 * (double)(b & 7));
}

/* Measures m into *r; false when the reference was refused. */
static bool check(const tessel_mesh *m, const tessel_cloud *input, const tessel_mesh *reference,
                  int threads, tessel_mesh_report *r)
{
    tessel_check_params cp = tessel_check_params_default();
    cp.threads = threads;
    cp.input = input;
    cp.reference = reference;
    cp.samples = 2000;
    tessel_status st = tessel_mesh_check(m, &cp, r);
    /* A reference without a non-degenerate triangle is the only refusal
     * left: indices are in range and coordinates finite. */
    if (st != TESSEL_OK && !(reference && st == TESSEL_ERR_INVALID_ARG))
        abort();
    return st == TESSEL_OK;
}

static int same_double(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

static void same_reports(const tessel_mesh_report *a, const tessel_mesh_report *b)
{
    if (a->components != b->components || a->edges != b->edges ||
        a->boundary_edges != b->boundary_edges || a->boundary_loops != b->boundary_loops ||
        a->nonmanifold_edges != b->nonmanifold_edges ||
        a->nonmanifold_vertices != b->nonmanifold_vertices ||
        a->orientation_conflicts != b->orientation_conflicts ||
        a->self_intersections != b->self_intersections ||
        a->self_intersecting_triangles != b->self_intersecting_triangles ||
        a->duplicate_triangles != b->duplicate_triangles ||
        a->degenerate_triangles != b->degenerate_triangles || a->euler != b->euler ||
        a->genus != b->genus || !same_double(a->area, b->area) ||
        !same_double(a->min_angle_deg, b->min_angle_deg) || !same_double(a->fscore, b->fscore) ||
        !same_double(a->chamfer, b->chamfer) ||
        !same_double(a->input_distance_rms, b->input_distance_rms))
        abort();
}

/* Valid but for vertices with more than one fan (a tessel_refine input
 * may have them; its output must then be valid in the same sense). */
static bool valid_but_pinched(const tessel_mesh_report *r)
{
    return r->triangles > 0 && !r->nonmanifold_edges && !r->orientation_conflicts &&
           !r->self_intersections && !r->duplicate_triangles && !r->degenerate_triangles;
}

static void consistent(const tessel_mesh_report *r, size_t triangles)
{
    if (r->triangles != triangles || r->boundary_edges > r->edges ||
        r->nonmanifold_edges > r->edges || r->self_intersecting_triangles > triangles ||
        r->duplicate_triangles + r->degenerate_triangles > 2 * triangles ||
        (r->self_intersections == 0) != (r->self_intersecting_triangles == 0) ||
        (r->orientation_conflicts == 0) != (r->oriented == 1))
        abort();
    if (tessel_mesh_report_valid(r) &&
        (r->nonmanifold_edges || r->nonmanifold_vertices || r->orientation_conflicts ||
         r->self_intersections || r->duplicate_triangles || r->degenerate_triangles))
        abort();
}

typedef struct tri_list {
    uint32_t *t;
    size_t n, cap;
} tri_list;

static tessel_status collect(void *user, const uint32_t *t, size_t count)
{
    tri_list *l = user;
    if (l->n + count > l->cap) {
        size_t cap = 2 * (l->n + count);
        uint32_t *p = realloc(l->t, 3 * cap * sizeof *p);
        if (!p)
            return TESSEL_ERR_NOMEM;
        l->t = p;
        l->cap = cap;
    }
    memcpy(l->t + 3 * l->n, t, 3 * count * sizeof *t);
    l->n += count;
    return TESSEL_OK;
}

/* Greedy projection started from the valid mesh m as existing triangles
 * (how tiles are stitched): m's triangles and the new ones together must
 * be valid. */
static void grow_from(const tessel_mesh *m, const tessel_cloud *cloud)
{
    tessel_greedy_params gp = tessel_greedy_params_default();
    gp.existing = m->triangles;
    gp.existing_count = m->triangle_count;
    tri_list added = {NULL, 0, 0};
    tessel_triangle_sink sink = {collect, &added};
    tessel_status st = tessel_reconstruct_greedy(cloud, &gp, NULL, &sink, NULL);
    if (st != TESSEL_OK && st != TESSEL_ERR_INVALID_ARG && st != TESSEL_ERR_TOO_FEW_POINTS)
        abort();
    tessel_mesh all;
    if (st == TESSEL_OK &&
        tessel_mesh_alloc(&all, cloud->count, m->triangle_count + added.n, 0, 0) == TESSEL_OK) {
        memcpy(all.xyz, cloud->xyz, 3 * cloud->count * sizeof *all.xyz);
        if (m->triangle_count)
            memcpy(all.triangles, m->triangles, 3 * m->triangle_count * sizeof *all.triangles);
        if (added.n) /* added.t is NULL when nothing was added */
            memcpy(all.triangles + 3 * m->triangle_count, added.t,
                   3 * added.n * sizeof *all.triangles);
        tessel_mesh_report r;
        check(&all, NULL, NULL, 1, &r);
        if (!tessel_mesh_report_valid(&r))
            abort();
        tessel_mesh_free(&all);
    }
    free(added.t);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 3)
        return 0;
    const uint8_t opt = data[0];
    const double scale = pow(10.0, (double)(data[1] % 13) - 6.0);
    const size_t nv = 3 + data[2] % 62;
    if (size < 3 + 3 * nv + 3)
        return 0;
    size_t nt = (size - 3 - 3 * nv) / 3;
    if (nt > MAX_TRIANGLES)
        nt = MAX_TRIANGLES;
    tessel_mesh m;
    if (tessel_mesh_alloc(&m, nv, nt, 0, 0) != TESSEL_OK)
        return 0;
    const uint8_t *p = data + 3;
    for (size_t i = 0; i < 3 * nv; i++)
        m.xyz[i] = (float)coordinate(p[i], scale);
    p += 3 * nv;
    for (size_t i = 0; i < 3 * nt; i++)
        m.triangles[i] = (uint32_t)(p[i] % nv);

    /* The cloud: the vertices, and each triangle's centroid moved off it
     * along its normal by -0.3, 0 or 0.3 of its size, so that refinement
     * finds edges to split. */
    tessel_cloud cloud;
    if (tessel_cloud_alloc(&cloud, nv + nt, 0, 0) != TESSEL_OK) {
        tessel_mesh_free(&m);
        return 0;
    }
    memcpy(cloud.xyz, m.xyz, 3 * nv * sizeof *m.xyz);
    for (size_t t = 0; t < nt; t++) {
        const float *a = m.xyz + 3 * (size_t)m.triangles[3 * t],
                    *b = m.xyz + 3 * (size_t)m.triangles[3 * t + 1],
                    *c = m.xyz + 3 * (size_t)m.triangles[3 * t + 2];
        double u[3], v[3], n[3];
        for (int k = 0; k < 3; k++) {
            u[k] = (double)b[k] - a[k];
            v[k] = (double)c[k] - a[k];
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        /* |n| is twice the area: a length of sqrt(|n|) over |n| per unit */
        double lift = len > 0.0 ? 0.3 * (double)((int)(t % 3) - 1) / sqrt(len) : 0.0;
        for (int k = 0; k < 3; k++)
            cloud.xyz[3 * (nv + t) + k] =
                (float)(((double)a[k] + b[k] + c[k]) / 3.0 + lift * n[k]);
    }

    tessel_mesh_report r1;
    check(&m, NULL, NULL, 1, &r1);
    consistent(&r1, nt);
    if (opt & 1) {
        tessel_mesh_report r2;
        check(&m, NULL, NULL, 2, &r2);
        same_reports(&r1, &r2);
    }
    if (opt & 2) {
        tessel_mesh_report a;
        if (check(&m, &cloud, &m, 1, &a)) {
            consistent(&a, nt);
            if (a.fscore != 100.0 && a.tau > 0.0)
                abort();
            if (opt & 1) {
                tessel_mesh_report b;
                check(&m, &cloud, &m, 2, &b);
                same_reports(&a, &b);
            }
        }
    }
    if ((opt & 0x60) == 0x60 && tessel_mesh_report_valid(&r1))
        grow_from(&m, &cloud);
    if (opt & 4) {
        tessel_refine_params rp = tessel_refine_params_default();
        rp.rounds = 1 + ((opt >> 3) & 1);
        rp.k = 1 + (opt >> 4) % 8;
        rp.flip = !(opt & 0x80);
        rp.threads = 1;
        tessel_status st = tessel_refine(&m, &cloud, NULL, &rp, NULL, NULL);
        if (st != TESSEL_OK && st != TESSEL_ERR_INVALID_ARG && st != TESSEL_ERR_TOO_FEW_POINTS)
            abort();
        if (st == TESSEL_OK && valid_but_pinched(&r1)) {
            tessel_mesh_report after;
            check(&m, NULL, NULL, 1, &after);
            consistent(&after, m.triangle_count);
            if (!valid_but_pinched(&after) ||
                (tessel_mesh_report_valid(&r1) && !tessel_mesh_report_valid(&after)))
                abort();
        }
    }
    tessel_cloud_free(&cloud);
    tessel_mesh_free(&m);
    return 0;
}
