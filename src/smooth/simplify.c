/* Data reduction: one representative point per cluster. Mederos, Velho &
 * de Figueiredo, "Smooth surface reconstruction from noisy clouds" (2003),
 * section 2.3: the centroid c of a cluster is not on the surface (the
 * cluster is curved, and noisy), so it is projected onto the clustered cloud
 * with the robust operator Q of section 2.1 (src/smooth/); Q(c) is the
 * representative. Clusters are independent: an OpenMP loop writes one slot
 * per cluster, and the kept slots are compacted in cluster order, so the
 * output does not depend on the thread count. */
#include "smooth/smooth.h"

#include <stdlib.h>
#include <string.h>

/* Clusters per progress report / cancellation check. */
#define SIMPLIFY_CHUNK ((size_t)1 << 15)

tessel_simplify_params tessel_simplify_params_default(void)
{
    tessel_simplify_params p;
    memset(&p, 0, sizeof p);
    p.cluster = tessel_cluster_params_default();
    /* The clustered cloud is normally smooth already: a tighter operator
     * than for smoothing has less bias on curved parts (on the smoothed
     * noisy bunny, representatives 0.28% of the diagonal from the surface
     * with these, 0.32% with the smoothing defaults; bench_smooth). */
    p.projection = tessel_smooth_params_default();
    p.projection.k = 16;
    p.projection.sigma_w = 1.5;
    p.keep_unfit = 0;
    return p;
}

static bool clusters_valid(const tessel_clusters *cl, size_t n)
{
    if (cl->point_count != n || cl->count == 0 || !cl->order || !cl->offsets)
        return false;
    if (cl->offsets[0] != 0 || cl->offsets[cl->count] != n)
        return false;
    for (size_t c = 0; c < cl->count; c++)
        if (cl->offsets[c + 1] <= cl->offsets[c])
            return false;
    for (size_t i = 0; i < n; i++)
        if (cl->order[i] >= n)
            return false;
    return true;
}

/* The arguments of tessel_representatives: the projection parameters to
 * use (spacing from the clusters when not given) in *proj. */
static tessel_status check_args(const tessel_cloud *cloud, const tessel_clusters *clusters,
                                const tessel_simplify_params *params, tessel_cloud *out,
                                tessel_simplify_stats *stats, tessel_smooth_params *proj)
{
    if (!out)
        return TESSEL_ERR_INVALID_ARG;
    memset(out, 0, sizeof *out);
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!cloud || !clusters || (cloud->count > 0 && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;
    if (!clusters_valid(clusters, cloud->count))
        return TESSEL_ERR_INVALID_ARG;
    *proj = params ? params->projection : tessel_simplify_params_default().projection;
    if (proj->spacing == 0.0)
        proj->spacing = clusters->spacing;
    return TESSEL_OK;
}

/* One representative per cluster: its centroid projected by pr (arguments
 * checked by the caller). */
static tessel_status representatives(const tessel_cloud *cloud, const tessel_clusters *clusters,
                                     const tessel_simplify_params *params,
                                     const tessel_smooth_params *proj,
                                     const tessel_projector *pr,
                                     const tessel_callbacks *callbacks, tessel_cloud *out,
                                     tessel_simplify_stats *stats)
{
    tessel_status st = TESSEL_OK;
    tessel_simplify_params p = params ? *params : tessel_simplify_params_default();

    const size_t nc = clusters->count;
    const int with_rgb = cloud->rgb != NULL;
    float *xyz = tsl_alloc_array(nc, 3 * sizeof(float));
    float *nrm = tsl_alloc_array(nc, 3 * sizeof(float));
    uint8_t *rgb = with_rgb ? tsl_alloc_array(nc, 3) : NULL;
    uint8_t *fit = tsl_alloc_array(nc, 1);
    if (!xyz || !nrm || !fit || (with_rgb && !rgb)) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }

    int threads = tsl_threads(proj->threads);
    (void)threads;
    for (size_t lo = 0; lo < nc; lo += SIMPLIFY_CHUNK) {
        st = tsl_progress(callbacks, "representatives", (double)lo / (double)nc);
        if (st != TESSEL_OK)
            goto done;
        size_t hi = lo + SIMPLIFY_CHUNK < nc ? lo + SIMPLIFY_CHUNK : nc;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 64)
        for (size_t c = lo; c < hi; c++) {
            size_t a = clusters->offsets[c], b = clusters->offsets[c + 1];
            double s[3] = {0, 0, 0}, col[3] = {0, 0, 0};
            for (size_t i = a; i < b; i++) {
                size_t id = clusters->order[i];
                const float *q = cloud->xyz + 3 * id;
                s[0] += q[0];
                s[1] += q[1];
                s[2] += q[2];
                if (with_rgb) {
                    col[0] += cloud->rgb[3 * id];
                    col[1] += cloud->rgb[3 * id + 1];
                    col[2] += cloud->rgb[3 * id + 2];
                }
            }
            double m = (double)(b - a);
            float centroid[3] = {(float)(s[0] / m), (float)(s[1] / m), (float)(s[2] / m)};
            fit[c] = tessel_project(pr, centroid, xyz + 3 * c, nrm + 3 * c, NULL) == TESSEL_OK;
            if (with_rgb)
                for (int k = 0; k < 3; k++)
                    rgb[3 * c + k] = (uint8_t)lround(col[k] / m);
        }
    }

    size_t kept = 0, unfit = 0;
    for (size_t c = 0; c < nc; c++) {
        unfit += !fit[c];
        kept += fit[c] || p.keep_unfit;
    }
    st = tessel_cloud_alloc(out, kept, 1, with_rgb);
    if (st != TESSEL_OK)
        goto done;
    size_t j = 0;
    for (size_t c = 0; c < nc; c++) {
        if (!fit[c] && !p.keep_unfit)
            continue;
        memcpy(out->xyz + 3 * j, xyz + 3 * c, 3 * sizeof(float));
        memcpy(out->normals + 3 * j, nrm + 3 * c, 3 * sizeof(float));
        if (with_rgb)
            memcpy(out->rgb + 3 * j, rgb + 3 * c, 3);
        j++;
    }
    memcpy(out->offset, cloud->offset, sizeof out->offset);
    memcpy(out->viewpoint, cloud->viewpoint, sizeof out->viewpoint);
    out->has_viewpoint = cloud->has_viewpoint;
    if (stats) {
        stats->spacing = tessel_projector_spacing(pr);
        stats->clusters = nc;
        stats->representatives = kept;
        stats->unfit = unfit;
    }
    st = tsl_progress(callbacks, "representatives", 1.0);
    if (st != TESSEL_OK) {
        tessel_cloud_free(out);
        if (stats)
            memset(stats, 0, sizeof *stats);
    }

