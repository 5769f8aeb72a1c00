/* tessel reconstruct IN OUT --method smooth: the noisy-cloud pipeline of
 * Mederos, Velho & de Figueiredo 2003 (smooth, cluster, reduce, advancing
 * front, refine) through tessel_reconstruct_smooth(). argv[0] is
 * "reconstruct". See docs/advancing_front.md. */
#include "cli.h"

#include <math.h>
#include <string.h>

/* Help with the library's current defaults filled in. */
static const char smooth_recon_help_fmt[] =
    "usage: tessel reconstruct IN OUT --method smooth [options]\n\n"
    "Surface from a noisy cloud, no normals needed (Mederos, Velho & de\n"
    "Figueiredo 2003): robust smoothing, clusters and one representative\n"
    "each, an advancing-front triangulation of the representatives, then\n"
    "refinement of the edges far from the smoothed cloud. The mesh is\n"
    "manifold, consistently oriented (outward when closed) and free of\n"
    "self-intersections; its vertices are new points, not input points.\n"
    "Lengths are multiples of the mean point spacing h, estimated from IN.\n\n"
    "Options:\n"
    "  --refine N          refinement rounds, 0..20 (default %u)\n"
    "  --passes N          smoothing passes (default %u)\n"
    "  --k N               neighbours of the smoothing fit (also the\n"
    "                      refinement's projection), 3..256 (default %u)\n"
    "  --sigma-rho X       robust scale of that fit in h (default %g)\n"
    "  --sigma-w X         distance weight scale of that fit in h (default %g)\n"
    "  --sigma-max X       cluster flatness tolerance, 0..1/3 (default %g)\n"
    "  --n-min N           clusters of at most N points are not split for\n"
    "                      flatness (default %u)\n"
    "  --max-diameter X    largest cluster in h (default: from the noise, 3..8)\n"
    "  --max-edge X        eps1: new edges shorter than X times the local\n"
    "                      spacing of the representatives (default %g)\n"
    "  --theta DEG         first dihedral tolerance (default %g)\n"
    "  --theta-step DEG    its widening step eps2 (default %g)\n"
    "  --phi DEG           largest angle at an edge's ends (default %g)\n"
    "  --normal-angle DEG  largest angle of a triangle to its vertices'\n"
    "                      normals (default %g)\n"
    "  --max-hole X        close holes up to X spacings of the representatives\n"
    "                      wide (area over half perimeter; default %g; 0: none)\n"
    "  --tile-points N     triangulate more representatives than N in tiles of\n"
    "                      at most N, in parallel, then close the seams; the\n"
    "                      result depends on N, not on --threads (default %zu;\n"
    "                      0: one front; else at least 256)\n"
    "  --eps X             refine edges farther than X h from the cloud\n"
    "                      (default %g)\n"
    "  --min-edge X        do not split edges shorter than X h (default %g)\n"
    "  --no-flip           refinement without diagonal flips\n"
    "  --spacing X         use this h (world units) instead of estimating it\n"
    "  --max-noise X       noise above X surface spacings (the cloud's own\n"
    "                      estimate) thins the cloud until it is X, each kept\n"
    "                      point fitted to its neighbours in the whole cloud:\n"
    "                      detail finer than the noise cannot be recovered,\n"
    "                      and the fit averages the dropped points' noise away\n"
    "                      (default %g; 0: never thin)\n"
    "  --method smooth     this method\n"
    "  --ascii             write ascii PLY\n\n";

static void format_help(char *buf, size_t size)
{
    tessel_smooth_recon_params d = tessel_smooth_recon_params_default();
    snprintf(buf, size, smooth_recon_help_fmt, d.refine.rounds, d.smooth.passes, d.smooth.k,
             d.smooth.sigma_rho, d.smooth.sigma_w, d.simplify.cluster.sigma_max,
             d.simplify.cluster.n_min, d.front.max_edge_ratio, d.front.theta_deg,
             d.front.theta_step_deg, d.front.max_angle_deg, d.front.normal_angle_deg, d.front.max_hole_radius,
             d.front.tile_points, d.refine.min_offset, d.refine.min_edge_length,
             d.noise_ratio_max);
}

