/* tessel reconstruct IN OUT: surface reconstruction. --method auto (the
 * default) chooses from the cloud (tessel_choose_method) and hands the
 * cloud it read to the method's command: greedy projection (here; Gopi &
 * Krishnan 2002, src/greedy/, the triangles streamed into the mesh
 * writer), the noisy-cloud pipeline (cmd_reconstruct_smooth) or the range
 * mode (cmd_reconstruct_fixed). See docs/greedy.md. */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

/* Above this share of boundary edges the summary suggests the other
 * methods: clean scans stay under about 2% (the border of an open scan,
 * sheets closer than the sampling), clouds with noise of one spacing reach
 * 7-13%. */
#define HOLE_HINT_FRACTION 0.05

static const char greedy_help[] =
    "usage: tessel reconstruct IN OUT --method greedy [options]\n\n"
    "Greedy projection reconstruction (Gopi & Krishnan 2002), the method auto\n"
    "picks for clean clouds: a mesh through the input points, grown\n"
    "breadth-first from a seed.\n"
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
    "  --method greedy    this method\n"
    "  --mu M             sphere of influence: M times the distance to the\n"
    "                     nearest neighbour, 1.2..10 (default: from the\n"
    "                     sampling, 2 on even samples up to 3 on uniformly\n"
    "                     random ones; smaller when surfaces come close)\n"
    "  --max-angle DEG    neighbours farther apart than DEG around a point are\n"
    "                     not joined (a hole), 60..175 (default 120)\n"
    "  --min-angle DEG    drop neighbours making angles below DEG when that\n"
    "                     traps no point, 0..45 (default 0: off; the fans\n"
    "                     are Delaunay already, so it seldom helps)\n"
    "  --plane pca|axis   projection plane: the tangent estimate (default) or\n"
    "                     the nearest coordinate plane\n"
    "  --max-spacing K    no edge spans more than about 2*mu*K mean spacings;\n"
    "                     points with no neighbour within mu*K are isolated\n"
    "                     (default 4)\n"
    "  --no-flip          keep the triangles as the front makes them (the\n"
    "                     paper's), without the diagonal flips\n"
    "  --tile-points N    above N points the front runs in tiles of at most N\n"
    "                     points, in parallel, and closes the seams after;\n"
    "                     the mesh depends on N, not on --threads (default\n"
    "                     262144; 0: one front)\n"
    "  --stream           write triangles as they are final, without the\n"
    "                     inside-out check and the flips: memory for the\n"
    "                     points and the front only, not the mesh (for the\n"
    "                     largest clouds)\n"
    "  --memory SIZE      memory to mesh within (2G, 500M; default half the\n"
    "                     machine's): a cloud whose file would need more in\n"
    "                     core is meshed out of core, in slabs along its\n"
    "                     longest axis through scratch files (no inside-out\n"
    "                     check; see docs/outofcore.md)\n"
    "  --scratch DIR      folder for the scratch files (default: the output's);\n"
    "                     they are removed on success, failure and Ctrl-C\n"
    "  --ascii            write ascii PLY\n\n";

