/* Normal quality and speed against a reference surface.
 *
 * Usage: bench_normals [--k K] [--no-orient] [--threads T] CLOUD REF
 * Estimates the cloud's normals (tessel_normals_estimate), then compares
 * each with the normal of the nearest reference triangle: the share within
 * 30 degrees ignoring sign (plane fit quality) and with sign (orientation),
 * and the share pointing the wrong way (more than 90 degrees). The nearest
 * triangle is the nearest by exact point-triangle distance among the 32
 * triangles whose centroids are nearest (exact for meshes whose triangles
 * are not much larger than their neighbours, as with the reference meshes
 * of the evaluation set, bench/README.md). */
#include "tessel.h"

#include "bench_data.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#define CANDIDATES 32

/* Closest point to p on triangle abc (Ericson, Real-Time Collision
 * Detection, 5.1.5); returns the squared distance. */
static double closest_on_triangle(const double p[3], const double a[3], const double b[3],
                                  const double c[3])
{
    double ab[3], ac[3], ap[3], q[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i];
        ac[i] = c[i] - a[i];
        ap[i] = p[i] - a[i];
    }
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        for (int i = 0; i < 3; i++)
            q[i] = a[i];
    } else {
        double bp[3], cp[3];
        for (int i = 0; i < 3; i++) {
            bp[i] = p[i] - b[i];
            cp[i] = p[i] - c[i];
        }
        double d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
        double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0 && d4 <= d3) {
            for (int i = 0; i < 3; i++)
                q[i] = b[i];
        } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
            double v = d1 / (d1 - d3);
            for (int i = 0; i < 3; i++)
                q[i] = a[i] + v * ab[i];
        } else if (d6 >= 0 && d5 <= d6) {
            for (int i = 0; i < 3; i++)
                q[i] = c[i];
        } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
            double w = d2 / (d2 - d6);
            for (int i = 0; i < 3; i++)
                q[i] = a[i] + w * ac[i];
        } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
            double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            for (int i = 0; i < 3; i++)
                q[i] = b[i] + w * (c[i] - b[i]);
        } else {
            double den = 1.0 / (va + vb + vc), v = vb * den, w = vc * den;
            for (int i = 0; i < 3; i++)
                q[i] = a[i] + ab[i] * v + ac[i] * w;
        }
    }
    double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    return DOT(d, d);
}

static void vertex(const tessel_mesh *m, uint32_t v, double out[3])
{
    for (int a = 0; a < 3; a++)
        out[a] = m->offset[a] + (double)m->xyz[3 * (size_t)v + a];
}

int main(int argc, char **argv)
{
    tessel_normals_params np = tessel_normals_params_default();
    const char *paths[2] = {NULL, NULL};
    int npaths = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--k") && i + 1 < argc)
            np.k = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            np.threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--no-orient"))
            np.orient = 0;
        else if (argv[i][0] != '-' && npaths < 2)
            paths[npaths++] = argv[i];
        else
            npaths = 3;
    }
    if (npaths != 2) {
        fprintf(stderr, "usage: %s [--k K] [--no-orient] [--threads T] CLOUD REF\n", argv[0]);
        return 2;
    }
    tessel_cloud cloud;
    tessel_mesh ref;
    tessel_diag diag;
    tessel_status st = tessel_cloud_read(&cloud, paths[0], NULL, &diag);
    if (st == TESSEL_OK) {
        st = tessel_mesh_read(&ref, paths[1], NULL, &diag);
        if (st != TESSEL_OK)
            tessel_cloud_free(&cloud);
    }
    if (st != TESSEL_OK) {
        fprintf(stderr, "bench_normals: %s: %s\n", diag.file, diag.message);
        return 1;
    }
    if (ref.triangle_count == 0) {
        fprintf(stderr, "bench_normals: %s has no triangles\n", paths[1]);
        return 1;
    }

    double t0 = bench_now();
    st = tessel_normals_estimate(&cloud, &np, NULL);
    double t_est = bench_now() - t0;
    if (st != TESSEL_OK) {
        fprintf(stderr, "bench_normals: %s\n", tessel_status_str(st));
        return 1;
    }

    /* Triangle centroids in the cloud's local frame, and unit normals. */
    size_t nt = ref.triangle_count;
    float *cen = malloc(nt * 3 * sizeof *cen);
    double *tn = malloc(nt * 3 * sizeof *tn);
    for (size_t t = 0; t < nt; t++) {
        double a[3], b[3], c[3], e1[3], e2[3], n[3];
        vertex(&ref, ref.triangles[3 * t], a);
        vertex(&ref, ref.triangles[3 * t + 1], b);
        vertex(&ref, ref.triangles[3 * t + 2], c);
        for (int i = 0; i < 3; i++) {
            cen[3 * t + i] = (float)((a[i] + b[i] + c[i]) / 3.0 - cloud.offset[i]);
            e1[i] = b[i] - a[i];
            e2[i] = c[i] - a[i];
        }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double l = sqrt(DOT(n, n));
        for (int i = 0; i < 3; i++)
            tn[3 * t + i] = l > 0 ? n[i] / l : 0.0;
    }
    tessel_index *ix = NULL;
    if (tessel_index_build(&ix, cen, nt) != TESSEL_OK)
        return 1;
    size_t unsigned_ok = 0, signed_ok = 0, flipped = 0;
    double cos30 = cos(30.0 * 3.141592653589793 / 180.0);
    ptrdiff_t n = (ptrdiff_t)cloud.count;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : unsigned_ok, signed_ok, flipped)
#endif
    for (ptrdiff_t i = 0; i < n; i++) {
        const float *q = cloud.xyz + 3 * (size_t)i;
        uint32_t cand[CANDIDATES];
        size_t got = tessel_index_knn(ix, q, CANDIDATES, cand, NULL);
        double p[3], best = INFINITY;
        size_t bt = 0;
        for (int a = 0; a < 3; a++)
            p[a] = cloud.offset[a] + (double)q[a];
        for (size_t c = 0; c < got; c++) {
            double va[3], vb[3], vc[3];
            vertex(&ref, ref.triangles[3 * (size_t)cand[c]], va);
            vertex(&ref, ref.triangles[3 * (size_t)cand[c] + 1], vb);
            vertex(&ref, ref.triangles[3 * (size_t)cand[c] + 2], vc);
            double d = closest_on_triangle(p, va, vb, vc);
            if (d < best) {
                best = d;
                bt = cand[c];
            }
        }
        const float *nn = cloud.normals + 3 * (size_t)i;
        double d = nn[0] * tn[3 * bt] + nn[1] * tn[3 * bt + 1] + nn[2] * tn[3 * bt + 2];
        unsigned_ok += fabs(d) >= cos30;
        signed_ok += d >= cos30;
        flipped += d < 0.0;
    }
    const char *base = strrchr(paths[0], '/');
    printf("%-22s %8zu points  k=%u orient=%d  %.3f s  within 30 deg: unsigned %.2f%%  "
           "oriented %.2f%%  wrong side %.2f%%\n",
           base ? base + 1 : paths[0], cloud.count, np.k, np.orient, t_est,
           100.0 * (double)unsigned_ok / (double)cloud.count,
           100.0 * (double)signed_ok / (double)cloud.count,
           100.0 * (double)flipped / (double)cloud.count);
    tessel_index_destroy(ix);
    free(cen);
    free(tn);
    tessel_cloud_free(&cloud);
    tessel_mesh_free(&ref);
    return 0;
}