done:
    free(xyz);
    free(nrm);
    free(rgb);
    free(fit);
    return st;
}

tessel_status tessel_representatives(const tessel_cloud *cloud, const tessel_clusters *clusters,
                                     const tessel_simplify_params *params,
                                     const tessel_callbacks *callbacks, tessel_cloud *out,
                                     tessel_simplify_stats *stats)
{
    tessel_smooth_params proj;
    tessel_status st = check_args(cloud, clusters, params, out, stats, &proj);
    if (st != TESSEL_OK)
        return st;
    tessel_projector *pr = NULL;
    if ((st = tessel_projector_create(&pr, cloud, &proj)) == TESSEL_OK)
        st = representatives(cloud, clusters, params, &proj, pr, callbacks, out, stats);
    tessel_projector_destroy(pr);
    return st;
}

tessel_status tsl_representatives_with(const tessel_cloud *cloud,
                                       const tessel_clusters *clusters,
                                       const tessel_simplify_params *params,
                                       const tessel_projector *pr,
                                       const tessel_callbacks *callbacks, tessel_cloud *out,
                                       tessel_simplify_stats *stats)
{
    tessel_smooth_params proj;
    tessel_status st = check_args(cloud, clusters, params, out, stats, &proj);
    if (st != TESSEL_OK)
        return st;
    return representatives(cloud, clusters, params, &proj, pr, callbacks, out, stats);
}

tessel_status tessel_simplify(const tessel_cloud *cloud, tessel_cloud *out,
                              const tessel_simplify_params *params,
                              const tessel_callbacks *callbacks, tessel_simplify_stats *stats)
{
    if (!out)
        return TESSEL_ERR_INVALID_ARG;
    memset(out, 0, sizeof *out);
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!cloud || (cloud->count > 0 && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;
    tessel_simplify_params p = params ? *params : tessel_simplify_params_default();
    /* One spacing estimate serves both stages. */
    if (p.cluster.spacing == 0.0 && p.projection.spacing == 0.0) {
        double h;
        tessel_status st = tessel_cloud_spacing(cloud, &h);
        if (st != TESSEL_OK)
            return st;
        if (!(h > 0.0) || !isfinite(h))
            return TESSEL_ERR_TOO_FEW_POINTS;
        p.cluster.spacing = h;
        p.projection.spacing = h;
    }
    tessel_clusters cl;
    tessel_status st = tessel_cluster(cloud, &p.cluster, callbacks, &cl);
    if (st != TESSEL_OK)
        return st;
    st = tessel_representatives(cloud, &cl, &p, callbacks, out, stats);
    tessel_clusters_free(&cl);
    return st;
}
