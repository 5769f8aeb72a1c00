/* tessel smooth IN OUT: robust smoothing of a noisy cloud (Mederos et al.
 * 2003, section 2.1). tessel simplify IN OUT: BSP clusters and one
 * representative per cluster (sections 2.2-2.3), optionally after
 * smoothing. See docs/smooth.md. */
#include "cli.h"

#include <math.h>
#include <string.h>

static const char smooth_help[] =
    "usage: tessel smooth IN OUT [options]\n\n"
    "Moves every point onto a robust local fit of its neighbours (Mederos,\n"
    "Velho & de Figueiredo 2003, plus a quadric over their robust plane): noise\n"
    "goes, outliers do not pull. OUT gets the smoothed points with the fitted\n"
    "normals. Lengths are multiples of the mean point spacing h, estimated\n"
    "from IN.\n\n"
    "Options:\n"
    "  --passes N          smoothing passes (default 2)\n"
    "  --k N               neighbours per point, 3..256 (default 30)\n"
    "  --sigma-rho X       robust scale in h: heights beyond ~2x count as\n"
    "                      outliers (default 2)\n"
    "  --sigma-rho-later X robust scale of the passes after the first (default 1)\n"
    "  --sigma-w X         Gaussian distance weight scale in h (default 3)\n"
    "  --plane             the paper's plane operator, no quadric\n"
    "  --exclude-self      leave each point out of its own fit, so its own noise\n"
    "                      does not pull the fit: better on noise of about a\n"
    "                      spacing or more, worse on little noise or tight curves\n"
    "  --aggregate         after each pass, average each point's projections onto\n"
    "                      its neighbours' fitted surfaces: more accurate, about\n"
    "                      half again the time; best with --passes 3\n"
    "  --iterations N      iteration cap of each fit (default 20)\n"
    "  --tolerance X       fit convergence, in h and radians (default 1e-2)\n"
    "  --min-neighbors N   fewer neighbours: the point stays (default 6)\n"
    "  --spacing X         use this h (world units) instead of estimating it\n"
    "  --ascii             write ascii PLY\n\n";

static const char simplify_help[] =
    "usage: tessel simplify IN OUT [options]\n\n"
    "Splits the cloud into flat, local clusters (a BSP tree on covariance\n"
    "flatness and a diameter bound) and writes one point per cluster: its\n"
    "centroid projected onto the cloud by the robust smoothing operator\n"
    "(Mederos, Velho & de Figueiredo 2003). Use it on a smoothed cloud, or\n"
    "give --smooth. Lengths are multiples of the mean spacing h.\n\n"
    "Options:\n"
    "  --smooth N          smooth with N passes first (default 0: IN is used as is)\n"
    "  --sigma-max X       flatness tolerance l1/(l1+l2+l3), 0..1/3 (default 0.01)\n"
    "  --n-min N           clusters of at most N points are not split for\n"
    "                      flatness (default 10)\n"
    "  --max-diameter X    largest cluster, in h; 'inf' for none (default 8)\n"
    "  --keep-unfit        keep the centroid of a cluster with no robust fit\n"
    "                      (isolated outliers; dropped by default)\n"
    "  --k N, --sigma-rho X, --sigma-w X\n"
    "                      the projection operator, as in tessel smooth\n"
    "  --spacing X         use this h (world units) instead of estimating it\n"
    "  --ascii             write ascii PLY\n\n";

typedef struct smooth_opts {
    tessel_smooth_params smooth;
    tessel_cluster_params cluster;
    long pre_passes; /* simplify --smooth */
    int keep_unfit;
    int ascii;
    bool simplify;
} smooth_opts;

