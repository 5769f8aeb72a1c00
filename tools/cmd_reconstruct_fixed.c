/* tessel reconstruct IN OUT --mode height|range|grid: the fixed-plane
 * reconstruction of Gopi & Krishnan 2002, section 5, for height fields
 * (terrain, aerial LIDAR), range scans from one centre of projection and
 * organized grids. The triangles stream into the mesh writer, so memory
 * stays that of the cloud. See docs/fixed_plane.md. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char fixed_help[] =
    "usage: tessel reconstruct IN OUT --mode height|range|grid [options]\n\n"
    "Fixed-plane reconstruction (Gopi & Krishnan 2002, section 5): the points\n"
    "are bucketed into a 2D array of dexels on a fixed projection plane, one\n"
    "representative per dexel, and adjacent dexels are joined. Fast, and noise\n"
    "along the line of sight does not disturb it. Depth discontinuities (a\n"
    "step, a chair in front of a wall) stay open.\n\n"
    "Modes:\n"
    "  height   terrain, aerial LIDAR (LAS): dexels on the plane of least\n"
    "           variance, or across --axis; triangles face up\n"
    "  range    a scan from one position (terrestrial laser scanner):\n"
    "           dexels in (theta, phi) round the viewpoint; triangles face it\n"
    "  grid     an organized cloud (PCD WIDTH x HEIGHT, PLY 'comment\n"
    "           organized W H'): its own grid, missing points skipped,\n"
    "           shorter diagonal of each cell\n\n"
    "Options:\n"
    "  --axis x|y|z|auto      height: project along this axis (default auto:\n"
    "                         the plane of least variance, normal up)\n"
    "  --grid WxH             height, range: W x H dexels over the data\n"
    "                         (range: W in phi, H in theta)\n"
    "  --cell SIZE            height: dexel size in world units; range: dexel\n"
    "                         angle in degrees (default: from the density)\n"
    "  --points-per-dexel N   target of the automatic cell, >= 1 (default 3)\n"
    "  --viewpoint X,Y,Z      range, grid: scanner position (default: the\n"
    "                         file's PCD VIEWPOINT or PLY 'comment viewpoint';\n"
    "                         grid falls back to the origin)\n"
    "  --max-angle DEG        steepest edge still joined, from the plane facing\n"
    "                         the projection direction, 0..90 (default 80)\n"
    "  --noise SIGMA          noise along the line of sight, world units\n"
    "                         (default: estimated from the data)\n"
    "  --noise-factor K       joins reach K*SIGMA beyond the sampling (default 6)\n"
    "  --no-denoise           range, grid: mesh the points as they are (by\n"
    "                         default a noisy scan, 0.3 surface spacings or\n"
    "                         more, is first denoised along its rays: each\n"
    "                         point moves along its line of sight onto a\n"
    "                         robust plane through its neighbours)\n"
    "  --ascii                write ascii PLY\n\n";

typedef struct fixed_opts {
    tessel_fixed_plane_params p;
    int mode_given;
    int ascii;
    int no_denoise;
    double cell_arg;
} fixed_opts;

/* "W" "x" "H" with positive whole numbers. */
static bool parse_grid(const char *text, uint32_t *w, uint32_t *h)
{
    char *end = NULL;
    unsigned long a = strtoul(text, &end, 10);
    if (end == text || (*end != 'x' && *end != 'X'))
        goto bad;
    const char *rest = end + 1;
    unsigned long b = strtoul(rest, &end, 10);
    if (end == rest || *end != '\0' || a == 0 || b == 0 || a > 1000000 || b > 1000000)
        goto bad;
    *w = (uint32_t)a;
    *h = (uint32_t)b;
    return true;
bad:
    cli_error("--grid expects WxH with whole numbers from 1 to 1000000, got '%s'", text);
    return false;
}

static bool parse_triple(const char *opt, const char *text, double out[3])
{
    char buf[256];
    snprintf(buf, sizeof buf, "%s", text);
    char *save = buf;
    for (int k = 0; k < 3; k++) {
        char *tok = save;
        char *comma = strchr(save, ',');
        if ((comma == NULL) != (k == 2)) {
            cli_error("%s expects X,Y,Z, got '%s'", opt, text);
            return false;
        }
        if (comma) {
            *comma = '\0';
            save = comma + 1;
        }
        if (!cli_parse_double(opt, tok, &out[k]))
            return false;
    }
    return true;
}