int cli_greedy_option(void *ctx, int argc, char **argv, int *i)
{
    cli_greedy_opts *o = ctx;
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
        strcmp(a, "--plane") && strcmp(a, "--max-spacing") && strcmp(a, "--method") &&
        strcmp(a, "--tile-points") && strcmp(a, "--memory") && strcmp(a, "--scratch"))
        return 0;
    const char *v = cli_option_value(argc, argv, i);
    if (!v)
        return -1;
    if (strcmp(a, "--memory") == 0)
        return cli_parse_size(a, v, &o->ooc.memory) ? 1 : -1;
    if (strcmp(a, "--scratch") == 0) {
        o->ooc.scratch = v;
        return 1;
    }
    if (strcmp(a, "--tile-points") == 0) {
        long n;
        if (!cli_parse_int(a, v, 0, 1L << 30, &n))
            return -1;
        o->p.tile_points = (size_t)n;
        return 1;
    }
    if (strcmp(a, "--method") == 0) {
        if (strcmp(v, "greedy") != 0 && strcmp(v, "auto") != 0) {
            cli_error("--method must be auto, greedy or smooth, got '%s'", v);
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
        dst = &o->p.mu, lo = 1.2, hi = 10.0, o->p.mu_from_sampling = 0;
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
    cli_greedy_opts o;
    memset(&o, 0, sizeof o);
    o.p = tessel_greedy_params_default();
    o.ooc = tessel_outofcore_params_default();
    const char *in = NULL, *out = NULL;
    int r = cli_parse_in_out(argc, argv, greedy_help, &common, &in, &out, cli_greedy_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    cli_apply_threads(&common);
    if (cli_outofcore_wanted(in, &o))
        return cli_reconstruct_outofcore(in, out, &o, &common, tessel_reconstruct_greedy_file);

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
               "\"write_seconds\": %.6f, \"seconds\": %.6f, \"points_per_second\": %.0f, "
               "\"tiles\": %zu, \"peak_mib\": %.1f",
               n, sum.points_used, sum.left_duplicate, sum.left_isolated, sum.left_closed_in,
               sum.left_untriangulated, sum.triangles, sum.components, sum.boundary_edges,
               sum.seeds, sum.rejected_intersecting, sum.peak_held_triangles, sum.reoriented,
               sum.flips, sum.spacing,
               sum.mu, o.p.max_angle, o.p.min_angle,
               o.p.plane == TESSEL_GREEDY_PLANE_AXIS ? "axis" : "pca", t_read, sum.seconds,
               t_write, seconds, rate, sum.tiles, cli_peak_mib());
        cli_chosen_json_end();
    } else if (!common.quiet) {
        cli_chosen_text();
        size_t left = n - sum.points_used;
        fprintf(stderr,
                "tessel: greedy: %zu of %zu points used, %zu triangles, %zu component%s, "
                "%zu boundary edges, %zu diagonals flipped (mu %g, spacing %.4g)\n",
                sum.points_used, n, sum.triangles, sum.components,
                sum.components == 1 ? "" : "s", sum.boundary_edges, sum.flips, sum.mu,
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
        if (sum.tiles)
            fprintf(stderr, "tessel: %zu tiles meshed in parallel, seams closed\n", sum.tiles);
        fprintf(stderr,
                "tessel: wrote %s in %.2f s (read %.2f s, reconstruction %.3f s = %.2fM "
                "points/s, write %.2f s; peak memory %.0f MiB)\n",
                out, seconds, t_read, sum.seconds, rate / 1e6, t_write, cli_peak_mib());
    }
    return CLI_OK;
}

static const char auto_help[] =
    "usage: tessel reconstruct IN OUT [--method auto|greedy|smooth | --mode\n"
    "                          height|range|grid] [options]\n\n"
    "Triangulates a point cloud. Without --method or --mode (or with --method\n"
    "auto) the method is chosen from the cloud, and the summary says which\n"
    "and why:\n"
    "  - an organized scan with its viewpoint (PCD, PLY 'comment organized'\n"
    "    and 'comment viewpoint'): the range mode, along the scanner's rays;\n"
    "  - else the noise is measured (as tessel info does): under 0.3 surface\n"
    "    spacings greedy projection, a mesh through the points; above, the\n"
    "    smooth method, a smooth surface near them.\n"
    "Measuring takes a fraction of a second on 10^6 points.\n\n"
    "Methods and their options:\n"
    "  --method greedy          clean clouds (see --method greedy --help)\n"
    "  --method smooth          noisy clouds (see --method smooth --help)\n"
    "  --mode height|range|grid fixed projection plane: terrain, scans from\n"
    "                           one position, organized grids (see --mode\n"
    "                           height --help)\n"
    "A method's own options choose it (--mu greedy, --refine smooth, ...);\n"
    "the fixed-plane options need their --mode.\n\n"
    "A cloud whose file is too large to mesh in core (see --memory) goes to\n"
    "greedy projection out of core.\n\n"
    "Options:\n"
    "  --ascii       write ascii PLY\n"
    "  --memory SIZE, --scratch DIR   out of core (see --method greedy --help)\n\n";

/* Options every method takes without a value. */
static bool is_flag(const char *a)
{
    static const char *const flags[] = {"--quiet", "-q",    "--json",    "--ascii",
                                        "--help",  "-h",    "--stream",  "--no-flip"};
    for (size_t i = 0; i < sizeof flags / sizeof flags[0]; i++)
        if (strcmp(a, flags[i]) == 0)
            return true;
    return false;
}

/* Options only one method takes: giving one asks for that method
 * (--tile-points, which both take, does not). */
static bool in_list(const char *a, const char *const *list, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (strcmp(a, list[i]) == 0)
            return true;
    return false;
}

static const char *const greedy_only[] = {"--mu", "--min-angle", "--plane", "--max-spacing",
                                          "--stream", "--memory", "--scratch"};
static const char *const smooth_only[] = {
    "--refine",       "--passes",      "--k",         "--sigma-rho",  "--sigma-w",
    "--sigma-max",    "--n-min",       "--max-diameter", "--max-edge", "--theta",
    "--theta-step",   "--phi",         "--normal-angle", "--max-hole",
    "--eps",          "--min-edge",    "--spacing",   "--max-noise"};
#define COUNT(a) (sizeof(a) / sizeof *(a))

/* Whether a cloud too large to read in core goes to greedy projection out
 * of core (the only method that meshes out of core), with --memory as
 * given. */
static bool outofcore_wanted(int argc, char **argv, const char *in)
{
    cli_greedy_opts o;
    memset(&o, 0, sizeof o);
    for (int i = 1; i + 1 < argc; i++)
        if (strcmp(argv[i], "--memory") == 0 && !cli_parse_size(argv[i], argv[i + 1], &o.ooc.memory))
            return false;
    return cli_outofcore_wanted(in, &o);
}

/* --method auto: reads IN, chooses the method, hands the cloud to it. */
static int reconstruct_auto(int argc, char **argv)
{
    bool want_greedy = false, want_smooth = false;
    for (int i = 1; i < argc; i++) {
        want_greedy |= in_list(argv[i], greedy_only, COUNT(greedy_only));
        want_smooth |= in_list(argv[i], smooth_only, COUNT(smooth_only));
    }
    if (want_greedy && want_smooth) {
        cli_error("reconstruct: options of greedy projection and of the smooth method "
                  "together: give --method");
        return CLI_USAGE;
    }
    const char *in = NULL, *out = NULL;
    cli_common common = {0};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            fputs(auto_help, stdout);
            fputs(cli_common_help, stdout);
            return CLI_OK;
        }
        int r = cli_common_option(&common, argc, argv, &i);
        if (r < 0)
            return CLI_USAGE;
        if (r > 0)
            continue;
        if (a[0] == '-' && a[1] != '\0') {
            if (!is_flag(a) && i + 1 < argc)
                i++; /* its value: the method's parser checks it */
            continue;
        }
        if (!in)
            in = a;
        else if (!out)
            out = a;
    }
    if (!in || !out) {
        fputs(auto_help, stderr);
        return CLI_USAGE;
    }
    cli_apply_threads(&common);
    if (!want_smooth && outofcore_wanted(argc, argv, in))
        return greedy(argc, argv);
    tessel_cloud cloud = {0};
    int rc = cli_read_cloud(in, &cloud, 3, "a surface", &common);
    if (rc != CLI_OK)
        return rc;
    tessel_reconstruct_params p = tessel_reconstruct_params_default();
    p.threads = common.threads;
    if (want_greedy || want_smooth)
        p.method = want_greedy ? TESSEL_METHOD_GREEDY : TESSEL_METHOD_SMOOTH;
    tessel_method_choice choice;
    tessel_status st = tessel_choose_method(&cloud, &p, &choice);
    if (want_greedy || want_smooth)
        choice.reason = "its options were given";
    if (st != TESSEL_OK) {
        cli_error("%s: choosing the method failed: %s", in, tessel_status_str(st));
        tessel_cloud_free(&cloud);
        return CLI_FAILURE;
    }
    cli_preload_cloud(in, &cloud, &choice);
    switch (choice.method) {
    case TESSEL_METHOD_SMOOTH:
        return cmd_reconstruct_smooth(argc, argv);
    case TESSEL_METHOD_FIXED_PLANE: {
        /* The range mode, as if asked for. */
        char **args = malloc(((size_t)argc + 3) * sizeof *args);
        if (!args) {
            cli_error("out of memory");
            return CLI_FAILURE;
        }
        memcpy(args, argv, (size_t)argc * sizeof *args);
        args[argc] = "--mode";
        args[argc + 1] = "range";
        args[argc + 2] = NULL;
        rc = cmd_reconstruct_fixed(argc + 2, args);
        free(args);
        return rc;
    }
    default:
        return greedy(argc, argv);
    }
}

int cmd_reconstruct(int argc, char **argv)
{
    /* The method decides which command parses the options. */
    const char *method = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--mode") == 0)
            return cmd_reconstruct_fixed(argc, argv);
        if (strcmp(argv[i], "--method") == 0 && i + 1 < argc)
            method = argv[i + 1];
    }
    if (!method || strcmp(method, "auto") == 0)
        return reconstruct_auto(argc, argv);
    if (strcmp(method, "smooth") == 0)
        return cmd_reconstruct_smooth(argc, argv);
    if (strcmp(method, "greedy") == 0)
        return greedy(argc, argv);
    cli_error("--method must be auto, greedy or smooth, got '%s'", method);
    return CLI_USAGE;
}