static int smooth_option(void *ctx, int argc, char **argv, int *i)
{
    smooth_opts *o = ctx;
    const char *a = argv[*i], *v;
    long n;
    double x;
    if (strcmp(a, "--ascii") == 0) {
        o->ascii = 1;
        return 1;
    }
    if (o->simplify && strcmp(a, "--keep-unfit") == 0) {
        o->keep_unfit = 1;
        return 1;
    }
#define INT_OPT(name, lo, hi, dst)                                                             \
    if (strcmp(a, name) == 0) {                                                                \
        if (!(v = cli_option_value(argc, argv, i)) || !cli_parse_int(a, v, lo, hi, &n))                \
            return -1;                                                                         \
        dst = n;                                                                               \
        return 1;                                                                              \
    }
#define POS_OPT(name, dst)                                                                     \
    if (strcmp(a, name) == 0) {                                                                \
        if (!(v = cli_option_value(argc, argv, i)) || !cli_parse_double(a, v, &x))                     \
            return -1;                                                                         \
        if (!(x > 0)) {                                                                        \
            cli_error("%s must be positive, got '%s'", a, v);                                  \
            return -1;                                                                         \
        }                                                                                      \
        dst = x;                                                                               \
        return 1;                                                                              \
    }
    INT_OPT("--k", 3, 256, o->smooth.k)
    POS_OPT("--sigma-rho", o->smooth.sigma_rho)
    POS_OPT("--sigma-w", o->smooth.sigma_w)
    POS_OPT("--spacing", o->smooth.spacing)
    if (!o->simplify) {
        if (strcmp(a, "--plane") == 0) {
            o->smooth.quadric = 0;
            return 1;
        }
        if (strcmp(a, "--aggregate") == 0) {
            o->smooth.aggregate = 1;
            return 1;
        }
        if (strcmp(a, "--exclude-self") == 0) {
            o->smooth.exclude_self = 1;
            return 1;
        }
        POS_OPT("--sigma-rho-later", o->smooth.sigma_rho_later)
        INT_OPT("--passes", 1, 100, o->smooth.passes)
        INT_OPT("--iterations", 1, 1000, o->smooth.max_iterations)
        INT_OPT("--min-neighbors", 3, 256, o->smooth.min_neighbors)
        POS_OPT("--tolerance", o->smooth.tolerance)
        return 0;
    }
    INT_OPT("--smooth", 0, 100, o->pre_passes)
    INT_OPT("--n-min", 1, 1000000, o->cluster.n_min)
    if (strcmp(a, "--sigma-max") == 0) {
        if (!(v = cli_option_value(argc, argv, i)) || !cli_parse_double(a, v, &x))
            return -1;
        if (x < 0 || x > 1.0 / 3.0 + 1e-12) {
            cli_error("--sigma-max must be between 0 and 1/3, got '%s'", v);
            return -1;
        }
        o->cluster.sigma_max = x;
        return 1;
    }
    if (strcmp(a, "--max-diameter") == 0) {
        if (!(v = cli_option_value(argc, argv, i)))
            return -1;
        if (strcmp(v, "inf") == 0) {
            o->cluster.max_diameter = INFINITY;
            return 1;
        }
        if (!cli_parse_double(a, v, &x))
            return -1;
        if (!(x > 0)) {
            cli_error("--max-diameter must be positive or 'inf', got '%s'", v);
            return -1;
        }
        o->cluster.max_diameter = x;
        return 1;
    }
#undef INT_OPT
#undef POS_OPT
    return 0;
}

static int write_output(const char *out, const tessel_cloud *cloud, int ascii)
{
    tessel_write_params wp = tessel_write_params_default();
    wp.ascii = ascii;
    tessel_diag diag = {0};
    tessel_status st = tessel_cloud_write(cloud, out, &wp, &diag);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, out);
        return cli_exit_for_write(st);
    }
    return CLI_OK;
}

static int compute_failed(tessel_status st, const char *what)
{
    if (st == TESSEL_ERR_TOO_FEW_POINTS)
        cli_error("%s: not enough distinct points", what);
    else
        cli_error("%s failed: %s", what, tessel_status_str(st));
    return CLI_FAILURE;
}

