/* The noisy-cloud pipeline of Mederos, Velho & de Figueiredo 2003, "Smooth
 * surface reconstruction from noisy clouds", section 2, in one call:
 * robust smoothing (2.1, src/smooth.c), BSP clustering (2.2, src/cluster.c),
 * one representative per cluster (2.3, src/simplify.c), advancing-front
 * triangulation of the representatives (2.4, src/advancing_front.c) and
 * refinement against the smoothed cloud (2.5, src/refine.c).
 *
 * The spacing h is estimated once and handed to every stage, and the
 * projection operator Q of steps 3 and 5 is the smoothing's own. The
 * representatives' normals are passed to the triangulation only when their
 * sign means something (the input had normals or a viewpoint, which the
 * smoothing orients by); otherwise the triangulation fits its own and
 * closed components are turned outward by their volume. Points no triangle
 * uses are dropped before refinement, and the result's normals are those of
 * the vertices' stars. Each stage is timed, as in the paper's Table 1. */
#include "internal.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Automatic cluster diameter (multiples of h): this many times the RMS
 * displacement of the smoothing (in h), within [MIN, MAX]. Measured on the
 * data sets of the project: clean Poisson-disk samples move by 0.1-0.3 h
 * (curvature) and triangulate best from clusters 3 h wide; samples with
 * noise of the order of h move by about 0.7 h and need 8 h. */
#define AUTO_DIAMETER_PER_NOISE 11.0
#define AUTO_DIAMETER_MIN 3.0
#define AUTO_DIAMETER_MAX 8.0

tessel_smooth_recon_params tessel_smooth_recon_params_default(void)
{
    tessel_smooth_recon_params p;
    memset(&p, 0, sizeof p);
    p.smooth = tessel_smooth_params_default();
    /* One pass, as in the paper (section 4): every pass of the plane-fit
     * operator pulls curved surfaces inward by about sigma_w^2 / R. */
    p.smooth.passes = 1;
    p.simplify = tessel_simplify_params_default();
    p.front = tessel_front_params_default();
    p.refine = tessel_refine_params_default();
    p.auto_cluster_size = 1;
    p.threads = 0;
    return p;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Drops vertices no triangle uses (keeping order). */
static tessel_status compact(tessel_mesh *m)
{
    uint32_t *map = tsl_alloc_array(m->vertex_count ? m->vertex_count : 1, sizeof *map);
    if (!map)
        return TESSEL_ERR_NOMEM;
    for (size_t v = 0; v < m->vertex_count; v++)
        map[v] = TESSEL_NONE;
    for (size_t i = 0; i < 3 * m->triangle_count; i++)
        map[m->triangles[i]] = 0;
    size_t n = 0;
    for (size_t v = 0; v < m->vertex_count; v++) {
        if (map[v] == TESSEL_NONE)
            continue;
        map[v] = (uint32_t)n;
        memmove(m->xyz + 3 * n, m->xyz + 3 * v, 3 * sizeof *m->xyz);
        if (m->normals)
            memmove(m->normals + 3 * n, m->normals + 3 * v, 3 * sizeof *m->normals);
        if (m->rgb)
            memmove(m->rgb + 3 * n, m->rgb + 3 * v, 3);
        n++;
    }
    for (size_t i = 0; i < 3 * m->triangle_count; i++)
        m->triangles[i] = map[m->triangles[i]];
    m->vertex_count = n;
    free(map);
    return TESSEL_OK;
}

/* Unit vertex normals from the area-weighted normals of their stars. */
static tessel_status star_normals(tessel_mesh *m)
{
    if (!m->normals) {
        m->normals = tsl_alloc_array(3 * (m->vertex_count ? m->vertex_count : 1),
                                     sizeof *m->normals);
        if (!m->normals)
            return TESSEL_ERR_NOMEM;
    }
    double *acc = tsl_calloc_array(3 * (m->vertex_count ? m->vertex_count : 1), sizeof *acc);
    if (!acc)
        return TESSEL_ERR_NOMEM;
    for (size_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *v = m->triangles + 3 * t;
        double a[3], b[3], c[3], u[3], w[3], n[3];
        tsl_load(m->xyz + 3 * (size_t)v[0], a);
        tsl_load(m->xyz + 3 * (size_t)v[1], b);
        tsl_load(m->xyz + 3 * (size_t)v[2], c);
        tsl_sub(b, a, u);
        tsl_sub(c, a, w);
        tsl_cross(u, w, n);
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++)
                acc[3 * (size_t)v[i] + k] += n[k];
    }
    for (size_t v = 0; v < m->vertex_count; v++) {
        double *n = acc + 3 * v;
        if (!tsl_normalize(n)) {
            n[0] = n[1] = 0.0;
            n[2] = 1.0;
        }
        for (int k = 0; k < 3; k++)
            m->normals[3 * v + k] = (float)n[k];
    }
    free(acc);
    return TESSEL_OK;
}