typedef struct smooth_recon_opts {
    tessel_smooth_recon_params p;
    int ascii;
} smooth_recon_opts;

/* Integer options: name, range, destination. */
static bool int_option(const char *a, const char *v, smooth_recon_opts *o)
{
    static const struct {
        const char *name;
        long lo, hi;
    } ints[] = {{"--refine", 0, 20}, {"--passes", 1, 100}, {"--k", 3, 256},
                {"--n-min", 1, 1000000}, {"--tile-points", 0, 1L << 30}};
    for (size_t k = 0; k < sizeof ints / sizeof ints[0]; k++) {
        if (strcmp(a, ints[k].name) != 0)
            continue;
        long x;
        if (!cli_parse_int(a, v, ints[k].lo, ints[k].hi, &x))
            return false;
        switch (k) {
        case 0:
            o->p.refine.rounds = (uint32_t)x;
            break;
        case 1:
            o->p.smooth.passes = (uint32_t)x;
            break;
        case 2:
            o->p.smooth.k = (uint32_t)x;
            break;
        case 3:
            o->p.simplify.cluster.n_min = (uint32_t)x;
            break;
        default:
            if (x > 0 && x < 256) {
                cli_error("%s: %s is out of range (0, or 256 and more)", a, v);
                return false;
            }
            o->p.front.tile_points = (size_t)x;
            break;
        }
        return true;
    }
    return false;
}

static int smooth_recon_option(void *ctx, int argc, char **argv, int *i)
{
    smooth_recon_opts *o = ctx;
    const char *a = argv[*i], *v;
    if (strcmp(a, "--method") == 0) {
        if (!(v = cli_option_value(argc, argv, i)))
            return -1;
        if (strcmp(v, "smooth") != 0 && strcmp(v, "auto") != 0) {
            cli_error("--method %s is not this method's (smooth)", v);
            return -1;
        }
        return 1;
    }
    if (strcmp(a, "--ascii") == 0) {
        o->ascii = 1;
        return 1;
    }
    if (strcmp(a, "--no-flip") == 0) {
        o->p.refine.flip = 0;
        return 1;
    }
    static const char *const ints[] = {"--refine", "--passes", "--k", "--n-min", "--tile-points"};
    for (size_t k = 0; k < sizeof ints / sizeof ints[0]; k++)
        if (strcmp(a, ints[k]) == 0) {
            if (!(v = cli_option_value(argc, argv, i)))
                return -1;
            return int_option(a, v, o) ? 1 : -1;
        }
    static const char *const reals[] = {"--sigma-rho", "--sigma-w",   "--sigma-max",
                                        "--max-diameter", "--max-edge", "--theta",
                                        "--theta-step", "--phi",       "--normal-angle",
                                        "--eps",       "--min-edge",   "--max-hole",
                                        "--spacing",   "--max-noise"};
    for (size_t k = 0; k < sizeof reals / sizeof reals[0]; k++) {
        if (strcmp(a, reals[k]) != 0)
            continue;
        double x;
        if (!(v = cli_option_value(argc, argv, i)) || !cli_parse_double(a, v, &x))
            return -1;
        bool ok;
        switch (k) {
        case 0:
            ok = x > 0;
            o->p.smooth.sigma_rho = x;
            break;
        case 1:
            ok = x > 0;
            o->p.smooth.sigma_w = x;
            break;
        case 2:
            ok = x >= 0 && x <= 1.0 / 3.0;
            o->p.simplify.cluster.sigma_max = x;
            break;
        case 3:
            ok = x > 0;
            o->p.simplify.cluster.max_diameter = x;
            o->p.auto_cluster_size = 0;
            break;
        case 4:
            ok = x > 1;
            o->p.front.max_edge_ratio = x;
            break;
        case 5:
            ok = x >= 0 && x <= 90;
            o->p.front.theta_deg = x;
            break;
        case 6:
            ok = x > 0 && x <= 90;
            o->p.front.theta_step_deg = x;
            break;
        case 7:
            ok = x >= 60 && x <= 180;
            o->p.front.max_angle_deg = x;
            break;
        case 8:
            ok = x > 0 && x <= 180;
            o->p.front.normal_angle_deg = x;
            break;
        case 9:
            ok = x >= 0;
            o->p.refine.min_offset = x;
            break;
        case 10:
            ok = x >= 0;
            o->p.refine.min_edge_length = x;
            break;
        case 11:
            ok = x >= 0;
            o->p.front.max_hole_radius = x;
            break;
        case 12:
            ok = x > 0;
            o->p.smooth.spacing = x;
            break;
        default:
            ok = x >= 0;
            o->p.noise_ratio_max = x;
            break;
        }
        if (!ok) {
            cli_error("%s: %s is out of range (see tessel reconstruct --method smooth --help)",
                      a, v);
            return -1;
        }
        return 1;
    }
    return 0;
}

