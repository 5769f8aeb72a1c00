/* tessel reconstruct IN OUT: surface reconstruction. The default method is
 * the greedy projection of Gopi & Krishnan 2002 (src/greedy/); --mode
 * height|range|grid selects the fixed-plane variant (cmd_reconstruct_fixed)
 * and --method smooth the noisy-cloud pipeline (cmd_reconstruct_smooth).
 * The triangles stream into the mesh writer. See docs/greedy.md. */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

/* Above this share of boundary edges the summary suggests the other
 * methods: clean scans stay under about 2% (the border of an open scan,
 * sheets closer than the sampling), clouds with noise of one spacing reach
 * 7-13%. */
#define HOLE_HINT_FRACTION 0.05

static const char greedy_help[] =
    "usage: tessel reconstruct IN OUT [options]\n\n"
    "Greedy projection reconstruction (Gopi & Krishnan 2002), the default\n"
    "method: a mesh through the input points, grown breadth-first from a seed.\n"
    "Each point joins the neighbours within mu times its nearest distance,\n"
    "ordered by angle on its tangent plane, skipping those hidden by the mesh\n"
    "boundary. Every triangle is checked exactly: the output is manifold,\n"
    "consistently oriented (counter-clockwise seen from outside on closed\n"
    "surfaces) and free of self-intersections. Regions meshed the wrong way\n"
    "round (where two sheets touch, a hand on a thigh; folds of a noisy scan)\n"
    "are then found, by the input normals or viewpoint when the cloud has\n"
    "them, else by rays, and rebuilt. Last, diagonals are flipped where the\n"
    "two angles facing them add up to more than 180 degrees (the Delaunay\n"
    "rule), which removes most slivers.\n"
    "Best on clean, evenly sampled clouds; for noisy ones use --method\n"
    "smooth.\n\n"
    "Other methods:\n"
    "  --method smooth          noisy clouds (see --method smooth --help)\n"
    "  --mode height|range|grid fixed projection plane: terrain, scans from\n"
    "                           one position, organized grids (see --mode\n"
    "                           height --help)\n\n"
    "Options:\n"
    "  --method greedy    this method (the default)\n"
    "  --mu M             sphere of influence: M times the distance to the\n"
    "                     nearest neighbour, 1.2..10 (default 2; 2.5-3 for\n"
    "                     uneven or uniformly random samples, smaller when\n"
    "                     surfaces come close)\n"
    "  --max-angle DEG    neighbours farther apart than DEG around a point are\n"
    "                     not joined (a hole), 60..175 (default 120)\n"
    "  --min-angle DEG    drop neighbours making angles below DEG when that\n"
    "                     traps no point, 0..45 (default 0: off)\n"
    "  --plane pca|axis   projection plane: the tangent estimate (default) or\n"
    "                     the nearest coordinate plane\n"
    "  --max-spacing K    no edge spans more than about 2*mu*K mean spacings;\n"
    "                     points with no neighbour within mu*K are isolated\n"
    "                     (default 4)\n"
    "  --no-flip          keep the triangles as the front makes them (the\n"
    "                     paper's), without the diagonal flips\n"
    "  --stream           write triangles as they are final, without the\n"
    "                     inside-out check and the flips: memory for the\n"
    "                     points and the front only, not the mesh (for the\n"
    "                     largest clouds)\n"
    "  --ascii            write ascii PLY\n\n";

typedef struct greedy_opts {
    tessel_greedy_params p;
    int ascii;
} greedy_opts;

static int greedy_option(void *ctx, int argc, char **argv, int *i)
{
    greedy_opts *o = ctx;
    const char *a = argv[*i];
    if (strcmp(a, "--ascii") == 0)
        return o->ascii = 1;
    if (strcmp(a, "--stream") == 0) {
        o->p.orient_check = 0;
        o->p.flip = 0;
        return 1;
    }
    if (strcmp(a, "--no-flip") == 0) {
        o->p.flip = 0;
        return 1;
    }
    if (strcmp(a, "--mu") && strcmp(a, "--max-angle") && strcmp(a, "--min-angle") &&
        strcmp(a, "--plane") && strcmp(a, "--max-spacing") && strcmp(a, "--method"))
        return 0;
    const char *v = cli_option_value(argc, argv, i);
    if (!v)
        return -1;
    if (strcmp(a, "--method") == 0) {
        if (strcmp(v, "greedy") != 0) {
            cli_error("--method must be greedy or smooth, got '%s'", v);
            return -1;
        }
        return 1;
    }
    if (strcmp(a, "--plane") == 0) {
        if (strcmp(v, "pca") == 0)
            o->p.plane = TESSEL_GREEDY_PLANE_PCA;
        else if (strcmp(v, "axis") == 0)
            o->p.plane = TESSEL_GREEDY_PLANE_AXIS;
        else {
            cli_error("--plane must be pca or axis, got '%s'", v);
            return -1;
        }
        return 1;
    }
    double x;
    if (!cli_parse_double(a, v, &x))
        return -1;
    double lo, hi;
    double *dst;
    if (strcmp(a, "--mu") == 0)
        dst = &o->p.mu, lo = 1.2, hi = 10.0;
    else if (strcmp(a, "--max-angle") == 0)
        dst = &o->p.max_angle, lo = 60.0, hi = 175.0;
    else if (strcmp(a, "--min-angle") == 0)
        dst = &o->p.min_angle, lo = 0.0, hi = 45.0;
    else
        dst = &o->p.max_spacing, lo = 1.0, hi = 1000.0;
    if (!(x >= lo && x <= hi)) {
        cli_error("%s must be between %g and %g, got %s", a, lo, hi, v);
        return -1;
    }
    *dst = x;
    return 1;
}

