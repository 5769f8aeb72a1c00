/* tessel info FILE: what a file holds and what the cloud looks like. */
#include "cli.h"

#include <string.h>

static const char info_help[] =
    "usage: tessel info FILE [--json] [--threads N]\n\n"
    "Prints the file's format, point and triangle counts, attributes,\n"
    "bounding box, mean and median point spacing, the noise estimated from\n"
    "the cloud (standard deviation of the points' distance from the surface,\n"
    "in world units and in mean spacings), exact duplicates, isolated\n"
    "outliers and how many points were dropped for NaN/Inf coordinates.\n\n";

static bool format_has_faces(tessel_format f)
{
    return f == TESSEL_FORMAT_PLY || f == TESSEL_FORMAT_OBJ || f == TESSEL_FORMAT_OFF ||
           f == TESSEL_FORMAT_AUTO;
}

/* The tiles of the recursive halving into parts of at most max points. */
static size_t tiles_for(size_t n, size_t max)
{
    return n <= max ? 1 : tiles_for(n / 2, max) + tiles_for(n - n / 2, max);
}

/* st is NULL when the cloud has too few points for statistics. */
static void print_text(const char *path, tessel_format format, const tessel_cloud *c,
                       size_t triangles, const tessel_cloud_stats *st,
                       const tessel_noise_estimate *noise)
{
    printf("file:        %s\n", path);
    printf("format:      %s\n", format == TESSEL_FORMAT_AUTO ? "detected from content"
                                                             : tessel_format_name(format));
    printf("points:      %zu\n", c->count);
    if (triangles)
        printf("triangles:   %zu\n", triangles);
    printf("normals:     %s\n", c->normals ? "yes" : "no");
    printf("colours:     %s\n", c->rgb ? "yes" : "no");
    if (c->grid)
        printf("organized:   %u x %u\n", c->width, c->height);
    if (c->has_viewpoint)
        printf("viewpoint:   %.9g %.9g %.9g\n", c->viewpoint[0], c->viewpoint[1],
               c->viewpoint[2]);
    if (c->offset[0] != 0 || c->offset[1] != 0 || c->offset[2] != 0)
        printf("offset:      %.17g %.17g %.17g\n", c->offset[0], c->offset[1], c->offset[2]);
    if (!st) {
        printf("spacing:     too few points to measure\n");
        printf("nan/inf:     %zu dropped\n", c->dropped_nonfinite);
        return;
    }
    printf("bbox min:    %.9g %.9g %.9g\n", st->bbox_min[0], st->bbox_min[1], st->bbox_min[2]);
    printf("bbox max:    %.9g %.9g %.9g\n", st->bbox_max[0], st->bbox_max[1], st->bbox_max[2]);
    printf("diagonal:    %.9g\n", st->diagonal);
    printf("spacing:     mean %.6g, median %.6g\n", st->mean_spacing, st->median_spacing);
    if (noise)
        printf("noise:       %.6g (%.2f spacings; %.2f times the surface spacing %.6g)\n",
               noise->sigma, noise->sigma / st->mean_spacing, noise->noise_ratio,
               noise->surface_spacing);
    size_t tp = tessel_greedy_params_default().tile_points;
    if (tp && c->count > tp)
        printf("tiles:       %zu of at most %zu points (greedy projection meshes them in "
               "parallel)\n",
               tiles_for(c->count, tp), tp);
    printf("duplicates:  %zu\n", st->exact_duplicates);
    printf("outliers:    %zu\n", st->outliers);
    printf("nan/inf:     %zu dropped\n", c->dropped_nonfinite);
}