tessel_status tessel_reconstruct_smooth(const tessel_cloud *cloud,
                                        const tessel_smooth_recon_params *params,
                                        const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                        tessel_smooth_recon_stats *stats)
{
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!cloud || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_smooth_recon_params p = params ? *params : tessel_smooth_recon_params_default();
    if (p.threads) {
        p.smooth.threads = p.simplify.cluster.threads = p.simplify.projection.threads =
            p.front.threads = p.refine.threads = p.threads;
    }
    tessel_smooth_recon_stats s;
    memset(&s, 0, sizeof s);
    s.points = cloud->count;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;

    tessel_cloud smoothed = {0}, reps = {0};
    tessel_projector *projector = NULL;
    tessel_status st;
    double t_all = now(), t = t_all;

    /* h once for every stage. */
    double h = p.smooth.spacing;
    if (!(h > 0.0)) {
        if ((st = tessel_cloud_spacing(cloud, &h)))
            goto fail;
        if (!(h > 0.0)) {
            st = TESSEL_ERR_TOO_FEW_POINTS; /* every point at one place */
            goto fail;
        }
    }
    s.spacing = h;
    p.smooth.spacing = h;
    if (!(p.simplify.cluster.spacing > 0.0))
        p.simplify.cluster.spacing = h;
    if (!(p.simplify.projection.spacing > 0.0))
        p.simplify.projection.spacing = h;
    s.seconds_spacing = now() - t;

    t = now();
    if ((st = tessel_smooth(cloud, &smoothed, &p.smooth, callbacks, &s.smooth)))
        goto fail;
    s.seconds_smooth = now() - t;

    /* Representatives far enough apart for the noise left (see the
     * params): on clean input small clusters follow thin parts; on noisy
     * input closer representatives would make the triangulation trip over
     * their residual noise. */
    if (p.auto_cluster_size) {
        double noise = s.smooth.rms_displacement / h;
        double d = AUTO_DIAMETER_PER_NOISE * noise;
        p.simplify.cluster.max_diameter = d < AUTO_DIAMETER_MIN   ? AUTO_DIAMETER_MIN
                                          : d > AUTO_DIAMETER_MAX ? AUTO_DIAMETER_MAX
                                                                  : d;
    }
    s.cluster_diameter = p.simplify.cluster.max_diameter;

    t = now();
    if ((st = tessel_simplify(&smoothed, &reps, &p.simplify, callbacks, &s.simplify)))
        goto fail;
    s.seconds_simplify = now() - t;
    s.representatives = reps.count;
    if (reps.count < 3) {
        st = TESSEL_ERR_TOO_FEW_POINTS;
        goto fail;
    }
    /* Normals whose sign is arbitrary would orient open components at
     * random: then they serve only as second normal lines of the
     * triangulation's normal cone (next to the planes it fits to the
     * representatives, which are poor at tips and narrow parts). */
    float *lines = NULL;
    if (!cloud->normals && !cloud->has_viewpoint) {
        lines = reps.normals;
        reps.normals = NULL;
    }

    t = now();
    st = tsl_advancing_front_lines(&reps, lines, &p.front, callbacks, mesh, &s.front);
    free(lines);
    if (st)
        goto fail;
    if ((st = compact(mesh)))
        goto fail;
    s.seconds_front = now() - t;

    t = now();
    if (p.refine.rounds > 0) {
        tessel_smooth_params q = p.smooth;
        q.spacing = h;
        if ((st = tessel_projector_create(&projector, &smoothed, &q)) ||
            (st = tessel_refine(mesh, &smoothed, projector, &p.refine, callbacks, &s.refine)))
            goto fail;
    }
    if ((st = star_normals(mesh)))
        goto fail;
    s.seconds_refine = now() - t;

    s.vertices = mesh->vertex_count;
    s.triangles = mesh->triangle_count;
    /* Refinement splits border edges too. */
    s.border_edges = p.refine.rounds > 0 ? s.refine.border_edges : s.front.border_edges;
    s.seconds_total = now() - t_all;
    tessel_projector_destroy(projector);
    tessel_cloud_free(&smoothed);
    tessel_cloud_free(&reps);
    if (stats)
        *stats = s;
    return TESSEL_OK;
fail:
    tessel_projector_destroy(projector);
    tessel_cloud_free(&smoothed);
    tessel_cloud_free(&reps);
    tessel_mesh_free(mesh);
    if (stats)
        *stats = s;
    return st;
}