typedef struct greedy_run {
    const tessel_greedy_params *params;
    tessel_recon_summary summary;
} greedy_run;

static tessel_status run_greedy(const tessel_cloud *cloud, const tessel_callbacks *cb,
                                const tessel_triangle_sink *sink, void *ctx)
{
    greedy_run *r = ctx;
    return tessel_reconstruct_greedy(cloud, r->params, cb, sink, &r->summary);
}

static int greedy(int argc, char **argv)
{
    cli_common common = {0};
    greedy_opts o;
    memset(&o, 0, sizeof o);
    o.p = tessel_greedy_params_default();
    const char *in = NULL, *out = NULL;
    int r = cli_parse_in_out(argc, argv, greedy_help, &common, &in, &out, greedy_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    cli_apply_threads(&common);

    double t0 = cli_now();
    tessel_cloud cloud = {0};
    int rc = cli_read_cloud(in, &cloud, 3, "a surface", &common);
    if (rc != CLI_OK)
        return rc;
    double t_read = cli_now() - t0;
    greedy_run run = {&o.p, {0}};
    double t_write = 0;
    int code = cli_stream_reconstruction(in, out, &cloud, o.ascii, &common, "reconstruction",
                                         run_greedy, &run, &t_write);
    size_t n = cloud.count;
    tessel_cloud_free(&cloud);
    if (code != CLI_OK)
        return code;
    const tessel_recon_summary sum = run.summary;
    double seconds = cli_now() - t0;
    double rate = sum.seconds > 0 ? (double)n / sum.seconds : 0.0;
    if (common.json) {
        printf("{\"method\": \"greedy\", \"points\": %zu, \"points_used\": %zu, "
               "\"left_duplicate\": %zu, \"left_isolated\": %zu, \"left_closed_in\": %zu, "
               "\"left_untriangulated\": %zu, \"triangles\": %zu, \"components\": %zu, "
               "\"boundary_edges\": %zu, \"seeds\": %zu, \"rejected_intersecting\": %zu, "
               "\"peak_held_triangles\": %zu, \"reoriented\": %zu, \"flips\": %zu, "
               "\"spacing\": %.9g, "
               "\"mu\": %g, "
               "\"max_angle\": %g, \"min_angle\": %g, \"plane\": \"%s\", "
               "\"read_seconds\": %.6f, \"reconstruct_seconds\": %.6f, "
               "\"write_seconds\": %.6f, \"seconds\": %.6f, \"points_per_second\": %.0f}\n",
               n, sum.points_used, sum.left_duplicate, sum.left_isolated, sum.left_closed_in,
               sum.left_untriangulated, sum.triangles, sum.components, sum.boundary_edges,
               sum.seeds, sum.rejected_intersecting, sum.peak_held_triangles, sum.reoriented,
               sum.flips, sum.spacing,
               o.p.mu, o.p.max_angle, o.p.min_angle,
               o.p.plane == TESSEL_GREEDY_PLANE_AXIS ? "axis" : "pca", t_read, sum.seconds,
               t_write, seconds, rate);
    } else if (!common.quiet) {
        size_t left = n - sum.points_used;
        fprintf(stderr,
                "tessel: greedy: %zu of %zu points used, %zu triangles, %zu component%s, "
                "%zu boundary edges, %zu diagonals flipped (mu %g, spacing %.4g)\n",
                sum.points_used, n, sum.triangles, sum.components,
                sum.components == 1 ? "" : "s", sum.boundary_edges, sum.flips, o.p.mu,
                sum.spacing);
        if (left)
            fprintf(stderr,
                    "tessel: %zu points left out: %zu duplicates, %zu isolated, %zu enclosed "
                    "by the surface, %zu with no valid triangle\n",
                    left, sum.left_duplicate, sum.left_isolated, sum.left_closed_in,
                    sum.left_untriangulated);
        if (sum.reoriented)
            fprintf(stderr,
                    "tessel: %zu triangles of regions meshed the wrong way round were "
                    "turned and "
                    "their seams meshed again\n",
                    sum.reoriented);
        /* Each edge has two triangle sides, a boundary edge one. */
        double edges = (3.0 * (double)sum.triangles + (double)sum.boundary_edges) / 2.0;
        if (edges > 0.0 && (double)sum.boundary_edges > HOLE_HINT_FRACTION * edges)
            fprintf(stderr,
                    "tessel: hint: %.1f%% of the edges lie on a boundary; greedy projection "
                    "keeps every point, so noise of about the point spacing tears the "
                    "surface\ntessel: hint: for a noisy cloud try --method smooth; for a "
                    "scan from one position, --mode range\n",
                    100.0 * (double)sum.boundary_edges / edges);
        fprintf(stderr,
                "tessel: wrote %s in %.2f s (read %.2f s, reconstruction %.3f s = %.2fM "
                "points/s, write %.2f s)\n",
                out, seconds, t_read, sum.seconds, rate / 1e6, t_write);
    }
    return CLI_OK;
}

int cmd_reconstruct(int argc, char **argv)
{
    /* The method decides which command parses the options. */
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--mode") == 0)
            return cmd_reconstruct_fixed(argc, argv);
        if (strcmp(argv[i], "--method") == 0 && i + 1 < argc &&
            strcmp(argv[i + 1], "smooth") == 0)
            return cmd_reconstruct_smooth(argc, argv);
    }
    return greedy(argc, argv);
}