static int fixed_option(void *ctx, int argc, char **argv, int *i)
{
    fixed_opts *o = ctx;
    const char *a = argv[*i], *v;
    if (strcmp(a, "--mode") == 0) {
        if (!(v = cli_option_value(argc, argv, i)))
            return -1;
        if (strcmp(v, "height") == 0)
            o->p.mode = TESSEL_FIXED_PLANE_HEIGHT;
        else if (strcmp(v, "range") == 0)
            o->p.mode = TESSEL_FIXED_PLANE_RANGE;
        else if (strcmp(v, "grid") == 0)
            o->p.mode = TESSEL_FIXED_PLANE_GRID;
        else {
            cli_error("--mode expects height, range or grid, got '%s'", v);
            return -1;
        }
        o->mode_given = 1;
        return 1;
    }
    if (strcmp(a, "--method") == 0) {
        /* --method auto chose this mode. */
        if (!(v = cli_option_value(argc, argv, i)))
            return -1;
        if (strcmp(v, "auto") != 0) {
            cli_error("--method %s and --mode do not go together", v);
            return -1;
        }
        return 1;
    }
    if (strcmp(a, "--axis") == 0) {
        if (!(v = cli_option_value(argc, argv, i)))
            return -1;
        if (strcmp(v, "x") == 0 || strcmp(v, "y") == 0 || strcmp(v, "z") == 0)
            o->p.axis = v[0] - 'x';
        else if (strcmp(v, "auto") == 0)
            o->p.axis = -1;
        else {
            cli_error("--axis expects x, y, z or auto, got '%s'", v);
            return -1;
        }
        return 1;
    }
    if (strcmp(a, "--grid") == 0) {
        if (!(v = cli_option_value(argc, argv, i)))
            return -1;
        return parse_grid(v, &o->p.columns, &o->p.rows) ? 1 : -1;
    }
    if (strcmp(a, "--viewpoint") == 0) {
        if (!(v = cli_option_value(argc, argv, i)))
            return -1;
        if (!parse_triple(a, v, o->p.viewpoint))
            return -1;
        o->p.use_viewpoint = 1;
        return 1;
    }
    if (strcmp(a, "--ascii") == 0) {
        o->ascii = 1;
        return 1;
    }
    if (strcmp(a, "--no-denoise") == 0) {
        o->no_denoise = 1;
        return 1;
    }
    static const char *const numeric[] = {"--cell", "--points-per-dexel", "--max-angle",
                                          "--noise", "--noise-factor"};
    for (int k = 0; k < 5; k++) {
        if (strcmp(a, numeric[k]) != 0)
            continue;
        double x;
        if (!(v = cli_option_value(argc, argv, i)) || !cli_parse_double(a, v, &x))
            return -1;
        bool ok = true;
        switch (k) {
        case 0:
            ok = x > 0;
            o->cell_arg = x;
            break;
        case 1:
            ok = x >= 1;
            o->p.points_per_dexel = x;
            break;
        case 2:
            ok = x > 0 && x < 90;
            o->p.max_angle = x;
            break;
        case 3:
            ok = x > 0;
            o->p.noise = x;
            break;
        default:
            ok = x >= 0;
            o->p.noise_factor = x;
            break;
        }
        if (!ok) {
            cli_error("%s: %s is out of range (see tessel reconstruct --help)", a, v);
            return -1;
        }
        return 1;
    }
    return 0;
}

static const char *mode_name(tessel_fixed_plane_mode m)
{
    return m == TESSEL_FIXED_PLANE_HEIGHT ? "height" : m == TESSEL_FIXED_PLANE_RANGE ? "range"
                                                                                     : "grid";
}

typedef struct fixed_run {
    const tessel_fixed_plane_params *params;
    tessel_fixed_plane_stats stats;
} fixed_run;

static tessel_status run_fixed(const tessel_cloud *cloud, const tessel_callbacks *cb,
                               const tessel_triangle_sink *sink, void *ctx)
{
    fixed_run *r = ctx;
    return tessel_reconstruct_fixed_plane(cloud, r->params, cb, sink, &r->stats);
}

