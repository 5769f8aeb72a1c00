/* One entry point for every method: tessel_reconstruct runs the method the
 * caller names, or picks one from the cloud (tessel_choose_method):
 *  - an organized scan with its viewpoint (a range or depth camera, a
 *    terrestrial scanner's grid): the fixed-plane range mode (Gopi &
 *    Krishnan 2002, section 5), which meshes along the scanner's rays;
 *  - else the noise is measured (tessel_cloud_noise): below clean_below
 *    surface spacings greedy projection, which interpolates the points
 *    (Gopi & Krishnan 2002); above, the smooth method (Mederos, Velho & de
 *    Figueiredo 2003), which approximates them. */
#include "core/core.h"

#include <string.h>

/* Noise (surface spacings) below which a cloud counts as clean. Measured
 * with bench/noise_grid.sh: greedy on samples with noise of 0.34-0.42
 * surface spacings left 12-28 components where the smooth method left one
 * (F-score 100 both); the clean samples measure 0.01-0.09, scanned meshes'
 * vertices 0.05 (bunny) to 0.28 (man). */
#define CLEAN_BELOW 0.3

tessel_reconstruct_params tessel_reconstruct_params_default(void)
{
    tessel_reconstruct_params p;
    memset(&p, 0, sizeof p);
    p.method = TESSEL_METHOD_AUTO;
    p.clean_below = CLEAN_BELOW;
    p.greedy = tessel_greedy_params_default();
    p.smooth = tessel_smooth_recon_params_default();
    p.fixed = tessel_fixed_plane_params_default();
    p.fixed.mode = TESSEL_FIXED_PLANE_RANGE;
    p.denoise = 1;
    p.threads = 0;
    return p;
}

const char *tessel_method_name(tessel_method method)
{
    switch (method) {
    case TESSEL_METHOD_AUTO:
        return "auto";
    case TESSEL_METHOD_GREEDY:
        return "greedy";
    case TESSEL_METHOD_SMOOTH:
        return "smooth";
    case TESSEL_METHOD_FIXED_PLANE:
        return "fixed-plane";
    }
    return "unknown";
}

tessel_status tessel_choose_method(const tessel_cloud *cloud, const tessel_reconstruct_params *params,
                                   tessel_method_choice *choice)
{
    if (!cloud || !choice || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_reconstruct_params p = params ? *params : tessel_reconstruct_params_default();
    memset(choice, 0, sizeof *choice);
    if (p.method != TESSEL_METHOD_AUTO) {
        choice->method = p.method;
        choice->reason = "asked for";
        return TESSEL_OK;
    }
    if (cloud->grid && cloud->has_viewpoint) {
        choice->method = TESSEL_METHOD_FIXED_PLANE;
        choice->mode = TESSEL_FIXED_PLANE_RANGE;
        choice->reason = "an organized scan with its viewpoint: meshed along the rays";
        return TESSEL_OK;
    }
    double t0 = tsl_seconds();
    tessel_noise_estimate e;
    tessel_status st = tessel_cloud_noise(cloud, p.threads, &e);
    choice->seconds = tsl_seconds() - t0;
    if (st == TESSEL_ERR_TOO_FEW_POINTS) {
        /* Too few points, or parts too thin, to tell: the points as they
         * are. */
        choice->method = TESSEL_METHOD_GREEDY;
        choice->reason = "noise not measurable: the points as they are";
        return TESSEL_OK;
    }
    if (st)
        return st;
    choice->noise = e.sigma;
    choice->noise_ratio = e.noise_ratio;
    choice->measured = 1;
    if (e.noise_ratio < p.clean_below) {
        choice->method = TESSEL_METHOD_GREEDY;
        choice->reason = "clean: the surface through the points";
    } else {
        choice->method = TESSEL_METHOD_SMOOTH;
        choice->reason = "noisy: a smooth surface near the points";
    }
    return TESSEL_OK;
}

/* The range and grid modes on a noisy scan: on a copy denoised along its
 * rays, the joins keeping the reach of the scan's noise. */
static tessel_status fixed_plane(const tessel_cloud *cloud, tessel_reconstruct_params *p,
                                 const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                 tessel_reconstruct_summary *s)
{
    tessel_noise_estimate e;
    bool rays = p->fixed.mode != TESSEL_FIXED_PLANE_HEIGHT &&
                (p->fixed.use_viewpoint || cloud->has_viewpoint);
    if (!p->denoise || !rays || tessel_cloud_noise(cloud, p->threads, &e) != TESSEL_OK ||
        e.noise_ratio < p->clean_below)
        return tessel_reconstruct_fixed_plane_mesh(cloud, &p->fixed, callbacks, mesh, &s->fixed);
    tessel_cloud copy;
    tessel_status st = tessel_cloud_copy(&copy, cloud);
    if (st)
        return st;
    tessel_ray_denoise_params dp = tessel_ray_denoise_params_default();
    dp.noise = e.sigma;
    dp.threads = p->threads;
    if (p->fixed.use_viewpoint) {
        dp.use_viewpoint = 1;
        memcpy(dp.viewpoint, p->fixed.viewpoint, sizeof dp.viewpoint);
    }
    if ((st = tessel_denoise_along_rays(&copy, &dp, &s->denoise)) == TESSEL_OK) {
        s->denoised = 1;
        if (!(p->fixed.noise > 0.0))
            p->fixed.noise = e.sigma;
        st = tessel_reconstruct_fixed_plane_mesh(&copy, &p->fixed, callbacks, mesh, &s->fixed);
    }
    tessel_cloud_free(&copy);
    return st;
}

tessel_status tessel_reconstruct(const tessel_cloud *cloud, const tessel_reconstruct_params *params,
                                 const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                 tessel_reconstruct_summary *summary)
{
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    if (summary)
        memset(summary, 0, sizeof *summary);
    tessel_reconstruct_params p = params ? *params : tessel_reconstruct_params_default();
    if (p.threads)
        p.smooth.threads = p.fixed.threads = p.threads;
    double t0 = tsl_seconds();
    tessel_reconstruct_summary s;
    memset(&s, 0, sizeof s);
    tessel_status st = tessel_choose_method(cloud, &p, &s.choice);
    if (st)
        return st;
    switch (s.choice.method) {
    case TESSEL_METHOD_GREEDY:
        st = tessel_reconstruct_greedy_mesh(cloud, &p.greedy, callbacks, mesh, &s.greedy);
        s.boundary_edges = s.greedy.boundary_edges;
        s.components = s.greedy.components;
        break;
    case TESSEL_METHOD_FIXED_PLANE:
        if (p.method == TESSEL_METHOD_AUTO)
            p.fixed.mode = s.choice.mode;
        s.choice.mode = p.fixed.mode;
        st = fixed_plane(cloud, &p, callbacks, mesh, &s);
        break;
    case TESSEL_METHOD_SMOOTH:
        if (s.choice.measured && !(p.smooth.noise > 0.0)) {
            p.smooth.noise = s.choice.noise;
            p.smooth.noise_ratio = s.choice.noise_ratio;
        }
        st = tessel_reconstruct_smooth(cloud, &p.smooth, callbacks, mesh, &s.smooth);
        s.boundary_edges = s.smooth.border_edges;
        break;
    default:
        st = TESSEL_ERR_INVALID_ARG;
    }
    s.vertices = mesh->vertex_count;
    s.triangles = mesh->triangle_count;
    s.seconds = tsl_seconds() - t0;
    if (summary)
        *summary = s;
    return st;
}