static void print_json(const char *path, tessel_format format, const tessel_cloud *c,
                       size_t triangles, const tessel_cloud_stats *st,
                       const tessel_noise_estimate *noise)
{
    printf("{\"file\": ");
    cli_json_string(stdout, path);
    printf(", \"format\": ");
    cli_json_string(stdout, format == TESSEL_FORMAT_AUTO ? "auto" : tessel_format_name(format));
    printf(", \"points\": %zu, \"triangles\": %zu", c->count, triangles);
    printf(", \"normals\": %s, \"colours\": %s", c->normals ? "true" : "false",
           c->rgb ? "true" : "false");
    printf(", \"organized\": %s", c->grid ? "true" : "false");
    if (c->grid)
        printf(", \"width\": %u, \"height\": %u", c->width, c->height);
    if (c->has_viewpoint)
        printf(", \"viewpoint\": [%.17g, %.17g, %.17g]", c->viewpoint[0], c->viewpoint[1],
               c->viewpoint[2]);
    printf(", \"offset\": [%.17g, %.17g, %.17g]", c->offset[0], c->offset[1], c->offset[2]);
    if (!st) {
        printf(", \"nonfinite_dropped\": %zu}\n", c->dropped_nonfinite);
        return;
    }
    printf(", \"bbox_min\": [%.17g, %.17g, %.17g]", st->bbox_min[0], st->bbox_min[1],
           st->bbox_min[2]);
    printf(", \"bbox_max\": [%.17g, %.17g, %.17g]", st->bbox_max[0], st->bbox_max[1],
           st->bbox_max[2]);
    printf(", \"diagonal\": %.17g, \"mean_spacing\": %.17g, \"median_spacing\": %.17g",
           st->diagonal, st->mean_spacing, st->median_spacing);
    if (noise)
        printf(", \"noise\": %.17g, \"noise_spacings\": %.17g, \"surface_spacing\": %.17g, "
               "\"noise_ratio\": %.17g",
               noise->sigma, noise->sigma / st->mean_spacing, noise->surface_spacing,
               noise->noise_ratio);
    printf(", \"duplicates\": %zu, \"outliers\": %zu, \"nonfinite_dropped\": %zu}\n",
           st->exact_duplicates, st->outliers, c->dropped_nonfinite);
}

int cmd_info(int argc, char **argv)
{
    cli_common common = {0};
    const char *path = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            fputs(info_help, stdout);
            fputs(cli_common_help, stdout);
            return CLI_OK;
        }
        int r = cli_common_option(&common, argc, argv, &i);
        if (r < 0)
            return CLI_USAGE;
        if (r > 0)
            continue;
        if (argv[i][0] == '-' && argv[i][1] != '\0') {
            cli_error("info: unknown option '%s'", argv[i]);
            return CLI_USAGE;
        }
        if (path) {
            cli_error("info: expects one FILE");
            return CLI_USAGE;
        }
        path = argv[i];
    }
    if (!path) {
        fputs(info_help, stderr);
        return CLI_USAGE;
    }
    cli_apply_threads(&common);

    tessel_diag diag = {0};
    tessel_cloud cloud = {0};
    tessel_read_params rp = cli_read_params(&common);
    tessel_status st = tessel_cloud_read(&cloud, path, &rp, &diag);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, path);
        return cli_exit_for_read(st);
    }
    tessel_format format = tessel_format_from_path(path);
    size_t triangles = 0;
    if (format_has_faces(format)) {
        tessel_mesh mesh = {0};
        st = tessel_mesh_read(&mesh, path, NULL, &diag);
        if (st != TESSEL_OK) {
            cli_error_status(st, &diag, path);
            tessel_cloud_free(&cloud);
            return cli_exit_for_read(st);
        }
        triangles = mesh.triangle_count;
        tessel_mesh_free(&mesh);
    }
    tessel_stats_params sp = tessel_stats_params_default();
    sp.threads = common.threads;
    tessel_cloud_stats stats;
    st = tessel_cloud_stats_compute(&cloud, &sp, &stats);
    bool have_stats = st == TESSEL_OK;
    if (st == TESSEL_ERR_TOO_FEW_POINTS)
        st = TESSEL_OK; /* empty or one-point files are described all the same */
    if (st != TESSEL_OK) {
        cli_error("%s: statistics failed: %s", path, tessel_status_str(st));
        tessel_cloud_free(&cloud);
        return CLI_FAILURE;
    }
    tessel_noise_estimate noise;
    bool have_noise =
        have_stats && tessel_cloud_noise(&cloud, common.threads, &noise) == TESSEL_OK;
    const tessel_cloud_stats *stp = have_stats ? &stats : NULL;
    const tessel_noise_estimate *np = have_noise ? &noise : NULL;
    if (common.json)
        print_json(path, format, &cloud, triangles, stp, np);
    else
        print_text(path, format, &cloud, triangles, stp, np);
    tessel_cloud_free(&cloud);
    return CLI_OK;
}