int cmd_reconstruct_fixed(int argc, char **argv)
{
    cli_common common = {0};
    fixed_opts o;
    memset(&o, 0, sizeof o);
    o.p = tessel_fixed_plane_params_default();
    const char *in = NULL, *out = NULL;
    int r = cli_parse_in_out(argc, argv, fixed_help, &common, &in, &out, fixed_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    if (!o.mode_given) {
        cli_error("reconstruct: --mode height|range|grid is needed for the fixed-plane "
                  "reconstruction");
        return CLI_USAGE;
    }
    if (o.cell_arg > 0)
        o.p.cell = o.p.mode == TESSEL_FIXED_PLANE_RANGE ? o.cell_arg * 3.14159265358979323846 / 180.0
                                                        : o.cell_arg;
    cli_apply_threads(&common);
    o.p.threads = common.threads;

    double t0 = cli_now();
    tessel_cloud cloud = {0};
    int rc = cli_read_cloud(in, &cloud, 3, "a surface", &common);
    if (rc != CLI_OK)
        return rc;
    double t_read = cli_now() - t0;
    /* Wrong input for the mode: say so before any work (never an empty
     * mesh without a word). */
    if (o.p.mode == TESSEL_FIXED_PLANE_GRID && !cloud.grid) {
        cli_error("%s: grid mode needs an organized cloud (PCD WIDTH x HEIGHT with HEIGHT > 1, "
                  "or PLY 'comment organized W H'); this file holds %zu unorganized points: "
                  "use --mode height or --mode range",
                  in, cloud.count);
        tessel_cloud_free(&cloud);
        return CLI_INPUT_ERROR;
    }
    if (o.p.mode == TESSEL_FIXED_PLANE_RANGE && !o.p.use_viewpoint && !cloud.has_viewpoint) {
        cli_error("%s: range mode needs the scanner position: the file has none (PCD "
                  "VIEWPOINT or PLY 'comment viewpoint X Y Z'); give --viewpoint X,Y,Z",
                  in);
        tessel_cloud_free(&cloud);
        return CLI_USAGE;
    }

    /* Range and grid scans with noise: denoised along their rays first. */
    tessel_ray_denoise_stats ds = {0};
    int denoised = 0;
    if (!o.no_denoise && o.p.mode != TESSEL_FIXED_PLANE_HEIGHT &&
        (o.p.use_viewpoint || cloud.has_viewpoint)) {
        tessel_noise_estimate e;
        if (tessel_cloud_noise(&cloud, common.threads, &e) == TESSEL_OK &&
            e.noise_ratio >= tessel_reconstruct_params_default().clean_below) {
            tessel_ray_denoise_params dp = tessel_ray_denoise_params_default();
            dp.noise = e.sigma;
            dp.threads = common.threads;
            if (o.p.use_viewpoint) {
                dp.use_viewpoint = 1;
                memcpy(dp.viewpoint, o.p.viewpoint, sizeof dp.viewpoint);
            }
            tessel_status dst = tessel_denoise_along_rays(&cloud, &dp, &ds);
            if (dst != TESSEL_OK) {
                cli_error("%s: denoising along the rays failed: %s", in, tessel_status_str(dst));
                tessel_cloud_free(&cloud);
                return CLI_FAILURE;
            }
            denoised = 1;
            /* The joins' reach stays that of the noise the scan had: the
             * denoised points' residue would cut the surface at every
             * ripple. */
            if (!(o.p.noise > 0.0))
                o.p.noise = e.sigma;
        }
    }

    fixed_run run = {&o.p, {0}};
    double t_write = 0;
    int code = cli_stream_reconstruction(in, out, &cloud, o.ascii, &common,
                                         "fixed-plane reconstruction", run_fixed, &run,
                                         &t_write);
    size_t n = cloud.count;
    int offset = cloud.offset[0] != 0 || cloud.offset[1] != 0 || cloud.offset[2] != 0;
    tessel_cloud_free(&cloud);
    if (code != CLI_OK)
        return code;
    const tessel_fixed_plane_stats fs = run.stats;
    double seconds = cli_now() - t0;
    const double deg = 180.0 / 3.14159265358979323846;
    double cu = fs.mode == TESSEL_FIXED_PLANE_RANGE ? fs.cell[0] * deg : fs.cell[0];
    double cv = fs.mode == TESSEL_FIXED_PLANE_RANGE ? fs.cell[1] * deg : fs.cell[1];
    if (common.json) {
        printf("{\"mode\": \"%s\", \"points\": %zu, \"representatives\": %zu, "
               "\"dexels_filled\": %zu, \"columns\": %u, \"rows\": %u, \"cell\": [%.9g, %.9g], "
               "\"wrap_columns\": %d, \"wrap_rows\": %d, \"axis\": [%.9g, %.9g, %.9g], "
               "\"viewpoint\": [%.17g, %.17g, %.17g], \"noise\": %.9g, "
               "\"noise_estimated\": %d, \"margin\": %.9g, \"max_angle\": %g, "
               "\"cells\": %zu, \"cells_missing\": %zu, \"cells_open\": %zu, "
               "\"triangles_folded\": %zu, \"triangles_nonmanifold\": %zu, "
               "\"poles_closed\": %d, \"triangles\": %zu, \"read_seconds\": %.6f, \"reconstruct_seconds\": %.6f, "
               "\"dexel_seconds\": %.6f, \"write_seconds\": %.6f, \"seconds\": %.6f, "
               "\"denoised\": %d, \"denoise_noise\": %.9g, \"denoise_rms_move\": %.9g, "
               "\"peak_mib\": %.1f",
               mode_name(fs.mode), n, fs.representatives, fs.dexels_filled, fs.columns, fs.rows,
               cu, cv, fs.wrap_columns, fs.wrap_rows, fs.axis[0], fs.axis[1], fs.axis[2],
               fs.viewpoint[0], fs.viewpoint[1], fs.viewpoint[2], fs.noise, fs.noise_estimated,
               fs.margin, o.p.max_angle, fs.cells, fs.cells_missing, fs.cells_open,
               fs.triangles_folded, fs.triangles_nonmanifold, fs.poles_closed, fs.triangles,
               t_read, fs.seconds,
               fs.seconds_dexels, t_write, seconds, denoised, ds.noise, ds.rms_move,
               cli_peak_mib());
        cli_chosen_json_end();
    } else if (!common.quiet) {
        cli_chosen_text();
        if (denoised)
            fprintf(stderr,
                    "tessel: denoised along the rays: noise %.4g, %u neighbours, points moved "
                    "%.4g (RMS)\n",
                    ds.noise, ds.k, ds.rms_move);
        fprintf(stderr, "tessel: %s mode: %zu points, %u x %u %s", mode_name(fs.mode), n,
                fs.columns, fs.rows, fs.mode == TESSEL_FIXED_PLANE_GRID ? "grid" : "dexels");
        if (fs.mode == TESSEL_FIXED_PLANE_HEIGHT)
            fprintf(stderr, " of %.4g x %.4g, normal (%.3f, %.3f, %.3f)", cu, cv, fs.axis[0],
                    fs.axis[1], fs.axis[2]);
        else if (fs.mode == TESSEL_FIXED_PLANE_RANGE)
            fprintf(stderr, " of %.4g x %.4g degrees, pole (%.0f, %.0f, %.0f)", cu, cv,
                    fs.axis[0], fs.axis[1], fs.axis[2]);
        if (fs.mode != TESSEL_FIXED_PLANE_HEIGHT)
            fprintf(stderr, ", viewpoint %.6g %.6g %.6g", fs.viewpoint[0], fs.viewpoint[1],
                    fs.viewpoint[2]);
        if (fs.wrap_columns || fs.wrap_rows)
            fprintf(stderr, ", 360-degree %s", fs.wrap_columns ? "columns" : "rows");
        fprintf(stderr, "%s\n", offset ? ", georeferenced offset kept" : "");
        fprintf(stderr,
                "tessel: %zu representatives (%zu one-dexel gaps filled); noise %.4g (%s), "
                "edges reach %.4g beyond the sampling up to %g degrees\n",
                fs.representatives, fs.dexels_filled, fs.noise,
                fs.noise_estimated ? "estimated" : "given", fs.margin, o.p.max_angle);
        fprintf(stderr,
                "tessel: %zu triangles; of %zu cells %zu lack points, %zu are cut by a "
                "discontinuity; %zu triangles folded, %zu removed to keep vertices manifold",
                fs.triangles, fs.cells, fs.cells_missing, fs.cells_open, fs.triangles_folded,
                fs.triangles_nonmanifold);
        if (fs.poles_closed)
            fprintf(stderr, "; %d pole%s closed", fs.poles_closed,
                    fs.poles_closed == 1 ? "" : "s");
        fputc('\n', stderr);
        fprintf(stderr,
                "tessel: wrote %s in %.2f s (read %.2f s, reconstruction %.3f s = %.2fM "
                "points/s, write %.2f s)\n",
                out, seconds, t_read, fs.seconds,
                fs.seconds > 0 ? (double)n / fs.seconds / 1e6 : 0.0, t_write);
    }
    return CLI_OK;
}
