/* Greedy projection out of core (tessel_reconstruct_greedy_file): clouds
 * forced through a budget of a few thousand points per slab come out as
 * valid as in core, the same kind of surface (pieces, border), the same
 * bytes for any thread count, and no scratch file is left, whether the
 * call succeeds, fails or is cancelled. */
#include "surfaces.h"
#include "test.h"

#include <dirent.h>
#include <sys/stat.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[256];

static tessel_mesh_report check_mesh(const tessel_mesh *m)
{
    tessel_check_params cp = tessel_check_params_default();
    tessel_mesh_report rep;
    memset(&rep, 0, sizeof rep);
    CHECK(tessel_mesh_check(m, &cp, &rep) == TESSEL_OK);
    return rep;
}

/* Six times the signed volume enclosed (positive when outward). */
static double signed_volume(const tessel_mesh *m)
{
    double v = 0.0;
    for (size_t t = 0; t < m->triangle_count; t++) {
        const float *a = m->xyz + 3 * (size_t)m->triangles[3 * t];
        const float *b = m->xyz + 3 * (size_t)m->triangles[3 * t + 1];
        const float *c = m->xyz + 3 * (size_t)m->triangles[3 * t + 2];
        v += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
             (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
             (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return v;
}

/* Files in a folder, . and .. aside. */
static int files_in(const char *dir)
{
    int n = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL)
        n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    if (d)
        closedir(d);
    return n;
}

static bool same_file(const char *a, const char *b)
{
    FILE *f = fopen(a, "rb"), *g = fopen(b, "rb");
    bool same = f && g;
    while (same) {
        int x = fgetc(f), y = fgetc(g);
        same = x == y;
        if (x == EOF)
            break;
    }
    if (f)
        fclose(f);
    if (g)
        fclose(g);
    return same;
}

/* Slabs of 1,000 points, the least the sweep takes (memory 1 byte). */
static tessel_status ooc(const char *in, const char *out, int threads, const char *scratch,
                         const tessel_callbacks *cb, tessel_recon_summary *sum)
{
    tessel_greedy_params p = tessel_greedy_params_default();
    p.threads = threads;
    tessel_outofcore_params op = tessel_outofcore_params_default();
    op.memory = 1;
    op.scratch = scratch;
    tessel_diag diag;
    tessel_status st = tessel_reconstruct_greedy_file(in, out, NULL, &p, NULL, &op, cb, sum,
                                                      &diag);
    if (st && st != TESSEL_ERR_CANCELLED)
        fprintf(stderr, "%s: %s\n", diag.file, diag.message);
    return st;
}

/* Against one front in core on generated surfaces: valid, as many pieces,
 * closed ones closed outward, a border no longer than in core's and a few
 * seam edges more at most; every point in core uses is used but a few. */
static void test_against_in_core(void)
{
    const char *names[] = {"sphere", "torus", "open plane", "thin box"};
    char scratch[300], in[300], out[300], out2[300];
    snprintf(scratch, sizeof scratch, "%s/scratch", tmpdir);
    CHECK(mkdir(scratch, 0700) == 0);
    for (int i = 0; i < 4; i++) {
        tessel_cloud c;
        tessel_status st = i == 0   ? surf_sphere(&c, 0.02, 31)
                           : i == 1 ? surf_torus(&c, 1.0, 0.35, 0.02, 32)
                           : i == 2 ? surf_plane_hole(&c, 0.015, 33)
                                    : surf_thin_box(&c, 0.12, 0.02, 34);
        CHECK(st == TESSEL_OK);
        snprintf(in, sizeof in, "%s/in.ply", tmpdir);
        snprintf(out, sizeof out, "%s/out.ply", tmpdir);
        snprintf(out2, sizeof out2, "%s/out2.ply", tmpdir);
        CHECK(tessel_cloud_write(&c, in, NULL, NULL) == TESSEL_OK);
        tessel_mesh whole, part;
        tessel_recon_summary ws, ps;
        CHECK(tessel_reconstruct_greedy_mesh(&c, NULL, NULL, &whole, &ws) == TESSEL_OK);
        tessel_mesh_report w = check_mesh(&whole);
        CHECK(ooc(in, out, 1, scratch, NULL, &ps) == TESSEL_OK);
        CHECK_MSG(files_in(scratch) == 0, "%s: scratch files left", names[i]);
        CHECK(tessel_mesh_read(&part, out, NULL, NULL) == TESSEL_OK);
        tessel_mesh_report r = check_mesh(&part);
        printf("%-10s %6zu points: %3zu slabs, %6zu used (in core %6zu), %4zu boundary edges "
               "(%zu), %zu components (%zu)\n",
               names[i], c.count, ps.slabs, ps.points_used, ws.points_used, r.boundary_edges,
               w.boundary_edges, r.components, w.components);
        CHECK_MSG(ps.slabs >= c.count / 1000, "%s: %zu slabs", names[i], ps.slabs);
        CHECK_MSG(tessel_mesh_report_valid(&r) && r.self_intersections == 0,
                  "%s: invalid: %zu non-manifold edges, %zu vertices, %zu conflicts, %zu "
                  "self-intersections",
                  names[i], r.nonmanifold_edges, r.nonmanifold_vertices,
                  r.orientation_conflicts, r.self_intersections);
        CHECK_MSG(r.components == w.components, "%s: %zu components, in core %zu", names[i],
                  r.components, w.components);
        CHECK_MSG(r.boundary_edges <= w.boundary_edges + 12, "%s: %zu boundary edges, in core %zu",
                  names[i], r.boundary_edges, w.boundary_edges);
        CHECK_MSG(ps.points_used + c.count / 200 >= ws.points_used, "%s: %zu points used of %zu",
                  names[i], ps.points_used, ws.points_used);
        CHECK(ps.triangles == part.triangle_count && ps.points_used == part.vertex_count);
        if (i < 2)
            CHECK_MSG(signed_volume(&part) > 0.0, "%s: meshed inside out", names[i]);
        /* Any thread count: the same bytes. */
        CHECK(ooc(in, out2, 2, scratch, NULL, &ps) == TESSEL_OK);
        CHECK_MSG(same_file(out, out2), "%s: 2 threads differ from 1", names[i]);
        tessel_mesh_free(&whole);
        tessel_mesh_free(&part);
        tessel_cloud_free(&c);
        unlink(out);
        unlink(out2);
    }
    rmdir(scratch);
}

static int cancel_after(void *user, const char *stage, double fraction)
{
    (void)stage;
    (void)fraction;
    int *left = user;
    return --*left < 0;
}

/* Cancelled at any of its progress reports and failing on a bad output:
 * no output, no scratch file. */
static void test_cleanup(void)
{
    tessel_cloud c;
    CHECK(surf_sphere(&c, 0.03, 41) == TESSEL_OK);
    char in[300], out[300];
    snprintf(in, sizeof in, "%s/in.ply", tmpdir);
    snprintf(out, sizeof out, "%s/out.ply", tmpdir);
    CHECK(tessel_cloud_write(&c, in, NULL, NULL) == TESSEL_OK);
    tessel_cloud_free(&c);
    int before = files_in(tmpdir);
    int reports = 0;
    tessel_callbacks count = {cancel_after, NULL, &reports};
    reports = 1 << 30;
    tessel_recon_summary sum;
    CHECK(ooc(in, out, 0, NULL, &count, &sum) == TESSEL_OK);
    int total = (1 << 30) - reports;
    CHECK(total > 10 && files_in(tmpdir) == before + 1);
    unlink(out);
    for (int at = 0; at < total; at += total / 7 + 1) {
        reports = at;
        CHECK_MSG(ooc(in, out, 0, NULL, &count, &sum) == TESSEL_ERR_CANCELLED,
                  "cancel at report %d", at);
        CHECK_MSG(files_in(tmpdir) == before, "cancelled at report %d: %d files left", at,
                  files_in(tmpdir) - before);
    }
    /* Formats it cannot write, a folder that does not exist, a missing
     * input: refused with the file named, nothing left. */
    tessel_greedy_params p = tessel_greedy_params_default();
    tessel_diag diag;
    snprintf(out, sizeof out, "%s/out.stl", tmpdir);
    CHECK(tessel_reconstruct_greedy_file(in, out, NULL, &p, NULL, NULL, NULL, &sum, &diag) ==
              TESSEL_ERR_UNSUPPORTED &&
          strstr(diag.file, "out.stl"));
    CHECK(tessel_reconstruct_greedy_file(in, "/nonexistent/folder/out.ply", NULL, &p, NULL, NULL,
                                         NULL, &sum, &diag) != TESSEL_OK);
    snprintf(out, sizeof out, "%s/out.ply", tmpdir);
    CHECK(tessel_reconstruct_greedy_file("/nonexistent.ply", out, NULL, &p, NULL, NULL, NULL,
                                         &sum, &diag) == TESSEL_ERR_IO &&
          strstr(diag.file, "nonexistent.ply"));
    CHECK(files_in(tmpdir) == before);
    unlink(in);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/tessel_test_ooc_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_against_in_core();
    test_cleanup();
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
    return TEST_SUMMARY();
}