int cmd_reconstruct_smooth(int argc, char **argv)
{
    return cli_reconstruct_smooth_with(argc, argv, NULL);
}

int cli_reconstruct_smooth_with(int argc, char **argv, const cli_smooth_hooks *hooks)
{
    cli_common common = {0};
    smooth_recon_opts o;
    memset(&o, 0, sizeof o);
    o.p = tessel_smooth_recon_params_default();
    const char *in = NULL, *out = NULL;
    char help[4096];
    format_help(help, sizeof help);
    int r = cli_parse_in_out(argc, argv, help, &common, &in, &out, smooth_recon_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    cli_apply_threads(&common);
    o.p.threads = common.threads;

    double t0 = cli_now();
    tessel_cloud cloud = {0};
    int rc = hooks ? hooks->read(hooks->ctx, in, &cloud, "the smooth method", &common)
                   : cli_read_cloud(in, &cloud, 3, "the smooth method", &common);
    if (rc != CLI_OK)
        return rc;
    double t_read = cli_now() - t0;
    /* Measured once: the choice of the method did it on this cloud. */
    cli_chosen_noise(&o.p.noise, &o.p.noise_ratio);

    cli_progress prog;
    cli_progress_init(&prog, &common);
    tessel_callbacks cb = cli_callbacks(&prog);
    cli_progress_items(&prog, cloud.count);
    tessel_mesh mesh;
    tessel_smooth_recon_stats s;
    tessel_status st = hooks ? hooks->reconstruct(hooks->ctx, &cloud, &o.p, &cb, &mesh, &s)
                             : tessel_reconstruct_smooth(&cloud, &o.p, &cb, &mesh, &s);
    cli_progress_done(&prog);
    size_t n = cloud.count;
    tessel_cloud_free(&cloud);
    if (hooks && hooks->worker) {
        tessel_mesh_free(&mesh);
        return st == TESSEL_OK ? CLI_OK : CLI_FAILURE;
    }
    if (st != TESSEL_OK) {
        if (st == TESSEL_ERR_TOO_FEW_POINTS)
            cli_error("%s: too few distinct points left to triangulate (%zu representatives)",
                      in, s.representatives);
        else
            cli_error("%s: smooth reconstruction failed: %s", in, tessel_status_str(st));
        return CLI_FAILURE;
    }
    double t1 = cli_now();
    tessel_write_params wp = tessel_write_params_default();
    wp.ascii = o.ascii;
    tessel_diag diag = {0};
    st = tessel_mesh_write(&mesh, out, &wp, &diag);
    double t_write = cli_now() - t1;
    tessel_mesh_free(&mesh);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, out);
        return cli_exit_for_write(st);
    }
    double seconds = cli_now() - t0;
    if (common.json) {
        printf("{\"method\": \"smooth\", \"points\": %zu, \"noise\": %.9g, "
               "\"noise_ratio\": %.4g, \"points_used\": %zu, \"fitted\": %s, "
               "\"spacing\": %.9g, \"cluster_diameter\": %.4g, "
               "\"representatives\": %zu, \"vertices\": %zu, \"triangles\": %zu, "
               "\"border_edges\": %zu, \"seeds\": %zu, \"bridges\": %zu, "
               "\"hole_triangles\": %zu, \"reoriented\": %zu, \"splits\": %zu, "
               "\"flips\": %zu, "
               "\"read_seconds\": %.6f, \"noise_seconds\": %.6f, \"spacing_seconds\": %.6f, "
               "\"smooth_seconds\": %.6f, "
               "\"simplify_seconds\": %.6f, \"front_seconds\": %.6f, "
               "\"refine_seconds\": %.6f, \"reconstruct_seconds\": %.6f, "
               "\"write_seconds\": %.6f, \"seconds\": %.6f, \"peak_mib\": %.1f",
               n, s.noise, s.noise_ratio, s.points_used, s.fitted ? "true" : "false", s.spacing,
               s.cluster_diameter,
               s.representatives, s.vertices, s.triangles,
               s.border_edges,
               s.front.seeds, s.front.bridges, s.front.hole_triangles, s.reoriented,
               s.refine.splits,
               s.refine.flips, t_read, s.seconds_noise, s.seconds_spacing, s.seconds_smooth,
               s.seconds_simplify, s.seconds_front, s.seconds_refine, s.seconds_total,
               t_write, seconds, cli_peak_mib());
        cli_chosen_json_end();
    } else if (!common.quiet) {
        cli_chosen_text();
        if (s.points_used < n)
            fprintf(stderr,
                    "tessel: noise %.4g = %.2f surface spacings: thinned to %zu points "
                    "(%.2f spacings%s; detail finer than the noise is not recoverable)\n",
                    s.noise, s.noise_ratio, s.points_used, o.p.noise_ratio_max,
                    s.fitted ? ", each fitted to its neighbours in the whole cloud" : "");
        else if (s.noise > 0.0)
            fprintf(stderr, "tessel: noise %.4g = %.2f surface spacings\n", s.noise,
                    s.noise_ratio);
        fprintf(stderr,
                "tessel: smooth method: %zu points, spacing h = %.4g; %zu representatives "
                "(clusters up to %.3g h); %zu triangles on them (%zu fronts, %zu hole "
                "triangles, %zu border edges)\n",
                s.points_used, s.spacing, s.representatives, s.cluster_diameter,
                s.front.triangles,
                s.front.seeds,
                s.front.hole_triangles, s.front.border_edges);
        if (s.reoriented)
            fprintf(stderr,
                    "tessel: %zu triangles turned outward (regions meshed inside out where "
                    "two sheets touch)\n",
                    s.reoriented);
        fprintf(stderr,
                "tessel: %u refinement rounds: %zu splits, %zu flips -> %zu vertices, %zu "
                "triangles, %zu border edges\n",
                o.p.refine.rounds, s.refine.splits, s.refine.flips, s.vertices, s.triangles,
                s.border_edges);
        fprintf(stderr,
                "tessel: wrote %s in %.2f s (read %.2f, smooth %.2f, cluster+reduce %.2f, "
                "triangulate %.2f, refine %.2f, write %.2f; %.2fM points/s; peak memory %.0f "
                "MiB)\n",
                out, seconds, t_read, s.seconds_smooth, s.seconds_simplify, s.seconds_front,
                s.seconds_refine, t_write,
                s.seconds_total > 0 ? (double)n / s.seconds_total / 1e6 : 0.0, cli_peak_mib());
    }
    return CLI_OK;
}