int cmd_smooth(int argc, char **argv)
{
    cli_common common = {0};
    smooth_opts o;
    memset(&o, 0, sizeof o);
    o.smooth = tessel_smooth_params_default();
    const char *in = NULL, *out = NULL;
    int r = cli_parse_in_out(argc, argv, smooth_help, &common, &in, &out, smooth_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    if (o.smooth.min_neighbors > o.smooth.k) {
        cli_error("--min-neighbors (%u) cannot exceed --k (%u)", o.smooth.min_neighbors,
                  o.smooth.k);
        return CLI_USAGE;
    }
    cli_apply_threads(&common);
    o.smooth.threads = common.threads;

    double t0 = cli_now();
    tessel_cloud cloud = {0}, smooth = {0};
    int rc = cli_read_cloud(in, &cloud, 3, "smoothing", &common);
    if (rc != CLI_OK)
        return rc;
    cli_progress prog;
    cli_progress_init(&prog, &common);
    tessel_callbacks cb = cli_callbacks(&prog);
    cli_progress_items(&prog, cloud.count * o.smooth.passes);
    tessel_smooth_stats st;
    double t1 = cli_now();
    tessel_status s = tessel_smooth(&cloud, &smooth, &o.smooth, &cb, &st);
    double ts = cli_now() - t1;
    cli_progress_done(&prog);
    if (s != TESSEL_OK) {
        tessel_cloud_free(&cloud);
        return compute_failed(s, "smoothing");
    }
    rc = write_output(out, &smooth, o.ascii);
    size_t n = cloud.count;
    tessel_cloud_free(&cloud);
    tessel_cloud_free(&smooth);
    if (rc != CLI_OK)
        return rc;
    double seconds = cli_now() - t0;
    if (common.json) {
        printf("{\"points\": %zu, \"spacing\": %.9g, \"passes\": %u, \"k\": %u, "
               "\"sigma_rho\": %g, \"sigma_rho_later\": %g, \"sigma_w\": %g, "
               "\"quadric\": %d, \"aggregate\": %d, \"exclude_self\": %d, \"unfit\": %zu, "
               "\"unconverged\": %zu, "
               "\"mean_iterations\": %.3f, \"rms_displacement\": %.9g, "
               "\"max_displacement\": %.9g, \"smooth_seconds\": %.6f, \"seconds\": %.6f}\n",
               n, st.spacing, o.smooth.passes, o.smooth.k, o.smooth.sigma_rho,
               o.smooth.sigma_rho_later, o.smooth.sigma_w, o.smooth.quadric, o.smooth.aggregate,
               o.smooth.exclude_self, st.unfit, st.unconverged, st.mean_iterations, st.rms_displacement, st.max_displacement, ts,
               seconds);
    } else if (!common.quiet) {
        fprintf(stderr,
                "tessel: smoothed %zu points: h = %.6g%s, %u pass%s, k = %u, sigma_rho = %g h "
                "(later passes %g h), sigma_w = %g h, %s%s%s\n"
                "tessel: %zu unfit (left in place), %.2f iterations per fit, points moved "
                "%.3g h RMS, %.3g h at most\n"
                "tessel: wrote %s in %.2f s (smoothing %.2f s, %.2fM points/s)\n",
                n, st.spacing, o.smooth.spacing > 0 ? " (given)" : " (estimated)",
                o.smooth.passes, o.smooth.passes == 1 ? "" : "es", o.smooth.k,
                o.smooth.sigma_rho, o.smooth.sigma_rho_later, o.smooth.sigma_w,
                o.smooth.quadric ? "quadric" : "plane",
                o.smooth.aggregate ? ", aggregated" : "",
                o.smooth.exclude_self ? ", each point out of its own fit" : "", st.unfit,
                st.mean_iterations,
                st.rms_displacement / st.spacing, st.max_displacement / st.spacing, out,
                seconds, ts, ts > 0 ? (double)n / ts / 1e6 : 0.0);
    }
    return CLI_OK;
}

int cmd_simplify(int argc, char **argv)
{
    cli_common common = {0};
    smooth_opts o;
    memset(&o, 0, sizeof o);
    o.simplify = true;
    o.smooth = tessel_smooth_params_default();
    o.cluster = tessel_cluster_params_default();
    const char *in = NULL, *out = NULL;
    int r = cli_parse_in_out(argc, argv, simplify_help, &common, &in, &out, smooth_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    cli_apply_threads(&common);
    o.smooth.threads = common.threads;
    o.cluster.threads = common.threads;

    double t0 = cli_now();
    tessel_cloud cloud = {0}, smooth = {0}, reps = {0};
    int rc = cli_read_cloud(in, &cloud, 3, "simplification", &common);
    if (rc != CLI_OK)
        return rc;
    cli_progress prog;
    cli_progress_init(&prog, &common);
    tessel_callbacks cb = cli_callbacks(&prog);
    tessel_status s = TESSEL_OK;
    /* One spacing for every stage: the input's. */
    double h = o.smooth.spacing;
    if (h == 0) {
        s = tessel_cloud_spacing(&cloud, &h);
        if (s == TESSEL_OK && !(h > 0))
            s = TESSEL_ERR_TOO_FEW_POINTS;
    }
    const tessel_cloud *src = &cloud;
    tessel_smooth_stats sst;
    memset(&sst, 0, sizeof sst);
    if (s == TESSEL_OK && o.pre_passes > 0) {
        tessel_smooth_params sp = o.smooth;
        sp.passes = (uint32_t)o.pre_passes;
        sp.spacing = h;
        cli_progress_items(&prog, cloud.count * sp.passes);
        s = tessel_smooth(&cloud, &smooth, &sp, &cb, &sst);
        src = &smooth;
    }
    tessel_simplify_stats st;
    memset(&st, 0, sizeof st);
    double t1 = cli_now();
    if (s == TESSEL_OK) {
        tessel_simplify_params p = tessel_simplify_params_default();
        p.cluster = o.cluster;
        p.cluster.spacing = h;
        p.projection = o.smooth;
        p.projection.spacing = h;
        p.keep_unfit = o.keep_unfit;
        cli_progress_items(&prog, src->count);
        s = tessel_simplify(src, &reps, &p, &cb, &st);
    }
    double tr = cli_now() - t1;
    cli_progress_done(&prog);
    size_t n = cloud.count;
    tessel_cloud_free(&cloud);
    tessel_cloud_free(&smooth);
    if (s != TESSEL_OK)
        return compute_failed(s, "simplification");
    rc = write_output(out, &reps, o.ascii);
    tessel_cloud_free(&reps);
    if (rc != CLI_OK)
        return rc;
    double seconds = cli_now() - t0;
    if (common.json) {
        printf("{\"points\": %zu, \"spacing\": %.9g, \"smooth_passes\": %ld, "
               "\"clusters\": %zu, \"representatives\": %zu, \"unfit_clusters\": %zu, "
               "\"sigma_max\": %g, \"n_min\": %u, \"max_diameter\": %g, "
               "\"simplify_seconds\": %.6f, \"seconds\": %.6f}\n",
               n, h, o.pre_passes, st.clusters, st.representatives, st.unfit,
               o.cluster.sigma_max, o.cluster.n_min,
               isfinite(o.cluster.max_diameter) ? o.cluster.max_diameter : -1.0, tr, seconds);
    } else if (!common.quiet) {
        fprintf(stderr,
                "tessel: %zu points%s, h = %.6g%s: %zu clusters (sigma_max = %g, n_min = %u, "
                "max diameter = %g h)\n"
                "tessel: wrote %s: %zu representatives (%.1fx fewer; %zu outlier clusters "
                "%s) in %.2f s\n",
                n, o.pre_passes > 0 ? " smoothed" : "", h,
                o.smooth.spacing > 0 ? " (given)" : " (estimated)", st.clusters,
                o.cluster.sigma_max, o.cluster.n_min, o.cluster.max_diameter, out,
                st.representatives, st.representatives ? (double)n / st.representatives : 0.0,
                st.unfit, o.keep_unfit ? "kept" : "dropped", seconds);
    }
    return CLI_OK;
}
